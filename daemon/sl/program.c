/*
 * The compiler's driver: source text -> tokens -> tree -> checked tree ->
 * IR -> inferred IR, and the printable forms of each (relight compile --emit).
 */
#include "sema.h"
#include "builtin.h"
#include "../common/strbuf.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#define MAX_SOURCE (64u << 20)

static const char *const kind_names[] = {
	[SL_SHADER_SURFACE] = "surface", [SL_SHADER_LIGHT] = "light",
	[SL_SHADER_DISPLACEMENT] = "displacement", [SL_SHADER_VOLUME] = "volume",
	[SL_SHADER_IMAGER] = "imager",
};

const char *sl_shader_kind_name(enum sl_shader_kind kind)
{
	return (unsigned)kind <= SL_SHADER_IMAGER ? kind_names[kind] : "?";
}

const char *sl_program_name(const struct sl_program *prog)
{
	return prog->name;
}

const char *sl_program_source_hash(const struct sl_program *prog)
{
	return prog->source_hash;
}

const char *sl_program_hash(const struct sl_program *prog)
{
	return prog->program_hash;
}

enum sl_shader_kind sl_program_kind(const struct sl_program *prog)
{
	return prog->kind;
}

const struct sl_program *sl_program_atmosphere(const struct sl_program *prog)
{
	return prog->atmosphere;
}

const struct sl_program *sl_program_surface_part(const struct sl_program *prog)
{
	return prog->surface_part ? prog->surface_part : prog;
}

void sl_program_own_parts(struct sl_program *joined)
{
	joined->owns_parts = joined->surface_part != NULL;
}

void sl_program_destroy(struct sl_program *prog)
{
	if (!prog)
		return;
	if (prog->owns_parts) {
		/* the parts were made for this program alone */
		sl_program_destroy((struct sl_program *)(uintptr_t)prog->surface_part);
		sl_program_destroy((struct sl_program *)(uintptr_t)prog->atmosphere);
	}
	rl_arena_destroy(prog->arena);
}

/* Read a whole file; NULL (and a message) on failure. */
static char *read_file(struct sl_ctx *ctx, const char *path, size_t *len)
{
	FILE *f = fopen(path, "rb");
	if (!f) {
		fprintf(ctx->diag, "%s: error: cannot open: %s\n", path, strerror(errno));
		ctx->nerrors++;
		return NULL;
	}
	struct rl_strbuf b = { 0 };
	char chunk[65536];
	size_t n;
	while ((n = fread(chunk, 1, sizeof(chunk), f)) > 0) {
		if (b.len + n > MAX_SOURCE) {
			fprintf(ctx->diag, "%s: error: file is larger than %u MB\n", path,
				MAX_SOURCE >> 20);
			ctx->nerrors++;
			fclose(f);
			rl_strbuf_finish(&b);
			return NULL;
		}
		rl_strbuf_add(&b, chunk, n);
	}
	bool failed = ferror(f);
	fclose(f);
	if (failed) {
		fprintf(ctx->diag, "%s: error: cannot read: %s\n", path, strerror(errno));
		ctx->nerrors++;
		rl_strbuf_finish(&b);
		return NULL;
	}
	*len = b.len;
	if (!b.data)
		return rl_xcalloc(1, 1);
	return b.data;
}

static struct sl_program *compile(struct sl_ctx *ctx, const char *path, const char *src,
				  size_t len)
{
	struct sl_token_list toks = { 0 };
	sl_preprocess(ctx, path, src, len, &toks);
	struct sl_ast *unit = NULL;
	if (!ctx->too_many)
		unit = sl_parse(ctx, toks.data, toks.len);
	free(toks.data);
	if (ctx->nerrors || !unit)
		return NULL;
	struct sl_ast *shader = sl_sema(ctx, unit);
	if (!shader)
		return NULL;
	struct sl_program *prog = sl_lower(ctx, shader);
	if (!prog)
		return NULL;
	if (!sl_infer(ctx, prog))
		return NULL;
	/* The program keeps the compilation's arena (tree and all: small). */
	prog->arena = ctx->arena;
	ctx->arena = rl_arena_create();
	prog->source_path = rl_arena_strdup(prog->arena, path);
	prog->nfiles = (uint32_t)ctx->files.len;
	rl_hash128_hex(&ctx->source_hash, prog->source_hash);
	rl_hash128_hex(&ctx->program_hash, prog->program_hash);
	prog->files = rl_arena_alloc(prog->arena, sizeof(char *) * (ctx->files.len + 1));
	for (size_t i = 0; i < ctx->files.len; i++)
		prog->files[i] = rl_arena_strdup(prog->arena, ctx->files.data[i]);
	return prog;
}

struct sl_program *sl_compile_string(const char *name, const char *src, size_t len,
				     const struct sl_options *opts)
{
	struct sl_ctx ctx;
	sl_ctx_init(&ctx, opts);
	struct sl_program *prog = compile(&ctx, name, src, len);
	sl_ctx_finish(&ctx);
	return prog;
}

char *sl_declared_name(const char *path, const char *src, size_t len,
		       const struct sl_options *opts)
{
	struct sl_ctx ctx;
	sl_ctx_init(&ctx, opts);
	ctx.quiet = true;
	struct sl_token_list toks = { 0 };
	sl_preprocess(&ctx, path, src, len, &toks);
	char *name = NULL;
	for (size_t i = 0; i + 2 < toks.len && !name; i++) {
		enum sl_tok k = toks.data[i].kind;
		if (k >= SL_TOK_KW_SURFACE && k <= SL_TOK_KW_IMAGER &&
		    toks.data[i + 1].kind == SL_TOK_IDENT && toks.data[i + 2].kind == SL_TOK_LPAREN)
		{
			name = rl_xcalloc(toks.data[i + 1].len + 1, 1);
			memcpy(name, toks.data[i + 1].text, toks.data[i + 1].len);
		}
	}
	free(toks.data);
	sl_ctx_finish(&ctx);
	return name;
}

struct sl_program *sl_compile_file(const char *path, const struct sl_options *opts)
{
	struct sl_ctx ctx;
	sl_ctx_init(&ctx, opts);
	size_t len = 0;
	char *src = read_file(&ctx, path, &len);
	struct sl_program *prog = src ? compile(&ctx, path, src, len) : NULL;
	free(src);
	sl_ctx_finish(&ctx);
	return prog;
}

bool sl_emit_ast_file(const char *path, const struct sl_options *opts, FILE *out)
{
	struct sl_ctx ctx;
	sl_ctx_init(&ctx, opts);
	size_t len = 0;
	char *src = read_file(&ctx, path, &len);
	bool ok = false;
	if (src) {
		struct sl_token_list toks = { 0 };
		sl_preprocess(&ctx, path, src, len, &toks);
		struct sl_ast *unit = ctx.too_many ? NULL : sl_parse(&ctx, toks.data, toks.len);
		free(toks.data);
		if (unit && !ctx.nerrors) {
			sl_ast_dump(&ctx, unit, out);
			ok = true;
		}
	}
	free(src);
	sl_ctx_finish(&ctx);
	return ok;
}

/* ---- the JSON report ---- */

/*
 * Fold a parameter's default when it is made of constants only: the
 * instructions [begin, end) may use MOV, NEG, arithmetic, TRIPLE, MATRIX and
 * ASET on constants. Returns false for anything else (a transform, a call).
 */
static bool fold_default(const struct sl_program *prog, const struct sl_param *p, float *out,
			 int nout, const char **sout)
{
	/* values of registers written in the range, by register */
	enum { MAXV = 64 };
	int32_t regs[MAXV];
	float vals[MAXV][16];
	int nv = 0;
	*sout = NULL;
	for (uint32_t i = p->init_begin; i < p->init_end; i++) {
		const struct sl_insn *in = &prog->code[i];
		float a[16] = { 0 }, b[16] = { 0 };
		float *ops[2] = { a, b };
		for (int k = 0; k < in->nargs && k < 2; k++) {
			int32_t r = in->args[k];
			const struct sl_reg *reg = &prog->regs[r];
			if (reg->kind == SL_REG_CONST && reg->type == SL_TYPE_FLOAT) {
				for (int c = 0; c < 16; c++)
					ops[k][c] = prog->consts[reg->cindex];
			} else if (reg->kind == SL_REG_CONST && reg->type == SL_TYPE_STRING) {
				if (in->op != SL_OP_MOV || in->dst != p->reg)
					return false;
				*sout = prog->strings[reg->cindex];
				return true;
			} else {
				int found = -1;
				for (int j = 0; j < nv; j++)
					if (regs[j] == r)
						found = j;
				if (found < 0)
					return false;
				int nc = sl_reg_ncomp(reg);
				for (int c = 0; c < 16; c++)
					ops[k][c] = vals[found][nc == 1 ? 0 : c % (nc ? nc : 1)];
			}
		}
		float r[16] = { 0 };
		int nc = in->dst >= 0 ? sl_reg_ncomp(&prog->regs[in->dst]) : 0;
		switch (in->op) {
		case SL_OP_MOV:
			for (int c = 0; c < 16; c++)
				r[c] = a[c];
			if (nc == 16 && prog->regs[in->args[0]].type == SL_TYPE_FLOAT)
				for (int c = 0; c < 16; c++)
					r[c] = c % 5 == 0 ? a[0] : 0;
			break;
		case SL_OP_NEG:
			for (int c = 0; c < 16; c++)
				r[c] = -a[c];
			break;
		case SL_OP_ADD: case SL_OP_SUB: case SL_OP_MUL: case SL_OP_DIV:
			if (nc == 16)
				return false;
			for (int c = 0; c < 3; c++)
				r[c] = in->op == SL_OP_ADD ? a[c] + b[c] :
				       in->op == SL_OP_SUB ? a[c] - b[c] :
				       in->op == SL_OP_MUL ? a[c] * b[c] :
				       b[c] != 0 ? a[c] / b[c] : 0;
			break;
		case SL_OP_TRIPLE:
		case SL_OP_MATRIX:
			for (int k = 0; k < in->nargs && k < 16; k++) {
				const struct sl_reg *reg = &prog->regs[in->args[k]];
				if (reg->kind != SL_REG_CONST) {
					int found = -1;
					for (int j = 0; j < nv; j++)
						if (regs[j] == in->args[k])
							found = j;
					if (found < 0)
						return false;
					r[k] = vals[found][0];
				} else {
					r[k] = prog->consts[reg->cindex];
				}
			}
			break;
		case SL_OP_ASET: {
			/* element writes into the parameter array */
			if (in->dst != p->reg)
				return false;
			const struct sl_reg *ir = &prog->regs[in->args[1]];
			if (ir->kind != SL_REG_CONST)
				return false;
			int e = (int)prog->consts[ir->cindex];
			int enc = sl_reg_ncomp(&prog->regs[p->reg]);
			for (int c = 0; c < enc; c++)
				if (e * enc + c < nout)
					out[e * enc + c] = prog->regs[in->args[0]].type == SL_TYPE_FLOAT &&
								   enc > 1 ? a[0] : a[c];
			continue;
		}
		default:
			return false;
		}
		if (in->dst == p->reg) {
			for (int c = 0; c < nc && c < nout; c++)
				out[c] = r[c];
			continue;
		}
		if (nv >= MAXV)
			return false;
		regs[nv] = in->dst;
		memcpy(vals[nv], r, sizeof(r));
		nv++;
	}
	return true;
}

static void json_float(struct rl_strbuf *b, float v)
{
	rl_strbuf_printf(b, "%.9g", (double)v);
}

void sl_emit(const struct sl_program *prog, enum sl_emit_kind kind, FILE *out)
{
	if (kind == SL_EMIT_IR)
		sl_ir_dump(prog, out);
	else if (kind == SL_EMIT_REPORT)
		sl_emit_report(prog, NULL, out);
}

static void json_loc(struct rl_strbuf *b, const struct sl_program *prog, struct sl_loc loc)
{
	const char *file = loc.file < prog->nfiles ? prog->files[loc.file] : "?";
	rl_strbuf_json_string(b, file);
	rl_strbuf_printf(b, ", \"line\": %u", loc.line);
}

/*
 * The uniform locals inference made varying, and why (see infer.c): name,
 * line of the declaration, and file and line of the write that made it vary.
 */
static void report_promoted(struct rl_strbuf *b, const struct sl_program *prog)
{
	for (uint32_t k = 0; k < prog->npromoted; k++) {
		const struct sl_promotion *m = &prog->promoted[k];
		const struct sl_reg *r = &prog->regs[m->reg];
		rl_strbuf_printf(b, "%s\n    {\"name\": ", k ? "," : "");
		rl_strbuf_json_string(b, r->name ? r->name : "");
		rl_strbuf_printf(b, ", \"declared\": %u, \"file\": ", r->loc.line);
		json_loc(b, prog, m->at);
		rl_strbuf_printf(b, ", \"reason\": \"%s\"}",
				 m->ctl ? "assigned under varying control flow"
					: "assigned a varying value");
	}
	if (prog->npromoted)
		rl_strbuf_puts(b, "\n  ");
}

void sl_emit_report(const struct sl_program *prog, const char *extra, FILE *out)
{
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, "{\n  \"name\": ");
	rl_strbuf_json_string(&b, prog->name);
	rl_strbuf_printf(&b, ",\n  \"type\": \"%s\",\n  \"source\": ",
			 sl_shader_kind_name(prog->kind));
	rl_strbuf_json_string(&b, prog->source_path ? prog->source_path : "");
	rl_strbuf_puts(&b, ",\n  \"parameters\": [");
	for (uint32_t i = 0; i < prog->nparams; i++) {
		const struct sl_param *p = &prog->params[i];
		rl_strbuf_printf(&b, "%s\n    {\"name\": ", i ? "," : "");
		rl_strbuf_json_string(&b, p->name);
		rl_strbuf_printf(&b, ", \"type\": \"%s\", \"detail\": \"%s\", ",
				 sl_basetype_name(p->type.base),
				 p->type.detail == SL_DETAIL_VARYING ? "varying" : "uniform");
		if (p->type.arraylen > 0)
			rl_strbuf_printf(&b, "\"arraylen\": %d, ", p->type.arraylen);
		rl_strbuf_printf(&b, "\"output\": %s, \"default\": ", p->output ? "true" : "false");
		int n = sl_type_ncomp(p->type.base) * (p->type.arraylen > 0 ? p->type.arraylen : 1);
		float vals[256] = { 0 };
		const char *sval = NULL;
		if (n <= 256 && fold_default(prog, p, vals, n, &sval)) {
			if (p->type.base == SL_TYPE_STRING) {
				rl_strbuf_json_string(&b, sval ? sval : "");
			} else if (n == 1) {
				json_float(&b, vals[0]);
			} else {
				rl_strbuf_putc(&b, '[');
				for (int k = 0; k < n; k++) {
					if (k)
						rl_strbuf_puts(&b, ", ");
					json_float(&b, vals[k]);
				}
				rl_strbuf_putc(&b, ']');
			}
		} else {
			rl_strbuf_puts(&b, "null");
		}
		rl_strbuf_putc(&b, '}');
	}
	rl_strbuf_puts(&b, "\n  ],\n  \"globals\": [");
	bool first = true;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		if (prog->global_reg[g] < 0)
			continue;
		rl_strbuf_printf(&b, "%s\"%s\"", first ? "" : ", ", sl_global_name((enum sl_global)g));
		first = false;
	}
	rl_strbuf_puts(&b, "],\n  \"promoted\": [");
	report_promoted(&b, prog);
	unsigned total = prog->ncode, varying = 0, calls = 0, control = 0;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (in->op >= SL_OP_IF)
			control++;
		if (in->op == SL_OP_CALL)
			calls++;
		if (in->dst >= 0 && prog->regs[in->dst].varying)
			varying++;
	}
	unsigned nvarying_regs = 0;
	for (uint32_t r = 0; r < prog->nregs; r++)
		nvarying_regs += prog->regs[r].varying;
	rl_strbuf_printf(&b,
			 "],\n  \"instructions\": {\"total\": %u, \"varying\": %u, \"uniform\": %u, "
			 "\"calls\": %u, \"control\": %u},\n  \"registers\": {\"total\": %u, "
			 "\"varying\": %u}%s%s\n}\n",
			 total, varying, total - varying - control, calls, control, prog->nregs,
			 nvarying_regs, extra ? ",\n  " : "", extra ? extra : "");
	fputs(rl_strbuf_str(&b), out);
	rl_strbuf_finish(&b);
}

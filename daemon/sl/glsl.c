/*
 * GLSL generation, the core: the program's structure becomes GLSL control
 * flow, its registers per-invocation variables, and the scene's light
 * shaders functions light_k() called where the surface asks for lights.
 *
 * The source is built in sections (glsl_impl.h), each a string builder,
 * joined at the end; any error sets a sticky flag checked once, after
 * everything has been reported.
 *
 * One invocation runs one shading sample, so the interpreter's running-state
 * masks become ordinary control flow:
 *   IF            if (c != 0.0) { ... } else { ... }
 *   LOOP          while (true) { condition; if (c == 0.0) break;
 *                                do { body } while (false); step; }
 *   FUNC          do { body } while (false)
 *   ILLUMINANCE   the body once per light, inside do { } while (false)
 * A break, continue or return sets its target's flag x..., then breaks out of
 * the innermost GLSL loop; after each construct it may leave, the flags of
 * the targets beyond it are tested and the break goes on outwards. The
 * do-while around a loop body is where a continue lands, so the step code
 * still runs.
 *
 * Data. Registers are per-invocation globals (r<reg>, light k's l<k>r<reg>),
 * zero to start with as the interpreter's storage is. A parameter that is
 * not an input comes from its uniform, which holds the value the register
 * has when a run starts (defaults evaluated, points in "current" space).
 * Strings are token ids: every string constant of the surface and its
 * lights, and every name in an illuminance category list, has an id in the
 * layout's table. A string parameter set to a string the table lacks takes
 * any id past the table, one per distinct string: it equals no constant and
 * is a category no list names (so a light category list that is not in the
 * table is not split into its names).
 *
 * Matrices: a GLSL mat4 m holds RSL element (row i, column j) at m[i][j],
 * i.e. the 16 floats of an RSL matrix in order, as glUniformMatrix4fv takes
 * them untransposed. Then RSL p * M is m * p in GLSL and RSL A * B is
 * b * a.
 */
#include "glsl_impl.h"
#include "spec.h"
#include "exec_impl.h"
#include "config.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <stddef.h>
#include <string.h>

#define NONE UINT32_MAX
/* Iterations of one loop in one invocation before it is cut short (as the interpreter). */
#define MAX_LOOP_ITERS 10000000u
/* The generated source may not grow past this. */
#define MAX_SOURCE ((size_t)16 << 20)
/* More lights than this in one program is refused. */
#define MAX_LIGHTS 4096

enum { EXIT_BREAK = 1, EXIT_CONTINUE = 2, EXIT_RETURN = 4 };

/* ------------------------------------------------------------------------ */
/* Diagnostics and text                                                      */

static const char *prog_file(const struct sl_program *prog, const struct sl_insn *in)
{
	if (in && prog->files && in->loc.file < prog->nfiles && prog->files[in->loc.file])
		return prog->files[in->loc.file];
	if (prog->source_path)
		return prog->source_path;
	return prog->name ? prog->name : "shader";
}

static void report(struct glsl_gen *g, const struct sl_insn *in, const char *what,
		   const char *fmt, va_list ap)
{
	FILE *f = g->diag ? g->diag : stderr;
	const struct sl_program *prog = g->cur ? g->cur->prog : g->surf;
	if (in)
		fprintf(f, "%s:%u:%u: %s: ", prog_file(prog, in), in->loc.line, in->loc.col, what);
	else
		fprintf(f, "%s: %s: ", prog_file(prog, NULL), what);
	vfprintf(f, fmt, ap);
	fputc('\n', f);
}

void sl_glsl_error(struct glsl_gen *g, const struct sl_insn *in, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	report(g, in, "error", fmt, ap);
	va_end(ap);
	g->failed = true;
}

void sl_glsl_warning(struct glsl_gen *g, const struct sl_insn *in, const char *fmt, ...)
{
	/* A moved copy repeats code whose warnings were given once already. */
	if (g->moved)
		return;
	va_list ap;
	va_start(ap, fmt);
	report(g, in, "warning", fmt, ap);
	va_end(ap);
}

void sl_glsl_line(struct glsl_gen *g, const char *fmt, ...)
{
	struct rl_strbuf *b = g->out;
	if (b->len > MAX_SOURCE) {
		if (!g->failed)
			sl_glsl_error(g, NULL, "the generated GLSL is too large (over %zu MB)",
				      MAX_SOURCE >> 20);
		return;
	}
	for (int i = 0; i < g->indent; i++)
		rl_strbuf_putc(b, '\t');
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(b, fmt, ap);
	va_end(ap);
	rl_strbuf_putc(b, '\n');
}

const char *sl_glsl_float(struct glsl_gen *g, float v)
{
	if (v != v)
		v = 0.0f;
	if (v > FLT_MAX)
		v = FLT_MAX;
	if (v < -FLT_MAX)
		v = -FLT_MAX;
	char buf[48];
	snprintf(buf, sizeof(buf), "%.9g", (double)v);
	bool plain = !strpbrk(buf, ".e");
	if (v < 0.0f || (v == 0.0f && signbit(v)))
		return SL_GLSL_FMT(g, "(%s%s)", buf, plain ? ".0" : "");
	return SL_GLSL_FMT(g, "%s%s", buf, plain ? ".0" : "");
}

/* ------------------------------------------------------------------------ */
/* String table                                                              */

static uint32_t str_hash(const char *s)
{
	uint32_t h = 2166136261u;
	for (; *s; s++)
		h = (h ^ (uint8_t)*s) * 16777619u;
	return h;
}

uint32_t sl_glsl_string_id(struct glsl_gen *g, const char *s)
{
	if ((g->strings.len + 1) * 2 > g->shcap) {
		size_t cap = g->shcap ? 2 * g->shcap : 64;
		uint32_t *t = rl_xcalloc(cap, sizeof(uint32_t));
		for (size_t i = 0; i < g->strings.len; i++) {
			size_t j = str_hash(g->strings.data[i]) & (cap - 1);
			while (t[j])
				j = (j + 1) & (cap - 1);
			t[j] = (uint32_t)i + 1;
		}
		free(g->shash);
		g->shash = t;
		g->shcap = cap;
	}
	size_t j = str_hash(s) & (g->shcap - 1);
	for (; g->shash[j]; j = (j + 1) & (g->shcap - 1))
		if (!strcmp(g->strings.data[g->shash[j] - 1], s))
			return g->shash[j] - 1;
	rl_vec_push(g->strings, s);
	g->shash[j] = (uint32_t)g->strings.len;
	return (uint32_t)g->strings.len - 1;
}

/* Every string constant of @prog in the table, so that ids are known before any code. */
static void collect_strings(struct glsl_gen *g, const struct sl_program *prog)
{
	/* Interned strings repeat as pointers: skip a pointer seen just before. */
	const char *last = NULL;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		if (rg->kind != SL_REG_CONST || rg->type != SL_TYPE_STRING)
			continue;
		uint32_t ne = rg->arraylen > 0 ? (uint32_t)rg->arraylen : 1;
		for (uint32_t e = 0; e < ne; e++) {
			const char *s = prog->strings[rg->cindex + e] ? prog->strings[rg->cindex + e]
								       : "";
			if (s != last)
				sl_glsl_string_id(g, s);
			last = s;
		}
	}
}

/*
 * The names an illuminance category list is made of ("a, -b" gives "a" and
 * "b"), so that a light whose __category is one of them has its own id.
 */
static void collect_category_terms(struct glsl_gen *g, const struct glsl_prog *p)
{
	const struct sl_program *prog = p->prog;
	for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (in->op != SL_OP_ILLUMINANCE || in->imm != 1 || !in->nargs)
			continue;
		const char *cat = p->cstr[in->args[0]];
		while (cat && *cat) {
			const char *e = strchr(cat, ',');
			if (!e)
				e = cat + strlen(cat);
			const char *b = cat, *t = e;
			while (b < t && (*b == ' ' || *b == '\t' || *b == '-'))
				b++;
			while (t > b && (t[-1] == ' ' || t[-1] == '\t'))
				t--;
			if (b < t)
				sl_glsl_string_id(g, rl_arena_strndup(g->arena, b, (size_t)(t - b)));
			cat = *e ? e + 1 : e;
		}
	}
}

/* ------------------------------------------------------------------------ */
/* Registers                                                                 */

int sl_glsl_ncomp(const struct sl_program *prog, int32_t r)
{
	const struct sl_reg *rg = &prog->regs[r];
	return rg->type == SL_TYPE_STRING ? 1 : sl_reg_ncomp(rg);
}

static const char *type_name(int nc)
{
	return nc == 16 ? "mat4" : nc == 3 ? "vec3" : "float";
}

static const char *zero_of(int nc)
{
	return nc == 16 ? "mat4(0.0)" : nc == 3 ? "vec3(0.0)" : "0.0";
}

/* One element of constant register @r. */
static const char *const_elem(struct glsl_gen *g, const struct sl_program *prog, int32_t r,
			      uint32_t e)
{
	const struct sl_reg *rg = &prog->regs[r];
	if (rg->type == SL_TYPE_STRING) {
		const char *s = prog->strings[rg->cindex + e];
		return SL_GLSL_FMT(g, "%u.0", sl_glsl_string_id(g, s ? s : ""));
	}
	int nc = sl_reg_ncomp(rg);
	const float *v = prog->consts + rg->cindex + (size_t)e * (size_t)nc;
	if (nc == 1)
		return sl_glsl_float(g, v[0]);
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, nc == 3 ? "vec3(" : "mat4(");
	for (int c = 0; c < nc; c++) {
		if (c)
			rl_strbuf_puts(&b, ", ");
		rl_strbuf_puts(&b, sl_glsl_float(g, v[c]));
	}
	rl_strbuf_putc(&b, ')');
	const char *s = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return s;
}

static const char *const_expr(struct glsl_gen *g, const struct sl_program *prog, int32_t r)
{
	const struct sl_reg *rg = &prog->regs[r];
	if (rg->arraylen <= 0)
		return const_elem(g, prog, r, 0);
	struct rl_strbuf b = { 0 };
	rl_strbuf_printf(&b, "%s[%d](", type_name(sl_glsl_ncomp(prog, r)), rg->arraylen);
	for (int32_t e = 0; e < rg->arraylen; e++) {
		if (e)
			rl_strbuf_puts(&b, ", ");
		rl_strbuf_puts(&b, const_elem(g, prog, r, (uint32_t)e));
	}
	rl_strbuf_putc(&b, ')');
	const char *s = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return s;
}

static const char *moved_name(struct glsl_gen *g, struct glsl_prog *p, int32_t r, int dir);

const char *sl_glsl_op(struct glsl_gen *g, int32_t r, int want)
{
	const struct sl_program *prog = g->cur->prog;
	const char *e = prog->regs[r].kind == SL_REG_CONST ? const_expr(g, prog, r)
							  : g->cur->name[r];
	if (g->moved && g->cur->need && g->cur->need[r])
		e = moved_name(g, g->cur, r, g->moved);
	int nc = sl_glsl_ncomp(prog, r);
	if (want == 0 || prog->regs[r].arraylen > 0 || nc != 1 || want == 1)
		return e;
	if (want == 3)
		return SL_GLSL_FMT(g, "vec3(%s)", e);
	if (want == 16)
		return SL_GLSL_FMT(g, "mat4(%s)", e);
	return SL_GLSL_FMT(g, "rl_fill(%s)", e);
}

const char *sl_glsl_lv(struct glsl_gen *g, int32_t r)
{
	if (g->cur->prog->regs[r].kind == SL_REG_CONST)
		return NULL;
	return g->moved ? moved_name(g, g->cur, r, g->moved) : g->cur->name[r];
}

const char *sl_glsl_cstr(struct glsl_gen *g, int32_t r)
{
	return g->cur->cstr[r];
}

/* What register @r of @p holds before any code runs (as the interpreter starts it). */
static const char *reg_init(const struct glsl_prog *p, int32_t r)
{
	const struct sl_reg *rg = &p->prog->regs[r];
	/* As the interpreter starts a surface: Ci = 0, Oi = 1. */
	if (p->prog->kind == SL_SHADER_SURFACE && rg->kind == SL_REG_GLOBAL &&
	    rg->global == SL_GLOBAL_OI)
		return "vec3(1.0)";
	return zero_of(sl_glsl_ncomp(p->prog, r));
}

/*
 * The copy of register @r of @p moved one grid step along u (@dir 1) or v
 * (2), declared on first use and starting as the register starts.
 */
static const char *moved_name(struct glsl_gen *g, struct glsl_prog *p, int32_t r, int dir)
{
	const char *name = SL_GLSL_FMT(g, "%c%s", dir == 1 ? 'u' : 'v', p->name[r]);
	uint8_t bit = (uint8_t)dir;
	if (p->mdecl && !(p->mdecl[r] & bit)) {
		p->mdecl[r] |= bit;
		const struct sl_reg *rg = &p->prog->regs[r];
		const char *t = type_name(sl_glsl_ncomp(p->prog, r));
		if (rg->arraylen)
			rl_strbuf_printf(&g->sec[GS_GLOBALS], "%s %s[%d];\n", t, name, rg->arraylen);
		else
			rl_strbuf_printf(&g->sec[GS_GLOBALS], "%s %s = %s;\n", t, name, reg_init(p, r));
	}
	return name;
}

int sl_glsl_class(const struct glsl_gen *g, int32_t r)
{
	return g->cur->cls ? g->cur->cls[r] : 0;
}

const char *sl_glsl_moved(struct glsl_gen *g, int32_t r, int want, int dir)
{
	int saved = g->moved;
	g->moved = dir;
	const char *e = sl_glsl_op(g, r, want);
	g->moved = saved;
	return e;
}

/* A register name's readable part: letters, digits and single underscores. */
static void put_sanitized(struct rl_strbuf *b, const char *name)
{
	char prev = '_';
	for (const char *s = name; *s && s - name < 32; s++) {
		char c = *s;
		bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
		if (!ok)
			c = '_';
		if (c == '_' && prev == '_')
			continue;
		rl_strbuf_putc(b, c);
		prev = c;
	}
	/* No trailing underscore: it would join the next one into "__". */
	if (b->len && b->data[b->len - 1] == '_')
		b->data[--b->len] = '\0';
}

/* Is @s a GLSL identifier body (letters, digits, '_'), not empty? */
static bool is_ident(const char *s)
{
	if (!*s)
		return false;
	for (; *s; s++)
		if (!((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z') ||
		      (*s >= '0' && *s <= '9') || *s == '_'))
			return false;
	return true;
}

/* ------------------------------------------------------------------------ */
/* Coordinate systems                                                        */

const char *sl_glsl_space(struct glsl_gen *g, const struct sl_insn *in, const char *name)
{
	if (!*name || !strcmp(name, "current") || !strcmp(name, "camera"))
		return NULL;
	if (!strcmp(name, "shader") && g->cur->light >= 0)
		return SL_GLSL_FMT(g, "l%d_shader", g->cur->light);
	if (!is_ident(name) || strstr(name, "__")) {
		sl_glsl_error(g, in, "coordinate system '%s' cannot be named in GLSL", name);
		return NULL;
	}
	uint32_t id = sl_glsl_string_id(g, name);
	while (g->space_on.len <= id)
		rl_vec_push(g->space_on, 0);
	if (!g->space_on.data[id]) {
		g->space_on.data[id] = 1;
		rl_vec_push(g->spaces, id);
	}
	return SL_GLSL_FMT(g, "space_%s", name);
}

/* ------------------------------------------------------------------------ */
/* Program analysis                                                          */

static int closer_of(const struct sl_insn *in)
{
	switch (in->op) {
	case SL_OP_IF: case SL_OP_LOOP:
		return in->jump[1];
	case SL_OP_FUNC: case SL_OP_ILLUMINANCE: case SL_OP_ILLUMINATE: case SL_OP_SOLAR:
		return in->jump[0];
	default:
		return -1;
	}
}

/* Does CALL @in write its argument @k? */
static bool call_writes_arg(const struct sl_insn *in, uint32_t k)
{
	if (in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins)
		return false;
	const char *sig = strchr(sl_builtins[in->bi].sig, ':');
	if (!sig)
		return false;
	sig++;
	for (uint32_t a = 0; *sig && *sig != '*'; a++, sig++) {
		bool out = *sig == '&';
		if (out)
			sig++;
		if (!*sig)
			break;
		if (a == k)
			return out;
	}
	return false;
}

/* Operand count and range checks the emitter relies on; NULL if fine. */
static const char *check_insn(const struct sl_program *prog, const struct sl_insn *in)
{
	if (in->op >= SL_OP_COUNT)
		return "unknown op";
	if (in->nargs && !in->args)
		return "missing argument list";
	if (in->dst < -1 || (in->dst >= 0 && (uint32_t)in->dst >= prog->nregs))
		return "bad destination register";
	for (uint32_t k = 0; k < in->nargs; k++)
		if (in->args[k] < 0 || (uint32_t)in->args[k] >= prog->nregs)
			return "bad argument register";
	static const int8_t nargs[SL_OP_COUNT] = {
		[SL_OP_MOV] = 1, [SL_OP_NEG] = 1, [SL_OP_ADD] = 2, [SL_OP_SUB] = 2,
		[SL_OP_MUL] = 2, [SL_OP_DIV] = 2, [SL_OP_DOT] = 2, [SL_OP_CROSS] = 2,
		[SL_OP_LT] = 2, [SL_OP_LE] = 2, [SL_OP_GT] = 2, [SL_OP_GE] = 2, [SL_OP_EQ] = 2,
		[SL_OP_NE] = 2, [SL_OP_NOT] = 1, [SL_OP_AND] = 2, [SL_OP_OR] = 2,
		[SL_OP_TRIPLE] = 3, [SL_OP_MATRIX] = 16, [SL_OP_COMP] = 1, [SL_OP_SETCOMP] = 1,
		[SL_OP_AREF] = 2, [SL_OP_ASET] = 2, [SL_OP_SELECT] = 3, [SL_OP_IF] = 1,
		[SL_OP_LOOPTEST] = 1,
	};
	if (nargs[in->op] && in->nargs != (uint16_t)nargs[in->op])
		return "wrong operand count";
	if (nargs[in->op] && in->op != SL_OP_IF && in->op != SL_OP_LOOPTEST && in->dst < 0)
		return "missing destination";
	if (in->op == SL_OP_COMP || in->op == SL_OP_SETCOMP) {
		int32_t v = in->op == SL_OP_COMP ? in->args[0] : in->dst;
		if (in->imm < 0 || in->imm >= sl_glsl_ncomp(prog, v))
			return "bad component";
	}
	if ((in->op == SL_OP_AREF && prog->regs[in->args[0]].arraylen <= 0) ||
	    (in->op == SL_OP_ASET && prog->regs[in->dst].arraylen <= 0))
		return "bad array access";
	if (in->op == SL_OP_CALL && (in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins))
		return "unknown built-in";
	if (in->op == SL_OP_ILLUMINANCE) {
		if (in->imm != 0 && in->imm != 1)
			return "bad category flag";
		if (in->nargs != (uint32_t)in->imm + 1 && in->nargs != (uint32_t)in->imm + 3)
			return "wrong operand count";
	}
	if (in->op == SL_OP_ILLUMINATE && in->nargs != 1 && in->nargs != 3)
		return "wrong operand count";
	if (in->op == SL_OP_SOLAR && in->nargs != 0 && in->nargs != 2)
		return "wrong operand count";
	return NULL;
}

struct open_block {
	uint32_t pc;
	uint8_t state;   /* IF: 1 after ELSE; LOOP: 0 condition, 1 body, 2 step */
};

/*
 * Check the body's nesting (every jump names its partner), resolve each
 * break, continue and return to the construct it leaves, and record per
 * construct the range of its exits.
 */
static bool analyze_structure(struct glsl_gen *g, struct glsl_prog *p)
{
	const struct sl_program *prog = p->prog;
	const struct sl_insn *code = prog->code;
	uint32_t n = prog->ncode, e = n;
	struct open_block *st = rl_xmalloc(((size_t)n + 1) * sizeof(*st));
	uint32_t depth = 0;
	const char *why = NULL;
	uint32_t pc;
	p->static_ambient = true;
	for (pc = prog->body_begin; pc < e && !why; pc++) {
		const struct sl_insn *in = &code[pc];
		why = check_insn(prog, in);
		if (why)
			break;
		const struct sl_insn *top = depth ? &code[st[depth - 1].pc] : NULL;
		uint32_t tpc = depth ? st[depth - 1].pc : 0;
		switch ((enum sl_op)in->op) {
		case SL_OP_IF:
			if (in->jump[0] <= (int32_t)pc || in->jump[1] < in->jump[0] ||
			    in->jump[1] >= (int32_t)e)
				why = "bad if jumps";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_ELSE:
			if (!top || top->op != SL_OP_IF || st[depth - 1].state ||
			    top->jump[0] != (int32_t)pc || in->jump[1] != top->jump[1])
				why = "else without its if";
			else
				st[depth - 1].state = 1;
			break;
		case SL_OP_ENDIF:
			if (!top || top->op != SL_OP_IF || top->jump[1] != (int32_t)pc ||
			    (!st[depth - 1].state && top->jump[0] != (int32_t)pc))
				why = "endif without its if";
			else
				depth--;
			break;
		case SL_OP_LOOP:
			if (in->jump[0] <= (int32_t)pc || in->jump[1] <= in->jump[0] ||
			    in->jump[1] >= (int32_t)e)
				why = "bad loop jumps";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_LOOPTEST:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state != 0 ||
			    top->jump[0] != (int32_t)pc)
				why = "looptest without its loop";
			else
				st[depth - 1].state = 1;
			break;
		case SL_OP_LOOPCONT:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state != 1)
				why = "loopcont without its loop";
			else {
				st[depth - 1].state = 2;
				p->loopcont[tpc] = pc;
			}
			break;
		case SL_OP_LOOPEND:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state == 0 ||
			    top->jump[1] != (int32_t)pc)
				why = "loopend without its loop";
			else
				depth--;
			break;
		case SL_OP_BREAK:
		case SL_OP_CONTINUE:
		case SL_OP_RETURN: {
			int32_t levels = in->imm;
			uint32_t k = depth;
			bool found = false;
			while (k-- > 0) {
				uint16_t op = code[st[k].pc].op;
				if (in->op == SL_OP_RETURN) {
					if (op == SL_OP_FUNC) {
						found = true;
						break;
					}
					continue;
				}
				if (op == SL_OP_FUNC)
					break;
				if ((op == SL_OP_LOOP || op == SL_OP_ILLUMINANCE) && --levels == 0) {
					found = true;
					break;
				}
			}
			if (!found || (in->op != SL_OP_RETURN && in->imm < 1)) {
				why = in->op == SL_OP_RETURN ? "return outside a function"
							     : "break or continue outside its loop";
				break;
			}
			uint32_t t = st[k].pc;
			p->target[pc] = (int32_t)t;
			p->exits[t] |= in->op == SL_OP_BREAK ? EXIT_BREAK :
				       in->op == SL_OP_CONTINUE ? EXIT_CONTINUE : EXIT_RETURN;
			if (p->exit_lo[t] == NONE || pc < p->exit_lo[t])
				p->exit_lo[t] = pc;
			if (p->exit_hi[t] == NONE || pc > p->exit_hi[t])
				p->exit_hi[t] = pc;
			break;
		}
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			p->static_ambient = false;
			/* fall through */
		case SL_OP_FUNC:
		case SL_OP_ILLUMINANCE:
			if (in->jump[0] <= (int32_t)pc || in->jump[0] >= (int32_t)e)
				why = "bad block jump";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_FUNCEND:
		case SL_OP_ILLUMINANCE_END:
		case SL_OP_ILLUMINATE_END:
		case SL_OP_SOLAR_END: {
			uint16_t want = in->op == SL_OP_FUNCEND ? SL_OP_FUNC :
					in->op == SL_OP_ILLUMINANCE_END ? SL_OP_ILLUMINANCE :
					in->op == SL_OP_ILLUMINATE_END ? SL_OP_ILLUMINATE : SL_OP_SOLAR;
			if (!top || top->op != want || top->jump[0] != (int32_t)pc)
				why = "block end without its opener";
			else
				depth--;
			break;
		}
		default:
			break;
		}
	}
	if (!why && depth)
		why = "block not closed";
	free(st);
	if (why) {
		struct glsl_prog *saved = g->cur;
		g->cur = p;
		sl_glsl_error(g, pc < n ? &code[pc] : NULL, "invalid program: instruction %u: %s",
			      pc, why);
		g->cur = saved;
		return false;
	}
	return true;
}

/* Names, compile-time strings and structure of @prog (light @light, or -1). */
static bool prepare(struct glsl_gen *g, struct glsl_prog *p, const struct sl_program *prog,
		    int light)
{
	memset(p, 0, sizeof(*p));
	p->prog = prog;
	p->light = light;
	if ((prog->nregs && !prog->regs) || (prog->ncode && !prog->code) ||
	    (prog->nparams && !prog->params) || prog->body_begin > prog->ncode) {
		g->cur = p;
		sl_glsl_error(g, NULL, "invalid program (missing tables)");
		return false;
	}
	uint32_t nr = prog->nregs, n = prog->ncode;
	p->name = rl_arena_alloc(g->arena, (nr + 1) * sizeof(*p->name));
	p->cstr = rl_arena_alloc(g->arena, (nr + 1) * sizeof(*p->cstr));
	p->target = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->target));
	p->exit_lo = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->exit_lo));
	p->exit_hi = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->exit_hi));
	p->exits = rl_arena_alloc(g->arena, n + 1);
	p->loopcont = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->loopcont));
	p->declared = rl_arena_alloc(g->arena, n + 1);
	/* Copies and map sites are known off stencils too: a light's
	 * environment() of four directions needs no derivative. */
	p->copy_of = rl_arena_alloc(g->arena, (nr + 1) * sizeof(*p->copy_of));
	p->site = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->site));
	p->msite = rl_arena_alloc(g->arena, (n + 1) * sizeof(*p->msite));
	for (uint32_t i = 0; i <= n; i++)
		p->site[i] = p->msite[i] = -1;
	if (g->stencil) {
		p->cls = rl_arena_alloc(g->arena, nr + 1);
		p->need = rl_arena_alloc(g->arena, nr + 1);
		p->mdecl = rl_arena_alloc(g->arena, nr + 1);
	}
	for (uint32_t i = 0; i <= n; i++) {
		p->target[i] = -1;
		p->exit_lo[i] = p->exit_hi[i] = NONE;
		p->loopcont[i] = NONE;
	}
	for (uint32_t r = 0; r < nr; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		bool bad = rg->type == SL_TYPE_VOID || rg->type >= SL_TYPE_COUNT || rg->arraylen < 0 ||
			   rg->arraylen > (1 << 20);
		if (!bad && rg->kind == SL_REG_CONST) {
			uint64_t tot = (uint64_t)(rg->arraylen > 0 ? rg->arraylen : 1) *
				       (uint64_t)(rg->type == SL_TYPE_STRING ? 1 : sl_reg_ncomp(rg));
			uint64_t end = (uint64_t)rg->cindex + tot;
			bad = rg->type == SL_TYPE_STRING ? (!prog->strings || end > prog->nstrings)
							 : (!prog->consts || end > prog->nconsts);
		}
		if (bad) {
			g->cur = p;
			sl_glsl_error(g, NULL, "invalid program: register %u", r);
			return false;
		}
		if (rg->kind == SL_REG_CONST)
			continue;
		struct rl_strbuf b = { 0 };
		if (light >= 0)
			rl_strbuf_printf(&b, "l%dr%u", light, r);
		else
			rl_strbuf_printf(&b, "r%u", r);
		if (rg->name) {
			rl_strbuf_putc(&b, '_');
			put_sanitized(&b, rg->name);
		}
		p->name[r] = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
		rl_strbuf_finish(&b);
	}
	for (int gl = 0; gl < SL_GLOBAL_COUNT; gl++) {
		int32_t r = prog->global_reg[gl];
		if (r != -1 && (r < 0 || (uint32_t)r >= nr || sl_reg_ncomp(&prog->regs[r]) < 1 ||
				prog->regs[r].arraylen)) {
			g->cur = p;
			sl_glsl_error(g, NULL, "invalid program: bad register for global %d", gl);
			return false;
		}
	}
	for (uint32_t k = 0; k < prog->nparams; k++) {
		const struct sl_param *pp = &prog->params[k];
		if (!pp->name || pp->reg < 0 || (uint32_t)pp->reg >= nr) {
			g->cur = p;
			sl_glsl_error(g, NULL, "invalid program: parameter %u", k);
			return false;
		}
	}
	/* Strings known at compile time: constants, and registers whose one write copies one. */
	uint32_t *writes = rl_xcalloc(nr + 1, sizeof(uint32_t));
	int32_t *src = rl_xcalloc(nr + 1, sizeof(int32_t));
	for (uint32_t pc = 0; pc < n; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (check_insn(prog, in))
			continue;
		if (in->dst >= 0) {
			writes[in->dst]++;
			src[in->dst] = in->op == SL_OP_MOV ? in->args[0] : -1;
		}
		if (in->op == SL_OP_CALL)
			for (uint32_t k = 0; k < in->nargs; k++)
				if (call_writes_arg(in, k))
					writes[in->args[k]] += 2;
	}
	for (uint32_t r = 0; p->copy_of && r < nr; r++)
		p->copy_of[r] = writes[r] == 1 && prog->regs[r].kind != SL_REG_CONST ? src[r] : -1;
	for (uint32_t r = 0; r < nr; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		if (rg->type != SL_TYPE_STRING || rg->arraylen)
			continue;
		int32_t c = -1;
		if (rg->kind == SL_REG_CONST)
			c = (int32_t)r;
		else if ((rg->kind == SL_REG_TEMP || rg->kind == SL_REG_LOCAL) && writes[r] == 1 &&
			 src[r] >= 0 && prog->regs[src[r]].kind == SL_REG_CONST &&
			 prog->regs[src[r]].type == SL_TYPE_STRING && !prog->regs[src[r]].arraylen)
			c = src[r];
		if (c >= 0) {
			const char *s = prog->strings[prog->regs[c].cindex];
			p->cstr[r] = s ? s : "";
		}
	}
	free(writes);
	free(src);
	return analyze_structure(g, p);
}

/* ------------------------------------------------------------------------ */
/* Code                                                                      */

static bool kept(const struct glsl_gen *g, uint32_t pc)
{
	return g->cur->light >= 0 || !g->slice->keep || g->slice->keep[pc];
}

static void push_construct(struct glsl_gen *g, uint32_t pc)
{
	if (g->nstack == g->maxstack) {
		g->maxstack = g->maxstack ? 2 * g->maxstack : 16;
		g->stack = rl_xrealloc(g->stack, g->maxstack * sizeof(*g->stack));
	}
	g->stack[g->nstack++] = (int32_t)pc;
}

static const char *flag_name(struct glsl_gen *g, uint32_t pc)
{
	if (g->cur->light >= 0)
		return SL_GLSL_FMT(g, "xl%d_%u", g->cur->light, pc);
	return SL_GLSL_FMT(g, "x%u", pc);
}

static const char *local_name(struct glsl_gen *g, const char *what, uint32_t pc)
{
	if (g->cur->light >= 0)
		return SL_GLSL_FMT(g, "%sl%d_%u", what, g->cur->light, pc);
	return SL_GLSL_FMT(g, "%s%u", what, pc);
}

/*
 * Declare a per-invocation variable in the globals section, once: an
 * illuminance body is emitted once per light, its constructs as often.
 */
static void declare(struct glsl_gen *g, uint32_t pc, uint8_t bit, const char *type,
		    const char *name, const char *init)
{
	if (g->cur->declared[pc] & bit)
		return;
	g->cur->declared[pc] |= bit;
	rl_strbuf_printf(&g->sec[GS_GLOBALS], "%s %s = %s;\n", type, name, init);
}

/*
 * After a construct spanning [co, cc] closes: leave the enclosing GLSL loop
 * too when an exit to a construct further out is under way.
 */
static void emit_propagate(struct glsl_gen *g, uint32_t co, uint32_t cc)
{
	const struct glsl_prog *p = g->cur;
	struct rl_strbuf cond = { 0 };
	for (uint32_t k = g->nstack; k-- > 0;) {
		uint32_t t = (uint32_t)g->stack[k];
		if (t >= co)
			continue;
		if (p->exits[t] && p->exit_lo[t] <= cc && p->exit_hi[t] >= co) {
			if (cond.len)
				rl_strbuf_puts(&cond, " || ");
			rl_strbuf_printf(&cond, "%s != 0", flag_name(g, t));
		}
		/* Nothing leaves a function but its returns. */
		if (p->prog->code[t].op == SL_OP_FUNC)
			break;
	}
	if (cond.len)
		sl_glsl_line(g, "if (%s) break;", rl_strbuf_str(&cond));
	rl_strbuf_finish(&cond);
}

/* Do exits of constructs outside [co, cc] pass through it? */
static bool crossed(const struct glsl_gen *g, uint32_t co, uint32_t cc)
{
	const struct glsl_prog *p = g->cur;
	for (uint32_t k = g->nstack; k-- > 0;) {
		uint32_t t = (uint32_t)g->stack[k];
		if (t >= co)
			continue;
		if (p->exits[t] && p->exit_lo[t] <= cc && p->exit_hi[t] >= co)
			return true;
		if (p->prog->code[t].op == SL_OP_FUNC)
			break;
	}
	return false;
}

static void emit_range(struct glsl_gen *g, uint32_t b, uint32_t e);

static void emit_insn(struct glsl_gen *g, const struct sl_insn *in);

static void emit_moved(struct glsl_gen *g, const struct sl_insn *in);

static void emit_if(struct glsl_gen *g, uint32_t pc)
{
	const struct sl_insn *in = &g->cur->prog->code[pc];
	uint32_t els = (uint32_t)in->jump[0], end = (uint32_t)in->jump[1];
	sl_glsl_line(g, "if (%s != 0.0) {", sl_glsl_op(g, in->args[0], 1));
	g->indent++;
	emit_range(g, pc + 1, els);
	g->indent--;
	if (els != end) {
		sl_glsl_line(g, "} else {");
		g->indent++;
		emit_range(g, els + 1, end);
		g->indent--;
	}
	sl_glsl_line(g, "}");
}

static void emit_loop(struct glsl_gen *g, uint32_t pc)
{
	const struct glsl_prog *p = g->cur;
	const struct sl_insn *in = &p->prog->code[pc];
	uint32_t test = (uint32_t)in->jump[0], end = (uint32_t)in->jump[1];
	uint32_t cont = p->loopcont[pc];
	const struct sl_insn *ti = &p->prog->code[test];
	const char *x = flag_name(g, pc), *cnt = local_name(g, "n", pc);
	bool wrap = p->exits[pc] || crossed(g, pc, end);
	declare(g, pc, 1, "uint", cnt, "0u");
	if (p->exits[pc]) {
		declare(g, pc, 2, "int", x, "0");
		sl_glsl_line(g, "%s = 0;", x);
	}
	sl_glsl_line(g, "%s = 0u;", cnt);
	sl_glsl_line(g, "while (true) {");
	g->indent++;
	emit_range(g, pc + 1, test);
	sl_glsl_line(g, "if (%s == 0.0) break;", sl_glsl_op(g, ti->args[0], 1));
	sl_glsl_line(g, "if (++%s > %uu) break;", cnt, MAX_LOOP_ITERS);
	push_construct(g, pc);
	sl_glsl_line(g, wrap ? "do {" : "{");
	g->indent++;
	emit_range(g, test + 1, cont != NONE ? cont : end);
	g->indent--;
	sl_glsl_line(g, wrap ? "} while (false);" : "}");
	g->nstack--;
	emit_propagate(g, pc, end);
	if (p->exits[pc] & EXIT_BREAK)
		sl_glsl_line(g, "if (%s == 1) break;", x);
	if (p->exits[pc] & EXIT_CONTINUE)
		sl_glsl_line(g, "%s = 0;", x);
	if (cont != NONE)
		emit_range(g, cont + 1, end);
	g->indent--;
	sl_glsl_line(g, "}");
	emit_propagate(g, pc, end);
}

static void emit_func(struct glsl_gen *g, uint32_t pc)
{
	const struct glsl_prog *p = g->cur;
	uint32_t end = (uint32_t)p->prog->code[pc].jump[0];
	bool ret = (p->exits[pc] & EXIT_RETURN) != 0;
	if (ret) {
		const char *x = flag_name(g, pc);
		declare(g, pc, 2, "int", x, "0");
		sl_glsl_line(g, "%s = 0;", x);
	}
	push_construct(g, pc);
	sl_glsl_line(g, ret ? "do {" : "{");
	g->indent++;
	emit_range(g, pc + 1, end);
	g->indent--;
	sl_glsl_line(g, ret ? "} while (false);" : "}");
	g->nstack--;
}

static void emit_exit(struct glsl_gen *g, uint32_t pc)
{
	const struct sl_insn *in = &g->cur->prog->code[pc];
	int v = in->op == SL_OP_CONTINUE ? 2 : 1;
	sl_glsl_line(g, "%s = %d;", flag_name(g, (uint32_t)g->cur->target[pc]), v);
	sl_glsl_line(g, "break;");
}

/*
 * The test selecting light @k for an illuminance of category @cat: "" for
 * always, NULL for never, else a condition on the light's __category id.
 */
static const char *category_test(struct glsl_gen *g, const char *cat, int k)
{
	if (!cat)
		return "";
	const struct sl_program *lp = g->lights[k];
	int pk = sl_program_find_param(lp, "__category");
	const struct sl_reg *rg = pk >= 0 ? &lp->regs[lp->params[pk].reg] : NULL;
	if (!rg || rg->type != SL_TYPE_STRING || rg->arraylen)
		return sl_category_match(cat, "") ? "" : NULL;
	char uname[64];
	sl_glsl_param_uniform(uname, sizeof(uname), (int)k, "__category");
	const char *u = SL_GLSL_FMT(g, "%s", uname);
	struct rl_strbuf b = { 0 };
	size_t nmatch = 0;
	for (size_t i = 0; i < g->strings.len; i++) {
		if (!sl_category_match(cat, g->strings.data[i]))
			continue;
		rl_strbuf_printf(&b, "%s%s == %zu.0", nmatch ? " || " : "", u, i);
		nmatch++;
	}
	/* A value the table does not hold (any id past it) is a name no term can equal. */
	bool unknown = sl_category_match(cat, "\x1f");
	if (unknown)
		rl_strbuf_printf(&b, "%s%s >= %zu.0", nmatch ? " || " : "", u, g->strings.len);
	const char *r = NULL;
	if (unknown && nmatch == g->strings.len)
		r = "";
	else if (b.len)
		r = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return r;
}

static void emit_illuminance(struct glsl_gen *g, uint32_t pc)
{
	const struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	const struct sl_insn *in = &prog->code[pc];
	uint32_t end = (uint32_t)in->jump[0];
	if (p->light >= 0) {
		sl_glsl_error(g, in, "illuminance in a light shader is not supported on the GPU");
		return;
	}
	uint32_t k = (uint32_t)in->imm;
	const char *cat = NULL;
	if (k) {
		cat = sl_glsl_cstr(g, in->args[0]);
		if (!cat) {
			sl_glsl_error(g, in, "illuminance categories must be constant strings on the "
				      "GPU");
			return;
		}
	}
	bool cone = in->nargs == k + 3;
	const char *P = local_name(g, "iP", pc), *A = local_name(g, "iA", pc),
		   *N = local_name(g, "iN", pc), *x = flag_name(g, pc);
	/* Position, axis and angle as they were on entry, for every light. */
	declare(g, pc, 4, "vec3", P, "vec3(0.0)");
	sl_glsl_line(g, "%s = %s;", P, sl_glsl_op(g, in->args[k], 3));
	const char *Pu = local_name(g, "iPu", pc), *Pv = local_name(g, "iPv", pc);
	if (g->any_moved_ps) {
		declare(g, pc, 64, "vec3", Pu, "vec3(0.0)");
		declare(g, pc, 128, "vec3", Pv, "vec3(0.0)");
		sl_glsl_line(g, "%s = %s;", Pu, sl_glsl_moved(g, in->args[k], 3, 1));
		sl_glsl_line(g, "%s = %s;", Pv, sl_glsl_moved(g, in->args[k], 3, 2));
	}
	/* The lights' Ns: the cone's axis, else the surface's N (the light host's rule). */
	int32_t Nr = prog->global_reg[SL_GLOBAL_N];
	const char *Ns = cone ? A : Nr >= 0 ? local_name(g, "iNs", pc) : "vec3(0.0)";
	if (cone) {
		declare(g, pc, 8, "vec3", A, "vec3(0.0)");
		declare(g, pc, 16, "float", N, "0.0");
		sl_glsl_line(g, "%s = %s;", A, sl_glsl_op(g, in->args[k + 1], 3));
		sl_glsl_line(g, "%s = %s;", N, sl_glsl_op(g, in->args[k + 2], 1));
		sl_glsl_need(g, GH_CONE);
	} else if (Nr >= 0) {
		declare(g, pc, 8, "vec3", Ns, "vec3(0.0)");
		sl_glsl_line(g, "%s = %s;", Ns, sl_glsl_op(g, Nr, 3));
	}
	bool wrap = p->exits[pc] || crossed(g, pc, end);
	if (p->exits[pc]) {
		declare(g, pc, 2, "int", x, "0");
		sl_glsl_line(g, "%s = 0;", x);
	}
	sl_glsl_line(g, wrap ? "do {" : "{");
	g->indent++;
	push_construct(g, pc);
	int saved = g->cur_light;
	int32_t Lr = prog->global_reg[SL_GLOBAL_L], Clr = prog->global_reg[SL_GLOBAL_CL],
		Olr = prog->global_reg[SL_GLOBAL_OL];
	for (uint32_t j = 0; j < g->nlights && !g->failed; j++) {
		if (g->lp[j].static_ambient)
			continue;
		const char *test = category_test(g, cat, (int)j);
		if (!test)
			continue;
		sl_glsl_line(g, "/* light %u */", j);
		if (g->slice->per_light)
			test = *test ? SL_GLSL_FMT(g, "rl_only == %u && (%s)", j, test)
				     : SL_GLSL_FMT(g, "rl_only == %u", j);
		if (*test) {
			sl_glsl_line(g, "if (%s) {", test);
			g->indent++;
		}
		if (g->lp[j].moved_ps)
			sl_glsl_line(g, "light_%u(%s, %s, %s, %s);", j, P, Ns, Pu, Pv);
		else
			sl_glsl_line(g, "light_%u(%s, %s);", j, P, Ns);
		sl_glsl_line(g, "if (!rl_amb) {");
		g->indent++;
		if (Lr >= 0)
			sl_glsl_line(g, "%s = rl_L;", p->name[Lr]);
		if (Clr >= 0)
			sl_glsl_line(g, "%s = rl_Cl;", p->name[Clr]);
		if (Olr >= 0)
			sl_glsl_line(g, "%s = rl_Ol;", p->name[Olr]);
		if (cone)
			sl_glsl_line(g, "if (rl_lit && rl_in_cone(rl_L, %s, %s)) {", A, N);
		else
			sl_glsl_line(g, "if (rl_lit) {");
		g->indent++;
		g->cur_light = (int)j;
		sl_glsl_line(g, wrap ? "do {" : "{");
		g->indent++;
		emit_range(g, pc + 1, end);
		g->indent--;
		sl_glsl_line(g, wrap ? "} while (false);" : "}");
		g->cur_light = saved;
		emit_propagate(g, pc, end);
		if (p->exits[pc] & EXIT_BREAK)
			sl_glsl_line(g, "if (%s == 1) break;", x);
		if (p->exits[pc] & EXIT_CONTINUE)
			sl_glsl_line(g, "%s = 0;", x);
		g->indent--;
		sl_glsl_line(g, "}");
		g->indent--;
		sl_glsl_line(g, "}");
		if (*test) {
			g->indent--;
			sl_glsl_line(g, "}");
		}
	}
	g->nstack--;
	g->indent--;
	sl_glsl_line(g, wrap ? "} while (false);" : "}");
	emit_propagate(g, pc, end);
}

/* ILLUMINATE and SOLAR in a light shader. */
static void emit_emit(struct glsl_gen *g, uint32_t pc)
{
	const struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	const struct sl_insn *in = &prog->code[pc];
	uint32_t end = (uint32_t)in->jump[0];
	bool solar = in->op == SL_OP_SOLAR;
	if (p->light < 0) {
		sl_glsl_error(g, in, "%s outside a light shader", solar ? "solar" : "illuminate");
		return;
	}
	int32_t Lr = prog->global_reg[SL_GLOBAL_L], Psr = prog->global_reg[SL_GLOBAL_PS];
	int32_t Nsr = prog->global_reg[SL_GLOBAL_NS];
	const char *Lv = local_name(g, "eL", pc);
	declare(g, pc, 32, "vec3", Lv, "vec3(0.0)");
	/* solar() without arguments: from every direction, L = -Ns (exec.c, op_solar_all). */
	if (solar && in->nargs == 0)
		sl_glsl_line(g, "%s = %s;", Lv, Nsr >= 0 ? SL_GLSL_FMT(g, "-%s", p->name[Nsr])
							 : "vec3(0.0)");
	else if (solar)
		sl_glsl_line(g, "%s = %s;", Lv, sl_glsl_op(g, in->args[0], 3));
	else
		sl_glsl_line(g, "%s = rl_c(%s - %s);", Lv, Psr >= 0 ? p->name[Psr] : "vec3(0.0)",
			     sl_glsl_op(g, in->args[0], 3));
	if (Lr >= 0)
		sl_glsl_line(g, "%s = %s;", p->name[Lr], Lv);
	sl_glsl_line(g, "rl_amb = false;");
	if (!solar && in->nargs == 3) {
		sl_glsl_need(g, GH_CONE);
		sl_glsl_line(g, "if (rl_in_cone(%s, %s, %s)) {", Lv, sl_glsl_op(g, in->args[1], 3),
			     sl_glsl_op(g, in->args[2], 1));
	} else {
		sl_glsl_line(g, "{");
	}
	g->indent++;
	sl_glsl_line(g, "rl_lit = true;");
	emit_range(g, pc + 1, end);
	g->indent--;
	sl_glsl_line(g, "}");
}

/* The code of [b, e), a properly nested range of the current program. */
static void emit_range(struct glsl_gen *g, uint32_t b, uint32_t e)
{
	const struct sl_program *prog = g->cur->prog;
	for (uint32_t pc = b; pc < e && !g->failed;) {
		const struct sl_insn *in = &prog->code[pc];
		int close = closer_of(in);
		if (!kept(g, pc)) {
			pc = close >= 0 ? (uint32_t)close + 1 : pc + 1;
			continue;
		}
		switch ((enum sl_op)in->op) {
		case SL_OP_IF:
			emit_if(g, pc);
			break;
		case SL_OP_LOOP:
			emit_loop(g, pc);
			break;
		case SL_OP_FUNC:
			emit_func(g, pc);
			break;
		case SL_OP_ILLUMINANCE:
			emit_illuminance(g, pc);
			break;
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			emit_emit(g, pc);
			break;
		case SL_OP_BREAK:
		case SL_OP_CONTINUE:
		case SL_OP_RETURN:
			emit_exit(g, pc);
			break;
		case SL_OP_NOP:
			break;
		case SL_OP_ELSE: case SL_OP_ENDIF: case SL_OP_LOOPTEST: case SL_OP_LOOPCONT:
		case SL_OP_LOOPEND: case SL_OP_FUNCEND: case SL_OP_ILLUMINANCE_END:
		case SL_OP_ILLUMINATE_END: case SL_OP_SOLAR_END:
			/* Closers are consumed by their openers; the structure check saw to it. */
			break;
		default:
			emit_insn(g, in);
			if (g->stencil)
				emit_moved(g, in);
			break;
		}
		pc = close >= 0 ? (uint32_t)close + 1 : pc + 1;
	}
}

/* ------------------------------------------------------------------------ */
/* Instructions                                                              */

static void assign(struct glsl_gen *g, const struct sl_insn *in, const char *expr)
{
	const char *d = sl_glsl_lv(g, in->dst);
	if (!d) {
		sl_glsl_error(g, in, "invalid program: write to a constant");
		return;
	}
	sl_glsl_line(g, "%s = %s;", d, expr);
}

static void emit_arith(struct glsl_gen *g, const struct sl_insn *in)
{
	const struct sl_program *prog = g->cur->prog;
	int32_t d = in->dst, a = in->args[0], b = in->nargs > 1 ? in->args[1] : a;
	int nd = sl_glsl_ncomp(prog, d), na = sl_glsl_ncomp(prog, a), nb = sl_glsl_ncomp(prog, b);
	const char *e;
	if (in->op == SL_OP_NEG) {
		assign(g, in, SL_GLSL_FMT(g, "-%s", sl_glsl_op(g, a, nd == 16 ? -16 : nd)));
		return;
	}
	if (in->op == SL_OP_DIV) {
		if (nd == 16 && na == 16 && nb == 16) {
			sl_glsl_need(g, GH_MATDIV);
			e = SL_GLSL_FMT(g, "rl_matdiv(%s, %s)", sl_glsl_op(g, a, 0),
					sl_glsl_op(g, b, 0));
		} else {
			int w = nd == 16 ? -16 : nd;
			e = SL_GLSL_FMT(g, "rl_div(%s, %s)", sl_glsl_op(g, a, w), sl_glsl_op(g, b, w));
		}
		assign(g, in, e);
		return;
	}
	if (in->op == SL_OP_MUL && na == 16 && nb == 16) {
		assign(g, in, SL_GLSL_FMT(g, "rl_c(%s * %s)", sl_glsl_op(g, b, 0),
					  sl_glsl_op(g, a, 0)));
		return;
	}
	const char *sym = in->op == SL_OP_ADD ? "+" : in->op == SL_OP_SUB ? "-" : "*";
	/* Scalars combine with vectors and matrices componentwise in GLSL as in RSL. */
	e = SL_GLSL_FMT(g, "rl_c(%s %s %s)", sl_glsl_op(g, a, 0), sym, sl_glsl_op(g, b, 0));
	if (na == 1 && nb == 1 && nd == 3)
		e = SL_GLSL_FMT(g, "vec3(%s)", e);
	else if (na == 1 && nb == 1 && nd == 16)
		e = SL_GLSL_FMT(g, "rl_fill(%s)", e);
	assign(g, in, e);
}

static void emit_eq(struct glsl_gen *g, const struct sl_insn *in)
{
	const struct sl_program *prog = g->cur->prog;
	int32_t a = in->args[0], b = in->args[1];
	const char *sym = in->op == SL_OP_EQ ? "==" : "!=";
	int na = sl_glsl_ncomp(prog, a), nb = sl_glsl_ncomp(prog, b);
	if (prog->regs[a].arraylen || prog->regs[b].arraylen ||
	    (prog->regs[a].type == SL_TYPE_STRING) != (prog->regs[b].type == SL_TYPE_STRING)) {
		sl_glsl_error(g, in, "invalid program: bad comparison");
		return;
	}
	int w = na == 16 || nb == 16 ? -16 : na > nb ? na : nb;
	assign(g, in, SL_GLSL_FMT(g, "float(%s %s %s)", sl_glsl_op(g, a, w), sym,
				  sl_glsl_op(g, b, w)));
}

static void emit_select(struct glsl_gen *g, const struct sl_insn *in)
{
	const struct sl_program *prog = g->cur->prog;
	int32_t d = in->dst;
	const char *dn = sl_glsl_lv(g, d);
	if (!dn) {
		sl_glsl_error(g, in, "invalid program: write to a constant");
		return;
	}
	int nd = sl_glsl_ncomp(prog, d);
	int w = prog->regs[d].arraylen ? 0 : nd == 16 ? -16 : nd;
	sl_glsl_line(g, "if (%s != 0.0) %s = %s; else %s = %s;", sl_glsl_op(g, in->args[0], 1), dn,
		     sl_glsl_op(g, in->args[1], w), dn, sl_glsl_op(g, in->args[2], w));
}

static void emit_insn(struct glsl_gen *g, const struct sl_insn *in)
{
	const struct sl_program *prog = g->cur->prog;
	int32_t d = in->dst;
	const int32_t *a = in->args;
	switch ((enum sl_op)in->op) {
	case SL_OP_MOV: {
		if (a[0] == d)
			return;
		int nd = sl_glsl_ncomp(prog, d);
		assign(g, in, sl_glsl_op(g, a[0], prog->regs[d].arraylen ? 0 : nd));
		return;
	}
	case SL_OP_NEG: case SL_OP_ADD: case SL_OP_SUB: case SL_OP_MUL: case SL_OP_DIV:
		emit_arith(g, in);
		return;
	case SL_OP_DOT:
		assign(g, in, SL_GLSL_FMT(g, "rl_c(dot(%s, %s))", sl_glsl_op(g, a[0], 3),
					  sl_glsl_op(g, a[1], 3)));
		return;
	case SL_OP_CROSS:
		assign(g, in, SL_GLSL_FMT(g, "rl_c(cross(%s, %s))", sl_glsl_op(g, a[0], 3),
					  sl_glsl_op(g, a[1], 3)));
		return;
	case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE: {
		static const char *const sym[] = { "<", "<=", ">", ">=" };
		assign(g, in, SL_GLSL_FMT(g, "float(%s %s %s)", sl_glsl_op(g, a[0], 1),
					  sym[in->op - SL_OP_LT], sl_glsl_op(g, a[1], 1)));
		return;
	}
	case SL_OP_EQ: case SL_OP_NE:
		emit_eq(g, in);
		return;
	case SL_OP_NOT:
		assign(g, in, SL_GLSL_FMT(g, "float(%s == 0.0)", sl_glsl_op(g, a[0], 1)));
		return;
	case SL_OP_AND: case SL_OP_OR:
		assign(g, in, SL_GLSL_FMT(g, "float(%s != 0.0 %s %s != 0.0)", sl_glsl_op(g, a[0], 1),
					  in->op == SL_OP_AND ? "&&" : "||", sl_glsl_op(g, a[1], 1)));
		return;
	case SL_OP_TRIPLE: case SL_OP_MATRIX: {
		struct rl_strbuf b = { 0 };
		rl_strbuf_puts(&b, in->op == SL_OP_TRIPLE ? "vec3(" : "mat4(");
		for (uint32_t k = 0; k < in->nargs; k++) {
			if (k)
				rl_strbuf_puts(&b, ", ");
			rl_strbuf_puts(&b, sl_glsl_op(g, a[k], 1));
		}
		rl_strbuf_putc(&b, ')');
		assign(g, in, rl_arena_strdup(g->arena, rl_strbuf_str(&b)));
		rl_strbuf_finish(&b);
		return;
	}
	case SL_OP_COMP: {
		int nc = sl_glsl_ncomp(prog, a[0]);
		const char *v = sl_glsl_op(g, a[0], 0);
		if (nc == 16)
			v = SL_GLSL_FMT(g, "%s[%d][%d]", v, in->imm / 4, in->imm % 4);
		else if (nc == 3)
			v = SL_GLSL_FMT(g, "%s[%d]", v, in->imm);
		assign(g, in, v);
		return;
	}
	case SL_OP_SETCOMP: {
		int nc = sl_glsl_ncomp(prog, d);
		const char *dn = sl_glsl_lv(g, d);
		if (!dn) {
			sl_glsl_error(g, in, "invalid program: write to a constant");
			return;
		}
		if (nc == 16)
			dn = SL_GLSL_FMT(g, "%s[%d][%d]", dn, in->imm / 4, in->imm % 4);
		else if (nc == 3)
			dn = SL_GLSL_FMT(g, "%s[%d]", dn, in->imm);
		sl_glsl_line(g, "%s = %s;", dn, sl_glsl_op(g, a[0], 1));
		return;
	}
	case SL_OP_AREF:
		sl_glsl_need(g, GH_AIDX);
		assign(g, in, SL_GLSL_FMT(g, "%s[rl_aidx(%s, %d)]", sl_glsl_op(g, a[0], 0),
					  sl_glsl_op(g, a[1], 1), prog->regs[a[0]].arraylen));
		return;
	case SL_OP_ASET: {
		const char *dn = sl_glsl_lv(g, d);
		if (!dn) {
			sl_glsl_error(g, in, "invalid program: write to a constant");
			return;
		}
		sl_glsl_need(g, GH_AIDX);
		sl_glsl_line(g, "%s[rl_aidx(%s, %d)] = %s;", dn, sl_glsl_op(g, a[1], 1),
			     prog->regs[d].arraylen, sl_glsl_op(g, a[0], 0));
		return;
	}
	case SL_OP_SELECT:
		emit_select(g, in);
		return;
	case SL_OP_CALL:
		sl_glsl_call(g, in);
		return;
	default:
		sl_glsl_error(g, in, "invalid program: unexpected %s", sl_op_name(in->op));
		return;
	}
}

/* ------------------------------------------------------------------------ */
/* Programs                                                                  */

/* Per-invocation variables for every register of the current program. */
/*
 * Which temporaries and locals the emitted code names: those of the kept
 * instructions and of the parameter defaults. A production shader's dynamic
 * part is a small slice of it, and declaring all of its registers made the
 * kernel as long as the whole shader.
 */
static uint8_t *used_registers(struct glsl_gen *g)
{
	const struct sl_program *prog = g->cur->prog;
	uint8_t *used = rl_arena_alloc(g->arena, prog->nregs + 1);
	memset(used, 0, prog->nregs + 1);
	for (uint32_t pc = 0; pc < prog->ncode; pc++) {
		if (pc >= prog->body_begin && !kept(g, pc))
			continue;
		const struct sl_insn *in = &prog->code[pc];
		if (in->dst >= 0 && (uint32_t)in->dst < prog->nregs)
			used[in->dst] = 1;
		for (uint32_t k = 0; k < in->nargs; k++)
			if (in->args[k] >= 0 && (uint32_t)in->args[k] < prog->nregs)
				used[in->args[k]] = 1;
	}
	return used;
}

/* Is register @r declared in the GLSL (see used_registers)? */
static bool declared_reg(const struct glsl_prog *p, int32_t r)
{
	const struct sl_reg *rg = &p->prog->regs[r];
	if (rg->kind != SL_REG_TEMP && rg->kind != SL_REG_LOCAL)
		return true;
	return !p->decl || p->decl[r];
}

static void declare_registers(struct glsl_gen *g)
{
	const struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	struct rl_strbuf *b = &g->sec[GS_GLOBALS];
	uint8_t *used = used_registers(g);
	g->cur->decl = used;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		if (rg->kind == SL_REG_CONST)
			continue;
		if (!declared_reg(g->cur, (int32_t)r))
			continue;
		int nc = sl_glsl_ncomp(prog, (int32_t)r);
		if (rg->arraylen) {
			rl_strbuf_printf(b, "%s %s[%d];\n", type_name(nc), p->name[r], rg->arraylen);
			continue;
		}
		rl_strbuf_printf(b, "%s %s = %s;\n", type_name(nc), p->name[r],
				 reg_init(p, (int32_t)r));
	}
}

/* Zero the arrays of the current program (scalars are zero from their declarations). */
static void zero_arrays(struct glsl_gen *g)
{
	struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		if (rg->kind == SL_REG_CONST || !rg->arraylen || !declared_reg(p, (int32_t)r))
			continue;
		sl_glsl_line(g, "for (int k = 0; k < %d; k++) %s[k] = %s;", rg->arraylen, p->name[r],
			     zero_of(sl_glsl_ncomp(prog, (int32_t)r)));
		for (int dir = 1; p->need && p->need[r] && dir <= 2; dir++)
			sl_glsl_line(g, "for (int k = 0; k < %d; k++) %s[k] = %s;", rg->arraylen,
				     moved_name(g, g->cur, (int32_t)r, dir),
				     zero_of(sl_glsl_ncomp(prog, (int32_t)r)));
	}
}

void sl_glsl_param_uniform(char *out, size_t cap, int light, const char *name)
{
	char head[16];
	if (light >= 0)
		snprintf(head, sizeof(head), "l%d", light);
	else
		snprintf(head, sizeof(head), "p");
	if (name[0] != '_' && !strstr(name, "__")) {
		snprintf(out, cap, "%s_%s", head, name);
		return;
	}
	size_t n = (size_t)snprintf(out, cap, "%sU", head);
	for (const char *c = name; *c && n + 3 < cap; c++) {
		out[n++] = *c;
		if (*c == '_')
			out[n++] = '0';
	}
	if (n < cap)
		out[n] = '\0';
}

/* The uniform holding parameter @k of the current program. */
static const char *param_uniform(struct glsl_gen *g, uint32_t k)
{
	const struct glsl_prog *p = g->cur;
	char name[320];
	sl_glsl_param_uniform(name, sizeof(name), p->light, p->prog->params[k].name);
	return SL_GLSL_FMT(g, "%s", name);
}

/* Declare the uniforms of the current program's parameters (but @skip) and copy them in. */
static void load_params(struct glsl_gen *g, const uint8_t *skip)
{
	const struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	for (uint32_t k = 0; k < prog->nparams; k++) {
		int32_t r = prog->params[k].reg;
		const struct sl_reg *rg = &prog->regs[r];
		if ((skip && skip[r]) || rg->kind == SL_REG_CONST)
			continue;
		const char *name = prog->params[k].name;
		if (!is_ident(name)) {
			sl_glsl_error(g, NULL, "parameter '%s' cannot be named in GLSL", name);
			continue;
		}
		if (p->light >= 0 && !strcmp(name, "shader")) {
			sl_glsl_error(g, NULL, "a light parameter named 'shader' collides with the "
				      "light's coordinate system uniform");
			continue;
		}
		const char *u = param_uniform(g, k);
		int nc = sl_glsl_ncomp(prog, r);
		if (rg->arraylen)
			rl_strbuf_printf(&g->sec[GS_UNIFORMS], "uniform %s %s[%d];\n", type_name(nc), u,
					 rg->arraylen);
		else
			rl_strbuf_printf(&g->sec[GS_UNIFORMS], "uniform %s %s;\n", type_name(nc), u);
		sl_glsl_line(g, "%s = %s;", p->name[r], u);
	}
}

/* light_k(): the whole light shader, from a surface position to L, Cl, Ol, lit. */
static void emit_light(struct glsl_gen *g, uint32_t k)
{
	struct glsl_prog *p = &g->lp[k];
	const struct sl_program *prog = p->prog;
	g->cur = p;
	g->cur_light = -1;
	g->nstack = 0;
	g->out = &g->sec[GS_LIGHTS];
	g->indent = 0;
	declare_registers(g);
	rl_strbuf_printf(&g->sec[GS_UNIFORMS], "uniform mat4 l%u_shader;\n", k);
	sl_glsl_line(g, "/* light %u: %s */", k, prog->name ? prog->name : "?");
	if (p->moved_ps)
		sl_glsl_line(g, "void light_%u(vec3 rl_Ps, vec3 rl_Ns, vec3 rl_Psu, vec3 rl_Psv) {",
			     k);
	else
		sl_glsl_line(g, "void light_%u(vec3 rl_Ps, vec3 rl_Ns) {", k);
	g->indent++;
	load_params(g, NULL);
	const int32_t *gr = prog->global_reg;
	static const int zeroed[] = { SL_GLOBAL_L, SL_GLOBAL_CL, SL_GLOBAL_OL };
	for (size_t i = 0; i < sizeof(zeroed) / sizeof(zeroed[0]); i++) {
		int32_t r = gr[zeroed[i]];
		if (r < 0)
			continue;
		sl_glsl_line(g, "%s = vec3(0.0);", p->name[r]);
		for (int dir = 1; p->need && p->need[r] && dir <= 2; dir++)
			sl_glsl_line(g, "%s = vec3(0.0);", moved_name(g, p, r, dir));
	}
	if (gr[SL_GLOBAL_PS] >= 0) {
		int32_t r = gr[SL_GLOBAL_PS];
		sl_glsl_line(g, "%s = rl_Ps;", p->name[r]);
		if (p->moved_ps) {
			sl_glsl_line(g, "%s = rl_Psu;", moved_name(g, p, r, 1));
			sl_glsl_line(g, "%s = rl_Psv;", moved_name(g, p, r, 2));
		}
	}
	if (gr[SL_GLOBAL_NS] >= 0)
		sl_glsl_line(g, "%s = rl_Ns;", p->name[gr[SL_GLOBAL_NS]]);
	/* As the light host does: P is the origin of the light's shader space,
	 * ncomps 3, and E, time and dtime come from the surface when both have them. */
	if (gr[SL_GLOBAL_P] >= 0) {
		sl_glsl_need(g, GH_XFORM);
		sl_glsl_line(g, "%s = rl_xpoint(l%u_shader, vec3(0.0));", p->name[gr[SL_GLOBAL_P]],
			     k);
	}
	if (gr[SL_GLOBAL_NCOMPS] >= 0)
		sl_glsl_line(g, "%s = 3.0;", p->name[gr[SL_GLOBAL_NCOMPS]]);
	static const int shared[] = { SL_GLOBAL_E, SL_GLOBAL_TIME, SL_GLOBAL_DTIME };
	for (size_t i = 0; i < sizeof(shared) / sizeof(shared[0]); i++) {
		int32_t lr = gr[shared[i]], sr = g->surf->global_reg[shared[i]];
		if (lr >= 0 && sr >= 0 &&
		    sl_glsl_ncomp(prog, lr) == sl_glsl_ncomp(g->surf, sr))
			sl_glsl_line(g, "%s = %s;", p->name[lr], g->sp.name[sr]);
	}
	sl_glsl_line(g, "rl_lit = false;");
	sl_glsl_line(g, "rl_amb = true;");
	emit_range(g, prog->body_begin, prog->ncode);
	/* The light's L runs light to surface; the surface wants the reverse. */
	sl_glsl_line(g, "rl_L = %s;", gr[SL_GLOBAL_L] >= 0 ?
		     SL_GLSL_FMT(g, "-%s", p->name[gr[SL_GLOBAL_L]]) : "vec3(0.0)");
	sl_glsl_line(g, "rl_Cl = %s;", gr[SL_GLOBAL_CL] >= 0 ? p->name[gr[SL_GLOBAL_CL]] :
		     "vec3(0.0)");
	sl_glsl_line(g, "rl_Ol = %s;", gr[SL_GLOBAL_OL] >= 0 ? p->name[gr[SL_GLOBAL_OL]] :
		     "vec3(0.0)");
	sl_glsl_line(g, "if (rl_amb) rl_lit = true;");
	g->indent--;
	sl_glsl_line(g, "}");
	sl_glsl_line(g, "%s", "");
}

/* Fetch input @r (ncomp x elements floats from @off) into its register. */
/*
 * Float @o of the sample's record: records are read as RGBA32F texels (one
 * fetch brings four floats; the compiler merges fetches of the same texel),
 * the record's first texel at rl_in.
 */
static const char *in_float(struct glsl_gen *g, uint32_t o)
{
	return SL_GLSL_FMT(g, "texelFetch(u_in, rl_in + %u).%c", o / 4, "xyzw"[o % 4]);
}

static void load_input(struct glsl_gen *g, int32_t r, uint32_t off, const char *name)
{
	const struct sl_program *prog = g->surf;
	const struct sl_reg *rg = &prog->regs[r];
	int nc = sl_glsl_ncomp(prog, r);
	int ne = rg->arraylen > 0 ? rg->arraylen : 1;
	for (int e = 0; e < ne; e++) {
		const char *lv = rg->arraylen ? SL_GLSL_FMT(g, "%s[%d]", name, e) : name;
		uint32_t o = off + (uint32_t)(e * nc);
		if (nc == 1) {
			sl_glsl_line(g, "%s = %s;", lv, in_float(g, o));
		} else if (nc == 3) {
			sl_glsl_line(g, "%s = vec3(%s, %s, %s);", lv, in_float(g, o), in_float(g, o + 1),
				     in_float(g, o + 2));
		} else {
			for (int c = 0; c < 16; c++)
				sl_glsl_line(g, "%s[%d][%d] = %s;", lv, c / 4, c % 4,
					     in_float(g, o + (uint32_t)c));
		}
	}
}

/*
 * The copies of input @r moved along u and v: the value plus its step (as
 * the interpreter's moved blocks are made), or the value itself for an input
 * without steps (@ou, @ov NONE).
 */
static void load_moved(struct glsl_gen *g, int32_t r, uint32_t ou, uint32_t ov)
{
	const struct sl_reg *rg = &g->surf->regs[r];
	const char *base = g->sp.name[r];
	for (int dir = 1; dir <= 2; dir++) {
		uint32_t off = dir == 1 ? ou : ov;
		const char *m = moved_name(g, &g->sp, r, dir);
		if (off == NONE) {
			sl_glsl_line(g, "%s = %s;", m, base);
			continue;
		}
		load_input(g, r, off, m);
		if (rg->arraylen)
			sl_glsl_line(g, "for (int k = 0; k < %d; k++) %s[k] = %s[k] + %s[k];",
				     rg->arraylen, m, base, m);
		else
			sl_glsl_line(g, "%s = %s + %s;", m, base, m);
	}
}

static void store_output(struct glsl_gen *g, int32_t r, uint32_t off)
{
	const struct sl_program *prog = g->surf;
	const struct sl_reg *rg = &prog->regs[r];
	int nc = sl_glsl_ncomp(prog, r);
	int ne = rg->arraylen > 0 ? rg->arraylen : 1;
	const char *v = sl_glsl_op(g, r, 0);
	for (int e = 0; e < ne; e++) {
		const char *el = rg->arraylen ? SL_GLSL_FMT(g, "%s[%d]", v, e) : v;
		for (int c = 0; c < nc; c++) {
			const char *comp = nc == 1 ? el : nc == 3 ? SL_GLSL_FMT(g, "%s[%d]", el, c) :
				SL_GLSL_FMT(g, "%s[%d][%d]", el, c / 4, c % 4);
			sl_glsl_line(g, "out_data[rl_out + %uu] = %s;", off + (uint32_t)(e * nc + c),
				     comp);
		}
	}
}

/* Floats a register takes in a buffer. */
static uint64_t reg_floats(const struct sl_program *prog, int32_t r)
{
	const struct sl_reg *rg = &prog->regs[r];
	return (uint64_t)sl_glsl_ncomp(prog, r) * (uint64_t)(rg->arraylen > 0 ? rg->arraylen : 1);
}

static bool check_slice(struct glsl_gen *g, const struct sl_slice *s,
			const struct sl_program *const *lights, uint32_t nlights)
{
	const struct sl_program *prog = s->prog;
	if ((s->ninputs && !s->inputs) || (s->noutputs && !s->outputs) ||
	    (nlights && !lights) || nlights > MAX_LIGHTS) {
		sl_glsl_error(g, NULL, "invalid slice (missing tables or too many lights)");
		return false;
	}
	for (uint32_t i = 0; i < nlights; i++)
		if (!lights[i]) {
			sl_glsl_error(g, NULL, "light %u is missing", i);
			return false;
		}
	uint64_t in = 0, out = 0;
	for (uint32_t i = 0; i < s->ninputs; i++) {
		if (s->inputs[i] < 0 || (uint32_t)s->inputs[i] >= prog->nregs) {
			sl_glsl_error(g, NULL, "invalid slice: input %u is not a register", i);
			return false;
		}
		in += reg_floats(prog, s->inputs[i]);
	}
	for (uint32_t i = 0; i < s->noutputs; i++) {
		if (s->outputs[i] < 0 || (uint32_t)s->outputs[i] >= prog->nregs) {
			sl_glsl_error(g, NULL, "invalid slice: output %u is not a register", i);
			return false;
		}
		out += reg_floats(prog, s->outputs[i]);
	}
	if (in > (1u << 20) || out > (1u << 20)) {
		sl_glsl_error(g, NULL, "invalid slice: too many floats per sample");
		return false;
	}
	return true;
}

/* The global register a CALL reads besides its arguments (ambient() reads P), or -1. */
static int32_t implicit_global(const struct sl_program *prog, const struct sl_insn *in)
{
	switch (sl_builtins[in->bi].id) {
	case SL_BI_AMBIENT: case SL_BI_DIFFUSE: case SL_BI_SPECULAR: case SL_BI_PHONG:
		return prog->global_reg[SL_GLOBAL_P];
	case SL_BI_FACEFORWARD:
		return in->nargs == 2 ? prog->global_reg[SL_GLOBAL_NG] : -1;
	default:
		return -1;
	}
}

/* ------------------------------------------------------------------------ */
/* Derivative stencils                                                       */

/*
 * With input_steps, a derivative is a difference within the sample's
 * stencil, as the interpreter takes it (sl_exec_set_stencil): what the
 * operand is computed from runs again on the inputs moved one grid step
 * along u and along v. Every register the derivatives need (p->need) has
 * two moved copies, u<name> and v<name>, written by a copy of each
 * instruction that writes it, right after it and under the same control
 * flow (so a branch taken differently in the moved blocks than at the
 * sample is not followed: the interpreter's masks would). Which registers
 * those are comes from two passes over the kept code: forwards, what each
 * register's value depends on (GC_* classes); backwards from the
 * derivatives' operands, what they are computed from.
 */

static int numeric_args(const struct sl_program *prog, const struct sl_insn *in, int from)
{
	int k = from;
	while (k < in->nargs && prog->regs[in->args[k]].type != SL_TYPE_STRING)
		k++;
	return k - from;
}

/* A CALL whose result is a derivative: the moved blocks get the sample's value. */
static bool deriv_call(const struct sl_program *prog, const struct sl_insn *in)
{
	switch (sl_builtins[in->bi].id) {
	case SL_BI_DU: case SL_BI_DV: case SL_BI_DERIV: case SL_BI_AREA:
	case SL_BI_CALCULATENORMAL:
		return true;
	case SL_BI_FILTERSTEP:
		return numeric_args(prog, in, 0) < 3;
	default:
		return false;
	}
}

/* Does CALL @in compute what it writes from its arguments alone (a moved copy is the same call)? */
static bool replayable(const struct sl_program *prog, const struct sl_insn *in)
{
	if (in->op != SL_OP_CALL)
		return true;
	if (deriv_call(prog, in))
		return false;
	switch (sl_builtins[in->bi].id) {
	case SL_BI_TEXTURE: case SL_BI_ENVIRONMENT: case SL_BI_SHADOW: case SL_BI_TEXTUREINFO:
	case SL_BI_AMBIENT: case SL_BI_DIFFUSE: case SL_BI_SPECULAR: case SL_BI_PHONG:
	case SL_BI_LIGHTSOURCE: case SL_BI_SURFACE: case SL_BI_DISPLACEMENT:
	case SL_BI_ATMOSPHERE: case SL_BI_INCIDENT: case SL_BI_OPPOSITE: case SL_BI_RANDOM:
	case SL_BI_ATTRIBUTE: case SL_BI_OPTION: case SL_BI_RENDERERINFO: case SL_BI_PRINTF:
	case SL_BI_FORMAT: case SL_BI_CONCAT: case SL_BI_DEPTH:
		return false;
	default:
		return true;
	}
}

/*
 * The registers whose derivatives @in takes on the GPU (up to 2); returns
 * how many. The interpreter's (spec.h), less shadow() other than by one
 * lookup point. (texture() and environment() of named maps filter on the
 * stencil as the interpreter does.)
 */
static int deriv_operands(const struct sl_program *prog, const struct sl_insn *in, int32_t r[2])
{
	if (in->op == SL_OP_CALL && in->bi >= 0 && (uint32_t)in->bi < sl_nbuiltins) {
		int id = sl_builtins[in->bi].id;
		if (id == SL_BI_SHADOW && (in->nargs < 3 || numeric_args(prog, in, 2) != 1))
			return 0;
	}
	return sl_spec_deriv_operands(prog, in, r);
}

/* The registers @in reads: its arguments, a partly written destination, an implicit global. */
static uint32_t insn_reads(const struct sl_program *prog, const struct sl_insn *in, int32_t *out)
{
	uint32_t n = 0;
	for (uint32_t k = 0; k < in->nargs; k++)
		out[n++] = in->args[k];
	if ((in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET) && in->dst >= 0)
		out[n++] = in->dst;
	if (in->op == SL_OP_CALL) {
		int32_t r = implicit_global(prog, in);
		if (r >= 0)
			out[n++] = r;
	}
	return n;
}

static bool add_class(struct glsl_prog *p, int32_t r, uint8_t c)
{
	if (r < 0 || (p->cls[r] | c) == p->cls[r])
		return false;
	p->cls[r] |= c;
	return true;
}

/* Forwards: the class of every register the kept code writes, from the seeds in p->cls. */
static void classify(struct glsl_gen *g, struct glsl_prog *p)
{
	const struct sl_program *prog = p->prog;
	int32_t *rd = rl_xmalloc(((size_t)UINT16_MAX + 3) * sizeof(int32_t));
	g->cur = p;
	for (bool changed = true; changed;) {
		changed = false;
		for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
			const struct sl_insn *in = &prog->code[pc];
			if (!kept(g, pc) || (in->dst < 0 && in->op != SL_OP_CALL))
				continue;
			uint8_t rc = 0;
			uint32_t n = insn_reads(prog, in, rd);
			for (uint32_t k = 0; k < n; k++)
				rc |= p->cls[rd[k]];
			uint8_t out = replayable(prog, in) ? rc :
				      in->op == SL_OP_CALL && deriv_call(prog, in) ? rc & GC_OPAQUE :
				      GC_OPAQUE;
			if (!out)
				continue;
			changed |= add_class(p, in->dst, out);
			if (in->op == SL_OP_CALL)
				for (uint32_t k = 0; k < in->nargs; k++)
					if (call_writes_arg(in, k))
						changed |= add_class(p, in->args[k], out);
		}
	}
	free(rd);
}

static bool add_need(struct glsl_prog *p, int32_t r)
{
	if (r < 0 || p->cls[r] != GC_STEP || p->need[r])
		return false;
	p->need[r] = 1;
	return true;
}

/* Backwards: from the derivatives' operands (and @extra, -1 ended) to what they are computed from. */
static void find_needs(struct glsl_gen *g, struct glsl_prog *p, const int32_t *extra)
{
	const struct sl_program *prog = p->prog;
	int32_t *rd = rl_xmalloc(((size_t)UINT16_MAX + 3) * sizeof(int32_t));
	g->cur = p;
	for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
		int32_t r[2];
		int n = kept(g, pc) ? deriv_operands(prog, &prog->code[pc], r) : 0;
		for (int k = 0; k < n; k++)
			add_need(p, r[k]);
	}
	for (; extra && *extra >= 0; extra++)
		add_need(p, *extra);
	for (bool changed = true; changed;) {
		changed = false;
		for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
			const struct sl_insn *in = &prog->code[pc];
			if (!kept(g, pc) || !replayable(prog, in) ||
			    (in->dst < 0 && in->op != SL_OP_CALL))
				continue;
			bool w = in->dst >= 0 && p->need[in->dst];
			for (uint32_t k = 0; in->op == SL_OP_CALL && k < in->nargs; k++)
				w = w || (call_writes_arg(in, k) && p->need[in->args[k]]);
			if (!w)
				continue;
			uint32_t n = insn_reads(prog, in, rd);
			for (uint32_t k = 0; k < n; k++)
				changed |= add_need(p, rd[k]);
		}
	}
	free(rd);
}

/*
 * The surface's registers that lights get as Ps (illuminance positions; P
 * for ambient(), diffuse(), ...), -1 ended, into @out (room for ncode + 2).
 */
static void ps_sources(struct glsl_gen *g, int32_t *out)
{
	const struct sl_program *prog = g->surf;
	uint32_t n = 0;
	bool lighting = false;
	g->cur = &g->sp;
	for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (!kept(g, pc))
			continue;
		if (in->op == SL_OP_ILLUMINANCE && in->nargs > (uint32_t)in->imm)
			out[n++] = in->args[in->imm];
		if (in->op == SL_OP_CALL && implicit_global(prog, in) >= 0 &&
		    sl_builtins[in->bi].id != SL_BI_FACEFORWARD)
			lighting = true;
	}
	if (lighting && prog->global_reg[SL_GLOBAL_P] >= 0)
		out[n++] = prog->global_reg[SL_GLOBAL_P];
	out[n] = -1;
}

static void analyze_stencils(struct glsl_gen *g)
{
	const struct sl_slice *s = g->slice;
	struct glsl_prog *sp = &g->sp;
	const int32_t *gr = g->surf->global_reg;
	for (uint32_t i = 0; i < s->ninputs; i++)
		sp->cls[s->inputs[i]] |= s->input_steps[i] ? GC_STEP : GC_OPAQUE;
	/* What illuminance bodies get from the lights. */
	static const int from_lights[] = { SL_GLOBAL_L, SL_GLOBAL_CL, SL_GLOBAL_OL };
	for (size_t k = 0; k < sizeof(from_lights) / sizeof(from_lights[0]); k++)
		if (gr[from_lights[k]] >= 0)
			sp->cls[gr[from_lights[k]]] |= GC_OPAQUE;
	classify(g, sp);
	int32_t *src = rl_xmalloc(((size_t)g->surf->ncode + 2) * sizeof(int32_t));
	ps_sources(g, src);
	uint8_t ps_cls = 0;
	for (const int32_t *r = src; *r >= 0; r++)
		ps_cls |= sp->cls[*r];
	for (uint32_t k = 0; k < g->nlights; k++) {
		struct glsl_prog *lp = &g->lp[k];
		const int32_t *lg = lp->prog->global_reg;
		if (lg[SL_GLOBAL_PS] >= 0)
			lp->cls[lg[SL_GLOBAL_PS]] = ps_cls;
		static const int opaque[] = { SL_GLOBAL_L, SL_GLOBAL_E, SL_GLOBAL_TIME,
					      SL_GLOBAL_DTIME, SL_GLOBAL_NS };
		for (size_t j = 0; j < sizeof(opaque) / sizeof(opaque[0]); j++)
			if (lg[opaque[j]] >= 0)
				lp->cls[lg[opaque[j]]] |= GC_OPAQUE;
		classify(g, lp);
		find_needs(g, lp, NULL);
		lp->moved_ps = lg[SL_GLOBAL_PS] >= 0 && lp->need[lg[SL_GLOBAL_PS]];
		g->any_moved_ps = g->any_moved_ps || lp->moved_ps;
	}
	find_needs(g, sp, g->any_moved_ps ? src : NULL);
	free(src);
	g->cur = sp;
}

/* After @in: its copies moved along u and v, for the registers it writes that have them. */
static void emit_moved(struct glsl_gen *g, const struct sl_insn *in)
{
	struct glsl_prog *p = g->cur;
	if (!p->need || g->failed)
		return;
	bool w = in->dst >= 0 && p->need[in->dst];
	for (uint32_t k = 0; in->op == SL_OP_CALL && k < in->nargs; k++)
		w = w || (call_writes_arg(in, k) && p->need[in->args[k]]);
	if (!w)
		return;
	if (replayable(p->prog, in)) {
		for (int dir = 1; dir <= 2; dir++) {
			g->moved = dir;
			emit_insn(g, in);
			g->moved = 0;
		}
		return;
	}
	/* A derivative: the moved blocks take the sample's value. */
	for (int dir = 1; dir <= 2; dir++) {
		if (in->dst >= 0 && p->need[in->dst])
			sl_glsl_line(g, "%s = %s;", moved_name(g, p, in->dst, dir), p->name[in->dst]);
		for (uint32_t k = 0; in->op == SL_OP_CALL && k < in->nargs; k++)
			if (call_writes_arg(in, k) && p->need[in->args[k]])
				sl_glsl_line(g, "%s = %s;", moved_name(g, p, in->args[k], dir),
					     p->name[in->args[k]]);
	}
}

const char *sl_glsl_string_param(struct glsl_gen *g, int32_t r)
{
	struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	for (int hop = 0; hop < 16 && r >= 0; hop++) {
		for (uint32_t k = 0; k < prog->nparams; k++)
			if (prog->params[k].reg == r && prog->regs[r].type == SL_TYPE_STRING &&
			    !prog->regs[r].arraylen)
				return prog->params[k].name;
		r = p->copy_of ? p->copy_of[r] : -1;
	}
	return NULL;
}

/*
 * The map a lookup names: a string parameter of its program (through
 * copies) in *param, or a constant in *name. False (an error) for neither.
 */
static bool site_name(struct glsl_gen *g, const struct sl_insn *in, const char **param,
		      const char **name)
{
	*param = sl_glsl_string_param(g, in->args[0]);
	*name = *param ? NULL : sl_glsl_cstr(g, in->args[0]);
	if (*param || *name)
		return true;
	sl_glsl_error(g, in, "%s map names must be string parameters or constant strings on the "
		      "GPU", sl_builtins[in->bi].name);
	return false;
}

int sl_glsl_map_site(struct glsl_gen *g, const struct sl_insn *in, enum sl_glsl_map_kind kind)
{
	struct glsl_prog *p = g->cur;
	if (!p->msite)
		return -1;
	uint32_t pc = (uint32_t)(in - p->prog->code);
	if (p->msite[pc] >= 0)
		return p->msite[pc];
	const char *param, *name;
	if (!site_name(g, in, &param, &name))
		return -1;
	uint32_t k = (uint32_t)g->msites.len;
	struct sl_glsl_map_site site = { p->light, param, name, kind };
	rl_vec_push(g->msites, site);
	p->msite[pc] = (int32_t)k;
	/* the sampler's declaration, with its unit, comes when the shadow sites are all known */
	return (int)k;
}

int sl_glsl_shadow_site(struct glsl_gen *g, const struct sl_insn *in)
{
	struct glsl_prog *p = g->cur;
	const struct sl_program *prog = p->prog;
	if (!p->site)
		return -1;
	uint32_t pc = (uint32_t)(in - prog->code);
	if (p->site[pc] >= 0)
		return p->site[pc];
	const char *param, *name;
	if (!site_name(g, in, &param, &name))
		return -1;
	uint32_t k = (uint32_t)g->sites.len;
	struct sl_glsl_shadow_site site = { p->light, param, name,
					    p->light >= 0 && g->slice->raytrace_shadows &&
					    (param || !strcmp(name, "raytrace")) };
	rl_vec_push(g->sites, site);
	p->site[pc] = (int32_t)k;
	struct rl_strbuf *u = &g->sec[GS_UNIFORMS];
	if (k == 0)
		rl_strbuf_puts(u, "uniform mat4 u_to_world;\n");
	rl_strbuf_printf(u, "layout(binding = %u) uniform samplerBuffer u_shadow%u;\n",
			 SL_GLSL_SHADOW_UNIT0 + k, k);
	rl_strbuf_printf(u, "uniform int u_shadow%u_size[2];\n", k);
	rl_strbuf_printf(u, "uniform mat4 u_shadow%u_to_camera;\n", k);
	rl_strbuf_printf(u, "uniform mat4 u_shadow%u_to_ndc;\n", k);
	rl_strbuf_printf(u, "uniform float u_shadow%u_bias;\n", k);
	rl_strbuf_printf(u, "uniform int u_shadow%u_deep;\n", k);
	if (site.raytrace)
		rl_strbuf_printf(u, "uniform int u_shadow%u_rt;\n", k);
	return (int)k;
}

/*
 * Warn about globals the kept code reads that are neither inputs nor
 * computed by kept code: they would be 0 (a slice that left out an input).
 * Ci, Oi, L, Cl and Ol start as the interpreter starts them.
 */
static void check_inputs(struct glsl_gen *g, const uint8_t *is_input)
{
	const struct sl_program *prog = g->surf;
	uint8_t *known = rl_arena_alloc(g->arena, prog->nregs + 1);
	for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (!kept(g, pc))
			continue;
		if (in->dst >= 0)
			known[in->dst] = 1;
		if (in->op == SL_OP_CALL)
			for (uint32_t k = 0; k < in->nargs; k++)
				if (call_writes_arg(in, k))
					known[in->args[k]] = 1;
	}
	for (int gl = 0; gl < SL_GLOBAL_COUNT; gl++) {
		int32_t r = prog->global_reg[gl];
		if (r >= 0 && (gl == SL_GLOBAL_CI || gl == SL_GLOBAL_OI || gl == SL_GLOBAL_L ||
			       gl == SL_GLOBAL_CL || gl == SL_GLOBAL_OL || is_input[r]))
			known[r] = 1;
	}
	for (uint32_t pc = prog->body_begin; pc < prog->ncode; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (!kept(g, pc))
			continue;
		for (uint32_t k = 0; k <= in->nargs; k++) {
			int32_t r = k < in->nargs ? in->args[k] :
				    in->op == SL_OP_CALL ? implicit_global(prog, in) : -1;
			if (r < 0 || known[r] || prog->regs[r].kind != SL_REG_GLOBAL)
				continue;
			known[r] = 1;
			sl_glsl_warning(g, in, "global '%s' is read but is not an input of the slice "
					"(0 is used)", sl_global_name(prog->regs[r].global));
		}
	}
}

/*
 * Per-light passes: rl_reset() sets every register of the surface (and
 * their moved copies) back to where a kernel starts them, so that each
 * pass starts as the one-light kernel does. Emitted after the passes, when
 * the moved copies they use are known.
 */
static void emit_reset(struct glsl_gen *g)
{
	struct glsl_prog *p = &g->sp;
	const struct sl_program *prog = p->prog;
	g->cur = p;
	g->out = &g->sec[GS_MAIN];
	g->indent = 0;
	sl_glsl_line(g, "void rl_reset() {");
	g->indent++;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *rg = &prog->regs[r];
		if (rg->kind == SL_REG_CONST || rg->arraylen || !declared_reg(p, (int32_t)r))
			continue;
		sl_glsl_line(g, "%s = %s;", p->name[r], reg_init(p, (int32_t)r));
		for (int dir = 1; p->mdecl && dir <= 2; dir++)
			if (p->mdecl[r] & dir)
				sl_glsl_line(g, "%c%s = %s;", dir == 1 ? 'u' : 'v', p->name[r],
					     reg_init(p, (int32_t)r));
	}
	g->indent--;
	sl_glsl_line(g, "}");
}

static void emit_main(struct glsl_gen *g, struct sl_glsl_layout *layout)
{
	const struct sl_slice *s = g->slice;
	const struct sl_program *prog = g->surf;
	g->cur = &g->sp;
	g->cur_light = -1;
	g->nstack = 0;
	g->out = &g->sec[GS_MAIN];
	g->indent = 0;
	if (s->per_light) {
		rl_strbuf_puts(&g->sec[GS_GLOBALS], "uint idx = 0u;\nint rl_only = -1;\n");
		sl_glsl_line(g, "void rl_reset();");
		sl_glsl_line(g, "/* the slice lit by light rl_only alone */");
		sl_glsl_line(g, "void rl_pass() {");
		g->indent++;
		sl_glsl_line(g, "rl_reset();");
	} else {
		sl_glsl_line(g, "void main() {");
		g->indent++;
		sl_glsl_line(g, "uint idx = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * "
			     "gl_NumWorkGroups.x * 64u;");
		sl_glsl_line(g, "if (idx >= uint(u_count)) return;");
		sl_glsl_line(g, "idx += uint(u_first);");
	}
	zero_arrays(g);
	for (uint32_t k = 0; k < g->nlights; k++) {
		g->cur = &g->lp[k];
		zero_arrays(g);
	}
	g->cur = &g->sp;
	uint8_t *is_input = rl_arena_alloc(g->arena, prog->nregs + 1);
	for (uint32_t i = 0; i < s->ninputs; i++)
		is_input[s->inputs[i]] = 1;
	load_params(g, is_input);
	check_inputs(g, is_input);
	uint32_t off = 0;
	if (s->ninputs)
		sl_glsl_line(g, "int rl_in = int(idx) * %u;", layout->in_stride / 4);
	for (uint32_t i = 0; i < s->ninputs; i++) {
		layout->in_offset[i] = off;
		load_input(g, s->inputs[i], off, g->sp.name[s->inputs[i]]);
		if (g->sp.need && g->sp.need[s->inputs[i]])
			load_moved(g, s->inputs[i], layout->in_step_u[i], layout->in_step_v[i]);
		off += (uint32_t)reg_floats(prog, s->inputs[i]);
	}
	if (layout->du_offset != NONE) {
		rl_strbuf_puts(&g->sec[GS_GLOBALS], "float rl_du = 0.0;\nfloat rl_dv = 0.0;\n");
		sl_glsl_line(g, "rl_du = %s;", in_float(g, layout->du_offset));
		sl_glsl_line(g, "rl_dv = %s;", in_float(g, layout->dv_offset));
	}
	emit_range(g, prog->body_begin, prog->ncode);
	off = 0;
	if (s->per_light && s->sink) {
		const struct sl_reg *rg = &prog->regs[s->outputs[0]];
		if (s->noutputs != 1 || rg->arraylen || sl_glsl_ncomp(prog, s->outputs[0]) != 3)
			sl_glsl_error(g, NULL, "a sink takes one output of three floats");
		else
			sl_glsl_line(g, "rl_sink(idx, uint(rl_only), %s);",
				     sl_glsl_op(g, s->outputs[0], 3));
		layout->out_offset[0] = 0;
	} else if (s->noutputs && s->per_light)
		sl_glsl_line(g, "uint rl_out = ((idx - uint(u_first)) * %uu + uint(rl_only)) * %uu;",
			     g->nlights, layout->out_stride);
	else if (s->noutputs)
		sl_glsl_line(g, "uint rl_out = idx * %uu;", layout->out_stride);
	for (uint32_t i = 0; i < s->noutputs && !(s->per_light && s->sink); i++) {
		layout->out_offset[i] = off;
		store_output(g, s->outputs[i], off);
		off += (uint32_t)reg_floats(prog, s->outputs[i]);
	}
	g->indent--;
	sl_glsl_line(g, "}");
	if (!s->per_light)
		return;
	if (s->sink)
		rl_strbuf_printf(&g->sec[GS_GENERATED], "%s\n", s->sink);
	/* The passes: rl_only is a constant in each, so only its light's code stays. */
	sl_glsl_line(g, "%s", "");
	sl_glsl_line(g, "void main() {");
	g->indent++;
	sl_glsl_line(g, "idx = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * "
		     "gl_NumWorkGroups.x * 64u;");
	sl_glsl_line(g, "if (idx >= uint(u_count)) return;");
	sl_glsl_line(g, "idx += uint(u_first);");
	for (uint32_t k = 0; k < g->nlights; k++) {
		sl_glsl_line(g, "rl_only = %u;", k);
		sl_glsl_line(g, "rl_pass();");
	}
	if (s->sink)
		sl_glsl_line(g, "rl_sink_end(idx);");
	g->indent--;
	sl_glsl_line(g, "}");
	sl_glsl_line(g, "%s", "");
	emit_reset(g);
}

/* The table of strings, copied into one block that layout->strings owns. */
static void fill_strings(struct glsl_gen *g, struct sl_glsl_layout *layout)
{
	size_t n = g->strings.len, chars = 0;
	for (size_t i = 0; i < n; i++)
		chars += strlen(g->strings.data[i]) + 1;
	char *block = rl_xmalloc((n + 1) * sizeof(char *) + chars + 1);
	const char **tab = (const char **)(void *)block;
	char *c = block + (n + 1) * sizeof(char *);
	for (size_t i = 0; i < n; i++) {
		size_t len = strlen(g->strings.data[i]) + 1;
		memcpy(c, g->strings.data[i], len);
		tab[i] = c;
		c += len;
	}
	tab[n] = NULL;
	layout->strings = tab;
	layout->nstrings = (uint32_t)n;
}

/*
 * A copy of @n sites of @size bytes each whose strings, the `param` and `name`
 * fields at @param_off and @name_off, are copied into the same block after
 * the array: freeing the block frees them all.
 */
static void *copy_sites(const void *sites, size_t n, size_t size, size_t param_off,
			size_t name_off)
{
	const size_t offs[2] = { param_off, name_off };
	size_t chars = 0;
	for (size_t i = 0; i < n; i++)
		for (int f = 0; f < 2; f++) {
			const char *str;
			memcpy(&str, (const char *)sites + i * size + offs[f], sizeof(str));
			chars += str ? strlen(str) + 1 : 0;
		}
	char *block = rl_xmalloc(n * size + chars + 1);
	memcpy(block, sites, n * size);
	char *c = block + n * size;
	for (size_t i = 0; i < n; i++)
		for (int f = 0; f < 2; f++) {
			const char *str;
			memcpy(&str, block + i * size + offs[f], sizeof(str));
			if (!str)
				continue;
			size_t len = strlen(str) + 1;
			memcpy(c, str, len);
			memcpy(block + i * size + offs[f], &c, sizeof(c));
			c += len;
		}
	return block;
}

/* The shadow() sites, their strings in the same block as the array (layout->shadows owns it). */
static void fill_sites(struct glsl_gen *g, struct sl_glsl_layout *layout)
{
	size_t n = g->sites.len;
	if (!n)
		return;
	layout->shadows = copy_sites(g->sites.data, n, sizeof(struct sl_glsl_shadow_site),
				     offsetof(struct sl_glsl_shadow_site, param),
				     offsetof(struct sl_glsl_shadow_site, name));
	layout->nshadows = (uint32_t)n;
}

/* The map sites (layout->maps owns their strings) and their samplers' units, after the shadow sites'. */
static void fill_map_sites(struct glsl_gen *g, struct sl_glsl_layout *layout)
{
	size_t n = g->msites.len;
	bool rt = false;
	for (size_t i = 0; i < g->sites.len; i++)
		rt |= g->sites.data[i].raytrace;
	if (rt) {
		layout->bvh_unit = SL_GLSL_SHADOW_UNIT0 + (uint32_t)(g->sites.len + n);
		rl_strbuf_printf(&g->sec[GS_UNIFORMS],
				 "layout(binding = %u) uniform samplerBuffer u_bvh_nodes;\n"
				 "layout(binding = %u) uniform samplerBuffer u_bvh_tris;\n"
				 "layout(binding = %u) uniform samplerBuffer u_bvh_casts;\n"
				 "uniform float u_trace_bias;\n", layout->bvh_unit,
				 layout->bvh_unit + 1, layout->bvh_unit + 2);
	}
	if (!n)
		return;
	for (size_t i = 0; i < n; i++)
		rl_strbuf_printf(&g->sec[GS_UNIFORMS],
				 "layout(binding = %u) uniform samplerBuffer u_map%zu;\n",
				 SL_GLSL_SHADOW_UNIT0 + (unsigned)g->sites.len + (unsigned)i, i);
	layout->maps = copy_sites(g->msites.data, n, sizeof(struct sl_glsl_map_site),
				  offsetof(struct sl_glsl_map_site, param),
				  offsetof(struct sl_glsl_map_site, name));
	layout->nmaps = (uint32_t)n;
}

static const char prelude[] =
	"#version 430 core\n"
	"layout(local_size_x = 64) in;\n"
	"layout(binding = 0) uniform samplerBuffer u_in;   /* RGBA32F texels */\n"
	"uniform int u_count;\n"
	"uniform int u_first;\n"
	"layout(std430, binding = 1) buffer Out { float out_data[]; };\n";

char *sl_glsl_emit(const struct sl_slice *s, const struct sl_program *const *lights,
		   uint32_t nlights, struct sl_glsl_layout *layout, FILE *diag)
{
	if (layout)
		memset(layout, 0, sizeof(*layout));
	if (!s || !s->prog || !layout) {
		fprintf(diag ? diag : stderr, "glsl: error: no slice or layout\n");
		return NULL;
	}
	struct glsl_gen gen = { 0 };
	struct glsl_gen *g = &gen;
	g->slice = s;
	g->surf = s->prog;
	g->lights = lights;
	g->nlights = nlights;
	g->diag = diag;
	g->arena = rl_arena_create();
	g->cur_light = -1;
	g->cur = &g->sp;
	g->sp.prog = s->prog;
	g->stencil = s->input_steps != NULL;
	char *src = NULL;

	if (!check_slice(g, s, lights, nlights))
		goto out;
	/* An imager's pixels are samples like a surface's: its inputs and
	 * outputs are the slice's, and it calls no light. */
	if (s->prog->kind != SL_SHADER_SURFACE && s->prog->kind != SL_SHADER_IMAGER)
		sl_glsl_warning(g, NULL, "emitting a %s shader as a surface",
				sl_shader_kind_name(s->prog->kind));
	if (!prepare(g, &g->sp, s->prog, -1))
		goto out;
	g->lp = rl_arena_alloc(g->arena, (nlights + 1) * sizeof(*g->lp));
	for (uint32_t k = 0; k < nlights; k++) {
		if (!prepare(g, &g->lp[k], lights[k], (int)k))
			goto out;
		if (lights[k]->kind != SL_SHADER_LIGHT) {
			g->cur = &g->lp[k];
			sl_glsl_error(g, NULL, "light %u is a %s shader", k,
				      sl_shader_kind_name(lights[k]->kind));
			goto out;
		}
	}
	collect_strings(g, s->prog);
	for (uint32_t k = 0; k < nlights; k++)
		collect_strings(g, lights[k]);
	collect_category_terms(g, &g->sp);

	layout->in_offset = rl_xcalloc(s->ninputs + 1, sizeof(uint32_t));
	layout->out_offset = rl_xcalloc(s->noutputs + 1, sizeof(uint32_t));
	for (uint32_t i = 0; i < s->ninputs; i++)
		layout->in_stride += (uint32_t)reg_floats(s->prog, s->inputs[i]);
	/* Steps after the plain inputs: per input its u step then its v step, then du, dv. */
	layout->in_step_u = rl_xmalloc((s->ninputs + 1) * sizeof(uint32_t));
	layout->in_step_v = rl_xmalloc((s->ninputs + 1) * sizeof(uint32_t));
	layout->du_offset = layout->dv_offset = NONE;
	bool steps = false;
	for (uint32_t i = 0; i < s->ninputs; i++) {
		layout->in_step_u[i] = layout->in_step_v[i] = NONE;
		if (!s->input_steps || !s->input_steps[i])
			continue;
		uint32_t nf = (uint32_t)reg_floats(s->prog, s->inputs[i]);
		layout->in_step_u[i] = layout->in_stride;
		layout->in_step_v[i] = layout->in_stride + nf;
		layout->in_stride += 2 * nf;
		steps = true;
	}
	if (steps) {
		layout->du_offset = layout->in_stride;
		layout->dv_offset = layout->in_stride + 1;
		layout->in_stride += 2;
	}
	/* whole RGBA32F texels per record */
	layout->in_stride = (layout->in_stride + 3) / 4 * 4;
	if (g->stencil)
		analyze_stencils(g);
	for (uint32_t i = 0; i < s->noutputs; i++)
		layout->out_stride += (uint32_t)reg_floats(s->prog, s->outputs[i]);

	rl_strbuf_puts(&g->sec[GS_PRELUDE], prelude);
	/* What the code was made from: with the code itself, the key of the
	 * compiled program kept on disk (gpu_set_program_cache). */
	rl_strbuf_printf(&g->sec[GS_PRELUDE], "// relight %s, GLSL generator %d\n", RELIGHT_VERSION,
			 SL_GLSL_GENERATOR_VERSION);
	rl_strbuf_printf(&g->sec[GS_PRELUDE], "// surface %s, source %s\n", s->prog->name,
			 s->prog->source_hash);
	for (uint32_t k = 0; k < nlights; k++)
		rl_strbuf_printf(&g->sec[GS_PRELUDE], "// light %u: %s, source %s\n", k,
				 lights[k]->name, lights[k]->source_hash);
	sl_glsl_need(g, GH_CORE);
	rl_strbuf_puts(&g->sec[GS_GLOBALS], "vec3 rl_L = vec3(0.0);\nvec3 rl_Cl = vec3(0.0);\n"
			"vec3 rl_Ol = vec3(0.0);\nbool rl_lit = false;\nbool rl_amb = true;\n");
	g->cur = &g->sp;
	declare_registers(g);
	for (uint32_t k = 0; k < nlights && !g->failed; k++)
		emit_light(g, k);
	if (!g->failed)
		emit_main(g, layout);
	for (int w = 0; w < GL_COUNT && !g->failed; w++)
		if (g->lighting[w])
			sl_glsl_emit_lighting(g, (enum glsl_lighting)w);
	for (size_t i = 0; i < g->spaces.len; i++)
		rl_strbuf_printf(&g->sec[GS_UNIFORMS], "uniform mat4 space_%s;\n",
				 g->strings.data[g->spaces.data[i]]);
	if (g->failed)
		goto out;
	sl_glsl_emit_helpers(g);
	fill_strings(g, layout);
	fill_sites(g, layout);
	fill_map_sites(g, layout);

	struct rl_strbuf all = { 0 };
	for (int k = 0; k < GS_COUNT; k++) {
		rl_strbuf_add(&all, g->sec[k].data ? g->sec[k].data : "", g->sec[k].len);
		if (g->sec[k].len)
			rl_strbuf_putc(&all, '\n');
	}
	src = rl_xstrdup(rl_strbuf_str(&all));
	rl_strbuf_finish(&all);
out:
	if (!src)
		sl_glsl_layout_finish(layout);
	for (int k = 0; k < GS_COUNT; k++)
		rl_strbuf_finish(&g->sec[k]);
	rl_vec_free(g->strings);
	free(g->shash);
	rl_vec_free(g->spaces);
	rl_vec_free(g->space_on);
	rl_vec_free(g->splines);
	rl_vec_free(g->sites);
	rl_vec_free(g->msites);
	free(g->stack);
	rl_arena_destroy(g->arena);
	return src;
}

void sl_glsl_layout_finish(struct sl_glsl_layout *layout)
{
	if (!layout)
		return;
	free(layout->in_offset);
	free(layout->out_offset);
	free((void *)layout->strings);
	free(layout->in_step_u);
	free(layout->in_step_v);
	free(layout->shadows);
	free(layout->maps);
	memset(layout, 0, sizeof(*layout));
}

char *sl_glsl_emit_imager(const struct sl_program *im, enum sl_global *globals, uint32_t *nin,
			  struct sl_glsl_layout *layout, FILE *diag)
{
	static const enum sl_global order[SL_GLSL_IMAGER_INPUTS] = {
		SL_GLOBAL_CI, SL_GLOBAL_OI, SL_GLOBAL_ALPHA, SL_GLOBAL_P,
		SL_GLOBAL_NCOMPS, SL_GLOBAL_TIME, SL_GLOBAL_DTIME,
	};
	int32_t inputs[SL_GLSL_IMAGER_INPUTS], outputs[2];
	*nin = 0;
	if (!im || im->kind != SL_SHADER_IMAGER || im->global_reg[SL_GLOBAL_CI] < 0 ||
	    im->global_reg[SL_GLOBAL_ALPHA] < 0) {
		fprintf(diag ? diag : stderr, "error: not an imager shader\n");
		return NULL;
	}
	for (int k = 0; k < SL_GLSL_IMAGER_INPUTS; k++)
		if (im->global_reg[order[k]] >= 0) {
			globals[*nin] = order[k];
			inputs[(*nin)++] = im->global_reg[order[k]];
		}
	outputs[0] = im->global_reg[SL_GLOBAL_CI];
	outputs[1] = im->global_reg[SL_GLOBAL_ALPHA];
	struct sl_slice slice = { im, NULL, inputs, *nin, outputs, 2 };
	return sl_glsl_emit(&slice, NULL, 0, layout, diag);
}

/* AST nodes: allocation, names and a readable dump. */
#include "ast.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const basetype_names[SL_TYPE_COUNT] = {
	[SL_TYPE_VOID] = "void",
	[SL_TYPE_FLOAT] = "float",
	[SL_TYPE_COLOR] = "color",
	[SL_TYPE_POINT] = "point",
	[SL_TYPE_VECTOR] = "vector",
	[SL_TYPE_NORMAL] = "normal",
	[SL_TYPE_MATRIX] = "matrix",
	[SL_TYPE_STRING] = "string",
	[SL_TYPE_BOOL] = "bool",
};

const char *sl_basetype_name(int base)
{
	if (base < 0 || base >= SL_TYPE_COUNT)
		return "?";
	return basetype_names[base];
}

static const char *const kind_names[SL_AST_KIND_COUNT] = {
	[SL_AST_NUM] = "NUM",
	[SL_AST_STR] = "STR",
	[SL_AST_IDENT] = "IDENT",
	[SL_AST_UNARY] = "UNARY",
	[SL_AST_BINARY] = "BINARY",
	[SL_AST_ASSIGN] = "ASSIGN",
	[SL_AST_INCDEC] = "INCDEC",
	[SL_AST_COND] = "COND",
	[SL_AST_CALL] = "CALL",
	[SL_AST_INDEX] = "INDEX",
	[SL_AST_CTOR] = "CTOR",
	[SL_AST_ARRAYLIT] = "ARRAYLIT",
	[SL_AST_VAR] = "VAR",
	[SL_AST_DECL] = "DECL",
	[SL_AST_FUNC] = "FUNC",
	[SL_AST_SHADER] = "SHADER",
	[SL_AST_UNIT] = "UNIT",
	[SL_AST_BLOCK] = "BLOCK",
	[SL_AST_EXPR] = "EXPR",
	[SL_AST_IF] = "IF",
	[SL_AST_WHILE] = "WHILE",
	[SL_AST_FOR] = "FOR",
	[SL_AST_BREAK] = "BREAK",
	[SL_AST_CONTINUE] = "CONTINUE",
	[SL_AST_RETURN] = "RETURN",
	[SL_AST_ILLUMINANCE] = "ILLUMINANCE",
	[SL_AST_ILLUMINATE] = "ILLUMINATE",
	[SL_AST_SOLAR] = "SOLAR",
	[SL_AST_EMPTY] = "EMPTY",
};

const char *sl_ast_kind_name(enum sl_ast_kind kind)
{
	if ((unsigned)kind >= SL_AST_KIND_COUNT)
		return "?";
	return kind_names[kind];
}

struct sl_ast *sl_ast_new(struct sl_ctx *ctx, enum sl_ast_kind kind, struct sl_loc loc)
{
	struct sl_ast *n = rl_arena_alloc(ctx->arena, sizeof(*n));
	n->kind = kind;
	n->loc = loc;
	n->type.arraylen = -1;
	n->ty.arraylen = -1;
	n->overload = -1;
	return n;
}

static const char *const shader_kind_names[] = {
	[SL_SHADER_SURFACE] = "surface",
	[SL_SHADER_LIGHT] = "light",
	[SL_SHADER_DISPLACEMENT] = "displacement",
	[SL_SHADER_VOLUME] = "volume",
	[SL_SHADER_IMAGER] = "imager",
};

/* The spelling of an operator kept in a node's op field. */
static const char *op_spelling(int op)
{
	switch (op) {
	case SL_TOK_PLUS: return "+";
	case SL_TOK_MINUS: return "-";
	case SL_TOK_STAR: return "*";
	case SL_TOK_SLASH: return "/";
	case SL_TOK_CARET: return "^";
	case SL_TOK_DOT: return ".";
	case SL_TOK_BANG: return "!";
	case SL_TOK_EQ: return "==";
	case SL_TOK_NE: return "!=";
	case SL_TOK_LT: return "<";
	case SL_TOK_LE: return "<=";
	case SL_TOK_GT: return ">";
	case SL_TOK_GE: return ">=";
	case SL_TOK_AND: return "&&";
	case SL_TOK_OR: return "||";
	case SL_TOK_ASSIGN: return "=";
	case SL_TOK_PLUS_ASSIGN: return "+=";
	case SL_TOK_MINUS_ASSIGN: return "-=";
	case SL_TOK_STAR_ASSIGN: return "*=";
	case SL_TOK_SLASH_ASSIGN: return "/=";
	case SL_TOK_INC: return "++";
	case SL_TOK_DEC: return "--";
	default: return "?";
	}
}

static void dump_string(const char *s, FILE *out)
{
	fputc('"', out);
	for (; s && *s; s++) {
		unsigned char c = (unsigned char)*s;
		switch (c) {
		case '"': fputs("\\\"", out); break;
		case '\\': fputs("\\\\", out); break;
		case '\n': fputs("\\n", out); break;
		case '\t': fputs("\\t", out); break;
		default:
			if (c < 0x20 || c == 0x7f)
				fprintf(out, "\\%03o", c);
			else
				fputc(c, out);
		}
	}
	fputc('"', out);
}

static void dump_type(const struct sl_type *t, FILE *out)
{
	if (t->detail == SL_DETAIL_UNIFORM)
		fputs("uniform ", out);
	else if (t->detail == SL_DETAIL_VARYING)
		fputs("varying ", out);
	fputs(sl_basetype_name(t->base), out);
	if (t->arraylen == 0)
		fputs("[]", out);
	else if (t->arraylen > 0)
		fprintf(out, "[%d]", (int)t->arraylen);
}

static void dump_node(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out);

/*
 * Two spaces a level; past MAX_INDENT levels the level is written as a
 * number after them, so that a flat chain of 100,000 terms (100,000 levels
 * of the left-leaning tree) prints in linear, not quadratic, space.
 */
#define MAX_INDENT 64

static void indent(int depth, FILE *out)
{
	for (int i = 0; i < depth && i < MAX_INDENT; i++)
		fputs("  ", out);
	if (depth > MAX_INDENT)
		fprintf(out, "[%d] ", depth);
}

static void dump_child(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out,
		       bool show_null)
{
	if (n) {
		dump_node(ctx, n, depth, out);
	} else if (show_null) {
		indent(depth, out);
		fputs("(none)\n", out);
	}
}

static void dump_list(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out)
{
	for (uint32_t i = 0; i < n->nlist; i++)
		dump_child(ctx, n->list[i], depth, out, true);
}

/* The node's own line: kind, details, location. */
static void dump_line(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out)
{
	indent(depth, out);
	fputs(sl_ast_kind_name(n->kind), out);

	switch (n->kind) {
	case SL_AST_NUM:
		fprintf(out, " %.9g", n->num);
		break;
	case SL_AST_STR:
		fputc(' ', out);
		dump_string(n->str, out);
		break;
	case SL_AST_IDENT:
	case SL_AST_CALL:
		fprintf(out, " %s", n->name ? n->name : "?");
		break;
	case SL_AST_UNARY:
	case SL_AST_BINARY:
	case SL_AST_ASSIGN:
		fprintf(out, " '%s'", op_spelling(n->op));
		break;
	case SL_AST_INCDEC:
		fprintf(out, " '%s' %s", op_spelling(n->op), n->num != 0 ? "prefix" : "postfix");
		break;
	case SL_AST_CTOR:
		fprintf(out, " %s", sl_basetype_name(n->type.base));
		break;
	case SL_AST_VAR:
		fprintf(out, " %s :", n->name ? n->name : "?");
		if (n->is_extern)
			fputs(" extern", out);
		if (n->output)
			fputs(" output", out);
		fputc(' ', out);
		dump_type(&n->type, out);
		break;
	case SL_AST_FUNC:
		fprintf(out, " %s : ", n->name ? n->name : "?");
		dump_type(&n->type, out);
		break;
	case SL_AST_SHADER:
		if (n->op >= 0 && n->op <= SL_SHADER_IMAGER)
			fprintf(out, " %s", shader_kind_names[n->op]);
		fprintf(out, " %s", n->name ? n->name : "?");
		break;
	case SL_AST_BREAK:
	case SL_AST_CONTINUE:
		fprintf(out, " %g", n->num);
		break;
	default:
		break;
	}

	const char *file = n->loc.file < ctx->files.len ? ctx->files.data[n->loc.file] : "<input>";
	fprintf(out, " (%s:%u:%u)\n", file, n->loc.line, n->loc.col);
}

/*
 * A chain a + b + c + ... prints as the tree it is, each operator above its
 * operands, but its left spine is followed in a loop: ten thousand terms
 * are not ten thousand frames.
 */
static void dump_chain(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out)
{
	RL_VEC(const struct sl_ast *) spine = { 0 };
	for (; n->kind == SL_AST_BINARY && n->a; n = n->a) {
		dump_line(ctx, n, depth + (int)spine.len, out);
		rl_vec_push(spine, n);
	}
	dump_node(ctx, n, depth + (int)spine.len, out);
	for (size_t i = spine.len; i-- > 0;)
		dump_child(ctx, spine.data[i]->b, depth + (int)i + 1, out, false);
	rl_vec_free(spine);
}

static void dump_node(const struct sl_ctx *ctx, const struct sl_ast *n, int depth, FILE *out)
{
	if (n->kind == SL_AST_BINARY) {
		dump_chain(ctx, n, depth, out);
		return;
	}
	dump_line(ctx, n, depth, out);
	int d = depth + 1;
	switch (n->kind) {
	case SL_AST_CTOR:
		/* the space name comes before the components, as written */
		dump_child(ctx, n->a, d, out, false);
		dump_list(ctx, n, d, out);
		break;
	case SL_AST_FOR:
		/* missing parts are shown so that the four slots stay recognisable */
		dump_child(ctx, n->a, d, out, true);
		dump_child(ctx, n->b, d, out, true);
		dump_child(ctx, n->c, d, out, true);
		dump_child(ctx, n->d, d, out, true);
		break;
	default:
		dump_list(ctx, n, d, out);
		dump_child(ctx, n->a, d, out, false);
		dump_child(ctx, n->b, d, out, false);
		dump_child(ctx, n->c, d, out, false);
		dump_child(ctx, n->d, d, out, false);
		break;
	}
}

void sl_ast_dump(const struct sl_ctx *ctx, const struct sl_ast *node, FILE *out)
{
	if (!node) {
		fputs("(none)\n", out);
		return;
	}
	dump_node(ctx, node, 0, out);
}

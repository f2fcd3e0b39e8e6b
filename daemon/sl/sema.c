/*
 * Semantic analysis: names, types, overloads.
 *
 * Walks the tree once, with a stack of scopes, and annotates every
 * expression with its type (ast.ty), every name with its symbol (ast.sym)
 * and every built-in call with its overload (ast.overload). Uniform/varying
 * is not decided here: the IR's inference pass does that with the full
 * picture of control flow.
 *
 * Conversions, as the specification allows them implicitly:
 *   float -> color, point, vector, normal, matrix (promotion)
 *   point <-> vector <-> normal
 *   bool  -> float (0 or 1)
 * Colors and spatial triples convert only by an explicit cast.
 */
#include "sema.h"
#include "builtin.h"
#include "../common/strbuf.h"

#include <stdlib.h>
#include <string.h>

#define MAX_DEPTH 256

struct scope_entry {
	const char *name;
	struct sl_sym *sym;
};

struct sema {
	struct sl_ctx *ctx;
	RL_VEC(struct scope_entry) scope;
	RL_VEC(size_t) marks;
	struct sl_sym *func;          /* function whose body is being checked, or NULL */
	const char *defining;         /* its name, to explain recursion */
	enum sl_shader_kind kind;
	int loops;                    /* enclosing loops, illuminance included */
	int illuminance;              /* enclosing illuminance statements */
	int illuminate;               /* enclosing illuminate/solar statements */
	int depth;
};

static struct sl_type mktype(int base, int arraylen)
{
	struct sl_type t = { (uint8_t)base, SL_DETAIL_DEFAULT, arraylen };
	return t;
}

static const struct sl_type T_VOID = { SL_TYPE_VOID, 0, -1 };
static const struct sl_type T_FLOAT = { SL_TYPE_FLOAT, 0, -1 };
static const struct sl_type T_BOOL = { SL_TYPE_BOOL, 0, -1 };
static const struct sl_type T_STRING = { SL_TYPE_STRING, 0, -1 };
static const struct sl_type T_VECTOR = { SL_TYPE_VECTOR, 0, -1 };
static const struct sl_type T_POINT = { SL_TYPE_POINT, 0, -1 };

/* A parenthesized tuple without a type name whose type comes from context. */
static bool is_bare_tuple(const struct sl_ast *e)
{
	return e && e->kind == SL_AST_CTOR && e->type.base == SL_TYPE_VOID;
}

struct sl_type sl_sig_type(char c)
{
	switch (c) {
	case 'f': return mktype(SL_TYPE_FLOAT, -1);
	case 'c': return mktype(SL_TYPE_COLOR, -1);
	case 'p': return mktype(SL_TYPE_POINT, -1);
	case 'v': return mktype(SL_TYPE_VECTOR, -1);
	case 'n': return mktype(SL_TYPE_NORMAL, -1);
	case 'm': return mktype(SL_TYPE_MATRIX, -1);
	case 's': return mktype(SL_TYPE_STRING, -1);
	case 'F': return mktype(SL_TYPE_FLOAT, 0);
	case 'C': return mktype(SL_TYPE_COLOR, 0);
	case 'P': return mktype(SL_TYPE_POINT, 0);
	case 'V': return mktype(SL_TYPE_VECTOR, 0);
	case 'N': return mktype(SL_TYPE_NORMAL, 0);
	default: return mktype(SL_TYPE_VOID, -1);
	}
}

const char *sl_type_str(struct sl_ctx *ctx, struct sl_type t)
{
	const char *detail = t.detail == SL_DETAIL_UNIFORM ? "uniform " :
			     t.detail == SL_DETAIL_VARYING ? "varying " : "";
	if (t.arraylen > 0)
		return rl_arena_printf(ctx->arena, "%s%s[%d]", detail, sl_basetype_name(t.base),
				       t.arraylen);
	if (t.arraylen == 0)
		return rl_arena_printf(ctx->arena, "%s%s[]", detail, sl_basetype_name(t.base));
	return rl_arena_printf(ctx->arena, "%s%s", detail, sl_basetype_name(t.base));
}

static const char *tname(struct sema *s, struct sl_type t)
{
	t.detail = SL_DETAIL_DEFAULT;
	return sl_type_str(s->ctx, t);
}

/*
 * Cost of using a value of type @from where @to is wanted: 0 exact, higher
 * for implicit conversions, -1 when not allowed. Arrays must match in base
 * type; an unsized array (arraylen 0) accepts any length.
 */
static int convert_cost(struct sl_type to, struct sl_type from)
{
	if (to.arraylen >= 0 || from.arraylen >= 0) {
		if (to.arraylen < 0 || from.arraylen < 0 || to.base != from.base)
			return -1;
		if (to.arraylen != 0 && to.arraylen != from.arraylen)
			return -1;
		return 0;
	}
	if (to.base == from.base)
		return 0;
	if (sl_type_is_spatial(to.base) && sl_type_is_spatial(from.base))
		return 1;
	if (to.base == SL_TYPE_FLOAT && from.base == SL_TYPE_BOOL)
		return 1;
	if (to.base == SL_TYPE_BOOL && from.base == SL_TYPE_FLOAT)
		return 1;
	if ((sl_type_is_triple(to.base) || to.base == SL_TYPE_MATRIX) &&
	    (from.base == SL_TYPE_FLOAT || from.base == SL_TYPE_BOOL))
		return 2;
	return -1;
}

/* ---- scopes ---- */

static void push_scope(struct sema *s)
{
	rl_vec_push(s->marks, s->scope.len);
}

static void pop_scope(struct sema *s)
{
	s->scope.len = s->marks.data[--s->marks.len];
}

static struct sl_sym *lookup(struct sema *s, const char *name)
{
	for (size_t i = s->scope.len; i-- > 0;)
		if (s->scope.data[i].name == name)
			return s->scope.data[i].sym;
	return NULL;
}

/* Is @name declared in the innermost scope? */
static struct sl_sym *lookup_local(struct sema *s, const char *name)
{
	size_t begin = s->marks.len ? s->marks.data[s->marks.len - 1] : 0;
	for (size_t i = s->scope.len; i-- > begin;)
		if (s->scope.data[i].name == name)
			return s->scope.data[i].sym;
	return NULL;
}

static void declare(struct sema *s, struct sl_sym *sym)
{
	struct scope_entry e = { sym->name, sym };
	rl_vec_push(s->scope, e);
}

static struct sl_sym *new_sym(struct sema *s, enum sl_sym_kind kind, const char *name,
			      struct sl_type type)
{
	struct sl_sym *sym = rl_arena_alloc(s->ctx->arena, sizeof(*sym));
	sym->kind = kind;
	sym->name = name;
	sym->type = type;
	sym->global = -1;
	return sym;
}

/* ---- expressions ---- */

static struct sl_type check_expr(struct sema *s, struct sl_ast *e, struct sl_type expect);
static void check_stmt(struct sema *s, struct sl_ast *st);

/* Give a bare tuple its type from context (a triple type or matrix). */
static void settle_tuple(struct sema *s, struct sl_ast *e, struct sl_type t)
{
	if (!is_bare_tuple(e))
		return;
	int base = t.base;
	if (e->nlist == 16)
		base = SL_TYPE_MATRIX;
	else if (!sl_type_is_triple(base))
		base = SL_TYPE_POINT;
	e->type.base = (uint8_t)base;
	e->ty = mktype(base, -1);
}

/* Check @e as a value that will be converted to @to; report a mismatch. */
static bool check_convert(struct sema *s, struct sl_ast *e, struct sl_type to, const char *what)
{
	struct sl_type from = check_expr(s, e, to);
	if (from.base == SL_TYPE_VOID && !is_bare_tuple(e))
		return false; /* already reported */
	settle_tuple(s, e, to);
	from = e->ty;
	if (convert_cost(to, from) < 0) {
		sl_error(s->ctx, e->loc, "cannot convert %s to %s in %s", tname(s, from),
			 tname(s, to), what);
		return false;
	}
	return true;
}

static bool is_lvalue(struct sema *s, struct sl_ast *e)
{
	if (e->kind == SL_AST_IDENT)
		return e->sym && e->sym->kind != SL_SYM_FUNC;
	if (e->kind == SL_AST_INDEX)
		return e->a->kind == SL_AST_IDENT && e->a->ty.arraylen > 0;
	return false;
}

static struct sl_type check_ident(struct sema *s, struct sl_ast *e)
{
	struct sl_sym *sym = lookup(s, e->name);
	if (!sym && !strcmp(e->name, "PI")) {
		/* the language's one named constant */
		e->kind = SL_AST_NUM;
		e->num = 3.14159265358979323846;
		return T_FLOAT;
	}
	if (!sym || sym->kind == SL_SYM_FUNC) {
		if (sym)
			sl_error(s->ctx, e->loc, "function '%s' used as a variable", e->name);
		else
			sl_error(s->ctx, e->loc, "undeclared identifier '%s'", e->name);
		return T_VOID;
	}
	e->sym = sym;
	if (sym->kind == SL_SYM_GLOBAL) {
		int g = sym->global;
		/* PRMan's Ns: the normal the lights are evaluated with, which only a
		 * light has; a surface has N. */
		if (g == SL_GLOBAL_NS && s->kind != SL_SHADER_LIGHT) {
			sl_error(s->ctx, e->loc, "'Ns' is defined only in light shaders");
			return T_VOID;
		}
		if ((g == SL_GLOBAL_L || g == SL_GLOBAL_CL || g == SL_GLOBAL_OL) &&
		    s->kind != SL_SHADER_LIGHT && !s->illuminance && !s->func)
			sl_warning(s->ctx, e->loc,
				   "'%s' is only meaningful inside an illuminance statement",
				   e->name);
	}
	return sym->type;
}

/* Result type of arithmetic between two triples (same family). */
static int triple_result(int op, int a, int b)
{
	if (a == b) {
		if (op == SL_TOK_MINUS && a == SL_TYPE_POINT)
			return SL_TYPE_VECTOR;
		return a;
	}
	if (a == SL_TYPE_POINT || b == SL_TYPE_POINT)
		return SL_TYPE_POINT;
	return SL_TYPE_VECTOR;
}

static struct sl_type arith_type(struct sema *s, struct sl_ast *e, int op, struct sl_type a,
				 struct sl_type b)
{
	const char *opname = sl_tok_name((enum sl_tok)op);
	if (a.arraylen >= 0 || b.arraylen >= 0) {
		sl_error(s->ctx, e->loc, "operator %s cannot be applied to arrays", opname);
		return T_VOID;
	}
	int ab = a.base == SL_TYPE_BOOL ? SL_TYPE_FLOAT : a.base;
	int bb = b.base == SL_TYPE_BOOL ? SL_TYPE_FLOAT : b.base;
	if (ab == SL_TYPE_FLOAT && bb == SL_TYPE_FLOAT)
		return T_FLOAT;
	if (ab == SL_TYPE_MATRIX || bb == SL_TYPE_MATRIX) {
		if (ab == SL_TYPE_MATRIX && bb == SL_TYPE_MATRIX)
			return mktype(SL_TYPE_MATRIX, -1);
		if ((ab == SL_TYPE_FLOAT || bb == SL_TYPE_FLOAT) &&
		    (op == SL_TOK_STAR || op == SL_TOK_SLASH || op == SL_TOK_PLUS ||
		     op == SL_TOK_MINUS))
			return mktype(SL_TYPE_MATRIX, -1);
		goto bad;
	}
	if (ab == SL_TYPE_STRING || bb == SL_TYPE_STRING || ab == SL_TYPE_VOID ||
	    bb == SL_TYPE_VOID)
		goto bad;
	if (ab == SL_TYPE_FLOAT)
		return mktype(bb, -1);
	if (bb == SL_TYPE_FLOAT)
		return mktype(ab, -1);
	if ((ab == SL_TYPE_COLOR) != (bb == SL_TYPE_COLOR))
		goto bad;
	return mktype(triple_result(op, ab, bb), -1);
bad:
	sl_error(s->ctx, e->loc, "operator %s cannot be applied to %s and %s", opname,
		 tname(s, a), tname(s, b));
	return T_VOID;
}

/* One operator of a chain whose left operand, when @left_done, is already checked. */
static struct sl_type check_binary_node(struct sema *s, struct sl_ast *e, struct sl_type expect,
					bool left_done)
{
	int op = e->op;
	struct sl_type a, b;
	/* A bare tuple takes its type from the other operand. */
	if (!left_done && is_bare_tuple(e->a) && !is_bare_tuple(e->b)) {
		b = check_expr(s, e->b, expect);
		a = check_expr(s, e->a, b);
		settle_tuple(s, e->a, sl_type_is_triple(b.base) ? b : expect);
		a = e->a->ty;
	} else {
		if (!left_done)
			a = check_expr(s, e->a, expect);
		settle_tuple(s, e->a, expect);
		a = e->a->ty;
		/* float * f(...) in a colour's place: f's colour form, as for a lone call */
		bool arith = op == SL_TOK_PLUS || op == SL_TOK_MINUS || op == SL_TOK_STAR ||
			     op == SL_TOK_SLASH;
		b = check_expr(s, e->b, arith && a.base == SL_TYPE_FLOAT && a.arraylen < 0 &&
					sl_type_is_triple(expect.base) && expect.arraylen < 0 ? expect : a);
		settle_tuple(s, e->b, sl_type_is_triple(a.base) ? a : expect);
		b = e->b->ty;
	}
	if (a.base == SL_TYPE_VOID || b.base == SL_TYPE_VOID)
		return T_VOID;
	switch (op) {
	case SL_TOK_PLUS:
	case SL_TOK_MINUS:
	case SL_TOK_STAR:
	case SL_TOK_SLASH:
		return arith_type(s, e, op, a, b);
	case SL_TOK_DOT:
		if (a.arraylen < 0 && b.arraylen < 0 && sl_type_is_triple(a.base) &&
		    sl_type_is_triple(b.base) &&
		    (a.base == SL_TYPE_COLOR) == (b.base == SL_TYPE_COLOR))
			return T_FLOAT;
		break;
	case SL_TOK_CARET:
		if (a.arraylen < 0 && b.arraylen < 0 && sl_type_is_spatial(a.base) &&
		    sl_type_is_spatial(b.base))
			return T_VECTOR;
		break;
	case SL_TOK_LT:
	case SL_TOK_LE:
	case SL_TOK_GT:
	case SL_TOK_GE:
		if (convert_cost(T_FLOAT, a) >= 0 && convert_cost(T_FLOAT, b) >= 0)
			return T_BOOL;
		break;
	case SL_TOK_EQ:
	case SL_TOK_NE:
		if (a.arraylen >= 0 || b.arraylen >= 0)
			break;
		if (convert_cost(a, b) >= 0 || convert_cost(b, a) >= 0)
			return T_BOOL;
		break;
	case SL_TOK_AND:
	case SL_TOK_OR:
		if (convert_cost(T_BOOL, a) >= 0 && convert_cost(T_BOOL, b) >= 0)
			return T_BOOL;
		break;
	default:
		sl_error(s->ctx, e->loc, "unknown binary operator");
		return T_VOID;
	}
	sl_error(s->ctx, e->loc, "operator %s cannot be applied to %s and %s",
		 sl_tok_name((enum sl_tok)op), tname(s, a), tname(s, b));
	return T_VOID;
}

/*
 * A chain a + b + c + ... leans left: its spine is walked in a loop,
 * innermost operator first, so that ten thousand terms are not ten thousand
 * stack frames. Each operator's left operand is checked as check_expr()
 * would, with the chain's expected type.
 */
static struct sl_type check_binary(struct sema *s, struct sl_ast *e, struct sl_type expect)
{
	RL_VEC(struct sl_ast *) spine = { 0 };
	struct sl_ast *n = e;
	while (n->a && n->a->kind == SL_AST_BINARY) {
		rl_vec_push(spine, n);
		n = n->a;
	}
	struct sl_type t = check_binary_node(s, n, expect, false);
	for (size_t i = spine.len; i-- > 0;) {
		t.detail = SL_DETAIL_DEFAULT;
		spine.data[i]->a->ty = t;
		t = check_binary_node(s, spine.data[i], expect, true);
	}
	rl_vec_free(spine);
	return t;
}

static struct sl_type check_assign(struct sema *s, struct sl_ast *e)
{
	struct sl_type t = check_expr(s, e->a, T_VOID);
	if (t.base == SL_TYPE_VOID) {
		check_expr(s, e->b, T_VOID);
		return T_VOID;
	}
	if (!is_lvalue(s, e->a)) {
		sl_error(s->ctx, e->a->loc, "left side of assignment is not a variable");
		check_expr(s, e->b, t);
		return T_VOID;
	}
	if (e->op == SL_TOK_ASSIGN) {
		if (t.arraylen > 0 && e->b->kind == SL_AST_ARRAYLIT) {
			sl_error(s->ctx, e->b->loc, "array literals are only allowed in declarations");
			return T_VOID;
		}
		check_convert(s, e->b, t, "assignment");
		return t;
	}
	/* a op= b is a = a op b */
	static const int binop[] = { [SL_TOK_PLUS_ASSIGN] = SL_TOK_PLUS,
				     [SL_TOK_MINUS_ASSIGN] = SL_TOK_MINUS,
				     [SL_TOK_STAR_ASSIGN] = SL_TOK_STAR,
				     [SL_TOK_SLASH_ASSIGN] = SL_TOK_SLASH };
	struct sl_type b = check_expr(s, e->b, t);
	settle_tuple(s, e->b, t);
	b = e->b->ty;
	if (b.base == SL_TYPE_VOID)
		return T_VOID;
	struct sl_type r = arith_type(s, e, binop[e->op], t, b);
	if (r.base != SL_TYPE_VOID && convert_cost(t, r) < 0) {
		sl_error(s->ctx, e->loc, "result of %s is %s, which cannot be stored in %s",
			 sl_tok_name((enum sl_tok)e->op), tname(s, r), tname(s, t));
		return T_VOID;
	}
	return t;
}

/* ---- calls ---- */

/* Parse a signature "R:ARGS" into the result letter and the argument part. */
static const char *sig_args(const char *sig)
{
	const char *c = strchr(sig, ':');
	return c ? c + 1 : "";
}

struct sig_param {
	char letter;
	bool output;
};

/* Split an argument signature; returns the count, *rest = a final '*'. */
static int sig_params(const char *args, struct sig_param *out, int max, bool *rest)
{
	int n = 0;
	*rest = false;
	for (const char *p = args; *p; p++) {
		if (*p == '*') {
			*rest = true;
			break;
		}
		bool output = false;
		if (*p == '&') {
			output = true;
			p++;
		}
		if (n < max) {
			out[n].letter = *p;
			out[n].output = output;
		}
		n++;
	}
	return n;
}

/*
 * Score one built-in overload against the (already checked) arguments.
 * Returns -1 if it does not fit, else a cost (lower is better).
 */
static int score_builtin(struct sema *s, const struct sl_builtin *b, struct sl_ast **args,
			 int nargs, struct sl_type expect)
{
	struct sig_param ps[32];
	bool rest;
	int np = sig_params(sig_args(b->sig), ps, 32, &rest);
	if (np > 32 || nargs < np || (!rest && nargs != np))
		return -1;
	int cost = 0;
	for (int i = 0; i < np; i++) {
		struct sl_ast *a = args[i];
		if (ps[i].letter == '?') {
			if (ps[i].output && !is_lvalue(s, a))
				return -1;
			continue;
		}
		struct sl_type want = sl_sig_type(ps[i].letter);
		if (is_bare_tuple(a)) {
			if (a->nlist == 16 ? want.base != SL_TYPE_MATRIX
					   : !sl_type_is_triple(want.base) || want.arraylen >= 0)
				return -1;
			continue;
		}
		int c = convert_cost(want, a->ty);
		if (c < 0)
			return -1;
		if (ps[i].output) {
			/* Output arguments are written in place: no conversions but
			 * between spatial triples (same storage). */
			if (!is_lvalue(s, a) || (c > 1))
				return -1;
		}
		cost += c * 4;
	}
	/* A variadic overload fits worse the more arguments its '*' absorbs:
	 * texture(name, s, t) is the (s, t) form, not the one with no coordinates. */
	if (rest)
		cost += 1 + 2 * (nargs - np);
	/* Result type: prefer the one the context asks for. */
	struct sl_type r = sl_sig_type(b->sig[0]);
	if (expect.base != SL_TYPE_VOID && expect.arraylen < 0) {
		if (r.base == expect.base)
			;
		else if (convert_cost(expect, r) >= 0)
			cost += 1 + convert_cost(expect, r);
		else
			cost += 2;
	}
	return cost;
}

/* texture("name"[channel], ...): split the channel into its own argument. */
static void split_texname(struct sema *s, struct sl_ast *e)
{
	if (e->nlist == 0)
		return;
	struct sl_ast *first = e->list[0];
	struct sl_ast *chan;
	if (first->kind == SL_AST_INDEX) {
		chan = first->b;
		e->list[0] = first->a;
	} else {
		chan = sl_ast_new(s->ctx, SL_AST_NUM, first->loc);
		chan->num = 0;
	}
	struct sl_ast **nl = rl_arena_alloc(s->ctx->arena, sizeof(*nl) * (e->nlist + 1));
	nl[0] = e->list[0];
	nl[1] = chan;
	memcpy(nl + 2, e->list + 1, sizeof(*nl) * (e->nlist - 1));
	e->list = nl;
	e->nlist++;
}

static struct sl_type check_builtin_call(struct sema *s, struct sl_ast *e, int first,
					 struct sl_type expect)
{
	const char *name = e->name;
	if (sl_builtins[first].flags & SL_BIF_TEXNAME) {
		split_texname(s, e);
		if (e->nlist >= 2) {
			check_convert(s, e->list[0], T_STRING, "texture name");
			check_convert(s, e->list[1], T_FLOAT, "texture channel");
		}
	}
	int start = (sl_builtins[first].flags & SL_BIF_TEXNAME) && e->nlist >= 2 ? 2 : 0;
	bool ok = true;
	for (uint32_t i = (uint32_t)start; i < e->nlist; i++) {
		struct sl_type t = check_expr(s, e->list[i], T_VOID);
		if (t.base == SL_TYPE_VOID && !is_bare_tuple(e->list[i]))
			ok = false;
	}
	if (!ok)
		return T_VOID;

	/* The texture name and channel are not part of the signature match. */
	struct sl_ast **args = e->list;
	int nargs = (int)e->nlist;
	int best = -1, best_cost = 0, ties = 0;
	for (uint32_t i = (uint32_t)first; i < sl_nbuiltins && !strcmp(sl_builtins[i].name, name);
	     i++) {
		int c;
		if (start == 2) {
			/* match "s" + the arguments after the channel */
			struct sl_ast *tmp[64];
			if (nargs - 1 > 64)
				continue;
			tmp[0] = args[0];
			for (int k = 2; k < nargs; k++)
				tmp[k - 1] = args[k];
			c = score_builtin(s, &sl_builtins[i], tmp, nargs - 1, expect);
		} else {
			c = score_builtin(s, &sl_builtins[i], args, nargs, expect);
		}
		if (c < 0)
			continue;
		if (best < 0 || c < best_cost) {
			best = (int)i;
			best_cost = c;
			ties = 0;
		} else if (c == best_cost) {
			ties++;
		}
	}
	if (best < 0) {
		struct rl_strbuf msg = { 0 };
		for (int k = start ? 2 : 0; k < nargs; k++)
			rl_strbuf_printf(&msg, "%s%s", k > (start ? 2 : 0) ? ", " : "",
					 is_bare_tuple(args[k]) ? "tuple" : tname(s, args[k]->ty));
		sl_error(s->ctx, e->loc, "no version of '%s' takes (%s)", name,
			 rl_strbuf_str(&msg));
		rl_strbuf_finish(&msg);
		return T_VOID;
	}
	const struct sl_builtin *b = &sl_builtins[best];
	e->overload = best;
	/* Give bare tuples the parameter's type, and check output arguments. */
	struct sig_param ps[32];
	bool rest;
	int np = sig_params(sig_args(b->sig), ps, 32, &rest);
	for (int i = 0; i < np; i++) {
		int ai = start == 2 && i > 0 ? i + 1 : i;
		if (ai >= nargs)
			break;
		if (ps[i].letter != '?')
			settle_tuple(s, args[ai], sl_sig_type(ps[i].letter));
	}
	if (b->id == SL_BI_PRINTF || b->id == SL_BI_FORMAT || b->id == SL_BI_CONCAT) {
		for (int i = 0; i < nargs; i++) {
			settle_tuple(s, args[i], T_POINT);
			if (args[i]->ty.arraylen >= 0) {
				sl_error(s->ctx, args[i]->loc, "'%s' cannot take an array", name);
				return T_VOID;
			}
		}
		if (b->id == SL_BI_CONCAT)
			for (int i = 0; i < nargs; i++)
				if (args[i]->ty.base != SL_TYPE_STRING) {
					sl_error(s->ctx, args[i]->loc,
						 "concat() takes strings, not %s",
						 tname(s, args[i]->ty));
					return T_VOID;
				}
	}
	if (b->id == SL_BI_SPLINE || b->id == SL_BI_MIN || b->id == SL_BI_MAX) {
		/* The extra values of a variadic call must have the values' type. */
		struct sl_type vt = sl_sig_type(b->sig[0]);
		for (int i = np; i < nargs; i++) {
			settle_tuple(s, args[i], vt);
			if (convert_cost(vt, args[i]->ty) < 0) {
				sl_error(s->ctx, args[i]->loc, "'%s' value must be %s, not %s", name,
					 tname(s, vt), tname(s, args[i]->ty));
				return T_VOID;
			}
		}
	}
	if (b->flags & SL_BIF_TEXNAME) {
		/* Options are "name", value pairs after the coordinates. */
		int nopt = nargs - (np + 1);
		int base = np + 1;
		if (nopt % 2) {
			sl_error(s->ctx, e->loc,
				 "'%s' options must come in pairs: \"name\", value", name);
			return T_VOID;
		}
		for (int i = base; i < nargs; i += 2) {
			if (args[i]->kind != SL_AST_STR) {
				sl_error(s->ctx, args[i]->loc,
					 "'%s' option name must be a string constant", name);
				return T_VOID;
			}
			static const char *const known[] = { "blur", "sblur", "tblur", "width",
							     "swidth", "twidth", "samples",
							     "bias", "fill", "filter" };
			bool found = false;
			for (size_t k = 0; k < sizeof(known) / sizeof(known[0]); k++)
				if (!strcmp(args[i]->str, known[k]))
					found = true;
			if (!found) {
				sl_warning(s->ctx, args[i]->loc, "unknown %s option \"%s\" ignored",
					   name, args[i]->str);
			} else if (!strcmp(args[i]->str, "filter")) {
				if (args[i + 1]->ty.base != SL_TYPE_STRING) {
					sl_error(s->ctx, args[i + 1]->loc,
						 "\"filter\" takes a string");
					return T_VOID;
				}
			} else if (convert_cost(T_FLOAT, args[i + 1]->ty) < 0) {
				sl_error(s->ctx, args[i + 1]->loc, "option \"%s\" takes a float",
					 args[i]->str);
				return T_VOID;
			}
		}
	}
	if ((b->id == SL_BI_FORMAT || b->id == SL_BI_PRINTF) && args[0]->kind != SL_AST_STR)
		sl_warning(s->ctx, args[0]->loc, "%s format is not a string constant", name);
	if (ties && getenv("RELIGHT_DEBUG_OVERLOADS"))
		sl_warning(s->ctx, e->loc, "ambiguous call of '%s'", name);
	struct sl_type r = sl_sig_type(b->sig[0]);
	if (b->sig[0] == '-')
		r = T_VOID;
	return r;
}

static bool returns_value(const struct sl_type t)
{
	return t.base != SL_TYPE_VOID;
}

static struct sl_type check_user_call(struct sema *s, struct sl_ast *e, struct sl_sym *f,
				      struct sl_type expect)
{
	for (uint32_t i = 0; i < e->nlist; i++)
		check_expr(s, e->list[i], T_VOID);
	struct sl_sym *best = NULL;
	int best_cost = 0;
	for (struct sl_sym *o = f; o; o = o->next) {
		struct sl_ast *fn = o->decl;
		if (fn->nlist != e->nlist)
			continue;
		int cost = 0;
		for (uint32_t i = 0; i < e->nlist && cost >= 0; i++) {
			struct sl_ast *a = e->list[i];
			struct sl_type want = fn->list[i]->type;
			int c;
			if (is_bare_tuple(a))
				c = sl_type_is_triple(want.base) || want.base == SL_TYPE_MATRIX ? 0 : -1;
			else if (a->ty.base == SL_TYPE_VOID)
				c = -1;
			else
				c = convert_cost(want, a->ty);
			if (c >= 0 && fn->list[i]->output && (!is_lvalue(s, a) || c > 1))
				c = -1;
			cost = c < 0 ? -1 : cost + c * 4;
		}
		if (cost < 0)
			continue;
		if (expect.base != SL_TYPE_VOID && o->type.base != expect.base)
			cost += 1;
		if (!best || cost < best_cost) {
			best = o;
			best_cost = cost;
		}
	}
	if (!best) {
		sl_error(s->ctx, e->loc, "no version of function '%s' takes these %u argument%s",
			 e->name, e->nlist, e->nlist == 1 ? "" : "s");
		return T_VOID;
	}
	e->sym = best;
	for (uint32_t i = 0; i < e->nlist; i++)
		settle_tuple(s, e->list[i], best->decl->list[i]->type);
	return best->type;
}

static struct sl_type check_call(struct sema *s, struct sl_ast *e, struct sl_type expect)
{
	struct sl_sym *sym = lookup(s, e->name);
	if (sym && sym->kind == SL_SYM_FUNC)
		return check_user_call(s, e, sym, expect);
	if (sym) {
		sl_error(s->ctx, e->loc, "'%s' is a variable, not a function", e->name);
		return T_VOID;
	}
	int first = sl_builtin_find(e->name);
	if (first < 0) {
		if (s->defining && e->name == s->defining)
			sl_error(s->ctx, e->loc,
				 "function '%s' calls itself: RSL functions cannot be recursive",
				 e->name);
		else if (!strcmp(e->name, "gather") || !strcmp(e->name, "photonmap") ||
			 !strcmp(e->name, "bake3d") || !strcmp(e->name, "texture3d"))
			sl_error(s->ctx, e->loc, "'%s' is not supported by relight", e->name);
		else
			sl_error(s->ctx, e->loc, "unknown function '%s'", e->name);
		for (uint32_t i = 0; i < e->nlist; i++)
			check_expr(s, e->list[i], T_VOID);
		return T_VOID;
	}
	return check_builtin_call(s, e, first, expect);
}

static struct sl_type check_ctor(struct sema *s, struct sl_ast *e, struct sl_type expect)
{
	if (e->a) {
		struct sl_type st = check_expr(s, e->a, T_STRING);
		if (st.base != SL_TYPE_VOID && (st.base != SL_TYPE_STRING || st.arraylen >= 0))
			sl_error(s->ctx, e->a->loc, "space name must be a string, not %s",
				 tname(s, st));
		if (e->type.base == SL_TYPE_FLOAT || e->type.base == SL_TYPE_STRING)
			sl_error(s->ctx, e->loc, "a %s has no coordinate system",
				 sl_basetype_name(e->type.base));
	}
	int base = e->type.base;
	if (base == SL_TYPE_VOID) {
		/* a bare tuple: settled by the context */
		for (uint32_t i = 0; i < e->nlist; i++)
			check_convert(s, e->list[i], T_FLOAT, "tuple component");
		if (e->nlist != 3 && e->nlist != 16) {
			sl_error(s->ctx, e->loc, "a tuple needs 3 or 16 components, not %u",
				 e->nlist);
			return T_VOID;
		}
		if (sl_type_is_triple(expect.base) && expect.arraylen < 0 && e->nlist == 3)
			settle_tuple(s, e, expect);
		else if (e->nlist == 16)
			settle_tuple(s, e, mktype(SL_TYPE_MATRIX, -1));
		return e->type.base == SL_TYPE_VOID ? T_VOID : e->ty;
	}
	struct sl_type t = mktype(base, -1);
	if (e->nlist == 1) {
		struct sl_type from = check_expr(s, e->list[0], t);
		settle_tuple(s, e->list[0], t);
		from = e->list[0]->ty;
		if (from.base == SL_TYPE_VOID)
			return T_VOID;
		bool ok = from.arraylen < 0 &&
			  (convert_cost(t, from) >= 0 ||
			   (sl_type_is_triple(base) && sl_type_is_triple(from.base)));
		if (!ok) {
			sl_error(s->ctx, e->loc, "cannot cast %s to %s", tname(s, from), tname(s, t));
			return T_VOID;
		}
		return t;
	}
	int want = sl_type_is_triple(base) ? 3 : base == SL_TYPE_MATRIX ? 16 : 1;
	if ((int)e->nlist != want) {
		sl_error(s->ctx, e->loc, "%s constructor needs %d component%s, not %u",
			 sl_basetype_name(base), want, want == 1 ? "" : "s", e->nlist);
		return T_VOID;
	}
	for (uint32_t i = 0; i < e->nlist; i++)
		check_convert(s, e->list[i], T_FLOAT, "constructor component");
	return t;
}

static struct sl_type check_expr_inner(struct sema *s, struct sl_ast *e, struct sl_type expect)
{
	switch (e->kind) {
	case SL_AST_NUM:
		return T_FLOAT;
	case SL_AST_STR:
		return T_STRING;
	case SL_AST_IDENT:
		return check_ident(s, e);
	case SL_AST_UNARY: {
		struct sl_type a = check_expr(s, e->a, expect);
		settle_tuple(s, e->a, expect);
		a = e->a->ty;
		if (a.base == SL_TYPE_VOID)
			return T_VOID;
		if (e->op == SL_TOK_BANG) {
			if (convert_cost(T_BOOL, a) >= 0)
				return T_BOOL;
		} else if (a.arraylen < 0 && (a.base == SL_TYPE_FLOAT || a.base == SL_TYPE_BOOL ||
					      sl_type_is_triple(a.base) ||
					      a.base == SL_TYPE_MATRIX)) {
			return a.base == SL_TYPE_BOOL ? T_FLOAT : a;
		}
		sl_error(s->ctx, e->loc, "operator %s cannot be applied to %s",
			 sl_tok_name((enum sl_tok)e->op), tname(s, a));
		return T_VOID;
	}
	case SL_AST_BINARY:
		return check_binary(s, e, expect);
	case SL_AST_ASSIGN:
		return check_assign(s, e);
	case SL_AST_INCDEC: {
		struct sl_type t = check_expr(s, e->a, T_VOID);
		if (t.base == SL_TYPE_VOID)
			return T_VOID;
		if (!is_lvalue(s, e->a) || t.base != SL_TYPE_FLOAT || t.arraylen >= 0) {
			sl_error(s->ctx, e->loc, "operator %s needs a float variable",
				 sl_tok_name((enum sl_tok)e->op));
			return T_VOID;
		}
		return T_FLOAT;
	}
	case SL_AST_COND: {
		struct sl_type c = check_expr(s, e->a, T_BOOL);
		if (c.base != SL_TYPE_VOID && convert_cost(T_BOOL, c) < 0)
			sl_error(s->ctx, e->a->loc, "condition must be a boolean or float, not %s",
				 tname(s, c));
		struct sl_type a = check_expr(s, e->b, expect);
		struct sl_type b = check_expr(s, e->c, expect);
		if (is_bare_tuple(e->b))
			settle_tuple(s, e->b, sl_type_is_triple(b.base) ? b : expect);
		if (is_bare_tuple(e->c))
			settle_tuple(s, e->c, sl_type_is_triple(e->b->ty.base) ? e->b->ty : expect);
		a = e->b->ty;
		b = e->c->ty;
		if (a.base == SL_TYPE_VOID || b.base == SL_TYPE_VOID)
			return T_VOID;
		if (a.arraylen >= 0 || b.arraylen >= 0) {
			sl_error(s->ctx, e->loc, "?: cannot choose between arrays");
			return T_VOID;
		}
		if (a.base == b.base)
			return a;
		if (a.base == SL_TYPE_BOOL && b.base == SL_TYPE_BOOL)
			return T_BOOL;
		/* the wider type wins */
		if (convert_cost(a, b) >= 0 && (b.base == SL_TYPE_FLOAT || b.base == SL_TYPE_BOOL))
			return a;
		if (convert_cost(b, a) >= 0 && (a.base == SL_TYPE_FLOAT || a.base == SL_TYPE_BOOL))
			return b;
		if (sl_type_is_spatial(a.base) && sl_type_is_spatial(b.base))
			return sl_type_is_spatial(expect.base) ? mktype(expect.base, -1) : a;
		sl_error(s->ctx, e->loc, "?: branches have different types: %s and %s",
			 tname(s, a), tname(s, b));
		return T_VOID;
	}
	case SL_AST_CALL:
		return check_call(s, e, expect);
	case SL_AST_INDEX: {
		struct sl_type a = check_expr(s, e->a, T_VOID);
		struct sl_type i = check_expr(s, e->b, T_FLOAT);
		if (a.base == SL_TYPE_VOID)
			return T_VOID;
		if (a.arraylen < 0) {
			if (a.base == SL_TYPE_STRING)
				sl_error(s->ctx, e->loc,
					 "a [channel] subscript is only allowed on the texture name "
					 "of texture(), environment() or shadow()");
			else
				sl_error(s->ctx, e->loc, "subscripted value is %s, not an array",
					 tname(s, a));
			return T_VOID;
		}
		if (i.base != SL_TYPE_VOID && convert_cost(T_FLOAT, i) < 0)
			sl_error(s->ctx, e->b->loc, "array index must be a float, not %s",
				 tname(s, i));
		if (e->b->kind == SL_AST_NUM && a.arraylen > 0 &&
		    (e->b->num < 0 || e->b->num >= a.arraylen))
			sl_error(s->ctx, e->b->loc, "array index %g is out of range [0, %d]",
				 e->b->num, a.arraylen - 1);
		return mktype(a.base, -1);
	}
	case SL_AST_CTOR:
		return check_ctor(s, e, expect);
	case SL_AST_ARRAYLIT:
		sl_error(s->ctx, e->loc, "an array literal {...} is only allowed as an initializer");
		return T_VOID;
	default:
		sl_error(s->ctx, e->loc, "expected an expression");
		return T_VOID;
	}
}

static struct sl_type check_expr(struct sema *s, struct sl_ast *e, struct sl_type expect)
{
	if (++s->depth > MAX_DEPTH) {
		sl_error(s->ctx, e->loc, "expression nested too deeply");
		s->depth--;
		e->ty = T_VOID;
		return T_VOID;
	}
	struct sl_type t = check_expr_inner(s, e, expect);
	s->depth--;
	t.detail = SL_DETAIL_DEFAULT;
	if (!is_bare_tuple(e) || t.base != SL_TYPE_VOID)
		e->ty = t;
	return t;
}

/* ---- declarations and statements ---- */

static void check_cond(struct sema *s, struct sl_ast *c)
{
	struct sl_type t = check_expr(s, c, T_BOOL);
	if (t.base != SL_TYPE_VOID && (t.arraylen >= 0 || convert_cost(T_BOOL, t) < 0))
		sl_error(s->ctx, c->loc, "condition must be a boolean or float, not %s", tname(s, t));
}

static void check_init(struct sema *s, struct sl_ast *var)
{
	struct sl_ast *init = var->a;
	if (!init)
		return;
	if (init->kind == SL_AST_ARRAYLIT) {
		if (var->type.arraylen < 0) {
			sl_error(s->ctx, init->loc, "'%s' is not an array", var->name);
			return;
		}
		if (var->type.arraylen > 0 && init->nlist != (uint32_t)var->type.arraylen)
			sl_error(s->ctx, init->loc, "'%s' has %d elements but %u initializers",
				 var->name, var->type.arraylen, init->nlist);
		struct sl_type et = mktype(var->type.base, -1);
		for (uint32_t i = 0; i < init->nlist; i++)
			check_convert(s, init->list[i], et, "array initializer");
		init->ty = var->type;
		return;
	}
	check_convert(s, init, var->type, "initializer");
}

/* Declare a variable (local, formal or parameter) from a VAR node. */
static struct sl_sym *declare_var(struct sema *s, struct sl_ast *v, bool is_param,
				  bool is_formal)
{
	if (v->type.base == SL_TYPE_VOID || v->type.base == SL_TYPE_BOOL) {
		sl_error(s->ctx, v->loc, "variable '%s' cannot have type %s", v->name,
			 sl_basetype_name(v->type.base));
		v->type.base = SL_TYPE_FLOAT;
	}
	if (v->type.arraylen == 0 && !is_formal) {
		if (v->a && v->a->kind == SL_AST_ARRAYLIT && v->a->nlist > 0) {
			v->type.arraylen = (int32_t)v->a->nlist;
		} else {
			sl_error(s->ctx, v->loc, "array '%s' needs a size", v->name);
			v->type.arraylen = 1;
		}
	}
	struct sl_sym *old = lookup_local(s, v->name);
	if (old && !v->is_extern)
		sl_error(s->ctx, v->loc, "'%s' is already declared in this scope", v->name);
	struct sl_sym *sym = new_sym(s, SL_SYM_VAR, v->name, v->type);
	sym->output = v->output;
	sym->is_param = is_param;
	sym->is_formal = is_formal;
	sym->decl = v;
	v->sym = sym;
	v->ty = v->type;
	return sym;
}

static void check_extern(struct sema *s, struct sl_ast *v)
{
	/* `extern float x;` makes a variable of an enclosing scope (or a global) visible. */
	struct sl_sym *sym = lookup(s, v->name);
	if (!sym || sym->kind == SL_SYM_FUNC) {
		sl_error(s->ctx, v->loc, "extern '%s' names no variable of an enclosing scope",
			 v->name);
		return;
	}
	if (sym->type.base != v->type.base || (sym->type.arraylen >= 0) != (v->type.arraylen >= 0))
		sl_error(s->ctx, v->loc, "extern '%s' is declared %s but is %s", v->name,
			 tname(s, v->type), tname(s, sym->type));
	v->sym = sym;
	v->ty = sym->type;
	declare(s, sym);
}

static void check_decl(struct sema *s, struct sl_ast *d)
{
	for (uint32_t i = 0; i < d->nlist; i++) {
		struct sl_ast *v = d->list[i];
		if (v->is_extern) {
			check_extern(s, v);
			continue;
		}
		/* The initializer is checked before the name is visible. */
		if (v->type.arraylen == 0 && v->a && v->a->kind == SL_AST_ARRAYLIT)
			v->type.arraylen = (int32_t)v->a->nlist;
		struct sl_sym *sym = declare_var(s, v, false, false);
		check_init(s, v);
		declare(s, sym);
	}
}

/* Does the body of a function hold a return before its last statement? */
static bool has_early_return(const struct sl_ast *st, bool tail)
{
	if (!st)
		return false;
	switch (st->kind) {
	case SL_AST_RETURN:
		return !tail;
	case SL_AST_BLOCK:
		for (uint32_t i = 0; i < st->nlist; i++)
			if (has_early_return(st->list[i], tail && i + 1 == st->nlist))
				return true;
		return false;
	case SL_AST_IF:
		return has_early_return(st->b, false) || has_early_return(st->c, false);
	case SL_AST_WHILE:
		return has_early_return(st->b, false);
	case SL_AST_FOR:
		return has_early_return(st->d, false);
	case SL_AST_ILLUMINANCE:
	case SL_AST_ILLUMINATE:
	case SL_AST_SOLAR:
		return has_early_return(st->a, false);
	default:
		return false;
	}
}

static bool ends_with_return(const struct sl_ast *body)
{
	if (!body)
		return false;
	if (body->kind == SL_AST_RETURN)
		return true;
	if (body->kind == SL_AST_BLOCK && body->nlist)
		return ends_with_return(body->list[body->nlist - 1]);
	return false;
}

static void check_func(struct sema *s, struct sl_ast *f)
{
	struct sl_sym *prev = lookup(s, f->name);
	if (prev && prev->kind != SL_SYM_FUNC && lookup_local(s, f->name)) {
		sl_error(s->ctx, f->loc, "'%s' is already declared as a variable", f->name);
		prev = NULL;
	}
	if (prev && prev->kind != SL_SYM_FUNC)
		prev = NULL;
	if (sl_builtin_find(f->name) >= 0)
		sl_warning(s->ctx, f->loc, "function '%s' hides the built-in of the same name",
			   f->name);
	struct sl_sym *sym = new_sym(s, SL_SYM_FUNC, f->name, f->type);
	sym->decl = f;
	sym->next = prev;
	f->sym = sym;
	f->ty = f->type;
	if (f->type.arraylen >= 0)
		sl_error(s->ctx, f->loc, "function '%s' cannot return an array", f->name);

	struct sl_sym *outer_func = s->func;
	const char *outer_def = s->defining;
	int outer_loops = s->loops, outer_ill = s->illuminance, outer_illum = s->illuminate;
	s->func = sym;
	s->defining = f->name;
	s->loops = 0;
	s->illuminance = 0;
	s->illuminate = 0;
	push_scope(s);
	for (uint32_t i = 0; i < f->nlist; i++) {
		struct sl_ast *p = f->list[i];
		if (p->a)
			sl_error(s->ctx, p->a->loc, "function parameters cannot have defaults");
		declare(s, declare_var(s, p, false, true));
	}
	check_stmt(s, f->a);
	pop_scope(s);
	s->func = outer_func;
	s->defining = outer_def;
	s->loops = outer_loops;
	s->illuminance = outer_ill;
	s->illuminate = outer_illum;

	sym->has_return = has_early_return(f->a, true);
	if (returns_value(f->type) && !ends_with_return(f->a) && !sym->has_return)
		sl_error(s->ctx, f->loc, "function '%s' must return a %s", f->name,
			 tname(s, f->type));
	/* Visible after its definition (and not inside it: no recursion). */
	declare(s, sym);
}

static void check_light_args(struct sema *s, struct sl_ast *st, int first_point)
{
	/* [category,] P [, axis, angle] */
	uint32_t n = st->nlist;
	uint32_t i = 0;
	if (first_point) {
		if (n == 2 || n == 4) {
			check_convert(s, st->list[0], T_STRING, "illuminance category");
			i = 1;
		}
		if (n - i != 1 && n - i != 3) {
			sl_error(s->ctx, st->loc,
				 "illuminance takes ([category,] position [, axis, angle])");
			return;
		}
	} else if (n != 1 && n != 3) {
		sl_error(s->ctx, st->loc, "illuminate takes (position [, axis, angle])");
		return;
	}
	check_convert(s, st->list[i], T_POINT, "light position");
	if (n - i == 3) {
		check_convert(s, st->list[i + 1], T_VECTOR, "axis");
		check_convert(s, st->list[i + 2], T_FLOAT, "angle");
	}
}

static void check_stmt(struct sema *s, struct sl_ast *st)
{
	if (!st || s->ctx->too_many)
		return;
	if (++s->depth > MAX_DEPTH) {
		sl_error(s->ctx, st->loc, "statements nested too deeply");
		s->depth--;
		return;
	}
	switch (st->kind) {
	case SL_AST_BLOCK:
		push_scope(s);
		for (uint32_t i = 0; i < st->nlist; i++)
			check_stmt(s, st->list[i]);
		pop_scope(s);
		break;
	case SL_AST_EXPR: {
		struct sl_ast *e = st->a;
		check_expr(s, e, T_VOID);
		if (is_bare_tuple(e))
			settle_tuple(s, e, T_POINT);
		break;
	}
	case SL_AST_DECL:
		check_decl(s, st);
		break;
	case SL_AST_FUNC:
		check_func(s, st);
		break;
	case SL_AST_IF:
		check_cond(s, st->a);
		check_stmt(s, st->b);
		check_stmt(s, st->c);
		break;
	case SL_AST_WHILE:
		check_cond(s, st->a);
		s->loops++;
		check_stmt(s, st->b);
		s->loops--;
		break;
	case SL_AST_FOR:
		push_scope(s);
		if (st->a) {
			if (st->a->kind == SL_AST_DECL)
				check_decl(s, st->a);
			else
				check_stmt(s, st->a);
		}
		if (st->b)
			check_cond(s, st->b);
		if (st->c)
			check_expr(s, st->c, T_VOID);
		s->loops++;
		check_stmt(s, st->d);
		s->loops--;
		pop_scope(s);
		break;
	case SL_AST_BREAK:
	case SL_AST_CONTINUE: {
		const char *what = st->kind == SL_AST_BREAK ? "break" : "continue";
		if (st->num < 1 || st->num != (double)(int)st->num)
			sl_error(s->ctx, st->loc, "%s level must be a positive integer", what);
		else if ((int)st->num > s->loops)
			sl_error(s->ctx, st->loc, "%s %d is not inside %d loop%s", what, (int)st->num,
				 (int)st->num, st->num == 1 ? "" : "s");
		break;
	}
	case SL_AST_RETURN:
		if (s->func) {
			struct sl_type rt = s->func->type;
			if (!returns_value(rt)) {
				if (st->a) {
					sl_error(s->ctx, st->loc, "void function '%s' returns a value",
						 s->func->name);
					check_expr(s, st->a, T_VOID);
				}
			} else if (!st->a) {
				sl_error(s->ctx, st->loc, "function '%s' must return a %s",
					 s->func->name, tname(s, rt));
			} else {
				check_convert(s, st->a, rt, "return");
			}
		} else if (st->a) {
			sl_error(s->ctx, st->loc, "a shader cannot return a value");
			check_expr(s, st->a, T_VOID);
		}
		break;
	case SL_AST_ILLUMINANCE:
		if (s->kind == SL_SHADER_LIGHT)
			sl_error(s->ctx, st->loc, "illuminance is not allowed in a light shader");
		check_light_args(s, st, 1);
		s->loops++;
		s->illuminance++;
		check_stmt(s, st->a);
		s->illuminance--;
		s->loops--;
		break;
	case SL_AST_ILLUMINATE:
	case SL_AST_SOLAR:
		if (s->kind != SL_SHADER_LIGHT)
			sl_error(s->ctx, st->loc, "%s is only allowed in a light shader",
				 st->kind == SL_AST_SOLAR ? "solar" : "illuminate");
		if (s->illuminate)
			sl_error(s->ctx, st->loc, "%s cannot be nested",
				 st->kind == SL_AST_SOLAR ? "solar" : "illuminate");
		if (st->kind == SL_AST_ILLUMINATE) {
			check_light_args(s, st, 0);
		} else if (st->nlist == 0) {
			/* Light from every direction: L is -Ns (see exec.c, op_emit). */
		} else if (st->nlist == 2) {
			check_convert(s, st->list[0], T_VECTOR, "axis");
			check_convert(s, st->list[1], T_FLOAT, "angle");
		} else {
			sl_error(s->ctx, st->loc, "solar takes (axis, angle)");
		}
		s->illuminate++;
		check_stmt(s, st->a);
		s->illuminate--;
		break;
	case SL_AST_EMPTY:
		break;
	default:
		sl_error(s->ctx, st->loc, "expected a statement");
		break;
	}
	s->depth--;
}

/* RISpec 3.2's imager globals: the pixel (P, Ci, Oi, alpha) and the frame
 * (ncomps, time, dtime), nothing of any surface; alpha is an imager's alone. */
static bool global_visible(enum sl_shader_kind kind, enum sl_global g)
{
	if (kind != SL_SHADER_IMAGER)
		return g != SL_GLOBAL_ALPHA;
	return g == SL_GLOBAL_P || g == SL_GLOBAL_CI || g == SL_GLOBAL_OI ||
	       g == SL_GLOBAL_ALPHA || g == SL_GLOBAL_NCOMPS || g == SL_GLOBAL_TIME ||
	       g == SL_GLOBAL_DTIME;
}

static void declare_globals(struct sema *s)
{
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		if (!global_visible(s->kind, (enum sl_global)g))
			continue;
		struct sl_type t = sl_global_type((enum sl_global)g);
		struct sl_sym *sym =
			new_sym(s, SL_SYM_GLOBAL, sl_intern_cstr(s->ctx, sl_global_name(g)), t);
		sym->global = g;
		declare(s, sym);
	}
}

static void check_shader(struct sema *s, struct sl_ast *sh)
{
	s->kind = (enum sl_shader_kind)sh->op;
	push_scope(s);
	for (uint32_t i = 0; i < sh->nlist; i++) {
		struct sl_ast *p = sh->list[i];
		if (!p->a)
			sl_error(s->ctx, p->loc, "shader parameter '%s' needs a default value",
				 p->name);
		struct sl_sym *sym = declare_var(s, p, true, false);
		check_init(s, p);
		declare(s, sym);
	}
	check_stmt(s, sh->a);
	pop_scope(s);
}

struct sl_ast *sl_sema(struct sl_ctx *ctx, struct sl_ast *unit)
{
	struct sema s = { .ctx = ctx };
	struct sl_ast *shader = NULL;
	/* The illuminance checks in functions are made where they are called;
	 * the globals they see are the shader kind's. */
	s.kind = SL_SHADER_SURFACE;
	for (uint32_t i = 0; unit && i < unit->nlist; i++) {
		struct sl_ast *n = unit->list[i];
		if (n->kind == SL_AST_SHADER) {
			if (shader) {
				sl_error(ctx, n->loc,
					 "a second shader '%s' in one file (the first is '%s')",
					 n->name, shader->name);
				continue;
			}
			shader = n;
		}
	}
	if (shader)
		s.kind = (enum sl_shader_kind)shader->op;
	push_scope(&s);
	declare_globals(&s);
	for (uint32_t i = 0; unit && i < unit->nlist && !ctx->too_many; i++) {
		struct sl_ast *n = unit->list[i];
		if (n->kind == SL_AST_FUNC)
			check_func(&s, n);
		else if (n == shader)
			check_shader(&s, n);
	}
	pop_scope(&s);
	rl_vec_free(s.scope);
	rl_vec_free(s.marks);
	if (!shader && !ctx->nerrors) {
		struct sl_loc loc = { 0, 1, 1 };
		sl_error(ctx, loc, "no shader definition (surface, light, displacement or imager) "
			 "found");
	}
	return ctx->nerrors ? NULL : shader;
}

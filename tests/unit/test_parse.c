/* Tests of the RSL parser (parse.c) and the AST utilities (ast.c). */
#include "test.h"

#include "ast.h"
#include "../common/strbuf.h"

#include <stdint.h>
#include <stdio.h>

/* ---- fixture: one compilation with its diagnostics captured ---- */

struct fx {
	struct sl_ctx ctx;
	FILE *diag;
	char *diag_text;
	size_t diag_len;
	struct sl_token_list toks;
	struct sl_ast *unit;
};

static void fx_init(struct fx *fx)
{
	memset(fx, 0, sizeof(*fx));
	fx->diag = open_memstream(&fx->diag_text, &fx->diag_len);
	struct sl_options opts = {.diag = fx->diag, .max_errors = 50};
	sl_ctx_init(&fx->ctx, &opts);
}

static void fx_finish(struct fx *fx)
{
	rl_vec_free(fx->toks);
	sl_ctx_finish(&fx->ctx);
	fclose(fx->diag);
	free(fx->diag_text);
}

/* Everything reported so far. */
static const char *fx_diag(struct fx *fx)
{
	fflush(fx->diag);
	return fx->diag_text ? fx->diag_text : "";
}

/* Preprocess and parse @src as the file "t.sl". */
static struct sl_ast *fx_parse(struct fx *fx, const char *src)
{
	sl_preprocess(&fx->ctx, "t.sl", src, strlen(src), &fx->toks);
	fx->unit = sl_parse(&fx->ctx, fx->toks.data, fx->toks.len);
	return fx->unit;
}

/* ---- a compact s-expression view of a tree, for checking shapes ---- */

static void sx(struct rl_strbuf *b, const struct sl_ast *n);

static const char *op_str(int op)
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
	default: return "?op";
	}
}

/* "(p1 p2 ...)" */
static void sx_params(struct rl_strbuf *b, const struct sl_ast *n)
{
	rl_strbuf_putc(b, '(');
	for (uint32_t i = 0; i < n->nlist; i++) {
		if (i)
			rl_strbuf_putc(b, ' ');
		sx(b, n->list[i]);
	}
	rl_strbuf_putc(b, ')');
}

static void sx_list(struct rl_strbuf *b, const struct sl_ast *n)
{
	for (uint32_t i = 0; i < n->nlist; i++) {
		rl_strbuf_putc(b, ' ');
		sx(b, n->list[i]);
	}
}

static void sx_opt(struct rl_strbuf *b, const struct sl_ast *n)
{
	rl_strbuf_putc(b, ' ');
	if (n)
		sx(b, n);
	else
		rl_strbuf_putc(b, '_');
}

static void sx_type(struct rl_strbuf *b, struct sl_type t)
{
	if (t.detail == SL_DETAIL_UNIFORM)
		rl_strbuf_puts(b, "uniform ");
	else if (t.detail == SL_DETAIL_VARYING)
		rl_strbuf_puts(b, "varying ");
	rl_strbuf_puts(b, sl_basetype_name(t.base));
	if (t.arraylen == 0)
		rl_strbuf_puts(b, "[]");
	else if (t.arraylen > 0)
		rl_strbuf_printf(b, "[%d]", (int)t.arraylen);
}

static void sx(struct rl_strbuf *b, const struct sl_ast *n)
{
	if (!n) {
		rl_strbuf_puts(b, "NULL");
		return;
	}
	switch (n->kind) {
	case SL_AST_NUM: rl_strbuf_printf(b, "%g", n->num); break;
	case SL_AST_STR: rl_strbuf_printf(b, "\"%s\"", n->str); break;
	case SL_AST_IDENT: rl_strbuf_puts(b, n->name); break;
	case SL_AST_UNARY:
		rl_strbuf_printf(b, "(%s", op_str(n->op));
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_BINARY:
	case SL_AST_ASSIGN:
		rl_strbuf_printf(b, "(%s", op_str(n->op));
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_INCDEC:
		rl_strbuf_printf(b, n->num != 0 ? "(%s." : "(.%s", op_str(n->op));
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_COND:
		rl_strbuf_puts(b, "(?");
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		sx_opt(b, n->c);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_CALL:
		rl_strbuf_printf(b, "(call %s", n->name);
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_INDEX:
		rl_strbuf_puts(b, "([]");
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_CTOR:
		rl_strbuf_printf(b, "(%s", n->type.base == SL_TYPE_VOID ? "tuple"
					   : sl_basetype_name(n->type.base));
		if (n->a) {
			rl_strbuf_puts(b, " @");
			sx(b, n->a);
		}
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_ARRAYLIT:
		rl_strbuf_puts(b, "(array");
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_VAR:
		rl_strbuf_printf(b, "(var %s%s%s ", n->is_extern ? "extern " : "",
				 n->output ? "output " : "", n->name);
		sx_type(b, n->type);
		if (n->a) {
			rl_strbuf_puts(b, " =");
			sx_opt(b, n->a);
		}
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_DECL:
		rl_strbuf_puts(b, "(decl");
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_FUNC:
		rl_strbuf_printf(b, "(func %s ", n->name);
		sx_type(b, n->type);
		rl_strbuf_putc(b, ' ');
		sx_params(b, n);
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_SHADER: {
		static const char *const kinds[] = {"surface", "light", "displacement", "volume",
						    "imager"};
		rl_strbuf_printf(b, "(%s %s ", n->op >= 0 && n->op < 5 ? kinds[n->op] : "?",
				 n->name);
		sx_params(b, n);
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	}
	case SL_AST_UNIT:
		rl_strbuf_puts(b, "(unit");
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_BLOCK:
		rl_strbuf_puts(b, "(block");
		sx_list(b, n);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_EXPR:
		rl_strbuf_puts(b, "(expr");
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_IF:
		rl_strbuf_puts(b, "(if");
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		sx_opt(b, n->c);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_WHILE:
		rl_strbuf_puts(b, "(while");
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_FOR:
		rl_strbuf_puts(b, "(for");
		sx_opt(b, n->a);
		sx_opt(b, n->b);
		sx_opt(b, n->c);
		sx_opt(b, n->d);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_BREAK: rl_strbuf_printf(b, "(break %g)", n->num); break;
	case SL_AST_CONTINUE: rl_strbuf_printf(b, "(continue %g)", n->num); break;
	case SL_AST_RETURN:
		rl_strbuf_puts(b, "(return");
		if (n->a)
			sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_ILLUMINANCE:
	case SL_AST_ILLUMINATE:
	case SL_AST_SOLAR:
		rl_strbuf_printf(b, "(%s", n->kind == SL_AST_ILLUMINANCE ? "illuminance"
					   : n->kind == SL_AST_ILLUMINATE ? "illuminate" : "solar");
		sx_list(b, n);
		sx_opt(b, n->a);
		rl_strbuf_putc(b, ')');
		break;
	case SL_AST_EMPTY: rl_strbuf_puts(b, "(empty)"); break;
	default: rl_strbuf_puts(b, "(?)"); break;
	}
}

/* The s-expression of @n, valid until the next call. */
static const char *sexpr(const struct sl_ast *n)
{
	static struct rl_strbuf b;
	rl_strbuf_reset(&b);
	sx(&b, n);
	return rl_strbuf_str(&b);
}

/* Parse `void f() { SRC }` and return the s-expression of the body's statements. */
static const char *body_sexpr(const char *body, int *nerrors)
{
	static char out[4096];
	struct fx fx;
	fx_init(&fx);
	char src[2048];
	snprintf(src, sizeof(src), "void f() { %s }", body);
	struct sl_ast *u = fx_parse(&fx, src);
	*nerrors = fx.ctx.nerrors;
	if (fx.ctx.nerrors)
		fprintf(stderr, "  while parsing { %s }:\n%s", body, fx_diag(&fx));
	const struct sl_ast *blk = u && u->nlist == 1 && u->list[0]->kind == SL_AST_FUNC
					   ? u->list[0]->a : NULL;
	if (!blk) {
		snprintf(out, sizeof(out), "(no body)");
	} else {
		struct rl_strbuf b = {0};
		for (uint32_t i = 0; i < blk->nlist; i++) {
			if (i)
				rl_strbuf_putc(&b, ' ');
			sx(&b, blk->list[i]);
		}
		snprintf(out, sizeof(out), "%s", rl_strbuf_str(&b));
		rl_strbuf_finish(&b);
	}
	fx_finish(&fx);
	return out;
}

#define CHECK_BODY(src, expected) \
	do { \
		int nerr_; \
		CHECK_STR(body_sexpr((src), &nerr_), (expected)); \
		CHECK(nerr_ == 0); \
	} while (0)

/* The expression of `void f() { SRC; }`. */
#define CHECK_EXPR(src, expected) CHECK_BODY(src ";", "(expr " expected ")")

/* Parse @src expecting errors; returns the diagnostics (static copy) and the count. */
static const char *errors_of(const char *src, int *nerrors)
{
	static char out[8192];
	struct fx fx;
	fx_init(&fx);
	fx_parse(&fx, src);
	*nerrors = fx.ctx.nerrors;
	snprintf(out, sizeof(out), "%s", fx_diag(&fx));
	fx_finish(&fx);
	return out;
}

/* Exactly one error, with this text. */
#define CHECK_ERROR(src, expected) \
	do { \
		int nerr_; \
		CHECK_STR(errors_of((src), &nerr_), expected "\n"); \
		CHECK(nerr_ == 1); \
	} while (0)

/* ---- tests ---- */

static void test_precedence(void)
{
	CHECK_EXPR("a + b * c", "(+ a (* b c))");
	CHECK_EXPR("a * b + c", "(+ (* a b) c)");
	CHECK_EXPR("a - b - c", "(- (- a b) c)");
	CHECK_EXPR("a / b * c", "(* (/ a b) c)");
	/* RISpec: '.' binds tighter than '*' '/', which bind tighter than '^', then '+' '-' */
	CHECK_EXPR("a . b ^ c", "(^ (. a b) c)");
	CHECK_EXPR("a ^ b . c", "(^ a (. b c))");
	CHECK_EXPR("a * b . c", "(* a (. b c))");
	CHECK_EXPR("a ^ b * c", "(^ a (* b c))");
	CHECK_EXPR("a + b ^ c", "(+ a (^ b c))");
	CHECK_EXPR("-a.b", "(. (- a) b)");
	CHECK_EXPR("!a && b || c && !d", "(|| (&& (! a) b) (&& c (! d)))");
	CHECK_EXPR("a < b == c >= d", "(== (< a b) (>= c d))");
	CHECK_EXPR("a + 1 <= b * 2", "(<= (+ a 1) (* b 2))");
	CHECK_EXPR("a != b", "(!= a b)");
	CHECK_EXPR("x = y = 1", "(= x (= y 1))");
	CHECK_EXPR("x += y -= 2", "(+= x (-= y 2))");
	CHECK_EXPR("x *= 2", "(*= x 2)");
	CHECK_EXPR("x /= 2", "(/= x 2)");
	CHECK_EXPR("c ? a : b ? d : e", "(? c a (? b d e))");
	CHECK_EXPR("a || b ? x + 1 : y", "(? (|| a b) (+ x 1) y)");
	CHECK_EXPR("x = c ? 1 : 2", "(= x (? c 1 2))");
	CHECK_EXPR("(a + b) * c", "(* (+ a b) c)");
	CHECK_EXPR("- - a", "(- (- a))");
	CHECK_EXPR("+a", "(+ a)");
	CHECK_EXPR("a[i + 1] = b[2]", "(= ([] a (+ i 1)) ([] b 2))");
	CHECK_EXPR("i++", "(.++ i)");
	CHECK_EXPR("--i", "(--. i)");
	CHECK_EXPR("a[1]--", "(.-- ([] a 1))");
	CHECK_EXPR("-i++", "(- (.++ i))");
	CHECK_EXPR("f(a, b + 1, g())", "(call f a (+ b 1) (call g))");
	CHECK_EXPR("1.5e2", "150");

	/* locations: BINARY and ASSIGN at their operator */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "void f()\n{\n  x = a +\n    b;\n}\n");
	CHECK(fx.ctx.nerrors == 0);
	if (u && u->nlist == 1) {
		const struct sl_ast *e = u->list[0]->a->list[0];
		CHECK(e->kind == SL_AST_EXPR);
		CHECK(e->loc.line == 3 && e->loc.col == 3);
		const struct sl_ast *as = e->a;
		CHECK(as->kind == SL_AST_ASSIGN && as->op == SL_TOK_ASSIGN);
		CHECK(as->loc.line == 3 && as->loc.col == 5);
		CHECK(as->b->kind == SL_AST_BINARY && as->b->loc.line == 3 && as->b->loc.col == 9);
		CHECK(as->b->b->kind == SL_AST_IDENT && as->b->b->loc.line == 4 &&
		      as->b->b->loc.col == 5);
		CHECK(as->a->name == sl_intern_cstr(&fx.ctx, "x"));
		CHECK(as->a->overload == -1 && as->a->type.arraylen == -1);
	} else {
		CHECK(!"unit");
	}
	fx_finish(&fx);
}

static void test_constructors(void)
{
	CHECK_EXPR("color(1, 0, 0)", "(color 1 0 0)");
	CHECK_EXPR("color \"hsv\" (0.5, 1, 1)", "(color @\"hsv\" 0.5 1 1)");
	CHECK_EXPR("point \"world\" (0, 0, 0)", "(point @\"world\" 0 0 0)");
	CHECK_EXPR("point \"wor\" \"ld\" (0, 0, 0)", "(point @\"world\" 0 0 0)");
	CHECK_EXPR("x = vector P", "(= x (vector P))");
	CHECK_EXPR("color 1", "(color 1)");
	CHECK_EXPR("normal (1)", "(normal 1)");
	CHECK_EXPR("x = float noise(P)", "(= x (float (call noise P)))");
	CHECK_EXPR("x = float noise(P) * 2", "(= x (* (float (call noise P)) 2))");
	CHECK_EXPR("x = color c[1]", "(= x (color ([] c 1)))");
	CHECK_EXPR("point \"shader\" P", "(point @\"shader\" P)");
	CHECK_EXPR("vector -N", "(vector (- N))");
	CHECK_EXPR("string \"abc\"", "(string \"abc\")");
	CHECK_EXPR("matrix (1)", "(matrix 1)");
	CHECK_EXPR("matrix \"shader\" (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1)",
		   "(matrix @\"shader\" 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1)");
	/* a space held in a string variable, versus a cast of a built-in call */
	CHECK_EXPR("x = point spc (1, 2, 3)", "(= x (point @spc 1 2 3))");
	CHECK_EXPR("x = color mix(a, b, t)", "(= x (color (call mix a b t)))");
	CHECK_EXPR("x = point spc (1, 2)", "(= x (point (call spc 1 2)))");
	/* at the start of a statement, TYPE NAME is a declaration */
	CHECK_BODY("vector P;", "(decl (var P vector))");
	/* tuples typed by context */
	CHECK_EXPR("c = (1, 2, 3)", "(= c (tuple 1 2 3))");
	CHECK_EXPR("m = (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1)",
		   "(= m (tuple 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1))");
	CHECK_EXPR("(a, b, c) . (d, e, f)", "(. (tuple a b c) (tuple d e f))");
	/* strings and channels */
	CHECK_EXPR("printf(\"a\" \"b\" \"c\", x)", "(call printf \"abc\" x)");
	CHECK_EXPR("texture(\"file.tx\"[1], s, t)", "(call texture ([] \"file.tx\" 1) s t)");
	CHECK_EXPR("texture(name[0])", "(call texture ([] name 0))");
	/* message passing through shader-kind keywords */
	CHECK_EXPR("surface(\"Kd\", kd)", "(call surface \"Kd\" kd)");
	CHECK_EXPR("displacement(\"Ps\", p)", "(call displacement \"Ps\" p)");
	CHECK_EXPR("lightsource(\"x\", v) + atmosphere(\"y\", w)",
		   "(+ (call lightsource \"x\" v) (call atmosphere \"y\" w))");

	/* CTOR fields directly */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "void f() { c = color \"rgb\" (1, 0.5, 0); }");
	CHECK(fx.ctx.nerrors == 0);
	if (u) {
		const struct sl_ast *c = u->list[0]->a->list[0]->a->b;
		CHECK(c->kind == SL_AST_CTOR);
		CHECK(c->type.base == SL_TYPE_COLOR && c->type.arraylen == -1);
		CHECK(c->a && c->a->kind == SL_AST_STR);
		CHECK_STR(c->a->str, "rgb");
		CHECK(c->nlist == 3);
		CHECK_NEAR(c->list[1]->num, 0.5, 0);
		CHECK(c->loc.line == 1 && c->loc.col == 16);
	}
	fx_finish(&fx);
}

static void test_declarations(void)
{
	CHECK_BODY("float a, b = 1, c = a + b;",
		   "(decl (var a float) (var b float = 1) (var c float = (+ a b)))");
	CHECK_BODY("uniform color Cs = 1;", "(decl (var Cs uniform color = 1))");
	CHECK_BODY("varying point p[2];", "(decl (var p varying point[2]))");
	CHECK_BODY("float a[3] = {1, 2, 3};", "(decl (var a float[3] = (array 1 2 3)))");
	CHECK_BODY("string s = \"x\" \"y\";", "(decl (var s string = \"xy\"))");
	CHECK_BODY("matrix m = 1, n;", "(decl (var m matrix = 1) (var n matrix))");
	CHECK_BODY("extern point P; extern uniform float Kd;",
		   "(decl (var extern P point)) (decl (var extern Kd uniform float))");
	/* an expression statement that starts with a type */
	CHECK_BODY("color(1, 2, 3);", "(expr (color 1 2 3))");
}

static void test_statements(void)
{
	CHECK_BODY("{ a = 1; { } ; }", "(block (expr (= a 1)) (block) (empty))");
	CHECK_BODY("if (a > b) x = 1;", "(if (> a b) (expr (= x 1)) _)");
	CHECK_BODY("if (a) if (b) x = 1; else x = 2;",
		   "(if a (if b (expr (= x 1)) (expr (= x 2))) _)");
	CHECK_BODY("if (a) { } else if (b) { } else { }",
		   "(if a (block) (if b (block) (block)))");
	CHECK_BODY("while (i < 10) i += 1;", "(while (< i 10) (expr (+= i 1)))");
	CHECK_BODY("for (i = 0; i < 10; i += 1) { break; }",
		   "(for (expr (= i 0)) (< i 10) (+= i 1) (block (break 1)))");
	CHECK_BODY("for (;;) continue 2;", "(for _ _ _ (continue 2))");
	CHECK_BODY("for (; i < 3;) break 2;", "(for _ (< i 3) _ (break 2))");
	CHECK_BODY("for (float i = 0; i < 4; i += 1) s += i;",
		   "(block (decl (var i float = 0)) (for _ (< i 4) (+= i 1) (expr (+= s i))))");
	CHECK_BODY("return; return a * 2;", "(return) (return (* a 2))");
	CHECK_BODY("illuminance (P) { }", "(illuminance P (block))");
	CHECK_BODY("illuminance (P, N, PI/2) Ci += Cl;",
		   "(illuminance P N (/ PI 2) (expr (+= Ci Cl)))");
	CHECK_BODY("illuminance (\"spec\", P, N, 1) ;",
		   "(illuminance \"spec\" P N 1 (empty))");
	CHECK_BODY("illuminance (\"amb\", P) ;", "(illuminance \"amb\" P (empty))");
	CHECK_BODY("illuminate (P) Cl = 1;", "(illuminate P (expr (= Cl 1)))");
	CHECK_BODY("illuminate (from, A, angle) { }", "(illuminate from A angle (block))");
	CHECK_BODY("solar () ;", "(solar (empty))");
	CHECK_BODY("solar (A, 0) { Cl = 1; }", "(solar A 0 (block (expr (= Cl 1))))");
	CHECK_BODY(";", "(empty)");
	CHECK_BODY("f(1);", "(expr (call f 1))");

	/* node fields for loops and breaks */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "void f() { while (1) { break 3; } }");
	CHECK(fx.ctx.nerrors == 0);
	if (u) {
		const struct sl_ast *w = u->list[0]->a->list[0];
		CHECK(w->kind == SL_AST_WHILE);
		CHECK(w->b->kind == SL_AST_BLOCK && w->b->nlist == 1);
		CHECK(w->b->list[0]->kind == SL_AST_BREAK);
		CHECK_NEAR(w->b->list[0]->num, 3, 0);
		CHECK(w->b->list[0]->loc.col == 24);
	}
	fx_finish(&fx);
}

static void test_shaders(void)
{
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx,
		"surface plastic(float Ka = 1, Kd = .5; float Ks = .5;\n"
		"                float roughness = .1; color specularcolor = 1;)\n"
		"{\n"
		"  normal Nf = faceforward(normalize(N), I);\n"
		"  Ci = Cs * (Ka * ambient() + Kd * diffuse(Nf));\n"
		"}\n"
		"light pointlight(float intensity = 1; color lightcolor = 1;\n"
		"                 point from = point \"shader\" (0, 0, 0))\n"
		"{ illuminate (from) Cl = intensity * lightcolor / (L . L); }\n"
		"displacement bumpy(float Km = 1; string texturename = \"\") { P += Km * N; }\n"
		"volume fog(output varying float depth = 0; float a[3] = {1, 2, 3}) { }\n"
		"imager bg(uniform color background = 0) { }\n");
	CHECK(fx.ctx.nerrors == 0);
	if (!u || u->nlist != 5) {
		CHECK(!"five shaders");
		fx_finish(&fx);
		return;
	}
	CHECK_STR(sexpr(u->list[0]),
		  "(surface plastic ((var Ka float = 1) (var Kd float = 0.5) (var Ks float = 0.5) "
		  "(var roughness float = 0.1) (var specularcolor color = 1)) "
		  "(block (decl (var Nf normal = (call faceforward (call normalize N) I))) "
		  "(expr (= Ci (* Cs (+ (* Ka (call ambient)) (* Kd (call diffuse Nf))))))))");
	CHECK(u->list[0]->op == SL_SHADER_SURFACE);
	CHECK(u->list[0]->loc.line == 1 && u->list[0]->loc.col == 9);
	CHECK(u->list[1]->op == SL_SHADER_LIGHT);
	CHECK_STR(sexpr(u->list[1]),
		  "(light pointlight ((var intensity float = 1) (var lightcolor color = 1) "
		  "(var from point = (point @\"shader\" 0 0 0))) (block (illuminate from "
		  "(expr (= Cl (/ (* intensity lightcolor) (. L L)))))))");
	CHECK(u->list[2]->op == SL_SHADER_DISPLACEMENT);
	CHECK_STR(sexpr(u->list[2]),
		  "(displacement bumpy ((var Km float = 1) (var texturename string = \"\")) "
		  "(block (expr (+= P (* Km N)))))");
	CHECK(u->list[3]->op == SL_SHADER_VOLUME);
	CHECK_STR(sexpr(u->list[3]),
		  "(volume fog ((var output depth varying float = 0) "
		  "(var a float[3] = (array 1 2 3))) (block))");
	CHECK(u->list[3]->list[0]->output && !u->list[3]->list[1]->output);
	CHECK(u->list[4]->op == SL_SHADER_IMAGER);
	CHECK_STR(sexpr(u->list[4]), "(imager bg ((var background uniform color = 0)) (block))");
	fx_finish(&fx);
}

static void test_functions(void)
{
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx,
		"float sq(float x) { return x * x; }\n"
		"void two(float a, b; output color c; point pts[]) { c = a + b; }\n"
		"color comma(float a, color b, string names[]) { return b; }\n"
		"uniform float uf(uniform float a) { return a; }\n"
		"noret() { }\n"
		"surface s(float Kd = 1)\n"
		"{\n"
		"  float helper(float t) {\n"
		"    extern float Kd;\n"
		"    extern point P, Ps;\n"
		"    return t * Kd;\n"
		"  }\n"
		"  Ci = helper(sq(2));\n"
		"}\n");
	CHECK(fx.ctx.nerrors == 0);
	if (!u || u->nlist != 6) {
		CHECK(!"six definitions");
		fprintf(stderr, "%s", fx_diag(&fx));
		fx_finish(&fx);
		return;
	}
	CHECK_STR(sexpr(u->list[0]),
		  "(func sq float ((var x float)) (block (return (* x x))))");
	CHECK_STR(sexpr(u->list[1]),
		  "(func two void ((var a float) (var b float) (var output c color) "
		  "(var pts point[])) (block (expr (= c (+ a b)))))");
	CHECK(u->list[1]->list[2]->output && u->list[1]->list[3]->type.arraylen == 0);
	CHECK_STR(sexpr(u->list[2]),
		  "(func comma color ((var a float) (var b color) (var names string[])) "
		  "(block (return b)))");
	CHECK_STR(sexpr(u->list[3]),
		  "(func uf uniform float ((var a uniform float)) (block (return a)))");
	CHECK_STR(sexpr(u->list[4]), "(func noret void () (block))");
	const struct sl_ast *sh = u->list[5];
	CHECK(sh->kind == SL_AST_SHADER);
	const struct sl_ast *nested = sh->a->list[0];
	CHECK(nested->kind == SL_AST_FUNC);
	CHECK_STR(sexpr(nested),
		  "(func helper float ((var t float)) (block (decl (var extern Kd float)) "
		  "(decl (var extern P point) (var extern Ps point)) (return (* t Kd))))");
	CHECK(nested->a->list[0]->list[0]->is_extern);
	CHECK(nested->loc.line == 8 && nested->loc.col == 9);
	CHECK_STR(sexpr(sh->a->list[1]), "(expr (= Ci (call helper (call sq 2))))");
	/* a user function is a call, not a space, under a cast */
	struct fx fx2;
	fx_init(&fx2);
	u = fx_parse(&fx2, "point trip(float a, b, c) { return (a, b, c); }\n"
			   "void g() { p = point trip(1, 2, 3); q = point other(1, 2, 3); }\n");
	CHECK(fx2.ctx.nerrors == 0);
	if (u && u->nlist == 2) {
		CHECK_STR(sexpr(u->list[1]->a),
			  "(block (expr (= p (point (call trip 1 2 3)))) "
			  "(expr (= q (point @other 1 2 3))))");
	}
	fx_finish(&fx2);
	fx_finish(&fx);
}

static void test_errors(void)
{
	CHECK_ERROR("void f() {\n  a = 1\n  b = 2;\n}\n", "t.sl:3:3: error: expected ';' near 'b'");
	CHECK_ERROR("surface s() {\n  x = (1 + ;\n}\n",
		    "t.sl:2:12: error: expected expression near ';'");
	CHECK_ERROR("surface s() { x = 1; ", "t.sl:1:22: error: expected '}' near end of file");
	CHECK_ERROR("surface s(float a = ) { }", "t.sl:1:21: error: expected expression near ')'");
	CHECK_ERROR("surface s() { 1 + a = 2; }",
		    "t.sl:1:21: error: the left side of '=' must be a variable or an array element "
		    "near '='");
	CHECK_ERROR("surface s() { f(x) = 2; }",
		    "t.sl:1:20: error: the left side of '=' must be a variable or an array element "
		    "near '='");
	CHECK_ERROR("surface s() {\n\tgather(\"illuminance\", P, N, 1, 8) { }\n}\n",
		    "t.sl:2:2: error: gather is not supported");
	CHECK_ERROR("surface s() { c = (1, 2); }",
		    "t.sl:1:24: error: a parenthesized list needs 1, 3 or 16 values, not 2 near ')'");
	CHECK_ERROR("surface s() { c = color (1, 2); }",
		    "t.sl:1:25: error: a color constructor needs 1, 3 or 16 values, not 2 near '('");
	CHECK_ERROR("surface s() { float a[0]; }",
		    "t.sl:1:23: error: array size must be a whole number from 1 to 1048576 near '0'");
	CHECK_ERROR("surface s(float a[]) { }",
		    "t.sl:1:19: error: array size must be a whole number from 1 to 1048576 near ']'");
	CHECK_ERROR("surface s() { void v; }", "t.sl:1:15: error: expected expression near 'void'");
	CHECK_ERROR("surface s() { float v = 1 }", "t.sl:1:27: error: expected ';' near '}'");
	CHECK_ERROR("surface s() { solar (a) { } }",
		    "t.sl:1:21: error: 'solar' does not take 1 arguments near '('");
	CHECK_ERROR("surface s() { break x; }",
		    "t.sl:1:21: error: expected a loop count or ';' near 'x'");
	CHECK_ERROR("surface s() { 3++; }",
		    "t.sl:1:16: error: '++' needs a variable or an array element near '++'");
	CHECK_ERROR("float x;", "t.sl:1:1: error: expected a shader or function definition near 'float'");
	CHECK_ERROR("surface s float", "t.sl:1:11: error: expected '(' near 'float'");
	CHECK_ERROR("x = 1;", "t.sl:1:1: error: expected a shader or function definition near 'x'");
	CHECK_ERROR("surface { }", "t.sl:1:9: error: expected a shader name near '{'");
	CHECK_ERROR("surface s(float a; b) { }", "t.sl:1:20: error: expected a type near 'b'");
	CHECK_ERROR("surface s(float a b) { }", "t.sl:1:19: error: expected ';' or ')' near 'b'");
	CHECK_ERROR("surface s() { x = \"a very long string literal that goes on and on\" + ; }",
		    "t.sl:1:70: error: expected expression near ';'");
	CHECK_ERROR("surface s() { x = y \"a very long string literal that goes on and on\"; }",
		    "t.sl:1:21: error: expected ';' near '\"a very long string literal that goes on...'");

	/* the partial tree keeps what parsed */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "surface s() { a = ; b = 1; }");
	CHECK(fx.ctx.nerrors == 1);
	CHECK(u && u->nlist == 1);
	if (u && u->nlist == 1)
		CHECK_STR(sexpr(u->list[0]->a), "(block (expr (= b 1)))");
	fx_finish(&fx);

	/* nothing parsed: NULL */
	fx_init(&fx);
	CHECK(fx_parse(&fx, "}}}") == NULL);
	CHECK(fx.ctx.nerrors >= 1);
	fx_finish(&fx);

	/* an empty unit is no error */
	fx_init(&fx);
	u = fx_parse(&fx, "");
	CHECK(u && u->kind == SL_AST_UNIT && u->nlist == 0 && fx.ctx.nerrors == 0);
	fx_finish(&fx);
}

static void test_recovery(void)
{
	int n;
	const char *d = errors_of("surface s()\n"
				  "{\n"
				  "  a = 1 +;\n"
				  "  if (b c) { d = 1; }\n"
				  "  e = f(1, ;\n"
				  "  g = 2;\n"
				  "  float h = ;\n"
				  "}\n"
				  "void k( { }\n"
				  "float m() { return 1 }\n"
				  "surface t() { x = 1; }\n",
				  &n);
	CHECK_STR(d, "t.sl:3:10: error: expected expression near ';'\n"
		     "t.sl:4:9: error: expected ')' near 'c'\n"
		     "t.sl:5:12: error: expected expression near ';'\n"
		     "t.sl:7:13: error: expected expression near ';'\n"
		     "t.sl:9:9: error: expected a type near '{'\n"
		     "t.sl:10:22: error: expected ';' near '}'\n");
	CHECK(n == 6);

	/* the definitions around the errors are all kept */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "surface s() { a = ; }\nvoid f() { b = 1; }\n"
					 "void g() { c = = 1; d = 2; }\n");
	CHECK(fx.ctx.nerrors == 2);
	CHECK(u && u->nlist == 3);
	if (u && u->nlist == 3)
		CHECK_STR(sexpr(u->list[2]->a), "(block (expr (= d 2)))");
	fx_finish(&fx);

	/* max_errors stops the parse */
	struct rl_strbuf b = {0};
	rl_strbuf_puts(&b, "surface s() {\n");
	for (int i = 0; i < 200; i++)
		rl_strbuf_puts(&b, "  x = ;\n");
	rl_strbuf_puts(&b, "}\n");
	fx_init(&fx);
	fx_parse(&fx, rl_strbuf_str(&b));
	CHECK(fx.ctx.nerrors == 50);
	CHECK(fx.ctx.too_many);
	fx_finish(&fx);
	rl_strbuf_finish(&b);
}

static void test_deep_nesting(void)
{
	enum { N = 100000 };
	/* each repeated N times between a prefix and "1; }" */
	static const struct {
		const char *prefix, *open;
	} cases[] = {
		{"surface s() { x = ", "("},
		{"surface s() { x = ", "-"},
		{"surface s() { x = ", "!"},
		{"surface s() { x = ", "++"},
		{"surface s() { x = ", "a = "},
		{"surface s() { x = ", "c ? 1 : "},
		{"surface s() { x = ", "c ? "},
		{"surface s() { x = ", "float "},
		{"surface s() { x = ", "color \"rgb\" "},
		{"surface s() { x = ", "x["},
		{"surface s() { x = ", "f("},
		{"surface s() { ", "{"},
		{"surface s() { ", "if (1) "},
		{"surface s() { ", "if (1) ; else "},
		{"surface s() { ", "while (1) "},
		{"surface s() { ", "for (;;) "},
		{"surface s() { ", "illuminance (P) "},
		{"surface s() { ", "float f() { "},
	};
	for (size_t k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
		struct rl_strbuf b = {0};
		rl_strbuf_puts(&b, cases[k].prefix);
		for (int i = 0; i < N; i++)
			rl_strbuf_puts(&b, cases[k].open);
		rl_strbuf_puts(&b, "1; }");
		struct fx fx;
		fx_init(&fx);
		fx_parse(&fx, rl_strbuf_str(&b));
		CHECK(fx.ctx.nerrors == 1);
		CHECK(strstr(fx_diag(&fx), "error: nesting too deep near") != NULL);
		if (fx.ctx.nerrors != 1 || !strstr(fx_diag(&fx), "nesting too deep"))
			fprintf(stderr, "  with '%s' x %d:\n%s", cases[k].open, N, fx_diag(&fx));
		fx_finish(&fx);
		rl_strbuf_finish(&b);
	}

	/*
	 * A flat chain leans left and is walked in loops: not nesting. It is
	 * bounded by its size, 100,000 operators; one more is an error.
	 */
	static const char *const flat[] = { "a + ", "a * ", "1 . ", "a - " };
	for (size_t k = 0; k < sizeof(flat) / sizeof(flat[0]); k++) {
		for (int over = 0; over <= 1; over++) {
			struct rl_strbuf b = {0};
			rl_strbuf_puts(&b, "surface s() { x = ");
			for (int i = 0; i < N + over; i++)
				rl_strbuf_puts(&b, flat[k]);
			rl_strbuf_puts(&b, "1; }");
			struct fx fx;
			fx_init(&fx);
			fx_parse(&fx, rl_strbuf_str(&b));
			CHECK(fx.ctx.nerrors == over);
			if (over)
				CHECK(strstr(fx_diag(&fx), "error: expression too large (more than "
						"100000 operators) near") != NULL);
			if (fx.ctx.nerrors != over)
				fprintf(stderr, "  with '%s' x %d:\n%s", flat[k], N + over,
					fx_diag(&fx));
			fx_finish(&fx);
			rl_strbuf_finish(&b);
		}
	}

	/* just under the limit is fine */
	struct rl_strbuf b = {0};
	rl_strbuf_puts(&b, "surface s() { x = ");
	for (int i = 0; i < 200; i++)
		rl_strbuf_puts(&b, "(");
	rl_strbuf_puts(&b, "1");
	for (int i = 0; i < 200; i++)
		rl_strbuf_puts(&b, ")");
	rl_strbuf_puts(&b, "; }");
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, rl_strbuf_str(&b));
	CHECK(fx.ctx.nerrors == 0);
	if (u && u->nlist == 1)
		CHECK_STR(sexpr(u->list[0]->a), "(block (expr (= x 1)))");
	fx_finish(&fx);
	rl_strbuf_finish(&b);

	/* 100000 nested blocks */
	rl_strbuf_reset(&b);
	for (int i = 0; i < N; i++)
		rl_strbuf_puts(&b, "{");
	fx_init(&fx);
	CHECK(fx_parse(&fx, rl_strbuf_str(&b)) == NULL);
	CHECK(fx.ctx.nerrors == 1);
	fx_finish(&fx);
	rl_strbuf_reset(&b);
	rl_strbuf_puts(&b, "void f() ");
	for (int i = 0; i < N; i++)
		rl_strbuf_puts(&b, "{");
	for (int i = 0; i < N; i++)
		rl_strbuf_puts(&b, "}");
	fx_init(&fx);
	fx_parse(&fx, rl_strbuf_str(&b));
	CHECK(fx.ctx.nerrors == 1);
	CHECK(strstr(fx_diag(&fx), "t.sl:1:267: error: nesting too deep near '{'") != NULL);
	fx_finish(&fx);
	rl_strbuf_finish(&b);
}

/* xorshift, for repeatable soups */
static uint32_t rnd(uint32_t *s)
{
	*s ^= *s << 13;
	*s ^= *s >> 17;
	*s ^= *s << 5;
	return *s;
}

static void test_token_soup(void)
{
	/* hand-made token arrays of every kind, in random order and length */
	static const char *const spell[] = {"x", "1", "\"s\"", "(", ")", "{", "}", "[", "]", ";",
					    ",", ".", "?", ":", "^", "+", "-", "*", "/", "%", "!",
					    "=", "+=", "-=", "*=", "/=", "++", "--", "==", "!=",
					    "<", "<=", ">", ">=", "&&", "||", "#", "##"};
	uint32_t seed = 12345;
	int parsed = 0;
	for (int round = 0; round < 3000; round++) {
		struct fx fx;
		fx_init(&fx);
		fx.ctx.quiet = true;
		size_t n = rnd(&seed) % 200;
		struct sl_token *toks = calloc(n + 1, sizeof(*toks));
		const char *x = sl_intern_cstr(&fx.ctx, "x");
		for (size_t i = 0; i < n; i++) {
			/* favour the interesting kinds: structure and keywords */
			enum sl_tok k = (enum sl_tok)(1 + rnd(&seed) % (SL_TOK_COUNT - 1));
			toks[i].kind = k;
			toks[i].loc = (struct sl_loc){0, 1, (uint32_t)i + 1};
			if (k < sizeof(spell) / sizeof(spell[0]) + 1 && k >= SL_TOK_IDENT) {
				toks[i].text = spell[k - 1];
			} else {
				toks[i].text = sl_tok_name(k);
			}
			toks[i].len = (uint32_t)strlen(toks[i].text);
			toks[i].num = (double)(rnd(&seed) % 5);
			toks[i].str = k == SL_TOK_STRING ? "s" : k == SL_TOK_NUMBER ? NULL : x;
		}
		toks[n].kind = SL_TOK_EOF;
		/* some rounds lack the final EOF */
		struct sl_ast *u = sl_parse(&fx.ctx, toks, round % 7 ? n + 1 : n);
		parsed += u != NULL;
		free(toks);
		fx_finish(&fx);
	}
	CHECK(parsed >= 0);

	/* soups of plausible source */
	static const char *const words[] = {
		"surface", "s", "(", ")", "{", "}", "float", "a", "=", "1", ";", "if", "else",
		"for", "while", "color", "\"rgb\"", ",", "illuminance", "P", "return", "[", "]",
		"+", "*", ".", "^", "?", ":", "void", "f", "output", "extern", "uniform", "break",
		"solar", "gather", "matrix", "-", "++", "\"x\""};
	for (int round = 0; round < 2000; round++) {
		struct rl_strbuf b = {0};
		size_t n = rnd(&seed) % 120;
		for (size_t i = 0; i < n; i++) {
			rl_strbuf_puts(&b, words[rnd(&seed) % (sizeof(words) / sizeof(words[0]))]);
			rl_strbuf_putc(&b, ' ');
		}
		struct fx fx;
		fx_init(&fx);
		fx.ctx.quiet = true;
		fx_parse(&fx, rl_strbuf_str(&b));
		fx_finish(&fx);
		rl_strbuf_finish(&b);
	}

	/* no tokens at all, or NULL */
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = sl_parse(&fx.ctx, NULL, 0);
	CHECK(u && u->nlist == 0);
	fx_finish(&fx);
}

static void test_dump(void)
{
	struct fx fx;
	fx_init(&fx);
	struct sl_ast *u = fx_parse(&fx, "surface s(output float k[2] = {1, 2})\n"
					 "{\n"
					 "  for (;;) break 2;\n"
					 "  Ci = color \"rgb\" (1, \"q\\\"\", -x);\n"
					 "  i++;\n"
					 "}\n");
	CHECK(fx.ctx.nerrors == 0);
	char *text = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&text, &len);
	sl_ast_dump(&fx.ctx, u, f);
	fclose(f);
	CHECK_STR(text, "UNIT (t.sl:1:1)\n"
			"  SHADER surface s (t.sl:1:9)\n"
			"    VAR k : output float[2] (t.sl:1:24)\n"
			"      ARRAYLIT (t.sl:1:31)\n"
			"        NUM 1 (t.sl:1:32)\n"
			"        NUM 2 (t.sl:1:35)\n"
			"    BLOCK (t.sl:2:1)\n"
			"      FOR (t.sl:3:3)\n"
			"        (none)\n"
			"        (none)\n"
			"        (none)\n"
			"        BREAK 2 (t.sl:3:12)\n"
			"      EXPR (t.sl:4:3)\n"
			"        ASSIGN '=' (t.sl:4:6)\n"
			"          IDENT Ci (t.sl:4:3)\n"
			"          CTOR color (t.sl:4:8)\n"
			"            STR \"rgb\" (t.sl:4:14)\n"
			"            NUM 1 (t.sl:4:21)\n"
			"            STR \"q\\\"\" (t.sl:4:24)\n"
			"            UNARY '-' (t.sl:4:31)\n"
			"              IDENT x (t.sl:4:32)\n"
			"      EXPR (t.sl:5:3)\n"
			"        INCDEC '++' postfix (t.sl:5:4)\n"
			"          IDENT i (t.sl:5:3)\n");
	free(text);
	fx_finish(&fx);

	CHECK_STR(sl_ast_kind_name(SL_AST_ILLUMINANCE), "ILLUMINANCE");
	CHECK_STR(sl_ast_kind_name(SL_AST_NUM), "NUM");
	CHECK_STR(sl_ast_kind_name(SL_AST_EMPTY), "EMPTY");
	CHECK_STR(sl_ast_kind_name(SL_AST_KIND_COUNT), "?");
	static const char *const names[] = {"void", "float", "color", "point", "vector",
					    "normal", "matrix", "string", "bool"};
	for (int i = 0; i < SL_TYPE_COUNT; i++)
		CHECK_STR(sl_basetype_name(i), names[i]);
	CHECK_STR(sl_basetype_name(-1), "?");

	/* sl_ast_new's defaults */
	fx_init(&fx);
	struct sl_ast *n = sl_ast_new(&fx.ctx, SL_AST_CALL, (struct sl_loc){0, 7, 9});
	CHECK(n->kind == SL_AST_CALL && n->loc.line == 7 && n->loc.col == 9);
	CHECK(n->overload == -1 && n->type.arraylen == -1);
	CHECK(n->a == NULL && n->list == NULL && n->nlist == 0 && n->name == NULL);
	fx_finish(&fx);
}

int main(void)
{
	RUN(test_precedence);
	RUN(test_constructors);
	RUN(test_declarations);
	RUN(test_statements);
	RUN(test_shaders);
	RUN(test_functions);
	RUN(test_errors);
	RUN(test_recovery);
	RUN(test_deep_nesting);
	RUN(test_token_soup);
	RUN(test_dump);
	return test_finish();
}

/* The preprocessor: macros, conditionals, includes, -D, keywords and diagnostics. */
#include "test.h"
#include "token.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

struct pped {
	struct sl_ctx ctx;
	struct sl_token_list toks;
	FILE *diag;
	char *diag_buf;
	size_t diag_len;
	bool ok;
	char *text; /* the tokens' spellings joined by spaces */
};

static void pp_opts(struct pped *p, const char *path, const char *src,
		    const struct sl_options *opts)
{
	memset(p, 0, sizeof(*p));
	p->diag = open_memstream(&p->diag_buf, &p->diag_len);
	struct sl_options o = opts ? *opts : (struct sl_options){ 0 };
	o.diag = p->diag;
	sl_ctx_init(&p->ctx, &o);
	/* a copy without a NUL after it, freed before the tokens are read */
	size_t len = strlen(src);
	char *copy = malloc(len ? len : 1);
	memcpy(copy, src, len);
	p->ok = sl_preprocess(&p->ctx, path, copy, len, &p->toks);
	free(copy);

	size_t n = 1;
	for (size_t i = 0; i < p->toks.len; i++)
		n += p->toks.data[i].len + 1;
	p->text = calloc(1, n);
	char *w = p->text;
	for (size_t i = 0; i + 1 < p->toks.len; i++) {
		if (i)
			*w++ = ' ';
		memcpy(w, p->toks.data[i].text, p->toks.data[i].len);
		w += p->toks.data[i].len;
	}
}

static void pp(struct pped *p, const char *src)
{
	pp_opts(p, "t.sl", src, NULL);
}

static const char *diag(struct pped *p)
{
	fflush(p->diag);
	return p->diag_buf ? p->diag_buf : "";
}

static void pp_done(struct pped *p)
{
	fclose(p->diag);
	free(p->diag_buf);
	free(p->text);
	free(p->toks.data);
	sl_ctx_finish(&p->ctx);
}

/* Exactly one EOF, at the end. */
static bool one_eof(const struct pped *p)
{
	if (!p->toks.len || p->toks.data[p->toks.len - 1].kind != SL_TOK_EOF)
		return false;
	for (size_t i = 0; i + 1 < p->toks.len; i++)
		if (p->toks.data[i].kind == SL_TOK_EOF)
			return false;
	return true;
}

/* Preprocess @src; check the output text and that there was no diagnostic. */
#define EXPECT(src, want) \
	do { \
		struct pped p_; \
		pp(&p_, (src)); \
		CHECK_STR(p_.text, (want)); \
		CHECK_STR(diag(&p_), ""); \
		CHECK(p_.ok); \
		CHECK(one_eof(&p_)); \
		pp_done(&p_); \
	} while (0)

/* Preprocess @src; check the output text and the diagnostics. */
#define EXPECT_DIAG(src, want, msgs) \
	do { \
		struct pped p_; \
		pp(&p_, (src)); \
		CHECK_STR(p_.text, (want)); \
		CHECK_STR(diag(&p_), (msgs)); \
		CHECK(!p_.ok == (strstr((msgs), ": error: ") != NULL)); \
		CHECK(one_eof(&p_)); \
		pp_done(&p_); \
	} while (0)

static void test_plain(void)
{
	EXPECT("", "");
	EXPECT("a + b;\n", "a + b ;");
	struct pped p;
	pp(&p, "x\n  y(1.5, \"s\\n\")");
	CHECK(p.ok);
	CHECK(p.toks.len == 8);
	const struct sl_token *t = p.toks.data;
	CHECK(t[0].loc.line == 1 && t[0].loc.col == 1);
	CHECK(t[1].loc.line == 2 && t[1].loc.col == 3);
	CHECK(t[3].kind == SL_TOK_NUMBER);
	CHECK_NEAR(t[3].num, 1.5, 0);
	CHECK(t[5].kind == SL_TOK_STRING);
	CHECK_STR(t[5].str, "s\n");
	CHECK(t[7].kind == SL_TOK_EOF);
	CHECK(t[7].loc.line == 2 && t[7].loc.col == 16);
	CHECK(p.ctx.files.len >= 1);
	CHECK_STR(p.ctx.files.data[t[0].loc.file], "t.sl");
	pp_done(&p);
}

static void test_object_macros(void)
{
	EXPECT("#define N 4\nN * N", "4 * 4");
	EXPECT("#define E\na E b", "a b");
	EXPECT("#define A B\n#define B C\n#define C 7\nA", "7");
	EXPECT("#define X 1\n#undef X\nX", "X");
	EXPECT("#define X 1\n#define X 1\nX", "1"); /* the same again is no redefinition */
	EXPECT("__RELIGHT__", "1");
	EXPECT("#define S \"str\"\nS", "\"str\"");
	/* expanded tokens take the use site's location */
	struct pped p;
	pp(&p, "#define N (1 + 2)\n\n  x = N;");
	CHECK_STR(p.text, "x = ( 1 + 2 ) ;");
	CHECK(p.toks.len == 9);
	for (size_t i = 2; i < 7 && i < p.toks.len; i++)
		CHECK(p.toks.data[i].loc.line == 3 && p.toks.data[i].loc.col == 7);
	CHECK(p.toks.data[7].loc.col == 8);
	pp_done(&p);

	EXPECT_DIAG("#define X 1\n#define X 2\nX", "2", "t.sl:2:9: warning: 'X' redefined\n");
	EXPECT_DIAG("#define 3 x\n", "", "t.sl:1:9: error: macro names must be identifiers\n");
	EXPECT_DIAG("#define defined 1\n", "",
		    "t.sl:1:9: error: 'defined' cannot be used as a macro name\n");
}

static void test_function_macros(void)
{
	EXPECT("#define f(x) [x]\nf(1) f((a, b)) f(g(1, 2)) f()",
	       "[ 1 ] [ ( a , b ) ] [ g ( 1 , 2 ) ] [ ]");
	EXPECT("#define add(a, b) ((a) + (b))\nadd(1, add(2, 3))",
	       "( ( 1 ) + ( ( ( 2 ) + ( 3 ) ) ) )");
	EXPECT("#define z() 0\nz() z ( )", "0 0");
	/* not followed by '(': no call */
	EXPECT("#define f(x) x\nf + f", "f + f");
	/* '(' with a space before it in the definition: object-like */
	EXPECT("#define o (x) x\no", "( x ) x");
	/* arguments over several lines */
	EXPECT("#define f(a, b) a-b\nf(1,\n  2)\nq", "1 - 2 q");
	/* a call whose name comes from an expansion */
	EXPECT("#define f(x) <x>\n#define g f\ng(3)", "< 3 >");
	/* arguments are expanded before substitution */
	EXPECT("#define N 9\n#define id(x) x\nid(N)", "9");
	EXPECT("#define v(x, ...) x: __VA_ARGS__\nv(1) v(1, 2, 3)", "1 : 1 : 2 , 3");

	EXPECT_DIAG("#define f(a, b) a\nf(1)", "",
		    "t.sl:2:1: error: macro 'f' expects 2 arguments, got 1\n");
	EXPECT_DIAG("#define f(a) a\n  f(1, 2)", "",
		    "t.sl:2:3: error: macro 'f' expects 1 argument, got 2\n");
	EXPECT_DIAG("#define f(a) a\nx f(1, 2", "x",
		    "t.sl:2:3: error: unterminated argument list invoking macro 'f'\n");
	EXPECT_DIAG("#define f(a) a\nf(1\n#define y\n)", ")",
		    "t.sl:2:1: error: unterminated argument list invoking macro 'f'\n");
	EXPECT_DIAG("#define f(a, a) a\n", "",
		    "t.sl:1:14: error: duplicate macro parameter 'a'\n");
	EXPECT_DIAG("#define f(a b\n", "",
		    "t.sl:1:13: error: bad macro parameter list near 'b'\n");
}

static void test_stringize_paste(void)
{
	struct pped p;
	pp(&p, "#define S(x) #x\nS(a  +\n b \"q\\n\\\\\") S() S(  1  )");
	CHECK(p.ok);
	CHECK(p.toks.len == 4);
	CHECK(p.toks.data[0].kind == SL_TOK_STRING);
	CHECK_STR(p.toks.data[0].str, "a + b \"q\\n\\\\\"");
	CHECK_STR(p.text, "\"a + b \\\"q\\\\n\\\\\\\\\\\"\" \"\" \"1\"");
	CHECK_STR(p.toks.data[1].str, "");
	CHECK_STR(p.toks.data[2].str, "1");
	pp_done(&p);

	pp(&p, "#define P(a, b) a ## b\nP(x, y) P(1, 2) P(, y) P(x, ) P(+, =) P(,) P(a b, c d)");
	CHECK(p.ok);
	CHECK_STR(p.text, "xy 12 y x += a bc d");
	CHECK(p.toks.data[0].kind == SL_TOK_IDENT);
	CHECK(p.toks.data[0].str == sl_intern_cstr(&p.ctx, "xy"));
	CHECK(p.toks.data[1].kind == SL_TOK_NUMBER);
	CHECK_NEAR(p.toks.data[1].num, 12, 0);
	CHECK(p.toks.data[4].kind == SL_TOK_PLUS_ASSIGN);
	pp_done(&p);

	/* pasted operands are not expanded first; the result is rescanned */
	EXPECT("#define N 1\n#define NN 2\n#define P(a) a ## N\nP(N)", "2");
	EXPECT("#define CAT(a, b) a##b\n#define X(a, b) CAT(a, b)\nX(X(p, q), r)", "pqr");
	EXPECT("#define V v ## 1 ## 2\nV", "v12");
	EXPECT("#define P(a, b) a ## b\nP(&, &)", "&&");
	EXPECT("#define P(a, b) #a ## b\nP(x, )", "\"x\"");

	EXPECT_DIAG("#define P(a, b) a ## b\n P(+, -)", "+ -",
		    "t.sl:2:2: error: pasting '+' and '-' does not give a valid token\n");
	EXPECT_DIAG("#define S(x) #y\n", "",
		    "t.sl:1:14: error: '#' is not followed by a macro parameter\n");
	EXPECT_DIAG("#define P(x) ## x\n", "",
		    "t.sl:1:14: error: '##' cannot appear at either end of a macro expansion\n");
}

static void test_recursion(void)
{
	EXPECT("#define a a\na", "a");
	EXPECT("#define f(x) f(x)+1\nf(2)", "f ( 2 ) + 1");
	EXPECT("#define a b\n#define b a\na b", "a b");
	EXPECT("#define f(x) g(x)\n#define g(x) f(x)\nf(1)", "f ( 1 )");
	/* a name that was not expanded stays so when its tokens are rescanned */
	EXPECT("#define id(x) x\n#define a id(a)\na", "a");
	/* the name may expand again once its expansion is done */
	EXPECT("#define f(x) (x)\nf(f(1))", "( ( 1 ) )");
	/* a name read inside its own expansion stays unexpanded even when the
	 * '(' comes from after the expansion */
	EXPECT("#define f(x) x\nf(f)(1)", "f ( 1 )");

	/* exponential growth ends with an error */
	struct pped p;
	const char *bomb = "#define a0 x x\n#define a1 a0 a0\n#define a2 a1 a1\n#define a3 a2 a2\n"
			   "#define a4 a3 a3\n#define a5 a4 a4\n#define a6 a5 a5\n#define a7 a6 a6\n"
			   "#define a8 a7 a7\n#define a9 a8 a8\n#define b0 a9 a9\n#define b1 b0 b0\n"
			   "#define b2 b1 b1\n#define b3 b2 b2\n#define b4 b3 b3\n#define b5 b4 b4\n"
			   "#define b6 b5 b5\n#define b7 b6 b6\n#define b8 b7 b7\n#define b9 b8 b8\n"
			   "#define c0 b9 b9\n#define c1 c0 c0\n#define c2 c1 c1\n#define c3 c2 c2\n"
			   "c3 end\n";
	pp(&p, bomb);
	CHECK(!p.ok);
	CHECK(strstr(diag(&p), "t.sl:25:1: error: macro expansion too large\n") != NULL);
	CHECK(one_eof(&p));
	CHECK(p.toks.len < (size_t)4 << 20);
	pp_done(&p);

	pp(&p, "#define f(x) x x x x x x x x\nf(f(f(f(f(f(f(f(f(1)))))))))");
	CHECK(!p.ok);
	CHECK(!strncmp(diag(&p), "t.sl:2:", 7));
	CHECK(strstr(diag(&p), ": error: macro expansion too large\n") != NULL);
	CHECK(p.ctx.nerrors == 1);
	pp_done(&p);

	/* deeply nested arguments */
	static const size_t depths[] = { 300, 100000 };
	for (int k = 0; k < 2; k++) {
		size_t depth = depths[k];
		char *src = malloc(depth * 3 + 64);
		strcpy(src, "#define f(x) x\n");
		char *w = src + strlen(src);
		for (size_t i = 0; i < depth; i++) {
			*w++ = 'f';
			*w++ = '(';
		}
		*w++ = '1';
		for (size_t i = 0; i < depth; i++)
			*w++ = ')';
		*w = '\0';
		pp(&p, src);
		CHECK(!p.ok);
		CHECK(one_eof(&p));
		CHECK(p.ctx.nerrors == 1);
		if (k == 0)
			CHECK(strstr(diag(&p), "t.sl:2:401: error: macro arguments nested too deeply\n"));
		else
			CHECK(strstr(diag(&p), "error: macro expansion too large\n"));
		pp_done(&p);
		free(src);
	}
}

/* "#if EXPR" selects "yes" or "no". */
static void check_if(const char *expr, bool want)
{
	char src[512];
	snprintf(src, sizeof(src), "#define TWO 2\n#define F(x) x\n#if %s\nyes\n#else\nno\n#endif\n",
		 expr);
	struct pped p;
	pp(&p, src);
	if (strcmp(p.text, want ? "yes" : "no") || !p.ok)
		fprintf(stderr, "#if %s: got '%s'\n", expr, p.text);
	CHECK_STR(p.text, want ? "yes" : "no");
	CHECK(p.ok);
	CHECK_STR(diag(&p), "");
	pp_done(&p);
}

static void test_if_arithmetic(void)
{
	check_if("1", true);
	check_if("0", false);
	check_if("1 + 2 * 3 == 7", true);
	check_if("(1 + 2) * 3 == 9", true);
	check_if("10 - 2 - 3 == 5", true);
	check_if("7 / 2 == 3 && 7 % 3 == 1", true);
	check_if("-7 / 2 == -3 && -7 % 2 == -1", true);
	check_if("1 << 4 == 16 && 256 >> 4 == 16", true);
	check_if("-16 >> 2 == -4", true);
	check_if("(6 & 3) == 2 && (6 | 3) == 7 && (6 ^ 3) == 5", true);
	check_if("~0 == -1 && ~5 == -6", true);
	check_if("!0 && !!7 == 1 && !5 == 0", true);
	check_if("1 < 2 && 2 <= 2 && 3 > 2 && 2 >= 3", false);
	check_if("1 != 2", true);
	check_if("0 || 0", false);
	check_if("0 || 3", true);
	check_if("1 ? 2 : 0", true);
	check_if("0 ? 1 : 0", false);
	check_if("1 ? 0 ? 5 : 6 : 7", true);
	check_if("(0 ? 1 : 2) == 2", true);
	check_if("-1 < 0", true);
	check_if("+3 == 3", true);
	check_if("TWO * TWO == 4", true);
	check_if("F(TWO) + 1 == 3", true);
	check_if("UNKNOWN", false);
	check_if("UNKNOWN == 0 && float == 0", true);
	check_if("defined TWO", true);
	check_if("defined(TWO) && defined F", true);
	check_if("defined(NOPE)", false);
	check_if("!defined NOPE", true);
	check_if("defined __RELIGHT__ && __RELIGHT__ == 1", true);
	check_if("0 && 1 / 0", false);
	check_if("1 || 1 % 0", true);
	check_if("1 ? 1 : 1 / 0", true);
	check_if("9223372036854775807 + 1 < 0", true);
	check_if("(-9223372036854775807 - 1) / -1 < 0", true);
	check_if("(-9223372036854775807 - 1) % -1 == 0", true);
	check_if("1 << 64 == 0 && 1 << -1 == 0 && -1 >> 70 == -1", true);
	check_if("((((((((((1))))))))))", true);

	EXPECT_DIAG("#if 1 / 0\nx\n#endif\n", "", "t.sl:1:7: error: division by zero in #if\n");
	EXPECT_DIAG("#if 5 % (2 - 2)\nx\n#else\ny\n#endif\n", "y",
		    "t.sl:1:7: error: division by zero in #if\n");
	EXPECT_DIAG("#if\n#endif\n", "", "t.sl:1:2: error: #if with no expression\n");
	EXPECT_DIAG("#if (1\n#endif\n", "", "t.sl:1:2: error: missing ')' in #if at end of line\n");
	EXPECT_DIAG("#if 1 +\n#endif\n", "", "t.sl:1:2: error: expected a value in #if at end of line\n");
	EXPECT_DIAG("#if 1 2\n#endif\n", "", "t.sl:1:7: error: unexpected token in #if near '2'\n");
	EXPECT_DIAG("#if 1.5\n#endif\n", "", "t.sl:1:5: error: floating constant in #if near '1.5'\n");
	EXPECT_DIAG("#if \"s\"\n#endif\n", "", "t.sl:1:5: error: expected a value in #if near '\"s\"'\n");
	EXPECT_DIAG("#if defined(\n#endif\n", "",
		    "t.sl:1:5: error: operator 'defined' requires an identifier\n");
	EXPECT_DIAG("#if 1 ? 2\n#endif\n", "", "t.sl:1:2: error: missing ':' in #if at end of line\n");
}

static void test_conditionals(void)
{
	EXPECT("#ifdef __RELIGHT__\na\n#else\nb\n#endif", "a");
	EXPECT("#ifndef __RELIGHT__\na\n#else\nb\n#endif", "b");
	EXPECT("#define X\n#ifdef X\na\n#endif\n#undef X\n#ifdef X\nb\n#endif", "a");
	/* elif chains take the first true group only */
	const char *chain = "#if N == 1\none\n#elif N == 2\ntwo\n#elif N >= 2\nmany\n#else\nnone\n#endif";
	char src[256];
	const char *want[] = { "none", "one", "two", "many" };
	for (int n = 0; n < 4; n++) {
		snprintf(src, sizeof(src), "#define N %d\n%s", n, chain);
		EXPECT(src, want[n]);
	}
	/* nested conditionals in skipped groups, with garbage that is not looked at */
	EXPECT("#if 0\n#if 1/0 garbage (((\nx\n#else\ny\n#endif\n#bogus\n#error no\n"
	       "#include <nothing>\n#elif 1\nz\n#endif\nw",
	       "z w");
	EXPECT("#if 1\n#if 0\na\n#elif 1\nb\n#else\nc\n#endif\n#else\n#if 1\nd\n#endif\n#endif", "b");
	EXPECT("#if 0\n#ifdef X\n#else\na\n#endif\n#else\nb\n#endif", "b");
	EXPECT("#if 0\n'unbalanced \" quotes in a skipped group $\n#endif\nok", "ok");
	EXPECT("#if 1\n#elif 1/0\n#endif\nok", "ok");

	EXPECT_DIAG("a\n#endif\nb", "a b", "t.sl:2:2: error: #endif without #if\n");
	EXPECT_DIAG("#else\n", "", "t.sl:1:2: error: #else without #if\n");
	EXPECT_DIAG("#elif 1\n", "", "t.sl:1:2: error: #elif without #if\n");
	EXPECT_DIAG("x\n  #if 1\ny\n", "x y", "t.sl:2:3: error: unterminated conditional directive\n");
	EXPECT_DIAG("#ifdef A\n#else\n#else\n#endif\n", "",
		    "t.sl:3:2: error: #else after #else\n");
	EXPECT_DIAG("#if 0\n#else\n#elif 1\n#endif\n", "",
		    "t.sl:3:2: error: #elif after #else\n");
	EXPECT_DIAG("#ifdef\n#endif\n", "", "t.sl:1:2: error: #ifdef expects a macro name\n");
	EXPECT_DIAG("#ifdef A B\n#endif C\n", "",
		    "t.sl:1:10: warning: extra tokens at end of #ifdef near 'B'\n");
}

static void test_directives(void)
{
	EXPECT("#\n# \na", "a");
	/* a comment that spans lines is a space: the directive goes on */
	EXPECT("#define Y 2 /* a\n*/ + 3\nY", "2 + 3");
	EXPECT("#define Y 2 /* a\n*/\nY", "2");
	/* and a '#' after it starts a directive */
	EXPECT("/* a\n*/ #define X 1\nX", "1");
	/* a directive ends where its line does, even if a macro call is open */
	EXPECT("#define f(x) x\nf\n#define g 1\n(g)", "f ( 1 )");
	EXPECT("#define A /* x */ 1 // y\nA", "1");
	EXPECT("#pragma anything (at all)\n#line 10 \"x.sl\"\na", "a");
	EXPECT_DIAG("a\n#error stop  here, please\nb", "a b",
		    "t.sl:2:1: error: stop here, please\n");
	EXPECT_DIAG("#warning don't\n", "", "t.sl:1:1: warning: don't\n");
	EXPECT_DIAG("#frobnicate x\n", "",
		    "t.sl:1:2: error: invalid preprocessing directive near '#frobnicate'\n");
	/* '#' not at the start of a line is no directive */
	EXPECT_DIAG("a # define b\n", "a define b", "t.sl:1:3: error: stray '#' in program\n");
	EXPECT_DIAG("#define H #\nx H\n", "x", "t.sl:2:3: error: stray '#' in program\n");
	EXPECT_DIAG("a ## b & c", "a b c",
		    "t.sl:1:3: error: stray '##' in program\n"
		    "t.sl:1:8: error: stray '&' in program\n");
	EXPECT_DIAG("\"open\n", "\"open",
		    "t.sl:1:1: error: unterminated string near '\"open'\n");
	/* lexical errors count only where tokens are kept */
	EXPECT("#if 0\n0x1F 1e 'c' \"open $\n#endif\nok", "ok");
	EXPECT_DIAG("a 0x1F", "a 0x1F", "t.sl:1:3: error: invalid number near '0x1F'\n");
	EXPECT_DIAG("#define P(a, b) a ## b\n P(1, e)", "1e",
		    "t.sl:2:2: error: invalid number near '1e'\n");
}

static void test_keywords(void)
{
	static const char *const names[] = {
		"float", "color", "point", "vector", "normal", "matrix", "string", "void",
		"uniform", "varying", "output", "extern", "surface", "light", "displacement",
		"volume", "imager", "if", "else", "while", "for", "break", "continue", "return",
		"illuminance", "illuminate", "solar", "gather",
	};
	size_t n = sizeof(names) / sizeof(names[0]);
	CHECK(n == SL_TOK_KW_GATHER - SL_TOK_KW_FLOAT + 1);
	char src[512] = "";
	for (size_t i = 0; i < n; i++) {
		strcat(src, names[i]);
		strcat(src, " ");
	}
	strcat(src, "floaty Float _if");
	struct pped p;
	pp(&p, src);
	CHECK(p.ok);
	CHECK(p.toks.len == n + 4);
	for (size_t i = 0; i < n && i < p.toks.len; i++) {
		CHECK(p.toks.data[i].kind == (enum sl_tok)(SL_TOK_KW_FLOAT + i));
		CHECK_STR(p.toks.data[i].str, names[i]);
	}
	for (size_t i = n; i < n + 3 && i < p.toks.len; i++)
		CHECK(p.toks.data[i].kind == SL_TOK_IDENT);
	pp_done(&p);

	/* keywords that come from macros, and keyword names as macro names */
	pp(&p, "#define T float\n#define color 3\nT x = color;");
	CHECK_STR(p.text, "float x = 3 ;");
	CHECK(p.toks.data[0].kind == SL_TOK_KW_FLOAT);
	CHECK(p.toks.data[0].loc.line == 3 && p.toks.data[0].loc.col == 1);
	pp_done(&p);
}

static void test_defines(void)
{
	const char *defs[] = { "FOO", "BAR=3+4", "EMPTY=", "SQ(x)=((x)*(x))" };
	struct sl_options o = { .defines = defs, .n_defines = 4 };
	struct pped p;
	pp_opts(&p, "t.sl", "FOO BAR [EMPTY] SQ(2)\n#if FOO && BAR == 7\nyes\n#endif", &o);
	CHECK(p.ok);
	CHECK_STR(p.text, "1 3 + 4 [ ] ( ( 2 ) * ( 2 ) ) yes");
	CHECK_STR(diag(&p), "");
	CHECK(p.toks.data[0].loc.line == 1 && p.toks.data[0].loc.col == 1);
	CHECK_STR(p.ctx.files.data[p.toks.data[0].loc.file], "t.sl");
	pp_done(&p);

	const char *bad[] = { "1X=2" };
	o = (struct sl_options){ .defines = bad, .n_defines = 1 };
	pp_opts(&p, "t.sl", "x", &o);
	CHECK(!p.ok);
	CHECK_STR(p.text, "x");
	CHECK(strstr(diag(&p), "<command line>:1:") != NULL);
	CHECK(strstr(diag(&p), "error: macro names must be identifiers") != NULL);
	pp_done(&p);
}

static char *tmpdir;

static bool mkdir_ok(const char *path)
{
	return mkdir(path, 0700) == 0;
}

static char *tmp_path(const char *name)
{
	size_t n = strlen(tmpdir) + strlen(name) + 2;
	char *p = malloc(n);
	snprintf(p, n, "%s/%s", tmpdir, name);
	return p;
}

static void write_file(const char *name, const char *text)
{
	char *path = tmp_path(name);
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (f) {
		fputs(text, f);
		fclose(f);
	}
	free(path);
}

static void remove_file(const char *name)
{
	char *path = tmp_path(name);
	remove(path);
	free(path);
}

static void test_includes(void)
{
	char tmpl[] = "/tmp/relight-test-pp-XXXXXX";
	tmpdir = mkdtemp(tmpl);
	CHECK(tmpdir != NULL);
	if (!tmpdir)
		return;
	char *sub = tmp_path("sys");
	char *sub2 = tmp_path("sys2");
	CHECK(mkdir_ok(sub));
	CHECK(mkdir_ok(sub2));

	write_file("a.h", "#define FROM_A 1\nint_a\n#include <b.h>\n");
	write_file("sys/b.h", "b_here\n#include \"c.h\"\n");
	write_file("sys/c.h", "c_beside_b\n");
	write_file("sys2/d.h", "d2\n");
	write_file("sys/d.h", "d1\n");
	write_file("bad.h", "ok_line\n  $\n");
	write_file("self.h", "#include \"self.h\"\n");
	write_file("twice.h", "#include \"twice.h\"\n#include \"twice.h\"\n");
	write_file("open.h", "#if 1\n");

	char *main_path = tmp_path("main.sl");
	const char *dirs[] = { sub, sub2 };
	struct sl_options o = { .include_dirs = dirs, .n_include_dirs = 2 };
	struct pped p;

	pp_opts(&p, main_path,
		"#include \"a.h\"\nFROM_A\n#include <d.h>\n#define H \"c.h\"\n#include H\nend", &o);
	CHECK(p.ok);
	CHECK_STR(diag(&p), "");
	CHECK_STR(p.text, "int_a b_here c_beside_b 1 d1 c_beside_b end");
	if (p.toks.len == 8) {
		char *a = tmp_path("a.h");
		CHECK_STR(p.ctx.files.data[p.toks.data[0].loc.file], a);
		CHECK(p.toks.data[0].loc.line == 2 && p.toks.data[0].loc.col == 1);
		CHECK_STR(p.ctx.files.data[p.toks.data[3].loc.file], main_path);
		CHECK(p.toks.data[3].loc.line == 2);
		free(a);
		CHECK(strstr(p.ctx.files.data[p.toks.data[2].loc.file], "/sys/c.h") != NULL);
	}
	pp_done(&p);

	/* errors name the file and place they are in */
	char want[1024];
	char *bad = tmp_path("bad.h");
	pp_opts(&p, main_path, "x\n#include \"bad.h\"\ny", &o);
	CHECK(!p.ok);
	CHECK_STR(p.text, "x ok_line y");
	snprintf(want, sizeof(want), "%s:2:3: error: stray '$' in program\n", bad);
	CHECK_STR(diag(&p), want);
	free(bad);
	pp_done(&p);

	pp_opts(&p, main_path, "x\n#include   \"nope.h\"\ny", &o);
	CHECK(!p.ok);
	CHECK_STR(p.text, "x y");
	snprintf(want, sizeof(want), "%s:2:12: error: cannot find include file 'nope.h'\n", main_path);
	CHECK_STR(diag(&p), want);
	pp_done(&p);

	pp_opts(&p, main_path, "#include <nope.h>\n#include\n#include x\n", &o);
	CHECK(!p.ok);
	snprintf(want, sizeof(want),
		 "%s:1:10: error: cannot find include file 'nope.h'\n"
		 "%s:2:2: error: #include expects \"FILENAME\" or <FILENAME>\n"
		 "%s:3:10: error: #include expects \"FILENAME\" or <FILENAME>\n",
		 main_path, main_path, main_path);
	CHECK_STR(diag(&p), want);
	pp_done(&p);

	/* recursion ends at the depth limit; doubling ends at the include count limit */
	pp_opts(&p, main_path, "#include \"self.h\"\n", &o);
	CHECK(!p.ok);
	CHECK(strstr(diag(&p), "self.h:1:10: error: #include nested too deeply\n") != NULL);
	CHECK(one_eof(&p));
	pp_done(&p);
	struct sl_options many = o;
	many.max_errors = 1000000;
	pp_opts(&p, main_path, "#include \"twice.h\"\n", &many);
	CHECK(!p.ok);
	CHECK(strstr(diag(&p), "error: #include nested too deeply\n") != NULL);
	CHECK(strstr(diag(&p), "error: too many #include directives\n") != NULL);
	pp_done(&p);

	/* included source is limited in all */
	size_t big = (size_t)5 << 20;
	char *text = malloc(big + 1);
	memset(text, ' ', big);
	memcpy(text, "big /*", 6);
	memcpy(text + big - 2, "*/", 2);
	text[big] = '\0';
	write_file("big.h", text);
	free(text);
	pp_opts(&p, main_path, "#include \"big.h\"\n#include \"big.h\"\nend", &o);
	CHECK(!p.ok);
	CHECK_STR(p.text, "big end");
	char *big_path = tmp_path("big.h");
	snprintf(want, sizeof(want), "%s:2:10: error: too much included source in '%s'\n",
		 main_path, big_path);
	CHECK_STR(diag(&p), want);
	free(big_path);
	pp_done(&p);

	/* a conditional may not run past the end of its file */
	pp_opts(&p, main_path, "#include \"open.h\"\n#endif\n", &o);
	CHECK(!p.ok);
	CHECK(strstr(diag(&p), "open.h:1:1: error: unterminated conditional directive\n") != NULL);
	CHECK(strstr(diag(&p), "main.sl:2:2: error: #endif without #if\n") != NULL);
	pp_done(&p);

	/* the top-level file's own directory is searched first */
	pp_opts(&p, main_path, "#include \"sys/c.h\"", NULL);
	CHECK(p.ok);
	CHECK_STR(p.text, "c_beside_b");
	pp_done(&p);

	const char *names[] = { "a.h", "sys/b.h", "sys/c.h", "sys/d.h", "sys2/d.h", "bad.h",
				"self.h", "twice.h", "open.h", "big.h" };
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		remove_file(names[i]);
	rmdir(sub);
	rmdir(sub2);
	rmdir(tmpdir);
	free(sub);
	free(sub2);
	free(main_path);
}

static void test_many_errors(void)
{
	/* errors stop at the limit but the output still ends with one EOF */
	struct pped p;
	char *src = malloc(200001);
	for (int i = 0; i < 100000; i++) {
		src[2 * i] = '#';
		src[2 * i + 1] = ' ';
	}
	src[200000] = '\0';
	src[0] = 'x';
	pp(&p, src);
	CHECK(!p.ok);
	CHECK(p.ctx.too_many);
	CHECK(p.ctx.nerrors == 20);
	CHECK(one_eof(&p));
	CHECK(p.toks.len == 2);
	pp_done(&p);
	free(src);
}

int main(void)
{
	RUN(test_plain);
	RUN(test_object_macros);
	RUN(test_function_macros);
	RUN(test_stringize_paste);
	RUN(test_recursion);
	RUN(test_if_arithmetic);
	RUN(test_conditionals);
	RUN(test_directives);
	RUN(test_keywords);
	RUN(test_defines);
	RUN(test_includes);
	RUN(test_many_errors);
	return test_finish();
}

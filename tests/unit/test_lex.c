/* The lexer: token kinds, positions, flags, values and errors. */
#include "test.h"
#include "token.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct lexed {
	struct sl_ctx ctx;
	struct sl_token_list toks;
	FILE *diag;
	char *diag_buf;
	size_t diag_len;
	bool ok;
	uint32_t file;
	char *src; /* the spellings may point into it */
};

/* Lex @len bytes of @src from a heap copy of exactly that size (no NUL after it). */
static void lex_mem(struct lexed *lx, const char *src, size_t len)
{
	memset(lx, 0, sizeof(*lx));
	lx->diag = open_memstream(&lx->diag_buf, &lx->diag_len);
	struct sl_options opts = { .diag = lx->diag };
	sl_ctx_init(&lx->ctx, &opts);
	lx->file = sl_ctx_add_file(&lx->ctx, "t.sl");
	lx->src = malloc(len ? len : 1);
	memcpy(lx->src, src, len);
	lx->ok = sl_lex(&lx->ctx, lx->file, lx->src, len, &lx->toks);
}

static void lex(struct lexed *lx, const char *src)
{
	lex_mem(lx, src, strlen(src));
}

static const char *diag(struct lexed *lx)
{
	fflush(lx->diag);
	return lx->diag_buf ? lx->diag_buf : "";
}

static void lex_done(struct lexed *lx)
{
	free(lx->src);
	fclose(lx->diag);
	free(lx->diag_buf);
	free(lx->toks.data);
	sl_ctx_finish(&lx->ctx);
}

static bool spelled(const struct sl_token *t, const char *s)
{
	return t->len == strlen(s) && !memcmp(t->text, s, t->len);
}

static bool at(const struct sl_token *t, uint32_t line, uint32_t col)
{
	return t->loc.line == line && t->loc.col == col;
}

static void test_punctuators(void)
{
	static const struct {
		const char *s;
		enum sl_tok kind;
	} cases[] = {
		{ "(", SL_TOK_LPAREN }, { ")", SL_TOK_RPAREN }, { "{", SL_TOK_LBRACE },
		{ "}", SL_TOK_RBRACE }, { "[", SL_TOK_LBRACKET }, { "]", SL_TOK_RBRACKET },
		{ ";", SL_TOK_SEMI }, { ",", SL_TOK_COMMA }, { ".", SL_TOK_DOT },
		{ "?", SL_TOK_QUESTION }, { ":", SL_TOK_COLON }, { "^", SL_TOK_CARET },
		{ "+", SL_TOK_PLUS }, { "-", SL_TOK_MINUS }, { "*", SL_TOK_STAR },
		{ "/", SL_TOK_SLASH }, { "%", SL_TOK_PERCENT }, { "!", SL_TOK_BANG },
		{ "=", SL_TOK_ASSIGN }, { "+=", SL_TOK_PLUS_ASSIGN }, { "-=", SL_TOK_MINUS_ASSIGN },
		{ "*=", SL_TOK_STAR_ASSIGN }, { "/=", SL_TOK_SLASH_ASSIGN }, { "++", SL_TOK_INC },
		{ "--", SL_TOK_DEC }, { "==", SL_TOK_EQ }, { "!=", SL_TOK_NE }, { "<", SL_TOK_LT },
		{ "<=", SL_TOK_LE }, { ">", SL_TOK_GT }, { ">=", SL_TOK_GE }, { "&&", SL_TOK_AND },
		{ "||", SL_TOK_OR }, { "#", SL_TOK_HASH }, { "##", SL_TOK_HASHHASH },
	};
	size_t n = sizeof(cases) / sizeof(cases[0]);

	/* all on one line, one space apart */
	char src[512] = "";
	for (size_t i = 0; i < n; i++) {
		strcat(src, cases[i].s);
		strcat(src, " ");
	}
	struct lexed lx;
	lex(&lx, src);
	CHECK(lx.ok);
	CHECK(lx.toks.len == n + 1);
	uint32_t col = 1;
	for (size_t i = 0; i < n && i < lx.toks.len; i++) {
		const struct sl_token *t = &lx.toks.data[i];
		CHECK(t->kind == cases[i].kind);
		CHECK(spelled(t, cases[i].s));
		CHECK(at(t, 1, col));
		CHECK(t->loc.file == lx.file);
		col += (uint32_t)strlen(cases[i].s) + 1;
	}
	CHECK(lx.toks.data[lx.toks.len - 1].kind == SL_TOK_EOF);
	CHECK(at(&lx.toks.data[lx.toks.len - 1], 1, col));
	CHECK_STR(diag(&lx), "");
	lex_done(&lx);

	/* longest match, no spaces */
	lex(&lx, "a+++b<=c==d!=!e");
	enum sl_tok want[] = { SL_TOK_IDENT, SL_TOK_INC, SL_TOK_PLUS, SL_TOK_IDENT, SL_TOK_LE,
			       SL_TOK_IDENT, SL_TOK_EQ, SL_TOK_IDENT, SL_TOK_NE, SL_TOK_BANG,
			       SL_TOK_IDENT, SL_TOK_EOF };
	CHECK(lx.toks.len == sizeof(want) / sizeof(want[0]));
	for (size_t i = 0; i < lx.toks.len && i < sizeof(want) / sizeof(want[0]); i++)
		CHECK(lx.toks.data[i].kind == want[i]);
	CHECK(at(&lx.toks.data[2], 1, 4));
	CHECK(at(&lx.toks.data[4], 1, 6));
	lex_done(&lx);
}

static void test_identifiers(void)
{
	struct lexed lx;
	lex(&lx, "foo _bar\tBaz9 foo\n  float x_1");
	CHECK(lx.ok);
	CHECK(lx.toks.len == 7);
	const struct sl_token *t = lx.toks.data;
	for (int i = 0; i < 6; i++)
		CHECK(t[i].kind == SL_TOK_IDENT);
	CHECK_STR(t[0].str, "foo");
	CHECK_STR(t[1].str, "_bar");
	CHECK_STR(t[2].str, "Baz9");
	CHECK(t[0].str == t[3].str); /* interned */
	CHECK(t[0].str == sl_intern_cstr(&lx.ctx, "foo"));
	CHECK_STR(t[4].str, "float"); /* keywords are the preprocessor's business */
	CHECK(at(&t[0], 1, 1));
	CHECK(at(&t[1], 1, 5));
	CHECK(at(&t[2], 1, 10)); /* a tab counts one column */
	CHECK(at(&t[3], 1, 15));
	CHECK(at(&t[4], 2, 3));
	CHECK(at(&t[5], 2, 9));
	CHECK(spelled(&t[5], "x_1"));
	lex_done(&lx);
}

static void test_numbers(void)
{
	static const struct {
		const char *s;
		double v;
	} cases[] = {
		{ "0", 0 }, { "42", 42 }, { "1.5", 1.5 }, { "1.", 1 }, { ".5", 0.5 },
		{ ".5e2", 50 }, { "1e-3", 1e-3 }, { "2.5E+2", 250 }, { "3f", 3 }, { "1.f", 1 },
		{ "1.5F", 1.5 }, { "6e2f", 600 }, { "007", 7 }, { "123456789012", 123456789012.0 },
		{ "0.1", 0.1 },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		struct lexed lx;
		lex(&lx, cases[i].s);
		CHECK(lx.ok);
		CHECK(lx.toks.len == 2);
		CHECK(lx.toks.data[0].kind == SL_TOK_NUMBER);
		CHECK(spelled(&lx.toks.data[0], cases[i].s));
		CHECK_NEAR(lx.toks.data[0].num, cases[i].v, fabs(cases[i].v) * 1e-15);
		lex_done(&lx);
	}

	/* where numbers end */
	struct lexed lx;
	lex(&lx, "1.5.25 2e x.5 3-1");
	const struct sl_token *t = lx.toks.data;
	CHECK(lx.toks.len == 9);
	CHECK(t[0].kind == SL_TOK_NUMBER && spelled(&t[0], "1.5"));
	CHECK(t[1].kind == SL_TOK_NUMBER && spelled(&t[1], ".25"));
	CHECK_NEAR(t[1].num, 0.25, 0);
	CHECK(at(&t[1], 1, 4));
	CHECK(t[2].kind == SL_TOK_NUMBER && spelled(&t[2], "2e")); /* reported */
	CHECK(t[3].kind == SL_TOK_IDENT && spelled(&t[3], "x"));
	CHECK(t[4].kind == SL_TOK_NUMBER && spelled(&t[4], ".5"));
	CHECK(t[5].kind == SL_TOK_NUMBER && t[6].kind == SL_TOK_MINUS && t[7].kind == SL_TOK_NUMBER);
	CHECK(!lx.ok);
	CHECK_STR(diag(&lx), "t.sl:1:8: error: invalid number near '2e'\n");
	lex_done(&lx);

	/* a number at the very end of a buffer that is not NUL-terminated */
	lex_mem(&lx, "x 12345", 7);
	CHECK(lx.toks.len == 3);
	CHECK_NEAR(lx.toks.data[1].num, 12345, 0);
	lex_done(&lx);
	lex_mem(&lx, "2.5e+1", 6);
	CHECK_NEAR(lx.toks.data[0].num, 25, 0);
	lex_done(&lx);
	lex_mem(&lx, "9e+", 3);
	CHECK(lx.toks.len == 3);
	CHECK(lx.toks.data[0].kind == SL_TOK_NUMBER);
	CHECK(spelled(&lx.toks.data[0], "9e"));
	CHECK(lx.toks.data[1].kind == SL_TOK_PLUS);
	lex_done(&lx);
}

static void test_strings(void)
{
	struct lexed lx;
	lex(&lx, "\"a\\nb\\t\\\\\\\"\\r\\a\\b\\f\\v\\101\\x41\\x7e\\'\\?\" \"\"");
	CHECK(lx.ok);
	CHECK(lx.toks.len == 3);
	const struct sl_token *t = lx.toks.data;
	CHECK(t[0].kind == SL_TOK_STRING);
	CHECK_STR(t[0].str, "a\nb\t\\\"\r\a\b\f\vAA~'?");
	CHECK(spelled(&t[0], "\"a\\nb\\t\\\\\\\"\\r\\a\\b\\f\\v\\101\\x41\\x7e\\'\\?\""));
	CHECK(t[1].kind == SL_TOK_STRING);
	CHECK_STR(t[1].str, "");
	CHECK(at(&t[1], 1, 40));
	lex_done(&lx);

	/* octal stops after three digits, hex after two */
	lex(&lx, "\"\\1234\\x414\"");
	CHECK_STR(lx.toks.data[0].str, "S4A4");
	lex_done(&lx);

	/* unknown escapes warn and keep the character */
	lex(&lx, "\"\\q\"");
	CHECK(lx.ok);
	CHECK_STR(lx.toks.data[0].str, "q");
	CHECK_STR(diag(&lx), "t.sl:1:3: warning: unknown escape sequence '\\q'\n");
	lex_done(&lx);
}

static void test_unterminated(void)
{
	struct lexed lx;
	lex(&lx, "x = \"abc\ny");
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 5);
	CHECK(lx.toks.data[2].kind == SL_TOK_STRING);
	CHECK_STR(lx.toks.data[2].str, "abc");
	CHECK(lx.toks.data[3].kind == SL_TOK_IDENT);
	CHECK(at(&lx.toks.data[3], 2, 1));
	CHECK(lx.toks.data[3].flags & SL_TOKF_BOL);
	CHECK_STR(diag(&lx), "t.sl:1:5: error: unterminated string near '\"abc'\n");
	lex_done(&lx);

	/* at the end of the buffer */
	lex_mem(&lx, "\n  \"ab\\", 7);
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 2);
	CHECK_STR(diag(&lx), "t.sl:2:3: error: unterminated string near '\"ab\\'\n");
	lex_done(&lx);

	lex(&lx, "a /* one\n two *\n");
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 2);
	CHECK_STR(diag(&lx), "t.sl:1:3: error: unterminated comment\n");
	lex_done(&lx);

	lex_mem(&lx, "/", 1);
	CHECK(lx.ok);
	CHECK(lx.toks.len == 2 && lx.toks.data[0].kind == SL_TOK_SLASH);
	lex_done(&lx);
	lex_mem(&lx, "/*", 2);
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 1);
	lex_done(&lx);
}

static void test_stray(void)
{
	struct lexed lx;
	lex_mem(&lx, "a $ b\n@\x01\x80 \xff c\0d '", 17);
	CHECK(!lx.ok);
	const struct sl_token *t = lx.toks.data;
	CHECK(lx.toks.len == 5);
	CHECK(spelled(&t[0], "a") && spelled(&t[1], "b") && spelled(&t[2], "c"));
	CHECK(spelled(&t[3], "d"));
	CHECK(at(&t[2], 2, 7));
	CHECK(t[2].flags == (SL_TOKF_BOL | SL_TOKF_SPACE)); /* the first token on its line */
	CHECK(at(&t[3], 2, 9));
	CHECK(t[3].flags == 0);
	CHECK(t[4].kind == SL_TOK_EOF);
	CHECK_STR(diag(&lx), "t.sl:1:3: error: stray '$' in program\n"
			     "t.sl:2:1: error: stray '@' in program\n"
			     "t.sl:2:2: error: stray '\\x01' in program\n"
			     "t.sl:2:3: error: stray '\\x80' in program\n"
			     "t.sl:2:5: error: stray '\\xff' in program\n"
			     "t.sl:2:8: error: stray '\\x00' in program\n"
			     "t.sl:2:11: error: stray ''' in program\n");
	lex_done(&lx);

	/* '&', '|' and '~' alone are no RSL tokens */
	lex(&lx, "a & b | ~c");
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 4);
	CHECK(strstr(diag(&lx), "t.sl:1:3: error: stray '&' in program\n") != NULL);
	CHECK(strstr(diag(&lx), "t.sl:1:9: error: stray '~' in program\n") != NULL);
	lex_done(&lx);

	/* a lone backslash */
	lex_mem(&lx, "\\", 1);
	CHECK(!lx.ok);
	CHECK(lx.toks.len == 1 && lx.toks.data[0].kind == SL_TOK_EOF);
	CHECK_STR(diag(&lx), "t.sl:1:1: error: stray '\\' in program\n");
	lex_done(&lx);
}

static void test_flags(void)
{
	struct lexed lx;
	lex(&lx, "a b(c)\n  d /* x */e//z\nf/*\n*/g\n\n#h");
	const struct sl_token *t = lx.toks.data;
	CHECK(lx.toks.len == 12);
	/* a */ CHECK(t[0].flags == SL_TOKF_BOL);
	/* b */ CHECK(t[1].flags == SL_TOKF_SPACE);
	/* ( */ CHECK(t[2].flags == 0);
	/* c */ CHECK(t[3].flags == 0);
	/* d */ CHECK(t[5].flags == (SL_TOKF_BOL | SL_TOKF_SPACE));
	CHECK(at(&t[5], 2, 3));
	/* e */ CHECK(t[6].flags == SL_TOKF_SPACE);
	CHECK(at(&t[6], 2, 12));
	/* f */ CHECK(t[7].flags == (SL_TOKF_BOL | SL_TOKF_SPACE));
	/* g: after a comment that spans a newline */
	CHECK(t[8].flags == (SL_TOKF_BOL | SL_TOKF_SPACE));
	CHECK(at(&t[8], 4, 3));
	/* # */ CHECK(t[9].kind == SL_TOK_HASH && (t[9].flags & SL_TOKF_BOL));
	CHECK(at(&t[9], 6, 1));
	CHECK(t[10].kind == SL_TOK_IDENT && t[10].flags == 0);
	lex_done(&lx);

	lex(&lx, "");
	CHECK(lx.ok);
	CHECK(lx.toks.len == 1);
	CHECK(lx.toks.data[0].kind == SL_TOK_EOF);
	CHECK(at(&lx.toks.data[0], 1, 1));
	lex_done(&lx);
}

static void test_splices(void)
{
	struct lexed lx;
	/* a name split over lines, a splice before a token, CR-LF splices */
	lex(&lx, "ab\\\ncd x\\\n y \"s\\\nt\" 1\\\r\n.5 +\\\n=");
	CHECK(lx.ok);
	const struct sl_token *t = lx.toks.data;
	CHECK(lx.toks.len == 7);
	CHECK(spelled(&t[0], "abcd"));
	CHECK_STR(t[0].str, "abcd");
	CHECK(at(&t[0], 1, 1));
	CHECK(spelled(&t[1], "x") && at(&t[1], 2, 4));
	/* a continuation line is no new line */
	CHECK(spelled(&t[2], "y") && at(&t[2], 3, 2) && t[2].flags == SL_TOKF_SPACE);
	CHECK(t[3].kind == SL_TOK_STRING && spelled(&t[3], "\"st\""));
	CHECK_STR(t[3].str, "st");
	CHECK(t[4].kind == SL_TOK_NUMBER && spelled(&t[4], "1.5"));
	CHECK_NEAR(t[4].num, 1.5, 0);
	CHECK(at(&t[4], 4, 4));
	CHECK(t[5].kind == SL_TOK_PLUS_ASSIGN && spelled(&t[5], "+="));
	lex_done(&lx);

	/* a comment continued by a splice */
	lex(&lx, "a // x \\\n b\nc");
	CHECK(lx.toks.len == 3);
	CHECK(spelled(&lx.toks.data[1], "c"));
	lex_done(&lx);

	/* a splice at the end, and a file of splices */
	lex_mem(&lx, "x\\\n", 3);
	CHECK(lx.ok);
	CHECK(lx.toks.len == 2);
	CHECK(at(&lx.toks.data[1], 2, 1));
	lex_done(&lx);
	lex(&lx, "\\\n\\\n\\\n");
	CHECK(lx.ok && lx.toks.len == 1);
	lex_done(&lx);
}

static void test_tok_name(void)
{
	CHECK_STR(sl_tok_name(SL_TOK_EOF), "end of file");
	CHECK_STR(sl_tok_name(SL_TOK_IDENT), "identifier");
	CHECK_STR(sl_tok_name(SL_TOK_NUMBER), "number");
	CHECK_STR(sl_tok_name(SL_TOK_STRING), "string");
	CHECK_STR(sl_tok_name(SL_TOK_LPAREN), "'('");
	CHECK_STR(sl_tok_name(SL_TOK_SLASH_ASSIGN), "'/='");
	CHECK_STR(sl_tok_name(SL_TOK_KW_FLOAT), "'float'");
	CHECK_STR(sl_tok_name(SL_TOK_KW_GATHER), "'gather'");
	for (int k = 0; k < SL_TOK_COUNT; k++)
		CHECK(sl_tok_name((enum sl_tok)k)[0] != '\0');
	CHECK_STR(sl_tok_name(SL_TOK_COUNT), "token");
}

static void test_big_inputs(void)
{
	/* a 1 MB line of "a+" */
	size_t n = 1 << 20;
	char *src = malloc(n);
	for (size_t i = 0; i < n; i += 2) {
		src[i] = 'a';
		src[i + 1] = '+';
	}
	struct lexed lx;
	lex_mem(&lx, src, n);
	CHECK(lx.ok);
	CHECK(lx.toks.len == n + 1);
	CHECK(at(&lx.toks.data[n - 1], 1, (uint32_t)n));
	lex_done(&lx);

	/* one 1 MB identifier and one 1 MB number */
	memset(src, 'z', n);
	lex_mem(&lx, src, n);
	CHECK(lx.toks.len == 2 && lx.toks.data[0].len == n);
	lex_done(&lx);
	memset(src, '7', n);
	src[1] = '.';
	lex_mem(&lx, src, n);
	CHECK(lx.toks.len == 2);
	CHECK_NEAR(lx.toks.data[0].num, 7.777777777777778, 1e-12);
	lex_done(&lx);

	/* 1 MB of random bytes: errors stop at the limit, lexing goes on to EOF */
	uint64_t state = 0x9e3779b97f4a7c15ull;
	for (size_t i = 0; i < n; i++) {
		state = state * 6364136223846793005ull + 1442695040888963407ull;
		src[i] = (char)(state >> 56);
	}
	lex_mem(&lx, src, n);
	CHECK(!lx.ok);
	CHECK(lx.toks.len >= 1);
	CHECK(lx.toks.data[lx.toks.len - 1].kind == SL_TOK_EOF);
	size_t eofs = 0;
	for (size_t i = 0; i < lx.toks.len; i++)
		eofs += lx.toks.data[i].kind == SL_TOK_EOF;
	CHECK(eofs == 1);
	CHECK(lx.ctx.too_many);
	CHECK(lx.ctx.nerrors == 20);
	CHECK(strstr(diag(&lx), "too many errors") != NULL);
	lex_done(&lx);

	/* 1 MB of stray bytes only */
	memset(src, '@', n);
	lex_mem(&lx, src, n);
	CHECK(lx.toks.len == 1);
	CHECK(lx.ctx.nerrors == 20);
	lex_done(&lx);

	/* 1 MB of backslashes */
	memset(src, '\\', n);
	lex_mem(&lx, src, n);
	CHECK(lx.toks.len == 1);
	lex_done(&lx);
	free(src);
}

int main(void)
{
	RUN(test_punctuators);
	RUN(test_identifiers);
	RUN(test_numbers);
	RUN(test_strings);
	RUN(test_unterminated);
	RUN(test_stray);
	RUN(test_flags);
	RUN(test_splices);
	RUN(test_tok_name);
	RUN(test_big_inputs);
	return test_finish();
}

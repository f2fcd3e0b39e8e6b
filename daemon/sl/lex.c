/*
 * The lexer: bytes to tokens. Backslash-newline splices are skipped while
 * reading, so a token may span physical lines; such a token's spelling is a
 * copy without the splices. Every token records where it starts, whether it
 * begins a physical line and whether blank space or a comment precedes it.
 */
#include "token.h"
#include "../common/strbuf.h"

#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/*
 * sl_lex() for the preprocessor, which reports these errors only for tokens
 * that reach its output, so that skipped groups and #error text may hold
 * anything and #if may use '&', '|' and '~': a byte that starts no token
 * becomes a one-byte SL_TOK_HASH token spelled as that byte; an invalid
 * number gets the value NaN; an unterminated string is left unreported.
 * A token that starts a line only because a comment before it spans lines
 * also gets TOKF_COMMENT_LINE: such a line break does not end a directive.
 */
bool sl_lex_pp(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
	       struct sl_token_list *out);

#define TOKF_COMMENT_LINE (1u << 6)

struct lexer {
	struct sl_ctx *ctx;
	uint32_t file;
	const char *src;
	size_t len, pos;
	uint32_t line, col;
	bool spliced;          /* a splice was skipped since the current token began */
	bool pp_mode;          /* sl_lex_pp(): some errors are left to the preprocessor */
	bool failed;
	struct rl_strbuf buf;  /* a string literal's value while it is read */
	char decimal_point;    /* what strtod() expects in place of '.' */
	struct sl_token_list *out;
};

static const char *const tok_names[SL_TOK_COUNT] = {
	[SL_TOK_EOF] = "end of file",
	[SL_TOK_IDENT] = "identifier",
	[SL_TOK_NUMBER] = "number",
	[SL_TOK_STRING] = "string",
	[SL_TOK_LPAREN] = "'('",
	[SL_TOK_RPAREN] = "')'",
	[SL_TOK_LBRACE] = "'{'",
	[SL_TOK_RBRACE] = "'}'",
	[SL_TOK_LBRACKET] = "'['",
	[SL_TOK_RBRACKET] = "']'",
	[SL_TOK_SEMI] = "';'",
	[SL_TOK_COMMA] = "','",
	[SL_TOK_DOT] = "'.'",
	[SL_TOK_QUESTION] = "'?'",
	[SL_TOK_COLON] = "':'",
	[SL_TOK_CARET] = "'^'",
	[SL_TOK_PLUS] = "'+'",
	[SL_TOK_MINUS] = "'-'",
	[SL_TOK_STAR] = "'*'",
	[SL_TOK_SLASH] = "'/'",
	[SL_TOK_PERCENT] = "'%'",
	[SL_TOK_BANG] = "'!'",
	[SL_TOK_ASSIGN] = "'='",
	[SL_TOK_PLUS_ASSIGN] = "'+='",
	[SL_TOK_MINUS_ASSIGN] = "'-='",
	[SL_TOK_STAR_ASSIGN] = "'*='",
	[SL_TOK_SLASH_ASSIGN] = "'/='",
	[SL_TOK_INC] = "'++'",
	[SL_TOK_DEC] = "'--'",
	[SL_TOK_EQ] = "'=='",
	[SL_TOK_NE] = "'!='",
	[SL_TOK_LT] = "'<'",
	[SL_TOK_LE] = "'<='",
	[SL_TOK_GT] = "'>'",
	[SL_TOK_GE] = "'>='",
	[SL_TOK_AND] = "'&&'",
	[SL_TOK_OR] = "'||'",
	[SL_TOK_HASH] = "'#'",
	[SL_TOK_HASHHASH] = "'##'",
	[SL_TOK_KW_FLOAT] = "'float'",
	[SL_TOK_KW_COLOR] = "'color'",
	[SL_TOK_KW_POINT] = "'point'",
	[SL_TOK_KW_VECTOR] = "'vector'",
	[SL_TOK_KW_NORMAL] = "'normal'",
	[SL_TOK_KW_MATRIX] = "'matrix'",
	[SL_TOK_KW_STRING] = "'string'",
	[SL_TOK_KW_VOID] = "'void'",
	[SL_TOK_KW_UNIFORM] = "'uniform'",
	[SL_TOK_KW_VARYING] = "'varying'",
	[SL_TOK_KW_OUTPUT] = "'output'",
	[SL_TOK_KW_EXTERN] = "'extern'",
	[SL_TOK_KW_SURFACE] = "'surface'",
	[SL_TOK_KW_LIGHT] = "'light'",
	[SL_TOK_KW_DISPLACEMENT] = "'displacement'",
	[SL_TOK_KW_VOLUME] = "'volume'",
	[SL_TOK_KW_IMAGER] = "'imager'",
	[SL_TOK_KW_IF] = "'if'",
	[SL_TOK_KW_ELSE] = "'else'",
	[SL_TOK_KW_WHILE] = "'while'",
	[SL_TOK_KW_FOR] = "'for'",
	[SL_TOK_KW_BREAK] = "'break'",
	[SL_TOK_KW_CONTINUE] = "'continue'",
	[SL_TOK_KW_RETURN] = "'return'",
	[SL_TOK_KW_ILLUMINANCE] = "'illuminance'",
	[SL_TOK_KW_ILLUMINATE] = "'illuminate'",
	[SL_TOK_KW_SOLAR] = "'solar'",
	[SL_TOK_KW_GATHER] = "'gather'",
};

const char *sl_tok_name(enum sl_tok kind)
{
	if ((unsigned)kind < SL_TOK_COUNT && tok_names[kind])
		return tok_names[kind];
	return "token";
}

static void lex_error(struct lexer *L, struct sl_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void lex_error(struct lexer *L, struct sl_loc loc, const char *fmt, ...)
{
	L->failed = true;
	if (L->ctx->too_many)
		return;
	struct rl_strbuf msg = { 0 };
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(&msg, fmt, ap);
	va_end(ap);
	sl_error(L->ctx, loc, "%s", rl_strbuf_str(&msg));
	rl_strbuf_finish(&msg);
}

/* The length of a backslash-newline (or backslash-CR-LF) splice at @p, or 0. */
static size_t splice_at(const char *src, size_t len, size_t p)
{
	if (p + 1 >= len || src[p] != '\\')
		return 0;
	if (src[p + 1] == '\n')
		return 2;
	if (src[p + 1] == '\r' && p + 2 < len && src[p + 2] == '\n')
		return 3;
	return 0;
}

/* The byte at the read position, after any splices there; -1 at the end. */
static int cur(struct lexer *L)
{
	size_t n;
	while ((n = splice_at(L->src, L->len, L->pos)) != 0) {
		L->pos += n;
		L->line++;
		L->col = 1;
		L->spliced = true;
	}
	return L->pos < L->len ? (unsigned char)L->src[L->pos] : -1;
}

/* The byte @n places after the current one (n >= 1), looking past splices. */
static int ahead(const struct lexer *L, int n)
{
	size_t p = L->pos;
	while (n-- > 0) {
		if (p >= L->len)
			return -1;
		p++;
		size_t s;
		while ((s = splice_at(L->src, L->len, p)) != 0)
			p += s;
	}
	return p < L->len ? (unsigned char)L->src[p] : -1;
}

/* Step over the current byte; cur() must have been called before. */
static void adv(struct lexer *L)
{
	if (L->src[L->pos] == '\n') {
		L->line++;
		L->col = 1;
	} else {
		L->col++;
	}
	L->pos++;
}

static bool is_digit(int c)
{
	return c >= '0' && c <= '9';
}

static bool is_ident_start(int c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}

static bool is_ident_char(int c)
{
	return is_ident_start(c) || is_digit(c);
}

static struct sl_loc here(const struct lexer *L)
{
	return (struct sl_loc){ L->file, L->line, L->col };
}

static struct sl_token *push(struct lexer *L, enum sl_tok kind, uint8_t flags, struct sl_loc loc,
			     size_t start)
{
	struct sl_token t = { .kind = kind, .flags = flags, .loc = loc };
	size_t end = L->pos;
	if (!L->spliced) {
		t.text = L->src + start;
		t.len = (uint32_t)(end - start);
	} else {
		/* the spelling without its splices */
		char *s = rl_arena_alloc(L->ctx->arena, end - start + 1);
		size_t n = 0;
		for (size_t p = start; p < end;) {
			size_t sp = splice_at(L->src, end, p);
			if (sp) {
				p += sp;
				continue;
			}
			s[n++] = L->src[p++];
		}
		t.text = s;
		t.len = (uint32_t)n;
	}
	rl_vec_push(*L->out, t);
	return &L->out->data[L->out->len - 1];
}

/* number: digits ['.' digits] [exponent] ['f'] | '.' digits [exponent] ['f'] */
static void lex_number(struct lexer *L, uint8_t flags)
{
	struct sl_loc loc = here(L);
	size_t start = L->pos;
	bool has_f = false;
	while (is_digit(cur(L)))
		adv(L);
	if (cur(L) == '.') {
		adv(L);
		while (is_digit(cur(L)))
			adv(L);
	}
	int c = cur(L);
	if (c == 'e' || c == 'E') {
		int c1 = ahead(L, 1);
		if (is_digit(c1) || ((c1 == '+' || c1 == '-') && is_digit(ahead(L, 2)))) {
			adv(L);
			if (!is_digit(cur(L)))
				adv(L);
			while (is_digit(cur(L)))
				adv(L);
		}
	}
	c = cur(L);
	if (c == 'f' || c == 'F') {
		adv(L);
		has_f = true;
	}
	bool bad_suffix = false;
	if (is_ident_char(cur(L))) {
		bad_suffix = true;
		while (is_ident_char(cur(L)))
			adv(L);
	}
	struct sl_token *t = push(L, SL_TOK_NUMBER, flags, loc, start);
	if (bad_suffix && L->pp_mode) {
		t->num = NAN;
		return;
	}
	if (bad_suffix)
		lex_error(L, loc, "invalid number near '%.*s'", t->len > 40 ? 40 : (int)t->len,
			  t->text);

	/* strtod() on a terminated copy (it stops at a bad suffix); it reads the
	 * locale's decimal point */
	size_t n = t->len - (has_f && !bad_suffix ? 1 : 0);
	char small[64];
	char *copy = n < sizeof(small) ? small : rl_xmalloc(n + 1);
	memcpy(copy, t->text, n);
	copy[n] = '\0';
	if (L->decimal_point != '.') {
		char *dot = memchr(copy, '.', n);
		if (dot)
			*dot = L->decimal_point;
	}
	t->num = strtod(copy, NULL);
	if (copy != small)
		free(copy);
}

static int hex_value(int c)
{
	if (is_digit(c))
		return c - '0';
	if (c >= 'a' && c <= 'f')
		return c - 'a' + 10;
	if (c >= 'A' && c <= 'F')
		return c - 'A' + 10;
	return -1;
}

/* The value of the escape after a backslash, which has been read. */
static char lex_escape(struct lexer *L)
{
	struct sl_loc loc = here(L);
	int c = cur(L);
	if (c < 0 || c == '\n')
		return '\\'; /* the caller reports the unterminated string */
	adv(L);
	switch (c) {
	case 'n': return '\n';
	case 't': return '\t';
	case 'r': return '\r';
	case 'a': return '\a';
	case 'b': return '\b';
	case 'f': return '\f';
	case 'v': return '\v';
	case '\\': return '\\';
	case '"': return '"';
	case '\'': return '\'';
	case '?': return '?';
	case 'x': {
		int v = 0, digits = 0, d;
		while (digits < 2 && (d = hex_value(cur(L))) >= 0) {
			v = v * 16 + d;
			digits++;
			adv(L);
		}
		if (!digits)
			lex_error(L, loc, "\\x used with no following hex digits");
		return (char)v;
	}
	default:
		break;
	}
	if (c >= '0' && c <= '7') {
		int v = c - '0';
		for (int i = 0; i < 2 && cur(L) >= '0' && cur(L) <= '7'; i++) {
			v = v * 8 + (cur(L) - '0');
			adv(L);
		}
		return (char)(v & 0xff);
	}
	if (!L->ctx->too_many) {
		char what[16];
		if (c > ' ' && c < 0x7f)
			snprintf(what, sizeof(what), "%c", c);
		else
			snprintf(what, sizeof(what), "x%02x", (unsigned)(unsigned char)c);
		sl_warning(L->ctx, loc, "unknown escape sequence '\\%s'", what);
	}
	return (char)c;
}

/* string: '"' { char | escape } '"' */
static void lex_string(struct lexer *L, uint8_t flags)
{
	struct sl_loc loc = here(L);
	size_t start = L->pos;
	bool closed = false;
	rl_strbuf_reset(&L->buf);
	adv(L);
	for (;;) {
		int c = cur(L);
		if (c < 0 || c == '\n')
			break;
		adv(L);
		if (c == '"') {
			closed = true;
			break;
		}
		char v = c == '\\' ? lex_escape(L) : (char)c;
		rl_strbuf_add(&L->buf, &v, 1);
	}
	struct sl_token *t = push(L, SL_TOK_STRING, flags, loc, start);
	t->str = rl_arena_strndup(L->ctx->arena, rl_strbuf_str(&L->buf), L->buf.len);
	if (!closed && !L->pp_mode) {
		/* quote at most the start of a long literal */
		int n = t->len > 40 ? 40 : (int)t->len;
		lex_error(L, loc, "unterminated string near '%.*s'", n, t->text);
	}
}

/* Punctuators: the longest match wins. */
static enum sl_tok lex_punct(struct lexer *L, int c)
{
	int c1 = ahead(L, 1);
	enum sl_tok one, two = SL_TOK_EOF;
	switch (c) {
	case '(': return SL_TOK_LPAREN;
	case ')': return SL_TOK_RPAREN;
	case '{': return SL_TOK_LBRACE;
	case '}': return SL_TOK_RBRACE;
	case '[': return SL_TOK_LBRACKET;
	case ']': return SL_TOK_RBRACKET;
	case ';': return SL_TOK_SEMI;
	case ',': return SL_TOK_COMMA;
	case '.': return SL_TOK_DOT;
	case '?': return SL_TOK_QUESTION;
	case ':': return SL_TOK_COLON;
	case '^': return SL_TOK_CARET;
	case '%': return SL_TOK_PERCENT;
	case '+':
		one = SL_TOK_PLUS;
		if (c1 == '+')
			two = SL_TOK_INC;
		else if (c1 == '=')
			two = SL_TOK_PLUS_ASSIGN;
		break;
	case '-':
		one = SL_TOK_MINUS;
		if (c1 == '-')
			two = SL_TOK_DEC;
		else if (c1 == '=')
			two = SL_TOK_MINUS_ASSIGN;
		break;
	case '*':
		one = SL_TOK_STAR;
		if (c1 == '=')
			two = SL_TOK_STAR_ASSIGN;
		break;
	case '/':
		one = SL_TOK_SLASH;
		if (c1 == '=')
			two = SL_TOK_SLASH_ASSIGN;
		break;
	case '!':
		one = SL_TOK_BANG;
		if (c1 == '=')
			two = SL_TOK_NE;
		break;
	case '=':
		one = SL_TOK_ASSIGN;
		if (c1 == '=')
			two = SL_TOK_EQ;
		break;
	case '<':
		one = SL_TOK_LT;
		if (c1 == '=')
			two = SL_TOK_LE;
		break;
	case '>':
		one = SL_TOK_GT;
		if (c1 == '=')
			two = SL_TOK_GE;
		break;
	case '#':
		one = SL_TOK_HASH;
		if (c1 == '#')
			two = SL_TOK_HASHHASH;
		break;
	case '&':
		if (c1 != '&')
			return SL_TOK_EOF;
		one = SL_TOK_EOF;
		two = SL_TOK_AND;
		break;
	case '|':
		if (c1 != '|')
			return SL_TOK_EOF;
		one = SL_TOK_EOF;
		two = SL_TOK_OR;
		break;
	default:
		return SL_TOK_EOF;
	}
	if (two != SL_TOK_EOF) {
		adv(L);
		return two;
	}
	return one;
}

/* A byte that starts no token; returns whether a token was made of it. */
static bool lex_stray(struct lexer *L, int c, uint8_t flags)
{
	struct sl_loc loc = here(L);
	size_t start = L->pos;
	adv(L);
	if (L->pp_mode) {
		push(L, SL_TOK_HASH, flags, loc, start);
		return true;
	}
	char what[16];
	if (c > ' ' && c < 0x7f)
		snprintf(what, sizeof(what), "%c", c);
	else
		snprintf(what, sizeof(what), "\\x%02x", (unsigned)(unsigned char)c);
	lex_error(L, loc, "stray '%s' in program", what);
	return false;
}

/* Skip blanks and comments; returns the flags for the next token. */
static uint8_t skip_space(struct lexer *L, uint8_t flags)
{
	for (;;) {
		int c = cur(L);
		if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
			adv(L);
			flags |= SL_TOKF_SPACE;
		} else if (c == '\n') {
			adv(L);
			flags = (uint8_t)((flags | SL_TOKF_BOL | SL_TOKF_SPACE) & ~TOKF_COMMENT_LINE);
		} else if (c == '/' && ahead(L, 1) == '/') {
			while ((c = cur(L)) >= 0 && c != '\n')
				adv(L);
			flags |= SL_TOKF_SPACE;
		} else if (c == '/' && ahead(L, 1) == '*') {
			struct sl_loc loc = here(L);
			adv(L);
			adv(L);
			for (;;) {
				c = cur(L);
				if (c < 0) {
					lex_error(L, loc, "unterminated comment");
					break;
				}
				if (c == '*' && ahead(L, 1) == '/') {
					adv(L);
					cur(L);
					adv(L);
					break;
				}
				if (c == '\n' && !(flags & SL_TOKF_BOL))
					flags |= SL_TOKF_BOL | (L->pp_mode ? TOKF_COMMENT_LINE : 0);
				adv(L);
			}
			flags |= SL_TOKF_SPACE;
		} else {
			return flags;
		}
	}
}

static bool lex_all(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
		    struct sl_token_list *out, bool pp_mode)
{
	struct lexer L = {
		.ctx = ctx,
		.file = file,
		.src = src ? src : "",
		.len = src ? len : 0,
		.line = 1,
		.col = 1,
		.pp_mode = pp_mode,
		.out = out,
	};
	const char *dp = localeconv()->decimal_point;
	L.decimal_point = dp && dp[0] ? dp[0] : '.';

	uint8_t flags = SL_TOKF_BOL;
	for (;;) {
		flags = skip_space(&L, flags);
		int c = cur(&L);
		if (c < 0)
			break;
		L.spliced = false;
		if (is_ident_start(c)) {
			struct sl_loc loc = here(&L);
			size_t start = L.pos;
			while (is_ident_char(cur(&L)))
				adv(&L);
			struct sl_token *t = push(&L, SL_TOK_IDENT, flags, loc, start);
			t->str = sl_intern(ctx, t->text, t->len);
		} else if (is_digit(c) || (c == '.' && is_digit(ahead(&L, 1)))) {
			lex_number(&L, flags);
		} else if (c == '"') {
			lex_string(&L, flags);
		} else {
			struct sl_loc loc = here(&L);
			size_t start = L.pos;
			enum sl_tok kind = lex_punct(&L, c);
			if (kind == SL_TOK_EOF) {
				/* the next token takes the flags of what was skipped */
				if (!lex_stray(&L, c, flags))
					continue;
			} else {
				cur(&L);
				adv(&L);
				push(&L, kind, flags, loc, start);
			}
		}
		flags = 0;
	}
	struct sl_token eof = {
		.kind = SL_TOK_EOF,
		.flags = flags,
		.text = "",
		.loc = here(&L),
	};
	rl_vec_push(*out, eof);
	rl_strbuf_finish(&L.buf);
	return !L.failed;
}

bool sl_lex(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
	    struct sl_token_list *out)
{
	return lex_all(ctx, file, src, len, out, false);
}

bool sl_lex_pp(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
	       struct sl_token_list *out)
{
	return lex_all(ctx, file, src, len, out, true);
}

/* Tokens, the lexer and the preprocessor. */
#ifndef SL_TOKEN_H
#define SL_TOKEN_H

#include "ctx.h"

enum sl_tok {
	SL_TOK_EOF,
	SL_TOK_IDENT,
	SL_TOK_NUMBER,
	SL_TOK_STRING,

	/* punctuators */
	SL_TOK_LPAREN, SL_TOK_RPAREN, SL_TOK_LBRACE, SL_TOK_RBRACE,
	SL_TOK_LBRACKET, SL_TOK_RBRACKET, SL_TOK_SEMI, SL_TOK_COMMA,
	SL_TOK_DOT, SL_TOK_QUESTION, SL_TOK_COLON, SL_TOK_CARET,
	SL_TOK_PLUS, SL_TOK_MINUS, SL_TOK_STAR, SL_TOK_SLASH, SL_TOK_PERCENT,
	SL_TOK_BANG, SL_TOK_ASSIGN,
	SL_TOK_PLUS_ASSIGN, SL_TOK_MINUS_ASSIGN, SL_TOK_STAR_ASSIGN, SL_TOK_SLASH_ASSIGN,
	SL_TOK_INC, SL_TOK_DEC,
	SL_TOK_EQ, SL_TOK_NE, SL_TOK_LT, SL_TOK_LE, SL_TOK_GT, SL_TOK_GE,
	SL_TOK_AND, SL_TOK_OR,
	SL_TOK_HASH, SL_TOK_HASHHASH, /* only inside the preprocessor */

	/* keywords: the preprocessor's last step turns IDENTs with these names into them */
	SL_TOK_KW_FLOAT, SL_TOK_KW_COLOR, SL_TOK_KW_POINT, SL_TOK_KW_VECTOR,
	SL_TOK_KW_NORMAL, SL_TOK_KW_MATRIX, SL_TOK_KW_STRING, SL_TOK_KW_VOID,
	SL_TOK_KW_UNIFORM, SL_TOK_KW_VARYING, SL_TOK_KW_OUTPUT, SL_TOK_KW_EXTERN,
	SL_TOK_KW_SURFACE, SL_TOK_KW_LIGHT, SL_TOK_KW_DISPLACEMENT,
	SL_TOK_KW_VOLUME, SL_TOK_KW_IMAGER,
	SL_TOK_KW_IF, SL_TOK_KW_ELSE, SL_TOK_KW_WHILE, SL_TOK_KW_FOR,
	SL_TOK_KW_BREAK, SL_TOK_KW_CONTINUE, SL_TOK_KW_RETURN,
	SL_TOK_KW_ILLUMINANCE, SL_TOK_KW_ILLUMINATE, SL_TOK_KW_SOLAR,
	SL_TOK_KW_GATHER,

	SL_TOK_COUNT
};

enum {
	SL_TOKF_BOL = 1 << 0,   /* first token on its source line */
	SL_TOKF_SPACE = 1 << 1, /* whitespace (or a comment) before it */
};

struct sl_token {
	enum sl_tok kind;
	uint8_t flags;
	uint32_t len;          /* length of the spelling */
	const char *text;      /* spelling, not NUL-terminated (arena or source) */
	struct sl_loc loc;     /* where it was written (for macro expansions: the use site) */
	double num;            /* SL_TOK_NUMBER: its value */
	const char *str;       /* SL_TOK_STRING: the value, escapes resolved, NUL-terminated;
				  SL_TOK_IDENT and keywords: the interned name */
};

struct sl_token_list {
	struct sl_token *data;
	size_t len, cap;
};

/** The spelling of a token kind for messages: "'('", "identifier", "'float'"... */
const char *sl_tok_name(enum sl_tok kind);

/**
 * Split @src (the contents of file @file) into tokens, appended to @out,
 * followed by one SL_TOK_EOF. Comments (C and C++ style) are skipped;
 * backslash-newline joins lines. Numbers: 1, 1.5, .5, 1e-3, 1.f (a trailing f
 * is accepted). Strings: C escapes \n \t \\ \" \r \a \b \f \v \ooo \xhh.
 * Errors (a stray character, an unterminated string or comment) are reported
 * and lexing continues. Returns false if there was an error.
 */
bool sl_lex(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
	    struct sl_token_list *out);

/**
 * Lex and preprocess the file @path whose contents are @src: #include "x"
 * and <x> (searched beside the including file, then in ctx->opts.include_dirs),
 * #define (object- and function-like, # and ##), #undef, #if/#ifdef/#ifndef/
 * #elif/#else/#endif with defined() and integer arithmetic, #error, #warning,
 * #line and #pragma (ignored); -D definitions from ctx->opts.defines.
 * The result, appended to @out and ended by SL_TOK_EOF, holds no directives;
 * identifiers that are keywords have their keyword kinds; adjacent string
 * literals are left separate (the parser joins them).
 * Returns false if there was an error; the tokens are still usable.
 */
bool sl_preprocess(struct sl_ctx *ctx, const char *path, const char *src, size_t len,
		   struct sl_token_list *out);

#endif

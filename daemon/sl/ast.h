/* The abstract syntax tree of one RSL translation unit. */
#ifndef SL_AST_H
#define SL_AST_H

#include "token.h"

/** Base types. TRIPLE kinds (color, point, vector, normal) hold three floats. */
enum sl_basetype {
	SL_TYPE_VOID,
	SL_TYPE_FLOAT,
	SL_TYPE_COLOR,
	SL_TYPE_POINT,
	SL_TYPE_VECTOR,
	SL_TYPE_NORMAL,
	SL_TYPE_MATRIX,
	SL_TYPE_STRING,
	SL_TYPE_BOOL,   /* conditions only: relations and logic; never stored in a variable */
	SL_TYPE_COUNT
};

enum sl_detail {
	SL_DETAIL_DEFAULT,  /* not written: parameters are uniform, locals varying */
	SL_DETAIL_UNIFORM,
	SL_DETAIL_VARYING,
};

/** A type as written or inferred. */
struct sl_type {
	uint8_t base;      /* enum sl_basetype */
	uint8_t detail;    /* enum sl_detail */
	int32_t arraylen;  /* -1: not an array; 0: array of unspecified size (function
			      parameters, "float a[]"); n > 0: fixed size */
};

static inline bool sl_type_is_triple(int base)
{
	return base == SL_TYPE_COLOR || base == SL_TYPE_POINT || base == SL_TYPE_VECTOR ||
	       base == SL_TYPE_NORMAL;
}

/** Floats per element: float 1, triples 3, matrix 16, others 0. */
static inline int sl_type_ncomp(int base)
{
	switch (base) {
	case SL_TYPE_FLOAT: case SL_TYPE_BOOL: return 1;
	case SL_TYPE_COLOR: case SL_TYPE_POINT: case SL_TYPE_VECTOR: case SL_TYPE_NORMAL: return 3;
	case SL_TYPE_MATRIX: return 16;
	default: return 0;
	}
}

/** "float", "color", ... */
const char *sl_basetype_name(int base);

/**
 * Node kinds. Per kind, which fields are used (all others zero):
 *
 * Expressions
 *   NUM       num
 *   STR       str (adjacent literals already joined)
 *   IDENT     name
 *   UNARY     op (SL_TOK_MINUS, SL_TOK_PLUS, SL_TOK_BANG), a
 *   BINARY    op (+ - * / ^ . == != < <= > >= && ||; '.' is SL_TOK_DOT, '^' SL_TOK_CARET), a, b
 *   ASSIGN    op (SL_TOK_ASSIGN or a compound one), a = target (IDENT or INDEX), b = value
 *   INCDEC    op (SL_TOK_INC/SL_TOK_DEC), a = target; num = 1 for prefix, 0 for postfix
 *   COND      a ? b : c
 *   CALL      name, list = arguments
 *   INDEX     a[b]
 *   CTOR      type (base; arraylen -1), a = space-name expression or NULL,
 *             list = components: 1 (a cast or promotion: `color 1`, `vector P`,
 *             `point "world" P`), 3 (a triple), 16 (a matrix)
 *   ARRAYLIT  list = elements ({1, 2, 3}; only as an initializer)
 *
 * Declarations
 *   VAR       name, type, output, is_extern, a = initializer or NULL
 *             (a declarator of a DECL, or a shader or function parameter)
 *   DECL      list = VARs sharing one type (`float Ka = 1, Kd = .5;`)
 *   FUNC      name, type = return type, list = parameters (VAR), a = body (BLOCK)
 *   SHADER    op = enum sl_shader_kind, name, list = parameters (VAR), a = body (BLOCK)
 *   UNIT      list = FUNCs and SHADERs in source order
 *
 * Statements
 *   BLOCK     list = statements
 *   EXPR      a = expression
 *   IF        a = condition, b = then, c = else or NULL
 *   WHILE     a = condition, b = body
 *   FOR       a = init (EXPR or NULL), b = condition or NULL, c = step expression
 *             or NULL, d = body
 *   BREAK     num = levels (1 when not written)
 *   CONTINUE  num = levels
 *   RETURN    a = value or NULL
 *   ILLUMINANCE list = arguments in order: [category string,] position
 *             [, axis, angle]; a = body
 *   ILLUMINATE list = position [, axis, angle]; a = body
 *   SOLAR     list = [axis, angle]; a = body
 *   EMPTY     ;
 *   (FUNC and DECL also appear as statements.)
 */
enum sl_ast_kind {
	SL_AST_NUM, SL_AST_STR, SL_AST_IDENT, SL_AST_UNARY, SL_AST_BINARY, SL_AST_ASSIGN,
	SL_AST_INCDEC, SL_AST_COND, SL_AST_CALL, SL_AST_INDEX, SL_AST_CTOR, SL_AST_ARRAYLIT,
	SL_AST_VAR, SL_AST_DECL, SL_AST_FUNC, SL_AST_SHADER, SL_AST_UNIT,
	SL_AST_BLOCK, SL_AST_EXPR, SL_AST_IF, SL_AST_WHILE, SL_AST_FOR, SL_AST_BREAK,
	SL_AST_CONTINUE, SL_AST_RETURN, SL_AST_ILLUMINANCE, SL_AST_ILLUMINATE, SL_AST_SOLAR,
	SL_AST_EMPTY,
	SL_AST_KIND_COUNT
};

struct sl_ast {
	enum sl_ast_kind kind;
	struct sl_loc loc;       /* the node's first token (for BINARY/ASSIGN: the operator) */
	int op;
	const char *name;        /* interned */
	double num;
	const char *str;
	struct sl_type type;
	bool output, is_extern;
	struct sl_ast *a, *b, *c, *d;
	struct sl_ast **list;
	uint32_t nlist;

	/* Filled in by semantic analysis. */
	struct sl_type ty;       /* an expression's type (detail: UNIFORM or VARYING) */
	struct sl_sym *sym;      /* IDENT, VAR, FUNC: the symbol; CALL of a user function: it */
	int overload;            /* CALL of a built-in: index into sl_builtins[]; else -1 */
};

/** A new node of @kind at @loc, zeroed, overload -1, type.arraylen -1, in ctx's arena. */
struct sl_ast *sl_ast_new(struct sl_ctx *ctx, enum sl_ast_kind kind, struct sl_loc loc);

/**
 * Parse a preprocessed token list (ending in SL_TOK_EOF) into a UNIT.
 * Reports "FILE:LINE:COL: error: MESSAGE near 'tok'" and recovers at the next
 * ';' or '}' to report more. Returns the UNIT (possibly partial) or NULL when
 * nothing could be parsed; check ctx->nerrors. Nesting deeper than 256 levels
 * is an error, never a stack overflow.
 */
struct sl_ast *sl_parse(struct sl_ctx *ctx, const struct sl_token *toks, size_t ntoks);

/** Print the tree, one node a line, indented by depth ("[N] " past 64 levels). */
void sl_ast_dump(const struct sl_ctx *ctx, const struct sl_ast *node, FILE *out);

/** "NUM", "BINARY", ... */
const char *sl_ast_kind_name(enum sl_ast_kind kind);

#endif

/* Semantic analysis, lowering and uniformity inference: the compiler's middle. */
#ifndef SL_SEMA_H
#define SL_SEMA_H

#include "ir.h"

enum sl_sym_kind {
	SL_SYM_VAR,     /* local variable, function formal or shader parameter */
	SL_SYM_GLOBAL,  /* renderer-provided global (P, N, Ci...) */
	SL_SYM_FUNC,    /* user function (one overload) */
};

struct sl_sym {
	enum sl_sym_kind kind;
	const char *name;          /* interned */
	struct sl_type type;       /* variables: their type; functions: the return type */
	bool output;               /* output parameter or formal */
	bool is_param;             /* shader parameter */
	bool is_formal;            /* function formal */
	int global;                /* SL_SYM_GLOBAL: enum sl_global */
	struct sl_ast *decl;       /* VAR or FUNC node */
	struct sl_sym *next;       /* SL_SYM_FUNC: the next overload visible with this name */
	bool has_return;           /* SL_SYM_FUNC: its body holds a return not in tail position */
};

/**
 * Check the unit: resolve names, check and annotate types (ast.ty, ast.sym,
 * ast.overload), pick built-in overloads. Returns the shader node, or NULL
 * (errors reported) when the unit is not a valid shader.
 */
struct sl_ast *sl_sema(struct sl_ctx *ctx, struct sl_ast *unit);

/** Lower a checked shader to IR, inlining user functions. NULL on errors. */
struct sl_program *sl_lower(struct sl_ctx *ctx, struct sl_ast *shader);

/**
 * Decide which registers are varying (the fixpoint described in infer.c) and
 * report uniform variables that would have to become varying. False on errors.
 */
bool sl_infer(struct sl_ctx *ctx, struct sl_program *prog);

/** True for the spatial triples (point, vector, normal). */
static inline bool sl_type_is_spatial(int base)
{
	return base == SL_TYPE_POINT || base == SL_TYPE_VECTOR || base == SL_TYPE_NORMAL;
}

/** Type from a builtin signature letter ('f', 'c', 'P', ...); arraylen 0 for capitals. */
struct sl_type sl_sig_type(char letter);

/** "uniform float", "varying color[3]"... (arena string) */
const char *sl_type_str(struct sl_ctx *ctx, struct sl_type t);

#endif

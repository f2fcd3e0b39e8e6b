/* One compilation: its arena, its files, its diagnostics, its interned names. */
#ifndef SL_CTX_H
#define SL_CTX_H

#include "sl.h"
#include "../common/arena.h"
#include "../common/fileutil.h"

#include <stdbool.h>
#include <stdint.h>

/** A place in the source: file index into sl_ctx.files, 1-based line and column. */
struct sl_loc {
	uint32_t file;
	uint32_t line;
	uint32_t col;
};

struct sl_intern_table {
	const char **slots;
	size_t cap, count;
};

struct sl_ctx {
	struct rl_arena *arena;       /* everything of this compilation lives here */
	struct sl_options opts;
	FILE *diag;
	RL_VEC(const char *) files;   /* file names, indexed by sl_loc.file */
	int nerrors, nwarnings;
	int max_errors;
	bool too_many;                /* max_errors reached: phases should wind down */
	bool quiet;                   /* suppress diagnostics (counts still kept) */
	struct sl_intern_table names;
	/* Every source text read (the file, its includes) and the -D definitions,
	 * in order: the key of generated programs cached on disk. */
	struct rl_hash128 source_hash;
	/* The tokens the preprocessor hands the parser (kind and spelling):
	 * what a shader compiles to, whatever its comments and layout. */
	struct rl_hash128 program_hash;
};

void sl_ctx_init(struct sl_ctx *ctx, const struct sl_options *opts);
void sl_ctx_finish(struct sl_ctx *ctx);

/** Register a file name; returns its index for sl_loc.file. */
uint32_t sl_ctx_add_file(struct sl_ctx *ctx, const char *name);

/**
 * Report "FILE:LINE:COL: error: MESSAGE" (or "warning"). Messages about a token
 * should end in "near 'tok'". After max_errors errors, one "too many errors"
 * line is printed and ctx->too_many is set.
 */
void sl_error(struct sl_ctx *ctx, struct sl_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
void sl_warning(struct sl_ctx *ctx, struct sl_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/**
 * The one copy of a name: equal names give equal pointers, so interned names
 * compare with ==. Lives in the arena.
 */
const char *sl_intern(struct sl_ctx *ctx, const char *s, size_t len);
const char *sl_intern_cstr(struct sl_ctx *ctx, const char *s);

#endif

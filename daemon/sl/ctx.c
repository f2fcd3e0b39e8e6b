#include "ctx.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sl_ctx_init(struct sl_ctx *ctx, const struct sl_options *opts)
{
	memset(ctx, 0, sizeof(*ctx));
	ctx->arena = rl_arena_create();
	if (opts)
		ctx->opts = *opts;
	ctx->diag = ctx->opts.diag ? ctx->opts.diag : stderr;
	ctx->max_errors = ctx->opts.max_errors > 0 ? ctx->opts.max_errors : 20;
	rl_hash128_init(&ctx->source_hash);
	rl_hash128_init(&ctx->program_hash);
}

void sl_ctx_finish(struct sl_ctx *ctx)
{
	rl_arena_destroy(ctx->arena);
	rl_vec_free(ctx->files);
	free(ctx->names.slots);
	memset(ctx, 0, sizeof(*ctx));
}

uint32_t sl_ctx_add_file(struct sl_ctx *ctx, const char *name)
{
	for (size_t i = 0; i < ctx->files.len; i++)
		if (!strcmp(ctx->files.data[i], name))
			return (uint32_t)i;
	rl_vec_push(ctx->files, rl_arena_strdup(ctx->arena, name));
	return (uint32_t)(ctx->files.len - 1);
}

static void report(struct sl_ctx *ctx, struct sl_loc loc, const char *what, const char *fmt,
		   va_list ap)
{
	const char *file = loc.file < ctx->files.len ? ctx->files.data[loc.file] : "<input>";
	fprintf(ctx->diag, "%s:%u:%u: %s: ", file, loc.line, loc.col, what);
	vfprintf(ctx->diag, fmt, ap);
	fputc('\n', ctx->diag);
}

void sl_error(struct sl_ctx *ctx, struct sl_loc loc, const char *fmt, ...)
{
	if (ctx->too_many)
		return;
	ctx->nerrors++;
	if (!ctx->quiet) {
		va_list ap;
		va_start(ap, fmt);
		report(ctx, loc, "error", fmt, ap);
		va_end(ap);
	}
	if (ctx->nerrors >= ctx->max_errors) {
		ctx->too_many = true;
		if (!ctx->quiet) {
			const char *file =
				loc.file < ctx->files.len ? ctx->files.data[loc.file] : "<input>";
			fprintf(ctx->diag, "%s: error: too many errors (%d), stopping\n", file,
				ctx->nerrors);
		}
	}
}

void sl_warning(struct sl_ctx *ctx, struct sl_loc loc, const char *fmt, ...)
{
	if (ctx->too_many)
		return;
	ctx->nwarnings++;
	if (ctx->quiet)
		return;
	va_list ap;
	va_start(ap, fmt);
	report(ctx, loc, "warning", fmt, ap);
	va_end(ap);
}

static uint64_t hash_name(const char *s, size_t len)
{
	uint64_t h = 1469598103934665603ull;
	for (size_t i = 0; i < len; i++) {
		h ^= (unsigned char)s[i];
		h *= 1099511628211ull;
	}
	return h;
}

const char *sl_intern(struct sl_ctx *ctx, const char *s, size_t len)
{
	struct sl_intern_table *t = &ctx->names;
	if (t->count * 2 >= t->cap) {
		size_t ncap = t->cap ? t->cap * 2 : 256;
		const char **nslots = rl_xcalloc(ncap, sizeof(*nslots));
		for (size_t i = 0; i < t->cap; i++) {
			const char *n = t->slots[i];
			if (!n)
				continue;
			size_t j = hash_name(n, strlen(n)) & (ncap - 1);
			while (nslots[j])
				j = (j + 1) & (ncap - 1);
			nslots[j] = n;
		}
		free(t->slots);
		t->slots = nslots;
		t->cap = ncap;
	}
	size_t j = hash_name(s, len) & (t->cap - 1);
	while (t->slots[j]) {
		const char *n = t->slots[j];
		if (!strncmp(n, s, len) && n[len] == '\0')
			return n;
		j = (j + 1) & (t->cap - 1);
	}
	const char *n = rl_arena_strndup(ctx->arena, s, len);
	t->slots[j] = n;
	t->count++;
	return n;
}

const char *sl_intern_cstr(struct sl_ctx *ctx, const char *s)
{
	return sl_intern(ctx, s, strlen(s));
}

/*
 * The shader cache: entries keyed by the source file's path, the include
 * folders and the definitions; each remembers a hash of the bytes of every
 * file the compilation read, and is reused only while they still hash the
 * same (a shader or one of its headers edited between two reads is
 * compiled again).
 */
#include "shader_cache.h"

#include "arena.h"
#include "fileutil.h"
#include "ir.h"
#include "sl.h"
#include "strbuf.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Larger source files do not compile (MAX_SOURCE in program.c); their hash is "none". */
#define MAX_HASHED (64u << 20)

struct entry {
	char *key;
	struct sl_program *prog;
	char files_hash[33];
	char *log;     /* the compilation's warnings, repeated at each reuse */
	size_t loglen;
};

struct reyes_shader_cache {
	RL_VEC(struct entry) entries;
	uint64_t compiled, reused;
};

struct reyes_shader_cache *reyes_shader_cache_create(void)
{
	return rl_xcalloc(1, sizeof(struct reyes_shader_cache));
}

void reyes_shader_cache_destroy(struct reyes_shader_cache *c)
{
	if (!c)
		return;
	for (size_t i = 0; i < c->entries.len; i++) {
		free(c->entries.data[i].key);
		free(c->entries.data[i].log);
		sl_program_destroy(c->entries.data[i].prog);
	}
	rl_vec_free(c->entries);
	free(c);
}

/* What a compilation depends on besides the files: path, include folders, definitions. */
static char *make_key(const char *path, const struct sl_options *o)
{
	struct rl_strbuf b = {0};
	rl_strbuf_printf(&b, "%s", path);
	for (size_t i = 0; i < o->n_include_dirs; i++)
		rl_strbuf_printf(&b, "\n-I%s", o->include_dirs[i] ? o->include_dirs[i] : "");
	for (size_t i = 0; i < o->n_defines; i++)
		rl_strbuf_printf(&b, "\n-D%s", o->defines[i] ? o->defines[i] : "");
	char *key = rl_xstrdup(rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return key;
}

/* A hash of the bytes of every file @prog was compiled from, in order (a missing file counts). */
static void hash_files(const struct sl_program *prog, char out[33])
{
	struct rl_hash128 h;
	rl_hash128_init(&h);
	for (uint32_t i = 0; i < prog->nfiles; i++) {
		char err[128];
		size_t len = 0;
		char *data = rl_read_file(prog->files[i], MAX_HASHED, &len, err, sizeof(err));
		rl_hash128_str(&h, prog->files[i]);
		rl_hash128_add(&h, data ? "+" : "-", 1);
		if (data)
			rl_hash128_add(&h, data, len);
		free(data);
	}
	rl_hash128_hex(&h, out);
}

struct sl_program *reyes_shader_cache_compile(struct reyes_shader_cache *c, const char *path,
					      const struct sl_options *opts)
{
	static const struct sl_options none = {0};
	if (!opts)
		opts = &none;
	char *key = make_key(path, opts);
	struct entry *e = NULL;
	for (size_t i = 0; i < c->entries.len && !e; i++)
		if (strcmp(c->entries.data[i].key, key) == 0)
			e = &c->entries.data[i];
	FILE *diag = opts->diag ? opts->diag : stderr;
	if (e) {
		char now[33];
		hash_files(e->prog, now);
		if (strcmp(now, e->files_hash) == 0) {
			free(key);
			c->reused++;
			fwrite(e->log, 1, e->loglen, diag);
			return e->prog;
		}
	}
	/* The diagnostics are kept, so that a reuse reports the same warnings. */
	char *log = NULL;
	size_t loglen = 0;
	FILE *mem = open_memstream(&log, &loglen);
	struct sl_options so = *opts;
	so.diag = mem ? mem : diag;
	struct sl_program *prog = sl_compile_file(path, &so);
	c->compiled++;
	if (mem) {
		fclose(mem);
		fwrite(log, 1, loglen, diag);
	}
	if (!prog) {
		free(log);
		free(key);
		return NULL;
	}
	if (!e) {
		rl_vec_push(c->entries, ((struct entry){.key = key}));
		e = &c->entries.data[c->entries.len - 1];
	} else {
		free(key);
		free(e->log);
		sl_program_destroy(e->prog);
	}
	e->prog = prog;
	e->log = log;
	e->loglen = mem ? loglen : 0;
	hash_files(prog, e->files_hash);
	return prog;
}

void reyes_shader_cache_counts(const struct reyes_shader_cache *c, uint64_t *compiled,
			       uint64_t *reused)
{
	if (compiled)
		*compiled = c ? c->compiled : 0;
	if (reused)
		*reused = c ? c->reused : 0;
}

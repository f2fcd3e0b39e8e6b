/*
 * Compiled shaders kept between the reads of a scene and the frames of a
 * render, so that a run compiles each shader once: reused while the files
 * it was compiled from (its source and every #include) are unchanged.
 */
#ifndef REYES_SHADER_CACHE_H
#define REYES_SHADER_CACHE_H

#include <stdint.h>

struct sl_options;
struct sl_program;

/** A cache of compiled shaders. Not thread-safe: one user at a time. */
struct reyes_shader_cache;

/** An empty cache; never NULL (aborts when out of memory). */
struct reyes_shader_cache *reyes_shader_cache_create(void);

/** Free @c and every program it holds. Accepts NULL. */
void reyes_shader_cache_destroy(struct reyes_shader_cache *c);

/**
 * The shader in the file at @path compiled with @opts' include folders and
 * definitions: the program compiled before when the files it came from hold
 * the same bytes as then, else a fresh compilation (diagnostics to
 * opts->diag). Returns NULL when it does not compile (nothing is kept then).
 * The program belongs to @c: valid until @c is destroyed or the same
 * @path and options are compiled again after a change of its files.
 */
struct sl_program *reyes_shader_cache_compile(struct reyes_shader_cache *c, const char *path,
					      const struct sl_options *opts);

/** How many compilations @c has made, and how many requests it served without one. */
void reyes_shader_cache_counts(const struct reyes_shader_cache *c, uint64_t *compiled,
			       uint64_t *reused);

#endif

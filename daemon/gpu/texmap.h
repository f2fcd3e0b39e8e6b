/*
 * Texture and environment maps on the GPU for the texture() and
 * environment() calls of generated kernels (sl/glsl.h map sites): a map as
 * the texture system holds it (every mip level, channels reordered),
 * uploaded once with its level table and wrap modes, and bound to a
 * kernel's call site.
 */
#ifndef GPU_TEXMAP_H
#define GPU_TEXMAP_H

#include "gpu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

struct reyes_texsys;
struct gpu_texmap;

/** The most mip levels a map may have on the GPU (the level table of sl/glsl_texmap.c). */
#define GPU_TEXMAP_LEVELS 16

/**
 * Load map @name through @ts (its search path, as the renderer's texture()
 * and environment() find it) and upload its levels. NULL with the reason
 * in @err when the file is missing or unreadable, or too big for the GPU.
 */
struct gpu_texmap *gpu_texmap_load(struct gpu_ctx *ctx, struct reyes_texsys *ts,
				   const char *name, char *err, size_t errlen);
void gpu_texmap_destroy(struct gpu_texmap *m);

/** Bytes the map takes in GPU memory. */
size_t gpu_texmap_bytes(const struct gpu_texmap *m);

/**
 * Fill @b with the binding of map @m for gpu_dispatch(): its buffer (levels
 * and their table, sl/glsl_texmap.c) at texture unit @unit, that of map site
 * k of a kernel: SL_GLSL_SHADOW_UNIT0 + the kernel's shadow sites + k. @m
 * NULL: no map, the lookups give the fill; then @b must come in with
 * b->buffer set to a buffer of zeros of the same context (any size).
 */
bool gpu_texmap_bind(const struct gpu_texmap *m, uint32_t unit, struct gpu_binding *b);

struct gpu_texmaps;

/**
 * A shot's maps by name, each loaded through @ts once and shared by every
 * light and site that names it. Warnings go to @diag as
 * "relight: warning: WHO: NAME: why".
 */
struct gpu_texmaps *gpu_texmaps_create(struct gpu_ctx *ctx, struct reyes_texsys *ts, FILE *diag);
/** Frees every map. Accepts NULL. */
void gpu_texmaps_destroy(struct gpu_texmaps *c);

/**
 * The map named @name (NULL for the empty name, and for a map that is
 * missing, unreadable or over @room bytes: the lookups then give the fill,
 * with one warning for the name that says which light, @who, wanted it).
 */
const struct gpu_texmap *gpu_texmaps_get(struct gpu_texmaps *c, const char *name, const char *who,
					 size_t room);

/** GPU bytes of the maps loaded. */
size_t gpu_texmaps_bytes(const struct gpu_texmaps *c);

/** How many maps are loaded (for tests: a swap back to a map loads nothing). */
uint32_t gpu_texmaps_count(const struct gpu_texmaps *c);

/**
 * Free the maps whose names are not among @names[0 .. n) (those something
 * may still read): what a shot holds of its maps follows its lights.
 */
void gpu_texmaps_keep_only(struct gpu_texmaps *c, const char *const *names, uint32_t n);

#endif

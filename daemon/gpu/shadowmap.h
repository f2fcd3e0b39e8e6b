/*
 * Shadow maps on the GPU for the shadow() calls of generated kernels
 * (sl/glsl.h): a depth map file as the renderer reads it, uploaded once, and
 * bound to a kernel's call site with its matrices and bias.
 */
#ifndef GPU_SHADOWMAP_H
#define GPU_SHADOWMAP_H

#include "gpu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct reyes_texsys;
struct gpu_shadow_map;

/**
 * Load the shadow map @name through @ts (its search path, as the renderer's
 * shadow() finds it) and upload its depths. NULL with the reason in @err
 * when the file is missing, unreadable, or not a shadow map (no depth
 * channel or no camera matrices).
 */
struct gpu_shadow_map *gpu_shadow_map_load(struct gpu_ctx *ctx, struct reyes_texsys *ts,
					   const char *name, char *err, size_t errlen);
void gpu_shadow_map_destroy(struct gpu_shadow_map *m);

/** Bytes the map takes in GPU memory. */
size_t gpu_shadow_map_bytes(const struct gpu_shadow_map *m);

/**
 * Set the uniforms of shadow() site @site of @p for map @m (NULL: no map,
 * the lookup gives the fill) and fill @b with the binding to pass to
 * gpu_dispatch() (a placeholder buffer when @m is NULL). @to_world takes the
 * kernel's current space to world. False when @p has no such site.
 */
bool gpu_shadow_map_bind(struct gpu_ctx *ctx, struct gpu_program *p, uint32_t site,
			 const struct gpu_shadow_map *m, const float to_world[16],
			 struct gpu_binding *b);

#endif

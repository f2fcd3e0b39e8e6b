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

/** A deep shadow map (render/deepshadow.h), not a depth map. */
bool gpu_shadow_map_is_deep(const struct gpu_shadow_map *m);

/** The map's size in texels. */
void gpu_shadow_map_size(const struct gpu_shadow_map *m, uint32_t *width, uint32_t *height);

/**
 * A map with the camera, size and bias of @like and the depths of @depth (an
 * SSBO of width * height floats of @like's context, as
 * gpu_shadow_geometry_render writes them). The map does not own @depth,
 * which must outlive it. NULL when out of memory.
 */
struct gpu_shadow_map *gpu_shadow_map_with_depth(const struct gpu_shadow_map *like,
						 struct gpu_buffer *depth);

/**
 * A deep map with the camera, size and bias of @like and the offsets and
 * nodes of @deep (@bytes of them, as gpu_shadow_geometry_render_deep writes
 * them), which the map takes over (destroyed with it). NULL when out of
 * memory (@deep is then still the caller's).
 */
struct gpu_shadow_map *gpu_shadow_map_with_deep(const struct gpu_shadow_map *like,
						struct gpu_buffer *deep, size_t bytes);

/** Give @m another camera (a map made by gpu_shadow_map_with_depth, re-rendered). */
void gpu_shadow_map_set_camera(struct gpu_shadow_map *m, const float world_to_camera[16],
			       const float world_to_ndc[16]);

/** The camera of @m: world -> camera and world -> NDC (row vectors). */
void gpu_shadow_map_camera(const struct gpu_shadow_map *m, float world_to_camera[16],
			   float world_to_ndc[16]);

/**
 * Set the uniforms of shadow() site @site of @p (sl/glsl.h: u_shadow<site>_*,
 * u_to_world) for map @m and fill @b with the binding to pass to
 * gpu_dispatch(): the map's depths at texture unit SL_GLSL_SHADOW_UNIT0 +
 * @site. @m NULL: no map, the lookup gives the fill (size 0 x 0); the kernel
 * then reads nothing at that unit, but a binding needs some buffer, so @b
 * must come in with b->buffer set to any buffer of @ctx (the kernel's input
 * buffer will do) and only its unit and kind are set. @to_world takes the
 * kernel's current space to world (what reyes_texsys_create() got as
 * camera_to_world). False when @p has no such site, or @m is NULL and no
 * buffer came in.
 */
bool gpu_shadow_map_bind(struct gpu_ctx *ctx, struct gpu_program *p, uint32_t site,
			 const struct gpu_shadow_map *m, const float to_world[16],
			 struct gpu_binding *b);

#endif

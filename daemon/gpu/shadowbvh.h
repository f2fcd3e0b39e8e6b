/*
 * Ray-traced shadows on the GPU: a bounding-volume hierarchy over a shot's
 * shadow geometry (shadowrender.h), traversed by the shading kernels
 * (sl/glsl.h's rl_bvh_transmission) for each sample and light, so that a
 * moved light moves its ray-traced shadow with no map.
 *
 * The hierarchy is built on the CPU by Embree's BVH builder (SAH, two
 * children a node, leaves of at most 4 triangles, depth at most 32) over the
 * two triangles (v0, v1, v2), (v0, v2, v3) of every micropolygon, the cut
 * the hider makes, and kept beside the geometry in GPU memory: 32 bytes a
 * node and 48 a triangle.
 */
#ifndef GPU_SHADOWBVH_H
#define GPU_SHADOWBVH_H

#include "shadowrender.h"

/* A ray-traced shadow's start offset along its ray when its shadow() gives no "bias":
 * the renderer's default Attribute "trace" "bias". */
#define GPU_TRACE_BIAS 0.01f

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/**
 * Build @g's hierarchy if it has none yet (@ctx current): its micropolygons
 * are read back from GPU memory once. False with the reason in @err: out
 * of memory, a GPU error, or more than 2^30 triangles.
 */
bool gpu_shadow_bvh_build(struct gpu_shadow_geometry *g, char *err, size_t errlen);

/** Nodes and triangles of @g's hierarchy, and the GPU bytes they take (0s before a build). */
void gpu_shadow_bvh_stats(const struct gpu_shadow_geometry *g, uint32_t *nodes, uint32_t *tris,
			  size_t *bytes);

/**
 * The three bindings rl_bvh_transmission reads, at texture units @unit
 * (nodes), @unit + 1 (triangles) and @unit + 2 (cast flags), with the cast
 * flags set from @casts as gpu_shadow_geometry_render takes them. False
 * before a build or on a GPU error.
 */
bool gpu_shadow_bvh_bind(struct gpu_shadow_geometry *g, uint32_t unit, const float *casts,
			 uint32_t ncasts, struct gpu_binding out[3]);

/**
 * The light that gets through @g along @n rays (for tests and benchmarks):
 * ray i from org[3i..] along dir[3i..] for t in (0, tmax[i]) in units of
 * dir, into out[i]. Builds the hierarchy first if needed. False on a GPU
 * error or bad arguments.
 */
bool gpu_shadow_bvh_trace(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g, const float *org,
			  const float *dir, const float *tmax, uint32_t n, const float *casts,
			  uint32_t ncasts, float *out);

#endif

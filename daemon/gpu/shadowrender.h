/*
 * Shadow maps rendered on the GPU from the bake's shadow geometry
 * (lightspeed-2007 §6.1): the micropolygons of every shadow caster, in world
 * space with their object ids, rasterized into a depth map seen by a light's
 * camera, leaving out the objects that do not cast. The runtime uses it when
 * casting is edited per object.
 */
#ifndef GPU_SHADOWRENDER_H
#define GPU_SHADOWRENDER_H

#include "gpu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct gpu_shadow_geometry;

/**
 * Upload shadow geometry (bake/shadowgeo.h's layout: the shot's
 * "shadow.points" and "shadow.quads" tables): @P, 3 floats per point (world
 * space); @quads, 4 point indices per micropolygon; @object, its object id
 * (any 32-bit value); @opacity, its opacity for deep maps (clamped to
 * [0, 1], 1 where not finite), or NULL when the shot has none (deep maps
 * cannot be rendered then). Micropolygons with an index out of range or a
 * non-finite corner are dropped. The arrays are copied (the caller keeps
 * them); nothing at all (0 micropolygons) is valid and renders empty maps.
 * NULL with the reason in @err (may be NULL): no context, a NULL array
 * with a non-zero count, out of memory.
 */
struct gpu_shadow_geometry *gpu_shadow_geometry_create(struct gpu_ctx *ctx, const float *P,
						       uint64_t npoints, const uint32_t *quads,
						       const uint32_t *object, const float *opacity,
						       uint64_t nquads, char *err, size_t errlen);

/** Free @g's GPU buffers (@ctx current); NULL is fine. */
void gpu_shadow_geometry_destroy(struct gpu_shadow_geometry *g);

/**
 * GPU memory @g holds: 12 bytes per point, 20 per kept micropolygon (24
 * with opacity), 4 per
 * distinct object id, and, once a midpoint map was rendered, 8 per pixel of
 * the largest such map (scratch kept for the next render). 0 for NULL.
 */
size_t gpu_shadow_geometry_bytes(const struct gpu_shadow_geometry *g);

/** How a pixel's depth comes from the surfaces at its centre (the hider's depthfilter). */
enum gpu_depth_filter {
	GPU_DEPTH_MIN,       /* the nearest */
	GPU_DEPTH_MIDPOINT,  /* halfway between the two nearest (1e30 with fewer than two) */
};

/**
 * Render the depth map of @g seen by a camera: @world_to_camera and
 * @world_to_ndc as a shadow map file holds them (row vectors; RenderMan NDC,
 * (0, 0) the top left corner, after the homogeneous divide), @width x
 * @height pixels sampled at their centres. A pixel's depth is the camera-space
 * z of the surfaces covering its centre, combined by @filter; 1e30 where
 * nothing is (an empty pixel casts no shadow). Objects whose @casts entry is
 * 0 are left out (@casts NULL: every object casts; objects at or past
 * @ncasts cast). @depth: an SSBO of at least @width * @height floats,
 * written row-major from the top row. False on a GPU error or bad
 * arguments (a matrix not finite, an empty or too small map, @depth
 * smaller than the map, @g of another context).
 *
 * Coverage follows the renderer's hider: each micropolygon is cut into
 * (v0, v1, v2) and (v0, v2, v3), and a centre on an edge belongs to the
 * side it would fall in if moved right, then down, so one surface counts
 * once at every centre. Depth is interpolated with perspective-correct
 * weights (the exact intersection with the triangle's plane). Left out:
 * micropolygons with a corner at or behind the eye (h.w <= 0) or projecting
 * to a non-finite point, hits at z <= 0 or at or past 1e30, and any
 * micropolygon whose bounding box holds more than 65536 pixel centres of
 * the map (the cap on one micropolygon's work; such a micropolygon is far
 * coarser than a shadow map is diced for).
 */
bool gpu_shadow_geometry_render(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g,
				const float world_to_camera[16], const float world_to_ndc[16],
				uint32_t width, uint32_t height, enum gpu_depth_filter filter,
				const float *casts, uint32_t ncasts, struct gpu_buffer *depth);

/* Deep maps: bounds of one render (see gpu_shadow_geometry_render_deep). */
#define GPU_DEEP_MAX_SAMPLES 64          /* samples per texel */
#define GPU_DEEP_MAX_TEXEL_HITS 4096     /* hits in one texel (its sort is quadratic) */
#define GPU_DEEP_MAX_HITS (1u << 24)     /* hits in one map, by default */
#define GPU_DEEP_MAX_NODES (1u << 24)    /* nodes: the map's offsets are floats */

/*
 * What the runtime renders deep maps with: the shot does not record its
 * shadow pass's PixelSamples or opacity threshold, so 4 x 4 samples per
 * texel (prman's and the examples' deep passes) and RISpec's default.
 */
#define GPU_DEEP_SAMPLES 4
#define GPU_DEEP_THRESHOLD 0.996f

struct gpu_deep_opts {
	uint32_t samples;    /* per texel, on each axis: samples x samples (at most 8 x 8) */
	float error;         /* the compression's bound in transmittance (REYES_DEEP_DEFAULT_ERROR) */
	float threshold;     /* a sample this opaque sees nothing behind (the hider's, 0.996) */
	uint64_t max_hits;   /* 0: GPU_DEEP_MAX_HITS */
};

struct gpu_deep_stats {
	uint64_t hits;         /* (depth, opacity) events in all */
	uint32_t max_hits;     /* the most in one texel */
	uint64_t nodes;        /* of the compressed map */
	size_t bytes;          /* the map's buffer */
	size_t scratch_bytes;  /* GPU memory the passes held while they ran (freed) */
};

/** Does @g hold each micropolygon's opacity (what deep maps need)? */
bool gpu_shadow_geometry_has_opacity(const struct gpu_shadow_geometry *g);

/**
 * Render a deep shadow map (render/deepshadow.h) of @g from a camera, as
 * gpu_shadow_geometry_render does a depth map (same matrices, coverage and
 * depth, same objects left out), at @o->samples x @o->samples points per
 * texel (the centres of a grid of cells, where the hider jitters inside
 * them; the 65536-centre cap on a micropolygon counts these sample points,
 * 4096 texels at 4 x 4). Each texel's function is the renderer's: the mean
 * over its samples of the product of (1 - opacity) of the micropolygons in
 * front of a depth, a sample stopping at the point where it became
 * @o->threshold opaque, compressed with the same runs and bound
 * (reyes_deep_build_pixel). The
 * result is a new buffer of @ctx in the layout the runtime uploads deep maps
 * in (gpu/shadowmap.c: width * height + 1 offsets as floats, then the (z, T)
 * nodes), which the caller owns. Passes: count each texel's hits, prefix
 * sums on the host, write the hits, sort each texel's list and compress it,
 * prefix sums of the node counts, pack. NULL with the reason in @err (may be
 * NULL): no opacity in @g, bad arguments, a texel of more than
 * GPU_DEEP_MAX_TEXEL_HITS hits, more hits than @o->max_hits or nodes than
 * GPU_DEEP_MAX_NODES, out of GPU memory. @st (may be NULL) says what it
 * took, on failure too as far as it got.
 */
struct gpu_buffer *gpu_shadow_geometry_render_deep(struct gpu_ctx *ctx,
						   struct gpu_shadow_geometry *g,
						   const float world_to_camera[16],
						   const float world_to_ndc[16], uint32_t width,
						   uint32_t height, const struct gpu_deep_opts *o,
						   const float *casts, uint32_t ncasts,
						   struct gpu_deep_stats *st, char *err, size_t errlen);

#endif

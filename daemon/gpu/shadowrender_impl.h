/*
 * What shadowrender.c and shadowbvh.c share of a shadow geometry: its
 * buffers and their encoding. Private to daemon/gpu.
 */
#ifndef GPU_SHADOWRENDER_IMPL_H
#define GPU_SHADOWRENDER_IMPL_H

#include "shadowrender.h"

/* Indices and slots as float bits: value + IDX_BIAS, at most IDX_MAX + IDX_BIAS. */
#define IDX_BIAS 0x00800000u
#define IDX_MAX (0x7effffffu - IDX_BIAS)

struct gpu_shadow_geometry {
	struct gpu_ctx *ctx;
	uint64_t npoints;
	uint32_t nquads;             /* kept micropolygons */
	uint32_t nslots;             /* distinct object ids */
	uint32_t *slot_id;           /* the object id of each slot, ascending */
	float *flags;                /* the cast flags last uploaded, per slot */
	struct gpu_buffer *points;   /* R32F: x, y, z per point */
	struct gpu_buffer *quads;    /* RGBA32F: 4 biased point indices per micropolygon */
	struct gpu_buffer *slots;    /* R32F: biased slot per micropolygon */
	struct gpu_buffer *casts;    /* R32F: flag per slot */
	struct gpu_buffer *opacity;  /* R32F: opacity per micropolygon, or NULL */
	struct gpu_buffer *scratch;  /* midpoint: 2 uint per pixel (second depth, count) */
	size_t scratch_bytes;
	size_t bytes;                /* GPU memory held, scratch included */
	struct gpu_program *clear, *raster, *resolve;
	struct gpu_program *deep_clear, *deep_raster, *deep_build, *deep_pack;
	struct gpu_buffer *bvh_nodes;  /* RGBA32F: the ray-tracing hierarchy (shadowbvh.c), or NULL */
	struct gpu_buffer *bvh_tris;   /* RGBA32F: its triangles */
	uint32_t bvh_nnodes, bvh_ntris;
	struct gpu_program *bvh_trace;  /* gpu_shadow_bvh_trace's kernel */
};

/* A buffer of @bytes for @g (at least 16, so that an empty table can still be bound). */
struct gpu_buffer *gpu_shadow_upload(struct gpu_shadow_geometry *g, size_t bytes, const void *data);

/* Set the per-slot cast flags from @casts (as gpu_shadow_geometry_render takes them). */
bool gpu_shadow_set_casts(struct gpu_shadow_geometry *g, const float *casts, uint32_t ncasts);

#endif

/*
 * Shadow maps from shadow geometry on the GPU: see shadowrender.h.
 */
#include "shadowrender.h"

#include <stdio.h>

struct gpu_shadow_geometry *gpu_shadow_geometry_create(struct gpu_ctx *ctx, const float *P,
						       uint64_t npoints, const uint32_t *quads,
						       const uint32_t *object, uint64_t nquads,
						       char *err, size_t errlen)
{
	(void)ctx;
	(void)P;
	(void)npoints;
	(void)quads;
	(void)object;
	(void)nquads;
	snprintf(err, errlen, "shadow geometry on the GPU is not available");
	return NULL;
}

void gpu_shadow_geometry_destroy(struct gpu_shadow_geometry *g)
{
	(void)g;
}

size_t gpu_shadow_geometry_bytes(const struct gpu_shadow_geometry *g)
{
	(void)g;
	return 0;
}

bool gpu_shadow_geometry_render(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g,
				const float world_to_camera[16], const float world_to_ndc[16],
				uint32_t width, uint32_t height, enum gpu_depth_filter filter,
				const float *casts, uint32_t ncasts, struct gpu_buffer *depth)
{
	(void)ctx;
	(void)g;
	(void)world_to_camera;
	(void)world_to_ndc;
	(void)width;
	(void)height;
	(void)filter;
	(void)casts;
	(void)ncasts;
	(void)depth;
	return false;
}

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
 * space); @quads, 4 point indices per micropolygon; @object, its object id.
 * Micropolygons with an index out of range or a non-finite corner are
 * dropped. NULL with the reason in @err.
 */
struct gpu_shadow_geometry *gpu_shadow_geometry_create(struct gpu_ctx *ctx, const float *P,
						       uint64_t npoints, const uint32_t *quads,
						       const uint32_t *object, uint64_t nquads,
						       char *err, size_t errlen);
void gpu_shadow_geometry_destroy(struct gpu_shadow_geometry *g);
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
 * @ncasts cast). @depth: an SSBO of @width * @height floats, written
 * row-major from the top row. False on a GPU error or bad arguments.
 */
bool gpu_shadow_geometry_render(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g,
				const float world_to_camera[16], const float world_to_ndc[16],
				uint32_t width, uint32_t height, enum gpu_depth_filter filter,
				const float *casts, uint32_t ncasts, struct gpu_buffer *depth);

#endif

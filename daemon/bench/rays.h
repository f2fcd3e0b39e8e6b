/*
 * Rays per second: the same shadow rays through the same triangles, traced
 * by Embree on every core (the renderer's ray tracer) and by the GPU's
 * shadow kernel (gpu/shadowbvh.h, llvmpipe where there is no GPU), and how
 * many rays the two disagree on (the error that goes with the speed).
 */
#ifndef BENCH_RAYS_H
#define BENCH_RAYS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct gpu_ctx;

struct bench_rays {
	uint32_t triangles, rays, threads;
	double embree_build_s, embree_s, embree_rays_per_s;
	double gpu_build_s, gpu_s, gpu_rays_per_s;  /* 0 without a GPU context */
	size_t gpu_bytes;                            /* the hierarchy in GPU memory */
	uint64_t occluded;                           /* rays Embree finds blocked */
	uint64_t disagree;                           /* rays the GPU answers otherwise */
};

/**
 * A field of 10 x 10 spheres (@quick: 5 x 5) of 64 x 32 micropolygons
 * each over a floor, and one shadow ray from each of @side x @side floor
 * points to a light. @ctx NULL: Embree only. False with the reason in @err.
 */
bool bench_rays(struct gpu_ctx *ctx, bool quick, uint32_t side, uint32_t threads,
		struct bench_rays *out, char *err, size_t errlen);

#endif

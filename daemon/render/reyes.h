/*
 * The REYES renderer: a scene (scene.h) to images. Primitives are bounded,
 * culled, split until small enough on screen and diced into grids at the
 * shading rate; grids are displaced and shaded on the grid interpreter with
 * the scene's lights; the hider samples them bucket by bucket, and the
 * filtered pixels go to the scene's displays. Buckets run on several threads.
 */
#ifndef REYES_H
#define REYES_H

#include "scene.h"

#include <stdio.h>

struct reyes_render_opts {
	uint32_t threads;          /* 0: all cores */
	uint32_t bucket_size;      /* pixels, 0: 16 */
	uint32_t max_grid;         /* points per grid, 0: 256 (16x16 at shading rate 1) */
	bool progress;             /* a progress bar on stderr */
	FILE *diag;                /* NULL: stderr */
	const char *texture_path;  /* for the texture system, NULL: the scene's option */
	/* Crop in pixels, overriding the scene's CropWindow when x1 > x0 (relight render --crop). */
	uint32_t crop_x0, crop_x1, crop_y0, crop_y1;
};

/** What a render did, for the summary line and the benchmark. */
struct reyes_stats {
	double seconds;
	uint64_t grids;            /* grids shaded */
	uint64_t micropolygons;    /* points shaded */
	uint64_t samples;          /* subpixel samples taken */
	uint64_t peak_bytes;       /* peak resident memory of the process */
	uint32_t width, height;
};

/**
 * Render @scene's frame and write its displays. False on failure (reported
 * on opts->diag). @stats may be NULL.
 */
bool reyes_render(const struct reyes_scene *scene, const struct reyes_render_opts *opts,
		  struct reyes_stats *stats);

#endif

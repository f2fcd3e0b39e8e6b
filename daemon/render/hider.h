/*
 * The hider: stochastic point sampling of shaded micropolygons, one bucket
 * at a time. Each pixel has xsamples x ysamples subpixel samples, jittered
 * within their strata, each with its own time in the shutter interval (for
 * motion blur). A sample keeps the micropolygons it hits sorted by depth and
 * composites them front to back (premultiplied colour, opacity) until it is
 * opaque; pixels are the filter-weighted sum of the samples within the
 * filter's width. Sample positions and times depend only on the sample's
 * place in the image and the seed, so neighbouring buckets (which each
 * sample the filter margin around their pixels) agree exactly.
 */
#ifndef REYES_HIDER_H
#define REYES_HIDER_H

#include "scene.h"

struct reyes_hider_opts {
	uint32_t xres, yres;              /* image size in pixels */
	uint32_t xsamples, ysamples;      /* per pixel, >= 1 */
	enum reyes_filter filter;
	float filter_width[2];            /* total width in pixels (RenderMan's convention) */
	bool jitter;                      /* else samples at stratum centres, times at midpoints */
	uint32_t seed;
	float opacity_threshold;          /* compositing stops at this opacity (all channels) */
	enum reyes_depthfilter depthfilter;
	uint32_t naov;                    /* extra channels carried per vertex and per pixel */
};

/**
 * A shaded grid in raster space, ready to be sampled: nu x nv vertices
 * (vertex (i, j) at j * nu + i), planar arrays. Micropolygons are the quads
 * between neighbouring vertices. Positions move linearly from [0] (shutter
 * open) to [1] (shutter close); [1] may equal [0]. z is camera-space depth
 * (positive in front of the camera).
 */
struct reyes_hider_grid {
	uint32_t nu, nv;
	const float *x[2], *y[2], *z[2];
	const float *Ci;                  /* 3 planes: colour, premultiplied by opacity */
	const float *Oi;                  /* 3 planes */
	const float *const *aov;          /* naov planes, or NULL when naov is 0 */
	bool smooth;                      /* interpolate Ci/Oi/aov bilinearly inside a micropolygon;
					     else each micropolygon takes its (i, j) vertex's values */
	bool cull_backfacing;             /* Sides 1: drop micropolygons facing away */
	bool flip;                        /* reverse the facing test (Orientation) */
	bool matte;                       /* hides what is behind but adds no colour (alpha 0) */
};

struct reyes_hider;

/** NULL if an option is out of range (reported on stderr). */
struct reyes_hider *reyes_hider_create(const struct reyes_hider_opts *opts);
void reyes_hider_destroy(struct reyes_hider *h);

/**
 * Start a bucket: pixels [px0, px1) x [py0, py1). Grids whose raster bound
 * does not touch the rectangle reyes_hider_region() returns can be skipped.
 */
void reyes_hider_begin(struct reyes_hider *h, uint32_t px0, uint32_t py0, uint32_t px1,
		       uint32_t py1);

/** The raster rectangle the current bucket samples (its pixels plus the filter margin). */
void reyes_hider_region(const struct reyes_hider *h, float *x0, float *y0, float *x1,
			float *y1);

/** Sample a grid into the current bucket (the grid's data is not kept after the call). */
void reyes_hider_add(struct reyes_hider *h, const struct reyes_hider_grid *g);

/**
 * Finish the bucket: filter the samples into its pixels. @rgba receives 4
 * floats per pixel, @z 1 (depth of the nearest opaque hit, combined over the
 * pixel's samples by depthfilter; 1e30 where nothing was hit), @aov naov
 * floats per pixel; each image is row-major over the bucket (width px1 - px0).
 * Any of them may be NULL. Returns the number of subpixel samples taken.
 */
uint64_t reyes_hider_end(struct reyes_hider *h, float *rgba, float *z, float *aov);

/** The filter's weight at offset (dx, dy) pixels from a pixel's centre. */
float reyes_filter_eval(enum reyes_filter f, float dx, float dy, float xwidth, float ywidth);

/** Parse a PixelFilter name ("box", "catmull-rom", ...); false if unknown. */
bool reyes_filter_from_name(const char *name, enum reyes_filter *f);

#endif

/*
 * The hider: stochastic point sampling of shaded micropolygons, one bucket
 * at a time. Each pixel has xsamples x ysamples subpixel samples, jittered
 * within their strata, each with its own time in the shutter interval (for
 * motion blur). A sample keeps the micropolygons it hits sorted by depth and
 * composites them front to back (premultiplied colour, opacity) until it is
 * opaque; pixels are the filter-weighted sum of the samples within the
 * filter's width. With depth of field each sample also has a lens position,
 * stratified over the pixel's samples like time. Sample positions, times and
 * lens positions depend only on the sample's place in the image and the
 * seed, so neighbouring buckets (which each sample the filter margin around
 * their pixels) agree exactly.
 */
#ifndef REYES_HIDER_H
#define REYES_HIDER_H

#include "scene.h"

struct reyes_trim;

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
	/* Depth of field (a thin lens): a sample at lens position (lu, lv) of the
	 * unit disk sees a vertex at camera depth z moved by
	 * (lu lens[0], lv lens[1]) (focus - 1/z) pixels, where lens[] is the
	 * aperture radius in raster pixels at unit distance and focus is
	 * 1 / focaldistance. lens[0] == 0 is a pinhole (no lens samples). */
	float lens[2];
	float focus;
	/* Bake mode (lightspeed-2007 §3.4): record, per pixel, the linear weight of
	 * every shaded grid vertex that reaches it (reyes_hider_end_record). Grids
	 * then need no Ci (it may be NULL) and no AOVs; Oi is used as usual. */
	bool record;
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
	/* DetailRange's cross-fade: only samples whose dissolve number (uniform
	   in [0, 1), a hash of the sample's place) is in [lod_lo, lod_hi) see
	   the grid; when false every sample does. */
	bool dissolve;
	float lod_lo, lod_hi;
	/* Solid modeling: 1 + the grid's leaf (its "primitive" solid) in *csg,
	   or 0 when it is in no solid. Micropolygons of a solid are never
	   culled; a sample keeps one of their hits only where the ray crosses
	   the composite solid's boundary (front-facing: the ray enters the
	   leaf; see hider.c). */
	const struct reyes_csg *csg;
	uint32_t csg_leaf;
	/* A trimmed NuPatch (TrimCurve): each vertex's surface (u, v), 2 planes,
	   and the trim region; a sample whose (u, v), interpolated in the
	   micropolygon's triangle, is cut away misses. NULL for everything else. */
	const float *trim_uv;
	const struct reyes_trim *trim;
	uint32_t id0;                     /* record mode: vertex k is shading sample id0 + k;
					     micropolygons using an id past 2^32 - 1 are
					     dropped (reported once) */
};

/** One entry of a pixel's recipe: shading sample @id contributes @weight times its Ci. */
struct reyes_vis_entry {
	uint32_t id;
	float weight;
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
 * A record-mode hider has no colours: it reports an error (once), gives
 * empty pixels (0, depth 1e30) and returns 0.
 */
uint64_t reyes_hider_end(struct reyes_hider *h, float *rgba, float *z, float *aov);

/**
 * Finish the bucket in record mode: each of its pixels as the list of
 * shading samples it is made of, so that for any colours Ci given to the
 * vertices, sum(weight * Ci[id]) over a pixel's entries is the colour
 * reyes_hider_end would give. A weight is filter weight x subpixel
 * coverage x the transmittance in front of the hit x the vertex's
 * interpolation weight, over the pixel's filter-normalised samples. Entries
 * of one id are merged (one entry per id per pixel); matte hits give no
 * entry but still hide what is behind. Transmittance is the mean of the
 * three channels' transmittance, as AOVs composite: exact for grey opacity;
 * for coloured opacity the sum is what an AOV carrying Ci would give.
 * Weights are finite and nonzero; negative filter lobes (Catmull-Rom,
 * sinc) make negative ones. Pixel p of the bucket (row-major, width
 * px1 - px0) has entries [offsets[p], offsets[p + 1]), sorted by id;
 * @offsets and @entries are the hider's and stay valid until the next
 * reyes_hider_begin. @alpha (1 float per pixel) and @z (may be NULL) are
 * bit-identical to reyes_hider_end's alpha and depth. Returns the number of
 * subpixel samples taken. With no bucket begun, after the bucket was
 * finished, or on a hider not in record mode (an error, reported once), it
 * returns 0 and every pixel's list is empty (the latter also sets alpha 0
 * and depth 1e30); *offsets and *entries are always set (when not NULL).
 */
uint64_t reyes_hider_end_record(struct reyes_hider *h, const uint32_t **offsets,
				const struct reyes_vis_entry **entries, float *alpha, float *z);

/**
 * Deep shadows: the hits of subpixel sample @k (row-major among the
 * pixel's xsamples x ysamples) of pixel (x, y) of the current bucket, front
 * to back, as depth and opacity (the mean of the three channels; matte hits
 * too, as they hide what is behind). The first @cap go to @z and @o; returns
 * how many the sample has (call again with more room when that is over
 * @cap). Hits behind the depth where the sample became opaque are not kept.
 * 0 outside the bucket's pixels. Call before reyes_hider_end.
 */
uint32_t reyes_hider_sample_hits(const struct reyes_hider *h, uint32_t x, uint32_t y, uint32_t k,
				 float *z, float *o, uint32_t cap);

/**
 * Bytes a bucket of @h takes per subpixel sample, sampled once by one
 * opaque grid: the sample, its filter weights and colour (or, recording,
 * its alpha and list of contributions) and one hit. More hits per sample
 * (transparency, overlapping grids) take more; the renderer's memory
 * estimate starts from this.
 */
size_t reyes_hider_sample_bytes(const struct reyes_hider *h);

/** The filter's weight at offset (dx, dy) pixels from a pixel's centre. */
float reyes_filter_eval(enum reyes_filter f, float dx, float dy, float xwidth, float ywidth);

/** Parse a PixelFilter name ("box", "catmull-rom", ...); false if unknown. */
bool reyes_filter_from_name(const char *name, enum reyes_filter *f);

#endif

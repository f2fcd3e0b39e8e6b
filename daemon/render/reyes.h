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
#include "hider.h"

#include <stdio.h>

struct sl_exec;

/**
 * Bake mode (lightspeed-2007 §3.4): the renderer runs, instead of each
 * surface shader, the program the bake gives for it (its caching program),
 * hands every shaded grid to @grid, which keeps the values it wants and
 * numbers the grid's vertices, and records, instead of colours, which
 * shading samples make up each pixel (@bucket). Callbacks run on the
 * renderer's threads, several at once.
 */
struct reyes_bake_hooks {
	void *user;
	/** The program to run for surface @surf (NULL: the bake fails). */
	const struct sl_program *(*program)(void *user, const struct reyes_shader *surf);
	/**
	 * A grid of @n points was shaded with @x (which ran program(surf); its
	 * registers hold the results, planar with sl_exec_stride). @prim is the
	 * primitive it came from. Return the id of its first vertex (vertex k is
	 * id0 + k), or UINT32_MAX to fail the bake.
	 */
	uint32_t (*grid)(void *user, const struct reyes_shader *surf, const struct reyes_prim *prim,
			 struct sl_exec *x, uint32_t n);
	/**
	 * The bucket of pixels [x0, x1) x [y0, y1) is done: its pixels' entries
	 * and alpha as reyes_hider_end_record gives them (row-major over the
	 * bucket). False fails the bake.
	 */
	bool (*bucket)(void *user, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1,
		       const uint32_t *offsets, const struct reyes_vis_entry *entries,
		       const float *alpha);
};

struct reyes_render_opts {
	uint32_t threads;          /* 0: all cores */
	uint32_t bucket_size;      /* pixels, 0: 16 */
	uint32_t max_grid;         /* points per grid, 0: 1024 (32x32 at shading rate 1) */
	bool progress;             /* a progress bar on stderr */
	FILE *diag;                /* NULL: stderr */
	const char *texture_path;  /* for the texture system, NULL: the scene's option */
	/* Crop in pixels, overriding the scene's CropWindow when x1 > x0 (relight render --crop). */
	uint32_t crop_x0, crop_x1, crop_y0, crop_y1;
	/* Bake instead of rendering (no display is written). NULL: render. */
	const struct reyes_bake_hooks *bake;
	/* Called on the calling thread after each row of buckets with the
	 * fraction of rows done, whether or not there is a progress bar (NULL:
	 * not called). */
	void (*progress_fn)(void *user, double fraction);
	void *progress_user;
	/* Where the default surface (defaultsurface.sl) is compiled once for every
	 * frame of a run (NULL: compiled by each render). */
	struct reyes_shader_cache *shader_cache;
	/* Bytes the frame may take (render/memlimit.h); 0: reyes_mem_default_limit(). A
	 * frame estimated over it fails before it is diced, naming what to change. */
	uint64_t memory_limit;
};

/** What a render did, for the summary line and the benchmark. */
struct reyes_stats {
	double seconds;
	uint64_t grids;            /* grids shaded */
	uint64_t micropolygons;    /* points shaded */
	uint64_t samples;          /* subpixel samples taken */
	uint64_t rays;             /* rays cast (Embree intersections) */
	uint64_t ray_bytes;        /* the scene rays saw: grids kept for shading hits, Embree's */
	uint64_t peak_bytes;       /* peak resident memory of the process */
	uint32_t width, height;
};

/**
 * The warnings renders of this process printed about what they left out
 * (pieces dropped at the eye plane), for a run's summary and --strict.
 */
uint64_t reyes_render_warnings(void);

/** Count one more of those warnings (a bake's, printed by the caller). */
void reyes_render_warned(void);

/**
 * Render @scene's frame and write its displays. False on failure (reported
 * on opts->diag). @stats may be NULL.
 */
bool reyes_render(const struct reyes_scene *scene, const struct reyes_render_opts *opts,
		  struct reyes_stats *stats);

/** What reyes_dice does and where its grids go. */
struct reyes_dice_opts {
	/*
	 * Largest micropolygon area, in pixels of the scene's camera, as
	 * ShadingRate; 0: each primitive's own ShadingRate.
	 */
	float rate;
	/*
	 * Leave out, as reyes_render does, what the camera cannot see. When
	 * false everything is diced: geometry in the view at @rate pixels,
	 * geometry behind the eye or off the screen as finely as if the camera
	 * turned to face it (by the size a pixel has at its distance from the
	 * eye, no nearer than the near clipping plane).
	 */
	bool cull_to_view;
	bool casters_only;         /* leave out primitives that cast no shadows */
	/* Dice every piece by the size of a pixel at its distance, as if the
	 * camera faced it (with cull_to_view false): what the renderer's rays see. */
	bool orient_free;
	uint32_t max_grid;         /* points per grid, 0: 1024 */
	FILE *diag;                /* NULL: stderr */
	const char *texture_path;  /* for displacement shaders, NULL: the scene's option */
	void *user;
	/**
	 * A grid of @prim, @nu x @nv points (point (i, j) is k = j * nu + i),
	 * displaced, in camera space at shutter open, planar: x, y, z of point
	 * k at P[k], P[n + k], P[2n + k] with n = nu * nv. @P is the dicer's,
	 * valid during the call. @keep: NULL, or for a trimmed NuPatch one
	 * byte per micropolygon (i, j) at j * (nu - 1) + i, 0 where the trim
	 * curve cuts its centre away. @Os: the grid's "Os" primitive variable
	 * per point, planar like @P, or NULL when the primitive has none (its
	 * Opacity attribute holds). Return false to stop (dicing then fails).
	 */
	bool (*grid)(void *user, const struct reyes_prim *prim, const float *P, uint32_t nu,
		     uint32_t nv, const uint8_t *keep, const float *Os);
};

/**
 * The geometric half of the pipeline: bound, split and dice every primitive
 * of @scene, in declaration order, run displacement shaders, and hand each
 * grid to opts->grid. No surface is shaded and nothing is hidden. One
 * thread. False on failure (reported on opts->diag, or when opts->grid
 * said stop).
 */
bool reyes_dice(const struct reyes_scene *scene, const struct reyes_dice_opts *opts);

/**
 * Is @scene's frame a shadow pass (every display a depth map)? Objects that
 * cast no shadows stay out of it, and the bake renders it as it is.
 */
bool reyes_scene_is_shadow_pass(const struct reyes_scene *scene);

/** A display of depth (zfile, shadow, deepshad, or mode "z"): no colour, no AOVs. */
bool reyes_display_is_depth(const struct reyes_display *d);

#endif

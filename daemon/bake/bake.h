/*
 * The bake (lightspeed-2007 §3.4, §4): run the reference renderer with each
 * surface's caching program in place of the shader, keep every shading
 * sample's cached values, record which samples make up each pixel, and
 * write it all to a shot file (shotfile.h).
 *
 * What a shot file holds (SHOT_FORMAT_VERSION 1):
 *  - one table per surface shader, "samples.NAME": a row per kept shading
 *    sample, a channel per component of each cached value ("cKKK.CC": value
 *    KKK of the shader's cached list, component CC, both zero-padded),
 *    plus "object" (the primitive's id) and "lightset" (the index of the
 *    set of lights that reach it). Rows of all tables are numbered one after
 *    the other in table order: that number is a sample's id.
 *  - "pixels": a table of width x height rows, channel "A" (alpha).
 *  - "ifb", the indirect framebuffer: a deep part with, per pixel, entries
 *    "sample" (uint id) and "weight" (float), heaviest first; the pixel's
 *    colour is sum(weight * Ci[sample]).
 *  - metadata (JSON): image, lights (shader, parameters, transforms), light
 *    sets, shader groups (cached channels, dynamic parameters, source hash),
 *    figures.
 */
#ifndef BAKE_H
#define BAKE_H

#include "scene.h"
#include "reyes.h"
#include "shotfile.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/**
 * Progress of a bake: @fraction of the work done, in [0, 1] and never
 * decreasing; @what a short phrase ("rendering", "writing"). Called on the
 * thread that called the bake.
 */
typedef void (*bake_progress_fn)(void *user, double fraction, const char *what);

struct bake_opts {
	/* Surface parameters a user may edit (made dynamic in every surface
	 * shader that has them). */
	const char *const *dynamic_surface;
	size_t ndynamic;
	uint32_t threads;          /* 0: all cores */
	bool progress;             /* a progress bar on stderr */
	FILE *diag;                /* NULL: stderr */
	struct shot_write_options write;
	/* Screen tiles: each tile's samples, entries and levels take at most
	 * this many bytes (0: BAKE_DEFAULT_TILE_BUDGET); the frame is one tile
	 * when it fits. */
	uint64_t tile_budget;
	/* Shadow geometry's dicing rate, in pixels of area as ShadingRate (0:
	 * BAKE_DEFAULT_SHADOW_RATE). */
	float shadow_rate;
	bool full_float;           /* store no channel as half */
	/* Bytes a frame may take (reyes_render_opts.memory_limit; 0: the default). */
	uint64_t memory_limit;
	/* Where the default surface is compiled; it must outlive the bake, whose
	   shot names the programs it shaded with (NULL: the bake's own). */
	struct reyes_shader_cache *shader_cache;
	bake_progress_fn progress_fn;  /* NULL: none (independent of @progress) */
	void *progress_user;
	/* bake_rib_file's shader search path, colon-separated (NULL:
	 * $RELIGHT_SHADER_PATH, then $RMAN_SHADERPATH, then the standard library). */
	const char *shader_path;
	/* bake_rib_file's folders for shaders' #include, colon-separated (NULL: none). */
	const char *include_path;
	/* bake_rib_file: every warning of the scene is an error (relight bake --strict). */
	bool strict;
};

#define BAKE_DEFAULT_TILE_BUDGET (512ull << 20)
#define BAKE_DEFAULT_SHADOW_RATE 4.0f
/** Refinement levels (lightspeed §5.2): 4x4 blocks, 2x2 blocks, one entry a pixel, all. */
#define BAKE_LEVELS 4

struct bake_stats {
	double render_seconds, write_seconds;
	uint64_t shaded_points;    /* grid points the renderer shaded */
	uint64_t shading_samples;  /* kept: reached some pixel */
	uint64_t sample_rows;      /* rows stored: a sample several tiles use has one in each */
	uint64_t subpixel_samples; /* pixels x pixel samples */
	uint64_t raw_entries;      /* (pixel, sample) contributions before merging */
	uint64_t indirect_entries; /* entries kept */
	/* cached scalars per sample, summed over surface shaders; those that
	 * vary over the frame; those among them no other channel equals */
	uint32_t channels_dynamic, channels_varying, channels_unique;
	/* channels stored: as half, as float (the rest are constants or aliases) */
	uint32_t channels_half, channels_float;
	uint32_t width, height;
	uint32_t tiles, tile_size;           /* tile_size: 0 when the frame is one tile */
	/* per refinement level: shading samples shaded (all tiles) and entries resolved */
	uint64_t level_samples[BAKE_LEVELS], level_entries[BAKE_LEVELS];
	uint64_t shadow_points, shadow_quads; /* shadow geometry (0: no light casts shadows) */
};

/**
 * Bake @scene's frame to the shot file @path (written atomically). False on
 * failure, reported on opts->diag. @stats may be NULL.
 */
bool bake_scene(const struct reyes_scene *scene, const char *path, const struct bake_opts *opts,
		struct bake_stats *stats);

/**
 * Bake the RIB file @rib as `relight bake` does: read it, render its shadow
 * passes (frames whose every display is a depth map) as they are, so that
 * the maps later frames read exist, and bake the first other frame to the
 * shot file @out (later frames are left out with a warning). Errors, with
 * the RIB's file and line, go to opts->diag; so do a line per frame and the
 * summary when @verbose. Relative file names in the scene (displays,
 * textures) are relative to the working directory. Progress runs from 0 to
 * 1 over the whole file. False on failure, or when the file has no frame to
 * bake. @stats (the baked frame's) may be NULL.
 */
bool bake_rib_file(const char *rib, const char *out, const struct bake_opts *opts, bool verbose,
		   struct bake_stats *stats);

#endif

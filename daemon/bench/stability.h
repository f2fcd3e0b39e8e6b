/*
 * The numerical stability suite (relight bench --stability): hard cases for
 * the renderer, the bake and the GPU runtime, each measured against a
 * closed-form answer or the reference renderer, with a stated tolerance,
 * pass or fail.
 *
 *   drift        100,000 random edits of one light (intensities 1e-4 to
 *                1e4, colour, position) folded into the light cache, then
 *                the light restored: the image against the original, max
 *                relative difference. Beside it, what a float32 cache would
 *                drift over the same edits (reported, not judged).
 *   hdr          light intensities from 1e-4 to 1e4: the GPU's final level
 *                against the CPU resolver (relative), and every value
 *                finite; the half output of the brightest within half's range.
 *   degenerate   a light lying on a surface, a grazing distant light,
 *                roughness near 0, zero-length normals, zero-area polygons:
 *                every level finite (render, CPU resolver, GPU) and the GPU
 *                within 1e-4 relative of the CPU.
 *   transparency long chains of layers with opacity near 1 (and near 0):
 *                the rendered and previewed colour and alpha against the
 *                closed form sum_i c_i a (1 - a)^i.
 *   weights      16x16 supersampling of a constant-colour frame: every
 *                pixel's filter weights sum to 1 (colour and alpha equal
 *                the constant), in the renderer and through the indirect
 *                framebuffer on the GPU.
 *   half         a shot baked with half-float channels against the same
 *                shot baked in float (--full-float): the previews' largest
 *                relative difference against the bound the bake records,
 *                and the 8-bit error.
 *
 * Quick mode (CI) runs every case smaller (10,000 edits, shorter chains,
 * smaller images); the full suite runs from `relight bench`.
 */
#ifndef BENCH_STABILITY_H
#define BENCH_STABILITY_H

#include <stdbool.h>
#include <stdio.h>

struct gpu_ctx;

enum stab_verdict { STAB_PASS, STAB_FAIL, STAB_SKIP };

/** One check of a case (a case may make several). */
struct stab_check {
	char group[24];        /* the case: "drift", "hdr", ... */
	char name[96];         /* what was measured, e.g. "restored image, max relative diff" */
	double value;          /* the measurement */
	double limit;          /* pass when value <= limit (NAN: reported only, never fails) */
	enum stab_verdict verdict;
	char note[192];        /* why skipped or failed, or a fact worth printing */
};

struct stab_opts {
	bool quick;            /* the CI size */
	const char *workdir;   /* an existing folder for scenes, shots and images */
	struct gpu_ctx *ctx;   /* current on this thread; NULL: the GPU checks are skipped */
	FILE *log;             /* progress and diagnostics; NULL: stderr */
	const char *only;      /* NULL, or a comma-separated list of groups to run */
};

/**
 * Run the suite. Fills up to @cap checks into @out and returns how many
 * (never more than @cap), or -1 with the reason in @err when the suite
 * could not run at all (the work folder unwritable). A case that cannot
 * build its scene fails its checks with the reason in their note.
 */
int stab_run(const struct stab_opts *o, struct stab_check *out, int cap, char *err,
	     size_t errlen);

#endif

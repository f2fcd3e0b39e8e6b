/*
 * The CPU resolver (`relight preview --cpu`): shade a shot's samples with
 * each surface's dynamic program on the grid interpreter, the lights run
 * whole as in the reference renderer, and resolve the pixels through the
 * indirect framebuffer. The ground truth of the GPU runtime.
 */
#ifndef BAKE_RESOLVE_H
#define BAKE_RESOLVE_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/** A light edit: light @light's parameter @param takes @values. */
struct resolve_edit {
	const char *light;         /* the light's name (its RIB handle) */
	const char *param;
	float values[16];
	uint32_t nvalues;          /* 1 for a float; 3 for a colour, point or vector (1 broadcasts
				      to a colour); 16 for a matrix; 0: @text is the value */
	const char *text;          /* the value as written: a string parameter's */
};

struct resolve_opts {
	FILE *diag;                /* NULL: stderr */
	const char *texture_path;  /* where shadow maps and textures are found ("." when NULL) */
	bool progress;             /* a progress bar on stderr */
	/* The refinement level (lightspeed §5.2): 0, one entry per 4x4 block;
	 * 1, per 2x2 block; 2, one entry per pixel; 3 (RESOLVE_FINAL), all
	 * entries. Only the samples the level uses are shaded. */
	int level;
	/* Light edits applied over the baked parameters. An unknown light or
	 * parameter, a string or array parameter, a wrong count or a value that
	 * is not finite is refused with a clear error. */
	const struct resolve_edit *edits;
	size_t nedits;
};

#define RESOLVE_FINAL 3

struct resolve_result {
	uint32_t width, height;
	float *rgba;               /* width * height * 4, premultiplied linear; free() it */
	double load_seconds, shade_seconds, resolve_seconds;
	uint64_t samples, entries;
};

/**
 * Shade and resolve the shot file at @path. False on failure (a clear
 * message on opts->diag: unreadable shot, a shader that changed since the
 * bake, ...).
 */
bool resolve_cpu(const char *path, const struct resolve_opts *opts, struct resolve_result *out);

#endif

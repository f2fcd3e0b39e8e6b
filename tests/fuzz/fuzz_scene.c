/*
 * libFuzzer target for the scene builder and the geometry behind it: every
 * input is read as one RIB file through reyes_ri_read (requests to
 * primitives, their parameter lists, tags and codes), and each frame's
 * primitives are cut into pieces, bounded, split and diced into small
 * grids, so that the parsers of every primitive's data and the geometry
 * they feed run under the sanitizers. The read checks only (check_only:
 * MakeTexture and MakeShadow write nothing) and finds shaders in the
 * project's shaders/ folder only. Crashes, sanitizer reports, hangs and
 * leaks are failures; diagnostics are expected and discarded.
 */
#include "geom.h"
#include "ri.h"
#include "shader_cache.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Bounds on the work one input may ask for, so that a large mesh is not a hang. */
enum { MAX_PIECES = 256, DICE = 4 };

static void exercise_piece(const struct reyes_patch *pa)
{
	float lo[3], hi[3];
	reyes_patch_bound(pa, 0, lo, hi);
	reyes_patch_bound(pa, 1, lo, hi);

	struct reyes_patch half[2];
	reyes_patch_split(pa, pa->depth % 2 == 0, half);
	reyes_patch_bound(&half[1], 0, lo, hi);

	struct reyes_grid g = {0};
	if (reyes_patch_dice(&half[0], DICE, DICE, &g)) {
		/* Read what dicing wrote, so that uninitialised output shows up. */
		volatile float sink = 0;
		for (uint32_t k = 0; k < g.n; k++)
			sink += g.P[0][k] + g.P[1][g.n + k] + g.Ng[2 * g.n + k];
		(void)sink;
	}
	reyes_grid_finish(&g);
}

static bool frame(void *user, const struct reyes_scene *scene)
{
	(void)user;
	struct reyes_patch *pieces = NULL;
	size_t cap = 0;
	size_t budget = MAX_PIECES;
	for (uint32_t p = 0; p < scene->nprims && budget > 0; p++) {
		size_t n = 0;
		reyes_prim_deforms(&scene->prims[p]);
		if (!reyes_prim_pieces(&scene->prims[p], &pieces, &n, &cap))
			continue;
		for (size_t i = 0; i < n && budget > 0; i++, budget--)
			exercise_piece(&pieces[i]);
	}
	free(pieces);
	return true;
}

static char path[64];

static void remove_input(void)
{
	unlink(path);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static FILE *devnull;
	static struct reyes_shader_cache *shaders;
	if (!devnull) {
		devnull = fopen("/dev/null", "w");
		snprintf(path, sizeof(path), "/tmp/fuzz_scene.%ld.rib", (long)getpid());
		shaders = reyes_shader_cache_create();
		if (!devnull || !shaders)
			return 0;
		atexit(remove_input);
	}
	/* The builder reads files (archives resolve against the RIB's folder). */
	FILE *f = fopen(path, "wb");
	if (!f)
		return 0;
	bool written = fwrite(data, 1, size, f) == size;
	if (fclose(f) != 0 || !written)
		return 0;

	struct reyes_ri_opts opts = {
		.diag = devnull,
		.max_errors = 1000,
		.shader_cache = shaders,
		.check_only = true,
		.frame = frame,
	};
	reyes_ri_read(path, &opts, NULL);
	return 0;
}

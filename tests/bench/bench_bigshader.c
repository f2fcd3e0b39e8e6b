/*
 * A production-sized shader (tests/bench/gen_bigshader.py, over 20,000 IR
 * instructions after inlining) through each step from source to GPU: the
 * front end (preprocess, parse, check, lower, infer), the specialization,
 * the GLSL generation, the GL compile cold (Mesa's shader cache off) and
 * from relight's program cache, and one run of the kernel over 65,536
 * samples, for three dynamic sets: the lights only, four material parameters
 * (roughness, Ks, sheen, wrap) and the whole pattern stack (layerscale),
 * whose kernel is only generated (see docs/specialization.md).
 *
 *   bench_bigshader [--mesa-cache] SHADER.sl [SHADER_DIR]
 *
 * By default Mesa's shader cache is off, so compiles are cold; with
 * --mesa-cache it is left on, and a second run shows the warm figures (a
 * program loaded from relight's cache, whose binaries need Mesa's). The GL
 * compile is followed by the first run, where llvmpipe JITs the kernel.
 * Times are medians of five (the compiles and the first runs: one).
 */
#include "gpu.h"
#include "clock.h"
#include "spec.h"
#include "config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define NSAMPLES (1u << 16)
#define REPS 5

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(*v), cmp_double);
	return v[n / 2];
}

static size_t count_lines(const char *s)
{
	size_t n = 0;
	for (; *s; s++)
		n += *s == '\n';
	return n;
}

struct variant {
	const char *name;
	const char *const *dynamic;
	size_t ndynamic;
	bool on_gpu;            /* compile and run it (the whole stack is not) */
};

static const char *const material[] = { "roughness", "Ks", "sheen", "wrap" };
static const char *const stack[] = { "layerscale" };
static const struct variant variants[] = {
	{ "lights", NULL, 0, true },
	{ "material", material, 4, true },
	{ "pattern stack", stack, 1, false },
};

/* Random inputs for @layout, a run, and the best of REPS runs after it. */
static bool run_kernel(struct gpu_ctx *ctx, struct gpu_program *gp,
		       const struct sl_glsl_layout *layout, double *first, double *best)
{
	size_t nin = (size_t)layout->in_stride * NSAMPLES;
	float *data = malloc((nin + 1) * sizeof(float));
	if (!data)
		return false;
	uint32_t seed = 12345;
	for (size_t i = 0; i < nin; i++) {
		seed = seed * 1664525u + 1013904223u;
		data[i] = (float)(seed >> 8) / 16777216.0f;
	}
	struct gpu_buffer *in = gpu_buffer_create(ctx, (nin + 1) * sizeof(float), data);
	struct gpu_buffer *out = gpu_buffer_create(
		ctx, (size_t)layout->out_stride * NSAMPLES * sizeof(float), NULL);
	free(data);
	bool ok = in && out;
	struct gpu_binding b[2] = { { 0, false, in, true }, { 1, true, out } };
	double t[REPS];
	for (int r = -1; r < REPS && ok; r++) {
		float one;
		double t0 = rl_now_ms();
		ok = gpu_dispatch(ctx, gp, b, 2, NSAMPLES) &&
		     gpu_buffer_read(out, 0, sizeof(one), &one);
		if (r < 0)
			*first = rl_now_ms() - t0;
		else
			t[r] = rl_now_ms() - t0;
	}
	if (ok)
		*best = median(t, REPS);
	gpu_buffer_destroy(in);
	gpu_buffer_destroy(out);
	return ok;
}

int main(int argc, char **argv)
{
	bool mesa_cache = argc > 1 && !strcmp(argv[1], "--mesa-cache");
	argv += mesa_cache;
	argc -= mesa_cache;
	if (argc < 2) {
		fprintf(stderr, "usage: bench_bigshader [--mesa-cache] SHADER.sl [SHADER_DIR]\n");
		return 2;
	}
	const char *dir = argc > 2 ? argv[2] : RELIGHT_SOURCE_SHADER_DIR;
	if (!mesa_cache)
		setenv("MESA_SHADER_CACHE_DISABLE", "true", 1);
	setvbuf(stdout, NULL, _IONBF, 0);
	char cache[] = "/tmp/relight-bench-bigshader-XXXXXX";
	if (!mkdtemp(cache)) {
		perror("mkdtemp");
		return 1;
	}
	double t[REPS];
	struct sl_program *prog = NULL;
	for (int r = 0; r < REPS; r++) {
		sl_program_destroy(prog);
		double t0 = rl_now_ms();
		prog = sl_compile_file(argv[1], NULL);
		t[r] = rl_now_ms() - t0;
		if (!prog)
			return 1;
	}
	char lpath[4096];
	snprintf(lpath, sizeof(lpath), "%s/spotlight.sl", dir);
	struct sl_program *spot = sl_compile_file(lpath, NULL);
	if (!spot)
		return 1;
	const struct sl_program *lights[1] = { spot };
	printf("bench_bigshader: %s, %u IR instructions\n", argv[1], prog->ncode);
	printf("front end (preprocess, parse, check, lower, infer): %.1f ms\n", median(t, REPS));

	char err[512];
	struct gpu_ctx *ctx = gpu_create(err, sizeof(err));
	if (!ctx)
		printf("no OpenGL 4.3 context (%s): GPU figures left out\n", err);
	else
		printf("GPU: %s\n", gpu_renderer(ctx));
	printf("\n%-14s %7s %8s %7s %10s %7s %9s %9s %10s %10s %7s\n", "dynamic", "dyn ins",
	       "cached r", "spec ms", "glsl lines", "glsl ms", "GL ms", "1st run", "GL again",
	       "1st again", "run ms");
	bool ok = true;
	for (size_t v = 0; v < sizeof(variants) / sizeof(variants[0]) && ok; v++) {
		const struct variant *var = &variants[v];
		struct sl_spec *s = NULL;
		for (int r = 0; r < REPS; r++) {
			sl_spec_destroy(s);
			double t0 = rl_now_ms();
			s = sl_specialize(prog, var->dynamic, var->ndynamic, stderr);
			t[r] = rl_now_ms() - t0;
			if (!s)
				return 1;
		}
		double spec_ms = median(t, REPS);
		char *glsl = NULL;
		struct sl_glsl_layout layout;
		for (int r = 0; r < REPS; r++) {
			if (glsl) {
				sl_glsl_layout_finish(&layout);
				free(glsl);
			}
			double t0 = rl_now_ms();
			glsl = sl_glsl_emit(&s->slice, lights, 1, &layout, stderr);
			t[r] = rl_now_ms() - t0;
			if (!glsl)
				return 1;
		}
		double glsl_ms = median(t, REPS);
		double cold = -1, warm = -1, first = -1, first2 = -1, run = -1, run2 = -1;
		if (ctx && var->on_gpu) {
			gpu_set_program_cache(ctx, cache);
			double t0 = rl_now_ms();
			struct gpu_program *gp = gpu_program(ctx, glsl, stderr);
			cold = rl_now_ms() - t0;
			ok = gp && run_kernel(ctx, gp, &layout, &first, &run);
			/* A new context: the program comes from relight's cache. */
			gpu_destroy(ctx);
			ctx = gpu_create(err, sizeof(err));
			if (ctx && ok) {
				gpu_set_program_cache(ctx, cache);
				t0 = rl_now_ms();
				struct gpu_program *again = gpu_program(ctx, glsl, stderr);
				warm = rl_now_ms() - t0;
				ok = again && run_kernel(ctx, again, &layout, &first2, &run2);
			}
		}
		printf("%-14s %7u %8u %7.1f %10zu %7.1f %9.1f %9.1f %10.1f %10.1f %7.2f\n",
		       var->name, s->ndynamic, s->ncached, spec_ms, count_lines(glsl), glsl_ms, cold,
		       first, warm, first2, run);
		sl_glsl_layout_finish(&layout);
		free(glsl);
		sl_spec_destroy(s);
	}
	printf("(-1: not run; %u samples a run; \"again\": the same program in a new context, "
	       "through relight's program cache; Mesa's shader cache %s)\n", NSAMPLES,
	       mesa_cache ? "on" : "off");
	gpu_destroy(ctx);
	sl_program_destroy(spot);
	sl_program_destroy(prog);
	char cmd[4200];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", cache);
	if (system(cmd) != 0)
		fprintf(stderr, "bench_bigshader: could not remove %s\n", cache);
	return ok ? 0 : 1;
}

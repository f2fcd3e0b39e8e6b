/*
 * How the GPU code of a shot should be cut into kernels, measured on the
 * shipped shaders: plastic lit by eight lights of five light shaders.
 *
 *  per set   one kernel for the surface with all eight lights (the light
 *            loop unrolled, every light's code inlined);
 *  per pair  one kernel per (surface, light shader), run once per light,
 *            the runtime adding the lights' contributions.
 *
 * For each: what compiling costs (cold, with Mesa's shader cache off, and
 * loaded from relight's program cache), the GLSL size, and the time to shade
 * every sample for all lights and for an edit of one light. A kernel that
 * dispatches over light shaders at run time cannot beat the per-set kernel
 * (same code plus a switch, and on llvmpipe a loop bounded by a uniform costs
 * its maximum, see docs/specialization.md); its one advantage, never
 * compiling on an edit, the per-pair cut has as well.
 *
 *   bench_kernels [--mesa-cache] [SHADER_DIR]
 *
 * By default Mesa's shader cache is off, so compiles are cold; with
 * --mesa-cache it is left on (run twice to see warm figures). Mesa's
 * program binaries need its cache: without it relight's program cache has
 * nothing to keep (GL_NUM_PROGRAM_BINARY_FORMATS is 0).
 */
#include "gpu.h"
#include "clock.h"
#include "spec.h"
#include "config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define NSAMPLES (1u << 18)
#define NLIGHTS 8

static const char *const light_names[NLIGHTS] = {
	"spotlight", "spotlight", "spotlight", "pointlight", "pointlight", "distantlight",
	"uberlight", "shadowspot",
};

static struct sl_program *load(const char *dir, const char *name)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/%s.sl", dir, name);
	struct sl_program *p = sl_compile_file(path, NULL);
	if (!p)
		fprintf(stderr, "bench_kernels: cannot compile %s\n", path);
	return p;
}

struct kernel {
	char *glsl;
	struct sl_glsl_layout layout;
	struct gpu_program *prog;
	struct gpu_buffer *in, *out;
	double compile_ms, first_ms;
	size_t lines;
};

static size_t count_lines(const char *s)
{
	size_t n = 0;
	for (; *s; s++)
		n += *s == '\n';
	return n;
}

static bool make(struct kernel *k, const struct sl_spec *s, const struct sl_program *const *lights,
		 uint32_t nlights)
{
	memset(k, 0, sizeof(*k));
	k->glsl = sl_glsl_emit(&s->slice, lights, nlights, &k->layout, stderr);
	if (!k->glsl)
		return false;
	k->lines = count_lines(k->glsl);
	return true;
}

/* Compile, bind buffers of random inputs and run once (the JIT happens at first use). */
static bool build(struct gpu_ctx *ctx, struct kernel *k)
{
	double t0 = rl_now_ms();
	k->prog = gpu_program(ctx, k->glsl, NULL);
	k->compile_ms = rl_now_ms() - t0;
	if (!k->prog)
		return false;
	size_t nin = (size_t)k->layout.in_stride * NSAMPLES;
	float *data = malloc((nin + 1) * sizeof(float));
	if (!data)
		return false;
	uint32_t seed = 12345;
	for (size_t i = 0; i < nin; i++) {
		seed = seed * 1664525u + 1013904223u;
		data[i] = (float)(seed >> 8) / 16777216.0f * 2.0f - 1.0f;
	}
	k->in = gpu_buffer_create(ctx, (nin + 1) * sizeof(float), data);
	k->out = gpu_buffer_create(ctx, (size_t)k->layout.out_stride * NSAMPLES * sizeof(float),
				   NULL);
	free(data);
	if (!k->in || !k->out)
		return false;
	float one;
	struct gpu_binding b[2] = { { 0, false, k->in, true }, { 1, true, k->out } };
	t0 = rl_now_ms();
	bool ok = gpu_dispatch(ctx, k->prog, b, 2, NSAMPLES) &&
		  gpu_buffer_read(k->out, 0, sizeof(one), &one);
	k->first_ms = rl_now_ms() - t0;
	return ok;
}

static double run_ms(struct gpu_ctx *ctx, struct kernel *k)
{
	struct gpu_binding b[2] = { { 0, false, k->in, true }, { 1, true, k->out } };
	double best = 1e30;
	for (int r = 0; r < 5; r++) {
		float one;
		double t0 = rl_now_ms();
		gpu_dispatch(ctx, k->prog, b, 2, NSAMPLES);
		gpu_buffer_read(k->out, 0, sizeof(one), &one);
		double t = rl_now_ms() - t0;
		best = t < best ? t : best;
	}
	return best;
}

static void release(struct kernel *k)
{
	gpu_buffer_destroy(k->in);
	gpu_buffer_destroy(k->out);
	sl_glsl_layout_finish(&k->layout);
	free(k->glsl);
	memset(k, 0, sizeof(*k));
}

int main(int argc, char **argv)
{
	bool mesa_cache = argc > 1 && !strcmp(argv[1], "--mesa-cache");
	const char *dir = argc > 1 + mesa_cache ? argv[1 + mesa_cache] : RELIGHT_SOURCE_SHADER_DIR;
	/* Cold compiles: Mesa's own shader cache off for this process. */
	if (!mesa_cache)
		setenv("MESA_SHADER_CACHE_DISABLE", "true", 1);
	char cache[] = "/tmp/relight-bench-kernels-XXXXXX";
	setvbuf(stdout, NULL, _IONBF, 0);
	if (!mkdtemp(cache)) {
		perror("mkdtemp");
		return 1;
	}
	struct sl_program *surface = load(dir, "plastic");
	const struct sl_program *lights[NLIGHTS];
	struct sl_program *owned[NLIGHTS] = { 0 };
	bool ok = surface != NULL;
	for (int k = 0; k < NLIGHTS && ok; k++) {
		int same = -1;
		for (int j = 0; j < k; j++)
			if (!strcmp(light_names[j], light_names[k]))
				same = j;
		lights[k] = same >= 0 ? lights[same] : (owned[k] = load(dir, light_names[k]));
		ok = lights[k] != NULL;
	}
	struct sl_spec *s = ok ? sl_specialize(surface, NULL, 0, stderr) : NULL;
	char err[512];
	struct gpu_ctx *ctx = s ? gpu_create(err, sizeof(err)) : NULL;
	if (!ctx) {
		if (s)
			printf("SKIP: no OpenGL 4.3 context: %s\n", err);
		sl_spec_destroy(s);
		sl_program_destroy(surface);
		for (int k = 0; k < NLIGHTS; k++)
			sl_program_destroy(owned[k]);
		rmdir(cache);
		return s ? 77 : 1;
	}
	printf("bench_kernels: plastic, %u samples, on %s\n", NSAMPLES, gpu_renderer(ctx));
	gpu_set_program_cache(ctx, cache);

	/* One kernel per light set, for sets of 1, 2, 4 and 8 lights. */
	printf("\nper set (one kernel, lights unrolled)\n");
	printf("%7s %8s %12s %12s %12s %12s\n", "lights", "lines", "compile ms", "1st run ms",
	       "all ms", "edit ms");
	double set8_run = 0, set8_compile = 0, set8_first = 0;
	for (uint32_t n = 1; n <= NLIGHTS; n *= 2) {
		struct kernel k;
		if (!make(&k, s, lights, n) || !build(ctx, &k)) {
			release(&k);
			ok = false;
			break;
		}
		double t = run_ms(ctx, &k);
		printf("%7u %8zu %12.1f %12.1f %12.2f %12.2f\n", n, k.lines, k.compile_ms,
		       k.first_ms, t, t);
		if (n == NLIGHTS) {
			set8_run = t;
			set8_compile = k.compile_ms;
			set8_first = k.first_ms;
		}
		release(&k);
	}

	/* One kernel per (surface, light shader): five kernels serve eight lights. */
	printf("\nper pair (one kernel per light shader, one dispatch per light)\n");
	printf("%-14s %8s %12s %12s %12s\n", "light shader", "lines", "compile ms", "1st run ms",
	       "run ms");
	double pair_all = 0, pair_compile = 0, pair_edit_max = 0, pair_edit_min = 1e30;
	for (int k = 0; k < NLIGHTS && ok; k++) {
		bool seen = false;
		for (int j = 0; j < k; j++)
			seen = seen || lights[j] == lights[k];
		struct kernel kr;
		if (!make(&kr, s, &lights[k], 1) || !build(ctx, &kr)) {
			release(&kr);
			ok = false;
			break;
		}
		double t = run_ms(ctx, &kr);
		pair_all += t;
		pair_edit_max = t > pair_edit_max ? t : pair_edit_max;
		pair_edit_min = t < pair_edit_min ? t : pair_edit_min;
		if (!seen) {
			pair_compile += kr.compile_ms;
			printf("%-14s %8zu %12.1f %12.1f %12.2f\n", light_names[k], kr.lines,
			       kr.compile_ms, kr.first_ms, t);
		}
		release(&kr);
	}

	/* The per-set kernel again in a new context: loaded from relight's cache. */
	if (ok) {
		gpu_destroy(ctx);
		ctx = gpu_create(err, sizeof(err));
		if (ctx) {
			gpu_set_program_cache(ctx, cache);
			struct kernel k;
			if (make(&k, s, lights, NLIGHTS) && build(ctx, &k)) {
				unsigned hits = 0;
				gpu_program_stats(ctx, &hits, NULL);
				printf("\n8-light kernel: cold compile %.1f ms + first run %.1f ms; "
				       "from relight's program cache (%s) %.1f ms + first run %.1f ms\n",
				       set8_compile, set8_first, hits ? "hit" : "MISS", k.compile_ms,
				       k.first_ms);
			}
			release(&k);
		}
	}
	if (ok) {
		printf("\nall 8 lights: per set %.2f ms, per pair %.2f ms (%.2fx)\n", set8_run,
		       pair_all, pair_all / set8_run);
		printf("edit of 1 light (with the other lights' sum kept): per set %.2f ms, per pair "
		       "%.2f to %.2f ms (%.1fx to %.1fx faster)\n", set8_run, pair_edit_min,
		       pair_edit_max, set8_run / pair_edit_max, set8_run / pair_edit_min);
		printf("compiling: per set %.1f ms for this one set (any new set compiles again); "
		       "per pair %.1f ms once for all five light shaders\n", set8_compile,
		       pair_compile);
	}
	gpu_destroy(ctx);
	sl_spec_destroy(s);
	sl_program_destroy(surface);
	for (int k = 0; k < NLIGHTS; k++)
		sl_program_destroy(owned[k]);
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf %s", cache);
	if (system(cmd) != 0)
		fprintf(stderr, "bench_kernels: could not remove %s\n", cache);
	return ok ? 0 : 1;
}

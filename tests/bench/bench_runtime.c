/*
 * The GPU runtime's speed, with its error: a 960x540 street of spheres
 * (about half a million shading samples) baked twice, lit by 32 lights and
 * by 1, and the same edit of the same spot light on both.
 *
 *   bench_runtime [--json] PATH/TO/relight [WORKDIR]
 *
 * For each shot: loading, the first frame with every light (full), then a
 * run of edits of light 1's intensity, each refined level by level as an
 * interactive session sees it: the median time of each level and of the
 * whole refinement, the host's share of it (CPU time of the calling thread:
 * on a GPU, a level whose host time is close to its time is bound by the
 * host), the entries resolved, the samples shaded and the kernels run. The first
 * edit after the full frame also takes light 1 out of the light cache
 * (shading it once more), so it is reported apart; the edits after it are
 * what a lighter dragging a slider gets.
 *
 * Beside them: the shading rate of the kernels alone (gpu_shot_profile:
 * samples per second, and float operations per second counted on the
 * interpreter) against the device's arithmetic rate (gpu_arith_rate) and
 * against a hand-written kernel of the batch kernels' shading (ceiling.h:
 * what that shading reaches at best on the device), and
 * each level's error against the final level and the final level's error
 * against `relight render` of the RIB edited the same way, in percent of
 * the 8-bit range after sRGB (mean and max).
 *
 * Targets on llvmpipe (issue: the GPU runtime): coarsest level <= 10 ms and
 * final level <= 100 ms after a one-light edit; 32 lights <= 1.5x one light
 * at every level; kernels >= half the arithmetic rate. The figures are
 * printed, not asserted: machines here are noisy.
 */
#include "benchutil.h"
#include "ceiling.h"
#include "clock.h"
#include "gpu.h"
#include "imgerr.h"
#include "microbench.h"
#include "png.h"
#include "runtime.h"
#include "scenes.h"
#include "texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define EDITS 9
#define LEVELS GPU_SHOT_LEVELS

/* Mean and max of |srgb(a) - srgb(b)| in percent of the range, over RGB (as relight diff). */
static void image_error(const float *a, const float *b, uint32_t w, uint32_t h, double *mean,
			double *max)
{
	struct img_error e;
	img_error_rgba(a, b, w, h, NULL, &e);
	*mean = img_error_mean_pct(&e);
	*max = img_error_max_pct(&e);
}

struct result {
	int nlights;
	double load_ms, full_ms, first_edit_ms;
	double level_ms[LEVELS], total_ms;
	uint64_t entries[LEVELS], shaded[LEVELS], samples;
	uint32_t dispatches[LEVELS];    /* kernels an edit runs at each level */
	double host_ms[LEVELS];         /* CPU time of the calling thread a level (median) */
	double err_mean[LEVELS], err_max[LEVELS];
	double render_mean, render_max;
	struct gpu_shot_profile prof;
	struct gpu_shot_profile point;   /* a point light's, with its batch kernel (32 lights) */
	size_t bytes;
	bool ok;
	/* while running */
	struct gpu_shot *s;
	double lv[LEVELS][EDITS], host[LEVELS][EDITS], tot[EDITS];
	float v;
};

/* Bake (once) and load the shot lit by @nlights lights, and render it whole. */
static bool shot_open(struct gpu_ctx *ctx, const char *relight, const char *dir, int nlights,
		      struct result *r)
{
	memset(r, 0, sizeof(*r));
	r->nlights = nlights;
	char cmd[4096], rib[1024], shot[1024], err[512];
	snprintf(rib, sizeof(rib), "%s/street%d.rib", dir, nlights);
	snprintf(shot, sizeof(shot), "%s/street%d.shot.exr", dir, nlights);
	if (!bench_street_rib(rib, 960, 540, nlights, nlights, 40.0f, err, sizeof(err))) {
		fprintf(stderr, "bench_runtime: %s\n", err);
		return false;
	}
	struct stat st;
	if (stat(shot, &st) != 0) {
		fprintf(stderr, "bench_runtime: baking %s\n", rib);
		snprintf(cmd, sizeof(cmd), "cd %s && %s bake -q -o %s %s", dir, relight, shot, rib);
		if (system(cmd) != 0)
			return false;
	}
	double t0 = rl_now_ms();
	struct gpu_shot_opts o = { .diag = stderr };
	r->s = gpu_shot_open(ctx, shot, &o);
	if (!r->s)
		return false;
	r->load_ms = rl_now_ms() - t0;
	r->samples = gpu_shot_samples(r->s);
	r->bytes = gpu_shot_bytes(r->s);
	struct gpu_shot_stats stt;
	bool ok = gpu_shot_render(r->s, GPU_SHOT_FINAL, &stt);
	r->full_ms = stt.ms;
	return ok;
}

/* Edit @e (-1: the first, which takes light 1 out of the cache), refined level by level. */
static bool shot_edit(struct result *r, int e)
{
	char err[512];
	struct gpu_shot_stats stt;
	r->v = 40.0f + 3.0f * (float)(e + 2);
	bool ok = gpu_shot_set(r->s, "1", "intensity", &r->v, 1, err, sizeof(err));
	double sum = 0.0;
	for (int L = 0; ok && L < LEVELS; L++) {
		double c0 = rl_thread_cpu_ms();
		ok = gpu_shot_render(r->s, L, &stt);
		double host = rl_thread_cpu_ms() - c0;
		sum += stt.ms;
		if (e >= 0) {
			r->lv[L][e] = stt.ms;
			r->host[L][e] = host;
			r->entries[L] = stt.entries;
			r->shaded[L] = stt.shaded;
			r->dispatches[L] = stt.dispatches;
		}
	}
	if (e < 0)
		r->first_edit_ms = sum;
	else
		r->tot[e] = sum;
	return ok;
}

/* The medians, the errors and the kernels' profile; closes the shot. */
static bool shot_finish(const char *relight, const char *dir, struct result *r)
{
	char cmd[4096], err[512];
	struct gpu_shot *s = r->s;
	int nlights = r->nlights;
	float v = r->v;
	bool ok = true;
	for (int L = 0; L < LEVELS; L++) {
		r->level_ms[L] = bench_median(r->lv[L], EDITS);
		r->host_ms[L] = bench_median(r->host[L], EDITS);
	}
	r->total_ms = bench_median(r->tot, EDITS);
	/* errors: each level against the final level, the final level against the renderer */
	uint32_t W = gpu_shot_width(s), H = gpu_shot_height(s);
	size_t px = (size_t)W * H;
	float *img[LEVELS];
	for (int L = 0; L < LEVELS; L++) {
		img[L] = malloc(px * 4 * sizeof(float));
		ok = ok && img[L] && gpu_shot_read_rgba(s, L, img[L]);
	}
	for (int L = 0; ok && L < LEVELS; L++)
		image_error(img[L], img[LEVELS - 1], W, H, &r->err_mean[L], &r->err_max[L]);
	if (ok) {
		char edited[1024], ref[1024];
		snprintf(edited, sizeof(edited), "%s/street%d.edited.rib", dir, nlights);
		snprintf(ref, sizeof(ref), "%s/street%d.edited.exr", dir, nlights);
		if (!bench_street_rib(edited, 960, 540, nlights, nlights, v, err, sizeof(err)))
			fprintf(stderr, "bench_runtime: %s\n", err);
		snprintf(cmd, sizeof(cmd), "cd %s && %s render -q -o %s %s", dir, relight, ref,
			 edited);
		float *ref_rgba = system(cmd) == 0
					  ? bench_read_rgba_exr(ref, W, H, false, NULL, err, sizeof(err))
					  : NULL;
		if (ref_rgba)
			image_error(img[LEVELS - 1], ref_rgba, W, H, &r->render_mean, &r->render_max);
		else
			r->render_mean = r->render_max = NAN;
		free(ref_rgba);
	}
	for (int L = 0; L < LEVELS; L++)
		free(img[L]);
	ok = ok && gpu_shot_profile(s, "1", &r->prof, err, sizeof(err));
	/* light 4 is the first of the street's point lights */
	ok = ok && (r->nlights < 4 || gpu_shot_profile(s, "4", &r->point, err, sizeof(err)));
	if (!ok)
		fprintf(stderr, "bench_runtime: %s\n", err);
	gpu_shot_close(s);
	r->s = NULL;
	r->ok = ok;
	return ok;
}

int main(int argc, char **argv)
{
	int a = 1;
	bool json = a < argc && !strcmp(argv[a], "--json");
	a += json;
	if (a >= argc) {
		fprintf(stderr, "usage: bench_runtime [--json] PATH/TO/relight [WORKDIR]\n");
		return 2;
	}
	char relight[2048], cwd[1024];
	if (argv[a][0] == '/')
		snprintf(relight, sizeof(relight), "%s", argv[a]);
	else
		snprintf(relight, sizeof(relight), "%s/%s", getcwd(cwd, sizeof(cwd)) ? cwd : ".",
			 argv[a]);
	char tmp[] = "/tmp/relight-bench-runtime-XXXXXX";
	const char *dir = a + 1 < argc ? argv[a + 1] : mkdtemp(tmp);
	if (!dir)
		return 1;
	mkdir(dir, 0755);
	char err[512];
	struct gpu_ctx *ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		printf("SKIP: no OpenGL 4.3 context: %s\n", err);
		return 77;
	}
	struct gpu_arith_rate rate;
	bool ok = gpu_arith_rate(ctx, 5, 100.0, &rate);
	/* both shots at once, their edits interleaved: a busy machine slows both alike */
	struct result r[2];
	memset(r, 0, sizeof(r));
	ok = ok && shot_open(ctx, relight, dir, 1, &r[0]) && shot_open(ctx, relight, dir, 32, &r[1]);
	for (int e = -1; ok && e < EDITS; e++)
		ok = shot_edit(&r[0], e) && shot_edit(&r[1], e);
	ok = ok && shot_finish(relight, dir, &r[0]) && shot_finish(relight, dir, &r[1]);
	gpu_shot_close(r[0].s);
	gpu_shot_close(r[1].s);
	struct ceiling ceil;
	ok = ok && ceiling_run(ctx, (uint32_t)r[1].samples, 5, &ceil);
	if (!ok) {
		fprintf(stderr, "bench_runtime: failed\n");
		gpu_destroy(ctx);
		return 1;
	}
	if (json) {
		printf("{\"device\": \"%s\", \"arith_flops\": %.4g, \"ceiling_ms\": %.3f, "
		       "\"ceiling_flops_per_sample\": %.1f, \"ceiling_flops\": %.4g, "
		       "\"ceiling_max_rel_err\": %.3g, \"shots\": [", gpu_renderer(ctx), rate.flops,
		       ceil.ms, ceil.flops_per_sample, ceil.flops, ceil.max_rel_err);
		for (int i = 0; i < 2; i++) {
			const struct result *x = &r[i];
			printf("%s{\"lights\": %d, \"samples\": %llu, \"gpu_bytes\": %zu, \"load_ms\": %.1f, "
			       "\"full_ms\": %.2f, \"first_edit_ms\": %.2f, \"edit_ms\": %.2f, "
			       "\"render_mean_pct\": %.4f, \"render_max_pct\": %.4f, "
			       "\"kernel_ms\": %.3f, \"base_ms\": %.3f, \"kernel_samples\": %llu, \"flops_per_sample\": %.1f, "
			       "\"kernel_flops\": %.4g, \"point_kernel_ms\": %.3f, "
			       "\"point_flops_per_sample\": %.1f, \"point_kernel_flops\": %.4g, "
			       "\"batch_lights\": %u, \"batch_ms\": %.3f, "
			       "\"batch_flops_per_sample\": %.1f, \"batch_flops\": %.4g, \"levels\": [",
			       i ? ", " : "", x->nlights,
			       (unsigned long long)x->samples, x->bytes, x->load_ms, x->full_ms,
			       x->first_edit_ms, x->total_ms, x->render_mean, x->render_max,
			       x->prof.kernel_ms, x->prof.base_ms, (unsigned long long)x->prof.samples,
			       x->prof.flops_per_sample, x->prof.flops, x->point.kernel_ms,
			       x->point.flops_per_sample, x->point.flops, x->point.batch_lights,
			       x->point.batch_ms, x->point.batch_flops_per_sample,
			       x->point.batch_flops);
			for (int L = 0; L < LEVELS; L++)
				printf("%s{\"level\": %d, \"ms\": %.3f, \"entries\": %llu, \"shaded\": %llu, "
				       "\"host_ms\": %.3f, \"dispatches\": %u, "
				       "\"mean_pct\": %.4f, \"max_pct\": %.4f}", L ? ", " : "", L,
				       x->level_ms[L], (unsigned long long)x->entries[L],
				       (unsigned long long)x->shaded[L], x->host_ms[L], x->dispatches[L],
				       x->err_mean[L], x->err_max[L]);
			printf("]}");
		}
		printf("]}\n");
	} else {
		printf("bench_runtime on %s; arithmetic rate %.1f GFLOP/s (gpu_arith_rate)\n\n",
		       gpu_renderer(ctx), rate.flops * 1e-9);
		for (int i = 0; i < 2; i++) {
			const struct result *x = &r[i];
			printf("%d light%s: %llu samples, %.1f MiB on the GPU, loaded in %.0f ms, every "
			       "light %.1f ms; first edit (light 1 leaves the cache) %.1f ms\n",
			       x->nlights, x->nlights > 1 ? "s" : "", (unsigned long long)x->samples,
			       (double)x->bytes / 1048576.0, x->load_ms, x->full_ms, x->first_edit_ms);
			printf("  %-6s %10s %10s %10s %10s %10s %10s %16s\n", "level", "ms", "cumul ms",
			       "host ms", "entries", "shaded", "kernels", "error vs final");
			double cum = 0.0;
			for (int L = 0; L < LEVELS; L++) {
				cum += x->level_ms[L];
				printf("  %-6d %10.2f %10.2f %10.2f %10llu %10llu %10u   %5.3f / %5.2f %%\n",
				       L, x->level_ms[L], cum, x->host_ms[L],
				       (unsigned long long)x->entries[L],
				       (unsigned long long)x->shaded[L], x->dispatches[L],
				       x->err_mean[L], x->err_max[L]);
			}
			printf("  final level against relight render of the edited RIB: mean %.4f %%, "
			       "max %.4f %%\n", x->render_mean, x->render_max);
			printf("  kernels alone: %llu samples in %.2f ms (with no light %.2f ms) = %.1f M "
			       "samples/s; %.0f flops/sample = %.1f GFLOP/s = %.2f of the arithmetic "
			       "rate\n\n", (unsigned long long)x->prof.samples, x->prof.kernel_ms,
			       x->prof.base_ms,
			       (double)x->prof.samples / (x->prof.kernel_ms * 1e3),
			       x->prof.flops_per_sample, x->prof.flops * 1e-9,
			       x->prof.flops / rate.flops);
			if (!x->point.batch_lights)
				continue;
			const struct gpu_shot_profile *p = &x->point;
			printf("  point light 4 alone: %.2f ms, %.0f flops/sample = %.1f GFLOP/s = %.2f "
			       "of the arithmetic rate\n", p->kernel_ms, p->flops_per_sample,
			       p->flops * 1e-9, p->flops / rate.flops);
			printf("  batch kernel (%u point lights a pass each, one read of each record): "
			       "%.2f ms = %.2f ms a light; %.0f flops/sample = %.1f GFLOP/s = %.2f of "
			       "the arithmetic rate\n\n", p->batch_lights, p->batch_ms,
			       p->batch_ms / p->batch_lights, p->batch_flops_per_sample,
			       p->batch_flops * 1e-9, p->batch_flops / rate.flops);
		}
		printf("hand-written kernel of the same shading (ceiling.h: plastic, %d point lights, "
		       "no guards), %u synthetic samples: %.2f ms = %.2f ms a light; %.0f "
		       "flops/sample = %.1f GFLOP/s = %.2f of the arithmetic rate (max error against "
		       "the CPU %.1e over %u samples)\n\n", CEILING_LIGHTS, ceil.samples, ceil.ms,
		       ceil.ms / CEILING_LIGHTS, ceil.flops_per_sample, ceil.flops * 1e-9,
		       ceil.flops / rate.flops, ceil.max_rel_err, ceil.checked);
		printf("32 lights against 1, per level:");
		for (int L = 0; L < LEVELS; L++)
			printf(" %.2fx", r[1].level_ms[L] / r[0].level_ms[L]);
		printf("; whole refinement %.2fx\n", r[1].total_ms / r[0].total_ms);
	}
	gpu_destroy(ctx);
	return 0;
}

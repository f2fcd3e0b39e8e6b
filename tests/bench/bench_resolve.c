/*
 * The GPU resolve at preview size: 960x540, 0..8 entries a pixel (binomial,
 * 3 on average, ~1.56M entries), 500k samples. Prints milliseconds per
 * resolve of each level (median of 20; each timed call ends with a 4-byte
 * readback, which waits for the GPU), the sRGB8 encoding, and entries per
 * second. Two id orders: coherent (a pixel's samples lie near each other in
 * the sample table, as a bake lays them out) and random. Exit 77 without EGL.
 */
#include "resolve.h"
#include "clock.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

enum { W = 960, H = 540, NSAMPLES = 500000, RUNS = 20 };

static uint64_t rng_state = 0x2007beefull;

static uint64_t rng(void)
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

struct timing {
	struct gpu_ifb *f;
	struct gpu_buffer *colors, *rgba, *rgba8;
	int level;  /* -1: the encoding */
};

/* Median ms of RUNS calls after one warm-up; -1 on failure. */
static double time_it(struct gpu_ctx *ctx, const struct timing *t)
{
	double ms[RUNS];
	uint32_t word;
	for (int r = -1; r < RUNS; r++) {
		double s = rl_now_ms();
		bool ok = t->level >= 0
			  ? gpu_ifb_resolve(t->f, t->colors, NSAMPLES, t->level, t->rgba) &&
			    gpu_buffer_read(t->rgba, 0, 4, &word)
			  : gpu_encode_srgb8(ctx, t->rgba, W * H, t->rgba8) &&
			    gpu_buffer_read(t->rgba8, 0, 4, &word);
		if (!ok)
			return -1;
		if (r >= 0)
			ms[r] = rl_now_ms() - s;
	}
	qsort(ms, RUNS, sizeof(ms[0]), cmp_double);
	return 0.5 * (ms[RUNS / 2 - 1] + ms[RUNS / 2]);
}

/* The sample of a pixel's entry: near the pixel's place in the table, or anywhere. */
static uint32_t sample_for(size_t p, bool coherent)
{
	if (!coherent)
		return (uint32_t)(rng() % NSAMPLES);
	uint64_t base = (uint64_t)p * NSAMPLES / ((uint64_t)W * H);
	uint64_t id = base + rng() % 8;
	return (uint32_t)(id < NSAMPLES ? id : NSAMPLES - 1);
}

static int run(struct gpu_ctx *ctx, bool coherent)
{
	size_t npix = (size_t)W * H;
	uint64_t *offsets = malloc((npix + 1) * sizeof(*offsets));
	float *alpha = malloc(npix * sizeof(float));
	float *colors = malloc((size_t)NSAMPLES * 3 * sizeof(float));
	if (!offsets || !alpha || !colors)
		return 1;
	offsets[0] = 0;
	for (size_t p = 0; p < npix; p++) {
		unsigned n = 0;  /* binomial(8, 3/8) */
		for (int k = 0; k < 8; k++)
			n += rng() % 8 < 3;
		offsets[p + 1] = offsets[p] + n;
		alpha[p] = 1.0f;
	}
	size_t ne = offsets[npix];
	uint32_t *sample = malloc((ne + 1) * sizeof(uint32_t));
	float *weight = malloc((ne + 1) * sizeof(float));
	struct gpu_ifb_desc d = { .width = W, .height = H, .offsets = offsets, .sample = sample,
				  .weight = weight, .alpha = alpha };
	static const uint32_t side[3] = { 4, 2, 1 };
	uint32_t *lsample[3] = { NULL, NULL, NULL };
	float *lweight[3] = { NULL, NULL, NULL };
	for (size_t p = 0; p < npix; p++)
		for (uint64_t e = offsets[p]; e < offsets[p + 1]; e++) {
			sample[e] = sample_for(p, coherent);
			weight[e] = 1.0f / (float)(offsets[p + 1] - offsets[p]);
		}
	for (size_t i = 0; i < (size_t)NSAMPLES * 3; i++)
		colors[i] = (float)(rng() % 1000) * 1e-3f;
	for (int L = 0; L < 3; L++) {
		uint32_t nx = (W + side[L] - 1) / side[L], ny = (H + side[L] - 1) / side[L];
		lsample[L] = malloc((size_t)nx * ny * sizeof(uint32_t));
		lweight[L] = malloc((size_t)nx * ny * sizeof(float));
		for (uint32_t b = 0; b < nx * ny; b++) {
			size_t p = (size_t)(b / nx) * side[L] * W + (size_t)(b % nx) * side[L];
			lsample[L][b] = sample_for(p, coherent);
			lweight[L][b] = 1.0f;
		}
		d.level_sample[L] = lsample[L];
		d.level_weight[L] = lweight[L];
	}
	char err[256];
	double t0 = rl_now_ms();
	struct timing t = { .f = gpu_ifb_create(ctx, &d, err, sizeof(err)) };
	double create_ms = rl_now_ms() - t0;
	t.colors = gpu_buffer_create(ctx, (size_t)NSAMPLES * 3 * sizeof(float), colors);
	t.rgba = gpu_buffer_create(ctx, npix * 4 * sizeof(float), NULL);
	t.rgba8 = gpu_buffer_create(ctx, npix * sizeof(uint32_t), NULL);
	int rc = 0;
	if (!t.f || !t.colors || !t.rgba || !t.rgba8) {
		fprintf(stderr, "bench_resolve: setup failed: %s\n", t.f ? "buffers" : err);
		rc = 1;
		goto done;
	}
	printf("%s ids: %zu entries (%.2f a pixel), %.1f MB on the GPU, upload %.1f ms\n",
	       coherent ? "coherent" : "random", ne, (double)ne / (double)npix,
	       (double)gpu_ifb_bytes(t.f) / 1e6, create_ms);
	printf("| what | ms (median of %d) | per second |\n|---|---|---|\n", RUNS);
	for (t.level = 0; t.level < GPU_LEVELS; t.level++) {
		double ms = time_it(ctx, &t);
		if (ms < 0) {
			rc = 1;
			break;
		}
		if (t.level == GPU_LEVELS - 1)
			printf("| level 3 (final) | %.2f | %.0fM entries |\n", ms, (double)ne / ms * 1e-3);
		else
			printf("| level %d | %.2f | %.0fM pixels |\n", t.level, ms,
			       (double)npix / ms * 1e-3);
	}
	t.level = -1;
	double ms = rc ? -1 : time_it(ctx, &t);
	if (ms < 0)
		rc = 1;
	else
		printf("| sRGB8 encode | %.2f | %.0fM pixels |\n\n", ms, (double)npix / ms * 1e-3);
done:
	gpu_buffer_destroy(t.rgba8);
	gpu_buffer_destroy(t.rgba);
	gpu_buffer_destroy(t.colors);
	gpu_ifb_destroy(t.f);
	for (int L = 0; L < 3; L++) {
		free(lsample[L]);
		free(lweight[L]);
	}
	free(weight);
	free(sample);
	free(colors);
	free(alpha);
	free(offsets);
	return rc;
}

int main(void)
{
	char err[512];
	struct gpu_ctx *ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "SKIP: no GPU context, nothing measured: %s\n", err);
		return 77;
	}
	printf("GPU resolve, %dx%d, %d samples, on %s\n\n", W, H, NSAMPLES, gpu_renderer(ctx));
	int rc = run(ctx, true);
	if (!rc)
		rc = run(ctx, false);
	gpu_destroy(ctx);
	return rc;
}

/*
 * The GPU resolve against a CPU reference written here by the rules of
 * daemon/bake/resolve.c: random indirect framebuffers of odd sizes (partial
 * blocks, empty pixels, ids past the sample count, non-finite alphas and
 * weights, NaN and Inf colours), every level; and the 8-bit encoding
 * against reyes_srgb8 / reyes_unorm8, bit for bit. Skips (77), loudly,
 * without EGL.
 *
 * Tolerances: level 3 sums in float on the GPU and in double on the CPU, so
 * its colours are held to 1e-5 relative + 1e-6 absolute (colours and
 * weights are non-negative here, so no sum cancels to below the float
 * rounding of its terms). Everything else is
 * exact: a coarse colour is one float product (correctly rounded in GLSL),
 * alphas are prepared on the CPU, and the bytes come from exact comparisons.
 */
#include "test.h"
#include "resolve.h"
#include "png.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static struct gpu_ctx *ctx;
static uint64_t rng_state = 0x5eed1234abcdull;

static uint64_t rng(void)
{
	uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

static float unit(void)
{
	return (float)(rng() >> 40) / (float)(1u << 24);
}

/* A framebuffer with its arrays, as a shot holds it. */
struct fb {
	struct gpu_ifb_desc d;
	uint64_t *offsets;
	uint32_t *sample;
	float *weight, *alpha;
	uint32_t *lsample[3];
	float *lweight[3];
};

static const uint32_t side[3] = { 4, 2, 1 };

static uint32_t random_id(uint64_t nsamples)
{
	uint64_t r = rng() % 64;
	if (r == 0)
		return UINT32_MAX;
	if (r < 8)
		return (uint32_t)(nsamples + rng() % 100);  /* past the end */
	return (uint32_t)(rng() % nsamples);
}

static float odd_float(float usual)
{
	switch (rng() % 50) {
	case 0: return NAN;
	case 1: return INFINITY;
	case 2: return -INFINITY;
	default: return usual;
	}
}

static void fb_make(struct fb *f, uint32_t W, uint32_t H, uint64_t nsamples, int max_count,
		    bool odd_weights)
{
	memset(f, 0, sizeof(*f));
	size_t npix = (size_t)W * H;
	f->offsets = calloc(npix + 1, sizeof(*f->offsets));
	for (size_t p = 0; p < npix; p++) {
		/* A quarter of the pixels empty. */
		uint64_t n = rng() % 4 == 0 ? 0 : rng() % (uint64_t)(max_count + 1);
		f->offsets[p + 1] = f->offsets[p] + n;
	}
	size_t ne = f->offsets[npix];
	f->sample = malloc((ne + 1) * sizeof(*f->sample));
	f->weight = malloc((ne + 1) * sizeof(*f->weight));
	for (size_t e = 0; e < ne; e++) {
		f->sample[e] = random_id(nsamples);
		f->weight[e] = unit();
		if (odd_weights)
			f->weight[e] = odd_float(f->weight[e]);
	}
	f->alpha = malloc((npix + 1) * sizeof(*f->alpha));
	for (size_t p = 0; p < npix; p++)
		f->alpha[p] = odd_float(unit());
	for (int L = 0; L < 3; L++) {
		size_t nb = (size_t)((W + side[L] - 1) / side[L]) * ((H + side[L] - 1) / side[L]);
		f->lsample[L] = malloc((nb + 1) * sizeof(uint32_t));
		f->lweight[L] = malloc((nb + 1) * sizeof(float));
		for (size_t b = 0; b < nb; b++) {
			f->lsample[L][b] = random_id(nsamples);
			f->lweight[L][b] = odd_float(unit());
		}
		f->d.level_sample[L] = f->lsample[L];
		f->d.level_weight[L] = f->lweight[L];
	}
	f->d.width = W;
	f->d.height = H;
	f->d.offsets = f->offsets;
	f->d.sample = f->sample;
	f->d.weight = f->weight;
	f->d.alpha = f->alpha;
}

static void fb_free(struct fb *f)
{
	free(f->offsets);
	free(f->sample);
	free(f->weight);
	free(f->alpha);
	for (int L = 0; L < 3; L++) {
		free(f->lsample[L]);
		free(f->lweight[L]);
	}
}

/* daemon/bake/resolve.c's rules, written out again. */
static void reference(const struct fb *f, const float *Ci, uint64_t ns, int L, float *out)
{
	uint32_t W = f->d.width, H = f->d.height;
	if (L == 3) {
		for (size_t p = 0; p < (size_t)W * H; p++) {
			double c[3] = { 0, 0, 0 };
			for (uint64_t e = f->offsets[p]; e < f->offsets[p + 1]; e++) {
				if (f->sample[e] >= ns)
					continue;
				for (int k = 0; k < 3; k++)
					c[k] += (double)f->weight[e] * Ci[(size_t)f->sample[e] * 3 + k];
			}
			for (int k = 0; k < 3; k++)
				out[p * 4 + k] = isfinite(c[k]) ? (float)c[k] : 0.0f;
			out[p * 4 + 3] = isfinite(f->alpha[p]) ? f->alpha[p] : 0.0f;
		}
		return;
	}
	uint32_t B = side[L], nx = (W + B - 1) / B, ny = (H + B - 1) / B;
	float *ba = calloc((size_t)nx * ny, sizeof(float));
	for (uint32_t y = 0; y < H; y++)
		for (uint32_t x = 0; x < W; x++) {
			float a = f->alpha[(size_t)y * W + x];
			ba[(size_t)(y / B) * nx + x / B] += isfinite(a) ? a : 0.0f;
		}
	for (uint32_t y = 0; y < H; y++)
		for (uint32_t x = 0; x < W; x++) {
			size_t b = (size_t)(y / B) * nx + x / B, p = (size_t)y * W + x;
			uint32_t bx0 = x / B * B, by0 = y / B * B;
			uint32_t bw = bx0 + B < W ? B : W - bx0, bh = by0 + B < H ? B : H - by0;
			float w = isfinite(f->lweight[L][b]) ? f->lweight[L][b] : 0.0f;
			uint32_t id = f->lsample[L][b];
			for (int k = 0; k < 3; k++) {
				float v = id < ns ? w * Ci[(size_t)id * 3 + k] : 0.0f;
				out[p * 4 + k] = isfinite(v) ? v : 0.0f;
			}
			out[p * 4 + 3] = ba[b] / (float)(bw * bh);
		}
	free(ba);
}

static bool same_bits(float a, float b)
{
	return memcmp(&a, &b, sizeof(a)) == 0 || (a == 0.0f && b == 0.0f);
}

/* Resolve every level of a random framebuffer and compare. */
static void check_fb(uint32_t W, uint32_t H, uint64_t ns, int max_count, bool odd)
{
	struct fb f;
	fb_make(&f, W, H, ns, max_count, odd);
	float *Ci = malloc((ns * 3 + 1) * sizeof(float));
	for (uint64_t i = 0; i < ns * 3; i++)
		Ci[i] = odd ? odd_float(2.0f * unit()) : 2.0f * unit();
	size_t npix = (size_t)W * H;
	float *want = malloc(npix * 4 * sizeof(float));
	float *got = malloc(npix * 4 * sizeof(float));
	char err[256];
	struct gpu_ifb *g = gpu_ifb_create(ctx, &f.d, err, sizeof(err));
	if (!g)
		fprintf(stderr, "gpu_ifb_create: %s\n", err);
	CHECK(g != NULL);
	CHECK(gpu_ifb_bytes(g) >= f.offsets[npix] * 8 + npix * 8);
	struct gpu_buffer *colors = gpu_buffer_create(ctx, ns * 3 * sizeof(float) + 4, Ci);
	struct gpu_buffer *out = gpu_buffer_create(ctx, npix * 4 * sizeof(float), NULL);
	CHECK(colors && out);
	for (int L = 0; g && colors && out && L < GPU_LEVELS; L++) {
		reference(&f, Ci, ns, L, want);
		memset(got, 0xff, npix * 4 * sizeof(float));  /* NaNs: unwritten shows */
		CHECK(gpu_ifb_resolve(g, colors, ns, L, out));
		CHECK(gpu_buffer_read(out, 0, npix * 4 * sizeof(float), got));
		size_t bad = 0, nonfinite = 0;
		double worst = 0;
		for (size_t i = 0; i < npix * 4; i++) {
			nonfinite += !isfinite(got[i]);
			bool ok;
			if (L == 3 && i % 4 != 3) {
				double d = fabs((double)got[i] - want[i]);
				ok = d <= 1e-5 * fabs(want[i]) + 1e-6;
				if (d > worst)
					worst = d;
			} else {
				ok = same_bits(got[i], want[i]);
			}
			if (!ok && bad++ < 3)
				fprintf(stderr, "%ux%u level %d: pixel %zu channel %zu: %.9g, expected "
					"%.9g\n", W, H, L, i / 4, i % 4, got[i], want[i]);
		}
		CHECK(bad == 0);
		CHECK(nonfinite == 0);
		if (L == 3)
			printf("%ux%u, %llu entries: level 3 largest difference %.3g\n", W, H,
			       (unsigned long long)f.offsets[npix], worst);
	}
	gpu_buffer_destroy(out);
	gpu_buffer_destroy(colors);
	gpu_ifb_destroy(g);
	free(got);
	free(want);
	free(Ci);
	fb_free(&f);
}

static void test_levels(void)
{
	check_fb(37, 23, 500, 6, false);    /* partial 4x4 and 2x2 blocks */
	check_fb(1, 1, 3, 8, false);
	check_fb(1, 19, 40, 3, false);
	check_fb(130, 7, 2000, 8, false);
	check_fb(64, 64, 100000, 4, false); /* whole blocks, sparse ids */
}

/* Non-finite weights, alphas and colours: zeros where the CPU gives them, never NaN. */
static void test_nonfinite(void)
{
	check_fb(37, 23, 300, 6, true);
	check_fb(33, 9, 50, 8, true);
}

static void test_empty(void)
{
	/* No entries at all: every pixel black, alpha kept. */
	check_fb(9, 5, 10, 0, false);
}

static void test_refused(void)
{
	struct fb f;
	fb_make(&f, 7, 5, 20, 3, false);
	char err[256];
	struct gpu_ifb *g = gpu_ifb_create(ctx, &f.d, err, sizeof(err));
	CHECK(g != NULL);
	struct gpu_buffer *colors = gpu_buffer_create(ctx, 20 * 3 * sizeof(float), NULL);
	struct gpu_buffer *out = gpu_buffer_create(ctx, 35 * 4 * sizeof(float), NULL);
	printf("expect errors for levels -1, 4 and a missing level 1:\n");
	fflush(stdout);
	CHECK(!gpu_ifb_resolve(g, colors, 20, -1, out));
	CHECK(!gpu_ifb_resolve(g, colors, 20, GPU_LEVELS, out));
	CHECK(!gpu_ifb_resolve(g, NULL, 20, 3, out));
	CHECK(!gpu_ifb_resolve(NULL, colors, 20, 3, out));
	CHECK(!gpu_ifb_resolve(g, colors, (uint64_t)1 << 40, 3, out));
	CHECK(gpu_ifb_resolve(g, colors, 20, 3, out));
	gpu_ifb_destroy(g);

	/* A framebuffer without level 1 refuses only that level. */
	f.d.level_sample[1] = NULL;
	f.d.level_weight[1] = NULL;
	g = gpu_ifb_create(ctx, &f.d, err, sizeof(err));
	CHECK(g != NULL);
	CHECK(!gpu_ifb_resolve(g, colors, 20, 1, out));
	CHECK(gpu_ifb_resolve(g, colors, 20, 0, out));
	gpu_ifb_destroy(g);
	/* Ids without weights. */
	f.d.level_sample[1] = f.lsample[1];
	g = gpu_ifb_create(ctx, &f.d, err, sizeof(err));
	CHECK(g == NULL && strstr(err, "level 1"));

	/* Decreasing offsets, a first offset not 0, more than 2^32 - 1 entries. */
	f.d.level_sample[1] = NULL;
	uint64_t keep = f.offsets[3];
	f.offsets[3] = f.offsets[2] + 1000;
	g = gpu_ifb_create(ctx, &f.d, err, sizeof(err));
	CHECK(g == NULL && strstr(err, "decrease"));
	f.offsets[3] = keep;
	uint64_t big[2] = { 0, (uint64_t)UINT32_MAX + 1 };
	float a = 1.0f;
	struct gpu_ifb_desc d = { .width = 1, .height = 1, .offsets = big, .alpha = &a };
	g = gpu_ifb_create(ctx, &d, err, sizeof(err));
	CHECK(g == NULL && strstr(err, "2^32"));
	big[0] = 1;
	g = gpu_ifb_create(ctx, &d, err, sizeof(err));
	CHECK(g == NULL && strstr(err, "first offset"));
	CHECK(gpu_ifb_create(ctx, NULL, err, sizeof(err)) == NULL);
	gpu_buffer_destroy(out);
	gpu_buffer_destroy(colors);
	fb_free(&f);
}

/* The smallest float in [0, 1] where @enc reaches @k, by bisection. */
static float first_at(uint8_t (*enc)(float), unsigned k)
{
	uint32_t lo = 0, hi = 0x3f800000u;
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		float m;
		memcpy(&m, &mid, sizeof(m));
		if (enc(m) >= k)
			hi = mid;
		else
			lo = mid;
	}
	float h;
	memcpy(&h, &hi, sizeof(h));
	return h;
}

static void test_encode(void)
{
	enum { EVEN = 1 << 16 };
	/* Values: evenly spaced, each step of either encoding and its neighbours, specials. */
	size_t cap = EVEN + 2 * 255 * 3 + 16, n = 0;
	float *v = malloc(cap * sizeof(float));
	for (int i = 0; i < EVEN; i++)
		v[n++] = -0.1f + 1.3f * (float)i / (float)(EVEN - 1);
	for (unsigned k = 1; k < 256; k++)
		for (int e = 0; e < 2; e++) {
			float t = first_at(e ? reyes_unorm8 : reyes_srgb8, k);
			v[n++] = nextafterf(t, -INFINITY);
			v[n++] = t;
			v[n++] = nextafterf(t, INFINITY);
		}
	const float special[] = { NAN, -NAN, INFINITY, -INFINITY, 0.0f, -0.0f, 1.0f, FLT_MAX,
				  -FLT_MAX, FLT_MIN, 1e-40f, 0.0031308f, 0.5f, 0.999999f };
	for (size_t i = 0; i < sizeof(special) / sizeof(special[0]); i++)
		v[n++] = special[i];
	/* Every value goes through every channel: pixel i has v[i], v[i+1], v[i+2], v[i+3]. */
	float *rgba = malloc(n * 4 * sizeof(float));
	for (size_t i = 0; i < n; i++)
		for (int c = 0; c < 4; c++)
			rgba[i * 4 + c] = v[(i + (size_t)c) % n];
	struct gpu_buffer *in = gpu_buffer_create(ctx, n * 4 * sizeof(float), rgba);
	struct gpu_buffer *out = gpu_buffer_create(ctx, n * sizeof(uint32_t), NULL);
	uint32_t *got = malloc(n * sizeof(uint32_t));
	CHECK(in && out && got);
	CHECK(gpu_encode_srgb8(ctx, in, (uint32_t)n, out));
	CHECK(gpu_buffer_read(out, 0, n * sizeof(uint32_t), got));
	size_t bad = 0;
	for (size_t i = 0; i < n; i++) {
		const float *p = rgba + i * 4;
		uint32_t want = reyes_srgb8(p[0]) | (uint32_t)reyes_srgb8(p[1]) << 8 |
				(uint32_t)reyes_srgb8(p[2]) << 16 | (uint32_t)reyes_unorm8(p[3]) << 24;
		if (got[i] != want && bad++ < 5)
			fprintf(stderr, "pixel %zu (%.9g %.9g %.9g %.9g): %08x, expected %08x\n", i,
				p[0], p[1], p[2], p[3], got[i], want);
	}
	CHECK(bad == 0);
	printf("sRGB8: %zu pixels, %zu differ from the CPU\n", n, bad);
	/* The specials, spelled out. */
	CHECK(reyes_srgb8(NAN) == 0 && reyes_srgb8(INFINITY) == 255 && reyes_unorm8(NAN) == 0);
	CHECK(!gpu_encode_srgb8(ctx, NULL, 1, out));
	gpu_buffer_destroy(in);
	gpu_buffer_destroy(out);
	free(got);
	free(rgba);
	free(v);
}

int main(void)
{
	char err[512];
	ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "SKIP: no GPU context, the GPU resolve is NOT tested: %s\n", err);
		return 77;
	}
	printf("renderer: %s\n", gpu_renderer(ctx));
	RUN(test_levels);
	RUN(test_nonfinite);
	RUN(test_empty);
	RUN(test_refused);
	RUN(test_encode);
	gpu_destroy(ctx);
	return test_finish();
}

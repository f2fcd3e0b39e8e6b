/*
 * The image error measures against values worked out by hand: identical
 * images, one changed sample, the relative difference's floor, non-finite
 * values, the alpha path (no transfer function), strides and channel maps,
 * and the per-pixel map in percent.
 */
#include "imgerr.h"

#include "test.h"

#include <stdint.h>

/* The sRGB transfer, written out here in double precision. */
static double srgb(double v)
{
	v = v < 0.0 ? 0.0 : v > 1.0 ? 1.0 : v;
	return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

/* @w x @h RGBA pixels, every channel @v. */
static float *flat(uint32_t w, uint32_t h, float v)
{
	float *p = malloc((size_t)w * h * 4 * sizeof(*p));
	for (size_t i = 0; p && i < (size_t)w * h * 4; i++)
		p[i] = v;
	return p;
}

static void test_identical(void)
{
	float *a = flat(3, 2, 0.25f), *b = flat(3, 2, 0.25f);
	float map[6] = { -1, -1, -1, -1, -1, -1 };
	struct img_error e;
	memset(&e, 0x55, sizeof(e)); /* garbage: the measure clears it */
	img_error_rgba(a, b, 3, 2, map, &e);
	CHECK(e.samples == 18);
	CHECK_NEAR(img_error_rmse(&e), 0.0, 0.0);
	CHECK_NEAR(img_error_mean_pct(&e), 0.0, 0.0);
	CHECK_NEAR(img_error_max_pct(&e), 0.0, 0.0);
	CHECK(isnan(img_error_psnr_db(&e)));
	CHECK(e.over_1pct == 0 && e.max_x == 0 && e.max_y == 0 && e.max_rel == 0.0);
	CHECK(e.nonfinite[0] == 0 && e.nonfinite[1] == 0);
	for (int i = 0; i < 6; i++)
		CHECK(map[i] == 0.0f);
	free(a);
	free(b);

	/* Nothing compared: all zero, and the derived measures are defined. */
	img_error_measure(NULL, 4, NULL, NULL, 4, NULL, 3, 2, 2, true, NULL, &e);
	CHECK(e.samples == 0 && img_error_rmse(&e) == 0.0 && img_error_mean_pct(&e) == 0.0);
	CHECK(isnan(img_error_psnr_db(&e)));
}

static void test_one_sample(void)
{
	/* 4 x 3 pixels of 0.25; in b, the G of pixel (2, 1) is 0.5. */
	float *a = flat(4, 3, 0.25f), *b = flat(4, 3, 0.25f);
	b[(1 * 4 + 2) * 4 + 1] = 0.5f;
	float map[12];
	struct img_error e;
	img_error_rgba(a, b, 4, 3, map, &e);
	double d = srgb(0.5) - srgb(0.25); /* 0.1982583 */
	CHECK(e.samples == 36);
	CHECK_NEAR(img_error_rmse(&e), sqrt(0.0625 / 36.0), 1e-12);
	CHECK_NEAR(img_error_mean_pct(&e), 100.0 * d / 36.0, 1e-5);
	CHECK_NEAR(img_error_max_pct(&e), 100.0 * d, 1e-5);
	CHECK_NEAR(img_error_max_pct(&e), 19.825825, 1e-5);
	CHECK_NEAR(img_error_psnr_db(&e), -10.0 * log10(d * d / 36.0), 1e-5);
	CHECK(e.max_x == 2 && e.max_y == 1);
	CHECK(e.over_1pct == 1);
	CHECK_NEAR(e.max_rel, 0.5, 1e-12);
	CHECK_NEAR(e.sum_lin2, 0.0625, 1e-12);
	for (int i = 0; i < 12; i++)
		CHECK_NEAR(map[i], i == 6 ? 100.0 * d : 0.0, 1e-4);
	free(a);
	free(b);
}

static void test_first_max(void)
{
	/* Two pixels with the same, largest error: the first in scanline order is reported. */
	float *a = flat(3, 3, 0.0f), *b = flat(3, 3, 0.0f);
	b[(2 * 3 + 0) * 4 + 0] = 1.0f;     /* (0, 2) */
	b[(1 * 3 + 2) * 4 + 2] = 1.0f;     /* (2, 1): earlier in scanline order */
	b[(0 * 3 + 1) * 4 + 1] = 0.5f;     /* (1, 0): smaller */
	struct img_error e;
	img_error_rgba(a, b, 3, 3, NULL, &e);
	CHECK(e.max_x == 2 && e.max_y == 1);
	CHECK_NEAR(img_error_max_pct(&e), 100.0, 1e-9);
	CHECK(e.over_1pct == 3);
	free(a);
	free(b);
}

static void test_relative_floor(void)
{
	/* One channel, no transfer: |a - b| / max(|a|, |b|, 1e-3). */
	static const int c0[1] = { 0 };
	struct img_error e;
	float a1[1] = { 0.0005f }, b1[1] = { 0.0f };
	img_error_measure(a1, 1, c0, b1, 1, c0, 1, 1, 1, false, NULL, &e);
	CHECK_NEAR(e.max_rel, 0.5, 1e-6);       /* not 1: the floor */
	float a2[1] = { 1e-4f }, b2[1] = { 2e-4f };
	img_error_measure(a2, 1, c0, b2, 1, c0, 1, 1, 1, false, NULL, &e);
	CHECK_NEAR(e.max_rel, 0.1, 1e-6);
	float a3[1] = { 2.0f }, b3[1] = { -1.0f };
	img_error_measure(a3, 1, c0, b3, 1, c0, 1, 1, 1, false, NULL, &e);
	CHECK_NEAR(e.max_rel, 1.5, 1e-12);      /* above the floor: relative to the larger */
	CHECK_NEAR(img_error_rmse(&e), 3.0, 1e-12);
	/* Displayed, they clamp to the two ends of the range: all of it. */
	CHECK_NEAR(img_error_max_pct(&e), 100.0, 1e-12);
}

static void test_nonfinite(void)
{
	/* 4 x 2 pixels of 0.25; a NaN G at (1, 0) in a; an infinite R at (3, 1) in b. */
	float *a = flat(4, 2, 0.25f), *b = flat(4, 2, 0.25f);
	a[(0 * 4 + 1) * 4 + 1] = NAN;
	b[(1 * 4 + 3) * 4 + 0] = INFINITY;
	/* Both non-finite in one sample: counted in each image, one sample of error. */
	a[(1 * 4 + 0) * 4 + 2] = -INFINITY;
	b[(1 * 4 + 0) * 4 + 2] = NAN;
	float map[8];
	struct img_error e;
	img_error_rgba(a, b, 4, 2, map, &e);
	CHECK(e.nonfinite[0] == 2 && e.nonfinite[1] == 2);
	CHECK(e.samples == 24);
	CHECK_NEAR(img_error_max_pct(&e), 100.0, 0.0);
	CHECK(e.max_x == 1 && e.max_y == 0);
	CHECK(e.over_1pct == 3);
	CHECK_NEAR(img_error_mean_pct(&e), 300.0 / 24.0, 1e-9);
	CHECK_NEAR(img_error_rmse(&e), sqrt(3.0 / 24.0), 1e-12);
	CHECK_NEAR(img_error_psnr_db(&e), -10.0 * log10(3.0 / 24.0), 1e-9);
	CHECK(isfinite(e.max_rel) && e.max_rel == 0.0);
	for (int i = 0; i < 8; i++)
		CHECK_NEAR(map[i], (i == 1 || i == 7 || i == 4) ? 100.0 : 0.0, 0.0);
	free(a);
	free(b);
}

static void test_alpha(void)
{
	/* Alpha alone (channel 3), no transfer: 0.5 against 0.25 is 25 %. */
	static const int ca[1] = { 3 };
	float a[3 * 4] = { 0, 0, 0, 0.5f, 0, 0, 0, 0.5f, 0, 0, 0, 2.0f };
	float b[3 * 4] = { 0, 0, 0, 0.25f, 0, 0, 0, 0.509f, 0, 0, 0, 1.0f };
	float map[3];
	struct img_error e;
	img_error_measure(a, 4, ca, b, 4, ca, 1, 3, 1, false, map, &e);
	CHECK(e.samples == 3);
	CHECK_NEAR(map[0], 25.0, 1e-5);
	CHECK_NEAR(map[1], 0.9, 1e-4);          /* 0.009: not over 1 % */
	CHECK_NEAR(map[2], 0.0, 0.0);           /* 2 and 1 both clamp to 1 */
	CHECK(e.over_1pct == 1);
	CHECK_NEAR(img_error_max_pct(&e), 25.0, 1e-5);
	CHECK(e.max_x == 0 && e.max_y == 0);
	/* The linear RMSE sees the clamped-away difference of 1. */
	double lin2 = 0.0625 + 0.009 * 0.009 + 1.0;
	CHECK_NEAR(img_error_rmse(&e), sqrt(lin2 / 3.0), 1e-6);
	/* Through sRGB the same values would differ by more than 25 %: the path matters. */
	struct img_error s;
	img_error_measure(a, 4, ca, b, 4, ca, 1, 3, 1, true, NULL, &s);
	CHECK_NEAR(img_error_max_pct(&s), 100.0 * (srgb(0.5) - srgb(0.25)), 1e-4);

	/* A known PSNR: every sample 0.1 apart is 20 dB. */
	float c[4] = { 0.5f, 0.5f, 0.5f, 0.5f }, d[4] = { 0.4f, 0.4f, 0.4f, 0.4f };
	static const int c0[1] = { 0 };
	img_error_measure(c, 1, c0, d, 1, c0, 1, 2, 2, false, NULL, &e);
	CHECK_NEAR(img_error_psnr_db(&e), 20.0, 1e-5);
	CHECK_NEAR(img_error_mean_pct(&e), 10.0, 1e-5);
}

static void test_strides(void)
{
	/* RGBA against BGR (stride 3, channels reversed): the same as RGBA against RGBA. */
	enum { W = 5, H = 4 };
	float *a = flat(W, H, 0.0f), *b4 = flat(W, H, 0.0f);
	float *b3 = malloc(sizeof(float) * W * H * 3);
	for (int p = 0; p < W * H; p++) {
		for (int k = 0; k < 3; k++) {
			a[p * 4 + k] = (float)((p * 7 + k * 3) % 11) / 10.0f;
			b4[p * 4 + k] = (float)((p * 5 + k) % 13) / 12.0f;
			b3[p * 3 + (2 - k)] = b4[p * 4 + k];
		}
	}
	static const int rgb[3] = { 0, 1, 2 }, bgr[3] = { 2, 1, 0 };
	struct img_error e1, e2;
	float m1[W * H], m2[W * H];
	img_error_rgba(a, b4, W, H, m1, &e1);
	img_error_measure(a, 4, rgb, b3, 3, bgr, 3, W, H, true, m2, &e2);
	CHECK(memcmp(&e1, &e2, sizeof(e1)) == 0);
	CHECK(memcmp(m1, m2, sizeof(m1)) == 0);
	CHECK(e1.samples == W * H * 3 && e1.max_enc > 0.0);
	free(a);
	free(b4);
	free(b3);
}

int main(void)
{
	RUN(test_identical);
	RUN(test_one_sample);
	RUN(test_first_max);
	RUN(test_relative_floor);
	RUN(test_nonfinite);
	RUN(test_alpha);
	RUN(test_strides);
	return test_finish();
}

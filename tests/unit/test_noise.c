/* Tests of the noise library: range, mean, continuity, periodicity, cells, determinism. */
#include "noise.h"
#include "test.h"

#include <stdint.h>

/* A small deterministic generator for sample positions. */
static uint32_t lcg_state = 12345;

static float lcg_float(float lo, float hi)
{
	lcg_state = lcg_state * 1664525U + 1013904223U;
	return lo + (hi - lo) * (float)(lcg_state >> 8) * (1.0f / 16777216.0f);
}

static void test_range_and_mean(void)
{
	/* Extremes documented in noise.h, with a small margin. */
	static const float doc_min[5] = { 0, 0.10f, 0.025f, 0.015f, 0.015f };
	static const float doc_max[5] = { 0, 0.935f, 0.975f, 0.985f, 0.995f };
	for (int dim = 1; dim <= 4; dim++) {
		double mn = 1.0, mx = 0.0, sum = 0.0;
		const int n = 1 << 20;
		lcg_state = 777u + (uint32_t)dim;
		for (int k = 0; k < n; k++) {
			float p[4];
			for (int d = 0; d < dim; d++)
				p[d] = lcg_float(-32.0f, 32.0f);
			float v = sl_noise(dim, p, NULL, 0);
			mn = v < mn ? v : mn;
			mx = v > mx ? v : mx;
			sum += v;
		}
		CHECK(mn >= 0.0 && mx <= 1.0);
		CHECK(mn >= doc_min[dim]);
		CHECK(mx <= doc_max[dim]);
		/* It does use most of its range. */
		CHECK(mn < 0.25 && mx > 0.75);
		CHECK_NEAR(sum / n, 0.5, 0.005);
	}
}

static void test_lattice_is_half(void)
{
	CHECK_NEAR(sl_noise1(3.0f), 0.5, 1e-7);
	CHECK_NEAR(sl_noise2(-2.0f, 7.0f), 0.5, 1e-7);
	CHECK_NEAR(sl_noise3(1.0f, 0.0f, -5.0f), 0.5, 1e-7);
	CHECK_NEAR(sl_noise4(1.0f, 2.0f, 3.0f, 4.0f), 0.5, 1e-7);
	/* And not constant between lattice points. */
	CHECK(fabsf(sl_noise3(0.3f, 0.6f, 0.2f) - 0.5f) > 1e-4f ||
	      fabsf(sl_noise3(1.3f, 2.6f, 0.7f) - 0.5f) > 1e-4f);
}

static void test_continuity(void)
{
	/*
	 * The gradient is bounded (by the fade's slope 1.875 times the gradient
	 * sums, times the scale): over a step h the change stays below ~4h even
	 * across cell boundaries.
	 */
	const float h = 1e-3f;
	for (int dim = 1; dim <= 4; dim++) {
		double worst = 0.0;
		lcg_state = 99u + (uint32_t)dim;
		for (int k = 0; k < 20000; k++) {
			float p[4], q[4];
			for (int d = 0; d < dim; d++) {
				p[d] = lcg_float(-8.0f, 8.0f);
				q[d] = p[d] + (d == k % dim ? h : 0.0f);
			}
			double dv = fabs((double)sl_noise(dim, p, NULL, 0) - sl_noise(dim, q, NULL, 0));
			worst = dv > worst ? dv : worst;
		}
		CHECK(worst < 4.0 * h);
	}
	/* Straddling a cell boundary exactly. */
	CHECK_NEAR(sl_noise1(2.0f - 1e-4f), sl_noise1(2.0f + 1e-4f), 1e-3);
	CHECK_NEAR(sl_noise3(0.5f, 1.0f - 1e-4f, 0.25f), sl_noise3(0.5f, 1.0f + 1e-4f, 0.25f), 1e-3);
}

static void test_periodic(void)
{
	int32_t per[4] = { 4, 3, 5, 2 };
	lcg_state = 4242;
	for (int dim = 1; dim <= 4; dim++) {
		for (int k = 0; k < 200; k++) {
			float p[4], q[4];
			for (int d = 0; d < dim; d++)
				p[d] = lcg_float(-10.0f, 10.0f);
			for (int d = 0; d < dim; d++) {
				/* Shift one dimension by a multiple of its period. */
				for (int e = 0; e < dim; e++)
					q[e] = p[e];
				q[d] = p[d] + (float)(per[d] * (k % 3 - 1));
				CHECK_NEAR(sl_noise(dim, p, per, 0), sl_noise(dim, q, per, 0), 2e-5);
			}
		}
	}
	/* Without a period it does not repeat. */
	int differ = 0;
	for (int k = 0; k < 50; k++) {
		float x = 0.37f + (float)k * 0.13f;
		if (fabsf(sl_noise1(x) - sl_noise1(x + 4.0f)) > 1e-3f)
			differ++;
	}
	CHECK(differ > 40);
	/* Period <= 0 means non-periodic in that dimension only. */
	int32_t mixed[2] = { 0, 3 };
	float a[2] = { 0.3f, 0.7f }, b[2] = { 0.3f, 3.7f }, c[2] = { 3.3f, 0.7f };
	CHECK_NEAR(sl_noise(2, a, mixed, 0), sl_noise(2, b, mixed, 0), 2e-5);
	CHECK(fabsf(sl_noise(2, a, mixed, 0) - sl_noise(2, c, mixed, 0)) > 1e-6f ||
	      sl_noise(2, a, NULL, 0) != sl_noise(2, c, NULL, 0));
	/* Periodic noise matches plain noise inside the first period. */
	float in[3] = { 0.4f, 0.2f, 0.9f };
	int32_t p3[3] = { 8, 8, 8 };
	CHECK_NEAR(sl_noise(3, in, p3, 0), sl_noise(3, in, NULL, 0), 1e-6);
	CHECK(sl_noise_period(3.4f) == 3 && sl_noise_period(0.0f) == 0 &&
	      sl_noise_period(-2.0f) == 0 && sl_noise_period(2.5f) == 3);
}

static void test_cellnoise(void)
{
	/* Constant within a cell. */
	for (int dim = 1; dim <= 4; dim++) {
		float base[4] = { 2.0f, -3.0f, 5.0f, 0.0f };
		float v0 = sl_cellnoise(dim, base, 0);
		CHECK(v0 >= 0.0f && v0 < 1.0f);
		for (int k = 0; k < 100; k++) {
			float p[4];
			for (int d = 0; d < dim; d++)
				p[d] = base[d] + lcg_float(0.0f, 0.999f);
			CHECK(sl_cellnoise(dim, p, 0) == v0);
		}
	}
	/* Different across cells: 1000 cells give (almost) all distinct values
	 * with a mean near 0.5. */
	double sum = 0.0;
	int same_as_next = 0;
	for (int k = 0; k < 1000; k++) {
		float p[3] = { (float)k + 0.5f, 0.5f, 0.5f };
		float q[3] = { (float)k + 1.5f, 0.5f, 0.5f };
		float v = sl_cellnoise(3, p, 0);
		CHECK(v >= 0.0f && v < 1.0f);
		sum += v;
		if (v == sl_cellnoise(3, q, 0))
			same_as_next++;
	}
	CHECK(same_as_next == 0);
	CHECK_NEAR(sum / 1000.0, 0.5, 0.05);
	/* Negative coordinates floor correctly: -0.5 is in cell -1, not 0. */
	float neg[1] = { -0.5f }, neg2[1] = { -0.01f }, pos[1] = { 0.5f };
	CHECK(sl_cellnoise(1, neg, 0) == sl_cellnoise(1, neg2, 0));
	CHECK(sl_cellnoise(1, neg, 0) != sl_cellnoise(1, pos, 0));
}

static void test_vector_channels(void)
{
	/* The three channels are decorrelated: over many points the correlation
	 * between channels is small. */
	const int n = 20000;
	double s[3] = { 0 }, ss[3] = { 0 }, sxy = 0, sxz = 0;
	lcg_state = 31337;
	for (int k = 0; k < n; k++) {
		float p[3] = { lcg_float(-20, 20), lcg_float(-20, 20), lcg_float(-20, 20) };
		float v[3];
		sl_vnoise(3, p, NULL, v);
		for (int c = 0; c < 3; c++) {
			CHECK(v[c] >= 0.0f && v[c] <= 1.0f);
			s[c] += v[c];
			ss[c] += (double)v[c] * v[c];
		}
		sxy += (double)v[0] * v[1];
		sxz += (double)v[0] * v[2];
	}
	double m0 = s[0] / n, m1 = s[1] / n, m2 = s[2] / n;
	double v0 = ss[0] / n - m0 * m0, v1 = ss[1] / n - m1 * m1, v2 = ss[2] / n - m2 * m2;
	double cxy = (sxy / n - m0 * m1) / sqrt(v0 * v1);
	double cxz = (sxz / n - m0 * m2) / sqrt(v0 * v2);
	CHECK(fabs(cxy) < 0.05);
	CHECK(fabs(cxz) < 0.05);
	/* Vector cellnoise also differs per channel. */
	float p[2] = { 1.5f, 2.5f }, c3[3];
	sl_vcellnoise(2, p, c3);
	CHECK(c3[0] != c3[1] && c3[1] != c3[2]);
}

static void test_determinism(void)
{
	/* Fixed values pin the hash and the interpolation down across platforms
	 * (and for the GLSL port): these are the values this implementation
	 * produced when written. */
	CHECK(sl_hash_mix(0) == 0);
	CHECK(sl_hash_mix(1) != 1);
	int32_t ip[3] = { 1, 2, 3 };
	uint32_t h = sl_hash_lattice(3, ip, 0);
	CHECK(h == 2616821524U);
	CHECK(h != sl_hash_lattice(3, ip, 1));
	/* Hash-derived values are exact; interpolated ones within float rounding. */
	CHECK_NEAR(sl_noise3(0.25f, 1.5f, -2.75f), 0.600947499, 1e-6);
	CHECK_NEAR(sl_noise1(0.5f), 0.6933707, 1e-6);
	float cp[2] = { 1.5f, 2.5f };
	CHECK(sl_cellnoise(2, cp, 0) == 0x1.8c0474p-2f);
	float r1 = sl_random(7, 100, 3);
	CHECK(r1 == 0x1.60a4ecp-1f);
	CHECK(r1 != sl_random(7, 101, 3));
	CHECK(r1 != sl_random(7, 100, 4));
	CHECK(r1 != sl_random(8, 100, 3));
	/* random is uniform in [0,1). */
	double sum = 0.0;
	int bins[10] = { 0 };
	for (uint32_t i = 0; i < 100000; i++) {
		float r = sl_random(1, i, 0);
		CHECK(r >= 0.0f && r < 1.0f);
		sum += r;
		bins[(int)(r * 10.0f)]++;
	}
	CHECK_NEAR(sum / 100000.0, 0.5, 0.005);
	for (int b = 0; b < 10; b++)
		CHECK(bins[b] > 9500 && bins[b] < 10500);
}

static void test_bad_input(void)
{
	float nanv = NAN, inf = INFINITY;
	float v = sl_noise1(nanv);
	CHECK(v == v && v >= 0.0f && v <= 1.0f);
	v = sl_noise3(inf, -inf, 1e30f);
	CHECK(v == v && v >= 0.0f && v <= 1.0f);
	float p[1] = { nanv };
	v = sl_cellnoise(1, p, 0);
	CHECK(v == v && v >= 0.0f && v < 1.0f);
	CHECK(sl_noise(0, p, NULL, 0) == 0.5f);
	CHECK(sl_noise(5, p, NULL, 0) == 0.5f);
	CHECK(sl_noise_period(nanv) == 0);
}

int main(void)
{
	RUN(test_range_and_mean);
	RUN(test_lattice_is_half);
	RUN(test_continuity);
	RUN(test_periodic);
	RUN(test_cellnoise);
	RUN(test_vector_channels);
	RUN(test_determinism);
	RUN(test_bad_input);
	return test_finish();
}

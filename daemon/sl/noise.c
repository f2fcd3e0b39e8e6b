/*
 * Lattice noise for RSL. The structure is kept simple enough to be written
 * the same way in GLSL: integer hash per lattice corner, a gradient chosen
 * from the hash bits (no tables), quintic fade, multilinear blend.
 */
#include "noise.h"

#include <math.h>
#include <stddef.h>

/* Coordinates are clamped to this magnitude so that floor() fits an int32. */
#define LATTICE_LIMIT 1073741824.0f

/*
 * Per-dimension scale taking the raw gradient-noise value to a little inside
 * [-1,1] before the remap to [0,1], so that the final clamp almost never
 * flattens a peak. Chosen from dense samples (see noise.h for the extremes).
 */
static const float noise_scale[5] = { 0.0f, 2.0f, 1.41421356f, 0.95f, 0.8f };

uint32_t sl_hash_mix(uint32_t h)
{
	/* Two multiply-xorshift rounds: every input bit reaches every output bit. */
	h ^= h >> 16;
	h *= 0x7feb352dU;
	h ^= h >> 15;
	h *= 0x846ca68bU;
	h ^= h >> 16;
	return h;
}

uint32_t sl_hash_lattice(int dim, const int32_t *ip, uint32_t seed)
{
	uint32_t h = sl_hash_mix(seed * 0x9e3779b9U + 0x632be5abU);
	for (int d = 0; d < dim; d++)
		h = sl_hash_mix(h ^ (uint32_t)ip[d]);
	return h;
}

float sl_hash_unit(uint32_t h)
{
	return (float)(h >> 8) * (1.0f / 16777216.0f);
}

/* Split @x into its floor (as an integer) and fraction. */
static int32_t lattice(float x, float *frac)
{
	if (!(x == x))
		x = 0.0f;
	if (x > LATTICE_LIMIT)
		x = LATTICE_LIMIT;
	if (x < -LATTICE_LIMIT)
		x = -LATTICE_LIMIT;
	float fl = floorf(x);
	*frac = x - fl;
	return (int32_t)fl;
}

static int32_t wrap(int32_t i, int32_t period)
{
	if (period <= 0)
		return i;
	int32_t m = i % period;
	return m < 0 ? m + period : m;
}

/* The quintic 6t^5 - 15t^4 + 10t^3: C2 continuity across cells. */
static float fade(float t)
{
	return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}

/* Dot product of the gradient selected by @h with the offset @f. */
static float grad(int dim, uint32_t h, const float *f)
{
	switch (dim) {
	case 1:
		return (sl_hash_unit(h) * 2.0f - 1.0f) * f[0];
	case 2: {
		/* Eight unit directions: the four axes and the four diagonals. */
		uint32_t k = h >> 29;
		if (k < 4) {
			float g = (k & 1) ? f[1] : f[0];
			return (k & 2) ? -g : g;
		}
		const float r = 0.70710678f;
		return ((k & 1) ? -f[0] : f[0]) * r + ((k & 2) ? -f[1] : f[1]) * r;
	}
	case 3: {
		/* The twelve cube-edge directions (four of them twice). */
		uint32_t k = h >> 28;
		float a = k < 8 ? f[0] : f[1];
		float b = k < 4 ? f[1] : (k == 12 || k == 14) ? f[0] : f[2];
		return ((k & 1) ? -a : a) + ((k & 2) ? -b : b);
	}
	default: {
		/* The 32 directions with one zero coordinate and three +-1. */
		uint32_t k = h >> 27;
		uint32_t zero = k >> 3;
		float s = 0.0f;
		uint32_t bit = 0;
		for (uint32_t d = 0; d < 4; d++) {
			if (d == zero)
				continue;
			s += ((k >> bit) & 1) ? -f[d] : f[d];
			bit++;
		}
		return s;
	}
	}
}

float sl_noise(int dim, const float *p, const int32_t *period, uint32_t seed)
{
	if (dim < 1 || dim > 4)
		return 0.5f;
	int32_t i0[4];
	float f[4], w[4], v[16];
	for (int d = 0; d < dim; d++) {
		i0[d] = lattice(p[d], &f[d]);
		w[d] = fade(f[d]);
	}
	int ncorner = 1 << dim;
	for (int c = 0; c < ncorner; c++) {
		int32_t ic[4];
		float off[4];
		for (int d = 0; d < dim; d++) {
			int bit = (c >> d) & 1;
			ic[d] = wrap(i0[d] + bit, period ? period[d] : 0);
			off[d] = f[d] - (float)bit;
		}
		v[c] = grad(dim, sl_hash_lattice(dim, ic, seed), off);
	}
	/* Blend along dimension 0 first: corners 2k and 2k+1 differ in bit 0. */
	for (int d = 0; d < dim; d++) {
		ncorner >>= 1;
		for (int k = 0; k < ncorner; k++)
			v[k] = v[2 * k] + w[d] * (v[2 * k + 1] - v[2 * k]);
	}
	float r = 0.5f + 0.5f * noise_scale[dim] * v[0];
	return r < 0.0f ? 0.0f : r > 1.0f ? 1.0f : r;
}

float sl_noise1(float x)
{
	return sl_noise(1, &x, NULL, 0);
}

float sl_noise2(float x, float y)
{
	float p[2] = { x, y };
	return sl_noise(2, p, NULL, 0);
}

float sl_noise3(float x, float y, float z)
{
	float p[3] = { x, y, z };
	return sl_noise(3, p, NULL, 0);
}

float sl_noise4(float x, float y, float z, float w)
{
	float p[4] = { x, y, z, w };
	return sl_noise(4, p, NULL, 0);
}

void sl_vnoise(int dim, const float *p, const int32_t *period, float out[3])
{
	for (uint32_t c = 0; c < 3; c++)
		out[c] = sl_noise(dim, p, period, c + 1);
}

float sl_cellnoise(int dim, const float *p, uint32_t seed)
{
	if (dim < 1 || dim > 4)
		return 0.0f;
	int32_t ip[4];
	float frac;
	for (int d = 0; d < dim; d++)
		ip[d] = lattice(p[d], &frac);
	/* Offset the seed so that cells do not repeat the gradient hashes. */
	return sl_hash_unit(sl_hash_lattice(dim, ip, seed + 0x8000U));
}

void sl_vcellnoise(int dim, const float *p, float out[3])
{
	for (uint32_t c = 0; c < 3; c++)
		out[c] = sl_cellnoise(dim, p, c + 1);
}

float sl_random(uint32_t seed, uint32_t index, uint32_t counter)
{
	uint32_t h = sl_hash_mix(seed * 0x9e3779b9U + 0x1b873593U);
	h = sl_hash_mix(h ^ index);
	h = sl_hash_mix(h ^ counter);
	return sl_hash_unit(h);
}

int32_t sl_noise_period(float period)
{
	if (!(period >= 0.5f) || period > LATTICE_LIMIT)
		return 0;
	return (int32_t)floorf(period + 0.5f);
}

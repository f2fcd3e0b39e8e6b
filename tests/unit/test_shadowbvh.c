/*
 * Ray-traced shadows on the GPU: the shadow geometry's hierarchy (built by
 * Embree, traversed by sl/glsl.h's rl_bvh_transmission) against a brute
 * force in double precision and against closed forms. Skips (77), loudly,
 * without EGL.
 *
 * - A soup of random semi-opaque micropolygons of several objects and random
 *   rays: every ray whose hits are unambiguous (no triangle within 1e-4 of
 *   an edge in barycentric terms, no hit within 1e-4 relative of either end
 *   of the ray) carries, through the hierarchy, the product of 1 - opacity of
 *   the triangles the brute force finds, within 1e-5; with an object's
 *   casting turned off, the product without it. At most 5 % of the rays may
 *   be ambiguous.
 * - A sphere of radius 1 diced into 64 x 128 micropolygons (inscribed: its
 *   facets lie between cos(pi/64) and 1 of the radius from the centre), a
 *   point light, points on a plane: a point whose segment to the light
 *   passes nearer the centre than 0.999 cos(pi/64) is in full shadow (0), one
 *   whose segment passes farther than 1.001 is fully lit (1), exactly.
 * - No geometry lets all light through; degenerate rays (zero direction, zero
 *   or negative or NaN length, NaN origin) give a finite value in [0, 1].
 *
 * Rays per second: `relight bench --only rays` (daemon/bench/rays.c).
 */
#include "test.h"
#include "shadowbvh.h"
#include "gpu.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static struct gpu_ctx *ctx;
static const double PI = 3.14159265358979323846;

static uint64_t rng = 0x9e3779b97f4a7c15ull;

static double frand(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0;
}

/* What the hierarchy is built from: shadowrender.h's arrays. */
struct soup {
	float *P;
	uint32_t *quads, *object;
	float *opacity;
	uint32_t npoints, nquads;
};

static void soup_free(struct soup *s)
{
	free(s->P);
	free(s->quads);
	free(s->object);
	free(s->opacity);
	memset(s, 0, sizeof(*s));
}

/*
 * Brute force: ray o + t d, t in (0, tmax), against triangle (a, b, c).
 * Returns 1 for a hit, 0 for a miss, -1 when too near an edge or an end.
 */
static int tri_hit(const double o[3], const double d[3], double tmax, const float *a,
		   const float *b, const float *c)
{
	double e1[3], e2[3], s[3], p[3], q[3];
	for (int k = 0; k < 3; k++) {
		e1[k] = (double)b[k] - a[k];
		e2[k] = (double)c[k] - a[k];
		s[k] = o[k] - a[k];
	}
	p[0] = d[1] * e2[2] - d[2] * e2[1];
	p[1] = d[2] * e2[0] - d[0] * e2[2];
	p[2] = d[0] * e2[1] - d[1] * e2[0];
	double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
	if (fabs(det) < 1e-12)
		return 0;
	double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
	q[0] = s[1] * e1[2] - s[2] * e1[1];
	q[1] = s[2] * e1[0] - s[0] * e1[2];
	q[2] = s[0] * e1[1] - s[1] * e1[0];
	double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
	double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
	const double m = 1e-4;
	bool in = u > m && v > m && u + v < 1 - m;
	bool out = u < -m || v < -m || u + v > 1 + m;
	if (out)
		return 0;
	if (!in)
		return -1;
	if (t > m * tmax && t < (1 - m) * tmax)
		return 1;
	if (t < -m * tmax || t > (1 + m) * tmax)
		return 0;
	return -1;
}

/* The brute force's transmission, or -1 for an ambiguous ray. */
static double brute(const struct soup *s, const float *org, const float *dir, float tmax,
		    const float *casts, uint32_t ncasts)
{
	double o[3] = { org[0], org[1], org[2] }, d[3] = { dir[0], dir[1], dir[2] };
	double trans = 1;
	for (uint32_t q = 0; q < s->nquads; q++) {
		const uint32_t *v = s->quads + 4 * q;
		const float *c[4] = { s->P + 3 * v[0], s->P + 3 * v[1], s->P + 3 * v[2],
				      s->P + 3 * v[3] };
		bool casting = !(casts && s->object[q] < ncasts && casts[s->object[q]] == 0);
		for (int h = 0; h < 2; h++) {
			int r = tri_hit(o, d, tmax, c[0], c[1 + h], c[2 + h]);
			if (r < 0)
				return -1;
			if (r && casting)
				trans *= 1 - (s->opacity ? s->opacity[q] : 1.0);
		}
	}
	return trans;
}

/* A random soup of small planar squares in [-1, 1]^3. */
static void make_soup(struct soup *s, uint32_t n)
{
	s->nquads = n;
	s->npoints = 4 * n;
	s->P = malloc(sizeof(float) * 3 * s->npoints);
	s->quads = malloc(sizeof(uint32_t) * 4 * n);
	s->object = malloc(sizeof(uint32_t) * n);
	s->opacity = malloc(sizeof(float) * n);
	for (uint32_t q = 0; q < n; q++) {
		double c[3], a[3], b[3], len = 0.02 + 0.1 * frand();
		for (int k = 0; k < 3; k++) {
			c[k] = 2 * frand() - 1;
			a[k] = 2 * frand() - 1;
		}
		/* b: a direction perpendicular to a */
		double t[3] = { frand() - 0.5, frand() - 0.5, frand() - 0.5 };
		b[0] = a[1] * t[2] - a[2] * t[1];
		b[1] = a[2] * t[0] - a[0] * t[2];
		b[2] = a[0] * t[1] - a[1] * t[0];
		double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
		double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
		const double corner[4][2] = { { -1, -1 }, { 1, -1 }, { 1, 1 }, { -1, 1 } };
		for (int i = 0; i < 4; i++)
			for (int k = 0; k < 3; k++)
				s->P[3 * (4 * q + (uint32_t)i) + (uint32_t)k] =
					(float)(c[k] + len * (corner[i][0] * a[k] / la +
							      corner[i][1] * b[k] / lb));
		for (int i = 0; i < 4; i++)
			s->quads[4 * q + (uint32_t)i] = 4 * q + (uint32_t)i;
		s->object[q] = 100 + q % 7;
		s->opacity[q] = (float)(0.1 + 0.8 * frand());
	}
}

static struct gpu_shadow_geometry *upload(const struct soup *s)
{
	char err[256];
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(
		ctx, s->P, s->npoints, s->quads, s->object, s->opacity, s->nquads, err,
		sizeof(err));
	if (!g)
		fprintf(stderr, "shadow geometry: %s\n", err);
	return g;
}

static void test_soup(void)
{
	struct soup s = { 0 };
	make_soup(&s, 3000);
	struct gpu_shadow_geometry *g = upload(&s);
	CHECK(g != NULL);
	if (!g) {
		soup_free(&s);
		return;
	}
	char err[256];
	CHECK(gpu_shadow_bvh_build(g, err, sizeof(err)));
	uint32_t nodes = 0, tris = 0;
	size_t bytes = 0;
	gpu_shadow_bvh_stats(g, &nodes, &tris, &bytes);
	printf("soup: %u micropolygons, %u triangles, %u nodes, %zu bytes (%.1f a triangle)\n",
	       s.nquads, tris, nodes, bytes, (double)bytes / tris);
	CHECK(tris == 2 * s.nquads);
	CHECK(nodes > 0 && nodes < 2 * tris);

	enum { N = 20000 };
	float *org = malloc(sizeof(float) * 3 * N), *dir = malloc(sizeof(float) * 3 * N);
	float *tmax = malloc(sizeof(float) * N), *out = malloc(sizeof(float) * N);
	for (uint32_t i = 0; i < N; i++) {
		for (int k = 0; k < 3; k++) {
			org[3 * i + (uint32_t)k] = (float)(2.4 * frand() - 1.2);
			dir[3 * i + (uint32_t)k] = (float)(2 * frand() - 1);
		}
		tmax[i] = (float)(0.2 + 2 * frand());
	}
	float casts[108];
	for (int pass = 0; pass < 2; pass++) {
		for (int i = 0; i < 108; i++)
			casts[i] = pass && i == 103 ? 0.0f : 1.0f;
		CHECK(gpu_shadow_bvh_trace(ctx, g, org, dir, tmax, N, casts, 108, out));
		uint32_t ambiguous = 0, hits = 0;
		double worst = 0;
		for (uint32_t i = 0; i < N; i++) {
			double want = brute(&s, org + 3 * i, dir + 3 * i, tmax[i], casts, 108);
			if (want < 0) {
				ambiguous++;
				continue;
			}
			hits += want < 1;
			worst = fmax(worst, fabs(out[i] - want));
		}
		printf("soup, %s: %u rays, %u through something, %u ambiguous; worst %.3g off the "
		       "brute force (tolerance 1e-5)\n", pass ? "object 103 not casting" :
		       "every object casting", N, hits, ambiguous, worst);
		CHECK(ambiguous <= N / 20);
		CHECK(hits > N / 10);
		CHECK(worst <= 1e-5);
	}
	free(org);
	free(dir);
	free(tmax);
	free(out);
	gpu_shadow_geometry_destroy(g);
	soup_free(&s);
}

/* A sphere of radius @r at @c as a (nu x nv)-point latitude-longitude grid, appended to @s. */
static void add_sphere(struct soup *s, const double c[3], double r, uint32_t nu, uint32_t nv,
		       uint32_t object)
{
	uint32_t base = s->npoints, qbase = s->nquads;
	s->npoints += nu * nv;
	s->nquads += (nu - 1) * (nv - 1);
	s->P = realloc(s->P, sizeof(float) * 3 * s->npoints);
	s->quads = realloc(s->quads, sizeof(uint32_t) * 4 * s->nquads);
	s->object = realloc(s->object, sizeof(uint32_t) * s->nquads);
	for (uint32_t j = 0; j < nv; j++)
		for (uint32_t i = 0; i < nu; i++) {
			double phi = 2 * PI * i / (nu - 1), theta = PI * j / (nv - 1);
			float *p = s->P + 3 * (base + j * nu + i);
			p[0] = (float)(c[0] + r * sin(theta) * cos(phi));
			p[1] = (float)(c[1] + r * sin(theta) * sin(phi));
			p[2] = (float)(c[2] + r * cos(theta));
		}
	for (uint32_t j = 0; j + 1 < nv; j++)
		for (uint32_t i = 0; i + 1 < nu; i++) {
			uint32_t q = qbase + j * (nu - 1) + i, k = base + j * nu + i;
			uint32_t *v = s->quads + 4 * q;
			v[0] = k;
			v[1] = k + 1;
			v[2] = k + 1 + nu;
			v[3] = k + nu;
			s->object[q] = object;
		}
}

/* Distance from @c to the segment from @p to @l. */
static double segment_distance(const double p[3], const double l[3], const double c[3])
{
	double d[3], w[3], dd = 0, t = 0;
	for (int k = 0; k < 3; k++) {
		d[k] = l[k] - p[k];
		w[k] = c[k] - p[k];
		dd += d[k] * d[k];
		t += w[k] * d[k];
	}
	t = fmin(1, fmax(0, t / dd));
	double e = 0;
	for (int k = 0; k < 3; k++)
		e += (p[k] + t * d[k] - c[k]) * (p[k] + t * d[k] - c[k]);
	return sqrt(e);
}

static void test_sphere_shadow(void)
{
	struct soup s = { 0 };
	const double centre[3] = { 1, 0, 7 }, light[3] = { 2, 0, 4 };
	add_sphere(&s, centre, 1, 129, 65, 1);
	struct gpu_shadow_geometry *g = upload(&s);
	CHECK(g != NULL);
	if (!g) {
		soup_free(&s);
		return;
	}
	enum { W = 128 };
	float *org = malloc(sizeof(float) * 3 * W * W), *dir = malloc(sizeof(float) * 3 * W * W);
	float *tmax = malloc(sizeof(float) * W * W), *out = malloc(sizeof(float) * W * W);
	for (uint32_t y = 0; y < W; y++)
		for (uint32_t x = 0; x < W; x++) {
			uint32_t i = y * W + x;
			double p[3] = { -4 + 8 * (x + 0.5) / W, -4 + 8 * (y + 0.5) / W, 10 };
			for (int k = 0; k < 3; k++) {
				org[3 * i + (uint32_t)k] = (float)p[k];
				dir[3 * i + (uint32_t)k] = (float)(light[k] - p[k]);
			}
			tmax[i] = 1;
		}
	CHECK(gpu_shadow_bvh_trace(ctx, g, org, dir, tmax, W * W, NULL, 0, out));
	const double inner = 0.999 * cos(PI / 64), outer = 1.001;
	uint32_t shadowed = 0, lit = 0, wrong = 0;
	for (uint32_t i = 0; i < W * W; i++) {
		double p[3] = { org[3 * i], org[3 * i + 1], org[3 * i + 2] };
		double e = segment_distance(p, light, centre);
		if (e < inner) {
			shadowed++;
			wrong += out[i] != 0;
		} else if (e > outer) {
			lit++;
			wrong += out[i] != 1;
		}
	}
	printf("sphere's shadow: %u points in full shadow, %u fully lit, %u wrong (want 0)\n",
	       shadowed, lit, wrong);
	CHECK(shadowed > 500 && lit > 5000);
	CHECK(wrong == 0);
	free(org);
	free(dir);
	free(tmax);
	free(out);
	gpu_shadow_geometry_destroy(g);
	soup_free(&s);
}

static void test_degenerate(void)
{
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(ctx, NULL, 0, NULL, NULL, NULL,
								   0, NULL, 0);
	CHECK(g != NULL);
	const float org[6] = { 0, 0, 0, 1, 2, 3 }, dir[6] = { 0, 0, 1, 0, 0, -1 };
	const float tmax[2] = { 1e30f, 5 };
	float out[2] = { -1, -1 };
	CHECK(g && gpu_shadow_bvh_trace(ctx, g, org, dir, tmax, 2, NULL, 0, out));
	CHECK(out[0] == 1 && out[1] == 1);
	gpu_shadow_geometry_destroy(g);

	struct soup s = { 0 };
	make_soup(&s, 200);
	g = upload(&s);
	CHECK(g != NULL);
	if (!g) {
		soup_free(&s);
		return;
	}
	const float nan = NAN;
	const float o5[15] = { 0, 0, 0, 0, 0, 0, 0, 0, 0, nan, 0, 0, 0, 0, 0 };
	const float d5[15] = { 0, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, nan, 1, 0 };
	const float t5[5] = { 1, 0, -1, 1, nan };
	float o[5];
	CHECK(gpu_shadow_bvh_trace(ctx, g, o5, d5, t5, 5, NULL, 0, o));
	for (int i = 0; i < 5; i++)
		CHECK(isfinite(o[i]) && o[i] >= 0 && o[i] <= 1);
	CHECK(o[1] == 1 && o[2] == 1 && o[4] == 1);
	gpu_shadow_geometry_destroy(g);
	soup_free(&s);
}

int main(void)
{
	char err[512];
	ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "SKIP: no GPU context, ray-traced shadows on the GPU are NOT tested: "
			"%s\n", err);
		return 77;
	}
	RUN(test_soup);
	RUN(test_sphere_shadow);
	RUN(test_degenerate);
	int rc = test_finish();
	gpu_destroy(ctx);
	return rc;
}

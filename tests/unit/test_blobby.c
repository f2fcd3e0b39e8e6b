/*
 * Blobby implicit surfaces: the field program's decoding (malformed code
 * refused with a message), its operators against hand-computed values, the
 * polygonization of a lone blob and a segment blob against the closed-form
 * sphere and capsule (vertices on the surface, normals radial, the mesh
 * closed and outward), and a rendered lone blob's coverage against the
 * disk of its threshold radius.
 */
#include "geom.h"
#include "geom_blobby.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Where (1 - r^2)^3 = 0.5: a lone blob's surface radius in its unit space. */
static double threshold_radius(void)
{
	return sqrt(1 - cbrt(0.5));
}

static void scale_matrix(float *m, double s, double tx, double ty, double tz)
{
	memset(m, 0, sizeof(float) * 16);
	m[0] = m[5] = m[10] = (float)s;
	m[12] = (float)tx, m[13] = (float)ty, m[14] = (float)tz;
	m[15] = 1;
}

static bool decode(const int32_t *code, uint32_t ncode, const float *fl, uint32_t nfl,
		   uint32_t nleaf, struct reyes_blobby *b, char *err)
{
	return reyes_blobby_decode(b, nleaf, code, ncode, fl, nfl, 1, err, 256);
}

static void test_decode_errors(void)
{
	float fl[40];
	scale_matrix(fl, 1, 0, 0, 0);
	scale_matrix(fl + 16, 1, 1, 0, 0);
	float sing[16] = {0};
	sing[15] = 1;
	char err[256];
	struct reyes_blobby b;
	static const struct {
		int32_t code[8];
		uint32_t ncode, nleaf;
		const char *want;
	} bad[] = {
		{{1001, 0, 42}, 3, 1, "not a Blobby opcode"},
		{{1001, 0, 0, 2, 0, 1}, 6, 1, "index out of range"},   /* operand 1 is itself */
		{{1001, 30}, 2, 1, "needs 16 floats"},
		{{1001, 0, 1001}, 3, 2, "ends inside opcode"},
		{{1001, 0}, 2, 2, "nleaf is 2"},
		{{1001, 0, 0, 0}, 4, 1, "operand count"},
		{{1001, 0, 0, 9, 0}, 5, 1, "operand count"},
		{{1001, 0, 4, 0}, 4, 1, "ends inside opcode"},
		{{0}, 0, 1, "empty"},
		{{1001, -1}, 2, 1, "out of range"},
		{{1003, 5, 0}, 3, 1, "string index"},
	};
	for (size_t k = 0; k < sizeof(bad) / sizeof(bad[0]); k++) {
		err[0] = 0;
		bool ok = decode(bad[k].code, bad[k].ncode, fl, 32, bad[k].nleaf, &b, err);
		CHECK(!ok);
		if (ok || !strstr(err, bad[k].want)) {
			fprintf(stderr, "  case %zu: \"%s\", expected \"%s\"\n", k, err, bad[k].want);
			CHECK(!"the message names the fault");
		}
	}
	/* a singular or projective matrix, a radius that is not positive */
	int32_t one[2] = {1001, 0};
	CHECK(!decode(one, 2, sing, 16, 1, &b, err) && strstr(err, "singular"));
	float proj[16];
	scale_matrix(proj, 1, 0, 0, 0);
	proj[3] = 0.5f;
	CHECK(!decode(one, 2, proj, 16, 1, &b, err) && strstr(err, "projective"));
	float seg[23] = {0, 0, 0, 1, 0, 0, 0};
	scale_matrix(seg + 7, 1, 0, 0, 0);
	int32_t sc[2] = {1002, 0};
	CHECK(!decode(sc, 2, seg, 23, 1, &b, err) && strstr(err, "radius"));
	float nan_m[16];
	scale_matrix(nan_m, 1, 0, 0, 0);
	nan_m[5] = NAN;
	CHECK(!decode(one, 2, nan_m, 16, 1, &b, err) && strstr(err, "not finite"));
}

/* Each operator against the value computed by hand from its operands. */
static void test_operators(void)
{
	float fl[40];
	scale_matrix(fl, 1, 0, 0, 0);
	scale_matrix(fl + 16, 1, 0.5, 0, 0);
	fl[32] = 0.25f;
	double p[3] = {0.2, 0.1, 0};
	double r0 = 0.2 * 0.2 + 0.1 * 0.1, r1 = 0.3 * 0.3 + 0.1 * 0.1;
	double f0 = pow(1 - r0, 3), f1 = pow(1 - r1, 3), c = 0.25;
	static const struct {
		int32_t op[4];
		uint32_t nop;
	} ops[] = {
		{{0, 3, 0, 1}, 4}, {{1, 3, 0, 1}, 4}, {{2, 2, 0, 1}, 4}, {{3, 2, 0, 1}, 4},
		{{4, 0, 1}, 3}, {{5, 1, 2}, 3}, {{6, 1}, 2}, {{7, 0}, 2},
	};
	int k = 0;
	double want[8];
	want[k++] = f0 + f1 + c;  /* the add takes operand 2 (the constant) through its count */
	want[k++] = f0 * f1 * c;
	want[k++] = fmax(f0, f1);
	want[k++] = fmin(f0, f1);
	want[k++] = f0 - f1;
	want[k++] = f1 / c;
	want[k++] = -f1;
	want[k++] = f0;
	for (int i = 0; i < 8; i++) {
		int32_t code[16] = {1001, 0, 1001, 16, 1000, 32};
		uint32_t n = 6;
		for (uint32_t j = 0; j < ops[i].nop; j++)
			code[n++] = ops[i].op[j];
		/* the add and multiply take the constant as a third operand */
		if (i < 2)
			code[n++] = 2;
		struct reyes_blobby b;
		char err[256];
		bool ok = decode(code, n, fl, 33, 3, &b, err);
		CHECK(ok);
		if (!ok) {
			fprintf(stderr, "  operator %d: %s\n", i, err);
			continue;
		}
		double vals[8];
		CHECK_NEAR(reyes_blobby_field(&b, p, vals), want[i], 1e-12);
		reyes_blobby_finish(&b);
	}
	/* a zero divisor gives 0, not an infinity */
	int32_t dz[] = {1001, 0, 1000, 32, 5, 0, 1};
	fl[32] = 0;
	struct reyes_blobby b;
	char err[256];
	CHECK(decode(dz, 7, fl, 33, 2, &b, err));
	double vals[4];
	CHECK(reyes_blobby_field(&b, p, vals) == 0);
	reyes_blobby_finish(&b);
}

/* Counts of each undirected edge's uses (as a sorted list of keys): each must be 2. */
static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

/* Closed and consistently oriented: each directed edge once, its reverse once. */
static bool closed_mesh(const struct reyes_blobby_mesh *m)
{
	size_t ne = 3 * (size_t)m->ntris;
	uint64_t *e = malloc(sizeof(uint64_t) * ne);
	for (uint32_t t = 0; t < m->ntris; t++)
		for (int k = 0; k < 3; k++) {
			uint64_t a = m->tris[3 * t + k], b = m->tris[3 * t + (k + 1) % 3];
			e[3 * t + k] = a << 32 | b;
		}
	qsort(e, ne, sizeof(uint64_t), cmp_u64);
	bool ok = true;
	for (size_t i = 0; i < ne && ok; i++) {
		uint64_t rev = (e[i] & 0xffffffffu) << 32 | e[i] >> 32;
		ok = (i + 1 >= ne || e[i + 1] != e[i]) &&
		     bsearch(&rev, e, ne, sizeof(uint64_t), cmp_u64) != NULL;
	}
	free(e);
	return ok;
}

/*
 * A lone ellipsoid blob scaled by 2 about (1, -2, 3): every vertex at the
 * threshold radius 2 * 0.454202 from the centre (relative 1e-6), every normal
 * radial (cosine above 0.99999), every triangle facing out, the mesh closed.
 */
static void test_lone_blob_is_sphere(void)
{
	float fl[16];
	scale_matrix(fl, 2, 1, -2, 3);
	int32_t code[] = {1001, 0};
	struct reyes_blobby b;
	char err[256];
	CHECK(decode(code, 2, fl, 16, 1, &b, err));
	struct reyes_blobby_mesh m;
	CHECK(reyes_blobby_polygonize(&b, 0.1, 192, &m));
	CHECK(m.ntris > 500);
	double R = 2 * threshold_radius(), c[3] = {1, -2, 3};
	double worst_r = 0, worst_cos = 1;
	for (uint32_t k = 0; k < m.npoints; k++) {
		double d[3], len = 0, dot = 0;
		for (int a = 0; a < 3; a++) {
			d[a] = m.P[3 * k + a] - c[a];
			len += d[a] * d[a];
		}
		len = sqrt(len);
		for (int a = 0; a < 3; a++)
			dot += d[a] / len * m.N[3 * k + a];
		worst_r = fmax(worst_r, fabs(len / R - 1));
		worst_cos = fmin(worst_cos, dot);
	}
	printf("lone blob: %u points, %u triangles, radius within %.2g, normals' cosine >= %.8f\n",
	       m.npoints, m.ntris, worst_r, worst_cos);
	CHECK(worst_r < 1e-6);
	CHECK(worst_cos > 0.99999);
	int inward = 0;
	for (uint32_t t = 0; t < m.ntris; t++) {
		const float *A = &m.P[3 * m.tris[3 * t]], *B = &m.P[3 * m.tris[3 * t + 1]],
			    *C = &m.P[3 * m.tris[3 * t + 2]];
		double u[3], v[3], mid[3];
		for (int a = 0; a < 3; a++) {
			u[a] = B[a] - A[a];
			v[a] = C[a] - A[a];
			mid[a] = (A[a] + B[a] + C[a]) / 3 - c[a];
		}
		double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
			       u[0] * v[1] - u[1] * v[0]};
		inward += n[0] * mid[0] + n[1] * mid[1] + n[2] * mid[2] <= 0;
	}
	CHECK(inward == 0);
	CHECK(closed_mesh(&m));
	reyes_blobby_mesh_finish(&m);
	reyes_blobby_finish(&b);
}

/* A segment blob from (0,0,0) to (2,0,0), radius 0.5: a capsule of radius 0.5 * 0.454202. */
static void test_segment_is_capsule(void)
{
	float fl[23] = {0, 0, 0, 2, 0, 0, 0.5f};
	scale_matrix(fl + 7, 1, 0, 0, 0);
	int32_t code[] = {1002, 0};
	struct reyes_blobby b;
	char err[256];
	CHECK(decode(code, 2, fl, 23, 1, &b, err));
	struct reyes_blobby_mesh m;
	CHECK(reyes_blobby_polygonize(&b, 0.02, 192, &m));
	double R = 0.5 * threshold_radius(), worst = 0;
	for (uint32_t k = 0; k < m.npoints; k++) {
		double x = fmin(fmax(m.P[3 * k], 0), 2);
		double d[3] = {m.P[3 * k] - x, m.P[3 * k + 1], m.P[3 * k + 2]};
		worst = fmax(worst, fabs(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / R - 1));
	}
	printf("segment blob: %u triangles, radius within %.2g\n", m.ntris, worst);
	CHECK(m.ntris > 100);
	CHECK(worst < 1e-5);
	CHECK(closed_mesh(&m));
	reyes_blobby_mesh_finish(&m);
	reyes_blobby_finish(&b);
}

/*
 * Two blobs whose fields add: the surface bulges between them (a point
 * midway, where each field alone is below the threshold, is inside), and
 * with max instead of add it does not.
 */
static void test_blend(void)
{
	float fl[32];
	scale_matrix(fl, 1, -0.3, 0, 0);
	scale_matrix(fl + 16, 1, 0.3, 0, 0);
	double mid[3] = {0, 0.42, 0}, vals[4];
	double alone = pow(1 - (0.09 + 0.42 * 0.42), 3);
	CHECK(alone < 0.5 && 2 * alone > 0.5);
	struct reyes_blobby b;
	char err[256];
	int32_t add[] = {1001, 0, 1001, 16, 0, 2, 0, 1}, max[] = {1001, 0, 1001, 16, 2, 2, 0, 1};
	CHECK(decode(add, 8, fl, 32, 2, &b, err));
	CHECK(reyes_blobby_field(&b, mid, vals) > REYES_BLOBBY_THRESHOLD);
	reyes_blobby_finish(&b);
	CHECK(decode(max, 8, fl, 32, 2, &b, err));
	CHECK(reyes_blobby_field(&b, mid, vals) < REYES_BLOBBY_THRESHOLD);
	reyes_blobby_finish(&b);
}

/*
 * A lone blob of scale 1.5 rendered orthographically on a 2 x 2 screen of
 * 200 x 200 pixels: the alpha image's sum over the pixel count is the
 * disk's area, pi (1.5 * 0.454202)^2 / 4, within a relative 0.5 % (the
 * Done-when tolerance; 8 x 8 samples per pixel put the sampling noise on the
 * edge far below it). Its normals face the camera: the front is lit.
 */
static void test_render_coverage(void)
{
	const char *rib =
		"Format 200 200 1\n"
		"PixelSamples 8 8\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -1 1 -1 1\n"
		"Display \"blob.exr\" \"file\" \"rgba\"\n"
		"Translate 0 0 5\n"
		"WorldBegin\n"
		"  LightSource \"distantlight\" 1 \"from\" [0 0 0] \"to\" [0 0 1]\n"
		"  Surface \"matte\"\n"
		"  Sides 1\n"
		"  Blobby 1 [1001 0] [1.5 0 0 0 0 1.5 0 0 0 0 1.5 0 0.1 -0.05 0 1] [\"\"]\n"
		"WorldEnd\n";
	struct reyes_image im = {0};
	CHECK(render(rib, "blob.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A"), r = channel(&im, "R");
	double sum = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++)
			sum += px(&im, a, x, y);
	double R = 1.5 * threshold_radius();
	double want = 3.14159265358979323846 * R * R / 4, got = sum / ((double)im.width * im.height);
	printf("rendered coverage %.6f, the disk of the threshold radius %.6f (%+.3f %%)\n", got,
	       want, 100 * (got / want - 1));
	CHECK(fabs(got / want - 1) < 0.005);
	/* the centre faces the light head on: matte's Kd * cos = 1 */
	CHECK_NEAR(px(&im, r, 110, 105), 1.0, 0.02);
	reyes_image_finish(&im);
}

int main(void)
{
	if (!scene_dir_create("relight-blobby"))
		return 1;
	RUN(test_decode_errors);
	RUN(test_operators);
	RUN(test_lone_blob_is_sphere);
	RUN(test_segment_is_capsule);
	RUN(test_blend);
	RUN(test_render_coverage);
	scene_dir_remove();
	return test_finish();
}

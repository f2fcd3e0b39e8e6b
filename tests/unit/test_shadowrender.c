/*
 * Shadow depth maps rendered on the GPU from shadow geometry, against
 * closed forms and against the renderer's own shadow pass. Skips (77),
 * loudly, without EGL.
 *
 * Closed forms: a camera at the origin looking down +z with a 90 degree
 * field of view, built here as matrices, so that dyadic world coordinates
 * project to exact pixel coordinates. Squares facing it have exact depths;
 * their edges pass through pixel centres to check the tie rule (a centre on
 * an edge belongs to the side it would fall in if moved right, then down:
 * pixel centres in [left, right) x [top, bottom) on the screen) and that a
 * centre on an edge shared by two micropolygons counts once (the midpoint
 * filter would show a second hit). A tilted plane seen by a turned and
 * moved camera is held to the analytic ray/plane z within 1e-4 relative.
 *
 * Against the renderer: a scene's shadow pass rendered by the hider (one
 * sample at each pixel centre, no jitter, midpoint depthfilter) and its
 * shadow geometry diced at rate 1 rendered here with the map's matrices.
 * Both depthfilters, midpoint and min. A pixel agrees when both are empty
 * or the depths are within 1% relative; at least 98% of the map must agree,
 * and the mismatches may be at most 5% of the pixels that have a depth (the
 * hider interpolates z linearly on the screen and its micropolygons are
 * diced on their own, so silhouettes may differ by a pixel).
 *
 * With "--bench FILE.rib" (examples/shadows/shadows.rib): renders the
 * shadow pass of FILE with the renderer, dices the other frame's shadow
 * geometry at the bake's default rate, and times the GPU render of that
 * geometry into the pass's map (min and midpoint), reporting agreement.
 */
#include "test.h"
#include "shadowrender.h"
#include "shadowgeo.h"
#include "bake.h"
#include "reyes.h"
#include "ri.h"
#include "texture.h"
#include "deepshadow.h"
#include "config.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define EMPTY 1e30f

static struct gpu_ctx *ctx;
static char tmpdir[256];

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- matrices (row vectors: p' = p M) ---- */

static void mat_identity(float m[16])
{
	for (int i = 0; i < 16; i++)
		m[i] = i % 5 == 0 ? 1.0f : 0.0f;
}

static void mat_mul(const float a[16], const float b[16], float out[16])
{
	float r[16];
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++) {
			double s = 0;
			for (int k = 0; k < 4; k++)
				s += (double)a[4 * i + k] * b[4 * k + j];
			r[4 * i + j] = (float)s;
		}
	memcpy(out, r, sizeof(r));
}

/* Camera space to NDC: 90 degree field of view, ndc = (x / z, -y / z) / 2 + 1/2. */
static void projection(float m[16])
{
	static const float p[16] = {
		0.5f, 0.0f, 0.0f, 0.0f,
		0.0f, -0.5f, 0.0f, 0.0f,
		0.5f, 0.5f, 1.0f, 1.0f,
		0.0f, 0.0f, 0.0f, 0.0f,
	};
	memcpy(m, p, sizeof(p));
}

/* ---- geometry ---- */

struct mesh {
	float *P;
	uint32_t *quads, *object;
	uint32_t npoints, nquads, cap_p, cap_q;
};

static void mesh_free(struct mesh *m)
{
	free(m->P);
	free(m->quads);
	free(m->object);
	memset(m, 0, sizeof(*m));
}

static uint32_t mesh_point(struct mesh *m, double x, double y, double z)
{
	if (m->npoints == m->cap_p) {
		m->cap_p = m->cap_p ? 2 * m->cap_p : 64;
		m->P = realloc(m->P, (size_t)m->cap_p * 3 * sizeof(float));
		if (!m->P)
			abort();
	}
	m->P[3 * m->npoints] = (float)x;
	m->P[3 * m->npoints + 1] = (float)y;
	m->P[3 * m->npoints + 2] = (float)z;
	return m->npoints++;
}

static void mesh_quad(struct mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t d, uint32_t obj)
{
	if (m->nquads == m->cap_q) {
		m->cap_q = m->cap_q ? 2 * m->cap_q : 64;
		m->quads = realloc(m->quads, (size_t)m->cap_q * 4 * sizeof(uint32_t));
		m->object = realloc(m->object, (size_t)m->cap_q * sizeof(uint32_t));
		if (!m->quads || !m->object)
			abort();
	}
	uint32_t *q = m->quads + 4 * (size_t)m->nquads;
	q[0] = a;
	q[1] = b;
	q[2] = c;
	q[3] = d;
	m->object[m->nquads++] = obj;
}

/*
 * An n x n grid of micropolygons over the parallelogram o + s u + t v
 * (s, t in [0, 1]), in grid order; @flip reverses every other row's winding.
 */
static void mesh_grid(struct mesh *m, const double o[3], const double u[3], const double v[3],
		      uint32_t n, uint32_t obj, bool flip)
{
	uint32_t base = m->npoints;
	for (uint32_t j = 0; j <= n; j++)
		for (uint32_t i = 0; i <= n; i++) {
			double s = (double)i / n, t = (double)j / n;
			mesh_point(m, o[0] + s * u[0] + t * v[0], o[1] + s * u[1] + t * v[1],
				   o[2] + s * u[2] + t * v[2]);
		}
	for (uint32_t j = 0; j < n; j++)
		for (uint32_t i = 0; i < n; i++) {
			uint32_t a = base + j * (n + 1) + i;
			if (flip && (j & 1))
				mesh_quad(m, a + n + 1, a + n + 2, a + 1, a, obj);
			else
				mesh_quad(m, a, a + 1, a + n + 2, a + n + 1, obj);
		}
}

/* An axis-aligned square facing the camera at depth z, world x in [x0, x1], y in [y0, y1]. */
static void mesh_square(struct mesh *m, double x0, double x1, double y0, double y1, double z,
			uint32_t n, uint32_t obj)
{
	const double o[3] = { x0, y0, z }, u[3] = { x1 - x0, 0, 0 }, v[3] = { 0, y1 - y0, 0 };
	mesh_grid(m, o, u, v, n, obj, false);
}

/* Render @m into a fresh map read back into @out (w * h floats). */
static bool render_mesh(const struct mesh *m, const float w2c[16], const float w2ndc[16],
			uint32_t w, uint32_t h, enum gpu_depth_filter f, const float *casts,
			uint32_t ncasts, float *out)
{
	char err[256];
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(ctx, m->P, m->npoints, m->quads,
								   m->object, NULL, m->nquads, err,
								   sizeof(err));
	if (!g) {
		fprintf(stderr, "geometry: %s\n", err);
		return false;
	}
	struct gpu_buffer *depth = gpu_buffer_create(ctx, (size_t)w * h * sizeof(float), NULL);
	bool ok = depth && gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, w, h, f, casts, ncasts,
						      depth) &&
		  gpu_buffer_read(depth, 0, (size_t)w * h * sizeof(float), out);
	gpu_buffer_destroy(depth);
	gpu_shadow_geometry_destroy(g);
	return ok;
}

/* ---- (a) closed forms ---- */

#define SW 16
#define SH 16

/* Pixels whose centres lie in screen [x0, x1) x [y0, y1) (pixel units) get @in, others @out. */
static int count_unlike(const float *d, double x0, double x1, double y0, double y1, float in,
			float out)
{
	int bad = 0;
	for (int y = 0; y < SH; y++)
		for (int x = 0; x < SW; x++) {
			double cx = x + 0.5, cy = y + 0.5;
			bool inside = cx >= x0 && cx < x1 && cy >= y0 && cy < y1;
			float want = inside ? in : out;
			if (d[y * SW + x] != want) {
				if (bad < 4)
					fprintf(stderr, "  pixel (%d, %d): %.9g, expected %.9g\n", x, y,
						(double)d[y * SW + x], (double)want);
				bad++;
			}
		}
	return bad;
}

/*
 * Screen X = 4x + 8, Y = 8 - 4y at z = 2 (16x16). The square x in
 * [-0.875, 0.625], y in [-0.625, 0.875] covers screen [4.5, 10.5) x
 * [4.5, 10.5): its edges, its 2x2 grid's inner edges (X = 7.5, Y = 7.5)
 * and its diagonals pass through pixel centres.
 */
static void test_square(void)
{
	float w2c[16], w2ndc[16], d[SW * SH];
	mat_identity(w2c);
	projection(w2ndc);
	struct mesh m = { 0 };
	mesh_square(&m, -0.875, 0.625, -0.625, 0.875, 2.0, 2, 0);

	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL, 0, d));
	CHECK(count_unlike(d, 4.5, 10.5, 4.5, 10.5, 2.0f, EMPTY) == 0);
	/* One surface: every centre, those on shared edges too, sees one hit. */
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT, NULL, 0, d));
	CHECK(count_unlike(d, 4.5, 10.5, 4.5, 10.5, EMPTY, EMPTY) == 0);

	/* Finer (6x6, one pixel each: every centre is a corner of up to four
	 * micropolygons), with every other row wound the other way. */
	mesh_free(&m);
	const double o[3] = { -0.875, -0.625, 2 }, u[3] = { 1.5, 0, 0 }, v[3] = { 0, 1.5, 0 };
	mesh_grid(&m, o, u, v, 6, 0, true);
	/* A back plane at z = 4 over the whole screen (X = 2x + 8, Y = 8 - 2y). */
	mesh_square(&m, -8, 8, -4, 4, 4.0, 1, 1);
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL, 0, d));
	CHECK(count_unlike(d, 4.5, 10.5, 4.5, 10.5, 2.0f, 4.0f) == 0);
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT, NULL, 0, d));
	CHECK(count_unlike(d, 4.5, 10.5, 4.5, 10.5, 3.0f, EMPTY) == 0);
	mesh_free(&m);
}

/* Two parallel squares, different objects; casting masks. */
static void test_two_squares(void)
{
	float w2c[16], w2ndc[16], d[SW * SH];
	mat_identity(w2c);
	projection(w2ndc);
	struct mesh m = { 0 };
	/* Front: z = 2, screen [4.5, 10.5)^2. Back: z = 3, X = 8x / 3 + 8: x in
	 * [-1.5, 1.5] covers [4, 12], y likewise. */
	mesh_square(&m, -0.875, 0.625, -0.625, 0.875, 2.0, 3, 5);
	mesh_square(&m, -1.5, 1.5, -1.5, 1.5, 3.0, 4, 0xfffffff0u);
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL, 0, d));
	int bad = 0;
	for (int y = 0; y < SH; y++)
		for (int x = 0; x < SW; x++) {
			bool front = x >= 4 && x < 10 && y >= 4 && y < 10;
			bool back = x >= 4 && x < 12 && y >= 4 && y < 12;
			float want = front ? 2.0f : back ? 3.0f : EMPTY;
			bad += fabsf(d[y * SW + x] - want) > 1e-6f * want;
		}
	CHECK(bad == 0);
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT, NULL, 0, d));
	bad = 0;
	for (int y = 0; y < SH; y++)
		for (int x = 0; x < SW; x++) {
			bool front = x >= 4 && x < 10 && y >= 4 && y < 10;
			float want = front ? 2.5f : EMPTY;
			bad += fabsf(d[y * SW + x] - want) > 1e-6f * want;
		}
	CHECK(bad == 0);

	/* Object 5 does not cast: only the back square. The back's id is past
	 * ncasts, so it casts. */
	float casts[8] = { 1, 1, 1, 1, 1, 0, 1, 1 };
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, casts, 8, d));
	bad = 0;
	for (int y = 0; y < SH; y++)
		for (int x = 0; x < SW; x++) {
			bool back = x >= 4 && x < 12 && y >= 4 && y < 12;
			float want = back ? 3.0f : EMPTY;
			bad += fabsf(d[y * SW + x] - want) > 1e-6f * want;
		}
	CHECK(bad == 0);
	/* Midpoint with one surface left: empty everywhere. */
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT, casts, 8, d));
	bad = 0;
	for (int i = 0; i < SW * SH; i++)
		bad += d[i] != EMPTY;
	CHECK(bad == 0);
	/* ncasts 5: object 5 is past the table and casts. */
	CHECK(render_mesh(&m, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, casts, 5, d));
	CHECK(d[5 * SW + 5] == 2.0f);

	/* A coincident copy of the front square is a second surface at the same
	 * depth, as the hider counts it: the midpoint is that depth. */
	struct mesh twin = { 0 };
	mesh_square(&twin, -0.875, 0.625, -0.625, 0.875, 2.0, 3, 1);
	mesh_square(&twin, -0.875, 0.625, -0.625, 0.875, 2.0, 2, 2);
	mesh_square(&twin, -1.5, 1.5, -1.5, 1.5, 3.0, 4, 3);
	CHECK(render_mesh(&twin, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT, NULL, 0, d));
	CHECK(count_unlike(d, 4.5, 10.5, 4.5, 10.5, 2.0f, EMPTY) == 0);
	mesh_free(&twin);

	/* One geometry rendered again with other masks and sizes (flags and
	 * scratch are reused). */
	char err[256];
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(ctx, m.P, m.npoints, m.quads,
								   m.object, NULL, m.nquads, err,
								   sizeof(err));
	CHECK(g != NULL);
	struct gpu_buffer *buf = gpu_buffer_create(ctx, 32 * 32 * sizeof(float), NULL);
	CHECK(buf != NULL);
	if (g && buf) {
		CHECK(gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, casts, 8,
						 buf));
		CHECK(gpu_buffer_read(buf, 0, sizeof(d), d));
		CHECK_NEAR(d[5 * SW + 5], 3.0, 3e-6);
		CHECK(gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL, 0,
						 buf));
		CHECK(gpu_buffer_read(buf, 0, sizeof(d), d) && d[5 * SW + 5] == 2.0f);
		float d32[32 * 32];
		CHECK(gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, 32, 32, GPU_DEPTH_MIDPOINT,
						 NULL, 0, buf));
		CHECK(gpu_buffer_read(buf, 0, sizeof(d32), d32));
		/* At 32x32 the front covers [9, 21)^2, the back [8, 24)^2. */
		CHECK_NEAR(d32[10 * 32 + 10], 2.5, 3e-6);
		CHECK(d32[22 * 32 + 22] == EMPTY && d32[0] == EMPTY);
		CHECK(gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, SW, SH, GPU_DEPTH_MIDPOINT,
						 NULL, 0, buf));
		CHECK(gpu_buffer_read(buf, 0, sizeof(d), d));
		CHECK_NEAR(d[5 * SW + 5], 2.5, 3e-6);
		/* Bad arguments. */
		float nan_m[16];
		memcpy(nan_m, w2ndc, sizeof(nan_m));
		nan_m[3] = NAN;
		CHECK(!gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, 64, 64, GPU_DEPTH_MIN, NULL,
						  0, buf));
		CHECK(!gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, 0, 16, GPU_DEPTH_MIN, NULL,
						  0, buf));
		CHECK(!gpu_shadow_geometry_render(ctx, g, w2c, nan_m, SW, SH, GPU_DEPTH_MIN, NULL,
						  0, buf));
		CHECK(!gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, SW, SH,
						  (enum gpu_depth_filter)7, NULL, 0, buf));
		CHECK(!gpu_shadow_geometry_render(ctx, g, NULL, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL,
						  0, buf));
		CHECK(!gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, SW, SH, GPU_DEPTH_MIN, NULL,
						  0, NULL));
		CHECK(gpu_shadow_geometry_bytes(g) > 0);
	}
	gpu_buffer_destroy(buf);
	gpu_shadow_geometry_destroy(g);
	mesh_free(&m);
}

/*
 * A plane through world (-2.5, -4, 3.5) tilted about two axes, seen by a
 * camera turned 20 degrees about y and moved: each pixel's depth against
 * the analytic intersection of the ray through its centre with the plane.
 */
static void test_tilted(void)
{
	enum { W = 64, H = 48 };
	const double th = 20 * 3.14159265358979323846 / 180;
	/* World to camera: rotate about y, then move by (0.1, -0.3, 0.5). */
	float w2c[16] = {
		(float)cos(th), 0, (float)sin(th), 0,
		0, 1, 0, 0,
		(float)-sin(th), 0, (float)cos(th), 0,
		0.1f, -0.3f, 0.5f, 1,
	};
	float proj[16], w2ndc[16];
	projection(proj);
	/* Non-square: x scaled by H / W so that pixels stay square. */
	proj[0] *= (float)H / W;
	mat_mul(w2c, proj, w2ndc);

	const double o[3] = { -2.5, -4.0, 3.5 }, u[3] = { 9.0, 0.0, 3.0 }, v[3] = { 0.6, 8.0, 2.0 };
	struct mesh m = { 0 };
	mesh_grid(&m, o, u, v, 9, 3, false);
	float *d = malloc(W * H * sizeof(float));
	CHECK(render_mesh(&m, w2c, w2ndc, W, H, GPU_DEPTH_MIN, NULL, 0, d));

	/* The plane in camera space: a point and a normal. */
	double n[3] = { u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
			u[0] * v[1] - u[1] * v[0] };
	double oc[3], nc[3];
	for (int c = 0; c < 3; c++) {
		oc[c] = o[0] * w2c[c] + o[1] * w2c[4 + c] + o[2] * w2c[8 + c] + w2c[12 + c];
		nc[c] = n[0] * w2c[c] + n[1] * w2c[4 + c] + n[2] * w2c[8 + c];
	}
	double ox = (double)H / W;
	int bad = 0, hits = 0, edge_px = 0;
	double worst = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			/* The ray through the centre: camera (dx, dy, 1). */
			double ndx = (x + 0.5) / W, ndy = (y + 0.5) / H;
			double dir[3] = { (ndx - 0.5) / (0.5 * ox), (0.5 - ndy) / 0.5, 1 };
			double z = (nc[0] * oc[0] + nc[1] * oc[1] + nc[2] * oc[2]) /
				   (nc[0] * dir[0] + nc[1] * dir[1] + nc[2] * dir[2]);
			/* Where it meets the plane, in (s, t) of the parallelogram. */
			double pc[3] = { dir[0] * z - oc[0], dir[1] * z - oc[1], z - oc[2] };
			/* Back to world directions (the rotation's transpose). */
			double pw[3];
			for (int r = 0; r < 3; r++)
				pw[r] = pc[0] * w2c[4 * r] + pc[1] * w2c[4 * r + 1] +
					pc[2] * w2c[4 * r + 2];
			/* Solve pw = s u + t v by least squares (exact for points on the plane). */
			double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
			double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
			double uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
			double pu = pw[0] * u[0] + pw[1] * u[1] + pw[2] * u[2];
			double pv = pw[0] * v[0] + pw[1] * v[1] + pw[2] * v[2];
			double det = uu * vv - uv * uv;
			double s = (pu * vv - pv * uv) / det, t = (pv * uu - pu * uv) / det;
			const double margin = 1e-3;
			float got = d[y * W + x];
			if (s > margin && s < 1 - margin && t > margin && t < 1 - margin) {
				hits++;
				double rel = fabs(got - z) / z;
				if (rel > worst)
					worst = rel;
				bad += !(rel <= 1e-4);
			} else if (s < -margin || s > 1 + margin || t < -margin || t > 1 + margin) {
				bad += got != EMPTY;
			} else {
				edge_px++;
			}
		}
	for (int y = 0; getenv("SHOW") && y < H; y++) {
		for (int x = 0; x < W; x++)
			putchar(d[y * W + x] < 1e29f ? '#' : '.');
		putchar('\n');
	}
	printf("tilted plane: %d pixels covered, worst relative depth error %.3g, %d on the "
	       "boundary not checked\n", hits, worst, edge_px);
	CHECK(hits > W * H / 4);
	CHECK(bad == 0);
	free(d);
	mesh_free(&m);
}

/* NaN points, indices out of range, micropolygons behind the eye or huge. */
static void test_garbage(void)
{
	enum { W = 512, H = 512 };
	float w2c[16], w2ndc[16];
	mat_identity(w2c);
	projection(w2ndc);
	struct mesh m = { 0 };
	/* A good one: X = 256 x + 256 at z = 1; x in [0, 0.25) covers [256, 320). */
	mesh_square(&m, 0.0, 0.25, -0.25, 0.0, 1.0, 1, 0);
	uint32_t nan_p = mesh_point(&m, NAN, 0, 1);
	uint32_t inf_p = mesh_point(&m, 0, INFINITY, 1);
	uint32_t a = mesh_point(&m, -0.5, 0.5, 1), b = mesh_point(&m, -0.4, 0.5, 1),
		 c = mesh_point(&m, -0.4, 0.4, 1), e = mesh_point(&m, -0.5, 0.4, 1);
	mesh_quad(&m, a, b, nan_p, e, 1);
	mesh_quad(&m, a, inf_p, c, e, 1);
	mesh_quad(&m, a, b, c, 1000000, 1);
	mesh_quad(&m, 0xffffffffu, b, c, e, 1);
	/* Behind the eye, straddling it, and beyond float range once projected. */
	uint32_t bh = mesh_point(&m, -0.5, 0.5, -1), far = mesh_point(&m, 3e38, 3e38, 1e-30);
	mesh_quad(&m, a, b, c, bh, 2);
	mesh_quad(&m, a, b, far, e, 2);
	/* Degenerate: all corners one point, and a line. */
	mesh_quad(&m, a, a, a, a, 2);
	mesh_quad(&m, a, b, b, a, 2);
	/* Huge: spans the whole 512x512 screen (past the per-micropolygon cap). */
	uint32_t h0 = mesh_point(&m, -1e7, -1e7, 0.5), h1 = mesh_point(&m, 1e7, -1e7, 0.5),
		 h2 = mesh_point(&m, 1e7, 1e7, 0.5), h3 = mesh_point(&m, -1e7, 1e7, 0.5);
	for (int i = 0; i < 200; i++)
		mesh_quad(&m, h0, h1, h2, h3, 3);

	float *d = malloc(W * H * sizeof(float));
	double t0 = now();
	CHECK(render_mesh(&m, w2c, w2ndc, W, H, GPU_DEPTH_MIN, NULL, 0, d));
	double t = now() - t0;
	int bad = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			bool in = x >= 256 && x < 320 && y >= 256 && y < 320;
			bad += d[y * W + x] != (in ? 1.0f : EMPTY);
		}
	CHECK(bad == 0);
	printf("garbage: 512x512 with 200 screen-sized micropolygons (left out) in %.3f s\n", t);
	CHECK(t < 5.0);

	/* At 64x64 the huge micropolygon is under the cap and fills the map at z = 0.5. */
	CHECK(render_mesh(&m, w2c, w2ndc, 64, 64, GPU_DEPTH_MIN, NULL, 0, d));
	bad = 0;
	for (int i = 0; i < 64 * 64; i++)
		bad += d[i] != 0.5f;
	CHECK(bad == 0);
	free(d);
	mesh_free(&m);

	/* Nothing at all, and no points. */
	char err[256];
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(ctx, NULL, 0, NULL, NULL, NULL, 0, err,
								   sizeof(err));
	CHECK(g != NULL);
	struct gpu_buffer *buf = gpu_buffer_create(ctx, 8 * 8 * sizeof(float), NULL);
	float e8[64];
	CHECK(g && buf && gpu_shadow_geometry_render(ctx, g, w2c, w2ndc, 8, 8, GPU_DEPTH_MIDPOINT,
						     NULL, 0, buf));
	CHECK(buf && gpu_buffer_read(buf, 0, sizeof(e8), e8) && e8[0] == EMPTY && e8[63] == EMPTY);
	gpu_buffer_destroy(buf);
	gpu_shadow_geometry_destroy(g);
	gpu_shadow_geometry_destroy(NULL);
	CHECK(gpu_shadow_geometry_bytes(NULL) == 0);
	uint32_t q4[4] = { 0, 0, 0, 0 };
	CHECK(!gpu_shadow_geometry_create(ctx, NULL, 1, q4, q4, NULL, 1, err, sizeof(err)));
	CHECK(!gpu_shadow_geometry_create(NULL, NULL, 0, NULL, NULL, NULL, 0, NULL, 0));
}

/* ---- (b) against the renderer ---- */

/* A shadow pass rendered by the renderer, and a frame's shadow geometry. */
struct pass {
	float rate;
	bool dice_shadow_pass;         /* else dice the frame that is not a shadow pass */
	bool ok;
	struct bake_shadow_geometry geo;
	double render_s;
};

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct pass *ps = user;
	bool shadow = reyes_scene_is_shadow_pass(scene);
	if (shadow) {
		struct reyes_render_opts o = { .diag = stderr };
		double t0 = now();
		if (!reyes_render(scene, &o, NULL))
			return false;
		ps->render_s = now() - t0;
	}
	if (shadow == ps->dice_shadow_pass) {
		bake_shadow_geometry_free(&ps->geo);
		ps->ok = bake_shadow_geometry(scene, ps->rate, stderr, &ps->geo);
		return ps->ok;
	}
	return true;
}

static bool read_rib(const char *path, struct pass *ps)
{
	char shaders[600];
	snprintf(shaders, sizeof(shaders), "%s:%s", tmpdir, RELIGHT_SOURCE_SHADER_DIR);
	struct reyes_ri_opts o = { .default_shader_path = shaders, .frame = on_frame, .user = ps };
	int nerr = 0;
	if (!reyes_ri_read(path, &o, &nerr)) {
		fprintf(stderr, "%s: failed (%d errors)\n", path, nerr);
		return false;
	}
	return ps->ok;
}

/* Pixels of @gpu within 1% of @ref (or both empty); mismatches printed by kind. */
static double agreement(const float *gpu, const float *ref, uint32_t w, uint32_t h,
			uint32_t stride, uint32_t *mismatches)
{
	uint32_t agree = 0, only_gpu = 0, only_ref = 0, differ = 0;
	double worst = 0;
	for (uint32_t i = 0; i < w * h; i++) {
		float a = gpu[i], b = ref[(size_t)i * stride];
		bool ea = !(a < 1e29f), eb = !(b < 1e29f);
		if (ea && eb) {
			agree++;
		} else if (ea) {
			only_ref++;
		} else if (eb) {
			only_gpu++;
		} else if (fabsf(a - b) <= 0.01f * fabsf(b)) {
			agree++;
			worst = fmax(worst, fabs((double)a - b) / b);
		} else {
			differ++;
		}
	}
	*mismatches = w * h - agree;
	printf("  %u of %u pixels agree within 1%% (%.3f%%, the largest relative difference among "
	       "them %.2g); mismatches: %u depths differ, %u only on the GPU, %u only in the "
	       "renderer\n", agree, w * h, 100.0 * agree / (w * h), worst, differ, only_gpu,
	       only_ref);
	return (double)agree / (w * h);
}

/*
 * The shadows example's shadow pass at 256x256 with a pixel-centred
 * sample, twice: depthfilter midpoint (key.shd) and min (keymin.shd).
 */
#define PASS_FRAME(filter, name) \
	"FrameBegin 1\n" \
	"  Format 256 256 1\n" \
	"  PixelSamples 1 1\n" \
	"  PixelFilter \"box\" 1 1\n" \
	"  Hider \"hidden\" \"depthfilter\" \"" filter "\" \"jitter\" 0\n" \
	"  Projection \"perspective\" \"fov\" 57.5662\n" \
	"  Display \"" name ".z\" \"zfile\" \"z\"\n" \
	"  Transform [0.780869 -0.407041 -0.473879 0 -0 0.758577 -0.651584 0 0.624695 0.508801 " \
	"0.592349 0 -1.24939 -1.39689 7.58207 1]\n" \
	"  WorldBegin\n" \
	"    ShadingRate 1\n" \
	"    Surface \"constant\"\n" \
	"    Polygon \"P\" [-4 0 -4  -4 0 4  4 0 4  4 0 -4]\n" \
	"    AttributeBegin\n" \
	"      Translate -0.8 0.7 2\n" \
	"      Sphere 0.7 -0.7 0.7 360\n" \
	"    AttributeEnd\n" \
	"    AttributeBegin\n" \
	"      Translate 0.9 0 2.6\n" \
	"      Rotate -90 1 0 0\n" \
	"      Cylinder 0.45 0 1.4 360\n" \
	"      Translate 0 0 1.4\n" \
	"      Disk 0 0.45 360\n" \
	"    AttributeEnd\n" \
	"    AttributeBegin\n" \
	"      Translate 0.2 0.25 1.2\n" \
	"      Rotate 90 1 0 0\n" \
	"      Torus 0.35 0.12 0 360 360\n" \
	"    AttributeEnd\n" \
	"  WorldEnd\n" \
	"FrameEnd\n" \
	"MakeShadow \"" name ".z\" \"" name ".shd\"\n"

static const char *scene_rib = PASS_FRAME("midpoint", "key") PASS_FRAME("min", "keymin");

/*
 * Render @geo into @map's camera, timed, and compare with @map's depths
 * unless @time_only: the fraction that agrees (1 when only timed), -1 on
 * failure.
 */
static double compare_with_map(const struct bake_shadow_geometry *geo,
			       const struct reyes_shadow_map_info *map, enum gpu_depth_filter f,
			       bool time_only, uint32_t *mismatches, double *seconds)
{
	char err[256];
	double t0 = now();
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(ctx, geo->P, geo->npoints,
								   geo->quads, geo->object, geo->opacity,
								   geo->nquads, err, sizeof(err));
	double t_create = now() - t0;
	if (!g) {
		fprintf(stderr, "geometry: %s\n", err);
		return -1;
	}
	size_t n = (size_t)map->width * map->height;
	struct gpu_buffer *buf = gpu_buffer_create(ctx, n * sizeof(float), NULL);
	float *d = malloc(n * sizeof(float));
	double frac = -1;
	if (!buf || !d)
		goto done;
	/* The first render compiles the programs (or loads them from the disk cache). */
	t0 = now();
	if (!gpu_shadow_geometry_render(ctx, g, map->world_to_camera, map->world_to_ndc,
					map->width, map->height, f, NULL, 0, buf) ||
	    !gpu_finish(ctx))
		goto done;
	double t_first = now() - t0;
	double best = 1e9, total = 0;
	enum { RUNS = 5 };
	for (int r = 0; r < RUNS; r++) {
		t0 = now();
		if (!gpu_shadow_geometry_render(ctx, g, map->world_to_camera, map->world_to_ndc,
						map->width, map->height, f, NULL, 0, buf) ||
		    !gpu_buffer_read(buf, 0, n * sizeof(float), d))
			goto done;
		double t = now() - t0;
		total += t;
		best = t < best ? t : best;
	}
	*seconds = best;
	printf("  %s: %llu micropolygons into %ux%u: upload %.1f ms, first render %.1f ms, then "
	       "best %.1f ms, mean %.1f ms (render + readback, %d runs)\n",
	       f == GPU_DEPTH_MIN ? "min" : "midpoint", (unsigned long long)geo->nquads, map->width,
	       map->height, 1e3 * t_create, 1e3 * t_first, 1e3 * best, 1e3 * total / RUNS, RUNS);
	*mismatches = 0;
	frac = time_only ? 1.0 :
	       agreement(d, map->depth, map->width, map->height, map->stride, mismatches);
done:
	free(d);
	gpu_buffer_destroy(buf);
	gpu_shadow_geometry_destroy(g);
	return frac;
}

static bool load_map(struct reyes_texsys **ts, const char *name,
		     struct reyes_shadow_map_info *map)
{
	float id[16];
	mat_identity(id);
	if (!*ts)
		*ts = reyes_texsys_create(tmpdir, id, stderr);
	return *ts && reyes_tex_shadow_map(*ts, name, map);
}

static void test_renderer(void)
{
	char path[512];
	snprintf(path, sizeof(path), "%s/scene.rib", tmpdir);
	FILE *f = fopen(path, "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs(scene_rib, f);
	fclose(f);
	struct pass ps = { .rate = 1.0f, .dice_shadow_pass = true };
	CHECK(read_rib(path, &ps));
	struct reyes_texsys *ts = NULL;
	static const char *const names[2] = { "key.shd", "keymin.shd" };
	static const enum gpu_depth_filter filters[2] = { GPU_DEPTH_MIDPOINT, GPU_DEPTH_MIN };
	for (int k = 0; k < 2 && ps.ok; k++) {
		struct reyes_shadow_map_info map;
		if (!load_map(&ts, names[k], &map)) {
			CHECK(!"the renderer's shadow map");
			break;
		}
		uint32_t n = map.width * map.height, with_depth = 0;
		for (uint32_t i = 0; i < n; i++)
			with_depth += map.depth[(size_t)i * map.stride] < 1e29f;
		printf("renderer: %s %ux%u (%u pixels with a depth); shadow geometry at rate 1: "
		       "%llu micropolygons\n", names[k], map.width, map.height, with_depth,
		       (unsigned long long)ps.geo.nquads);
		uint32_t mism = 0;
		double secs = 0;
		double frac = compare_with_map(&ps.geo, &map, filters[k], false, &mism, &secs);
		CHECK(frac >= 0.98);
		/* Mismatches are at silhouettes: a few percent of the pixels
		 * that have a depth, not a fraction of the map that is empty. */
		CHECK(mism <= with_depth / 20);
		/* The comparison is not of empty pixels alone. */
		CHECK(with_depth > n / (k ? 2 : 50));
	}
	reyes_texsys_destroy(ts);
	bake_shadow_geometry_free(&ps.geo);
}

/*
 * A deep shadow pass (render/deepshadow.h) of semi-transparent planes, a
 * sphere and hairs, at 4 x 4 unjittered samples per texel, against the
 * same pass rendered on the GPU from its own shadow geometry: both
 * functions evaluated just before and after every node depth of either
 * (1e-3 of the 6 units to the receiver) and halfway to the next node when
 * that is further, per texel. Each is compressed within REYES_DEEP_DEFAULT_ERROR of the
 * exact function, so two of the same hits differ by at most twice that.
 */
static const char deep_rib[] =
	"FrameBegin 1\n"
	"  Format 64 64 1\n"
	"  PixelSamples 4 4\n"
	"  PixelFilter \"box\" 1 1\n"
	"  Hider \"hidden\" \"jitter\" 0\n"
	"  Projection \"orthographic\"\n"
	"  ScreenWindow -4 4 -4 4\n"
	"  Display \"deep.dsm\" \"deepshad\" \"deepopacity\"\n"
	"  Rotate -90 1 0 0\n"
	"  Translate -0.3 -6 0.2\n"
	"  WorldBegin\n"
	"    ShadingRate 1\n"
	"    Surface \"constant\"\n"
	"    AttributeBegin Opacity [0.3 0.3 0.3]\n"
	"      Polygon \"P\" [-2 1 -2  2 1 -2  2 1 2  -2 1 2] AttributeEnd\n"
	"    AttributeBegin Opacity [0.5 0.5 0.5]\n"
	"      Polygon \"P\" [-1 2 -3  3 2 -3  3 2 1  -1 2 1] AttributeEnd\n"
	"    AttributeBegin Opacity [0.4 0.2 0.6] Translate -1.5 3 1.5\n"
	"      Sphere 1 -1 1 360 AttributeEnd\n"
	"    AttributeBegin Opacity [0.6 0.6 0.6]\n"
	"      Curves \"linear\" [3 3] \"nonperiodic\" \"P\" [-3 0.5 -1  0 0.7 -0.5  3 0.5 0\n"
	"        -3 0.6 1  0 0.4 1.5  3 0.6 2] \"N\" [0 1 0  0 1 0  0 1 0  0 1 0  0 1 0  0 1 0]\n"
	"        \"constantwidth\" [0.15] AttributeEnd\n"
	"    Polygon \"P\" [-4 0 -4  4 0 -4  4 0 4  -4 0 4]\n"
	"  WorldEnd\n"
	"FrameEnd\n";

static void test_deep(void)
{
	char path[512], err[256];
	snprintf(path, sizeof(path), "%s/deep.rib", tmpdir);
	FILE *f = fopen(path, "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs(deep_rib, f);
	fclose(f);
	struct pass ps = { .rate = 1.0f, .dice_shadow_pass = true };
	CHECK(read_rib(path, &ps));
	struct reyes_texsys *ts = NULL;
	struct reyes_shadow_map_info map;
	if (!ps.ok || !load_map(&ts, "deep.dsm", &map) || map.depth) {
		CHECK(!"the renderer's deep shadow map");
		reyes_texsys_destroy(ts);
		bake_shadow_geometry_free(&ps.geo);
		return;
	}
	struct gpu_shadow_geometry *g = gpu_shadow_geometry_create(
		ctx, ps.geo.P, ps.geo.npoints, ps.geo.quads, ps.geo.object, ps.geo.opacity,
		ps.geo.nquads, err, sizeof(err));
	CHECK(g && gpu_shadow_geometry_has_opacity(g));
	const struct gpu_deep_opts o = { .samples = 4, .error = REYES_DEEP_DEFAULT_ERROR,
					 .threshold = GPU_DEEP_THRESHOLD };
	struct gpu_deep_stats st;
	struct gpu_buffer *b = g ? gpu_shadow_geometry_render_deep(ctx, g, map.world_to_camera,
								   map.world_to_ndc, map.width,
								   map.height, &o, NULL, 0, &st, err,
								   sizeof(err)) : NULL;
	if (!b)
		fprintf(stderr, "deep render: %s\n", err);
	CHECK(b != NULL);
	size_t npix = (size_t)map.width * map.height;
	float *plane = b ? malloc(st.bytes) : NULL;
	CHECK(!b || (plane && gpu_buffer_read(b, 0, st.bytes, plane)));
	if (plane) {
		uint32_t *off = malloc((npix + 1) * sizeof(uint32_t));
		for (size_t p = 0; p <= npix; p++)
			off[p] = (uint32_t)plane[p];
		CHECK(off[npix] == st.nodes && st.bytes == (npix + 1 + 2 * st.nodes) * 4);
		struct reyes_deep_map gm = { map.width, map.height, off, plane + npix + 1 };
		struct reyes_deep_map rm = { map.width, map.height, (uint32_t *)map.deep_offsets,
					     (float *)map.deep_nodes };
		double worst = 0, sum = 0, lit = 0;
		uint64_t evals = 0, shadowed = 0;
		for (uint32_t y = 0; y < map.height; y++)
			for (uint32_t x = 0; x < map.width; x++) {
				size_t p = (size_t)y * map.width + x;
				const struct reyes_deep_map *m2[2] = { &gm, &rm };
				for (int k = 0; k < 2; k++)
					for (uint32_t i = m2[k]->offsets[p]; i < m2[k]->offsets[p + 1];
					     i++) {
						double z0 = m2[k]->zt[2 * i];
						double z1 = i + 1 < m2[k]->offsets[p + 1]
								    ? m2[k]->zt[2 * i + 2] : z0 + 1;
						/* beside a node, not at it: a step's depth one
						   rounding apart is a whole step apart there */
						double zs[3] = { z0 - 1e-3, z0 + 1e-3, 0.5 * (z0 + z1) };
						for (int j = 0; j < (z1 - z0 > 2e-3 ? 3 : 2); j++) {
							double d = fabs(reyes_deep_eval(&gm, x, y, zs[j]) -
									reyes_deep_eval(&rm, x, y, zs[j]));
							worst = fmax(worst, d);
							sum += d;
							evals++;
						}
					}
				double tr = reyes_deep_eval(&rm, x, y, 5.9);
				shadowed += tr < 0.99;
				lit += tr;
			}
		printf("deep map: GPU %llu hits (at most %u in a texel), %llu nodes, %zu bytes, "
		       "%zu of scratch; renderer %u nodes; over %llu lookups |T_gpu - T_render| "
		       "mean %.3g, largest %.3g (bound %.3g); %llu of %zu texels shadowed above "
		       "the floor, mean T %.3f\n", (unsigned long long)st.hits, st.max_hits,
		       (unsigned long long)st.nodes, st.bytes, st.scratch_bytes,
		       map.deep_offsets[npix], (unsigned long long)evals, sum / (double)evals,
		       worst, 2.0 * REYES_DEEP_DEFAULT_ERROR, (unsigned long long)shadowed, npix,
		       lit / (double)npix);
		CHECK(evals > 1000 && shadowed > npix / 4);
		CHECK(worst <= 2.0 * REYES_DEEP_DEFAULT_ERROR + 1e-4);
		/* the same samples see the same hits: far closer than the bound */
		CHECK(sum / (double)evals <= 1e-5);
		free(off);
	}
	free(plane);
	/* over the bound of one texel's list: refused, and said */
	const struct gpu_deep_opts few = { .samples = 4, .error = REYES_DEEP_DEFAULT_ERROR,
					   .threshold = GPU_DEEP_THRESHOLD, .max_hits = 10 };
	CHECK(!g || !gpu_shadow_geometry_render_deep(ctx, g, map.world_to_camera,
						      map.world_to_ndc, map.width, map.height,
						      &few, NULL, 0, NULL, err, sizeof(err)));
	CHECK(strstr(err, "hits, over the 10") != NULL);
	gpu_buffer_destroy(b);
	gpu_shadow_geometry_destroy(g);
	reyes_texsys_destroy(ts);
	bake_shadow_geometry_free(&ps.geo);
}

static int bench(const char *rib)
{
	char path[4096];
	if (rib[0] != '/' && getcwd(path, sizeof(path) - strlen(rib) - 2)) {
		strcat(path, "/");
		strcat(path, rib);
	} else {
		snprintf(path, sizeof(path), "%s", rib);
	}
	if (chdir(tmpdir) != 0)
		return 1;
	struct pass ps = { .rate = BAKE_DEFAULT_SHADOW_RATE, .dice_shadow_pass = false };
	if (!read_rib(path, &ps))
		return 1;
	struct reyes_texsys *ts = NULL;
	struct reyes_shadow_map_info map;
	if (!load_map(&ts, "key.shd", &map))
		return 1;
	printf("%s: renderer's shadow pass %ux%u in %.2f s; the view's shadow geometry at rate %g: "
	       "%llu points, %llu micropolygons\n", rib, map.width, map.height, ps.render_s,
	       (double)ps.rate, (unsigned long long)ps.geo.npoints,
	       (unsigned long long)ps.geo.nquads);
	printf("GPU: %s\n", gpu_renderer(ctx));
	uint32_t mism;
	double secs;
	/* The example's pass is a midpoint map: min is timed, not compared. */
	compare_with_map(&ps.geo, &map, GPU_DEPTH_MIN, true, &mism, &secs);
	compare_with_map(&ps.geo, &map, GPU_DEPTH_MIDPOINT, false, &mism, &secs);
	reyes_texsys_destroy(ts);
	bake_shadow_geometry_free(&ps.geo);
	return 0;
}

int main(int argc, char **argv)
{
	char err[512];
	ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "SKIP: no GPU context, shadow maps from geometry are NOT tested: %s\n",
			err);
		return 77;
	}
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/relight-shadowrender-XXXXXX");
	if (!mkdtemp(tmpdir)) {
		perror("mkdtemp");
		gpu_destroy(ctx);
		return 1;
	}
	int rc;
	if (argc == 3 && strcmp(argv[1], "--bench") == 0) {
		rc = bench(argv[2]);
	} else {
		if (chdir(tmpdir) != 0) {
			perror(tmpdir);
			return 1;
		}
		RUN(test_square);
		RUN(test_two_squares);
		RUN(test_tilted);
		RUN(test_garbage);
		RUN(test_renderer);
		RUN(test_deep);
		rc = test_finish();
	}
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", tmpdir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", tmpdir);
	gpu_destroy(ctx);
	return rc;
}

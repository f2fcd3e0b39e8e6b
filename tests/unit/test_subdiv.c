/*
 * SubdivisionMesh end to end: RIB scenes rendered through the scene builder
 * and the REYES pipeline, against OpenSubdiv's own limit points and closed
 * forms; and the diced grids of the geometry against the cage.
 */
#include "geom.h"
#include "geom_subdiv.h"
#include "reyes.h"
#include "ri.h"
#include "texture.h"
#include "config.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* The cube's cage: 8 points, 6 quads, each face's vertices counter-clockwise
   seen from outside. */
static const float cube_pts[24] = { -1, -1, 1, 1, -1, 1, -1, 1, 1, 1, 1, 1,
				    -1, 1, -1, 1, 1, -1, -1, -1, -1, 1, -1, -1 };
static const uint32_t cube_nv[6] = { 4, 4, 4, 4, 4, 4 };
static const uint32_t cube_fv[24] = { 0, 1, 3, 2, 2, 3, 5, 4, 4, 5, 7, 6,
				      6, 7, 1, 0, 1, 7, 5, 3, 6, 0, 2, 4 };
static const uint32_t cube_edges[24] = { 0, 1, 1, 3, 3, 2, 2, 0, 3, 5, 5, 4, 4, 2,
					 5, 7, 7, 6, 6, 4, 7, 1, 6, 0 };

/* The cube turned 40 degrees about y, then 30 about x (seen from a corner). */
static void turned_cube(float out[24])
{
	double ay = 40 * PI / 180, ax = 30 * PI / 180;
	for (int i = 0; i < 8; i++) {
		double x = cube_pts[3 * i], y = cube_pts[3 * i + 1], z = cube_pts[3 * i + 2];
		double x1 = cos(ay) * x + sin(ay) * z, z1 = -sin(ay) * x + cos(ay) * z;
		double y2 = cos(ax) * y - sin(ax) * z1, z2 = sin(ax) * y + cos(ax) * z1;
		out[3 * i] = (float)x1, out[3 * i + 1] = (float)y2, out[3 * i + 2] = (float)z2;
	}
}

static char ribbuf[32768];

/* Append to ribbuf. */
static void rib_add(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void rib_add(const char *fmt, ...)
{
	size_t len = strlen(ribbuf);
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(ribbuf + len, sizeof(ribbuf) - len, fmt, ap);
	va_end(ap);
}

static void rib_ints(const uint32_t *v, uint32_t n)
{
	rib_add("[");
	for (uint32_t i = 0; i < n; i++)
		rib_add(" %u", v[i]);
	rib_add(" ]");
}

static void rib_points(const float *p, uint32_t n)
{
	rib_add(" \"P\" [");
	for (uint32_t i = 0; i < 3 * n; i++)
		rib_add(" %.9g", (double)p[i]);
	rib_add(" ]\n");
}

/* A subdivision cube with @tags (RIB text, may be empty) over points @p. */
static void rib_subdiv_cube(const float *p, const char *tags)
{
	rib_add("SubdivisionMesh \"catmull-clark\" ");
	rib_ints(cube_nv, 6);
	rib_ints(cube_fv, 24);
	rib_add(" %s", tags);
	rib_points(p, 8);
}

/* The tags of a cube creased on every edge and corner (sharpness 10: infinitely sharp). */
static const char *all_creased(void)
{
	static char tags[2048];
	size_t len = 0;
	len += (size_t)snprintf(tags + len, sizeof(tags) - len, "[");
	for (int e = 0; e < 12; e++)
		len += (size_t)snprintf(tags + len, sizeof(tags) - len, " \"crease\"");
	len += (size_t)snprintf(tags + len, sizeof(tags) - len, " \"corner\"] [");
	for (int e = 0; e < 12; e++)
		len += (size_t)snprintf(tags + len, sizeof(tags) - len, " 2 1");
	len += (size_t)snprintf(tags + len, sizeof(tags) - len, " 8 1] [");
	for (int e = 0; e < 24; e++)
		len += (size_t)snprintf(tags + len, sizeof(tags) - len, " %u", cube_edges[e]);
	len += (size_t)snprintf(tags + len, sizeof(tags) - len, " 0 1 2 3 4 5 6 7] [");
	for (int e = 0; e < 13; e++)
		len += (size_t)snprintf(tags + len, sizeof(tags) - len, " 10");
	snprintf(tags + len, sizeof(tags) - len, "]");
	return tags;
}

/* The camera of the cube scenes: perspective, fov 40, the cube 5 ahead. */
static void rib_camera(const char *out, uint32_t res, uint32_t samples)
{
	ribbuf[0] = 0;
	rib_add("Format %u %u 1\nPixelSamples %u %u\nPixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\nSurface \"constant\"\nShadingRate 0.25\nTranslate 0 0 5\n",
		res, res, samples, samples, out);
}

static double alpha_at(const struct reyes_image *im, int a, uint32_t x, uint32_t y)
{
	return px(im, a, x, y);
}

/* Render @rib's "A" channel into *im; its channel index, or -1. */
static int render_alpha(const char *out, struct reyes_image *im)
{
	memset(im, 0, sizeof(*im));
	CHECK(render(ribbuf, out, im));
	int a = im->data ? channel(im, "A") : -1;
	CHECK(a >= 0);
	return a;
}

/* ---- a convex hull of points in the plane (monotone chain) ---- */

struct pt { double x, y; };

static int pt_cmp(const void *pa, const void *pb)
{
	const struct pt *a = pa, *b = pb;
	if (a->x != b->x)
		return a->x < b->x ? -1 : 1;
	return (a->y > b->y) - (a->y < b->y);
}

static double cross3(struct pt o, struct pt a, struct pt b)
{
	return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

/* The hull of p[0..n) into h (2n room), counter-clockwise; its size. */
static size_t hull(struct pt *p, size_t n, struct pt *h)
{
	qsort(p, n, sizeof(*p), pt_cmp);
	size_t k = 0;
	for (size_t i = 0; i < n; i++) {
		while (k >= 2 && cross3(h[k - 2], h[k - 1], p[i]) <= 0)
			k--;
		h[k++] = p[i];
	}
	for (size_t i = n - 1, t = k + 1; i-- > 0;) {
		while (k >= t && cross3(h[k - 2], h[k - 1], p[i]) <= 0)
			k--;
		h[k++] = p[i];
	}
	return k - 1;
}

/* The hull's chord at height y: false if the line misses it. */
static bool chord(const struct pt *h, size_t n, double y, double *xl, double *xr)
{
	*xl = INFINITY, *xr = -INFINITY;
	for (size_t i = 0; i < n; i++) {
		struct pt a = h[i], b = h[(i + 1) % n];
		if ((a.y - y) * (b.y - y) > 0 || a.y == b.y)
			continue;
		double x = a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y);
		*xl = fmin(*xl, x), *xr = fmax(*xr, x);
	}
	return *xl < *xr;
}

/* A subdivision-mesh primitive over the cube's cage with points @p. */
static void cube_prim(struct reyes_prim *p, struct reyes_subdiv *sd, struct reyes_primvar *P,
		      const float *pts, uint64_t serial)
{
	memset(p, 0, sizeof(*p));
	*sd = (struct reyes_subdiv){ .serial = serial, .nfaces = 6, .nverts = cube_nv,
				     .verts = cube_fv, .fvar_boundary = 1 };
	*P = (struct reyes_primvar){ .name = "P", .cls = REYES_VERTEX, .type = SL_TYPE_POINT,
				     .count = 8, .values = pts };
	p->kind = REYES_SUBDIV;
	p->subdiv = sd;
	p->npoints = 8;
	p->vars = P;
	p->nvars = 1;
}

/*
 * The Catmull-Clark cube's silhouette against OpenSubdiv's limit surface.
 * The turned cube is rendered at 160x160 with 16x16 samples and a one-pixel
 * box filter, so a pixel's alpha is its covered area. On each row, the alpha
 * summed left of a column inside the silhouette is how far the silhouette's
 * left edge lies from that column, averaged over the row's height; the same
 * on the right. Those are compared with the hull of 6 x 101 x 101 limit
 * points from OpenSubdiv (the projected limit surface of a convex cage is
 * convex), projected with the same camera, its chords averaged over 16
 * heights per row: every row within 0.1 pixel. The cage's own silhouette
 * lies several pixels out, and a shrunk limit (the cube's limit points are
 * inside the cage) would show as a difference of pixels. No pinholes: at
 * ShadingRate 4, where neighbouring faces' grids are diced at different
 * rates, every pixel wholly inside the silhouette has alpha 1.
 */
static void test_cube_silhouette(void)
{
	enum { RES = 160, S = 101 };
	float pts[24];
	turned_cube(pts);
	rib_camera("sil.exr", RES, 16);
	rib_subdiv_cube(pts, "");
	rib_add("WorldEnd\n");
	struct reyes_image im = { 0 };
	CHECK(render(ribbuf, "sil.exr", &im));
	int a = im.data ? channel(&im, "A") : -1;
	CHECK(a >= 0);
	if (a < 0)
		return;

	struct reyes_prim prim;
	struct reyes_subdiv sd;
	struct reyes_primvar P;
	cube_prim(&prim, &sd, &P, pts, 0x5d00000000000001ull);
	size_t n = 6 * S * S;
	struct pt *p = malloc(sizeof(*p) * n), *h = malloc(sizeof(*h) * 2 * n);
	double *uv = malloc(sizeof(double) * 2 * S * S), *L = malloc(sizeof(double) * 3 * S * S);
	bool ok = p && h && uv && L;
	for (int j = 0; ok && j < S; j++)
		for (int i = 0; i < S; i++)
			uv[2 * (j * S + i)] = (double)i / (S - 1), uv[2 * (j * S + i) + 1] = (double)j / (S - 1);
	double k = RES / 2.0 / tan(20 * PI / 180);
	for (uint32_t f = 0; ok && f < 6; f++) {
		ok = reyes_subdiv_limit(&prim, f, 0, S * S, uv, L);
		for (int q = 0; ok && q < S * S; q++) {
			double z = L[3 * q + 2] + 5;
			p[f * S * S + q] = (struct pt){ RES / 2.0 + k * L[3 * q] / z,
							RES / 2.0 - k * L[3 * q + 1] / z };
		}
	}
	CHECK(ok);
	size_t nh = ok ? hull(p, n, h) : 0;
	double ylo = INFINITY, yhi = -INFINITY, worst = 0;
	for (size_t i = 0; i < nh; i++)
		ylo = fmin(ylo, h[i].y), yhi = fmax(yhi, h[i].y);
	int rows = 0;
	for (uint32_t y = 0; ok && y < RES; y++) {
		if (y < ylo + 1 || y + 1 > yhi - 1)
			continue;
		double xl = 0, xr = 0, l, r;
		for (int s = 0; s < 16; s++) {
			CHECK(chord(h, nh, y + (s + 0.5) / 16, &l, &r));
			xl += l / 16, xr += r / 16;
		}
		uint32_t xs = (uint32_t)floor(0.5 * (xl + xr));
		double left = 0, right = 0;
		for (uint32_t x = 0; x < xs; x++)
			left += alpha_at(&im, a, x, y);
		for (uint32_t x = xs; x < RES; x++)
			right += alpha_at(&im, a, x, y);
		double el = fabs((xs - left) - xl), er = fabs((xs + right) - xr);
		worst = fmax(worst, fmax(el, er));
		CHECK(el <= 0.1 && er <= 0.1);
		if (!(el <= 0.1 && er <= 0.1))
			fprintf(stderr, "  row %u: limit %.3f..%.3f, render %.3f..%.3f\n", y, xl, xr,
				xs - left, xs + right);
		rows++;
	}
	printf("cube silhouette: %d rows, largest difference from the limit %.4f pixel (limit 0.1)\n",
	       rows, worst);
	CHECK(rows > 60);
	reyes_image_finish(&im);

	/* Pinholes: at ShadingRate 4 (grids of neighbouring faces diced at their own
	   rates), no pixel wholly inside the silhouette is less than opaque. */
	rib_camera("pin.exr", RES, 16);
	char *rate = strstr(ribbuf, "ShadingRate 0.25");
	if (rate)
		memcpy(rate, "ShadingRate 4   ", 16);
	rib_subdiv_cube(pts, "");
	rib_add("WorldEnd\n");
	a = render_alpha("pin.exr", &im);
	int inside = 0, holes = 0;
	for (uint32_t y = 0; a >= 0 && nh && y + 1 < RES; y++) {
		double l0, r0, l1, r1;
		if (!chord(h, nh, y, &l0, &r0) || !chord(h, nh, y + 1, &l1, &r1))
			continue;
		for (uint32_t x = 0; x < RES; x++) {
			if (x < fmax(l0, l1) + 0.5 || x + 1 > fmin(r0, r1) - 0.5)
				continue;
			inside++;
			holes += px(&im, a, x, y) < 1.0f;
		}
	}
	printf("pinholes at ShadingRate 4: %d of %d pixels inside the silhouette\n", holes, inside);
	CHECK(inside > 3000 && holes == 0);
	reyes_image_finish(&im);
	free(p), free(h), free(uv), free(L);
}

static double alpha_sum(const struct reyes_image *im, int a)
{
	double s = 0;
	for (uint32_t y = 0; y < im->height; y++)
		for (uint32_t x = 0; x < im->width; x++)
			s += px(im, a, x, y);
	return s;
}

/*
 * A cube creased on every edge and corner (sharpness 10, infinitely sharp)
 * renders as the polygonal cube: the turned cube as SubdivisionMesh and as
 * PointsPolygons, 128x128 at 8x8 samples, differ per pixel in alpha by at
 * most 0.02 (the pixels on the silhouette edge see the same straight edges,
 * diced apart differently) and in coverage by at most 0.1 %. The smooth
 * cube's coverage is far from the polygons' (checked, so that the test sees
 * the creases).
 */
static void test_creased_cube(void)
{
	float pts[24];
	turned_cube(pts);
	struct reyes_image sub, poly, smooth;
	rib_camera("creased.exr", 128, 8);
	rib_subdiv_cube(pts, all_creased());
	rib_add("WorldEnd\n");
	int a = render_alpha("creased.exr", &sub);
	rib_camera("poly.exr", 128, 8);
	rib_add("PointsPolygons ");
	rib_ints(cube_nv, 6);
	rib_ints(cube_fv, 24);
	rib_points(pts, 8);
	rib_add("WorldEnd\n");
	int b = render_alpha("poly.exr", &poly);
	rib_camera("smooth.exr", 128, 8);
	rib_subdiv_cube(pts, "");
	rib_add("WorldEnd\n");
	int c = render_alpha("smooth.exr", &smooth);
	if (a < 0 || b < 0 || c < 0)
		return;
	double worst = 0;
	for (uint32_t y = 0; y < 128; y++)
		for (uint32_t x = 0; x < 128; x++)
			worst = fmax(worst, fabs(px(&sub, a, x, y) - px(&poly, b, x, y)));
	double cs = alpha_sum(&sub, a), cp = alpha_sum(&poly, b), cm = alpha_sum(&smooth, c);
	printf("creased cube: coverage %.2f vs the polygons' %.2f (%.4f %%), largest pixel "
	       "difference %.4f; smooth cube %.2f\n", cs, cp, 100 * fabs(cs - cp) / cp, worst, cm);
	CHECK(worst <= 0.02);
	CHECK(fabs(cs - cp) <= 1e-3 * cp);
	CHECK(cm < 0.9 * cp);
	reyes_image_finish(&sub);
	reyes_image_finish(&poly);
	reyes_image_finish(&smooth);
}

/*
 * A flat 4x4-point grid of 3x3 unit quads with interpolateboundary 1: its
 * limit is the square itself (a planar, evenly spaced cage is reproduced
 * exactly), 96x96 pixels seen orthographically at 32 pixels per unit. With
 * the middle face a hole the coverage is 8/9 of it: both within 0.1 %. With
 * Opacity 0.5 the alpha inside is 0.5 (within 0.002: no pixel where
 * neighbouring faces' grids meet is covered twice), and with the boundary
 * not interpolated (interpolateboundary 0) only the middle face has a limit
 * surface, a square a third the size or less.
 */
static void grid_rib(const char *out, const char *tags, const char *attrs)
{
	ribbuf[0] = 0;
	rib_add("Format 128 128 1\nPixelSamples 4 4\nPixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\nScreenWindow -2 2 -2 2\n"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\nSurface \"constant\"\n%s\nTranslate 0 0 5\n"
		"SubdivisionMesh \"catmull-clark\" [4 4 4 4 4 4 4 4 4]\n"
		"[0 1 5 4  1 2 6 5  2 3 7 6  4 5 9 8  5 6 10 9  6 7 11 10  8 9 13 12  9 10 14 13"
		"  10 11 15 14] %s \"P\" [", out, attrs, tags);
	for (int j = 0; j < 4; j++)
		for (int i = 0; i < 4; i++)
			rib_add(" %g %g 0", i - 1.5, j - 1.5);
	rib_add("]\nWorldEnd\n");
}

static void test_hole(void)
{
	struct reyes_image im;
	grid_rib("full.exr", "[\"interpolateboundary\"] [1 0] [1] []", "");
	int a = render_alpha("full.exr", &im);
	double full = a >= 0 ? alpha_sum(&im, a) : 0;
	reyes_image_finish(&im);
	grid_rib("hole.exr", "[\"interpolateboundary\" \"hole\"] [1 0 1 0] [1 4] []", "");
	a = render_alpha("hole.exr", &im);
	double hole = a >= 0 ? alpha_sum(&im, a) : 0;
	reyes_image_finish(&im);
	grid_rib("half.exr", "[\"interpolateboundary\"] [1 0] [1] []", "Opacity [0.5 0.5 0.5]");
	a = render_alpha("half.exr", &im);
	double lo = 1, hi = 0;
	for (uint32_t y = 17; a >= 0 && y < 111; y++)
		for (uint32_t x = 17; x < 111; x++)
			lo = fmin(lo, px(&im, a, x, y)), hi = fmax(hi, px(&im, a, x, y));
	reyes_image_finish(&im);
	grid_rib("none.exr", "", "");
	a = render_alpha("none.exr", &im);
	double none = a >= 0 ? alpha_sum(&im, a) : 0;
	reyes_image_finish(&im);
	printf("grid: coverage %.2f (closed form 9216), with a hole %.2f (8192), with no boundary "
	       "interpolation %.2f; Opacity 0.5: alpha %.4f..%.4f\n", full, hole, none, lo, hi);
	CHECK_NEAR(full, 9216, 9.216);
	CHECK_NEAR(hole, 8192, 8.192);
	CHECK(none > 0 && none <= 1024 * 1.001);
	CHECK(lo >= 0.498 && hi <= 0.502);
}

/*
 * Grids of the geometry. On a cube creased on every edge and corner, each
 * face's limit is its planar cage face, and facevarying s, t given per face
 * as the corners' (0,0) (1,0) (1,1) (0,1) interpolate as the cage's
 * bilinear s, t: s = u and t = v at every grid point, within 1e-5. A
 * vertex variable and a facevarying one with the same value at every corner
 * of a vertex (welded, so smooth across the faces) agree within 1e-5 on the
 * smooth cube. Two faces' grids evaluate their shared edge to the same
 * points (within 1e-6 of the cube's size: no cracks where grids meet at
 * the same dicing).
 */
static void test_grids(void)
{
	float pts[24];
	turned_cube(pts);
	float s[24], t[24], w8[8], w24[24];
	static const float cs[4] = { 0, 1, 1, 0 }, ct[4] = { 0, 0, 1, 1 };
	for (int c = 0; c < 24; c++) {
		s[c] = cs[c % 4], t[c] = ct[c % 4];
		w24[c] = (float)(cube_fv[c] * cube_fv[c]) * 0.1f;
	}
	for (int v = 0; v < 8; v++)
		w8[v] = (float)(v * v) * 0.1f;
	uint32_t corner_v[8] = { 0, 1, 2, 3, 4, 5, 6, 7 };
	float sharp[12] = { 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10 };
	for (int creased = 1; creased >= 0; creased--) {
		struct reyes_prim p;
		struct reyes_subdiv sd;
		struct reyes_primvar vars[5];
		cube_prim(&p, &sd, &vars[0], pts, 0x5d00000000000010ull + (uint64_t)creased);
		if (creased) {
			sd.ncreases = 12, sd.crease_verts = cube_edges, sd.crease_sharp = sharp;
			sd.ncorners = 8, sd.corner_verts = corner_v, sd.corner_sharp = sharp;
		}
		vars[1] = (struct reyes_primvar){ .name = "s", .cls = REYES_FACEVARYING,
						  .type = SL_TYPE_FLOAT, .count = 24, .values = s };
		vars[2] = vars[1], vars[2].name = "t", vars[2].values = t;
		vars[3] = vars[1], vars[3].name = "wf", vars[3].values = w24;
		vars[4] = (struct reyes_primvar){ .name = "wv", .cls = REYES_VERTEX,
						  .type = SL_TYPE_FLOAT, .count = 8, .values = w8 };
		p.vars = vars, p.nvars = 5;
		struct reyes_patch *pieces = NULL;
		size_t n = 0, cap = 0;
		CHECK(reyes_prim_pieces(&p, &pieces, &n, &cap));
		CHECK(n == 6);
		double st_err = 0, w_err = 0, flat_err = 0;
		for (size_t i = 0; i < n; i++) {
			struct reyes_grid g;
			CHECK(reyes_patch_dice(&pieces[i], 9, 9, &g));
			if (!g.n)
				continue;
			CHECK(g.s && g.t && g.nvars == 2);
			const float *wf = NULL, *wv = NULL;
			for (uint32_t k = 0; k < g.nvars; k++)
				if (strcmp(g.vars[k].name, "wf") == 0)
					wf = g.vars[k].data;
				else if (strcmp(g.vars[k].name, "wv") == 0)
					wv = g.vars[k].data;
			CHECK(wf && wv);
			const uint32_t *fv = &cube_fv[4 * pieces[i].piece];
			for (uint32_t k = 0; k < g.n && g.s && g.t && wf && wv; k++) {
				double u = g.u[k], v = g.v[k];
				st_err = fmax(st_err, fmax(fabs(g.s[k] - u), fabs(g.t[k] - v)));
				w_err = fmax(w_err, fabs(wf[k] - wv[k]));
				/* the cage's bilinear point at (u, v) */
				for (int c = 0; c < 3; c++) {
					double q = (1 - u) * (1 - v) * pts[3 * fv[0] + c] +
						   u * (1 - v) * pts[3 * fv[1] + c] +
						   u * v * pts[3 * fv[2] + c] + (1 - u) * v * pts[3 * fv[3] + c];
					flat_err = fmax(flat_err, fabs(g.P[0][c * g.n + k] - q));
				}
			}
			reyes_grid_finish(&g);
		}
		printf("%s cube grids: |s - u|, |t - v| <= %.2g; welded facevarying vs vertex <= %.2g; "
		       "from the cage's bilinear faces <= %.3g\n", creased ? "creased" : "smooth",
		       st_err, w_err, flat_err);
		if (creased) {
			CHECK(st_err <= 1e-5);
			CHECK(flat_err <= 1e-5);
		} else {
			CHECK(w_err <= 1e-5);
			CHECK(flat_err > 0.1);
		}
		free(pieces);
		if (creased)
			continue;
		/* faces 0 [0 1 3 2] and 1 [2 3 5 4] share the edge 2-3: face 0's (u, 1)
		   is face 1's (u, 0) (point 2 at u = 0 on both) */
		double uv0[2 * 17], uv1[2 * 17], P0[3 * 17], P1[3 * 17], crack = 0;
		for (int k = 0; k < 17; k++) {
			uv0[2 * k] = k / 16.0, uv0[2 * k + 1] = 1;
			uv1[2 * k] = k / 16.0, uv1[2 * k + 1] = 0;
		}
		CHECK(reyes_subdiv_limit(&p, 0, 0, 17, uv0, P0));
		CHECK(reyes_subdiv_limit(&p, 1, 0, 17, uv1, P1));
		for (int k = 0; k < 3 * 17; k++)
			crack = fmax(crack, fabs(P0[k] - P1[k]));
		printf("shared edge of two faces: largest difference %.3g\n", crack);
		CHECK(crack <= 1e-6);
	}
}

/*
 * Deformation: a mesh whose second MotionBegin sample is moved 0.5 along x
 * renders as the same mesh under a moving transformation (Shutter 0 1): per
 * pixel alpha within 0.02, coverage within 0.1 %.
 */
static void test_motion(void)
{
	float pts[24], moved[24];
	turned_cube(pts);
	memcpy(moved, pts, sizeof(moved));
	for (int i = 0; i < 8; i++)
		moved[3 * i] += 0.5f;
	struct reyes_image a, b;
	rib_camera("deform.exr", 96, 8);
	memmove(ribbuf + strlen("Shutter 0 1\n"), ribbuf, strlen(ribbuf) + 1);
	memcpy(ribbuf, "Shutter 0 1\n", strlen("Shutter 0 1\n"));
	rib_add("MotionBegin [0 1]\n");
	rib_subdiv_cube(pts, "");
	rib_subdiv_cube(moved, "");
	rib_add("MotionEnd\nWorldEnd\n");
	int ca = render_alpha("deform.exr", &a);
	rib_camera("xform.exr", 96, 8);
	memmove(ribbuf + strlen("Shutter 0 1\n"), ribbuf, strlen(ribbuf) + 1);
	memcpy(ribbuf, "Shutter 0 1\n", strlen("Shutter 0 1\n"));
	rib_add("MotionBegin [0 1]\nTranslate 0 0 0\nTranslate 0.5 0 0\nMotionEnd\n");
	rib_subdiv_cube(pts, "");
	rib_add("WorldEnd\n");
	int cb = render_alpha("xform.exr", &b);
	if (ca < 0 || cb < 0)
		return;
	double worst = 0, blur = 0;
	for (uint32_t y = 0; y < 96; y++)
		for (uint32_t x = 0; x < 96; x++) {
			double v = px(&a, ca, x, y);
			worst = fmax(worst, fabs(v - px(&b, cb, x, y)));
			blur += v > 0.05 && v < 0.95;
		}
	double sa = alpha_sum(&a, ca), sb = alpha_sum(&b, cb);
	printf("deforming mesh vs moving transform: largest pixel difference %.4f, coverage %.2f "
	       "vs %.2f; %g partly covered pixels\n", worst, sa, sb, blur);
	CHECK(worst <= 0.02);
	CHECK(fabs(sa - sb) <= 1e-3 * sb);
	CHECK(blur > 200);
	reyes_image_finish(&a);
	reyes_image_finish(&b);
}

int main(void)
{
	if (!scene_dir_create("relight-subdiv"))
		return 1;
	RUN(test_cube_silhouette);
	RUN(test_creased_cube);
	RUN(test_hole);
	RUN(test_grids);
	RUN(test_motion);
	scene_dir_remove();
	return test_finish();
}

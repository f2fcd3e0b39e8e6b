/*
 * Geometry "teapot": it reads with no diagnostic, its diced surface's bound
 * is the Newell teapot's (z from the base, 0, to the knob, 3.15; y from -2
 * to 2 at the body's widest; x from the handle's -3 to the spout lip's
 * Bezier maximum), its body and bottom face out as a sphere does, and
 * rendered from above, below and the side its patch seams leak no more than
 * the renderer's known cracks between grids (see test_no_pinholes).
 * Another Geometry name is a warning at its line.
 */
#include "geom.h"
#include "render_scene.h"
#include "ri.h"
#include "test.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

struct seen {
	uint32_t nprims;
	double lo[3], hi[3];
	int sphere_sign;        /* the sign of a sphere's Ng . P */
	int agree, disagree;    /* body and bottom points facing as the sphere, or not */
};

static void dice_prim(const struct reyes_prim *p, uint32_t index, struct seen *s)
{
	struct reyes_patch *pcs = NULL;
	size_t n = 0, cap = 0;
	CHECK(reyes_prim_pieces(p, &pcs, &n, &cap));
	for (size_t i = 0; i < n; i++) {
		struct reyes_grid g = {0};
		CHECK(reyes_patch_dice(&pcs[i], 33, 33, &g));
		for (uint32_t k = 0; k < g.n; k++) {
			double P[3], Ng[3];
			for (int c = 0; c < 3; c++) {
				P[c] = g.P[0][c * g.n + k];
				Ng[c] = g.Ng[c * g.n + k];
			}
			if (index == 0) {
				double d = P[0] * Ng[0] + P[1] * Ng[1] + P[2] * Ng[2];
				s->sphere_sign = d > 0 ? 1 : -1;
				continue;
			}
			for (int c = 0; c < 3; c++) {
				s->lo[c] = fmin(s->lo[c], P[c]);
				s->hi[c] = fmax(s->hi[c], P[c]);
			}
			/* body patches 4-11 face away from the z axis, bottom ones 28-31 down;
			   their seams and poles have no clear side */
			double out = 0, len = sqrt(Ng[0] * Ng[0] + Ng[1] * Ng[1] + Ng[2] * Ng[2]);
			if (index >= 5 && index <= 12)
				out = (P[0] * Ng[0] + P[1] * Ng[1]) / (len * hypot(P[0], P[1]));
			else if (index >= 29)
				out = -Ng[2] / len;
			if (out > 0.2)
				s->agree += s->sphere_sign > 0;
			if (out < -0.2)
				s->disagree += s->sphere_sign > 0;
			if (out > 0.2)
				s->disagree += s->sphere_sign < 0;
			if (out < -0.2)
				s->agree += s->sphere_sign < 0;
		}
		reyes_grid_finish(&g);
	}
	free(pcs);
}

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct seen *s = user;
	s->nprims = scene->nprims;
	for (uint32_t i = 0; i < scene->nprims; i++)
		dice_prim(&scene->prims[i], i, s);
	return true;
}

/* The largest value of the cubic Bezier with control values @b (fine sampling). */
static double bezier_max(const double b[4])
{
	double best = -DBL_MAX;
	for (int i = 0; i <= 100000; i++) {
		double t = i / 100000.0, u = 1 - t;
		best = fmax(best, u * u * u * b[0] + 3 * u * u * t * b[1] + 3 * u * t * t * b[2] +
				      t * t * t * b[3]);
	}
	return best;
}

static void test_bound_and_facing(void)
{
	const char *rib = "WorldBegin\n  Sphere 1 -1 1 360\n  Geometry \"teapot\"\nWorldEnd\n";
	const char *path = tmp_path("bound.rib");
	FILE *f = fopen(path, "w");
	fputs(rib, f);
	fclose(f);
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	struct seen s = {.lo = {DBL_MAX, DBL_MAX, DBL_MAX}, .hi = {-DBL_MAX, -DBL_MAX, -DBL_MAX}};
	struct reyes_ri_opts o = {.diag = diag, .frame = on_frame, .user = &s};
	int nerr = 0;
	CHECK(reyes_ri_read(path, &o, &nerr));
	fclose(diag);
	CHECK(nerr == 0);
	CHECK(dlen == 0);
	if (dlen)
		fprintf(stderr, "  diagnostics: %s", dbuf);
	free(dbuf);
	CHECK(s.nprims == 33);
	/* the spout lip's outer edge, the patch edge at y = 0 with the largest x */
	static const double lip[4] = {3.3, 3.525, 3.45, 3.2};
	double want_lo[3] = {-3, -2, 0}, want_hi[3] = {bezier_max(lip), 2, 3.15};
	printf("teapot bound [%.5f %.5f] [%.5f %.5f] [%.5f %.5f], expected x to %.5f\n", s.lo[0],
	       s.hi[0], s.lo[1], s.hi[1], s.lo[2], s.hi[2], want_hi[0]);
	for (int c = 0; c < 3; c++) {
		CHECK_NEAR(s.lo[c], want_lo[c], 1e-4);
		CHECK_NEAR(s.hi[c], want_hi[c], 1e-4);
	}
	printf("body and bottom points facing as a sphere's: %d, against: %d\n", s.agree,
	       s.disagree);
	CHECK(s.agree > 1000);
	CHECK(s.disagree == 0);
}

/*
 * Pixels inside the silhouette, 4x4 samples: one that is not fully covered
 * while its eight neighbours are is a pinhole (a crack at a seam). *worst:
 * the least alpha among them.
 */
static int pinholes(const struct reyes_image *im, double *worst)
{
	int a = channel(im, "A"), holes = 0;
	*worst = 1;
	for (uint32_t y = 1; y + 1 < im->height; y++)
		for (uint32_t x = 1; x + 1 < im->width; x++) {
			if (px(im, a, x, y) > 0.999f)
				continue;
			bool closed = true;
			for (int dy = -1; dy <= 1; dy++)
				for (int dx = -1; dx <= 1; dx++)
					closed &= (dx == 0 && dy == 0) ||
						  px(im, a, x + dx, y + dy) > 0.999f;
			if (closed && getenv("TEAPOT_HOLES"))
				printf("  pinhole at (%u, %u): alpha %.4f\n", x, y, px(im, a, x, y));
			holes += closed;
			if (closed)
				*worst = fmin(*worst, px(im, a, x, y));
		}
	return holes;
}

static void test_no_pinholes(void)
{
	static const char *views[] = {
		"Translate 0 0 10\n",                          /* from below the base */
		"Translate 0 -1.5 10\nRotate -90 1 0 0\n",     /* from the side */
		"Translate 0 0 10\nRotate 180 1 0 0\n",        /* from above the lid */
	};
	for (size_t v = 0; v < 3; v++) {
		char rib[1024];
		snprintf(rib, sizeof(rib),
			 "Format 240 240 1\nPixelSamples 4 4\nPixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\nScreenWindow -4 4 -4 4\n"
			 "Display \"tea.exr\" \"file\" \"rgba\"\n%s"
			 "WorldBegin\n  Surface \"matte\"\n  Geometry \"teapot\"\nWorldEnd\n",
			 views[v]);
		struct reyes_image im = {0};
		CHECK(render(rib, "tea.exr", &im));
		CHECK(diag_text[0] == 0 || strstr(diag_text, "warning") == NULL);
		if (!im.data)
			continue;
		int a = channel(&im, "A");
		double covered = 0;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++)
				covered += px(&im, a, x, y);
		double worst;
		int holes = pinholes(&im, &worst);
		printf("view %zu: %.0f pixels covered, %d pinholes, the least alpha among them "
		       "%.4f\n", v, covered, holes, worst);
		CHECK(covered > 2000);
		/*
		 * The renderer's grids of one primitive diced at different rates
		 * meet with cracks a subpixel sample may fall through
		 * (docs/renderer.md, Limitations): the teapot's 32 patches are held
		 * to that and no worse, no pinhole losing more than one sample of
		 * 16, and fewer than one covered pixel in 1000 losing one.
		 */
		CHECK(worst >= 15.0 / 16 - 1e-4);
		CHECK(holes * 1000.0 < covered);
		reyes_image_finish(&im);
	}
}

static void test_other_names(void)
{
	const char *rib = "Format 16 16 1\nDisplay \"o.exr\" \"file\" \"rgba\"\nWorldBegin\n"
			  "  Geometry \"cow\"\nWorldEnd\n";
	struct reyes_image im = {0};
	CHECK(render(rib, "o.exr", &im));
	CHECK(strstr(diag_text, "scene.rib:4: warning: Geometry \"cow\" is not supported: "
			       "ignored (known: \"teapot\")") != NULL);
	reyes_image_finish(&im);
}

int main(void)
{
	if (!scene_dir_create("relight-teapot"))
		return 1;
	RUN(test_bound_and_facing);
	RUN(test_no_pinholes);
	RUN(test_other_names);
	scene_dir_remove();
	return test_finish();
}

/*
 * NuPatch and TrimCurve, end to end against closed forms and against the
 * primitives they must equal. Each test writes a RIB scene, renders it
 * through the scene builder and the REYES pipeline to a float OpenEXR image,
 * reads it back and compares (tolerances stated at each test):
 *
 *   - a rational NuPatch sphere (the 9-point circle swept along the 5-point
 *     half circle, order 3, weights sqrt(2)/2) against Sphere: coverage
 *     within 0.1 %, per-pixel alpha within 0.1, mean colour within 0.1 %;
 *     and with umax 0.5 against Sphere's thetamax 180 (a knot range clipped);
 *   - a square bilinear NuPatch trimmed by a rational circle: its area
 *     matches the circle's within 0.5 %; the circle reversed (clockwise)
 *     keeps the square minus the disk, and so does a counter-clockwise
 *     square loop around a clockwise circle;
 *   - a non-rational bicubic NuPatch with uniform knots against the same
 *     control points as a B-spline PatchMesh, half transparent, moving:
 *     per-pixel alpha within 0.02 and colour within 0.5 % mean;
 *   - the shadow geometry's dicer leaves out micropolygons whose centre is
 *     trimmed: their area matches the disk's within 2 % (micropolygon
 *     granularity);
 *   - malformed NuPatch and TrimCurve requests: FILE:LINE errors, only
 *     those primitives dropped (the rest of the frame is the same image).
 */
#include "reyes.h"
#include "ri.h"
#include "texture.h"
#include "config.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PI 3.14159265358979323846

static char rib[1 << 16];

/* Append to a string buffer. */
static void cat(char *buf, size_t cap, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static void cat(char *buf, size_t cap, const char *fmt, ...)
{
	size_t n = strlen(buf);
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf + n, cap - n, fmt, ap);
	va_end(ap);
}

/* The unit circle as 9 rational points (x, y, w), knots 0 0 0 .25 .25 .5 .5 .75 .75 1 1 1. */
static const double circle[9][3] = {
	{ 1, 0, 1 }, { 1, 1, 0.70710678118654752 }, { 0, 1, 1 }, { -1, 1, 0.70710678118654752 },
	{ -1, 0, 1 }, { -1, -1, 0.70710678118654752 }, { 0, -1, 1 }, { 1, -1, 0.70710678118654752 },
	{ 1, 0, 1 },
};
static const char *circle_knots = "[0 0 0 .25 .25 .5 .5 .75 .75 1 1 1]";

/* A NuPatch sphere of radius 1: the circle swept along a half circle (r, z, w), u in [0, umax]. */
static void nurbs_sphere(char *buf, size_t cap, double umax)
{
	static const double half[5][3] = {
		{ 0, -1, 1 }, { 1, -1, 0.70710678118654752 }, { 1, 0, 1 },
		{ 1, 1, 0.70710678118654752 }, { 0, 1, 1 },
	};
	cat(buf, cap, "NuPatch 9 3 %s 0 %g 5 3 [0 0 0 .5 .5 1 1 1] 0 1 \"Pw\" [", circle_knots,
	    umax);
	for (int l = 0; l < 5; l++)
		for (int k = 0; k < 9; k++) {
			double w = circle[k][2] * half[l][2];
			cat(buf, cap, " %.9g %.9g %.9g %.9g", half[l][0] * circle[k][0] * w,
			    half[l][0] * circle[k][1] * w, half[l][1] * w, w);
		}
	cat(buf, cap, "]\n");
}

/* A trim loop: the circle (cx, cy, r) in (u, v), counter-clockwise unless @cw. */
static void trim_circle(char *buf, size_t cap, double cx, double cy, double r, bool cw)
{
	const char *axis[3] = { "u", "v", "w" };
	(void)axis;
	cat(buf, cap, " [3] %s [0] [1] [9]", circle_knots);
	for (int c = 0; c < 3; c++) {
		cat(buf, cap, " [");
		for (int k = 0; k < 9; k++) {
			const double *p = circle[cw ? 8 - k : k];
			double x = c == 0 ? (cx + r * p[0]) * p[2] : c == 1 ? (cy + r * (p[1])) * p[2]
									 : p[2];
			cat(buf, cap, " %.9g", x);
		}
		cat(buf, cap, "]");
	}
}

static double alpha_sum(const struct reyes_image *im)
{
	int a = channel(im, "A");
	double s = 0.0;
	for (uint32_t y = 0; y < im->height; y++)
		for (uint32_t x = 0; x < im->width; x++)
			s += px(im, a, x, y);
	return s;
}

/* Largest per-pixel difference of channel @name, and the mean absolute one into *mean. */
static double max_diff(const struct reyes_image *a, const struct reyes_image *b, const char *name,
		       double *mean)
{
	int ca = channel(a, name), cb = channel(b, name);
	double m = 0.0, s = 0.0;
	for (uint32_t y = 0; y < a->height; y++)
		for (uint32_t x = 0; x < a->width; x++) {
			double d = fabs(px(a, ca, x, y) - px(b, cb, x, y));
			m = d > m ? d : m;
			s += d;
		}
	if (mean)
		*mean = s / ((double)a->width * a->height);
	return m;
}

static const char *sphere_head =
	"Format 96 96 1\n"
	"PixelSamples 8 8\n"
	"Projection \"perspective\" \"fov\" 40\n"
	"Display \"out.exr\" \"file\" \"rgba\"\n"
	"Translate 0 0 4\n"
	"WorldBegin\n"
	"LightSource \"pointlight\" 1 \"from\" [2 2 -2] \"intensity\" 6\n"
	"Surface \"plastic\"\n"
	"Rotate 30 1 0.3 0\n";

/*
 * The rational sphere against Sphere 1 -1 1 360, same camera: coverage
 * within 0.1 %, each pixel's alpha within 0.1, the mean colour difference
 * within 0.1 % (of 1), since normals and u, v derivatives agree too.
 */
static void sphere_case(double umax, double thetamax)
{
	struct reyes_image a = { 0 }, b = { 0 };
	snprintf(rib, sizeof(rib), "%s", sphere_head);
	nurbs_sphere(rib, sizeof(rib), umax);
	cat(rib, sizeof(rib), "WorldEnd\n");
	CHECK(render(rib, "out.exr", &a));
	snprintf(rib, sizeof(rib), "%sSphere 1 -1 1 %g\nWorldEnd\n", sphere_head, thetamax);
	CHECK(render(rib, "out.exr", &b));
	if (!a.data || !b.data)
		goto done;
	double sa = alpha_sum(&a), sb = alpha_sum(&b), mean;
	printf("sphere (umax %g): NuPatch coverage %.4f, Sphere %.4f (%.4f %%)\n", umax, sa, sb,
	       100.0 * (sa - sb) / sb);
	CHECK(sb > 500.0);
	CHECK_NEAR(sa / sb, 1.0, 1e-3);
	double da = max_diff(&a, &b, "A", NULL);
	printf("sphere: largest alpha difference %.4f\n", da);
	CHECK(da <= 0.1);
	max_diff(&a, &b, "R", &mean);
	printf("sphere: mean red difference %.5f\n", mean);
	CHECK(mean <= 1e-3);
done:
	reyes_image_finish(&a);
	reyes_image_finish(&b);
}

/* The whole sphere, and u clipped to [0, 0.5] (knot 0.5 is the circle's half): Sphere's 180. */
static void test_sphere(void)
{
	sphere_case(1.0, 360.0);
	sphere_case(0.5, 180.0);
}

static const char *square_head =
	"Format 200 200 1\n"
	"PixelSamples 8 8\n"
	"ScreenWindow -1.25 1.25 -1.25 1.25\n"
	"Display \"out.exr\" \"file\" \"rgba\"\n"
	"WorldBegin\n"
	"Surface \"constant\"\n";

/* The square [-1, 1]^2 at z = 1: u, v over [0, 1], so (u, v) areas are world areas / 4. */
static const char *square =
	"NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [-1 -1 1  1 -1 1  -1 1 1  1 1 1]\n";

/* The area the square covers with the trim curve @trim (world units, 2.5 / 200 per pixel). */
static double trimmed_area(const char *trim)
{
	struct reyes_image im = { 0 };
	snprintf(rib, sizeof(rib), "%s%s\n%sWorldEnd\n", square_head, trim, square);
	double s = -1.0;
	if (render(rib, "out.exr", &im))
		s = alpha_sum(&im) * (2.5 / 200) * (2.5 / 200);
	reyes_image_finish(&im);
	return s;
}

/*
 * A circle of radius 0.4 in (u, v) is one of radius 0.8 on the square:
 * area 0.64 pi. Counter-clockwise it keeps the disk (within 0.5 %);
 * clockwise the region to its left, the square minus the disk; a
 * counter-clockwise square loop around the clockwise circle too.
 */
static void test_trim_disk(void)
{
	char t[4096] = "TrimCurve [1]";
	trim_circle(t, sizeof(t), 0.5, 0.5, 0.4, false);
	double disk = 0.64 * PI, got = trimmed_area(t);
	printf("trim: disk area %.5f, expected %.5f (%.3f %%)\n", got, disk,
	       100.0 * (got - disk) / disk);
	CHECK_NEAR(got / disk, 1.0, 5e-3);

	snprintf(t, sizeof(t), "TrimCurve [1]");
	trim_circle(t, sizeof(t), 0.5, 0.5, 0.4, true);
	got = trimmed_area(t);
	printf("trim: reversed circle %.5f, expected %.5f (%.3f %%)\n", got, 4.0 - disk,
	       100.0 * (got - (4.0 - disk)) / (4.0 - disk));
	CHECK_NEAR(got / (4.0 - disk), 1.0, 5e-3);

	/* Two loops: an order-2 square (counter-clockwise), then the clockwise circle. */
	char c[4096] = "";
	trim_circle(c, sizeof(c), 0.5, 0.5, 0.4, true);
	/* Merge the arrays by hand: order, knot, min, max, n, u, v, w of both curves. */
	snprintf(t, sizeof(t),
		 "TrimCurve [1 1] [2 3] [0 0 1 2 3 4 4  0 0 0 .25 .25 .5 .5 .75 .75 1 1 1] [0 0] "
		 "[4 1] [5 9]");
	const char *p = c;
	for (int k = 0; k < 5; k++)         /* skip " [3] knots [0] [1] [9]" */
		p = strchr(p + 1, ']');
	p++;
	static const char *sq[3] = { "-0.1 1.1 1.1 -0.1 -0.1", "-0.1 -0.1 1.1 1.1 -0.1",
				     "1 1 1 1 1" };
	for (int k = 0; k < 3; k++) {
		const char *open = strchr(p, '['), *close = strchr(open, ']');
		cat(t, sizeof(t), " [%s %.*s]", sq[k], (int)(close - open - 1), open + 1);
		p = close + 1;
	}
	got = trimmed_area(t);
	printf("trim: square loop around a reversed circle %.5f, expected %.5f\n", got,
	       4.0 - disk);
	CHECK_NEAR(got / (4.0 - disk), 1.0, 5e-3);

	/* A trim curve ends with its attribute scope. */
	snprintf(rib, sizeof(rib), "%sAttributeBegin\nTrimCurve [1]", square_head);
	trim_circle(rib, sizeof(rib), 0.5, 0.5, 0.4, false);
	cat(rib, sizeof(rib), "\nAttributeEnd\n%sWorldEnd\n", square);
	struct reyes_image im = { 0 };
	CHECK(render(rib, "out.exr", &im));
	if (im.data)
		CHECK_NEAR(alpha_sum(&im) * (2.5 / 200) * (2.5 / 200), 4.0, 4.0 * 1e-3);
	reyes_image_finish(&im);
}

/*
 * A bicubic NuPatch with uniform knots is a B-spline patch mesh. 5 x 5
 * control points of a wavy sheet, half transparent and moving sideways
 * over the shutter: the NuPatch and the PatchMesh agree per pixel in alpha
 * within 0.02 and in red within 0.5 % mean.
 */
static void test_bspline(void)
{
	char pts[4096] = "";
	for (int j = 0; j < 5; j++)
		for (int i = 0; i < 5; i++)
			cat(pts, sizeof(pts), " %g %g %g", (i - 2) * 0.6, (j - 2) * 0.6,
			    0.3 * sin(i * 1.3 + j * 0.7));
	const char *head =
		"Format 96 96 1\n"
		"PixelSamples 8 8\n"
		"Shutter 0 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"out.exr\" \"file\" \"rgba\"\n"
		"Translate 0 0 4\n"
		"WorldBegin\n"
		"LightSource \"pointlight\" 1 \"from\" [2 2 -2] \"intensity\" 6\n"
		"Surface \"plastic\"\n"
		"Opacity [0.5 0.5 0.5]\n"
		"Rotate -30 1 0 0\n";
	char moved[4096] = "";
	for (int j = 0; j < 5; j++)
		for (int i = 0; i < 5; i++)
			cat(moved, sizeof(moved), " %g %g %g", (i - 2) * 0.6 + 0.2, (j - 2) * 0.6,
			    0.3 * sin(i * 1.3 + j * 0.7));
	struct reyes_image a = { 0 }, b = { 0 };
	snprintf(rib, sizeof(rib),
		 "%sMotionBegin [0 1]\n"
		 "NuPatch 5 4 [0 1 2 3 4 5 6 7 8] 3 5 5 4 [0 1 2 3 4 5 6 7 8] 3 5 \"P\" [%s]\n"
		 "NuPatch 5 4 [0 1 2 3 4 5 6 7 8] 3 5 5 4 [0 1 2 3 4 5 6 7 8] 3 5 \"P\" [%s]\n"
		 "MotionEnd\nWorldEnd\n", head, pts, moved);
	CHECK(render(rib, "out.exr", &a));
	snprintf(rib, sizeof(rib),
		 "%sBasis \"b-spline\" 1 \"b-spline\" 1\nMotionBegin [0 1]\n"
		 "PatchMesh \"bicubic\" 5 \"nonperiodic\" 5 \"nonperiodic\" \"P\" [%s]\n"
		 "PatchMesh \"bicubic\" 5 \"nonperiodic\" 5 \"nonperiodic\" \"P\" [%s]\n"
		 "MotionEnd\nWorldEnd\n", head, pts, moved);
	CHECK(render(rib, "out.exr", &b));
	if (!a.data || !b.data)
		goto done;
	double mean, sa = alpha_sum(&a), sb = alpha_sum(&b);
	double da = max_diff(&a, &b, "A", NULL);
	max_diff(&a, &b, "R", &mean);
	printf("bspline: coverage %.3f vs %.3f, largest alpha difference %.4f, mean red %.5f\n",
	       sa, sb, da, mean);
	CHECK(sb > 300.0);
	CHECK(da <= 0.02);
	CHECK(mean <= 5e-3);
done:
	reyes_image_finish(&a);
	reyes_image_finish(&b);
}

/* ---- the shadow geometry's dicer ---- */

struct kept {
	double area;
	uint64_t grids;
};

static bool on_grid(void *user, const struct reyes_prim *prim, const float *P, uint32_t nu,
		    uint32_t nv, const uint8_t *keep, const float *Os)
{
	(void)Os;
	(void)prim;
	struct kept *k = user;
	uint32_t n = nu * nv;
	k->grids++;
	for (uint32_t j = 0; j + 1 < nv; j++)
		for (uint32_t i = 0; i + 1 < nu; i++) {
			if (keep && !keep[j * (nu - 1) + i])
				continue;
			uint32_t a = j * nu + i, b = a + 1, c = a + nu + 1, d = a + nu;
			/* the quad's area in x, y (the square faces the camera) */
			double x[4] = { P[a], P[b], P[c], P[d] }, y[4] = { P[n + a], P[n + b],
									  P[n + c], P[n + d] };
			double s = 0.0;
			for (int q = 0; q < 4; q++)
				s += x[q] * y[(q + 1) % 4] - x[(q + 1) % 4] * y[q];
			k->area += 0.5 * fabs(s);
		}
	return true;
}

static struct kept kept_result;

static bool dice_frame(void *user, const struct reyes_scene *scene)
{
	(void)user;
	struct reyes_dice_opts o = { .rate = 1, .grid = on_grid, .user = &kept_result };
	return reyes_dice(scene, &o);
}

static void test_shadow_dice(void)
{
	snprintf(rib, sizeof(rib), "%sTrimCurve [1]", square_head);
	trim_circle(rib, sizeof(rib), 0.5, 0.5, 0.4, false);
	cat(rib, sizeof(rib), "\n%sWorldEnd\n", square);
	const char *path = tmp_path("dice.rib");
	FILE *f = fopen(path, "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs(rib, f);
	fclose(f);
	memset(&kept_result, 0, sizeof(kept_result));
	struct reyes_ri_opts o = { .default_shader_path = RELIGHT_SOURCE_SHADER_DIR,
				   .frame = dice_frame };
	int nerr = 0;
	CHECK(reyes_ri_read(path, &o, &nerr) && nerr == 0);
	double disk = 0.64 * PI;
	printf("shadow dice: %llu grids, kept area %.4f, disk %.4f\n",
	       (unsigned long long)kept_result.grids, kept_result.area, disk);
	CHECK(kept_result.grids > 0);
	CHECK_NEAR(kept_result.area / disk, 1.0, 0.02);
}

/* ---- malformed input ---- */

static void test_malformed(void)
{
	const char *head =
		"Format 64 64 1\n"
		"PixelSamples 4 4\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"out.exr\" \"file\" \"rgba\"\n"
		"Translate 0 0 4\n"
		"WorldBegin\n"
		"Surface \"constant\"\n"
		"Sphere 0.5 -0.5 0.5 360\n";
	static const struct {
		const char *rib, *msg;
	} bad[] = {
		{ "NuPatch 2 2 [0 1 0 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]",
		  "a knot vector decreases" },
		{ "NuPatch 2 2 [0 0 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]",
		  "uknot has 3 values, expected 4" },
		{ "NuPatch 2 1 [0 1 2] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]",
		  "an order is below 2" },
		{ "NuPatch 2 2 [0 0 1 1] 1 0 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]",
		  "min is not below max" },
		{ "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0]",
		  "\"P\" has 3" },
		{ "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"Pw\" [0 0 0 1 1 0 0 -1 0 1 0 1 1 1 0 1]",
		  "not positive" },
		{ "AttributeBegin\nTrimCurve [2] [3] [0 0 0 1 1 1] [0] [1] [3] [0 1 1] [0 0 1] [1 1 1]\n"
		  "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
		  "AttributeEnd", "ncurves adds up to 2 curves" },
		{ "AttributeBegin\nTrimCurve [1] [3] [0 0 0 1 1] [0] [1] [3] [0 1 1] [0 0 1] [1 1 1]\n"
		  "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
		  "AttributeEnd", "knot has 5 values, expected 6" },
		{ "AttributeBegin\nTrimCurve [1] [3] [0 0 0 1 1 1] [0] [1] [3] [0 1 1] [0 0 1] [1 1 1]\n"
		  "NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 \"P\" [0 0 0 1 0 0 0 1 0 1 1 0] "
		  "\"uniform float k\" [1 2]\nAttributeEnd", "needs 1 values, got 2" },
	};
	struct reyes_image ref = { 0 };
	snprintf(rib, sizeof(rib), "%sWorldEnd\n", head);
	CHECK(render(rib, "out.exr", &ref));
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		snprintf(rib, sizeof(rib), "%s%s\nWorldEnd\n", head, bad[i].rib);
		unlink(tmp_path("out.exr"));
		struct reyes_image im = { 0 };
		failure_expected = true;
		bool ok = render(rib, "out.exr", &im);
		failure_expected = false;
		CHECK(!ok);
		/* the request is on line 9 (a TrimCurve on line 10, its NuPatch on 11) */
		bool where = strstr(diag_text, "scene.rib:9: error:") ||
			     strstr(diag_text, "scene.rib:10: error:") ||
			     strstr(diag_text, "scene.rib:11: error:");
		if (!where || !strstr(diag_text, bad[i].msg))
			printf("malformed %zu: diagnostics:\n%s", i, diag_text);
		CHECK(where);
		CHECK(strstr(diag_text, bad[i].msg) != NULL);
		/* the rest of the frame renders, the same image */
		CHECK(reyes_image_read_exr(tmp_path("out.exr"), &im, NULL));
		if (im.data && ref.data)
			CHECK(max_diff(&im, &ref, "A", NULL) == 0.0);
		reyes_image_finish(&im);
	}
	reyes_image_finish(&ref);
}

int main(void)
{
	if (!scene_dir_create("relight-nurbs"))
		return 1;
	RUN(test_sphere);
	RUN(test_trim_disk);
	RUN(test_bspline);
	RUN(test_shadow_dice);
	RUN(test_malformed);
	scene_dir_remove();
	return test_finish();
}

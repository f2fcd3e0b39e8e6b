/*
 * The reference renderer end to end, against closed forms: each test writes
 * a RIB scene, renders it through the scene builder and the REYES pipeline
 * to OpenEXR, reads the image back and compares.
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

/*
 * A Lambertian (matte, Kd 1) plane z = 4 facing the camera, lit by a point
 * light of intensity 4 at (0, 0, 2): at a point at distance d from the light,
 * the cosine is 2/d and the falloff 1/d^2, so Ci = 4 * (2/d) / d^2 = 8/d^3.
 * A box filter one pixel wide averages that over the pixel; at a shading rate
 * of 0.25 with smooth interpolation the pixel matches the value at its centre
 * within 1% (the function's curvature over a pixel is far below that).
 */
static void test_lambert_plane(void)
{
	const char *rib =
		"Format 64 64 1\n"
		"PixelSamples 4 4\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"lambert.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  LightSource \"pointlight\" 1 \"intensity\" 4 \"from\" [0 0 2]\n"
		"  ShadingRate 0.25\n"
		"  ShadingInterpolation \"smooth\"\n"
		"  Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"  Polygon \"P\" [-10 -10 4  10 -10 4  10 10 4  -10 10 4]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "lambert.exr", &im));
	if (!im.data)
		return;
	int r = channel(&im, "R"), a = channel(&im, "A");
	CHECK(r >= 0 && a >= 0);
	if (r < 0 || a < 0)
		return;
	float t = tanf(20.0f * 3.14159265f / 180.0f);
	double worst = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			double sx = -1 + 2 * (x + 0.5) / im.width, sy = 1 - 2 * (y + 0.5) / im.height;
			double X = sx * 4 * t, Y = sy * 4 * t;
			double d = sqrt(X * X + Y * Y + 4);
			double want = 8 / (d * d * d);
			double rel = fabs(px(&im, r, x, y) - want) / want;
			if (rel > worst)
				worst = rel;
			CHECK_NEAR(px(&im, a, x, y), 1, 1e-6);
		}
	printf("lambert plane: worst relative error %.4f%% (tolerance 1%%)\n", worst * 100);
	CHECK(worst <= 0.01);
	reyes_image_finish(&im);
}

/*
 * A sphere seen orthographically is a disk: with 8x8 samples each pixel's
 * alpha is within 0.1 of the exact disk-pixel overlap, and the total within
 * 0.5% of pi r^2.
 */
static void test_sphere_coverage(void)
{
	const char *rib =
		"Format 32 32 1\n"
		"PixelSamples 8 8\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -1 1 -1 1\n"
		"Display \"sphere.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  Translate 0 0 5\n"
		"  Sphere 0.6 -0.6 0.6 360\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "sphere.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A");
	CHECK(a >= 0);
	if (a < 0)
		return;
	double rad = 0.6 / (2.0 / 32), total = 0, worst = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			double want = disk_pixel(16, 16, rad, x, y);
			double got = px(&im, a, x, y);
			total += got;
			if (fabs(got - want) > worst)
				worst = fabs(got - want);
		}
	double area = 3.14159265358979 * rad * rad;
	printf("sphere: worst pixel alpha error %.4f (tolerance 0.1), total %.3f vs %.3f "
	       "(%.3f%%, tolerance 0.5%%)\n", worst, total, area, 100 * fabs(total - area) / area);
	CHECK(worst <= 0.1);
	CHECK_NEAR(total, area, 0.005 * area);
	reyes_image_finish(&im);
}

/*
 * A disk of radius 3 pixels moving 8 pixels to the right over the shutter:
 * each pixel's alpha is the fraction of the shutter the disk covers it,
 * averaged over the pixel (computed here by fine sampling in space and time).
 * Shading rate 0.25 keeps the tessellated outline's area within about 0.5%
 * of the circle's (an inscribed polygon of ~38 sides), so the comparison
 * measures motion sampling; the same disk rendered still must cover the same
 * total, which isolates the motion from the tessellation exactly.
 */
static void test_motion_coverage(void)
{
	const char *rib =
		"Format 32 16 1\n"
		"PixelSamples 8 8\n"
		"PixelFilter \"box\" 1 1\n"
		"Shutter 0 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -16 16 -8 8\n"
		"Display \"motion.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  ShadingRate 0.25\n"
		"  MotionBegin [0 1]\n"
		"    Translate -4 0 5\n"
		"    Translate 4 0 5\n"
		"  MotionEnd\n"
		"  Disk 0 3 360\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "motion.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A");
	CHECK(a >= 0);
	if (a < 0)
		return;
	double total = 0, want_total = 0, worst = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			/* disk centre moves from x = 12 to 20 (pixels), y = 8 */
			int nt = 64, ns = 32;
			double cov = 0;
			for (int k = 0; k < nt; k++) {
				double cx = 12 + 8 * (k + 0.5) / nt;
				for (int j = 0; j < ns; j++)
					for (int i = 0; i < ns; i++) {
						double sx = x + (i + 0.5) / ns - cx;
						double sy = y + (j + 0.5) / ns - 8;
						cov += sx * sx + sy * sy <= 9;
					}
			}
			cov /= (double)nt * ns * ns;
			double got = px(&im, a, x, y);
			total += got;
			want_total += cov;
			if (fabs(got - cov) > worst)
				worst = fabs(got - cov);
		}
	printf("moving disk: worst pixel error %.4f (tolerance 0.1), total %.3f vs %.3f\n", worst,
	       total, want_total);
	CHECK(worst <= 0.1);
	CHECK_NEAR(total, want_total, 0.01 * want_total);
	reyes_image_finish(&im);

	const char *still =
		"Format 32 16 1\n"
		"PixelSamples 8 8\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -16 16 -8 8\n"
		"Display \"still.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  ShadingRate 0.25\n"
		"  Translate 0 0 5\n"
		"  Disk 0 3 360\n"
		"WorldEnd\n";
	struct reyes_image st = { 0 };
	CHECK(render(still, "still.exr", &st));
	if (!st.data)
		return;
	double still_total = 0;
	for (size_t p = 0; p < (size_t)st.width * st.height; p++)
		still_total += st.data[p * st.nchannels + (size_t)channel(&st, "A")];
	printf("moving disk total %.3f, still disk total %.3f (tolerance 0.5%%)\n", total,
	       still_total);
	CHECK_NEAR(total, still_total, 0.005 * still_total);
	reyes_image_finish(&st);
}

/*
 * Two 50%-opaque planes, red at z = 4 and blue at z = 6: whatever the order of
 * declaration, the image is red over blue: (0.5, 0, 0.25), alpha 0.75.
 */
static void test_transparency_order(void)
{
	static const char *const orders[2][2] = {
		{ "Color [1 0 0] Polygon \"P\" [-9 -9 4  9 -9 4  9 9 4  -9 9 4]\n",
		  "Color [0 0 1] Polygon \"P\" [-9 -9 6  9 -9 6  9 9 6  -9 9 6]\n" },
		{ "Color [0 0 1] Polygon \"P\" [-9 -9 6  9 -9 6  9 9 6  -9 9 6]\n",
		  "Color [1 0 0] Polygon \"P\" [-9 -9 4  9 -9 4  9 9 4  -9 9 4]\n" },
	};
	for (int o = 0; o < 2; o++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Format 16 16 1\n"
			 "PixelSamples 2 2\n"
			 "Projection \"perspective\" \"fov\" 30\n"
			 "Display \"transp.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"constant\"\n"
			 "  Opacity [0.5 0.5 0.5]\n"
			 "  %s  %s"
			 "WorldEnd\n",
			 orders[o][0], orders[o][1]);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "transp.exr", &im));
		if (!im.data)
			continue;
		int r = channel(&im, "R"), g = channel(&im, "G"), b = channel(&im, "B"),
		    a = channel(&im, "A");
		CHECK(r >= 0 && g >= 0 && b >= 0 && a >= 0);
		if (r < 0 || g < 0 || b < 0 || a < 0)
			continue;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				CHECK_NEAR(px(&im, r, x, y), 0.5, 1e-4);
				CHECK_NEAR(px(&im, g, x, y), 0, 1e-4);
				CHECK_NEAR(px(&im, b, x, y), 0.25, 1e-4);
				CHECK_NEAR(px(&im, a, x, y), 0.75, 1e-4);
			}
		reyes_image_finish(&im);
	}
}

/*
 * A one-sided sphere under a mirroring transform (Scale 1 1 -1) still shows
 * its outside: the same coverage as without the mirror, and its normals
 * still face the camera (a matte sphere lit from the camera is not black).
 */
static void test_mirror_one_sided(void)
{
	float total[2] = { 0, 0 }, lit[2] = { 0, 0 };
	for (int m = 0; m < 2; m++) {
		char rib[1024];
		snprintf(rib, sizeof(rib),
			 "Format 32 32 1\n"
			 "PixelSamples 4 4\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -1 1 -1 1\n"
			 "Display \"mirror.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  LightSource \"distantlight\" 1 \"from\" [0 0 0] \"to\" [0 0 1]\n"
			 "  Sides 1\n"
			 "  Surface \"matte\" \"Ka\" 0\n"
			 "  Translate 0 0 5\n"
			 "  %s\n"
			 "  Sphere 0.6 -0.6 0.6 360\n"
			 "WorldEnd\n",
			 m ? "Scale 1 1 -1" : "");
		struct reyes_image im = { 0 };
		CHECK(render(rib, "mirror.exr", &im));
		if (!im.data)
			return;
		int a = channel(&im, "A"), r = channel(&im, "R");
		for (size_t p = 0; p < (size_t)im.width * im.height; p++) {
			total[m] += im.data[p * im.nchannels + (size_t)a];
			lit[m] += im.data[p * im.nchannels + (size_t)r];
		}
		reyes_image_finish(&im);
	}
	printf("mirror: coverage %.2f vs %.2f, light %.2f vs %.2f\n", total[1], total[0], lit[1],
	       lit[0]);
	CHECK(total[0] > 100);
	CHECK_NEAR(total[1], total[0], 0.01 * total[0]);
	CHECK_NEAR(lit[1], lit[0], 0.01 * lit[0]);
}

/*
 * MakeTexture and texture() through a render: a 32x32 texture whose red
 * channel is s at each texel centre ((i + 0.5) / 32), mapped by "st" onto a
 * square that fills a 32x32 image exactly, so each pixel looks up its own
 * texel: the red channel equals the pixel's s within 1% (filtering a linear
 * ramp symmetrically keeps its value), green is t, and blue the constant 0.25.
 * Jitter is off: jittered samples would average the ramp at random places in
 * the pixel (about 0.1 pixel off its centre), which is sampling noise, not
 * texture filtering; samples at stratum centres average it exactly.
 */
static void test_texture_lookup(void)
{
	const char *names[3] = { "R", "G", "B" };
	struct reyes_image tex;
	CHECK(reyes_image_init(&tex, 32, 32, 3, names));
	for (uint32_t y = 0; y < 32; y++)
		for (uint32_t x = 0; x < 32; x++) {
			float *p = &tex.data[(y * 32 + x) * 3];
			p[0] = (x + 0.5f) / 32;
			p[1] = (y + 0.5f) / 32;
			p[2] = 0.25f;
		}
	CHECK(reyes_image_write_exr(tmp_path("ramp.exr"), &tex, false, NULL));
	reyes_image_finish(&tex);
	FILE *f = fopen(tmp_path("texcolor.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("surface texcolor(string texturename = \"\") {\n"
	      "\tOi = 1;\n\tCi = color texture(texturename);\n}\n", f);
	fclose(f);
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"MakeTexture \"ramp.exr\" \"ramp.tex\" \"clamp\" \"clamp\" \"box\" 1 1\n"
		"Format 32 32 1\n"
		"PixelSamples 2 2\n"
		"PixelFilter \"box\" 1 1\n"
		"Hider \"hidden\" \"jitter\" 0\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -1 1 -1 1\n"
		"Display \"tex.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"texcolor\" \"texturename\" \"ramp.tex\"\n"
		"  ShadingInterpolation \"smooth\"\n"
		"  Translate 0 0 5\n"
		"  Polygon \"P\" [-1 1 0  1 1 0  1 -1 0  -1 -1 0]\n"
		"          \"st\" [0 0  1 0  1 1  0 1]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "tex.exr", &im));
	if (!im.data)
		return;
	int r = channel(&im, "R"), g = channel(&im, "G"), b = channel(&im, "B");
	double worst = 0;
	for (uint32_t y = 2; y < 30; y++)
		for (uint32_t x = 2; x < 30; x++) {
			double ws = (x + 0.5) / 32, wt = (y + 0.5) / 32;
			worst = fmax(worst, fabs(px(&im, r, x, y) - ws) / ws);
			worst = fmax(worst, fabs(px(&im, g, x, y) - wt) / wt);
			CHECK_NEAR(px(&im, b, x, y), 0.25, 0.0025);
		}
	printf("texture: worst relative error %.4f%% (tolerance 1%%)\n", worst * 100);
	CHECK(worst <= 0.01);
	reyes_image_finish(&im);
}

/*
 * Shadow maps through a render: a shadowspot above the plane y = 0, a 1x1
 * square occluder at height 1 between them. Frame 1 renders depth from the
 * light, MakeShadow makes the map, frame 2 looks straight down at the plane.
 * The umbra (the occluder's projection from the light) must be black; points
 * well outside it must match a render without the occluder within 2% (no
 * self-shadowing of the lit plane).
 */
static void test_shadow_map(void)
{
	float lit_sum[3] = { 0, 0, 0 };
	double umbra = 0, umbra_nocast = 0;
	/* 0: no occluder, 1: an occluder, 2: an occluder that casts no shadow */
	for (int occluded = 0; occluded < 3; occluded++) {
		char rib[4096];
		const char *occluder =
			occluded == 1 ? "  Polygon \"P\" [-0.5 1 -0.5  -0.5 1 0.5  0.5 1 0.5  0.5 1 -0.5]\n" :
			occluded == 2 ? "  Attribute \"visibility\" \"transmission\" 0\n"
					"  Polygon \"P\" [-0.5 1 -0.5  -0.5 1 0.5  0.5 1 0.5  0.5 1 -0.5]\n" :
					"";
		snprintf(rib, sizeof(rib),
			 "FrameBegin 1\n"
			 "  Format 256 256 1\n"
			 "  PixelSamples 1 1\n"
			 "  PixelFilter \"box\" 1 1\n"
			 "  Hider \"hidden\" \"depthfilter\" \"midpoint\"\n"
			 "  Projection \"perspective\" \"fov\" 90\n"
			 "  Display \"light.z\" \"zfile\" \"z\"\n"
			 "  Rotate -90 1 0 0\n"
			 "  Translate 0 -3 0\n"
			 "  WorldBegin\n"
			 "    Surface \"constant\"\n"
			 "    Polygon \"P\" [-6 0 -6  -6 0 6  6 0 6  6 0 -6]\n"
			 "%s"
			 "  WorldEnd\n"
			 "FrameEnd\n"
			 "MakeShadow \"light.z\" \"light.shd\"\n"
			 "FrameBegin 2\n"
			 "  Format 64 64 1\n"
			 "  PixelSamples 2 2\n"
			 "  PixelFilter \"box\" 1 1\n"
			 "  Projection \"orthographic\"\n"
			 "  ScreenWindow -4 4 -4 4\n"
			 "  Display \"shadowed.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "  Rotate -90 1 0 0\n"
			 "  Translate 0 -10 0\n"
			 "  WorldBegin\n"
			 "    LightSource \"shadowspot\" 1 \"intensity\" 9 \"from\" [0 3 0] \"to\" [0 0 0]\n"
			 "        \"coneangle\" 1.2 \"conedeltaangle\" 0.05 \"shadowname\" \"%s\"\n"
			 "        \"samples\" 16\n"
			 "    Surface \"matte\" \"Ka\" 0\n"
			 "    Polygon \"P\" [-6 0 -6  -6 0 6  6 0 6  6 0 -6]\n"
			 "  WorldEnd\n"
			 "FrameEnd\n",
			 occluder, occluded ? "light.shd" : "");
		struct reyes_image im = { 0 };
		CHECK(render(rib, "shadowed.exr", &im));
		if (!im.data)
			return;
		int r = channel(&im, "R");
		/* Plane point (X, Z) seen at pixel x = (X + 4) * 8, y = (Z + 4) * 8 (Z down
		 * the image: the camera looks down -y with its up along +z). The umbra: a
		 * square of half-size 0.5 * 3 / 2 = 0.75 around the origin. */
		for (uint32_t y = 0; y < 64; y++)
			for (uint32_t x = 0; x < 64; x++) {
				double X = (x + 0.5) / 8 - 4, Z = 4 - (y + 0.5) / 8;
				double v = px(&im, r, x, y);
				if (fabs(X) < 0.6 && fabs(Z) < 0.6 && occluded == 1)
					umbra = fmax(umbra, v);
				if (fabs(X) < 0.6 && fabs(Z) < 0.6 && occluded == 2)
					umbra_nocast = fmax(umbra_nocast, v);
				/* outside the penumbra margin, inside the cone */
				if ((fabs(X) > 1.0 || fabs(Z) > 1.0) && X * X + Z * Z < 4)
					lit_sum[occluded] += (float)v;
			}
		reyes_image_finish(&im);
	}
	printf("shadow: brightest umbra pixel %.4f, lit region %.3f vs %.3f unshadowed\n", umbra,
	       lit_sum[1], lit_sum[0]);
	CHECK(lit_sum[0] > 10);
	CHECK(umbra < 0.02);
	CHECK_NEAR(lit_sum[1], lit_sum[0], 0.02 * lit_sum[0]);
	/* an occluder that casts no shadow leaves the plane lit under it */
	printf("shadow: under an occluder that casts no shadow %.4f\n", umbra_nocast);
	CHECK(umbra_nocast > 0.5);
}

/* Every pixel of channel @name of @im is @want within @tol; the worst error is printed. */
static void check_flat(const struct reyes_image *im, const char *what, const char *name,
		       double want, double tol)
{
	int c = channel(im, name);
	CHECK(c >= 0);
	if (c < 0)
		return;
	double worst = 0;
	for (uint32_t y = 0; y < im->height; y++)
		for (uint32_t x = 0; x < im->width; x++)
			worst = fmax(worst, fabs(px(im, c, x, y) - want));
	printf("%s: %s %.5f expected, worst error %.2g (tolerance %.2g)\n", what, name, want,
	       worst, tol);
	CHECK(worst <= tol);
}

/* The bilinear mix of the four corner colours of the square [-1, 1]^2 at (X, Y). */
static const float corner_rgb[4][3] = {
	{ 1, 0, 0 },     /* (-1, -1) */
	{ 0, 1, 0 },     /* ( 1, -1) */
	{ 0, 0, 1 },     /* ( 1,  1) */
	{ 1, 1, 1 },     /* (-1,  1) */
};

static double bilinear_mix(int c, double X, double Y)
{
	double u = (X + 1) / 2, v = (Y + 1) / 2;
	return (1 - u) * (1 - v) * corner_rgb[0][c] + u * (1 - v) * corner_rgb[1][c] +
	       u * v * corner_rgb[2][c] + (1 - u) * v * corner_rgb[3][c];
}

/*
 * Primitive variables bound to a shader parameter declared varying reach the
 * shader, each class interpolated as RISpec says, on each kind of primitive
 * that takes them: an orthographic 32x32 view of the square [-1, 1]^2 whose
 * surface shows the parameter as it is. Varying and vertex values on a
 * Polygon, varying on a bilinear Patch (bilinear over its corners),
 * facevarying on PointsPolygons (per face corner), and vertex values on a
 * bicubic Bezier patch (interpolated as the position: the control points and
 * colours lie on the same bilinear map, which the Bezier basis reproduces).
 * The facevarying case has two faces sharing an edge, the right one given
 * the complement of the mix at its corners: a value per face corner, not
 * per vertex.
 * Each pixel (box filter, one pixel wide) averages a bilinear function, which
 * is its value at the pixel's centre: within 1% of the colour range, the
 * corners' colours and the centre's mix (0.5 0.5 0.5) included.
 */
static void test_varying_primvars(void)
{
	CHECK(scene_write_file("showvc.sl",
			 "surface showvc(varying color vc = 0) { Oi = 1; Ci = vc; }\n"));
	char bez_p[1024] = "", bez_c[1024] = "";
	size_t lp = 0, lc = 0;
	for (int j = 0; j < 4; j++)
		for (int i = 0; i < 4; i++) {
			double X = -1 + 2 * i / 3.0, Y = -1 + 2 * j / 3.0;
			lp += (size_t)snprintf(bez_p + lp, sizeof(bez_p) - lp, " %.9g %.9g 0", X, Y);
			lc += (size_t)snprintf(bez_c + lc, sizeof(bez_c) - lc, " %.9g %.9g %.9g",
					       bilinear_mix(0, X, Y), bilinear_mix(1, X, Y),
					       bilinear_mix(2, X, Y));
		}
	/* Two faces sharing the edge X = 0: the left one takes the mix, the
	   right one its complement, so that the shared vertices carry a value
	   per face. */
	static const double fv_xy[8][2] = { { -1, -1 }, { 0, -1 }, { 0, 1 }, { -1, 1 },
					    { 0, -1 }, { 1, -1 }, { 1, 1 }, { 0, 1 } };
	char fv_c[1024] = "";
	size_t lf = 0;
	for (int k = 0; k < 8; k++)
		for (int c = 0; c < 3; c++) {
			double m = bilinear_mix(c, fv_xy[k][0], fv_xy[k][1]);
			lf += (size_t)snprintf(fv_c + lf, sizeof(fv_c) - lf, " %.9g", k < 4 ? m : 1 - m);
		}
	char facevarying[1400];
	snprintf(facevarying, sizeof(facevarying),
		 "PointsPolygons [4 4] [0 1 4 5  1 2 3 4]"
		 " \"P\" [-1 -1 0  0 -1 0  1 -1 0  1 1 0  0 1 0  -1 1 0]"
		 " \"facevarying color vc\" [%s]", fv_c);
	char bezier[2400];
	snprintf(bezier, sizeof(bezier),
		 "Patch \"bicubic\" \"P\" [%s] \"vertex color vc\" [%s]", bez_p, bez_c);
	const struct {
		const char *what, *prim;
		bool complement;    /* right of X = 0 the complement of the mix */
	} cases[] = {
		{ "Polygon varying",
		  "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"
		  " \"varying color vc\" [1 0 0  0 1 0  0 0 1  1 1 1]" },
		{ "Polygon vertex",
		  "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]"
		  " \"vertex color vc\" [1 0 0  0 1 0  0 0 1  1 1 1]" },
		{ "bilinear Patch varying",
		  "Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]"
		  " \"varying color vc\" [1 0 0  0 1 0  1 1 1  0 0 1]" },
		{ "PointsPolygons varying",
		  "PointsPolygons [4] [3 0 1 2] \"P\" [1 -1 0  1 1 0  -1 1 0  -1 -1 0]"
		  " \"varying color vc\" [0 1 0  0 0 1  1 1 1  1 0 0]" },
		{ "PointsPolygons facevarying", facevarying, true },
		{ "bicubic Patch vertex", bezier },
	};
	for (size_t k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
		char rib[4096];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" \"%s:@\"\n"
			 "Format 32 32 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "Display \"varying.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Translate 0 0 5\n"
			 "  ShadingRate 0.25\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  Surface \"showvc\"\n"
			 "  %s\n"
			 "WorldEnd\n", tmpdir, cases[k].prim);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "varying.exr", &im));
		if (!im.data)
			continue;
		int ch[3] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B") };
		CHECK(ch[0] >= 0 && ch[1] >= 0 && ch[2] >= 0);
		if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0) {
			reyes_image_finish(&im);
			continue;
		}
		double worst = 0;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				double X = -1 + 2 * (x + 0.5) / im.width;
				double Y = 1 - 2 * (y + 0.5) / im.height;
				bool complement = cases[k].complement && X > 0;
				for (int c = 0; c < 3; c++) {
					double m = bilinear_mix(c, X, Y);
					worst = fmax(worst, fabs(px(&im, ch[c], x, y) -
								 (complement ? 1 - m : m)));
				}
			}
		/* the corner pixels are their corners' colours within a pixel's slope */
		printf("%s: worst error %.4f (tolerance 0.01); corner (-1,-1) %.3f %.3f %.3f, "
		       "centre %.3f %.3f %.3f\n", cases[k].what, worst,
		       px(&im, ch[0], 0, im.height - 1), px(&im, ch[1], 0, im.height - 1),
		       px(&im, ch[2], 0, im.height - 1),
		       0.25 * (px(&im, ch[0], 15, 15) + px(&im, ch[0], 16, 15) +
			       px(&im, ch[0], 15, 16) + px(&im, ch[0], 16, 16)),
		       0.25 * (px(&im, ch[1], 15, 15) + px(&im, ch[1], 16, 15) +
			       px(&im, ch[1], 15, 16) + px(&im, ch[1], 16, 16)),
		       0.25 * (px(&im, ch[2], 15, 15) + px(&im, ch[2], 16, 15) +
			       px(&im, ch[2], 15, 16) + px(&im, ch[2], 16, 16)));
		CHECK(worst <= 0.01);
		reyes_image_finish(&im);
	}

	/* A uniform parameter takes the variable's value, every component of it. */
	CHECK(scene_write_file("showuc.sl",
			 "surface showuc(uniform color uc = 0) { Oi = 1; Ci = uc; }\n"));
	static const char *const uniform_prims[] = {
		"Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] \"uniform color uc\" [0.2 0.4 0.6]",
		"Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] \"constant color uc\" [0.2 0.4 0.6]",
	};
	for (size_t k = 0; k < 2; k++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" \"%s:@\"\n"
			 "Format 8 8 1\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "Display \"uniform.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Translate 0 0 5\n"
			 "  Surface \"showuc\"\n"
			 "  %s\n"
			 "WorldEnd\n", tmpdir, uniform_prims[k]);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "uniform.exr", &im));
		if (!im.data)
			continue;
		check_flat(&im, k ? "constant color on a uniform parameter"
				  : "uniform color on a uniform parameter", "R", 0.2, 1e-6);
		check_flat(&im, "... green", "G", 0.4, 1e-6);
		check_flat(&im, "... blue", "B", 0.6, 1e-6);
		reyes_image_finish(&im);
	}
}

/*
 * Lights declared before WorldBegin, and before the first FrameBegin, as the
 * RenderMan Companion's scenes do: their shader space is camera space (the
 * camera transformation after them does not turn them), and they light every
 * frame that follows; one declared inside a frame ends with it; Illuminate
 * before WorldBegin switches one off for its frame. A matte (Kd 1, Ka 0)
 * plane facing the camera, lit by a distant light of intensity 2 shining
 * along camera (0, -1, 1): Ci = 2 cos 45 = 1.41421; frame 1 adds a light of
 * intensity 1 straight ahead (2.41421); in frame 3 light 1 is off (0).
 * Within 0.1% (a flat plane, a constant value: only float rounding).
 */
static void test_lights_before_world(void)
{
	const char *rib =
		"Format 16 16 1\n"
		"PixelSamples 2 2\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"LightSource \"distantlight\" 1 \"intensity\" 2 \"to\" [0 -1 1]\n"
		"FrameBegin 1\n"
		"  Display \"pre1.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"  LightSource \"distantlight\" 2 \"intensity\" 1\n"
		"  Rotate 30 0 1 0\n"
		"  WorldBegin\n"
		"    Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"    CoordSysTransform \"camera\"\n"
		"    Polygon \"P\" [-3 -3 5  3 -3 5  3 3 5  -3 3 5]\n"
		"  WorldEnd\n"
		"FrameEnd\n"
		"FrameBegin 2\n"
		"  Display \"pre2.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"  Rotate 30 0 1 0\n"
		"  WorldBegin\n"
		"    Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"    CoordSysTransform \"camera\"\n"
		"    Polygon \"P\" [-3 -3 5  3 -3 5  3 3 5  -3 3 5]\n"
		"  WorldEnd\n"
		"FrameEnd\n"
		"FrameBegin 3\n"
		"  Display \"pre3.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"  Illuminate 1 0\n"
		"  WorldBegin\n"
		"    Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"    Polygon \"P\" [-3 -3 5  3 -3 5  3 3 5  -3 3 5]\n"
		"  WorldEnd\n"
		"FrameEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "pre1.exr", &im));
	if (im.data) {
		check_flat(&im, "light before FrameBegin and one in frame 1", "R",
			   2 * sqrt(0.5) + 1, 1e-3 * (2 * sqrt(0.5) + 1));
		check_flat(&im, "frame 1 coverage", "A", 1, 1e-6);
		reyes_image_finish(&im);
	}
	CHECK(reyes_image_read_exr(tmp_path("pre2.exr"), &im, NULL));
	if (im.data) {
		check_flat(&im, "light before FrameBegin, frame 2", "R", 2 * sqrt(0.5),
			   1e-3 * 2 * sqrt(0.5));
		reyes_image_finish(&im);
	}
	CHECK(reyes_image_read_exr(tmp_path("pre3.exr"), &im, NULL));
	if (im.data) {
		check_flat(&im, "Illuminate 1 0 before WorldBegin, frame 3", "R", 0, 1e-6);
		check_flat(&im, "frame 3 coverage", "A", 1, 1e-6);
		reyes_image_finish(&im);
	}
}

/*
 * Attributes set inside ObjectBegin are the object's: an object whose
 * definition sets Color red, Opacity 0.5 and the "constant" surface is red
 * and half transparent wherever it is instanced, whatever the instance's
 * colour; an object whose definition sets none takes the instance's (blue,
 * opaque, "constant"). Left half of the image the first, right half the
 * second; exact within float rounding (constant colours, flat coverage).
 */
static void test_object_attributes(void)
{
	const char *rib =
		"Format 16 8 1\n"
		"PixelSamples 2 2\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -2 2 -1 1\n"
		"Display \"objects.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"ObjectBegin \"own\"\n"
		"  Color [1 0 0]\n"
		"  Opacity [0.5 0.5 0.5]\n"
		"  Surface \"constant\"\n"
		"  Polygon \"P\" [-2 -1 0  0 -1 0  0 1 0  -2 1 0]\n"
		"ObjectEnd\n"
		"WorldBegin\n"
		"  Translate 0 0 5\n"
		"  ObjectBegin \"plain\"\n"
		"    Polygon \"P\" [0 -1 0  2 -1 0  2 1 0  0 1 0]\n"
		"  ObjectEnd\n"
		"  Surface \"constant\"\n"
		"  Color [0 0 1]\n"
		"  ObjectInstance \"own\"\n"
		"  ObjectInstance \"plain\"\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "objects.exr", &im));
	if (!im.data)
		return;
	int ch[4] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B"), channel(&im, "A") };
	CHECK(ch[0] >= 0 && ch[1] >= 0 && ch[2] >= 0 && ch[3] >= 0);
	if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0 || ch[3] < 0) {
		reyes_image_finish(&im);
		return;
	}
	/* premultiplied: red 0.5 at alpha 0.5; blue 1 at alpha 1 */
	const float want[2][4] = { { 0.5f, 0, 0, 0.5f }, { 0, 0, 1, 1 } };
	double worst = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++)
			for (int c = 0; c < 4; c++)
				worst = fmax(worst, fabs(px(&im, ch[c], x, y) -
							 want[x >= im.width / 2][c]));
	printf("objects: left %.3f %.3f %.3f %.3f, right %.3f %.3f %.3f %.3f, worst error %.2g "
	       "(tolerance 1e-5)\n", px(&im, ch[0], 0, 0), px(&im, ch[1], 0, 0),
	       px(&im, ch[2], 0, 0), px(&im, ch[3], 0, 0), px(&im, ch[0], 15, 0),
	       px(&im, ch[1], 15, 0), px(&im, ch[2], 15, 0), px(&im, ch[3], 15, 0), worst);
	CHECK(worst <= 1e-5);
	reyes_image_finish(&im);
}

/*
 * A sphere whose radius grows from 4 to 12 pixels over the shutter
 * (MotionBegin [0 1] with two Sphere samples), seen orthographically: a
 * point at distance d from the centre is covered while r(t) = 4 + 8 t > d,
 * a fraction clamp((12 - d) / 8, 0, 1) of the shutter. Each pixel's alpha
 * is that fraction averaged over the pixel (fine sampling here) within 0.1,
 * as for the moving disk, and the total within 1% of the time-averaged
 * area pi (r0^2 + r0 r1 + r1^2) / 3.
 */
static void test_deforming_sphere(void)
{
	const char *rib =
		"Format 32 32 1\n"
		"PixelSamples 8 8\n"
		"PixelFilter \"box\" 1 1\n"
		"Shutter 0 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -16 16 -16 16\n"
		"Display \"grow.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  ShadingRate 0.25\n"
		"  Translate 0 0 20\n"
		"  MotionBegin [0 1]\n"
		"    Sphere 4 -4 4 360\n"
		"    Sphere 12 -12 12 360\n"
		"  MotionEnd\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "grow.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A");
	CHECK(a >= 0);
	if (a < 0)
		return;
	double total = 0, worst = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			int ns = 32;
			double cov = 0;
			for (int j = 0; j < ns; j++)
				for (int i = 0; i < ns; i++) {
					double sx = x + (i + 0.5) / ns - 16, sy = y + (j + 0.5) / ns - 16;
					double f = (12 - sqrt(sx * sx + sy * sy)) / 8;
					cov += f < 0 ? 0 : f > 1 ? 1 : f;
				}
			cov /= (double)ns * ns;
			double got = px(&im, a, x, y);
			total += got;
			worst = fmax(worst, fabs(got - cov));
		}
	double area = 3.14159265358979 * (16 + 48 + 144) / 3.0;
	printf("growing sphere: worst pixel error %.4f (tolerance 0.1), total %.3f vs %.3f "
	       "(%.3f%%, tolerance 1%%)\n", worst, total, area, 100 * fabs(total - area) / area);
	CHECK(worst <= 0.1);
	CHECK_NEAR(total, area, 0.01 * area);
	reyes_image_finish(&im);
}

/* The bicubic Bezier height field of 4x4 heights @z (u first) at (u, v). */
static double bezier_height(const double z[16], double u, double v)
{
	double bu[4] = { (1 - u) * (1 - u) * (1 - u), 3 * u * (1 - u) * (1 - u), 3 * u * u * (1 - u),
			 u * u * u };
	double bv[4] = { (1 - v) * (1 - v) * (1 - v), 3 * v * (1 - v) * (1 - v), 3 * v * v * (1 - v),
			 v * v * v };
	double h = 0;
	for (int j = 0; j < 4; j++)
		for (int i = 0; i < 4; i++)
			h += bu[i] * bv[j] * z[j * 4 + i];
	return h;
}

/*
 * Height fields ("Pz"): the surface's x and y are its u and v over the
 * unit square, z the heights through the patch's basis (RISpec). Seen from
 * above orthographically over exactly [0, 1]^2, with a shader showing z in
 * object space: a bilinear Patch (pixel (i, j) at u = (i + 0.5) / 32,
 * v = 1 - (j + 0.5) / 32 shows the bilinear mix of its four heights), a
 * 3x3 bilinear PatchMesh (u and v run over the whole mesh: four cells,
 * each bilinear), and a bicubic Bezier Patch (the Bernstein sum). A box
 * pixel averages a bilinear function to its centre value; the bicubic one
 * differs from it by under 1e-3 here. Tolerance 1% of the heights' range.
 */
static void test_height_field(void)
{
	CHECK(scene_write_file("showz.sl",
			 "surface showz() { Oi = 1; point Po = transform(\"object\", P);"
			 " Ci = color(zcomp(Po)); }\n"));
	static const double bl[4] = { 0, 1, 0.5, 0.25 };
	static const double mesh[9] = { 0, 0.5, 1, 0.25, 1, 0, 0.75, 0.5, 0.25 };
	static const double cub[16] = { 0, 0.5, 1, 0.5, 0.5, 1, 0, 0.5,
					1, 0, 0.5, 1, 0.5, 0.5, 1, 0 };
	char cubs[400] = "";
	size_t lc = 0;
	for (int k = 0; k < 16; k++)
		lc += (size_t)snprintf(cubs + lc, sizeof(cubs) - lc, " %g", cub[k]);
	char prims[3][600];
	snprintf(prims[0], sizeof(prims[0]), "Patch \"bilinear\" \"Pz\" [0 1 0.5 0.25]");
	snprintf(prims[1], sizeof(prims[1]), "PatchMesh \"bilinear\" 3 \"nonperiodic\" 3 "
		 "\"nonperiodic\" \"Pz\" [0 0.5 1  0.25 1 0  0.75 0.5 0.25]");
	snprintf(prims[2], sizeof(prims[2]), "Patch \"bicubic\" \"Pz\" [%s]", cubs);
	static const char *const what[3] = { "bilinear Patch", "bilinear PatchMesh 3x3",
					     "bicubic Patch" };
	for (int k = 0; k < 3; k++) {
		char rib[4096];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" [\".:@\"]\n"
			 "Format 32 32 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Hider \"hidden\" \"jitter\" 0\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -0.5 0.5 -0.5 0.5\n"
			 "Display \"height.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"showz\"\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  ShadingRate 0.25\n"
			 "  Translate -0.5 -0.5 5\n"
			 "  %s\n"
			 "WorldEnd\n", prims[k]);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "height.exr", &im));
		if (!im.data)
			continue;
		int r = channel(&im, "R"), a = channel(&im, "A");
		double worst = 0;
		for (uint32_t y = 0; y < 32; y++)
			for (uint32_t x = 0; x < 32; x++) {
				double u = (x + 0.5) / 32, v = 1 - (y + 0.5) / 32, want;
				if (k == 0) {
					want = (1 - u) * (1 - v) * bl[0] + u * (1 - v) * bl[1] +
					       (1 - u) * v * bl[2] + u * v * bl[3];
				} else if (k == 1) {
					int ci = u < 0.5 ? 0 : 1, cj = v < 0.5 ? 0 : 1;
					double fu = 2 * u - ci, fv = 2 * v - cj;
					const double *z = &mesh[cj * 3 + ci];
					want = (1 - fu) * (1 - fv) * z[0] + fu * (1 - fv) * z[1] +
					       (1 - fu) * fv * z[3] + fu * fv * z[4];
				} else {
					want = bezier_height(cub, u, v);
				}
				worst = fmax(worst, fabs(px(&im, r, x, y) - want));
				CHECK_NEAR(px(&im, a, x, y), 1, 1e-4);
			}
		printf("height field, %s: worst z error %.4f (tolerance 0.01)\n", what[k], worst);
		CHECK(worst <= 0.01);
		reyes_image_finish(&im);
	}
}

/* Point @t of the closed uniform cubic B-spline through the regular octagon of radius 1. */
static void octagon_bspline(double t, double p[2])
{
	int seg = (int)floor(t);
	double f = t - seg;
	double w[4] = { (1 - f) * (1 - f) * (1 - f) / 6, (3 * f * f * f - 6 * f * f + 4) / 6,
			(-3 * f * f * f + 3 * f * f + 3 * f + 1) / 6, f * f * f / 6 };
	p[0] = p[1] = 0;
	for (int k = 0; k < 4; k++) {
		double th = 2 * 3.14159265358979 * ((seg + k) % 8) / 8;
		p[0] += w[k] * cos(th);
		p[1] += w[k] * sin(th);
	}
}

/*
 * A PatchMesh periodic in u: 8 columns of control points round a regular
 * octagon (radius 1), b-spline, step 1, make 8 segments that close on
 * themselves (RISpec: nu / ustep patches), the closed B-spline curve of the
 * octagon; the 4 rows scale it by -1, 0, 1, 2, so that (the b-spline
 * reproducing a linear function) the surface fills the curve from the
 * centre out: a flat disk-like region seen face on. Its v direction is
 * "nowrap" (taken as nonperiodic). Every pixel well inside the curve is
 * covered (no seam where u wraps: at least 0.9; a crack between two grids
 * diced at different rates can drop a sample of 64 anywhere, which the
 * renderer does on open meshes too) and every one well outside is empty;
 * the total alpha is the region's area, from the curve itself, within
 * 0.5%. With u "nonperiodic" the same points make 5 segments, which
 * cover visibly less.
 */
static void test_periodic_patch_mesh(void)
{
	char pts[4000] = "";
	size_t lp = 0;
	for (int j = 0; j < 4; j++)
		for (int i = 0; i < 8; i++) {
			double th = 2 * 3.14159265358979 * i / 8, sc = j - 1;
			lp += (size_t)snprintf(pts + lp, sizeof(pts) - lp, " %.9g %.9g 0",
					       sc * cos(th), sc * sin(th));
		}
	/* The region's area and the curve's radius range, from 8000 points of it. */
	double area = 0, rmin = 1e9, rmax = 0;
	int n = 8000;
	for (int k = 0; k < n; k++) {
		double p[2], q[2];
		octagon_bspline(8.0 * k / n, p);
		octagon_bspline(8.0 * (k + 1) / n, q);
		area += 0.5 * (p[0] * q[1] - p[1] * q[0]);
		rmin = fmin(rmin, hypot(p[0], p[1]));
		rmax = fmax(rmax, hypot(p[0], p[1]));
	}
	double totals[2] = { 0, 0 };
	for (int wrap = 0; wrap < 2; wrap++) {
		char rib[6000];
		snprintf(rib, sizeof(rib),
			 "Format 64 64 1\n"
			 "PixelSamples 8 8\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -1 1 -1 1\n"
			 "Display \"ring.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"constant\"\n"
			 "  ShadingRate 0.25\n"
			 "  Basis \"b-spline\" 1 \"b-spline\" 1\n"
			 "  Translate 0 0 5\n"
			 "  PatchMesh \"bicubic\" 8 \"%s\" 4 \"nowrap\" \"P\" [%s]\n"
			 "WorldEnd\n", wrap ? "periodic" : "nonperiodic", pts);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "ring.exr", &im));
		if (!im.data)
			continue;
		int a = channel(&im, "A");
		int bad_in = 0, bad_out = 0, cracked = 0;
		for (uint32_t y = 0; y < 64; y++)
			for (uint32_t x = 0; x < 64; x++) {
				double X = -1 + (x + 0.5) / 32, Y = 1 - (y + 0.5) / 32;
				double d = hypot(X, Y), al = px(&im, a, x, y);
				totals[wrap] += al;
				/* a pixel's half diagonal is 0.0221 */
				if (d < rmin - 0.03 && al < 0.9)
					bad_in++;
				else if (d < rmin - 0.03 && al < 1 - 1e-4)
					cracked++;
				if (d > rmax + 0.03 && al > 1e-4)
					bad_out++;
			}
		totals[wrap] /= 32 * 32;
		if (wrap) {
			printf("periodic b-spline PatchMesh: %d pixels inside under 0.9 covered (%d "
			       "short of 1 by a sample or two), %d outside covered; area %.5f vs %.5f "
			       "(%.3f%%, tolerance 0.5%%)\n", bad_in, cracked, bad_out, totals[1], area,
			       100 * fabs(totals[1] - area) / area);
			CHECK(bad_in == 0);
			CHECK(bad_out == 0);
			CHECK_NEAR(totals[1], area, 0.005 * area);
		}
		reyes_image_finish(&im);
	}
	printf("nonperiodic in u: area %.5f (5 of 8 segments)\n", totals[0]);
	CHECK(totals[0] > 0.3 * area && totals[0] < 0.9 * area);
}

/* Write a @w x @w picture of constant colour @rgb to @name in the test folder. */
static void write_flat(const char *name, uint32_t w, const float rgb[3])
{
	const char *names[3] = { "R", "G", "B" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, w, w, 3, names));
	for (size_t k = 0; k < (size_t)w * w; k++)
		memcpy(&im.data[3 * k], rgb, 3 * sizeof(float));
	CHECK(reyes_image_write_exr(tmp_path(name), &im, false, NULL));
	reyes_image_finish(&im);
}

/*
 * shaders/envlight.sl, the closed form: a Lambertian (matte) plane under an
 * environment of constant radiance L and nothing else receives the
 * irradiance PI L about its normal, so every pixel is Cs Kd PI L, whichever
 * way the plane faces (towards the eye, tilted, seen from behind, with world
 * space turned from camera space). The environment is a lat-long map made by
 * MakeLatLongEnvironment from a constant picture, and the empty name with
 * lightcolor L. Tolerance 0.5% of the value (the quadrature's weights sum
 * to PI, so only float rounding is left).
 */
static void test_envlight_render(void)
{
	static const float L[3] = { 0.6f, 0.3f, 0.15f }, Cs[3] = { 0.5f, 0.7f, 0.9f };
	const float Kd = 0.8f;
	write_flat("sky.exr", 16, L);
	static const char *const turns[] = { "", "Rotate 60 1 0 0", "Rotate 70 0 1 0 Rotate 30 1 0 0",
					     "Rotate 180 0 1 0", "Rotate -70 1 1 0" };
	double worst = 0;
	int checked = 0;
	for (int m = 0; m < 2; m++)
		for (size_t k = 0; k < sizeof(turns) / sizeof(turns[0]); k++) {
			char rib[2000];
			snprintf(rib, sizeof(rib),
				 "MakeLatLongEnvironment \"sky.exr\" \"sky.env\" \"box\" 1 1\n"
				 "Format 16 16 1\n"
				 "PixelSamples 2 2\n"
				 "Projection \"orthographic\"\n"
				 "ScreenWindow -1 1 -1 1\n"
				 "Display \"envl.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
				 "Rotate 30 0 1 0\n"
				 "WorldBegin\n"
				 "  LightSource \"envlight\" 1 \"string envname\" \"%s\" "
				 "\"color lightcolor\" [%g %g %g] \"float samples\" 36\n"
				 "  Color [%g %g %g]\n"
				 "  Surface \"matte\" \"Kd\" %g\n"
				 "  TransformBegin\n"
				 "    Rotate -30 0 1 0\n"
				 "    Translate 0 0 10\n"
				 "    %s\n"
				 "    Polygon \"P\" [-8 -8 0  8 -8 0  8 8 0  -8 8 0]\n"
				 "  TransformEnd\n"
				 "WorldEnd\n",
				 m ? "" : "sky.env", m ? L[0] : 1, m ? L[1] : 1, m ? L[2] : 1, Cs[0],
				 Cs[1], Cs[2], Kd, turns[k]);
			struct reyes_image im = { 0 };
			CHECK(render(rib, "envl.exr", &im));
			if (!im.data)
				continue;
			for (int c = 0; c < 3; c++) {
				int ch = channel(&im, (const char *[]){ "R", "G", "B" }[c]);
				CHECK(ch >= 0);
				double want = Cs[c] * Kd * 3.14159265358979 * L[c];
				for (uint32_t y = 0; ch >= 0 && y < im.height; y++)
					for (uint32_t x = 0; x < im.width; x++) {
						double e = fabs(px(&im, ch, x, y) - want) / want;
						worst = fmax(worst, e);
						checked++;
						if (e > 0.005)
							fprintf(stderr, "%s, %s: pixel (%u, %u) %c %.6f, "
								"expected %.6f\n", m ? "\"\"" : "map",
								turns[k], x, y, "RGB"[c],
								px(&im, ch, x, y), want);
					}
			}
			reyes_image_finish(&im);
		}
	printf("envlight on a matte plane, 5 orientations, a map and the empty name: %d values "
	       "within %.2g of Cs Kd PI L (tolerance 0.5%%)\n", checked, worst);
	CHECK(checked == 2 * 5 * 3 * 16 * 16);
	CHECK(worst <= 0.005);
}

/*
 * MakeCubeFaceEnvironment and MakeLatLongEnvironment in a RIB, looked up by
 * environment() in a render: a unit sphere seen orthographically from -z
 * (world and camera spaces the same) with Ci = environment(map, N in
 * world space). The cube map has six constant faces: each pixel whose
 * normals all point into one face (the pixel's corners' largest component
 * is the same axis, with a margin) shows that face's colour within 1e-4.
 * The lat-long map's R is t = acos(z) / pi at texel centres: each pixel
 * inside the disk shows the mean of acos(Nz) / pi over its normals within
 * 0.01 (the filter averages over the pixel's cone of directions), but for
 * the pixels round the map's pole at -z (Nz < -0.95), where the cone spans
 * every longitude and t is clamped at the last row's centre. The
 * sphere's poles are turned to +-y, out of the region checked: seen pole
 * on, the grids round the pole meet with cracks that let half a pixel's
 * samples through to the far side in four pixels.
 */
static void test_environment_render(void)
{
	static const float colours[6][3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 },
					      { 1, 1, 0 }, { 1, 0, 1 }, { 0, 1, 1 } };
	static const char *const faces[6] = { "px.exr", "nx.exr", "py.exr", "ny.exr", "pz.exr",
					       "nz.exr" };
	for (int k = 0; k < 6; k++)
		write_flat(faces[k], 16, colours[k]);
	const char *names[3] = { "R", "G", "B" };
	struct reyes_image ll;
	CHECK(reyes_image_init(&ll, 64, 32, 3, names));
	for (uint32_t y = 0; y < 32; y++)
		for (uint32_t x = 0; x < 64; x++)
			ll.data[(y * 64 + x) * 3] = (y + 0.5f) / 32;
	CHECK(reyes_image_write_exr(tmp_path("ll.exr"), &ll, false, NULL));
	reyes_image_finish(&ll);
	CHECK(scene_write_file("showenv.sl",
			 "surface showenv(string map = \"\") { Oi = 1;"
			 " vector Nw = vtransform(\"world\", normalize(N));"
			 " Ci = color environment(map, Nw); }\n"));
	for (int m = 0; m < 2; m++) {
		char rib[2000];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" [\".:@\"]\n"
			 "MakeCubeFaceEnvironment \"px.exr\" \"nx.exr\" \"py.exr\" \"ny.exr\" "
			 "\"pz.exr\" \"nz.exr\" \"cube.env\" 90 \"box\" 1 1\n"
			 "MakeLatLongEnvironment \"ll.exr\" \"ll.env\" \"box\" 1 1\n"
			 "Format 32 32 1\n"
			 "PixelSamples 2 2\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Hider \"hidden\" \"jitter\" 0\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -1 1 -1 1\n"
			 "Display \"env.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"showenv\" \"map\" \"%s\"\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  ShadingRate 0.25\n"
			 "  Translate 0 0 5\n"
			 "  Rotate 90 1 0 0\n"
			 "  Sphere 1 -1 1 360\n"
			 "WorldEnd\n", m ? "ll.env" : "cube.env");
		struct reyes_image im = { 0 };
		CHECK(render(rib, "env.exr", &im));
		if (!im.data)
			continue;
		int ch[3] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B") };
		int checked = 0;
		double worst = 0;
		for (uint32_t y = 0; y < 32; y++)
			for (uint32_t x = 0; x < 32; x++) {
				/* the normals at the pixel's corners and centre, seen from -z */
				int axis = -1, sign = 0, n = 0;
				bool one_face = true;
				double tsum = 0;
				for (int c = 0; c < 5; c++) {
					double X = -1 + (x + (c < 4 ? c % 2 : 0.5)) / 16;
					double Y = 1 - (y + (c < 4 ? c / 2 : 0.5)) / 16;
					double r2 = X * X + Y * Y;
					if (r2 > 0.9) {
						one_face = false;
						n = -1;
						break;
					}
					double N[3] = { X, Y, -sqrt(1 - r2) };
					double a[3] = { fabs(N[0]), fabs(N[1]), fabs(N[2]) };
					int ax = a[0] >= a[1] && a[0] >= a[2] ? 0 : a[1] >= a[2] ? 1 : 2;
					double second = ax == 0 ? fmax(a[1], a[2]) :
						       ax == 1 ? fmax(a[0], a[2]) : fmax(a[0], a[1]);
					int sg = N[ax] < 0;
					if (a[ax] - second < 0.05 || (axis >= 0 && (ax != axis || sg != sign)))
						one_face = false;
					axis = ax, sign = sg;
					n++;
				}
				if (n < 0)
					continue;
				if (m == 0) {
					if (!one_face)
						continue;
					int face = 2 * axis + sign;
					for (int c = 0; c < 3; c++)
						worst = fmax(worst, fabs(px(&im, ch[c], x, y) -
									 colours[face][c]));
				} else {
					double X = -1 + (x + 0.5) / 16, Y = 1 - (y + 0.5) / 16;
					if (X * X + Y * Y < 0.1)
						continue;
					int ns = 8;
					for (int j = 0; j < ns; j++)
						for (int i = 0; i < ns; i++) {
							double X = -1 + (x + (i + 0.5) / ns) / 16;
							double Y = 1 - (y + (j + 0.5) / ns) / 16;
							double Nz = -sqrt(fmax(0, 1 - X * X - Y * Y));
							tsum += acos(Nz) / 3.14159265358979;
						}
					worst = fmax(worst, fabs(px(&im, ch[0], x, y) - tsum / (ns * ns)));
				}
				checked++;
			}
		printf("environment() on %s: %d pixels checked, worst error %.2g (tolerance %g)\n",
		       m ? "a lat-long map" : "a cube map", checked, worst, m ? 0.01 : 1e-4);
		CHECK(checked > (m ? 400 : 300));
		CHECK(worst <= (m ? 0.01 : 1e-4));
		reyes_image_finish(&im);
	}
}

int main(void)
{
	if (!scene_dir_create("relight-render"))
		return 1;
	RUN(test_lambert_plane);
	RUN(test_sphere_coverage);
	RUN(test_motion_coverage);
	RUN(test_transparency_order);
	RUN(test_mirror_one_sided);
	RUN(test_texture_lookup);
	RUN(test_shadow_map);
	RUN(test_varying_primvars);
	RUN(test_lights_before_world);
	RUN(test_object_attributes);
	RUN(test_deforming_sphere);
	RUN(test_height_field);
	RUN(test_periodic_patch_mesh);
	RUN(test_environment_render);
	RUN(test_envlight_render);
	scene_dir_remove();
	return test_finish();
}

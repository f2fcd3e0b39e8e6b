/*
 * Atmosphere shaders in the reference renderer, against closed forms: the
 * volume shader runs on every shading sample of the surfaces in its
 * attribute scope, after the surface, on the surface's Ci and Oi, with I
 * the ray from the eye (at the camera's origin) to the point. Interior and
 * Exterior are bound and reported as doing nothing.
 */
#include "reyes.h"
#include "ri.h"
#include "texture.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double C[3] = { 0.8, 0.3, 0.1 }, BG[3] = { 0.2, 0.4, 0.9 };

/* Distance from the eye to the plane z = @z seen through the centre of pixel (x, y). */
static double eye_distance(const struct reyes_image *im, uint32_t x, uint32_t y, double z,
			   double fov_deg)
{
	double t = tan(fov_deg * 0.5 * 3.14159265358979 / 180);
	double sx = -1 + 2 * (x + 0.5) / im->width, sy = 1 - 2 * (y + 0.5) / im->height;
	/* the field of view spans the shorter side */
	double X = sx * t * im->width / im->height, Y = sy * t;
	if (im->width < im->height) {
		X = sx * t;
		Y = sy * t * im->height / im->width;
	}
	return z * sqrt(X * X + Y * Y + 1);
}

/*
 * RISpec's fog (distance 4) over a constant plane z = 5 facing the camera,
 * in an attribute block, and the same plane beside it outside the block: on
 * the left Ci = mix(C, background, 1 - exp(-l / 4)) with l the distance
 * from the eye through the pixel's centre; on the right the plane's own
 * colour. The box filter averages the fog over a pixel, where l changes by
 * less than 0.2%: within 5e-4 of the value at the centre (measured 1e-4).
 */
static void test_fog_plane(void)
{
	const char *rib =
		"Format 64 48 1\n"
		"PixelSamples 4 4\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"fog.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  ShadingRate 0.25\n"
		"  ShadingInterpolation \"smooth\"\n"
		"  Color [0.8 0.3 0.1]\n"
		"  Surface \"constant\"\n"
		"  AttributeBegin\n"
		"    Atmosphere \"fog\" \"distance\" 4 \"background\" [0.2 0.4 0.9]\n"
		"    Polygon \"P\" [-10 -10 5  0 -10 5  0 10 5  -10 10 5]\n"
		"  AttributeEnd\n"
		"  Polygon \"P\" [0 -10 5  10 -10 5  10 10 5  0 10 5]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "fog.exr", &im));
	if (!im.data)
		return;
	int ch[4] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B"), channel(&im, "A") };
	CHECK(ch[0] >= 0 && ch[1] >= 0 && ch[2] >= 0 && ch[3] >= 0);
	if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0 || ch[3] < 0)
		return;
	double worst_fog = 0, worst_clear = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			if (x == im.width / 2 - 1 || x == im.width / 2)
				continue;   /* the seam's pixels see both planes */
			bool fog = x < im.width / 2;
			double d = 1 - exp(-eye_distance(&im, x, y, 5, 40) / 4);
			for (int c = 0; c < 3; c++) {
				double want = fog ? C[c] + (BG[c] - C[c]) * d : C[c];
				double err = fabs(px(&im, ch[c], x, y) - want);
				double *worst = fog ? &worst_fog : &worst_clear;
				if (err > *worst)
					*worst = err;
			}
			CHECK_NEAR(px(&im, ch[3], x, y), 1, 1e-6);
		}
	printf("fog plane: worst error %.2g with fog (tolerance 5e-4), %.2g without (1e-6)\n",
	       worst_fog, worst_clear);
	CHECK(worst_fog <= 5e-4);
	CHECK(worst_clear <= 1e-6);
	reyes_image_finish(&im);
}

/*
 * RISpec's depthcue over a constant plane at z = 5, with depth() normalized
 * between the clipping planes 1 and 11 (so 0.4) and the cue from 0.2 to 0.6:
 * exactly half of the background everywhere.
 */
static void test_depthcue_plane(void)
{
	const char *rib =
		"Format 32 32 1\n"
		"PixelSamples 2 2\n"
		"Projection \"perspective\" \"fov\" 30\n"
		"Clipping 1 11\n"
		"Display \"cue.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Color [0.8 0.3 0.1]\n"
		"  Surface \"constant\"\n"
		"  Atmosphere \"depthcue\" \"mindistance\" 0.2 \"maxdistance\" 0.6 "
		"\"background\" [0.2 0.4 0.9]\n"
		"  Polygon \"P\" [-10 -10 5  10 -10 5  10 10 5  -10 10 5]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "cue.exr", &im));
	if (!im.data)
		return;
	double worst = 0;
	for (int c = 0; c < 3; c++) {
		int k = channel(&im, c == 0 ? "R" : c == 1 ? "G" : "B");
		CHECK(k >= 0);
		for (uint32_t y = 0; k >= 0 && y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				double err = fabs(px(&im, k, x, y) - 0.5 * (C[c] + BG[c]));
				worst = err > worst ? err : worst;
			}
	}
	printf("depthcue plane: worst error %.2g (tolerance 1e-6)\n", worst);
	CHECK(worst <= 1e-6);
	reyes_image_finish(&im);
}

/*
 * Fog over a lit surface: the matte plane z = 4 of test_render's
 * test_lambert_plane (Ci = 8 / d^3 at distance d from the light) seen
 * through fog of distance 10 and a black background: Ci = 8 / d^3 * exp(-l /
 * 10), within 1% as there.
 */
static void test_fog_lit(void)
{
	const char *rib =
		"Format 64 64 1\n"
		"PixelSamples 4 4\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"litfog.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  LightSource \"pointlight\" 1 \"intensity\" 4 \"from\" [0 0 2]\n"
		"  ShadingRate 0.25\n"
		"  ShadingInterpolation \"smooth\"\n"
		"  Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"  Atmosphere \"fog\" \"distance\" 10\n"
		"  Polygon \"P\" [-10 -10 4  10 -10 4  10 10 4  -10 10 4]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "litfog.exr", &im));
	if (!im.data)
		return;
	int r = channel(&im, "R");
	CHECK(r >= 0);
	double worst = 0;
	float t = tanf(20.0f * 3.14159265f / 180.0f);
	for (uint32_t y = 0; r >= 0 && y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			double sx = -1 + 2 * (x + 0.5) / im.width, sy = 1 - 2 * (y + 0.5) / im.height;
			double X = sx * 4 * t, Y = sy * 4 * t;
			double d = sqrt(X * X + Y * Y + 4), l = sqrt(X * X + Y * Y + 16);
			double want = 8 / (d * d * d) * exp(-l / 10);
			double rel = fabs(px(&im, r, x, y) - want) / want;
			worst = rel > worst ? rel : worst;
		}
	printf("fog over a lit plane: worst relative error %.4f%% (tolerance 1%%)\n", worst * 100);
	CHECK(worst <= 0.01);
	reyes_image_finish(&im);
}

/*
 * Where an atmosphere binds: after the default surface of a primitive with no
 * Surface, and inside an object definition (its instance takes it). A
 * depthcue that is all background at the plane's depth (maxdistance 0.1,
 * normalized depth 0.4) makes either exactly the background (the instance
 * is made where no atmosphere is bound: it has the definition's).
 */
static void test_where_it_binds(void)
{
	const char *rib =
		"Format 32 16 1\n"
		"Projection \"perspective\" \"fov\" 30\n"
		"Clipping 1 11\n"
		"Display \"bind.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  LightSource \"distantlight\" 1\n"
		"  ObjectBegin \"right\"\n"
		"    Atmosphere \"depthcue\" \"maxdistance\" 0.1 \"background\" [0.2 0.4 0.9]\n"
		"    Polygon \"P\" [0 -10 5  10 -10 5  10 10 5  0 10 5]\n"
		"  ObjectEnd\n"
		"  AttributeBegin\n"
		"    Atmosphere \"depthcue\" \"maxdistance\" 0.1 \"background\" [0.2 0.4 0.9]\n"
		"    Polygon \"P\" [-10 -10 5  0 -10 5  0 10 5  -10 10 5]\n"
		"  AttributeEnd\n"
		"  ObjectInstance \"right\"\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "bind.exr", &im));
	if (!im.data)
		return;
	double worst = 0;
	for (int c = 0; c < 3; c++) {
		int k = channel(&im, c == 0 ? "R" : c == 1 ? "G" : "B");
		CHECK(k >= 0);
		for (uint32_t y = 0; k >= 0 && y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				if (x == im.width / 2 - 1 || x == im.width / 2)
					continue;
				double err = fabs(px(&im, k, x, y) - BG[c]);
				worst = err > worst ? err : worst;
			}
	}
	printf("atmospheres after the default surface and in an object: worst error %.2g "
	       "(tolerance 1e-6)\n", worst);
	CHECK(worst <= 1e-6);
	reyes_image_finish(&im);
}

/*
 * Interior and Exterior are bound and said to do nothing, with their line;
 * Atmosphere "null" unbinds (the plane keeps its colour).
 */
static void test_interior_exterior(void)
{
	const char *rib =
		"Format 8 8 1\n"
		"Projection \"perspective\" \"fov\" 30\n"
		"Display \"ie.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Color [0.8 0.3 0.1]\n"
		"  Surface \"constant\"\n"
		"  Interior \"fog\"\n"
		"  Exterior \"depthcue\"\n"
		"  Atmosphere \"fog\"\n"
		"  Atmosphere \"null\"\n"
		"  Polygon \"P\" [-10 -10 5  10 -10 5  10 10 5  -10 10 5]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "ie.exr", &im));
	CHECK(strstr(diag_text, ":7: warning: Interior shaders act on traced rays, which relight "
			"does not trace: no effect") != NULL);
	CHECK(strstr(diag_text, ":8: warning: Exterior shaders act on traced rays") != NULL);
	if (!im.data)
		return;
	int r = channel(&im, "R");
	CHECK(r >= 0);
	if (r >= 0)
		CHECK_NEAR(px(&im, r, 4, 4), 0.8, 1e-6);
	reyes_image_finish(&im);
}

int main(void)
{
	if (!scene_dir_create("relight-atmosphere"))
		return 1;
	RUN(test_fog_plane);
	RUN(test_depthcue_plane);
	RUN(test_fog_lit);
	RUN(test_where_it_binds);
	RUN(test_interior_exterior);
	scene_dir_remove();
	return test_finish();
}

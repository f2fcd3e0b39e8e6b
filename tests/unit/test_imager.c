/*
 * Imager shaders (RISpec 3.2 Imager): the language's imager globals, and
 * `relight render` running the scene's imager on the filtered pixels before
 * Exposure, against closed forms.
 */
#include "reyes.h"
#include "ri.h"
#include "sl.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A lit sphere over nothing: covered, uncovered and edge pixels. */
#define SPHERE_SCENE(IMAGER) \
	"Format 48 36 1\n" \
	"PixelSamples 3 3\n" \
	"PixelFilter \"box\" 1 1\n" \
	IMAGER \
	"Display \"out.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n" \
	"Projection \"perspective\" \"fov\" 40\n" \
	"Translate 0 0 5\n" \
	"WorldBegin\n" \
	"  LightSource \"pointlight\" 1 \"from\" [2 3 -4] \"intensity\" [20]\n" \
	"  Surface \"plastic\"\n" \
	"  Color [0.9 0.4 0.2]\n" \
	"  Sphere 1 -1 1 360\n" \
	"WorldEnd\n"

/*
 * The library's background imager: every pixel becomes Ci + (1 - alpha) *
 * bgcolor with alpha 1. Against the same frame without it: uncovered
 * pixels are bgcolor exactly, covered ones unchanged, edges the composite
 * (the imager's float arithmetic: within 1e-6).
 */
static void test_background(void)
{
	struct reyes_image a = { 0 }, b = { 0 };
	CHECK(render(SPHERE_SCENE(""), "out.exr", &a));
	CHECK(render(SPHERE_SCENE("Imager \"background\" \"color bgcolor\" [0.25 0.5 0.75]\n"),
		     "out.exr", &b));
	if (!a.data || !b.data || a.width != b.width || a.height != b.height)
		goto out;
	const double bg[3] = { 0.25, 0.5, 0.75 };
	int ca[4] = { channel(&a, "R"), channel(&a, "G"), channel(&a, "B"), channel(&a, "A") };
	int cb[4] = { channel(&b, "R"), channel(&b, "G"), channel(&b, "B"), channel(&b, "A") };
	uint32_t empty = 0, covered = 0, edge = 0;
	double worst = 0;
	for (uint32_t y = 0; y < a.height; y++)
		for (uint32_t x = 0; x < a.width; x++) {
			double al = px(&a, ca[3], x, y);
			empty += al == 0;
			covered += al == 1;
			edge += al > 0 && al < 1;
			for (int c = 0; c < 3; c++) {
				double want = px(&a, ca[c], x, y) + (1 - al) * bg[c];
				double d = fabs(px(&b, cb[c], x, y) - want);
				if (al == 0 || al == 1)
					CHECK(d == 0 || (al == 0 && d <= 1e-7));
				worst = d > worst ? d : worst;
			}
			CHECK(px(&b, cb[3], x, y) == 1.0f);
		}
	printf("background: %u empty, %u covered, %u edge pixels; largest difference %.3g\n",
	       empty, covered, edge, worst);
	CHECK(empty > 100 && covered > 100 && edge > 20);
	CHECK(worst <= 1e-6);
out:
	reyes_image_finish(&a);
	reyes_image_finish(&b);
}

/*
 * What an imager sees: P the pixel's centre in raster space, ncomps 3,
 * time and dtime from Shutter; and that it runs before Exposure (gain 2
 * doubles what it writes, not what it reads; alpha is not exposed).
 */
static void test_globals_and_order(void)
{
	const char *sl =
		"imager probe(float k = 10) {\n"
		"	Ci = color(xcomp(P), ycomp(P), ncomps + time + k * dtime) + 0 * Ci;\n"
		"	alpha = 0.5 + zcomp(P) + 0 * comp(Oi, 0);\n"
		"}\n";
	FILE *f = fopen(tmp_path("probe.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs(sl, f);
	fclose(f);
	char rib[1024];
	snprintf(rib, sizeof(rib),
		 "Format 8 6 1\n"
		 "Shutter 0.25 0.75\n"
		 "Exposure 2 1\n"
		 "Imager \"%s\"\n"
		 "Display \"probe.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		 "WorldBegin\n"
		 "WorldEnd\n", tmp_path("probe.sl"));
	struct reyes_image im = { 0 };
	CHECK(render(rib, "probe.exr", &im));
	if (!im.data)
		return;
	int c[4] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B"), channel(&im, "A") };
	int bad = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			bad += px(&im, c[0], x, y) != 2 * (x + 0.5f);
			bad += px(&im, c[1], x, y) != 2 * (y + 0.5f);
			bad += px(&im, c[2], x, y) != 2 * (3 + 0.25f + 10 * 0.5f);
			bad += px(&im, c[3], x, y) != 0.5f;
		}
	if (bad)
		printf("probe: pixel (1, 2) = %g %g %g %g\n", px(&im, c[0], 1, 2),
		       px(&im, c[1], 1, 2), px(&im, c[2], 1, 2), px(&im, c[3], 1, 2));
	CHECK(bad == 0);
	reyes_image_finish(&im);
}

/* An imager reads textures as surfaces do (a constant map: no filter question). */
static void test_texture(void)
{
	const char *names[3] = { "R", "G", "B" };
	struct reyes_image tex;
	CHECK(reyes_image_init(&tex, 16, 16, 3, names));
	for (uint32_t i = 0; i < 16 * 16; i++) {
		tex.data[i * 3] = 0.25f;
		tex.data[i * 3 + 1] = 0.5f;
		tex.data[i * 3 + 2] = 0.75f;
	}
	CHECK(reyes_image_write_exr(tmp_path("flat.exr"), &tex, false, NULL));
	reyes_image_finish(&tex);
	FILE *f = fopen(tmp_path("flatimager.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("imager flatimager(string map = \"\") {\n"
	      "\tCi = color texture(map, xcomp(P) / 8, ycomp(P) / 6);\n\talpha = 1;\n}\n", f);
	fclose(f);
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"MakeTexture \"flat.exr\" \"flat.tex\" \"clamp\" \"clamp\" \"box\" 1 1\n"
		"Format 8 6 1\n"
		"Imager \"flatimager\" \"string map\" \"flat.tex\"\n"
		"Display \"flat.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\nWorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "flat.exr", &im));
	if (!im.data)
		return;
	double worst = 0;
	const double want[3] = { 0.25, 0.5, 0.75 };
	int ch[3] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B") };
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++)
			for (int c = 0; c < 3; c++) {
				double d = fabs(px(&im, ch[c], x, y) - want[c]);
				worst = d > worst ? d : worst;
			}
	if (worst > 1e-6)
		printf("flat: pixel (0, 0) = %g %g %g; %s\n", px(&im, ch[0], 0, 0),
		       px(&im, ch[1], 0, 0), px(&im, ch[2], 0, 0), diag_text);
	CHECK(worst <= 1e-6);
	CHECK(!strstr(diag_text, "not found"));
	reyes_image_finish(&im);
}

static bool compiles(const char *src)
{
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	struct sl_options so = { .diag = diag };
	struct sl_program *p = sl_compile_string("t.sl", src, strlen(src), &so);
	fclose(diag);
	free(buf);
	sl_program_destroy(p);
	return p != NULL;
}

/* An imager sees the pixel and the frame alone; alpha is an imager's. */
static void test_language(void)
{
	CHECK(compiles("imager a(color c = 1) { Ci = Ci * Oi + c * (1 - alpha); }"));
	CHECK(compiles("imager a() { float t = time + dtime + ncomps; Ci = color(xcomp(P), t, 0); }"));
	CHECK(!compiles("imager a() { Ci = N; }"));
	CHECK(!compiles("imager a() { Ci = s; }"));
	CHECK(!compiles("surface a() { Ci = alpha; }"));
	CHECK(compiles("surface a() { float alpha = 1; Ci = alpha; }"));
}

/* Imager is an option, and takes an imager shader. */
static void test_rib_errors(void)
{
	struct reyes_image im = { 0 };
	failure_expected = true;
	CHECK(!render("Display \"x.exr\" \"file\" \"rgba\"\n"
		      "WorldBegin\nImager \"background\"\nWorldEnd\n", "x.exr", &im));
	CHECK(strstr(diag_text, "scene.rib:3:") && strstr(diag_text, "Imager is an option"));
	CHECK(!render("Imager \"plastic\"\nDisplay \"x.exr\" \"file\" \"rgba\"\n"
		      "WorldBegin\nWorldEnd\n", "x.exr", &im));
	CHECK(strstr(diag_text, "scene.rib:1:") && strstr(diag_text, "surface shader"));
	failure_expected = false;
	reyes_image_finish(&im);
	/* "null" turns it off again */
	CHECK(render("Imager \"background\"\nImager \"null\"\n"
		     "Display \"x.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		     "WorldBegin\nWorldEnd\n", "x.exr", &im));
	if (im.data)
		CHECK(px(&im, channel(&im, "R"), 0, 0) == 0 && px(&im, channel(&im, "A"), 0, 0) == 0);
	reyes_image_finish(&im);
}

int main(void)
{
	if (!scene_dir_create("relight-imager"))
		return 1;
	RUN(test_language);
	RUN(test_background);
	RUN(test_globals_and_order);
	RUN(test_texture);
	RUN(test_rib_errors);
	scene_dir_remove();
	return test_finish();
}

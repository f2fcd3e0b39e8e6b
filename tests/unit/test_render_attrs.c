/*
 * The attributes of how geometry is seen, rendered end to end against
 * closed forms: TextureCoordinates, Matte, Detail, RelativeDetail and
 * DetailRange (the representation each camera distance picks, the
 * cross-fade between two, the near-plane clipping of the bound),
 * GeometricApproximation and GeometricRepresentation (accepted, or
 * reported with the line), and a RIB string spanning lines.
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

/* The four channels R G B A of @im into @ch; false (checked) when one is missing. */
static bool rgba_channels(const struct reyes_image *im, int ch[4])
{
	static const char *const names[4] = { "R", "G", "B", "A" };
	bool ok = true;
	for (int c = 0; c < 4; c++) {
		ch[c] = channel(im, names[c]);
		ok = ok && ch[c] >= 0;
	}
	CHECK(ok);
	return ok;
}

/* ---- TextureCoordinates ------------------------------------------------------- */

/* s, t at the corners (u, v) = (0, 0), (1, 0), (0, 1), (1, 1) */
static const double tc[8] = { 0.1, 0.2, 0.9, 0.3, 0.2, 0.8, 0.7, 1.0 };

static double tc_mix(int c, double u, double v)
{
	return (1 - u) * (1 - v) * tc[c] + u * (1 - v) * tc[2 + c] + (1 - u) * v * tc[4 + c] +
	       u * v * tc[6 + c];
}

/*
 * A bilinear Patch over [-1, 1]^2 (u along x, v along y), seen
 * orthographically at 32x32 with a box filter a pixel wide, under
 * TextureCoordinates and a surface showing color(s, t, 0): each pixel
 * averages a bilinear function, which is its value at the pixel's centre,
 * so R and G are the bilinear mix of the corners' s and t there within 0.01
 * (as the varying primitive variables are held). A patch with its own "s"
 * keeps it (and takes t from TextureCoordinates); a Polygon, which has no
 * (u, v) square, is left alone.
 */
static void test_texture_coordinates(void)
{
	CHECK(scene_write_file("showst.sl",
			 "surface showst() { Oi = 1; Ci = color(s, t, 0); }\n"));
	static const char *const prims[] = {
		"Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]",
		"Patch \"bilinear\" \"P\" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]"
		" \"varying float s\" [0.5 0.5 0.5 0.5]",
	};
	for (int k = 0; k < 2; k++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" \"%s:@\"\n"
			 "Format 32 32 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "Display \"st.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Translate 0 0 5\n"
			 "  ShadingRate 0.25\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  Surface \"showst\"\n"
			 "  TextureCoordinates %g %g %g %g %g %g %g %g\n"
			 "  %s\n"
			 "WorldEnd\n", tmpdir, tc[0], tc[1], tc[2], tc[3], tc[4], tc[5], tc[6],
			 tc[7], prims[k]);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "st.exr", &im));
		int ch[4];
		if (!im.data || !rgba_channels(&im, ch)) {
			reyes_image_finish(&im);
			continue;
		}
		double worst = 0;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				double u = (x + 0.5) / im.width, v = 1 - (y + 0.5) / im.height;
				double s = k ? 0.5 : tc_mix(0, u, v), t = tc_mix(1, u, v);
				worst = fmax(worst, fabs(px(&im, ch[0], x, y) - s));
				worst = fmax(worst, fabs(px(&im, ch[1], x, y) - t));
			}
		printf("TextureCoordinates on a Patch%s: worst error %.4f (tolerance 0.01)\n",
		       k ? " with its own s" : "", worst);
		CHECK(worst <= 0.01);
		reyes_image_finish(&im);
	}

	/*
	 * A quadric: a Disk of radius 1 (r = 1 - v, RISpec's parametrisation)
	 * under TextureCoordinates 0 0.3 0 0.3 1 0.3 1 0.3, that is s = v and
	 * t = 0.3: R is 1 - r at the pixel's centre within 0.01 over the ring
	 * 0.2 < r < 0.9 (a pixel averages a function linear in r, curved only
	 * near the centre), G 0.3 everywhere on it.
	 */
	{
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" \"%s:@\"\n"
			 "Format 32 32 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "Display \"disk.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Translate 0 0 5\n"
			 "  ShadingRate 0.25\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  Surface \"showst\"\n"
			 "  TextureCoordinates [0 0.3 0 0.3 1 0.3 1 0.3]\n"
			 "  Disk 0 1 360\n"
			 "WorldEnd\n", tmpdir);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "disk.exr", &im));
		int ch[4];
		if (im.data && rgba_channels(&im, ch)) {
			double worst = 0;
			for (uint32_t y = 0; y < im.height; y++)
				for (uint32_t x = 0; x < im.width; x++) {
					double X = -1 + 2 * (x + 0.5) / im.width;
					double Y = 1 - 2 * (y + 0.5) / im.height;
					double rr = hypot(X, Y);
					if (rr <= 0.2 || rr >= 0.9)
						continue;
					worst = fmax(worst, fabs(px(&im, ch[0], x, y) - (1 - rr)));
					worst = fmax(worst, fabs(px(&im, ch[1], x, y) - 0.3));
				}
			printf("TextureCoordinates on a Disk: worst error %.4f (tolerance 0.01)\n",
			       worst);
			CHECK(worst <= 0.01);
		}
		reyes_image_finish(&im);
	}

	/* A Polygon keeps its own s, t whatever TextureCoordinates says. */
	const char *poly = "Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]";
	struct reyes_image a = { 0 }, b = { 0 };
	for (int k = 0; k < 2; k++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" \"%s:@\"\n"
			 "Format 16 16 1\n"
			 "Projection \"orthographic\"\n"
			 "Display \"poly.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Translate 0 0 5\n"
			 "  Surface \"showst\"\n"
			 "  %s\n"
			 "  %s\n"
			 "WorldEnd\n", tmpdir, k ? "TextureCoordinates 5 5 5 5 5 5 5 5" : "", poly);
		CHECK(render(rib, "poly.exr", k ? &b : &a));
	}
	CHECK(a.data && b.data && a.width == b.width && a.height == b.height &&
	      a.nchannels == b.nchannels &&
	      !memcmp(a.data, b.data, sizeof(float) * a.width * a.height * a.nchannels));
	reyes_image_finish(&a);
	reyes_image_finish(&b);
}

/* ---- Matte ------------------------------------------------------------------- */

/*
 * A red-shaded Disk made a matte object, in front of a white plane that
 * fills the view (orthographic, 32x32, 8x8 samples, box filter): where the
 * disk covers a pixel entirely (by a quarter pixel, as diced), colour and
 * alpha are exactly 0 (no colour of its own shader, and the plane hidden);
 * a quarter pixel clear of it, exactly the plane's (1, 1, 1, 1); at its edge every channel is 1 - the exact
 * disk-pixel overlap within 0.1 (as the sphere's coverage is held), and the
 * hole's total area is pi r^2 within 0.5%. The same disk behind the plane
 * changes nothing.
 */
static void test_matte(void)
{
	for (int behind = 0; behind < 2; behind++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Format 32 32 1\n"
			 "PixelSamples 8 8\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -1 1 -1 1\n"
			 "Display \"matte.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"constant\"\n"
			 "  AttributeBegin\n"
			 "    Translate 0 0 10\n"
			 "    Polygon \"P\" [-2 -2 0  2 -2 0  2 2 0  -2 2 0]\n"
			 "  AttributeEnd\n"
			 "  AttributeBegin\n"
			 "    Matte 1\n"
			 "    Color [1 0 0]\n"
			 "    Translate 0 0 %d\n"
			 "    Disk 0 0.6 360\n"
			 "  AttributeEnd\n"
			 "WorldEnd\n", behind ? 12 : 5);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "matte.exr", &im));
		int ch[4];
		if (!im.data || !rgba_channels(&im, ch)) {
			reyes_image_finish(&im);
			continue;
		}
		double rad = 0.6 / (2.0 / 32), hole = 0, worst_edge = 0, worst_exact = 0;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				double cov = behind ? 0 : disk_pixel(16, 16, rad, x, y);
				/* the pixel's nearest and farthest points from the centre */
				double nx = fmax(fmax(x - 16.0, 16.0 - (x + 1)), 0);
				double ny = fmax(fmax(y - 16.0, 16.0 - (y + 1)), 0);
				double fx = fmax(fabs(x - 16.0), fabs(x + 1 - 16.0));
				double fy = fmax(fabs(y - 16.0), fabs(y + 1 - 16.0));
				bool clear = behind || hypot(nx, ny) >= rad + 0.25;
				bool covered = !behind && hypot(fx, fy) <= rad - 0.25;
				hole += 1 - px(&im, ch[3], x, y);
				for (int c = 0; c < 4; c++) {
					double err = fabs(px(&im, ch[c], x, y) - (1 - cov));
					if (clear || covered)
						worst_exact = fmax(worst_exact, err);
					else
						worst_edge = fmax(worst_edge, err);
				}
			}
		double area = behind ? 0 : 3.14159265358979 * rad * rad;
		printf("matte disk %s the plane: covered and clear pixels worst error %.2g "
		       "(tolerance 0), edge pixels %.4f (tolerance 0.1), hole %.3f vs %.3f\n",
		       behind ? "behind" : "in front of", worst_exact, worst_edge, hole, area);
		CHECK(worst_exact == 0);
		CHECK(worst_edge <= 0.1);
		CHECK_NEAR(hole, area, 0.005 * area);
		reyes_image_finish(&im);
	}
}

/* ---- Detail and DetailRange --------------------------------------------------------- */

/*
 * Three representations of one object, chosen by the raster area of its
 * Detail bound [-1 1 -1 1 0 0] at distance z from a 64x64 camera with a
 * 90-degree field of view: (64 / z)^2 pixels. Red is seen over detail
 * [0, 100] and fades out to 400, green fades in over [100, 400], is seen to
 * 1000 and fades out to 4000, blue fades in over [1000, 4000] and has no
 * upper limit. Each representation is a plane filling the view, so every
 * subpixel sample sees exactly the representations its dissolve number
 * selects.
 */
static const char detail_rib[] =
	"Format 64 64 1\n"
	"PixelSamples 4 4\n"
	"PixelFilter \"box\" 1 1\n"
	"Projection \"perspective\" \"fov\" 90\n"
	"Display \"detail.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
	"WorldBegin\n"
	"  Surface \"constant\"\n"
	"  Translate 0 0 %.9g\n"
	"  Detail [-1 1 -1 1 0 0]\n"
	"  AttributeBegin\n"
	"    DetailRange 0 0 100 400\n"
	"    Color [1 0 0]\n"
	"    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"  AttributeEnd\n"
	"  AttributeBegin\n"
	"    DetailRange [100 400 1000 4000]\n"
	"    Color [0 1 0]\n"
	"    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"  AttributeEnd\n"
	"  AttributeBegin\n"
	"    DetailRange 1000 4000 1e38 1e38\n"
	"    Color [0 0 1]\n"
	"    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"  AttributeEnd\n"
	"WorldEnd\n";

/* The same with the representations defined as objects, Detail given at the instances. */
static const char detail_obj_rib[] =
	"Format 64 64 1\n"
	"PixelSamples 4 4\n"
	"PixelFilter \"box\" 1 1\n"
	"Projection \"perspective\" \"fov\" 90\n"
	"Display \"detail.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
	"ObjectBegin \"red\"\n"
	"  DetailRange 0 0 100 400\n"
	"  Color [1 0 0]\n"
	"  Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"ObjectEnd\n"
	"WorldBegin\n"
	"  ObjectBegin \"green\"\n"
	"    DetailRange [100 400 1000 4000]\n"
	"    Color [0 1 0]\n"
	"    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"  ObjectEnd\n"
	"  Surface \"constant\"\n"
	"  Translate 0 0 %.9g\n"
	"  Detail [-1 1 -1 1 0 0]\n"
	"  ObjectInstance \"red\"\n"
	"  ObjectInstance \"green\"\n"
	"  AttributeBegin\n"
	"    DetailRange 1000 4000 1e38 1e38\n"
	"    Color [0 0 1]\n"
	"    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
	"  AttributeEnd\n"
	"WorldEnd\n";

/* RISpec's importance of a representation over [lo0, lo1, hi0, hi1] at detail @d. */
static double importance(double d, double lo0, double lo1, double hi0, double hi1)
{
	if (d < lo0 || d > hi1)
		return 0;
	if (d < lo1)
		return (d - lo0) / (lo1 - lo0);
	if (d > hi0)
		return (hi1 - d) / (hi1 - hi0);
	return 1;
}

/*
 * At z = 8 (detail 64), 2.56 (625) and 0.8 (6400) one representation fills
 * the image exactly; at z = 4.8 (177.8) red and green cross-fade, at 1.2
 * (2844) green and blue. The mean colour over the image is the closed-form
 * importance of each representation within 0.01 (65536 samples: the
 * binomial spread of a fraction is at most 0.002), and every pixel is
 * covered once, R + G + B = A = 1 within 1e-5, the fading
 * representations sharing the samples without overlap or gap. Twice more
 * with two of the representations objects (one defined outside the world)
 * whose definitions give the DetailRange and whose instances the Detail.
 */
static void test_detail(void)
{
	static const double zs[] = { 8, 2.56, 0.8, 4.8, 1.2, 2.56, 4.8 };
	for (size_t k = 0; k < sizeof(zs) / sizeof(zs[0]); k++) {
		char rib[4096];
		bool objects = k >= 5;
		snprintf(rib, sizeof(rib), objects ? detail_obj_rib : detail_rib, zs[k]);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "detail.exr", &im));
		int ch[4];
		if (!im.data || !rgba_channels(&im, ch)) {
			reyes_image_finish(&im);
			continue;
		}
		double d = (64 / zs[k]) * (64 / zs[k]);
		double want[3] = { importance(d, 0, 0, 100, 400),
				   importance(d, 100, 400, 1000, 4000),
				   importance(d, 1000, 4000, 1e38, 1e38) };
		double mean[3] = { 0 }, worst_sum = 0;
		size_t npx = (size_t)im.width * im.height;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++) {
				double sum = 0;
				for (int c = 0; c < 3; c++) {
					mean[c] += px(&im, ch[c], x, y) / (double)npx;
					sum += px(&im, ch[c], x, y);
				}
				worst_sum = fmax(worst_sum, fabs(sum - 1));
				worst_sum = fmax(worst_sum, fabs(px(&im, ch[3], x, y) - 1));
			}
		printf("%sdetail %.1f (z %.2g): mean %.4f %.4f %.4f, expected %.4f %.4f %.4f "
		       "(tolerance 0.01); worst |R+G+B-1|, |A-1| %.2g (tolerance 1e-5)\n",
		       objects ? "objects, " : "", d, zs[k], mean[0], mean[1], mean[2], want[0],
		       want[1], want[2], worst_sum);
		if (objects)
			CHECK_STR(diag_text, "");
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(mean[c], want[c], 0.01);
		CHECK(worst_sum <= 1e-5);
		reyes_image_finish(&im);
	}
}

/*
 * How the detail is measured: two representations, red fading out and
 * green in over [T0, T1], filling the 64x64 view (fov 90), their mean colour
 * against the closed-form importance within 0.01 as above.
 *  - RelativeDetail 4 scales the square of side 2 at z = 8 (64 pixels) to 256.
 *  - The cube of side 2 at z = 1.5 with Clipping 1 is clipped to the near
 *    plane: its front face there is 64 pixels wide, 4096 (unclipped, at
 *    z = 0.5, it would be 16384).
 *  - The camera inside the cube (z = 0.5, Clipping 0.25): clipped at 0.25,
 *    the face is 256 pixels wide, 65536.
 */
static void test_detail_measure(void)
{
	static const struct {
		const char *options, *bound;
		double z, t0, t1, detail;
	} cases[] = {
		{ "RelativeDetail 4", "-1 1 -1 1 0 0", 8, 100, 400, 256 },
		{ "Clipping 1 100", "-1 1 -1 1 -1 1", 1.5, 2048, 6144, 4096 },
		{ "Clipping 0.25 100", "-1 1 -1 1 -1 1", 0.5, 32768, 98304, 65536 },
	};
	for (size_t k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
		char rib[4096];
		snprintf(rib, sizeof(rib),
			 "Format 64 64 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"perspective\" \"fov\" 90\n"
			 "%s\n"
			 "Display \"measure.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  Surface \"constant\"\n"
			 "  Translate 0 0 %g\n"
			 "  Detail %s\n"
			 "  AttributeBegin\n"
			 "    DetailRange 0 0 %g %g\n"
			 "    Color [1 0 0]\n"
			 "    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
			 "  AttributeEnd\n"
			 "  AttributeBegin\n"
			 "    DetailRange %g %g 1e38 1e38\n"
			 "    Color [0 1 0]\n"
			 "    Polygon \"P\" [-100 -100 0  100 -100 0  100 100 0  -100 100 0]\n"
			 "  AttributeEnd\n"
			 "WorldEnd\n", cases[k].options, cases[k].z, cases[k].bound, cases[k].t0,
			 cases[k].t1, cases[k].t0, cases[k].t1);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "measure.exr", &im));
		int ch[4];
		if (!im.data || !rgba_channels(&im, ch)) {
			reyes_image_finish(&im);
			continue;
		}
		double want_g = importance(cases[k].detail, cases[k].t0, cases[k].t1, 1e38, 1e38);
		double mean[2] = { 0 };
		size_t npx = (size_t)im.width * im.height;
		for (uint32_t y = 0; y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++)
				for (int c = 0; c < 2; c++)
					mean[c] += px(&im, ch[c], x, y) / (double)npx;
		printf("%s, Detail [%s] at z %g: detail %g, mean red %.4f green %.4f, expected "
		       "%.4f %.4f (tolerance 0.01)\n", cases[k].options, cases[k].bound,
		       cases[k].z, cases[k].detail, mean[0], mean[1], 1 - want_g, want_g);
		CHECK_NEAR(mean[0], 1 - want_g, 0.01);
		CHECK_NEAR(mean[1], want_g, 0.01);
		reyes_image_finish(&im);
	}
}

/* ---- GeometricApproximation, GeometricRepresentation, strings over lines -------- */

/*
 * GeometricApproximation "flatness" and "motionfactor" are accepted and
 * change nothing (the image is bit for bit the one without them); an
 * unknown type, and GeometricRepresentation other than "primitive", are
 * warnings at their line, and the frame renders as without them. The RIB
 * has a string spanning three lines before them, so the lines reported
 * are counted across it.
 */
static void test_geometric_requests(void)
{
	static const char base[] =
		"Format 16 16 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"geo.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Attribute \"identifier\" \"name\" \"a name\n"
		"over\n"
		"lines\"\n"
		"  %s\n"
		"  Translate 0 0 5\n"
		"  Sphere 1 -1 1 360\n"
		"WorldEnd\n";
	const char *extra[] = {
		"",
		"GeometricApproximation \"flatness\" 0.5 GeometricApproximation \"motionfactor\" 1",
		"GeometricApproximation \"bogus\" 2\n  GeometricRepresentation \"lines\"\n"
		"  GeometricRepresentation \"primitive\"",
	};
	struct reyes_image im[3] = { { 0 } };
	for (int k = 0; k < 3; k++) {
		char rib[2048];
		snprintf(rib, sizeof(rib), base, extra[k]);
		CHECK(render(rib, "geo.exr", &im[k]));
		if (k < 2) {
			CHECK_STR(diag_text, "");
			continue;
		}
		printf("diagnostics:\n%s", diag_text);
		CHECK(strstr(diag_text, "scene.rib:8: warning: GeometricApproximation \"bogus\" "
					"is not supported") != NULL);
		CHECK(strstr(diag_text, "scene.rib:9: warning: GeometricRepresentation \"lines\" "
					"is not supported") != NULL);
		CHECK(strstr(diag_text, "scene.rib:10:") == NULL);
	}
	for (int k = 1; k < 3; k++) {
		CHECK(im[0].data && im[k].data && im[0].nchannels == im[k].nchannels &&
		      im[0].width == im[k].width && im[0].height == im[k].height);
		if (im[0].data && im[k].data)
			CHECK(!memcmp(im[0].data, im[k].data,
				      sizeof(float) * im[0].width * im[0].height * im[0].nchannels));
	}
	for (int k = 0; k < 3; k++)
		reyes_image_finish(&im[k]);
}

/*
 * Malformed requests are errors at their line, and the frame is not
 * rendered; requests that cannot mean anything where they are are warnings.
 */
static void test_bad_requests(void)
{
	static const struct {
		const char *req, *diag;
	} cases[] = {
		{ "DetailRange 0 10 5 20",
		  "scene.rib:3: error: DetailRange needs minvisible <= lowertransition <= "
		  "uppertransition <= maxvisible, got 0 10 5 20\n" },
		{ "Detail [-1 1 -1 1 0]",
		  "scene.rib:3: error: Detail expects 6 numbers, got an array of 5 numbers\n" },
		{ "Detail [1 -1 -1 1 0 0]",
		  "scene.rib:3: error: Detail: the bound's minimum 1 is above its maximum -1\n" },
		{ "GeometricApproximation \"flatness\" -1",
		  "scene.rib:3: error: GeometricApproximation \"flatness\" must not be negative, "
		  "got -1\n" },
		{ "RelativeDetail 2",
		  "scene.rib:3: error: RelativeDetail is an option: it must come before "
		  "WorldBegin\n" },
		{ "TextureCoordinates 0 0 1 0 0 1 1",
		  "scene.rib:3: error: TextureCoordinates expects 8 numbers, got 7\n" },
	};
	failure_expected = true;
	for (size_t k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
		char rib[1024];
		snprintf(rib, sizeof(rib),
			 "Display \"bad.exr\" \"file\" \"rgba\"\n"
			 "WorldBegin\n"
			 "%s\n"
			 "Sphere 1 -1 1 360\n"
			 "WorldEnd\n", cases[k].req);
		unlink(tmp_path("bad.exr"));
		struct reyes_image im = { 0 };
		CHECK(!render(rib, "bad.exr", &im));
		const char *d = strstr(diag_text, "scene.rib:");
		CHECK_STR(d, cases[k].diag);
		CHECK(access(tmp_path("bad.exr"), F_OK) != 0);
		reyes_image_finish(&im);
	}
	failure_expected = false;
	struct reyes_image im = { 0 };
	CHECK(render("Detail [-1 1 -1 1 -1 1]\nDisplay \"w.exr\" \"file\" \"rgba\"\n"
		     "WorldBegin\nDetailRange 0 0 10 20\nSphere 1 -1 1 360\nWorldEnd\n",
		     "w.exr", &im));
	CHECK(strstr(diag_text, "scene.rib:1: warning: Detail outside WorldBegin/WorldEnd is "
				"ignored") != NULL);
	CHECK(strstr(diag_text, "scene.rib:4: warning: DetailRange without a Detail bound") !=
	      NULL);
	reyes_image_finish(&im);
}

int main(void)
{
	if (!scene_dir_create("relight-attrs"))
		return 1;
	RUN(test_texture_coordinates);
	RUN(test_matte);
	RUN(test_detail);
	RUN(test_detail_measure);
	RUN(test_geometric_requests);
	RUN(test_bad_requests);
	scene_dir_remove();
	return test_finish();
}

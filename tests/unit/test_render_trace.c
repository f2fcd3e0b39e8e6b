/*
 * Ray tracing in the reference renderer, end to end against closed forms:
 * occlusion() under a sphere, a mirror's reflection of a sphere (its size,
 * and its shading by the sphere's own shader and lights), a point light's
 * ray-traced shadow of a sphere, and transmission() through slabs of known
 * opacity. Each test writes a RIB scene and its shaders, renders them
 * through the scene builder and the REYES pipeline to OpenEXR and compares
 * the pixels. The objects that only rays should see are hidden from the
 * camera (Attribute "visibility" "camera" 0), so the closed forms hold at
 * every pixel.
 */
#include "reyes.h"
#include "texture.h"
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/*
 * occlusion() on a plane z = 5 facing an orthographic camera, under a
 * sphere of radius r centred at distance d in front of it (between camera
 * and plane, seen by diffuse rays only). Seen from a plane point X at
 * distance D from the centre, the sphere is a cap of half-angle asin(r/D)
 * whose axis makes the angle theta with the normal, cos(theta) = d / D; the
 * cosine-weighted fraction of the hemisphere it covers is its projected solid
 * angle over pi, (r/D)^2 cos(theta), wherever the whole cap is above the
 * horizon. Directly below the centre that is (r/d)^2: within 1 % there (the
 * issue's bound) with 16384 samples, the sphere diced at ShadingRate 0.25 (its
 * inscribed facets make it 0.1 % smaller; 1024 samples resolve 1/1024 of the
 * hemisphere, 2.4 % of (r/d)^2 for the smaller sphere). Elsewhere the pixel (2x2 samples of
 * smoothly interpolated shading over one-pixel micropolygons) is compared with
 * the closed form averaged over the pixel: within 2 % of the centre's value.
 * With "maxdist" short of the sphere nothing is occluded: 0 exactly.
 */
static void test_occlusion_sphere(void)
{
	CHECK(scene_write_file("occl.sl",
		"surface occl(float samples = 256; float maxdist = 1e30)\n"
		"{\n"
		"\tnormal Nf = faceforward(normalize(N), I);\n"
		"\tCi = occlusion(P, Nf, samples, \"maxdist\", maxdist);\n"
		"\tOi = 1;\n"
		"}\n"));
	const double cases[3][3] = { { 1, 2, 1e30 }, { 0.5, 2.5, 1e30 }, { 1, 2, 0.9 } };
	for (int c = 0; c < 3; c++) {
		double r = cases[c][0], d = cases[c][1], maxdist = cases[c][2];
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Option \"searchpath\" \"shader\" [\".:@\"]\n"
			 "Format 33 33 1\n"
			 "PixelSamples 2 2\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -2 2 -2 2\n"
			 "Display \"occl.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  AttributeBegin\n"
			 "    Attribute \"visibility\" \"int camera\" 0 \"int diffuse\" 1\n"
			 "    ShadingRate 0.25\n"
			 "    Surface \"constant\"\n"
			 "    Translate 0 0 %g\n"
			 "    Sphere %g %g %g 360\n"
			 "  AttributeEnd\n"
			 "  ShadingInterpolation \"smooth\"\n"
			 "  Surface \"occl\" \"samples\" 16384 \"maxdist\" %g\n"
			 "  Polygon \"P\" [-3 -3 5  3 -3 5  3 3 5  -3 3 5]\n"
			 "WorldEnd\n",
			 5 - d, r, -r, r, maxdist);
		struct reyes_image im = { 0 };
		CHECK(render(rib, "occl.exr", &im));
		if (!im.data)
			return;
		int ch = channel(&im, "R");
		CHECK(ch >= 0 && im.width == 33 && im.height == 33);
		if (ch < 0 || im.width != 33 || im.height != 33) {
			reyes_image_finish(&im);
			return;
		}
		double centre = px(&im, ch, 16, 16);
		if (maxdist < d - r) {
			double most = 0;
			for (uint32_t k = 0; k < 33 * 33; k++)
				most = fmax(most, fabs(px(&im, ch, k % 33, k / 33)));
			printf("occlusion, maxdist %g short of the sphere: largest %g (want 0)\n",
			       maxdist, most);
			CHECK(most == 0);
			reyes_image_finish(&im);
			continue;
		}
		double want = (r / d) * (r / d), worst = 0;
		for (uint32_t y = 0; y < 33; y++)
			for (uint32_t x = 0; x < 33; x++) {
				/* the closed form averaged over the pixel (8x8 points) */
				double sum = 0;
				bool above = true;
				for (int j = 0; j < 8; j++)
					for (int i = 0; i < 8; i++) {
						double X = -2 + 4 * (x + (i + 0.5) / 8) / 33;
						double Y = 2 - 4 * (y + (j + 0.5) / 8) / 33;
						double D = sqrt(X * X + Y * Y + d * d);
						double theta = acos(d / D), alpha = asin(r / D);
						above = above && theta + alpha < PI / 2;
						sum += (r / D) * (r / D) * (d / D);
					}
				if (!above)
					continue;
				worst = fmax(worst, fabs(px(&im, ch, x, y) - sum / 64));
			}
		printf("occlusion under a sphere r %g at d %g: centre %.5f, closed form %.5f "
		       "(%.3f%%, tolerance 1%%); worst pixel %.5f off (tolerance %.5f)\n",
		       r, d, centre, want, 100 * fabs(centre - want) / want, worst, 0.02 * want);
		CHECK(fabs(centre - want) <= 0.01 * want);
		CHECK(worst <= 0.02 * want);
		reyes_image_finish(&im);
	}
}

/*
 * A perfectly reflecting plane z = 10 facing a perspective camera (fov 30,
 * 128 pixels) and a sphere of radius 1 centred at z = 8 that only specular
 * rays see, its constant colour (1, 0.5, 0.25). The camera sees the sphere's
 * mirror image, a sphere of radius 1 at distance L = 12: a disk of angular
 * radius asin(1/L), tan(asin(1/L)) / tan(15 deg) * 64 pixels in radius. The
 * red channel summed over the image is the disk's area in pixels; the radius
 * it gives is within a pixel of that (the issue's bound), and the middle
 * pixel is the sphere's colour within 1e-4.
 */
static void test_mirror_radius(void)
{
	CHECK(scene_write_file("mirror.sl",
		"surface mirror(float Kr = 1)\n"
		"{\n"
		"\tnormal Nf = faceforward(normalize(N), I);\n"
		"\tCi = Kr * trace(P, reflect(normalize(I), Nf));\n"
		"\tOi = 1;\n"
		"}\n"));
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"Format 128 128 1\n"
		"PixelSamples 4 4\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 30\n"
		"Display \"mirror.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  AttributeBegin\n"
		"    Attribute \"visibility\" \"int camera\" 0 \"int specular\" 1\n"
		"    Color [1 0.5 0.25]\n"
		"    Surface \"constant\"\n"
		"    Translate 0 0 8\n"
		"    Sphere 1 -1 1 360\n"
		"  AttributeEnd\n"
		"  Surface \"mirror\"\n"
		"  Polygon \"P\" [-20 -20 10  20 -20 10  20 20 10  -20 20 10]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "mirror.exr", &im));
	if (!im.data)
		return;
	int r = channel(&im, "R"), g = channel(&im, "G"), b = channel(&im, "B");
	CHECK(r >= 0 && g >= 0 && b >= 0 && im.width == 128 && im.height == 128);
	if (r < 0 || g < 0 || b < 0 || im.width != 128 || im.height != 128) {
		reyes_image_finish(&im);
		return;
	}
	double area = 0;
	for (uint32_t y = 0; y < 128; y++)
		for (uint32_t x = 0; x < 128; x++)
			area += px(&im, r, x, y);
	double L = 12, want = (1 / sqrt(L * L - 1)) / tan(15 * PI / 180) * 64;
	double got = sqrt(area / PI);
	printf("mirror: reflected sphere radius %.3f pixels, closed form %.3f (tolerance 1 pixel); "
	       "middle (%.5f %.5f %.5f), corner %.5f\n", got, want, px(&im, r, 64, 64),
	       px(&im, g, 64, 64), px(&im, b, 64, 64), px(&im, r, 2, 2));
	CHECK(fabs(got - want) <= 1);
	CHECK_NEAR(px(&im, r, 64, 64), 1, 1e-4);
	CHECK_NEAR(px(&im, g, 64, 64), 0.5, 1e-4);
	CHECK_NEAR(px(&im, b, 64, 64), 0.25, 1e-4);
	CHECK(px(&im, r, 2, 2) == 0);
	reyes_image_finish(&im);
}

/*
 * What a mirror shows is shaded by the reflected object's own shader and
 * lights: an orthographic camera, a mirror z = 10, a matte sphere (Kd 1) of
 * radius 0.8 at z = 5 seen only by specular rays, lit by a distant light of
 * intensity 1 shining along -z. The reflected ray of pixel (X, Y) travels
 * along -z and meets the sphere where its normal is (X, Y, sqrt(R^2 - X^2 -
 * Y^2)) / R, so the pixel is sqrt(1 - (X^2 + Y^2) / R^2) averaged over the
 * pixel (the mirror's shading interpolated over micropolygons of ShadingRate
 * 0.25: a constant one would move the picture by half a micropolygon, and
 * larger ones bend the curve sqrt(1 - rho^2) by more near 0.9 R). Pixels within 0.9 R of the middle: within 0.01 (the ray grid's
 * tessellation moves a hit by a fraction of a micropolygon).
 */
static void test_mirror_lit_sphere(void)
{
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"Format 41 41 1\n"
		"PixelSamples 4 4\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -1 1 -1 1\n"
		"Display \"mirrorlit.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  LightSource \"distantlight\" 1 \"intensity\" 1 \"from\" [0 0 20] \"to\" [0 0 0]\n"
		"  AttributeBegin\n"
		"    Attribute \"visibility\" \"int camera\" 0 \"int specular\" 1\n"
		"    Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		"    Translate 0 0 5\n"
		"    Sphere 0.8 -0.8 0.8 360\n"
		"  AttributeEnd\n"
		"  ShadingInterpolation \"smooth\"\n"
		"  ShadingRate 0.25\n"
		"  Surface \"mirror\"\n"
		"  Polygon \"P\" [-3 -3 10  3 -3 10  3 3 10  -3 3 10]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "mirrorlit.exr", &im));
	if (!im.data)
		return;
	int r = channel(&im, "R");
	CHECK(r >= 0 && im.width == 41 && im.height == 41);
	if (r < 0 || im.width != 41 || im.height != 41) {
		reyes_image_finish(&im);
		return;
	}
	const double R = 0.8;
	double worst = 0;
	int compared = 0;
	for (uint32_t y = 0; y < 41; y++)
		for (uint32_t x = 0; x < 41; x++) {
			double sum = 0;
			bool inside = true;
			for (int j = 0; j < 8; j++)
				for (int i = 0; i < 8; i++) {
					double X = -1 + 2 * (x + (i + 0.5) / 8) / 41;
					double Y = 1 - 2 * (y + (j + 0.5) / 8) / 41;
					double rho2 = (X * X + Y * Y) / (R * R);
					inside = inside && rho2 < 0.81;
					sum += sqrt(fmax(0, 1 - rho2));
				}
			if (!inside)
				continue;
			compared++;
			worst = fmax(worst, fabs(px(&im, r, x, y) - sum / 64));
		}
	printf("mirror of a lit matte sphere: %d pixels, worst %.5f off the closed form "
	       "(tolerance 0.01)\n", compared, worst);
	CHECK(compared > 300);
	CHECK(worst <= 0.01);
	reyes_image_finish(&im);
}

/* Does the segment from @p to @l pass within @r of @c? */
static bool segment_blocked(const double p[3], const double l[3], const double c[3], double r)
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
	return e < r * r;
}

/*
 * A point light's ray-traced shadow (shadowspot with "shadowname"
 * "raytrace", as prman takes it) of a sphere of radius 1 at (1, 0, 7) on a
 * matte plane z = 10, the light at (2, 0, 4): the shadow is the ellipse cut
 * from the plane by the cone of rays from the light tangent to the sphere.
 * The plane is rendered with and without the sphere casting (visibility
 * "transmission"); their ratio is the light that reaches each pixel. The
 * exact shadowed fraction of each pixel comes from testing 8x8 points of it
 * against the sphere. Every pixel whose 3x3 neighbourhood is wholly inside
 * or wholly outside the ellipse is within 0.02 of it (so the edge is within a
 * pixel), and the shadow's area within 2 %.
 */
static void test_raytraced_shadow(void)
{
	struct reyes_image im[2] = { { 0 }, { 0 } };
	for (int casts = 0; casts < 2; casts++) {
		char rib[2048];
		snprintf(rib, sizeof(rib),
			 "Format 64 64 1\n"
			 "PixelSamples 4 4\n"
			 "PixelFilter \"box\" 1 1\n"
			 "Projection \"orthographic\"\n"
			 "ScreenWindow -4 4 -4 4\n"
			 "Display \"shadow.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			 "WorldBegin\n"
			 "  LightSource \"shadowspot\" 1 \"intensity\" 40 \"from\" [2 0 4] "
			 "\"to\" [0 0 10]\n"
			 "      \"coneangle\" 1.4 \"conedeltaangle\" 0.05 \"shadowname\" \"raytrace\"\n"
			 "      \"samples\" 1\n"
			 "  AttributeBegin\n"
			 "    Attribute \"visibility\" \"int camera\" 0 \"int transmission\" %d\n"
			 "    Surface \"constant\"\n"
			 "    Translate 1 0 7\n"
			 "    Sphere 1 -1 1 360\n"
			 "  AttributeEnd\n"
			 "  Surface \"matte\" \"Ka\" 0\n"
			 "  Polygon \"P\" [-6 -6 10  6 -6 10  6 6 10  -6 6 10]\n"
			 "WorldEnd\n",
			 casts);
		CHECK(render(rib, "shadow.exr", &im[casts]));
		if (!im[casts].data)
			goto done;
		CHECK(im[casts].width == 64 && im[casts].height == 64);
		if (im[casts].width != 64 || im[casts].height != 64)
			goto done;
	}
	int r = channel(&im[0], "R");
	CHECK(r >= 0);
	if (r < 0)
		goto done;
	static double frac[64][64];
	const double light[3] = { 2, 0, 4 }, centre[3] = { 1, 0, 7 };
	double exact_area = 0, got_area = 0, worst = 0;
	for (uint32_t y = 0; y < 64; y++)
		for (uint32_t x = 0; x < 64; x++) {
			int in = 0;
			for (int j = 0; j < 8; j++)
				for (int i = 0; i < 8; i++) {
					double p[3] = { -4 + 8 * (x + (i + 0.5) / 8) / 64,
							4 - 8 * (y + (j + 0.5) / 8) / 64, 10 };
					in += segment_blocked(p, light, centre, 1);
				}
			frac[y][x] = in / 64.0;
			exact_area += frac[y][x];
		}
	int compared = 0;
	for (uint32_t y = 0; y < 64; y++)
		for (uint32_t x = 0; x < 64; x++) {
			double lit = px(&im[0], r, x, y);
			CHECK(lit > 0);
			if (!(lit > 0))
				goto done;
			double blocked = 1 - px(&im[1], r, x, y) / lit;
			got_area += blocked;
			bool uniform = true;
			for (int dy = -1; dy <= 1; dy++)
				for (int dx = -1; dx <= 1; dx++) {
					int xx = (int)x + dx, yy = (int)y + dy;
					if (xx >= 0 && yy >= 0 && xx < 64 && yy < 64 &&
					    frac[yy][xx] != frac[y][x])
						uniform = false;
				}
			if (!uniform || (frac[y][x] != 0 && frac[y][x] != 1))
				continue;
			compared++;
			worst = fmax(worst, fabs(blocked - frac[y][x]));
		}
	printf("ray-traced shadow: area %.2f pixels, exact %.2f (%.2f%%, tolerance 2%%); %d pixels "
	       "off the edge, worst %.4f (tolerance 0.02)\n", got_area, exact_area,
	       100 * fabs(got_area - exact_area) / exact_area, compared, worst);
	CHECK(exact_area > 100);
	CHECK(fabs(got_area - exact_area) <= 0.02 * exact_area);
	CHECK(worst <= 0.02);
done:
	reyes_image_finish(&im[0]);
	reyes_image_finish(&im[1]);
}

/*
 * transmission() from a plane z = 10 toward the camera (to z = 0.5), through slabs only
 * shadow rays see: z = 5 everywhere, opacity (0.25, 0.5, 0.75), its
 * transmission "Os"; z = 3 over x < 0, opacity 0.5, "Os"; z = 2 over y < 0,
 * "transparent" (not seen); z = 1 over x > 0.5, "opaque". The light that gets
 * through is 1 - o for each slab crossed, multiplied: exact (1e-6) away from
 * the slabs' edges.
 */
static void test_transmission_slabs(void)
{
	CHECK(scene_write_file("transm.sl",
		"surface transm(float reach = 8)\n"
		"{\n"
		"\tCi = transmission(P, P - vector(0, 0, reach));\n"
		"\tOi = 1;\n"
		"}\n"));
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"Format 32 32 1\n"
		"PixelSamples 2 2\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -1 1 -1 1\n"
		"Display \"transm.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  AttributeBegin\n"
		"    Attribute \"visibility\" \"int camera\" 0 \"string transmission\" \"Os\"\n"
		"    Opacity [0.25 0.5 0.75]\n"
		"    Polygon \"P\" [-2 -2 5  2 -2 5  2 2 5  -2 2 5]\n"
		"    Opacity [0.5 0.5 0.5]\n"
		"    Polygon \"P\" [-2 -2 3  0 -2 3  0 2 3  -2 2 3]\n"
		"    Attribute \"visibility\" \"string transmission\" \"transparent\"\n"
		"    Opacity [1 1 1]\n"
		"    Polygon \"P\" [-2 -2 2  2 -2 2  2 0 2  -2 0 2]\n"
		"    Attribute \"visibility\" \"string transmission\" \"opaque\"\n"
		"    Opacity [0.1 0.1 0.1]\n"
		"    Polygon \"P\" [0.5 -2 1  2 -2 1  2 2 1  0.5 2 1]\n"
		"  AttributeEnd\n"
		"  Surface \"transm\" \"reach\" 9.5\n"
		"  Polygon \"P\" [-3 -3 10  3 -3 10  3 3 10  -3 3 10]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "transm.exr", &im));
	if (!im.data)
		return;
	int ch[3] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "B") };
	CHECK(ch[0] >= 0 && ch[1] >= 0 && ch[2] >= 0 && im.width == 32 && im.height == 32);
	if (ch[0] < 0 || ch[1] < 0 || ch[2] < 0 || im.width != 32 || im.height != 32) {
		reyes_image_finish(&im);
		return;
	}
	double worst = 0;
	int compared = 0;
	for (uint32_t y = 0; y < 32; y++)
		for (uint32_t x = 0; x < 32; x++) {
			/* pixel x covers X in [-1 + x / 16, -1 + (x + 1) / 16] */
			if (x == 15 || x == 16 || x == 23 || x == 24)
				continue;
			double X = -1 + (x + 0.5) / 16;
			double want[3] = { 0.75, 0.5, 0.25 };
			for (int c = 0; c < 3; c++) {
				if (X < 0)
					want[c] *= 0.5;
				if (X > 0.5)
					want[c] = 0;
				worst = fmax(worst, fabs(px(&im, ch[c], x, y) - want[c]));
			}
			compared++;
		}
	printf("transmission through slabs: %d pixels, worst %.2g off 1 - o (tolerance 1e-6)\n",
	       compared, worst);
	CHECK(compared == 28 * 32);
	CHECK(worst <= 1e-6);
	reyes_image_finish(&im);
}

/*
 * Can the renderer ray trace at all? A shader that calls occlusion() must
 * compile; where the shading language still refuses the ray-tracing calls,
 * the tests skip loudly instead of failing on every check.
 */
static bool can_ray_trace(void)
{
	if (!scene_write_file("probe.sl", "surface probe() { Ci = occlusion(P, N, 1); }\n"))
		return false;
	const char *rib =
		"Option \"searchpath\" \"shader\" [\".:@\"]\n"
		"Format 2 2 1\n"
		"Display \"probe.exr\" \"file\" \"rgba\"\n"
		"WorldBegin\n"
		"  Surface \"probe\"\n"
		"  Polygon \"P\" [-1 -1 5  1 -1 5  1 1 5  -1 1 5]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	failure_expected = true;
	bool ok = render(rib, "probe.exr", &im);
	failure_expected = false;
	reyes_image_finish(&im);
	if (!ok && strstr(diag_text, "is not supported by relight"))
		return false;
	return true;
}

int main(void)
{
	if (!scene_dir_create("relight-trace"))
		return 1;
	if (!can_ray_trace()) {
		fprintf(stderr, "SKIP: the shading language refuses the ray-tracing calls:\n%s",
			diag_text);
		scene_dir_remove();
		return 77;
	}
	RUN(test_occlusion_sphere);
	RUN(test_mirror_radius);
	RUN(test_mirror_lit_sphere);
	RUN(test_raytraced_shadow);
	RUN(test_transmission_slabs);
	scene_dir_remove();
	return test_finish();
}

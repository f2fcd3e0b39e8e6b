/*
 * The camera's lens and its motion, end to end against closed forms: each
 * test writes a RIB scene, renders it through the scene builder and the
 * REYES pipeline to a float OpenEXR image, reads it back and compares.
 *
 * Depth of field (DepthOfField fstop focallength focaldistance): a thin lens
 * of aperture diameter A = focallength / fstop at the eye, focused at
 * distance d, shows a point at depth z as a disk whose diameter on the
 * screen (x/z units, before the projection's 1 / tan(fov/2) and the screen
 * window's scale to pixels) is A |1/d - 1/z|. That is the film-plane circle
 * of confusion of a real lens, A (focallength / (d - focallength)) |z - d| / z,
 * divided by the film's distance behind the lens, d focallength /
 * (d - focallength), which is what maps the film to the screen.
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
 * A small disk of radius 0.25 at depth 4, facing the camera, against black;
 * fov 90 on a 96x96 image is 48 pixels per screen unit, so its pinhole image
 * has radius rho = 0.25 / 4 * 48 = 3 pixels. The lens: focallength 0.5,
 * fstop 1 (A = 0.5), focused at 1: the circle of confusion at depth 4 has
 * radius c = 0.25 * |1/1 - 1/4| * 48 = 9 pixels.
 *
 * The blurred image is the disk's image convolved with the circle of
 * confusion and with the one-pixel box filter. Convolution keeps the total
 * (sum of alpha = pi rho^2, the lens moves coverage but makes none) and adds
 * second moments: the alpha-weighted mean of r^2 about the centroid is
 * rho^2 / 2 + c^2 / 2 + 1/6 (a uniform disk of radius R has R^2 / 2, a
 * one-pixel box 1/12 per axis). So c = sqrt(2 (E[r^2] - rho^2 / 2 - 1/6)),
 * which must match 9 pixels within 1 %. Inside radius c - rho the alpha is
 * flat at the disk's share of the circle, (rho / c)^2: the mean over the
 * pixels within 4 pixels of the centre must match it within 3 % (each pixel
 * has 256 samples; the pixels average their noise). ShadingRate 0.25 keeps
 * the tessellated outline's area within 1 % of the circle's.
 */
static void test_circle_of_confusion(void)
{
	const char *rib =
		"Format 96 96 1\n"
		"PixelSamples 16 16\n"
		"PixelFilter \"box\" 1 1\n"
		"Projection \"perspective\" \"fov\" 90\n"
		"DepthOfField 1 0.5 1\n"
		"Display \"coc.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  ShadingRate 0.25\n"
		"  Translate 0 0 4\n"
		"  Disk 0 0.25 360\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "coc.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A");
	CHECK(a >= 0);
	if (a < 0)
		return;
	double rho = 3, c = 9, sum = 0, sx = 0, sy = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			double v = px(&im, a, x, y);
			sum += v;
			sx += v * (x + 0.5);
			sy += v * (y + 0.5);
		}
	CHECK(sum > 0);
	if (!(sum > 0))
		return;
	double cx = sx / sum, cy = sy / sum, m2 = 0, flat = 0;
	int nflat = 0;
	for (uint32_t y = 0; y < im.height; y++)
		for (uint32_t x = 0; x < im.width; x++) {
			double v = px(&im, a, x, y), dx = x + 0.5 - cx, dy = y + 0.5 - cy;
			m2 += v * (dx * dx + dy * dy);
			if (dx * dx + dy * dy <= 16) {
				flat += v;
				nflat++;
			}
		}
	m2 /= sum;
	flat /= nflat;
	double area = 3.14159265358979 * rho * rho;
	double got_c = sqrt(2 * (m2 - rho * rho / 2 - 1.0 / 6));
	double want_flat = rho * rho / (c * c);
	printf("circle of confusion: centroid (%.3f, %.3f), total alpha %.3f vs pi rho^2 %.3f "
	       "(%.3f%%, tolerance 1%%), radius %.4f vs %.4f pixels (%.3f%%, tolerance 1%%), "
	       "plateau %.5f vs %.5f (%.2f%%, tolerance 3%%)\n",
	       cx, cy, sum, area, 100 * fabs(sum - area) / area, got_c, c,
	       100 * fabs(got_c - c) / c, flat, want_flat, 100 * fabs(flat - want_flat) / want_flat);
	CHECK_NEAR(cx, 48, 0.05);
	CHECK_NEAR(cy, 48, 0.05);
	CHECK_NEAR(sum, area, 0.01 * area);
	CHECK_NEAR(got_c, c, 0.01 * c);
	CHECK_NEAR(flat, want_flat, 0.03 * want_flat);
	reyes_image_finish(&im);
}

/*
 * What lies on the focal plane is sharp: a lit, coloured square at depth
 * 3 = focaldistance (with a wide aperture, fstop 0.5) renders as it does
 * through a pinhole. Its vertices move by |1/d - 1/z| ~ 1e-7 of the lens
 * radius, so only samples within that of an edge can change sides: every
 * channel of every pixel within 1e-4 (stated: one sample of 64 flipping
 * would be 1/64), the mean difference within 1e-6. The same lens focused
 * at 2 instead must blur it (some channel differs by more than 0.05).
 */
static void test_in_focus(void)
{
	const char *scene =
		"Format 48 48 1\n"
		"PixelSamples 8 8\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"%s"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n"
		"  LightSource \"pointlight\" 1 \"intensity\" 6 \"from\" [0.5 0.5 1]\n"
		"  Surface \"plastic\"\n"
		"  Color [0.8 0.4 0.2]\n"
		"  Translate 0 0 3\n"
		"  Rotate 20 0 0 1\n"
		"  Polygon \"P\" [-0.6 -0.6 0  0.6 -0.6 0  0.6 0.6 0  -0.6 0.6 0]\n"
		"WorldEnd\n";
	char rib[2048];
	struct reyes_image sharp = { 0 }, lens = { 0 }, blur = { 0 };
	snprintf(rib, sizeof(rib), scene, "", "pinhole.exr");
	CHECK(render(rib, "pinhole.exr", &sharp));
	snprintf(rib, sizeof(rib), scene, "DepthOfField 0.5 0.5 3\n", "focused.exr");
	CHECK(render(rib, "focused.exr", &lens));
	snprintf(rib, sizeof(rib), scene, "DepthOfField 0.5 0.5 2\n", "blurred.exr");
	CHECK(render(rib, "blurred.exr", &blur));
	if (!sharp.data || !lens.data || !blur.data)
		goto done;
	CHECK(sharp.width == lens.width && sharp.height == lens.height &&
	      sharp.nchannels == lens.nchannels);
	double worst = 0, mean = 0, total = 0, worst_blur = 0;
	size_t n = (size_t)sharp.width * sharp.height * sharp.nchannels;
	for (size_t i = 0; i < n; i++) {
		double d = fabs((double)sharp.data[i] - lens.data[i]);
		double e = fabs((double)sharp.data[i] - blur.data[i]);
		worst = d > worst ? d : worst;
		worst_blur = e > worst_blur ? e : worst_blur;
		mean += d;
		total += sharp.data[i];
	}
	mean /= (double)n;
	printf("in focus: worst channel difference %.3g (tolerance 1e-4), mean %.3g (tolerance "
	       "1e-6), image mean %.4f; focused at 2: worst difference %.3f (must exceed 0.05)\n",
	       worst, mean, total / (double)n, worst_blur);
	CHECK(total > 0.05 * (double)n);
	CHECK(worst <= 1e-4);
	CHECK(mean <= 1e-6);
	CHECK(worst_blur > 0.05);
done:
	reyes_image_finish(&sharp);
	reyes_image_finish(&lens);
	reyes_image_finish(&blur);
}

/* Exact shutter-averaged coverage of pixel column @x by the half-plane x >= e0 + v t. */
static double ramp_coverage(double x, double e0, double v)
{
	int n = 4096;
	double cov = 0;
	for (int k = 0; k < n; k++) {
		double e = e0 + v * (k + 0.5) / n, f = x + 1 - e;
		cov += f < 0 ? 0 : f > 1 ? 1 : f;
	}
	return cov / n;
}

/*
 * A camera translating over the shutter: an orthographic camera (one pixel
 * per unit) looks at the half-plane x >= 0 while it moves 8 units, so the
 * edge moves from raster x 16 to 24. Each pixel's alpha is the fraction of
 * the shutter and of the pixel that the half-plane covers,
 * integral over t of clamp(x + 1 - (16 + 8 t), 0, 1): a linear ramp 8 pixels
 * wide. With 8x8 samples (64 time strata, shuffled against position) every
 * pixel is within 0.1 of it (computed here by integration over the
 * shutter) and each column's mean over its 8 rows (512 samples) within 0.03;
 * the band of columns 14 to 25 sums to its integral within 0.5 %, and
 * exactly columns 16 to 23 are partly covered (from 1/16 to 15/16).
 */
static void test_camera_motion_ramp(void)
{
	const char *rib =
		"Format 40 8 1\n"
		"PixelSamples 8 8\n"
		"PixelFilter \"box\" 1 1\n"
		"Shutter 0 1\n"
		"Projection \"orthographic\"\n"
		"ScreenWindow -16 24 -4 4\n"
		"Display \"pan.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"MotionBegin [0 1]\n"
		"  Translate 0 0 5\n"
		"  Translate 8 0 5\n"
		"MotionEnd\n"
		"WorldBegin\n"
		"  Surface \"constant\"\n"
		"  Polygon \"P\" [0 -100 0  100 -100 0  100 100 0  0 100 0]\n"
		"WorldEnd\n";
	struct reyes_image im = { 0 };
	CHECK(render(rib, "pan.exr", &im));
	if (!im.data)
		return;
	int a = channel(&im, "A");
	CHECK(a >= 0);
	if (a < 0)
		return;
	double worst = 0, worst_col = 0, got_ramp = 0, want_ramp = 0;
	int partial = 0;
	for (uint32_t x = 0; x < im.width; x++) {
		double want = ramp_coverage(x, 16, 8), col = 0;
		for (uint32_t y = 0; y < im.height; y++) {
			double got = px(&im, a, x, y);
			worst = fabs(got - want) > worst ? fabs(got - want) : worst;
			col += got / im.height;
			if (x >= 14 && x < 26) {
				got_ramp += got;
				want_ramp += want;
			}
		}
		worst_col = fabs(col - want) > worst_col ? fabs(col - want) : worst_col;
		partial += col > 0.01 && col < 0.99;
	}
	printf("camera motion ramp: worst pixel %.4f (tolerance 0.1), worst column mean %.4f "
	       "(tolerance 0.03), band 14..25 total %.3f vs %.3f (%.3f%%, tolerance 0.5%%), %d "
	       "partly covered columns (8 expected)\n", worst, worst_col, got_ramp, want_ramp,
	       100 * fabs(got_ramp - want_ramp) / want_ramp, partial);
	CHECK(worst <= 0.1);
	CHECK(worst_col <= 0.03);
	CHECK_NEAR(got_ramp, want_ramp, 0.005 * want_ramp);
	CHECK(partial == 8);
	reyes_image_finish(&im);
}

/*
 * Camera and object motion combine: a perspective camera panning 0.6 units
 * to the right while the object moves 0.6 to the right with it sees the
 * object still. Camera space is the object's motion composed with the
 * camera's at each time, so the image matches the still scene within 1e-4
 * per channel (float rounding of the composed matrices can move a vertex
 * by ~1e-6 pixels); the same camera over a still object must blur it (the
 * image differs by more than 0.1 somewhere).
 */
static void test_camera_and_object_motion(void)
{
	const char *scene =
		"Format 48 32 1\n"
		"PixelSamples 8 8\n"
		"Shutter 0 1\n"
		"Projection \"perspective\" \"fov\" 45\n"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"%s"
		"WorldBegin\n"
		"  LightSource \"distantlight\" 1 \"intensity\" 1 \"from\" [0 1 -1] \"to\" [0 0 0]\n"
		"  Surface \"matte\"\n"
		"  Color [0.3 0.7 0.9]\n"
		"%s"
		"  Sphere 0.8 -0.8 0.8 360\n"
		"WorldEnd\n";
	const char *pan = "MotionBegin [0 1]\n  Translate 0 0 4\n  Translate -0.6 0 4\nMotionEnd\n";
	const char *follow = "  MotionBegin [0 1]\n    Translate 0 0 0\n    Translate 0.6 0 0\n"
			     "  MotionEnd\n";
	char rib[2048];
	struct reyes_image still = { 0 }, both = { 0 }, cam = { 0 };
	snprintf(rib, sizeof(rib), scene, "still.exr", "Translate 0 0 4\n", "");
	CHECK(render(rib, "still.exr", &still));
	snprintf(rib, sizeof(rib), scene, "both.exr", pan, follow);
	CHECK(render(rib, "both.exr", &both));
	snprintf(rib, sizeof(rib), scene, "cam.exr", pan, "");
	CHECK(render(rib, "cam.exr", &cam));
	if (!still.data || !both.data || !cam.data)
		goto done;
	size_t n = (size_t)still.width * still.height * still.nchannels;
	double worst_both = 0, worst_cam = 0;
	for (size_t i = 0; i < n; i++) {
		double d = fabs((double)still.data[i] - both.data[i]);
		double e = fabs((double)still.data[i] - cam.data[i]);
		worst_both = d > worst_both ? d : worst_both;
		worst_cam = e > worst_cam ? e : worst_cam;
	}
	printf("camera + object motion: worst difference from the still scene %.3g (tolerance "
	       "1e-4); camera motion alone %.3f (must exceed 0.1)\n", worst_both, worst_cam);
	CHECK(worst_both <= 1e-4);
	CHECK(worst_cam > 0.1);
done:
	reyes_image_finish(&still);
	reyes_image_finish(&both);
	reyes_image_finish(&cam);
}

int main(void)
{
	if (!scene_dir_create("relight-lens"))
		return 1;
	RUN(test_circle_of_confusion);
	RUN(test_in_focus);
	RUN(test_camera_motion_ramp);
	RUN(test_camera_and_object_motion);
	scene_dir_remove();
	return test_finish();
}

/*
 * Solid modeling (SolidBegin/SolidEnd) end to end, against closed forms.
 *
 * Two spheres whose centres lie in one plane facing an orthographic camera
 * project onto disks A (radius R, centre 0) and B (radius r, centre d along
 * x). Along a ray, each sphere's chord is centred on that plane, so the
 * shorter chord lies inside the longer: A - B is seen where A's chord is
 * the longer, i.e. short of the circles' radical line x0 = (R^2 - r^2 +
 * d^2) / 2d. The silhouettes are then made of circular segments cut by
 * the common chord: A - B is disk A less A's segment beyond x0, A & B is
 * the lens (the two segments), A | B is the disks' union. Coverage is the
 * sum of the alpha image times the pixel area (8x8 samples a pixel, a box
 * filter one pixel wide, 128x128 pixels over [-1, 1]^2), within 0.5 % of
 * the closed form (the tessellated outlines and sampling stay well
 * inside that: see the printed errors).
 */
#include "render_scene.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N 128
#define PI 3.14159265358979323846

static const double R = 0.6, r = 0.4, d = 0.6;

/* The area of a circle's segment (radius @rad) beyond a chord at distance @h from its centre. */
static double segment(double rad, double h)
{
	return rad * rad * acos(h / rad) - h * sqrt(rad * rad - h * h);
}

static double radical_x(void)
{
	return (R * R - r * r + d * d) / (2 * d);
}

/*
 * Render the world body @world under camera @camera (its projection and
 * transformation); the channel sums of R, G and A (in screen-window area)
 * into @sum.
 */
static bool render_camera(const char *camera, const char *world, const char *name,
			  double sum[3])
{
	char rib[8192], out[64];
	snprintf(out, sizeof(out), "%s.exr", name);
	snprintf(rib, sizeof(rib),
		 "Format %d %d 1\n"
		 "PixelSamples 8 8\n"
		 "PixelFilter \"box\" 1 1\n"
		 "ScreenWindow -1 1 -1 1\n"
		 "Shutter 0 1\n"
		 "Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		 "%s"
		 "WorldBegin\n"
		 "  Surface \"constant\"\n"
		 "%s"
		 "WorldEnd\n",
		 N, N, out, camera, world);
	struct reyes_image im = { 0 };
	bool ok = render(rib, out, &im);
	CHECK(ok);
	if (!ok || !im.data)
		return false;
	int ch[3] = { channel(&im, "R"), channel(&im, "G"), channel(&im, "A") };
	double pix = (2.0 / N) * (2.0 / N);
	for (int c = 0; c < 3; c++) {
		sum[c] = 0;
		CHECK(ch[c] >= 0);
		for (uint32_t y = 0; ch[c] >= 0 && y < im.height; y++)
			for (uint32_t x = 0; x < im.width; x++)
				sum[c] += px(&im, ch[c], x, y) * pix;
	}
	reyes_image_finish(&im);
	return true;
}

/* The scenes of the header comment: orthographic, the spheres' centres at depth 5. */
static bool render_sums(const char *world, const char *name, double sum[3])
{
	char body[4096];
	snprintf(body, sizeof(body), "  Translate 0 0 5\n%s", world);
	return render_camera("Projection \"orthographic\"\n", body, name, sum);
}

static void check_area(const char *what, double got, double want, double tol)
{
	double err = fabs(got - want) / want;
	printf("%s: area %.5f vs %.5f closed form (%.3f%%, tolerance %.1f%%)\n", what, got, want,
	       100 * err, 100 * tol);
	CHECK(err <= tol);
}

/* The spheres A and B of the header comment, as primitive solids. */
#define SOLID_A "    SolidBegin \"primitive\" Color [1 0 0] Sphere 0.6 -0.6 0.6 360 SolidEnd\n"
#define SOLID_B \
	"    SolidBegin \"primitive\" AttributeBegin Color [0 1 0] Translate 0.6 0 0\n" \
	"      Sphere 0.4 -0.4 0.4 360 AttributeEnd SolidEnd\n"

static void test_difference(void)
{
	double s[3];
	if (!render_sums("  SolidBegin \"difference\"\n" SOLID_A SOLID_B "  SolidEnd\n",
			 "difference", s))
		return;
	check_area("difference A - B", s[2], PI * R * R - segment(R, radical_x()), 0.005);
}

static void test_intersection(void)
{
	double s[3], x0 = radical_x();
	if (!render_sums("  SolidBegin \"intersection\"\n" SOLID_A SOLID_B "  SolidEnd\n",
			 "intersection", s))
		return;
	check_area("intersection A & B", s[2], segment(R, x0) + segment(r, d - x0), 0.005);
}

static void test_union(void)
{
	double s[3], x0 = radical_x();
	if (!render_sums("  SolidBegin \"union\"\n" SOLID_A SOLID_B "  SolidEnd\n", "union", s))
		return;
	double lens = segment(R, x0) + segment(r, d - x0);
	check_area("union A | B", s[2], PI * (R * R + r * r) - lens, 0.005);
	/* A's disk is red and B's green where each is in front; no inner surface shows. */
	check_area("union: A's colour", s[0], PI * R * R - segment(R, x0), 0.005);
	/* Half transparent, every ray crosses the union's boundary twice: no
	   inner surface adds opacity (alpha 0.75 over the union). */
	if (!render_sums("  Opacity [0.5 0.5 0.5]\n"
			 "  SolidBegin \"union\"\n" SOLID_A SOLID_B "  SolidEnd\n", "union_t", s))
		return;
	check_area("transparent union: alpha", s[2], 0.75 * (PI * (R * R + r * r) - lens), 0.005);
}

/*
 * A bite seen from the front: a sphere of radius rb = 0.3 centred on A's
 * nearest point cuts a dimple whose rim is the spheres' intersection
 * circle, of radius rb sqrt(1 - rb^2 / 4R^2) seen along the axis. Inside
 * it the camera sees the subtracting sphere's inner side, with its own
 * surface colour (green); A's red covers the rest of its disk. The rim is
 * where two tessellated spheres cross, hence 1 % on the colours' areas.
 */
static void test_cut_face(void)
{
	double s[3];
	if (!render_sums("  SolidBegin \"difference\"\n" SOLID_A
			 "    SolidBegin \"primitive\" Color [0 1 0] Translate 0 0 -0.6\n"
			 "      Sphere 0.3 -0.3 0.3 360 SolidEnd\n"
			 "  SolidEnd\n",
			 "cut", s))
		return;
	double rb = 0.3, rim = rb * sqrt(1 - rb * rb / (4 * R * R));
	check_area("cut face: silhouette", s[2], PI * R * R, 0.005);
	check_area("cut face: the subtracting sphere's colour", s[1], PI * rim * rim, 0.01);
	check_area("cut face: the rest in A's colour", s[0], PI * (R * R - rim * rim), 0.01);
}

/*
 * Nested solids: A (two hemispheres forming one primitive solid) less the
 * union of B and its mirror image, the latter an object instance: A's
 * disk less both segments.
 */
static void test_nested(void)
{
	double s[3];
	if (!render_sums("  ObjectBegin \"ball\" Sphere 0.4 -0.4 0.4 360 ObjectEnd\n"
			 "  SolidBegin \"difference\"\n"
			 "    SolidBegin \"primitive\" Sphere 0.6 0 0.6 360 Sphere 0.6 -0.6 0 360"
			 " SolidEnd\n"
			 "    SolidBegin \"union\"\n" SOLID_B
			 "      SolidBegin \"primitive\" TransformBegin Translate -0.6 0 0\n"
			 "        ObjectInstance \"ball\" TransformEnd SolidEnd\n"
			 "    SolidEnd\n"
			 "  SolidEnd\n",
			 "nested", s))
		return;
	check_area("nested A - (B | B')", s[2], PI * R * R - 2 * segment(R, radical_x()), 0.005);
}

/*
 * A - B with opacity 0.5 on both: where only A is crossed the ray meets
 * A's front and back (alpha 0.75); in B's segment short of the radical
 * line it also crosses B's surface twice, both bounding the solid (alpha
 * 1 - 0.5^4); A's segment beyond the line is cut away (0).
 */
static void test_transparent(void)
{
	double s[3], x0 = radical_x();
	if (!render_sums("  Opacity [0.5 0.5 0.5]\n"
			 "  SolidBegin \"difference\"\n" SOLID_A SOLID_B "  SolidEnd\n",
			 "transparent", s))
		return;
	double lens = segment(R, x0) + segment(r, d - x0);
	double want = 0.75 * (PI * R * R - lens) + 0.9375 * segment(r, d - x0);
	check_area("transparent A - B: alpha", s[2], want, 0.005);
}

/* The difference moving 0.3 along x over the shutter covers the still area in all. */
static void test_motion(void)
{
	double s[3];
	if (!render_sums("  MotionBegin [0 1] Translate 0 0 0 Translate 0.3 0 0 MotionEnd\n"
			 "  SolidBegin \"difference\"\n" SOLID_A SOLID_B "  SolidEnd\n",
			 "motion", s))
		return;
	check_area("moving A - B", s[2], PI * R * R - segment(R, radical_x()), 0.005);
}

/*
 * The eye inside a solid: a 90-degree perspective camera at the centre of
 * a sphere of radius 10, intersected with a ball of radius 1 at distance
 * 5 on the axis. The big sphere's first crossing along every ray is an
 * exit, so the eye is taken as inside it and the intersection is the ball
 * alone: a disk of radius tan(asin(1/5)) on the screen window [-1, 1]^2.
 */
static void test_camera_inside(void)
{
	double s[3];
	if (!render_camera("Projection \"perspective\" \"fov\" 90\n",
			   "  SolidBegin \"intersection\"\n"
			   "    SolidBegin \"primitive\" Sphere 10 -10 10 360 SolidEnd\n"
			   "    SolidBegin \"primitive\" Translate 0 0 5 Sphere 1 -1 1 360 SolidEnd\n"
			   "  SolidEnd\n",
			   "inside", s))
		return;
	double t = tan(asin(0.2));
	check_area("eye inside: A & ball", s[2], PI * t * t, 0.005);
}

int main(void)
{
	if (!scene_dir_create("relight-csg"))
		return 1;
	RUN(test_difference);
	RUN(test_intersection);
	RUN(test_union);
	RUN(test_cut_face);
	RUN(test_nested);
	RUN(test_transparent);
	RUN(test_motion);
	RUN(test_camera_inside);
	scene_dir_remove();
	return test_finish();
}

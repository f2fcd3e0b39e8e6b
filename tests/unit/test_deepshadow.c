/*
 * Deep shadow maps (a `Display "deepshad" "deepopacity"` shadow pass, then
 * shadow() of the map) end to end, against closed forms:
 *  - a stack of semi-transparent planes between a spot light and an opaque
 *    receiver lets through the product of their transparencies (1 %);
 *  - a depth map of the same stack gives an all-or-nothing answer;
 *  - a pixel half covered by an opaque plane holds visibility 0.5 (the
 *    average over the pixel's samples);
 *  - many thin layers compress within the error bound;
 *  - malformed deep maps are refused with the file's name.
 */
#include "deepshadow.h"
#include "exr_internal.h"
#include "render_scene.h"
#include "test.h"
#include "texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/*
 * Frame 1, the shadow pass: an orthographic camera 5 above the origin
 * looking down (camera x = world x, camera y = world z), 32x32 pixels over
 * [-2, 2]^2, 4x4 samples, box filter; @planes (a RIB fragment) and the
 * receiver y = 0. @display names the map's kind ("deepshad" "deepopacity"
 * or "zfile" "z"). Frame 2: the receiver alone, matte Kd 1, seen from above
 * the same way, lit by shadowspot at (0, 5, 0) with @shadowname.
 */
static char *scene(const char *display, const char *mkshadow, const char *planes,
		   const char *shadowname)
{
	static char buf[16384];
	snprintf(buf, sizeof(buf),
		 "FrameBegin 1\n"
		 "  Format 32 32 1\n"
		 "  PixelSamples 4 4\n"
		 "  PixelFilter \"box\" 1 1\n"
		 "  Projection \"orthographic\"\n"
		 "  ScreenWindow -2 2 -2 2\n"
		 "  Display \"map.in\" %s\n"
		 "  Rotate -90 1 0 0\n"
		 "  Translate 0 -5 0\n"
		 "  WorldBegin\n"
		 "    Surface \"constant\"\n"
		 "    %s\n"
		 "    Polygon \"P\" [-3 0 -3  3 0 -3  3 0 3  -3 0 3]\n"
		 "  WorldEnd\n"
		 "FrameEnd\n"
		 "%s\n"
		 "FrameBegin 2\n"
		 "  Format 32 32 1\n"
		 "  PixelSamples 4 4\n"
		 "  PixelFilter \"box\" 1 1\n"
		 "  Projection \"orthographic\"\n"
		 "  ScreenWindow -2 2 -2 2\n"
		 "  Display \"lit.exr\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		 "  Rotate -90 1 0 0\n"
		 "  Translate 0 -10 0\n"
		 "  WorldBegin\n"
		 "    LightSource \"shadowspot\" 1 \"intensity\" 25 \"from\" [0 5 0] \"to\" [0 0 0]\n"
		 "      \"coneangle\" 1.2 \"conedeltaangle\" 0.1 \"beamdistribution\" 0\n"
		 "      \"shadowname\" \"%s\" \"samples\" 1\n"
		 "    Surface \"matte\" \"Ka\" 0 \"Kd\" 1\n"
		 "    Polygon \"P\" [-3 0 -3  3 0 -3  3 0 3  -3 0 3]\n"
		 "  WorldEnd\n"
		 "FrameEnd\n",
		 display, planes, mkshadow, shadowname);
	return buf;
}

/* Three planes over x < 0 at heights 1, 2, 3, opacities 0.3, 0.5, 0.2. */
static const char stack[] =
	"AttributeBegin Opacity [0.3 0.3 0.3] Polygon \"P\" [-3 1 -3  0 1 -3  0 1 3  -3 1 3] "
	"AttributeEnd "
	"AttributeBegin Opacity [0.5 0.5 0.5] Polygon \"P\" [-3 2 -3  0 2 -3  0 2 3  -3 2 3] "
	"AttributeEnd "
	"AttributeBegin Opacity [0.2 0.2 0.2] Polygon \"P\" [-3 3 -3  0 3 -3  0 3 3  -3 3 3] "
	"AttributeEnd";

/* The mean red of columns [x0, x1), rows [4, 28) of @im. */
static double region(const struct reyes_image *im, uint32_t x0, uint32_t x1)
{
	int r = channel(im, "R");
	double sum = 0;
	uint32_t n = 0;
	for (uint32_t y = 4; y < 28; y++)
		for (uint32_t x = x0; x < x1; x++, n++)
			sum += px(im, r, x, y);
	return n ? sum / n : 0;
}

/* Render @rib; the lit frame's image. */
static bool lit(const char *rib, struct reyes_image *im)
{
	memset(im, 0, sizeof(*im));
	return render(rib, "lit.exr", im) && channel(im, "R") >= 0;
}

/*
 * Under the stack the receiver gets (1 - 0.3)(1 - 0.5)(1 - 0.2) = 0.28 of
 * the light it gets without the map, pixel region by pixel region, within
 * 1 %; beside the stack (x > 0) all of it. The same stack as a depth map
 * (MakeShadow of a zfile) is opaque: no light under it.
 */
static void test_stack(void)
{
	struct reyes_image open = { 0 }, deep = { 0 }, depth = { 0 };
	CHECK(lit(scene("\"deepshad\" \"deepopacity\"", "", stack, ""), &open));
	CHECK(lit(scene("\"deepshad\" \"deepopacity\"", "", stack, "map.in"), &deep));
	CHECK(lit(scene("\"zfile\" \"z\"", "MakeShadow \"map.in\" \"map.shd\"", stack,
			"map.shd"), &depth));
	if (!open.data || !deep.data || !depth.data)
		goto done;
	double o_in = region(&open, 2, 14), o_out = region(&open, 18, 30);
	double d_in = region(&deep, 2, 14), d_out = region(&deep, 18, 30);
	double z_in = region(&depth, 2, 14);
	double want = 0.7 * 0.5 * 0.8;
	printf("stack: deep %.5f of the light under it (closed form %.5f, tolerance 1%%), "
	       "%.5f beside it; depth map %.5f\n", d_in / o_in, want, d_out / o_out, z_in / o_in);
	CHECK(o_in > 0.1);
	CHECK_NEAR(d_in / o_in, want, 0.01 * want);
	CHECK_NEAR(d_out / o_out, 1.0, 0.01);
	/* a depth map's answer is all or nothing: the stack lets 0.72 through,
	   under the opacity threshold, so the sample's depth is the receiver's */
	CHECK(z_in / o_in < 0.01 || fabs(z_in / o_in - 1.0) < 0.01);
	/* and pixel by pixel, the region under the stack */
	int r = channel(&deep, "R");
	double worst = 0;
	for (uint32_t y = 4; y < 28; y++)
		for (uint32_t x = 2; x < 14; x++) {
			double e = fabs(px(&deep, r, x, y) / px(&open, r, x, y) - want) / want;
			worst = e > worst ? e : worst;
		}
	printf("stack: worst pixel off by %.4f%% (tolerance 1%%)\n", worst * 100);
	CHECK(worst < 0.01);
done:
	reyes_image_finish(&open);
	reyes_image_finish(&deep);
	reyes_image_finish(&depth);
}

/* The map's texel (x, y) transmittance at depth @z, through the texture system. */
static double texel_at(const char *name, uint32_t x, uint32_t y, double z, uint32_t *nodes)
{
	static const float id[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	struct reyes_texsys *ts = reyes_texsys_create(tmpdir, id, NULL);
	struct reyes_shadow_map_info info;
	double t = -1;
	if (ts && reyes_tex_shadow_map(ts, name, &info) && info.deep_offsets) {
		struct reyes_deep_map m = {
			.width = info.width, .height = info.height,
			.offsets = (uint32_t *)info.deep_offsets, .zt = (float *)info.deep_nodes,
		};
		t = reyes_deep_eval(&m, x, y, z);
		size_t p = (size_t)y * info.width + x;
		if (nodes)
			*nodes = info.deep_offsets[p + 1] - info.deep_offsets[p];
	}
	reyes_texsys_destroy(ts);
	return t;
}

/*
 * An opaque plane over x < -0.0625 at height 2: the map's column 15 spans
 * x in [-0.125, 0), so the plane covers half of each of its pixels. With
 * 4x4 stratified samples, two columns of strata are in: visibility 0.5
 * behind the plane (depth > 3), 1 in front, and 0 in column 14, 1 in
 * column 16.
 */
static void test_half_pixel(void)
{
	const char *half = "Polygon \"P\" [-3 2 -3  -0.0625 2 -3  -0.0625 2 3  -3 2 3]";
	struct reyes_image im = { 0 };
	CHECK(lit(scene("\"deepshad\" \"deepopacity\"", "", half, "map.in"), &im));
	reyes_image_finish(&im);
	uint32_t n = 0;
	double t = texel_at("map.in", 15, 16, 4.0, &n);
	printf("half-covered pixel: visibility %.5f behind the plane (want 0.5), %u nodes\n", t, n);
	CHECK_NEAR(t, 0.5, 0.01);
	CHECK_NEAR(texel_at("map.in", 15, 16, 2.9, NULL), 1.0, 1e-6);
	CHECK_NEAR(texel_at("map.in", 14, 16, 4.0, NULL), 0.0, 1e-6);
	/* column 16 sees only the receiver at depth 5 */
	CHECK_NEAR(texel_at("map.in", 16, 16, 4.0, NULL), 1.0, 1e-6);
	CHECK_NEAR(texel_at("map.in", 16, 16, 5.5, NULL), 0.0, 1e-6);
}

/*
 * Fifty layers of opacity 0.01 between heights 1 and 3.45, in a map built
 * with "deepshadowerror" 0.02: the exact visibility behind layer k is
 * 0.99^k. The compressed function stays within 0.02 of it everywhere
 * between the layers, and keeps fewer nodes than the 100 of the
 * uncompressed steps (runs of layers become ramps).
 */
static void test_compression(void)
{
	static char layers[8192];
	size_t at = 0;
	for (int k = 0; k < 50; k++)
		at += (size_t)snprintf(layers + at, sizeof(layers) - at,
				       "AttributeBegin Opacity [0.01 0.01 0.01] Polygon \"P\" "
				       "[-3 %g -3  3 %g -3  3 %g 3  -3 %g 3] AttributeEnd ",
				       3.45 - 0.05 * k, 3.45 - 0.05 * k, 3.45 - 0.05 * k,
				       3.45 - 0.05 * k);
	struct reyes_image im = { 0 };
	CHECK(lit(scene("\"deepshad\" \"deepopacity\" \"float deepshadowerror\" [0.02]", "",
			layers, "map.in"), &im));
	reyes_image_finish(&im);
	double worst = 0;
	uint32_t n = 0;
	/* layer k at height 3.45 - 0.05 k is at depth 1.55 + 0.05 k */
	for (int k = 0; k <= 50; k++) {
		double z = 1.55 + 0.05 * k - 0.025;     /* between layers k - 1 and k */
		double exact = pow(0.99, k);
		double got = texel_at("map.in", 10, 10, z, &n);
		double e = fabs(got - exact);
		worst = e > worst ? e : worst;
	}
	printf("50 layers: %u nodes (100 uncompressed), worst error %.5f (bound 0.02)\n", n, worst);
	CHECK(worst <= 0.02 + 1e-6);
	CHECK(n > 2 && n < 100);
}

/* Write a deep map file whose "deepshadow" attribute is @attr over a 2x1 image @data (T, Z). */
static void write_bad(const char *name, const char *attr, uint32_t w, uint32_t h,
		      const float *data)
{
	static const char *const names[2] = { "T", "Z" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, w, h, 2, names));
	memcpy(im.data, data, sizeof(float) * 2 * w * h);
	im.has_matrices = true;
	for (int k = 0; k < 16; k++)
		im.world_to_camera[k] = im.world_to_ndc[k] = k % 5 == 0;
	const char *sa[2] = { "deepshadow", attr };
	struct reyes_exr_write_opts o = { .strattrs = sa, .nstrattrs = 1 };
	CHECK(reyes_exr_write(tmp_path(name), &im, 1, &o, NULL));
	reyes_image_finish(&im);
}

/* A malformed deep map: shadow() and MakeShadow refuse it, naming the file. */
static void expect_refused(const char *name, const char *why)
{
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	static const float id[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	struct reyes_texsys *ts = reyes_texsys_create(tmpdir, id, diag);
	struct reyes_shadow_map_info info;
	CHECK(!reyes_tex_shadow_map(ts, name, &info));
	reyes_texsys_destroy(ts);
	CHECK(!reyes_make_shadow(tmp_path(name), tmp_path("bad.out"), diag));
	fclose(diag);
	printf("%s: %s", name, dbuf);
	CHECK(dbuf && strstr(dbuf, name) && strstr(dbuf, why));
	free(dbuf);
}

static void test_malformed(void)
{
	/* a 1x1 map of 2 nodes, a step from 1 to 0.5 at depth 1: row 0 holds the
	   count (Z) and the final transmittance (T), rows 1 and 2 the nodes (T, Z) */
	const float good[6] = { 0.5f, 2, 1.0f, 1.0f, 0.5f, 1.0f };
	write_bad("good.dsm", "relight-dsm 1 1 1 2", 1, 3, good);
	CHECK_NEAR(texel_at("good.dsm", 0, 0, 2.0, NULL), 0.5, 1e-6);
	/* textureinfo: a shadow map of the map's size, not of its image's */
	static const float id[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	struct reyes_texsys *ts = reyes_texsys_create(tmpdir, id, NULL);
	float res[2] = { 0, 0 };
	const char *type = NULL;
	CHECK(reyes_tex_info(ts, "good.dsm", "resolution", SL_TYPE_FLOAT, 2, res, NULL));
	CHECK(res[0] == 1 && res[1] == 1);
	CHECK(reyes_tex_info(ts, "good.dsm", "type", SL_TYPE_STRING, 0, NULL, &type));
	CHECK(type && !strcmp(type, "shadow"));
	reyes_texsys_destroy(ts);
	write_bad("attr.dsm", "relight-dsm one", 1, 3, good);
	expect_refused("attr.dsm", "attribute");
	write_bad("version.dsm", "relight-dsm 7 1 1 2", 1, 3, good);
	expect_refused("version.dsm", "version");
	write_bad("size.dsm", "relight-dsm 1 1 1 5", 1, 3, good);
	expect_refused("size.dsm", "size");
	const float count[6] = { 0.5f, 3, 1.0f, 1.0f, 0.5f, 1.0f };
	write_bad("count.dsm", "relight-dsm 1 1 1 2", 1, 3, count);
	expect_refused("count.dsm", "count");
	const float order[6] = { 0.5f, 2, 1.0f, 2.0f, 0.5f, 1.0f };
	write_bad("order.dsm", "relight-dsm 1 1 1 2", 1, 3, order);
	expect_refused("order.dsm", "order");
	const float range[6] = { 0.5f, 2, 1.0f, 1.0f, 1.5f, 2.0f };
	write_bad("range.dsm", "relight-dsm 1 1 1 2", 1, 3, range);
	expect_refused("range.dsm", "range");
}

int main(void)
{
	if (!scene_dir_create("relight-deep"))
		return 1;
	RUN(test_stack);
	RUN(test_half_pixel);
	RUN(test_compression);
	RUN(test_malformed);
	scene_dir_remove();
	return test_finish();
}

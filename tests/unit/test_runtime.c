/*
 * The GPU runtime against the CPU resolver and against itself, on a small
 * scene baked here (argv[1] is the relight command) with the hard cases of
 * shading in it: a point light lying on the ground plane, a distant light
 * grazing it, roughness near 0, and a polygon whose normals are all zero.
 *
 *  - every level is finite and the final level matches resolve_cpu within
 *    1e-4 relative (|gpu - cpu| / max(|gpu|, |cpu|, 1e-3), as relight diff);
 *  - 100,000 random edits of one light (intensities 1e-4 to 1e4, colours,
 *    positions), each folded into the light cache and rendered, then its
 *    parameters restored: the final image within 1e-4 relative of the one
 *    before (the cache is summed in double: exact, so the bound holds with
 *    room to spare);
 *  - NaN, infinite and out-of-range values are refused and change nothing;
 *  - mute, solo and light linking against the CPU resolver with the light's
 *    intensity at 0;
 *  - the graph reruns nothing when nothing changed, and an edit of an
 *    unfrozen light shades each sample of the level once.
 *
 * Skips (exit 77) without an EGL context.
 */
#include "color.h"
#include "gpu.h"
#include "shotfile.h"
#include "graph.h"
#include "bake/resolve.h"
#include "runtime.h"
#include "shadowrender.h"
#include "texture.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define REL_TOL 1e-4
#define NEDITS 100000

static const char scene[] =
	"Format 64 48 1\n"
	"PixelSamples 2 2\n"
	"Projection \"perspective\" \"fov\" 45\n"
	"Display \"hard.exr\" \"file\" \"rgba\"\n"
	"Translate 0 -0.6 4\n"
	"Rotate -15 1 0 0\n"
	"WorldBegin\n"
	"  LightSource \"ambientlight\" 1 \"intensity\" 0.05\n"
	"  LightSource \"pointlight\" 2 \"intensity\" 1.5 \"from\" [0.4 0 0.5]\n"
	"  LightSource \"spotlight\" 3 \"intensity\" 12 \"from\" [1 3 -1] \"to\" [0 0 0.5]"
	" \"coneangle\" 0.5 \"conedeltaangle\" 0.1\n"
	"  LightSource \"distantlight\" 4 \"intensity\" 0.8 \"from\" [0 0 0] \"to\" [1 0 0]\n"
	"  AttributeBegin\n"
	"    Surface \"plastic\" \"roughness\" 1e-6 \"Ks\" 0.8\n"
	"    Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
	"  AttributeEnd\n"
	"  AttributeBegin\n"
	"    Surface \"metal\" \"roughness\" 0.0001\n"
	"    Translate -0.6 0.45 0.8\n"
	"    Sphere 0.45 -0.45 0.45 360\n"
	"  AttributeEnd\n"
	"  AttributeBegin\n"
	"    Surface \"plastic\"\n"
	"    Polygon \"P\" [0.3 0.1 0  0.9 0.1 0  0.9 0.6 0  0.3 0.6 0]"
	" \"N\" [0 0 0  0 0 0  0 0 0  0 0 0]\n"
	"  AttributeEnd\n"
	"WorldEnd\n";

/* A shadowed key light: frame 1 renders its depth, frame 2 the view. The
 * string SHADOWNAME is replaced by the map's name, or by nothing. */
static const char shadow_scene[] =
	"FrameBegin 1\n"
	"Format 128 128 1\nPixelSamples 1 1\nPixelFilter \"box\" 1 1\n"
	"Hider \"hidden\" \"depthfilter\" \"midpoint\"\n"
	"Projection \"perspective\" \"fov\" 50\n"
	"Display \"key.z\" \"zfile\" \"z\"\n"
	"Rotate -90 1 0 0\nTranslate 0 -4 -1.7\n"
	"WorldBegin\n"
	"  Surface \"constant\"\n"
	"  Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
	"  AttributeBegin Translate 0 0.5 1 Sphere 0.5 -0.5 0.5 360 AttributeEnd\n"
	"WorldEnd\nFrameEnd\n"
	"MakeShadow \"key.z\" \"key.shd\"\n"
	"FrameBegin 2\n"
	"Format 64 48 1\nPixelSamples 2 2\n"
	"Projection \"perspective\" \"fov\" 45\n"
	"Display \"shadowed.exr\" \"file\" \"rgba\"\n"
	"Translate 0 -0.6 4\nRotate -15 1 0 0\n"
	"WorldBegin\n"
	"  LightSource \"ambientlight\" 1 \"intensity\" 0.1\n"
	"  LightSource \"shadowspot\" 2 \"intensity\" 14 \"from\" [0 4 1.7] \"to\" [0 0 1.7]"
	" \"coneangle\" 0.9 SHADOWNAME\n"
	"  Surface \"plastic\" \"Kd\" 0.7\n"
	"  Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
	"  AttributeBegin Surface \"matte\" Translate 0 0.5 1 Sphere 0.5 -0.5 0.5 360 AttributeEnd\n"
	"WorldEnd\nFrameEnd\n";

static struct gpu_ctx *ctx;
static struct gpu_shot *shot;
static char shot_path[512];
static uint32_t W, H;

static double max_rel(const float *a, const float *b, size_t n, size_t *at)
{
	double m = 0.0;
	for (size_t i = 0; i < n; i++) {
		if (i % 4 == 3)
			continue;
		double d = fabs((double)a[i] - (double)b[i]);
		double s = fmax(fmax(fabs((double)a[i]), fabs((double)b[i])), 1e-3);
		if (!(d / s <= m)) {
			m = isfinite(d / s) ? d / s : INFINITY;
			if (at)
				*at = i;
		}
	}
	return m;
}

static bool all_finite(const float *a, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (!isfinite(a[i]))
			return false;
	return true;
}

static float *gpu_image(int level)
{
	float *img = calloc((size_t)W * H * 4, sizeof(float));
	struct gpu_shot_stats st;
	CHECK(gpu_shot_render(shot, level, &st));
	CHECK(gpu_shot_read_rgba(shot, level, img));
	return img;
}

static float *cpu_image(int level, const struct resolve_edit *e, size_t ne)
{
	struct resolve_opts o = { .diag = stderr, .level = level, .edits = e, .nedits = ne };
	struct resolve_result r;
	if (!resolve_cpu(shot_path, &o, &r)) {
		CHECK(!"resolve_cpu failed");
		return calloc((size_t)W * H * 4, sizeof(float));
	}
	return r.rgba;
}

/* The linear half and 8-bit outputs: exactly the CPU's conversions of the floats. */
static void test_outputs(void)
{
	size_t n = (size_t)W * H;
	float *f = gpu_image(3);
	uint16_t *h = calloc(n * 4, sizeof(uint16_t));
	uint32_t *px = calloc(n, sizeof(uint32_t));
	CHECK(gpu_shot_read_half(shot, 3, h) && gpu_shot_read_srgb8(shot, 3, px));
	size_t bad_half = 0, bad8 = 0;
	for (size_t i = 0; i < n * 4; i++)
		bad_half += shot_half_value(h[i]) != shot_half_round(f[i]);
	for (size_t i = 0; i < n; i++) {
		uint32_t want = 0;
		for (int c = 0; c < 3; c++)
			want |= (uint32_t)rl_srgb8(f[i * 4 + (size_t)c]) << (8 * c);
		want |= (uint32_t)rl_unorm8(f[i * 4 + 3]) << 24;
		bad8 += px[i] != want;
	}
	if (bad_half || bad8)
		fprintf(stderr, "outputs: %zu half values and %zu 8-bit pixels differ\n", bad_half,
			bad8);
	CHECK(bad_half == 0);
	CHECK(bad8 == 0);
	free(f);
	free(h);
	free(px);
}

static void test_matches_cpu(void)
{
	for (int level = 0; level <= 3; level++) {
		float *g = gpu_image(level), *c = cpu_image(level, NULL, 0);
		size_t at = 0;
		double r = max_rel(g, c, (size_t)W * H * 4, &at);
		CHECK(all_finite(g, (size_t)W * H * 4));
		double sum = 0.0;
		for (size_t i = 0; i < (size_t)W * H * 4; i++)
			sum += i % 4 == 3 ? 0.0 : g[i];
		CHECK(sum / ((double)W * H * 3) > 0.01);
		if (!(r <= REL_TOL))
			fprintf(stderr, "level %d: relative difference %g at pixel %zu\n", level, r,
				at / 4);
		CHECK(r <= REL_TOL);
		free(g);
		free(c);
	}
}

static uint32_t rng = 0x9e3779b9u;

static double uniform(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 17;
	rng ^= rng << 5;
	return (rng >> 8) * (1.0 / 16777216.0);
}

static void test_stability(void)
{
	float *before = gpu_image(3);
	float inten[16], from[16], color[16];
	uint32_t ni, nf, nc;
	CHECK(gpu_shot_get(shot, "3", "intensity", inten, &ni) && ni == 1);
	CHECK(gpu_shot_get(shot, "3", "from", from, &nf) && nf == 3);
	CHECK(gpu_shot_get(shot, "3", "lightcolor", color, &nc) && nc == 3);
	/* the values gpu_shot_get gives are in current space: edit in the light's space */
	const float from0[3] = { 1, 3, -1 };
	char err[256];
	bool finite = true;
	for (int i = 0; i < NEDITS; i++) {
		float v = (float)pow(10.0, -4.0 + 8.0 * uniform());
		float c[3] = { (float)uniform(), (float)uniform(), (float)uniform() };
		float p[3] = { (float)(uniform() * 4 - 2), (float)(uniform() * 4), (float)(uniform() * 4 - 2) };
		CHECK(gpu_shot_set(shot, "3", "intensity", &v, 1, err, sizeof(err)));
		if (i % 3 == 0)
			CHECK(gpu_shot_set(shot, "3", "lightcolor", c, 3, err, sizeof(err)));
		if (i % 7 == 0)
			CHECK(gpu_shot_set(shot, "3", "from", p, 3, err, sizeof(err)));
		/* into the cache: the next render subtracts the old and adds the new */
		CHECK(gpu_shot_freeze(shot, "3", true, err, sizeof(err)));
		int level = i % 1000 == 999 ? 3 : 0;
		CHECK(gpu_shot_render(shot, level, NULL));
		if (i % 10000 == 9999) {
			float *img = gpu_image(level);
			finite = finite && all_finite(img, (size_t)W * H * 4);
			free(img);
		}
		if (test_failures)
			break;
	}
	CHECK(finite);
	float one = 12.0f;
	float col0[3] = { 1, 1, 1 };
	CHECK(gpu_shot_set(shot, "3", "intensity", &one, 1, err, sizeof(err)));
	CHECK(gpu_shot_set(shot, "3", "lightcolor", col0, 3, err, sizeof(err)));
	CHECK(gpu_shot_set(shot, "3", "from", from0, 3, err, sizeof(err)));
	CHECK(gpu_shot_freeze(shot, "3", true, err, sizeof(err)));
	float after_i[16], after_f[16];
	CHECK(gpu_shot_get(shot, "3", "intensity", after_i, &ni) && after_i[0] == inten[0]);
	CHECK(gpu_shot_get(shot, "3", "from", after_f, &nf) && !memcmp(after_f, from, 12));
	float *after = gpu_image(3);
	size_t at = 0;
	double r = max_rel(after, before, (size_t)W * H * 4, &at);
	printf("after %d edits folded into the light cache and restored: relative difference "
	       "%g\n", NEDITS, r);
	CHECK(r <= REL_TOL);
	free(before);
	free(after);
}

static void test_refused(void)
{
	float *before = gpu_image(3);
	char err[256];
	float nan = NAN, inf = INFINITY, big = 4.0f, v3[3] = { 1, NAN, 0 };
	err[0] = '\0';
	CHECK(!gpu_shot_set(shot, "3", "intensity", &nan, 1, err, sizeof(err)));
	CHECK(strstr(err, "finite") != NULL);
	CHECK(!gpu_shot_set(shot, "3", "intensity", &inf, 1, err, sizeof(err)));
	CHECK(!gpu_shot_set(shot, "3", "coneangle", &big, 1, err, sizeof(err)));
	CHECK(strstr(err, "outside") != NULL);
	CHECK(!gpu_shot_set(shot, "3", "from", v3, 3, err, sizeof(err)));
	CHECK(!gpu_shot_set(shot, "3", "from", v3, 2, err, sizeof(err)));
	CHECK(!gpu_shot_set(shot, "9", "intensity", &big, 1, err, sizeof(err)));
	CHECK(strstr(err, "no light named '9'") != NULL);
	CHECK(!gpu_shot_set(shot, "3", "nope", &big, 1, err, sizeof(err)));
	CHECK(!gpu_shot_link(shot, "3", 100000, false, err, sizeof(err)));
	float *after = gpu_image(3);
	CHECK(!memcmp(before, after, (size_t)W * H * 4 * sizeof(float)));
	free(before);
	free(after);
}

static void test_mute_solo_link(void)
{
	char err[256];
	struct resolve_edit off2 = { .light = "2", .param = "intensity", .values = { 0 }, .nvalues = 1 };
	float *cpu_off2 = cpu_image(3, &off2, 1);
	CHECK(gpu_shot_mute(shot, "2", true, err, sizeof(err)));
	float *muted = gpu_image(3);
	CHECK(max_rel(muted, cpu_off2, (size_t)W * H * 4, NULL) <= REL_TOL);
	CHECK(gpu_shot_mute(shot, "2", false, err, sizeof(err)));
	/* unlinking every object from light 2 is muting it */
	for (uint32_t o = 0; o < 64; o++)
		if (!gpu_shot_link(shot, "2", o, false, err, sizeof(err)))
			break;
	float *unlinked = gpu_image(3);
	CHECK(max_rel(unlinked, muted, (size_t)W * H * 4, NULL) <= 1e-6);
	for (uint32_t o = 0; o < 64; o++)
		if (!gpu_shot_link(shot, "2", o, true, err, sizeof(err)))
			break;
	/* solo 3: the others at intensity 0 */
	struct resolve_edit others[3] = {
		{ .light = "1", .param = "intensity", .nvalues = 1 },
		{ .light = "2", .param = "intensity", .nvalues = 1 },
		{ .light = "4", .param = "intensity", .nvalues = 1 },
	};
	float *cpu_solo = cpu_image(3, others, 3);
	CHECK(gpu_shot_solo(shot, "3", err, sizeof(err)));
	float *solo = gpu_image(3);
	CHECK(max_rel(solo, cpu_solo, (size_t)W * H * 4, NULL) <= REL_TOL);
	CHECK(gpu_shot_solo(shot, NULL, err, sizeof(err)));
	float *back = gpu_image(3), *cpu = cpu_image(3, NULL, 0);
	CHECK(max_rel(back, cpu, (size_t)W * H * 4, NULL) <= REL_TOL);
	free(cpu_off2);
	free(muted);
	free(unlinked);
	free(cpu_solo);
	free(solo);
	free(back);
	free(cpu);
}

static void test_graph_work(void)
{
	struct gpu_shot_stats st;
	char err[256];
	CHECK(gpu_shot_render(shot, 3, &st));
	CHECK(gpu_shot_render(shot, 3, &st));
	CHECK(st.shaded == 0 && st.dispatches == 0);
	/* light 4 is frozen: its first edit shades the old and the new state, later
	 * edits only the new one, each sample once */
	float v = 0.5f;
	CHECK(gpu_shot_set(shot, "4", "intensity", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_render(shot, 3, &st));
	uint64_t first = st.shaded;
	v = 0.6f;
	CHECK(gpu_shot_set(shot, "4", "intensity", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_render(shot, 3, &st));
	CHECK(first == 2 * st.shaded);
	CHECK(st.shaded == gpu_shot_samples(shot));
	/* a coarse level shades only its band */
	v = 0.7f;
	CHECK(gpu_shot_set(shot, "4", "intensity", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_render(shot, 0, &st));
	CHECK(st.shaded > 0 && st.shaded * 8 < gpu_shot_samples(shot));
	v = 0.8f;
	CHECK(gpu_shot_set(shot, "4", "intensity", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_render(shot, 3, &st));
}

static char workdir[64], relight_cmd[1024];

/* @in with every @from replaced by @to, into @out (@len bytes). */
static void replace_all(const char *in, const char *from, const char *to, char *out, size_t len)
{
	size_t at = 0, nf = strlen(from), nt = strlen(to);
	while (*in && at + 1 < len) {
		if (!strncmp(in, from, nf) && at + nt + 1 < len) {
			memcpy(out + at, to, nt);
			at += nt;
			in += nf;
		} else {
			out[at++] = *in++;
		}
	}
	out[at] = '\0';
}

/* Bake @rib_text (with @from replaced by @to) into WORKDIR/@name.shot.exr with @flags. */
static bool bake(const char *name, const char *rib_text, const char *from, const char *to,
		 const char *flags, char *shot, size_t len)
{
	char rib[256], cmd[2048];
	snprintf(rib, sizeof(rib), "%s/%s.rib", workdir, name);
	FILE *f = fopen(rib, "w");
	if (!f)
		return false;
	const char *at = from ? strstr(rib_text, from) : NULL;
	if (at) {
		fwrite(rib_text, 1, (size_t)(at - rib_text), f);
		fputs(to, f);
		fputs(at + strlen(from), f);
	} else {
		fputs(rib_text, f);
	}
	fclose(f);
	snprintf(shot, len, "%s/%s.shot.exr", workdir, name);
	snprintf(cmd, sizeof(cmd), "cd %s && %s bake -q %s -o %s %s", workdir, relight_cmd, flags,
		 shot, rib);
	return system(cmd) == 0;
}

static float *image_of(const char *path, bool gpu_side, struct gpu_shot *sh)
{
	float *img = calloc((size_t)W * H * 4, sizeof(float));
	if (gpu_side) {
		CHECK(gpu_shot_render(sh, 3, NULL) && gpu_shot_read_rgba(sh, 3, img));
		return img;
	}
	struct resolve_opts o = { .diag = stderr, .level = 3, .texture_path = workdir };
	struct resolve_result r;
	CHECK(resolve_cpu(path, &o, &r));
	if (r.rgba && r.width == W && r.height == H)
		memcpy(img, r.rgba, (size_t)W * H * 4 * sizeof(float));
	free(r.rgba);
	return img;
}

/* Shadows off, shadow density and colour, against the CPU with and without the map. */
static void test_shadow_look(void)
{
	char on[512], off[512], err[256];
	CHECK(bake("on", shadow_scene, "SHADOWNAME", "\"shadowname\" \"key.shd\" \"samples\" 16", "",
		   on, sizeof(on)));
	CHECK(bake("off", shadow_scene, "SHADOWNAME", "", "", off, sizeof(off)));
	struct gpu_shot_opts o = { .texture_path = workdir };
	struct gpu_shot *sh = gpu_shot_open(ctx, on, &o);
	CHECK(sh != NULL);
	if (!sh)
		return;
	size_t n = (size_t)W * H * 4;
	float *cpu_on = image_of(on, false, NULL), *cpu_off = image_of(off, false, NULL);
	float *g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_on, n, NULL) <= REL_TOL);
	/* the map darkens part of the frame */
	CHECK(max_rel(cpu_on, cpu_off, n, NULL) > 0.5);
	free(g);
	CHECK(!gpu_shot_shadows(sh, "1", false, err, sizeof(err)));
	CHECK(strstr(err, "casts no shadows") != NULL);
	CHECK(gpu_shot_shadows(sh, "2", false, err, sizeof(err)));
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_off, n, NULL) <= REL_TOL);
	free(g);
	CHECK(gpu_shot_shadows(sh, "2", true, err, sizeof(err)));
	const float blue[3] = { 0.2f, 0.4f, 1.0f };
	CHECK(gpu_shot_shadow_look(sh, "2", 0.6f, blue, err, sizeof(err)));
	g = image_of(on, true, sh);
	float *want = malloc(n * sizeof(float));
	for (size_t i = 0; i < n; i++) {
		float w = i % 4 == 3 ? 0.0f : 0.6f * (1.0f - blue[i % 4]);
		want[i] = cpu_off[i] * (1.0f - w) + cpu_on[i] * w;
	}
	size_t at = 0;
	double r = max_rel(g, want, n, &at);
	if (!(r <= REL_TOL))
		fprintf(stderr, "shadow look: %g at %zu\n", r, at);
	CHECK(r <= REL_TOL);
	const float bad[3] = { 0, 2, 0 };
	CHECK(!gpu_shot_shadow_look(sh, "2", 1.5f, blue, err, sizeof(err)));
	CHECK(!gpu_shot_shadow_look(sh, "2", 0.5f, bad, err, sizeof(err)));
	/* and back to plain shadows */
	const float black[3] = { 0, 0, 0 };
	CHECK(gpu_shot_shadow_look(sh, "2", 1.0f, black, err, sizeof(err)));
	free(g);
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_on, n, NULL) <= REL_TOL);
	free(g);
	/* no object receiving the key light's shadows is its shadows off */
	uint32_t objects = 0;
	while (objects < 1000 && gpu_shot_receive_shadows(sh, "2", objects, false, err, sizeof(err)))
		objects++;
	CHECK(objects >= 2 && strstr(err, "no object") != NULL);
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_off, n, NULL) <= REL_TOL);
	free(g);
	/* one object receiving again: some pixels shadowed, none darker than with shadows */
	CHECK(gpu_shot_receive_shadows(sh, "2", 0, true, err, sizeof(err)));
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_off, n, NULL) > REL_TOL || max_rel(g, cpu_on, n, NULL) <= REL_TOL);
	free(g);
	for (uint32_t o = 0; o < objects; o++)
		CHECK(gpu_shot_receive_shadows(sh, "2", o, true, err, sizeof(err)));
	CHECK(!gpu_shot_receive_shadows(sh, "1", 0, false, err, sizeof(err)));
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_on, n, NULL) <= REL_TOL);
	free(g);

	/* casting: with no object casting, the map is empty: shadows off */
	uint32_t casting = 0;
	while (casting < objects && gpu_shot_cast_shadows(sh, "2", casting, false, err, sizeof(err)))
		casting++;
	if (casting < objects)
		fprintf(stderr, "cast: %s\n", err);
	CHECK(casting == objects);
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_off, n, NULL) <= REL_TOL);
	free(g);
	/* the ground alone casting (the sphere is object 1): the shot whose
	 * shadow pass leaves the sphere out, but for the map's rasterization */
	char nosphere[512], text[4096], text2[4096];
	const char *sphere = "  AttributeBegin Translate 0 0.5 1 Sphere 0.5 -0.5 0.5 360 AttributeEnd\n";
	const char *first = strstr(shadow_scene, sphere);
	snprintf(text, sizeof(text), "%.*s%s", (int)(first - shadow_scene), shadow_scene,
		 first + strlen(sphere));
	replace_all(text, "key.", "ns.", text2, sizeof(text2));
	CHECK(bake("nosphere", text2, "SHADOWNAME", "\"shadowname\" \"ns.shd\" \"samples\" 16",
		   "", nosphere, sizeof(nosphere)));
	CHECK(gpu_shot_cast_shadows(sh, "2", 0, true, err, sizeof(err)));
	g = image_of(on, true, sh);
	float *cpu_ns = image_of(nosphere, false, NULL);
	double mean = 0.0;
	for (size_t i = 0; i < n; i++)
		mean += fabs((double)g[i] - cpu_ns[i]) / (double)n;
	printf("casting edited: GPU-rendered map against the renderer's map of the same casters: "
	       "mean difference %.3g, largest relative %.3g\n", mean, max_rel(g, cpu_ns, n, NULL));
	CHECK(mean <= 1e-3);
	free(g);
	free(cpu_ns);
	for (uint32_t o = 0; o < objects; o++)
		CHECK(gpu_shot_cast_shadows(sh, "2", o, true, err, sizeof(err)));
	g = image_of(on, true, sh);
	CHECK(max_rel(g, cpu_on, n, NULL) <= REL_TOL);
	free(g);

	/* maps that follow the light: unmoved, the map file's camera (the key
	 * light looks straight down, as the shadow pass does); moved, the
	 * shot whose shadow pass and light moved together */
	CHECK(!gpu_shot_shadow_follow(sh, "1", true, err, sizeof(err)));
	CHECK(gpu_shot_shadow_follow(sh, "2", true, err, sizeof(err)));
	g = image_of(on, true, sh);
	double mean_rel = 0.0;
	for (size_t i = 0; i < n; i++)
		mean_rel += fabs((double)g[i] - cpu_on[i]) / (double)n;
	printf("maps following the light, unmoved: mean difference %.3g, largest relative %.3g\n",
	       mean_rel, max_rel(g, cpu_on, n, NULL));
	CHECK(mean_rel <= 1e-3);
	free(g);
	char moved[512], mtext[4096], mtext2[4096];
	replace_all(shadow_scene, "Translate 0 -4 -1.7", "Translate -0.6 -4 -1.2", mtext,
		    sizeof(mtext));
	replace_all(mtext, "\"from\" [0 4 1.7] \"to\" [0 0 1.7]",
		    "\"from\" [0.6 4 1.2] \"to\" [0.6 0 1.2]", mtext2, sizeof(mtext2));
	replace_all(mtext2, "key.", "mv.", mtext, sizeof(mtext));
	CHECK(bake("moved", mtext, "SHADOWNAME", "\"shadowname\" \"mv.shd\" \"samples\" 16",
		   "", moved, sizeof(moved)));
	const float mfrom[3] = { 0.6f, 4, 1.2f }, mto[3] = { 0.6f, 0, 1.2f };
	CHECK(gpu_shot_set(sh, "2", "from", mfrom, 3, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "2", "to", mto, 3, err, sizeof(err)));
	g = image_of(on, true, sh);
	float *cpu_moved = image_of(moved, false, NULL);
	mean_rel = 0.0;
	for (size_t i = 0; i < n; i++)
		mean_rel += fabs((double)g[i] - cpu_moved[i]) / (double)n;
	printf("maps following the light, moved: mean difference %.3g, largest relative %.3g\n",
	       mean_rel, max_rel(g, cpu_moved, n, NULL));
	CHECK(mean_rel <= 1e-3);
	/* and the shadow did move */
	CHECK(max_rel(cpu_moved, cpu_on, n, NULL) > 0.1);
	free(g);
	free(cpu_moved);
	free(want);
	free(cpu_on);
	free(cpu_off);
	gpu_shot_close(sh);
}

/*
 * A deep shadow map on the GPU (render/deepshadow.h): the shadowed key light
 * with its pass written as a deep map (4 x 4 samples a texel) and a
 * semi-transparent sphere, against the CPU resolver within REL_TOL; with
 * its maps following a moved light, the deep map is rendered again from the
 * shadow geometry, which is the shot whose deep pass moved with the light
 * (within the mean difference the depth maps are held to), the preview
 * saying nothing of a kept map; with follow off the moved light keeps the
 * baked map, which is not that shot.
 */
static void deep_scene(const char *prefix, const char *scene, char *out, size_t len)
{
	char a[4096], b[4096];
	replace_all(scene, "\"key.z\" \"zfile\" \"z\"", "\"key.z\" \"deepshad\" \"deepopacity\"",
		    a, sizeof(a));
	replace_all(a, "PixelSamples 1 1", "PixelSamples 4 4", b, sizeof(b));
	/* the sphere half-transparent in the pass and in the view (what the
	   shadow geometry records) */
	replace_all(b, "AttributeBegin Translate 0 0.5 1 Sphere", "AttributeBegin Opacity "
		    "[0.4 0.4 0.4] Translate 0 0.5 1 Sphere", a, sizeof(a));
	replace_all(a, "AttributeBegin Surface \"matte\" Translate", "AttributeBegin Opacity "
		    "[0.4 0.4 0.4] Surface \"matte\" Translate", b, sizeof(b));
	replace_all(b, "key.", prefix, out, len);
}

static void test_deep_follow(void)
{
	char text[4096], mtext[4096], mtext2[4096], deep[512], moved[512], err[256];
	deep_scene("dk.", shadow_scene, text, sizeof(text));
	CHECK(strstr(text, "deepshad") && strstr(text, "Opacity [0.4 0.4 0.4] Surface"));
	CHECK(bake("deep", text, "SHADOWNAME", "\"shadowname\" \"dk.shd\" \"samples\" 16", "",
		   deep, sizeof(deep)));
	replace_all(shadow_scene, "Translate 0 -4 -1.7", "Translate -0.6 -4 -1.2", mtext,
		    sizeof(mtext));
	replace_all(mtext, "\"from\" [0 4 1.7] \"to\" [0 0 1.7]",
		    "\"from\" [0.6 4 1.2] \"to\" [0.6 0 1.2]", mtext2, sizeof(mtext2));
	deep_scene("dm.", mtext2, mtext, sizeof(mtext));
	CHECK(bake("deepmoved", mtext, "SHADOWNAME", "\"shadowname\" \"dm.shd\" \"samples\" 16",
		   "", moved, sizeof(moved)));
	char *buf = NULL;
	size_t len = 0;
	FILE *mem = open_memstream(&buf, &len);
	struct gpu_shot_opts o = { .texture_path = workdir, .diag = mem };
	struct gpu_shot *sh = gpu_shot_open(ctx, deep, &o);
	CHECK(sh != NULL);
	if (!sh) {
		fclose(mem);
		free(buf);
		return;
	}
	size_t n = (size_t)W * H * 4;
	float *cpu = image_of(deep, false, NULL), *g = image_of(deep, true, sh);
	double r = max_rel(g, cpu, n, NULL);
	printf("deep shadow map: GPU against the CPU resolver, largest relative %.3g "
	       "(tolerance %g)\n", r, REL_TOL);
	CHECK(r <= REL_TOL);
	free(g);
	const float mfrom[3] = { 0.6f, 4, 1.2f }, mto[3] = { 0.6f, 0, 1.2f };
	CHECK(gpu_shot_set(sh, "2", "from", mfrom, 3, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "2", "to", mto, 3, err, sizeof(err)));
	float *kept = image_of(deep, true, sh);
	CHECK(gpu_shot_shadow_follow(sh, "2", true, err, sizeof(err)));
	g = image_of(deep, true, sh);
	float *want = image_of(moved, false, NULL);
	double mean = 0.0, mean_kept = 0.0;
	for (size_t i = 0; i < n; i++) {
		mean += fabs((double)g[i] - want[i]) / (double)n;
		mean_kept += fabs((double)kept[i] - want[i]) / (double)n;
	}
	struct gpu_deep_stats st;
	uint32_t nrendered = gpu_shot_deep_stats(sh, &st);
	printf("deep maps following the light, moved: against the shot whose deep pass moved, "
	       "mean difference %.3g, largest relative %.3g (the baked map kept: mean %.3g); "
	       "%u rendered, the last of %llu hits, %llu nodes, %zu bytes\n", mean,
	       max_rel(g, want, n, NULL), mean_kept, nrendered, (unsigned long long)st.hits,
	       (unsigned long long)st.nodes, st.bytes);
	CHECK(mean <= 1e-3);
	CHECK(nrendered >= 1 && st.nodes > 0);
	/* the shadow did move, and following is what moved it: the baked map
	   kept is past the tolerance */
	CHECK(max_rel(want, cpu, n, NULL) > 0.1);
	CHECK(mean_kept > 1e-3 && mean_kept > 2 * mean);
	free(g);
	free(want);
	fflush(mem);
	CHECK(!buf || !strstr(buf, "is not rendered again"));
	if (buf && strstr(buf, "is not rendered again"))
		fprintf(stderr, "the deep shot said: %s\n", buf);
	gpu_shot_close(sh);
	fclose(mem);
	free(buf);
	free(kept);
	free(cpu);
}

/* Editable surface parameters, and adding and removing lights, against
 * the CPU resolver of shots baked with the RIB edited the same way. */
static void test_surface_and_lights(void)
{
	char base[512], kd[512], more[512], err[256];
	const char *flags = "--dynamic-surface Kd";
	CHECK(bake("sbase", shadow_scene, "SHADOWNAME", "", flags, base, sizeof(base)));
	/* the scene without shadows, then edited */
	char text[4096];
	const char *mark = strstr(shadow_scene, "SHADOWNAME");
	snprintf(text, sizeof(text), "%.*s%s", (int)(mark - shadow_scene), shadow_scene,
		 mark + strlen("SHADOWNAME"));
	CHECK(bake("skd", text, "\"Kd\" 0.7", "\"Kd\" 0.25", flags, kd, sizeof(kd)));
	CHECK(bake("smore", shadow_scene, "SHADOWNAME\n",
		   "\n  LightSource \"pointlight\" 7 \"intensity\" 3 \"from\" [1 1 0]"
		   " \"lightcolor\" [1 0.5 0.2]\n", flags, more, sizeof(more)));
	char shaders[1024];
	const char *src = getenv("RELIGHT_SOURCE_DIR");
	snprintf(shaders, sizeof(shaders), "%s/shaders", src ? src : ".");
	struct gpu_shot_opts o = { .texture_path = workdir, .shader_path = shaders };
	struct gpu_shot *sh = gpu_shot_open(ctx, base, &o);
	CHECK(sh != NULL);
	if (!sh)
		return;
	size_t n = (size_t)W * H * 4;
	float v = 0.25f;
	CHECK(!gpu_shot_set_surface(sh, "plastic", "Ks", &v, 1, err, sizeof(err)));
	CHECK(strstr(err, "--dynamic-surface") != NULL);
	CHECK(!gpu_shot_set_surface(sh, "nosuch", "Kd", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_set_surface(sh, "plastic", "Kd", &v, 1, err, sizeof(err)));
	float *g = image_of(base, true, sh), *c = image_of(kd, false, NULL);
	CHECK(max_rel(g, c, n, NULL) <= REL_TOL);
	free(g);
	free(c);
	v = 0.7f;
	CHECK(gpu_shot_set_surface(sh, "plastic", "Kd", &v, 1, err, sizeof(err)));
	/* the light cache full when the light comes: adding it keeps what is cached */
	struct gpu_shot_stats st;
	CHECK(gpu_shot_render(sh, GPU_SHOT_FINAL, &st));
	/* a point light: a shader the shot does not have, compiled when added */
	const float xf[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	int k = gpu_shot_add_light(sh, "7", "pointlight", xf, err, sizeof(err));
	if (k < 0)
		fprintf(stderr, "add light: %s\n", err);
	CHECK(k >= 0);
	CHECK(gpu_shot_add_light(sh, "7", "pointlight", xf, err, sizeof(err)) < 0);
	CHECK(gpu_shot_add_light(sh, "8", "plastic", xf, err, sizeof(err)) < 0);
	float from[3] = { 1, 1, 0 }, col[3] = { 1, 0.5f, 0.2f }, in = 3;
	CHECK(gpu_shot_set(sh, "7", "from", from, 3, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "7", "lightcolor", col, 3, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "7", "intensity", &in, 1, err, sizeof(err)));
	g = image_of(base, true, sh);
	c = image_of(more, false, NULL);
	size_t at = 0;
	double r = max_rel(g, c, n, &at);
	if (!(r <= REL_TOL))
		fprintf(stderr, "added light: %g at %zu\n", r, at);
	CHECK(r <= REL_TOL);
	free(g);
	free(c);
	/* removing it gives the shot back */
	CHECK(gpu_shot_remove_light(sh, "7", err, sizeof(err)));
	CHECK(gpu_shot_find_light(sh, "7") < 0);
	CHECK(!gpu_shot_set(sh, "7", "intensity", &in, 1, err, sizeof(err)));
	g = image_of(base, true, sh);
	c = image_of(base, false, NULL);
	CHECK(max_rel(g, c, n, NULL) <= REL_TOL);
	free(g);
	free(c);
	gpu_shot_close(sh);
}

/*
 * Lights of one shader enter the light cache in batches (runtime.c BATCH):
 * eleven point lights from 1e-3 to 1e3, one of them kept off the sphere by
 * Illuminate (so it goes alone), against the CPU; then one batched light
 * edited at random and restored, which takes its own contribution out of a
 * batch's.
 */
static const char batch_scene[] =
	"Format 64 48 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 45\n"
	"Display \"batch.exr\" \"file\" \"rgba\"\n"
	"Translate 0 -0.6 4\nRotate -15 1 0 0\nWorldBegin\n"
	"LIGHTS"
	"  LightSource \"distantlight\" 20 \"intensity\" 0.3 \"from\" [0 1 0] \"to\" [0.2 0 0.3]\n"
	"  Surface \"plastic\" \"roughness\" 0.2\n"
	"  Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
	"  AttributeBegin Illuminate 3 0 Surface \"matte\" Translate 0 0.5 1"
	" Sphere 0.5 -0.5 0.5 360 AttributeEnd\n"
	"WorldEnd\n";

static void test_batches(void)
{
	char lights[4096], shot[512], err[256];
	size_t at = 0;
	for (int k = 1; k <= 11; k++)
		at += (size_t)snprintf(lights + at, sizeof(lights) - at,
				       "  LightSource \"pointlight\" %d \"intensity\" %g \"from\" [%g %g %g]"
				       " \"lightcolor\" [1 %g 0.5]\n", k, pow(10.0, (k - 6) * 0.6),
				       -2.0 + 0.4 * k, 0.3 + 0.2 * (k % 3), 0.5 + 0.3 * (k % 4),
				       0.2 + 0.07 * k);
	CHECK(bake("batch", batch_scene, "LIGHTS", lights, "", shot, sizeof(shot)));
	struct gpu_shot_opts o = { .texture_path = workdir };
	struct gpu_shot *sh = gpu_shot_open(ctx, shot, &o);
	CHECK(sh != NULL);
	if (!sh)
		return;
	size_t n = (size_t)W * H * 4;
	struct gpu_shot_stats st;
	CHECK(gpu_shot_render(sh, GPU_SHOT_FINAL, &st));
	/* ten point lights in two batches (8 and 2); light 3 and the distant one alone */
	CHECK(st.batched == 10 * gpu_shot_samples(sh));
	CHECK(st.shaded == 13 * gpu_shot_samples(sh));
	float *g0 = image_of(shot, true, sh), *c = image_of(shot, false, NULL);
	size_t worst = 0;
	double r = max_rel(g0, c, n, &worst);
	if (!(r <= REL_TOL))
		fprintf(stderr, "batches against the CPU: %g at %zu\n", r, worst / 4);
	CHECK(r <= REL_TOL);
	CHECK(all_finite(g0, n));
	free(c);
	/* light 9 (intensity 10) edited 200 times, then one edit checked against the CPU */
	for (int e = 0; e < 200; e++) {
		float v = (float)pow(10.0, 8.0 * uniform() - 4.0);
		float from[3] = { (float)(4 * uniform() - 2), (float)(0.2 + uniform()), 0.5f };
		CHECK(gpu_shot_set(sh, "9", "intensity", &v, 1, err, sizeof(err)));
		CHECK(gpu_shot_set(sh, "9", "from", from, 3, err, sizeof(err)));
		CHECK(gpu_shot_render(sh, e % 4, NULL));
	}
	float v = 40.0f, from[3] = { 0.5f, 1.2f, 0.5f };
	CHECK(gpu_shot_set(sh, "9", "intensity", &v, 1, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "9", "from", from, 3, err, sizeof(err)));
	float *g = image_of(shot, true, sh);
	struct resolve_edit ed[2] = { { .light = "9", .param = "intensity", .values = { 40.0f },
					.nvalues = 1 },
				      { .light = "9", .param = "from", .values = { 0.5f, 1.2f, 0.5f },
					.nvalues = 3 } };
	struct resolve_opts ro = { .diag = stderr, .level = 3, .texture_path = workdir,
				   .edits = ed, .nedits = 2 };
	struct resolve_result rr;
	CHECK(resolve_cpu(shot, &ro, &rr));
	r = rr.rgba && rr.width == W && rr.height == H ? max_rel(g, rr.rgba, n, &worst) : 1.0;
	if (!(r <= REL_TOL))
		fprintf(stderr, "batched light edited, against the CPU: %g at %zu\n", r, worst / 4);
	CHECK(r <= REL_TOL);
	free(rr.rgba);
	free(g);
	/* restored: the image before the edits */
	float one = (float)pow(10.0, 3 * 0.6);
	float back[3] = { -2.0f + 0.4f * 9, 0.3f + 0.2f * (9 % 3), 0.5f + 0.3f * (9 % 4) };
	CHECK(gpu_shot_set(sh, "9", "intensity", &one, 1, err, sizeof(err)));
	CHECK(gpu_shot_set(sh, "9", "from", back, 3, err, sizeof(err)));
	g = image_of(shot, true, sh);
	r = max_rel(g, g0, n, &worst);
	if (!(r <= REL_TOL))
		fprintf(stderr, "batched light restored: %g at %zu\n", r, worst / 4);
	CHECK(r <= REL_TOL);
	free(g);
	free(g0);
	gpu_shot_close(sh);
}

/* A surface that squares its lighting is not linear in its lights: loading says so. */
static void test_nonlinear(void)
{
	char path[512], shot_nl[512];
	snprintf(path, sizeof(path), "%s/nonlin.sl", workdir);
	FILE *f = fopen(path, "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("surface nonlin() { normal Nf = faceforward(normalize(N), I);\n"
	      "  color d = diffuse(Nf); Ci = d * d; Oi = Os; }\n", f);
	fclose(f);
	/* a second light on the ground, from above: two lights on the same samples */
	char text[4096];
	const char *wb = strstr(scene, "WorldBegin\n") + strlen("WorldBegin\n");
	snprintf(text, sizeof(text), "Option \"searchpath\" \"shader\" [\".:&\"]\n%.*s"
		 "  LightSource \"distantlight\" 9 \"intensity\" 0.7 \"from\" [0 1 0] \"to\" [0.2 0 0.1]\n"
		 "%s", (int)(wb - scene), scene, wb);
	CHECK(bake("nonlin", text, "Surface \"plastic\" \"roughness\" 1e-6 \"Ks\" 0.8",
		   "Surface \"nonlin\"", "", shot_nl, sizeof(shot_nl)));
	char *buf = NULL;
	size_t len = 0;
	FILE *mem = open_memstream(&buf, &len);
	struct gpu_shot_opts o = { .diag = mem };
	struct gpu_shot *sh = gpu_shot_open(ctx, shot_nl, &o);
	fclose(mem);
	CHECK(sh != NULL);
	CHECK(buf && strstr(buf, "surface 'nonlin' is not linear in its lights"));
	if (!buf || !strstr(buf, "not linear"))
		fprintf(stderr, "loading %s said: %s\n", shot_nl, buf ? buf : "");
	free(buf);
	/* the library's surfaces are: no such warning for them */
	buf = NULL;
	mem = open_memstream(&buf, &len);
	o.diag = mem;
	struct gpu_shot *lin = gpu_shot_open(ctx, shot_path, &o);
	fclose(mem);
	CHECK(lin != NULL);
	CHECK(!buf || !strstr(buf, "not linear"));
	free(buf);
	gpu_shot_close(sh);
	gpu_shot_close(lin);

	/* a light whose texture() names a file that is not there: the fill, and a warning */
	char shot_tx[512];
	CHECK(bake("slide", scene, "WorldBegin\n", "WorldBegin\n  LightSource \"uberlight\" 5 "
		   "\"slidename\" \"slide.tx\" \"intensity\" 0.5\n", "", shot_tx, sizeof(shot_tx)));
	buf = NULL;
	mem = open_memstream(&buf, &len);
	o.diag = mem;
	sh = gpu_shot_open(ctx, shot_tx, &o);
	fclose(mem);
	CHECK(sh != NULL);
	CHECK(buf && strstr(buf, "light '5': slide.tx: not found"));
	free(buf);
	gpu_shot_close(sh);
}

/* A slide picture of @w x @h made into texture @name in the work folder. */
static bool make_slide(const char *name, uint32_t w, uint32_t h, float tint)
{
	static const char *const names[] = { "R", "G", "B" };
	struct reyes_image im;
	if (!reyes_image_init(&im, w, h, 3, names))
		return false;
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++)
			for (uint32_t c = 0; c < 3; c++)
				im.data[((size_t)y * w + x) * 3 + c] =
					((x * 4 / w + y * 4 / h + c) % 2 ? 0.9f : 0.2f) * (c ? 1 : tint);
	char pic[512], tex[512];
	snprintf(pic, sizeof(pic), "%s/%s.exr", workdir, name);
	snprintf(tex, sizeof(tex), "%s/%s", workdir, name);
	bool ok = reyes_image_write_exr(pic, &im, false, stderr) &&
		  reyes_make_texture(pic, tex, "black", "black", "box", 1, 1, stderr);
	reyes_image_finish(&im);
	return ok;
}

/*
 * A slide projector's maps in GPU memory: the shot holds the map its light
 * names, counted in its bytes; swapping the slide compiles nothing, binds
 * the new map and frees the old one once no band of the light cache holds
 * light shaded with it; no slide frees it, the slide back loads it again.
 * Each state matches the CPU resolver with the same edit.
 */
static void test_texture_maps(void)
{
	CHECK(make_slide("slide_t.tx", 32, 32, 1.0f) && make_slide("slide_u.tx", 48, 16, 0.3f));
	char shot[512];
	CHECK(bake("slides", scene, "WorldBegin\n", "WorldBegin\n  LightSource \"projector\" 5 "
		   "\"intensity\" 9 \"from\" [0 3 0.5] \"to\" [0 0 0.8] \"fov\" 1.4 "
		   "\"slidename\" \"slide_t.tx\"\n", "", shot, sizeof(shot)));
	struct gpu_shot_opts o = { .texture_path = workdir };
	struct gpu_shot *sh = gpu_shot_open(ctx, shot, &o);
	CHECK(sh != NULL);
	if (!sh)
		return;
	size_t n = (size_t)W * H * 4, worst, tb = 0;
	/* loaded with the shot: one map, its levels' texels and the level table */
	CHECK(gpu_shot_texmaps(sh, &tb) == 1);
	size_t levels = (32 * 32 + 16 * 16 + 8 * 8 + 4 * 4 + 2 * 2 + 1) * 3 * sizeof(float);
	CHECK(tb > levels && tb < levels + 1024);
	size_t with = gpu_shot_bytes(sh);
	unsigned hits0, built0, hits1, built1;
	gpu_program_stats(ctx, &hits0, &built0);

	static const char *const states[] = { "slide_u.tx", "", "slide_t.tx" };
	for (int k = -1; k < 3; k++) {
		char err[256];
		if (k >= 0)
			CHECK(gpu_shot_set_string(sh, "5", "slidename", states[k], err, sizeof(err)));
		float *g = image_of(shot, true, sh);
		struct resolve_edit e = { .light = "5", .param = "slidename",
					  .text = k >= 0 ? states[k] : "slide_t.tx" };
		struct resolve_opts ro = { .diag = stderr, .level = 3, .texture_path = workdir,
					   .edits = &e, .nedits = 1 };
		struct resolve_result rr;
		CHECK(resolve_cpu(shot, &ro, &rr));
		double r = rr.rgba ? max_rel(g, rr.rgba, n, &worst) : 1.0;
		if (!(r <= REL_TOL))
			fprintf(stderr, "slide '%s': GPU against the CPU %g at %zu\n", e.text, r,
				worst / 4);
		CHECK(r <= REL_TOL);
		free(rr.rgba);
		free(g);
		size_t b;
		uint32_t maps = gpu_shot_texmaps(sh, &b);
		if (k == 1) {
			/* no slide: no map, and the shot is smaller by the map's bytes */
			CHECK(maps == 0 && b == 0 && gpu_shot_bytes(sh) == with - tb);
		} else {
			CHECK(maps == 1 && gpu_shot_bytes(sh) == with - tb + b);
		}
	}
	CHECK(gpu_shot_bytes(sh) == with);
	gpu_program_stats(ctx, &hits1, &built1);
	CHECK(hits1 == hits0 && built1 == built0);

	/* values of the wrong kind change nothing */
	char err[256] = "";
	float one = 1;
	CHECK(!gpu_shot_set_string(sh, "5", "intensity", "slide_u.tx", err, sizeof(err)));
	CHECK(strstr(err, "parameter 'intensity' is a float, not a string") != NULL);
	CHECK(!gpu_shot_set(sh, "5", "slidename", &one, 1, err, sizeof(err)));
	CHECK(strstr(err, "is a string") != NULL);
	CHECK(!gpu_shot_set_string(sh, "5", "nothing", "x", err, sizeof(err)));
	char *cur = gpu_shot_get_string(sh, "5", "slidename");
	CHECK(cur && !strcmp(cur, "slide_t.tx"));
	free(cur);
	gpu_shot_close(sh);
}

/* Metadata a shot file should never have, written with valid checksums:
 * loading refuses it or copes, and never crashes (run under ASan in CI). */
static void test_bad_metadata(void)
{
	static const char *const edits[][2] = {
		{ "tiling", NULL },
		{ "tiling.tiles.0.surfaces.0.first_row", "-5" },
		{ "tiling.tiles.0.surfaces.0.first_row", "1e12" },
		{ "tiling.tiles.0.surfaces.0.levels", "[5, 3, 1, 0]" },
		{ "tiling.tiles.0.surfaces.0.levels", "[1e9, 1e9, 1e9, 1e9]" },
		{ "tiling.tiles.0.surfaces.0.levels", "\"x\"" },
		{ "tiling.tiles.0.surfaces", "[]" },
		{ "surfaces.0.first_id", "1e12" },
		{ "surfaces.0.first_id", "-1" },
		{ "surfaces.0.table", "\"nope\"" },
		{ "surfaces.0.source_hash", "\"0\"" },
		{ "surfaces.0.param_sets", "\"x\"" },
		{ "surfaces.0.dynamic_params", "[\"nope\"]" },
		{ "lights.0.shader_to_world", "[1, 2]" },
		{ "lights.0.source_hash", "\"0\"" },
		{ "lights.0.params", "[{\"name\": 3}]" },
		{ "lights.0.name", "7" },
		{ "lightsets", "[[99], [-1], \"x\"]" },
		{ "width", "0" },
		{ "width", "1e9" },
		{ "world_to_camera", "[0,0,0,0, 0,0,0,0, 0,0,0,0, 0,0,0,0]" },
		{ "surfaces", "{}" },
		{ "lights", "3" },
	};
	char err[512], out[600];
	struct shot_file *f = shot_read(shot_path, err, sizeof(err));
	CHECK(f != NULL);
	if (!f)
		return;
	char *orig = f->metadata;
	snprintf(out, sizeof(out), "%s/bad.shot.exr", workdir);
	for (size_t e = 0; e < sizeof(edits) / sizeof(edits[0]); e++) {
		cJSON *m = cJSON_Parse(orig);
		/* walk the dotted path; the last step is set or removed */
		char path[256];
		snprintf(path, sizeof(path), "%s", edits[e][0]);
		cJSON *at = m;
		char *save = NULL, *key = strtok_r(path, ".", &save), *next;
		while (at && key && (next = strtok_r(NULL, ".", &save))) {
			at = cJSON_IsArray(at) ? cJSON_GetArrayItem(at, atoi(key))
					       : cJSON_GetObjectItemCaseSensitive(at, key);
			key = next;
		}
		CHECK(at != NULL);
		if (!at) {
			cJSON_Delete(m);
			continue;
		}
		cJSON *v = edits[e][1] ? cJSON_Parse(edits[e][1]) : NULL;
		bool done = true;
		if (cJSON_IsArray(at))
			done = cJSON_ReplaceItemInArray(at, atoi(key), v);
		else if (v && cJSON_GetObjectItemCaseSensitive(at, key))
			done = cJSON_ReplaceItemInObjectCaseSensitive(at, key, v);
		else if (v)
			done = cJSON_AddItemToObject(at, key, v);
		else
			cJSON_DeleteItemFromObjectCaseSensitive(at, key);
		CHECK(done);
		if (!done)
			cJSON_Delete(v);
		f->metadata = cJSON_PrintUnformatted(m);
		cJSON_Delete(m);
		CHECK(shot_write(out, f, NULL, err, sizeof(err)));
		free(f->metadata);
		f->metadata = orig;
		FILE *quiet = fopen("/dev/null", "w");
		struct gpu_shot_opts o = { .diag = quiet };
		struct gpu_shot *sh = gpu_shot_open(ctx, out, &o);
		if (sh) {
			/* it loaded: it must render finite pixels */
			float *img = calloc((size_t)gpu_shot_width(sh) * gpu_shot_height(sh) * 4 + 4,
					    sizeof(float));
			if (gpu_shot_render(sh, 3, NULL) && gpu_shot_read_rgba(sh, 3, img))
				CHECK(all_finite(img, (size_t)gpu_shot_width(sh) * gpu_shot_height(sh) * 4));
			free(img);
			gpu_shot_close(sh);
		}
		if (quiet)
			fclose(quiet);
	}
	shot_free(f);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: test_runtime PATH/TO/relight\n");
		return 2;
	}
	char dir[] = "/tmp/relight-test-runtime-XXXXXX";
	char relight[1024], cwd[512];
	if (argv[1][0] == '/')
		snprintf(relight, sizeof(relight), "%s", argv[1]);
	else
		snprintf(relight, sizeof(relight), "%s/%s", getcwd(cwd, sizeof(cwd)) ? cwd : ".",
			 argv[1]);
	if (!mkdtemp(dir))
		return 1;
	snprintf(workdir, sizeof(workdir), "%s", dir);
	snprintf(relight_cmd, sizeof(relight_cmd), "%s", relight);
	char cmd[2048];
	snprintf(cmd, sizeof(cmd), "cd %s && cat > hard.rib && %s bake -q -o hard.shot.exr hard.rib",
		 dir, relight);
	FILE *p = popen(cmd, "w");
	bool baked = p && fputs(scene, p) >= 0;
	baked = p && pclose(p) == 0 && baked;
	snprintf(shot_path, sizeof(shot_path), "%s/hard.shot.exr", dir);
	char err[512];
	ctx = baked ? gpu_create(err, sizeof(err)) : NULL;
	int rc;
	if (!baked) {
		fprintf(stderr, "test_runtime: baking the scene failed\n");
		rc = 1;
	} else if (!ctx) {
		printf("SKIP: no OpenGL 4.3 context: %s\n", err);
		rc = 77;
	} else {
		shot = gpu_shot_open(ctx, shot_path, NULL);
		CHECK(shot != NULL);
		if (shot) {
			W = gpu_shot_width(shot);
			H = gpu_shot_height(shot);
			RUN(test_matches_cpu);
			RUN(test_outputs);
			RUN(test_refused);
			RUN(test_mute_solo_link);
			RUN(test_graph_work);
			RUN(test_bad_metadata);
			if (!getenv("RELIGHT_TEST_QUICK"))
				RUN(test_stability);
			gpu_shot_close(shot);
			shot = NULL;
			RUN(test_shadow_look);
			RUN(test_deep_follow);
			RUN(test_nonlinear);
			RUN(test_texture_maps);
			RUN(test_surface_and_lights);
			RUN(test_batches);
		}
		rc = test_finish();
	}
	gpu_destroy(ctx);
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "test_runtime: cannot remove %s\n", dir);
	return rc;
}

/*
 * The numerical stability suite (stability.h). Each case writes its own
 * small RIB scene into the work folder, renders or bakes it in this process
 * and measures the result against a closed form or against the CPU
 * resolver, the reference the GPU runtime is held to. A check carries its
 * measurement, the limit it is held to (each limit is a #define below with
 * the reason for its value) and the verdict.
 *
 * A case declares all its checks before it starts, so a case that stops
 * early (a scene that does not bake, a shot that does not load) still
 * reports every check, failed with the reason; without a GPU context the
 * GPU checks are skipped with a note and the others still run.
 */
#include "stability.h"
#include "benchutil.h"

#include "bake.h"
#include "bake/resolve.h"
#include "gpu.h"
#include "imgerr.h"
#include "reyes.h"
#include "ri.h"
#include "runtime.h"
#include "shotfile.h"
#include "strbuf.h"
#include "texture.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* ---- limits ---- */

/*
 * The GPU against the CPU resolver, relative to max(|gpu|, |cpu|, floor):
 * the project's tolerance for two float implementations of the same shading
 * (tests/cli/gpu.sh, relight diff), whose operations are ordered differently.
 */
#define STAB_GPU_CPU_REL 1e-4
/* Values under this (times the light's scale) are compared absolutely. */
#define STAB_REL_FLOOR 1e-3

/*
 * drift: the light cache sums in float64, so taking a float32 contribution
 * out again gives back the sum it went into up to float64 rounding (1e-16
 * relative per edit): after 100,000 edits the restored image must still be
 * within the GPU/CPU tolerance of the original; in practice it is exact.
 */
#define STAB_DRIFT_REL STAB_GPU_CPU_REL
#define STAB_DRIFT_EDITS_FULL 100000
#define STAB_DRIFT_EDITS_QUICK 10000

/*
 * half: a value written as half is the float rounded to the nearest half,
 * at most half a unit in the last place away: 2^-11 relative for normal
 * halves, 2^-25 absolute for subnormal ones. Beyond 65504 the output is
 * clamped to 65504, never infinite. Measured as error / that bound: <= 1.
 */
#define STAB_HALF_ULP_RATIO 1.0
#define STAB_HALF_MAX 65504.0

/*
 * transparency: the renderer composites front to back in float (T *= 1 - a
 * once per layer, C += T c a), so the n-th layer's transmittance carries up
 * to n float roundings, 2^-24 each: 64 layers, 3.8e-6 relative; 1e-5 leaves
 * room for the filter's normalisation. The preview rounds each stored
 * weight to float once and sums a pixel's entries in float: through 64
 * layers a pixel has up to about 600 entries, and a float sum of n
 * positive terms is within (n - 1) 2^-24 relative, 3.6e-5 (the roundings
 * mostly cancel: 2e-6 is typical): 4e-5.
 */
#define STAB_TRANSP_RENDER_REL 1e-5
#define STAB_TRANSP_GPU_REL 4e-5
/*
 * The renderer stops compositing a subpixel sample once its opacity
 * reaches this in every channel (RenderMan's othreshold default; reyes.c),
 * so the closed form sums the layers up to that one: the check follows the
 * renderer's float arithmetic to find it.
 */
#define STAB_OPACITY_THRESHOLD 0.996f
#define STAB_TRANSP_LAYERS_FULL 64
#define STAB_TRANSP_LAYERS_QUICK 16
/* Alpha is a filter-normalised mean of opacities in [0, 1]: above 1 by at
 * most the last place of a float at 1. */
#define STAB_ALPHA_OVER 0x1p-23

/*
 * weights: the renderer normalises a pixel's filter weights in double and
 * rounds the pixel to float once: 6e-8 relative; 1e-6 leaves room for the
 * float sample colours. Through the indirect framebuffer each weight is
 * rounded to float when stored and a pixel's entries (about 9, a few tens
 * at most) are summed in float on the GPU: 40 entries, (40 - 1) 2^-24 =
 * 2.3e-6 at worst; limit 1e-5.
 */
#define STAB_WEIGHTS_RENDER_REL 1e-6
#define STAB_WEIGHTS_GPU_REL 1e-5
#define STAB_WEIGHTS_SIZE_FULL 128
#define STAB_WEIGHTS_SIZE_QUICK 32

/*
 * half (bake): a lossy channel (colour, normal, vector) is stored as half
 * when it fits, each value at most 2^-11 relative off, and the bake records
 * the largest such error, e. A shaded value is a product of such channels,
 * each adding up to e of relative error, but two things amplify it. The
 * specular lobe raises a cosine to 1/roughness (10 for plastic's default
 * 0.1), and that cosine carries the rounding of the normal and of the view
 * vector: 10 x 2e, with the colour's e besides, 21e; the limit is the
 * recorded bound times 32, half as much again. Near the terminator N.L is
 * small and its error (e, absolute) large relative to it: values under 1 %
 * of white are compared absolutely. On screen: the 8-bit error, mean and
 * worst, in percent of the range (0.1 % is a quarter of a code value).
 */
#define STAB_HALF_BOUND_FACTOR 32.0
#define STAB_HALF_FLOOR 1e-2
#define STAB_HALF_MEAN_PCT 0.1
#define STAB_HALF_MAX_PCT 1.0

/* ---- checks ---- */

/* Room for a reason a case stopped: a path and a message. */
#define WHY_LEN 1024

static const char *const groups[] = { "drift", "hdr", "degenerate", "transparency", "weights",
				      "half" };
#define NGROUPS (sizeof(groups) / sizeof(groups[0]))

struct suite {
	const struct stab_opts *o;
	FILE *log;
	struct stab_check *out;
	bool *pending;       /* out[k] declared and not measured yet */
	int cap, n, dropped;
	const char *shader_path;  /* the bake's and the renderer's search path, NULL: default */
};

static void say(struct suite *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void say(struct suite *s, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fputs("stability: ", s->log);
	vfprintf(s->log, fmt, ap);
	fputc('\n', s->log);
	va_end(ap);
	fflush(s->log);
}

static double now_s(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* Declare check @name of @group held to @limit: its index, or -1 when the
 * caller's array is full (its measurements are then dropped). */
static int check(struct suite *s, const char *group, const char *name, double limit)
{
	if (s->n >= s->cap) {
		s->dropped++;
		return -1;
	}
	struct stab_check *c = &s->out[s->n];
	memset(c, 0, sizeof(*c));
	snprintf(c->group, sizeof(c->group), "%s", group);
	snprintf(c->name, sizeof(c->name), "%s", name);
	c->value = NAN;
	c->limit = limit;
	c->verdict = STAB_FAIL;
	s->pending[s->n] = true;
	return s->n++;
}

static void vnote(struct stab_check *c, const char *fmt, va_list ap)
{
	if (fmt)
		vsnprintf(c->note, sizeof(c->note), fmt, ap);
	else
		c->note[0] = '\0';
}

/* Check @k measured @value; the verdict follows from its limit. @fmt (may
 * be NULL) is a note. */
static void measured(struct suite *s, int k, double value, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

static void measured(struct suite *s, int k, double value, const char *fmt, ...)
{
	if (k < 0)
		return;
	struct stab_check *c = &s->out[k];
	c->value = value;
	if (isnan(c->limit))
		c->verdict = STAB_PASS;
	else
		c->verdict = value <= c->limit ? STAB_PASS : STAB_FAIL; /* NaN fails */
	va_list ap;
	va_start(ap, fmt);
	vnote(c, fmt, ap);
	va_end(ap);
	s->pending[k] = false;
}

static void skipped(struct suite *s, int k, const char *why)
{
	if (k < 0)
		return;
	s->out[k].verdict = STAB_SKIP;
	s->out[k].value = NAN;
	snprintf(s->out[k].note, sizeof(s->out[k].note), "%s", why);
	s->pending[k] = false;
}

/* Every check from @first on that is still unmeasured fails with the reason. */
static void fail_pending(struct suite *s, int first, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void fail_pending(struct suite *s, int first, const char *fmt, ...)
{
	char why[192];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(why, sizeof(why), fmt, ap);
	va_end(ap);
	for (int k = first < 0 ? 0 : first; k < s->n; k++) {
		if (!s->pending[k])
			continue;
		s->out[k].verdict = STAB_FAIL;
		s->out[k].value = NAN;
		snprintf(s->out[k].note, sizeof(s->out[k].note), "%s", why);
		s->pending[k] = false;
	}
}

/* ---- images ---- */

/*
 * The largest |a - b| / max(|a|, |b|, @floor) over the first @nch channels
 * of two RGBA images of @npix pixels; infinite where either value is not
 * finite. *@at (may be NULL) gets the pixel.
 */
static double max_rel(const float *a, const float *b, size_t npix, int nch, double floor,
		      size_t *at)
{
	double m = 0.0;
	for (size_t p = 0; p < npix; p++) {
		for (int c = 0; c < nch; c++) {
			double va = a[p * 4 + (size_t)c], vb = b[p * 4 + (size_t)c];
			double d = fabs(va - vb) / fmax(fmax(fabs(va), fabs(vb)), floor);
			if (!isfinite(d))
				d = INFINITY;
			if (d > m) {
				m = d;
				if (at)
					*at = p;
			}
		}
	}
	return m;
}

static size_t count_nonfinite(const float *v, size_t n)
{
	size_t bad = 0;
	for (size_t i = 0; i < n; i++)
		bad += !isfinite(v[i]);
	return bad;
}

/* The mean of the colour channels: a check that an image is not black. */
static double mean_rgb(const float *v, size_t npix)
{
	double sum = 0.0;
	for (size_t p = 0; p < npix; p++)
		sum += (double)v[p * 4] + v[p * 4 + 1] + v[p * 4 + 2];
	return npix ? sum / (3.0 * (double)npix) : 0.0;
}

/* ---- scenes, renders, bakes ---- */

/* Write @text to WORKDIR/@name.rib; its path into @rib. */
static bool write_rib(struct suite *s, const char *name, const char *text, char *rib, size_t len,
		      char *why, size_t wlen)
{
	snprintf(rib, len, "%s/%s.rib", s->o->workdir, name);
	FILE *f = fopen(rib, "w");
	if (!f) {
		snprintf(why, wlen, "cannot write %s: %s", rib, strerror(errno));
		return false;
	}
	bool ok = fputs(text, f) >= 0;
	ok = fclose(f) == 0 && ok;
	if (!ok)
		snprintf(why, wlen, "cannot write %s", rib);
	return ok;
}

struct render_job {
	struct reyes_render_opts ro;
	int frames;
};

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct render_job *j = user;
	j->frames++;
	return reyes_render(scene, &j->ro, NULL);
}

/*
 * Render the RIB file @rib, whose one display is the float OpenEXR @exr,
 * and read the image back: @w x @h RGBA floats (free() them), or NULL with
 * the reason in @why.
 */
static float *render_rib(struct suite *s, const char *rib, const char *exr, uint32_t w,
			 uint32_t h, char *why, size_t wlen)
{
	struct render_job job = { .ro = { .diag = s->log, .texture_path = s->o->workdir } };
	struct reyes_ri_opts ri = {
		.diag = s->log,
		.default_shader_path = s->shader_path,
		.default_texture_path = s->o->workdir,
		.frame = on_frame,
		.user = &job,
	};
	int nerrors = 0;
	if (!reyes_ri_read(rib, &ri, &nerrors) || job.frames != 1) {
		snprintf(why, wlen, "rendering %s failed (%d errors, %d frames)", rib, nerrors,
			 job.frames);
		return NULL;
	}
	return bench_read_rgba_exr(exr, w, h, true, s->log, why, wlen);
}

/* Bake WORKDIR/@name.rib (@rib) to WORKDIR/@name.shot.exr (@shot). */
static bool bake(struct suite *s, const char *name, const char *rib, bool full_float, char *shot,
		 size_t len, char *why, size_t wlen)
{
	snprintf(shot, len, "%s/%s.shot.exr", s->o->workdir, name);
	struct bake_opts bo = {
		.diag = s->log,
		.full_float = full_float,
		.shader_path = s->shader_path,
	};
	if (!bake_rib_file(rib, shot, &bo, false, NULL)) {
		snprintf(why, wlen, "baking %s failed", rib);
		return false;
	}
	return true;
}

/* The CPU resolver's image of @shot at @level with @edits (@w x @h RGBA). */
static float *cpu_image(struct suite *s, const char *shot, int level,
			const struct resolve_edit *edits, size_t nedits, uint32_t w, uint32_t h,
			char *why, size_t wlen)
{
	struct resolve_opts ro = {
		.diag = s->log,
		.texture_path = s->o->workdir,
		.level = level,
		.edits = edits,
		.nedits = nedits,
	};
	struct resolve_result r = { 0 };
	if (!resolve_cpu(shot, &ro, &r)) {
		snprintf(why, wlen, "the CPU resolver failed on %s", shot);
		free(r.rgba);
		return NULL;
	}
	if (r.width != w || r.height != h) {
		snprintf(why, wlen, "the CPU resolver gave %ux%u, expected %ux%u", r.width,
			 r.height, w, h);
		free(r.rgba);
		return NULL;
	}
	return r.rgba;
}

static struct gpu_shot *gpu_open(struct suite *s, const char *shot, uint32_t w, uint32_t h,
				 char *why, size_t wlen)
{
	struct gpu_shot_opts go = { .diag = s->log, .texture_path = s->o->workdir };
	struct gpu_shot *sh = gpu_shot_open(s->o->ctx, shot, &go);
	if (!sh) {
		snprintf(why, wlen, "the GPU runtime cannot load %s", shot);
		return NULL;
	}
	if (gpu_shot_width(sh) != w || gpu_shot_height(sh) != h) {
		snprintf(why, wlen, "the shot is %ux%u, expected %ux%u", gpu_shot_width(sh),
			 gpu_shot_height(sh), w, h);
		gpu_shot_close(sh);
		return NULL;
	}
	return sh;
}

/* Level @level of @sh brought up to date and read into @rgba. */
static bool gpu_image(struct gpu_shot *sh, int level, float *rgba, char *why, size_t wlen)
{
	if (!gpu_shot_render(sh, level, NULL) || !gpu_shot_read_rgba(sh, level, rgba)) {
		snprintf(why, wlen, "the GPU runtime failed to render level %d", level);
		return false;
	}
	return true;
}

/* A small deterministic generator (xorshift32): the same edits every run. */
static double uniform(uint32_t *st)
{
	uint32_t x = *st;
	x ^= x << 13;
	x ^= x >> 17;
	x ^= x << 5;
	*st = x;
	return (x >> 8) * (1.0 / 16777216.0);
}

/* ---- drift ---- */

/* The drift scene's edited light as baked (restored to this after the edits). */
static const float drift_from0[3] = { 0.5f, 1.2f, 0.3f };
#define DRIFT_INTENSITY0 3.0f
#define DRIFT_KD 0.6f

struct drift_edit {
	float intensity;
	float color[3];
	float from[3];
};

/* Which parameters edit @i sets beside the intensity: colour every third,
 * position every seventh, so that the three change out of step. */
static bool drift_sets_color(int i)
{
	return i % 3 == 0;
}

static bool drift_sets_from(int i)
{
	return i % 7 == 0;
}

/*
 * What the point light gives a ground point @P (normal +y) through the
 * diffuse lobe, in float as a kernel shades it: a model of one light
 * cache entry, enough to show how the cache's own arithmetic drifts.
 */
static float drift_light(const float P[3], float intensity, float color, const float from[3])
{
	float d[3] = { from[0] - P[0], from[1] - P[1], from[2] - P[2] };
	float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
	if (!(d2 > 0.0f) || d[1] <= 0.0f)
		return 0.0f;
	return intensity * color * DRIFT_KD * (d[1] / sqrtf(d2)) / d2;
}

/*
 * The light cache of a few ground points summed in float32 and in float64
 * over the same edits (each: the old contribution out, the new one in),
 * then the light restored: the largest relative drift of each.
 */
static void drift_simulate(const struct drift_edit *e, int n, double *drift32, double *drift64)
{
	*drift32 = *drift64 = 0.0;
	for (int k = 0; k < 8; k++) {
		const float P[3] = { -1.4f + 0.4f * (float)k, 0.0f, -0.6f + 0.2f * (float)k };
		/* the other lights' share, frozen all along: the ambient light
		 * and the distant one at a cosine of 0.55 */
		const float base = 0.05f + 0.6f * DRIFT_KD * 0.55f;
		for (int c = 0; c < 3; c++) {
			const float white = 1.0f;
			float c0 = drift_light(P, DRIFT_INTENSITY0, white, drift_from0);
			float a32 = base + c0, start32 = a32;
			double a64 = (double)base + c0, start64 = a64;
			float prev = c0, col = white;
			const float *from = drift_from0;
			for (int i = 0; i < n; i++) {
				if (drift_sets_color(i))
					col = e[i].color[c];
				if (drift_sets_from(i))
					from = e[i].from;
				float next = drift_light(P, e[i].intensity, col, from);
				a32 = (a32 - prev) + next;
				a64 = (a64 - prev) + next;
				prev = next;
			}
			a32 = (a32 - prev) + c0;
			a64 = (a64 - prev) + c0;
			double r32 = fabs((double)a32 - start32) / fabs((double)start32);
			double r64 = fabs(a64 - start64) / fabs(start64);
			*drift32 = fmax(*drift32, r32);
			*drift64 = fmax(*drift64, r64);
		}
	}
}

static void case_drift(struct suite *s)
{
	const char *G = "drift";
	const int first = s->n;
	const int nedits = s->o->quick ? STAB_DRIFT_EDITS_QUICK : STAB_DRIFT_EDITS_FULL;
	const uint32_t W = s->o->quick ? 64 : 96, H = s->o->quick ? 48 : 72;
	const int k_rest = check(s, G, "restored light: image vs original, max relative",
				 STAB_DRIFT_REL);
	const int k_fin = check(s, G, "non-finite values in the levels read after each edit", 0);
	const int k_32 = check(s, G, "float32 cache (simulated): relative drift", NAN);
	const int k_64 = check(s, G, "float64 cache (simulated): relative drift", NAN);
	char why[WHY_LEN], rib[512], shot[512], err[256];
	float *before = NULL, *img = NULL;
	struct gpu_shot *sh = NULL;
	struct drift_edit *e = calloc((size_t)nedits, sizeof(*e));
	if (!e) {
		fail_pending(s, first, "out of memory");
		return;
	}
	uint32_t rng = 0x2545f491u;
	for (int i = 0; i < nedits; i++) {
		e[i].intensity = (float)pow(10.0, -4.0 + 8.0 * uniform(&rng));
		for (int c = 0; c < 3; c++)
			e[i].color[c] = (float)uniform(&rng);
		e[i].from[0] = (float)(uniform(&rng) * 4.0 - 2.0);
		e[i].from[1] = (float)(0.05 + uniform(&rng) * 3.0);
		e[i].from[2] = (float)(uniform(&rng) * 4.0 - 2.0);
	}
	double d32, d64;
	drift_simulate(e, nedits, &d32, &d64);
	measured(s, k_32, d32, "%d edits of intensities 1e-4..1e4 at 8 ground points", nedits);
	measured(s, k_64, d64, "the same edits, as the runtime's cache sums them");

	if (!s->o->ctx) {
		skipped(s, k_rest, "no GPU context");
		skipped(s, k_fin, "no GPU context");
		goto done;
	}
	struct rl_strbuf t = { 0 };
	rl_strbuf_printf(&t,
		"Format %u %u 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 40\n"
		"Display \"%s/stab-drift.exr\" \"file\" \"rgba\"\n"
		"Translate 0 -0.5 4\nRotate -20 1 0 0\nWorldBegin\n"
		"  LightSource \"ambientlight\" \"fill\" \"intensity\" 0.05\n"
		"  LightSource \"distantlight\" \"sun\" \"intensity\" 0.6 \"from\" [0 0 0]"
		" \"to\" [0.4 -1 0.6]\n"
		"  LightSource \"pointlight\" \"key\" \"intensity\" %.9g \"from\" [%.9g %.9g %.9g]\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\" \"Kd\" %.9g \"Ks\" 0.4 \"roughness\" 0.1\n"
		"    Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"matte\"\n    Translate -0.4 0.5 0.6\n    Sphere 0.5 -0.5 0.5 360\n"
		"  AttributeEnd\n"
		"WorldEnd\n",
		W, H, s->o->workdir, (double)DRIFT_INTENSITY0, (double)drift_from0[0],
		(double)drift_from0[1], (double)drift_from0[2], (double)DRIFT_KD);
	bool ok = write_rib(s, "stab-drift", rl_strbuf_str(&t), rib, sizeof(rib), why, sizeof(why));
	rl_strbuf_finish(&t);
	if (!ok || !bake(s, "stab-drift", rib, false, shot, sizeof(shot), why, sizeof(why)) ||
	    !(sh = gpu_open(s, shot, W, H, why, sizeof(why))))
		goto fail;
	size_t n = (size_t)W * H * 4;
	before = calloc(n, sizeof(float));
	img = calloc(n, sizeof(float));
	if (!before || !img) {
		snprintf(why, sizeof(why), "out of memory");
		goto fail;
	}
	if (!gpu_image(sh, GPU_SHOT_FINAL, before, why, sizeof(why)))
		goto fail;
	if (!(mean_rgb(before, (size_t)W * H) > 0.01)) {
		snprintf(why, sizeof(why), "the scene renders black: nothing to measure");
		goto fail;
	}
	say(s, "drift: %d edits of one light folded into the light cache", nedits);
	double t0 = now_s();
	size_t bad = 0;
	for (int i = 0; i < nedits; i++) {
		const struct drift_edit *d = &e[i];
		if (!gpu_shot_set(sh, "key", "intensity", &d->intensity, 1, err, sizeof(err)) ||
		    (drift_sets_color(i) &&
		     !gpu_shot_set(sh, "key", "lightcolor", d->color, 3, err, sizeof(err))) ||
		    (drift_sets_from(i) &&
		     !gpu_shot_set(sh, "key", "from", d->from, 3, err, sizeof(err))) ||
		    !gpu_shot_freeze(sh, "key", true, err, sizeof(err))) {
			snprintf(why, sizeof(why), "edit %d refused: %s", i, err);
			goto fail;
		}
		/*
		 * Each edit is shaded into the cache of band 0 (level 0, the
		 * cheap one an interactive drag shows); every hundredth also
		 * refines to level 1 and every thousandth to the final level,
		 * so that every band's cache goes through many edits.
		 */
		int level = i % 1000 == 999 ? GPU_SHOT_FINAL : i % 100 == 99 ? 1 : 0;
		if (!gpu_image(sh, level, img, why, sizeof(why)))
			goto fail;
		bad += count_nonfinite(img, n);
		if (i % 10000 == 9999)
			say(s, "drift: %d edits, %.1f s", i + 1, now_s() - t0);
	}
	const float i0 = DRIFT_INTENSITY0, white[3] = { 1, 1, 1 };
	if (!gpu_shot_set(sh, "key", "intensity", &i0, 1, err, sizeof(err)) ||
	    !gpu_shot_set(sh, "key", "lightcolor", white, 3, err, sizeof(err)) ||
	    !gpu_shot_set(sh, "key", "from", drift_from0, 3, err, sizeof(err)) ||
	    !gpu_shot_freeze(sh, "key", true, err, sizeof(err))) {
		snprintf(why, sizeof(why), "restoring the light refused: %s", err);
		goto fail;
	}
	if (!gpu_image(sh, GPU_SHOT_FINAL, img, why, sizeof(why)))
		goto fail;
	bad += count_nonfinite(img, n);
	double secs = now_s() - t0;
	measured(s, k_rest, max_rel(img, before, (size_t)W * H, 4, STAB_REL_FLOOR, NULL),
		 "%d edits in %.1f s (%.0f us each), %ux%u", nedits, secs, 1e6 * secs / nedits, W, H);
	measured(s, k_fin, (double)bad, "%d images: level 0, every 100th 1, every 1000th 3",
		 nedits + 1);
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	gpu_shot_close(sh);
	free(before);
	free(img);
	free(e);
}

/* ---- hdr ---- */

static const double hdr_intensities[] = { 1e-4, 1e-2, 1, 1e2, 1e4 };
#define HDR_N (sizeof(hdr_intensities) / sizeof(hdr_intensities[0]))

/*
 * Half output against the float image: the worst error in units of half
 * precision (see STAB_HALF_ULP_RATIO); *nonfinite, *clamped counted.
 */
static double half_error(const float *f, const uint16_t *h, size_t n, size_t *nonfinite,
			 size_t *clamped)
{
	double worst = 0.0;
	for (size_t i = 0; i < n; i++) {
		double hv = shot_half_value(h[i]), fv = f[i];
		if (!isfinite(hv) || !isfinite(fv)) {
			(*nonfinite)++;
			continue;
		}
		double r;
		if (fabs(fv) > STAB_HALF_MAX) {
			(*clamped)++;
			r = hv == copysign(STAB_HALF_MAX, fv) ? 0.0 : INFINITY;
		} else {
			r = fabs(hv - fv) / fmax(fabs(fv) * 0x1p-11, 0x1p-25);
		}
		worst = fmax(worst, r);
	}
	return worst;
}

static void case_hdr(struct suite *s)
{
	const char *G = "hdr";
	const int first = s->n;
	const uint32_t W = s->o->quick ? 64 : 160, H = s->o->quick ? 48 : 120;
	int k_rel[HDR_N];
	for (size_t i = 0; i < HDR_N; i++) {
		char name[96];
		snprintf(name, sizeof(name), "intensity %g: GPU vs CPU, max relative",
			 hdr_intensities[i]);
		k_rel[i] = check(s, G, name, STAB_GPU_CPU_REL);
	}
	const int k_cpu_fin = check(s, G, "CPU resolver: non-finite values", 0);
	const int k_gpu_fin = check(s, G, "GPU: non-finite values", 0);
	const int k_half = check(s, G, "half output vs float: error in half ulps",
				 STAB_HALF_ULP_RATIO);
	const int k_half_fin = check(s, G, "half output: non-finite values", 0);
	char why[WHY_LEN], rib[512], shot[512], err[256];
	struct gpu_shot *sh = NULL;
	float *cpu = NULL, *gpu = NULL;
	uint16_t *half = NULL;
	struct rl_strbuf t = { 0 };
	/* One light, at intensity 1 in the bake, close to the ground: at 1e4
	 * the nearest pixels pass half's largest value. */
	rl_strbuf_printf(&t,
		"Format %u %u 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 40\n"
		"Display \"%s/stab-hdr.exr\" \"file\" \"rgba\"\n"
		"Translate 0 -0.5 4\nRotate -20 1 0 0\nWorldBegin\n"
		"  LightSource \"pointlight\" \"key\" \"intensity\" 1 \"from\" [0.2 0.25 0.4]\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\" \"Kd\" 0.8 \"Ks\" 0.5 \"roughness\" 0.05\n"
		"    Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"matte\"\n    Translate -0.7 0.4 0.8\n    Sphere 0.4 -0.4 0.4 360\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"metal\" \"roughness\" 0.05\n    Translate 0.8 0.3 0.2\n"
		"    Sphere 0.3 -0.3 0.3 360\n"
		"  AttributeEnd\n"
		"WorldEnd\n",
		W, H, s->o->workdir);
	bool ok = write_rib(s, "stab-hdr", rl_strbuf_str(&t), rib, sizeof(rib), why, sizeof(why));
	rl_strbuf_finish(&t);
	if (!ok || !bake(s, "stab-hdr", rib, false, shot, sizeof(shot), why, sizeof(why)))
		goto fail;
	size_t npix = (size_t)W * H;
	if (s->o->ctx) {
		if (!(sh = gpu_open(s, shot, W, H, why, sizeof(why))))
			goto fail;
		gpu = calloc(npix * 4, sizeof(float));
		half = calloc(npix * 4, sizeof(uint16_t));
		if (!gpu || !half) {
			snprintf(why, sizeof(why), "out of memory");
			goto fail;
		}
	} else {
		for (size_t i = 0; i < HDR_N; i++)
			skipped(s, k_rel[i], "no GPU context");
		skipped(s, k_gpu_fin, "no GPU context");
		skipped(s, k_half, "no GPU context");
		skipped(s, k_half_fin, "no GPU context");
	}
	size_t cpu_bad = 0, gpu_bad = 0, half_bad = 0, clamped = 0;
	double half_worst = 0.0, brightest = 0.0;
	for (size_t i = 0; i < HDR_N; i++) {
		const double v = hdr_intensities[i];
		say(s, "hdr: intensity %g", v);
		struct resolve_edit ed = { .light = "key", .param = "intensity",
					   .values = { (float)v }, .nvalues = 1 };
		if (!(cpu = cpu_image(s, shot, RESOLVE_FINAL, &ed, 1, W, H, why, sizeof(why))))
			goto fail;
		cpu_bad += count_nonfinite(cpu, npix * 4);
		if (v == 1.0 && !(mean_rgb(cpu, npix) > 0.01)) {
			snprintf(why, sizeof(why), "the scene resolves black: nothing to measure");
			goto fail;
		}
		if (sh) {
			const float fv = (float)v;
			if (!gpu_shot_set(sh, "key", "intensity", &fv, 1, err, sizeof(err))) {
				snprintf(why, sizeof(why), "intensity %g refused: %s", v, err);
				goto fail;
			}
			if (!gpu_image(sh, GPU_SHOT_FINAL, gpu, why, sizeof(why)))
				goto fail;
			if (!gpu_shot_read_half(sh, GPU_SHOT_FINAL, half)) {
				snprintf(why, sizeof(why), "reading the half output failed");
				goto fail;
			}
			gpu_bad += count_nonfinite(gpu, npix * 4);
			size_t at = 0;
			/* Below a thousandth of what the light gives at intensity 1,
			 * compared absolutely: the floor scales with the light. */
			double r = max_rel(gpu, cpu, npix, 4, STAB_REL_FLOOR * v, &at);
			for (size_t p = 0; p < npix * 4; p++)
				brightest = fmax(brightest, gpu[p]);
			measured(s, k_rel[i], r, "worst at pixel (%zu, %zu), floor %g",
				 at % W, at / W, STAB_REL_FLOOR * v);
			half_worst = fmax(half_worst,
					  half_error(gpu, half, npix * 4, &half_bad, &clamped));
		}
		free(cpu);
		cpu = NULL;
	}
	measured(s, k_cpu_fin, (double)cpu_bad, "%zu intensities, %ux%u", HDR_N, W, H);
	if (sh) {
		measured(s, k_gpu_fin, (double)gpu_bad, NULL);
		measured(s, k_half, half_worst, "%zu values clamped at 65504 (brightest %.3g)",
			 clamped, brightest);
		measured(s, k_half_fin, (double)half_bad, NULL);
	}
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	gpu_shot_close(sh);
	free(cpu);
	free(gpu);
	free(half);
}

/* ---- degenerate ---- */

static void case_degenerate(struct suite *s)
{
	const char *G = "degenerate";
	const int first = s->n;
	const uint32_t W = s->o->quick ? 64 : 160, H = s->o->quick ? 48 : 120;
	const int k_render = check(s, G, "render: non-finite values", 0);
	const int k_cpu = check(s, G, "CPU resolver, levels 0-3: non-finite values", 0);
	const int k_gpu = check(s, G, "GPU, levels 0-3: non-finite values", 0);
	const int k_rel = check(s, G, "GPU vs CPU, levels 0-3: max relative", STAB_GPU_CPU_REL);
	char why[WHY_LEN], rib[512], shot[512], exr[512];
	struct gpu_shot *sh = NULL;
	float *ref = NULL, *cpu = NULL, *gpu = NULL;
	struct rl_strbuf t = { 0 };
	/*
	 * A point light lying on the ground, a distant light grazing it, a
	 * mirror-smooth plastic ground, a card whose normals are all zero, two
	 * zero-area polygons (collinear, and one point four times), a sphere
	 * smaller than a micropolygon and one of a few pixels.
	 */
	snprintf(exr, sizeof(exr), "%s/stab-degenerate.exr", s->o->workdir);
	rl_strbuf_printf(&t,
		"Format %u %u 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 45\n"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"Translate 0 -0.5 4\nRotate -20 1 0 0\nWorldBegin\n"
		"  LightSource \"ambientlight\" \"fill\" \"intensity\" 0.05\n"
		"  LightSource \"pointlight\" \"onground\" \"intensity\" 2 \"from\" [0.3 0 0.6]\n"
		"  LightSource \"distantlight\" \"grazing\" \"intensity\" 1 \"from\" [0 0 0]"
		" \"to\" [1 0 0.2]\n"
		"  LightSource \"spotlight\" \"spot\" \"intensity\" 10 \"from\" [0 3 0]"
		" \"to\" [0 0 0] \"coneangle\" 0.6\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\" \"roughness\" 1e-6 \"Ks\" 0.9\n"
		"    Polygon \"P\" [-3 0 -2  -3 0 4  3 0 4  3 0 -2]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\" \"roughness\" 0.2\n"
		"    Polygon \"P\" [-1 0.1 0  -0.4 0.1 0  -0.4 0.7 0  -1 0.7 0]"
		" \"N\" [0 0 0  0 0 0  0 0 0  0 0 0]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"matte\"\n"
		"    Polygon \"P\" [0.2 0.2 0  0.6 0.2 0  1 0.2 0]\n"
		"    Polygon \"P\" [0.5 0.5 0.5  0.5 0.5 0.5  0.5 0.5 0.5  0.5 0.5 0.5]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"metal\" \"roughness\" 1e-6\n"
		"    Translate 0.6 0.3 0.4\n    Sphere 1e-4 -1e-4 1e-4 360\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\"\n    Translate -0.3 0.3 0.9\n    Sphere 0.02 -0.02 0.02 360\n"
		"  AttributeEnd\n"
		"WorldEnd\n",
		W, H, exr);
	bool ok = write_rib(s, "stab-degenerate", rl_strbuf_str(&t), rib, sizeof(rib), why,
			    sizeof(why));
	rl_strbuf_finish(&t);
	if (!ok)
		goto fail;
	size_t npix = (size_t)W * H;
	say(s, "degenerate: render, bake, levels 0-3 on the CPU%s",
	    s->o->ctx ? " and the GPU" : "");
	if (!(ref = render_rib(s, rib, exr, W, H, why, sizeof(why))))
		goto fail;
	measured(s, k_render, (double)count_nonfinite(ref, npix * 4), "mean %.3g",
		 mean_rgb(ref, npix));
	if (!bake(s, "stab-degenerate", rib, false, shot, sizeof(shot), why, sizeof(why)))
		goto fail;
	if (s->o->ctx) {
		if (!(sh = gpu_open(s, shot, W, H, why, sizeof(why))))
			goto fail;
		if (!(gpu = calloc(npix * 4, sizeof(float)))) {
			snprintf(why, sizeof(why), "out of memory");
			goto fail;
		}
	} else {
		skipped(s, k_gpu, "no GPU context");
		skipped(s, k_rel, "no GPU context");
	}
	size_t cpu_bad = 0, gpu_bad = 0;
	double worst = 0.0;
	int worst_level = 0;
	for (int level = 0; level < GPU_SHOT_LEVELS; level++) {
		if (!(cpu = cpu_image(s, shot, level, NULL, 0, W, H, why, sizeof(why))))
			goto fail;
		cpu_bad += count_nonfinite(cpu, npix * 4);
		if (level == GPU_SHOT_FINAL && !(mean_rgb(cpu, npix) > 0.01)) {
			snprintf(why, sizeof(why), "the scene resolves black: nothing to measure");
			goto fail;
		}
		if (sh) {
			if (!gpu_image(sh, level, gpu, why, sizeof(why)))
				goto fail;
			gpu_bad += count_nonfinite(gpu, npix * 4);
			double r = max_rel(gpu, cpu, npix, 4, STAB_REL_FLOOR, NULL);
			if (!(r <= worst)) {
				worst = r;
				worst_level = level;
			}
		}
		free(cpu);
		cpu = NULL;
	}
	measured(s, k_cpu, (double)cpu_bad, NULL);
	if (sh) {
		measured(s, k_gpu, (double)gpu_bad, NULL);
		measured(s, k_rel, worst, "worst at level %d", worst_level);
	}
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	gpu_shot_close(sh);
	free(ref);
	free(cpu);
	free(gpu);
}

/* ---- transparency ---- */

#define TRANSP_COLUMNS 4
#define TRANSP_COLUMN_PX 16

/* Layer @i's colour, on a 1/256 grid (exact in float and in the RIB). */
static float transp_color(int i, int c)
{
	static const int mul[3] = { 37, 61, 97 };
	return (float)((mul[c] * i + 50 * c + 40) % 200 + 40) / 256.0f;
}

/*
 * The closed form of @n layers of colour transp_color(i) and opacity @a
 * composited front to back: colour sum_i c_i a (1 - a)^i, alpha
 * 1 - (1 - a)^k, over the k layers before the sample reaches the opacity
 * threshold (found with the renderer's float arithmetic). Into @rgba.
 */
static int transp_closed_form(int n, float a, double rgba[4])
{
	float T = 1.0f;
	int k = 0;
	while (k < n) {
		T *= 1.0f - a;
		k++;
		if (T <= 1.0f - STAB_OPACITY_THRESHOLD)
			break;
	}
	double Td = 1.0, C[3] = { 0, 0, 0 };
	for (int i = 0; i < k; i++) {
		for (int c = 0; c < 3; c++)
			C[c] += (double)transp_color(i, c) * a * Td;
		Td *= 1.0 - (double)a;
	}
	for (int c = 0; c < 3; c++)
		rgba[c] = C[c];
	rgba[3] = 1.0 - Td;
	return k;
}

/* The largest relative difference of column @col's inner pixels from @want. */
static double transp_column_error(const float *img, uint32_t W, uint32_t H, int col,
				  const double want[4])
{
	double m = 0.0;
	/* 3 pixels from the column's sides: beyond the filter's reach of the next */
	for (uint32_t y = 0; y < H; y++) {
		for (uint32_t x = (uint32_t)col * TRANSP_COLUMN_PX + 3;
		     x < (uint32_t)(col + 1) * TRANSP_COLUMN_PX - 3; x++) {
			const float *p = img + ((size_t)y * W + x) * 4;
			for (int c = 0; c < 4; c++) {
				double d = fabs((double)p[c] - want[c]) / fmax(fabs(want[c]), 1e-30);
				m = isfinite(d) ? fmax(m, d) : INFINITY;
			}
		}
	}
	return m;
}

static double max_alpha(const float *img, size_t npix)
{
	double m = -INFINITY;
	for (size_t p = 0; p < npix; p++)
		m = isfinite(img[p * 4 + 3]) ? fmax(m, img[p * 4 + 3]) : INFINITY;
	return m;
}

static void case_transparency(struct suite *s)
{
	const char *G = "transparency";
	const int first = s->n;
	const int N = s->o->quick ? STAB_TRANSP_LAYERS_QUICK : STAB_TRANSP_LAYERS_FULL;
	const uint32_t W = TRANSP_COLUMNS * TRANSP_COLUMN_PX, H = 16;
	/*
	 * Four stacks side by side, one a column: layers nearly opaque
	 * (compositing stops after the first), half (stops after 8), nearly
	 * clear, and the opacity whose N layers come closest to the threshold
	 * without reaching it: the longest chain the renderer composites.
	 */
	float a[TRANSP_COLUMNS] = { 0.999f, 0.5f, 0.01f, 0.0f };
	a[3] = (float)(1.0 - pow(1.0 - STAB_OPACITY_THRESHOLD + 5e-4, 1.0 / N));
	int k_render[TRANSP_COLUMNS], k_gpu[TRANSP_COLUMNS];
	for (int j = 0; j < TRANSP_COLUMNS; j++) {
		char name[96];
		snprintf(name, sizeof(name), "%d layers of opacity %.4g: render vs closed form", N,
			 (double)a[j]);
		k_render[j] = check(s, G, name, STAB_TRANSP_RENDER_REL);
		snprintf(name, sizeof(name), "%d layers of opacity %.4g: GPU vs closed form", N,
			 (double)a[j]);
		k_gpu[j] = check(s, G, name, STAB_TRANSP_GPU_REL);
	}
	const int k_alpha = check(s, G, "largest alpha (render and GPU)", 1.0 + STAB_ALPHA_OVER);
	char why[WHY_LEN], rib[512], shot[512], exr[512];
	struct gpu_shot *sh = NULL;
	float *ref = NULL, *gpu = NULL;
	struct rl_strbuf t = { 0 };
	snprintf(exr, sizeof(exr), "%s/stab-transparency.exr", s->o->workdir);
	rl_strbuf_printf(&t,
		"Format %u %u 1\nPixelSamples 2 2\nProjection \"orthographic\"\n"
		"ScreenWindow -4 4 -1 1\n"
		"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
		"WorldBegin\n  Surface \"constant\"\n", W, H, exr);
	for (int j = 0; j < TRANSP_COLUMNS; j++) {
		/* the outer columns reach past the frame's sides */
		double x0 = j == 0 ? -5.0 : -4.0 + 2.0 * j;
		double x1 = j == TRANSP_COLUMNS - 1 ? 5.0 : -2.0 + 2.0 * j;
		rl_strbuf_printf(&t, "  AttributeBegin\n    Opacity [%.9g %.9g %.9g]\n",
				 (double)a[j], (double)a[j], (double)a[j]);
		for (int i = 0; i < N; i++) {
			double z = 1.0 + 0.01 * i;
			rl_strbuf_printf(&t,
				"    Color [%.9g %.9g %.9g]\n"
				"    Polygon \"P\" [%g -2 %g  %g -2 %g  %g 2 %g  %g 2 %g]\n",
				(double)transp_color(i, 0), (double)transp_color(i, 1),
				(double)transp_color(i, 2), x0, z, x1, z, x1, z, x0, z);
		}
		rl_strbuf_puts(&t, "  AttributeEnd\n");
	}
	rl_strbuf_puts(&t, "WorldEnd\n");
	bool ok = write_rib(s, "stab-transparency", rl_strbuf_str(&t), rib, sizeof(rib), why,
			    sizeof(why));
	rl_strbuf_finish(&t);
	if (!ok)
		goto fail;
	size_t npix = (size_t)W * H;
	say(s, "transparency: %d layers, opacities %g, %g, %g, %g", N, (double)a[0],
	    (double)a[1], (double)a[2], (double)a[3]);
	if (!(ref = render_rib(s, rib, exr, W, H, why, sizeof(why))))
		goto fail;
	double alpha = max_alpha(ref, npix);
	if (s->o->ctx) {
		/* Stored in float: the half case measures storage, this one compositing. */
		if (!bake(s, "stab-transparency", rib, true, shot, sizeof(shot), why, sizeof(why)) ||
		    !(sh = gpu_open(s, shot, W, H, why, sizeof(why))))
			goto fail;
		if (!(gpu = calloc(npix * 4, sizeof(float)))) {
			snprintf(why, sizeof(why), "out of memory");
			goto fail;
		}
		if (!gpu_image(sh, GPU_SHOT_FINAL, gpu, why, sizeof(why)))
			goto fail;
		alpha = fmax(alpha, max_alpha(gpu, npix));
	}
	for (int j = 0; j < TRANSP_COLUMNS; j++) {
		double want[4];
		int k = transp_closed_form(N, a[j], want);
		measured(s, k_render[j], transp_column_error(ref, W, H, j, want),
			 "%d layers composited, alpha %.9g", k, want[3]);
		if (sh)
			measured(s, k_gpu[j], transp_column_error(gpu, W, H, j, want), NULL);
		else
			skipped(s, k_gpu[j], "no GPU context");
	}
	measured(s, k_alpha, alpha, NULL);
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	gpu_shot_close(sh);
	free(ref);
	free(gpu);
}

/* ---- weights ---- */

static const float weights_color[3] = { 0.25f, 0.5f, 0.75f };

/* Full cover: every pixel's colour and alpha against the constant, relative. */
static double weights_full_error(const float *img, size_t npix)
{
	double m = 0.0;
	for (size_t p = 0; p < npix; p++) {
		for (int c = 0; c < 4; c++) {
			double want = c < 3 ? weights_color[c] : 1.0;
			double d = fabs((double)img[p * 4 + (size_t)c] - want) / want;
			m = isfinite(d) ? fmax(m, d) : INFINITY;
		}
	}
	return m;
}

/* Partial cover: how far alpha leaves [0, 1], and how far the (premultiplied)
 * colour is from alpha x the constant, relative to the constant. */
static void weights_edge_error(const float *img, size_t npix, double *alpha_out,
			       double *color_dev)
{
	*alpha_out = *color_dev = 0.0;
	for (size_t p = 0; p < npix; p++) {
		double A = img[p * 4 + 3];
		double out = fmax(A - 1.0, -A);
		*alpha_out = isfinite(out) ? fmax(*alpha_out, out) : INFINITY;
		for (int c = 0; c < 3; c++) {
			double d = fabs((double)img[p * 4 + (size_t)c] - A * weights_color[c]) /
				   weights_color[c];
			*color_dev = isfinite(d) ? fmax(*color_dev, d) : INFINITY;
		}
	}
	*alpha_out += 0.0; /* -0 when alpha is 0 somewhere: print it as 0 */
}

static void case_weights(struct suite *s)
{
	const char *G = "weights";
	const int first = s->n;
	const uint32_t R = s->o->quick ? STAB_WEIGHTS_SIZE_QUICK : STAB_WEIGHTS_SIZE_FULL;
	const int k_rf = check(s, G, "render, full cover: colour and alpha vs constant, max rel",
			       STAB_WEIGHTS_RENDER_REL);
	const int k_gf = check(s, G, "GPU, full cover: colour and alpha vs constant, max rel",
			       STAB_WEIGHTS_GPU_REL);
	const int k_ra = check(s, G, "render, edge: alpha outside [0, 1] by", STAB_ALPHA_OVER);
	const int k_rc = check(s, G, "render, edge: colour vs alpha x constant, max rel",
			       STAB_WEIGHTS_RENDER_REL);
	const int k_ga = check(s, G, "GPU, edge: alpha outside [0, 1] by", STAB_ALPHA_OVER);
	const int k_gc = check(s, G, "GPU, edge: colour vs alpha x constant, max rel",
			       STAB_WEIGHTS_GPU_REL);
	char why[WHY_LEN], rib[512], shot[512], exr[512];
	struct gpu_shot *sh = NULL;
	float *ref = NULL, *gpu = NULL;
	size_t npix = (size_t)R * R;
	/* The plane reaches half the frame beyond every side, past the filter;
	 * the edge variant's slanted side crosses the frame. */
	static const char *const polys[2] = {
		"-1.5 -1.5 1  1.5 -1.5 1  1.5 1.5 1  -1.5 1.5 1",
		"-1.5 -1.5 1  0.2 -1.5 1  -0.3 1.5 1  -1.5 1.5 1",
	};
	static const char *const names[2] = { "stab-weights", "stab-weights-edge" };
	say(s, "weights: 16x16 samples, %ux%u, full cover and an edge", R, R);
	for (int v = 0; v < 2; v++) {
		struct rl_strbuf t = { 0 };
		snprintf(exr, sizeof(exr), "%s/%s.exr", s->o->workdir, names[v]);
		rl_strbuf_printf(&t,
			"Format %u %u 1\nPixelSamples 16 16\nProjection \"orthographic\"\n"
			"ScreenWindow -1 1 -1 1\n"
			"Display \"%s\" \"file\" \"rgba\" \"string type\" \"float\"\n"
			"WorldBegin\n  Surface \"constant\"\n  Color [%.9g %.9g %.9g]\n"
			"  Polygon \"P\" [%s]\nWorldEnd\n",
			R, R, exr, (double)weights_color[0], (double)weights_color[1],
			(double)weights_color[2], polys[v]);
		bool ok = write_rib(s, names[v], rl_strbuf_str(&t), rib, sizeof(rib), why,
				    sizeof(why));
		rl_strbuf_finish(&t);
		if (!ok || !(ref = render_rib(s, rib, exr, R, R, why, sizeof(why))))
			goto fail;
		if (v == 0) {
			measured(s, k_rf, weights_full_error(ref, npix), NULL);
		} else {
			double ao, cd;
			weights_edge_error(ref, npix, &ao, &cd);
			measured(s, k_ra, ao, NULL);
			measured(s, k_rc, cd, NULL);
		}
		if (s->o->ctx) {
			if (!bake(s, names[v], rib, true, shot, sizeof(shot), why, sizeof(why)) ||
			    !(sh = gpu_open(s, shot, R, R, why, sizeof(why))))
				goto fail;
			if (!(gpu = calloc(npix * 4, sizeof(float)))) {
				snprintf(why, sizeof(why), "out of memory");
				goto fail;
			}
			if (!gpu_image(sh, GPU_SHOT_FINAL, gpu, why, sizeof(why)))
				goto fail;
			if (v == 0) {
				measured(s, k_gf, weights_full_error(gpu, npix), NULL);
			} else {
				double ao, cd;
				weights_edge_error(gpu, npix, &ao, &cd);
				measured(s, k_ga, ao, NULL);
				measured(s, k_gc, cd, NULL);
			}
			gpu_shot_close(sh);
			sh = NULL;
			free(gpu);
			gpu = NULL;
		} else if (v == 0) {
			skipped(s, k_gf, "no GPU context");
			skipped(s, k_ga, "no GPU context");
			skipped(s, k_gc, "no GPU context");
		}
		free(ref);
		ref = NULL;
	}
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	gpu_shot_close(sh);
	free(ref);
	free(gpu);
}

/* ---- half ---- */

/*
 * The largest "half_max_relative_error" the bake recorded over the shot's
 * surface shaders (shot metadata: surfaces[].channels), or NAN with the
 * reason in @why.
 */
static double recorded_half_bound(const char *shot, char *why, size_t wlen)
{
	char err[256];
	struct shot_file *f = shot_read_header(shot, err, sizeof(err));
	if (!f) {
		snprintf(why, wlen, "%s", err);
		return NAN;
	}
	double bound = NAN;
	cJSON *meta = cJSON_Parse(f->metadata ? f->metadata : "");
	const cJSON *srf;
	cJSON_ArrayForEach(srf, cJSON_GetObjectItemCaseSensitive(meta, "surfaces")) {
		const cJSON *ch = cJSON_GetObjectItemCaseSensitive(srf, "channels");
		const cJSON *e = cJSON_GetObjectItemCaseSensitive(ch, "half_max_relative_error");
		if (cJSON_IsNumber(e))
			bound = isnan(bound) ? e->valuedouble : fmax(bound, e->valuedouble);
	}
	if (isnan(bound))
		snprintf(why, wlen, "%s: no half error recorded in the metadata", shot);
	cJSON_Delete(meta);
	shot_free(f);
	return bound;
}

/* The final level of @shot, on the GPU when there is one, else the CPU resolver. */
static float *half_preview(struct suite *s, const char *shot, uint32_t W, uint32_t H, char *why,
			   size_t wlen)
{
	if (!s->o->ctx)
		return cpu_image(s, shot, RESOLVE_FINAL, NULL, 0, W, H, why, wlen);
	struct gpu_shot *sh = gpu_open(s, shot, W, H, why, wlen);
	float *img = sh ? calloc((size_t)W * H * 4, sizeof(float)) : NULL;
	if (sh && !img)
		snprintf(why, wlen, "out of memory");
	if (img && !gpu_image(sh, GPU_SHOT_FINAL, img, why, wlen)) {
		free(img);
		img = NULL;
	}
	gpu_shot_close(sh);
	return img;
}

static void case_half(struct suite *s)
{
	const char *G = "half";
	const int first = s->n;
	const uint32_t W = s->o->quick ? 128 : 256, H = s->o->quick ? 72 : 144;
	/* rounding to the nearest half is never more than 2^-11 relative off */
	const int k_bound = check(s, G, "largest channel rounding the bake records", 0x1p-11);
	const int k_rel = check(s, G, "preview, half vs float bake: max relative", NAN);
	const int k_mean = check(s, G, "preview, half vs float bake: mean 8-bit error %",
				 STAB_HALF_MEAN_PCT);
	const int k_max = check(s, G, "preview, half vs float bake: max 8-bit error %",
				STAB_HALF_MAX_PCT);
	char why[WHY_LEN], rib[512], shot_h[512], shot_f[512];
	float *ih = NULL, *iff = NULL;
	struct rl_strbuf t = { 0 };
	rl_strbuf_printf(&t,
		"Format %u %u 1\nPixelSamples 2 2\nProjection \"perspective\" \"fov\" 35\n"
		"Display \"%s/stab-half.exr\" \"file\" \"rgba\"\n"
		"Translate 0 -0.6 4\nRotate -18 1 0 0\nWorldBegin\n"
		"  LightSource \"spotlight\" \"spot\" \"intensity\" 18 \"from\" [2 4 -1]"
		" \"to\" [0 0 0.5] \"coneangle\" 0.5 \"conedeltaangle\" 0.1\n"
		"  LightSource \"pointlight\" \"point\" \"intensity\" 2"
		" \"lightcolor\" [1 0.8 0.6] \"from\" [-1.5 1.5 0]\n"
		"  AttributeBegin\n"
		"    Surface \"matte\"\n    Color [0.7 0.7 0.6]\n"
		"    Polygon \"P\" [-4 0 -3  -4 0 6  4 0 6  4 0 -3]\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Surface \"plastic\" \"Ks\" 0.6\n    Color [0.8 0.2 0.15]\n"
		"    Translate 0 0.6 0.5\n    Sphere 0.6 -0.6 0.6 360\n"
		"  AttributeEnd\n"
		"WorldEnd\n",
		W, H, s->o->workdir);
	bool ok = write_rib(s, "stab-half", rl_strbuf_str(&t), rib, sizeof(rib), why, sizeof(why));
	rl_strbuf_finish(&t);
	say(s, "half: baking %ux%u with half channels and in float, previewing both on the %s", W,
	    H, s->o->ctx ? "GPU" : "CPU resolver (no GPU)");
	if (!ok || !bake(s, "stab-half", rib, false, shot_h, sizeof(shot_h), why, sizeof(why)) ||
	    !bake(s, "stab-half-float", rib, true, shot_f, sizeof(shot_f), why, sizeof(why)))
		goto fail;
	double bound = recorded_half_bound(shot_h, why, sizeof(why));
	if (isnan(bound))
		goto fail;
	measured(s, k_bound, bound, NULL);
	if (k_rel >= 0)
		s->out[k_rel].limit = bound * STAB_HALF_BOUND_FACTOR;
	if (!(ih = half_preview(s, shot_h, W, H, why, sizeof(why))) ||
	    !(iff = half_preview(s, shot_f, W, H, why, sizeof(why))))
		goto fail;
	size_t npix = (size_t)W * H, at = 0;
	if (!(mean_rgb(iff, npix) > 0.01)) {
		snprintf(why, sizeof(why), "the scene renders black: nothing to measure");
		goto fail;
	}
	double r = max_rel(ih, iff, npix, 4, STAB_HALF_FLOOR, &at);
	measured(s, k_rel, r, "limit: the bound x %g; worst at (%zu, %zu)%s",
		 STAB_HALF_BOUND_FACTOR, at % W, at / W, s->o->ctx ? "" : "; CPU resolver");
	struct img_error e;
	img_error_rgba(ih, iff, W, H, NULL, &e);
	measured(s, k_mean, img_error_mean_pct(&e), NULL);
	measured(s, k_max, img_error_max_pct(&e), "at (%u, %u)", e.max_x, e.max_y);
	goto done;
fail:
	fail_pending(s, first, "%s", why);
done:
	free(ih);
	free(iff);
}

/* ---- the suite ---- */

/* Whether @group is in the comma-separated list @only (NULL: all are). */
static bool wanted(const char *only, const char *group)
{
	if (!only)
		return true;
	size_t n = strlen(group);
	for (const char *p = only; *p;) {
		const char *e = strchr(p, ',');
		size_t len = e ? (size_t)(e - p) : strlen(p);
		if (len == n && !strncmp(p, group, n))
			return true;
		if (!e)
			break;
		p = e + 1;
	}
	return false;
}

/* Every name in @only is a group: false with the first that is not in @err. */
static bool only_valid(const char *only, char *err, size_t errlen)
{
	for (const char *p = only; p && *p;) {
		const char *e = strchr(p, ',');
		size_t len = e ? (size_t)(e - p) : strlen(p);
		bool known = false;
		for (size_t g = 0; g < NGROUPS && !known; g++)
			known = strlen(groups[g]) == len && !strncmp(p, groups[g], len);
		if (!known) {
			snprintf(err, errlen,
				 "unknown stability case '%.*s' (drift, hdr, degenerate, "
				 "transparency, weights, half)", (int)(len < 40 ? len : 40), p);
			return false;
		}
		if (!e)
			break;
		p = e + 1;
	}
	return true;
}

int stab_run(const struct stab_opts *o, struct stab_check *out, int cap, char *err,
	     size_t errlen)
{
	if (!o || !o->workdir || !*o->workdir || (cap > 0 && !out) || cap < 0) {
		snprintf(err, errlen, "stab_run: no work folder or no room for the checks");
		return -1;
	}
	/* Scenes name their images by absolute path inside RIB strings. */
	if (strpbrk(o->workdir, "\"\\\n")) {
		snprintf(err, errlen, "the work folder '%s' has a quote, backslash or newline in "
			 "its name", o->workdir);
		return -1;
	}
	if (!only_valid(o->only, err, errlen))
		return -1;
	if (access(o->workdir, W_OK | X_OK) != 0) {
		snprintf(err, errlen, "cannot write to the work folder '%s': %s", o->workdir,
			 strerror(errno));
		return -1;
	}
	struct suite s = {
		.o = o,
		.log = o->log ? o->log : stderr,
		.out = out,
		.cap = cap,
		.pending = calloc((size_t)cap + 1, sizeof(bool)),
	};
	if (!s.pending) {
		snprintf(err, errlen, "out of memory");
		return -1;
	}
	const char *env = getenv("RELIGHT_SHADER_PATH");
	s.shader_path = env && *env ? env : NULL;
	static void (*const cases[NGROUPS])(struct suite *) = {
		case_drift, case_hdr, case_degenerate, case_transparency, case_weights, case_half,
	};
	say(&s, "%s mode%s", o->quick ? "quick" : "full", o->ctx ? "" : ", no GPU: GPU checks skipped");
	double t0 = now_s();
	for (size_t g = 0; g < NGROUPS; g++) {
		if (!wanted(o->only, groups[g]))
			continue;
		double t = now_s();
		int from = s.n;
		cases[g](&s);
		/* A check a case declared and left unmeasured is a fault of the case. */
		fail_pending(&s, from, "not measured");
		int fails = 0;
		for (int k = from; k < s.n; k++)
			fails += out[k].verdict == STAB_FAIL;
		say(&s, "%s: %d checks, %d failed, %.1f s", groups[g], s.n - from, fails,
		    now_s() - t);
	}
	if (s.dropped)
		say(&s, "%d checks left out: room for %d", s.dropped, cap);
	say(&s, "done in %.1f s", now_s() - t0);
	free(s.pending);
	return s.n;
}

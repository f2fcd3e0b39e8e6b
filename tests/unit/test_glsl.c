/*
 * The GLSL generator against the grid interpreter, its reference: each
 * shader runs on the interpreter (lights through lighthost.h) over random
 * points, normals and parameters (fixed seed; a 1D grid, so no derivatives
 * are in play), and as generated GLSL over the same points with the
 * interpreter's globals as inputs; the results must agree within a stated
 * tolerance. Every emitted program also passes glslangValidator, and every
 * error path gives its "FILE:LINE:COL: error:" message.
 *
 * Differences are measured as |gpu - cpu| / max(1, |cpu|): relative above
 * 1, absolute below (colours are mostly in [0, 1]). The default tolerance
 * is 1e-4; looser ones are justified where they are used.
 *
 * Without an EGL context the cross-checks are skipped (exit 77) after the
 * generator-only tests have run.
 */
#include "glsl.h"
#include "clock.h"
#include "strbuf.h"
#include "spec.h"
#include "gpu.h"
#include "exec.h"
#include "lighthost.h"
#include "mathlib.h"
#include "sl.h"
#include "test.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define NPTS 256
#define MAXL 12
#define TOL 1e-4

static struct gpu_ctx *ctx;
static bool have_validator = true;

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */

static uint32_t rng_state = 12345u;

static void rng_seed(uint32_t s)
{
	rng_state = s ? s : 1u;
}

/* Uniform in [lo, hi) (xorshift32). */
static float rnd(float lo, float hi)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 17;
	rng_state ^= rng_state << 5;
	return lo + (hi - lo) * (float)(rng_state >> 8) * (1.0f / 16777216.0f);
}

static struct sl_program *compile(const char *name, const char *src)
{
	struct sl_program *p = sl_compile_string(name, src, strlen(src), NULL);
	if (!p)
		fprintf(stderr, "cannot compile %s:\n%s\n", name, src);
	return p;
}

static struct sl_program *load(const char *name)
{
	const char *dir = getenv("RELIGHT_SOURCE_DIR");
	char path[1024];
	snprintf(path, sizeof(path), "%s/shaders/%s.sl", dir ? dir : ".", name);
	struct sl_program *p = sl_compile_file(path, NULL);
	if (!p)
		fprintf(stderr, "cannot compile %s\n", path);
	return p;
}

/* Validate @src offline: it must pass (when glslangValidator is there at all). */
/* The first identifier of @src, outside comments, holding "__" (GLSL reserves
 * those names: NVIDIA's compiler refuses them where Mesa's accepts them). */
static const char *reserved_name(const char *src)
{
	for (const char *c = src; *c; c++) {
		if (c[0] == '/' && c[1] == '/') {
			while (*c && *c != '\n')
				c++;
			if (!*c)
				break;
		} else if (c[0] == '/' && c[1] == '*') {
			const char *e = strstr(c + 2, "*/");
			if (!e)
				break;
			c = e + 1;
		} else if (c[0] == '_' && c[1] == '_') {
			return c;
		}
	}
	return NULL;
}

static void check_valid(const char *what, const char *src)
{
	const char *rsv = reserved_name(src);
	if (rsv)
		fprintf(stderr, "%s: generated GLSL has a reserved name near '%.24s'\n", what, rsv);
	CHECK(rsv == NULL);
	int v = gpu_validate_glsl(src, stderr);
	if (v < 0) {
		if (have_validator)
			fprintf(stderr, "WARNING: glslangValidator is missing: generated GLSL is "
				"not validated offline\n");
		have_validator = false;
		return;
	}
	if (v != 1)
		fprintf(stderr, "%s: generated GLSL fails glslangValidator\n", what);
	CHECK(v == 1);
}

/* ------------------------------------------------------------------------ */
/* Coordinate systems of the test scene                                      */

/* A rotation about a unit axis and a translation, in RenderMan's row-vector form. */
static void rigid(float m[16], float ax, float ay, float az, float angle, float tx, float ty,
		  float tz, float scale)
{
	float l = sqrtf(ax * ax + ay * ay + az * az);
	float x = ax / l, y = ay / l, z = az / l, c = cosf(angle), s = sinf(angle), t = 1 - c;
	float r[16] = {
		t * x * x + c, t * x * y + s * z, t * x * z - s * y, 0,
		t * x * y - s * z, t * y * y + c, t * y * z + s * x, 0,
		t * x * z + s * y, t * y * z - s * x, t * z * z + c, 0,
		tx, ty, tz, 1,
	};
	for (int i = 0; i < 12; i++)
		r[i] *= scale;
	memcpy(m, r, sizeof(r));
}

static const char *const space_names[] = { "shader", "world", "object" };
static float space_mats[3][16];
static float light_mats[MAXL][16];

static void init_spaces(void)
{
	rigid(space_mats[0], 1, 2, 3, 0.7f, 0.5f, -0.25f, 1.0f, 1.0f);
	rigid(space_mats[1], -1, 0.5f, 0.2f, 1.9f, 2, 1, -3, 1.0f);
	rigid(space_mats[2], 0.3f, 1, -0.4f, -0.6f, -1, 0.5f, 0.25f, 1.5f);
	for (int k = 0; k < MAXL; k++)
		rigid(light_mats[k], 0.2f + (float)k, 1, 0.5f, 0.3f * (float)k - 0.4f, 0.1f * (float)k,
		      -0.2f, 0.3f, 1.0f);
}

/* A host that only answers coordinate systems, with @shader as "shader". */
struct space_host {
	struct sl_host host;
	const float *shader;
};

static bool sh_space(void *user, const char *name, float m[16])
{
	const struct space_host *h = user;
	if (!strcmp(name, "shader") && h->shader) {
		memcpy(m, h->shader, 16 * sizeof(float));
		return true;
	}
	for (int k = 1; k < 3; k++)
		if (!strcmp(name, space_names[k])) {
			memcpy(m, space_mats[k], 16 * sizeof(float));
			return true;
		}
	return false;
}

/* ------------------------------------------------------------------------ */
/* One cross-check: a surface and its lights, on the interpreter and the GPU */

struct xc {
	const char *name;
	uint32_t n;
	int nl;
	struct sl_program *prog[1 + MAXL];     /* surface, then lights */
	struct sl_program init[1 + MAXL];      /* the same, cut before the body */
	struct sl_exec *x[1 + MAXL];
	struct sl_exec *ix[1 + MAXL];          /* runs only the parameter defaults */
	float *glob[SL_GLOBAL_COUNT];          /* the surface's inputs, planar, n points */
	double cpu_ms, gpu_ms, compile_ms;
	size_t src_len;
};

/* Globals the interpreter sets itself for a surface: not inputs. An
 * imager's Ci and Oi are the pixel's: inputs (see xc_init). */
static bool computed_global(int g)
{
	return g == SL_GLOBAL_CI || g == SL_GLOBAL_OI || g == SL_GLOBAL_L || g == SL_GLOBAL_CL ||
	       g == SL_GLOBAL_OL;
}

static void xc_add(struct xc *c, struct sl_program *p)
{
	int i = c->nl < 0 ? 0 : 1 + c->nl;
	c->prog[i] = p;
	c->init[i] = *p;
	c->init[i].ncode = p->body_begin;
	c->x[i] = sl_exec_create(p, c->n);
	c->ix[i] = sl_exec_create(&c->init[i], 1);
	CHECK(c->x[i] && c->ix[i]);
	c->nl++;
}

/* A cross-check of @surf over @n points; add lights with xc_add. */
static void xc_init(struct xc *c, const char *name, struct sl_program *surf, uint32_t n)
{
	memset(c, 0, sizeof(*c));
	c->name = name;
	c->n = n;
	c->nl = -1;
	xc_add(c, surf);
	/* Inputs: random, the same recipe for every shader. */
	rng_seed(0x5eed1234u ^ n);
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool imager_input = surf->kind == SL_SHADER_IMAGER &&
				    (g == SL_GLOBAL_CI || g == SL_GLOBAL_OI);
		if (surf->global_reg[g] < 0 || (computed_global(g) && !imager_input))
			continue;
		bool vary = surf->regs[surf->global_reg[g]].varying;
		int nc = sl_reg_ncomp(&surf->regs[surf->global_reg[g]]);
		float *v = calloc((size_t)nc * n, sizeof(float));
		for (uint32_t i = 0; i < n; i++) {
			float r[3];
			if (vary || i == 0) {
				switch (g) {
				case SL_GLOBAL_P: case SL_GLOBAL_I:
					r[0] = rnd(-1, 1);
					r[1] = rnd(-1, 1);
					r[2] = rnd(2, 4);
					break;
				case SL_GLOBAL_E: case SL_GLOBAL_TIME: case SL_GLOBAL_DTIME:
				case SL_GLOBAL_DPDTIME:
					r[0] = r[1] = r[2] = 0;
					break;
				case SL_GLOBAL_DU: case SL_GLOBAL_DV:
					r[0] = r[1] = r[2] = 1.0f / (float)(n - 1);
					break;
				case SL_GLOBAL_CS: case SL_GLOBAL_OS:
					r[0] = rnd(0.2f, 1);
					r[1] = rnd(0.2f, 1);
					r[2] = rnd(0.2f, 1);
					break;
				case SL_GLOBAL_NCOMPS:
					r[0] = 3;
					break;
				default:
					r[0] = rnd(-1, 1);
					r[1] = rnd(-1, 1);
					r[2] = rnd(-1, 1);
					if (g == SL_GLOBAL_S || g == SL_GLOBAL_T || g == SL_GLOBAL_U ||
					    g == SL_GLOBAL_V)
						r[0] = rnd(0, 1);
					break;
				}
				/* The shading point's position is where the eye looks: I = P - E. */
				if (g == SL_GLOBAL_I && c->glob[SL_GLOBAL_P])
					for (int k = 0; k < 3; k++)
						r[k] = c->glob[SL_GLOBAL_P][(size_t)k * n + i];
			} else {
				for (int k = 0; k < nc; k++)
					r[k] = v[(size_t)k * n];
			}
			for (int k = 0; k < nc; k++)
				v[(size_t)k * n + i] = r[k];
		}
		c->glob[g] = v;
	}
}

static void xc_free(struct xc *c)
{
	for (int i = 0; i <= c->nl; i++) {
		sl_exec_destroy(c->x[i]);
		sl_exec_destroy(c->ix[i]);
	}
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		free(c->glob[g]);
}

/* Set parameter @name of program @i (0 surface, 1 + k light k) on both executors. */
static void xc_set(struct xc *c, int i, const char *name, const float *v, uint32_t nv)
{
	CHECK(sl_exec_set_param(c->x[i], name, v, nv));
	CHECK(sl_exec_set_param(c->ix[i], name, v, nv));
}

static void xc_setf(struct xc *c, int i, const char *name, float f)
{
	xc_set(c, i, name, &f, 1);
}

static void xc_set3(struct xc *c, int i, const char *name, float a, float b, float d)
{
	float v[3] = { a, b, d };
	xc_set(c, i, name, v, 3);
}

static void xc_sets(struct xc *c, int i, const char *name, const char *s)
{
	CHECK(sl_exec_set_param_string(c->x[i], name, s));
	CHECK(sl_exec_set_param_string(c->ix[i], name, s));
}

/* printf() output of the interpreter's runs: not wanted in the test log. */
static void quiet_print(void *user, const char *text)
{
	(void)user;
	(void)text;
}

/* The interpreter's run; false on a run-time error. */
static bool xc_cpu(struct xc *c)
{
	struct sl_program *surf = c->prog[0];
	struct sl_exec *x = c->x[0];
	CHECK(sl_exec_set_grid(x, c->n, 1));
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		if (!c->glob[g])
			continue;
		bool vary;
		float *d = sl_exec_global(x, g, &vary);
		int nc = sl_reg_ncomp(&surf->regs[surf->global_reg[g]]);
		for (int k = 0; k < nc; k++)
			for (uint32_t i = 0; i < (vary ? c->n : 1); i++)
				d[(size_t)k * (vary ? sl_exec_stride(x) : 1) + i] =
					c->glob[g][(size_t)k * c->n + i];
	}
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, c->x + 1, c->nl);
	lh.host.print = quiet_print;
	lh.space_names = space_names;
	lh.space_mats = (const float (*)[16])space_mats;
	lh.nspaces = 3;
	lh.light_shader_mats = (const float (*)[16])light_mats;
	double t0 = rl_now_ms();
	bool ok = sl_exec_run(x, &lh.host);
	c->cpu_ms = rl_now_ms() - t0;
	/* The parameters' values at the start of a run, for the uniforms. */
	for (int i = 0; i <= c->nl; i++) {
		struct space_host sh = { .host = { .space = sh_space }, .shader = NULL };
		sh.host.user = &sh;
		sh.shader = i == 0 ? space_mats[0] : light_mats[i - 1];
		ok = sl_exec_run(c->ix[i], &sh.host) && ok;
	}
	return ok;
}

/* A string's token id in @lay (an id past the table for strings it does not hold). */
static float string_id(const struct sl_glsl_layout *lay, const char *s)
{
	for (uint32_t i = 0; i < lay->nstrings; i++)
		if (!strcmp(lay->strings[i], s))
			return (float)i;
	return (float)lay->nstrings + 7.0f;
}

/* Set the uniforms of program @i's parameters from its defaults run. */
static void set_param_uniforms(struct xc *c, int i, struct gpu_program *gp,
			       const struct sl_glsl_layout *lay, const uint8_t *skip)
{
	const struct sl_program *p = c->prog[i];
	for (uint32_t k = 0; k < p->nparams; k++) {
		int32_t r = p->params[k].reg;
		const struct sl_reg *rg = &p->regs[r];
		if (skip && skip[r])
			continue;
		char name[300];
		if (i == 0)
			sl_glsl_param_uniform(name, sizeof(name), -1, p->params[k].name);
		else
			sl_glsl_param_uniform(name, sizeof(name), i - 1, p->params[k].name);
		uint32_t ne = rg->arraylen > 0 ? (uint32_t)rg->arraylen : 1;
		uint32_t stride = rg->varying ? sl_exec_stride(c->ix[i]) : 1;
		if (rg->type == SL_TYPE_STRING) {
			const char **s = sl_exec_reg_strings(c->ix[i], r);
			float ids[64];
			for (uint32_t e = 0; e < ne && e < 64; e++)
				ids[e] = string_id(lay, s[e * stride] ? s[e * stride] : "");
			gpu_uniform_float(gp, name, ids, (int)(ne < 64 ? ne : 64));
			continue;
		}
		int nc = sl_reg_ncomp(rg);
		const float *d = sl_exec_reg(c->ix[i], r);
		float v[1024];
		uint32_t tot = ne * (uint32_t)nc;
		if (tot > 1024)
			continue;
		for (uint32_t q = 0; q < tot; q++)
			v[q] = d[q * stride];
		if (nc == 16 && ne == 1)
			gpu_uniform_mat4(gp, name, v);
		else
			gpu_uniform_float(gp, name, v, (int)tot);
	}
}

/* Output @name of the surface: a global ("Ci") or an output parameter. */
static int32_t output_reg(const struct sl_program *p, const char *name)
{
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		if (!strcmp(sl_global_name(g), name))
			return p->global_reg[g];
	int k = sl_program_find_param(p, name);
	return k >= 0 ? p->params[k].reg : -1;
}

/*
 * Per-light passes (sl_slice.per_light): when set, xc_gpu emits one pass per
 * light and compares pass k with pass_ref[k], the same surface lit by light
 * k alone, run on the interpreter.
 */
static struct xc *pass_ref[MAXL];

/*
 * Emit the surface with its lights, run it on the GPU over the same inputs
 * and compare @outs with the interpreter's. Returns the largest difference
 * (negative when the GPU part could not run).
 */
static double xc_gpu(struct xc *c, const char *const *outs, int nouts, double tol)
{
	bool passes = pass_ref[0] != NULL;
	uint32_t npass = passes ? (uint32_t)c->nl : 1;
	const struct sl_program *surf = c->prog[0];
	int32_t inputs[SL_GLOBAL_COUNT], outputs[32];
	uint32_t nin = 0;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		if (c->glob[g])
			inputs[nin++] = surf->global_reg[g];
	for (int k = 0; k < nouts; k++) {
		outputs[k] = output_reg(surf, outs[k]);
		CHECK(outputs[k] >= 0);
		if (outputs[k] < 0)
			return -1;
	}
	struct sl_slice slice = { surf, NULL, inputs, nin, outputs, (uint32_t)nouts };
	slice.per_light = passes;
	struct sl_glsl_layout lay;
	const struct sl_program *lights[MAXL];
	for (int k = 0; k < c->nl; k++)
		lights[k] = c->prog[1 + k];
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	char *src = sl_glsl_emit(&slice, lights, (uint32_t)c->nl, &lay, diag);
	fclose(diag);
	CHECK(src != NULL);
	if (!src)
		fprintf(stderr, "%s: no GLSL:\n%s", c->name, dbuf ? dbuf : "");
	free(dbuf);
	if (!src)
		return -1;
	c->src_len = strlen(src);
	check_valid(c->name, src);
	double maxerr = -1;
	if (!ctx)
		goto out;
	double t0 = rl_now_ms();
	struct gpu_program *gp = gpu_program(ctx, src, stderr);
	c->compile_ms = rl_now_ms() - t0;
	CHECK(gp != NULL);
	if (!gp)
		goto out;
	uint8_t *is_input = calloc(surf->nregs + 1, 1);
	for (uint32_t i = 0; i < nin; i++)
		is_input[inputs[i]] = 1;
	for (int i = 0; i <= c->nl; i++)
		set_param_uniforms(c, i, gp, &lay, i == 0 ? is_input : NULL);
	free(is_input);
	for (int k = 0; k < c->nl; k++) {
		char name[32];
		snprintf(name, sizeof(name), "l%d_shader", k);
		gpu_uniform_mat4(gp, name, light_mats[k]);
	}
	for (int k = 0; k < 3; k++) {
		char name[32];
		snprintf(name, sizeof(name), "space_%s", space_names[k]);
		gpu_uniform_mat4(gp, name, space_mats[k]);
	}
	/* Inputs, in the layout's order. */
	uint32_t n = c->n, is = lay.in_stride ? lay.in_stride : 1, os = lay.out_stride;
	float *in = calloc((size_t)n * is, sizeof(float));
	for (uint32_t j = 0; j < nin; j++) {
		int g = surf->regs[inputs[j]].global;
		int nc = sl_reg_ncomp(&surf->regs[inputs[j]]);
		for (uint32_t i = 0; i < n; i++)
			for (int k = 0; k < nc; k++)
				in[(size_t)i * is + lay.in_offset[j] + (uint32_t)k] =
					c->glob[g][(size_t)k * n + i];
	}
	struct gpu_buffer *bin = gpu_buffer_create(ctx, (size_t)n * is * sizeof(float), in);
	size_t nout = (size_t)n * npass * (os ? os : 1);
	struct gpu_buffer *bout = gpu_buffer_create(ctx, nout * sizeof(float), NULL);
	float *out = calloc(nout, sizeof(float));
	struct gpu_binding b[2] = { { 0, false, bin, true }, { 1, true, bout } };
	CHECK(gpu_dispatch(ctx, gp, b, 2, n));
	t0 = rl_now_ms();
	CHECK(gpu_dispatch(ctx, gp, b, 2, n));
	CHECK(gpu_buffer_read(bout, 0, nout * sizeof(float), out));
	c->gpu_ms = rl_now_ms() - t0;
	maxerr = 0;
	int reported = 0;
	for (int kp = 0; kp < nouts * (int)npass; kp++) {
		int k = kp % nouts;
		uint32_t pass = (uint32_t)kp / (uint32_t)nouts;
		struct sl_exec *x = passes ? pass_ref[pass]->x[0] : c->x[0];
		double kerr = 0;
		int32_t r = outputs[k];
		const struct sl_reg *rg = &surf->regs[r];
		int nc = sl_reg_ncomp(rg) * (rg->arraylen > 0 ? rg->arraylen : 1);
		bool vary = rg->varying;
		const float *d = sl_exec_reg(x, r);
		for (uint32_t i = 0; i < n; i++)
			for (int q = 0; q < nc; q++) {
				float cpu = d[(size_t)q * (vary ? sl_exec_stride(x) : 1) +
					      (vary ? i : 0)];
				float gpu = out[((size_t)i * npass + pass) * os + lay.out_offset[k] +
						(uint32_t)q];
				double e = fabs((double)gpu - cpu) / fmax(1.0, fabs((double)cpu));
				if (!(e <= tol) && reported++ < 8)
					fprintf(stderr, "%s: %s[%d] at point %u (pass %u): gpu %.9g cpu %.9g\n",
						c->name, outs[k], q, i, pass, gpu, cpu);
				if (!(e <= maxerr))
					maxerr = e;
				if (!(e <= kerr))
					kerr = e;
			}
		if (!(kerr <= tol))
			fprintf(stderr, "%s: output %s differs by up to %.3g\n", c->name, outs[k], kerr);
	}
	CHECK(maxerr <= tol);
	printf("%-34s max diff %.2e (tol %.0e)  cpu %7.3f ms  gpu %7.3f ms  compile %6.0f ms  "
	       "%zu bytes of GLSL\n", c->name, maxerr, tol, c->cpu_ms, c->gpu_ms, c->compile_ms,
	       c->src_len);
	free(in);
	free(out);
	gpu_buffer_destroy(bin);
	gpu_buffer_destroy(bout);
out:
	free(src);
	sl_glsl_layout_finish(&lay);
	return maxerr;
}

/* Run @c both ways and compare @outs. */
static double xc_check(struct xc *c, const char *const *outs, int nouts, double tol)
{
	CHECK(xc_cpu(c));
	return xc_gpu(c, outs, nouts, tol);
}

static const char *const ci_oi[] = { "Ci", "Oi" };

/* Compile @src, cross-check its outputs @outs with no lights, free it. */
static double check_source(const char *name, const char *src, const char *const *outs,
			   int nouts, double tol)
{
	struct sl_program *p = compile(name, src);
	CHECK(p != NULL);
	if (!p)
		return -1;
	struct xc c;
	xc_init(&c, name, p, NPTS);
	double e = xc_check(&c, outs, nouts, tol);
	xc_free(&c);
	sl_program_destroy(p);
	return e;
}

/* ------------------------------------------------------------------------ */
/* The shader library                                                        */

/*
 * Parameters that aim program @i (1 + the light's index), a light shader of
 * shaders/ named @name, at the test points, which lie around (0, 0, 3).
 * Positions are in the light's "shader" space.
 */
static void aim_light(struct xc *c, int i, const char *name)
{
	if (!strcmp(name, "pointlight") || !strcmp(name, "spotlight") ||
	    !strcmp(name, "shadowspot")) {
		xc_set3(c, i, "from", 0.5f, 1.5f, 0.5f);
		xc_setf(c, i, "intensity", 6);
		xc_set3(c, i, "lightcolor", 1, 0.8f, 0.6f);
	}
	if (!strcmp(name, "spotlight") || !strcmp(name, "shadowspot")) {
		xc_set3(c, i, "to", 0, -0.5f, 3.5f);
		xc_setf(c, i, "coneangle", 0.6f);
		xc_setf(c, i, "conedeltaangle", 0.2f);
	}
	if (!strcmp(name, "distantlight")) {
		xc_set3(c, i, "from", 0, 0, 0);
		xc_set3(c, i, "to", 0.3f, -0.4f, 1);
		xc_setf(c, i, "intensity", 0.9f);
	}
	if (!strcmp(name, "ambientlight"))
		xc_setf(c, i, "intensity", 0.15f);
	if (!strcmp(name, "uberlight")) {
		xc_setf(c, i, "intensity", 3);
		xc_setf(c, i, "falloff", 1);
		xc_setf(c, i, "beamdistribution", 1.5f);
		xc_setf(c, i, "width", 3);
		xc_setf(c, i, "height", 2.5f);
		xc_setf(c, i, "wedge", 1);
		xc_setf(c, i, "hedge", 1);
		xc_setf(c, i, "roundness", 0.7f);
		xc_setf(c, i, "barnleft", 1.5f);
		xc_setf(c, i, "barnedge", 0.5f);
		xc_setf(c, i, "nearedge", 0.5f);
		xc_setf(c, i, "cutoff", 10);
		xc_setf(c, i, "faredge", 2);
	}
}

/* Random values in [0.05, 1) for the float and color parameters of program @i. */
static void randomize_params(struct xc *c, int i)
{
	const struct sl_program *p = c->prog[i];
	for (uint32_t k = 0; k < p->nparams; k++) {
		const struct sl_reg *rg = &p->regs[p->params[k].reg];
		if (p->params[k].output || rg->arraylen || p->params[k].name[0] == '_')
			continue;
		if (rg->type == SL_TYPE_FLOAT)
			xc_setf(c, i, p->params[k].name, rnd(0.05f, 1));
		else if (rg->type == SL_TYPE_COLOR)
			xc_set3(c, i, p->params[k].name, rnd(0.05f, 1), rnd(0.05f, 1), rnd(0.05f, 1));
	}
}

static const char *const surfaces[] = {
	"constant", "defaultsurface", "matte", "metal", "plastic", "paintedplastic", "shinymetal",
};
static const char *const lightnames[] = {
	"ambientlight", "distantlight", "pointlight", "spotlight", "shadowspot", "uberlight",
	"envlight",
};
#define NSURF (sizeof(surfaces) / sizeof(surfaces[0]))
#define NLIGHT (sizeof(lightnames) / sizeof(lightnames[0]))

/* Every surface of shaders/ lit by all the light shaders of shaders/ at once. */
static void test_library_surfaces(void)
{
	struct sl_program *lp[NLIGHT];
	for (size_t k = 0; k < NLIGHT; k++)
		lp[k] = load(lightnames[k]);
	for (size_t s = 0; s < NSURF; s++) {
		struct sl_program *sp = load(surfaces[s]);
		CHECK(sp != NULL);
		if (!sp)
			continue;
		struct xc c;
		char name[64];
		snprintf(name, sizeof(name), "%s + all lights", surfaces[s]);
		xc_init(&c, name, sp, NPTS);
		randomize_params(&c, 0);
		for (size_t k = 0; k < NLIGHT; k++) {
			if (!lp[k])
				continue;
			xc_add(&c, lp[k]);
			aim_light(&c, c.nl, lightnames[k]);
		}
		xc_check(&c, ci_oi, 2, TOL);
		xc_free(&c);
		sl_program_destroy(sp);
	}
	for (size_t k = 0; k < NLIGHT; k++)
		sl_program_destroy(lp[k]);
}

/*
 * The specialized path, as the preview runs it: the surface's caching
 * program on the interpreter computes the cached values; the generated GLSL
 * of its dynamic part reads them on the GPU with the lights. The result must
 * equal the whole shader on the interpreter (within TOL, relative). @dyn:
 * surface parameters marked dynamic besides the lights.
 */
static double xc_specialized(struct xc *c, const char *const *dyn, size_t ndyn)
{
	struct sl_program *surf = c->prog[0];
	double maxerr = -1;
	if (!xc_cpu(c))
		return -1;
	struct sl_spec *sp = sl_specialize(surf, dyn, ndyn, stderr);
	CHECK(sp != NULL);
	if (!sp)
		return -1;
	/* The caching program over the same points, parameters and spaces. */
	uint32_t n = c->n;
	struct sl_exec *ce = sl_exec_create(sp->caching, n);
	CHECK(ce != NULL);
	if (!ce) {
		sl_spec_destroy(sp);
		return -1;
	}
	CHECK(sl_exec_set_grid(ce, n, 1));
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool vary;
		float *d = c->glob[g] ? sl_exec_global(ce, (enum sl_global)g, &vary) : NULL;
		if (!d)
			continue;
		int nc = sl_reg_ncomp(&surf->regs[surf->global_reg[g]]);
		for (int k = 0; k < nc; k++)
			for (uint32_t i = 0; i < (vary ? n : 1); i++)
				d[(size_t)k * (vary ? sl_exec_stride(ce) : 1) + i] =
					c->glob[g][(size_t)k * n + i];
	}
	/* parameter values as the whole shader started with them (floats, colours,
	 * strings: the library's surfaces have no point parameters) */
	for (uint32_t k = 0; k < surf->nparams; k++) {
		int32_t r = surf->params[k].reg;
		const struct sl_reg *rg = &surf->regs[r];
		if (surf->params[k].output || rg->varying || rg->arraylen)
			continue;
		if (rg->type == SL_TYPE_STRING) {
			const char **sv = sl_exec_reg_strings(c->ix[0], r);
			CHECK(sl_exec_set_param_string(ce, surf->params[k].name, sv[0] ? sv[0] : ""));
		} else if (rg->type == SL_TYPE_FLOAT || rg->type == SL_TYPE_COLOR) {
			CHECK(sl_exec_set_param(ce, surf->params[k].name, sl_exec_reg(c->ix[0], r),
						(uint32_t)sl_reg_ncomp(rg)));
		}
	}
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, NULL, 0);
	lh.host.print = quiet_print;
	lh.space_names = space_names;
	lh.space_mats = (const float (*)[16])space_mats;
	lh.nspaces = 3;
	CHECK(sl_exec_run(ce, &lh.host));

	const struct sl_program *lights[MAXL];
	for (int k = 0; k < c->nl; k++)
		lights[k] = c->prog[1 + k];
	struct sl_glsl_layout lay;
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	char *src = sl_glsl_emit(&sp->slice, lights, (uint32_t)c->nl, &lay, diag);
	fclose(diag);
	CHECK(src != NULL);
	if (!src)
		fprintf(stderr, "%s: no GLSL:\n%s", c->name, dbuf ? dbuf : "");
	free(dbuf);
	if (!src || !ctx)
		goto out;
	check_valid(c->name, src);
	struct gpu_program *gp = gpu_program(ctx, src, stderr);
	CHECK(gp != NULL);
	if (!gp)
		goto out;
	uint8_t *is_input = calloc(surf->nregs + 1, 1);
	for (uint32_t i = 0; i < sp->ncached; i++)
		is_input[sp->cached[i]] = 1;
	for (int i = 0; i <= c->nl; i++)
		set_param_uniforms(c, i, gp, &lay, i == 0 ? is_input : NULL);
	free(is_input);
	for (int k = 0; k < c->nl; k++) {
		char name[32];
		snprintf(name, sizeof(name), "l%d_shader", k);
		gpu_uniform_mat4(gp, name, light_mats[k]);
	}
	for (int k = 0; k < 3; k++) {
		char name[32];
		snprintf(name, sizeof(name), "space_%s", space_names[k]);
		gpu_uniform_mat4(gp, name, space_mats[k]);
	}
	/* The cache: each cached register's values from the caching run. */
	uint32_t is = lay.in_stride ? lay.in_stride : 1, os = lay.out_stride ? lay.out_stride : 1;
	float *in = calloc((size_t)n * is, sizeof(float));
	for (uint32_t j = 0; j < sp->ncached; j++) {
		int32_t r = sp->cached[j];
		const struct sl_reg *rg = &surf->regs[r];
		int nc = sl_reg_ncomp(rg) * (rg->arraylen ? rg->arraylen : 1);
		bool vary = rg->varying;
		const float *d = sl_exec_reg(ce, r);
		if (rg->type == SL_TYPE_STRING)
			continue;
		for (uint32_t i = 0; i < n; i++)
			for (int k = 0; k < nc; k++)
				in[(size_t)i * is + lay.in_offset[j] + (uint32_t)k] =
					d[(size_t)k * (vary ? sl_exec_stride(ce) : 1) + (vary ? i : 0)];
	}
	struct gpu_buffer *bin = gpu_buffer_create(ctx, (size_t)n * is * sizeof(float), in);
	struct gpu_buffer *bout = gpu_buffer_create(ctx, (size_t)n * os * sizeof(float), NULL);
	float *out = calloc((size_t)n * os, sizeof(float));
	struct gpu_binding b[2] = { { 0, false, bin, true }, { 1, true, bout } };
	CHECK(gpu_dispatch(ctx, gp, b, 2, n));
	CHECK(gpu_buffer_read(bout, 0, (size_t)n * os * sizeof(float), out));
	maxerr = 0;
	int reported = 0;
	for (uint32_t k = 0; k < sp->slice.noutputs; k++) {
		int32_t r = sp->slice.outputs[k];
		const struct sl_reg *rg = &surf->regs[r];
		int nc = sl_reg_ncomp(rg);
		const float *d = sl_exec_reg(c->x[0], r);
		for (uint32_t i = 0; i < n; i++)
			for (int q = 0; q < nc; q++) {
				float cpu = d[(size_t)q * (rg->varying ? sl_exec_stride(c->x[0]) : 1) +
					      (rg->varying ? i : 0)];
				float gpu = out[(size_t)i * os + lay.out_offset[k] + (uint32_t)q];
				double e = fabs((double)gpu - cpu) / fmax(1.0, fabs((double)cpu));
				if (!(e <= TOL) && reported++ < 4)
					fprintf(stderr, "%s: output %u[%d] at %u: gpu %.9g cpu %.9g\n",
						c->name, k, q, i, gpu, cpu);
				if (!(e <= maxerr))
					maxerr = e;
			}
	}
	CHECK(maxerr <= TOL);
	printf("%-44s specialized: %u cached registers, max diff %.2e (tol %.0e)\n", c->name,
	       sp->ncached, maxerr, TOL);
	free(in);
	free(out);
	gpu_buffer_destroy(bin);
	gpu_buffer_destroy(bout);
out:
	free(src);
	if (src)
		sl_glsl_layout_finish(&lay);
	sl_exec_destroy(ce);
	sl_spec_destroy(sp);
	return maxerr;
}

/*
 * Every surface of shaders/ with every light of shaders/, specialized with
 * only the lights dynamic and with a surface parameter dynamic too.
 */
static void test_specialized_library(void)
{
	struct sl_program *lp[NLIGHT];
	for (size_t k = 0; k < NLIGHT; k++)
		lp[k] = load(lightnames[k]);
	for (size_t s = 0; s < NSURF; s++) {
		struct sl_program *sp = load(surfaces[s]);
		if (!sp)
			continue;
		/* the first float parameter, if any, as the user-edited one */
		const char *edit = NULL;
		for (uint32_t k = 0; k < sp->nparams && !edit; k++)
			if (!sp->params[k].output && sp->regs[sp->params[k].reg].type == SL_TYPE_FLOAT)
				edit = sp->params[k].name;
		for (size_t l = 0; l < NLIGHT; l++) {
			if (!lp[l])
				continue;
			for (int d = 0; d < (edit ? 2 : 1); d++) {
				struct xc c;
				char name[96];
				snprintf(name, sizeof(name), "%s + %s%s%s", surfaces[s], lightnames[l],
					 d ? ", dynamic " : "", d ? edit : "");
				xc_init(&c, name, sp, NPTS);
				randomize_params(&c, 0);
				xc_add(&c, lp[l]);
				aim_light(&c, c.nl, lightnames[l]);
				xc_specialized(&c, d ? &edit : NULL, d ? 1 : 0);
				xc_free(&c);
			}
		}
		sl_program_destroy(sp);
	}
	for (size_t k = 0; k < NLIGHT; k++)
		sl_program_destroy(lp[k]);
}

static const char diffuse_src[] =
	"surface difftest() { Ci = diffuse(N); Oi = ambient(); }\n";

/* Each light shader of shaders/ alone, through a surface that is just diffuse(N). */
static void test_library_lights(void)
{
	for (size_t k = 0; k < NLIGHT; k++) {
		struct sl_program *sp = compile("difftest.sl", diffuse_src), *lp = load(lightnames[k]);
		CHECK(sp && lp);
		if (sp && lp) {
			struct xc c;
			char name[64];
			snprintf(name, sizeof(name), "diffuse(N) + %s", lightnames[k]);
			xc_init(&c, name, sp, NPTS);
			xc_add(&c, lp);
			aim_light(&c, 1, lightnames[k]);
			xc_check(&c, ci_oi, 2, TOL);
			xc_free(&c);
		}
		sl_program_destroy(sp);
		sl_program_destroy(lp);
	}
}

/* uberlight's other switches: omni, no falloff, a category, __nondiffuse. */
static void test_uberlight_modes(void)
{
	struct sl_program *sp = load("plastic"), *lp = load("uberlight"), *dp = load("pointlight");
	CHECK(sp && lp && dp);
	if (sp && lp && dp) {
		struct xc c;
		xc_init(&c, "plastic + uberlight omni, flags", sp, NPTS);
		xc_add(&c, lp);
		aim_light(&c, 1, "uberlight");
		xc_sets(&c, 1, "lighttype", "omni");
		xc_setf(&c, 1, "__nondiffuse", 1);
		xc_add(&c, lp);
		aim_light(&c, 2, "uberlight");
		xc_setf(&c, 2, "__nonspecular", 1);
		xc_setf(&c, 2, "roundness", 0);
		xc_add(&c, dp);
		aim_light(&c, 3, "pointlight");
		xc_check(&c, ci_oi, 2, TOL);
		xc_free(&c);
	}
	sl_program_destroy(sp);
	sl_program_destroy(lp);
	sl_program_destroy(dp);
}

/* ------------------------------------------------------------------------ */
/* Control flow                                                              */

static const char flow_src[] =
	"float first_above(float x) {\n"
	"	float i;\n"
	"	for (i = 0; i < 10; i += 1) {\n"
	"		if (i * 0.1 > x) return i;\n"
	"		if (i > 8) return -2;\n"
	"	}\n"
	"	return -1;\n"
	"}\n"
	"float nested(float x) {\n"
	"	float r = 0, i;\n"
	"	if (x < 0.2) return 5;\n"
	"	for (i = 0; i < 3; i += 1) r += first_above(x * i);\n"
	"	return r;\n"
	"}\n"
	"surface flow(float K = 3; output varying float a = 0; output varying float b = 0;\n"
	"	output varying float c = 0; output varying float d = 0)\n"
	"{\n"
	"	float i, j, acc = 0;\n"
	"	for (i = 0; i < 8; i += 1) {\n"
	"		if (u * 8 < i) break;\n"
	"		if (mod(i, 2) == 1) continue;\n"
	"		acc += i * v;\n"
	"	}\n"
	"	a = acc;\n"
	"	acc = 0;\n"
	"	for (i = 0; i < 5; i += 1) {\n"
	"		for (j = 0; j < 5; j += 1) {\n"
	"			if (j > s * 5) continue 2;\n"
	"			if (i + j > t * 8 + K) break 2;\n"
	"			if (j == 3) continue;\n"
	"			acc += 0.1 * j + i;\n"
	"		}\n"
	"		acc += 100;\n"
	"	}\n"
	"	b = acc;\n"
	"	float k = 0;\n"
	"	while (k < s * 10) {\n"
	"		k += 1;\n"
	"		if (k > 7) break;\n"
	"	}\n"
	"	c = k + first_above(u) + nested(v);\n"
	"	if (u > 0.5) {\n"
	"		if (v > 0.5) d = 1; else d = 2;\n"
	"	} else if (v > 0.3) {\n"
	"		d = u > 0.25 ? 3 : 4;\n"
	"	} else {\n"
	"		d = -1;\n"
	"	}\n"
	"	Ci = color(a, b, c) * 0.01;\n"
	"}\n";

static void test_control_flow(void)
{
	static const char *const outs[] = { "a", "b", "c", "d", "Ci" };
	check_source("flow.sl", flow_src, outs, 5, TOL);
}

/* ------------------------------------------------------------------------ */
/* Built-ins, one shader per group                                          */

static const char math_src[] =
	"surface mathtest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0, o9 = 0, o10 = 0, o11 = 0, o12 = 0)\n"
	"{\n"
	"	float x = (u - 0.5) * 4, y = (v - 0.5) * 4, z = s * 3, w = t;\n"
	"	o1 = color(sin(x), cos(y), tan(x * 0.3));\n"
	"	o2 = color(asin(x / 2.5), acos(y / 3), atan(x));\n"
	"	o3 = color(atan(y, x), sinh(x), cosh(y));\n"
	"	o4 = color(tanh(x * 10), pow(z, y), exp(x));\n"
	"	o5 = color(sqrt(x), inversesqrt(z), log(z));\n"
	"	o6 = color(log(z, 2), mod(x, 0.7), abs(x));\n"
	"	o7 = color(sign(x), min(x, y, z), max(x, y));\n"
	"	o8 = color(clamp(x, -1, 1), mix(x, y, w), floor(x * 3));\n"
	"	o9 = color(ceil(y * 3), round(x * 3), step(0.2, x));\n"
	"	o10 = color(smoothstep(-1, 1, x), radians(x * 40), degrees(y));\n"
	"	color c = color(z, w, 0.5);\n"
	"	o11 = pow(c, color(x, y, 2)) + sqrt(color(x, y, z)) + mod(color(x, y, z), 0.3) +\n"
	"	      mix(color(x), color(y), w) + mix(c, color(1, 2, 3), color(w, 1 - w, 0.5));\n"
	"	o12 = clamp(color(x, y, z), color(-1), color(1)) + abs(color(x, y, -z)) +\n"
	"	      floor(color(x, y, z)) + max(color(x), color(y), c) + exp(color(x, y, -z)) +\n"
	"	      asin(x) + acos(y) + log(-z) + pow(-z, 3) + pow(-z, 0.5) + x / (z - z) +\n"
	"	      log(z, -1) + pow(0, y) + smoothstep(w, w, 0.5);\n"
	"	Ci = o1;\n"
	"}\n";

static const char *const o12[] = { "o1", "o2", "o3", "o4", "o5", "o6", "o7", "o8", "o9",
				   "o10", "o11", "o12" };

static void test_math(void)
{
	check_source("math.sl", math_src, o12, 12, TOL);
}

static const char geom_src[] =
	"surface geomtest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0, o9 = 0, o10 = 0, o11 = 0, o12 = 0)\n"
	"{\n"
	"	vector a = vector(u - 0.5, v - 0.5, s), b = vector(t, s - 0.5, 0.5 - u);\n"
	"	point p = P;\n"
	"	o1 = color(length(a), distance(P, point(a)), ptlined(point(0), point(b), P));\n"
	"	o2 = color(normalize(a)) + color(normalize(vector(0))) + color(a . b, 0, 0);\n"
	"	o3 = color(a ^ b) + color(faceforward(a, b)) + color(faceforward(a, b, N));\n"
	"	o4 = color(reflect(a, normalize(b))) + color(refract(normalize(a), normalize(b),\n"
	"		0.7)) + color(refract(normalize(a), normalize(b), 1.6));\n"
	"	float kr, kt;\n"
	"	vector R, T;\n"
	"	fresnel(normalize(a), normalize(b), 0.66, kr, kt);\n"
	"	o5 = color(kr, kt, 0);\n"
	"	fresnel(normalize(a), normalize(b), 1.5, kr, kt, R, T);\n"
	"	o6 = color(kr, kt, 0) + color(R) * 2 + color(T) * 3;\n"
	"	o7 = color(rotate(p, u * 3, point(0, 0, 1), point(b))) +\n"
	"	     specularbrdf(normalize(a), N, normalize(b), 0.2);\n"
	"	o8 = color(xcomp(p), ycomp(p), zcomp(p));\n"
	"	setxcomp(p, u);\n"
	"	setycomp(p, v);\n"
	"	setzcomp(p, 2);\n"
	"	color c = color(u, v, s);\n"
	"	setcomp(c, 1, 5);\n"
	"	setcomp(c, t * 4 - 1, -1);\n"
	"	o9 = color(p) + c + color(comp(c, 0), comp(c, s * 3), comp(c, 7));\n"
	"	o10 = color(a . normalize(b), length(b ^ a), distance(point(a), point(b)));\n"
	"	o11 = color(normalize(N)) + color(normalize(I)) * 0.5;\n"
	"	o12 = color(ptlined(point(0), point(0), P), ptlined(point(a), point(b), point(a)), 0);\n"
	"	Ci = o1;\n"
	"}\n";

static void test_geometry(void)
{
	check_source("geom.sl", geom_src, o12, 12, TOL);
}

static const char xform_src[] =
	"surface xformtest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0, o9 = 0, o10 = 0, o11 = 0, o12 = 0;\n"
	"	matrix M = matrix(1, 0.2, 0, 0, 0.1, 1, 0.3, 0, 0, 0, 2, 0, 1, 2, 3, 1))\n"
	"{\n"
	"	o1 = color(transform(\"shader\", P)) + color(transform(\"world\", \"object\", P));\n"
	"	o2 = color(vtransform(\"world\", I)) + color(ntransform(\"object\", N));\n"
	"	o3 = color(transform(\"current\", P)) + color(transform(\"shader\", \"current\", P)) +\n"
	"	     color(vtransform(\"object\", \"world\", vector(N)));\n"
	"	o4 = color(transform(M, P)) + color(transform(\"world\", M, P)) +\n"
	"	     color(ntransform(M, N)) + color(vtransform(\"camera\", I));\n"
	"	point ps = point \"object\" (u, v, 1);\n"
	"	vector vs = vector \"world\" (1, u, v);\n"
	"	normal ns = normal \"shader\" (v, 1, u);\n"
	"	o5 = color(ps) + color(vs) + color(ns);\n"
	"	matrix m2 = matrix \"world\" (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, u, v, 0, 1);\n"
	"	matrix m3 = m2 * M;\n"
	"	o6 = color(comp(m3, 3, 0), comp(m3, 3, 1), comp(m3, 1, 2)) +\n"
	"	     color(determinant(M * u), determinant(m2), 0);\n"
	"	matrix m4 = M / m2;\n"
	"	matrix m5 = 1 / M;\n"
	"	o7 = color(comp(m4, 0, 0), comp(m4, 3, 2), comp(m4, 2, 1)) +\n"
	"	     color(comp(m5, 0, 1), comp(m5, 3, 0), comp(m5, 3, 2));\n"
	"	matrix m6 = translate(M, vector(u, 1, 2));\n"
	"	matrix m7 = rotate(M, v * 2, vector(1, 1, 0));\n"
	"	matrix m8 = scale(M, point(2, u, 3));\n"
	"	o8 = color(comp(m6, 3, 0), comp(m7, 0, 1), comp(m8, 1, 1)) +\n"
	"	     color(comp(m6, 3, 2), comp(m7, 2, 2), comp(m8, 3, 1));\n"
	"	matrix m9 = M;\n"
	"	setcomp(m9, 0, 3, u);\n"
	"	setcomp(m9, s * 4, 2, v);\n"
	"	o9 = color(transform(m9, P)) + color(comp(m9, 0, 3), comp(m9, 1, 2), 0);\n"
	"	matrix z = 0;\n"
	"	matrix m10 = M / z;\n"
	"	o10 = color(comp(m10, 0, 0), (M == m9) ? 1 : 0, (M != M) ? 1 : 0) +\n"
	"	      color(comp(M + m2, 3, 0), comp(M - 2, 1, 1), comp(u * M, 2, 2));\n"
	"	matrix m11 = matrix(u);\n"
	"	o11 = color(comp(m11, 0, 0), comp(m11, 0, 1), comp(m11, 3, 3));\n"
	"	o12 = color(transform(\"object\", transform(\"world\", P)));\n"
	"	Ci = o1;\n"
	"}\n";

static void test_transforms(void)
{
	check_source("xform.sl", xform_src, o12, 12, TOL);
}

static const char color_src[] =
	"surface colortest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0, o9 = 0, o10 = 0, o11 = 0, o12 = 0)\n"
	"{\n"
	"	color c = color(u, v, s), h = color(t, v, u);\n"
	"	o1 = ctransform(\"hsv\", c);\n"
	"	o2 = ctransform(\"hsl\", c);\n"
	"	o3 = ctransform(\"XYZ\", c);\n"
	"	o4 = ctransform(\"xyY\", c);\n"
	"	o5 = ctransform(\"YIQ\", c);\n"
	"	o6 = ctransform(\"hsv\", \"rgb\", h);\n"
	"	o7 = ctransform(\"hsl\", \"rgb\", h);\n"
	"	o8 = ctransform(\"xyz\", \"rgb\", h);\n"
	"	o9 = ctransform(\"xyy\", \"rgb\", h + color(0, 0.1, 0));\n"
	"	o10 = ctransform(\"yiq\", \"hsv\", h - 0.5);\n"
	"	o11 = color \"hsv\" (u, v, 1) + color \"hsl\" (t, 0.5, 0.5) + ctransform(\"rgb\", c);\n"
	"	o12 = ctransform(\"hsv\", color(0.5)) + ctransform(\"xyY\", color(0)) +\n"
	"	      ctransform(\"hsv\", \"rgb\", color(-0.25, 1, 1));\n"
	"	Ci = o1;\n"
	"}\n";

static void test_colors(void)
{
	check_source("color.sl", color_src, o12, 12, TOL);
}

static const char spline_src[] =
	"surface splinetest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0, o9 = 0, o10 = 0, o11 = 0, o12 = 0; float vals[6] = {0, 1, 3, 2, 5, 4})\n"
	"{\n"
	"	float x = u * 1.2 - 0.1;\n"
	"	o1 = color(spline(x, 0, 1, 4, 2, 3), spline(\"catmull-rom\", x, 1, 2, 0, 3),\n"
	"		spline(\"bspline\", x, 0, 1, 4, 2, 3, 5));\n"
	"	o2 = color(spline(\"bezier\", x, 0, 1, 4, 2, 3, 5, 1), spline(\"hermite\", x, 0, 1, 4, 2),\n"
	"		spline(\"linear\", x, 0, 1, 4, 2, 3));\n"
	"	o3 = color(spline(\"constant\", x, 0, 1, 4, 2, 3), spline(x, vals),\n"
	"		spline(\"linear\", x, vals));\n"
	"	o4 = spline(x, color(1, 0, 0), color(0, 1, 0), color(0, 0, 1), color(1, 1, 1)) +\n"
	"	     spline(\"bspline\", x, color(u), color(v), color(s), color(t), color(1));\n"
	"	o5 = color(spline(\"solvelinear\", u * 4, 0, 1, 2, 3, 4, 5),\n"
	"		spline(\"solvecatmull-rom\", u * 3, 0, 0, 1, 2, 4, 4), spline(x, 1, 2, 3, 4));\n"
	"	o6 = color(filterstep(0.5, u, v), filterstep(0.3, s, t, \"width\", 2),\n"
	"		filterstep(0.5, u, u));\n"
	"	color cs[4] = { color(1, 0, 0), color(0, 1, 0), color(0, 0, 1), color(u) };\n"
	"	o7 = spline(\"catmull-rom\", x, cs) + spline(\"bspline\", x, vals);\n"
	"	Ci = o1;\n"
	"}\n";

static void test_splines(void)
{
	static const char *const outs[] = { "o1", "o2", "o3", "o4", "o5", "o6", "o7" };
	check_source("spline.sl", spline_src, outs, 7, TOL);
}

static const char array_src[] =
	"surface arraytest(float K[3] = {1, 2, 3}; color C[2] = {color(1, 0, 0), color(0, 1, 0)};\n"
	"	string names[2] = {\"a\", \"b\"}; output varying color o1 = 0, o2 = 0)\n"
	"{\n"
	"	float a[4] = {0, 0, 0, 0};\n"
	"	a[u * 4] = v;\n"
	"	a[-3 * u - 1] = s;\n"
	"	a[v + 10] = t;\n"
	"	color c[2];\n"
	"	c = C;\n"
	"	c[v * 2] = color(u, v, s);\n"
	"	string nm = names[u * 2];\n"
	"	o1 = color(a[0] + a[1], a[2] + a[3], K[v * 3] + K[v + 5]);\n"
	"	o2 = c[0] + c[1] * 2 + C[u * 2] * 4 + ((nm == \"b\") ? 1 : 0);\n"
	"	Ci = o1;\n"
	"}\n";

static void test_arrays(void)
{
	static const char *const outs[] = { "o1", "o2" };
	check_source("array.sl", array_src, outs, 2, TOL);
}

/* Strings as token ids: constants, parameters in and outside the table, arrays. */
static const char string_src[] =
	"surface stringtest(string mode = \"b\"; string other = \"x\";\n"
	"	output varying color o1 = 0)\n"
	"{\n"
	"	string m = mode;\n"
	"	if (u > 0.5) m = \"c\";\n"
	"	float k = 0;\n"
	"	if (m == \"b\") k += 1;\n"
	"	if (m != \"a\") k += 2;\n"
	"	if (mode == other) k += 4;\n"
	"	if (other == \"\") k += 8;\n"
	"	string z = (v > 0.5) ? mode : \"b\";\n"
	"	if (z == \"b\") k += 16;\n"
	"	if (match(\"^a.c$\", \"abc\") == 1) k += 32;\n"
	"	o1 = color(k, 0, 0);\n"
	"	Ci = o1;\n"
	"}\n";

static void test_strings(void)
{
	static const char *const outs[] = { "o1" };
	static const char *const modes[][2] = {
		{ "b", "x" }, { "a", "" }, { "zzz", "zzz" }, { "b", "b" }, { "unknown", "" },
	};
	struct sl_program *p = compile("string.sl", string_src);
	CHECK(p != NULL);
	if (!p)
		return;
	for (size_t k = 0; k < sizeof(modes) / sizeof(modes[0]); k++) {
		struct xc c;
		char name[64];
		snprintf(name, sizeof(name), "strings (%s, %s)", modes[k][0], modes[k][1]);
		xc_init(&c, name, p, NPTS);
		xc_sets(&c, 0, "mode", modes[k][0]);
		xc_sets(&c, 0, "other", modes[k][1]);
		xc_check(&c, outs, 1, 0);
		xc_free(&c);
	}
	sl_program_destroy(p);
}

/*
 * Noise equality over many points: the hash is exact, so cellnoise agrees
 * bit for bit; gradient noise agrees to float rounding of the blend (a few
 * ulps of values in [0, 1]: 1e-5 is generous).
 */
static const char noise_src[] =
	"surface noisetest(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0, o8 = 0)\n"
	"{\n"
	"	float x = (u - 0.5) * 40, y = (v - 0.5) * 40, z = (s - 0.5) * 40, w = (t - 0.5) * 40;\n"
	"	point p = point(x, y, z);\n"
	"	o1 = color(noise(x), noise(x, y), noise(p));\n"
	"	o2 = color(noise(p, w), pnoise(x, 5), pnoise(x, y, 3, 4));\n"
	"	o3 = color(pnoise(p, point(3, 5, 7)), pnoise(p, w, point(2, 3, 4), 6), noise(x * 1e9));\n"
	"	o4 = color noise(x) + color noise(x, y) + color noise(p) * 2 + color noise(p, w) * 4;\n"
	"	o5 = color pnoise(p, point(4, 0, 3)) + color pnoise(x, y, 0, 2) * 2;\n"
	"	o6 = color(noise(floor(x)), noise(floor(x), floor(y)), noise(floor(p)));\n"
	"	o7 = color(cellnoise(x), cellnoise(x, y), cellnoise(p)) + color(cellnoise(p, w)) * 2;\n"
	"	o8 = color cellnoise(x) + color cellnoise(x, y) * 2 + color cellnoise(p) * 4 +\n"
	"	     color cellnoise(p, w) * 8 + color(vector noise(p)) * 16;\n"
	"	Ci = o1;\n"
	"}\n";

static void test_noise(void)
{
	static const char *const cells[] = { "o7", "o8" };
	struct sl_program *p = compile("noise.sl", noise_src);
	CHECK(p != NULL);
	if (!p)
		return;
	struct xc c;
	xc_init(&c, "noise (8192 points)", p, 8192);
	xc_check(&c, o12, 6, 1e-5);
	xc_free(&c);
	xc_init(&c, "cellnoise (8192 points, exact)", p, 8192);
	xc_check(&c, cells, 2, 0);
	xc_free(&c);
	sl_program_destroy(p);
}

/* ------------------------------------------------------------------------ */
/* Lights: illuminance, categories, messages, the lighting functions         */

static const char lightsA_src[] =
	"light keylight(float intensity = 1; color lightcolor = 1; point from = point \"shader\"\n"
	"	(0, 0, 0); string __category = \"key,rim\"; float __nonspecular = 0;\n"
	"	output varying float seen = 0)\n"
	"{\n"
	"	float k = 1;\n"
	"	if (surface(\"Kd\", k) == 0) k = 0.5;\n"
	"	illuminate(from) {\n"
	"		Cl = intensity * lightcolor * k / (L . L);\n"
	"		seen = 1;\n"
	"	}\n"
	"}\n";

static const char lightsB_src[] =
	"light filllight(float intensity = 1; vector dir = vector(0, 0, 1);\n"
	"	string __category = \"fill\"; float __nondiffuse = 0)\n"
	"{\n"
	"	float i;\n"
	"	solar(dir, 0) {\n"
	"		Cl = 0;\n"
	"		for (i = 0; i < 3; i += 1) {\n"
	"			if (i == 1) continue;\n"
	"			Cl += intensity * color(1, 0.5, 0.25) * (i + 1);\n"
	"		}\n"
	"	}\n"
	"}\n";

static const char lightsC_src[] =
	"light conelight(float intensity = 1; point from = point(0, 1, 0);\n"
	"	vector axis = vector(0, -1, 1); float angle = 0.8)\n"
	"{\n"
	"	if (intensity > 0.5) {\n"
	"		illuminate(from, axis, angle)\n"
	"			Cl = intensity * (1 - Ps . Ps * 0.01);\n"
	"	} else {\n"
	"		Cl = color(0.1, 0.2, 0.3);\n"
	"	}\n"
	"}\n";

static const char illum_src[] =
	"float firstlit(point p) {\n"
	"	illuminance(p) {\n"
	"		if (comp(Cl, 1) > 0.4) return comp(Cl, 1);\n"
	"	}\n"
	"	return -1;\n"
	"}\n"
	"surface illumtest(float Kd = 0.8; string cat = \"key\";\n"
	"	output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0, o7 = 0)\n"
	"{\n"
	"	normal Nf = faceforward(normalize(N), I);\n"
	"	vector V = -normalize(I);\n"
	"	illuminance(P, Nf, PI / 2)\n"
	"		o1 += Cl * (normalize(L) . Nf);\n"
	"	illuminance(\"key\", P) {\n"
	"		float inten = 0, seen = 0;\n"
	"		lightsource(\"intensity\", inten);\n"
	"		if (lightsource(\"seen\", seen) == 1) o2 += color(seen, 0, 0);\n"
	"		o2 += Cl * inten;\n"
	"	}\n"
	"	illuminance(\"-fill\", P, Nf, 1) {\n"
	"		if (comp(Cl, 0) > 0.3) break;\n"
	"		o3 += Cl;\n"
	"	}\n"
	"	illuminance(\"fill, rim\", P) {\n"
	"		if (u > 0.5) continue;\n"
	"		o4 += Cl;\n"
	"		float i;\n"
	"		for (i = 0; i < 4; i += 1) {\n"
	"			if (i > v * 4) break 2;\n"
	"			o4 += 0.1;\n"
	"		}\n"
	"	}\n"
	"	o5 = ambient() + diffuse(Nf) * Kd;\n"
	"	o6 = specular(Nf, V, 0.2) + phong(Nf, V, 12);\n"
	"	o7 = Cl + color(L) + Ol + firstlit(P);\n"
	"	Ci = o1;\n"
	"}\n";

static const char *const o7[] = { "o1", "o2", "o3", "o4", "o5", "o6", "o7" };

static void test_illuminance(void)
{
	struct sl_program *sp = compile("illum.sl", illum_src), *a = compile("key.sl", lightsA_src),
			  *b = compile("fill.sl", lightsB_src), *cn = compile("cone.sl", lightsC_src),
			  *amb = load("ambientlight");
	CHECK(sp && a && b && cn && amb);
	if (sp && a && b && cn && amb) {
		struct xc c;
		xc_init(&c, "illuminance, messages, lighting", sp, NPTS);
		xc_add(&c, a);
		xc_set3(&c, 1, "from", 0.5f, 2, 1);
		xc_setf(&c, 1, "intensity", 4);
		xc_add(&c, b);
		xc_set3(&c, 2, "dir", 0.2f, -0.3f, 1);
		xc_add(&c, cn);
		xc_add(&c, amb);
		xc_setf(&c, 4, "intensity", 0.2f);
		xc_add(&c, a);
		xc_sets(&c, 5, "__category", "rim");
		xc_setf(&c, 5, "__nonspecular", 1);
		xc_add(&c, b);
		xc_setf(&c, 6, "__nondiffuse", 1);
		xc_sets(&c, 6, "__category", "key");
		xc_add(&c, cn);
		xc_setf(&c, 7, "intensity", 0.25f);
		/* A category the program never names: no id of its own, and none needed. */
		xc_add(&c, a);
		xc_sets(&c, 8, "__category", "bounce");
		xc_set3(&c, 8, "from", -1, 1, 2);
		xc_check(&c, o7, 7, TOL);
		xc_free(&c);
	}
	sl_program_destroy(sp);
	sl_program_destroy(a);
	sl_program_destroy(b);
	sl_program_destroy(cn);
	sl_program_destroy(amb);
}

/*
 * Uniform locals that have to vary are promoted (rsl.md, "Storage classes"):
 * an fBm's uniform counter and amplitude inlined under a varying if, a
 * uniform counter of a loop whose condition varies, a uniform message read
 * for each light and a uniform assigned inside illuminate. The generated
 * GLSL must compute per point what the interpreter does.
 */
static const char promote_src[] =
	"float fbm(point p; uniform float octaves) {\n"
	"	uniform float i, amp = 1;\n"
	"	float sum = 0;\n"
	"	point pp = p;\n"
	"	for (i = 0; i < octaves; i += 1) {\n"
	"		sum += amp * noise(pp);\n"
	"		amp *= 0.5;\n"
	"		pp *= 2;\n"
	"	}\n"
	"	return sum;\n"
	"}\n"
	"surface promote(float oct = 4; output varying float o1 = 0, o2 = 0;\n"
	"	output varying color o3 = 0)\n"
	"{\n"
	"	if (s > 0.5)\n"
	"		o1 = fbm(P, oct);\n"
	"	uniform float j;\n"
	"	float fw = u * 0.9 + 0.02;\n"
	"	for (j = 0; j < 6 && fw < 1.0; j += 1)\n"
	"		fw *= 2;\n"
	"	o2 = j + fw;\n"
	"	uniform float nonspec = 0;\n"
	"	illuminance(P) {\n"
	"		nonspec = 0;\n"
	"		lightsource(\"__nonspecular\", nonspec);\n"
	"		uniform float w = 1 - nonspec;\n"
	"		o3 += w * Cl;\n"
	"	}\n"
	"	Ci = o3;\n"
	"}\n";

static const char promote_light_src[] =
	"light promotelight(float intensity = 1; point from = point(0, 1, -2);\n"
	"	float __nonspecular = 0)\n"
	"{\n"
	"	uniform float k = 0;\n"
	"	illuminate(from) {\n"
	"		k = 1 / (1 + L . L);\n"
	"		Cl = intensity * k;\n"
	"	}\n"
	"}\n";

static void test_promoted_uniforms(void)
{
	static const char *const outs[] = { "o1", "o2", "o3", "Ci" };
	struct sl_program *sp = compile("promote.sl", promote_src);
	struct sl_program *l = compile("promotelight.sl", promote_light_src);
	CHECK(sp && l);
	if (sp && l) {
		struct xc c;
		xc_init(&c, "promoted uniforms", sp, NPTS);
		xc_add(&c, l);
		xc_add(&c, l);
		xc_setf(&c, 2, "intensity", 2);
		xc_setf(&c, 2, "__nonspecular", 1);
		xc_add(&c, l);
		xc_setf(&c, 3, "intensity", 0.5f);
		xc_setf(&c, 3, "__nonspecular", 0.25f);
		xc_check(&c, outs, 4, TOL);
		xc_free(&c);
	}
	sl_program_destroy(sp);
	sl_program_destroy(l);
}

/*
 * A flat chain of FLAT_TERMS products, as generated shaders write them: the
 * GLSL of a long left-leaning expression computes what the interpreter does.
 * (A thousand terms: llvmpipe's compile time grows faster than the source,
 * 1.8 s here; test_uniform.c generates the GLSL of ten thousand.)
 */
#define FLAT_TERMS 1000

static void test_flat_expression(void)
{
	static const char *const outs[] = { "x" };
	static const char *const names[] = { "s", "t", "u", "Kd" };
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, "surface flat(float Kd = 0.5; output varying float x = 0)\n{\n\tx = ");
	for (int k = 0; k < FLAT_TERMS; k++)
		rl_strbuf_printf(&b, "%s%d*%s", k ? (k % 5 == 4 ? " - " : " + ") : "", k % 7 + 1,
				 names[k % 4]);
	rl_strbuf_puts(&b, ";\n\tCi = x;\n}\n");
	double e = check_source("flat.sl", rl_strbuf_str(&b), outs, 1, TOL);
	CHECK(e >= 0);
	rl_strbuf_finish(&b);
}

/*
 * solar() without arguments and Ns (test_exec.c checks the closed forms on
 * the interpreter): the GPU gives each light the same Ns for every way a
 * surface runs its lights: an illuminance with an axis, one without (the
 * surface's N), diffuse(), specular(), phong() (the normal given) and
 * ambient() (zero); and a light's own P (its shader space's origin) and ncomps.
 */
static const char allsky_src[] =
	"light allsky(float k = 2) {\n"
	"	solar() { Cl = k * color(xcomp(Ns), ycomp(Ns), zcomp(Ns)); }\n"
	"}\n";
static const char nsprobe_src[] =
	"light nsprobe(point from = point(0, 0, 10)) {\n"
	"	illuminate(from) { Cl = color(xcomp(Ns), ycomp(Ns), zcomp(Ns)); }\n"
	"}\n";
static const char geo_src[] =
	"light geo() { solar() { Cl = color(xcomp(P), ycomp(P), zcomp(P)) * 0.1 + ncomps; } }\n";
static const char ambns_src[] =
	"light ambns() { Cl = color(xcomp(Ns), ycomp(Ns), zcomp(Ns)) + 0.25; }\n";
static const char solarsurf_src[] =
	"surface solarsurf(output varying color o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, o6 = 0,\n"
	"	o7 = 0)\n"
	"{\n"
	"	normal Nf = normalize(N);\n"
	"	illuminance(P, Nf, 0.01) { o1 += color(L); o2 += Cl; o3 += 1; }\n"
	"	illuminance(P) { o4 += color(L) + Cl; }\n"
	"	o5 = diffuse(Nf);\n"
	"	o6 = specular(Nf, -normalize(I), 0.2) + phong(Nf, -normalize(I), 10);\n"
	"	o7 = ambient();\n"
	"	Ci = o1;\n"
	"}\n";

static void test_solar_all(void)
{
	struct sl_program *sp = compile("solarsurf.sl", solarsurf_src),
			  *a = compile("allsky.sl", allsky_src),
			  *b = compile("nsprobe.sl", nsprobe_src),
			  *amb = compile("ambns.sl", ambns_src), *geo = compile("geo.sl", geo_src);
	CHECK(sp && a && b && amb && geo);
	if (sp && a && b && amb && geo) {
		struct xc c;
		xc_init(&c, "solar() without arguments, Ns", sp, NPTS);
		xc_add(&c, a);
		xc_setf(&c, 1, "k", 1.5f);
		xc_add(&c, b);
		xc_add(&c, amb);
		xc_add(&c, geo);
		double e = xc_check(&c, o7, 7, TOL);
		/* Every point is lit by allsky through the narrowest cone. */
		const struct sl_program *p = c.prog[0];
		int32_t o3 = p->params[sl_program_find_param(p, "o3")].reg;
		for (uint32_t i = 0; i < NPTS; i++)
			CHECK(sl_exec_reg(c.x[0], o3)[i] >= 1);
		printf("solar(), Ns: GPU within %.3g of the interpreter\n", e);
		xc_free(&c);
	}
	sl_program_destroy(sp);
	sl_program_destroy(a);
	sl_program_destroy(b);
	sl_program_destroy(amb);
	sl_program_destroy(geo);
}

/* Light @j of the per-light test, program @i of @c: its parameters. */
static void pass_light(struct xc *c, int i, int j)
{
	if (j == 0) {
		xc_set3(c, i, "from", 0.5f, 2, 1);
		xc_setf(c, i, "intensity", 4);
		xc_sets(c, i, "__category", "rim");
		xc_setf(c, i, "__nonspecular", 1);
	} else if (j == 1) {
		xc_set3(c, i, "dir", 0.2f, -0.3f, 1);
		xc_setf(c, i, "__nondiffuse", 1);
		xc_sets(c, i, "__category", "key");
	} else if (j == 2) {
		xc_setf(c, i, "intensity", 0.25f);
	} else {
		xc_setf(c, i, "intensity", 0.2f);
	}
}

/*
 * Per-light passes (sl_slice.per_light): the illuminance surface with four
 * lights of four shaders (categories, __nondiffuse, __nonspecular, an
 * ambient light), each pass against the interpreter lit by that light alone.
 */
static void test_per_light(void)
{
	struct sl_program *sp = compile("illum.sl", illum_src), *a = compile("key.sl", lightsA_src),
			  *b = compile("fill.sl", lightsB_src), *cn = compile("cone.sl", lightsC_src),
			  *amb = load("ambientlight");
	CHECK(sp && a && b && cn && amb);
	if (sp && a && b && cn && amb) {
		struct sl_program *set[4] = { a, b, cn, amb };
		struct xc all, one[4];
		for (int k = 0; k <= 4; k++) {
			struct xc *c = k < 4 ? &one[k] : &all;
			xc_init(c, k < 4 ? "one light" : "per-light passes", sp, NPTS);
			for (int j = 0; j < 4; j++) {
				if (k < 4 && j != k)
					continue;
				xc_add(c, set[j]);
				pass_light(c, k < 4 ? 1 : 1 + j, j);
			}
		}
		/* light k alone, in the space it has as light k of all four */
		float first[16];
		memcpy(first, light_mats[0], sizeof(first));
		for (int k = 0; k < 4; k++) {
			memcpy(light_mats[0], light_mats[k], sizeof(first));
			CHECK(xc_cpu(&one[k]));
			pass_ref[k] = &one[k];
		}
		memcpy(light_mats[0], first, sizeof(first));
		xc_check(&all, o7, 7, TOL);
		memset(pass_ref, 0, sizeof(pass_ref));
		for (int k = 0; k <= 4; k++)
			xc_free(k < 4 ? &one[k] : &all);
	}
	sl_program_destroy(sp);
	sl_program_destroy(a);
	sl_program_destroy(b);
	sl_program_destroy(cn);
	sl_program_destroy(amb);
}

/* The golden programs and the fuzzing corpus that can run on the GPU: every output. */
static void test_other_shaders(void)
{
	static const char *const files[] = {
		"tests/golden/run_arrays.sl", "tests/golden/run_functions.sl",
		"tests/golden/run_illuminance_none.sl", "tests/golden/run_loops.sl",
		"tests/golden/run_operators.sl", "tests/fuzz/corpus_sl/matrix.sl",
		"tests/fuzz/corpus_sl/nesting.sl", "tests/fuzz/corpus_sl/plastic.sl",
	};
	const char *dir = getenv("RELIGHT_SOURCE_DIR");
	for (size_t f = 0; f < sizeof(files) / sizeof(files[0]); f++) {
		char path[1024];
		snprintf(path, sizeof(path), "%s/%s", dir ? dir : ".", files[f]);
		struct sl_program *p = sl_compile_file(path, NULL);
		CHECK(p != NULL);
		if (!p)
			continue;
		const char *outs[32];
		int n = 0;
		for (int g = SL_GLOBAL_CI; g <= SL_GLOBAL_OI; g++)
			if (p->global_reg[g] >= 0)
				outs[n++] = sl_global_name(g);
		for (uint32_t k = 0; k < p->nparams && n < 32; k++)
			if (p->params[k].output &&
			    p->regs[p->params[k].reg].type != SL_TYPE_STRING)
				outs[n++] = p->params[k].name;
		struct xc c;
		xc_init(&c, files[f], p, NPTS);
		xc_check(&c, outs, n, TOL);
		xc_free(&c);
		sl_program_destroy(p);
	}
}

/*
 * Imager shaders (the GPU runtime's imager pass): the library's background
 * and one that reads every imager global and a parameter, on random
 * pixels (Ci, Oi, alpha and P as inputs), against the interpreter.
 */
static const char imager_src[] =
	"imager probe(float k = 0.5; color tint = color(0.2, 0.9, 0.4)) {\n"
	"	float d = distance(P, point(0.1, 0.2, 0));\n"
	"	Ci = mix(Ci, tint * comp(Oi, 1), smoothstep(0, 1, d * k)) + ncomps * 0.01;\n"
	"	alpha = clamp(alpha + time + dtime + 0.25 * sin(xcomp(P) * 3), 0, 1);\n"
	"}\n";
static const char *const ci_alpha[] = { "Ci", "alpha" };

static void test_imagers(void)
{
	struct sl_program *bg = load("background");
	CHECK(bg != NULL);
	if (bg) {
		struct xc c;
		xc_init(&c, "background", bg, NPTS);
		xc_set3(&c, 0, "bgcolor", 0.3f, 0.6f, 0.9f);
		printf("imager background: largest difference %.3g\n",
		       xc_check(&c, ci_alpha, 2, TOL));
		xc_free(&c);
		sl_program_destroy(bg);
	}
	printf("imager probe: largest difference %.3g\n",
	       check_source("probe", imager_src, ci_alpha, 2, TOL));
}

/* ------------------------------------------------------------------------ */
/* Timings: the interpreter and the GPU over a big grid                      */

static void test_benchmark(void)
{
	if (!ctx)
		return;
	static const char *const lnames[] = { "spotlight", "pointlight", "uberlight",
					      "ambientlight" };
	struct sl_program *sp = load("plastic"), *lp[4];
	for (int k = 0; k < 4; k++)
		lp[k] = load(lnames[k]);
	uint32_t n = 1u << 16;
	struct xc c;
	xc_init(&c, "bench: plastic + 4 lights, 65536", sp, n);
	for (int k = 0; k < 4; k++) {
		xc_add(&c, lp[k]);
		aim_light(&c, 1 + k, lnames[k]);
	}
	xc_check(&c, ci_oi, 2, TOL);
	printf("benchmark: interpreter %.1f ns/sample, GPU (%s) %.1f ns/sample\n",
	       c.cpu_ms * 1e6 / n, gpu_renderer(ctx), c.gpu_ms * 1e6 / n);
	xc_free(&c);
	sl_program_destroy(sp);
	for (int k = 0; k < 4; k++)
		sl_program_destroy(lp[k]);
}

/* ------------------------------------------------------------------------ */
/* Errors                                                                    */

/* Emit @src (no lights but @light, if given); its diagnostics must contain @want. */
static void expect_error(const char *src, const char *light, const char *want)
{
	struct sl_program *p = compile("err.sl", src);
	struct sl_program *l = light ? compile("errlight.sl", light) : NULL;
	CHECK(p != NULL && (!light || l));
	if (!p || (light && !l)) {
		sl_program_destroy(p);
		sl_program_destroy(l);
		return;
	}
	int32_t out = p->global_reg[SL_GLOBAL_CI];
	struct sl_slice s = { p, NULL, NULL, 0, &out, out >= 0 ? 1 : 0 };
	struct sl_glsl_layout lay;
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	const struct sl_program *lights[1] = { l };
	char *glsl = sl_glsl_emit(&s, lights, l ? 1 : 0, &lay, diag);
	fclose(diag);
	CHECK(glsl == NULL);
	CHECK(buf && strstr(buf, want));
	if (!buf || !strstr(buf, want))
		fprintf(stderr, "expected \"%s\", got:\n%s\n", want, buf ? buf : "");
	CHECK(lay.strings == NULL && lay.in_offset == NULL);
	free(glsl);
	free(buf);
	sl_program_destroy(p);
	sl_program_destroy(l);
}

/* Emit @p (a surface) with light @l; the diagnostics must contain @want. */
static void expect_emit_error(const struct sl_program *p, const struct sl_program *l,
			      uint32_t nl, const char *want)
{
	int32_t out = p->global_reg[SL_GLOBAL_CI];
	struct sl_slice s = { p, NULL, NULL, 0, &out, out >= 0 ? 1 : 0 };
	struct sl_glsl_layout lay;
	const struct sl_program *lights[MAXL];
	for (uint32_t k = 0; k < nl && k < MAXL; k++)
		lights[k] = l;
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	char *glsl = sl_glsl_emit(&s, lights, nl, &lay, diag);
	fclose(diag);
	CHECK(glsl == NULL);
	CHECK(buf && strstr(buf, want));
	if (!buf || !strstr(buf, want))
		fprintf(stderr, "expected \"%s\", got:\n%s\n", want, buf ? buf : "");
	free(glsl);
	free(buf);
}

/* IR the front end never makes, made by hand from a compiled program. */
static void test_patched_programs(void)
{
	struct sl_program *sp = compile("ok.sl", "surface ok() { Ci = diffuse(N); }\n");
	struct sl_program *lp = compile("sun.sl", "light sun() { solar(vector(0, 0, 1), 0) "
					"Cl = 1; }\n");
	CHECK(sp && lp);
	if (!sp || !lp) {
		sl_program_destroy(sp);
		sl_program_destroy(lp);
		return;
	}
	struct sl_program l2 = *lp;
	struct sl_insn *code = malloc(lp->ncode * sizeof(*code));
	l2.code = code;
	/* An instruction that writes a constant. */
	memcpy(code, lp->code, lp->ncode * sizeof(*code));
	int32_t k = -1;
	for (uint32_t r = 0; r < lp->nregs; r++)
		if (lp->regs[r].kind == SL_REG_CONST && lp->regs[r].type == SL_TYPE_FLOAT)
			k = (int32_t)r;
	for (uint32_t i = lp->body_begin; i < lp->ncode; i++)
		if (code[i].op == SL_OP_MOV && lp->regs[code[i].dst].type == SL_TYPE_FLOAT && k >= 0)
			code[i].dst = k;
	code[lp->body_begin] = (struct sl_insn){ .op = SL_OP_NEG, .nargs = 1, .dst = k,
						 .args = code[lp->body_begin].args,
						 .loc = code[lp->body_begin].loc };
	if (code[lp->body_begin].args && k >= 0)
		expect_emit_error(sp, &l2, 1, "invalid program");
	/* A break with nothing to leave. */
	memcpy(code, lp->code, lp->ncode * sizeof(*code));
	code[lp->body_begin] = (struct sl_insn){ .op = SL_OP_BREAK, .imm = 1, .dst = -1,
						 .loc = code[lp->body_begin].loc };
	expect_emit_error(sp, &l2, 1, "break or continue outside its loop");
	code[lp->body_begin].op = SL_OP_RETURN;
	expect_emit_error(sp, &l2, 1, "return outside a function");
	free(code);
	sl_program_destroy(sp);
	sl_program_destroy(lp);
}

/*
 * Illuminance inside illuminance unrolls once per light at every level:
 * the source size is capped, so that this is an error, not hours of work.
 */
static void test_too_large(void)
{
	struct sl_program *sp = compile("nest.sl",
		"surface nest() {\n"
		"  illuminance(P) { illuminance(P) { illuminance(P) { illuminance(P) {\n"
		"    illuminance(P) { Ci += Cl * color(u, v, s) + noise(P) * Cl; } } } } }\n"
		"}\n");
	struct sl_program *lp = load("pointlight");
	CHECK(sp && lp);
	if (sp && lp) {
		double t0 = rl_now_ms();
		expect_emit_error(sp, lp, MAXL, "the generated GLSL is too large");
		double ms = rl_now_ms() - t0;
		printf("nested illuminance over %d lights refused after %.0f ms\n", MAXL, ms);
		CHECK(ms < 20000);
	}
	sl_program_destroy(sp);
	sl_program_destroy(lp);
}

static void test_errors(void)
{
	expect_error("surface e() {\n  Ci = random();\n}\n",
		     NULL, "err.sl:2:8: error: random() is not supported on the GPU");
	expect_error("surface e() {\n  Ci = Du(s) + Dv(t) + Deriv(s, t);\n}\n",
		     NULL, "err.sl:2:8: error: derivatives of GPU-computed values are not "
		     "supported (Du)");
	expect_error("surface e() {\n  float a = area(P);\n  Ci = a + xcomp(calculatenormal(P));\n}\n",
		     NULL, "derivatives of GPU-computed values are not supported (area)");
	expect_error("surface e() {\n  Ci = filterstep(0.5, s);\n}\n",
		     NULL, "err.sl:2:8: error: derivatives of GPU-computed values are not supported");
	expect_error("surface e() {\n  Ci = texture(\"wood.tex\");\n}\n",
		     NULL, "err.sl:2:8: error: texture 'wood.tex' cannot be read on the GPU");
	expect_error("surface e() {\n  Ci = environment(\"sky.env\", I);\n}\n",
		     NULL, "environment 'sky.env' cannot be read on the GPU");
	expect_error("surface e() {\n  Ci = shadow(\"s.shd\", P);\n}\n",
		     NULL, "shadow 's.shd' cannot be read on the GPU");
	expect_error("surface e() {\n  float r;\n  Ci = textureinfo(\"a.tex\", \"type\", r);\n}\n",
		     NULL, "textureinfo 'a.tex' cannot be read on the GPU");
	expect_error("surface e() {\n  string a = format(\"%f\", s);\n  if (a == \"1\") Ci = 1;\n}\n",
		     NULL, "err.sl:2:14: error: format() is not supported on the GPU");
	expect_error("surface e(string x = \"a\") {\n  if (concat(x, \"b\") == \"ab\") Ci = 1;\n}\n",
		     NULL, "concat() is not supported on the GPU");
	expect_error("surface e() {\n  float a = 0;\n  attribute(\"identifier:name\", a);\n"
		     "  Ci = a;\n}\n",
		     NULL, "err.sl:3:3: error: attribute() is not supported on the GPU");
	expect_error("surface e() {\n  float a[2];\n  option(\"Clipping\", a);\n  Ci = a[0];\n}\n",
		     NULL, "option() is not supported on the GPU");
	expect_error("surface e() {\n  Ci = depth(P);\n}\n",
		     NULL, "err.sl:2:8: error: depth() is not supported on the GPU");
	expect_error("surface e(string sp = \"world\") {\n  Ci = color transform(sp, P);\n}\n",
		     NULL, "coordinate system names must be constant strings on the GPU");
	expect_error("surface e(string sp = \"hsv\") {\n  Ci = ctransform(sp, Cs);\n}\n",
		     NULL, "color space names must be constant strings on the GPU");
	expect_error("surface e(string c = \"key\") {\n  illuminance(c, P) Ci += Cl;\n}\n",
		     NULL, "err.sl:2:3: error: illuminance categories must be constant strings");
	expect_error("surface e(string b = \"linear\") {\n  Ci = spline(b, s, 0, 1, 2, 3);\n}\n",
		     NULL, "spline bases must be constant strings on the GPU");
	expect_error("surface e(string m = \"a\") {\n  Ci = match(m, \"abc\");\n}\n",
		     NULL, "match() is not supported on the GPU");
	expect_error("surface e() {\n  Ci = diffuse(N);\n}\n",
		     "light l() {\n  illuminate(P) Cl = ambient();\n}\n",
		     "errlight.sl:2:22: error: ambient() is not supported on the GPU");
	expect_error("surface e() {\n  Ci = 1;\n}\n",
		     "light l() {\n  float x = random();\n  illuminate(P) Cl = x;\n}\n",
		     "errlight.sl:2:13: error: random() is not supported on the GPU");
	expect_error("surface e(string n = \"Kd\") {\n  float x = 0;\n"
		     "  illuminance(P) { lightsource(n, x); Ci += x; }\n}\n",
		     "light l() {\n  illuminate(P) Cl = 1;\n}\n",
		     "message names must be constant strings on the GPU");

	expect_error("surface e() {\n  Ci = color transform(\"my-space\", P);\n}\n",
		     NULL, "err.sl:2:14: error: coordinate system 'my-space' cannot be named in GLSL");
	expect_error("surface e() {\n  Ci = diffuse(N);\n}\n",
		     "light l(float shader = 1) {\n  illuminate(P) Cl = shader;\n}\n",
		     "a light parameter named 'shader' collides");
	expect_error("surface e() {\n  float r = 0;\n  rendererinfo(\"versionstring\", r);\n"
		     "  Ci = r;\n}\n",
		     NULL, "rendererinfo() is not supported on the GPU");
	expect_error("surface e(float Kd = 1) {\n  Ci = Kd;\n}\n",
		     "light l() {\n  uniform string n = format(\"%s\", \"Kd\");\n  float k = 0;\n"
		     "  surface(n, k);\n  illuminate(P) Cl = k;\n}\n",
		     "errlight.sl:2:22: error: format() is not supported on the GPU");

	/* Slices and programs that do not hold together. */
	struct sl_program *p = compile("ok.sl", "surface ok() { Ci = Cs; }\n");
	CHECK(p != NULL);
	if (!p)
		return;
	struct sl_glsl_layout lay;
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	int32_t bad = (int32_t)p->nregs + 5;
	struct sl_slice s = { p, NULL, &bad, 1, NULL, 0 };
	CHECK(sl_glsl_emit(&s, NULL, 0, &lay, diag) == NULL);
	struct sl_slice s2 = { p, NULL, NULL, 0, &bad, 1 };
	CHECK(sl_glsl_emit(&s2, NULL, 0, &lay, diag) == NULL);
	struct sl_slice s3 = { p, NULL, NULL, 0, NULL, 0 };
	CHECK(sl_glsl_emit(&s3, NULL, 2, &lay, diag) == NULL);
	const struct sl_program *nolight[2] = { NULL, NULL };
	CHECK(sl_glsl_emit(&s3, nolight, 2, &lay, diag) == NULL);
	const struct sl_program *notlight[1] = { p };
	CHECK(sl_glsl_emit(&s3, notlight, 1, &lay, diag) == NULL);
	CHECK(sl_glsl_emit(NULL, NULL, 0, &lay, diag) == NULL);
	/* A block opener whose closer is out of place. */
	struct sl_program broken = *p;
	struct sl_insn *code = malloc(p->ncode * sizeof(*code));
	memcpy(code, p->code, p->ncode * sizeof(*code));
	broken.code = code;
	code[p->body_begin].op = SL_OP_IF;
	code[p->body_begin].jump[0] = code[p->body_begin].jump[1] = (int32_t)p->ncode + 3;
	char *g = sl_glsl_emit(&(struct sl_slice){ &broken, NULL, NULL, 0, NULL, 0 }, NULL, 0,
			       &lay, diag);
	CHECK(g == NULL);
	free(g);
	fclose(diag);
	CHECK(buf && strstr(buf, "invalid slice: input 0 is not a register"));
	CHECK(buf && strstr(buf, "invalid slice: output 0 is not a register"));
	CHECK(buf && strstr(buf, "light 0 is missing"));
	CHECK(buf && strstr(buf, "light 0 is a surface shader"));
	CHECK(buf && strstr(buf, "no slice or layout"));
	CHECK(buf && strstr(buf, "invalid program: instruction"));
	free(buf);
	free(code);
	sl_program_destroy(p);
	test_patched_programs();
	test_too_large();
}

/* Warnings, not errors: printf is dropped; texture names known only at run time. */
static void test_warnings(void)
{
	static const char src[] =
		"surface w(string tx = \"\") {\n"
		"  printf(\"%f\\n\", s);\n"
		"  float r = 7, ok = textureinfo(\"\", \"type\", r);\n"
		"  ok += displacement(\"Km\", r) + atmosphere(\"a\", r) + incident(\"b\", r) +\n"
		"        opposite(\"c\", r) + lightsource(\"intensity\", r) + surface(\"d\", r);\n"
		"  Ci = texture(tx, s, t) + color texture(\"\", \"fill\", 0.5) + ok + r +\n"
		"       environment(\"\", I) + shadow(\"\", P);\n"
		"}\n";
	struct sl_program *p = compile("warn.sl", src);
	CHECK(p != NULL);
	if (!p)
		return;
	int32_t out = p->global_reg[SL_GLOBAL_CI];
	struct sl_slice s = { p, NULL, NULL, 0, &out, 1 };
	struct sl_glsl_layout lay;
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	char *glsl = sl_glsl_emit(&s, NULL, 0, &lay, diag);
	fclose(diag);
	CHECK(glsl != NULL);
	CHECK(buf && strstr(buf, "warn.sl:2:3: warning: printf() output is dropped on the GPU"));
	CHECK(buf && strstr(buf, "warn.sl:6:8: warning: texture() with a name that is not a "
			    "constant"));
	if (glsl)
		check_valid("warnings", glsl);
	free(glsl);
	free(buf);
	sl_glsl_layout_finish(&lay);
	sl_program_destroy(p);
	/* A slice that leaves out a global its code reads, here P, read by diffuse(). */
	struct sl_program *d = compile("nop.sl", "surface nop() {\n  Ci = Cs * diffuse(N);\n}\n");
	CHECK(d != NULL);
	if (d) {
		int32_t in[2] = { d->global_reg[SL_GLOBAL_N], d->global_reg[SL_GLOBAL_CS] };
		int32_t o = d->global_reg[SL_GLOBAL_CI];
		struct sl_slice ds = { d, NULL, in, 2, &o, 1 };
		buf = NULL;
		diag = open_memstream(&buf, &len);
		glsl = sl_glsl_emit(&ds, NULL, 0, &lay, diag);
		fclose(diag);
		CHECK(glsl != NULL);
		CHECK(buf && strstr(buf, "nop.sl:2:13: warning: global 'P' is read but is not an "
				    "input of the slice (0 is used)"));
		CHECK(buf && !strstr(buf, "'N'") && !strstr(buf, "'Cs'"));
		free(glsl);
		free(buf);
		sl_glsl_layout_finish(&lay);
		sl_program_destroy(d);
	}
	/* And the cross-check: with tx = "" both give the fill values. */
	static const char *const outs[] = { "Ci" };
	check_source("warn.sl", src, outs, 1, TOL);
}

/* The layout: offsets in order, strides, the string table. */
static void test_layout(void)
{
	struct sl_program *p = compile("lay.sl",
		"surface lay(string a = \"one\"; output varying float f = 0;\n"
		"	output varying color c = 0; output varying float arr[3] = {0, 0, 0})\n"
		"{\n"
		"	if (a == \"two\") f = s; else f = t;\n"
		"	c = Cs + color(u);\n"
		"	arr[1] = v;\n"
		"	Ci = color(xcomp(N), 0, 0);\n"
		"}\n");
	CHECK(p != NULL);
	if (!p)
		return;
	int32_t in[4] = { p->global_reg[SL_GLOBAL_CS], p->global_reg[SL_GLOBAL_S],
			  p->global_reg[SL_GLOBAL_N], p->global_reg[SL_GLOBAL_U] };
	int32_t out[3] = { output_reg(p, "c"), output_reg(p, "arr"), output_reg(p, "f") };
	struct sl_slice s = { p, NULL, in, 4, out, 3 };
	struct sl_glsl_layout lay;
	/* t and v are left out on purpose: they are warned about, and 0. */
	char *buf = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&buf, &len);
	char *glsl = sl_glsl_emit(&s, NULL, 0, &lay, diag);
	fclose(diag);
	CHECK(buf && strstr(buf, "global 't' is read") && strstr(buf, "global 'v' is read"));
	free(buf);
	CHECK(glsl != NULL);
	if (glsl) {
		CHECK(lay.in_stride == 3 + 1 + 3 + 1);
		CHECK(lay.in_offset[0] == 0 && lay.in_offset[1] == 3 && lay.in_offset[2] == 4 &&
		      lay.in_offset[3] == 7);
		CHECK(lay.out_stride == 3 + 3 + 1);
		CHECK(lay.out_offset[0] == 0 && lay.out_offset[1] == 3 && lay.out_offset[2] == 6);
		bool one = false, two = false;
		for (uint32_t i = 0; i < lay.nstrings; i++) {
			one |= !strcmp(lay.strings[i], "one");
			two |= !strcmp(lay.strings[i], "two");
		}
		CHECK(one && two);
		CHECK(strstr(glsl, "uniform float p_a;") != NULL);
		CHECK(strstr(glsl, "layout(local_size_x = 64) in;") != NULL);
		check_valid("layout", glsl);
	}
	free(glsl);
	sl_glsl_layout_finish(&lay);
	sl_glsl_layout_finish(NULL);
	sl_program_destroy(p);
}

/* A slice: only the kept instructions are emitted, inputs stand for the rest. */
static void test_slice(void)
{
	struct sl_program *p = compile("slice.sl",
		"surface sl(float Kd = 0.5) {\n"
		"	color base = Cs * noise(P * 3);\n"
		"	Ci = base * Kd + color(u);\n"
		"}\n");
	CHECK(p != NULL);
	if (!p)
		return;
	/* Keep what follows the noise call; "base" comes in as an input. */
	int32_t base = -1;
	for (uint32_t r = 0; r < p->nregs; r++)
		if (p->regs[r].name && !strcmp(p->regs[r].name, "base"))
			base = (int32_t)r;
	CHECK(base >= 0);
	uint8_t *keep = calloc(p->ncode, 1);
	bool after = false;
	for (uint32_t i = p->body_begin; i < p->ncode; i++) {
		keep[i] = after;
		if (p->code[i].dst == base)
			after = true;
	}
	int32_t in[2] = { base, p->global_reg[SL_GLOBAL_U] };
	int32_t out = p->global_reg[SL_GLOBAL_CI];
	struct sl_slice s = { p, keep, in, 2, &out, 1 };
	struct sl_glsl_layout lay;
	char *glsl = sl_glsl_emit(&s, NULL, 0, &lay, stderr);
	CHECK(glsl != NULL);
	if (glsl) {
		CHECK(strstr(glsl, "rl_noise") == NULL);
		CHECK(strstr(glsl, "uniform float p_Kd;") != NULL);
		check_valid("slice", glsl);
	}
	if (glsl && ctx) {
		struct gpu_program *gp = gpu_program(ctx, glsl, stderr);
		CHECK(gp != NULL);
		float inv[4 * 4], outv[3 * 4];
		for (int i = 0; i < 4; i++) {
			inv[i * lay.in_stride + lay.in_offset[0]] = 0.1f * (float)i;
			inv[i * lay.in_stride + lay.in_offset[0] + 1] = 0.2f;
			inv[i * lay.in_stride + lay.in_offset[0] + 2] = 0.3f;
			inv[i * lay.in_stride + lay.in_offset[1]] = 1.0f;
		}
		float kd = 2;
		CHECK(gp && gpu_uniform_float(gp, "p_Kd", &kd, 1));
		struct gpu_buffer *bi = gpu_buffer_create(ctx, sizeof(inv), inv);
		struct gpu_buffer *bo = gpu_buffer_create(ctx, sizeof(outv), NULL);
		struct gpu_binding b[2] = { { 0, false, bi, true }, { 1, true, bo } };
		CHECK(gp && gpu_dispatch(ctx, gp, b, 2, 4));
		CHECK(gpu_buffer_read(bo, 0, sizeof(outv), outv));
		for (int i = 0; i < 4; i++) {
			CHECK_NEAR(outv[i * 3 + 0], 0.1 * i * 2 + 1, 1e-6);
			CHECK_NEAR(outv[i * 3 + 1], 0.2 * 2 + 1, 1e-6);
			CHECK_NEAR(outv[i * 3 + 2], 0.3 * 2 + 1, 1e-6);
		}
		gpu_buffer_destroy(bi);
		gpu_buffer_destroy(bo);
	}
	free(glsl);
	free(keep);
	sl_glsl_layout_finish(&lay);
	sl_program_destroy(p);
}

/* ------------------------------------------------------------------------ */
/* Derivative stencils and shadow maps                                       */

/*
 * The dynamic part of a specialized surface on derivative stencils, as a
 * shot runs it: the caching program runs over a real nu x nv grid, each
 * sample's record holds the cached values, the steps (sl_exec_reg_delta) of
 * those the derivatives go through and the grid steps du, dv. The
 * interpreter runs s->dynamic on stencils (sl_exec_set_stencil: the samples,
 * then the samples moved along u and along v); the GPU runs the slice
 * emitted with input_steps over the same records.
 */
struct reyes_texsys;

struct stencil_run {
	struct xc c;                /* the surface (defaults) and its light, 3 n points */
	struct sl_spec *sp;
	uint32_t nu, nv, n;
	struct sl_slice slice;
	struct sl_glsl_layout lay;
	char *src;
	float *rec;                 /* n GPU records (with steps) */
	float *rec3;                /* 3 n records for the interpreter, same layout */
	float *du, *dv;
	float *cpu;                 /* Ci of the interpreter, n x 3 */
	struct reyes_texsys *ts;    /* NULL: no texture system */
};

#if defined(__has_include)
#if __has_include("texture.h") && __has_include("shadowmap.h")
#define GLSL_TEST_SHADOW_MAPS 1
#include "texture.h"
#include "shadowmap.h"
#include "texmap.h"
#endif
#endif

#ifdef GLSL_TEST_SHADOW_MAPS
/* Samples (the first third of a stencil run) the renderer finds in full and in partial shadow. */
static uint32_t shadow_full, shadow_partial;

static bool st_shadow(void *user, const struct sl_tex_lookup *q)
{
	const struct sl_lighthost *lh = user;
	bool ok = reyes_tex_shadow(lh->owner, q);
	for (uint32_t i = 0; ok && i < q->n / 3; i++) {
		if (q->mask && !q->mask[i])
			continue;
		shadow_full += q->out[i] == 1.0f;
		shadow_partial += q->out[i] > 0.0f && q->out[i] < 1.0f;
	}
	return ok;
}

static bool st_texture(void *user, const struct sl_tex_lookup *q)
{
	const struct sl_lighthost *lh = user;
	return reyes_tex_texture(lh->owner, q);
}

static bool st_environment(void *user, const struct sl_tex_lookup *q)
{
	const struct sl_lighthost *lh = user;
	return reyes_tex_environment(lh->owner, q);
}
#endif

/* The smooth test surface: a height field over [-1, 1]^2 at z around 3. */
static void surface_point(float u, float v, float P[3], float N[3])
{
	float x = 2 * u - 1, y = 2 * v - 1;
	P[0] = x;
	P[1] = y;
	P[2] = 3.0f + 0.4f * sinf(2.1f * x) * cosf(1.7f * y);
	float dzx = 0.4f * 2.1f * cosf(2.1f * x) * cosf(1.7f * y);
	float dzy = -0.4f * 1.7f * sinf(2.1f * x) * sinf(1.7f * y);
	float l = sqrtf(dzx * dzx + dzy * dzy + 1);
	N[0] = -dzx / l;
	N[1] = -dzy / l;
	N[2] = -1 / l;
}

/*
 * Specialize @surf for @dyn (with cached parameters and the lights'
 * derivatives), bake it over an @nu x @nv grid and run it on the
 * interpreter's stencils with light @light. @cfg sets parameters on c; @ts
 * (may be NULL) answers shadow().
 */
static bool stencil_setup(struct stencil_run *t, const char *name, struct sl_program *surf,
			  struct sl_program *light, const char *const *dyn, size_t ndyn,
			  uint32_t nu, uint32_t nv, void (*cfg)(struct xc *c), struct reyes_texsys *ts)
{
	memset(t, 0, sizeof(*t));
	t->ts = ts;
	t->nu = nu;
	t->nv = nv;
	t->n = nu * nv;
	uint32_t n = t->n;
	xc_init(&t->c, name, surf, 3 * n);
	xc_add(&t->c, light);
	if (cfg)
		cfg(&t->c);
	t->sp = sl_specialize_ex(surf, dyn, ndyn, SL_SPEC_CACHE_PARAMS | SL_SPEC_LIGHT_DERIVATIVES,
				 stderr);
	CHECK(t->sp && t->sp->needs_stencil);
	if (!t->sp || !t->sp->needs_stencil)
		return false;
	t->slice = t->sp->slice;
	t->slice.input_steps = t->sp->cached_deriv;
	const struct sl_program *lights[1] = { light };
	t->src = sl_glsl_emit(&t->slice, lights, 1, &t->lay, stderr);
	CHECK(t->src != NULL);
	if (!t->src)
		return false;
	check_valid(name, t->src);
	const struct sl_glsl_layout *lay = &t->lay;
	CHECK(lay->du_offset != UINT32_MAX && lay->dv_offset == lay->du_offset + 1 &&
	      lay->in_stride == lay->dv_offset + 1);

	/* The bake: the caching program over the grid. */
	struct sl_exec *ce = sl_exec_create(t->sp->caching, n);
	CHECK(ce && sl_exec_set_grid(ce, nu, nv));
	if (!ce)
		return false;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool vary;
		float *d = sl_exec_global(ce, (enum sl_global)g, &vary);
		if (!d || computed_global(g))
			continue;
		uint32_t st = vary ? sl_exec_stride(ce) : 1;
		for (uint32_t i = 0; i < (vary ? n : 1); i++) {
			float u = (float)(i % nu) / (float)(nu - 1), v = (float)(i / nu) / (float)(nv - 1);
			float P[3], N[3], val[3] = { 0, 0, 0 };
			surface_point(u, v, P, N);
			switch (g) {
			case SL_GLOBAL_P: case SL_GLOBAL_I:
				memcpy(val, P, sizeof(val));
				break;
			case SL_GLOBAL_N: case SL_GLOBAL_NG:
				memcpy(val, N, sizeof(val));
				break;
			case SL_GLOBAL_S: case SL_GLOBAL_U:
				val[0] = u;
				break;
			case SL_GLOBAL_T: case SL_GLOBAL_V:
				val[0] = v;
				break;
			case SL_GLOBAL_DU:
				val[0] = 1.0f / (float)(nu - 1);
				break;
			case SL_GLOBAL_DV:
				val[0] = 1.0f / (float)(nv - 1);
				break;
			case SL_GLOBAL_CS:
				val[0] = 0.9f, val[1] = 0.6f, val[2] = 0.4f;
				break;
			case SL_GLOBAL_OS:
				val[0] = val[1] = val[2] = 1;
				break;
			default:
				break;
			}
			int nc = sl_reg_ncomp(&t->sp->caching->regs[t->sp->caching->global_reg[g]]);
			for (int k = 0; k < nc && k < 3; k++)
				d[(size_t)k * st + i] = val[k];
		}
	}
	struct sl_lighthost lh0;
	sl_lighthost_init(&lh0, NULL, 0);
	lh0.host.print = quiet_print;
	lh0.space_names = space_names;
	lh0.space_mats = (const float (*)[16])space_mats;
	lh0.nspaces = 3;
	CHECK(sl_exec_run(ce, &lh0.host));

	/* The records: values, then steps and du, dv where the layout has them. */
	uint32_t is = lay->in_stride;
	t->rec = calloc((size_t)n * is, sizeof(float));
	t->rec3 = calloc((size_t)3 * n * is, sizeof(float));
	t->du = calloc(n, sizeof(float));
	t->dv = calloc(n, sizeof(float));
	float *tu = calloc(n, sizeof(float)), *tv = calloc(n, sizeof(float));
	float gdu, gdv;
	sl_exec_grid_steps(ce, &gdu, &gdv);
	for (uint32_t i = 0; i < n; i++) {
		t->du[i] = gdu;
		t->dv[i] = gdv;
		t->rec[(size_t)i * is + lay->du_offset] = gdu;
		t->rec[(size_t)i * is + lay->dv_offset] = gdv;
	}
	for (uint32_t k = 0; k < t->sp->ncached; k++) {
		int32_t r = t->sp->cached[k];
		const struct sl_reg *rg = &surf->regs[r];
		if (rg->type == SL_TYPE_STRING)
			continue;
		int nc = sl_reg_ncomp(rg) * (rg->arraylen ? rg->arraylen : 1);
		const float *d = sl_exec_reg(ce, r);
		uint32_t st = rg->varying ? sl_exec_stride(ce) : 1;
		for (int q = 0; q < nc; q++) {
			bool steps = t->sp->cached_deriv[k];
			CHECK(steps == (lay->in_step_u[k] != UINT32_MAX));
			if (steps)
				CHECK(sl_exec_reg_delta(ce, r, q, tu, tv));
			for (uint32_t i = 0; i < n; i++) {
				float v = d[(size_t)q * st + (rg->varying ? i : 0)];
				float *g = t->rec + (size_t)i * is;
				g[lay->in_offset[k] + (uint32_t)q] = v;
				float *b0 = t->rec3 + (size_t)i * is, *bu = t->rec3 + (size_t)(n + i) * is;
				float *bv = t->rec3 + (size_t)(2 * n + i) * is;
				b0[lay->in_offset[k] + (uint32_t)q] = v;
				bu[lay->in_offset[k] + (uint32_t)q] = v + (steps ? tu[i] : 0.0f);
				bv[lay->in_offset[k] + (uint32_t)q] = v + (steps ? tv[i] : 0.0f);
				if (steps) {
					g[lay->in_step_u[k] + (uint32_t)q] = tu[i];
					g[lay->in_step_v[k] + (uint32_t)q] = tv[i];
				}
			}
		}
	}
	free(tu);
	free(tv);
	sl_exec_destroy(ce);

	/* The interpreter on stencils. */
	struct sl_exec *x = sl_exec_create(t->sp->dynamic, 3 * n);
	CHECK(x != NULL);
	if (!x)
		return false;
	for (size_t k = 0; k < ndyn; k++) {
		int pk = sl_program_find_param(surf, dyn[k]);
		float v[3];
		const struct sl_reg *rg = &surf->regs[surf->params[pk].reg];
		memcpy(v, sl_exec_reg(t->c.ix[0], surf->params[pk].reg), sizeof(float) * 3);
		CHECK(sl_exec_set_param(x, dyn[k], v, (uint32_t)sl_reg_ncomp(rg)));
	}
	CHECK(sl_spec_bind_cache(t->sp, x, 3 * n, t->rec3, is, lay->in_offset));
	CHECK(sl_exec_set_stencil(x, n, t->du, t->dv));
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, t->c.x + 1, 1);
	lh.host.print = quiet_print;
	lh.space_names = space_names;
	lh.space_mats = (const float (*)[16])space_mats;
	lh.nspaces = 3;
	lh.light_shader_mats = (const float (*)[16])light_mats;
#ifdef GLSL_TEST_SHADOW_MAPS
	lh.owner = t->ts;
	if (t->ts) {
		lh.host.shadow = st_shadow;
		lh.host.texture = st_texture;
		lh.host.environment = st_environment;
	}
#endif
	bool ok = sl_exec_run(x, &lh.host);
	CHECK(ok);
	bool vary;
	const float *ci = sl_exec_global(x, SL_GLOBAL_CI, &vary);
	t->cpu = calloc((size_t)n * 3, sizeof(float));
	for (uint32_t i = 0; ci && i < n; i++)
		for (int q = 0; q < 3; q++)
			t->cpu[(size_t)i * 3 + q] = ci[(size_t)q * (vary ? sl_exec_stride(x) : 1) +
						       (vary ? i : 0)];
	sl_exec_destroy(x);
	return ok;
}

/* The defaults runs (for the uniforms) of the surface and its light. */
static void stencil_defaults(struct stencil_run *t)
{
	for (int i = 0; i <= t->c.nl; i++) {
		struct space_host sh = { .host = { .space = sh_space }, .shader = NULL };
		sh.host.user = &sh;
		sh.shader = i == 0 ? space_mats[0] : light_mats[i - 1];
		CHECK(sl_exec_run(t->c.ix[i], &sh.host));
	}
}

/*
 * The GPU over the same records; @bind (may be NULL) binds shadow() sites.
 * Fills @gpu (n x 3). Returns false when it could not run.
 */
static bool stencil_gpu(struct stencil_run *t, float *gpu,
			bool (*bind)(struct stencil_run *t, struct gpu_program *gp,
				     struct gpu_binding *b, uint32_t *nb, struct gpu_buffer *bin))
{
	struct gpu_program *gp = gpu_program(ctx, t->src, stderr);
	CHECK(gp != NULL);
	if (!gp)
		return false;
	const struct sl_program *surf = t->c.prog[0];
	uint8_t *is_input = calloc(surf->nregs + 1, 1);
	for (uint32_t i = 0; i < t->slice.ninputs; i++)
		is_input[t->slice.inputs[i]] = 1;
	set_param_uniforms(&t->c, 0, gp, &t->lay, is_input);
	set_param_uniforms(&t->c, 1, gp, &t->lay, NULL);
	free(is_input);
	gpu_uniform_mat4(gp, "l0_shader", light_mats[0]);
	for (int k = 0; k < 3; k++) {
		char name[32];
		snprintf(name, sizeof(name), "space_%s", space_names[k]);
		gpu_uniform_mat4(gp, name, space_mats[k]);
	}
	uint32_t n = t->n, is = t->lay.in_stride, os = t->lay.out_stride;
	struct gpu_buffer *bin = gpu_buffer_create(ctx, (size_t)n * is * sizeof(float), t->rec);
	struct gpu_buffer *bout = gpu_buffer_create(ctx, (size_t)n * os * sizeof(float), NULL);
	struct gpu_binding b[2 + 8] = { { 0, false, bin, true }, { 1, true, bout } };
	uint32_t nb = 2;
	bool ok = !bind || bind(t, gp, b, &nb, bin);
	CHECK(ok);
	float *out = calloc((size_t)n * os, sizeof(float));
	ok = ok && gpu_dispatch(ctx, gp, b, nb, n) &&
	     gpu_buffer_read(bout, 0, (size_t)n * os * sizeof(float), out);
	CHECK(ok);
	/* Ci is output 0 of a specialized slice (spec.h: Ci, Oi, outputs). */
	int32_t ci = surf->global_reg[SL_GLOBAL_CI];
	uint32_t k0 = 0;
	while (k0 < t->slice.noutputs && t->slice.outputs[k0] != ci)
		k0++;
	CHECK(k0 < t->slice.noutputs);
	for (uint32_t i = 0; ok && k0 < t->slice.noutputs && i < n; i++)
		for (int q = 0; q < 3; q++)
			gpu[(size_t)i * 3 + q] = out[(size_t)i * os + t->lay.out_offset[k0] + (uint32_t)q];
	free(out);
	gpu_buffer_destroy(bin);
	gpu_buffer_destroy(bout);
	return ok && k0 < t->slice.noutputs;
}

static void stencil_finish(struct stencil_run *t)
{
	free(t->src);
	if (t->src)
		sl_glsl_layout_finish(&t->lay);
	sl_spec_destroy(t->sp);
	free(t->rec);
	free(t->rec3);
	free(t->du);
	free(t->dv);
	free(t->cpu);
	xc_free(&t->c);
}

/* Largest |gpu - cpu| / max(1, |cpu|) over Ci; counts samples beyond @tol in *nbad. */
static double stencil_compare(const struct stencil_run *t, const float *gpu, double tol,
			      uint32_t *nbad)
{
	double maxerr = 0;
	*nbad = 0;
	for (uint32_t i = 0; i < t->n; i++) {
		bool bad = false;
		for (int q = 0; q < 3; q++) {
			float c = t->cpu[(size_t)i * 3 + q], g = gpu[(size_t)i * 3 + q];
			double e = fabs((double)g - c) / fmax(1.0, fabs((double)c));
			if (!(e <= maxerr))
				maxerr = e;
			if (!(e <= tol)) {
				if (!bad && *nbad < 6)
					fprintf(stderr, "%s: sample %u Ci[%d]: gpu %.9g cpu %.9g\n",
						t->c.name, i, q, g, c);
				bad = true;
			}
		}
		*nbad += bad;
	}
	return maxerr;
}

static const char deriv_src[] =
	"surface dstencil(float Kd = 0.8; float freq = 2.5) {\n"
	"	point Q = P * freq;\n"
	"	float f = sin(xcomp(Q)) * cos(ycomp(Q)) + 0.1 * zcomp(Q) * zcomp(Q);\n"
	"	normal Nq = calculatenormal(Q);\n"
	"	float a = area(Q);\n"
	"	float w = filterstep(0.2, f);\n"
	"	color d = color(Du(f), Dv(f), Deriv(f, xcomp(Q)));\n"
	"	Ci = Kd * (0.1 * d + color(w, 50 * a, 0) +\n"
	"		color(normalize(Nq)) * diffuse(faceforward(normalize(N), I)));\n"
	"	Oi = Os;\n"
	"}\n";

static void aim_pointlight(struct xc *c)
{
	aim_light(c, 1, "pointlight");
}

/*
 * Derivatives of values the GPU computes (Du, Dv, Deriv, area,
 * calculatenormal, filterstep's width) on stencils: a whole surface as the
 * slice, P an input with steps, against the interpreter running the same
 * surface on stencils of the same samples. Within TOL.
 */
static void test_stencil_derivs(void)
{
	enum { NU = 24, NV = 20, NS = NU * NV };
	struct sl_program *surf = compile("dstencil.sl", deriv_src);
	struct sl_program *light = load("pointlight");
	CHECK(surf && light);
	if (!surf || !light || !ctx) {
		sl_program_destroy(surf);
		sl_program_destroy(light);
		return;
	}
	struct stencil_run t;
	memset(&t, 0, sizeof(t));
	t.n = NS;
	xc_init(&t.c, "stencil derivatives", surf, 3 * NS);
	xc_add(&t.c, light);
	aim_pointlight(&t.c);
	xc_setf(&t.c, 0, "freq", 1.7f);
	/* Samples of a grid; the moved blocks differ from the samples in P only. */
	static float stepu[3 * NS], stepv[3 * NS];
	t.du = calloc(NS, sizeof(float));
	t.dv = calloc(NS, sizeof(float));
	float hu = 1.0f / (NU - 1), hv = 1.0f / (NV - 1);
	int32_t inputs[SL_GLOBAL_COUNT], outputs[1] = { surf->global_reg[SL_GLOBAL_CI] };
	uint8_t steps[SL_GLOBAL_COUNT];
	uint32_t nin = 0;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		float *v = t.c.glob[g];
		if (!v)
			continue;
		int nc = sl_reg_ncomp(&surf->regs[surf->global_reg[g]]);
		steps[nin] = g == SL_GLOBAL_P;
		inputs[nin++] = surf->global_reg[g];
		for (uint32_t i = 0; i < NS; i++) {
			float u = (float)(i % NU) * hu, w = (float)(i / NU) * hv, P[3], N[3], Pu[3],
			      Pv[3];
			surface_point(u, w, P, N);
			surface_point(u + hu, w, Pu, N);
			surface_point(u, w + hv, Pv, N);
			surface_point(u, w, P, N);
			t.du[i] = hu;
			t.dv[i] = hv;
			for (int q = 0; q < nc && q < 3; q++) {
				float *b = v + (size_t)q * 3 * NS;
				if (g == SL_GLOBAL_P || g == SL_GLOBAL_I)
					b[i] = P[q];
				else if (g == SL_GLOBAL_N)
					b[i] = N[q];
				stepu[(size_t)q * NS + i] = Pu[q] - P[q];
				stepv[(size_t)q * NS + i] = Pv[q] - P[q];
				bool moved = g == SL_GLOBAL_P;
				b[NS + i] = moved ? b[i] + stepu[(size_t)q * NS + i] : b[i];
				b[2 * NS + i] = moved ? b[i] + stepv[(size_t)q * NS + i] : b[i];
			}
		}
	}
	t.slice = (struct sl_slice){ surf, NULL, inputs, nin, outputs, 1, steps };
	const struct sl_program *lights[1] = { light };
	t.src = sl_glsl_emit(&t.slice, lights, 1, &t.lay, stderr);
	CHECK(t.src != NULL);
	if (t.src) {
		check_valid("stencil derivatives", t.src);
		CHECK(strstr(t.src, "rl_du = texelFetch(u_in") && strstr(t.src, "rl_area(") &&
		      strstr(t.src, "rl_fstep_d(") && strstr(t.src, "rl_pcross("));
		CHECK(t.lay.nshadows == 0 && t.lay.du_offset != UINT32_MAX);
		uint32_t is = t.lay.in_stride;
		t.rec = calloc((size_t)NS * is, sizeof(float));
		for (uint32_t j = 0; j < nin; j++) {
			int g = surf->regs[inputs[j]].global;
			int nc = sl_reg_ncomp(&surf->regs[inputs[j]]);
			CHECK((t.lay.in_step_u[j] != UINT32_MAX) == (steps[j] != 0));
			for (uint32_t i = 0; i < NS; i++)
				for (int q = 0; q < nc; q++) {
					float *r = t.rec + (size_t)i * is;
					r[t.lay.in_offset[j] + (uint32_t)q] = t.c.glob[g][(size_t)q * 3 * NS + i];
					if (steps[j]) {
						r[t.lay.in_step_u[j] + (uint32_t)q] = stepu[(size_t)q * NS + i];
						r[t.lay.in_step_v[j] + (uint32_t)q] = stepv[(size_t)q * NS + i];
					}
				}
		}
		for (uint32_t i = 0; i < NS; i++) {
			t.rec[(size_t)i * is + t.lay.du_offset] = t.du[i];
			t.rec[(size_t)i * is + t.lay.dv_offset] = t.dv[i];
		}
		CHECK(sl_exec_set_stencil(t.c.x[0], NS, t.du, t.dv));
		CHECK(xc_cpu(&t.c));
		bool vary;
		const float *ci = sl_exec_global(t.c.x[0], SL_GLOBAL_CI, &vary);
		t.cpu = calloc((size_t)NS * 3, sizeof(float));
		for (uint32_t i = 0; ci && i < NS; i++)
			for (int q = 0; q < 3; q++)
				t.cpu[(size_t)i * 3 + q] =
					ci[(size_t)q * (vary ? sl_exec_stride(t.c.x[0]) : 1) + (vary ? i : 0)];
		float *gpu = calloc((size_t)NS * 3, sizeof(float));
		if (stencil_gpu(&t, gpu, NULL)) {
			uint32_t nbad;
			double e = stencil_compare(&t, gpu, TOL, &nbad);
			CHECK(e <= TOL);
			/* The derivatives are there: Du(f) and Dv(f) are far from 0 somewhere. */
			double big = 0;
			for (uint32_t i = 0; i < NS; i++)
				big = fmax(big, fabs(t.cpu[i * 3]) + fabs(t.cpu[i * 3 + 1]));
			CHECK(big > 0.5);
			printf("%-44s %u samples, max diff %.2e (tol %.0e)\n", "stencil derivatives", NS,
			       e, TOL);
		}
		free(gpu);
	}
	stencil_finish(&t);
	sl_program_destroy(surf);
	sl_program_destroy(light);
}

static void aim_nomap(struct xc *c)
{
	aim_light(c, 1, "shadowspot");
	xc_setf(c, 1, "coneangle", 1.4f);
	xc_sets(c, 1, "shadowname", "relight-no-such-map.shd");
}

static bool bind_nomap(struct stencil_run *t, struct gpu_program *gp, struct gpu_binding *b,
		       uint32_t *nb, struct gpu_buffer *bin)
{
	if (t->lay.nshadows != 1)
		return false;
	bool ok = gpu_uniform_int(gp, "u_shadow0_size[0]", 0) &&
		  gpu_uniform_int(gp, "u_shadow0_size[1]", 0);
	b[(*nb)++] = (struct gpu_binding){ SL_GLSL_SHADOW_UNIT0, false, bin };
	return ok;
}

/*
 * The shot's path: plastic specialized with the lights' derivatives, baked
 * over a grid, shadowspot's shadow() on stencils of the cached P. Its map is
 * missing on both sides (the fill).
 */
static void test_stencil_specialized(void)
{
	struct sl_program *surf = load("plastic");
	struct sl_program *light = load("shadowspot");
	CHECK(surf && light);
	struct stencil_run t;
	memset(&t, 0, sizeof(t));
	if (surf && light && ctx &&
	    stencil_setup(&t, "plastic + shadowspot, stencils", surf, light, NULL, 0, 16, 12,
			  aim_nomap, NULL)) {
		CHECK(t.lay.nshadows == 1);
		stencil_defaults(&t);
		float *gpu = calloc((size_t)t.n * 3, sizeof(float));
		if (stencil_gpu(&t, gpu, bind_nomap)) {
			uint32_t nbad;
			double e = stencil_compare(&t, gpu, TOL, &nbad);
			CHECK(e <= TOL);
			printf("%-44s %u samples, max diff %.2e (tol %.0e)\n", t.c.name, t.n, e, TOL);
		}
		free(gpu);
	}
	stencil_finish(&t);
	sl_program_destroy(surf);
	sl_program_destroy(light);
}

/* shadowspot's shadow() becomes a site naming its parameter; errors stay clear. */
static void test_shadow_sites(void)
{
	struct sl_program *surf = load("plastic");
	struct sl_program *light = load("shadowspot");
	CHECK(surf && light);
	if (!surf || !light)
		return;
	struct sl_spec *sp = sl_specialize_ex(surf, NULL, 0, SL_SPEC_CACHE_PARAMS |
					      SL_SPEC_LIGHT_DERIVATIVES, stderr);
	CHECK(sp && sp->needs_stencil);
	if (sp) {
		struct sl_slice s = sp->slice;
		s.input_steps = sp->cached_deriv;
		const struct sl_program *lights[2] = { light, light };
		struct sl_glsl_layout lay;
		char *src = sl_glsl_emit(&s, lights, 2, &lay, stderr);
		CHECK(src != NULL);
		if (src) {
			CHECK(lay.nshadows == 2);
			for (uint32_t k = 0; k < lay.nshadows && k < 2; k++) {
				CHECK(lay.shadows[k].light == (int)k);
				CHECK_STR(lay.shadows[k].param, "shadowname");
				CHECK(lay.shadows[k].name == NULL);
			}
			CHECK(strstr(src, "layout(binding = 2) uniform samplerBuffer u_shadow0;") &&
			      strstr(src, "layout(binding = 3) uniform samplerBuffer u_shadow1;") &&
			      strstr(src, "uniform int u_shadow1_size[2];") &&
			      strstr(src, "uniform mat4 u_to_world;"));
			check_valid("shadow sites", src);
			free(src);
			sl_glsl_layout_finish(&lay);
		}
		/* Without input_steps: as before, the fill and no site. */
		s.input_steps = NULL;
		src = sl_glsl_emit(&s, lights, 1, &lay, NULL);
		CHECK(src && lay.nshadows == 0 && !strstr(src, "u_shadow0"));
		free(src);
		sl_glsl_layout_finish(&lay);
		sl_spec_destroy(sp);
	}
	/* A constant name is a site too; a name built at run time is an error. */
	struct sl_program *cs = compile("cshadow.sl", "surface cs() {\n"
					"  Ci = shadow(\"key.shd\", P, \"samples\", 4);\n}\n");
	CHECK(cs != NULL);
	if (cs) {
		int32_t in[1] = { cs->global_reg[SL_GLOBAL_P] }, out[1] = {
			cs->global_reg[SL_GLOBAL_CI] };
		uint8_t steps[1] = { 1 };
		struct sl_slice s = { cs, NULL, in, 1, out, 1, steps };
		struct sl_glsl_layout lay;
		char *src = sl_glsl_emit(&s, NULL, 0, &lay, stderr);
		CHECK(src && lay.nshadows == 1 && lay.shadows[0].light == -1 &&
		      !lay.shadows[0].param && lay.shadows[0].name &&
		      !strcmp(lay.shadows[0].name, "key.shd"));
		CHECK(src && lay.in_stride == 12 /* 3 + 3 + 3 + 2, padded to texels */ && lay.in_step_u[0] == 3 &&
		      lay.in_step_v[0] == 6 && lay.du_offset == 9 && lay.dv_offset == 10);
		if (src)
			check_valid("constant shadow site", src);
		free(src);
		sl_glsl_layout_finish(&lay);
		/* P without steps: its derivatives cannot be taken. */
		steps[0] = 0;
		char *buf = NULL;
		size_t len = 0;
		FILE *diag = open_memstream(&buf, &len);
		src = sl_glsl_emit(&s, NULL, 0, &lay, diag);
		fclose(diag);
		CHECK(src == NULL);
		CHECK(buf && strstr(buf, "cshadow.sl:2:8: error: derivatives of GPU-computed values "
				    "are not supported (shadow)"));
		free(buf);
		free(src);
		sl_program_destroy(cs);
	}
	expect_error("surface e() {\n  string n = format(\"%d.shd\", 1);\n"
		     "  Ci = shadow(n, P);\n}\n", NULL, "format() is not supported on the GPU");
	sl_program_destroy(surf);
	sl_program_destroy(light);
}

/* A shadow() site with no map bound (size 0 x 0) gives the fill, as a missing file does. */
static void test_shadow_fill(void)
{
	struct sl_program *surf = compile("fill.sl", "surface fill(string map = \"none.shd\") {\n"
					  "  Ci = color shadow(map, P, \"fill\", 0.375) + s;\n}\n");
	CHECK(surf != NULL);
	if (!surf || !ctx) {
		sl_program_destroy(surf);
		return;
	}
	int32_t in[2] = { surf->global_reg[SL_GLOBAL_P], surf->global_reg[SL_GLOBAL_S] };
	int32_t out[1] = { surf->global_reg[SL_GLOBAL_CI] };
	uint8_t steps[2] = { 1, 0 };
	struct sl_slice s = { surf, NULL, in, 2, out, 1, steps };
	struct sl_glsl_layout lay;
	char *src = sl_glsl_emit(&s, NULL, 0, &lay, stderr);
	CHECK(src && lay.nshadows == 1 && lay.shadows[0].param &&
	      !strcmp(lay.shadows[0].param, "map"));
	struct gpu_program *gp = src ? gpu_program(ctx, src, stderr) : NULL;
	CHECK(gp != NULL);
	if (gp) {
		enum { N = 100 };
		uint32_t is = lay.in_stride;
		float *rec = calloc((size_t)N * is, sizeof(float)), res[N * 3];
		for (uint32_t i = 0; i < N; i++) {
			float *r = rec + (size_t)i * is;
			r[lay.in_offset[0]] = (float)i * 0.01f;
			r[lay.in_offset[0] + 1] = 0.5f;
			r[lay.in_offset[0] + 2] = 3;
			r[lay.in_offset[1]] = (float)i * 0.001f;
			r[lay.in_step_u[0]] = 0.01f;
			r[lay.in_step_v[0] + 1] = 0.01f;
			r[lay.du_offset] = r[lay.dv_offset] = 0.1f;
		}
		struct gpu_buffer *bin = gpu_buffer_create(ctx, (size_t)N * is * sizeof(float), rec);
		struct gpu_buffer *bout = gpu_buffer_create(ctx, sizeof(res), NULL);
		CHECK(gpu_uniform_int(gp, "u_shadow0_size[0]", 0));
		CHECK(gpu_uniform_int(gp, "u_shadow0_size[1]", 0));
		struct gpu_binding b[3] = { { 0, false, bin, true }, { 1, true, bout },
					    { SL_GLSL_SHADOW_UNIT0, false, bin } };
		CHECK(gpu_dispatch(ctx, gp, b, 3, N));
		CHECK(gpu_buffer_read(bout, 0, sizeof(res), res));
		double maxerr = 0;
		for (uint32_t i = 0; i < N; i++)
			for (int q = 0; q < 3; q++)
				maxerr = fmax(maxerr, fabs(res[i * 3 + q] - (0.375 + i * 0.001f)));
		CHECK(maxerr <= 1e-6);
		free(rec);
		gpu_buffer_destroy(bin);
		gpu_buffer_destroy(bout);
	}
	free(src);
	sl_glsl_layout_finish(&lay);
	sl_program_destroy(surf);
}

#ifdef GLSL_TEST_SHADOW_MAPS
#define MAP_NAME "relight_test_glsl_shadow.exr"
#define MAP_W 64
#define MAP_H 48

static float current_to_world[16];
static struct gpu_shadow_map *test_map;

/*
 * A depth map seen from the viewing camera itself (the map's camera space
 * is current space, with an arbitrary world between): the left part of the
 * image holds an occluder at depth 2, with a step edge down the middle and
 * a notch, the rest is empty.
 */
static bool write_test_map(const char *path)
{
	float world_to_current[16], proj[16] = { 0 };
	rigid(current_to_world, 0.3f, -1, 0.5f, 0.8f, 1.5f, -2, 0.5f, 1.0f);
	if (!sl_m44_inverse(world_to_current, current_to_world))
		return false;
	/* s = 0.5 + 0.4 x / z, t = 0.5 - 0.4 y / z, row vectors. */
	proj[0] = 0.4f;
	proj[5] = -0.4f;
	proj[8] = 0.5f;
	proj[9] = 0.5f;
	proj[11] = 1;
	static const char *const zname[] = { "Z" };
	struct reyes_image im;
	if (!reyes_image_init(&im, MAP_W, MAP_H, 1, zname))
		return false;
	for (uint32_t y = 0; y < MAP_H; y++)
		for (uint32_t x = 0; x < MAP_W; x++) {
			bool occ = x < MAP_W / 2 || (y > MAP_H / 3 && y < MAP_H / 2 && x < 3 * MAP_W / 4);
			im.data[y * MAP_W + x] = occ ? 2.0f + 0.01f * (float)(x % 7) : 0.0f;
		}
	im.has_matrices = true;
	memcpy(im.world_to_camera, world_to_current, sizeof(im.world_to_camera));
	sl_m44_mul(im.world_to_ndc, world_to_current, proj);
	bool ok = reyes_image_write_exr(path, &im, false, stderr);
	reyes_image_finish(&im);
	return ok;
}

static void aim_shadowspot(struct xc *c)
{
	aim_light(c, 1, "shadowspot");
	xc_setf(c, 1, "coneangle", 1.4f);
	xc_setf(c, 1, "samples", 16);
	xc_setf(c, 1, "blur", 0.02f);
	xc_sets(c, 1, "shadowname", MAP_NAME);
}

static bool bind_test_map(struct stencil_run *t, struct gpu_program *gp, struct gpu_binding *b,
			  uint32_t *nb, struct gpu_buffer *bin)
{
	(void)bin;
	if (t->lay.nshadows != 1)
		return false;
	return gpu_shadow_map_bind(ctx, gp, 0, test_map, current_to_world, &b[(*nb)++]);
}

/*
 * shadowspot with a real map over plastic, on stencils: the GPU's shadow()
 * against reyes_tex_shadow through the interpreter, every sample within TOL.
 */
static void test_shadow_map(void)
{
	char dir[] = "/tmp/relight-glsl-XXXXXX";
	CHECK(mkdtemp(dir) != NULL);
	char path[128];
	snprintf(path, sizeof(path), "%s/%s", dir, MAP_NAME);
	CHECK(write_test_map(path));
	struct reyes_texsys *ts = reyes_texsys_create(dir, current_to_world, stderr);
	struct sl_program *surf = load("plastic");
	struct sl_program *light = load("shadowspot");
	CHECK(ts && surf && light);
	struct stencil_run t;
	memset(&t, 0, sizeof(t));
	shadow_full = shadow_partial = 0;
	if (ts && surf && light &&
	    stencil_setup(&t, "shadowspot + plastic", surf, light, NULL, 0, 32, 24, aim_shadowspot,
			  ts)) {
		CHECK(t.lay.nshadows == 1 && t.lay.shadows[0].light == 0);
		char err[256];
		test_map = gpu_shadow_map_load(ctx, ts, MAP_NAME, err, sizeof(err));
		CHECK(test_map != NULL);
		if (!test_map)
			fprintf(stderr, "%s\n", err);
		uint32_t w = 0, h = 0;
		gpu_shadow_map_size(test_map, &w, &h);
		CHECK(w == MAP_W && h == MAP_H && gpu_shadow_map_bytes(test_map) == MAP_W * MAP_H * 4);
		stencil_defaults(&t);
		float *gpu = calloc((size_t)t.n * 3, sizeof(float));
		if (test_map && stencil_gpu(&t, gpu, bind_test_map)) {
			uint32_t nbad;
			double e = stencil_compare(&t, gpu, TOL, &nbad);
			CHECK(e <= TOL);
			CHECK(nbad == 0);
			/* The map matters: samples in full shadow and on the edge's penumbra. */
			CHECK(shadow_full > t.n / 10 && shadow_partial > 10);
			printf("%-44s %u samples (lookups: %u in full shadow, %u partly), max diff %.2e "
			       "(tol %.0e), %u beyond\n", "shadowspot + plastic, shadow map", t.n,
			       shadow_full, shadow_partial, e, TOL, nbad);
		}
		free(gpu);
		gpu_shadow_map_destroy(test_map);
		test_map = NULL;
	}
	stencil_finish(&t);
	sl_program_destroy(surf);
	sl_program_destroy(light);
	reyes_texsys_destroy(ts);
	unlink(path);
	rmdir(dir);
}

/* ---- texture() and environment() of named maps on stencils ---- */

static struct gpu_texmap *test_tex;

/*
 * A picture of @w x @h with sharp cells and a smooth ramp (so that every
 * filter footprint and mip level shows), written to @path as an EXR.
 */
static bool write_test_picture(const char *path, uint32_t w, uint32_t h, uint32_t nch,
			       uint32_t shift)
{
	static const char *const names[] = { "R", "G", "B" };
	struct reyes_image im;
	if (!reyes_image_init(&im, w, h, nch, names))
		return false;
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++)
			for (uint32_t c = 0; c < nch; c++) {
				bool cell = ((x * 5 / w) + (y * 3 / h) + c + shift) % 2 == 0;
				im.data[((size_t)y * w + x) * nch + c] =
					(cell ? 0.9f : 0.1f) + 0.3f * (float)x / (float)w * (float)(c + 1) +
					0.1f * (float)shift;
			}
	bool ok = reyes_image_write_exr(path, &im, false, stderr);
	reyes_image_finish(&im);
	return ok;
}

static const char *tex_param;       /* the light's parameter naming the map */
static const char *tex_extra;       /* a float parameter to set, or NULL */
static float tex_extra_value;

static void aim_textured(struct xc *c)
{
	const float from[3] = { 0, 0, 0 }, to[3] = { 0.05f, -0.03f, 1 };
	if (sl_program_find_param(c->prog[1], "to") >= 0) {
		xc_set(c, 1, "from", from, 3);
		xc_set(c, 1, "to", to, 3);
	} else if (sl_program_find_param(c->prog[1], "from") >= 0) {
		xc_set(c, 1, "from", from, 3);
	}
	if (sl_program_find_param(c->prog[1], "coneangle") >= 0)
		xc_setf(c, 1, "coneangle", 0.5f);
	if (sl_program_find_param(c->prog[1], "fov") >= 0)
		xc_setf(c, 1, "fov", 0.9f);
	if (tex_extra)
		xc_setf(c, 1, tex_extra, tex_extra_value);
	xc_sets(c, 1, tex_param, "relight_test_glsl_tex.tx");
}

static bool bind_test_tex(struct stencil_run *t, struct gpu_program *gp, struct gpu_binding *b,
			  uint32_t *nb, struct gpu_buffer *bin)
{
	if (t->lay.nmaps != 1)
		return false;
	(void)gp;
	b[*nb].buffer = bin;
	return gpu_texmap_bind(test_tex, SL_GLSL_SHADOW_UNIT0 + t->lay.nshadows, &b[(*nb)++]);
}

/*
 * Light shaders of shaders/ that read a named map, over plastic on
 * stencils: the GPU's texture() and environment() against render/texture.c
 * through the interpreter, every sample within TOL; then with no map bound,
 * against the interpreter without the file (the fill).
 */
static void test_texture_maps(void)
{
	static const struct {
		const char *light, *param, *make, *extra;
		float extra_value;
		uint32_t w, h, nch;
	} cases[] = {
		{ "uberlight", "slidename", "black", NULL, 0, 64, 64, 3 },
		{ "projector", "slidename", "clamp", "blur", 0.05f, 48, 32, 3 },
		{ "cookielight", "cookiename", "periodic", "cookiescale", 6, 40, 40, 1 },
		{ "cookielight", "cookiename", "periodic", "cookiescale", 0.5f, 16, 16, 3 },
		{ "cookielight", "cookiename", "clamp", "cookiescale", 0.5f, 16, 16, 3 },
		{ "projector", "slidename", "periodic", "blur", 0.0f, 16, 16, 3 },
		{ "envcolorlight", "envname", "latlong", NULL, 0, 64, 32, 3 },
		{ "envcolorlight", "envname", "latlong", "blur", 0.1f, 64, 32, 3 },
		{ "envcolorlight", "envname", "cube", NULL, 0, 16, 16, 3 },
		{ "envcolorlight", "envname", "cube", "blur", 0.2f, 32, 32, 3 },
	};
	char dir[] = "/tmp/relight-glsl-XXXXXX";
	CHECK(mkdtemp(dir) != NULL);
	char pic[160], tex[160];
	snprintf(pic, sizeof(pic), "%s/picture.exr", dir);
	snprintf(tex, sizeof(tex), "%s/relight_test_glsl_tex.tx", dir);
	struct sl_program *surf = load("plastic");
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		CHECK(write_test_picture(pic, cases[i].w, cases[i].h, cases[i].nch, 0));
		if (!strcmp(cases[i].make, "cube")) {
			/* six faces, each its own picture, 100 degrees wide (a margin) */
			char faces[6][160];
			const char *fp[6];
			for (int f = 0; f < 6; f++) {
				snprintf(faces[f], sizeof(faces[f]), "%s/face%d.exr", dir, f);
				fp[f] = faces[f];
				CHECK(write_test_picture(faces[f], cases[i].w, cases[i].h, cases[i].nch,
							 (uint32_t)f));
			}
			CHECK(reyes_make_cube_environment(fp, tex, 100, "box", 1, 1, stderr));
			for (int f = 0; f < 6; f++)
				unlink(faces[f]);
		} else if (!strcmp(cases[i].make, "latlong")) {
			CHECK(reyes_make_latlong_environment(pic, tex, "box", 1, 1, stderr));
		} else {
			CHECK(reyes_make_texture(pic, tex, cases[i].make, cases[i].make, "box", 1, 1,
						 stderr));
		}
		struct reyes_texsys *ts = reyes_texsys_create(dir, current_to_world, stderr);
		struct sl_program *light = load(cases[i].light);
		CHECK(ts && surf && light);
		tex_param = cases[i].param;
		tex_extra = cases[i].extra;
		tex_extra_value = cases[i].extra_value;
		char name[96];
		snprintf(name, sizeof(name), "%s + plastic, %s %ux%u%s%s", cases[i].light,
			 cases[i].make, cases[i].w, cases[i].h, cases[i].extra ? " " : "",
			 cases[i].extra ? cases[i].extra : "");
		struct stencil_run t;
		memset(&t, 0, sizeof(t));
		if (ts && surf && light &&
		    stencil_setup(&t, name, surf, light, NULL, 0, 32, 24, aim_textured, ts)) {
			CHECK(t.lay.nmaps == 1 && t.lay.maps[0].light == 0 &&
			      t.lay.maps[0].param && !strcmp(t.lay.maps[0].param, cases[i].param));
			char err[256];
			test_tex = gpu_texmap_load(ctx, ts, "relight_test_glsl_tex.tx", err, sizeof(err));
			CHECK(test_tex != NULL);
			if (!test_tex)
				fprintf(stderr, "%s\n", err);
			stencil_defaults(&t);
			float *gpu = calloc((size_t)t.n * 3, sizeof(float));
			if (test_tex && stencil_gpu(&t, gpu, bind_test_tex)) {
				uint32_t nbad;
				double e = stencil_compare(&t, gpu, TOL, &nbad);
				CHECK(e <= TOL);
				CHECK(nbad == 0);
				printf("%-44s %u samples, max diff %.2e (tol %.0e), %u beyond\n", name,
				       t.n, e, TOL, nbad);
			}
			free(gpu);
			gpu_texmap_destroy(test_tex);
			test_tex = NULL;
		}
		stencil_finish(&t);
		sl_program_destroy(light);
		reyes_texsys_destroy(ts);
		unlink(tex);
	}
	sl_program_destroy(surf);
	unlink(pic);
	rmdir(dir);
}
#endif

int main(void)
{
	init_spaces();
	/* What needs no GPU: diagnostics, layouts, validation. */
	RUN(test_errors);
	RUN(test_layout);
	RUN(test_shadow_sites);
	char err[256] = "";
	ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "\n*** SKIP: no OpenGL 4.3 context (%s): the GPU cross-checks "
			"did not run ***\n\n", err);
		int rc = test_finish();
		return rc ? rc : 77;
	}
	printf("GPU: %s%s\n", gpu_renderer(ctx), gpu_is_software(ctx) ? " (software)" : "");
	RUN(test_warnings);
	RUN(test_slice);
	RUN(test_control_flow);
	RUN(test_math);
	RUN(test_geometry);
	RUN(test_transforms);
	RUN(test_colors);
	RUN(test_splines);
	RUN(test_arrays);
	RUN(test_strings);
	RUN(test_noise);
	RUN(test_illuminance);
	RUN(test_promoted_uniforms);
	RUN(test_flat_expression);
	RUN(test_per_light);
	RUN(test_solar_all);
	RUN(test_other_shaders);
	RUN(test_imagers);
	RUN(test_library_lights);
	RUN(test_library_surfaces);
	RUN(test_specialized_library);
	RUN(test_uberlight_modes);
	RUN(test_stencil_derivs);
	RUN(test_stencil_specialized);
	RUN(test_shadow_fill);
#ifdef GLSL_TEST_SHADOW_MAPS
	RUN(test_shadow_map);
	RUN(test_texture_maps);
#else
	printf("*** the shadow map cross-check needs test_glsl linked with the renderer and the "
	       "GPU runtime (libruntime_dep): not built ***\n");
#endif
	RUN(test_benchmark);
	gpu_destroy(ctx);
	return test_finish();
}

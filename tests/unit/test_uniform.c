/*
 * Storage classes as production shaders use them, and expressions as
 * generated shaders write them.
 *
 * A local declared uniform that has to vary is promoted to varying, as prman
 * and aqsl do (infer.c). Each pattern of shader libraries that relies on it
 * is compiled twice, as written (`uniform`) and with its declarations made
 * `varying` (the -D STORAGE switch), and the two must agree at every point,
 * exactly: promotion means "as if declared varying". Where the answer has a
 * closed form the values are checked against it too. random() stored into a
 * uniform is one value for the grid; stored into a varying, one per point.
 *
 * A flat chain of 10,000 operands compiles, runs on the interpreter (checked
 * against the same sum in double precision, relative tolerance 1e-5: float
 * rounding over 10,000 additions of values below 10) and generates GLSL;
 * real nesting past 256 levels and an expression past the size limit are
 * still errors.
 */
#include "test.h"

#include "exec.h"
#include "glsl.h"
#include "ir.h"
#include "lighthost.h"
#include "sl.h"
#include "spec.h"

#include <stdbool.h>
#include <stdint.h>

#define NU 8
#define NV 2
#define NPT (NU * NV)

/* ---- compiling and running ---- */

static struct sl_program *compile_as(const char *name, const char *src, const char *storage,
				     FILE *diag)
{
	char def[64];
	snprintf(def, sizeof(def), "STORAGE=%s", storage);
	const char *defs[] = { def };
	struct sl_options o = { .defines = defs, .n_defines = 1, .diag = diag };
	return sl_compile_string(name, src, strlen(src), &o);
}

/* The grid of run_golden.c: u = iu/(NU-1), v = iv/(NV-1), s = u, t = v,
 * P = (u, v, 0), N = Ng = (0, 0, 1), E = (0, 0, -1), I = P - E. */
static void fill_globals(struct sl_exec *x)
{
	uint32_t st = sl_exec_stride(x);
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool varying;
		float *d = sl_exec_global(x, (enum sl_global)g, &varying);
		if (!d)
			continue;
		for (uint32_t i = 0; i < (varying ? NPT : 1u); i++) {
			float u = (float)(i % NU) / (NU - 1), v = (float)(i / NU) / (NV - 1);
			float c3[3] = { 0, 0, 0 };
			float f = 0;
			switch (g) {
			case SL_GLOBAL_P: case SL_GLOBAL_PS: c3[0] = u, c3[1] = v; break;
			case SL_GLOBAL_N: case SL_GLOBAL_NG: c3[2] = 1; break;
			case SL_GLOBAL_E: c3[2] = -1; break;
			case SL_GLOBAL_I: c3[0] = u, c3[1] = v, c3[2] = 1; break;
			case SL_GLOBAL_CS: case SL_GLOBAL_OS: c3[0] = c3[1] = c3[2] = 1; break;
			case SL_GLOBAL_DPDU: c3[0] = 1; break;
			case SL_GLOBAL_DPDV: c3[1] = 1; break;
			case SL_GLOBAL_S: case SL_GLOBAL_U: f = u; break;
			case SL_GLOBAL_T: case SL_GLOBAL_V: f = v; break;
			case SL_GLOBAL_DU: f = 1.0f / (NU - 1); break;
			case SL_GLOBAL_DV: f = 1.0f / (NV - 1); break;
			case SL_GLOBAL_NCOMPS: f = 3; break;
			default: break;
			}
			enum sl_global e = (enum sl_global)g;
			bool triple = e == SL_GLOBAL_P || e == SL_GLOBAL_PS || e == SL_GLOBAL_N ||
				      e == SL_GLOBAL_NG || e == SL_GLOBAL_E || e == SL_GLOBAL_I ||
				      e == SL_GLOBAL_CS || e == SL_GLOBAL_OS || e == SL_GLOBAL_CI ||
				      e == SL_GLOBAL_OI || e == SL_GLOBAL_DPDU || e == SL_GLOBAL_DPDV ||
				      e == SL_GLOBAL_L || e == SL_GLOBAL_CL || e == SL_GLOBAL_OL ||
				      e == SL_GLOBAL_DPDTIME;
			size_t step = varying ? st : 1;
			if (triple)
				for (int c = 0; c < 3; c++)
					d[c * step + i] = c3[c];
			else
				d[i] = f;
		}
	}
}

static bool run(struct sl_exec *x, const struct sl_host *host)
{
	if (!sl_exec_set_grid(x, NU, NV))
		return false;
	fill_globals(x);
	return sl_exec_run(x, host);
}

/* Component @c of output parameter @name at point @i (NaN if there is none). */
static float out(struct sl_exec *x, const struct sl_program *p, const char *name, int c,
		 uint32_t i)
{
	int k = sl_program_find_param(p, name);
	if (k < 0)
		return NAN;
	int32_t r = p->params[k].reg;
	const float *d = sl_exec_reg(x, r);
	return p->regs[r].varying ? d[(size_t)c * sl_exec_stride(x) + i] : d[c];
}

/* Do the programs @a and @b, run on the same grid, agree on @names everywhere? */
static void check_same(struct sl_exec *xa, const struct sl_program *a, struct sl_exec *xb,
		       const struct sl_program *b, const char *const *names, int n, int ncomp)
{
	for (int k = 0; k < n; k++)
		for (uint32_t i = 0; i < NPT; i++)
			for (int c = 0; c < ncomp; c++)
				CHECK_NEAR(out(xa, a, names[k], c, i), out(xb, b, names[k], c, i), 0);
}

/* Is @name listed under "promoted" in @p's compile report? */
static bool reported_promoted(const struct sl_program *p, const char *name)
{
	char *text = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&text, &len);
	if (!f)
		return false;
	sl_emit_report(p, NULL, f);
	fclose(f);
	const char *list = strstr(text, "\"promoted\": [");
	const char *end = list ? strstr(list, "]") : NULL;
	char want[80];
	snprintf(want, sizeof(want), "{\"name\": \"%s\"", name);
	const char *hit = list ? strstr(list, want) : NULL;
	bool ok = hit && hit < end;
	free(text);
	return ok;
}

/* ---- a. the uniform locals of an fBm inlined under a varying if ---- */

/* Advanced RenderMan's noises.h style: uniform counters and amplitudes. */
static const char fbm_src[] =
	"#define snoise(x) (2 * noise(x) - 1)\n"
	"float fBm(point p; uniform float octaves, lacunarity, gain)\n"
	"{\n"
	"	STORAGE float amp = 1;\n"
	"	varying point pp = p;\n"
	"	varying float sum = 0;\n"
	"	STORAGE float i;\n"
	"	for (i = 0; i < octaves; i += 1) {\n"
	"		sum += amp * snoise(pp);\n"
	"		amp *= gain;\n"
	"		pp *= lacunarity;\n"
	"	}\n"
	"	return sum;\n"
	"}\n"
	"surface fbmif(float octaves = 5; output varying float f = 0, g = 0)\n"
	"{\n"
	"	point q = P * 3 + point(0.3, 0.7, 0.1);\n"
	"	if (s > 0.4)\n"
	"		f = fBm(q, octaves, 2, 0.5);\n"
	"	g = fBm(q, octaves, 2, 0.5);\n"
	"	Ci = f;\n"
	"}\n";

static void test_fbm_under_if(void)
{
	struct sl_program *u = compile_as("fbmif.sl", fbm_src, "uniform", stderr);
	struct sl_program *v = compile_as("fbmif.sl", fbm_src, "varying", stderr);
	CHECK(u != NULL);
	CHECK(v != NULL);
	if (!u || !v)
		goto out;
	/* The counter and the amplitude of the call under the if are promoted
	 * (noted in the report); those of the call outside it stay uniform. */
	CHECK(reported_promoted(u, "i"));
	CHECK(reported_promoted(u, "amp"));
	struct sl_exec *xu = sl_exec_create(u, NPT), *xv = sl_exec_create(v, NPT);
	CHECK(run(xu, NULL));
	CHECK(run(xv, NULL));
	static const char *const names[] = { "f", "g" };
	check_same(xu, u, xv, v, names, 2, 1);
	/* Where the if holds, the call under it is the call outside it. */
	int inside = 0;
	for (uint32_t i = 0; i < NPT; i++) {
		float s = (float)(i % NU) / (NU - 1);
		if (s > 0.4f) {
			CHECK_NEAR(out(xu, u, "f", 0, i), out(xu, u, "g", 0, i), 0);
			inside++;
		} else {
			CHECK_NEAR(out(xu, u, "f", 0, i), 0, 0);
		}
	}
	CHECK(inside > 0 && inside < NPT);
	/* An fBm, not a constant: its values differ over the grid. */
	CHECK(out(xu, u, "g", 0, 0) != out(xu, u, "g", 0, NPT - 1));
	sl_exec_destroy(xu);
	sl_exec_destroy(xv);
out:
	sl_program_destroy(u);
	sl_program_destroy(v);
}

/* ---- b. a uniform counter of a loop whose condition varies ---- */

static const char loop_src[] =
	"surface vloop(float maxoctaves = 6; output varying float n = 0, fwo = 0)\n"
	"{\n"
	"	STORAGE float i;\n"
	"	float fw = s * 0.9 + 0.02;\n"
	"	for (i = 0; i < maxoctaves && fw < 1.0; i += 1)\n"
	"		fw *= 2;\n"
	"	n = i;\n"
	"	fwo = fw;\n"
	"}\n";

static void test_varying_loop_condition(void)
{
	struct sl_program *u = compile_as("vloop.sl", loop_src, "uniform", stderr);
	struct sl_program *v = compile_as("vloop.sl", loop_src, "varying", stderr);
	CHECK(u != NULL);
	CHECK(v != NULL);
	if (!u || !v)
		goto out;
	CHECK(reported_promoted(u, "i"));
	struct sl_exec *xu = sl_exec_create(u, NPT), *xv = sl_exec_create(v, NPT);
	CHECK(run(xu, NULL));
	CHECK(run(xv, NULL));
	static const char *const names[] = { "n", "fwo" };
	check_same(xu, u, xv, v, names, 2, 1);
	/* Closed form: the doublings that take fw0 to 1 or more, at most 6. */
	for (uint32_t i = 0; i < NPT; i++) {
		float fw = (float)(i % NU) / (NU - 1) * 0.9f + 0.02f;
		int k = 0;
		while (k < 6 && fw < 1) {
			fw *= 2;
			k++;
		}
		CHECK_NEAR(out(xu, u, "n", 0, i), k, 0);
		CHECK_NEAR(out(xu, u, "fwo", 0, i), fw, 0);
	}
	/* 0.02 needs 6 doublings, 0.92 one: the trip counts differ. */
	CHECK_NEAR(out(xu, u, "n", 0, 0), 6, 0);
	CHECK_NEAR(out(xu, u, "n", 0, NU - 1), 1, 0);
	sl_exec_destroy(xu);
	sl_exec_destroy(xv);
out:
	sl_program_destroy(u);
	sl_program_destroy(v);
}

/* ---- c. uniforms inside illuminate and illuminance: message passing ---- */

/* A light whose falloff goes through a uniform assigned inside illuminate. */
static const char msg_light_src[] =
	"light msglight(float intensity = 1; color lightcolor = 1;\n"
	"	point from = point(0, 0, -1); output float __nonspecular = 0)\n"
	"{\n"
	"	STORAGE float k = 0;\n"
	"	illuminate(from) {\n"
	"		k = 1 / (1 + L . L);\n"
	"		Cl = intensity * lightcolor * k;\n"
	"	}\n"
	"}\n";

/* The standard idiom: a uniform message read for each light in illuminance. */
static const char msg_surf_src[] =
	"surface msgsurf(output varying color spec = 0, diff = 0; output varying float seen = 0)\n"
	"{\n"
	"	STORAGE float nonspec = 0;\n"
	"	illuminance(P) {\n"
	"		nonspec = 0;\n"
	"		lightsource(\"__nonspecular\", nonspec);\n"
	"		spec += (1 - nonspec) * Cl;\n"
	"		diff += Cl;\n"
	"		STORAGE float one = 1;\n"
	"		seen += one;\n"
	"	}\n"
	"	Ci = spec;\n"
	"}\n";

static void run_lit(struct sl_exec *surf, struct sl_exec **lights)
{
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, lights, 2);
	CHECK(run(surf, &lh.host));
}

static void test_message_passing(void)
{
	struct sl_program *su = compile_as("msgsurf.sl", msg_surf_src, "uniform", stderr);
	struct sl_program *sv = compile_as("msgsurf.sl", msg_surf_src, "varying", stderr);
	struct sl_program *lu = compile_as("msglight.sl", msg_light_src, "uniform", stderr);
	struct sl_program *lv = compile_as("msglight.sl", msg_light_src, "varying", stderr);
	CHECK(su && sv && lu && lv);
	if (!su || !sv || !lu || !lv)
		goto out;
	CHECK(reported_promoted(su, "nonspec"));
	CHECK(reported_promoted(su, "one"));
	CHECK(reported_promoted(lu, "k"));
	/* Light 0: intensity 1, specular; light 1: intensity 2, __nonspecular 1. */
	struct sl_exec *lights_u[2] = { sl_exec_create(lu, NPT), sl_exec_create(lu, NPT) };
	struct sl_exec *lights_v[2] = { sl_exec_create(lv, NPT), sl_exec_create(lv, NPT) };
	float two = 2, one = 1;
	CHECK(sl_exec_set_param(lights_u[1], "intensity", &two, 1));
	CHECK(sl_exec_set_param(lights_u[1], "__nonspecular", &one, 1));
	CHECK(sl_exec_set_param(lights_v[1], "intensity", &two, 1));
	CHECK(sl_exec_set_param(lights_v[1], "__nonspecular", &one, 1));
	struct sl_exec *xu = sl_exec_create(su, NPT), *xv = sl_exec_create(sv, NPT);
	run_lit(xu, lights_u);
	run_lit(xv, lights_v);
	static const char *const names[] = { "spec", "diff", "seen" };
	check_same(xu, su, xv, sv, names, 3, 1);
	/*
	 * Closed form: L = Ps - from = (u, v, 1), so each light gives
	 * Cl = intensity / (2 + u^2 + v^2); spec sees light 0 only, diff both.
	 */
	for (uint32_t i = 0; i < NPT; i++) {
		double u = (double)(i % NU) / (NU - 1), v = (double)(i / NU) / (NV - 1);
		double cl = 1 / (2 + u * u + v * v);
		for (int c = 0; c < 3; c++) {
			CHECK_NEAR(out(xu, su, "spec", c, i), cl, 1e-6);
			CHECK_NEAR(out(xu, su, "diff", c, i), 3 * cl, 1e-6);
		}
		CHECK_NEAR(out(xu, su, "seen", 0, i), 2, 0);
	}
	for (int k = 0; k < 2; k++) {
		sl_exec_destroy(lights_u[k]);
		sl_exec_destroy(lights_v[k]);
	}
	sl_exec_destroy(xu);
	sl_exec_destroy(xv);
out:
	sl_program_destroy(su);
	sl_program_destroy(sv);
	sl_program_destroy(lu);
	sl_program_destroy(lv);
}

/* ---- d. random() in a uniform context ---- */

static const char random_src[] =
	"surface rnd(output varying color uc = 0, vc = 0; output varying float ua = 0,\n"
	"	va = 0, uif = -1)\n"
	"{\n"
	"	uniform color c = color(random(), random(), random());\n"
	"	varying color d = color(random(), random(), random());\n"
	"	uniform float a;\n"
	"	a = random();\n"
	"	float b = random();\n"
	"	uc = c;\n"
	"	vc = d;\n"
	"	ua = a;\n"
	"	va = b;\n"
	"	if (s > 0.5) {\n"
	"		uniform float r = random();\n"
	"		uif = r;\n"
	"	}\n"
	"	Ci = c;\n"
	"}\n";

static void test_random_uniform(void)
{
	struct sl_program *p = compile_as("rnd.sl", random_src, "uniform", stderr);
	CHECK(p != NULL);
	if (!p)
		return;
	/* c and a are one value for the grid: they are not promoted. */
	CHECK(!reported_promoted(p, "c"));
	CHECK(!reported_promoted(p, "a"));
	struct sl_exec *x = sl_exec_create(p, NPT);
	CHECK(run(x, NULL));
	for (int c = 0; c < 3; c++) {
		float c0 = out(x, p, "uc", c, 0);
		CHECK(c0 >= 0 && c0 < 1);
		bool vary = false;
		for (uint32_t i = 1; i < NPT; i++) {
			CHECK_NEAR(out(x, p, "uc", c, i), c0, 0);
			vary = vary || out(x, p, "vc", c, i) != out(x, p, "vc", c, 0);
		}
		CHECK(vary);
	}
	/* the three components are three draws */
	CHECK(out(x, p, "uc", 0, 0) != out(x, p, "uc", 1, 0));
	bool vary = false;
	float r0 = -1;
	for (uint32_t i = 0; i < NPT; i++) {
		CHECK_NEAR(out(x, p, "ua", 0, i), out(x, p, "ua", 0, 0), 0);
		vary = vary || out(x, p, "va", 0, i) != out(x, p, "va", 0, 0);
		float s = (float)(i % NU) / (NU - 1);
		float r = out(x, p, "uif", 0, i);
		if (s <= 0.5f) {
			CHECK_NEAR(r, -1, 0);
		} else {
			/* under a varying if, still one draw for the grid */
			if (r0 < 0)
				r0 = r;
			CHECK(r >= 0 && r < 1);
			CHECK_NEAR(r, r0, 0);
		}
	}
	CHECK(vary);
	sl_exec_destroy(x);
	sl_program_destroy(p);
}

/*
 * The uniform random() through specialization: it is cache-required (the
 * GPU cannot draw it), so the caching program computes it, one value for
 * the grid, and the dynamic part reads it from the cache. The dynamic
 * program on the interpreter must give what the whole shader gives, and the
 * slice's GLSL must generate.
 */
static const char random_spec_src[] =
	"surface rndspec(float Kd = 0.5)\n"
	"{\n"
	"	uniform float k = random();\n"
	"	float j = random();\n"
	"	Ci = color(Kd * k, Kd * j, Kd * (k + s));\n"
	"}\n";

/*
 * Run @p whole and specialized for its parameter Kd = @kd (the caching
 * program, then the dynamic program on its cache); Ci of both into @whole
 * and @dyn (3 x NPT, component-major). The slice's GLSL must generate.
 */
static bool run_specialized(const struct sl_program *p, float kd, float *whole, float *dyn)
{
	const char *dynp[] = { "Kd" };
	struct sl_spec *sp = sl_specialize(p, dynp, 1, stderr);
	CHECK(sp != NULL);
	if (!sp)
		return false;
	struct sl_exec *wx = sl_exec_create(p, NPT), *cx = sl_exec_create(sp->caching, NPT);
	struct sl_exec *dx = sl_exec_create(sp->dynamic, NPT);
	bool ok = sl_exec_set_param(wx, "Kd", &kd, 1) && sl_exec_set_param(dx, "Kd", &kd, 1) &&
		  run(wx, NULL) && run(cx, NULL) && sl_spec_copy_cache(sp, dx, cx, NULL, NPT) &&
		  sl_exec_run(dx, NULL);
	CHECK(ok);
	bool vw = false, vd = false;
	const float *cw = ok ? sl_exec_global(wx, SL_GLOBAL_CI, &vw) : NULL;
	const float *cd = ok ? sl_exec_global(dx, SL_GLOBAL_CI, &vd) : NULL;
	ok = cw && cd && vw && vd;
	CHECK(ok);
	for (uint32_t i = 0; ok && i < NPT; i++)
		for (int c = 0; c < 3; c++) {
			whole[c * NPT + i] = cw[c * sl_exec_stride(wx) + i];
			dyn[c * NPT + i] = cd[c * sl_exec_stride(dx) + i];
		}
	struct sl_glsl_layout lay;
	char *glsl = sl_glsl_emit(&sp->slice, NULL, 0, &lay, stderr);
	CHECK(glsl != NULL);
	if (glsl) {
		free(glsl);
		sl_glsl_layout_finish(&lay);
	}
	sl_exec_destroy(wx);
	sl_exec_destroy(cx);
	sl_exec_destroy(dx);
	sl_spec_destroy(sp);
	return ok;
}

static void test_random_specialized(void)
{
	struct sl_program *p = compile_as("rndspec.sl", random_spec_src, "uniform", stderr);
	CHECK(p != NULL);
	if (!p)
		return;
	float whole[3 * NPT], dyn[3 * NPT];
	if (run_specialized(p, 0.75f, whole, dyn)) {
		bool vary = false;
		for (uint32_t i = 0; i < NPT; i++) {
			for (int c = 0; c < 3; c++)
				CHECK_NEAR(dyn[c * NPT + i], whole[c * NPT + i], 1e-6);
			CHECK_NEAR(whole[i], whole[0], 0);                 /* Kd * k: uniform */
			vary = vary || whole[NPT + i] != whole[NPT];       /* Kd * j: varying */
		}
		CHECK(vary);
	}
	sl_program_destroy(p);
}

/*
 * Promoted uniforms through specialization: the fBm's, static, computed by
 * the caching program; a loop counter whose loop's condition reads the
 * dynamic Kd, in the dynamic part. Both must give what the whole shader
 * gives, as written and with the declarations varying.
 */
static const char promoted_spec_src[] =
	"surface pspec(float Kd = 0.5; float oct = 4)\n"
	"{\n"
	"	STORAGE float i, amp = 1;\n"
	"	float sum = 0;\n"
	"	if (s > 0.4)\n"
	"		for (i = 0; i < oct; i += 1) {\n"
	"			sum += amp * noise(P * 3 * (i + 1));\n"
	"			amp *= 0.5;\n"
	"		}\n"
	"	STORAGE float j;\n"
	"	float fw = u * 0.9 + 0.02;\n"
	"	for (j = 0; j < 6 && fw < Kd * 2; j += 1)\n"
	"		fw *= 2;\n"
	"	Ci = color(sum, j, fw) * Kd;\n"
	"}\n";

static void test_promoted_specialized(void)
{
	struct sl_program *u = compile_as("pspec.sl", promoted_spec_src, "uniform", stderr);
	struct sl_program *v = compile_as("pspec.sl", promoted_spec_src, "varying", stderr);
	CHECK(u && v);
	if (u && v) {
		CHECK(reported_promoted(u, "i") && reported_promoted(u, "j"));
		static const float kds[] = { 0.5f, 0.3f };
		for (int k = 0; k < 2; k++) {
			float wu[3 * NPT], du[3 * NPT], wv[3 * NPT], dv[3 * NPT];
			if (!run_specialized(u, kds[k], wu, du) || !run_specialized(v, kds[k], wv, dv))
				continue;
			for (uint32_t i = 0; i < 3 * NPT; i++) {
				CHECK_NEAR(du[i], wu[i], 1e-6);
				CHECK_NEAR(wu[i], wv[i], 0);
				CHECK_NEAR(dv[i], wv[i], 1e-6);
			}
			/* the counter differs over the grid */
			CHECK(wu[NPT] != wu[NPT + NU - 1]);
		}
	}
	sl_program_destroy(u);
	sl_program_destroy(v);
}

/* ---- a uniform formal given a varying argument ---- */

static const char formal_src[] =
	"float twice(STORAGE float n) { return n * 2; }\n"
	"surface formal(output varying float a = 0, b = 0) { a = twice(s); b = twice(3); }\n";

static void test_uniform_formal(void)
{
	struct sl_program *p = compile_as("formal.sl", formal_src, "uniform", stderr);
	CHECK(p != NULL);
	if (!p)
		return;
	/* The call with s promotes its n (noted); the call with 3 keeps its own uniform. */
	CHECK(reported_promoted(p, "n"));
	struct sl_exec *x = sl_exec_create(p, NPT);
	CHECK(run(x, NULL));
	for (uint32_t i = 0; i < NPT; i++) {
		CHECK_NEAR(out(x, p, "a", 0, i), 2.0 * (i % NU) / (NU - 1), 1e-6);
		CHECK_NEAR(out(x, p, "b", 0, i), 6, 0);
	}
	sl_exec_destroy(x);
	sl_program_destroy(p);
}

/* ---- what stays an error ---- */

static char diag_text[4096];

/* Compile @src expecting failure; the diagnostics are left in diag_text. */
static bool fails(const char *src)
{
	FILE *f = fmemopen(diag_text, sizeof(diag_text) - 1, "w");
	if (!f)
		return false;
	memset(diag_text, 0, sizeof(diag_text));
	struct sl_program *p = compile_as("bad.sl", src, "uniform", f);
	fclose(f);
	sl_program_destroy(p);
	return p == NULL;
}

static void test_still_errors(void)
{
	/* A promoted variable passed to an output uniform formal. */
	CHECK(fails("void inc(output uniform float x) { x += 1; }\n"
		    "surface a() {\n"
		    "	uniform float c = 0;\n"
		    "	if (s > .5) c = 1;\n"
		    "	inc(c);\n"
		    "	Ci = c;\n"
		    "}\n"));
	CHECK(strstr(diag_text, "bad.sl:5:2: error: 'c' is declared uniform but is assigned under "
				"varying control flow at line 4, and it is passed to the output "
				"uniform formal 'x' of inc()") != NULL);
	/* The same call outside varying control is fine. */
	CHECK(!fails("void inc(output uniform float x) { x += 1; }\n"
		     "surface a() { uniform float c = 0; inc(c); Ci = c; }\n"));
	/* A promoted texture name, with the reason. */
	CHECK(fails("surface b(string m = \"a.tx\") {\n"
		    "	uniform string name = \"\";\n"
		    "	if (s > .5) name = m;\n"
		    "	Ci = texture(name);\n"
		    "}\n"));
	CHECK(strstr(diag_text, "bad.sl:4:7: error: the name given to texture() must be uniform, "
				"not varying ('name' is declared uniform but is assigned under "
				"varying control flow at line 3)") != NULL);
	/* Parameters are the shader's interface: not promoted. */
	CHECK(fails("surface c(float Kd = 1) { Kd = s; Ci = Kd; }\n"));
	CHECK(strstr(diag_text, "uniform parameter 'Kd' is assigned a varying value") != NULL);
	CHECK(fails("surface d(output uniform float o = 0) { if (s > .5) o = 1; Ci = o; }\n"));
	CHECK(strstr(diag_text, "output uniform parameter 'o' is assigned inside varying control "
				"flow") != NULL);
}

/* ---- flat expressions ---- */

#define NTERMS 10000

/* x = 1*s + 2*Kd + 3*t + ... : NTERMS products, alternating s, Kd, t. */
static char *flat_source(int nterms, double kd, double *ref, uint32_t npt)
{
	size_t cap = (size_t)nterms * 24 + 256;
	char *src = malloc(cap);
	size_t len = (size_t)snprintf(src, cap,
				      "surface flat(float Kd = 0.5; output varying float x = 0)\n"
				      "{\n\tx = ");
	static const char *const names[] = { "s", "Kd", "t" };
	for (uint32_t i = 0; i < npt; i++)
		ref[i] = 0;
	for (int k = 0; k < nterms; k++) {
		int w = k % 7 + 1;
		len += (size_t)snprintf(src + len, cap - len, "%s%d*%s", k ? " + " : "", w,
					names[k % 3]);
		for (uint32_t i = 0; i < npt; i++) {
			double s = (double)(i % NU) / (NU - 1), t = (double)(i / NU) / (NV - 1);
			double val = k % 3 == 0 ? s : k % 3 == 1 ? kd : t;
			ref[i] += w * val;
		}
	}
	snprintf(src + len, cap - len, ";\n\tCi = x;\n}\n");
	return src;
}

static void test_flat_expression(void)
{
	double ref[NPT];
	char *src = flat_source(NTERMS, 0.5, ref, NPT);
	struct sl_program *p = sl_compile_string("flat.sl", src, strlen(src), NULL);
	CHECK(p != NULL);
	free(src);
	if (!p)
		return;
	struct sl_exec *x = sl_exec_create(p, NPT);
	CHECK(run(x, NULL));
	for (uint32_t i = 0; i < NPT; i++)
		CHECK_NEAR(out(x, p, "x", 0, i), ref[i], 1e-5 * ref[i]);
	sl_exec_destroy(x);
	/* With Kd dynamic the whole chain from its first Kd term on is GLSL. */
	const char *dyn[] = { "Kd" };
	struct sl_spec *sp = sl_specialize(p, dyn, 1, stderr);
	CHECK(sp != NULL);
	if (sp) {
		CHECK(sp->ndynamic >= NTERMS);
		struct sl_glsl_layout lay;
		char *glsl = sl_glsl_emit(&sp->slice, NULL, 0, &lay, stderr);
		CHECK(glsl != NULL);
		if (glsl) {
			size_t lines = 0;
			for (const char *c = glsl; *c; c++)
				lines += *c == '\n';
			CHECK(lines > NTERMS);
			free(glsl);
			sl_glsl_layout_finish(&lay);
		}
		sl_spec_destroy(sp);
	}
	sl_program_destroy(p);
}

/* Repeat @unit @n times into a string (malloc'd). */
static char *repeat(const char *head, const char *unit, int n, const char *mid,
		    const char *close, const char *tail)
{
	size_t cap = strlen(head) + (strlen(unit) + strlen(close)) * (size_t)n + strlen(mid) +
		     strlen(tail) + 1;
	char *s = malloc(cap);
	size_t len = (size_t)snprintf(s, cap, "%s", head);
	for (int i = 0; i < n; i++)
		len += (size_t)snprintf(s + len, cap - len, "%s", unit);
	len += (size_t)snprintf(s + len, cap - len, "%s", mid);
	for (int i = 0; i < n; i++)
		len += (size_t)snprintf(s + len, cap - len, "%s", close);
	snprintf(s + len, cap - len, "%s", tail);
	return s;
}

static void test_real_nesting(void)
{
	/* 300 parentheses, 300 nested calls, 300 right operands: real nesting. */
	char *a = repeat("surface n() { Ci = ", "(", 300, "s", ")", "; }\n");
	CHECK(fails(a));
	CHECK(strstr(diag_text, "error: nesting too deep") != NULL);
	free(a);
	char *b = repeat("surface n() { Ci = ", "abs(", 300, "s", ")", "; }\n");
	CHECK(fails(b));
	CHECK(strstr(diag_text, "error: nesting too deep") != NULL);
	free(b);
	char *c = repeat("surface n() { Ci = ", "s + (", 300, "s", ")", "; }\n");
	CHECK(fails(c));
	CHECK(strstr(diag_text, "error: nesting too deep") != NULL);
	free(c);
	/* 200 levels are allowed. */
	char *d = repeat("surface n() { Ci = ", "s + (", 200, "s", ")", "; }\n");
	CHECK(!fails(d));
	free(d);
	/* Size, not depth, bounds a flat chain: past 100,000 operators it is an error. */
	char *e = repeat("surface n() { Ci = s", " + s", 100001, "", "", "; }\n");
	CHECK(fails(e));
	CHECK(strstr(diag_text, "error: expression too large (more than 100000 operators)") !=
	      NULL);
	free(e);
}

int main(void)
{
	RUN(test_fbm_under_if);
	RUN(test_varying_loop_condition);
	RUN(test_message_passing);
	RUN(test_random_uniform);
	RUN(test_random_specialized);
	RUN(test_promoted_specialized);
	RUN(test_uniform_formal);
	RUN(test_still_errors);
	RUN(test_flat_expression);
	RUN(test_real_nesting);
	return test_finish();
}

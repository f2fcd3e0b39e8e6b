/*
 * Every built-in function of RSL, through compiled shaders run by the grid
 * interpreter on a small grid. The grid is 5 x 3 points with u = s in
 * {0, .25, .5, .75, 1}, v = t in {0, .5, 1}, du = .25, dv = .5, P = (u, v, 0),
 * N = Ng = (0, 0, 1), E = (0, 0, -1), I = P - E, Cs = (1, .5, .25).
 * Expected values are computed here by hand or with libm in double.
 */
#include "builtin.h"
#include "exec.h"
#include "lighthost.h"
#include "mathlib.h"
#include "noise.h"
#include "sl.h"
#include "strbuf.h"
#include "test.h"

#include <float.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

#define NU 5
#define NV 3
#define NPTS (NU * NV)
#define PI_D 3.14159265358979323846

static bool covered[SL_BI_COUNT];

struct run {
	struct sl_program *prog;
	struct sl_exec *x;
	bool ok;
};

static float U(uint32_t i)
{
	return (float)(i % NU) / (NU - 1);
}

static float V(uint32_t i)
{
	return (float)(i / NU) / (NV - 1);
}

/* Mark the built-ins a program calls. */
static void note_coverage(const struct sl_program *p)
{
	for (uint32_t k = 0; k < p->ncode; k++)
		if (p->code[k].op == SL_OP_CALL && p->code[k].bi >= 0)
			covered[sl_builtins[p->code[k].bi].id] = true;
}

static struct sl_program *compile(const char *src)
{
	struct sl_options o = { 0 };
	struct sl_program *p = sl_compile_string("test.sl", src, strlen(src), &o);
	if (!p)
		fprintf(stderr, "[%s] compile failed:\n%s\n", test_current, src);
	else
		note_coverage(p);
	return p;
}

static void set3(struct sl_exec *x, enum sl_global g, uint32_t i, float a, float b, float c)
{
	bool v;
	float *d = sl_exec_global(x, g, &v);
	if (!d || (!v && i > 0))
		return;
	size_t s = v ? sl_exec_stride(x) : 1, o = v ? i : 0;
	d[o] = a;
	d[s + o] = b;
	d[2 * s + o] = c;
}

static void set1(struct sl_exec *x, enum sl_global g, uint32_t i, float a)
{
	bool v;
	float *d = sl_exec_global(x, g, &v);
	if (!d || (!v && i > 0))
		return;
	d[v ? i : 0] = a;
}

static void fill_globals(struct sl_exec *x)
{
	for (uint32_t i = 0; i < NPTS; i++) {
		float u = U(i), v = V(i);
		set3(x, SL_GLOBAL_P, i, u, v, 0);
		set3(x, SL_GLOBAL_N, i, 0, 0, 1);
		set3(x, SL_GLOBAL_NG, i, 0, 0, 1);
		set3(x, SL_GLOBAL_E, i, 0, 0, -1);
		set3(x, SL_GLOBAL_I, i, u, v, 1);
		set3(x, SL_GLOBAL_CS, i, 1, 0.5f, 0.25f);
		set3(x, SL_GLOBAL_OS, i, 1, 1, 1);
		set3(x, SL_GLOBAL_DPDU, i, 1, 0, 0);
		set3(x, SL_GLOBAL_DPDV, i, 0, 1, 0);
		set1(x, SL_GLOBAL_S, i, u);
		set1(x, SL_GLOBAL_T, i, v);
		set1(x, SL_GLOBAL_U, i, u);
		set1(x, SL_GLOBAL_V, i, v);
		set1(x, SL_GLOBAL_DU, i, 1.0f / (NU - 1));
		set1(x, SL_GLOBAL_DV, i, 1.0f / (NV - 1));
	}
}

/* Compile @src and make an executor for the test grid (not run yet). */
static struct run setup(const char *src)
{
	struct run r = { 0 };
	r.prog = compile(src);
	if (!r.prog)
		return r;
	r.x = sl_exec_create(r.prog, NPTS);
	if (r.x && sl_exec_set_grid(r.x, NU, NV))
		fill_globals(r.x);
	return r;
}

static bool go(struct run *r, const struct sl_host *host)
{
	if (!r->x)
		return false;
	r->ok = sl_exec_run(r->x, host);
	return r->ok;
}

/* Compile and run @src on the grid. */
static struct run run_src(const char *src, const struct sl_host *host)
{
	struct run r = setup(src);
	CHECK(r.x != NULL);
	CHECK(go(&r, host));
	return r;
}

static void done(struct run *r)
{
	sl_exec_destroy(r->x);
	sl_program_destroy(r->prog);
	r->x = NULL;
	r->prog = NULL;
}

/* Output parameter @name, component @c, at point @i (NaN when missing). */
static float out(struct run *r, const char *name, int c, uint32_t i)
{
	if (!r->x)
		return NAN;
	const struct sl_program *p = r->prog;
	int k = sl_program_find_param(p, name);
	if (k < 0) {
		fprintf(stderr, "[%s] no parameter %s\n", test_current, name);
		return NAN;
	}
	int32_t reg = p->params[k].reg;
	const float *d = sl_exec_reg(r->x, reg);
	return p->regs[reg].varying ? d[(size_t)c * sl_exec_stride(r->x) + i] : d[c];
}

static const char *out_str(struct run *r, const char *name, uint32_t i)
{
	if (!r->x)
		return NULL;
	const struct sl_program *p = r->prog;
	int k = sl_program_find_param(p, name);
	if (k < 0)
		return NULL;
	int32_t reg = p->params[k].reg;
	const char **d = sl_exec_reg_strings(r->x, reg);
	return p->regs[reg].varying ? d[i] : d[0];
}

static float ci(struct run *r, int c, uint32_t i)
{
	bool v;
	const float *d = r->x ? sl_exec_global(r->x, SL_GLOBAL_CI, &v) : NULL;
	if (!d)
		return NAN;
	return v ? d[(size_t)c * sl_exec_stride(r->x) + i] : d[c];
}

/* Run @fn with stderr captured into @buf. */
static void capture_stderr(char *buf, size_t cap, void (*fn)(void *), void *arg)
{
	fflush(stderr);
	FILE *tmp = tmpfile();
	if (!tmp) {
		fn(arg);
		buf[0] = 0;
		return;
	}
	int saved = dup(2);
	dup2(fileno(tmp), 2);
	fn(arg);
	fflush(stderr);
	dup2(saved, 2);
	close(saved);
	rewind(tmp);
	size_t n = fread(buf, 1, cap - 1, tmp);
	buf[n] = 0;
	fclose(tmp);
}

/* ------------------------------------------------------------------------ */

static void test_math(void)
{
	struct run r = run_src(
		"surface t(output varying float rad = 0, deg = 0, s_ = 0, as = 0, c_ = 0, ac = 0,\n"
		"  ta = 0, at = 0, at2 = 0, sh = 0, ch = 0, th = 0, pw = 0, ex = 0, sq = 0, isq = 0,\n"
		"  lg = 0, lgb = 0, md = 0, ab = 0, sg = 0, mn = 0, mx = 0, mn3 = 0, cl = 0, mi = 0,\n"
		"  fl = 0, ce = 0, ro = 0, st = 0, ss = 0;\n"
		"  output varying color cpow = 0, cmix = 0, cmod = 0, cmax = 0, cabs = 0;)\n"
		"{\n"
		"  rad = radians(u * 180); deg = degrees(u); s_ = sin(u); as = asin(u - 0.5);\n"
		"  c_ = cos(u); ac = acos(u * 2 - 1); ta = tan(u); at = atan(u); at2 = atan(v, u - 0.5);\n"
		"  sh = sinh(u); ch = cosh(u); th = tanh(u); pw = pow(u, 2.5); ex = exp(u);\n"
		"  sq = sqrt(u); isq = inversesqrt(u + 1); lg = log(u + 1); lgb = log(8, 2);\n"
		"  md = mod(u * 7 - 3, 2); ab = abs(u - 0.5); sg = sign(u - 0.5);\n"
		"  mn = min(u, v); mx = max(u, v); mn3 = min(u, v, 0.3); cl = clamp(u, 0.2, 0.7);\n"
		"  mi = mix(1, 3, u); fl = floor(u * 3.5); ce = ceil(u * 3.5); ro = round(u * 5 - 2.5);\n"
		"  st = step(0.5, u); ss = smoothstep(0.25, 0.75, u);\n"
		"  cpow = pow(color(u, 2, 3), 2); cmix = mix(color 0, color(2, 4, 6), color(u, v, 0.5));\n"
		"  cmod = mod(color(u * 3, -1, 5), 2); cmax = max(color(u, 0.5, 1), color(v, v, v));\n"
		"  cabs = abs(color(u - 1, 1, -2));\n"
		"}\n", NULL);
	const double tol = 2e-6;
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i), v = V(i);
		CHECK_NEAR(out(&r, "rad", 0, i), u * PI_D, 1e-5);
		CHECK_NEAR(out(&r, "deg", 0, i), u * 180 / PI_D, 1e-4);
		CHECK_NEAR(out(&r, "s_", 0, i), sin(u), tol);
		CHECK_NEAR(out(&r, "as", 0, i), asin(u - 0.5), tol);
		CHECK_NEAR(out(&r, "c_", 0, i), cos(u), tol);
		CHECK_NEAR(out(&r, "ac", 0, i), acos(u * 2 - 1), tol);
		CHECK_NEAR(out(&r, "ta", 0, i), tan(u), tol);
		CHECK_NEAR(out(&r, "at", 0, i), atan(u), tol);
		CHECK_NEAR(out(&r, "at2", 0, i), (u == 0.5 && v == 0) ? 0 : atan2(v, u - 0.5), tol);
		CHECK_NEAR(out(&r, "sh", 0, i), sinh(u), tol);
		CHECK_NEAR(out(&r, "ch", 0, i), cosh(u), tol);
		CHECK_NEAR(out(&r, "th", 0, i), tanh(u), tol);
		CHECK_NEAR(out(&r, "pw", 0, i), pow(u, 2.5), tol);
		CHECK_NEAR(out(&r, "ex", 0, i), exp(u), 1e-5);
		CHECK_NEAR(out(&r, "sq", 0, i), sqrt(u), tol);
		CHECK_NEAR(out(&r, "isq", 0, i), 1 / sqrt(u + 1), tol);
		CHECK_NEAR(out(&r, "lg", 0, i), log(u + 1), tol);
		CHECK_NEAR(out(&r, "lgb", 0, i), 3, tol);
		double a = u * 7 - 3;
		CHECK_NEAR(out(&r, "md", 0, i), a - 2 * floor(a / 2), 1e-5);
		CHECK_NEAR(out(&r, "ab", 0, i), fabs(u - 0.5), tol);
		CHECK_NEAR(out(&r, "sg", 0, i), u > 0.5 ? 1 : u < 0.5 ? -1 : 0, 0);
		CHECK_NEAR(out(&r, "mn", 0, i), fmin(u, v), 0);
		CHECK_NEAR(out(&r, "mx", 0, i), fmax(u, v), 0);
		CHECK_NEAR(out(&r, "mn3", 0, i), fmin(fmin(u, v), 0.3), 1e-7);
		CHECK_NEAR(out(&r, "cl", 0, i), fmin(fmax(u, 0.2), 0.7), 1e-7);
		CHECK_NEAR(out(&r, "mi", 0, i), 1 + 2 * u, tol);
		CHECK_NEAR(out(&r, "fl", 0, i), floor(u * 3.5), 0);
		CHECK_NEAR(out(&r, "ce", 0, i), ceil(u * 3.5), 0);
		/* u * 5 - 2.5 = -2.5, -1.25, 0, 1.25, 2.5: halves round away from zero. */
		static const double ro[NU] = { -3, -1, 0, 1, 3 };
		CHECK_NEAR(out(&r, "ro", 0, i), ro[i % NU], 0);
		CHECK_NEAR(out(&r, "st", 0, i), u < 0.5 ? 0 : 1, 0);
		double t = fmin(fmax((u - 0.25) / 0.5, 0), 1);
		CHECK_NEAR(out(&r, "ss", 0, i), t * t * (3 - 2 * t), tol);
		CHECK_NEAR(out(&r, "cpow", 0, i), u * u, tol);
		CHECK_NEAR(out(&r, "cpow", 1, i), 4, tol);
		CHECK_NEAR(out(&r, "cpow", 2, i), 9, tol);
		CHECK_NEAR(out(&r, "cmix", 0, i), 2 * u, tol);
		CHECK_NEAR(out(&r, "cmix", 1, i), 4 * v, tol);
		CHECK_NEAR(out(&r, "cmix", 2, i), 3, tol);
		double m0 = u * 3 - 2 * floor(u * 3 / 2);
		CHECK_NEAR(out(&r, "cmod", 0, i), m0, 1e-6);
		CHECK_NEAR(out(&r, "cmod", 1, i), 1, 0);
		CHECK_NEAR(out(&r, "cmod", 2, i), 1, 0);
		CHECK_NEAR(out(&r, "cmax", 0, i), fmax(u, v), 0);
		CHECK_NEAR(out(&r, "cmax", 1, i), fmax(0.5, v), 0);
		CHECK_NEAR(out(&r, "cabs", 0, i), 1 - u, 1e-7);
		CHECK_NEAR(out(&r, "cabs", 2, i), 2, 0);
	}
	done(&r);
}

/* Domain edges: RSL programs never see NaN or Inf. */
static void test_math_edges(void)
{
	struct run r = run_src(
		"surface t(output varying float p00 = -1, ac = -1, sq = -1, lg = 0, md = 0, md2 = 0,\n"
		"  ss = -1, pneg = -1, big = 0, isq = -1, as = 0, at00 = -1, tn = 0;\n"
		"  output varying vector nz = 1;)\n"
		"{\n"
		"  p00 = pow(u * 0, 0); ac = acos(1.0000001); sq = sqrt(-1 - u); lg = log(u * 0);\n"
		"  md = mod(-1, 3); md2 = mod(u + 1, 0); ss = smoothstep(0.5, 0.5, u);\n"
		"  pneg = pow(-2, 0.5); big = exp(1000 + u); isq = inversesqrt(-u);\n"
		"  as = asin(-7); at00 = atan(0, 0); tn = tan(1.5707963);\n"
		"  nz = normalize(vector(0, 0, 0) * u);\n"
		"}\n", NULL);
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i);
		CHECK(out(&r, "p00", 0, i) == 1.0f);
		CHECK(out(&r, "ac", 0, i) == 0.0f);
		CHECK(out(&r, "sq", 0, i) == 0.0f);
		CHECK_NEAR(out(&r, "lg", 0, i), -87.336544, 1e-3);
		CHECK_NEAR(out(&r, "md", 0, i), 2, 1e-6);
		CHECK(out(&r, "md2", 0, i) == 0.0f);
		CHECK(out(&r, "ss", 0, i) == (u < 0.5 ? 0.0f : 1.0f));
		CHECK(out(&r, "pneg", 0, i) == 0.0f);
		CHECK(out(&r, "big", 0, i) == FLT_MAX);
		CHECK(out(&r, "isq", 0, i) == 0.0f);
		CHECK_NEAR(out(&r, "as", 0, i), -PI_D / 2, 1e-6);
		CHECK(out(&r, "at00", 0, i) == 0.0f);
		float tn = out(&r, "tn", 0, i);
		CHECK(tn == tn && fabsf(tn) <= FLT_MAX);
		for (int c = 0; c < 3; c++)
			CHECK(out(&r, "nz", c, i) == 0.0f);
	}
	done(&r);
}

static void test_filterstep_spline(void)
{
	struct run r = run_src(
		"surface t(output varying float f1 = -1, f2 = -1, f3 = -1, sp = -1, spl = -1, spa = -1,\n"
		"  spb = -1, sps = -1; output varying color spc = -1;)\n"
		"{\n"
		"  f1 = filterstep(0.5, u);\n"
		"  f2 = filterstep(0.5, u - 0.1, u + 0.1);\n"
		"  f3 = filterstep(0.5, u, \"width\", 4);\n"
		"  sp = spline(u, 5, 0, 1, 4, 2, 9);\n"
		"  spl = spline(\"linear\", u, 5, 0, 1, 4, 2, 9);\n"
		"  float arr[6] = { 5, 0, 1, 4, 2, 9 };\n"
		"  spa = spline(\"catmull-rom\", u, arr);\n"
		"  spb = spline(\"bezier\", u, 0, 1, 1, 0);\n"
		"  sps = spline(\"solvelinear\", u * 10, 0, 0, 10, 10);\n"
		"  spc = spline(u, color 0, color 0, color(1, 2, 3), color(2, 4, 6), color(3, 6, 9));\n"
		"}\n", NULL);
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i);
		int iu = (int)(i % NU);
		/* Box of width du = .25 around u: 0 below, 1/2 at the edge, 1 above. */
		static const double f1[NU] = { 0, 0, 0.5, 1, 1 };
		CHECK_NEAR(out(&r, "f1", 0, i), f1[iu], 1e-6);
		static const double f2[NU] = { 0, 0, 0.5, 1, 1 };
		CHECK_NEAR(out(&r, "f2", 0, i), f2[iu], 1e-6);
		/* width 4: the box is 1 wide: [u - .5, u + .5] above .5 = u. */
		CHECK_NEAR(out(&r, "f3", 0, i), fmin(fmax(u, 0), 1), 1e-6);
		/* Catmull-rom through 0, 1, 4, 2 at u = 0, 1/3, 2/3, 1 (3 segments). */
		static const double sp[NU] = { 0, 0.25 * 0 + 0, 43.0 / 16, 0, 2 };
		if (iu == 0 || iu == 2 || iu == 4)
			CHECK_NEAR(out(&r, "sp", 0, i), sp[iu], 1e-5);
		float ref;
		float vals[6] = { 5, 0, 1, 4, 2, 9 };
		sl_spline_eval(SL_SPLINE_CATMULL_ROM, (float)u, vals, 6, 1, &ref);
		CHECK_NEAR(out(&r, "sp", 0, i), ref, 1e-5);
		CHECK_NEAR(out(&r, "spa", 0, i), ref, 1e-5);
		/* Linear: 0 -> 1 -> 4 -> 2 at thirds. */
		double x = u * 3;
		int seg = x >= 3 ? 2 : (int)x;
		static const double lin[4] = { 0, 1, 4, 2 };
		CHECK_NEAR(out(&r, "spl", 0, i), lin[seg] + (x - seg) * (lin[seg + 1] - lin[seg]), 1e-5);
		/* One bezier segment 0 1 1 0: 3u(1-u). */
		CHECK_NEAR(out(&r, "spb", 0, i), 3 * u * (1 - u), 1e-6);
		CHECK_NEAR(out(&r, "sps", 0, i), u, 1e-5);
		/* Colors k (1, 2, 3), k = 0 1 2 3 from the second value on: two segments
		 * from k = 0 to k = 2, linear in the second. */
		if (iu == 2) {
			CHECK_NEAR(out(&r, "spc", 0, i), 1, 1e-5);
			CHECK_NEAR(out(&r, "spc", 2, i), 3, 1e-5);
		}
		if (iu == 3) {
			CHECK_NEAR(out(&r, "spc", 0, i), 1.5, 1e-5);
			CHECK_NEAR(out(&r, "spc", 1, i), 3, 1e-5);
			CHECK_NEAR(out(&r, "spc", 2, i), 4.5, 1e-5);
		}
	}
	done(&r);
}

static void test_noise_random(void)
{
	struct run r = run_src(
		"surface t(output varying float n1 = -1, n2 = -1, n3 = -1, n4 = -1, pn = -1, pn2 = -1,\n"
		"  cn = -1, cn1 = -1, r1 = -1, r2 = -1, rsum = 0;\n"
		"  output varying color nc = -1, cc = -1, rc = -1; output varying point np = -1;)\n"
		"{\n"
		"  n1 = noise(u * 3.7); n2 = noise(u * 3.1, v * 2.3); n3 = noise(P * 2.9);\n"
		"  n4 = noise(P * 1.3, v + 0.4); nc = color noise(P * 2.9); np = point noise(u * 3.7);\n"
		"  pn = pnoise(u * 8, 4); pn2 = pnoise(u * 8 + 4, 4);\n"
		"  cn = cellnoise(P * 3); cn1 = cellnoise(u * 1.5); cc = color cellnoise(u * 3, v * 3);\n"
		"  r1 = random(); r2 = random(); rc = color random();\n"
		"  for (float k = 0; k < 64; k += 1) rsum += random();\n"
		"}\n", NULL);
	int differ_pts = 0, differ_calls = 0;
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		float u = U(i), v = V(i);
		/* The same functions as the library, to float rounding of the arguments. */
		CHECK_NEAR(out(&r, "n1", 0, i), sl_noise1(u * 3.7f), 1e-6);
		CHECK_NEAR(out(&r, "n2", 0, i), sl_noise2(u * 3.1f, v * 2.3f), 1e-6);
		CHECK_NEAR(out(&r, "n3", 0, i), sl_noise3(u * 2.9f, v * 2.9f, 0), 1e-6);
		CHECK_NEAR(out(&r, "n4", 0, i), sl_noise4(u * 1.3f, v * 1.3f, 0, v + 0.4f), 1e-6);
		float p3[3] = { u * 2.9f, v * 2.9f, 0 }, vn[3];
		sl_vnoise(3, p3, NULL, vn);
		float p1[1] = { u * 3.7f }, vn1[3];
		sl_vnoise(1, p1, NULL, vn1);
		for (int c = 0; c < 3; c++) {
			CHECK_NEAR(out(&r, "nc", c, i), vn[c], 1e-6);
			CHECK_NEAR(out(&r, "np", c, i), vn1[c], 1e-6);
		}
		CHECK_NEAR(out(&r, "pn", 0, i), out(&r, "pn2", 0, i), 1e-5);
		int32_t per[1] = { 4 };
		float pp[1] = { u * 8 };
		CHECK_NEAR(out(&r, "pn", 0, i), sl_noise(1, pp, per, 0), 1e-6);
		float pc[3] = { u * 3, v * 3, 0 };
		CHECK(out(&r, "cn", 0, i) == sl_cellnoise(3, pc, 0));
		float pc1[1] = { u * 1.5f };
		CHECK(out(&r, "cn1", 0, i) == sl_cellnoise(1, pc1, 0));
		float pc2[2] = { u * 3, v * 3 }, vc[3];
		sl_vcellnoise(2, pc2, vc);
		CHECK(out(&r, "cc", 0, i) == vc[0] && out(&r, "cc", 2, i) == vc[2]);
		float r1 = out(&r, "r1", 0, i), r2 = out(&r, "r2", 0, i);
		CHECK(r1 >= 0 && r1 < 1 && r2 >= 0 && r2 < 1);
		if (r1 != r2)
			differ_calls++;
		if (i > 0 && r1 != out(&r, "r1", 0, i - 1))
			differ_pts++;
		for (int c = 0; c < 3; c++)
			CHECK(out(&r, "rc", c, i) >= 0 && out(&r, "rc", c, i) < 1);
		/* 64 draws in a loop: each iteration differs, so the mean is near .5. */
		CHECK_NEAR(out(&r, "rsum", 0, i) / 64, 0.5, 0.2);
	}
	CHECK(differ_calls == NPTS);
	CHECK(differ_pts == NPTS - 1);
	done(&r);
}

static void test_geometry(void)
{
	struct run r = run_src(
		"surface t(output varying float xc = -1, yc = -1, zc = -1, len = -1, dist = -1,\n"
		"  pl = -1, ar = -1, kr = -1, kt = -1, dp = -1;\n"
		"  output varying point q = 0, rot = 0; output varying vector nrm = 0, ff = 0, ff3 = 0,\n"
		"  rf = 0, rr = 0, tir = 0, R = 0, T = 0; output varying normal cn = 0;)\n"
		"{\n"
		"  xc = xcomp(P); yc = ycomp(P); zc = zcomp(P);\n"
		"  q = P; setxcomp(q, 5); setycomp(q, u * 2); setzcomp(q, -1);\n"
		"  len = length(vector P); nrm = normalize(vector P + vector(0, 0, 1));\n"
		"  dist = distance(P, point(1, 1, 0));\n"
		"  pl = ptlined(point(0, 0, 0), point(1, 0, 0), P);\n"
		"  rot = rotate(P, PI / 2, point(0, 0, 0), point(0, 0, 1));\n"
		"  ar = area(P); cn = calculatenormal(P);\n"
		"  ff = faceforward(vector(0, 0, 1), vector(0, 0, 1));\n"
		"  ff3 = faceforward(vector(0, 0, 1), vector(0, 0, -1), vector(0, 0, 1));\n"
		"  rf = reflect(vector(1, -1, 0), vector(0, 1, 0));\n"
		"  rr = refract(vector(0, 0, -1), vector(0, 0, 1), 1 / 1.5);\n"
		"  tir = refract(vector(0.8660254, 0, -0.5), vector(0, 0, 1), 1.5);\n"
		"  fresnel(vector(0, 0, -1), vector(0, 0, 1), 1 / 1.5, kr, kt, R, T);\n"
		"  float k1, k2; fresnel(vector(0.8660254, 0, -0.5), vector(0, 0, 1), 1.5, k1, k2);\n"
		"  dp = k1 * 10 + k2;\n"
		"}\n", NULL);
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i), v = V(i);
		CHECK_NEAR(out(&r, "xc", 0, i), u, 0);
		CHECK_NEAR(out(&r, "yc", 0, i), v, 0);
		CHECK_NEAR(out(&r, "zc", 0, i), 0, 0);
		CHECK_NEAR(out(&r, "q", 0, i), 5, 0);
		CHECK_NEAR(out(&r, "q", 1, i), 2 * u, 1e-7);
		CHECK_NEAR(out(&r, "q", 2, i), -1, 0);
		CHECK_NEAR(out(&r, "len", 0, i), sqrt(u * u + v * v), 1e-6);
		double nl = sqrt(u * u + v * v + 1);
		CHECK_NEAR(out(&r, "nrm", 0, i), u / nl, 1e-6);
		CHECK_NEAR(out(&r, "nrm", 2, i), 1 / nl, 1e-6);
		CHECK_NEAR(out(&r, "dist", 0, i), sqrt((1 - u) * (1 - u) + (1 - v) * (1 - v)), 1e-6);
		CHECK_NEAR(out(&r, "pl", 0, i), v, 1e-6);
		CHECK_NEAR(out(&r, "rot", 0, i), -v, 1e-6);
		CHECK_NEAR(out(&r, "rot", 1, i), u, 1e-6);
		/* A flat grid: area du * dv, normal +z. */
		CHECK_NEAR(out(&r, "ar", 0, i), 0.25 * 0.5, 1e-6);
		CHECK_NEAR(out(&r, "cn", 0, i), 0, 1e-6);
		CHECK_NEAR(out(&r, "cn", 1, i), 0, 1e-6);
		CHECK_NEAR(out(&r, "cn", 2, i), 1, 1e-6);
		/* faceforward with two arguments uses Ng = (0,0,1): I along it flips N. */
		CHECK_NEAR(out(&r, "ff", 2, i), -1, 0);
		CHECK_NEAR(out(&r, "ff3", 2, i), 1, 0);
		CHECK_NEAR(out(&r, "rf", 0, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "rf", 1, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "rr", 2, i), -1, 1e-6);
		for (int c = 0; c < 3; c++)
			CHECK(out(&r, "tir", c, i) == 0.0f);
		CHECK_NEAR(out(&r, "kr", 0, i), 0.04, 1e-6);
		CHECK_NEAR(out(&r, "kt", 0, i), 0.96, 1e-6);
		CHECK_NEAR(out(&r, "R", 2, i), 1, 1e-6);
		CHECK_NEAR(out(&r, "T", 2, i), -1, 1e-6);
		CHECK_NEAR(out(&r, "dp", 0, i), 10, 1e-6);
	}
	done(&r);
}

static void test_derivatives(void)
{
	struct run r = run_src(
		"surface t(output varying float du2 = -1, dv2 = -1, dr = -1, dr0 = -1, duc = 0;\n"
		"  output varying color dcol = -1; output varying vector dp = -1, dpv = -1;)\n"
		"{\n"
		"  du2 = Du(u * u); dv2 = Dv(v * v); dr = Deriv(u * u, u); dr0 = Deriv(u, 2);\n"
		"  duc = Du(3); dcol = Du(color(u, 2 * u, u * v));\n"
		"  dp = Du(P); dpv = Deriv(P * 2, v);\n"
		"}\n", NULL);
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i), v = V(i);
		/* Central and one-sided second-order differences are exact on quadratics. */
		CHECK_NEAR(out(&r, "du2", 0, i), 2 * u, 1e-5);
		CHECK_NEAR(out(&r, "dv2", 0, i), 2 * v, 1e-5);
		CHECK_NEAR(out(&r, "dr", 0, i), 2 * u, 1e-5);
		/* Derivative with respect to a constant: zero-safe division gives 0. */
		CHECK(out(&r, "dr0", 0, i) == 0.0f);
		CHECK(out(&r, "duc", 0, i) == 0.0f);
		CHECK_NEAR(out(&r, "dcol", 0, i), 1, 1e-5);
		CHECK_NEAR(out(&r, "dcol", 1, i), 2, 1e-5);
		CHECK_NEAR(out(&r, "dcol", 2, i), v, 1e-5);
		CHECK_NEAR(out(&r, "dp", 0, i), 1, 1e-5);
		CHECK_NEAR(out(&r, "dp", 1, i), 0, 1e-5);
		CHECK_NEAR(out(&r, "dpv", 1, i), 2, 1e-5);
		CHECK_NEAR(out(&r, "dpv", 0, i), 0, 1e-5);
	}
	done(&r);
}

/* Spaces for the transform tests: "world" is translated by (1,2,3) from current,
 * "obj" scales by (2,4,8), "flat" is singular. */
static const char *const space_names[] = { "world", "obj", "flat", "camera" };
static const float space_mats[][16] = {
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 2, 3, 1 },
	{ 2, 0, 0, 0, 0, 4, 0, 0, 0, 0, 8, 0, 0, 0, 0, 1 },
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1 },
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -10, 1 },
};

static bool clip_option(void *user, const char *name, int type, int arraylen, float *o,
			const char **so)
{
	(void)user;
	(void)so;
	if (strcmp(name, "Clipping") || type != SL_TYPE_FLOAT || arraylen != 2)
		return false;
	o[0] = 5;
	o[1] = 15;
	return true;
}

static void test_transforms(void)
{
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, NULL, 0);
	lh.space_names = space_names;
	lh.space_mats = space_mats;
	lh.nspaces = 4;
	lh.host.option = clip_option;
	struct run r = run_src(
		"surface t(output varying point tw = 0, tfw = 0, tm = 0, tfm = 0, tsing = 0, pm = 0;\n"
		"  output varying vector vw = 0, vo = 0, tv = 0; output varying normal no = 0;\n"
		"  output varying float dep = -1, det = 0, m30 = 0, sm30 = 0;\n"
		"  output varying color hsv = 0, rgb = 0, xyz = 0, c1 = 0; output varying float cmp = 0;)\n"
		"{\n"
		"  tw = transform(\"world\", P); tfw = transform(\"world\", \"obj\", P);\n"
		"  matrix m = translate(matrix 1, vector(1, 2, 3));\n"
		"  tm = transform(m, P); tfm = transform(\"obj\", m, P);\n"
		"  tsing = transform(\"flat\", P);\n"
		"  vw = vtransform(\"world\", vector(1, 1, 1)); vo = vtransform(\"obj\", \"current\", vector(1, 1, 1));\n"
		"  tv = transform(\"world\", \"current\", vector(1, 1, 1));\n"
		"  no = ntransform(\"obj\", \"current\", normal(1, 1, 0));\n"
		"  dep = depth(P + point(0, 0, u * 4));\n"
		"  matrix r = rotate(matrix 1, PI / 2, vector(0, 0, 1));\n"
		"  pm = transform(scale(r, point(2, 3, 4)), point(1, 0, 0));\n"
		"  det = determinant(scale(matrix 1, point(2, 3, 4)) * (1 + u));\n"
		"  m30 = comp(m, 3, 0) + comp(m, 3, 1) * 10;\n"
		"  sm30 = comp(matrix \"world\" 1, 3, 2);\n"
		"  hsv = ctransform(\"hsv\", color(1, 0, 0)); rgb = ctransform(\"hsv\", \"rgb\", color(0.5, 1, 1));\n"
		"  xyz = ctransform(\"XYZ\", color(1, 1, 1));\n"
		"  c1 = Cs; setcomp(c1, 2, u); cmp = comp(Cs, 1);\n"
		"}\n", &lh.host);
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		double u = U(i), v = V(i);
		/* current -> world is the inverse of world -> current. */
		CHECK_NEAR(out(&r, "tw", 0, i), u - 1, 1e-6);
		CHECK_NEAR(out(&r, "tw", 1, i), v - 2, 1e-6);
		CHECK_NEAR(out(&r, "tw", 2, i), -3, 1e-6);
		/* world -> current -> obj: (P + (1,2,3)) / (2,4,8). */
		CHECK_NEAR(out(&r, "tfw", 0, i), (u + 1) / 2, 1e-6);
		CHECK_NEAR(out(&r, "tfw", 1, i), (v + 2) / 4, 1e-6);
		CHECK_NEAR(out(&r, "tfw", 2, i), 3.0 / 8, 1e-6);
		CHECK_NEAR(out(&r, "tm", 0, i), u + 1, 1e-6);
		CHECK_NEAR(out(&r, "tm", 2, i), 3, 1e-6);
		/* obj -> current (scale), then m (translate). */
		CHECK_NEAR(out(&r, "tfm", 0, i), 2 * u + 1, 1e-6);
		CHECK_NEAR(out(&r, "tfm", 1, i), 4 * v + 2, 1e-6);
		/* A singular space warns and leaves the point alone. */
		CHECK_NEAR(out(&r, "tsing", 0, i), u, 1e-7);
		/* Vectors ignore translation; normals take the inverse transpose. */
		CHECK_NEAR(out(&r, "vw", 0, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "vo", 1, i), 4, 1e-7);
		/* transform() of a vector is a vector transform: no translation. */
		CHECK_NEAR(out(&r, "tv", 0, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "tv", 2, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "no", 0, i), 0.5, 1e-7);
		CHECK_NEAR(out(&r, "no", 1, i), 0.25, 1e-7);
		/* camera -> current moves z by -10, so z_cam = z + 10 = 4u + 10; the
		 * clipping planes 5 and 15 map to 0 and 1. */
		double zc = u * 4 + 10;
		CHECK_NEAR(out(&r, "dep", 0, i), (zc - 5) / 10, 1e-6);
		/* scale(r, s) = S * R: (1,0,0) -> (2,0,0) -> (0,2,0). */
		CHECK_NEAR(out(&r, "pm", 0, i), 0, 1e-6);
		CHECK_NEAR(out(&r, "pm", 1, i), 2, 1e-6);
		double k = 1 + u;
		CHECK_NEAR(out(&r, "det", 0, i), 2 * 3 * 4 * k * k * k * k, 1e-3);
		CHECK_NEAR(out(&r, "m30", 0, i), 21, 1e-6);
		CHECK_NEAR(out(&r, "sm30", 0, i), 3, 1e-6);
		CHECK_NEAR(out(&r, "hsv", 0, i), 0, 1e-7);
		CHECK_NEAR(out(&r, "hsv", 1, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "hsv", 2, i), 1, 1e-7);
		CHECK_NEAR(out(&r, "rgb", 0, i), 0, 1e-6);
		CHECK_NEAR(out(&r, "rgb", 1, i), 1, 1e-6);
		CHECK_NEAR(out(&r, "rgb", 2, i), 1, 1e-6);
		CHECK_NEAR(out(&r, "xyz", 1, i), 1, 1e-5);
		CHECK_NEAR(out(&r, "xyz", 0, i), 0.95047, 2e-4);
		CHECK_NEAR(out(&r, "c1", 0, i), 1, 0);
		CHECK_NEAR(out(&r, "c1", 2, i), u, 0);
		CHECK_NEAR(out(&r, "cmp", 0, i), 0.5, 0);
	}
	done(&r);
}

/* ---- lights ---- */

static const char *light_src =
	"light sun(float intensity = 1; color lightcolor = 1; vector dir = vector(0, 0, -1);\n"
	"  float __nondiffuse = 0; float __nonspecular = 0;)\n"
	"{\n"
	"  solar(dir, 0) { Cl = intensity * lightcolor; }\n"
	"}\n";

static const char *amb_src =
	"light amb(float intensity = 0.25; color lightcolor = 1;)\n"
	"{\n"
	"  Cl = intensity * lightcolor;\n"
	"}\n";

static void set_light_param(struct sl_exec *x, const char *name, const float *v, uint32_t n)
{
	CHECK(sl_exec_set_param(x, name, v, n));
}

static void test_lighting(void)
{
	struct sl_program *psun = compile(light_src), *pamb = compile(amb_src);
	CHECK(psun && pamb);
	if (!psun || !pamb) {
		sl_program_destroy(psun);
		sl_program_destroy(pamb);
		return;
	}
	/*
	 * Light 0: key, intensity 2 from direction (0.6, 0, 0.8) (L on the surface).
	 * Light 1: fill, intensity 1 from (0, 0, 1), marked __nondiffuse.
	 * Light 2: ambient 0.25. Light 3: from below the surface, reaches nothing.
	 * Light 4: intensity 4 from (0, 0.6, 0.8), marked __nonspecular.
	 */
	struct sl_exec *lights[5] = {
		sl_exec_create(psun, NPTS), sl_exec_create(psun, NPTS), sl_exec_create(pamb, NPTS),
		sl_exec_create(psun, NPTS), sl_exec_create(psun, NPTS),
	};
	float two = 2, one = 1, four = 4;
	float d0[3] = { -0.6f, 0, -0.8f }, d1[3] = { 0, 0, -1 }, d3[3] = { 0, 0, 1 };
	float d4[3] = { 0, -0.6f, -0.8f };
	set_light_param(lights[0], "intensity", &two, 1);
	set_light_param(lights[0], "dir", d0, 3);
	set_light_param(lights[1], "dir", d1, 3);
	set_light_param(lights[1], "__nondiffuse", &one, 1);
	set_light_param(lights[3], "dir", d3, 3);
	set_light_param(lights[4], "intensity", &four, 1);
	set_light_param(lights[4], "dir", d4, 3);
	set_light_param(lights[4], "__nonspecular", &one, 1);
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, lights, 5);

	/*
	 * specular() and specularbrdf() with roughness 0.1 under each model:
	 * max(0, N.H)^e with e = 1 / 0.1 = 10 (RiSpec) and e = 8 / 0.1 = 80
	 * (PRMan's, the default). phong() is the same under both.
	 */
	static const enum sl_specular_model models[2] = { SL_SPECULAR_RISPEC, SL_SPECULAR_PRMAN };
	static const double exponent[2] = { 10, 80 };
	struct run r;
	for (int m = 0; m < 2; m++) {
		lh.host.specular_model = models[m];
		r = run_src(
			"surface t(output varying color amb = -1, dif = -1, spe = -1, pho = -1, brdf = -1;\n"
			"  output varying float isum = -1, miss = -1, nlit = 0;)\n"
			"{\n"
			"  normal Nf = normalize(N);\n"
			"  vector V = vector(0, 0, 1);\n"
			"  amb = ambient(); dif = diffuse(Nf); spe = specular(Nf, V, 0.1);\n"
			"  pho = phong(Nf, V, 5);\n"
			"  brdf = specularbrdf(normalize(vector(0.6, 0, 0.8)), Nf, V, 0.1);\n"
			"  isum = 0; miss = 0;\n"
			"  illuminance(P, Nf, PI / 2) {\n"
			"    float k = 0, z = 0;\n"
			"    if (lightsource(\"intensity\", k) == 1) isum += k;\n"
			"    miss += lightsource(\"nosuch\", z);\n"
			"    nlit += 1;\n"
			"  }\n"
			"  Ci = dif;\n"
			"}\n", &lh.host);
		/* The key light's half vector with V = +z. */
		double hx = 0.6, hz = 1.8, hl = sqrt(hx * hx + hz * hz);
		double brdf_key = pow(hz / hl, exponent[m]);
		/* Light 4 from (0, .6, .8): same geometry rotated. */
		double spec = 2 * brdf_key + 1 * 1.0;
		double phong = 2 * pow(0.8, 5) + 1 * 1.0;
		for (uint32_t i = 0; i < NPTS && r.ok; i++) {
			for (int c = 0; c < 3; c++) {
				CHECK_NEAR(out(&r, "amb", c, i), 0.25, 1e-6);
				/* key 2 * .8 + light 4: 4 * .8; the fill is non-diffuse. */
				CHECK_NEAR(out(&r, "dif", c, i), 2 * 0.8 + 4 * 0.8, 1e-5);
				CHECK_NEAR(ci(&r, c, i), 2 * 0.8 + 4 * 0.8, 1e-5);
				CHECK_NEAR(out(&r, "spe", c, i), spec, 1e-5);
				CHECK_NEAR(out(&r, "pho", c, i), phong, 1e-5);
				CHECK_NEAR(out(&r, "brdf", c, i), brdf_key, 1e-5);
			}
			/* illuminance visits the lights above the horizon: 2 + 1 + 4. */
			CHECK_NEAR(out(&r, "isum", 0, i), 7, 1e-6);
			CHECK_NEAR(out(&r, "nlit", 0, i), 3, 0);
			CHECK_NEAR(out(&r, "miss", 0, i), 0, 0);
		}
		done(&r);
	}

	/* Without lights: everything is black, nothing fails. */
	r = run_src("surface t(output varying color d = -1;) { d = diffuse(N) + ambient() + "
		    "specular(N, -I, 0.2) + phong(N, -I, 3); }", NULL);
	for (uint32_t i = 0; i < NPTS && r.ok; i++)
		CHECK(out(&r, "d", 0, i) == 0.0f && out(&r, "d", 2, i) == 0.0f);
	done(&r);

	for (int k = 0; k < 5; k++)
		sl_exec_destroy(lights[k]);
	sl_program_destroy(psun);
	sl_program_destroy(pamb);
}

/* ---- textures ---- */

struct texlog {
	int calls;
	char name[64];
	int channel, nchannels;
	float swidth, blur, fill;
	float spread;      /* |s[1] - s[0]| at the first active point */
	float tspread;     /* |t[3] - t[0]| */
	char filter[32];
};

static struct texlog texlog;

static uint32_t first_set(const uint8_t *m, uint32_t n)
{
	for (uint32_t i = 0; i < n; i++)
		if (m[i])
			return i;
	return 0;
}

/* A "map" whose value is the filter region's centre s + 10 * channel. */
static bool fake_texture(void *user, const struct sl_tex_lookup *q)
{
	(void)user;
	texlog.calls++;
	snprintf(texlog.name, sizeof(texlog.name), "%s", q->name);
	snprintf(texlog.filter, sizeof(texlog.filter), "%s", q->filter ? q->filter : "");
	texlog.channel = q->channel;
	texlog.nchannels = q->nchannels;
	texlog.swidth = q->swidth;
	texlog.blur = q->blur;
	texlog.fill = q->fill;
	uint32_t f = first_set(q->mask, q->n);
	texlog.spread = fabsf(q->s[1][f] - q->s[0][f]);
	texlog.tspread = fabsf(q->t[3][f] - q->t[0][f]);
	if (strcmp(q->name, "map") != 0)
		return false;
	for (uint32_t i = 0; i < q->n; i++) {
		if (!q->mask[i])
			continue;
		float sc = 0.25f * (q->s[0][i] + q->s[1][i] + q->s[2][i] + q->s[3][i]);
		for (int c = 0; c < q->nchannels; c++)
			q->out[(size_t)c * q->stride + i] = sc + 10.0f * (float)(q->channel + c);
	}
	return true;
}

/* Environment: the x of the direction; shadow: the z of the position. */
static bool fake_environment(void *user, const struct sl_tex_lookup *q)
{
	(void)user;
	for (uint32_t i = 0; i < q->n; i++)
		if (q->mask[i])
			for (int c = 0; c < q->nchannels; c++)
				q->out[(size_t)c * q->stride + i] =
					0.25f * (q->dir[0][i] + q->dir[1][i] + q->dir[2][i] + q->dir[3][i]);
	return true;
}

static bool fake_shadow(void *user, const struct sl_tex_lookup *q)
{
	(void)user;
	texlog.spread = 0;
	uint32_t f = first_set(q->mask, q->n);
	texlog.spread = fabsf(q->pos[1][f] - q->pos[0][f]);
	for (uint32_t i = 0; i < q->n; i++)
		if (q->mask[i])
			q->out[i] = q->pos[2][2 * q->stride + i] + q->samples;
	return true;
}

static bool fake_textureinfo(void *user, const char *name, const char *query, int type,
			     int arraylen, float *o, const char **so)
{
	(void)user;
	(void)so;
	if (strcmp(name, "map") || strcmp(query, "resolution") || type != SL_TYPE_FLOAT ||
	    arraylen != 2)
		return false;
	o[0] = 512;
	o[1] = 256;
	return true;
}

struct texrun {
	struct run r;
	struct sl_host host;
};

static void run_textures(void *arg)
{
	struct texrun *t = arg;
	go(&t->r, &t->host);
}

static void test_textures(void)
{
	struct texrun t;
	memset(&t, 0, sizeof(t));
	t.host.texture = fake_texture;
	t.host.environment = fake_environment;
	t.host.shadow = fake_shadow;
	t.host.textureinfo = fake_textureinfo;
	t.r = setup(
		"surface t(output varying float tf = -1, tmiss = -1, tempty = -1, env = -1, sh = -1,\n"
		"  ti = -1, ti2 = -1, t8 = -1, tg = -1; output varying color tc = -1;)\n"
		"{\n"
		"  tf = float texture(\"map\", s, t, \"blur\", 0.5, \"swidth\", 2, \"filter\", \"box\");\n"
		"  tc = color texture(\"map\"[1], s, t);\n"
		"  tmiss = float texture(\"nomap\", s, t, \"fill\", 0.7);\n"
		"  tempty = float texture(\"\", s, t);\n"
		"  t8 = float texture(\"map\", s, t, s + 1, t, s + 1, t + 1, s, t + 1);\n"
		"  tg = float texture(\"map\");\n"
		"  env = float environment(\"env\", vector(u, 1, 0));\n"
		"  sh = shadow(\"shd\", P + point(0, 0, 2), \"samples\", 4);\n"
		"  float res[2] = { 0, 0 };\n"
		"  ti = textureinfo(\"map\", \"resolution\", res); ti2 = res[0] + res[1] / 1000;\n"
		"}\n");
	char err[2048];
	CHECK(t.r.x != NULL);
	capture_stderr(err, sizeof(err), run_textures, &t);
	CHECK(t.r.ok);
	struct run *r = &t.r;
	for (uint32_t i = 0; i < NPTS && r->ok; i++) {
		double u = U(i);
		CHECK_NEAR(out(r, "tf", 0, i), u, 1e-6);
		CHECK_NEAR(out(r, "tc", 0, i), u + 10, 1e-5);
		CHECK_NEAR(out(r, "tc", 1, i), u + 20, 1e-5);
		CHECK_NEAR(out(r, "tc", 2, i), u + 30, 1e-5);
		CHECK_NEAR(out(r, "tmiss", 0, i), 0.7, 1e-7);
		CHECK_NEAR(out(r, "tempty", 0, i), 0, 0);
		/* Explicit corners s, s+1: their centre is s + .5. */
		CHECK_NEAR(out(r, "t8", 0, i), u + 0.5, 1e-6);
		/* No coordinates: the global s and t. */
		CHECK_NEAR(out(r, "tg", 0, i), u, 1e-6);
		CHECK_NEAR(out(r, "env", 0, i), u, 1e-6);
		/* The shadow position's z (2) plus the samples option. */
		CHECK_NEAR(out(r, "sh", 0, i), 2 + 4, 1e-6);
		CHECK_NEAR(out(r, "ti", 0, i), 1, 0);
		CHECK_NEAR(out(r, "ti2", 0, i), 512.256, 1e-3);
	}
	CHECK(strstr(err, "texture 'nomap' not found") != NULL);
	CHECK(strstr(err, "texture ''") == NULL);
	done(&t.r);

	/* The options and the filter region of one lookup: du = .25 of s. */
	memset(&texlog, 0, sizeof(texlog));
	t.r = run_src("surface t(output varying float o = 0;)\n"
		      "{ o = float texture(\"map\"[2], s, t * 2, \"blur\", 0.5, \"swidth\", 2,\n"
		      "    \"filter\", \"box\"); }", &t.host);
	CHECK(texlog.calls == 1);
	CHECK_STR(texlog.name, "map");
	CHECK(texlog.channel == 2 && texlog.nchannels == 1);
	CHECK_NEAR(texlog.blur, 0.5, 0);
	CHECK_NEAR(texlog.swidth, 2, 0);
	CHECK_STR(texlog.filter, "box");
	CHECK_NEAR(texlog.spread, 0.25, 1e-6);
	CHECK_NEAR(texlog.tspread, 2 * 0.5, 1e-6);
	done(&t.r);

	/* No host at all: the fill, and a warning. */
	t.r = setup("surface t(output varying float o = -1;) { o = float texture(\"map\", s, t); }");
	t.host = (struct sl_host){ 0 };
	capture_stderr(err, sizeof(err), run_textures, &t);
	CHECK(t.r.ok);
	CHECK(out(&t.r, "o", 0, 3) == 0.0f);
	CHECK(strstr(err, "texture 'map' not found") != NULL);
	done(&t.r);
}

/* ---- message passing and queries ---- */

static bool fake_attribute(void *user, const char *name, int type, int arraylen, float *o,
			   const char **so)
{
	(void)user;
	(void)so;
	if (!strcmp(name, "ShadingRate") && type == SL_TYPE_FLOAT && arraylen == 0) {
		o[0] = 4;
		return true;
	}
	return false;
}

static bool fake_option(void *user, const char *name, int type, int arraylen, float *o,
			const char **so)
{
	(void)user;
	(void)so;
	if (!strcmp(name, "Format") && type == SL_TYPE_FLOAT && arraylen == 3) {
		o[0] = 640;
		o[1] = 480;
		o[2] = 1;
		return true;
	}
	return false;
}

static bool fake_rendererinfo(void *user, const char *name, int type, int arraylen, float *o,
			      const char **so)
{
	(void)user;
	(void)o;
	(void)arraylen;
	if (!strcmp(name, "renderer") && type == SL_TYPE_STRING) {
		so[0] = "relight";
		return true;
	}
	return false;
}

static void test_messages(void)
{
	/* A surface whose parameters the other shader reads. */
	struct run a = run_src("surface a(float Kd = 0.7; varying float vk = 0; string nm = \"abc\";)\n"
			       "{ vk = u * 3; }", NULL);
	struct run d = run_src("displacement dd(float amp = 0.125;) { P += amp * N; }", NULL);
	struct sl_host host = { 0 };
	host.attribute = fake_attribute;
	host.option = fake_option;
	host.rendererinfo = fake_rendererinfo;
	struct run b = setup(
		"surface b(output varying float kd = -1, ok1 = -1, vk = -1, ok2 = -1, amp = -1,\n"
		"  ok3 = -1, miss = -1, bad = -1, inc = -1, opp = -1, atm = -1, sr = -1, okf = -1,\n"
		"  fmt = -1, okr = -1, noattr = -1; output varying string nm = \"\", rn = \"\";)\n"
		"{\n"
		"  float k = 0, x = 0, y = 0, z = 0; string s = \"\";\n"
		"  ok1 = surface(\"Kd\", k); kd = k;\n"
		"  ok2 = surface(\"vk\", x); vk = x;\n"
		"  float ok4 = surface(\"nm\", s); nm = s;\n"
		"  ok3 = displacement(\"amp\", y); amp = y;\n"
		"  miss = surface(\"nosuch\", z);\n"
		"  color c = 0; bad = surface(\"Kd\", c);\n"
		"  inc = incident(\"x\", z); opp = opposite(\"x\", z); atm = atmosphere(\"x\", z);\n"
		"  float rate = 0; float r1 = attribute(\"ShadingRate\", rate); sr = rate * 10 + r1;\n"
		"  float f[3] = { 0, 0, 0 }; okf = option(\"Format\", f); fmt = f[0] + f[1] / 1000;\n"
		"  string rname = \"\"; okr = rendererinfo(\"renderer\", rname); rn = rname;\n"
		"  noattr = attribute(\"nope\", rate);\n"
		"}\n");
	if (b.x && a.x && d.x) {
		sl_exec_set_peer(b.x, SL_PEER_SURFACE, a.x);
		sl_exec_set_peer(b.x, SL_PEER_DISPLACEMENT, d.x);
	}
	CHECK(go(&b, &host));
	for (uint32_t i = 0; i < NPTS && b.ok; i++) {
		CHECK_NEAR(out(&b, "ok1", 0, i), 1, 0);
		CHECK_NEAR(out(&b, "kd", 0, i), 0.7, 1e-7);
		CHECK_NEAR(out(&b, "ok2", 0, i), 1, 0);
		CHECK_NEAR(out(&b, "vk", 0, i), U(i) * 3, 1e-6);
		CHECK_STR(out_str(&b, "nm", i), "abc");
		CHECK_NEAR(out(&b, "ok3", 0, i), 1, 0);
		CHECK_NEAR(out(&b, "amp", 0, i), 0.125, 0);
		CHECK_NEAR(out(&b, "miss", 0, i), 0, 0);
		CHECK_NEAR(out(&b, "bad", 0, i), 0, 0);
		CHECK_NEAR(out(&b, "inc", 0, i), 0, 0);
		CHECK_NEAR(out(&b, "opp", 0, i), 0, 0);
		CHECK_NEAR(out(&b, "atm", 0, i), 0, 0);
		CHECK_NEAR(out(&b, "sr", 0, i), 41, 0);
		CHECK_NEAR(out(&b, "okf", 0, i), 1, 0);
		CHECK_NEAR(out(&b, "fmt", 0, i), 640.48, 1e-4);
		CHECK_NEAR(out(&b, "okr", 0, i), 1, 0);
		CHECK_STR(out_str(&b, "rn", i), "relight");
		CHECK_NEAR(out(&b, "noattr", 0, i), 0, 0);
	}
	done(&b);
	done(&a);
	done(&d);
}

/* ---- strings ---- */

struct printlog {
	char text[4096];
	size_t len;
	int calls;
};

static void capture_print(void *user, const char *text)
{
	struct printlog *pl = user;
	pl->calls++;
	size_t n = strlen(text);
	if (pl->len + n < sizeof(pl->text)) {
		memcpy(pl->text + pl->len, text, n + 1);
		pl->len += n;
	}
}

static void run_strings(void *arg)
{
	struct texrun *t = arg;
	go(&t->r, &t->host);
}

static void test_strings(void)
{
	struct printlog pl = { .len = 0 };
	struct texrun t;
	memset(&t, 0, sizeof(t));
	t.host.print = capture_print;
	t.host.user = &pl;
	t.r = setup(
		"surface t(output varying string f = \"\", cc = \"\", f2 = \"\";\n"
		"  output varying float m1 = -1, m2 = -1, m3 = -1, m4 = -1;)\n"
		"{\n"
		"  if (v == 0) printf(\"u=%.2f\\n\", u);\n"
		"  printf(\"%d %s %c %5.1f%%\\n\", 3.7, \"ab\", color(1, 0, 0.5), 2.25);\n"
		"  printf(\"%p|%m\\n\", point(1, 2, 3), matrix 1);\n"
		"  f = format(\"<%3d|%-4s|%.3e>\", u * 8, \"x\", 1234.5);\n"
		"  f2 = format(\"%f %q %\");\n"
		"  cc = concat(\"a\", \"b\", format(\"%g\", u));\n"
		"  m1 = match(\"^a.c$\", \"abc\"); m2 = match(\"^a.c$\", \"abcd\");\n"
		"  m3 = match(\"[0-9]+\", format(\"x%gy\", u * 4)); m4 = match(\"(\", \"(\");\n"
		"}\n");
	char err[2048];
	capture_stderr(err, sizeof(err), run_strings, &t);
	struct run *r = &t.r;
	CHECK(r->ok);
	/* The varying printf once per active point (v == 0: 5 points), the uniform ones once. */
	CHECK(pl.calls == NU + 2);
	CHECK_STR(pl.text, "u=0.00\nu=0.25\nu=0.50\nu=0.75\nu=1.00\n"
			   "3 ab 1.000000 0.000000 0.500000   2.2%\n"
			   "1.000000 2.000000 3.000000|1.000000 0.000000 0.000000 0.000000 "
			   "0.000000 1.000000 0.000000 0.000000 0.000000 0.000000 1.000000 "
			   "0.000000 0.000000 0.000000 0.000000 1.000000\n");
	for (uint32_t i = 0; i < NPTS && r->ok; i++) {
		char want[64];
		snprintf(want, sizeof(want), "<%3d|x   |1.234e+03>", (int)(U(i) * 8));
		CHECK_STR(out_str(r, "f", i), want);
		snprintf(want, sizeof(want), "ab%g", U(i));
		CHECK_STR(out_str(r, "cc", i), want);
		CHECK_NEAR(out(r, "m1", 0, i), 1, 0);
		CHECK_NEAR(out(r, "m2", 0, i), 0, 0);
		CHECK_NEAR(out(r, "m3", 0, i), 1, 0);
		CHECK_NEAR(out(r, "m4", 0, i), 0, 0);
	}
	/* Missing arguments and unknown conversions are printed as written. */
	CHECK_STR(out_str(r, "f2", 0), "%f %q %");
	CHECK(strstr(err, "invalid pattern") != NULL);
	CHECK(strstr(err, "more conversions than arguments") != NULL);
	done(r);
}

/* Extreme but finite inputs: every result stays finite. */
static void test_finite_results(void)
{
	static const char *const exprs[] = {
		"pow(u, u)", "pow(-u, 0.5)", "exp(u)", "log(u)", "log(u, u)", "sqrt(u)",
		"inversesqrt(u)", "tan(u)", "sinh(u)", "cosh(u)", "mod(u, 3)", "mod(3, u)",
		"mod(u, u * 1e-30)", "smoothstep(u, -u, 1)", "noise(u)", "pnoise(u, u)",
		"cellnoise(u, u)", "length(vector(u, u, u))", "area(point(u, u * v, 0))",
		"Du(u * u)", "Dv(u * v)", "Deriv(u, v * u)", "filterstep(0, u)",
		"filterstep(0, u, -u)", "spline(u, u, -u, u, -u)", "degrees(u)", "radians(u)",
		"atan(u, -u)", "acos(u)", "ptlined(point(u, 0, 0), point(-u, 0, 0), point(0, u, u))",
		"distance(point(u, u, u), point(-u, -u, -u))", "determinant(matrix 1 * u)",
		"depth(point(u, u, u))", "xcomp(normalize(vector(u, u, u)))",
		"comp(ctransform(\"hsv\", color(u, -u, 1)), 0)",
		"comp(ctransform(\"xyY\", \"rgb\", color(u, u, u)), 0)",
		"comp(ctransform(\"hsl\", \"rgb\", color(u, u, u)), 2)",
		"xcomp(transform(scale(matrix 1, point(u, u, u)), point(u, 1, 1)))",
		"ycomp(refract(vector(u, 1, 0), vector(0, 1, 0), u))",
		"xcomp(rotate(point(u, 1, 0), u, point(0, 0, 0), point(u, u, 1)))",
		"comp(rotate(matrix 1, u, vector(u, 0, u)), 0, 0)",
		"ycomp(ntransform(scale(matrix 1, point(u, 1e-30, 1)), normal(1, 1, 1)))",
		"zcomp(calculatenormal(point(u, v * u, u * u)))",
		"comp(specularbrdf(vector(u, 0, 1), normal(0, 0, 1), vector(0, u, 1), 1e-30), 0)",
		"comp(spline(\"bezier\", u, color(u), color(-u), color(u), color(1)), 1)",
		"random() * u",
	};
	const size_t n = sizeof(exprs) / sizeof(exprs[0]);
	struct rl_strbuf src = { 0 };
	rl_strbuf_puts(&src, "surface t(output varying float o[");
	rl_strbuf_printf(&src, "%zu] = {", n);
	for (size_t k = 0; k < n; k++)
		rl_strbuf_puts(&src, k ? ", 0" : "0");
	rl_strbuf_puts(&src, "};) {\n");
	for (size_t k = 0; k < n; k++)
		rl_strbuf_printf(&src, "  o[%zu] = %s;\n", k, exprs[k]);
	rl_strbuf_puts(&src, "}\n");
	struct run r = setup(rl_strbuf_str(&src));
	rl_strbuf_finish(&src);
	CHECK(r.x != NULL);
	if (!r.x) {
		done(&r);
		return;
	}
	/* u takes extreme values along the grid: 0, +-1e30, +-FLT_MAX. */
	static const float extreme[NU] = { 0, 1e30f, -1e30f, FLT_MAX, -FLT_MAX };
	for (uint32_t i = 0; i < NPTS; i++)
		set1(r.x, SL_GLOBAL_U, i, extreme[i % NU]);
	CHECK(go(&r, NULL));
	int k = sl_program_find_param(r.prog, "o");
	CHECK(k >= 0);
	if (r.ok && k >= 0) {
		int32_t reg = r.prog->params[k].reg;
		const float *d = sl_exec_reg(r.x, reg);
		bool vary = r.prog->regs[reg].varying;
		for (size_t e = 0; e < n; e++) {
			for (uint32_t i = 0; i < NPTS; i++) {
				float v = vary ? d[e * sl_exec_stride(r.x) + i] : d[e];
				if (!(fabsf(v) <= FLT_MAX)) {
					fprintf(stderr, "[%s] %s = %g at u = %g\n", test_current, exprs[e],
						v, extreme[i % NU]);
					CHECK(fabsf(v) <= FLT_MAX);
				}
			}
		}
	}
	done(&r);
}

/*
 * The ray-tracing built-ins against a host whose scene is the plane z = 1
 * (colour (0.2, 0.4, 0.6), opaque), seen by every ray type; the grid lies at
 * z = 0 facing it (N = (0, 0, 1)). Closed forms: trace() along +z brings
 * back the plane's colour at distance 1; transmission() to a point past the
 * plane is 0, short of it 1; occlusion() over the hemisphere is 1, and with
 * "maxdist" 1.5 the cosine-weighted fraction of directions within
 * acos(2/3) of N, sin^2 = 5/9, within 1 % at 1024 samples;
 * indirectdiffuse() is the plane's colour. raylevel(), isshadowray() and
 * rayinfo() answer from the host's rayinfo.
 */
static uint32_t mock_rays;

struct cap_run {
	struct run *r;
	const struct sl_host *h;
};

static void cap_go(void *arg)
{
	struct cap_run *c = arg;
	go(c->r, c->h);
}

static bool mock_trace(void *user, struct sl_ray_query *q)
{
	(void)user;
	for (uint32_t k = 0; k < q->n; k++) {
		const float *o = q->org + 3 * k, *d = q->dir + 3 * k;
		float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
		float t = d[2] > 0 ? (1 - o[2]) / (d[2] / len) : 1e30f;
		float maxd = q->maxdist ? q->maxdist[k] : 1e30f;
		bool hit = t < 1e30f && t >= 0 && t <= maxd;
		static const float col[3] = { 0.2f, 0.4f, 0.6f };
		if (q->dist)
			q->dist[k] = hit ? t : 1e30f;
		for (int c = 0; c < 3; c++) {
			if (q->Ci)
				q->Ci[3 * k + (uint32_t)c] = hit ? col[c] : 0;
			if (q->Oi)
				q->Oi[3 * k + (uint32_t)c] = hit ? 1 : 0;
			if (q->trans)
				q->trans[3 * k + (uint32_t)c] = hit ? 0 : 1;
		}
	}
	mock_rays += q->n;
	return true;
}

static bool mock_rayinfo(void *user, const char *name, int type, int arraylen, float *o,
			 const char **so)
{
	(void)user;
	(void)arraylen;
	if (!strcmp(name, "depth") && type == SL_TYPE_FLOAT) {
		*o = 2;
		return true;
	}
	if (!strcmp(name, "type") && type == SL_TYPE_STRING) {
		*so = "transmission";
		return true;
	}
	return false;
}

static const char ray_src[] =
	"surface r(output varying color tc = -1, id = -1, tm = -1, tx = -1, none = -1;\n"
	"  output varying float td = -1, tdmiss = -1, oc = -1, ocmax = -1, ocz = -1, lvl = -1,\n"
	"  shad = -1, ri = -1, rd = -1;)\n"
	"{\n"
	"  tc = trace(P, vector(0, 0, 1));\n"
	"  color ct = trace(P, vector(0, 0, -1)); none = ct;\n"
	"  float d = trace(P, vector(0, 0, 1)); td = d;\n"
	"  float dm = trace(P, vector(0, 0, -1)); tdmiss = dm;\n"
	"  tm = transmission(P, P + vector(0, 0, 2));\n"
	"  tx = transmission(P, P + vector(0, 0, 0.5));\n"
	"  oc = occlusion(P, N, 256);\n"
	"  ocmax = occlusion(P, N, 1024, \"maxdist\", 1.5);\n"
	"  ocz = occlusion(P, normal(0, 0, 0), 16);\n"
	"  id = indirectdiffuse(P, N, 64);\n"
	"  lvl = raylevel(); shad = isshadowray();\n"
	"  float depth = -1; ri = rayinfo(\"depth\", depth); rd = depth;\n"
	"}\n";

static void test_raytracing(void)
{
	struct sl_host host = { 0 };
	host.trace = mock_trace;
	host.rayinfo = mock_rayinfo;
	mock_rays = 0;
	struct run r = run_src(ray_src, &host);
	double want = 5.0 / 9.0;
	for (uint32_t i = 0; i < NPTS && r.ok; i++) {
		static const float col[3] = { 0.2f, 0.4f, 0.6f };
		for (int c = 0; c < 3; c++) {
			CHECK_NEAR(out(&r, "tc", c, i), col[c], 1e-7);
			CHECK_NEAR(out(&r, "none", c, i), 0, 0);
			CHECK_NEAR(out(&r, "tm", c, i), 0, 0);
			CHECK_NEAR(out(&r, "tx", c, i), 1, 0);
			CHECK_NEAR(out(&r, "id", c, i), col[c], 1e-6);
		}
		CHECK_NEAR(out(&r, "td", 0, i), 1, 1e-6);
		CHECK_NEAR(out(&r, "tdmiss", 0, i), 1e30, 1e24);
		CHECK_NEAR(out(&r, "oc", 0, i), 1, 0);
		CHECK_NEAR(out(&r, "ocmax", 0, i), want, 0.01 * want);
		CHECK_NEAR(out(&r, "ocz", 0, i), 0, 0);
		CHECK_NEAR(out(&r, "lvl", 0, i), 2, 0);
		CHECK_NEAR(out(&r, "shad", 0, i), 1, 0);
		CHECK_NEAR(out(&r, "ri", 0, i), 1, 0);
		CHECK_NEAR(out(&r, "rd", 0, i), 2, 0);
	}
	printf("occlusion within acos(2/3): %.5f at point 0, closed form %.5f (tolerance 1%%); "
	       "%u rays\n", r.ok ? out(&r, "ocmax", 0, 0) : -1.0, want, mock_rays);
	/* 15 points: 6 single rays each, 256 + 1024 + 64 hemisphere samples; none for N = 0 */
	CHECK(mock_rays == NPTS * (6 + 256 + 1024 + 64));
	done(&r);

	/* a host that cannot ray trace: what a miss gives, and a warning */
	char err[4096];
	struct sl_host none = { 0 };
	struct run n = setup(ray_src);
	struct cap_run cr = { &n, &none };
	capture_stderr(err, sizeof(err), cap_go, &cr);
	CHECK(n.ok);
	CHECK(strstr(err, "cannot ray trace") != NULL);
	for (uint32_t i = 0; i < NPTS && n.ok; i++) {
		CHECK_NEAR(out(&n, "tc", 0, i), 0, 0);
		CHECK_NEAR(out(&n, "tm", 1, i), 1, 0);
		CHECK_NEAR(out(&n, "oc", 0, i), 0, 0);
		CHECK_NEAR(out(&n, "lvl", 0, i), 0, 0);
	}
	done(&n);
}

/* Every id of enum sl_bi was called by some test shader. */
static void test_coverage(void)
{
	for (int id = 0; id < SL_BI_COUNT; id++) {
		if (!covered[id])
			fprintf(stderr, "built-in '%s' (id %d) is not tested\n",
				sl_bi_name((enum sl_bi)id), id);
		CHECK(covered[id]);
	}
}

int main(void)
{
	RUN(test_math);
	RUN(test_math_edges);
	RUN(test_filterstep_spline);
	RUN(test_noise_random);
	RUN(test_geometry);
	RUN(test_derivatives);
	RUN(test_transforms);
	RUN(test_lighting);
	RUN(test_textures);
	RUN(test_messages);
	RUN(test_strings);
	RUN(test_finite_results);
	RUN(test_raytracing);
	RUN(test_coverage);
	return test_finish();
}

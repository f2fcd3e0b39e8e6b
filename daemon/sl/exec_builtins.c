/*
 * RSL's built-in functions for the grid interpreter. sl_exec_builtin()
 * dispatches on the built-in's id; the overloads that share an id are told
 * apart by the actual types of the destination and argument registers (the
 * lowering pass has already promoted floats where a signature asks for a
 * triple). The numerics themselves live in mathlib.c and noise.c.
 *
 * Every result goes through sl_finite(): no built-in produces NaN or Inf.
 */
#include "exec_impl.h"
#include "mathlib.h"
#include "noise.h"
#include "../common/arena.h"
#include "../common/strbuf.h"

#include <float.h>
#include <math.h>
#include <regex.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI_F 3.14159265358979f

/* Widths and precisions of printf conversions are capped at this. */
#define MAX_FIELD 256

/* ------------------------------------------------------------------------ */
/* Register access                                                           */

static inline const struct sl_reg *reg_of(const struct sl_exec *x, int32_t r)
{
	return &x->prog->regs[r];
}

static inline int rtype(const struct sl_exec *x, int32_t r)
{
	return reg_of(x, r)->type;
}

static inline bool is_string(const struct sl_exec *x, int32_t r)
{
	return rtype(x, r) == SL_TYPE_STRING;
}

/* Floats per element (1 for bools). */
static inline int rncomp(const struct sl_exec *x, int32_t r)
{
	return sl_type_ncomp(rtype(x, r));
}

static inline int relems(const struct sl_exec *x, int32_t r)
{
	int32_t n = reg_of(x, r)->arraylen;
	return n > 0 ? n : 1;
}

/* Component @c of numeric register @r at point @i; a float gives its value for any c. */
static inline float getc_(const struct sl_exec *x, int32_t r, int c, uint32_t i)
{
	return sl_x_get(x, r, rncomp(x, r) == 1 ? 0 : c, i);
}

static inline float getf(const struct sl_exec *x, int32_t r, uint32_t i)
{
	return sl_x_get(x, r, 0, i);
}

static void get3(const struct sl_exec *x, int32_t r, uint32_t i, float v[3])
{
	for (int c = 0; c < 3; c++)
		v[c] = getc_(x, r, c, i);
}

/* A matrix register, or a float as that multiple of the identity. */
static void getm(const struct sl_exec *x, int32_t r, uint32_t i, float m[16])
{
	if (rncomp(x, r) == 16) {
		for (int c = 0; c < 16; c++)
			m[c] = sl_x_get(x, r, c, i);
		return;
	}
	float v = getf(x, r, i);
	for (int c = 0; c < 16; c++)
		m[c] = (c % 5 == 0) ? v : 0.0f;
}

static inline void put(struct sl_exec *x, int32_t r, int c, uint32_t i, float v)
{
	sl_x_set(x, r, c, i, sl_finite(v));
}

/* Write a triple (or, into a float register, its first component). */
static void put3(struct sl_exec *x, int32_t r, uint32_t i, const float v[3])
{
	int nc = rncomp(x, r) < 3 ? rncomp(x, r) : 3;
	for (int c = 0; c < nc; c++)
		put(x, r, c, i, v[c]);
}

static void putm(struct sl_exec *x, int32_t r, uint32_t i, const float m[16])
{
	if (rncomp(x, r) != 16)
		return;
	for (int c = 0; c < 16; c++)
		put(x, r, c, i, m[c]);
}

/* String element @e of @r at point @i ("" for none). */
static const char *sget(const struct sl_exec *x, int32_t r, int e, uint32_t i)
{
	const char **d = x->sdata[r];
	if (!d)
		return "";
	const char *s = reg_of(x, r)->varying ? d[(size_t)e * x->stride + i] : d[e];
	return s ? s : "";
}

static void sset(struct sl_exec *x, int32_t r, int e, uint32_t i, const char *s)
{
	const char **d = x->sdata[r];
	if (!d)
		return;
	if (reg_of(x, r)->varying)
		d[(size_t)e * x->stride + i] = s;
	else
		d[e] = s;
}

/* The first active point (0 when none): where uniform-ish arguments are read. */
static uint32_t first_active(const struct sl_exec *x)
{
	if (x->nactive == x->n)
		return 0;
	for (uint32_t i = 0; i < x->n; i++)
		if (x->mask[i])
			return i;
	return 0;
}

/* Where to read the operands for point @i of a write to @dst. */
static inline uint32_t src_index(const struct sl_exec *x, int32_t dst, uint32_t i, uint32_t i0)
{
	return sl_x_varying(x, dst) ? i : i0;
}

/* Component @c of @r over the whole grid (n floats). */
static const float *plane_of(struct sl_exec *x, int32_t r, int c)
{
	if (r >= 0 && rncomp(x, r) == 1)
		c = 0;
	if (r >= 0 && sl_x_varying(x, r))
		return x->data[r] + (size_t)c * x->stride;
	float *b = sl_exec_scratch(x, x->n);
	float v = r >= 0 ? x->data[r][c] : 0.0f;
	for (uint32_t i = 0; i < x->n; i++)
		b[i] = v;
	return b;
}

/* A global triple as three planes with the register stride (zeros if absent). */
static const float *global_planes(struct sl_exec *x, enum sl_global g)
{
	int32_t r = x->prog->global_reg[g];
	if (r >= 0 && sl_x_varying(x, r) && rncomp(x, r) == 3)
		return x->data[r];
	float *b = sl_exec_scratch(x, 3 * (size_t)x->stride);
	for (int c = 0; c < 3; c++) {
		float v = (r >= 0 && rncomp(x, r) == 3) ? x->data[r][c] : 0.0f;
		for (uint32_t i = 0; i < x->n; i++)
			b[(size_t)c * x->stride + i] = v;
	}
	return b;
}

/*
 * The plane whose derivatives are wanted: component @c of @r, or NULL for a
 * uniform value, whose derivatives @du and @dv are then zeroed.
 */
static const float *deriv_plane(struct sl_exec *x, int32_t r, int c, float *du, float *dv)
{
	if (r < 0 || !sl_x_varying(x, r)) {
		memset(du, 0, x->n * sizeof(float));
		memset(dv, 0, x->n * sizeof(float));
		return NULL;
	}
	return x->data[r] + (size_t)(rncomp(x, r) == 1 ? 0 : c) * x->stride;
}

/* d/du and d/dv of component @c of @r over the grid; zero for uniform values. */
static void deriv_of(struct sl_exec *x, int32_t r, int c, float *du, float *dv)
{
	const float *f = deriv_plane(x, r, c, du, dv);
	if (f)
		sl_exec_deriv(x, f, du, dv);
}

/*
 * The same for turning into changes over one step: Du(v) du is du[i] * *hu
 * (sl_exec_deriv_steps); zero for uniform values.
 */
static void deriv_steps_of(struct sl_exec *x, int32_t r, int c, float *du, float *dv, float *hu,
			   float *hv)
{
	*hu = *hv = 1.0f;
	const float *f = deriv_plane(x, r, c, du, dv);
	if (f)
		sl_exec_deriv_steps(x, f, du, dv, hu, hv);
}

static bool need_args(struct sl_exec *x, const struct sl_insn *in, int n)
{
	if (in->nargs >= n)
		return true;
	sl_exec_fail(x, in, "built-in '%s' needs %d arguments, has %d",
		     sl_builtins[in->bi].name, n, in->nargs);
	return false;
}

/* A component index from a float: truncated and clamped to [0, max], NaN -> 0. */
static int comp_index(float f, int max, bool *clamped)
{
	int k = f >= 0.0f ? (f <= (float)max ? (int)f : max) : 0;
	*clamped = f != (float)k;
	return k;
}

static inline float safe_div(float a, float b)
{
	return b == 0.0f ? 0.0f : sl_finite(a / b);
}

/* ------------------------------------------------------------------------ */
/* Math                                                                      */

static float math_op(int id, const float *a, int na)
{
	switch (id) {
	case SL_BI_RADIANS: return a[0] * (PI_F / 180.0f);
	case SL_BI_DEGREES: return a[0] * (180.0f / PI_F);
	case SL_BI_SIN: return sinf(a[0]);
	case SL_BI_ASIN: return sl_asin(a[0]);
	case SL_BI_COS: return cosf(a[0]);
	case SL_BI_ACOS: return sl_acos(a[0]);
	case SL_BI_TAN: return tanf(a[0]);
	case SL_BI_ATAN: return na >= 2 ? sl_atan2(a[0], a[1]) : atanf(a[0]);
	case SL_BI_SINH: return sinhf(a[0]);
	case SL_BI_COSH: return coshf(a[0]);
	case SL_BI_TANH: return tanhf(a[0]);
	case SL_BI_POW: return sl_pow(a[0], a[1]);
	case SL_BI_EXP: return sl_exp(a[0]);
	case SL_BI_SQRT: return sl_sqrt(a[0]);
	case SL_BI_INVERSESQRT: return sl_inversesqrt(a[0]);
	case SL_BI_LOG: return na >= 2 ? sl_logb(a[0], a[1]) : sl_log(a[0]);
	case SL_BI_MOD: return sl_mod(a[0], a[1]);
	case SL_BI_ABS: return fabsf(a[0]);
	case SL_BI_SIGN: return sl_sign(a[0]);
	case SL_BI_CLAMP: return fminf(fmaxf(a[0], a[1]), a[2]);
	case SL_BI_MIX: return (1.0f - a[2]) * a[0] + a[2] * a[1];
	case SL_BI_FLOOR: return floorf(a[0]);
	case SL_BI_CEIL: return ceilf(a[0]);
	case SL_BI_ROUND: return sl_round(a[0]);
	case SL_BI_STEP: return a[1] < a[0] ? 0.0f : 1.0f;
	case SL_BI_SMOOTHSTEP: return sl_smoothstep(a[0], a[1], a[2]);
	default: return 0.0f;
	}
}

static int math_arity(int id)
{
	switch (id) {
	case SL_BI_POW: case SL_BI_MOD: case SL_BI_STEP: case SL_BI_MIN: case SL_BI_MAX:
		return 2;
	case SL_BI_CLAMP: case SL_BI_MIX: case SL_BI_SMOOTHSTEP:
		return 3;
	default:
		return 1;
	}
}

/* Componentwise math: the destination's components, floats broadcast. */
static void do_math(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, math_arity(id)))
		return;
	int nc = rncomp(x, d);
	int na = in->nargs;
	SL_X_EACH(x, d, i) {
		float r[16];
		for (int c = 0; c < nc && c < 16; c++) {
			if (id == SL_BI_MIN || id == SL_BI_MAX) {
				float m = getc_(x, in->args[0], c, i);
				for (int k = 1; k < na; k++) {
					float v = getc_(x, in->args[k], c, i);
					m = id == SL_BI_MIN ? fminf(m, v) : fmaxf(m, v);
				}
				r[c] = m;
				continue;
			}
			float a[3] = { 0, 0, 0 };
			for (int k = 0; k < na && k < 3; k++)
				a[k] = getc_(x, in->args[k], c, i);
			r[c] = math_op(id, a, na);
		}
		for (int c = 0; c < nc && c < 16; c++)
			put(x, d, c, i, r[c]);
	}
}

/* filterstep(edge, s1 [, s2] [, "width", w, "filter", f ...]) with a box filter. */
static void do_filterstep(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	int nnum = 0;
	while (nnum < in->nargs && !is_string(x, a[nnum]))
		nnum++;
	uint32_t i0 = first_active(x);
	float width = 1.0f;
	for (int k = nnum; k + 1 < in->nargs; k += 2) {
		const char *opt = sget(x, a[k], 0, i0);
		if ((!strcmp(opt, "width") || !strcmp(opt, "swidth")) && !is_string(x, a[k + 1]))
			width = getf(x, a[k + 1], i0);
		else if (strcmp(opt, "filter") != 0 && strcmp(opt, "twidth") != 0)
			sl_exec_warn_once(x, in, "filterstep: unknown option '%s'", opt);
	}
	if (!(width >= 0.0f))
		width = 0.0f;
	float *dsu = NULL, *dsv = NULL, hu = 1.0f, hv = 1.0f;
	if (nnum < 3) {
		dsu = sl_exec_scratch(x, x->n);
		dsv = sl_exec_scratch(x, x->n);
		deriv_steps_of(x, a[1], 0, dsu, dsv, &hu, &hv);
	}
	SL_X_EACH(x, d, i) {
		float edge = getf(x, a[0], i), s1 = getf(x, a[1], i), lo, hi;
		if (nnum >= 3) {
			float s2 = getf(x, a[2], i);
			float mid = 0.5f * (s1 + s2), half = 0.5f * fabsf(s2 - s1) * width;
			lo = mid - half;
			hi = mid + half;
		} else {
			uint32_t j = sl_x_varying(x, d) ? i : i0;
			float w = (fabsf(dsu[j] * hu) + fabsf(dsv[j] * hv)) * width;
			lo = s1 - 0.5f * w;
			hi = s1 + 0.5f * w;
		}
		put(x, d, 0, i, sl_filterstep_box(edge, lo, hi));
	}
}

/* spline([basis,] t, v1, ..., vn) or spline([basis,] t, values[]). */
static void do_spline(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	int first = 0;
	int32_t basis_reg = -1;
	if (is_string(x, a[0])) {
		basis_reg = a[0];
		first = 1;
	}
	if (!need_args(x, in, first + 2))
		return;
	int32_t treg = a[first];
	int nc = rncomp(x, d);
	bool array = in->nargs == first + 2 && reg_of(x, a[first + 1])->arraylen > 0;
	int nvals = array ? relems(x, a[first + 1]) : in->nargs - first - 1;
	float *vals = sl_exec_scratch(x, (size_t)nvals * (size_t)nc);
	const char *last_name = NULL;
	int basis = SL_SPLINE_CATMULL_ROM;
	SL_X_EACH(x, d, i) {
		if (basis_reg >= 0) {
			const char *name = sget(x, basis_reg, 0, i);
			if (name != last_name) {
				last_name = name;
				basis = sl_spline_basis(name);
				if (basis < 0) {
					sl_exec_warn_once(x, in, "spline: unknown basis '%s' "
							  "(catmull-rom used)", name);
					basis = SL_SPLINE_CATMULL_ROM;
				}
			}
		}
		for (int k = 0; k < nvals; k++) {
			for (int c = 0; c < nc; c++) {
				if (array) {
					int32_t r = a[first + 1];
					int rc = rncomp(x, r);
					vals[k * nc + c] = sl_x_get(x, r, k * rc + (rc == 1 ? 0 : c), i);
				} else {
					vals[k * nc + c] = getc_(x, a[first + 1 + k], c, i);
				}
			}
		}
		float out[16];
		sl_spline_eval(basis, getf(x, treg, i), vals, nvals, nc, out);
		for (int c = 0; c < nc; c++)
			put(x, d, c, i, out[c]);
	}
}

/* ------------------------------------------------------------------------ */
/* Noise and random                                                          */

static void do_noise(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 1))
		return;
	int total = 0;
	for (int k = 0; k < in->nargs; k++)
		total += rncomp(x, in->args[k]);
	int dim = id == SL_BI_PNOISE ? total / 2 : total;
	if (dim < 1 || dim > 4) {
		sl_exec_fail(x, in, "%s: unsupported arguments", sl_builtins[in->bi].name);
		return;
	}
	int nc = rncomp(x, d);
	SL_X_EACH(x, d, i) {
		float comps[8];
		int m = 0;
		for (int k = 0; k < in->nargs; k++)
			for (int c = 0; c < rncomp(x, in->args[k]) && m < 8; c++)
				comps[m++] = sl_x_get(x, in->args[k], c, i);
		int32_t period[4] = { 0, 0, 0, 0 };
		if (id == SL_BI_PNOISE)
			for (int k = 0; k < dim; k++)
				period[k] = sl_noise_period(comps[dim + k]);
		float v[3];
		if (id == SL_BI_CELLNOISE) {
			if (nc == 1)
				v[0] = sl_cellnoise(dim, comps, 0);
			else
				sl_vcellnoise(dim, comps, v);
		} else {
			const int32_t *per = id == SL_BI_PNOISE ? period : NULL;
			if (nc == 1)
				v[0] = sl_noise(dim, comps, per, 0);
			else
				sl_vnoise(dim, comps, per, v);
		}
		put3(x, d, i, v);
	}
}

/*
 * random(): a hash of (call site, point index, number of random() calls in
 * this run). In a uniform context (imm 1) it is one value for the grid, the
 * one point 0 would draw, even where its result is stored per point.
 */
static void do_random(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0)
		return;
	uint32_t call = x->random_calls++;
	uint32_t seed = (uint32_t)(in - x->prog->code);
	int nc = rncomp(x, d);
	bool one = in->imm == 1;
	SL_X_EACH(x, d, i) {
		for (int c = 0; c < nc && c < 3; c++)
			put(x, d, c, i, sl_random(seed, one ? 0 : i, call * 3u + (uint32_t)c));
	}
}

/* ------------------------------------------------------------------------ */
/* Geometry                                                                  */

/* The host's specular model; PRMan's without a host. */
static enum sl_specular_model specular_model(const struct sl_exec *x)
{
	return x->host ? x->host->specular_model : SL_SPECULAR_PRMAN;
}

static void do_geometry(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	const int32_t *a = in->args;
	static const int nargs_of[SL_BI_COUNT] = {
		[SL_BI_XCOMP] = 1, [SL_BI_YCOMP] = 1, [SL_BI_ZCOMP] = 1, [SL_BI_LENGTH] = 1,
		[SL_BI_NORMALIZE] = 1, [SL_BI_DISTANCE] = 2, [SL_BI_PTLINED] = 3,
		[SL_BI_ROTATE] = 3, [SL_BI_FACEFORWARD] = 2, [SL_BI_REFLECT] = 2,
		[SL_BI_REFRACT] = 3, [SL_BI_SPECULARBRDF] = 4, [SL_BI_DETERMINANT] = 1,
		[SL_BI_TRANSLATE] = 2, [SL_BI_SCALE] = 2,
	};
	if (d < 0 || !need_args(x, in, nargs_of[id]))
		return;
	int32_t nref = -1;
	if (id == SL_BI_FACEFORWARD) {
		nref = in->nargs >= 3 ? a[2] : x->prog->global_reg[SL_GLOBAL_NG];
		if (nref < 0)
			nref = a[0];
	}
	bool matrix_rotate = id == SL_BI_ROTATE && rncomp(x, a[0]) == 16;
	if (id == SL_BI_ROTATE && !matrix_rotate && !need_args(x, in, 4))
		return;
	SL_X_EACH(x, d, i) {
		float p[3], q[3], r[3], s[3], m[16];
		switch (id) {
		case SL_BI_XCOMP: case SL_BI_YCOMP: case SL_BI_ZCOMP:
			put(x, d, 0, i, getc_(x, a[0], id - SL_BI_XCOMP, i));
			break;
		case SL_BI_LENGTH:
			get3(x, a[0], i, p);
			put(x, d, 0, i, sl_v3_length(p));
			break;
		case SL_BI_NORMALIZE:
			get3(x, a[0], i, p);
			sl_v3_normalize(r, p);
			put3(x, d, i, r);
			break;
		case SL_BI_DISTANCE:
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			for (int c = 0; c < 3; c++)
				r[c] = p[c] - q[c];
			put(x, d, 0, i, sl_v3_length(r));
			break;
		case SL_BI_PTLINED:
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			get3(x, a[2], i, s);
			put(x, d, 0, i, sl_ptlined(p, q, s));
			break;
		case SL_BI_ROTATE:
			if (matrix_rotate) {
				getm(x, a[0], i, m);
				get3(x, a[2], i, p);
				sl_m44_rotate(m, m, getf(x, a[1], i), p);
				putm(x, d, i, m);
			} else {
				get3(x, a[0], i, p);
				get3(x, a[2], i, q);
				get3(x, a[3], i, s);
				sl_rotate_point(r, p, getf(x, a[1], i), q, s);
				put3(x, d, i, r);
			}
			break;
		case SL_BI_FACEFORWARD:
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			get3(x, nref, i, s);
			sl_faceforward(r, p, q, s);
			put3(x, d, i, r);
			break;
		case SL_BI_REFLECT:
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			sl_reflect(r, p, q);
			put3(x, d, i, r);
			break;
		case SL_BI_REFRACT:
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			sl_refract(r, p, q, getf(x, a[2], i));
			put3(x, d, i, r);
			break;
		case SL_BI_SPECULARBRDF: {
			get3(x, a[0], i, p);
			get3(x, a[1], i, q);
			get3(x, a[2], i, s);
			float v = sl_specularbrdf(p, q, s, getf(x, a[3], i), specular_model(x));
			float c3[3] = { v, v, v };
			put3(x, d, i, c3);
			break;
		}
		case SL_BI_DETERMINANT:
			getm(x, a[0], i, m);
			put(x, d, 0, i, sl_m44_det(m));
			break;
		case SL_BI_TRANSLATE:
			getm(x, a[0], i, m);
			get3(x, a[1], i, p);
			sl_m44_translate(m, m, p);
			putm(x, d, i, m);
			break;
		case SL_BI_SCALE:
			getm(x, a[0], i, m);
			get3(x, a[1], i, p);
			sl_m44_scale(m, m, p);
			putm(x, d, i, m);
			break;
		default:
			break;
		}
	}
}

/* Is any of the registers @r[0..n) varying? */
static bool any_varying(const struct sl_exec *x, const int32_t *r, int n)
{
	for (int k = 0; k < n; k++)
		if (r[k] >= 0 && sl_x_varying(x, r[k]))
			return true;
	return false;
}

/* fresnel(I, N, eta, Kr, Kt [, R, T]) */
static void do_fresnel(struct sl_exec *x, const struct sl_insn *in)
{
	if (!need_args(x, in, 5))
		return;
	const int32_t *a = in->args;
	bool dirs = in->nargs >= 7;
	bool vary = any_varying(x, a + 3, dirs ? 4 : 2);
	uint32_t n = vary ? x->n : (x->nactive ? 1 : 0);
	uint32_t i0 = first_active(x);
	for (uint32_t k = 0; k < n; k++) {
		if (vary && !x->mask[k])
			continue;
		uint32_t i = vary ? k : i0;
		float I[3], N[3], R[3], T[3], kr, kt;
		get3(x, a[0], i, I);
		get3(x, a[1], i, N);
		sl_fresnel(I, N, getf(x, a[2], i), &kr, &kt, R, T);
		/* A uniform output is written once, at its single slot. */
		put(x, a[3], 0, i, kr);
		put(x, a[4], 0, i, kt);
		if (dirs) {
			put3(x, a[5], i, R);
			put3(x, a[6], i, T);
		}
	}
}

/* setxcomp / setycomp / setzcomp (P, value) and setcomp (c, index, value) / (m, row, col, value). */
static void do_setcomp(struct sl_exec *x, const struct sl_insn *in, int id)
{
	if (!need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	bool mat = rncomp(x, a[0]) == 16;
	int want = id == SL_BI_SETCOMP ? (mat ? 4 : 3) : 2;
	if (!need_args(x, in, want))
		return;
	int32_t t = a[0];
	int nc = rncomp(x, t);
	SL_X_EACH(x, t, i) {
		int c;
		if (id != SL_BI_SETCOMP) {
			c = id - SL_BI_SETXCOMP;
		} else if (mat) {
			bool bad_r, bad_c;
			int ri = comp_index(getf(x, a[1], i), 3, &bad_r);
			int ci = comp_index(getf(x, a[2], i), 3, &bad_c);
			if (bad_r || bad_c)
				sl_exec_warn_once(x, in, "setcomp: index out of range (clamped)");
			c = ri * 4 + ci;
		} else {
			bool bad;
			c = comp_index(getf(x, a[1], i), nc - 1, &bad);
			if (bad)
				sl_exec_warn_once(x, in, "setcomp: index out of range (clamped)");
		}
		if (c < nc)
			put(x, t, c, i, getf(x, a[want - 1], i));
	}
}

/* comp(c, index) / comp(m, row, col) */
static void do_comp(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	bool mat = rncomp(x, a[0]) == 16;
	if (mat && !need_args(x, in, 3))
		return;
	int nc = rncomp(x, a[0]);
	SL_X_EACH(x, d, i) {
		int c;
		if (mat) {
			bool bad_r, bad_c;
			int ri = comp_index(getf(x, a[1], i), 3, &bad_r);
			int ci = comp_index(getf(x, a[2], i), 3, &bad_c);
			if (bad_r || bad_c)
				sl_exec_warn_once(x, in, "comp: index out of range (clamped)");
			c = ri * 4 + ci;
		} else {
			bool bad;
			c = comp_index(getf(x, a[1], i), nc - 1, &bad);
			if (bad)
				sl_exec_warn_once(x, in, "comp: index out of range (clamped)");
		}
		put(x, d, 0, i, sl_x_get(x, a[0], c < nc ? c : 0, i));
	}
}

/* ---- coordinate systems ---- */

/* A one-entry cache of a space's matrix, by name pointer. */
struct space_cache {
	const char *name;
	bool inverse;
	float m[16];
};

/* space -> current (or, with @inverse, current -> space). */
static const float *space_matrix(struct sl_exec *x, const struct sl_insn *in,
				 struct space_cache *sc, const char *name, bool inverse)
{
	if (sc->name && sc->name == name && sc->inverse == inverse)
		return sc->m;
	sc->name = name;
	sc->inverse = inverse;
	float m[16];
	sl_exec_space(x, in, name, m);
	if (!inverse)
		memcpy(sc->m, m, sizeof(m));
	else if (!sl_m44_inverse(sc->m, m))
		sl_exec_warn_once(x, in, "the matrix of coordinate system '%s' is singular "
				  "(identity used)", name);
	return sc->m;
}

enum xf_kind { XF_POINT, XF_VECTOR, XF_NORMAL };

/* transform / vtransform / ntransform: (to, v), (from, to, v), (m, v), (from, m, v). */
static void do_transform(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	int na = in->nargs > 3 ? 3 : in->nargs;
	int32_t val = a[na - 1];
	enum xf_kind kind = id == SL_BI_VTRANSFORM ? XF_VECTOR :
			    id == SL_BI_NTRANSFORM ? XF_NORMAL : XF_POINT;
	if (id == SL_BI_TRANSFORM) {
		/* transform() of a vector or normal transforms it as one. */
		if (rtype(x, val) == SL_TYPE_VECTOR)
			kind = XF_VECTOR;
		else if (rtype(x, val) == SL_TYPE_NORMAL)
			kind = XF_NORMAL;
	}
	struct space_cache from = { 0 }, to = { 0 };
	/* The matrix is the same for every point unless a space argument varies. */
	bool fixed = !any_varying(x, a, na - 1);
	float M[16];
	sl_m44_identity(M);
	uint32_t i0 = first_active(x);
	SL_X_EACH(x, d, i) {
		if (!fixed || i == i0 || !sl_x_varying(x, d)) {
			uint32_t j = fixed ? i0 : i;
			int32_t last = a[na - 2];
			float tail[16];
			if (rncomp(x, last) == 16)
				getm(x, last, j, tail);
			else
				memcpy(tail, space_matrix(x, in, &to, sget(x, last, 0, j), true),
				       sizeof(tail));
			if (na == 3)
				sl_m44_mul(M, space_matrix(x, in, &from, sget(x, a[0], 0, j), false),
					   tail);
			else
				memcpy(M, tail, sizeof(M));
		}
		float v[3], r[3];
		get3(x, val, i, v);
		if (kind == XF_POINT)
			sl_xform_point(r, M, v);
		else if (kind == XF_VECTOR)
			sl_xform_vector(r, M, v);
		else
			sl_xform_normal(r, M, v);
		put3(x, d, i, r);
	}
}

/* __spacematrix(space, m): m expressed in @space, i.e. m * (space -> current). */
static void do_spacematrix(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	struct space_cache sc = { 0 };
	SL_X_EACH(x, d, i) {
		float m[16];
		getm(x, in->args[1], i, m);
		sl_m44_mul(m, m, space_matrix(x, in, &sc, sget(x, in->args[0], 0, i), false));
		putm(x, d, i, m);
	}
}

/* depth(P): camera-space z mapped so that the clipping planes are 0 and 1. */
static void do_depth(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 1))
		return;
	struct space_cache sc = { 0 };
	const float *tocam = space_matrix(x, in, &sc, "camera", true);
	const struct sl_host *h = x->host;
	float clip[2] = { 0, 0 };
	bool have_clip = h && h->option &&
			 h->option(h->user, "Clipping", SL_TYPE_FLOAT, 2, clip, NULL) &&
			 clip[1] != clip[0];
	SL_X_EACH(x, d, i) {
		float p[3], c[3];
		get3(x, in->args[0], i, p);
		sl_xform_point(c, tocam, p);
		put(x, d, 0, i, have_clip ? safe_div(c[2] - clip[0], clip[1] - clip[0]) : c[2]);
	}
}

/* ctransform(to, c) / ctransform(from, to, c) */
static void do_ctransform(struct sl_exec *x, const struct sl_insn *in)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	bool two = in->nargs >= 3;
	int32_t val = a[two ? 2 : 1];
	SL_X_EACH(x, d, i) {
		const char *from = two ? sget(x, a[0], 0, i) : "rgb";
		const char *to = sget(x, a[two ? 1 : 0], 0, i);
		float c[3], rgb[3], out[3];
		get3(x, val, i, c);
		if (!sl_color_to_rgb(from, c, rgb))
			sl_exec_warn_once(x, in, "unknown color space '%s'", from);
		if (!sl_color_from_rgb(to, rgb, out))
			sl_exec_warn_once(x, in, "unknown color space '%s'", to);
		put3(x, d, i, out);
	}
}

/* ---- derivatives ---- */

static void do_deriv(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	int want = id == SL_BI_DERIV ? 2 : 1;
	if (d < 0 || !need_args(x, in, want))
		return;
	const int32_t *a = in->args;
	uint32_t n = x->n;
	int nc = rncomp(x, d);
	if (nc > 3)
		nc = 3;
	uint32_t i0 = first_active(x);
	float *du = sl_exec_scratch(x, n), *dv = sl_exec_scratch(x, n);
	float *ddu = NULL, *ddv = NULL;
	if (id == SL_BI_DERIV) {
		ddu = sl_exec_scratch(x, n);
		ddv = sl_exec_scratch(x, n);
		deriv_of(x, a[1], 0, ddu, ddv);
	}
	for (int c = 0; c < nc; c++) {
		deriv_of(x, a[0], c, du, dv);
		SL_X_EACH(x, d, i) {
			uint32_t j = src_index(x, d, i, i0);
			float v;
			if (id == SL_BI_DU)
				v = du[j];
			else if (id == SL_BI_DV)
				v = dv[j];
			else
				v = safe_div(du[j], ddu[j]) + safe_div(dv[j], ddv[j]);
			put(x, d, c, i, v);
		}
	}
}

/* area(P) = |Du(P) du x Dv(P) dv|; calculatenormal(P) = Du(P) x Dv(P). */
static void do_surface_deriv(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 1))
		return;
	uint32_t n = x->n;
	float *pu = sl_exec_scratch(x, 3 * (size_t)n), *pv = sl_exec_scratch(x, 3 * (size_t)n);
	float hu = 1.0f, hv = 1.0f;
	for (int c = 0; c < 3; c++) {
		float *cu = pu + (size_t)c * n, *cv = pv + (size_t)c * n;
		if (id == SL_BI_AREA)
			deriv_steps_of(x, in->args[0], c, cu, cv, &hu, &hv);
		else
			deriv_of(x, in->args[0], c, cu, cv);
	}
	uint32_t i0 = first_active(x);
	SL_X_EACH(x, d, i) {
		uint32_t j = src_index(x, d, i, i0);
		float u[3], v[3], r[3];
		for (int c = 0; c < 3; c++) {
			u[c] = pu[(size_t)c * n + j];
			v[c] = pv[(size_t)c * n + j];
		}
		if (id == SL_BI_AREA) {
			for (int c = 0; c < 3; c++) {
				u[c] *= hu;
				v[c] *= hv;
			}
			sl_v3_cross(r, u, v);
			put(x, d, 0, i, sl_v3_length(r));
		} else {
			sl_v3_cross(r, u, v);
			put3(x, d, i, r);
		}
	}
}

/* ------------------------------------------------------------------------ */
/* Lighting                                                                  */

/*
 * A light's message @name as a per-point flag: fills @flag (planes of stride
 * floats; @sflag is room for strings) and returns whether the light
 * answered; *vary says whether flag[i] or flag[0] holds the value.
 */
static bool light_flag(struct sl_exec *x, int light, const char *name, float *flag,
		       const char **sflag, bool *vary)
{
	const struct sl_host *h = x->host;
	*vary = false;
	if (!h || !h->light_message)
		return false;
	flag[0] = 0.0f;
	return h->light_message(h->user, light, name, SL_TYPE_FLOAT, 0, flag, sflag, vary,
				x->stride);
}

/* Float operations to normalize L and N and test the hemisphere (exec.h). */
#define LIGHT_TEST_COST 24u

/* ambient(), diffuse(N), specular(N, V, roughness), phong(N, V, size) */
static void do_lighting(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	const int32_t *a = in->args;
	int want = id == SL_BI_AMBIENT ? 0 : id == SL_BI_DIFFUSE ? 1 : 3;
	if (d < 0 || !need_args(x, in, want))
		return;
	size_t s = x->stride;
	uint32_t n = x->n;
	float *acc = sl_exec_scratch(x, 3 * s);
	memset(acc, 0, 3 * s * sizeof(float));
	/* Room for 16 planes: the callback is not told how much it may write. */
	float *flag = sl_exec_scratch(x, 16 * s);
	const char **sflag = (const char **)(void *)sl_exec_scratch(
		x, (16 * s * sizeof(char *) + sizeof(float) - 1) / sizeof(float));
	const float *Ps = global_planes(x, SL_GLOBAL_P);
	const char *skip = id == SL_BI_DIFFUSE ? "__nondiffuse" :
			   id == SL_BI_AMBIENT ? NULL : "__nonspecular";
	/* The lights' Ns: the normal given, none for ambient(). */
	float *Ns = NULL;
	if (id != SL_BI_AMBIENT) {
		Ns = sl_exec_scratch(x, 3 * s);
		for (int c = 0; c < 3; c++)
			memcpy(Ns + c * s, plane_of(x, a[0], c), n * sizeof(float));
	}
	int nl = sl_exec_nlights(x);
	for (int li = 0; li < nl && !x->failed; li++) {
		struct sl_light_result res;
		if (!sl_exec_light(x, li, 0, Ps, Ns, &res))
			continue;
		if (id == SL_BI_AMBIENT) {
			if (!res.ambient)
				continue;
			for (uint32_t i = 0; i < n; i++)
				if (x->mask[i])
					for (int c = 0; c < 3; c++)
						acc[c * s + i] += res.Cl[c * s + i];
			sl_exec_add_ops(x, 3, x->nactive);
			continue;
		}
		if (res.ambient)
			continue;
		bool fvary, has_flag = light_flag(x, li, skip, flag, sflag, &fvary);
		uint32_t tested = 0, facing = 0;
		for (uint32_t i = 0; i < n; i++) {
			if (!x->mask[i] || !res.lit[i])
				continue;
			if (has_flag && (fvary ? flag[i] : flag[0]) > 0.5f)
				continue;
			tested++;
			float L[3] = { res.L[i], res.L[s + i], res.L[2 * s + i] };
			float Ln[3], N[3], Nn[3];
			sl_v3_normalize(Ln, L);
			get3(x, a[0], i, N);
			sl_v3_normalize(Nn, N);
			/* The light cone is the hemisphere around N. */
			float cosl = sl_v3_dot(Ln, Nn);
			if (cosl < 0.0f)
				continue;
			facing++;
			float k;
			if (id == SL_BI_DIFFUSE) {
				k = cosl;
			} else {
				float V[3];
				get3(x, a[1], i, V);
				float p = getf(x, a[2], i);
				if (id == SL_BI_SPECULAR) {
					k = sl_specularbrdf(Ln, N, V, p, specular_model(x));
				} else {
					float mv[3], Vn[3], R[3];
					sl_v3_normalize(Vn, V);
					for (int c = 0; c < 3; c++)
						mv[c] = -Vn[c];
					sl_reflect(R, mv, Nn);
					k = sl_pow(fmaxf(0.0f, sl_v3_dot(R, Ln)), p);
				}
			}
			for (int c = 0; c < 3; c++)
				acc[c * s + i] = sl_finite(acc[c * s + i] + res.Cl[c * s + i] * k);
		}
		sl_exec_add_ops(x, LIGHT_TEST_COST, tested);
		sl_exec_add_ops(x, id == SL_BI_DIFFUSE ? 6 : id == SL_BI_SPECULAR ? 26 : 37, facing);
	}
	uint32_t i0 = first_active(x);
	SL_X_EACH(x, d, i) {
		uint32_t j = src_index(x, d, i, i0);
		float c3[3] = { acc[j], acc[s + j], acc[2 * s + j] };
		put3(x, d, i, c3);
	}
}

/* ------------------------------------------------------------------------ */
/* Textures                                                                  */

enum tex_kind { TEX_TEXTURE, TEX_ENVIRONMENT, TEX_SHADOW };

static const char *const tex_kind_name[] = { "texture", "environment", "shadow" };

/*
 * The four corners of the filter region around component @c of @r:
 * v -+ Du(v) du / 2 -+ Dv(v) dv / 2, written to out[k] (n floats each).
 */
static void tex_region(struct sl_exec *x, int32_t r, int c, float *const out[4])
{
	static const float su[4] = { -0.5f, 0.5f, 0.5f, -0.5f };
	static const float sv[4] = { -0.5f, -0.5f, 0.5f, 0.5f };
	uint32_t n = x->n;
	const float *v = plane_of(x, r, c);
	float *du = sl_exec_scratch(x, n), *dv = sl_exec_scratch(x, n), hu, hv;
	deriv_steps_of(x, r, c, du, dv, &hu, &hv);
	for (int k = 0; k < 4; k++)
		for (uint32_t i = 0; i < n; i++)
			out[k][i] = sl_finite(v[i] + su[k] * du[i] * hu + sv[k] * dv[i] * hv);
}

/* Options "name", value pairs from argument @k on. */
static void tex_options(struct sl_exec *x, const struct sl_insn *in, int k,
			struct sl_tex_lookup *q)
{
	const int32_t *a = in->args;
	uint32_t i0 = first_active(x);
	for (; k < in->nargs; k += 2) {
		if (!is_string(x, a[k]) || k + 1 >= in->nargs) {
			sl_exec_warn_once(x, in, "%s: options must be \"name\", value pairs",
					  sl_builtins[in->bi].name);
			return;
		}
		const char *opt = sget(x, a[k], 0, i0);
		int32_t vr = a[k + 1];
		if (is_string(x, vr)) {
			if (!strcmp(opt, "filter"))
				q->filter = sget(x, vr, 0, i0);
			else
				sl_exec_warn_once(x, in, "%s: unknown option '%s'",
						  sl_builtins[in->bi].name, opt);
			continue;
		}
		float v = getf(x, vr, i0);
		if (!strcmp(opt, "blur"))
			q->blur = q->sblur = q->tblur = v;
		else if (!strcmp(opt, "sblur"))
			q->sblur = v;
		else if (!strcmp(opt, "tblur"))
			q->tblur = v;
		else if (!strcmp(opt, "width"))
			q->width = q->swidth = q->twidth = v;
		else if (!strcmp(opt, "swidth"))
			q->swidth = v;
		else if (!strcmp(opt, "twidth"))
			q->twidth = v;
		else if (!strcmp(opt, "samples"))
			q->samples = v;
		else if (!strcmp(opt, "bias"))
			q->bias = v;
		else if (!strcmp(opt, "fill"))
			q->fill = v;
		else
			sl_exec_warn_once(x, in, "%s: unknown option '%s'", sl_builtins[in->bi].name,
					  opt);
	}
}

/* texture / environment / shadow: [name, channel, coordinates..., options...] */
static void do_texture(struct sl_exec *x, const struct sl_insn *in, enum tex_kind kind)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	uint32_t i0 = first_active(x), n = x->n;
	size_t s = x->stride;
	struct sl_tex_lookup q;
	memset(&q, 0, sizeof(q));
	q.name = sget(x, a[0], 0, i0);
	float ch = getf(x, a[1], i0);
	q.channel = ch > 0.0f && ch < 65536.0f ? (int)ch : 0;
	q.nchannels = rncomp(x, d) == 3 ? 3 : 1;
	q.n = n;
	q.stride = x->stride;
	q.mask = x->mask;
	q.width = q.swidth = q.twidth = 1.0f;
	q.samples = kind == TEX_SHADOW ? 16.0f : 1.0f;
	q.bias = -1.0f;
	q.filter = "gaussian";

	int ncoord = 0;
	while (2 + ncoord < in->nargs && !is_string(x, a[2 + ncoord]))
		ncoord++;
	if (kind != TEX_TEXTURE && ncoord >= 1 && !strcmp(q.name, "raytrace")) {
		sl_exec_ray_lookup(x, in, kind == TEX_SHADOW, ncoord >= 4 ? 4 : 1);
		return;
	}
	if (kind == TEX_TEXTURE) {
		float *buf = sl_exec_scratch(x, 8 * s);
		float *sc[4], *tc[4];
		for (int k = 0; k < 4; k++) {
			sc[k] = buf + (size_t)(2 * k) * s;
			tc[k] = buf + (size_t)(2 * k + 1) * s;
			q.s[k] = sc[k];
			q.t[k] = tc[k];
		}
		if (ncoord >= 8) {
			for (int k = 0; k < 4; k++) {
				const float *ps = plane_of(x, a[2 + 2 * k], 0);
				const float *pt = plane_of(x, a[3 + 2 * k], 0);
				memcpy(sc[k], ps, n * sizeof(float));
				memcpy(tc[k], pt, n * sizeof(float));
			}
		} else {
			int32_t sr = ncoord >= 2 ? a[2] : x->prog->global_reg[SL_GLOBAL_S];
			int32_t tr = ncoord >= 2 ? a[3] : x->prog->global_reg[SL_GLOBAL_T];
			tex_region(x, sr, 0, sc);
			tex_region(x, tr, 0, tc);
		}
		ncoord = ncoord >= 8 ? 8 : ncoord >= 2 ? 2 : 0;
	} else {
		if (ncoord < 1) {
			sl_exec_fail(x, in, "%s: missing direction", tex_kind_name[kind]);
			return;
		}
		float *buf = sl_exec_scratch(x, 12 * s);
		float *corner[4];
		for (int k = 0; k < 4; k++) {
			corner[k] = buf + (size_t)(3 * k) * s;
			if (kind == TEX_ENVIRONMENT)
				q.dir[k] = corner[k];
			else
				q.pos[k] = corner[k];
		}
		if (ncoord >= 4) {
			for (int k = 0; k < 4; k++)
				for (int c = 0; c < 3; c++)
					memcpy(corner[k] + (size_t)c * s, plane_of(x, a[2 + k], c),
					       n * sizeof(float));
			ncoord = 4;
		} else {
			float *center = sl_exec_scratch(x, 3 * s);
			for (int c = 0; c < 3; c++) {
				float *out[4];
				for (int k = 0; k < 4; k++)
					out[k] = corner[k] + (size_t)c * s;
				tex_region(x, a[2], c, out);
				memcpy(center + (size_t)c * s, plane_of(x, a[2], c), n * sizeof(float));
			}
			if (kind == TEX_SHADOW)
				q.center = center;
			ncoord = 1;
		}
	}
	tex_options(x, in, 2 + ncoord, &q);

	q.out = sl_exec_scratch(x, (size_t)q.nchannels * s);
	const struct sl_host *h = x->host;
	bool (*fn)(void *, const struct sl_tex_lookup *) = NULL;
	if (h)
		fn = kind == TEX_TEXTURE ? h->texture :
		     kind == TEX_ENVIRONMENT ? h->environment : h->shadow;
	/* An empty name is the usual "no map" parameter default: quietly the fill. */
	bool ok = q.name[0] && fn && fn(h->user, &q);
	if (!ok) {
		if (q.name[0])
			sl_exec_warn_once(x, in, "%s '%s' not found", tex_kind_name[kind], q.name);
		for (int c = 0; c < q.nchannels; c++)
			for (uint32_t i = 0; i < n; i++)
				q.out[(size_t)c * s + i] = q.fill;
	}
	int nc = rncomp(x, d);
	SL_X_EACH(x, d, i) {
		uint32_t j = src_index(x, d, i, i0);
		for (int c = 0; c < nc && c < 3; c++)
			put(x, d, c, i, q.out[(size_t)(q.nchannels == 1 ? 0 : c) * s + j]);
	}
}

/* ------------------------------------------------------------------------ */
/* Message passing and queries                                               */

/* Write the same (uniform-layout) value into output register @r at every written point. */
static void write_out(struct sl_exec *x, int32_t r, const float *vals, const char **svals)
{
	int total = rncomp(x, r) * relems(x, r);
	int ne = relems(x, r);
	if (is_string(x, r)) {
		for (int e = 0; e < ne; e++)
			svals[e] = sl_exec_strdup(x, svals[e] ? svals[e] : "");
	}
	SL_X_EACH(x, r, i) {
		if (is_string(x, r)) {
			for (int e = 0; e < ne; e++)
				sset(x, r, e, i, svals[e]);
		} else {
			for (int k = 0; k < total; k++)
				put(x, r, k, i, vals[k]);
		}
	}
}

static void put_result(struct sl_exec *x, int32_t d, bool ok)
{
	if (d < 0)
		return;
	SL_X_EACH(x, d, i)
		put(x, d, 0, i, ok ? 1.0f : 0.0f);
}

/* attribute / option / rendererinfo (name, out) and textureinfo (tex, query, out). */
static void do_query(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int want = id == SL_BI_TEXTUREINFO ? 3 : 2;
	if (!need_args(x, in, want))
		return;
	const int32_t *a = in->args;
	int32_t out = a[want - 1];
	uint32_t i0 = first_active(x);
	const struct sl_host *h = x->host;
	int ne = relems(x, out);
	int32_t alen = reg_of(x, out)->arraylen > 0 ? reg_of(x, out)->arraylen : 0;
	size_t nf = (size_t)rncomp(x, out) * (size_t)ne;
	float *vals = sl_exec_scratch(x, nf ? nf : 1);
	memset(vals, 0, (nf ? nf : 1) * sizeof(float));
	const char **svals = (const char **)(void *)sl_exec_scratch(
		x, ((size_t)ne * sizeof(char *) + sizeof(float) - 1) / sizeof(float));
	for (int e = 0; e < ne; e++)
		svals[e] = NULL;
	const char *name = sget(x, a[0], 0, i0);
	int type = rtype(x, out);
	bool ok = false;
	if (h) {
		switch (id) {
		case SL_BI_ATTRIBUTE:
			ok = h->attribute && h->attribute(h->user, name, type, alen, vals, svals);
			break;
		case SL_BI_OPTION:
			ok = h->option && h->option(h->user, name, type, alen, vals, svals);
			break;
		case SL_BI_RENDERERINFO:
			ok = h->rendererinfo &&
			     h->rendererinfo(h->user, name, type, alen, vals, svals);
			break;
		case SL_BI_RAYINFO:
			ok = h->rayinfo && h->rayinfo(h->user, name, type, alen, vals, svals);
			break;
		default:
			ok = h->textureinfo && h->textureinfo(h->user, name, sget(x, a[1], 0, i0),
							      type, alen, vals, svals);
			break;
		}
	}
	if (ok)
		write_out(x, out, vals, svals);
	put_result(x, in->dst, ok);
}

/* lightsource(name, out): a parameter of the light the enclosing illuminance visits. */
static void do_lightsource(struct sl_exec *x, const struct sl_insn *in)
{
	if (!need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	int32_t out = a[1];
	const struct sl_host *h = x->host;
	bool ok = false;
	if (x->cur_light >= 0 && h && h->light_message) {
		size_t s = x->stride;
		int total = rncomp(x, out) * relems(x, out);
		int ne = relems(x, out);
		/* The host writes exactly the variable's type and array length. */
		size_t room = (size_t)(total > 1 ? total : 1) * s;
		size_t sroom = (size_t)(ne > 1 ? ne : 1) * s;
		float *buf = sl_exec_scratch(x, room);
		const char **sbuf = (const char **)(void *)sl_exec_scratch(
			x, (sroom * sizeof(char *) + sizeof(float) - 1) / sizeof(float));
		for (size_t k = 0; k < sroom; k++)
			sbuf[k] = NULL;
		bool vary = false;
		const char *name = sget(x, a[0], 0, first_active(x));
		ok = h->light_message(h->user, x->cur_light, name, rtype(x, out),
				      x->prog->regs[out].arraylen, buf, sbuf, &vary, x->stride);
		if (ok) {
			uint32_t i0 = first_active(x);
			SL_X_EACH(x, out, i) {
				uint32_t j = sl_x_varying(x, out) ? i : i0;
				if (is_string(x, out)) {
					for (int e = 0; e < ne; e++) {
						const char *v = vary ? sbuf[(size_t)e * s + j] : sbuf[e];
						sset(x, out, e, i, sl_exec_strdup(x, v));
					}
				} else {
					for (int k = 0; k < total; k++)
						put(x, out, k, i, vary ? buf[(size_t)k * s + j] : buf[k]);
				}
			}
		}
	}
	put_result(x, in->dst, ok);
}

/* surface() / displacement() / atmosphere(): read a parameter of the peer shader. */
static void do_peer(struct sl_exec *x, const struct sl_insn *in, enum sl_peer which)
{
	if (!need_args(x, in, 2))
		return;
	const int32_t *a = in->args;
	int32_t out = a[1];
	struct sl_exec *p = x->peer[which];
	bool ok = false;
	const char *name = sget(x, a[0], 0, first_active(x));
	int k = p ? sl_program_find_param(p->prog, name) : -1;
	if (k >= 0) {
		int32_t pr = p->prog->params[k].reg;
		const struct sl_reg *src = &p->prog->regs[pr], *dst = reg_of(x, out);
		bool pstr = src->type == SL_TYPE_STRING, xstr = dst->type == SL_TYPE_STRING;
		int pe = src->arraylen > 0 ? src->arraylen : 1;
		ok = pstr == xstr && sl_type_ncomp(src->type) == rncomp(x, out) &&
		     pe == relems(x, out);
		if (ok && src->varying && p->n != x->n) {
			sl_exec_warn_once(x, in, "message passing between grids of different sizes");
			ok = false;
		}
		if (ok) {
			int total = xstr ? pe : rncomp(x, out) * pe;
			uint32_t i0 = first_active(x);
			SL_X_EACH(x, out, i) {
				uint32_t j = sl_x_varying(x, out) ? i : i0;
				for (int c = 0; c < total; c++) {
					if (xstr) {
						const char **sd = p->sdata[pr];
						const char *v = src->varying ? sd[(size_t)c * p->stride + j]
									     : sd[c];
						/* The peer's strings die with its next run. */
						sset(x, out, c, i, sl_exec_strdup(x, v));
					} else {
						const float *fd = p->data[pr];
						float v = src->varying ? fd[(size_t)c * p->stride + j]
								       : fd[c];
						put(x, out, c, i, v);
					}
				}
			}
		}
	}
	put_result(x, in->dst, ok);
}

/* ------------------------------------------------------------------------ */
/* Strings                                                                   */

/* Append @v formatted by the conversion @conv with @flags, @width, @prec. */
static void fmt_number(struct rl_strbuf *b, float v, char conv, const char *flags, int width,
		       int prec)
{
	char spec[48];
	char w[16] = "", p[16] = "";
	if (width >= 0)
		snprintf(w, sizeof(w), "%d", width);
	if (prec >= 0)
		snprintf(p, sizeof(p), ".%d", prec);
	if (conv == 'd' || conv == 'i') {
		double dv = v;
		long long iv = dv != dv ? 0 :
			       dv >= 9.2e18 ? (long long)9.2e18 :
			       dv <= -9.2e18 ? -(long long)9.2e18 : (long long)dv;
		snprintf(spec, sizeof(spec), "%%%s%s%slld", flags, w, p);
		rl_strbuf_printf(b, spec, iv);
		return;
	}
	if (!strchr("fFeEgG", conv))
		conv = 'f';
	snprintf(spec, sizeof(spec), "%%%s%s%s%c", flags, w, p, conv);
	rl_strbuf_printf(b, spec, (double)v);
}

/* Append the value of register @r at point @i for one conversion. */
static void fmt_value(struct sl_exec *x, struct rl_strbuf *b, int32_t r, uint32_t i, char conv,
		      const char *flags, int width, int prec)
{
	if (is_string(x, r)) {
		char spec[48], w[16] = "", p[16] = "";
		if (width >= 0)
			snprintf(w, sizeof(w), "%d", width);
		if (prec >= 0)
			snprintf(p, sizeof(p), ".%d", prec);
		snprintf(spec, sizeof(spec), "%%%s%s%ss", flags, w, p);
		for (int e = 0; e < relems(x, r); e++) {
			if (e)
				rl_strbuf_putc(b, ' ');
			rl_strbuf_printf(b, spec, sget(x, r, e, i));
		}
		return;
	}
	int total = rncomp(x, r) * relems(x, r);
	/* Conversions of a whole triple or matrix print its components as floats. */
	char cconv = conv;
	if (strchr("cpvnms", conv))
		cconv = (conv == 's' && total == 1) ? 'g' : 'f';
	for (int k = 0; k < total; k++) {
		if (k)
			rl_strbuf_putc(b, ' ');
		fmt_number(b, sl_x_get(x, r, k, i), cconv, flags, width, prec);
	}
}

/* A field width or precision: digits, capped. */
static int parse_field(const char **f)
{
	int v = 0;
	while (**f >= '0' && **f <= '9') {
		if (v < MAX_FIELD)
			v = v * 10 + (**f - '0');
		(*f)++;
	}
	return v > MAX_FIELD ? MAX_FIELD : v;
}

/*
 * Format argument @fmt_arg of @in with the arguments after it, at point @i:
 * %f %e %g (floats), %d %i (integers), %s (strings), %c (colors), %p %v %n
 * (points, vectors, normals), %m (matrices), %% -- each with optional flags,
 * width and precision.
 */
static void format_at(struct sl_exec *x, const struct sl_insn *in, int fmt_arg, uint32_t i,
		      struct rl_strbuf *b)
{
	const char *f = sget(x, in->args[fmt_arg], 0, i);
	int k = fmt_arg + 1;
	while (*f) {
		if (*f != '%') {
			const char *e = strchr(f, '%');
			size_t len = e ? (size_t)(e - f) : strlen(f);
			rl_strbuf_add(b, f, len);
			f += len;
			continue;
		}
		const char *start = f++;
		if (*f == '%') {
			rl_strbuf_putc(b, '%');
			f++;
			continue;
		}
		char flags[8];
		int nflags = 0;
		while (*f && strchr("-+ #0", *f)) {
			if (nflags < 5)
				flags[nflags++] = *f;
			f++;
		}
		flags[nflags] = '\0';
		int width = -1, prec = -1;
		if (*f >= '0' && *f <= '9')
			width = parse_field(&f);
		if (*f == '.') {
			f++;
			prec = parse_field(&f);
		}
		char conv = *f;
		if (!conv || !strchr("dieEfFgGscpvnm", conv)) {
			/* Not a conversion: print it as written. */
			if (conv)
				f++;
			rl_strbuf_add(b, start, (size_t)(f - start));
			continue;
		}
		f++;
		if (k >= in->nargs) {
			sl_exec_warn_once(x, in, "%s: more conversions than arguments",
					  sl_builtins[in->bi].name);
			rl_strbuf_add(b, start, (size_t)(f - start));
			continue;
		}
		fmt_value(x, b, in->args[k++], i, conv, flags, width, prec);
	}
}

static void do_printf(struct sl_exec *x, const struct sl_insn *in)
{
	if (!need_args(x, in, 1) || !x->nactive)
		return;
	struct rl_strbuf b = { 0 };
	bool vary = any_varying(x, in->args, in->nargs);
	const struct sl_host *h = x->host;
	for (uint32_t i = vary ? 0 : first_active(x); i < x->n; i++) {
		if (!x->mask[i])
			continue;
		rl_strbuf_reset(&b);
		format_at(x, in, 0, i, &b);
		if (h && h->print)
			h->print(h->user, rl_strbuf_str(&b));
		else
			fputs(rl_strbuf_str(&b), stdout);
		if (!vary)
			break;
	}
	if (!(h && h->print))
		fflush(stdout);
	rl_strbuf_finish(&b);
}

static void do_strings(struct sl_exec *x, const struct sl_insn *in, int id)
{
	int32_t d = in->dst;
	if (d < 0 || !need_args(x, in, id == SL_BI_MATCH ? 2 : 1))
		return;
	const int32_t *a = in->args;
	struct rl_strbuf b = { 0 };
	/* match(): a pattern that is the same everywhere is compiled once. */
	regex_t re;
	bool re_ok = false;
	const char *re_src = NULL;
	SL_X_EACH(x, d, i) {
		if (id == SL_BI_MATCH) {
			const char *pat = sget(x, a[0], 0, i);
			if (!re_src || strcmp(pat, re_src) != 0) {
				if (re_ok)
					regfree(&re);
				re_src = pat;
				re_ok = regcomp(&re, pat, REG_EXTENDED | REG_NOSUB) == 0;
				if (!re_ok)
					sl_exec_warn_once(x, in, "match: invalid pattern '%s'", pat);
			}
			bool m = re_ok && regexec(&re, sget(x, a[1], 0, i), 0, NULL, 0) == 0;
			put(x, d, 0, i, m ? 1.0f : 0.0f);
			continue;
		}
		rl_strbuf_reset(&b);
		if (id == SL_BI_FORMAT) {
			format_at(x, in, 0, i, &b);
		} else {
			for (int k = 0; k < in->nargs; k++)
				rl_strbuf_puts(&b, sget(x, a[k], 0, i));
		}
		sset(x, d, 0, i, sl_exec_strdup(x, rl_strbuf_str(&b)));
	}
	if (re_ok)
		regfree(&re);
	rl_strbuf_finish(&b);
}

/* ------------------------------------------------------------------------ */

void sl_exec_builtin(struct sl_exec *x, const struct sl_insn *in)
{
	if (in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins) {
		sl_exec_fail(x, in, "call of an unknown built-in");
		return;
	}
	int id = sl_builtins[in->bi].id;
	switch ((enum sl_bi)id) {
	case SL_BI_RADIANS: case SL_BI_DEGREES: case SL_BI_SIN: case SL_BI_ASIN: case SL_BI_COS:
	case SL_BI_ACOS: case SL_BI_TAN: case SL_BI_ATAN: case SL_BI_SINH: case SL_BI_COSH:
	case SL_BI_TANH: case SL_BI_POW: case SL_BI_EXP: case SL_BI_SQRT: case SL_BI_INVERSESQRT:
	case SL_BI_LOG: case SL_BI_MOD: case SL_BI_ABS: case SL_BI_SIGN: case SL_BI_MIN:
	case SL_BI_MAX: case SL_BI_CLAMP: case SL_BI_MIX: case SL_BI_FLOOR: case SL_BI_CEIL:
	case SL_BI_ROUND: case SL_BI_STEP: case SL_BI_SMOOTHSTEP:
		do_math(x, in, id);
		break;
	case SL_BI_FILTERSTEP:
		do_filterstep(x, in);
		break;
	case SL_BI_SPLINE:
		do_spline(x, in);
		break;
	case SL_BI_NOISE: case SL_BI_PNOISE: case SL_BI_CELLNOISE:
		do_noise(x, in, id);
		break;
	case SL_BI_RANDOM:
		do_random(x, in);
		break;
	case SL_BI_XCOMP: case SL_BI_YCOMP: case SL_BI_ZCOMP: case SL_BI_LENGTH:
	case SL_BI_NORMALIZE: case SL_BI_DISTANCE: case SL_BI_PTLINED: case SL_BI_ROTATE:
	case SL_BI_FACEFORWARD: case SL_BI_REFLECT: case SL_BI_REFRACT:
	case SL_BI_SPECULARBRDF: case SL_BI_DETERMINANT: case SL_BI_TRANSLATE: case SL_BI_SCALE:
		do_geometry(x, in, id);
		break;
	case SL_BI_SETXCOMP: case SL_BI_SETYCOMP: case SL_BI_SETZCOMP: case SL_BI_SETCOMP:
		do_setcomp(x, in, id);
		break;
	case SL_BI_COMP:
		do_comp(x, in);
		break;
	case SL_BI_FRESNEL:
		do_fresnel(x, in);
		break;
	case SL_BI_TRANSFORM: case SL_BI_VTRANSFORM: case SL_BI_NTRANSFORM:
		do_transform(x, in, id);
		break;
	case SL_BI_SPACEMATRIX:
		do_spacematrix(x, in);
		break;
	case SL_BI_DEPTH:
		do_depth(x, in);
		break;
	case SL_BI_CTRANSFORM:
		do_ctransform(x, in);
		break;
	case SL_BI_DU: case SL_BI_DV: case SL_BI_DERIV:
		do_deriv(x, in, id);
		break;
	case SL_BI_AREA: case SL_BI_CALCULATENORMAL:
		do_surface_deriv(x, in, id);
		break;
	case SL_BI_AMBIENT: case SL_BI_DIFFUSE: case SL_BI_SPECULAR: case SL_BI_PHONG:
		do_lighting(x, in, id);
		break;
	case SL_BI_TEXTURE:
		do_texture(x, in, TEX_TEXTURE);
		break;
	case SL_BI_ENVIRONMENT:
		do_texture(x, in, TEX_ENVIRONMENT);
		break;
	case SL_BI_SHADOW:
		do_texture(x, in, TEX_SHADOW);
		break;
	case SL_BI_TEXTUREINFO: case SL_BI_ATTRIBUTE: case SL_BI_OPTION: case SL_BI_RENDERERINFO:
	case SL_BI_RAYINFO:
		do_query(x, in, id);
		break;
	case SL_BI_LIGHTSOURCE:
		do_lightsource(x, in);
		break;
	case SL_BI_SURFACE:
		do_peer(x, in, SL_PEER_SURFACE);
		break;
	case SL_BI_DISPLACEMENT:
		do_peer(x, in, SL_PEER_DISPLACEMENT);
		break;
	case SL_BI_ATMOSPHERE:
		do_peer(x, in, SL_PEER_ATMOSPHERE);
		break;
	case SL_BI_INCIDENT: case SL_BI_OPPOSITE:
		/* No volume shaders: nothing to read. */
		put_result(x, in->dst, false);
		break;
	case SL_BI_PRINTF:
		do_printf(x, in);
		break;
	case SL_BI_TRACE: case SL_BI_TRANSMISSION: case SL_BI_OCCLUSION:
	case SL_BI_INDIRECTDIFFUSE: case SL_BI_RAYLEVEL: case SL_BI_ISSHADOWRAY:
		sl_exec_ray_builtin(x, in, id);
		break;
	case SL_BI_FORMAT: case SL_BI_CONCAT: case SL_BI_MATCH:
		do_strings(x, in, id);
		break;
	case SL_BI_COUNT:
	default:
		sl_exec_fail(x, in, "built-in '%s' is not implemented", sl_builtins[in->bi].name);
		break;
	}
}

/* ------------------------------------------------------------------------ */
/* Float operation counts (the table in exec.h)                              */

/*
 * Per output component of noise() of 1 to 4 dimensions: lattice and
 * fraction (2 per dimension), fade (7 per dimension), per corner the
 * offsets (1 per dimension) and the gradient's dot (4, 3, 1, 2 by
 * dimension), the blends (3 each) and the final scale and clamp (5).
 */
static const uint16_t noise_cost[5] = { 0, 27, 52, 85, 182 };

/* Is register @r the constant string "rgb"? */
static bool is_const_rgb(const struct sl_program *prog, int32_t r)
{
	const struct sl_reg *g = &prog->regs[r];
	return g->kind == SL_REG_CONST && g->type == SL_TYPE_STRING &&
	       prog->strings[g->cindex] && !strcmp(prog->strings[g->cindex], "rgb");
}

uint32_t sl_exec_builtin_cost(const struct sl_program *prog, const struct sl_insn *in)
{
	if (in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins)
		return 0;
	const int32_t *a = in->args;
	int na = in->nargs;
	uint32_t nc = in->dst >= 0 ? (uint32_t)sl_reg_ncomp(&prog->regs[in->dst]) : 0;
	switch ((enum sl_bi)sl_builtins[in->bi].id) {
	case SL_BI_RADIANS: case SL_BI_DEGREES: case SL_BI_STEP:
		return 1;
	case SL_BI_SIN: case SL_BI_ASIN: case SL_BI_COS: case SL_BI_ACOS: case SL_BI_TAN:
	case SL_BI_ATAN: case SL_BI_SINH: case SL_BI_COSH: case SL_BI_TANH: case SL_BI_POW:
	case SL_BI_EXP: case SL_BI_SQRT: case SL_BI_INVERSESQRT: case SL_BI_ABS: case SL_BI_SIGN:
	case SL_BI_FLOOR: case SL_BI_CEIL: case SL_BI_ROUND:
		return nc;
	case SL_BI_LOG:
		return na >= 2 ? 3 : nc;
	case SL_BI_MOD:
		return 4 * nc;
	case SL_BI_MIN: case SL_BI_MAX:
		return na > 1 ? (uint32_t)(na - 1) * nc : 0;
	case SL_BI_CLAMP:
		return 2 * nc;
	case SL_BI_MIX:
		return 3 * nc;
	case SL_BI_SMOOTHSTEP:
		return 9;
	case SL_BI_FILTERSTEP: {
		int nnum = 0;
		while (nnum < na && prog->regs[a[nnum]].type != SL_TYPE_STRING)
			nnum++;
		return nnum >= 3 ? 14 : 19;
	}
	case SL_BI_SPLINE:
		return 29 + 7 * nc;
	case SL_BI_NOISE: case SL_BI_PNOISE: case SL_BI_CELLNOISE: {
		int total = 0;
		for (int k = 0; k < na; k++)
			total += sl_reg_ncomp(&prog->regs[a[k]]);
		int dim = sl_builtins[in->bi].id == SL_BI_PNOISE ? total / 2 : total;
		if (dim < 1 || dim > 4)
			return 0;
		if (sl_builtins[in->bi].id == SL_BI_CELLNOISE)
			return (uint32_t)(dim + 1) * nc;
		return noise_cost[dim] * nc;
	}
	case SL_BI_LENGTH:
		return 6;
	case SL_BI_NORMALIZE: case SL_BI_DISTANCE: case SL_BI_FACEFORWARD:
		return 9;
	case SL_BI_PTLINED:
		return 31;
	case SL_BI_ROTATE:
		return na >= 1 && sl_reg_ncomp(&prog->regs[a[0]]) == 16 ? 151 : 63;
	case SL_BI_REFLECT:
		return 12;
	case SL_BI_REFRACT:
		return 24;
	case SL_BI_FRESNEL:
		return na >= 7 ? 88 : 52;
	case SL_BI_SPECULARBRDF:
		return 20;
	case SL_BI_AREA:
		return 33;
	case SL_BI_CALCULATENORMAL:
		return 21;
	case SL_BI_DU: case SL_BI_DV:
		return 2 * nc;
	case SL_BI_DERIV:
		return 4 + 7 * nc;
	case SL_BI_TRANSFORM:
		if (na >= 1 && prog->regs[a[na > 3 ? 2 : na - 1]].type == SL_TYPE_POINT)
			return 27;
		return 15;
	case SL_BI_VTRANSFORM: case SL_BI_NTRANSFORM:
		return 15;
	case SL_BI_DEPTH:
		return 30;
	case SL_BI_CTRANSFORM: {
		if (na < 2)
			return 0;
		uint32_t c = is_const_rgb(prog, a[na >= 3 ? 1 : 0]) ? 0 : 9;
		if (na >= 3 && !is_const_rgb(prog, a[0]))
			c += 9;
		return c;
	}
	case SL_BI_DETERMINANT:
		return 63;
	case SL_BI_TRANSLATE: case SL_BI_SCALE: case SL_BI_SPACEMATRIX:
		return 112;
	default:
		return 0;
	}
}

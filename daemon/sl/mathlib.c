/* Numerics of RSL's built-in library: scalars, triples, matrices, colors, splines. */
#include "mathlib.h"

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

/* ---- scalars ---- */

float sl_finite(float x)
{
	if (x != x)
		return 0.0f;
	if (x > FLT_MAX)
		return FLT_MAX;
	if (x < -FLT_MAX)
		return -FLT_MAX;
	return x;
}

float sl_to_float(double x)
{
	if (x != x)
		return 0.0f;
	if (x > FLT_MAX)
		return FLT_MAX;
	if (x < -FLT_MAX)
		return -FLT_MAX;
	return (float)x;
}

float sl_clampf(float x, float lo, float hi)
{
	return x < lo ? lo : x > hi ? hi : x;
}

float sl_pow(float x, float y)
{
	if (y == 0.0f)
		return 1.0f;
	if (x == 0.0f)
		return 0.0f;
	if (x < 0.0f && floorf(y) != y)
		return 0.0f;
	return sl_finite(powf(x, y));
}

float sl_sqrt(float x)
{
	return x > 0.0f ? sqrtf(x) : 0.0f;
}

float sl_inversesqrt(float x)
{
	return x > 0.0f ? sl_finite(1.0f / sqrtf(x)) : 0.0f;
}

float sl_log(float x)
{
	if (!(x >= FLT_MIN))
		x = FLT_MIN;
	return logf(sl_finite(x));
}

float sl_logb(float x, float base)
{
	if (!(base > 0.0f) || base == 1.0f)
		return 0.0f;
	return sl_finite(sl_log(x) / sl_log(base));
}

float sl_exp(float x)
{
	return sl_finite(expf(x));
}

float sl_acos(float x)
{
	return acosf(sl_clampf(x, -1.0f, 1.0f));
}

float sl_asin(float x)
{
	return asinf(sl_clampf(x, -1.0f, 1.0f));
}

float sl_atan2(float y, float x)
{
	if (y == 0.0f && x == 0.0f)
		return 0.0f;
	return atan2f(y, x);
}

float sl_mod(float a, float b)
{
	if (b == 0.0f)
		return 0.0f;
	float r = sl_finite(a - b * floorf(a / b));
	/* Rounding can land exactly on b (mod(-1e-9, 1)); keep r in [0,b) or (b,0]. */
	if ((b > 0.0f && r >= b) || (b < 0.0f && r <= b))
		r = 0.0f;
	return r;
}

float sl_round(float x)
{
	return roundf(x);
}

float sl_sign(float x)
{
	return x > 0.0f ? 1.0f : x < 0.0f ? -1.0f : 0.0f;
}

float sl_smoothstep(float e0, float e1, float x)
{
	if (e0 == e1)
		return x < e0 ? 0.0f : 1.0f;
	float t = sl_clampf(sl_finite((x - e0) / (e1 - e0)), 0.0f, 1.0f);
	return t * t * (3.0f - 2.0f * t);
}

float sl_filterstep_box(float edge, float s0, float s1)
{
	if (s1 < s0) {
		float tmp = s0;
		s0 = s1;
		s1 = tmp;
	}
	float w = s1 - s0;
	if (!(w > 0.0f))
		return s0 < edge ? 0.0f : 1.0f;
	return sl_clampf(sl_finite((s1 - edge) / w), 0.0f, 1.0f);
}

/* ---- triples ---- */

float sl_v3_dot(const float a[3], const float b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

void sl_v3_cross(float r[3], const float a[3], const float b[3])
{
	float x = a[1] * b[2] - a[2] * b[1];
	float y = a[2] * b[0] - a[0] * b[2];
	float z = a[0] * b[1] - a[1] * b[0];
	r[0] = x;
	r[1] = y;
	r[2] = z;
}

float sl_v3_length(const float a[3])
{
	/* In double: the squares of large components would overflow a float. */
	double x = a[0], y = a[1], z = a[2];
	return sl_to_float(sqrt(x * x + y * y + z * z));
}

void sl_v3_normalize(float r[3], const float a[3])
{
	double x = a[0], y = a[1], z = a[2];
	double len = sqrt(x * x + y * y + z * z);
	if (!(len >= FLT_MIN) || len != len) {
		r[0] = r[1] = r[2] = 0.0f;
		return;
	}
	r[0] = (float)(x / len);
	r[1] = (float)(y / len);
	r[2] = (float)(z / len);
}

float sl_ptlined(const float p0[3], const float p1[3], const float q[3])
{
	double d[3], w[3];
	for (int c = 0; c < 3; c++) {
		d[c] = (double)p1[c] - p0[c];
		w[c] = (double)q[c] - p0[c];
	}
	double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
	double t = dd > 0.0 ? (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd : 0.0;
	t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
	double s = 0.0;
	for (int c = 0; c < 3; c++) {
		double e = w[c] - t * d[c];
		s += e * e;
	}
	return sl_to_float(sqrt(s));
}

void sl_reflect(float r[3], const float I[3], const float N[3])
{
	float k = 2.0f * sl_v3_dot(I, N);
	for (int c = 0; c < 3; c++)
		r[c] = sl_finite(I[c] - k * N[c]);
}

void sl_refract(float r[3], const float I[3], const float N[3], float eta)
{
	float idn = sl_v3_dot(I, N);
	float k = 1.0f - eta * eta * (1.0f - idn * idn);
	if (!(k >= 0.0f)) {
		r[0] = r[1] = r[2] = 0.0f;
		return;
	}
	float a = eta * idn + sqrtf(k);
	for (int c = 0; c < 3; c++)
		r[c] = sl_finite(eta * I[c] - a * N[c]);
}

void sl_fresnel(const float I[3], const float N[3], float eta, float *Kr, float *Kt,
		float R[3], float T[3])
{
	float in[3], nn[3];
	sl_v3_normalize(in, I);
	sl_v3_normalize(nn, N);
	if (sl_v3_dot(in, in) == 0.0f || sl_v3_dot(nn, nn) == 0.0f || !(eta > 0.0f)) {
		*Kr = 0.0f;
		*Kt = 1.0f;
		for (int c = 0; c < 3; c++) {
			if (R)
				R[c] = I[c];
			if (T)
				T[c] = I[c];
		}
		return;
	}
	float idn = sl_v3_dot(in, nn);
	if (idn > 0.0f) {
		/* I arrives from behind N: use the normal that faces it. */
		for (int c = 0; c < 3; c++)
			nn[c] = -nn[c];
		idn = -idn;
	}
	if (R)
		sl_reflect(R, in, nn);
	if (T)
		sl_refract(T, in, nn, eta);

	double c = -idn;
	double n = 1.0 / eta;   /* index of the entered side over the incident side */
	double g2 = n * n + c * c - 1.0;
	if (g2 < 0.0) {
		*Kr = 1.0f;
		*Kt = 0.0f;
		return;
	}
	double g = sqrt(g2);
	double gpc = g + c, gmc = g - c;
	double kr = 1.0;
	if (gpc > 0.0) {
		double a = gmc / gpc;
		double den = c * gmc + 1.0;
		double b = den != 0.0 ? (c * gpc - 1.0) / den : 0.0;
		kr = 0.5 * a * a * (1.0 + b * b);
	}
	kr = kr < 0.0 ? 0.0 : kr > 1.0 ? 1.0 : kr;
	*Kr = (float)kr;
	*Kt = (float)(1.0 - kr);
}

void sl_faceforward(float r[3], const float N[3], const float I[3], const float Nref[3])
{
	float s = sl_v3_dot(I, Nref) > 0.0f ? -1.0f : 1.0f;
	for (int c = 0; c < 3; c++)
		r[c] = s * N[c];
}

void sl_rotate_point(float r[3], const float q[3], float angle, const float p0[3],
		     const float p1[3])
{
	float axis[3] = { p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2] };
	float m[16], d[3];
	sl_m44_rotation(m, angle, axis);
	for (int c = 0; c < 3; c++)
		d[c] = q[c] - p0[c];
	sl_xform_vector(d, m, d);
	for (int c = 0; c < 3; c++)
		r[c] = sl_finite(d[c] + p0[c]);
}

const char *sl_specular_model_name(enum sl_specular_model m)
{
	return m == SL_SPECULAR_RISPEC ? "rispec" : "prman";
}

bool sl_specular_model_parse(const char *name, enum sl_specular_model *m)
{
	if (!name)
		return false;
	if (!strcmp(name, "prman"))
		*m = SL_SPECULAR_PRMAN;
	else if (!strcmp(name, "rispec"))
		*m = SL_SPECULAR_RISPEC;
	else
		return false;
	return true;
}

float sl_specularbrdf(const float L[3], const float N[3], const float V[3], float roughness,
		      enum sl_specular_model m)
{
	float h[3] = { L[0] + V[0], L[1] + V[1], L[2] + V[2] };
	sl_v3_normalize(h, h);
	float d = sl_v3_dot(N, h);
	if (!(d > 0.0f))
		return 0.0f;
	if (!(roughness > 1e-6f))
		roughness = 1e-6f;
	return sl_pow(d, (m == SL_SPECULAR_RISPEC ? 1.0f : 8.0f) / roughness);
}

/* ---- 4x4 matrices ---- */

void sl_m44_identity(float m[16])
{
	for (int i = 0; i < 16; i++)
		m[i] = (i % 5 == 0) ? 1.0f : 0.0f;
}

void sl_m44_mul(float r[16], const float a[16], const float b[16])
{
	float t[16];
	for (int i = 0; i < 4; i++) {
		for (int j = 0; j < 4; j++) {
			double s = 0.0;
			for (int k = 0; k < 4; k++)
				s += (double)a[i * 4 + k] * b[k * 4 + j];
			t[i * 4 + j] = sl_to_float(s);
		}
	}
	memcpy(r, t, sizeof(t));
}

void sl_m44_transpose(float r[16], const float m[16])
{
	float t[16];
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++)
			t[j * 4 + i] = m[i * 4 + j];
	memcpy(r, t, sizeof(t));
}

/* Determinant of the 3x3 minor of @m without row @skip_r and column @skip_c. */
static double minor3(const double m[16], int skip_r, int skip_c)
{
	double a[9];
	int k = 0;
	for (int i = 0; i < 4; i++) {
		if (i == skip_r)
			continue;
		for (int j = 0; j < 4; j++)
			if (j != skip_c)
				a[k++] = m[i * 4 + j];
	}
	return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
	       a[2] * (a[3] * a[7] - a[4] * a[6]);
}

float sl_m44_det(const float m[16])
{
	double d[16];
	for (int i = 0; i < 16; i++)
		d[i] = m[i];
	double det = 0.0;
	for (int j = 0; j < 4; j++) {
		double cof = minor3(d, 0, j);
		det += (j & 1 ? -d[j] : d[j]) * cof;
	}
	return sl_to_float(det);
}

bool sl_m44_inverse(float r[16], const float m[16])
{
	/*
	 * Gauss-Jordan elimination with partial pivoting, in double, on a copy
	 * whose rows are first scaled to unit maximum, so that a matrix that is
	 * merely small (a scale by 1e-5) is not mistaken for a singular one.
	 */
	double a[4][8];
	for (int i = 0; i < 4; i++) {
		double rmax = 0.0;
		for (int j = 0; j < 4; j++) {
			double v = m[i * 4 + j];
			if (v != v)
				goto singular;
			rmax = fmax(rmax, fabs(v));
		}
		if (!(rmax > 0.0) || rmax > DBL_MAX)
			goto singular;
		for (int j = 0; j < 4; j++) {
			a[i][j] = m[i * 4 + j] / rmax;
			a[i][4 + j] = (i == j) ? 1.0 / rmax : 0.0;
		}
	}
	for (int col = 0; col < 4; col++) {
		int piv = col;
		for (int i = col + 1; i < 4; i++)
			if (fabs(a[i][col]) > fabs(a[piv][col]))
				piv = i;
		if (!(fabs(a[piv][col]) > 1e-12))
			goto singular;
		if (piv != col) {
			for (int j = 0; j < 8; j++) {
				double t = a[col][j];
				a[col][j] = a[piv][j];
				a[piv][j] = t;
			}
		}
		double inv = 1.0 / a[col][col];
		for (int j = 0; j < 8; j++)
			a[col][j] *= inv;
		for (int i = 0; i < 4; i++) {
			if (i == col || a[i][col] == 0.0)
				continue;
			double f = a[i][col];
			for (int j = 0; j < 8; j++)
				a[i][j] -= f * a[col][j];
		}
	}
	float t[16];
	for (int i = 0; i < 4; i++) {
		for (int j = 0; j < 4; j++) {
			double v = a[i][4 + j];
			if (!(fabs(v) <= FLT_MAX))
				goto singular;
			t[i * 4 + j] = (float)v;
		}
	}
	memcpy(r, t, sizeof(t));
	return true;
singular:
	sl_m44_identity(r);
	return false;
}

void sl_m44_translation(float m[16], const float t[3])
{
	sl_m44_identity(m);
	m[12] = t[0];
	m[13] = t[1];
	m[14] = t[2];
}

void sl_m44_rotation(float m[16], float angle, const float axis[3])
{
	float u[3];
	sl_m44_identity(m);
	sl_v3_normalize(u, axis);
	if (sl_v3_dot(u, u) == 0.0f)
		return;
	double c = cos(angle), s = sin(angle), t = 1.0 - c;
	double x = u[0], y = u[1], z = u[2];
	/* Row-vector form (the transpose of the usual column-vector matrix). */
	m[0] = (float)(t * x * x + c);
	m[1] = (float)(t * x * y + s * z);
	m[2] = (float)(t * x * z - s * y);
	m[4] = (float)(t * x * y - s * z);
	m[5] = (float)(t * y * y + c);
	m[6] = (float)(t * y * z + s * x);
	m[8] = (float)(t * x * z + s * y);
	m[9] = (float)(t * y * z - s * x);
	m[10] = (float)(t * z * z + c);
}

void sl_m44_scaling(float m[16], const float s[3])
{
	sl_m44_identity(m);
	m[0] = s[0];
	m[5] = s[1];
	m[10] = s[2];
}

void sl_m44_translate(float r[16], const float m[16], const float t[3])
{
	float x[16];
	sl_m44_translation(x, t);
	sl_m44_mul(r, x, m);
}

void sl_m44_rotate(float r[16], const float m[16], float angle, const float axis[3])
{
	float x[16];
	sl_m44_rotation(x, angle, axis);
	sl_m44_mul(r, x, m);
}

void sl_m44_scale(float r[16], const float m[16], const float s[3])
{
	float x[16];
	sl_m44_scaling(x, s);
	sl_m44_mul(r, x, m);
}

void sl_xform_point(float r[3], const float m[16], const float p[3])
{
	double o[4];
	for (int j = 0; j < 4; j++)
		o[j] = (double)p[0] * m[j] + (double)p[1] * m[4 + j] + (double)p[2] * m[8 + j] +
		       m[12 + j];
	double w = o[3];
	if (w != 0.0 && w != 1.0) {
		o[0] /= w;
		o[1] /= w;
		o[2] /= w;
	}
	for (int j = 0; j < 3; j++)
		r[j] = sl_to_float(o[j]);
}

void sl_xform_vector(float r[3], const float m[16], const float v[3])
{
	double o[3];
	for (int j = 0; j < 3; j++)
		o[j] = (double)v[0] * m[j] + (double)v[1] * m[4 + j] + (double)v[2] * m[8 + j];
	for (int j = 0; j < 3; j++)
		r[j] = sl_to_float(o[j]);
}

void sl_xform_normal(float r[3], const float m[16], const float n[3])
{
	/* cof[i][j]: cofactor of element (i, j) of the upper 3x3. */
	double a[3][3], cof[3][3];
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			a[i][j] = m[i * 4 + j];
	for (int i = 0; i < 3; i++) {
		for (int j = 0; j < 3; j++) {
			int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
			int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
			cof[i][j] = a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1];
		}
	}
	double det = a[0][0] * cof[0][0] + a[0][1] * cof[0][1] + a[0][2] * cof[0][2];
	/* n * inverse(A)^T = n * cof / det; without an inverse, keep the direction. */
	double scale = (det != 0.0 && fabs(det) > 1e-30) ? 1.0 / det : 1.0;
	for (int j = 0; j < 3; j++) {
		double s = 0.0;
		for (int i = 0; i < 3; i++)
			s += (double)n[i] * cof[i][j];
		r[j] = sl_to_float(s * scale);
	}
}

/* ---- colors ---- */

enum cspace { CS_RGB, CS_HSV, CS_HSL, CS_XYZ, CS_XYY, CS_YIQ, CS_UNKNOWN };

static enum cspace color_space(const char *name)
{
	static const char *const names[] = { "rgb", "hsv", "hsl", "xyz", "xyy", "yiq" };
	if (!name)
		return CS_UNKNOWN;
	char low[8];
	size_t len = strlen(name);
	if (len >= sizeof(low))
		return CS_UNKNOWN;
	for (size_t i = 0; i <= len; i++) {
		char ch = name[i];
		low[i] = (ch >= 'A' && ch <= 'Z') ? (char)(ch - 'A' + 'a') : ch;
	}
	for (int i = 0; i < CS_UNKNOWN; i++)
		if (strcmp(low, names[i]) == 0)
			return (enum cspace)i;
	return CS_UNKNOWN;
}

bool sl_color_space_known(const char *space)
{
	return color_space(space) != CS_UNKNOWN;
}

/* Linear Rec.709 RGB to CIE XYZ, D65 white. */
static const double rgb_to_xyz[3][3] = {
	{ 0.4124564, 0.3575761, 0.1804375 },
	{ 0.2126729, 0.7151522, 0.0721750 },
	{ 0.0193339, 0.1191920, 0.9503041 },
};

/* RGB to NTSC YIQ. */
static const double rgb_to_yiq[3][3] = {
	{ 0.299, 0.587, 0.114 },
	{ 0.595716, -0.274453, -0.321263 },
	{ 0.211456, -0.522591, 0.311135 },
};

static void mat3_apply(const double m[3][3], const float in[3], float out[3])
{
	double o[3];
	for (int i = 0; i < 3; i++)
		o[i] = m[i][0] * in[0] + m[i][1] * in[1] + m[i][2] * in[2];
	for (int i = 0; i < 3; i++)
		out[i] = sl_to_float(o[i]);
}

/* Apply the inverse of @m (computed exactly, so that round trips close). */
static void mat3_apply_inverse(const double m[3][3], const float in[3], float out[3])
{
	double cof[3][3];
	for (int i = 0; i < 3; i++) {
		for (int j = 0; j < 3; j++) {
			int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
			int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
			cof[i][j] = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
		}
	}
	double det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
	double o[3];
	/* inverse = transpose(cof) / det */
	for (int i = 0; i < 3; i++)
		o[i] = (cof[0][i] * in[0] + cof[1][i] * in[1] + cof[2][i] * in[2]) / det;
	for (int i = 0; i < 3; i++)
		out[i] = sl_to_float(o[i]);
}

/* Hue in [0,1) of an RGB color with maximum @mx and range @d > 0. */
static float hue_of(const float c[3], float mx, float d)
{
	float h;
	if (mx == c[0])
		h = (c[1] - c[2]) / d;
	else if (mx == c[1])
		h = 2.0f + (c[2] - c[0]) / d;
	else
		h = 4.0f + (c[0] - c[1]) / d;
	h /= 6.0f;
	if (h < 0.0f)
		h += 1.0f;
	if (h >= 1.0f)
		h -= 1.0f;
	return sl_finite(h);
}

static void rgb_to_hsv(const float c[3], float o[3])
{
	float mx = fmaxf(c[0], fmaxf(c[1], c[2]));
	float mn = fminf(c[0], fminf(c[1], c[2]));
	float d = mx - mn;
	o[2] = mx;
	o[1] = (mx > 0.0f && d > 0.0f) ? sl_finite(d / mx) : 0.0f;
	o[0] = d > 0.0f ? hue_of(c, mx, d) : 0.0f;
}

static void hsv_to_rgb(const float c[3], float o[3])
{
	float h = c[0] - floorf(c[0]), s = c[1], v = c[2];
	float h6 = h * 6.0f;
	/* h can round up to exactly 1 (hue -1e-9): that is hue 0. */
	if (!(h6 >= 0.0f && h6 < 6.0f))
		h6 = 0.0f;
	int sector = (int)h6;
	float f = h6 - (float)sector;
	float p = v * (1.0f - s), q = v * (1.0f - s * f), t = v * (1.0f - s * (1.0f - f));
	switch (sector) {
	case 0: o[0] = v; o[1] = t; o[2] = p; break;
	case 1: o[0] = q; o[1] = v; o[2] = p; break;
	case 2: o[0] = p; o[1] = v; o[2] = t; break;
	case 3: o[0] = p; o[1] = q; o[2] = v; break;
	case 4: o[0] = t; o[1] = p; o[2] = v; break;
	default: o[0] = v; o[1] = p; o[2] = q; break;
	}
}

static void rgb_to_hsl(const float c[3], float o[3])
{
	float mx = fmaxf(c[0], fmaxf(c[1], c[2]));
	float mn = fminf(c[0], fminf(c[1], c[2]));
	float d = mx - mn, l = 0.5f * (mx + mn);
	o[2] = l;
	if (!(d > 0.0f)) {
		o[0] = o[1] = 0.0f;
		return;
	}
	float den = l <= 0.5f ? mx + mn : 2.0f - mx - mn;
	o[1] = den != 0.0f ? sl_finite(d / den) : 0.0f;
	o[0] = hue_of(c, mx, d);
}

static float hsl_channel(float p, float q, float h)
{
	h -= floorf(h);
	if (h < 1.0f / 6.0f)
		return p + (q - p) * 6.0f * h;
	if (h < 0.5f)
		return q;
	if (h < 2.0f / 3.0f)
		return p + (q - p) * (2.0f / 3.0f - h) * 6.0f;
	return p;
}

static void hsl_to_rgb(const float c[3], float o[3])
{
	float h = c[0], s = c[1], l = c[2];
	if (s == 0.0f) {
		o[0] = o[1] = o[2] = l;
		return;
	}
	float q = l < 0.5f ? l * (1.0f + s) : l + s - l * s;
	float p = 2.0f * l - q;
	o[0] = hsl_channel(p, q, h + 1.0f / 3.0f);
	o[1] = hsl_channel(p, q, h);
	o[2] = hsl_channel(p, q, h - 1.0f / 3.0f);
}

/* D65 white chromaticity, for black in xyY. */
#define WHITE_X 0.3127f
#define WHITE_Y 0.3290f

static void xyz_to_xyy(const float c[3], float o[3])
{
	double sum = (double)c[0] + c[1] + c[2];
	if (sum == 0.0) {
		o[0] = WHITE_X;
		o[1] = WHITE_Y;
		o[2] = c[1];
		return;
	}
	o[0] = sl_to_float(c[0] / sum);
	o[1] = sl_to_float(c[1] / sum);
	o[2] = c[1];
}

static void xyy_to_xyz(const float c[3], float o[3])
{
	double x = c[0], y = c[1], Y = c[2];
	if (y == 0.0) {
		o[0] = o[1] = o[2] = 0.0f;
		return;
	}
	o[0] = sl_to_float(x * Y / y);
	o[1] = c[2];
	o[2] = sl_to_float((1.0 - x - y) * Y / y);
}

bool sl_color_from_rgb(const char *space, const float rgb[3], float out[3])
{
	float in[3] = { sl_finite(rgb[0]), sl_finite(rgb[1]), sl_finite(rgb[2]) }, xyz[3];
	switch (color_space(space)) {
	case CS_RGB: memcpy(out, in, sizeof(in)); return true;
	case CS_HSV: rgb_to_hsv(in, out); return true;
	case CS_HSL: rgb_to_hsl(in, out); return true;
	case CS_XYZ: mat3_apply(rgb_to_xyz, in, out); return true;
	case CS_XYY:
		mat3_apply(rgb_to_xyz, in, xyz);
		xyz_to_xyy(xyz, out);
		return true;
	case CS_YIQ: mat3_apply(rgb_to_yiq, in, out); return true;
	default: memcpy(out, in, sizeof(in)); return false;
	}
}

bool sl_color_to_rgb(const char *space, const float in[3], float rgb[3])
{
	float c[3] = { sl_finite(in[0]), sl_finite(in[1]), sl_finite(in[2]) }, xyz[3];
	switch (color_space(space)) {
	case CS_RGB: memcpy(rgb, c, sizeof(c)); return true;
	case CS_HSV: hsv_to_rgb(c, rgb); return true;
	case CS_HSL: hsl_to_rgb(c, rgb); return true;
	case CS_XYZ: mat3_apply_inverse(rgb_to_xyz, c, rgb); return true;
	case CS_XYY:
		xyy_to_xyz(c, xyz);
		mat3_apply_inverse(rgb_to_xyz, xyz, rgb);
		return true;
	case CS_YIQ: mat3_apply_inverse(rgb_to_yiq, c, rgb); return true;
	default: memcpy(rgb, c, sizeof(c)); return false;
	}
}

/* ---- splines ---- */

/* Basis matrices: weights of the four window values are (t^3 t^2 t 1) * M. */
static const float basis_matrix[SL_SPLINE_NBASES][4][4] = {
	[SL_SPLINE_CATMULL_ROM] = {
		{ -0.5f, 1.5f, -1.5f, 0.5f },
		{ 1.0f, -2.5f, 2.0f, -0.5f },
		{ -0.5f, 0.0f, 0.5f, 0.0f },
		{ 0.0f, 1.0f, 0.0f, 0.0f },
	},
	[SL_SPLINE_BSPLINE] = {
		{ -1.0f / 6, 3.0f / 6, -3.0f / 6, 1.0f / 6 },
		{ 3.0f / 6, -6.0f / 6, 3.0f / 6, 0.0f },
		{ -3.0f / 6, 0.0f, 3.0f / 6, 0.0f },
		{ 1.0f / 6, 4.0f / 6, 1.0f / 6, 0.0f },
	},
	[SL_SPLINE_BEZIER] = {
		{ -1.0f, 3.0f, -3.0f, 1.0f },
		{ 3.0f, -6.0f, 3.0f, 0.0f },
		{ -3.0f, 3.0f, 0.0f, 0.0f },
		{ 1.0f, 0.0f, 0.0f, 0.0f },
	},
	[SL_SPLINE_HERMITE] = {
		{ 2.0f, 1.0f, -2.0f, 1.0f },
		{ -3.0f, -2.0f, 3.0f, -1.0f },
		{ 0.0f, 1.0f, 0.0f, 0.0f },
		{ 1.0f, 0.0f, 0.0f, 0.0f },
	},
	[SL_SPLINE_LINEAR] = {
		{ 0.0f, 0.0f, 0.0f, 0.0f },
		{ 0.0f, 0.0f, 0.0f, 0.0f },
		{ 0.0f, -1.0f, 1.0f, 0.0f },
		{ 0.0f, 1.0f, 0.0f, 0.0f },
	},
};

static int basis_step(int basis)
{
	switch (basis) {
	case SL_SPLINE_BEZIER: return 3;
	case SL_SPLINE_HERMITE: return 2;
	default: return 1;
	}
}

int sl_spline_basis(const char *name)
{
	static const struct { const char *name; int basis; } names[] = {
		{ "catmull-rom", SL_SPLINE_CATMULL_ROM },
		{ "catrom", SL_SPLINE_CATMULL_ROM },
		{ "bspline", SL_SPLINE_BSPLINE },
		{ "b-spline", SL_SPLINE_BSPLINE },
		{ "bezier", SL_SPLINE_BEZIER },
		{ "hermite", SL_SPLINE_HERMITE },
		{ "linear", SL_SPLINE_LINEAR },
		{ "constant", SL_SPLINE_CONSTANT },
	};
	if (!name)
		return -1;
	int solve = 0;
	if (strncmp(name, "solve", 5) == 0) {
		name += 5;
		solve = SL_SPLINE_SOLVE;
	}
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (strcmp(name, names[i].name) == 0)
			return names[i].basis + solve;
	return -1;
}

int sl_spline_segments(int basis, int nvals)
{
	basis &= ~SL_SPLINE_SOLVE;
	if (nvals < 4)
		return 1;
	return (nvals - 4) / basis_step(basis) + 1;
}

/* One evaluation of a non-solve basis. */
static void spline_forward(int basis, float t, const float *vals, int nvals, int ncomp,
			   float *out)
{
	int nseg = sl_spline_segments(basis, nvals);
	t = sl_clampf(t != t ? 0.0f : t, 0.0f, 1.0f);
	float x = t * (float)nseg;
	int seg = (int)floorf(x);
	if (seg >= nseg)
		seg = nseg - 1;
	if (seg < 0)
		seg = 0;
	float u = x - (float)seg;
	int first = seg * basis_step(basis);

	float w[4];
	if (basis == SL_SPLINE_CONSTANT) {
		w[0] = w[1] = w[2] = w[3] = 0.0f;
		w[u < 1.0f ? 1 : 2] = 1.0f;
	} else {
		float pw[4] = { u * u * u, u * u, u, 1.0f };
		const float (*m)[4] = basis_matrix[basis];
		for (int j = 0; j < 4; j++)
			w[j] = pw[0] * m[0][j] + pw[1] * m[1][j] + pw[2] * m[2][j] + pw[3] * m[3][j];
	}
	for (int c = 0; c < ncomp; c++) {
		double s = 0.0;
		for (int j = 0; j < 4; j++) {
			int k = first + j;
			/* Short lists are padded with their last value. */
			if (k >= nvals)
				k = nvals - 1;
			s += (double)w[j] * vals[k * ncomp + c];
		}
		out[c] = sl_to_float(s);
	}
}

void sl_spline_eval(int basis, float t, const float *vals, int nvals, int ncomp, float *out)
{
	if (nvals <= 0 || ncomp <= 0) {
		for (int c = 0; c < ncomp; c++)
			out[c] = 0.0f;
		return;
	}
	int solve = basis >= 0 && (basis & SL_SPLINE_SOLVE);
	basis &= ~SL_SPLINE_SOLVE;
	if (basis < 0 || basis >= SL_SPLINE_NBASES)
		basis = SL_SPLINE_CATMULL_ROM;
	if (!solve || ncomp != 1) {
		spline_forward(basis, t, vals, nvals, ncomp, out);
		return;
	}
	/* Find the parameter where the (increasing or decreasing) spline equals t. */
	float f0, f1, fm;
	spline_forward(basis, 0.0f, vals, nvals, 1, &f0);
	spline_forward(basis, 1.0f, vals, nvals, 1, &f1);
	bool up = f1 >= f0;
	float lo = 0.0f, hi = 1.0f;
	for (int it = 0; it < 32; it++) {
		float mid = 0.5f * (lo + hi);
		spline_forward(basis, mid, vals, nvals, 1, &fm);
		if ((fm < t) == up)
			lo = mid;
		else
			hi = mid;
	}
	out[0] = 0.5f * (lo + hi);
}

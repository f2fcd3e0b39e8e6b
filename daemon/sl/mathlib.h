/*
 * Scalar, triple and matrix arithmetic behind RSL's built-in functions.
 *
 * Conventions. Triples are float[3]. Matrices are float[16], row-major, in
 * RenderMan's row-vector convention: a point transforms as p' = p * M, the
 * translation sits in elements 12, 13, 14, and A * B applies A first.
 *
 * No function here returns NaN or Inf for finite arguments: domain errors
 * give the nearest meaningful value, as documented per function, and results
 * beyond the float range are clamped to +-FLT_MAX.
 */
#ifndef SL_MATHLIB_H
#define SL_MATHLIB_H

#include <stdbool.h>

/* ---- scalars ---- */

/** NaN -> 0, +-Inf -> +-FLT_MAX, anything else unchanged. */
float sl_finite(float x);
/** A double brought into the float range: NaN gives 0, overflow the largest float. */
float sl_to_float(double x);

/** x^y. pow(0,0) = 1; 0^negative = 0 (like division by zero); a negative base
 *  with a non-integer exponent gives 0; overflow gives +-FLT_MAX. */
float sl_pow(float x, float y);
/** Square root; negative arguments give 0. */
float sl_sqrt(float x);
/** 1/sqrt(x); x <= 0 gives 0. */
float sl_inversesqrt(float x);
/**
 * Natural logarithm. Arguments below FLT_MIN (the smallest normal float),
 * including 0 and negatives, are taken as FLT_MIN, so the result is at least
 * log(FLT_MIN) ~ -87.34: finite, and safe to use in further arithmetic.
 */
float sl_log(float x);
/** Logarithm to @base (log(x)/log(base)); a base <= 0 or == 1 gives 0. */
float sl_logb(float x, float base);
/** e^x, clamped to FLT_MAX. */
float sl_exp(float x);
/** acos/asin with the argument clamped to [-1,1] (acos(1.0000001) = 0). */
float sl_acos(float x);
float sl_asin(float x);
/** atan2(y, x); atan(0, 0) = 0. */
float sl_atan2(float y, float x);
/** a - b * floor(a/b): the result has the sign of b; mod(a, 0) = 0. */
float sl_mod(float a, float b);
/** Round half away from zero. */
float sl_round(float x);
/** -1, 0 or 1. */
float sl_sign(float x);
/** 0 below @e0, 1 at or above @e1, Hermite blend between. Equal edges give a
 *  step at the edge: 0 for x < e0, 1 otherwise. */
float sl_smoothstep(float e0, float e1, float x);
/**
 * step(edge, s) filtered with a box over [s0, s1] (in either order): the
 * fraction of the interval at or above @edge. A zero-width interval gives
 * the plain step at s0.
 */
float sl_filterstep_box(float edge, float s0, float s1);
/** @x limited to [lo, hi]. */
float sl_clampf(float x, float lo, float hi);

/* ---- triples ---- */

/** a . b */
float sl_v3_dot(const float a[3], const float b[3]);
/** r = a x b (right-handed); @r may alias @a or @b. */
void sl_v3_cross(float r[3], const float a[3], const float b[3]);
/** |a|, computed in double so that large components do not overflow. */
float sl_v3_length(const float a[3]);
/** Unit vector along @a; a zero (or denormal-length) vector gives the zero vector. */
void sl_v3_normalize(float r[3], const float a[3]);
/** Distance from @q to the segment from @p0 to @p1 (RSL ptlined(P0, P1, Q)). */
float sl_ptlined(const float p0[3], const float p1[3], const float q[3]);
/** I - 2 (I.N) N (N as given, not normalized). */
void sl_reflect(float r[3], const float I[3], const float N[3]);
/**
 * The refracted direction for incident @I, normal @N and relative index @eta
 * (index of the side I comes from over the side it enters), by Snell's law:
 * k = 1 - eta^2 (1 - (I.N)^2); k < 0 (total internal reflection) gives the
 * zero vector, else eta I - (eta (I.N) + sqrt(k)) N. I and N are used as
 * given; with unit vectors the result is a unit vector.
 */
void sl_refract(float r[3], const float I[3], const float N[3], float eta);
/**
 * Fresnel reflection and transmission for a dielectric, unpolarized light.
 * With I and N normalized, c = |I.N| (N is flipped to face I) and
 * g^2 = 1/eta^2 + c^2 - 1, the reflectance is
 *   Kr = 1/2 ((g-c)/(g+c))^2 (1 + ((c (g+c) - 1) / (c (g-c) + 1))^2),
 * Kt = 1 - Kr; g^2 < 0 is total internal reflection (Kr = 1, Kt = 0).
 * At normal incidence Kr = ((eta-1)/(eta+1))^2. @R and @T (may be NULL)
 * get the unit reflected and refracted directions (T is zero on total
 * internal reflection). A zero I or N gives Kr = 0, Kt = 1, R = T = I.
 */
void sl_fresnel(const float I[3], const float N[3], float eta, float *Kr, float *Kt,
		float R[3], float T[3]);
/** @N flipped, if need be, to face against @I: -N when I.Nref > 0, else N. */
void sl_faceforward(float r[3], const float N[3], const float I[3], const float Nref[3]);
/** @q rotated by @angle radians about the axis through @p0 and @p1
 *  (right-handed about p1 - p0). A degenerate axis leaves q unchanged. */
void sl_rotate_point(float r[3], const float q[3], float angle, const float p0[3],
		     const float p1[3]);
/**
 * The highlight of specular() and specularbrdf(), chosen per scene with
 * Option "shading" "string specularmodel" (docs/rsl.md). Both are
 * pow(max(0, N . H), e) with H = normalize(L + V) and no normalization
 * factor; they differ in the exponent e.
 */
enum sl_specular_model {
	SL_SPECULAR_PRMAN,      /* e = 8 / roughness: PRMan's, as BMRT and Aqsis draw it (default) */
	SL_SPECULAR_RISPEC,     /* e = 1 / roughness: the RenderMan Interface Specification's text */
};
/** "prman" or "rispec". */
const char *sl_specular_model_name(enum sl_specular_model m);
/** The model named @name ("prman", "rispec"); false for another name or NULL. */
bool sl_specular_model_parse(const char *name, enum sl_specular_model *m);
/** specularbrdf() under model @m; roughness <= 0 is treated as 1e-6. */
float sl_specularbrdf(const float L[3], const float N[3], const float V[3], float roughness,
		      enum sl_specular_model m);

/* ---- 4x4 matrices ---- */

/** m = the identity. */
void sl_m44_identity(float m[16]);
/** r = a * b. @r may alias @a or @b. */
void sl_m44_mul(float r[16], const float a[16], const float b[16]);
/** r = m^T. @r may alias @m. */
void sl_m44_transpose(float r[16], const float m[16]);
/** Determinant (cofactor expansion in double). */
float sl_m44_det(const float m[16]);
/** r = inverse of m; false (and r = identity) when m is singular. @r may alias @m. */
bool sl_m44_inverse(float r[16], const float m[16]);
/** Translation, rotation (angle radians about @axis, right-handed; a zero axis
 *  gives the identity) and scaling matrices. */
void sl_m44_translation(float m[16], const float t[3]);
void sl_m44_rotation(float m[16], float angle, const float axis[3]);
void sl_m44_scaling(float m[16], const float s[3]);
/**
 * RSL's translate(m, t), rotate(m, angle, axis) and scale(m, s): the simple
 * transformation concatenated onto @m the way RiTranslate, RiRotate and
 * RiScale concatenate onto the current transformation, i.e. applied to
 * points before m: r = X * m. @r may alias @m.
 */
void sl_m44_translate(float r[16], const float m[16], const float t[3]);
void sl_m44_rotate(float r[16], const float m[16], float angle, const float axis[3]);
void sl_m44_scale(float r[16], const float m[16], const float s[3]);

/** p * M with the homogeneous divide (skipped when w is 0). @r may alias @p. */
void sl_xform_point(float r[3], const float m[16], const float p[3]);
/** v * M, upper 3x3 only. */
void sl_xform_vector(float r[3], const float m[16], const float v[3]);
/** n * inverse(M)^T (upper 3x3); a singular M uses its cofactor matrix instead. */
void sl_xform_normal(float r[3], const float m[16], const float n[3]);

/* ---- colors ---- */

/**
 * Convert between RGB and the color space @space: "rgb", "hsv", "hsl",
 * "xyz"/"XYZ" (CIE 1931 with Rec.709/sRGB primaries, D65 white, linear RGB),
 * "xyY", "YIQ" (NTSC). Hue is in [0,1). Returns false (and copies the color
 * unchanged) for an unknown space.
 */
bool sl_color_from_rgb(const char *space, const float rgb[3], float out[3]);
bool sl_color_to_rgb(const char *space, const float in[3], float rgb[3]);
/** Is @space one of the names above? */
bool sl_color_space_known(const char *space);

/* ---- splines ---- */

enum sl_spline_basis {
	SL_SPLINE_CATMULL_ROM,
	SL_SPLINE_BSPLINE,
	SL_SPLINE_BEZIER,
	SL_SPLINE_HERMITE,
	SL_SPLINE_LINEAR,
	SL_SPLINE_CONSTANT,
	SL_SPLINE_NBASES,
	/* Added to a basis: the inverse ("solve" bases, floats only). */
	SL_SPLINE_SOLVE = 16,
};

/**
 * The basis for a spline() basis name: "catmull-rom" (or "catrom"),
 * "bspline" (or "b-spline"), "bezier", "hermite", "linear", "constant", each
 * optionally prefixed by "solve" ("solvecatmull-rom", "solvelinear", ...),
 * which gives basis + SL_SPLINE_SOLVE. -1 for an unknown name.
 */
int sl_spline_basis(const char *name);

/** Number of curve segments @nvals control values make for @basis (>= 1). */
int sl_spline_segments(int basis, int nvals);

/**
 * Evaluate RSL's spline(basis, t, v1 ... vn): @vals holds @nvals values of
 * @ncomp floats each (value k, component c at vals[k * ncomp + c]); the
 * result goes to @out (ncomp floats). t is clamped to [0,1] and maps
 * uniformly onto the segments. Windows of four values step by 1 (catmull-rom,
 * b-spline, linear, constant: nvals = segments + 3), 3 (bezier: 3 segments + 1)
 * or 2 (hermite: value, tangent pairs: 2 segments + 2). Catmull-rom, linear
 * and constant pass through v2 at t = 0 and v(n-1) at t = 1, v1 and vn only
 * shaping the ends; bezier passes through v1 and vn, hermite through v1 and
 * v(n-1); b-spline approximates. Surplus values past the last full window
 * are ignored. Fewer than four values
 * are padded by repeating the last one. A "solve" basis (floats only)
 * returns the parameter at which the spline reaches t, by bisection,
 * assuming the spline increases over [0,1].
 */
void sl_spline_eval(int basis, float t, const float *vals, int nvals, int ncomp, float *out);

#endif

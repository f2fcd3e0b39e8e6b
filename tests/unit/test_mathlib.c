/* Tests of the scalar, triple, matrix, color and spline numerics behind RSL built-ins. */
#include "mathlib.h"
#include "test.h"

#include <float.h>

#define PI_F 3.14159265358979f

static void check_v3(const char *what, const float got[3], float x, float y, float z, double tol)
{
	(void)what;
	CHECK_NEAR(got[0], x, tol);
	CHECK_NEAR(got[1], y, tol);
	CHECK_NEAR(got[2], z, tol);
}

static void test_scalars(void)
{
	CHECK(sl_pow(0.0f, 0.0f) == 1.0f);
	CHECK(sl_pow(0.0f, -2.0f) == 0.0f);
	CHECK(sl_pow(-2.0f, 0.5f) == 0.0f);
	CHECK_NEAR(sl_pow(-2.0f, 3.0f), -8.0, 1e-6);
	CHECK_NEAR(sl_pow(2.0f, 0.5f), 1.41421356, 1e-6);
	CHECK(sl_pow(10.0f, 100.0f) == FLT_MAX);
	CHECK(sl_acos(1.0000001f) == 0.0f);
	CHECK_NEAR(sl_acos(-1.5f), PI_F, 1e-6);
	CHECK_NEAR(sl_asin(2.0f), PI_F / 2, 1e-6);
	CHECK(sl_sqrt(-4.0f) == 0.0f);
	CHECK_NEAR(sl_sqrt(9.0f), 3.0, 1e-7);
	CHECK(sl_inversesqrt(0.0f) == 0.0f);
	CHECK_NEAR(sl_inversesqrt(4.0f), 0.5, 1e-7);
	/* log of 0 or a negative is log(FLT_MIN): finite, about -87.34. */
	CHECK_NEAR(sl_log(0.0f), -87.336544, 1e-3);
	CHECK(sl_log(-1.0f) == sl_log(0.0f));
	CHECK_NEAR(sl_log(2.718281828f), 1.0, 1e-6);
	CHECK_NEAR(sl_logb(8.0f, 2.0f), 3.0, 1e-6);
	CHECK(sl_logb(8.0f, 1.0f) == 0.0f && sl_logb(8.0f, -2.0f) == 0.0f);
	CHECK(sl_exp(1000.0f) == FLT_MAX);
	CHECK_NEAR(sl_exp(1.0f), 2.718281828, 1e-6);
	CHECK(sl_atan2(0.0f, 0.0f) == 0.0f);
	CHECK_NEAR(sl_atan2(1.0f, -1.0f), 3 * PI_F / 4, 1e-6);
	/* mod has the sign of the divisor. */
	CHECK_NEAR(sl_mod(-1.0f, 3.0f), 2.0, 1e-6);
	CHECK_NEAR(sl_mod(1.0f, -3.0f), -2.0, 1e-6);
	CHECK_NEAR(sl_mod(-7.5f, 2.0f), 0.5, 1e-6);
	CHECK_NEAR(sl_mod(7.5f, 2.0f), 1.5, 1e-6);
	CHECK(sl_mod(5.0f, 0.0f) == 0.0f);
	float m = sl_mod(-1e-9f, 1.0f);
	CHECK(m >= 0.0f && m < 1.0f);
	CHECK(sl_round(2.5f) == 3.0f && sl_round(-2.5f) == -3.0f && sl_round(1.49f) == 1.0f);
	CHECK(sl_sign(-3.0f) == -1.0f && sl_sign(0.0f) == 0.0f && sl_sign(0.1f) == 1.0f);
	CHECK(sl_finite(NAN) == 0.0f && sl_finite(INFINITY) == FLT_MAX &&
	      sl_finite(-INFINITY) == -FLT_MAX && sl_finite(1.5f) == 1.5f);
}

static void test_steps(void)
{
	/* Equal edges: a step at the edge, no division by zero. */
	CHECK(sl_smoothstep(0.5f, 0.5f, 0.4f) == 0.0f);
	CHECK(sl_smoothstep(0.5f, 0.5f, 0.5f) == 1.0f);
	CHECK(sl_smoothstep(0.5f, 0.5f, 0.6f) == 1.0f);
	CHECK_NEAR(sl_smoothstep(0.0f, 2.0f, 1.0f), 0.5, 1e-7);
	CHECK_NEAR(sl_smoothstep(0.0f, 1.0f, 0.25f), 0.15625, 1e-7);
	CHECK(sl_smoothstep(0.0f, 1.0f, -1.0f) == 0.0f && sl_smoothstep(0.0f, 1.0f, 2.0f) == 1.0f);
	/* Box-filtered step: the fraction of [s0, s1] at or above the edge. */
	CHECK_NEAR(sl_filterstep_box(0.5f, 0.0f, 1.0f), 0.5, 1e-7);
	CHECK_NEAR(sl_filterstep_box(0.25f, 0.0f, 1.0f), 0.75, 1e-7);
	CHECK_NEAR(sl_filterstep_box(0.25f, 1.0f, 0.0f), 0.75, 1e-7);
	CHECK(sl_filterstep_box(2.0f, 0.0f, 1.0f) == 0.0f);
	CHECK(sl_filterstep_box(-2.0f, 0.0f, 1.0f) == 1.0f);
	CHECK(sl_filterstep_box(0.5f, 0.7f, 0.7f) == 1.0f);
	CHECK(sl_filterstep_box(0.5f, 0.3f, 0.3f) == 0.0f);
}

static void test_vectors(void)
{
	float z[3] = { 0, 0, 0 }, r[3];
	sl_v3_normalize(r, z);
	check_v3("normalize 0", r, 0, 0, 0, 0);
	float tiny[3] = { 1e-30f, 0, 0 };
	sl_v3_normalize(r, tiny);
	check_v3("normalize tiny", r, 1, 0, 0, 1e-6);
	float big[3] = { 3e30f, 4e30f, 0 };
	CHECK_NEAR(sl_v3_length(big), 5e30, 1e24);
	sl_v3_normalize(r, big);
	check_v3("normalize big", r, 0.6f, 0.8f, 0, 1e-6);

	float a[3] = { 1, 0, 0 }, b[3] = { 0, 1, 0 };
	sl_v3_cross(r, a, b);
	check_v3("cross", r, 0, 0, 1, 0);
	CHECK(sl_v3_dot(a, b) == 0.0f);

	/* ptlined: perpendicular distance inside the segment, else to an end. */
	float p0[3] = { 0, 0, 0 }, p1[3] = { 2, 0, 0 };
	float q1[3] = { 1, 3, 0 }, q2[3] = { -3, 4, 0 }, q3[3] = { 5, 0, 4 };
	CHECK_NEAR(sl_ptlined(p0, p1, q1), 3.0, 1e-6);
	CHECK_NEAR(sl_ptlined(p0, p1, q2), 5.0, 1e-6);
	CHECK_NEAR(sl_ptlined(p0, p1, q3), 5.0, 1e-6);
	CHECK_NEAR(sl_ptlined(p0, p0, q1), sqrt(10.0), 1e-6);

	/* reflect */
	float I[3] = { 1, -1, 0 }, N[3] = { 0, 1, 0 };
	sl_reflect(r, I, N);
	check_v3("reflect", r, 1, 1, 0, 1e-7);

	/* faceforward: N facing against I. */
	float Iin[3] = { 0, 0, -1 }, Nup[3] = { 0, 0, 1 }, Ndn[3] = { 0, 0, -1 };
	sl_faceforward(r, Ndn, Iin, Ndn);
	check_v3("faceforward flip", r, 0, 0, 1, 0);
	sl_faceforward(r, Nup, Iin, Nup);
	check_v3("faceforward keep", r, 0, 0, 1, 0);

	/* rotate a point 90 degrees about the z axis through (1,0,0). */
	float q[3] = { 2, 0, 5 }, ax0[3] = { 1, 0, 0 }, ax1[3] = { 1, 0, 1 };
	sl_rotate_point(r, q, PI_F / 2, ax0, ax1);
	check_v3("rotate point", r, 1, 1, 5, 1e-6);
	sl_rotate_point(r, q, PI_F / 2, ax0, ax0);
	check_v3("rotate degenerate", r, 2, 0, 5, 0);

	/*
	 * specularbrdf under both models: max(0, N . H)^e, H = normalize(L + V),
	 * e = 1 / roughness (RiSpec) or 8 / roughness (PRMan's). N along the
	 * half vector gives 1 under both.
	 */
	const enum sl_specular_model RS = SL_SPECULAR_RISPEC, PR = SL_SPECULAR_PRMAN;
	float L[3] = { 0, 0, 1 }, V[3] = { 0, 0, 1 };
	CHECK_NEAR(sl_specularbrdf(L, Nup, V, 0.1f, RS), 1.0, 1e-6);
	CHECK_NEAR(sl_specularbrdf(L, Nup, V, 0.1f, PR), 1.0, 1e-6);
	float L2[3] = { 1, 0, 1 };
	sl_v3_normalize(L2, L2);
	/* H at 22.5 degrees from N: cos^10 (RiSpec), cos^80 (PRMan) at roughness 0.1. */
	CHECK_NEAR(sl_specularbrdf(L2, Nup, V, 0.1f, RS), pow(cos(PI_F / 8), 10), 1e-5);
	CHECK_NEAR(sl_specularbrdf(L2, Nup, V, 0.1f, PR), pow(cos(PI_F / 8), 80), 1e-6);
	/* PRMan's highlight at roughness 0.8 is the RiSpec's at 0.1. */
	CHECK_NEAR(sl_specularbrdf(L2, Nup, V, 0.8f, PR), pow(cos(PI_F / 8), 10), 1e-5);
	/*
	 * The highlight's half width: the brdf falls to 1/2 where H is
	 * acos(2^(-roughness / 8)) from N under PRMan's model (7.53 degrees at
	 * roughness 0.1), acos(2^(-roughness)) under the RiSpec's (21.09
	 * degrees). L at twice that angle from V = N.
	 */
	static const double hw_exp[2] = { 8, 1 };
	for (int m = 0; m < 2; m++) {
		double half = acos(pow(2, -0.1 / hw_exp[m]));
		float Lh[3] = { (float)sin(2 * half), 0, (float)cos(2 * half) };
		CHECK_NEAR(sl_specularbrdf(Lh, Nup, V, 0.1f, m ? RS : PR), 0.5, 1e-4);
	}
	float Lback[3] = { 0, 0, -1 }, Vside[3] = { 1, 0, 0 };
	CHECK(sl_specularbrdf(Lback, Nup, Vside, 0.1f, PR) == 0.0f);
	CHECK(sl_specularbrdf(Lback, Nup, Vside, 0.1f, RS) == 0.0f);
	CHECK(sl_specularbrdf(L, Nup, V, 0.0f, PR) == 1.0f);
	CHECK(sl_specularbrdf(L, Nup, V, 0.0f, RS) == 1.0f);

	/* The option's names. */
	enum sl_specular_model m;
	CHECK(sl_specular_model_parse("rispec", &m) && m == RS);
	CHECK(sl_specular_model_parse("prman", &m) && m == PR);
	CHECK(!sl_specular_model_parse("blinn", &m) && !sl_specular_model_parse(NULL, &m));
	CHECK(!strcmp(sl_specular_model_name(RS), "rispec"));
	CHECK(!strcmp(sl_specular_model_name(PR), "prman"));
}

static void test_refract_fresnel(void)
{
	float r[3], kr, kt, R[3], T[3];
	/* Normal incidence into glass: straight through, Kr = ((eta-1)/(eta+1))^2. */
	float I[3] = { 0, 0, -1 }, N[3] = { 0, 0, 1 };
	float eta = 1.0f / 1.5f;
	sl_refract(r, I, N, eta);
	check_v3("refract normal", r, 0, 0, -1, 1e-6);
	sl_fresnel(I, N, eta, &kr, &kt, R, T);
	double e = (eta - 1.0) / (eta + 1.0);
	CHECK_NEAR(kr, e * e, 1e-6);
	CHECK_NEAR(kr, 0.04, 1e-6);
	CHECK_NEAR(kr + kt, 1.0, 1e-7);
	check_v3("fresnel R", R, 0, 0, 1, 1e-6);
	check_v3("fresnel T", T, 0, 0, -1, 1e-6);

	/* 45 degrees into glass: Snell gives sin(t) = sin(45)/1.5; Kr from the
	 * s and p reflectances (computed here independently). */
	float I45[3] = { 0.70710678f, 0, -0.70710678f };
	sl_refract(r, I45, N, eta);
	double st = sin(PI_F / 4) / 1.5, ct = sqrt(1 - st * st), ci = cos(PI_F / 4);
	check_v3("refract 45", r, (float)st, 0, -(float)ct, 1e-6);
	sl_fresnel(I45, N, eta, &kr, &kt, R, T);
	double rs = (ci - 1.5 * ct) / (ci + 1.5 * ct), rp = (ct - 1.5 * ci) / (ct + 1.5 * ci);
	CHECK_NEAR(kr, 0.5 * (rs * rs + rp * rp), 1e-5);
	CHECK_NEAR(kr + kt, 1.0, 1e-7);
	check_v3("fresnel R45", R, 0.70710678f, 0, 0.70710678f, 1e-6);
	check_v3("fresnel T45", T, (float)st, 0, -(float)ct, 1e-6);

	/* Unnormalized inputs give the same coefficients. */
	float I45b[3] = { 3, 0, -3 }, Nb[3] = { 0, 0, 7 };
	float kr2, kt2;
	sl_fresnel(I45b, Nb, eta, &kr2, &kt2, NULL, NULL);
	CHECK_NEAR(kr2, kr, 1e-6);

	/* Total internal reflection leaving glass at 60 degrees (critical ~41.8). */
	float I60[3] = { 0.8660254f, 0, -0.5f };
	sl_refract(r, I60, N, 1.5f);
	check_v3("refract TIR", r, 0, 0, 0, 0);
	sl_fresnel(I60, N, 1.5f, &kr, &kt, R, T);
	CHECK(kr == 1.0f && kt == 0.0f);
	check_v3("fresnel T TIR", T, 0, 0, 0, 0);

	/* Grazing incidence reflects everything; normal incidence from inside
	 * equals normal incidence from outside. */
	float Igraze[3] = { 1, 0, -1e-4f };
	sl_fresnel(Igraze, N, eta, &kr, &kt, NULL, NULL);
	CHECK(kr > 0.99f);
	sl_fresnel(I, N, 1.5f, &kr, &kt, NULL, NULL);
	CHECK_NEAR(kr, 0.04, 1e-6);

	/* N facing away from I is flipped. */
	float Nback[3] = { 0, 0, -1 };
	sl_fresnel(I45, Nback, eta, &kr2, &kt2, NULL, T);
	sl_fresnel(I45, N, eta, &kr, &kt, NULL, NULL);
	CHECK_NEAR(kr2, kr, 1e-7);
	check_v3("fresnel T flipped N", T, (float)st, 0, -(float)ct, 1e-6);

	/* Degenerate input never gives NaN. */
	float zero[3] = { 0, 0, 0 };
	sl_fresnel(zero, N, eta, &kr, &kt, R, T);
	CHECK(kr == 0.0f && kt == 1.0f);
	sl_fresnel(I, N, 0.0f, &kr, &kt, R, T);
	CHECK(kr == kr && kt == kt);
}

static void test_matrices(void)
{
	float m[16], inv[16], prod[16], id[16];
	sl_m44_identity(id);

	/* A known inverse: translate(1,2,3) * scale(2,4,8). */
	float t[3] = { 1, 2, 3 }, s[3] = { 2, 4, 8 };
	sl_m44_scaling(m, s);
	sl_m44_translate(m, m, t);    /* T * S: translate first, then scale */
	float p[3] = { 1, 1, 1 }, r[3];
	sl_xform_point(r, m, p);
	check_v3("T*S point", r, 4, 12, 32, 1e-6);
	CHECK(sl_m44_inverse(inv, m));
	sl_xform_point(r, inv, r);
	check_v3("inverse point", r, 1, 1, 1, 1e-6);
	CHECK_NEAR(inv[0], 0.5, 1e-7);
	CHECK_NEAR(inv[5], 0.25, 1e-7);
	CHECK_NEAR(inv[10], 0.125, 1e-7);
	CHECK_NEAR(inv[12], -1, 1e-7);
	CHECK_NEAR(inv[13], -2, 1e-7);
	CHECK_NEAR(inv[14], -3, 1e-7);
	sl_m44_mul(prod, m, inv);
	for (int i = 0; i < 16; i++)
		CHECK_NEAR(prod[i], id[i], 1e-6);
	CHECK_NEAR(sl_m44_det(m), 64.0, 1e-4);

	/* A general matrix: inverse times itself is the identity. */
	float g[16] = { 2, 1, 0, 0, 1, 3, 1, 0, 0, 1, 4, 1, 1, 2, 3, 1 };
	CHECK(sl_m44_inverse(inv, g));
	sl_m44_mul(prod, inv, g);
	for (int i = 0; i < 16; i++)
		CHECK_NEAR(prod[i], id[i], 1e-5);
	/* det(g) = 18 - 12 = 6 (cofactors of the last column); det(inverse) = 1/6. */
	CHECK_NEAR(sl_m44_det(g) * sl_m44_det(inv), 1.0, 1e-5);
	CHECK_NEAR(sl_m44_det(g), 6.0, 1e-5);

	/* A tiny but valid scale is invertible. */
	float small[3] = { 1e-5f, 1e-5f, 1e-5f };
	sl_m44_scaling(m, small);
	CHECK(sl_m44_inverse(inv, m));
	CHECK_NEAR(inv[0], 1e5, 1.0);

	/* Singular matrices are reported and give the identity. */
	float sing[16] = { 1, 2, 3, 4, 2, 4, 6, 8, 0, 0, 1, 0, 0, 0, 0, 1 };
	CHECK(!sl_m44_inverse(inv, sing));
	for (int i = 0; i < 16; i++)
		CHECK(inv[i] == id[i]);
	float zero[16] = { 0 };
	CHECK(!sl_m44_inverse(inv, zero));
	CHECK(sl_m44_det(sing) == 0.0f);

	/* Rotation of known vectors: 90 degrees about z takes x to y. */
	float zaxis[3] = { 0, 0, 1 }, xaxis[3] = { 1, 0, 0 }, yaxis[3] = { 0, 2, 0 };
	float ex[3] = { 1, 0, 0 }, ey[3] = { 0, 1, 0 }, ez[3] = { 0, 0, 1 };
	sl_m44_rotation(m, PI_F / 2, zaxis);
	sl_xform_vector(r, m, ex);
	check_v3("rotz x", r, 0, 1, 0, 1e-6);
	sl_m44_rotation(m, PI_F / 2, xaxis);
	sl_xform_vector(r, m, ey);
	check_v3("rotx y", r, 0, 0, 1, 1e-6);
	sl_m44_rotation(m, PI_F / 2, yaxis);   /* axis length does not matter */
	sl_xform_vector(r, m, ez);
	check_v3("roty z", r, 1, 0, 0, 1e-6);
	/* 120 degrees about (1,1,1) cycles the axes. */
	float diag[3] = { 1, 1, 1 };
	sl_m44_rotation(m, 2 * PI_F / 3, diag);
	sl_xform_vector(r, m, ex);
	check_v3("rot diag", r, 0, 1, 0, 1e-6);
	CHECK_NEAR(sl_m44_det(m), 1.0, 1e-6);
	float zero3[3] = { 0, 0, 0 };
	sl_m44_rotation(m, 1.0f, zero3);
	for (int i = 0; i < 16; i++)
		CHECK(m[i] == id[i]);

	/* rotate(m, ...) applies the rotation before m (like RiRotate). */
	float tr[3] = { 10, 0, 0 };
	sl_m44_translation(m, tr);
	sl_m44_rotate(m, m, PI_F / 2, zaxis);
	sl_xform_point(r, m, ex);
	check_v3("rotate then translate", r, 10, 1, 0, 1e-5);
	sl_m44_identity(m);
	sl_m44_scale(m, m, s);
	sl_xform_point(r, m, p);
	check_v3("scale", r, 2, 4, 8, 0);

	/* Points get the homogeneous divide; vectors ignore translation. */
	float persp[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0 };
	float pz[3] = { 2, 4, 2 };
	sl_xform_point(r, persp, pz);
	check_v3("perspective", r, 1, 2, 1, 1e-7);
	sl_m44_translation(m, t);
	sl_xform_vector(r, m, ex);
	check_v3("vector ignores translation", r, 1, 0, 0, 0);

	/* Normals transform by the inverse transpose: a plane's normal stays
	 * perpendicular to the transformed plane. */
	float sc[3] = { 1, 4, 1 };
	sl_m44_scaling(m, sc);
	float n[3] = { 1, 1, 0 };     /* normal of the plane x + y = 0 */
	float tan_[3] = { 1, -1, 0 }; /* a tangent of that plane */
	float nt[3], tt[3];
	sl_xform_normal(nt, m, n);
	sl_xform_vector(tt, m, tan_);
	CHECK_NEAR(sl_v3_dot(nt, tt), 0.0, 1e-6);
	check_v3("normal scale", nt, 1, 0.25f, 0, 1e-7);
	/* A singular matrix still gives a finite normal. */
	float flat[3] = { 1, 1, 0 };
	sl_m44_scaling(m, flat);
	sl_xform_normal(nt, m, ez);
	CHECK(nt[0] == nt[0] && fabsf(nt[2]) <= FLT_MAX);
}

static void check_round_trip(const char *space, const float rgb[3], double tol)
{
	float c[3], back[3];
	CHECK(sl_color_from_rgb(space, rgb, c));
	CHECK(sl_color_to_rgb(space, c, back));
	CHECK_NEAR(back[0], rgb[0], tol);
	CHECK_NEAR(back[1], rgb[1], tol);
	CHECK_NEAR(back[2], rgb[2], tol);
}

static void test_colors(void)
{
	float red[3] = { 1, 0, 0 }, c[3];
	CHECK(sl_color_from_rgb("hsv", red, c));
	check_v3("red hsv", c, 0, 1, 1, 1e-7);
	CHECK(sl_color_from_rgb("hsl", red, c));
	check_v3("red hsl", c, 0, 1, 0.5f, 1e-7);
	float green[3] = { 0, 1, 0 }, blue[3] = { 0, 0, 1 };
	sl_color_from_rgb("hsv", green, c);
	CHECK_NEAR(c[0], 1.0 / 3, 1e-6);
	sl_color_from_rgb("hsv", blue, c);
	CHECK_NEAR(c[0], 2.0 / 3, 1e-6);
	float magenta[3] = { 1, 0, 1 };
	sl_color_from_rgb("hsv", magenta, c);
	CHECK_NEAR(c[0], 5.0 / 6, 1e-6);
	float grey[3] = { 0.5f, 0.5f, 0.5f };
	sl_color_from_rgb("hsv", grey, c);
	check_v3("grey hsv", c, 0, 0, 0.5f, 1e-7);
	float hsv_cyan[3] = { 0.5f, 1, 1 };
	sl_color_to_rgb("hsv", hsv_cyan, c);
	check_v3("cyan", c, 0, 1, 1, 1e-6);

	/* White is D65: XYZ ~ (0.9505, 1, 1.089), xyY ~ (0.3127, 0.3290, 1). */
	float white[3] = { 1, 1, 1 };
	sl_color_from_rgb("XYZ", white, c);
	check_v3("white XYZ", c, 0.95047f, 1.0f, 1.08883f, 2e-4);
	sl_color_from_rgb("xyz", white, c);
	check_v3("white xyz", c, 0.95047f, 1.0f, 1.08883f, 2e-4);
	sl_color_from_rgb("xyY", white, c);
	check_v3("white xyY", c, 0.3127f, 0.3290f, 1.0f, 2e-4);
	sl_color_from_rgb("xyz", red, c);
	CHECK_NEAR(c[1], 0.2126729, 1e-6);
	float black[3] = { 0, 0, 0 };
	sl_color_from_rgb("xyY", black, c);
	check_v3("black xyY", c, 0.3127f, 0.3290f, 0, 1e-6);
	sl_color_to_rgb("xyY", c, c);
	check_v3("black back", c, 0, 0, 0, 1e-6);
	sl_color_from_rgb("YIQ", white, c);
	check_v3("white YIQ", c, 1, 0, 0, 1e-5);

	float samples[][3] = {
		{ 0.2f, 0.4f, 0.6f }, { 0.9f, 0.1f, 0.3f }, { 0.0f, 0.0f, 0.0f },
		{ 1, 1, 1 }, { 0.7f, 0.7f, 0.2f }, { 0.05f, 0.8f, 0.8f },
	};
	const char *spaces[] = { "rgb", "hsv", "hsl", "xyz", "XYZ", "xyY", "YIQ" };
	for (size_t s = 0; s < sizeof(spaces) / sizeof(spaces[0]); s++)
		for (size_t k = 0; k < sizeof(samples) / sizeof(samples[0]); k++)
			check_round_trip(spaces[s], samples[k], 2e-6);

	/* A hue just below 0 wraps to (almost) red, not to garbage. */
	float wrap[3] = { -1e-9f, 1, 1 };
	sl_color_to_rgb("hsv", wrap, c);
	check_v3("hue wrap", c, 1, 0, 0, 1e-6);
	float nan_c[3] = { NAN, INFINITY, 0.5f };
	sl_color_to_rgb("hsv", nan_c, c);
	CHECK(c[0] == c[0] && c[1] == c[1] && c[2] == c[2]);

	CHECK(!sl_color_from_rgb("cmyk", red, c));
	check_v3("unknown space copies", c, 1, 0, 0, 0);
	CHECK(!sl_color_space_known("lab") && sl_color_space_known("hsv"));
	CHECK(!sl_color_space_known(NULL));
}

static void test_splines(void)
{
	CHECK(sl_spline_basis("catmull-rom") == SL_SPLINE_CATMULL_ROM);
	CHECK(sl_spline_basis("bspline") == SL_SPLINE_BSPLINE);
	CHECK(sl_spline_basis("bezier") == SL_SPLINE_BEZIER);
	CHECK(sl_spline_basis("hermite") == SL_SPLINE_HERMITE);
	CHECK(sl_spline_basis("linear") == SL_SPLINE_LINEAR);
	CHECK(sl_spline_basis("constant") == SL_SPLINE_CONSTANT);
	CHECK(sl_spline_basis("solvelinear") == (SL_SPLINE_LINEAR | SL_SPLINE_SOLVE));
	CHECK(sl_spline_basis("cubic-ish") == -1);

	/* Catmull-rom through its control points: 6 values, 3 segments. */
	float v[6] = { 5, 0, 1, 4, 2, 9 }, out;
	CHECK(sl_spline_segments(SL_SPLINE_CATMULL_ROM, 6) == 3);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 0.0f, v, 6, 1, &out);
	CHECK_NEAR(out, 0, 1e-6);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 1.0f / 3, v, 6, 1, &out);
	CHECK_NEAR(out, 1, 1e-5);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 2.0f / 3, v, 6, 1, &out);
	CHECK_NEAR(out, 4, 1e-5);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 1.0f, v, 6, 1, &out);
	CHECK_NEAR(out, 2, 1e-6);
	/* Mid-segment: 0.5*(p0 ... ) = (-v0 + 9 v1 + 9 v2 - v3) / 16. */
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 0.5f, v, 6, 1, &out);
	CHECK_NEAR(out, (-0.0 + 9 * 1 + 9 * 4 - 2) / 16.0, 1e-5);
	/* Out of range t clamps. */
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, -3.0f, v, 6, 1, &out);
	CHECK_NEAR(out, 0, 1e-6);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 7.0f, v, 6, 1, &out);
	CHECK_NEAR(out, 2, 1e-6);

	/* Linear: the polyline through the interior values. */
	sl_spline_eval(SL_SPLINE_LINEAR, 1.0f / 6, v, 6, 1, &out);
	CHECK_NEAR(out, 0.5, 1e-6);
	sl_spline_eval(SL_SPLINE_LINEAR, 5.0f / 6, v, 6, 1, &out);
	CHECK_NEAR(out, 3.0, 1e-5);
	/* Constant: steps. */
	sl_spline_eval(SL_SPLINE_CONSTANT, 0.5f, v, 6, 1, &out);
	CHECK_NEAR(out, 1, 0);
	sl_spline_eval(SL_SPLINE_CONSTANT, 1.0f, v, 6, 1, &out);
	CHECK_NEAR(out, 2, 0);

	/* B-spline of constant values is that constant; of 0 0 6 0 0 peaks at 4. */
	float cst[5] = { 3, 3, 3, 3, 3 }, bump[5] = { 0, 0, 6, 0, 0 };
	sl_spline_eval(SL_SPLINE_BSPLINE, 0.37f, cst, 5, 1, &out);
	CHECK_NEAR(out, 3, 1e-5);
	sl_spline_eval(SL_SPLINE_BSPLINE, 0.5f, bump, 5, 1, &out);
	CHECK_NEAR(out, 4, 1e-5);

	/* Bezier: one segment 0 1 1 0 gives 0.75 at the middle; ends interpolate. */
	float bz[7] = { 0, 1, 1, 0, 2, 2, 6 };
	CHECK(sl_spline_segments(SL_SPLINE_BEZIER, 7) == 2);
	sl_spline_eval(SL_SPLINE_BEZIER, 0.25f, bz, 7, 1, &out);
	CHECK_NEAR(out, 0.75, 1e-6);
	sl_spline_eval(SL_SPLINE_BEZIER, 0.5f, bz, 7, 1, &out);
	CHECK_NEAR(out, 0, 1e-6);
	sl_spline_eval(SL_SPLINE_BEZIER, 1.0f, bz, 7, 1, &out);
	CHECK_NEAR(out, 6, 1e-6);

	/* Hermite: P0=0, T0=0, P1=1, T1=0 is smoothstep. */
	float he[4] = { 0, 0, 1, 0 };
	sl_spline_eval(SL_SPLINE_HERMITE, 0.25f, he, 4, 1, &out);
	CHECK_NEAR(out, sl_smoothstep(0, 1, 0.25f), 1e-6);

	/* Colors: each channel independently. */
	float cv[12] = { 0, 0, 0, 1, 2, 3, 2, 4, 6, 3, 6, 9 }, cout[3];
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 0.5f, cv, 4, 3, cout);
	check_v3("color spline", cout, 1.5f, 3, 4.5f, 1e-5);

	/* Solve: the parameter at which a linear ramp reaches the value. */
	float ramp[4] = { 0, 0, 10, 10 };
	sl_spline_eval(SL_SPLINE_LINEAR | SL_SPLINE_SOLVE, 2.5f, ramp, 4, 1, &out);
	CHECK_NEAR(out, 0.25, 1e-6);
	sl_spline_eval(sl_spline_basis("solvecatmull-rom"), 5.0f, ramp, 4, 1, &out);
	CHECK_NEAR(out, 0.5, 1e-6);

	/* Too few values are padded, never read past the end. */
	float two[2] = { 1, 3 };
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 0.5f, two, 2, 1, &out);
	CHECK(out == out && fabsf(out) < 10.0f);
	sl_spline_eval(SL_SPLINE_CATMULL_ROM, 0.5f, two, 0, 1, &out);
	CHECK(out == 0.0f);
}

int main(void)
{
	RUN(test_scalars);
	RUN(test_steps);
	RUN(test_vectors);
	RUN(test_refract_fresnel);
	RUN(test_matrices);
	RUN(test_colors);
	RUN(test_splines);
	return test_finish();
}

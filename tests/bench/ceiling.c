/*
 * The shading kernels' yardstick: see ceiling.h.
 */
#include "ceiling.h"
#include "clock.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TEXELS 6                 /* RGBA32F texels a sample */
#define FLOATS (TEXELS * 4)
#define CHECKS 256u
#define MAX_REL_ERR 1e-4

/*
 * Counted as exec.h counts (neg add sub mul div compare 1 a component; dot 5;
 * normalize 9; inversesqrt, pow, max 1; selects 0):
 *   once a sample:  normalize(Nf) 9, 1 / max(rough, 1e-6) 2, Cs * Kd 3    = 14
 *   a light:        L 3, dot 5, intensity * colour / d2 6, -inversesqrt 2,
 *                   * 3, dot 5, Ln + V 3, normalize 9, dot 5, compare 1,
 *                   pow 1, compare 1, Cl * c 3, Cl * sp 3,
 *                   Os * (CsKd * dif + sc * spe) 12, ci - base 3, acc + 3 = 68
 */
#define FLOPS_ONCE 14.0
#define FLOPS_LIGHT 68.0

/* The lights, and their unrolled passes. */
#define LIGHT_PASS(k)                                                                          \
	"\t{\n"                                                                                \
	"\t\tvec3 L = P - u_from[" #k "];\n"                                                   \
	"\t\tfloat d2 = dot(L, L);\n"                                                          \
	"\t\tvec3 Cl = u_intensity[" #k "] * u_color[" #k "] / d2;\n"                          \
	"\t\tvec3 Ln = L * -inversesqrt(d2);\n"                                                \
	"\t\tfloat c = dot(Ln, Nn);\n"                                                         \
	"\t\tvec3 H = normalize(Ln + V);\n"                                                    \
	"\t\tfloat d = dot(Nf, H);\n"                                                          \
	"\t\tfloat sp = d > 0.0 ? pow(d, ir) : 0.0;\n"                                         \
	"\t\tbool lit = c >= 0.0;\n"                                                           \
	"\t\tvec3 dif = lit ? Cl * c : vec3(0.0);\n"                                           \
	"\t\tvec3 spe = lit ? Cl * sp : vec3(0.0);\n"                                          \
	"\t\tvec3 ci = Os * (CsKd * dif + sc * spe);\n"                                        \
	"\t\tacc += dvec3(ci - base);\n"                                                       \
	"\t}\n"

static const char kernel_src[] =
	"#version 430 core\n"
	"layout(local_size_x = 64) in;\n"
	"layout(binding = 0) uniform samplerBuffer u_in;\n"
	"layout(binding = 1) uniform samplerBuffer u_base;\n"
	"layout(std430, binding = 2) buffer Cache { double cache[]; };\n"
	"uniform int u_count;\n"
	"uniform vec3 u_from[8];\n"
	"uniform float u_intensity[8];\n"
	"uniform vec3 u_color[8];\n"
	"void main() {\n"
	"\tuint idx = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	"\tif (idx >= uint(u_count)) return;\n"
	"\tint t = int(idx) * 6;\n"
	"\tvec4 t0 = texelFetch(u_in, t), t1 = texelFetch(u_in, t + 1);\n"
	"\tvec4 t2 = texelFetch(u_in, t + 2), t3 = texelFetch(u_in, t + 3);\n"
	"\tvec4 t4 = texelFetch(u_in, t + 4), t5 = texelFetch(u_in, t + 5);\n"
	"\tvec3 P = t0.xyz, Nf = t1.xyz, V = t3.xyz, sc = t4.xyz, Os = t5.xyz;\n"
	"\tvec3 Nn = normalize(Nf);\n"
	"\tfloat ir = 1.0 / max(t2.w, 1e-6);\n"
	"\tvec3 CsKd = t2.xyz * t1.w;\n"
	"\tint id = int(idx) * 3;\n"
	"\tvec3 base = vec3(texelFetch(u_base, id).x, texelFetch(u_base, id + 1).x,\n"
	"\t\t\t texelFetch(u_base, id + 2).x);\n"
	"\tdvec3 acc = dvec3(cache[id], cache[id + 1], cache[id + 2]);\n"
	LIGHT_PASS(0) LIGHT_PASS(1) LIGHT_PASS(2) LIGHT_PASS(3)
	LIGHT_PASS(4) LIGHT_PASS(5) LIGHT_PASS(6) LIGHT_PASS(7)
	"\tcache[id] = acc.x;\n"
	"\tcache[id + 1] = acc.y;\n"
	"\tcache[id + 2] = acc.z;\n"
	"}\n";

/* A uniform number in [lo, hi) from a 32-bit LCG. */
static float uniform(uint32_t *s, float lo, float hi)
{
	*s = *s * 1664525u + 1013904223u;
	return lo + (hi - lo) * (float)(*s >> 8) * (1.0f / 16777216.0f);
}

static void normalize3(float v[3])
{
	float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int c = 0; c < 3; c++)
		v[c] /= l;
}

/* A street-like sample: points over 20 x 20 units seen from (0, 1, -5). */
static void make_sample(uint32_t *s, float *r)
{
	memset(r, 0, FLOATS * sizeof(float));
	float *P = r, *Nf = r + 4, *Cs = r + 8, *V = r + 12, *sc = r + 16, *Os = r + 20;
	P[0] = uniform(s, -10.0f, 10.0f);
	P[1] = uniform(s, 0.0f, 2.0f);
	P[2] = uniform(s, 5.0f, 25.0f);
	r[3] = uniform(s, 0.0f, 1.0f);                        /* Ka */
	Nf[0] = uniform(s, -1.0f, 1.0f);
	Nf[1] = uniform(s, 0.2f, 1.0f);
	Nf[2] = uniform(s, -1.0f, 1.0f);
	normalize3(Nf);
	r[7] = uniform(s, 0.3f, 0.8f);                        /* Kd */
	for (int c = 0; c < 3; c++) {
		Cs[c] = uniform(s, 0.2f, 0.9f);
		sc[c] = uniform(s, 0.2f, 0.6f);               /* Ks * specularcolor */
		Os[c] = uniform(s, 0.5f, 1.0f);
	}
	r[11] = uniform(s, 0.05f, 0.5f);                      /* roughness */
	V[0] = -P[0];
	V[1] = 1.0f - P[1];
	V[2] = -5.0f - P[2];
	normalize3(V);
}

struct lights {
	float from[CEILING_LIGHTS * 3], intensity[CEILING_LIGHTS], color[CEILING_LIGHTS * 3];
};

/*
 * Sample @r's colour summed over the lights, in double; false when a light
 * is within rounding of grazing the sample (c near 0, where float and
 * double may take different sides of plastic's hemisphere test).
 */
static bool cpu_shade(const float *r, const struct lights *l, double out[3])
{
	const float *P = r, *Nf = r + 4, *Cs = r + 8, *V = r + 12, *sc = r + 16, *Os = r + 20;
	double nl = sqrt((double)Nf[0] * Nf[0] + (double)Nf[1] * Nf[1] + (double)Nf[2] * Nf[2]);
	double ir = 1.0 / fmax(r[11], 1e-6);
	out[0] = out[1] = out[2] = 0.0;
	for (int k = 0; k < CEILING_LIGHTS; k++) {
		double L[3], d2 = 0.0;
		for (int c = 0; c < 3; c++) {
			L[c] = (double)P[c] - l->from[3 * k + c];
			d2 += L[c] * L[c];
		}
		double inv = 1.0 / sqrt(d2), Ln[3], c = 0.0, H[3], hl = 0.0, d = 0.0;
		for (int i = 0; i < 3; i++) {
			Ln[i] = -L[i] * inv;
			c += Ln[i] * Nf[i] / nl;
			H[i] = Ln[i] + V[i];
			hl += H[i] * H[i];
		}
		if (fabs(c) < 1e-5)
			return false;
		for (int i = 0; i < 3; i++)
			d += Nf[i] * H[i] / sqrt(hl);
		double sp = d > 0.0 ? pow(d, ir) : 0.0;
		for (int i = 0; i < 3; i++) {
			double Cl = (double)l->intensity[k] * l->color[3 * k + i] / d2;
			double dif = c >= 0.0 ? Cl * c : 0.0, spe = c >= 0.0 ? Cl * sp : 0.0;
			out[i] += Os[i] * ((double)Cs[i] * r[7] * dif + sc[i] * spe);
		}
	}
	return true;
}

bool ceiling_run(struct gpu_ctx *ctx, uint32_t samples, uint32_t runs, struct ceiling *out)
{
	memset(out, 0, sizeof(*out));
	if (samples < CHECKS || runs < 1) {
		fprintf(stderr, "ceiling: needs at least %u samples and one run\n", CHECKS);
		return false;
	}
	struct lights l;
	for (int k = 0; k < CEILING_LIGHTS; k++) {
		l.from[3 * k] = -8.0f + 2.0f * (float)k;
		l.from[3 * k + 1] = 5.0f + 0.3f * (float)k;
		l.from[3 * k + 2] = 8.0f + 1.5f * (float)k;
		l.intensity[k] = 5.0f * (float)(k + 1);
		l.color[3 * k] = 1.0f;
		l.color[3 * k + 1] = 0.9f - 0.05f * (float)k;
		l.color[3 * k + 2] = 0.8f;
	}
	float *rec = malloc((size_t)samples * FLOATS * sizeof(float));
	float *zero = calloc((size_t)samples * 3, sizeof(float));
	double *cache = calloc((size_t)samples * 3, sizeof(double));
	struct gpu_program *p = gpu_program(ctx, kernel_src, stderr);
	struct gpu_buffer *in = NULL, *base = NULL, *acc = NULL;
	bool ok = rec && zero && cache && p;
	if (ok) {
		uint32_t s = 12345u;
		for (uint32_t i = 0; i < samples; i++)
			make_sample(&s, rec + (size_t)i * FLOATS);
		in = gpu_buffer_create(ctx, (size_t)samples * FLOATS * sizeof(float), rec);
		base = gpu_buffer_create(ctx, (size_t)samples * 3 * sizeof(float), zero);
		acc = gpu_buffer_create(ctx, (size_t)samples * 3 * sizeof(double), cache);
		ok = in && base && acc;
	}
	ok = ok && gpu_uniform_float(p, "u_from", l.from, 3 * CEILING_LIGHTS) &&
	     gpu_uniform_float(p, "u_intensity", l.intensity, CEILING_LIGHTS) &&
	     gpu_uniform_float(p, "u_color", l.color, 3 * CEILING_LIGHTS);
	const struct gpu_binding b[3] = {
		{ .unit = 0, .buffer = in, .rgba = true },
		{ .unit = 1, .buffer = base },
		{ .unit = 2, .ssbo = true, .buffer = acc },
	};
	/* The first run starts from a zero cache: its results are checked. */
	ok = ok && gpu_dispatch(ctx, p, b, 3, samples) &&
	     gpu_buffer_read(acc, 0, (size_t)samples * 3 * sizeof(double), cache);
	for (uint32_t j = 0; ok && j < CHECKS; j++) {
		uint32_t i = (uint32_t)(((uint64_t)j * samples) / CHECKS);
		double want[3];
		if (!cpu_shade(rec + (size_t)i * FLOATS, &l, want))
			continue;
		out->checked++;
		for (int c = 0; c < 3; c++) {
			double e = fabs(cache[(size_t)i * 3 + c] - want[c]) / fmax(fabs(want[c]), 1e-6);
			out->max_rel_err = fmax(out->max_rel_err, e);
		}
	}
	if (ok && (out->checked < CHECKS / 2 || !(out->max_rel_err <= MAX_REL_ERR))) {
		fprintf(stderr, "ceiling: the kernel's results differ from the CPU's by %.3g "
			"relative (limit %g) over %u samples\n", out->max_rel_err, MAX_REL_ERR,
			out->checked);
		ok = false;
	}
	double best = INFINITY;
	for (uint32_t r = 0; ok && r < runs; r++) {
		ok = gpu_finish(ctx);
		double t = rl_now_ms();
		ok = ok && gpu_dispatch(ctx, p, b, 3, samples) && gpu_finish(ctx);
		best = fmin(best, rl_now_ms() - t);
	}
	if (ok) {
		out->samples = samples;
		out->ms = best;
		out->flops_per_sample = FLOPS_ONCE + CEILING_LIGHTS * FLOPS_LIGHT;
		out->flops = out->flops_per_sample * samples / (best * 1e-3);
	}
	gpu_buffer_destroy(in);
	gpu_buffer_destroy(base);
	gpu_buffer_destroy(acc);
	free(rec);
	free(zero);
	free(cache);
	return ok;
}

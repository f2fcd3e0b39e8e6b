/*
 * The arithmetic micro-benchmark: see microbench.h.
 *
 * The loop body repeats the step UNROLL times so that the loop's own
 * counter and branch are a small share of the work; the trip count is a
 * uniform, so one program serves every step count.
 */
#include "microbench.h"

#include "clock.h"
#include "log.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define UNROLL 4
/* The exactness argument of microbench.h holds up to this many steps. */
#define MAX_STEPS (1u << 20)
/* Invocations of a timed run unless the device is too slow for them. */
#define BASE_INVOCATIONS (1u << 20)
#define MIN_INVOCATIONS 1024u
#define MAX_INVOCATIONS (1u << 24)
/* Trips of the calibration run. */
#define CAL_TRIPS 8u

/* Append to @buf; an overflow leaves *len past @cap, which the caller checks. */
static void put(char *buf, size_t cap, size_t *len, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
static void put(char *buf, size_t cap, size_t *len, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(*len < cap ? buf + *len : NULL, *len < cap ? cap - *len : 0, fmt, ap);
	va_end(ap);
	*len += n > 0 ? (size_t)n : 0;
}

/* The kernel of @chains chains of vec4 (@vec4) or float multiply-adds, into @buf. */
static bool kernel_source(char *buf, size_t cap, bool vec4, int chains)
{
	const char *t = vec4 ? "vec4" : "float";
	const char *m = vec4 ? "u_mul" : "u_mul.x", *a = vec4 ? "u_add" : "u_add.x";
	size_t len = 0;
	put(buf, cap, &len,
	    "#version 430 core\n"
	    "layout(local_size_x = 64) in;\n"
	    "layout(std430, binding = 0) writeonly buffer Out { float v[]; } u_out;\n"
	    "uniform uint u_count;\n"
	    "uniform int u_trips;\n"
	    "uniform float u_seed;\n"
	    "uniform vec4 u_mul;\n"
	    "uniform vec4 u_add;\n"
	    "void main()\n"
	    "{\n"
	    "\tuint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	    "\tif (i >= u_count)\n"
	    "\t\treturn;\n"
	    "\tfloat f = u_seed + float(i & 1023u) * 0.0009765625;\n");
	for (int k = 0; k < chains; k++) {
		if (vec4)
			put(buf, cap, &len, "\tvec4 x%d = f + vec4(%d.0, %d.0, %d.0, %d.0) * 0.0078125;\n",
			    k, 4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3);
		else
			put(buf, cap, &len, "\tfloat x%d = f + %d.0 * 0.0078125;\n", k, k);
	}
	put(buf, cap, &len, "\tfor (int n = 0; n < u_trips; n++) {\n");
	for (int u = 0; u < UNROLL; u++)
		for (int k = 0; k < chains; k++)
			put(buf, cap, &len, "\t\tx%d = fma(x%d, %s, %s);\n", k, k, m, a);
	put(buf, cap, &len, "\t}\n\t%s s = x0;\n", t);
	for (int k = 1; k < chains; k++)
		put(buf, cap, &len, "\ts += x%d;\n", k);
	put(buf, cap, &len, "\tu_out.v[i] = %s;\n}\n",
	    vec4 ? "(s.x + s.y) + (s.z + s.w)" : "s");
	return len < cap;
}

struct bench {
	struct gpu_ctx *ctx;
	struct gpu_program *prog;
	struct gpu_buffer *out;
	uint32_t cap;           /* invocations the output buffer holds */
};

/* One run of @n invocations, @trips trips: its time in ms, or -1 on failure. */
static double timed_run(struct bench *b, uint32_t n, uint32_t trips, float *check,
			const uint32_t *check_index)
{
	if (!gpu_uniform_int(b->prog, "u_trips", (int)trips))
		return -1;
	struct gpu_binding bd = { .unit = 0, .ssbo = true, .buffer = b->out };
	float last;
	double t0 = rl_now_ms();
	/* Reading a result waits for the dispatch to finish. */
	if (!gpu_dispatch(b->ctx, b->prog, &bd, 1, n) ||
	    !gpu_buffer_read(b->out, (size_t)(n - 1) * sizeof(float), sizeof(float), &last))
		return -1;
	double t = rl_now_ms() - t0;
	for (int c = 0; check && c < GPU_ARITH_CHECKS; c++) {
		if (check_index[c] >= n)
			check[c] = 0.0f;
		else if (!gpu_buffer_read(b->out, (size_t)check_index[c] * sizeof(float),
					  sizeof(float), &check[c]))
			return -1;
	}
	return t;
}

/*
 * Scale a run of *n invocations and *trips trips that took @t ms to about
 * @target ms: more trips up to MAX_STEPS, then more invocations; fewer
 * invocations when even the given trips take too long.
 */
static void fit(uint32_t *n, uint32_t *trips, double t, double target)
{
	if (t < 1e-3)
		t = 1e-3;
	double scale = target / t;
	double tr = (double)*trips * scale, m = *n;
	if (tr < CAL_TRIPS) {
		m *= tr / CAL_TRIPS;
		tr = CAL_TRIPS;
	}
	if (tr > MAX_STEPS / UNROLL) {
		m *= tr / (MAX_STEPS / UNROLL);
		tr = MAX_STEPS / UNROLL;
	}
	m = m < MIN_INVOCATIONS ? MIN_INVOCATIONS : m > MAX_INVOCATIONS ? MAX_INVOCATIONS : m;
	*n = (uint32_t)m / 64u * 64u;
	*trips = (uint32_t)tr;
}

/* Measure one kernel into @k. */
static bool measure(struct gpu_ctx *ctx, bool vec4, uint32_t runs, double target_ms,
		    const struct gpu_arith_rate *r, struct gpu_arith_kernel *k)
{
	int chains = vec4 ? GPU_ARITH_VEC4_CHAINS : GPU_ARITH_SCALAR_CHAINS;
	char src[16384];
	if (!kernel_source(src, sizeof(src), vec4, chains)) {
		rl_log(RL_LOG_ERROR, "gpu_arith_rate: kernel source too long");
		return false;
	}
	struct bench b = { .ctx = ctx, .prog = gpu_program(ctx, src, NULL) };
	if (!b.prog)
		return false;
	bool ok = false;
	if (!gpu_uniform_float(b.prog, "u_seed", &r->seed, 1) ||
	    !gpu_uniform_float(b.prog, "u_mul", r->mul, 4) ||
	    !gpu_uniform_float(b.prog, "u_add", r->add, 4))
		return false;
	b.cap = BASE_INVOCATIONS;
	b.out = gpu_buffer_create(ctx, (size_t)b.cap * sizeof(float), NULL);
	if (!b.out)
		return false;

	/*
	 * Warm-up: the driver may compile on first use, and fresh memory is
	 * slow to touch the first time.
	 */
	uint32_t n = BASE_INVOCATIONS, trips = CAL_TRIPS;
	if (timed_run(&b, n, 1, NULL, NULL) < 0)
		goto out;
	/* Two calibration runs: a short one, then one near the target. */
	for (int cal = 0; cal < 2; cal++) {
		double t = timed_run(&b, n, trips, NULL, NULL);
		if (t < 0)
			goto out;
		fit(&n, &trips, t, target_ms);
		if (n > b.cap) {
			gpu_buffer_destroy(b.out);
			b.cap = n;
			b.out = gpu_buffer_create(ctx, (size_t)b.cap * sizeof(float), NULL);
			if (!b.out || timed_run(&b, n, 1, NULL, NULL) < 0)
				goto out;
		}
	}
	double best = -1;
	for (uint32_t i = 0; i < runs; i++) {
		double t = timed_run(&b, n, trips, i + 1 == runs ? k->check : NULL, r->check_index);
		if (t < 0)
			goto out;
		if (best < 0 || t < best)
			best = t;
	}
	if (best < 1e-6)
		best = 1e-6;
	k->ms = best;
	k->invocations = n;
	k->steps = trips * UNROLL;
	k->flops = 2.0 * (vec4 ? 4.0 : 1.0) * chains * (double)k->steps * (double)n /
		   (best * 1e-3);
	ok = true;
out:
	gpu_buffer_destroy(b.out);
	return ok;
}

bool gpu_arith_rate(struct gpu_ctx *ctx, uint32_t runs, double target_ms,
		    struct gpu_arith_rate *out)
{
	if (!out)
		return false;
	memset(out, 0, sizeof(*out));
	if (!ctx) {
		rl_log(RL_LOG_ERROR, "gpu_arith_rate: no context");
		return false;
	}
	if (runs < 1)
		runs = 1;
	if (!(target_ms >= 1.0))
		target_ms = 1.0;
	if (target_ms > 10000.0)
		target_ms = 10000.0;
	struct gpu_arith_rate r = {
		.runs = runs,
		.seed = 0.5f,
		.mul = { 1.0f, 1.0f, 1.0f, 1.0f },
		/* (1, 2, 3, 4) * 2^-20 */
		.add = { 0x1p-20f, 0x1p-19f, 0x3p-20f, 0x1p-18f },
		.check_index = { 0, 1, 777, 1023 + 64 * 5 },
	};
	if (!measure(ctx, true, runs, target_ms, &r, &r.vec4) ||
	    !measure(ctx, false, runs, target_ms, &r, &r.scalar))
		return false;
	const struct gpu_arith_kernel *best = r.vec4.flops >= r.scalar.flops ? &r.vec4 : &r.scalar;
	r.flops = best->flops;
	r.ms = best->ms;
	r.invocations = best->invocations;
	*out = r;
	return isfinite(out->flops) && out->flops > 0;
}

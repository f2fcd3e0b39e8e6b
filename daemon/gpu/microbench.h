/*
 * The arithmetic throughput of the GPU (or llvmpipe): what the shading
 * kernels' rate is judged against.
 *
 * Two compute kernels (local size 64) run independent chains of fused
 * multiply-adds on values seeded from the invocation index and a uniform,
 * with no memory traffic in the loop, and write one float per invocation to
 * an SSBO:
 *
 *   vec4:   GPU_ARITH_VEC4_CHAINS chains of vec4 fma(x, mul, add)
 *   scalar: GPU_ARITH_SCALAR_CHAINS chains of float fma(x, mul.x, add.x)
 *
 * The chains, exactly (for a CPU check of the results): for invocation i,
 * with f = seed + (i & 1023) / 1024,
 *
 *   vec4 chain k, component j starts at   f + (4 k + j) / 128
 *   scalar chain k starts at              f + k / 128
 *
 * and each of @steps steps sets x = fma(x, mul, add) (the scalar kernel
 * uses mul[0], add[0]). The result of an invocation is the sum of its chain
 * ends, chain 0 first, each vec4 chain added componentwise into a vec4 s,
 * then (s.x + s.y) + (s.z + s.w); the scalar kernel sums its chains in
 * order. The values passed (mul = 1, add = (1, 2, 3, 4) * 2^-20, seed = 0.5,
 * steps <= 2^20) keep every chain exact in float whether or not the device
 * fuses: only the final sum rounds. A kernel that skipped steps would give
 * a different sum, which is how a test can tell the work was done; the
 * compiler cannot fold the chains because mul and add are uniforms.
 *
 * A multiply-add counts 2 float operations per component. A run lasts about
 * the requested time: the step count (and, on a slow device, the invocation
 * count) is scaled from a timed calibration run; each timed run covers the
 * dispatch up to a read of the results, so it includes completion.
 *
 * Which figure to compare with. Generated shading code is mostly scalar
 * and vec3 arithmetic, but on every device relight runs on the vector width
 * is not the hardware's: llvmpipe runs each component as a separate 8-lane
 * SIMD operation across invocations (SoA), and current GPUs have scalar
 * lanes, so scalar and vec4 code reach the same peak when there is enough
 * independent work. The benchmark therefore judges kernels against `flops`,
 * the larger of the two kernels' rates: the best arithmetic rate measured on
 * the device, the strict choice for "at least half of it". `vec4` and
 * `scalar` keep each kernel's own figure; a large gap between them says
 * the measurement (not the kernels) needs a look.
 */
#ifndef GPU_MICROBENCH_H
#define GPU_MICROBENCH_H

#include "gpu.h"

#include <stdbool.h>
#include <stdint.h>

/*
 * Chains per invocation. Beyond hiding latency, more chains share each loop
 * trip's own work (llvmpipe keeps a per-lane counter and mask) among more
 * multiply-adds: on llvmpipe with 2 cores, 4, 8 and 16 vec4 chains measured
 * about 60, 95 and 110 GFLOP/s.
 */
/** Independent chains per invocation of the vec4 kernel. */
#define GPU_ARITH_VEC4_CHAINS 16
/** Independent chains per invocation of the scalar kernel. */
#define GPU_ARITH_SCALAR_CHAINS 32
/** Invocations whose results are kept for checking (indices in check_index). */
#define GPU_ARITH_CHECKS 4

/** One kernel's measurement. */
struct gpu_arith_kernel {
	double flops;              /* float operations per second (a multiply-add counts 2) */
	double ms;                 /* time of the best run */
	uint64_t invocations;
	uint32_t steps;            /* multiply-add steps per chain */
	float check[GPU_ARITH_CHECKS]; /* results of invocations check_index[] (last run) */
};

struct gpu_arith_rate {
	double flops;              /* max(vec4.flops, scalar.flops): compare kernels with this */
	double ms;                 /* time of the best run of the kernel giving flops */
	uint64_t invocations;      /* its invocation count */
	uint32_t runs;             /* timed runs per kernel */
	struct gpu_arith_kernel vec4, scalar;
	/* The chains' inputs (see above) and the invocations whose results are in check[]. */
	float seed;
	float mul[4], add[4];
	uint32_t check_index[GPU_ARITH_CHECKS];
};

/**
 * Measure the float arithmetic rate of @ctx's device with the vec4 and the
 * scalar multiply-add kernels, best of @runs runs (at least 1) of about
 * @target_ms each (clamped to [1, 10000]); @ctx must be current. Compiles
 * two small programs (kept in the context's program cache). Fills all of
 * @out; false (with @out zeroed and a logged message) on a GPU error.
 */
bool gpu_arith_rate(struct gpu_ctx *ctx, uint32_t runs, double target_ms,
		    struct gpu_arith_rate *out);

#endif

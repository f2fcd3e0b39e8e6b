/*
 * The arithmetic throughput of the GPU (or llvmpipe): what the shading
 * kernels' rate is judged against.
 */
#ifndef GPU_MICROBENCH_H
#define GPU_MICROBENCH_H

#include "gpu.h"

#include <stdbool.h>
#include <stdint.h>

struct gpu_arith_rate {
	double flops;              /* float operations per second (a fused multiply-add counts 2) */
	double ms;                 /* time of the best run */
	uint64_t invocations;
	uint32_t runs;
};

/**
 * Measure the float arithmetic rate of @ctx's device with a compute kernel
 * of independent multiply-add chains (no memory traffic in the loop), best
 * of @runs runs of about @target_ms each. False on a GPU error.
 */
bool gpu_arith_rate(struct gpu_ctx *ctx, uint32_t runs, double target_ms,
		    struct gpu_arith_rate *out);

#endif

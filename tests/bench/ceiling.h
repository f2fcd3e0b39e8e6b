/*
 * A yardstick for the shading kernels: the shading of a batch kernel
 * (plastic.sl lit by eight pointlight.sl lights, one pass a light, each
 * pass's colour less the base added into a float64 cache), written by hand
 * in GLSL as lean as it goes: one read of each record, the lights unrolled,
 * normalize, inversesqrt and pow as GLSL has them, and none of the
 * generated code's guards (no clamps to the float range, no checks for
 * zero divisors or NaN). It runs over synthetic samples laid out as the
 * street's plastic records (six RGBA32F texels a sample), with no ambient
 * light (plastic's Ka * ambient() is then 0).
 *
 * What it is for: the generated kernels are judged against the device's
 * arithmetic rate (gpu_arith_rate); this kernel says how much of that rate
 * the same shading reaches at best on the device, so a gap between the two
 * can be told apart from a gap the device itself sets.
 *
 * Its float operations are counted with the interpreter's rules (exec.h's
 * sl_exec_count_ops) over the operations the kernel runs for every sample
 * (ceiling.c counts them line by line: 558 a sample). Its
 * results are checked against the same shading in double on the CPU, so a
 * kernel that skipped work would fail rather than look fast.
 */
#ifndef BENCH_CEILING_H
#define BENCH_CEILING_H

#include "gpu.h"

#include <stdbool.h>
#include <stdint.h>

#define CEILING_LIGHTS 8

struct ceiling {
	uint32_t samples;
	double ms;                 /* best run */
	double flops_per_sample;   /* counted as exec.h counts: 14 + 68 a light */
	double flops;              /* counted float operations per second */
	double max_rel_err;        /* against the CPU in double, over the checked samples */
	uint32_t checked;
};

/**
 * Time the yardstick over @samples synthetic samples, best of @runs runs, on
 * @ctx (current). False, with a message on stderr, on a GPU error or when
 * the kernel's results differ from the CPU's by more than 1e-4 relative.
 */
bool ceiling_run(struct gpu_ctx *ctx, uint32_t samples, uint32_t runs, struct ceiling *out);

#endif

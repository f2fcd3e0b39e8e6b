/*
 * What the benchmarks share: order statistics of timings, and reading a
 * rendered image back as RGBA.
 */
#ifndef BENCH_BENCHUTIL_H
#define BENCH_BENCHUTIL_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/** The median of @n values (sorts @v); NAN when @n is 0. */
double bench_median(double *v, int n);

/** The 99th percentile, nearest rank (sorts @v); NAN when @n is 0. */
double bench_p99(double *v, int n);

/**
 * The R, G, B and A channels of the OpenEXR image at @path, which must be
 * @w x @h, as a malloc'd array of w * h * 4 floats. Without an A channel,
 * alpha is 1 unless @need_alpha (then it is an error). NULL with the reason
 * in @why (the reader's own messages go to @diag, NULL: stderr).
 */
float *bench_read_rgba_exr(const char *path, uint32_t w, uint32_t h, bool need_alpha,
			   FILE *diag, char *why, size_t cap);

#endif

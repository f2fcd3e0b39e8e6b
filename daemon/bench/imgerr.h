/*
 * How far one image is from another, as `relight diff` and `relight bench`
 * report it: the RMSE of the linear values; the mean and largest absolute
 * error of the displayed values in percent of the 8-bit range (through the
 * sRGB transfer of the value clamped to [0, 1], continuous, not rounded);
 * the PSNR of those values (peak 1); the largest relative difference of the
 * linear values, |a - b| / max(|a|, |b|, 1e-3). A NaN or infinite value
 * counts as an error of the whole range (1 linear, 100 %) and is counted.
 */
#ifndef BENCH_IMGERR_H
#define BENCH_IMGERR_H

#include <stdbool.h>
#include <stdint.h>

/* Values under this are compared absolutely by the relative difference. */
#define IMG_ERROR_REL_FLOOR 1e-3

struct img_error {
	uint64_t samples;          /* values compared (pixels x channels) */
	double sum_lin2;           /* sum of squared linear differences */
	double sum_enc, sum_enc2;  /* sum of displayed differences (fraction of range), squared */
	double max_enc;            /* the largest per-pixel displayed difference */
	uint32_t max_x, max_y;     /* where (the first in scanline order) */
	double max_rel;
	uint64_t over_1pct;        /* pixels whose largest channel error exceeds 1 % */
	uint64_t nonfinite[2];     /* non-finite values in a, in b */
};

/**
 * Compare @n channels of two @w x @h images: pixel p of @a has its values
 * at a[p * astride + ca[k]], of @b at b[p * bstride + cb[k]]. Through the
 * sRGB transfer when @srgb (colour), else clamped to [0, 1] only (alpha).
 * With @map (w * h floats, or NULL), map[p] gets the pixel's largest
 * displayed difference in percent of the 8-bit range (100 for a non-finite
 * value). @e is cleared first; with a NULL image or @n <= 0 it stays zero.
 */
void img_error_measure(const float *a, uint32_t astride, const int *ca, const float *b,
		       uint32_t bstride, const int *cb, int n, uint32_t w, uint32_t h, bool srgb,
		       float *map, struct img_error *e);

/** RGB of two RGBA images (4 floats per pixel), through sRGB. */
void img_error_rgba(const float *a, const float *b, uint32_t w, uint32_t h, float *map,
		    struct img_error *e);

double img_error_rmse(const struct img_error *e);
double img_error_mean_pct(const struct img_error *e);
double img_error_max_pct(const struct img_error *e);
/** The PSNR in dB (peak 1), or NAN when the images are identical. */
double img_error_psnr_db(const struct img_error *e);

#endif

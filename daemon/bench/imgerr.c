/*
 * Image error measures shared by `relight diff` and `relight bench`. The
 * arithmetic is fixed: the numbers `relight diff` prints (and tests hold to
 * the last digit of its JSON) come from here, so any change to the order of
 * operations below changes its output.
 */
#include "imgerr.h"

#include "png.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

static float clamp01(float v)
{
	return v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f;
}

void img_error_measure(const float *a, uint32_t astride, const int *ca, const float *b,
		       uint32_t bstride, const int *cb, int n, uint32_t w, uint32_t h, bool srgb,
		       float *map, struct img_error *e)
{
	memset(e, 0, sizeof(*e));
	if (!a || !b || !ca || !cb || n <= 0)
		return;
	for (uint32_t y = 0; y < h; y++) {
		for (uint32_t x = 0; x < w; x++) {
			size_t px = (size_t)y * w + x;
			const float *pa = a + px * astride;
			const float *pb = b + px * bstride;
			/* The pixel's error is its worst channel, so that a wrong hue shows. */
			double pixel = 0.0;
			for (int k = 0; k < n; k++) {
				float va = pa[ca[k]], vb = pb[cb[k]];
				double lin, enc;
				bool fa = isfinite(va), fb = isfinite(vb);
				if (!fa || !fb) {
					e->nonfinite[0] += !fa;
					e->nonfinite[1] += !fb;
					lin = enc = 1.0;
				} else {
					lin = (double)va - (double)vb;
					double m = fmax(fmax(fabs((double)va), fabs((double)vb)),
							IMG_ERROR_REL_FLOOR);
					if (fabs(lin) / m > e->max_rel)
						e->max_rel = fabs(lin) / m;
					enc = srgb ? fabs((double)reyes_srgb_encode(va) -
							  (double)reyes_srgb_encode(vb))
						   : fabs((double)clamp01(va) - (double)clamp01(vb));
				}
				e->sum_lin2 += lin * lin;
				e->sum_enc += enc;
				e->sum_enc2 += enc * enc;
				if (enc > pixel)
					pixel = enc;
			}
			e->samples += (uint64_t)n;
			/* Strictly greater: the first pixel in scanline order keeps the place. */
			if (pixel > e->max_enc) {
				e->max_enc = pixel;
				e->max_x = x;
				e->max_y = y;
			}
			e->over_1pct += pixel > 0.01;
			if (map)
				map[px] = (float)(100.0 * pixel);
		}
	}
}

void img_error_rgba(const float *a, const float *b, uint32_t w, uint32_t h, float *map,
		    struct img_error *e)
{
	static const int c[3] = { 0, 1, 2 };
	img_error_measure(a, 4, c, b, 4, c, 3, w, h, true, map, e);
}

double img_error_rmse(const struct img_error *e)
{
	return e->samples ? sqrt(e->sum_lin2 / (double)e->samples) : 0.0;
}

double img_error_mean_pct(const struct img_error *e)
{
	return e->samples ? 100.0 * e->sum_enc / (double)e->samples : 0.0;
}

double img_error_max_pct(const struct img_error *e)
{
	return 100.0 * e->max_enc;
}

double img_error_psnr_db(const struct img_error *e)
{
	double mse = e->samples ? e->sum_enc2 / (double)e->samples : 0.0;
	return mse > 0.0 ? -10.0 * log10(mse) : NAN;
}

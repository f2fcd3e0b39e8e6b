/* What the benchmarks share (benchutil.h). */
#include "benchutil.h"
#include "texture.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

double bench_median(double *v, int n)
{
	if (n <= 0)
		return NAN;
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double bench_p99(double *v, int n)
{
	if (n <= 0)
		return NAN;
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	int k = (int)ceil(0.99 * n);
	return v[(k < 1 ? 1 : k) - 1];
}

float *bench_read_rgba_exr(const char *path, uint32_t w, uint32_t h, bool need_alpha,
			   FILE *diag, char *why, size_t cap)
{
	struct reyes_image im = { 0 };
	if (!reyes_image_read_exr(path, &im, diag ? diag : stderr)) {
		snprintf(why, cap, "cannot read the image %s", path);
		return NULL;
	}
	int ch[4] = { -1, -1, -1, -1 };
	static const char *const names[4] = { "R", "G", "B", "A" };
	for (uint32_t c = 0; c < im.nchannels; c++)
		for (int k = 0; k < 4; k++)
			if (im.channel_names[c] && !strcmp(im.channel_names[c], names[k]))
				ch[k] = (int)c;
	float *rgba = NULL;
	if (im.width != w || im.height != h || ch[0] < 0 || ch[1] < 0 || ch[2] < 0 ||
	    (need_alpha && ch[3] < 0)) {
		snprintf(why, cap, "%s: %ux%u, channels R, G, B%s %s; expected %ux%u", path,
			 im.width, im.height, need_alpha ? ", A" : "",
			 ch[0] < 0 || ch[1] < 0 || ch[2] < 0 || (need_alpha && ch[3] < 0) ? "missing"
											  : "present",
			 w, h);
	} else {
		size_t px = (size_t)w * h;
		rgba = malloc(px * 4 * sizeof(float));
		if (!rgba)
			snprintf(why, cap, "out of memory reading %s", path);
		for (size_t i = 0; rgba && i < px; i++)
			for (int k = 0; k < 4; k++)
				rgba[i * 4 + (size_t)k] =
					ch[k] >= 0 ? im.data[i * im.nchannels + (size_t)ch[k]] : 1.0f;
	}
	reyes_image_finish(&im);
	return rgba;
}

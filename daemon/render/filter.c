/*
 * Pixel reconstruction filters (RISpec Appendix E) and PixelFilter names.
 *
 * Offsets and widths are in pixels; a width is the filter's total extent, so
 * the support is |dx| <= xwidth/2, |dy| <= ywidth/2 and every filter is 0
 * outside it. Within the support:
 *
 *   box                    1
 *   triangle               (1 - |dx|/hx) (1 - |dy|/hy), hx = xwidth/2
 *   catmull-rom            radial Catmull-Rom cubic of r = sqrt(dx^2 + dy^2),
 *                          r in pixels (not scaled by the width), 0 for r >= 2
 *   gaussian               exp(-2 (x^2 + y^2)), x = dx / hx, y = dy / hy
 *   sinc                   s(dx, xwidth) s(dy, ywidth) with
 *                          s(d, w) = cos(pi d / (2 w)) sin(pi d) / (pi d)
 *   separable-catmull-rom  c(|dx|) c(|dy|), c the 1D form of the cubic above
 *   separable-gaussian     exp(-2 x^2) exp(-2 y^2)
 *
 * The values are not normalised: the hider divides by the sum of the weights.
 * The two Gaussians are the same function (a Gaussian is separable); the
 * Catmull-Rom pair differ: the radial one has circular level sets.
 */
#include "hider.h"

#include <math.h>
#include <string.h>

#define FILTER_PI 3.14159265358979323846

/* RISpec's Catmull-Rom cubic (twice the usual 1D kernel) at distance r >= 0. */
static double catmull_rom(double r)
{
	double r2 = r * r;
	if (r >= 2.0)
		return 0.0;
	if (r < 1.0)
		return 3.0 * r * r2 - 5.0 * r2 + 2.0;
	return -r * r2 + 5.0 * r2 - 8.0 * r + 4.0;
}

/* The windowed sinc of one axis; d within [-w/2, w/2]. */
static double sinc_axis(double d, double w)
{
	if (d == 0.0)
		return 1.0;
	double x = FILTER_PI * d;
	return cos(0.5 * x / w) * sin(x) / x;
}

float reyes_filter_eval(enum reyes_filter f, float dx, float dy, float xwidth, float ywidth)
{
	double hx = 0.5 * (double)xwidth, hy = 0.5 * (double)ywidth;
	double ax = fabs((double)dx), ay = fabs((double)dy);

	/* Written so that NaN offsets or widths fall out as 0. */
	if (!(hx > 0.0 && hy > 0.0 && ax <= hx && ay <= hy))
		return 0.0f;
	switch (f) {
	case REYES_FILTER_BOX:
		return 1.0f;
	case REYES_FILTER_TRIANGLE:
		return (float)(((hx - ax) / hx) * ((hy - ay) / hy));
	case REYES_FILTER_CATMULLROM:
		return (float)catmull_rom(sqrt(ax * ax + ay * ay));
	case REYES_FILTER_GAUSSIAN: {
		double x = ax / hx, y = ay / hy;
		return (float)exp(-2.0 * (x * x + y * y));
	}
	case REYES_FILTER_SINC:
		return (float)(sinc_axis(ax, xwidth) * sinc_axis(ay, ywidth));
	case REYES_FILTER_SEP_CATMULLROM:
		return (float)(catmull_rom(ax) * catmull_rom(ay));
	case REYES_FILTER_SEP_GAUSSIAN: {
		double x = ax / hx, y = ay / hy;
		return (float)(exp(-2.0 * x * x) * exp(-2.0 * y * y));
	}
	}
	return 0.0f;
}

bool reyes_filter_from_name(const char *name, enum reyes_filter *f)
{
	static const struct {
		const char *name;
		enum reyes_filter f;
	} names[] = {
		{ "box", REYES_FILTER_BOX },
		{ "triangle", REYES_FILTER_TRIANGLE },
		{ "catmull-rom", REYES_FILTER_CATMULLROM },
		{ "gaussian", REYES_FILTER_GAUSSIAN },
		{ "sinc", REYES_FILTER_SINC },
		{ "separable-catmull-rom", REYES_FILTER_SEP_CATMULLROM },
		{ "separable-gaussian", REYES_FILTER_SEP_GAUSSIAN },
	};
	if (!name)
		return false;
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		if (strcmp(name, names[i].name) == 0) {
			if (f)
				*f = names[i].f;
			return true;
		}
	}
	return false;
}

/*
 * Pictures for the benchmark report (relight bench): line and scatter plots
 * and grouped bar charts as standalone SVG, and error heat maps as PNG, in
 * the manner of lightspeed-2007's Fig. 1 (error in percent of the 8-bit
 * range).
 *
 * Every writer refuses NaN and infinite inputs rather than drawing them
 * (points with a non-finite coordinate, or a non-positive one on a log
 * axis, are left out and counted in the plot's caption line), writes its
 * file atomically (a failed write leaves any old file intact), and reports
 * failures in @err.
 *
 * SVG geometry, for those who check it: the plot area is the <rect> of
 * class "plot-area"; an axis runs from its first tick at one edge of the
 * area to its last at the other (x left to right, y bottom to top), linear
 * in the value or, on a log axis, in its log10. Linear axes end on
 * multiples of a 1, 2 or 5 x 10^k step that just cover the drawn values;
 * log axes on the powers of ten that do.
 */
#ifndef BENCH_PLOT_H
#define BENCH_PLOT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/** One series of a line plot: @n points (x[i], y[i]), drawn in order. */
struct plot_series {
	const char *label;          /* legend text (XML-escaped when written) */
	const double *x, *y;
	size_t n;
	bool dashed;                /* a dashed line (e.g. "without the light cache") */
	int color;                  /* index into the palette; -1: the series' index */
	const char *const *point_labels; /* NULL, or n short texts drawn beside the points */
};

struct plot_opts {
	const char *title;          /* drawn above the plot */
	const char *xlabel, *ylabel;
	bool xlog, ylog;            /* base-10 log axes (decades labelled, 1-2-5 minor ticks) */
	int width, height;          /* pixels, 240 x 160 to 16384 x 16384; 0: 720 x 440 */
};

/* The heat map PNG's gaps between maps and above the colour bar, and the bar's height. */
#define PLOT_HEATMAP_GAP 4
#define PLOT_HEATMAP_BAR 12

/**
 * A line plot with markers at the points, axes with "nice" ticks that cover
 * every drawable point, a grid and a legend (series with a NULL label have
 * no entry). @o may be NULL for an untitled 720 x 440 plot. At least one
 * drawable point is needed. The line of a series breaks where a point is
 * left out.
 */
bool plot_lines_svg(const char *path, const struct plot_opts *o, const struct plot_series *s,
		    size_t ns, char *err, size_t errlen);

/**
 * A grouped bar chart: @ngroups groups along x (labelled @groups), each
 * with @nseries bars (legend @series), heights values[g * nseries + k]
 * (>= 0; o->ylog draws them on a log axis, non-positive ones left out).
 * Each bar's value is printed above it (3 significant digits). Negative and
 * non-finite values are left out and counted. @groups, @series and entries
 * of them may be NULL (no label); @o may be NULL.
 */
bool plot_bars_svg(const char *path, const struct plot_opts *o, const char *const *groups,
		   size_t ngroups, const char *const *series, size_t nseries, const double *values,
		   char *err, size_t errlen);

/**
 * Error heat maps side by side in one PNG: @nmaps maps of @w x @h values
 * (each maps[k][y * w + x], in percent of the 8-bit range, >= 0), each
 * reduced by @shrink (>= 1: each output pixel shows the largest value of
 * its shrink x shrink block, so a single bad pixel stays visible), with
 * 4-pixel gaps between them and a colour bar along the bottom. Values map
 * through plot_ramp from 0 to @vmax (values above it saturate; non-finite
 * values are drawn in pure magenta so that they cannot be missed).
 *
 * The PNG is nmaps * ceil(w / shrink) + (nmaps - 1) * PLOT_HEATMAP_GAP
 * pixels wide and ceil(h / shrink) + PLOT_HEATMAP_GAP + PLOT_HEATMAP_BAR
 * high; map k starts at x = k * (ceil(w / shrink) + PLOT_HEATMAP_GAP). The
 * gaps are mid grey (128, 128, 128), a colour the ramp never takes; the
 * bar runs the ramp from 0 at its left end to @vmax at its right.
 */
bool plot_heatmap_png(const char *path, const float *const *maps, size_t nmaps, uint32_t w,
		      uint32_t h, uint32_t shrink, double vmax, char *err, size_t errlen);

/**
 * The heat maps' colour ramp, the one `relight diff --heatmap` draws: black,
 * blue, green, yellow, red, white at 0, 1/5, ... 5/5; @v in [0, 1] (clamped;
 * NaN gives black) to 8-bit RGB.
 */
void plot_ramp(double v, uint8_t rgb[3]);

#endif

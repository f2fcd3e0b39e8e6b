/*
 * relight diff: measure how far one rendered image is from another (a
 * preview against the final frame, a render before and after a change).
 * Errors are reported both on the linear values and, as the paper's
 * figures do, as a percentage of the 8-bit range of the displayed (sRGB)
 * values; optionally as a heat map PNG.
 */
#include "cmd.h"
#include "imgerr.h"
#include "plot.h"
#include "png.h"
#include "texture.h"

#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight diff [OPTIONS] A.exr B.exr\n"
		"\n"
		"Compare two OpenEXR images of the same size (for example a preview and the\n"
		"final frame written by 'relight render') over their colour channels R, G, B,\n"
		"and report:\n"
		"  - the RMSE of the linear values;\n"
		"  - the mean and the maximum absolute error of the displayed values, in percent\n"
		"    of the 8-bit range: 100 |srgb(a) - srgb(b)|, where srgb() is the sRGB\n"
		"    transfer function of the value clamped to [0, 1], taken as a continuous\n"
		"    value (not rounded to 8 bits); colour is taken as it is (premultiplied),\n"
		"    that is over black;\n"
		"  - the PSNR in dB of those sRGB values (peak 1); identical images have no\n"
		"    finite PSNR: the text says 'identical', the JSON has null;\n"
		"  - the pixel (x, y) of the maximum error (the first in scanline order) and\n"
		"    the number of pixels whose error, the largest over R, G, B, exceeds 1%%.\n"
		"When both images have an alpha channel A it is compared apart, the same way\n"
		"but with no transfer function. A NaN or infinite value in either image counts\n"
		"as an error of the whole range (1 in linear, 100%%) and is reported.\n"
		"\n"
		"Options:\n"
		"  --json               Print one JSON object instead of text, with the keys\n"
		"                       a, b, width, height, pixels, channels, rmse, mean_pct,\n"
		"                       max_pct, psnr_db (null when identical), max_at [x, y],\n"
		"                       over_1pct, nonfinite [in A, in B], max_rel, alpha (an object\n"
		"                       with the same error keys, or null), heatmap (null\n"
		"                       without --heatmap), scale_pct\n"
		"  --heatmap OUT.png    Write the per-pixel error (the largest over R, G, B) as\n"
		"                       an RGB PNG, through the colour ramp black, blue, green,\n"
		"                       yellow, red, white at 0, 1/5, 2/5, 3/5, 4/5 and 5/5 of\n"
		"                       the scale; errors beyond the scale are white\n"
		"  --scale S            The error, in percent, at the top of the heat map's\n"
		"                       ramp (default 5)\n"
		"  --fail-rel R         Exit with status 1 when the largest relative difference\n"
		"                       of the linear colour values, |a - b| / max(|a|, |b|),\n"
		"                       is above R (values under 1e-3 are compared absolutely,\n"
		"                       as if they were 1e-3); reported as max_rel\n"
		"  --fail-above PCT     Exit with status 1 when the maximum error is above PCT\n"
		"                       percent (the report is printed all the same)\n"
		"  -h, --help           Show this help and exit\n"
		"\n"
		"Exit status: 0 when the images were compared (whatever their difference),\n"
		"1 when an image cannot be read, the images differ in size or channels, the\n"
		"heat map cannot be written or the error is above --fail-above, 2 on a usage\n"
		"error.\n");
}

#define usage_error(...) cmd_usage_error("diff", __VA_ARGS__)

static bool parse_pct(const char *s, double lo, bool lo_open, double *out)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (errno || end == s || *end || !isfinite(v) || v > 100.0 || v < lo ||
	    (lo_open && v == lo))
		return false;
	*out = v;
	return true;
}

static int find_channel(const struct reyes_image *im, const char *name)
{
	for (uint32_t c = 0; c < im->nchannels; c++)
		if (im->channel_names[c] && strcmp(im->channel_names[c], name) == 0)
			return (int)c;
	return -1;
}

/*
 * Compare channels @ca of @a with @cb of @b (@n of them), through the sRGB
 * transfer when @srgb.
 */
static void measure(const struct reyes_image *a, const struct reyes_image *b, const int *ca,
		    const int *cb, int n, bool srgb, struct img_error *e)
{
	img_error_measure(a->data, a->nchannels, ca, b->data, b->nchannels, cb, n, a->width,
			  a->height, srgb, NULL, e);
}

/*
 * The heat map of the colour channels, @scale (a fraction of the range) at
 * the ramp's top. Each pixel is measured alone so that its colour comes from
 * its exact error, not from the rounded float of an error map: the PNG stays
 * the same, byte for byte, as the one relight diff has always written.
 */
static void heat_map(const struct reyes_image *a, const struct reyes_image *b, const int *ca,
		     const int *cb, int n, double scale, uint8_t *heat)
{
	size_t npx = (size_t)a->width * a->height;
	for (size_t p = 0; p < npx; p++) {
		struct img_error e;
		img_error_measure(a->data + p * a->nchannels, a->nchannels, ca,
				  b->data + p * b->nchannels, b->nchannels, cb, n, 1, 1, true, NULL,
				  &e);
		plot_ramp(e.max_enc / scale, heat + 3 * p);
	}
}

/* A JSON number; null for what JSON cannot hold. */
static void json_number(FILE *out, double v)
{
	if (isfinite(v))
		fprintf(out, "%.9g", v);
	else
		fputs("null", out);
}

static void json_string(FILE *out, const char *s)
{
	fputc('"', out);
	for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
		if (*p == '"' || *p == '\\')
			fprintf(out, "\\%c", *p);
		else if (*p < 0x20)
			fprintf(out, "\\u%04x", *p);
		else
			fputc(*p, out);
	}
	fputc('"', out);
}

static void json_stats(FILE *out, const struct img_error *s)
{
	fputs("\"rmse\": ", out);
	json_number(out, img_error_rmse(s));
	fputs(", \"mean_pct\": ", out);
	json_number(out, img_error_mean_pct(s));
	fputs(", \"max_pct\": ", out);
	json_number(out, img_error_max_pct(s));
	fputs(", \"psnr_db\": ", out);
	json_number(out, img_error_psnr_db(s));
	fprintf(out, ", \"max_at\": [%" PRIu32 ", %" PRIu32 "], \"over_1pct\": %" PRIu64
		", \"nonfinite\": [%" PRIu64 ", %" PRIu64 "]",
		s->max_x, s->max_y, s->over_1pct, s->nonfinite[0], s->nonfinite[1]);
	fputs(", \"max_rel\": ", out);
	json_number(out, s->max_rel);
}

struct report {
	const char *path_a, *path_b;
	uint32_t width, height;
	const char *channels[3];
	int nchannels;
	struct img_error colour, alpha;
	bool has_alpha;
	const char *alpha_only;         /* the one image with an alpha channel, or NULL */
	const char *heatmap;
	double scale_pct;
};

static void print_json(FILE *out, const struct report *r)
{
	fputs("{\"a\": ", out);
	json_string(out, r->path_a);
	fputs(", \"b\": ", out);
	json_string(out, r->path_b);
	fprintf(out, ", \"width\": %" PRIu32 ", \"height\": %" PRIu32 ", \"pixels\": %" PRIu64
		", \"channels\": [", r->width, r->height, (uint64_t)r->width * r->height);
	for (int k = 0; k < r->nchannels; k++)
		fprintf(out, "%s\"%s\"", k ? ", " : "", r->channels[k]);
	fputs("], ", out);
	json_stats(out, &r->colour);
	fputs(", \"alpha\": ", out);
	if (r->has_alpha) {
		fputc('{', out);
		json_stats(out, &r->alpha);
		fputc('}', out);
	} else {
		fputs("null", out);
	}
	fputs(", \"heatmap\": ", out);
	if (r->heatmap)
		json_string(out, r->heatmap);
	else
		fputs("null", out);
	fputs(", \"scale_pct\": ", out);
	json_number(out, r->scale_pct);
	fputs("}\n", out);
}

static void print_text(FILE *out, const struct report *r)
{
	const struct img_error *s = &r->colour;
	uint64_t pixels = (uint64_t)r->width * r->height;
	fprintf(out, "%s vs %s: %" PRIu32 "x%" PRIu32 ", channels", r->path_a, r->path_b,
		r->width, r->height);
	for (int k = 0; k < r->nchannels; k++)
		fprintf(out, " %s", r->channels[k]);
	fputc('\n', out);
	fprintf(out, "  RMSE (linear)      %.6g\n", img_error_rmse(s));
	fprintf(out, "  max relative       %.3g (linear)\n", s->max_rel);
	fprintf(out, "  mean error         %.4f %% of the 8-bit range (sRGB)\n", img_error_mean_pct(s));
	fprintf(out, "  max error          %.4f %% at pixel (%" PRIu32 ", %" PRIu32 ")\n",
		img_error_max_pct(s), s->max_x, s->max_y);
	double p = img_error_psnr_db(s);
	if (isfinite(p))
		fprintf(out, "  PSNR (sRGB)        %.2f dB\n", p);
	else
		fprintf(out, "  PSNR (sRGB)        identical\n");
	fprintf(out, "  pixels over 1%%     %" PRIu64 " of %" PRIu64 " (%.2f %%)\n", s->over_1pct,
		pixels, pixels ? 100.0 * (double)s->over_1pct / (double)pixels : 0.0);
	if (s->nonfinite[0] || s->nonfinite[1])
		fprintf(out, "  non-finite values  %" PRIu64 " in %s, %" PRIu64 " in %s "
			"(each an error of 100 %%)\n", s->nonfinite[0], r->path_a,
			s->nonfinite[1], r->path_b);
	if (r->has_alpha) {
		const struct img_error *a = &r->alpha;
		fprintf(out, "  alpha              RMSE %.6g, mean %.4f %%, max %.4f %% at (%" PRIu32
			", %" PRIu32 "), %" PRIu64 " pixels over 1%%", img_error_rmse(a),
			img_error_mean_pct(a), img_error_max_pct(a), a->max_x, a->max_y, a->over_1pct);
		if (a->nonfinite[0] || a->nonfinite[1])
			fprintf(out, ", %" PRIu64 " + %" PRIu64 " non-finite", a->nonfinite[0],
				a->nonfinite[1]);
		fputc('\n', out);
	} else if (r->alpha_only) {
		fprintf(out, "  alpha              only in %s, not compared\n", r->alpha_only);
	}
	if (r->heatmap)
		fprintf(out, "  heat map           %s (black 0, blue %.3g, green %.3g, yellow %.3g, "
			"red %.3g, white %.3g %% and above)\n", r->heatmap, r->scale_pct * 0.2,
			r->scale_pct * 0.4, r->scale_pct * 0.6, r->scale_pct * 0.8, r->scale_pct);
}

/* The names of @im's channels, comma-separated, for messages. */
static void list_channels(const struct reyes_image *im, char *buf, size_t size)
{
	size_t len = 0;
	buf[0] = '\0';
	for (uint32_t c = 0; c < im->nchannels && len < size; c++)
		len += (size_t)snprintf(buf + len, size - len, "%s%s", c ? ", " : "",
					im->channel_names[c] ? im->channel_names[c] : "?");
	if (im->nchannels == 0)
		snprintf(buf, size, "none");
}

int cmd_diff(int argc, char **argv)
{
	bool json = false;
	const char *heatmap = NULL;
	double scale = 5.0, fail_above = -1.0, fail_rel = -1.0;
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "json", no_argument, NULL, 'j' },
		{ "heatmap", required_argument, NULL, 'H' },
		{ "scale", required_argument, NULL, 's' },
		{ "fail-above", required_argument, NULL, 'f' },
		{ "fail-rel", required_argument, NULL, 'r' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt;
	while ((opt = getopt_long(argc, argv, ":h", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'j':
			json = true;
			break;
		case 'H':
			if (!optarg[0])
				return usage_error("--heatmap needs a file name");
			heatmap = optarg;
			break;
		case 's':
			if (!parse_pct(optarg, 0.0, true, &scale))
				return usage_error("--scale needs a percentage above 0 and at most "
						   "100, not '%s'", optarg);
			break;
		case 'f':
			if (!parse_pct(optarg, 0.0, false, &fail_above))
				return usage_error("--fail-above needs a percentage from 0 to 100, "
						   "not '%s'", optarg);
			break;
		case 'r':
			if (!cmd_parse_double(optarg, 0.0, 1.0, &fail_rel))
				return usage_error("--fail-rel needs a number from 0 to 1, not '%s'",
						   optarg);
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (argc - optind < 2)
		return usage_error(argc - optind == 0 ? "no images to compare"
						       : "two images expected, A.exr and B.exr");
	if (argc - optind > 2)
		return usage_error("two images expected; extra argument '%s'", argv[optind + 2]);

	struct report r = {
		.path_a = argv[optind],
		.path_b = argv[optind + 1],
		.heatmap = heatmap,
		.scale_pct = scale,
	};
	struct reyes_image a, b;
	uint8_t *heat = NULL;
	int status = CMD_FAILED;
	bool have_a = reyes_image_read_exr(r.path_a, &a, stderr);
	bool have_b = reyes_image_read_exr(r.path_b, &b, stderr);
	if (!have_a || !have_b)
		goto done;
	if (a.width != b.width || a.height != b.height) {
		fprintf(stderr, "relight diff: error: the images differ in size: %s is %" PRIu32
			"x%" PRIu32 ", %s is %" PRIu32 "x%" PRIu32 "\n", r.path_a, a.width,
			a.height, r.path_b, b.width, b.height);
		goto done;
	}
	r.width = a.width;
	r.height = a.height;

	/* The colour channels: those of R, G, B that the images have; the same in both. */
	static const char *const rgb[3] = { "R", "G", "B" };
	int ca[3], cb[3];
	bool same = true;
	for (int k = 0; k < 3; k++) {
		int ia = find_channel(&a, rgb[k]), ib = find_channel(&b, rgb[k]);
		same = same && (ia < 0) == (ib < 0);
		if (ia >= 0 && ib >= 0) {
			ca[r.nchannels] = ia;
			cb[r.nchannels] = ib;
			r.channels[r.nchannels++] = rgb[k];
		}
	}
	if (!same || r.nchannels == 0) {
		char la[256], lb[256];
		list_channels(&a, la, sizeof(la));
		list_channels(&b, lb, sizeof(lb));
		fprintf(stderr, "relight diff: error: the images have %s colour channels "
			"(R, G, B): %s has %s; %s has %s\n", same ? "no" : "different", r.path_a,
			la, r.path_b, lb);
		goto done;
	}
	int aa = find_channel(&a, "A"), ab = find_channel(&b, "A");
	r.has_alpha = aa >= 0 && ab >= 0;
	if (!r.has_alpha && (aa >= 0 || ab >= 0))
		r.alpha_only = aa >= 0 ? r.path_a : r.path_b;

	if (heatmap) {
		heat = malloc((size_t)r.width * r.height * 3);
		if (!heat) {
			fprintf(stderr, "relight diff: error: out of memory for a %" PRIu32 "x%" PRIu32
				" heat map\n", r.width, r.height);
			goto done;
		}
	}
	measure(&a, &b, ca, cb, r.nchannels, true, &r.colour);
	if (r.has_alpha)
		measure(&a, &b, &aa, &ab, 1, false, &r.alpha);
	if (heat)
		heat_map(&a, &b, ca, cb, r.nchannels, scale / 100.0, heat);

	status = CMD_OK;
	if (heat && !reyes_png_write(heatmap, heat, r.width, r.height, 3, stderr)) {
		r.heatmap = NULL;
		status = CMD_FAILED;
	}
	if (json)
		print_json(stdout, &r);
	else
		print_text(stdout, &r);
	double max_pct = img_error_max_pct(&r.colour);
	if (fail_above >= 0.0 && max_pct > fail_above) {
		fprintf(stderr, "relight diff: the maximum error, %.4f %%, is above --fail-above "
			"%g %%\n", max_pct, fail_above);
		status = CMD_FAILED;
	}
	if (fail_rel >= 0.0 && r.colour.max_rel > fail_rel) {
		fprintf(stderr, "relight diff: the largest relative difference, %.3g, is above "
			"--fail-rel %g\n", r.colour.max_rel, fail_rel);
		status = CMD_FAILED;
	}
done:
	free(heat);
	if (have_a)
		reyes_image_finish(&a);
	if (have_b)
		reyes_image_finish(&b);
	return status;
}

/*
 * relight info: what a shot file holds — image, lights, surfaces, and the
 * figures of lightspeed-2007's Fig. 5 and Fig. 10 (shading samples kept of
 * those shaded, indirect entries against subpixel samples, channels, bytes).
 */
#include "cmd.h"
#include "shotfile.h"
#include "shotmeta.h"

#include <cjson/cJSON.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight info [--json] SHOT.exr\n"
		"\n"
		"Describe a shot file written by 'relight bake': image size, lights, surface\n"
		"shaders, and how much the bake kept: grid points shaded and shading samples\n"
		"kept, subpixel samples and indirect-framebuffer entries, cached channels per\n"
		"sample (dynamic: all; varying: not constant over the frame; unique: varying\n"
		"and equal to no other), and the bytes each part takes in the file.\n"
		"Only headers are read; the data is not checked (the preview checks it).\n"
		"\n"
		"Options:\n"
		"  --json       One JSON object with keys width, height, lights, surfaces,\n"
		"               shaded_points, shading_samples, subpixel_samples,\n"
		"               indirect_entries, channels {dynamic, varying, unique,\n"
		"               half, float}, sample_rows, tiles, tile_size, shadow_points,\n"
		"               shadow_quads, shadow_bytes, shadow_opacity, levels\n"
		"               [{block, samples, entries}], bytes {PART: N},\n"
		"               total_bytes, format, specular_model (\"prman\" or\n"
		"               \"rispec\": the highlight of specular() the shot was\n"
		"               baked and is previewed with), imager (its imager\n"
		"               shader's name, or null)\n"
		"  -h, --help   Show this help and exit\n"
		"\n"
		"Exit status: 0 on success, 1 when the file cannot be read as a shot file,\n"
		"2 on a usage error.\n");
}

#define usage_error(...) cmd_usage_error("info", __VA_ARGS__)

static double num(const cJSON *o, const char *key)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	return cJSON_IsNumber(v) ? v->valuedouble : 0.0;
}

int cmd_info(int argc, char **argv)
{
	bool json = false;
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "json", no_argument, NULL, 'j' },
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
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (optind >= argc)
		return usage_error("no shot file");
	if (optind + 1 < argc)
		return usage_error("one shot file expected; extra argument '%s'", argv[optind + 1]);
	const char *path = argv[optind];
	char err[1024] = "";
	struct shot_file *f = shot_read_header(path, err, sizeof(err));
	if (!f) {
		fprintf(stderr, "relight info: error: %s\n", err);
		return CMD_FAILED;
	}
	cJSON *meta = cJSON_Parse(f->metadata ? f->metadata : "");
	if (!cJSON_IsObject(meta)) {
		fprintf(stderr, "relight info: error: %s: the metadata is not a JSON object\n", path);
		cJSON_Delete(meta);
		shot_free(f);
		return CMD_FAILED;
	}
	const cJSON *fig = cJSON_GetObjectItemCaseSensitive(meta, "figures");
	const cJSON *chn = cJSON_GetObjectItemCaseSensitive(fig, "channels");
	cJSON *out = cJSON_CreateObject();
	cJSON_AddNumberToObject(out, "format", num(meta, "format"));
	cJSON_AddNumberToObject(out, "width", num(meta, "width"));
	cJSON_AddNumberToObject(out, "height", num(meta, "height"));
	enum sl_specular_model model;
	bool model_ok = shot_meta_specular_model(meta, &model);
	cJSON_AddStringToObject(out, "specular_model",
				model_ok ? sl_specular_model_name(model) : "unknown");
	cJSON *lights = cJSON_AddArrayToObject(out, "lights");
	const cJSON *l;
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(meta, "lights")) {
		const cJSON *n = cJSON_GetObjectItemCaseSensitive(l, "name");
		cJSON_AddItemToArray(lights, cJSON_CreateString(cJSON_IsString(n) ? n->valuestring
								     : ""));
	}
	/* the imager shader, edited as "imager" (shotmeta.h SHOT_IMAGER) */
	const cJSON *im = cJSON_GetObjectItemCaseSensitive(meta, "imager");
	const cJSON *imname = cJSON_GetObjectItemCaseSensitive(im, "shader");
	if (cJSON_IsString(imname))
		cJSON_AddStringToObject(out, "imager", imname->valuestring);
	else
		cJSON_AddNullToObject(out, "imager");
	cJSON *surfs = cJSON_AddArrayToObject(out, "surfaces");
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(meta, "surfaces")) {
		const cJSON *n = cJSON_GetObjectItemCaseSensitive(l, "shader");
		cJSON_AddItemToArray(surfs, cJSON_CreateString(cJSON_IsString(n) ? n->valuestring
								    : ""));
	}
	static const char *const figs[] = { "shaded_points", "shading_samples",
					    "subpixel_samples", "indirect_entries" };
	for (size_t i = 0; i < sizeof(figs) / sizeof(figs[0]); i++)
		cJSON_AddNumberToObject(out, figs[i], num(fig, figs[i]));
	cJSON *c = cJSON_AddObjectToObject(out, "channels");
	cJSON_AddNumberToObject(c, "dynamic", num(chn, "dynamic"));
	cJSON_AddNumberToObject(c, "varying", num(chn, "varying"));
	cJSON_AddNumberToObject(c, "unique", num(chn, "unique"));
	cJSON_AddNumberToObject(c, "half", num(chn, "half"));
	cJSON_AddNumberToObject(c, "float", num(chn, "float"));
	cJSON_AddNumberToObject(out, "sample_rows", num(fig, "sample_rows"));
	cJSON_AddNumberToObject(out, "tiles", num(fig, "tiles"));
	const cJSON *tiling = cJSON_GetObjectItemCaseSensitive(meta, "tiling");
	cJSON_AddNumberToObject(out, "tile_size", num(tiling, "tile_size"));
	cJSON_AddNumberToObject(out, "shadow_points", num(fig, "shadow_points"));
	cJSON_AddNumberToObject(out, "shadow_quads", num(fig, "shadow_quads"));
	cJSON *levels = cJSON_AddArrayToObject(out, "levels");
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(meta, "levels")) {
		cJSON *lj = cJSON_CreateObject();
		cJSON_AddNumberToObject(lj, "block", num(l, "block"));
		cJSON_AddNumberToObject(lj, "samples", num(l, "samples"));
		cJSON_AddNumberToObject(lj, "entries", num(l, "entries"));
		cJSON_AddItemToArray(levels, lj);
	}
	cJSON *bytes = cJSON_AddObjectToObject(out, "bytes");
	double total = 0;
	for (uint32_t i = 0; i < f->ntables + f->ndeeps; i++) {
		const char *name = i < f->ntables ? f->tables[i].name : f->deeps[i - f->ntables].name;
		double b = f->part_bytes ? (double)f->part_bytes[i] : 0.0;
		cJSON_AddNumberToObject(bytes, name, b);
		total += b;
	}
	cJSON_AddNumberToObject(out, "total_bytes", total);
	/* the shadow geometry: its two tables; the opacity deep maps need, or none
	   (a shot baked before it was recorded) */
	double shadow_bytes = 0;
	for (uint32_t i = 0; f->part_bytes && i < f->ntables; i++)
		if (!strncmp(f->tables[i].name, "shadow.", 7))
			shadow_bytes += (double)f->part_bytes[i];
	const cJSON *sg = cJSON_GetObjectItemCaseSensitive(meta, "shadow_geometry");
	bool shadow_opacity = cJSON_IsString(cJSON_GetObjectItemCaseSensitive(sg, "opacity"));
	cJSON_AddNumberToObject(out, "shadow_bytes", shadow_bytes);
	/* ray-traced shadows on the GPU: 48 bytes a triangle, two a micropolygon,
	   and fewer than two 32-byte nodes a triangle (gpu/shadowbvh.h) */
	double rt_bytes = num(fig, "shadow_quads") * 2 * (48 + 2 * 32);
	cJSON_AddNumberToObject(out, "shadow_bvh_bytes_max", rt_bytes);
	cJSON_AddBoolToObject(out, "shadow_opacity", shadow_opacity);

	if (json) {
		char *s = cJSON_Print(out);
		if (s)
			puts(s);
		free(s);
	} else {
		double sp = num(fig, "shaded_points"), ss = num(fig, "shading_samples");
		double sub = num(fig, "subpixel_samples"), ie = num(fig, "indirect_entries");
		printf("%s: shot format %g, %gx%g\n", path, num(meta, "format"), num(meta, "width"),
		       num(meta, "height"));
		printf("lights (%d):", cJSON_GetArraySize(lights));
		cJSON_ArrayForEach(l, lights)
			printf(" %s", l->valuestring);
		printf("\nsurface shaders (%d):", cJSON_GetArraySize(surfs));
		cJSON_ArrayForEach(l, surfs)
			printf(" %s", l->valuestring);
		if (cJSON_IsString(imname))
			printf("\nimager: %s (edited as '%s')", imname->valuestring, SHOT_IMAGER);
		printf("\nspecular model: %s",
		       model_ok ? sl_specular_model_name(model) : "unknown");
		printf("\nshading samples: %.0f kept of %.0f shaded (%.2fx fewer)\n", ss, sp,
		       ss > 0 ? sp / ss : 0.0);
		printf("indirect entries: %.0f for %.0f subpixel samples (%.2fx fewer)\n", ie, sub,
		       ie > 0 ? sub / ie : 0.0);
		printf("channels per sample: %g dynamic, %g varying, %g unique (%g half, %g float)\n",
		       num(chn, "dynamic"), num(chn, "varying"), num(chn, "unique"),
		       num(chn, "half"), num(chn, "float"));
		double ts = num(tiling, "tile_size");
		if (ts > 0)
			printf("tiles: %g of %gx%g pixels, %.0f sample rows\n", num(fig, "tiles"), ts,
			       ts, num(fig, "sample_rows"));
		else
			printf("tiles: 1 (the whole frame)\n");
		if (num(fig, "shadow_quads") > 0)
			printf("shadow geometry: %.0f micropolygons, %.0f points, %s (%.0f bytes)\n",
			       num(fig, "shadow_quads"), num(fig, "shadow_points"),
			       shadow_opacity ? "with their opacity for deep maps"
					      : "no opacity (deep maps are not rendered from it)",
			       shadow_bytes);
		if (num(fig, "shadow_quads") > 0)
			printf("ray-traced shadows: a hierarchy of at most %.0f bytes in GPU memory "
			       "once a light's shadow is \"raytrace\"\n", rt_bytes);
		printf("refinement levels:\n");
		int k = 0;
		cJSON_ArrayForEach(l, levels) {
			double bl = num(l, "block");
			const char *what = bl == 4 ? "4x4 pixel blocks" : bl == 2 ? "2x2 pixel blocks"
					 : k == 2 ? "one entry per pixel" : "all entries";
			printf("  %d: %-22s %10.0f samples %10.0f entries\n", k, what,
			       num(l, "samples"), num(l, "entries"));
			k++;
		}
		printf("bytes: %.0f in all\n", total);
		const cJSON *b;
		cJSON_ArrayForEach(b, bytes)
			printf("  %-24s %12.0f\n", b->string, b->valuedouble);
	}
	cJSON_Delete(out);
	cJSON_Delete(meta);
	shot_free(f);
	return CMD_OK;
}

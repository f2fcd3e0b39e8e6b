/*
 * relight preview: the preview of a shot file, headless. By default the GPU
 * runtime (gpu/runtime.h) loads the shot, renders it from nothing to the
 * final level, applies the --set edits and refines the edited image level
 * by level, timing each step. With --cpu it shades the samples on the grid
 * interpreter instead (the ground truth of the GPU runtime).
 */
#include "cmd.h"
#include "graph.h"
#include "bake/resolve.h"
#include "runtime.h"
#include "shadowrender.h"
#include "png.h"
#include "shotfile.h"
#include "texture.h"

#include <getopt.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight preview [--cpu] [--set LIGHT.PARAM=V[,V,V]]... [--follow LIGHT]...\n"
		"                       [--level N|final] [-o OUT.exr] [--json] SHOT.exr\n"
		"\n"
		"Relight a shot file written by 'relight bake' and write the image.\n"
		"\n"
		"By default the shot is loaded into GPU memory (through EGL: a GPU, or Mesa's\n"
		"llvmpipe where there is none), rendered from nothing to the final level with\n"
		"every light in the light cache, then the --set edits are applied and the\n"
		"image refined level by level, as an interactive session would see it.\n"
		"\n"
		"With --cpu every shading sample is shaded by its surface's dynamic program on\n"
		"relight's shading-language interpreter, the lights run whole as in 'relight\n"
		"render', and each pixel is resolved from its indirect-framebuffer entries:\n"
		"the CPU reference that the GPU preview must match. Shadow maps and textures\n"
		"are looked up as at bake time, relative to the current directory.\n"
		"\n"
		"Options:\n"
		"  --cpu                Shade on the CPU interpreter instead of the GPU\n"
		"  --level N|final      The refinement level to resolve: 0, one sample per 4x4\n"
		"                       pixel block; 1, per 2x2 block; 2, one sample per pixel\n"
		"                       (the heaviest); 3 or final (default), every sample\n"
		"                       with its antialiasing, motion blur and transparency\n"
		"                       weight. Only the samples a level uses are shaded.\n"
		"  --set LIGHT.PARAM=V[,V,V]\n"
		"                       Edit a light: LIGHT is its name (the RIB handle, as\n"
		"                       'relight info' lists them), PARAM one of its shader's\n"
		"                       parameters; one value for a float (or a grey colour),\n"
		"                       three for a colour, point or vector (points and\n"
		"                       vectors in the light's own space, as in the RIB),\n"
		"                       sixteen for a matrix, the text for a string (a map's\n"
		"                       name: uberlight's slidename; nothing after '=' for the\n"
		"                       empty string, no map). Repeatable. LIGHT 'imager'\n"
		"                       edits the shot's imager shader instead (RIB Imager),\n"
		"                       which runs on the final pixels after the resolve\n"
		"  --follow LIGHT       On the GPU, the light's shadow maps follow it: each is\n"
		"                       rendered from the shot's shadow geometry from the\n"
		"                       light's 'from' towards its 'to' (depth and deep maps\n"
		"                       alike). Repeatable. With --cpu, a warning: the CPU\n"
		"                       preview reads the maps as baked\n"
		"  -o, --output FILE    The image (OpenEXR, RGBA float; default: SHOT with\n"
		"                       .shot.exr replaced by .preview.exr). On the GPU, a\n"
		"                       name ending in .png writes the runtime's 8-bit sRGB\n"
		"                       output (colour over black, alpha)\n"
		"  --half               On the GPU, write the runtime's linear half output\n"
		"                       (RGBA half floats) instead of float\n"
		"  --json               Print timings and counts as one JSON object. On the GPU:\n"
		"                       full_ms (every light, from nothing to the final level),\n"
		"                       full_shaded and full_batched ((sample, light) pairs\n"
		"                       shaded for it, and those shaded in batches of lights),\n"
		"                       edit_ms (after the --set edits, levels 0 to 3 refined\n"
		"                       in turn with the light cache warm), levels (per level:\n"
		"                       ms, entries resolved, samples shaded, kernels run),\n"
		"                       programs_at_load and programs_by_edits (GPU programs\n"
		"                       made before the edits and by them: an edit makes none),\n"
		"                       texture_maps and texture_map_bytes (the texture and\n"
		"                       environment maps the lights read, in GPU memory),\n"
		"                       deep_maps_rendered and, of the last one, deep_hits,\n"
		"                       deep_max_texel_hits, deep_nodes, deep_map_bytes and\n"
		"                       deep_scratch_bytes (deep shadow maps rendered from the\n"
		"                       shadow geometry), shadow_bvh_bytes, shadow_bvh_nodes\n"
		"                       and shadow_bvh_triangles (the hierarchy ray-traced\n"
		"                       shadows trace, 0 when no light's shadow is \"raytrace\")\n"
		"                       and graph (the computation graph's\n"
		"                       nodes and their runs)\n"
		"  -q, --quiet          No summary\n"
		"  -h, --help           Show this help and exit\n"
		"\n"
		"Exit status: 0 on success, 1 when the shot cannot be read or resolved, 2 on a\n"
		"usage error, 3 when the image was written but is not the shot's: a shadow\n"
		"map or texture it reads could not be read (named in a warning), so its\n"
		"lookups gave their fill value.\n");
}

#define usage_error(...) cmd_usage_error("preview", __VA_ARGS__)

/* The exit status of an image written with maps missing: not the shot's image. */
enum { CMD_NOT_THE_SHOT = 3 };

/*
 * @rc, or CMD_NOT_THE_SHOT when it is CMD_OK but maps could not be read
 * since @unread (reyes_tex_unread_maps() before the preview).
 */
static int check_maps(int rc, uint64_t unread, const char *output)
{
	uint64_t missing = reyes_tex_unread_maps() - unread;
	if (rc != CMD_OK || missing == 0)
		return rc;
	fprintf(stderr, "relight preview: error: %s is not the shot's image: %llu shadow map%s or "
		"texture%s could not be read (see the warnings; run where 'relight bake' ran, "
		"beside the maps)\n", output, (unsigned long long)missing, missing > 1 ? "s" : "",
		missing > 1 ? "s" : "");
	return CMD_NOT_THE_SHOT;
}

static char *default_output(const char *shot)
{
	size_t n = strlen(shot);
	size_t base = n > 9 && !strcmp(shot + n - 9, ".shot.exr") ? n - 9 :
		      n > 4 && !strcmp(shot + n - 4, ".exr") ? n - 4 : n;
	char *out = malloc(base + 16);
	if (out)
		snprintf(out, base + 16, "%.*s.preview.exr", (int)base, shot);
	return out;
}

static bool write_rgba(const char *path, uint32_t w, uint32_t h, float *rgba)
{
	static const char *const names[4] = { "R", "G", "B", "A" };
	struct reyes_image im = { .width = w, .height = h, .nchannels = 4,
				  .channel_names = (const char **)names, .data = rgba };
	return reyes_image_write_exr(path, &im, false, stderr);
}

/* The preview on the GPU runtime. */
static bool ends_with(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && !strcmp(s + n - m, suffix);
}

/* Write level @level of @s: PNG (the GPU's 8-bit sRGB), EXR of half or float. */
static bool write_gpu_image(struct gpu_shot *s, int level, const char *path, bool half)
{
	uint32_t w = gpu_shot_width(s), h = gpu_shot_height(s);
	size_t n = (size_t)w * h;
	bool ok;
	if (ends_with(path, ".png")) {
		uint32_t *px = malloc(n * sizeof(uint32_t) + 4);
		uint8_t *rgba = malloc(n * 4 + 4);
		ok = px && rgba && gpu_shot_read_srgb8(s, level, px);
		for (size_t i = 0; ok && i < n; i++)
			for (int c = 0; c < 4; c++)
				rgba[i * 4 + (size_t)c] = (uint8_t)(px[i] >> (8 * c));
		ok = ok && reyes_png_write(path, rgba, w, h, 4, stderr);
		free(px);
		free(rgba);
		return ok;
	}
	float *f = malloc(n * 4 * sizeof(float) + 4);
	uint16_t *hv = half ? malloc(n * 4 * sizeof(uint16_t) + 4) : NULL;
	ok = f && (half ? hv && gpu_shot_read_half(s, level, hv) : gpu_shot_read_rgba(s, level, f));
	for (size_t i = 0; ok && half && i < n * 4; i++)
		f[i] = shot_half_value(hv[i]);
	static const char *const names[4] = { "R", "G", "B", "A" };
	struct reyes_image im = { .width = w, .height = h, .nchannels = 4,
				  .channel_names = (const char **)names, .data = f };
	ok = ok && reyes_image_write_exr(path, &im, half, stderr);
	free(f);
	free(hv);
	return ok;
}

static int preview_gpu(const char *shot, const char *output, int level,
		       const struct resolve_edit *edits, size_t nedits, char *const *follow,
		       size_t nfollow, bool json, bool quiet, bool half)
{
	char err[1024];
	struct gpu_ctx *ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		fprintf(stderr, "relight: error: no GPU context (%s); 'relight preview --cpu' "
			"previews on the CPU\n", err);
		return CMD_FAILED;
	}
	struct gpu_shot_opts so = { .diag = stderr, .texture_path = ".", .progress = !quiet && !json };
	struct gpu_shot *s = gpu_shot_open(ctx, shot, &so);
	bool ok = s != NULL;
	struct gpu_shot_stats full = { 0 }, lv[GPU_SHOT_LEVELS];
	memset(lv, 0, sizeof(lv));
	ok = ok && gpu_shot_render(s, GPU_SHOT_FINAL, &full);
	/* programs made (compiled, or read from the disk cache) before the edits */
	unsigned hits0 = 0, built0 = 0, hits1 = 0, built1 = 0;
	gpu_program_stats(ctx, &hits0, &built0);
	for (size_t i = 0; ok && i < nfollow; i++) {
		if (!gpu_shot_shadow_follow(s, follow[i], true, err, sizeof(err))) {
			fprintf(stderr, "relight: error: --follow %s: %s\n", follow[i], err);
			ok = false;
		}
	}
	for (size_t i = 0; ok && i < nedits; i++) {
		const struct resolve_edit *e = &edits[i];
		bool is_string = e->nvalues == 0 && gpu_shot_param_is_string(s, e->light, e->param);
		if (is_string ? !gpu_shot_set_string(s, e->light, e->param, e->text, err,
						     sizeof(err))
			      : e->nvalues == 0 ? snprintf(err, sizeof(err), "light '%s': parameter "
							   "'%s' needs numbers, not '%s'", e->light,
							   e->param, e->text) >= 0
			      : !gpu_shot_set(s, e->light, e->param, e->values, e->nvalues, err,
					      sizeof(err))) {
			fprintf(stderr, "relight: error: %s\n", err);
			ok = false;
		}
	}
	double edit_ms = 0;
	for (int L = 0; ok && L < GPU_SHOT_LEVELS; L++) {
		ok = gpu_shot_render(s, L, &lv[L]);
		edit_ms += lv[L].ms;
	}
	gpu_program_stats(ctx, &hits1, &built1);
	uint32_t w = s ? gpu_shot_width(s) : 0, h = s ? gpu_shot_height(s) : 0;
	ok = ok && write_gpu_image(s, level, output, half);
	if (ok && json) {
		printf("{\"device\": \"%s\", \"width\": %u, \"height\": %u, \"level\": %d, "
		       "\"samples\": %llu, \"lights\": %u, \"gpu_bytes\": %zu, "
		       "\"full_ms\": %.3f, \"full_shaded\": %llu, \"full_batched\": %llu, "
		       "\"edit_ms\": %.3f, \"levels\": [",
		       gpu_renderer(ctx), w, h, level, (unsigned long long)gpu_shot_samples(s),
		       gpu_shot_light_count(s), gpu_shot_bytes(s), full.ms,
		       (unsigned long long)full.shaded, (unsigned long long)full.batched, edit_ms);
		for (int L = 0; L < GPU_SHOT_LEVELS; L++)
			printf("%s{\"level\": %d, \"ms\": %.3f, \"entries\": %llu, \"shaded\": %llu, "
			       "\"dispatches\": %u}", L ? ", " : "", L, lv[L].ms,
			       (unsigned long long)lv[L].entries, (unsigned long long)lv[L].shaded,
			       lv[L].dispatches);
		size_t tbytes = 0;
		uint32_t nmaps = gpu_shot_texmaps(s, &tbytes);
		printf("], \"programs_at_load\": %u, \"programs_by_edits\": %u, \"texture_maps\": %u, "
		       "\"texture_map_bytes\": %zu", hits0 + built0, hits1 + built1 - hits0 - built0,
		       nmaps, tbytes);
		struct gpu_deep_stats ds;
		uint32_t ndeep = gpu_shot_deep_stats(s, &ds);
		printf(", \"deep_maps_rendered\": %u, \"deep_hits\": %llu, \"deep_max_texel_hits\": "
		       "%u, \"deep_nodes\": %llu, \"deep_map_bytes\": %zu, \"deep_scratch_bytes\": %zu",
		       ndeep, (unsigned long long)ds.hits, ds.max_hits,
		       (unsigned long long)ds.nodes, ds.bytes, ds.scratch_bytes);
		uint32_t bnodes, btris;
		size_t bbytes = gpu_shot_shadow_bvh(s, &bnodes, &btris);
		printf(", \"shadow_bvh_bytes\": %zu, \"shadow_bvh_nodes\": %u, "
		       "\"shadow_bvh_triangles\": %u", bbytes, bnodes, btris);
		printf(", \"output\": \"%s\", \"graph\": ", output);
		graph_print_json(gpu_shot_graph(s), stdout);
		printf("}\n");
	} else if (ok && !quiet && nedits) {
		fprintf(stderr, "wrote %s: %ux%u on %s; every light %.1f ms, the edit%s refined to "
			"the final level in %.1f ms (level 0 in %.1f ms)\n", output, w, h,
			gpu_renderer(ctx), full.ms, nedits > 1 ? "s" : "", edit_ms, lv[0].ms);
	} else if (ok && !quiet) {
		fprintf(stderr, "wrote %s: %ux%u on %s; every light, nothing to the final level, "
			"in %.1f ms\n", output, w, h, gpu_renderer(ctx), full.ms);
	}
	gpu_shot_close(s);
	gpu_destroy(ctx);
	return ok ? CMD_OK : CMD_FAILED;
}

int cmd_preview(int argc, char **argv)
{
	bool cpu = false, json = false, quiet = false, half = false;
	int level = RESOLVE_FINAL;
	enum { MAX_EDITS = 256, MAX_EDIT_LEN = 256 };
	struct resolve_edit edits[MAX_EDITS];
	char copies[MAX_EDITS][MAX_EDIT_LEN];
	size_t nedits = 0, nfollow = 0;
	enum { MAX_FOLLOW = 64 };
	char *follow[MAX_FOLLOW];
	const char *output = NULL;
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "cpu", no_argument, NULL, 'c' },
		{ "level", required_argument, NULL, 'l' },
		{ "set", required_argument, NULL, 's' },
		{ "follow", required_argument, NULL, 'f' },
		{ "output", required_argument, NULL, 'o' },
		{ "json", no_argument, NULL, 'j' },
		{ "half", no_argument, NULL, 'H' },
		{ "quiet", no_argument, NULL, 'q' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt;
	while ((opt = getopt_long(argc, argv, ":ho:q", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'c':
			cpu = true;
			break;
		case 'l':
			if (!strcmp(optarg, "final")) {
				level = RESOLVE_FINAL;
			} else if (optarg[0] >= '0' && optarg[0] <= '0' + RESOLVE_FINAL &&
				   !optarg[1]) {
				level = optarg[0] - '0';
			} else {
				return usage_error("--level needs 0, 1, 2, 3 or final, not '%s'",
						   optarg);
			}
			break;
		case 's':
			if (nedits == MAX_EDITS)
				return usage_error("at most %d --set edits", MAX_EDITS);
			memset(&edits[nedits], 0, sizeof(edits[nedits]));
			{
				int rc = cmd_set_option("preview", optarg, copies[nedits], MAX_EDIT_LEN,
							&edits[nedits].light, &edits[nedits].param,
							edits[nedits].values, &edits[nedits].nvalues,
							&edits[nedits].text);
				if (rc != CMD_OK)
					return rc;
			}
			nedits++;
			break;
		case 'f':
			if (nfollow == MAX_FOLLOW)
				return usage_error("at most %d --follow lights", MAX_FOLLOW);
			follow[nfollow++] = optarg;
			break;
		case 'o':
			output = optarg;
			break;
		case 'j':
			json = true;
			break;
		case 'H':
			half = true;
			break;
		case 'q':
			quiet = true;
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (optind >= argc)
		return usage_error("no shot file");
	if (optind + 1 < argc)
		return usage_error("one shot file expected; extra argument '%s'", argv[optind + 1]);
	const char *shot = argv[optind];
	char *out_alloc = output ? NULL : default_output(shot);
	if (!output)
		output = out_alloc;
	if (cpu && (half || ends_with(output ? output : "", ".png"))) {
		free(out_alloc);
		return usage_error("--half and PNG output are the GPU runtime's; not with --cpu");
	}
	uint64_t unread = reyes_tex_unread_maps();
	if (!cpu) {
		int rc = output ? preview_gpu(shot, output, level, edits, nedits, follow, nfollow, json,
					      quiet, half)
				: CMD_FAILED;
		rc = check_maps(rc, unread, output);
		free(out_alloc);
		return rc;
	}
	/* the CPU resolver reads the maps the bake named, depth and deep alike */
	for (size_t i = 0; i < nfollow; i++)
		fprintf(stderr, "relight: warning: --follow %s: the CPU preview reads the light's "
			"shadow maps as baked; they follow the light on the GPU only\n", follow[i]);
	struct resolve_opts ro = { .diag = stderr, .texture_path = ".", .level = level,
				   .edits = edits, .nedits = nedits };
	struct resolve_result res;
	bool ok = output && resolve_cpu(shot, &ro, &res);
	if (ok) {
		ok = write_rgba(output, res.width, res.height, res.rgba);
		if (ok && json)
			printf("{\"width\": %u, \"height\": %u, \"level\": %d, \"samples\": %llu, "
			       "\"entries\": %llu, "
			       "\"load_ms\": %.3f, \"shade_ms\": %.3f, \"resolve_ms\": %.3f, "
			       "\"output\": \"%s\"}\n", res.width, res.height, level,
			       (unsigned long long)res.samples, (unsigned long long)res.entries,
			       res.load_seconds * 1e3, res.shade_seconds * 1e3,
			       res.resolve_seconds * 1e3, output);
		else if (ok && !quiet)
			fprintf(stderr, "wrote %s: %ux%u, %llu samples shaded in %.2f s, %llu entries "
				"resolved in %.3f s\n", output, res.width, res.height,
				(unsigned long long)res.samples, res.shade_seconds,
				(unsigned long long)res.entries, res.resolve_seconds);
		free(res.rgba);
	}
	int rc = check_maps(ok ? CMD_OK : CMD_FAILED, unread, output);
	free(out_alloc);
	return rc;
}

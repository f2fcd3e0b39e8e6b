/*
 * relight bake: render a RIB scene in bake mode and write the shot file the
 * preview reads (daemon/bake/bake.h).
 */
#include "cmd.h"
#include "exec.h"
#include "bake.h"
#include "memlimit.h"
#include "config.h"

#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight bake [OPTIONS] SCENE.rib\n"
		"\n"
		"Bake a RIB scene for interactive relighting: render it with relight's REYES\n"
		"renderer, each surface shader replaced by its caching program (the part that\n"
		"does not depend on the lights or on editable parameters), keep every shading\n"
		"sample's cached values and, per pixel, the weight of each sample that reaches\n"
		"it, and write everything to one shot file (multi-part OpenEXR).\n"
		"Shadow-pass frames (every display a depth map) are rendered as they are, so\n"
		"that the shadow maps the lights read exist; the first other frame is baked.\n"
		"\n"
		"Options:\n"
		"  -o, --output FILE        The shot file (default: SCENE.shot.exr next to the\n"
		"                           scene, with the .rib suffix dropped)\n"
		"  --dynamic-surface P1,... Surface parameters a user may edit in the preview\n"
		"                           (in every surface shader that has them)\n"
		"  --compress MODE          none (default), rle, zips or zip: how the shot's\n"
		"                           parts are compressed (zip only for the sample\n"
		"                           tables; the indirect framebuffer then uses zips)\n"
		"  --tile-budget MB         Split the frame into screen tiles of at most MB\n"
		"                           megabytes of samples and entries each (default:\n"
		"                           %llu; the frame is one tile when it fits)\n"
		"  --shadow-rate R          Dice the shadow geometry of shadow-casting lights\n"
		"                           to micropolygons of R pixels' area (as ShadingRate;\n"
		"                           default: %g)\n"
		"  --full-float             Store every channel as 32-bit float (default: half\n"
		"                           where it holds the values: colours, normals and\n"
		"                           vectors in half's range, exact halves)\n"
		"  -t, --threads N          Render with N threads (default: all cores)\n"
		"  --memory-limit SIZE      Refuse a frame estimated to need more than SIZE\n"
		"                           bytes (8G, 512M, ...; default: 3/4 of the memory,\n"
		"                           physical or the cgroup's), naming the Format,\n"
		"                           PixelSamples or ShadingRate to change\n"
		"  -I, --include DIR        Look in DIR for shaders' #include files, after the\n"
		"                           shader's own folder (repeatable, in order; the\n"
		"                           scene's Option \"searchpath\" \"include\" replaces\n"
		"                           the list, '@' in it standing for the -I folders)\n"
		"  --strict                 Every warning of the scene is an error: a scene\n"
		"                           with any is not baked\n"
		"  -q, --quiet              No progress bar and no summary\n"
		"  -h, --help               Show this help and exit\n"
		"\n"
		"Shaders are looked up along the scene's Option \"searchpath\" \"shader\", by\n"
		"default $RELIGHT_SHADER_PATH, then $RMAN_SHADERPATH, then the standard library\n"
		"(%s): first a file NAME.sl, then a .sl file along the path that declares\n"
		"the shader NAME; \"null\" is the built-in shader that does nothing.\n"
		"\n"
		"What relight does not support in the scene is a warning (FILE:LINE: warning:)\n"
		"naming what is ignored, and the shot is baked; a primitive whose data is\n"
		"malformed is an error that drops it, the rest is baked.\n"
		"\n"
		"Exit status: 0 on success, warnings or not; 1 when the scene has errors\n"
		"(reported with the file and line: a primitive dropped, or nothing baked), a\n"
		"warning under --strict, or it cannot be baked; 2 on a usage error.\n",
		BAKE_DEFAULT_TILE_BUDGET >> 20, (double)BAKE_DEFAULT_SHADOW_RATE,
		RELIGHT_SOURCE_SHADER_DIR);
}

#define usage_error(...) cmd_usage_error("bake", __VA_ARGS__)

struct bake_job {
	struct bake_opts bo;
	const char *output;
	bool quiet;
};

/* Split "a,b,c" into a NULL-terminated array (one malloc'd block). */
static char **split_list(const char *s, size_t *n)
{
	size_t len = strlen(s), count = 1;
	for (const char *p = s; *p; p++)
		count += *p == ',';
	char **v = malloc((count + 1) * sizeof(char *) + len + 1);
	if (!v)
		return NULL;
	char *text = (char *)(v + count + 1);
	memcpy(text, s, len + 1);
	*n = 0;
	for (char *tok = text, *e; tok; tok = e) {
		e = strchr(tok, ',');
		if (e)
			*e++ = '\0';
		if (*tok)
			v[(*n)++] = tok;
	}
	v[*n] = NULL;
	return v;
}

static char *default_output(const char *scene)
{
	size_t n = strlen(scene);
	const char *ext = n > 4 && !strcmp(scene + n - 4, ".rib") ? scene + n - 4 :
			  n > 7 && !strcmp(scene + n - 7, ".rib.gz") ? scene + n - 7 : scene + n;
	size_t base = (size_t)(ext - scene);
	char *out = malloc(base + 16);
	if (out)
		snprintf(out, base + 16, "%.*s.shot.exr", (int)base, scene);
	return out;
}

int cmd_bake(int argc, char **argv)
{
	struct bake_job job = { 0 };
	char **dyn = NULL;
	char *out_alloc = NULL;
	char includes[8192] = "";
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "include", required_argument, NULL, 'I' },
		{ "output", required_argument, NULL, 'o' },
		{ "dynamic-surface", required_argument, NULL, 'd' },
		{ "compress", required_argument, NULL, 'c' },
		{ "threads", required_argument, NULL, 't' },
		{ "memory-limit", required_argument, NULL, 'm' },
		{ "tile-budget", required_argument, NULL, 'b' },
		{ "shadow-rate", required_argument, NULL, 'r' },
		{ "full-float", no_argument, NULL, 'f' },
		{ "quiet", no_argument, NULL, 'q' },
		{ "strict", no_argument, NULL, 'S' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt, rc = CMD_OK;
	while ((opt = getopt_long(argc, argv, ":ho:t:qI:", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			free(dyn);
			return CMD_OK;
		case 'I':
			rc = cmd_add_include("bake", includes, sizeof(includes), optarg);
			if (rc != CMD_OK) {
				free(dyn);
				return rc;
			}
			break;
		case 'o':
			job.output = optarg;
			break;
		case 'd':
			free(dyn);
			dyn = split_list(optarg, &job.bo.ndynamic);
			if (!dyn || !job.bo.ndynamic) {
				free(dyn);
				return usage_error("--dynamic-surface needs parameter names, not '%s'",
						   optarg);
			}
			job.bo.dynamic_surface = (const char *const *)dyn;
			break;
		case 'c':
			if (!strcmp(optarg, "none")) {
				job.bo.write.tables = job.bo.write.deep = SHOT_COMPRESS_NONE;
			} else if (!strcmp(optarg, "rle")) {
				job.bo.write.tables = job.bo.write.deep = SHOT_COMPRESS_RLE;
			} else if (!strcmp(optarg, "zips")) {
				job.bo.write.tables = job.bo.write.deep = SHOT_COMPRESS_ZIPS;
			} else if (!strcmp(optarg, "zip")) {
				job.bo.write.tables = SHOT_COMPRESS_ZIP;
				job.bo.write.deep = SHOT_COMPRESS_ZIPS;
			} else {
				free(dyn);
				return usage_error("--compress needs none, rle, zips or zip, not '%s'",
						   optarg);
			}
			break;
		case 't':
			if (!cmd_parse_uint(optarg, 64, &job.bo.threads) || job.bo.threads == 0) {
				free(dyn);
				return usage_error("--threads needs a number from 1 to 64, not '%s'",
						   optarg);
			}
			break;
		case 'b': {
			double mb;
			if (!cmd_parse_double(optarg, 0.01, 1048576.0, &mb)) {
				free(dyn);
				return usage_error("--tile-budget needs megabytes from 0.01 to 1048576, "
						   "not '%s'", optarg);
			}
			job.bo.tile_budget = (uint64_t)(mb * 1048576.0);
			break;
		}
		case 'r': {
			double r;
			if (!cmd_parse_double(optarg, 0.01, 10000.0, &r)) {
				free(dyn);
				return usage_error("--shadow-rate needs a number from 0.01 to 10000, "
						   "not '%s'", optarg);
			}
			job.bo.shadow_rate = (float)r;
			break;
		}
		case 'f':
			job.bo.full_float = true;
			break;
		case 'm':
			if (!reyes_mem_parse_size(optarg, &job.bo.memory_limit)) {
				free(dyn);
				return usage_error("--memory-limit needs a size such as 8G or 512M, "
						   "not '%s'", optarg);
			}
			break;
		case 'q':
			job.quiet = true;
			break;
		case 'S':
			job.bo.strict = true;
			break;
		case ':':
			free(dyn);
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			free(dyn);
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (optind >= argc || optind + 1 < argc) {
		free(dyn);
		return optind >= argc ? usage_error("no scene file")
				      : usage_error("one scene file expected; extra argument '%s'",
						    argv[optind + 1]);
	}
	const char *path = argv[optind];
	if (access(path, R_OK) != 0) {
		fprintf(stderr, "relight bake: error: cannot read '%s': %s\n", path,
			strerror(errno));
		free(dyn);
		return CMD_FAILED;
	}
	if (!job.output)
		job.output = out_alloc = default_output(path);
	if (job.output && !cmd_check_output(job.output, "relight bake")) {
		free(dyn);
		free(out_alloc);
		return CMD_FAILED;
	}
	job.bo.progress = !job.quiet && isatty(2);
	job.bo.diag = stderr;

	/* Shaders: the default search path ($RELIGHT_SHADER_PATH, $RMAN_SHADERPATH, then
	   the library). */
	job.bo.include_path = includes;
	bool ok = job.output && bake_rib_file(path, job.output, &job.bo, !job.quiet, NULL);
	uint64_t shading, repeats;
	sl_exec_warning_counts(&shading, &repeats);
	if (ok && job.bo.strict && shading) {
		fprintf(stderr, "relight bake: error: the shaders warned %llu time%s: an error "
			"under --strict\n", (unsigned long long)shading, shading == 1 ? "" : "s");
		ok = false;
	}
	if (ok && job.bo.strict && reyes_render_warnings()) {
		fprintf(stderr, "relight bake: error: the renderer left something out (its "
			"warning above): an error under --strict\n");
		ok = false;
	}
	if (!ok)
		rc = CMD_FAILED;
	free(dyn);
	free(out_alloc);
	return rc;
}

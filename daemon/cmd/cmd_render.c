/*
 * relight render: the final-frame reference renderer. Reads a RIB scene and
 * renders each of its frames with the REYES pipeline to the displays it
 * names (OpenEXR).
 */
#include "cmd.h"
#include "reyes.h"
#include "ri.h"
#include "config.h"

#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { MAX_EDITS = 64, MAX_EDIT_LEN = 256 };

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight render [OPTIONS] SCENE.rib\n"
		"\n"
		"Render a RIB scene (plain or gzip-compressed) with relight's REYES renderer,\n"
		"the final-frame reference of every preview. Each frame (FrameBegin..FrameEnd,\n"
		"or WorldBegin..WorldEnd) is written to the displays it names, as OpenEXR.\n"
		"\n"
		"Options:\n"
		"  -o, --output FILE      Write the image to FILE instead of the name in the\n"
		"                         scene's first image Display\n"
		"  -t, --threads N        Render with N threads (default: all cores)\n"
		"  --crop X0 X1 Y0 Y1     Render only pixels X0 <= x < X1, Y0 <= y < Y1 (others\n"
		"                         stay empty); overrides the scene's CropWindow\n"
		"  --bucket N             Bucket size in pixels (default 16)\n"
		"  --set LIGHT.PARAM=V[,V,V]\n"
		"                         Edit a light: LIGHT is its name (the RIB handle, as\n"
		"                         'relight info' lists them), PARAM one of its shader's\n"
		"                         parameters; one value for a float (or a grey colour),\n"
		"                         three for a colour, point or vector (points and\n"
		"                         vectors in the light's own space, as in the RIB),\n"
		"                         sixteen for a matrix. Repeatable (up to %d). The\n"
		"                         value replaces the one the scene gives, in every\n"
		"                         frame, as 'relight preview --set' edits a shot\n"
		"  -q, --quiet            No progress bar and no summary\n"
		"  -h, --help             Show this help and exit\n"
		"\n"
		"Shaders are looked up along the scene's Option \"searchpath\" \"shader\", then in\n"
		"$RELIGHT_SHADER_PATH and the standard library (%s).\n"
		"A progress bar is shown when standard error is a terminal; at the end a summary\n"
		"gives the time, the micropolygons shaded, the subpixel samples and the peak memory.\n"
		"\n"
		"Exit status: 0 on success, 1 when the scene has errors (reported as\n"
		"FILE:LINE: error: MESSAGE; a --set edit that does not fit its light is one)\n"
		"or an image cannot be written, 2 on a usage error.\n",
		MAX_EDITS, RELIGHT_SOURCE_SHADER_DIR);
}

#define usage_error(...) cmd_usage_error("render", __VA_ARGS__)

struct render_job {
	struct reyes_render_opts ro;
	bool quiet;
	int frames;
};

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct render_job *j = user;
	struct reyes_stats st = { 0 };
	j->frames++;
	if (!j->quiet && j->ro.progress)
		fprintf(stderr, "frame %d: %ux%u, %u primitives, %u lights\n", j->frames,
			scene->opts.xres, scene->opts.yres, scene->nprims, scene->nlights);
	if (!reyes_render(scene, &j->ro, &st))
		return false;
	if (!j->quiet) {
		for (uint32_t i = 0; i < scene->opts.ndisplays; i++)
			fprintf(stderr, "wrote %s\n", scene->opts.displays[i].name);
		fprintf(stderr,
			"frame %d: %.2f s, %llu grids, %llu micropolygons shaded, %llu subpixel "
			"samples, peak memory %.1f MB\n",
			j->frames, st.seconds, (unsigned long long)st.grids,
			(unsigned long long)st.micropolygons, (unsigned long long)st.samples,
			(double)st.peak_bytes / (1024.0 * 1024.0));
	}
	return true;
}

int cmd_render(int argc, char **argv)
{
	struct render_job job = { 0 };
	const char *output = NULL;
	struct reyes_light_edit edits[MAX_EDITS];
	char copies[MAX_EDITS][MAX_EDIT_LEN];
	uint32_t nedits = 0;
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "output", required_argument, NULL, 'o' },
		{ "threads", required_argument, NULL, 't' },
		{ "crop", required_argument, NULL, 'c' },
		{ "bucket", required_argument, NULL, 'b' },
		{ "set", required_argument, NULL, 's' },
		{ "quiet", no_argument, NULL, 'q' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt;
	while ((opt = getopt_long(argc, argv, ":ho:t:q", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'o':
			output = optarg;
			break;
		case 't':
			if (!cmd_parse_uint(optarg, 64, &job.ro.threads) || job.ro.threads == 0)
				return usage_error("--threads needs a number from 1 to 64, not '%s'",
						   optarg);
			break;
		case 'b':
			if (!cmd_parse_uint(optarg, 256, &job.ro.bucket_size) || job.ro.bucket_size < 4)
				return usage_error("--bucket needs a number from 4 to 256, not '%s'",
						   optarg);
			break;
		case 'c': {
			/* --crop X0 X1 Y0 Y1: the first value is optarg, three more follow */
			uint32_t v[4];
			if (optind + 3 > argc)
				return usage_error("--crop needs four numbers: X0 X1 Y0 Y1");
			const char *s[4] = { optarg, argv[optind], argv[optind + 1], argv[optind + 2] };
			for (int k = 0; k < 4; k++)
				if (!cmd_parse_uint(s[k], 1u << 20, &v[k]))
					return usage_error("--crop: '%s' is not a pixel coordinate", s[k]);
			optind += 3;
			if (v[1] <= v[0] || v[3] <= v[2])
				return usage_error("--crop: the window %u %u %u %u is empty", v[0], v[1],
						   v[2], v[3]);
			job.ro.crop_x0 = v[0];
			job.ro.crop_x1 = v[1];
			job.ro.crop_y0 = v[2];
			job.ro.crop_y1 = v[3];
			break;
		}
		case 's':
			/* the same checks and messages as relight preview --set */
			if (nedits == MAX_EDITS)
				return usage_error("at most %d --set edits", MAX_EDITS);
			memset(&edits[nedits], 0, sizeof(edits[nedits]));
			{
				int rc = cmd_set_option("render", optarg, copies[nedits], MAX_EDIT_LEN,
							&edits[nedits].light, &edits[nedits].param,
							edits[nedits].values, &edits[nedits].nvalues);
				if (rc != CMD_OK)
					return rc;
			}
			nedits++;
			break;
		case 'q':
			job.quiet = true;
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (optind >= argc)
		return usage_error("no scene file");
	if (optind + 1 < argc)
		return usage_error("one scene file expected; extra argument '%s'", argv[optind + 1]);
	const char *path = argv[optind];
	if (access(path, R_OK) != 0) {
		fprintf(stderr, "relight render: error: cannot read '%s': %s\n", path,
			strerror(errno));
		return CMD_FAILED;
	}
	job.ro.progress = !job.quiet && isatty(2);
	job.ro.diag = stderr;

	char shader_path[8192];
	cmd_shader_path(shader_path, sizeof(shader_path));
	struct reyes_ri_opts ri = {
		.diag = stderr,
		.default_shader_path = shader_path,
		.default_texture_path = ".",
		.output_override = output,
		.light_edits = edits,
		.nlight_edits = nedits,
		.frame = on_frame,
		.user = &job,
	};
	int nerrors = 0;
	bool ok = reyes_ri_read(path, &ri, &nerrors);
	if (ok && job.frames == 0) {
		fprintf(stderr, "%s: error: the scene has no frame (no WorldBegin ... WorldEnd)\n",
			path);
		ok = false;
	}
	return ok ? CMD_OK : CMD_FAILED;
}

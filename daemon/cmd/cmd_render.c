/*
 * relight render: the final-frame reference renderer. Reads a RIB scene and
 * renders each of its frames with the REYES pipeline to the displays it
 * names (OpenEXR or PNG), every output planned before the first frame.
 */
/* realpath() is an X/Open part of POSIX 2008. */
#define _XOPEN_SOURCE 700
#include "cmd.h"
#include "exec.h"
#include "reyes.h"
#include "ri.h"
#include "shader_cache.h"
#include "memlimit.h"
#include "config.h"

#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

enum { MAX_EDITS = 64, MAX_EDIT_LEN = 256 };

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight render [OPTIONS] SCENE.rib\n"
		"\n"
		"Render a RIB scene (plain or gzip-compressed) with relight's REYES renderer,\n"
		"the final-frame reference of every preview. Each frame (FrameBegin..FrameEnd,\n"
		"or WorldBegin..WorldEnd) is written to the displays it names: Display type\n"
		"\"file\" as OpenEXR (PNG when the name ends in .png), \"openexr\", \"png\", and\n"
		"depth maps \"zfile\" and \"shadow\", and deep shadow maps \"deepshad\" (mode\n"
		"\"deepopacity\"). A \"framebuffer\" display is skipped with a warning; any\n"
		"other type or extension (tiff, .jpg) is an error.\n"
		"\n"
		"The whole scene is read and checked first: nothing is rendered or written when\n"
		"it has errors that make a frame meaningless (syntax, unbalanced blocks, a\n"
		"missing shader or archive, an option that cannot work), a --set edit does not\n"
		"fit it, or two outputs (two displays, two frames) would write the same file.\n"
		"What relight does not know or support (a request, option, attribute, shader\n"
		"parameter) is a warning, FILE:LINE: warning: MESSAGE, naming what is ignored:\n"
		"the frame renders. A primitive whose data is malformed is an error that drops\n"
		"that primitive; the rest of the frame renders. Each message is printed once per\n"
		"place (a request an archive repeats reports its line once).\n"
		"\n"
		"Options:\n"
		"  -o, --output FILE      Write each frame's first image display to FILE (.exr,\n"
		"                         no extension: OpenEXR; .png: PNG), its other image\n"
		"                         displays to FILE with their mode before the\n"
		"                         extension (out.N.exr). With several frames, the\n"
		"                         frame number (FrameBegin's) goes before the\n"
		"                         extension: out.0001.exr; or where FILE has a run of\n"
		"                         '#' or a %%d / %%04d: out.####.exr. Shadow passes keep\n"
		"                         their maps' names\n"
		"  -t, --threads N        Render with N threads (default: all cores)\n"
		"  --crop X0 X1 Y0 Y1     Render only pixels X0 <= x < X1, Y0 <= y < Y1 (others\n"
		"                         stay empty); overrides the scene's CropWindow\n"
		"  --bucket N             Bucket size in pixels (default 16)\n"
		"  --memory-limit SIZE    Refuse a frame estimated to need more than SIZE bytes\n"
		"                         (8G, 512M, ...; default: 3/4 of the memory, physical\n"
		"                         or the cgroup's), naming the Format, PixelSamples or\n"
		"                         ShadingRate to change, before it is diced\n"
		"  --set LIGHT.PARAM=V[,V,V]\n"
		"                         Edit a light: LIGHT is its name (the RIB handle, as\n"
		"                         'relight info' lists them), PARAM one of its shader's\n"
		"                         parameters; one value for a float (or a grey colour),\n"
		"                         three for a colour, point or vector (points and\n"
		"                         vectors in the light's own space, as in the RIB),\n"
		"                         sixteen for a matrix, the text for a string (a\n"
		"                         map's name; nothing after '=' for the empty\n"
		"                         string). Repeatable (up to %d). The\n"
		"                         value replaces the one the scene gives, in every\n"
		"                         frame, as 'relight preview --set' edits a shot;\n"
		"                         LIGHT 'imager' edits the Imager shader (and a\n"
		"                         light of that handle)\n"
		"  -I, --include DIR      Look in DIR for shaders' #include files, after the\n"
		"                         shader's own folder (repeatable, in order; the\n"
		"                         scene's Option \"searchpath\" \"include\" replaces\n"
		"                         the list, '@' in it standing for the -I folders)\n"
		"  --strict               Every warning is an error: a scene with any renders\n"
		"                         nothing\n"
		"  -q, --quiet            No progress bar and no summary\n"
		"  -h, --help             Show this help and exit\n"
		"\n"
		"Shaders are looked up along the scene's Option \"searchpath\" \"shader\", by\n"
		"default $RELIGHT_SHADER_PATH, then $RMAN_SHADERPATH, then the standard library\n"
		"(%s): first a file NAME.sl, then a .sl file along the path that declares\n"
		"the shader NAME (surface NAME(...)); \"null\" is the built-in shader that does\n"
		"nothing. Each shader file is compiled once a run.\n"
		"A progress bar is shown when standard error is a terminal; at the end a summary\n"
		"gives each frame's time, micropolygons shaded, subpixel samples and peak memory,\n"
		"and a last line counts the frames, warnings (and repeats not shown) and errors.\n"
		"\n"
		"Exit status: 0 when every frame rendered, warnings or not; 1 when the scene has\n"
		"errors (FILE:LINE: error: MESSAGE; when one makes a frame meaningless nothing\n"
		"is rendered, else the frames render without the primitives the errors\n"
		"dropped), a warning under --strict, a --set edit that does not fit, a display\n"
		"that cannot be written, two outputs of one name, or an image that cannot be\n"
		"written; 2 on a usage error (an -o extension relight does not write too).\n",
		MAX_EDITS, RELIGHT_SOURCE_SHADER_DIR);
}

#define usage_error(...) cmd_usage_error("render", __VA_ARGS__)

/* ---- outputs ------------------------------------------------------------------------------ */

/*
 * Every file a run writes is planned before anything renders: a first read
 * of the scene (check_only: no rendering, no MakeTexture or MakeShadow)
 * records each frame's displays, then each gets its file name and format,
 * and a display relight cannot write, or two outputs naming one file, stop
 * the run before the first frame.
 */

enum out_kind { OUT_EXR, OUT_PNG, OUT_DEPTH, OUT_SKIP };

/* One display of one frame, as the run writes it. */
struct out {
	char *name;             /* the file written (owned) */
	char *key;              /* the same, with its folder resolved: compared for collisions */
	enum out_kind kind;
	char *where;            /* "FILE:LINE" of the Display, or the scene's name (owned) */
	char *type, *mode;      /* as the scene gives them (owned) */
	bool from_output;       /* named after -o */
};

struct frame_plan {
	int32_t number;         /* FrameBegin's number, else the frame's place from 1 */
	bool shadow_pass;       /* depth maps only */
	struct out *outs;
	uint32_t nouts;
};

struct render_job {
	struct reyes_render_opts ro;
	bool quiet;
	const char *output;     /* -o, or NULL */
	bool checking;          /* the first read: record the frames, render nothing */
	bool strict;            /* warnings are errors */
	int warnings;           /* the run's own, about displays */
	uint32_t rendered;      /* frames rendered */
	struct frame_plan *plan;
	uint32_t nplanned, cap;
};

static char *xstrdup(const char *s)
{
	char *d = strdup(s ? s : "");
	if (!d) {
		fprintf(stderr, "relight render: error: out of memory\n");
		exit(CMD_FAILED);
	}
	return d;
}

static char *xprintf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

static char *xprintf(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(NULL, 0, fmt, ap);
	va_end(ap);
	char *s = malloc((size_t)(n > 0 ? n : 0) + 1);
	if (!s) {
		fprintf(stderr, "relight render: error: out of memory\n");
		exit(CMD_FAILED);
	}
	va_start(ap, fmt);
	vsnprintf(s, (size_t)n + 1, fmt, ap);
	va_end(ap);
	return s;
}

static void plan_free(struct render_job *j)
{
	for (uint32_t i = 0; i < j->nplanned; i++) {
		for (uint32_t k = 0; k < j->plan[i].nouts; k++) {
			struct out *o = &j->plan[i].outs[k];
			free(o->name);
			free(o->key);
			free(o->where);
			free(o->type);
			free(o->mode);
		}
		free(j->plan[i].outs);
	}
	free(j->plan);
	j->plan = NULL;
	j->nplanned = j->cap = 0;
}

static bool is_depth(const struct reyes_display *d)
{
	return reyes_display_is_depth(d);
}

/* The extension of @name's last component, without the dot ("" when none). */
static const char *extension(const char *name)
{
	const char *base = strrchr(name, '/');
	base = base ? base + 1 : name;
	const char *dot = strrchr(base, '.');
	return dot && dot != base ? dot + 1 : "";
}

static bool ext_is(const char *ext, const char *want)
{
	return strcasecmp(ext, want) == 0;
}

/* The format of an -o name: OpenEXR (.exr or no extension) or PNG; false for others. */
static bool output_kind(const char *name, enum out_kind *kind)
{
	const char *ext = extension(name);
	if (!*ext || ext_is(ext, "exr"))
		*kind = OUT_EXR;
	else if (ext_is(ext, "png"))
		*kind = OUT_PNG;
	else
		return false;
	return true;
}

#define WRITTEN "relight writes Display types \"file\" (OpenEXR, or PNG for a name ending " \
		"in .png), \"openexr\" and \"png\", depth maps \"zfile\", \"shadow\" and \"deepshad\", " \
		"and skips \"framebuffer\""

/* A display's format from its type and name; false (reported at @o->where) when unwritable. */
static bool display_kind(struct render_job *j, struct out *o)
{
	const char *ext = extension(o->name);
	const char *t = o->type;
	bool exr_name = !*ext || ext_is(ext, "exr"), png_name = ext_is(ext, "png");
	if (!strcmp(t, "framebuffer") || !strcmp(t, "it")) {
		fprintf(stderr, "%s: %s: Display \"%s\" \"%s\": relight has no framebuffer; "
			"the display is skipped (-o FILE writes it to a file)\n", o->where,
			j->strict ? "error" : "warning", o->name, t);
		o->kind = OUT_SKIP;
		j->warnings++;
		return !j->strict;
	}
	if (!strcmp(t, "file") && (exr_name || png_name)) {
		o->kind = png_name ? OUT_PNG : OUT_EXR;
		return true;
	}
	if ((!strcmp(t, "openexr") || !strcmp(t, "exr")) && exr_name) {
		o->kind = OUT_EXR;
		return true;
	}
	if (!strcmp(t, "png") && (png_name || !*ext)) {
		o->kind = OUT_PNG;
		return true;
	}
	if (!strcmp(t, "file") || !strcmp(t, "openexr") || !strcmp(t, "exr") || !strcmp(t, "png"))
		fprintf(stderr, "%s: error: Display \"%s\" \"%s\": a file name ending in .%s is "
			"not an image relight writes (.exr or .png)\n", o->where, o->name, t, ext);
	else
		fprintf(stderr, "%s: error: Display \"%s\" \"%s\": type '%s' cannot be written; "
			WRITTEN "\n", o->where, o->name, t, t);
	return false;
}

/* A PNG holds one of the modes rgba, rgb, a, or one output variable (no depth). */
static bool png_mode_ok(const char *mode)
{
	return strcmp(mode, "z") && strcmp(mode, "rgbaz") && !strchr(mode, ',');
}

/*
 * @base with the frame number @n: a run of '#' becomes @n with as many
 * digits (at least), else "%d" or "%0Nd" (N from 1 to 9) becomes @n printed
 * so; without either, @numbered inserts ".NNNN" before the extension.
 */
static char *frame_name(const char *base, int32_t n, bool numbered)
{
	const char *hash = strchr(base, '#');
	if (hash) {
		size_t w = strspn(hash, "#");
		return xprintf("%.*s%0*d%s", (int)(hash - base), base, (int)w, (int)n, hash + w);
	}
	for (const char *p = strchr(base, '%'); p; p = strchr(p + 1, '%')) {
		const char *q = p + 1;
		int w = 0;
		if (q[0] == '0' && q[1] >= '1' && q[1] <= '9') {
			w = q[1] - '0';
			q += 2;
		}
		if (*q == 'd')
			return xprintf("%.*s%0*d%s", (int)(p - base), base, w, (int)n, q + 1);
	}
	if (!numbered)
		return xstrdup(base);
	const char *ext = extension(base);
	size_t stem = *ext ? (size_t)(ext - 1 - base) : strlen(base);
	return xprintf("%.*s.%04d%s%s", (int)stem, base, (int)n, *ext ? "." : "", ext);
}

/* @base with ".TAG" before its extension; TAG is @mode, commas turned into '_'. */
static char *with_mode(const char *base, const char *mode)
{
	const char *ext = extension(base);
	size_t stem = *ext ? (size_t)(ext - 1 - base) : strlen(base);
	char *s = xprintf("%.*s.%s%s%s", (int)stem, base, mode, *ext ? "." : "", ext);
	for (char *c = s + stem + 1; *c && *c != '.'; c++)
		if (*c == ',')
			*c = '_';
	return s;
}

/* @name with its folder resolved, so that "./a.exr" and "a.exr" compare equal. */
static char *file_key(const char *name)
{
	const char *slash = strrchr(name, '/');
	char *dir = slash ? xprintf("%.*s", (int)(slash - name + (slash == name)), name)
			  : xstrdup(".");
	char *real = realpath(dir, NULL);
	char *key = real ? xprintf("%s/%s", real, slash ? slash + 1 : name) : xstrdup(name);
	free(real);
	free(dir);
	return key;
}

/* The check read's frame: its displays as the scene gives them. */
static bool record_frame(struct render_job *j, const struct reyes_scene *scene)
{
	if (j->nplanned == j->cap) {
		uint32_t cap = j->cap ? j->cap * 2 : 8;
		struct frame_plan *p = realloc(j->plan, cap * sizeof(*p));
		if (!p) {
			fprintf(stderr, "relight render: error: out of memory\n");
			return false;
		}
		j->plan = p;
		j->cap = cap;
	}
	const struct reyes_options *so = &scene->opts;
	if (scene->world != j->nplanned) {
		fprintf(stderr, "relight render: error: a frame of the scene was not handed over\n");
		return false;
	}
	struct frame_plan *f = &j->plan[j->nplanned];
	*f = (struct frame_plan){
		.number = so->numbered ? so->frame_number : (int32_t)j->nplanned + 1,
		.shadow_pass = reyes_scene_is_shadow_pass(scene),
		.outs = calloc(so->ndisplays ? so->ndisplays : 1, sizeof(*f->outs)),
		.nouts = so->ndisplays,
	};
	if (!f->outs) {
		fprintf(stderr, "relight render: error: out of memory\n");
		return false;
	}
	j->nplanned++;
	for (uint32_t k = 0; k < so->ndisplays; k++) {
		const struct reyes_display *d = &so->displays[k];
		struct out *o = &f->outs[k];
		o->name = xstrdup(d->name);
		o->type = xstrdup(d->type);
		o->mode = xstrdup(d->mode);
		o->kind = is_depth(d) ? OUT_DEPTH : OUT_EXR;
		o->where = d->file && d->line ? xprintf("%s:%u", d->file, d->line)
					      : xstrdup(d->file ? d->file : "(scene)");
	}
	return true;
}

static int cmp_out(const void *a, const void *b)
{
	const struct out *x = *(const struct out *const *)a, *y = *(const struct out *const *)b;
	return strcmp(x->key, y->key);
}

/* The frame of output @o (a pointer into the plan). */
static const struct frame_plan *frame_of(const struct render_job *j, const struct out *o)
{
	for (uint32_t i = 0; i < j->nplanned; i++)
		if (o >= j->plan[i].outs && o < j->plan[i].outs + j->plan[i].nouts)
			return &j->plan[i];
	return NULL;
}

/*
 * Name every output and check them: formats relight writes, no two outputs
 * naming one file (a depth map may be written again by a later frame: shadow
 * passes of an animation reuse their maps). Errors are printed; false if any.
 */
static bool plan_outputs(struct render_job *j)
{
	uint32_t image_frames = 0;
	for (uint32_t i = 0; i < j->nplanned; i++)
		image_frames += !j->plan[i].shadow_pass;
	enum out_kind okind = OUT_EXR;
	if (j->output)
		output_kind(j->output, &okind);     /* checked with the options */
	bool ok = true;
	size_t total = 0;
	for (uint32_t i = 0; i < j->nplanned; i++) {
		struct frame_plan *f = &j->plan[i];
		bool first = true;
		for (uint32_t k = 0; k < f->nouts; k++) {
			struct out *o = &f->outs[k];
			if (o->kind == OUT_DEPTH) {
				/* a shadow pass keeps its names: the frames after it read the maps */
			} else if (j->output) {
				char *base = first ? xstrdup(j->output) : with_mode(j->output, o->mode);
				free(o->name);
				o->name = frame_name(base, f->number, image_frames > 1);
				free(base);
				o->kind = okind;
				o->from_output = true;
				first = false;
			} else if (!display_kind(j, o)) {
				ok = false;
				continue;
			}
			if (o->kind == OUT_PNG && !png_mode_ok(o->mode)) {
				fprintf(stderr, "%s: error: %s: a PNG holds the mode rgba, rgb, a or one "
					"output variable, not '%s' (write it to .exr)\n", o->where,
					o->name, o->mode);
				ok = false;
			}
			if (o->kind != OUT_SKIP &&
			    !cmd_check_output(o->name, o->from_output ? "relight render: --output"
								      : o->where))
				ok = false;
			o->key = file_key(o->name);
			total++;
		}
	}
	if (!ok)
		return false;

	struct out **all = malloc((total ? total : 1) * sizeof(*all));
	if (!all) {
		fprintf(stderr, "relight render: error: out of memory\n");
		return false;
	}
	size_t n = 0;
	for (uint32_t i = 0; i < j->nplanned; i++)
		for (uint32_t k = 0; k < j->plan[i].nouts; k++)
			if (j->plan[i].outs[k].kind != OUT_SKIP)
				all[n++] = &j->plan[i].outs[k];
	qsort(all, n, sizeof(*all), cmp_out);
	for (size_t a = 0; a + 1 < n; a++) {
		const struct out *x = all[a], *y = all[a + 1];
		if (strcmp(x->key, y->key) != 0)
			continue;
		const struct frame_plan *fx = frame_of(j, x), *fy = frame_of(j, y);
		if (fx != fy && x->kind == OUT_DEPTH && y->kind == OUT_DEPTH)
			continue;
		if (fy < fx) {
			const struct out *t = x;
			x = y;
			y = t;
			const struct frame_plan *tf = fx;
			fx = fy;
			fy = tf;
		}
		if (y->from_output)
			fprintf(stderr, "relight render: error: -o %s: frames %d and %d would both "
				"write %s (a '#' run or %%04d in the name numbers the frames)\n",
				j->output, (int)fx->number, (int)fy->number, y->name);
		else if (fx == fy)
			fprintf(stderr, "%s: error: Display \"%s\": the frame's display at %s writes "
				"that file too; each display needs a file of its own\n", y->where,
				y->name, x->where);
		else
			fprintf(stderr, "%s: error: Display \"%s\" of frame %d would write over frame "
				"%d's (%s); give each frame's displays their own names\n", y->where,
				y->name, (int)fy->number, (int)fx->number, x->where);
		ok = false;
	}
	free(all);
	return ok;
}

/* ---- frames ------------------------------------------------------------------------------- */

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct render_job *j = user;
	if (j->checking)
		return record_frame(j, scene);

	/* by the world's place: a frame with errors found only now is not handed over */
	uint32_t at = scene->world;
	const struct reyes_options *so = &scene->opts;
	if (at >= j->nplanned || j->plan[at].nouts != so->ndisplays) {
		fprintf(stderr, "relight render: error: frame %u differs from the first read of "
			"the scene\n", at + 1);
		return false;
	}
	const struct frame_plan *f = &j->plan[at];
	struct reyes_display *ds = calloc(so->ndisplays ? so->ndisplays : 1, sizeof(*ds));
	if (!ds) {
		fprintf(stderr, "relight render: error: out of memory\n");
		return false;
	}
	uint32_t nd = 0;
	for (uint32_t k = 0; k < so->ndisplays; k++) {
		const struct out *o = &f->outs[k];
		if (o->kind == OUT_SKIP)
			continue;
		ds[nd] = so->displays[k];
		ds[nd].name = o->name;
		ds[nd].png = o->kind == OUT_PNG;
		nd++;
	}
	bool ok = true;
	if (nd == 0) {
		if (!j->quiet)
			fprintf(stderr, "frame %d: nothing to write: not rendered\n", (int)f->number);
		goto out;
	}
	struct reyes_scene sc = *scene;
	sc.opts.displays = ds;
	sc.opts.ndisplays = nd;
	struct reyes_stats st = { 0 };
	if (!j->quiet && j->ro.progress)
		fprintf(stderr, "frame %d: %ux%u, %u primitives, %u lights\n", (int)f->number,
			so->xres, so->yres, scene->nprims, scene->nlights);
	ok = reyes_render(&sc, &j->ro, &st);
	j->rendered += ok;
	if (ok && !j->quiet) {
		for (uint32_t i = 0; i < nd; i++)
			fprintf(stderr, "wrote %s\n", ds[i].name);
		fprintf(stderr,
			"frame %d: %.2f s, %llu grids, %llu micropolygons shaded, %llu subpixel "
			"samples, peak memory %.1f MB\n",
			(int)f->number, st.seconds, (unsigned long long)st.grids,
			(unsigned long long)st.micropolygons, (unsigned long long)st.samples,
			(double)st.peak_bytes / (1024.0 * 1024.0));
	}
out:
	free(ds);
	return ok;
}

/* The run's last line: frames, warnings (and the repeats not shown), errors. */
static void summary(const struct render_job *j, const struct reyes_ri_counts *c)
{
	uint64_t shading, shading_repeats;
	sl_exec_warning_counts(&shading, &shading_repeats);
	unsigned long long warnings = (unsigned long long)(c->warnings + j->warnings) + shading +
				      reyes_render_warnings();
	unsigned long long repeats = (unsigned long long)c->repeats + shading_repeats;
	fprintf(stderr, "relight render: %u of %u frame%s rendered, %llu warning%s (%llu repeat%s "
		"not shown), %d error%s", j->rendered, c->frames, c->frames == 1 ? "" : "s",
		warnings, warnings == 1 ? "" : "s", repeats, repeats == 1 ? "" : "s", c->errors,
		c->errors == 1 ? "" : "s");
	if (c->dropped)
		fprintf(stderr, ", %d primitive%s dropped", c->dropped, c->dropped == 1 ? "" : "s");
	fputc('\n', stderr);
}

int cmd_render(int argc, char **argv)
{
	struct render_job job = { 0 };
	const char *output = NULL;
	struct reyes_light_edit edits[MAX_EDITS];
	char copies[MAX_EDITS][MAX_EDIT_LEN];
	uint32_t nedits = 0;
	char includes[8192] = "";
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "include", required_argument, NULL, 'I' },
		{ "output", required_argument, NULL, 'o' },
		{ "threads", required_argument, NULL, 't' },
		{ "crop", required_argument, NULL, 'c' },
		{ "bucket", required_argument, NULL, 'b' },
		{ "memory-limit", required_argument, NULL, 'm' },
		{ "set", required_argument, NULL, 's' },
		{ "quiet", no_argument, NULL, 'q' },
		{ "strict", no_argument, NULL, 'S' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt;
	while ((opt = getopt_long(argc, argv, ":ho:t:qI:", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'I': {
			int rc = cmd_add_include("render", includes, sizeof(includes), optarg);
			if (rc != CMD_OK)
				return rc;
			break;
		}
		case 'o': {
			enum out_kind kind;
			if (!*optarg || optarg[strlen(optarg) - 1] == '/')
				return usage_error("--output needs a file name, not '%s'", optarg);
			if (!output_kind(optarg, &kind))
				return usage_error("--output %s: relight writes OpenEXR (.exr, or no "
						   "extension) and PNG (.png), not .%s", optarg,
						   extension(optarg));
			output = optarg;
			break;
		}
		case 't':
			if (!cmd_parse_uint(optarg, 64, &job.ro.threads) || job.ro.threads == 0)
				return usage_error("--threads needs a number from 1 to 64, not '%s'",
						   optarg);
			break;
		case 'm':
			if (!reyes_mem_parse_size(optarg, &job.ro.memory_limit))
				return usage_error("--memory-limit needs a size such as 8G or 512M, "
						   "not '%s'", optarg);
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
							edits[nedits].values, &edits[nedits].nvalues,
							&edits[nedits].text);
				if (rc != CMD_OK)
					return rc;
			}
			nedits++;
			break;
		case 'q':
			job.quiet = true;
			break;
		case 'S':
			job.strict = true;
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
	job.output = output;

	char shader_path[8192];
	cmd_shader_path(shader_path, sizeof(shader_path));
	/* Each shader is compiled once for both reads and every frame. */
	struct reyes_shader_cache *cache = reyes_shader_cache_create();
	job.ro.shader_cache = cache;
	struct reyes_ri_counts counts = { 0 };
	struct reyes_ri_opts ri = {
		.diag = stderr,
		.default_shader_path = shader_path,
		.default_texture_path = ".",
		.default_include_path = includes,
		.shader_cache = cache,
		.light_edits = edits,
		.nlight_edits = nedits,
		.strict = job.strict,
		.counts = &counts,
		.frame = on_frame,
		.user = &job,
	};

	/*
	 * First read: the whole scene checked (--set names and values included)
	 * and its outputs planned, nothing rendered or written. Its diagnostics
	 * are shown only when it fails: the rendering read repeats the warnings,
	 * and the errors of primitives it drops (which do not stop the run).
	 */
	char *check_log = NULL;
	size_t check_len = 0;
	FILE *check_diag = open_memstream(&check_log, &check_len);
	if (!check_diag) {
		fprintf(stderr, "relight render: error: out of memory\n");
		reyes_shader_cache_destroy(cache);
		return CMD_FAILED;
	}
	ri.diag = check_diag;
	ri.check_only = true;
	job.checking = true;
	int nerrors = 0;
	bool ok = reyes_ri_read(path, &ri, &nerrors);
	fclose(check_diag);
	if (!ok && (counts.fatal > 0 || counts.dropped == 0)) {
		fputs(check_log ? check_log : "", stderr);
		free(check_log);
		if (!job.quiet)
			summary(&job, &counts);
		plan_free(&job);
		reyes_shader_cache_destroy(cache);
		return CMD_FAILED;
	}
	free(check_log);
	if (job.nplanned == 0) {
		fprintf(stderr, "%s: error: the scene has no frame (no WorldBegin ... WorldEnd)\n",
			path);
		plan_free(&job);
		reyes_shader_cache_destroy(cache);
		return CMD_FAILED;
	}
	if (!plan_outputs(&job)) {
		fprintf(stderr, "relight render: nothing rendered\n");
		plan_free(&job);
		reyes_shader_cache_destroy(cache);
		return CMD_FAILED;
	}

	ri.diag = stderr;
	ri.check_only = false;
	job.checking = false;
	ok = reyes_ri_read(path, &ri, &nerrors);
	uint64_t shading, shading_repeats;
	sl_exec_warning_counts(&shading, &shading_repeats);
	if (job.strict && shading) {
		fprintf(stderr, "relight render: error: the shaders warned %llu time%s: an error "
			"under --strict\n", (unsigned long long)shading, shading == 1 ? "" : "s");
		ok = false;
	}
	if (job.strict && reyes_render_warnings()) {
		fprintf(stderr, "relight render: error: the renderer left something out (its "
			"warning above): an error under --strict\n");
		ok = false;
	}
	if (!job.quiet)
		summary(&job, &counts);
	plan_free(&job);
	reyes_shader_cache_destroy(cache);
	return ok ? CMD_OK : CMD_FAILED;
}

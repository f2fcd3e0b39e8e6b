/*
 * relight bench: speed against error, in one picture a user can judge.
 *
 * For each example (EXAMPLES/NAME/NAME.rib), in a work folder of its own:
 * the reference render and the bake, timed; the shot on the GPU runtime;
 * a one-light edit refined level by level, each level timed (the median of
 * several edits) and compared with `relight render` of the RIB edited the
 * same way; heat maps of those errors; the cache's sizes and compression;
 * the edit-to-tile latency through relightd. Then a street of spheres lit by
 * 1 to 64 lights, an edit of one of them timed with the light cache and
 * without; then the stability suite (bench/stability.h). The results go to
 * the terminal, to JSON, and with --out to a Markdown report with plots.
 */
#include "cmd.h"
#include "benchutil.h"
#include "config.h"
#include "fileutil.h"
#include "gpu.h"
#include "imgerr.h"
#include "latency.h"
#include "microbench.h"
#include "plot.h"
#include "runtime.h"
#include "scenes.h"
#include "rays.h"
#include "shotfile.h"
#include "stability.h"
#include "texture.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_EXAMPLES 64
#define MAX_EDITS 101
#define MAX_CHECKS 256
#define MAX_COUNTS 8
#define LEVELS GPU_SHOT_LEVELS
#define HEAT_SCALE_PCT 5.0      /* the heat maps' top, as `relight diff --heatmap` */

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight bench [OPTIONS] [EXAMPLE...]\n"
		"\n"
		"Measure relight's speed against its error on the examples, and its numerical\n"
		"stability, and report both. For each example EXAMPLES/NAME/NAME.rib (all of\n"
		"them, or the NAMEs given):\n"
		"  - the reference render ('relight render') and the bake, timed;\n"
		"  - the shot on the GPU runtime: one light's intensity and colour edited, the\n"
		"    edit refined level by level (0: one sample per 4x4 pixels ... 3: final),\n"
		"    each level timed (the median of --edits edits) and compared with\n"
		"    'relight render --set' of the same edit: linear RMSE, mean and max error in\n"
		"    percent of the 8-bit range, PSNR (as 'relight diff' measures them);\n"
		"  - the cache: samples kept of the micropolygons shaded, indirect entries of\n"
		"    the subpixel samples (in all and per pixel), channels, bytes before and\n"
		"    after compression;\n"
		"  - the latency from an edit sent to relightd to its first tile received.\n"
		"Then a street of spheres lit by 1 to 64 lights: the time of one light's edit\n"
		"with the light cache and without it (every light shaded again), and the\n"
		"final level against the reference render. Then the stability suite: light\n"
		"cache drift over 100,000 edits, intensities 1e-4 to 1e4, grazing and\n"
		"degenerate geometry, long transparency chains, filter weights at 16x16\n"
		"samples, half-float channels against float; each check has a tolerance.\n"
		"Then rays per second: one shadow ray from each of 1024 x 1024 floor points\n"
		"(--quick: 256 x 256) through 100 spheres (409,600 triangles; --quick: 25),\n"
		"traced by Embree on every core and by the GPU's shadow kernel, and the rays\n"
		"the two answer differently.\n"
		"\n"
		"Options:\n"
		"  -o, --out DIR        Write the report DIR/report.md, and its figures\n"
		"                       (report.json), plots and heat maps in DIR/report/\n"
		"                       ('relight bench -o docs' refreshes docs/report.md)\n"
		"  --json               Print the results as JSON on stdout (progress stays on\n"
		"                       stderr)\n"
		"  --quick              A small run: 5 edits, 1, 4 and 16 lights at 480x270,\n"
		"                       the stability suite's quick mode, 10 latency edits\n"
		"  --only PARTS         Only these parts, comma-separated: examples, lights,\n"
		"                       latency, stability, rays\n"
		"  --stability          The stability suite alone (as --only stability)\n"
		"  --examples DIR       Where the examples are (default: ./examples when it\n"
		"                       exists, else the source tree's)\n"
		"  --edits N            Timed edits per measurement, 1 to 101 (default 9)\n"
		"  --viewers N          Latency: also measure with N more clients watching\n"
		"                       (default 15; 0: one client only)\n"
		"  --relightd PATH      The daemon to measure latency with (default: beside\n"
		"                       this program, then on PATH)\n"
		"  --work DIR           Keep the renders, shots and logs in DIR (default: a\n"
		"                       temporary folder, removed at the end)\n"
		"  -q, --quiet          No progress messages\n"
		"  -h, --help           Show this help and exit\n"
		"\n"
		"Times are wall-clock on this machine; compare figures from one run. The\n"
		"stability suite's checks pass or fail; the speed figures are reported, and\n"
		"the report says which targets they meet.\n"
		"\n"
		"Exit status: 0 when everything ran and every stability check passed, 1 when\n"
		"something failed (a render, a bake, a check), 2 on a usage error, 77 when\n"
		"there is no GPU context (OpenGL 4.3 through EGL) and nothing failed.\n");
}

#define usage_error(...) cmd_usage_error("bench", __VA_ARGS__)

enum { PART_EXAMPLES = 1, PART_LIGHTS = 2, PART_LATENCY = 4, PART_STABILITY = 8, PART_RAYS = 16,
       PART_ALL = 31 };

struct bench_cfg {
	bool json, quick, quiet;
	unsigned parts;
	const char *out, *work_opt, *relightd_opt;
	char examples[PATH_MAX], work[PATH_MAX], self[PATH_MAX], relightd[PATH_MAX];
	int edits, viewers;
	const char *only_names[MAX_EXAMPLES];
	int nonly;
};

struct level_res {
	double ms, cum_ms;
	uint64_t entries, shaded;
	struct img_error err;
};

struct example_res {
	char name[64];
	bool ok;
	char why[512];
	double render_s, bake_s, load_ms, full_ms, first_edit_ms, edit_ms;
	uint32_t width, height;
	uint64_t samples;
	size_t gpu_bytes;
	uint32_t nlights;
	char edit[256];               /* what was edited, as --set arguments */
	struct level_res lv[LEVELS];
	/* the cache (the shot's metadata) */
	double shaded_points, shading_samples, subpixel_samples, indirect_entries;
	double pixels;                /* the shot's width x height, NaN when it does not say */
	double ch_dynamic, ch_varying, ch_unique, ch_half, ch_float;
	double sample_bytes, file_bytes;
	bool heatmap;
	/* latency */
	bool lat_ok;
	struct latency_row lat[2];
	int nlat;
};

struct count_res {
	int lights;
	double cache_ms[LEVELS], cache_total, nocache_ms[LEVELS], nocache_total;
	double cache_vs_nocache;      /* largest relative difference of the two final images */
	double render_rmse, render_mean, render_max;   /* final level vs relight render */
	bool ok;
};

struct bench {
	struct bench_cfg c;
	struct gpu_ctx *ctx;
	char device[256];
	double arith_flops;
	struct example_res ex[MAX_EXAMPLES];
	int nex;
	struct count_res counts[MAX_COUNTS];
	int ncounts;
	int count_w, count_h;
	struct stab_check checks[MAX_CHECKS];
	int nchecks;
	bool stab_ran;
	struct bench_rays rays;
	bool rays_ran;
	bool failed, no_gpu;
	char failures[2048];
};

/*
 * snprintf for the paths and messages built here: they fit (PATH_MAX) or are
 * cut, which only a message can be; the compiler's truncation warnings do not
 * look through it.
 */
static int fmtf(char *buf, size_t cap, const char *f, ...) __attribute__((format(printf, 3, 4)));
static int fmtf(char *buf, size_t cap, const char *f, ...)
{
	va_list ap;
	va_start(ap, f);
	int n = vsnprintf(buf, cap, f, ap);
	va_end(ap);
	return n;
}

static void note(const struct bench *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note(const struct bench *b, const char *fmt, ...)
{
	if (b->c.quiet)
		return;
	va_list ap;
	va_start(ap, fmt);
	fputs("bench: ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

static void fail(struct bench *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void fail(struct bench *b, const char *fmt, ...)
{
	char msg[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	fprintf(stderr, "relight bench: error: %s\n", msg);
	size_t len = strlen(b->failures);
	fmtf(b->failures + len, sizeof(b->failures) - len, "%s%s", len ? "; " : "", msg);
	b->failed = true;
}

static double now_s(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* ---- files and processes ---- */

static bool is_dir(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static bool is_file(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Copy the plain files of folder @from into @to (made if needed): an example's RIB and assets. */
static bool copy_folder(const char *from, const char *to)
{
	if (!rl_mkdir_p(to))
		return false;
	DIR *d = opendir(from);
	if (!d)
		return false;
	bool ok = true;
	struct dirent *e;
	while (ok && (e = readdir(d))) {
		char a[PATH_MAX], z[PATH_MAX];
		if (e->d_name[0] == '.')
			continue;
		fmtf(a, sizeof(a), "%s/%s", from, e->d_name);
		fmtf(z, sizeof(z), "%s/%s", to, e->d_name);
		if (is_file(a))
			ok = rl_copy_file(a, z);
	}
	closedir(d);
	return ok;
}

/*
 * Run this program with @argv (argv[0] a name for messages) in folder @dir,
 * its output to @log: the seconds it took, or a negative value when it did
 * not succeed.
 */
static double run_self(const struct bench *b, const char *dir, const char *log,
		       char *const argv[])
{
	double t0 = now_s();
	pid_t pid = fork();
	if (pid < 0)
		return -1.0;
	if (pid == 0) {
		int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
		if (fd < 0 || chdir(dir) != 0)
			_exit(127);
		dup2(fd, 1);
		dup2(fd, 2);
		execv(b->c.self, argv);
		_exit(127);
	}
	int status;
	while (waitpid(pid, &status, 0) < 0)
		if (errno != EINTR)
			return -1.0;
	double t = now_s() - t0;
	return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? t : -1.0;
}

/* The last line of @log that says "error", for a failure's reason. */
static void log_reason(const char *log, char *out, size_t cap)
{
	fmtf(out, cap, "see %s", log);
	FILE *f = fopen(log, "r");
	if (!f)
		return;
	char line[512];
	while (fgets(line, sizeof(line), f))
		if (strstr(line, "error")) {
			line[strcspn(line, "\n")] = 0;
			fmtf(out, cap, "%s (%s)", line, log);
		}
	fclose(f);
}

/* ---- the examples ---- */

/* Light parameter @param's current value, or false when the light has none. */
static bool light_param(struct gpu_shot *s, uint32_t li, const char *param,
			struct gpu_shot_param *out)
{
	for (uint32_t k = 0; gpu_shot_light_param(s, li, k, out); k++)
		if (!strcmp(out->name, param))
			return true;
	return false;
}

/*
 * The edit every example gets: the first light with an intensity that is not
 * an ambient light, its intensity times 1.5 (1 when it was 0) and its colour
 * warmer. @alt gives a second value (2 % brighter) to alternate with, so that
 * every timed edit changes something.
 */
struct edit {
	char light[64];
	float intensity[2], color[2][3];
	bool has_color;
};

static bool choose_edit(struct gpu_shot *s, struct edit *e)
{
	memset(e, 0, sizeof(*e));
	uint32_t n = gpu_shot_light_count(s);
	for (int pass = 0; pass < 2; pass++)
		for (uint32_t i = 0; i < n; i++) {
			const char *name = gpu_shot_light_name(s, i);
			const char *shader = gpu_shot_light_shader(s, i);
			struct gpu_shot_param p;
			if (!name || !light_param(s, i, "intensity", &p))
				continue;
			if (pass == 0 && shader && strstr(shader, "ambient"))
				continue;
			fmtf(e->light, sizeof(e->light), "%s", name);
			float v = p.value[0] > 0.0f ? 1.5f * p.value[0] : 1.0f;
			e->intensity[0] = fminf(v, p.max);
			e->intensity[1] = fminf(1.02f * v, p.max);
			struct gpu_shot_param c;
			if (light_param(s, i, "lightcolor", &c) && c.n == 3) {
				static const float warm[3] = { 1.0f, 0.85f, 0.7f };
				e->has_color = true;
				for (int k = 0; k < 3; k++)
					e->color[0][k] = e->color[1][k] = c.value[k] * warm[k];
			}
			return true;
		}
	return false;
}

static bool apply_edit(struct gpu_shot *s, const struct edit *e, int which, char *err,
		       size_t errlen)
{
	return gpu_shot_set(s, e->light, "intensity", &e->intensity[which], 1, err, errlen) &&
	       (!e->has_color || gpu_shot_set(s, e->light, "lightcolor", e->color[which], 3, err,
					      errlen));
}

/* The shot's figures of compression (its metadata, as `relight info` prints them). */
static void read_cache_figures(const char *shot, struct example_res *r)
{
	char err[512];
	struct shot_file *f = shot_read_header(shot, err, sizeof(err));
	if (!f)
		return;
	cJSON *meta = cJSON_Parse(f->metadata ? f->metadata : "");
	const cJSON *fig = cJSON_GetObjectItemCaseSensitive(meta, "figures");
	const cJSON *chn = cJSON_GetObjectItemCaseSensitive(fig, "channels");
#define FIG(obj, name) (cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(obj, name)) ? \
	cJSON_GetObjectItemCaseSensitive(obj, name)->valuedouble : NAN)
	double w = FIG(meta, "width"), h = FIG(meta, "height");
	r->pixels = w > 0.0 && h > 0.0 ? w * h : NAN;
	r->shaded_points = FIG(fig, "shaded_points");
	r->shading_samples = FIG(fig, "shading_samples");
	r->subpixel_samples = FIG(fig, "subpixel_samples");
	r->indirect_entries = FIG(fig, "indirect_entries");
	r->ch_dynamic = FIG(chn, "dynamic");
	r->ch_varying = FIG(chn, "varying");
	r->ch_unique = FIG(chn, "unique");
	r->ch_half = FIG(chn, "half");
	r->ch_float = FIG(chn, "float");
#undef FIG
	r->sample_bytes = 0.0;
	for (uint32_t i = 0; i < f->ntables + f->ndeeps; i++) {
		const char *name = i < f->ntables ? f->tables[i].name : f->deeps[i - f->ntables].name;
		if (f->part_bytes && !strncmp(name, "samples.", 8))
			r->sample_bytes += (double)f->part_bytes[i];
	}
	struct stat st;
	r->file_bytes = stat(shot, &st) == 0 ? (double)st.st_size : NAN;
	cJSON_Delete(meta);
	shot_free(f);
}

/* Render the example's RIB with @e applied (value 0) into @out: seconds, or < 0. */
static double render_edited(const struct bench *b, const char *dir, const char *rib,
			    const struct edit *e, const char *out, const char *log)
{
	char a[2][128];
	fmtf(a[0], sizeof(a[0]), "%s.intensity=%.9g", e->light, (double)e->intensity[0]);
	fmtf(a[1], sizeof(a[1]), "%s.lightcolor=%.9g,%.9g,%.9g", e->light,
		 (double)e->color[0][0], (double)e->color[0][1], (double)e->color[0][2]);
	char *argv[12];
	int n = 0;
	argv[n++] = "relight";
	argv[n++] = "render";
	argv[n++] = "-q";
	argv[n++] = "--set";
	argv[n++] = a[0];
	if (e->has_color) {
		argv[n++] = "--set";
		argv[n++] = a[1];
	}
	argv[n++] = "-o";
	argv[n++] = (char *)out;
	argv[n++] = (char *)rib;
	argv[n] = NULL;
	return run_self(b, dir, log, argv);
}

/* One edit refined level by level: each level's time into @ms. */
static bool refine(struct gpu_shot *s, double ms[LEVELS], struct gpu_shot_stats st[LEVELS])
{
	for (int L = 0; L < LEVELS; L++) {
		if (!gpu_shot_render(s, L, &st[L]))
			return false;
		ms[L] = st[L].ms;
	}
	return true;
}

static void bench_example(struct bench *b, const char *name)
{
	struct example_res *r = &b->ex[b->nex++];
	memset(r, 0, sizeof(*r));
	fmtf(r->name, sizeof(r->name), "%s", name);
	char src[PATH_MAX], dir[PATH_MAX], rib[PATH_MAX], log[PATH_MAX], path[PATH_MAX];
	fmtf(src, sizeof(src), "%s/%s", b->c.examples, name);
	fmtf(dir, sizeof(dir), "%s/%s", b->c.work, name);
	fmtf(rib, sizeof(rib), "%s.rib", name);
	if (!copy_folder(src, dir)) {
		fmtf(r->why, sizeof(r->why), "cannot copy %s to %s", src, dir);
		goto out;
	}
	/* the reference render of the RIB as it is, and the bake */
	note(b, "%s: rendering the reference", name);
	fmtf(log, sizeof(log), "%s/render.log", dir);
	char out_exr[PATH_MAX], shot[PATH_MAX];
	fmtf(out_exr, sizeof(out_exr), "%s/%s.ref.exr", dir, name);
	char *rargv[] = { "relight", "render", "-q", "-o", out_exr, rib, NULL };
	r->render_s = run_self(b, dir, log, rargv);
	if (r->render_s < 0) {
		log_reason(log, r->why, sizeof(r->why));
		goto out;
	}
	note(b, "%s: baking", name);
	fmtf(log, sizeof(log), "%s/bake.log", dir);
	fmtf(shot, sizeof(shot), "%s/%s.shot.exr", dir, name);
	char *bargv[] = { "relight", "bake", "-q", "-o", shot, rib, NULL };
	r->bake_s = run_self(b, dir, log, bargv);
	if (r->bake_s < 0) {
		log_reason(log, r->why, sizeof(r->why));
		goto out;
	}
	read_cache_figures(shot, r);
	if (!b->ctx) {
		fmtf(r->why, sizeof(r->why), "no GPU context");
		goto out;
	}

	/* the shot on the GPU: every light, then the edit, timed */
	note(b, "%s: loading the shot on the GPU", name);
	char err[1024] = "";
	FILE *diag = fmemopen(err, sizeof(err), "w");
	struct gpu_shot_opts o = { .diag = diag ? diag : stderr, .texture_path = dir };
	double t0 = now_s();
	struct gpu_shot *s = gpu_shot_open(b->ctx, shot, &o);
	r->load_ms = (now_s() - t0) * 1e3;
	if (!s) {
		if (diag)
			fclose(diag);
		fmtf(r->why, sizeof(r->why), "loading the shot: %s", err);
		goto out;
	}
	r->width = gpu_shot_width(s);
	r->height = gpu_shot_height(s);
	r->samples = gpu_shot_samples(s);
	r->gpu_bytes = gpu_shot_bytes(s);
	r->nlights = gpu_shot_light_count(s);
	struct edit e;
	struct gpu_shot_stats st[LEVELS];
	double ms[LEVELS];
	double lv[LEVELS][MAX_EDITS], tot[MAX_EDITS];
	char msg[512] = "";
	bool ok = choose_edit(s, &e);
	if (!ok)
		fmtf(msg, sizeof(msg), "no light with an intensity to edit");
	ok = ok && gpu_shot_render(s, GPU_SHOT_FINAL, &st[0]);
	r->full_ms = st[0].ms;
	/* the first edit also takes the light out of the light cache: apart */
	ok = ok && apply_edit(s, &e, 1, msg, sizeof(msg)) && refine(s, ms, st);
	r->first_edit_ms = ms[0] + ms[1] + ms[2] + ms[3];
	int E = b->c.edits;
	for (int k = 0; ok && k < E; k++) {
		/* alternating, the last with the edited value the reference has */
		ok = apply_edit(s, &e, (E - 1 - k) % 2, msg, sizeof(msg)) && refine(s, ms, st);
		tot[k] = 0.0;
		for (int L = 0; L < LEVELS; L++) {
			lv[L][k] = ms[L];
			tot[k] += ms[L];
			r->lv[L].entries = st[L].entries;
			r->lv[L].shaded = st[L].shaded;
		}
	}
	if (e.has_color)
		fmtf(r->edit, sizeof(r->edit), "%s.intensity=%.4g %s.lightcolor=%.3g,%.3g,%.3g",
			 e.light, (double)e.intensity[0], e.light, (double)e.color[0][0],
			 (double)e.color[0][1], (double)e.color[0][2]);
	else
		fmtf(r->edit, sizeof(r->edit), "%s.intensity=%.4g", e.light,
			 (double)e.intensity[0]);
	if (ok) {
		double cum = 0.0;
		for (int L = 0; L < LEVELS; L++) {
			r->lv[L].ms = bench_median(lv[L], E);
			cum += r->lv[L].ms;
			r->lv[L].cum_ms = cum;
		}
		r->edit_ms = bench_median(tot, E);
	}
	/* every level against the render of the RIB edited the same way */
	float *img[LEVELS] = { NULL }, *maps[LEVELS] = { NULL }, *ref = NULL;
	size_t px = (size_t)r->width * r->height;
	if (ok) {
		note(b, "%s: rendering the edited RIB (%s)", name, r->edit);
		fmtf(log, sizeof(log), "%s/render-edited.log", dir);
		fmtf(path, sizeof(path), "%s/%s.edited.exr", dir, name);
		if (render_edited(b, dir, rib, &e, path, log) < 0) {
			log_reason(log, msg, sizeof(msg));
			ok = false;
		} else {
			ref = bench_read_rgba_exr(path, r->width, r->height, false, NULL, msg, sizeof(msg));
			ok = ref != NULL;
		}
	}
	for (int L = 0; ok && L < LEVELS; L++) {
		img[L] = malloc(px * 4 * sizeof(float));
		maps[L] = malloc(px * sizeof(float));
		ok = img[L] && maps[L] && gpu_shot_read_rgba(s, L, img[L]);
		if (ok)
			img_error_rgba(img[L], ref, r->width, r->height, maps[L], &r->lv[L].err);
	}
	if (ok && b->c.out) {
		char perr[256];
		uint32_t shrink = (uint32_t)((4 * r->width + 1599) / 1600);
		fmtf(path, sizeof(path), "%s/report/heat-%s.png", b->c.out, name);
		r->heatmap = plot_heatmap_png(path, (const float *const *)maps, LEVELS, r->width,
					      r->height, shrink ? shrink : 1, HEAT_SCALE_PCT, perr,
					      sizeof(perr));
		if (!r->heatmap)
			fail(b, "%s: heat map: %s", name, perr);
	}
	for (int L = 0; L < LEVELS; L++) {
		free(img[L]);
		free(maps[L]);
	}
	free(ref);
	gpu_shot_close(s);
	if (diag)
		fclose(diag);
	if (!ok) {
		fmtf(r->why, sizeof(r->why), "%s", msg[0] ? msg : err);
		goto out;
	}
	r->ok = true;
	note(b, "%s: edit to final %.1f ms; final level against the render: mean %.4f %%, "
	     "max %.3f %%", name, r->edit_ms, img_error_mean_pct(&r->lv[3].err),
	     img_error_max_pct(&r->lv[3].err));
out:
	if (!r->ok)
		fail(b, "%s: %s", name, r->why);
}

static void bench_latency_of(struct bench *b, struct example_res *r)
{
	char dir[PATH_MAX], err[512];
	fmtf(dir, sizeof(dir), "%s/%s", b->c.work, r->name);
	const char *names[1] = { r->name };
	struct latency_opts o = {
		.relightd = b->c.relightd, .shots = dir, .names = names, .nnames = 1,
		.edits = b->c.quick ? 10 : 30, .viewers = b->c.viewers,
		.log = b->c.quiet ? NULL : stderr,
	};
	note(b, "%s: latency through relightd", r->name);
	int n = latency_run(&o, r->lat, 2, err, sizeof(err));
	if (n == -77) {
		note(b, "%s: latency skipped: relightd has no GPU context", r->name);
		return;
	}
	if (n < 0) {
		fail(b, "%s: latency: %s", r->name, err);
		return;
	}
	r->nlat = n;
	r->lat_ok = true;
}

/* ---- light count ---- */

static bool add_street_light(struct gpu_shot *s, int k, int ring, char *err, size_t errlen)
{
	struct bench_light l;
	bench_street_light_params(k, ring, 40.0f, &l);
	char name[16];
	fmtf(name, sizeof(name), "%d", k);
	if (gpu_shot_add_light(s, name, l.shader, NULL, err, errlen) < 0)
		return false;
	bool ok = gpu_shot_set(s, name, "intensity", &l.intensity, 1, err, errlen);
	if (ok && strcmp(l.shader, "ambientlight"))
		ok = gpu_shot_set(s, name, "from", l.from, 3, err, errlen);
	if (ok && !strcmp(l.shader, "distantlight"))
		ok = gpu_shot_set(s, name, "to", l.to, 3, err, errlen);
	if (ok && !strcmp(l.shader, "pointlight"))
		ok = gpu_shot_set(s, name, "lightcolor", l.color, 3, err, errlen);
	return ok;
}

static bool freeze_all(struct gpu_shot *s, int n, bool frozen, char *err, size_t errlen)
{
	for (int k = 1; k <= n; k++) {
		char name[16];
		fmtf(name, sizeof(name), "%d", k);
		if (!gpu_shot_freeze(s, name, frozen, err, errlen))
			return false;
	}
	return true;
}

/* Timed edits of light 1's intensity, each refined to the final level: medians. */
static bool time_edits(struct gpu_shot *s, int E, double out[LEVELS], double *total, char *err,
		       size_t errlen)
{
	double lv[LEVELS][MAX_EDITS], tot[MAX_EDITS], ms[LEVELS];
	struct gpu_shot_stats st[LEVELS];
	/* one untimed edit first: it takes light 1 out of the cache */
	for (int k = -1; k < E; k++) {
		float v = (E - 1 - k) % 2 ? 41.0f : 60.0f;
		if (!gpu_shot_set(s, "1", "intensity", &v, 1, err, errlen) || !refine(s, ms, st)) {
			fmtf(err, errlen, "rendering failed");
			return false;
		}
		if (k < 0)
			continue;
		tot[k] = 0.0;
		for (int L = 0; L < LEVELS; L++) {
			lv[L][k] = ms[L];
			tot[k] += ms[L];
		}
	}
	for (int L = 0; L < LEVELS; L++)
		out[L] = bench_median(lv[L], E);
	*total = bench_median(tot, E);
	return true;
}

static void bench_light_counts(struct bench *b)
{
	static const int full[] = { 1, 2, 4, 8, 16, 32, 64 }, quick[] = { 1, 4, 16 };
	const int *counts = b->c.quick ? quick : full;
	int ncounts = b->c.quick ? 3 : 7, ring = counts[ncounts - 1];
	b->count_w = b->c.quick ? 480 : 960;
	b->count_h = b->c.quick ? 270 : 540;
	char dir[PATH_MAX], rib[PATH_MAX], shot[PATH_MAX], log[PATH_MAX], err[1024] = "";
	fmtf(dir, sizeof(dir), "%s/street", b->c.work);
	fmtf(rib, sizeof(rib), "%s/street1.rib", dir);
	fmtf(shot, sizeof(shot), "%s/street1.shot.exr", dir);
	fmtf(log, sizeof(log), "%s/bake.log", dir);
	if (!rl_mkdir_p(dir) ||
	    !bench_street_rib(rib, b->count_w, b->count_h, 1, ring, 40.0f, err, sizeof(err))) {
		fail(b, "light counts: %s", err[0] ? err : strerror(errno));
		return;
	}
	note(b, "light counts: baking a %dx%d street of spheres", b->count_w, b->count_h);
	char *bargv[] = { "relight", "bake", "-q", "-o", shot, rib, NULL };
	if (run_self(b, dir, log, bargv) < 0) {
		log_reason(log, err, sizeof(err));
		fail(b, "light counts: bake: %s", err);
		return;
	}
	FILE *diag = fmemopen(err, sizeof(err), "w");
	struct gpu_shot_opts o = { .diag = diag ? diag : stderr, .texture_path = dir };
	struct gpu_shot *s = gpu_shot_open(b->ctx, shot, &o);
	if (diag)
		fclose(diag);
	if (!s) {
		fail(b, "light counts: loading: %s", err);
		return;
	}
	size_t px = (size_t)b->count_w * (size_t)b->count_h;
	float *cached = malloc(px * 4 * sizeof(float)), *uncached = malloc(px * 4 * sizeof(float));
	int have = 1;
	bool ok = cached && uncached;
	struct gpu_shot_stats st;
	for (int i = 0; ok && i < ncounts; i++) {
		struct count_res *c = &b->counts[b->ncounts];
		memset(c, 0, sizeof(*c));
		c->lights = counts[i];
		note(b, "light counts: %d light%s", c->lights, c->lights > 1 ? "s" : "");
		while (ok && have < c->lights)
			ok = add_street_light(s, ++have, ring, err, sizeof(err));
		/* with the light cache: every light frozen but the one edited */
		ok = ok && freeze_all(s, have, true, err, sizeof(err)) &&
		     gpu_shot_render(s, GPU_SHOT_FINAL, &st) &&
		     time_edits(s, b->c.edits, c->cache_ms, &c->cache_total, err, sizeof(err)) &&
		     gpu_shot_read_rgba(s, GPU_SHOT_FINAL, cached);
		/* without: every light unfrozen, so every edit shades them all */
		ok = ok && freeze_all(s, have, false, err, sizeof(err)) &&
		     gpu_shot_render(s, GPU_SHOT_FINAL, &st) &&
		     time_edits(s, b->c.edits, c->nocache_ms, &c->nocache_total, err,
				sizeof(err)) &&
		     gpu_shot_read_rgba(s, GPU_SHOT_FINAL, uncached);
		if (!ok)
			break;
		struct img_error ie;
		img_error_rgba(cached, uncached, (uint32_t)b->count_w, (uint32_t)b->count_h, NULL,
			       &ie);
		c->cache_vs_nocache = ie.max_rel;
		/* the final level against the renderer with as many lights, edited alike */
		char crib[PATH_MAX], cexr[PATH_MAX], clog[PATH_MAX];
		fmtf(crib, sizeof(crib), "%s/street%d.rib", dir, c->lights);
		fmtf(cexr, sizeof(cexr), "%s/street%d.exr", dir, c->lights);
		fmtf(clog, sizeof(clog), "%s/render%d.log", dir, c->lights);
		c->render_rmse = c->render_mean = c->render_max = NAN;
		char *rargv[] = { "relight", "render", "-q", "-o", cexr, crib, NULL };
		if (bench_street_rib(crib, b->count_w, b->count_h, c->lights, ring, 60.0f, err,
				     sizeof(err)) &&
		    run_self(b, dir, clog, rargv) >= 0) {
			float *ref = bench_read_rgba_exr(cexr, (uint32_t)b->count_w,
							 (uint32_t)b->count_h, false, NULL, err,
							 sizeof(err));
			if (ref) {
				img_error_rgba(cached, ref, (uint32_t)b->count_w,
					       (uint32_t)b->count_h, NULL, &ie);
				c->render_rmse = img_error_rmse(&ie);
				c->render_mean = img_error_mean_pct(&ie);
				c->render_max = img_error_max_pct(&ie);
				free(ref);
			}
		}
		c->ok = true;
		b->ncounts++;
	}
	if (!ok)
		fail(b, "light counts: %s", err);
	free(cached);
	free(uncached);
	gpu_shot_close(s);
}

/* ---- the stability suite ---- */

static void bench_stability(struct bench *b)
{
	char dir[PATH_MAX], err[512];
	fmtf(dir, sizeof(dir), "%s/stability", b->c.work);
	if (!rl_mkdir_p(dir)) {
		fail(b, "stability: %s: %s", dir, strerror(errno));
		return;
	}
	note(b, "stability suite (%s)", b->c.quick ? "quick" : "full");
	struct stab_opts o = { .quick = b->c.quick, .workdir = dir, .ctx = b->ctx,
			       .log = b->c.quiet ? NULL : stderr };
	FILE *devnull = b->c.quiet ? fopen("/dev/null", "w") : NULL;
	if (devnull)
		o.log = devnull;
	int n = stab_run(&o, b->checks, MAX_CHECKS, err, sizeof(err));
	if (devnull)
		fclose(devnull);
	if (n < 0) {
		fail(b, "stability: %s", err);
		return;
	}
	b->nchecks = n;
	b->stab_ran = true;
	for (int i = 0; i < n; i++)
		if (b->checks[i].verdict == STAB_FAIL)
			fail(b, "stability: %s: %s: %.3g over its limit %.3g%s%s", b->checks[i].group,
			     b->checks[i].name, b->checks[i].value, b->checks[i].limit,
			     b->checks[i].note[0] ? ": " : "", b->checks[i].note);
}

/* ---- results: JSON ---- */

static cJSON *num_or_null(double v)
{
	return isfinite(v) ? cJSON_CreateNumber(v) : cJSON_CreateNull();
}

static void add_num(cJSON *o, const char *key, double v)
{
	cJSON_AddItemToObject(o, key, num_or_null(v));
}

/* Bytes of the cache at each step of its compression (lightspeed-2007 Fig. 5 and 10). */
struct cache_steps {
	double raw;           /* every micropolygon shaded, every dynamic channel, float */
	double visible;       /* the samples kept (static visibility), every dynamic channel */
	double unique;        /* constant and duplicate channels removed */
	double half;          /* channels in half where exact enough */
	double stored;        /* in the file, compressed */
};

static struct cache_steps cache_steps(const struct example_res *r)
{
	struct cache_steps c = {
		.raw = r->shaded_points * r->ch_dynamic * 4.0,
		.visible = r->shading_samples * r->ch_dynamic * 4.0,
		.unique = r->shading_samples * r->ch_unique * 4.0,
		.half = r->shading_samples * (r->ch_half * 2.0 + r->ch_float * 4.0),
		.stored = r->sample_bytes,
	};
	return c;
}

static cJSON *json_results(const struct bench *b, int argc, char **argv)
{
	cJSON *j = cJSON_CreateObject();
	cJSON_AddStringToObject(j, "relight", RELIGHT_VERSION);
	char cmd[2048] = "relight bench";
	for (int i = 1; i < argc; i++) {
		size_t len = strlen(cmd);
		fmtf(cmd + len, sizeof(cmd) - len, " %s", argv[i]);
	}
	cJSON_AddStringToObject(j, "command", cmd);
	char date[64];
	time_t t = time(NULL);
	struct tm tm;
	strftime(date, sizeof(date), "%Y-%m-%d %H:%M UTC", gmtime_r(&t, &tm));
	cJSON_AddStringToObject(j, "date", date);
	cJSON *m = cJSON_AddObjectToObject(j, "machine");
	struct utsname u;
	if (uname(&u) == 0) {
		cJSON_AddStringToObject(m, "system", u.sysname);
		cJSON_AddStringToObject(m, "release", u.release);
		cJSON_AddStringToObject(m, "arch", u.machine);
	}
	add_num(m, "cpus", (double)sysconf(_SC_NPROCESSORS_ONLN));
	cJSON_AddStringToObject(m, "device", b->device);
	add_num(m, "arith_gflops", b->arith_flops * 1e-9);
	cJSON_AddBoolToObject(j, "quick", b->c.quick);
	add_num(j, "edits", b->c.edits);

	cJSON *exs = cJSON_AddArrayToObject(j, "examples");
	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		cJSON *e = cJSON_CreateObject();
		cJSON_AddItemToArray(exs, e);
		cJSON_AddStringToObject(e, "name", r->name);
		cJSON_AddBoolToObject(e, "ok", r->ok);
		if (!r->ok)
			cJSON_AddStringToObject(e, "error", r->why);
		add_num(e, "width", r->width);
		add_num(e, "height", r->height);
		add_num(e, "lights", r->nlights);
		add_num(e, "samples", (double)r->samples);
		add_num(e, "gpu_bytes", (double)r->gpu_bytes);
		add_num(e, "render_s", r->render_s);
		add_num(e, "bake_s", r->bake_s);
		add_num(e, "load_ms", r->load_ms);
		add_num(e, "full_ms", r->full_ms);
		add_num(e, "first_edit_ms", r->first_edit_ms);
		add_num(e, "edit_ms", r->edit_ms);
		cJSON_AddStringToObject(e, "edit", r->edit);
		cJSON *lv = cJSON_AddArrayToObject(e, "levels");
		for (int L = 0; r->ok && L < LEVELS; L++) {
			const struct level_res *x = &r->lv[L];
			cJSON *l = cJSON_CreateObject();
			cJSON_AddItemToArray(lv, l);
			add_num(l, "level", L);
			add_num(l, "ms", x->ms);
			add_num(l, "cum_ms", x->cum_ms);
			add_num(l, "entries", (double)x->entries);
			add_num(l, "shaded", (double)x->shaded);
			add_num(l, "rmse", img_error_rmse(&x->err));
			add_num(l, "mean_pct", img_error_mean_pct(&x->err));
			add_num(l, "max_pct", img_error_max_pct(&x->err));
			add_num(l, "psnr_db", img_error_psnr_db(&x->err));
			add_num(l, "max_rel", x->err.max_rel);
			add_num(l, "over_1pct", (double)x->err.over_1pct);
		}
		cJSON *c = cJSON_AddObjectToObject(e, "cache");
		struct cache_steps cs = cache_steps(r);
		add_num(c, "shaded_points", r->shaded_points);
		add_num(c, "shading_samples", r->shading_samples);
		add_num(c, "subpixel_samples", r->subpixel_samples);
		add_num(c, "indirect_entries", r->indirect_entries);
		add_num(c, "shading_samples_per_pixel", r->shading_samples / r->pixels);
		add_num(c, "indirect_entries_per_pixel", r->indirect_entries / r->pixels);
		add_num(c, "channels_dynamic", r->ch_dynamic);
		add_num(c, "channels_varying", r->ch_varying);
		add_num(c, "channels_unique", r->ch_unique);
		add_num(c, "channels_half", r->ch_half);
		add_num(c, "channels_float", r->ch_float);
		add_num(c, "raw_bytes", cs.raw);
		add_num(c, "visible_bytes", cs.visible);
		add_num(c, "unique_bytes", cs.unique);
		add_num(c, "half_bytes", cs.half);
		add_num(c, "stored_bytes", cs.stored);
		add_num(c, "file_bytes", r->file_bytes);
		cJSON *la = cJSON_AddArrayToObject(e, "latency");
		for (int k = 0; k < r->nlat; k++) {
			const struct latency_row *x = &r->lat[k];
			cJSON *l = cJSON_CreateObject();
			cJSON_AddItemToArray(la, l);
			add_num(l, "clients", x->clients);
			add_num(l, "edits", x->edits);
			add_num(l, "median_ms", x->median);
			add_num(l, "p99_ms", x->p99);
			add_num(l, "final_median_ms", x->final_median);
			if (x->clients > 1) {
				add_num(l, "viewer_median_ms", x->viewer_median);
				add_num(l, "viewer_p99_ms", x->viewer_p99);
			}
			cJSON_AddBoolToObject(l, "meets_targets", latency_meets_targets(x));
		}
	}

	if (b->ncounts) {
		cJSON *lc = cJSON_AddObjectToObject(j, "light_counts");
		add_num(lc, "width", b->count_w);
		add_num(lc, "height", b->count_h);
		cJSON *rows = cJSON_AddArrayToObject(lc, "rows");
		for (int i = 0; i < b->ncounts; i++) {
			const struct count_res *c = &b->counts[i];
			cJSON *r = cJSON_CreateObject();
			cJSON_AddItemToArray(rows, r);
			add_num(r, "lights", c->lights);
			cJSON *w = cJSON_AddObjectToObject(r, "with_cache");
			cJSON *wo = cJSON_AddObjectToObject(r, "without_cache");
			cJSON *wl = cJSON_AddArrayToObject(w, "level_ms");
			cJSON *wol = cJSON_AddArrayToObject(wo, "level_ms");
			for (int L = 0; L < LEVELS; L++) {
				cJSON_AddItemToArray(wl, num_or_null(c->cache_ms[L]));
				cJSON_AddItemToArray(wol, num_or_null(c->nocache_ms[L]));
			}
			add_num(w, "edit_ms", c->cache_total);
			add_num(wo, "edit_ms", c->nocache_total);
			add_num(r, "cache_vs_nocache_max_rel", c->cache_vs_nocache);
			cJSON *rr = cJSON_AddObjectToObject(r, "vs_render");
			add_num(rr, "rmse", c->render_rmse);
			add_num(rr, "mean_pct", c->render_mean);
			add_num(rr, "max_pct", c->render_max);
		}
	}

	if (b->rays_ran) {
		const struct bench_rays *r = &b->rays;
		cJSON *o = cJSON_AddObjectToObject(j, "rays");
		add_num(o, "triangles", r->triangles);
		add_num(o, "rays", r->rays);
		add_num(o, "threads", r->threads);
		add_num(o, "embree_build_s", r->embree_build_s);
		add_num(o, "embree_s", r->embree_s);
		add_num(o, "embree_rays_per_s", r->embree_rays_per_s);
		add_num(o, "occluded", (double)r->occluded);
		if (b->ctx) {
			add_num(o, "gpu_build_s", r->gpu_build_s);
			add_num(o, "gpu_s", r->gpu_s);
			add_num(o, "gpu_rays_per_s", r->gpu_rays_per_s);
			add_num(o, "gpu_bytes", (double)r->gpu_bytes);
			add_num(o, "disagree", (double)r->disagree);
		}
	}
	if (b->stab_ran) {
		cJSON *s = cJSON_AddObjectToObject(j, "stability");
		cJSON_AddBoolToObject(s, "quick", b->c.quick);
		cJSON *cs = cJSON_AddArrayToObject(s, "checks");
		int count[3] = { 0, 0, 0 };
		static const char *const verdicts[3] = { "pass", "fail", "skip" };
		for (int i = 0; i < b->nchecks; i++) {
			const struct stab_check *k = &b->checks[i];
			cJSON *o = cJSON_CreateObject();
			cJSON_AddItemToArray(cs, o);
			cJSON_AddStringToObject(o, "group", k->group);
			cJSON_AddStringToObject(o, "name", k->name);
			add_num(o, "value", k->value);
			add_num(o, "limit", k->limit);
			cJSON_AddStringToObject(o, "verdict", verdicts[k->verdict]);
			if (k->note[0])
				cJSON_AddStringToObject(o, "note", k->note);
			count[k->verdict]++;
		}
		add_num(s, "passed", count[STAB_PASS]);
		add_num(s, "failed", count[STAB_FAIL]);
		add_num(s, "skipped", count[STAB_SKIP]);
	}
	cJSON_AddBoolToObject(j, "ok", !b->failed);
	if (b->failures[0])
		cJSON_AddStringToObject(j, "failures", b->failures);
	return j;
}

/* ---- results: text, Markdown, plots ---- */

/* A number for a table: "-" when it is not finite. */
static const char *fmt(char *buf, size_t cap, const char *f, double v)
{
	if (!isfinite(v))
		fmtf(buf, cap, "-");
	else
		fmtf(buf, cap, f, v);
	return buf;
}

static const char *psnr_text(char *buf, size_t cap, double v)
{
	if (isnan(v))
		fmtf(buf, cap, "identical");
	else
		fmtf(buf, cap, "%.1f", v);
	return buf;
}

static void level_table(FILE *f, const struct example_res *r, bool md)
{
	char a[32], bb[32], c[32], d[32], e[32], g[32], h[32];
	if (md)
		fprintf(f, "| level | ms | ms since the edit | entries | samples shaded | RMSE (linear) | "
			"mean %% | max %% | PSNR dB |\n|---|---|---|---|---|---|---|---|---|\n");
	else
		fprintf(f, "  %-6s %8s %8s %10s %10s %10s %9s %8s %9s\n", "level", "ms", "cumul",
			"entries", "shaded", "RMSE", "mean %", "max %", "PSNR dB");
	for (int L = 0; L < LEVELS; L++) {
		const struct level_res *x = &r->lv[L];
		const char *lname = L == GPU_SHOT_FINAL ? "3 (final)" : (L == 0 ? "0" : L == 1 ? "1" : "2");
		fmt(a, sizeof(a), "%.2f", x->ms);
		fmt(bb, sizeof(bb), "%.2f", x->cum_ms);
		fmt(c, sizeof(c), "%.2e", img_error_rmse(&x->err));
		fmt(d, sizeof(d), "%.4f", img_error_mean_pct(&x->err));
		fmt(e, sizeof(e), "%.3f", img_error_max_pct(&x->err));
		psnr_text(g, sizeof(g), img_error_psnr_db(&x->err));
		fmtf(h, sizeof(h), "%llu", (unsigned long long)x->shaded);
		if (md)
			fprintf(f, "| %s | %s | %s | %llu | %s | %s | %s | %s | %s |\n", lname, a, bb,
				(unsigned long long)x->entries, h, c, d, e, g);
		else
			fprintf(f, "  %-6d %8s %8s %10llu %10s %10s %9s %8s %9s\n", L, a, bb,
				(unsigned long long)x->entries, h, c, d, e, g);
	}
}

/*
 * The cache's totals and per pixel: lightspeed-2007 gives totals (Fig. 15: 11M
 * samples, 17M entries at 720x389); per pixel they compare with another size.
 */
static void cache_line(FILE *f, const struct example_res *r)
{
	if (!(r->shading_samples > 0.0) || !(r->pixels > 0.0))
		return;
	fprintf(f, "  cache: %.0f shading samples kept of %.0f micropolygons shaded (%.1f per "
		"pixel), %.0f indirect-framebuffer entries of %.0f subpixel samples (%.1f per "
		"pixel)\n", r->shading_samples, r->shaded_points, r->shading_samples / r->pixels,
		r->indirect_entries, r->subpixel_samples, r->indirect_entries / r->pixels);
}

static void print_text(FILE *f, const struct bench *b)
{
	fprintf(f, "relight bench on %s (%.0f GFLOP/s measured)\n\n", b->device,
		b->arith_flops * 1e-9);
	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		if (!r->ok) {
			fprintf(f, "%s: FAILED: %s\n\n", r->name, r->why);
			continue;
		}
		fprintf(f, "%s: %ux%u, %u lights, %llu samples; render %.2f s, bake %.2f s, load %.0f "
			"ms, every light %.1f ms\n  edit %s: to the final level %.1f ms (the first "
			"edit of the light %.1f ms)\n", r->name, r->width, r->height, r->nlights,
			(unsigned long long)r->samples, r->render_s, r->bake_s, r->load_ms,
			r->full_ms, r->edit, r->edit_ms, r->first_edit_ms);
		cache_line(f, r);
		level_table(f, r, false);
		for (int k = 0; k < r->nlat; k++)
			fprintf(f, "  latency through relightd, %d client%s: median %.1f ms, p99 %.1f ms%s\n",
				r->lat[k].clients, r->lat[k].clients > 1 ? "s" : "", r->lat[k].median,
				r->lat[k].p99, latency_meets_targets(&r->lat[k]) ? "" : " (MISS)");
		fputc('\n', f);
	}
	if (b->ncounts) {
		fprintf(f, "light counts (%dx%d street, one light's edit to the final level, ms):\n",
			b->count_w, b->count_h);
		fprintf(f, "  %-7s %12s %12s %10s\n", "lights", "with cache", "without", "ratio");
		for (int i = 0; i < b->ncounts; i++) {
			const struct count_res *c = &b->counts[i];
			fprintf(f, "  %-7d %12.2f %12.2f %10.2f\n", c->lights, c->cache_total,
				c->nocache_total, c->nocache_total / c->cache_total);
		}
		fputc('\n', f);
	}
	if (b->rays_ran) {
		const struct bench_rays *r = &b->rays;
		fprintf(f, "rays: %u shadow rays through %u triangles (%llu blocked)\n"
			"  Embree, %u threads: %.3g rays/s (built in %.3f s)\n", r->rays, r->triangles,
			(unsigned long long)r->occluded, r->threads, r->embree_rays_per_s,
			r->embree_build_s);
		if (b->ctx)
			fprintf(f, "  GPU shadow kernel: %.3g rays/s (hierarchy of %.1f MB built in "
				"%.3f s); %llu rays answered otherwise than Embree\n", r->gpu_rays_per_s,
				(double)r->gpu_bytes * 1e-6, r->gpu_build_s,
				(unsigned long long)r->disagree);
		fputc('\n', f);
	}
	if (b->stab_ran) {
		static const char *const verdicts[3] = { "pass", "FAIL", "skip" };
		fprintf(f, "stability suite (%s):\n", b->c.quick ? "quick" : "full");
		for (int i = 0; i < b->nchecks; i++) {
			const struct stab_check *k = &b->checks[i];
			char v[32], l[32];
			fprintf(f, "  %-4s %-12s %-60s %10s <= %-8s %s\n", verdicts[k->verdict], k->group,
				k->name, fmt(v, sizeof(v), "%.3g", k->value),
				isnan(k->limit) ? "(report)" : fmt(l, sizeof(l), "%.3g", k->limit),
				k->note);
		}
	}
}

/* The plots of the report into DIR/report/. */
static void write_plots(struct bench *b)
{
	char path[PATH_MAX], err[256];
	/* error against time, one line per example through its levels */
	struct plot_series s[MAX_EXAMPLES];
	double xs[MAX_EXAMPLES][LEVELS], ys[MAX_EXAMPLES][LEVELS];
	static const char *const lnames[LEVELS] = { "0", "1", "2", "final" };
	size_t ns = 0;
	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		if (!r->ok)
			continue;
		for (int L = 0; L < LEVELS; L++) {
			xs[ns][L] = r->lv[L].cum_ms;
			ys[ns][L] = img_error_mean_pct(&r->lv[L].err);
		}
		s[ns] = (struct plot_series){ .label = r->name, .x = xs[ns], .y = ys[ns], .n = LEVELS,
					      .color = -1, .point_labels = lnames };
		ns++;
	}
	if (ns) {
		struct plot_opts o = { .title = "Error against time after a one-light edit, per level",
				       .xlabel = "ms since the edit (level done)",
				       .ylabel = "mean error, % of the 8-bit range", .xlog = true,
				       .ylog = true };
		fmtf(path, sizeof(path), "%s/report/speed-error.svg", b->c.out);
		if (!plot_lines_svg(path, &o, s, ns, err, sizeof(err)))
			fail(b, "%s: %s", path, err);
		/* the same with the largest error */
		ns = 0;
		for (int i = 0; i < b->nex; i++) {
			if (!b->ex[i].ok)
				continue;
			for (int L = 0; L < LEVELS; L++)
				ys[ns][L] = img_error_max_pct(&b->ex[i].lv[L].err);
			ns++;
		}
		o.title = "Largest pixel error against time after a one-light edit";
		o.ylabel = "max error, % of the 8-bit range";
		fmtf(path, sizeof(path), "%s/report/speed-maxerror.svg", b->c.out);
		if (!plot_lines_svg(path, &o, s, ns, err, sizeof(err)))
			fail(b, "%s: %s", path, err);
	}
	/* time against light count */
	if (b->ncounts) {
		double x[MAX_COUNTS], y[4][MAX_COUNTS];
		for (int i = 0; i < b->ncounts; i++) {
			x[i] = b->counts[i].lights;
			y[0][i] = b->counts[i].cache_total;
			y[1][i] = b->counts[i].nocache_total;
			y[2][i] = b->counts[i].cache_ms[0];
			y[3][i] = b->counts[i].nocache_ms[0];
		}
		size_t n = (size_t)b->ncounts;
		struct plot_series ls[4] = {
			{ .label = "to the final level, light cache", .x = x, .y = y[0], .n = n, .color = 0 },
			{ .label = "to the final level, no cache", .x = x, .y = y[1], .n = n, .color = 0,
			  .dashed = true },
			{ .label = "level 0, light cache", .x = x, .y = y[2], .n = n, .color = 1 },
			{ .label = "level 0, no cache", .x = x, .y = y[3], .n = n, .color = 1,
			  .dashed = true },
		};
		char title[128];
		fmtf(title, sizeof(title), "One light's edit against the number of lights (%dx%d)",
			 b->count_w, b->count_h);
		struct plot_opts o = { .title = title, .xlabel = "lights in the shot",
				       .ylabel = "ms", .xlog = true, .ylog = true };
		fmtf(path, sizeof(path), "%s/report/lights.svg", b->c.out);
		if (!plot_lines_svg(path, &o, ls, 4, err, sizeof(err)))
			fail(b, "%s: %s", path, err);
	}
	/* compression */
	const char *groups[MAX_EXAMPLES];
	double vals[MAX_EXAMPLES * 3];
	size_t ng = 0;
	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		struct cache_steps cs = cache_steps(r);
		if (!(cs.stored > 0.0) || !(r->indirect_entries > 0.0) || !(r->shading_samples > 0.0))
			continue;
		groups[ng] = r->name;
		vals[ng * 3 + 0] = r->shaded_points / r->shading_samples;
		vals[ng * 3 + 1] = r->subpixel_samples / r->indirect_entries;
		vals[ng * 3 + 2] = cs.raw / cs.stored;
		ng++;
	}
	if (ng) {
		static const char *const series[3] = {
			"micropolygons shaded / samples kept",
			"subpixel samples / indirect entries",
			"cache bytes: raw / stored",
		};
		struct plot_opts o = { .title = "Cache compression (higher is smaller)",
				       .ylabel = "ratio", .ylog = true };
		fmtf(path, sizeof(path), "%s/report/compression.svg", b->c.out);
		if (!plot_bars_svg(path, &o, groups, ng, series, 3, vals, err, sizeof(err)))
			fail(b, "%s: %s", path, err);
	}
}

static void write_markdown(FILE *f, const struct bench *b, const cJSON *j)
{
	const cJSON *m = cJSON_GetObjectItemCaseSensitive(j, "machine");
	const char *date = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(j, "date"));
	const char *cmd = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(j, "command"));
	const char *sys = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(m, "system"));
	const char *arch = cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(m, "arch"));
	char a[32], c[32], d[32], e[32], g[32];
	fprintf(f, "# Speed against error\n\n"
		"Written by `relight bench`; do not edit by hand. To refresh it, from the top of the\n"
		"repository, after `./scripts/quickstart` (or any build into `build/`):\n\n"
		"```sh\nbuild/daemon/%s\n```\n\n"
		"This run: %s, relight %s, %s %s with %ld cores; GPU runtime on **%s**, whose\n"
		"arithmetic rate measured by `gpu_arith_rate` (independent multiply-add chains) is\n"
		"%.0f GFLOP/s. %s. Times are wall-clock medians of %d edits; compare figures from one\n"
		"run, not across machines. Raw figures: [report.json](report/report.json).\n\n",
		cmd && !strncmp(cmd, "relight ", 8) ? cmd : "relight bench -o docs", date ? date : "",
		RELIGHT_VERSION, sys ? sys : "", arch ? arch : "",
		sysconf(_SC_NPROCESSORS_ONLN), b->device, b->arith_flops * 1e-9,
		b->c.quick ? "Quick mode (smaller than the full run)" : "Full run", b->c.edits);

	fprintf(f, "## How the figures are taken\n\n"
		"For each example `examples/NAME/NAME.rib`: `relight render` renders the reference\n"
		"and `relight bake` bakes the shot (both timed, wall clock, all cores). The shot is\n"
		"loaded on the GPU runtime and rendered with every light; then one light is edited\n"
		"(the first that is not an ambient light: its intensity times 1.5 and its colour\n"
		"warmer) and the edit refined level by level, as a lighter sees it: level 0 shades\n"
		"one sample per 4x4 pixels, level 1 per 2x2, level 2 one per pixel, level 3 (final)\n"
		"all of them with every indirect-framebuffer entry. Each level's time is the median\n"
		"over edits alternating between two values (the first edit of a light, which also\n"
		"takes it out of the light cache, is reported apart). Each level is then compared\n"
		"with `relight render --set` of the same edit, as `relight diff` measures: RMSE of the\n"
		"linear values; mean and maximum absolute error of the displayed (sRGB) values in\n"
		"percent of the 8-bit range; PSNR of the displayed values. The coarse levels' errors\n"
		"are their honest cost: edges stay blocky until the final level. \"Samples shaded\"\n"
		"counts what each level's step shades: a level shades only the samples the coarser\n"
		"levels did not. relightd's final level is the same image, bit for bit, as the\n"
		"runtime's (`tests/cli/remote.sh`), so its latency rows carry these errors too.\n\n");

	fprintf(f, "## Summary\n\n| example | image | lights | samples | render s | bake s | level 0 ms "
		"| level 0 mean / max %% | final ms | final mean / max %% | latency ms (median, 1 "
		"client) |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		if (!r->ok) {
			fprintf(f, "| %s | failed: %s |||||||||\n", r->name, r->why);
			continue;
		}
		const struct level_res *l0 = &r->lv[0], *l3 = &r->lv[3];
		fprintf(f, "| %s | %ux%u | %u | %llu | %.2f | %.2f | %.2f | %.3f / %.1f | %.2f | "
			"%.4f / %.2f | %s |\n", r->name, r->width, r->height, r->nlights,
			(unsigned long long)r->samples, r->render_s, r->bake_s, l0->ms,
			img_error_mean_pct(&l0->err), img_error_max_pct(&l0->err), l3->cum_ms,
			img_error_mean_pct(&l3->err), img_error_max_pct(&l3->err),
			r->nlat ? fmt(a, sizeof(a), "%.1f", r->lat[0].median) : "-");
	}
	fprintf(f, "\n\"final ms\" is the whole refinement, from the edit to the final level.\n\n");
	bool have_ok = false;
	for (int i = 0; i < b->nex; i++)
		have_ok = have_ok || b->ex[i].ok;
	if (have_ok)
		fprintf(f, "![Mean error against time per level](report/speed-error.svg)\n\n"
			"![Largest error against time per level](report/speed-maxerror.svg)\n\n");

	for (int i = 0; i < b->nex; i++) {
		const struct example_res *r = &b->ex[i];
		if (!r->ok)
			continue;
		fprintf(f, "## %s\n\n%ux%u pixels, %u lights, %llu shading samples (%.1f MiB on the GPU). "
			"Reference render %.2f s; bake %.2f s; loading the shot %.0f ms (its kernels "
			"compiled); every light from nothing %.1f ms.\n\nEdit: `%s`. From the edit to the "
			"final level: %.2f ms (median); the light's first edit, which also takes it out "
			"of the light cache: %.2f ms.\n\n", r->name, r->width, r->height, r->nlights,
			(unsigned long long)r->samples, (double)r->gpu_bytes / 1048576.0, r->render_s,
			r->bake_s, r->load_ms, r->full_ms, r->edit, r->edit_ms, r->first_edit_ms);
		level_table(f, r, true);
		if (r->heatmap)
			fprintf(f, "\n![Error heat maps of levels 0 to 3 of %s](report/heat-%s.png)\n\n"
				"Error per pixel against the reference render of the edited RIB, levels 0, "
				"1, 2 and final from left to right (the largest over R, G, B; black 0, "
				"then blue, green, yellow, red, white at %.0f %% of the 8-bit range and "
				"above; each pixel of the map is the largest of its block).\n",
				r->name, r->name, HEAT_SCALE_PCT);
		for (int k = 0; k < r->nlat; k++) {
			if (k == 0)
				fprintf(f, "\nThrough relightd (edit sent to its first tile received, "
					"rgba8 tiles, %d edits):\n\n| clients | median ms | p99 ms | to the "
					"final level, median ms | viewers' median / p99 ms |\n"
					"|---|---|---|---|---|\n", r->lat[k].edits);
			const struct latency_row *x = &r->lat[k];
			fprintf(f, "| %d | %.1f | %.1f | %.1f | %s |\n", x->clients, x->median, x->p99,
				x->final_median,
				x->clients > 1 ? (fmtf(g, sizeof(g), "%.1f / %.1f", x->viewer_median,
							   x->viewer_p99), g) : "-");
		}
		fputc('\n', f);
	}

	if (b->ncounts) {
		fprintf(f, "## Light count\n\nA street of spheres (`bench_street_rib`: a ground and 32 "
			"spheres of three surface shaders, %dx%d pixels) baked with one spot light; "
			"lights 2 to 64 (an ambient, a distant, then point lights) added to the shot on "
			"the GPU (`gpu_shot_add_light`). The spot light's intensity is edited: with the "
			"light cache every other light stays frozen in it; without, every light is "
			"unfrozen and shaded again on every edit. Both give the same image (largest "
			"relative difference below); the final level is compared with `relight render` "
			"of the same scene.\n\n| lights | level 0 ms, cache | final ms, cache | level 0 "
			"ms, no cache | final ms, no cache | no cache / cache | cache vs no cache, max "
			"rel | vs render mean / max %% |\n|---|---|---|---|---|---|---|---|\n",
			b->count_w, b->count_h);
		for (int i = 0; i < b->ncounts; i++) {
			const struct count_res *x = &b->counts[i];
			fprintf(f, "| %d | %.2f | %.2f | %.2f | %.2f | %.2f | %s | %s / %s |\n", x->lights,
				x->cache_ms[0], x->cache_total, x->nocache_ms[0], x->nocache_total,
				x->nocache_total / x->cache_total,
				fmt(c, sizeof(c), "%.1e", x->cache_vs_nocache),
				fmt(d, sizeof(d), "%.4f", x->render_mean),
				fmt(e, sizeof(e), "%.2f", x->render_max));
		}
		fprintf(f, "\n![Time against light count](report/lights.svg)\n\n");
	}

	if (b->nex) {
		fprintf(f, "## Cache size and compression\n\nAs lightspeed-2007 Fig. 5 and 10 count "
			"them: the samples kept of the micropolygons shaded (static visibility), the "
			"indirect-framebuffer entries of the subpixel samples, the channels of a sample "
			"(dynamic: what the dynamic code reads; varying: not constant over the frame; "
			"unique: no duplicates), and the bytes of the samples at each step: raw (every "
			"micropolygon, every dynamic channel, float), kept samples, unique channels, "
			"half where exact enough, and as stored in the shot file (compressed).\n\n"
			"\"Per pixel\" divides the samples kept and the entries by the image's pixels, "
			"so that they compare with the paper's totals at another size (Fig. 15: 11M "
			"samples and 17M entries at 720x389, 39 and 61 per pixel).\n\n"
			"| example | micropolygons / samples | subpixel samples / entries | per pixel: "
			"samples / entries | channels dynamic / varying / unique (half) | raw MB | kept MB "
			"| unique MB | half MB | stored MB | raw / stored | shot file MB |\n|---|---|---|"
			"---|---|---|---|---|---|---|---|---|\n");
		for (int i = 0; i < b->nex; i++) {
			const struct example_res *r = &b->ex[i];
			struct cache_steps cs = cache_steps(r);
			if (!(cs.stored > 0.0))
				continue;
			fprintf(f, "| %s | %.0f / %.0f (%.2fx) | %.0f / %.0f (%.2fx) | %.1f / %.1f | %.0f "
				"/ %.0f / %.0f (%.0f) | %.2f | %.2f | %.2f | %.2f | %.2f | %.1fx | %.2f |\n",
				r->name, r->shaded_points, r->shading_samples,
				r->shaded_points / r->shading_samples, r->subpixel_samples,
				r->indirect_entries, r->subpixel_samples / r->indirect_entries,
				r->shading_samples / r->pixels, r->indirect_entries / r->pixels,
				r->ch_dynamic, r->ch_varying, r->ch_unique, r->ch_half, cs.raw * 1e-6,
				cs.visible * 1e-6, cs.unique * 1e-6, cs.half * 1e-6, cs.stored * 1e-6,
				cs.raw / cs.stored, r->file_bytes * 1e-6);
		}
		fprintf(f, "\n![Cache compression](report/compression.svg)\n\n");
	}

	if (b->rays_ran) {
		const struct bench_rays *r = &b->rays;
		fprintf(f, "## Rays per second\n\nOne shadow ray from each of %u floor points to a "
			"light, through %u triangles (spheres of 64 x 32 micropolygons, cut in two as "
			"the hider cuts them; %llu rays blocked), traced by Embree (`rtcOccluded1`, "
			"%u threads: the renderer's ray tracer) and by the GPU's shadow kernel "
			"(`daemon/gpu/shadowbvh.h`: the hierarchy ray-traced shadows follow an edited "
			"light with; device: %s). The error that goes with the speed: the rays the GPU "
			"answers otherwise than Embree.\n\n| tracer | build s | trace s | rays/s | "
			"rays answered otherwise |\n|---|--:|--:|--:|--:|\n| Embree | %.3f | %.3f | "
			"%.3g | (reference) |\n", r->rays, r->triangles,
			(unsigned long long)r->occluded, r->threads, b->device, r->embree_build_s,
			r->embree_s, r->embree_rays_per_s);
		if (b->ctx)
			fprintf(f, "| GPU shadow kernel | %.3f | %.3f | %.3g | %llu of %u |\n",
				r->gpu_build_s, r->gpu_s, r->gpu_rays_per_s,
				(unsigned long long)r->disagree, r->rays);
		fputc('\n', f);
	}
	if (b->stab_ran) {
		int count[3] = { 0, 0, 0 };
		for (int i = 0; i < b->nchecks; i++)
			count[b->checks[i].verdict]++;
		fprintf(f, "## Numerical stability\n\nThe stability suite (`daemon/bench/stability.h`; "
			"%s mode; CI runs the quick mode as the unit test `stability`): %d checks passed, "
			"%d failed, %d skipped. A check passes when its value is at most its limit; "
			"\"report\" rows are figures shown for comparison, not judged.\n\n| case | check "
			"| value | limit | verdict | note |\n|---|---|---|---|---|---|\n",
			b->c.quick ? "quick" : "full", count[STAB_PASS], count[STAB_FAIL],
			count[STAB_SKIP]);
		static const char *const verdicts[3] = { "pass", "**FAIL**", "skipped" };
		for (int i = 0; i < b->nchecks; i++) {
			const struct stab_check *k = &b->checks[i];
			fprintf(f, "| %s | %s | %s | %s | %s | %s |\n", k->group, k->name,
				fmt(a, sizeof(a), "%.3g", k->value),
				isnan(k->limit) ? "report" : fmt(c, sizeof(c), "%.3g", k->limit),
				isnan(k->limit) && k->verdict == STAB_PASS ? "-" : verdicts[k->verdict],
				k->note);
		}
		fputc('\n', f);
	}
	if (b->failures[0])
		fprintf(f, "## Failures\n\n%s\n", b->failures);
}

/* ---- rays per second ---- */

static void bench_ray_rates(struct bench *b)
{
	uint32_t side = b->c.quick ? 256 : 1024;
	uint32_t threads = (uint32_t)sysconf(_SC_NPROCESSORS_ONLN);
	char err[512] = "";
	note(b, "rays: %u shadow rays through %s spheres, Embree on %u threads%s", side * side,
	     b->c.quick ? "25" : "100", threads, b->ctx ? " and the GPU" : "");
	if (!bench_rays(b->ctx, b->c.quick, side, threads, &b->rays, err, sizeof(err))) {
		fail(b, "rays: %s", err);
		return;
	}
	b->rays_ran = true;
}

/* ---- the command ---- */

static bool find_relightd(struct bench_cfg *c)
{
	if (c->relightd_opt) {
		fmtf(c->relightd, sizeof(c->relightd), "%s", c->relightd_opt);
		return access(c->relightd, X_OK) == 0;
	}
	char dir[PATH_MAX];
	fmtf(dir, sizeof(dir), "%s", c->self);
	char *slash = strrchr(dir, '/');
	if (slash)
		*slash = 0;
	static const char *const beside[] = { "relightd", "server/relightd" };
	for (size_t i = 0; i < 2; i++) {
		fmtf(c->relightd, sizeof(c->relightd), "%s/%s", dir, beside[i]);
		if (access(c->relightd, X_OK) == 0)
			return true;
	}
	const char *path = getenv("PATH");
	while (path && *path) {
		size_t n = strcspn(path, ":");
		fmtf(c->relightd, sizeof(c->relightd), "%.*s/relightd", (int)n, path);
		if (n && access(c->relightd, X_OK) == 0)
			return true;
		path += n + (path[n] == ':');
	}
	c->relightd[0] = 0;
	return false;
}

/* @path made absolute into @out (which may be @path): false when it does not fit. */
static bool absolute(const char *path, char *out, size_t cap)
{
	char *abs = rl_path_absolute(path);
	bool ok = abs && strlen(abs) < cap;
	if (ok)
		memmove(out, abs, strlen(abs) + 1);
	free(abs);
	return ok;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The examples: every EXAMPLES/NAME/NAME.rib (sorted), or the names asked for. */
static int list_examples(const struct bench_cfg *c, char **names, int cap)
{
	int n = 0;
	if (c->nonly) {
		for (int i = 0; i < c->nonly && n < cap; i++)
			names[n++] = strdup(c->only_names[i]);
		return n;
	}
	DIR *d = opendir(c->examples);
	if (!d)
		return 0;
	struct dirent *e;
	while ((e = readdir(d)) && n < cap) {
		char rib[PATH_MAX];
		if (e->d_name[0] == '.')
			continue;
		fmtf(rib, sizeof(rib), "%s/%s/%s.rib", c->examples, e->d_name, e->d_name);
		if (is_file(rib))
			names[n++] = strdup(e->d_name);
	}
	closedir(d);
	qsort(names, (size_t)n, sizeof(char *), cmp_str);
	return n;
}

static int parse_parts(const char *s, unsigned *parts)
{
	*parts = 0;
	static const char *const names[] = { "examples", "lights", "latency", "stability", "rays" };
	while (*s) {
		size_t n = strcspn(s, ",");
		bool found = false;
		for (unsigned i = 0; i < 5; i++)
			if (strlen(names[i]) == n && !strncmp(s, names[i], n)) {
				*parts |= 1u << i;
				found = true;
			}
		if (!found)
			return -1;
		s += n + (s[n] == ',');
	}
	return *parts ? 0 : -1;
}

int cmd_bench(int argc, char **argv)
{
	static struct bench bench;      /* large: the checks and the examples' results */
	struct bench *b = &bench;
	memset(b, 0, sizeof(*b));
	struct bench_cfg *c = &b->c;
	c->parts = PART_ALL;
	c->edits = -1;
	c->viewers = 15;
	const char *examples_opt = NULL;
	static const struct option long_opts[] = {
		{ "out", required_argument, NULL, 'o' },
		{ "json", no_argument, NULL, 'j' },
		{ "quick", no_argument, NULL, 'Q' },
		{ "only", required_argument, NULL, 'O' },
		{ "stability", no_argument, NULL, 'S' },
		{ "examples", required_argument, NULL, 'E' },
		{ "edits", required_argument, NULL, 'e' },
		{ "viewers", required_argument, NULL, 'v' },
		{ "relightd", required_argument, NULL, 'r' },
		{ "work", required_argument, NULL, 'w' },
		{ "quiet", no_argument, NULL, 'q' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	int opt;
	uint32_t u;
	while ((opt = getopt_long(argc, argv, ":ho:q", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'o':
			c->out = optarg;
			break;
		case 'j':
			c->json = true;
			break;
		case 'Q':
			c->quick = true;
			break;
		case 'O':
			if (parse_parts(optarg, &c->parts) != 0)
				return usage_error("--only: '%s': expected parts among examples, "
						   "lights, latency, stability, rays", optarg);
			break;
		case 'S':
			c->parts = PART_STABILITY;
			break;
		case 'E':
			examples_opt = optarg;
			break;
		case 'e':
			if (!cmd_parse_uint(optarg, MAX_EDITS, &u) || u < 1)
				return usage_error("--edits: '%s' is not a count from 1 to %d", optarg,
						   MAX_EDITS);
			c->edits = (int)u;
			break;
		case 'v':
			if (!cmd_parse_uint(optarg, 255, &u))
				return usage_error("--viewers: '%s' is not a count from 0 to 255", optarg);
			c->viewers = (int)u;
			break;
		case 'r':
			c->relightd_opt = optarg;
			break;
		case 'w':
			c->work_opt = optarg;
			break;
		case 'q':
			c->quiet = true;
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (c->edits < 0)
		c->edits = c->quick ? 5 : 9;
	for (int i = optind; i < argc; i++) {
		if (c->nonly == MAX_EXAMPLES)
			return usage_error("more than %d examples named", MAX_EXAMPLES);
		if (!argv[i][0] || strchr(argv[i], '/') || argv[i][0] == '.')
			return usage_error("'%s' is not an example's name (a folder of --examples)",
					   argv[i]);
		c->only_names[c->nonly++] = argv[i];
	}
	/* this program, to run its render and bake */
	ssize_t n = readlink("/proc/self/exe", c->self, sizeof(c->self) - 1);
	if (n <= 0) {
		fprintf(stderr, "relight bench: error: cannot find this program: %s\n",
			strerror(errno));
		return CMD_FAILED;
	}
	c->self[n] = 0;
	if (examples_opt)
		fmtf(c->examples, sizeof(c->examples), "%s", examples_opt);
	else if (is_dir("examples"))
		fmtf(c->examples, sizeof(c->examples), "examples");
	else
		fmtf(c->examples, sizeof(c->examples), "%s/../examples",
			 RELIGHT_SOURCE_SHADER_DIR);
	if (!absolute(c->examples, c->examples, sizeof(c->examples)))
		return usage_error("--examples: '%s': path too long", c->examples);
	char *names[MAX_EXAMPLES];
	int nnames = 0;
	if (c->parts & (PART_EXAMPLES | PART_LATENCY)) {
		if (!is_dir(c->examples)) {
			fprintf(stderr, "relight bench: error: %s: no such folder (see --examples)\n",
				c->examples);
			return CMD_FAILED;
		}
		nnames = list_examples(c, names, MAX_EXAMPLES);
		for (int i = 0; i < nnames; i++) {
			char rib[PATH_MAX];
			fmtf(rib, sizeof(rib), "%s/%s/%s.rib", c->examples, names[i], names[i]);
			if (!is_file(rib)) {
				fprintf(stderr, "relight bench: error: %s: no such example\n", rib);
				for (int k = 0; k < nnames; k++)
					free(names[k]);
				return CMD_FAILED;
			}
		}
	}
	if ((c->parts & PART_LATENCY) && !find_relightd(c)) {
		fprintf(stderr, "relight bench: error: relightd not found (beside %s or on PATH);"
			" give it with --relightd, or leave latency out with --only\n", c->self);
		for (int k = 0; k < nnames; k++)
			free(names[k]);
		return CMD_FAILED;
	}
	/* the work folder and the report's */
	char tmpl[] = "/tmp/relight-bench-XXXXXX";
	bool own_work = !c->work_opt;
	if (own_work ? !mkdtemp(tmpl) : !rl_mkdir_p(c->work_opt)) {
		fprintf(stderr, "relight bench: error: %s: %s\n", own_work ? tmpl : c->work_opt,
			strerror(errno));
		return CMD_FAILED;
	}
	if (!absolute(own_work ? tmpl : c->work_opt, c->work, sizeof(c->work))) {
		fprintf(stderr, "relight bench: error: the work folder's path is too long\n");
		return CMD_FAILED;
	}
	char path[PATH_MAX];
	if (c->out) {
		fmtf(path, sizeof(path), "%s/report", c->out);
		if (!rl_mkdir_p(path)) {
			fprintf(stderr, "relight bench: error: %s: %s\n", path, strerror(errno));
			return CMD_FAILED;
		}
	}
	char err[512];
	b->ctx = gpu_create(err, sizeof(err));
	if (!b->ctx) {
		fprintf(stderr, "relight bench: no GPU context (%s): only the renderer's checks "
			"run\n", err);
		b->no_gpu = true;
		fmtf(b->device, sizeof(b->device), "none");
	} else {
		fmtf(b->device, sizeof(b->device), "%s", gpu_renderer(b->ctx));
		struct gpu_arith_rate rate;
		if (c->parts != PART_STABILITY && gpu_arith_rate(b->ctx, 5, 100.0, &rate))
			b->arith_flops = rate.flops;
	}
	note(b, "work folder %s; device %s", c->work, b->device);

	if (b->ctx && (c->parts & PART_EXAMPLES))
		for (int i = 0; i < nnames; i++)
			bench_example(b, names[i]);
	if (b->ctx && (c->parts & PART_LATENCY)) {
		if (!(c->parts & PART_EXAMPLES)) {
			/* latency alone: the shots are baked first */
			for (int i = 0; i < nnames; i++) {
				char src[PATH_MAX], dir[PATH_MAX], log[PATH_MAX], rib[PATH_MAX];
				struct example_res *r = &b->ex[b->nex++];
				memset(r, 0, sizeof(*r));
				fmtf(r->name, sizeof(r->name), "%s", names[i]);
				fmtf(src, sizeof(src), "%s/%s", c->examples, names[i]);
				fmtf(dir, sizeof(dir), "%s/%s", c->work, names[i]);
				fmtf(log, sizeof(log), "%s/bake.log", dir);
				fmtf(rib, sizeof(rib), "%s.rib", names[i]);
				char *bargv[] = { "relight", "bake", "-q", rib, NULL };
				note(b, "%s: baking", names[i]);
				if (!copy_folder(src, dir) || run_self(b, dir, log, bargv) < 0) {
					log_reason(log, r->why, sizeof(r->why));
					fail(b, "%s: %s", names[i], r->why);
				}
			}
		}
		for (int i = 0; i < b->nex; i++)
			if (b->ex[i].ok || !(c->parts & PART_EXAMPLES))
				bench_latency_of(b, &b->ex[i]);
	}
	if (b->ctx && (c->parts & PART_LIGHTS))
		bench_light_counts(b);
	if (c->parts & PART_STABILITY)
		bench_stability(b);
	if (c->parts & PART_RAYS)
		bench_ray_rates(b);
	for (int k = 0; k < nnames; k++)
		free(names[k]);

	/* the results */
	cJSON *j = json_results(b, argc, argv);
	if (c->json) {
		char *s = cJSON_Print(j);
		if (s)
			puts(s);
		free(s);
	} else {
		print_text(stdout, b);
	}
	if (c->out) {
		write_plots(b);
		char *s = cJSON_Print(j);
		fmtf(path, sizeof(path), "%s/report/report.json", c->out);
		if (!s || !rl_write_file_atomic(path, s, strlen(s), err, sizeof(err)))
			fail(b, "%s: %s", path, s ? err : "out of memory");
		free(s);
		char *md = NULL;
		size_t mdlen = 0;
		FILE *f = open_memstream(&md, &mdlen);
		if (f) {
			write_markdown(f, b, j);
			fclose(f);
		}
		fmtf(path, sizeof(path), "%s/report.md", c->out);
		if (!md || !rl_write_file_atomic(path, md, mdlen, err, sizeof(err)))
			fail(b, "%s: %s", path, md ? err : "out of memory");
		else
			note(b, "wrote %s", path);
		free(md);
	}
	cJSON_Delete(j);
	if (b->ctx)
		gpu_destroy(b->ctx);
	if (own_work && !b->failed)
		rl_remove_tree(c->work);
	else if (own_work)
		fprintf(stderr, "relight bench: the work folder is kept for its logs: %s\n", c->work);
	if (b->failed)
		return CMD_FAILED;
	return b->no_gpu ? 77 : CMD_OK;
}

/*
 * The latency of a light edit as a client of relightd sees it: from the
 * moment the edit is sent to the moment the first tile of that edit (its
 * coarsest level) is read off the client's socket.
 *
 *   bench_latency [--json FILE] [--shots DIR] [--edits N] [--viewers N]
 *                 [--param intensity|from] RELIGHT RELIGHTD EXAMPLES
 *
 * Each example EXAMPLES/NAME/NAME.rib is baked with `RELIGHT bake` into a
 * temporary shots folder (or the shot files of --shots DIR are used), and
 * RELIGHTD is started on 127.0.0.1 with a free port. For each shot one
 * editor client opens it (rgba8 tiles) and makes N edits (default 60) of one
 * light's intensity (or its position, --param from), alternating between
 * two values, each time waiting for the final level before the next edit;
 * then the same with V more clients (default 15), each on its own thread
 * and connection, that have the shot open and read every tile. A few edits
 * before each run are not counted: the first edit of a light takes it out
 * of the light cache.
 *
 * Printed per shot and number of clients: the median and the 99th
 * percentile (nearest rank) of the editor's latency, the median time until
 * the final level, and, with the viewers, their latency too. Targets: with
 * one client, median <= 20 ms and p99 <= 60 ms; with 16, median <= 40 ms.
 * A miss is reported ("MISS"), not a failure: the exit status is 1 only
 * when something failed (a bake, the daemon, a connection, a timeout), 77
 * when relightd has no GPU context.
 *
 * The measurement itself is daemon/bench/latency.c (shared with `relight
 * bench`); this program bakes, prints and writes the JSON.
 */
#include "fileutil.h"
#include "latency.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#define MAX_SHOTS 64
#define MAX_EDITS 10000
#define MAX_VIEWERS 256

static const char *prog = "bench_latency";

struct config {
	const char *relight, *relightd, *examples, *shots, *json;
	int edits, viewers;
	bool move;               /* edit "from" instead of "intensity" */
};

/* Run @argv in folder @dir and wait; true when it exits with status 0. */
static bool run_in(const char *dir, char *const argv[])
{
	pid_t pid = fork();
	if (pid < 0)
		return false;
	if (pid == 0) {
		if (chdir(dir) != 0)
			_exit(127);
		execv(argv[0], argv);
		_exit(127);
	}
	int st;
	while (waitpid(pid, &st, 0) < 0)
		if (errno != EINTR)
			return false;
	return WIFEXITED(st) && WEXITSTATUS(st) == 0;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/*
 * Bake each example into @shots: the regular files of its folder copied
 * there (a RIB may name files beside it), then `relight bake -q NAME.rib`
 * run there, so that shadow maps land where the daemon looks for them.
 * Fills @names (sorted) and *@n, the caller's to free even after a
 * failure; false on failure.
 */
static bool bake_examples(const struct config *c, const char *shots, char **names, int *n)
{
	*n = 0;
	DIR *d = opendir(c->examples);
	if (!d) {
		fprintf(stderr, "%s: cannot read %s: %s\n", prog, c->examples, strerror(errno));
		return false;
	}
	struct dirent *e;
	char path[8192];
	struct stat st;
	bool ok = true;
	while (ok && (e = readdir(d)) && *n < MAX_SHOTS) {
		if (e->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s/%s.rib", c->examples, e->d_name, e->d_name);
		if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) {
			names[*n] = strdup(e->d_name);
			ok = names[(*n)++] != NULL;
		}
	}
	closedir(d);
	if (!ok) {
		fprintf(stderr, "%s: out of memory\n", prog);
		return false;
	}
	if (*n == 0) {
		fprintf(stderr, "%s: no examples (NAME/NAME.rib) in %s\n", prog, c->examples);
		return false;
	}
	qsort(names, (size_t)*n, sizeof(char *), cmp_str);
	for (int i = 0; i < *n; i++) {
		char dir[4096], to[8192];
		snprintf(dir, sizeof(dir), "%s/%s", c->examples, names[i]);
		DIR *ed = opendir(dir);
		ok = ed != NULL;
		while (ok && (e = readdir(ed))) {
			snprintf(path, sizeof(path), "%s/%s", dir, e->d_name);
			snprintf(to, sizeof(to), "%s/%s", shots, e->d_name);
			if (e->d_name[0] != '.' && stat(path, &st) == 0 && S_ISREG(st.st_mode))
				ok = rl_copy_file(path, to);
		}
		if (ed)
			closedir(ed);
		char rib[512];
		snprintf(rib, sizeof(rib), "%s.rib", names[i]);
		char *argv[] = { (char *)c->relight, "bake", "-q", rib, NULL };
		fprintf(stderr, "%s: baking %s\n", prog, names[i]);
		if (!ok || !run_in(shots, argv)) {
			fprintf(stderr, "%s: cannot bake %s/%s.rib\n", prog, dir, names[i]);
			return false;
		}
	}
	return true;
}

static void print_table(const struct latency_row *rows, int n, const struct config *c)
{
	printf("\nEdit latency over relightd, edit sent to its first tile received (%s of one "
	       "light, %d edits a row):\n\n", c->move ? "position" : "intensity", c->edits);
	printf("%-12s %7s %10s %9s %9s %11s %9s  %-24s %s\n", "shot", "clients", "median ms",
	       "p99 ms", "final ms", "viewers med", "viewers p99", "target", "");
	for (int i = 0; i < n; i++) {
		const struct latency_row *r = &rows[i];
		char vm[32] = "-", vp[32] = "-";
		if (r->clients > 1 && !isnan(r->viewer_median)) {
			snprintf(vm, sizeof(vm), "%.2f", r->viewer_median);
			snprintf(vp, sizeof(vp), "%.2f", r->viewer_p99);
		}
		printf("%-12s %7d %10.2f %9.2f %9.2f %11s %9s  %-24s %s\n", r->shot, r->clients,
		       r->median, r->p99, r->final_median, vm, vp,
		       r->clients == 1 ? "median<=20 p99<=60" : "median<=40",
		       r->ok ? "ok" : "MISS");
	}
	int misses = 0, not0 = 0;
	for (int i = 0; i < n; i++) {
		misses += !rows[i].ok;
		not0 += rows[i].not_level0;
	}
	printf("\n%d of %d rows within target", n - misses, n);
	if (not0)
		printf("; %d edits' first tile was not of level 0", not0);
	printf("\n");
}

static bool write_json(const char *path, const struct latency_row *rows, int n, const struct config *c)
{
	FILE *f = fopen(path, "w");
	if (!f) {
		fprintf(stderr, "%s: cannot write %s: %s\n", prog, path, strerror(errno));
		return false;
	}
	fprintf(f, "{\"param\": \"%s\", \"edits\": %d, \"rows\": [", c->move ? "from" : "intensity",
		c->edits);
	for (int i = 0; i < n; i++) {
		const struct latency_row *r = &rows[i];
		fprintf(f, "%s\n  {\"shot\": \"%s\", \"clients\": %d, \"edits\": %d, "
			"\"median_ms\": %.3f, \"p99_ms\": %.3f, \"final_median_ms\": %.3f, ",
			i ? "," : "", r->shot, r->clients, r->edits, r->median, r->p99, r->final_median);
		if (r->clients > 1 && !isnan(r->viewer_median))
			fprintf(f, "\"viewers_median_ms\": %.3f, \"viewers_p99_ms\": %.3f, ",
				r->viewer_median, r->viewer_p99);
		fprintf(f, "\"target_median_ms\": %d, ", r->clients == 1 ? 20 : 40);
		if (r->clients == 1)
			fprintf(f, "\"target_p99_ms\": 60, ");
		fprintf(f, "\"first_tile_not_level0\": %d, \"ok\": %s}", r->not_level0,
			r->ok ? "true" : "false");
	}
	fprintf(f, "\n]}\n");
	return fclose(f) == 0;
}

static void usage(FILE *out)
{
	fprintf(out, "usage: %s [--json FILE] [--shots DIR] [--edits N] [--viewers N]\n"
		"                     [--param intensity|from] RELIGHT RELIGHTD EXAMPLES\n", prog);
}

/* @path made absolute (against the current folder) into @out; the program must exist. */
static bool absolute(const char *path, char *out, size_t cap)
{
	char cwd[PATH_MAX];
	if (path[0] == '/')
		snprintf(out, cap, "%s", path);
	else if (getcwd(cwd, sizeof(cwd)))
		snprintf(out, cap, "%s/%s", cwd, path);
	else
		out[0] = '\0';
	if (!out[0] || access(out, X_OK) != 0) {
		fprintf(stderr, "%s: no program %s\n", prog, path);
		return false;
	}
	return true;
}

int main(int argc, char **argv)
{
	struct config c = { .edits = 60, .viewers = 15 };
	const char *pos[3];
	int npos = 0;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];
		bool has = i + 1 < argc;
		if (!strcmp(a, "--json") && has) {
			c.json = argv[++i];
		} else if (!strcmp(a, "--shots") && has) {
			c.shots = argv[++i];
		} else if (!strcmp(a, "--edits") && has) {
			c.edits = atoi(argv[++i]);
		} else if (!strcmp(a, "--viewers") && has) {
			c.viewers = atoi(argv[++i]);
		} else if (!strcmp(a, "--param") && has) {
			const char *p = argv[++i];
			if (strcmp(p, "intensity") && strcmp(p, "from")) {
				usage(stderr);
				return 2;
			}
			c.move = !strcmp(p, "from");
		} else if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
			usage(stdout);
			return 0;
		} else if (a[0] == '-' || npos == 3) {
			usage(stderr);
			return 2;
		} else {
			pos[npos++] = a;
		}
	}
	if (npos < 2 || (npos < 3 && !c.shots) || c.edits < 1 || c.edits > MAX_EDITS ||
	    c.viewers < 0 || c.viewers > MAX_VIEWERS) {
		usage(stderr);
		return 2;
	}
	/* absolute: the bakes run in the shots folder */
	char relight[PATH_MAX + 256], relightd[PATH_MAX + 256];
	if (!absolute(pos[0], relight, sizeof(relight)) ||
	    !absolute(pos[1], relightd, sizeof(relightd)))
		return 1;
	c.relight = relight;
	c.relightd = relightd;
	c.examples = npos > 2 ? pos[2] : NULL;

	/* the examples baked into a temporary folder, or the shots given */
	char tmp[] = "/tmp/relight-latency-XXXXXX", shots[4096];
	char *names[MAX_SHOTS];
	int nshots = 0;
	bool have_tmp = false;
	struct latency_row *rows = calloc(2 * MAX_SHOTS, sizeof(*rows));
	int status = 1;
	if (!rows) {
		fprintf(stderr, "%s: out of memory\n", prog);
		goto out;
	}
	if (c.shots) {
		snprintf(shots, sizeof(shots), "%s", c.shots);
	} else {
		if (!mkdtemp(tmp)) {
			fprintf(stderr, "%s: cannot make a temporary folder: %s\n", prog,
				strerror(errno));
			goto out;
		}
		have_tmp = true;
		snprintf(shots, sizeof(shots), "%s/shots", tmp);
		if (mkdir(shots, 0755) != 0) {
			fprintf(stderr, "%s: cannot make %s: %s\n", prog, shots, strerror(errno));
			goto out;
		}
		if (!bake_examples(&c, shots, names, &nshots))
			goto out;
	}

	struct latency_opts o = {
		.relightd = c.relightd,
		.shots = shots,
		/* --shots: every shot of the folder; else the examples just baked */
		.names = c.shots ? NULL : (const char *const *)names,
		.nnames = c.shots ? 0 : (size_t)nshots,
		.edits = c.edits,
		.viewers = c.viewers,
		.move = c.move,
		.log = stderr,
	};
	char err[1024];
	int nrows = latency_run(&o, rows, 2 * MAX_SHOTS, err, sizeof(err));
	if (nrows == -77) {
		printf("SKIP: %s\n", err);
		status = 77;
		goto out;
	}
	bool ok = nrows >= 0;
	if (!ok) {
		fprintf(stderr, "%s: %s\n", prog, err);
		/* the rows measured before the failure, if any, still go out */
		nrows = 0;
		while (nrows < 2 * MAX_SHOTS && rows[nrows].clients > 0)
			nrows++;
		if (nrows == 0)
			goto out;
	}
	print_table(rows, nrows, &c);
	if (c.json && !write_json(c.json, rows, nrows, &c))
		ok = false;
	status = ok ? 0 : 1;
out:
	if (have_tmp)
		rl_remove_tree(tmp);
	for (int i = 0; i < nshots; i++)
		free(names[i]);
	free(rows);
	return status;
}

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
 */
#include "remote.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_SHOTS 64
#define MAX_EDITS 10000
#define MAX_VIEWERS 256
#define WARMUP_EDITS 3
#define OPEN_TIMEOUT_MS 300000   /* a first open loads the shot and compiles its kernels */
#define EDIT_TIMEOUT_MS 60000

static const char *prog = "bench_latency";

struct config {
	const char *relight, *relightd, *examples, *shots, *json;
	int edits, viewers;
	bool move;               /* edit "from" instead of "intensity" */
};

/* One row of the table. */
struct row {
	char shot[128];
	int clients;
	int edits;
	double median, p99, final_median;   /* the editor's, ms */
	double viewer_median, viewer_p99;   /* the viewers' (clients > 1), ms */
	int not_level0;                     /* edits whose first tile was not level 0 */
	bool ok;
};

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
	if (n <= 0)
		return NAN;
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The 99th percentile, nearest rank. */
static double p99(double *v, int n)
{
	if (n <= 0)
		return NAN;
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	int k = (int)ceil(0.99 * n);
	return v[(k < 1 ? 1 : k) - 1];
}

/* ---- processes and files ---- */

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

static bool copy_file(const char *from, const char *to)
{
	int in = open(from, O_RDONLY), out = in < 0 ? -1 :
		 open(to, O_WRONLY | O_CREAT | O_TRUNC, 0644);
	bool ok = in >= 0 && out >= 0;
	char buf[65536];
	ssize_t n;
	while (ok && (n = read(in, buf, sizeof(buf))) != 0) {
		ok = n > 0 && write(out, buf, (size_t)n) == n;
	}
	if (in >= 0)
		close(in);
	if (out >= 0 && close(out) != 0)
		ok = false;
	return ok;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/*
 * Bake each example into @shots: the regular files of its folder copied
 * there (a RIB may name files beside it), then `relight bake -q NAME.rib`
 * run there, so that shadow maps land where the daemon looks for them.
 * Fills @names (sorted); returns how many, -1 on failure.
 */
static int bake_examples(const struct config *c, const char *shots, char **names)
{
	DIR *d = opendir(c->examples);
	if (!d) {
		fprintf(stderr, "%s: cannot read %s: %s\n", prog, c->examples, strerror(errno));
		return -1;
	}
	int n = 0;
	struct dirent *e;
	char path[8192];
	struct stat st;
	while ((e = readdir(d)) && n < MAX_SHOTS) {
		if (e->d_name[0] == '.')
			continue;
		snprintf(path, sizeof(path), "%s/%s/%s.rib", c->examples, e->d_name, e->d_name);
		if (stat(path, &st) == 0 && S_ISREG(st.st_mode))
			names[n++] = strdup(e->d_name);
	}
	closedir(d);
	qsort(names, (size_t)n, sizeof(char *), cmp_str);
	for (int i = 0; i < n; i++) {
		char dir[4096], to[8192];
		snprintf(dir, sizeof(dir), "%s/%s", c->examples, names[i]);
		DIR *ed = opendir(dir);
		bool ok = ed != NULL;
		while (ok && (e = readdir(ed))) {
			snprintf(path, sizeof(path), "%s/%s", dir, e->d_name);
			snprintf(to, sizeof(to), "%s/%s", shots, e->d_name);
			if (e->d_name[0] != '.' && stat(path, &st) == 0 && S_ISREG(st.st_mode))
				ok = copy_file(path, to);
		}
		if (ed)
			closedir(ed);
		char rib[512];
		snprintf(rib, sizeof(rib), "%s.rib", names[i]);
		char *argv[] = { (char *)c->relight, "bake", "-q", rib, NULL };
		fprintf(stderr, "%s: baking %s\n", prog, names[i]);
		if (!ok || !run_in(shots, argv)) {
			fprintf(stderr, "%s: cannot bake %s/%s.rib\n", prog, dir, names[i]);
			return -1;
		}
	}
	return n;
}

/* The shot files of @dir: NAME.shot.exr gives NAME. */
static int list_shots(const char *dir, char **names)
{
	DIR *d = opendir(dir);
	if (!d) {
		fprintf(stderr, "%s: cannot read %s: %s\n", prog, dir, strerror(errno));
		return -1;
	}
	int n = 0;
	struct dirent *e;
	while ((e = readdir(d)) && n < MAX_SHOTS) {
		size_t len = strlen(e->d_name);
		if (len > 9 && e->d_name[0] != '.' && !strcmp(e->d_name + len - 9, ".shot.exr"))
			names[n++] = strndup(e->d_name, len - 9);
	}
	closedir(d);
	qsort(names, (size_t)n, sizeof(char *), cmp_str);
	return n;
}

/* The daemon, its stdout read for the line that gives its port. */
struct daemon {
	pid_t pid;
	char url[300];
	char log[4200];
};

static bool daemon_start(const struct config *c, const char *shots, const char *tmp,
			 struct daemon *dm)
{
	int fds[2];
	snprintf(dm->log, sizeof(dm->log), "%s/relightd.log", tmp);
	int logfd = open(dm->log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
	if (logfd < 0 || pipe(fds) != 0) {
		fprintf(stderr, "%s: cannot start relightd: %s\n", prog, strerror(errno));
		return false;
	}
	dm->pid = fork();
	if (dm->pid == 0) {
		dup2(fds[1], STDOUT_FILENO);
		dup2(logfd, STDERR_FILENO);
		close(fds[0]);
		close(fds[1]);
		close(logfd);
		char *argv[] = { (char *)c->relightd, "--listen", "127.0.0.1:0", "--shots",
				 (char *)shots, "--log-level", "warn", NULL };
		execv(argv[0], argv);
		_exit(127);
	}
	close(fds[1]);
	close(logfd);
	if (dm->pid < 0) {
		close(fds[0]);
		return false;
	}
	/* the first line, within a minute */
	char line[512];
	size_t len = 0;
	double t0 = remote_now_ms();
	while (len < sizeof(line) - 1 && (len == 0 || line[len - 1] != '\n')) {
		struct pollfd p = { .fd = fds[0], .events = POLLIN };
		int left = (int)(60000 - (remote_now_ms() - t0));
		if (left <= 0 || poll(&p, 1, left) <= 0)
			break;
		ssize_t n = read(fds[0], line + len, sizeof(line) - 1 - len);
		if (n <= 0)
			break;
		len += (size_t)n;
	}
	close(fds[0]);
	line[len] = '\0';
	char host[256];
	if (sscanf(line, "relightd: listening on http://%255[^/]/", host) != 1) {
		fprintf(stderr, "%s: relightd did not start (its first line: '%.*s'); its log is %s\n",
			prog, (int)strcspn(line, "\n"), line, dm->log);
		return false;
	}
	snprintf(dm->url, sizeof(dm->url), "ws://%s/ws", host);
	return true;
}

/* SIGTERM, and its exit status (-1: none within 30 s, then killed). */
static int daemon_stop(struct daemon *dm)
{
	kill(dm->pid, SIGTERM);
	double t0 = remote_now_ms();
	int st;
	for (;;) {
		pid_t p = waitpid(dm->pid, &st, WNOHANG);
		if (p == dm->pid)
			return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
		if (p < 0 && errno != EINTR)
			return -1;
		if (remote_now_ms() - t0 > 30000) {
			kill(dm->pid, SIGKILL);
			waitpid(dm->pid, &st, 0);
			return -1;
		}
		nanosleep(&(struct timespec){ .tv_nsec = 20000000 }, NULL);
	}
}

/* Whether the daemon's log says it has no GPU context. */
static bool log_says_no_gpu(const char *log)
{
	FILE *f = fopen(log, "r");
	char line[1024];
	bool found = false;
	while (f && !found && fgets(line, sizeof(line), f))
		found = strstr(line, "no GPU context") != NULL;
	if (f)
		fclose(f);
	return found;
}

/* ---- clients ---- */

static cJSON *open_request(const char *shot)
{
	cJSON *j = cJSON_CreateObject();
	cJSON_AddStringToObject(j, "op", "open");
	cJSON_AddStringToObject(j, "shot", shot);
	cJSON_AddStringToObject(j, "format", "rgba8");
	return j;
}

static double num(const cJSON *j, const char *name, double dflt)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, name);
	return cJSON_IsNumber(v) ? v->valuedouble : dflt;
}

/*
 * Open @shot; wait for the final level of the state it opens on. Returns
 * the "opened" reply (the caller's), NULL with the reason printed.
 */
static cJSON *open_shot(struct remote *r, const char *shot, const char *who)
{
	cJSON *req = open_request(shot), *reply = NULL;
	bool ok = remote_request(r, req, &reply, OPEN_TIMEOUT_MS);
	cJSON_Delete(req);
	const char *code, *msg;
	if (!ok || remote_reply_error(reply, &code, &msg)) {
		fprintf(stderr, "%s: %s: open %s: %s%s%s\n", prog, who, shot,
			ok ? code : remote_error(r), ok ? ": " : "", ok ? msg : "");
		cJSON_Delete(reply);
		return NULL;
	}
	double edit = num(reply, "edit", 0), final = num(reply, "levels", 4) - 1;
	double deadline = remote_now_ms() + OPEN_TIMEOUT_MS;
	for (;;) {
		struct remote_event ev;
		int left = (int)(deadline - remote_now_ms());
		enum remote_kind k = remote_next(r, &ev, left > 0 ? left : 0);
		bool done = k == REMOTE_TEXT && !strcmp(ev.op, "level") &&
			    num(ev.json, "edit", -1) >= edit && num(ev.json, "level", -1) >= final;
		remote_event_finish(&ev);
		if (done)
			return reply;
		if (k == REMOTE_TIMEOUT || k == REMOTE_CLOSED) {
			fprintf(stderr, "%s: %s: open %s: the first image did not come: %s\n", prog,
				who, shot, k == REMOTE_TIMEOUT ? "timed out" : remote_error(r));
			cJSON_Delete(reply);
			return NULL;
		}
	}
}

/* The light to edit: the first with the parameter, preferring one that is not ambient. */
static bool pick_light(const cJSON *opened, const char *param, char *light, size_t cap,
		       float value[3], int *nvalues)
{
	const cJSON *l, *found = NULL, *found_param = NULL;
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(opened, "lights")) {
		const cJSON *p;
		cJSON_ArrayForEach(p, cJSON_GetObjectItemCaseSensitive(l, "params")) {
			const cJSON *name = cJSON_GetObjectItemCaseSensitive(p, "name");
			if (!cJSON_IsString(name) || strcmp(name->valuestring, param))
				continue;
			const cJSON *sh = cJSON_GetObjectItemCaseSensitive(l, "shader");
			bool ambient = cJSON_IsString(sh) && strstr(sh->valuestring, "ambient");
			if (!found || !ambient) {
				found = l;
				found_param = p;
			}
			if (!ambient)
				goto done;
		}
	}
done:
	if (!found)
		return false;
	const cJSON *name = cJSON_GetObjectItemCaseSensitive(found, "name");
	snprintf(light, cap, "%s", cJSON_IsString(name) ? name->valuestring : "");
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(found_param, "value");
	*nvalues = 0;
	if (cJSON_IsNumber(v)) {
		value[(*nvalues)++] = (float)v->valuedouble;
	} else {
		const cJSON *x;
		cJSON_ArrayForEach(x, v)
			if (*nvalues < 3 && cJSON_IsNumber(x))
				value[(*nvalues)++] = (float)x->valuedouble;
	}
	return *nvalues > 0;
}

/* What the editor edits: a light's parameter, between two values. */
struct target {
	char light[256];
	const char *param;
	float base[3];
	int n;
};

static cJSON *edit_request(const struct target *t, int i)
{
	cJSON *j = cJSON_CreateObject(), *params = cJSON_CreateObject();
	cJSON_AddStringToObject(j, "op", "set");
	cJSON_AddStringToObject(j, "light", t->light);
	if (t->n == 1) {
		/* 0.8x and 1x of the intensity in turn */
		cJSON_AddNumberToObject(params, t->param, t->base[0] * (i % 2 ? 1.0 : 0.8));
	} else {
		/* a step of 0.25 along x and back */
		cJSON *a = cJSON_AddArrayToObject(params, t->param);
		for (int k = 0; k < t->n; k++)
			cJSON_AddItemToArray(a, cJSON_CreateNumber(t->base[k] +
								   (k == 0 && i % 2 == 0 ? 0.25 : 0.0)));
	}
	cJSON_AddItemToObject(j, "params", params);
	return j;
}

/*
 * One measured edit: its ack's edit number, the latency to its first tile
 * and to its final level. False with the reason printed.
 */
static bool one_edit(struct remote *r, const struct target *t, int i, double *t0, int64_t *edit,
		     double *first_ms, double *final_ms, int *first_level)
{
	cJSON *req = edit_request(t, i), *reply = NULL;
	*t0 = remote_now_ms();
	bool ok = remote_request(r, req, &reply, EDIT_TIMEOUT_MS);
	cJSON_Delete(req);
	const char *code, *msg;
	if (!ok || remote_reply_error(reply, &code, &msg) ||
	    !cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(reply, "edit"))) {
		fprintf(stderr, "%s: set %s.%s: %s%s%s\n", prog, t->light, t->param,
			ok ? code : remote_error(r), ok ? ": " : "", ok ? msg : "");
		cJSON_Delete(reply);
		return false;
	}
	*edit = (int64_t)num(reply, "edit", -1);
	cJSON_Delete(reply);
	*first_ms = -1;
	double deadline = *t0 + EDIT_TIMEOUT_MS;
	for (;;) {
		struct remote_event ev;
		int left = (int)(deadline - remote_now_ms());
		enum remote_kind k = remote_next(r, &ev, left > 0 ? left : 0);
		if (k == REMOTE_TILE && ev.tile.edit == (uint32_t)*edit && *first_ms < 0) {
			*first_ms = ev.t_ms - *t0;
			*first_level = (int)ev.tile.level;
		}
		bool done = k == REMOTE_TEXT && !strcmp(ev.op, "level") &&
			    num(ev.json, "edit", -1) == (double)*edit && num(ev.json, "level", -1) >= 3;
		if (done)
			*final_ms = ev.t_ms - *t0;
		remote_event_finish(&ev);
		if (done && *first_ms < 0)
			fprintf(stderr, "%s: edit %lld: its final level came with no tile\n", prog,
				(long long)*edit);
		if (done)
			return *first_ms >= 0;
		if (k == REMOTE_TIMEOUT || k == REMOTE_CLOSED || k == REMOTE_INVALID) {
			fprintf(stderr, "%s: edit %lld: %s\n", prog, (long long)*edit,
				k == REMOTE_TIMEOUT ? "its final level did not come in time" :
				k == REMOTE_INVALID ? ev.reason : remote_error(r));
			return false;
		}
	}
}

/* A viewer: its own connection on its own thread, reading every tile. */
struct viewer {
	pthread_t thread;
	const char *url, *shot;
	int index;
	/* when the first tile of each edit came */
	int64_t edits[MAX_EDITS];
	double first[MAX_EDITS];
	int nedits;
	uint64_t tiles;
	bool failed;
};

static pthread_mutex_t viewers_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t viewers_cond = PTHREAD_COND_INITIALIZER;
static int viewers_ready;
static atomic_int viewers_stop;

static void viewer_ready(struct viewer *v, bool ok)
{
	pthread_mutex_lock(&viewers_lock);
	v->failed = !ok;
	viewers_ready++;
	pthread_cond_broadcast(&viewers_cond);
	pthread_mutex_unlock(&viewers_lock);
}

static void *viewer_main(void *arg)
{
	struct viewer *v = arg;
	char err[512], who[64];
	snprintf(who, sizeof(who), "viewer %d", v->index);
	struct remote *r = remote_connect(v->url, NULL, NULL, err, sizeof(err));
	if (!r) {
		fprintf(stderr, "%s: %s: %s\n", prog, who, err);
		viewer_ready(v, false);
		return NULL;
	}
	cJSON *opened = open_shot(r, v->shot, who);
	bool ok = opened != NULL;
	cJSON_Delete(opened);
	viewer_ready(v, ok);
	int64_t last = -1;
	while (ok && !atomic_load(&viewers_stop)) {
		struct remote_event ev;
		enum remote_kind k = remote_next(r, &ev, 50);
		if (k == REMOTE_TILE) {
			v->tiles++;
			if ((int64_t)ev.tile.edit > last && v->nedits < MAX_EDITS) {
				last = ev.tile.edit;
				v->edits[v->nedits] = last;
				v->first[v->nedits++] = ev.t_ms;
			}
		}
		remote_event_finish(&ev);
		if (k == REMOTE_CLOSED) {
			fprintf(stderr, "%s: %s: %s\n", prog, who, remote_error(r));
			v->failed = true;
			break;
		}
	}
	remote_close(r);
	return NULL;
}

/* Start @n viewers on @shot and wait until each has the shot's image. */
static bool viewers_start(struct viewer *vs, int n, const char *url, const char *shot)
{
	viewers_ready = 0;
	atomic_store(&viewers_stop, 0);
	for (int i = 0; i < n; i++) {
		memset(&vs[i], 0, sizeof(vs[i]));
		vs[i].url = url;
		vs[i].shot = shot;
		vs[i].index = i + 1;
		if (pthread_create(&vs[i].thread, NULL, viewer_main, &vs[i]) != 0) {
			fprintf(stderr, "%s: cannot start a thread\n", prog);
			atomic_store(&viewers_stop, 1);
			for (int k = 0; k < i; k++)
				pthread_join(vs[k].thread, NULL);
			return false;
		}
	}
	pthread_mutex_lock(&viewers_lock);
	while (viewers_ready < n)
		pthread_cond_wait(&viewers_cond, &viewers_lock);
	pthread_mutex_unlock(&viewers_lock);
	bool ok = true;
	for (int i = 0; i < n; i++)
		ok = ok && !vs[i].failed;
	return ok;
}

static bool viewers_stop_all(struct viewer *vs, int n)
{
	atomic_store(&viewers_stop, 1);
	bool ok = true;
	for (int i = 0; i < n; i++) {
		pthread_join(vs[i].thread, NULL);
		ok = ok && !vs[i].failed;
	}
	return ok;
}

/*
 * Measure the edits of one run; @vs (NULL: none) are the viewers. Fills
 * @row but for its name and verdict.
 */
static bool measure(struct remote *r, const struct target *t, const struct config *c,
		    struct viewer *vs, int nviewers, struct row *row)
{
	int n = c->edits;
	double *lat = calloc((size_t)n, sizeof(double)), *fin = calloc((size_t)n, sizeof(double));
	double *t0s = calloc((size_t)n, sizeof(double));
	int64_t *edits = calloc((size_t)n, sizeof(int64_t));
	size_t vcap = (size_t)n * (size_t)(nviewers > 0 ? nviewers : 1);
	double *vlat = calloc(vcap, sizeof(double));
	bool ok = lat && fin && t0s && edits && vlat;
	double t0, first, final;
	int64_t e;
	int level;
	for (int i = 0; ok && i < WARMUP_EDITS; i++)
		ok = one_edit(r, t, i, &t0, &e, &first, &final, &level);
	row->not_level0 = 0;
	for (int i = 0; ok && i < n; i++) {
		ok = one_edit(r, t, i + WARMUP_EDITS, &t0s[i], &edits[i], &lat[i], &fin[i], &level);
		row->not_level0 += ok && level != 0;
	}
	row->edits = ok ? n : 0;
	if (vs && ok)
		ok = viewers_stop_all(vs, nviewers);
	if (ok) {
		/* the viewers' latencies: their first tile of each measured edit */
		int nv = 0;
		for (int v = 0; vs && v < nviewers; v++)
			for (int i = 0; i < n; i++)
				for (int k = 0; k < vs[v].nedits; k++)
					if (vs[v].edits[k] == edits[i]) {
						vlat[nv++] = vs[v].first[k] - t0s[i];
						break;
					}
		row->median = median(lat, n);
		row->p99 = p99(lat, n);
		row->final_median = median(fin, n);
		row->viewer_median = median(vlat, nv);
		row->viewer_p99 = p99(vlat, nv);
	}
	free(lat);
	free(fin);
	free(t0s);
	free(edits);
	free(vlat);
	return ok;
}

static bool verdict(const struct row *r)
{
	if (r->clients == 1)
		return r->median <= 20.0 && r->p99 <= 60.0;
	return r->median <= 40.0;
}

/* Both runs on one shot. */
static bool bench_shot(const struct config *c, const char *url, const char *shot,
		       struct row *rows, int *nrows)
{
	char err[512];
	struct remote *r = remote_connect(url, NULL, NULL, err, sizeof(err));
	if (!r) {
		fprintf(stderr, "%s: editor: %s\n", prog, err);
		return false;
	}
	struct target t = { .param = c->move ? "from" : "intensity" };
	struct viewer *vs = NULL;
	cJSON *opened = open_shot(r, shot, "editor");
	bool ok = opened != NULL;
	if (ok && !pick_light(opened, t.param, t.light, sizeof(t.light), t.base, &t.n)) {
		fprintf(stderr, "%s: %s: no light has a parameter '%s'\n", prog, shot, t.param);
		ok = false;
	}
	cJSON_Delete(opened);
	for (int run = 0; ok && run < 2; run++) {
		int nviewers = run ? c->viewers : 0;
		if (run && nviewers == 0)
			break;
		struct row *row = &rows[(*nrows)];
		memset(row, 0, sizeof(*row));
		snprintf(row->shot, sizeof(row->shot), "%s", shot);
		row->clients = 1 + nviewers;
		if (nviewers) {
			vs = calloc((size_t)nviewers, sizeof(*vs));
			ok = vs && viewers_start(vs, nviewers, url, shot);
		}
		ok = ok && measure(r, &t, c, vs, nviewers, row);
		/* threads still running after a failure (viewers_start stops its own when it
		 * cannot start one, measure stops them when it gets to the end) */
		if (!ok && vs && !atomic_load(&viewers_stop))
			viewers_stop_all(vs, nviewers);
		free(vs);
		vs = NULL;
		if (ok) {
			row->ok = verdict(row);
			(*nrows)++;
			fprintf(stderr, "%s: %s, %d client%s: median %.2f ms, p99 %.2f ms\n", prog, shot,
				row->clients, row->clients > 1 ? "s" : "", row->median, row->p99);
		}
	}
	remote_close(r);
	return ok;
}

static void print_table(const struct row *rows, int n, const struct config *c)
{
	printf("\nEdit latency over relightd, edit sent to its first tile received (%s of one "
	       "light, %d edits a row):\n\n", c->move ? "position" : "intensity", c->edits);
	printf("%-12s %7s %10s %9s %9s %11s %9s  %-24s %s\n", "shot", "clients", "median ms",
	       "p99 ms", "final ms", "viewers med", "viewers p99", "target", "");
	for (int i = 0; i < n; i++) {
		const struct row *r = &rows[i];
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

static bool write_json(const char *path, const struct row *rows, int n, const struct config *c)
{
	FILE *f = fopen(path, "w");
	if (!f) {
		fprintf(stderr, "%s: cannot write %s: %s\n", prog, path, strerror(errno));
		return false;
	}
	fprintf(f, "{\"param\": \"%s\", \"edits\": %d, \"rows\": [", c->move ? "from" : "intensity",
		c->edits);
	for (int i = 0; i < n; i++) {
		const struct row *r = &rows[i];
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

/* Remove the temporary folder: its files, then it. */
static void remove_tree(const char *dir)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	char path[8192];
	while (d && (e = readdir(d))) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(path, sizeof(path), "%s/%s", dir, e->d_name);
		struct stat st;
		if (lstat(path, &st) == 0 && S_ISDIR(st.st_mode))
			remove_tree(path);
		else
			unlink(path);
	}
	if (d)
		closedir(d);
	rmdir(dir);
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

	char tmp[] = "/tmp/relight-latency-XXXXXX";
	if (!mkdtemp(tmp)) {
		fprintf(stderr, "%s: cannot make a temporary folder: %s\n", prog, strerror(errno));
		return 1;
	}
	char shots[4096];
	char *names[MAX_SHOTS];
	int nshots;
	if (c.shots) {
		snprintf(shots, sizeof(shots), "%s", c.shots);
		nshots = list_shots(shots, names);
	} else {
		snprintf(shots, sizeof(shots), "%s/shots", tmp);
		nshots = mkdir(shots, 0755) == 0 ? bake_examples(&c, shots, names) : -1;
	}
	int status = 1;
	struct daemon dm = { 0 };
	struct row *rows = calloc(2 * MAX_SHOTS, sizeof(*rows));
	int nrows = 0;
	if (nshots <= 0 || !rows) {
		if (nshots == 0)
			fprintf(stderr, "%s: no shots\n", prog);
		goto out;
	}
	if (!daemon_start(&c, shots, tmp, &dm)) {
		if (dm.pid > 0 && daemon_stop(&dm) >= 0 && log_says_no_gpu(dm.log)) {
			printf("SKIP: relightd has no GPU context\n");
			status = 77;
		}
		goto out;
	}
	fprintf(stderr, "%s: relightd at %s\n", prog, dm.url);
	bool ok = true;
	for (int i = 0; ok && i < nshots; i++)
		ok = bench_shot(&c, dm.url, names[i], rows, &nrows);
	int rc = daemon_stop(&dm);
	if (rc != 0) {
		fprintf(stderr, "%s: relightd exited with status %d after SIGTERM; its log is %s\n",
			prog, rc, dm.log);
		ok = false;
	}
	print_table(rows, nrows, &c);
	if (c.json && !write_json(c.json, rows, nrows, &c))
		ok = false;
	status = ok ? 0 : 1;
out:
	if (status != 1 || !dm.pid) {
		remove_tree(tmp);
	} else {
		/* keep the daemon's log for a look */
		fprintf(stderr, "%s: relightd's log kept in %s\n", prog, dm.log);
	}
	for (int i = 0; i < nshots; i++)
		free(names[i]);
	free(rows);
	return status;
}

/*
 * Edit-to-tile latency through relightd (latency.h): the daemon as a child
 * process, one editor connection on the caller's thread and, for the second
 * run of each shot, a crowd of viewer connections, one thread each.
 *
 * Everything a call needs lives in its own structures (struct run, struct
 * daemon, struct crowd), so two calls share nothing but the process: its
 * children (each call waits only for its own) and SIGPIPE (see latency.h).
 */
#include "latency.h"
#include "benchutil.h"

#include "remote.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define LATENCY_MAX_EDITS 10000
#define LATENCY_MAX_VIEWERS 256
#define DEFAULT_EDITS 60
#define WARMUP_EDITS 3
#define OPEN_TIMEOUT_MS 300000   /* a first open loads the shot and compiles its kernels */
#define EDIT_TIMEOUT_MS 60000
#define START_TIMEOUT_MS 60000   /* until the daemon prints its port */
#define STOP_TIMEOUT_MS 30000    /* from SIGTERM to SIGKILL */

/* One call of latency_run: its options and the first thing that went wrong. */
struct run {
	const struct latency_opts *o;
	FILE *log;
	int edits;
	const char *param;
	const char *shot;      /* the shot being measured: the errors' prefix */
	char *err;
	size_t errlen;
	bool failed;
};

static void fail(struct run *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Record why the run failed; the first reason is kept, later ones follow from it. */
static void fail(struct run *r, const char *fmt, ...)
{
	if (r->failed)
		return;
	r->failed = true;
	size_t at = 0;
	if (r->shot) {
		int k = snprintf(r->err, r->errlen, "%s: ", r->shot);
		at = k > 0 && (size_t)k < r->errlen ? (size_t)k : 0;
	}
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(r->err + at, r->errlen - at, fmt, ap);
	va_end(ap);
}

static void say(char *buf, size_t len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

static void say(char *buf, size_t len, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, len, fmt, ap);
	va_end(ap);
}

/* ---- statistics ---- */

bool latency_meets_targets(const struct latency_row *r)
{
	if (!r)
		return false;
	if (r->clients == 1)
		return r->median <= 20.0 && r->p99 <= 60.0;
	return r->median <= 40.0;
}

/* ---- the shots ---- */

struct names {
	char **v;
	int n, cap;
};

static void names_finish(struct names *ns)
{
	for (int i = 0; i < ns->n; i++)
		free(ns->v[i]);
	free(ns->v);
	memset(ns, 0, sizeof(*ns));
}

static bool names_add(struct names *ns, const char *name, size_t len)
{
	if (ns->n == ns->cap) {
		int cap = ns->cap ? 2 * ns->cap : 16;
		char **v = realloc(ns->v, (size_t)cap * sizeof(*v));
		if (!v)
			return false;
		ns->v = v;
		ns->cap = cap;
	}
	char *s = malloc(len + 1);
	if (!s)
		return false;
	memcpy(s, name, len);
	s[len] = '\0';
	ns->v[ns->n++] = s;
	return true;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

#define SHOT_SUFFIX ".shot.exr"

/* The shots to measure: the NAMEs of o->names, each checked, or every NAME.shot.exr of the folder. */
static bool find_shots(struct run *r, struct names *ns)
{
	const struct latency_opts *o = r->o;
	char path[4096];
	struct stat st;
	if (o->nnames) {
		for (size_t i = 0; i < o->nnames; i++) {
			const char *name = o->names[i];
			if (!name || !name[0] || strchr(name, '/')) {
				fail(r, "'%s' is not a shot name", name ? name : "(null)");
				return false;
			}
			if (snprintf(path, sizeof(path), "%s/%s" SHOT_SUFFIX, o->shots, name) >=
				    (int)sizeof(path) ||
			    stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
				fail(r, "no shot '%s' in %s (no file %s)", name, o->shots, path);
				return false;
			}
			if (!names_add(ns, name, strlen(name))) {
				fail(r, "out of memory");
				return false;
			}
		}
		return true;
	}
	DIR *d = opendir(o->shots);
	if (!d) {
		fail(r, "cannot read %s: %s", o->shots, strerror(errno));
		return false;
	}
	const size_t sl = strlen(SHOT_SUFFIX);
	struct dirent *e;
	bool ok = true;
	while (ok && (e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len > sl && e->d_name[0] != '.' && !strcmp(e->d_name + len - sl, SHOT_SUFFIX))
			ok = names_add(ns, e->d_name, len - sl);
	}
	closedir(d);
	if (!ok) {
		fail(r, "out of memory");
		return false;
	}
	if (ns->n == 0) {
		fail(r, "no shots (NAME" SHOT_SUFFIX ") in %s", o->shots);
		return false;
	}
	qsort(ns->v, (size_t)ns->n, sizeof(char *), cmp_str);
	return true;
}

/* ---- the daemon ---- */

/* The daemon, a child of this process; its stdout read for the line that gives its port. */
struct daemon {
	pid_t pid;            /* 0: none running (or it was waited for) */
	bool started;         /* it runs (execv worked): its log is worth keeping after a failure */
	char first[512];      /* the first line it printed */
	bool late;            /* it printed no whole line in time */
	char dir[4096];       /* the temporary folder of its log; "" when none */
	char log[4200];
	char url[300];
};

static bool cloexec(int fd)
{
	int fl = fcntl(fd, F_GETFD);
	return fl >= 0 && fcntl(fd, F_SETFD, fl | FD_CLOEXEC) == 0;
}

static void close_fd(int *fd)
{
	if (*fd >= 0)
		close(*fd);
	*fd = -1;
}

/*
 * Read from @fd until a newline, EOF or @timeout_ms; the text (without
 * the newline) in @line. True when the time ran out.
 */
static bool read_line(int fd, char *line, size_t cap, int timeout_ms)
{
	bool late = false;
	size_t len = 0;
	double t0 = remote_now_ms();
	while (len < cap - 1 && (len == 0 || line[len - 1] != '\n')) {
		struct pollfd p = { .fd = fd, .events = POLLIN };
		int left = (int)(timeout_ms - (remote_now_ms() - t0));
		int k = left > 0 ? poll(&p, 1, left) : 0;
		if (k < 0 && errno == EINTR)
			continue;
		late = k == 0;
		if (k <= 0)
			break;
		ssize_t n = read(fd, line + len, cap - 1 - len);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0)
			break;
		len += (size_t)n;
	}
	line[len] = '\0';
	line[strcspn(line, "\n")] = '\0';
	return late;
}

/*
 * Fork and exec relightd on a free port of 127.0.0.1, its stderr into a log
 * in a fresh temporary folder, and wait for the line that names its port.
 * @child_pipe is the SIGPIPE disposition the daemon starts with (the
 * caller's, not the one this call set for itself). False with the reason
 * recorded; the child, if any, is left for daemon_stop.
 */
static bool daemon_start(struct run *r, const struct sigaction *child_pipe, struct daemon *dm)
{
	const struct latency_opts *o = r->o;
	int out[2] = { -1, -1 }, status[2] = { -1, -1 }, logfd = -1;
	bool ok = false;
	const char *tmp = getenv("TMPDIR");
	if (!tmp || !tmp[0])
		tmp = "/tmp";
	if (snprintf(dm->dir, sizeof(dm->dir), "%s/relight-latency-XXXXXX", tmp) >=
		    (int)sizeof(dm->dir) ||
	    !mkdtemp(dm->dir)) {
		fail(r, "cannot make a temporary folder in %s: %s", tmp, strerror(errno));
		dm->dir[0] = '\0';
		return false;
	}
	snprintf(dm->log, sizeof(dm->log), "%s/relightd.log", dm->dir);
	logfd = open(dm->log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
	if (logfd < 0 || pipe(out) != 0 || pipe(status) != 0) {
		fail(r, "cannot start relightd: %s", strerror(errno));
		goto cleanup;
	}
	/* close-on-exec everywhere, so that no other child of this process holds
	 * a pipe's end open (the reads below wait for EOF); the status pipe
	 * closing on exec is how the parent learns that execv worked */
	if (!cloexec(logfd) || !cloexec(out[0]) || !cloexec(out[1]) || !cloexec(status[0]) ||
	    !cloexec(status[1])) {
		fail(r, "cannot start relightd: %s", strerror(errno));
		goto cleanup;
	}
	char *argv[] = { (char *)o->relightd, "--listen", "127.0.0.1:0", "--shots",
			 (char *)o->shots, "--log-level", "warn", NULL };
	sigset_t none;
	sigemptyset(&none);
	pid_t pid = fork();
	if (pid < 0) {
		fail(r, "cannot start relightd: fork: %s", strerror(errno));
		goto cleanup;
	}
	if (pid == 0) {
		/* only async-signal-safe calls until execv: the caller may have threads */
		if (dup2(out[1], STDOUT_FILENO) < 0 || dup2(logfd, STDERR_FILENO) < 0 ||
		    fcntl(STDOUT_FILENO, F_SETFD, 0) != 0 || fcntl(STDERR_FILENO, F_SETFD, 0) != 0)
			_exit(127);
		sigaction(SIGPIPE, child_pipe, NULL);
		sigprocmask(SIG_SETMASK, &none, NULL);
		execv(argv[0], argv);
		int e = errno;
		ssize_t w = write(status[1], &e, sizeof(e));
		(void)w;
		_exit(127);
	}
	dm->pid = pid;
	close_fd(&out[1]);
	close_fd(&status[1]);
	close_fd(&logfd);

	/* EOF when the exec worked, its errno when it did not */
	int e = 0;
	ssize_t n;
	while ((n = read(status[0], &e, sizeof(e))) < 0 && errno == EINTR)
		;
	if (n == (ssize_t)sizeof(e)) {
		fail(r, "cannot run relightd '%s': %s", o->relightd, strerror(e));
		goto cleanup;
	}
	dm->started = true;

	char host[256];
	dm->late = read_line(out[0], dm->first, sizeof(dm->first), START_TIMEOUT_MS);
	if (sscanf(dm->first, "relightd: listening on http://%255[^/]/", host) != 1) {
		/* the reason is recorded after the daemon is stopped, with its status and log */
		goto cleanup;
	}
	snprintf(dm->url, sizeof(dm->url), "ws://%s/ws", host);
	ok = true;
cleanup:
	close_fd(&logfd);
	close_fd(&out[0]);
	close_fd(&out[1]);
	close_fd(&status[0]);
	close_fd(&status[1]);
	return ok;
}

/*
 * SIGTERM, and its exit status (128 + N for a signal; -1: it had to be
 * killed, or its status is lost). The child is always waited for, so none
 * is left behind; 0 when there was none.
 */
static int daemon_stop(struct daemon *dm)
{
	if (dm->pid <= 0)
		return 0;
	pid_t pid = dm->pid;
	dm->pid = 0;
	kill(pid, SIGTERM);
	double t0 = remote_now_ms();
	int st;
	for (;;) {
		pid_t p = waitpid(pid, &st, WNOHANG);
		if (p == pid)
			return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
		/* ECHILD: the caller reaps its children itself (SIGCHLD ignored) */
		if (p < 0 && errno != EINTR)
			return -1;
		if (remote_now_ms() - t0 > STOP_TIMEOUT_MS) {
			kill(pid, SIGKILL);
			while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
				;
			return -1;
		}
		nanosleep(&(struct timespec){ .tv_nsec = 20000000 }, NULL);
	}
}

/*
 * The daemon's log: whether it says there is no GPU context, and its last
 * non-empty line (for an error message).
 */
static bool log_scan(const char *log, char *last, size_t cap)
{
	FILE *f = fopen(log, "r");
	char line[1024];
	bool no_gpu = false;
	last[0] = '\0';
	while (f && fgets(line, sizeof(line), f)) {
		no_gpu = no_gpu || strstr(line, "no GPU context") != NULL;
		line[strcspn(line, "\n")] = '\0';
		size_t n = strlen(line);
		if (n) {
			/* cut to fit: the start of a long line is enough to tell what it says */
			n = n < cap - 1 ? n : cap - 1;
			memcpy(last, line, n);
			last[n] = '\0';
		}
	}
	if (f)
		fclose(f);
	return no_gpu;
}

/* Remove the daemon's temporary folder (its log, then it). */
static void daemon_forget(struct daemon *dm)
{
	if (!dm->dir[0])
		return;
	unlink(dm->log);
	rmdir(dm->dir);
	dm->dir[0] = '\0';
}

/* ---- clients ---- */

static double num(const cJSON *j, const char *name, double dflt)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, name);
	return cJSON_IsNumber(v) ? v->valuedouble : dflt;
}

/*
 * Open @shot in rgba8 and wait for the final level of the state it opens
 * on. Returns the "opened" reply (the caller's), NULL with the reason in
 * @err.
 */
static cJSON *open_shot(struct remote *rm, const char *shot, char *err, size_t errlen)
{
	cJSON *req = cJSON_CreateObject(), *reply = NULL;
	if (!req || !cJSON_AddStringToObject(req, "op", "open") ||
	    !cJSON_AddStringToObject(req, "shot", shot) ||
	    !cJSON_AddStringToObject(req, "format", "rgba8")) {
		cJSON_Delete(req);
		say(err, errlen, "open: out of memory");
		return NULL;
	}
	bool ok = remote_request(rm, req, &reply, OPEN_TIMEOUT_MS);
	cJSON_Delete(req);
	const char *code, *msg;
	if (!ok || remote_reply_error(reply, &code, &msg)) {
		if (ok)
			say(err, errlen, "open: %s: %s", code, msg);
		else
			say(err, errlen, "open: %s", remote_error(rm));
		cJSON_Delete(reply);
		return NULL;
	}
	double edit = num(reply, "edit", 0), final = num(reply, "levels", 4) - 1;
	double deadline = remote_now_ms() + OPEN_TIMEOUT_MS;
	for (;;) {
		struct remote_event ev;
		int left = (int)(deadline - remote_now_ms());
		enum remote_kind k = remote_next(rm, &ev, left > 0 ? left : 0);
		bool done = k == REMOTE_TEXT && !strcmp(ev.op, "level") &&
			    num(ev.json, "edit", -1) >= edit && num(ev.json, "level", -1) >= final;
		remote_event_finish(&ev);
		if (done)
			return reply;
		if (k == REMOTE_TIMEOUT || k == REMOTE_CLOSED) {
			say(err, errlen, "open: the first image did not come: %s",
			    k == REMOTE_TIMEOUT ? "timed out" : remote_error(rm));
			cJSON_Delete(reply);
			return NULL;
		}
	}
}

/* What the editor edits: a light's parameter, between two values. */
struct target {
	char light[256];
	const char *param;
	float base[3];
	int n;
};

/* The light to edit: the first with the parameter, preferring one that is not ambient. */
static bool pick_light(const cJSON *opened, struct target *t)
{
	const cJSON *l, *found = NULL, *found_param = NULL;
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(opened, "lights")) {
		const cJSON *p;
		cJSON_ArrayForEach(p, cJSON_GetObjectItemCaseSensitive(l, "params")) {
			const cJSON *name = cJSON_GetObjectItemCaseSensitive(p, "name");
			if (!cJSON_IsString(name) || strcmp(name->valuestring, t->param))
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
	snprintf(t->light, sizeof(t->light), "%s", cJSON_IsString(name) ? name->valuestring : "");
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(found_param, "value");
	t->n = 0;
	if (cJSON_IsNumber(v)) {
		t->base[t->n++] = (float)v->valuedouble;
	} else {
		const cJSON *x;
		cJSON_ArrayForEach(x, v)
			if (t->n < 3 && cJSON_IsNumber(x))
				t->base[t->n++] = (float)x->valuedouble;
	}
	return t->n > 0;
}

/* The @i-th edit's request; NULL when out of memory. */
static cJSON *edit_request(const struct target *t, int i)
{
	cJSON *j = cJSON_CreateObject(), *params = cJSON_CreateObject();
	bool ok = j && params && cJSON_AddStringToObject(j, "op", "set") &&
		  cJSON_AddStringToObject(j, "light", t->light);
	if (ok && t->n == 1) {
		/* 0.8x and 1x of the intensity in turn */
		ok = cJSON_AddNumberToObject(params, t->param, t->base[0] * (i % 2 ? 1.0 : 0.8));
	} else if (ok) {
		/* a step of 0.25 along x and back */
		cJSON *a = cJSON_AddArrayToObject(params, t->param);
		ok = a != NULL;
		for (int k = 0; ok && k < t->n; k++)
			ok = cJSON_AddItemToArray(a, cJSON_CreateNumber(t->base[k] +
							(k == 0 && i % 2 == 0 ? 0.25 : 0.0)));
	}
	if (ok && cJSON_AddItemToObject(j, "params", params))
		return j;
	cJSON_Delete(params);
	cJSON_Delete(j);
	return NULL;
}

/*
 * One measured edit: its ack's edit number, and the latency to its first
 * tile and to its final level. False with the reason recorded.
 */
static bool one_edit(struct run *r, struct remote *rm, const struct target *t, int i, double *t0,
		     int64_t *edit, double *first_ms, double *final_ms, int *first_level)
{
	cJSON *req = edit_request(t, i), *reply = NULL;
	if (!req) {
		fail(r, "out of memory");
		return false;
	}
	*t0 = remote_now_ms();
	bool ok = remote_request(rm, req, &reply, EDIT_TIMEOUT_MS);
	cJSON_Delete(req);
	const char *code, *msg;
	if (!ok || remote_reply_error(reply, &code, &msg) ||
	    !cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(reply, "edit"))) {
		if (!ok)
			fail(r, "set %s.%s: %s", t->light, t->param, remote_error(rm));
		else if (remote_reply_error(reply, &code, &msg))
			fail(r, "set %s.%s: %s: %s", t->light, t->param, code, msg);
		else
			fail(r, "set %s.%s: the reply has no edit number", t->light, t->param);
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
		enum remote_kind k = remote_next(rm, &ev, left > 0 ? left : 0);
		if (k == REMOTE_TILE && ev.tile.edit == (uint32_t)*edit && *first_ms < 0) {
			*first_ms = ev.t_ms - *t0;
			*first_level = (int)ev.tile.level;
		}
		bool done = k == REMOTE_TEXT && !strcmp(ev.op, "level") &&
			    num(ev.json, "edit", -1) == (double)*edit && num(ev.json, "level", -1) >= 3;
		if (done)
			*final_ms = ev.t_ms - *t0;
		/* the reason is taken before the event is emptied */
		if (k == REMOTE_TIMEOUT)
			fail(r, "edit %lld: its final level did not come in time", (long long)*edit);
		else if (k == REMOTE_INVALID)
			fail(r, "edit %lld: %s", (long long)*edit, ev.reason);
		else if (k == REMOTE_CLOSED)
			fail(r, "edit %lld: %s", (long long)*edit, remote_error(rm));
		remote_event_finish(&ev);
		if (done && *first_ms < 0)
			fail(r, "edit %lld: its final level came with no tile", (long long)*edit);
		if (done)
			return *first_ms >= 0;
		if (k == REMOTE_TIMEOUT || k == REMOTE_CLOSED || k == REMOTE_INVALID)
			return false;
	}
}

/* ---- viewers ---- */

struct crowd;

/* A viewer: its own connection on its own thread, reading every tile. */
struct viewer {
	pthread_t thread;
	struct crowd *crowd;
	int index;
	/* when the first tile of each edit came (edit numbers increasing) */
	int64_t *edits;
	double *first;
	int nedits, cap;
	uint64_t tiles;
	bool opened;          /* under crowd.lock until ready: it has the shot's image */
	bool failed;          /* read after the thread is joined */
	char err[512];
};


/* The viewers of one run, and how they start and stop together. */
struct crowd {
	const char *url, *shot;
	struct viewer *v;
	int total;            /* viewers allocated */
	int running;          /* threads started and not yet joined */
	bool sync;            /* lock and cond initialised */
	pthread_mutex_t lock;
	pthread_cond_t cond;
	int ready;            /* under lock: threads that have opened the shot or given up */
	atomic_int stop;
};

static void viewer_ready(struct viewer *v, bool ok)
{
	struct crowd *c = v->crowd;
	pthread_mutex_lock(&c->lock);
	v->opened = ok;
	c->ready++;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
}

/* Remember when the first tile of @edit came. */
static bool viewer_note(struct viewer *v, int64_t edit, double t_ms)
{
	if (v->nedits == v->cap) {
		int cap = v->cap ? 2 * v->cap : 128;
		int64_t *e = realloc(v->edits, (size_t)cap * sizeof(*e));
		if (!e)
			return false;
		v->edits = e;
		double *f = realloc(v->first, (size_t)cap * sizeof(*f));
		if (!f)
			return false;
		v->first = f;
		v->cap = cap;
	}
	v->edits[v->nedits] = edit;
	v->first[v->nedits++] = t_ms;
	return true;
}

static void *viewer_main(void *arg)
{
	struct viewer *v = arg;
	struct crowd *c = v->crowd;
	char err[512];
	struct remote *rm = remote_connect(c->url, NULL, NULL, err, sizeof(err));
	if (!rm) {
		say(v->err, sizeof(v->err), "viewer %d: %s", v->index, err);
		v->failed = true;
		viewer_ready(v, false);
		return NULL;
	}
	cJSON *opened = open_shot(rm, c->shot, err, sizeof(err));
	bool ok = opened != NULL;
	cJSON_Delete(opened);
	if (!ok) {
		say(v->err, sizeof(v->err), "viewer %d: %s", v->index, err);
		v->failed = true;
	}
	viewer_ready(v, ok);
	int64_t last = -1;
	while (ok && !atomic_load(&c->stop)) {
		struct remote_event ev;
		enum remote_kind k = remote_next(rm, &ev, 50);
		if (k == REMOTE_TILE) {
			v->tiles++;
			if ((int64_t)ev.tile.edit > last) {
				last = ev.tile.edit;
				if (!viewer_note(v, last, ev.t_ms)) {
					say(v->err, sizeof(v->err), "viewer %d: out of memory", v->index);
					v->failed = true;
					ok = false;
				}
			}
		}
		remote_event_finish(&ev);
		if (k == REMOTE_CLOSED) {
			say(v->err, sizeof(v->err), "viewer %d: %s", v->index, remote_error(rm));
			v->failed = true;
			ok = false;
		}
	}
	remote_close(rm);
	return NULL;
}

/*
 * Start @n viewers on @shot and wait until each has the shot's image.
 * False with the reason recorded; either way crowd_stop and crowd_finish
 * follow.
 */
static bool crowd_start(struct run *r, struct crowd *c, int n, const char *url, const char *shot)
{
	memset(c, 0, sizeof(*c));
	c->url = url;
	c->shot = shot;
	atomic_init(&c->stop, 0);
	c->v = calloc((size_t)n, sizeof(*c->v));
	if (!c->v) {
		fail(r, "out of memory");
		return false;
	}
	c->total = n;
	if (pthread_mutex_init(&c->lock, NULL) != 0) {
		fail(r, "cannot make a mutex");
		return false;
	}
	if (pthread_cond_init(&c->cond, NULL) != 0) {
		pthread_mutex_destroy(&c->lock);
		fail(r, "cannot make a condition variable");
		return false;
	}
	c->sync = true;
	bool ok = true;
	for (int i = 0; ok && i < n; i++) {
		c->v[i].crowd = c;
		c->v[i].index = i + 1;
		int e = pthread_create(&c->v[i].thread, NULL, viewer_main, &c->v[i]);
		if (e != 0) {
			fail(r, "cannot start viewer %d's thread: %s", i + 1, strerror(e));
			ok = false;
		} else {
			c->running++;
		}
	}
	pthread_mutex_lock(&c->lock);
	while (c->ready < c->running)
		pthread_cond_wait(&c->cond, &c->lock);
	for (int i = 0; i < c->running; i++) {
		if (!c->v[i].opened && ok)
			fail(r, "%s", c->v[i].err);
		ok = ok && c->v[i].opened;
	}
	pthread_mutex_unlock(&c->lock);
	return ok;
}

/* Stop and join the viewers still running; true when none failed. */
static bool crowd_stop(struct run *r, struct crowd *c)
{
	atomic_store(&c->stop, 1);
	for (int i = 0; i < c->running; i++)
		pthread_join(c->v[i].thread, NULL);
	bool ok = true;
	for (int i = 0; i < c->running; i++) {
		if (c->v[i].failed && ok)
			fail(r, "%s", c->v[i].err);
		ok = ok && !c->v[i].failed;
	}
	c->running = 0;
	return ok;
}

/* Free what the (stopped) viewers hold. */
static void crowd_finish(struct crowd *c)
{
	for (int i = 0; i < c->total; i++) {
		free(c->v[i].edits);
		free(c->v[i].first);
	}
	free(c->v);
	if (c->sync) {
		pthread_cond_destroy(&c->cond);
		pthread_mutex_destroy(&c->lock);
	}
	memset(c, 0, sizeof(*c));
}

/* ---- one run ---- */

/*
 * Measure the edits of one run; @c (NULL: none) are its viewers, stopped
 * here once the edits are done. Fills @row but for its name, clients and
 * verdict.
 */
static bool measure(struct run *r, struct remote *rm, const struct target *t, struct crowd *c,
		    struct latency_row *row)
{
	int n = r->edits, nviewers = c ? c->total : 0;
	double *lat = calloc((size_t)n, sizeof(double)), *fin = calloc((size_t)n, sizeof(double));
	double *t0s = calloc((size_t)n, sizeof(double));
	int64_t *edits = calloc((size_t)n, sizeof(int64_t));
	size_t vcap = (size_t)n * (size_t)(nviewers > 0 ? nviewers : 1);
	double *vlat = calloc(vcap, sizeof(double));
	bool ok = lat && fin && t0s && edits && vlat;
	if (!ok)
		fail(r, "out of memory");
	double t0, first, final;
	int64_t e;
	int level;
	for (int i = 0; ok && i < WARMUP_EDITS; i++)
		ok = one_edit(r, rm, t, i, &t0, &e, &first, &final, &level);
	row->not_level0 = 0;
	for (int i = 0; ok && i < n; i++) {
		ok = one_edit(r, rm, t, i + WARMUP_EDITS, &t0s[i], &edits[i], &lat[i], &fin[i],
			      &level);
		row->not_level0 += ok && level != 0;
	}
	row->edits = ok ? n : 0;
	if (c && ok)
		ok = crowd_stop(r, c);
	if (ok) {
		/* the viewers' latencies: their first tile of each measured edit; both lists
		 * go up in edit number, so one walk along each pairs them */
		int nv = 0;
		for (int v = 0; v < nviewers; v++) {
			const struct viewer *vw = &c->v[v];
			int k = 0;
			for (int i = 0; i < n; i++) {
				while (k < vw->nedits && vw->edits[k] < edits[i])
					k++;
				if (k < vw->nedits && vw->edits[k] == edits[i])
					vlat[nv++] = vw->first[k] - t0s[i];
			}
		}
		row->median = bench_median(lat, n);
		row->p99 = bench_p99(lat, n);
		row->final_median = bench_median(fin, n);
		row->viewer_median = bench_median(vlat, nv);
		row->viewer_p99 = bench_p99(vlat, nv);
	}
	free(lat);
	free(fin);
	free(t0s);
	free(edits);
	free(vlat);
	return ok;
}

/* Both runs on one shot, their rows appended to @rows. */
static bool bench_shot(struct run *r, const char *url, const char *shot, struct latency_row *rows,
		       int *nrows)
{
	char err[512];
	r->shot = shot;
	struct remote *rm = remote_connect(url, NULL, NULL, err, sizeof(err));
	if (!rm) {
		fail(r, "editor: %s", err);
		r->shot = NULL;
		return false;
	}
	struct target t = { .param = r->param };
	cJSON *opened = open_shot(rm, shot, err, sizeof(err));
	bool ok = opened != NULL;
	if (!ok)
		fail(r, "editor: %s", err);
	if (ok && !pick_light(opened, &t)) {
		fail(r, "no light has a parameter '%s'", t.param);
		ok = false;
	}
	cJSON_Delete(opened);
	int runs = r->o->viewers > 0 ? 2 : 1;
	for (int run = 0; ok && run < runs; run++) {
		int nviewers = run ? r->o->viewers : 0;
		struct latency_row row = { .clients = 1 + nviewers };
		snprintf(row.shot, sizeof(row.shot), "%s", shot);
		struct crowd crowd, *c = NULL;
		if (nviewers) {
			c = &crowd;
			ok = crowd_start(r, c, nviewers, url, shot);
		}
		ok = ok && measure(r, rm, &t, c, &row);
		if (c) {
			/* measure stopped them when it got to the end; not after a failure */
			crowd_stop(r, c);
			crowd_finish(c);
		}
		if (ok) {
			row.ok = latency_meets_targets(&row);
			rows[(*nrows)++] = row;
			fprintf(r->log, "latency: %s, %d client%s: median %.2f ms, p99 %.2f ms\n",
				shot, row.clients, row.clients > 1 ? "s" : "", row.median, row.p99);
		}
	}
	remote_close(rm);
	r->shot = NULL;
	return ok;
}

int latency_run(const struct latency_opts *o, struct latency_row *rows, int cap, char *err,
		size_t errlen)
{
	char dummy[1];
	struct run r = { .o = o, .err = err ? err : dummy, .errlen = err ? errlen : sizeof(dummy) };
	if (r.errlen)
		r.err[0] = '\0';
	if (!o || !o->relightd || !o->relightd[0] || !o->shots || !o->shots[0]) {
		fail(&r, "no relightd or shots folder given");
		return -1;
	}
	r.log = o->log ? o->log : stderr;
	r.edits = o->edits ? o->edits : DEFAULT_EDITS;
	r.param = o->move ? "from" : "intensity";
	if (r.edits < 1 || r.edits > LATENCY_MAX_EDITS) {
		fail(&r, "%d edits (1 to %d)", o->edits, LATENCY_MAX_EDITS);
		return -1;
	}
	if (o->viewers < 0 || o->viewers > LATENCY_MAX_VIEWERS) {
		fail(&r, "%d viewers (0 to %d)", o->viewers, LATENCY_MAX_VIEWERS);
		return -1;
	}
	if ((o->nnames && !o->names) || cap < 0 || (cap > 0 && !rows)) {
		fail(&r, "bad arguments");
		return -1;
	}
	for (int i = 0; i < cap; i++)
		memset(&rows[i], 0, sizeof(rows[i]));

	int result = -1, nrows = 0, status;
	struct names shots = { 0 };
	struct daemon dm = { .pid = 0 };
	struct sigaction ign = { .sa_handler = SIG_IGN }, caller_pipe;
	bool pipe_saved = false;
	if (!find_shots(&r, &shots))
		goto cleanup;
	int need = shots.n * (o->viewers > 0 ? 2 : 1);
	if (need > cap) {
		fail(&r, "%d shots make %d rows; room for %d", shots.n, need, cap);
		goto cleanup;
	}

	/* A write to a connection the daemon has closed must fail with EPIPE, not
	 * end the process. libwebsockets ignores SIGPIPE itself when it makes a
	 * context; the caller's disposition is put back on return. */
	sigemptyset(&ign.sa_mask);
	if (sigaction(SIGPIPE, &ign, &caller_pipe) != 0) {
		fail(&r, "cannot ignore SIGPIPE: %s", strerror(errno));
		goto cleanup;
	}
	pipe_saved = true;

	if (!daemon_start(&r, &caller_pipe, &dm)) {
		status = daemon_stop(&dm);
		char last[512] = "";
		bool no_gpu = dm.started && log_scan(dm.log, last, sizeof(last));
		if (no_gpu && status >= 0) {
			fail(&r, "relightd has no GPU context");
			result = -77;
		} else if (dm.started) {
			char said[700];
			if (dm.late)
				snprintf(said, sizeof(said), "it printed %s%.512s%s within %d s",
					 dm.first[0] ? "'" : "nothing", dm.first,
					 dm.first[0] ? "' and no more" : "", START_TIMEOUT_MS / 1000);
			else if (status >= 0)
				snprintf(said, sizeof(said), "%s%.512s%s, exit status %d",
					 dm.first[0] ? "its first line: '" : "it printed nothing",
					 dm.first, dm.first[0] ? "'" : "", status);
			else
				snprintf(said, sizeof(said), "%s%.512s%s, and it had to be killed",
					 dm.first[0] ? "its first line: '" : "it printed nothing",
					 dm.first, dm.first[0] ? "'" : "");
			fail(&r, "relightd did not start (%s); its log is %s%s%s%s", said, dm.log,
			     last[0] ? ", ending '" : " (empty)", last, last[0] ? "'" : "");
		}
		goto cleanup;
	}
	fprintf(r.log, "latency: relightd at %s\n", dm.url);
	bool ok = true;
	for (int i = 0; ok && i < shots.n; i++)
		ok = bench_shot(&r, dm.url, shots.v[i], rows, &nrows);
	status = daemon_stop(&dm);
	if (status != 0) {
		fail(&r, "relightd exited with status %d after SIGTERM; its log is %s", status,
		     dm.log);
		ok = false;
	}
	if (ok)
		result = nrows;
cleanup:
	/* stopped on every path: no daemon outlives the call */
	daemon_stop(&dm);
	if (pipe_saved)
		sigaction(SIGPIPE, &caller_pipe, NULL);
	if (result == -1 && dm.started)
		fprintf(r.log, "latency: relightd's log kept in %s\n", dm.log);
	else
		daemon_forget(&dm);
	names_finish(&shots);
	return result;
}

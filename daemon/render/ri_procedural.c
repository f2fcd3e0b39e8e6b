/*
 * Procedural "NAME" [args] [xmin xmax ymin ymax zmin zmax]
 *
 * The scene builder gathers a whole world before it renders, so a
 * procedural is expanded where it is declared, in the graphics state of the
 * request, or not at all: that is the state RISpec expands it in, and the
 * frame it draws is the same.
 *
 *  - DelayedReadArchive ["file"]: the archive, found as ReadArchive finds
 *    it, is read only when its bound can be seen: not when the bound lies
 *    wholly outside the camera's viewing volume (reyes_ri_bound_unseen) and
 *    no light declared so far reads a shadow map (what is out of view may
 *    still cast into the frame through a map the preview redraws). A light
 *    with a shadow map declared after an archive left unread is a warning at
 *    the light: its shadows in a relit preview miss what the archive holds.
 *  - RunProgram ["program args" "datablock"]: the program (found on $PATH;
 *    the first word is the program, the others its arguments, no shell) runs
 *    with relight's own privileges. It is sent "DETAIL DATABLOCK\n" on its
 *    standard input, which is then closed, and its standard output up to a
 *    0xFF byte (or its end, when the program exits with status 0) is read as
 *    RIB in the current state, named after the program in diagnostics. A
 *    program that cannot be run, dies, exits with an error before it ends
 *    its output, runs past $RELIGHT_RUNPROGRAM_TIMEOUT seconds (default 60;
 *    it is killed) or writes what is not RIB is an error at the Procedural's
 *    line: nothing of its output is used and the rest of the frame renders.
 *    A read that only checks (reyes_ri_opts's check_only) runs no program.
 *  - DynamicLoad: relight loads no foreign code: a warning, an error with
 *    --strict.
 */
#include "ri_impl.h"

#include "mathlib.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

enum {
	MAX_ARGS = 256,                    /* words of a RunProgram command */
	MAX_OUTPUT = 256 << 20,            /* bytes of a program's output */
	DEFAULT_TIMEOUT = 60,              /* seconds */
};

/* Bound argument @r->args[2] into @b; false (reported) if it is not 6 numbers. */
static bool bound_arg(struct ri *ri, const struct rib_request *r, float b[6])
{
	const struct rib_value *v = &r->args[2];
	if (v->n != 6)
		return reyes_ri_err(ri, r->loc, "Procedural: the bound has %u numbers, not 6", v->n),
		       false;
	if (!reyes_ri_value_floats(ri, v, v->loc, "Procedural bound", b))
		return false;
	for (int k = 0; k < 3; k++)
		if (!(b[2 * k] <= b[2 * k + 1]))
			return reyes_ri_err(ri, r->loc, "Procedural: the bound's minimum %g is above "
					    "its maximum %g", (double)b[2 * k], (double)b[2 * k + 1]),
			       false;
	return true;
}

/* Does some light declared so far read a shadow map (a "shadow..." string parameter set)? */
static bool shadow_lights(struct ri *ri)
{
	for (int list = 0; list < 2; list++) {
		const struct reyes_light *l = list ? ri->lights.data : ri->pre_lights.data;
		size_t n = list ? ri->lights.len : ri->pre_lights.len;
		for (size_t i = 0; i < n; i++)
			for (uint32_t k = 0; k < l[i].shader.nparams; k++) {
				const struct reyes_param_value *p = &l[i].shader.params[k];
				if (p->strings && p->nvalues && strncmp(p->name, "shadow", 6) == 0 &&
				    p->strings[0] && p->strings[0][0])
					return true;
			}
	}
	return false;
}

/* DelayedReadArchive left unread in this world. */
static uint32_t *unread(struct ri *ri)
{
	if (ri->unread_world != ri->worlds) {
		ri->unread_world = ri->worlds;
		ri->unread_archives = 0;
	}
	return &ri->unread_archives;
}

static void delayed_read_archive(struct ri *ri, const struct rib_request *r, const float b[6])
{
	const struct rib_value *a = &r->args[1];
	if (a->n != 1)
		FAIL(ri, r->loc, "Procedural \"DelayedReadArchive\" takes one file name, got %u",
		     a->n);
	if (reyes_ri_bound_unseen(ri, b) && !shadow_lights(ri)) {
		(*unread(ri))++;
		return;
	}
	/* an archive that cannot be found or read drops this procedural alone */
	reyes_ri_read_archive(ri, r, "DelayedReadArchive", a->strs[0]);
}

/* ---- RunProgram ----------------------------------------------------------------------- */

/* The words of @cmd (split at blanks) into argv (in @a), NULL-terminated; their count. */
static int split_words(struct rl_arena *a, const char *cmd, char **argv)
{
	int n = 0;
	for (const char *p = cmd; *p && n < MAX_ARGS;) {
		while (*p == ' ' || *p == '\t' || *p == '\n')
			p++;
		const char *s = p;
		while (*p && *p != ' ' && *p != '\t' && *p != '\n')
			p++;
		if (p > s)
			argv[n++] = rl_arena_strndup(a, s, (size_t)(p - s));
	}
	argv[n] = NULL;
	return n;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double timeout_s(void)
{
	const char *e = getenv("RELIGHT_RUNPROGRAM_TIMEOUT");
	double t = e ? strtod(e, NULL) : DEFAULT_TIMEOUT;
	return t > 0 && isfinite(t) ? t : DEFAULT_TIMEOUT;
}

struct run {
	char *out;
	size_t len, cap;
	bool ended;            /* the 0xFF byte came */
	bool timed_out;
	int status;            /* waitpid's */
	int exec_errno;        /* the child could not exec: its errno */
};

/* Write all of @s to @fd; a program that does not read it is not an error here. */
static void write_all(int fd, const char *s, size_t n)
{
	while (n) {
		ssize_t w = write(fd, s, n);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0)
			return;
		s += w;
		n -= (size_t)w;
	}
}

/* Reads the program's output until the 0xFF byte, its end, or the deadline. */
static void read_output(int fd, double deadline, struct run *run)
{
	for (;;) {
		double left = deadline - now_s();
		if (left <= 0) {
			run->timed_out = true;
			return;
		}
		struct pollfd p = {.fd = fd, .events = POLLIN};
		int k = poll(&p, 1, (int)fmin(left * 1000 + 1, 1000));
		if (k < 0 && errno == EINTR)
			continue;
		if (k <= 0)
			continue;
		if (run->cap - run->len < 65536) {
			run->cap = run->cap ? run->cap * 2 : 65536;
			run->out = rl_xrealloc(run->out, run->cap);
		}
		ssize_t n = read(fd, run->out + run->len, run->cap - run->len);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0)
			return;
		char *end = memchr(run->out + run->len, 0xff, (size_t)n);
		if (end) {
			run->len = (size_t)(end - run->out);
			run->ended = true;
			return;
		}
		run->len += (size_t)n;
		if (run->len > MAX_OUTPUT)
			return;
	}
}

/* Waits for @pid until @deadline, then kills it; its status into run->status. */
static void reap(pid_t pid, double deadline, struct run *run)
{
	for (;;) {
		int st;
		pid_t w = waitpid(pid, &st, WNOHANG);
		if (w == pid) {
			run->status = st;
			return;
		}
		if (w < 0 && errno != EINTR)
			return;
		if (now_s() >= deadline) {
			kill(pid, SIGKILL);
			while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
				;
			run->status = st;
			if (!run->ended)
				run->timed_out = true;
			return;
		}
		struct timespec ts = {0, 10 * 1000 * 1000};
		nanosleep(&ts, NULL);
	}
}

/* Runs @argv with @request on its input; false when it could not even start. */
static bool run_program(char *const *argv, const char *request, struct run *run)
{
	int in[2], out[2], err[2];
	if (pipe(in) != 0)
		return false;
	if (pipe(out) != 0) {
		close(in[0]), close(in[1]);
		return false;
	}
	if (pipe(err) != 0) {
		close(in[0]), close(in[1]), close(out[0]), close(out[1]);
		return false;
	}
	fcntl(err[1], F_SETFD, FD_CLOEXEC);
	pid_t pid = fork();
	if (pid < 0) {
		close(in[0]), close(in[1]), close(out[0]), close(out[1]), close(err[0]),
			close(err[1]);
		return false;
	}
	if (pid == 0) {
		dup2(in[0], 0);
		dup2(out[1], 1);
		close(in[0]), close(in[1]), close(out[0]), close(out[1]), close(err[0]);
		execvp(argv[0], argv);
		int e = errno;
		if (write(err[1], &e, sizeof(e)) < 0)
			_exit(127);
		_exit(127);
	}
	close(in[0]), close(out[1]), close(err[1]);
	/* a program that exits without reading its input must not end relight */
	struct sigaction ign = {.sa_handler = SIG_IGN}, old;
	sigemptyset(&ign.sa_mask);
	sigaction(SIGPIPE, &ign, &old);
	write_all(in[1], request, strlen(request));
	close(in[1]);
	sigaction(SIGPIPE, &old, NULL);
	int e = 0;
	if (read(err[0], &e, sizeof(e)) == (ssize_t)sizeof(e))
		run->exec_errno = e;
	close(err[0]);
	double deadline = now_s() + timeout_s();
	read_output(out[0], deadline, run);
	close(out[0]);
	/* after its answer the program sees the end of its input: it should end */
	reap(pid, run->ended ? fmin(deadline, now_s() + 5) : run->timed_out ? now_s() : deadline,
	     run);
	return true;
}

/* A handler that takes every request: the reader alone checks the output's syntax. */
static bool accept_all(void *user, const struct rib_request *req)
{
	(void)user;
	(void)req;
	return true;
}

/* Is @data RIB the reader accepts? If not, its first diagnostic into @why. */
static bool output_is_rib(const char *name, const char *data, size_t len, char *why,
			  size_t whylen)
{
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	if (!diag)
		return false;
	struct rib_reader_opts ro = {.diag = diag, .max_errors = 1};
	int n = 0;
	rib_read_buffer(name, data, len, &ro, accept_all, NULL, &n);
	fclose(diag);
	snprintf(why, whylen, "%.*s", (int)strcspn(dbuf ? dbuf : "", "\n"), dbuf ? dbuf : "");
	free(dbuf);
	return n == 0;
}

static void run_program_proc(struct ri *ri, const struct rib_request *r, const float b[6])
{
	const struct rib_value *a = &r->args[1];
	if (a->n != 2)
		FAIL(ri, r->loc, "Procedural \"RunProgram\" takes a program and a data block, got "
		     "%u strings", a->n);
	char **argv = rl_arena_alloc(ri->perm, sizeof(char *) * (MAX_ARGS + 1));
	if (split_words(ri->perm, a->strs[0], argv) == 0)
		FAIL(ri, r->loc, "Procedural \"RunProgram\": no program named");
	/* a read that only checks (relight render's planning read, the fuzzer) runs nothing */
	if (ri->opts->check_only)
		return;
	float m[16];
	sl_m44_mul(m, ri->gs.x.m[0], ri->opt.o.world_to_camera);
	double detail = ri->world ? reyes_ri_raster_area(&ri->opt.o, m, b) : 0;
	const char *request = rl_arena_printf(ri->perm, "%g %s\n", isfinite(detail) ? detail : 1e38,
					      a->strs[1]);
	fflush(NULL);
	struct run run = {0};
	if (!run_program(argv, request, &run))
		FAIL(ri, r->loc, "RunProgram '%s' could not be started: %s", argv[0],
		     strerror(errno));
	const char *prog = argv[0];
	if (run.exec_errno)
		reyes_ri_err(ri, r->loc, "RunProgram '%s' cannot be run: %s", prog,
			     strerror(run.exec_errno));
	else if (run.timed_out)
		reyes_ri_err(ri, r->loc, "RunProgram '%s' did not answer within %g s: killed (its "
			     "output is not used)", prog, timeout_s());
	else if (run.len > MAX_OUTPUT)
		reyes_ri_err(ri, r->loc, "RunProgram '%s' wrote more than %d MB: not used", prog,
			     MAX_OUTPUT >> 20);
	else if (!run.ended && WIFSIGNALED(run.status))
		reyes_ri_err(ri, r->loc, "RunProgram '%s' died (signal %d) before it ended its "
			     "output", prog, WTERMSIG(run.status));
	else if (!run.ended && !(WIFEXITED(run.status) && WEXITSTATUS(run.status) == 0))
		reyes_ri_err(ri, r->loc, "RunProgram '%s' exited with status %d before it ended "
			     "its output", prog, WIFEXITED(run.status) ? WEXITSTATUS(run.status) : -1);
	else {
		char why[512];
		if (!output_is_rib(prog, run.out ? run.out : "", run.len, why, sizeof(why)))
			reyes_ri_err(ri, r->loc, "RunProgram '%s' wrote what is not RIB (%s): not "
				     "used", prog, why);
		else
			reyes_ri_read_buffer(ri, prog, run.out ? run.out : "", run.len);
	}
	free(run.out);
}

void reyes_ri_req_procedural(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	float b[6];
	if (!reyes_ri_geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name) ||
	    !bound_arg(ri, r, b))
		return;
	if (strcmp(name, "DelayedReadArchive") == 0)
		delayed_read_archive(ri, r, b);
	else if (strcmp(name, "RunProgram") == 0)
		run_program_proc(ri, r, b);
	else if (strcmp(name, "DynamicLoad") == 0)
		reyes_ri_warn(ri, r->loc, "relight loads no foreign code: DynamicLoad '%s' skipped",
			      r->args[1].n ? r->args[1].strs[0] : "");
	else
		reyes_ri_warn(ri, r->loc, "Procedural \"%s\" is not supported: skipped (known: "
			      "\"DelayedReadArchive\", \"RunProgram\")", name);
}

void reyes_ri_procedural_light(struct ri *ri, const struct rib_request *r,
			       const struct reyes_light *l)
{
	uint32_t n = *unread(ri);
	if (!n)
		return;
	for (uint32_t k = 0; k < l->shader.nparams; k++) {
		const struct reyes_param_value *p = &l->shader.params[k];
		if (p->strings && p->nvalues && strncmp(p->name, "shadow", 6) == 0 &&
		    p->strings[0] && p->strings[0][0]) {
			reyes_ri_warn(ri, r->loc, "this light reads a shadow map, but %u "
				      "DelayedReadArchive out of view before it %s not read: its "
				      "shadows in a relit preview miss what %s", n, n == 1 ? "was" : "were",
				      n == 1 ? "it holds" : "they hold");
			return;
		}
	}
}

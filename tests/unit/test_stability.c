/*
 * The numerical stability suite (bench/stability.h) in quick mode, as CI
 * runs it:
 *  - every check of every case passes, and every case is there;
 *  - `only` runs just the cases it names, and an unknown name is refused;
 *  - the suite can fail: with a "constant" shader that is one percent off
 *    on the shader path, the weights case fails its colour checks with the
 *    measured error; with one that does not compile, every check of the
 *    case fails with the reason, and nothing crashes;
 *  - a caller's array that is too small is never overrun.
 * Without an EGL context the renderer-only checks must still pass (the GPU
 * ones are skipped), then the test exits 77.
 */
#include "gpu.h"
#include "stability.h"
#include "test.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define CAP 128

static struct gpu_ctx *ctx;
static char workdir[64];
static struct stab_check checks[CAP];

static const char *verdict_name(enum stab_verdict v)
{
	return v == STAB_PASS ? "PASS" : v == STAB_FAIL ? "FAIL" : "SKIP";
}

static void print_table(const struct stab_check *c, int n)
{
	for (int i = 0; i < n; i++)
		printf("%-12s %-58s %11.4g %11.4g %s  %s\n", c[i].group, c[i].name, c[i].value,
		       c[i].limit, verdict_name(c[i].verdict), c[i].note);
}

static int run(bool quick, const char *only, struct stab_check *out, int cap)
{
	struct stab_opts o = { .quick = quick, .workdir = workdir, .ctx = ctx, .log = stderr,
			       .only = only };
	char err[256] = "";
	int n = stab_run(&o, out, cap, err, sizeof(err));
	if (n < 0)
		fprintf(stderr, "stab_run: %s\n", err);
	return n;
}

static int count_group(const struct stab_check *c, int n, const char *group)
{
	int k = 0;
	for (int i = 0; i < n; i++)
		k += !strcmp(c[i].group, group);
	return k;
}

static int full_weights;

static void test_quick_suite(void)
{
	int n = run(true, NULL, checks, CAP);
	CHECK(n > 0);
	if (n <= 0)
		return;
	print_table(checks, n);
	static const char *const groups[] = { "drift", "hdr", "degenerate", "transparency",
					      "weights", "half" };
	for (size_t g = 0; g < sizeof(groups) / sizeof(groups[0]); g++) {
		if (!count_group(checks, n, groups[g]))
			fprintf(stderr, "no checks of case '%s'\n", groups[g]);
		CHECK(count_group(checks, n, groups[g]) > 0);
	}
	full_weights = count_group(checks, n, "weights");
	int skips = 0;
	for (int i = 0; i < n; i++) {
		const struct stab_check *c = &checks[i];
		/* only the GPU's checks may be skipped, and only without a GPU */
		if (c->verdict == STAB_SKIP && !ctx && !strcmp(c->note, "no GPU context")) {
			skips++;
			continue;
		}
		if (c->verdict != STAB_PASS)
			fprintf(stderr, "%s / %s: %s, %g against %g: %s\n", c->group, c->name,
				verdict_name(c->verdict), c->value, c->limit, c->note);
		CHECK(c->verdict == STAB_PASS);
		/* a judged check that passed carries a real measurement */
		if (c->verdict == STAB_PASS && !isnan(c->limit))
			CHECK(!isnan(c->value) && c->value <= c->limit);
	}
	if (!ctx)
		CHECK(skips > 0);
}

static void test_only(void)
{
	struct stab_check c[CAP];
	int n = run(true, "weights", c, CAP);
	CHECK(n == full_weights);
	CHECK(n > 0 && count_group(c, n, "weights") == n);

	/* an unknown case is refused before anything runs */
	struct stab_opts o = { .quick = true, .workdir = workdir, .only = "weights,wieghts" };
	char err[256] = "";
	CHECK(stab_run(&o, c, CAP, err, sizeof(err)) == -1);
	CHECK(strstr(err, "wieghts") != NULL);
	o.only = "weights";
	o.workdir = "/nonexistent/relight-stability";
	CHECK(stab_run(&o, c, CAP, err, sizeof(err)) == -1);
	CHECK(strstr(err, "/nonexistent/relight-stability") != NULL);

	/* room for two: two are filled, the rest left out */
	memset(c, 0xa5, sizeof(c));
	n = run(true, "weights", c, 2);
	CHECK(n == 2);
	unsigned char untouched[sizeof(c[2])];
	memset(untouched, 0xa5, sizeof(untouched));
	CHECK(!memcmp(&c[2], untouched, sizeof(untouched)));
}

/* Write a "constant" surface shader with body @body into WORKDIR/shaders. */
static bool write_constant(const char *body)
{
	char path[256];
	snprintf(path, sizeof(path), "%s/shaders", workdir);
	if (access(path, F_OK) != 0 && mkdir(path, 0755) != 0)
		return false;
	snprintf(path, sizeof(path), "%s/shaders/constant.sl", workdir);
	FILE *f = fopen(path, "w");
	if (!f)
		return false;
	fprintf(f, "surface constant()\n{\n%s\n}\n", body);
	return fclose(f) == 0;
}

static const struct stab_check *find(const struct stab_check *c, int n, const char *prefix)
{
	for (int i = 0; i < n; i++)
		if (!strncmp(c[i].name, prefix, strlen(prefix)))
			return &c[i];
	return NULL;
}

static void test_can_fail(void)
{
	char dir[256];
	snprintf(dir, sizeof(dir), "%s/shaders", workdir);
	struct stab_check c[CAP];

	/* one percent too dark: the renderer's colours miss the constant */
	CHECK(write_constant("\tOi = Os;\n\tCi = Os * Cs * 0.99;"));
	setenv("RELIGHT_SHADER_PATH", dir, 1);
	int n = run(true, "weights", c, CAP);
	CHECK(n == full_weights);
	print_table(c, n);
	const struct stab_check *full = find(c, n, "render, full cover");
	const struct stab_check *edge = find(c, n, "render, edge: colour");
	CHECK(full && full->verdict == STAB_FAIL && fabs(full->value - 0.01) < 1e-4);
	CHECK(edge && edge->verdict == STAB_FAIL && edge->value > 0.005);
	const struct stab_check *alpha = find(c, n, "render, edge: alpha");
	CHECK(alpha && alpha->verdict == STAB_PASS);
	if (ctx) {
		const struct stab_check *g = find(c, n, "GPU, full cover");
		CHECK(g && g->verdict == STAB_FAIL && fabs(g->value - 0.01) < 1e-4);
	}

	/* a shader that does not compile: every check fails with the reason */
	CHECK(write_constant("\tCi = undefined_thing;"));
	n = run(true, "weights", c, CAP);
	CHECK(n == full_weights);
	print_table(c, n);
	for (int i = 0; i < n; i++) {
		CHECK(c[i].verdict == STAB_FAIL);
		CHECK(strstr(c[i].note, "failed") != NULL);
	}
	unsetenv("RELIGHT_SHADER_PATH");
}

int main(void)
{
	char dir[] = "/tmp/relight-test-stability-XXXXXX";
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	snprintf(workdir, sizeof(workdir), "%s", dir);
	char err[512];
	ctx = gpu_create(err, sizeof(err));
	RUN(test_quick_suite);
	RUN(test_only);
	RUN(test_can_fail);
	int rc = test_finish();
	gpu_destroy(ctx);
	char cmd[256];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "test_stability: cannot remove %s\n", dir);
	if (!ctx && rc == 0) {
		printf("SKIP: no OpenGL 4.3 context (%s): the renderer-only checks passed, the GPU "
		       "checks were skipped\n", err);
		return 77;
	}
	return rc;
}

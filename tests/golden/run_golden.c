/*
 * Golden shader tests: each .sl file in this folder states what it expects
 * in comment lines, and this program checks it.
 *
 *   // expect-error: LINE:COL: TEXT    compiling fails with a diagnostic at
 *                                       LINE:COL containing TEXT (repeatable)
 *   // grid: NU NV                     run on an NU x NV grid (default 4 4)
 *   // expect: NAME[I] = V [V V] ~TOL  after the run, component values of the
 *                                       output parameter or global NAME at point
 *                                       I ('*' for every point) match within TOL
 *   // expect-print: TEXT              printf output contains TEXT
 *
 * The grid: u = iu/(nu-1), v = iv/(nv-1) (0 when a dimension has one point),
 * s = u, t = v, du = 1/(nu-1), dv = 1/(nv-1), P = (u, v, 0), N = Ng = (0,0,1),
 * dPdu = (1,0,0), dPdv = (0,1,0), E = (0,0,-1), I = P - E, Cs = Os = 1,
 * time = 0, dtime = 0, ncomps = 3.
 */
#include "exec.h"
#include "../../daemon/common/strbuf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures;

#include <stdarg.h>

__attribute__((format(printf, 3, 4)))
static void fail(const char *path, int line, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "%s:%d: ", path, line);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	failures++;
}

static struct rl_strbuf printed;

static void capture(void *user, const char *text)
{
	(void)user;
	rl_strbuf_puts(&printed, text);
}

static void fill_globals(struct sl_exec *x, uint32_t nu, uint32_t nv)
{
	uint32_t st = sl_exec_stride(x);
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool varying;
		float *d = sl_exec_global(x, (enum sl_global)g, &varying);
		if (!d)
			continue;
		uint32_t n = varying ? nu * nv : 1;
		for (uint32_t i = 0; i < n; i++) {
			float u = nu > 1 ? (float)(i % nu) / (float)(nu - 1) : 0;
			float v = nv > 1 ? (float)(i / nu) / (float)(nv - 1) : 0;
			float val[3] = { 0, 0, 0 };
			switch (g) {
			case SL_GLOBAL_P: case SL_GLOBAL_PS: val[0] = u; val[1] = v; break;
			case SL_GLOBAL_N: case SL_GLOBAL_NG: val[2] = 1; break;
			case SL_GLOBAL_DPDU: val[0] = 1; break;
			case SL_GLOBAL_DPDV: val[1] = 1; break;
			case SL_GLOBAL_E: val[2] = -1; break;
			case SL_GLOBAL_I: val[0] = u; val[1] = v; val[2] = 1; break;
			case SL_GLOBAL_CS: case SL_GLOBAL_OS: case SL_GLOBAL_OI:
				val[0] = val[1] = val[2] = 1; break;
			case SL_GLOBAL_S: case SL_GLOBAL_U: val[0] = u; break;
			case SL_GLOBAL_T: case SL_GLOBAL_V: val[0] = v; break;
			case SL_GLOBAL_DU: val[0] = nu > 1 ? 1.0f / (float)(nu - 1) : 1; break;
			case SL_GLOBAL_DV: val[0] = nv > 1 ? 1.0f / (float)(nv - 1) : 1; break;
			case SL_GLOBAL_NCOMPS: val[0] = 3; break;
			default: break;
			}
			int nc = sl_type_ncomp(sl_global_type((enum sl_global)g).base);
			for (int c = 0; c < nc; c++) {
				if (varying)
					d[(size_t)c * st + i] = val[c];
				else
					d[c] = val[c];
			}
		}
	}
}

/* Register of an output parameter or global named @name, or -1. */
static int32_t find_reg(const struct sl_program *p, const char *name)
{
	int k = sl_program_find_param(p, name);
	if (k >= 0)
		return p->params[k].reg;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		if (!strcmp(sl_global_name((enum sl_global)g), name))
			return p->global_reg[g];
	return -1;
}

static void check_expect(const char *path, int line, const char *spec, struct sl_exec *x,
			 uint32_t npts)
{
	const struct sl_program *p = sl_exec_program(x);
	char name[64], idx[16];
	const char *eq = strchr(spec, '=');
	if (!eq || sscanf(spec, " %63[A-Za-z0-9_] [ %15[0-9*] ]", name, idx) != 2) {
		fail(path, line, "bad expect line: %s", spec);
		return;
	}
	float want[16];
	int nwant = 0;
	double tol = 0;
	const char *q = eq + 1;
	while (*q && nwant < 16) {
		while (*q == ' ' || *q == '\t' || *q == '(' || *q == ',' || *q == ')')
			q++;
		if (*q == '~') {
			tol = strtod(q + 1, NULL);
			break;
		}
		char *end;
		double d = strtod(q, &end);
		if (end == q)
			break;
		want[nwant++] = (float)d;
		q = end;
	}
	int32_t r = find_reg(p, name);
	if (r < 0) {
		fail(path, line, "no output parameter or global '%s'", name);
		return;
	}
	const struct sl_reg *reg = &p->regs[r];
	int nc = sl_reg_ncomp(reg) * (reg->arraylen ? reg->arraylen : 1);
	if (nwant != nc) {
		fail(path, line, "'%s' has %d components, the line gives %d", name, nc, nwant);
		return;
	}
	const float *d = sl_exec_reg(x, r);
	uint32_t st = sl_exec_stride(x);
	uint32_t first = 0, last = 0;
	if (idx[0] == '*') {
		first = 0;
		last = npts - 1;
	} else {
		first = last = (uint32_t)atoi(idx);
		if (first >= npts) {
			fail(path, line, "point %u is outside the grid", first);
			return;
		}
	}
	for (uint32_t i = first; i <= last; i++) {
		for (int c = 0; c < nc; c++) {
			float got = reg->varying ? d[(size_t)c * st + i] : d[c];
			if (!(fabs((double)got - (double)want[c]) <= tol)) {
				fail(path, line, "%s[%u] component %d = %.9g, expected %.9g (tolerance %g)",
				     name, i, c, (double)got, (double)want[c], tol);
				return;
			}
		}
	}
}

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: run_golden FILE.sl\n");
		return 2;
	}
	const char *path = argv[1];
	FILE *f = fopen(path, "r");
	if (!f) {
		perror(path);
		return 2;
	}
	char line[1024];
	RL_VEC(char *) errors = { 0 };
	RL_VEC(char *) expects = { 0 };
	RL_VEC(int) expect_lines = { 0 };
	RL_VEC(char *) prints = { 0 };
	unsigned nu = 4, nv = 4;
	int lineno = 0;
	while (fgets(line, sizeof(line), f)) {
		lineno++;
		line[strcspn(line, "\n")] = 0;
		const char *c = strstr(line, "// ");
		if (!c)
			continue;
		c += 3;
		if (!strncmp(c, "expect-error:", 13))
			rl_vec_push(errors, rl_xstrdup(c + 13));
		else if (!strncmp(c, "expect-print:", 13))
			rl_vec_push(prints, rl_xstrdup(c + 14));
		else if (!strncmp(c, "expect:", 7)) {
			rl_vec_push(expects, rl_xstrdup(c + 7));
			rl_vec_push(expect_lines, lineno);
		} else if (!strncmp(c, "grid:", 5))
			sscanf(c + 5, "%u %u", &nu, &nv);
	}
	fclose(f);

	char *diag = NULL;
	size_t diaglen = 0;
	FILE *dout = open_memstream(&diag, &diaglen);
	struct sl_options opts = { .diag = dout };
	struct sl_program *prog = sl_compile_file(path, &opts);
	fclose(dout);

	if (errors.len) {
		if (prog) {
			fprintf(stderr, "%s: compiled, but errors were expected\n", path);
			failures++;
		}
		for (size_t i = 0; i < errors.len; i++) {
			/* "LINE:COL: TEXT" must appear as FILE:LINE:COL: error: ...TEXT */
			unsigned l = 0, col = 0;
			char text[512] = "";
			sscanf(errors.data[i], " %u:%u: %511[^\n]", &l, &col, text);
			char at[64];
			snprintf(at, sizeof(at), ":%u:%u: error: ", l, col);
			const char *hit = diag ? strstr(diag, at) : NULL;
			const char *eol = hit ? strchr(hit, '\n') : NULL;
			bool ok = hit && strstr(hit, text) && (!eol || strstr(hit, text) < eol);
			if (!ok) {
				fprintf(stderr, "%s: expected error at %u:%u containing \"%s\"; got:\n%s",
					path, l, col, text, diag ? diag : "");
				failures++;
			}
		}
	} else if (!prog) {
		fprintf(stderr, "%s: failed to compile:\n%s", path, diag ? diag : "");
		failures++;
	} else if (expects.len || prints.len) {
		struct sl_exec *x = sl_exec_create(prog, nu * nv);
		sl_exec_set_grid(x, nu, nv);
		fill_globals(x, nu, nv);
		struct sl_host host = { .print = capture };
		if (!sl_exec_run(x, &host)) {
			fprintf(stderr, "%s: run failed\n", path);
			failures++;
		}
		for (size_t i = 0; i < expects.len; i++)
			check_expect(path, expect_lines.data[i], expects.data[i], x, nu * nv);
		for (size_t i = 0; i < prints.len; i++)
			if (!strstr(rl_strbuf_str(&printed), prints.data[i])) {
				fprintf(stderr, "%s: printed \"%s\", expected to contain \"%s\"\n", path,
					rl_strbuf_str(&printed), prints.data[i]);
				failures++;
			}
		sl_exec_destroy(x);
	}
	sl_program_destroy(prog);
	free(diag);
	for (size_t i = 0; i < errors.len; i++)
		free(errors.data[i]);
	for (size_t i = 0; i < expects.len; i++)
		free(expects.data[i]);
	for (size_t i = 0; i < prints.len; i++)
		free(prints.data[i]);
	rl_vec_free(errors);
	rl_vec_free(expects);
	rl_vec_free(expect_lines);
	rl_vec_free(prints);
	rl_strbuf_finish(&printed);
	if (failures)
		fprintf(stderr, "%s: %d failure(s)\n", path, failures);
	return failures ? 1 : 0;
}

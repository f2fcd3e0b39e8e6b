/*
 * The grid interpreter on real shaders: every surface shader of shaders/,
 * lit by the four shipped local lights (distant, point, spot, uberlight),
 * on a 32x32 grid (1024 points, the REYES default grid size) over a
 * curved patch. Reports operations per second on one thread, where an
 * operation is one instruction applied to one point (sl_exec_op_count),
 * light shaders' work included.
 *
 *   bench_shaders [SHADER_DIR] [SECONDS_PER_CASE]
 */
#include "exec.h"
#include "lighthost.h"
#include "config.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define NU 32
#define NV 32

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static struct sl_program *load(const char *dir, const char *name)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/%s.sl", dir, name);
	struct sl_program *p = sl_compile_file(path, NULL);
	if (!p)
		fprintf(stderr, "bench_shaders: cannot compile %s\n", path);
	return p;
}

/* A patch of a sphere of radius 2 seen from the origin, 3 units away. */
static void fill_surface(struct sl_exec *x)
{
	uint32_t st = sl_exec_stride(x);
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		bool vary;
		float *d = sl_exec_global(x, (enum sl_global)g, &vary);
		if (!d)
			continue;
		uint32_t n = vary ? NU * NV : 1;
		for (uint32_t i = 0; i < n; i++) {
			float u = (float)(i % NU) / (NU - 1), v = (float)(i / NU) / (NV - 1);
			float th = (u - 0.5f) * 1.2f, ph = (v - 0.5f) * 1.2f;
			float nx = sinf(th) * cosf(ph), ny = sinf(ph), nz = -cosf(th) * cosf(ph);
			float p[3] = { 2 * nx, 2 * ny, 5 + 2 * nz };
			float val[3] = { 0, 0, 0 };
			switch (g) {
			case SL_GLOBAL_P: case SL_GLOBAL_PS: memcpy(val, p, sizeof(p)); break;
			case SL_GLOBAL_I: memcpy(val, p, sizeof(p)); break;
			case SL_GLOBAL_N: case SL_GLOBAL_NG:
				val[0] = nx; val[1] = ny; val[2] = nz; break;
			case SL_GLOBAL_CS: val[0] = 0.8f; val[1] = 0.5f; val[2] = 0.3f; break;
			case SL_GLOBAL_OS: case SL_GLOBAL_OI: val[0] = val[1] = val[2] = 1; break;
			case SL_GLOBAL_S: case SL_GLOBAL_U: val[0] = u; break;
			case SL_GLOBAL_T: case SL_GLOBAL_V: val[0] = v; break;
			case SL_GLOBAL_DU: val[0] = 1.0f / (NU - 1); break;
			case SL_GLOBAL_DV: val[0] = 1.0f / (NV - 1); break;
			case SL_GLOBAL_DPDU: val[0] = 1.2f; break;
			case SL_GLOBAL_DPDV: val[1] = 1.2f; break;
			case SL_GLOBAL_NCOMPS: val[0] = 3; break;
			default: break;
			}
			int nc = sl_type_ncomp(sl_global_type((enum sl_global)g).base);
			for (int c = 0; c < nc; c++) {
				if (vary)
					d[(size_t)c * st + i] = val[c];
				else
					d[c] = val[c];
			}
		}
	}
}

int main(int argc, char **argv)
{
	const char *dir = argc > 1 ? argv[1] : RELIGHT_SOURCE_SHADER_DIR;
	double budget = argc > 2 ? atof(argv[2]) : 0.5;
	static const char *const light_names[] = { "distantlight", "pointlight", "spotlight",
						   "uberlight" };
	static const char *const surfaces[] = { "constant", "matte", "metal", "shinymetal",
						"plastic", "paintedplastic", "defaultsurface" };
	enum { NL = 4 };
	struct sl_program *lp[NL];
	struct sl_exec *lx[NL];
	for (int i = 0; i < NL; i++) {
		lp[i] = load(dir, light_names[i]);
		if (!lp[i])
			return 1;
		lx[i] = sl_exec_create(lp[i], NU * NV);
	}
	/* Put the lights where they light the patch. */
	float from[3] = { 0, 0, 0 }, to[3] = { 0, 0, 5 }, pfrom[3] = { 1, 1, 1 };
	sl_exec_set_param(lx[0], "from", from, 3);
	sl_exec_set_param(lx[0], "to", to, 3);
	sl_exec_set_param(lx[1], "from", pfrom, 3);
	sl_exec_set_param(lx[2], "from", from, 3);
	sl_exec_set_param(lx[2], "to", to, 3);
	float angle = 0.6f;
	sl_exec_set_param(lx[2], "coneangle", &angle, 1);

	printf("grid %dx%d, %d lights (%s, %s, %s, %s), one thread\n", NU, NV, NL,
	       light_names[0], light_names[1], light_names[2], light_names[3]);
	printf("%-16s %10s %12s %14s\n", "surface", "runs", "ms/grid", "M ops/s");
	double all_ops = 0, all_time = 0;
	int status = 0;
	for (size_t s = 0; s < sizeof(surfaces) / sizeof(surfaces[0]); s++) {
		struct sl_program *sp = load(dir, surfaces[s]);
		if (!sp) {
			status = 1;
			continue;
		}
		struct sl_exec *sx = sl_exec_create(sp, NU * NV);
		sl_exec_set_grid(sx, NU, NV);
		fill_surface(sx);
		struct sl_lighthost lh;
		sl_lighthost_init(&lh, lx, NL);
		/* shader, object and world space coincide with camera space here */
		static const char *const spaces[] = { "shader", "object", "world" };
		static const float ident[3][16] = { { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 },
						   { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 },
						   { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 } };
		lh.space_names = spaces;
		lh.space_mats = ident;
		lh.nspaces = 3;
		uint64_t ops0 = sl_exec_op_count(sx);
		uint64_t lops0 = 0;
		for (int i = 0; i < NL; i++)
			lops0 += sl_exec_op_count(lx[i]);
		int runs = 0;
		double t0 = now(), t;
		do {
			if (!sl_exec_run(sx, &lh.host)) {
				status = 1;
				break;
			}
			runs++;
			t = now();
		} while (t - t0 < budget);
		t = now() - t0;
		uint64_t lops = 0;
		for (int i = 0; i < NL; i++)
			lops += sl_exec_op_count(lx[i]);
		double ops = (double)(sl_exec_op_count(sx) - ops0) + (double)(lops - lops0);
		printf("%-16s %10d %12.3f %14.1f\n", surfaces[s], runs, 1e3 * t / runs,
		       ops / t * 1e-6);
		all_ops += ops;
		all_time += t;
		sl_exec_destroy(sx);
		sl_program_destroy(sp);
	}
	printf("%-16s %10s %12s %14.1f\n", "all", "", "", all_ops / all_time * 1e-6);
	for (int i = 0; i < NL; i++) {
		sl_exec_destroy(lx[i]);
		sl_program_destroy(lp[i]);
	}
	return status;
}

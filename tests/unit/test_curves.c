/*
 * Tests of Curves and Points: the scene builder's counts, classes and the
 * eye they face; their pieces' bounds (every diced point of every split
 * inside, for bases whose weights go negative too); ribbons' widths,
 * facing and parameters; disks' exact area whatever the dice rate.
 */
#include "geom.h"
#include "mathlib.h"
#include "ri.h"
#include "test.h"

#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#define PI_D 3.14159265358979323846

static char dir[64];
static char diag[1 << 14];
static void (*inspect)(const struct reyes_scene *sc);
static int frames;

static bool on_frame(void *user, const struct reyes_scene *sc)
{
	(void)user;
	frames++;
	inspect(sc);
	return true;
}

/* Reads @text (a world's body after a camera) with @fn called on the scene. */
static bool run(const char *camera, const char *body, void (*fn)(const struct reyes_scene *))
{
	const char *path = test_fmt("%s/t.rib", dir);
	FILE *f = fopen(path, "w");
	if (!f)
		exit(1);
	fprintf(f, "%s\nWorldBegin\n%s\nWorldEnd\n", camera, body);
	fclose(f);
	FILE *d = tmpfile();
	struct reyes_ri_opts o = {.diag = d, .frame = on_frame};
	int nerrors = 0;
	frames = 0;
	inspect = fn;
	bool ok = reyes_ri_read(path, &o, &nerrors);
	rewind(d);
	size_t n = fread(diag, 1, sizeof(diag) - 1, d);
	diag[n] = '\0';
	fclose(d);
	unlink(path);
	return ok && nerrors == 0;
}

static const char *ortho = "Projection \"orthographic\"\nTranslate 0 0 5";
static const char *persp = "Projection \"perspective\" \"fov\" 40\nTranslate 0 0 5";

static size_t npieces(const struct reyes_prim *p)
{
	struct reyes_patch *out = NULL;
	size_t n = 0, cap = 0;
	if (!reyes_prim_pieces(p, &out, &n, &cap))
		n = SIZE_MAX;
	free(out);
	return n;
}

/* ---- the scene builder ---- */

static void counts_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 4);
	if (sc->nprims != 4)
		return;
	/* b-spline [6 5]: 3 + 2 segments; periodic [4 6]: 4 + 6; linear [3 2]: 2 + 1; 3 points */
	CHECK(sc->prims[0].kind == REYES_CURVES && npieces(&sc->prims[0]) == 5);
	CHECK(sc->prims[1].kind == REYES_CURVES && npieces(&sc->prims[1]) == 10);
	CHECK(sc->prims[2].kind == REYES_CURVES && npieces(&sc->prims[2]) == 3);
	CHECK(sc->prims[3].kind == REYES_POINTS && npieces(&sc->prims[3]) == 3);
	const struct reyes_primvar *w = reyes_prim_var(&sc->prims[0], "width");
	CHECK(w && w->cls == REYES_VARYING && w->count == 7);
	const struct reyes_primvar *cw = reyes_prim_var(&sc->prims[2], "constantwidth");
	CHECK(cw && cw->cls == REYES_CONSTANT && cw->count == 1);
	const struct reyes_primvar *cs = reyes_prim_var(&sc->prims[1], "Cs");
	CHECK(cs && cs->cls == REYES_UNIFORM && cs->count == 2);
	/* the eye of an orthographic camera: the direction towards it, -z */
	CHECK_NEAR(sc->prims[0].eye[0][2], -1.0, 1e-6);
	CHECK_NEAR(sc->prims[0].eye[0][3], 0.0, 0);
}

static void test_counts(void)
{
	CHECK(run(ortho,
		  "Basis \"b-spline\" 1 \"b-spline\" 1\n"
		  "Curves \"cubic\" [6 5] \"nonperiodic\" \"P\" [0 0 0 1 0 0 2 0 0 3 0 0 4 0 0 5 0 0 "
		  "0 1 0 1 1 0 2 1 0 3 1 0 4 1 0] \"width\" [1 2 3 4 5 6 7]\n"
		  "Curves \"cubic\" [4 6] \"periodic\" \"P\" [0 0 0 1 0 0 1 1 0 0 1 0 "
		  "0 0 1 1 0 1 2 0 1 2 1 1 1 1 1 0 1 1] \"uniform color Cs\" [1 0 0 0 1 0]\n"
		  "Curves \"linear\" [3 2] \"nonperiodic\" \"P\" [0 0 0 1 0 0 1 1 0 0 0 2 1 0 2] "
		  "\"constantwidth\" 0.1\n"
		  "Points \"P\" [0 0 0 1 0 0 0 1 0] \"width\" [0.1 0.2 0.3]",
		  counts_scene));
	CHECK(frames == 1);
}

static void eye_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	if (sc->nprims < 1)
		return;
	/* the camera 5 in front of the world's origin, the points 2 further along x */
	const float *e = sc->prims[0].eye[0];
	CHECK_NEAR(e[0], -2.0, 1e-5);
	CHECK_NEAR(e[1], 0.0, 1e-5);
	CHECK_NEAR(e[2], -5.0, 1e-5);
	CHECK_NEAR(e[3], 1.0, 0);
	CHECK(!sc->prims[0].mirror);
}

static void test_eye(void)
{
	CHECK(run(persp, "Translate 2 0 0\nPoints \"P\" [0 0 0]", eye_scene));
}

static void dropped_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 0);
}

static void test_malformed(void)
{
	static const struct {
		const char *body, *msg;
	} cases[] = {
		{"Curves \"linear\" [2 2] \"nonperiodic\" \"P\" [0 0 0 1 0 0 2 0 0]",
		 "nvertices add up to 4, but \"P\" has 3 points"},
		{"Curves \"cubic\" [3] \"nonperiodic\" \"P\" [0 0 0 1 0 0 2 0 0]",
		 "curve 0 has 3 vertices, too few"},
		{"Basis \"bezier\" 3 \"bezier\" 3\nCurves \"cubic\" [6] \"nonperiodic\" \"P\" "
		 "[0 0 0 1 0 0 2 0 0 3 0 0 4 0 0 5 0 0]", "curve 0 has 6 vertices"},
		{"Curves \"linear\" [2] \"nonperiodic\" \"P\" [0 0 0 1 0 0] \"width\" [1 -1]",
		 "\"width\" 1 is -1"},
		{"Curves \"linear\" [2] \"nonperiodic\" \"P\" [0 0 0 1 0 0] \"width\" [1 1 1]",
		 "\"width\" (varying float) needs 2 values, got 3"},
		{"Curves \"quadratic\" [2] \"nonperiodic\" \"P\" [0 0 0 1 0 0]",
		 "Curves type must be \"linear\" or \"cubic\""},
		{"Curves \"linear\" 2 \"nonperiodic\" \"P\" [0 0 0 1 0 0]", "Curves"},
		{"Points \"P\" [0 0 0] \"constantwidth\" [-2]", "\"constantwidth\" 0 is -2"},
		{"Points \"constantwidth\" [1]", "Points needs \"P\""},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		CHECK(!run(ortho, cases[i].body, dropped_scene));
		CHECK(frames == 1);      /* the frame renders without it */
		if (!strstr(diag, cases[i].msg) || !strstr(diag, "t.rib:"))
			fprintf(stderr, "case %zu: diagnostics lack \"%s\": %s", i, cases[i].msg, diag);
		CHECK(strstr(diag, cases[i].msg) && strstr(diag, "t.rib:"));
	}
}

/* ---- bounds and dicing ---- */

static uint64_t rng = 88172645463325252u;
static double rnd(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0;
}

/* Every point of a 9x9 dice of @pa (and of its halves, @depth times down) inside its bound. */
static int outside(const struct reyes_patch *pa, int depth)
{
	int bad = 0;
	struct reyes_grid g;
	if (!reyes_patch_dice(pa, 9, 9, &g))
		return 1000;
	for (int t = 0; t < 2; t++) {
		float lo[3], hi[3];
		reyes_patch_bound(pa, t, lo, hi);
		for (uint32_t k = 0; k < g.n; k++)
			for (int c = 0; c < 3; c++) {
				float x = g.P[t][c * g.n + k];
				bad += !(x >= lo[c] && x <= hi[c]);
			}
	}
	reyes_grid_finish(&g);
	if (depth > 0) {
		struct reyes_patch half[2];
		reyes_patch_split(pa, rnd() < 0.5, half);
		bad += outside(&half[0], depth - 1) + outside(&half[1], depth - 1);
	}
	return bad;
}

static void bounds_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 5);
	for (uint32_t i = 0; i < sc->nprims; i++) {
		struct reyes_patch *out = NULL;
		size_t n = 0, cap = 0;
		CHECK(reyes_prim_pieces(&sc->prims[i], &out, &n, &cap));
		int bad = 0;
		for (size_t k = 0; k < n; k++)
			bad += outside(&out[k], 4);
		if (bad)
			fprintf(stderr, "primitive %u: %d diced coordinates outside their bounds\n", i,
				bad);
		CHECK(bad == 0);
		free(out);
	}
}

static void test_bounds(void)
{
	/* catmull-rom overshoots its control points; widths taper; N turns; points move */
	CHECK(run(persp,
		  "Basis \"catmull-rom\" 1 \"catmull-rom\" 1\n"
		  "Curves \"cubic\" [6] \"nonperiodic\" \"P\" [0 0 0  1 2 0  2 -2 1  3 2 0  4 -2 -1  5 0 0] "
		  "\"width\" [0.5 0.1 0.9 0.2]\n"
		  "Curves \"cubic\" [5] \"periodic\" \"P\" [0 0 0  1 2 0  2 -2 1  3 2 0  4 -2 -1] "
		  "\"vertex float width\" [0.3 0.9 0.1 0.5 0.7]\n"
		  "Curves \"linear\" [3] \"nonperiodic\" \"P\" [0 0 0  1 1 1  2 0 3] "
		  "\"N\" [0 0 1  1 0 0  0 1 0] \"width\" [0.4 0.4 0.1]\n"
		  "MotionBegin [0 1]\n"
		  "Points \"P\" [0 0 0  1 1 1] \"width\" [0.4 0.8]\n"
		  "Points \"P\" [0.5 0 0  1 1 2] \"width\" [0.6 0.2]\n"
		  "MotionEnd\n"
		  "MotionBegin [0 1]\n"
		  "Curves \"linear\" [2] \"nonperiodic\" \"P\" [0 0 0  1 0 0] \"constantwidth\" 0.3\n"
		  "Curves \"linear\" [2] \"nonperiodic\" \"P\" [0 1 0  1 2 1] \"constantwidth\" 0.3\n"
		  "MotionEnd",
		  bounds_scene));
}

static void ribbon_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	if (sc->nprims < 1)
		return;
	const struct reyes_prim *p = &sc->prims[0];
	struct reyes_patch *out = NULL;
	size_t n = 0, cap = 0;
	CHECK(reyes_prim_pieces(p, &out, &n, &cap) && n == 2);
	const float *e = p->eye[0];
	for (size_t k = 0; k < n; k++) {
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&out[k], 3, 5, &g));
		for (uint32_t j = 0; j < g.nv; j++) {
			uint32_t a = j * g.nu, b = a + g.nu - 1;
			/* across: the width, 0.2 at the curve's start to 0.6 at its end */
			double d[3], v = g.v[a];
			for (int c = 0; c < 3; c++)
				d[c] = g.P[0][c * g.n + b] - g.P[0][c * g.n + a];
			CHECK_NEAR(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 0.2 + 0.4 * v, 1e-5);
			CHECK_NEAR(g.u[a], 0.0, 0);
			CHECK_NEAR(g.u[b], 1.0, 0);
			for (uint32_t i = 0; i < g.nu; i++) {
				uint32_t q = a + i;
				double to_eye = 0.0;
				for (int c = 0; c < 3; c++)
					to_eye += g.Ng[c * g.n + q] * (e[c] - g.P[0][c * g.n + q]);
				CHECK(to_eye > 0.0);
			}
		}
		/* v runs over the whole curve: 0 to 0.5, then 0.5 to 1 */
		CHECK_NEAR(g.v[0], 0.5 * (double)k, 1e-6);
		CHECK_NEAR(g.v[g.n - 1], 0.5 * (double)(k + 1), 1e-6);
		reyes_grid_finish(&g);
	}
	free(out);
}

static void test_ribbon(void)
{
	CHECK(run(persp,
		  "Rotate 30 0 1 0\n"
		  "Curves \"linear\" [3] \"nonperiodic\" \"P\" [-1 0 0  0 0.5 0  1 0 0.5] "
		  "\"width\" [0.2 0.4 0.6]",
		  ribbon_scene));
}

/* The area of the polygon a disk's diced outer ring makes, from its centre. */
static void disk_scene(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	if (sc->nprims < 1)
		return;
	struct reyes_patch pa = {.prim = &sc->prims[0], .u0 = 0, .u1 = 1, .v0 = 0, .v1 = 1};
	const uint32_t rates[] = {2, 5, 9, 17, 64};
	for (size_t r = 0; r < sizeof(rates) / sizeof(rates[0]); r++) {
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa, rates[r], 3, &g));
		CHECK(g.nu >= 9);      /* at least 8 sides */
		double area = 0.0;
		uint32_t ring = (g.nv - 1) * g.nu;
		for (uint32_t i = 0; i + 1 < g.nu; i++) {
			/* the disk faces -z (towards the eye): project on xy */
			double x0 = g.P[0][ring + i] - 1, y0 = g.P[0][g.n + ring + i] - 2;
			double x1 = g.P[0][ring + i + 1] - 1, y1 = g.P[0][g.n + ring + i + 1] - 2;
			area += 0.5 * fabs(x0 * y1 - x1 * y0);
		}
		CHECK_NEAR(area, PI_D * 0.25 * 0.25, 1e-6);
		for (uint32_t k = 0; k < g.n; k++)
			CHECK_NEAR(g.P[0][2 * g.n + k], 3.0, 1e-6);
		reyes_grid_finish(&g);
	}
}

static void test_disk(void)
{
	CHECK(run(ortho, "Points \"P\" [1 2 3] \"constantwidth\" [0.5]", disk_scene));
}

int main(void)
{
	snprintf(dir, sizeof(dir), "/tmp/test_curves.XXXXXX");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_counts);
	RUN(test_eye);
	RUN(test_malformed);
	RUN(test_bounds);
	RUN(test_ribbon);
	RUN(test_disk);
	rmdir(dir);
	return test_finish();
}

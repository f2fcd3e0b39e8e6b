/* Tests of the geometry module: pieces, bounds, splits and diced grids, against closed forms. */
#include "geom.h"
#include "log.h"
#include "test.h"

#include <float.h>
#include <pthread.h>
#include <stdint.h>
#include <time.h>

#define PI_D 3.14159265358979323846

/* A primitive with room for its own variables and attributes. */
struct tprim {
	struct reyes_prim prim;
	struct reyes_attrs attrs;
	struct reyes_primvar vars[8];
};

static void tprim_init(struct tprim *t, enum reyes_prim_kind kind)
{
	memset(t, 0, sizeof(*t));
	t->prim.kind = kind;
	t->prim.attrs = &t->attrs;
	t->prim.vars = t->vars;
}

static struct reyes_primvar *add_var(struct tprim *t, const char *name, enum reyes_class cls,
				     int type, uint32_t arraylen, uint32_t count, const float *values)
{
	struct reyes_primvar *v = &t->vars[t->prim.nvars++];
	v->name = name;
	v->cls = cls;
	v->type = type;
	v->arraylen = arraylen;
	v->count = count;
	v->values = values;
	return v;
}

static void quadric(struct tprim *t, enum reyes_prim_kind kind, float a, float b, float c,
		    float d, float e, float f, float g)
{
	tprim_init(t, kind);
	float q[7] = { a, b, c, d, e, f, g };
	memcpy(t->prim.q, q, sizeof(q));
}

/* The prim's pieces in a fresh array (caller frees); count in *n. */
static struct reyes_patch *pieces(const struct reyes_prim *p, size_t *n, bool *ok)
{
	struct reyes_patch *out = NULL;
	size_t cap = 0;
	*n = 0;
	bool r = reyes_prim_pieces(p, &out, n, &cap);
	if (ok)
		*ok = r;
	return out;
}

static bool all_finite(const float *a, size_t count)
{
	if (!a)
		return true;
	for (size_t i = 0; i < count; i++)
		if (!isfinite(a[i]))
			return false;
	return true;
}

/* No NaN or Inf anywhere in a grid. */
static bool grid_finite(const struct reyes_grid *g)
{
	size_t n = g->n, n3 = 3 * n;
	bool ok = all_finite(g->P[0], n3) && all_finite(g->P[1], n3) && all_finite(g->dPdu, n3) &&
		  all_finite(g->dPdv, n3) && all_finite(g->Ng, n3) && all_finite(g->N, n3) &&
		  all_finite(g->u, n) && all_finite(g->v, n) && all_finite(g->s, n) &&
		  all_finite(g->t, n) && all_finite(g->Cs, n3) && all_finite(g->Os, n3) &&
		  isfinite(g->du) && isfinite(g->dv);
	for (uint32_t i = 0; i < g->nvars; i++)
		ok = ok && all_finite(g->vars[i].data, n);
	return ok;
}

static void get3(const float *planar, uint32_t n, uint32_t k, double out[3])
{
	out[0] = planar[k];
	out[1] = planar[n + k];
	out[2] = planar[2 * n + k];
}

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double len3(const double a[3])
{
	return sqrt(dot3(a, a));
}

static void cross3(double r[3], const double a[3], const double b[3])
{
	r[0] = a[1] * b[2] - a[2] * b[1];
	r[1] = a[2] * b[0] - a[0] * b[2];
	r[2] = a[0] * b[1] - a[1] * b[0];
}

/* Area of a planar bilinear piece from its 2x2 dice. */
static double piece_area(const struct reyes_patch *pa)
{
	struct reyes_grid g;
	if (!reyes_patch_dice(pa, 2, 2, &g))
		return -1.0;
	double p0[3], p1[3], p2[3], p3[3], a[3], b[3], c[3];
	get3(g.P[0], 4, 0, p0);
	get3(g.P[0], 4, 1, p1);
	get3(g.P[0], 4, 2, p2);
	get3(g.P[0], 4, 3, p3);
	for (int i = 0; i < 3; i++)
		a[i] = p3[i] - p0[i], b[i] = p2[i] - p1[i];
	cross3(c, a, b);
	reyes_grid_finish(&g);
	return 0.5 * len3(c);
}

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

/* Uniform in [0, 1). */
static double rnd(void)
{
	rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
	return (double)(rng_state >> 11) / 9007199254740992.0;
}

/* Whether every point of g (both times) lies in the bound at that time. */
static bool grid_in_bound(const struct reyes_patch *pa, const struct reyes_grid *g)
{
	for (int t = 0; t < 2; t++) {
		float lo[3], hi[3];
		reyes_patch_bound(pa, t, lo, hi);
		for (uint32_t k = 0; k < g->n; k++)
			for (int c = 0; c < 3; c++) {
				float x = g->P[t][c * g->n + k];
				if (x < lo[c] || x > hi[c]) {
					fprintf(stderr, "point %u comp %d = %.9g outside [%.9g, %.9g]\n",
						k, c, x, lo[c], hi[c]);
					return false;
				}
			}
	}
	return true;
}

/*
 * dPdu and dPdv against central differences of P over a small sub-range
 * around (u, v) of piece @pa (tolerance relative to the derivative's size).
 */
static void check_derivatives(const struct reyes_patch *pa, double u, double v, double h,
			      double tol)
{
	struct reyes_patch sub = *pa;
	sub.u0 = (float)(u - h), sub.u1 = (float)(u + h);
	sub.v0 = (float)(v - h), sub.v1 = (float)(v + h);
	struct reyes_grid g;
	CHECK(reyes_patch_dice(&sub, 3, 3, &g));
	if (!g.n)
		return;
	/* The derivatives are with respect to the primitive's u, v: use the grid's own spacing. */
	double Pl[3], Pr[3], Pb[3], Pt[3], du[3], dv[3];
	get3(g.P[0], 9, 3, Pl);
	get3(g.P[0], 9, 5, Pr);
	get3(g.P[0], 9, 1, Pb);
	get3(g.P[0], 9, 7, Pt);
	get3(g.dPdu, 9, 4, du);
	get3(g.dPdv, 9, 4, dv);
	double su = 2.0 * g.du, sv = 2.0 * g.dv;
	double lu = len3(du), lv = len3(dv);
	for (int c = 0; c < 3; c++) {
		CHECK_NEAR((Pr[c] - Pl[c]) / su, du[c], tol * lu + 1e-6);
		CHECK_NEAR((Pt[c] - Pb[c]) / sv, dv[c], tol * lv + 1e-6);
	}
	reyes_grid_finish(&g);
}

static void test_sphere(void)
{
	struct tprim t;
	const double r = 2.0, zmin = -1.0, zmax = 1.5;
	quadric(&t, REYES_SPHERE, (float)r, (float)zmin, (float)zmax, 300.0f, 0, 0, 0);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	if (n != 1) {
		free(pa);
		return;
	}
	CHECK(pa[0].u0 == 0.0f && pa[0].u1 == 1.0f && pa[0].v0 == 0.0f && pa[0].v1 == 1.0f);
	struct reyes_grid g;
	CHECK(reyes_patch_dice(&pa[0], 9, 7, &g));
	CHECK(g.nu == 9 && g.nv == 7 && g.n == 63);
	CHECK(grid_finite(&g));
	CHECK(g.P[1] == g.P[0]);
	CHECK(!g.N && !g.s && !g.t && !g.Cs && !g.Os && g.nvars == 0);
	CHECK_NEAR(g.du, 1.0 / 8, 1e-7);
	CHECK_NEAR(g.dv, 1.0 / 6, 1e-7);
	double phimin = asin(zmin / r), phimax = asin(zmax / r), tmax = 300.0 * PI_D / 180.0;
	for (uint32_t k = 0; k < g.n; k++) {
		double P[3], Ng[3], du[3];
		get3(g.P[0], g.n, k, P);
		get3(g.Ng, g.n, k, Ng);
		get3(g.dPdu, g.n, k, du);
		/* |P| = r and zmin <= z <= zmax, within float rounding. */
		CHECK_NEAR(len3(P), r, 2e-6);
		CHECK(P[2] >= zmin - 1e-6 && P[2] <= zmax + 1e-6);
		/* Outward: Ng along P (Ng / |Ng| . P / r = 1). */
		CHECK_NEAR(dot3(Ng, P) / (len3(Ng) * r), 1.0, 1e-5);
		/* The RISpec parameterisation at the point's (u, v). */
		double th = g.u[k] * tmax, phi = phimin + g.v[k] * (phimax - phimin);
		CHECK_NEAR(P[0], r * cos(th) * cos(phi), 2e-6);
		CHECK_NEAR(P[1], r * sin(th) * cos(phi), 2e-6);
		CHECK_NEAR(P[2], r * sin(phi), 2e-6);
		/* dP/du = thetamax (-y, x, 0). */
		CHECK_NEAR(du[0], -tmax * P[1], 1e-5);
		CHECK_NEAR(du[1], tmax * P[0], 1e-5);
		CHECK_NEAR(du[2], 0.0, 1e-6);
	}
	CHECK_NEAR(g.u[0], 0.0, 0);
	CHECK_NEAR(g.u[8], 1.0, 0);
	CHECK_NEAR(g.v[62], 1.0, 0);
	reyes_grid_finish(&g);
	CHECK(g.P[0] == NULL && g.n == 0);
	reyes_grid_finish(&g);

	/* Finite differences, a few places. */
	check_derivatives(&pa[0], 0.3, 0.4, 1e-3, 2e-3);
	check_derivatives(&pa[0], 0.8, 0.9, 1e-3, 2e-3);

	/* Half the u range: u runs 0..0.5. */
	struct reyes_patch half = pa[0];
	half.u1 = 0.5f;
	CHECK(reyes_patch_dice(&half, 5, 3, &g));
	CHECK_NEAR(g.u[0], 0.0, 0);
	CHECK_NEAR(g.u[4], 0.5, 1e-7);
	CHECK_NEAR(g.du, 0.125, 1e-7);
	reyes_grid_finish(&g);

	/* Flipped orientation: Ng inward. */
	t.attrs.flip_normals = true;
	CHECK(reyes_patch_dice(&pa[0], 6, 6, &g));
	for (uint32_t k = 0; k < g.n; k++) {
		double P[3], Ng[3];
		get3(g.P[0], g.n, k, P);
		get3(g.Ng, g.n, k, Ng);
		CHECK_NEAR(dot3(Ng, P) / (len3(Ng) * r), -1.0, 1e-5);
	}
	reyes_grid_finish(&g);
	free(pa);
}

/* A full sphere: the poles give the limit normal, not NaN or zero. */
static void test_sphere_poles(void)
{
	struct tprim t;
	quadric(&t, REYES_SPHERE, 1.0f, -1.0f, 1.0f, 360.0f, 0, 0, 0);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	struct reyes_grid g;
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 8, 5, &g));
	if (g.n) {
		CHECK(grid_finite(&g));
		for (uint32_t k = 0; k < g.n; k++) {
			double P[3], Ng[3];
			get3(g.P[0], g.n, k, P);
			get3(g.Ng, g.n, k, Ng);
			CHECK(len3(Ng) > 0.0);
			CHECK_NEAR(dot3(Ng, P) / len3(Ng), 1.0, 1e-5);
		}
		/* South pole row (v = 0) and north pole row (v = 1). */
		double s[3], no[3];
		get3(g.Ng, g.n, 3, s);
		get3(g.Ng, g.n, g.n - 3, no);
		CHECK_NEAR(s[2] / len3(s), -1.0, 1e-6);
		CHECK_NEAR(no[2] / len3(no), 1.0, 1e-6);
		reyes_grid_finish(&g);
	}
	free(pa);
}

/* Check the implicit equation of a quadric's surface at every diced point. */
typedef double (*implicit_fn)(const double P[3], const float *q);

static double f_cylinder(const double P[3], const float *q)
{
	return hypot(P[0], P[1]) - fabs(q[0]);
}

static double f_cone(const double P[3], const float *q)
{
	/* Cone height radius: rho = radius (1 - z / height). */
	return hypot(P[0], P[1]) - q[1] * (1.0 - P[2] / q[0]);
}

static double f_disk(const double P[3], const float *q)
{
	return P[2] - q[0] + (hypot(P[0], P[1]) > fabs(q[1]) + 1e-6 ? 1.0 : 0.0);
}

static double f_paraboloid(const double P[3], const float *q)
{
	/* rho^2 = rmax^2 z / zmax */
	return (P[0] * P[0] + P[1] * P[1]) - q[0] * q[0] * P[2] / q[2];
}

static double f_torus(const double P[3], const float *q)
{
	double a = hypot(P[0], P[1]) - q[0];
	return sqrt(a * a + P[2] * P[2]) - fabs(q[1]);
}

static double f_hyperboloid(const double P[3], const float *q)
{
	/* The line at height z (z1 != z2): rho^2 = |xy of the line at that z|^2. */
	double v = (P[2] - q[2]) / (q[5] - q[2]);
	double x = (1 - v) * q[0] + v * q[3], y = (1 - v) * q[1] + v * q[4];
	return (P[0] * P[0] + P[1] * P[1]) - (x * x + y * y);
}

static double f_sphere(const double P[3], const float *q)
{
	return len3(P) - fabs(q[0]);
}

struct quadric_case {
	const char *name;
	enum reyes_prim_kind kind;
	float q[7];
	implicit_fn f;
	double zlo, zhi;     /* z range of the surface */
};

static const struct quadric_case quadric_cases[] = {
	{ "sphere", REYES_SPHERE, { 1.5f, -0.5f, 1.0f, 270.0f }, f_sphere, -0.5, 1.0 },
	{ "sphere-neg", REYES_SPHERE, { 1.0f, -2.0f, 2.0f, -120.0f }, f_sphere, -1.0, 1.0 },
	{ "cylinder", REYES_CYLINDER, { 0.7f, -0.2f, 1.3f, 200.0f }, f_cylinder, -0.2, 1.3 },
	{ "cone", REYES_CONE, { 2.0f, 0.8f, 330.0f }, f_cone, 0.0, 2.0 },
	{ "disk", REYES_DISK, { 0.4f, 1.2f, 360.0f }, f_disk, 0.4, 0.4 },
	{ "paraboloid", REYES_PARABOLOID, { 1.0f, 0.0f, 2.0f, 300.0f }, f_paraboloid, 0.0, 2.0 },
	{ "paraboloid2", REYES_PARABOLOID, { 0.5f, 0.5f, 1.5f, 90.0f }, f_paraboloid, 0.5, 1.5 },
	{ "torus", REYES_TORUS, { 2.0f, 0.5f, -30.0f, 250.0f, 300.0f }, f_torus, -0.5, 0.5 },
	{ "hyperboloid", REYES_HYPERBOLOID, { 1.0f, 0.0f, -1.0f, 0.0f, 1.0f, 1.0f, 360.0f },
	  f_hyperboloid, -1.0, 1.0 },
	{ "hyperboloid-axis", REYES_HYPERBOLOID, { -1.0f, 0.0f, -1.0f, 1.0f, 0.5f, 1.0f, 180.0f },
	  f_hyperboloid, -1.0, 1.0 },
};

static void test_quadric_surfaces(void)
{
	for (size_t c = 0; c < sizeof(quadric_cases) / sizeof(quadric_cases[0]); c++) {
		const struct quadric_case *qc = &quadric_cases[c];
		struct tprim t;
		quadric(&t, qc->kind, qc->q[0], qc->q[1], qc->q[2], qc->q[3], qc->q[4], qc->q[5],
			qc->q[6]);
		size_t n;
		struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
		CHECK(n == 1);
		if (n != 1) {
			fprintf(stderr, "  (%s)\n", qc->name);
			free(pa);
			continue;
		}
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[0], 11, 9, &g));
		CHECK(grid_finite(&g));
		int bad = 0;
		for (uint32_t k = 0; k < g.n; k++) {
			double P[3], Ng[3];
			get3(g.P[0], g.n, k, P);
			get3(g.Ng, g.n, k, Ng);
			if (fabs(qc->f(P, qc->q)) > 1e-5 || P[2] < qc->zlo - 1e-6 ||
			    P[2] > qc->zhi + 1e-6 || !(len3(Ng) > 0.0))
				bad++;
		}
		CHECK(bad == 0);
		if (bad)
			fprintf(stderr, "  (%s: %d points off the surface)\n", qc->name, bad);
		reyes_grid_finish(&g);
		/* Derivatives away from the axis. */
		check_derivatives(&pa[0], 0.37, 0.55, 1e-3, 3e-3);
		free(pa);
	}
}

/* Outward normals of the other quadrics (RISpec: Ng points away from the z axis). */
static void test_quadric_orientation(void)
{
	struct tprim t;
	size_t n;
	struct reyes_grid g;
	struct reyes_patch *pa;

	/* Cylinder and cone: Ng . (x, y, 0) > 0. */
	const enum reyes_prim_kind kinds[2] = { REYES_CYLINDER, REYES_CONE };
	const float qs[2][4] = { { 1.0f, 0.0f, 1.0f, 360.0f }, { 1.0f, 1.0f, 360.0f, 0 } };
	for (int i = 0; i < 2; i++) {
		quadric(&t, kinds[i], qs[i][0], qs[i][1], qs[i][2], qs[i][3], 0, 0, 0);
		pa = pieces(&t.prim, &n, NULL);
		CHECK(n == 1 && reyes_patch_dice(&pa[0], 6, 6, &g));
		for (uint32_t k = 0; g.n && k < g.n; k++) {
			double P[3], Ng[3];
			get3(g.P[0], g.n, k, P);
			get3(g.Ng, g.n, k, Ng);
			double rho = hypot(P[0], P[1]);
			if (rho > 1e-6)
				CHECK(Ng[0] * P[0] + Ng[1] * P[1] > 0.0);
			CHECK(len3(Ng) > 0.0);
			if (kinds[i] == REYES_CONE && rho <= 1e-6) {
				/* Apex: the limit normal of the generator through it. */
				double th = g.u[k] * 2.0 * PI_D;
				CHECK_NEAR((Ng[0] * cos(th) + Ng[1] * sin(th)) / len3(Ng),
					   1.0 / sqrt(2.0), 1e-5);
				CHECK_NEAR(Ng[2] / len3(Ng), 1.0 / sqrt(2.0), 1e-5);
			}
		}
		reyes_grid_finish(&g);
		free(pa);
	}

	/* Disk: +z for positive thetamax, including the centre; -z for negative. */
	for (int sgn = -1; sgn <= 1; sgn += 2) {
		quadric(&t, REYES_DISK, 0.5f, 1.0f, sgn * 300.0f, 0, 0, 0, 0);
		pa = pieces(&t.prim, &n, NULL);
		CHECK(n == 1 && reyes_patch_dice(&pa[0], 5, 5, &g));
		for (uint32_t k = 0; g.n && k < g.n; k++)
			CHECK_NEAR(g.Ng[2 * g.n + k] / sqrt(g.Ng[k] * g.Ng[k] +
							     g.Ng[g.n + k] * g.Ng[g.n + k] +
							     g.Ng[2 * g.n + k] * g.Ng[2 * g.n + k]),
				   sgn, 1e-6);
		/* Negative thetamax sweeps clockwise: y <= 0 near u = small. */
		if (g.n)
			CHECK(sgn * g.P[0][g.n + 1] > 0.0);
		reyes_grid_finish(&g);
		free(pa);
	}

	/* Torus: Ng along P - (tube centre). */
	quadric(&t, REYES_TORUS, 1.0f, 0.25f, 0.0f, 360.0f, 360.0f, 0, 0);
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 7, 7, &g));
	for (uint32_t k = 0; g.n && k < g.n; k++) {
		double P[3], Ng[3];
		get3(g.P[0], g.n, k, P);
		get3(g.Ng, g.n, k, Ng);
		double rho = hypot(P[0], P[1]);
		double c[3] = { P[0] / rho, P[1] / rho, 0.0 };
		double d[3] = { P[0] - c[0], P[1] - c[1], P[2] };
		CHECK_NEAR(dot3(Ng, d) / (len3(Ng) * len3(d)), 1.0, 1e-5);
	}
	reyes_grid_finish(&g);
	free(pa);

	/* Paraboloid: the apex gets the limit normal -z, finite. */
	quadric(&t, REYES_PARABOLOID, 1.0f, 0.0f, 1.0f, 360.0f, 0, 0, 0);
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 5, 5, &g));
	if (g.n) {
		CHECK(grid_finite(&g));
		double Ng[3];
		get3(g.Ng, g.n, 2, Ng);
		CHECK(Ng[2] / len3(Ng) < -0.999);
		/* Away from the apex: outward and down (-z), along (2x, 2y, -1) scaled. */
		double P[3];
		get3(g.P[0], g.n, 3 * 5 + 1, P);
		get3(g.Ng, g.n, 3 * 5 + 1, Ng);
		double e[3] = { 2.0 * P[0], 2.0 * P[1], -1.0 };
		CHECK_NEAR(dot3(Ng, e) / (len3(Ng) * len3(e)), 1.0, 1e-5);
	}
	reyes_grid_finish(&g);
	free(pa);
}

/* Bounds contain every diced point, over random sub-ranges of every quadric. */
static void test_quadric_bounds(void)
{
	int misses = 0, tries = 0;
	for (size_t c = 0; c < sizeof(quadric_cases) / sizeof(quadric_cases[0]); c++) {
		const struct quadric_case *qc = &quadric_cases[c];
		struct tprim t;
		quadric(&t, qc->kind, qc->q[0], qc->q[1], qc->q[2], qc->q[3], qc->q[4], qc->q[5],
			qc->q[6]);
		size_t n;
		struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
		for (int i = 0; n == 1 && i < 200; i++) {
			struct reyes_patch sub = pa[0];
			double a = rnd(), b = rnd(), cc = rnd(), d = rnd();
			if (i == 0)
				a = 0, b = 1, cc = 0, d = 1;
			sub.u0 = (float)fmin(a, b), sub.u1 = (float)fmax(a, b);
			sub.v0 = (float)fmin(cc, d), sub.v1 = (float)fmax(cc, d);
			struct reyes_grid g;
			if (!reyes_patch_dice(&sub, 9, 9, &g)) {
				misses++;
				continue;
			}
			tries++;
			if (!grid_in_bound(&sub, &g)) {
				misses++;
				fprintf(stderr, "  (%s u %g..%g v %g..%g)\n", qc->name, sub.u0, sub.u1,
					sub.v0, sub.v1);
			}
			reyes_grid_finish(&g);
		}
		/* A full-range bound is not much bigger than the surface. */
		float lo[3], hi[3];
		if (n == 1) {
			reyes_patch_bound(&pa[0], 0, lo, hi);
			CHECK(lo[2] >= qc->zlo - 1e-4 && hi[2] <= qc->zhi + 1e-4);
		}
		free(pa);
	}
	CHECK(misses == 0);
	CHECK(tries == 2000);

	/* Tight for a sphere octant: [0, r] in x and y, [0, r] in z. */
	struct tprim t;
	quadric(&t, REYES_SPHERE, 1.0f, 0.0f, 1.0f, 90.0f, 0, 0, 0);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	float lo[3], hi[3];
	reyes_patch_bound(&pa[0], 0, lo, hi);
	for (int c = 0; c < 3; c++) {
		CHECK_NEAR(lo[c], 0.0, 1e-5);
		CHECK_NEAR(hi[c], 1.0, 1e-5);
	}
	free(pa);
}

/* Degenerate quadrics give no piece; near-degenerate ones dice without NaN. */
static void test_quadric_degenerate(void)
{
	struct tprim t;
	size_t n;
	struct reyes_patch *pa;
	bool ok;
	const struct { enum reyes_prim_kind kind; float q[7]; } none[] = {
		{ REYES_SPHERE, { 0.0f, -1.0f, 1.0f, 360.0f } },
		{ REYES_SPHERE, { 1.0f, -1.0f, 1.0f, 0.0f } },
		{ REYES_SPHERE, { 1.0f, 0.5f, 0.5f, 360.0f } },
		{ REYES_SPHERE, { 1.0f, 2.0f, 3.0f, 360.0f } },
		{ REYES_SPHERE, { NAN, -1.0f, 1.0f, 360.0f } },
		{ REYES_CYLINDER, { 0.0f, 0.0f, 1.0f, 360.0f } },
		{ REYES_CYLINDER, { 1.0f, 1.0f, 1.0f, 360.0f } },
		{ REYES_CONE, { 1.0f, 0.0f, 360.0f } },
		{ REYES_DISK, { 1.0f, 0.0f, 360.0f } },
		{ REYES_DISK, { 1.0f, 1.0f, 0.0f } },
		{ REYES_PARABOLOID, { 1.0f, 0.0f, 0.0f, 360.0f } },
		{ REYES_PARABOLOID, { 0.0f, 0.0f, 1.0f, 360.0f } },
		{ REYES_TORUS, { 1.0f, 0.0f, 0.0f, 360.0f, 360.0f } },
		{ REYES_TORUS, { 1.0f, 0.5f, 90.0f, 90.0f, 360.0f } },
		{ REYES_HYPERBOLOID, { 1, 0, 0, 1, 0, 0, 360.0f } },
		{ REYES_HYPERBOLOID, { 0, 0, 0, 0, 0, 1, 360.0f } },
		{ REYES_HYPERBOLOID, { 1, 0, 0, 1, 1, 1, INFINITY } },
	};
	for (size_t i = 0; i < sizeof(none) / sizeof(none[0]); i++) {
		quadric(&t, none[i].kind, none[i].q[0], none[i].q[1], none[i].q[2], none[i].q[3],
			none[i].q[4], none[i].q[5], none[i].q[6]);
		pa = pieces(&t.prim, &n, &ok);
		CHECK(ok && n == 0);
		/* Dicing a piece of it anyway fails cleanly. */
		struct reyes_patch fake = { .prim = &t.prim, .u1 = 1.0f, .v1 = 1.0f };
		struct reyes_grid g;
		CHECK(!reyes_patch_dice(&fake, 4, 4, &g));
		CHECK(g.P[0] == NULL);
		float lo[3], hi[3];
		reyes_patch_bound(&fake, 0, lo, hi);
		CHECK(isfinite(lo[0]) && isfinite(hi[0]));
		free(pa);
	}
	/* Cone of height 0 (a disk), tiny radius, torus crossing the axis: all finite. */
	const struct { enum reyes_prim_kind kind; float q[7]; } odd[] = {
		{ REYES_CONE, { 0.0f, 1.0f, 360.0f } },
		{ REYES_SPHERE, { 1e-20f, -1.0f, 1.0f, 360.0f } },
		{ REYES_TORUS, { 0.5f, 1.0f, 0.0f, 360.0f, 360.0f } },
		{ REYES_PARABOLOID, { 1.0f, -1.0f, 1.0f, 360.0f } },
		{ REYES_SPHERE, { 1.0f, -1.0f, 1.0f, 1e30f } },
	};
	for (size_t i = 0; i < sizeof(odd) / sizeof(odd[0]); i++) {
		quadric(&t, odd[i].kind, odd[i].q[0], odd[i].q[1], odd[i].q[2], odd[i].q[3],
			odd[i].q[4], odd[i].q[5], odd[i].q[6]);
		pa = pieces(&t.prim, &n, &ok);
		CHECK(ok && n == 1);
		struct reyes_grid g;
		if (n == 1) {
			CHECK(reyes_patch_dice(&pa[0], 9, 9, &g));
			CHECK(grid_finite(&g));
			CHECK(grid_in_bound(&pa[0], &g));
			reyes_grid_finish(&g);
		}
		free(pa);
	}
}

static void test_split(void)
{
	struct tprim t;
	quadric(&t, REYES_TORUS, 1.0f, 0.3f, 0.0f, 360.0f, 270.0f, 0, 0);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	struct reyes_patch h[2], q[2];
	reyes_patch_split(&pa[0], true, h);
	CHECK(h[0].u0 == 0.0f && h[0].u1 == 0.5f && h[1].u0 == 0.5f && h[1].u1 == 1.0f);
	CHECK(h[0].v0 == 0.0f && h[0].v1 == 1.0f && h[1].v0 == 0.0f && h[1].v1 == 1.0f);
	CHECK(h[0].depth == 1 && h[1].depth == 1 && h[0].prim == &t.prim && h[1].piece == 0);
	reyes_patch_split(&h[1], false, q);
	CHECK(q[0].u0 == 0.5f && q[0].u1 == 1.0f && q[0].v0 == 0.0f && q[0].v1 == 0.5f);
	CHECK(q[1].v0 == 0.5f && q[1].v1 == 1.0f && q[1].depth == 2);

	/* The halves meet: last column of the left = first column of the right. */
	struct reyes_grid a, b, whole;
	CHECK(reyes_patch_dice(&h[0], 5, 5, &a));
	CHECK(reyes_patch_dice(&h[1], 5, 5, &b));
	CHECK(reyes_patch_dice(&pa[0], 9, 5, &whole));
	for (uint32_t j = 0; a.n && b.n && whole.n && j < 5; j++)
		for (int c = 0; c < 3; c++) {
			CHECK(a.P[0][c * 25 + j * 5 + 4] == b.P[0][c * 25 + j * 5]);
			CHECK_NEAR(a.P[0][c * 25 + j * 5 + 2], whole.P[0][c * 45 + j * 9 + 2], 1e-6);
			CHECK_NEAR(b.P[0][c * 25 + j * 5 + 4], whole.P[0][c * 45 + j * 9 + 8], 1e-6);
		}
	if (a.n && b.n) {
		CHECK_NEAR(a.u[4], 0.5, 0);
		CHECK_NEAR(b.u[0], 0.5, 0);
		CHECK_NEAR(b.u[4], 1.0, 0);
	}
	reyes_grid_finish(&a);
	reyes_grid_finish(&b);
	reyes_grid_finish(&whole);
	free(pa);
}

/* ---- polygons ---- */

/* One face (outline + holes) in the xy plane; points flat as x y pairs. */
struct poly {
	struct tprim t;
	float P[3 * 64];
	uint32_t nloops[4], nverts[8], verts[64];
};

static void poly_init(struct poly *p, const float *xy, uint32_t npts, const uint32_t *loops,
		      uint32_t nloops)
{
	tprim_init(&p->t, REYES_POLYGONS);
	for (uint32_t i = 0; i < npts; i++) {
		p->P[3 * i] = xy[2 * i];
		p->P[3 * i + 1] = xy[2 * i + 1];
		p->P[3 * i + 2] = 0.0f;
	}
	p->t.prim.npoints = npts;
	p->t.prim.nfaces = 1;
	p->nloops[0] = nloops;
	uint32_t k = 0;
	for (uint32_t l = 0; l < nloops; l++) {
		p->nverts[l] = loops[l];
		for (uint32_t i = 0; i < loops[l]; i++, k++)
			p->verts[k] = k;
	}
	p->t.prim.nloops = p->nloops;
	p->t.prim.nverts = p->nverts;
	p->t.prim.verts = p->verts;
	add_var(&p->t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, npts, p->P);
}

/*
 * Total area of a polygon's pieces; every piece's Ng must be along +z and
 * every diced point pass @inside (NULL: no check).
 */
static double poly_area(const struct reyes_prim *prim, bool (*inside)(double x, double y),
			size_t *npieces)
{
	size_t n;
	bool ok;
	struct reyes_patch *pa = pieces(prim, &n, &ok);
	CHECK(ok);
	*npieces = n;
	double area = 0.0;
	for (size_t i = 0; i < n; i++) {
		area += piece_area(&pa[i]);
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[i], 4, 4, &g));
		if (!g.n)
			continue;
		CHECK(grid_finite(&g));
		for (uint32_t k = 0; k < g.n; k++) {
			double Ng[3];
			get3(g.Ng, g.n, k, Ng);
			CHECK(Ng[2] > 0.0 && fabs(Ng[0]) + fabs(Ng[1]) <= 1e-6 * Ng[2]);
			if (inside)
				CHECK(inside(g.P[0][k], g.P[0][g.n + k]));
		}
		CHECK(grid_in_bound(&pa[i], &g));
		reyes_grid_finish(&g);
	}
	free(pa);
	return area;
}

static bool in_L(double x, double y)
{
	const double e = 1e-6;
	return x >= -e && y >= -e && ((x <= 2 + e && y <= 1 + e) || (x <= 1 + e && y <= 2 + e));
}

static bool in_holed(double x, double y)
{
	const double e = 1e-6;
	bool in_outer = x >= -e && x <= 4 + e && y >= -e && y <= 4 + e;
	bool in_hole = x > 1 + e && x < 3 - e && y > 1 + e && y < 3 - e;
	return in_outer && !in_hole;
}

static void test_polygons(void)
{
	struct poly p;
	size_t np;

	/* A convex quad stays one piece: P00 P10 P11 P01 = v0 v1 v2 v3. */
	const float sq[] = { 0, 0, 2, 0, 2, 1, 0, 1 };
	uint32_t l4 = 4;
	poly_init(&p, sq, 4, &l4, 1);
	CHECK_NEAR(poly_area(&p.t.prim, NULL, &np), 2.0, 1e-6);
	CHECK(np == 1);
	size_t n;
	struct reyes_patch *pa = pieces(&p.t.prim, &n, NULL);
	struct reyes_grid g;
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 2, 2, &g));
	if (g.n) {
		const float want[4][2] = { { 0, 0 }, { 2, 0 }, { 0, 1 }, { 2, 1 } };
		for (int k = 0; k < 4; k++) {
			CHECK(g.P[0][k] == want[k][0] && g.P[0][4 + k] == want[k][1]);
		}
		/* u, v: the piece's own parameters. */
		CHECK(g.u[0] == 0.0f && g.u[3] == 1.0f && g.v[3] == 1.0f);
		double du[3];
		get3(g.dPdu, 4, 0, du);
		CHECK_NEAR(du[0], 2.0, 1e-6);
		reyes_grid_finish(&g);
	}
	free(pa);

	/* A triangle: three pieces, area exact, derivatives nowhere zero. */
	const float tri[] = { 0, 0, 3, 0, 0, 2 };
	uint32_t l3 = 3;
	poly_init(&p, tri, 3, &l3, 1);
	CHECK_NEAR(poly_area(&p.t.prim, NULL, &np), 3.0, 1e-6);
	CHECK(np == 3);
	pa = pieces(&p.t.prim, &n, NULL);
	for (size_t i = 0; i < n; i++) {
		CHECK(reyes_patch_dice(&pa[i], 5, 5, &g));
		for (uint32_t k = 0; g.n && k < g.n; k++) {
			double du[3], dv[3], Ng[3];
			get3(g.dPdu, g.n, k, du);
			get3(g.dPdv, g.n, k, dv);
			get3(g.Ng, g.n, k, Ng);
			CHECK(len3(du) > 0.1 && len3(dv) > 0.1);
			CHECK(Ng[2] > 0.0);
		}
		check_derivatives(&pa[i], 0.5, 0.5, 1e-2, 1e-4);
		reyes_grid_finish(&g);
	}
	free(pa);

	/* A concave L: exact area, every point inside. */
	const float L[] = { 0, 0, 2, 0, 2, 1, 1, 1, 1, 2, 0, 2 };
	uint32_t l6 = 6;
	poly_init(&p, L, 6, &l6, 1);
	CHECK_NEAR(poly_area(&p.t.prim, in_L, &np), 3.0, 1e-6);
	CHECK(np == 12);
	/* The same L wound clockwise: Ng follows the winding (-z), area the same. */
	const float Lcw[] = { 0, 0, 0, 2, 1, 2, 1, 1, 2, 1, 2, 0 };
	poly_init(&p, Lcw, 6, &l6, 1);
	pa = pieces(&p.t.prim, &n, NULL);
	double area = 0.0;
	for (size_t i = 0; i < n; i++) {
		area += piece_area(&pa[i]);
		CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
		for (uint32_t k = 0; g.n && k < g.n; k++)
			CHECK(g.Ng[2 * g.n + k] < 0.0);
		reyes_grid_finish(&g);
	}
	CHECK_NEAR(area, 3.0, 1e-6);
	free(pa);

	/* A square with a square hole (given with the outline's winding, and reversed). */
	const float holed[] = { 0, 0, 4, 0, 4, 4, 0, 4, 1, 1, 3, 1, 3, 3, 1, 3 };
	const float holed_cw[] = { 0, 0, 4, 0, 4, 4, 0, 4, 1, 1, 1, 3, 3, 3, 3, 1 };
	uint32_t loops[2] = { 4, 4 };
	poly_init(&p, holed, 8, loops, 2);
	CHECK_NEAR(poly_area(&p.t.prim, in_holed, &np), 12.0, 1e-5);
	poly_init(&p, holed_cw, 8, loops, 2);
	CHECK_NEAR(poly_area(&p.t.prim, in_holed, &np), 12.0, 1e-5);

	/* Two holes and a comb-shaped outline. */
	const float comb[] = { 0, 0, 7, 0, 7, 3, 6, 3, 6, 1, 5, 1, 5, 3, 4, 3, 4, 1, 3, 1, 3, 3,
			       2, 3, 2, 1, 1, 1, 1, 3, 0, 3 };
	uint32_t l16 = 16;
	poly_init(&p, comb, 16, &l16, 1);
	CHECK_NEAR(poly_area(&p.t.prim, NULL, &np), 7.0 + 4 * 2.0, 1e-5);
	const float two[] = { 0, 0, 10, 0, 10, 4, 0, 4, 1, 1, 3, 1, 3, 3, 1, 3,
			      6, 1, 9, 1, 9, 2, 6, 2 };
	uint32_t loops3[3] = { 4, 4, 4 };
	poly_init(&p, two, 12, loops3, 3);
	CHECK_NEAR(poly_area(&p.t.prim, NULL, &np), 40.0 - 4.0 - 3.0, 1e-5);
}

/* A tilted (non-axis) planar polygon triangulates in its own plane. */
static void test_polygon_tilted(void)
{
	struct poly p;
	const float L[] = { 0, 0, 2, 0, 2, 1, 1, 1, 1, 2, 0, 2 };
	uint32_t l6 = 6;
	poly_init(&p, L, 6, &l6, 1);
	/* Rotate the plane: (x, y, 0) -> (x, y cos a, y sin a) about x, then about z. */
	double a = 0.7, b = 1.1;
	for (int i = 0; i < 6; i++) {
		double x = p.P[3 * i], y = p.P[3 * i + 1];
		double y1 = y * cos(a), z1 = y * sin(a);
		p.P[3 * i] = (float)(x * cos(b) - y1 * sin(b));
		p.P[3 * i + 1] = (float)(x * sin(b) + y1 * cos(b));
		p.P[3 * i + 2] = (float)z1;
	}
	size_t n;
	struct reyes_patch *pa = pieces(&p.t.prim, &n, NULL);
	double area = 0.0, nz[3] = { 0, -sin(a), cos(a) }, nrm[3];
	nrm[0] = nz[0] * cos(b) - nz[1] * sin(b);
	nrm[1] = nz[0] * sin(b) + nz[1] * cos(b);
	nrm[2] = nz[2];
	for (size_t i = 0; i < n; i++) {
		area += piece_area(&pa[i]);
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
		for (uint32_t k = 0; g.n && k < g.n; k++) {
			double Ng[3];
			get3(g.Ng, g.n, k, Ng);
			CHECK_NEAR(dot3(Ng, nrm) / len3(Ng), 1.0, 1e-5);
		}
		reyes_grid_finish(&g);
	}
	CHECK_NEAR(area, 3.0, 1e-5);
	free(pa);
}

/* Two faces: a quad and a triangle, with uniform, facevarying, vertex and user data. */
static void test_polygon_primvars(void)
{
	struct tprim t;
	tprim_init(&t, REYES_POLYGONS);
	const float P[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0.5f, 0 };
	uint32_t nloops[2] = { 1, 1 }, nverts[2] = { 4, 3 }, verts[7] = { 0, 1, 2, 3, 1, 4, 2 };
	t.prim.nfaces = 2;
	t.prim.npoints = 5;
	t.prim.nloops = nloops;
	t.prim.nverts = nverts;
	t.prim.verts = verts;
	add_var(&t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, 5, P);
	const float Cs[] = { 1, 0, 0, 0, 1, 0 };
	add_var(&t, "Cs", REYES_UNIFORM, SL_TYPE_COLOR, 0, 2, Cs);
	/* st per face corner, in loop order: corner c gets (c, 10 c). */
	float st[14];
	for (int c = 0; c < 7; c++)
		st[2 * c] = (float)c, st[2 * c + 1] = 10.0f * c;
	add_var(&t, "st", REYES_FACEVARYING, SL_TYPE_FLOAT, 2, 7, st);
	const float temp[] = { 0, 100, 200, 300, 400 };
	add_var(&t, "temperature", REYES_VERTEX, SL_TYPE_FLOAT, 0, 5, temp);
	const float N[] = { 0, 0, 2, 0, 0, 2, 0, 0, 2, 0, 0, 2, 0, 1, 1 };
	add_var(&t, "N", REYES_VERTEX, SL_TYPE_NORMAL, 0, 5, N);
	const float Os[] = { 0.5f, 0.5f, 0.5f };
	add_var(&t, "Os", REYES_CONSTANT, SL_TYPE_COLOR, 0, 1, Os);
	const char *const names[] = { "a" };
	struct reyes_primvar *sv = add_var(&t, "label", REYES_CONSTANT, SL_TYPE_STRING, 0, 1, NULL);
	(void)names;
	(void)sv;

	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 4);
	if (n != 4) {
		free(pa);
		return;
	}
	struct reyes_grid g;
	/* The quad: face 0. */
	CHECK(reyes_patch_dice(&pa[0], 2, 2, &g));
	if (g.n) {
		CHECK(grid_finite(&g));
		CHECK(g.Cs && g.Cs[0] == 1.0f && g.Cs[4] == 0.0f && g.Cs[8] == 0.0f);
		CHECK(g.Os && g.Os[3] == 0.5f);
		/* Corners (0,0) (1,0) (0,1) (1,1) = loop corners 0, 1, 3, 2. */
		CHECK(g.s && g.t);
		if (g.s && g.t) {
			CHECK(g.s[0] == 0.0f && g.s[1] == 1.0f && g.s[2] == 3.0f && g.s[3] == 2.0f);
			CHECK(g.t[0] == 0.0f && g.t[1] == 10.0f && g.t[2] == 30.0f && g.t[3] == 20.0f);
		}
		CHECK(g.nvars == 1);
		if (g.nvars == 1) {
			CHECK_STR(g.vars[0].name, "temperature");
			CHECK(g.vars[0].data[1] == 100.0f && g.vars[0].data[2] == 300.0f);
		}
		CHECK(g.N && g.N[2 * 4] == 1.0f);
		reyes_grid_finish(&g);
	}
	/* The triangle's thirds: face 1. */
	for (size_t i = 1; i < 4; i++) {
		CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
		if (!g.n)
			continue;
		CHECK(grid_finite(&g));
		CHECK(g.Cs && g.Cs[4] == 0.0f && g.Cs[9 + 4] == 1.0f);
		/* Corner (0,0) is one of the triangle's corners 4, 5, 6; (1,1) the centroid. */
		CHECK(g.s && (g.s[0] == 4.0f || g.s[0] == 5.0f || g.s[0] == 6.0f));
		CHECK(g.s && fabs(g.s[8] - 5.0f) < 1e-5 && fabs(g.t[8] - 50.0f) < 1e-4);
		/* The shading normal is unit length. */
		for (uint32_t k = 0; g.N && k < g.n; k++) {
			double v[3];
			get3(g.N, g.n, k, v);
			CHECK_NEAR(len3(v), 1.0, 1e-6);
		}
		/* Vertex temperature matches P: T = 100 * vertex, so at a point the value is linear. */
		reyes_grid_finish(&g);
	}
	/* Which corner starts each third: 4, 5 and 6, once each. */
	int seen = 0;
	for (size_t i = 1; i < 4; i++)
		if (reyes_patch_dice(&pa[i], 2, 2, &g)) {
			if (g.s)
				seen |= 1 << (int)(g.s[0] - 4.0f);
			reyes_grid_finish(&g);
		}
	CHECK(seen == 7);
	free(pa);

	/* Deforming motion: P[1] from values1, inside the t = 1 bound. */
	float P1[15];
	for (int i = 0; i < 15; i++)
		P1[i] = P[i] + (i % 3 == 2 ? 1.0f : 0.0f);
	t.vars[0].values1 = P1;
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 4 && reyes_patch_dice(&pa[0], 3, 3, &g));
	if (g.n) {
		CHECK(g.P[1] != g.P[0]);
		CHECK(g.P[1][2 * 9 + 4] == 1.0f && g.P[0][2 * 9 + 4] == 0.0f);
		CHECK(grid_in_bound(&pa[0], &g));
		float lo[3], hi[3];
		reyes_patch_bound(&pa[0], 1, lo, hi);
		CHECK(lo[2] > 0.99f && hi[2] < 1.01f);
		reyes_grid_finish(&g);
	}
	free(pa);
}

static void test_polygon_degenerate(void)
{
	struct poly p;
	size_t n, np;
	bool ok;
	/* Coincident points: a square with doubled corners and a repeated closing point. */
	const float dup[] = { 0, 0, 0, 0, 1, 0, 1, 1, 1, 1, 0, 1, 0, 0 };
	uint32_t l7 = 7;
	poly_init(&p, dup, 7, &l7, 1);
	CHECK_NEAR(poly_area(&p.t.prim, NULL, &np), 1.0, 1e-6);
	CHECK(np == 1);
	/* All one point; collinear points; two points: no pieces, no error. */
	const float same[] = { 1, 1, 1, 1, 1, 1, 1, 1 };
	uint32_t l4 = 4;
	poly_init(&p, same, 4, &l4, 1);
	struct reyes_patch *pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok && n == 0);
	free(pa);
	const float line[] = { 0, 0, 1, 1, 2, 2, 3, 3 };
	poly_init(&p, line, 4, &l4, 1);
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok && n == 0);
	free(pa);
	uint32_t l2 = 2;
	poly_init(&p, line, 2, &l2, 1);
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok && n == 0);
	free(pa);
	/* A self-intersecting bow tie and a spike: finite pieces, no hang. */
	const float bow[] = { 0, 0, 2, 2, 2, 0, 0, 2, 1, 5, 1, 5, 1, -3 };
	uint32_t l7b = 7;
	poly_init(&p, bow, 7, &l7b, 1);
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok);
	for (size_t i = 0; i < n; i++) {
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
		CHECK(grid_finite(&g));
		reyes_grid_finish(&g);
	}
	free(pa);
	/* A hole outside the outline and a degenerate hole. */
	const float outside[] = { 0, 0, 1, 0, 1, 1, 0, 1, 5, 5, 6, 5, 6, 6, 5, 6, 0.5f, 0.5f,
				  0.5f, 0.5f, 0.5f, 0.5f };
	uint32_t loops[3] = { 4, 4, 3 };
	poly_init(&p, outside, 11, loops, 3);
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok && n > 0);
	for (size_t i = 0; i < n; i++) {
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
		CHECK(grid_finite(&g));
		reyes_grid_finish(&g);
	}
	free(pa);
	/* A vertex index out of range is an error. */
	rl_log_set_level(RL_LOG_SILENT);
	const float sq[] = { 0, 0, 1, 0, 1, 1, 0, 1 };
	poly_init(&p, sq, 4, &l4, 1);
	p.verts[2] = 9;
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(!ok && n == 0);
	free(pa);
	rl_log_set_level(RL_LOG_WARN);
	/* A non-planar quad is triangulated rather than kept bilinear. */
	poly_init(&p, sq, 4, &l4, 1);
	p.P[3 * 2 + 2] = 0.5f;
	pa = pieces(&p.t.prim, &n, &ok);
	CHECK(ok && n == 6);
	free(pa);
}

/* A large mesh: pieces, then every piece diced, in time linear in the mesh. */
static void test_polygon_mesh(void)
{
	enum { W = 200, H = 200 };
	struct tprim t;
	tprim_init(&t, REYES_POLYGONS);
	float *P = malloc(sizeof(float) * 3 * (W + 1) * (H + 1));
	uint32_t *nloops = malloc(sizeof(uint32_t) * W * H), *nverts = malloc(sizeof(uint32_t) * W * H);
	uint32_t *verts = malloc(sizeof(uint32_t) * 4 * W * H);
	for (uint32_t j = 0; j <= H; j++)
		for (uint32_t i = 0; i <= W; i++) {
			uint32_t k = j * (W + 1) + i;
			P[3 * k] = (float)i, P[3 * k + 1] = (float)j, P[3 * k + 2] = 0.0f;
		}
	for (uint32_t j = 0; j < H; j++)
		for (uint32_t i = 0; i < W; i++) {
			uint32_t f = j * W + i, a = j * (W + 1) + i;
			nloops[f] = 1;
			nverts[f] = 4;
			verts[4 * f] = a, verts[4 * f + 1] = a + 1;
			verts[4 * f + 2] = a + W + 2, verts[4 * f + 3] = a + W + 1;
		}
	t.prim.nfaces = W * H;
	t.prim.npoints = (W + 1) * (H + 1);
	t.prim.nloops = nloops;
	t.prim.nverts = nverts;
	t.prim.verts = verts;
	float *Cs = malloc(sizeof(float) * 3 * W * H);
	for (uint32_t f = 0; f < W * H; f++)
		Cs[3 * f] = (float)f, Cs[3 * f + 1] = Cs[3 * f + 2] = 0.0f;
	add_var(&t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, (W + 1) * (H + 1), P);
	add_var(&t, "Cs", REYES_UNIFORM, SL_TYPE_COLOR, 0, W * H, Cs);
	size_t n;
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == W * H);
	int wrong = 0;
	for (size_t i = 0; i < n; i++) {
		struct reyes_grid g;
		if (!reyes_patch_dice(&pa[i], 2, 2, &g)) {
			wrong++;
			continue;
		}
		/* Face f covers [i, i+1] x [j, j+1] and has Cs.r = f. */
		uint32_t f = (uint32_t)g.Cs[0];
		if (g.P[0][0] != (float)(f % W) || g.P[0][4] != (float)(f / W) || f != i)
			wrong++;
		reyes_grid_finish(&g);
	}
	clock_gettime(CLOCK_MONOTONIC, &t1);
	CHECK(wrong == 0);
	printf("mesh of %d quads: pieces + dice 2x2 each: %.1f ms\n", W * H,
	       (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) * 1e-6);
	free(pa);
	free(P);
	free(Cs);
	free(nloops);
	free(nverts);
	free(verts);
}

/* A random star-shaped face (angles sorted, radii random) with an optional star hole. */
static void star_face(float *xy, uint32_t n, double rmin, double rmax, double cx, double cy,
		      bool clockwise)
{
	double *ang = malloc(sizeof(double) * n);
	for (uint32_t i = 0; i < n; i++)
		ang[i] = 2.0 * PI_D * (i + 0.8 * rnd()) / n;
	for (uint32_t i = 0; i < n; i++) {
		double r = rmin + (rmax - rmin) * rnd(), a = clockwise ? -ang[i] : ang[i];
		xy[2 * i] = (float)(cx + r * cos(a));
		xy[2 * i + 1] = (float)(cy + r * sin(a));
	}
	free(ang);
}

static double shoelace(const float *xy, uint32_t n)
{
	double a = 0.0;
	for (uint32_t i = 0; i < n; i++) {
		uint32_t j = (i + 1) % n;
		a += (double)xy[2 * i] * xy[2 * j + 1] - (double)xy[2 * j] * xy[2 * i + 1];
	}
	return 0.5 * a;
}

static void test_polygon_random(void)
{
	int wrong_area = 0, wrong_count = 0;
	for (int trial = 0; trial < 300; trial++) {
		/*
		 * With a hole, at least 12 outline points: angular gaps stay under
		 * 54 degrees, so the outline holds the disc of radius 0.6 cos 27 > 0.53
		 * and the hole (radius <= 0.35, centre within 0.07) lies inside.
		 */
		uint32_t nh = trial % 3 ? 3 + (uint32_t)(rnd() * 8) : 0;
		uint32_t no = (nh ? 12 : 3) + (uint32_t)(rnd() * 28);
		float xy[2 * 64];
		star_face(xy, no, 0.6, 1.0, 0.0, 0.0, false);
		double area = shoelace(xy, no);
		if (nh) {
			/* A hole around a point near the middle, inside the outline's inner radius. */
			star_face(xy + 2 * no, nh, 0.1, 0.35, 0.05 * rnd(), 0.05 * rnd(), trial % 2);
			area -= fabs(shoelace(xy + 2 * no, nh));
		}
		struct poly p;
		uint32_t loops[2] = { no, nh };
		poly_init(&p, xy, no + nh, loops, nh ? 2 : 1);
		size_t np;
		double got = poly_area(&p.t.prim, NULL, &np);
		if (fabs(got - area) > 1e-6) {
			wrong_area++;
			fprintf(stderr, "  trial %d: %u + %u points: area %.9g, expected %.9g\n", trial,
				no, nh, got, area);
		}
		/* n + 2 h - 2 triangles of three pieces each (a convex quad may stay one). */
		size_t tris = no + nh + (nh ? 2 : 0) - 2;
		if (np != 3 * tris && !(no == 4 && !nh && np == 1))
			wrong_count++;
	}
	CHECK(wrong_area == 0);
	CHECK(wrong_count == 0);

	/*
	 * Many holes: a 4x3 grid of random star holes in a square (rays from
	 * later holes meet the bridges of earlier ones), and square holes all
	 * in one row, with their rightmost points at the same height.
	 */
	for (int trial = 0; trial < 40; trial++) {
		struct tprim t;
		tprim_init(&t, REYES_POLYGONS);
		float xy[2 * 200], P[3 * 200];
		uint32_t nloops = 13, nverts[13], verts[200], total = 4;
		const float sq[8] = { 0, 0, 8, 0, 8, 6, 0, 6 };
		memcpy(xy, sq, sizeof(sq));
		nverts[0] = 4;
		double area = 48.0;
		for (int h = 0; h < 12; h++) {
			uint32_t nh = 3 + (uint32_t)(rnd() * 10);
			if (trial % 2) {
				/* Axis-aligned squares in rows. */
				float x0 = 0.5f + 2.0f * (h % 4), y0 = 0.5f + 2.0f * (h / 4);
				const float q[8] = { x0, y0, x0 + 1, y0, x0 + 1, y0 + 1, x0, y0 + 1 };
				nh = 4;
				memcpy(xy + 2 * total, q, sizeof(q));
			} else {
				star_face(xy + 2 * total, nh, 0.2, 0.9, 1.0 + 2.0 * (h % 4), 1.0 + 2.0 * (h / 4),
					  h % 2);
			}
			area -= fabs(shoelace(xy + 2 * total, nh));
			nverts[1 + h] = nh;
			total += nh;
		}
		for (uint32_t i = 0; i < total; i++) {
			P[3 * i] = xy[2 * i], P[3 * i + 1] = xy[2 * i + 1], P[3 * i + 2] = 0.0f;
			verts[i] = i;
		}
		t.prim.nfaces = 1;
		t.prim.npoints = total;
		t.prim.nloops = &nloops;
		t.prim.nverts = nverts;
		t.prim.verts = verts;
		add_var(&t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, total, P);
		size_t np;
		double got = poly_area(&t.prim, NULL, &np);
		CHECK_NEAR(got, area, 1e-5);
		CHECK(np == 3 * (total + 2 * 12 - 2));
	}

	/* Garbage: random points, loops, repeats; no crash, finite grids. */
	rl_log_set_level(RL_LOG_SILENT);
	for (int trial = 0; trial < 300; trial++) {
		struct poly p;
		float xy[2 * 64];
		uint32_t nl = 1 + (uint32_t)(rnd() * 3), loops[3], total = 0;
		for (uint32_t l = 0; l < nl; l++) {
			loops[l] = (uint32_t)(rnd() * 12);
			total += loops[l];
		}
		for (uint32_t i = 0; i < 2 * total; i++)
			xy[i] = (float)(rnd() < 0.2 ? 0.5 : floor(rnd() * 4.0) / 2.0);
		poly_init(&p, xy, total, loops, nl);
		size_t n;
		bool ok;
		struct reyes_patch *pa = pieces(&p.t.prim, &n, &ok);
		CHECK(ok);
		for (size_t i = 0; i < n; i++) {
			struct reyes_grid g;
			CHECK(reyes_patch_dice(&pa[i], 3, 3, &g));
			CHECK(grid_finite(&g));
			CHECK(grid_in_bound(&pa[i], &g));
			reyes_grid_finish(&g);
		}
		free(pa);
	}
	rl_log_set_level(RL_LOG_WARN);
}

/* One face of many points: linear-ish triangulation, checked by area. */
static void test_polygon_big(void)
{
	enum { NPTS = 20000 };
	struct tprim t;
	tprim_init(&t, REYES_POLYGONS);
	float *xy = malloc(sizeof(float) * 2 * NPTS), *P = malloc(sizeof(float) * 3 * NPTS);
	uint32_t *verts = malloc(sizeof(uint32_t) * NPTS), nl = 1, nv = NPTS;
	star_face(xy, NPTS, 0.5, 1.0, 0.0, 0.0, false);
	for (uint32_t i = 0; i < NPTS; i++) {
		P[3 * i] = xy[2 * i], P[3 * i + 1] = xy[2 * i + 1], P[3 * i + 2] = 0.0f;
		verts[i] = i;
	}
	t.prim.nfaces = 1;
	t.prim.npoints = NPTS;
	t.prim.nloops = &nl;
	t.prim.nverts = &nv;
	t.prim.verts = verts;
	add_var(&t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, NPTS, P);
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	CHECK(n == 3 * (NPTS - 2));
	double area = 0.0;
	for (size_t i = 0; i < n; i++)
		area += piece_area(&pa[i]);
	CHECK_NEAR(area, shoelace(xy, NPTS), 1e-4);
	printf("star face of %d points: pieces in %.1f ms\n", NPTS,
	       (t1.tv_sec - t0.tv_sec) * 1e3 + (t1.tv_nsec - t0.tv_nsec) * 1e-6);
	free(pa);
	free(xy);
	free(P);
	free(verts);
}

/* Threads dicing one mesh's pieces while its pieces are asked for again. */
struct dice_job {
	const struct reyes_patch *pa;
	size_t n;
	int bad;
};

static void *dice_worker(void *arg)
{
	struct dice_job *j = arg;
	for (int rep = 0; rep < 3; rep++)
		for (size_t i = 0; i < j->n; i++) {
			struct reyes_grid g;
			float lo[3], hi[3];
			reyes_patch_bound(&j->pa[i], 0, lo, hi);
			if (!reyes_patch_dice(&j->pa[i], 3, 3, &g) || !grid_finite(&g))
				j->bad++;
			reyes_grid_finish(&g);
		}
	return NULL;
}

static void test_threads(void)
{
	struct poly p;
	float xy[2 * 40];
	star_face(xy, 40, 0.5, 1.0, 0.0, 0.0, false);
	uint32_t l = 40;
	poly_init(&p, xy, 40, &l, 1);
	size_t n;
	struct reyes_patch *pa = pieces(&p.t.prim, &n, NULL);
	CHECK(n == 3 * 38);
	struct dice_job jobs[4];
	pthread_t th[4];
	for (int i = 0; i < 4; i++) {
		jobs[i] = (struct dice_job){ pa, n, 0 };
		CHECK(pthread_create(&th[i], NULL, dice_worker, &jobs[i]) == 0);
	}
	for (int r = 0; r < 20; r++) {
		size_t n2;
		struct reyes_patch *again = pieces(&p.t.prim, &n2, NULL);
		CHECK(n2 == n);
		free(again);
	}
	for (int i = 0; i < 4; i++) {
		pthread_join(th[i], NULL);
		CHECK(jobs[i].bad == 0);
	}
	free(pa);
}

/* ---- patches ---- */

static const float basis_bezier[16] = { -1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0 };
static const float basis_bspline[16] = {
	-1 / 6.0f, 3 / 6.0f, -3 / 6.0f, 1 / 6.0f, 3 / 6.0f, -6 / 6.0f, 3 / 6.0f, 0,
	-3 / 6.0f, 0, 3 / 6.0f, 0, 1 / 6.0f, 4 / 6.0f, 1 / 6.0f, 0,
};
static const float basis_catmull[16] = {
	-0.5f, 1.5f, -1.5f, 0.5f, 1, -2.5f, 2, -0.5f, -0.5f, 0, 0.5f, 0, 0, 1, 0, 0,
};
static const float basis_hermite[16] = { 2, 1, -2, 1, -3, -2, 3, -1, 0, 1, 0, 0, 1, 0, 0, 0 };
static const float basis_power[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };

static void patch_init(struct tprim *t, bool bicubic, uint32_t nu, uint32_t nv, const float *P,
		       const float *ub, const float *vb, uint32_t ustep, uint32_t vstep)
{
	tprim_init(t, REYES_PATCHES);
	t->prim.bicubic = bicubic;
	t->prim.nu = nu;
	t->prim.nv = nv;
	t->prim.npoints = nu * nv;
	if (ub)
		memcpy(t->prim.ubasis, ub, sizeof(t->prim.ubasis));
	if (vb)
		memcpy(t->prim.vbasis, vb, sizeof(t->prim.vbasis));
	t->prim.ustep = ustep;
	t->prim.vstep = vstep;
	add_var(t, "P", REYES_VERTEX, SL_TYPE_POINT, 0, nu * nv, P);
}

static void test_bilinear_mesh(void)
{
	struct tprim t;
	float P[27];
	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++) {
			P[3 * (j * 3 + i)] = (float)i;
			P[3 * (j * 3 + i) + 1] = (float)j;
			P[3 * (j * 3 + i) + 2] = 0.0f;
		}
	patch_init(&t, false, 3, 3, P, NULL, NULL, 1, 1);
	/* Varying: one per point; uniform: one per cell. */
	float vary[9], uni[4] = { 10, 11, 12, 13 };
	for (int i = 0; i < 9; i++)
		vary[i] = (float)i;
	add_var(&t, "s", REYES_VARYING, SL_TYPE_FLOAT, 0, 9, vary);
	add_var(&t, "cell", REYES_UNIFORM, SL_TYPE_FLOAT, 0, 4, uni);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 4);
	double area = 0.0;
	int covered[9] = { 0 };
	for (size_t c = 0; c < n; c++) {
		area += piece_area(&pa[c]);
		struct reyes_grid g;
		CHECK(reyes_patch_dice(&pa[c], 5, 5, &g));
		if (!g.n)
			continue;
		uint32_t cu = (uint32_t)c % 2, cv = (uint32_t)c / 2;
		/* The cell's square, and u, v a quarter of the mesh's 0..1 range. */
		CHECK(g.P[0][0] == (float)cu && g.P[0][25] == (float)cv);
		CHECK(g.P[0][24] == (float)cu + 1 && g.P[0][25 + 24] == (float)cv + 1);
		CHECK_NEAR(g.u[0], 0.5 * cu, 0);
		CHECK_NEAR(g.u[4], 0.5 * cu + 0.5, 1e-7);
		CHECK_NEAR(g.v[24], 0.5 * cv + 0.5, 1e-7);
		CHECK_NEAR(g.du, 0.125, 1e-7);
		/* Derivatives with respect to the mesh's u: 2 units of x per unit u. */
		CHECK_NEAR(g.dPdu[12], 2.0, 1e-6);
		CHECK_NEAR(g.dPdv[25 + 12], 2.0, 1e-6);
		CHECK(g.Ng[50] > 0.0f);
		/* Mid-cell sample lands in 1 of 4 unit squares, each once. */
		int x = (int)g.P[0][12], y = (int)g.P[0][25 + 12];
		covered[y * 3 + x]++;
		CHECK(g.s && g.s[0] == (float)(cv * 3 + cu) && g.s[24] == (float)((cv + 1) * 3 + cu + 1));
		CHECK(g.nvars == 1 && g.vars[0].data[7] == uni[c]);
		reyes_grid_finish(&g);
	}
	CHECK_NEAR(area, 4.0, 1e-6);
	CHECK(covered[0] == 1 && covered[1] == 1 && covered[3] == 1 && covered[4] == 1);
	free(pa);

	/* A collapsed edge (a triangle as a bilinear patch): a finite, nonzero Ng everywhere. */
	const float tri[] = { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0 };
	patch_init(&t, false, 2, 2, tri, NULL, NULL, 1, 1);
	pa = pieces(&t.prim, &n, NULL);
	struct reyes_grid g;
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 4, 4, &g));
	for (uint32_t k = 0; g.n && k < g.n; k++) {
		double Ng[3];
		get3(g.Ng, g.n, k, Ng);
		CHECK(Ng[2] > 0.0 && fabs(Ng[0]) + fabs(Ng[1]) <= 1e-6 * Ng[2]);
	}
	CHECK(grid_finite(&g));
	reyes_grid_finish(&g);
	free(pa);
}

/*
 * A deforming sphere (qmoving: radius 1 at open, 3 at close): P[1] on the
 * bigger sphere at the same (u, v), each time's bound holding its points;
 * one growing from radius 0 has its derivatives and normal from the close
 * sample and its points at open at the centre.
 */
static void test_deforming_quadric(void)
{
	struct tprim t;
	quadric(&t, REYES_SPHERE, 1, -1, 1, 360, 0, 0, 0);
	t.prim.qmoving = true;
	t.prim.q1[0] = 3, t.prim.q1[1] = -3, t.prim.q1[2] = 3, t.prim.q1[3] = 360;
	CHECK(reyes_prim_deforms(&t.prim));
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	struct reyes_grid g;
	if (n == 1 && reyes_patch_dice(&pa[0], 7, 5, &g)) {
		CHECK(g.P[1] != g.P[0] && grid_finite(&g));
		float lo[2][3], hi[2][3];
		reyes_patch_bound(&pa[0], 0, lo[0], hi[0]);
		reyes_patch_bound(&pa[0], 1, lo[1], hi[1]);
		CHECK(hi[0][0] < 1.01f && hi[1][0] > 2.99f && hi[1][0] < 3.01f);
		for (uint32_t k = 0; k < g.n; k++) {
			double P0[3], P1[3];
			get3(g.P[0], g.n, k, P0);
			get3(g.P[1], g.n, k, P1);
			CHECK_NEAR(len3(P0), 1.0, 2e-6);
			for (int c = 0; c < 3; c++) {
				CHECK_NEAR(P1[c], 3 * P0[c], 1e-5);
				CHECK(P0[c] >= lo[0][c] && P0[c] <= hi[0][c]);
				CHECK(P1[c] >= lo[1][c] && P1[c] <= hi[1][c]);
			}
		}
		reyes_grid_finish(&g);
	}
	free(pa);
	t.prim.q[0] = t.prim.q[1] = t.prim.q[2] = 0;
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	if (n == 1 && reyes_patch_dice(&pa[0], 5, 5, &g)) {
		CHECK(grid_finite(&g));
		for (uint32_t k = 0; k < g.n; k++) {
			double P0[3], P1[3], Ng[3];
			get3(g.P[0], g.n, k, P0);
			get3(g.P[1], g.n, k, P1);
			get3(g.Ng, g.n, k, Ng);
			CHECK(len3(P0) == 0.0);
			CHECK_NEAR(len3(P1), 3.0, 1e-5);
			CHECK_NEAR(dot3(Ng, P1) / (len3(Ng) * 3), 1.0, 1e-4);
		}
		reyes_grid_finish(&g);
	}
	free(pa);
	/* Degenerate at both times: nothing to dice. */
	t.prim.q1[0] = 0;
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 0);
	free(pa);
}

/*
 * A height field: a 3x2 bilinear mesh whose "P" holds only z (x and y
 * unused, here 7): diced points at (u, v, z), dPdu = (1, 0, dz/du) and
 * dPdv = (0, 1, dz/dv) with respect to the mesh's u and v, the bound's x
 * and y the piece's (u, v) range.
 */
static void test_height_field(void)
{
	struct tprim t;
	const float z[6] = { 0, 1, 3, 2, 2, 2 };
	float P[18];
	for (int i = 0; i < 6; i++)
		P[3 * i] = P[3 * i + 1] = 7, P[3 * i + 2] = z[i];
	patch_init(&t, false, 3, 2, P, NULL, NULL, 1, 1);
	t.prim.heightfield = true;
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 2);
	for (size_t c = 0; c < n; c++) {
		struct reyes_grid g;
		if (!reyes_patch_dice(&pa[c], 5, 5, &g))
			continue;
		float lo[3], hi[3];
		reyes_patch_bound(&pa[c], 0, lo, hi);
		CHECK_NEAR(lo[0], 0.5 * c, 1e-5);
		CHECK_NEAR(hi[0], 0.5 * c + 0.5, 1e-5);
		CHECK_NEAR(lo[1], 0, 1e-5);
		CHECK_NEAR(hi[1], 1, 1e-5);
		for (uint32_t k = 0; k < g.n; k++) {
			double p[3], du[3], dv[3];
			get3(g.P[0], g.n, k, p);
			get3(g.dPdu, g.n, k, du);
			get3(g.dPdv, g.n, k, dv);
			double u = g.u[k], v = g.v[k], f = 2 * u - (double)c;
			const float *zc = &z[c];
			double want = (1 - f) * (1 - v) * zc[0] + f * (1 - v) * zc[1] +
				      (1 - f) * v * zc[3] + f * v * zc[4];
			CHECK_NEAR(p[0], u, 1e-6);
			CHECK_NEAR(p[1], v, 1e-6);
			CHECK_NEAR(p[2], want, 1e-5);
			CHECK_NEAR(du[0], 1, 0);
			CHECK_NEAR(du[1], 0, 0);
			CHECK_NEAR(du[2], 2 * ((1 - v) * (zc[1] - zc[0]) + v * (zc[4] - zc[3])), 1e-5);
			CHECK_NEAR(dv[0], 0, 0);
			CHECK_NEAR(dv[1], 1, 0);
			CHECK(p[0] >= lo[0] && p[0] <= hi[0] && p[2] >= lo[2] && p[2] <= hi[2]);
		}
		reyes_grid_finish(&g);
	}
	free(pa);
}

static void test_periodic(void)
{
	/* Bilinear, periodic in u: 4 points on a square ring, 2 rows: 4 cells. */
	struct tprim t;
	float P[24];
	for (int j = 0; j < 2; j++)
		for (int i = 0; i < 4; i++) {
			double a = i * PI_D / 2;
			P[3 * (j * 4 + i)] = (float)cos(a);
			P[3 * (j * 4 + i) + 1] = (float)sin(a);
			P[3 * (j * 4 + i) + 2] = (float)j;
		}
	patch_init(&t, false, 4, 2, P, NULL, NULL, 1, 1);
	t.prim.uperiodic = true;
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 4);
	struct reyes_grid first, last;
	if (n == 4 && reyes_patch_dice(&pa[0], 3, 3, &first) &&
	    reyes_patch_dice(&pa[3], 3, 3, &last)) {
		/* The last cell ends where the first begins. */
		for (int j = 0; j < 3; j++)
			for (int c = 0; c < 3; c++)
				CHECK(last.P[0][c * 9 + j * 3 + 2] == first.P[0][c * 9 + j * 3]);
		CHECK_NEAR(last.u[2], 1.0, 0);
		CHECK_NEAR(last.u[0], 0.75, 0);
		reyes_grid_finish(&first);
		reyes_grid_finish(&last);
	}
	free(pa);

	/* Bicubic b-spline periodic in u (6 points round a circle, step 1: 6 segments). */
	float Q[3 * 6 * 4];
	for (int j = 0; j < 4; j++)
		for (int i = 0; i < 6; i++) {
			double a = i * PI_D / 3;
			Q[3 * (j * 6 + i)] = (float)cos(a);
			Q[3 * (j * 6 + i) + 1] = (float)sin(a);
			Q[3 * (j * 6 + i) + 2] = (float)j;
		}
	patch_init(&t, true, 6, 4, Q, basis_bspline, basis_bspline, 1, 1);
	t.prim.uperiodic = true;
	/* Varying at segment ends: 6 (wrapped) x 2. */
	float vary[12];
	for (int i = 0; i < 12; i++)
		vary[i] = (float)i;
	add_var(&t, "s", REYES_VARYING, SL_TYPE_FLOAT, 0, 12, vary);
	pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 6);
	if (n == 6 && reyes_patch_dice(&pa[0], 3, 3, &first) &&
	    reyes_patch_dice(&pa[5], 3, 3, &last)) {
		for (int j = 0; j < 3; j++)
			for (int c = 0; c < 3; c++) {
				CHECK_NEAR(last.P[0][c * 9 + j * 3 + 2], first.P[0][c * 9 + j * 3], 1e-6);
				CHECK_NEAR(last.dPdu[c * 9 + j * 3 + 2], first.dPdu[c * 9 + j * 3], 1e-5);
			}
		/* A uniform b-spline of a regular hexagon stays within radius 1. */
		for (uint32_t k = 0; k < 9; k++)
			CHECK(hypot(first.P[0][k], first.P[0][9 + k]) <= 1.0 + 1e-6);
		/* Wrapped varying: last segment's end is item 0 (row 0) and item 6 (row 1). */
		CHECK(last.s && last.s[2] == 0.0f && last.s[8] == 6.0f && last.s[0] == 5.0f);
		reyes_grid_finish(&first);
		reyes_grid_finish(&last);
	}
	free(pa);
}

struct basis_case {
	const char *name;
	const float *b;
	uint32_t step;
};

static const struct basis_case bases[] = {
	{ "bezier", basis_bezier, 3 },
	{ "b-spline", basis_bspline, 1 },
	{ "catmull-rom", basis_catmull, 1 },
	{ "hermite", basis_hermite, 2 },
	{ "power", basis_power, 4 },
};

static void test_bicubic_bounds(void)
{
	int misses = 0, dices = 0;
	for (size_t b = 0; b < sizeof(bases) / sizeof(bases[0]); b++) {
		/* Three segments each way, random control points. */
		uint32_t nu = 4 + 2 * bases[b].step, nv = nu;
		float *P = malloc(sizeof(float) * 3 * nu * nv);
		for (uint32_t i = 0; i < 3 * nu * nv; i++)
			P[i] = (float)(2.0 * rnd() - 1.0);
		struct tprim t;
		patch_init(&t, true, nu, nv, P, bases[b].b, bases[b].b, bases[b].step, bases[b].step);
		size_t n;
		struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
		CHECK(n == 9);
		for (size_t c = 0; c < n; c++)
			for (int i = 0; i < 30; i++) {
				struct reyes_patch sub = pa[c];
				double x = rnd(), y = rnd(), z = rnd(), w = rnd();
				if (i == 0)
					x = 0, y = 1, z = 0, w = 1;
				sub.u0 = (float)fmin(x, y), sub.u1 = (float)fmax(x, y);
				sub.v0 = (float)fmin(z, w), sub.v1 = (float)fmax(z, w);
				struct reyes_grid g;
				if (!reyes_patch_dice(&sub, 7, 7, &g)) {
					misses++;
					continue;
				}
				dices++;
				if (!grid_finite(&g) || !grid_in_bound(&sub, &g)) {
					misses++;
					fprintf(stderr, "  (%s cell %zu)\n", bases[b].name, c);
				}
				reyes_grid_finish(&g);
			}
		/* Derivatives against differences in one cell. */
		if (n)
			check_derivatives(&pa[4], 0.4, 0.6, 1e-3, 2e-3);
		free(pa);
		free(P);
	}
	CHECK(misses == 0);
	CHECK(dices == 5 * 9 * 30);
}

static void test_bezier_corners(void)
{
	float P[48];
	for (int i = 0; i < 48; i++)
		P[i] = (float)(4.0 * rnd() - 2.0);
	struct tprim t;
	patch_init(&t, true, 4, 4, P, basis_bezier, basis_bezier, 3, 3);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	CHECK(n == 1);
	struct reyes_grid g;
	if (n == 1 && reyes_patch_dice(&pa[0], 2, 2, &g)) {
		const int corner[4] = { 0, 3, 12, 15 };
		for (int k = 0; k < 4; k++)
			for (int c = 0; c < 3; c++)
				CHECK_NEAR(g.P[0][c * 4 + k], P[3 * corner[k] + c], 1e-6);
		/* Bezier end tangents: dP/du at (0,0) = 3 (P1 - P0). */
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(g.dPdu[c * 4], 3.0 * (P[3 + c] - P[c]), 1e-5);
		reyes_grid_finish(&g);
	}
	free(pa);

	/* A bicubic patch with its top row collapsed to a point: Ng finite and nonzero. */
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++) {
			P[3 * (j * 4 + i)] = j == 3 ? 0.0f : (float)i - 1.5f;
			P[3 * (j * 4 + i) + 1] = (float)j;
			P[3 * (j * 4 + i) + 2] = 0.0f;
		}
	pa = pieces(&t.prim, &n, NULL);
	if (n == 1 && reyes_patch_dice(&pa[0], 5, 5, &g)) {
		CHECK(grid_finite(&g));
		for (uint32_t k = 0; k < g.n; k++) {
			double Ng[3];
			get3(g.Ng, g.n, k, Ng);
			CHECK(Ng[2] > 0.0);
		}
		reyes_grid_finish(&g);
	}
	free(pa);

	/* Meshes that cannot be diced are errors: too few points, step 0, too little P. */
	bool ok;
	rl_log_set_level(RL_LOG_SILENT);
	patch_init(&t, true, 3, 4, P, basis_bezier, basis_bezier, 3, 3);
	pa = pieces(&t.prim, &n, &ok);
	CHECK(!ok && n == 0);
	free(pa);
	patch_init(&t, true, 4, 4, P, basis_bezier, basis_bezier, 0, 3);
	pa = pieces(&t.prim, &n, &ok);
	CHECK(!ok);
	free(pa);
	patch_init(&t, false, 4, 4, P, NULL, NULL, 1, 1);
	t.vars[0].count = 15;
	pa = pieces(&t.prim, &n, &ok);
	CHECK(!ok);
	free(pa);
	P[7] = NAN;
	patch_init(&t, true, 4, 4, P, basis_bezier, basis_bezier, 3, 3);
	pa = pieces(&t.prim, &n, &ok);
	CHECK(!ok && n == 0);
	free(pa);
	rl_log_set_level(RL_LOG_WARN);
}

/* Each kind diced at 16x16, timed (printed, not checked). */
static void test_timing(void)
{
	struct tprim t[6];
	const char *names[6] = { "sphere", "torus", "hyperboloid", "polygon", "bilinear", "bicubic" };
	quadric(&t[0], REYES_SPHERE, 1, -1, 1, 360, 0, 0, 0);
	quadric(&t[1], REYES_TORUS, 1, 0.3f, 0, 360, 360, 0, 0);
	quadric(&t[2], REYES_HYPERBOLOID, 1, 0, -1, 0, 1, 1, 360);
	struct poly p;
	const float L[] = { 0, 0, 2, 0, 2, 1, 1, 1, 1, 2, 0, 2 };
	uint32_t l6 = 6;
	poly_init(&p, L, 6, &l6, 1);
	t[3] = p.t;
	t[3].prim.vars = t[3].vars;
	t[3].prim.attrs = &t[3].attrs;
	float P[48];
	for (int i = 0; i < 48; i++)
		P[i] = (float)rnd();
	patch_init(&t[4], false, 4, 4, P, NULL, NULL, 1, 1);
	patch_init(&t[5], true, 4, 4, P, basis_bspline, basis_bspline, 1, 1);
	for (int k = 0; k < 6; k++) {
		size_t n;
		struct reyes_patch *pa = pieces(&t[k].prim, &n, NULL);
		CHECK(n > 0);
		if (!n) {
			free(pa);
			continue;
		}
		const int reps = 2000;
		struct timespec t0, t1;
		clock_gettime(CLOCK_MONOTONIC, &t0);
		for (int r = 0; r < reps; r++) {
			struct reyes_grid g;
			CHECK(reyes_patch_dice(&pa[0], 16, 16, &g));
			reyes_grid_finish(&g);
		}
		clock_gettime(CLOCK_MONOTONIC, &t1);
		double us = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) * 1e-3 / reps;
		printf("dice 16x16 %-12s %7.2f us\n", names[k], us);
		free(pa);
	}
}

static void test_prim_var(void)
{
	struct tprim t;
	tprim_init(&t, REYES_SPHERE);
	const float c[3] = { 1, 2, 3 };
	add_var(&t, "Cs", REYES_CONSTANT, SL_TYPE_COLOR, 0, 1, c);
	add_var(&t, "foo", REYES_CONSTANT, SL_TYPE_FLOAT, 0, 1, c);
	CHECK(reyes_prim_var(&t.prim, "foo") == &t.vars[1]);
	CHECK(reyes_prim_var(&t.prim, "Cs") == &t.vars[0]);
	CHECK(reyes_prim_var(&t.prim, "P") == NULL);
	CHECK(reyes_prim_var(NULL, "P") == NULL);

	/* Quadric varying data: four corners in RISpec order, bilinear between. */
	quadric(&t, REYES_CYLINDER, 1, 0, 1, 360, 0, 0, 0);
	const float corners[4] = { 0, 1, 2, 3 };
	add_var(&t, "x", REYES_VARYING, SL_TYPE_FLOAT, 0, 4, corners);
	add_var(&t, "Cs", REYES_CONSTANT, SL_TYPE_COLOR, 0, 1, c);
	size_t n;
	struct reyes_patch *pa = pieces(&t.prim, &n, NULL);
	struct reyes_grid g;
	CHECK(n == 1 && reyes_patch_dice(&pa[0], 3, 3, &g));
	if (g.n) {
		CHECK(g.nvars == 1 && g.vars[0].data[0] == 0.0f && g.vars[0].data[2] == 1.0f &&
		      g.vars[0].data[6] == 2.0f && g.vars[0].data[8] == 3.0f &&
		      g.vars[0].data[4] == 1.5f);
		CHECK(g.Cs && g.Cs[4] == 1.0f && g.Cs[9 + 4] == 2.0f && g.Cs[18 + 4] == 3.0f);
		reyes_grid_finish(&g);
	}
	free(pa);
}

int main(void)
{
	RUN(test_prim_var);
	RUN(test_sphere);
	RUN(test_sphere_poles);
	RUN(test_quadric_surfaces);
	RUN(test_quadric_orientation);
	RUN(test_quadric_bounds);
	RUN(test_quadric_degenerate);
	RUN(test_split);
	RUN(test_polygons);
	RUN(test_polygon_tilted);
	RUN(test_polygon_primvars);
	RUN(test_polygon_degenerate);
	RUN(test_polygon_mesh);
	RUN(test_polygon_random);
	RUN(test_polygon_big);
	RUN(test_threads);
	RUN(test_bilinear_mesh);
	RUN(test_periodic);
	RUN(test_deforming_quadric);
	RUN(test_height_field);
	RUN(test_bicubic_bounds);
	RUN(test_bezier_corners);
	RUN(test_timing);
	return test_finish();
}

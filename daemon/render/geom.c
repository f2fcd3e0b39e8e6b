/*
 * Geometry: primitives to parametric pieces, their bounds, splits and diced
 * grids.
 *
 * Pieces. A quadric is one piece over its whole (u, v) square, parameterised
 * as RISpec 3.2's quadrics are (theta = u * thetamax about z, the profile
 * curve along v; thetamax is limited to +-360). A patch mesh gives one piece per cell, numbered
 * cu + cv * ncu; u and v run 0..1 over the whole mesh, each cell a sub-range.
 * A polygon face is triangulated by ear clipping in its best-fit (Newell)
 * plane, holes first bridged into the outline; a planar convex quad stays
 * one bilinear piece with corners P00 P10 P11 P01 = v0 v1 v2 v3.
 *
 * Triangles. A bilinear patch with two coincident corners has a vanishing
 * dPdu along one edge, and no smooth map of the square onto a triangle avoids
 * a singular point, so a triangle (a, b, c) becomes three bilinear pieces,
 * one per corner: P00 = a, P10 = midpoint of ab, P11 = centroid, P01 =
 * midpoint of ac (and the same from b and from c). Each is a convex planar
 * quad: its derivatives never vanish and dPdu ^ dPdv points along the
 * triangle's normal, which is the polygon's normal by the right-hand rule
 * over the outline's vertex order. Polygon pieces are numbered
 * 4 * element + sub (sub 0..2 for a triangle's thirds, 0 for a quad); u and
 * v on them are the piece's own parameters.
 *
 * A piece number cannot name a triangle of an arbitrary face by itself, so
 * triangulations live in a small process-wide cache keyed by the primitive's
 * address: reyes_prim_pieces (re)builds a primitive's entry, bounding and
 * dicing look it up (rebuilding it if it was evicted). A primitive whose
 * points or faces change in place must be given to reyes_prim_pieces again.
 */
#include "geom.h"
#include "geom_subdiv.h"
#include "nurbs.h"
#include "geom_curves.h"

#include "arena.h"
#include "log.h"
#include "mathlib.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#define PI_D 3.14159265358979323846
#define DEG_TO_RAD (PI_D / 180.0)
#define NONE UINT32_MAX

/* ---- small helpers ---- */

static void v3_sub(double r[3], const double a[3], const double b[3])
{
	r[0] = a[0] - b[0];
	r[1] = a[1] - b[1];
	r[2] = a[2] - b[2];
}

static void v3_cross(double r[3], const double a[3], const double b[3])
{
	double x = a[1] * b[2] - a[2] * b[1];
	double y = a[2] * b[0] - a[0] * b[2];
	double z = a[0] * b[1] - a[1] * b[0];
	r[0] = x;
	r[1] = y;
	r[2] = z;
}

static double v3_dot(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static double v3_len(const double a[3])
{
	return sqrt(v3_dot(a, a));
}

static double clampd(double x, double lo, double hi)
{
	return x < lo ? lo : x > hi ? hi : x;
}

const struct reyes_primvar *reyes_prim_var(const struct reyes_prim *p, const char *name)
{
	if (!p || !name || !p->vars)
		return NULL;
	for (uint32_t i = 0; i < p->nvars; i++)
		if (p->vars[i].name && strcmp(p->vars[i].name, name) == 0)
			return &p->vars[i];
	return NULL;
}

bool reyes_prim_deforms(const struct reyes_prim *p)
{
	if (!p)
		return false;
	if (p->kind < REYES_POLYGONS)
		return p->qmoving;
	if (p->kind == REYES_CURVES || p->kind == REYES_POINTS)
		return reyes_curves_deform(p);
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	return P && P->values1;
}

size_t reyes_primvar_stride(const struct reyes_primvar *v)
{
	return (size_t)sl_type_ncomp(v->type) * (v->arraylen ? v->arraylen : 1);
}

/* The "P" variable of a polygon or patch primitive if it holds @need points. */
static const struct reyes_primvar *points_var(const struct reyes_prim *p, uint64_t need)
{
	const struct reyes_primvar *v = reyes_prim_var(p, "P");
	if (!v || !v->values || reyes_primvar_stride(v) != 3 || v->count < need)
		return NULL;
	return v;
}

/* ---- quadrics ---- */

/*
 * A quadric's parameters in radians. Every quadric is a profile curve c(v)
 * in the xz half-plane (the hyperboloid's leaves it) rotated by
 * theta = u * thetamax about z, so dP/du = thetamax (-y, x, 0).
 */
struct quadric {
	enum reyes_prim_kind kind;
	double tmax;           /* thetamax, radians */
	double a, b, c, d;     /* sphere: radius phimin phimax; cylinder: radius zmin zmax;
				  cone, disk: height radius; paraboloid: rmax zmin zmax;
				  torus: major minor phimin phimax */
	double p1[3], p2[3];   /* hyperboloid */
};

/* The number of parameters of a quadric kind; 0 for other kinds. */
static int quadric_nparams(enum reyes_prim_kind kind)
{
	switch (kind) {
	case REYES_SPHERE: case REYES_CYLINDER: case REYES_PARABOLOID: return 4;
	case REYES_CONE: case REYES_DISK: return 3;
	case REYES_HYPERBOLOID: return 7;
	case REYES_TORUS: return 5;
	default: return 0;
	}
}

/*
 * The quadric of @kind with RIB parameters @a into @q. False for a quadric
 * with no area (zero radius, thetamax 0, ...); *ok false as well for
 * non-finite parameters. A quadric with no area still evaluates to finite
 * points (a zero radius puts them all on the axis), which is what the
 * degenerate sample of a deforming quadric needs (a sphere growing from
 * radius 0).
 */
static bool quadric_params(enum reyes_prim_kind kind, const float *a, struct quadric *q,
			   bool *ok)
{
	int nq = quadric_nparams(kind);
	*ok = nq > 0;
	for (int i = 0; i < nq; i++)
		if (!isfinite(a[i]))
			*ok = false;
	memset(q, 0, sizeof(*q));
	q->kind = kind;
	if (!*ok)
		return false;
	/* A sweep past a full turn would only cover the surface again. */
	double tm = clampd(a[nq - 1], -360.0, 360.0);
	q->tmax = tm * DEG_TO_RAD;
	bool area = tm != 0.0;
	switch (kind) {
	case REYES_SPHERE:
		/* asin(z/r), clamped: -90 below -r and 90 above r, as RISpec has it for r > 0. */
		q->a = a[0];
		if (q->a == 0.0)
			return false;
		q->b = asin(clampd(a[1] / q->a, -1.0, 1.0));
		q->c = asin(clampd(a[2] / q->a, -1.0, 1.0));
		return area && q->b != q->c;
	case REYES_CYLINDER:
		q->a = a[0], q->b = a[1], q->c = a[2];
		return area && q->a != 0.0 && q->b != q->c;
	case REYES_CONE:
	case REYES_DISK:
		q->a = a[0], q->b = a[1];
		return area && q->b != 0.0;
	case REYES_PARABOLOID:
		q->a = a[0], q->b = a[1], q->c = a[2];
		if (q->c == 0.0) {
			/* No paraboloid (zmax 0): its points at the apex. */
			q->a = 0.0, q->b = q->c = 1e-30;
			return false;
		}
		/* (z = zmax itself is always on the paraboloid's side of 0.) */
		return area && q->a != 0.0 && q->b != q->c;
	case REYES_TORUS:
		q->a = a[0], q->b = a[1];
		q->c = a[2] * DEG_TO_RAD, q->d = a[3] * DEG_TO_RAD;
		return area && q->b != 0.0 && q->c != q->d;
	case REYES_HYPERBOLOID:
		for (int i = 0; i < 3; i++)
			q->p1[i] = a[i], q->p2[i] = a[3 + i];
		if (q->p1[0] == q->p2[0] && q->p1[1] == q->p2[1] && q->p1[2] == q->p2[2])
			return false;
		/* A segment on the axis sweeps nothing. */
		return area && (q->p1[0] != 0.0 || q->p1[1] != 0.0 || q->p2[0] != 0.0 ||
				q->p2[1] != 0.0);
	default:
		return false;
	}
}

/*
 * The quadric @p at shutter open (q[0]) and close (q[1], the same unless it
 * deforms); *shape: the one whose derivatives and normals the grid takes
 * (the open one, unless only the close one has area). False when it has no
 * area at either time or a parameter is not finite.
 */
static bool quadric_setup(const struct reyes_prim *p, struct quadric q[2], int *shape)
{
	bool ok0, ok1;
	bool area0 = quadric_params(p->kind, p->q, &q[0], &ok0);
	*shape = 0;
	if (!p->qmoving) {
		q[1] = q[0];
		return area0;
	}
	bool area1 = quadric_params(p->kind, p->q1, &q[1], &ok1);
	*shape = area0 ? 0 : 1;
	return ok0 && ok1 && (area0 || area1);
}

/* The profile point c(v) (before the rotation) and dc/dv. */
static void quadric_profile(const struct quadric *q, double v, double c[3], double dc[3])
{
	double phi, s, z, dz;
	switch (q->kind) {
	case REYES_SPHERE:
		phi = q->b + v * (q->c - q->b);
		c[0] = q->a * cos(phi), c[1] = 0.0, c[2] = q->a * sin(phi);
		dc[0] = -(q->c - q->b) * q->a * sin(phi), dc[1] = 0.0;
		dc[2] = (q->c - q->b) * q->a * cos(phi);
		return;
	case REYES_CYLINDER:
		/* z runs from zmin to zmax (the spec's "z = v (zmax - zmin)" drops the zmin). */
		c[0] = q->a, c[1] = 0.0, c[2] = q->b + v * (q->c - q->b);
		dc[0] = 0.0, dc[1] = 0.0, dc[2] = q->c - q->b;
		return;
	case REYES_CONE:
		c[0] = q->b * (1.0 - v), c[1] = 0.0, c[2] = v * q->a;
		dc[0] = -q->b, dc[1] = 0.0, dc[2] = q->a;
		return;
	case REYES_DISK:
		c[0] = q->b * (1.0 - v), c[1] = 0.0, c[2] = q->a;
		dc[0] = -q->b, dc[1] = 0.0, dc[2] = 0.0;
		return;
	case REYES_PARABOLOID:
		/*
		 * r = rmax sqrt(z / zmax) with z = zmin + v (zmax - zmin). At the
		 * apex dr/dv is infinite; it is kept finite by a floor on z / zmax
		 * (the normal there comes from the limit, see quadric_normal).
		 */
		z = q->b + v * (q->c - q->b);
		dz = q->c - q->b;
		s = z / q->c;
		c[0] = q->a * sqrt(s > 0.0 ? s : 0.0), c[1] = 0.0, c[2] = z;
		dc[0] = q->a * dz / (2.0 * q->c * sqrt(s > 1e-8 ? s : 1e-8)), dc[1] = 0.0;
		dc[2] = dz;
		return;
	case REYES_TORUS:
		phi = q->c + v * (q->d - q->c);
		c[0] = q->a + q->b * cos(phi), c[1] = 0.0, c[2] = q->b * sin(phi);
		dc[0] = -(q->d - q->c) * q->b * sin(phi), dc[1] = 0.0;
		dc[2] = (q->d - q->c) * q->b * cos(phi);
		return;
	case REYES_HYPERBOLOID:
		for (int i = 0; i < 3; i++) {
			c[i] = (1.0 - v) * q->p1[i] + v * q->p2[i];
			dc[i] = q->p2[i] - q->p1[i];
		}
		return;
	default:
		c[0] = c[1] = c[2] = dc[0] = dc[1] = dc[2] = 0.0;
		return;
	}
}

/* P, dP/du and dP/dv at the primitive's (u, v). */
static void quadric_eval(const struct quadric *q, double u, double v, double P[3],
			 double dPdu[3], double dPdv[3])
{
	double c[3], dc[3];
	quadric_profile(q, v, c, dc);
	double th = u * q->tmax, ct = cos(th), st = sin(th);
	P[0] = c[0] * ct - c[1] * st;
	P[1] = c[0] * st + c[1] * ct;
	P[2] = c[2];
	dPdu[0] = -q->tmax * P[1];
	dPdu[1] = q->tmax * P[0];
	dPdu[2] = 0.0;
	dPdv[0] = dc[0] * ct - dc[1] * st;
	dPdv[1] = dc[0] * st + dc[1] * ct;
	dPdv[2] = dc[2];
}

/*
 * dPdu ^ dPdv, or where P is on the axis (a pole, an apex, a disk's centre)
 * and dPdu vanishes, its limit. Near such a point at v*, dPdu is about
 * (v - v*) d2 with d2 = d(dPdu)/dv = thetamax (-dPdv.y, dPdv.x, 0), so the
 * normal tends to sign(v - v*) (d2 ^ dPdv); the surface lies on the side of
 * v* towards the middle of the v range.
 */
static void quadric_normal(const struct quadric *q, double v, const double dPdu[3],
			   const double dPdv[3], double n[3])
{
	v3_cross(n, dPdu, dPdv);
	double d2[3] = { -q->tmax * dPdv[1], q->tmax * dPdv[0], 0.0 }, lim[3];
	v3_cross(lim, d2, dPdv);
	double ll = v3_len(lim);
	if (ll > 0.0 && v3_len(n) <= 1e-6 * ll) {
		double s = v > 0.5 ? -1.0 : 1.0;
		n[0] = s * lim[0], n[1] = s * lim[1], n[2] = s * lim[2];
	}
}

/* Whether x0 + k * period lies in [a, b] for some integer k. */
static bool hits(double a, double b, double x0, double period)
{
	return x0 + ceil((a - x0) / period) * period <= b;
}

/* The ranges of cos and sin over [a, b], a <= b. */
static void trig_range(double a, double b, double cr[2], double sr[2])
{
	if (b - a >= 2.0 * PI_D) {
		cr[0] = sr[0] = -1.0;
		cr[1] = sr[1] = 1.0;
		return;
	}
	double ca = cos(a), cb = cos(b), sa = sin(a), sb = sin(b);
	cr[0] = fmin(ca, cb), cr[1] = fmax(ca, cb);
	sr[0] = fmin(sa, sb), sr[1] = fmax(sa, sb);
	if (hits(a, b, 0.0, 2.0 * PI_D))
		cr[1] = 1.0;
	if (hits(a, b, PI_D, 2.0 * PI_D))
		cr[0] = -1.0;
	if (hits(a, b, 0.5 * PI_D, 2.0 * PI_D))
		sr[1] = 1.0;
	if (hits(a, b, 1.5 * PI_D, 2.0 * PI_D))
		sr[0] = -1.0;
}

static void box_add(double lo[3], double hi[3], const double p[3])
{
	for (int c = 0; c < 3; c++) {
		lo[c] = fmin(lo[c], p[c]);
		hi[c] = fmax(hi[c], p[c]);
	}
}

/* Add the xy box of the points at angles [a, b] and distances [rlo, rhi] from the axis. */
static void sector_box(double a, double b, double rlo, double rhi, double z0, double z1,
		       double lo[3], double hi[3])
{
	double cr[2], sr[2];
	trig_range(a, b, cr, sr);
	double l[3] = { cr[0] < 0.0 ? rhi * cr[0] : rlo * cr[0],
			sr[0] < 0.0 ? rhi * sr[0] : rlo * sr[0], z0 };
	double h[3] = { cr[1] > 0.0 ? rhi * cr[1] : rlo * cr[1],
			sr[1] > 0.0 ? rhi * sr[1] : rlo * sr[1], z1 };
	box_add(lo, hi, l);
	box_add(lo, hi, h);
}

/* A box around the quadric over [u0, u1] x [v0, v1], from the ranges of its profile. */
static void quadric_bound(const struct quadric *q, double u0, double u1, double v0, double v1,
			  double lo[3], double hi[3])
{
	double ta = fmin(u0, u1) * q->tmax, tb = fmax(u0, u1) * q->tmax;
	if (ta > tb) {
		double t = ta;
		ta = tb, tb = t;
	}
	double c0[3], c1[3], dc[3];
	quadric_profile(q, v0, c0, dc);
	quadric_profile(q, v1, c1, dc);
	double zr[2] = { fmin(c0[2], c1[2]), fmax(c0[2], c1[2]) };

	if (q->kind == REYES_HYPERBOLOID) {
		/*
		 * The profile is a segment AB off the xz plane: its distance from
		 * the axis is convex along it, and its angle about the axis moves
		 * monotonically by less than half a turn unless it crosses the axis.
		 */
		double ax = c0[0], ay = c0[1], bx = c1[0], by = c1[1];
		double ra = hypot(ax, ay), rb = hypot(bx, by), rhi = fmax(ra, rb);
		double ex = bx - ax, ey = by - ay, ee = ex * ex + ey * ey;
		double t = ee > 0.0 ? clampd(-(ax * ex + ay * ey) / ee, 0.0, 1.0) : 0.0;
		double rlo = hypot(ax + t * ex, ay + t * ey);
		double alo = 0.0, ahi = 2.0 * PI_D;
		if (rlo > 1e-12 * rhi && ra > 0.0 && rb > 0.0) {
			double a0 = atan2(ay, ax);
			double delta = atan2(ax * by - ay * bx, ax * bx + ay * by);
			alo = a0 + fmin(0.0, delta);
			ahi = a0 + fmax(0.0, delta);
		} else {
			ta = 0.0, tb = 0.0;
		}
		sector_box(ta + alo, tb + ahi, rlo, rhi, zr[0], zr[1], lo, hi);
		return;
	}

	/* Signed distance from the axis (x of the profile) and height ranges. */
	double xr[2], cr[2], sr[2], pa, pb;
	switch (q->kind) {
	case REYES_SPHERE:
	case REYES_TORUS: {
		double ph0 = q->kind == REYES_SPHERE ? q->b : q->c;
		double ph1 = q->kind == REYES_SPHERE ? q->c : q->d;
		pa = ph0 + v0 * (ph1 - ph0);
		pb = ph0 + v1 * (ph1 - ph0);
		trig_range(fmin(pa, pb), fmax(pa, pb), cr, sr);
		double rad = q->kind == REYES_SPHERE ? q->a : q->b;
		double off = q->kind == REYES_SPHERE ? 0.0 : q->a;
		xr[0] = off + fmin(rad * cr[0], rad * cr[1]);
		xr[1] = off + fmax(rad * cr[0], rad * cr[1]);
		zr[0] = fmin(rad * sr[0], rad * sr[1]);
		zr[1] = fmax(rad * sr[0], rad * sr[1]);
		break;
	}
	default:
		/* Linear or monotonic in v: the ends bound it. */
		xr[0] = fmin(c0[0], c1[0]);
		xr[1] = fmax(c0[0], c1[0]);
		break;
	}
	if (xr[1] > 0.0)
		sector_box(ta, tb, fmax(xr[0], 0.0), xr[1], zr[0], zr[1], lo, hi);
	if (xr[0] < 0.0)
		sector_box(ta + PI_D, tb + PI_D, fmax(-xr[1], 0.0), -xr[0], zr[0], zr[1], lo, hi);
	if (xr[1] <= 0.0 && xr[0] >= 0.0) {
		double p[3] = { 0.0, 0.0, zr[0] }, p2[3] = { 0.0, 0.0, zr[1] };
		box_add(lo, hi, p);
		box_add(lo, hi, p2);
	}
}

/* ---- polygon triangulation ---- */

/* A triangle (c[3] == NONE) or planar convex quad of a polygon face. */
struct poly_elem {
	uint32_t face;
	uint32_t c[4];     /* corners: indices into prim->verts, in the face's loop order */
};

/* A node of the ring being triangulated. */
struct pnode {
	double p[3];       /* object space */
	double x, y;       /* in the face's plane */
	uint32_t corner;
	uint32_t prev, next;
	uint32_t cell;          /* grid cell, while on the non-convex lists */
	uint32_t cprev, cnext;  /* neighbours on its cell's list of non-convex nodes */
	uint32_t rprev, rnext;  /* neighbours on the list of all non-convex nodes */
	bool reflex;
};

struct tri_work {
	RL_VEC(struct pnode) nodes;
	RL_VEC(uint32_t) loops;        /* first node and count of each usable loop */
	RL_VEC(struct poly_elem) elems;
	/*
	 * The non-convex nodes (the only ones that can block an ear), bucketed
	 * in a uniform grid over the face so that an ear test looks only near
	 * its triangle: cells[cy * gw + cx] heads a list.
	 */
	RL_VEC(uint32_t) cells;
	uint32_t gw;
	uint32_t rhead, nreflex;       /* all of them, for ears spanning many cells */
	double gx0, gy0, gs;           /* cell of x: (x - gx0) * gs */
	double flat;                   /* twice an area that counts as none */
	uint32_t face;
};

/* Twice the signed area of (a, b, c): positive when counter-clockwise in the plane. */
static double turn(const struct pnode *a, const struct pnode *b, const struct pnode *c)
{
	return (b->x - a->x) * (c->y - a->y) - (b->y - a->y) * (c->x - a->x);
}

static bool same_place(const struct pnode *a, const struct pnode *b)
{
	return a->x == b->x && a->y == b->y;
}

static void emit_tri(struct tri_work *w, uint32_t a, uint32_t b, uint32_t c)
{
	struct pnode *n = w->nodes.data;
	if (turn(&n[a], &n[b], &n[c]) <= w->flat)
		return;
	struct poly_elem e = { w->face, { n[a].corner, n[b].corner, n[c].corner, NONE } };
	rl_vec_push(w->elems, e);
}

static uint32_t grid_coord(const struct tri_work *w, double x, double x0)
{
	double c = (x - x0) * w->gs;
	return c <= 0.0 ? 0 : c >= w->gw - 1 ? w->gw - 1 : (uint32_t)c;
}

static void reflex_add(struct tri_work *w, uint32_t k)
{
	struct pnode *n = w->nodes.data;
	uint32_t cell = grid_coord(w, n[k].y, w->gy0) * w->gw + grid_coord(w, n[k].x, w->gx0);
	n[k].reflex = true;
	n[k].cell = cell;
	n[k].cprev = NONE;
	n[k].cnext = w->cells.data[cell];
	if (n[k].cnext != NONE)
		n[n[k].cnext].cprev = k;
	w->cells.data[cell] = k;
	n[k].rprev = NONE;
	n[k].rnext = w->rhead;
	if (w->rhead != NONE)
		n[w->rhead].rprev = k;
	w->rhead = k;
	w->nreflex++;
}

static void reflex_remove(struct tri_work *w, uint32_t k)
{
	struct pnode *n = w->nodes.data;
	if (n[k].cprev != NONE)
		n[n[k].cprev].cnext = n[k].cnext;
	else
		w->cells.data[n[k].cell] = n[k].cnext;
	if (n[k].cnext != NONE)
		n[n[k].cnext].cprev = n[k].cprev;
	if (n[k].rprev != NONE)
		n[n[k].rprev].rnext = n[k].rnext;
	else
		w->rhead = n[k].rnext;
	if (n[k].rnext != NONE)
		n[n[k].rnext].rprev = n[k].rprev;
	n[k].reflex = false;
	w->nreflex--;
}

/* Keep node @k's convexity and its place on the non-convex lists up to date. */
static void classify(struct tri_work *w, uint32_t k)
{
	struct pnode *n = w->nodes.data;
	bool reflex = turn(&n[n[k].prev], &n[k], &n[n[k].next]) <= w->flat;
	if (reflex && !n[k].reflex)
		reflex_add(w, k);
	else if (!reflex && n[k].reflex)
		reflex_remove(w, k);
}

/* Whether p lies in triangle (a, b, c) or on its edges, in either winding. */
static bool in_triangle(const struct pnode *a, const struct pnode *b, const struct pnode *c,
			const struct pnode *p)
{
	double d1 = turn(a, b, p), d2 = turn(b, c, p), d3 = turn(c, a, p);
	return (d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0) || (d1 <= 0.0 && d2 <= 0.0 && d3 <= 0.0);
}

/* Whether non-convex node @r blocks the ear (a, b, c). */
static bool blocks(const struct pnode *a, const struct pnode *b, const struct pnode *c,
		   const struct pnode *r)
{
	return !same_place(r, a) && !same_place(r, b) && !same_place(r, c) &&
	       in_triangle(a, b, c, r);
}

static bool is_ear(const struct tri_work *w, uint32_t k)
{
	const struct pnode *n = w->nodes.data;
	if (n[k].reflex)
		return false;
	const struct pnode *a = &n[n[k].prev], *b = &n[k], *c = &n[n[k].next];
	uint32_t x0 = grid_coord(w, fmin(a->x, fmin(b->x, c->x)), w->gx0);
	uint32_t x1 = grid_coord(w, fmax(a->x, fmax(b->x, c->x)), w->gx0);
	uint32_t y0 = grid_coord(w, fmin(a->y, fmin(b->y, c->y)), w->gy0);
	uint32_t y1 = grid_coord(w, fmax(a->y, fmax(b->y, c->y)), w->gy0);
	if ((uint64_t)(x1 - x0 + 1) * (y1 - y0 + 1) > w->nreflex) {
		for (uint32_t r = w->rhead; r != NONE; r = n[r].rnext)
			if (blocks(a, b, c, &n[r]))
				return false;
		return true;
	}
	for (uint32_t cy = y0; cy <= y1; cy++)
		for (uint32_t cx = x0; cx <= x1; cx++)
			for (uint32_t r = w->cells.data[cy * w->gw + cx]; r != NONE; r = n[r].cnext)
				if (blocks(a, b, c, &n[r]))
					return false;
	return true;
}

/* Take node @k out of the ring; returns its successor. */
static uint32_t unlink_node(struct tri_work *w, uint32_t k)
{
	struct pnode *n = w->nodes.data;
	uint32_t p = n[k].prev, q = n[k].next;
	n[p].next = q;
	n[q].prev = p;
	if (n[k].reflex)
		reflex_remove(w, k);
	classify(w, p);
	classify(w, q);
	return q;
}

/*
 * Ear clipping of the ring through @head (counter-clockwise in the plane).
 * An ear is a convex corner whose triangle holds no non-convex node. When a
 * whole turn finds none (a degenerate or self-intersecting outline), a flat
 * corner is dropped, or failing that a convex one (or any) is clipped, so the
 * loop always ends. Ear tests look only at the grid cells under the ear
 * (or at the whole list, when that is shorter): about linear in the face's
 * size for ordinary faces, O(n^1.5) for spiky stars of long slivers.
 */
static void ear_clip(struct tri_work *w, uint32_t head, uint32_t count)
{
	struct pnode *n = w->nodes.data;
	double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
	uint32_t k = head;
	for (uint32_t i = 0; i < count; i++, k = n[k].next) {
		n[k].reflex = false;
		x0 = fmin(x0, n[k].x), x1 = fmax(x1, n[k].x);
		y0 = fmin(y0, n[k].y), y1 = fmax(y1, n[k].y);
	}
	/* About one node per cell. */
	w->gw = (uint32_t)sqrt((double)count);
	w->gw = w->gw < 1 ? 1 : w->gw > 1024 ? 1024 : w->gw;
	double span = fmax(x1 - x0, y1 - y0);
	w->gx0 = x0, w->gy0 = y0;
	w->gs = span > 0.0 ? w->gw / span : 0.0;
	w->cells.len = 0;
	rl_vec_reserve(w->cells, (size_t)w->gw * w->gw);
	for (size_t i = 0; i < (size_t)w->gw * w->gw; i++)
		w->cells.data[i] = NONE;
	w->cells.len = (size_t)w->gw * w->gw;
	w->rhead = NONE;
	w->nreflex = 0;
	for (uint32_t i = 0; i < count; i++, k = n[k].next)
		classify(w, k);

	uint32_t cur = head, stall = 0;
	while (count > 3) {
		n = w->nodes.data;
		if (is_ear(w, cur)) {
			emit_tri(w, n[cur].prev, cur, n[cur].next);
			/* Moving on past the next corner makes fewer fans of slivers. */
			cur = n[unlink_node(w, cur)].next;
			count--;
			stall = 0;
			continue;
		}
		cur = n[cur].next;
		if (++stall < count)
			continue;
		uint32_t pick = NONE, k2 = cur;
		for (uint32_t i = 0; i < count && pick == NONE; i++, k2 = n[k2].next)
			if (fabs(turn(&n[n[k2].prev], &n[k2], &n[n[k2].next])) <= w->flat)
				pick = k2;
		if (pick == NONE) {
			k2 = cur;
			for (uint32_t i = 0; i < count && pick == NONE; i++, k2 = n[k2].next)
				if (!n[k2].reflex)
					pick = k2;
			if (pick == NONE)
				pick = cur;
			emit_tri(w, n[pick].prev, pick, n[pick].next);
		}
		cur = unlink_node(w, pick);
		count--;
		stall = 0;
	}
	if (count == 3)
		emit_tri(w, n[cur].prev, cur, n[cur].next);
}

/* Is direction (dx, dy) from node k inside the polygon's angle at k? */
static bool in_wedge(const struct pnode *n, uint32_t k, double dx, double dy)
{
	const struct pnode *a = &n[n[k].prev], *b = &n[k], *c = &n[n[k].next];
	double px = a->x - b->x, py = a->y - b->y, qx = c->x - b->x, qy = c->y - b->y;
	if (turn(a, b, c) >= 0.0)
		return qx * dy - qy * dx > 0.0 && dx * py - dy * px > 0.0;
	return !(px * dy - py * dx >= 0.0 && dx * qy - dy * qx >= 0.0);
}

/*
 * The node of the outer ring (through @head) to bridge hole node @m to: cast
 * a ray from m along +x, take the nearest edge it crosses and that edge's
 * endpoint further along x; a non-convex node inside the triangle (m, hit,
 * endpoint) would hide it, and then the one closest in angle to the ray is
 * taken instead. Without a hit (a hole outside the outline) the nearest node.
 */
static uint32_t find_bridge(const struct tri_work *w, uint32_t head, uint32_t m)
{
	const struct pnode *n = w->nodes.data;
	double mx = n[m].x, my = n[m].y, best = INFINITY;
	uint32_t cand = NONE, k = head;
	bool at_vertex = false;
	do {
		const struct pnode *a = &n[k], *b = &n[n[k].next];
		if (a->y <= my && my <= b->y && a->y < b->y) {
			double x = a->x + (my - a->y) * (b->x - a->x) / (b->y - a->y);
			if (x >= mx && x < best) {
				best = x;
				at_vertex = true;
				if (x == a->x && my == a->y)
					cand = k;
				else if (x == b->x && my == b->y)
					cand = n[k].next;
				else {
					at_vertex = false;
					if (a->x != b->x)
						cand = a->x > b->x ? k : n[k].next;
					else
						cand = fabs(a->y - my) <= fabs(b->y - my) ? k : n[k].next;
				}
			}
		}
		k = n[k].next;
	} while (k != head);

	if (cand == NONE) {
		double bd = INFINITY;
		k = head;
		do {
			double d = hypot(n[k].x - mx, n[k].y - my);
			if (d < bd)
				bd = d, cand = k;
			k = n[k].next;
		} while (k != head);
		return cand;
	}
	if (!at_vertex) {
		struct pnode hit = { .x = best, .y = my };
		double bang = INFINITY, bdist = INFINITY;
		uint32_t chosen = cand;
		k = head;
		do {
			const struct pnode *r = &n[k];
			if (k != cand && turn(&n[r->prev], r, &n[r->next]) < 0.0 &&
			    in_triangle(&n[m], &hit, &n[cand], r) && !same_place(r, &n[m])) {
				double ang = atan2(fabs(r->y - my), r->x - mx);
				double d = hypot(r->x - mx, r->y - my);
				if (ang < bang || (ang == bang && d < bdist))
					bang = ang, bdist = d, chosen = k;
			}
			k = n[k].next;
		} while (k != head);
		cand = chosen;
	}
	/* Earlier bridges leave copies of a node: take the copy whose angle sees m. */
	k = head;
	do {
		if (same_place(&n[k], &n[cand]) &&
		    in_wedge(n, k, mx - n[k].x, my - n[k].y))
			return k;
		k = n[k].next;
	} while (k != head);
	return cand;
}

static uint32_t copy_node(struct tri_work *w, uint32_t k)
{
	struct pnode c = w->nodes.data[k];
	rl_vec_push(w->nodes, c);
	return (uint32_t)(w->nodes.len - 1);
}

/* Link nodes [first, first + count) into a ring, in order or reversed. */
static void make_ring(struct tri_work *w, uint32_t first, uint32_t count, bool reverse)
{
	struct pnode *n = w->nodes.data;
	for (uint32_t i = 0; i < count; i++) {
		uint32_t k = first + i;
		uint32_t nx = first + (i + 1) % count, pv = first + (i + count - 1) % count;
		n[k].next = reverse ? pv : nx;
		n[k].prev = reverse ? nx : pv;
	}
}

static double loop_area2(const struct tri_work *w, uint32_t first, uint32_t count)
{
	const struct pnode *n = w->nodes.data;
	double a = 0.0;
	for (uint32_t i = 0; i < count; i++) {
		const struct pnode *p = &n[first + i], *q = &n[first + (i + 1) % count];
		a += p->x * q->y - q->x * p->y;
	}
	return a;
}

struct hole {
	uint32_t first, count, right;  /* right: the node furthest along +x */
	double rx;
};

static int hole_cmp(const void *pa, const void *pb)
{
	const struct hole *a = pa, *b = pb;
	return a->rx < b->rx ? 1 : a->rx > b->rx ? -1 : 0;
}

/*
 * Triangulate the face whose loops were gathered into w->nodes/w->loops
 * (outline first), appending elements to w->elems.
 */
static void triangulate_face(struct tri_work *w)
{
	uint32_t nloops = (uint32_t)(w->loops.len / 2);
	if (nloops == 0 || w->loops.data[0] != 0)
		return;
	struct pnode *n = w->nodes.data;
	uint32_t ocount = w->loops.data[1];

	double lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
	for (size_t k = 0; k < w->nodes.len; k++)
		box_add(lo, hi, n[k].p);
	double ext[3];
	v3_sub(ext, hi, lo);
	double diag = v3_len(ext);
	if (!(diag > 0.0) || !isfinite(diag))
		return;

	/* Newell's normal of the outline: twice its vector area. */
	double N[3] = { 0.0, 0.0, 0.0 };
	for (uint32_t i = 0; i < ocount; i++) {
		const double *p = n[i].p, *q = n[(i + 1) % ocount].p;
		N[0] += (p[1] - q[1]) * (p[2] + q[2]);
		N[1] += (p[2] - q[2]) * (p[0] + q[0]);
		N[2] += (p[0] - q[0]) * (p[1] + q[1]);
	}
	double nl = v3_len(N);
	w->flat = 1e-12 * diag * diag;
	if (!(nl > w->flat))
		return;
	double nh[3] = { N[0] / nl, N[1] / nl, N[2] / nl };

	/* A basis (e1, e2) of the plane with e1 ^ e2 = n: the outline is counter-clockwise. */
	int ax = fabs(nh[0]) <= fabs(nh[1]) && fabs(nh[0]) <= fabs(nh[2]) ? 0 :
		 fabs(nh[1]) <= fabs(nh[2]) ? 1 : 2;
	double e1[3] = { 0.0, 0.0, 0.0 }, e2[3];
	e1[ax] = 1.0;
	double d = v3_dot(e1, nh);
	for (int c = 0; c < 3; c++)
		e1[c] -= d * nh[c];
	double l1 = v3_len(e1);
	for (int c = 0; c < 3; c++)
		e1[c] /= l1;
	v3_cross(e2, nh, e1);
	for (size_t k = 0; k < w->nodes.len; k++) {
		double rel[3];
		v3_sub(rel, n[k].p, n[0].p);
		n[k].x = v3_dot(rel, e1);
		n[k].y = v3_dot(rel, e2);
	}

	/* Holes with an area, wound clockwise. */
	RL_VEC(struct hole) holes = { 0 };
	for (uint32_t l = 1; l < nloops; l++) {
		uint32_t first = w->loops.data[2 * l], count = w->loops.data[2 * l + 1];
		double a2 = loop_area2(w, first, count);
		if (fabs(a2) <= w->flat)
			continue;
		make_ring(w, first, count, a2 > 0.0);
		struct hole h = { first, count, first, n[first].x };
		for (uint32_t i = 1; i < count; i++)
			if (n[first + i].x > h.rx)
				h.rx = n[first + i].x, h.right = first + i;
		rl_vec_push(holes, h);
	}
	make_ring(w, 0, ocount, false);

	if (holes.len == 0 && ocount == 3) {
		struct poly_elem e = { w->face, { n[0].corner, n[1].corner, n[2].corner, NONE } };
		rl_vec_push(w->elems, e);
		return;
	}
	if (holes.len == 0 && ocount == 4) {
		bool quad = true;
		for (uint32_t i = 0; i < 4 && quad; i++) {
			double off[3];
			v3_sub(off, n[i].p, n[0].p);
			quad = turn(&n[(i + 3) % 4], &n[i], &n[(i + 1) % 4]) > 1e-9 * diag * diag &&
			       fabs(v3_dot(off, nh)) <= 1e-6 * diag;
		}
		if (quad) {
			struct poly_elem e = { w->face,
					       { n[0].corner, n[1].corner, n[2].corner, n[3].corner } };
			rl_vec_push(w->elems, e);
			return;
		}
	}

	/* Bridge the holes in, rightmost first, then clip ears. */
	if (holes.len > 1)
		qsort(holes.data, holes.len, sizeof(*holes.data), hole_cmp);
	uint32_t count = ocount;
	for (size_t h = 0; h < holes.len; h++) {
		uint32_t m = holes.data[h].right;
		uint32_t p = find_bridge(w, 0, m);
		uint32_t m2 = copy_node(w, m), p2 = copy_node(w, p);
		n = w->nodes.data;
		uint32_t pn = n[p].next, mp = n[m].prev;
		n[p].next = m, n[m].prev = p;
		n[mp].next = m2, n[m2].prev = mp;
		n[m2].next = p2, n[p2].prev = m2;
		n[p2].next = pn, n[pn].prev = p2;
		count += holes.data[h].count + 2;
	}
	rl_vec_free(holes);
	ear_clip(w, 0, count);
}

/* ---- the triangulation cache ---- */

/* A primitive's triangulation, and what it was made from. */
struct poly_mesh {
	const struct reyes_prim *prim;
	uint32_t nfaces, npoints;
	const uint32_t *nloops, *nverts, *verts;
	const float *P;
	struct poly_elem *elems;
	size_t nelems;
	uint32_t refs;       /* users holding it */
	bool dead;           /* out of the table; freed by its last user */
	uint64_t stamp;      /* last use, for eviction */
	struct poly_mesh *chain;
};

/* Beyond this many bytes of triangulations, the least recently used go. */
#define CACHE_LIMIT ((size_t)256 << 20)

static struct {
	pthread_mutex_t lock;
	struct poly_mesh **buckets;
	size_t nbuckets, count, bytes;
	uint64_t clock;
} cache = { .lock = PTHREAD_MUTEX_INITIALIZER };

static size_t mesh_bytes(const struct poly_mesh *m)
{
	return sizeof(*m) + m->nelems * sizeof(*m->elems);
}

static void mesh_free(struct poly_mesh *m)
{
	if (m) {
		free(m->elems);
		free(m);
	}
}

static bool mesh_current(const struct poly_mesh *m, const struct reyes_prim *p)
{
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	return m->prim == p && m->nfaces == p->nfaces && m->npoints == p->npoints &&
	       m->nloops == p->nloops && m->nverts == p->nverts && m->verts == p->verts &&
	       m->P == (P ? P->values : NULL);
}

static size_t bucket_of(const struct reyes_prim *p)
{
	uint64_t h = (uint64_t)(uintptr_t)p;
	h ^= h >> 33;
	h *= 0xff51afd7ed558ccdull;
	h ^= h >> 33;
	return (size_t)(h & (cache.nbuckets - 1));
}

/* Lock held. */
static struct poly_mesh *cache_find(const struct reyes_prim *p)
{
	if (!cache.nbuckets)
		return NULL;
	for (struct poly_mesh *m = cache.buckets[bucket_of(p)]; m; m = m->chain)
		if (m->prim == p)
			return m;
	return NULL;
}

/* Lock held: take @m out of the table, freeing it unless someone uses it. */
static void cache_remove(struct poly_mesh *m)
{
	struct poly_mesh **pp = &cache.buckets[bucket_of(m->prim)];
	while (*pp != m)
		pp = &(*pp)->chain;
	*pp = m->chain;
	cache.count--;
	cache.bytes -= mesh_bytes(m);
	if (m->refs)
		m->dead = true;
	else
		mesh_free(m);
}

/* Lock held: add @m (whose key is not in the table), then evict down to the limit. */
static void cache_insert(struct poly_mesh *m)
{
	if (cache.count + 1 > cache.nbuckets) {
		size_t nb = cache.nbuckets ? cache.nbuckets * 2 : 64;
		struct poly_mesh **b = calloc(nb, sizeof(*b));
		if (b) {
			struct poly_mesh **old = cache.buckets;
			size_t onb = cache.nbuckets;
			cache.buckets = b;
			cache.nbuckets = nb;
			for (size_t i = 0; i < onb; i++)
				for (struct poly_mesh *e = old[i], *nx; e; e = nx) {
					nx = e->chain;
					size_t at = bucket_of(e->prim);
					e->chain = cache.buckets[at];
					cache.buckets[at] = e;
				}
			free(old);
		}
	}
	if (!cache.nbuckets) {
		/* No table at all (memory ran out): the caller keeps a private copy. */
		m->dead = true;
		return;
	}
	size_t at = bucket_of(m->prim);
	m->chain = cache.buckets[at];
	cache.buckets[at] = m;
	cache.count++;
	cache.bytes += mesh_bytes(m);
	m->stamp = ++cache.clock;
	while (cache.bytes > CACHE_LIMIT) {
		struct poly_mesh *old = NULL;
		for (size_t i = 0; i < cache.nbuckets; i++)
			for (struct poly_mesh *e = cache.buckets[i]; e; e = e->chain)
				if (e != m && !e->refs && (!old || e->stamp < old->stamp))
					old = e;
		if (!old)
			break;
		cache_remove(old);
	}
}

/*
 * Triangulate every face of @p. NULL for input that cannot be triangulated
 * (with *why set): missing arrays, vertex indices out of range, too many
 * pieces, non-finite points, or memory.
 */
static struct poly_mesh *mesh_build(const struct reyes_prim *p, const char **why)
{
	const struct reyes_primvar *P = points_var(p, p->npoints);
	*why = NULL;
	if (!P) {
		*why = "no \"P\" with a point per vertex";
		return NULL;
	}
	if (p->nfaces && (!p->nloops || !p->nverts || !p->verts)) {
		*why = "face arrays missing";
		return NULL;
	}
	struct tri_work w = { 0 };
	uint64_t loop = 0, corner = 0;
	for (uint32_t f = 0; f < p->nfaces && !*why; f++) {
		w.nodes.len = 0;
		w.loops.len = 0;
		w.face = f;
		for (uint32_t l = 0; l < p->nloops[f]; l++, loop++) {
			uint32_t nv = p->nverts[loop], first = (uint32_t)w.nodes.len;
			for (uint32_t i = 0; i < nv; i++, corner++) {
				uint32_t vi = p->verts[corner];
				if (vi >= p->npoints || corner >= NONE) {
					*why = "vertex index out of range";
					break;
				}
				struct pnode nd = { .corner = (uint32_t)corner };
				for (int c = 0; c < 3; c++) {
					nd.p[c] = P->values[(size_t)vi * 3 + c];
					if (!isfinite(nd.p[c]) ||
					    (P->values1 && !isfinite(P->values1[(size_t)vi * 3 + c])))
						*why = "a point is not finite";
				}
				/* Coincident neighbours make zero-length edges: keep the first. */
				if (w.nodes.len > first) {
					const double *q = w.nodes.data[w.nodes.len - 1].p;
					if (q[0] == nd.p[0] && q[1] == nd.p[1] && q[2] == nd.p[2])
						continue;
				}
				rl_vec_push(w.nodes, nd);
			}
			if (*why)
				break;
			uint32_t count = (uint32_t)w.nodes.len - first;
			while (count > 1) {
				const double *a = w.nodes.data[first].p, *b = w.nodes.data[first + count - 1].p;
				if (a[0] != b[0] || a[1] != b[1] || a[2] != b[2])
					break;
				count--;
			}
			w.nodes.len = first + count;
			if (count < 3) {
				w.nodes.len = first;
				if (l == 0) {
					/* No outline: nothing of this face is drawn. */
					w.loops.len = 0;
				}
				continue;
			}
			if (l > 0 && w.loops.len == 0) {
				w.nodes.len = first;
				continue;
			}
			rl_vec_push(w.loops, first);
			rl_vec_push(w.loops, count);
		}
		if (!*why && w.loops.len)
			triangulate_face(&w);
		if (w.elems.len >= (size_t)1 << 30)
			*why = "too many polygons";
	}
	rl_vec_free(w.nodes);
	rl_vec_free(w.loops);
	rl_vec_free(w.cells);
	if (*why) {
		rl_vec_free(w.elems);
		return NULL;
	}
	struct poly_mesh *m = calloc(1, sizeof(*m));
	if (!m) {
		rl_vec_free(w.elems);
		*why = "out of memory";
		return NULL;
	}
	m->prim = p;
	m->nfaces = p->nfaces;
	m->npoints = p->npoints;
	m->nloops = p->nloops;
	m->nverts = p->nverts;
	m->verts = p->verts;
	m->P = P->values;
	m->elems = w.elems.data;
	m->nelems = w.elems.len;
	return m;
}

/*
 * Put a freshly built @m in the table, unless an identical entry is there
 * (then @m is freed and that one returned). Takes a reference if @ref.
 */
static struct poly_mesh *mesh_install(struct poly_mesh *m, bool ref)
{
	pthread_mutex_lock(&cache.lock);
	struct poly_mesh *old = cache_find(m->prim);
	if (old && mesh_current(old, m->prim) && old->nelems == m->nelems &&
	    (m->nelems == 0 || memcmp(old->elems, m->elems, m->nelems * sizeof(*m->elems)) == 0)) {
		mesh_free(m);
		m = old;
		m->stamp = ++cache.clock;
	} else {
		if (old)
			cache_remove(old);
		cache_insert(m);
	}
	if (ref)
		m->refs++;
	pthread_mutex_unlock(&cache.lock);
	return m;
}

/* The triangulation of @p, held until mesh_release; NULL if it cannot be made. */
static struct poly_mesh *mesh_acquire(const struct reyes_prim *p)
{
	pthread_mutex_lock(&cache.lock);
	struct poly_mesh *m = cache_find(p);
	if (m && mesh_current(m, p)) {
		m->refs++;
		m->stamp = ++cache.clock;
		pthread_mutex_unlock(&cache.lock);
		return m;
	}
	pthread_mutex_unlock(&cache.lock);
	const char *why;
	m = mesh_build(p, &why);
	return m ? mesh_install(m, true) : NULL;
}

static void mesh_release(struct poly_mesh *m)
{
	pthread_mutex_lock(&cache.lock);
	bool gone = --m->refs == 0 && m->dead;
	pthread_mutex_unlock(&cache.lock);
	if (gone)
		mesh_free(m);
}

/* ---- patch meshes ---- */

/* Cells of a patch mesh along u and v; false if the mesh cannot be diced. */
static bool patch_cells(const struct reyes_prim *p, uint32_t *ncu, uint32_t *ncv)
{
	uint32_t n[2] = { p->nu, p->nv }, step[2] = { p->ustep, p->vstep }, cells[2];
	bool per[2] = { p->uperiodic, p->vperiodic };
	for (int d = 0; d < 2; d++) {
		if (!p->bicubic) {
			if (n[d] < 2)
				return false;
			cells[d] = per[d] ? n[d] : n[d] - 1;
		} else {
			if (step[d] < 1)
				return false;
			if (per[d]) {
				if (n[d] < step[d])
					return false;
				cells[d] = n[d] / step[d];
			} else {
				if (n[d] < 4)
					return false;
				cells[d] = (n[d] - 4) / step[d] + 1;
			}
		}
	}
	if ((uint64_t)cells[0] * cells[1] > NONE || (uint64_t)n[0] * n[1] > NONE)
		return false;
	*ncu = cells[0];
	*ncv = cells[1];
	return true;
}

/* The Bezier basis' inverse: power-basis coefficients (t^3..1) to Bezier control points. */
static const double bezier_inverse[16] = {
	0.0, 0.0, 0.0, 1.0,
	0.0, 0.0, 1.0 / 3.0, 1.0,
	0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0,
	1.0, 1.0, 1.0, 1.0,
};

static void m4_mul(double r[16], const double a[16], const double b[16])
{
	double t[16];
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++) {
			double s = 0.0;
			for (int k = 0; k < 4; k++)
				s += a[i * 4 + k] * b[k * 4 + j];
			t[i * 4 + j] = s;
		}
	memcpy(r, t, sizeof(t));
}

/*
 * Rows: the Bezier control points of the curve T(t) B G restricted to
 * t in [a, b], as combinations of G. With t = a + h s, T(t) = T(s) R, so the
 * curve is T(s) Bz (Bz^-1 R B) G.
 */
static void bezier_of(const double basis[16], double a, double b, double m[16])
{
	double h = b - a;
	double R[16] = {
		h * h * h, 0.0, 0.0, 0.0,
		3.0 * a * h * h, h * h, 0.0, 0.0,
		3.0 * a * a * h, 2.0 * a * h, h, 0.0,
		a * a * a, a * a, a, 1.0,
	};
	m4_mul(m, R, basis);
	m4_mul(m, bezier_inverse, m);
}

/* Basis weights of the four control values at t, and their derivatives. */
static void basis_weights(const double B[16], double t, double w[4], double dw[4])
{
	double T[4] = { t * t * t, t * t, t, 1.0 }, dT[4] = { 3.0 * t * t, 2.0 * t, 1.0, 0.0 };
	for (int k = 0; k < 4; k++) {
		w[k] = dw[k] = 0.0;
		for (int r = 0; r < 4; r++) {
			w[k] += T[r] * B[r * 4 + k];
			dw[k] += dT[r] * B[r * 4 + k];
		}
	}
}

/* ---- pieces ---- */

enum piece_kind { PIECE_QUADRIC, PIECE_BILINEAR, PIECE_BICUBIC };

/*
 * What bounding and dicing need of a piece. Bilinear data (and varying,
 * facevarying data everywhere) comes from the values at four corners
 * k = (0,0) (1,0) (0,1) (1,1), each a weighted sum of up to four source
 * items: corner k = sum_i w[k][i] item(src i).
 */
struct piece {
	enum piece_kind kind;
	struct quadric q[2];        /* a quadric at shutter open and close */
	int qshape;                 /* which of them gives derivatives and normals */
	bool qmoving;
	const float *P[2];          /* vertex positions at shutter open and close */
	uint32_t nsrc;
	uint32_t vtx[4], vary[4], fvary[4];  /* source item of each class */
	double w[4][4];
	uint32_t uniform;
	uint32_t cp[16];            /* bicubic: control point at u index k, v index l: cp[l * 4 + k] */
	double bu[16], bv[16];      /* bicubic bases */
	double uoff, uscale, voff, vscale;  /* primitive u = uoff + uscale * piece-local u */
	bool height;                /* a height field: x, y are the primitive's u, v */
};

static void identity_weights(struct piece *pc)
{
	memset(pc->w, 0, sizeof(pc->w));
	for (int k = 0; k < 4; k++)
		pc->w[k][k] = 1.0;
	pc->nsrc = 4;
}

static bool setup_polygon(const struct reyes_patch *pa, struct piece *pc)
{
	const struct reyes_prim *p = pa->prim;
	struct poly_mesh *m = mesh_acquire(p);
	if (!m)
		return false;
	uint32_t e = pa->piece / 4, sub = pa->piece % 4;
	bool ok = e < m->nelems;
	struct poly_elem el;
	if (ok) {
		el = m->elems[e];
		ok = el.c[3] == NONE ? sub < 3 : sub == 0;
	}
	mesh_release(m);
	if (!ok)
		return false;
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	pc->kind = PIECE_BILINEAR;
	pc->P[0] = P->values;
	pc->P[1] = P->values1 ? P->values1 : P->values;
	pc->uniform = el.face;
	pc->uoff = pc->voff = 0.0;
	pc->uscale = pc->vscale = 1.0;
	memset(pc->w, 0, sizeof(pc->w));
	if (el.c[3] == NONE) {
		/* One third of the triangle: corner, edge midpoint, centroid, edge midpoint. */
		pc->nsrc = 3;
		for (uint32_t i = 0; i < 3; i++)
			pc->fvary[i] = el.c[(sub + i) % 3];
		pc->w[0][0] = 1.0;
		pc->w[1][0] = pc->w[1][1] = 0.5;
		pc->w[2][0] = pc->w[2][2] = 0.5;
		pc->w[3][0] = pc->w[3][1] = pc->w[3][2] = 1.0 / 3.0;
	} else {
		/* P00 P10 P11 P01 = v0 v1 v2 v3. */
		pc->nsrc = 4;
		for (uint32_t i = 0; i < 4; i++)
			pc->fvary[i] = el.c[i];
		pc->w[0][0] = pc->w[1][1] = pc->w[2][3] = pc->w[3][2] = 1.0;
	}
	for (uint32_t i = 0; i < pc->nsrc; i++)
		pc->vtx[i] = pc->vary[i] = p->verts[pc->fvary[i]];
	return true;
}

static bool setup_patch(const struct reyes_patch *pa, struct piece *pc)
{
	const struct reyes_prim *p = pa->prim;
	uint32_t ncu, ncv;
	if (!patch_cells(p, &ncu, &ncv) || pa->piece >= ncu * ncv)
		return false;
	const struct reyes_primvar *P = points_var(p, (uint64_t)p->nu * p->nv);
	if (!P)
		return false;
	uint32_t cu = pa->piece % ncu, cv = pa->piece / ncu;
	pc->P[0] = P->values;
	pc->P[1] = P->values1 ? P->values1 : P->values;
	pc->uniform = pa->piece;
	pc->height = p->heightfield;
	pc->uoff = (double)cu / ncu, pc->uscale = 1.0 / ncu;
	pc->voff = (double)cv / ncv, pc->vscale = 1.0 / ncv;
	identity_weights(pc);
	uint32_t du[2] = { cu, (cu + 1) % p->nu }, dv[2] = { cv, (cv + 1) % p->nv };
	if (!p->bicubic) {
		pc->kind = PIECE_BILINEAR;
		for (int k = 0; k < 4; k++)
			pc->vtx[k] = dv[k / 2] * p->nu + du[k % 2];
		memcpy(pc->vary, pc->vtx, sizeof(pc->vtx));
		memcpy(pc->fvary, pc->vtx, sizeof(pc->vtx));
		return true;
	}
	pc->kind = PIECE_BICUBIC;
	for (int i = 0; i < 16; i++) {
		pc->bu[i] = p->ubasis[i];
		pc->bv[i] = p->vbasis[i];
		if (!isfinite(pc->bu[i]) || !isfinite(pc->bv[i]))
			return false;
	}
	for (uint32_t l = 0; l < 4; l++)
		for (uint32_t k = 0; k < 4; k++) {
			uint32_t iu = (cu * p->ustep + k) % p->nu, iv = (cv * p->vstep + l) % p->nv;
			pc->cp[l * 4 + k] = iv * p->nu + iu;
		}
	/* Varying data sits at the segment ends: (ncu + 1) x (ncv + 1), or wrapped. */
	uint32_t nvu = p->uperiodic ? ncu : ncu + 1, nvv = p->vperiodic ? ncv : ncv + 1;
	uint32_t su[2] = { cu, (cu + 1) % nvu }, sv[2] = { cv, (cv + 1) % nvv };
	for (int k = 0; k < 4; k++) {
		pc->vtx[k] = pc->cp[(k / 2) * 12 + (k % 2) * 3];
		pc->vary[k] = pc->fvary[k] = sv[k / 2] * nvu + su[k % 2];
	}
	return true;
}

static bool setup_piece(const struct reyes_patch *pa, struct piece *pc)
{
	memset(pc, 0, sizeof(*pc));
	if (!pa || !pa->prim)
		return false;
	const struct reyes_prim *p = pa->prim;
	switch (p->kind) {
	case REYES_POLYGONS:
		return setup_polygon(pa, pc);
	case REYES_PATCHES:
		return setup_patch(pa, pc);
	default:
		if (pa->piece != 0 || !quadric_setup(p, pc->q, &pc->qshape))
			return false;
		pc->kind = PIECE_QUADRIC;
		pc->qmoving = p->qmoving;
		identity_weights(pc);
		for (uint32_t k = 0; k < 4; k++)
			pc->vtx[k] = pc->vary[k] = pc->fvary[k] = k;
		pc->uscale = pc->vscale = 1.0;
		return true;
	}
}

/* The four corner positions of a bilinear piece from @vals. */
static void bilinear_corners(const struct piece *pc, const float *vals, double Q[4][3])
{
	for (int k = 0; k < 4; k++)
		for (int c = 0; c < 3; c++) {
			double s = 0.0;
			for (uint32_t i = 0; i < pc->nsrc; i++)
				if (pc->w[k][i] != 0.0)
					s += pc->w[k][i] * vals[(size_t)pc->vtx[i] * 3 + c];
			Q[k][c] = s;
		}
}

/* Position and piece-local derivatives of a bilinear piece at local (s, t). */
static void bilinear_eval(const double Q[4][3], double s, double t, double P[3], double dPds[3],
			  double dPdt[3])
{
	for (int c = 0; c < 3; c++) {
		P[c] = (1 - s) * (1 - t) * Q[0][c] + s * (1 - t) * Q[1][c] + (1 - s) * t * Q[2][c] +
		       s * t * Q[3][c];
		dPds[c] = (1 - t) * (Q[1][c] - Q[0][c]) + t * (Q[3][c] - Q[2][c]);
		dPdt[c] = (1 - s) * (Q[2][c] - Q[0][c]) + s * (Q[3][c] - Q[1][c]);
	}
}

/* Position and piece-local derivatives of a bicubic piece at local (s, t). */
static void bicubic_eval(const struct piece *pc, const float *vals, double s, double t,
			 double P[3], double dPds[3], double dPdt[3])
{
	double wu[4], dwu[4], wv[4], dwv[4];
	basis_weights(pc->bu, s, wu, dwu);
	basis_weights(pc->bv, t, wv, dwv);
	for (int c = 0; c < 3; c++)
		P[c] = dPds[c] = dPdt[c] = 0.0;
	for (int l = 0; l < 4; l++)
		for (int k = 0; k < 4; k++) {
			const float *g = &vals[(size_t)pc->cp[l * 4 + k] * 3];
			for (int c = 0; c < 3; c++) {
				P[c] += wu[k] * wv[l] * g[c];
				dPds[c] += dwu[k] * wv[l] * g[c];
				dPdt[c] += wu[k] * dwv[l] * g[c];
			}
		}
}

bool reyes_prim_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
		       size_t *cap)
{
	if (!p || !out || !n || !cap)
		return false;
	if (p->kind == REYES_NUPATCH)
		return reyes_nurbs_pieces(p, out, n, cap);
	size_t count = 0;
	struct poly_mesh *m = NULL;
	uint32_t ncu = 0, ncv = 0;
	struct quadric q[2];
	int shape;
	switch (p->kind) {
	case REYES_SUBDIV:
		return reyes_subdiv_pieces(p, out, n, cap);
	case REYES_POLYGONS: {
		const char *why;
		m = mesh_build(p, &why);
		if (!m) {
			rl_log(RL_LOG_ERROR, "primitive %u (polygons): %s", p->id, why);
			return false;
		}
		for (size_t e = 0; e < m->nelems; e++)
			count += m->elems[e].c[3] == NONE ? 3 : 1;
		break;
	}
	case REYES_PATCHES:
		if (!patch_cells(p, &ncu, &ncv)) {
			rl_log(RL_LOG_ERROR, "primitive %u (patch mesh %ux%u): no cells to dice",
			       p->id, p->nu, p->nv);
			return false;
		}
		const struct reyes_primvar *P = points_var(p, (uint64_t)p->nu * p->nv);
		if (!P) {
			rl_log(RL_LOG_ERROR, "primitive %u (patch mesh): \"P\" needs %u points",
			       p->id, p->nu * p->nv);
			return false;
		}
		for (size_t i = 0; i < 3 * (size_t)p->nu * p->nv; i++)
			if (!isfinite(P->values[i]) || (P->values1 && !isfinite(P->values1[i]))) {
				rl_log(RL_LOG_ERROR, "primitive %u (patch mesh): a point is not finite",
				       p->id);
				return false;
			}
		count = (size_t)ncu * ncv;
		break;
	case REYES_CURVES:
	case REYES_POINTS:
		if (!reyes_curves_count(p, &count))
			return false;
		break;
	default:
		count = quadric_setup(p, q, &shape) ? 1 : 0;
		break;
	}
	if (*n + count > *cap) {
		size_t nc = *cap ? *cap : 16;
		while (nc < *n + count)
			nc *= 2;
		*out = rl_xrealloc(*out, nc * sizeof(**out));
		*cap = nc;
	}
	struct reyes_patch base = { .prim = p, .u0 = 0.0f, .u1 = 1.0f, .v0 = 0.0f, .v1 = 1.0f };
	if (m) {
		for (size_t e = 0; e < m->nelems; e++)
			for (uint32_t s = 0; s < (m->elems[e].c[3] == NONE ? 3u : 1u); s++) {
				base.piece = (uint32_t)(e * 4 + s);
				(*out)[(*n)++] = base;
			}
		mesh_install(m, false);
	} else {
		for (size_t i = 0; i < count; i++) {
			base.piece = (uint32_t)i;
			(*out)[(*n)++] = base;
		}
	}
	return true;
}

void reyes_patch_split(const struct reyes_patch *pa, bool along_u, struct reyes_patch out[2])
{
	out[0] = out[1] = *pa;
	if (pa->depth < UINT16_MAX)
		out[0].depth = out[1].depth = (uint16_t)(pa->depth + 1);
	if (along_u) {
		float m = 0.5f * (pa->u0 + pa->u1);
		out[0].u1 = m;
		out[1].u0 = m;
	} else {
		float m = 0.5f * (pa->v0 + pa->v1);
		out[0].v1 = m;
		out[1].v0 = m;
	}
}

void reyes_bound_to_float(const double blo[3], const double bhi[3], float lo[3], float hi[3])
{
	double a[3], b[3], mag = 0.0;
	for (int c = 0; c < 3; c++) {
		bool empty = !(blo[c] <= bhi[c]);
		a[c] = empty ? 0.0 : blo[c];
		b[c] = empty ? 0.0 : bhi[c];
		mag = fmax(mag, fmax(fabs(a[c]), fabs(b[c])));
	}
	/* Pad for the rounding of diced points to float. */
	double pad = 1e-6 * mag + 1e-30;
	for (int c = 0; c < 3; c++) {
		lo[c] = sl_to_float(a[c] - pad);
		hi[c] = sl_to_float(b[c] + pad);
	}
}

void reyes_patch_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3])
{
	if (pa && pa->prim && pa->prim->kind == REYES_SUBDIV) {
		reyes_subdiv_bound(pa, t, lo, hi);
		return;
	}
	if (pa && pa->prim && pa->prim->kind == REYES_NUPATCH) {
		reyes_nurbs_bound(pa, t, lo, hi);
		return;
	}
	if (pa && pa->prim && (pa->prim->kind == REYES_CURVES || pa->prim->kind == REYES_POINTS)) {
		reyes_curves_bound(pa, t, lo, hi);
		return;
	}
	double blo[3] = { INFINITY, INFINITY, INFINITY }, bhi[3] = { -INFINITY, -INFINITY, -INFINITY };
	struct piece pc;
	if (!setup_piece(pa, &pc)) {
		for (int c = 0; c < 3; c++)
			lo[c] = hi[c] = 0.0f;
		return;
	}
	double u0 = pa->u0, u1 = pa->u1, v0 = pa->v0, v1 = pa->v1;
	const float *vals = pc.P[t ? 1 : 0];
	if (pc.kind == PIECE_QUADRIC) {
		quadric_bound(&pc.q[t ? 1 : 0], u0, u1, v0, v1, blo, bhi);
	} else if (pc.kind == PIECE_BILINEAR) {
		/* A bilinear patch lies in the hull of its corners. */
		double Q[4][3], P[3], ds[3], dt[3];
		bilinear_corners(&pc, vals, Q);
		for (int k = 0; k < 4; k++) {
			bilinear_eval(Q, k % 2 ? u1 : u0, k / 2 ? v1 : v0, P, ds, dt);
			box_add(blo, bhi, P);
		}
	} else {
		/* The hull of the Bezier control points of the sub-patch. */
		double mu[16], mv[16];
		bezier_of(pc.bu, u0, u1, mu);
		bezier_of(pc.bv, v0, v1, mv);
		double H[4][4][3];
		for (int l = 0; l < 4; l++)
			for (int i = 0; i < 4; i++)
				for (int c = 0; c < 3; c++) {
					double s = 0.0;
					for (int k = 0; k < 4; k++)
						s += mu[i * 4 + k] * vals[(size_t)pc.cp[l * 4 + k] * 3 + c];
					H[l][i][c] = s;
				}
		for (int j = 0; j < 4; j++)
			for (int i = 0; i < 4; i++) {
				double P[3] = { 0.0, 0.0, 0.0 };
				for (int l = 0; l < 4; l++)
					for (int c = 0; c < 3; c++)
						P[c] += mv[j * 4 + l] * H[l][i][c];
				box_add(blo, bhi, P);
			}
	}
	if (pc.height) {
		/* The surface's x and y are u and v: the hull's z, the piece's (u, v) range. */
		blo[0] = pc.uoff + pc.uscale * fmin(u0, u1), bhi[0] = pc.uoff + pc.uscale * fmax(u0, u1);
		blo[1] = pc.voff + pc.vscale * fmin(v0, v1), bhi[1] = pc.voff + pc.vscale * fmax(v0, v1);
	}
	reyes_bound_to_float(blo, bhi, lo, hi);
}

/* ---- dicing ---- */

/* Parameters of the grid points and, for bicubic pieces, their basis weights. */
struct dice {
	uint32_t nu, nv, n;
	double *s, *t;          /* piece-local parameters of columns and rows */
	double *wu, *wv;        /* bicubic: 4 weights per column / row */
};

/*
 * Interpolate @var over the grid into @dst (stride planes of n floats).
 * False when the variable has too few values for this piece.
 */
static bool interp_var(const struct piece *pc, const struct dice *d,
		       const struct reyes_primvar *var, float *dst)
{
	size_t stride = reyes_primvar_stride(var);
	const float *vals = var->values;
	if (!stride || !vals)
		return false;
	uint32_t n = d->n;
	switch (var->cls) {
	case REYES_CONSTANT:
	case REYES_UNIFORM: {
		uint32_t item = var->cls == REYES_UNIFORM ? pc->uniform : 0;
		if (item >= var->count)
			return false;
		for (size_t e = 0; e < stride; e++) {
			float x = sl_to_float(vals[(size_t)item * stride + e]);
			for (uint32_t k = 0; k < n; k++)
				dst[e * n + k] = x;
		}
		return true;
	}
	case REYES_VERTEX:
		if (pc->kind == PIECE_BICUBIC) {
			for (int i = 0; i < 16; i++)
				if (pc->cp[i] >= var->count)
					return false;
			for (size_t e = 0; e < stride; e++)
				for (uint32_t j = 0; j < d->nv; j++) {
					double H[4];
					for (int k = 0; k < 4; k++) {
						H[k] = 0.0;
						for (int l = 0; l < 4; l++)
							H[k] += d->wv[j * 4 + l] *
								vals[(size_t)pc->cp[l * 4 + k] * stride + e];
					}
					for (uint32_t i = 0; i < d->nu; i++) {
						const double *w = &d->wu[i * 4];
						double x = w[0] * H[0] + w[1] * H[1] + w[2] * H[2] +
							   w[3] * H[3];
						dst[e * n + j * d->nu + i] = sl_to_float(x);
					}
				}
			return true;
		}
		break;
	case REYES_VARYING:
	case REYES_FACEVARYING:
		break;
	default:
		return false;
	}
	const uint32_t *items = var->cls == REYES_VERTEX ? pc->vtx :
				var->cls == REYES_VARYING ? pc->vary : pc->fvary;
	for (uint32_t i = 0; i < pc->nsrc; i++)
		if (items[i] >= var->count)
			return false;
	for (size_t e = 0; e < stride; e++) {
		double q[4];
		for (int k = 0; k < 4; k++) {
			q[k] = 0.0;
			for (uint32_t i = 0; i < pc->nsrc; i++)
				if (pc->w[k][i] != 0.0)
					q[k] += pc->w[k][i] * vals[(size_t)items[i] * stride + e];
		}
		for (uint32_t j = 0; j < d->nv; j++) {
			double t = d->t[j];
			for (uint32_t i = 0; i < d->nu; i++) {
				double s = d->s[i];
				double x = (1 - s) * (1 - t) * q[0] + s * (1 - t) * q[1] +
					   (1 - s) * t * q[2] + s * t * q[3];
				dst[e * n + j * d->nu + i] = sl_to_float(x);
			}
		}
	}
	return true;
}

static float *alloc_floats(size_t count, bool *failed)
{
	float *p = malloc(count * sizeof(float));
	if (!p)
		*failed = true;
	return p;
}

bool reyes_grid_alloc(struct reyes_grid *g, uint32_t n, bool moving)
{
	bool failed = false;
	g->P[0] = alloc_floats(3 * (size_t)n, &failed);
	g->P[1] = moving ? alloc_floats(3 * (size_t)n, &failed) : g->P[0];
	g->dPdu = alloc_floats(3 * (size_t)n, &failed);
	g->dPdv = alloc_floats(3 * (size_t)n, &failed);
	g->Ng = alloc_floats(3 * (size_t)n, &failed);
	g->u = alloc_floats(n, &failed);
	g->v = alloc_floats(n, &failed);
	return !failed;
}

/* Position and derivatives (piece-local) at local (s, t) for a non-quadric piece. */
static void piece_eval(const struct piece *pc, const double Q[4][3], const float *vals, double s,
		       double t, double P[3], double ds[3], double dt[3])
{
	if (pc->kind == PIECE_BICUBIC)
		bicubic_eval(pc, vals, s, t, P, ds, dt);
	else
		bilinear_eval(Q, s, t, P, ds, dt);
}

static bool is_special_var(const char *name)
{
	static const char *const names[] = { "P", "N", "Cs", "Os", "s", "t", "st" };
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (strcmp(name, names[i]) == 0)
			return true;
	return false;
}

/* Variable @name of @p through @fill, if it has @stride floats per item; NULL otherwise. */
static float *fill_named(const struct reyes_prim *p, uint32_t n, const char *name, size_t stride,
			 reyes_var_fill fill, const void *ctx, bool *failed)
{
	const struct reyes_primvar *v = reyes_prim_var(p, name);
	if (!v || reyes_primvar_stride(v) != stride)
		return NULL;
	float *dst = alloc_floats(stride * n, failed);
	if (dst && !fill(ctx, v, dst)) {
		free(dst);
		dst = NULL;
	}
	return dst;
}

/* s and t from "st" where they are not given on their own. */
static void split_st(struct reyes_grid *g, const struct reyes_prim *p, reyes_var_fill fill,
		     const void *ctx, bool *failed)
{
	uint32_t n = g->n;
	float *st = fill_named(p, n, "st", 2, fill, ctx, failed);
	if (!st)
		return;
	if (!g->s) {
		g->s = alloc_floats(n, failed);
		if (g->s)
			memcpy(g->s, st, n * sizeof(float));
	}
	if (!g->t) {
		g->t = alloc_floats(n, failed);
		if (g->t)
			memcpy(g->t, st + n, n * sizeof(float));
	}
	free(st);
}

bool reyes_grid_fill_vars(struct reyes_grid *g, const struct reyes_prim *p, bool with_N,
			  reyes_var_fill fill, const void *ctx)
{
	bool failed = false;
	uint32_t n = g->n;
	if (with_N)
		g->N = fill_named(p, n, "N", 3, fill, ctx, &failed);
	for (uint32_t k = 0; g->N && k < n; k++) {
		float a[3] = { g->N[k], g->N[n + k], g->N[2 * n + k] }, r[3];
		sl_v3_normalize(r, a);
		g->N[k] = r[0], g->N[n + k] = r[1], g->N[2 * n + k] = r[2];
	}
	g->Cs = fill_named(p, n, "Cs", 3, fill, ctx, &failed);
	g->Os = fill_named(p, n, "Os", 3, fill, ctx, &failed);
	g->s = fill_named(p, n, "s", 1, fill, ctx, &failed);
	g->t = fill_named(p, n, "t", 1, fill, ctx, &failed);
	if (!g->s || !g->t)
		split_st(g, p, fill, ctx, &failed);

	uint32_t nuser = 0;
	for (uint32_t i = 0; i < p->nvars; i++)
		if (p->vars[i].name && !is_special_var(p->vars[i].name) &&
		    reyes_primvar_stride(&p->vars[i]))
			nuser++;
	if (!nuser || failed)
		return !failed;
	g->vars = calloc(nuser, sizeof(*g->vars));
	if (!g->vars)
		return false;
	for (uint32_t i = 0; i < p->nvars; i++) {
		const struct reyes_primvar *v = &p->vars[i];
		if (!v->name || is_special_var(v->name) || !reyes_primvar_stride(v))
			continue;
		float *dst = alloc_floats(reyes_primvar_stride(v) * n, &failed);
		if (!dst)
			return false;
		if (!fill(ctx, v, dst)) {
			free(dst);
			continue;
		}
		struct reyes_grid_var *gv = &g->vars[g->nvars++];
		gv->name = v->name;
		gv->type = v->type;
		gv->arraylen = v->arraylen;
		gv->data = dst;
	}
	return true;
}

/* A piece's interpolation of one variable, for reyes_grid_fill_vars. */
struct piece_fill {
	const struct piece *pc;
	const struct dice *d;
};

static bool piece_fill(const void *ctx, const struct reyes_primvar *v, float *dst)
{
	const struct piece_fill *f = ctx;
	return interp_var(f->pc, f->d, v, dst);
}

bool reyes_patch_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		      struct reyes_grid *g)
{
	if (pa && pa->prim && (pa->prim->kind == REYES_CURVES || pa->prim->kind == REYES_POINTS))
		return reyes_curves_dice(pa, nu, nv, g);
	if (!g)
		return false;
	if (pa && pa->prim && pa->prim->kind == REYES_SUBDIV)
		return reyes_subdiv_dice(pa, nu, nv, g);
	if (pa && pa->prim && pa->prim->kind == REYES_NUPATCH)
		return reyes_nurbs_dice(pa, nu, nv, g);
	memset(g, 0, sizeof(*g));
	struct piece pc;
	if (!setup_piece(pa, &pc))
		return false;
	const struct reyes_prim *p = pa->prim;
	nu = nu < 2 ? 2 : nu;
	nv = nv < 2 ? 2 : nv;
	if ((uint64_t)nu * nv > (1u << 26))
		return false;
	uint32_t n = nu * nv;
	g->nu = nu, g->nv = nv, g->n = n;

	bool failed = false;
	struct dice d = { nu, nv, n, NULL, NULL, NULL, NULL };
	d.s = malloc((size_t)(nu + nv) * sizeof(double));
	d.wu = malloc((size_t)(nu + nv) * 8 * sizeof(double));
	bool moving = pc.kind == PIECE_QUADRIC ? pc.qmoving : pc.P[1] != pc.P[0];
	if (!reyes_grid_alloc(g, n, moving))
		failed = true;
	if (failed || !d.s || !d.wu)
		goto fail;
	d.t = d.s + nu;
	d.wv = d.wu + 4 * (size_t)nu;
	double *dwu = d.wu + 4 * (size_t)(nu + nv), *dwv = dwu + 4 * (size_t)nu;

	double su = ((double)pa->u1 - pa->u0) / (nu - 1), sv = ((double)pa->v1 - pa->v0) / (nv - 1);
	for (uint32_t i = 0; i < nu; i++) {
		d.s[i] = i == nu - 1 ? pa->u1 : pa->u0 + su * i;
		if (pc.kind == PIECE_BICUBIC)
			basis_weights(pc.bu, d.s[i], &d.wu[4 * i], &dwu[4 * i]);
	}
	for (uint32_t j = 0; j < nv; j++) {
		d.t[j] = j == nv - 1 ? pa->v1 : pa->v0 + sv * j;
		if (pc.kind == PIECE_BICUBIC)
			basis_weights(pc.bv, d.t[j], &d.wv[4 * j], &dwv[4 * j]);
	}
	g->du = (float)(su * pc.uscale);
	g->dv = (float)(sv * pc.vscale);

	double Q[2][4][3];
	if (pc.kind == PIECE_BILINEAR) {
		bilinear_corners(&pc, pc.P[0], Q[0]);
		bilinear_corners(&pc, pc.P[1], Q[1]);
	}
	/* Derivatives with respect to the primitive's u, v rather than the piece's. */
	double ku = 1.0 / pc.uscale, kv = 1.0 / pc.vscale, maxu = 0.0, maxv = 0.0;
	for (uint32_t j = 0; j < nv; j++)
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			double P[3], du[3], dv[3], N[3];
			if (pc.kind == PIECE_QUADRIC) {
				/* Derivatives and normal from the sample with area. */
				double P1[3] = { 0.0, 0.0, 0.0 };
				quadric_eval(&pc.q[pc.qshape], d.s[i], d.t[j], P, du, dv);
				quadric_normal(&pc.q[pc.qshape], d.t[j], du, dv, N);
				if (pc.qshape) {
					double a[3], b[3];
					memcpy(P1, P, sizeof(P1));
					quadric_eval(&pc.q[0], d.s[i], d.t[j], P, a, b);
				} else if (moving) {
					double a[3], b[3];
					quadric_eval(&pc.q[1], d.s[i], d.t[j], P1, a, b);
				}
				if (moving)
					for (int c = 0; c < 3; c++)
						g->P[1][c * n + k] = sl_to_float(P1[c]);
			} else {
				piece_eval(&pc, Q[0], pc.P[0], d.s[i], d.t[j], P, du, dv);
				for (int c = 0; c < 3; c++)
					du[c] *= ku, dv[c] *= kv;
				double uu = pc.uoff + pc.uscale * d.s[i], vv = pc.voff + pc.vscale * d.t[j];
				if (pc.height) {
					P[0] = uu, P[1] = vv;
					du[0] = 1.0, du[1] = 0.0, dv[0] = 0.0, dv[1] = 1.0;
				}
				v3_cross(N, du, dv);
				maxu = fmax(maxu, v3_len(du));
				maxv = fmax(maxv, v3_len(dv));
				if (moving) {
					double P1[3], a[3], b[3];
					piece_eval(&pc, Q[1], pc.P[1], d.s[i], d.t[j], P1, a, b);
					if (pc.height)
						P1[0] = uu, P1[1] = vv;
					for (int c = 0; c < 3; c++)
						g->P[1][c * n + k] = sl_to_float(P1[c]);
				}
			}
			for (int c = 0; c < 3; c++) {
				g->P[0][c * n + k] = sl_to_float(P[c]);
				g->dPdu[c * n + k] = sl_to_float(du[c]);
				g->dPdv[c * n + k] = sl_to_float(dv[c]);
				g->Ng[c * n + k] = sl_to_float(N[c]);
			}
			g->u[k] = (float)(pc.uoff + pc.uscale * d.s[i]);
			g->v[k] = (float)(pc.voff + pc.vscale * d.t[j]);
		}

	/*
	 * Where a patch collapses (an edge pulled to a point, a pole of control
	 * points) dPdu ^ dPdv vanishes: take the normal a little way in towards
	 * the middle of the piece instead, its limit.
	 */
	if (pc.kind != PIECE_QUADRIC && !pc.height && maxu > 0.0 && maxv > 0.0) {
		for (uint32_t j = 0; j < nv; j++)
			for (uint32_t i = 0; i < nu; i++) {
				uint32_t k = j * nu + i;
				double N[3] = { g->Ng[k], g->Ng[n + k], g->Ng[2 * n + k] };
				if (v3_len(N) > 1e-6 * maxu * maxv)
					continue;
				for (double step = 1e-4; step < 0.5; step *= 10.0) {
					double s = d.s[i] + (d.s[i] <= 0.5 ? step : -step);
					double t = d.t[j] + (d.t[j] <= 0.5 ? step : -step);
					double P[3], du[3], dv[3];
					piece_eval(&pc, Q[0], pc.P[0], s, t, P, du, dv);
					v3_cross(N, du, dv);
					double len = v3_len(N);
					if (len * ku * kv > 1e-6 * maxu * maxv) {
						for (int c = 0; c < 3; c++)
							g->Ng[c * n + k] = sl_to_float(N[c] * ku * kv);
						break;
					}
				}
			}
	}
	if (p->attrs && p->attrs->flip_normals)
		for (size_t k = 0; k < 3 * (size_t)n; k++)
			g->Ng[k] = -g->Ng[k];

	/* Primitive variables. */
	struct piece_fill pf = { &pc, &d };
	if (!reyes_grid_fill_vars(g, p, true, piece_fill, &pf))
		failed = true;
	if (failed)
		goto fail;
	free(d.s);
	free(d.wu);
	return true;
fail:
	free(d.s);
	free(d.wu);
	reyes_grid_finish(g);
	return false;
}

void reyes_grid_finish(struct reyes_grid *g)
{
	if (!g)
		return;
	if (g->P[1] != g->P[0])
		free(g->P[1]);
	free(g->P[0]);
	free(g->dPdu);
	free(g->dPdv);
	free(g->Ng);
	free(g->N);
	free(g->u);
	free(g->v);
	free(g->s);
	free(g->t);
	free(g->Cs);
	free(g->Os);
	for (uint32_t i = 0; i < g->nvars; i++)
		free(g->vars[i].data);
	free(g->vars);
	memset(g, 0, sizeof(*g));
}

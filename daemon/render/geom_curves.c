/*
 * Curves and Points: ribbons and disks that face the camera, as prman
 * draws hair and particles.
 *
 * Curves. A piece is one segment of one curve (a cubic curve's segment is
 * the basis window at vstep times its index); the patch's v is the
 * segment's own parameter t, u runs across the width. The centre line C(t)
 * goes through the two vertices (linear) or the four control points and
 * the v basis (cubic); the ribbon at t spans C(t) + (u - 1/2) w(t) W(t),
 * where w is the width ("width" per segment end or per vertex,
 * "constantwidth", else 1) and W = normalize(C' x F) with F the direction
 * the ribbon faces: "N" when the curve has normals (an oriented ribbon),
 * else towards the eye (prim->eye, set by the scene builder). Then
 * dPdu x dPdv = w W x C' points along F: the ribbon's Ng faces the
 * camera (or N), so a one-sided curve is never culled and plastic shades it
 * as prman shades its flat ribbons. The grid's v is the curve's: (segment +
 * t) / segments, 0..1 along the whole curve.
 *
 * Points. A piece is one point's disk of radius w/2 facing the eye: u is
 * the angle (theta = 2 pi u), v the distance from the centre (0..1). A
 * polygon with k sides inscribed in a circle has less area than the circle;
 * the grid's outer ring is pushed out by sqrt(dtheta / sin dtheta) so that
 * the diced disk has the circle's area whatever the dice rate (at least 8
 * sides per full turn, so the push stays under 5.4 %). A point's primitive
 * variables are constant over its disk.
 *
 * Both deform over the shutter with their points (and widths), and face the
 * eye where it is at each shutter time.
 */
#include "geom_curves.h"

#include "log.h"
#include "mathlib.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI_D 3.14159265358979323846
#define MIN_SIDES 8            /* sides of a diced disk per full turn, at least */

/* Widest push of a disk's outer ring: sqrt(dtheta / sin dtheta) at 2 pi / MIN_SIDES. */
#define MAX_PUSH 1.0540

/* ---- small helpers ---- */

static void cross3(double r[3], const double a[3], const double b[3])
{
	double x = a[1] * b[2] - a[2] * b[1];
	double y = a[2] * b[0] - a[0] * b[2];
	double z = a[0] * b[1] - a[1] * b[0];
	r[0] = x, r[1] = y, r[2] = z;
}

static double len3(const double a[3])
{
	return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/* @a scaled to unit length; false (a unchanged) when it has none. */
static bool unit3(double a[3])
{
	double l = len3(a);
	if (!(l > 1e-30) || !isfinite(l))
		return false;
	a[0] /= l, a[1] /= l, a[2] /= l;
	return true;
}

/* A unit vector perpendicular to the unit vector @a. */
static void perp3(double r[3], const double a[3])
{
	double axis[3] = { 0.0, 0.0, 0.0 };
	double x = fabs(a[0]), y = fabs(a[1]), z = fabs(a[2]);
	axis[x <= y && x <= z ? 0 : y <= z ? 1 : 2] = 1.0;   /* the axis least along a */
	cross3(r, a, axis);
	if (!unit3(r))
		r[0] = 1.0, r[1] = r[2] = 0.0;
}

/* ---- pieces ---- */

/* What bounding and dicing need of one piece. */
struct cpiece {
	const struct reyes_prim *p;
	bool point;
	uint32_t item;          /* the point, or the curve */
	uint32_t seg, nseg;     /* the segment of the curve and their number */
	bool cubic;
	uint32_t vtx[4];        /* vertex items (linear curves and points: the first two or one) */
	uint32_t vary[2];       /* varying items at the segment's ends */
	double B[16];
	const float *P[2];
	bool moving;
};

static const struct reyes_primvar *points_of(const struct reyes_prim *p)
{
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	if (!P || !P->values || reyes_primvar_stride(P) != 3 || P->cls != REYES_VERTEX)
		return NULL;
	return P;
}

/* The curve holding piece @piece: the last with sfirst[c] <= piece. */
static uint32_t curve_of(const struct reyes_curves *cv, uint32_t piece)
{
	uint32_t lo = 0, hi = cv->ncurves - 1;
	while (lo < hi) {
		uint32_t mid = lo + (hi - lo + 1) / 2;
		if (cv->sfirst[mid] <= piece)
			lo = mid;
		else
			hi = mid - 1;
	}
	return lo;
}

static bool setup(const struct reyes_patch *pa, struct cpiece *c)
{
	memset(c, 0, sizeof(*c));
	if (!pa || !pa->prim)
		return false;
	const struct reyes_prim *p = pa->prim;
	const struct reyes_primvar *P = points_of(p);
	if (!P)
		return false;
	c->p = p;
	c->P[0] = P->values;
	c->P[1] = P->values1 ? P->values1 : P->values;
	c->moving = reyes_curves_deform(p);
	if (p->kind == REYES_POINTS) {
		if (pa->piece >= P->count)
			return false;
		c->point = true;
		c->item = c->vtx[0] = c->vary[0] = c->vary[1] = pa->piece;
		return true;
	}
	const struct reyes_curves *cv = p->curves;
	if (!cv || !cv->ncurves || pa->piece >= cv->sfirst[cv->ncurves])
		return false;
	uint32_t k = curve_of(cv, pa->piece);
	uint32_t nseg = cv->sfirst[k + 1] - cv->sfirst[k], nv = cv->nverts[k];
	if (!nseg || !nv)
		return false;
	c->item = k;
	c->seg = pa->piece - cv->sfirst[k];
	c->nseg = nseg;
	c->cubic = cv->cubic;
	uint32_t first = cv->vfirst[k], nvtx = c->cubic ? 4 : 2;
	for (uint32_t i = 0; i < nvtx; i++) {
		uint64_t off = c->cubic ? (uint64_t)c->seg * cv->vstep + i : (uint64_t)c->seg + i;
		c->vtx[i] = first + (uint32_t)(off % nv);
		if (c->vtx[i] >= P->count)
			return false;
	}
	for (int i = 0; i < 16; i++)
		c->B[i] = cv->basis[i];
	uint32_t nvary = cv->periodic ? nseg : nseg + 1;
	uint32_t base = cv->sfirst[k] + (cv->periodic ? 0 : k);
	c->vary[0] = base + c->seg;
	c->vary[1] = base + (c->seg + 1) % nvary;
	return true;
}

/*
 * The items of class @cls that make a value at the piece's t and their
 * weights (and the weights' derivatives in t); the number of items.
 */
static uint32_t weights(const struct cpiece *c, enum reyes_class cls, double t, uint32_t item[4],
			double w[4], double dw[4])
{
	for (int i = 0; i < 4; i++)
		item[i] = 0, w[i] = dw[i] = 0.0;
	if (cls == REYES_CONSTANT || (c->point && cls == REYES_UNIFORM)) {
		w[0] = 1.0;
		return 1;
	}
	if (cls == REYES_UNIFORM || c->point) {
		item[0] = c->item;
		w[0] = 1.0;
		return 1;
	}
	if (cls == REYES_VERTEX && c->cubic) {
		double T[4] = { t * t * t, t * t, t, 1.0 }, dT[4] = { 3.0 * t * t, 2.0 * t, 1.0, 0.0 };
		for (int k = 0; k < 4; k++) {
			item[k] = c->vtx[k];
			for (int r = 0; r < 4; r++) {
				w[k] += T[r] * c->B[r * 4 + k];
				dw[k] += dT[r] * c->B[r * 4 + k];
			}
		}
		return 4;
	}
	const uint32_t *src = cls == REYES_VERTEX ? c->vtx : c->vary;
	item[0] = src[0], item[1] = src[1];
	w[0] = 1.0 - t, w[1] = t;
	dw[0] = -1.0, dw[1] = 1.0;
	return 2;
}

/*
 * Component @e of @v (values @vals) at the piece's t, and its derivative;
 * false when @v has too few items for this piece.
 */
static bool value_at(const struct cpiece *c, const struct reyes_primvar *v, const float *vals,
		     size_t e, double t, double *x, double *dx)
{
	uint32_t item[4];
	double w[4], dw[4];
	uint32_t n = weights(c, v->cls, t, item, w, dw);
	size_t stride = reyes_primvar_stride(v);
	*x = 0.0;
	if (dx)
		*dx = 0.0;
	for (uint32_t i = 0; i < n; i++) {
		if (item[i] >= v->count)
			return false;
		double y = vals[(size_t)item[i] * stride + e];
		*x += w[i] * y;
		if (dx)
			*dx += dw[i] * y;
	}
	return true;
}

/* The width variable: "width", else "constantwidth", else NULL (a width of 1). */
static const struct reyes_primvar *width_var(const struct reyes_prim *p)
{
	const struct reyes_primvar *v = reyes_prim_var(p, "width");
	if (!v || reyes_primvar_stride(v) != 1 || !v->values)
		v = reyes_prim_var(p, "constantwidth");
	if (!v || reyes_primvar_stride(v) != 1 || !v->values)
		return NULL;
	return v;
}

static double width_at(const struct cpiece *c, const struct reyes_primvar *wv, int ti, double t)
{
	double w;
	if (!wv)
		return 1.0;
	const float *vals = ti && wv->values1 ? wv->values1 : wv->values;
	if (!value_at(c, wv, vals, 0, t, &w, NULL) || !isfinite(w))
		return 0.0;
	return w;
}

/* Centre and tangent (d/dt) of the piece at t, shutter time @ti. */
static void centre_at(const struct cpiece *c, int ti, double t, double C[3], double T[3])
{
	uint32_t item[4];
	double w[4], dw[4];
	uint32_t n = weights(c, REYES_VERTEX, t, item, w, dw);
	for (int k = 0; k < 3; k++) {
		C[k] = T[k] = 0.0;
		for (uint32_t i = 0; i < n; i++) {
			double y = c->P[ti][(size_t)item[i] * 3 + k];
			C[k] += w[i] * y;
			T[k] += dw[i] * y;
		}
	}
}

/* The unit direction the piece faces at @C, shutter time @ti: to the eye, or "N". */
static void facing(const struct cpiece *c, const struct reyes_primvar *N, int ti, double t,
		   const double C[3], double F[3])
{
	bool ok = false;
	if (N) {
		const float *vals = ti && N->values1 ? N->values1 : N->values;
		ok = true;
		for (size_t k = 0; k < 3 && ok; k++)
			ok = value_at(c, N, vals, k, t, &F[k], NULL);
		ok = ok && unit3(F);
	}
	if (!ok) {
		const float *e = c->p->eye[ti ? 1 : 0];
		for (int k = 0; k < 3; k++)
			F[k] = e[k] - e[3] * C[k];
		ok = unit3(F);
	}
	if (!ok)
		F[0] = F[1] = 0.0, F[2] = -1.0;   /* an eye nobody set: looking down +z */
}

static const struct reyes_primvar *normals_of(const struct cpiece *c)
{
	const struct reyes_primvar *N = c->point ? NULL : reyes_prim_var(c->p, "N");
	return N && reyes_primvar_stride(N) == 3 && N->values ? N : NULL;
}

bool reyes_curves_deform(const struct reyes_prim *p)
{
	const struct reyes_primvar *P = reyes_prim_var(p, "P"), *w = width_var(p);
	/* the eye moving in object space turns the ribbons and disks over the shutter */
	return (P && P->values1) || (w && w->values1) ||
	       memcmp(p->eye[0], p->eye[1], sizeof(p->eye[0])) != 0;
}

bool reyes_curves_count(const struct reyes_prim *p, size_t *count)
{
	const char *what = p->kind == REYES_POINTS ? "points" : "curves";
	const struct reyes_primvar *P = points_of(p);
	if (!P) {
		rl_log(RL_LOG_ERROR, "primitive %u (%s): no vertex \"P\"", p->id, what);
		return false;
	}
	for (size_t i = 0; i < 3 * (size_t)P->count; i++)
		if (!isfinite(P->values[i]) || (P->values1 && !isfinite(P->values1[i]))) {
			rl_log(RL_LOG_ERROR, "primitive %u (%s): a point is not finite", p->id, what);
			return false;
		}
	if (p->kind == REYES_POINTS) {
		*count = P->count;
		return true;
	}
	const struct reyes_curves *cv = p->curves;
	if (!cv || !cv->ncurves || !cv->nverts || !cv->vfirst || !cv->sfirst ||
	    (cv->cubic && !cv->vstep)) {
		rl_log(RL_LOG_ERROR, "primitive %u (curves): no curves to dice", p->id);
		return false;
	}
	for (uint32_t k = 0; k < cv->ncurves; k++)
		if (cv->sfirst[k + 1] < cv->sfirst[k] ||
		    (uint64_t)cv->vfirst[k] + cv->nverts[k] > P->count) {
			rl_log(RL_LOG_ERROR, "primitive %u (curves): curve %u has no vertices", p->id,
			       k);
			return false;
		}
	*count = cv->sfirst[cv->ncurves];
	return true;
}

/* ---- bounds ---- */

/*
 * Bounds of component @e of vertex or varying @v over t in [a, b]: the
 * hull of the Bezier control values of that span (a cubic's through its
 * basis), or its two ends.
 */
static bool span_hull(const struct cpiece *c, const struct reyes_primvar *v, const float *vals,
		      size_t e, double a, double b, double *lo, double *hi)
{
	if (!(v->cls == REYES_VERTEX && c->cubic && !c->point)) {
		double x0, x1;
		if (!value_at(c, v, vals, e, a, &x0, NULL) || !value_at(c, v, vals, e, b, &x1, NULL))
			return false;
		*lo = fmin(x0, x1), *hi = fmax(x0, x1);
		return true;
	}
	double g[4], cf[4];
	for (int k = 0; k < 4; k++) {
		if (c->vtx[k] >= v->count)
			return false;
		g[k] = vals[(size_t)c->vtx[k] * reyes_primvar_stride(v) + e];
	}
	for (int r = 0; r < 4; r++)
		cf[r] = c->B[r * 4] * g[0] + c->B[r * 4 + 1] * g[1] + c->B[r * 4 + 2] * g[2] +
			c->B[r * 4 + 3] * g[3];
	/* p(t) = cf0 t^3 + cf1 t^2 + cf2 t + cf3 at t = a + h s, then to Bezier form */
	double h = b - a;
	double d3 = cf[0] * h * h * h;
	double d2 = (3.0 * cf[0] * a + cf[1]) * h * h;
	double d1 = (3.0 * cf[0] * a * a + 2.0 * cf[1] * a + cf[2]) * h;
	double d0 = ((cf[0] * a + cf[1]) * a + cf[2]) * a + cf[3];
	double bz[4] = { d0, d0 + d1 / 3.0, d0 + 2.0 * d1 / 3.0 + d2 / 3.0, d0 + d1 + d2 + d3 };
	*lo = fmin(fmin(bz[0], bz[1]), fmin(bz[2], bz[3]));
	*hi = fmax(fmax(bz[0], bz[1]), fmax(bz[2], bz[3]));
	return true;
}

void reyes_curves_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3])
{
	struct cpiece c;
	for (int k = 0; k < 3; k++)
		lo[k] = hi[k] = 0.0f;
	if (!setup(pa, &c))
		return;
	int ti = t ? 1 : 0;
	const struct reyes_primvar *P = points_of(c.p), *wv = width_var(c.p);
	double blo[3], bhi[3], wlo = 1.0, whi = 1.0, reach;
	double a = c.point ? 0.0 : pa->v0, b = c.point ? 0.0 : pa->v1;
	for (size_t k = 0; k < 3; k++)
		if (!span_hull(&c, P, c.P[ti], k, a, b, &blo[k], &bhi[k]))
			return;
	if (wv && !span_hull(&c, wv, ti && wv->values1 ? wv->values1 : wv->values, 0, a, b, &wlo,
			     &whi))
		wlo = whi = 0.0;
	/* The ribbon or disk lies within half its width of the centre. */
	reach = 0.5 * fmax(fabs(wlo), fabs(whi)) * (c.point ? MAX_PUSH : 1.0);
	for (int k = 0; k < 3; k++)
		blo[k] -= reach, bhi[k] += reach;
	reyes_bound_to_float(blo, bhi, lo, hi);
}

/* ---- dicing ---- */

/*
 * Fill @dst (stride planes of nu * nv) with @v over the grid: one value per
 * row (a curve's primitive variables do not vary across its width; a
 * point's are constant over its disk). False when @v does not fit.
 */
static bool fill_var(const struct cpiece *c, const struct reyes_primvar *v, const double *rows,
		     uint32_t nu, uint32_t nv, float *dst)
{
	size_t stride = reyes_primvar_stride(v), n = (size_t)nu * nv;
	if (!stride || !v->values)
		return false;
	for (size_t e = 0; e < stride; e++)
		for (uint32_t j = 0; j < nv; j++) {
			double x;
			if (!value_at(c, v, v->values, e, c->point ? 0.0 : rows[j], &x, NULL))
				return false;
			float f = sl_to_float(x);
			for (uint32_t i = 0; i < nu; i++)
				dst[e * n + (size_t)j * nu + i] = f;
		}
	return true;
}

static void put3(float *dst, uint32_t n, uint32_t k, const double a[3])
{
	for (int c = 0; c < 3; c++)
		dst[(size_t)c * n + k] = sl_to_float(a[c]);
}

/*
 * Should the grid wind the other way? The hider takes a micropolygon for
 * front-facing when its raster winding and the attributes' flip agree, and
 * a transform that mirrors reverses the winding: a ribbon or disk winds so
 * that it is front-facing whatever the two (a one-sided curve is never
 * culled), while Ng faces F either way.
 */
static bool reversed(const struct reyes_prim *p)
{
	return (p->attrs && p->attrs->flip_normals) != p->mirror;
}

/* Positions (and at @ti == 0 derivatives and normals) of a curve piece's grid. */
static void dice_ribbon(const struct cpiece *c, const struct reyes_patch *pa, int ti,
			const double *rows, struct reyes_grid *g)
{
	const struct reyes_primvar *wv = width_var(c->p), *N = normals_of(c);
	bool flip = reversed(c->p);
	uint32_t nu = g->nu, n = g->n;
	for (uint32_t j = 0; j < g->nv; j++) {
		double C[3], T[3], F[3], W[3], t = rows[j];
		centre_at(c, ti, t, C, T);
		double w = width_at(c, wv, ti, t);
		facing(c, N, ti, t, C, F);
		cross3(W, T, F);
		if (!unit3(W))
			perp3(W, F);
		if (flip)
			W[0] = -W[0], W[1] = -W[1], W[2] = -W[2];
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			double u = i == nu - 1 ? pa->u1 : pa->u0 + (pa->u1 - pa->u0) * i / (nu - 1);
			double P[3] = { C[0] + (u - 0.5) * w * W[0], C[1] + (u - 0.5) * w * W[1],
					C[2] + (u - 0.5) * w * W[2] };
			put3(g->P[ti], n, k, P);
			if (ti)
				continue;
			double du[3] = { w * W[0], w * W[1], w * W[2] };
			double dv[3] = { T[0] * c->nseg, T[1] * c->nseg, T[2] * c->nseg }, Ng[3];
			cross3(Ng, du, dv);
			if (Ng[0] * F[0] + Ng[1] * F[1] + Ng[2] * F[2] < 0)
				Ng[0] = -Ng[0], Ng[1] = -Ng[1], Ng[2] = -Ng[2];
			if (!(len3(Ng) > 1e-12 * (len3(du) + 1e-30) * (len3(dv) + 1e-30)))
				memcpy(Ng, F, sizeof(Ng));   /* a tip of zero width faces F too */
			put3(g->dPdu, n, k, du);
			put3(g->dPdv, n, k, dv);
			put3(g->Ng, n, k, Ng);
			g->u[k] = (float)u;
			g->v[k] = (float)((c->seg + t) / c->nseg);
		}
	}
}

/* Positions (and at @ti == 0 derivatives and normals) of a point's disk. */
static void dice_disk(const struct cpiece *c, const struct reyes_patch *pa, int ti,
		      struct reyes_grid *g)
{
	uint32_t nu = g->nu, nv = g->nv, n = g->n;
	double dtheta = 2.0 * PI_D * ((double)pa->u1 - pa->u0) / (nu - 1);
	double push = fabs(dtheta) > 1e-6 ? sqrt(fabs(dtheta) / sin(fabs(dtheta))) : 1.0;
	double C[3], T[3], F[3], X[3], Y[3];
	centre_at(c, ti, 0.0, C, T);
	double r = 0.5 * width_at(c, width_var(c->p), ti, 0.0) * push;
	facing(c, NULL, ti, 0.0, C, F);
	/* X x Y = -F, so that dPdu x dPdv points along F */
	perp3(X, F);
	cross3(Y, X, F);
	if (reversed(c->p))
		Y[0] = -Y[0], Y[1] = -Y[1], Y[2] = -Y[2];
	for (uint32_t j = 0; j < nv; j++) {
		double v = j == nv - 1 ? pa->v1 : pa->v0 + ((double)pa->v1 - pa->v0) * j / (nv - 1);
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			double u = i == nu - 1 ? pa->u1
				   : pa->u0 + ((double)pa->u1 - pa->u0) * i / (nu - 1);
			double cs = cos(2.0 * PI_D * u), sn = sin(2.0 * PI_D * u), P[3], du[3], dv[3];
			for (int e = 0; e < 3; e++) {
				P[e] = C[e] + r * v * (cs * X[e] + sn * Y[e]);
				du[e] = 2.0 * PI_D * r * v * (cs * Y[e] - sn * X[e]);
				dv[e] = r * (cs * X[e] + sn * Y[e]);
			}
			put3(g->P[ti], n, k, P);
			if (ti)
				continue;
			put3(g->dPdu, n, k, du);
			put3(g->dPdv, n, k, dv);
			put3(g->Ng, n, k, F);
			g->u[k] = (float)u;
			g->v[k] = (float)v;
		}
	}
}

/* A piece's variables by row, for reyes_grid_fill_vars. */
struct cpiece_fill {
	const struct cpiece *c;
	const double *rows;
	uint32_t nu, nv;
};

static bool cpiece_fill(const void *ctx, const struct reyes_primvar *v, float *dst)
{
	const struct cpiece_fill *f = ctx;
	return fill_var(f->c, v, f->rows, f->nu, f->nv, dst);
}

bool reyes_curves_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		       struct reyes_grid *g)
{
	if (!g)
		return false;
	memset(g, 0, sizeof(*g));
	struct cpiece c;
	if (!setup(pa, &c))
		return false;
	nu = nu < 2 ? 2 : nu;
	nv = nv < 2 ? 2 : nv;
	if (c.point) {
		/* enough sides that the pushed ring stays within the bound */
		double need = ceil(MIN_SIDES * fabs((double)pa->u1 - pa->u0)) + 1;
		if (nu < need)
			nu = (uint32_t)need;
	}
	if ((uint64_t)nu * nv > (1u << 26))
		return false;
	uint32_t n = nu * nv;
	g->nu = nu, g->nv = nv, g->n = n;
	double *rows = malloc(nv * sizeof(double));
	if (!reyes_grid_alloc(g, n, c.moving) || !rows)
		goto fail;
	for (uint32_t j = 0; j < nv; j++)
		rows[j] = j == nv - 1 ? pa->v1 : pa->v0 + ((double)pa->v1 - pa->v0) * j / (nv - 1);
	g->du = (float)(((double)pa->u1 - pa->u0) / (nu - 1));
	g->dv = (float)(((double)pa->v1 - pa->v0) / (nv - 1) / (c.point ? 1 : c.nseg));
	for (int ti = 0; ti < (c.moving ? 2 : 1); ti++) {
		if (c.point)
			dice_disk(&c, pa, ti, g);
		else
			dice_ribbon(&c, pa, ti, rows, g);
	}
	/* "N" shades only where it orients the ribbons (normals_of). */
	struct cpiece_fill cf = { &c, rows, g->nu, g->nv };
	if (!reyes_grid_fill_vars(g, c.p, normals_of(&c) != NULL, cpiece_fill, &cf))
		goto fail;
	free(rows);
	return true;
fail:
	free(rows);
	reyes_grid_finish(g);
	return false;
}

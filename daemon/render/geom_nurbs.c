/*
 * NuPatch geometry and trim regions (see nurbs.h).
 *
 * Pieces. Piece su + sv * nus is the pair of the su-th non-empty u span and
 * the sv-th non-empty v span, over [max(knot[i], umin), min(knot[i + 1],
 * umax)] (and the same in v). A piece a trim curve cuts away entirely is
 * left out. On a piece, the surface is the span's polynomial in homogeneous
 * coordinates: S(u, v) = sum N_k(u) N_l(v) w_kl (P_kl, 1), P = S.xyz / S.w.
 *
 * Bounds. The Bezier points of a span restricted to [a, b] are its blossoms
 * at (a, ..., a, b, ..., b) (de Boor's algorithm with a different argument
 * at each level); with positive weights the rational surface lies in the
 * hull of the projected Bezier points, and the hull shrinks with the
 * sub-range, so splitting converges.
 *
 * Primitive variables (RISpec): uniform per segment (segment index
 * i - (uorder - 1) along u), varying at the (nu - uorder + 2) x
 * (nv - vorder + 2) segment corners (bilinear over the span), facevarying 4
 * per segment (corners in the order (0,0) (1,0) (0,1) (1,1)), vertex through
 * the rational basis (weighted as P is).
 */
#include "nurbs.h"

#include "log.h"
#include "mathlib.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAXO REYES_NURBS_MAX_ORDER

/* ---- basis ---- */

/*
 * The p + 1 basis functions of degree p nonzero on span i of knots @t, at x
 * (N[k] belongs to control point i - p + k), and their derivatives.
 */
static void basis(const float *t, uint32_t i, uint32_t p, double x, double *N, double *dN)
{
	double left[MAXO + 1], right[MAXO + 1], Nm[MAXO + 1];
	N[0] = 1.0;
	for (uint32_t j = 1; j <= p; j++) {
		if (j == p)
			memcpy(Nm, N, sizeof(double) * p);
		left[j] = x - t[i + 1 - j];
		right[j] = t[i + j] - x;
		double saved = 0.0;
		for (uint32_t r = 0; r < j; r++) {
			double den = right[r + 1] + left[j - r];
			double tmp = den != 0.0 ? N[r] / den : 0.0;
			N[r] = saved + right[r + 1] * tmp;
			saved = left[j - r] * tmp;
		}
		N[j] = saved;
	}
	for (uint32_t k = 0; k <= p; k++) {
		uint32_t g = i - p + k;
		double d = 0.0;
		if (k > 0 && t[g + p] > t[g])
			d += Nm[k - 1] / ((double)t[g + p] - t[g]);
		if (k < p && t[g + p + 1] > t[g + 1])
			d -= Nm[k] / ((double)t[g + p + 1] - t[g + 1]);
		dN[k] = p * d;
	}
}

/*
 * The Bezier points of span i (degree p) restricted to [a, b]: out[k] is
 * the blossom at a (p - k times) and b (k times) of the span's p + 1
 * control points @src (@dim doubles each).
 */
static void bezier_points(const float *t, uint32_t i, uint32_t p, double a, double b,
			  const double *src, int dim, double *out)
{
	double d[MAXO + 1][4];
	for (uint32_t k = 0; k <= p; k++) {
		memcpy(d, src, sizeof(double) * 4 * (p + 1));
		for (uint32_t r = 1; r <= p; r++) {
			double x = r <= p - k ? a : b;
			for (uint32_t j = p; j >= r; j--) {
				uint32_t g = i - p + j;
				double al = (x - t[g]) / ((double)t[g + p + 1 - r] - t[g]);
				for (int c = 0; c < dim; c++)
					d[j][c] = (1.0 - al) * d[j - 1][c] + al * d[j][c];
			}
		}
		memcpy(&out[4 * k], d[p], sizeof(double) * 4);
	}
}

/* ---- checking ---- */

static const char *knots_ok(const float *k, uint32_t n, uint32_t order, float *lo, float *hi)
{
	if (order < 2)
		return "an order is below 2";
	if (order > MAXO)
		return "an order is above 32 (not supported)";
	if (n < order)
		return "fewer control points than the order along a direction";
	for (uint32_t i = 0; i < n + order; i++) {
		if (!isfinite(k[i]))
			return "a knot is not finite";
		if (i && k[i] < k[i - 1])
			return "a knot vector decreases";
	}
	if (!(isfinite(*lo) && isfinite(*hi) && *lo < *hi))
		return "a parameter range is empty (min is not below max)";
	float a = k[order - 1], b = k[n];
	if (*lo > b || *hi < a)
		return "a parameter range lies outside the knots";
	*lo = *lo < a ? a : *lo;
	*hi = *hi > b ? b : *hi;
	if (!(*lo < *hi))
		return "a parameter range is empty within the knots";
	return NULL;
}

static uint32_t *spans(const float *k, uint32_t n, uint32_t order, float lo, float hi,
		       uint32_t *count, void *(*alloc)(void *, size_t), void *ctx)
{
	uint32_t c = 0;
	for (uint32_t i = order - 1; i < n; i++)
		c += fmaxf(k[i], lo) < fminf(k[i + 1], hi);
	uint32_t *s = alloc(ctx, sizeof(uint32_t) * (c ? c : 1));
	c = 0;
	for (uint32_t i = order - 1; i < n; i++)
		if (fmaxf(k[i], lo) < fminf(k[i + 1], hi))
			s[c++] = i;
	*count = c;
	return s;
}

const char *reyes_nurbs_prepare(struct reyes_nurbs *n, void *(*alloc)(void *, size_t),
				void *ctx)
{
	const char *why = knots_ok(n->uknot, n->nu, n->uorder, &n->umin, &n->umax);
	if (!why)
		why = knots_ok(n->vknot, n->nv, n->vorder, &n->vmin, &n->vmax);
	if (why)
		return why;
	if ((uint64_t)n->nu * n->nv > UINT32_MAX / 4)
		return "too many control points";
	for (uint64_t k = 0; n->w && k < (uint64_t)n->nu * n->nv; k++)
		if (!(n->w[k] > 0) || !isfinite(n->w[k]))
			return "a weight (\"Pw\"'s w) is not positive (not supported)";
	n->uspan = spans(n->uknot, n->nu, n->uorder, n->umin, n->umax, &n->nus, alloc, ctx);
	n->vspan = spans(n->vknot, n->nv, n->vorder, n->vmin, n->vmax, &n->nvs, alloc, ctx);
	if (!n->nus || !n->nvs)
		return "no knot span is non-empty within the parameter ranges";
	if ((uint64_t)n->nus * n->nvs > UINT32_MAX / 4)
		return "too many knot spans";
	return NULL;
}

/* ---- trim regions ---- */

bool reyes_trim_keeps(const struct reyes_trim *t, float u, float v)
{
	bool odd = false;
	if (!(v >= t->lo[1] && v <= t->hi[1] && u <= t->hi[0]))
		return odd != t->keep_even;
	double h = (double)t->hi[1] - t->lo[1];
	uint32_t b = h > 0 ? (uint32_t)(((double)v - t->lo[1]) / h * t->nbands) : 0;
	b = b >= t->nbands ? t->nbands - 1 : b;
	for (uint32_t k = t->band_off[b]; k < t->band_off[b + 1]; k++) {
		const float *e = &t->edges[4 * (size_t)t->band_edges[k]];
		if ((e[1] > v) == (e[3] > v))
			continue;
		double x = e[0] + ((double)v - e[1]) * ((double)e[2] - e[0]) / ((double)e[3] - e[1]);
		if (x > u)
			odd = !odd;
	}
	return odd != t->keep_even;
}

struct tbuild {
	float *e;
	uint32_t n, cap;
	double area;
	bool full;
};

static void add_edge(struct tbuild *b, const double p[2], const double q[2])
{
	if (b->n == b->cap) {
		b->full = true;
		return;
	}
	float *e = &b->e[4 * (size_t)b->n++];
	e[0] = (float)p[0], e[1] = (float)p[1], e[2] = (float)q[0], e[3] = (float)q[1];
	b->area += p[0] * q[1] - q[0] * p[1];
}

/* Samples per non-empty span of a trim curve of order @k. */
static uint32_t trim_steps(uint32_t k)
{
	uint32_t s = 32 * (k - 1);
	return s < 16 ? 16 : s;
}

/* Flatten one curve into edges from *prev on (*first set by the first point). */
static const char *flatten(struct tbuild *b, uint32_t k, uint32_t n, const float *knot, float lo,
			   float hi, const float *u, const float *v, const float *w, double prev[2],
			   bool *started, double first[2])
{
	const char *why = knots_ok(knot, n, k, &lo, &hi);
	if (why)
		return why;
	for (uint32_t i = 0; i < n; i++)
		if (!isfinite(u[i]) || !isfinite(v[i]) || !(w[i] > 0) || !isfinite(w[i]))
			return "a trim curve point is not finite or has w <= 0";
	uint32_t p = k - 1;
	double N[MAXO + 1], dN[MAXO + 1];
	for (uint32_t i = p; i < n; i++) {
		double a = fmax(knot[i], lo), c = fmin(knot[i + 1], hi);
		if (!(a < c))
			continue;
		uint32_t steps = trim_steps(k);
		for (uint32_t s = 0; s <= steps; s++) {
			double x = s == steps ? c : a + (c - a) * s / steps;
			basis(knot, i, p, x, N, dN);
			double hu = 0.0, hv = 0.0, hw = 0.0;
			for (uint32_t j = 0; j <= p; j++) {
				uint32_t g = i - p + j;
				hu += N[j] * u[g];
				hv += N[j] * v[g];
				hw += N[j] * w[g];
			}
			double q[2] = { hu / hw, hv / hw };
			if (!*started) {
				*started = true;
				first[0] = q[0], first[1] = q[1];
			} else if (q[0] != prev[0] || q[1] != prev[1]) {
				add_edge(b, prev, q);
			}
			prev[0] = q[0], prev[1] = q[1];
		}
	}
	return NULL;
}

static void *talloc(void *(*alloc)(void *, size_t), void *ctx, size_t n)
{
	return alloc(ctx, n ? n : 1);
}

/* The bands of each edge for @nb bands; the number of (band, edge) entries. */
static uint64_t band_ranges(const struct reyes_trim *t, uint32_t nb, uint32_t (*range)[2])
{
	double h = (double)t->hi[1] - t->lo[1];
	uint64_t total = 0;
	for (uint32_t k = 0; k < t->nedges; k++) {
		const float *e = &t->edges[4 * (size_t)k];
		double a = fmin(e[1], e[3]), b = fmax(e[1], e[3]);
		uint32_t b0 = h > 0 ? (uint32_t)((a - t->lo[1]) / h * nb) : 0;
		uint32_t b1 = h > 0 ? (uint32_t)((b - t->lo[1]) / h * nb) : 0;
		b0 = b0 >= nb ? nb - 1 : b0;
		b1 = b1 >= nb ? nb - 1 : b1;
		range[k][0] = b0, range[k][1] = b1;
		total += b1 - b0 + 1;
	}
	return total;
}

static const char *trim_bands(struct reyes_trim *t, void *(*alloc)(void *, size_t), void *ctx)
{
	uint32_t nb = t->nedges / 4;
	nb = nb < 1 ? 1 : nb > 1024 ? 1024 : nb;
	uint32_t (*range)[2] = malloc(sizeof(*range) * (t->nedges ? t->nedges : 1));
	if (!range)
		return "out of memory";
	/* Edges that each span many bands (a zigzag) would make the lists huge: fewer bands. */
	uint64_t total = band_ranges(t, nb, range);
	while (nb > 1 && total > 4 * (uint64_t)t->nedges + 4 * (uint64_t)nb) {
		nb /= 2;
		total = band_ranges(t, nb, range);
	}
	uint32_t *off = talloc(alloc, ctx, sizeof(uint32_t) * (nb + 1));
	memset(off, 0, sizeof(uint32_t) * (nb + 1));
	uint32_t *list = talloc(alloc, ctx, sizeof(uint32_t) * total);
	for (uint32_t k = 0; k < t->nedges; k++)
		for (uint32_t b = range[k][0]; b <= range[k][1]; b++)
			off[b + 1]++;
	for (uint32_t b = 0; b < nb; b++)
		off[b + 1] += off[b];
	uint32_t *fill = calloc(nb, sizeof(uint32_t));
	if (!fill) {
		free(range);
		return "out of memory";
	}
	for (uint32_t k = 0; k < t->nedges; k++)
		for (uint32_t b = range[k][0]; b <= range[k][1]; b++)
			list[off[b] + fill[b]++] = k;
	free(fill);
	free(range);
	t->nbands = nb;
	t->band_off = off;
	t->band_edges = list;
	return NULL;
}

const char *reyes_trim_build(const struct reyes_trim_curves *c, void *(*alloc)(void *, size_t),
			     void *ctx, const struct reyes_trim **out)
{
	*out = NULL;
	uint64_t nk = 0, np = 0, edges = 0;
	for (uint32_t i = 0; i < c->ntotal; i++) {
		if (c->order[i] < 2 || c->order[i] > MAXO)
			return c->order[i] < 2 ? "a trim curve's order is below 2"
					       : "a trim curve's order is above 32 (not supported)";
		if (c->n[i] < c->order[i])
			return "a trim curve has fewer points than its order";
		nk += (uint64_t)c->n[i] + c->order[i];
		np += c->n[i];
		/* each span adds at most steps + 1 edges (one joins it to the span before) */
		edges += (uint64_t)(c->n[i] - c->order[i] + 1) * (trim_steps(c->order[i]) + 1) + 1;
	}
	if (nk != c->nknots)
		return "the knot array's length is not the sum of n + order";
	if (np != c->npoints)
		return "the u, v and w arrays' length is not the sum of n";
	edges += c->nloops;
	if (edges > (1u << 22))
		return "the trim curves are too large";
	struct tbuild b = { .cap = (uint32_t)edges };
	b.e = talloc(alloc, ctx, sizeof(float) * 4 * b.cap);
	uint32_t ci = 0;
	size_t ko = 0, po = 0;
	for (uint32_t l = 0; l < c->nloops; l++) {
		double prev[2] = { 0, 0 }, first[2] = { 0, 0 };
		bool started = false;
		for (uint32_t j = 0; j < c->ncurves[l]; j++, ci++) {
			const char *why = flatten(&b, c->order[ci], c->n[ci], c->knot + ko,
						  c->min[ci], c->max[ci], c->u + po, c->v + po,
						  c->w + po, prev, &started, first);
			if (why)
				return why;
			ko += (size_t)c->n[ci] + c->order[ci];
			po += c->n[ci];
		}
		if (started && (prev[0] != first[0] || prev[1] != first[1]))
			add_edge(&b, prev, first);
	}
	if (b.full)
		return "the trim curves are too large";
	struct reyes_trim *t = talloc(alloc, ctx, sizeof(*t));
	memset(t, 0, sizeof(*t));
	t->edges = b.e;
	t->nedges = b.n;
	t->keep_even = b.area < 0.0;
	t->lo[0] = t->lo[1] = INFINITY;
	t->hi[0] = t->hi[1] = -INFINITY;
	for (uint32_t k = 0; k < b.n; k++)
		for (int q = 0; q < 2; q++)
			for (int d = 0; d < 2; d++) {
				float x = b.e[4 * (size_t)k + 2 * q + d];
				t->lo[d] = fminf(t->lo[d], x);
				t->hi[d] = fmaxf(t->hi[d], x);
			}
	if (!b.n)
		t->lo[0] = t->lo[1] = t->hi[0] = t->hi[1] = 0.0f;
	const char *why = trim_bands(t, alloc, ctx);
	if (why)
		return why;
	*out = t;
	return NULL;
}

/* ---- pieces ---- */

struct span {
	const struct reyes_nurbs *n;
	uint32_t iu, iv;             /* knot spans */
	uint32_t su, sv;             /* segment indices (for uniform and varying data) */
	double u0, u1, v0, v1;       /* the piece's range in u and v */
	const float *P[2];
};

static bool span_of(const struct reyes_patch *pa, struct span *s)
{
	const struct reyes_prim *p = pa ? pa->prim : NULL;
	if (!p || p->kind != REYES_NUPATCH || !p->nurbs)
		return false;
	const struct reyes_nurbs *n = p->nurbs;
	if (pa->piece >= n->nus * n->nvs)
		return false;
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	if (!P || !P->values || P->count < n->nu * n->nv)
		return false;
	s->n = n;
	s->iu = n->uspan[pa->piece % n->nus];
	s->iv = n->vspan[pa->piece / n->nus];
	s->su = s->iu - (n->uorder - 1);
	s->sv = s->iv - (n->vorder - 1);
	s->u0 = fmax(n->uknot[s->iu], n->umin);
	s->u1 = fmin(n->uknot[s->iu + 1], n->umax);
	s->v0 = fmax(n->vknot[s->iv], n->vmin);
	s->v1 = fmin(n->vknot[s->iv + 1], n->vmax);
	s->P[0] = P->values;
	s->P[1] = P->values1 ? P->values1 : P->values;
	return true;
}

/* Is the (u, v) rectangle cut away entirely by @t? */
static bool trimmed_out(const struct reyes_trim *t, double u0, double u1, double v0, double v1)
{
	for (uint32_t k = 0; k < t->nedges; k++) {
		const float *e = &t->edges[4 * (size_t)k];
		if (fmax(e[0], e[2]) >= u0 && fmin(e[0], e[2]) <= u1 && fmax(e[1], e[3]) >= v0 &&
		    fmin(e[1], e[3]) <= v1)
			return false;
	}
	return !reyes_trim_keeps(t, (float)(0.5 * (u0 + u1)), (float)(0.5 * (v0 + v1)));
}

bool reyes_nurbs_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
			size_t *cap)
{
	const struct reyes_nurbs *nb = p->nurbs;
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	if (!nb || !P || !P->values || P->count < nb->nu * nb->nv || !nb->nus || !nb->nvs) {
		rl_log(RL_LOG_ERROR, "primitive %u (NuPatch): malformed", p->id);
		return false;
	}
	for (size_t i = 0; i < 3 * (size_t)nb->nu * nb->nv; i++)
		if (!isfinite(P->values[i]) || (P->values1 && !isfinite(P->values1[i]))) {
			rl_log(RL_LOG_ERROR, "primitive %u (NuPatch): a point is not finite", p->id);
			return false;
		}
	size_t count = (size_t)nb->nus * nb->nvs;
	if (*n + count > *cap) {
		size_t nc = *cap ? *cap : 16;
		while (nc < *n + count)
			nc *= 2;
		*out = rl_xrealloc(*out, nc * sizeof(**out));
		*cap = nc;
	}
	/* Culling pieces against the trim curve costs pieces x edges: skip it when huge. */
	const struct reyes_trim *t = nb->trim;
	bool cull = t && (uint64_t)count * t->nedges < 50000000u;
	struct reyes_patch base = { .prim = p, .u0 = 0.0f, .u1 = 1.0f, .v0 = 0.0f, .v1 = 1.0f };
	for (size_t i = 0; i < count; i++) {
		base.piece = (uint32_t)i;
		struct span s;
		if (cull && span_of(&base, &s) && trimmed_out(t, s.u0, s.u1, s.v0, s.v1))
			continue;
		(*out)[(*n)++] = base;
	}
	return true;
}

/* The span's homogeneous control points: row l (v), column k (u). */
static void span_points(const struct span *s, const float *vals, double H[MAXO][MAXO][4])
{
	const struct reyes_nurbs *n = s->n;
	uint32_t pu = n->uorder - 1, pv = n->vorder - 1;
	for (uint32_t l = 0; l <= pv; l++)
		for (uint32_t k = 0; k <= pu; k++) {
			size_t idx = (size_t)(s->iv - pv + l) * n->nu + (s->iu - pu + k);
			double w = n->w ? n->w[idx] : 1.0;
			for (int c = 0; c < 3; c++)
				H[l][k][c] = vals[3 * idx + (size_t)c] * w;
			H[l][k][3] = w;
		}
}

void reyes_nurbs_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3])
{
	struct span s;
	if (!span_of(pa, &s)) {
		for (int c = 0; c < 3; c++)
			lo[c] = hi[c] = 0.0f;
		return;
	}
	const struct reyes_nurbs *n = s.n;
	uint32_t pu = n->uorder - 1, pv = n->vorder - 1;
	static _Thread_local double H[MAXO][MAXO][4], R[MAXO][MAXO][4];
	span_points(&s, s.P[t ? 1 : 0], H);
	double a = s.u0 + (s.u1 - s.u0) * pa->u0, b = s.u0 + (s.u1 - s.u0) * pa->u1;
	double c = s.v0 + (s.v1 - s.v0) * pa->v0, d = s.v0 + (s.v1 - s.v0) * pa->v1;
	/* Along u for each row, then along v for each column. */
	double tmp[MAXO][4], col[MAXO][4], outp[MAXO][4];
	for (uint32_t l = 0; l <= pv; l++)
		bezier_points(n->uknot, s.iu, pu, a, b, &H[l][0][0], 4, &R[l][0][0]);
	double blo[3] = { INFINITY, INFINITY, INFINITY }, bhi[3] = { -INFINITY, -INFINITY, -INFINITY };
	for (uint32_t k = 0; k <= pu; k++) {
		for (uint32_t l = 0; l <= pv; l++)
			memcpy(col[l], R[l][k], sizeof(col[l]));
		bezier_points(n->vknot, s.iv, pv, c, d, &col[0][0], 4, &outp[0][0]);
		for (uint32_t m = 0; m <= pv; m++) {
			memcpy(tmp[m], outp[m], sizeof(tmp[m]));
			for (int q = 0; q < 3; q++) {
				double x = tmp[m][q] / tmp[m][3];
				blo[q] = fmin(blo[q], x);
				bhi[q] = fmax(bhi[q], x);
			}
		}
	}
	reyes_bound_to_float(blo, bhi, lo, hi);
}

/* ---- dicing ---- */

struct ndice {
	uint32_t nu, nv, n;
	uint32_t pu, pv;
	double *u, *v;           /* parameters of columns and rows */
	double *Nu, *dNu, *Nv, *dNv; /* (p + 1) weights per column / row */
};

/* Homogeneous position and derivatives at grid point (i, j) from @vals (3 floats per point). */
static void eval_point(const struct span *s, const struct ndice *d, uint32_t i, uint32_t j,
		       const float *vals, double P[3], double du[3], double dv[3])
{
	const struct reyes_nurbs *n = s->n;
	const double *Nu = &d->Nu[i * (d->pu + 1)], *dNu = &d->dNu[i * (d->pu + 1)];
	const double *Nv = &d->Nv[j * (d->pv + 1)], *dNv = &d->dNv[j * (d->pv + 1)];
	double S[4] = { 0 }, Su[4] = { 0 }, Sv[4] = { 0 };
	for (uint32_t l = 0; l <= d->pv; l++)
		for (uint32_t k = 0; k <= d->pu; k++) {
			size_t idx = (size_t)(s->iv - d->pv + l) * n->nu + (s->iu - d->pu + k);
			double w = n->w ? n->w[idx] : 1.0;
			double h[4] = { vals[3 * idx] * w, vals[3 * idx + 1] * w, vals[3 * idx + 2] * w,
					w };
			double a = Nu[k] * Nv[l], b = dNu[k] * Nv[l], c = Nu[k] * dNv[l];
			for (int q = 0; q < 4; q++) {
				S[q] += a * h[q];
				Su[q] += b * h[q];
				Sv[q] += c * h[q];
			}
		}
	for (int q = 0; q < 3; q++) {
		P[q] = S[q] / S[3];
		du[q] = (Su[q] - P[q] * Su[3]) / S[3];
		dv[q] = (Sv[q] - P[q] * Sv[3]) / S[3];
	}
}

/* The same at any (u, v) of the span (for normals where the grid's vanish). */
static void eval_at(const struct span *s, double u, double v, double P[3], double du[3],
		    double dv[3])
{
	const struct reyes_nurbs *n = s->n;
	double Nu[MAXO + 1], dNu[MAXO + 1], Nv[MAXO + 1], dNv[MAXO + 1];
	basis(n->uknot, s->iu, n->uorder - 1, u, Nu, dNu);
	basis(n->vknot, s->iv, n->vorder - 1, v, Nv, dNv);
	double uu = 0, vv = 0;
	struct ndice d = { 1, 1, 1, n->uorder - 1, n->vorder - 1, &uu, &vv, Nu, dNu, Nv, dNv };
	eval_point(s, &d, 0, 0, s->P[0], P, du, dv);
}

static void cross(double r[3], const double a[3], const double b[3])
{
	r[0] = a[1] * b[2] - a[2] * b[1];
	r[1] = a[2] * b[0] - a[0] * b[2];
	r[2] = a[0] * b[1] - a[1] * b[0];
}

static double len3(const double a[3])
{
	return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/* Interpolate @var over the grid into @dst (stride planes of n floats); false if it does not fit. */
static bool dice_var(const struct span *s, const struct ndice *d, const struct reyes_primvar *var,
		     float *dst)
{
	const struct reyes_nurbs *nb = s->n;
	size_t st = reyes_primvar_stride(var), n = d->n;
	const float *vals = var->values;
	if (!st || !vals)
		return false;
	uint32_t nsu = nb->nu - nb->uorder + 1, nsv = nb->nv - nb->vorder + 1;
	uint32_t seg = s->sv * nsu + s->su;
	switch (var->cls) {
	case REYES_CONSTANT:
	case REYES_UNIFORM: {
		uint32_t item = var->cls == REYES_UNIFORM ? seg : 0;
		if (item >= var->count || (var->cls == REYES_UNIFORM && var->count != nsu * nsv))
			return false;
		for (size_t e = 0; e < st; e++)
			for (size_t k = 0; k < n; k++)
				dst[e * n + k] = sl_to_float(vals[item * st + e]);
		return true;
	}
	case REYES_VERTEX: {
		if (var->count < nb->nu * nb->nv)
			return false;
		for (uint32_t j = 0; j < d->nv; j++)
			for (uint32_t i = 0; i < d->nu; i++) {
				const double *Nu = &d->Nu[i * (d->pu + 1)], *Nv = &d->Nv[j * (d->pv + 1)];
				double wsum = 0.0;
				for (size_t e = 0; e < st; e++)
					dst[e * n + j * d->nu + i] = 0.0f;
				double acc[64];
				size_t chunk = st < 64 ? st : 64;
				for (size_t e0 = 0; e0 < st; e0 += chunk) {
					size_t e1 = e0 + chunk > st ? st : e0 + chunk;
					for (size_t e = e0; e < e1; e++)
						acc[e - e0] = 0.0;
					wsum = 0.0;
					for (uint32_t l = 0; l <= d->pv; l++)
						for (uint32_t k = 0; k <= d->pu; k++) {
							size_t idx = (size_t)(s->iv - d->pv + l) * nb->nu +
								     (s->iu - d->pu + k);
							double w = Nu[k] * Nv[l] * (nb->w ? nb->w[idx] : 1.0);
							wsum += w;
							for (size_t e = e0; e < e1; e++)
								acc[e - e0] += w * vals[idx * st + e];
						}
					for (size_t e = e0; e < e1; e++)
						dst[e * n + j * d->nu + i] = sl_to_float(acc[e - e0] / wsum);
				}
			}
		return true;
	}
	case REYES_VARYING:
	case REYES_FACEVARYING:
		break;
	default:
		return false;
	}
	uint32_t item[4];
	if (var->cls == REYES_VARYING) {
		uint32_t nvu = nsu + 1;
		if (var->count != nvu * (nsv + 1))
			return false;
		for (int k = 0; k < 4; k++)
			item[k] = (s->sv + (uint32_t)(k / 2)) * nvu + s->su + (uint32_t)(k % 2);
	} else {
		if (var->count != 4 * nsu * nsv)
			return false;
		for (int k = 0; k < 4; k++)
			item[k] = 4 * seg + (uint32_t)k;
	}
	double ku0 = nb->uknot[s->iu], ku1 = nb->uknot[s->iu + 1];
	double kv0 = nb->vknot[s->iv], kv1 = nb->vknot[s->iv + 1];
	for (size_t e = 0; e < st; e++)
		for (uint32_t j = 0; j < d->nv; j++) {
			double t = (d->v[j] - kv0) / (kv1 - kv0);
			for (uint32_t i = 0; i < d->nu; i++) {
				double a = (d->u[i] - ku0) / (ku1 - ku0);
				double x = (1 - a) * (1 - t) * vals[item[0] * st + e] +
					   a * (1 - t) * vals[item[1] * st + e] +
					   (1 - a) * t * vals[item[2] * st + e] + a * t * vals[item[3] * st + e];
				dst[e * n + j * d->nu + i] = sl_to_float(x);
			}
		}
	return true;
}

/* Where dPdu ^ dPdv vanishes (a pole), the normal a little way in towards the piece's middle. */
static void fix_normal(const struct span *s, double u, double v, double N[3])
{
	double mu = 0.5 * (s->u0 + s->u1), mv = 0.5 * (s->v0 + s->v1);
	for (double f = 1e-4; f < 0.6; f *= 10.0) {
		double P[3], du[3], dv[3], M[3];
		eval_at(s, u + (mu - u) * f, v + (mv - v) * f, P, du, dv);
		cross(M, du, dv);
		if (len3(M) > 0.0) {
			memcpy(N, M, sizeof(M));
			return;
		}
	}
}

/* A span's interpolation of one variable, for reyes_grid_fill_vars. */
struct span_fill {
	const struct span *s;
	const struct ndice *d;
};

static bool span_fill(const void *ctx, const struct reyes_primvar *v, float *dst)
{
	const struct span_fill *f = ctx;
	return dice_var(f->s, f->d, v, dst);
}

bool reyes_nurbs_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		      struct reyes_grid *g)
{
	memset(g, 0, sizeof(*g));
	struct span s;
	if (!span_of(pa, &s))
		return false;
	const struct reyes_prim *p = pa->prim;
	nu = nu < 2 ? 2 : nu;
	nv = nv < 2 ? 2 : nv;
	if ((uint64_t)nu * nv > (1u << 26))
		return false;
	uint32_t n = nu * nv;
	g->nu = nu, g->nv = nv, g->n = n;
	struct ndice d = { nu, nv, n, s.n->uorder - 1, s.n->vorder - 1, NULL, NULL, NULL, NULL,
			   NULL, NULL };
	bool moving = s.P[1] != s.P[0];
	size_t wu = (size_t)nu * (d.pu + 1), wv = (size_t)nv * (d.pv + 1);
	double *buf = malloc(sizeof(double) * (nu + nv + 2 * wu + 2 * wv));
	if (!reyes_grid_alloc(g, n, moving) || !buf)
		goto fail;
	d.u = buf, d.v = buf + nu;
	d.Nu = d.v + nv, d.dNu = d.Nu + wu, d.Nv = d.dNu + wu, d.dNv = d.Nv + wv;
	double a = s.u0 + (s.u1 - s.u0) * pa->u0, b = s.u0 + (s.u1 - s.u0) * pa->u1;
	double c = s.v0 + (s.v1 - s.v0) * pa->v0, e = s.v0 + (s.v1 - s.v0) * pa->v1;
	for (uint32_t i = 0; i < nu; i++) {
		d.u[i] = i == nu - 1 ? b : a + (b - a) * i / (nu - 1);
		basis(s.n->uknot, s.iu, d.pu, d.u[i], &d.Nu[i * (d.pu + 1)], &d.dNu[i * (d.pu + 1)]);
	}
	for (uint32_t j = 0; j < nv; j++) {
		d.v[j] = j == nv - 1 ? e : c + (e - c) * j / (nv - 1);
		basis(s.n->vknot, s.iv, d.pv, d.v[j], &d.Nv[j * (d.pv + 1)], &d.dNv[j * (d.pv + 1)]);
	}
	g->du = (float)((b - a) / (nu - 1));
	g->dv = (float)((e - c) / (nv - 1));
	double maxu = 0.0, maxv = 0.0;
	for (uint32_t j = 0; j < nv; j++)
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			double P[3], du[3], dv[3], N[3];
			eval_point(&s, &d, i, j, s.P[0], P, du, dv);
			cross(N, du, dv);
			maxu = fmax(maxu, len3(du));
			maxv = fmax(maxv, len3(dv));
			if (moving) {
				double P1[3], x[3], y[3];
				eval_point(&s, &d, i, j, s.P[1], P1, x, y);
				for (int q = 0; q < 3; q++)
					g->P[1][q * n + k] = sl_to_float(P1[q]);
			}
			for (int q = 0; q < 3; q++) {
				g->P[0][q * n + k] = sl_to_float(P[q]);
				g->dPdu[q * n + k] = sl_to_float(du[q]);
				g->dPdv[q * n + k] = sl_to_float(dv[q]);
				g->Ng[q * n + k] = sl_to_float(N[q]);
			}
			g->u[k] = (float)d.u[i];
			g->v[k] = (float)d.v[j];
		}
	for (uint32_t j = 0; j < nv; j++)
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			double N[3] = { g->Ng[k], g->Ng[n + k], g->Ng[2 * n + k] };
			if (len3(N) > 1e-6 * maxu * maxv)
				continue;
			fix_normal(&s, d.u[i], d.v[j], N);
			for (int q = 0; q < 3; q++)
				g->Ng[q * n + k] = sl_to_float(N[q]);
		}
	if (p->attrs && p->attrs->flip_normals)
		for (size_t k = 0; k < 3 * (size_t)n; k++)
			g->Ng[k] = -g->Ng[k];
	struct span_fill sf = { &s, &d };
	if (!reyes_grid_fill_vars(g, p, true, span_fill, &sf))
		goto fail;
	free(buf);
	return true;
fail:
	free(buf);
	reyes_grid_finish(g);
	return false;
}

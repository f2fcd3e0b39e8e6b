/*
 * Subdivision meshes: Catmull-Clark limit surfaces through OpenSubdiv
 * (subdiv_osd.h), cut into REYES pieces.
 *
 * Pieces. Every base face with a limit surface gives one piece per quad
 * sub-face of OpenSubdiv's parameterization: one for a quad, n for an n-gon
 * (holes, and faces that a boundary without interpolation leaves without a
 * limit surface, give none). Piece numbers run over all faces' sub-faces in
 * order, first[f] + sub, so a piece names its face whatever faces are holes.
 * u and v on a piece are its sub-face's normalized parameters, 0..1, as
 * prman gives them per face.
 *
 * Dicing evaluates the limit surface itself at the grid's parameters, with
 * its derivatives for dPdu, dPdv and the geometric normal (the limit
 * normal: an "N" given on the mesh is not used, as prman does not). Points on
 * an edge two faces share are the same limit curve evaluated from either
 * side, so grids of neighbouring faces meet on the surface.
 *
 * Primitive variables: constant and uniform (per face) values as given;
 * vertex data through the limit surface as P; varying data bilinear over the
 * face (OpenSubdiv's varying surface); face-varying data through the limit
 * of its own channel, where corners around a vertex that hold the same
 * value share it and differing values are a seam.
 *
 * The OpenSubdiv meshes (topology only, built once) live in a small
 * process-wide cache keyed by the mesh's serial number and its variables.
 */
#include "geom_subdiv.h"

#include "log.h"
#include "mathlib.h"
#include "subdiv_osd.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#define CACHE_SLOTS 64

struct sd_mesh {
	uint64_t serial;
	const struct reyes_primvar *vars;   /* what the face-varying channels were welded from */
	struct osd_mesh *osd;
	uint32_t nfaces;
	uint32_t *first;                    /* nfaces + 1: piece number of each face's sub-face 0 */
	int *channel;                       /* per primitive variable: its channel, or -1 */
	uint32_t refs;
	uint64_t used;
};

static struct {
	pthread_mutex_t lock;
	struct sd_mesh *slot[CACHE_SLOTS];
	uint64_t clock;
} cache = { .lock = PTHREAD_MUTEX_INITIALIZER };

static void sd_free(struct sd_mesh *m)
{
	if (!m)
		return;
	osd_mesh_destroy(m->osd);
	free(m->first);
	free(m->channel);
	free(m);
}

/*
 * Face-varying indices of @v: the first corner around the same vertex with
 * the same value, so that equal values are one (smooth across the edge)
 * and different ones a seam.
 */
static uint32_t *weld(const struct reyes_subdiv *sd, uint32_t ncorners, uint32_t npoints,
		      const struct reyes_primvar *v)
{
	size_t st = reyes_primvar_stride(v);
	uint32_t *idx = malloc(sizeof(uint32_t) * (ncorners ? ncorners : 1));
	uint32_t *head = malloc(sizeof(uint32_t) * (npoints ? npoints : 1));
	uint32_t *next = malloc(sizeof(uint32_t) * (ncorners ? ncorners : 1));
	if (!idx || !head || !next) {
		free(idx), free(head), free(next);
		return NULL;
	}
	for (uint32_t i = 0; i < npoints; i++)
		head[i] = UINT32_MAX;
	for (uint32_t c = 0; c < ncorners; c++) {
		uint32_t vert = sd->verts[c];
		idx[c] = c;
		for (uint32_t o = head[vert]; o != UINT32_MAX; o = next[o])
			if (memcmp(&v->values[(size_t)o * st], &v->values[(size_t)c * st],
				   st * sizeof(float)) == 0) {
				idx[c] = o;
				break;
			}
		if (idx[c] == c) {
			next[c] = head[vert];
			head[vert] = c;
		}
	}
	free(head);
	free(next);
	return idx;
}

static struct sd_mesh *sd_build(const struct reyes_prim *p, char *why, size_t whylen)
{
	const struct reyes_subdiv *sd = p->subdiv;
	struct sd_mesh *m = calloc(1, sizeof(*m));
	if (!m)
		goto oom;
	m->serial = sd->serial;
	m->vars = p->vars;
	m->nfaces = sd->nfaces;
	m->first = malloc(sizeof(uint32_t) * ((size_t)sd->nfaces + 1));
	m->channel = malloc(sizeof(int) * (p->nvars ? p->nvars : 1));
	uint32_t **index = calloc(p->nvars ? p->nvars : 1, sizeof(uint32_t *));
	uint32_t *nvalues = malloc(sizeof(uint32_t) * (p->nvars ? p->nvars : 1));
	if (!m->first || !m->channel || !index || !nvalues) {
		free(index), free(nvalues);
		goto oom;
	}
	uint64_t ncorners = 0;
	for (uint32_t f = 0; f < sd->nfaces; f++)
		ncorners += sd->nverts[f];
	struct osd_topology t = {
		.npoints = p->npoints, .nfaces = sd->nfaces,
		.face_sizes = sd->nverts, .face_verts = sd->verts,
		.ncreases = sd->ncreases, .crease_verts = sd->crease_verts,
		.crease_sharp = sd->crease_sharp,
		.ncorners = sd->ncorners, .corner_verts = sd->corner_verts,
		.corner_sharp = sd->corner_sharp,
		.nholes = sd->nholes, .holes = sd->holes,
		.boundary = (enum osd_boundary)sd->interp_boundary,
		.fvar_boundary = sd->fvar_boundary,
		.channel_index = (const uint32_t *const *)index,
		.channel_nvalues = nvalues,
	};
	bool ok = true;
	for (uint32_t i = 0; i < p->nvars; i++) {
		m->channel[i] = -1;
		const struct reyes_primvar *v = &p->vars[i];
		if (v->cls != REYES_FACEVARYING || !reyes_primvar_stride(v) || v->count != ncorners)
			continue;
		index[t.nchannels] = weld(sd, (uint32_t)ncorners, p->npoints, v);
		if (!index[t.nchannels])
			ok = false;
		nvalues[t.nchannels] = (uint32_t)ncorners;
		m->channel[i] = (int)t.nchannels++;
	}
	if (ok)
		m->osd = osd_mesh_create(&t, why, whylen);
	else
		snprintf(why, whylen, "out of memory");
	for (uint32_t c = 0; c < t.nchannels; c++)
		free(index[c]);
	free(index);
	free(nvalues);
	if (!m->osd) {
		sd_free(m);
		return NULL;
	}
	m->first[0] = 0;
	for (uint32_t f = 0; f < sd->nfaces; f++)
		m->first[f + 1] = m->first[f] + (sd->nverts[f] == 4 ? 1 : sd->nverts[f]);
	return m;
oom:
	sd_free(m);
	snprintf(why, whylen, "out of memory");
	return NULL;
}

/* The OpenSubdiv mesh of @p, built if not cached; NULL (with @why) if it has none. */
static struct sd_mesh *sd_acquire(const struct reyes_prim *p, char *why, size_t whylen)
{
	if (!p || p->kind != REYES_SUBDIV || !p->subdiv) {
		snprintf(why, whylen, "not a subdivision mesh");
		return NULL;
	}
	pthread_mutex_lock(&cache.lock);
	struct sd_mesh *m = NULL;
	int free_slot = -1, victim = -1;
	for (int i = 0; i < CACHE_SLOTS; i++) {
		struct sd_mesh *e = cache.slot[i];
		if (!e) {
			free_slot = free_slot < 0 ? i : free_slot;
		} else if (e->serial == p->subdiv->serial && e->vars == p->vars) {
			m = e;
			break;
		} else if (!e->refs && (victim < 0 || e->used < cache.slot[victim]->used)) {
			victim = i;
		}
	}
	if (!m) {
		m = sd_build(p, why, whylen);
		int i = free_slot >= 0 ? free_slot : victim;
		if (m && i >= 0) {
			sd_free(cache.slot[i]);
			cache.slot[i] = m;
		} else if (m) {
			m->refs = UINT32_MAX / 2;   /* not cached: the caller frees it */
		}
	}
	if (m) {
		m->refs++;
		m->used = ++cache.clock;
	}
	pthread_mutex_unlock(&cache.lock);
	return m;
}

static void sd_release(struct sd_mesh *m)
{
	if (!m)
		return;
	pthread_mutex_lock(&cache.lock);
	m->refs--;
	bool own = m->refs == UINT32_MAX / 2;
	pthread_mutex_unlock(&cache.lock);
	if (own)
		sd_free(m);
}

/* The face and sub-face of piece @piece; false if out of range. */
static bool piece_face(const struct sd_mesh *m, uint32_t piece, uint32_t *face, uint32_t *sub)
{
	if (piece >= m->first[m->nfaces])
		return false;
	uint32_t lo = 0, hi = m->nfaces;    /* first[lo] <= piece < first[hi] */
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (m->first[mid] <= piece)
			lo = mid;
		else
			hi = mid;
	}
	*face = lo;
	*sub = piece - m->first[lo];
	return true;
}

bool reyes_subdiv_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
			 size_t *cap)
{
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	if (!P || !P->values || reyes_primvar_stride(P) != 3 || P->count < p->npoints) {
		rl_log(RL_LOG_ERROR, "primitive %u (subdivision mesh): \"P\" needs %u points",
		       p->id, p->npoints);
		return false;
	}
	for (size_t i = 0; i < 3 * (size_t)p->npoints; i++)
		if (!isfinite(P->values[i]) || (P->values1 && !isfinite(P->values1[i]))) {
			rl_log(RL_LOG_ERROR, "primitive %u (subdivision mesh): a point is not finite",
			       p->id);
			return false;
		}
	char why[256] = "";
	struct sd_mesh *m = sd_acquire(p, why, sizeof(why));
	if (!m) {
		rl_log(RL_LOG_ERROR, "primitive %u (subdivision mesh): %s", p->id, why);
		return false;
	}
	size_t count = 0;
	for (uint32_t f = 0; f < m->nfaces; f++)
		if (!osd_face_hole(m->osd, f))
			count += m->first[f + 1] - m->first[f];
	if (*n + count > *cap) {
		size_t nc = *cap ? *cap : 16;
		while (nc < *n + count)
			nc *= 2;
		*out = rl_xrealloc(*out, nc * sizeof(**out));
		*cap = nc;
	}
	struct reyes_patch base = { .prim = p, .u0 = 0.0f, .u1 = 1.0f, .v0 = 0.0f, .v1 = 1.0f };
	for (uint32_t f = 0; f < m->nfaces; f++) {
		if (osd_face_hole(m->osd, f))
			continue;
		for (uint32_t k = m->first[f]; k < m->first[f + 1]; k++) {
			base.piece = k;
			(*out)[(*n)++] = base;
		}
	}
	sd_release(m);
	return true;
}

/* Evaluate the limit positions (and derivatives) of a piece at @n (u, v) pairs. */
static bool eval_P(const struct sd_mesh *m, const struct reyes_patch *pa, const float *vals,
		   uint32_t n, const double *uv, double *P, double *du, double *dv)
{
	uint32_t face, sub;
	if (!piece_face(m, pa->piece, &face, &sub))
		return false;
	return osd_eval(m->osd, face, sub, OSD_VERTEX, 0, vals, 3, n, uv, P, du, dv);
}

static const float *points_at(const struct reyes_prim *p, int t)
{
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	if (!P || !P->values || reyes_primvar_stride(P) != 3 || P->count < p->npoints)
		return NULL;
	return t && P->values1 ? P->values1 : P->values;
}

/*
 * The bound of a piece's range: the hull of the face's control points (the
 * limit surface lies in it), narrowed to the box of 9 x 9 limit points over
 * the range padded by twice the most any cell's midpoint strays from its
 * corners' average (how far the surface bulges between the samples).
 */
void reyes_subdiv_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3])
{
	enum { S = 9 };
	for (int c = 0; c < 3; c++)
		lo[c] = hi[c] = 0.0f;
	char why[64];
	const float *vals = pa ? points_at(pa->prim, t) : NULL;
	struct sd_mesh *m = vals ? sd_acquire(pa->prim, why, sizeof(why)) : NULL;
	if (!m)
		return;
	uint32_t face, sub;
	double hlo[3], hhi[3], uv[2 * S * S], P[3 * S * S];
	bool ok = piece_face(m, pa->piece, &face, &sub) &&
		  osd_face_hull(m->osd, face, vals, hlo, hhi);
	for (int j = 0; j < S; j++)
		for (int i = 0; i < S; i++) {
			uv[2 * (j * S + i)] = pa->u0 + (pa->u1 - pa->u0) * (double)i / (S - 1);
			uv[2 * (j * S + i) + 1] = pa->v0 + (pa->v1 - pa->v0) * (double)j / (S - 1);
		}
	ok = ok && eval_P(m, pa, vals, S * S, uv, P, NULL, NULL);
	sd_release(m);
	if (!ok)
		return;
	double blo[3] = { INFINITY, INFINITY, INFINITY }, bhi[3] = { -INFINITY, -INFINITY, -INFINITY };
	double bulge = 0.0;
	for (int k = 0; k < S * S; k++)
		for (int c = 0; c < 3; c++) {
			blo[c] = fmin(blo[c], P[3 * k + c]);
			bhi[c] = fmax(bhi[c], P[3 * k + c]);
		}
	for (int j = 1; j < S - 1; j += 2)
		for (int i = 1; i < S - 1; i += 2) {
			double d2 = 0.0;
			for (int c = 0; c < 3; c++) {
				double avg = 0.25 * (P[3 * ((j - 1) * S + i - 1) + c] +
						     P[3 * ((j - 1) * S + i + 1) + c] +
						     P[3 * ((j + 1) * S + i - 1) + c] +
						     P[3 * ((j + 1) * S + i + 1) + c]);
				double d = P[3 * (j * S + i) + c] - avg;
				d2 += d * d;
			}
			bulge = fmax(bulge, sqrt(d2));
		}
	for (int c = 0; c < 3; c++) {
		blo[c] = fmax(blo[c] - 2.0 * bulge, hlo[c]);
		bhi[c] = fmin(bhi[c] + 2.0 * bulge, hhi[c]);
		if (!(blo[c] <= bhi[c]))
			blo[c] = hlo[c], bhi[c] = hhi[c];
	}
	reyes_bound_to_float(blo, bhi, lo, hi);
}

/* ---- dicing ---- */

struct sd_dice {
	const struct sd_mesh *m;
	const struct reyes_prim *p;
	uint32_t face, sub, n;
	const double *uv;       /* normalized sub-face parameters of the grid points */
	double *tmp;            /* n * stride doubles */
};

/* Interpolate @v over the grid into @dst (planar); false if it does not fit the mesh. */
static bool sd_var(const struct sd_dice *d, const struct reyes_primvar *v, const float *vals,
		   float *dst)
{
	size_t st = reyes_primvar_stride(v);
	uint32_t n = d->n;
	if (!st || !vals)
		return false;
	if (v->cls == REYES_CONSTANT || v->cls == REYES_UNIFORM) {
		uint32_t item = v->cls == REYES_UNIFORM ? d->face : 0;
		if (item >= v->count)
			return false;
		for (size_t e = 0; e < st; e++)
			for (uint32_t k = 0; k < n; k++)
				dst[e * n + k] = sl_to_float(vals[(size_t)item * st + e]);
		return true;
	}
	enum osd_data data = OSD_VERTEX;
	uint32_t channel = 0;
	if (v->cls == REYES_VERTEX || v->cls == REYES_VARYING) {
		if (v->count < d->p->npoints)
			return false;
		data = v->cls == REYES_VERTEX ? OSD_VERTEX : OSD_VARYING;
	} else {
		int c = (int)(v - d->p->vars);
		if (c < 0 || (uint32_t)c >= d->p->nvars || d->m->channel[c] < 0)
			return false;
		data = OSD_FACEVARYING;
		channel = (uint32_t)d->m->channel[c];
	}
	if (!osd_eval(d->m->osd, d->face, d->sub, data, channel, vals, (uint32_t)st, n, d->uv,
		      d->tmp, NULL, NULL))
		return false;
	for (size_t e = 0; e < st; e++)
		for (uint32_t k = 0; k < n; k++)
			dst[e * n + k] = sl_to_float(d->tmp[(size_t)k * st + e]);
	return true;
}

/* For reyes_grid_fill_vars. */
static bool sd_fill(const void *ctx, const struct reyes_primvar *v, float *dst)
{
	return sd_var(ctx, v, v->values, dst);
}

/*
 * Where the limit's derivatives are parallel (they are not on a Catmull-Clark
 * surface, but a collapsed cage can make them so) take the normal a little
 * way in towards the middle of the sub-face, its limit.
 */
static void fix_normal(const struct sd_mesh *m, const struct reyes_patch *pa, const float *vals,
		       double u, double v, double N[3])
{
	for (double step = 1e-4; step < 0.5; step *= 10.0) {
		double uv[2] = { u + (u <= 0.5 ? step : -step), v + (v <= 0.5 ? step : -step) };
		double P[3], du[3], dv[3];
		if (!eval_P(m, pa, vals, 1, uv, P, du, dv))
			return;
		double c[3] = { du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2],
				du[0] * dv[1] - du[1] * dv[0] };
		if (c[0] != 0.0 || c[1] != 0.0 || c[2] != 0.0) {
			memcpy(N, c, sizeof(c));
			return;
		}
	}
}

static bool sd_positions(const struct sd_dice *d, const struct reyes_patch *pa,
			 struct reyes_grid *g, double *P, double *du, double *dv)
{
	uint32_t n = d->n;
	const float *v0 = points_at(d->p, 0), *v1 = points_at(d->p, 1);
	if (!eval_P(d->m, pa, v0, n, d->uv, P, du, dv))
		return false;
	for (uint32_t k = 0; k < n; k++) {
		const double *a = &du[3 * k], *b = &dv[3 * k];
		double N[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
				a[0] * b[1] - a[1] * b[0] };
		if (N[0] == 0.0 && N[1] == 0.0 && N[2] == 0.0)
			fix_normal(d->m, pa, v0, d->uv[2 * k], d->uv[2 * k + 1], N);
		for (int c = 0; c < 3; c++) {
			g->P[0][c * n + k] = sl_to_float(P[3 * k + c]);
			g->dPdu[c * n + k] = sl_to_float(a[c]);
			g->dPdv[c * n + k] = sl_to_float(b[c]);
			g->Ng[c * n + k] = sl_to_float(N[c]);
		}
	}
	if (g->P[1] != g->P[0]) {
		if (!eval_P(d->m, pa, v1, n, d->uv, P, NULL, NULL))
			return false;
		for (uint32_t k = 0; k < n; k++)
			for (int c = 0; c < 3; c++)
				g->P[1][c * n + k] = sl_to_float(P[3 * k + c]);
	}
	if (d->p->attrs && d->p->attrs->flip_normals)
		for (size_t k = 0; k < 3 * (size_t)n; k++)
			g->Ng[k] = -g->Ng[k];
	return true;
}

bool reyes_subdiv_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		       struct reyes_grid *g)
{
	memset(g, 0, sizeof(*g));
	const struct reyes_prim *p = pa ? pa->prim : NULL;
	const float *v0 = p ? points_at(p, 0) : NULL;
	char why[64];
	struct sd_mesh *m = v0 ? sd_acquire(p, why, sizeof(why)) : NULL;
	if (!m)
		return false;
	nu = nu < 2 ? 2 : nu;
	nv = nv < 2 ? 2 : nv;
	struct sd_dice d = { .m = m, .p = p };
	if ((uint64_t)nu * nv > (1u << 26) || !piece_face(m, pa->piece, &d.face, &d.sub)) {
		sd_release(m);
		return false;
	}
	uint32_t n = nu * nv;
	size_t maxst = 3;
	for (uint32_t i = 0; i < p->nvars; i++)
		maxst = reyes_primvar_stride(&p->vars[i]) > maxst ? reyes_primvar_stride(&p->vars[i]) : maxst;
	d.n = n;
	double *uv = malloc(sizeof(double) * 2 * n);
	double *P = malloc(sizeof(double) * 9 * n);
	d.tmp = malloc(sizeof(double) * maxst * n);
	d.uv = uv;
	bool moving = points_at(p, 1) != v0, failed = !uv || !P || !d.tmp;
	g->nu = nu, g->nv = nv, g->n = n;
	failed |= !reyes_grid_alloc(g, n, moving);
	if (!failed) {
		double su = ((double)pa->u1 - pa->u0) / (nu - 1), sv = ((double)pa->v1 - pa->v0) / (nv - 1);
		for (uint32_t j = 0; j < nv; j++)
			for (uint32_t i = 0; i < nu; i++) {
				uint32_t k = j * nu + i;
				uv[2 * k] = i == nu - 1 ? pa->u1 : pa->u0 + su * i;
				uv[2 * k + 1] = j == nv - 1 ? pa->v1 : pa->v0 + sv * j;
				g->u[k] = (float)uv[2 * k];
				g->v[k] = (float)uv[2 * k + 1];
			}
		g->du = (float)su;
		g->dv = (float)sv;
		failed = !sd_positions(&d, pa, g, P, P + 3 * (size_t)n, P + 6 * (size_t)n);
	}
	/* The limit normal shades: an "N" given on the mesh is not used (as prman). */
	if (!failed)
		failed = !reyes_grid_fill_vars(g, p, false, sd_fill, &d);
	free(uv);
	free(P);
	free(d.tmp);
	sd_release(m);
	if (failed)
		reyes_grid_finish(g);
	return !failed;
}

bool reyes_subdiv_limit(const struct reyes_prim *p, uint32_t face, uint32_t sub, uint32_t n,
			const double *uv, double *P)
{
	const float *v0 = p ? points_at(p, 0) : NULL;
	char why[64];
	struct sd_mesh *m = v0 ? sd_acquire(p, why, sizeof(why)) : NULL;
	if (!m)
		return false;
	bool ok = face < m->nfaces &&
		  osd_eval(m->osd, face, sub, OSD_VERTEX, 0, v0, 3, n, uv, P, NULL, NULL);
	sd_release(m);
	return ok;
}

bool reyes_subdiv_check(const struct reyes_prim *p, char *why, size_t whylen)
{
	struct sd_mesh *m = sd_acquire(p, why, whylen);
	sd_release(m);
	return m != NULL;
}

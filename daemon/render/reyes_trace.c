/*
 * Ray tracing in the REYES renderer: the rays of the shading language's
 * trace(), transmission(), occlusion(), indirectdiffuse(), and environment()
 * and shadow() of the map "raytrace" (struct sl_host's trace, exec.h).
 *
 * The scene rays see is built once a frame, on the first ray (under a lock:
 * buckets shade on several threads), from the renderer's own dicing: every
 * primitive some ray type sees (Attribute "visibility" "specular",
 * "diffuse", "transmission") is split and diced by its ShadingRate as if
 * the camera turned to face each piece (the size of a pixel at its distance,
 * not its projection: rays see it from every side, so what the camera sees
 * edge on is not diced coarser), and displaced. Each grid's micropolygons are Embree quads in camera space, at
 * shutter open and close when they move (two time steps; a ray's time picks
 * between them), in one Embree scene per ray type sharing the vertex and
 * index buffers; the grid itself (camera-space positions, normals,
 * derivatives, texture coordinates, primitive variables) is kept for
 * shading its hits.
 *
 * A ray starts at its origin moved by the bias along it (the query's, else
 * the shaded object's Attribute "trace" "bias") and reaches what its type
 * sees within [0, maxdist]. Hits are composited front to back through
 * semi-opaque ones until opaque, at most MAX_HITS of them. A hit is shaded
 * as its hit mode says (the query's "hitmode", else the hit object's
 * Attribute "shade"): "primitive" gives its Cs * Os and Os; "shader" runs
 * its surface shader with its lights at the hit, on a grid of 2 x 2 points
 * made from its grid at the hit's parameter and one micropolygon on along u
 * and v (so that derivatives are the micropolygon's), with I along the ray,
 * on a context one ray level deeper (rayinfo "depth"). Shadow rays take
 * 1 - Os of each hit ("opaque": 1). Past Option "trace" "maxdepth", or the
 * casting object's "maxspeculardepth" or "maxdiffusedepth", a ray reaches
 * nothing.
 */
#include "reyes_impl.h"
#include "reyes_trace.h"
#include "mathlib.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_HITS 64

struct rt_grid {
	const struct reyes_prim *prim;
	struct reyes_grid g;        /* kept for its primitive variables */
	struct cgrid c;             /* camera space; c.P0 owns the planes */
	float *verts[2];            /* xyz per point at shutter open and close, padded */
	uint32_t *quads;            /* 4 point indices per kept micropolygon */
	uint32_t *cell;             /* per kept micropolygon: its (i, j) as j * (nu - 1) + i */
	uint32_t nquads;
	bool moving;
};

struct reyes_rt {
	RTCDevice dev;
	RTCScene scene[SL_RAY_TYPE_COUNT];
	struct rt_grid *grids;
	size_t ngrids, cap;
	uint64_t micropolygons, bytes;
};

static bool sees(const struct reyes_attrs *a, enum sl_ray_type type)
{
	switch (type) {
	case SL_RAY_SPECULAR:
		return a->ray.specular;
	case SL_RAY_DIFFUSE:
		return a->ray.diffuse;
	default:
		return a->ray.transmission != REYES_TRANS_NONE;
	}
}

static void grid_free(struct rt_grid *rg)
{
	free(rg->c.P0);
	reyes_grid_finish(&rg->g);
	free(rg->verts[0]);
	free(rg->verts[1]);
	free(rg->quads);
	free(rg->cell);
}

void reyes_rt_destroy(struct reyes_rt *rt)
{
	if (!rt)
		return;
	for (int k = 0; k < SL_RAY_TYPE_COUNT; k++)
		if (rt->scene[k])
			rtcReleaseScene(rt->scene[k]);
	if (rt->dev)
		rtcReleaseDevice(rt->dev);
	for (size_t i = 0; i < rt->ngrids; i++)
		grid_free(&rt->grids[i]);
	free(rt->grids);
	free(rt);
}

/* Keep grid @g, @c of @prim (trimmed by @keep) as rays' geometry. */
static bool add_grid(struct reyes_rt *rt, const struct reyes_prim *prim, struct reyes_grid *g,
		     struct cgrid *c, const uint8_t *keep)
{
	uint32_t nu = c->nu, nv = c->nv, n = c->n;
	if (rt->ngrids == rt->cap) {
		size_t cap = rt->cap ? 2 * rt->cap : 64;
		struct rt_grid *ng = realloc(rt->grids, cap * sizeof(*ng));
		if (!ng)
			return false;
		rt->grids = ng;
		rt->cap = cap;
	}
	struct rt_grid *rg = &rt->grids[rt->ngrids];
	memset(rg, 0, sizeof(*rg));
	rg->prim = prim;
	rg->moving = memcmp(c->P0, c->P1, sizeof(float) * 3 * n) != 0;
	uint32_t ncells = (nu - 1) * (nv - 1);
	rg->quads = malloc(sizeof(uint32_t) * 4 * (ncells ? ncells : 1));
	rg->cell = malloc(sizeof(uint32_t) * (ncells ? ncells : 1));
	for (int ts = 0; ts < (rg->moving ? 2 : 1); ts++)
		rg->verts[ts] = malloc(sizeof(float) * (3 * (size_t)n + 1));
	if (!rg->quads || !rg->cell || !rg->verts[0] || (rg->moving && !rg->verts[1])) {
		grid_free(rg);
		return false;
	}
	/*
	 * Coordinates within a ten-millionth of the grid's size of 0 are 0: the
	 * edges grids share on the axes' planes (a quadric's seams at 90 degree
	 * steps: cos(pi / 2) is 6e-17) then coincide, and a ray along such a
	 * plane cannot pass between two neighbours.
	 */
	float size = 0;
	for (size_t k = 0; k < 3 * (size_t)n; k++)
		size = fmaxf(size, fabsf(c->P0[k]));
	for (int ts = 0; ts < (rg->moving ? 2 : 1); ts++) {
		const float *P = ts ? c->P1 : c->P0;
		for (uint32_t k = 0; k < n; k++)
			for (int q = 0; q < 3; q++) {
				float v = P[(size_t)q * n + k];
				rg->verts[ts][3 * (size_t)k + (size_t)q] = fabsf(v) < 1e-7f * size ? 0 : v;
			}
		rg->verts[ts][3 * (size_t)n] = 0;
	}
	for (uint32_t j = 0; j + 1 < nv; j++)
		for (uint32_t i = 0; i + 1 < nu; i++) {
			uint32_t cidx = j * (nu - 1) + i, k = j * nu + i;
			if (keep && !keep[cidx])
				continue;
			/* Embree cuts a quad (a, b, c, d) along b-d: given from the
			   micropolygon's second corner, that is the hider's v0-v2 cut */
			uint32_t *v = rg->quads + 4 * (size_t)rg->nquads;
			v[0] = k + 1;
			v[1] = k + 1 + nu;
			v[2] = k + nu;
			v[3] = k;
			rg->cell[rg->nquads++] = cidx;
		}
	rg->g = *g;
	rg->c = *c;
	rt->micropolygons += rg->nquads;
	rt->bytes += sizeof(float) * (size_t)n * (3 * 7 + 2) * 1 + sizeof(uint32_t) * 5 * rg->nquads +
		     sizeof(float) * 3 * (size_t)n * (rg->moving ? 2 : 1);
	rt->ngrids++;
	return true;
}

/* Attach grid @id to the scenes of the ray types its primitive is seen by. */
static bool attach_grid(struct reyes_rt *rt, uint32_t id)
{
	const struct rt_grid *rg = &rt->grids[id];
	if (!rg->nquads)
		return true;
	for (int type = 0; type < SL_RAY_TYPE_COUNT; type++) {
		if (!sees(rg->prim->attrs, (enum sl_ray_type)type))
			continue;
		RTCGeometry geo = rtcNewGeometry(rt->dev, RTC_GEOMETRY_TYPE_QUAD);
		if (!geo)
			return false;
		rtcSetGeometryTimeStepCount(geo, rg->moving ? 2 : 1);
		for (unsigned ts = 0; ts < (rg->moving ? 2u : 1u); ts++)
			rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, ts, RTC_FORMAT_FLOAT3,
						   rg->verts[ts], 0, 3 * sizeof(float), rg->c.n);
		rtcSetSharedGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, rg->quads,
					   0, 4 * sizeof(uint32_t), rg->nquads);
		rtcCommitGeometry(geo);
		rtcAttachGeometryByID(rt->scene[type], geo, id);
		rtcReleaseGeometry(geo);
		/* about what Embree's BVH keeps per quad */
		rt->bytes += 64 * (uint64_t)rg->nquads;
	}
	return rtcGetDeviceError(rt->dev) == RTC_ERROR_NONE;
}

/* Dice what rays see, as reyes_dice dices (everything, not only the view). */
static struct reyes_rt *build(struct render *parent)
{
	const struct reyes_scene *scene = parent->scene;
	bool any = false;
	for (uint32_t p = 0; p < scene->nprims; p++) {
		const struct reyes_attrs *a = scene->prims[p].attrs;
		any |= a->ray.specular || a->ray.diffuse || a->ray.transmission != REYES_TRANS_NONE;
	}
	struct reyes_rt *rt = calloc(1, sizeof(*rt));
	if (!rt)
		return NULL;
	rt->dev = rtcNewDevice(NULL);
	for (int k = 0; rt->dev && k < SL_RAY_TYPE_COUNT; k++) {
		rt->scene[k] = rtcNewScene(rt->dev);
		if (rt->scene[k])
			rtcSetSceneFlags(rt->scene[k], RTC_SCENE_FLAG_ROBUST);
	}
	if (!rt->dev || !rt->scene[0] || !rt->scene[1] || !rt->scene[2]) {
		fprintf(parent->diag, "relight: error: Embree cannot start (error %d)\n",
			rt->dev ? (int)rtcGetDeviceError(rt->dev) : -1);
		reyes_rt_destroy(rt);
		return NULL;
	}
	/* a render of its own for the dicing, as reyes_dice makes one */
	struct render d = { 0 };
	d.scene = scene;
	d.o = parent->o;
	d.diag = parent->diag;
	d.cam = parent->cam;
	d.px1 = scene->opts.xres;
	d.py1 = scene->opts.yres;
	d.margin = parent->margin;
	d.bucket = 16;
	d.nbx = (d.px1 + d.bucket - 1) / d.bucket;
	d.nby = (d.py1 + d.bucket - 1) / d.bucket;
	d.max_points = parent->max_points;
	d.nthreads = 1;
	d.keep_unseen = true;
	d.orient_free = true;
	d.tex = parent->tex;
	d.light_mats = parent->light_mats;
	d.rt_tried = true;       /* a displacement shader's rays reach nothing */
	pthread_mutex_init(&d.rt_lock, NULL);
	struct tctx bt = { .r = &d };
	struct reyes_patch *pieces = NULL;
	size_t np = 0, capp = 0;
	bool ok = true;
	for (uint32_t p = 0; any && ok && p < scene->nprims; p++) {
		const struct reyes_prim *prim = &scene->prims[p];
		const struct reyes_attrs *a = prim->attrs;
		if (!a->ray.specular && !a->ray.diffuse && a->ray.transmission == REYES_TRANS_NONE)
			continue;
		np = 0;
		if (!reyes_prim_pieces(prim, &pieces, &np, &capp))
			continue;
		d.njobs = 0;
		for (size_t k = 0; k < np; k++)
			reyes_split_piece(&d, &pieces[k]);
		if (atomic_load(&d.failed)) {
			fprintf(d.diag, "relight: error: out of memory dicing primitive %u for rays\n",
				prim->id);
			ok = false;
		}
		for (size_t i = 0; ok && i < d.njobs; i++) {
			struct reyes_grid g = { 0 };
			struct cgrid c;
			if (!reyes_dice_job(&bt, &d.jobs[i], &g, &c)) {
				fprintf(d.diag, "relight: error: dicing or displacement failed for rays "
					"(primitive %u)\n", prim->id);
				ok = false;
				break;
			}
			uint8_t *keep = NULL;
			if (!reyes_trim_keep(prim, &g, &keep) || !add_grid(rt, prim, &g, &c, keep)) {
				fprintf(d.diag, "relight: error: out of memory for the rays' geometry\n");
				free(c.P0);
				reyes_grid_finish(&g);
				ok = false;
			}
			free(keep);
		}
	}
	free(pieces);
	for (size_t k = 0; k < bt.nexecs; k++)
		sl_exec_destroy(bt.execs[k].x);
	free(bt.execs);
	free(d.jobs);
	pthread_mutex_destroy(&d.rt_lock);
	for (size_t i = 0; ok && i < rt->ngrids; i++)
		ok = attach_grid(rt, (uint32_t)i);
	for (int k = 0; ok && k < SL_RAY_TYPE_COUNT; k++)
		rtcCommitScene(rt->scene[k]);
	if (ok && rtcGetDeviceError(rt->dev) != RTC_ERROR_NONE) {
		fprintf(parent->diag, "relight: error: Embree cannot build the rays' scene\n");
		ok = false;
	}
	if (!ok) {
		reyes_rt_destroy(rt);
		return NULL;
	}
	return rt;
}

/* ---- shading hits ---- */

/* Plane @pl of an nu x nv grid at grid coordinates (@fi, @fj), bilinear (linear past the edge). */
static float lerp2(const float *pl, uint32_t nu, uint32_t nv, double fi, double fj)
{
	double ci = floor(fi), cj = floor(fj);
	ci = ci < 0 ? 0 : ci > nu - 2 ? nu - 2 : ci;
	cj = cj < 0 ? 0 : cj > nv - 2 ? nv - 2 : cj;
	double a = fi - ci, b = fj - cj;
	size_t k = (size_t)cj * nu + (size_t)ci;
	return (float)((1 - a) * (1 - b) * pl[k] + a * (1 - b) * pl[k + 1] +
		       (1 - a) * b * pl[k + nu] + a * b * pl[k + nu + 1]);
}

/* @nc planes of @src (an nu x nv grid) at the four points of @at into @dst (4 a plane). */
static void sample_planes(float *dst, const float *src, int nc, const struct cgrid *c,
			  const double at[4][2])
{
	for (int q = 0; q < nc; q++)
		for (int k = 0; k < 4; k++)
			dst[q * 4 + k] = lerp2(src + (size_t)q * c->n, c->nu, c->nv, at[k][0], at[k][1]);
}

/* The context that shades @t's hits: one ray level deeper. */
static struct tctx *sub_context(struct tctx *t)
{
	if (t->sub)
		return t->sub;
	uint32_t nl = t->r->scene->nlights;
	struct tctx *s = calloc(1, sizeof(*s));
	if (!s)
		return NULL;
	s->r = t->r;
	s->light_x = calloc(nl + 1, sizeof(*s->light_x));
	s->lights_on = calloc(nl + 1, sizeof(*s->lights_on));
	s->light_mats = calloc(nl + 1, sizeof(*s->light_mats));
	if (!s->light_x || !s->lights_on || !s->light_mats) {
		free(s->light_x);
		free(s->lights_on);
		free(s->light_mats);
		free(s);
		return NULL;
	}
	s->depth = t->depth + 1;
	t->sub = s;
	return s;
}

void reyes_rt_free_sub(struct tctx *t)
{
	struct tctx *s = t->sub;
	t->sub = NULL;
	if (!s)
		return;
	reyes_rt_free_sub(s);
	for (size_t k = 0; k < s->nexecs; k++)
		sl_exec_destroy(s->execs[k].x);
	free(s->execs);
	for (uint32_t k = 0; s->light_x && k < s->r->scene->nlights; k++)
		sl_exec_destroy(s->light_x[k]);
	free(s->light_x);
	free(s->lights_on);
	free(s->light_mats);
	t->rays += s->rays;
	free(s);
}

/* Cs and Os of grid @rg at (@fi, @fj): its primitive variables, else its attributes. */
static void hit_color(const struct rt_grid *rg, double fi, double fj, float cs[3], float os[3])
{
	const struct reyes_attrs *a = rg->prim->attrs;
	const struct cgrid *c = &rg->c;
	for (int q = 0; q < 3; q++) {
		cs[q] = c->Cs ? lerp2(c->Cs + (size_t)q * c->n, c->nu, c->nv, fi, fj) : a->Cs[q];
		os[q] = c->Os ? lerp2(c->Os + (size_t)q * c->n, c->nu, c->nv, fi, fj) : a->Os[q];
	}
}

/*
 * N and Ng of the 2 x 2 hit grid @h where they vanish: @ng (the hit
 * micropolygon's geometric normal from Embree), turned to agree with the
 * normals at the corners of the micropolygon of @c holding (@fi, @fj).
 */
static void fix_normals(struct cgrid *h, const struct cgrid *c, double fi, double fj,
			const float ng[3])
{
	uint32_t ci = fi < 0 ? 0 : fi > c->nu - 2 ? c->nu - 2 : (uint32_t)fi;
	uint32_t cj = fj < 0 ? 0 : fj > c->nv - 2 ? c->nv - 2 : (uint32_t)fj;
	size_t k0 = (size_t)cj * c->nu + ci, corner[4] = { k0, k0 + 1, k0 + c->nu, k0 + c->nu + 1 };
	float *planes[2] = { h->N, h->Ng };
	const float *src[2] = { c->N, c->Ng };
	double gl = sqrt((double)ng[0] * ng[0] + (double)ng[1] * ng[1] + (double)ng[2] * ng[2]);
	if (!(gl > 0))
		return;
	for (int w = 0; w < 2; w++) {
		double sum[3] = { 0, 0, 0 }, most = 0;
		for (int k = 0; k < 4; k++) {
			double l = 0;
			for (int q = 0; q < 3; q++) {
				double v = src[w][(size_t)q * c->n + corner[k]];
				sum[q] += v;
				l += v * v;
			}
			most = fmax(most, sqrt(l));
		}
		double side = sum[0] * ng[0] + sum[1] * ng[1] + sum[2] * ng[2] < 0 ? -1 : 1;
		for (int k = 0; k < 4; k++) {
			float *n = planes[w];
			double l = sqrt((double)n[k] * n[k] + (double)n[4 + k] * n[4 + k] +
					(double)n[8 + k] * n[8 + k]);
			if (l > 1e-3 * most)
				continue;
			for (int q = 0; q < 3; q++)
				n[q * 4 + k] = (float)(side * ng[q] / gl * (most > 0 ? most : 1));
		}
	}
}

/* Run the hit object's surface shader at grid coordinates (@fi, @fj) of @rg. */
static bool shade_hit(struct tctx *t, const struct rt_grid *rg, double fi, double fj,
		      const float org[3], const float dir[3], const float ng[3], float len,
		      enum sl_ray_type type, float ci[3], float oi[3])
{
	const struct reyes_attrs *a = rg->prim->attrs;
	if (a->matte) {
		for (int q = 0; q < 3; q++) {
			ci[q] = 0;
			oi[q] = 1;
		}
		return true;
	}
	struct tctx *s = sub_context(t);
	if (!s)
		return false;
	s->ray_type = type;
	s->specular_depth = t->specular_depth + (type == SL_RAY_SPECULAR);
	s->diffuse_depth = t->diffuse_depth + (type == SL_RAY_DIFFUSE);
	memcpy(s->ray_org, org, sizeof(s->ray_org));
	memcpy(s->ray_dir, dir, sizeof(s->ray_dir));
	s->ray_len = len;
	const struct cgrid *c = &rg->c;
	const double at[4][2] = { { fi, fj }, { fi + 1, fj }, { fi, fj + 1 }, { fi + 1, fj + 1 } };
	/* P0 P1 N Ng dPdu dPdv I (3 each), s t u v (1 each), Cs Os (3 each) */
	float buf[4 * (3 * 7 + 4 + 6)];
	struct cgrid h = { .nu = 2, .nv = 2, .n = 4, .du = c->du, .dv = c->dv };
	h.P0 = buf;
	h.P1 = buf + 12;
	h.N = buf + 24;
	h.Ng = buf + 36;
	h.dPdu = buf + 48;
	h.dPdv = buf + 60;
	h.I = buf + 72;
	h.s = buf + 84;
	h.t = buf + 88;
	float *u = buf + 92, *v = buf + 96;
	sample_planes(h.P0, c->P0, 3, c, at);
	sample_planes(h.P1, c->P1, 3, c, at);
	sample_planes(h.N, c->N, 3, c, at);
	sample_planes(h.Ng, c->Ng, 3, c, at);
	sample_planes(h.dPdu, c->dPdu, 3, c, at);
	sample_planes(h.dPdv, c->dPdv, 3, c, at);
	sample_planes(h.s, c->s, 1, c, at);
	sample_planes(h.t, c->t, 1, c, at);
	sample_planes(u, c->u, 1, c, at);
	sample_planes(v, c->v, 1, c, at);
	h.u = u;
	h.v = v;
	if (c->Cs) {
		h.Cs = buf + 100;
		sample_planes(h.Cs, c->Cs, 3, c, at);
	}
	if (c->Os) {
		h.Os = buf + 112;
		sample_planes(h.Os, c->Os, 3, c, at);
	}
	for (int k = 0; k < 4; k++)
		for (int q = 0; q < 3; q++)
			h.I[q * 4 + k] = h.P0[q * 4 + k] - org[q];
	/* Where a grid degenerates (a sphere's pole: dPdu = 0) its normals vanish:
	 * there the hit micropolygon's own normal, turned as its other corners' */
	fix_normals(&h, c, fi, fj, ng);
	/* the primitive variables shader parameters read */
	struct reyes_grid g = { .nu = 2, .nv = 2, .n = 4, .u = u, .v = v, .du = c->du,
				.dv = c->dv, .nvars = rg->g.nvars };
	struct reyes_grid_var vars[16];
	float *vdata = NULL;
	if (g.nvars > 16)
		g.nvars = 16;
	if (g.nvars) {
		size_t total = 0;
		for (uint32_t i = 0; i < g.nvars; i++)
			total += (size_t)sl_type_ncomp(rg->g.vars[i].type) *
				 (rg->g.vars[i].arraylen ? rg->g.vars[i].arraylen : 1);
		vdata = malloc(sizeof(float) * 4 * (total ? total : 1));
		if (!vdata)
			return false;
		size_t off = 0;
		for (uint32_t i = 0; i < g.nvars; i++) {
			vars[i] = rg->g.vars[i];
			int nc = sl_type_ncomp(vars[i].type) *
				 (int)(vars[i].arraylen ? vars[i].arraylen : 1);
			sample_planes(vdata + off, rg->g.vars[i].data, nc, c, at);
			vars[i].data = vdata + off;
			off += 4 * (size_t)nc;
		}
		g.vars = vars;
	}
	const struct reyes_shader *surf = a->surface ? a->surface : &t->r->default_surface;
	struct sl_exec *sx = NULL;
	bool ok = reyes_shade_surface(s, a, surf, &g, &h, &sx);
	free(vdata);
	if (!ok)
		return false;
	bool vary;
	const float *C = sl_exec_global(sx, SL_GLOBAL_CI, &vary);
	const float *O = sl_exec_global(sx, SL_GLOBAL_OI, &vary);
	uint32_t st = sl_exec_stride(sx);
	for (int q = 0; q < 3; q++) {
		ci[q] = C ? C[vary ? (size_t)q * st : (size_t)q] : 0;
		oi[q] = O ? O[vary ? (size_t)q * st : (size_t)q] : 1;
		if (!isfinite(ci[q]))
			ci[q] = 0;
		if (!isfinite(oi[q]))
			oi[q] = 1;
	}
	return true;
}

/* ---- casting ---- */

static bool ensure_scene(struct render *r)
{
	pthread_mutex_lock(&r->rt_lock);
	if (!r->rt && !r->rt_tried) {
		r->rt_tried = true;
		r->rt = build(r);
	}
	pthread_mutex_unlock(&r->rt_lock);
	return r->rt != NULL;
}

static void miss(const struct sl_ray_query *q, uint32_t k)
{
	if (q->dist)
		q->dist[k] = 1e30f;
	for (int c = 0; c < 3; c++) {
		if (q->Ci)
			q->Ci[3 * k + (uint32_t)c] = 0;
		if (q->Oi)
			q->Oi[3 * k + (uint32_t)c] = 0;
		if (q->trans)
			q->trans[3 * k + (uint32_t)c] = 1;
	}
}

bool reyes_rt_trace(struct tctx *t, struct sl_ray_query *q)
{
	struct render *r = t->r;
	for (uint32_t k = 0; k < q->n; k++)
		miss(q, k);
	if ((unsigned)q->type >= SL_RAY_TYPE_COUNT)
		return false;
	/* depth limits: past them rays reach nothing */
	const struct reyes_attrs *from = t->shading;
	if (t->depth >= r->scene->opts.trace_maxdepth ||
	    (q->type == SL_RAY_SPECULAR && from && t->specular_depth >= from->ray.max_specular_depth) ||
	    (q->type == SL_RAY_DIFFUSE && from && t->diffuse_depth >= from->ray.max_diffuse_depth))
		return true;
	if (!ensure_scene(r))
		return true;     /* no scene (said when it failed; none while dicing it) */
	struct reyes_rt *rt = r->rt;
	RTCScene scene = rt->scene[q->type];
	float bias = q->bias >= 0 && isfinite(q->bias) ? q->bias : from ? from->ray.bias : 0.01f;
	int forced = !q->hitmode ? -1 : !strcmp(q->hitmode, "primitive") ? REYES_HIT_PRIMITIVE
				     : REYES_HIT_SHADER;
	bool colour = q->Ci || q->Oi;
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	for (uint32_t k = 0; k < q->n; k++) {
		float d[3], o[3];
		double len = 0;
		for (int c = 0; c < 3; c++)
			len += (double)q->dir[3 * k + (uint32_t)c] * q->dir[3 * k + (uint32_t)c];
		len = sqrt(len);
		if (!(len > 0) || !isfinite(len))
			continue;
		for (int c = 0; c < 3; c++) {
			d[c] = (float)(q->dir[3 * k + (uint32_t)c] / len);
			o[c] = q->org[3 * k + (uint32_t)c] + bias * d[c];
		}
		if (!isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]))
			continue;
		float maxd = q->maxdist ? q->maxdist[k] : 1e30f;
		float far = !(maxd < 1e30f) ? INFINITY : maxd - bias;
		if (!(far > 0))
			continue;
		float time = q->time && isfinite(q->time[k]) ? fminf(fmaxf(q->time[k], 0), 1) : 0;
		double T[3] = { 1, 1, 1 }, C[3] = { 0, 0, 0 };
		float first = 1e30f, tnear = 0;
		for (int hit = 0; hit < MAX_HITS; hit++) {
			struct RTCRayHit rh;
			memset(&rh, 0, sizeof(rh));
			rh.ray.org_x = o[0];
			rh.ray.org_y = o[1];
			rh.ray.org_z = o[2];
			rh.ray.dir_x = d[0];
			rh.ray.dir_y = d[1];
			rh.ray.dir_z = d[2];
			rh.ray.tnear = tnear;
			rh.ray.tfar = far;
			rh.ray.time = time;
			rh.ray.mask = 0xffffffffu;
			rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
			rtcIntersect1(scene, &ictx, &rh);
			t->rays++;
			if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
				break;
			float th = rh.ray.tfar;
			if (first == 1e30f)
				first = bias + th;
			const struct rt_grid *rg = &rt->grids[rh.hit.geomID];
			uint32_t cell = rg->cell[rh.hit.primID], nq = rg->c.nu - 1;
			/* the quad from the corner (i + 1, j): u runs along j, v back along i */
			double fi = cell % nq + 1.0 - (double)rh.hit.v, fj = cell / nq + (double)rh.hit.u;
			const struct reyes_attrs *a = rg->prim->attrs;
			float cs[3], os[3], ci[3], oi[3];
			if (q->type == SL_RAY_TRANSMISSION || !colour) {
				hit_color(rg, fi, fj, cs, os);
				bool opaque = q->type == SL_RAY_TRANSMISSION &&
					      a->ray.transmission == REYES_TRANS_OPAQUE;
				for (int c = 0; c < 3; c++)
					T[c] *= opaque ? 0.0 : 1.0 - fmin(fmax(os[c], 0.0f), 1.0f);
			} else {
				int mode = forced >= 0 ? forced : a->ray.hitmode[q->type];
				if (mode == REYES_HIT_SHADER) {
					float org[3];
					for (int c = 0; c < 3; c++)
						org[c] = q->org[3 * k + (uint32_t)c];
					const float hng[3] = { rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z };
					if (!shade_hit(t, rg, fi, fj, org, d, hng, bias + th, q->type, ci,
						       oi))
						return false;
				} else {
					hit_color(rg, fi, fj, cs, os);
					for (int c = 0; c < 3; c++) {
						ci[c] = cs[c] * os[c];
						oi[c] = os[c];
					}
				}
				for (int c = 0; c < 3; c++) {
					C[c] += T[c] * ci[c];
					T[c] *= 1.0 - fmin(fmax(oi[c], 0.0f), 1.0f);
				}
			}
			if (!q->Ci && !q->Oi && !q->trans)
				break;     /* the distance alone */
			if (T[0] <= 1e-6 && T[1] <= 1e-6 && T[2] <= 1e-6)
				break;
			tnear = th + 1e-5f * fmaxf(1.0f, th);
			if (!(tnear < far))
				break;
		}
		if (q->dist)
			q->dist[k] = first;
		for (int c = 0; c < 3; c++) {
			if (q->Ci)
				q->Ci[3 * k + (uint32_t)c] = (float)C[c];
			if (q->Oi)
				q->Oi[3 * k + (uint32_t)c] = (float)(1 - T[c]);
			if (q->trans)
				q->trans[3 * k + (uint32_t)c] = (float)T[c];
		}
	}
	return true;
}

bool reyes_rt_rayinfo(struct tctx *t, const char *name, int type, int arraylen, float *out,
		      const char **sout)
{
	static const char *const types[SL_RAY_TYPE_COUNT] = {
		[SL_RAY_SPECULAR] = "specular", [SL_RAY_DIFFUSE] = "diffuse",
		[SL_RAY_TRANSMISSION] = "transmission",
	};
	if (arraylen)
		return false;
	if (type == SL_TYPE_STRING && !strcmp(name, "type")) {
		*sout = t->depth ? types[t->ray_type] : "camera";
		return true;
	}
	if (type == SL_TYPE_FLOAT) {
		if (!strcmp(name, "depth"))
			*out = (float)t->depth;
		else if (!strcmp(name, "speculardepth"))
			*out = (float)t->specular_depth;
		else if (!strcmp(name, "diffusedepth"))
			*out = (float)t->diffuse_depth;
		else if (!strcmp(name, "length"))
			*out = t->depth ? t->ray_len : 0;
		else
			return false;
		return true;
	}
	if (sl_type_ncomp(type) == 3 && (!strcmp(name, "origin") || !strcmp(name, "direction"))) {
		memcpy(out, name[0] == 'o' ? t->ray_org : t->ray_dir, 3 * sizeof(float));
		return true;
	}
	return false;
}

uint64_t reyes_rt_bytes(const struct reyes_rt *rt)
{
	return rt ? rt->bytes : 0;
}

uint64_t reyes_rt_micropolygons(const struct reyes_rt *rt)
{
	return rt ? rt->micropolygons : 0;
}

/*
 * Blobby nleaf [code] [floats] [strings] ...primitive variables
 *
 * The request is decoded and checked here (malformed code drops the
 * primitive alone, with the request's FILE:LINE), then its isosurface is
 * polygonized at once, where it is declared: the camera is known by then
 * (it is fixed at WorldBegin), so the grid's cells are chosen from the
 * bound's projected size and the shading rate. The mesh becomes an
 * ordinary REYES_POLYGONS primitive (triangles, "N" from the field as a
 * vertex variable), which the renderer dices to the shading rate like any
 * polygon, and the bake and the shadow geometry record like any other.
 *
 * Primitive variables: constant and uniform ones (one value) apply to the
 * whole surface; varying, vertex and facevarying ones have one value per
 * leaf and are blended at each point of the surface by the leaves' field
 * values there, the way prman blends them.
 */
#include "ri_impl.h"

#include "geom_blobby.h"
#include "sl.h"

#include <math.h>
#include <string.h>

/*
 * The polygonization's cells are this many pixels wide times the square
 * root of the shading rate (a micropolygon's side), and at most MAX_CELLS
 * per axis. The mesh's vertices are on the surface, so a chord of c pixels
 * on a surface of radius R pixels strays c^2 / 8R pixels from it: a
 * triangle's edge is at most a cell's diagonal, 7 pixels at the default
 * rate, which strays 0.3 pixel from a surface 20 pixels in radius and 0.06
 * from one of 100 (shading uses the field's normals, exact at the vertices).
 * Finer cells would cost many tiny triangles, each diced on its own.
 */
#define CELL_PIXELS 4.0
#define MAX_CELLS 128
#define MIN_CELLS 8            /* across the bound's longest side, however small it looks */
#define UNSEEN_CELLS 32        /* ... for a bound all behind the camera (it may cast shadows) */
#define NO_CAMERA_CELLS 32     /* ... for an object defined before WorldBegin */

/* Integers of a code array, each within int32. */
static int32_t *code_values(struct ri *ri, const struct rib_value *v)
{
	int32_t *out = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(int32_t) * (v->n ? v->n : 1));
	for (uint32_t i = 0; i < v->n; i++) {
		double d = v->nums[i];
		if (!(fabs(d) < 2147483647.0)) {
			reyes_ri_err(ri, v->loc, "Blobby: code[%u] = %g is out of range", i, d);
			return NULL;
		}
		out[i] = (int32_t)d;
	}
	return out;
}

/* The cell size, in object space, for the bound of @b seen from the camera. */
static double cell_size(struct ri *ri, const struct reyes_blobby *b)
{
	float box[6], m[16];
	double ext[3];
	for (int c = 0; c < 3; c++) {
		box[2 * c] = (float)b->lo[c];
		box[2 * c + 1] = (float)b->hi[c];
		ext[c] = b->hi[c] - b->lo[c];
	}
	/* the two longest sides: the box's face most nearly towards the camera */
	double e0 = fmax(ext[0], fmax(ext[1], ext[2]));
	double e1 = ext[0] + ext[1] + ext[2] - e0 - fmin(ext[0], fmin(ext[1], ext[2]));
	double coarsest = e0 / MIN_CELLS;
	if (!ri->world)
		return e0 / NO_CAMERA_CELLS;
	sl_m44_mul(m, ri->gs.x.m[0], ri->opt.o.world_to_camera);
	double area = reyes_ri_raster_area(&ri->opt.o, m, box);
	if (!(area > 0))
		return e0 / UNSEEN_CELLS;
	if (!isfinite(area))
		return e0 / MAX_CELLS;
	double per_unit = sqrt(area / (e0 * fmax(e1, 1e-6 * e0)));
	double cell = CELL_PIXELS * sqrt(fmax(ri->gs.a.shading_rate, 1e-6)) / per_unit;
	return fmin(cell, coarsest);
}

/* Variable @v (one value per leaf) blended over the mesh's points by the leaves' fields. */
static float *blend(struct ri *ri, const struct reyes_primvar *v, const struct reyes_blobby *b,
		    const struct reyes_blobby_mesh *m)
{
	uint32_t per = (uint32_t)sl_type_ncomp(v->type) * (v->arraylen ? v->arraylen : 1);
	uint32_t nleaf = b->nleaf;
	float *out = rl_arena_alloc(reyes_ri_cur_arena(ri),
				    sizeof(float) * per * (m->npoints ? m->npoints : 1));
	for (uint32_t k = 0; k < m->npoints; k++) {
		const double *w = &m->leaf[(size_t)k * nleaf];
		double sum = 0;
		for (uint32_t l = 0; l < nleaf; l++)
			sum += fabs(w[l]);
		for (uint32_t c = 0; c < per; c++) {
			double acc = 0;
			for (uint32_t l = 0; l < nleaf; l++)
				acc += (sum > 0 ? fabs(w[l]) / sum : 1.0 / nleaf) *
				       v->values[(size_t)l * per + c];
			out[(size_t)k * per + c] = (float)acc;
		}
	}
	return out;
}

/* The polygon primitive of mesh @m, with @tmp's primitive variables turned to it. */
static struct reyes_prim *mesh_prim(struct ri *ri, const struct rib_request *r,
				    const struct reyes_prim *tmp, const struct reyes_blobby *b,
				    const struct reyes_blobby_mesh *m)
{
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_POLYGONS);
	uint32_t nt = m->ntris, np = m->npoints;
	uint32_t *ones = rl_arena_alloc(a, sizeof(uint32_t) * nt), *threes =
		rl_arena_alloc(a, sizeof(uint32_t) * nt), *verts =
		rl_arena_alloc(a, sizeof(uint32_t) * 3 * nt);
	for (uint32_t t = 0; t < nt; t++)
		ones[t] = 1, threes[t] = 3;
	memcpy(verts, m->tris, sizeof(uint32_t) * 3 * nt);
	float *P = rl_arena_alloc(a, sizeof(float) * 3 * np), *N =
		rl_arena_alloc(a, sizeof(float) * 3 * np);
	memcpy(P, m->P, sizeof(float) * 3 * np);
	memcpy(N, m->N, sizeof(float) * 3 * np);
	p->nfaces = nt;
	p->nloops = ones;
	p->nverts = threes;
	p->verts = verts;
	p->npoints = np;
	struct reyes_primvar *vars = rl_arena_alloc(a, sizeof(*vars) * (tmp->nvars + 2));
	uint32_t n = 0;
	vars[n++] = (struct reyes_primvar){.name = "P", .cls = REYES_VERTEX,
					   .type = SL_TYPE_POINT, .count = np, .values = P};
	vars[n++] = (struct reyes_primvar){.name = "N", .cls = REYES_VERTEX,
					   .type = SL_TYPE_NORMAL, .count = np, .values = N};
	for (uint32_t i = 0; i < tmp->nvars; i++) {
		struct reyes_primvar v = tmp->vars[i];
		if (strcmp(v.name, "N") == 0) {
			reyes_ri_warn(ri, r->loc, "Blobby: \"N\" ignored (the normals are the "
				      "field's)");
			continue;
		}
		if (v.cls == REYES_CONSTANT || v.cls == REYES_UNIFORM) {
			v.cls = REYES_CONSTANT;
			v.count = 1;
		} else {
			v.values = blend(ri, &v, b, m);
			v.cls = REYES_VERTEX;
			v.count = np;
		}
		vars[n++] = v;
	}
	p->vars = vars;
	p->nvars = n;
	return p;
}

void reyes_ri_req_blobby(struct ri *ri, const struct rib_request *r)
{
	if (!reyes_ri_geometry_ok(ri, r))
		return;
	double nleaf_d;
	if (!reyes_ri_num_arg(ri, r, 0, &nleaf_d))
		return;
	if (!(nleaf_d >= 1 && nleaf_d <= 1 << 24))
		FAIL(ri, r->loc, "Blobby: nleaf is %g (1 to %d)", nleaf_d, 1 << 24);
	uint32_t nleaf = (uint32_t)nleaf_d;
	const struct rib_value *vc = &r->args[1], *vf = &r->args[2], *vs = &r->args[3];
	int32_t *code = code_values(ri, vc);
	float *floats = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(float) * (vf->n ? vf->n : 1));
	if (!code || !reyes_ri_value_floats(ri, vf, vf->loc, "Blobby floats", floats))
		return;
	struct reyes_blobby b;
	char err[256];
	if (!reyes_blobby_decode(&b, nleaf, code, vc->n, floats, vf->n, vs->n, err, sizeof(err)))
		FAIL(ri, r->loc, "Blobby: %s", err);
	struct reyes_prim tmp = {0};
	uint32_t sizes[5] = {1, 1, nleaf, nleaf, nleaf};
	if (!reyes_ri_prim_vars(ri, r, sizes, false, &tmp))
		goto out;
	if (b.nplanes)
		reyes_ri_warn(ri, r->loc, "Blobby: repelling planes (opcode 1003) are not "
			      "supported: their field is taken as 0");
	if (!b.bounded) {
		reyes_ri_warn(ri, r->loc, "Blobby has no ellipsoid or segment leaf: there is "
			      "no bounded surface to draw");
		goto out;
	}
	struct reyes_blobby_mesh m;
	if (!reyes_blobby_polygonize(&b, cell_size(ri, &b), MAX_CELLS, &m)) {
		reyes_ri_err(ri, r->loc, "Blobby: its bound cannot be polygonized (out of "
			     "memory or degenerate)");
		goto out;
	}
	if (m.coarsened)
		reyes_ri_warn(ri, r->loc, "Blobby: %u instructions are too many for a grid at "
			      "the shading rate: polygonized on cells %g wide (object space) instead",
			      b.ninstr, m.cell);
	if (m.ntris)
		reyes_ri_emit_prim(ri, r, mesh_prim(ri, r, &tmp, &b, &m));
	reyes_blobby_mesh_finish(&m);
out:
	reyes_blobby_finish(&b);
}

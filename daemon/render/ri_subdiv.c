/*
 * SubdivisionMesh (RISpec 3.2 5.3, with prman's tags):
 *
 *   SubdivisionMesh scheme nvertices vertices [tags nargs intargs floatargs
 *                   [stringargs]] parameterlist
 *
 * "catmull-clark" only (other schemes are a warning and the mesh is left
 * out). Tags: "crease" (a chain of vertices, one sharpness), "corner"
 * (vertices, one sharpness or one each), "hole" (faces),
 * "interpolateboundary" (0, 1 or 2 as prman; no argument is 1) and
 * "facevaryinginterpolateboundary" (0..3); others are a warning and
 * ignored. nargs holds two counts per tag (integers, floats) or, as prman
 * writes it, three (and strings). Bad data is an error at its line that
 * drops this mesh only.
 */
#include "ri_impl.h"

#include "arena.h"
#include "geom_subdiv.h"

#include <math.h>
#include <stdatomic.h>
#include <string.h>

static atomic_uint_fast64_t next_serial = 1;

struct tagargs {
	const double *ints, *floats;
	uint32_t nints, nfloats, ni_total, nf_total;
	struct rib_loc loc;
};

/* Is (a, b) an edge of a face of @sd? */
static bool is_edge(const struct reyes_subdiv *sd, uint32_t a, uint32_t b)
{
	const uint32_t *v = sd->verts;
	for (uint32_t f = 0; f < sd->nfaces; v += sd->nverts[f], f++)
		for (uint32_t i = 0; i < sd->nverts[f]; i++) {
			uint32_t x = v[i], y = v[(i + 1) % sd->nverts[f]];
			if ((x == a && y == b) || (x == b && y == a))
				return true;
		}
	return false;
}

static bool int_in(struct ri *ri, const struct rib_request *r, const char *tag, double d,
		   uint64_t limit, const char *what, uint32_t *out)
{
	if (d >= 0 && d < (double)limit && d == floor(d)) {
		*out = (uint32_t)d;
		return true;
	}
	reyes_ri_err(ri, r->loc, "%s: tag \"%s\": %s %g is out of range (0 to %llu)", r->name,
		     tag, what, d, (unsigned long long)(limit ? limit - 1 : 0));
	return false;
}

static bool sharpness(struct ri *ri, const struct rib_request *r, const char *tag, double s,
		      float *out)
{
	if (s >= 0 && isfinite(s)) {
		*out = (float)s;
		return true;
	}
	reyes_ri_err(ri, r->loc, "%s: tag \"%s\": sharpness %g (expected a number >= 0)", r->name,
		     tag, s);
	return false;
}

/*
 * The tags' edges, corners and holes: each takes one of the tags' integers
 * at most, so arrays of intargs' length hold them.
 */
struct tagbuf {
	uint32_t *cv, *kv, *holes;
	float *cs, *ks;
	uint32_t nc, nk, nh;
};

/* One tag with its arguments into @sd and @b; false (reported) if they are malformed. */
static bool one_tag(struct ri *ri, const struct rib_request *r, const char *tag,
		    const struct tagargs *a, struct reyes_subdiv *sd, struct tagbuf *b,
		    uint32_t npoints)
{
	if (strcmp(tag, "crease") == 0) {
		if (a->nints < 2 || a->nfloats != 1) {
			reyes_ri_err(ri, r->loc, "%s: tag \"crease\" takes 2 or more vertices and "
				     "1 sharpness (got %u and %u)", r->name, a->nints, a->nfloats);
			return false;
		}
		float s;
		if (!sharpness(ri, r, tag, a->floats[0], &s))
			return false;
		for (uint32_t i = 0; i + 1 < a->nints; i++) {
			uint32_t x, y;
			if (!int_in(ri, r, tag, a->ints[i], npoints, "vertex", &x) ||
			    !int_in(ri, r, tag, a->ints[i + 1], npoints, "vertex", &y))
				return false;
			if (!is_edge(sd, x, y)) {
				reyes_ri_err(ri, r->loc, "%s: tag \"crease\": vertices %u and %u are "
					     "not joined by an edge", r->name, x, y);
				return false;
			}
			b->cv[2 * b->nc] = x, b->cv[2 * b->nc + 1] = y;
			b->cs[b->nc++] = s;
		}
		return true;
	}
	if (strcmp(tag, "corner") == 0) {
		if (a->nints < 1 || (a->nfloats != 1 && a->nfloats != a->nints)) {
			reyes_ri_err(ri, r->loc, "%s: tag \"corner\" takes vertices and 1 sharpness "
				     "or one each (got %u and %u)", r->name, a->nints, a->nfloats);
			return false;
		}
		for (uint32_t i = 0; i < a->nints; i++) {
			uint32_t x;
			float s;
			if (!int_in(ri, r, tag, a->ints[i], npoints, "vertex", &x) ||
			    !sharpness(ri, r, tag, a->floats[a->nfloats == 1 ? 0 : i], &s))
				return false;
			b->kv[b->nk] = x;
			b->ks[b->nk++] = s;
		}
		return true;
	}
	if (strcmp(tag, "hole") == 0) {
		if (a->nints < 1 || a->nfloats) {
			reyes_ri_err(ri, r->loc, "%s: tag \"hole\" takes faces and no floats (got %u "
				     "and %u)", r->name, a->nints, a->nfloats);
			return false;
		}
		for (uint32_t i = 0; i < a->nints; i++) {
			uint32_t f;
			if (!int_in(ri, r, tag, a->ints[i], sd->nfaces, "face", &f))
				return false;
			b->holes[b->nh++] = f;
		}
		return true;
	}
	bool fv = strcmp(tag, "facevaryinginterpolateboundary") == 0;
	if (fv || strcmp(tag, "interpolateboundary") == 0) {
		uint32_t x = 1, top = fv ? 4 : 3;
		if (a->nints > 1 || a->nfloats ||
		    (a->nints == 1 && !int_in(ri, r, tag, a->ints[0], top, "value", &x))) {
			if (a->nints > 1 || a->nfloats)
				reyes_ri_err(ri, r->loc, "%s: tag \"%s\" takes at most 1 integer and "
					     "no floats (got %u and %u)", r->name, tag, a->nints,
					     a->nfloats);
			return false;
		}
		*(fv ? &sd->fvar_boundary : &sd->interp_boundary) = (int)x;
		return true;
	}
	reyes_ri_warn(ri, a->loc, "%s: tag \"%s\" is not supported: ignored", r->name, tag);
	return true;
}

/* Is args[i] an array (of numbers, or of strings with @strings; [] is either)? */
static bool array_at(const struct rib_request *r, uint32_t i, bool strings)
{
	if (i >= r->nargs)
		return false;
	const struct rib_value *v = &r->args[i];
	if (v->n == 0)
		return true;
	return strings ? v->type == RIB_STRINGS : v->type == RIB_NUMBERS;
}

/* The tags (args 3 on) into @sd; false (reported) if they are malformed. */
static bool tags(struct ri *ri, const struct rib_request *r, struct reyes_subdiv *sd,
		 uint32_t npoints)
{
	sd->fvar_boundary = 1;
	if (r->nargs <= 3)
		return true;
	if (r->nargs < 7 || r->nargs > 8 || !array_at(r, 3, true) || !array_at(r, 4, false) ||
	    !array_at(r, 5, false) || !array_at(r, 6, false) ||
	    (r->nargs == 8 && !array_at(r, 7, true))) {
		reyes_ri_err(ri, r->loc, "%s: the tags take 4 or 5 arrays (tags nargs intargs "
			     "floatargs [stringargs]), got %u", r->name, r->nargs - 3);
		return false;
	}
	const struct rib_value *vt = &r->args[3], *vn = &r->args[4];
	uint32_t ntags = vt->n, per = ntags && vn->n == 3 * ntags ? 3 : 2;
	if (vn->n != per * ntags) {
		reyes_ri_err(ri, vn->loc, "%s: %u tags need %u or %u nargs, got %u", r->name, ntags,
			     2 * ntags, 3 * ntags, vn->n);
		return false;
	}
	struct tagargs a = { .ints = r->args[5].nums, .floats = r->args[6].nums,
			     .ni_total = r->args[5].n, .nf_total = r->args[6].n };
	struct rl_arena *ar = reyes_ri_cur_arena(ri);
	size_t cap = (size_t)a.ni_total + 1;
	struct tagbuf b = {
		.cv = rl_arena_alloc(ar, sizeof(uint32_t) * 2 * cap),
		.kv = rl_arena_alloc(ar, sizeof(uint32_t) * cap),
		.holes = rl_arena_alloc(ar, sizeof(uint32_t) * cap),
		.cs = rl_arena_alloc(ar, sizeof(float) * cap),
		.ks = rl_arena_alloc(ar, sizeof(float) * cap),
	};
	uint64_t ui = 0, uf = 0, us = 0;
	for (uint32_t t = 0; t < ntags; t++) {
		double ni = vn->nums[per * t], nf = vn->nums[per * t + 1];
		double ns = per == 3 ? vn->nums[per * t + 2] : 0;
		const char *tag = vt->strs[t];
		if (!(ni >= 0 && nf >= 0 && ns >= 0 && ni <= a.ni_total - ui &&
		      nf <= a.nf_total - uf && ns <= (r->nargs == 8 ? r->args[7].n : 0) - us)) {
			reyes_ri_err(ri, vn->loc, "%s: tag %u (\"%s\") asks for %g integers, %g "
				     "floats and %g strings: more than are left", r->name, t, tag,
				     ni, nf, ns);
			return false;
		}
		a.nints = (uint32_t)ni, a.nfloats = (uint32_t)nf;
		a.loc = vt->loc;
		struct tagargs here = a;
		here.ints = a.ints ? a.ints + ui : NULL;
		here.floats = a.floats ? a.floats + uf : NULL;
		if (!one_tag(ri, r, tag, &here, sd, &b, npoints))
			return false;
		ui += a.nints, uf += a.nfloats, us += (uint64_t)ns;
	}
	if (ui != a.ni_total || uf != a.nf_total) {
		reyes_ri_err(ri, vn->loc, "%s: the tags take %llu integers and %llu floats, "
			     "intargs has %u and floatargs %u", r->name, (unsigned long long)ui,
			     (unsigned long long)uf, a.ni_total, a.nf_total);
		return false;
	}
	sd->crease_verts = b.cv, sd->crease_sharp = b.cs, sd->ncreases = b.nc;
	sd->corner_verts = b.kv, sd->corner_sharp = b.ks, sd->ncorners = b.nk;
	sd->holes = b.holes, sd->nholes = b.nh;
	return true;
}

void reyes_ri_req_subdivision_mesh(struct ri *ri, const struct rib_request *r)
{
	const char *scheme;
	if (!reyes_ri_geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &scheme) ||
	    !reyes_ri_array_arg(ri, r, 1) || !reyes_ri_array_arg(ri, r, 2))
		return;
	if (strcmp(scheme, "catmull-clark") != 0) {
		reyes_ri_warn(ri, r->loc, "%s: scheme \"%s\" is not supported (only "
			      "\"catmull-clark\"): the mesh is left out", r->name, scheme);
		return;
	}
	const struct rib_value *vnv = &r->args[1], *vv = &r->args[2];
	uint32_t *nverts = reyes_ri_uint_values(ri, vnv, r->name, "nvertices", UINT32_MAX);
	uint64_t corners;
	if (!nverts || !reyes_ri_check_counts(ri, r, vnv, nverts, 3, "face", &corners))
		return;
	if (corners != vv->n)
		FAIL(ri, vv->loc, "%s: the faces have %llu vertices, the vertex array has %u",
		     r->name, (unsigned long long)corners, vv->n);
	if (vnv->n == 0)
		FAIL(ri, r->loc, "%s has no faces", r->name);
	uint32_t np;
	if (!reyes_ri_point_count(ri, r, &np))
		return;
	uint32_t *verts = reyes_ri_uint_values(ri, vv, r->name, "vertex", np);
	if (!verts)
		return;
	struct reyes_subdiv *sd = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(*sd));
	*sd = (struct reyes_subdiv){ .nfaces = vnv->n, .nverts = nverts, .verts = verts };
	sd->serial = atomic_fetch_add(&next_serial, 1);
	if (!tags(ri, r, sd, np))
		return;
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_SUBDIV);
	p->subdiv = sd;
	p->npoints = np;
	uint32_t sizes[5] = {1, sd->nfaces, np, np, (uint32_t)corners};
	if (!reyes_ri_prim_vars(ri, r, sizes, true, p))
		return;
	const struct reyes_primvar *P = reyes_prim_var(p, "P");
	for (size_t i = 0; i < 3 * (size_t)np; i++)
		if (!isfinite(P->values[i]))
			FAIL(ri, r->loc, "%s: point %zu of \"P\" is not finite", r->name, i / 3);
	char why[256];
	if (!reyes_subdiv_check(p, why, sizeof(why)))
		FAIL(ri, r->loc, "%s: %s", r->name, why);
	reyes_ri_emit_prim(ri, r, p);
}

/* Do two motion samples of subdivision meshes have the same faces and tags? */
bool reyes_ri_subdiv_same(const struct reyes_prim *a, const struct reyes_prim *b)
{
	const struct reyes_subdiv *x = a->subdiv, *y = b->subdiv;
	if (x->nfaces != y->nfaces || x->ncreases != y->ncreases || x->ncorners != y->ncorners ||
	    x->nholes != y->nholes || x->interp_boundary != y->interp_boundary ||
	    x->fvar_boundary != y->fvar_boundary ||
	    memcmp(x->nverts, y->nverts, sizeof(uint32_t) * x->nfaces) != 0)
		return false;
	uint64_t nc = 0;
	for (uint32_t f = 0; f < x->nfaces; f++)
		nc += x->nverts[f];
	return memcmp(x->verts, y->verts, sizeof(uint32_t) * nc) == 0 &&
	       (!x->ncreases ||
		(memcmp(x->crease_verts, y->crease_verts, 2 * sizeof(uint32_t) * x->ncreases) == 0 &&
		 memcmp(x->crease_sharp, y->crease_sharp, sizeof(float) * x->ncreases) == 0)) &&
	       (!x->ncorners ||
		(memcmp(x->corner_verts, y->corner_verts, sizeof(uint32_t) * x->ncorners) == 0 &&
		 memcmp(x->corner_sharp, y->corner_sharp, sizeof(float) * x->ncorners) == 0)) &&
	       (!x->nholes || memcmp(x->holes, y->holes, sizeof(uint32_t) * x->nholes) == 0);
}

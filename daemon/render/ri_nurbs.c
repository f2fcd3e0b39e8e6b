/*
 * NuPatch and TrimCurve requests (RISpec 3.2 §5.3): their arguments checked
 * and turned into a REYES_NUPATCH primitive (nurbs.h) and the current trim
 * region (an attribute). A malformed NuPatch is dropped with an error at its
 * line; a malformed TrimCurve is reported at its line and the NuPatches it
 * would trim are dropped (rendering them untrimmed would be wrong).
 */
#include "nurbs.h"
#include "ri_impl.h"

#include "arena.h"

#include <math.h>
#include <string.h>

static void *arena_alloc(void *ctx, size_t n)
{
	return rl_arena_alloc(ctx, n);
}

/* A count argument: a whole number from @min to 2^24. */
static bool count_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char *what,
		      uint32_t min, uint32_t *out)
{
	double d;
	if (!reyes_ri_num_arg(ri, r, i, &d))
		return false;
	if (!(d >= min && d <= (double)(1u << 24) && d == floor(d))) {
		reyes_ri_err(ri, r->loc, "%s: %s is %g (expected a whole number from %u)", r->name,
			     what, d, min);
		return false;
	}
	*out = (uint32_t)d;
	return true;
}

/* The floats of array argument @i, which must hold @want numbers. */
static float *floats_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char *what,
			 uint64_t want)
{
	const struct rib_value *v = &r->args[i];
	if (v->n != want) {
		reyes_ri_err(ri, v->loc, "%s: %s has %u values, expected %llu", r->name, what, v->n,
			     (unsigned long long)want);
		return NULL;
	}
	float *f = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(float) * (v->n ? v->n : 1));
	for (uint32_t k = 0; k < v->n; k++) {
		f[k] = (float)v->nums[k];
		if (!isfinite(f[k])) {
			reyes_ri_err(ri, v->loc, "%s: %s value %u is not finite", r->name, what, k);
			return NULL;
		}
	}
	return f;
}

/* The weights of a "Pw" in @r's parameter list (@np points), or NULL when positions are "P". */
static const float *weights(struct ri *ri, const struct rib_request *r, uint32_t np)
{
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *name;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &name) || strcmp(name, "Pw") ||
		    !reyes_ri_is_numbers(&p->value) || p->value.n != 4 * (uint64_t)np)
			continue;
		float *w = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(float) * (np ? np : 1));
		for (uint32_t k = 0; k < np; k++)
			w[k] = (float)p->value.nums[4 * k + 3];
		return w;
	}
	return NULL;
}

void reyes_ri_req_nu_patch(struct ri *ri, const struct rib_request *r)
{
	struct reyes_nurbs *nb = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(*nb));
	memset(nb, 0, sizeof(*nb));
	double umin, umax, vmin, vmax;
	if (!reyes_ri_geometry_ok(ri, r) || !count_arg(ri, r, 0, "nu", 1, &nb->nu) ||
	    !count_arg(ri, r, 1, "uorder", 0, &nb->uorder) || !reyes_ri_num_arg(ri, r, 3, &umin) ||
	    !reyes_ri_num_arg(ri, r, 4, &umax) || !count_arg(ri, r, 5, "nv", 1, &nb->nv) ||
	    !count_arg(ri, r, 6, "vorder", 0, &nb->vorder) || !reyes_ri_num_arg(ri, r, 8, &vmin) ||
	    !reyes_ri_num_arg(ri, r, 9, &vmax))
		return;
	const struct attrstate *a = &ri->gs.a;
	if (a->trim_bad)
		FAIL(ri, r->loc, "NuPatch: its TrimCurve (%s) is malformed: the NuPatch is dropped",
		     reyes_ri_where(ri, a->trim_loc, r->loc));
	nb->uknot = floats_arg(ri, r, 2, "uknot", (uint64_t)nb->nu + nb->uorder);
	nb->vknot = nb->uknot ? floats_arg(ri, r, 7, "vknot", (uint64_t)nb->nv + nb->vorder) : NULL;
	if (!nb->vknot)
		return;
	nb->umin = (float)umin, nb->umax = (float)umax;
	nb->vmin = (float)vmin, nb->vmax = (float)vmax;
	uint32_t np;
	if (!reyes_ri_point_count(ri, r, &np))
		return;
	if ((uint64_t)nb->nu * nb->nv != np)
		FAIL(ri, r->loc, "NuPatch: %u x %u control points, but \"P\" has %u", nb->nu,
		     nb->nv, np);
	nb->w = weights(ri, r, np);
	const char *why = reyes_nurbs_prepare(nb, arena_alloc, reyes_ri_cur_arena(ri));
	if (why)
		FAIL(ri, r->loc, "NuPatch: %s", why);
	nb->trim = a->trim;
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_NUPATCH);
	p->nurbs = nb;
	p->nu = nb->nu;
	p->nv = nb->nv;
	p->npoints = np;
	uint64_t nsu = nb->nu - nb->uorder + 1, nsv = nb->nv - nb->vorder + 1;
	if ((nsu + 1) * (nsv + 1) * 4 > UINT32_MAX)
		FAIL(ri, r->loc, "NuPatch is too large");
	uint32_t sizes[5] = {1, (uint32_t)(nsu * nsv), (uint32_t)((nsu + 1) * (nsv + 1)), np,
			     (uint32_t)(4 * nsu * nsv)};
	if (reyes_ri_prim_vars(ri, r, sizes, true, p))
		reyes_ri_emit_prim(ri, r, p);
}

/* Whole numbers of an integer array argument. */
static uint32_t *uints_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char *what)
{
	const struct rib_value *v = &r->args[i];
	uint32_t *u = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(uint32_t) * (v->n ? v->n : 1));
	for (uint32_t k = 0; k < v->n; k++) {
		double d = v->nums[k];
		if (!(d >= 0 && d <= (double)(1u << 24))) {
			reyes_ri_err(ri, v->loc, "TrimCurve: %s %u is %g", what, k, d);
			return NULL;
		}
		u[k] = (uint32_t)d;
	}
	return u;
}

static bool trim_curve(struct ri *ri, const struct rib_request *r, const struct reyes_trim **out)
{
	struct reyes_trim_curves c = { 0 };
	c.nloops = r->args[0].n;
	c.ncurves = uints_arg(ri, r, 0, "ncurves");
	if (!c.ncurves)
		return false;
	uint64_t total = 0;
	for (uint32_t l = 0; l < c.nloops; l++)
		total += c.ncurves[l];
	c.ntotal = (uint32_t)total;
	static const char *const per_curve[] = { "order", "min", "max", "n" };
	static const uint32_t arg_of[] = { 1, 3, 4, 5 };
	for (int k = 0; k < 4; k++)
		if (r->args[arg_of[k]].n != total) {
			reyes_ri_err(ri, r->args[arg_of[k]].loc,
				     "TrimCurve: %s has %u values, but ncurves adds up to %llu curves",
				     per_curve[k], r->args[arg_of[k]].n, (unsigned long long)total);
			return false;
		}
	c.order = uints_arg(ri, r, 1, "order");
	c.n = uints_arg(ri, r, 5, "n");
	if (!c.order || !c.n)
		return false;
	uint64_t nk = 0, np = 0;
	for (uint32_t i = 0; i < c.ntotal; i++) {
		nk += (uint64_t)c.order[i] + c.n[i];
		np += c.n[i];
	}
	c.knot = floats_arg(ri, r, 2, "knot", nk);
	c.min = c.knot ? floats_arg(ri, r, 3, "min", total) : NULL;
	c.max = c.min ? floats_arg(ri, r, 4, "max", total) : NULL;
	c.u = c.max ? floats_arg(ri, r, 6, "u", np) : NULL;
	c.v = c.u ? floats_arg(ri, r, 7, "v", np) : NULL;
	c.w = c.v ? floats_arg(ri, r, 8, "w", np) : NULL;
	if (!c.w)
		return false;
	c.nknots = (uint32_t)nk;
	c.npoints = (uint32_t)np;
	const char *why = reyes_trim_build(&c, arena_alloc, reyes_ri_cur_arena(ri), out);
	if (why) {
		reyes_ri_err(ri, r->loc, "TrimCurve: %s", why);
		return false;
	}
	return true;
}

void reyes_ri_req_trim_curve(struct ri *ri, const struct rib_request *r)
{
	const struct reyes_trim *t = NULL;
	bool ok = trim_curve(ri, r, &t);
	struct attrstate *a = &ri->gs.a;
	a->trim = ok && t && t->nedges ? t : NULL;
	a->trim_bad = !ok;
	a->trim_loc = reyes_ri_keep_loc(ri, r->loc);
}

bool reyes_ri_nurbs_same(const struct reyes_prim *a, const struct reyes_prim *b)
{
	const struct reyes_nurbs *x = a->nurbs, *y = b->nurbs;
	if (!x || !y)
		return x == y;
	if (x->nu != y->nu || x->nv != y->nv || x->uorder != y->uorder || x->vorder != y->vorder ||
	    x->umin != y->umin || x->umax != y->umax || x->vmin != y->vmin || x->vmax != y->vmax ||
	    x->trim != y->trim || !x->w != !y->w)
		return false;
	if (memcmp(x->uknot, y->uknot, sizeof(float) * (x->nu + x->uorder)) ||
	    memcmp(x->vknot, y->vknot, sizeof(float) * (x->nv + x->vorder)))
		return false;
	return !x->w || !memcmp(x->w, y->w, sizeof(float) * (size_t)x->nu * x->nv);
}

/*
 * Shadow geometry: see shadowgeo.h.
 *
 * The dicing is the renderer's (reyes_dice): this file decides which lights
 * need it and gathers the grids into world-space meshes.
 */
#include "shadowgeo.h"
#include "reyes.h"
#include "builtin.h"
#include "ir.h"
#include "mathlib.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- which lights cast shadows ---- */

/*
 * The value the light's instance gives string parameter @p: the RIB value,
 * else the default when it is a constant. NULL when the default is computed
 * (it may well be a map's name).
 */
static const char *string_param_value(const struct reyes_shader *sh, const struct sl_program *prog,
				      const struct sl_param *p)
{
	for (uint32_t i = 0; i < sh->nparams; i++) {
		const struct reyes_param_value *pv = &sh->params[i];
		if (pv->name && !strcmp(pv->name, p->name) && pv->type == SL_TYPE_STRING)
			return pv->strings && pv->nvalues && pv->strings[0] ? pv->strings[0] : "";
	}
	if (p->init_begin == p->init_end)
		return "";
	if (p->init_end - p->init_begin != 1 || p->init_end > prog->ncode)
		return NULL;
	const struct sl_insn *in = &prog->code[p->init_begin];
	if (in->op != SL_OP_MOV || in->dst != p->reg || in->nargs != 1 || in->args[0] < 0 ||
	    (uint32_t)in->args[0] >= prog->nregs)
		return NULL;
	const struct sl_reg *src = &prog->regs[in->args[0]];
	if (src->kind != SL_REG_CONST || src->type != SL_TYPE_STRING || src->cindex >= prog->nstrings)
		return NULL;
	return prog->strings[src->cindex];
}

/* Is a string parameter (not an array, not an output) set to a non-empty name? */
static bool any_string_param_set(const struct reyes_shader *sh, const struct sl_program *prog)
{
	for (uint32_t i = 0; i < prog->nparams; i++) {
		const struct sl_param *p = &prog->params[i];
		if (p->type.base != SL_TYPE_STRING || p->type.arraylen >= 0 || p->output)
			continue;
		const char *v = string_param_value(sh, prog, p);
		if (!v || *v)
			return true;
	}
	return false;
}

/* Does register @reg, a shadow() map argument, name a map? */
static bool names_map(const struct reyes_shader *sh, const struct sl_program *prog, int32_t reg)
{
	if (reg < 0 || (uint32_t)reg >= prog->nregs)
		return false;
	const struct sl_reg *r = &prog->regs[reg];
	if (r->kind == SL_REG_CONST)
		return r->type == SL_TYPE_STRING && r->cindex < prog->nstrings &&
		       prog->strings[r->cindex][0];
	if (r->kind == SL_REG_PARAM)
		for (uint32_t i = 0; i < prog->nparams; i++)
			if (prog->params[i].reg == reg) {
				const char *v = string_param_value(sh, prog, &prog->params[i]);
				return !v || *v;
			}
	/* a computed name: any name given to the light may reach it */
	return any_string_param_set(sh, prog);
}

bool bake_light_casts_shadows(const struct reyes_scene *scene, uint32_t light)
{
	if (!scene || light >= scene->nlights)
		return false;
	const struct reyes_shader *sh = &scene->lights[light].shader;
	const struct sl_program *prog = sh->prog;
	if (!prog)
		return false;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (in->op != SL_OP_CALL || in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins ||
		    sl_builtins[in->bi].id != SL_BI_SHADOW || in->nargs < 1)
			continue;
		if (names_map(sh, prog, in->args[0]))
			return true;
	}
	return false;
}

/* Does some light name the map "raytrace" (a ray-traced shadow), in a parameter's value? */
static bool traces_shadows(const struct reyes_scene *scene)
{
	for (uint32_t l = 0; l < scene->nlights; l++) {
		const struct reyes_shader *sh = &scene->lights[l].shader;
		const struct sl_program *prog = sh->prog;
		for (uint32_t i = 0; prog && i < prog->nparams; i++) {
			const struct sl_param *p = &prog->params[i];
			if (p->type.base != SL_TYPE_STRING || p->type.arraylen >= 0 || p->output)
				continue;
			const char *v = string_param_value(sh, prog, p);
			if (v && !strcmp(v, "raytrace"))
				return true;
		}
	}
	return false;
}

/* ---- gathering the grids ---- */

struct gather {
	struct bake_shadow_geometry *out;
	float c2w[16];               /* camera to world */
	uint64_t cap_points, cap_quads, cap_object, cap_opacity;
	uint64_t bad_points;         /* not finite: their micropolygons are left out */
	FILE *diag;
	const struct reyes_csg *csg;
	bool warned_csg;
	const struct sl_program **warned_oi;  /* surfaces already warned about */
	uint32_t nwarned_oi;
};

/* ---- opacity ---- */

enum oi_source { OI_OPAQUE, OI_OS, OI_COMPUTED };

/*
 * Where surface @prog's Oi comes from: never set (the renderer leaves it
 * 1), set only by copies of Os, or computed. *@at: the first instruction
 * that computes it.
 */
static enum oi_source oi_source(const struct sl_program *prog, const struct sl_insn **at)
{
	int32_t oi = prog->global_reg[SL_GLOBAL_OI], os = prog->global_reg[SL_GLOBAL_OS];
	bool set = false;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (oi < 0 || in->dst != oi)
			continue;
		set = true;
		if (in->op != SL_OP_MOV || in->nargs != 1 || os < 0 || in->args[0] != os) {
			*at = in;
			return OI_COMPUTED;
		}
	}
	return set ? OI_OS : OI_OPAQUE;
}

/* Say once per shader that its computed Oi is not what the deep maps see. */
static void warn_oi(struct gather *gt, const struct sl_program *prog, const struct sl_insn *at)
{
	for (uint32_t i = 0; i < gt->nwarned_oi; i++)
		if (gt->warned_oi[i] == prog)
			return;
	const struct sl_program **w = realloc(gt->warned_oi, (gt->nwarned_oi + 1) * sizeof(*w));
	if (!w)
		return;
	gt->warned_oi = w;
	w[gt->nwarned_oi++] = prog;
	const char *file = prog->files && at->loc.file < prog->nfiles && prog->files[at->loc.file]
				   ? prog->files[at->loc.file] : prog->name;
	fprintf(gt->diag, "%s:%u: warning: surface '%s' computes Oi: the shadow geometry takes "
		"its Os instead (the surface is not shaded for it), so a deep shadow map the GPU "
		"renders from it sees Os where the renderer's sees this Oi\n", file, at->loc.line,
		prog->name);
}

/*
 * Micropolygon (i, j)'s opacity, grey: @Os per point (planar, @n points) or
 * the attribute's, averaged over its corners @v.
 */
static float quad_opacity(const struct reyes_prim *prim, enum oi_source src, const float *Os,
			  uint64_t n, const uint32_t v[4])
{
	const float *a = prim->attrs->Os;
	if (src == OI_OPAQUE || prim->attrs->matte)
		return 1.0f;
	double sum = 0.0;
	if (!Os)
		sum = 4.0 * ((double)a[0] + a[1] + a[2]) / 3.0;
	for (int c = 0; Os && c < 4; c++)
		sum += ((double)Os[v[c]] + Os[n + v[c]] + Os[2 * n + v[c]]) / 3.0;
	float o = (float)(sum / 4.0);
	return o > 0.0f ? (o < 1.0f ? o : 1.0f) : 0.0f;
}

/*
 * Solids: which micropolygon of a solid bounds it is a question of the
 * whole ray, not of the micropolygon, so the shadow geometry keeps the
 * surfaces that can only add to the solid: a leaf on the subtracted side
 * of a difference is left out, every other kept whole. The solid's volume
 * lies inside those leaves' union, so a map from them shadows at least
 * where the solid does: a difference casts as its first child, uncut; an
 * intersection as the union of its children. A union is exact. Reported
 * once, at the first such solid.
 */
static bool csg_casts(struct gather *gt, const struct reyes_prim *prim)
{
	if (!prim->csg_leaf || prim->csg_leaf > gt->csg->nnodes)
		return true;
	uint32_t leaf = prim->csg_leaf - 1;
	if (reyes_csg_union_only(gt->csg, leaf))
		return true;
	if (!gt->warned_csg) {
		const struct reyes_csg_node *root = &gt->csg->nodes[gt->csg->nodes[leaf].root];
		rib_warning(gt->diag, root->loc,
			    "the GPU's shadow maps of this \"%s\" solid hold its surfaces without "
			    "the cuts (its subtracted parts left out, the rest whole): they shadow "
			    "more than the render's where the cuts show to the light",
			    reyes_csg_op_name(root->op));
		gt->warned_csg = true;
	}
	return !reyes_csg_subtracted(gt->csg, leaf);
}

/* Make room for @need elements of @elem bytes in *data (capacity *cap). */
static bool reserve(void **data, uint64_t *cap, uint64_t need, size_t elem)
{
	if (need <= *cap)
		return true;
	uint64_t nc = *cap ? *cap : 4096;
	while (nc < need)
		nc *= 2;
	if (nc > SIZE_MAX / elem)
		return false;
	void *p = realloc(*data, (size_t)nc * elem);
	if (!p)
		return false;
	*data = p;
	*cap = nc;
	return true;
}

static bool on_grid(void *user, const struct reyes_prim *prim, const float *P, uint32_t nu,
		    uint32_t nv, const uint8_t *keep, const float *Os)
{
	struct gather *gt = user;
	struct bake_shadow_geometry *o = gt->out;
	if (nu < 2 || nv < 2 || !csg_casts(gt, prim))
		return true;
	/* no surface: the default one, which sets Oi = Os */
	const struct sl_program *surf = prim->attrs->surface ? prim->attrs->surface->prog : NULL;
	const struct sl_insn *at = NULL;
	enum oi_source src = surf ? oi_source(surf, &at) : OI_OS;
	if (src == OI_COMPUTED && !prim->attrs->matte)
		warn_oi(gt, surf, at);
	uint64_t n = (uint64_t)nu * nv, nq = (uint64_t)(nu - 1) * (nv - 1);
	if (o->npoints + n > UINT32_MAX || o->ngrids == UINT32_MAX) {
		fprintf(gt->diag, "relight: error: the shadow geometry would have more than %u "
			"points: dice it coarser (a larger shadow rate)\n", UINT32_MAX);
		return false;
	}
	if (!reserve((void **)&o->P, &gt->cap_points, o->npoints + n, 3 * sizeof(float)) ||
	    !reserve((void **)&o->quads, &gt->cap_quads, o->nquads + nq, 4 * sizeof(uint32_t)) ||
	    !reserve((void **)&o->object, &gt->cap_object, o->nquads + nq, sizeof(uint32_t)) ||
	    !reserve((void **)&o->opacity, &gt->cap_opacity, o->nquads + nq, sizeof(float))) {
		fprintf(gt->diag, "relight: error: out of memory for the shadow geometry (%llu "
			"points)\n", (unsigned long long)(o->npoints + n));
		return false;
	}
	uint32_t base = (uint32_t)o->npoints;
	float *dst = o->P + 3 * o->npoints;
	for (uint64_t k = 0; k < n; k++) {
		float c[3] = { P[k], P[n + k], P[2 * n + k] }, w[3];
		sl_xform_point(w, gt->c2w, c);
		if (!isfinite(w[0]) || !isfinite(w[1]) || !isfinite(w[2])) {
			/*
			 * Kept, so that indices stay grid-shaped, but marked (x is
			 * NaN) until its micropolygons are left out below.
			 */
			w[0] = NAN;
			w[1] = w[2] = 0;
			gt->bad_points++;
		}
		memcpy(dst + 3 * k, w, sizeof(w));
	}
	uint32_t *q = o->quads + 4 * o->nquads;
	uint32_t *obj = o->object + o->nquads;
	float *op = o->opacity + o->nquads;
	uint64_t kept = 0;
	for (uint32_t j = 0; j + 1 < nv; j++)
		for (uint32_t i = 0; i + 1 < nu; i++) {
			uint32_t a = j * nu + i;
			uint32_t v[4] = { a, a + 1, a + nu + 1, a + nu };
			/* a trimmed NuPatch: micropolygons whose centre is cut away cast nothing */
			bool good = !keep || keep[j * (nu - 1) + i];
			for (int c = 0; c < 4; c++)
				good = good && !isnan(dst[3 * v[c]]);
			if (!good)
				continue;
			for (int c = 0; c < 4; c++)
				q[4 * kept + (uint64_t)c] = base + v[c];
			op[kept] = quad_opacity(prim, src, Os, n, v);
			obj[kept++] = prim->id;
		}
	for (uint64_t k = 0; k < n; k++)
		if (isnan(dst[3 * k]))
			dst[3 * k] = 0;
	o->npoints += n;
	o->nquads += kept;
	o->ngrids++;
	return true;
}

bool bake_shadow_geometry(const struct reyes_scene *scene, float rate, FILE *diag,
			  struct bake_shadow_geometry *out)
{
	memset(out, 0, sizeof(*out));
	if (!diag)
		diag = stderr;
	if (!(rate > 0) || !isfinite(rate)) {
		fprintf(diag, "relight: error: the shadow rate must be a positive number (got %g)\n",
			(double)rate);
		return false;
	}
	struct gather gt = { .out = out, .diag = diag, .csg = &scene->csg };
	if (!sl_m44_inverse(gt.c2w, scene->opts.world_to_camera)) {
		fprintf(diag, "relight: error: the camera transform cannot be inverted\n");
		return false;
	}
	/*
	 * With a ray-traced shadow the GPU traces this geometry where the
	 * renderer traces its own: dice it as the renderer dices what rays see
	 * (each primitive's ShadingRate, every piece as if the camera faced it),
	 * so that both shadows have the same edges.
	 */
	bool rays = traces_shadows(scene);
	struct reyes_dice_opts o = {
		.rate = rays ? 0.0f : rate,
		.orient_free = rays,
		.cull_to_view = false,
		.casters_only = true,
		.diag = diag,
		.user = &gt,
		.grid = on_grid,
	};
	bool ok = reyes_dice(scene, &o);
	free(gt.warned_oi);
	if (gt.bad_points)
		fprintf(diag, "relight: warning: %llu shadow geometry points were not finite; "
			"their micropolygons are left out\n", (unsigned long long)gt.bad_points);
	if (!ok) {
		bake_shadow_geometry_free(out);
		return false;
	}
	/* give back what doubling left over (a failure keeps the larger block) */
	void *p;
	if (out->npoints && (p = realloc(out->P, (size_t)out->npoints * 3 * sizeof(float))))
		out->P = p;
	if (out->nquads && (p = realloc(out->quads, (size_t)out->nquads * 4 * sizeof(uint32_t))))
		out->quads = p;
	if (out->nquads && (p = realloc(out->object, (size_t)out->nquads * sizeof(uint32_t))))
		out->object = p;
	if (out->nquads && (p = realloc(out->opacity, (size_t)out->nquads * sizeof(float))))
		out->opacity = p;
	return true;
}

void bake_shadow_geometry_free(struct bake_shadow_geometry *g)
{
	free(g->P);
	free(g->quads);
	free(g->object);
	free(g->opacity);
	memset(g, 0, sizeof(*g));
}

/*
 * Geometry NAME ...primitive variables: the implementation-specific
 * primitives. "teapot" is the Newell teapot (geom_teapot.h), as prman and
 * Aqsis provide it: 32 bicubic Bezier patches under the current attributes,
 * each taking the request's constant and uniform primitive variables. Any
 * other name is a warning at its line, and nothing is drawn.
 */
#include "ri_impl.h"

#include "geom_teapot.h"
#include "sl.h"

#include <string.h>

static const float bezier[16] = {-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0};

/* Patch @i of the teapot, with @r's (constant, uniform) primitive variables. */
static void teapot_patch(struct ri *ri, const struct rib_request *r, uint32_t i)
{
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	struct reyes_prim tmp = {0};
	static const uint32_t sizes[5] = {1, 1, 4, 16, 4};
	if (!reyes_ri_prim_vars(ri, r, sizes, false, &tmp))
		return;
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_PATCHES);
	p->bicubic = true;
	p->nu = p->nv = 4;
	p->npoints = 16;
	memcpy(p->ubasis, bezier, sizeof(bezier));
	memcpy(p->vbasis, bezier, sizeof(bezier));
	p->ustep = p->vstep = 3;
	float *P = rl_arena_alloc(a, sizeof(float) * 48);
	reyes_teapot_patch(i, P);
	struct reyes_primvar *vars = rl_arena_alloc(a, sizeof(*vars) * (tmp.nvars + 1));
	vars[0] = (struct reyes_primvar){.name = "P", .cls = REYES_VERTEX, .type = SL_TYPE_POINT,
					 .count = 16, .values = P};
	memcpy(vars + 1, tmp.vars, sizeof(*vars) * tmp.nvars);
	p->vars = vars;
	p->nvars = tmp.nvars + 1;
	reyes_ri_emit_prim(ri, r, p);
}

void reyes_ri_req_geometry(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name))
		return;
	if (strcmp(name, "teapot") != 0) {
		reyes_ri_warn(ri, r->loc, "Geometry \"%s\" is not supported: ignored (known: "
			      "\"teapot\")", name);
		return;
	}
	for (uint32_t i = 0; i < REYES_TEAPOT_PATCHES && !ri->prim_failed; i++)
		teapot_patch(ri, r, i);
}

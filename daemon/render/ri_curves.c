/*
 * The RIB scene builder's Curves and Points (RISpec 3.2 section 5.5), and
 * the eye their ribbons and disks face once the scene is finished.
 *
 * Curves TYPE [NVERTICES] WRAP ...: "linear" or "cubic" (through the
 * current v basis and its step), "periodic" or "nonperiodic". Curve c of n
 * vertices has n - 1 (linear), n (linear periodic), (n - 4) / vstep + 1
 * (cubic) or n / vstep (cubic periodic) segments. Its primitive variables
 * are constant (one), uniform (one per curve), varying (one per segment
 * end: segments + 1 per curve, or segments when periodic) and vertex (one
 * per point); "width" (varying by default) or "constantwidth" give the
 * ribbon's width in object space (default 1), "N" makes it face N.
 *
 * Points ...: "P", "width" (varying, one per point) or "constantwidth".
 * Disks always face the camera: "N" is warned about and not used.
 */
#include "ri_impl.h"

#include "mathlib.h"
#include "sl.h"

#include <math.h>
#include <string.h>

/* Every value of "width" or "constantwidth" finite and not negative; reported if not. */
static bool widths_ok(struct ri *ri, const struct rib_request *r, const struct reyes_prim *p)
{
	for (uint32_t i = 0; i < p->nvars; i++) {
		const struct reyes_primvar *v = &p->vars[i];
		if (strcmp(v->name, "width") != 0 && strcmp(v->name, "constantwidth") != 0)
			continue;
		if (v->type != SL_TYPE_FLOAT || v->arraylen) {
			reyes_ri_err(ri, r->loc, "%s: \"%s\" must be a float", r->name, v->name);
			return false;
		}
		for (uint32_t k = 0; k < v->count; k++)
			if (!(v->values[k] >= 0) || !isfinite(v->values[k])) {
				reyes_ri_err(ri, r->loc, "%s: \"%s\" %u is %g (a width is 0 or more)",
					     r->name, v->name, k, (double)v->values[k]);
				return false;
			}
	}
	return true;
}

/*
 * The segments of a curve of @n vertices, or 0 when @n makes no whole
 * segments.
 */
static uint32_t segments(bool cubic, bool periodic, uint32_t n, uint32_t vstep)
{
	if (!cubic)
		return periodic ? (n >= 2 ? n : 0) : (n >= 2 ? n - 1 : 0);
	if (periodic)
		return n >= 3 && n % vstep == 0 ? n / vstep : 0;
	return n >= 4 && (n - 4) % vstep == 0 ? (n - 4) / vstep + 1 : 0;
}

void reyes_ri_req_curves(struct ri *ri, const struct rib_request *r)
{
	const char *type, *wrap;
	if (!reyes_ri_geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &type))
		return;
	if (r->nargs < 2 || !reyes_ri_is_numbers(&r->args[1]) || r->args[1].n == 0)
		FAIL(ri, r->loc, "Curves: argument 2 should be an array of vertex counts");
	if (!reyes_ri_str_arg(ri, r, 2, &wrap))
		return;
	bool cubic = strcmp(type, "cubic") == 0;
	if (!cubic && strcmp(type, "linear") != 0)
		FAIL(ri, r->loc, "Curves type must be \"linear\" or \"cubic\", got '%s'", type);
	bool periodic = strcmp(wrap, "periodic") == 0;
	if (!periodic && strcmp(wrap, "nonperiodic") != 0)
		FAIL(ri, r->loc, "Curves wrap mode must be \"periodic\" or \"nonperiodic\", got '%s'",
		     wrap);
	const struct rib_value *nv = &r->args[1];
	uint32_t nc = nv->n, vstep = ri->gs.a.vstep;
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	uint32_t *nverts = rl_arena_alloc(a, sizeof(uint32_t) * nc);
	uint32_t *vfirst = rl_arena_alloc(a, sizeof(uint32_t) * nc);
	uint32_t *sfirst = rl_arena_alloc(a, sizeof(uint32_t) * (nc + 1));
	uint64_t nvtx = 0, nseg = 0, nvary = 0;
	for (uint32_t c = 0; c < nc; c++) {
		double d = nv->nums[c];
		if (!(d >= 1 && d <= UINT32_MAX && d == floor(d)))
			FAIL(ri, nv->loc, "Curves: nvertices %u is %g (a count of 1 or more)", c, d);
		uint32_t n = (uint32_t)d, s = segments(cubic, periodic, n, vstep);
		if (!s)
			FAIL(ri, nv->loc, "Curves: curve %u has %u vertices, too few or not whole %s "
			     "segments (%s%s)", c, n, cubic ? "cubic" : "linear", wrap,
			     cubic ? rl_arena_printf(ri->perm, ", vstep %u", vstep) : "");
		nverts[c] = n;
		vfirst[c] = (uint32_t)nvtx;
		sfirst[c] = (uint32_t)nseg;
		nvtx += n;
		nseg += s;
		nvary += periodic ? s : s + 1;
		if (nvtx > UINT32_MAX || nvary > UINT32_MAX)
			FAIL(ri, r->loc, "Curves is too large");
	}
	sfirst[nc] = (uint32_t)nseg;
	uint32_t np;
	if (!reyes_ri_point_count(ri, r, &np))
		return;
	if (np != nvtx)
		FAIL(ri, r->loc, "Curves: nvertices add up to %llu, but \"P\" has %u points",
		     (unsigned long long)nvtx, np);
	struct reyes_curves *cv = rl_arena_alloc(a, sizeof(*cv));
	*cv = (struct reyes_curves){.cubic = cubic, .periodic = periodic, .ncurves = nc,
				    .nverts = nverts, .vfirst = vfirst, .sfirst = sfirst,
				    .vstep = vstep};
	memcpy(cv->basis, ri->gs.a.vbasis, sizeof(cv->basis));
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_CURVES);
	p->curves = cv;
	p->npoints = np;
	uint32_t sizes[5] = {1, nc, (uint32_t)nvary, np, (uint32_t)nvary};
	if (reyes_ri_prim_vars(ri, r, sizes, true, p) && widths_ok(ri, r, p))
		reyes_ri_emit_prim(ri, r, p);
}

void reyes_ri_req_points(struct ri *ri, const struct rib_request *r)
{
	uint32_t np;
	if (!reyes_ri_geometry_ok(ri, r) || !reyes_ri_point_count(ri, r, &np))
		return;
	struct reyes_prim *p = reyes_ri_new_prim(ri, REYES_POINTS);
	p->npoints = np;
	uint32_t sizes[5] = {1, 1, np, np, np};
	if (!reyes_ri_prim_vars(ri, r, sizes, true, p) || !widths_ok(ri, r, p))
		return;
	if (reyes_prim_var(p, "N"))
		reyes_ri_warn(ri, r->loc, "Points: \"N\" (disks facing N) is not supported: the "
			      "disks face the camera");
	reyes_ri_emit_prim(ri, r, p);
}

bool reyes_ri_same_curves(const struct reyes_curves *a, const struct reyes_curves *b)
{
	if (!a || !b)
		return a == b;
	return a->cubic == b->cubic && a->periodic == b->periodic && a->ncurves == b->ncurves &&
	       a->vstep == b->vstep && memcmp(a->basis, b->basis, sizeof(a->basis)) == 0 &&
	       memcmp(a->nverts, b->nverts, sizeof(uint32_t) * a->ncurves) == 0;
}

void reyes_ri_face_camera(struct reyes_scene *sc)
{
	const struct reyes_options *o = &sc->opts;
	for (uint32_t i = 0; i < sc->nprims; i++) {
		struct reyes_prim *p = &sc->prims[i];
		if (p->kind != REYES_CURVES && p->kind != REYES_POINTS)
			continue;
		for (int t = 0; t < 2; t++) {
			const struct reyes_attrs *at = p->attrs;
			float m[16], inv[16];
			sl_m44_mul(m, at->object_to_world[at->moving ? t : 0],
				   t ? o->world_to_camera1 : o->world_to_camera);
			float *e = p->eye[t];
			memset(e, 0, sizeof(p->eye[t]));
			if (t == 0)
				p->mirror = sl_m44_det(m) < 0;
			if (!sl_m44_inverse(inv, m))
				continue;       /* geometry then faces down +z */
			if (o->perspective) {
				/* the camera's origin (row vectors: the inverse's translation) */
				e[0] = inv[12], e[1] = inv[13], e[2] = inv[14], e[3] = 1.0f;
			} else {
				/* towards the camera: its -z */
				float back[3] = {0.0f, 0.0f, -1.0f};
				sl_xform_vector(e, inv, back);
			}
		}
	}
}

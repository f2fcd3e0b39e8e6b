/*
 * The RIB scene builder: the meaning of the requests the RIB reader hands
 * over, following the RenderMan Interface Specification 3.2. This file has
 * diagnostics, the graphics state, transformations, blocks, shaders,
 * archives, frames and the dispatch of requests; ri_options.c has the
 * options (camera, image, displays, hider), ri_prims.c the geometry
 * (declarations, primitives, motion blocks, retained objects) with the
 * primitives of files of their own (ri_subdiv.c, ri_nurbs.c, ri_curves.c,
 * ri_blobby.c, ri_geometry.c, ri_procedural.c, ri_csg.c), and ri_impl.h the
 * state they share.
 *
 * State, from the longest-lived down:
 *  - the read: declarations, the compiled shaders (one compilation per file
 *    and read), objects defined outside a world, lights declared before
 *    WorldBegin (until the end of their frame), in the `perm` arena;
 *  - options, saved and restored by FrameBegin/FrameEnd;
 *  - the graphics state (attributes and the current transformation) with
 *    its stack of blocks; a block records what it must restore;
 *  - the world being built (lights, primitives, named spaces, objects
 *    defined inside it), in the `world` arena, which becomes the scene's
 *    arena at WorldEnd and is freed after the frame callback.
 *
 * Transformations use RenderMan's row-vector convention: a new
 * transformation applies to points before the current one, M' = T * M.
 * Before WorldBegin the current transformation maps to camera space; inside
 * the world it maps to world space.
 */
#include "ri_impl.h"

#include "arena.h"
#include "config.h"
#include "fileutil.h"
#include "hider.h"
#include "ir.h"
#include "mathlib.h"
#include "shader_cache.h"
#include "sl.h"
#include "strbuf.h"
#include "texture.h"
#include "deepshadow.h"

#include <ctype.h>
#include <dirent.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum {
	MAX_ARCHIVE_DEPTH = 64,       /* ReadArchive nesting */
	MAX_ARCHIVE_READS = 100000,   /* ReadArchive requests in one read */
	MAX_BLOCK_DEPTH = 10000,      /* nested blocks */
};

#define PI_F 3.14159265358979323846f
#define DEFAULT_NEAR 1e-10f
#define DEFAULT_FAR 1e30f

static const char *const blk_begin[] = {
	"FrameBegin", "WorldBegin", "AttributeBegin", "TransformBegin", "MotionBegin",
	"ObjectBegin",
};

/* ---- diagnostics ------------------------------------------------------------------- */

static void forward_reader_diag(struct ri *ri);

/*
 * One diagnostic. Each (message, place) is printed once a read: a request
 * repeated by a loop of ReadArchive reports its place once, the repeats
 * counted. --strict makes a warning an error. An error inside a primitive's
 * request drops that primitive only; any other holds back its frame.
 */
static void verr(struct ri *ri, struct rib_loc loc, bool warning, const char *fmt, va_list ap)
{
	forward_reader_diag(ri);
	bool strict = warning && ri->opts->strict;
	if (strict)
		warning = false;
	struct rl_strbuf b = {0};
	rl_strbuf_printf(&b, "%c%s:%u: ", warning ? 'w' : 'e', loc.file ? loc.file : "",
			 (unsigned)loc.line);
	size_t msg = b.len;
	rl_strbuf_vprintf(&b, fmt, ap);
	if (strict)
		rl_strbuf_printf(&b, " (an error under --strict)");
	uintptr_t seen;
	bool repeat = strmap_get(&ri->seen, rl_strbuf_str(&b), &seen);
	if (repeat) {
		ri->repeats++;
	} else {
		strmap_put(&ri->seen, rl_arena_strdup(ri->perm, rl_strbuf_str(&b)), 1);
		if (warning)
			rib_warning(ri->diag, loc, "%s", rl_strbuf_str(&b) + msg);
		else
			rib_error(ri->diag, loc, "%s", rl_strbuf_str(&b) + msg);
	}
	if (warning) {
		ri->warnings += !repeat;
	} else {
		ri->nerrors += !repeat;
		if (ri->in_prim) {
			ri->prim_failed = true;
			ri->prim_errors += !repeat;
		} else {
			ri->frame_errors++;
		}
		/* the limit counts the errors printed that hold back frames: repeats and
		   dropped primitives cannot end the read */
		if (ri->nerrors - ri->prim_errors + ri->reader_errors >= ri->max_errors)
			ri->stop = true;
	}
	rl_strbuf_finish(&b);
}

void reyes_ri_err(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	verr(ri, loc, false, fmt, ap);
	va_end(ap);
}

void reyes_ri_warn(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	verr(ri, loc, true, fmt, ap);
	va_end(ap);
}

/*
 * Passes the reader's pending messages on; its errors count against the
 * frame, or with @prim against the primitive they dropped.
 */
static void forward_reader_diag_as(struct ri *ri, bool prim)
{
	if (!ri->rdiag)
		return;
	fflush(ri->rdiag);
	if (!ri->rlen)
		return;
	fwrite(ri->rbuf, 1, ri->rlen, ri->diag);
	fflush(ri->diag);
	const char *p = ri->rbuf, *end = ri->rbuf + ri->rlen;
	static const char tag[] = ": error: ";
	while (p < end) {
		const char *nl = memchr(p, '\n', (size_t)(end - p));
		size_t len = nl ? (size_t)(nl - p) : (size_t)(end - p);
		for (size_t i = 0; i + sizeof(tag) - 1 <= len; i++)
			if (memcmp(p + i, tag, sizeof(tag) - 1) == 0) {
				if (prim)
					ri->reader_prim++;
				else
					ri->frame_errors++;
				break;
			}
		p += len + 1;
	}
	rewind(ri->rdiag);
	fflush(ri->rdiag);
}

static void forward_reader_diag(struct ri *ri)
{
	forward_reader_diag_as(ri, false);
}

/* The loc with its file name interned (the reader's name dies with its read). */
struct rib_loc reyes_ri_keep_loc(struct ri *ri, struct rib_loc loc)
{
	if (ri->files.len) {
		struct file *f = &ri->files.data[ri->files.len - 1];
		if (loc.file == f->raw_name && f->name)
			return (struct rib_loc){f->name, loc.line};
		if (loc.file) {
			f->raw_name = loc.file;
			f->name = rl_arena_strdup(ri->perm, loc.file);
			return (struct rib_loc){f->name, loc.line};
		}
	}
	return (struct rib_loc){loc.file ? rl_arena_strdup(ri->perm, loc.file) : NULL, loc.line};
}

/* "line 9", or "FILE:9" when @at is in another file than @from. */
const char *reyes_ri_where(struct ri *ri, struct rib_loc at, struct rib_loc from)
{
	if (at.file && from.file && strcmp(at.file, from.file) == 0)
		return rl_arena_printf(ri->perm, "line %u", (unsigned)at.line);
	return rl_arena_printf(ri->perm, "%s:%u", at.file ? at.file : "<rib>", (unsigned)at.line);
}

/* ---- arguments ----------------------------------------------------------------------- */

bool reyes_ri_num_arg(struct ri *ri, const struct rib_request *r, uint32_t i, double *out)
{
	if (i < r->nargs && (r->args[i].type == RIB_NUMBER || r->args[i].type == RIB_NUMBERS) &&
	    r->args[i].n == 1) {
		*out = r->args[i].nums[0];
		return true;
	}
	reyes_ri_err(ri, r->loc, "%s: argument %u should be a number", r->name, i + 1);
	return false;
}

bool reyes_ri_str_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char **out)
{
	if (i < r->nargs && (r->args[i].type == RIB_STRING || r->args[i].type == RIB_STRINGS) &&
	    r->args[i].n == 1) {
		*out = r->args[i].strs[0];
		return true;
	}
	reyes_ri_err(ri, r->loc, "%s: argument %u should be a string", r->name, i + 1);
	return false;
}

/* Numbers args[first..first+n) as floats. */
bool reyes_ri_float_args(struct ri *ri, const struct rib_request *r, uint32_t first, uint32_t n,
			 float *out)
{
	for (uint32_t i = 0; i < n; i++) {
		double d;
		if (!reyes_ri_num_arg(ri, r, first + i, &d))
			return false;
		if (!(fabs(d) <= FLT_MAX)) {
			reyes_ri_err(ri, r->loc, "%s: %g is out of range", r->name, d);
			return false;
		}
		out[i] = (float)d;
	}
	return true;
}

/* A handle (integer or string) as a string in @a. */
const char *reyes_ri_handle_arg(struct ri *ri, const struct rib_request *r, uint32_t i,
				struct rl_arena *a)
{
	if (i < r->nargs && (r->args[i].type == RIB_STRING || r->args[i].type == RIB_STRINGS) &&
	    r->args[i].n == 1)
		return rl_arena_strdup(a, r->args[i].strs[0]);
	double d;
	if (!reyes_ri_num_arg(ri, r, i, &d))
		return NULL;
	return rl_arena_printf(a, "%.17g", d);
}

/* A value's numbers as floats; false (reported) when one is beyond the float range. */
bool reyes_ri_value_floats(struct ri *ri, const struct rib_value *v, struct rib_loc loc,
			   const char *what, float *out)
{
	for (uint32_t i = 0; i < v->n; i++) {
		double d = v->nums[i];
		if (!(fabs(d) <= FLT_MAX)) {
			reyes_ri_err(ri, loc, "%s: %g is out of range for a float", what, d);
			return false;
		}
		out[i] = (float)d;
	}
	return true;
}

bool reyes_ri_is_numbers(const struct rib_value *v)
{
	return v->type == RIB_NUMBER || v->type == RIB_NUMBERS;
}

/* ---- the graphics state ------------------------------------------------------------- */

static void attrs_init(struct attrstate *a)
{
	static const float bezier[16] = {-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0};
	*a = (struct attrstate){0};
	a->Cs[0] = a->Cs[1] = a->Cs[2] = 1;
	a->Os[0] = a->Os[1] = a->Os[2] = 1;
	a->sides = 2;
	a->shading_rate = 1;
	a->dbound_space = "object";
	a->casts_shadows = true;
	a->ray = (struct reyes_ray_attrs){
		.camera = true, .transmission = REYES_TRANS_OS,
		.hitmode = { REYES_HIT_SHADER, REYES_HIT_PRIMITIVE, REYES_HIT_SHADER },
		.bias = 0.01f, .max_specular_depth = 2, .max_diffuse_depth = 1,
	};
	memcpy(a->ubasis, bezier, sizeof(bezier));
	memcpy(a->vbasis, bezier, sizeof(bezier));
	a->ustep = a->vstep = 3;
	reyes_ri_detail_init(a);
}

static void xform_init(struct xform *x)
{
	sl_m44_identity(x->m[0]);
	sl_m44_identity(x->m[1]);
	x->moving = false;
}

struct rl_arena *reyes_ri_cur_arena(struct ri *ri)
{
	return ri->world ? ri->world : ri->perm;
}

static void attrs_changed(struct ri *ri)
{
	ri->gs.bundle = NULL;
}

void reyes_ri_set_xform(struct ri *ri, const float m0[16], const float m1[16])
{
	memcpy(ri->gs.x.m[0], m0, sizeof(float) * 16);
	memcpy(ri->gs.x.m[1], m1, sizeof(float) * 16);
	ri->gs.x.moving = memcmp(m0, m1, sizeof(float) * 16) != 0;
	ri->gs.bundle = NULL;
}

/* Is the current coordinate system right-handed (camera space is left-handed)? */
static bool right_handed(const struct ri *ri)
{
	bool flip = sl_m44_det(ri->gs.x.m[0]) < 0;
	if (ri->world)
		flip ^= ri->w2c_mirror;
	return flip;
}

static const struct reyes_shader *join_atmosphere(struct ri *ri, const struct reyes_shader *surf,
						  const struct reyes_shader *atm);

/* A bundle of the current attributes with transformation @x. */
const struct reyes_attrs *reyes_ri_make_bundle(struct ri *ri, const struct xform *x)
{
	const struct attrstate *a = &ri->gs.a;
	struct reyes_attrs *b = rl_arena_alloc(ri->world, sizeof(*b));
	ri->gs.own_lights = NULL;       /* the bundle shares the light set */
	memcpy(b->Cs, a->Cs, sizeof(b->Cs));
	memcpy(b->Os, a->Os, sizeof(b->Os));
	b->surface = a->atmosphere ? join_atmosphere(ri, a->surface, a->atmosphere) : a->surface;
	b->displacement = a->displacement;
	b->lights = a->lights;
	b->nlights = a->nlights;
	b->sides = a->sides;
	b->flip_normals = a->inside;
	b->shading_rate = a->shading_rate;
	b->shading_rate_loc = a->shading_rate_loc;
	b->smooth = a->smooth;
	b->identifier = a->identifier;
	b->displacement_bound = a->dbound;
	b->displacement_bound_space = a->dbound_space;
	b->casts_shadows = a->casts_shadows;
	b->ray = a->ray;
	b->matte = a->matte;
	if (a->has_texcoords) {
		float *tc = rl_arena_alloc(ri->world, sizeof(a->texcoords));
		memcpy(tc, a->texcoords, sizeof(a->texcoords));
		b->texcoords = tc;
	}
	/* a representation its DetailRange leaves out is dropped (lod_hi 0) */
	if (!reyes_ri_detail_visible(a, &b->lod_lo, &b->lod_hi))
		b->lod_lo = b->lod_hi = 0;
	b->dissolve = b->lod_lo > 0 || b->lod_hi < 1;
	b->moving = x->moving;
	memcpy(b->object_to_world, x->m, sizeof(b->object_to_world));
	return b;
}

const struct reyes_attrs *reyes_ri_cur_bundle(struct ri *ri)
{
	if (!ri->gs.bundle)
		ri->gs.bundle = reyes_ri_make_bundle(ri, &ri->gs.x);
	return ri->gs.bundle;
}

static void req_color(struct ri *ri, const struct rib_request *r)
{
	float c[3];
	if (!reyes_ri_float_args(ri, r, 0, 3, c))
		return;
	bool color = strcmp(r->name, "Color") == 0;
	memcpy(color ? ri->gs.a.Cs : ri->gs.a.Os, c, sizeof(c));
	ri->gs.a.objset |= color ? OBJ_CS : OBJ_OS;
	attrs_changed(ri);
}

static void req_sides(struct ri *ri, const struct rib_request *r)
{
	double n;
	if (!reyes_ri_num_arg(ri, r, 0, &n))
		return;
	if (n != 1 && n != 2)
		FAIL(ri, r->loc, "Sides must be 1 or 2, got %g", n);
	ri->gs.a.sides = (int)n;
	ri->gs.a.objset |= OBJ_SIDES;
	attrs_changed(ri);
}

static void req_orientation(struct ri *ri, const struct rib_request *r)
{
	const char *o;
	if (!reyes_ri_str_arg(ri, r, 0, &o))
		return;
	bool rh = right_handed(ri);
	if (strcmp(o, "outside") == 0)
		ri->gs.a.inside = false;
	else if (strcmp(o, "inside") == 0)
		ri->gs.a.inside = true;
	else if (strcmp(o, "lh") == 0)
		ri->gs.a.inside = rh;
	else if (strcmp(o, "rh") == 0)
		ri->gs.a.inside = !rh;
	else
		FAIL(ri, r->loc,
			   "Orientation must be \"outside\", \"inside\", \"lh\" or \"rh\", got '%s'",
			   o);
	ri->gs.a.objset |= OBJ_ORIENTATION;
	attrs_changed(ri);
}

static void req_reverse_orientation(struct ri *ri, const struct rib_request *r)
{
	(void)r;
	ri->gs.a.inside = !ri->gs.a.inside;
	ri->gs.a.objset |= OBJ_ORIENTATION;
	attrs_changed(ri);
}

static void req_shading_rate(struct ri *ri, const struct rib_request *r)
{
	float s;
	if (!reyes_ri_float_args(ri, r, 0, 1, &s))
		return;
	if (!(s > 0))
		FAIL(ri, r->loc, "ShadingRate must be positive, got %g", s);
	ri->gs.a.shading_rate = s;
	ri->gs.a.shading_rate_loc = reyes_ri_keep_loc(ri, r->loc);
	ri->gs.a.objset |= OBJ_SHADING_RATE;
	attrs_changed(ri);
}

static void req_shading_interpolation(struct ri *ri, const struct rib_request *r)
{
	const char *s;
	if (!reyes_ri_str_arg(ri, r, 0, &s))
		return;
	if (strcmp(s, "smooth") == 0)
		ri->gs.a.smooth = true;
	else if (strcmp(s, "constant") == 0)
		ri->gs.a.smooth = false;
	else
		FAIL(ri, r->loc,
			   "ShadingInterpolation must be \"constant\" or \"smooth\", got '%s'", s);
	ri->gs.a.objset |= OBJ_INTERPOLATION;
	attrs_changed(ri);
}

static void req_attribute(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	bool identifier = strcmp(name, "identifier") == 0;
	bool dbound = strcmp(name, "displacementbound") == 0;
	bool visibility = strcmp(name, "visibility") == 0;
	if (!strcmp(name, "shade") || !strcmp(name, "trace")) {
		reyes_ri_trace_attribute(ri, r, name);
		return;
	}
	if (!identifier && !dbound && !visibility) {
		reyes_ri_warn(ri, r->loc, "unknown attribute '%s' ignored", name);
		return;
	}
	struct attrstate *a = &ri->gs.a;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		bool str1 = !reyes_ri_is_numbers(v) && v->n == 1;
		bool num1 = reyes_ri_is_numbers(v) && v->n == 1;
		if (identifier && strcmp(pname, "name") == 0 && str1) {
			a->identifier = rl_arena_strdup(reyes_ri_cur_arena(ri), v->strs[0]);
			a->objset |= OBJ_IDENTIFIER;
		} else if (dbound && strcmp(pname, "sphere") == 0 && num1) {
			if (!(v->nums[0] >= 0 && v->nums[0] <= FLT_MAX))
				FAIL(ri, p->loc, "displacementbound: bad sphere %g", v->nums[0]);
			a->dbound = (float)v->nums[0];
			a->objset |= OBJ_DBOUND;
		} else if (dbound && strcmp(pname, "coordinatesystem") == 0 && str1) {
			a->dbound_space = rl_arena_strdup(reyes_ri_cur_arena(ri), v->strs[0]);
			a->objset |= OBJ_DBOUND;
		} else if (visibility && strcmp(pname, "transmission") == 0 && (num1 || str1)) {
			/* Numbers 0/1, or the older strings "opaque", "transparent", "Os", "shader". */
			const char *m = str1 ? v->strs[0] : NULL;
			if (m && strcmp(m, "opaque") && strcmp(m, "transparent") && strcmp(m, "Os") &&
			    strcmp(m, "shader")) {
				reyes_ri_warn(ri, p->loc, "visibility \"transmission\" \"%s\" is not "
					      "\"opaque\", \"transparent\", \"Os\" or \"shader\": "
					      "ignored", m);
				continue;
			}
			if (m && !strcmp(m, "shader"))
				reyes_ri_warn(ri, p->loc, "visibility \"transmission\" \"shader\": "
					      "shadow rays see the primitive's Os, not its shader's Oi");
			a->casts_shadows = num1 ? v->nums[0] != 0 : strcmp(m, "transparent") != 0;
			a->ray.transmission = num1 ? (v->nums[0] != 0 ? REYES_TRANS_OS : REYES_TRANS_NONE)
					    : !strcmp(m, "transparent") ? REYES_TRANS_NONE
					    : !strcmp(m, "opaque") ? REYES_TRANS_OPAQUE : REYES_TRANS_OS;
			a->objset |= OBJ_VISIBILITY;
		} else if (visibility && num1 && (strcmp(pname, "camera") == 0 ||
						  strcmp(pname, "diffuse") == 0 ||
						  strcmp(pname, "specular") == 0 ||
						  strcmp(pname, "trace") == 0)) {
			bool on = v->nums[0] != 0;
			if (pname[0] == 'c')
				a->ray.camera = on;
			if (pname[0] == 'd' || pname[0] == 't')
				a->ray.diffuse = on;
			if (pname[0] == 's' || pname[0] == 't')
				a->ray.specular = on;
			a->objset |= OBJ_VISIBILITY;
		} else if (visibility && strcmp(pname, "photon") == 0) {
			reyes_ri_warn(ri, p->loc, "visibility \"photon\": relight casts no photons; "
				      "ignored");
		} else {
			reyes_ri_warn(ri, p->loc, "unknown attribute '%s' '%s' ignored", name,
				      pname);
			continue;
		}
	}
	attrs_changed(ri);
}

/* ---- transformations ---------------------------------------------------------------- */

/*
 * RISpec's skew: points move parallel to @v2 so that @v1 turns by @angle
 * degrees towards it. With a the unit vector along v2 and p the unit part of
 * v1 perpendicular to a, x' = x + k (x . p) a, where k takes v1 (at angle phi
 * from a) to phi - angle: k = cot(phi - angle) - cot(phi).
 */
static bool skew_matrix(float m[16], float angle, const float v1[3], const float v2[3])
{
	float a[3], u1[3], p[3];
	sl_v3_normalize(a, v2);
	sl_v3_normalize(u1, v1);
	if (sl_v3_length(a) == 0 || sl_v3_length(u1) == 0)
		return false;
	float c = sl_v3_dot(u1, a);
	for (int i = 0; i < 3; i++)
		p[i] = u1[i] - c * a[i];
	float s = sl_v3_length(p);
	if (s < 1e-6f)
		return false;
	for (int i = 0; i < 3; i++)
		p[i] /= s;
	double phi = atan2(s, c), rest = phi - angle * (PI_F / 180);
	if (!(rest > 1e-6 && rest < PI_F - 1e-6))
		return false;
	float k = (float)(1 / tan(rest) - c / s);
	sl_m44_identity(m);
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			m[i * 4 + j] += k * p[i] * a[j];
	return true;
}

/*
 * The matrix of a transformation request: *set when it replaces the current
 * transformation (Identity, Transform), else it is concatenated.
 */
static bool xform_of(struct ri *ri, const struct rib_request *r, float m[16], bool *set)
{
	*set = false;
	const char *n = r->name;
	if (strcmp(n, "Identity") == 0) {
		*set = true;
		sl_m44_identity(m);
		return true;
	}
	if (strcmp(n, "Transform") == 0 || strcmp(n, "ConcatTransform") == 0) {
		*set = n[0] == 'T';
		if (r->nargs < 1 || !reyes_ri_is_numbers(&r->args[0]) || r->args[0].n != 16)
			return reyes_ri_err(ri, r->loc, "%s needs 16 numbers", n), false;
		return reyes_ri_value_floats(ri, &r->args[0], r->loc, n, m);
	}
	float v[7];
	if (strcmp(n, "Translate") == 0) {
		if (!reyes_ri_float_args(ri, r, 0, 3, v))
			return false;
		sl_m44_translation(m, v);
	} else if (strcmp(n, "Rotate") == 0) {
		if (!reyes_ri_float_args(ri, r, 0, 4, v))
			return false;
		if (v[1] == 0 && v[2] == 0 && v[3] == 0)
			return reyes_ri_err(ri, r->loc, "Rotate: the axis is zero"), false;
		sl_m44_rotation(m, v[0] * (PI_F / 180), v + 1);
	} else if (strcmp(n, "Scale") == 0) {
		if (!reyes_ri_float_args(ri, r, 0, 3, v))
			return false;
		sl_m44_scaling(m, v);
	} else if (strcmp(n, "Skew") == 0) {
		if (!reyes_ri_float_args(ri, r, 0, 7, v))
			return false;
		if (!skew_matrix(m, v[0], v + 1, v + 4))
			return reyes_ri_err(ri, r->loc,
					    "Skew: the angle %g is not less than the angle between "
					    "the axes (or an axis is zero)", v[0]), false;
	} else {
		return false;
	}
	return true;
}

static void req_xform(struct ri *ri, const struct rib_request *r)
{
	float m[16];
	bool set;
	if (!xform_of(ri, r, m, &set))
		return;
	if (ri->motion.active) {
		reyes_ri_motion_xform(ri, r, m, set);
		return;
	}
	if (set) {
		reyes_ri_set_xform(ri, m, m);
		return;
	}
	float m0[16], m1[16];
	sl_m44_mul(m0, m, ri->gs.x.m[0]);
	sl_m44_mul(m1, m, ri->gs.x.m[1]);
	reyes_ri_set_xform(ri, m0, m1);
}

static void req_coordinate_system(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	static const char *const builtin[] = {"object", "world", "camera", "screen", "raster",
					      "NDC", "shader", "current"};
	for (size_t i = 0; i < sizeof(builtin) / sizeof(builtin[0]); i++)
		if (strcmp(name, builtin[i]) == 0)
			FAIL(ri, r->loc, "CoordinateSystem: '%s' is a predefined space", name);
	bool w = ri->world != NULL;
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	struct strmap *index = w ? &ri->space_index : &ri->pre_space_index;
	uintptr_t k;
	struct space s = {.name = rl_arena_strdup(a, name)};
	memcpy(s.m, ri->gs.x.m[0], sizeof(s.m));
	if (strmap_get(index, name, &k)) {
		(w ? ri->spaces.data : ri->pre_spaces.data)[k - 1] = s;
	} else if (w) {
		rl_vec_push(ri->spaces, s);
		strmap_put(index, s.name, ri->spaces.len);
	} else {
		rl_vec_push(ri->pre_spaces, s);
		strmap_put(index, s.name, ri->pre_spaces.len);
	}
}

static void req_coord_sys_transform(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	float id[16];
	sl_m44_identity(id);
	const float *m = NULL;
	uintptr_t k;
	if (ri->world) {
		if (strcmp(name, "world") == 0)
			m = id;
		else if (strcmp(name, "camera") == 0)
			m = ri->w2c_inv;
		else if (strmap_get(&ri->space_index, name, &k))
			m = ri->spaces.data[k - 1].m;
	} else {
		if (strcmp(name, "camera") == 0)
			m = id;
		else if (strmap_get(&ri->pre_space_index, name, &k))
			m = ri->pre_spaces.data[k - 1].m;
	}
	if (m)
		reyes_ri_set_xform(ri, m, m);
	else
		reyes_ri_err(ri, r->loc, "unknown coordinate system '%s'", name);
}

/* ---- blocks ----------------------------------------------------------------------------- */

void reyes_ri_push_block(struct ri *ri, const struct rib_request *r, enum blk kind)
{
	struct block b = {
		.kind = kind,
		.loc = reyes_ri_keep_loc(ri, r->loc),
		.file_depth = (uint32_t)ri->files.len,
		.pre_lights = ri->pre_lights.len,
		.gs = ri->gs,
		.opt = ri->opt,
	};
	/* The saved state and the live one share the light set now. */
	b.gs.own_lights = NULL;
	ri->gs.own_lights = NULL;
	rl_vec_push(ri->blocks, b);
}

bool reyes_ri_depth_ok(struct ri *ri, const struct rib_request *r)
{
	if (ri->blocks.len < MAX_BLOCK_DEPTH)
		return true;
	reyes_ri_err(ri, r->loc, "%s: blocks nested too deeply (limit %d)", r->name,
		     MAX_BLOCK_DEPTH);
	return false;
}

const struct block *reyes_ri_find_block(const struct ri *ri, enum blk kind)
{
	for (size_t i = ri->blocks.len; i-- > 0;)
		if (ri->blocks.data[i].kind == kind)
			return &ri->blocks.data[i];
	return NULL;
}

static void world_end(struct ri *ri, bool render);

/* The lights declared before WorldBegin end with the frame that declared them. */
static void drop_pre_lights(struct ri *ri, size_t keep)
{
	if (ri->pre_lights.len <= keep)
		return;
	ri->pre_lights.len = keep;
	strmap_free(&ri->pre_light_index);
	for (size_t i = 0; i < keep; i++)
		strmap_put(&ri->pre_light_index, ri->pre_lights.data[i].handle, i + 1);
}

/* Pops the innermost block, restoring what it saved. @ok: it was closed properly. */
static void pop_block(struct ri *ri, bool ok)
{
	struct block b = ri->blocks.data[--ri->blocks.len];
	switch (b.kind) {
	case BLK_FRAME:
		ri->gs = b.gs;
		ri->opt = b.opt;
		drop_pre_lights(ri, b.pre_lights);
		break;
	case BLK_WORLD:
		world_end(ri, ok);
		ri->gs = b.gs;
		ri->gs.bundle = NULL;
		break;
	case BLK_ATTRIBUTE:
		ri->gs = b.gs;
		break;
	case BLK_TRANSFORM:
		ri->gs.x = b.gs.x;
		ri->gs.bundle = NULL;
		break;
	case BLK_MOTION:
		reyes_ri_motion_end(ri, ok);
		break;
	case BLK_OBJECT:
		reyes_ri_object_end(ri);
		ri->gs = b.gs;
		break;
	}
}

/* The end of a block of @kind: it must close the innermost open block. */
bool reyes_ri_close_block(struct ri *ri, const struct rib_request *r, enum blk kind)
{
	if (!ri->blocks.len) {
		reyes_ri_err(ri, r->loc, "%s without a matching %s", r->name, blk_begin[kind]);
		return false;
	}
	const struct block *b = &ri->blocks.data[ri->blocks.len - 1];
	if (b->kind != kind) {
		reyes_ri_err(ri, r->loc, "%s at line %u does not close the %s at %s", r->name,
			     (unsigned)r->loc.line, blk_begin[b->kind],
			     reyes_ri_where(ri, b->loc, r->loc));
		return false;
	}
	if (b->file_depth != ri->files.len) {
		reyes_ri_err(ri, r->loc, "%s closes the %s at %s, opened in another file", r->name,
			     blk_begin[kind], reyes_ri_where(ri, b->loc, r->loc));
		return false;
	}
	pop_block(ri, true);
	return true;
}

/* At the end of a file: blocks it opened and left open are errors (and closed). */
static void close_file_blocks(struct ri *ri)
{
	const struct file *f = &ri->files.data[ri->files.len - 1];
	while (ri->blocks.len && ri->blocks.data[ri->blocks.len - 1].file_depth == ri->files.len) {
		const struct block *b = &ri->blocks.data[ri->blocks.len - 1];
		struct rib_loc at = f->last.file ? f->last : b->loc;
		reyes_ri_err(ri, at, "the file ends inside the %s at %s", blk_begin[b->kind],
			     reyes_ri_where(ri, b->loc, at));
		pop_block(ri, false);
	}
}

static void req_frame_begin(struct ri *ri, const struct rib_request *r)
{
	const struct block *b = reyes_ri_find_block(ri, BLK_FRAME);
	if (b)
		FAIL(ri, r->loc, "FrameBegin inside the FrameBegin at %s",
			   reyes_ri_where(ri, b->loc, r->loc));
	if (ri->world)
		FAIL(ri, r->loc, "FrameBegin inside a world block");
	if (!reyes_ri_depth_ok(ri, r))
		return;
	reyes_ri_push_block(ri, r, BLK_FRAME);
	/* the number names the frame's outputs (relight render -o); FrameEnd restores the options */
	double n = rib_num(r, 0);
	if (n >= INT32_MIN && n <= INT32_MAX && n == (int32_t)n) {
		ri->opt.o.numbered = true;
		ri->opt.o.frame_number = (int32_t)n;
	} else {
		reyes_ri_warn(ri, r->loc, "FrameBegin: %g is not a frame number", n);
	}
}

static void req_frame_end(struct ri *ri, const struct rib_request *r)
{
	reyes_ri_close_block(ri, r, BLK_FRAME);
}

static void req_attribute_begin(struct ri *ri, const struct rib_request *r)
{
	if (reyes_ri_depth_ok(ri, r))
		reyes_ri_push_block(ri, r, strcmp(r->name, "AttributeBegin") == 0 ? BLK_ATTRIBUTE
									 : BLK_TRANSFORM);
}

static void req_attribute_end(struct ri *ri, const struct rib_request *r)
{
	reyes_ri_close_block(ri, r, strcmp(r->name, "AttributeEnd") == 0 ? BLK_ATTRIBUTE
									  : BLK_TRANSFORM);
}

static void req_world_begin(struct ri *ri, const struct rib_request *r)
{
	if (ri->world)
		FAIL(ri, r->loc, "WorldBegin inside the WorldBegin at %s",
			   reyes_ri_where(ri, reyes_ri_find_block(ri, BLK_WORLD)->loc, r->loc));
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "WorldBegin inside an object definition");
	if (!reyes_ri_depth_ok(ri, r))
		return;
	struct reyes_options *o = &ri->opt.o;
	/* A MotionBegin of transformations before WorldBegin moves the camera. */
	memcpy(o->world_to_camera, ri->gs.x.m[0], sizeof(o->world_to_camera));
	memcpy(o->world_to_camera1, ri->gs.x.m[ri->gs.x.moving ? 1 : 0],
	       sizeof(o->world_to_camera1));
	o->camera_moving = ri->gs.x.moving;
	float close_inv[16];
	if (o->camera_moving && !sl_m44_inverse(close_inv, o->world_to_camera1))
		reyes_ri_err(ri, r->loc, "the camera transformation at shutter close is singular");
	if (o->fstop > 0 && !o->perspective) {
		reyes_ri_warn(ri, ri->opt.dof_loc,
			      "DepthOfField needs a perspective projection: the orthographic "
			      "camera renders in focus");
		o->fstop = 0;
	}
	if (!sl_m44_inverse(ri->w2c_inv, o->world_to_camera))
		reyes_ri_err(ri, r->loc, "the camera transformation is singular");
	ri->w2c_mirror = sl_m44_det(o->world_to_camera) < 0;

	/* The projection, mapping near and far to screen z 0 and 1 (RISpec). */
	float n = o->clip_near, f = o->clip_far, *c = o->camera_to_screen;
	memset(c, 0, sizeof(o->camera_to_screen));
	if (o->perspective) {
		float d = 1 / tanf(o->fov * (PI_F / 360));
		c[0] = c[5] = d;
		c[10] = f / (f - n);
		c[11] = 1;
		c[14] = -n * f / (f - n);
	} else {
		c[0] = c[5] = c[15] = 1;
		c[10] = 1 / (f - n);
		c[14] = -n / (f - n);
	}

	reyes_ri_push_block(ri, r, BLK_WORLD);
	ri->world = rl_arena_create();
	/* Spaces named before WorldBegin, now relative to world. */
	for (size_t i = 0; i < ri->pre_spaces.len; i++) {
		struct space s = {.name = ri->pre_spaces.data[i].name};
		sl_m44_mul(s.m, ri->pre_spaces.data[i].m, ri->w2c_inv);
		rl_vec_push(ri->spaces, s);
		strmap_put(&ri->space_index, s.name, ri->spaces.len);
	}
	/* Lights declared before WorldBegin are the world's first, their shader
	   space (camera-relative when declared) now relative to world. */
	for (size_t i = 0; i < ri->pre_lights.len; i++) {
		struct reyes_light l = ri->pre_lights.data[i];
		sl_m44_mul(l.shader.shader_to_world, ri->pre_lights.data[i].shader.shader_to_world,
			   ri->w2c_inv);
		rl_vec_push(ri->lights, l);
		strmap_put(&ri->light_index, l.handle, i + 1);
	}
	xform_init(&ri->gs.x);
	ri->gs.bundle = NULL;
}

static void req_world_end(struct ri *ri, const struct rib_request *r)
{
	reyes_ri_close_block(ri, r, BLK_WORLD);
}

/* ---- shaders ------------------------------------------------------------------------------ */

static bool is_file(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/*
 * @name along the colon-separated @path (absolute names as they are; names
 * with a '/' are also tried as given). @first, if not NULL, is a directory
 * tried before the path. Returns the file's path in perm, or NULL.
 */
static const char *search_file(struct ri *ri, const char *name, const char *first,
			       const char *path)
{
	if (name[0] == '/')
		return is_file(name) ? rl_arena_strdup(ri->perm, name) : NULL;
	struct rl_strbuf b = {0};
	const char *found = NULL;
	if (first) {
		rl_strbuf_printf(&b, "%s/%s", first, name);
		if (is_file(rl_strbuf_str(&b)))
			found = rl_arena_strdup(ri->perm, rl_strbuf_str(&b));
	}
	const char *p = path;
	while (!found && p && *p) {
		const char *e = strchr(p, ':');
		size_t n = e ? (size_t)(e - p) : strlen(p);
		if (n) {
			rl_strbuf_reset(&b);
			rl_strbuf_printf(&b, "%.*s/%s", (int)n, p, name);
			if (is_file(rl_strbuf_str(&b)))
				found = rl_arena_strdup(ri->perm, rl_strbuf_str(&b));
		}
		p = e ? e + 1 : NULL;
	}
	if (!found && strchr(name, '/') && is_file(name))
		found = rl_arena_strdup(ri->perm, name);
	rl_strbuf_finish(&b);
	return found;
}

static int cmp_names(const void *a, const void *b)
{
	return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/*
 * Index the .sl files of each folder of @path by the name they declare
 * (after preprocessing, with the include path of the moment), once per
 * search path and read: "path\nname" -> file in ri->shader_names.
 * The first folder of the path that has a name wins, and within a folder
 * the file whose name sorts first.
 */
static const char *const *split_path(struct ri *ri, const char *path, size_t *n);

static void index_shader_names(struct ri *ri, const char *path)
{
	uintptr_t v;
	if (strmap_get(&ri->names_indexed, path, &v))
		return;
	strmap_put(&ri->names_indexed, rl_arena_strdup(ri->perm, path), 1);
	size_t nincs;
	const char *const *incs = split_path(ri, ri->opt.o.include_path, &nincs);
	for (const char *p = path; p && *p;) {
		const char *e = strchr(p, ':');
		size_t n = e ? (size_t)(e - p) : strlen(p);
		char *dir = rl_arena_printf(ri->perm, "%.*s", (int)n, p);
		p = e ? e + 1 : NULL;
		DIR *d = n ? opendir(dir) : NULL;
		if (!d)
			continue;
		RL_VEC(char *) files = {0};
		for (struct dirent *de; (de = readdir(d));) {
			size_t len = strlen(de->d_name);
			if (len > 3 && strcmp(de->d_name + len - 3, ".sl") == 0)
				rl_vec_push(files, rl_xstrdup(de->d_name));
		}
		closedir(d);
		if (files.len)
			qsort(files.data, files.len, sizeof(files.data[0]), cmp_names);
		for (size_t i = 0; i < files.len; i++) {
			char *file = rl_arena_printf(ri->perm, "%s/%s", dir, files.data[i]);
			free(files.data[i]);
			char err[256];
			size_t len;
			char *src = is_file(file) ? rl_read_file(file, 4u << 20, &len, err,
								 sizeof(err))
						  : NULL;
			struct sl_options so = {.include_dirs = incs, .n_include_dirs = nincs};
			char *name = src ? sl_declared_name(file, src, len, &so) : NULL;
			if (name) {
				const char *key = rl_arena_printf(ri->perm, "%s\n%s", path, name);
				if (!strmap_get(&ri->shader_names, key, &v))
					strmap_put(&ri->shader_names, key, (uintptr_t)file);
			}
			free(name);
			free(src);
		}
		rl_vec_free(files);
	}
}

/* The folders of the colon-separated @path, in perm, as sl_options wants them. */
static const char *const *split_path(struct ri *ri, const char *path, size_t *n)
{
	*n = 0;
	size_t cap = 1;
	for (const char *p = path; p && *p; p++)
		cap += *p == ':';
	const char **dirs = rl_arena_alloc(ri->perm, cap * sizeof(*dirs));
	for (const char *p = path; p && *p;) {
		const char *e = strchr(p, ':');
		size_t len = e ? (size_t)(e - p) : strlen(p);
		if (len)
			dirs[(*n)++] = rl_arena_printf(ri->perm, "%.*s", (int)len, p);
		p = e ? e + 1 : NULL;
	}
	return dirs;
}

/*
 * The compiled shader @name of @kind (compiled once per read), or NULL
 * (reported). As prman: NAME.sl along the shader path, else the .sl file
 * along the path that declares a shader NAME, else the built-in "null".
 */
static struct sl_program *load_shader(struct ri *ri, const struct rib_request *r,
				      const char *name, enum sl_shader_kind kind)
{
	size_t len = strlen(name);
	bool has_ext = len > 3 && strcmp(name + len - 3, ".sl") == 0;
	const char *sp = ri->opt.o.shader_path;
	const char *file = has_ext ? name : rl_arena_printf(ri->perm, "%s.sl", name);
	const char *path = search_file(ri, file, NULL, sp);
	if (!path && !has_ext && !strchr(name, '/') && sp) {
		index_shader_names(ri, sp);
		uintptr_t v;
		if (strmap_get(&ri->shader_names, rl_arena_printf(ri->perm, "%s\n%s", sp, name),
			       &v))
			path = (const char *)v;
	}
	/* The built-in "null": a file of the standard library, so that a shot
	   baked with it finds its source as it finds any other. */
	if (!path && strcmp(name, "null") == 0) {
		const char *lib = rl_arena_printf(ri->perm, "%s/null_%s.sl",
						  RELIGHT_SOURCE_SHADER_DIR,
						  sl_shader_kind_name(kind));
		path = is_file(lib) ? lib : NULL;
	}
	if (!path) {
		reyes_ri_err(ri, r->loc, "cannot find shader '%s' (searched: %s)", name, sp);
		return NULL;
	}
	/* One compilation per file and include path: an #include may find
	   another file once the include path changes. */
	const char *inc = ri->opt.o.include_path;
	const char *key = rl_arena_printf(ri->perm, "%s\n%s", path, inc ? inc : "");
	uintptr_t v;
	if (strmap_get(&ri->shader_cache, key, &v)) {
		if (!v)
			reyes_ri_err(ri, r->loc, "shader '%s' (%s) did not compile", name, path);
		return (struct sl_program *)v;
	}
	forward_reader_diag(ri);
	struct sl_options so = {.diag = ri->diag, .max_errors = ri->max_errors};
	so.include_dirs = split_path(ri, inc, &so.n_include_dirs);
	struct reyes_shader_cache *cache = ri->opts->shader_cache;
	struct sl_program *prog = cache ? reyes_shader_cache_compile(cache, path, &so)
					: sl_compile_file(path, &so);
	strmap_put(&ri->shader_cache, key, (uintptr_t)prog);
	if (!prog) {
		reyes_ri_err(ri, r->loc, "shader '%s' (%s) did not compile", name, path);
		return NULL;
	}
	if (!cache)
		rl_vec_push(ri->progs, prog);
	return prog;
}

static const char *type_desc(struct ri *ri, int type, uint32_t arraylen)
{
	if (arraylen)
		return rl_arena_printf(ri->perm, "%s[%u]", sl_basetype_name(type), arraylen);
	return sl_basetype_name(type);
}

static bool same_type(const struct decl *d, int base, uint32_t arraylen)
{
	return !d->hpoint && d->type == base && d->arraylen == arraylen;
}

/* The parameter list of a shader request as typed values of @prog's parameters. */
static bool shader_params(struct ri *ri, const struct rib_request *r, const char *shname,
			  const struct sl_program *prog, struct reyes_shader *sh)
{
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	struct reyes_param_value *vals = rl_arena_alloc(a, sizeof(*vals) * (r->nparams + 1));
	bool *seen = rl_xcalloc(prog->nparams + 1, sizeof(bool));
	uint32_t n = 0;
	bool ok = true;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *name;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &name)) {
			ok = false;
			continue;
		}
		uintptr_t dv;
		if (!has && strmap_get(&ri->decls, name, &dv)) {
			d = *(const struct decl *)dv;
			has = true;
		}
		int pi = sl_program_find_param(prog, name);
		if (pi < 0) {
			reyes_ri_warn(ri, p->loc, "shader '%s' has no parameter '%s': ignored",
				      shname, name);
			continue;
		}
		const struct sl_param *sp = &prog->params[pi];
		int base = sp->type.base;
		uint32_t alen = sp->type.arraylen > 0 ? (uint32_t)sp->type.arraylen : 0;
		if (has && !same_type(&d, base, alen)) {
			reyes_ri_warn(ri, p->loc,
				      "parameter '%s' of shader '%s' is %s, but it is given as %s%s: "
				      "ignored", name, shname, type_desc(ri, base, alen),
				      d.hpoint ? "hpoint" : type_desc(ri, d.type, 0),
				      d.arraylen ? rl_arena_printf(ri->perm, "[%u]", d.arraylen)
						 : "");
			continue;
		}
		if (seen[pi]) {
			reyes_ri_warn(ri, p->loc, "parameter '%s' of shader '%s' is given twice: "
				      "the first value is kept", name, shname);
			continue;
		}
		seen[pi] = true;
		struct reyes_param_value *pv = &vals[n];
		*pv = (struct reyes_param_value){.name = name, .type = base, .arraylen = alen};
		uint32_t count = alen ? alen : 1;
		if (base == SL_TYPE_STRING) {
			if (reyes_ri_is_numbers(&p->value) || p->value.n != count) {
				reyes_ri_err(ri, p->loc,
					     "parameter '%s' of shader '%s' needs %u string%s",
					     name, shname, count, count == 1 ? "" : "s");
				ok = false;
				continue;
			}
			const char **s = rl_arena_alloc(a, sizeof(*s) * count);
			for (uint32_t k = 0; k < count; k++)
				s[k] = rl_arena_strdup(a, p->value.strs[k]);
			pv->strings = s;
			pv->nvalues = count;
		} else {
			uint32_t want = count * (uint32_t)sl_type_ncomp(base);
			if (!reyes_ri_is_numbers(&p->value) || p->value.n != want) {
				if (reyes_ri_is_numbers(&p->value))
					reyes_ri_err(ri, p->loc, "parameter '%s' of shader '%s' "
						     "needs %u value%s, got %u", name, shname, want,
						     want == 1 ? "" : "s", p->value.n);
				else
					reyes_ri_err(ri, p->loc, "parameter '%s' of shader '%s' "
						     "needs %u number%s, got a string", name,
						     shname, want, want == 1 ? "" : "s");
				ok = false;
				continue;
			}
			float *f = rl_arena_alloc(a, sizeof(float) * want);
			if (!reyes_ri_value_floats(ri, &p->value, p->loc, name, f)) {
				ok = false;
				continue;
			}
			pv->values = f;
			pv->nvalues = want;
		}
		n++;
	}
	free(seen);
	sh->params = vals;
	sh->nparams = n;
	return ok;
}

/* A shader instance for a Surface, Displacement, LightSource or Imager request. */
static struct reyes_shader *make_shader(struct ri *ri, const struct rib_request *r,
					enum sl_shader_kind want)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return NULL;
	struct sl_program *prog = load_shader(ri, r, name, want);
	if (!prog)
		return NULL;
	enum sl_shader_kind kind = sl_program_kind(prog);
	if (kind != want) {
		reyes_ri_err(ri, r->loc, "%s needs a %s shader, but '%s' is a %s shader", r->name,
			     sl_shader_kind_name(want), name, sl_shader_kind_name(kind));
		return NULL;
	}
	struct reyes_shader *sh = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(*sh));
	sh->name = rl_arena_strdup(reyes_ri_cur_arena(ri), name);
	sh->prog = prog;
	memcpy(sh->shader_to_world, ri->gs.x.m[0], sizeof(sh->shader_to_world));
	if (!shader_params(ri, r, name, prog, sh))
		return NULL;
	return sh;
}

static void req_surface(struct ri *ri, const struct rib_request *r)
{
	bool surf = strcmp(r->name, "Surface") == 0;
	struct reyes_shader *sh =
		make_shader(ri, r, surf ? SL_SHADER_SURFACE : SL_SHADER_DISPLACEMENT);
	if (!sh)
		return;
	if (surf)
		ri->gs.a.surface = sh;
	else
		ri->gs.a.displacement = sh;
	ri->gs.a.objset |= surf ? OBJ_SURFACE : OBJ_DISPLACEMENT;
	attrs_changed(ri);
}

/*
 * Atmosphere, Interior, Exterior (RISpec 3.2 §4.1.8): volume shaders. An
 * atmosphere changes the colour of the camera rays that reach the surfaces
 * it is bound to, so relight runs it on every shading sample after the
 * surface (reyes_ri_make_bundle). Interior and exterior shaders act on rays
 * refracted into and reflected off a surface by trace(), which relight does
 * not have: they are bound, and said to do nothing. "null" (RI_NULL) or ""
 * unbinds.
 */
static void req_volume(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	const struct reyes_shader *sh = NULL;
	if (name[0] && strcmp(name, "null") != 0) {
		sh = make_shader(ri, r, SL_SHADER_VOLUME);
		if (!sh)
			return;
	}
	struct attrstate *a = &ri->gs.a;
	if (!strcmp(r->name, "Atmosphere")) {
		if (sh && !ri->default_surface) {
			/* the surface of primitives that have none, which it follows */
			const char *dflt = search_file(ri, "defaultsurface.sl", NULL,
						       ri->opt.o.shader_path)
						   ? "defaultsurface"
						   : RELIGHT_SOURCE_SHADER_DIR "/defaultsurface.sl";
			ri->default_surface = load_shader(ri, r, dflt, SL_SHADER_SURFACE);
			if (!ri->default_surface)
				return;
		}
		a->atmosphere = sh;
		a->objset |= OBJ_ATMOSPHERE;
		attrs_changed(ri);
		return;
	}
	if (sh)
		reyes_ri_warn(ri, r->loc, "%s shaders act on traced rays, which relight does not "
			      "trace: no effect", r->name);
	if (!strcmp(r->name, "Interior"))
		a->interior = sh;
	else
		a->exterior = sh;
}

/*
 * The program of @surf followed by @atm (sl_program_compose), made once per
 * pair in a read, so that every primitive of the pair shares one program (the
 * bake's group, the preview's kernels).
 */
static struct sl_program *joined_program(struct ri *ri, const struct sl_program *surf,
					 const struct sl_program *atm)
{
	char key[64];
	snprintf(key, sizeof(key), "%p+%p", (const void *)surf, (const void *)atm);
	uintptr_t v;
	if (strmap_get(&ri->joined, key, &v))
		return (struct sl_program *)v;
	struct sl_program *p = sl_program_compose(surf, atm);
	if (!p)
		return NULL;
	rl_vec_push(ri->progs, p);
	strmap_put(&ri->joined, rl_arena_strdup(ri->perm, key), (uintptr_t)p);
	return p;
}

/*
 * The shader instance that runs the surface @surf (NULL: the default
 * surface) then the atmosphere @atm: the joined program with both
 * instances' parameter values, the atmosphere's under the names the joined
 * program gives them. Shader space is the surface's.
 */
static const struct reyes_shader *join_atmosphere(struct ri *ri, const struct reyes_shader *surf,
						  const struct reyes_shader *atm)
{
	struct rl_arena *ar = ri->world;
	struct reyes_shader *dflt = NULL;
	if (!surf) {
		dflt = rl_arena_alloc(ar, sizeof(*dflt));
		dflt->name = "defaultsurface";
		dflt->prog = ri->default_surface;
		sl_m44_identity(dflt->shader_to_world);
		surf = dflt;
	}
	struct sl_program *p = joined_program(ri, surf->prog, atm->prog);
	if (!p)
		return surf;
	struct reyes_shader *sh = rl_arena_alloc(ar, sizeof(*sh));
	sh->name = sl_program_name(p);
	sh->prog = p;
	memcpy(sh->shader_to_world, surf->shader_to_world, sizeof(sh->shader_to_world));
	struct reyes_param_value *pv =
		rl_arena_alloc(ar, sizeof(*pv) * (surf->nparams + atm->nparams + 1));
	if (surf->nparams)
		memcpy(pv, surf->params, sizeof(*pv) * surf->nparams);
	uint32_t n = surf->nparams;
	uint32_t first = surf->prog->nparams;
	for (uint32_t i = 0; i < atm->nparams; i++) {
		int k = sl_program_find_param(atm->prog, atm->params[i].name);
		if (k < 0)
			continue;
		pv[n] = atm->params[i];
		pv[n++].name = p->params[first + (uint32_t)k].name;
	}
	sh->params = pv;
	sh->nparams = n;
	return sh;
}

/*
 * Switches light @index on or off in the current light set: in place when
 * the set is not shared, else in a copy (with room to grow, so that a run
 * of LightSource requests takes linear time).
 */
static void set_light(struct ri *ri, uint32_t index, bool on)
{
	struct gstate *gs = &ri->gs;
	struct attrstate *a = &gs->a;
	uint32_t lo = 0, hi = a->nlights;
	while (lo < hi) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (a->lights[mid] < index)
			lo = mid + 1;
		else
			hi = mid;
	}
	bool is_on = lo < a->nlights && a->lights[lo] == index;
	if (on == is_on)
		return;
	uint32_t n = on ? a->nlights + 1 : a->nlights - 1;
	if (gs->own_lights != a->lights || n > gs->lights_cap) {
		uint32_t cap = n < 4 ? 8 : 2 * n;
		uint32_t *l = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(uint32_t) * cap);
		if (a->nlights)
			memcpy(l, a->lights, sizeof(uint32_t) * a->nlights);
		gs->own_lights = l;
		gs->lights_cap = cap;
		a->lights = l;
	}
	uint32_t *l = gs->own_lights;
	if (on) {
		memmove(l + lo + 1, l + lo, sizeof(uint32_t) * (a->nlights - lo));
		l[lo] = index;
	} else {
		memmove(l + lo, l + lo + 1, sizeof(uint32_t) * (a->nlights - lo - 1));
	}
	a->nlights = n;
	attrs_changed(ri);
}

/*
 * Check an edit of light shader @sh's parameters and apply it: the value
 * of @e->param replaces the one the request gave (or joins the list).
 * @vals has room for sh->nparams plus one entry per edit.
 */
static bool apply_light_edit(struct ri *ri, const struct rib_request *r,
			     const struct reyes_light_edit *e, struct reyes_shader *sh,
			     struct reyes_param_value *vals)
{
	const struct sl_program *prog = sh->prog;
	int k = sl_program_find_param(prog, e->param);
	if (k < 0 || prog->params[k].output) {
		reyes_ri_err(ri, r->loc, "--set %s.%s: shader '%s' has no parameter '%s'", e->light,
			     e->param, sh->name, e->param);
		return false;
	}
	const struct sl_param *sp = &prog->params[k];
	uint32_t nc = (uint32_t)sl_type_ncomp(sp->type.base);
	uint32_t i = 0;
	while (i < sh->nparams && strcmp(vals[i].name, sp->name) != 0)
		i++;
	if (sp->type.base == SL_TYPE_STRING && sp->type.arraylen < 0 && e->nvalues == 0 &&
	    e->text) {
		/* a string: the value as written, a map's name say */
		const char **sv = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(char *));
		size_t len = strlen(e->text) + 1;
		char *copy = rl_arena_alloc(reyes_ri_cur_arena(ri), len);
		memcpy(copy, e->text, len);
		sv[0] = copy;
		vals[i] = (struct reyes_param_value){.name = sp->name, .type = sp->type.base,
						     .nvalues = 1, .strings = sv};
		if (i == sh->nparams)
			sh->nparams++;
		return true;
	}
	if (e->nvalues == 0) {
		reyes_ri_err(ri, r->loc, "--set %s.%s: parameter '%s' of shader '%s' is a %s and "
			     "needs numbers, not '%s'", e->light, e->param, e->param, sh->name,
			     sl_basetype_name(sp->type.base), e->text ? e->text : "");
		return false;
	}
	if (sp->type.base == SL_TYPE_STRING || sp->type.arraylen >= 0 || nc == 0) {
		reyes_ri_err(ri, r->loc, "--set %s.%s: parameter '%s' of shader '%s' is a %s%s; only "
			     "float, colour, point, vector, normal and matrix parameters take "
			     "numbers (a string takes its text, an array nothing)", e->light, e->param, e->param, sh->name,
			     sl_basetype_name(sp->type.base), sp->type.arraylen >= 0 ? " array" : "");
		return false;
	}
	/* One value stands for a grey colour, as in the preview. */
	bool grey = e->nvalues == 1 && sp->type.base == SL_TYPE_COLOR;
	if (!grey && e->nvalues != nc) {
		reyes_ri_err(ri, r->loc, "--set %s.%s: parameter '%s' of shader '%s' is a %s and "
			     "takes %u value%s, not %u", e->light, e->param, e->param, sh->name,
			     sl_basetype_name(sp->type.base), nc, nc == 1 ? "" : "s", e->nvalues);
		return false;
	}
	float *f = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(float) * nc);
	for (uint32_t c = 0; c < nc; c++) {
		f[c] = e->values[grey ? 0 : c];
		if (!isfinite(f[c])) {
			reyes_ri_err(ri, r->loc, "--set %s.%s: parameter '%s' needs finite values, "
				     "not %g", e->light, e->param, e->param, (double)f[c]);
			return false;
		}
	}
	vals[i] = (struct reyes_param_value){.name = sp->name, .type = sp->type.base,
					     .nvalues = nc, .values = f};
	if (i == sh->nparams)
		sh->nparams++;
	return true;
}

/* The edits of the light @handle, after its request's own parameters. */
static void apply_light_edits(struct ri *ri, const struct rib_request *r, const char *handle,
			      struct reyes_shader *sh)
{
	const struct reyes_ri_opts *o = ri->opts;
	struct reyes_param_value *vals = NULL;
	for (uint32_t i = 0; i < o->nlight_edits; i++) {
		const struct reyes_light_edit *e = &o->light_edits[i];
		if (strcmp(e->light, handle) != 0)
			continue;
		if (!vals) {
			/* the request's list is shared with nothing else yet, but is
			   const; the edited list is a copy with room to grow */
			vals = rl_arena_alloc(reyes_ri_cur_arena(ri),
					      sizeof(*vals) * (sh->nparams + o->nlight_edits));
			if (sh->nparams)
				memcpy(vals, sh->params, sizeof(*vals) * sh->nparams);
			sh->params = vals;
		}
		apply_light_edit(ri, r, e, sh, vals);
	}
}

/* Marks the edits of light @handle as having found their light. */
static void note_light_handle(struct ri *ri, const char *handle)
{
	for (uint32_t i = 0; i < ri->opts->nlight_edits; i++)
		if (strcmp(ri->opts->light_edits[i].light, handle) == 0)
			ri->edit_seen[i] = true;
}

/*
 * Imager "name" params: an option (RISpec 3.2), kept with the frame's
 * options; "null" turns the imager off.
 */
static void req_imager(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name))
		return;
	if (strcmp(name, "null") == 0) {
		ri->opt.o.imager = NULL;
		return;
	}
	/* relight render --set imager.PARAM=V edits it, as the previews name it
	   (shotmeta.h SHOT_IMAGER) */
	note_light_handle(ri, "imager");
	struct reyes_shader *sh = make_shader(ri, r, SL_SHADER_IMAGER);
	if (!sh)
		return;
	apply_light_edits(ri, r, "imager", sh);
	ri->opt.o.imager = sh;
	ri->opt.o.imager_loc = r->loc;
}

/*
 * LightSource NAME HANDLE PARAMS. Before WorldBegin (even before the first
 * FrameBegin) the light's shader space is the camera-relative current
 * transformation, and the light belongs to every world that follows until
 * the end of the frame it is declared in; its being on is an attribute, as
 * inside the world.
 */
static void req_light_source(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "LightSource inside an object definition");
	bool world = ri->world != NULL;
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	size_t count = world ? ri->lights.len : ri->pre_lights.len;
	/* The handle first: an edit of a light whose shader fails has found its light. */
	const char *handle = r->nargs > 1 ? reyes_ri_handle_arg(ri, r, 1, a)
					  : rl_arena_printf(a, "%zu", count + 1);
	if (!handle)
		return;
	note_light_handle(ri, handle);
	struct reyes_shader *sh = make_shader(ri, r, SL_SHADER_LIGHT);
	if (!sh)
		return;
	apply_light_edits(ri, r, handle, sh);
	uint32_t index = (uint32_t)count;
	struct reyes_light l = {.shader = *sh, .handle = handle, .default_on = true,
				.index = index};
	if (world) {
		rl_vec_push(ri->lights, l);
		strmap_put(&ri->light_index, handle, index + 1);
		reyes_ri_procedural_light(ri, r, &l);
	} else {
		rl_vec_push(ri->pre_lights, l);
		strmap_put(&ri->pre_light_index, handle, index + 1);
	}
	set_light(ri, index, true);
}

static void req_illuminate(struct ri *ri, const struct rib_request *r)
{
	bool world = ri->world != NULL;
	const char *handle = reyes_ri_handle_arg(ri, r, 0, reyes_ri_cur_arena(ri));
	double on;
	if (!handle || !reyes_ri_num_arg(ri, r, 1, &on))
		return;
	uintptr_t k;
	if (!strmap_get(world ? &ri->light_index : &ri->pre_light_index, handle, &k))
		FAIL(ri, r->loc, "Illuminate: unknown light '%s'", handle);
	(world ? ri->lights.data : ri->pre_lights.data)[k - 1].default_on = on != 0;
	set_light(ri, (uint32_t)(k - 1), on != 0);
}

/* ---- archives and textures ----------------------------------------------------------- */

static bool on_request(void *user, const struct rib_request *r);

static struct rib_reader_opts reader_opts(struct ri *ri)
{
	return (struct rib_reader_opts){
		.diag = ri->rdiag ? ri->rdiag : ri->diag,
		.max_errors = ri->max_errors,
	};
}

/*
 * Reads one file (the top-level one or an archive) with the builder's
 * handler; or, with @data, @len bytes of RIB in memory named @path (a
 * procedural's output).
 */
static bool read_source(struct ri *ri, const char *path, const struct stat *st, const char *data,
			size_t len)
{
	struct file f = {.path = path};
	if (st) {
		f.st = *st;
		f.have_st = true;
	}
	rl_vec_push(ri->files, f);
	struct rib_reader_opts ro = reader_opts(ri);
	int n = 0;
	/* an archive a Procedural reads holds requests of its own, not that primitive's */
	bool in_prim = ri->in_prim, prim_failed = ri->prim_failed;
	ri->in_prim = false;
	/* The errors of this file's reader that dropped primitives, apart from
	   those of the archives it reads. */
	int outer = ri->reader_prim;
	ri->reader_prim = 0;
	bool ok = data ? rib_read_buffer(path, data, len, &ro, on_request, ri, &n)
		       : rib_read_file(path, &ro, on_request, ri, &n);
	forward_reader_diag(ri);
	ri->reader_errors += n - ri->reader_prim;
	ri->reader_prim_total += ri->reader_prim;
	ri->reader_prim = outer;
	if (n && ri->nerrors - ri->prim_errors + ri->reader_errors >= ri->max_errors)
		ri->stop = true;
	if (!ri->stop)
		close_file_blocks(ri);
	ri->files.len--;
	ri->in_prim = in_prim;
	ri->prim_failed = prim_failed;
	return ok;
}

static bool read_file(struct ri *ri, const char *path, const struct stat *st)
{
	return read_source(ri, path, st, NULL, 0);
}

bool reyes_ri_read_buffer(struct ri *ri, const char *name, const char *data, size_t len)
{
	return read_source(ri, name, NULL, data, len);
}

/* The directory part of @file, in perm ("." when none). */
static const char *dir_of(struct ri *ri, const char *file)
{
	const char *slash = file ? strrchr(file, '/') : NULL;
	if (!slash)
		return ".";
	if (slash == file)
		return "/";
	return rl_arena_strndup(ri->perm, file, (size_t)(slash - file));
}

bool reyes_ri_read_archive(struct ri *ri, const struct rib_request *r, const char *what,
			   const char *name)
{
	if (ri->files.len > MAX_ARCHIVE_DEPTH) {
		reyes_ri_err(ri, r->loc, "%s '%s': archives nested too deeply (limit %d)", what,
			     name, MAX_ARCHIVE_DEPTH);
		return false;
	}
	if (++ri->archive_reads > MAX_ARCHIVE_READS) {
		reyes_ri_err(ri, r->loc, "too many %s requests (limit %d)", what,
			     MAX_ARCHIVE_READS);
		return false;
	}
	const char *path = search_file(ri, name, dir_of(ri, r->loc.file), ri->opt.o.archive_path);
	if (!path) {
		reyes_ri_err(ri, r->loc, "cannot find archive '%s' (searched: %s:%s)", name,
			     dir_of(ri, r->loc.file), ri->opt.o.archive_path);
		return false;
	}
	struct stat st;
	if (stat(path, &st) != 0) {
		reyes_ri_err(ri, r->loc, "cannot read archive '%s'", path);
		return false;
	}
	for (size_t i = 0; i < ri->files.len; i++) {
		const struct file *f = &ri->files.data[i];
		if (f->have_st && f->st.st_dev == st.st_dev && f->st.st_ino == st.st_ino) {
			reyes_ri_err(ri, r->loc, "%s '%s' would read itself again (%s)", what, name,
				     path);
			return false;
		}
	}
	return read_file(ri, path, &st);
}

static void req_read_archive(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	for (uint32_t i = 0; i < r->nparams; i++)
		reyes_ri_warn(ri, r->params[i].loc, "ReadArchive: parameter '%s' ignored",
			      r->params[i].token);
	reyes_ri_read_archive(ri, r, "ReadArchive", name);
}

static bool wrap_ok(const char *w)
{
	return strcmp(w, "periodic") == 0 || strcmp(w, "clamp") == 0 || strcmp(w, "black") == 0;
}

static void req_make_texture(struct ri *ri, const struct rib_request *r)
{
	const char *pic, *tex, *sw, *tw, *filter;
	float w[2];
	if (!reyes_ri_str_arg(ri, r, 0, &pic) || !reyes_ri_str_arg(ri, r, 1, &tex) ||
	    !reyes_ri_str_arg(ri, r, 2, &sw) || !reyes_ri_str_arg(ri, r, 3, &tw) ||
	    !reyes_ri_str_arg(ri, r, 4, &filter) || !reyes_ri_float_args(ri, r, 5, 2, w))
		return;
	if (!wrap_ok(sw) || !wrap_ok(tw))
		FAIL(ri, r->loc,
			   "MakeTexture: wrap modes must be \"periodic\", \"clamp\" or \"black\", "
			   "got '%s' and '%s'", sw, tw);
	for (uint32_t i = 0; i < r->nparams; i++)
		reyes_ri_warn(ri, r->params[i].loc, "MakeTexture: parameter '%s' ignored",
			      r->params[i].token);
	forward_reader_diag(ri);
	if (ri->opts->check_only)
		return;
	if (!reyes_make_texture(pic, tex, sw, tw, filter, w[0], w[1], ri->diag))
		reyes_ri_err(ri, r->loc, "MakeTexture '%s' -> '%s' failed", pic, tex);
}

static void req_make_shadow(struct ri *ri, const struct rib_request *r)
{
	const char *pic, *tex;
	if (!reyes_ri_str_arg(ri, r, 0, &pic) || !reyes_ri_str_arg(ri, r, 1, &tex))
		return;
	for (uint32_t i = 0; i < r->nparams; i++)
		reyes_ri_warn(ri, r->params[i].loc, "MakeShadow: parameter '%s' ignored",
			      r->params[i].token);
	forward_reader_diag(ri);
	if (ri->opts->check_only)
		return;
	if (!reyes_make_shadow(pic, tex, ri->diag))
		reyes_ri_err(ri, r->loc, "MakeShadow '%s' -> '%s' failed", pic, tex);
}

/* MakeLatLongEnvironment picturename texturename filter swidth twidth */
static void req_make_latlong(struct ri *ri, const struct rib_request *r)
{
	const char *pic, *tex, *filter;
	float w[2];
	if (!reyes_ri_str_arg(ri, r, 0, &pic) || !reyes_ri_str_arg(ri, r, 1, &tex) ||
	    !reyes_ri_str_arg(ri, r, 2, &filter) || !reyes_ri_float_args(ri, r, 3, 2, w))
		return;
	for (uint32_t i = 0; i < r->nparams; i++)
		reyes_ri_warn(ri, r->params[i].loc, "%s: parameter '%s' ignored", r->name,
			      r->params[i].token);
	forward_reader_diag(ri);
	if (ri->opts->check_only)
		return;
	if (!reyes_make_latlong_environment(pic, tex, filter, w[0], w[1], ri->diag))
		reyes_ri_err(ri, r->loc, "%s '%s' -> '%s' failed", r->name, pic, tex);
}

/* MakeCubeFaceEnvironment px nx py ny pz nz texturename fov filter swidth twidth */
static void req_make_cubeface(struct ri *ri, const struct rib_request *r)
{
	const char *faces[6], *tex, *filter;
	float fov, w[2];
	for (uint32_t k = 0; k < 6; k++)
		if (!reyes_ri_str_arg(ri, r, k, &faces[k]))
			return;
	if (!reyes_ri_str_arg(ri, r, 6, &tex) || !reyes_ri_float_args(ri, r, 7, 1, &fov) ||
	    !reyes_ri_str_arg(ri, r, 8, &filter) || !reyes_ri_float_args(ri, r, 9, 2, w))
		return;
	if (!(fov >= 1.0f && fov < 180.0f))
		FAIL(ri, r->loc, "%s: field of view %g out of range (1 to 180 degrees)", r->name,
		     (double)fov);
	if (fov < 90.0f)
		reyes_ri_warn(ri, r->loc, "%s: a field of view of %g degrees leaves the cube's "
			      "edges uncovered (the faces' edge texels are stretched there)",
			      r->name, (double)fov);
	for (uint32_t i = 0; i < r->nparams; i++)
		reyes_ri_warn(ri, r->params[i].loc, "%s: parameter '%s' ignored", r->name,
			      r->params[i].token);
	forward_reader_diag(ri);
	if (ri->opts->check_only)
		return;
	if (!reyes_make_cube_environment(faces, tex, fov, filter, w[0], w[1], ri->diag))
		reyes_ri_err(ri, r->loc, "%s -> '%s' failed", r->name, tex);
}

static void req_ignore(struct ri *ri, const struct rib_request *r)
{
	(void)ri;
	(void)r;
}

/* ---- the frame ---------------------------------------------------------------------------- */

static void build_scene(struct ri *ri, struct reyes_scene *sc)
{
	struct rl_arena *a = ri->world;
	*sc = (struct reyes_scene){.arena = a, .opts = ri->opt.o};
	struct reyes_options *o = &sc->opts;
	if (!(o->frame_aspect > 0))
		o->frame_aspect = (float)o->xres * o->pixel_aspect / (float)o->yres;
	if (!o->screen_set) {
		float fa = o->frame_aspect;
		float s[4] = {-fa, fa, -1, 1}, t[4] = {-1, 1, -1 / fa, 1 / fa};
		memcpy(o->screen, fa >= 1 ? s : t, sizeof(s));
	}
	/* The displays, copied so that this frame's changes stay its own. */
	uint32_t nd = o->ndisplays ? o->ndisplays : 1;
	struct reyes_display *ds = rl_arena_alloc(a, sizeof(*ds) * nd);
	if (o->ndisplays) {
		memcpy(ds, o->displays, sizeof(*ds) * nd);
	} else {
		ds[0] = (struct reyes_display){.name = "ri.exr", .type = "file", .mode = "rgba",
					       .half = true,
					       .file = ri->files.len ? ri->files.data[0].name : NULL};
	}
	for (uint32_t i = 0; i < nd; i++)
		if (ri->opt.quantize_float)
			ds[i].half = false;
	if (ri->opts->output_override) {
		/* the first image display; a frame of depth maps only (a shadow
		 * pass) keeps its names, so the maps its lights read exist */
		uint32_t k = nd;
		for (uint32_t i = nd; i-- > 0;)
			if (strcmp(ds[i].type, "zfile") != 0 && strcmp(ds[i].type, "shadow") != 0 &&
			    strcmp(ds[i].type, "deepshad") != 0 && strcmp(ds[i].mode, "z") != 0)
				k = i;
		if (k < nd)
			ds[k].name = rl_arena_strdup(a, ri->opts->output_override);
	}
	o->displays = ds;
	o->ndisplays = nd;

	sc->lights = ri->lights.data;
	sc->nlights = (uint32_t)ri->lights.len;
	sc->prims = ri->prims.data;
	sc->nprims = (uint32_t)ri->prims.len;
	reyes_ri_csg_scene(ri, a, &sc->csg);
	reyes_ri_face_camera(sc);
	uint32_t ns = (uint32_t)ri->spaces.len;
	const char **names = rl_arena_alloc(a, sizeof(*names) * (ns ? ns : 1));
	float (*m)[16] = rl_arena_alloc(a, sizeof(*m) * (ns ? ns : 1));
	for (uint32_t i = 0; i < ns; i++) {
		names[i] = ri->spaces.data[i].name;
		memcpy(m[i], ri->spaces.data[i].m, sizeof(m[i]));
	}
	sc->space_names = names;
	sc->space_to_world = (const float(*)[16])m;
	sc->nspaces = ns;
}

static void world_end(struct ri *ri, bool render)
{
	forward_reader_diag(ri);
	reyes_ri_csg_world_end(ri, ri->files.len ? ri->files.data[ri->files.len - 1].last
						 : (struct rib_loc){0});
	if (render && !ri->stop && ri->frame_errors == 0 && ri->opts->frame) {
		struct reyes_scene sc;
		build_scene(ri, &sc);
		sc.world = ri->worlds;
		if (!ri->opts->frame(ri->opts->user, &sc)) {
			ri->nerrors++;
			ri->stop = true;
		}
	}
	ri->frame_errors = 0;
	ri->worlds++;
	/* Objects defined inside the world end with it. */
	for (size_t i = ri->outer_objects; i < ri->objects.len; i++)
		rl_vec_free(ri->objects.data[i].prims);
	ri->objects.len = ri->outer_objects;
	strmap_free(&ri->world_object_index);
	strmap_free(&ri->light_index);
	strmap_free(&ri->space_index);
	ri->lights.len = 0;
	ri->prims.len = 0;
	ri->csg_nodes.len = 0;
	ri->spaces.len = 0;
	rl_arena_destroy(ri->world);
	ri->world = NULL;
}

/* ---- dispatch ---------------------------------------------------------------------------- */

enum {
	F_OPTION = 1 << 0,   /* only before WorldBegin (checked by the handler) */
	F_WORLD = 1 << 1,    /* only inside the world */
	F_MOTION = 1 << 2,   /* may be a sample of a motion block */
	F_PRIM = 1 << 3,     /* a primitive: its errors drop it, not the frame */
};

struct handler {
	const char *name;
	void (*fn)(struct ri *ri, const struct rib_request *r);
	unsigned flags;
};

static const struct handler handlers[] = {
	{"version", req_ignore, 0},
	{"FrameBegin", req_frame_begin, 0},
	{"FrameEnd", req_frame_end, 0},
	{"WorldBegin", req_world_begin, 0},
	{"WorldEnd", req_world_end, 0},
	{"AttributeBegin", req_attribute_begin, 0},
	{"AttributeEnd", req_attribute_end, 0},
	{"TransformBegin", req_attribute_begin, 0},
	{"TransformEnd", req_attribute_end, 0},
	{"Format", reyes_ri_req_format, 0},
	{"FrameAspectRatio", reyes_ri_req_frame_aspect, 0},
	{"ScreenWindow", reyes_ri_req_screen_window, 0},
	{"CropWindow", reyes_ri_req_crop_window, 0},
	{"Projection", reyes_ri_req_projection, 0},
	{"Clipping", reyes_ri_req_clipping, 0},
	{"Shutter", reyes_ri_req_shutter, 0},
	{"DepthOfField", reyes_ri_req_depth_of_field, 0},
	{"PixelSamples", reyes_ri_req_pixel_samples, 0},
	{"PixelVariance", req_ignore, 0},
	{"PixelFilter", reyes_ri_req_pixel_filter, 0},
	{"Exposure", reyes_ri_req_exposure, 0},
	{"Quantize", reyes_ri_req_quantize, 0},
	{"Display", reyes_ri_req_display, 0},
	{"Hider", reyes_ri_req_hider, 0},
	{"Option", reyes_ri_req_option, 0},
	{"Attribute", req_attribute, 0},
	{"Color", req_color, 0},
	{"Opacity", req_color, 0},
	{"Surface", req_surface, 0},
	{"Imager", req_imager, 0},
	{"Displacement", req_surface, 0},
	{"Atmosphere", req_volume, 0},
	{"Interior", req_volume, 0},
	{"Exterior", req_volume, 0},
	{"LightSource", req_light_source, 0},
	{"Illuminate", req_illuminate, 0},
	{"Sides", req_sides, 0},
	{"Orientation", req_orientation, 0},
	{"ReverseOrientation", req_reverse_orientation, 0},
	{"ShadingRate", req_shading_rate, 0},
	{"ShadingInterpolation", req_shading_interpolation, 0},
	{"Basis", reyes_ri_req_basis, 0},
	{"Declare", reyes_ri_req_declare, 0},
	{"TextureCoordinates", reyes_ri_req_texture_coordinates, 0},
	{"Matte", reyes_ri_req_matte, 0},
	{"Detail", reyes_ri_req_detail, 0},
	{"RelativeDetail", reyes_ri_req_relative_detail, 0},
	{"DetailRange", reyes_ri_req_detail_range, 0},
	{"GeometricApproximation", reyes_ri_req_geometric_approximation, 0},
	{"GeometricRepresentation", reyes_ri_req_geometric_representation, 0},
	{"Identity", req_xform, F_MOTION},
	{"Transform", req_xform, F_MOTION},
	{"ConcatTransform", req_xform, F_MOTION},
	{"Translate", req_xform, F_MOTION},
	{"Rotate", req_xform, F_MOTION},
	{"Scale", req_xform, F_MOTION},
	{"Skew", req_xform, F_MOTION},
	{"CoordinateSystem", req_coordinate_system, 0},
	{"CoordSysTransform", req_coord_sys_transform, 0},
	{"MotionBegin", reyes_ri_req_motion_begin, 0},
	{"MotionEnd", reyes_ri_req_motion_end, F_MOTION},
	{"ObjectBegin", reyes_ri_req_object_begin, 0},
	{"ObjectEnd", reyes_ri_req_object_end, 0},
	{"ObjectInstance", reyes_ri_req_object_instance, 0},
	{"SolidBegin", reyes_ri_req_solid_begin, 0},
	{"SolidEnd", reyes_ri_req_solid_end, 0},
	{"ReadArchive", req_read_archive, 0},
	{"MakeTexture", req_make_texture, 0},
	{"MakeShadow", req_make_shadow, 0},
	{"MakeLatLongEnvironment", req_make_latlong, 0},
	{"MakeCubeFaceEnvironment", req_make_cubeface, 0},
	{"Sphere", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Cylinder", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Cone", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Disk", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Hyperboloid", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Paraboloid", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Torus", reyes_ri_req_quadric, F_MOTION | F_PRIM},
	{"Polygon", reyes_ri_req_polygon, F_MOTION | F_PRIM},
	{"GeneralPolygon", reyes_ri_req_general_polygon, F_MOTION | F_PRIM},
	{"PointsPolygons", reyes_ri_req_points_polygons, F_MOTION | F_PRIM},
	{"PointsGeneralPolygons", reyes_ri_req_points_polygons, F_MOTION | F_PRIM},
	{"Patch", reyes_ri_req_patch, F_MOTION | F_PRIM},
	{"PatchMesh", reyes_ri_req_patch_mesh, F_MOTION | F_PRIM},
	{"SubdivisionMesh", reyes_ri_req_subdivision_mesh, F_MOTION | F_PRIM},
	{"NuPatch", reyes_ri_req_nu_patch, F_MOTION | F_PRIM},
	{"TrimCurve", reyes_ri_req_trim_curve, F_PRIM},
	{"Curves", reyes_ri_req_curves, F_MOTION | F_PRIM},
	{"Points", reyes_ri_req_points, F_MOTION | F_PRIM},
	{"Blobby", reyes_ri_req_blobby, F_PRIM},
	{"Geometry", reyes_ri_req_geometry, F_PRIM},
	{"Procedural", reyes_ri_req_procedural, F_PRIM},
};

/*
 * Requests relight does not support whose absence changes what the rest of
 * the scene means (conditional RIB would render every branch, an inline
 * archive its contents in place): errors, not warnings.
 */
static bool refused(const char *name)
{
	static const char *const names[] = {
		"ArchiveBegin", "ArchiveEnd", "Else", "ElseIf", "IfBegin", "IfEnd",
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (strcmp(names[i], name) == 0)
			return true;
	return false;
}

static bool on_request(void *user, const struct rib_request *r)
{
	struct ri *ri = user;
	forward_reader_diag_as(ri, r->known == RIB_MALFORMED);
	if (ri->stop)
		return false;
	if (r->known == RIB_MALFORMED) {
		/* its error is reported: the primitive is dropped, and a deforming
		   one goes with the sample it lacks */
		ri->dropped++;
		if (ri->motion.active)
			ri->motion.bad = true;
		return true;
	}
	if (ri->files.len)
		ri->files.data[ri->files.len - 1].last = reyes_ri_keep_loc(ri, r->loc);
	const struct handler *h = NULL;
	for (size_t i = 0; i < sizeof(handlers) / sizeof(handlers[0]) && !h; i++)
		if (handlers[i].name[0] == r->name[0] && strcmp(handlers[i].name, r->name) == 0)
			h = &handlers[i];
	if (r->known == RIB_UNSUPPORTED && refused(r->name)) {
		reyes_ri_err(ri, r->loc, "%s is not supported, and the frame would be wrong "
			     "without it", r->name);
		return !ri->stop;
	}
	if (r->known == RIB_UNSUPPORTED || (!h && r->known == RIB_KNOWN)) {
		reyes_ri_warn(ri, r->loc, "%s is not supported: ignored", r->name);
		return !ri->stop;
	}
	if (!h) {
		if (r->near)
			reyes_ri_warn(ri, r->loc, "unknown request '%s' ignored; did you mean '%s'?",
				      r->name, r->near);
		else
			reyes_ri_warn(ri, r->loc, "unknown request '%s' ignored", r->name);
		return !ri->stop;
	}
	if (ri->motion.active && !(h->flags & F_MOTION)) {
		reyes_ri_err(ri, r->loc, "%s cannot be inside the MotionBegin at %s", r->name,
			     reyes_ri_where(ri, ri->motion.loc, r->loc));
		return !ri->stop;
	}
	if ((h->flags & F_WORLD) && !ri->world) {
		reyes_ri_err(ri, r->loc, "%s outside WorldBegin/WorldEnd", r->name);
		return !ri->stop;
	}
	if (h->flags & F_PRIM) {
		ri->in_prim = true;
		ri->prim_failed = false;
		h->fn(ri, r);
		ri->in_prim = false;
		ri->dropped += ri->prim_failed;
		/* a deforming primitive goes with the sample it lacks */
		if (ri->prim_failed && ri->motion.active)
			ri->motion.bad = true;
		return !ri->stop;
	}
	h->fn(ri, r);
	return !ri->stop;
}

/* ---- entry point ------------------------------------------------------------------------ */

/* @path's last colon-separated element equals @dir? */
static bool path_ends_with(const char *path, const char *dir)
{
	const char *last = strrchr(path, ':');
	last = last ? last + 1 : path;
	return strcmp(last, dir) == 0;
}

bool reyes_ri_read(const char *path, const struct reyes_ri_opts *opts, int *nerrors)
{
	static const struct reyes_ri_opts no_opts = {0};
	if (!opts)
		opts = &no_opts;
	for (uint32_t i = 0; i < opts->nlight_edits; i++)
		if (!opts->light_edits[i].light || !opts->light_edits[i].param) {
			rib_error(opts->diag, (struct rib_loc){path, 0},
				  "light edit %u names no light or no parameter", i + 1);
			if (nerrors)
				*nerrors = 1;
			return false;
		}
	struct ri state = {
		.opts = opts,
		.diag = opts->diag ? opts->diag : stderr,
		.max_errors = opts->max_errors > 0 ? opts->max_errors : 20,
		.perm = rl_arena_create(),
		.objdef = -1,
		.edit_seen = rl_xcalloc(opts->nlight_edits + 1, sizeof(bool)),
	};
	struct ri *ri = &state;
	ri->rdiag = open_memstream(&ri->rbuf, &ri->rlen);
	const char *sp = opts->default_shader_path;
	if (!sp || !*sp)
		ri->default_shader_path = RELIGHT_SOURCE_SHADER_DIR;
	else if (path_ends_with(sp, RELIGHT_SOURCE_SHADER_DIR))
		ri->default_shader_path = rl_arena_strdup(ri->perm, sp);
	else
		ri->default_shader_path = rl_arena_printf(ri->perm, "%s:%s", sp,
							 RELIGHT_SOURCE_SHADER_DIR);
	ri->default_include_path = opts->default_include_path && *opts->default_include_path
					  ? rl_arena_strdup(ri->perm, opts->default_include_path)
					  : "";
	ri->default_texture_path = opts->default_texture_path && *opts->default_texture_path
					  ? rl_arena_strdup(ri->perm, opts->default_texture_path)
					  : ".";
	reyes_ri_options_init(ri, &ri->opt);
	attrs_init(&ri->gs.a);
	xform_init(&ri->gs.x);

	struct stat st;
	bool have_st = path && stat(path, &st) == 0;
	bool read_ok = read_file(ri, path, have_st ? &st : NULL);

	/* Blocks left open when the read stopped early: unwind without rendering. */
	while (ri->blocks.len)
		pop_block(ri, false);
	forward_reader_diag(ri);

	/* An edit of a light the scene never declares is a mistake, not a no-op
	   (unless the read stopped before it could know). */
	for (uint32_t i = 0; have_st && !ri->stop && i < opts->nlight_edits; i++) {
		const struct reyes_light_edit *e = &opts->light_edits[i];
		if (!ri->edit_seen[i])
			reyes_ri_err(ri, (struct rib_loc){path, 0},
				     "--set %s.%s: no LightSource with handle %s%s", e->light, e->param,
				     e->light, strcmp(e->light, "imager") ? "" : ", and no Imager");
	}

	int total = ri->nerrors + ri->reader_errors + ri->reader_prim_total;
	if (nerrors)
		*nerrors = total;
	if (opts->counts)
		*opts->counts = (struct reyes_ri_counts){
			.errors = total,
			.fatal = total - ri->prim_errors - ri->reader_prim_total,
			.dropped = ri->dropped,
			.warnings = ri->warnings,
			.repeats = ri->repeats,
			.frames = ri->worlds,
		};

	for (size_t i = 0; i < ri->objects.len; i++)
		rl_vec_free(ri->objects.data[i].prims);
	rl_vec_free(ri->objects);
	rl_vec_free(ri->blocks);
	rl_vec_free(ri->files);
	rl_vec_free(ri->pre_spaces);
	rl_vec_free(ri->pre_lights);
	rl_vec_free(ri->lights);
	rl_vec_free(ri->prims);
	rl_vec_free(ri->csg_nodes);
	rl_vec_free(ri->csg_open);
	rl_vec_free(ri->spaces);
	strmap_free(&ri->decls);
	strmap_free(&ri->shader_cache);
	strmap_free(&ri->joined);
	strmap_free(&ri->shader_names);
	strmap_free(&ri->names_indexed);
	strmap_free(&ri->pre_space_index);
	strmap_free(&ri->pre_light_index);
	strmap_free(&ri->outer_object_index);
	strmap_free(&ri->world_object_index);
	strmap_free(&ri->light_index);
	strmap_free(&ri->space_index);
	strmap_free(&ri->seen);
	for (size_t i = 0; i < ri->progs.len; i++)
		sl_program_destroy(ri->progs.data[i]);
	rl_vec_free(ri->progs);
	if (ri->rdiag)
		fclose(ri->rdiag);
	free(ri->rbuf);
	rl_arena_destroy(ri->world);
	rl_arena_destroy(ri->perm);
	free(ri->edit_seen);
	return read_ok && total == 0;
}

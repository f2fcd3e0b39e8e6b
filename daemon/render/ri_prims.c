/*
 * The RIB scene builder's geometry (see ri.c for the rest): type
 * declarations (Declare and inline ones, whose classes say how primitive
 * variables are interpolated), the geometric primitive requests and their
 * primitive variables, the Basis they use, motion blocks (transformation
 * and deformation samples) and retained objects (ObjectBegin, ObjectEnd,
 * ObjectInstance). Each request checks its arguments and counts, builds a
 * struct reyes_prim in the current arena and hands it to the world, to the
 * object being defined, or to the open motion block.
 */
#include "ri_impl.h"

#include "mathlib.h"
#include "sl.h"

#include <ctype.h>
#include <math.h>
#include <string.h>

enum {
	MAX_PRIMVARS = 256,           /* primitive variables of one primitive */
	MAX_DECL_ARRAY = 1 << 16,     /* array length in a declaration */
};

/* ---- declarations ---------------------------------------------------------------- */

static const char *const class_names[] = {
	[REYES_CONSTANT] = "constant", [REYES_UNIFORM] = "uniform", [REYES_VARYING] = "varying",
	[REYES_VERTEX] = "vertex", [REYES_FACEVARYING] = "facevarying",
};

static bool word_is(const char *w, size_t n, const char *s)
{
	return strlen(s) == n && memcmp(w, s, n) == 0;
}

static bool type_word(const char *w, size_t n, struct decl *d)
{
	static const struct {
		const char *name;
		int type;
	} types[] = {
		{"float", SL_TYPE_FLOAT}, {"integer", SL_TYPE_FLOAT}, {"int", SL_TYPE_FLOAT},
		{"color", SL_TYPE_COLOR}, {"point", SL_TYPE_POINT}, {"vector", SL_TYPE_VECTOR},
		{"normal", SL_TYPE_NORMAL}, {"hpoint", SL_TYPE_POINT}, {"matrix", SL_TYPE_MATRIX},
		{"string", SL_TYPE_STRING},
	};
	for (size_t i = 0; i < sizeof(types) / sizeof(types[0]); i++)
		if (word_is(w, n, types[i].name)) {
			d->type = types[i].type;
			d->hpoint = word_is(w, n, "hpoint");
			return true;
		}
	return false;
}

/*
 * decl := [class] type ['[' integer ']'] [name]
 * The name is required when @with_name (an inline declaration in a
 * parameter's token), absent otherwise (Declare). The class defaults to
 * uniform.
 */
static bool parse_decl(struct rl_arena *a, const char *s, bool with_name, struct decl *d)
{
	*d = (struct decl){.cls = REYES_UNIFORM};
	const char *w[4];
	size_t wl[4];
	int nw = 0, arr_pos = -1;
	long arr = -1;
	const char *p = s;
	while (*p) {
		if (isspace((unsigned char)*p)) {
			p++;
		} else if (*p == '[') {
			if (arr >= 0)
				return false;
			p++;
			while (isspace((unsigned char)*p))
				p++;
			if (!isdigit((unsigned char)*p))
				return false;
			arr = 0;
			while (isdigit((unsigned char)*p)) {
				arr = arr * 10 + (*p++ - '0');
				if (arr > MAX_DECL_ARRAY)
					return false;
			}
			while (isspace((unsigned char)*p))
				p++;
			if (*p++ != ']')
				return false;
			arr_pos = nw;
		} else {
			if (nw == 4)
				return false;
			w[nw] = p;
			while (*p && !isspace((unsigned char)*p) && *p != '[' && *p != ']')
				p++;
			if (*p == ']')
				return false;
			wl[nw] = (size_t)(p - w[nw]);
			nw++;
		}
	}
	int i = 0;
	for (int c = 0; c < 5 && i < nw; c++)
		if (word_is(w[i], wl[i], class_names[c])) {
			d->cls = (enum reyes_class)c;
			i++;
			break;
		}
	if (i >= nw || !type_word(w[i], wl[i], d))
		return false;
	i++;
	if (arr >= 0) {
		if (arr_pos != i || arr == 0)
			return false;
		d->arraylen = (uint32_t)arr;
	}
	if (with_name) {
		if (i != nw - 1)
			return false;
		d->name = rl_arena_strndup(a, w[i], wl[i]);
	} else if (i != nw) {
		return false;
	}
	return true;
}

/* Does a parameter's token hold an inline declaration (more than one word)? */
static bool is_inline_decl(const char *tok)
{
	const char *p = tok;
	while (isspace((unsigned char)*p))
		p++;
	while (*p && !isspace((unsigned char)*p) && *p != '[')
		p++;
	while (isspace((unsigned char)*p))
		p++;
	return *p != '\0';
}

/*
 * A parameter's name and, if it has one, its inline declaration. Plain
 * tokens ("Kd") give *has_decl = false. False (reported) for a malformed
 * inline declaration.
 */
bool reyes_ri_param_token(struct ri *ri, const struct rib_param *par, const char *req,
			  struct decl *d, bool *has_decl, const char **name)
{
	if (!is_inline_decl(par->token)) {
		const char *p = par->token;
		while (isspace((unsigned char)*p))
			p++;
		size_t n = 0;
		while (p[n] && !isspace((unsigned char)p[n]))
			n++;
		*has_decl = false;
		*name = rl_arena_strndup(ri->world ? ri->world : ri->perm, p, n);
		if (n == 0) {
			reyes_ri_err(ri, par->loc, "%s: empty parameter name", req);
			return false;
		}
		return true;
	}
	if (!parse_decl(ri->world ? ri->world : ri->perm, par->token, true, d)) {
		reyes_ri_err(ri, par->loc,
			     "%s: bad inline declaration '%s' (expected [class] type [n] name)",
			     req, par->token);
		return false;
	}
	*has_decl = true;
	*name = d->name;
	return true;
}

void reyes_ri_req_declare(struct ri *ri, const struct rib_request *r)
{
	const char *name, *decl;
	if (!reyes_ri_str_arg(ri, r, 0, &name) || !reyes_ri_str_arg(ri, r, 1, &decl))
		return;
	if (!*name || is_inline_decl(name))
		FAIL(ri, r->loc, "Declare: bad name '%s'", name);
	struct decl *d = rl_arena_alloc(ri->perm, sizeof(*d));
	if (!parse_decl(ri->perm, decl, false, d))
		FAIL(ri, r->loc,
			   "Declare: bad declaration '%s' for '%s' (expected [class] type [n])",
			   decl, name);
	strmap_put(&ri->decls, rl_arena_strdup(ri->perm, name), (uintptr_t)d);
}

/* ---- primitives ---------------------------------------------------------------------- */

/* Non-negative integers of an array, each below @limit. */
static uint32_t *uint_values(struct ri *ri, const struct rib_value *v, const char *req,
			     const char *what, uint64_t limit)
{
	uint32_t *out = rl_arena_alloc(ri->world ? ri->world : ri->perm,
				       sizeof(uint32_t) * (v->n ? v->n : 1));
	for (uint32_t i = 0; i < v->n; i++) {
		double d = v->nums[i];
		if (!(d >= 0 && d < (double)limit && d == floor(d))) {
			reyes_ri_err(ri, v->loc,
				     "%s: %s %u is %g (expected an integer from 0 to %llu)", req,
				     what, i, d, (unsigned long long)(limit - 1));
			return NULL;
		}
		out[i] = (uint32_t)d;
	}
	return out;
}

/* Standard primitive variables (RISpec), typed when no declaration says otherwise. */
static const struct {
	const char *name;
	struct decl d;
} std_vars[] = {
	{"P", {.cls = REYES_VERTEX, .type = SL_TYPE_POINT}},
	{"Pw", {.cls = REYES_VERTEX, .type = SL_TYPE_POINT, .hpoint = true}},
	{"Pz", {.cls = REYES_VERTEX, .type = SL_TYPE_FLOAT}},
	{"N", {.cls = REYES_VARYING, .type = SL_TYPE_NORMAL}},
	{"Cs", {.cls = REYES_VARYING, .type = SL_TYPE_COLOR}},
	{"Os", {.cls = REYES_VARYING, .type = SL_TYPE_COLOR}},
	{"s", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT}},
	{"t", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT}},
	{"st", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT, .arraylen = 2}},
	/* Curves and Points */
	{"width", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT}},
	{"constantwidth", {.cls = REYES_CONSTANT, .type = SL_TYPE_FLOAT}},
};

/*
 * The type of a primitive variable: inline declaration, Declare, or
 * standard. False when it has none (*unknown set, not reported: the caller
 * ignores it with a warning) or its token is malformed (reported).
 */
static bool var_decl(struct ri *ri, const struct rib_request *r, const struct rib_param *p,
		     struct decl *d, const char **name, bool *unknown)
{
	bool has;
	*unknown = false;
	if (!reyes_ri_param_token(ri, p, r->name, d, &has, name))
		return false;
	if (has)
		return true;
	uintptr_t dv;
	if (strmap_get(&ri->decls, *name, &dv)) {
		*d = *(const struct decl *)dv;
		return true;
	}
	for (size_t i = 0; i < sizeof(std_vars) / sizeof(std_vars[0]); i++)
		if (strcmp(*name, std_vars[i].name) == 0) {
			*d = std_vars[i].d;
			return true;
		}
	*unknown = true;
	return false;
}

/* Floats per item of a declared type. */
static uint32_t decl_ncomp(const struct decl *d)
{
	uint32_t c = d->hpoint ? 4 : (uint32_t)sl_type_ncomp(d->type);
	return c * (d->arraylen ? d->arraylen : 1);
}

/* Is @name a position: "P", "Pw", or (a height field's) "Pz"? */
static bool is_position(const char *name)
{
	return strcmp(name, "P") == 0 || strcmp(name, "Pw") == 0 || strcmp(name, "Pz") == 0;
}

/*
 * The number of points "P" (or "Pw", or with @height_ok "Pz") gives; false
 * (reported) when missing or uneven.
 */
static bool point_count(struct ri *ri, const struct rib_request *r, bool height_ok, uint32_t *np)
{
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		const char *name;
		bool unknown;
		if (!var_decl(ri, r, p, &d, &name, &unknown)) {
			if (unknown)
				continue;       /* prim_vars warns */
			return false;
		}
		if (!is_position(name))
			continue;
		bool pz = strcmp(name, "Pz") == 0;
		if (pz && !height_ok) {
			reyes_ri_err(ri, p->loc, "%s does not take \"Pz\" (only Patch and PatchMesh "
				     "are height fields)", r->name);
			return false;
		}
		uint32_t c = decl_ncomp(&d);
		bool want_type = pz ? d.type == SL_TYPE_FLOAT && !d.hpoint
				    : d.type == SL_TYPE_POINT && (strcmp(name, "Pw") == 0) == d.hpoint;
		if (d.cls != REYES_VERTEX || !want_type || d.arraylen) {
			reyes_ri_err(ri, p->loc, "%s: \"%s\" must be a vertex %s", r->name, name,
				     pz ? "float" : strcmp(name, "Pw") == 0 ? "hpoint" : "point");
			return false;
		}
		if (!reyes_ri_is_numbers(&p->value) || p->value.n % c) {
			reyes_ri_err(ri, p->loc, "%s: \"%s\" has %u values, not a multiple of %u",
				     r->name, name, p->value.n, c);
			return false;
		}
		*np = p->value.n / c;
		return true;
	}
	reyes_ri_err(ri, r->loc, "%s needs \"P\"", r->name);
	return false;
}

/*
 * The parameter of shader @sh that a primitive variable @name of @type
 * (@alen: its array length, 0 for none) would bind to but does not fit, or
 * NULL. A parameter takes a variable of as many floats (a colour takes a
 * point), and no string.
 */
static const struct sl_param *misfit(const struct reyes_shader *sh, const char *name, int type,
				     uint32_t alen)
{
	if (!sh || !sh->prog)
		return NULL;
	int k = sl_program_find_param(sh->prog, name);
	if (k < 0)
		return NULL;
	const struct sl_param *sp = &sh->prog->params[k];
	uint32_t tlen = sp->type.arraylen > 0 ? (uint32_t)sp->type.arraylen : 0;
	uint32_t want = (uint32_t)sl_type_ncomp(sp->type.base) * (tlen ? tlen : 1);
	uint32_t have = (uint32_t)sl_type_ncomp(type) * (alen ? alen : 1);
	return sp->type.base != SL_TYPE_STRING && want == have ? NULL : sp;
}

/* "TYPE" or "TYPE[N]", in ri->perm. */
static const char *type_name(struct ri *ri, int type, uint32_t alen)
{
	return alen ? rl_arena_printf(ri->perm, "%s[%u]", sl_basetype_name(type), alen)
		    : sl_basetype_name(type);
}

/*
 * Does a primitive variable fit the parameter of its name of the current
 * surface and displacement shaders, if they have one? One that does not is
 * ignored with a warning here, where it is written, rather than refused at
 * each grid. Inside an object definition only the shaders the definition
 * sets count: the others are the instances', checked at ObjectInstance.
 */
static bool binds(struct ri *ri, const struct rib_request *r, const struct rib_param *par,
		  const char *name, int type, uint32_t alen)
{
	const struct attrstate *a = &ri->gs.a;
	bool def = ri->objdef >= 0;
	const struct reyes_shader *shs[2] = {
		!def || (a->objset & OBJ_SURFACE) ? a->surface : NULL,
		!def || (a->objset & OBJ_DISPLACEMENT) ? a->displacement : NULL,
	};
	for (int i = 0; i < 2; i++) {
		const struct sl_param *sp = misfit(shs[i], name, type, alen);
		if (!sp)
			continue;
		reyes_ri_warn(ri, par->loc, "%s: primitive variable '%s' (%s) does not fit "
			      "parameter '%s' of shader '%s' (%s): ignored", r->name, name,
			      type_name(ri, type, alen), name, shs[i]->name,
			      type_name(ri, sp->type.base,
					sp->type.arraylen > 0 ? (uint32_t)sp->type.arraylen : 0));
		return false;
	}
	return true;
}

/*
 * The primitive variables of an object's primitive @p against the shaders
 * the instance gives it (those its definition did not set): one that does
 * not fit is ignored, with a warning at the ObjectInstance @r.
 */
static void instance_binds(struct ri *ri, const struct rib_request *r, const char *handle,
			   const struct obj_prim *op)
{
	unsigned set = op->a ? op->a->objset : 0;
	const struct reyes_shader *shs[2] = {
		set & OBJ_SURFACE ? NULL : ri->gs.a.surface,
		set & OBJ_DISPLACEMENT ? NULL : ri->gs.a.displacement,
	};
	for (uint32_t v = 0; v < op->p->nvars; v++) {
		const struct reyes_primvar *pv = &op->p->vars[v];
		for (int i = 0; i < 2; i++) {
			const struct sl_param *sp = misfit(shs[i], pv->name, pv->type, pv->arraylen);
			if (!sp)
				continue;
			reyes_ri_warn(ri, r->loc, "ObjectInstance %s: primitive variable '%s' (%s) "
				      "does not fit parameter '%s' of shader '%s' (%s): ignored",
				      handle, pv->name, type_name(ri, pv->type, pv->arraylen),
				      pv->name, shs[i]->name,
				      type_name(ri, sp->type.base,
						sp->type.arraylen > 0 ? (uint32_t)sp->type.arraylen
								      : 0));
			break;
		}
	}
}

/*
 * The primitive variables of @r's parameter list into @p, each checked
 * against the count of its class: sizes[class] items.
 */
static bool prim_vars(struct ri *ri, const struct rib_request *r, const uint32_t sizes[5],
		      bool points, struct reyes_prim *p)
{
	struct rl_arena *a = reyes_ri_cur_arena(ri);
	if (r->nparams > MAX_PRIMVARS) {
		reyes_ri_err(ri, r->loc, "%s: too many primitive variables (limit %d)", r->name,
			     MAX_PRIMVARS);
		return false;
	}
	struct reyes_primvar *vars = rl_arena_alloc(a, sizeof(*vars) * (r->nparams + 2));
	uint32_t n = 0;
	bool have_P = false;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *par = &r->params[i];
		struct decl d;
		const char *name;
		bool unknown;
		if (!var_decl(ri, r, par, &d, &name, &unknown)) {
			if (!unknown)
				return false;
			reyes_ri_warn(ri, par->loc, "%s: primitive variable '%s' has no type "
				      "(declare it with Declare or an inline type): ignored", r->name,
				      name);
			continue;
		}
		if (d.type == SL_TYPE_STRING) {
			reyes_ri_warn(ri, par->loc, "%s: string primitive variable '%s' ignored",
				      r->name, name);
			continue;
		}
		bool is_P = is_position(name);
		if (is_P && !points) {
			reyes_ri_warn(ri, par->loc, "%s does not take \"%s\": ignored", r->name,
				      name);
			continue;
		}
		uint32_t per = decl_ncomp(&d);
		uint64_t want = (uint64_t)sizes[d.cls] * per;
		if (!reyes_ri_is_numbers(&par->value) || par->value.n != want) {
			reyes_ri_err(ri, par->loc, "%s: primitive variable \"%s\" (%s %s%s) needs "
				     "%llu values, got %u%s", r->name, name, class_names[d.cls],
				     d.hpoint ? "hpoint" : sl_basetype_name(d.type),
				     d.arraylen ? rl_arena_printf(ri->perm, "[%u]", d.arraylen)
						: "",
				     (unsigned long long)want, par->value.n,
				     reyes_ri_is_numbers(&par->value) ? "" : " strings");
			return false;
		}
		float *f = rl_arena_alloc(a, sizeof(float) * (want ? want : 1));
		if (!reyes_ri_value_floats(ri, &par->value, par->loc, name, f))
			return false;
		uint32_t count = sizes[d.cls];
		if (d.hpoint) {
			/* To points: divide by w. */
			uint32_t items = count * (d.arraylen ? d.arraylen : 1);
			for (uint32_t k = 0; k < items; k++) {
				float w = f[4 * k + 3];
				if (w == 0) {
					reyes_ri_err(ri, par->loc, "%s: \"%s\" point %u has w = 0",
						     r->name, name, k);
					return false;
				}
				for (int c = 0; c < 3; c++)
					f[3 * k + c] = f[4 * k + c] / w;
			}
			if (strcmp(name, "Pw") == 0)
				name = "P";
		}
		if (is_P && strcmp(name, "Pz") == 0) {
			/* A height field: "P" with z from "Pz"; x and y are the surface's u
			   and v (RISpec), which the geometry puts in when it dices. */
			float *f3 = rl_arena_alloc(a, sizeof(float) * 3 * (count ? count : 1));
			for (uint32_t k = 0; k < count; k++)
				f3[3 * k + 2] = f[k];
			f = f3;
			name = "P";
			d.type = SL_TYPE_POINT;
			p->heightfield = true;
		}
		/* The standard variables keep their standard types. */
		const char *std_type = NULL;
		if (strcmp(name, "N") == 0 && !(sl_type_is_triple(d.type) && !d.arraylen))
			std_type = "a normal";
		else if ((strcmp(name, "Cs") == 0 || strcmp(name, "Os") == 0) &&
			 !(d.type == SL_TYPE_COLOR && !d.arraylen))
			std_type = "a color";
		else if ((strcmp(name, "s") == 0 || strcmp(name, "t") == 0) &&
			 !(d.type == SL_TYPE_FLOAT && !d.arraylen))
			std_type = "a float";
		else if (strcmp(name, "st") == 0 && !(d.type == SL_TYPE_FLOAT && d.arraylen == 2))
			std_type = "a float[2]";
		if (std_type) {
			reyes_ri_err(ri, par->loc, "%s: \"%s\" must be %s", r->name, name,
				     std_type);
			return false;
		}
		int type = strcmp(name, "N") == 0 ? SL_TYPE_NORMAL : d.type;
		const char *names[2] = {name, NULL};
		const float *vals[2] = {f, NULL};
		uint32_t alen = d.arraylen;
		if (strcmp(name, "st") == 0) {
			/* Split into "s" and "t", which the renderer knows. */
			float *s = rl_arena_alloc(a, sizeof(float) * (count ? count : 1));
			float *t = rl_arena_alloc(a, sizeof(float) * (count ? count : 1));
			for (uint32_t k = 0; k < count; k++) {
				s[k] = f[2 * k];
				t[k] = f[2 * k + 1];
			}
			names[0] = "s";
			names[1] = "t";
			vals[0] = s;
			vals[1] = t;
			alen = 0;
		}
		if (!binds(ri, r, par, name, type, alen))
			continue;
		for (int j = 0; j < 2 && names[j]; j++) {
			for (uint32_t k = 0; k < n; k++)
				if (strcmp(vars[k].name, names[j]) == 0) {
					reyes_ri_err(ri, par->loc,
						     "%s: primitive variable \"%s\" is given twice",
						     r->name, names[j]);
					return false;
				}
			vars[n++] = (struct reyes_primvar){
				.name = names[j],
				.cls = d.cls,
				.type = type,
				.arraylen = alen,
				.count = count,
				.values = vals[j],
			};
		}
		have_P |= is_P;
	}
	if (points && !have_P) {
		reyes_ri_err(ri, r->loc, "%s needs \"P\"", r->name);
		return false;
	}
	p->vars = vars;
	p->nvars = n;
	return true;
}

static struct reyes_prim *new_prim(struct ri *ri, enum reyes_prim_kind kind)
{
	struct reyes_prim *p = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(*p));
	p->kind = kind;
	return p;
}

/* Can a primitive go here? Inside the world, or into an object definition. */
static bool geometry_ok(struct ri *ri, const struct rib_request *r)
{
	if (ri->world || ri->objdef >= 0)
		return true;
	reyes_ri_err(ri, r->loc, "%s outside WorldBegin/WorldEnd", r->name);
	return false;
}

/* Adds a finished primitive to the world or to the object being defined. */
static void add_prim(struct ri *ri, struct reyes_prim *p, const struct xform *x)
{
	if (ri->objdef >= 0) {
		struct object *o = &ri->objects.data[ri->objdef];
		struct obj_prim op = {.p = p};
		if (ri->gs.a.objset) {
			/* primitives under the same attributes share one record */
			const struct obj_prim *last = o->prims.len ? &o->prims.data[o->prims.len - 1]
								   : NULL;
			if (last && last->a && memcmp(last->a, &ri->gs.a, sizeof(ri->gs.a)) == 0) {
				op.a = last->a;
			} else {
				struct attrstate *a = rl_arena_alloc(reyes_ri_cur_arena(ri),
								     sizeof(*a));
				*a = ri->gs.a;
				op.a = a;
			}
		}
		for (int k = 0; k < 2; k++)
			sl_m44_mul(op.rel[k], x->m[k], ri->objdef_inv[k]);
		op.identity = reyes_ri_is_identity(op.rel[0]) && reyes_ri_is_identity(op.rel[1]);
		rl_vec_push(o->prims, op);
		return;
	}
	struct reyes_prim q = *p;
	q.attrs = x == &ri->gs.x ? reyes_ri_cur_bundle(ri) : reyes_ri_make_bundle(ri, x);
	if (q.attrs->dissolve && !(q.attrs->lod_hi > q.attrs->lod_lo))
		return;         /* a representation its DetailRange leaves out */
	q.id = (uint32_t)ri->prims.len;
	q.csg_leaf = reyes_ri_csg_leaf(ri);
	rl_vec_push(ri->prims, q);
}

static void motion_prim(struct ri *ri, const struct rib_request *r, struct reyes_prim *p);

static void emit_prim(struct ri *ri, const struct rib_request *r, struct reyes_prim *p)
{
	if (ri->motion.active)
		motion_prim(ri, r, p);
	else
		add_prim(ri, p, &ri->gs.x);
}

void reyes_ri_req_quadric(struct ri *ri, const struct rib_request *r)
{
	static const struct {
		const char *name;
		enum reyes_prim_kind kind;
		uint32_t nq;
	} quadrics[] = {
		{"Sphere", REYES_SPHERE, 4}, {"Cylinder", REYES_CYLINDER, 4},
		{"Cone", REYES_CONE, 3}, {"Disk", REYES_DISK, 3},
		{"Hyperboloid", REYES_HYPERBOLOID, 7}, {"Paraboloid", REYES_PARABOLOID, 4},
		{"Torus", REYES_TORUS, 5},
	};
	size_t k = 0;
	while (strcmp(quadrics[k].name, r->name) != 0)
		k++;
	if (!geometry_ok(ri, r))
		return;
	struct reyes_prim *p = new_prim(ri, quadrics[k].kind);
	if (!reyes_ri_float_args(ri, r, 0, quadrics[k].nq, p->q))
		return;
	static const uint32_t sizes[5] = {1, 1, 4, 4, 4};
	if (prim_vars(ri, r, sizes, false, p))
		emit_prim(ri, r, p);
}

/* 0, 1, ... n-1. */
static uint32_t *iota(struct ri *ri, uint32_t n)
{
	uint32_t *v = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(uint32_t) * (n ? n : 1));
	for (uint32_t i = 0; i < n; i++)
		v[i] = i;
	return v;
}

/* Every count at least @min; their sum (64-bit) into *sum. */
static bool check_counts(struct ri *ri, const struct rib_request *r, const struct rib_value *v,
			 const uint32_t *c, uint32_t min, const char *what, uint64_t *sum)
{
	*sum = 0;
	for (uint32_t i = 0; i < v->n; i++) {
		if (c[i] < min) {
			reyes_ri_err(ri, v->loc, "%s: %s %u is %u (at least %u)", r->name, what, i,
				     c[i], min);
			return false;
		}
		*sum += c[i];
	}
	return true;
}

static bool array_arg(struct ri *ri, const struct rib_request *r, uint32_t i)
{
	if (i < r->nargs && reyes_ri_is_numbers(&r->args[i]))
		return true;
	reyes_ri_err(ri, r->loc, "%s: argument %u should be an array of integers", r->name, i + 1);
	return false;
}

void reyes_ri_req_polygon(struct ri *ri, const struct rib_request *r)
{
	if (!geometry_ok(ri, r))
		return;
	uint32_t np;
	if (!point_count(ri, r, false, &np))
		return;
	if (np < 3)
		FAIL(ri, r->loc, "Polygon has %u points (at least 3)", np);
	struct reyes_prim *p = new_prim(ri, REYES_POLYGONS);
	uint32_t *one = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(uint32_t) * 2);
	one[0] = 1;
	one[1] = np;
	p->nfaces = 1;
	p->nloops = one;
	p->nverts = one + 1;
	p->verts = iota(ri, np);
	p->npoints = np;
	uint32_t sizes[5] = {1, 1, np, np, np};
	if (prim_vars(ri, r, sizes, true, p))
		emit_prim(ri, r, p);
}

void reyes_ri_req_general_polygon(struct ri *ri, const struct rib_request *r)
{
	if (!geometry_ok(ri, r) || !array_arg(ri, r, 0))
		return;
	const struct rib_value *nv = &r->args[0];
	uint32_t *nverts = uint_values(ri, nv, r->name, "nvertices", UINT32_MAX);
	uint64_t sum;
	if (!nverts || !check_counts(ri, r, nv, nverts, 3, "loop", &sum))
		return;
	if (nv->n == 0)
		FAIL(ri, r->loc, "GeneralPolygon has no loops");
	uint32_t np;
	if (!point_count(ri, r, false, &np))
		return;
	if (sum != np)
		FAIL(ri, r->loc, "GeneralPolygon: the loops have %llu vertices, \"P\" has %u",
			   (unsigned long long)sum, np);
	struct reyes_prim *p = new_prim(ri, REYES_POLYGONS);
	uint32_t *nl = rl_arena_alloc(reyes_ri_cur_arena(ri), sizeof(uint32_t));
	nl[0] = nv->n;
	p->nfaces = 1;
	p->nloops = nl;
	p->nverts = nverts;
	p->verts = iota(ri, np);
	p->npoints = np;
	uint32_t sizes[5] = {1, 1, np, np, np};
	if (prim_vars(ri, r, sizes, true, p))
		emit_prim(ri, r, p);
}

/* PointsPolygons and PointsGeneralPolygons. */
void reyes_ri_req_points_polygons(struct ri *ri, const struct rib_request *r)
{
	bool general = strcmp(r->name, "PointsGeneralPolygons") == 0;
	uint32_t a = general ? 1 : 0;
	if (!geometry_ok(ri, r) || !array_arg(ri, r, 0) || !array_arg(ri, r, 1) ||
	    (general && !array_arg(ri, r, 2)))
		return;
	const struct rib_value *vnl = general ? &r->args[0] : NULL;
	const struct rib_value *vnv = &r->args[a], *vv = &r->args[a + 1];
	uint32_t *nloops = NULL, *nverts, *verts;
	uint64_t nloops_sum, nverts_sum;
	uint32_t nfaces;
	if (general) {
		nloops = uint_values(ri, vnl, r->name, "nloops", UINT32_MAX);
		if (!nloops || !check_counts(ri, r, vnl, nloops, 1, "polygon", &nloops_sum))
			return;
		if (nloops_sum != vnv->n)
			FAIL(ri, vnv->loc, "%s: the polygons have %llu loops, nvertices has %u",
				   r->name, (unsigned long long)nloops_sum, vnv->n);
		nfaces = vnl->n;
	} else {
		nfaces = vnv->n;
	}
	nverts = uint_values(ri, vnv, r->name, "nvertices", UINT32_MAX);
	if (!nverts || !check_counts(ri, r, vnv, nverts, 3, general ? "loop" : "polygon",
				     &nverts_sum))
		return;
	if (nverts_sum != vv->n)
		FAIL(ri, vv->loc, "%s: the %s have %llu vertices, the vertex array has %u",
			   r->name, general ? "loops" : "polygons",
			   (unsigned long long)nverts_sum, vv->n);
	uint32_t np;
	if (!point_count(ri, r, false, &np))
		return;
	verts = uint_values(ri, vv, r->name, "vertex", UINT32_MAX);
	if (!verts)
		return;
	for (uint32_t i = 0; i < vv->n; i++)
		if (verts[i] >= np)
			FAIL(ri, vv->loc,
				   "%s: vertex index %u (element %u) is out of range (%u points)",
				   r->name, verts[i], i, np);
	if (!general) {
		nloops = rl_arena_alloc(reyes_ri_cur_arena(ri),
					sizeof(uint32_t) * (nfaces ? nfaces : 1));
		for (uint32_t i = 0; i < nfaces; i++)
			nloops[i] = 1;
	}
	struct reyes_prim *p = new_prim(ri, REYES_POLYGONS);
	p->nfaces = nfaces;
	p->nloops = nloops;
	p->nverts = nverts;
	p->verts = verts;
	p->npoints = np;
	uint32_t sizes[5] = {1, nfaces, np, np, (uint32_t)nverts_sum};
	if (prim_vars(ri, r, sizes, true, p) && nfaces)
		emit_prim(ri, r, p);
}

static bool basis_arg(struct ri *ri, const struct rib_request *r, uint32_t i, float m[16])
{
	static const struct {
		const char *name;
		float m[16];
	} bases[] = {
		{"bezier", {-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0}},
		{"b-spline", {-1.f / 6, 3.f / 6, -3.f / 6, 1.f / 6, 3.f / 6, -6.f / 6, 3.f / 6, 0,
			      -3.f / 6, 0, 3.f / 6, 0, 1.f / 6, 4.f / 6, 1.f / 6, 0}},
		{"catmull-rom", {-.5f, 1.5f, -1.5f, .5f, 1, -2.5f, 2, -.5f, -.5f, 0, .5f, 0, 0, 1,
				 0, 0}},
		{"hermite", {2, 1, -2, 1, -3, -2, 3, -1, 0, 1, 0, 0, 1, 0, 0, 0}},
		{"power", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}},
	};
	if (i >= r->nargs)
		return reyes_ri_err(ri, r->loc, "Basis: missing argument %u", i + 1), false;
	const struct rib_value *v = &r->args[i];
	if (v->type == RIB_STRING || v->type == RIB_STRINGS) {
		const char *name = v->n == 1 ? v->strs[0] : "";
		if (strcmp(name, "bspline") == 0)
			name = "b-spline";
		for (size_t k = 0; k < sizeof(bases) / sizeof(bases[0]); k++)
			if (strcmp(name, bases[k].name) == 0) {
				memcpy(m, bases[k].m, sizeof(bases[k].m));
				return true;
			}
		reyes_ri_err(ri, v->loc,
			     "unknown basis '%s' (bezier, b-spline, catmull-rom, hermite, power or "
			     "16 numbers)", name);
		return false;
	}
	if (v->n != 16)
		return reyes_ri_err(ri, v->loc, "Basis: a basis matrix has 16 numbers, got %u",
				    v->n), false;
	return reyes_ri_value_floats(ri, v, v->loc, "Basis", m);
}

void reyes_ri_req_basis(struct ri *ri, const struct rib_request *r)
{
	float ub[16], vb[16];
	double us, vs;
	if (!basis_arg(ri, r, 0, ub) || !reyes_ri_num_arg(ri, r, 1, &us) ||
	    !basis_arg(ri, r, 2, vb) || !reyes_ri_num_arg(ri, r, 3, &vs))
		return;
	if (!(us >= 1 && us <= 16 && vs >= 1 && vs <= 16))
		FAIL(ri, r->loc, "Basis: steps %g %g out of range (1 to 16)", us, vs);
	memcpy(ri->gs.a.ubasis, ub, sizeof(ub));
	memcpy(ri->gs.a.vbasis, vb, sizeof(vb));
	ri->gs.a.ustep = (uint32_t)us;
	ri->gs.a.vstep = (uint32_t)vs;
}

static void set_bases(struct ri *ri, struct reyes_prim *p)
{
	const struct attrstate *a = &ri->gs.a;
	memcpy(p->ubasis, a->ubasis, sizeof(p->ubasis));
	memcpy(p->vbasis, a->vbasis, sizeof(p->vbasis));
	p->ustep = a->ustep;
	p->vstep = a->vstep;
}

void reyes_ri_req_patch(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	if (!geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &type))
		return;
	bool bicubic = strcmp(type, "bicubic") == 0;
	if (!bicubic && strcmp(type, "bilinear") != 0)
		FAIL(ri, r->loc, "Patch type must be \"bilinear\" or \"bicubic\", got '%s'",
			   type);
	uint32_t np, want = bicubic ? 16 : 4;
	if (!point_count(ri, r, true, &np))
		return;
	if (np != want)
		FAIL(ri, r->loc, "a %s Patch has %u points, got %u", type, want, np);
	struct reyes_prim *p = new_prim(ri, REYES_PATCHES);
	p->bicubic = bicubic;
	p->nu = p->nv = bicubic ? 4 : 2;
	p->npoints = np;
	set_bases(ri, p);
	uint32_t sizes[5] = {1, 1, 4, np, 4};
	if (prim_vars(ri, r, sizes, true, p))
		emit_prim(ri, r, p);
}

/* Patches along one direction of a mesh of @n points; 0 when @n does not fit. */
static uint32_t mesh_patches(bool bicubic, bool periodic, uint32_t n, uint32_t step)
{
	if (!bicubic)
		return n < 2 ? 0 : periodic ? n : n - 1;
	if (periodic)
		return n >= 4 && n % step == 0 ? n / step : 0;
	return n >= 4 && (n - 4) % step == 0 ? (n - 4) / step + 1 : 0;
}

/*
 * A PatchMesh wrap mode: "periodic" (*periodic true) or "nonperiodic".
 * "nowrap", a name some exporters write for the latter, is taken as it
 * with a warning. False (reported) for anything else.
 */
static bool wrap_mode(struct ri *ri, const struct rib_request *r, const char *w, bool *periodic)
{
	*periodic = strcmp(w, "periodic") == 0;
	if (*periodic || strcmp(w, "nonperiodic") == 0)
		return true;
	if (strcmp(w, "nowrap") == 0) {
		reyes_ri_warn(ri, r->loc, "PatchMesh wrap mode \"nowrap\" taken as \"nonperiodic\"");
		return true;
	}
	reyes_ri_err(ri, r->loc,
		     "PatchMesh wrap modes must be \"periodic\" or \"nonperiodic\", got '%s'", w);
	return false;
}

void reyes_ri_req_patch_mesh(struct ri *ri, const struct rib_request *r)
{
	const char *type, *uwrap, *vwrap;
	double nu, nv;
	if (!geometry_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &type) ||
	    !reyes_ri_num_arg(ri, r, 1, &nu) || !reyes_ri_str_arg(ri, r, 2, &uwrap) ||
	    !reyes_ri_num_arg(ri, r, 3, &nv) || !reyes_ri_str_arg(ri, r, 4, &vwrap))
		return;
	bool bicubic = strcmp(type, "bicubic") == 0;
	if (!bicubic && strcmp(type, "bilinear") != 0)
		FAIL(ri, r->loc,
			   "PatchMesh type must be \"bilinear\" or \"bicubic\", got '%s'", type);
	bool up, vp;
	if (!wrap_mode(ri, r, uwrap, &up) || !wrap_mode(ri, r, vwrap, &vp))
		return;
	if (!(nu >= 1 && nu <= UINT32_MAX && nv >= 1 && nv <= UINT32_MAX))
		FAIL(ri, r->loc, "PatchMesh: bad size %g x %g", nu, nv);
	uint32_t ustep = ri->gs.a.ustep, vstep = ri->gs.a.vstep;
	uint32_t nup = mesh_patches(bicubic, up, (uint32_t)nu, ustep);
	uint32_t nvp = mesh_patches(bicubic, vp, (uint32_t)nv, vstep);
	if (!nup || !nvp) {
		if (bicubic)
			FAIL(ri, r->loc,
				   "PatchMesh: %g x %g points do not make whole bicubic patches with "
				   "steps %u and %u (%s, %s)", nu, nv, ustep, vstep, uwrap, vwrap);
		FAIL(ri, r->loc, "PatchMesh: %g x %g points are too few", nu, nv);
	}
	uint32_t np;
	if (!point_count(ri, r, true, &np))
		return;
	if ((uint64_t)nu * (uint64_t)nv != np)
		FAIL(ri, r->loc, "PatchMesh: %g x %g points, but \"P\" has %u", nu, nv, np);
	struct reyes_prim *p = new_prim(ri, REYES_PATCHES);
	p->bicubic = bicubic;
	p->nu = (uint32_t)nu;
	p->nv = (uint32_t)nv;
	p->uperiodic = up;
	p->vperiodic = vp;
	p->npoints = np;
	set_bases(ri, p);
	uint64_t npatch = (uint64_t)nup * nvp;
	uint64_t nuv = up ? nup : nup + 1, nvv = vp ? nvp : nvp + 1;
	if (npatch * 4 > UINT32_MAX || nuv * nvv > UINT32_MAX)
		FAIL(ri, r->loc, "PatchMesh is too large");
	uint32_t sizes[5] = {1, (uint32_t)npatch, (uint32_t)(nuv * nvv), np,
			     (uint32_t)(npatch * 4)};
	if (prim_vars(ri, r, sizes, true, p))
		emit_prim(ri, r, p);
}

/* ---- motion ---------------------------------------------------------------------------- */

void reyes_ri_req_motion_begin(struct ri *ri, const struct rib_request *r)
{
	if (!reyes_ri_depth_ok(ri, r))
		return;
	struct motion *m = &ri->motion;
	*m = (struct motion){.active = true, .loc = reyes_ri_keep_loc(ri, r->loc)};
	reyes_ri_push_block(ri, r, BLK_MOTION);
	if (r->nargs < 1 || !reyes_ri_is_numbers(&r->args[0]) || r->args[0].n == 0) {
		m->bad = true;
		FAIL(ri, r->loc, "MotionBegin needs an array of times");
	}
	const struct rib_value *t = &r->args[0];
	if (t->n > 2) {
		m->bad = true;
		FAIL(ri, r->loc, "only 2 motion samples are supported (MotionBegin has %u)",
			   t->n);
	}
	if (!reyes_ri_value_floats(ri, t, r->loc, "MotionBegin", m->times)) {
		m->bad = true;
		return;
	}
	m->ntimes = t->n;
	if (m->ntimes == 2 && !(m->times[1] > m->times[0])) {
		m->bad = true;
		FAIL(ri, r->loc, "MotionBegin: the times %g %g must increase", m->times[0],
			   m->times[1]);
	}
	const float *s = ri->opt.o.shutter;
	if (m->ntimes == 2 && s[1] > s[0] && (m->times[0] != s[0] || m->times[1] != s[1]))
		reyes_ri_warn(ri, r->loc,
			      "MotionBegin times %g %g differ from the shutter %g %g: they are "
			      "used as the shutter's open and close", m->times[0], m->times[1],
			      s[0], s[1]);
}

void reyes_ri_req_motion_end(struct ri *ri, const struct rib_request *r)
{
	reyes_ri_close_block(ri, r, BLK_MOTION);
}

/* Is request @r the next sample of the open motion block? */
static bool motion_sample(struct ri *ri, const struct rib_request *r, enum motion_kind kind)
{
	struct motion *m = &ri->motion;
	if (m->bad)
		return false;
	if (m->nsamples && strcmp(m->request, r->name) != 0) {
		reyes_ri_err(ri, r->loc,
			     "%s does not match the %s before it in the MotionBegin at %s", r->name,
			     m->request, reyes_ri_where(ri, m->loc, r->loc));
		m->bad = true;
		return false;
	}
	if (m->nsamples >= m->ntimes) {
		reyes_ri_err(ri, r->loc, "more samples than times in the MotionBegin at %s",
			     reyes_ri_where(ri, m->loc, r->loc));
		m->bad = true;
		return false;
	}
	m->request = r->name;
	m->kind = kind;
	return true;
}

void reyes_ri_motion_xform(struct ri *ri, const struct rib_request *r, const float x[16], bool set)
{
	struct motion *m = &ri->motion;
	if (!motion_sample(ri, r, MOTION_XFORM))
		return;
	m->set = set;
	memcpy(m->xf[m->nsamples++], x, sizeof(float) * 16);
}

static bool same_u32(const uint32_t *a, const uint32_t *b, uint32_t n)
{
	return n == 0 || memcmp(a, b, sizeof(uint32_t) * n) == 0;
}

static uint32_t sum_u32(const uint32_t *a, uint32_t n)
{
	uint64_t s = 0;
	for (uint32_t i = 0; i < n; i++)
		s += a[i];
	return (uint32_t)s;
}

/* Do two samples of a deforming primitive agree in kind and topology? */
static const char *topology_mismatch(const struct reyes_prim *a, const struct reyes_prim *b)
{
	if (a->kind != b->kind)
		return "kind";
	if (a->kind == REYES_POLYGONS) {
		if (a->nfaces != b->nfaces || !same_u32(a->nloops, b->nloops, a->nfaces))
			return "polygons";
		uint32_t nl = sum_u32(a->nloops, a->nfaces);
		if (!same_u32(a->nverts, b->nverts, nl) ||
		    !same_u32(a->verts, b->verts, sum_u32(a->nverts, nl)))
			return "polygons";
	} else if (a->kind == REYES_PATCHES &&
		   (a->bicubic != b->bicubic || a->nu != b->nu || a->nv != b->nv ||
		    a->uperiodic != b->uperiodic || a->vperiodic != b->vperiodic ||
		    a->heightfield != b->heightfield)) {
		return "patch mesh";
	} else if (a->kind == REYES_SUBDIV && !reyes_ri_subdiv_same(a, b)) {
		return "subdivision mesh";
	} else if (a->kind == REYES_NUPATCH && !reyes_ri_nurbs_same(a, b)) {
		return "NuPatch orders, knots, ranges or weights";
	} else if (a->kind == REYES_CURVES && !reyes_ri_same_curves(a->curves, b->curves)) {
		return "curves";
	}
	if (a->npoints != b->npoints)
		return "number of points";
	if (a->nvars != b->nvars)
		return "primitive variables";
	for (uint32_t i = 0; i < a->nvars; i++) {
		const struct reyes_primvar *va = &a->vars[i], *vb = &b->vars[i];
		if (strcmp(va->name, vb->name) != 0 || va->cls != vb->cls || va->type != vb->type ||
		    va->arraylen != vb->arraylen || va->count != vb->count)
			return "primitive variables";
	}
	return NULL;
}

static void motion_prim(struct ri *ri, const struct rib_request *r, struct reyes_prim *p)
{
	struct motion *m = &ri->motion;
	if (!motion_sample(ri, r, MOTION_PRIM))
		return;
	if (m->nsamples == 1) {
		const char *what = topology_mismatch(m->prim[0], p);
		if (what) {
			reyes_ri_err(ri, r->loc,
				     "the %s samples of the MotionBegin at %s differ in their %s",
				     r->name, reyes_ri_where(ri, m->loc, r->loc), what);
			m->bad = true;
			return;
		}
	}
	m->prim[m->nsamples++] = p;
}

void reyes_ri_motion_end(struct ri *ri, bool apply)
{
	struct motion m = ri->motion;
	ri->motion = (struct motion){0};
	if (!apply || m.bad || m.nsamples == 0)
		return;
	if (m.nsamples != m.ntimes) {
		reyes_ri_err(ri, m.loc, "MotionBegin has %u times but %u %s", m.ntimes, m.nsamples,
			     m.nsamples == 1 ? "sample" : "samples");
		return;
	}
	if (m.kind == MOTION_XFORM) {
		uint32_t k1 = m.nsamples - 1;
		if (m.set) {
			reyes_ri_set_xform(ri, m.xf[0], m.xf[k1]);
		} else {
			float a[16], b[16];
			sl_m44_mul(a, m.xf[0], ri->gs.x.m[0]);
			sl_m44_mul(b, m.xf[k1], ri->gs.x.m[1]);
			reyes_ri_set_xform(ri, a, b);
		}
		return;
	}
	struct reyes_prim *p = m.prim[0];
	if (m.nsamples == 2) {
		const struct reyes_prim *q = m.prim[1];
		/* A quadric deforms through its parameters (a sphere's radius grows). */
		if (p->kind < REYES_POLYGONS && memcmp(p->q, q->q, sizeof(p->q)) != 0) {
			memcpy(p->q1, q->q, sizeof(p->q1));
			p->qmoving = true;
		}
		struct reyes_primvar *vars = (struct reyes_primvar *)p->vars;
		for (uint32_t i = 0; i < p->nvars; i++) {
			size_t nf = (size_t)vars[i].count *
				    (size_t)sl_type_ncomp(vars[i].type) *
				    (vars[i].arraylen ? vars[i].arraylen : 1);
			if (nf && memcmp(vars[i].values, q->vars[i].values, sizeof(float) * nf) != 0)
				vars[i].values1 = q->vars[i].values;
		}
	}
	add_prim(ri, p, &ri->gs.x);
}

/* ---- objects ------------------------------------------------------------------------- */

void reyes_ri_req_object_begin(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "ObjectBegin inside the ObjectBegin at %s",
			   reyes_ri_where(ri, reyes_ri_find_block(ri, BLK_OBJECT)->loc, r->loc));
	if (!reyes_ri_depth_ok(ri, r))
		return;
	const char *handle = reyes_ri_handle_arg(ri, r, 0, reyes_ri_cur_arena(ri));
	if (!handle)
		return;
	float inv[2][16];
	if (!sl_m44_inverse(inv[0], ri->gs.x.m[0]) || !sl_m44_inverse(inv[1], ri->gs.x.m[1]))
		FAIL(ri, r->loc, "ObjectBegin: the current transformation is singular");
	reyes_ri_push_block(ri, r, BLK_OBJECT);
	/* From here the attributes a request sets are the object's own. */
	ri->gs.a.objset = 0;
	rl_vec_push(ri->objects, (struct object){0});
	ri->objdef = (int)ri->objects.len - 1;
	memcpy(ri->objdef_inv, inv, sizeof(inv));
	strmap_put(ri->world ? &ri->world_object_index : &ri->outer_object_index, handle,
		   ri->objects.len);
	if (!ri->world)
		ri->outer_objects = ri->objects.len;
}

void reyes_ri_object_end(struct ri *ri)
{
	ri->objdef = -1;
}

void reyes_ri_req_object_end(struct ri *ri, const struct rib_request *r)
{
	reyes_ri_close_block(ri, r, BLK_OBJECT);
}

/* Into the instance's attributes @a, those the object's definition set in @def. */
static void instance_attrs(struct attrstate *a, const struct attrstate *def)
{
	unsigned set = def->objset;
	if (set & OBJ_CS)
		memcpy(a->Cs, def->Cs, sizeof(a->Cs));
	if (set & OBJ_OS)
		memcpy(a->Os, def->Os, sizeof(a->Os));
	if (set & OBJ_SURFACE)
		a->surface = def->surface;
	if (set & OBJ_DISPLACEMENT)
		a->displacement = def->displacement;
	if (set & OBJ_ATMOSPHERE)
		a->atmosphere = def->atmosphere;
	if (set & OBJ_SIDES)
		a->sides = def->sides;
	if (set & OBJ_ORIENTATION)
		a->inside = def->inside;
	if (set & OBJ_SHADING_RATE) {
		a->shading_rate = def->shading_rate;
		a->shading_rate_loc = def->shading_rate_loc;
	}
	if (set & OBJ_INTERPOLATION)
		a->smooth = def->smooth;
	if (set & OBJ_IDENTIFIER)
		a->identifier = def->identifier;
	if (set & OBJ_DBOUND) {
		a->dbound = def->dbound;
		a->dbound_space = def->dbound_space;
	}
	if (set & OBJ_VISIBILITY) {
		a->casts_shadows = def->casts_shadows;
		a->ray = def->ray;
	}
	if (set & OBJ_TEXCOORDS) {
		memcpy(a->texcoords, def->texcoords, sizeof(a->texcoords));
		a->has_texcoords = def->has_texcoords;
	}
	if (set & OBJ_MATTE)
		a->matte = def->matte;
	if (set & OBJ_DETAIL)
		a->detail = def->detail;
	if (set & OBJ_DETAIL_RANGE) {
		memcpy(a->detail_range, def->detail_range, sizeof(a->detail_range));
		a->has_detail_range = def->has_detail_range;
	}
}

void reyes_ri_req_object_instance(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "ObjectInstance inside an object definition");
	if (!ri->world)
		FAIL(ri, r->loc, "ObjectInstance outside WorldBegin/WorldEnd");
	const char *handle = reyes_ri_handle_arg(ri, r, 0, ri->world);
	if (!handle)
		return;
	uintptr_t k;
	if (!strmap_get(&ri->world_object_index, handle, &k) &&
	    !strmap_get(&ri->outer_object_index, handle, &k))
		FAIL(ri, r->loc, "ObjectInstance: unknown object '%s'", handle);
	const struct object *o = &ri->objects.data[k - 1];
	/* one bundle for a run of primitives under the same recorded attributes */
	const struct attrstate *bundle_a = NULL;
	const struct reyes_attrs *bundle = NULL;
	bool warned = false;
	for (size_t i = 0; i < o->prims.len; i++) {
		const struct obj_prim *op = &o->prims.data[i];
		instance_binds(ri, r, handle, op);
		struct xform x = ri->gs.x;
		if (!op->identity) {
			for (int t = 0; t < 2; t++)
				sl_m44_mul(x.m[t], op->rel[t], ri->gs.x.m[t]);
			x.moving = memcmp(x.m[0], x.m[1], sizeof(x.m[0])) != 0;
		}
		if (!op->a) {
			add_prim(ri, op->p, op->identity ? &ri->gs.x : &x);
			continue;
		}
		struct reyes_prim q = *op->p;
		if (op->identity && op->a == bundle_a) {
			q.attrs = bundle;
		} else {
			/* The attributes the definition set, over the instance's. */
			struct attrstate saved = ri->gs.a;
			instance_attrs(&ri->gs.a, op->a);
			if (ri->gs.a.has_detail_range && ri->gs.a.detail < 0 && !warned) {
				reyes_ri_warn(ri, r->loc,
					      "object '%s' has a DetailRange but no Detail bound is "
					      "in effect: every representation renders", handle);
				warned = true;
			}
			q.attrs = reyes_ri_make_bundle(ri, &x);
			ri->gs.a = saved;
			bundle_a = op->identity ? op->a : NULL;
			bundle = q.attrs;
		}
		if (q.attrs->dissolve && !(q.attrs->lod_hi > q.attrs->lod_lo))
			continue;
		q.id = (uint32_t)ri->prims.len;
		q.csg_leaf = reyes_ri_csg_leaf(ri);
		rl_vec_push(ri->prims, q);
	}
}

/* ---- for the primitives parsed in files of their own (ri_subdiv.c, ri_nurbs.c, ...) --- */

bool reyes_ri_geometry_ok(struct ri *ri, const struct rib_request *r)
{
	return geometry_ok(ri, r);
}

bool reyes_ri_array_arg(struct ri *ri, const struct rib_request *r, uint32_t i)
{
	return array_arg(ri, r, i);
}

uint32_t *reyes_ri_uint_values(struct ri *ri, const struct rib_value *v, const char *req,
			       const char *what, uint64_t limit)
{
	return uint_values(ri, v, req, what, limit);
}

bool reyes_ri_check_counts(struct ri *ri, const struct rib_request *r, const struct rib_value *v,
			   const uint32_t *c, uint32_t min, const char *what, uint64_t *sum)
{
	return check_counts(ri, r, v, c, min, what, sum);
}

bool reyes_ri_point_count(struct ri *ri, const struct rib_request *r, uint32_t *np)
{
	return point_count(ri, r, false, np);
}

struct reyes_prim *reyes_ri_new_prim(struct ri *ri, enum reyes_prim_kind kind)
{
	return new_prim(ri, kind);
}

bool reyes_ri_prim_vars(struct ri *ri, const struct rib_request *r, const uint32_t sizes[5],
			bool points, struct reyes_prim *p)
{
	return prim_vars(ri, r, sizes, points, p);
}

void reyes_ri_emit_prim(struct ri *ri, const struct rib_request *r, struct reyes_prim *p)
{
	emit_prim(ri, r, p);
}

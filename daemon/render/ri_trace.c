/*
 * The attributes and options of ray tracing: Attribute "shade" (how hits
 * are shaded), Attribute "trace" (bias and depth limits) and Option
 * "trace" "maxdepth". Attribute "visibility", which says which rays see a
 * primitive, is read with the other attributes (ri.c).
 */
#include "ri_impl.h"
#include "exec.h"

#include <float.h>
#include <string.h>

/* One number, or one string: the value of @p, else a warning and false. */
static bool one_number(struct ri *ri, const struct rib_param *p, const char *what, double *out)
{
	const struct rib_value *v = &p->value;
	if (!reyes_ri_is_numbers(v) || v->n != 1 || !(v->nums[0] >= 0 && v->nums[0] <= FLT_MAX)) {
		reyes_ri_warn(ri, p->loc, "%s takes one number, at least 0: ignored", what);
		return false;
	}
	*out = v->nums[0];
	return true;
}

void reyes_ri_trace_attribute(struct ri *ri, const struct rib_request *r, const char *name)
{
	struct attrstate *a = &ri->gs.a;
	bool shade = strcmp(name, "shade") == 0;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		double x;
		if (shade) {
			static const char *const modes[SL_RAY_TYPE_COUNT] = {
				[SL_RAY_SPECULAR] = "specularhitmode", [SL_RAY_DIFFUSE] = "diffusehitmode",
				[SL_RAY_TRANSMISSION] = "transmissionhitmode",
			};
			int k = -1;
			for (int t = 0; t < SL_RAY_TYPE_COUNT; t++)
				if (!strcmp(pname, modes[t]))
					k = t;
			if (k < 0) {
				reyes_ri_warn(ri, p->loc, "unknown attribute 'shade' '%s' ignored", pname);
				continue;
			}
			const char *m = !reyes_ri_is_numbers(v) && v->n == 1 ? v->strs[0] : "";
			if (!strcmp(m, "primitive")) {
				a->ray.hitmode[k] = REYES_HIT_PRIMITIVE;
			} else if (!strcmp(m, "shader") || !strcmp(m, "cache")) {
				if (!strcmp(m, "cache"))
					reyes_ri_warn(ri, p->loc, "shade \"%s\" \"cache\": relight keeps no "
						      "radiance cache; hits are shaded (\"shader\")", pname);
				a->ray.hitmode[k] = REYES_HIT_SHADER;
			} else {
				reyes_ri_warn(ri, p->loc, "shade \"%s\" must be \"primitive\" or "
					      "\"shader\": ignored", pname);
				continue;
			}
		} else if (!strcmp(pname, "bias")) {
			if (!one_number(ri, p, "trace \"bias\"", &x))
				continue;
			a->ray.bias = (float)x;
		} else if (!strcmp(pname, "maxspeculardepth") || !strcmp(pname, "maxdiffusedepth")) {
			if (!one_number(ri, p, pname, &x))
				continue;
			uint32_t n = x > 1000 ? 1000 : (uint32_t)x;
			if (pname[3] == 's')
				a->ray.max_specular_depth = n;
			else
				a->ray.max_diffuse_depth = n;
		} else if (!strcmp(pname, "displacements")) {
			if (one_number(ri, p, "trace \"displacements\"", &x) && x == 0)
				reyes_ri_warn(ri, p->loc, "trace \"displacements\" 0: rays see the "
					      "displaced surface all the same");
		} else if (!strcmp(pname, "samplemotion")) {
			/* rays see the geometry at their own time whatever it says */
		} else {
			reyes_ri_warn(ri, p->loc, "unknown attribute 'trace' '%s' ignored", pname);
			continue;
		}
		a->objset |= OBJ_VISIBILITY;
	}
	ri->gs.bundle = NULL;
}

void reyes_ri_trace_option(struct ri *ri, const struct rib_request *r)
{
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		double x;
		if (!strcmp(pname, "maxdepth")) {
			if (one_number(ri, p, "trace \"maxdepth\"", &x))
				ri->opt.o.trace_maxdepth = x > 1000 ? 1000 : (uint32_t)x;
		} else if (!strcmp(pname, "specularthreshold") || !strcmp(pname, "continuationbydefault")) {
			reyes_ri_warn(ri, p->loc, "option 'trace' '%s' ignored", pname);
		} else {
			reyes_ri_warn(ri, p->loc, "unknown option 'trace' '%s' ignored", pname);
		}
	}
}

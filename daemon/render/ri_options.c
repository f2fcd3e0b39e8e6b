/*
 * The RIB scene builder's options (RISpec 3.2 section 4.1): the camera,
 * the image and its displays, the hider and Option; options are saved and
 * restored by FrameBegin and FrameEnd (ri.c), which owns the rest of the
 * scene builder.
 */
#include "ri_impl.h"

#include "arena.h"
#include "deepshadow.h"
#include "hider.h"
#include "mathlib.h"
#include "sl.h"
#include "strbuf.h"

#include <ctype.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum {
	MAX_DISPLAYS = 64,            /* Display requests in one frame */
	MAX_RESOLUTION = 1 << 16,     /* Format */
	MAX_PIXEL_SAMPLES = 1024,     /* PixelSamples, each direction */
};

#define DEFAULT_NEAR 1e-10f
#define DEFAULT_FAR 1e30f

/* ---- options ------------------------------------------------------------------------- */

void reyes_ri_options_init(struct ri *ri, struct optstate *s)
{
	*s = (struct optstate){0};
	struct reyes_options *o = &s->o;
	o->xres = 640;
	o->yres = 480;
	o->pixel_aspect = 1;
	o->crop[1] = o->crop[3] = 1;
	o->fov = 90;
	o->trace_maxdepth = 10;
	o->clip_near = DEFAULT_NEAR;
	o->clip_far = DEFAULT_FAR;
	o->xsamples = o->ysamples = 2;
	o->filter = REYES_FILTER_GAUSSIAN;
	o->filter_width[0] = o->filter_width[1] = 2;
	o->gain = o->gamma = 1;
	o->depthfilter = REYES_DEPTH_MIN;
	o->jitter = true;
	o->opacity_threshold = 0.996f;
	o->shader_path = ri->default_shader_path;
	o->texture_path = ri->default_texture_path;
	o->archive_path = ".";
	o->include_path = ri->default_include_path;
	sl_m44_identity(o->world_to_camera);
	sl_m44_identity(o->world_to_camera1);
	sl_m44_identity(o->camera_to_screen);
	s->relative_detail = 1;
}

/* Would this request change an option? They must come before WorldBegin. */
bool reyes_ri_option_ok(struct ri *ri, const struct rib_request *r)
{
	if (!ri->world)
		return true;
	reyes_ri_err(ri, r->loc, "%s is an option: it must come before WorldBegin", r->name);
	return false;
}

void reyes_ri_req_format(struct ri *ri, const struct rib_request *r)
{
	double x, y, a;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_num_arg(ri, r, 0, &x) ||
	    !reyes_ri_num_arg(ri, r, 1, &y) || !reyes_ri_num_arg(ri, r, 2, &a))
		return;
	if (!(x >= 1 && x <= MAX_RESOLUTION && y >= 1 && y <= MAX_RESOLUTION)) {
		reyes_ri_err(ri, r->loc, "Format: resolution %gx%g out of range (1 to %d)", x, y,
			     MAX_RESOLUTION);
		return;
	}
	if (a == 0 || !(fabs(a) <= 1e6)) {
		reyes_ri_err(ri, r->loc, "Format: bad pixel aspect ratio %g", a);
		return;
	}
	ri->opt.o.xres = (uint32_t)x;
	ri->opt.o.yres = (uint32_t)y;
	ri->opt.o.format_loc = reyes_ri_keep_loc(ri, r->loc);
	/* A negative aspect ratio keeps the current one. */
	if (a > 0)
		ri->opt.o.pixel_aspect = (float)a;
}

void reyes_ri_req_frame_aspect(struct ri *ri, const struct rib_request *r)
{
	float a;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 1, &a))
		return;
	if (!(a > 0)) {
		reyes_ri_err(ri, r->loc, "FrameAspectRatio must be positive, got %g", a);
		return;
	}
	ri->opt.o.frame_aspect = a;
}

void reyes_ri_req_screen_window(struct ri *ri, const struct rib_request *r)
{
	float s[4];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 4, s))
		return;
	if (s[0] == s[1] || s[2] == s[3]) {
		reyes_ri_err(ri, r->loc, "ScreenWindow %g %g %g %g is empty", s[0], s[1], s[2],
			     s[3]);
		return;
	}
	memcpy(ri->opt.o.screen, s, sizeof(s));
	ri->opt.o.screen_set = true;
}

void reyes_ri_req_crop_window(struct ri *ri, const struct rib_request *r)
{
	float c[4];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 4, c))
		return;
	for (int i = 0; i < 4; i++)
		c[i] = sl_clampf(c[i], 0, 1);
	if (!(c[0] < c[1] && c[2] < c[3])) {
		reyes_ri_err(ri, r->loc, "CropWindow %g %g %g %g is empty", c[0], c[1], c[2], c[3]);
		return;
	}
	memcpy(ri->opt.o.crop, c, sizeof(c));
	ri->opt.o.crop_loc = reyes_ri_keep_loc(ri, r->loc);
}

bool reyes_ri_is_identity(const float m[16])
{
	float id[16];
	sl_m44_identity(id);
	return memcmp(m, id, sizeof(id)) == 0;
}

void reyes_ri_req_projection(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name))
		return;
	struct reyes_options *o = &ri->opt.o;
	if (strcmp(name, "perspective") == 0) {
		float fov = 90;
		for (uint32_t i = 0; i < r->nparams; i++) {
			const struct rib_param *p = &r->params[i];
			struct decl d;
			bool has;
			const char *pname;
			if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
				return;
			if (strcmp(pname, "fov") != 0) {
				reyes_ri_warn(ri, p->loc,
					      "Projection: unknown parameter '%s' ignored", pname);
				continue;
			}
			if (!reyes_ri_is_numbers(&p->value) || p->value.n != 1)
				FAIL(ri, p->loc, "Projection: \"fov\" takes one number");
			if (!reyes_ri_value_floats(ri, &p->value, p->loc, "fov", &fov))
				return;
			if (!(fov > 0 && fov < 180))
				FAIL(ri, p->loc, "Projection: fov %g is out of range (0 to 180)",
					   fov);
		}
		o->perspective = true;
		o->fov = fov;
	} else if (strcmp(name, "orthographic") == 0) {
		o->perspective = false;
		for (uint32_t i = 0; i < r->nparams; i++)
			reyes_ri_warn(ri, r->params[i].loc,
				      "Projection: unknown parameter '%s' ignored",
				      r->params[i].token);
	} else {
		FAIL(ri, r->loc,
			   "unsupported projection '%s' (use \"perspective\" or \"orthographic\")",
			   name);
	}
	ri->opt.projection_given = true;
	/* RISpec: Projection marks camera space; the current transformation restarts. */
	if (!reyes_ri_is_identity(ri->gs.x.m[0]) || ri->gs.x.moving)
		reyes_ri_warn(ri, r->loc, "transformations before Projection are ignored");
	sl_m44_identity(ri->gs.x.m[0]);
	sl_m44_identity(ri->gs.x.m[1]);
	ri->gs.x.moving = false;
	ri->gs.bundle = NULL;
}

void reyes_ri_req_clipping(struct ri *ri, const struct rib_request *r)
{
	float c[2];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 2, c))
		return;
	if (!(c[0] > 0 && c[1] > c[0])) {
		reyes_ri_err(ri, r->loc, "Clipping %g %g: need 0 < near < far", c[0], c[1]);
		return;
	}
	ri->opt.o.clip_near = c[0];
	ri->opt.o.clip_far = c[1];
}

void reyes_ri_req_shutter(struct ri *ri, const struct rib_request *r)
{
	float s[2];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 2, s))
		return;
	if (s[1] < s[0]) {
		reyes_ri_err(ri, r->loc, "Shutter %g %g closes before it opens", s[0], s[1]);
		return;
	}
	memcpy(ri->opt.o.shutter, s, sizeof(s));
}

/*
 * DepthOfField fstop focallength focaldistance, or DepthOfField alone: a
 * pinhole camera (as is an fstop of RI_INFINITY, 1e38, or more).
 */
void reyes_ri_req_depth_of_field(struct ri *ri, const struct rib_request *r)
{
	struct reyes_options *o = &ri->opt.o;
	float v[3];
	if (!reyes_ri_option_ok(ri, r))
		return;
	if (r->nargs == 0) {
		o->fstop = 0;
		return;
	}
	if (!reyes_ri_float_args(ri, r, 0, 3, v))
		return;
	if (v[0] >= 1e30f) {
		o->fstop = 0;
		return;
	}
	if (!(v[0] > 0 && v[1] > 0 && v[2] > 0 && isfinite(v[1]) && isfinite(v[2])))
		FAIL(ri, r->loc, "DepthOfField %g %g %g: fstop, focal length and focal distance "
			   "must be positive", v[0], v[1], v[2]);
	if (!(v[2] > v[1]))
		FAIL(ri, r->loc, "DepthOfField: a lens of focal length %g cannot focus at %g "
			   "(the focal distance must be greater)", v[1], v[2]);
	o->fstop = v[0];
	o->focallength = v[1];
	o->focaldistance = v[2];
	ri->opt.dof_loc = r->loc;
}

void reyes_ri_req_pixel_samples(struct ri *ri, const struct rib_request *r)
{
	float s[2];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 2, s))
		return;
	if (!(s[0] >= 1 && s[1] >= 1 && s[0] <= MAX_PIXEL_SAMPLES && s[1] <= MAX_PIXEL_SAMPLES)) {
		reyes_ri_err(ri, r->loc, "PixelSamples %g %g out of range (1 to %d)", s[0], s[1],
			     MAX_PIXEL_SAMPLES);
		return;
	}
	ri->opt.o.xsamples = (uint32_t)s[0];
	ri->opt.o.ysamples = (uint32_t)s[1];
	ri->opt.o.samples_loc = reyes_ri_keep_loc(ri, r->loc);
}

void reyes_ri_req_pixel_filter(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	float w[2];
	enum reyes_filter f;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name) ||
	    !reyes_ri_float_args(ri, r, 1, 2, w))
		return;
	if (!reyes_filter_from_name(name, &f)) {
		reyes_ri_err(ri, r->loc, "unknown pixel filter '%s'", name);
		return;
	}
	if (!(w[0] > 0 && w[1] > 0 && w[0] <= 64 && w[1] <= 64)) {
		reyes_ri_err(ri, r->loc, "PixelFilter widths %g %g out of range (0 to 64)", w[0],
			     w[1]);
		return;
	}
	ri->opt.o.filter = f;
	memcpy(ri->opt.o.filter_width, w, sizeof(w));
}

void reyes_ri_req_exposure(struct ri *ri, const struct rib_request *r)
{
	float e[2];
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_float_args(ri, r, 0, 2, e))
		return;
	if (!(e[1] > 0)) {
		reyes_ri_err(ri, r->loc, "Exposure: gamma must be positive, got %g", e[1]);
		return;
	}
	ri->opt.o.gain = e[0];
	ri->opt.o.gamma = e[1];
}

void reyes_ri_req_quantize(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	double one;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &type) ||
	    !reyes_ri_num_arg(ri, r, 1, &one))
		return;
	if (strcmp(type, "rgba") == 0)
		ri->opt.quantize_float = one == 0;
	else if (strcmp(type, "z") != 0)
		reyes_ri_warn(ri, r->loc, "Quantize: unknown type '%s' ignored", type);
}

/* An output variable's name: an identifier. */
static bool is_identifier(const char *s)
{
	if (!isalpha((unsigned char)*s) && *s != '_')
		return false;
	for (s++; *s; s++)
		if (!isalnum((unsigned char)*s) && *s != '_')
			return false;
	return true;
}

void reyes_ri_req_display(struct ri *ri, const struct rib_request *r)
{
	const char *name, *type, *mode;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name) ||
	    !reyes_ri_str_arg(ri, r, 1, &type) || !reyes_ri_str_arg(ri, r, 2, &mode))
		return;
	bool add = name[0] == '+';
	if (add)
		name++;
	if (!*name)
		FAIL(ri, r->loc, "Display: empty file name");
	bool depth = strcmp(type, "zfile") == 0 || strcmp(type, "shadow") == 0;
	/* prman's deep shadow display: the visibility function of each pixel */
	bool deep = strcmp(type, "deepshad") == 0;
	if (deep && strcmp(mode, "deepopacity") != 0)
		FAIL(ri, r->loc, "Display \"deepshad\": mode '%s' is not supported "
		     "(\"deepopacity\" is)", mode);
	static const char *const modes[] = {"rgba", "rgb", "a", "z", "rgbaz"};
	const char *m = deep ? "deepopacity" : NULL;
	float deep_error = REYES_DEEP_DEFAULT_ERROR;
	for (size_t i = 0; !m && i < sizeof(modes) / sizeof(modes[0]); i++)
		if (strcmp(mode, modes[i]) == 0)
			m = modes[i];
	if (!m) {
		/*
		 * A comma-separated list of those and output variables, each
		 * perhaps with its type: "rgba,color diffuse,N". Kept as the
		 * names alone: "rgba,diffuse,N".
		 */
		struct rl_strbuf list = {0};
		for (const char *t = mode;;) {
			const char *e = strchr(t, ',');
			size_t n = e ? (size_t)(e - t) : strlen(t);
			while (n && isspace((unsigned char)t[n - 1]))
				n--;
			const char *last = t + n;
			while (last > t && !isspace((unsigned char)last[-1]))
				last--;
			char word[256];
			size_t wl = (size_t)(t + n - last);
			bool known = false;
			if (wl > 0 && wl < sizeof(word)) {
				memcpy(word, last, wl);
				word[wl] = '\0';
				for (size_t i = 0; i < sizeof(modes) / sizeof(modes[0]); i++)
					known = known || strcmp(word, modes[i]) == 0;
			}
			if (!wl || wl >= sizeof(word) || (!known && !is_identifier(word))) {
				rl_strbuf_finish(&list);
				FAIL(ri, r->loc,
				     "Display: bad mode '%s' (rgba, rgb, a, z, rgbaz or output "
				     "variables' names, separated by commas)", mode);
			}
			if (list.len)
				rl_strbuf_putc(&list, ',');
			rl_strbuf_puts(&list, word);
			if (!e)
				break;
			t = e + 1;
		}
		m = rl_arena_strdup(ri->perm, rl_strbuf_str(&list));
		rl_strbuf_finish(&list);
	}
	if (depth)
		m = "z";
	bool half = !depth && !deep && strcmp(m, "z") != 0;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		if (strcmp(pname, "quantize") == 0) {
			bool zero = reyes_ri_is_numbers(v) && v->n > 0;
			for (uint32_t k = 0; zero && k < v->n; k++)
				zero = v->nums[k] == 0;
			if (zero || (!reyes_ri_is_numbers(v) && v->n == 1 &&
				     strcmp(v->strs[0], "float") == 0))
				half = false;
		} else if (deep && strcmp(pname, "deepshadowerror") == 0) {
			if (!reyes_ri_is_numbers(v) || v->n != 1 || !(v->nums[0] >= 0.0 &&
								      v->nums[0] < 1.0))
				FAIL(ri, p->loc, "Display: deepshadowerror must be one number in "
				     "[0, 1)");
			deep_error = (float)v->nums[0];
		} else if (strcmp(pname, "type") == 0 && !reyes_ri_is_numbers(v) && v->n == 1) {
			if (strcmp(v->strs[0], "float") == 0)
				half = false;
			else if (strcmp(v->strs[0], "half") == 0)
				half = !depth;
			else
				reyes_ri_warn(ri, p->loc, "Display: unknown data type '%s' ignored",
					      v->strs[0]);
		} else {
			reyes_ri_warn(ri, p->loc, "Display: unknown parameter '%s' ignored", pname);
		}
	}
	struct reyes_options *o = &ri->opt.o;
	uint32_t keep = add ? o->ndisplays : 0;
	if (keep >= MAX_DISPLAYS)
		FAIL(ri, r->loc, "too many displays (limit %d)", MAX_DISPLAYS);
	struct reyes_display *ds = rl_arena_alloc(ri->perm, sizeof(*ds) * (keep + 1));
	if (keep)
		memcpy(ds, o->displays, sizeof(*ds) * keep);
	struct rib_loc loc = reyes_ri_keep_loc(ri, r->loc);
	ds[keep] = (struct reyes_display){
		.name = rl_arena_strdup(ri->perm, name),
		.type = rl_arena_strdup(ri->perm, type),
		.mode = m,
		.half = half,
		.file = loc.file,
		.line = loc.line,
		.deep_error = deep_error,
	};
	o->displays = ds;
	o->ndisplays = keep + 1;
}

void reyes_ri_req_hider(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &type))
		return;
	if (strcmp(type, "hidden") != 0) {
		reyes_ri_warn(ri, r->loc, "Hider '%s' is not supported: using \"hidden\"", type);
		return;
	}
	struct reyes_options *o = &ri->opt.o;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		if (strcmp(pname, "depthfilter") == 0) {
			static const char *const names[] = {"min", "max", "average", "midpoint"};
			int k = -1;
			for (int j = 0; j < 4 && !reyes_ri_is_numbers(v) && v->n == 1; j++)
				if (strcmp(v->strs[0], names[j]) == 0)
					k = j;
			if (k < 0)
				FAIL(ri, p->loc,
					   "Hider: \"depthfilter\" must be \"min\", \"max\", "
					   "\"average\" or \"midpoint\"");
			o->depthfilter = (enum reyes_depthfilter)k;
		} else if (strcmp(pname, "jitter") == 0) {
			if (!reyes_ri_is_numbers(v) || v->n != 1)
				FAIL(ri, p->loc, "Hider: \"jitter\" takes one number");
			o->jitter = v->nums[0] != 0;
		} else {
			reyes_ri_warn(ri, p->loc, "Hider: unknown parameter '%s' ignored", pname);
		}
	}
}

/* @spec with '&' (@prev) and '@' (@dflt) elements replaced; empty elements dropped. */
static const char *expand_path(struct ri *ri, const char *spec, const char *prev,
			       const char *dflt)
{
	struct rl_strbuf b = {0};
	const char *p = spec;
	while (*p) {
		const char *e = strchr(p, ':');
		size_t n = e ? (size_t)(e - p) : strlen(p);
		const char *add = NULL;
		size_t addn = 0;
		if (n == 1 && *p == '&') {
			add = prev;
		} else if (n == 1 && *p == '@') {
			add = dflt;
		} else {
			add = p;
			addn = n;
		}
		if (add && add != p)
			addn = strlen(add);
		if (addn) {
			if (b.len)
				rl_strbuf_putc(&b, ':');
			rl_strbuf_add(&b, add, addn);
		}
		p += n;
		if (*p == ':')
			p++;
	}
	const char *out = rl_arena_strdup(ri->perm, rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return out;
}

/* Option "shading" "string specularmodel" ["prman" | "rispec"] */
static void shading_option(struct ri *ri, const struct rib_request *r)
{
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		if (strcmp(pname, "specularmodel") != 0) {
			reyes_ri_warn(ri, p->loc, "unknown option 'shading' '%s' ignored", pname);
			continue;
		}
		if (reyes_ri_is_numbers(&p->value) || p->value.n != 1 ||
		    !sl_specular_model_parse(p->value.strs[0], &ri->opt.o.specular_model))
			reyes_ri_err(ri, p->loc,
				     "Option \"shading\" \"specularmodel\" takes \"prman\" or \"rispec\"");
	}
}

void reyes_ri_req_option(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_option_ok(ri, r) || !reyes_ri_str_arg(ri, r, 0, &name))
		return;
	if (strcmp(name, "shading") == 0) {
		shading_option(ri, r);
		return;
	}
	if (strcmp(name, "trace") == 0) {
		reyes_ri_trace_option(ri, r);
		return;
	}
	if (strcmp(name, "searchpath") != 0) {
		reyes_ri_warn(ri, r->loc, "unknown option '%s' ignored", name);
		return;
	}
	struct reyes_options *o = &ri->opt.o;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!reyes_ri_param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const char **slot = NULL, *dflt = NULL;
		if (strcmp(pname, "shader") == 0) {
			slot = &o->shader_path;
			dflt = ri->default_shader_path;
		} else if (strcmp(pname, "texture") == 0) {
			slot = &o->texture_path;
			dflt = ri->default_texture_path;
		} else if (strcmp(pname, "archive") == 0) {
			slot = &o->archive_path;
			dflt = ".";
		} else if (strcmp(pname, "include") == 0) {
			slot = &o->include_path;
			dflt = ri->default_include_path;
		} else {
			reyes_ri_warn(ri, p->loc, "unknown option 'searchpath' '%s' ignored",
				      pname);
			continue;
		}
		if (reyes_ri_is_numbers(&p->value) || p->value.n != 1) {
			reyes_ri_err(ri, p->loc, "Option \"searchpath\" \"%s\" takes one string",
				     pname);
			continue;
		}
		*slot = expand_path(ri, p->value.strs[0], *slot, dflt);
	}
}


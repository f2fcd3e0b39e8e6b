/*
 * The RIB scene builder: the meaning of the requests the RIB reader hands
 * over, following the RenderMan Interface Specification 3.2.
 *
 * State, from the longest-lived down:
 *  - the read: declarations, the compiled shaders (one compilation per file
 *    and read), objects defined outside a world, in the `perm` arena;
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
#include "ri.h"

#include "arena.h"
#include "config.h"
#include "hider.h"
#include "ir.h"
#include "mathlib.h"
#include "sl.h"
#include "strbuf.h"
#include "texture.h"

#include <ctype.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum {
	MAX_ARCHIVE_DEPTH = 64,       /* ReadArchive nesting */
	MAX_ARCHIVE_READS = 100000,   /* ReadArchive requests in one read */
	MAX_BLOCK_DEPTH = 10000,      /* nested blocks */
	MAX_DISPLAYS = 64,            /* Display requests in one frame */
	MAX_PRIMVARS = 256,           /* primitive variables of one primitive */
	MAX_DECL_ARRAY = 1 << 16,     /* array length in a declaration */
	MAX_RESOLUTION = 1 << 16,     /* Format */
	MAX_PIXEL_SAMPLES = 1024,     /* PixelSamples, each direction */
};

#define PI_F 3.14159265358979323846f
#define DEFAULT_NEAR 1e-10f
#define DEFAULT_FAR 1e30f

/* ---- a string-keyed hash map ------------------------------------------------ */

struct strmap_slot {
	const char *key;      /* owned by an arena that outlives the entry */
	uintptr_t val;
};

struct strmap {
	struct strmap_slot *slots;
	size_t cap, len;
};

static uint64_t hash_str(const char *s)
{
	uint64_t h = 1469598103934665603u;
	for (; *s; s++) {
		h ^= (unsigned char)*s;
		h *= 1099511628211u;
	}
	return h;
}

static struct strmap_slot *strmap_slot(const struct strmap *m, const char *key)
{
	size_t mask = m->cap - 1;
	for (size_t i = (size_t)hash_str(key) & mask;; i = (i + 1) & mask) {
		struct strmap_slot *s = &m->slots[i];
		if (!s->key || strcmp(s->key, key) == 0)
			return s;
	}
}

static bool strmap_get(const struct strmap *m, const char *key, uintptr_t *val)
{
	if (!m->cap)
		return false;
	const struct strmap_slot *s = strmap_slot(m, key);
	if (!s->key)
		return false;
	*val = s->val;
	return true;
}

static void strmap_put(struct strmap *m, const char *key, uintptr_t val)
{
	if ((m->len + 1) * 2 > m->cap) {
		struct strmap old = *m;
		m->cap = old.cap ? old.cap * 2 : 16;
		m->slots = rl_xcalloc(m->cap, sizeof(*m->slots));
		m->len = 0;
		for (size_t i = 0; i < old.cap; i++)
			if (old.slots[i].key) {
				*strmap_slot(m, old.slots[i].key) = old.slots[i];
				m->len++;
			}
		free(old.slots);
	}
	struct strmap_slot *s = strmap_slot(m, key);
	if (!s->key) {
		s->key = key;
		m->len++;
	}
	s->val = val;
}

static void strmap_free(struct strmap *m)
{
	free(m->slots);
	*m = (struct strmap){0};
}

/* ---- the builder's state ------------------------------------------------------ */

/* A type from a declaration: "[class] type ['[' n ']'] [name]". */
struct decl {
	enum reyes_class cls;
	int type;              /* enum sl_basetype; integer is float, hpoint is point */
	bool hpoint;           /* four components, divided by w on the way in */
	uint32_t arraylen;     /* 0: not an array */
	const char *name;      /* inline declarations only */
};

/* The current transformation at shutter open and close. */
struct xform {
	float m[2][16];
	bool moving;
};

/* The attributes of the graphics state (the transformation aside). */
struct attrstate {
	float Cs[3], Os[3];
	const struct reyes_shader *surface, *displacement;
	const uint32_t *lights;         /* indices of the lights that are on, ascending */
	uint32_t nlights;
	int sides;
	/* The orientation differs from the coordinate system's handedness. */
	bool inside;
	float shading_rate;
	bool smooth;
	const char *identifier;
	float dbound;
	const char *dbound_space;
	bool casts_shadows;
	float ubasis[16], vbasis[16];
	uint32_t ustep, vstep;
};

struct gstate {
	struct attrstate a;
	struct xform x;
	/* The bundle for a and x, made when a primitive first needs it. */
	const struct reyes_attrs *bundle;
	/*
	 * a.lights when nothing else refers to it (no bundle, no saved block),
	 * so that it may change in place; it has room for lights_cap entries.
	 * Otherwise NULL, and a change makes a copy.
	 */
	uint32_t *own_lights;
	uint32_t lights_cap;
};

struct optstate {
	struct reyes_options o;        /* displays: an immutable array in perm */
	bool projection_given;
	bool quantize_float;           /* Quantize "rgba" 0 ...: float images */
};

enum blk { BLK_FRAME, BLK_WORLD, BLK_ATTRIBUTE, BLK_TRANSFORM, BLK_MOTION, BLK_OBJECT };

static const char *const blk_begin[] = {
	"FrameBegin", "WorldBegin", "AttributeBegin", "TransformBegin", "MotionBegin",
	"ObjectBegin",
};

struct block {
	enum blk kind;
	struct rib_loc loc;      /* file name interned */
	uint32_t file_depth;     /* which file (archive nesting) opened it */
	struct gstate gs;        /* what to restore */
	struct optstate opt;     /* BLK_FRAME */
};

enum motion_kind { MOTION_NONE, MOTION_XFORM, MOTION_PRIM };

struct motion {
	bool active;
	bool bad;                 /* the block was rejected: its samples are skipped */
	struct rib_loc loc;
	float times[2];
	uint32_t ntimes, nsamples;
	const char *request;      /* the first sample's request */
	enum motion_kind kind;
	bool set;                 /* transform samples replace the transformation */
	float xf[2][16];
	struct reyes_prim *prim[2];
};

struct obj_prim {
	struct reyes_prim *p;     /* attrs NULL: given at each instance */
	float rel[2][16];         /* the primitive's transformation relative to ObjectBegin's */
	bool identity;
};

struct object {
	RL_VEC(struct obj_prim) prims;
};

struct space {
	const char *name;
	float m[16];              /* that space to world (before WorldBegin: to camera) */
};

/* A file being read: the top-level file or an archive. */
struct file {
	const char *path;
	const char *raw_name;     /* the reader's name pointer, valid while it reads */
	const char *name;         /* interned */
	struct stat st;
	bool have_st;
	struct rib_loc last;      /* the last request seen */
};

struct ri {
	const struct reyes_ri_opts *opts;
	FILE *diag;               /* where diagnostics end up */
	int max_errors;
	int nerrors;              /* the builder's own, plus frames the callback refused */
	int reader_errors;
	int frame_errors;         /* in the frame being built */
	bool stop;

	/* The reader's diagnostics pass through a memory stream, so that its
	   errors can hold back the frame they occur in. */
	FILE *rdiag;
	char *rbuf;
	size_t rlen;

	struct rl_arena *perm;
	struct strmap decls;              /* name -> struct decl * */
	struct strmap shader_cache;       /* path -> struct sl_program * (NULL: failed) */
	RL_VEC(struct sl_program *) progs;
	const char *default_shader_path;
	const char *default_texture_path;

	struct optstate opt;
	struct gstate gs;
	RL_VEC(struct block) blocks;
	RL_VEC(struct file) files;
	uint32_t archive_reads;

	/* before WorldBegin: named spaces relative to camera */
	RL_VEC(struct space) pre_spaces;
	struct strmap pre_space_index;    /* name -> index + 1 */

	/* objects: those defined outside a world first, then the world's */
	RL_VEC(struct object) objects;
	size_t outer_objects;
	struct strmap outer_object_index; /* handle -> index + 1 */
	struct strmap world_object_index;
	int objdef;                       /* the object being defined, or -1 */
	float objdef_inv[2][16];

	struct motion motion;

	/* the world */
	struct rl_arena *world;
	float w2c_inv[16];
	bool w2c_mirror;                  /* the camera transformation flips handedness */
	RL_VEC(struct reyes_light) lights;
	struct strmap light_index;        /* handle -> index + 1 */
	RL_VEC(struct reyes_prim) prims;
	RL_VEC(struct space) spaces;
	struct strmap space_index;
};

/* ---- diagnostics ------------------------------------------------------------------- */

static void forward_reader_diag(struct ri *ri);

static void verr(struct ri *ri, struct rib_loc loc, bool warning, const char *fmt, va_list ap)
{
	forward_reader_diag(ri);
	struct rl_strbuf b = {0};
	rl_strbuf_vprintf(&b, fmt, ap);
	if (warning) {
		rib_warning(ri->diag, loc, "%s", rl_strbuf_str(&b));
	} else {
		rib_error(ri->diag, loc, "%s", rl_strbuf_str(&b));
		ri->nerrors++;
		ri->frame_errors++;
		if (ri->nerrors + ri->reader_errors >= ri->max_errors)
			ri->stop = true;
	}
	rl_strbuf_finish(&b);
}

static void err(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static void warn(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* Reports an error and leaves the (void) request handler. */
#define FAIL(...) \
	do { \
		err(__VA_ARGS__); \
		return; \
	} while (0)

static void err(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	verr(ri, loc, false, fmt, ap);
	va_end(ap);
}

static void warn(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	verr(ri, loc, true, fmt, ap);
	va_end(ap);
}

/* Passes the reader's pending messages on; its errors count against the frame. */
static void forward_reader_diag(struct ri *ri)
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
				ri->frame_errors++;
				break;
			}
		p += len + 1;
	}
	rewind(ri->rdiag);
	fflush(ri->rdiag);
}

/* The loc with its file name interned (the reader's name dies with its read). */
static struct rib_loc keep_loc(struct ri *ri, struct rib_loc loc)
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
static const char *where(struct ri *ri, struct rib_loc at, struct rib_loc from)
{
	if (at.file && from.file && strcmp(at.file, from.file) == 0)
		return rl_arena_printf(ri->perm, "line %u", (unsigned)at.line);
	return rl_arena_printf(ri->perm, "%s:%u", at.file ? at.file : "<rib>", (unsigned)at.line);
}

/* ---- arguments ----------------------------------------------------------------------- */

static bool num_arg(struct ri *ri, const struct rib_request *r, uint32_t i, double *out)
{
	if (i < r->nargs && (r->args[i].type == RIB_NUMBER || r->args[i].type == RIB_NUMBERS) &&
	    r->args[i].n == 1) {
		*out = r->args[i].nums[0];
		return true;
	}
	err(ri, r->loc, "%s: argument %u should be a number", r->name, i + 1);
	return false;
}

static bool str_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char **out)
{
	if (i < r->nargs && (r->args[i].type == RIB_STRING || r->args[i].type == RIB_STRINGS) &&
	    r->args[i].n == 1) {
		*out = r->args[i].strs[0];
		return true;
	}
	err(ri, r->loc, "%s: argument %u should be a string", r->name, i + 1);
	return false;
}

/* Numbers args[first..first+n) as floats. */
static bool float_args(struct ri *ri, const struct rib_request *r, uint32_t first, uint32_t n,
		       float *out)
{
	for (uint32_t i = 0; i < n; i++) {
		double d;
		if (!num_arg(ri, r, first + i, &d))
			return false;
		if (!(fabs(d) <= FLT_MAX)) {
			err(ri, r->loc, "%s: %g is out of range", r->name, d);
			return false;
		}
		out[i] = (float)d;
	}
	return true;
}

/* A handle (integer or string) as a string in @a. */
static const char *handle_arg(struct ri *ri, const struct rib_request *r, uint32_t i,
			      struct rl_arena *a)
{
	if (i < r->nargs && (r->args[i].type == RIB_STRING || r->args[i].type == RIB_STRINGS) &&
	    r->args[i].n == 1)
		return rl_arena_strdup(a, r->args[i].strs[0]);
	double d;
	if (!num_arg(ri, r, i, &d))
		return NULL;
	return rl_arena_printf(a, "%.17g", d);
}

/* A value's numbers as floats; false (reported) when one is beyond the float range. */
static bool value_floats(struct ri *ri, const struct rib_value *v, struct rib_loc loc,
			 const char *what, float *out)
{
	for (uint32_t i = 0; i < v->n; i++) {
		double d = v->nums[i];
		if (!(fabs(d) <= FLT_MAX)) {
			err(ri, loc, "%s: %g is out of range for a float", what, d);
			return false;
		}
		out[i] = (float)d;
	}
	return true;
}

static bool is_numbers(const struct rib_value *v)
{
	return v->type == RIB_NUMBER || v->type == RIB_NUMBERS;
}

/* Non-negative integers of an array, each below @limit. */
static uint32_t *uint_values(struct ri *ri, const struct rib_value *v, const char *req,
			     const char *what, uint64_t limit)
{
	uint32_t *out = rl_arena_alloc(ri->world ? ri->world : ri->perm,
				       sizeof(uint32_t) * (v->n ? v->n : 1));
	for (uint32_t i = 0; i < v->n; i++) {
		double d = v->nums[i];
		if (!(d >= 0 && d < (double)limit && d == floor(d))) {
			err(ri, v->loc, "%s: %s %u is %g (expected an integer from 0 to %llu)", req,
			    what, i, d, (unsigned long long)(limit - 1));
			return NULL;
		}
		out[i] = (uint32_t)d;
	}
	return out;
}

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
static bool param_token(struct ri *ri, const struct rib_param *par, const char *req,
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
			err(ri, par->loc, "%s: empty parameter name", req);
			return false;
		}
		return true;
	}
	if (!parse_decl(ri->world ? ri->world : ri->perm, par->token, true, d)) {
		err(ri, par->loc, "%s: bad inline declaration '%s' (expected [class] type [n] name)",
		    req, par->token);
		return false;
	}
	*has_decl = true;
	*name = d->name;
	return true;
}

static const char *type_desc(struct ri *ri, int type, uint32_t arraylen)
{
	if (arraylen)
		return rl_arena_printf(ri->perm, "%s[%u]", sl_basetype_name(type), arraylen);
	return sl_basetype_name(type);
}

/* ---- options ------------------------------------------------------------------------- */

static void options_init(struct ri *ri, struct optstate *s)
{
	*s = (struct optstate){0};
	struct reyes_options *o = &s->o;
	o->xres = 640;
	o->yres = 480;
	o->pixel_aspect = 1;
	o->crop[1] = o->crop[3] = 1;
	o->fov = 90;
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
	sl_m44_identity(o->world_to_camera);
	sl_m44_identity(o->camera_to_screen);
}

/* Would this request change an option? They must come before WorldBegin. */
static bool option_ok(struct ri *ri, const struct rib_request *r)
{
	if (!ri->world)
		return true;
	err(ri, r->loc, "%s is an option: it must come before WorldBegin", r->name);
	return false;
}

static void req_format(struct ri *ri, const struct rib_request *r)
{
	double x, y, a;
	if (!option_ok(ri, r) || !num_arg(ri, r, 0, &x) || !num_arg(ri, r, 1, &y) ||
	    !num_arg(ri, r, 2, &a))
		return;
	if (!(x >= 1 && x <= MAX_RESOLUTION && y >= 1 && y <= MAX_RESOLUTION)) {
		err(ri, r->loc, "Format: resolution %gx%g out of range (1 to %d)", x, y,
		    MAX_RESOLUTION);
		return;
	}
	if (a == 0 || !(fabs(a) <= 1e6)) {
		err(ri, r->loc, "Format: bad pixel aspect ratio %g", a);
		return;
	}
	ri->opt.o.xres = (uint32_t)x;
	ri->opt.o.yres = (uint32_t)y;
	/* A negative aspect ratio keeps the current one. */
	if (a > 0)
		ri->opt.o.pixel_aspect = (float)a;
}

static void req_frame_aspect(struct ri *ri, const struct rib_request *r)
{
	float a;
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 1, &a))
		return;
	if (!(a > 0)) {
		err(ri, r->loc, "FrameAspectRatio must be positive, got %g", a);
		return;
	}
	ri->opt.o.frame_aspect = a;
}

static void req_screen_window(struct ri *ri, const struct rib_request *r)
{
	float s[4];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 4, s))
		return;
	if (s[0] == s[1] || s[2] == s[3]) {
		err(ri, r->loc, "ScreenWindow %g %g %g %g is empty", s[0], s[1], s[2], s[3]);
		return;
	}
	memcpy(ri->opt.o.screen, s, sizeof(s));
	ri->opt.o.screen_set = true;
}

static void req_crop_window(struct ri *ri, const struct rib_request *r)
{
	float c[4];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 4, c))
		return;
	for (int i = 0; i < 4; i++)
		c[i] = sl_clampf(c[i], 0, 1);
	if (!(c[0] < c[1] && c[2] < c[3])) {
		err(ri, r->loc, "CropWindow %g %g %g %g is empty", c[0], c[1], c[2], c[3]);
		return;
	}
	memcpy(ri->opt.o.crop, c, sizeof(c));
}

static bool is_identity(const float m[16])
{
	float id[16];
	sl_m44_identity(id);
	return memcmp(m, id, sizeof(id)) == 0;
}

static void req_projection(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &name))
		return;
	struct reyes_options *o = &ri->opt.o;
	if (strcmp(name, "perspective") == 0) {
		float fov = 90;
		for (uint32_t i = 0; i < r->nparams; i++) {
			const struct rib_param *p = &r->params[i];
			struct decl d;
			bool has;
			const char *pname;
			if (!param_token(ri, p, r->name, &d, &has, &pname))
				return;
			if (strcmp(pname, "fov") != 0) {
				warn(ri, p->loc, "Projection: unknown parameter '%s' ignored", pname);
				continue;
			}
			if (!is_numbers(&p->value) || p->value.n != 1)
				FAIL(ri, p->loc, "Projection: \"fov\" takes one number");
			if (!value_floats(ri, &p->value, p->loc, "fov", &fov))
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
			warn(ri, r->params[i].loc, "Projection: unknown parameter '%s' ignored",
			     r->params[i].token);
	} else {
		FAIL(ri, r->loc,
			   "unsupported projection '%s' (use \"perspective\" or \"orthographic\")",
			   name);
	}
	ri->opt.projection_given = true;
	/* RISpec: Projection marks camera space; the current transformation restarts. */
	if (!is_identity(ri->gs.x.m[0]) || ri->gs.x.moving)
		warn(ri, r->loc, "transformations before Projection are ignored");
	sl_m44_identity(ri->gs.x.m[0]);
	sl_m44_identity(ri->gs.x.m[1]);
	ri->gs.x.moving = false;
	ri->gs.bundle = NULL;
}

static void req_clipping(struct ri *ri, const struct rib_request *r)
{
	float c[2];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 2, c))
		return;
	if (!(c[0] > 0 && c[1] > c[0])) {
		err(ri, r->loc, "Clipping %g %g: need 0 < near < far", c[0], c[1]);
		return;
	}
	ri->opt.o.clip_near = c[0];
	ri->opt.o.clip_far = c[1];
}

static void req_shutter(struct ri *ri, const struct rib_request *r)
{
	float s[2];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 2, s))
		return;
	if (s[1] < s[0]) {
		err(ri, r->loc, "Shutter %g %g closes before it opens", s[0], s[1]);
		return;
	}
	memcpy(ri->opt.o.shutter, s, sizeof(s));
}

static void req_pixel_samples(struct ri *ri, const struct rib_request *r)
{
	float s[2];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 2, s))
		return;
	if (!(s[0] >= 1 && s[1] >= 1 && s[0] <= MAX_PIXEL_SAMPLES && s[1] <= MAX_PIXEL_SAMPLES)) {
		err(ri, r->loc, "PixelSamples %g %g out of range (1 to %d)", s[0], s[1],
		    MAX_PIXEL_SAMPLES);
		return;
	}
	ri->opt.o.xsamples = (uint32_t)s[0];
	ri->opt.o.ysamples = (uint32_t)s[1];
}

static void req_pixel_filter(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	float w[2];
	enum reyes_filter f;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &name) || !float_args(ri, r, 1, 2, w))
		return;
	if (!reyes_filter_from_name(name, &f)) {
		err(ri, r->loc, "unknown pixel filter '%s'", name);
		return;
	}
	if (!(w[0] > 0 && w[1] > 0 && w[0] <= 64 && w[1] <= 64)) {
		err(ri, r->loc, "PixelFilter widths %g %g out of range (0 to 64)", w[0], w[1]);
		return;
	}
	ri->opt.o.filter = f;
	memcpy(ri->opt.o.filter_width, w, sizeof(w));
}

static void req_exposure(struct ri *ri, const struct rib_request *r)
{
	float e[2];
	if (!option_ok(ri, r) || !float_args(ri, r, 0, 2, e))
		return;
	if (!(e[1] > 0)) {
		err(ri, r->loc, "Exposure: gamma must be positive, got %g", e[1]);
		return;
	}
	ri->opt.o.gain = e[0];
	ri->opt.o.gamma = e[1];
}

static void req_quantize(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	double one;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &type) || !num_arg(ri, r, 1, &one))
		return;
	if (strcmp(type, "rgba") == 0)
		ri->opt.quantize_float = one == 0;
	else if (strcmp(type, "z") != 0)
		warn(ri, r->loc, "Quantize: unknown type '%s' ignored", type);
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

static void req_display(struct ri *ri, const struct rib_request *r)
{
	const char *name, *type, *mode;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &name) || !str_arg(ri, r, 1, &type) ||
	    !str_arg(ri, r, 2, &mode))
		return;
	bool add = name[0] == '+';
	if (add)
		name++;
	if (!*name)
		FAIL(ri, r->loc, "Display: empty file name");
	bool depth = strcmp(type, "zfile") == 0 || strcmp(type, "shadow") == 0;
	static const char *const modes[] = {"rgba", "rgb", "a", "z", "rgbaz"};
	const char *m = NULL;
	for (size_t i = 0; i < sizeof(modes) / sizeof(modes[0]); i++)
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
	bool half = !depth && strcmp(m, "z") != 0;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		if (strcmp(pname, "quantize") == 0) {
			bool zero = is_numbers(v) && v->n > 0;
			for (uint32_t k = 0; zero && k < v->n; k++)
				zero = v->nums[k] == 0;
			if (zero || (!is_numbers(v) && v->n == 1 && strcmp(v->strs[0], "float") == 0))
				half = false;
		} else if (strcmp(pname, "type") == 0 && !is_numbers(v) && v->n == 1) {
			if (strcmp(v->strs[0], "float") == 0)
				half = false;
			else if (strcmp(v->strs[0], "half") == 0)
				half = !depth;
			else
				warn(ri, p->loc, "Display: unknown data type '%s' ignored", v->strs[0]);
		} else {
			warn(ri, p->loc, "Display: unknown parameter '%s' ignored", pname);
		}
	}
	struct reyes_options *o = &ri->opt.o;
	uint32_t keep = add ? o->ndisplays : 0;
	if (keep >= MAX_DISPLAYS)
		FAIL(ri, r->loc, "too many displays (limit %d)", MAX_DISPLAYS);
	struct reyes_display *ds = rl_arena_alloc(ri->perm, sizeof(*ds) * (keep + 1));
	if (keep)
		memcpy(ds, o->displays, sizeof(*ds) * keep);
	struct rib_loc loc = keep_loc(ri, r->loc);
	ds[keep] = (struct reyes_display){
		.name = rl_arena_strdup(ri->perm, name),
		.type = rl_arena_strdup(ri->perm, type),
		.mode = m,
		.half = half,
		.file = loc.file,
		.line = loc.line,
	};
	o->displays = ds;
	o->ndisplays = keep + 1;
}

static void req_hider(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &type))
		return;
	if (strcmp(type, "hidden") != 0) {
		warn(ri, r->loc, "Hider '%s' is not supported: using \"hidden\"", type);
		return;
	}
	struct reyes_options *o = &ri->opt.o;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		if (strcmp(pname, "depthfilter") == 0) {
			static const char *const names[] = {"min", "max", "average", "midpoint"};
			int k = -1;
			for (int j = 0; j < 4 && !is_numbers(v) && v->n == 1; j++)
				if (strcmp(v->strs[0], names[j]) == 0)
					k = j;
			if (k < 0)
				FAIL(ri, p->loc,
					   "Hider: \"depthfilter\" must be \"min\", \"max\", "
					   "\"average\" or \"midpoint\"");
			o->depthfilter = (enum reyes_depthfilter)k;
		} else if (strcmp(pname, "jitter") == 0) {
			if (!is_numbers(v) || v->n != 1)
				FAIL(ri, p->loc, "Hider: \"jitter\" takes one number");
			o->jitter = v->nums[0] != 0;
		} else {
			warn(ri, p->loc, "Hider: unknown parameter '%s' ignored", pname);
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

static void req_option(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!option_ok(ri, r) || !str_arg(ri, r, 0, &name))
		return;
	if (strcmp(name, "searchpath") != 0) {
		warn(ri, r->loc, "unknown option '%s' ignored", name);
		return;
	}
	struct reyes_options *o = &ri->opt.o;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!param_token(ri, p, r->name, &d, &has, &pname))
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
		} else {
			warn(ri, p->loc, "unknown option 'searchpath' '%s' ignored", pname);
			continue;
		}
		if (is_numbers(&p->value) || p->value.n != 1) {
			err(ri, p->loc, "Option \"searchpath\" \"%s\" takes one string", pname);
			continue;
		}
		*slot = expand_path(ri, p->value.strs[0], *slot, dflt);
	}
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
	memcpy(a->ubasis, bezier, sizeof(bezier));
	memcpy(a->vbasis, bezier, sizeof(bezier));
	a->ustep = a->vstep = 3;
}

static void xform_init(struct xform *x)
{
	sl_m44_identity(x->m[0]);
	sl_m44_identity(x->m[1]);
	x->moving = false;
}

static struct rl_arena *cur_arena(struct ri *ri)
{
	return ri->world ? ri->world : ri->perm;
}

static void attrs_changed(struct ri *ri)
{
	ri->gs.bundle = NULL;
}

static void set_xform(struct ri *ri, const float m0[16], const float m1[16])
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

/* A bundle of the current attributes with transformation @x. */
static const struct reyes_attrs *make_bundle(struct ri *ri, const struct xform *x)
{
	const struct attrstate *a = &ri->gs.a;
	struct reyes_attrs *b = rl_arena_alloc(ri->world, sizeof(*b));
	ri->gs.own_lights = NULL;       /* the bundle shares the light set */
	memcpy(b->Cs, a->Cs, sizeof(b->Cs));
	memcpy(b->Os, a->Os, sizeof(b->Os));
	b->surface = a->surface;
	b->displacement = a->displacement;
	b->lights = a->lights;
	b->nlights = a->nlights;
	b->sides = a->sides;
	b->flip_normals = a->inside;
	b->shading_rate = a->shading_rate;
	b->smooth = a->smooth;
	b->identifier = a->identifier;
	b->displacement_bound = a->dbound;
	b->displacement_bound_space = a->dbound_space;
	b->casts_shadows = a->casts_shadows;
	b->moving = x->moving;
	memcpy(b->object_to_world, x->m, sizeof(b->object_to_world));
	return b;
}

static const struct reyes_attrs *cur_bundle(struct ri *ri)
{
	if (!ri->gs.bundle)
		ri->gs.bundle = make_bundle(ri, &ri->gs.x);
	return ri->gs.bundle;
}

static void req_color(struct ri *ri, const struct rib_request *r)
{
	float c[3];
	if (!float_args(ri, r, 0, 3, c))
		return;
	memcpy(strcmp(r->name, "Color") == 0 ? ri->gs.a.Cs : ri->gs.a.Os, c, sizeof(c));
	attrs_changed(ri);
}

static void req_sides(struct ri *ri, const struct rib_request *r)
{
	double n;
	if (!num_arg(ri, r, 0, &n))
		return;
	if (n != 1 && n != 2)
		FAIL(ri, r->loc, "Sides must be 1 or 2, got %g", n);
	ri->gs.a.sides = (int)n;
	attrs_changed(ri);
}

static void req_orientation(struct ri *ri, const struct rib_request *r)
{
	const char *o;
	if (!str_arg(ri, r, 0, &o))
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
	attrs_changed(ri);
}

static void req_reverse_orientation(struct ri *ri, const struct rib_request *r)
{
	(void)r;
	ri->gs.a.inside = !ri->gs.a.inside;
	attrs_changed(ri);
}

static void req_shading_rate(struct ri *ri, const struct rib_request *r)
{
	float s;
	if (!float_args(ri, r, 0, 1, &s))
		return;
	if (!(s > 0))
		FAIL(ri, r->loc, "ShadingRate must be positive, got %g", s);
	ri->gs.a.shading_rate = s;
	attrs_changed(ri);
}

static void req_shading_interpolation(struct ri *ri, const struct rib_request *r)
{
	const char *s;
	if (!str_arg(ri, r, 0, &s))
		return;
	if (strcmp(s, "smooth") == 0)
		ri->gs.a.smooth = true;
	else if (strcmp(s, "constant") == 0)
		ri->gs.a.smooth = false;
	else
		FAIL(ri, r->loc,
			   "ShadingInterpolation must be \"constant\" or \"smooth\", got '%s'", s);
	attrs_changed(ri);
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
		return err(ri, r->loc, "Basis: missing argument %u", i + 1), false;
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
		err(ri, v->loc,
		    "unknown basis '%s' (bezier, b-spline, catmull-rom, hermite, power or 16 "
		    "numbers)", name);
		return false;
	}
	if (v->n != 16)
		return err(ri, v->loc, "Basis: a basis matrix has 16 numbers, got %u", v->n), false;
	return value_floats(ri, v, v->loc, "Basis", m);
}

static void req_basis(struct ri *ri, const struct rib_request *r)
{
	float ub[16], vb[16];
	double us, vs;
	if (!basis_arg(ri, r, 0, ub) || !num_arg(ri, r, 1, &us) || !basis_arg(ri, r, 2, vb) ||
	    !num_arg(ri, r, 3, &vs))
		return;
	if (!(us >= 1 && us <= 16 && vs >= 1 && vs <= 16))
		FAIL(ri, r->loc, "Basis: steps %g %g out of range (1 to 16)", us, vs);
	memcpy(ri->gs.a.ubasis, ub, sizeof(ub));
	memcpy(ri->gs.a.vbasis, vb, sizeof(vb));
	ri->gs.a.ustep = (uint32_t)us;
	ri->gs.a.vstep = (uint32_t)vs;
}

static void req_attribute(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!str_arg(ri, r, 0, &name))
		return;
	bool identifier = strcmp(name, "identifier") == 0;
	bool dbound = strcmp(name, "displacementbound") == 0;
	bool visibility = strcmp(name, "visibility") == 0;
	if (!identifier && !dbound && !visibility) {
		warn(ri, r->loc, "unknown attribute '%s' ignored", name);
		return;
	}
	struct attrstate *a = &ri->gs.a;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *pname;
		if (!param_token(ri, p, r->name, &d, &has, &pname))
			return;
		const struct rib_value *v = &p->value;
		bool str1 = !is_numbers(v) && v->n == 1, num1 = is_numbers(v) && v->n == 1;
		if (identifier && strcmp(pname, "name") == 0 && str1) {
			a->identifier = rl_arena_strdup(cur_arena(ri), v->strs[0]);
		} else if (dbound && strcmp(pname, "sphere") == 0 && num1) {
			if (!(v->nums[0] >= 0 && v->nums[0] <= FLT_MAX))
				FAIL(ri, p->loc, "displacementbound: bad sphere %g", v->nums[0]);
			a->dbound = (float)v->nums[0];
		} else if (dbound && strcmp(pname, "coordinatesystem") == 0 && str1) {
			a->dbound_space = rl_arena_strdup(cur_arena(ri), v->strs[0]);
		} else if (visibility && strcmp(pname, "transmission") == 0 && (num1 || str1)) {
			/* Numbers 0/1, or the older strings "opaque", "transparent", "Os", "shader". */
			a->casts_shadows = num1 ? v->nums[0] != 0 : strcmp(v->strs[0], "transparent") != 0;
		} else if (visibility && (strcmp(pname, "camera") == 0 || strcmp(pname, "diffuse") == 0 ||
					  strcmp(pname, "specular") == 0 || strcmp(pname, "photon") == 0)) {
			/* Everything is seen by the camera; no ray tracing. */
		} else {
			warn(ri, p->loc, "unknown attribute '%s' '%s' ignored", name, pname);
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
		if (r->nargs < 1 || !is_numbers(&r->args[0]) || r->args[0].n != 16)
			return err(ri, r->loc, "%s needs 16 numbers", n), false;
		return value_floats(ri, &r->args[0], r->loc, n, m);
	}
	float v[7];
	if (strcmp(n, "Translate") == 0) {
		if (!float_args(ri, r, 0, 3, v))
			return false;
		sl_m44_translation(m, v);
	} else if (strcmp(n, "Rotate") == 0) {
		if (!float_args(ri, r, 0, 4, v))
			return false;
		if (v[1] == 0 && v[2] == 0 && v[3] == 0)
			return err(ri, r->loc, "Rotate: the axis is zero"), false;
		sl_m44_rotation(m, v[0] * (PI_F / 180), v + 1);
	} else if (strcmp(n, "Scale") == 0) {
		if (!float_args(ri, r, 0, 3, v))
			return false;
		sl_m44_scaling(m, v);
	} else if (strcmp(n, "Skew") == 0) {
		if (!float_args(ri, r, 0, 7, v))
			return false;
		if (!skew_matrix(m, v[0], v + 1, v + 4))
			return err(ri, r->loc,
				   "Skew: the angle %g is not less than the angle between the axes "
				   "(or an axis is zero)", v[0]), false;
	} else {
		return false;
	}
	return true;
}

static void motion_xform(struct ri *ri, const struct rib_request *r, const float m[16], bool set);

static void req_xform(struct ri *ri, const struct rib_request *r)
{
	float m[16];
	bool set;
	if (!xform_of(ri, r, m, &set))
		return;
	if (ri->motion.active) {
		motion_xform(ri, r, m, set);
		return;
	}
	if (set) {
		set_xform(ri, m, m);
		return;
	}
	float m0[16], m1[16];
	sl_m44_mul(m0, m, ri->gs.x.m[0]);
	sl_m44_mul(m1, m, ri->gs.x.m[1]);
	set_xform(ri, m0, m1);
}

static void req_coordinate_system(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!str_arg(ri, r, 0, &name))
		return;
	static const char *const builtin[] = {"object", "world", "camera", "screen", "raster",
					      "NDC", "shader", "current"};
	for (size_t i = 0; i < sizeof(builtin) / sizeof(builtin[0]); i++)
		if (strcmp(name, builtin[i]) == 0)
			FAIL(ri, r->loc, "CoordinateSystem: '%s' is a predefined space", name);
	bool w = ri->world != NULL;
	struct rl_arena *a = cur_arena(ri);
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
	if (!str_arg(ri, r, 0, &name))
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
		set_xform(ri, m, m);
	else
		err(ri, r->loc, "unknown coordinate system '%s'", name);
}

/* ---- blocks ----------------------------------------------------------------------------- */

static void push_block(struct ri *ri, const struct rib_request *r, enum blk kind)
{
	struct block b = {
		.kind = kind,
		.loc = keep_loc(ri, r->loc),
		.file_depth = (uint32_t)ri->files.len,
		.gs = ri->gs,
		.opt = ri->opt,
	};
	/* The saved state and the live one share the light set now. */
	b.gs.own_lights = NULL;
	ri->gs.own_lights = NULL;
	rl_vec_push(ri->blocks, b);
}

static bool depth_ok(struct ri *ri, const struct rib_request *r)
{
	if (ri->blocks.len < MAX_BLOCK_DEPTH)
		return true;
	err(ri, r->loc, "%s: blocks nested too deeply (limit %d)", r->name, MAX_BLOCK_DEPTH);
	return false;
}

static const struct block *find_block(const struct ri *ri, enum blk kind)
{
	for (size_t i = ri->blocks.len; i-- > 0;)
		if (ri->blocks.data[i].kind == kind)
			return &ri->blocks.data[i];
	return NULL;
}

static void world_end(struct ri *ri, bool render);
static void motion_end(struct ri *ri, bool apply);
static void object_end(struct ri *ri);

/* Pops the innermost block, restoring what it saved. @ok: it was closed properly. */
static void pop_block(struct ri *ri, bool ok)
{
	struct block b = ri->blocks.data[--ri->blocks.len];
	switch (b.kind) {
	case BLK_FRAME:
		ri->gs = b.gs;
		ri->opt = b.opt;
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
		motion_end(ri, ok);
		break;
	case BLK_OBJECT:
		object_end(ri);
		ri->gs = b.gs;
		break;
	}
}

/* The end of a block of @kind: it must close the innermost open block. */
static bool close_block(struct ri *ri, const struct rib_request *r, enum blk kind)
{
	if (!ri->blocks.len) {
		err(ri, r->loc, "%s without a matching %s", r->name, blk_begin[kind]);
		return false;
	}
	const struct block *b = &ri->blocks.data[ri->blocks.len - 1];
	if (b->kind != kind) {
		err(ri, r->loc, "%s at line %u does not close the %s at %s", r->name,
		    (unsigned)r->loc.line, blk_begin[b->kind], where(ri, b->loc, r->loc));
		return false;
	}
	if (b->file_depth != ri->files.len) {
		err(ri, r->loc, "%s closes the %s at %s, opened in another file", r->name,
		    blk_begin[kind], where(ri, b->loc, r->loc));
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
		err(ri, at, "the file ends inside the %s at %s", blk_begin[b->kind],
		    where(ri, b->loc, at));
		pop_block(ri, false);
	}
}

static void req_frame_begin(struct ri *ri, const struct rib_request *r)
{
	const struct block *b = find_block(ri, BLK_FRAME);
	if (b)
		FAIL(ri, r->loc, "FrameBegin inside the FrameBegin at %s",
			   where(ri, b->loc, r->loc));
	if (ri->world)
		FAIL(ri, r->loc, "FrameBegin inside a world block");
	if (depth_ok(ri, r))
		push_block(ri, r, BLK_FRAME);
}

static void req_frame_end(struct ri *ri, const struct rib_request *r)
{
	close_block(ri, r, BLK_FRAME);
}

static void req_attribute_begin(struct ri *ri, const struct rib_request *r)
{
	if (depth_ok(ri, r))
		push_block(ri, r, strcmp(r->name, "AttributeBegin") == 0 ? BLK_ATTRIBUTE
									 : BLK_TRANSFORM);
}

static void req_attribute_end(struct ri *ri, const struct rib_request *r)
{
	close_block(ri, r, strcmp(r->name, "AttributeEnd") == 0 ? BLK_ATTRIBUTE : BLK_TRANSFORM);
}

static void req_world_begin(struct ri *ri, const struct rib_request *r)
{
	if (ri->world)
		FAIL(ri, r->loc, "WorldBegin inside the WorldBegin at %s",
			   where(ri, find_block(ri, BLK_WORLD)->loc, r->loc));
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "WorldBegin inside an object definition");
	if (!depth_ok(ri, r))
		return;
	struct reyes_options *o = &ri->opt.o;
	if (ri->gs.x.moving)
		warn(ri, r->loc, "camera motion is not supported: using the shutter-open camera");
	memcpy(o->world_to_camera, ri->gs.x.m[0], sizeof(o->world_to_camera));
	if (!sl_m44_inverse(ri->w2c_inv, o->world_to_camera))
		err(ri, r->loc, "the camera transformation is singular");
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

	push_block(ri, r, BLK_WORLD);
	ri->world = rl_arena_create();
	/* Spaces named before WorldBegin, now relative to world. */
	for (size_t i = 0; i < ri->pre_spaces.len; i++) {
		struct space s = {.name = ri->pre_spaces.data[i].name};
		sl_m44_mul(s.m, ri->pre_spaces.data[i].m, ri->w2c_inv);
		rl_vec_push(ri->spaces, s);
		strmap_put(&ri->space_index, s.name, ri->spaces.len);
	}
	xform_init(&ri->gs.x);
	ri->gs.bundle = NULL;
}

static void req_world_end(struct ri *ri, const struct rib_request *r)
{
	close_block(ri, r, BLK_WORLD);
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

/* The compiled shader @name (compiled once per read), or NULL (reported). */
static struct sl_program *load_shader(struct ri *ri, const struct rib_request *r,
				      const char *name)
{
	size_t len = strlen(name);
	bool has_ext = len > 3 && strcmp(name + len - 3, ".sl") == 0;
	const char *file = has_ext ? name : rl_arena_printf(ri->perm, "%s.sl", name);
	const char *path = search_file(ri, file, NULL, ri->opt.o.shader_path);
	if (!path) {
		err(ri, r->loc, "cannot find shader '%s' (searched: %s)", name,
		    ri->opt.o.shader_path);
		return NULL;
	}
	uintptr_t v;
	if (strmap_get(&ri->shader_cache, path, &v)) {
		if (!v)
			err(ri, r->loc, "shader '%s' (%s) did not compile", name, path);
		return (struct sl_program *)v;
	}
	forward_reader_diag(ri);
	struct sl_options so = {.diag = ri->diag, .max_errors = ri->max_errors};
	struct sl_program *prog = sl_compile_file(path, &so);
	strmap_put(&ri->shader_cache, path, (uintptr_t)prog);
	if (!prog) {
		err(ri, r->loc, "shader '%s' (%s) did not compile", name, path);
		return NULL;
	}
	rl_vec_push(ri->progs, prog);
	return prog;
}

static bool same_type(const struct decl *d, int base, uint32_t arraylen)
{
	return !d->hpoint && d->type == base && d->arraylen == arraylen;
}

/* The parameter list of a shader request as typed values of @prog's parameters. */
static bool shader_params(struct ri *ri, const struct rib_request *r, const char *shname,
			  const struct sl_program *prog, struct reyes_shader *sh)
{
	struct rl_arena *a = cur_arena(ri);
	struct reyes_param_value *vals = rl_arena_alloc(a, sizeof(*vals) * (r->nparams + 1));
	bool *seen = rl_xcalloc(prog->nparams + 1, sizeof(bool));
	uint32_t n = 0;
	bool ok = true;
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		bool has;
		const char *name;
		if (!param_token(ri, p, r->name, &d, &has, &name)) {
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
			err(ri, p->loc, "shader '%s' has no parameter '%s'", shname, name);
			ok = false;
			continue;
		}
		const struct sl_param *sp = &prog->params[pi];
		int base = sp->type.base;
		uint32_t alen = sp->type.arraylen > 0 ? (uint32_t)sp->type.arraylen : 0;
		if (has && !same_type(&d, base, alen)) {
			err(ri, p->loc, "parameter '%s' of shader '%s' is %s, but it is given as %s%s",
			    name, shname, type_desc(ri, base, alen),
			    d.hpoint ? "hpoint" : type_desc(ri, d.type, 0),
			    d.arraylen ? rl_arena_printf(ri->perm, "[%u]", d.arraylen) : "");
			ok = false;
			continue;
		}
		if (seen[pi]) {
			err(ri, p->loc, "parameter '%s' of shader '%s' is given twice", name, shname);
			ok = false;
			continue;
		}
		seen[pi] = true;
		struct reyes_param_value *pv = &vals[n];
		*pv = (struct reyes_param_value){.name = name, .type = base, .arraylen = alen};
		uint32_t count = alen ? alen : 1;
		if (base == SL_TYPE_STRING) {
			if (is_numbers(&p->value) || p->value.n != count) {
				err(ri, p->loc, "parameter '%s' of shader '%s' needs %u string%s", name,
				    shname, count, count == 1 ? "" : "s");
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
			if (!is_numbers(&p->value) || p->value.n != want) {
				if (is_numbers(&p->value))
					err(ri, p->loc,
					    "parameter '%s' of shader '%s' needs %u value%s, got %u",
					    name, shname, want, want == 1 ? "" : "s", p->value.n);
				else
					err(ri, p->loc,
					    "parameter '%s' of shader '%s' needs %u number%s, got a string",
					    name, shname, want, want == 1 ? "" : "s");
				ok = false;
				continue;
			}
			float *f = rl_arena_alloc(a, sizeof(float) * want);
			if (!value_floats(ri, &p->value, p->loc, name, f)) {
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

/* A shader instance for a Surface, Displacement or LightSource request. */
static struct reyes_shader *make_shader(struct ri *ri, const struct rib_request *r,
					enum sl_shader_kind want)
{
	const char *name;
	if (!str_arg(ri, r, 0, &name))
		return NULL;
	struct sl_program *prog = load_shader(ri, r, name);
	if (!prog)
		return NULL;
	enum sl_shader_kind kind = sl_program_kind(prog);
	if (kind != want) {
		err(ri, r->loc, "%s needs a %s shader, but '%s' is a %s shader", r->name,
		    sl_shader_kind_name(want), name, sl_shader_kind_name(kind));
		return NULL;
	}
	struct reyes_shader *sh = rl_arena_alloc(cur_arena(ri), sizeof(*sh));
	sh->name = rl_arena_strdup(cur_arena(ri), name);
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
	attrs_changed(ri);
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
		uint32_t *l = rl_arena_alloc(ri->world, sizeof(uint32_t) * cap);
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

static void req_light_source(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "LightSource inside an object definition");
	struct reyes_shader *sh = make_shader(ri, r, SL_SHADER_LIGHT);
	if (!sh)
		return;
	const char *handle = r->nargs > 1 ? handle_arg(ri, r, 1, ri->world)
					  : rl_arena_printf(ri->world, "%zu", ri->lights.len + 1);
	if (!handle)
		return;
	uint32_t index = (uint32_t)ri->lights.len;
	struct reyes_light l = {.shader = *sh, .handle = handle, .default_on = true,
				.index = index};
	rl_vec_push(ri->lights, l);
	strmap_put(&ri->light_index, handle, index + 1);
	set_light(ri, index, true);
}

static void req_illuminate(struct ri *ri, const struct rib_request *r)
{
	const char *handle = handle_arg(ri, r, 0, ri->world);
	double on;
	if (!handle || !num_arg(ri, r, 1, &on))
		return;
	uintptr_t k;
	if (!strmap_get(&ri->light_index, handle, &k))
		FAIL(ri, r->loc, "Illuminate: unknown light '%s'", handle);
	ri->lights.data[k - 1].default_on = on != 0;
	set_light(ri, (uint32_t)(k - 1), on != 0);
}

static void req_declare(struct ri *ri, const struct rib_request *r)
{
	const char *name, *decl;
	if (!str_arg(ri, r, 0, &name) || !str_arg(ri, r, 1, &decl))
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

/* Standard primitive variables (RISpec), typed when no declaration says otherwise. */
static const struct {
	const char *name;
	struct decl d;
} std_vars[] = {
	{"P", {.cls = REYES_VERTEX, .type = SL_TYPE_POINT}},
	{"Pw", {.cls = REYES_VERTEX, .type = SL_TYPE_POINT, .hpoint = true}},
	{"N", {.cls = REYES_VARYING, .type = SL_TYPE_NORMAL}},
	{"Cs", {.cls = REYES_VARYING, .type = SL_TYPE_COLOR}},
	{"Os", {.cls = REYES_VARYING, .type = SL_TYPE_COLOR}},
	{"s", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT}},
	{"t", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT}},
	{"st", {.cls = REYES_VARYING, .type = SL_TYPE_FLOAT, .arraylen = 2}},
};

/* The type of a primitive variable: inline declaration, Declare, or standard. */
static bool var_decl(struct ri *ri, const struct rib_request *r, const struct rib_param *p,
		     struct decl *d, const char **name)
{
	bool has;
	if (!param_token(ri, p, r->name, d, &has, name))
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
	err(ri, p->loc, "%s: unknown primitive variable '%s' (declare it with Declare or an "
	    "inline type)", r->name, *name);
	return false;
}

/* Floats per item of a declared type. */
static uint32_t decl_ncomp(const struct decl *d)
{
	uint32_t c = d->hpoint ? 4 : (uint32_t)sl_type_ncomp(d->type);
	return c * (d->arraylen ? d->arraylen : 1);
}

/* The number of points "P" (or "Pw") gives; false (reported) when missing or uneven. */
static bool point_count(struct ri *ri, const struct rib_request *r, uint32_t *np)
{
	for (uint32_t i = 0; i < r->nparams; i++) {
		const struct rib_param *p = &r->params[i];
		struct decl d;
		const char *name;
		if (!var_decl(ri, r, p, &d, &name))
			return false;
		if (strcmp(name, "P") != 0 && strcmp(name, "Pw") != 0)
			continue;
		uint32_t c = decl_ncomp(&d);
		if (d.cls != REYES_VERTEX || d.type != SL_TYPE_POINT || d.arraylen ||
		    (strcmp(name, "Pw") == 0) != d.hpoint) {
			err(ri, p->loc, "%s: \"%s\" must be a vertex %s", r->name, name,
			    d.hpoint ? "hpoint" : "point");
			return false;
		}
		if (!is_numbers(&p->value) || p->value.n % c) {
			err(ri, p->loc, "%s: \"%s\" has %u values, not a multiple of %u", r->name,
			    name, p->value.n, c);
			return false;
		}
		*np = p->value.n / c;
		return true;
	}
	err(ri, r->loc, "%s needs \"P\"", r->name);
	return false;
}

/*
 * The primitive variables of @r's parameter list into @p, each checked
 * against the count of its class: sizes[class] items.
 */
static bool prim_vars(struct ri *ri, const struct rib_request *r, const uint32_t sizes[5],
		      bool points, struct reyes_prim *p)
{
	struct rl_arena *a = cur_arena(ri);
	if (r->nparams > MAX_PRIMVARS) {
		err(ri, r->loc, "%s: too many primitive variables (limit %d)", r->name,
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
		if (!var_decl(ri, r, par, &d, &name))
			return false;
		if (d.type == SL_TYPE_STRING) {
			warn(ri, par->loc, "%s: string primitive variable '%s' ignored", r->name, name);
			continue;
		}
		bool is_P = strcmp(name, "P") == 0 || strcmp(name, "Pw") == 0;
		if (is_P && !points) {
			err(ri, par->loc, "%s does not take \"%s\"", r->name, name);
			return false;
		}
		uint32_t per = decl_ncomp(&d);
		uint64_t want = (uint64_t)sizes[d.cls] * per;
		if (!is_numbers(&par->value) || par->value.n != want) {
			err(ri, par->loc, "%s: primitive variable \"%s\" (%s %s%s) needs %llu values, "
			    "got %u%s", r->name, name, class_names[d.cls],
			    d.hpoint ? "hpoint" : sl_basetype_name(d.type),
			    d.arraylen ? rl_arena_printf(ri->perm, "[%u]", d.arraylen) : "",
			    (unsigned long long)want, par->value.n,
			    is_numbers(&par->value) ? "" : " strings");
			return false;
		}
		float *f = rl_arena_alloc(a, sizeof(float) * (want ? want : 1));
		if (!value_floats(ri, &par->value, par->loc, name, f))
			return false;
		uint32_t count = sizes[d.cls];
		if (d.hpoint) {
			/* To points: divide by w. */
			uint32_t items = count * (d.arraylen ? d.arraylen : 1);
			for (uint32_t k = 0; k < items; k++) {
				float w = f[4 * k + 3];
				if (w == 0) {
					err(ri, par->loc, "%s: \"%s\" point %u has w = 0", r->name, name, k);
					return false;
				}
				for (int c = 0; c < 3; c++)
					f[3 * k + c] = f[4 * k + c] / w;
			}
			if (strcmp(name, "Pw") == 0)
				name = "P";
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
			err(ri, par->loc, "%s: \"%s\" must be %s", r->name, name, std_type);
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
		for (int j = 0; j < 2 && names[j]; j++) {
			for (uint32_t k = 0; k < n; k++)
				if (strcmp(vars[k].name, names[j]) == 0) {
					err(ri, par->loc, "%s: primitive variable \"%s\" is given twice",
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
		err(ri, r->loc, "%s needs \"P\"", r->name);
		return false;
	}
	p->vars = vars;
	p->nvars = n;
	return true;
}

static struct reyes_prim *new_prim(struct ri *ri, enum reyes_prim_kind kind)
{
	struct reyes_prim *p = rl_arena_alloc(cur_arena(ri), sizeof(*p));
	p->kind = kind;
	return p;
}

/* Can a primitive go here? Inside the world, or into an object definition. */
static bool geometry_ok(struct ri *ri, const struct rib_request *r)
{
	if (ri->world || ri->objdef >= 0)
		return true;
	err(ri, r->loc, "%s outside WorldBegin/WorldEnd", r->name);
	return false;
}

/* Adds a finished primitive to the world or to the object being defined. */
static void add_prim(struct ri *ri, struct reyes_prim *p, const struct xform *x)
{
	if (ri->objdef >= 0) {
		struct obj_prim op = {.p = p};
		for (int k = 0; k < 2; k++)
			sl_m44_mul(op.rel[k], x->m[k], ri->objdef_inv[k]);
		op.identity = is_identity(op.rel[0]) && is_identity(op.rel[1]);
		rl_vec_push(ri->objects.data[ri->objdef].prims, op);
		return;
	}
	struct reyes_prim q = *p;
	q.attrs = x == &ri->gs.x ? cur_bundle(ri) : make_bundle(ri, x);
	q.id = (uint32_t)ri->prims.len;
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

static void req_quadric(struct ri *ri, const struct rib_request *r)
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
	if (!float_args(ri, r, 0, quadrics[k].nq, p->q))
		return;
	static const uint32_t sizes[5] = {1, 1, 4, 4, 4};
	if (prim_vars(ri, r, sizes, false, p))
		emit_prim(ri, r, p);
}

/* 0, 1, ... n-1. */
static uint32_t *iota(struct ri *ri, uint32_t n)
{
	uint32_t *v = rl_arena_alloc(cur_arena(ri), sizeof(uint32_t) * (n ? n : 1));
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
			err(ri, v->loc, "%s: %s %u is %u (at least %u)", r->name, what, i, c[i], min);
			return false;
		}
		*sum += c[i];
	}
	return true;
}

static bool array_arg(struct ri *ri, const struct rib_request *r, uint32_t i)
{
	if (i < r->nargs && is_numbers(&r->args[i]))
		return true;
	err(ri, r->loc, "%s: argument %u should be an array of integers", r->name, i + 1);
	return false;
}

static void req_polygon(struct ri *ri, const struct rib_request *r)
{
	if (!geometry_ok(ri, r))
		return;
	uint32_t np;
	if (!point_count(ri, r, &np))
		return;
	if (np < 3)
		FAIL(ri, r->loc, "Polygon has %u points (at least 3)", np);
	struct reyes_prim *p = new_prim(ri, REYES_POLYGONS);
	uint32_t *one = rl_arena_alloc(cur_arena(ri), sizeof(uint32_t) * 2);
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

static void req_general_polygon(struct ri *ri, const struct rib_request *r)
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
	if (!point_count(ri, r, &np))
		return;
	if (sum != np)
		FAIL(ri, r->loc, "GeneralPolygon: the loops have %llu vertices, \"P\" has %u",
			   (unsigned long long)sum, np);
	struct reyes_prim *p = new_prim(ri, REYES_POLYGONS);
	uint32_t *nl = rl_arena_alloc(cur_arena(ri), sizeof(uint32_t));
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
static void req_points_polygons(struct ri *ri, const struct rib_request *r)
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
	if (!point_count(ri, r, &np))
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
		nloops = rl_arena_alloc(cur_arena(ri), sizeof(uint32_t) * (nfaces ? nfaces : 1));
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

static void set_bases(struct ri *ri, struct reyes_prim *p)
{
	const struct attrstate *a = &ri->gs.a;
	memcpy(p->ubasis, a->ubasis, sizeof(p->ubasis));
	memcpy(p->vbasis, a->vbasis, sizeof(p->vbasis));
	p->ustep = a->ustep;
	p->vstep = a->vstep;
}

static void req_patch(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	if (!geometry_ok(ri, r) || !str_arg(ri, r, 0, &type))
		return;
	bool bicubic = strcmp(type, "bicubic") == 0;
	if (!bicubic && strcmp(type, "bilinear") != 0)
		FAIL(ri, r->loc, "Patch type must be \"bilinear\" or \"bicubic\", got '%s'",
			   type);
	uint32_t np, want = bicubic ? 16 : 4;
	if (!point_count(ri, r, &np))
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

static void req_patch_mesh(struct ri *ri, const struct rib_request *r)
{
	const char *type, *uwrap, *vwrap;
	double nu, nv;
	if (!geometry_ok(ri, r) || !str_arg(ri, r, 0, &type) || !num_arg(ri, r, 1, &nu) ||
	    !str_arg(ri, r, 2, &uwrap) || !num_arg(ri, r, 3, &nv) || !str_arg(ri, r, 4, &vwrap))
		return;
	bool bicubic = strcmp(type, "bicubic") == 0;
	if (!bicubic && strcmp(type, "bilinear") != 0)
		FAIL(ri, r->loc,
			   "PatchMesh type must be \"bilinear\" or \"bicubic\", got '%s'", type);
	bool up = strcmp(uwrap, "periodic") == 0, vp = strcmp(vwrap, "periodic") == 0;
	if ((!up && strcmp(uwrap, "nonperiodic") != 0) || (!vp && strcmp(vwrap, "nonperiodic") != 0))
		FAIL(ri, r->loc,
			   "PatchMesh wrap modes must be \"periodic\" or \"nonperiodic\", got '%s' "
			   "and '%s'", uwrap, vwrap);
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
	if (!point_count(ri, r, &np))
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

static void req_motion_begin(struct ri *ri, const struct rib_request *r)
{
	if (!depth_ok(ri, r))
		return;
	struct motion *m = &ri->motion;
	*m = (struct motion){.active = true, .loc = keep_loc(ri, r->loc)};
	push_block(ri, r, BLK_MOTION);
	if (r->nargs < 1 || !is_numbers(&r->args[0]) || r->args[0].n == 0) {
		m->bad = true;
		FAIL(ri, r->loc, "MotionBegin needs an array of times");
	}
	const struct rib_value *t = &r->args[0];
	if (t->n > 2) {
		m->bad = true;
		FAIL(ri, r->loc, "only 2 motion samples are supported (MotionBegin has %u)",
			   t->n);
	}
	if (!value_floats(ri, t, r->loc, "MotionBegin", m->times)) {
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
		warn(ri, r->loc,
		     "MotionBegin times %g %g differ from the shutter %g %g: they are used as the "
		     "shutter's open and close", m->times[0], m->times[1], s[0], s[1]);
}

static void req_motion_end(struct ri *ri, const struct rib_request *r)
{
	close_block(ri, r, BLK_MOTION);
}

/* Is request @r the next sample of the open motion block? */
static bool motion_sample(struct ri *ri, const struct rib_request *r, enum motion_kind kind)
{
	struct motion *m = &ri->motion;
	if (m->bad)
		return false;
	if (m->nsamples && strcmp(m->request, r->name) != 0) {
		err(ri, r->loc, "%s does not match the %s before it in the MotionBegin at %s",
		    r->name, m->request, where(ri, m->loc, r->loc));
		m->bad = true;
		return false;
	}
	if (m->nsamples >= m->ntimes) {
		err(ri, r->loc, "more samples than times in the MotionBegin at %s",
		    where(ri, m->loc, r->loc));
		m->bad = true;
		return false;
	}
	m->request = r->name;
	m->kind = kind;
	return true;
}

static void motion_xform(struct ri *ri, const struct rib_request *r, const float x[16], bool set)
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
	if (a->kind < REYES_POLYGONS) {
		if (memcmp(a->q, b->q, sizeof(a->q)) != 0)
			return "quadric parameters (they cannot move)";
	} else if (a->kind == REYES_POLYGONS) {
		if (a->nfaces != b->nfaces || !same_u32(a->nloops, b->nloops, a->nfaces))
			return "polygons";
		uint32_t nl = sum_u32(a->nloops, a->nfaces);
		if (!same_u32(a->nverts, b->nverts, nl) ||
		    !same_u32(a->verts, b->verts, sum_u32(a->nverts, nl)))
			return "polygons";
	} else if (a->bicubic != b->bicubic || a->nu != b->nu || a->nv != b->nv ||
		   a->uperiodic != b->uperiodic || a->vperiodic != b->vperiodic) {
		return "patch mesh";
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
			err(ri, r->loc, "the %s samples of the MotionBegin at %s differ in their %s",
			    r->name, where(ri, m->loc, r->loc), what);
			m->bad = true;
			return;
		}
	}
	m->prim[m->nsamples++] = p;
}

static void motion_end(struct ri *ri, bool apply)
{
	struct motion m = ri->motion;
	ri->motion = (struct motion){0};
	if (!apply || m.bad || m.nsamples == 0)
		return;
	if (m.nsamples != m.ntimes) {
		err(ri, m.loc, "MotionBegin has %u times but %u %s", m.ntimes, m.nsamples,
		    m.nsamples == 1 ? "sample" : "samples");
		return;
	}
	if (m.kind == MOTION_XFORM) {
		uint32_t k1 = m.nsamples - 1;
		if (m.set) {
			set_xform(ri, m.xf[0], m.xf[k1]);
		} else {
			float a[16], b[16];
			sl_m44_mul(a, m.xf[0], ri->gs.x.m[0]);
			sl_m44_mul(b, m.xf[k1], ri->gs.x.m[1]);
			set_xform(ri, a, b);
		}
		return;
	}
	struct reyes_prim *p = m.prim[0];
	if (m.nsamples == 2) {
		const struct reyes_prim *q = m.prim[1];
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

static void req_object_begin(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "ObjectBegin inside the ObjectBegin at %s",
			   where(ri, find_block(ri, BLK_OBJECT)->loc, r->loc));
	if (!depth_ok(ri, r))
		return;
	const char *handle = handle_arg(ri, r, 0, cur_arena(ri));
	if (!handle)
		return;
	float inv[2][16];
	if (!sl_m44_inverse(inv[0], ri->gs.x.m[0]) || !sl_m44_inverse(inv[1], ri->gs.x.m[1]))
		FAIL(ri, r->loc, "ObjectBegin: the current transformation is singular");
	push_block(ri, r, BLK_OBJECT);
	rl_vec_push(ri->objects, (struct object){0});
	ri->objdef = (int)ri->objects.len - 1;
	memcpy(ri->objdef_inv, inv, sizeof(inv));
	strmap_put(ri->world ? &ri->world_object_index : &ri->outer_object_index, handle,
		   ri->objects.len);
	if (!ri->world)
		ri->outer_objects = ri->objects.len;
}

static void object_end(struct ri *ri)
{
	ri->objdef = -1;
}

static void req_object_end(struct ri *ri, const struct rib_request *r)
{
	close_block(ri, r, BLK_OBJECT);
}

static void req_object_instance(struct ri *ri, const struct rib_request *r)
{
	if (ri->objdef >= 0)
		FAIL(ri, r->loc, "ObjectInstance inside an object definition");
	if (!ri->world)
		FAIL(ri, r->loc, "ObjectInstance outside WorldBegin/WorldEnd");
	const char *handle = handle_arg(ri, r, 0, ri->world);
	if (!handle)
		return;
	uintptr_t k;
	if (!strmap_get(&ri->world_object_index, handle, &k) &&
	    !strmap_get(&ri->outer_object_index, handle, &k))
		FAIL(ri, r->loc, "ObjectInstance: unknown object '%s'", handle);
	const struct object *o = &ri->objects.data[k - 1];
	for (size_t i = 0; i < o->prims.len; i++) {
		const struct obj_prim *op = &o->prims.data[i];
		if (op->identity) {
			add_prim(ri, op->p, &ri->gs.x);
			continue;
		}
		struct xform x;
		for (int t = 0; t < 2; t++)
			sl_m44_mul(x.m[t], op->rel[t], ri->gs.x.m[t]);
		x.moving = memcmp(x.m[0], x.m[1], sizeof(x.m[0])) != 0;
		add_prim(ri, op->p, &x);
	}
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

/* Reads one file (the top-level one or an archive) with the builder's handler. */
static bool read_file(struct ri *ri, const char *path, const struct stat *st)
{
	struct file f = {.path = path};
	if (st) {
		f.st = *st;
		f.have_st = true;
	}
	rl_vec_push(ri->files, f);
	struct rib_reader_opts ro = reader_opts(ri);
	int n = 0;
	bool ok = rib_read_file(path, &ro, on_request, ri, &n);
	forward_reader_diag(ri);
	ri->reader_errors += n;
	if (n && ri->nerrors + ri->reader_errors >= ri->max_errors)
		ri->stop = true;
	if (!ri->stop)
		close_file_blocks(ri);
	ri->files.len--;
	return ok;
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

static void req_read_archive(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!str_arg(ri, r, 0, &name))
		return;
	if (ri->files.len > MAX_ARCHIVE_DEPTH)
		FAIL(ri, r->loc, "ReadArchive '%s': archives nested too deeply (limit %d)", name,
			   MAX_ARCHIVE_DEPTH);
	if (++ri->archive_reads > MAX_ARCHIVE_READS)
		FAIL(ri, r->loc, "too many ReadArchive requests (limit %d)",
			   MAX_ARCHIVE_READS);
	const char *path = search_file(ri, name, dir_of(ri, r->loc.file), ri->opt.o.archive_path);
	if (!path)
		FAIL(ri, r->loc, "cannot find archive '%s' (searched: %s:%s)", name,
			   dir_of(ri, r->loc.file), ri->opt.o.archive_path);
	struct stat st;
	if (stat(path, &st) != 0)
		FAIL(ri, r->loc, "cannot read archive '%s'", path);
	for (size_t i = 0; i < ri->files.len; i++) {
		const struct file *f = &ri->files.data[i];
		if (f->have_st && f->st.st_dev == st.st_dev && f->st.st_ino == st.st_ino)
			FAIL(ri, r->loc, "ReadArchive '%s' would read itself again (%s)", name,
				   path);
	}
	for (uint32_t i = 0; i < r->nparams; i++)
		warn(ri, r->params[i].loc, "ReadArchive: parameter '%s' ignored", r->params[i].token);
	read_file(ri, path, &st);
}

static bool wrap_ok(const char *w)
{
	return strcmp(w, "periodic") == 0 || strcmp(w, "clamp") == 0 || strcmp(w, "black") == 0;
}

static void req_make_texture(struct ri *ri, const struct rib_request *r)
{
	const char *pic, *tex, *sw, *tw, *filter;
	float w[2];
	if (!str_arg(ri, r, 0, &pic) || !str_arg(ri, r, 1, &tex) || !str_arg(ri, r, 2, &sw) ||
	    !str_arg(ri, r, 3, &tw) || !str_arg(ri, r, 4, &filter) || !float_args(ri, r, 5, 2, w))
		return;
	if (!wrap_ok(sw) || !wrap_ok(tw))
		FAIL(ri, r->loc,
			   "MakeTexture: wrap modes must be \"periodic\", \"clamp\" or \"black\", "
			   "got '%s' and '%s'", sw, tw);
	for (uint32_t i = 0; i < r->nparams; i++)
		warn(ri, r->params[i].loc, "MakeTexture: parameter '%s' ignored", r->params[i].token);
	forward_reader_diag(ri);
	if (!reyes_make_texture(pic, tex, sw, tw, filter, w[0], w[1], ri->diag))
		err(ri, r->loc, "MakeTexture '%s' -> '%s' failed", pic, tex);
}

static void req_make_shadow(struct ri *ri, const struct rib_request *r)
{
	const char *pic, *tex;
	if (!str_arg(ri, r, 0, &pic) || !str_arg(ri, r, 1, &tex))
		return;
	for (uint32_t i = 0; i < r->nparams; i++)
		warn(ri, r->params[i].loc, "MakeShadow: parameter '%s' ignored", r->params[i].token);
	forward_reader_diag(ri);
	if (!reyes_make_shadow(pic, tex, ri->diag))
		err(ri, r->loc, "MakeShadow '%s' -> '%s' failed", pic, tex);
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
		uint32_t k = 0;
		for (uint32_t i = nd; i-- > 0;)
			if (strcmp(ds[i].type, "zfile") != 0 && strcmp(ds[i].type, "shadow") != 0 &&
			    strcmp(ds[i].mode, "z") != 0)
				k = i;
		ds[k].name = rl_arena_strdup(a, ri->opts->output_override);
	}
	o->displays = ds;
	o->ndisplays = nd;

	sc->lights = ri->lights.data;
	sc->nlights = (uint32_t)ri->lights.len;
	sc->prims = ri->prims.data;
	sc->nprims = (uint32_t)ri->prims.len;
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
	if (render && !ri->stop && ri->frame_errors == 0 && ri->opts->frame) {
		struct reyes_scene sc;
		build_scene(ri, &sc);
		if (!ri->opts->frame(ri->opts->user, &sc)) {
			ri->nerrors++;
			ri->stop = true;
		}
	}
	ri->frame_errors = 0;
	/* Objects defined inside the world end with it. */
	for (size_t i = ri->outer_objects; i < ri->objects.len; i++)
		rl_vec_free(ri->objects.data[i].prims);
	ri->objects.len = ri->outer_objects;
	strmap_free(&ri->world_object_index);
	strmap_free(&ri->light_index);
	strmap_free(&ri->space_index);
	ri->lights.len = 0;
	ri->prims.len = 0;
	ri->spaces.len = 0;
	rl_arena_destroy(ri->world);
	ri->world = NULL;
}

/* ---- dispatch ---------------------------------------------------------------------------- */

enum {
	F_OPTION = 1 << 0,   /* only before WorldBegin (checked by the handler) */
	F_WORLD = 1 << 1,    /* only inside the world */
	F_MOTION = 1 << 2,   /* may be a sample of a motion block */
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
	{"Format", req_format, 0},
	{"FrameAspectRatio", req_frame_aspect, 0},
	{"ScreenWindow", req_screen_window, 0},
	{"CropWindow", req_crop_window, 0},
	{"Projection", req_projection, 0},
	{"Clipping", req_clipping, 0},
	{"Shutter", req_shutter, 0},
	{"PixelSamples", req_pixel_samples, 0},
	{"PixelVariance", req_ignore, 0},
	{"PixelFilter", req_pixel_filter, 0},
	{"Exposure", req_exposure, 0},
	{"Quantize", req_quantize, 0},
	{"Display", req_display, 0},
	{"Hider", req_hider, 0},
	{"Option", req_option, 0},
	{"Attribute", req_attribute, 0},
	{"Color", req_color, 0},
	{"Opacity", req_color, 0},
	{"Surface", req_surface, 0},
	{"Displacement", req_surface, 0},
	{"LightSource", req_light_source, F_WORLD},
	{"Illuminate", req_illuminate, F_WORLD},
	{"Sides", req_sides, 0},
	{"Orientation", req_orientation, 0},
	{"ReverseOrientation", req_reverse_orientation, 0},
	{"ShadingRate", req_shading_rate, 0},
	{"ShadingInterpolation", req_shading_interpolation, 0},
	{"Basis", req_basis, 0},
	{"Declare", req_declare, 0},
	{"Identity", req_xform, F_MOTION},
	{"Transform", req_xform, F_MOTION},
	{"ConcatTransform", req_xform, F_MOTION},
	{"Translate", req_xform, F_MOTION},
	{"Rotate", req_xform, F_MOTION},
	{"Scale", req_xform, F_MOTION},
	{"Skew", req_xform, F_MOTION},
	{"CoordinateSystem", req_coordinate_system, 0},
	{"CoordSysTransform", req_coord_sys_transform, 0},
	{"MotionBegin", req_motion_begin, 0},
	{"MotionEnd", req_motion_end, F_MOTION},
	{"ObjectBegin", req_object_begin, 0},
	{"ObjectEnd", req_object_end, 0},
	{"ObjectInstance", req_object_instance, 0},
	{"ReadArchive", req_read_archive, 0},
	{"MakeTexture", req_make_texture, 0},
	{"MakeShadow", req_make_shadow, 0},
	{"Sphere", req_quadric, F_MOTION},
	{"Cylinder", req_quadric, F_MOTION},
	{"Cone", req_quadric, F_MOTION},
	{"Disk", req_quadric, F_MOTION},
	{"Hyperboloid", req_quadric, F_MOTION},
	{"Paraboloid", req_quadric, F_MOTION},
	{"Torus", req_quadric, F_MOTION},
	{"Polygon", req_polygon, F_MOTION},
	{"GeneralPolygon", req_general_polygon, F_MOTION},
	{"PointsPolygons", req_points_polygons, F_MOTION},
	{"PointsGeneralPolygons", req_points_polygons, F_MOTION},
	{"Patch", req_patch, F_MOTION},
	{"PatchMesh", req_patch_mesh, F_MOTION},
};

static bool on_request(void *user, const struct rib_request *r)
{
	struct ri *ri = user;
	forward_reader_diag(ri);
	if (ri->stop)
		return false;
	if (ri->files.len)
		ri->files.data[ri->files.len - 1].last = keep_loc(ri, r->loc);
	const struct handler *h = NULL;
	for (size_t i = 0; i < sizeof(handlers) / sizeof(handlers[0]) && !h; i++)
		if (handlers[i].name[0] == r->name[0] && strcmp(handlers[i].name, r->name) == 0)
			h = &handlers[i];
	if (!h) {
		warn(ri, r->loc, "%s is not supported: ignored", r->name);
		return !ri->stop;
	}
	if (ri->motion.active && !(h->flags & F_MOTION)) {
		err(ri, r->loc, "%s cannot be inside the MotionBegin at %s", r->name,
		    where(ri, ri->motion.loc, r->loc));
		return !ri->stop;
	}
	if ((h->flags & F_WORLD) && !ri->world) {
		err(ri, r->loc, "%s outside WorldBegin/WorldEnd", r->name);
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
	struct ri ri = {
		.opts = opts,
		.diag = opts->diag ? opts->diag : stderr,
		.max_errors = opts->max_errors > 0 ? opts->max_errors : 20,
		.perm = rl_arena_create(),
		.objdef = -1,
	};
	ri.rdiag = open_memstream(&ri.rbuf, &ri.rlen);
	const char *sp = opts->default_shader_path;
	if (!sp || !*sp)
		ri.default_shader_path = RELIGHT_SOURCE_SHADER_DIR;
	else if (path_ends_with(sp, RELIGHT_SOURCE_SHADER_DIR))
		ri.default_shader_path = rl_arena_strdup(ri.perm, sp);
	else
		ri.default_shader_path = rl_arena_printf(ri.perm, "%s:%s", sp,
							 RELIGHT_SOURCE_SHADER_DIR);
	ri.default_texture_path = opts->default_texture_path && *opts->default_texture_path
					  ? rl_arena_strdup(ri.perm, opts->default_texture_path)
					  : ".";
	options_init(&ri, &ri.opt);
	attrs_init(&ri.gs.a);
	xform_init(&ri.gs.x);

	struct stat st;
	bool have_st = path && stat(path, &st) == 0;
	bool read_ok = read_file(&ri, path, have_st ? &st : NULL);

	/* Blocks left open when the read stopped early: unwind without rendering. */
	while (ri.blocks.len)
		pop_block(&ri, false);
	forward_reader_diag(&ri);

	int total = ri.nerrors + ri.reader_errors;
	if (nerrors)
		*nerrors = total;

	for (size_t i = 0; i < ri.objects.len; i++)
		rl_vec_free(ri.objects.data[i].prims);
	rl_vec_free(ri.objects);
	rl_vec_free(ri.blocks);
	rl_vec_free(ri.files);
	rl_vec_free(ri.pre_spaces);
	rl_vec_free(ri.lights);
	rl_vec_free(ri.prims);
	rl_vec_free(ri.spaces);
	strmap_free(&ri.decls);
	strmap_free(&ri.shader_cache);
	strmap_free(&ri.pre_space_index);
	strmap_free(&ri.outer_object_index);
	strmap_free(&ri.world_object_index);
	strmap_free(&ri.light_index);
	strmap_free(&ri.space_index);
	for (size_t i = 0; i < ri.progs.len; i++)
		sl_program_destroy(ri.progs.data[i]);
	rl_vec_free(ri.progs);
	if (ri.rdiag)
		fclose(ri.rdiag);
	free(ri.rbuf);
	rl_arena_destroy(ri.world);
	rl_arena_destroy(ri.perm);
	return read_ok && total == 0;
}

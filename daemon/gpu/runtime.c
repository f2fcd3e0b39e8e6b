/*
 * The GPU runtime: see runtime.h.
 *
 * Memory, per shot: for each surface shader, its samples' cached values as
 * packed records (a texture buffer, the layout of its kernels' inputs) and
 * the object id of each sample; for every sample, four colours: the surface
 * with no light (base), the light cache, the colour the resolve reads, and
 * a scratch of kernel outputs sized for the largest surface; per light, one
 * float per object saying whether the light reaches it; the indirect
 * framebuffer and its coarse levels (gpu/resolve.h); one RGBA image per
 * level.
 *
 * Rows: within each tile, each band's rows of a surface are a range of its
 * table (the bake orders them so). When a surface's editable parameters
 * take different values on different objects (paramset), the rows of each
 * range are sorted by paramset at load, so that one dispatch with one set
 * of uniforms covers each run; the indirect framebuffer's sample ids are
 * renumbered to match.
 *
 * Shading a light over a band: for each surface and each run of rows, the
 * (surface, light shader) kernel writes Ci for the light alone (plus the
 * surface's part that needs no light); a second kernel subtracts the base
 * and adds the difference, times the light's link to the sample's object,
 * into the cache or the colours (sanitized: a non-finite difference adds 0).
 */
#include "runtime.h"

#include "arena.h"
#include "clock.h"
#include "deepshadow.h"
#include "graph.h"
#include "imagerpass.h"
#include "lighthost.h"
#include "log.h"
#include "mathlib.h"
#include "resolve.h"
#include "shadowmap.h"
#include "shadowrender.h"
#include "shadowbvh.h"
#include "shotfile.h"
#include "shotmeta.h"
#include "strbuf.h"
#include "builtin.h"
#include "spec.h"
#include "texmap.h"
#include "texture.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEFAULT_BUDGET ((size_t)2 << 30)
/* Light shaders that gpu_shot_add_light may bring beyond the shot's own. */
#define MAX_ADDED_SHADERS 32
#define NBANDS GPU_SHOT_LEVELS
#define MAX_PARAM_FLOATS 4096
/*
 * Lights of one shader that enter the light cache together are shaded in
 * passes of BATCH lights: one kernel reads each sample's record once and
 * runs the surface with each light alone (sl_slice.per_light), and one
 * accumulate adds their differences. A batch with fewer lights repeats its
 * last light in the spare passes, which the accumulate leaves out.
 */
#define BATCH GPU_SHOT_BATCH

/* ------------------------------------------------------------------------ */
/* State                                                                     */

/* A light's parameters as its kernels take them (after the defaults ran,
 * points in current space), and whether it is on. */
struct lstate {
	bool valid;                /* in a cache table: the light is in the cache */
	bool on;                   /* contributes (not muted, not solo'd away) */
	float *v;                  /* every non-string parameter's floats, in order */
	uint32_t nv;
	char **s;                  /* per string parameter */
	uint32_t ns;
	uint32_t link;             /* the link version */
	/* How much of the light its shadow maps take away, per channel:
	 * density * (1 - shadow colour); 1 for plain shadows, 0 with shadows
	 * off (rerendering-2007 §5.4). */
	float shadow[3];
};

struct light {
	char *name;
	uint32_t shader;           /* index into shot->lshaders */
	float to_camera[16];       /* shader space -> current (camera) */
	struct sl_exec *init;      /* runs the parameter defaults */
	struct lstate cur;
	bool muted;
	bool frozen;               /* in the light cache */
	bool pinned;               /* unfrozen by gpu_shot_freeze: stays so */
	bool removed;              /* gpu_shot_remove_light: gone */
	bool shadows_off;
	struct gpu_buffer *recv;   /* per object: 1 receives this light's shadows, 0 not */
	float *recv_cpu;
	uint32_t not_receiving;    /* objects that do not */
	float *cast_cpu;           /* per object: 1 casts this light's shadows, 0 not */
	uint32_t not_casting;      /* objects that do not */
	uint32_t cast_version, rendered_version;
	bool follow;               /* the maps' cameras follow the light's from and to */
	bool warned_deep;          /* said that a deep map cannot be rendered again */
	bool warned_rt;            /* said that its ray-traced shadow cannot be previewed */
	float follow_key[6];       /* the from and to the maps were last rendered for */
	/* per shadow site, while some object does not cast: the map rendered
	 * from the shadow geometry without them, and its depths */
	struct gpu_shadow_map **rmaps;
	struct gpu_buffer **rdepth;
	float shadow_density, shadow_color[3];
	struct gpu_buffer *link;   /* per object: 1 reached, 0 not */
	float *link_cpu;
	uint32_t link_version;
	struct graph_node *node;
	struct graph_node *shadow_node;
	struct gpu_shadow_map **maps;  /* per shadow site of its kernels: the bound map */
	char **map_names;              /* per site: the name it was loaded for */
	uint32_t nmaps;
};

struct lshader {
	struct sl_program *prog;
	struct sl_program init;    /* prog cut to its parameter defaults */
};

struct kernel {
	char *glsl;
	struct sl_glsl_layout layout;
	struct gpu_program *prog;
};

struct surface_edit {
	char *param;
	float v[16];
	uint32_t n;
};

/* A run of rows shaded with one set of uniforms. */
struct run {
	uint32_t first, count, paramset;
};

struct surface {
	const cJSON *meta;
	char *name;
	struct sl_program *prog;
	struct sl_spec *spec;
	struct sl_program init;
	struct sl_exec *init_x;
	uint64_t nrows, id0;
	struct kernel base;
	struct kernel *lk;         /* per light shader */
	struct kernel *bk;         /* per light shader: BATCH lights a pass each (prog NULL: none) */
	struct gpu_buffer *records;
	struct gpu_buffer *object; /* per row, as float */
	RL_VEC(struct run) runs[NBANDS];
	uint32_t nparamsets;
	/* per paramset: the surface parameters' uniform values */
	struct lstate *pvals;
	/* gpu_shot_set_surface: values over every object's */
	RL_VEC(struct surface_edit) edits;
	struct graph_node *node;
};

struct gpu_shot {
	struct gpu_ctx *ctx;
	FILE *diag;
	char *path;
	cJSON *meta;
	struct reyes_texsys *tex;
	struct gpu_texmaps *texmaps;   /* the texture and environment maps lights read */
	struct rl_strbuf space_warned; /* "light\tspace\n" of each unknown space warned about */
	uint32_t width, height;
	float w2c[16], c2w[16];
	uint64_t nsamples;
	uint32_t nobjects;
	size_t bytes, budget;

	struct lshader *lshaders;
	uint32_t nlshaders;
	struct light *lights;
	uint32_t nlights;
	int solo;                  /* a light index, or -1 */
	char *shader_path;         /* where gpu_shot_add_light looks for shaders */
	struct surface *surfaces;
	uint32_t nsurfaces;

	struct gpu_ifb *ifb;
	uint32_t *pick;            /* per pixel: the object of its heaviest sample (UINT32_MAX: none) */
	struct gpu_shadow_geometry *shadow_geo;  /* NULL: the shot has none */
	bool shadow_bvh;           /* shadow_geo's ray-tracing hierarchy is built */
	bool traces_shadows;       /* some light's string parameter is "raytrace" at load */
	float trace_bias;          /* ray-traced shadows' start offset without a "bias" option */
	struct gpu_deep_stats deep_stats;        /* of the last deep map rendered or tried */
	uint32_t deep_maps_rendered;
	uint64_t level_entries[NBANDS];
	struct gpu_buffer *base, *cache, *colors, *scratch, *zero;
	struct gpu_buffer *rgba[NBANDS], *px8;
	struct gpu_program *accumulate, *accumulate_d, *combine, *clear, *half;
	struct gpu_buffer *px16;

	/* the light cache: per band, per light, what the cache holds of it */
	struct lstate *cached[NBANDS];
	bool base_valid[NBANDS];
	uint32_t link_version;

	/* the imager pass (imagerpass.h): level L's image is imaged[L] after it */
	struct gpu_imager *imager;
	struct gpu_buffer *imaged[NBANDS];

	struct graph *graph;
	struct graph_node *shade[NBANDS], *resolve[NBANDS];
	struct graph_node *imager_src, *image[NBANDS];  /* with an imager */
	struct gpu_shot_stats *stats;  /* of the call running, or NULL */
};

static bool fail(struct gpu_shot *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static bool fail(struct gpu_shot *s, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(s->diag, "relight: error: %s: ", s->path);
	vfprintf(s->diag, fmt, ap);
	fputc('\n', s->diag);
	va_end(ap);
	return false;
}

static void errorf(char *err, size_t errlen, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void errorf(char *err, size_t errlen, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	if (err && errlen)
		vsnprintf(err, errlen, fmt, ap);
	va_end(ap);
}

/* ------------------------------------------------------------------------ */
/* Parameter values                                                          */

static void lstate_free(struct lstate *st)
{
	for (uint32_t i = 0; i < st->ns; i++)
		free(st->s[i]);
	free(st->s);
	free(st->v);
	memset(st, 0, sizeof(*st));
}

static void lstate_copy(struct lstate *dst, const struct lstate *src)
{
	lstate_free(dst);
	*dst = *src;
	dst->v = rl_xmalloc((src->nv + 1) * sizeof(float));
	memcpy(dst->v, src->v, src->nv * sizeof(float));
	dst->s = rl_xcalloc(src->ns + 1, sizeof(char *));
	for (uint32_t i = 0; i < src->ns; i++)
		dst->s[i] = rl_xstrdup(src->s[i]);
}

static bool lstate_equal(const struct lstate *a, const struct lstate *b)
{
	if (a->valid != b->valid || a->on != b->on || a->nv != b->nv || a->ns != b->ns ||
	    a->link != b->link || memcmp(a->shadow, b->shadow, sizeof(a->shadow)))
		return false;
	if (memcmp(a->v, b->v, a->nv * sizeof(float)))
		return false;
	for (uint32_t i = 0; i < a->ns; i++)
		if (strcmp(a->s[i], b->s[i]))
			return false;
	return true;
}

/* The coordinate systems a parameter default may name. */
struct space_host {
	struct sl_host host;
	const float *shader;       /* NULL: "shader" is not known */
	const float *w2c;
};

static bool space_cb(void *user, const char *name, float m[16])
{
	const struct space_host *h = user;
	if (!strcmp(name, "shader") && h->shader) {
		memcpy(m, h->shader, 16 * sizeof(float));
		return true;
	}
	if (!strcmp(name, "world")) {
		memcpy(m, h->w2c, 16 * sizeof(float));
		return true;
	}
	return false;
}

/* Run @x (a program cut to its defaults) and gather its parameters' values. */
static bool eval_params(struct sl_exec *x, const struct sl_program *prog, const float *shader,
			const float *w2c, struct lstate *out)
{
	struct space_host h = { .host = { .space = space_cb }, .shader = shader, .w2c = w2c };
	h.host.user = &h;
	if (!sl_exec_set_grid(x, 1, 1) || !sl_exec_run(x, &h.host))
		return false;
	struct lstate keep = *out;
	lstate_free(out);
	out->valid = keep.valid;
	out->on = keep.on;
	out->link = keep.link;
	memcpy(out->shadow, keep.shadow, sizeof(out->shadow));
	RL_VEC(float) v = { 0 };
	RL_VEC(char *) sv = { 0 };
	for (uint32_t k = 0; k < prog->nparams; k++) {
		int32_t r = prog->params[k].reg;
		const struct sl_reg *g = &prog->regs[r];
		uint32_t ne = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
		uint32_t stride = g->varying ? sl_exec_stride(x) : 1;
		if (g->type == SL_TYPE_STRING) {
			const char **s = sl_exec_reg_strings(x, r);
			rl_vec_push(sv, rl_xstrdup(s && s[0] ? s[0] : ""));
			continue;
		}
		const float *d = sl_exec_reg(x, r);
		uint32_t tot = ne * (uint32_t)sl_reg_ncomp(g);
		for (uint32_t q = 0; q < tot; q++)
			rl_vec_push(v, d && isfinite(d[(size_t)q * stride]) ? d[(size_t)q * stride]
									   : 0.0f);
	}
	out->v = v.data ? v.data : rl_xcalloc(1, sizeof(float));
	out->nv = (uint32_t)v.len;
	out->s = sv.data ? sv.data : rl_xcalloc(1, sizeof(char *));
	out->ns = (uint32_t)sv.len;
	return true;
}

/* A string's token id in a kernel's table (past the table: a string it never compares to). */
static float string_id(const struct sl_glsl_layout *lay, const char *s)
{
	for (uint32_t i = 0; i < lay->nstrings; i++)
		if (!strcmp(lay->strings[i], s))
			return (float)i;
	return (float)lay->nstrings + 7.0f;
}

/* Set the uniforms of @prog's parameters from @st: those of light @light of
 * the kernel, or of its surface with @light < 0 (sl_glsl_param_uniform). */
static void set_uniforms(struct gpu_program *gp, const struct sl_glsl_layout *lay,
			 const struct sl_program *prog, const struct lstate *st, int light)
{
	uint32_t at = 0, si = 0;
	for (uint32_t k = 0; k < prog->nparams; k++) {
		const struct sl_reg *g = &prog->regs[prog->params[k].reg];
		char name[320];
		sl_glsl_param_uniform(name, sizeof(name), light, prog->params[k].name);
		if (g->type == SL_TYPE_STRING) {
			if (si < st->ns) {
				float id = string_id(lay, st->s[si]);
				gpu_uniform_float(gp, name, &id, 1);
			}
			si++;
			continue;
		}
		uint32_t ne = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
		uint32_t tot = ne * (uint32_t)sl_reg_ncomp(g);
		if (at + tot > st->nv)
			return;
		if (tot == 16 && ne == 1)
			gpu_uniform_mat4(gp, name, st->v + at);
		else if (tot <= MAX_PARAM_FLOATS)
			gpu_uniform_float(gp, name, st->v + at, (int)tot);
		at += tot;
	}
}

/*
 * The space a light's string parameter names, for transforms that name it
 * by the parameter: that space -> current, as the CPU's light host resolves
 * it (sl/lighthost.c with the shot's spaces: "world", the light's
 * "shader"; "current", "camera" and "" are the identity). False for any
 * other name: the identity, as on the CPU.
 */
static bool space_matrix(const struct gpu_shot *s, const struct light *L, const char *name,
			 float m[16])
{
	static const float identity[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	memcpy(m, identity, sizeof(identity));
	if (!strcmp(name, "world"))
		memcpy(m, s->w2c, sizeof(identity));
	else if (!strcmp(name, "shader"))
		memcpy(m, L->to_camera, sizeof(identity));
	else
		return !*name || !strcmp(name, "current") || !strcmp(name, "camera");
	return true;
}

/* A space the preview does not know, once per light and name. */
static void warn_space(struct gpu_shot *s, const struct light *L, const char *name)
{
	char key[600];
	snprintf(key, sizeof(key), "%s\t%s\n", L->name, name);
	if (strstr(rl_strbuf_str(&s->space_warned), key))
		return;
	rl_strbuf_puts(&s->space_warned, key);
	fprintf(s->diag, "relight: warning: %s: light '%s' names coordinate system '%s', which "
		"the preview does not know: the identity is used, as in preview --cpu\n", s->path,
		L->name, name);
}

/*
 * The spaces light @L's string parameters (values @st) name, as light @j of
 * kernel program @gp: the uniforms of the parameters its transforms name a
 * space by (the others are not in the program, and not set).
 */
static void set_spaces(struct gpu_shot *s, struct gpu_program *gp, const struct light *L,
		       const struct lstate *st, int j)
{
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	uint32_t si = 0;
	for (uint32_t k = 0; k < lp->nparams; k++) {
		if (lp->regs[lp->params[k].reg].type != SL_TYPE_STRING)
			continue;
		if (si < st->ns) {
			float m[16];
			bool known = space_matrix(s, L, st->s[si], m);
			char name[320];
			sl_glsl_space_uniform(name, sizeof(name), j, lp->params[k].name);
			if (gpu_uniform_mat4(gp, name, m) && !known)
				warn_space(s, L, st->s[si]);
		}
		si++;
	}
}

/* ------------------------------------------------------------------------ */
/* The hand-written kernels                                                  */

/*
 * Accumulate: dst[id] (+)= (weight + weight_recv * receives(object)) *
 * link(object) * (out[row] - base[id]) for
 * rows [u_first, u_first + u_count) of a surface; or, for the base itself,
 * dst[id] = out[row]. DST is float (the colours, the base) or double (the
 * light cache: a sum of floats whose magnitudes lie within 2^29 of each
 * other is exact in double, so subtracting a contribution that was added
 * gives back exactly the sum before it, however long the session).
 */
#define ACCUMULATE_SRC(DST) \
	"#version 430 core\n" \
	"layout(local_size_x = 64) in;\n" \
	"layout(binding = 0) uniform samplerBuffer u_out;\n" \
	"layout(binding = 1) uniform samplerBuffer u_obj;\n" \
	"layout(binding = 2) uniform samplerBuffer u_link;\n" \
	"layout(binding = 3) uniform samplerBuffer u_base;\n" \
	"layout(std430, binding = 4) buffer Dst { " DST " dst[]; };\n" \
	"layout(binding = 5) uniform samplerBuffer u_recv;\n" \
	"uniform int u_count;\n" \
	"uniform int u_first;\n" \
	"uniform int u_ostride;\n" \
	"uniform int u_id0;\n" \
	"uniform int u_mode;\n" \
	"uniform vec3 u_weight;\n" \
	"uniform vec3 u_weight_recv;\n" \
	"void main() {\n" \
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n" \
	"	if (i >= uint(u_count)) return;\n" \
	"	int row = int(i) + u_first;\n" \
	"	int id = u_id0 + row;\n" \
	"	if (u_mode == 0) {\n" \
	"		for (int c = 0; c < 3; c++) {\n" \
	"			float v = texelFetch(u_out, row * u_ostride + c).x;\n" \
	"			dst[id * 3 + c] = " DST "(isnan(v) || isinf(v) ? 0.0 : v);\n" \
	"		}\n" \
	"		return;\n" \
	"	}\n" \
	"	int obj = int(texelFetch(u_obj, row).x);\n" \
	"	float link = texelFetch(u_link, obj).x;\n" \
	"	if (link == 0.0) return;\n" \
	"	vec3 wt = u_weight + u_weight_recv * texelFetch(u_recv, obj).x;\n" \
	"	for (int c = 0; c < 3; c++) {\n" \
	"		precise float v = texelFetch(u_out, row * u_ostride + c).x - texelFetch(u_base, id * 3 + c).x;\n" \
	"		v = isnan(v) || isinf(v) ? 0.0 : v * (wt[c] * link);\n" \
	"		precise " DST " r = dst[id * 3 + c] + " DST "(v);\n" \
	"		dst[id * 3 + c] = isnan(r) || isinf(r) ? " DST "(0.0) : r;\n" \
	"	}\n" \
	"}\n"

static const char accumulate_src[] = ACCUMULATE_SRC("float");
static const char accumulate_d_src[] = ACCUMULATE_SRC("double");

/*
 * Where a batch kernel's passes go (sl_slice.sink): light k's colour less
 * the base, for the first u_n passes, added to the light cache of sample
 * u_id0 + row as the one-light accumulate adds it (lights of a batch reach
 * every object and take no shadow weights, so link and weight are 1).
 */
static const char batch_sink[] =
	"layout(binding = 1) uniform samplerBuffer u_base;\n"
	"layout(std430, binding = 2) buffer Cache { double cache[]; };\n"
	"uniform int u_id0;\n"
	"uniform int u_n;\n"
	"vec3 rl_base = vec3(0.0);\n"
	"dvec3 rl_acc = dvec3(0.0);\n"
	"void rl_sink(uint row, uint k, vec3 ci) {\n"
	"	int id = (u_id0 + int(row)) * 3;\n"
	"	if (k == 0u) {\n"
	"		rl_base = vec3(texelFetch(u_base, id).x, texelFetch(u_base, id + 1).x,\n"
	"			       texelFetch(u_base, id + 2).x);\n"
	"		rl_acc = dvec3(cache[id], cache[id + 1], cache[id + 2]);\n"
	"	}\n"
	"	if (int(k) >= u_n) return;\n"
	"	for (int c = 0; c < 3; c++) {\n"
	"		precise float v = ci[c] - rl_base[c];\n"
	"		v = isnan(v) || isinf(v) ? 0.0 : v * 1.0;\n"
	"		precise double r = rl_acc[c] + double(v);\n"
	"		rl_acc[c] = isnan(r) || isinf(r) ? 0.0 : r;\n"
	"	}\n"
	"}\n"
	"void rl_sink_end(uint row) {\n"
	"	int id = (u_id0 + int(row)) * 3;\n"
	"	for (int c = 0; c < 3; c++)\n"
	"		cache[id + c] = rl_acc[c];\n"
	"}\n";

/* Combine: colors = base + cache over ids [u_first, u_first + u_count). */
static const char combine_src[] =
	"#version 430 core\n"
	"layout(local_size_x = 64) in;\n"
	"layout(binding = 0) uniform samplerBuffer u_base;\n"
	"layout(std430, binding = 1) readonly buffer Cache { double cache[]; };\n"
	"layout(std430, binding = 2) buffer Dst { float dst[]; };\n"
	"uniform int u_count;\n"
	"uniform int u_first;\n"
	"void main() {\n"
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	"	if (i >= uint(u_count)) return;\n"
	"	int k = (int(i) + u_first) * 3;\n"
	"	for (int c = 0; c < 3; c++) {\n"
	"		float v = float(double(texelFetch(u_base, k + c).x) + cache[k + c]);\n"
	"		dst[k + c] = isnan(v) || isinf(v) ? 0.0 : v;\n"
	"	}\n"
	"}\n";

/* Linear half output: RGBA floats to two uints of packed halves a pixel,
 * clamped to the largest half (the resolve leaves no NaN or Inf). */
static const char half_src[] =
	"#version 430 core\n"
	"layout(local_size_x = 64) in;\n"
	"layout(std430, binding = 0) readonly buffer Src { vec4 src[]; };\n"
	"layout(std430, binding = 1) buffer Dst { uint dst[]; };\n"
	"uniform int u_count;\n"
	"void main() {\n"
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	"	if (i >= uint(u_count)) return;\n"
	"	vec4 v = clamp(src[i], vec4(-65504.0), vec4(65504.0));\n"
	"	dst[2u * i] = packHalf2x16(v.xy);\n"
	"	dst[2u * i + 1u] = packHalf2x16(v.zw);\n"
	"}\n";

/* Clear the light cache over ids [u_first, u_first + u_count). */
static const char clear_src[] =
	"#version 430 core\n"
	"layout(local_size_x = 64) in;\n"
	"layout(std430, binding = 0) buffer Dst { double dst[]; };\n"
	"uniform int u_count;\n"
	"uniform int u_first;\n"
	"void main() {\n"
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	"	if (i >= uint(u_count)) return;\n"
	"	int k = (int(i) + u_first) * 3;\n"
	"	for (int c = 0; c < 3; c++)\n"
	"		dst[k + c] = 0.0;\n"
	"}\n";

/* ------------------------------------------------------------------------ */
/* Shading                                                                   */

static void count_dispatch(struct gpu_shot *s, uint64_t shaded)
{
	if (s->stats) {
		s->stats->dispatches++;
		s->stats->shaded += shaded;
	}
}

/* The map a texture() or environment() site of light shader @lp reads with parameters @st. */
static const char *site_map_name(const struct sl_program *lp, const struct lstate *st,
				 const struct sl_glsl_map_site *site)
{
	if (!site->param)
		return site->name ? site->name : "";
	uint32_t si = 0;
	for (uint32_t p = 0; p < lp->nparams; p++) {
		if (lp->regs[lp->params[p].reg].type != SL_TYPE_STRING)
			continue;
		if (!strcmp(lp->params[p].name, site->param))
			return si < st->ns ? st->s[si] : "";
		si++;
	}
	return "";
}

/* What is left of the shot's GPU memory budget. */
static size_t budget_room(const struct gpu_shot *s)
{
	size_t used = gpu_shot_bytes(s);
	return used < s->budget ? s->budget - used : 0;
}

/*
 * Bind the texture and environment maps of kernel @k for light @L with
 * parameters @st (NULL: no light, every lookup gives the fill), at the units
 * after the shadow maps'. A map a parameter names is loaded on first use;
 * swapping one is a binding, never a compile.
 */
static bool bind_texmaps(struct gpu_shot *s, const struct kernel *k, const struct light *L,
			 const struct lstate *st, struct gpu_binding *b, uint32_t *nb)
{
	for (uint32_t i = 0; i < k->layout.nmaps; i++) {
		const struct sl_glsl_map_site *site = &k->layout.maps[i];
		const struct gpu_texmap *m = NULL;
		if (L && st) {
			char who[300];
			snprintf(who, sizeof(who), "%s: light '%s'", s->path, L->name);
			m = gpu_texmaps_get(s->texmaps,
					    site_map_name(s->lshaders[L->shader].prog, st, site), who,
					    budget_room(s));
		}
		b[*nb] = (struct gpu_binding){ 0, false, s->zero, false };
		if (!gpu_texmap_bind(m, SL_GLSL_SHADOW_UNIT0 + k->layout.nshadows + i, &b[*nb]))
			return fail(s, "cannot bind the texture map of a kernel");
		(*nb)++;
	}
	return true;
}

/* Bind the shadow maps of kernel @k for light @L (NULL: the base kernel),
 * or none when not @maps (every lookup gives the fill: no shadow), then its
 * texture maps for parameters @st. */
static bool bind_maps(struct gpu_shot *s, const struct kernel *k, const struct light *L,
		      const struct lstate *st, bool maps, struct gpu_binding *b, uint32_t *nb)
{
	for (uint32_t i = 0; i < k->layout.nshadows; i++) {
		const struct gpu_shadow_map *m = maps && L && L->maps ? L->maps[i] : NULL;
		if (m && (L->not_casting || L->follow) && L->rmaps && L->rmaps[i])
			m = L->rmaps[i];
		b[*nb] = (struct gpu_binding){ 0, false, s->zero, false };
		if (!gpu_shadow_map_bind(s->ctx, k->prog, i, m, s->c2w, &b[*nb]))
			return fail(s, "cannot bind the shadow map of a kernel");
		b[*nb].unit = SL_GLSL_SHADOW_UNIT0 + i;
		(*nb)++;
		if (k->layout.shadows[i].raytrace) {
			char u[64];
			snprintf(u, sizeof(u), "u_shadow%u_rt", i);
			bool rt = maps && L && L->map_names && L->map_names[i] && s->shadow_bvh &&
				  !strcmp(L->map_names[i], "raytrace");
			gpu_uniform_int(k->prog, u, rt ? 1 : 0);
		}
	}
	if (k->layout.bvh_unit) {
		gpu_uniform_float(k->prog, "u_trace_bias", &s->trace_bias, 1);
		if (!s->shadow_bvh ||
		    !gpu_shadow_bvh_bind(s->shadow_geo, k->layout.bvh_unit, L ? L->cast_cpu : NULL,
					 L ? s->nobjects : 0, &b[*nb]))
			for (uint32_t j = 0; j < 3; j++)
				b[*nb + j] = (struct gpu_binding){ k->layout.bvh_unit + j, false, s->zero,
								   j < 2 };
		*nb += 3;
	}
	return bind_texmaps(s, k, L, st, b, nb);
}

/* Bind the maps of kernel @k for light @L with parameters @st (NULL: the base kernel). */
static bool bind_shadows(struct gpu_shot *s, const struct kernel *k, const struct light *L,
			 const struct lstate *st, struct gpu_binding *b, uint32_t *nb)
{
	return bind_maps(s, k, L, st, true, b, nb);
}

/* Before dispatching kernel @k over run @ru of @sf: its paramset's uniforms and first row. */
static void run_uniforms(struct kernel *k, const struct surface *sf, const struct run *ru)
{
	if (sf->nparamsets && ru->paramset < sf->nparamsets)
		set_uniforms(k->prog, &k->layout, sf->spec->dynamic, &sf->pvals[ru->paramset], -1);
	gpu_uniform_int(k->prog, "u_first", (int)ru->first);
}

/*
 * Shade light @L (its state @st; NULL: the surface with no light) over the
 * rows of band @band of every surface, and fold the result into @dst:
 * with no light, dst = the result; else dst += sign * link * (result - base).
 */
static bool shade_pass(struct gpu_shot *s, struct light *L, const struct lstate *st, int band,
		       bool maps, const float weight[3], const float weight_recv[3],
		       struct gpu_buffer *dst)
{
	for (uint32_t si = 0; si < s->nsurfaces; si++) {
		struct surface *sf = &s->surfaces[si];
		if (!sf->runs[band].len)
			continue;
		struct kernel *k = L ? &sf->lk[L->shader] : &sf->base;
		const struct sl_program *lp = L ? s->lshaders[L->shader].prog : NULL;
		if (L) {
			set_uniforms(k->prog, &k->layout, lp, st, 0);
			gpu_uniform_mat4(k->prog, "l0_shader", L->to_camera);
			set_spaces(s, k->prog, L, st, 0);
		}
		gpu_uniform_mat4(k->prog, "space_world", s->w2c);
		struct gpu_binding b[2 + 64 + 3];
		uint32_t nb = 0;
		b[nb++] = (struct gpu_binding){ 0, false, sf->records, true };
		b[nb++] = (struct gpu_binding){ 1, true, s->scratch };
		if (!bind_maps(s, k, L, st, maps, b, &nb))
			return false;
		uint32_t ostride = k->layout.out_stride;
		for (size_t r = 0; r < sf->runs[band].len; r++) {
			const struct run *ru = &sf->runs[band].data[r];
			run_uniforms(k, sf, ru);
			if (!gpu_dispatch(s->ctx, k->prog, b, nb, ru->count))
				return fail(s, "shading '%s' on the GPU failed", sf->name);
			count_dispatch(s, ru->count);
			struct gpu_program *a = dst == s->cache ? s->accumulate_d : s->accumulate;
			gpu_uniform_int(a, "u_first", (int)ru->first);
			gpu_uniform_int(a, "u_ostride", (int)ostride);
			gpu_uniform_int(a, "u_id0", (int)sf->id0);
			gpu_uniform_int(a, "u_mode", L ? 1 : 0);
			gpu_uniform_float(a, "u_weight", weight, 3);
			gpu_uniform_float(a, "u_weight_recv", weight_recv, 3);
			struct gpu_binding ab[6] = {
				{ 0, false, s->scratch },
				{ 1, false, sf->object },
				{ 2, false, L ? L->link : s->zero },
				{ 3, false, s->base },
				{ 4, true, dst },
				{ 5, false, L && L->recv ? L->recv : s->zero },
			};
			if (!gpu_dispatch(s->ctx, a, ab, 6, ru->count))
				return fail(s, "accumulating light '%s' failed", L ? L->name : "(none)");
			count_dispatch(s, 0);
		}
	}
	return true;
}

/*
 * Shade light @L (its state @st; NULL: the surface with no light) over the
 * rows of band @band of every surface and fold the result into @dst: with
 * no light, dst = the result; else dst += sign * link * (result - base).
 * A light whose shadows are lightened or tinted is the blend of two passes,
 * without its maps and with them: unshadowed * (1 - w) + shadowed * w per
 * channel, w = st->shadow.
 */
static bool shade(struct gpu_shot *s, struct light *L, const struct lstate *st, int band,
		  float sign, struct gpu_buffer *dst)
{
	const float one[3] = { sign, sign, sign }, none[3] = { 0, 0, 0 };
	if (!L || !L->nmaps)
		return shade_pass(s, L, st, band, true, one, none, dst);
	/* an object that does not receive the light's shadows takes the
	 * unshadowed pass alone: weights 1 - w r and w r, r its receiving */
	float w[3], minus_w[3];
	bool any_w = false, all_w = true;
	for (int c = 0; c < 3; c++) {
		w[c] = sign * st->shadow[c];
		minus_w[c] = -w[c];
		any_w = any_w || w[c] != 0.0f;
		all_w = all_w && w[c] == sign;
	}
	bool unshadowed = !all_w || L->not_receiving;
	return (!unshadowed || shade_pass(s, L, st, band, false, one, minus_w, dst)) &&
	       (!any_w || shade_pass(s, L, st, band, true, none, w, dst));
}

/*
 * Can @L enter the light cache in a batch? Its shader has batch kernels,
 * it reads no shadow map (so no shadow weights) and it reaches every object.
 */
static bool batchable(const struct gpu_shot *s, const struct light *L)
{
	if (!s->nsurfaces || L->nmaps)
		return false;
	for (uint32_t i = 0; i < s->nsurfaces; i++)
		if (s->surfaces[i].nrows && (!s->surfaces[i].bk[L->shader].prog ||
					     s->surfaces[i].lk[L->shader].layout.nmaps))
			return false;
	/* (object ids stop at nobjects - 1; the last float is padding) */
	for (uint32_t o = 0; o < s->nobjects; o++)
		if (L->link_cpu[o] != 1.0f)
			return false;
	return true;
}

/* The uniforms of batch kernel @k for lights @ls[0 .. n), the last repeated in spare passes. */
static void batch_uniforms(struct gpu_shot *s, struct kernel *k, struct light *const *ls,
			   uint32_t n)
{
	const struct sl_program *lp = s->lshaders[ls[0]->shader].prog;
	for (uint32_t j = 0; j < BATCH; j++) {
		const struct light *L = ls[j < n ? j : n - 1];
		char name[32];
		set_uniforms(k->prog, &k->layout, lp, &L->cur, (int)j);
		snprintf(name, sizeof(name), "l%u_shader", j);
		gpu_uniform_mat4(k->prog, name, L->to_camera);
		set_spaces(s, k->prog, L, &L->cur, (int)j);
	}
	gpu_uniform_mat4(k->prog, "space_world", s->w2c);
	gpu_uniform_int(k->prog, "u_n", (int)n);
}

/*
 * Add lights @ls[0 .. n) (2 <= n <= BATCH, one shader, each batchable) to
 * the light cache over band @band: per surface and run, one dispatch of
 * the batch kernel, which adds to the cache itself (batch_sink).
 */
static bool shade_batch(struct gpu_shot *s, struct light *const *ls, uint32_t n, int band)
{
	for (uint32_t si = 0; si < s->nsurfaces; si++) {
		struct surface *sf = &s->surfaces[si];
		if (!sf->runs[band].len)
			continue;
		struct kernel *k = &sf->bk[ls[0]->shader];
		batch_uniforms(s, k, ls, n);
		gpu_uniform_int(k->prog, "u_id0", (int)sf->id0);
		struct gpu_binding b[3] = {
			{ 0, false, sf->records, true }, { 1, false, s->base }, { 2, true, s->cache },
		};
		for (size_t r = 0; r < sf->runs[band].len; r++) {
			const struct run *ru = &sf->runs[band].data[r];
			run_uniforms(k, sf, ru);
			if (!gpu_dispatch(s->ctx, k->prog, b, 3, ru->count))
				return fail(s, "shading a batch of lights on '%s' failed", sf->name);
			count_dispatch(s, (uint64_t)ru->count * n);
			if (s->stats)
				s->stats->batched += (uint64_t)ru->count * n;
		}
	}
	return true;
}

/* Run @p over the sample ids of band @band (u_first: each run's first id). */
static bool dispatch_band(struct gpu_shot *s, int band, struct gpu_program *p,
			  const struct gpu_binding *b, uint32_t nb, const char *what)
{
	for (uint32_t si = 0; si < s->nsurfaces; si++) {
		struct surface *sf = &s->surfaces[si];
		for (size_t r = 0; r < sf->runs[band].len; r++) {
			const struct run *ru = &sf->runs[band].data[r];
			gpu_uniform_int(p, "u_first", (int)(sf->id0 + ru->first));
			if (!gpu_dispatch(s->ctx, p, b, nb, ru->count))
				return fail(s, "%s failed", what);
			count_dispatch(s, 0);
		}
	}
	return true;
}

/* colors = base + cache over band @band's samples. */
static bool combine(struct gpu_shot *s, int band)
{
	struct gpu_binding b[3] = {
		{ 0, false, s->base }, { 1, true, s->cache }, { 2, true, s->colors },
	};
	return dispatch_band(s, band, s->combine, b, 3, "combining the light cache");
}

/* Zero the light cache over band @band's samples. */
static bool clear_band(struct gpu_shot *s, int band)
{
	struct gpu_binding b[1] = { { 0, true, s->cache } };
	return dispatch_band(s, band, s->clear, b, 1, "clearing the light cache");
}

static bool light_on(const struct gpu_shot *s, uint32_t i)
{
	return !s->lights[i].muted && !s->lights[i].removed && (s->solo < 0 || s->solo == (int)i);
}

/*
 * The shading node of band @band: bring the light cache of the band up to
 * date with every light's state, then the band's colours.
 */
static bool run_shade(struct graph_node *n, void *user, bool *changed)
{
	(void)n;
	struct gpu_shot *s = user;
	int band = -1;
	for (int b = 0; b < NBANDS; b++)
		if (s->shade[b] == n)
			band = b;
	if (band < 0)
		return false;
	*changed = true;
	for (uint32_t i = 0; i < s->nlights; i++) {
		s->lights[i].cur.on = light_on(s, i);
		s->lights[i].cur.link = s->lights[i].link_version;
		s->lights[i].cur.valid = true;
		for (int c = 0; c < 3; c++)
			s->lights[i].cur.shadow[c] =
				s->lights[i].shadows_off ? 0.0f
				: s->lights[i].shadow_density * (1.0f - s->lights[i].shadow_color[c]);
	}
	struct lstate *cached = s->cached[band];
	bool rebuild = !s->base_valid[band];
	/* a link change of a light in the cache: its old links are gone */
	for (uint32_t i = 0; i < s->nlights && !rebuild; i++)
		if (cached[i].valid && cached[i].link != s->lights[i].link_version)
			rebuild = true;
	if (!s->base_valid[band]) {
		if (!shade(s, NULL, NULL, band, 1.0f, s->base))
			return false;
		s->base_valid[band] = true;
	}
	if (rebuild) {
		if (!clear_band(s, band))
			return false;
		for (uint32_t i = 0; i < s->nlights; i++)
			lstate_free(&cached[i]);
	}
	/* lights entering the cache that can go in batches, by shader */
	struct light **pending = rl_xmalloc((s->nlights + 1) * sizeof(*pending));
	uint32_t npending = 0;
	bool ok = true;
	for (uint32_t i = 0; ok && i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		struct lstate *c = &cached[i];
		bool want = L->frozen;
		if (c->valid && (!want || !lstate_equal(c, &L->cur))) {
			/* take the old contribution out */
			if (c->on && !shade(s, L, c, band, -1.0f, s->cache))
				ok = false;
			lstate_free(c);
		}
		if (ok && want && !c->valid) {
			if (L->cur.on && batchable(s, L))
				pending[npending++] = L;
			else if (L->cur.on && !shade(s, L, &L->cur, band, 1.0f, s->cache))
				ok = false;
			lstate_copy(c, &L->cur);
		}
	}
	/* each shader's pending lights BATCH at a time; one left alone goes alone */
	for (uint32_t i = 0; ok && i < npending; i++) {
		if (!pending[i])
			continue;
		struct light *batch[BATCH];
		uint32_t n = 0, shader = pending[i]->shader;
		for (uint32_t j = i; j < npending && n < BATCH; j++)
			if (pending[j] && pending[j]->shader == shader) {
				batch[n++] = pending[j];
				pending[j] = NULL;
			}
		ok = n == 1 ? shade(s, batch[0], &batch[0]->cur, band, 1.0f, s->cache)
			    : shade_batch(s, batch, n, band);
	}
	free(pending);
	if (!ok)
		return false;
	if (!combine(s, band))
		return false;
	for (uint32_t i = 0; i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		if (!L->frozen && L->cur.on && !shade(s, L, &L->cur, band, 1.0f, s->colors))
			return false;
	}
	return true;
}

/* The resolve node of level @L. */
static bool run_resolve(struct graph_node *n, void *user, bool *changed)
{
	struct gpu_shot *s = user;
	int level = -1;
	for (int b = 0; b < NBANDS; b++)
		if (s->resolve[b] == n)
			level = b;
	*changed = true;
	if (level < 0 || !gpu_ifb_resolve(s->ifb, s->colors, s->nsamples, level, s->rgba[level]))
		return fail(s, "resolving level %d failed", level);
	count_dispatch(s, 0);
	if (s->stats)
		s->stats->entries = s->level_entries[level];
	return true;
}

/* The imager node of level @L: the imager over the resolved image. */
static bool run_image(struct graph_node *n, void *user, bool *changed)
{
	struct gpu_shot *s = user;
	int level = -1;
	for (int b = 0; b < NBANDS; b++)
		if (s->image[b] == n)
			level = b;
	*changed = true;
	if (level < 0 || !gpu_imager_run(s->imager, s->rgba[level], s->imaged[level]))
		return fail(s, "the imager pass of level %d failed", level);
	count_dispatch(s, 0);
	count_dispatch(s, 0);
	count_dispatch(s, 0);
	return true;
}

/* The node whose image level @level shows, and the buffer it is in. */
static struct graph_node *level_node(const struct gpu_shot *s, int level)
{
	return s->imager ? s->image[level] : s->resolve[level];
}

static struct gpu_buffer *level_image(const struct gpu_shot *s, int level)
{
	return s->imager ? s->imaged[level] : s->rgba[level];
}

static bool light_from_to(struct gpu_shot *s, const struct light *L, float from[3],
			  float to[3]);

/*
 * The camera of a map that follows its light: @w2c and @w2ndc (the file's
 * camera on entry) moved to look from @from to @to (world space), keeping
 * the projection, the handedness and, as far as it can, the up direction.
 */
static bool follow_camera(const float from[3], const float to[3], float w2c[16], float w2ndc[16])
{
	float c2w[16], proj[16];
	if (!sl_m44_inverse(c2w, w2c))
		return false;
	sl_m44_mul(proj, c2w, w2ndc);   /* camera -> NDC */
	float ax[3][3];
	for (int r = 0; r < 3; r++) {
		float len = sqrtf(c2w[r * 4] * c2w[r * 4] + c2w[r * 4 + 1] * c2w[r * 4 + 1] +
				  c2w[r * 4 + 2] * c2w[r * 4 + 2]);
		if (!(len > 0.0f))
			return false;
		for (int c = 0; c < 3; c++)
			ax[r][c] = c2w[r * 4 + c] / len;
	}
	float z[3] = { to[0] - from[0], to[1] - from[1], to[2] - from[2] };
	float zl = sqrtf(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
	if (!(zl > 0.0f) || !isfinite(zl))
		return false;
	for (int c = 0; c < 3; c++)
		z[c] /= zl;
	/* handedness of the file's camera: x = sign * (y cross z) */
	float yz[3] = { ax[1][1] * ax[2][2] - ax[1][2] * ax[2][1], ax[1][2] * ax[2][0] - ax[1][0] * ax[2][2],
			ax[1][0] * ax[2][1] - ax[1][1] * ax[2][0] };
	float sign = ax[0][0] * yz[0] + ax[0][1] * yz[1] + ax[0][2] * yz[2] < 0.0f ? -1.0f : 1.0f;
	float x[3] = { ax[1][1] * z[2] - ax[1][2] * z[1], ax[1][2] * z[0] - ax[1][0] * z[2],
		       ax[1][0] * z[1] - ax[1][1] * z[0] };
	float xl = sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
	if (!(xl > 1e-4f)) {
		/* looking along the old up: keep the old x, made square to z */
		float d = ax[0][0] * z[0] + ax[0][1] * z[1] + ax[0][2] * z[2];
		for (int c = 0; c < 3; c++)
			x[c] = sign * (ax[0][c] - d * z[c]);
		xl = sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
		if (!(xl > 0.0f))
			return false;
	}
	for (int c = 0; c < 3; c++)
		x[c] = sign * x[c] / xl;
	float y[3] = { sign * (z[1] * x[2] - z[2] * x[1]), sign * (z[2] * x[0] - z[0] * x[2]),
		       sign * (z[0] * x[1] - z[1] * x[0]) };
	float cw[16] = { x[0], x[1], x[2], 0, y[0], y[1], y[2], 0,
			 z[0], z[1], z[2], 0, from[0], from[1], from[2], 1 };
	if (!sl_m44_inverse(w2c, cw))
		return false;
	sl_m44_mul(w2ndc, w2c, proj);
	return true;
}

/*
 * Light @L's deep map at site @i rendered again from the shadow geometry
 * with camera @w2c, @w2ndc (gpu/shadowrender.h), into L->rmaps[i]. Where
 * it cannot be (a shot without opacity in its shadow geometry, a map over
 * the GPU's bounds), the baked map is kept, said once per light. False on
 * a GPU failure.
 */
static bool render_deep(struct gpu_shot *s, struct light *L, uint32_t i, const float w2c[16],
			const float w2ndc[16], uint32_t w, uint32_t h)
{
	const struct gpu_deep_opts o = {
		.samples = GPU_DEEP_SAMPLES,
		.error = REYES_DEEP_DEFAULT_ERROR,
		.threshold = GPU_DEEP_THRESHOLD,
	};
	char err[256];
	struct gpu_deep_stats st;
	struct gpu_buffer *b = gpu_shadow_geometry_render_deep(s->ctx, s->shadow_geo, w2c, w2ndc,
							       w, h, &o, L->cast_cpu,
							       s->nobjects, &st, err, sizeof(err));
	s->deep_stats = st;
	s->deep_maps_rendered += b != NULL;
	if (!b) {
		if (!L->warned_deep)
			fprintf(s->diag, "relight: warning: light '%s': its deep shadow map '%s' "
				"is not rendered again on the GPU: %s; the baked map is used as it "
				"is\n", L->name, L->map_names[i], err);
		L->warned_deep = true;
		return true;
	}
	L->rmaps[i] = gpu_shadow_map_with_deep(L->maps[i], b, st.bytes);
	if (!L->rmaps[i]) {
		gpu_buffer_destroy(b);
		return fail(s, "out of memory");
	}
	gpu_shadow_map_set_camera(L->rmaps[i], w2c, w2ndc);
	return true;
}

/*
 * The shadow geometry's ray-tracing hierarchy, built on first use (a light
 * whose shadow map is named "raytrace"). False when the shot has no shadow
 * geometry or the hierarchy cannot be built (said on diag).
 */
static bool shadow_hierarchy(struct gpu_shot *s)
{
	if (s->shadow_bvh)
		return true;
	if (!s->shadow_geo)
		return false;
	char err[512];
	size_t before = gpu_shadow_geometry_bytes(s->shadow_geo);
	if (!gpu_shadow_bvh_build(s->shadow_geo, err, sizeof(err))) {
		fprintf(s->diag, "relight: warning: %s: %s\n", s->path, err);
		return false;
	}
	s->bytes += gpu_shadow_geometry_bytes(s->shadow_geo) - before;
	s->shadow_bvh = true;
	return true;
}

/* A light's shadow-map node: the maps its kernels' shadow() sites read. */
static bool run_shadow(struct graph_node *n, void *user, bool *changed)
{
	struct gpu_shot *s = user;
	struct light *L = NULL;
	for (uint32_t i = 0; i < s->nlights; i++)
		if (s->lights[i].shadow_node == n)
			L = &s->lights[i];
	if (!L)
		return false;
	*changed = false;
	/* the sites are the same in every surface's kernel for this light shader */
	const struct kernel *k = &s->surfaces[0].lk[L->shader];
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	for (uint32_t i = 0; i < k->layout.nshadows; i++) {
		const struct sl_glsl_shadow_site *site = &k->layout.shadows[i];
		const char *name = site->name ? site->name : "";
		if (site->param) {
			/* the current value of the string parameter */
			uint32_t si = 0;
			for (uint32_t p = 0; p < lp->nparams; p++) {
				if (lp->regs[lp->params[p].reg].type != SL_TYPE_STRING)
					continue;
				if (!strcmp(lp->params[p].name, site->param) && si < L->cur.ns)
					name = L->cur.s[si];
				si++;
			}
		}
		if (L->map_names[i] && !strcmp(L->map_names[i], name))
			continue;
		free(L->map_names[i]);
		L->map_names[i] = rl_xstrdup(name);
		gpu_shadow_map_destroy(L->maps[i]);
		L->maps[i] = NULL;
		*changed = true;
		if (!site->raytrace && !strcmp(name, "raytrace")) {
			if (!L->warned_rt)
				fprintf(s->diag, "relight: warning: light '%s': its shadow is \"raytrace\" "
					"now, which the shot's kernels do not trace (no light traced its "
					"shadows when the shot was loaded): no shadow in the preview\n",
					L->name);
			L->warned_rt = true;
		} else if (site->raytrace && !strcmp(name, "raytrace")) {
			if (!shadow_hierarchy(s) && !L->warned_rt) {
				fprintf(s->diag, "relight: warning: light '%s': its ray-traced shadow is "
					"not previewed (the shot has no shadow geometry to trace: bake "
					"it again)\n", L->name);
				L->warned_rt = true;
			}
		} else if (name[0]) {
			char err[512];
			L->maps[i] = gpu_shadow_map_load(s->ctx, s->tex, name, err, sizeof(err));
			if (!L->maps[i])
				fprintf(s->diag, "relight: warning: light '%s': %s\n", L->name, err);
		}
		L->rendered_version = 0;
	}
	/* objects left out of casting, or cameras following the light: render
	 * the maps again from the geometry */
	float key[6] = { 0 };
	bool moved = false;
	if (L->follow) {
		if (!light_from_to(s, L, key, key + 3))
			return fail(s, "light '%s' has no 'from' and 'to' points for its shadow "
				    "maps to follow", L->name);
		moved = memcmp(key, L->follow_key, sizeof(key)) != 0;
	}
	if ((L->not_casting || L->follow) && (L->rendered_version != L->cast_version || moved)) {
		for (uint32_t i = 0; i < L->nmaps; i++) {
			gpu_shadow_map_destroy(L->rmaps[i]);
			L->rmaps[i] = NULL;
			if (!L->maps[i] || !s->shadow_geo)
				continue;
			uint32_t w, h;
			float w2c[16], w2ndc[16];
			gpu_shadow_map_size(L->maps[i], &w, &h);
			gpu_shadow_map_camera(L->maps[i], w2c, w2ndc);
			if (L->follow && !follow_camera(key, key + 3, w2c, w2ndc))
				return fail(s, "light '%s': its shadow camera cannot look from its "
					    "'from' to its 'to'", L->name);
			if (gpu_shadow_map_is_deep(L->maps[i])) {
				if (!render_deep(s, L, i, w2c, w2ndc, w, h))
					return false;
				continue;
			}
			if (!L->rdepth[i])
				L->rdepth[i] = gpu_buffer_create(s->ctx, (size_t)w * h * sizeof(float), NULL);
			if (!L->rdepth[i] ||
			    !gpu_shadow_geometry_render(s->ctx, s->shadow_geo, w2c, w2ndc, w, h,
							GPU_DEPTH_MIDPOINT, L->cast_cpu, s->nobjects,
							L->rdepth[i]))
				return fail(s, "rendering the shadow map of light '%s' failed", L->name);
			L->rmaps[i] = gpu_shadow_map_with_depth(L->maps[i], L->rdepth[i]);
			if (!L->rmaps[i])
				return fail(s, "out of memory");
			gpu_shadow_map_set_camera(L->rmaps[i], w2c, w2ndc);
		}
		L->rendered_version = L->cast_version;
		memcpy(L->follow_key, key, sizeof(key));
		/* what the cache holds of the light was shaded with the old maps */
		L->link_version = ++s->link_version;
		*changed = true;
	}
	return true;
}

/* ------------------------------------------------------------------------ */
/* Loading                                                                   */

static struct gpu_buffer *buffer(struct gpu_shot *s, size_t bytes, const void *data)
{
	if (s->bytes + bytes > s->budget) {
		fail(s, "the shot needs more than its GPU memory budget of %.0f MiB (at least "
		     "%.0f MiB); raise the budget or bake with smaller tiles",
		     (double)s->budget / 1048576.0, (double)(s->bytes + bytes) / 1048576.0);
		return NULL;
	}
	struct gpu_buffer *b = gpu_buffer_create(s->ctx, bytes ? bytes : 4, data);
	if (!b)
		fail(s, "out of GPU memory (%zu bytes)", bytes);
	else
		s->bytes += bytes;
	return b;
}

/*
 * Without map sites in its kernels (no derivative stencils: a shot baked
 * without light derivatives) the GPU reads no texture or environment file: warn, naming the light and
 * the file, when a light's texture() or environment() would read one (a
 * string parameter that names it, such as uberlight's slide, set to a file):
 * the preview then differs from the final frame where that light falls.
 */
static void warn_textures(struct gpu_shot *s, const struct light *L)
{
	const struct sl_program *p = s->lshaders[L->shader].prog;
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		if (in->op != SL_OP_CALL || in->bi < 0 || in->nargs < 1)
			continue;
		int id = sl_builtins[in->bi].id;
		if (id != SL_BI_TEXTURE && id != SL_BI_ENVIRONMENT)
			continue;
		/* the name's register, back through copies, to a parameter */
		int32_t r = in->args[0];
		for (int hop = 0; hop < 8; hop++) {
			int32_t from = -1;
			for (uint32_t k = 0; k < p->ncode && from < 0; k++)
				if (p->code[k].op == SL_OP_MOV && p->code[k].dst == r &&
				    p->code[k].nargs == 1)
					from = p->code[k].args[0];
			bool is_param = false;
			for (uint32_t k = 0; k < p->nparams; k++)
				is_param = is_param || p->params[k].reg == r;
			if (is_param || from < 0)
				break;
			r = from;
		}
		uint32_t si = 0;
		for (uint32_t k = 0; k < p->nparams; k++) {
			if (p->regs[p->params[k].reg].type != SL_TYPE_STRING)
				continue;
			if (p->params[k].reg == r && si < L->cur.ns && L->cur.s[si][0])
				fprintf(s->diag, "relight: warning: %s: light '%s' reads %s '%s' "
					"(parameter '%s'), which the GPU does not read: the preview "
					"differs from the final frame where the light falls\n", s->path,
					L->name, sl_builtins[in->bi].name, L->cur.s[si],
					p->params[k].name);
			si++;
		}
	}
}

/* Does some kernel of light shader @k read texture or environment maps? */
static bool reads_texmaps(const struct gpu_shot *s, uint32_t k)
{
	for (uint32_t i = 0; i < s->nsurfaces; i++)
		if (s->surfaces[i].lk && s->surfaces[i].lk[k].layout.nmaps)
			return true;
	return false;
}

/*
 * Load the maps the lights' parameters name when the shot loads, so that
 * a missing one is reported then and the first frame pays no upload; warn
 * about lights whose kernels cannot read theirs.
 */
static void load_texmaps(struct gpu_shot *s)
{
	for (uint32_t i = 0; i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		if (!reads_texmaps(s, L->shader)) {
			warn_textures(s, L);
			continue;
		}
		char who[300];
		snprintf(who, sizeof(who), "%s: light '%s'", s->path, L->name);
		for (uint32_t j = 0; j < s->nsurfaces; j++) {
			const struct kernel *k = &s->surfaces[j].lk[L->shader];
			for (uint32_t m = 0; m < k->layout.nmaps; m++)
				gpu_texmaps_get(s->texmaps, site_map_name(s->lshaders[L->shader].prog,
									  &L->cur, &k->layout.maps[m]),
						who, budget_room(s));
		}
	}
}

/*
 * Free the maps nothing reads any more: not named by a light's parameters
 * nor by what the light cache holds of a light (which is shaded again with
 * those to take it out).
 */
static void sweep_texmaps(struct gpu_shot *s)
{
	RL_VEC(const char *) names = { 0 };
	for (uint32_t i = 0; i < s->nlights; i++) {
		const struct light *L = &s->lights[i];
		for (uint32_t k = 0; k < L->cur.ns; k++)
			rl_vec_push(names, L->cur.s[k]);
		for (int b = 0; b < NBANDS; b++)
			for (uint32_t k = 0; s->cached[b] && k < s->cached[b][i].ns; k++)
				rl_vec_push(names, s->cached[b][i].s[k]);
	}
	gpu_texmaps_keep_only(s->texmaps, names.data, (uint32_t)names.len);
	rl_vec_free(names);
}

static bool load_lights(struct gpu_shot *s)
{
	const cJSON *ls = cJSON_GetObjectItemCaseSensitive(s->meta, "lights");
	int n = cJSON_GetArraySize(ls);
	s->lights = rl_xcalloc((size_t)n + 1, sizeof(*s->lights));
	s->lshaders = rl_xcalloc((size_t)n + MAX_ADDED_SHADERS, sizeof(*s->lshaders));
	const cJSON *l;
	cJSON_ArrayForEach(l, ls) {
		struct light *L = &s->lights[s->nlights];
		const char *name = shot_meta_str(l, "name"), *hash = shot_meta_str(l, "program_hash");
		bool by_program = hash != NULL;   /* shots of earlier versions: the source text's */
		if (!by_program)
			hash = shot_meta_str(l, "source_hash");
		float s2w[16];
		if (!name || !hash || !shot_meta_matrix(l, "shader_to_world", s2w))
			return fail(s, "a light in the metadata is malformed");
		L->name = rl_xstrdup(name);
		/* counted from here, so that closing frees what it holds */
		s->nlights++;
		sl_m44_mul(L->to_camera, s2w, s->w2c);
		uint32_t k = 0;
		while (k < s->nlshaders &&
		       strcmp(by_program ? sl_program_hash(s->lshaders[k].prog)
					 : s->lshaders[k].prog->source_hash, hash))
			k++;
		if (k == s->nlshaders) {
			struct sl_program *p = shot_meta_shader(l, s->path, s->diag);
			if (!p)
				return false;
			s->lshaders[k].prog = p;
			s->lshaders[k].init = *p;
			s->lshaders[k].init.ncode = p->body_begin;
			s->nlshaders++;
		}
		L->shader = k;
		L->init = sl_exec_create(&s->lshaders[k].init, 1);
		if (!L->init || !shot_meta_set_params(L->init, cJSON_GetObjectItemCaseSensitive(
							      l, "params"), s->path, s->diag))
			return fail(s, "cannot set up light '%s'", name);
		L->cur.on = true;
		if (!eval_params(L->init, s->lshaders[k].prog, L->to_camera, s->w2c, &L->cur))
			return fail(s, "light '%s': its parameter defaults failed", name);
		for (uint32_t q = 0; q < L->cur.ns; q++)
			s->traces_shadows |= L->cur.s[q] && !strcmp(L->cur.s[q], "raytrace");
		L->frozen = true;
		L->shadow_density = 1.0f;
		L->node = graph_add(s->graph, name, GRAPH_PARAMS, NULL, NULL);
	}
	return true;
}

/*
 * Emit and compile kernel @k of surface @sf with light shader @light (NULL:
 * none); with @batch, BATCH passes of it, one light each.
 */
static bool make_kernel(struct gpu_shot *s, struct surface *sf, const struct sl_program *light,
			struct kernel *k, const uint8_t *steps, bool batch)
{
	struct sl_slice slice = sf->spec->slice;
	slice.input_steps = steps;
	slice.raytrace_shadows = s->traces_shadows;
	slice.per_light = batch;
	slice.sink = batch ? batch_sink : NULL;
	/* the colour alone: the opacity comes with the pixels, output
	 * parameters reach no image */
	int32_t ci = sf->prog->global_reg[SL_GLOBAL_CI];
	for (uint32_t i = 0; i < slice.noutputs; i++)
		if (slice.outputs[i] == ci) {
			slice.outputs = &slice.outputs[i];
			slice.noutputs = 1;
			break;
		}
	if (slice.noutputs != 1 || slice.outputs[0] != ci)
		return fail(s, "surface '%s' sets no colour (Ci)", sf->name);
	const struct sl_program *lights[BATCH];
	for (int i = 0; i < BATCH; i++)
		lights[i] = light;
	k->glsl = sl_glsl_emit(&slice, lights, !light ? 0 : batch ? BATCH : 1, &k->layout, s->diag);
	if (!k->glsl)
		return fail(s, "surface '%s'%s%s cannot run on the GPU", sf->name,
			    light ? " lit by " : "", light ? light->name : "");
	k->prog = gpu_program(s->ctx, k->glsl, s->diag);
	if (!k->prog)
		return fail(s, "the GPU program of surface '%s'%s%s does not compile", sf->name,
			    light ? " with light " : "", light ? light->name : "");
	if (k->layout.in_stride != sf->base.layout.in_stride)
		return fail(s, "the kernels of surface '%s' disagree on their inputs", sf->name);
	return true;
}

/* Rows [lo, hi) of @sf as a band's runs, split by paramset (rows already sorted). */
static void add_runs(struct surface *sf, int band, uint64_t lo, uint64_t hi,
		     const uint32_t *paramset)
{
	while (lo < hi) {
		uint64_t e = lo + 1;
		uint32_t ps = paramset ? paramset[lo] : 0;
		while (e < hi && (!paramset || paramset[e] == ps))
			e++;
		struct run r = { (uint32_t)lo, (uint32_t)(e - lo), ps };
		rl_vec_push(sf->runs[band], r);
		lo = e;
	}
}

static const uint32_t *uint_channel(const struct shot_table *t, const char *name)
{
	for (uint32_t c = 0; c < t->nchannels; c++)
		if (!strcmp(t->channels[c].name, name) && t->channels[c].type == SHOT_UINT)
			return t->channels[c].data;
	return NULL;
}

/* A permutation sort key: (paramset, row). */
struct rowkey {
	uint32_t ps;
	uint32_t row;
};

static int rowkey_cmp(const void *a, const void *b)
{
	const struct rowkey *x = a, *y = b;
	if (x->ps != y->ps)
		return x->ps < y->ps ? -1 : 1;
	return x->row < y->row ? -1 : x->row > y->row;
}

static bool load_surface(struct gpu_shot *s, const struct shot_file *f, uint32_t si,
			 const cJSON *tiles, uint32_t *remap, uint32_t *lightset_of_object,
			 uint32_t nobjects)
{
	struct surface *sf = &s->surfaces[si];
	const char *table = shot_meta_str(sf->meta, "table");
	const struct shot_table *t = table ? shot_find_table(f, table) : NULL;
	const cJSON *first = cJSON_GetObjectItemCaseSensitive(sf->meta, "first_id");
	if (!t || !cJSON_IsNumber(first) || first->valuedouble < 0 ||
	    first->valuedouble + (double)t->nrows > (double)s->nsamples || t->nrows > INT32_MAX)
		return fail(s, "the surface table '%s' is missing or does not fit",
			    table ? table : "?");
	sf->nrows = t->nrows;
	sf->id0 = (uint64_t)first->valuedouble;
	sf->prog = shot_meta_shader(sf->meta, s->path, s->diag);
	if (!sf->prog)
		return false;
	sf->name = rl_xstrdup(sf->prog->name);
	sf->spec = shot_meta_specialize(s->meta, sf->meta, sf->prog, s->diag);
	if (!sf->spec)
		return fail(s, "cannot specialize surface '%s'", sf->name);
	struct sl_spec *sp = sf->spec;
	uint8_t *steps = NULL;
	if (sp->needs_stencil) {
		steps = rl_xcalloc(sp->ncached + 1, 1);
		memcpy(steps, sp->cached_deriv, sp->ncached);
	}
	/* kernels: the surface alone, then with each light shader */
	bool ok = make_kernel(s, sf, NULL, &sf->base, steps, false);
	if (ok && sp->needs_stencil && !sf->base.layout.in_step_u)
		ok = fail(s, "surface '%s' needs derivative stencils, which its GPU program "
			  "does not take", sf->name);
	sf->lk = rl_xcalloc(s->nlshaders + MAX_ADDED_SHADERS, sizeof(*sf->lk));
	for (uint32_t k = 0; ok && k < s->nlshaders; k++)
		ok = make_kernel(s, sf, s->lshaders[k].prog, &sf->lk[k], steps, false);
	/* batches for the shaders of two lights or more that read no shadow map */
	sf->bk = rl_xcalloc(s->nlshaders + MAX_ADDED_SHADERS, sizeof(*sf->bk));
	for (uint32_t k = 0; ok && k < s->nlshaders; k++) {
		uint32_t users = 0;
		for (uint32_t i = 0; i < s->nlights; i++)
			users += s->lights[i].shader == k;
		if (users >= 2 && !sf->lk[k].layout.nshadows && !sf->lk[k].layout.nmaps &&
		    !make_kernel(s, sf, s->lshaders[k].prog, &sf->bk[k], steps, true)) {
			ok = false;
		}
	}
	free(steps);
	if (!ok)
		return false;
	/* the parameter values of each paramset */
	sf->init = *sp->dynamic;
	sf->init.ncode = sp->dynamic->body_begin;
	sf->init_x = sl_exec_create(&sf->init, 1);
	const uint32_t *paramset = uint_channel(t, "paramset");
	const cJSON *psets = cJSON_GetObjectItemCaseSensitive(sf->meta, "param_sets");
	sf->nparamsets = paramset ? (uint32_t)cJSON_GetArraySize(psets) : 0;
	if (paramset && !sf->nparamsets)
		return fail(s, "surface '%s' has per-object parameters but no values", sf->name);
	sf->pvals = rl_xcalloc(sf->nparamsets + 1, sizeof(*sf->pvals));
	for (uint32_t ps = 0; ps < sf->nparamsets; ps++) {
		sl_exec_reset_params(sf->init_x);
		if (!sf->init_x ||
		    !shot_meta_set_params(sf->init_x, cJSON_GetArrayItem(psets, (int)ps), s->path,
					  s->diag) ||
		    !eval_params(sf->init_x, sp->dynamic, NULL, s->w2c, &sf->pvals[ps]))
			return fail(s, "surface '%s': its parameter values failed", sf->name);
	}
	if (!sf->nparamsets && sf->init_x) {
		/* one set: the defaults (and whatever the slice reads as a uniform) */
		sf->pvals[0].on = true;
		eval_params(sf->init_x, sp->dynamic, NULL, s->w2c, &sf->pvals[0]);
		sf->nparamsets = 1;
		paramset = NULL;
	}

	/* rows: per tile, per band; sorted by paramset within each range */
	const uint32_t *object = uint_channel(t, "object");
	const uint32_t *lightset = uint_channel(t, "lightset");
	uint32_t *perm = rl_xmalloc((sf->nrows + 1) * sizeof(uint32_t));
	for (uint64_t i = 0; i < sf->nrows; i++)
		perm[i] = (uint32_t)i;
	uint32_t *ps_sorted = paramset ? rl_xmalloc((sf->nrows + 1) * sizeof(uint32_t)) : NULL;
	if (ps_sorted)
		memcpy(ps_sorted, paramset, sf->nrows * sizeof(uint32_t));
	const cJSON *tile;
	cJSON_ArrayForEach(tile, tiles) {
		const cJSON *g = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(tile, "surfaces"),
						    (int)si);
		const cJSON *fr = cJSON_GetObjectItemCaseSensitive(g, "first_row");
		const cJSON *lv = cJSON_GetObjectItemCaseSensitive(g, "levels");
		if (!cJSON_IsNumber(fr) || fr->valuedouble < 0 || cJSON_GetArraySize(lv) != NBANDS) {
			free(perm);
			free(ps_sorted);
			return fail(s, "the tiling of surface '%s' in the metadata is malformed",
				    sf->name);
		}
		uint64_t base = (uint64_t)fr->valuedouble, prev = 0;
		for (int b = 0; b < NBANDS; b++) {
			const cJSON *c = cJSON_GetArrayItem(lv, b);
			double cnt = cJSON_IsNumber(c) ? c->valuedouble : -1;
			if (cnt < (double)prev || base + cnt > (double)sf->nrows) {
				free(perm);
				free(ps_sorted);
				return fail(s, "the tiling of surface '%s' does not fit its table",
					    sf->name);
			}
			uint64_t lo = base + prev, hi = base + (uint64_t)cnt;
			if (ps_sorted && hi > lo) {
				struct rowkey *keys = rl_xmalloc((hi - lo) * sizeof(*keys));
				for (uint64_t r = lo; r < hi; r++)
					keys[r - lo] = (struct rowkey){ paramset[r], (uint32_t)r };
				qsort(keys, hi - lo, sizeof(*keys), rowkey_cmp);
				for (uint64_t r = lo; r < hi; r++) {
					perm[r] = keys[r - lo].row;
					ps_sorted[r] = keys[r - lo].ps;
				}
				free(keys);
			}
			add_runs(sf, b, lo, hi, ps_sorted);
			prev = (uint64_t)cnt;
		}
	}
	/* the ids of the framebuffer: old row -> new row */
	for (uint64_t r = 0; r < sf->nrows; r++)
		remap[sf->id0 + perm[r]] = (uint32_t)(sf->id0 + r);
	free(ps_sorted);

	/* the records, uploaded a tile's rows at a time */
	const struct sl_glsl_layout *lay = &sf->base.layout;
	uint32_t stride = lay->in_stride;
	uint32_t *off = rl_xcalloc(sp->ncached + 1, sizeof(uint32_t));
	uint32_t cstride = sl_spec_cache_layout(sp, off);
	const cJSON *chans = cJSON_GetObjectItemCaseSensitive(sf->meta, "channels");
	/* per record float: its source column */
	const float **col = rl_xcalloc((size_t)stride + 1, sizeof(float *));
	float **owned = rl_xcalloc((size_t)stride * 3 + 3, sizeof(float *));
	uint32_t nowned = 0;
	for (uint32_t k = 0; ok && k < sp->ncached; k++) {
		uint32_t end = k + 1 < sp->ncached ? off[k + 1] : cstride;
		for (uint32_t c = 0; ok && c < end - off[k]; c++) {
			char nm[64];
			snprintf(nm, sizeof(nm), "c%03u.%02u", k, c);
			uint32_t at = lay->in_offset[k] + c;
			ok = at < stride;
			if (ok)
				col[at] = shot_meta_channel(t, chans, nm, &owned[nowned]);
			if (ok && owned[nowned])
				nowned++;
			ok = ok && col[at];
			if (ok && lay->in_step_u && lay->in_step_u[k] != UINT32_MAX) {
				snprintf(nm, sizeof(nm), "u%03u.%02u", k, c);
				col[lay->in_step_u[k] + c] =
					shot_meta_channel(t, chans, nm, &owned[nowned]);
				if (owned[nowned])
					nowned++;
				snprintf(nm, sizeof(nm), "v%03u.%02u", k, c);
				col[lay->in_step_v[k] + c] =
					shot_meta_channel(t, chans, nm, &owned[nowned]);
				if (owned[nowned])
					nowned++;
				ok = col[lay->in_step_u[k] + c] && col[lay->in_step_v[k] + c];
			}
		}
	}
	if (ok && lay->in_step_u && lay->du_offset != UINT32_MAX) {
		col[lay->du_offset] = shot_meta_channel(t, chans, "du", &owned[nowned]);
		if (owned[nowned])
			nowned++;
		col[lay->dv_offset] = shot_meta_channel(t, chans, "dv", &owned[nowned]);
		if (owned[nowned])
			nowned++;
		ok = col[lay->du_offset] && col[lay->dv_offset];
	}
	/* floats no channel fills pad the record to whole texels: 0 */
	free(off);
	if (!ok)
		fail(s, "the table '%s' does not hold what shader '%s' caches (bake again)", table,
		     sf->name);
	if (ok)
		sf->records = buffer(s, (size_t)sf->nrows * stride * sizeof(float) + 4, NULL);
	if (ok && sf->records) {
		/* one tile's rows at a time: staging stays a tile's size */
		cJSON_ArrayForEach(tile, tiles) {
			const cJSON *g = cJSON_GetArrayItem(
				cJSON_GetObjectItemCaseSensitive(tile, "surfaces"), (int)si);
			uint64_t lo = (uint64_t)cJSON_GetObjectItemCaseSensitive(g, "first_row")
					      ->valuedouble;
			uint64_t hi = lo + (uint64_t)cJSON_GetArrayItem(
						   cJSON_GetObjectItemCaseSensitive(g, "levels"),
						   NBANDS - 1)->valuedouble;
			if (hi <= lo)
				continue;
			float *rec = rl_xmalloc((hi - lo) * stride * sizeof(float));
			for (uint64_t r = lo; r < hi; r++)
				for (uint32_t c = 0; c < stride; c++) {
					float v = col[c] ? col[c][perm[r]] : 0.0f;
					rec[(r - lo) * stride + c] = isfinite(v) ? v : 0.0f;
				}
			ok = gpu_buffer_write(sf->records, lo * stride * sizeof(float),
					      (hi - lo) * stride * sizeof(float), rec);
			free(rec);
			if (!ok) {
				fail(s, "uploading the samples of '%s' failed", sf->name);
				break;
			}
		}
	} else {
		ok = false;
	}
	float *obj = ok ? rl_xmalloc((sf->nrows + 1) * sizeof(float)) : NULL;
	for (uint64_t r = 0; ok && r < sf->nrows; r++) {
		uint32_t o = object ? object[perm[r]] : 0;
		if (o >= nobjects)
			o = 0;
		obj[r] = (float)o;
		if (lightset && lightset_of_object[o] == UINT32_MAX)
			lightset_of_object[o] = lightset[perm[r]];
	}
	if (ok)
		sf->object = buffer(s, (sf->nrows + 1) * sizeof(float), obj);
	ok = ok && sf->object;
	free(obj);
	for (uint32_t i = 0; i < nowned; i++)
		free(owned[i]);
	free(owned);
	free(col);
	free(perm);
	return ok;
}

static uint32_t json_uint(const cJSON *o, const char *key)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	return cJSON_IsNumber(v) && v->valuedouble >= 0 && v->valuedouble < 4294967295.0
		       ? (uint32_t)v->valuedouble : 0;
}

/*
 * The shadow geometry (shadow.points, shadow.quads), for maps rendered when
 * casting is edited per object. Without it (or without the GPU's support)
 * casting cannot be edited; nothing else changes. A shot baked before the
 * micropolygons' opacity was recorded (no "opacity" channel) renders depth
 * maps from it but not deep ones.
 */
static void load_shadow_geometry(struct gpu_shot *s, const struct shot_file *f)
{
	const struct shot_table *pt = shot_find_table(f, "shadow.points");
	const struct shot_table *qt = shot_find_table(f, "shadow.quads");
	if (!pt || !qt)
		return;
	const float *xyz[3] = { 0 };
	const uint32_t *v[4] = { 0 }, *obj = NULL;
	const float *opacity = NULL;
	for (uint32_t c = 0; c < pt->nchannels; c++)
		for (int a = 0; a < 3; a++)
			if (!strcmp(pt->channels[c].name, (const char *[]){ "X", "Y", "Z" }[a]) &&
			    pt->channels[c].type != SHOT_UINT)
				xyz[a] = pt->channels[c].data;
	for (uint32_t c = 0; c < qt->nchannels; c++) {
		const struct shot_channel *ch = &qt->channels[c];
		if (ch->type != SHOT_UINT && !strcmp(ch->name, "opacity"))
			opacity = ch->data;
		if (ch->type != SHOT_UINT)
			continue;
		if (!strcmp(ch->name, "object"))
			obj = ch->data;
		for (int a = 0; a < 4; a++)
			if (!strcmp(ch->name, (const char *[]){ "v0", "v1", "v2", "v3" }[a]))
				v[a] = ch->data;
	}
	if (!xyz[0] || !xyz[1] || !xyz[2] || !v[0] || !v[1] || !v[2] || !v[3] || !obj) {
		fprintf(s->diag, "relight: warning: %s: the shadow geometry is malformed; casting "
			"cannot be edited\n", s->path);
		return;
	}
	float *P = rl_xmalloc((pt->nrows * 3 + 1) * sizeof(float));
	uint32_t *q = rl_xmalloc((qt->nrows * 4 + 1) * sizeof(uint32_t));
	for (uint64_t i = 0; i < pt->nrows; i++)
		for (int a = 0; a < 3; a++)
			P[i * 3 + (uint64_t)a] = xyz[a][i];
	for (uint64_t i = 0; i < qt->nrows; i++)
		for (int a = 0; a < 4; a++)
			q[i * 4 + (uint64_t)a] = v[a][i];
	char err[512];
	size_t need = (pt->nrows * 3 + qt->nrows * (opacity ? 6 : 5)) * sizeof(float);
	if (s->bytes + need <= s->budget) {
		s->shadow_geo = gpu_shadow_geometry_create(s->ctx, P, pt->nrows, q, obj, opacity,
							   qt->nrows, err, sizeof(err));
		if (!s->shadow_geo)
			fprintf(s->diag, "relight: warning: %s: %s; casting cannot be edited\n",
				s->path, err);
		else
			s->bytes += gpu_shadow_geometry_bytes(s->shadow_geo);
	}
	free(P);
	free(q);
}

/*
 * For picking: per pixel, the object of the sample that weighs most in it.
 * Sample ids of the framebuffer count the rows of the surfaces' tables in
 * the order the metadata lists them.
 */
static void pick_map(struct gpu_shot *s, const struct shot_file *f, const struct shot_deep *ifb)
{
	uint32_t *obj = rl_xmalloc((s->nsamples + 1) * sizeof(uint32_t));
	uint64_t at = 0;
	const cJSON *sj;
	cJSON_ArrayForEach(sj, cJSON_GetObjectItemCaseSensitive(s->meta, "surfaces")) {
		const char *tn = shot_meta_str(sj, "table");
		const struct shot_table *t = tn ? shot_find_table(f, tn) : NULL;
		const uint32_t *o = t ? uint_channel(t, "object") : NULL;
		for (uint64_t r = 0; t && r < t->nrows && at < s->nsamples; r++)
			obj[at++] = o ? o[r] : UINT32_MAX;
	}
	while (at < s->nsamples)
		obj[at++] = UINT32_MAX;
	size_t np = (size_t)s->width * s->height;
	free(s->pick);
	s->pick = rl_xmalloc(np * sizeof(uint32_t));
	const uint32_t *sid = ifb->channels[0].data;
	const float *w = ifb->channels[1].type != SHOT_UINT ? ifb->channels[1].data : NULL;
	for (size_t p = 0; p < np; p++) {
		uint32_t best = UINT32_MAX;
		float bw = -1;
		for (uint64_t e = ifb->offsets[p]; e < ifb->offsets[p + 1]; e++) {
			float we = w ? w[e] : 1.0f;
			if (sid[e] < s->nsamples && we > bw) {
				bw = we;
				best = obj[sid[e]];
			}
		}
		s->pick[p] = best;
	}
	free(obj);
}

static bool load_framebuffer(struct gpu_shot *s, const struct shot_file *f, const uint32_t *remap)
{
	const struct shot_deep *ifb = shot_find_deep(f, "ifb");
	const struct shot_table *pix = shot_find_table(f, "pixels");
	if (!ifb || !pix || ifb->width != s->width || ifb->height != s->height ||
	    pix->nrows != (uint64_t)s->width * s->height || ifb->nchannels != 2 ||
	    ifb->channels[0].type != SHOT_UINT || pix->channels[0].type == SHOT_UINT)
		return fail(s, "not a shot this relight can preview (missing or inconsistent parts)");
	uint64_t ne = ifb->offsets[(size_t)s->width * s->height];
	uint32_t *ids = rl_xmalloc((ne + 1) * sizeof(uint32_t));
	const uint32_t *sid = ifb->channels[0].data;
	for (uint64_t e = 0; e < ne; e++)
		ids[e] = sid[e] < s->nsamples ? remap[sid[e]] : UINT32_MAX;
	pick_map(s, f, ifb);
	struct gpu_ifb_desc d = {
		.width = s->width, .height = s->height, .offsets = ifb->offsets, .sample = ids,
		.weight = ifb->channels[1].data, .alpha = pix->channels[0].data,
	};
	static const char *const names[3] = { "level0", "level1", "level2" };
	static const uint32_t block[3] = { 4, 2, 1 };
	uint32_t *lids[3] = { 0 };
	bool ok = true;
	for (int L = 0; L < 3 && ok; L++) {
		const struct shot_table *lt = shot_find_table(f, names[L]);
		uint64_t nb = (uint64_t)((s->width + block[L] - 1) / block[L]) *
			      ((s->height + block[L] - 1) / block[L]);
		if (!lt || lt->nchannels != 2 || lt->channels[0].type != SHOT_UINT ||
		    lt->nrows != nb) {
			ok = fail(s, "the refinement level table '%s' is missing or malformed",
				  names[L]);
			break;
		}
		lids[L] = rl_xmalloc((nb + 1) * sizeof(uint32_t));
		const uint32_t *b = lt->channels[0].data;
		for (uint64_t i = 0; i < nb; i++)
			lids[L][i] = b[i] < s->nsamples ? remap[b[i]] : UINT32_MAX;
		d.level_sample[L] = lids[L];
		d.level_weight[L] = lt->channels[1].data;
		s->level_entries[L] = nb;
	}
	s->level_entries[3] = ne;
	char err[512];
	if (ok) {
		s->ifb = gpu_ifb_create(s->ctx, &d, err, sizeof(err));
		if (!s->ifb)
			ok = fail(s, "%s", err);
		else
			s->bytes += gpu_ifb_bytes(s->ifb);
	}
	free(ids);
	for (int L = 0; L < 3; L++)
		free(lids[L]);
	return ok;
}

/*
 * Run every program once on one sample, so that the driver's just-in-time
 * compilation (llvmpipe compiles at first use) happens at load, not on the
 * first edit; then clear what that wrote. With @only >= 0, only the kernels
 * of light shader @only (one just added).
 */
static bool warm_up(struct gpu_shot *s, int only)
{
	for (uint32_t si = 0; si < s->nsurfaces; si++) {
		struct surface *sf = &s->surfaces[si];
		if (!sf->nrows)
			continue;
		for (uint32_t k = 0; k <= 2 * s->nlshaders; k++) {
			if (only >= 0 && k != (uint32_t)only)
				continue;
			struct kernel *kk = k < s->nlshaders ? &sf->lk[k] : k == s->nlshaders
				? &sf->base : &sf->bk[k - s->nlshaders - 1];
			if (!kk->prog)
				continue;
			struct gpu_binding b[2 + 64 + 3];
			uint32_t nb = 0;
			b[nb++] = (struct gpu_binding){ 0, false, sf->records, true };
			b[nb++] = (struct gpu_binding){ 1, true, s->scratch };
			if (!bind_shadows(s, kk, NULL, NULL, b, &nb))
				return false;
			if (k > s->nlshaders) {
				/* a batch: no light counts, so the cache keeps its value */
				b[1] = (struct gpu_binding){ 1, false, s->base };
				b[nb++] = (struct gpu_binding){ 2, true, s->cache };
				gpu_uniform_int(kk->prog, "u_id0", (int)sf->id0);
				gpu_uniform_int(kk->prog, "u_n", 0);
			}
			gpu_uniform_int(kk->prog, "u_first", 0);
			if (!gpu_dispatch(s->ctx, kk->prog, b, nb, 1))
				return fail(s, "running the programs of '%s' failed", sf->name);
		}
	}
	/* A light shader added to a loaded shot: its kernels alone are new. The
	 * runtime's own programs below write the light cache and the colours,
	 * which hold the shot's state by now. */
	if (only >= 0)
		return gpu_finish(s->ctx);
	struct gpu_program *acc[2] = { s->accumulate, s->accumulate_d };
	struct gpu_buffer *dst[2] = { s->colors, s->cache };
	for (int i = 0; i < 2; i++) {
		gpu_uniform_int(acc[i], "u_first", 0);
		gpu_uniform_int(acc[i], "u_id0", 0);
		gpu_uniform_int(acc[i], "u_ostride", 3);
		gpu_uniform_int(acc[i], "u_mode", 1);
		static const float w[3] = { 1, 1, 1 };
		gpu_uniform_float(acc[i], "u_weight", w, 3);
		static const float z[3] = { 0, 0, 0 };
		gpu_uniform_float(acc[i], "u_weight_recv", z, 3);
		struct gpu_binding ab[6] = {
			{ 0, false, s->zero }, { 1, false, s->zero }, { 2, false, s->zero },
			{ 3, false, s->zero }, { 4, true, dst[i] }, { 5, false, s->zero },
		};
		if (!gpu_dispatch(s->ctx, acc[i], ab, 6, 1))
			return fail(s, "running the runtime's programs failed");
	}
	gpu_uniform_int(s->combine, "u_first", 0);
	gpu_uniform_int(s->clear, "u_first", 0);
	struct gpu_binding cb[3] = { { 0, false, s->zero }, { 1, true, s->cache },
				     { 2, true, s->colors } };
	struct gpu_binding clb[1] = { { 0, true, s->cache } };
	if (!gpu_dispatch(s->ctx, s->combine, cb, 3, 1) ||
	    !gpu_dispatch(s->ctx, s->clear, clb, 1, (uint32_t)s->nsamples))
		return fail(s, "running the runtime's programs failed");
	for (int L = 0; L < NBANDS; L++)
		if (!gpu_ifb_resolve(s->ifb, s->colors, s->nsamples, L, s->rgba[L]))
			return fail(s, "running the resolve failed");
	struct gpu_binding hb[2] = { { 0, true, s->rgba[0] }, { 1, true, s->px16 } };
	return gpu_encode_srgb8(s->ctx, s->rgba[0], s->width * s->height, s->px8) &&
	       gpu_dispatch(s->ctx, s->half, hb, 2, s->width * s->height) && gpu_finish(s->ctx);
}

static void check_linear(struct gpu_shot *s, struct surface *sf);

static bool make_receivers(struct gpu_shot *s, struct light *L);

static bool build_graph(struct gpu_shot *s)
{
	for (uint32_t i = 0; i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		const struct kernel *k = s->nsurfaces ? &s->surfaces[0].lk[L->shader] : NULL;
		if (k && k->layout.nshadows) {
			char name[300];
			snprintf(name, sizeof(name), "shadow:%s", L->name);
			L->maps = rl_xcalloc(k->layout.nshadows, sizeof(*L->maps));
			L->map_names = rl_xcalloc(k->layout.nshadows, sizeof(*L->map_names));
			L->nmaps = k->layout.nshadows;
			L->rmaps = rl_xcalloc(L->nmaps, sizeof(*L->rmaps));
			L->rdepth = rl_xcalloc(L->nmaps, sizeof(*L->rdepth));
			if (!make_receivers(s, L))
				return false;
			L->shadow_node = graph_add(s->graph, name, GRAPH_DEPTH_MAP, run_shadow, s);
			graph_connect(s->graph, L->node, L->shadow_node);
		}
	}
	for (uint32_t i = 0; i < s->nsurfaces; i++) {
		struct surface *sf = &s->surfaces[i];
		if (sf->spec->slice.ninputs && cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(
						       sf->meta, "dynamic_params")) > 0) {
			char name[300];
			snprintf(name, sizeof(name), "surface:%s", sf->name);
			sf->node = graph_add(s->graph, name, GRAPH_PARAMS, NULL, NULL);
		}
	}
	for (int b = 0; b < NBANDS; b++) {
		char name[32];
		snprintf(name, sizeof(name), "shade:band%d", b);
		s->shade[b] = graph_add(s->graph, name, GRAPH_SAMPLE_COLORS, run_shade, s);
		for (uint32_t i = 0; i < s->nlights; i++) {
			graph_connect(s->graph, s->lights[i].node, s->shade[b]);
			if (s->lights[i].shadow_node)
				graph_connect(s->graph, s->lights[i].shadow_node, s->shade[b]);
		}
		for (uint32_t i = 0; i < s->nsurfaces; i++)
			if (s->surfaces[i].node)
				graph_connect(s->graph, s->surfaces[i].node, s->shade[b]);
	}
	for (int L = 0; L < NBANDS; L++) {
		char name[32];
		snprintf(name, sizeof(name), "resolve:level%d", L);
		s->resolve[L] = graph_add(s->graph, name, GRAPH_IMAGE, run_resolve, s);
		for (int b = 0; b <= L; b++)
			graph_connect(s->graph, s->shade[b], s->resolve[L]);
	}
	if (s->imager) {
		s->imager_src = graph_add(s->graph, "imager", GRAPH_PARAMS, NULL, NULL);
		for (int L = 0; L < NBANDS; L++) {
			char name[32];
			snprintf(name, sizeof(name), "imager:level%d", L);
			s->image[L] = graph_add(s->graph, name, GRAPH_IMAGE, run_image, s);
			graph_connect(s->graph, s->resolve[L], s->image[L]);
			graph_connect(s->graph, s->imager_src, s->image[L]);
		}
	}
	return true;
}

/* The shot's imager, when it has one: its pass and an image per level after it. */
static bool load_imager(struct gpu_shot *s)
{
	const cJSON *j = cJSON_GetObjectItemCaseSensitive(s->meta, "imager");
	if (!j)
		return true;
	s->imager = gpu_imager_create(s->ctx, j, s->path, s->width, s->height, s->diag);
	if (!s->imager)
		return false;
	size_t ib = (size_t)s->width * s->height * 4 * sizeof(float);
	if (s->bytes + gpu_imager_bytes(s->imager) + NBANDS * ib > s->budget)
		return fail(s, "the imager pass needs more than the shot's GPU memory budget of "
			    "%.0f MiB", (double)s->budget / 1048576.0);
	s->bytes += gpu_imager_bytes(s->imager);
	for (int L = 0; L < NBANDS; L++)
		if (!(s->imaged[L] = buffer(s, ib, NULL)))
			return false;
	/* llvmpipe compiles at first use, and fresh memory is slow to touch: run it
	 * into every level's image now, never first on an edit */
	for (int L = 0; L < NBANDS; L++)
		if (!gpu_imager_run(s->imager, s->rgba[L], s->imaged[L]))
			return fail(s, "the imager pass failed");
	return true;
}

struct gpu_shot *gpu_shot_open(struct gpu_ctx *ctx, const char *path,
			       const struct gpu_shot_opts *opts)
{
	struct gpu_shot *s = rl_xcalloc(1, sizeof(*s));
	s->ctx = ctx;
	s->diag = opts && opts->diag ? opts->diag : stderr;
	s->path = rl_xstrdup(path);
	s->budget = opts && opts->budget ? opts->budget : DEFAULT_BUDGET;
	s->shader_path = opts && opts->shader_path ? rl_xstrdup(opts->shader_path) : NULL;
	s->solo = -1;
	s->trace_bias = GPU_TRACE_BIAS;
	s->graph = graph_create();
	double t0 = rl_now_ms();
	char err[1024] = "";
	struct shot_file *f = shot_read(path, err, sizeof(err));
	if (!f) {
		fprintf(s->diag, "relight: error: %s\n", err);
		gpu_shot_close(s);
		return NULL;
	}
	bool ok = true;
	s->meta = cJSON_Parse(f->metadata ? f->metadata : "");
	const cJSON *tiles = cJSON_GetObjectItemCaseSensitive(
		cJSON_GetObjectItemCaseSensitive(s->meta, "tiling"), "tiles");
	s->width = json_uint(s->meta, "width");
	s->height = json_uint(s->meta, "height");
	if (!cJSON_IsObject(s->meta) || !s->width || !s->height ||
	    !shot_meta_matrix(s->meta, "world_to_camera", s->w2c) || !cJSON_IsArray(tiles))
		ok = fail(s, "not a shot this relight can preview (its metadata is incomplete)");
	if (ok && !sl_m44_inverse(s->c2w, s->w2c))
		ok = fail(s, "the camera of the shot is singular");
	const cJSON *sfs = cJSON_GetObjectItemCaseSensitive(s->meta, "surfaces");
	const cJSON *sj, *sfs_ok = ok ? sfs : NULL;
	uint32_t nobjects = 1;
	cJSON_ArrayForEach(sj, sfs_ok) {
		const char *tn = shot_meta_str(sj, "table");
		const struct shot_table *t = tn ? shot_find_table(f, tn) : NULL;
		s->nsamples += t ? t->nrows : 0;
		const uint32_t *o = t ? uint_channel(t, "object") : NULL;
		for (uint64_t r = 0; o && r < t->nrows; r++)
			if (o[r] < (1u << 24) && o[r] + 1 > nobjects)
				nobjects = o[r] + 1;
	}
	if (ok && s->nsamples >= (1u << 30))
		ok = fail(s, "%llu shading samples are more than one GPU shot holds",
			  (unsigned long long)s->nsamples);
	s->nobjects = nobjects;
	if (ok) {
		s->tex = reyes_texsys_create(opts && opts->texture_path ? opts->texture_path : ".",
					     s->c2w, s->diag);
		s->texmaps = gpu_texmaps_create(ctx, s->tex, s->diag);
		ok = s->texmaps && load_lights(s);
	}
	s->accumulate = ok ? gpu_program(ctx, accumulate_src, s->diag) : NULL;
	s->accumulate_d = ok ? gpu_program(ctx, accumulate_d_src, s->diag) : NULL;
	s->combine = ok ? gpu_program(ctx, combine_src, s->diag) : NULL;
	s->clear = ok ? gpu_program(ctx, clear_src, s->diag) : NULL;
	s->half = ok ? gpu_program(ctx, half_src, s->diag) : NULL;
	if (ok && (!s->accumulate || !s->accumulate_d || !s->combine || !s->clear || !s->half))
		ok = fail(s, "the runtime's own GPU programs do not compile");
	int nsf = cJSON_GetArraySize(sfs);
	s->surfaces = rl_xcalloc((size_t)nsf + 1, sizeof(*s->surfaces));
	uint32_t *remap = rl_xmalloc((s->nsamples + 1) * sizeof(uint32_t));
	for (uint64_t i = 0; i < s->nsamples; i++)
		remap[i] = (uint32_t)i;
	uint32_t *lightset_of = rl_xmalloc((size_t)nobjects * sizeof(uint32_t));
	for (uint32_t i = 0; i < nobjects; i++)
		lightset_of[i] = UINT32_MAX;
	sfs_ok = ok ? sfs : NULL;
	cJSON_ArrayForEach(sj, sfs_ok) {
		struct surface *sf = &s->surfaces[s->nsurfaces];
		sf->meta = sj;
		s->nsurfaces++;
		if (opts && opts->progress)
			fprintf(stderr, "\rrelight: loading %s: surface %u/%d", path, s->nsurfaces,
				nsf);
		if (!load_surface(s, f, s->nsurfaces - 1, tiles, remap, lightset_of, nobjects)) {
			ok = false;
			break;
		}
	}
	if (opts && opts->progress)
		fprintf(stderr, "\n");
	size_t cbytes = (size_t)s->nsamples * 3 * sizeof(float) + 16;
	size_t sbytes = 16;
	for (uint32_t i = 0; ok && i < s->nsurfaces; i++) {
		size_t b = (size_t)s->surfaces[i].nrows * 4;
		for (uint32_t k = 0; k <= s->nlshaders; k++) {
			const struct kernel *kk = k < s->nlshaders ? &s->surfaces[i].lk[k]
								 : &s->surfaces[i].base;
			if ((size_t)kk->layout.out_stride * b > sbytes)
				sbytes = (size_t)kk->layout.out_stride * b;
		}
	}
	if (ok) {
		float *zero = rl_xcalloc(cbytes / sizeof(float) + 1, sizeof(float));
		ok = (s->base = buffer(s, cbytes, zero)) && (s->cache = buffer(s, 2 * cbytes, NULL)) &&
		     (s->colors = buffer(s, cbytes, zero)) && (s->zero = buffer(s, cbytes, zero)) &&
		     (s->scratch = buffer(s, sbytes, NULL));
		free(zero);
		size_t ib = (size_t)s->width * s->height * 4 * sizeof(float);
		for (int L = 0; ok && L < NBANDS; L++)
			ok = (s->rgba[L] = buffer(s, ib, NULL)) != NULL;
		ok = ok && (s->px8 = buffer(s, (size_t)s->width * s->height * 4, NULL)) &&
		     (s->px16 = buffer(s, (size_t)s->width * s->height * 8, NULL));
	}
	/* links: as the bake's light sets left them */
	const cJSON *sets = cJSON_GetObjectItemCaseSensitive(s->meta, "lightsets");
	for (uint32_t i = 0; ok && i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		L->link_cpu = rl_xcalloc(nobjects + 1, sizeof(float));
		for (uint32_t o = 0; o < nobjects; o++) {
			const cJSON *set = lightset_of[o] == UINT32_MAX
						   ? NULL : cJSON_GetArrayItem(sets, (int)lightset_of[o]);
			const cJSON *li;
			cJSON_ArrayForEach(li, set)
				if (cJSON_IsNumber(li) && (uint32_t)li->valuedouble == i)
					L->link_cpu[o] = 1.0f;
		}
		ok = (L->link = buffer(s, (nobjects + 1) * sizeof(float), L->link_cpu)) != NULL;
	}
	free(lightset_of);
	ok = ok && load_framebuffer(s, f, remap);
	if (ok)
		load_shadow_geometry(s, f);
	free(remap);
	for (int b = 0; b < NBANDS; b++)
		s->cached[b] = rl_xcalloc(s->nlights + 1, sizeof(struct lstate));
	ok = ok && load_imager(s);
	ok = ok && build_graph(s);
	if (ok)
		load_texmaps(s);
	ok = ok && warm_up(s, -1);
	for (uint32_t i = 0; ok && i < s->nsurfaces; i++)
		check_linear(s, &s->surfaces[i]);
	shot_free(f);
	if (!ok) {
		gpu_shot_close(s);
		return NULL;
	}
	rl_log(RL_LOG_INFO, "%s: loaded in %.0f ms, %.1f MiB of GPU memory", path, rl_now_ms() - t0,
	       (double)s->bytes / 1048576.0);
	return s;
}

static void kernel_free(struct kernel *k)
{
	free(k->glsl);
	sl_glsl_layout_finish(&k->layout);
}

void gpu_shot_close(struct gpu_shot *s)
{
	if (!s)
		return;
	for (uint32_t i = 0; i < s->nsurfaces; i++) {
		struct surface *sf = &s->surfaces[i];
		kernel_free(&sf->base);
		for (uint32_t k = 0; sf->lk && k < s->nlshaders; k++)
			kernel_free(&sf->lk[k]);
		for (uint32_t k = 0; sf->bk && k < s->nlshaders; k++)
			kernel_free(&sf->bk[k]);
		free(sf->lk);
		free(sf->bk);
		for (int b = 0; b < NBANDS; b++)
			rl_vec_free(sf->runs[b]);
		for (uint32_t p = 0; p < sf->nparamsets; p++)
			lstate_free(&sf->pvals[p]);
		free(sf->pvals);
		for (size_t e = 0; e < sf->edits.len; e++)
			free(sf->edits.data[e].param);
		rl_vec_free(sf->edits);
		gpu_buffer_destroy(sf->records);
		gpu_buffer_destroy(sf->object);
		sl_exec_destroy(sf->init_x);
		sl_spec_destroy(sf->spec);
		sl_program_destroy(sf->prog);
		free(sf->name);
	}
	free(s->surfaces);
	for (uint32_t i = 0; i < s->nlights; i++) {
		struct light *L = &s->lights[i];
		for (uint32_t m = 0; m < L->nmaps; m++) {
			gpu_shadow_map_destroy(L->maps[m]);
			gpu_shadow_map_destroy(L->rmaps[m]);
			gpu_buffer_destroy(L->rdepth[m]);
			free(L->map_names[m]);
		}
		free(L->maps);
		free(L->rmaps);
		free(L->rdepth);
		free(L->cast_cpu);
		free(L->map_names);
		free(L->name);
		sl_exec_destroy(L->init);
		lstate_free(&L->cur);
		gpu_buffer_destroy(L->link);
		free(L->link_cpu);
		gpu_buffer_destroy(L->recv);
		free(L->recv_cpu);
	}
	free(s->lights);
	for (int b = 0; b < NBANDS; b++) {
		for (uint32_t i = 0; s->cached[b] && i < s->nlights; i++)
			lstate_free(&s->cached[b][i]);
		free(s->cached[b]);
		gpu_buffer_destroy(s->rgba[b]);
		gpu_buffer_destroy(s->imaged[b]);
	}
	gpu_imager_destroy(s->imager);
	for (uint32_t k = 0; k < s->nlshaders; k++)
		sl_program_destroy(s->lshaders[k].prog);
	free(s->shader_path);
	free(s->lshaders);
	gpu_ifb_destroy(s->ifb);
	free(s->pick);
	gpu_shadow_geometry_destroy(s->shadow_geo);
	gpu_buffer_destroy(s->base);
	gpu_buffer_destroy(s->cache);
	gpu_buffer_destroy(s->colors);
	gpu_buffer_destroy(s->scratch);
	gpu_buffer_destroy(s->zero);
	gpu_buffer_destroy(s->px8);
	gpu_buffer_destroy(s->px16);
	gpu_texmaps_destroy(s->texmaps);
	rl_strbuf_finish(&s->space_warned);
	reyes_texsys_destroy(s->tex);
	graph_destroy(s->graph);
	cJSON_Delete(s->meta);
	free(s->path);
	free(s);
}

/* ------------------------------------------------------------------------ */
/* Queries and edits                                                         */

uint32_t gpu_shot_width(const struct gpu_shot *s)
{
	return s->width;
}

uint32_t gpu_shot_height(const struct gpu_shot *s)
{
	return s->height;
}

size_t gpu_shot_bytes(const struct gpu_shot *s)
{
	size_t b = s->bytes + gpu_texmaps_bytes(s->texmaps);
	for (uint32_t i = 0; i < s->nlights; i++)
		for (uint32_t m = 0; m < s->lights[i].nmaps; m++)
			b += gpu_shadow_map_bytes(s->lights[i].maps[m]) +
			     gpu_shadow_map_bytes(s->lights[i].rmaps ? s->lights[i].rmaps[m] : NULL);
	return b;
}

size_t gpu_shot_shadow_bvh(const struct gpu_shot *s, uint32_t *nodes, uint32_t *tris)
{
	size_t bytes = 0;
	gpu_shadow_bvh_stats(s ? s->shadow_geo : NULL, nodes, tris, &bytes);
	return bytes;
}

uint32_t gpu_shot_deep_stats(const struct gpu_shot *s, struct gpu_deep_stats *last)
{
	if (last)
		*last = s->deep_stats;
	return s->deep_maps_rendered;
}

uint64_t gpu_shot_samples(const struct gpu_shot *s)
{
	return s->nsamples;
}

const struct graph *gpu_shot_graph(const struct gpu_shot *s)
{
	return s->graph;
}

uint32_t gpu_shot_light_count(const struct gpu_shot *s)
{
	return s->nlights;
}

const char *gpu_shot_light_name(const struct gpu_shot *s, uint32_t i)
{
	return i < s->nlights && !s->lights[i].removed ? s->lights[i].name : NULL;
}

const char *gpu_shot_light_shader(const struct gpu_shot *s, uint32_t i)
{
	return i < s->nlights ? s->lshaders[s->lights[i].shader].prog->name : NULL;
}

int gpu_shot_find_light(const struct gpu_shot *s, const char *name)
{
	for (uint32_t i = 0; name && i < s->nlights; i++)
		if (!s->lights[i].removed && !strcmp(s->lights[i].name, name))
			return (int)i;
	return -1;
}

static struct light *find(struct gpu_shot *s, const char *name, char *err, size_t errlen)
{
	int i = gpu_shot_find_light(s, name);
	if (i >= 0)
		return &s->lights[i];
	char list[512] = "";
	size_t at = 0;
	for (uint32_t k = 0; k < s->nlights && at + 2 < sizeof(list); k++) {
		if (s->lights[k].removed)
			continue;
		int w = snprintf(list + at, sizeof(list) - at, "%s%s", at ? ", " : "",
				 s->lights[k].name);
		at += w > 0 ? (size_t)w : 0;
	}
	errorf(err, errlen, "no light named '%s'; the shot's lights are: %s", name ? name : "",
	       list);
	return NULL;
}

/* Something about light @L changed: everything downstream is out of date. */
static void touched(struct gpu_shot *s, struct light *L)
{
	(void)s;
	graph_touch(L->node);
}

/* An edit of @L: unfreeze it, and freeze the lights earlier edits unfroze. */
static void editing(struct gpu_shot *s, struct light *L)
{
	for (uint32_t i = 0; i < s->nlights; i++) {
		struct light *o = &s->lights[i];
		if (o != L && !o->frozen && !o->pinned) {
			o->frozen = true;
			touched(s, o);
		}
	}
	L->frozen = false;
}

/*
 * After a parameter of @L was set on its interpreter: its parameters (and the
 * defaults that depend on them) evaluated again into its state, and the
 * light marked edited.
 */
static bool reevaluate(struct gpu_shot *s, struct light *L, const struct sl_program *lp,
		       char *err, size_t errlen)
{
	struct lstate next = { 0 };
	lstate_copy(&next, &L->cur);
	if (!eval_params(L->init, lp, L->to_camera, s->w2c, &next)) {
		lstate_free(&next);
		errorf(err, errlen, "light '%s': its parameter defaults failed", L->name);
		return false;
	}
	lstate_free(&L->cur);
	L->cur = next;
	editing(s, L);
	touched(s, L);
	return true;
}

bool gpu_shot_set(struct gpu_shot *s, const char *light, const char *param,
		  const float *values, uint32_t n, char *err, size_t errlen)
{
	if (s->imager && light && !strcmp(light, SHOT_IMAGER)) {
		if (gpu_shot_find_light(s, light) >= 0) {
			errorf(err, errlen, "a light is named '%s' like the shot's imager: its "
			       "edits are refused", SHOT_IMAGER);
			return false;
		}
		if (!gpu_imager_set(s->imager, param, values, n, err, errlen))
			return false;
		graph_touch(s->imager_src);
		return true;
	}
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	float v[16];
	uint32_t nv;
	char who[300];
	snprintf(who, sizeof(who), "light '%s'", L->name);
	if (!values || !param ||
	    !shot_meta_check_edit(lp, who, param, values, n, v, &nv, err, errlen))
		return false;
	if (!sl_exec_set_param(L->init, param, v, nv)) {
		errorf(err, errlen, "light '%s': parameter '%s' cannot be set", L->name, param);
		return false;
	}
	return reevaluate(s, L, lp, err, errlen);
}

bool gpu_shot_param_is_string(const struct gpu_shot *s, const char *light, const char *param)
{
	int i = gpu_shot_find_light(s, light);
	if (i < 0 || !param)
		return false;
	const struct sl_program *lp = s->lshaders[s->lights[i].shader].prog;
	int k = sl_program_find_param(lp, param);
	return k >= 0 && !lp->params[k].output && lp->params[k].type.base == SL_TYPE_STRING &&
	       lp->params[k].type.arraylen < 0;
}

bool gpu_shot_set_string(struct gpu_shot *s, const char *light, const char *param,
			 const char *value, char *err, size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	int k = param ? sl_program_find_param(lp, param) : -1;
	if (k < 0 || lp->params[k].output) {
		errorf(err, errlen, "light '%s' (shader '%s') has no parameter '%s'", L->name,
		       lp->name, param ? param : "");
		return false;
	}
	if (!gpu_shot_param_is_string(s, light, param)) {
		errorf(err, errlen, "light '%s': parameter '%s' is a %s%s, not a string", L->name,
		       param, sl_basetype_name(lp->params[k].type.base),
		       lp->params[k].type.arraylen >= 0 ? " array" : "");
		return false;
	}
	if (!value || strlen(value) > 4095) {
		errorf(err, errlen, "light '%s': parameter '%s' needs a string of at most 4095 bytes",
		       L->name, param);
		return false;
	}
	if (!sl_exec_set_param_string(L->init, param, value)) {
		errorf(err, errlen, "light '%s': parameter '%s' cannot be set", L->name, param);
		return false;
	}
	return reevaluate(s, L, lp, err, errlen);
}

char *gpu_shot_get_string(const struct gpu_shot *s, const char *light, const char *param)
{
	if (!gpu_shot_param_is_string(s, light, param))
		return NULL;
	const struct light *L = &s->lights[gpu_shot_find_light(s, light)];
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	uint32_t si = 0;
	for (uint32_t p = 0; p < lp->nparams; p++) {
		if (lp->regs[lp->params[p].reg].type != SL_TYPE_STRING)
			continue;
		if (!strcmp(lp->params[p].name, param))
			return si < L->cur.ns ? rl_xstrdup(L->cur.s[si]) : NULL;
		si++;
	}
	return NULL;
}

uint32_t gpu_shot_texmaps(const struct gpu_shot *s, size_t *bytes)
{
	if (bytes)
		*bytes = gpu_texmaps_bytes(s->texmaps);
	return gpu_texmaps_count(s->texmaps);
}

bool gpu_shot_get(const struct gpu_shot *s, const char *light, const char *param, float out[16],
		  uint32_t *n)
{
	if (s->imager && light && !strcmp(light, SHOT_IMAGER))
		return gpu_imager_get(s->imager, param, out, n);
	int i = gpu_shot_find_light(s, light);
	if (i < 0 || !param)
		return false;
	const struct light *L = &s->lights[i];
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	uint32_t at = 0;
	for (uint32_t k = 0; k < lp->nparams; k++) {
		const struct sl_reg *g = &lp->regs[lp->params[k].reg];
		if (g->type == SL_TYPE_STRING)
			continue;
		uint32_t ne = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
		uint32_t tot = ne * (uint32_t)sl_reg_ncomp(g);
		if (!strcmp(lp->params[k].name, param)) {
			if (tot > 16 || at + tot > L->cur.nv)
				return false;
			memcpy(out, L->cur.v + at, tot * sizeof(float));
			*n = tot;
			return true;
		}
		at += tot;
	}
	return false;
}

/* The name of a parameter type as a client shows it. */
static const char *type_name(int type)
{
	static const char *const names[] = {
		[SL_TYPE_FLOAT] = "float", [SL_TYPE_COLOR] = "color",
		[SL_TYPE_POINT] = "point", [SL_TYPE_VECTOR] = "vector",
		[SL_TYPE_NORMAL] = "normal", [SL_TYPE_MATRIX] = "matrix",
	};
	return type >= 0 && (size_t)type < sizeof(names) / sizeof(names[0]) && names[type]
		       ? names[type] : "float";
}

const char *gpu_shot_imager_shader(const struct gpu_shot *s)
{
	return s->imager ? gpu_imager_shader(s->imager) : NULL;
}

bool gpu_shot_imager_param(const struct gpu_shot *s, uint32_t k, struct gpu_shot_param *out)
{
	int type;
	if (!s->imager ||
	    !gpu_imager_param(s->imager, k, &out->name, &type, &out->n, out->value))
		return false;
	out->type = type_name(type);
	shot_meta_param_range(out->name, &out->min, &out->max);
	return true;
}

bool gpu_shot_light_param(const struct gpu_shot *s, uint32_t light, uint32_t k,
			  struct gpu_shot_param *out)
{
	if (light >= s->nlights || !s->lights[light].name)
		return false;
	const struct light *L = &s->lights[light];
	const struct sl_program *lp = s->lshaders[L->shader].prog;
	/* The values as edits give them, in the light's shader space: its
	 * parameters evaluated with that space as the current one. */
	static const float identity[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	struct lstate own = { 0 };
	if (!eval_params(L->init, lp, identity, identity, &own))
		return false;
	uint32_t at = 0, seen = 0;
	bool found = false;
	for (uint32_t i = 0; i < lp->nparams && !found; i++) {
		const struct sl_reg *g = &lp->regs[lp->params[i].reg];
		if (g->type == SL_TYPE_STRING)
			continue;
		uint32_t ne = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
		uint32_t tot = ne * (uint32_t)sl_reg_ncomp(g);
		if (g->arraylen == 0 && tot <= 16 && at + tot <= own.nv && seen++ == k) {
			out->name = lp->params[i].name;
			out->type = type_name(g->type);
			out->n = tot;
			memcpy(out->value, own.v + at, tot * sizeof(float));
			shot_meta_param_range(out->name, &out->min, &out->max);
			found = true;
		}
		at += tot;
	}
	lstate_free(&own);
	return found;
}

bool gpu_shot_pick(const struct gpu_shot *s, uint32_t x, uint32_t y, uint32_t *object)
{
	if (x >= s->width || y >= s->height || !s->pick)
		return false;
	*object = s->pick[(size_t)y * s->width + x];
	return true;
}

bool gpu_shot_light_reaches(const struct gpu_shot *s, uint32_t light, uint32_t object)
{
	if (light >= s->nlights || !s->lights[light].name || object >= s->nobjects)
		return false;
	const struct light *L = &s->lights[light];
	return light_on(s, light) && L->link_cpu && L->link_cpu[object] > 0;
}

bool gpu_shot_mute(struct gpu_shot *s, const char *light, bool muted, char *err, size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	if (L->muted != muted) {
		L->muted = muted;
		touched(s, L);
	}
	return true;
}

bool gpu_shot_solo(struct gpu_shot *s, const char *light, char *err, size_t errlen)
{
	int solo = -1;
	if (light) {
		struct light *L = find(s, light, err, errlen);
		if (!L)
			return false;
		solo = (int)(L - s->lights);
	}
	if (solo != s->solo) {
		s->solo = solo;
		for (uint32_t i = 0; i < s->nlights; i++)
			touched(s, &s->lights[i]);
	}
	return true;
}

/* Is @object one of the shot's objects (the bake's primitive ids)? */
static bool known_object(const struct gpu_shot *s, uint32_t object, char *err, size_t errlen)
{
	if (object < s->nobjects)
		return true;
	errorf(err, errlen, "no object %u in the shot (its objects are 0 to %u)", object,
	       s->nobjects - 1);
	return false;
}

/*
 * Set object @object's entry of one of light @L's per-object masks (links,
 * shadow receivers, shadow casters) to @on: @cpu, its copy on the GPU @gpu
 * (NULL: none) and *@off, the count of objects at 0 (NULL: not kept). What
 * the cache holds of the light was shaded with the old mask, so its link
 * version moves on. Returns 1 when the mask changed, 0 when it already was
 * so, -1 on a GPU error (@what names the mask in the message).
 */
static int set_object_flag(struct gpu_shot *s, struct light *L, float *cpu, struct gpu_buffer *gpu,
			   uint32_t *off, uint32_t object, bool on, const char *what, char *err,
			   size_t errlen)
{
	float v = on ? 1.0f : 0.0f;
	if (cpu[object] == v)
		return 0;
	if (gpu && !gpu_buffer_write(gpu, object * sizeof(float), sizeof(float), &v)) {
		errorf(err, errlen, "updating the %s of light '%s' failed", what, L->name);
		return -1;
	}
	cpu[object] = v;
	if (off)
		*off += on ? (uint32_t)-1 : 1u;
	L->link_version = ++s->link_version;
	touched(s, L);
	return 1;
}

bool gpu_shot_link(struct gpu_shot *s, const char *light, uint32_t object, bool linked,
		   char *err, size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	return L && known_object(s, object, err, errlen) &&
	       set_object_flag(s, L, L->link_cpu, L->link, NULL, object, linked, "links", err,
			       errlen) >= 0;
}

bool gpu_shot_freeze(struct gpu_shot *s, const char *light, bool frozen, char *err,
		     size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	L->pinned = !frozen;
	if (L->frozen != frozen) {
		L->frozen = frozen;
		touched(s, L);
	}
	return true;
}

/* ------------------------------------------------------------------------ */
/* Rendering                                                                 */

bool gpu_shot_render(struct gpu_shot *s, int level, struct gpu_shot_stats *st)
{
	struct gpu_shot_stats local;
	if (!st)
		st = &local;
	memset(st, 0, sizeof(*st));
	if (level < 0 || level >= NBANDS)
		return fail(s, "no refinement level %d (0 to %d)", level, NBANDS - 1);
	double t0 = rl_now_ms();
	s->stats = st;
	bool ok = graph_pull(s->graph, level_node(s, level)) && gpu_finish(s->ctx);
	s->stats = NULL;
	sweep_texmaps(s);
	st->entries = s->level_entries[level];
	st->ms = rl_now_ms() - t0;
	return ok;
}

bool gpu_shot_read_rgba(struct gpu_shot *s, int level, float *rgba)
{
	if (level < 0 || level >= NBANDS || graph_node_runs(level_node(s, level)) == 0)
		return false;
	return gpu_buffer_read(level_image(s, level), 0, (size_t)s->width * s->height * 4 * sizeof(float),
			       rgba);
}

bool gpu_shot_read_half(struct gpu_shot *s, int level, uint16_t *rgba)
{
	if (level < 0 || level >= NBANDS || graph_node_runs(level_node(s, level)) == 0)
		return false;
	uint32_t n = s->width * s->height;
	struct gpu_binding hb[2] = { { 0, true, level_image(s, level) }, { 1, true, s->px16 } };
	return gpu_dispatch(s->ctx, s->half, hb, 2, n) &&
	       gpu_buffer_read(s->px16, 0, (size_t)n * 8, rgba);
}

bool gpu_shot_read_srgb8(struct gpu_shot *s, int level, uint32_t *px)
{
	if (level < 0 || level >= NBANDS || graph_node_runs(level_node(s, level)) == 0)
		return false;
	uint32_t n = s->width * s->height;
	return gpu_encode_srgb8(s->ctx, level_image(s, level), n, s->px8) &&
	       gpu_buffer_read(s->px8, 0, (size_t)n * 4, px);
}

/* ------------------------------------------------------------------------ */
/* Measuring                                                                 */

/*
 * Run surface @sf's dynamic program on the interpreter over its first @n
 * records (@rec), lit by lights @lights (@nl of them, with their baked
 * parameters). Fills @ci (3 floats a sample, NULL: not wanted) and adds the
 * float operations counted to *@ops (NULL: not counted). Maps are looked up
 * as the CPU resolver does, without derivative stencils (filter regions of
 * one point): what is run here needs no exact shadows.
 */
/* Rays while measuring: they reach nothing (the cost of shading is measured, not its light). */
static bool measure_trace(void *user, struct sl_ray_query *q)
{
	(void)user;
	for (uint32_t k = 0; k < q->n; k++)
		for (int c = 0; c < 3; c++) {
			if (q->dist && c == 0)
				q->dist[k] = 1e30f;
			if (q->Ci)
				q->Ci[3 * k + (uint32_t)c] = 0;
			if (q->Oi)
				q->Oi[3 * k + (uint32_t)c] = 0;
			if (q->trans)
				q->trans[3 * k + (uint32_t)c] = 1;
		}
	return true;
}

static bool run_cpu(struct gpu_shot *s, struct surface *sf, const float *rec, uint32_t n,
		    struct light *const *lights, uint32_t nl, float *ci, uint64_t *ops)
{
	const struct sl_glsl_layout *lay = &sf->base.layout;
	struct sl_exec *x = sl_exec_create(sf->spec->dynamic, n);
	struct sl_exec **lx = rl_xcalloc(nl + 1, sizeof(*lx));
	float (*mats)[16] = rl_xcalloc(nl + 1, sizeof(*mats));
	const cJSON *lms = cJSON_GetObjectItemCaseSensitive(s->meta, "lights");
	const cJSON *psets = cJSON_GetObjectItemCaseSensitive(sf->meta, "param_sets");
	bool ok = x && (!cJSON_GetArraySize(psets) ||
			shot_meta_set_params(x, cJSON_GetArrayItem(psets, 0), s->path, s->diag));
	for (uint32_t i = 0; ok && i < nl; i++) {
		const cJSON *lm = cJSON_GetArrayItem(lms, (int)(lights[i] - s->lights));
		lx[i] = sl_exec_create(s->lshaders[lights[i]->shader].prog, n);
		memcpy(mats[i], lights[i]->to_camera, sizeof(mats[i]));
		ok = lx[i] && shot_meta_set_params(lx[i], cJSON_GetObjectItemCaseSensitive(lm, "params"),
						   s->path, s->diag);
	}
	ok = ok && sl_spec_bind_cache(sf->spec, x, n, rec, lay->in_stride, lay->in_offset);
	if (ok) {
		struct sl_lighthost lh;
		sl_lighthost_init(&lh, lx, (int)nl);
		lh.host.specular_model = sf->spec->slice.specular_model;
		lh.light_shader_mats = (const float (*)[16])mats;
		static const char *const space_names[] = { "world" };
		lh.space_names = space_names;
		lh.space_mats = (const float (*)[16])s->w2c;
		lh.nspaces = 1;
		reyes_tex_serve(&lh, s->tex);
		lh.host.trace = measure_trace;
		sl_exec_count_ops(x, ops != NULL);
		for (uint32_t i = 0; i < nl; i++)
			sl_exec_count_ops(lx[i], ops != NULL);
		ok = sl_exec_run(x, &lh.host);
	}
	if (ok && ops) {
		*ops += sl_exec_ops(x);
		for (uint32_t i = 0; i < nl; i++)
			*ops += sl_exec_ops(lx[i]);
	}
	if (ok && ci) {
		bool vary;
		const float *c = sl_exec_global(x, SL_GLOBAL_CI, &vary);
		uint32_t st = sl_exec_stride(x);
		for (uint32_t i = 0; i < n; i++)
			for (int k = 0; k < 3; k++)
				ci[i * 3 + (uint32_t)k] =
					c ? (vary ? c[(size_t)k * st + i] : c[k]) : 0.0f;
	}
	for (uint32_t i = 0; i < nl; i++)
		sl_exec_destroy(lx[i]);
	free(lx);
	free(mats);
	sl_exec_destroy(x);
	return ok;
}

/* The first @n records of @sf, read back from the GPU (free() them). */
static float *records_of(struct surface *sf, uint32_t n)
{
	size_t bytes = (size_t)n * sf->base.layout.in_stride * sizeof(float);
	float *rec = rl_xmalloc(bytes + sizeof(float));
	if (!gpu_buffer_read(sf->records, 0, bytes, rec)) {
		free(rec);
		return NULL;
	}
	return rec;
}

/* Float operations per sample of surface @sf lit by @L (NULL: none), on the interpreter. */
static double count_flops(struct gpu_shot *s, struct surface *sf, struct light *L)
{
	uint32_t n = sf->nrows < 1024 ? (uint32_t)sf->nrows : 1024;
	float *rec = n ? records_of(sf, n) : NULL;
	uint64_t ops = 0;
	bool ok = rec && run_cpu(s, sf, rec, n, L ? &L : NULL, L ? 1 : 0, NULL, &ops);
	free(rec);
	return ok ? (double)ops / n : -1.0;
}

/*
 * The light cache adds lights' contributions one by one, which is right
 * for a surface linear in its lights (the library's illuminance loops are).
 * Check it on a few samples: the colour with every light against the colour
 * with none plus each light's difference. A warning, not an error: the
 * preview still runs, but differs from the final frame.
 */
static void check_linear(struct gpu_shot *s, struct surface *sf)
{
	enum { N = 64, MAXL = 8 };
	uint32_t n = sf->nrows < N ? (uint32_t)sf->nrows : N;
	uint32_t nl = 0;
	struct light *ls[MAXL];
	for (uint32_t i = 0; i < s->nlights && nl < MAXL; i++)
		ls[nl++] = &s->lights[i];
	float *rec = n && nl > 1 ? records_of(sf, n) : NULL;
	if (!rec)
		return;
	float *c0 = rl_xmalloc(n * 3 * sizeof(float)), *ck = rl_xmalloc(n * 3 * sizeof(float));
	float *all = rl_xmalloc(n * 3 * sizeof(float));
	double *sum = rl_xcalloc(n * 3, sizeof(double));
	bool ok = run_cpu(s, sf, rec, n, NULL, 0, c0, NULL) && run_cpu(s, sf, rec, n, ls, nl, all, NULL);
	for (uint32_t i = 0; ok && i < n * 3; i++)
		sum[i] = c0[i];
	for (uint32_t k = 0; ok && k < nl; k++) {
		ok = run_cpu(s, sf, rec, n, &ls[k], 1, ck, NULL);
		for (uint32_t i = 0; ok && i < n * 3; i++)
			sum[i] += (double)ck[i] - c0[i];
	}
	uint32_t off = 0;
	for (uint32_t i = 0; ok && i < n; i++) {
		bool bad = false;
		for (int c = 0; c < 3; c++) {
			double a = all[i * 3 + (uint32_t)c], b = sum[i * 3 + (uint32_t)c];
			if (isfinite(a) && isfinite(b) && fabs(a - b) > 1e-3 * fmax(fabs(a), 1e-2))
				bad = true;
		}
		off += bad;
	}
	if (off)
		fprintf(s->diag, "relight: warning: %s: surface '%s' is not linear in its lights (%u "
			"of %u samples checked): the light cache adds lights one by one, so its "
			"preview differs from the final frame\n", s->path, sf->name, off, n);
	free(rec);
	free(c0);
	free(ck);
	free(all);
	free(sum);
}

/*
 * The batch kernel of @L's shader on @sf, every pass lit by @L, over every
 * row: best of three runs in ms (-1 on failure). It adds into a cache of
 * its own, so the shot's stays as it was.
 */
static double profile_batch(struct gpu_shot *s, struct surface *sf, struct light *L)
{
	struct kernel *k = &sf->bk[L->shader];
	struct light *ls[1] = { L };
	batch_uniforms(s, k, ls, 1);
	gpu_uniform_int(k->prog, "u_n", BATCH);
	if (sf->nparamsets)
		set_uniforms(k->prog, &k->layout, sf->spec->dynamic, &sf->pvals[0], -1);
	gpu_uniform_int(k->prog, "u_id0", (int)sf->id0);
	gpu_uniform_int(k->prog, "u_first", 0);
	struct gpu_buffer *cache = gpu_buffer_create(s->ctx, (size_t)(sf->id0 + sf->nrows) * 3 *
						     sizeof(double) + 16, NULL);
	if (!cache)
		return -1.0;
	struct gpu_binding b[3] = {
		{ 0, false, sf->records, true }, { 1, false, s->base }, { 2, true, cache },
	};
	double best = 1e30;
	for (int r = 0; r < 3 && best >= 0; r++) {
		double t0 = rl_now_ms();
		if (!gpu_finish(s->ctx) || !gpu_dispatch(s->ctx, k->prog, b, 3, (uint32_t)sf->nrows) ||
		    !gpu_finish(s->ctx))
			best = -1.0;
		double t = rl_now_ms() - t0;
		best = best >= 0 && t < best ? t : best;
	}
	gpu_buffer_destroy(cache);
	return best;
}

bool gpu_shot_profile(struct gpu_shot *s, const char *light, struct gpu_shot_profile *out,
		      char *err, size_t errlen)
{
	memset(out, 0, sizeof(*out));
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	double flops = 0.0, bflops = 0.0;
	bool nobatch = false;
	for (uint32_t si = 0; si < s->nsurfaces; si++) {
		struct surface *sf = &s->surfaces[si];
		if (!sf->nrows)
			continue;
		struct kernel *k = &sf->lk[L->shader];
		set_uniforms(k->prog, &k->layout, s->lshaders[L->shader].prog, &L->cur, 0);
		gpu_uniform_mat4(k->prog, "l0_shader", L->to_camera);
		set_spaces(s, k->prog, L, &L->cur, 0);
		gpu_uniform_mat4(k->prog, "space_world", s->w2c);
		if (sf->nparamsets)
			set_uniforms(k->prog, &k->layout, sf->spec->dynamic, &sf->pvals[0], -1);
		gpu_uniform_int(k->prog, "u_first", 0);
		struct gpu_binding b[2 + 64 + 3];
		uint32_t nb = 0;
		b[nb++] = (struct gpu_binding){ 0, false, sf->records, true };
		b[nb++] = (struct gpu_binding){ 1, true, s->scratch };
		if (!bind_shadows(s, k, L, &L->cur, b, &nb))
			return false;
		double best = 1e30, base = 1e30;
		for (int r = 0; r < 6; r++) {
			struct kernel *kk = r % 2 ? &sf->base : k;
			struct gpu_binding *bb = b;
			struct gpu_binding b0[2 + 64];
			uint32_t n0 = 0;
			if (kk == &sf->base) {
				b0[n0++] = (struct gpu_binding){ 0, false, sf->records, true };
				b0[n0++] = (struct gpu_binding){ 1, true, s->scratch };
				if (!bind_shadows(s, kk, NULL, NULL, b0, &n0))
					return false;
				gpu_uniform_int(kk->prog, "u_first", 0);
				bb = b0;
			}
			if (!gpu_finish(s->ctx))
				return false;
			double t0 = rl_now_ms();
			if (!gpu_dispatch(s->ctx, kk->prog, bb, kk == k ? nb : n0,
					  (uint32_t)sf->nrows) ||
			    !gpu_finish(s->ctx)) {
				errorf(err, errlen, "running the kernel of '%s' failed", sf->name);
				return false;
			}
			double t = rl_now_ms() - t0;
			if (kk == k)
				best = t < best ? t : best;
			else
				base = t < base ? t : base;
		}
		out->base_ms += base;
		double per = count_flops(s, sf, L);
		if (per < 0) {
			errorf(err, errlen, "counting the operations of '%s' failed", sf->name);
			return false;
		}
		out->kernel_ms += best;
		out->samples += sf->nrows;
		flops += per * (double)sf->nrows;
		if (sf->bk[L->shader].prog) {
			double bms = profile_batch(s, sf, L);
			double none = count_flops(s, sf, NULL);
			if (bms < 0 || none < 0) {
				errorf(err, errlen, "timing the batch kernel of '%s' failed", sf->name);
				return false;
			}
			out->batch_lights = BATCH;
			out->batch_ms += bms;
			bflops += (none + BATCH * (per - none)) * (double)sf->nrows;
		} else {
			nobatch = true;
		}
	}
	if (nobatch || !out->batch_ms) {
		out->batch_lights = 0;
		out->batch_ms = 0.0;
	} else {
		out->batch_flops_per_sample = out->samples ? bflops / (double)out->samples : 0.0;
		out->batch_flops = bflops / (out->batch_ms * 1e-3);
	}
	out->flops_per_sample = out->samples ? flops / (double)out->samples : 0.0;
	out->flops = out->kernel_ms > 0 ? flops / (out->kernel_ms * 1e-3) : 0.0;
	return true;
}

/* ------------------------------------------------------------------------ */
/* Shadows, surfaces, adding and removing lights                             */

/* Every object receives @L's shadows at first (for a light with maps). */
static bool make_receivers(struct gpu_shot *s, struct light *L)
{
	L->recv_cpu = rl_xmalloc((s->nobjects + 1) * sizeof(float));
	for (uint32_t o = 0; o <= s->nobjects; o++)
		L->recv_cpu[o] = 1.0f;
	L->recv = buffer(s, (s->nobjects + 1) * sizeof(float), L->recv_cpu);
	L->cast_cpu = rl_xmalloc((s->nobjects + 1) * sizeof(float));
	for (uint32_t o = 0; o <= s->nobjects; o++)
		L->cast_cpu[o] = 1.0f;
	return L->recv != NULL;
}

static struct light *shadowed(struct gpu_shot *s, const char *light, char *err, size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	if (L && !L->nmaps) {
		errorf(err, errlen, "light '%s' casts no shadows (shader '%s' reads no shadow map)",
		       L->name, s->lshaders[L->shader].prog->name);
		return NULL;
	}
	return L;
}

bool gpu_shot_shadows(struct gpu_shot *s, const char *light, bool on, char *err, size_t errlen)
{
	struct light *L = shadowed(s, light, err, errlen);
	if (!L)
		return false;
	if (L->shadows_off == !on)
		return true;
	L->shadows_off = !on;
	editing(s, L);
	touched(s, L);
	return true;
}

bool gpu_shot_shadow_look(struct gpu_shot *s, const char *light, float density,
			  const float color[3], char *err, size_t errlen)
{
	struct light *L = shadowed(s, light, err, errlen);
	if (!L)
		return false;
	bool ok = density >= 0.0f && density <= 1.0f;
	for (int c = 0; c < 3 && color; c++)
		ok = ok && color[c] >= 0.0f && color[c] <= 1.0f;
	if (!ok || !color) {
		errorf(err, errlen, "light '%s': shadow density and colour take values in [0, 1]",
		       L->name);
		return false;
	}
	L->shadow_density = density;
	memcpy(L->shadow_color, color, sizeof(L->shadow_color));
	editing(s, L);
	touched(s, L);
	return true;
}

/* The parameter values of every paramset of @sf: the baked ones, then the edits. */
static bool surface_values(struct gpu_shot *s, struct surface *sf)
{
	const cJSON *psets = cJSON_GetObjectItemCaseSensitive(sf->meta, "param_sets");
	bool per_object = cJSON_GetArraySize(psets) > 0;
	for (uint32_t ps = 0; ps < sf->nparamsets; ps++) {
		sl_exec_reset_params(sf->init_x);
		if (per_object && !shot_meta_set_params(sf->init_x, cJSON_GetArrayItem(psets, (int)ps),
							s->path, s->diag))
			return false;
		for (size_t e = 0; e < sf->edits.len; e++)
			sl_exec_set_param(sf->init_x, sf->edits.data[e].param, sf->edits.data[e].v,
					  sf->edits.data[e].n);
		if (!eval_params(sf->init_x, sf->spec->dynamic, NULL, s->w2c, &sf->pvals[ps]))
			return false;
	}
	return true;
}

bool gpu_shot_set_surface(struct gpu_shot *s, const char *shader, const char *param,
			  const float *values, uint32_t n, char *err, size_t errlen)
{
	uint32_t found = 0;
	for (uint32_t i = 0; i < s->nsurfaces && shader && param && values; i++) {
		struct surface *sf = &s->surfaces[i];
		if (strcmp(sf->name, shader))
			continue;
		found++;
		bool editable = false;
		const cJSON *d;
		cJSON_ArrayForEach(d, cJSON_GetObjectItemCaseSensitive(sf->meta, "dynamic_params"))
			editable = editable || (cJSON_IsString(d) && !strcmp(d->valuestring, param));
		char who[300];
		snprintf(who, sizeof(who), "surface '%s'", sf->name);
		if (!editable) {
			if (sl_program_find_param(sf->prog, param) < 0)
				errorf(err, errlen, "%s has no parameter '%s'", who, param);
			else
				errorf(err, errlen, "%s: parameter '%s' was baked as part of the cache; "
				       "bake with --dynamic-surface %s to edit it", who, param, param);
			return false;
		}
		struct surface_edit e = { 0 };
		if (!shot_meta_check_edit(sf->prog, who, param, values, n, e.v, &e.n, err, errlen))
			return false;
		size_t k = 0;
		while (k < sf->edits.len && strcmp(sf->edits.data[k].param, param))
			k++;
		if (k == sf->edits.len) {
			e.param = rl_xstrdup(param);
			rl_vec_push(sf->edits, e);
		} else {
			memcpy(sf->edits.data[k].v, e.v, sizeof(e.v));
			sf->edits.data[k].n = e.n;
		}
		if (!surface_values(s, sf)) {
			errorf(err, errlen, "%s: its parameter values failed", who);
			return false;
		}
		graph_touch(sf->node);
	}
	if (!found) {
		errorf(err, errlen, "no surface shader '%s' in the shot", shader ? shader : "");
		return false;
	}
	/* every light's contribution changes with the surface: sum the cache again */
	for (int b = 0; b < NBANDS; b++)
		s->base_valid[b] = false;
	return true;
}

/* The light shader @name: one of the shot's, or compiled from the shader path. */
static int light_shader(struct gpu_shot *s, const char *name, char *err, size_t errlen)
{
	for (uint32_t k = 0; k < s->nlshaders; k++)
		if (!strcmp(s->lshaders[k].prog->name, name))
			return (int)k;
	if (s->nlshaders >= (uint32_t)cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(
				     s->meta, "lights")) + MAX_ADDED_SHADERS - 1) {
		errorf(err, errlen, "too many light shaders added to the shot");
		return -1;
	}
	/* the shader path, then the folders of the shot's own shaders */
	RL_VEC(char *) dirs = { 0 };
	if (s->shader_path) {
		char *p = rl_xstrdup(s->shader_path), *save = NULL;
		for (char *d = strtok_r(p, ":", &save); d; d = strtok_r(NULL, ":", &save))
			rl_vec_push(dirs, rl_xstrdup(d));
		free(p);
	}
	const cJSON *l;
	cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(s->meta, "lights")) {
		const char *src = shot_meta_str(l, "source");
		const char *slash = src ? strrchr(src, '/') : NULL;
		if (slash) {
			char *d = rl_xstrdup(src);
			d[slash - src] = '\0';
			rl_vec_push(dirs, d);
		}
	}
	struct sl_program *p = NULL;
	for (size_t i = 0; i < dirs.len && !p; i++) {
		char path[4096];
		snprintf(path, sizeof(path), "%s/%s.sl", dirs.data[i], name);
		if (access(path, R_OK) == 0) {
			struct sl_options so = { .diag = s->diag };
			p = sl_compile_file(path, &so);
		}
	}
	for (size_t i = 0; i < dirs.len; i++)
		free(dirs.data[i]);
	rl_vec_free(dirs);
	if (!p || p->kind != SL_SHADER_LIGHT) {
		errorf(err, errlen, "%s light shader '%s' %s", p ? "" : "no",
		       name, p ? "is not a light shader" : "on the shader path");
		sl_program_destroy(p);
		return -1;
	}
	uint32_t k = s->nlshaders;
	s->lshaders[k].prog = p;
	s->lshaders[k].init = *p;
	s->lshaders[k].init.ncode = p->body_begin;
	s->nlshaders++;
	for (uint32_t i = 0; i < s->nsurfaces; i++) {
		struct surface *sf = &s->surfaces[i];
		uint8_t *steps = NULL;
		if (sf->spec->needs_stencil) {
			steps = rl_xcalloc(sf->spec->ncached + 1, 1);
			memcpy(steps, sf->spec->cached_deriv, sf->spec->ncached);
		}
		bool ok = make_kernel(s, sf, p, &sf->lk[k], steps, false);
		free(steps);
		if (!ok) {
			errorf(err, errlen, "light shader '%s' cannot light surface '%s' on the GPU "
			       "(see the messages above)", name, sf->name);
			/* the kernels made so far stay: the shader may be added again */
			return -1;
		}
	}
	return (int)k;
}

int gpu_shot_add_light(struct gpu_shot *s, const char *name, const char *shader,
		       const float shader_to_world[16], char *err, size_t errlen)
{
	if (!name || !name[0] || !shader) {
		errorf(err, errlen, "a new light needs a name and a shader");
		return -1;
	}
	if (gpu_shot_find_light(s, name) >= 0) {
		errorf(err, errlen, "the shot already has a light named '%s'", name);
		return -1;
	}
	for (int c = 0; c < 16 && shader_to_world; c++)
		if (!isfinite(shader_to_world[c])) {
			errorf(err, errlen, "light '%s': its transform is not finite", name);
			return -1;
		}
	int k = light_shader(s, shader, err, errlen);
	if (k < 0)
		return -1;
	s->lights = rl_xrealloc(s->lights, (s->nlights + 1) * sizeof(*s->lights));
	for (int b = 0; b < NBANDS; b++) {
		s->cached[b] = rl_xrealloc(s->cached[b], (s->nlights + 1) * sizeof(struct lstate));
		memset(&s->cached[b][s->nlights], 0, sizeof(struct lstate));
	}
	struct light *L = &s->lights[s->nlights];
	memset(L, 0, sizeof(*L));
	static const float identity[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 };
	sl_m44_mul(L->to_camera, shader_to_world ? shader_to_world : identity, s->w2c);
	L->name = rl_xstrdup(name);
	L->shader = (uint32_t)k;
	L->shadow_density = 1.0f;
	L->cur.on = true;
	L->init = sl_exec_create(&s->lshaders[k].init, 1);
	L->link_cpu = rl_xmalloc((s->nobjects + 1) * sizeof(float));
	for (uint32_t o = 0; o <= s->nobjects; o++)
		L->link_cpu[o] = 1.0f;
	L->link = buffer(s, (s->nobjects + 1) * sizeof(float), L->link_cpu);
	if (!L->init || !L->link ||
	    !eval_params(L->init, s->lshaders[k].prog, L->to_camera, s->w2c, &L->cur)) {
		errorf(err, errlen, "light '%s' cannot be set up", name);
		sl_exec_destroy(L->init);
		gpu_buffer_destroy(L->link);
		free(L->link_cpu);
		free(L->name);
		lstate_free(&L->cur);
		return -1;
	}
	s->nlights++;
	L->node = graph_add(s->graph, name, GRAPH_PARAMS, NULL, NULL);
	const struct kernel *kk = s->nsurfaces ? &s->surfaces[0].lk[k] : NULL;
	if (kk && kk->layout.nshadows) {
		char nm[300];
		snprintf(nm, sizeof(nm), "shadow:%s", name);
		L->maps = rl_xcalloc(kk->layout.nshadows, sizeof(*L->maps));
		L->map_names = rl_xcalloc(kk->layout.nshadows, sizeof(*L->map_names));
		L->nmaps = kk->layout.nshadows;
		L->rmaps = rl_xcalloc(L->nmaps, sizeof(*L->rmaps));
		L->rdepth = rl_xcalloc(L->nmaps, sizeof(*L->rdepth));
		if (!make_receivers(s, L))
			errorf(err, errlen, "no GPU memory for light '%s''s shadow receivers", name);
		L->shadow_node = graph_add(s->graph, nm, GRAPH_DEPTH_MAP, run_shadow, s);
		graph_connect(s->graph, L->node, L->shadow_node);
	}
	for (int b = 0; b < NBANDS; b++) {
		graph_connect(s->graph, L->node, s->shade[b]);
		if (L->shadow_node)
			graph_connect(s->graph, L->shadow_node, s->shade[b]);
	}
	/* a new light is being edited: not in the cache */
	editing(s, L);
	if (!warm_up(s, k))
		errorf(err, errlen, "running the programs of light '%s' failed", name);
	return (int)(s->nlights - 1);
}

bool gpu_shot_remove_light(struct gpu_shot *s, const char *light, char *err, size_t errlen)
{
	struct light *L = find(s, light, err, errlen);
	if (!L)
		return false;
	if (s->solo == (int)(L - s->lights))
		s->solo = -1;
	L->removed = true;
	touched(s, L);
	return true;
}

bool gpu_shot_receive_shadows(struct gpu_shot *s, const char *light, uint32_t object,
			      bool receives, char *err, size_t errlen)
{
	struct light *L = shadowed(s, light, err, errlen);
	return L && known_object(s, object, err, errlen) &&
	       set_object_flag(s, L, L->recv_cpu, L->recv, &L->not_receiving, object, receives,
			       "shadow receivers", err, errlen) >= 0;
}

bool gpu_shot_cast_shadows(struct gpu_shot *s, const char *light, uint32_t object, bool casts,
			   char *err, size_t errlen)
{
	struct light *L = shadowed(s, light, err, errlen);
	if (!L)
		return false;
	if (!known_object(s, object, err, errlen))
		return false;
	if (!s->shadow_geo) {
		errorf(err, errlen, "the shot holds no shadow geometry the GPU can render: casting "
		       "cannot be edited");
		return false;
	}
	/* on the CPU alone: the maps are rendered again from it */
	if (set_object_flag(s, L, L->cast_cpu, NULL, &L->not_casting, object, casts,
			    "shadow casters", err, errlen) > 0) {
		L->cast_version++;
		graph_touch(L->shadow_node);
	}
	return true;
}

/* Light @L's "from" and "to" points in world space. */
static bool light_from_to(struct gpu_shot *s, const struct light *L, float from[3], float to[3])
{
	float f[16], t[16];
	uint32_t nf, nt;
	if (!gpu_shot_get(s, L->name, "from", f, &nf) || !gpu_shot_get(s, L->name, "to", t, &nt) ||
	    nf != 3 || nt != 3)
		return false;
	/* the values are in current (camera) space */
	sl_xform_point(from, s->c2w, f);
	sl_xform_point(to, s->c2w, t);
	return isfinite(from[0] + from[1] + from[2] + to[0] + to[1] + to[2]);
}

bool gpu_shot_shadow_follow(struct gpu_shot *s, const char *light, bool follow, char *err,
			    size_t errlen)
{
	struct light *L = shadowed(s, light, err, errlen);
	if (!L)
		return false;
	float f[3], t[3];
	if (follow && !light_from_to(s, L, f, t)) {
		errorf(err, errlen, "light '%s' (shader '%s') has no 'from' and 'to' points for its "
		       "shadow maps to follow", L->name, s->lshaders[L->shader].prog->name);
		return false;
	}
	if (follow && !s->shadow_geo) {
		errorf(err, errlen, "the shot holds no shadow geometry the GPU can render: its maps "
		       "cannot follow light '%s'", L->name);
		return false;
	}
	if (L->follow == follow)
		return true;
	L->follow = follow;
	memset(L->follow_key, 0, sizeof(L->follow_key));
	L->cast_version++;
	L->link_version = ++s->link_version;
	graph_touch(L->shadow_node);
	touched(s, L);
	return true;
}

/*
 * The bake: the renderer in bake mode (reyes_bake_hooks) feeding shading
 * samples and pixel recipes into memory, then compaction (samples no pixel
 * uses are dropped, the rest numbered surface shader by surface shader, each
 * pixel's entries sorted heaviest first) and the shot file.
 */
#include "bake.h"
#include "fileutil.h"
#include "shadowgeo.h"
#include "ri.h"
#include "shader_cache.h"

#include "arena.h"
#include "config.h"
#include "exec.h"
#include "glsl.h"
#include "mathlib.h"
#include "spec.h"
#include "ast.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <time.h>

/* A run of consecutive ids shaded in one grid. */
struct chunk {
	uint32_t id0, n;
	float *values;       /* n rows x ncols, row-major */
	uint32_t object, lightset, paramset;
};

/* One surface shader program and the samples shaded with it. */
struct group {
	const struct sl_program *prog;
	const char *shader;  /* the shader's name */
	struct sl_spec *spec;
	char *table;         /* "samples.NAME" */
	uint32_t ncols;      /* floats per sample: the cached values, then (derivative
				stencils) their steps along u and v and du, dv */
	uint32_t nbase;      /* floats of the cached values */
	char (*colname)[32]; /* per float: its channel's name */
	uint8_t *coltype;    /* per float: its value's enum sl_basetype */
	uint32_t *offset;    /* per cached value, its first float (sl_spec_cache_layout),
				then ncols */
	RL_VEC(struct chunk) chunks;
	uint64_t rows;       /* kept rows, after compaction */
	uint32_t first_id;   /* id of its first kept row */
	cJSON *compress;     /* constants, aliases, half error (for the metadata) */
	/* The values objects give the editable parameters, as JSON arrays of
	 * {name, type, value}: a sample's "paramset" indexes them. */
	const char **dyn;
	size_t ndyn;
	RL_VEC(char *) paramsets;
};

/* One finished bucket, copied. */
struct bucket {
	uint32_t x0, y0, x1, y1;
	uint32_t *offsets;
	struct reyes_vis_entry *entries;
	float *alpha;
};

struct bake {
	const struct reyes_scene *scene;
	const struct bake_opts *o;
	FILE *diag;
	pthread_mutex_t lock;
	RL_VEC(struct group *) groups;
	RL_VEC(struct bucket) buckets;
	/* distinct light sets (attrs->lights lists) */
	RL_VEC(const struct reyes_attrs *) lightsets;
	uint64_t next_id;
	bool failed;
	cJSON *tiles_json;   /* the layout's tiles (for the metadata) */
	bool light_derivatives; /* some light takes derivatives of Ps */
	struct bake_shadow_geometry shadow;  /* empty when no light casts shadows */
	RL_VEC(uint32_t) casters;            /* lights that cast shadows */
	float shadow_rate;
};

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* The shares of bake_scene's progress: rendering takes most of the time,
 * compaction and writing the rest. */
#define SHARE_RENDER 0.8
#define SHARE_COMPACT 0.85
#define SHARE_WRITE 0.9

static void report(const struct bake *b, double fraction, const char *what)
{
	if (b->o->progress_fn)
		b->o->progress_fn(b->o->progress_user, fraction, what);
}

static void render_progress(void *user, double fraction)
{
	report(user, SHARE_RENDER * fraction, "rendering");
}

/* ---- groups ---- */

/* Is Oi computed by a light-dependent instruction? Then coverage is not static. */
static bool opacity_dynamic(const struct sl_spec *s)
{
	const struct sl_program *p = s->prog;
	int32_t oi = p->global_reg[SL_GLOBAL_OI];
	if (oi < 0)
		return false;
	for (uint32_t i = 0; i < p->ncode; i++)
		if (p->code[i].dst == oi && s->insn_dynamic[i] && s->live[i])
			return true;
	return false;
}

static struct group *new_group(struct bake *b, const struct reyes_shader *surf)
{
	const struct sl_program *prog = surf->prog;
	/* the user's editable parameters that this shader has */
	const char **dyn = rl_xcalloc(b->o->ndynamic + 1, sizeof(char *));
	size_t nd = 0;
	for (size_t i = 0; i < b->o->ndynamic; i++)
		if (sl_program_find_param(prog, b->o->dynamic_surface[i]) >= 0)
			dyn[nd++] = b->o->dynamic_surface[i];
	unsigned flags = SL_SPEC_CACHE_PARAMS |
			 (b->light_derivatives ? SL_SPEC_LIGHT_DERIVATIVES : 0);
	struct sl_spec *spec = sl_specialize_ex(prog, dyn, nd, flags, b->diag);
	if (!spec) {
		free(dyn);
		return NULL;
	}
	/* ray-traced light the bake keeps: say it does not follow edits */
	uint32_t frozen = sl_program_report_frozen_rays(prog, b->diag, b->o->strict);
	for (uint32_t i = 0; i < frozen; i++)
		reyes_render_warned();
	if (frozen && b->o->strict) {
		sl_spec_destroy(spec);
		free(dyn);
		return NULL;
	}
	/* the GPU preview adds lights one at a time: say where that does not hold */
	if (sl_program_report_nonaffine(prog, b->diag, b->o->strict)) {
		if (b->o->strict) {
			sl_spec_destroy(spec);
			free(dyn);
			return NULL;
		}
	}
	if (opacity_dynamic(spec)) {
		fprintf(b->diag, "relight: error: surface shader '%s': its opacity (Oi) depends on "
			"the lights or on an editable parameter, so what each pixel sees cannot be "
			"baked\n", prog->name);
		sl_spec_destroy(spec);
		free(dyn);
		return NULL;
	}
	for (uint32_t k = 0; k < spec->ncached; k++)
		if (prog->regs[spec->cached[k]].type == SL_TYPE_STRING) {
			fprintf(b->diag, "relight: error: surface shader '%s': a string value (%s) is "
				"computed before the lights and used after them; shot files cannot "
				"hold cached strings yet\n", prog->name,
				sl_ir_reg_name(prog, spec->cached[k]));
			sl_spec_destroy(spec);
			free(dyn);
			return NULL;
		}
	struct group *g = rl_xcalloc(1, sizeof(*g));
	g->dyn = dyn;
	g->ndyn = nd;
	g->prog = prog;
	g->shader = prog->name;
	g->spec = spec;
	g->offset = rl_xcalloc(spec->ncached + 1, sizeof(uint32_t));
	g->nbase = sl_spec_cache_layout(spec, g->offset);
	g->offset[spec->ncached] = g->nbase;
	/* Derivative stencils (sl_exec_set_stencil): the steps of the values
	 * the dynamic part takes derivatives through, and the grid's du, dv. */
	uint32_t extra = 0;
	for (uint32_t k = 0; spec->needs_stencil && k < spec->ncached; k++)
		if (spec->cached_deriv[k])
			extra += 2 * (g->offset[k + 1] - g->offset[k]);
	g->ncols = g->nbase + extra + (spec->needs_stencil ? 2 : 0);
	g->colname = rl_xcalloc(g->ncols + 1, sizeof(*g->colname));
	g->coltype = rl_xcalloc(g->ncols + 1, 1);
	uint32_t col = 0;
	for (uint32_t k = 0; k < spec->ncached; k++)
		for (uint32_t f = 0; f < g->offset[k + 1] - g->offset[k]; f++, col++) {
			snprintf(g->colname[col], sizeof(g->colname[col]), "c%03u.%02u", k, f);
			g->coltype[col] = (uint8_t)prog->regs[spec->cached[k]].type;
		}
	for (uint32_t k = 0; spec->needs_stencil && k < spec->ncached; k++) {
		uint32_t nc = g->offset[k + 1] - g->offset[k];
		for (uint32_t f = 0; spec->cached_deriv[k] && f < 2 * nc; f++, col++) {
			snprintf(g->colname[col], sizeof(g->colname[col]), "%c%03u.%02u",
				 f < nc ? 'u' : 'v', k, f % nc);
			g->coltype[col] = (uint8_t)prog->regs[spec->cached[k]].type;
		}
	}
	if (spec->needs_stencil) {
		snprintf(g->colname[col], sizeof(g->colname[col]), "du");
		g->coltype[col++] = SL_TYPE_FLOAT;
		snprintf(g->colname[col], sizeof(g->colname[col]), "dv");
		g->coltype[col++] = SL_TYPE_FLOAT;
	}
	/* table names are unique: a second program of the same name gets a number */
	size_t n = strlen(prog->name) + 32;
	g->table = rl_xmalloc(n);
	snprintf(g->table, n, "samples.%s", prog->name);
	for (size_t i = 0, same = 0; i < b->groups.len; i++)
		if (!strcmp(b->groups.data[i]->shader, prog->name))
			snprintf(g->table, n, "samples.%s.%zu", prog->name, ++same);
	return g;
}

static struct group *find_group(struct bake *b, const struct sl_program *prog)
{
	for (size_t i = 0; i < b->groups.len; i++)
		if (b->groups.data[i]->prog == prog)
			return b->groups.data[i];
	return NULL;
}

static void free_group(struct group *g)
{
	for (size_t i = 0; i < g->chunks.len; i++)
		free(g->chunks.data[i].values);
	rl_vec_free(g->chunks);
	sl_spec_destroy(g->spec);
	cJSON_Delete(g->compress);
	free(g->colname);
	free(g->coltype);
	free(g->dyn);
	for (size_t i = 0; i < g->paramsets.len; i++)
		free(g->paramsets.data[i]);
	rl_vec_free(g->paramsets);
	free(g->offset);
	free(g->table);
	free(g);
}

static uint32_t lightset_of(struct bake *b, const struct reyes_attrs *a)
{
	for (size_t i = 0; i < b->lightsets.len; i++) {
		const struct reyes_attrs *o = b->lightsets.data[i];
		if (o->nlights == a->nlights &&
		    (!a->nlights || !memcmp(o->lights, a->lights, a->nlights * sizeof(uint32_t))))
			return (uint32_t)i;
	}
	rl_vec_push(b->lightsets, a);
	return (uint32_t)b->lightsets.len - 1;
}

static cJSON *param_json(const struct reyes_param_value *pv)
{
	cJSON *p = cJSON_CreateObject();
	cJSON_AddStringToObject(p, "name", pv->name);
	cJSON_AddStringToObject(p, "type", sl_basetype_name(pv->type));
	cJSON *v = cJSON_CreateArray();
	for (uint32_t k = 0; k < pv->nvalues; k++) {
		if (pv->type == SL_TYPE_STRING)
			cJSON_AddItemToArray(v, cJSON_CreateString(pv->strings && pv->strings[k]
								   ? pv->strings[k] : ""));
		else
			cJSON_AddItemToArray(v, cJSON_CreateNumber(pv->values[k]));
	}
	cJSON_AddItemToObject(p, "value", v);
	return p;
}

/* The index of the values @surf gives @g's editable parameters (lock held). */
static uint32_t paramset_of(struct group *g, const struct reyes_shader *surf)
{
	if (!g->ndyn)
		return 0;
	cJSON *a = cJSON_CreateArray();
	for (size_t i = 0; i < g->ndyn; i++)
		for (uint32_t k = 0; k < surf->nparams; k++)
			if (!strcmp(surf->params[k].name, g->dyn[i]))
				cJSON_AddItemToArray(a, param_json(&surf->params[k]));
	char *text = cJSON_PrintUnformatted(a);
	cJSON_Delete(a);
	if (!text)
		return 0;
	for (size_t i = 0; i < g->paramsets.len; i++)
		if (!strcmp(g->paramsets.data[i], text)) {
			free(text);
			return (uint32_t)i;
		}
	rl_vec_push(g->paramsets, text);
	return (uint32_t)g->paramsets.len - 1;
}

/* ---- the renderer's hooks ---- */

static const struct sl_program *hook_program(void *user, const struct reyes_shader *surf)
{
	struct bake *b = user;
	pthread_mutex_lock(&b->lock);
	struct group *g = find_group(b, surf->prog);
	if (!g && !b->failed) {
		g = new_group(b, surf);
		if (g)
			rl_vec_push(b->groups, g);
		else
			b->failed = true;
	}
	pthread_mutex_unlock(&b->lock);
	return g ? g->spec->caching : NULL;
}

static uint32_t hook_grid(void *user, const struct reyes_shader *surf,
			  const struct reyes_prim *prim, struct sl_exec *x, uint32_t n)
{
	struct bake *b = user;
	pthread_mutex_lock(&b->lock);
	struct group *g = find_group(b, surf->prog);
	uint64_t id0 = b->next_id;
	bool fits = g && id0 + n < UINT32_MAX;
	if (fits)
		b->next_id += n;
	else if (g && !b->failed) {
		struct rib_loc at = prim->attrs->shading_rate_loc;
		if (at.file)
			fprintf(b->diag, "%s:%u: error: ", at.file, at.line);
		else
			fputs("relight: error: ", b->diag);
		fprintf(b->diag, "more than %u shading samples: the scene is too large to bake in "
			"one shot (use a coarser ShadingRate)\n", UINT32_MAX - 1);
	}
	uint32_t lightset = fits ? lightset_of(b, prim->attrs) : 0;
	uint32_t paramset = fits ? paramset_of(g, surf) : 0;
	pthread_mutex_unlock(&b->lock);
	if (!fits)
		return UINT32_MAX;

	struct chunk c = { .id0 = (uint32_t)id0, .n = n, .object = prim->id, .lightset = lightset,
			   .paramset = paramset };
	c.values = rl_xmalloc(((size_t)n * g->ncols + 1) * sizeof(float));
	const struct sl_program *cp = sl_exec_program(x);
	uint32_t stride = sl_exec_stride(x);
	for (uint32_t k = 0; k < g->spec->ncached; k++) {
		int32_t reg = g->spec->cached[k];
		const float *d = sl_exec_reg(x, reg);
		bool vary = cp->regs[reg].varying;
		for (uint32_t f = 0, col = g->offset[k]; col < g->offset[k + 1]; f++, col++)
			for (uint32_t i = 0; i < n; i++) {
				float v = d ? (vary ? d[(size_t)f * stride + i] : d[f]) : 0.0f;
				c.values[(size_t)i * g->ncols + col] = isfinite(v) ? v : 0.0f;
			}
	}
	if (g->spec->needs_stencil) {
		float *du = rl_xmalloc(((size_t)n + 1) * sizeof(float));
		float *dv = rl_xmalloc(((size_t)n + 1) * sizeof(float));
		uint32_t col = g->nbase;
		for (uint32_t k = 0; k < g->spec->ncached; k++) {
			if (!g->spec->cached_deriv[k])
				continue;
			uint32_t nc = g->offset[k + 1] - g->offset[k];
			for (uint32_t f = 0; f < nc; f++) {
				if (!sl_exec_reg_delta(x, g->spec->cached[k], (int)f, du, dv)) {
					memset(du, 0, n * sizeof(float));
					memset(dv, 0, n * sizeof(float));
				}
				for (uint32_t i = 0; i < n; i++) {
					float *row = c.values + (size_t)i * g->ncols;
					row[col + f] = isfinite(du[i]) ? du[i] : 0.0f;
					row[col + nc + f] = isfinite(dv[i]) ? dv[i] : 0.0f;
				}
			}
			col += 2 * nc;
		}
		float hu, hv;
		sl_exec_grid_steps(x, &hu, &hv);
		for (uint32_t i = 0; i < n; i++) {
			c.values[(size_t)i * g->ncols + col] = isfinite(hu) ? hu : 0.0f;
			c.values[(size_t)i * g->ncols + col + 1] = isfinite(hv) ? hv : 0.0f;
		}
		free(du);
		free(dv);
	}
	pthread_mutex_lock(&b->lock);
	rl_vec_push(g->chunks, c);
	pthread_mutex_unlock(&b->lock);
	return (uint32_t)id0;
}

static bool hook_bucket(void *user, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1,
			const uint32_t *offsets, const struct reyes_vis_entry *entries,
			const float *alpha)
{
	struct bake *b = user;
	size_t np = (size_t)(x1 - x0) * (y1 - y0);
	struct bucket k = { x0, y0, x1, y1, NULL, NULL, NULL };
	k.offsets = rl_xmalloc((np + 1) * sizeof(uint32_t));
	memcpy(k.offsets, offsets, (np + 1) * sizeof(uint32_t));
	k.entries = rl_xmalloc(((size_t)offsets[np] + 1) * sizeof(*k.entries));
	memcpy(k.entries, entries, (size_t)offsets[np] * sizeof(*k.entries));
	k.alpha = rl_xmalloc((np + 1) * sizeof(float));
	memcpy(k.alpha, alpha, np * sizeof(float));
	pthread_mutex_lock(&b->lock);
	rl_vec_push(b->buckets, k);
	pthread_mutex_unlock(&b->lock);
	return true;
}

/* ---- compaction ---- */

static int cmp_chunk(const void *pa, const void *pb)
{
	const struct chunk *a = pa, *b = pb;
	return (a->id0 > b->id0) - (a->id0 < b->id0);
}

static int cmp_weight_desc(const void *pa, const void *pb)
{
	const struct reyes_vis_entry *a = pa, *b = pb;
	if (a->weight != b->weight)
		return a->weight < b->weight ? 1 : -1;
	return (a->id > b->id) - (a->id < b->id);
}

/* ---- metadata ---- */

/*
 * A shader's source: as an absolute path, so that the shot can be previewed
 * from any directory, and as a path relative to the shot file's folder
 * (@shot_dir), so that a project moved as a whole keeps its shots; and the
 * hashes its program is checked against when the shot is read.
 */
static void add_source(cJSON *j, const struct sl_program *p, const char *shot_dir)
{
	const char *path = p->source_path;
	char *abs = path ? rl_path_absolute(path) : NULL;
	char *rel = path && shot_dir ? rl_path_relative(path, shot_dir) : NULL;
	cJSON_AddStringToObject(j, "source", abs ? abs : path ? path : "");
	if (rel)
		cJSON_AddStringToObject(j, "source_relative", rel);
	cJSON_AddStringToObject(j, "source_hash", p->source_hash);
	cJSON_AddStringToObject(j, "program_hash", p->program_hash);
	free(abs);
	free(rel);
}

static cJSON *matrix_json(const float m[16])
{
	cJSON *a = cJSON_CreateArray();
	for (int i = 0; i < 16; i++)
		cJSON_AddItemToArray(a, cJSON_CreateNumber(m[i]));
	return a;
}

static cJSON *params_json(const struct reyes_shader *sh)
{
	cJSON *ps = cJSON_CreateArray();
	for (uint32_t i = 0; i < sh->nparams; i++)
		cJSON_AddItemToArray(ps, param_json(&sh->params[i]));
	return ps;
}

static char *metadata(const struct bake *b, const struct bake_stats *st, const char *shot_dir)
{
	const struct reyes_scene *sc = b->scene;
	const struct reyes_options *so = &sc->opts;
	cJSON *root = cJSON_CreateObject();
	cJSON_AddNumberToObject(root, "format", SHOT_FORMAT_VERSION);
	cJSON_AddStringToObject(root, "relight", RELIGHT_VERSION);
	cJSON_AddNumberToObject(root, "width", so->xres);
	cJSON_AddNumberToObject(root, "height", so->yres);
	cJSON *px = cJSON_AddArrayToObject(root, "pixel_samples");
	cJSON_AddItemToArray(px, cJSON_CreateNumber(so->xsamples ? so->xsamples : 1));
	cJSON_AddItemToArray(px, cJSON_CreateNumber(so->ysamples ? so->ysamples : 1));
	cJSON_AddItemToObject(root, "world_to_camera", matrix_json(so->world_to_camera));
	cJSON_AddBoolToObject(root, "light_derivatives", b->light_derivatives);
	cJSON_AddStringToObject(root, "specular_model", sl_specular_model_name(so->specular_model));

	cJSON *lights = cJSON_AddArrayToObject(root, "lights");
	for (uint32_t i = 0; i < sc->nlights; i++) {
		const struct reyes_light *l = &sc->lights[i];
		cJSON *j = cJSON_CreateObject();
		cJSON_AddStringToObject(j, "name", l->handle ? l->handle : "");
		cJSON_AddStringToObject(j, "shader", l->shader.name);
		add_source(j, l->shader.prog, shot_dir);
		cJSON_AddItemToObject(j, "params", params_json(&l->shader));
		cJSON_AddItemToObject(j, "shader_to_world", matrix_json(l->shader.shader_to_world));
		cJSON_AddItemToArray(lights, j);
	}
	if (so->imager) {
		/* the preview runs it after its resolve, with these values (imager.h) */
		cJSON *j = cJSON_AddObjectToObject(root, "imager");
		cJSON_AddStringToObject(j, "shader", so->imager->name);
		add_source(j, so->imager->prog, shot_dir);
		cJSON_AddItemToObject(j, "params", params_json(so->imager));
		cJSON_AddNumberToObject(j, "time", so->shutter[0]);
		cJSON_AddNumberToObject(j, "dtime", so->shutter[1] - so->shutter[0]);
	}
	cJSON *sets = cJSON_AddArrayToObject(root, "lightsets");
	for (size_t i = 0; i < b->lightsets.len; i++) {
		const struct reyes_attrs *a = b->lightsets.data[i];
		cJSON *s = cJSON_CreateArray();
		for (uint32_t k = 0; k < a->nlights; k++)
			cJSON_AddItemToArray(s, cJSON_CreateNumber(a->lights[k]));
		cJSON_AddItemToArray(sets, s);
	}
	cJSON *groups = cJSON_AddArrayToObject(root, "surfaces");
	for (size_t i = 0; i < b->groups.len; i++) {
		const struct group *g = b->groups.data[i];
		const struct sl_program *p = g->prog;
		cJSON *j = cJSON_CreateObject();
		cJSON_AddStringToObject(j, "shader", g->shader);
		add_source(j, sl_program_surface_part(p), shot_dir);
		if (sl_program_atmosphere(p)) {
			/* the atmosphere joined after the surface (sl_program_compose) */
			const struct sl_program *a = sl_program_atmosphere(p);
			cJSON *aj = cJSON_AddObjectToObject(j, "atmosphere");
			cJSON_AddStringToObject(aj, "shader", sl_program_name(a));
			add_source(aj, a, shot_dir);
		}
		cJSON_AddStringToObject(j, "table", g->table);
		cJSON_AddNumberToObject(j, "first_id", g->first_id);
		cJSON_AddNumberToObject(j, "samples", (double)g->rows);
		cJSON *dyn = cJSON_AddArrayToObject(j, "dynamic_params");
		for (size_t k = 0; k < b->o->ndynamic; k++)
			if (sl_program_find_param(p, b->o->dynamic_surface[k]) >= 0)
				cJSON_AddItemToArray(dyn, cJSON_CreateString(b->o->dynamic_surface[k]));
		if (g->ndyn) {
			cJSON *sets = cJSON_AddArrayToObject(j, "param_sets");
			for (size_t k = 0; k < g->paramsets.len; k++)
				cJSON_AddItemToArray(sets, cJSON_Parse(g->paramsets.data[k]));
		}
		cJSON *ch = cJSON_AddArrayToObject(j, "cached");
		for (uint32_t k = 0; k < g->spec->ncached; k++) {
			int32_t reg = g->spec->cached[k];
			cJSON *c = cJSON_CreateObject();
			cJSON_AddStringToObject(c, "name", sl_ir_reg_name(p, reg));
			cJSON_AddStringToObject(c, "type", sl_basetype_name(p->regs[reg].type));
			cJSON_AddNumberToObject(c, "components", g->offset[k + 1] - g->offset[k]);
			cJSON_AddItemToArray(ch, c);
		}
		if (g->compress) {
			cJSON_AddItemToObject(j, "channels", g->compress);
			((struct group *)g)->compress = NULL;
		}
		cJSON_AddItemToArray(groups, j);
	}
	cJSON *levels = cJSON_AddArrayToObject(root, "levels");
	static const char *const level_table[BAKE_LEVELS] = { "level0", "level1", "level2", "ifb" };
	static const int block[BAKE_LEVELS] = { 4, 2, 1, 1 };
	for (int L = 0; L < BAKE_LEVELS; L++) {
		cJSON *l = cJSON_CreateObject();
		cJSON_AddStringToObject(l, "part", level_table[L]);
		cJSON_AddNumberToObject(l, "block", block[L]);
		cJSON_AddNumberToObject(l, "entries", (double)st->level_entries[L]);
		cJSON_AddNumberToObject(l, "samples", (double)st->level_samples[L]);
		cJSON_AddItemToArray(levels, l);
	}
	if (b->casters.len) {
		cJSON *sg = cJSON_AddObjectToObject(root, "shadow_geometry");
		cJSON_AddNumberToObject(sg, "rate", b->shadow_rate);
		cJSON *ls = cJSON_AddArrayToObject(sg, "lights");
		for (size_t i = 0; i < b->casters.len; i++)
			cJSON_AddItemToArray(ls, cJSON_CreateNumber(b->casters.data[i]));
		cJSON_AddStringToObject(sg, "points", "shadow.points");
		cJSON_AddStringToObject(sg, "quads", "shadow.quads");
		cJSON_AddStringToObject(sg, "opacity", "shadow.quads.opacity");
		cJSON_AddStringToObject(sg, "space", "world");
	}
	cJSON *tl = cJSON_AddObjectToObject(root, "tiling");
	cJSON_AddNumberToObject(tl, "tile_size", st->tile_size);
	if (b->tiles_json) {
		cJSON_AddItemToObject(tl, "tiles", b->tiles_json);
		((struct bake *)b)->tiles_json = NULL;
	}
	cJSON *fig = cJSON_AddObjectToObject(root, "figures");
	cJSON_AddNumberToObject(fig, "shaded_points", (double)st->shaded_points);
	cJSON_AddNumberToObject(fig, "shading_samples", (double)st->shading_samples);
	cJSON_AddNumberToObject(fig, "sample_rows", (double)st->sample_rows);
	cJSON_AddNumberToObject(fig, "subpixel_samples", (double)st->subpixel_samples);
	cJSON_AddNumberToObject(fig, "raw_entries", (double)st->raw_entries);
	cJSON_AddNumberToObject(fig, "indirect_entries", (double)st->indirect_entries);
	cJSON_AddNumberToObject(fig, "render_seconds", st->render_seconds);
	cJSON *chn = cJSON_AddObjectToObject(fig, "channels");
	cJSON_AddNumberToObject(chn, "dynamic", st->channels_dynamic);
	cJSON_AddNumberToObject(chn, "varying", st->channels_varying);
	cJSON_AddNumberToObject(chn, "unique", st->channels_unique);
	cJSON_AddNumberToObject(chn, "half", st->channels_half);
	cJSON_AddNumberToObject(chn, "float", st->channels_float);
	cJSON_AddNumberToObject(fig, "tiles", st->tiles);
	cJSON_AddNumberToObject(fig, "shadow_points", (double)st->shadow_points);
	cJSON_AddNumberToObject(fig, "shadow_quads", (double)st->shadow_quads);
	char *text = cJSON_PrintUnformatted(root);
	cJSON_Delete(root);
	return text;
}

/* ---- the shot ---- */

/* Per pixel its entries (original sample ids), heaviest first. */
struct ifb {
	uint32_t W, H;
	uint64_t *offsets;   /* W * H + 1 */
	uint32_t *id;
	float *w;
	float *alpha;        /* per pixel */
};

/* A coarse refinement level: one entry per block x block pixels. */
struct level {
	uint32_t block, nx, ny;
	uint32_t *id;        /* nx * ny; UINT32_MAX: an empty block */
	float *w;
};

static const uint32_t level_block[BAKE_LEVELS - 1] = { 4, 2, 1 };

static void gather_ifb(const struct bake *b, const uint8_t *ok_id, struct ifb *f)
{
	size_t npix = (size_t)f->W * f->H;
	f->offsets = rl_xcalloc(npix + 1, sizeof(uint64_t));
	f->alpha = rl_xcalloc(npix + 1, sizeof(float));
	uint64_t nid = b->next_id;
	for (int pass = 0; pass < 2; pass++) {
		if (pass == 1) {
			for (size_t p = 0; p < npix; p++)
				f->offsets[p + 1] += f->offsets[p];
			f->id = rl_xmalloc((f->offsets[npix] + 1) * sizeof(uint32_t));
			f->w = rl_xmalloc((f->offsets[npix] + 1) * sizeof(float));
		}
		struct reyes_vis_entry *scratch = NULL;
		size_t scap = 0;
		for (size_t k = 0; k < b->buckets.len; k++) {
			const struct bucket *bk = &b->buckets.data[k];
			uint32_t w = bk->x1 - bk->x0;
			for (uint32_t y = bk->y0; y < bk->y1; y++)
				for (uint32_t x = bk->x0; x < bk->x1; x++) {
					size_t lp = (size_t)(y - bk->y0) * w + (x - bk->x0);
					size_t gp = (size_t)y * f->W + x;
					size_t n = 0, need = bk->offsets[lp + 1] - bk->offsets[lp];
					if (need > scap) {
						scap = need * 2;
						scratch = rl_xrealloc(scratch, scap * sizeof(*scratch));
					}
					for (uint32_t e = bk->offsets[lp]; e < bk->offsets[lp + 1]; e++) {
						const struct reyes_vis_entry *en = &bk->entries[e];
						if (en->id < nid && ok_id[en->id] && en->weight > 0.0f &&
						    isfinite(en->weight))
							scratch[n++] = *en;
					}
					if (pass == 0) {
						f->offsets[gp + 1] = n;
						f->alpha[gp] = isfinite(bk->alpha[lp]) ? bk->alpha[lp]
										       : 0.0f;
						continue;
					}
					if (n > 1)
						qsort(scratch, n, sizeof(*scratch), cmp_weight_desc);
					for (size_t e = 0; e < n; e++) {
						f->id[f->offsets[gp] + e] = scratch[e].id;
						f->w[f->offsets[gp] + e] = scratch[e].weight;
					}
				}
		}
		free(scratch);
	}
}

/*
 * Level @lv (block size set): per block, the sample that carries the most
 * weight over the block's pixels, weighted by the block's mean coverage, so
 * that brightness holds at every level (lightspeed §5.2).
 */
static void make_level(const struct ifb *f, struct level *lv)
{
	uint32_t B = lv->block;
	lv->nx = (f->W + B - 1) / B;
	lv->ny = (f->H + B - 1) / B;
	size_t nb = (size_t)lv->nx * lv->ny;
	lv->id = rl_xmalloc((nb + 1) * sizeof(uint32_t));
	lv->w = rl_xmalloc((nb + 1) * sizeof(float));
	uint32_t *sid = NULL;
	double *sw = NULL;
	size_t cap = 0;
	for (uint32_t by = 0; by < lv->ny; by++)
		for (uint32_t bx = 0; bx < lv->nx; bx++) {
			size_t n = 0;
			double total = 0.0;
			uint32_t npix = 0;
			for (uint32_t y = by * B; y < by * B + B && y < f->H; y++)
				for (uint32_t x = bx * B; x < bx * B + B && x < f->W; x++) {
					size_t p = (size_t)y * f->W + x;
					npix++;
					for (uint64_t e = f->offsets[p]; e < f->offsets[p + 1]; e++) {
						total += f->w[e];
						size_t k = 0;
						while (k < n && sid[k] != f->id[e])
							k++;
						if (k == n) {
							if (n == cap) {
								cap = cap ? cap * 2 : 64;
								sid = rl_xrealloc(sid, cap * sizeof(*sid));
								sw = rl_xrealloc(sw, cap * sizeof(*sw));
							}
							sid[n] = f->id[e];
							sw[n++] = 0.0;
						}
						sw[k] += f->w[e];
					}
				}
			size_t best = 0;
			for (size_t k = 1; k < n; k++)
				if (sw[k] > sw[best] || (sw[k] == sw[best] && sid[k] < sid[best]))
					best = k;
			size_t b = (size_t)by * lv->nx + bx;
			lv->id[b] = n ? sid[best] : UINT32_MAX;
			lv->w[b] = n ? (float)(total / npix) : 0.0f;
		}
	free(sid);
	free(sw);
}

/* Tiles of @T x @T pixels (@T a multiple of 4; 0: the whole frame). */
struct tiling {
	uint32_t T, nx, ny;
};

static struct tiling tiling_of(uint32_t W, uint32_t H, uint32_t T)
{
	struct tiling t = { T, 1, 1 };
	if (T) {
		t.nx = (W + T - 1) / T;
		t.ny = (H + T - 1) / T;
	}
	return t;
}

static void tile_rect(const struct tiling *t, uint32_t W, uint32_t H, uint32_t k, uint32_t r[4])
{
	if (!t->T) {
		r[0] = r[1] = 0;
		r[2] = W;
		r[3] = H;
		return;
	}
	r[0] = (k % t->nx) * t->T;
	r[1] = (k / t->nx) * t->T;
	r[2] = r[0] + t->T < W ? r[0] + t->T : W;
	r[3] = r[1] + t->T < H ? r[1] + t->T : H;
}

/* What the layout needs to know of every original sample id. */
struct idinfo {
	uint32_t *group;     /* group index; UINT32_MAX: no group */
	uint32_t *chunk;     /* index into its group's chunks */
	uint8_t *level;      /* scratch: first level a tile uses it at (255: unused) */
	uint32_t *map;       /* scratch: new id within the tile being laid out */
};

/*
 * The samples tile @k uses, as sorted keys (group << 40 | level << 32 | id):
 * the order of their rows. Returns the count; *bytes: what the tile takes.
 */
static size_t tile_keys(const struct bake *b, const struct ifb *f, const struct level *lv,
			const struct tiling *t, uint32_t k, struct idinfo *ii, uint64_t **keys,
			size_t *cap, uint64_t *bytes)
{
	uint32_t r[4];
	tile_rect(t, f->W, f->H, k, r);
	size_t n = 0;
	uint64_t entries = 0;
#define TOUCH(ID, L) do { \
		uint32_t id_ = (ID); \
		if (ii->level[id_] == 255) { \
			if (n == *cap) { \
				*cap = *cap ? *cap * 2 : 1024; \
				*keys = rl_xrealloc(*keys, *cap * sizeof(**keys)); \
			} \
			(*keys)[n++] = id_; \
		} \
		if ((L) < ii->level[id_]) \
			ii->level[id_] = (uint8_t)(L); \
	} while (0)
	for (int L = 0; L < BAKE_LEVELS - 1; L++) {
		const struct level *l = &lv[L];
		for (uint32_t by = r[1] / l->block; by * l->block < r[3]; by++)
			for (uint32_t bx = r[0] / l->block; bx * l->block < r[2]; bx++) {
				uint32_t id = l->id[(size_t)by * l->nx + bx];
				entries++;
				if (id != UINT32_MAX)
					TOUCH(id, L);
			}
	}
	for (uint32_t y = r[1]; y < r[3]; y++)
		for (uint32_t x = r[0]; x < r[2]; x++) {
			size_t p = (size_t)y * f->W + x;
			entries += f->offsets[p + 1] - f->offsets[p];
			for (uint64_t e = f->offsets[p]; e < f->offsets[p + 1]; e++)
				TOUCH(f->id[e], BAKE_LEVELS - 1);
		}
#undef TOUCH
	uint64_t by = entries * 8 + (uint64_t)(r[2] - r[0]) * (r[3] - r[1]) * 12;
	for (size_t i = 0; i < n; i++) {
		uint32_t id = (uint32_t)(*keys)[i];
		uint32_t g = ii->group[id];
		by += (uint64_t)(b->groups.data[g]->ncols + 2) * 4;
		(*keys)[i] = (uint64_t)g << 40 | (uint64_t)ii->level[id] << 32 | id;
		ii->level[id] = 255;
	}
	*bytes = by;
	return n;
}

static int cmp_u64(const void *pa, const void *pb)
{
	uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
	return (a > b) - (a < b);
}

/* The largest tile's bytes when tiled by @t. */
static uint64_t max_tile_bytes(const struct bake *b, const struct ifb *f, const struct level *lv,
			       const struct tiling *t, struct idinfo *ii)
{
	uint64_t *keys = NULL, worst = 0;
	size_t cap = 0;
	for (uint32_t k = 0; k < t->nx * t->ny; k++) {
		uint64_t by;
		tile_keys(b, f, lv, t, k, ii, &keys, &cap, &by);
		if (by > worst)
			worst = by;
	}
	free(keys);
	return worst;
}

/*
 * How a channel of a cached value of type @type is stored: points and
 * plain floats as half only when every value is one exactly (ids, flags,
 * 0.5); colours, normals and vectors as half when they fit its range (their
 * error, at most 2^-11 relative, is measured and reported).
 */
static bool store_as_half(enum sl_basetype type, const float *v, uint64_t n, double *max_rel)
{
	bool lossy = type == SL_TYPE_COLOR || type == SL_TYPE_NORMAL || type == SL_TYPE_VECTOR;
	double worst = 0.0;
	for (uint64_t r = 0; r < n; r++) {
		float h = shot_half_round(v[r]);
		if (h == v[r])
			continue;
		if (!lossy || !(fabsf(v[r]) <= 65504.0f))
			return false;
		double rel = fabs((double)h - v[r]) / fmax(fabs((double)v[r]), 1e-30);
		if (fabsf(v[r]) >= 0x1p-14f && rel > worst)
			worst = rel;
	}
	if (worst > *max_rel)
		*max_rel = worst;
	return true;
}

static bool write_shot(struct bake *b, const char *path, struct bake_stats *st)
{
	const struct reyes_options *so = &b->scene->opts;
	uint32_t W = so->xres, H = so->yres;
	size_t npix = (size_t)W * H;
	uint64_t nid = b->next_id;
	bool ok = true;
	report(b, SHARE_COMPACT, "compacting");

	/* Every id's group and chunk. */
	struct idinfo ii;
	ii.group = rl_xmalloc((nid + 1) * sizeof(uint32_t));
	ii.chunk = rl_xmalloc((nid + 1) * sizeof(uint32_t));
	ii.level = rl_xmalloc(nid + 1);
	ii.map = rl_xmalloc((nid + 1) * sizeof(uint32_t));
	memset(ii.level, 255, nid + 1);
	uint8_t *ok_id = rl_xcalloc(nid + 1, 1);
	for (uint64_t i = 0; i < nid; i++)
		ii.group[i] = UINT32_MAX;
	for (size_t gi = 0; gi < b->groups.len; gi++) {
		struct group *g = b->groups.data[gi];
		if (g->chunks.len > 1)
			qsort(g->chunks.data, g->chunks.len, sizeof(struct chunk), cmp_chunk);
		for (size_t c = 0; c < g->chunks.len; c++) {
			const struct chunk *ch = &g->chunks.data[c];
			for (uint32_t i = 0; i < ch->n; i++) {
				ii.group[ch->id0 + i] = (uint32_t)gi;
				ii.chunk[ch->id0 + i] = (uint32_t)c;
				ok_id[ch->id0 + i] = 1;
			}
		}
	}

	/* The indirect framebuffer and the coarse levels, in original ids. */
	struct ifb f = { .W = W, .H = H };
	gather_ifb(b, ok_id, &f);
	free(ok_id);
	struct level lv[BAKE_LEVELS - 1];
	for (int L = 0; L < BAKE_LEVELS - 1; L++) {
		lv[L].block = level_block[L];
		make_level(&f, &lv[L]);
	}

	/* Tiles: the whole frame if it fits the budget, else the largest square
	 * tiles (a multiple of 4 pixels, so blocks never straddle two) that do. */
	uint64_t budget = b->o->tile_budget ? b->o->tile_budget : BAKE_DEFAULT_TILE_BUDGET;
	struct tiling t = tiling_of(W, H, 0);
	uint64_t worst = max_tile_bytes(b, &f, lv, &t, &ii);
	for (uint32_t T = 1024; worst > budget && T >= 16; T /= 2) {
		if (T >= W && T >= H)
			continue;
		t = tiling_of(W, H, T);
		worst = max_tile_bytes(b, &f, lv, &t, &ii);
	}
	if (worst > budget)
		fprintf(b->diag, "relight: warning: a tile of %u x %u pixels still takes %.1f MB, "
			"more than the tile budget of %.1f MB\n", t.T, t.T, (double)worst / 1e6,
			(double)budget / 1e6);
	uint32_t ntiles = t.nx * t.ny;

	/* Rows: tile by tile; within a tile, surface by surface; within a
	 * surface, level by level (a level's samples are a prefix); then in
	 * id order (the renderer's order). A sample several tiles use has a
	 * row in each. */
	size_t ng = b->groups.len;
	uint64_t *counts = rl_xcalloc((size_t)ntiles * ng * BAKE_LEVELS + 1, sizeof(uint64_t));
	RL_VEC(uint64_t) rows = { 0 };
	uint64_t *tile_first = rl_xcalloc((size_t)ntiles + 1, sizeof(uint64_t));
	{
		uint64_t *keys = NULL;
		size_t cap = 0;
		for (uint32_t k = 0; k < ntiles; k++) {
			uint64_t by;
			size_t n = tile_keys(b, &f, lv, &t, k, &ii, &keys, &cap, &by);
			qsort(keys, n, sizeof(*keys), cmp_u64);
			tile_first[k] = rows.len;
			for (size_t i = 0; i < n; i++) {
				rl_vec_push(rows, keys[i]);
				uint32_t g = (uint32_t)(keys[i] >> 40);
				uint32_t L = (uint32_t)(keys[i] >> 32) & 255;
				counts[((size_t)k * ng + g) * BAKE_LEVELS + L]++;
			}
		}
		tile_first[ntiles] = rows.len;
		free(keys);
	}
	uint64_t total_rows = rows.len;
	if (total_rows >= UINT32_MAX) {
		fprintf(b->diag, "relight: error: more than %u shading samples after tiling; use "
			"a larger --tile-budget or a coarser ShadingRate\n", UINT32_MAX - 1);
		ok = false;
	}
	/* group sizes and first ids */
	uint64_t *gfill = rl_xcalloc(ng + 1, sizeof(uint64_t));
	uint32_t next = 0;
	for (size_t gi = 0; gi < ng; gi++) {
		struct group *g = b->groups.data[gi];
		g->rows = 0;
		for (uint32_t k = 0; k < ntiles; k++)
			for (int L = 0; L < BAKE_LEVELS; L++)
				g->rows += counts[((size_t)k * ng + gi) * BAKE_LEVELS + L];
		g->first_id = next;
		next += (uint32_t)g->rows;
	}
	/* New ids, and the entries and levels in them. */
	uint32_t *src = rl_xmalloc((total_rows + 1) * sizeof(uint32_t));
	uint32_t *ent_id = rl_xmalloc((f.offsets[npix] + 1) * sizeof(uint32_t));
	uint32_t *lv_id[BAKE_LEVELS - 1];
	for (int L = 0; L < BAKE_LEVELS - 1; L++)
		lv_id[L] = rl_xmalloc(((size_t)lv[L].nx * lv[L].ny + 1) * sizeof(uint32_t));
	cJSON *tiles_json = cJSON_CreateArray();
	for (uint32_t k = 0; ok && k < ntiles; k++) {
		uint32_t r[4];
		tile_rect(&t, W, H, k, r);
		cJSON *tj = cJSON_CreateObject();
		cJSON *rect = cJSON_AddArrayToObject(tj, "rect");
		for (int i = 0; i < 4; i++)
			cJSON_AddItemToArray(rect, cJSON_CreateNumber(r[i]));
		cJSON *sj = cJSON_AddArrayToObject(tj, "surfaces");
		for (size_t gi = 0; gi < ng; gi++) {
			cJSON *gj = cJSON_CreateObject();
			cJSON_AddNumberToObject(gj, "first_row", (double)gfill[gi]);
			cJSON *lj = cJSON_AddArrayToObject(gj, "levels");
			uint64_t cum = 0;
			for (int L = 0; L < BAKE_LEVELS; L++) {
				cum += counts[((size_t)k * ng + gi) * BAKE_LEVELS + L];
				cJSON_AddItemToArray(lj, cJSON_CreateNumber((double)cum));
				st->level_samples[L] += cum;
			}
			cJSON_AddItemToArray(sj, gj);
		}
		cJSON_AddItemToArray(tiles_json, tj);
		for (uint64_t i = tile_first[k]; i < tile_first[k + 1]; i++) {
			uint32_t g = (uint32_t)(rows.data[i] >> 40), id = (uint32_t)rows.data[i];
			uint32_t nidv = b->groups.data[g]->first_id + (uint32_t)gfill[g]++;
			ii.map[id] = nidv;
			src[nidv] = id;
		}
		for (int L = 0; L < BAKE_LEVELS - 1; L++) {
			const struct level *l = &lv[L];
			for (uint32_t by = r[1] / l->block; by * l->block < r[3]; by++)
				for (uint32_t bx = r[0] / l->block; bx * l->block < r[2]; bx++) {
					size_t bi = (size_t)by * l->nx + bx;
					lv_id[L][bi] = l->id[bi] == UINT32_MAX ? UINT32_MAX
									       : ii.map[l->id[bi]];
				}
		}
		for (uint32_t y = r[1]; y < r[3]; y++)
			for (uint32_t x = r[0]; x < r[2]; x++) {
				size_t p = (size_t)y * W + x;
				for (uint64_t e = f.offsets[p]; e < f.offsets[p + 1]; e++)
					ent_id[e] = ii.map[f.id[e]];
			}
	}
	free(gfill);
	free(counts);
	free(tile_first);
	rl_vec_free(rows);
	for (int L = 0; L < BAKE_LEVELS - 1; L++) {
		st->level_entries[L] = 0;
		for (size_t i = 0; i < (size_t)lv[L].nx * lv[L].ny; i++)
			st->level_entries[L] += lv[L].id[i] != UINT32_MAX;
	}
	st->level_entries[BAKE_LEVELS - 1] = f.offsets[npix];
	st->tiles = ntiles;
	st->tile_size = t.T;

	/* Sample tables, with constant channels dropped (kept in the
	 * metadata), aliases dropped, half where it holds the values. */
	bool shadow = b->casters.len > 0;
	size_t ntab = ng + 1 + (BAKE_LEVELS - 1) + (shadow ? 2 : 0);
	struct shot_table *tabs = rl_xcalloc(ntab, sizeof(*tabs));
	for (size_t gi = 0; ok && gi < ng; gi++) {
		struct group *g = b->groups.data[gi];
		struct shot_table *tb = &tabs[gi];
		tb->name = g->table;
		tb->nrows = g->rows;
		tb->channels = rl_xcalloc(g->ncols + 3, sizeof(*tb->channels));
		g->compress = cJSON_CreateObject();
		cJSON *consts = cJSON_AddObjectToObject(g->compress, "constants");
		cJSON *aliases = cJSON_AddObjectToObject(g->compress, "aliases");
		double half_err = 0.0;
		st->channels_dynamic += g->ncols;
		for (uint32_t col = 0; col < g->ncols; col++) {
			const char *name = g->colname[col];
			float *v = rl_xmalloc((g->rows + 1) * sizeof(float));
			for (uint64_t r = 0; r < g->rows; r++) {
				uint32_t id = src[g->first_id + r];
				const struct chunk *ch = &g->chunks.data[ii.chunk[id]];
				v[r] = ch->values[(size_t)(id - ch->id0) * g->ncols + col];
			}
			bool varies = false;
			for (uint64_t r = 1; r < g->rows && !varies; r++)
				varies = memcmp(&v[r], &v[0], sizeof(float)) != 0;
			if (!varies) {
				cJSON_AddItemToObject(consts, name,
						      cJSON_CreateNumber(g->rows ? v[0] : 0.0));
				free(v);
				continue;
			}
			st->channels_varying++;
			const char *same = NULL;
			for (uint32_t d = 0; d < tb->nchannels && !same; d++)
				if (!memcmp(v, tb->channels[d].data, g->rows * sizeof(float)))
					same = tb->channels[d].name;
			if (same) {
				cJSON_AddStringToObject(aliases, name, same);
				free(v);
				continue;
			}
			st->channels_unique++;
			struct shot_channel *c = &tb->channels[tb->nchannels++];
			c->name = rl_xstrdup(name);
			c->data = v;
			enum sl_basetype type = (enum sl_basetype)g->coltype[col];
			c->type = !b->o->full_float && store_as_half(type, v, g->rows, &half_err)
				  ? SHOT_HALF : SHOT_FLOAT;
			if (c->type == SHOT_HALF)
				st->channels_half++;
			else
				st->channels_float++;
		}
		cJSON_AddNumberToObject(g->compress, "half_max_relative_error", half_err);
		uint32_t *obj = rl_xmalloc((g->rows + 1) * sizeof(uint32_t));
		uint32_t *set = rl_xmalloc((g->rows + 1) * sizeof(uint32_t));
		for (uint64_t r = 0; r < g->rows; r++) {
			uint32_t id = src[g->first_id + r];
			const struct chunk *ch = &g->chunks.data[ii.chunk[id]];
			obj[r] = ch->object;
			set[r] = ch->lightset;
		}
		tb->channels[tb->nchannels++] = (struct shot_channel){ rl_xstrdup("object"),
								       SHOT_UINT, obj };
		tb->channels[tb->nchannels++] = (struct shot_channel){ rl_xstrdup("lightset"),
								       SHOT_UINT, set };
		if (g->ndyn) {
			uint32_t *ps = rl_xmalloc((g->rows + 1) * sizeof(uint32_t));
			for (uint64_t r = 0; r < g->rows; r++) {
				uint32_t id = src[g->first_id + r];
				ps[r] = g->chunks.data[ii.chunk[id]].paramset;
			}
			tb->channels[tb->nchannels++] = (struct shot_channel){
				rl_xstrdup("paramset"), SHOT_UINT, ps };
		}
	}
	struct shot_table *pt = &tabs[ng];
	pt->name = "pixels";
	pt->nrows = npix;
	pt->nchannels = 1;
	pt->channels = rl_xcalloc(1, sizeof(*pt->channels));
	pt->channels[0] = (struct shot_channel){ rl_xstrdup("A"), SHOT_FLOAT, f.alpha };
	f.alpha = NULL;
	static const char *const level_table[BAKE_LEVELS - 1] = { "level0", "level1", "level2" };
	for (int L = 0; L < BAKE_LEVELS - 1; L++) {
		struct shot_table *lt = &tabs[ng + 1 + L];
		lt->name = (char *)level_table[L];
		lt->nrows = (uint64_t)lv[L].nx * lv[L].ny;
		lt->nchannels = 2;
		lt->channels = rl_xcalloc(2, sizeof(*lt->channels));
		lt->channels[0] = (struct shot_channel){ rl_xstrdup("sample"), SHOT_UINT, lv_id[L] };
		lt->channels[1] = (struct shot_channel){ rl_xstrdup("weight"), SHOT_FLOAT, lv[L].w };
		lv[L].w = NULL;
		lv_id[L] = NULL;
	}

	if (shadow) {
		/* shadow geometry: points (world space) and micropolygons */
		const struct bake_shadow_geometry *sg = &b->shadow;
		struct shot_table *pts = &tabs[ng + BAKE_LEVELS];
		pts->name = "shadow.points";
		pts->nrows = sg->npoints;
		pts->nchannels = 3;
		pts->channels = rl_xcalloc(3, sizeof(*pts->channels));
		static const char *const axis[3] = { "X", "Y", "Z" };
		for (int c = 0; c < 3; c++) {
			float *v = rl_xmalloc((sg->npoints + 1) * sizeof(float));
			for (uint64_t i = 0; i < sg->npoints; i++)
				v[i] = sg->P[i * 3 + (uint64_t)c];
			pts->channels[c] = (struct shot_channel){ rl_xstrdup(axis[c]), SHOT_FLOAT, v };
		}
		struct shot_table *qs = &tabs[ng + BAKE_LEVELS + 1];
		qs->name = "shadow.quads";
		qs->nrows = sg->nquads;
		qs->nchannels = 6;
		qs->channels = rl_xcalloc(6, sizeof(*qs->channels));
		for (int c = 0; c < 4; c++) {
			uint32_t *v = rl_xmalloc((sg->nquads + 1) * sizeof(uint32_t));
			for (uint64_t i = 0; i < sg->nquads; i++)
				v[i] = sg->quads[i * 4 + (uint64_t)c];
			char name[8];
			snprintf(name, sizeof(name), "v%d", c);
			qs->channels[c] = (struct shot_channel){ rl_xstrdup(name), SHOT_UINT, v };
		}
		uint32_t *obj = rl_xmalloc((sg->nquads + 1) * sizeof(uint32_t));
		memcpy(obj, sg->object, sg->nquads * sizeof(uint32_t));
		qs->channels[4] = (struct shot_channel){ rl_xstrdup("object"), SHOT_UINT, obj };
		/* what a deep shadow map the GPU renders sees of each micropolygon */
		float *op = rl_xmalloc((sg->nquads + 1) * sizeof(float));
		if (sg->nquads)
			memcpy(op, sg->opacity, sg->nquads * sizeof(float));
		qs->channels[5] = (struct shot_channel){ rl_xstrdup("opacity"), SHOT_FLOAT, op };
		st->shadow_points = sg->npoints;
		st->shadow_quads = sg->nquads;
	}

	struct shot_channel dch[2] = {
		{ .name = "sample", .type = SHOT_UINT, .data = ent_id },
		{ .name = "weight", .type = SHOT_FLOAT, .data = f.w },
	};
	struct shot_deep deep = {
		.name = "ifb", .width = W, .height = H, .offsets = f.offsets, .nchannels = 2,
		.channels = dch,
	};

	/* distinct samples (a sample in several tiles has a row in each) */
	{
		uint8_t *seen = rl_xcalloc(nid + 1, 1);
		uint64_t distinct = 0;
		for (uint64_t e = 0; e < f.offsets[npix]; e++)
			if (!seen[f.id[e]]) {
				seen[f.id[e]] = 1;
				distinct++;
			}
		free(seen);
		st->shading_samples = distinct;
		st->sample_rows = next;
	}
	st->indirect_entries = f.offsets[npix];
	st->width = W;
	st->height = H;
	b->tiles_json = tiles_json;
	char shot_dir[4096];
	const char *slash = strrchr(path, '/');
	snprintf(shot_dir, sizeof(shot_dir), "%.*s", slash ? (int)(slash - path) + 1 : 1,
		 slash ? path : ".");
	char *meta = ok ? metadata(b, st, shot_dir) : NULL;
	struct shot_file sf = {
		.metadata = meta, .tables = tabs, .ntables = (uint32_t)ntab, .deeps = &deep,
		.ndeeps = 1,
	};
	double t0 = now();
	char err[1024] = "";
	if (ok)
		report(b, SHARE_WRITE, "writing");
	if (ok && (!meta || !shot_write(path, &sf, &b->o->write, err, sizeof(err)))) {
		fprintf(b->diag, "relight: error: %s\n", meta ? err : "out of memory");
		ok = false;
	}
	st->write_seconds = now() - t0;

	free(meta);
	for (size_t i = 0; i < ntab; i++) {
		for (uint32_t c = 0; c < tabs[i].nchannels; c++) {
			free(tabs[i].channels[c].name);
			free(tabs[i].channels[c].data);
		}
		free(tabs[i].channels);
	}
	free(tabs);
	for (int L = 0; L < BAKE_LEVELS - 1; L++) {
		free(lv[L].id);
		free(lv[L].w);
		free(lv_id[L]);
	}
	free(ent_id);
	free(src);
	free(f.offsets);
	free(f.id);
	free(f.w);
	free(f.alpha);
	free(ii.group);
	free(ii.chunk);
	free(ii.level);
	free(ii.map);
	return ok;
}

/*
 * The GPU preview runs the imager as a generated kernel: say now, at its
 * Imager request, when it cannot (the CPU preview still runs it).
 */
static void check_imager(const struct bake *b)
{
	const struct reyes_options *so = &b->scene->opts;
	if (!so->imager)
		return;
	char *text = NULL;
	size_t len = 0;
	FILE *mem = open_memstream(&text, &len);
	if (!mem)
		return;
	enum sl_global globals[SL_GLSL_IMAGER_INPUTS];
	uint32_t nin;
	struct sl_glsl_layout lay;
	char *src = sl_glsl_emit_imager(so->imager->prog, globals, &nin, &lay, mem);
	fclose(mem);
	if (src) {
		sl_glsl_layout_finish(&lay);
	} else {
		fprintf(b->diag, "%s:%u: warning: the imager '%s' cannot run in the GPU preview "
			"(relight preview --cpu runs it):\n%s",
			so->imager_loc.file ? so->imager_loc.file : "<rib>", so->imager_loc.line,
			so->imager->name, text ? text : "");
		reyes_render_warned();
	}
	free(src);
	free(text);
}

bool bake_scene(const struct reyes_scene *scene, const char *path, const struct bake_opts *opts,
		struct bake_stats *stats)
{
	struct bake_stats local = { 0 };
	struct bake_stats *st = stats ? stats : &local;
	memset(st, 0, sizeof(*st));
	struct bake b = { .scene = scene, .o = opts, .diag = opts->diag ? opts->diag : stderr };
	pthread_mutex_init(&b.lock, NULL);
	for (uint32_t i = 0; i < scene->nlights; i++)
		if (sl_program_takes_derivatives(scene->lights[i].shader.prog))
			b.light_derivatives = true;
	struct reyes_bake_hooks hooks = {
		.user = &b, .program = hook_program, .grid = hook_grid, .bucket = hook_bucket,
	};
	/* The default surface's program must live until the shot is written. */
	struct reyes_shader_cache *own = opts->shader_cache ? NULL : reyes_shader_cache_create();
	struct reyes_render_opts ro = {
		.threads = opts->threads, .progress = opts->progress, .diag = b.diag, .bake = &hooks,
		.memory_limit = opts->memory_limit,
		.progress_fn = opts->progress_fn ? render_progress : NULL, .progress_user = &b,
		.shader_cache = opts->shader_cache ? opts->shader_cache : own,
	};
	check_imager(&b);
	report(&b, 0.0, "rendering");
	struct reyes_stats rs = { 0 };
	bool ok = reyes_render(scene, &ro, &rs) && !b.failed;
	st->render_seconds = rs.seconds;
	st->shaded_points = rs.micropolygons;
	const struct reyes_options *so = &scene->opts;
	st->subpixel_samples = (uint64_t)so->xres * so->yres * (so->xsamples ? so->xsamples : 1) *
			       (so->ysamples ? so->ysamples : 1);
	for (size_t k = 0; k < b.buckets.len; k++) {
		const struct bucket *bk = &b.buckets.data[k];
		size_t np = (size_t)(bk->x1 - bk->x0) * (bk->y1 - bk->y0);
		st->raw_entries += bk->offsets[np];
	}
	b.shadow_rate = opts->shadow_rate > 0.0f ? opts->shadow_rate : BAKE_DEFAULT_SHADOW_RATE;
	for (uint32_t i = 0; ok && i < scene->nlights; i++)
		if (bake_light_casts_shadows(scene, i))
			rl_vec_push(b.casters, i);
	if (ok && b.casters.len)
		ok = bake_shadow_geometry(scene, b.shadow_rate, b.diag, &b.shadow);
	if (ok)
		ok = write_shot(&b, path, st);
	if (ok)
		report(&b, 1.0, "done");

	for (size_t k = 0; k < b.buckets.len; k++) {
		free(b.buckets.data[k].offsets);
		free(b.buckets.data[k].entries);
		free(b.buckets.data[k].alpha);
	}
	rl_vec_free(b.buckets);
	for (size_t i = 0; i < b.groups.len; i++)
		free_group(b.groups.data[i]);
	rl_vec_free(b.groups);
	rl_vec_free(b.lightsets);
	cJSON_Delete(b.tiles_json);
	bake_shadow_geometry_free(&b.shadow);
	rl_vec_free(b.casters);
	pthread_mutex_destroy(&b.lock);
	reyes_shader_cache_destroy(own);
	return ok;
}

/* ---- a RIB file ---- */

/* Shadow passes share the first part of a RIB file's progress: as their
 * number is not known ahead, each takes half of what is left of that part. */
#define SHARE_SHADOW_PASSES 0.3

struct rib_bake {
	const struct bake_opts *o;   /* the caller's */
	struct bake_opts bo;         /* the same, with its progress mapped into [lo, hi] */
	const char *rib, *out;
	FILE *diag;
	bool verbose;
	int frames, baked;
	double lo, hi, last;         /* the current step's share; the last fraction reported */
	struct bake_stats *stats;
	struct reyes_shader_cache *shaders; /* compiled once for the read and every pass */
};

static void rib_report(struct rib_bake *j, double fraction, const char *what)
{
	if (!j->o->progress_fn)
		return;
	double f = fraction < 0.0 ? 0.0 : fraction > 1.0 ? 1.0 : fraction;
	double g = j->lo + (j->hi - j->lo) * f;
	/* never backwards, whatever the steps report */
	if (g < j->last)
		g = j->last;
	j->last = g;
	j->o->progress_fn(j->o->progress_user, g, what);
}

static void rib_bake_progress(void *user, double fraction, const char *what)
{
	rib_report(user, fraction, what);
}

static void rib_pass_progress(void *user, double fraction)
{
	rib_report(user, fraction, "shadow pass");
}

static bool rib_frame(void *user, const struct reyes_scene *scene)
{
	struct rib_bake *j = user;
	j->frames++;
	if (reyes_scene_is_shadow_pass(scene)) {
		bool report_it = j->o->progress_fn && !j->baked;
		if (report_it) {
			j->lo = j->last;
			j->hi = j->last < SHARE_SHADOW_PASSES
					? j->last + (SHARE_SHADOW_PASSES - j->last) / 2.0
					: j->last;
		}
		struct reyes_render_opts ro = {
			.threads = j->o->threads, .diag = j->diag, .memory_limit = j->o->memory_limit,
			.progress_fn = report_it ? rib_pass_progress : NULL, .progress_user = j,
			.shader_cache = j->shaders,
		};
		if (j->verbose)
			fprintf(j->diag, "frame %d: a shadow pass, rendered\n", j->frames);
		return reyes_render(scene, &ro, NULL);
	}
	if (j->baked) {
		fprintf(j->diag, "%s: warning: frame %d is not baked (one shot holds one frame; "
			"frame %d was baked)\n", j->rib, j->frames, j->baked);
		return true;
	}
	if (j->verbose)
		fprintf(j->diag, "frame %d: %ux%u, %u primitives, %u lights: baking\n", j->frames,
			scene->opts.xres, scene->opts.yres, scene->nprims, scene->nlights);
	j->lo = j->last;
	j->hi = 1.0;
	struct bake_stats *st = j->stats;
	if (!bake_scene(scene, j->out, &j->bo, st))
		return false;
	j->baked = j->frames;
	if (j->verbose)
		fprintf(j->diag,
			"wrote %s: %ux%u, %llu shading samples kept of %llu shaded, %llu indirect "
			"entries for %llu subpixel samples; render %.2f s, write %.2f s\n",
			j->out, st->width, st->height, (unsigned long long)st->shading_samples,
			(unsigned long long)st->shaded_points,
			(unsigned long long)st->indirect_entries,
			(unsigned long long)st->subpixel_samples, st->render_seconds,
			st->write_seconds);
	return true;
}

/*
 * What a bake of @out killed mid-write left beside it: its temporary files
 * whose writer is gone (rl_remove_stale_temps). Said on @diag when @verbose.
 */
static void remove_stale_temps(const char *out, FILE *diag, bool verbose)
{
	const char *slash = strrchr(out, '/');
	char dir[4096];
	snprintf(dir, sizeof(dir), "%.*s", slash ? (int)(slash - out) + 1 : 1, slash ? out : ".");
	size_t n = rl_remove_stale_temps(dir, slash ? slash + 1 : out);
	if (n && verbose)
		fprintf(diag, "%s: removed %zu temporary file%s of an interrupted write\n", out, n,
			n == 1 ? "" : "s");
}

bool bake_rib_file(const char *rib, const char *out, const struct bake_opts *opts, bool verbose,
		   struct bake_stats *stats)
{
	struct bake_stats local = { 0 };
	struct rib_bake j = {
		.o = opts, .bo = *opts, .rib = rib, .out = out,
		.diag = opts->diag ? opts->diag : stderr, .verbose = verbose,
		.stats = stats ? stats : &local,
	};
	memset(j.stats, 0, sizeof(*j.stats));
	j.bo.diag = j.diag;
	remove_stale_temps(out, j.diag, verbose);
	j.bo.progress_fn = opts->progress_fn ? rib_bake_progress : NULL;
	j.bo.progress_user = &j;

	/* The reader puts the standard library after any path it is given. */
	const char *shader_path = opts->shader_path;
	char env_path[8192];
	if (!shader_path) {
		const char *env = getenv("RELIGHT_SHADER_PATH");
		const char *rman = getenv("RMAN_SHADERPATH");
		env = env ? env : "";
		rman = rman ? rman : "";
		snprintf(env_path, sizeof(env_path), "%s%s%s", env, *env && *rman ? ":" : "", rman);
		shader_path = *env_path ? env_path : NULL;
	}
	struct reyes_ri_counts counts = { 0 };
	struct reyes_ri_opts ri = {
		.diag = j.diag,
		.default_shader_path = shader_path,
		.default_include_path = opts->include_path,
		.shader_cache = j.shaders = reyes_shader_cache_create(),
		.default_texture_path = ".",
		.strict = opts->strict,
		.counts = &counts,
		.frame = rib_frame,
		.user = &j,
	};
	j.bo.shader_cache = j.shaders;
	rib_report(&j, 0.0, "reading");
	bool ok = reyes_ri_read(rib, &ri, NULL);
	reyes_shader_cache_destroy(j.shaders);
	int warnings = counts.warnings + (int)reyes_render_warnings();
	if (verbose && (warnings || counts.errors))
		fprintf(j.diag, "%s: %d warning%s (%d repeat%s not shown), %d error%s, %d "
			"primitive%s dropped\n", rib, warnings,
			warnings == 1 ? "" : "s", counts.repeats,
			counts.repeats == 1 ? "" : "s", counts.errors, counts.errors == 1 ? "" : "s",
			counts.dropped, counts.dropped == 1 ? "" : "s");
	if (ok && !j.baked) {
		fprintf(j.diag, "%s: error: the scene has no frame to bake (no WorldBegin ... "
			"WorldEnd other than shadow passes)\n", rib);
		ok = false;
	}
	return ok;
}

/*
 * The bake: the renderer in bake mode (reyes_bake_hooks) feeding shading
 * samples and pixel recipes into memory, then compaction (samples no pixel
 * uses are dropped, the rest numbered surface shader by surface shader, each
 * pixel's entries sorted heaviest first) and the shot file.
 */
#include "bake.h"

#include "arena.h"
#include "config.h"
#include "exec.h"
#include "mathlib.h"
#include "spec.h"
#include "ast.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* A run of consecutive ids shaded in one grid. */
struct chunk {
	uint32_t id0, n;
	float *values;       /* n rows x ncols, row-major */
	uint32_t object, lightset;
};

/* One surface shader program and the samples shaded with it. */
struct group {
	const struct sl_program *prog;
	const char *shader;  /* the shader's name */
	struct sl_spec *spec;
	char *table;         /* "samples.NAME" */
	uint32_t ncols;      /* floats per sample */
	uint32_t *offset;    /* per cached value, its first float (sl_spec_cache_layout),
				then ncols */
	RL_VEC(struct chunk) chunks;
	uint64_t rows;       /* kept rows, after compaction */
	uint32_t first_id;   /* id of its first kept row */
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
};

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
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
	struct sl_spec *spec = sl_specialize_ex(prog, dyn, nd, SL_SPEC_CACHE_PARAMS, b->diag);
	free(dyn);
	if (!spec)
		return NULL;
	if (opacity_dynamic(spec)) {
		fprintf(b->diag, "relight: error: surface shader '%s': its opacity (Oi) depends on "
			"the lights or on an editable parameter, so what each pixel sees cannot be "
			"baked\n", prog->name);
		sl_spec_destroy(spec);
		return NULL;
	}
	for (uint32_t k = 0; k < spec->ncached; k++)
		if (prog->regs[spec->cached[k]].type == SL_TYPE_STRING) {
			fprintf(b->diag, "relight: error: surface shader '%s': a string value (%s) is "
				"computed before the lights and used after them; shot files cannot "
				"hold cached strings yet\n", prog->name,
				sl_ir_reg_name(prog, spec->cached[k]));
			sl_spec_destroy(spec);
			return NULL;
		}
	struct group *g = rl_xcalloc(1, sizeof(*g));
	g->prog = prog;
	g->shader = prog->name;
	g->spec = spec;
	g->offset = rl_xcalloc(spec->ncached + 1, sizeof(uint32_t));
	g->ncols = sl_spec_cache_layout(spec, g->offset);
	g->offset[spec->ncached] = g->ncols;
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
	else if (g && !b->failed)
		fprintf(b->diag, "relight: error: more than %u shading samples: the scene is too "
			"large to bake in one shot (use a coarser ShadingRate)\n", UINT32_MAX - 1);
	uint32_t lightset = fits ? lightset_of(b, prim->attrs) : 0;
	pthread_mutex_unlock(&b->lock);
	if (!fits)
		return UINT32_MAX;

	struct chunk c = { .id0 = (uint32_t)id0, .n = n, .object = prim->id, .lightset = lightset };
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
	for (uint32_t i = 0; i < sh->nparams; i++) {
		const struct reyes_param_value *pv = &sh->params[i];
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
		cJSON_AddItemToArray(ps, p);
	}
	return ps;
}

static char *metadata(const struct bake *b, const struct bake_stats *st)
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

	cJSON *lights = cJSON_AddArrayToObject(root, "lights");
	for (uint32_t i = 0; i < sc->nlights; i++) {
		const struct reyes_light *l = &sc->lights[i];
		cJSON *j = cJSON_CreateObject();
		cJSON_AddStringToObject(j, "name", l->handle ? l->handle : "");
		cJSON_AddStringToObject(j, "shader", l->shader.name);
		cJSON_AddStringToObject(j, "source", l->shader.prog->source_path);
		cJSON_AddStringToObject(j, "source_hash", l->shader.prog->source_hash);
		cJSON_AddItemToObject(j, "params", params_json(&l->shader));
		cJSON_AddItemToObject(j, "shader_to_world", matrix_json(l->shader.shader_to_world));
		cJSON_AddItemToArray(lights, j);
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
		cJSON_AddStringToObject(j, "source", p->source_path);
		cJSON_AddStringToObject(j, "source_hash", p->source_hash);
		cJSON_AddStringToObject(j, "table", g->table);
		cJSON_AddNumberToObject(j, "first_id", g->first_id);
		cJSON_AddNumberToObject(j, "samples", (double)g->rows);
		cJSON *dyn = cJSON_AddArrayToObject(j, "dynamic_params");
		for (size_t k = 0; k < b->o->ndynamic; k++)
			if (sl_program_find_param(p, b->o->dynamic_surface[k]) >= 0)
				cJSON_AddItemToArray(dyn, cJSON_CreateString(b->o->dynamic_surface[k]));
		cJSON *ch = cJSON_AddArrayToObject(j, "cached");
		for (uint32_t k = 0; k < g->spec->ncached; k++) {
			int32_t reg = g->spec->cached[k];
			cJSON *c = cJSON_CreateObject();
			cJSON_AddStringToObject(c, "name", sl_ir_reg_name(p, reg));
			cJSON_AddStringToObject(c, "type", sl_basetype_name(p->regs[reg].type));
			cJSON_AddNumberToObject(c, "components", g->offset[k + 1] - g->offset[k]);
			cJSON_AddItemToArray(ch, c);
		}
		cJSON_AddItemToArray(groups, j);
	}
	cJSON *fig = cJSON_AddObjectToObject(root, "figures");
	cJSON_AddNumberToObject(fig, "shaded_points", (double)st->shaded_points);
	cJSON_AddNumberToObject(fig, "shading_samples", (double)st->shading_samples);
	cJSON_AddNumberToObject(fig, "subpixel_samples", (double)st->subpixel_samples);
	cJSON_AddNumberToObject(fig, "raw_entries", (double)st->raw_entries);
	cJSON_AddNumberToObject(fig, "indirect_entries", (double)st->indirect_entries);
	cJSON_AddNumberToObject(fig, "render_seconds", st->render_seconds);
	cJSON *chn = cJSON_AddObjectToObject(fig, "channels");
	cJSON_AddNumberToObject(chn, "dynamic", st->channels_dynamic);
	cJSON_AddNumberToObject(chn, "varying", st->channels_varying);
	cJSON_AddNumberToObject(chn, "unique", st->channels_unique);
	char *text = cJSON_PrintUnformatted(root);
	cJSON_Delete(root);
	return text;
}

/* ---- the shot ---- */

static bool write_shot(struct bake *b, const char *path, struct bake_stats *st)
{
	const struct reyes_options *so = &b->scene->opts;
	uint32_t W = so->xres, H = so->yres;
	size_t npix = (size_t)W * H;
	uint64_t nid = b->next_id;

	/* Which ids a pixel uses, and each pixel's entry count. */
	uint8_t *used = rl_xcalloc(nid + 1, 1);
	uint64_t *offsets = rl_xcalloc(npix + 1, sizeof(uint64_t));
	float *alpha = rl_xcalloc(npix + 1, sizeof(float));
	for (size_t k = 0; k < b->buckets.len; k++) {
		const struct bucket *bk = &b->buckets.data[k];
		uint32_t w = bk->x1 - bk->x0;
		for (uint32_t y = bk->y0; y < bk->y1; y++)
			for (uint32_t x = bk->x0; x < bk->x1; x++) {
				size_t lp = (size_t)(y - bk->y0) * w + (x - bk->x0);
				size_t gp = (size_t)y * W + x;
				uint32_t cnt = 0;
				for (uint32_t e = bk->offsets[lp]; e < bk->offsets[lp + 1]; e++) {
					const struct reyes_vis_entry *en = &bk->entries[e];
					if (en->id < nid && en->weight > 0.0f &&
					    isfinite(en->weight)) {
						used[en->id] = 1;
						cnt++;
					}
				}
				offsets[gp + 1] = cnt;
				alpha[gp] = isfinite(bk->alpha[lp]) ? bk->alpha[lp] : 0.0f;
			}
	}
	for (size_t p = 0; p < npix; p++)
		offsets[p + 1] += offsets[p];
	uint64_t nentries = offsets[npix];

	/* New ids: kept samples, shader by shader, in id order within each. */
	uint32_t *newid = rl_xmalloc((nid + 1) * sizeof(uint32_t));
	uint32_t next = 0;
	for (size_t gi = 0; gi < b->groups.len; gi++) {
		struct group *g = b->groups.data[gi];
		g->first_id = next;
		/* chunks in id order (threads finish grids in any order) */
		if (g->chunks.len > 1)
			qsort(g->chunks.data, g->chunks.len, sizeof(struct chunk), cmp_chunk);
		for (size_t c = 0; c < g->chunks.len; c++) {
			const struct chunk *ch = &g->chunks.data[c];
			for (uint32_t i = 0; i < ch->n; i++)
				if (used[ch->id0 + i])
					newid[ch->id0 + i] = next++;
		}
		g->rows = next - g->first_id;
	}

	/* The indirect framebuffer. */
	uint32_t *ent_id = rl_xmalloc((nentries + 1) * sizeof(uint32_t));
	float *ent_w = rl_xmalloc((nentries + 1) * sizeof(float));
	struct reyes_vis_entry *scratch = NULL;
	size_t scap = 0;
	for (size_t k = 0; k < b->buckets.len; k++) {
		const struct bucket *bk = &b->buckets.data[k];
		uint32_t w = bk->x1 - bk->x0;
		for (uint32_t y = bk->y0; y < bk->y1; y++)
			for (uint32_t x = bk->x0; x < bk->x1; x++) {
				size_t lp = (size_t)(y - bk->y0) * w + (x - bk->x0);
				size_t gp = (size_t)y * W + x;
				size_t n = 0, need = bk->offsets[lp + 1] - bk->offsets[lp];
				if (need > scap) {
					scap = need * 2;
					scratch = rl_xrealloc(scratch, scap * sizeof(*scratch));
				}
				for (uint32_t e = bk->offsets[lp]; e < bk->offsets[lp + 1]; e++) {
					struct reyes_vis_entry en = bk->entries[e];
					if (en.id < nid && en.weight > 0.0f && isfinite(en.weight)) {
						en.id = newid[en.id];
						scratch[n++] = en;
					}
				}
				if (n > 1)
					qsort(scratch, n, sizeof(*scratch), cmp_weight_desc);
				for (size_t e = 0; e < n; e++) {
					ent_id[offsets[gp] + e] = scratch[e].id;
					ent_w[offsets[gp] + e] = scratch[e].weight;
				}
			}
	}
	free(scratch);

	/* Sample tables. */
	size_t ntab = b->groups.len + 1;
	struct shot_table *tabs = rl_xcalloc(ntab, sizeof(*tabs));
	bool ok = true;
	for (size_t gi = 0; gi < b->groups.len; gi++) {
		struct group *g = b->groups.data[gi];
		struct shot_table *t = &tabs[gi];
		t->name = g->table;
		t->nrows = g->rows;
		t->nchannels = g->ncols + 2;
		t->channels = rl_xcalloc(t->nchannels, sizeof(*t->channels));
		uint32_t col = 0;
		for (uint32_t k = 0; k < g->spec->ncached; k++) {
			for (uint32_t f = 0; f < g->offset[k + 1] - g->offset[k]; f++, col++) {
				char name[64];
				snprintf(name, sizeof(name), "c%03u.%02u", k, f);
				t->channels[col].name = rl_xstrdup(name);
				t->channels[col].type = SHOT_FLOAT;
				t->channels[col].data = rl_xmalloc((g->rows + 1) * sizeof(float));
			}
		}
		t->channels[col].name = rl_xstrdup("object");
		t->channels[col].type = SHOT_UINT;
		t->channels[col].data = rl_xmalloc((g->rows + 1) * sizeof(uint32_t));
		t->channels[col + 1].name = rl_xstrdup("lightset");
		t->channels[col + 1].type = SHOT_UINT;
		t->channels[col + 1].data = rl_xmalloc((g->rows + 1) * sizeof(uint32_t));
		uint64_t row = 0;
		for (size_t c = 0; c < g->chunks.len; c++) {
			const struct chunk *ch = &g->chunks.data[c];
			for (uint32_t i = 0; i < ch->n; i++) {
				if (!used[ch->id0 + i])
					continue;
				for (uint32_t f = 0; f < g->ncols; f++)
					((float *)t->channels[f].data)[row] =
						ch->values[(size_t)i * g->ncols + f];
				((uint32_t *)t->channels[col].data)[row] = ch->object;
				((uint32_t *)t->channels[col + 1].data)[row] = ch->lightset;
				row++;
			}
		}
	}
	/* Channel figures (lightspeed Fig. 5): cached scalars per shader, those
	 * that vary over the frame, and those among them no other equals. */
	for (size_t gi = 0; gi < b->groups.len; gi++) {
		const struct group *g = b->groups.data[gi];
		const struct shot_table *t = &tabs[gi];
		st->channels_dynamic += g->ncols;
		for (uint32_t c = 0; c < g->ncols; c++) {
			const float *v = t->channels[c].data;
			bool varies = false;
			for (uint64_t r = 1; r < t->nrows && !varies; r++)
				varies = v[r] != v[0];
			if (!varies)
				continue;
			st->channels_varying++;
			bool alias = false;
			for (uint32_t d = 0; d < c && !alias; d++)
				alias = !memcmp(v, t->channels[d].data, t->nrows * sizeof(float));
			st->channels_unique += !alias;
		}
	}
	struct shot_table *pt = &tabs[b->groups.len];
	pt->name = "pixels";
	pt->nrows = npix;
	pt->nchannels = 1;
	pt->channels = rl_xcalloc(1, sizeof(*pt->channels));
	pt->channels[0].name = rl_xstrdup("A");
	pt->channels[0].type = SHOT_FLOAT;
	pt->channels[0].data = alpha;

	struct shot_channel dch[2] = {
		{ .name = "sample", .type = SHOT_UINT, .data = ent_id },
		{ .name = "weight", .type = SHOT_FLOAT, .data = ent_w },
	};
	struct shot_deep deep = {
		.name = "ifb", .width = W, .height = H, .offsets = offsets, .nchannels = 2,
		.channels = dch,
	};

	st->shading_samples = next;
	st->indirect_entries = nentries;
	st->width = W;
	st->height = H;
	char *meta = metadata(b, st);
	struct shot_file f = {
		.metadata = meta, .tables = tabs, .ntables = (uint32_t)ntab, .deeps = &deep,
		.ndeeps = 1,
	};
	double t0 = now();
	char err[1024] = "";
	if (!meta || !shot_write(path, &f, &b->o->write, err, sizeof(err))) {
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
	free(ent_id);
	free(ent_w);
	free(newid);
	free(offsets);
	free(used);
	return ok;
}

bool bake_scene(const struct reyes_scene *scene, const char *path, const struct bake_opts *opts,
		struct bake_stats *stats)
{
	struct bake_stats local = { 0 };
	struct bake_stats *st = stats ? stats : &local;
	memset(st, 0, sizeof(*st));
	struct bake b = { .scene = scene, .o = opts, .diag = opts->diag ? opts->diag : stderr };
	pthread_mutex_init(&b.lock, NULL);
	struct reyes_bake_hooks hooks = {
		.user = &b, .program = hook_program, .grid = hook_grid, .bucket = hook_bucket,
	};
	struct reyes_render_opts ro = {
		.threads = opts->threads, .progress = opts->progress, .diag = b.diag, .bake = &hooks,
	};
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
	if (ok)
		ok = write_shot(&b, path, st);

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
	pthread_mutex_destroy(&b.lock);
	return ok;
}

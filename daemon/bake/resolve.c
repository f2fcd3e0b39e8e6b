/*
 * The CPU resolver: for each surface shader of the shot, its shading samples
 * in batches (one light set per batch) through the dynamic program on the
 * interpreter; then every pixel is the weighted sum of its entries' colours.
 */
#include "resolve.h"

#include "arena.h"
#include "exec.h"
#include "imager.h"
#include "lighthost.h"
#include "mathlib.h"
#include "shotfile.h"
#include "shotmeta.h"
#include "spec.h"
#include "texture.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define BATCH 4096

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

struct light {
	struct sl_program *prog;
	struct sl_exec *x;
	float to_camera[16];
};

struct resolver {
	FILE *diag;
	const char *path;
	struct shot_file *f;
	cJSON *meta;
	float w2c[16];
	struct light *lights;
	uint32_t nlights;
	struct reyes_texsys *tex;
	float *Ci;                 /* 3 per sample id */
	uint64_t nsamples;
	uint64_t shaded;           /* samples shaded */
};

static bool fail(struct resolver *r, const char *fmt, const char *a, const char *b)
{
	fprintf(r->diag, "relight: error: %s: ", r->path);
	fprintf(r->diag, fmt, a ? a : "", b ? b : "");
	fputc('\n', r->diag);
	return false;
}

#define str shot_meta_str
#define matrix shot_meta_matrix

static struct sl_program *load_shader(struct resolver *r, const cJSON *o)
{
	return shot_meta_shader(o, r->path, r->diag);
}

static bool set_params(struct resolver *r, struct sl_exec *x, const cJSON *params)
{
	return shot_meta_set_params(x, params, r->path, r->diag);
}

/* Apply the edits of light @L (named @name) after its baked parameters. */
static bool apply_edits(struct resolver *r, struct light *L, const char *name,
			const struct resolve_opts *o)
{
	for (size_t i = 0; o && i < o->nedits; i++) {
		const struct resolve_edit *e = &o->edits[i];
		if (strcmp(e->light, name))
			continue;
		float v[16];
		uint32_t n;
		char err[512];
		char who[300];
		snprintf(who, sizeof(who), "light '%s'", name);
		int k = sl_program_find_param(L->prog, e->param);
		if (k >= 0 && !L->prog->params[k].output &&
		    L->prog->params[k].type.base == SL_TYPE_STRING &&
		    L->prog->params[k].type.arraylen < 0 && e->nvalues == 0 && e->text) {
			/* a string, a map's name say */
			if (!sl_exec_set_param_string(L->x, e->param, e->text))
				return false;
			continue;
		}
		if (e->nvalues == 0) {
			fprintf(r->diag, "relight: error: %s: parameter '%s' needs numbers, not '%s'\n",
				who, e->param, e->text ? e->text : "");
			return false;
		}
		if (!shot_meta_check_edit(L->prog, who, e->param, e->values, e->nvalues, v, &n, err,
					  sizeof(err))) {
			fprintf(r->diag, "relight: error: %s\n", err);
			return false;
		}
		if (!sl_exec_set_param(L->x, e->param, v, n))
			return false;
	}
	return true;
}

/* Whether edit @e is the imager's: the shot has one and the edit names it. */
static bool imager_edit(struct resolver *r, const struct resolve_edit *e)
{
	return cJSON_GetObjectItemCaseSensitive(r->meta, "imager") &&
	       !strcmp(e->light, SHOT_IMAGER);
}

/* Whether some edit is the imager's. */
static bool edits_imager(struct resolver *r, const struct resolve_opts *o)
{
	for (size_t i = 0; o && i < o->nedits; i++)
		if (imager_edit(r, &o->edits[i]))
			return true;
	return false;
}

static bool load_lights(struct resolver *r, const struct resolve_opts *o)
{
	const cJSON *ls = cJSON_GetObjectItemCaseSensitive(r->meta, "lights");
	int n = cJSON_GetArraySize(ls);
	r->lights = rl_xcalloc((size_t)n + 1, sizeof(*r->lights));
	const cJSON *l;
	cJSON_ArrayForEach(l, ls) {
		struct light *L = &r->lights[r->nlights];
		float s2w[16];
		if (!matrix(l, "shader_to_world", s2w))
			return fail(r, "a light's transform in the metadata is malformed%s%s", NULL,
				    NULL);
		sl_m44_mul(L->to_camera, s2w, r->w2c);
		L->prog = load_shader(r, l);
		if (!L->prog)
			return false;
		r->nlights++;
		L->x = sl_exec_create(L->prog, BATCH);
		if (!L->x || !set_params(r, L->x, cJSON_GetObjectItemCaseSensitive(l, "params")))
			return false;
		const char *name = str(l, "name");
		if (name && !strcmp(name, SHOT_IMAGER) && edits_imager(r, o))
			return fail(r, "a light is named '%s' like the shot's imager: its edits "
				    "are refused%s", SHOT_IMAGER, NULL);
		if (!apply_edits(r, L, name ? name : "", o))
			return false;
	}
	/* every edit names a light of the shot, or its imager */
	for (size_t i = 0; o && i < o->nedits; i++) {
		if (imager_edit(r, &o->edits[i]))
			continue;
		bool found = false;
		cJSON_ArrayForEach(l, ls) {
			const char *name = str(l, "name");
			found = found || (name && !strcmp(name, o->edits[i].light));
		}
		if (!found) {
			fprintf(r->diag, "relight: error: %s: no light named '%s'; the shot's lights "
				"are:", r->path, o->edits[i].light);
			cJSON_ArrayForEach(l, ls)
				fprintf(r->diag, " %s", str(l, "name") ? str(l, "name") : "?");
			fputc('\n', r->diag);
			return false;
		}
	}
	return true;
}

/*
 * The shot's imager over the resolved image @rgba, with its baked
 * parameters and the edits of SHOT_IMAGER, as `relight render` runs it.
 */
static bool run_imager(struct resolver *r, const struct resolve_opts *o, float *rgba, uint32_t w,
		       uint32_t h)
{
	const cJSON *im = cJSON_GetObjectItemCaseSensitive(r->meta, "imager");
	if (!im)
		return true;
	struct sl_program *prog = load_shader(r, im);
	if (!prog)
		return false;
	struct sl_exec *x = sl_exec_create(prog, w);
	bool ok = x && set_params(r, x, cJSON_GetObjectItemCaseSensitive(im, "params"));
	for (size_t i = 0; ok && o && i < o->nedits; i++) {
		const struct resolve_edit *e = &o->edits[i];
		if (!imager_edit(r, e))
			continue;
		float v[16];
		uint32_t n;
		char err[512], who[300];
		snprintf(who, sizeof(who), "imager '%s'", prog->name);
		ok = shot_meta_check_edit(prog, who, e->param, e->values, e->nvalues, v, &n, err,
					  sizeof(err));
		if (!ok)
			fprintf(r->diag, "relight: error: %s\n", err);
		ok = ok && sl_exec_set_param(x, e->param, v, n);
	}
	const cJSON *t = cJSON_GetObjectItemCaseSensitive(im, "time");
	const cJSON *dt = cJSON_GetObjectItemCaseSensitive(im, "dtime");
	struct reyes_imager_frame fr = { cJSON_IsNumber(t) ? (float)t->valuedouble : 0.0f,
					 cJSON_IsNumber(dt) ? (float)dt->valuedouble : 0.0f };
	if (ok && !reyes_imager_run(x, rgba, w, h, &fr, r->tex))
		ok = fail(r, "the imager '%s' failed%s", prog->name, NULL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
	return ok;
}

/* A channel of a surface table by name: stored, constant or an alias. */
static const float *channel(struct resolver *r, const struct shot_table *t, const cJSON *chans,
			    const char *name, float **owned, int depth)
{
	(void)r;
	(void)depth;
	return shot_meta_channel(t, chans, name, owned);
}

/* Rows [lo, hi) of a surface table to shade. */
struct span {
	uint64_t lo, hi;
};

/* Shade the rows @spans of one surface's samples. */
static bool shade_surface(struct resolver *r, const cJSON *s, const struct span *spans,
			  size_t nspans)
{
	const char *table = str(s, "table");
	const struct shot_table *t = table ? shot_find_table(r->f, table) : NULL;
	const cJSON *first = cJSON_GetObjectItemCaseSensitive(s, "first_id");
	if (!t || !cJSON_IsNumber(first) || first->valuedouble < 0 ||
	    first->valuedouble + (double)t->nrows > (double)r->nsamples)
		return fail(r, "the surface table '%s' is missing or does not fit%s", table, NULL);
	for (size_t i = 0; i < nspans; i++)
		if (spans[i].lo > spans[i].hi || spans[i].hi > t->nrows)
			return fail(r, "the tiles of the metadata do not fit table '%s'%s", table,
				    NULL);
	uint64_t id0 = (uint64_t)first->valuedouble;
	struct sl_program *prog = load_shader(r, s);
	if (!prog)
		return false;
	struct sl_spec *spec = shot_meta_specialize(r->meta, s, prog, r->diag);
	bool ok = spec != NULL;
	uint32_t stride = ok ? sl_spec_cache_layout(spec, NULL) : 0;
	/* each float of a sample's record: its channel */
	const float **col = rl_xcalloc(stride + 1, sizeof(float *));
	float **owned = rl_xcalloc(stride + 1, sizeof(float *));
	const uint32_t *lightset = NULL;
	uint32_t *offset = ok ? rl_xcalloc(spec->ncached + 1, sizeof(uint32_t)) : NULL;
	if (ok)
		sl_spec_cache_layout(spec, offset);
	const cJSON *chans = cJSON_GetObjectItemCaseSensitive(s, "channels");
	for (uint32_t k = 0; ok && k < spec->ncached; k++) {
		uint32_t end = k + 1 < spec->ncached ? offset[k + 1] : stride;
		for (uint32_t at = offset[k]; at < end; at++) {
			char name[64];
			snprintf(name, sizeof(name), "c%03u.%02u", k, at - offset[k]);
			col[at] = channel(r, t, chans, name, &owned[at], 0);
			ok = ok && col[at];
		}
	}
	const uint32_t *paramset = NULL;
	for (uint32_t c = 0; c < t->nchannels; c++) {
		if (!strcmp(t->channels[c].name, "lightset") && t->channels[c].type == SHOT_UINT)
			lightset = t->channels[c].data;
		if (!strcmp(t->channels[c].name, "paramset") && t->channels[c].type == SHOT_UINT)
			paramset = t->channels[c].data;
	}
	/* the values objects give the editable parameters */
	const cJSON *psets = cJSON_GetObjectItemCaseSensitive(s, "param_sets");
	int npsets = paramset ? cJSON_GetArraySize(psets) : 0;
	if (ok && paramset && npsets < 1)
		ok = false;
	if (ok && !lightset)
		ok = false;
	free(offset);
	if (!ok && spec)
		fail(r, "the table '%s' does not hold what shader '%s' caches (bake again)", table,
		     prog->name);
	struct sl_exec *x = ok ? sl_exec_create(spec->dynamic, BATCH) : NULL;
	ok = ok && x;
	/*
	 * Derivative stencils: each sample also runs moved one grid step along
	 * u and along v (the cached steps added to the values derivatives go
	 * through), in two more blocks of the batch.
	 */
	bool stencil = ok && spec->needs_stencil;
	uint32_t cap = stencil ? BATCH / 3 : BATCH;
	uint32_t nmoved = 0;
	uint32_t *moved_at = rl_xcalloc(stride + 1, sizeof(uint32_t));
	const float **moved_u = rl_xcalloc(stride + 1, sizeof(float *));
	const float **moved_v = rl_xcalloc(stride + 1, sizeof(float *));
	const float *step_u = NULL, *step_v = NULL;
	float *owned_du = NULL, *owned_dv = NULL;
	RL_VEC(float *) owned_steps = { 0 };
	if (stencil) {
		uint32_t *off = rl_xcalloc(spec->ncached + 1, sizeof(uint32_t));
		sl_spec_cache_layout(spec, off);
		for (uint32_t k = 0; ok && k < spec->ncached; k++) {
			if (!spec->cached_deriv[k])
				continue;
			uint32_t end = k + 1 < spec->ncached ? off[k + 1] : stride;
			for (uint32_t at = off[k]; ok && at < end; at++) {
				char un[64], vn[64];
				snprintf(un, sizeof(un), "u%03u.%02u", k, at - off[k]);
				snprintf(vn, sizeof(vn), "v%03u.%02u", k, at - off[k]);
				float *ou = NULL, *ov = NULL;
				moved_at[nmoved] = at;
				moved_u[nmoved] = channel(r, t, chans, un, &ou, 0);
				moved_v[nmoved] = channel(r, t, chans, vn, &ov, 0);
				if (ou)
					rl_vec_push(owned_steps, ou);
				if (ov)
					rl_vec_push(owned_steps, ov);
				ok = moved_u[nmoved] && moved_v[nmoved];
				nmoved++;
			}
		}
		free(off);
		step_u = ok ? channel(r, t, chans, "du", &owned_du, 0) : NULL;
		step_v = ok ? channel(r, t, chans, "dv", &owned_dv, 0) : NULL;
		if (ok && (!step_u || !step_v))
			ok = false;
		if (!ok)
			fail(r, "the table '%s' lacks the derivative steps shader '%s' needs (bake "
			     "again)%s", table, prog->name);
	}
	float *sdu = rl_xmalloc(((size_t)cap + 1) * sizeof(float));
	float *sdv = rl_xmalloc(((size_t)cap + 1) * sizeof(float));
	float *rec = rl_xmalloc(((size_t)BATCH * stride + 1) * sizeof(float));
	uint32_t *rows = rl_xmalloc(BATCH * sizeof(uint32_t));
	const cJSON *sets = cJSON_GetObjectItemCaseSensitive(r->meta, "lightsets");
	int nsets = cJSON_GetArraySize(sets);
	struct sl_exec *lx[1024];
	float lm[1024][16];
	for (int set = 0; ok && set < nsets; set++) {
		/* the lights of this set */
		int nl = 0;
		const cJSON *li;
		cJSON_ArrayForEach(li, cJSON_GetArrayItem(sets, set)) {
			int k = cJSON_IsNumber(li) ? (int)li->valuedouble : -1;
			if (k < 0 || (uint32_t)k >= r->nlights || nl >= 1024) {
				ok = fail(r, "a light set in the metadata names no light%s%s", NULL,
					  NULL);
				break;
			}
			lx[nl] = r->lights[k].x;
			memcpy(lm[nl], r->lights[k].to_camera, sizeof(lm[nl]));
			nl++;
		}
		for (int ps = 0; ok && ps < (npsets ? npsets : 1); ps++) {
			if (npsets) {
				sl_exec_reset_params(x);
				if (!set_params(r, x, cJSON_GetArrayItem(psets, ps))) {
					ok = false;
					break;
				}
			}
			size_t sp = 0;
			uint64_t row = nspans ? spans[0].lo : 0;
			while (ok) {
				uint32_t n = 0;
				while (sp < nspans && n < cap) {
					if (row >= spans[sp].hi) {
						if (++sp < nspans)
							row = spans[sp].lo;
						continue;
					}
					if (lightset[row] == (uint32_t)set &&
					    (!paramset || paramset[row] == (uint32_t)ps)) {
						for (uint32_t c = 0; c < stride; c++)
							rec[(size_t)n * stride + c] = col[c][row];
						rows[n++] = (uint32_t)row;
					}
					row++;
				}
				if (!n)
					break;
				r->shaded += n;
				struct sl_lighthost lh;
				sl_lighthost_init(&lh, lx, nl);
				lh.host.specular_model = spec->slice.specular_model;
				lh.light_shader_mats = (const float (*)[16])lm;
				reyes_tex_serve(&lh, r->tex);
				static const char *const space_names[] = { "world" };
				lh.space_names = space_names;
				lh.space_mats = (const float (*)[16])&r->w2c;
				lh.nspaces = 1;
				if (stencil) {
					for (uint32_t i = 0; i < n; i++) {
						float *base = rec + (size_t)i * stride;
						float *mu = rec + (size_t)(n + i) * stride;
						float *mv = rec + (size_t)(2 * n + i) * stride;
						memcpy(mu, base, stride * sizeof(float));
						memcpy(mv, base, stride * sizeof(float));
						for (uint32_t j = 0; j < nmoved; j++) {
							mu[moved_at[j]] += moved_u[j][rows[i]];
							mv[moved_at[j]] += moved_v[j][rows[i]];
						}
						sdu[i] = step_u[rows[i]];
						sdv[i] = step_v[rows[i]];
					}
				}
				if (!sl_spec_bind_cache(spec, x, stencil ? 3 * n : n, rec, stride,
							NULL) ||
				    (stencil && !sl_exec_set_stencil(x, n, sdu, sdv)) ||
				    !sl_exec_run(x, &lh.host)) {
					ok = fail(r, "shading the samples of '%s' failed%s", prog->name, NULL);
					break;
				}
				bool vary;
				const float *ci = sl_exec_global(x, SL_GLOBAL_CI, &vary);
				uint32_t st = sl_exec_stride(x);
				for (uint32_t i = 0; i < n; i++)
					for (int c = 0; c < 3; c++) {
						float v = ci ? (vary ? ci[(size_t)c * st + i] : ci[c]) : 0.0f;
						r->Ci[(id0 + rows[i]) * 3 + (uint64_t)c] = isfinite(v) ? v : 0.0f;
					}
			}
		}
	}
	free(rec);
	free(sdu);
	free(sdv);
	free(moved_at);
	free(moved_u);
	free(moved_v);
	free(owned_du);
	free(owned_dv);
	for (size_t i = 0; i < owned_steps.len; i++)
		free(owned_steps.data[i]);
	rl_vec_free(owned_steps);
	free(rows);
	for (uint32_t c = 0; c < stride; c++)
		free(owned[c]);
	free(owned);
	free(col);
	sl_exec_destroy(x);
	sl_spec_destroy(spec);
	sl_program_destroy(prog);
	return ok;
}

/* The rows of surface @si that level @L needs, tile by tile. */
static size_t level_spans(struct resolver *r, int si, int L, struct span **out)
{
	const cJSON *tiles = cJSON_GetObjectItemCaseSensitive(
		cJSON_GetObjectItemCaseSensitive(r->meta, "tiling"), "tiles");
	size_t n = 0, cap = (size_t)cJSON_GetArraySize(tiles) + 1;
	*out = rl_xcalloc(cap, sizeof(**out));
	const cJSON *t;
	cJSON_ArrayForEach(t, tiles) {
		const cJSON *g = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(t, "surfaces"),
						    si);
		const cJSON *first = cJSON_GetObjectItemCaseSensitive(g, "first_row");
		const cJSON *cnt = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(g, "levels"),
						      L);
		if (!cJSON_IsNumber(first) || !cJSON_IsNumber(cnt) || first->valuedouble < 0 ||
		    cnt->valuedouble < 0 || first->valuedouble > 1e15 || cnt->valuedouble > 1e15)
			continue;
		(*out)[n].lo = (uint64_t)first->valuedouble;
		(*out)[n].hi = (*out)[n].lo + (uint64_t)cnt->valuedouble;
		n++;
	}
	return n;
}

bool resolve_cpu(const char *path, const struct resolve_opts *opts, struct resolve_result *out)
{
	memset(out, 0, sizeof(*out));
	struct resolver r = { .diag = opts && opts->diag ? opts->diag : stderr, .path = path };
	double t0 = now();
	char err[1024] = "";
	r.f = shot_read(path, err, sizeof(err));
	if (!r.f) {
		fprintf(r.diag, "relight: error: %s\n", err);
		return false;
	}
	bool ok = true;
	r.meta = cJSON_Parse(r.f->metadata ? r.f->metadata : "");
	const struct shot_deep *ifb = shot_find_deep(r.f, "ifb");
	const struct shot_table *pix = shot_find_table(r.f, "pixels");
	const cJSON *wj = cJSON_GetObjectItemCaseSensitive(r.meta, "width");
	const cJSON *hj = cJSON_GetObjectItemCaseSensitive(r.meta, "height");
	if (!cJSON_IsObject(r.meta) || !ifb || !pix || !cJSON_IsNumber(wj) ||
	    !cJSON_IsNumber(hj) || ifb->width != (uint32_t)wj->valuedouble ||
	    ifb->height != (uint32_t)hj->valuedouble ||
	    pix->nrows != (uint64_t)ifb->width * ifb->height || ifb->nchannels != 2 ||
	    ifb->channels[0].type != SHOT_UINT || !matrix(r.meta, "world_to_camera", r.w2c))
		ok = fail(&r, "not a shot this relight can resolve (missing or "
			  "inconsistent parts)%s%s", NULL, NULL);
	/* sample count: the tables' rows */
	const cJSON *s, *surfaces = ok ? cJSON_GetObjectItemCaseSensitive(r.meta, "surfaces") : NULL;
	cJSON_ArrayForEach(s, surfaces) {
		const struct shot_table *t = str(s, "table") ? shot_find_table(r.f, str(s, "table"))
							     : NULL;
		r.nsamples += t ? t->nrows : 0;
	}
	if (ok) {
		const char *tp = opts && opts->texture_path ? opts->texture_path : ".";
		float c2w[16];
		sl_m44_inverse(c2w, r.w2c);
		r.tex = reyes_texsys_create(tp, c2w, r.diag);
		r.Ci = rl_xcalloc(r.nsamples * 3 + 1, sizeof(float));
		ok = load_lights(&r, opts);
	}
	out->load_seconds = now() - t0;
	double t1 = now();
	int L = opts && opts->level >= 0 && opts->level < RESOLVE_FINAL ? opts->level
									  : RESOLVE_FINAL;
	const struct shot_table *lt = NULL;
	if (ok && L < RESOLVE_FINAL) {
		static const char *const name[RESOLVE_FINAL] = { "level0", "level1", "level2" };
		static const uint32_t block[RESOLVE_FINAL] = { 4, 2, 1 };
		lt = shot_find_table(r.f, name[L]);
		if (!lt || lt->nchannels != 2 || lt->channels[0].type != SHOT_UINT ||
		    lt->nrows != (uint64_t)((ifb->width + block[L] - 1) / block[L]) *
				 ((ifb->height + block[L] - 1) / block[L]))
			ok = fail(&r, "the refinement level table '%s' is missing or malformed%s",
				  name[L], NULL);
	}
	int si = 0;
	if (ok)
		cJSON_ArrayForEach(s, surfaces) {
			struct span *spans;
			size_t n = level_spans(&r, si++, L, &spans);
			if (ok && !shade_surface(&r, s, spans, n))
				ok = false;
			free(spans);
		}
	out->shade_seconds = now() - t1;

	if (ok) {
		double t2 = now();
		uint32_t W = ifb->width, H = ifb->height;
		out->width = W;
		out->height = H;
		out->rgba = rl_xcalloc((size_t)W * H * 4, sizeof(float));
		const uint32_t *sid = ifb->channels[0].data;
		const float *wt = ifb->channels[1].data;
		const float *alpha = pix->channels[0].data;
		if (lt) {
			/* channels come in name order: sample, weight */
			uint32_t B = L == 0 ? 4 : L == 1 ? 2 : 1, nx = (W + B - 1) / B;
			const uint32_t *bid = lt->channels[0].data;
			const float *bw = lt->channels[1].data;
			/* alpha: the block's mean */
			float *ba = rl_xcalloc(lt->nrows + 1, sizeof(float));
			for (uint32_t y = 0; y < H; y++)
				for (uint32_t x = 0; x < W; x++)
					ba[(size_t)(y / B) * nx + x / B] +=
						isfinite(alpha[(size_t)y * W + x]) ? alpha[(size_t)y * W + x]
										    : 0.0f;
			for (uint32_t y = 0; y < H; y++)
				for (uint32_t x = 0; x < W; x++) {
					size_t b = (size_t)(y / B) * nx + x / B, p = (size_t)y * W + x;
					uint32_t bx0 = x / B * B, by0 = y / B * B;
					uint32_t bwid = bx0 + B < W ? B : W - bx0;
					uint32_t bhei = by0 + B < H ? B : H - by0;
					float w = isfinite(bw[b]) ? bw[b] : 0.0f;
					for (int k = 0; k < 3; k++) {
						float v = bid[b] < r.nsamples
							  ? w * r.Ci[(size_t)bid[b] * 3 + k] : 0.0f;
						out->rgba[p * 4 + k] = isfinite(v) ? v : 0.0f;
					}
					out->rgba[p * 4 + 3] = ba[b] / (float)(bwid * bhei);
				}
			free(ba);
			out->entries = lt->nrows;
		}
		for (size_t p = 0; !lt && p < (size_t)W * H; p++) {
			double c[3] = { 0, 0, 0 };
			for (uint64_t e = ifb->offsets[p]; e < ifb->offsets[p + 1]; e++) {
				if (sid[e] >= r.nsamples)
					continue;
				for (int k = 0; k < 3; k++)
					c[k] += (double)wt[e] * r.Ci[(size_t)sid[e] * 3 + k];
			}
			for (int k = 0; k < 3; k++)
				out->rgba[p * 4 + k] = isfinite(c[k]) ? (float)c[k] : 0.0f;
			out->rgba[p * 4 + 3] = isfinite(alpha[p]) ? alpha[p] : 0.0f;
		}
		out->samples = r.shaded;
		if (!lt)
			out->entries = ifb->offsets[(size_t)W * H];
		ok = run_imager(&r, opts, out->rgba, W, H);
		if (!ok) {
			free(out->rgba);
			out->rgba = NULL;
		}
		out->resolve_seconds = now() - t2;
	}
	for (uint32_t i = 0; i < r.nlights; i++) {
		sl_exec_destroy(r.lights[i].x);
		sl_program_destroy(r.lights[i].prog);
	}
	free(r.lights);
	free(r.Ci);
	reyes_texsys_destroy(r.tex);
	cJSON_Delete(r.meta);
	shot_free(r.f);
	return ok;
}

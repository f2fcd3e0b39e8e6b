/*
 * Reading a shot's metadata: see shotmeta.h.
 */
#include "shotmeta.h"

#include "arena.h"
#include "config.h"
#include "exec.h"
#include "sl.h"
#include "spec.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define MAX_MAGNITUDE 1e18f
#define PI_F 3.14159265358979f

const char *shot_meta_str(const cJSON *o, const char *key)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	return cJSON_IsString(v) ? v->valuestring : NULL;
}

bool shot_meta_matrix(const cJSON *o, const char *key, float m[16])
{
	const cJSON *a = cJSON_GetObjectItemCaseSensitive(o, key);
	if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != 16)
		return false;
	int i = 0;
	const cJSON *v;
	cJSON_ArrayForEach(v, a) {
		if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
			return false;
		m[i++] = (float)v->valuedouble;
	}
	return true;
}

/* A place a shader may be. */
struct candidate {
	char path[4096];
};

static void add_candidate(struct candidate *c, size_t *n, size_t cap, const char *dir,
			  const char *file)
{
	if (*n == cap || !file || !*file)
		return;
	int k = dir ? snprintf(c[*n].path, sizeof(c[*n].path), "%s%s%s", dir,
			       dir[0] && dir[strlen(dir) - 1] != '/' ? "/" : "", file)
		    : snprintf(c[*n].path, sizeof(c[*n].path), "%s", file);
	if (k < 0 || (size_t)k >= sizeof(c[*n].path))
		return;
	for (size_t i = 0; i < *n; i++)
		if (!strcmp(c[i].path, c[*n].path))
			return;
	(*n)++;
}

/*
 * Where the shader of entry @o may be, in order: its path relative to the
 * shot file ("source_relative": the project moved as a whole), the
 * absolute path of the bake ("source"), then its file name in the folders
 * of $RELIGHT_SHADER_PATH, then $RMAN_SHADERPATH, the shot's own folder and
 * the standard library.
 */
static size_t candidates(const cJSON *o, const char *shot, struct candidate *c, size_t cap)
{
	size_t n = 0;
	const char *src = shot_meta_str(o, "source"), *rel = shot_meta_str(o, "source_relative");
	char shot_dir[4096];
	const char *slash = shot ? strrchr(shot, '/') : NULL;
	snprintf(shot_dir, sizeof(shot_dir), "%.*s", slash ? (int)(slash - shot) + 1 : 1,
		 slash ? shot : ".");
	if (rel && rel[0] != '/')
		add_candidate(c, &n, cap, shot_dir, rel);
	add_candidate(c, &n, cap, NULL, src);
	const char *base = src ? strrchr(src, '/') : NULL;
	base = base ? base + 1 : src;
	const char *const vars[] = { "RELIGHT_SHADER_PATH", "RMAN_SHADERPATH" };
	for (size_t v = 0; v < sizeof(vars) / sizeof(vars[0]); v++) {
		const char *env = getenv(vars[v]);
		if (!env || !*env)
			continue;
		char *dirs = strdup(env), *save = NULL;
		for (char *d = dirs ? strtok_r(dirs, ":", &save) : NULL; d;
		     d = strtok_r(NULL, ":", &save))
			add_candidate(c, &n, cap, d, base);
		free(dirs);
	}
	add_candidate(c, &n, cap, shot_dir, base);
	add_candidate(c, &n, cap, RELIGHT_SOURCE_SHADER_DIR, base);
	add_candidate(c, &n, cap, RELIGHT_SHADER_DIR, base);
	return n;
}

/*
 * Whether @p is the program entry @o was baked with: the same program hash
 * (the tokens compiled: comments and layout do not count), or for a shot
 * of an earlier relight, which recorded none, the same source text.
 */
static bool same_program(const cJSON *o, const struct sl_program *p)
{
	const char *ph = shot_meta_str(o, "program_hash");
	if (ph)
		return !strcmp(sl_program_hash(p), ph);
	const char *sh = shot_meta_str(o, "source_hash");
	return sh && !strcmp(sl_program_source_hash(p), sh);
}

static struct sl_program *program_of(const cJSON *o, const char *shot, FILE *diag);

struct sl_program *shot_meta_shader(const cJSON *o, const char *shot, FILE *diag)
{
	struct sl_program *p = program_of(o, shot, diag);
	const cJSON *atm = cJSON_GetObjectItemCaseSensitive(o, "atmosphere");
	if (!p || !atm)
		return p;
	/* a surface and its atmosphere, joined as the bake joined them */
	struct sl_program *a = cJSON_IsObject(atm) ? program_of(atm, shot, diag) : NULL;
	struct sl_program *j = a ? sl_program_compose(p, a) : NULL;
	if (!j) {
		if (a || !cJSON_IsObject(atm))
			fprintf(diag ? diag : stderr, "relight: error: %s: the atmosphere of "
				"surface '%s' is not a volume shader\n", shot, sl_program_name(p));
		sl_program_destroy(a);
		sl_program_destroy(p);
		return NULL;
	}
	sl_program_own_parts(j);
	return j;
}

static struct sl_program *program_of(const cJSON *o, const char *shot, FILE *diag)
{
	const char *src = shot_meta_str(o, "source");
	if (!diag)
		diag = stderr;
	if (!src || (!shot_meta_str(o, "source_hash") && !shot_meta_str(o, "program_hash"))) {
		fprintf(diag, "relight: error: %s: a shader entry of the metadata has no source\n",
			shot);
		return NULL;
	}
	struct candidate c[16];
	size_t n = candidates(o, shot, c, 16);
	const char *changed = NULL, *broken = NULL;
	for (size_t i = 0; i < n; i++) {
		if (access(c[i].path, R_OK) != 0)
			continue;
		struct sl_options so = { .diag = diag };
		struct sl_program *p = sl_compile_file(c[i].path, &so);
		if (p && same_program(o, p))
			return p;
		if (!p && !broken)
			broken = c[i].path;
		if (p && !changed)
			changed = c[i].path;
		sl_program_destroy(p);
	}
	if (changed)
		fprintf(diag, "relight: error: %s: the shader '%s' changed since the bake; bake "
			"the scene again\n", shot, changed);
	else if (broken)
		fprintf(diag, "relight: error: %s: cannot compile the shader '%s' the shot was "
			"baked with\n", shot, broken);
	else
		fprintf(diag, "relight: error: %s: cannot find the shader '%s' the shot was baked "
			"with (not beside the shot as '%s', nor along $RELIGHT_SHADER_PATH, $RMAN_SHADERPATH or "
			"the standard library)\n", shot, src,
			shot_meta_str(o, "source_relative") ? shot_meta_str(o, "source_relative")
							     : src);
	return NULL;
}

struct sl_spec *shot_meta_specialize(const cJSON *meta, const cJSON *surface,
				     const struct sl_program *prog, FILE *diag)
{
	const char *names[256];
	size_t nd = 0;
	const cJSON *d;
	cJSON_ArrayForEach(d, cJSON_GetObjectItemCaseSensitive(surface, "dynamic_params"))
		if (cJSON_IsString(d) && nd < 256)
			names[nd++] = d->valuestring;
	const cJSON *ld = cJSON_GetObjectItemCaseSensitive(meta, "light_derivatives");
	unsigned flags = SL_SPEC_CACHE_PARAMS | (cJSON_IsTrue(ld) ? SL_SPEC_LIGHT_DERIVATIVES : 0);
	enum sl_specular_model model;
	if (!shot_meta_specular_model(meta, &model)) {
		fprintf(diag ? diag : stderr, "relight: error: the shot's \"specular_model\" is "
			"neither \"prman\" nor \"rispec\"\n");
		return NULL;
	}
	struct sl_spec *sp = sl_specialize_ex(prog, names, nd, flags, diag);
	if (sp)
		sp->slice.specular_model = model;
	return sp;
}

bool shot_meta_specular_model(const cJSON *meta, enum sl_specular_model *m)
{
	const cJSON *j = cJSON_GetObjectItemCaseSensitive(meta, "specular_model");
	if (!j) {
		/* shots from before the key were baked with the RiSpec formula */
		*m = SL_SPECULAR_RISPEC;
		return true;
	}
	return sl_specular_model_parse(cJSON_IsString(j) ? j->valuestring : NULL, m);
}

bool shot_meta_set_params(struct sl_exec *x, const cJSON *params, const char *shot, FILE *diag)
{
	const cJSON *p;
	cJSON_ArrayForEach(p, params) {
		const char *name = shot_meta_str(p, "name"), *type = shot_meta_str(p, "type");
		const cJSON *v = cJSON_GetObjectItemCaseSensitive(p, "value");
		if (!name || !type || !cJSON_IsArray(v)) {
			fprintf(diag ? diag : stderr, "relight: error: %s: a shader parameter in the "
				"metadata is malformed\n", shot);
			return false;
		}
		int n = cJSON_GetArraySize(v);
		if (!strcmp(type, "string")) {
			const cJSON *s = cJSON_GetArrayItem(v, 0);
			if (cJSON_IsString(s))
				sl_exec_set_param_string(x, name, s->valuestring);
			continue;
		}
		if (n <= 0 || n > 4096)
			continue;
		float *vals = rl_xmalloc((size_t)n * sizeof(float));
		int k = 0;
		const cJSON *e;
		cJSON_ArrayForEach(e, v)
			vals[k++] = cJSON_IsNumber(e) && isfinite(e->valuedouble) ? (float)e->valuedouble
										   : 0.0f;
		sl_exec_set_param(x, name, vals, (uint32_t)n);
		free(vals);
	}
	return true;
}

const float *shot_meta_channel(const struct shot_table *t, const cJSON *chans, const char *name,
			       float **owned)
{
	for (int depth = 0; depth < 8; depth++) {
		for (uint32_t c = 0; c < t->nchannels; c++)
			if (!strcmp(t->channels[c].name, name))
				return t->channels[c].type == SHOT_UINT ? NULL : t->channels[c].data;
		const cJSON *k = cJSON_GetObjectItemCaseSensitive(
			cJSON_GetObjectItemCaseSensitive(chans, "constants"), name);
		if (cJSON_IsNumber(k) && isfinite(k->valuedouble)) {
			float *v = rl_xmalloc((t->nrows + 1) * sizeof(float));
			for (uint64_t i = 0; i < t->nrows; i++)
				v[i] = (float)k->valuedouble;
			*owned = v;
			return v;
		}
		const cJSON *a = cJSON_GetObjectItemCaseSensitive(
			cJSON_GetObjectItemCaseSensitive(chans, "aliases"), name);
		if (!cJSON_IsString(a) || !strcmp(a->valuestring, name))
			return NULL;
		name = a->valuestring;
	}
	return NULL;
}

void shot_meta_param_range(const char *name, float *lo, float *hi)
{
	*lo = -MAX_MAGNITUDE;
	*hi = MAX_MAGNITUDE;
	if (strstr(name, "angle")) {
		*lo = 0.0f;
		*hi = PI_F;
	} else if (!strcmp(name, "samples")) {
		*lo = 1.0f;
		*hi = 1024.0f;
	}
}

bool shot_meta_check_edit(const struct sl_program *light, const char *who, const char *param,
			  const float *values, uint32_t n, float out[16], uint32_t *nout,
			  char *err, size_t errlen)
{
	int k = sl_program_find_param(light, param);
	if (k < 0 || light->params[k].output) {
		snprintf(err, errlen, "%s (shader '%s') has no parameter '%s'", who,
			 light->name, param);
		return false;
	}
	const struct sl_type *ty = &light->params[k].type;
	uint32_t nc = (uint32_t)sl_type_ncomp(ty->base);
	if (ty->base == SL_TYPE_STRING || ty->arraylen >= 0 || nc == 0) {
		snprintf(err, errlen, "%s: parameter '%s' is a %s%s; only float, colour, "
			 "point, vector, normal and matrix parameters take numbers (a string "
			 "takes its text, an array nothing)", who, param,
			 sl_basetype_name(ty->base), ty->arraylen >= 0 ? " array" : "");
		return false;
	}
	if (n == 0 || n > 16) {
		snprintf(err, errlen, "%s: parameter '%s' takes %u value%s, not %u", who,
			 param, nc, nc == 1 ? "" : "s", n);
		return false;
	}
	uint32_t m = n;
	if (n == 1 && ty->base == SL_TYPE_COLOR) {
		out[0] = out[1] = out[2] = values[0];
		m = 3;
	} else {
		memcpy(out, values, n * sizeof(float));
	}
	if (m != nc) {
		snprintf(err, errlen, "%s: parameter '%s' is a %s and takes %u value%s, not "
			 "%u", who, param, sl_basetype_name(ty->base), nc, nc == 1 ? "" : "s", n);
		return false;
	}
	float lo, hi;
	shot_meta_param_range(param, &lo, &hi);
	for (uint32_t c = 0; c < m; c++) {
		if (!isfinite(out[c])) {
			snprintf(err, errlen, "%s: parameter '%s' needs finite values", who,
				 param);
			return false;
		}
		if (!(out[c] >= lo && out[c] <= hi)) {
			snprintf(err, errlen, "%s: parameter '%s' is %g, outside [%g, %g]",
				 who, param, (double)out[c], (double)lo, (double)hi);
			return false;
		}
	}
	*nout = m;
	return true;
}

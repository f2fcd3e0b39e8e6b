/*
 * Reading a shot's metadata: see shotmeta.h.
 */
#include "shotmeta.h"

#include "arena.h"
#include "exec.h"
#include "sl.h"
#include "spec.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

struct sl_program *shot_meta_shader(const cJSON *o, const char *shot, FILE *diag)
{
	const char *src = shot_meta_str(o, "source"), *hash = shot_meta_str(o, "source_hash");
	if (!diag)
		diag = stderr;
	if (!src || !hash) {
		fprintf(diag, "relight: error: %s: a shader entry of the metadata has no source\n",
			shot);
		return NULL;
	}
	struct sl_options so = { .diag = diag };
	struct sl_program *p = sl_compile_file(src, &so);
	if (!p) {
		fprintf(diag, "relight: error: %s: cannot compile the shader '%s' the shot was "
			"baked with\n", shot, src);
		return NULL;
	}
	if (strcmp(sl_program_source_hash(p), hash)) {
		fprintf(diag, "relight: error: %s: the shader '%s' changed since the bake; bake "
			"the scene again\n", shot, src);
		sl_program_destroy(p);
		return NULL;
	}
	return p;
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
	return sl_specialize_ex(prog, names, nd, flags, diag);
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
			 "point, vector, normal and matrix parameters can be edited", who, param,
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

/*
 * The imager pass: three kernels over the pixels of a resolved image.
 *  - pack: each pixel's record of the imager's inputs (Ci, Oi, alpha, P,
 *    ncomps, time, dtime, those the shader reads) in the generated
 *    kernel's layout;
 *  - the imager, generated from its IR with every parameter a uniform;
 *  - unpack: (Ci, alpha) back into an RGBA image, non-finite values as 0.
 * The pack and unpack kernels are written here from the generated layout,
 * so the imager kernel is the generator's, unchanged, as surfaces' are.
 */
#include "imagerpass.h"

#include "arena.h"
#include "exec.h"
#include "glsl.h"
#include "shotmeta.h"
#include "strbuf.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct gpu_imager {
	struct gpu_ctx *ctx;
	struct sl_program *prog;
	struct sl_exec *x;         /* one point: the parameters' values, defaults and edits */
	enum sl_global input_global[SL_GLSL_IMAGER_INPUTS];  /* the kernel's inputs */
	uint32_t ninputs;
	struct sl_glsl_layout lay;
	struct gpu_program *kernel, *pack, *unpack;
	struct gpu_buffer *in, *out;
	uint32_t w, h;
	float time, dtime;
};

const char *gpu_imager_shader(const struct gpu_imager *im)
{
	return im->prog->name;
}

size_t gpu_imager_bytes(const struct gpu_imager *im)
{
	size_t n = (size_t)im->w * im->h;
	return n * (im->lay.in_stride + im->lay.out_stride) * sizeof(float);
}

/* A string's token id in the kernel's table (past it: a string never compared to). */
static float string_id(const struct sl_glsl_layout *lay, const char *s)
{
	for (uint32_t i = 0; i < lay->nstrings; i++)
		if (!strcmp(lay->strings[i], s))
			return (float)i;
	return (float)lay->nstrings + 7.0f;
}

/*
 * Evaluate the parameters on the interpreter (a default may depend on
 * another parameter) and hand them to the kernel's uniforms.
 */
static bool set_uniforms(struct gpu_imager *im)
{
	if (!sl_exec_set_grid(im->x, 1, 1) || !sl_exec_run(im->x, NULL))
		return false;
	const struct sl_program *prog = im->prog;
	for (uint32_t k = 0; k < prog->nparams; k++) {
		int32_t r = prog->params[k].reg;
		const struct sl_reg *g = &prog->regs[r];
		char name[320];
		sl_glsl_param_uniform(name, sizeof(name), -1, prog->params[k].name);
		if (g->type == SL_TYPE_STRING) {
			const char **s = sl_exec_reg_strings(im->x, r);
			float id = string_id(&im->lay, s && s[0] ? s[0] : "");
			gpu_uniform_float(im->kernel, name, &id, 1);
			continue;
		}
		uint32_t ne = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
		uint32_t tot = ne * (uint32_t)sl_reg_ncomp(g);
		uint32_t stride = g->varying ? sl_exec_stride(im->x) : 1;
		const float *d = sl_exec_reg(im->x, r);
		float *v = rl_xcalloc(tot + 1, sizeof(float));
		for (uint32_t q = 0; d && q < tot; q++)
			v[q] = isfinite(d[(size_t)q * stride]) ? d[(size_t)q * stride] : 0.0f;
		if (tot == 16 && ne == 1)
			gpu_uniform_mat4(im->kernel, name, v);
		else
			gpu_uniform_float(im->kernel, name, v, (int)tot);
		free(v);
	}
	return true;
}

/*
 * The pack kernel: pixel i of the image into record i of the inputs. On
 * llvmpipe a texture buffer reads 2.5x faster than an SSBO and whole vec4
 * stores beat scattered floats: pixels come in as RGBA32F texels and each
 * record, assembled in registers, goes out as in_stride / 4 vec4s.
 */
static char *pack_source(const struct gpu_imager *im)
{
	uint32_t n4 = im->lay.in_stride / 4;
	struct rl_strbuf b = { 0 };
	rl_strbuf_printf(&b,
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"layout(binding = 0) uniform samplerBuffer u_img;\n"
		"layout(std430, binding = 1) writeonly buffer Rec { vec4 rec[]; };\n"
		"uniform int u_count;\n"
		"uniform int u_width;\n"
		"uniform float u_time;\n"
		"uniform float u_dtime;\n"
		"void main() {\n"
		"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
		"	if (i >= uint(u_count)) return;\n"
		"	vec4 c = texelFetch(u_img, int(i));\n"
		"	uint x = i %% uint(u_width), y = i / uint(u_width);\n"
		"	vec4 r[%u];\n"
		"	for (int k = 0; k < %u; k++) r[k] = vec4(0.0);\n", n4 ? n4 : 1, n4 ? n4 : 1);
	for (uint32_t k = 0; k < im->ninputs; k++) {
		uint32_t o = im->lay.in_offset[k];
		const char *v[3] = { NULL, NULL, NULL };
		switch (im->input_global[k]) {
		case SL_GLOBAL_CI: v[0] = "c.r"; v[1] = "c.g"; v[2] = "c.b"; break;
		case SL_GLOBAL_OI: v[0] = v[1] = v[2] = "c.a"; break;
		case SL_GLOBAL_ALPHA: v[0] = "c.a"; break;
		case SL_GLOBAL_P:
			v[0] = "float(x) + 0.5"; v[1] = "float(y) + 0.5"; v[2] = "0.0"; break;
		case SL_GLOBAL_NCOMPS: v[0] = "3.0"; break;
		case SL_GLOBAL_TIME: v[0] = "u_time"; break;
		default: v[0] = "u_dtime"; break;
		}
		for (uint32_t c = 0; c < 3 && v[c]; c++)
			rl_strbuf_printf(&b, "\tr[%u][%u] = %s;\n", (o + c) / 4, (o + c) % 4, v[c]);
	}
	rl_strbuf_printf(&b, "\tfor (uint k = 0u; k < %uu; k++) rec[i * %uu + k] = r[k];\n}\n", n4,
			 n4);
	char *src = rl_xstrdup(rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return src;
}

/* The unpack kernel: (Ci, alpha) of record i into pixel i, as the CPU writes it. */
static char *unpack_source(const struct gpu_imager *im)
{
	struct rl_strbuf b = { 0 };
	rl_strbuf_printf(&b,
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"layout(binding = 0) uniform samplerBuffer u_out;\n"
		"layout(std430, binding = 1) writeonly buffer Img { vec4 img[]; };\n"
		"uniform int u_count;\n"
		"float finite(float v) { return isnan(v) || isinf(v) ? 0.0 : v; }\n"
		"void main() {\n"
		"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
		"	if (i >= uint(u_count)) return;\n"
		"	int r = int(i) * %u;\n"
		"	img[i] = vec4(finite(texelFetch(u_out, r + %u).x), finite(texelFetch(u_out, r + %u).x),\n"
		"		      finite(texelFetch(u_out, r + %u).x), finite(texelFetch(u_out, r + %u).x));\n"
		"}\n", im->lay.out_stride, im->lay.out_offset[0], im->lay.out_offset[0] + 1,
		im->lay.out_offset[0] + 2, im->lay.out_offset[1]);
	char *src = rl_xstrdup(rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return src;
}

static bool compile(struct gpu_imager *im, const char *shot, FILE *diag)
{
	const struct sl_program *prog = im->prog;
	char *src = sl_glsl_emit_imager(prog, im->input_global, &im->ninputs, &im->lay, diag);
	if (!src) {
		fprintf(diag, "relight: error: %s: the imager '%s' cannot run on the GPU\n", shot,
			prog->name);
		return false;
	}
	im->kernel = gpu_program(im->ctx, src, diag);
	free(src);
	char *ps = pack_source(im), *us = unpack_source(im);
	im->pack = gpu_program(im->ctx, ps, diag);
	im->unpack = gpu_program(im->ctx, us, diag);
	free(ps);
	free(us);
	if (!im->kernel || !im->pack || !im->unpack) {
		fprintf(diag, "relight: error: %s: the imager '%s' does not compile on the GPU\n",
			shot, prog->name);
		return false;
	}
	return true;
}

struct gpu_imager *gpu_imager_create(struct gpu_ctx *ctx, const cJSON *j, const char *shot,
				     uint32_t w, uint32_t h, FILE *diag)
{
	struct gpu_imager *im = rl_xcalloc(1, sizeof(*im));
	im->ctx = ctx;
	im->w = w;
	im->h = h;
	const cJSON *t = cJSON_GetObjectItemCaseSensitive(j, "time");
	const cJSON *dt = cJSON_GetObjectItemCaseSensitive(j, "dtime");
	im->time = cJSON_IsNumber(t) ? (float)t->valuedouble : 0.0f;
	im->dtime = cJSON_IsNumber(dt) ? (float)dt->valuedouble : 0.0f;
	im->prog = shot_meta_shader(j, shot, diag);
	bool ok = im->prog != NULL;
	if (ok && sl_program_kind(im->prog) != SL_SHADER_IMAGER) {
		fprintf(diag, "relight: error: %s: the imager '%s' is a %s shader\n", shot,
			im->prog->name, sl_shader_kind_name(sl_program_kind(im->prog)));
		ok = false;
	}
	im->x = ok ? sl_exec_create(im->prog, 1) : NULL;
	ok = ok && im->x &&
	     shot_meta_set_params(im->x, cJSON_GetObjectItemCaseSensitive(j, "params"), shot, diag);
	ok = ok && compile(im, shot, diag);
	size_t n = (size_t)w * h;
	ok = ok && (im->in = gpu_buffer_create(ctx, n * im->lay.in_stride * sizeof(float) + 16,
					       NULL)) &&
	     (im->out = gpu_buffer_create(ctx, n * im->lay.out_stride * sizeof(float) + 16, NULL));
	if (ok && !set_uniforms(im)) {
		fprintf(diag, "relight: error: %s: the imager's parameter defaults failed\n", shot);
		ok = false;
	}
	if (!ok) {
		gpu_imager_destroy(im);
		return NULL;
	}
	return im;
}

void gpu_imager_destroy(struct gpu_imager *im)
{
	if (!im)
		return;
	gpu_buffer_destroy(im->in);
	gpu_buffer_destroy(im->out);
	sl_glsl_layout_finish(&im->lay);
	sl_exec_destroy(im->x);
	sl_program_destroy(im->prog);
	free(im);
}

bool gpu_imager_set(struct gpu_imager *im, const char *param, const float *values, uint32_t n,
		    char *err, size_t errlen)
{
	float v[16];
	uint32_t nv;
	char who[300];
	snprintf(who, sizeof(who), "imager '%s'", im->prog->name);
	if (!param || !values ||
	    !shot_meta_check_edit(im->prog, who, param, values, n, v, &nv, err, errlen))
		return false;
	if (!sl_exec_set_param(im->x, param, v, nv) || !set_uniforms(im)) {
		snprintf(err, errlen, "imager '%s': parameter '%s' cannot be set", im->prog->name,
			 param);
		return false;
	}
	return true;
}

bool gpu_imager_get(const struct gpu_imager *im, const char *param, float out[16], uint32_t *n)
{
	int k = param ? sl_program_find_param(im->prog, param) : -1;
	if (k < 0)
		return false;
	int32_t r = im->prog->params[k].reg;
	const struct sl_reg *g = &im->prog->regs[r];
	uint32_t tot = (uint32_t)sl_reg_ncomp(g) * (g->arraylen > 0 ? (uint32_t)g->arraylen : 1);
	const float *d = sl_exec_reg(im->x, r);
	if (g->type == SL_TYPE_STRING || !d || tot > 16 || tot == 0)
		return false;
	uint32_t stride = g->varying ? sl_exec_stride(im->x) : 1;
	for (uint32_t q = 0; q < tot; q++)
		out[q] = d[(size_t)q * stride];
	*n = tot;
	return true;
}

bool gpu_imager_param(const struct gpu_imager *im, uint32_t k, const char **name, int *type,
		      uint32_t *n, float value[16])
{
	uint32_t seen = 0;
	for (uint32_t i = 0; i < im->prog->nparams; i++) {
		const struct sl_reg *g = &im->prog->regs[im->prog->params[i].reg];
		if (g->type == SL_TYPE_STRING || g->arraylen > 0 || seen++ != k)
			continue;
		*name = im->prog->params[i].name;
		*type = g->type;
		return gpu_imager_get(im, *name, value, n);
	}
	return false;
}

bool gpu_imager_run(struct gpu_imager *im, struct gpu_buffer *src, struct gpu_buffer *dst)
{
	uint32_t n = im->w * im->h;
	gpu_uniform_int(im->pack, "u_width", (int)im->w);
	gpu_uniform_float(im->pack, "u_time", &im->time, 1);
	gpu_uniform_float(im->pack, "u_dtime", &im->dtime, 1);
	struct gpu_binding pb[2] = { { 0, false, src, true }, { 1, true, im->in } };
	struct gpu_binding kb[2] = { { 0, false, im->in, true }, { 1, true, im->out } };
	struct gpu_binding ub[2] = { { 0, false, im->out }, { 1, true, dst } };
	return gpu_dispatch(im->ctx, im->pack, pb, 2, n) &&
	       gpu_dispatch(im->ctx, im->kernel, kb, 2, n) &&
	       gpu_dispatch(im->ctx, im->unpack, ub, 2, n);
}

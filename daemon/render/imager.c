/*
 * Imager shaders on the CPU: the interpreter over the final pixels, a row
 * of the image per grid.
 */
#include "imager.h"

#include "exec.h"
#include "lighthost.h"
#include "texture.h"

#include <math.h>
#include <string.h>

static void fill(float *d, bool varying, uint32_t n, float v)
{
	if (!d)
		return;
	for (uint32_t i = 0; i < (varying ? n : 1); i++)
		d[i] = v;
}

/* The pixels of row @y as the imager's globals (planar, stride @st). */
static void load_row(struct sl_exec *x, const float *row, uint32_t w, uint32_t y,
		     const struct reyes_imager_frame *fr)
{
	uint32_t st = sl_exec_stride(x);
	bool vary;
	float *ci = sl_exec_global(x, SL_GLOBAL_CI, &vary);
	for (uint32_t i = 0; ci && i < w; i++)
		for (int c = 0; c < 3; c++)
			ci[(size_t)c * st + i] = row[i * 4 + (uint32_t)c];
	float *oi = sl_exec_global(x, SL_GLOBAL_OI, &vary);
	for (uint32_t i = 0; oi && i < w; i++)
		for (int c = 0; c < 3; c++)
			oi[(size_t)c * st + i] = row[i * 4 + 3];
	float *al = sl_exec_global(x, SL_GLOBAL_ALPHA, &vary);
	for (uint32_t i = 0; al && i < w; i++)
		al[i] = row[i * 4 + 3];
	float *p = sl_exec_global(x, SL_GLOBAL_P, &vary);
	for (uint32_t i = 0; p && i < w; i++) {
		p[i] = (float)i + 0.5f;
		p[st + i] = (float)y + 0.5f;
		p[2 * (size_t)st + i] = 0.0f;
	}
	fill(sl_exec_global(x, SL_GLOBAL_NCOMPS, &vary), vary, w, 3.0f);
	fill(sl_exec_global(x, SL_GLOBAL_TIME, &vary), vary, w, fr ? fr->time : 0.0f);
	fill(sl_exec_global(x, SL_GLOBAL_DTIME, &vary), vary, w, fr ? fr->dtime : 0.0f);
}

static float finite(float v)
{
	return isfinite(v) ? v : 0.0f;
}

bool reyes_imager_run(struct sl_exec *x, float *rgba, uint32_t w, uint32_t h,
		      const struct reyes_imager_frame *fr, struct reyes_texsys *tex)
{
	if (!x || !rgba || !w || !sl_exec_set_grid(x, w, 1))
		return false;
	struct sl_lighthost lh = { 0 };
	lh.host.user = &lh;
	if (tex)
		reyes_tex_serve(&lh, tex);
	uint32_t st = sl_exec_stride(x);
	for (uint32_t y = 0; y < h; y++) {
		float *row = rgba + (size_t)y * w * 4;
		load_row(x, row, w, y, fr);
		if (!sl_exec_run(x, &lh.host))
			return false;
		bool vc, va;
		const float *ci = sl_exec_global(x, SL_GLOBAL_CI, &vc);
		const float *al = sl_exec_global(x, SL_GLOBAL_ALPHA, &va);
		for (uint32_t i = 0; i < w; i++) {
			for (int c = 0; ci && c < 3; c++)
				row[i * 4 + (uint32_t)c] =
					finite(ci[(size_t)c * (vc ? st : 1) + (vc ? i : 0)]);
			if (al)
				row[i * 4 + 3] = finite(al[va ? i : 0]);
		}
	}
	return true;
}

void reyes_imager_set_params(struct sl_exec *x, const struct reyes_shader *sh)
{
	sl_exec_reset_params(x);
	for (uint32_t i = 0; i < sh->nparams; i++) {
		const struct reyes_param_value *pv = &sh->params[i];
		if (pv->type == SL_TYPE_STRING) {
			if (pv->strings && pv->nvalues)
				sl_exec_set_param_string(x, pv->name, pv->strings[0]);
		} else if (pv->values) {
			sl_exec_set_param(x, pv->name, pv->values, pv->nvalues);
		}
	}
}

bool reyes_imager_apply(const struct reyes_shader *sh, float *rgba, uint32_t w, uint32_t h,
			const struct reyes_imager_frame *fr, struct reyes_texsys *tex, FILE *diag)
{
	struct sl_exec *x = sl_exec_create(sh->prog, w);
	if (!x) {
		fprintf(diag ? diag : stderr, "relight: error: imager '%s': no executor for "
			"rows of %u pixels\n", sh->name, w);
		return false;
	}
	reyes_imager_set_params(x, sh);
	bool ok = reyes_imager_run(x, rgba, w, h, fr, tex);
	if (!ok)
		fprintf(diag ? diag : stderr, "relight: error: imager '%s' failed\n", sh->name);
	sl_exec_destroy(x);
	return ok;
}

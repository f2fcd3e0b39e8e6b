/*
 * A host that serves light shader executors to a surface shader: it runs a
 * light on the surface's grid when the surface asks for it, and answers
 * lightsource() and category queries from the light's parameters.
 */
#include "lighthost.h"

#include "exec_impl.h"

#include <stdio.h>
#include <string.h>

static struct sl_exec *light_at(const struct sl_lighthost *lh, int i)
{
	if (!lh || i < 0 || i >= lh->nlights || !lh->lights)
		return NULL;
	return lh->lights[i];
}

static int find_param(const struct sl_program *prog, const char *name)
{
	for (uint32_t k = 0; k < prog->nparams; k++)
		if (prog->params[k].name && !strcmp(prog->params[k].name, name))
			return (int)k;
	return -1;
}

static int lh_nlights(void *user)
{
	const struct sl_lighthost *lh = user;
	return lh->nlights > 0 ? lh->nlights : 0;
}

/* Copy global @g of @from (first active point if @to's is uniform) into @to. */
static void copy_global(struct sl_exec *to, struct sl_exec *from, enum sl_global g,
			int ncomp, const uint8_t *mask)
{
	bool tv, fv;
	float *d = sl_exec_global(to, g, &tv);
	const float *s = sl_exec_global(from, g, &fv);
	if (!d || !s)
		return;
	uint32_t n = to->n, first = 0;
	while (first + 1 < n && !mask[first])
		first++;
	for (int c = 0; c < ncomp; c++)
		for (uint32_t i = 0; i < (tv ? n : 1); i++) {
			uint32_t si = tv ? i : first;
			float v = fv ? s[(size_t)c * from->stride + si] : s[c];
			if (tv)
				d[(size_t)c * to->stride + i] = v;
			else
				d[c] = v;
		}
}

/* Set triple global @g of @lx from 3 planes @src (NULL: zero; first active point if uniform). */
static void put_planes(struct sl_exec *lx, enum sl_global g, const float *src, uint32_t n,
		       uint32_t stride, const uint8_t *mask)
{
	bool v;
	float *d = sl_exec_global(lx, g, &v);
	if (!d)
		return;
	uint32_t first = 0;
	while (first + 1 < n && !mask[first])
		first++;
	for (int c = 0; c < 3; c++) {
		const float *s = src ? src + (size_t)c * stride : NULL;
		if (v && s)
			memcpy(d + (size_t)c * lx->stride, s, n * sizeof(float));
		else if (v)
			memset(d + (size_t)c * lx->stride, 0, n * sizeof(float));
		else
			d[c] = s ? s[first] : 0.0f;
	}
}

/* Value of component @c of a global at point @i (0 when the shader has none). */
static float global_at(struct sl_exec *x, enum sl_global g, int c, uint32_t i)
{
	bool v;
	const float *d = sl_exec_global(x, g, &v);
	if (!d)
		return 0.0f;
	return v ? d[(size_t)c * x->stride + i] : d[c];
}

static bool lh_space(void *user, const char *name, float m[16]);

/* Fill every point of float or triple global @g of @x with @v. */
static void fill_global(struct sl_exec *x, enum sl_global g, const float *v, int ncomp, uint32_t n)
{
	bool vary;
	float *d = sl_exec_global(x, g, &vary);
	if (!d)
		return;
	for (int c = 0; c < ncomp; c++)
		for (uint32_t k = 0; k < (vary ? n : 1); k++)
			d[(size_t)c * (vary ? x->stride : 1) + k] = v[c];
}

/*
 * The light's own geometry, as RISpec gives it to a light that is not an
 * area light: P is the origin of its shader space, ncomps 3 (N, s, t, ...
 * are zero: never set).
 */
static void light_geometry(struct sl_lighthost *lh, struct sl_exec *lx, uint32_t n)
{
	float m[16], o[3] = { 0, 0, 0 }, three = 3;
	if (lh_space(lh, "shader", m)) {
		float w = m[15];
		for (int c = 0; c < 3; c++)
			o[c] = w != 0 && w != 1 ? m[12 + c] / w : m[12 + c];
	}
	fill_global(lx, SL_GLOBAL_P, o, 3, n);
	fill_global(lx, SL_GLOBAL_NCOMPS, &three, 1, n);
}

static bool lh_light(void *user, int i, struct sl_exec *surface, uint32_t n, uint32_t stride,
		     const uint8_t *mask, const float *Ps, const float *Ns, float *L, float *Cl,
		     float *Ol, uint8_t *lit, bool *ambient)
{
	struct sl_lighthost *lh = user;
	struct sl_exec *lx = light_at(lh, i);
	if (!lx || lx == surface || !surface || !mask || !Ps)
		return false;
	bool grid_ok = n == surface->n ? sl_exec_set_grid(lx, surface->nu, surface->nv)
				      : sl_exec_set_grid(lx, n, 1);
	if (!grid_ok) {
		if (!lx->warned_small) {
			lx->warned_small = true;
			const struct sl_program *lp = sl_exec_program(lx);
			fprintf(stderr, "%s: warning: light shader '%s' has room for %u points, the "
				"surface grid has %u: the light is left out\n",
				lp->source_path ? lp->source_path : "light",
				lp->name ? lp->name : "?", lx->maxn, n);
		}
		return false;
	}
	/* The light's derivatives (shadow() of Ps) are taken as the surface's. */
	uint32_t m = n == surface->n ? surface->stencil_m : 0;
	if (!sl_exec_set_stencil(lx, m, surface->stencil_du, surface->stencil_dv))
		return false;

	put_planes(lx, SL_GLOBAL_PS, Ps, n, stride, mask);
	put_planes(lx, SL_GLOBAL_NS, Ns, n, stride, mask);
	copy_global(lx, surface, SL_GLOBAL_E, 3, mask);
	copy_global(lx, surface, SL_GLOBAL_TIME, 1, mask);
	copy_global(lx, surface, SL_GLOBAL_DTIME, 1, mask);

	sl_exec_set_peer(lx, SL_PEER_SURFACE, surface);
	int outer = lh->running;
	lh->running = i;
	light_geometry(lh, lx, n);
	bool ok = sl_exec_run(lx, &lh->host);
	lh->running = outer;
	sl_exec_set_peer(lx, SL_PEER_SURFACE, NULL);
	if (!ok)
		return false;

	bool amb = sl_exec_is_ambient(lx);
	const uint8_t *llit = sl_exec_lit_mask(lx);
	for (uint32_t k = 0; k < n; k++) {
		if (!mask[k])
			continue;
		for (int c = 0; c < 3; c++) {
			size_t o = (size_t)c * stride + k;
			/* The light's L runs light -> surface; the surface wants the reverse. */
			L[o] = -global_at(lx, SL_GLOBAL_L, c, k);
			Cl[o] = global_at(lx, SL_GLOBAL_CL, c, k);
			Ol[o] = global_at(lx, SL_GLOBAL_OL, c, k);
		}
		lit[k] = amb ? 1 : (llit[k] != 0);
	}
	*ambient = amb;
	return true;
}

/* A string parameter's value without running the shader: set, constant default, or last run. */
static const char *param_string(struct sl_exec *lx, int k)
{
	const struct sl_program *prog = sl_exec_program(lx);
	const struct sl_param *pp = &prog->params[k];
	const char **cur = sl_exec_reg_strings(lx, pp->reg);
	if (lx->param_set[k])
		return cur && cur[0] ? cur[0] : "";
	for (uint32_t pc = pp->init_begin; pc < pp->init_end; pc++) {
		const struct sl_insn *in = &prog->code[pc];
		if (in->op != SL_OP_MOV || in->dst != pp->reg || in->nargs != 1)
			continue;
		const struct sl_reg *src = &prog->regs[in->args[0]];
		if (src->kind == SL_REG_CONST && src->type == SL_TYPE_STRING)
			return prog->strings[src->cindex] ? prog->strings[src->cindex] : "";
	}
	return cur && cur[0] ? cur[0] : "";
}

static const char *lh_category(void *user, int i)
{
	const struct sl_lighthost *lh = user;
	struct sl_exec *lx = light_at(lh, i);
	if (lx) {
		const struct sl_program *prog = sl_exec_program(lx);
		int k = find_param(prog, "__category");
		if (k >= 0) {
			const struct sl_reg *g = &prog->regs[prog->params[k].reg];
			if (g->type == SL_TYPE_STRING && g->arraylen == 0) {
				const char *s = param_string(lx, k);
				if (*s)
					return s;
			}
		}
	}
	if (lh->categories && i >= 0 && i < lh->nlights && lh->categories[i])
		return lh->categories[i];
	return "";
}

static bool type_fits(int want, int have)
{
	if (want == have)
		return true;
	if (sl_type_is_triple(want) && sl_type_is_triple(have))
		return true;
	return (want == SL_TYPE_FLOAT || want == SL_TYPE_BOOL) &&
	       (have == SL_TYPE_FLOAT || have == SL_TYPE_BOOL);
}

static bool lh_message(void *user, int i, const char *name, int type, int arraylen,
		       float *out, const char **sout, bool *varying, uint32_t stride)
{
	struct sl_lighthost *lh = user;
	struct sl_exec *lx = light_at(lh, i);
	if (!lx || !name)
		return false;
	const struct sl_program *prog = sl_exec_program(lx);
	int k = find_param(prog, name);
	if (k < 0)
		return false;
	int32_t r = prog->params[k].reg;
	const struct sl_reg *g = &prog->regs[r];
	if (!type_fits(type, g->type) || g->arraylen != arraylen)
		return false;
	uint32_t nel = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
	uint32_t n = lx->n < stride ? lx->n : stride;
	bool v = g->varying;
	if (varying)
		*varying = v;
	if (g->type == SL_TYPE_STRING) {
		const char **s = sl_exec_reg_strings(lx, r);
		if (!sout || !s)
			return false;
		for (uint32_t e = 0; e < nel; e++) {
			if (!v)
				sout[e] = s[e] ? s[e] : "";
			else
				for (uint32_t p = 0; p < n; p++) {
					const char *t = s[(size_t)e * lx->stride + p];
					sout[(size_t)e * stride + p] = t ? t : "";
				}
		}
		return true;
	}
	const float *d = sl_exec_reg(lx, r);
	if (!out || !d)
		return false;
	uint32_t tot = nel * (uint32_t)sl_reg_ncomp(g);
	for (uint32_t c = 0; c < tot; c++) {
		if (!v)
			out[c] = d[c];
		else
			memcpy(out + (size_t)c * stride, d + (size_t)c * lx->stride,
			       n * sizeof(float));
	}
	return true;
}

static bool lh_space(void *user, const char *name, float m[16])
{
	const struct sl_lighthost *lh = user;
	if (name && lh->running >= 0 && lh->light_shader_mats && !strcmp(name, "shader")) {
		memcpy(m, lh->light_shader_mats[lh->running], 16 * sizeof(float));
		return true;
	}
	if (!name || !lh->space_names || !lh->space_mats)
		return false;
	for (int k = 0; k < lh->nspaces; k++)
		if (lh->space_names[k] && !strcmp(lh->space_names[k], name)) {
			memcpy(m, lh->space_mats[k], 16 * sizeof(float));
			return true;
		}
	return false;
}

void sl_lighthost_init(struct sl_lighthost *lh, struct sl_exec **lights, int nlights)
{
	memset(lh, 0, sizeof(*lh));
	lh->lights = lights;
	lh->nlights = lights ? nlights : 0;
	lh->host.user = lh;
	lh->host.nlights = lh_nlights;
	lh->host.light = lh_light;
	lh->host.light_category = lh_category;
	lh->host.light_message = lh_message;
	lh->host.space = lh_space;
	lh->running = -1;
}

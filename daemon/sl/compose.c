/*
 * A surface followed by its atmosphere as one program (RISpec 3.2 §4.1.8,
 * "Atmosphere"): the volume shader runs on every shading sample of the
 * surfaces it is bound to, after the surface shader, and changes the Ci, Oi
 * the surface computed; its P is the surface point and its I the ray from the
 * eye to it, which are the surface's own P and I.
 *
 * Joining the two at the level of the IR makes the pair a surface shader like
 * any other: the renderer runs it, the specializer splits it (the atmosphere's
 * mix after a lit surface is dynamic because its Ci input is; an atmosphere
 * with illuminance reads the lights itself), the bake caches it and the GLSL
 * generator emits it, with no stage of its own anywhere downstream.
 *
 * Layout of the joined code:
 *   surface parameter defaults | atmosphere parameter defaults |
 *   copies of globals the surface writes and the atmosphere reads |
 *   surface body | atmosphere body
 */
#include "ir.h"
#include "builtin.h"
#include "../common/arena.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct join {
	const struct sl_program *s, *a;
	struct sl_program *p;
	int32_t *amap;          /* atmosphere register -> joined register */
	uint32_t ncopies;
};

/* Whether the surface writes register @r anywhere. */
static bool surface_writes(const struct sl_program *s, int32_t r)
{
	for (uint32_t i = 0; i < s->ncode; i++) {
		const struct sl_insn *in = &s->code[i];
		if (in->dst == r)
			return true;
		for (int k = 0; k < in->nargs; k++)
			if (in->args[k] == r && sl_ir_arg_is_output(in, k))
				return true;
	}
	return false;
}

/* The joined index of surface instruction @i (i == ncode: the surface's end). */
static int32_t s_at(const struct join *j, int32_t i)
{
	if (i < 0 || (uint32_t)i < j->s->body_begin)
		return i;
	return i + (int32_t)(j->a->body_begin + j->ncopies);
}

/* The joined index of atmosphere instruction @i. */
static int32_t a_at(const struct join *j, int32_t i)
{
	if (i < 0)
		return i;
	if ((uint32_t)i < j->a->body_begin)
		return (int32_t)j->s->body_begin + i;
	return (int32_t)(j->s->ncode + j->ncopies) + i;
}

/*
 * Registers: the surface's as they are, then the atmosphere's, sharing the
 * globals (Ci, Oi always) unless the surface writes one the atmosphere reads
 * (a bump that moves P): the atmosphere then reads a copy made before the
 * surface ran.
 */
static void map_registers(struct join *j, int32_t *copy_src, int32_t *copy_dst)
{
	const struct sl_program *s = j->s, *a = j->a;
	struct sl_program *p = j->p;
	uint32_t n = s->nregs;
	p->regs = rl_arena_alloc(p->arena, sizeof(struct sl_reg) * (s->nregs + a->nregs + 1));
	if (s->nregs)
		memcpy(p->regs, s->regs, sizeof(struct sl_reg) * s->nregs);
	memcpy(p->global_reg, s->global_reg, sizeof(p->global_reg));
	for (uint32_t r = 0; r < a->nregs; r++) {
		struct sl_reg g = a->regs[r];
		if (g.kind == SL_REG_GLOBAL) {
			int32_t sr = s->global_reg[g.global];
			bool ci_oi = g.global == SL_GLOBAL_CI || g.global == SL_GLOBAL_OI;
			if (sr >= 0 && (ci_oi || !surface_writes(s, sr))) {
				j->amap[r] = sr;
				continue;
			}
			if (sr >= 0) {
				/* a local that holds the global as it was */
				copy_src[j->ncopies] = sr;
				copy_dst[j->ncopies++] = (int32_t)n;
				g.kind = SL_REG_LOCAL;
				g.global = -1;
				g.output = false;
			} else {
				p->global_reg[g.global] = (int32_t)n;
			}
		} else if (g.kind == SL_REG_CONST) {
			g.cindex += g.type == SL_TYPE_STRING ? s->nstrings : s->nconsts;
		}
		g.loc.file += s->nfiles;
		p->regs[n] = g;
		j->amap[r] = (int32_t)n++;
	}
	p->nregs = n;
}

static void copy_insn(struct join *j, struct sl_insn *out, const struct sl_insn *in, bool atm)
{
	*out = *in;
	out->args = rl_arena_alloc(j->p->arena, sizeof(int32_t) * ((size_t)in->nargs + 1));
	for (int k = 0; k < in->nargs; k++)
		out->args[k] = atm ? j->amap[in->args[k]] : in->args[k];
	if (atm) {
		out->dst = in->dst >= 0 ? j->amap[in->dst] : in->dst;
		out->loc.file += j->s->nfiles;
	}
	for (int k = 0; k < 2; k++)
		out->jump[k] = atm ? a_at(j, in->jump[k]) : s_at(j, in->jump[k]);
}

static void join_code(struct join *j, const int32_t *copy_src, const int32_t *copy_dst)
{
	const struct sl_program *s = j->s, *a = j->a;
	struct sl_program *p = j->p;
	p->ncode = s->ncode + a->ncode + j->ncopies;
	p->code = rl_arena_alloc(p->arena, sizeof(struct sl_insn) * (p->ncode + 1));
	for (uint32_t i = 0; i < s->ncode; i++)
		copy_insn(j, &p->code[s_at(j, (int32_t)i)], &s->code[i], false);
	for (uint32_t i = 0; i < a->ncode; i++)
		copy_insn(j, &p->code[a_at(j, (int32_t)i)], &a->code[i], true);
	uint32_t at = s->body_begin + a->body_begin;
	for (uint32_t c = 0; c < j->ncopies; c++) {
		struct sl_insn *in = &p->code[at + c];
		memset(in, 0, sizeof(*in));
		in->op = SL_OP_MOV;
		in->nargs = 1;
		in->bi = -1;
		in->dst = copy_dst[c];
		in->jump[0] = in->jump[1] = -1;
		in->args = rl_arena_alloc(p->arena, sizeof(int32_t) * 2);
		in->args[0] = copy_src[c];
		in->loc = a->code[a->body_begin < a->ncode ? a->body_begin : 0].loc;
		in->loc.file += s->nfiles;
	}
	p->body_begin = at + j->ncopies;
	p->atmosphere_begin = (uint32_t)a_at(j, (int32_t)a->body_begin);
}

static bool has_param(const struct sl_program *s, const char *name)
{
	return sl_program_find_param(s, name) >= 0;
}

static void join_params(struct join *j)
{
	const struct sl_program *s = j->s, *a = j->a;
	struct sl_program *p = j->p;
	p->nparams = s->nparams + a->nparams;
	p->params = rl_arena_alloc(p->arena, sizeof(struct sl_param) * (p->nparams + 1));
	if (s->nparams)
		memcpy(p->params, s->params, sizeof(struct sl_param) * s->nparams);
	for (uint32_t k = 0; k < a->nparams; k++) {
		struct sl_param q = a->params[k];
		/* one name, one parameter: the atmosphere's gives way */
		if (has_param(s, q.name))
			q.name = rl_arena_printf(p->arena, "%s%s", SL_ATMOSPHERE_PREFIX, q.name);
		q.reg = j->amap[q.reg];
		/* the defaults' code moves as a block: its end may be the body's start */
		q.init_begin += s->body_begin;
		q.init_end += s->body_begin;
		p->params[s->nparams + k] = q;
	}
}

static void join_pools(struct join *j)
{
	const struct sl_program *s = j->s, *a = j->a;
	struct sl_program *p = j->p;
	p->nconsts = s->nconsts + a->nconsts;
	p->consts = rl_arena_alloc(p->arena, sizeof(float) * (p->nconsts + 1));
	if (s->nconsts)
		memcpy(p->consts, s->consts, sizeof(float) * s->nconsts);
	if (a->nconsts)
		memcpy(p->consts + s->nconsts, a->consts, sizeof(float) * a->nconsts);
	p->nstrings = s->nstrings + a->nstrings;
	p->strings = rl_arena_alloc(p->arena, sizeof(char *) * (p->nstrings + 1));
	if (s->nstrings)
		memcpy(p->strings, s->strings, sizeof(char *) * s->nstrings);
	if (a->nstrings)
		memcpy(p->strings + s->nstrings, a->strings, sizeof(char *) * a->nstrings);
	p->nfiles = s->nfiles + a->nfiles;
	p->files = rl_arena_alloc(p->arena, sizeof(char *) * (p->nfiles + 1));
	if (s->nfiles)
		memcpy(p->files, s->files, sizeof(char *) * s->nfiles);
	if (a->nfiles)
		memcpy(p->files + s->nfiles, a->files, sizeof(char *) * a->nfiles);
}

struct sl_program *sl_program_compose(const struct sl_program *surf,
				      const struct sl_program *atm)
{
	if (!surf || !atm || surf->kind != SL_SHADER_SURFACE || atm->kind != SL_SHADER_VOLUME)
		return NULL;
	struct rl_arena *arena = rl_arena_create();
	struct sl_program *p = rl_arena_alloc(arena, sizeof(*p));
	p->arena = arena;
	p->kind = SL_SHADER_SURFACE;
	p->name = rl_arena_printf(arena, "%s+%s", surf->name, atm->name);
	p->source_path = surf->source_path;
	memcpy(p->source_hash, surf->source_hash, sizeof(p->source_hash));
	memcpy(p->program_hash, surf->program_hash, sizeof(p->program_hash));
	p->surface_part = surf;
	p->atmosphere = atm;

	struct join j = { .s = surf, .a = atm, .p = p };
	j.amap = rl_arena_alloc(arena, sizeof(int32_t) * (atm->nregs + 1));
	int32_t *copy_src = rl_arena_alloc(arena, sizeof(int32_t) * (atm->nregs + 1));
	int32_t *copy_dst = rl_arena_alloc(arena, sizeof(int32_t) * (atm->nregs + 1));
	map_registers(&j, copy_src, copy_dst);
	join_code(&j, copy_src, copy_dst);
	join_params(&j);
	join_pools(&j);
	return p;
}

/* ---- is the atmosphere a sum over lights? ---- */

/*
 * What a value of the atmosphere depends on: nothing that an edit of a light
 * changes; one light, inside illuminance (L, Cl and what is made of them);
 * or a sum over the lights (the surface's Ci, an accumulation over the
 * lights, diffuse() and its kind).
 */
enum { DEP_NONE, DEP_LIGHT, DEP_SUM };

struct affine {
	const struct sl_program *p;
	uint8_t *dep;           /* per register */
	uint8_t *outside;       /* per register: read or written outside illuminance */
	const char *why;
	struct sl_loc at;
	bool changed;
};

static bool is_read(const struct sl_insn *in, int k)
{
	return !sl_ir_arg_is_output(in, k);
}

static void refuse(struct affine *f, const struct sl_insn *in, const char *why)
{
	if (!f->why) {
		f->why = why;
		f->at = in->loc;
	}
}

static void set_dep(struct affine *f, int32_t r, int d)
{
	if (r >= 0 && f->dep[r] < d) {
		f->dep[r] = (uint8_t)d;
		f->changed = true;
	}
}

/* The dependence of what @in writes, from what it reads; refuses products of sums. */
static int insn_dep(struct affine *f, const struct sl_insn *in, int ill)
{
	int nsum = 0, nlight = 0, m = DEP_NONE;
	for (int k = 0; k < in->nargs; k++) {
		if (!is_read(in, k))
			continue;
		int d = f->dep[in->args[k]];
		nsum += d == DEP_SUM;
		nlight += d == DEP_LIGHT;
		m = d > m ? d : m;
	}
	if (in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET) {
		int d = f->dep[in->dst];
		m = d > m ? d : m;
	}
	if (nlight && !ill)
		refuse(f, in, "a light's value is used outside illuminance");
	const struct sl_builtin *b = in->op == SL_OP_CALL && in->bi >= 0 ? &sl_builtins[in->bi]
									 : NULL;
	if (b && (b->flags & SL_BIF_LIGHTS)) {
		if (nsum)
			refuse(f, in, "the lights are sampled with the surface's colour");
		return DEP_SUM;
	}
	if (!nsum)
		return m;
	switch (in->op) {
	case SL_OP_MOV: case SL_OP_NEG: case SL_OP_ADD: case SL_OP_SUB: case SL_OP_COMP:
	case SL_OP_SETCOMP: case SL_OP_TRIPLE: case SL_OP_ASET:
		return m;
	case SL_OP_AREF:
		if (f->dep[in->args[1]] != DEP_NONE)
			refuse(f, in, "an array is indexed by the surface's colour");
		return m;
	case SL_OP_MUL:
		if (nsum + nlight > 1)
			refuse(f, in, "the surface's colour is multiplied by itself or by a light");
		return m;
	case SL_OP_DIV:
		if (f->dep[in->args[1]] != DEP_NONE)
			refuse(f, in, "something is divided by the surface's colour or a light");
		return m;
	case SL_OP_SELECT:
		if (f->dep[in->args[0]] != DEP_NONE)
			refuse(f, in, "a choice depends on the surface's colour");
		return m;
	case SL_OP_CALL:
		if (b && b->id == SL_BI_MIX && in->nargs == 3 && f->dep[in->args[2]] == DEP_NONE &&
		    f->dep[in->args[0]] != DEP_LIGHT && f->dep[in->args[1]] != DEP_LIGHT)
			return m;
		refuse(f, in, "a built-in function of the surface's colour other than mix()");
		return m;
	default:
		refuse(f, in, "the surface's colour is compared or branched on");
		return m;
	}
}

/* One pass over the atmosphere's body; f->changed when a dependence grew. */
static void affine_pass(struct affine *f)
{
	const struct sl_program *p = f->p;
	int ill = 0;
	for (uint32_t pc = p->atmosphere_begin; pc < p->ncode && !f->why; pc++) {
		const struct sl_insn *in = &p->code[pc];
		if (in->op == SL_OP_ILLUMINANCE) {
			ill++;
			continue;
		}
		if (in->op == SL_OP_ILLUMINANCE_END) {
			ill--;
			continue;
		}
		if ((in->op == SL_OP_IF || in->op == SL_OP_LOOPTEST) && in->nargs &&
		    f->dep[in->args[0]] == DEP_SUM) {
			refuse(f, in, "a branch depends on the surface's colour");
			break;
		}
		int d = insn_dep(f, in, ill);
		/* a light's value kept past its iteration accumulates over the lights */
		if (d == DEP_LIGHT && ill && in->dst >= 0 && f->outside[in->dst])
			d = DEP_SUM;
		set_dep(f, in->dst, d);
		for (int k = 0; k < in->nargs && in->op == SL_OP_CALL; k++)
			if (!is_read(in, k))
				set_dep(f, in->args[k], d == DEP_LIGHT && f->outside[in->args[k]]
								? DEP_SUM : d);
	}
}

const char *sl_program_atmosphere_nonaffine(const struct sl_program *p, struct sl_loc *at)
{
	if (!p->atmosphere)
		return NULL;
	struct affine f = { .p = p };
	f.dep = calloc(p->nregs + 1, 1);
	f.outside = calloc(p->nregs + 1, 1);
	if (!f.dep || !f.outside) {
		free(f.dep);
		free(f.outside);
		return "out of memory";
	}
	int ill = 0;
	for (uint32_t pc = p->atmosphere_begin; pc < p->ncode; pc++) {
		const struct sl_insn *in = &p->code[pc];
		ill += in->op == SL_OP_ILLUMINANCE;
		ill -= in->op == SL_OP_ILLUMINANCE_END;
		if (ill || in->op == SL_OP_ILLUMINANCE)
			continue;
		if (in->dst >= 0)
			f.outside[in->dst] = 1;
		for (int k = 0; k < in->nargs; k++)
			f.outside[in->args[k]] = 1;
	}
	/* the surface's result is the sum over its lights */
	f.dep[p->global_reg[SL_GLOBAL_CI]] = DEP_SUM;
	static const enum sl_global light_globals[] = { SL_GLOBAL_L, SL_GLOBAL_CL, SL_GLOBAL_OL };
	for (size_t g = 0; g < 3; g++)
		if (p->global_reg[light_globals[g]] >= 0)
			f.dep[p->global_reg[light_globals[g]]] = DEP_LIGHT;
	/* loops carry dependences backwards: until nothing grows */
	for (int pass = 0; pass < 64; pass++) {
		f.changed = false;
		affine_pass(&f);
		if (!f.changed || f.why)
			break;
	}
	free(f.dep);
	free(f.outside);
	if (f.why && at)
		*at = f.at;
	return f.why;
}

uint32_t sl_program_report_frozen_rays(const struct sl_program *p, FILE *diag, bool error)
{
	uint32_t n = 0;
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		if (in->op != SL_OP_CALL || in->bi < 0)
			continue;
		const struct sl_builtin *b = &sl_builtins[in->bi];
		bool lit = b->flags & SL_BIF_RAYLIT;
		if (!lit && b->id == SL_BI_ENVIRONMENT && in->nargs > 0 && in->args[0] >= 0) {
			/* environment("raytrace", ...) of a constant name (one a parameter
			   gives is known at run time only) */
			const struct sl_reg *r = &p->regs[in->args[0]];
			lit = r->kind != SL_REG_CONST ||
			      (r->cindex < p->nstrings && !strcmp(p->strings[r->cindex], "raytrace"));
			lit = lit && r->kind == SL_REG_CONST;
		}
		if (!lit)
			continue;
		const char *file = in->loc.file < p->nfiles ? p->files[in->loc.file] : p->name;
		fprintf(diag, "%s:%u: %s: %s() brings back light from what its rays hit: the "
			"preview keeps the value baked with the scene's lights (it does not follow "
			"light edits; relight render does)\n", file, in->loc.line,
			error ? "error" : "warning", b->name);
		n++;
	}
	return n;
}

bool sl_program_report_nonaffine(const struct sl_program *p, FILE *diag, bool error)
{
	struct sl_loc at = { 0 };
	const char *why = sl_program_atmosphere_nonaffine(p, &at);
	if (!why)
		return false;
	const char *file = at.file < p->nfiles ? p->files[at.file] : p->atmosphere->name;
	fprintf(diag, "%s:%u: %s: atmosphere '%s' after surface '%s': %s, so it is no sum over "
		"the lights; the GPU preview, which adds the lights one at a time, differs from "
		"the render (relight preview --cpu does not)\n", file, at.line,
		error ? "error" : "warning", p->atmosphere->name, p->surface_part->name, why);
	return true;
}

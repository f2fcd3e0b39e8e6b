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
	memcpy(p->params, s->params, sizeof(struct sl_param) * s->nparams);
	for (uint32_t k = 0; k < a->nparams; k++) {
		struct sl_param q = a->params[k];
		/* one name, one parameter: the atmosphere's gives way */
		if (has_param(s, q.name))
			q.name = rl_arena_printf(p->arena, "%s%s", SL_ATMOSPHERE_PREFIX, q.name);
		q.reg = j->amap[q.reg];
		q.init_begin = (uint32_t)a_at(j, (int32_t)q.init_begin);
		q.init_end = (uint32_t)a_at(j, (int32_t)q.init_end);
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

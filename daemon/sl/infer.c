/*
 * Uniformity inference.
 *
 * A register is varying if some instruction writes it with a varying value:
 * a varying operand, a built-in whose result always varies (random, the
 * lighting functions), or any write under varying control flow, where some
 * points may be switched off. Control is varying inside an if or loop whose
 * condition is varying, inside illuminance/illuminate/solar, and inside a
 * loop or function body that some points may leave early (a break, continue
 * or return under varying control). Those facts feed each other, so the pass
 * iterates to a fixpoint; it only ever turns things varying, so it ends.
 *
 * A local declared `uniform` that has to vary is promoted, as prman and aqsl
 * do: it becomes varying, one value per point exactly as if declared so, and
 * the program records why (the compile report lists it). That is what makes
 * library code such as a uniform octave counter in an fBm inlined under a
 * varying `if`, or a uniform message read inside illuminance, mean what its
 * author meant. What stays an error is what promotion cannot keep: a shader
 * parameter (the renderer and other shaders hand it over, or read it, as
 * one value per grid), a promoted variable passed to an `output uniform`
 * formal, and names that are looked up once per grid.
 *
 * random() in a uniform context (lower.c marks it, imm = 1) is one value for
 * the grid: it does not make its result vary.
 *
 * Registers that stay uniform are computed once per grid instead of once per
 * point, which is most of the interpreter's speed on real shaders.
 */
#include "sema.h"
#include "builtin.h"

#include <stdlib.h>
#include <string.h>

struct ctl {
	int32_t at;      /* opener index */
	bool varying;
};

struct infer {
	const struct sl_program *prog;
	bool *var;        /* per register */
	int32_t *why;     /* per register: instruction that made it varying */
	bool *why_ctl;    /* ...because of varying control (else a varying value) */
	bool *block;      /* per opener: the whole block runs under varying control */
	RL_VEC(struct ctl) stack;
	bool changed;
};

static void set_varying(struct infer *f, int32_t r, int32_t at, bool ctl)
{
	if (r < 0 || f->var[r])
		return;
	f->var[r] = true;
	f->why[r] = at;
	f->why_ctl[r] = ctl;
	f->changed = true;
}

static void set_block(struct infer *f, int32_t at)
{
	if (!f->block[at]) {
		f->block[at] = true;
		f->changed = true;
	}
}

static bool ctl_varying(const struct infer *f)
{
	return f->stack.len && f->stack.data[f->stack.len - 1].varying;
}

static void push(struct infer *f, int32_t at, bool varying)
{
	struct ctl c = { at, varying || ctl_varying(f) || f->block[at] };
	rl_vec_push(f->stack, c);
}

static void pop(struct infer *f)
{
	if (f->stack.len)
		f->stack.len--;
}

static bool is_loop_op(int op)
{
	return op == SL_OP_LOOP || op == SL_OP_ILLUMINANCE;
}

/* Points leave the @levels innermost loops early: those blocks become varying. */
static void leave_loops(struct infer *f, int levels)
{
	for (size_t i = f->stack.len; i-- > 0 && levels > 0;) {
		int32_t at = f->stack.data[i].at;
		int op = f->prog->code[at].op;
		if (is_loop_op(op)) {
			set_block(f, at);
			levels--;
		}
	}
}

/* Points return: every block up to the innermost FUNC becomes varying. */
static void leave_func(struct infer *f)
{
	for (size_t i = f->stack.len; i-- > 0;) {
		int32_t at = f->stack.data[i].at;
		set_block(f, at);
		if (f->prog->code[at].op == SL_OP_FUNC)
			break;
	}
}

static void pass(struct infer *f)
{
	const struct sl_program *p = f->prog;
	f->stack.len = 0;
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		int32_t at = (int32_t)i;
		switch (in->op) {
		case SL_OP_IF:
			push(f, at, f->var[in->args[0]]);
			continue;
		case SL_OP_ELSE:
			continue;
		case SL_OP_LOOP:
		case SL_OP_FUNC:
			push(f, at, false);
			continue;
		case SL_OP_LOOPTEST:
			if (f->var[in->args[0]] && in->jump[0] >= 0) {
				set_block(f, in->jump[0]);
				if (f->stack.len)
					f->stack.data[f->stack.len - 1].varying = true;
			}
			continue;
		case SL_OP_ILLUMINANCE:
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			push(f, at, true);
			continue;
		case SL_OP_ENDIF:
		case SL_OP_LOOPEND:
		case SL_OP_FUNCEND:
		case SL_OP_ILLUMINANCE_END:
		case SL_OP_ILLUMINATE_END:
		case SL_OP_SOLAR_END:
			pop(f);
			continue;
		case SL_OP_BREAK:
		case SL_OP_CONTINUE:
			if (ctl_varying(f))
				leave_loops(f, in->imm > 0 ? in->imm : 1);
			continue;
		case SL_OP_RETURN:
			if (ctl_varying(f))
				leave_func(f);
			continue;
		case SL_OP_LOOPCONT:
		case SL_OP_NOP:
			continue;
		default:
			break;
		}
		bool ctl = ctl_varying(f);
		bool v = false;
		const struct sl_builtin *b = NULL;
		const char *sig = NULL;
		if (in->op == SL_OP_CALL && in->bi >= 0) {
			b = &sl_builtins[in->bi];
			sig = strchr(b->sig, ':') + 1;
			/* Built-ins that read globals (s, t, Ng, P...) without taking
			 * them as arguments vary as those do. */
			if (b->flags & (SL_BIF_VARYING | SL_BIF_LIGHTS | SL_BIF_GLOBALS))
				v = !(b->id == SL_BI_RANDOM && in->imm == 1);
		}
		/* Inputs: every argument that is not an output of a built-in. */
		const char *sp = sig;
		for (int k = 0; k < in->nargs; k++) {
			bool output = false;
			if (sp && *sp && *sp != '*') {
				if (b && (b->flags & SL_BIF_TEXNAME) && k == 1) {
					/* the channel, not in the signature */
				} else {
					if (*sp == '&') {
						output = true;
						sp++;
					}
					sp++;
				}
			}
			if (!output && f->var[in->args[k]])
				v = true;
		}
		if (in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET)
			v = v || f->var[in->dst];
		if (in->dst >= 0 && (v || ctl))
			set_varying(f, in->dst, at, !v);
		/* Outputs of built-ins (fresnel's Kr, message passing...). */
		if (sig) {
			sp = sig;
			for (int k = 0; k < in->nargs && *sp && *sp != '*'; k++) {
				if (b && (b->flags & SL_BIF_TEXNAME) && k == 1)
					continue;
				bool output = *sp == '&';
				if (output)
					sp++;
				sp++;
				if (!output)
					continue;
				/* Message passing may bring a varying value from another
				 * shader: only a variable declared uniform stays uniform. */
				bool mv = v || ctl ||
					  ((b->flags & SL_BIF_MESSAGE) &&
					   !p->regs[in->args[k]].declared_uniform);
				if (mv)
					set_varying(f, in->args[k], at, !v && ctl);
			}
		}
	}
}

/* Why register @r, declared uniform, varies: "assigned under varying control flow at 12". */
static const char *promotion_why(struct sl_ctx *ctx, const struct sl_program *prog, int32_t r)
{
	for (uint32_t k = 0; k < prog->npromoted; k++) {
		const struct sl_promotion *m = &prog->promoted[k];
		if (m->reg == r)
			return rl_arena_printf(ctx->arena, "'%s' is declared uniform but %s at line %u",
					     prog->regs[r].name,
					     m->ctl ? "is assigned under varying control flow"
						    : "is assigned a varying value",
					     m->at.line);
	}
	return NULL;
}

/* A uniform parameter that would have to vary: an error, with the reason. */
static void param_error(struct sl_ctx *ctx, const struct sl_program *prog, int32_t r,
			const struct sl_insn *in, int32_t at, bool ctl)
{
	const struct sl_reg *reg = &prog->regs[r];
	for (uint32_t k = 0; k < prog->nparams; k++) {
		if (prog->params[k].reg == r && (uint32_t)at < prog->params[k].init_end) {
			sl_error(ctx, in->loc, "the default of uniform parameter '%s' is varying",
				 reg->name);
			return;
		}
	}
	const char *how = ctl ? "assigned inside varying control flow" : "assigned a varying value";
	if (reg->output)
		sl_error(ctx, in->loc,
			 "output uniform parameter '%s' is %s: other shaders read it as one value "
			 "per grid (declare it varying)", reg->name, how);
	else
		sl_error(ctx, in->loc,
			 "uniform parameter '%s' is %s: the renderer hands a uniform parameter "
			 "over as one value per grid (declare it varying)", reg->name, how);
}

/* Make the uniform locals that vary varying; parameters that vary are errors. */
static bool promote(struct sl_ctx *ctx, struct sl_program *prog, const struct infer *f)
{
	bool ok = true;
	uint32_t n = 0;
	for (uint32_t r = 0; r < prog->nregs; r++)
		n += f->var[r] && prog->regs[r].declared_uniform && f->why[r] >= 0;
	prog->promoted = rl_arena_alloc(ctx->arena, sizeof(struct sl_promotion) * (n + 1));
	prog->npromoted = 0;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		struct sl_reg *reg = &prog->regs[r];
		if (f->var[r] && reg->declared_uniform && f->why[r] >= 0) {
			const struct sl_insn *in = &prog->code[f->why[r]];
			if (reg->kind == SL_REG_PARAM) {
				param_error(ctx, prog, (int32_t)r, in, f->why[r], f->why_ctl[r]);
				ok = false;
			} else {
				struct sl_promotion m = { (int32_t)r, in->loc, f->why_ctl[r] };
				prog->promoted[prog->npromoted++] = m;
				reg->promoted = true;
			}
		}
		reg->varying = f->var[r];
	}
	return ok;
}

/* Names of textures and messages are looked up once per grid: they must not
 * vary from point to point. Nor may a promoted variable be what an output
 * uniform formal refers to. */
static bool check_uniform_uses(struct sl_ctx *ctx, const struct sl_program *prog)
{
	bool ok = true;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (in->op != SL_OP_CALL || in->bi < 0 || in->nargs == 0)
			continue;
		const struct sl_builtin *b = &sl_builtins[in->bi];
		if (!(b->flags & (SL_BIF_TEXNAME | SL_BIF_MESSAGE)))
			continue;
		if (prog->regs[in->args[0]].varying) {
			const char *why = promotion_why(ctx, prog, in->args[0]);
			sl_error(ctx, in->loc, "the name given to %s() must be uniform, not varying%s%s%s",
				 b->name, why ? " (" : "", why ? why : "", why ? ")" : "");
			ok = false;
		}
		if ((b->flags & SL_BIF_TEXNAME) && in->nargs > 1 && prog->regs[in->args[1]].varying) {
			const char *why = promotion_why(ctx, prog, in->args[1]);
			sl_error(ctx, in->loc, "the channel given to %s() must be uniform%s%s%s",
				 b->name, why ? " (" : "", why ? why : "", why ? ")" : "");
			ok = false;
		}
	}
	for (uint32_t k = 0; k < prog->nurefs; k++) {
		const struct sl_uniform_ref *u = &prog->urefs[k];
		if (!prog->regs[u->reg].promoted)
			continue;
		sl_error(ctx, u->loc,
			 "%s, and it is passed to the output uniform formal '%s' of %s(), which "
			 "refers to one value for the grid (declare one of them varying)",
			 promotion_why(ctx, prog, u->reg), u->formal, u->func);
		ok = false;
	}
	return ok;
}

bool sl_infer(struct sl_ctx *ctx, struct sl_program *prog)
{
	struct infer f = { .prog = prog };
	f.var = rl_xcalloc(prog->nregs + 1, sizeof(bool));
	f.why = rl_xcalloc(prog->nregs + 1, sizeof(int32_t));
	f.why_ctl = rl_xcalloc(prog->nregs + 1, sizeof(bool));
	f.block = rl_xcalloc(prog->ncode + 1, sizeof(bool));
	for (uint32_t r = 0; r < prog->nregs; r++) {
		f.var[r] = prog->regs[r].varying;
		f.why[r] = -1;
	}
	do {
		f.changed = false;
		pass(&f);
	} while (f.changed);

	bool ok = promote(ctx, prog, &f);
	ok = check_uniform_uses(ctx, prog) && ok;
	free(f.var);
	free(f.why);
	free(f.why_ctl);
	free(f.block);
	rl_vec_free(f.stack);
	return ok;
}

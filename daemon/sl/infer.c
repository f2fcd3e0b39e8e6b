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
				v = true;
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

	bool ok = true;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		struct sl_reg *reg = &prog->regs[r];
		if (f.var[r] && reg->declared_uniform && f.why[r] >= 0) {
			const struct sl_insn *in = &prog->code[f.why[r]];
			bool in_default = false;
			for (uint32_t k = 0; k < prog->nparams; k++)
				if (prog->params[k].reg == (int32_t)r &&
				    (uint32_t)f.why[r] < prog->params[k].init_end)
					in_default = true;
			const char *what = reg->kind == SL_REG_PARAM ? "parameter" : "variable";
			if (in_default)
				sl_error(ctx, in->loc,
					 "the default of uniform parameter '%s' is varying", reg->name);
			else if (f.why_ctl[r])
				sl_error(ctx, in->loc,
					 "uniform %s '%s' is assigned inside varying control flow "
					 "(declare it varying)", what, reg->name);
			else
				sl_error(ctx, in->loc,
					 "uniform %s '%s' is assigned a varying value (declare it "
					 "varying)", what, reg->name);
			ok = false;
		}
		reg->varying = f.var[r];
	}
	/* Names of textures, coordinate systems' partners and messages are looked
	 * up once per grid: they must not vary from point to point. */
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (in->op != SL_OP_CALL || in->bi < 0 || in->nargs == 0)
			continue;
		const struct sl_builtin *b = &sl_builtins[in->bi];
		if (!(b->flags & (SL_BIF_TEXNAME | SL_BIF_MESSAGE)))
			continue;
		if (prog->regs[in->args[0]].varying) {
			sl_error(ctx, in->loc, "the name given to %s() must be uniform, not varying",
				 b->name);
			ok = false;
		}
		if ((b->flags & SL_BIF_TEXNAME) && in->nargs > 1 && prog->regs[in->args[1]].varying) {
			sl_error(ctx, in->loc, "the channel given to %s() must be uniform", b->name);
			ok = false;
		}
	}
	free(f.var);
	free(f.why);
	free(f.why_ctl);
	free(f.block);
	rl_vec_free(f.stack);
	return ok;
}

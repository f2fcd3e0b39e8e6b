/*
 * Specialization by dependence analysis (lightspeed-2007 §3.1).
 *
 * Dynamic: a register is dynamic if a dynamic instruction writes it; an
 * instruction is dynamic if it reads a dynamic register, calls a built-in
 * that reads the lights, writes a dynamic register (a variable is computed
 * wholly by one part), or writes a variable under dynamic control (inside
 * an illuminance statement, or an if/loop whose condition is dynamic, or a
 * loop with dynamic code inside, or a block some points leave early under
 * dynamic control). Temporaries that are written once are exempt from the
 * control rule: whether they are computed depends on the branch, but not
 * their value, so the caching program can compute them on both sides of a
 * dynamic branch.
 *
 * Live: an instruction is live if it writes a register that reaches an
 * output (Ci, Oi, output parameters) or has a side effect; a block is live
 * if anything in it is, and then its condition is too.
 *
 * Both are fixpoints over the structured IR, flow-insensitive per register
 * (conservative where a variable is reused for unrelated values).
 */
#include "spec.h"
#include "builtin.h"
#include "ctx.h"
#include "exec_impl.h"
#include "sema.h"
#include "../common/strbuf.h"

#include <stdlib.h>
#include <string.h>

static bool is_opener(int op)
{
	return op == SL_OP_IF || op == SL_OP_LOOP || op == SL_OP_FUNC || op == SL_OP_ILLUMINANCE ||
	       op == SL_OP_ILLUMINATE || op == SL_OP_SOLAR;
}

static bool is_closer(int op)
{
	return op == SL_OP_ENDIF || op == SL_OP_LOOPEND || op == SL_OP_FUNCEND ||
	       op == SL_OP_ILLUMINANCE_END || op == SL_OP_ILLUMINATE_END || op == SL_OP_SOLAR_END;
}

static bool is_control(int op)
{
	return op >= SL_OP_IF;
}

/* Argument k of a call is an output (written, not read). */
static bool arg_is_output(const struct sl_insn *in, int k)
{
	if (in->op != SL_OP_CALL || in->bi < 0)
		return false;
	const struct sl_builtin *b = &sl_builtins[in->bi];
	const char *sig = strchr(b->sig, ':') + 1;
	int pos = 0;
	for (const char *p = sig; *p && *p != '*'; p++) {
		bool out = false;
		if ((b->flags & SL_BIF_TEXNAME) && pos == 1) {
			/* the channel argument is not in the signature */
			pos++;
			if (pos > k)
				return false;
		}
		if (*p == '&') {
			out = true;
			p++;
		}
		if (pos == k)
			return out;
		pos++;
	}
	return false;
}

/* Built-ins the GPU cannot run: their values are computed at bake time. */
static bool gpu_cannot(const struct sl_program *prog, const struct sl_insn *in)
{
	if (in->op != SL_OP_CALL || in->bi < 0)
		return false;
	const struct sl_builtin *b = &sl_builtins[in->bi];
	switch (b->id) {
	case SL_BI_DU: case SL_BI_DV: case SL_BI_DERIV: case SL_BI_AREA:
	case SL_BI_CALCULATENORMAL: case SL_BI_FILTERSTEP: case SL_BI_RANDOM:
	case SL_BI_FORMAT: case SL_BI_CONCAT: case SL_BI_MATCH: case SL_BI_TEXTUREINFO:
	case SL_BI_ATTRIBUTE: case SL_BI_OPTION: case SL_BI_RENDERERINFO:
		return true;
	case SL_BI_TEXTURE: case SL_BI_ENVIRONMENT: case SL_BI_SHADOW: {
		/* only the empty name (no map) runs on the GPU */
		const struct sl_reg *r = &prog->regs[in->args[0]];
		return !(r->kind == SL_REG_CONST && prog->strings[r->cindex][0] == '\0');
	}
	default:
		return false;
	}
}

/* Is register @r the constant empty string (a lookup of no map)? */
static bool empty_name(const struct sl_program *prog, int32_t r)
{
	const struct sl_reg *g = &prog->regs[r];
	if (g->kind != SL_REG_CONST || g->type != SL_TYPE_STRING)
		return false;
	const char *str = prog->strings[g->cindex];
	return !str || !*str;
}

/* Leading numeric arguments of @in from argument @from on. */
static int numeric_args(const struct sl_program *prog, const struct sl_insn *in, int from)
{
	int k = from;
	while (k < in->nargs && prog->regs[in->args[k]].type != SL_TYPE_STRING)
		k++;
	return k - from;
}

/*
 * The values whose derivatives call @in takes, as the interpreter does
 * (exec_builtins.c): the operand of Du, Dv, area and calculatenormal, both
 * of Deriv, filterstep's s1 when no s2 gives the filter width, and the
 * coordinates a texture, environment or shadow lookup builds its filter
 * region around (texture() with none: the globals s and t). Explicit
 * corners take none, nor does a lookup of the constant empty name (the
 * fill, no map). Writes up to 2 registers to @r and returns how many.
 */
int sl_spec_deriv_operands(const struct sl_program *prog, const struct sl_insn *in, int32_t r[2])
{
	if (in->op != SL_OP_CALL || in->bi < 0 || (uint32_t)in->bi >= sl_nbuiltins)
		return 0;
	const int32_t *a = in->args;
	switch (sl_builtins[in->bi].id) {
	case SL_BI_DU: case SL_BI_DV: case SL_BI_AREA: case SL_BI_CALCULATENORMAL:
		if (in->nargs < 1)
			return 0;
		r[0] = a[0];
		return 1;
	case SL_BI_DERIV:
		if (in->nargs < 2)
			return 0;
		r[0] = a[0];
		r[1] = a[1];
		return 2;
	case SL_BI_FILTERSTEP:
		if (in->nargs < 2 || numeric_args(prog, in, 0) >= 3)
			return 0;
		r[0] = a[1];
		return 1;
	case SL_BI_TEXTURE: {
		if (in->nargs < 2 || empty_name(prog, a[0]))
			return 0;
		int nc = numeric_args(prog, in, 2);
		if (nc >= 8)
			return 0;
		r[0] = nc >= 2 ? a[2] : prog->global_reg[SL_GLOBAL_S];
		r[1] = nc >= 2 ? a[3] : prog->global_reg[SL_GLOBAL_T];
		return 2;
	}
	case SL_BI_ENVIRONMENT: case SL_BI_SHADOW: {
		if (in->nargs < 3 || empty_name(prog, a[0]))
			return 0;
		int nc = numeric_args(prog, in, 2);
		if (nc < 1 || nc >= 4)
			return 0;
		r[0] = a[2];
		return 1;
	}
	default:
		return 0;
	}
}

bool sl_program_takes_derivatives(const struct sl_program *prog)
{
	if (!prog)
		return false;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		int32_t r[2];
		int n = sl_spec_deriv_operands(prog, &prog->code[i], r);
		for (int k = 0; k < n; k++)
			if (r[k] >= 0 && prog->regs[r[k]].varying)
				return true;
	}
	return false;
}

struct ctl {
	int32_t at;
	bool dynamic;
};

struct state {
	const struct sl_program *prog;
	struct sl_spec *s;
	uint32_t *writes;        /* per register: instructions writing it */
	uint8_t *block_dyn;      /* per opener */
	RL_VEC(struct ctl) stack;
	bool changed;
	FILE *diag;
};

static bool ctl_dyn(const struct state *st)
{
	return st->stack.len && st->stack.data[st->stack.len - 1].dynamic;
}

static void push(struct state *st, int32_t at, bool dyn)
{
	struct ctl c = { at, dyn || ctl_dyn(st) || st->block_dyn[at] };
	rl_vec_push(st->stack, c);
}

static void set_block(struct state *st, int32_t at)
{
	if (!st->block_dyn[at]) {
		st->block_dyn[at] = 1;
		st->changed = true;
	}
}

static void set_reg(struct state *st, int32_t r)
{
	if (r >= 0 && !st->s->reg_dynamic[r]) {
		st->s->reg_dynamic[r] = 1;
		st->changed = true;
	}
}

/*
 * Dynamic code inside a loop runs once per iteration: what changes from one
 * iteration to the next (the counter, the condition) cannot be one cached
 * value, so the loops around dynamic code are under dynamic control.
 */
static void in_dynamic_loops(struct state *st)
{
	for (size_t k = 0; k < st->stack.len; k++) {
		int32_t at = st->stack.data[k].at;
		if (st->prog->code[at].op == SL_OP_LOOP)
			set_block(st, at);
	}
}

/* One forward pass of the dynamic fixpoint. */
static void dyn_pass(struct state *st)
{
	const struct sl_program *p = st->prog;
	struct sl_spec *s = st->s;
	st->stack.len = 0;
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		int32_t at = (int32_t)i;
		switch (in->op) {
		case SL_OP_IF:
			if (s->reg_dynamic[in->args[0]]) {
				s->insn_dynamic[i] = 1;
				in_dynamic_loops(st);
			}
			push(st, at, s->reg_dynamic[in->args[0]]);
			continue;
		case SL_OP_LOOP:
		case SL_OP_FUNC:
			push(st, at, false);
			continue;
		case SL_OP_ILLUMINANCE:
			/* which lights reach a point, and L, Cl, Ol: all light-dependent */
			s->insn_dynamic[i] = 1;
			in_dynamic_loops(st);
			push(st, at, true);
			continue;
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			push(st, at, true);
			continue;
		case SL_OP_LOOPTEST:
			if (s->reg_dynamic[in->args[0]] && in->jump[0] >= 0) {
				set_block(st, in->jump[0]);
				if (st->stack.len)
					st->stack.data[st->stack.len - 1].dynamic = true;
			}
			continue;
		case SL_OP_BREAK:
		case SL_OP_CONTINUE:
			if (ctl_dyn(st)) {
				int levels = in->imm > 0 ? in->imm : 1;
				for (size_t k = st->stack.len; k-- > 0 && levels > 0;) {
					int op = p->code[st->stack.data[k].at].op;
					if (op == SL_OP_LOOP || op == SL_OP_ILLUMINANCE) {
						set_block(st, st->stack.data[k].at);
						levels--;
					}
				}
			}
			continue;
		case SL_OP_RETURN:
			if (ctl_dyn(st))
				for (size_t k = st->stack.len; k-- > 0;) {
					set_block(st, st->stack.data[k].at);
					if (p->code[st->stack.data[k].at].op == SL_OP_FUNC)
						break;
				}
			continue;
		default:
			if (is_closer(in->op)) {
				if (st->stack.len)
					st->stack.len--;
				continue;
			}
			if (is_control(in->op))
				continue;
			break;
		}
		bool dyn = false;
		for (int k = 0; k < in->nargs; k++)
			if (!arg_is_output(in, k) && s->reg_dynamic[in->args[k]])
				dyn = true;
		if (in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET)
			dyn = dyn || s->reg_dynamic[in->dst];
		if (in->op == SL_OP_CALL && in->bi >= 0) {
			const struct sl_builtin *b = &sl_builtins[in->bi];
			if ((b->flags & SL_BIF_LIGHTS) || b->id == SL_BI_LIGHTSOURCE)
				dyn = true;
		}
		/* the control rule, for registers that merge values */
		if (ctl_dyn(st)) {
			if (in->dst >= 0 &&
			    (p->regs[in->dst].kind != SL_REG_TEMP || st->writes[in->dst] > 1))
				dyn = true;
			for (int k = 0; k < in->nargs; k++)
				if (arg_is_output(in, k))
					dyn = true;
		}
		/* A register is either cached (one value per sample, computed
		 * before the dynamic part runs) or computed by the dynamic part:
		 * every write of a dynamic variable is dynamic, its static start
		 * value included (color C = Cs; illuminance (...) C += ...). */
		if (in->dst >= 0 && s->reg_dynamic[in->dst])
			dyn = true;
		for (int k = 0; k < in->nargs; k++)
			if (arg_is_output(in, k) && s->reg_dynamic[in->args[k]])
				dyn = true;
		if (dyn && gpu_cannot(p, in)) {
			/* computed at bake time anyway: stays static */
			dyn = false;
		}
		if (dyn && !s->insn_dynamic[i]) {
			s->insn_dynamic[i] = 1;
			st->changed = true;
		}
		if (s->insn_dynamic[i]) {
			in_dynamic_loops(st);
			set_reg(st, in->dst);
			for (int k = 0; k < in->nargs; k++)
				if (arg_is_output(in, k))
					set_reg(st, in->args[k]);
		}
	}
}

/* Backward liveness: live registers and instructions, blocks included. */
static void liveness(struct state *st, uint8_t *reg_live)
{
	const struct sl_program *p = st->prog;
	struct sl_spec *s = st->s;
	bool changed = true;
	while (changed) {
		changed = false;
		for (uint32_t i = p->ncode; i-- > 0;) {
			const struct sl_insn *in = &p->code[i];
			bool live = s->live[i];
			if (!live && !is_control(in->op)) {
				if (in->dst >= 0 && reg_live[in->dst])
					live = true;
				for (int k = 0; k < in->nargs; k++)
					if (arg_is_output(in, k) && reg_live[in->args[k]])
						live = true;
				if (in->op == SL_OP_CALL && in->bi >= 0 &&
				    (sl_builtins[in->bi].flags & SL_BIF_SIDE_EFFECT))
					live = true;
			}
			if (live && !s->live[i]) {
				s->live[i] = 1;
				changed = true;
			}
			if (!s->live[i])
				continue;
			for (int k = 0; k < in->nargs; k++)
				if (!arg_is_output(in, k) && !reg_live[in->args[k]]) {
					reg_live[in->args[k]] = 1;
					changed = true;
				}
			if ((in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET) && !reg_live[in->dst]) {
				reg_live[in->dst] = 1;
				changed = true;
			}
		}
		/* blocks with anything live inside are live, with their parts */
		for (uint32_t i = 0; i < p->ncode; i++) {
			const struct sl_insn *in = &p->code[i];
			if (!is_opener(in->op) || s->live[i])
				continue;
			int32_t end = in->op == SL_OP_IF || in->op == SL_OP_LOOP ? in->jump[1] : in->jump[0];
			if (end < 0)
				continue;
			for (int32_t k = (int32_t)i + 1; k < end; k++)
				if (s->live[k] && !is_control(p->code[k].op)) {
					for (int32_t j = (int32_t)i; j <= end; j++) {
						const struct sl_insn *c = &p->code[j];
						/* the block's own structure and the jumps out of it */
						if (is_control(c->op) && !s->live[j]) {
							s->live[j] = 1;
							changed = true;
						}
					}
					break;
				}
		}
		for (uint32_t i = 0; i < p->ncode; i++) {
			const struct sl_insn *in = &p->code[i];
			if (s->live[i] && (in->op == SL_OP_IF || in->op == SL_OP_LOOPTEST ||
					   in->op == SL_OP_ILLUMINANCE))
				for (int k = 0; k < in->nargs; k++)
					if (!reg_live[in->args[k]]) {
						reg_live[in->args[k]] = 1;
						changed = true;
					}
		}
	}
}

/* Keep the structure around kept instructions: openers, middles, closers. */
static void keep_structure(const struct sl_program *p, uint8_t *keep, const uint8_t *want)
{
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		if (!is_opener(in->op))
			continue;
		int32_t end = in->op == SL_OP_IF || in->op == SL_OP_LOOP ? in->jump[1] : in->jump[0];
		if (end < 0)
			continue;
		bool any = false;
		for (int32_t k = (int32_t)i + 1; k < end && !any; k++)
			any = keep[k] && !is_control(p->code[k].op);
		if (!any)
			continue;
		for (int32_t j = (int32_t)i; j <= end; j++)
			if (is_control(p->code[j].op) && (!want || want[j]))
				keep[j] = 1;
	}
}

/*
 * A kept break or continue whose loop is not kept, or return whose inlined
 * function is not, leaves nothing dynamic behind: the block it leaves runs
 * no dynamic code. Kept alone it would leave whatever encloses it instead
 * (a break outside any loop), so it is dropped.
 */
static void drop_orphan_exits(const struct sl_program *p, uint8_t *keep)
{
	uint32_t *open = rl_xmalloc((p->ncode + 1) * sizeof(uint32_t));
	uint32_t nopen = 0;
	for (uint32_t i = p->body_begin; i < p->ncode; i++) {
		int op = p->code[i].op;
		if (is_opener(op)) {
			open[nopen++] = i;
		} else if (is_closer(op)) {
			if (nopen)
				nopen--;
		} else if ((op == SL_OP_BREAK || op == SL_OP_CONTINUE) && keep[i]) {
			int levels = p->code[i].imm > 0 ? p->code[i].imm : 1;
			for (uint32_t k = nopen; k-- > 0;) {
				int o = p->code[open[k]].op;
				if ((o == SL_OP_LOOP || o == SL_OP_ILLUMINANCE) && --levels == 0) {
					if (!keep[open[k]])
						keep[i] = 0;
					break;
				}
			}
		} else if (op == SL_OP_RETURN && keep[i]) {
			for (uint32_t k = nopen; k-- > 0;)
				if (p->code[open[k]].op == SL_OP_FUNC) {
					if (!keep[open[k]])
						keep[i] = 0;
					break;
				}
		}
	}
	free(open);
}

/*
 * A copy of @prog with only the instructions @keep marks (blocks must be kept
 * or dropped whole, with their ELSE optional). Jumps are renumbered; a jump
 * to a dropped ELSE lands on its ENDIF; a parameter whose default code is
 * dropped gets an empty default. Registers and pools are shared with @prog.
 */
static struct sl_program *cut_program(const struct sl_program *prog, const uint8_t *keep)
{
	struct rl_arena *arena = rl_arena_create();
	struct sl_program *c = rl_arena_alloc(arena, sizeof(*c));
	*c = *prog;
	c->arena = arena;
	/* map[i]: index in the copy of the first kept instruction at or after i */
	int32_t *map = rl_xcalloc(prog->ncode + 1, sizeof(int32_t));
	uint32_t n = 0;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		map[i] = (int32_t)n;
		if (keep[i])
			n++;
	}
	map[prog->ncode] = (int32_t)n;
	c->code = rl_arena_alloc(arena, sizeof(struct sl_insn) * (n + 1));
	c->ncode = n;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		if (!keep[i])
			continue;
		struct sl_insn in = prog->code[i];
		for (int k = 0; k < 2; k++)
			if (in.jump[k] >= 0) {
				int32_t t = in.jump[k];
				while (t < (int32_t)prog->ncode && !keep[t])
					t = prog->code[t].op == SL_OP_ELSE ? prog->code[t].jump[1] : t + 1;
				in.jump[k] = map[t < (int32_t)prog->ncode ? t : (int32_t)prog->ncode];
			}
		c->code[map[i]] = in;
	}
	c->body_begin = (uint32_t)map[prog->body_begin < prog->ncode ? prog->body_begin : prog->ncode];
	c->params = rl_arena_alloc(arena, sizeof(struct sl_param) * (prog->nparams + 1));
	for (uint32_t k = 0; k < prog->nparams; k++) {
		c->params[k] = prog->params[k];
		c->params[k].init_begin = (uint32_t)map[prog->params[k].init_begin];
		c->params[k].init_end = (uint32_t)map[prog->params[k].init_end];
	}
	free(map);
	return c;
}

/*
 * The caching program: @prog's parameter code and its live static
 * instructions; structure kept where its condition is static, dropped (so
 * both sides run) where it is dynamic.
 */
static struct sl_program *make_caching(const struct sl_program *prog, const struct sl_spec *s)
{
	uint8_t *keep = rl_xcalloc(prog->ncode + 1, 1);
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (i < prog->body_begin)
			keep[i] = 1; /* parameter defaults */
		else if (!is_control(in->op))
			keep[i] = s->live[i] && !s->insn_dynamic[i];
	}
	/* structure with a static condition whose body keeps something */
	uint8_t *want = rl_xcalloc(prog->ncode + 1, 1);
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (!is_opener(in->op))
			continue;
		bool dyn_block = in->op == SL_OP_ILLUMINANCE || in->op == SL_OP_ILLUMINATE ||
				 in->op == SL_OP_SOLAR || s->insn_dynamic[i];
		int32_t end = in->op == SL_OP_IF || in->op == SL_OP_LOOP ? in->jump[1] : in->jump[0];
		if (in->op == SL_OP_LOOP && in->jump[0] >= 0 &&
		    s->reg_dynamic[prog->code[in->jump[0]].args[0]])
			dyn_block = true;
		if (end < 0 || dyn_block)
			continue;
		for (int32_t j = (int32_t)i; j <= end; j++)
			want[j] = 1;
	}
	/* breaks/continues/returns inside a dynamic block go with it */
	keep_structure(prog, keep, want);
	for (uint32_t i = 0; i < prog->ncode; i++) {
		int op = prog->code[i].op;
		if ((op == SL_OP_BREAK || op == SL_OP_CONTINUE || op == SL_OP_RETURN) && !want[i])
			keep[i] = 0;
	}
	free(want);

	struct sl_program *c = cut_program(prog, keep);
	free(keep);
	return c;
}

/*
 * The dynamic program: the kept instructions of the slice (what the GLSL
 * generator emits) over a copy of @prog's registers in which every cached
 * number is varying, so that samples from different grids (with different
 * uniform values) run side by side; what they feed is re-inferred. The
 * defaults of parameters that are not cached stay (a light's surface() may
 * read any parameter); cached ones come from the cache (sl_exec_hold).
 */
static struct sl_program *make_dynamic(const struct sl_program *prog, const struct sl_spec *s)
{
	uint8_t *is_cached = rl_xcalloc(prog->nregs + 1, 1);
	for (uint32_t k = 0; k < s->ncached; k++)
		is_cached[s->cached[k]] = 1;
	uint8_t *keep = rl_xcalloc(prog->ncode + 1, 1);
	for (uint32_t i = prog->body_begin; i < prog->ncode; i++)
		keep[i] = s->keep[i];
	for (uint32_t k = 0; k < prog->nparams; k++)
		if (!is_cached[prog->params[k].reg])
			for (uint32_t i = prog->params[k].init_begin; i < prog->params[k].init_end; i++)
				keep[i] = 1;
	struct sl_program *d = cut_program(prog, keep);
	free(keep);

	struct sl_reg *regs = rl_arena_alloc(d->arena, sizeof(struct sl_reg) * (prog->nregs + 1));
	memcpy(regs, prog->regs, sizeof(struct sl_reg) * prog->nregs);
	for (uint32_t r = 0; r < prog->nregs; r++) {
		if (regs[r].type == SL_TYPE_STRING)
			continue;
		if (is_cached[r])
			regs[r].varying = true;
		/* not source code: what a cached value feeds may become varying */
		regs[r].declared_uniform = false;
	}
	d->regs = regs;
	struct sl_options opts = { 0 };
	struct sl_ctx ctx;
	sl_ctx_init(&ctx, &opts);
	ctx.quiet = true;
	bool ok = sl_infer(&ctx, d);
	sl_ctx_finish(&ctx);
	if (!ok) {
		/* Some value must stay uniform (a texture channel, a name): keep
		 * the original uniformity, which the kept code already satisfies. */
		memcpy(regs, prog->regs, sizeof(struct sl_reg) * prog->nregs);
	}
	free(is_cached);
	return d;
}

/* Mark @r as needing its derivatives: varying values only (a uniform one's are 0). */
static void need_deriv(const struct sl_program *p, uint8_t *need, int32_t r, bool *changed)
{
	if (r >= 0 && p->regs[r].varying && !need[r]) {
		need[r] = 1;
		*changed = true;
	}
}

/*
 * cached_deriv: which cached values the dynamic program takes derivatives
 * through. The roots are the operands of the derivatives it takes
 * (deriv_operands) and, with SL_SPEC_LIGHT_DERIVATIVES, the positions it
 * runs the lights at (an illuminance statement's, the global P of the
 * lighting functions). From there backwards along data flow through the
 * instructions it runs (the kept ones and the defaults of parameters that
 * are not cached), including the implicit inputs of built-ins and the
 * position behind the lights' L, Cl and Ol, to the cached values.
 */
static void mark_derivatives(struct sl_spec *s, unsigned flags)
{
	const struct sl_program *p = s->prog;
	s->cached_deriv = rl_xcalloc(s->ncached + 1, 1);
	uint8_t *need = rl_xcalloc(p->nregs + 1, 1);
	uint8_t *runs = rl_xcalloc(p->ncode + 1, 1);
	uint8_t *is_cached = rl_xcalloc(p->nregs + 1, 1);
	for (uint32_t k = 0; k < s->ncached; k++)
		is_cached[s->cached[k]] = 1;
	for (uint32_t i = p->body_begin; i < p->ncode; i++)
		runs[i] = s->keep[i];
	for (uint32_t k = 0; k < p->nparams; k++)
		if (!is_cached[p->params[k].reg])
			for (uint32_t i = p->params[k].init_begin; i < p->params[k].init_end; i++)
				runs[i] = 1;

	int32_t gP = p->global_reg[SL_GLOBAL_P];
	bool changed = false;
	for (uint32_t i = 0; i < p->ncode; i++) {
		if (!runs[i])
			continue;
		const struct sl_insn *in = &p->code[i];
		int32_t r[2];
		int n = sl_spec_deriv_operands(p, in, r);
		for (int k = 0; k < n; k++)
			need_deriv(p, need, r[k], &changed);
		if (!(flags & SL_SPEC_LIGHT_DERIVATIVES))
			continue;
		if (in->op == SL_OP_ILLUMINANCE && in->imm >= 0 && in->imm < in->nargs)
			need_deriv(p, need, in->args[in->imm], &changed);
		if (in->op == SL_OP_CALL && in->bi >= 0 &&
		    (sl_builtins[in->bi].flags & SL_BIF_LIGHTS))
			need_deriv(p, need, gP, &changed);
	}

	int32_t light_out[3] = { p->global_reg[SL_GLOBAL_L], p->global_reg[SL_GLOBAL_CL],
				 p->global_reg[SL_GLOBAL_OL] };
	while (changed) {
		changed = false;
		bool lights = false;
		for (int g = 0; g < 3; g++)
			lights = lights || (light_out[g] >= 0 && need[light_out[g]]);
		for (uint32_t i = p->ncode; i-- > 0;) {
			if (!runs[i])
				continue;
			const struct sl_insn *in = &p->code[i];
			if (in->op == SL_OP_ILLUMINANCE) {
				/* L, Cl and Ol come from lights run at this position */
				if (lights && in->imm >= 0 && in->imm < in->nargs)
					need_deriv(p, need, in->args[in->imm], &changed);
				continue;
			}
			if (is_control(in->op))
				continue;
			bool want = in->dst >= 0 && need[in->dst];
			for (int k = 0; k < in->nargs; k++)
				if (arg_is_output(in, k) && need[in->args[k]])
					want = true;
			if (!want)
				continue;
			for (int k = 0; k < in->nargs; k++)
				if (!arg_is_output(in, k))
					need_deriv(p, need, in->args[k], &changed);
			if (in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET)
				need_deriv(p, need, in->dst, &changed);
			if (in->op != SL_OP_CALL || in->bi < 0)
				continue;
			/* the globals built-ins read without being given them */
			const struct sl_builtin *b = &sl_builtins[in->bi];
			if (b->flags & SL_BIF_LIGHTS)
				need_deriv(p, need, gP, &changed);
			else if (b->id == SL_BI_FACEFORWARD && in->nargs == 2)
				need_deriv(p, need, p->global_reg[SL_GLOBAL_NG], &changed);
			else if (b->id == SL_BI_TEXTURE && numeric_args(p, in, 2) < 2) {
				need_deriv(p, need, p->global_reg[SL_GLOBAL_S], &changed);
				need_deriv(p, need, p->global_reg[SL_GLOBAL_T], &changed);
			}
		}
	}
	for (uint32_t k = 0; k < s->ncached; k++)
		if (need[s->cached[k]]) {
			s->cached_deriv[k] = 1;
			s->needs_stencil = true;
		}
	free(need);
	free(runs);
	free(is_cached);
}

bool sl_ir_arg_is_output(const struct sl_insn *in, int k)
{
	return arg_is_output(in, k);
}

/* Arithmetic that a value computed from constants alone may be made of. */
static bool pure_op(int op)
{
	return (op >= SL_OP_MOV && op <= SL_OP_OR) || op == SL_OP_TRIPLE || op == SL_OP_MATRIX ||
	       op == SL_OP_COMP || op == SL_OP_SELECT;
}

/*
 * konst[r]: temporary or local @r holds one value, computed from constants
 * alone, wherever it is read: every write is pure arithmetic of constants
 * and such registers, outside any block but inlined functions that have not
 * returned yet (so it always runs). Inlined functions' constant arguments
 * and locals such as `float a = 0.5; ... a *= gain;` are of this kind.
 */
static uint8_t *constant_registers(const struct sl_program *p, const struct sl_spec *s)
{
	uint8_t *konst = rl_xcalloc(p->nregs + 1, 1);
	uint8_t *bad = rl_xcalloc(p->nregs + 1, 1);
	for (uint32_t r = 0; r < p->nregs; r++) {
		const struct sl_reg *rg = &p->regs[r];
		konst[r] = (rg->kind == SL_REG_TEMP || rg->kind == SL_REG_LOCAL) && !rg->arraylen &&
			   rg->type != SL_TYPE_STRING && !s->reg_dynamic[r];
	}
	/* Writes that are not at function level or not pure disqualify at once.
	 * The open blocks: 1 an inlined function, 2 any other; after a return,
	 * the rest of its function may not run (taint: that function's depth). */
	uint8_t *open = rl_xcalloc(p->ncode + 1, 1);
	uint32_t nopen = 0, blocks = 0, taint = UINT32_MAX;
	for (uint32_t i = 0; i < p->ncode; i++) {
		const struct sl_insn *in = &p->code[i];
		if (is_opener(in->op)) {
			open[nopen++] = in->op == SL_OP_FUNC ? 1 : 2;
			blocks += in->op != SL_OP_FUNC;
		} else if (is_closer(in->op) && nopen) {
			blocks -= open[--nopen] == 2;
			if (nopen <= taint)
				taint = UINT32_MAX;
		} else if (in->op == SL_OP_RETURN) {
			uint32_t f = nopen;
			while (f > 0 && open[f - 1] != 1)
				f--;
			if (f > 0 && f - 1 < taint)
				taint = f - 1;
		}
		if (is_control(in->op))
			continue;
		bool ok = i >= p->body_begin && blocks == 0 && taint == UINT32_MAX &&
			  pure_op(in->op);
		for (int k = 0; k < in->nargs; k++)
			if (arg_is_output(in, k)) {
				bad[in->args[k]] = 1;
				ok = false;
			}
		if (in->dst >= 0 && !ok)
			bad[in->dst] = 1;
	}
	free(open);
	for (uint32_t r = 0; r < p->nregs; r++)
		if (bad[r])
			konst[r] = 0;
	/* Then the arguments: a write reading a non-constant disqualifies. */
	bool changed = true;
	while (changed) {
		changed = false;
		for (uint32_t i = p->body_begin; i < p->ncode; i++) {
			const struct sl_insn *in = &p->code[i];
			if (in->dst < 0 || !konst[in->dst] || is_control(in->op))
				continue;
			for (int k = 0; k < in->nargs; k++) {
				int32_t a = in->args[k];
				if (p->regs[a].kind != SL_REG_CONST && !konst[a]) {
					konst[in->dst] = 0;
					changed = true;
					break;
				}
			}
		}
	}
	free(bad);
	return konst;
}

/*
 * The dynamic part computes the constants it reads again instead of caching
 * them: their writes join the slice (they stay in the caching program too).
 * A production shader's inlined helpers read many such values, each of
 * which would otherwise be a float per sample in the cache.
 */
static void recompute_constants(const struct sl_program *p, struct sl_spec *s, uint8_t *konst)
{
	/* The writes of each register, as lists through next[]; a worklist of
	 * the instructions newly kept. */
	int32_t *head = rl_xmalloc((p->nregs + 1) * sizeof(int32_t));
	int32_t *next = rl_xmalloc((p->ncode + 1) * sizeof(int32_t));
	uint32_t *work = rl_xmalloc((p->ncode + 1) * sizeof(uint32_t));
	for (uint32_t r = 0; r <= p->nregs; r++)
		head[r] = -1;
	uint32_t nwork = 0;
	for (uint32_t i = p->ncode; i-- > p->body_begin;) {
		int32_t d = p->code[i].dst;
		if (d >= 0 && konst[d]) {
			next[i] = head[d];
			head[d] = (int32_t)i;
		}
		if (s->keep[i])
			work[nwork++] = i;
	}
	while (nwork) {
		const struct sl_insn *in = &p->code[work[--nwork]];
		for (int k = 0; k < in->nargs; k++) {
			int32_t a = in->args[k];
			if (konst[a] != 1)
				continue;
			konst[a] = 2; /* recomputed */
			for (int32_t j = head[a]; j >= 0; j = next[j])
				if (!s->keep[j]) {
					s->keep[j] = 1;
					work[nwork++] = (uint32_t)j;
				}
		}
	}
	free(head);
	free(next);
	free(work);
}

static void add_unique(int32_t **v, uint32_t *n, int32_t r)
{
	for (uint32_t i = 0; i < *n; i++)
		if ((*v)[i] == r)
			return;
	(*v)[(*n)++] = r;
}

struct sl_spec *sl_specialize(const struct sl_program *prog, const char *const *dynamic_params,
			      size_t ndynamic, FILE *diag)
{
	return sl_specialize_ex(prog, dynamic_params, ndynamic, 0, diag);
}

struct sl_spec *sl_specialize_ex(const struct sl_program *prog, const char *const *dynamic_params,
				 size_t ndynamic, unsigned flags, FILE *diag)
{
	if (!diag)
		diag = stderr;
	if (prog->kind != SL_SHADER_SURFACE) {
		fprintf(diag, "%s: error: only surface shaders are specialized (light shaders are "
			"translated whole)\n", prog->source_path ? prog->source_path : prog->name);
		return NULL;
	}
	struct sl_spec *s = rl_xcalloc(1, sizeof(*s));
	s->prog = prog;
	s->insn_dynamic = rl_xcalloc(prog->ncode + 1, 1);
	s->live = rl_xcalloc(prog->ncode + 1, 1);
	s->reg_dynamic = rl_xcalloc(prog->nregs + 1, 1);
	bool ok = true;
	for (size_t i = 0; i < ndynamic; i++) {
		int k = sl_program_find_param(prog, dynamic_params[i]);
		if (k < 0) {
			fprintf(diag, "%s: error: shader '%s' has no parameter '%s'\n",
				prog->source_path ? prog->source_path : prog->name, prog->name,
				dynamic_params[i]);
			ok = false;
			continue;
		}
		s->reg_dynamic[prog->params[k].reg] = 1;
	}
	if (!ok) {
		sl_spec_destroy(s);
		return NULL;
	}
	static const enum sl_global light_globals[] = { SL_GLOBAL_L, SL_GLOBAL_CL, SL_GLOBAL_OL };
	for (size_t g = 0; g < 3; g++)
		if (prog->global_reg[light_globals[g]] >= 0)
			s->reg_dynamic[prog->global_reg[light_globals[g]]] = 1;

	struct state st = { .prog = prog, .s = s, .diag = diag };
	st.writes = rl_xcalloc(prog->nregs + 1, sizeof(uint32_t));
	st.block_dyn = rl_xcalloc(prog->ncode + 1, 1);
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (in->dst >= 0)
			st.writes[in->dst]++;
		for (int k = 0; k < in->nargs; k++)
			if (arg_is_output(in, k))
				st.writes[in->args[k]]++;
	}
	/* Parameter defaults of dynamic parameters are not part of the analysis:
	 * the parameter's register is dynamic from the start. */
	do {
		st.changed = false;
		dyn_pass(&st);
	} while (st.changed);

	/* Liveness from the outputs. */
	uint8_t *reg_live = rl_xcalloc(prog->nregs + 1, 1);
	int32_t ci = prog->global_reg[SL_GLOBAL_CI], oi = prog->global_reg[SL_GLOBAL_OI];
	if (ci >= 0)
		reg_live[ci] = 1;
	if (oi >= 0)
		reg_live[oi] = 1;
	for (uint32_t k = 0; k < prog->nparams; k++)
		if (prog->params[k].output)
			reg_live[prog->params[k].reg] = 1;
	liveness(&st, reg_live);

	/* Cache-required: light-dependent operations the GPU cannot run. */
	s->cache_required = rl_xcalloc(prog->ncode + 1, sizeof(uint32_t));
	for (uint32_t i = prog->body_begin; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		if (!s->live[i] || !gpu_cannot(prog, in))
			continue;
		bool dyn_input = false;
		for (int k = 0; k < in->nargs; k++)
			if (!arg_is_output(in, k) && s->reg_dynamic[in->args[k]])
				dyn_input = true;
		if (dyn_input)
			s->cache_required[s->ncache_required++] = i;
	}

	/* The dynamic slice. */
	s->keep = rl_xcalloc(prog->ncode + 1, 1);
	for (uint32_t i = prog->body_begin; i < prog->ncode; i++)
		if (!is_control(prog->code[i].op))
			s->keep[i] = s->live[i] && s->insn_dynamic[i];
	keep_structure(prog, s->keep, NULL);
	for (uint32_t i = prog->body_begin; i < prog->ncode; i++) {
		int op = prog->code[i].op;
		if ((op == SL_OP_BREAK || op == SL_OP_CONTINUE || op == SL_OP_RETURN) && s->live[i])
			s->keep[i] = 1;
	}
	/* A kept break/continue/return needs its blocks. */
	keep_structure(prog, s->keep, NULL);
	uint8_t *konst = constant_registers(prog, s);
	recompute_constants(prog, s, konst);
	keep_structure(prog, s->keep, NULL);
	drop_orphan_exits(prog, s->keep);

	s->cached = rl_xcalloc(prog->nregs + 1, sizeof(int32_t));
	s->outputs = rl_xcalloc(prog->nregs + 1, sizeof(int32_t));
	uint32_t nout = 0;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		if (!s->keep[i])
			continue;
		const struct sl_insn *in = &prog->code[i];
		for (int k = 0; k < in->nargs; k++) {
			int32_t r = in->args[k];
			const struct sl_reg *reg = &prog->regs[r];
			if (arg_is_output(in, k) || s->reg_dynamic[r] || reg->kind == SL_REG_CONST ||
			    konst[r])
				continue;
			/* uniform parameters the body never writes stay uniforms */
			if (reg->kind == SL_REG_PARAM && !reg->varying && st.writes[r] <= 1 &&
			    !(flags & SL_SPEC_CACHE_PARAMS))
				continue;
			add_unique(&s->cached, &s->ncached, r);
		}
		if ((in->op == SL_OP_SETCOMP || in->op == SL_OP_ASET) && !s->reg_dynamic[in->dst] &&
		    prog->regs[in->dst].kind != SL_REG_CONST)
			add_unique(&s->cached, &s->ncached, in->dst);
		/* Built-ins that read globals they are not given: the lighting
		 * functions read P; faceforward(N, I) reads Ng; texture() with no
		 * coordinates reads s and t. Those globals are inputs too. */
		if (in->op == SL_OP_CALL && in->bi >= 0) {
			const struct sl_builtin *b = &sl_builtins[in->bi];
			enum sl_global implicit[2];
			int ni = 0;
			if (b->flags & SL_BIF_LIGHTS)
				implicit[ni++] = SL_GLOBAL_P;
			else if (b->id == SL_BI_FACEFORWARD && in->nargs == 2)
				implicit[ni++] = SL_GLOBAL_NG;
			else if (b->id == SL_BI_TEXTURE && in->nargs <= 2) {
				implicit[ni++] = SL_GLOBAL_S;
				implicit[ni++] = SL_GLOBAL_T;
			}
			for (int g = 0; g < ni; g++) {
				int32_t r = prog->global_reg[implicit[g]];
				if (r >= 0 && !s->reg_dynamic[r])
					add_unique(&s->cached, &s->ncached, r);
			}
		}
	}
	/* The light host gives the lights the surface's E, time and dtime (when both
	 * shaders have them): where the kept code runs lights, they are inputs. */
	bool runs_lights = false, axisless = false;
	for (uint32_t i = 0; i < prog->ncode; i++) {
		const struct sl_insn *in = &prog->code[i];
		/* An illuminance without an axis gives the lights the surface's N as Ns. */
		if (s->keep[i] && in->op == SL_OP_ILLUMINANCE && in->nargs == (uint32_t)in->imm + 1)
			axisless = true;
		if (s->keep[i] && (in->op == SL_OP_ILLUMINANCE ||
				   (in->op == SL_OP_CALL && in->bi >= 0 &&
				    (sl_builtins[in->bi].flags & SL_BIF_LIGHTS))))
			runs_lights = true;
	}
	static const enum sl_global shared_globals[] = {
		SL_GLOBAL_E, SL_GLOBAL_TIME, SL_GLOBAL_DTIME, SL_GLOBAL_N,
	};
	for (size_t g = 0; g < 4 && runs_lights; g++) {
		int32_t r = prog->global_reg[shared_globals[g]];
		if (r >= 0 && !s->reg_dynamic[r] && (g < 3 || axisless))
			add_unique(&s->cached, &s->ncached, r);
	}
	/* Outputs: Ci and Oi always (static ones pass their cached value through),
	 * dynamic output parameters. */
	if (ci >= 0) {
		s->outputs[nout++] = ci;
		if (!s->reg_dynamic[ci])
			add_unique(&s->cached, &s->ncached, ci);
	}
	if (oi >= 0) {
		s->outputs[nout++] = oi;
		if (!s->reg_dynamic[oi])
			add_unique(&s->cached, &s->ncached, oi);
	}
	for (uint32_t k = 0; k < prog->nparams; k++)
		if (prog->params[k].output && s->reg_dynamic[prog->params[k].reg])
			s->outputs[nout++] = prog->params[k].reg;

	for (uint32_t i = prog->body_begin; i < prog->ncode; i++) {
		if (is_control(prog->code[i].op))
			continue;
		if (!s->live[i])
			s->ndead++;
		else if (s->insn_dynamic[i])
			s->ndynamic++;
		else
			s->nstatic++;
	}
	s->slice.prog = prog;
	s->slice.keep = s->keep;
	s->slice.inputs = s->cached;
	s->slice.ninputs = s->ncached;
	s->slice.outputs = s->outputs;
	s->slice.noutputs = nout;
	s->caching = make_caching(prog, s);
	s->dynamic = make_dynamic(prog, s);
	mark_derivatives(s, flags);

	free(konst);
	free(reg_live);
	free(st.writes);
	free(st.block_dyn);
	rl_vec_free(st.stack);
	return s;
}

void sl_spec_destroy(struct sl_spec *s)
{
	if (!s)
		return;
	free(s->insn_dynamic);
	free(s->live);
	free(s->reg_dynamic);
	free(s->cached);
	free(s->cached_deriv);
	free(s->cache_required);
	free(s->keep);
	free(s->outputs);
	if (s->caching)
		rl_arena_destroy(s->caching->arena);
	if (s->dynamic)
		rl_arena_destroy(s->dynamic->arena);
	free(s);
}

char *sl_spec_report_fields(const struct sl_spec *s, const char *const *dynamic_params,
			    size_t ndynamic, long glsl_lines)
{
	const struct sl_program *p = s->prog;
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, "\"dynamic_params\": [");
	for (size_t i = 0; i < ndynamic; i++) {
		if (i)
			rl_strbuf_puts(&b, ", ");
		rl_strbuf_json_string(&b, dynamic_params[i]);
	}
	rl_strbuf_puts(&b, "],\n  \"cached_channels\": [");
	uint32_t scalars = 0;
	for (uint32_t k = 0; k < s->ncached; k++) {
		const struct sl_reg *r = &p->regs[s->cached[k]];
		int comps = sl_reg_ncomp(r) * (r->arraylen ? r->arraylen : 1);
		scalars += (uint32_t)comps;
		rl_strbuf_printf(&b, "%s\n    {\"name\": ", k ? "," : "");
		if (r->name)
			rl_strbuf_json_string(&b, r->name);
		else
			rl_strbuf_printf(&b, "\"t%d\"", s->cached[k]);
		rl_strbuf_printf(&b, ", \"type\": \"%s\", \"components\": %d}",
				 sl_basetype_name(r->type), comps);
	}
	rl_strbuf_printf(&b, "\n  ],\n  \"cached_scalars\": %u,\n  \"cache_required\": [", scalars);
	for (uint32_t k = 0; k < s->ncache_required; k++) {
		const struct sl_insn *in = &p->code[s->cache_required[k]];
		const char *file = in->loc.file < p->nfiles ? p->files[in->loc.file] : "?";
		rl_strbuf_printf(&b, "%s{\"builtin\": \"%s\", \"location\": ", k ? ", " : "",
				 in->bi >= 0 ? sl_builtins[in->bi].name : "?");
		char loc[512];
		snprintf(loc, sizeof(loc), "%s:%u:%u", file, in->loc.line, in->loc.col);
		rl_strbuf_json_string(&b, loc);
		rl_strbuf_putc(&b, '}');
	}
	rl_strbuf_printf(&b, "],\n  \"static_instructions\": %u,\n  \"dynamic_instructions\": %u,"
			 "\n  \"dead_instructions\": %u,\n  \"glsl_lines\": ",
			 s->nstatic, s->ndynamic, s->ndead);
	if (glsl_lines >= 0)
		rl_strbuf_printf(&b, "%ld", glsl_lines);
	else
		rl_strbuf_puts(&b, "null");
	char *out = rl_xstrdup(rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return out;
}

/* ------------------------------------------------------------------------ */
/* Running the dynamic program                                               */

/* Floats per sample of a cached register (strings: none, they are pointers). */
static uint32_t cache_floats(const struct sl_reg *r)
{
	if (r->type == SL_TYPE_STRING)
		return 0;
	return (uint32_t)sl_reg_ncomp(r) * (uint32_t)(r->arraylen > 0 ? r->arraylen : 1);
}

uint32_t sl_spec_cache_layout(const struct sl_spec *s, uint32_t *offset)
{
	uint32_t at = 0;
	for (uint32_t k = 0; k < s->ncached; k++) {
		if (offset)
			offset[k] = at;
		at += cache_floats(&s->prog->regs[s->cached[k]]);
	}
	return at;
}

/* @x runs s->dynamic over @n samples, every cached register held. */
static bool dynamic_ready(const struct sl_spec *s, struct sl_exec *x, uint32_t n)
{
	if (!s || !x || x->prog != s->dynamic) {
		fprintf(stderr, "%s: error: not an executor of the shader's dynamic program\n",
			s ? s->prog->name : "?");
		return false;
	}
	if (n == 0 || !sl_exec_set_grid(x, n, 1)) {
		fprintf(stderr, "%s: error: %u samples do not fit the executor (%u points)\n",
			s->prog->name, n, x->maxn);
		return false;
	}
	for (uint32_t k = 0; k < s->ncached; k++)
		sl_exec_hold(x, s->cached[k], true);
	return true;
}

bool sl_spec_bind_cache(const struct sl_spec *s, struct sl_exec *x, uint32_t n,
			const float *records, uint32_t stride, const uint32_t *offset)
{
	if (!dynamic_ready(s, x, n))
		return false;
	uint32_t packed = 0;
	for (uint32_t k = 0; k < s->ncached; k++) {
		int32_t r = s->cached[k];
		uint32_t nf = cache_floats(&s->prog->regs[r]);
		uint32_t off = offset ? offset[k] : packed;
		packed += nf;
		if (!nf)
			continue;
		if (!records || (uint64_t)off + nf > stride) {
			fprintf(stderr, "%s: error: cached value %u lies outside the %u-float records\n",
				s->prog->name, k, stride);
			return false;
		}
		float *d = x->data[r];
		if (!s->dynamic->regs[r].varying) {
			memcpy(d, records + off, nf * sizeof(float));
			continue;
		}
		for (uint32_t c = 0; c < nf; c++)
			for (uint32_t i = 0; i < n; i++)
				d[(size_t)c * x->stride + i] = records[(size_t)i * stride + off + c];
	}
	return true;
}

bool sl_spec_copy_cache(const struct sl_spec *s, struct sl_exec *x, const struct sl_exec *from,
			const uint32_t *order, uint32_t n)
{
	if (!s || !from || (from->prog != s->caching && from->prog != s->prog)) {
		fprintf(stderr, "%s: error: the cache comes from an executor of the caching program "
			"or of the shader\n", s ? s->prog->name : "?");
		return false;
	}
	for (uint32_t j = 0; order && j < n; j++)
		if (order[j] >= from->n) {
			fprintf(stderr, "%s: error: sample %u is not on the cached grid (%u points)\n",
				s->prog->name, order[j], from->n);
			return false;
		}
	if (!dynamic_ready(s, x, n))
		return false;
	for (uint32_t k = 0; k < s->ncached; k++) {
		int32_t r = s->cached[k];
		const struct sl_reg *rg = &s->prog->regs[r];
		bool fv = from->prog->regs[r].varying, xv = s->dynamic->regs[r].varying;
		uint32_t tot = (uint32_t)(rg->arraylen > 0 ? rg->arraylen : 1) *
			       (rg->type == SL_TYPE_STRING ? 1u : (uint32_t)sl_reg_ncomp(rg));
		for (uint32_t c = 0; c < tot; c++)
			for (uint32_t j = 0; j < (xv ? n : 1); j++) {
				uint32_t i = order ? order[j] : j;
				size_t src = fv ? (size_t)c * from->stride + i : c;
				size_t dst = xv ? (size_t)c * x->stride + j : c;
				if (rg->type == SL_TYPE_STRING)
					x->sdata[r][dst] = from->sdata[r][src];
				else
					x->data[r][dst] = from->data[r][src];
			}
	}
	return true;
}

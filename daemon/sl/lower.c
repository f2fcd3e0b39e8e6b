/*
 * Lowering: a checked shader to the IR of ir.h.
 *
 * Every variable becomes a register, every expression a few instructions
 * writing a temporary. User functions are inlined at each call: a frame maps
 * the function's symbols to this call's registers; non-output formals are
 * copies, output formals alias the caller's variables. Frames chain to the
 * caller, so a nested function finds its enclosing function's variables.
 * Control flow stays structured: every opener is patched with the index of
 * its closer.
 */
#include "sema.h"
#include "builtin.h"

#include <stdlib.h>
#include <string.h>

#define MAX_CODE (1u << 20)     /* instructions after inlining */
#define MAX_INLINE_DEPTH 64

struct binding {
	struct sl_sym *sym;
	int32_t reg;
};

struct frame {
	struct frame *caller;
	RL_VEC(struct binding) vars;
	int32_t ret;            /* register of the return value, or -1 */
	bool ret_block;         /* returns go through FUNC/RETURN/FUNCEND */
};

struct lower {
	struct sl_ctx *ctx;
	RL_VEC(struct sl_reg) regs;
	RL_VEC(struct sl_insn) code;
	RL_VEC(float) consts;
	RL_VEC(const char *) strings;
	int32_t global_reg[SL_GLOBAL_COUNT];
	struct frame *frame;
	int inline_depth;
	bool overflow;          /* too much code: reported once */
	/* constant registers by value: open addressing, key = bits or pointer */
	struct const_slot { uint64_t key; int32_t reg; } *cslots;
	size_t ccap, ccount;
	struct sl_loc loc;      /* location of the statement being lowered */
	/* Lowering a value stored into a variable declared uniform: random()
	 * there is one value for the grid, as in prman. */
	bool uniform_ctx;
	RL_VEC(struct sl_uniform_ref) urefs;
	enum sl_shader_kind kind;
};

static const char *const global_names[SL_GLOBAL_COUNT] = {
	[SL_GLOBAL_P] = "P", [SL_GLOBAL_N] = "N", [SL_GLOBAL_NG] = "Ng", [SL_GLOBAL_I] = "I",
	[SL_GLOBAL_E] = "E", [SL_GLOBAL_CS] = "Cs", [SL_GLOBAL_OS] = "Os", [SL_GLOBAL_CI] = "Ci",
	[SL_GLOBAL_OI] = "Oi", [SL_GLOBAL_S] = "s", [SL_GLOBAL_T] = "t", [SL_GLOBAL_U] = "u",
	[SL_GLOBAL_V] = "v", [SL_GLOBAL_DU] = "du", [SL_GLOBAL_DV] = "dv",
	[SL_GLOBAL_DPDU] = "dPdu", [SL_GLOBAL_DPDV] = "dPdv", [SL_GLOBAL_L] = "L",
	[SL_GLOBAL_CL] = "Cl", [SL_GLOBAL_OL] = "Ol", [SL_GLOBAL_PS] = "Ps",
	[SL_GLOBAL_NCOMPS] = "ncomps", [SL_GLOBAL_TIME] = "time", [SL_GLOBAL_DTIME] = "dtime",
	[SL_GLOBAL_DPDTIME] = "dPdtime", [SL_GLOBAL_ALPHA] = "alpha",
	[SL_GLOBAL_NS] = "Ns",
};

const char *sl_global_name(enum sl_global g)
{
	return (unsigned)g < SL_GLOBAL_COUNT ? global_names[g] : "?";
}

struct sl_type sl_global_type(enum sl_global g)
{
	struct sl_type t = { SL_TYPE_VECTOR, SL_DETAIL_VARYING, -1 };
	switch (g) {
	case SL_GLOBAL_P: case SL_GLOBAL_PS: t.base = SL_TYPE_POINT; break;
	case SL_GLOBAL_E: t.base = SL_TYPE_POINT; t.detail = SL_DETAIL_UNIFORM; break;
	case SL_GLOBAL_N: case SL_GLOBAL_NG: case SL_GLOBAL_NS: t.base = SL_TYPE_NORMAL; break;
	case SL_GLOBAL_CS: case SL_GLOBAL_OS: case SL_GLOBAL_CI: case SL_GLOBAL_OI:
	case SL_GLOBAL_CL: case SL_GLOBAL_OL: t.base = SL_TYPE_COLOR; break;
	case SL_GLOBAL_S: case SL_GLOBAL_T: case SL_GLOBAL_U: case SL_GLOBAL_V:
	case SL_GLOBAL_ALPHA:
		t.base = SL_TYPE_FLOAT; break;
	case SL_GLOBAL_DU: case SL_GLOBAL_DV: case SL_GLOBAL_NCOMPS: case SL_GLOBAL_TIME:
	case SL_GLOBAL_DTIME:
		t.base = SL_TYPE_FLOAT; t.detail = SL_DETAIL_UNIFORM; break;
	default: break; /* I, dPdu, dPdv, L, dPdtime: varying vectors */
	}
	return t;
}

/* ---- registers and instructions ---- */

static int32_t new_reg(struct lower *l, int base, int32_t arraylen, enum sl_reg_kind kind,
		       const char *name, struct sl_loc loc)
{
	struct sl_reg r = { 0 };
	r.kind = (uint8_t)kind;
	r.type = (uint8_t)(base == SL_TYPE_VOID ? SL_TYPE_FLOAT : base);
	r.arraylen = arraylen > 0 ? arraylen : 0;
	r.global = -1;
	r.name = name;
	r.loc = loc;
	rl_vec_push(l->regs, r);
	return (int32_t)(l->regs.len - 1);
}

static int32_t temp(struct lower *l, int base)
{
	return new_reg(l, base, 0, SL_REG_TEMP, NULL, l->loc);
}

static struct sl_insn *emit(struct lower *l, enum sl_op op, int32_t dst, int nargs)
{
	if (l->code.len >= MAX_CODE) {
		if (!l->overflow)
			sl_error(l->ctx, l->loc,
				 "shader is too large after inlining functions (over %u "
				 "instructions)", MAX_CODE);
		l->overflow = true;
		l->ctx->too_many = true;
		l->code.len = 0; /* keep going harmlessly; the result is discarded */
	}
	struct sl_insn in = { 0 };
	in.op = (uint16_t)op;
	in.dst = dst;
	in.bi = -1;
	in.jump[0] = in.jump[1] = -1;
	in.nargs = (uint16_t)nargs;
	in.args = nargs ? rl_arena_alloc(l->ctx->arena, sizeof(int32_t) * (size_t)nargs) : NULL;
	in.loc = l->loc;
	rl_vec_push(l->code, in);
	return &l->code.data[l->code.len - 1];
}

static int32_t here(struct lower *l)
{
	return (int32_t)l->code.len;
}

static int32_t emit1(struct lower *l, enum sl_op op, int32_t dst, int32_t a)
{
	struct sl_insn *in = emit(l, op, dst, 1);
	in->args[0] = a;
	return dst;
}

static int32_t emit2(struct lower *l, enum sl_op op, int32_t dst, int32_t a, int32_t b)
{
	struct sl_insn *in = emit(l, op, dst, 2);
	in->args[0] = a;
	in->args[1] = b;
	return dst;
}

/* Find the slot of @key in the constant table (growing it as needed). */
static struct const_slot *const_slot(struct lower *l, uint64_t key)
{
	if (l->ccount * 2 >= l->ccap) {
		size_t ncap = l->ccap ? l->ccap * 2 : 64;
		struct const_slot *ns = rl_xcalloc(ncap, sizeof(*ns));
		for (size_t i = 0; i < l->ccap; i++) {
			if (!l->cslots[i].reg)
				continue;
			size_t j = (l->cslots[i].key * 0x9e3779b97f4a7c15ull >> 20) & (ncap - 1);
			while (ns[j].reg)
				j = (j + 1) & (ncap - 1);
			ns[j] = l->cslots[i];
		}
		free(l->cslots);
		l->cslots = ns;
		l->ccap = ncap;
	}
	size_t j = (key * 0x9e3779b97f4a7c15ull >> 20) & (l->ccap - 1);
	while (l->cslots[j].reg && l->cslots[j].key != key)
		j = (j + 1) & (l->ccap - 1);
	return &l->cslots[j];
}

/* Constants are shared: shaders repeat 0, 1, 0.5... (slot.reg holds reg + 1). */
static int32_t const_float(struct lower *l, float v)
{
	uint32_t bits;
	memcpy(&bits, &v, sizeof(bits));
	struct const_slot *slot = const_slot(l, (uint64_t)bits | (1ull << 40));
	if (slot->reg)
		return slot->reg - 1;
	int32_t r = new_reg(l, SL_TYPE_FLOAT, 0, SL_REG_CONST, NULL, l->loc);
	l->regs.data[r].cindex = (uint32_t)l->consts.len;
	rl_vec_push(l->consts, v);
	slot->key = (uint64_t)bits | (1ull << 40);
	slot->reg = r + 1;
	l->ccount++;
	return r;
}

static int32_t const_string(struct lower *l, const char *s)
{
	s = sl_intern_cstr(l->ctx, s);
	uint64_t key = (uint64_t)(uintptr_t)s | (1ull << 63);
	struct const_slot *slot = const_slot(l, key);
	if (slot->reg)
		return slot->reg - 1;
	int32_t r = new_reg(l, SL_TYPE_STRING, 0, SL_REG_CONST, NULL, l->loc);
	l->regs.data[r].cindex = (uint32_t)l->strings.len;
	rl_vec_push(l->strings, s);
	slot->key = key;
	slot->reg = r + 1;
	l->ccount++;
	return r;
}

/*
 * Whether a volume shader sees global @g (RISpec 3.2 Table 4.4): the ray,
 * its colour and opacity, the lights inside illuminance, time. It is not
 * attached to a surface, so the surface's geometry (N, s, t, Cs...) is not
 * there to read.
 */
static bool volume_global(enum sl_global g)
{
	switch (g) {
	case SL_GLOBAL_P: case SL_GLOBAL_I: case SL_GLOBAL_E: case SL_GLOBAL_CI:
	case SL_GLOBAL_OI: case SL_GLOBAL_L: case SL_GLOBAL_CL: case SL_GLOBAL_OL:
	case SL_GLOBAL_NCOMPS: case SL_GLOBAL_TIME: case SL_GLOBAL_DTIME:
	case SL_GLOBAL_DU: case SL_GLOBAL_DV:
		return true;
	default:
		return false;
	}
}

static int32_t global(struct lower *l, enum sl_global g)
{
	if (l->global_reg[g] < 0) {
		if (l->kind == SL_SHADER_VOLUME && !volume_global(g))
			sl_error(l->ctx, l->loc, "'%s' is not available in a volume shader (it "
				 "sees P, I, E, Ci, Oi, time, and L, Cl inside illuminance)",
				 sl_global_name(g));
		struct sl_type t = sl_global_type(g);
		struct sl_loc none = { 0 };
		int32_t r = new_reg(l, t.base, 0, SL_REG_GLOBAL,
				    sl_intern_cstr(l->ctx, sl_global_name(g)), none);
		l->regs.data[r].global = g;
		l->regs.data[r].varying = t.detail == SL_DETAIL_VARYING;
		l->global_reg[g] = r;
	}
	return l->global_reg[g];
}

static int reg_type(struct lower *l, int32_t r)
{
	return l->regs.data[r].type;
}

/* ---- symbols ---- */

static void bind(struct lower *l, struct sl_sym *sym, int32_t reg)
{
	struct binding b = { sym, reg };
	rl_vec_push(l->frame->vars, b);
}

static int32_t sym_reg(struct lower *l, struct sl_sym *sym)
{
	if (sym->kind == SL_SYM_GLOBAL)
		return global(l, (enum sl_global)sym->global);
	for (struct frame *f = l->frame; f; f = f->caller)
		for (size_t i = f->vars.len; i-- > 0;)
			if (f->vars.data[i].sym == sym)
				return f->vars.data[i].reg;
	sl_error(l->ctx, l->loc, "'%s' is not visible here (a function uses a variable of "
		 "a function that is not calling it)", sym->name);
	return const_float(l, 0);
}

/* ---- expressions ---- */

static int32_t lower_expr(struct lower *l, struct sl_ast *e);
static void lower_stmt(struct lower *l, struct sl_ast *st);

/* Make @r usable where @to is expected (float promoted into a new triple/matrix). */
static int32_t coerce(struct lower *l, int32_t r, struct sl_type to)
{
	int from = reg_type(l, r);
	if (to.arraylen >= 0 || to.base == SL_TYPE_VOID)
		return r;
	int tb = to.base;
	if (sl_type_ncomp(from) == sl_type_ncomp(tb) &&
	    (from == SL_TYPE_STRING) == (tb == SL_TYPE_STRING))
		return r;
	if ((from == SL_TYPE_FLOAT || from == SL_TYPE_BOOL) &&
	    (sl_type_is_triple(tb) || tb == SL_TYPE_MATRIX))
		return emit1(l, SL_OP_MOV, temp(l, tb), r);
	return r;
}

/* Ops that may write a register they also read (componentwise, no reordering). */
static bool alias_safe(const struct lower *l, const struct sl_insn *in)
{
	switch (in->op) {
	case SL_OP_MOV: case SL_OP_NEG: case SL_OP_ADD: case SL_OP_SUB:
	case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE: case SL_OP_EQ: case SL_OP_NE:
	case SL_OP_NOT: case SL_OP_AND: case SL_OP_OR: case SL_OP_SELECT:
		return l->regs.data[in->dst].type != SL_TYPE_MATRIX ||
		       in->op == SL_OP_MOV || in->op == SL_OP_ADD || in->op == SL_OP_SUB ||
		       in->op == SL_OP_NEG;
	case SL_OP_MUL: case SL_OP_DIV:
		return l->regs.data[in->dst].type != SL_TYPE_MATRIX;
	default:
		return false;
	}
}

/*
 * Store @val into the variable register @dst (MOV handles promotions). When
 * @val is a temporary the last instruction just made, that instruction
 * writes @dst instead: one pass over the grid less.
 */
static void store(struct lower *l, int32_t dst, int32_t val)
{
	if (dst == val)
		return;
	if (l->code.len && !l->overflow) {
		struct sl_insn *last = &l->code.data[l->code.len - 1];
		const struct sl_reg *t = &l->regs.data[val];
		const struct sl_reg *d = &l->regs.data[dst];
		if (last->dst == val && t->kind == SL_REG_TEMP && alias_safe(l, last) &&
		    t->arraylen == 0 && d->arraylen == 0 && sl_type_ncomp(t->type) == sl_type_ncomp(d->type) &&
		    (t->type == SL_TYPE_STRING) == (d->type == SL_TYPE_STRING)) {
			last->dst = dst;
			return;
		}
	}
	emit1(l, SL_OP_MOV, dst, val);
}

/* Does evaluating @e write anything? (The left operand is followed in a
 * loop: a flat chain of ten thousand terms is not that many frames.) */
static bool has_side_effects(const struct sl_ast *e)
{
	for (; e; e = e->a) {
		switch (e->kind) {
		case SL_AST_ASSIGN:
		case SL_AST_INCDEC:
			return true;
		case SL_AST_CALL:
			if (e->overload < 0)
				return true; /* user functions */
			if (sl_builtins[e->overload].flags & SL_BIF_SIDE_EFFECT)
				return true;
			if (strchr(sl_builtins[e->overload].sig, '&'))
				return true;
			break;
		default:
			break;
		}
		if (has_side_effects(e->b) || has_side_effects(e->c))
			return true;
		for (uint32_t i = 0; i < e->nlist; i++)
			if (has_side_effects(e->list[i]))
				return true;
	}
	return false;
}

static enum sl_op binop(int tok)
{
	switch (tok) {
	case SL_TOK_PLUS: case SL_TOK_PLUS_ASSIGN: return SL_OP_ADD;
	case SL_TOK_MINUS: case SL_TOK_MINUS_ASSIGN: return SL_OP_SUB;
	case SL_TOK_STAR: case SL_TOK_STAR_ASSIGN: return SL_OP_MUL;
	case SL_TOK_SLASH: case SL_TOK_SLASH_ASSIGN: return SL_OP_DIV;
	case SL_TOK_DOT: return SL_OP_DOT;
	case SL_TOK_CARET: return SL_OP_CROSS;
	case SL_TOK_LT: return SL_OP_LT;
	case SL_TOK_LE: return SL_OP_LE;
	case SL_TOK_GT: return SL_OP_GT;
	case SL_TOK_GE: return SL_OP_GE;
	case SL_TOK_EQ: return SL_OP_EQ;
	case SL_TOK_NE: return SL_OP_NE;
	case SL_TOK_AND: return SL_OP_AND;
	case SL_TOK_OR: return SL_OP_OR;
	default: return SL_OP_NOP;
	}
}

/* Open an IF on @cond; returns its index for close_if(). */
static int32_t open_if(struct lower *l, int32_t cond)
{
	int32_t at = here(l);
	emit1(l, SL_OP_IF, -1, cond);
	return at;
}

static int32_t add_else(struct lower *l, int32_t if_at)
{
	int32_t at = here(l);
	struct sl_insn *in = emit(l, SL_OP_ELSE, -1, 0);
	in->jump[0] = if_at;
	if (!l->overflow)
		l->code.data[if_at].jump[0] = at;
	return at;
}

static void close_if(struct lower *l, int32_t if_at, int32_t else_at)
{
	int32_t at = here(l);
	struct sl_insn *in = emit(l, SL_OP_ENDIF, -1, 0);
	in->jump[0] = if_at;
	if (l->overflow)
		return;
	if (else_at < 0)
		l->code.data[if_at].jump[0] = at;
	else
		l->code.data[else_at].jump[1] = at;
	l->code.data[if_at].jump[1] = at;
}

/* a && b, a || b: both sides computed when the right one has no side effects. */
/* a && b, a || b, with @a (the left operand) already lowered. */
static int32_t lower_logic(struct lower *l, struct sl_ast *e, int32_t a)
{
	if (!has_side_effects(e->b)) {
		int32_t b = lower_expr(l, e->b);
		return emit2(l, binop(e->op), temp(l, SL_TYPE_BOOL), a, b);
	}
	int32_t r = temp(l, SL_TYPE_BOOL);
	emit1(l, SL_OP_MOV, r, a);
	int32_t cond = r;
	if (e->op == SL_TOK_OR)
		cond = emit1(l, SL_OP_NOT, temp(l, SL_TYPE_BOOL), r);
	int32_t at = open_if(l, cond);
	int32_t b = lower_expr(l, e->b);
	emit1(l, SL_OP_MOV, r, b);
	close_if(l, at, -1);
	return r;
}

static int32_t lower_cond(struct lower *l, struct sl_ast *e)
{
	int32_t c = lower_expr(l, e->a);
	struct sl_type t = e->ty;
	if (!has_side_effects(e->b) && !has_side_effects(e->c)) {
		int32_t a = coerce(l, lower_expr(l, e->b), t);
		int32_t b = coerce(l, lower_expr(l, e->c), t);
		struct sl_insn *in = emit(l, SL_OP_SELECT, temp(l, t.base), 3);
		in->args[0] = c;
		in->args[1] = a;
		in->args[2] = b;
		return in->dst;
	}
	int32_t r = temp(l, t.base);
	int32_t at = open_if(l, c);
	store(l, r, lower_expr(l, e->b));
	int32_t el = add_else(l, at);
	store(l, r, lower_expr(l, e->c));
	close_if(l, at, el);
	return r;
}

static int32_t lower_index(struct lower *l, struct sl_ast *e)
{
	int32_t arr = lower_expr(l, e->a);
	int32_t idx = lower_expr(l, e->b);
	return emit2(l, SL_OP_AREF, temp(l, e->ty.base), arr, idx);
}

/* An lvalue: a variable's register, or an array element (reg + index). */
struct lval {
	int32_t reg;
	int32_t index;  /* -1 for a whole variable */
};

static struct lval lower_lval(struct lower *l, struct sl_ast *e)
{
	struct lval v = { -1, -1 };
	if (e->kind == SL_AST_IDENT) {
		v.reg = sym_reg(l, e->sym);
	} else {
		v.reg = sym_reg(l, e->a->sym);
		v.index = lower_expr(l, e->b);
	}
	return v;
}

static int32_t load_lval(struct lower *l, struct lval v, int base)
{
	if (v.index < 0)
		return v.reg;
	return emit2(l, SL_OP_AREF, temp(l, base), v.reg, v.index);
}

static void store_lval(struct lower *l, struct lval v, int32_t val)
{
	if (v.index < 0)
		store(l, v.reg, val);
	else
		emit2(l, SL_OP_ASET, v.reg, val, v.index);
}

static int32_t lower_assign(struct lower *l, struct sl_ast *e)
{
	struct lval v = lower_lval(l, e->a);
	int base = e->a->ty.base;
	bool saved = l->uniform_ctx;
	l->uniform_ctx = l->regs.data[v.reg].declared_uniform;
	if (e->op == SL_TOK_ASSIGN) {
		int32_t val = lower_expr(l, e->b);
		l->uniform_ctx = saved;
		store_lval(l, v, val);
		return load_lval(l, v, base);
	}
	int32_t old = load_lval(l, v, base);
	int32_t val = lower_expr(l, e->b);
	l->uniform_ctx = saved;
	int rtype = base;
	/* point -= point is a vector; store back as the variable's type */
	int32_t r = emit2(l, binop(e->op), temp(l, rtype), old, val);
	store_lval(l, v, r);
	return load_lval(l, v, base);
}

static int32_t lower_incdec(struct lower *l, struct sl_ast *e)
{
	struct lval v = lower_lval(l, e->a);
	int32_t old = load_lval(l, v, SL_TYPE_FLOAT);
	int32_t result = old;
	if (!e->num) /* postfix: the value before */
		result = emit1(l, SL_OP_MOV, temp(l, SL_TYPE_FLOAT), old);
	int32_t r = emit2(l, e->op == SL_TOK_INC ? SL_OP_ADD : SL_OP_SUB, temp(l, SL_TYPE_FLOAT),
			  old, const_float(l, 1));
	store_lval(l, v, r);
	return e->num ? load_lval(l, v, SL_TYPE_FLOAT) : result;
}

/* A transform of a constructed value from space @space (string register) to current. */
static int32_t from_space(struct lower *l, int base, int32_t space, int32_t val)
{
	const char *fname = base == SL_TYPE_POINT ? "transform" :
			    base == SL_TYPE_VECTOR ? "vtransform" :
			    base == SL_TYPE_NORMAL ? "ntransform" : "ctransform";
	int first = sl_builtin_find(fname);
	/* the (string, string, value) overload */
	int ov = -1;
	for (uint32_t i = (uint32_t)first; i < sl_nbuiltins && !strcmp(sl_builtins[i].name, fname);
	     i++) {
		const char *args = strchr(sl_builtins[i].sig, ':') + 1;
		if (!strcmp(args, "ssp") || !strcmp(args, "ssv") || !strcmp(args, "ssn") ||
		    !strcmp(args, "ssc"))
			ov = (int)i;
	}
	struct sl_insn *in = emit(l, SL_OP_CALL, temp(l, base), 3);
	in->bi = ov;
	in->args[0] = space;
	in->args[1] = const_string(l, base == SL_TYPE_COLOR ? "rgb" : "current");
	in->args[2] = val;
	return in->dst;
}

static int32_t lower_ctor(struct lower *l, struct sl_ast *e)
{
	int base = e->type.base;
	int32_t r;
	if (e->nlist == 1) {
		/* a cast or promotion: a copy under the new type */
		int32_t v = lower_expr(l, e->list[0]);
		r = reg_type(l, v) == base ? v : emit1(l, SL_OP_MOV, temp(l, base), v);
	} else {
		int32_t comps[16];
		for (uint32_t i = 0; i < e->nlist && i < 16; i++)
			comps[i] = lower_expr(l, e->list[i]);
		struct sl_insn *in = emit(l, e->nlist == 16 ? SL_OP_MATRIX : SL_OP_TRIPLE,
					  temp(l, base), (int)e->nlist);
		for (uint32_t i = 0; i < e->nlist && i < 16; i++)
			in->args[i] = comps[i];
		r = in->dst;
	}
	if (e->a) {
		int32_t space = lower_expr(l, e->a);
		if (base == SL_TYPE_MATRIX) {
			/* matrix "space" (...): the matrix is expressed in that space,
			 * so it is m * (space -> current), through an internal built-in */
			struct sl_insn *in = emit(l, SL_OP_CALL, temp(l, SL_TYPE_MATRIX), 2);
			in->args[0] = space;
			in->args[1] = r;
			in->bi = sl_builtin_find("__spacematrix");
			if (in->bi < 0) {
				sl_error(l->ctx, e->loc,
					 "matrix constructors with a coordinate system are not "
					 "supported");
				in->op = SL_OP_MOV;
				in->nargs = 1;
				in->args[0] = r;
			}
			r = in->dst;
		} else if (base != SL_TYPE_FLOAT && base != SL_TYPE_STRING) {
			r = from_space(l, base, space, r);
		}
	}
	return r;
}

/* Inline a call of a user function. */
static int32_t lower_user_call(struct lower *l, struct sl_ast *e)
{
	struct sl_sym *f = e->sym;
	struct sl_ast *fn = f->decl;
	if (l->inline_depth >= MAX_INLINE_DEPTH) {
		sl_error(l->ctx, e->loc, "function calls nested too deeply (over %d)",
			 MAX_INLINE_DEPTH);
		return const_float(l, 0);
	}
	/* A function's value is its own: the caller's uniform context does not
	 * reach into its arguments or body. */
	bool saved_ctx = l->uniform_ctx;
	l->uniform_ctx = false;
	/* Arguments are evaluated in the caller's frame. */
	struct lval outs[64];
	int32_t vals[64];
	uint32_t n = e->nlist < 64 ? e->nlist : 64;
	for (uint32_t i = 0; i < n; i++) {
		struct sl_ast *p = fn->list[i];
		if (p->output)
			outs[i] = lower_lval(l, e->list[i]);
		else
			vals[i] = lower_expr(l, e->list[i]);
	}
	struct frame fr = { 0 };
	fr.caller = l->frame;
	fr.ret = f->type.base != SL_TYPE_VOID ? temp(l, f->type.base) : -1;
	fr.ret_block = f->has_return;
	l->frame = &fr;
	l->inline_depth++;
	/* Output formals alias the caller's variable (array elements go through a
	 * copy written back at the end); others are fresh copies. */
	int32_t formal_regs[64];
	for (uint32_t i = 0; i < n; i++) {
		struct sl_ast *p = fn->list[i];
		int32_t alen = p->type.arraylen > 0 ? p->type.arraylen : 0;
		if (p->type.arraylen == 0) {
			/* unsized formal: takes the argument's length */
			int32_t src = p->output ? outs[i].reg : vals[i];
			alen = l->regs.data[src].arraylen;
		}
		if (p->output && outs[i].index < 0) {
			formal_regs[i] = outs[i].reg;
			if (p->type.detail == SL_DETAIL_UNIFORM) {
				struct sl_uniform_ref u = { outs[i].reg, e->loc, f->name, p->name };
				rl_vec_push(l->urefs, u);
			}
		} else {
			formal_regs[i] = new_reg(l, p->type.base, alen, SL_REG_LOCAL, p->name, p->loc);
			/* a formal is a local of the call: a uniform one given a
			 * varying argument is promoted (and reported) like any other */
			l->regs.data[formal_regs[i]].declared_uniform =
				p->type.detail == SL_DETAIL_UNIFORM;
			if (p->output)
				store(l, formal_regs[i], load_lval(l, outs[i], p->type.base));
			else
				store(l, formal_regs[i], vals[i]);
		}
		bind(l, p->sym, formal_regs[i]);
	}
	int32_t func_at = -1;
	if (fr.ret_block) {
		func_at = here(l);
		emit(l, SL_OP_FUNC, -1, 0);
	}
	lower_stmt(l, fn->a);
	if (fr.ret_block) {
		int32_t at = here(l);
		struct sl_insn *in = emit(l, SL_OP_FUNCEND, -1, 0);
		in->jump[0] = func_at;
		if (!l->overflow)
			l->code.data[func_at].jump[0] = at;
	}
	for (uint32_t i = 0; i < n; i++)
		if (fn->list[i]->output && outs[i].index >= 0)
			store_lval(l, outs[i], formal_regs[i]);
	l->inline_depth--;
	l->frame = fr.caller;
	l->uniform_ctx = saved_ctx;
	rl_vec_free(fr.vars);
	return fr.ret >= 0 ? fr.ret : const_float(l, 0);
}

static int32_t lower_builtin_call(struct lower *l, struct sl_ast *e)
{
	const struct sl_builtin *b = &sl_builtins[e->overload];
	const char *sig = strchr(b->sig, ':') + 1;
	int32_t args[256];
	uint32_t n = e->nlist < 256 ? e->nlist : 256;
	bool tex = (b->flags & SL_BIF_TEXNAME) != 0;
	/* Signature position of argument i (texture calls have the channel at 1). */
	const char *p = sig;
	for (uint32_t i = 0; i < n; i++) {
		struct sl_ast *a = e->list[i];
		char letter = 0;
		bool output = false;
		if (!(tex && i == 1) && *p && *p != '*') {
			if (*p == '&') {
				output = true;
				p++;
			}
			letter = *p++;
		}
		if (output) {
			args[i] = lower_lval(l, a).reg;
			continue;
		}
		int32_t r = lower_expr(l, a);
		if (letter && letter != '?')
			r = coerce(l, r, sl_sig_type(letter));
		else if (tex && i == 1)
			r = coerce(l, r, sl_sig_type('f'));
		else if (!letter && (b->id == SL_BI_SPLINE || b->id == SL_BI_MIN ||
				     b->id == SL_BI_MAX))
			r = coerce(l, r, sl_sig_type(b->sig[0]));
		args[i] = r;
	}
	/* Globals read by the built-in without being passed must exist. */
	if (b->flags & (SL_BIF_GLOBALS | SL_BIF_LIGHTS)) {
		global(l, SL_GLOBAL_P);
		global(l, SL_GLOBAL_N);
		global(l, SL_GLOBAL_I);
		if (b->id == SL_BI_FACEFORWARD)
			global(l, SL_GLOBAL_NG);
		if (b->id == SL_BI_TEXTURE) {
			global(l, SL_GLOBAL_S);
			global(l, SL_GLOBAL_T);
		}
	}
	if (b->flags & SL_BIF_DERIV) {
		global(l, SL_GLOBAL_DU);
		global(l, SL_GLOBAL_DV);
	}
	int32_t dst = -1;
	if (b->sig[0] != '-')
		dst = temp(l, sl_sig_type(b->sig[0]).base);
	struct sl_insn *in = emit(l, SL_OP_CALL, dst, (int)n);
	in->bi = e->overload;
	if (b->id == SL_BI_RANDOM && l->uniform_ctx)
		in->imm = 1;
	if (n)
		memcpy(in->args, args, sizeof(int32_t) * n);
	in->loc = e->loc;
	return dst >= 0 ? dst : const_float(l, 0);
}

/* One operator of a chain, its left operand @a already lowered. */
static int32_t lower_binary_node(struct lower *l, struct sl_ast *e, int32_t a)
{
	if (e->op == SL_TOK_AND || e->op == SL_TOK_OR)
		return lower_logic(l, e, a);
	int32_t b = lower_expr(l, e->b);
	enum sl_op op = binop(e->op);
	if (op == SL_OP_EQ || op == SL_OP_NE) {
		/* compare like with like */
		int ta = reg_type(l, a), tb = reg_type(l, b);
		if (sl_type_ncomp(ta) > sl_type_ncomp(tb))
			b = coerce(l, b, e->a->ty);
		else if (sl_type_ncomp(tb) > sl_type_ncomp(ta))
			a = coerce(l, a, e->b->ty);
	}
	return emit2(l, op, temp(l, e->ty.base), a, b);
}

/* A chain a + b + c + ...: its left spine in a loop, innermost operator first. */
static int32_t lower_binary(struct lower *l, struct sl_ast *e)
{
	RL_VEC(struct sl_ast *) spine = { 0 };
	struct sl_ast *n = e;
	do {
		rl_vec_push(spine, n);
		n = n->a;
	} while (n->kind == SL_AST_BINARY);
	int32_t v = lower_expr(l, n);
	for (size_t i = spine.len; i-- > 0;) {
		l->loc = spine.data[i]->loc;
		v = lower_binary_node(l, spine.data[i], v);
	}
	rl_vec_free(spine);
	return v;
}

static int32_t lower_expr_inner(struct lower *l, struct sl_ast *e)
{
	switch (e->kind) {
	case SL_AST_NUM:
		return const_float(l, (float)e->num);
	case SL_AST_STR:
		return const_string(l, e->str);
	case SL_AST_IDENT:
		return sym_reg(l, e->sym);
	case SL_AST_UNARY: {
		int32_t a = lower_expr(l, e->a);
		if (e->op == SL_TOK_MINUS)
			return emit1(l, SL_OP_NEG, temp(l, e->ty.base), a);
		if (e->op == SL_TOK_BANG)
			return emit1(l, SL_OP_NOT, temp(l, SL_TYPE_BOOL), a);
		return a;
	}
	case SL_AST_BINARY:
		return lower_binary(l, e);
	case SL_AST_ASSIGN:
		return lower_assign(l, e);
	case SL_AST_INCDEC:
		return lower_incdec(l, e);
	case SL_AST_COND:
		return lower_cond(l, e);
	case SL_AST_CALL:
		if (e->overload >= 0)
			return lower_builtin_call(l, e);
		return lower_user_call(l, e);
	case SL_AST_INDEX:
		return lower_index(l, e);
	case SL_AST_CTOR:
		return lower_ctor(l, e);
	default:
		sl_error(l->ctx, e->loc, "cannot lower %s", sl_ast_kind_name(e->kind));
		return const_float(l, 0);
	}
}

static int32_t lower_expr(struct lower *l, struct sl_ast *e)
{
	struct sl_loc saved = l->loc;
	l->loc = e->loc;
	int32_t r = lower_expr_inner(l, e);
	l->loc = saved;
	return r;
}

/* ---- statements ---- */

static int32_t lower_var(struct lower *l, struct sl_ast *v, enum sl_reg_kind kind)
{
	int32_t r = new_reg(l, v->type.base, v->type.arraylen, kind, v->name, v->loc);
	struct sl_reg *reg = &l->regs.data[r];
	reg->output = v->output;
	/* Parameters are uniform unless declared varying; locals are varying
	 * unless declared uniform (inference may still find them uniform). */
	if (kind == SL_REG_PARAM)
		reg->declared_uniform = v->type.detail != SL_DETAIL_VARYING;
	else
		reg->declared_uniform = v->type.detail == SL_DETAIL_UNIFORM;
	if (kind == SL_REG_PARAM && v->type.detail == SL_DETAIL_VARYING)
		reg->varying = true;
	bind(l, v->sym, r);
	struct sl_ast *init = v->a;
	if (!init)
		return r;
	struct sl_loc saved = l->loc;
	bool saved_ctx = l->uniform_ctx;
	l->loc = init->loc;
	l->uniform_ctx = reg->declared_uniform;
	if (init->kind == SL_AST_ARRAYLIT) {
		for (uint32_t i = 0; i < init->nlist; i++) {
			int32_t val = lower_expr(l, init->list[i]);
			emit2(l, SL_OP_ASET, r, val, const_float(l, (float)i));
		}
	} else {
		store(l, r, lower_expr(l, init));
	}
	l->uniform_ctx = saved_ctx;
	l->loc = saved;
	return r;
}

static void open_loop(struct lower *l, int32_t *loop_at)
{
	*loop_at = here(l);
	emit(l, SL_OP_LOOP, -1, 0);
}

static void loop_test(struct lower *l, int32_t loop_at, int32_t cond)
{
	int32_t at = here(l);
	struct sl_insn *in = emit(l, SL_OP_LOOPTEST, -1, 1);
	in->args[0] = cond;
	in->jump[0] = loop_at;
	if (!l->overflow)
		l->code.data[loop_at].jump[0] = at;
}

static void loop_cont(struct lower *l, int32_t loop_at)
{
	struct sl_insn *in = emit(l, SL_OP_LOOPCONT, -1, 0);
	in->jump[0] = loop_at;
}

static void close_loop(struct lower *l, int32_t loop_at)
{
	int32_t at = here(l);
	struct sl_insn *in = emit(l, SL_OP_LOOPEND, -1, 0);
	in->jump[0] = loop_at;
	if (l->overflow)
		return;
	l->code.data[loop_at].jump[1] = at;
	int32_t test = l->code.data[loop_at].jump[0];
	if (test >= 0)
		l->code.data[test].jump[1] = at;
}

static void lower_block_op(struct lower *l, struct sl_ast *st, enum sl_op open,
			   enum sl_op close, int32_t *args, int nargs, int imm)
{
	int32_t at = here(l);
	struct sl_insn *in = emit(l, open, -1, nargs);
	if (nargs)
		memcpy(in->args, args, sizeof(int32_t) * (size_t)nargs);
	in->imm = imm;
	lower_stmt(l, st->a);
	int32_t end = here(l);
	struct sl_insn *c = emit(l, close, -1, 0);
	c->jump[0] = at;
	if (!l->overflow)
		l->code.data[at].jump[0] = end;
}

static void lower_stmt(struct lower *l, struct sl_ast *st)
{
	if (!st || l->overflow)
		return;
	struct sl_loc saved = l->loc;
	l->loc = st->loc;
	switch (st->kind) {
	case SL_AST_BLOCK:
		for (uint32_t i = 0; i < st->nlist; i++)
			lower_stmt(l, st->list[i]);
		break;
	case SL_AST_EXPR:
		lower_expr(l, st->a);
		break;
	case SL_AST_DECL:
		for (uint32_t i = 0; i < st->nlist; i++)
			if (!st->list[i]->is_extern)
				lower_var(l, st->list[i], SL_REG_LOCAL);
		break;
	case SL_AST_FUNC:
	case SL_AST_EMPTY:
		break;
	case SL_AST_IF: {
		int32_t c = lower_expr(l, st->a);
		int32_t at = open_if(l, c);
		lower_stmt(l, st->b);
		int32_t el = -1;
		if (st->c) {
			el = add_else(l, at);
			lower_stmt(l, st->c);
		}
		close_if(l, at, el);
		break;
	}
	case SL_AST_WHILE: {
		int32_t loop_at;
		open_loop(l, &loop_at);
		loop_test(l, loop_at, lower_expr(l, st->a));
		lower_stmt(l, st->b);
		loop_cont(l, loop_at);
		close_loop(l, loop_at);
		break;
	}
	case SL_AST_FOR: {
		if (st->a) {
			if (st->a->kind == SL_AST_DECL)
				lower_stmt(l, st->a);
			else
				lower_stmt(l, st->a);
		}
		int32_t loop_at;
		open_loop(l, &loop_at);
		loop_test(l, loop_at, st->b ? lower_expr(l, st->b) : const_float(l, 1));
		lower_stmt(l, st->d);
		loop_cont(l, loop_at);
		if (st->c)
			lower_expr(l, st->c);
		close_loop(l, loop_at);
		break;
	}
	case SL_AST_BREAK:
		emit(l, SL_OP_BREAK, -1, 0)->imm = (int32_t)st->num;
		break;
	case SL_AST_CONTINUE:
		emit(l, SL_OP_CONTINUE, -1, 0)->imm = (int32_t)st->num;
		break;
	case SL_AST_RETURN:
		if (st->a && l->frame->ret >= 0)
			store(l, l->frame->ret, lower_expr(l, st->a));
		if (l->frame->ret_block)
			emit(l, SL_OP_RETURN, -1, 0);
		break;
	case SL_AST_ILLUMINANCE: {
		int32_t args[4];
		int n = (int)st->nlist;
		bool cat = n == 2 || n == 4;
		for (int i = 0; i < n && i < 4; i++)
			args[i] = lower_expr(l, st->list[i]);
		/* the position is a point; axis a vector */
		lower_block_op(l, st, SL_OP_ILLUMINANCE, SL_OP_ILLUMINANCE_END, args, n, cat);
		break;
	}
	case SL_AST_ILLUMINATE: {
		int32_t args[3];
		int n = (int)st->nlist;
		for (int i = 0; i < n && i < 3; i++)
			args[i] = lower_expr(l, st->list[i]);
		global(l, SL_GLOBAL_PS);
		global(l, SL_GLOBAL_L);
		lower_block_op(l, st, SL_OP_ILLUMINATE, SL_OP_ILLUMINATE_END, args, n, 0);
		break;
	}
	case SL_AST_SOLAR: {
		int32_t args[2];
		int n = (int)st->nlist;
		for (int i = 0; i < n && i < 2; i++)
			args[i] = lower_expr(l, st->list[i]);
		global(l, SL_GLOBAL_L);
		if (n == 0)
			global(l, SL_GLOBAL_NS); /* L = -Ns */
		lower_block_op(l, st, SL_OP_SOLAR, SL_OP_SOLAR_END, args, n, 0);
		break;
	}
	default:
		sl_error(l->ctx, st->loc, "cannot lower %s", sl_ast_kind_name(st->kind));
		break;
	}
	l->loc = saved;
}

/* Does the statement @st hold a return (outside nested functions)? Only
 * statements are visited: an expression holds none. */
static bool shader_has_return(const struct sl_ast *st)
{
	if (!st)
		return false;
	switch (st->kind) {
	case SL_AST_RETURN:
		return true;
	case SL_AST_BLOCK:
		for (uint32_t i = 0; i < st->nlist; i++)
			if (shader_has_return(st->list[i]))
				return true;
		return false;
	case SL_AST_IF:
		return shader_has_return(st->b) || shader_has_return(st->c);
	case SL_AST_WHILE:
		return shader_has_return(st->b);
	case SL_AST_FOR:
		return shader_has_return(st->d);
	case SL_AST_ILLUMINANCE:
	case SL_AST_ILLUMINATE:
	case SL_AST_SOLAR:
		return shader_has_return(st->a);
	default:
		return false;
	}
}

struct sl_program *sl_lower(struct sl_ctx *ctx, struct sl_ast *shader)
{
	struct lower l = { .ctx = ctx, .kind = (enum sl_shader_kind)shader->op };
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		l.global_reg[g] = -1;
	struct frame top = { 0 };
	top.ret = -1;
	top.ret_block = shader_has_return(shader->a);
	l.frame = &top;
	l.loc = shader->loc;

	struct sl_program *prog = rl_arena_alloc(ctx->arena, sizeof(*prog));
	prog->kind = (enum sl_shader_kind)shader->op;
	prog->name = shader->name;

	/* The globals a shader of this kind hands back always exist. */
	switch (prog->kind) {
	case SL_SHADER_SURFACE:
		global(&l, SL_GLOBAL_CI);
		global(&l, SL_GLOBAL_OI);
		break;
	case SL_SHADER_LIGHT:
		global(&l, SL_GLOBAL_PS);
		global(&l, SL_GLOBAL_L);
		global(&l, SL_GLOBAL_CL);
		global(&l, SL_GLOBAL_OL);
		break;
	case SL_SHADER_DISPLACEMENT:
		global(&l, SL_GLOBAL_P);
		global(&l, SL_GLOBAL_N);
		break;
	case SL_SHADER_VOLUME:
		global(&l, SL_GLOBAL_CI);
		global(&l, SL_GLOBAL_OI);
		break;
	case SL_SHADER_IMAGER:
		global(&l, SL_GLOBAL_CI);
		global(&l, SL_GLOBAL_OI);
		global(&l, SL_GLOBAL_ALPHA);
		break;
	default:
		break;
	}

	prog->nparams = shader->nlist;
	prog->params = rl_arena_alloc(ctx->arena, sizeof(struct sl_param) * (shader->nlist + 1));
	for (uint32_t i = 0; i < shader->nlist; i++) {
		struct sl_ast *v = shader->list[i];
		struct sl_param *p = &prog->params[i];
		p->name = v->name;
		p->type = v->type;
		p->type.detail = v->type.detail == SL_DETAIL_VARYING ? SL_DETAIL_VARYING
								     : SL_DETAIL_UNIFORM;
		p->output = v->output;
		p->init_begin = (uint32_t)here(&l);
		p->reg = lower_var(&l, v, SL_REG_PARAM);
		p->init_end = (uint32_t)here(&l);
	}
	prog->body_begin = (uint32_t)here(&l);
	int32_t func_at = -1;
	if (top.ret_block) {
		func_at = here(&l);
		emit(&l, SL_OP_FUNC, -1, 0);
	}
	lower_stmt(&l, shader->a);
	if (top.ret_block) {
		int32_t at = here(&l);
		struct sl_insn *in = emit(&l, SL_OP_FUNCEND, -1, 0);
		in->jump[0] = func_at;
		if (!l.overflow)
			l.code.data[func_at].jump[0] = at;
	}
	rl_vec_free(top.vars);

	bool ok = !ctx->nerrors && !l.overflow;
	if (ok) {
		prog->nregs = (uint32_t)l.regs.len;
		prog->regs = rl_arena_alloc(ctx->arena, sizeof(struct sl_reg) * (l.regs.len + 1));
		if (l.regs.len)
			memcpy(prog->regs, l.regs.data, sizeof(struct sl_reg) * l.regs.len);
		prog->ncode = (uint32_t)l.code.len;
		prog->code = rl_arena_alloc(ctx->arena, sizeof(struct sl_insn) * (l.code.len + 1));
		if (l.code.len)
			memcpy(prog->code, l.code.data, sizeof(struct sl_insn) * l.code.len);
		prog->nconsts = (uint32_t)l.consts.len;
		prog->consts = rl_arena_alloc(ctx->arena, sizeof(float) * (l.consts.len + 1));
		if (l.consts.len)
			memcpy(prog->consts, l.consts.data, sizeof(float) * l.consts.len);
		prog->nstrings = (uint32_t)l.strings.len;
		prog->strings = rl_arena_alloc(ctx->arena, sizeof(char *) * (l.strings.len + 1));
		if (l.strings.len)
			memcpy(prog->strings, l.strings.data, sizeof(char *) * l.strings.len);
		memcpy(prog->global_reg, l.global_reg, sizeof(l.global_reg));
		prog->nurefs = (uint32_t)l.urefs.len;
		prog->urefs = rl_arena_alloc(ctx->arena,
					     sizeof(struct sl_uniform_ref) * (l.urefs.len + 1));
		if (l.urefs.len)
			memcpy(prog->urefs, l.urefs.data,
			       sizeof(struct sl_uniform_ref) * l.urefs.len);
	}
	rl_vec_free(l.regs);
	rl_vec_free(l.code);
	rl_vec_free(l.consts);
	rl_vec_free(l.strings);
	rl_vec_free(l.urefs);
	free(l.cslots);
	return ok ? prog : NULL;
}

/*
 * The checks a program passes before the interpreter runs it: every
 * operand a register of the right kind for its op, every jump and block
 * inside the program and properly nested, every loop with its continue.
 * They are what the interpreter relies on for memory safety, so that a
 * corrupt or hand-made program is refused rather than run (sl_exec_create
 * calls them).
 */
#include "exec_impl.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX


/* A numeric non-array register. */
static bool is_num(const struct sl_program *prog, int32_t r)
{
	return !is_str(prog, r) && creg(prog, r)->arraylen == 0;
}

static bool is_scalar(const struct sl_program *prog, int32_t r)
{
	return is_num(prog, r) && ncomp_of(prog, r) == 1;
}

/* Operand @a fits a componentwise op writing @d: same components or a float. */
static bool fits(const struct sl_program *prog, int32_t d, int32_t a)
{
	return is_num(prog, a) && (ncomp_of(prog, a) == ncomp_of(prog, d) ||
				   ncomp_of(prog, a) == 1);
}

/* NULL if @in's operands suit its op, else why not. */
static const char *check_operands(const struct sl_program *prog, const struct sl_insn *in)
{
	int32_t d = in->dst;
	const int32_t *a = in->args;
	uint32_t na = in->nargs;
	if (na && !a)
		return "missing argument list";
	if (d != -1 && !reg_ok(prog, d))
		return "bad destination register";
	for (uint32_t k = 0; k < na; k++)
		if (!reg_ok(prog, a[k]))
			return "bad argument register";
	switch ((enum sl_op)in->op) {
	case SL_OP_MOV:
	case SL_OP_NEG:
	case SL_OP_ADD: case SL_OP_SUB: case SL_OP_MUL: case SL_OP_DIV:
	case SL_OP_DOT: case SL_OP_CROSS:
	case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE:
	case SL_OP_EQ: case SL_OP_NE:
	case SL_OP_NOT: case SL_OP_AND: case SL_OP_OR:
	case SL_OP_TRIPLE: case SL_OP_MATRIX: case SL_OP_COMP: case SL_OP_SETCOMP:
	case SL_OP_AREF: case SL_OP_ASET: case SL_OP_SELECT:
		if (d < 0)
			return "missing destination";
		break;
	default:
		break;
	}
	switch ((enum sl_op)in->op) {
	case SL_OP_MOV: {
		if (na != 1)
			return "wrong operand count";
		const struct sl_reg *rd = creg(prog, d), *ra = creg(prog, a[0]);
		if (is_str(prog, d) != is_str(prog, a[0]))
			return "string and number mixed";
		if (rd->arraylen == ra->arraylen &&
		    (is_str(prog, d) || sl_reg_ncomp(rd) == sl_reg_ncomp(ra)))
			return NULL;
		if (is_scalar(prog, a[0]) && is_num(prog, d))
			return NULL;
		return "operand types differ";
	}
	case SL_OP_NEG:
		if (na != 1 || !is_num(prog, d) || !fits(prog, d, a[0]))
			return "bad operand types";
		return NULL;
	case SL_OP_ADD: case SL_OP_SUB: case SL_OP_MUL: case SL_OP_DIV:
		if (na != 2 || !is_num(prog, d) || !fits(prog, d, a[0]) || !fits(prog, d, a[1]))
			return "bad operand types";
		return NULL;
	case SL_OP_DOT: case SL_OP_CROSS:
		if (na != 2 || !is_num(prog, d) ||
		    ncomp_of(prog, d) != (in->op == SL_OP_DOT ? 1 : 3))
			return "bad destination type";
		for (int k = 0; k < 2; k++)
			if (!is_num(prog, a[k]) ||
			    (ncomp_of(prog, a[k]) != 3 && ncomp_of(prog, a[k]) != 1))
				return "operands must be triples";
		return NULL;
	case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE:
	case SL_OP_AND: case SL_OP_OR:
		if (na != 2 || !is_scalar(prog, d) || !is_scalar(prog, a[0]) ||
		    !is_scalar(prog, a[1]))
			return "operands must be floats";
		return NULL;
	case SL_OP_NOT:
		if (na != 1 || !is_scalar(prog, d) || !is_scalar(prog, a[0]))
			return "operand must be a float";
		return NULL;
	case SL_OP_EQ: case SL_OP_NE:
		if (na != 2 || !is_scalar(prog, d))
			return "bad operands";
		if (is_str(prog, a[0]) || is_str(prog, a[1])) {
			if (!is_str(prog, a[0]) || !is_str(prog, a[1]) ||
			    creg(prog, a[0])->arraylen || creg(prog, a[1])->arraylen)
				return "string compared with a number";
			return NULL;
		}
		if (!is_num(prog, a[0]) || !is_num(prog, a[1]))
			return "arrays cannot be compared";
		if (ncomp_of(prog, a[0]) != ncomp_of(prog, a[1]) &&
		    ncomp_of(prog, a[0]) != 1 && ncomp_of(prog, a[1]) != 1)
			return "operand types differ";
		return NULL;
	case SL_OP_TRIPLE: case SL_OP_MATRIX: {
		uint32_t want = in->op == SL_OP_TRIPLE ? 3 : 16;
		if (na != want || !is_num(prog, d) || (uint32_t)ncomp_of(prog, d) != want)
			return "bad operand count or destination";
		for (uint32_t k = 0; k < na; k++)
			if (!is_scalar(prog, a[k]))
				return "components must be floats";
		return NULL;
	}
	case SL_OP_COMP:
		if (na != 1 || !is_scalar(prog, d) || !is_num(prog, a[0]) ||
		    in->imm < 0 || in->imm >= ncomp_of(prog, a[0]))
			return "bad component";
		return NULL;
	case SL_OP_SETCOMP:
		if (na != 1 || !is_num(prog, d) || !is_scalar(prog, a[0]) || in->imm < 0 ||
		    in->imm >= ncomp_of(prog, d))
			return "bad component";
		return NULL;
	case SL_OP_AREF: case SL_OP_ASET: {
		int32_t arr = in->op == SL_OP_AREF ? a[0] : d;
		int32_t el = in->op == SL_OP_AREF ? d : a[0];
		if (na != 2 || creg(prog, arr)->arraylen <= 0 || creg(prog, el)->arraylen != 0 ||
		    is_str(prog, arr) != is_str(prog, el) ||
		    ncomp_of(prog, arr) != ncomp_of(prog, el) || !is_scalar(prog, a[1]))
			return "bad array access";
		return NULL;
	}
	case SL_OP_SELECT:
		if (na != 3 || !is_scalar(prog, a[0]))
			return "bad condition";
		for (int k = 1; k < 3; k++) {
			if (is_str(prog, d) != is_str(prog, a[k]))
				return "string and number mixed";
			if (creg(prog, a[k])->arraylen == creg(prog, d)->arraylen &&
			    (is_str(prog, d) || ncomp_of(prog, a[k]) == ncomp_of(prog, d)))
				continue;
			if (is_scalar(prog, a[k]) && is_num(prog, d))
				continue;
			return "operand types differ";
		}
		return NULL;
	case SL_OP_IF: case SL_OP_LOOPTEST:
		if (na != 1 || !is_scalar(prog, a[0]))
			return "condition must be a float";
		return NULL;
	case SL_OP_ILLUMINANCE: {
		if (in->imm != 0 && in->imm != 1)
			return "bad category flag";
		uint32_t k = (uint32_t)in->imm;
		if (na != k + 1 && na != k + 3)
			return "wrong operand count";
		if (k && (!is_str(prog, a[0]) || creg(prog, a[0])->arraylen))
			return "category must be a string";
		if (!is_num(prog, a[k]) || ncomp_of(prog, a[k]) != 3)
			return "position must be a point";
		if (na == k + 3 && (!is_num(prog, a[k + 1]) || ncomp_of(prog, a[k + 1]) != 3 ||
				    !is_scalar(prog, a[k + 2])))
			return "bad axis or angle";
		return NULL;
	}
	case SL_OP_ILLUMINATE:
		if (na != 1 && na != 3)
			return "wrong operand count";
		if (!is_num(prog, a[0]) || ncomp_of(prog, a[0]) != 3)
			return "position must be a point";
		if (na == 3 && (!is_num(prog, a[1]) || ncomp_of(prog, a[1]) != 3 ||
				!is_scalar(prog, a[2])))
			return "bad axis or angle";
		return NULL;
	case SL_OP_SOLAR:
		if (na != 0 && na != 2)
			return "wrong operand count";
		if (na == 2 && (!is_num(prog, a[0]) || ncomp_of(prog, a[0]) != 3 ||
				!is_scalar(prog, a[1])))
			return "bad axis or angle";
		return NULL;
	case SL_OP_BREAK: case SL_OP_CONTINUE:
		if (in->imm < 1)
			return "bad loop level";
		return NULL;
	default:
		return in->op < SL_OP_COUNT ? NULL : "unknown op";
	}
}

/* Open block on the checker's stack. */
struct open_block {
	uint32_t pc;
	uint8_t state;     /* IF: 1 after ELSE; LOOP: 0 condition, 1 body, 2 step */
};

/*
 * Check that [b, e) is properly nested and that every jump names its
 * partner; record each LOOP's LOOPCONT and the deepest nesting.
 */
static const char *check_range(const struct sl_program *prog, uint32_t b, uint32_t e,
			       uint32_t *loopcont, uint32_t *maxdepth, uint32_t *where)
{
	const struct sl_insn *code = prog->code;
	struct open_block *st = rl_xmalloc((size_t)(e - b + 1) * sizeof(*st));
	uint32_t depth = 0;
	const char *why = NULL;
	for (uint32_t pc = b; pc < e && !why; pc++) {
		const struct sl_insn *in = &code[pc];
		const struct sl_insn *top = depth ? &code[st[depth - 1].pc] : NULL;
		uint32_t tpc = depth ? st[depth - 1].pc : 0;
		*where = pc;
		switch ((enum sl_op)in->op) {
		case SL_OP_IF:
			if (in->jump[0] <= (int32_t)pc || in->jump[1] < in->jump[0] ||
			    in->jump[1] >= (int32_t)e)
				why = "bad if jumps";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_ELSE:
			if (!top || top->op != SL_OP_IF || st[depth - 1].state ||
			    top->jump[0] != (int32_t)pc || in->jump[0] != (int32_t)tpc ||
			    in->jump[1] != top->jump[1])
				why = "else without its if";
			else
				st[depth - 1].state = 1;
			break;
		case SL_OP_ENDIF:
			if (!top || top->op != SL_OP_IF || top->jump[1] != (int32_t)pc ||
			    in->jump[0] != (int32_t)tpc ||
			    (!st[depth - 1].state && top->jump[0] != (int32_t)pc))
				why = "endif without its if";
			else
				depth--;
			break;
		case SL_OP_LOOP:
			if (in->jump[0] <= (int32_t)pc || in->jump[1] <= in->jump[0] ||
			    in->jump[1] >= (int32_t)e)
				why = "bad loop jumps";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_LOOPTEST:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state != 0 ||
			    top->jump[0] != (int32_t)pc || in->jump[0] != (int32_t)tpc ||
			    in->jump[1] != top->jump[1])
				why = "looptest without its loop";
			else
				st[depth - 1].state = 1;
			break;
		case SL_OP_LOOPCONT:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state != 1 ||
			    in->jump[0] != (int32_t)tpc)
				why = "loopcont without its loop";
			else {
				st[depth - 1].state = 2;
				loopcont[tpc] = pc;
			}
			break;
		case SL_OP_LOOPEND:
			if (!top || top->op != SL_OP_LOOP || st[depth - 1].state == 0 ||
			    top->jump[1] != (int32_t)pc || in->jump[0] != (int32_t)tpc)
				why = "loopend without its loop";
			else
				depth--;
			break;
		case SL_OP_BREAK:
		case SL_OP_CONTINUE: {
			int32_t loops = 0;
			for (uint32_t k = depth; k-- > 0;) {
				uint16_t op = code[st[k].pc].op;
				if (op == SL_OP_FUNC)
					break;
				if (op == SL_OP_LOOP || op == SL_OP_ILLUMINANCE)
					loops++;
			}
			if (in->imm < 1 || in->imm > loops)
				why = "break or continue outside its loop";
			break;
		}
		case SL_OP_FUNC:
		case SL_OP_ILLUMINANCE:
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			if (in->jump[0] <= (int32_t)pc || in->jump[0] >= (int32_t)e)
				why = "bad block jump";
			st[depth++] = (struct open_block){ pc, 0 };
			break;
		case SL_OP_FUNCEND:
		case SL_OP_ILLUMINANCE_END:
		case SL_OP_ILLUMINATE_END:
		case SL_OP_SOLAR_END: {
			uint16_t want = in->op == SL_OP_FUNCEND ? SL_OP_FUNC :
					in->op == SL_OP_ILLUMINANCE_END ? SL_OP_ILLUMINANCE :
					in->op == SL_OP_ILLUMINATE_END ? SL_OP_ILLUMINATE : SL_OP_SOLAR;
			if (!top || top->op != want || top->jump[0] != (int32_t)pc ||
			    in->jump[0] != (int32_t)tpc)
				why = "block end without its opener";
			else
				depth--;
			break;
		}
		default:
			break;
		}
		if (depth > *maxdepth)
			*maxdepth = depth;
	}
	if (!why && depth)
		why = "block not closed";
	free(st);
	return why;
}

/* Everything the interpreter relies on for memory safety. */
bool sl_exec_check_program(const struct sl_program *prog, uint32_t *loopcont,
			   uint32_t *maxdepth)
{
	const char *label = sl_exec_label(prog);
	if ((prog->nregs && !prog->regs) || (prog->ncode && !prog->code) ||
	    (prog->nparams && !prog->params) || prog->body_begin > prog->ncode) {
		fprintf(stderr, "%s: error: invalid program (missing tables)\n", label);
		return false;
	}
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *g = &prog->regs[r];
		const char *why = NULL;
		if (g->type == SL_TYPE_VOID || g->type >= SL_TYPE_COUNT)
			why = "bad type";
		else if (g->arraylen < 0 || g->arraylen > SL_EXEC_MAX_ARRAY)
			why = "bad array length";
		else if (g->kind == SL_REG_CONST) {
			uint64_t end = (uint64_t)g->cindex + sl_exec_reg_total(g);
			if (g->type == SL_TYPE_STRING ? (end > prog->nstrings || !prog->strings)
						      : (end > prog->nconsts || !prog->consts))
				why = "constant outside the pool";
		}
		if (why) {
			fprintf(stderr, "%s: error: invalid program: register %u: %s\n", label, r,
				why);
			return false;
		}
	}
	for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
		int32_t r = prog->global_reg[g];
		if (r == -1)
			continue;
		if (!reg_ok(prog, r) || !is_num(prog, r) || ncomp_of(prog, r) != sl_exec_global_ncomp[g]) {
			fprintf(stderr, "%s: error: invalid program: bad register for global %d\n",
				label, g);
			return false;
		}
	}
	for (uint32_t k = 0; k < prog->nparams; k++) {
		const struct sl_param *pp = &prog->params[k];
		if (!pp->name || !reg_ok(prog, pp->reg) || pp->init_begin > pp->init_end ||
		    pp->init_end > prog->ncode) {
			fprintf(stderr, "%s: error: invalid program: parameter %u\n", label, k);
			return false;
		}
	}
	for (uint32_t pc = 0; pc < prog->ncode; pc++) {
		const char *why = check_operands(prog, &prog->code[pc]);
		if (why) {
			fprintf(stderr, "%s: error: invalid program: instruction %u (op %u): %s\n",
				label, pc, prog->code[pc].op, why);
			return false;
		}
	}
	for (uint32_t k = 0; k <= prog->nparams; k++) {
		uint32_t b = k < prog->nparams ? prog->params[k].init_begin : prog->body_begin;
		uint32_t e = k < prog->nparams ? prog->params[k].init_end : prog->ncode;
		uint32_t where = b;
		const char *why = check_range(prog, b, e, loopcont, maxdepth, &where);
		if (why) {
			fprintf(stderr, "%s: error: invalid program: instruction %u: %s\n", label,
				where, why);
			return false;
		}
	}
	return true;
}


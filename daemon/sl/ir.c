/* Printing the IR, and small queries on programs. */
#include "ir.h"
#include "builtin.h"

#include <stdio.h>
#include <string.h>

static const char *const op_names[SL_OP_COUNT] = {
	[SL_OP_NOP] = "nop", [SL_OP_MOV] = "mov", [SL_OP_NEG] = "neg", [SL_OP_ADD] = "add",
	[SL_OP_SUB] = "sub", [SL_OP_MUL] = "mul", [SL_OP_DIV] = "div", [SL_OP_DOT] = "dot",
	[SL_OP_CROSS] = "cross", [SL_OP_LT] = "lt", [SL_OP_LE] = "le", [SL_OP_GT] = "gt",
	[SL_OP_GE] = "ge", [SL_OP_EQ] = "eq", [SL_OP_NE] = "ne", [SL_OP_NOT] = "not",
	[SL_OP_AND] = "and", [SL_OP_OR] = "or", [SL_OP_TRIPLE] = "triple",
	[SL_OP_MATRIX] = "matrix", [SL_OP_COMP] = "comp", [SL_OP_SETCOMP] = "setcomp",
	[SL_OP_AREF] = "aref", [SL_OP_ASET] = "aset", [SL_OP_SELECT] = "select",
	[SL_OP_CALL] = "call", [SL_OP_IF] = "if", [SL_OP_ELSE] = "else", [SL_OP_ENDIF] = "endif",
	[SL_OP_LOOP] = "loop", [SL_OP_LOOPTEST] = "looptest", [SL_OP_LOOPCONT] = "loopcont",
	[SL_OP_LOOPEND] = "loopend", [SL_OP_BREAK] = "break", [SL_OP_CONTINUE] = "continue",
	[SL_OP_FUNC] = "func", [SL_OP_RETURN] = "return", [SL_OP_FUNCEND] = "funcend",
	[SL_OP_ILLUMINANCE] = "illuminance", [SL_OP_ILLUMINANCE_END] = "illuminance_end",
	[SL_OP_ILLUMINATE] = "illuminate", [SL_OP_ILLUMINATE_END] = "illuminate_end",
	[SL_OP_SOLAR] = "solar", [SL_OP_SOLAR_END] = "solar_end",
};

const char *sl_op_name(enum sl_op op)
{
	return (unsigned)op < SL_OP_COUNT && op_names[op] ? op_names[op] : "?";
}

const char *sl_ir_reg_name(const struct sl_program *prog, int32_t reg)
{
	static char bufs[4][96];
	static int which;
	char *b = bufs[which++ & 3];
	if (reg < 0 || (uint32_t)reg >= prog->nregs) {
		snprintf(b, 96, "-");
		return b;
	}
	const struct sl_reg *r = &prog->regs[reg];
	switch (r->kind) {
	case SL_REG_CONST:
		if (r->type == SL_TYPE_STRING)
			snprintf(b, 96, "\"%.80s\"", prog->strings[r->cindex]);
		else
			snprintf(b, 96, "%g", (double)prog->consts[r->cindex]);
		break;
	case SL_REG_TEMP:
		snprintf(b, 96, "%%t%d", reg);
		break;
	default:
		snprintf(b, 96, "%%%.60s.%d", r->name ? r->name : "?", reg);
		break;
	}
	return b;
}

static void print_type(const struct sl_program *prog, int32_t reg, FILE *out)
{
	const struct sl_reg *r = &prog->regs[reg];
	fprintf(out, ":%s%s", r->varying ? "v" : "u", sl_basetype_name(r->type));
	if (r->arraylen)
		fprintf(out, "[%d]", r->arraylen);
}

void sl_ir_print_insn(const struct sl_program *prog, uint32_t i, FILE *out)
{
	const struct sl_insn *in = &prog->code[i];
	fprintf(out, "%5u  %-14s", i, sl_op_name((enum sl_op)in->op));
	if (in->op == SL_OP_CALL)
		fprintf(out, " %s", in->bi >= 0 ? sl_builtins[in->bi].name : "?");
	if (in->dst >= 0) {
		fprintf(out, " %s", sl_ir_reg_name(prog, in->dst));
		print_type(prog, in->dst, out);
		fprintf(out, " <-");
	}
	for (int k = 0; k < in->nargs; k++)
		fprintf(out, "%s %s", k ? "," : "", sl_ir_reg_name(prog, in->args[k]));
	if (in->op == SL_OP_COMP || in->op == SL_OP_SETCOMP || in->op == SL_OP_BREAK ||
	    in->op == SL_OP_CONTINUE)
		fprintf(out, " [%d]", in->imm);
	if (in->op == SL_OP_CALL && in->imm == 1)
		fputs(" [uniform]", out);
	if (in->jump[0] >= 0 || in->jump[1] >= 0) {
		fprintf(out, "  ->");
		if (in->jump[0] >= 0)
			fprintf(out, " %d", in->jump[0]);
		if (in->jump[1] >= 0)
			fprintf(out, " %d", in->jump[1]);
	}
	const char *file = in->loc.file < prog->nfiles ? prog->files[in->loc.file] : "?";
	const char *base = strrchr(file, '/');
	fprintf(out, "    ; %s:%u\n", base ? base + 1 : file, in->loc.line);
}

void sl_ir_dump(const struct sl_program *prog, FILE *out)
{
	fprintf(out, "%s %s\n", sl_shader_kind_name(prog->kind), prog->name);
	for (uint32_t i = 0; i < prog->nparams; i++) {
		const struct sl_param *p = &prog->params[i];
		fprintf(out, "  param %s%s %s", p->output ? "output " : "",
			sl_ir_reg_name(prog, p->reg), sl_basetype_name(p->type.base));
		if (p->type.arraylen > 0)
			fprintf(out, "[%d]", p->type.arraylen);
		fprintf(out, " (%s), default at [%u, %u)\n",
			p->type.detail == SL_DETAIL_VARYING ? "varying" : "uniform", p->init_begin,
			p->init_end);
	}
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		if (prog->global_reg[g] >= 0) {
			fprintf(out, "  global %s", sl_ir_reg_name(prog, prog->global_reg[g]));
			print_type(prog, prog->global_reg[g], out);
			fputc('\n', out);
		}
	fprintf(out, "  body at %u\n", prog->body_begin);
	for (uint32_t i = 0; i < prog->ncode; i++) {
		sl_ir_print_insn(prog, i, out);
	}
}

int sl_program_find_param(const struct sl_program *prog, const char *name)
{
	for (uint32_t i = 0; i < prog->nparams; i++)
		if (!strcmp(prog->params[i].name, name))
			return (int)i;
	return -1;
}

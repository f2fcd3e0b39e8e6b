/*
 * The typed IR: a flat list of instructions over virtual registers, with
 * structured control flow (every block opener names its matching closer).
 * User functions are inlined, so a program is one instruction list. The grid
 * interpreter runs it over all points of a grid at once; the specializer
 * (dependence analysis) and the GLSL generator read the same form.
 */
#ifndef SL_IR_H
#define SL_IR_H

#include "ast.h"

/** Renderer-provided (global) variables of RSL. */
enum sl_global {
	SL_GLOBAL_P, SL_GLOBAL_N, SL_GLOBAL_NG, SL_GLOBAL_I, SL_GLOBAL_E,
	SL_GLOBAL_CS, SL_GLOBAL_OS, SL_GLOBAL_CI, SL_GLOBAL_OI,
	SL_GLOBAL_S, SL_GLOBAL_T, SL_GLOBAL_U, SL_GLOBAL_V, SL_GLOBAL_DU, SL_GLOBAL_DV,
	SL_GLOBAL_DPDU, SL_GLOBAL_DPDV, SL_GLOBAL_L, SL_GLOBAL_CL, SL_GLOBAL_OL,
	SL_GLOBAL_PS, SL_GLOBAL_NCOMPS, SL_GLOBAL_TIME, SL_GLOBAL_DTIME, SL_GLOBAL_DPDTIME,
	SL_GLOBAL_ALPHA,      /* imager shaders only: the pixel's coverage */
	SL_GLOBAL_NS,        /* light shaders: the normal the lights are evaluated with */
	SL_GLOBAL_COUNT
};

/** RSL name of a global ("P", "Ci", "dPdu", ...). */
const char *sl_global_name(enum sl_global g);
/** Its type; .detail says whether it is uniform or varying. */
struct sl_type sl_global_type(enum sl_global g);

enum sl_reg_kind {
	SL_REG_TEMP,    /* an intermediate value */
	SL_REG_LOCAL,   /* a declared local variable (or an inlined function's) */
	SL_REG_PARAM,   /* a shader parameter */
	SL_REG_GLOBAL,  /* a global variable; .global says which */
	SL_REG_CONST,   /* a constant; value in the program's constant pool */
};

struct sl_reg {
	uint8_t kind;        /* enum sl_reg_kind */
	uint8_t type;        /* enum sl_basetype (never VOID; BOOL is stored like FLOAT) */
	bool varying;        /* after uniformity inference */
	bool output;         /* an output parameter (or an output global such as Ci) */
	bool declared_uniform; /* written `uniform` (parameters: not written `varying`) */
	bool promoted;       /* declared uniform, made varying by inference (see infer.c) */
	int32_t arraylen;    /* 0: not an array; n > 0: n elements */
	int32_t global;      /* SL_REG_GLOBAL: enum sl_global; else -1 */
	uint32_t cindex;     /* SL_REG_CONST: float offset into consts, or index into strings */
	const char *name;    /* variable's name; NULL for temporaries */
	struct sl_loc loc;   /* declaration */
};

/** Floats per element of @r (string registers: 0; they hold string pointers). */
static inline int sl_reg_ncomp(const struct sl_reg *r)
{
	return sl_type_ncomp(r->type);
}

/**
 * Instructions. "a", "b", "c" are args[0..2]. Unless stated, operands and
 * results are registers; float operands of an arithmetic op on triples are
 * broadcast to all three components; a varying result with uniform operands
 * is the uniform value at every point. Writes honour the running-state mask:
 * inactive points of a varying destination keep their value, and a uniform
 * destination is written if any point is active.
 *
 *   NOP
 *   MOV       dst = a. Same type, or float -> triple/matrix (matrix: a on the
 *             diagonal), or bool <-> float. Arrays: all elements.
 *   NEG       dst = -a                       (float, triple, matrix)
 *   ADD SUB   dst = a op b                   (componentwise; matrix + - matrix)
 *   MUL       dst = a * b                    (componentwise; float * matrix;
 *             matrix * matrix is the 4x4 product)
 *   DIV       dst = a / b                    (componentwise; matrix / matrix is
 *             a * inverse(b); x/0 gives 0, never Inf or NaN)
 *   DOT       dst(float) = a . b             (triples)
 *   CROSS     dst = a ^ b                    (triples)
 *   LT LE GT GE  dst(bool) = a op b          (floats)
 *   EQ NE     dst(bool) = a op b             (same type: float, triple, matrix, string)
 *   NOT       dst(bool) = !a
 *   AND OR    dst(bool) = a op b             (both evaluated)
 *   TRIPLE    dst(triple) = (a, b, c)        (three floats)
 *   MATRIX    dst(matrix) = 16 floats, row-major (args[0..15])
 *   COMP      dst(float) = a[imm]            (component imm of a triple, 0..2,
 *             or element imm of a matrix, 0..15)
 *   SETCOMP   dst[imm] = a                   (dst triple or matrix is read and written)
 *   AREF      dst = a[b]                     (a is an array, b a float index,
 *             truncated; out-of-range indices are clamped and reported once)
 *   ASET      dst[b] = a                     (dst is an array register)
 *   SELECT    dst = a ? b : c                (a bool; b and c already computed)
 *   CALL      dst = builtin(args)            (bi = index into sl_builtins[];
 *             dst is -1 for void built-ins; output arguments are written;
 *             imm = 1 on random() in a uniform context: one value for the
 *             grid, whatever dst's storage)
 *
 * Structured control flow. jump[] hold instruction indices.
 *   IF a          jump[0] = its ELSE (or ENDIF if none), jump[1] = its ENDIF.
 *                 Points where a is false are switched off until ELSE/ENDIF.
 *   ELSE          jump[0] = its IF, jump[1] = its ENDIF
 *   ENDIF         jump[0] = its IF
 *   LOOP          jump[0] = its LOOPTEST, jump[1] = its LOOPEND. Opens a loop;
 *                 the condition's code follows.
 *   LOOPTEST a    jump[0] = its LOOP, jump[1] = its LOOPEND. Points where a is
 *                 false leave the loop; when none is left, go past LOOPEND.
 *   LOOPCONT      jump[0] = its LOOP. Points that did `continue` come back on;
 *                 the step code (of a for) follows.
 *   LOOPEND       jump[0] = its LOOP: go back to the condition.
 *   BREAK         imm = how many enclosing loops (including illuminance) to leave
 *   CONTINUE      imm = which enclosing loop to continue
 *   FUNC          jump[0] = its FUNCEND: an inlined function body with `return`s
 *   RETURN        points leave the innermost FUNC (the value was stored before)
 *   FUNCEND       jump[0] = its FUNC
 *   ILLUMINANCE   args: [category (string)], P, [axis, angle]; imm = 1 if a
 *                 category is given. jump[0] = its ILLUMINANCE_END. For each
 *                 light (non-ambient, matching the category): L, Cl, Ol are set
 *                 and the body runs for the points inside the cone.
 *                 Counts as a loop for BREAK/CONTINUE.
 *   ILLUMINANCE_END jump[0] = its ILLUMINANCE
 *   ILLUMINATE    args: P, [axis, angle]. In light shaders: L = Ps - P; the body
 *                 runs where L is inside the cone. jump[0] = its ILLUMINATE_END
 *   SOLAR         args: [axis, angle]: L = axis (or, with no arguments, from
 *                 everywhere). jump[0] = its SOLAR_END
 *   ILLUMINATE_END, SOLAR_END  jump[0] = the opener
 */
enum sl_op {
	SL_OP_NOP,
	SL_OP_MOV, SL_OP_NEG, SL_OP_ADD, SL_OP_SUB, SL_OP_MUL, SL_OP_DIV,
	SL_OP_DOT, SL_OP_CROSS,
	SL_OP_LT, SL_OP_LE, SL_OP_GT, SL_OP_GE, SL_OP_EQ, SL_OP_NE,
	SL_OP_NOT, SL_OP_AND, SL_OP_OR,
	SL_OP_TRIPLE, SL_OP_MATRIX, SL_OP_COMP, SL_OP_SETCOMP, SL_OP_AREF, SL_OP_ASET,
	SL_OP_SELECT, SL_OP_CALL,
	SL_OP_IF, SL_OP_ELSE, SL_OP_ENDIF,
	SL_OP_LOOP, SL_OP_LOOPTEST, SL_OP_LOOPCONT, SL_OP_LOOPEND,
	SL_OP_BREAK, SL_OP_CONTINUE,
	SL_OP_FUNC, SL_OP_RETURN, SL_OP_FUNCEND,
	SL_OP_ILLUMINANCE, SL_OP_ILLUMINANCE_END,
	SL_OP_ILLUMINATE, SL_OP_ILLUMINATE_END,
	SL_OP_SOLAR, SL_OP_SOLAR_END,
	SL_OP_COUNT
};

/** Mnemonic of an op ("add", "loopend", ...). */
const char *sl_op_name(enum sl_op op);

struct sl_insn {
	uint16_t op;        /* enum sl_op */
	uint16_t nargs;
	int32_t bi;         /* SL_OP_CALL: index into sl_builtins[] */
	int32_t dst;        /* register, or -1 */
	int32_t imm;        /* COMP/SETCOMP component, BREAK/CONTINUE levels, ILLUMINANCE flag */
	int32_t jump[2];    /* control flow: see above */
	int32_t *args;      /* registers */
	struct sl_loc loc;  /* source of the statement or expression */
};

/**
 * A local declared `uniform` that inference made varying (it is assigned a
 * varying value, or assigned under varying control flow): it then holds one
 * value per point, exactly as if declared varying. `relight compile --emit
 * report` lists these.
 */
struct sl_promotion {
	int32_t reg;
	struct sl_loc at;     /* the write that made it vary */
	bool ctl;             /* ...because it runs under varying control flow */
};

/** A variable passed by reference to an `output uniform` formal of a function. */
struct sl_uniform_ref {
	int32_t reg;
	struct sl_loc loc;    /* the call */
	const char *func, *formal;
};

/** A shader parameter: its register and its default's code. */
struct sl_param {
	const char *name;
	struct sl_type type;   /* as declared (detail resolved: UNIFORM or VARYING) */
	int32_t reg;
	bool output;
	/*
	 * The instructions [init_begin, init_end) of the program compute the
	 * default; they run first, in order, before the body. The interpreter
	 * skips a parameter's initializer when the host set the parameter.
	 */
	uint32_t init_begin, init_end;
};

struct sl_program {
	struct rl_arena *arena;  /* owns everything below */
	enum sl_shader_kind kind;
	const char *name;
	const char *source_path;

	struct sl_reg *regs;
	uint32_t nregs;
	struct sl_insn *code;
	uint32_t ncode;
	uint32_t body_begin;     /* first instruction of the body (after parameter defaults) */

	struct sl_param *params;
	uint32_t nparams;

	float *consts;           /* constant pool: float components */
	uint32_t nconsts;
	const char **strings;    /* constant string pool (interned) */
	uint32_t nstrings;

	int32_t global_reg[SL_GLOBAL_COUNT];  /* register of each global used, or -1 */

	struct sl_promotion *promoted;   /* uniform locals made varying, by register */
	uint32_t npromoted;
	struct sl_uniform_ref *urefs;    /* arguments of output uniform formals */
	uint32_t nurefs;

	/* The files the source came from, for locations (index = sl_loc.file). */
	const char **files;
	uint32_t nfiles;

	/* Hash of the source texts (file, includes) and -D definitions, as 32 hex digits. */
	char source_hash[33];
	/* Hash of the tokens compiled (sl_program_hash), as 32 hex digits. */
	char program_hash[33];
	/* A surface joined with its atmosphere (sl_program_compose): the two
	   programs it was made from, which outlive it; else NULL. Its name is
	   "SURFACE+ATMOSPHERE", its source and hashes the surface's. */
	const struct sl_program *surface_part, *atmosphere;
	bool owns_parts;         /* sl_program_destroy() destroys them too */
	uint32_t atmosphere_begin;  /* the first instruction of the atmosphere's body */
};

/** Print one instruction as "  12  add %t3:color <- %Cs, %t2  ; file:line". */
void sl_ir_print_insn(const struct sl_program *prog, uint32_t i, FILE *out);
/** Print all registers, parameters and instructions. */
void sl_ir_dump(const struct sl_program *prog, FILE *out);
/** A register's printable name ("Ci", "Kd", "t12", "k3"). Static buffer rotated 4 ways. */
const char *sl_ir_reg_name(const struct sl_program *prog, int32_t reg);

/** Whether argument @k of @in is an output of its built-in (written, not read). */
bool sl_ir_arg_is_output(const struct sl_insn *in, int k);

/**
 * Whether the atmosphere of a joined program (sl_program_compose) keeps the
 * program a sum over its lights, as the GPU preview's one-light-at-a-time
 * kernels need (docs/specialization.md): its colour affine in the surface's
 * Ci with coefficients no light changes, its own light samples accumulated.
 * NULL when it does (or there is no atmosphere), else why not, and where in
 * *@at.
 */
const char *sl_program_atmosphere_nonaffine(const struct sl_program *p, struct sl_loc *at);

/** Say so on @diag, as FILE:LINE: a warning or an @error; true when it is not a sum. */
bool sl_program_report_nonaffine(const struct sl_program *p, FILE *diag, bool error);

/**
 * The ray-tracing calls of @p whose value the bake keeps though it comes from
 * lit surfaces (trace(), indirectdiffuse(), environment("raytrace") of a
 * non-constant or "raytrace" name): say, as FILE:LINE, that the preview
 * keeps their baked value, which does not follow light edits; a warning, or
 * an @error. The number of calls said.
 */
uint32_t sl_program_report_frozen_rays(const struct sl_program *p, FILE *diag, bool error);

/** Index of parameter @name, or -1. */
int sl_program_find_param(const struct sl_program *prog, const char *name);

#endif

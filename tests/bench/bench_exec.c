/*
 * Throughput of the grid interpreter on varying arithmetic: hand-built
 * programs of float and color add / mul / multiply-add chains run over a
 * 1024-point grid on one thread. An "operation" is one instruction applied
 * to one point, so a color add over 1024 points counts 1024.
 *
 * Usage: bench_exec [seconds per case, default 0.5]
 */
#include "exec_impl.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define NU 32
#define NV 32
#define NPTS (NU * NV)

struct pb {
	struct rl_arena *arena;
	RL_VEC(struct sl_reg) regs;
	RL_VEC(struct sl_insn) code;
	RL_VEC(float) consts;
	int32_t global_reg[SL_GLOBAL_COUNT];
	struct sl_program prog;
	uint32_t nops;          /* arithmetic instructions, per point */
};

static void pb_init(struct pb *b)
{
	memset(b, 0, sizeof(*b));
	b->arena = rl_arena_create();
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		b->global_reg[g] = -1;
}

static void pb_free(struct pb *b)
{
	rl_vec_free(b->regs);
	rl_vec_free(b->code);
	rl_vec_free(b->consts);
	rl_arena_destroy(b->arena);
}

static int32_t newreg(struct pb *b, int kind, int type, bool varying)
{
	struct sl_reg r = { .kind = (uint8_t)kind, .type = (uint8_t)type, .varying = varying,
			    .global = -1 };
	rl_vec_push(b->regs, r);
	return (int32_t)b->regs.len - 1;
}

static int32_t vreg(struct pb *b, int type)
{
	return newreg(b, SL_REG_TEMP, type, true);
}

static int32_t kconst(struct pb *b, int type, float x, float y, float z)
{
	int32_t r = newreg(b, SL_REG_CONST, type, false);
	b->regs.data[r].cindex = (uint32_t)b->consts.len;
	rl_vec_push(b->consts, x);
	if (type != SL_TYPE_FLOAT) {
		rl_vec_push(b->consts, y);
		rl_vec_push(b->consts, z);
	}
	return r;
}

static int32_t glob(struct pb *b, enum sl_global g, int type)
{
	int32_t r = newreg(b, SL_REG_GLOBAL, type, true);
	b->regs.data[r].global = g;
	b->global_reg[g] = r;
	return r;
}

static uint32_t emit(struct pb *b, int op, int32_t dst, int nargs, ...)
{
	struct sl_insn in = { .op = (uint16_t)op, .nargs = (uint16_t)nargs, .dst = dst,
			      .jump = { -1, -1 } };
	in.args = rl_arena_alloc(b->arena, sizeof(int32_t) * (size_t)(nargs ? nargs : 1));
	va_list ap;
	va_start(ap, nargs);
	for (int k = 0; k < nargs; k++)
		in.args[k] = va_arg(ap, int32_t);
	va_end(ap);
	rl_vec_push(b->code, in);
	if (op >= SL_OP_MOV && op <= SL_OP_OR)
		b->nops++;
	return (uint32_t)b->code.len - 1;
}

static struct sl_program *pb_finish(struct pb *b)
{
	struct sl_program *p = &b->prog;
	memset(p, 0, sizeof(*p));
	p->arena = b->arena;
	p->kind = SL_SHADER_SURFACE;
	p->name = "bench";
	p->nregs = (uint32_t)b->regs.len;
	p->regs = b->regs.data;
	p->ncode = (uint32_t)b->code.len;
	p->code = b->code.data;
	p->nconsts = (uint32_t)b->consts.len;
	p->consts = b->consts.data;
	memcpy(p->global_reg, b->global_reg, sizeof(p->global_reg));
	return p;
}

/* Float chain, all operands varying: x = x + s; y = y + x; ... */
static void build_float_add(struct pb *b)
{
	int32_t s = glob(b, SL_GLOBAL_S, SL_TYPE_FLOAT), t = glob(b, SL_GLOBAL_T, SL_TYPE_FLOAT);
	int32_t x = vreg(b, SL_TYPE_FLOAT), y = vreg(b, SL_TYPE_FLOAT);
	emit(b, SL_OP_ADD, x, 2, s, t);
	emit(b, SL_OP_ADD, y, 2, x, t);
	for (int k = 0; k < 30; k++) {
		emit(b, SL_OP_ADD, x, 2, x, y);
		emit(b, SL_OP_SUB, y, 2, y, s);
	}
}

/* Float multiply-add chain with uniform constants: x = x * k + s. */
static void build_float_madd(struct pb *b)
{
	int32_t s = glob(b, SL_GLOBAL_S, SL_TYPE_FLOAT), t = glob(b, SL_GLOBAL_T, SL_TYPE_FLOAT);
	int32_t k = kconst(b, SL_TYPE_FLOAT, 0.5f, 0, 0), k2 = kconst(b, SL_TYPE_FLOAT, 1.5f, 0, 0);
	int32_t x = vreg(b, SL_TYPE_FLOAT), y = vreg(b, SL_TYPE_FLOAT);
	emit(b, SL_OP_MUL, x, 2, s, t);
	for (int i = 0; i < 20; i++) {
		emit(b, SL_OP_MUL, y, 2, x, k);      /* varying * uniform */
		emit(b, SL_OP_ADD, x, 2, y, s);      /* varying + varying */
		emit(b, SL_OP_MUL, y, 2, k2, x);     /* uniform * varying */
		emit(b, SL_OP_SUB, x, 2, k, y);      /* uniform - varying */
	}
}

/* Color chain: Ci = Ci * Cs + Os * k; with float * color broadcasts. */
static void build_color(struct pb *b)
{
	int32_t Cs = glob(b, SL_GLOBAL_CS, SL_TYPE_COLOR), Os = glob(b, SL_GLOBAL_OS, SL_TYPE_COLOR);
	int32_t s = glob(b, SL_GLOBAL_S, SL_TYPE_FLOAT);
	int32_t kc = kconst(b, SL_TYPE_COLOR, 0.25f, 0.5f, 0.75f);
	int32_t kf = kconst(b, SL_TYPE_FLOAT, 0.9f, 0, 0);
	int32_t c = vreg(b, SL_TYPE_COLOR), d = vreg(b, SL_TYPE_COLOR);
	emit(b, SL_OP_MUL, c, 2, Cs, Os);
	for (int i = 0; i < 12; i++) {
		emit(b, SL_OP_MUL, d, 2, c, Cs);     /* color * color */
		emit(b, SL_OP_ADD, c, 2, d, kc);     /* color + uniform color */
		emit(b, SL_OP_MUL, d, 2, s, c);      /* float * color */
		emit(b, SL_OP_ADD, c, 2, d, Os);     /* color + color */
		emit(b, SL_OP_MUL, c, 2, c, kf);     /* color * uniform float */
	}
}

/* The float chain under a varying if that keeps half the points. */
static void build_masked(struct pb *b)
{
	int32_t s = glob(b, SL_GLOBAL_S, SL_TYPE_FLOAT), t = glob(b, SL_GLOBAL_T, SL_TYPE_FLOAT);
	int32_t half = kconst(b, SL_TYPE_FLOAT, 0.5f, 0, 0);
	int32_t c = vreg(b, SL_TYPE_BOOL);
	int32_t x = vreg(b, SL_TYPE_FLOAT), y = vreg(b, SL_TYPE_FLOAT);
	emit(b, SL_OP_MOV, x, 1, s);
	emit(b, SL_OP_MOV, y, 1, t);
	emit(b, SL_OP_LT, c, 2, s, half);
	uint32_t i = emit(b, SL_OP_IF, -1, 1, c);
	for (int k = 0; k < 20; k++) {
		emit(b, SL_OP_MUL, y, 2, x, half);
		emit(b, SL_OP_ADD, x, 2, x, y);
	}
	uint32_t e = emit(b, SL_OP_ENDIF, -1, 0);
	b->code.data[i].jump[0] = b->code.data[i].jump[1] = (int32_t)e;
	b->code.data[e].jump[0] = (int32_t)i;
}

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

struct bench_case {
	const char *name;
	void (*build)(struct pb *b);
};

int main(int argc, char **argv)
{
	double budget = argc > 1 ? atof(argv[1]) : 0.5;
	if (!(budget > 0))
		budget = 0.5;
	static const struct bench_case cases[] = {
		{ "float add/sub, varying x varying", build_float_add },
		{ "float mul/add, varying x uniform mix", build_float_madd },
		{ "color mul/add/madd", build_color },
		{ "float madd under a half-grid mask", build_masked },
	};
	double total_ops = 0, total_time = 0;
	int status = 0;
	printf("grid %dx%d, one thread\n", NU, NV);
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct pb b;
		pb_init(&b);
		cases[c].build(&b);
		struct sl_program *prog = pb_finish(&b);
		struct sl_exec *x = sl_exec_create(prog, NPTS);
		if (!x) {
			fprintf(stderr, "bench_exec: cannot create the executor for '%s'\n",
				cases[c].name);
			pb_free(&b);
			status = 1;
			continue;
		}
		sl_exec_set_grid(x, NU, NV);
		for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
			bool v;
			float *d = sl_exec_global(x, (enum sl_global)g, &v);
			if (!d)
				continue;
			int nc = sl_reg_ncomp(&prog->regs[prog->global_reg[g]]);
			for (int k = 0; k < nc; k++)
				for (uint32_t i = 0; i < NPTS; i++)
					d[(size_t)k * x->stride + i] =
						(float)((i * 7 + (uint32_t)k * 13) % 101) / 101.0f;
		}
		/* Count the points each instruction runs for (the masked case: fewer). */
		double active = NPTS;
		if (cases[c].build == build_masked) {
			float *s = sl_exec_global(x, SL_GLOBAL_S, NULL);
			active = 0;
			for (uint32_t i = 0; i < NPTS; i++)
				active += s[i] < 0.5f;
		}
		sl_exec_run(x, NULL);   /* warm up */
		long reps = 0;
		double t0 = now(), t1;
		do {
			for (int k = 0; k < 64; k++)
				if (!sl_exec_run(x, NULL))
					status = 1;
			reps += 64;
			t1 = now();
		} while (t1 - t0 < budget);
		double ops;
		if (cases[c].build == build_masked)
			ops = (double)reps * (3.0 * NPTS + (double)(b.nops - 3) * active);
		else
			ops = (double)reps * b.nops * NPTS;
		double secs = t1 - t0;
		printf("%-40s %4u ops/pt  %9.1f M varying ops/s  (%.2f us/run)\n", cases[c].name,
		       b.nops, ops / secs * 1e-6, secs / (double)reps * 1e6);
		total_ops += ops;
		total_time += secs;
		sl_exec_destroy(x);
		pb_free(&b);
	}
	printf("%-40s               %9.1f M varying ops/s\n", "overall", total_ops / total_time * 1e-6);
	return status;
}

/*
 * Tests of the grid interpreter's core (exec.c) and the light host, on
 * programs built by hand: every op, masks through nested control flow,
 * loops with per-point trip counts, parameters, derivatives, lights; and,
 * on compiled shaders, derivatives over stencils of samples taken off
 * their grids.
 */
#include "exec_impl.h"
#include "lighthost.h"
#include "sl.h"
#include "test.h"

#include <float.h>
#include <stdarg.h>
#include <time.h>
#include <unistd.h>

/* ------------------------------------------------------------------------ */
/* A program builder                                                         */

struct pb {
	struct rl_arena *arena;
	enum sl_shader_kind kind;
	RL_VEC(struct sl_reg) regs;
	RL_VEC(struct sl_insn) code;
	RL_VEC(float) consts;
	RL_VEC(const char *) strings;
	RL_VEC(struct sl_param) params;
	int32_t global_reg[SL_GLOBAL_COUNT];
	uint32_t body_begin;
	struct sl_program prog;
};

static const char *test_files[] = { "test.sl" };

static void pb_init(struct pb *b, enum sl_shader_kind kind)
{
	memset(b, 0, sizeof(*b));
	b->arena = rl_arena_create();
	b->kind = kind;
	for (int g = 0; g < SL_GLOBAL_COUNT; g++)
		b->global_reg[g] = -1;
}

static void pb_free(struct pb *b)
{
	rl_vec_free(b->regs);
	rl_vec_free(b->code);
	rl_vec_free(b->consts);
	rl_vec_free(b->strings);
	rl_vec_free(b->params);
	rl_arena_destroy(b->arena);
}

static int32_t newreg(struct pb *b, int kind, int type, bool varying, int32_t arraylen)
{
	struct sl_reg r = {
		.kind = (uint8_t)kind, .type = (uint8_t)type, .varying = varying,
		.arraylen = arraylen, .global = -1,
	};
	rl_vec_push(b->regs, r);
	return (int32_t)b->regs.len - 1;
}

static int32_t vreg(struct pb *b, int type)
{
	return newreg(b, SL_REG_TEMP, type, true, 0);
}

static int32_t ureg(struct pb *b, int type)
{
	return newreg(b, SL_REG_TEMP, type, false, 0);
}

static int32_t kconst(struct pb *b, int type, int n, const float *v)
{
	int32_t r = newreg(b, SL_REG_CONST, type, false, 0);
	b->regs.data[r].cindex = (uint32_t)b->consts.len;
	for (int i = 0; i < n; i++)
		rl_vec_push(b->consts, v[i]);
	return r;
}

static int32_t kf(struct pb *b, float v)
{
	return kconst(b, SL_TYPE_FLOAT, 1, &v);
}

static int32_t kt(struct pb *b, int type, float x, float y, float z)
{
	float v[3] = { x, y, z };
	return kconst(b, type, 3, v);
}

static int32_t ks(struct pb *b, const char *s)
{
	int32_t r = newreg(b, SL_REG_CONST, SL_TYPE_STRING, false, 0);
	b->regs.data[r].cindex = (uint32_t)b->strings.len;
	rl_vec_push(b->strings, rl_arena_strdup(b->arena, s));
	return r;
}

static int32_t glob(struct pb *b, enum sl_global g, int type, bool varying)
{
	int32_t r = newreg(b, SL_REG_GLOBAL, type, varying, 0);
	b->regs.data[r].global = g;
	b->global_reg[g] = r;
	return r;
}

static uint32_t emitv(struct pb *b, int op, int32_t dst, int nargs, va_list ap)
{
	struct sl_insn in = { .op = (uint16_t)op, .nargs = (uint16_t)nargs, .dst = dst,
			      .jump = { -1, -1 } };
	in.args = rl_arena_alloc(b->arena, sizeof(int32_t) * (size_t)(nargs ? nargs : 1));
	for (int k = 0; k < nargs; k++)
		in.args[k] = va_arg(ap, int32_t);
	in.loc = (struct sl_loc){ 0, (uint32_t)b->code.len + 1, 1 };
	rl_vec_push(b->code, in);
	return (uint32_t)b->code.len - 1;
}

static uint32_t emit(struct pb *b, int op, int32_t dst, int nargs, ...)
{
	va_list ap;
	va_start(ap, nargs);
	uint32_t i = emitv(b, op, dst, nargs, ap);
	va_end(ap);
	return i;
}

#define INS(b, i) ((b)->code.data[i])

static uint32_t c_if(struct pb *b, int32_t cond)
{
	return emit(b, SL_OP_IF, -1, 1, cond);
}

static void c_else(struct pb *b, uint32_t i)
{
	uint32_t e = emit(b, SL_OP_ELSE, -1, 0);
	INS(b, i).jump[0] = (int32_t)e;
	INS(b, e).jump[0] = (int32_t)i;
}

static void c_endif(struct pb *b, uint32_t i)
{
	uint32_t e = emit(b, SL_OP_ENDIF, -1, 0);
	INS(b, e).jump[0] = (int32_t)i;
	INS(b, i).jump[1] = (int32_t)e;
	if (INS(b, i).jump[0] < 0)
		INS(b, i).jump[0] = (int32_t)e;
	else
		INS(b, INS(b, i).jump[0]).jump[1] = (int32_t)e;
}

static uint32_t c_loop(struct pb *b)
{
	return emit(b, SL_OP_LOOP, -1, 0);
}

static void c_looptest(struct pb *b, uint32_t l, int32_t cond)
{
	uint32_t t = emit(b, SL_OP_LOOPTEST, -1, 1, cond);
	INS(b, l).jump[0] = (int32_t)t;
	INS(b, t).jump[0] = (int32_t)l;
}

static void c_loopcont(struct pb *b, uint32_t l)
{
	uint32_t c = emit(b, SL_OP_LOOPCONT, -1, 0);
	INS(b, c).jump[0] = (int32_t)l;
}

static void c_loopend(struct pb *b, uint32_t l)
{
	uint32_t e = emit(b, SL_OP_LOOPEND, -1, 0);
	INS(b, e).jump[0] = (int32_t)l;
	INS(b, l).jump[1] = (int32_t)e;
	INS(b, INS(b, l).jump[0]).jump[1] = (int32_t)e;
}

static void c_jump(struct pb *b, int op, int levels)
{
	uint32_t i = emit(b, op, -1, 0);
	INS(b, i).imm = levels;
}

/* Close the block opened at @open with @op. */
static void c_end(struct pb *b, int op, uint32_t open)
{
	uint32_t e = emit(b, op, -1, 0);
	INS(b, e).jump[0] = (int32_t)open;
	INS(b, open).jump[0] = (int32_t)e;
}

/* A parameter whose default is computed by the code emitted until param_done(). */
static int32_t param(struct pb *b, const char *name, int type, bool varying, int32_t arraylen)
{
	int32_t r = newreg(b, SL_REG_PARAM, type, varying, arraylen);
	struct sl_param p = {
		.name = rl_arena_strdup(b->arena, name),
		.type = { (uint8_t)type, varying ? SL_DETAIL_VARYING : SL_DETAIL_UNIFORM,
			  arraylen ? arraylen : -1 },
		.reg = r,
		.init_begin = (uint32_t)b->code.len,
		.init_end = (uint32_t)b->code.len,
	};
	b->regs.data[r].name = p.name;
	rl_vec_push(b->params, p);
	return r;
}

static void param_done(struct pb *b)
{
	b->params.data[b->params.len - 1].init_end = (uint32_t)b->code.len;
}

static void body(struct pb *b)
{
	b->body_begin = (uint32_t)b->code.len;
}

static struct sl_program *pb_finish(struct pb *b)
{
	struct sl_program *p = &b->prog;
	memset(p, 0, sizeof(*p));
	p->arena = b->arena;
	p->kind = b->kind;
	p->name = "test";
	p->nregs = (uint32_t)b->regs.len;
	p->regs = rl_arena_alloc(b->arena, sizeof(struct sl_reg) * (b->regs.len + 1));
	if (b->regs.len)
		memcpy(p->regs, b->regs.data, sizeof(struct sl_reg) * b->regs.len);
	p->ncode = (uint32_t)b->code.len;
	p->code = rl_arena_alloc(b->arena, sizeof(struct sl_insn) * (b->code.len + 1));
	if (b->code.len)
		memcpy(p->code, b->code.data, sizeof(struct sl_insn) * b->code.len);
	p->nconsts = (uint32_t)b->consts.len;
	p->consts = rl_arena_alloc(b->arena, sizeof(float) * (b->consts.len + 1));
	if (b->consts.len)
		memcpy(p->consts, b->consts.data, sizeof(float) * b->consts.len);
	p->nstrings = (uint32_t)b->strings.len;
	p->strings = rl_arena_alloc(b->arena, sizeof(char *) * (b->strings.len + 1));
	if (b->strings.len)
		memcpy(p->strings, b->strings.data, sizeof(char *) * b->strings.len);
	p->nparams = (uint32_t)b->params.len;
	p->params = rl_arena_alloc(b->arena, sizeof(struct sl_param) * (b->params.len + 1));
	if (b->params.len)
		memcpy(p->params, b->params.data, sizeof(struct sl_param) * b->params.len);
	p->body_begin = b->body_begin;
	memcpy(p->global_reg, b->global_reg, sizeof(p->global_reg));
	p->files = test_files;
	p->nfiles = 1;
	return p;
}

/* Value of register @r, component @c, point @i. */
static float R(struct sl_exec *x, int32_t r, int c, uint32_t i)
{
	return sl_x_get(x, r, c, i);
}

/* Set a varying float global from @vals (n points). */
static void set_global1(struct sl_exec *x, enum sl_global g, const float *vals)
{
	bool v;
	float *d = sl_exec_global(x, g, &v);
	for (uint32_t i = 0; i < (v ? x->n : 1); i++)
		d[i] = vals[i];
}

/* Set a triple global's component c at point i. */
static void set_global3(struct sl_exec *x, enum sl_global g, uint32_t i, float a, float b2,
			float c)
{
	bool v;
	float *d = sl_exec_global(x, g, &v);
	size_t s = v ? x->stride : 1;
	size_t o = v ? i : 0;
	d[o] = a;
	d[s + o] = b2;
	d[2 * s + o] = c;
}

/* Capture stderr while @fn runs into @buf. */
static void capture_stderr(char *buf, size_t cap, bool (*fn)(void *), void *arg, bool *result)
{
	fflush(stderr);
	FILE *tmp = tmpfile();
	int saved = dup(2);
	dup2(fileno(tmp), 2);
	*result = fn(arg);
	fflush(stderr);
	dup2(saved, 2);
	close(saved);
	rewind(tmp);
	size_t n = fread(buf, 1, cap - 1, tmp);
	buf[n] = 0;
	fclose(tmp);
}

/* ------------------------------------------------------------------------ */
/* Arithmetic                                                                */

static void test_arith(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t t = glob(&b, SL_GLOBAL_T, SL_TYPE_FLOAT, true);
	int32_t Cs = glob(&b, SL_GLOBAL_CS, SL_TYPE_COLOR, true);
	int32_t k2 = kf(&b, 2), k0 = kf(&b, 0), k3 = kf(&b, 3);
	int32_t big = kf(&b, 1e30f);
	body(&b);
	int32_t add_vv = vreg(&b, SL_TYPE_FLOAT), add_vu = vreg(&b, SL_TYPE_FLOAT);
	int32_t sub_uv = vreg(&b, SL_TYPE_FLOAT), mul_uu_v = vreg(&b, SL_TYPE_FLOAT);
	int32_t mul_uu_u = ureg(&b, SL_TYPE_FLOAT), div_vv = vreg(&b, SL_TYPE_FLOAT);
	int32_t div_v0 = vreg(&b, SL_TYPE_FLOAT), neg = vreg(&b, SL_TYPE_FLOAT);
	int32_t cmul = vreg(&b, SL_TYPE_COLOR), cadd = vreg(&b, SL_TYPE_COLOR);
	int32_t cdiv = vreg(&b, SL_TYPE_COLOR), cneg = vreg(&b, SL_TYPE_COLOR);
	int32_t fsub = vreg(&b, SL_TYPE_COLOR);
	int32_t ovf = vreg(&b, SL_TYPE_FLOAT), ovf2 = vreg(&b, SL_TYPE_FLOAT);
	int32_t tiny = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_ADD, add_vv, 2, s, t);
	emit(&b, SL_OP_ADD, add_vu, 2, s, k2);
	emit(&b, SL_OP_SUB, sub_uv, 2, k3, t);
	emit(&b, SL_OP_MUL, mul_uu_v, 2, k2, k3);
	emit(&b, SL_OP_MUL, mul_uu_u, 2, k2, k3);
	emit(&b, SL_OP_DIV, div_vv, 2, s, t);
	emit(&b, SL_OP_DIV, div_v0, 2, s, k0);
	emit(&b, SL_OP_NEG, neg, 1, s);
	emit(&b, SL_OP_MUL, cmul, 2, Cs, k2);
	emit(&b, SL_OP_ADD, cadd, 2, Cs, Cs);
	emit(&b, SL_OP_DIV, cdiv, 2, k3, Cs);
	emit(&b, SL_OP_NEG, cneg, 1, Cs);
	emit(&b, SL_OP_SUB, fsub, 2, s, Cs);
	emit(&b, SL_OP_MUL, ovf, 2, big, big);
	emit(&b, SL_OP_SUB, ovf2, 2, neg, big);
	emit(&b, SL_OP_MUL, ovf2, 2, ovf2, big);
	emit(&b, SL_OP_DIV, tiny, 2, big, kf(&b, 1e-30f));
	struct sl_program *prog = pb_finish(&b);

	struct sl_exec *x = sl_exec_create(prog, 8);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	CHECK(sl_exec_set_grid(x, 4, 1));
	const float sv[4] = { 1, 2, -3, 0.5f }, tv[4] = { 0, 4, 2, -1 };
	set_global1(x, SL_GLOBAL_S, sv);
	set_global1(x, SL_GLOBAL_T, tv);
	for (uint32_t i = 0; i < 4; i++)
		set_global3(x, SL_GLOBAL_CS, i, sv[i], tv[i], 1);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t i = 0; i < 4; i++) {
		CHECK_NEAR(R(x, add_vv, 0, i), sv[i] + tv[i], 1e-6);
		CHECK_NEAR(R(x, add_vu, 0, i), sv[i] + 2, 1e-6);
		CHECK_NEAR(R(x, sub_uv, 0, i), 3 - tv[i], 1e-6);
		CHECK_NEAR(R(x, mul_uu_v, 0, i), 6, 0);
		CHECK_NEAR(R(x, div_vv, 0, i), tv[i] == 0 ? 0 : sv[i] / tv[i], 1e-6);
		CHECK_NEAR(R(x, div_v0, 0, i), 0, 0);
		CHECK_NEAR(R(x, neg, 0, i), -sv[i], 0);
		float cs[3] = { sv[i], tv[i], 1 };
		for (int c = 0; c < 3; c++) {
			CHECK_NEAR(R(x, cmul, c, i), 2 * cs[c], 1e-6);
			CHECK_NEAR(R(x, cadd, c, i), 2 * cs[c], 1e-6);
			CHECK_NEAR(R(x, cdiv, c, i), cs[c] == 0 ? 0 : 3 / cs[c], 1e-6);
			CHECK_NEAR(R(x, cneg, c, i), -cs[c], 0);
			CHECK_NEAR(R(x, fsub, c, i), sv[i] - cs[c], 1e-6);
		}
		CHECK(R(x, ovf, 0, i) == FLT_MAX);
		CHECK(R(x, ovf2, 0, i) == -FLT_MAX);
		CHECK(R(x, tiny, 0, i) == FLT_MAX);
	}
	CHECK_NEAR(x->data[mul_uu_u][0], 6, 0);
	/* Component 1 of point 0 divides by t = 0: only that component is 0. */
	CHECK_NEAR(R(x, cdiv, 0, 0), 3, 1e-6);
	CHECK_NEAR(R(x, cdiv, 1, 0), 0, 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

static void test_compare_logic(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t t = glob(&b, SL_GLOBAL_T, SL_TYPE_FLOAT, true);
	int32_t k1 = kf(&b, 1);
	int32_t c1 = kt(&b, SL_TYPE_COLOR, 1, 2, 3), c2 = kt(&b, SL_TYPE_COLOR, 1, 2, 3);
	int32_t c3 = kt(&b, SL_TYPE_COLOR, 1, 2, 4);
	/* Two string constants with equal contents in different storage. */
	int32_t sa = ks(&b, "plastic"), sb = ks(&b, "plastic"), sc = ks(&b, "metal");
	body(&b);
	int32_t lt = vreg(&b, SL_TYPE_BOOL), le = vreg(&b, SL_TYPE_BOOL);
	int32_t gt = vreg(&b, SL_TYPE_BOOL), ge = vreg(&b, SL_TYPE_BOOL);
	int32_t eq = vreg(&b, SL_TYPE_BOOL), ne = vreg(&b, SL_TYPE_BOOL);
	int32_t nt = vreg(&b, SL_TYPE_BOOL), an = vreg(&b, SL_TYPE_BOOL), orr = vreg(&b, SL_TYPE_BOOL);
	int32_t ceq = ureg(&b, SL_TYPE_BOOL), cne = ureg(&b, SL_TYPE_BOOL);
	int32_t seq = ureg(&b, SL_TYPE_BOOL), sne = ureg(&b, SL_TYPE_BOOL);
	int32_t vstr = vreg(&b, SL_TYPE_STRING), vseq = vreg(&b, SL_TYPE_BOOL);
	int32_t asf = vreg(&b, SL_TYPE_FLOAT), asb = vreg(&b, SL_TYPE_BOOL);
	emit(&b, SL_OP_LT, lt, 2, s, t);
	emit(&b, SL_OP_LE, le, 2, s, t);
	emit(&b, SL_OP_GT, gt, 2, s, t);
	emit(&b, SL_OP_GE, ge, 2, s, k1);
	emit(&b, SL_OP_EQ, eq, 2, s, t);
	emit(&b, SL_OP_NE, ne, 2, s, t);
	emit(&b, SL_OP_NOT, nt, 1, lt);
	emit(&b, SL_OP_AND, an, 2, le, ge);
	emit(&b, SL_OP_OR, orr, 2, lt, ge);
	emit(&b, SL_OP_EQ, ceq, 2, c1, c2);
	emit(&b, SL_OP_NE, cne, 2, c1, c3);
	emit(&b, SL_OP_EQ, seq, 2, sa, sb);
	emit(&b, SL_OP_NE, sne, 2, sa, sc);
	/* A varying string: "metal" where s < t, else "plastic"; compare with "metal". */
	emit(&b, SL_OP_SELECT, vstr, 3, lt, sc, sa);
	emit(&b, SL_OP_EQ, vseq, 2, vstr, sc);
	/* bool <-> float moves */
	emit(&b, SL_OP_MOV, asf, 1, gt);
	emit(&b, SL_OP_MOV, asb, 1, s);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[4] = { 0, 1, 2, 3 }, tv[4] = { 1, 1, 1, 1 };
	set_global1(x, SL_GLOBAL_S, sv);
	set_global1(x, SL_GLOBAL_T, tv);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t i = 0; i < 4; i++) {
		CHECK(R(x, lt, 0, i) == (sv[i] < tv[i]));
		CHECK(R(x, le, 0, i) == (sv[i] <= tv[i]));
		CHECK(R(x, gt, 0, i) == (sv[i] > tv[i]));
		CHECK(R(x, ge, 0, i) == (sv[i] >= 1));
		CHECK(R(x, eq, 0, i) == (sv[i] == tv[i]));
		CHECK(R(x, ne, 0, i) == (sv[i] != tv[i]));
		CHECK(R(x, nt, 0, i) == !(sv[i] < tv[i]));
		CHECK(R(x, an, 0, i) == (sv[i] <= tv[i] && sv[i] >= 1));
		CHECK(R(x, orr, 0, i) == (sv[i] < tv[i] || sv[i] >= 1));
		CHECK_STR(sl_x_str(x, vstr, i), sv[i] < tv[i] ? "metal" : "plastic");
		CHECK(R(x, vseq, 0, i) == (sv[i] < tv[i]));
		CHECK(R(x, asf, 0, i) == (sv[i] > tv[i]));
		CHECK(R(x, asb, 0, i) == sv[i]);
	}
	CHECK(x->data[ceq][0] == 1);
	CHECK(x->data[cne][0] == 1);
	CHECK(x->data[seq][0] == 1);
	CHECK(x->data[sne][0] == 1);
	sl_exec_destroy(x);
	pb_free(&b);
}

static void test_triples(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t P = glob(&b, SL_GLOBAL_P, SL_TYPE_POINT, true);
	int32_t k1 = kf(&b, 1), k2 = kf(&b, 2);
	int32_t ux = kt(&b, SL_TYPE_VECTOR, 1, 0, 0);
	body(&b);
	int32_t tr = vreg(&b, SL_TYPE_VECTOR), dot = vreg(&b, SL_TYPE_FLOAT);
	int32_t cr = vreg(&b, SL_TYPE_VECTOR), cru = vreg(&b, SL_TYPE_VECTOR);
	int32_t cy = vreg(&b, SL_TYPE_FLOAT), sc = vreg(&b, SL_TYPE_VECTOR);
	int32_t bc = vreg(&b, SL_TYPE_COLOR), bcu = ureg(&b, SL_TYPE_COLOR);
	int32_t m = ureg(&b, SL_TYPE_MATRIX), mv = vreg(&b, SL_TYPE_MATRIX);
	int32_t mc = vreg(&b, SL_TYPE_FLOAT), dotu = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_TRIPLE, tr, 3, s, k1, k2);           /* (s, 1, 2) */
	emit(&b, SL_OP_DOT, dot, 2, tr, P);
	emit(&b, SL_OP_CROSS, cr, 2, tr, P);
	emit(&b, SL_OP_CROSS, cru, 2, ux, tr);              /* uniform x varying */
	emit(&b, SL_OP_COMP, cy, 1, P);
	INS(&b, b.code.len - 1).imm = 1;
	emit(&b, SL_OP_MOV, sc, 1, P);
	emit(&b, SL_OP_SETCOMP, sc, 1, s);
	INS(&b, b.code.len - 1).imm = 2;
	emit(&b, SL_OP_MOV, bc, 1, s);                      /* float -> color */
	emit(&b, SL_OP_MOV, bcu, 1, k2);
	emit(&b, SL_OP_MOV, m, 1, k2);                      /* float -> matrix */
	emit(&b, SL_OP_MOV, mv, 1, s);
	emit(&b, SL_OP_COMP, mc, 1, mv);
	INS(&b, b.code.len - 1).imm = 10;
	emit(&b, SL_OP_DOT, dotu, 2, ux, P);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[4] = { 1, -2, 0.5f, 3 };
	float Pv[4][3] = { { 1, 2, 3 }, { 0, 1, 0 }, { -1, 4, 2 }, { 2, 2, 2 } };
	set_global1(x, SL_GLOBAL_S, sv);
	for (uint32_t i = 0; i < 4; i++)
		set_global3(x, SL_GLOBAL_P, i, Pv[i][0], Pv[i][1], Pv[i][2]);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t i = 0; i < 4; i++) {
		float a[3] = { sv[i], 1, 2 }, *p = Pv[i];
		CHECK_NEAR(R(x, tr, 0, i), sv[i], 0);
		CHECK_NEAR(R(x, tr, 2, i), 2, 0);
		CHECK_NEAR(R(x, dot, 0, i), a[0] * p[0] + a[1] * p[1] + a[2] * p[2], 1e-5);
		CHECK_NEAR(R(x, cr, 0, i), a[1] * p[2] - a[2] * p[1], 1e-5);
		CHECK_NEAR(R(x, cr, 1, i), a[2] * p[0] - a[0] * p[2], 1e-5);
		CHECK_NEAR(R(x, cr, 2, i), a[0] * p[1] - a[1] * p[0], 1e-5);
		/* (1,0,0) x (s,1,2) = (0, -2, 1) */
		CHECK_NEAR(R(x, cru, 0, i), 0, 0);
		CHECK_NEAR(R(x, cru, 1, i), -2, 0);
		CHECK_NEAR(R(x, cru, 2, i), 1, 0);
		CHECK_NEAR(R(x, cy, 0, i), p[1], 0);
		CHECK_NEAR(R(x, sc, 0, i), p[0], 0);
		CHECK_NEAR(R(x, sc, 2, i), sv[i], 0);
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(R(x, bc, c, i), sv[i], 0);
		CHECK_NEAR(R(x, mc, 0, i), sv[i], 0);       /* element 10 is on the diagonal */
		CHECK_NEAR(R(x, mv, 1, i), 0, 0);
		CHECK_NEAR(R(x, dotu, 0, i), p[0], 0);
	}
	for (int c = 0; c < 3; c++)
		CHECK_NEAR(x->data[bcu][c], 2, 0);
	for (int c = 0; c < 16; c++)
		CHECK_NEAR(x->data[m][c], c % 5 == 0 ? 2 : 0, 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

static void ref_matmul(const float *a, const float *b2, float *r)
{
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++) {
			float s = 0;
			for (int k = 0; k < 4; k++)
				s += a[i * 4 + k] * b2[k * 4 + j];
			r[i * 4 + j] = s;
		}
}

static void test_matrix(void)
{
	static const float A[16] = { 2, 0, 1, 0, 0, 1, 0, 0, 1, 0, 3, 0, 4, 5, 6, 1 };
	static const float B[16] = { 1, 2, 0, 0, 0, 1, 0, 0, 0, 0, 2, 0, -1, 0, 3, 1 };
	static const float S[16] = { 1, 2, 3, 4, 2, 4, 6, 8, 0, 0, 1, 0, 0, 0, 0, 1 };
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t a = kconst(&b, SL_TYPE_MATRIX, 16, A), bm = kconst(&b, SL_TYPE_MATRIX, 16, B);
	int32_t sing = kconst(&b, SL_TYPE_MATRIX, 16, S);
	body(&b);
	int32_t ab = ureg(&b, SL_TYPE_MATRIX), aa = ureg(&b, SL_TYPE_MATRIX);
	int32_t adb = ureg(&b, SL_TYPE_MATRIX), z = ureg(&b, SL_TYPE_MATRIX);
	int32_t sa = vreg(&b, SL_TYPE_MATRIX), sadb = vreg(&b, SL_TYPE_MATRIX);
	int32_t sum = ureg(&b, SL_TYPE_MATRIX), ms = ureg(&b, SL_TYPE_MATRIX);
	int32_t eqm = ureg(&b, SL_TYPE_BOOL), lit = ureg(&b, SL_TYPE_MATRIX);
	int32_t nem = ureg(&b, SL_TYPE_BOOL), eqb = ureg(&b, SL_TYPE_BOOL);
	int32_t k1 = kf(&b, 1);
	emit(&b, SL_OP_MUL, ab, 2, a, bm);
	emit(&b, SL_OP_DIV, aa, 2, a, a);
	emit(&b, SL_OP_DIV, adb, 2, ab, bm);
	emit(&b, SL_OP_DIV, z, 2, a, sing);
	emit(&b, SL_OP_MUL, sa, 2, s, a);          /* float * matrix, varying */
	emit(&b, SL_OP_DIV, sadb, 2, sa, bm);      /* varying matrix / uniform matrix */
	emit(&b, SL_OP_ADD, sum, 2, a, bm);
	emit(&b, SL_OP_SUB, ms, 2, a, k1);
	/* lit: A rebuilt component by component with MATRIX; equal to A, unequal to B. */
	{
		struct sl_insn in = { .op = SL_OP_MATRIX, .nargs = 16, .dst = lit, .jump = { -1, -1 } };
		in.args = rl_arena_alloc(b.arena, 16 * sizeof(int32_t));
		for (int c = 0; c < 16; c++)
			in.args[c] = kf(&b, A[c]);
		in.loc = (struct sl_loc){ 0, (uint32_t)b.code.len + 1, 1 };
		rl_vec_push(b.code, in);
	}
	emit(&b, SL_OP_EQ, eqm, 2, a, lit);
	emit(&b, SL_OP_NE, nem, 2, bm, lit);
	emit(&b, SL_OP_EQ, eqb, 2, bm, lit);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 3);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[3] = { 1, -0.5f, 2 };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	float ref[16];
	ref_matmul(A, B, ref);
	for (int c = 0; c < 16; c++) {
		CHECK_NEAR(x->data[ab][c], ref[c], 1e-5);
		CHECK_NEAR(x->data[aa][c], c % 5 == 0 ? 1 : 0, 1e-5);
		CHECK_NEAR(x->data[adb][c], A[c], 1e-4);
		CHECK_NEAR(x->data[z][c], 0, 0);
		CHECK_NEAR(x->data[sum][c], A[c] + B[c], 0);
		CHECK_NEAR(x->data[ms][c], A[c] - 1, 0);
		for (uint32_t i = 0; i < 3; i++) {
			CHECK_NEAR(R(x, sa, c, i), sv[i] * A[c], 1e-6);
			/* (s A) / B = s (A B^-1); (A B^-1) B = A, check through ref: */
		}
	}
	/* (s A) B^-1 B == s A */
	for (uint32_t i = 0; i < 3; i++) {
		float m[16], back[16];
		for (int c = 0; c < 16; c++)
			m[c] = R(x, sadb, c, i);
		ref_matmul(m, B, back);
		for (int c = 0; c < 16; c++)
			CHECK_NEAR(back[c], sv[i] * A[c], 1e-4);
	}
	CHECK(x->data[eqm][0] == 1);
	CHECK(x->data[nem][0] == 1);
	CHECK(x->data[eqb][0] == 0);
	for (int c = 0; c < 16; c++)
		CHECK(x->data[lit][c] == A[c]);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* ------------------------------------------------------------------------ */
/* Control flow                                                              */

static void test_if_else(void)
{
	/*
	 * x = 0;
	 * if (s < 2) { x = 1; if (s < 1) x = 10; else { x = 20; u1 = 7; } }
	 * else { x = 2; if (s > 100) { u2 = 5; } }
	 * y = x + 1;
	 */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t k0 = kf(&b, 0), k1 = kf(&b, 1), k2 = kf(&b, 2), k10 = kf(&b, 10);
	int32_t k20 = kf(&b, 20), k100 = kf(&b, 100), k7 = kf(&b, 7), k5 = kf(&b, 5);
	body(&b);
	int32_t xr = vreg(&b, SL_TYPE_FLOAT), y = vreg(&b, SL_TYPE_FLOAT);
	int32_t c1 = vreg(&b, SL_TYPE_BOOL), c2 = vreg(&b, SL_TYPE_BOOL), c3 = vreg(&b, SL_TYPE_BOOL);
	int32_t u1 = ureg(&b, SL_TYPE_FLOAT), u2 = ureg(&b, SL_TYPE_FLOAT);
	int32_t ucnt = ureg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, xr, 1, k0);
	emit(&b, SL_OP_MOV, u1, 1, k0);
	emit(&b, SL_OP_MOV, u2, 1, k0);
	emit(&b, SL_OP_MOV, ucnt, 1, k0);
	emit(&b, SL_OP_LT, c1, 2, s, k2);
	uint32_t i1 = c_if(&b, c1);
	emit(&b, SL_OP_MOV, xr, 1, k1);
	emit(&b, SL_OP_LT, c2, 2, s, k1);
	uint32_t i2 = c_if(&b, c2);
	emit(&b, SL_OP_MOV, xr, 1, k10);
	/* uniform code runs once per block entry: counts how often */
	emit(&b, SL_OP_ADD, ucnt, 2, ucnt, k1);
	c_else(&b, i2);
	emit(&b, SL_OP_MOV, xr, 1, k20);
	emit(&b, SL_OP_MOV, u1, 1, k7);
	c_endif(&b, i2);
	c_else(&b, i1);
	emit(&b, SL_OP_MOV, xr, 1, k2);
	emit(&b, SL_OP_GT, c3, 2, s, k100);
	uint32_t i3 = c_if(&b, c3);
	emit(&b, SL_OP_MOV, u2, 1, k5);   /* no point gets here: must not run */
	c_endif(&b, i3);
	c_endif(&b, i1);
	emit(&b, SL_OP_ADD, y, 2, xr, k1);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 16);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	CHECK(sl_exec_set_grid(x, 3, 2));
	const float sv[6] = { 0, 1.5f, 3, 0.5f, 2, 1 };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t i = 0; i < 6; i++) {
		float want = sv[i] < 2 ? (sv[i] < 1 ? 10 : 20) : 2;
		CHECK_NEAR(R(x, xr, 0, i), want, 0);
		CHECK_NEAR(R(x, y, 0, i), want + 1, 0);
	}
	CHECK_NEAR(x->data[u1][0], 7, 0);
	CHECK_NEAR(x->data[u2][0], 0, 0);
	CHECK_NEAR(x->data[ucnt][0], 1, 0);
	/* All points take the then-part: the else-part (with its uniform write) is skipped. */
	const float all0[6] = { 0, 0, 0, 0, 0, 0 };
	set_global1(x, SL_GLOBAL_S, all0);
	CHECK(sl_exec_run(x, NULL));
	CHECK_NEAR(x->data[u1][0], 0, 0);
	for (uint32_t i = 0; i < 6; i++)
		CHECK_NEAR(R(x, xr, 0, i), 10, 0);
	/* Points beyond the grid are never touched. */
	CHECK(sl_exec_set_grid(x, 2, 1));
	const float two3[2] = { 3, 3 };
	set_global1(x, SL_GLOBAL_S, two3);
	CHECK(sl_exec_run(x, NULL));
	CHECK_NEAR(R(x, xr, 0, 0), 2, 0);
	CHECK_NEAR(R(x, xr, 0, 1), 2, 0);
	CHECK_NEAR(R(x, xr, 0, 5), 10, 0);
	CHECK(!sl_exec_set_grid(x, 5, 4));
	CHECK(!sl_exec_set_grid(x, 0, 1));
	sl_exec_destroy(x);
	pb_free(&b);
}

static void test_while(void)
{
	/* i = 0; n = 0; while (i < s) { i += 1; n += 2; }  -- per-point trip counts */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t k0 = kf(&b, 0), k1 = kf(&b, 1), k2 = kf(&b, 2);
	body(&b);
	int32_t i = vreg(&b, SL_TYPE_FLOAT), n = vreg(&b, SL_TYPE_FLOAT);
	int32_t c = vreg(&b, SL_TYPE_BOOL), iters = ureg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, i, 1, k0);
	emit(&b, SL_OP_MOV, n, 1, k0);
	emit(&b, SL_OP_MOV, iters, 1, k0);
	uint32_t l = c_loop(&b);
	emit(&b, SL_OP_LT, c, 2, i, s);
	c_looptest(&b, l, c);
	emit(&b, SL_OP_ADD, i, 2, i, k1);
	emit(&b, SL_OP_ADD, n, 2, n, k2);
	emit(&b, SL_OP_ADD, iters, 2, iters, k1);   /* uniform: counts grid iterations */
	c_loopend(&b, l);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 8);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[8] = { 0, 1, 5, 2.5f, -1, 3, 7, 0.1f };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t k = 0; k < 8; k++) {
		float trips = sv[k] > 0 ? ceilf(sv[k]) : 0;
		CHECK_NEAR(R(x, i, 0, k), trips, 0);
		CHECK_NEAR(R(x, n, 0, k), 2 * trips, 0);
	}
	CHECK_NEAR(x->data[iters][0], 7, 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* The reference for test_break_continue, in plain C. */
static float ref_nested(float s)
{
	float total = 0;
	for (float i = 0; i < 5; i += 1) {
		if (i == s)
			continue;
		for (float j = 0; j < 5; j += 1) {
			if (j == 3)
				continue;
			if (i + j == s + 4)
				goto out;
			if (j == 2 && i == s - 1)
				goto next_i;
			if (j > i)
				break;
			total += 1 + 10 * i + 100 * j;
		}
		total += 1000;
next_i:;
	}
out:
	return total;
}

static void test_break_continue(void)
{
	/*
	 * for (i = 0; i < 5; i += 1) {
	 *   if (i == s) continue;
	 *   for (j = 0; j < 5; j += 1) {
	 *     if (j == 3) continue;
	 *     if (i + j == s + 4) break 2;
	 *     if (j == 2 && i == s - 1) continue 2;
	 *     if (j > i) break;
	 *     total += 1 + 10 i + 100 j;
	 *   }
	 *   total += 1000;
	 * }
	 */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t k0 = kf(&b, 0), k1 = kf(&b, 1), k2 = kf(&b, 2), k3 = kf(&b, 3), k4 = kf(&b, 4);
	int32_t k5 = kf(&b, 5), k10 = kf(&b, 10), k100 = kf(&b, 100), k1000 = kf(&b, 1000);
	body(&b);
	int32_t i = vreg(&b, SL_TYPE_FLOAT), j = vreg(&b, SL_TYPE_FLOAT);
	int32_t total = vreg(&b, SL_TYPE_FLOAT), c = vreg(&b, SL_TYPE_BOOL);
	int32_t c2 = vreg(&b, SL_TYPE_BOOL), t1 = vreg(&b, SL_TYPE_FLOAT);
	int32_t t2 = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, total, 1, k0);
	emit(&b, SL_OP_MOV, i, 1, k0);
	uint32_t lo = c_loop(&b);
	emit(&b, SL_OP_LT, c, 2, i, k5);
	c_looptest(&b, lo, c);
	emit(&b, SL_OP_EQ, c, 2, i, s);
	uint32_t f1 = c_if(&b, c);
	c_jump(&b, SL_OP_CONTINUE, 1);
	c_endif(&b, f1);
	emit(&b, SL_OP_MOV, j, 1, k0);
	uint32_t li = c_loop(&b);
	emit(&b, SL_OP_LT, c, 2, j, k5);
	c_looptest(&b, li, c);
	emit(&b, SL_OP_EQ, c, 2, j, k3);
	uint32_t f2 = c_if(&b, c);
	c_jump(&b, SL_OP_CONTINUE, 1);
	c_endif(&b, f2);
	emit(&b, SL_OP_ADD, t1, 2, i, j);
	emit(&b, SL_OP_ADD, t2, 2, s, k4);
	emit(&b, SL_OP_EQ, c, 2, t1, t2);
	uint32_t f3 = c_if(&b, c);
	c_jump(&b, SL_OP_BREAK, 2);
	c_endif(&b, f3);
	emit(&b, SL_OP_EQ, c, 2, j, k2);
	emit(&b, SL_OP_SUB, t1, 2, s, k1);
	emit(&b, SL_OP_EQ, c2, 2, i, t1);
	emit(&b, SL_OP_AND, c, 2, c, c2);
	uint32_t f4 = c_if(&b, c);
	c_jump(&b, SL_OP_CONTINUE, 2);
	c_endif(&b, f4);
	emit(&b, SL_OP_GT, c, 2, j, i);
	uint32_t f5 = c_if(&b, c);
	c_jump(&b, SL_OP_BREAK, 1);
	c_endif(&b, f5);
	emit(&b, SL_OP_MUL, t1, 2, i, k10);
	emit(&b, SL_OP_MUL, t2, 2, j, k100);
	emit(&b, SL_OP_ADD, t1, 2, t1, t2);
	emit(&b, SL_OP_ADD, t1, 2, t1, k1);
	emit(&b, SL_OP_ADD, total, 2, total, t1);
	c_loopcont(&b, li);
	emit(&b, SL_OP_ADD, j, 2, j, k1);
	c_loopend(&b, li);
	emit(&b, SL_OP_ADD, total, 2, total, k1000);
	c_loopcont(&b, lo);
	emit(&b, SL_OP_ADD, i, 2, i, k1);
	c_loopend(&b, lo);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 10);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[10] = { -1, 0, 1, 2, 3, 4, 5, 0.5f, 2, 6 };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t k = 0; k < 10; k++)
		CHECK_NEAR(R(x, total, 0, k), ref_nested(sv[k]), 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

static void test_func_return(void)
{
	/*
	 * r = -1; i = 0;
	 * FUNC {
	 *   while (i < 10) { if (i == s) { r = i * 2; return; } i += 1; }
	 *   r = 99;
	 * }
	 * out = r + 100;  -- every point, including those that returned
	 */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t km1 = kf(&b, -1), k0 = kf(&b, 0), k1 = kf(&b, 1), k2 = kf(&b, 2);
	int32_t k10 = kf(&b, 10), k99 = kf(&b, 99), k100 = kf(&b, 100);
	body(&b);
	int32_t r = vreg(&b, SL_TYPE_FLOAT), i = vreg(&b, SL_TYPE_FLOAT);
	int32_t c = vreg(&b, SL_TYPE_BOOL), out = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, r, 1, km1);
	emit(&b, SL_OP_MOV, i, 1, k0);
	uint32_t fn = emit(&b, SL_OP_FUNC, -1, 0);
	uint32_t l = c_loop(&b);
	emit(&b, SL_OP_LT, c, 2, i, k10);
	c_looptest(&b, l, c);
	emit(&b, SL_OP_EQ, c, 2, i, s);
	uint32_t f = c_if(&b, c);
	emit(&b, SL_OP_MUL, r, 2, i, k2);
	emit(&b, SL_OP_RETURN, -1, 0);
	c_endif(&b, f);
	emit(&b, SL_OP_ADD, i, 2, i, k1);
	c_loopend(&b, l);
	emit(&b, SL_OP_MOV, r, 1, k99);
	c_end(&b, SL_OP_FUNCEND, fn);
	emit(&b, SL_OP_ADD, out, 2, r, k100);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 5);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[5] = { 3, 0, 20, 9, 4.5f };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t k = 0; k < 5; k++) {
		bool hit = sv[k] == floorf(sv[k]) && sv[k] >= 0 && sv[k] < 10;
		float want = hit ? 2 * sv[k] : 99;
		CHECK_NEAR(R(x, r, 0, k), want, 0);
		CHECK_NEAR(R(x, out, 0, k), want + 100, 0);
	}
	sl_exec_destroy(x);
	pb_free(&b);
}

static bool run_guard(void *arg)
{
	return sl_exec_run(arg, NULL);
}

static void test_loop_guard(void)
{
	/* while (1) { n += 1; } */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t k1 = kf(&b, 1), k0 = kf(&b, 0);
	body(&b);
	int32_t n = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, n, 1, k0);
	uint32_t l = c_loop(&b);
	c_looptest(&b, l, k1);
	emit(&b, SL_OP_ADD, n, 2, n, k1);
	c_loopend(&b, l);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 1);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	char msg[512];
	bool ok = true;
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	capture_stderr(msg, sizeof(msg), run_guard, x, &ok);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
	CHECK(!ok);
	CHECK(x->failed);
	CHECK(strstr(msg, "test.sl:2:1: error: loop runs too long") != NULL);
	CHECK_NEAR(R(x, n, 0, 0), 10000000, 1);
	CHECK(secs < 60);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* ------------------------------------------------------------------------ */
/* Arrays                                                                    */

static bool run_null(void *arg)
{
	return sl_exec_run(arg, NULL);
}

static void test_arrays(void)
{
	/*
	 * float a[4]; a[0..3] = 10, 11, 12, 13 (uniform indices);
	 * a[s] = 50 (varying index, may be out of range -> clamped);
	 * g = a[t]; color ca[2]; ca[1] = Cs; h = ca[t]; string sa[2]; ...
	 */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t t = glob(&b, SL_GLOBAL_T, SL_TYPE_FLOAT, true);
	int32_t Cs = glob(&b, SL_GLOBAL_CS, SL_TYPE_COLOR, true);
	int32_t ki[4], kv[4];
	for (int k = 0; k < 4; k++) {
		ki[k] = kf(&b, (float)k);
		kv[k] = kf(&b, 10.0f + (float)k);
	}
	int32_t k50 = kf(&b, 50), k9 = kf(&b, 9), km2 = kf(&b, -2.5f);
	int32_t sx = ks(&b, "x"), sy = ks(&b, "y");
	body(&b);
	int32_t a = newreg(&b, SL_REG_LOCAL, SL_TYPE_FLOAT, true, 4);
	int32_t ua = newreg(&b, SL_REG_LOCAL, SL_TYPE_FLOAT, false, 4);
	int32_t a2 = newreg(&b, SL_REG_LOCAL, SL_TYPE_FLOAT, true, 4);
	int32_t ca = newreg(&b, SL_REG_LOCAL, SL_TYPE_COLOR, true, 2);
	int32_t sa = newreg(&b, SL_REG_LOCAL, SL_TYPE_STRING, false, 2);
	int32_t g = vreg(&b, SL_TYPE_FLOAT), h = vreg(&b, SL_TYPE_COLOR);
	int32_t u9 = ureg(&b, SL_TYPE_FLOAT), um = ureg(&b, SL_TYPE_FLOAT);
	int32_t ss = vreg(&b, SL_TYPE_STRING), g2 = vreg(&b, SL_TYPE_FLOAT);
	for (int k = 0; k < 4; k++) {
		emit(&b, SL_OP_ASET, ua, 2, kv[k], ki[k]);
		emit(&b, SL_OP_ASET, a, 2, kv[k], ki[k]);
	}
	emit(&b, SL_OP_MOV, a2, 1, a);               /* whole-array copy */
	emit(&b, SL_OP_ASET, a, 2, k50, s);
	emit(&b, SL_OP_AREF, g, 2, a, t);
	emit(&b, SL_OP_AREF, u9, 2, ua, k9);         /* clamped to 3 */
	emit(&b, SL_OP_AREF, um, 2, ua, km2);        /* clamped to 0 */
	emit(&b, SL_OP_ASET, ca, 2, kt(&b, SL_TYPE_COLOR, 0, 0, 0), ki[0]);
	emit(&b, SL_OP_ASET, ca, 2, Cs, ki[1]);
	emit(&b, SL_OP_AREF, h, 2, ca, t);
	emit(&b, SL_OP_ASET, sa, 2, sx, ki[0]);
	emit(&b, SL_OP_ASET, sa, 2, sy, ki[1]);
	emit(&b, SL_OP_AREF, ss, 2, sa, t);
	emit(&b, SL_OP_MOV, a, 1, ua);               /* uniform array broadcast */
	emit(&b, SL_OP_AREF, g2, 2, a, t);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const float sv[4] = { 0, 2.9f, -0.5f, 7 }, tv[4] = { 0, 1, 2, 3.5f };
	set_global1(x, SL_GLOBAL_S, sv);
	set_global1(x, SL_GLOBAL_T, tv);
	for (uint32_t i = 0; i < 4; i++)
		set_global3(x, SL_GLOBAL_CS, i, (float)i, 1, 2);
	char msg[1024];
	bool ok = false;
	capture_stderr(msg, sizeof(msg), run_null, x, &ok);
	CHECK(ok);
	/* s = 7 is out of range (ASET at line 10), t = 3.5 is fine; ua[9], ua[-2.5] warn. */
	CHECK(strstr(msg, "test.sl:10:1: warning: array index out of range") != NULL);
	CHECK(strstr(msg, "test.sl:12:1: warning: array index out of range") != NULL);
	CHECK(strstr(msg, "test.sl:13:1: warning: array index out of range") != NULL);
	CHECK(strstr(msg, "test.sl:11:1") == NULL);
	for (uint32_t i = 0; i < 4; i++) {
		/* a after ASET at trunc(s) clamped: s=0->0, 2.9->2, -0.5->0, 7->3 (clamped) */
		int w = i == 3 ? 3 : (int)sv[i];
		int ti = (int)tv[i];
		float want = ti == w ? 50 : 10.0f + (float)ti;
		CHECK_NEAR(R(x, g, 0, i), want, 0);
		for (int k = 0; k < 4; k++)
			CHECK_NEAR(R(x, a2, k, i), 10 + k, 0);
		int ci = ti > 1 ? 1 : ti;
		CHECK_NEAR(R(x, h, 0, i), ci ? (float)i : 0, 0);
		CHECK_NEAR(R(x, h, 2, i), ci ? 2 : 0, 0);
		CHECK_STR(sl_x_str(x, ss, i), ci ? "y" : "x");
		CHECK_NEAR(R(x, g2, 0, i), 10.0f + (float)ti, 0);
	}
	CHECK_NEAR(x->data[u9][0], 13, 0);
	CHECK_NEAR(x->data[um][0], 10, 0);
	/* A second run prints no new warnings. */
	capture_stderr(msg, sizeof(msg), run_null, x, &ok);
	CHECK(ok);
	CHECK(msg[0] == 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* ------------------------------------------------------------------------ */
/* Parameters                                                                */

struct space_host {
	struct sl_host host;
	float shader[16];
};

static bool sh_space(void *user, const char *name, float m[16])
{
	struct space_host *h = user;
	if (strcmp(name, "shader"))
		return false;
	memcpy(m, h->shader, sizeof(h->shader));
	return true;
}

static void test_params(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t k05 = kf(&b, 0.5f), k2 = kf(&b, 2);
	int32_t Kd = param(&b, "Kd", SL_TYPE_FLOAT, false, 0);
	emit(&b, SL_OP_MOV, Kd, 1, k05);
	param_done(&b);
	/* Ks's default depends on Kd: Ks = Kd * 2. */
	int32_t Ks = param(&b, "Ks", SL_TYPE_FLOAT, false, 0);
	emit(&b, SL_OP_MUL, Ks, 2, Kd, k2);
	param_done(&b);
	int32_t from = param(&b, "from", SL_TYPE_POINT, false, 0);
	emit(&b, SL_OP_MOV, from, 1, kt(&b, SL_TYPE_POINT, 1, 2, 3));
	param_done(&b);
	int32_t dir = param(&b, "dir", SL_TYPE_VECTOR, false, 0);
	emit(&b, SL_OP_MOV, dir, 1, kt(&b, SL_TYPE_VECTOR, 0, 0, 1));
	param_done(&b);
	int32_t nn = param(&b, "nn", SL_TYPE_NORMAL, false, 0);
	emit(&b, SL_OP_MOV, nn, 1, kt(&b, SL_TYPE_NORMAL, 0, 1, 0));
	param_done(&b);
	int32_t vp = param(&b, "vp", SL_TYPE_FLOAT, true, 0);
	emit(&b, SL_OP_MOV, vp, 1, kf(&b, -1));
	param_done(&b);
	int32_t name = param(&b, "texname", SL_TYPE_STRING, false, 0);
	emit(&b, SL_OP_MOV, name, 1, ks(&b, "default.tx"));
	param_done(&b);
	int32_t arr = param(&b, "weights", SL_TYPE_FLOAT, false, 3);
	param_done(&b);
	/* Code between the defaults and the body that must never run. */
	int32_t never = ureg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, never, 1, kf(&b, 123));
	body(&b);
	int32_t out = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_ADD, out, 2, Ks, vp);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	CHECK(sl_exec_set_grid(x, 2, 2));
	CHECK(sl_exec_run(x, NULL));
	CHECK_NEAR(x->data[Kd][0], 0.5, 0);
	CHECK_NEAR(x->data[Ks][0], 1, 0);
	CHECK_NEAR(x->data[from][2], 3, 0);
	CHECK_STR(x->sdata[name][0], "default.tx");
	CHECK_NEAR(x->data[never][0], 0, 0);
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(R(x, out, 0, i), 0, 0);

	/* Host values: Kd set (Ks's default follows it), vp per point. */
	float kd = 3;
	CHECK(sl_exec_set_param(x, "Kd", &kd, 1));
	const float vpv[4] = { 1, 2, 3, 4 };
	CHECK(sl_exec_set_param(x, "vp", vpv, 4));
	CHECK(sl_exec_set_param_string(x, "texname", "brick.tx"));
	const float w[3] = { 0.25f, 0.5f, 0.25f };
	CHECK(sl_exec_set_param(x, "weights", w, 3));
	/* Shader space: scale 2, then translate by (10, 20, 30). */
	struct space_host sh = { .host = { .space = sh_space } };
	sh.host.user = &sh;
	memset(sh.shader, 0, sizeof(sh.shader));
	sh.shader[0] = 2;
	sh.shader[5] = 2;
	sh.shader[10] = 2;
	sh.shader[15] = 1;
	sh.shader[12] = 10;
	sh.shader[13] = 20;
	sh.shader[14] = 30;
	const float fp[3] = { 1, 1, 1 }, dv[3] = { 0, 0, 1 }, nv[3] = { 0, 4, 0 };
	CHECK(sl_exec_set_param(x, "from", fp, 3));
	CHECK(sl_exec_set_param(x, "dir", dv, 3));
	CHECK(sl_exec_set_param(x, "nn", nv, 3));
	CHECK(sl_exec_run(x, &sh.host));
	CHECK_NEAR(x->data[Kd][0], 3, 0);
	CHECK_NEAR(x->data[Ks][0], 6, 0);
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(R(x, out, 0, i), 6 + vpv[i], 0);
	CHECK_STR(x->sdata[name][0], "brick.tx");
	CHECK_NEAR(x->data[arr][1], 0.5, 0);
	CHECK_NEAR(x->data[from][0], 12, 1e-6);
	CHECK_NEAR(x->data[from][1], 22, 1e-6);
	CHECK_NEAR(x->data[from][2], 32, 1e-6);
	CHECK_NEAR(x->data[dir][0], 0, 1e-6);
	CHECK_NEAR(x->data[dir][2], 2, 1e-6);
	CHECK_NEAR(x->data[nn][1], 2, 1e-6);   /* inverse transpose of 2I: halves */

	/* A non-uniform shader space: normals stay perpendicular to transformed tangents. */
	memset(sh.shader, 0, sizeof(sh.shader));
	sh.shader[0] = 1;
	sh.shader[1] = 1;      /* x' = x, y' = x + y (shear) */
	sh.shader[5] = 1;
	sh.shader[10] = 3;
	sh.shader[15] = 1;
	const float n2[3] = { 1, -1, 0 }, d2[3] = { 1, 1, 0 };   /* n . d = 0 */
	CHECK(sl_exec_set_param(x, "nn", n2, 3));
	CHECK(sl_exec_set_param(x, "dir", d2, 3));
	CHECK(sl_exec_run(x, &sh.host));
	float dd = x->data[nn][0] * x->data[dir][0] + x->data[nn][1] * x->data[dir][1] +
		   x->data[nn][2] * x->data[dir][2];
	CHECK_NEAR(dd, 0, 1e-5);
	CHECK_NEAR(x->data[dir][0], 1, 1e-6);
	CHECK_NEAR(x->data[dir][1], 2, 1e-6);

	/* The register may be changed by the body; host values are reapplied each run. */
	CHECK(!sl_exec_set_param(x, "Kd", vpv, 2));
	CHECK(!sl_exec_set_param(x, "nosuch", vpv, 1));
	CHECK(!sl_exec_set_param(x, "Kd", vpv, 4));   /* uniform: no per-point values */
	CHECK(!sl_exec_set_param_string(x, "Kd", "x"));
	CHECK(!sl_exec_set_param(x, "texname", vpv, 1));

	/* Per-point values for a different grid size fail the run. */
	CHECK(sl_exec_set_grid(x, 3, 1));
	CHECK(!sl_exec_run(x, NULL));
	CHECK(sl_exec_set_grid(x, 2, 2));

	sl_exec_reset_params(x);
	CHECK(sl_exec_run(x, NULL));
	CHECK_NEAR(x->data[Kd][0], 0.5, 0);
	CHECK_NEAR(x->data[Ks][0], 1, 0);
	CHECK_NEAR(x->data[from][0], 1, 0);
	CHECK_STR(x->sdata[name][0], "default.tx");
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(R(x, out, 0, i), 0, 0);
	/* One value for a varying parameter is broadcast. */
	float one = 5;
	CHECK(sl_exec_set_param(x, "vp", &one, 1));
	CHECK(sl_exec_run(x, NULL));
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(R(x, out, 0, i), 6, 0);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* ------------------------------------------------------------------------ */
/* Derivatives, spaces, scratch, diagnostics                                 */

static void test_deriv(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	emit(&b, SL_OP_NOP, -1, 0);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 64);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	const uint32_t NU = 6, NV = 5;
	CHECK(sl_exec_set_grid(x, NU, NV));
	float du = sl_exec_du(x), dv = sl_exec_dv(x);
	CHECK_NEAR(du, 1.0 / 5, 1e-7);
	CHECK_NEAR(dv, 1.0 / 4, 1e-7);
	float f[64], g[64], fu[64], fv[64];
	for (uint32_t v = 0; v < NV; v++)
		for (uint32_t u = 0; u < NU; u++) {
			float uu = (float)u * du, vv = (float)v * dv;
			f[v * NU + u] = 3 * uu - 2 * vv + 1;
			g[v * NU + u] = uu * uu + uu * vv + 2 * vv * vv;
		}
	sl_exec_deriv(x, f, fu, fv);
	for (uint32_t i = 0; i < NU * NV; i++) {
		CHECK_NEAR(fu[i], 3, 1e-4);
		CHECK_NEAR(fv[i], -2, 1e-4);
	}
	sl_exec_deriv(x, g, fu, fv);
	for (uint32_t v = 0; v < NV; v++)
		for (uint32_t u = 0; u < NU; u++) {
			float uu = (float)u * du, vv = (float)v * dv;
			/* Central and second-order one-sided differences are exact on quadratics. */
			CHECK_NEAR(fu[v * NU + u], 2 * uu + vv, 1e-4);
			CHECK_NEAR(fv[v * NU + u], uu + 4 * vv, 1e-4);
		}
	/* In place: the result may overwrite its input. */
	memcpy(fu, f, sizeof(f));
	sl_exec_deriv(x, fu, fu, NULL);
	CHECK_NEAR(fu[7], 3, 1e-4);
	/* Two points wide: first order; one point: 0. */
	CHECK(sl_exec_set_grid(x, 2, 1));
	float h[2] = { 1, 4 }, hu[2], hv[2];
	sl_exec_deriv(x, h, hu, hv);
	CHECK_NEAR(hu[0], 3, 1e-6);
	CHECK_NEAR(hu[1], 3, 1e-6);
	CHECK_NEAR(hv[0], 0, 0);
	CHECK_NEAR(sl_exec_dv(x), 1, 0);
	sl_exec_destroy(x);
	pb_free(&b);

	/* A program with du/dv globals: their values are the step. */
	pb_init(&b, SL_SHADER_SURFACE);
	glob(&b, SL_GLOBAL_DU, SL_TYPE_FLOAT, false);
	glob(&b, SL_GLOBAL_DV, SL_TYPE_FLOAT, false);
	body(&b);
	prog = pb_finish(&b);
	x = sl_exec_create(prog, 9);
	CHECK(x != NULL);
	if (x) {
		CHECK(sl_exec_set_grid(x, 3, 3));
		*sl_exec_global(x, SL_GLOBAL_DU, NULL) = 0.5f;
		*sl_exec_global(x, SL_GLOBAL_DV, NULL) = 2;
		float q[9], qu[9], qv[9];
		for (int i = 0; i < 9; i++)
			q[i] = (float)(i % 3) * 0.5f * 4 + (float)(i / 3) * 2 * 7;
		sl_exec_deriv(x, q, qu, qv);
		for (int i = 0; i < 9; i++) {
			CHECK_NEAR(qu[i], 4, 1e-5);
			CHECK_NEAR(qv[i], 7, 1e-5);
		}
		sl_exec_destroy(x);
	}
	pb_free(&b);
}

static bool warn_space(void *arg)
{
	struct sl_exec *x = arg;
	float m[16];
	return sl_exec_space(x, &x->prog->code[0], "nowhere", m);
}

static void test_space_scratch(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	emit(&b, SL_OP_NOP, -1, 0);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 16);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	float m[16];
	CHECK(sl_exec_space(x, NULL, "current", m));
	CHECK(m[0] == 1 && m[1] == 0 && m[15] == 1);
	CHECK(sl_exec_space(x, NULL, "camera", m));
	char msg[256];
	bool ok = true;
	capture_stderr(msg, sizeof(msg), warn_space, x, &ok);
	CHECK(!ok);
	CHECK(strstr(msg, "test.sl:1:1: warning: unknown coordinate system 'nowhere'") != NULL);
	CHECK(m[5] == 1 && m[4] == 0);
	/* With a host that knows "world". */
	static const char *names[] = { "world", "current" };
	static const float mats[2][16] = {
		{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 6, 7, 1 },
		{ 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1 },
	};
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, NULL, 0);
	lh.space_names = names;
	lh.space_mats = mats;
	lh.nspaces = 2;
	x->host = &lh.host;
	CHECK(sl_exec_space(x, NULL, "world", m));
	CHECK(m[12] == 5 && m[14] == 7);
	CHECK(sl_exec_space(x, NULL, "current", m));
	CHECK(m[0] == 2);
	x->host = NULL;

	/* Scratch pointers of one instruction stay valid while more is handed out. */
	float *ptr[40];
	for (int k = 0; k < 40; k++) {
		ptr[k] = sl_exec_scratch(x, 100 + (size_t)k * 300);
		for (int i = 0; i < 100; i++)
			ptr[k][i] = (float)(k * 1000 + i);
	}
	bool intact = true;
	for (int k = 0; k < 40; k++)
		for (int i = 0; i < 100; i++)
			intact = intact && ptr[k][i] == (float)(k * 1000 + i);
	CHECK(intact);
	CHECK(sl_exec_strdup(x, NULL)[0] == 0);
	CHECK_STR(sl_exec_strdup(x, "abc"), "abc");
	sl_exec_destroy(x);
	pb_free(&b);
}

static void test_invalid(void)
{
	struct pb b;
	CHECK(sl_exec_create(NULL, 4) == NULL);
	/* bad register */
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	int32_t r = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_ADD, r, 2, r, 77);
	struct sl_program *prog = pb_finish(&b);
	fprintf(stderr, "(expected errors follow)\n");
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* maxpoints 0 */
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 0) == NULL);
	pb_free(&b);
	/* break outside any loop */
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	c_jump(&b, SL_OP_BREAK, 1);
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* break 2 with one loop */
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t k1 = kf(&b, 1);
	body(&b);
	uint32_t l = c_loop(&b);
	c_looptest(&b, l, k1);
	c_jump(&b, SL_OP_BREAK, 2);
	c_loopend(&b, l);
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* unclosed if, and an endif naming the wrong if */
	pb_init(&b, SL_SHADER_SURFACE);
	k1 = kf(&b, 1);
	body(&b);
	c_if(&b, k1);
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	pb_init(&b, SL_SHADER_SURFACE);
	k1 = kf(&b, 1);
	body(&b);
	uint32_t i1 = c_if(&b, k1);
	c_endif(&b, i1);
	INS(&b, i1).jump[1] = 0;
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* type mismatch: float + matrix into a color */
	pb_init(&b, SL_SHADER_SURFACE);
	body(&b);
	int32_t c = vreg(&b, SL_TYPE_COLOR), m = vreg(&b, SL_TYPE_MATRIX);
	emit(&b, SL_OP_ADD, c, 2, c, m);
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* constant outside the pool */
	pb_init(&b, SL_SHADER_SURFACE);
	k1 = kf(&b, 1);
	body(&b);
	b.regs.data[k1].cindex = 5;
	prog = pb_finish(&b);
	CHECK(sl_exec_create(prog, 4) == NULL);
	pb_free(&b);
	/* solar without arguments (and without L or Ns) lights every point */
	pb_init(&b, SL_SHADER_LIGHT);
	body(&b);
	uint32_t so = emit(&b, SL_OP_SOLAR, -1, 0);
	c_end(&b, SL_OP_SOLAR_END, so);
	prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (x) {
		CHECK(sl_exec_run(x, NULL));
		CHECK(!sl_exec_is_ambient(x));
		for (uint32_t i = 0; i < 4; i++)
			CHECK(sl_exec_lit_mask(x)[i] == 1);
		sl_exec_destroy(x);
	}
	pb_free(&b);
	sl_exec_destroy(NULL);
}

/* ------------------------------------------------------------------------ */
/* Lights                                                                    */

static void test_category_match(void)
{
	CHECK(sl_category_match("", "key"));
	CHECK(sl_category_match(NULL, ""));
	CHECK(sl_category_match("", ""));
	CHECK(sl_category_match("key", "key"));
	CHECK(sl_category_match("key", "fill,key"));
	CHECK(sl_category_match("key", " fill , key "));
	CHECK(!sl_category_match("key", "keylight"));
	CHECK(!sl_category_match("key", ""));
	CHECK(!sl_category_match("key", "fill"));
	CHECK(sl_category_match("-key", "fill"));
	CHECK(sl_category_match("-key", ""));
	CHECK(!sl_category_match("-key", "rim,key"));
	CHECK(sl_category_match("rim,fill", "fill"));
	CHECK(sl_category_match("rim,fill", "rim"));
	CHECK(!sl_category_match("rim,fill", "key"));
	CHECK(sl_category_match("rim,-key", "bounce"));
	CHECK(sl_category_match(",", "anything"));
}

/*
 * light spot(point from = (0,0,5); vector axis = (0,0,-1); float angle = 0.25;
 *            float intensity = 2; string __category = "key,spot")
 * { illuminate(from, axis, angle) { Cl = intensity; } }
 */
static struct sl_program *build_spot(struct pb *b)
{
	pb_init(b, SL_SHADER_LIGHT);
	int32_t Ps = glob(b, SL_GLOBAL_PS, SL_TYPE_POINT, true);
	int32_t L = glob(b, SL_GLOBAL_L, SL_TYPE_VECTOR, true);
	int32_t Cl = glob(b, SL_GLOBAL_CL, SL_TYPE_COLOR, true);
	(void)Ps;
	(void)L;
	int32_t from = param(b, "from", SL_TYPE_POINT, false, 0);
	emit(b, SL_OP_MOV, from, 1, kt(b, SL_TYPE_POINT, 0, 0, 5));
	param_done(b);
	int32_t axis = param(b, "axis", SL_TYPE_VECTOR, false, 0);
	emit(b, SL_OP_MOV, axis, 1, kt(b, SL_TYPE_VECTOR, 0, 0, -1));
	param_done(b);
	int32_t angle = param(b, "angle", SL_TYPE_FLOAT, false, 0);
	emit(b, SL_OP_MOV, angle, 1, kf(b, 0.25f));
	param_done(b);
	int32_t inten = param(b, "intensity", SL_TYPE_FLOAT, false, 0);
	emit(b, SL_OP_MOV, inten, 1, kf(b, 2));
	param_done(b);
	int32_t cat = param(b, "__category", SL_TYPE_STRING, false, 0);
	emit(b, SL_OP_MOV, cat, 1, ks(b, "key,spot"));
	param_done(b);
	body(b);
	uint32_t il = emit(b, SL_OP_ILLUMINATE, -1, 3, from, axis, angle);
	emit(b, SL_OP_MOV, Cl, 1, inten);
	c_end(b, SL_OP_ILLUMINATE_END, il);
	return pb_finish(b);
}

/* light amb(float intensity = 0.25) { Cl = intensity; }  -- category via the host */
static struct sl_program *build_ambient(struct pb *b)
{
	pb_init(b, SL_SHADER_LIGHT);
	int32_t Cl = glob(b, SL_GLOBAL_CL, SL_TYPE_COLOR, true);
	int32_t inten = param(b, "intensity", SL_TYPE_FLOAT, false, 0);
	emit(b, SL_OP_MOV, inten, 1, kf(b, 0.25f));
	param_done(b);
	body(b);
	emit(b, SL_OP_MOV, Cl, 1, inten);
	return pb_finish(b);
}

/* light sun(string __category = "sun") { solar((1,0,0), 0) { Cl = (0.5, 0.5, 0.5); } } */
static struct sl_program *build_sun(struct pb *b)
{
	pb_init(b, SL_SHADER_LIGHT);
	glob(b, SL_GLOBAL_L, SL_TYPE_VECTOR, true);
	int32_t Cl = glob(b, SL_GLOBAL_CL, SL_TYPE_COLOR, true);
	int32_t cat = param(b, "__category", SL_TYPE_STRING, false, 0);
	emit(b, SL_OP_MOV, cat, 1, ks(b, "sun"));
	param_done(b);
	body(b);
	uint32_t so = emit(b, SL_OP_SOLAR, -1, 2, kt(b, SL_TYPE_VECTOR, 1, 0, 0), kf(b, 0));
	emit(b, SL_OP_MOV, Cl, 1, kf(b, 0.5f));
	c_end(b, SL_OP_SOLAR_END, so);
	return pb_finish(b);
}

/*
 * surface s(string cat = "")
 * {
 *   illuminance(cat, P) { Ci += Cl; n += 1; Lsum += L; }
 *   illuminance(P, N, PI/4) { m += 1; }      -- cone around N = (0,0,1)
 *   illuminance(P) { k += 1; break; }         -- only the first lit light
 * }
 */
struct surf {
	int32_t cat, n, Lsum, m, k, Ci;
};

static struct sl_program *build_surface(struct pb *b, struct surf *o)
{
	pb_init(b, SL_SHADER_SURFACE);
	int32_t P = glob(b, SL_GLOBAL_P, SL_TYPE_POINT, true);
	int32_t N = glob(b, SL_GLOBAL_N, SL_TYPE_NORMAL, true);
	int32_t L = glob(b, SL_GLOBAL_L, SL_TYPE_VECTOR, true);
	int32_t Cl = glob(b, SL_GLOBAL_CL, SL_TYPE_COLOR, true);
	o->Ci = glob(b, SL_GLOBAL_CI, SL_TYPE_COLOR, true);
	glob(b, SL_GLOBAL_OI, SL_TYPE_COLOR, true);
	int32_t k0 = kf(b, 0), k1 = kf(b, 1);
	o->cat = param(b, "cat", SL_TYPE_STRING, false, 0);
	emit(b, SL_OP_MOV, o->cat, 1, ks(b, ""));
	param_done(b);
	body(b);
	o->n = vreg(b, SL_TYPE_FLOAT);
	o->m = vreg(b, SL_TYPE_FLOAT);
	o->k = vreg(b, SL_TYPE_FLOAT);
	o->Lsum = vreg(b, SL_TYPE_VECTOR);
	emit(b, SL_OP_MOV, o->n, 1, k0);
	emit(b, SL_OP_MOV, o->m, 1, k0);
	emit(b, SL_OP_MOV, o->k, 1, k0);
	emit(b, SL_OP_MOV, o->Lsum, 1, k0);
	uint32_t i1 = emit(b, SL_OP_ILLUMINANCE, -1, 2, o->cat, P);
	INS(b, i1).imm = 1;
	emit(b, SL_OP_ADD, o->Ci, 2, o->Ci, Cl);
	emit(b, SL_OP_ADD, o->n, 2, o->n, k1);
	emit(b, SL_OP_ADD, o->Lsum, 2, o->Lsum, L);
	c_end(b, SL_OP_ILLUMINANCE_END, i1);
	uint32_t i2 = emit(b, SL_OP_ILLUMINANCE, -1, 3, P, N, kf(b, (float)(3.14159265358979 / 4)));
	emit(b, SL_OP_ADD, o->m, 2, o->m, k1);
	c_end(b, SL_OP_ILLUMINANCE_END, i2);
	uint32_t i3 = emit(b, SL_OP_ILLUMINANCE, -1, 1, P);
	emit(b, SL_OP_ADD, o->k, 2, o->k, k1);
	c_jump(b, SL_OP_BREAK, 1);
	emit(b, SL_OP_ADD, o->k, 2, o->k, kf(b, 100));   /* never */
	c_end(b, SL_OP_ILLUMINANCE_END, i3);
	return pb_finish(b);
}

static void test_illuminance(void)
{
	struct pb bs, bspot, bamb, bsun;
	struct surf o;
	struct sl_program *ps = build_surface(&bs, &o);
	struct sl_program *pspot = build_spot(&bspot);
	struct sl_program *pamb = build_ambient(&bamb);
	struct sl_program *psun = build_sun(&bsun);
	enum { NP = 5 };
	struct sl_exec *surf = sl_exec_create(ps, NP);
	struct sl_exec *lights[3] = {
		sl_exec_create(pspot, NP), sl_exec_create(pamb, NP), sl_exec_create(psun, NP),
	};
	CHECK(surf && lights[0] && lights[1] && lights[2]);
	if (!surf || !lights[0] || !lights[1] || !lights[2])
		goto done;
	static const char *const cats[3] = { "ignored", "fill", "ignored too" };
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, lights, 3);
	lh.categories = cats;
	CHECK_STR(lh.host.light_category(lh.host.user, 0), "key,spot");
	CHECK_STR(lh.host.light_category(lh.host.user, 1), "fill");
	CHECK_STR(lh.host.light_category(lh.host.user, 2), "sun");

	/* Points along x at z = 0, normals up. The spot at (0,0,5) reaches |x| <= 1.27. */
	const float px[NP] = { -2, -1, 0, 1, 2 };
	for (uint32_t i = 0; i < NP; i++) {
		set_global3(surf, SL_GLOBAL_P, i, px[i], 0, 0);
		set_global3(surf, SL_GLOBAL_N, i, 0, 0, 1);
	}
	CHECK(sl_exec_run(surf, &lh.host));
	for (uint32_t i = 0; i < NP; i++) {
		bool in = px[i] >= -1 && px[i] <= 1;
		/* spot (2) where inside, the sun (0.5) everywhere; the ambient light never. */
		CHECK_NEAR(R(surf, o.Ci, 0, i), (in ? 2 : 0) + 0.5, 1e-6);
		CHECK_NEAR(R(surf, o.n, 0, i), in ? 2 : 1, 0);
		/* L toward the spot: (0,0,5) - P; toward the sun: -(1,0,0). */
		CHECK_NEAR(R(surf, o.Lsum, 0, i), (in ? -px[i] : 0) - 1, 1e-5);
		CHECK_NEAR(R(surf, o.Lsum, 2, i), in ? 5 : 0, 1e-5);
		/* Cone around N (45 degrees): the spot's L is within it, the sun's is not. */
		CHECK_NEAR(R(surf, o.m, 0, i), in ? 1 : 0, 0);
		/* break leaves after the first light that reaches the point */
		CHECK_NEAR(R(surf, o.k, 0, i), 1, 0);
	}
	/* The last light run was the sun; the spot's lit mask is from its last run. */
	const uint8_t *lit = sl_exec_lit_mask(lights[0]);
	for (uint32_t i = 0; i < NP; i++)
		CHECK(lit[i] == (px[i] >= -1 && px[i] <= 1));
	CHECK(!sl_exec_is_ambient(lights[0]));
	CHECK(!sl_exec_is_ambient(lights[2]));
	CHECK(surf->cur_light == -1);
	/* The light's own L runs from the light to the surface: Ps - from. */
	CHECK_NEAR(R(lights[0], pspot->global_reg[SL_GLOBAL_L], 2, 0), -5, 1e-6);
	/* Message passing: a light's parameter after its run. */
	float v = 0;
	bool vary = true;
	CHECK(lh.host.light_message(lh.host.user, 0, "intensity", SL_TYPE_FLOAT, 0, &v, NULL, &vary,
				    NP));
	CHECK_NEAR(v, 2, 0);
	CHECK(!vary);
	float fr[3];
	CHECK(lh.host.light_message(lh.host.user, 0, "from", SL_TYPE_VECTOR, 0, fr, NULL, &vary, NP));
	CHECK_NEAR(fr[2], 5, 0);
	CHECK(!lh.host.light_message(lh.host.user, 0, "nosuch", SL_TYPE_FLOAT, 0, &v, NULL, &vary,
				     NP));
	CHECK(!lh.host.light_message(lh.host.user, 0, "intensity", SL_TYPE_STRING, 0, &v, NULL,
				     &vary, NP));
	const char *sv = NULL;
	CHECK(lh.host.light_message(lh.host.user, 2, "__category", SL_TYPE_STRING, 0, NULL, &sv,
				    &vary, NP));
	CHECK_STR(sv, "sun");
	/* A variable of another array length is not the light's parameter. */
	float arr[4] = { 0 };
	CHECK(!lh.host.light_message(lh.host.user, 0, "intensity", SL_TYPE_FLOAT, 4, arr, NULL,
				     &vary, NP));

	/* Ambient: light 1 by itself. */
	CHECK(sl_exec_run(lights[1], NULL));
	CHECK(sl_exec_is_ambient(lights[1]));

	/* Categories. */
	struct { const char *cat; float spot, sun; } cases[] = {
		{ "spot", 1, 0 }, { "-spot", 0, 1 }, { "key,sun", 1, 1 }, { "fill", 0, 0 },
		{ "-sun,-spot", 1, 1 }, { "nothing", 0, 0 },
	};
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		CHECK(sl_exec_set_param_string(surf, "cat", cases[c].cat));
		CHECK(sl_exec_run(surf, &lh.host));
		for (uint32_t i = 0; i < NP; i++) {
			bool in = px[i] >= -1 && px[i] <= 1;
			float want = (in ? 2 * cases[c].spot : 0) + 0.5f * cases[c].sun;
			CHECK_NEAR(R(surf, o.Ci, 0, i), want, 1e-6);
		}
	}

	/* Host-set light parameters: a wider cone, another intensity, a new category. */
	float wide = 1.2f, inten = 3;
	CHECK(sl_exec_set_param(lights[0], "angle", &wide, 1));
	CHECK(sl_exec_set_param(lights[0], "intensity", &inten, 1));
	CHECK(sl_exec_set_param_string(lights[0], "__category", "rim"));
	CHECK_STR(lh.host.light_category(lh.host.user, 0), "rim");
	CHECK(sl_exec_set_param_string(surf, "cat", "rim"));
	CHECK(sl_exec_run(surf, &lh.host));
	for (uint32_t i = 0; i < NP; i++)
		CHECK_NEAR(R(surf, o.Ci, 0, i), 3, 1e-6);

	/* Without a host: no lights; Ci stays 0 and Oi is 1. */
	CHECK(sl_exec_run(surf, NULL));
	for (uint32_t i = 0; i < NP; i++) {
		CHECK_NEAR(R(surf, o.Ci, 1, i), 0, 0);
		CHECK_NEAR(R(surf, ps->global_reg[SL_GLOBAL_OI], 1, i), 1, 0);
		CHECK_NEAR(R(surf, o.n, 0, i), 0, 0);
	}
done:
	sl_exec_destroy(surf);
	for (int k = 0; k < 3; k++)
		sl_exec_destroy(lights[k]);
	pb_free(&bs);
	pb_free(&bspot);
	pb_free(&bamb);
	pb_free(&bsun);
}

/* Three lights: light i has Cl = i + 1 and reaches every point from +z. */
struct fake_lights {
	int calls;
	uint32_t masked[8];   /* points asked for, per call */
};

static int fl_nlights(void *user)
{
	(void)user;
	return 3;
}

static bool fl_light(void *user, int i, struct sl_exec *surface, uint32_t n, uint32_t stride,
		     const uint8_t *mask, const float *Ps, const float *Ns, float *L, float *Cl,
		     float *Ol, uint8_t *lit, bool *ambient)
{
	struct fake_lights *fl = user;
	(void)surface;
	(void)Ps;
	(void)Ns;
	uint32_t cnt = 0;
	for (uint32_t k = 0; k < n; k++) {
		if (!mask[k])
			continue;
		cnt++;
		for (int c = 0; c < 3; c++) {
			L[c * stride + k] = c == 2 ? 1.0f : 0.0f;
			Cl[c * stride + k] = (float)(i + 1);
			Ol[c * stride + k] = 1;
		}
		lit[k] = 1;
	}
	if (fl->calls < 8)
		fl->masked[fl->calls] = cnt;
	fl->calls++;
	*ambient = false;
	return true;
}

static void test_illuminance_flow(void)
{
	/*
	 * for (j = 0; j < 2; j += 1) {
	 *   illuminance(P) {
	 *     if (Cl[0] == 2 && s > 0) continue;
	 *     if (Cl[0] == 3 && s > 1) break 2;
	 *     acc += Cl[0];
	 *   }
	 *   acc += 100;
	 * }
	 * FUNC { illuminance(P) { if (Cl[0] == 2 && s > 2) { r = 5; return; } r2 += Cl[0]; }
	 *        r2 += 1000; }
	 */
	struct pb b;
	pb_init(&b, SL_SHADER_SURFACE);
	int32_t s = glob(&b, SL_GLOBAL_S, SL_TYPE_FLOAT, true);
	int32_t P = glob(&b, SL_GLOBAL_P, SL_TYPE_POINT, true);
	int32_t Cl = glob(&b, SL_GLOBAL_CL, SL_TYPE_COLOR, true);
	int32_t k0 = kf(&b, 0), k1 = kf(&b, 1), k2 = kf(&b, 2), k3 = kf(&b, 3);
	int32_t k5 = kf(&b, 5), k100 = kf(&b, 100), k1000 = kf(&b, 1000);
	body(&b);
	int32_t j = vreg(&b, SL_TYPE_FLOAT), acc = vreg(&b, SL_TYPE_FLOAT);
	int32_t c = vreg(&b, SL_TYPE_BOOL), c2 = vreg(&b, SL_TYPE_BOOL);
	int32_t cl0 = vreg(&b, SL_TYPE_FLOAT), r = vreg(&b, SL_TYPE_FLOAT);
	int32_t r2 = vreg(&b, SL_TYPE_FLOAT);
	emit(&b, SL_OP_MOV, acc, 1, k0);
	emit(&b, SL_OP_MOV, r, 1, k0);
	emit(&b, SL_OP_MOV, r2, 1, k0);
	emit(&b, SL_OP_MOV, j, 1, k0);
	uint32_t l = c_loop(&b);
	emit(&b, SL_OP_LT, c, 2, j, k2);
	c_looptest(&b, l, c);
	uint32_t il = emit(&b, SL_OP_ILLUMINANCE, -1, 1, P);
	emit(&b, SL_OP_COMP, cl0, 1, Cl);
	emit(&b, SL_OP_EQ, c, 2, cl0, k2);
	emit(&b, SL_OP_GT, c2, 2, s, k0);
	emit(&b, SL_OP_AND, c, 2, c, c2);
	uint32_t f1 = c_if(&b, c);
	c_jump(&b, SL_OP_CONTINUE, 1);
	c_endif(&b, f1);
	emit(&b, SL_OP_EQ, c, 2, cl0, k3);
	emit(&b, SL_OP_GT, c2, 2, s, k1);
	emit(&b, SL_OP_AND, c, 2, c, c2);
	uint32_t f2 = c_if(&b, c);
	c_jump(&b, SL_OP_BREAK, 2);
	c_endif(&b, f2);
	emit(&b, SL_OP_ADD, acc, 2, acc, cl0);
	c_end(&b, SL_OP_ILLUMINANCE_END, il);
	emit(&b, SL_OP_ADD, acc, 2, acc, k100);
	c_loopcont(&b, l);
	emit(&b, SL_OP_ADD, j, 2, j, k1);
	c_loopend(&b, l);
	uint32_t fn = emit(&b, SL_OP_FUNC, -1, 0);
	uint32_t il2 = emit(&b, SL_OP_ILLUMINANCE, -1, 1, P);
	emit(&b, SL_OP_COMP, cl0, 1, Cl);
	emit(&b, SL_OP_EQ, c, 2, cl0, k2);
	emit(&b, SL_OP_GT, c2, 2, s, k2);
	emit(&b, SL_OP_AND, c, 2, c, c2);
	uint32_t f3 = c_if(&b, c);
	emit(&b, SL_OP_MOV, r, 1, k5);
	emit(&b, SL_OP_RETURN, -1, 0);
	c_endif(&b, f3);
	emit(&b, SL_OP_ADD, r2, 2, r2, cl0);
	c_end(&b, SL_OP_ILLUMINANCE_END, il2);
	emit(&b, SL_OP_ADD, r2, 2, r2, k1000);
	c_end(&b, SL_OP_FUNCEND, fn);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 4);
	CHECK(x != NULL);
	if (!x) {
		pb_free(&b);
		return;
	}
	struct fake_lights fl = { 0 };
	struct sl_host host = { .user = &fl, .nlights = fl_nlights, .light = fl_light };
	const float sv[4] = { -1, 0.5f, 1.5f, 3 };
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, &host));
	const float want_acc[4] = { 212, 208, 1, 1 };
	const float want_r[4] = { 0, 0, 0, 5 }, want_r2[4] = { 1006, 1006, 1006, 1 };
	for (uint32_t i = 0; i < 4; i++) {
		CHECK_NEAR(R(x, acc, 0, i), want_acc[i], 0);
		CHECK_NEAR(R(x, r, 0, i), want_r[i], 0);
		CHECK_NEAR(R(x, r2, 0, i), want_r2[i], 0);
	}
	/* Lights are asked only for points still in the loop: after the break at
	 * light 3 of the first pass, the second pass has two points. */
	CHECK(fl.calls == 9);
	CHECK(fl.masked[0] == 4 && fl.masked[2] == 4);
	CHECK(fl.masked[3] == 2 && fl.masked[5] == 2);
	CHECK(fl.masked[6] == 4 && fl.masked[7] == 4);
	sl_exec_destroy(x);
	pb_free(&b);
}

/* A light that evaluates itself through the host: refused, never recursion. */
static void test_light_recursion(void)
{
	struct pb b;
	pb_init(&b, SL_SHADER_LIGHT);
	int32_t P = glob(&b, SL_GLOBAL_PS, SL_TYPE_POINT, true);
	body(&b);
	uint32_t il = emit(&b, SL_OP_ILLUMINANCE, -1, 1, P);
	c_end(&b, SL_OP_ILLUMINANCE_END, il);
	struct sl_program *prog = pb_finish(&b);
	struct sl_exec *x = sl_exec_create(prog, 2);
	CHECK(x != NULL);
	if (x) {
		struct sl_exec *lights[1] = { x };
		struct sl_lighthost lh;
		sl_lighthost_init(&lh, lights, 1);
		CHECK(sl_exec_run(x, &lh.host));
		sl_exec_destroy(x);
	}
	pb_free(&b);
}

/*
 * solar() without arguments and Ns: the light shines along the normal the
 * surface evaluates it with (L = -Ns in the light, +Ns in the surface), so
 * N.L is 1, and no illuminance cone about that normal culls it, however
 * narrow. Closed forms: L, Cl and diffuse() equal the normal given.
 */
static const char allsky_src[] =
	"light allsky(float k = 2) {\n"
	"	solar() { Cl = k * color(xcomp(Ns), ycomp(Ns), zcomp(Ns)); }\n"
	"}\n";
/* A local light that reports Ns through Cl. */
static const char nsprobe_src[] =
	"light nsprobe(point from = point(0, 0, 10)) {\n"
	"	illuminate(from) { Cl = color(xcomp(Ns), ycomp(Ns), zcomp(Ns)); }\n"
	"}\n";
static const char solarsurf_src[] =
	"surface solarsurf(output varying vector Ls = 0; output varying color Ca = 0;\n"
	"	output varying float cnt = 0; output varying vector Lc = 0;\n"
	"	output varying color Cn = 0; output varying color Cd = 0;\n"
	"	output varying color Cs2 = 0)\n"
	"{\n"
	"	normal Nf = normalize(N);\n"
	"	illuminance(P, Nf, 0.01) { Ls += L; Ca += Cl; cnt += 1; }\n"
	"	illuminance(P) { Lc += L; Cn += Cl; }\n"
	"	Cd = diffuse(Nf);\n"
	"	Cs2 = specular(Nf, -normalize(I), 0.2);\n"
	"	Ci = 0;\n"
	"}\n";

static int32_t out_reg(const struct sl_program *p, const char *name)
{
	int k = sl_program_find_param(p, name);
	CHECK(k >= 0);
	return k >= 0 ? p->params[k].reg : -1;
}

static void test_solar_all(void)
{
	enum { NP = 4 };
	struct sl_program *sp = sl_compile_string("solarsurf.sl", solarsurf_src,
						  strlen(solarsurf_src), NULL);
	struct sl_program *lp = sl_compile_string("allsky.sl", allsky_src, strlen(allsky_src), NULL);
	struct sl_program *np = sl_compile_string("nsprobe.sl", nsprobe_src, strlen(nsprobe_src),
						  NULL);
	CHECK(sp && lp && np);
	struct sl_exec *sx = sp ? sl_exec_create(sp, NP) : NULL;
	struct sl_exec *lights[2] = { lp ? sl_exec_create(lp, NP) : NULL,
				      np ? sl_exec_create(np, NP) : NULL };
	if (!sx || !lights[0] || !lights[1])
		goto out;
	/* Normals of several lengths and directions, facing away from the eye too. */
	static const float N[NP][3] = { { 0, 0, 1 }, { 0.3f, -2, 0.5f }, { -1, 1, -1 },
					{ 0, 3, 0 } };
	for (uint32_t i = 0; i < NP; i++) {
		set_global3(sx, SL_GLOBAL_P, i, (float)i - 1.5f, 0.5f, 2);
		set_global3(sx, SL_GLOBAL_I, i, (float)i - 1.5f, 0.5f, 2);
		set_global3(sx, SL_GLOBAL_N, i, N[i][0], N[i][1], N[i][2]);
	}
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, lights, 1);
	CHECK(sl_exec_run(sx, &lh.host));
	int32_t Ls = out_reg(sp, "Ls"), Ca = out_reg(sp, "Ca"), cnt = out_reg(sp, "cnt"),
		Lc = out_reg(sp, "Lc"), Cn = out_reg(sp, "Cn"), Cd = out_reg(sp, "Cd"),
		Cs2 = out_reg(sp, "Cs2");
	for (uint32_t i = 0; i < NP; i++) {
		float len = sqrtf(N[i][0] * N[i][0] + N[i][1] * N[i][1] + N[i][2] * N[i][2]);
		/* Never culled by a cone of 0.01 rad about Nf. */
		CHECK_NEAR(R(sx, cnt, 0, i), 1, 0);
		for (int c = 0; c < 3; c++) {
			float nf = N[i][c] / len;
			CHECK_NEAR(R(sx, Ls, c, i), nf, 1e-6);
			CHECK_NEAR(R(sx, Ca, c, i), 2 * nf, 1e-6);
			/* Without an axis the lights get the surface's N, as it is. */
			CHECK_NEAR(R(sx, Lc, c, i), N[i][c], 1e-6);
			CHECK_NEAR(R(sx, Cn, c, i), 2 * N[i][c], 1e-6);
			/* diffuse(Nf): N.L = 1 for a light along Nf. */
			CHECK_NEAR(R(sx, Cd, c, i), 2 * nf, 1e-6);
		}
		/* specular(): L is the normal, H = normalize(Nf + V): PRMan's (N.H)^(8/r). */
		float V[3] = { -((float)i - 1.5f), -0.5f, -2 }, H[3], vl = 0, hl = 0, nh = 0;
		for (int c = 0; c < 3; c++)
			vl += V[c] * V[c];
		for (int c = 0; c < 3; c++) {
			H[c] = N[i][c] / len + V[c] / sqrtf(vl);
			hl += H[c] * H[c];
		}
		for (int c = 0; c < 3; c++)
			nh += N[i][c] / len * H[c] / sqrtf(hl);
		float spec = powf(fmaxf(0.0f, nh), 8 / 0.2f);
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(R(sx, Cs2, c, i), 2 * N[i][c] / len * spec, 1e-5);
	}
	/* Ns in a local light: the normal of each call, as a light from (0, 0, 10). */
	sl_lighthost_init(&lh, lights + 1, 1);
	CHECK(sl_exec_run(sx, &lh.host));
	for (uint32_t i = 0; i < NP; i++) {
		float len = sqrtf(N[i][0] * N[i][0] + N[i][1] * N[i][1] + N[i][2] * N[i][2]);
		float Lv[3] = { 1.5f - (float)i, -0.5f, 8 }, ll = 0, cosl = 0;
		for (int c = 0; c < 3; c++)
			ll += Lv[c] * Lv[c];
		for (int c = 0; c < 3; c++)
			cosl += N[i][c] / len * Lv[c] / sqrtf(ll);
		for (int c = 0; c < 3; c++) {
			CHECK_NEAR(R(sx, Cn, c, i), N[i][c], 1e-6);
			CHECK_NEAR(R(sx, Cd, c, i), cosl >= 0 ? N[i][c] / len * cosl : 0, 1e-6);
		}
	}
	/* A light's own P is the origin of its shader space; ncomps is 3. */
	static const char geo_src[] =
		"light geo() { solar() { Cl = color(xcomp(P), ycomp(P), zcomp(P)) + 10 * ncomps; } }\n";
	struct sl_program *gp = sl_compile_string("geo.sl", geo_src, strlen(geo_src), NULL);
	struct sl_exec *gx = gp ? sl_exec_create(gp, NP) : NULL;
	CHECK(gx != NULL);
	if (gx) {
		static const float shader_mat[1][16] = { { 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0,
							   1, 2, 3, 1 } };
		sl_lighthost_init(&lh, &gx, 1);
		lh.light_shader_mats = shader_mat;
		CHECK(sl_exec_run(sx, &lh.host));
		for (uint32_t i = 0; i < NP; i++)
			for (int c = 0; c < 3; c++)
				CHECK_NEAR(R(sx, Cn, c, i), 31 + c, 1e-6);
	}
	sl_exec_destroy(gx);
	sl_program_destroy(gp);
	/* dtime (and time) come from the surface, when both shaders have them. */
	static const char dtl_src[] = "light dtl() { solar() { Cl = color(dtime, time, 0); } }\n";
	static const char dts_src[] =
		"surface dts(output varying color c = 0) {\n"
		"	float d = dtime + time;\n"
		"	illuminance(P) c += Cl;\n"
		"	Ci = d;\n"
		"}\n";
	struct sl_program *dlp = sl_compile_string("dtl.sl", dtl_src, strlen(dtl_src), NULL);
	struct sl_program *dsp = sl_compile_string("dts.sl", dts_src, strlen(dts_src), NULL);
	struct sl_exec *dlx = dlp ? sl_exec_create(dlp, NP) : NULL;
	struct sl_exec *dsx = dsp ? sl_exec_create(dsp, NP) : NULL;
	CHECK(dlx && dsx);
	if (dlx && dsx) {
		bool v;
		sl_exec_global(dsx, SL_GLOBAL_DTIME, &v)[0] = 0.25f;
		sl_exec_global(dsx, SL_GLOBAL_TIME, &v)[0] = 0.5f;
		sl_lighthost_init(&lh, &dlx, 1);
		CHECK(sl_exec_run(dsx, &lh.host));
		int32_t c = out_reg(dsp, "c");
		for (uint32_t i = 0; i < NP; i++) {
			CHECK_NEAR(R(dsx, c, 0, i), 0.25f, 0);
			CHECK_NEAR(R(dsx, c, 1, i), 0.5f, 0);
		}
	}
	sl_exec_destroy(dlx);
	sl_exec_destroy(dsx);
	sl_program_destroy(dlp);
	sl_program_destroy(dsp);
	/* Ns outside a light shader is an error. */
	static const char bad_src[] = "surface bad() { Ci = color(xcomp(Ns), 0, 0); }\n";
	struct sl_program *bad = sl_compile_string("bad.sl", bad_src, strlen(bad_src), NULL);
	CHECK(bad == NULL);
	sl_program_destroy(bad);
out:
	sl_exec_destroy(sx);
	sl_exec_destroy(lights[0]);
	sl_exec_destroy(lights[1]);
	sl_program_destroy(sp);
	sl_program_destroy(lp);
	sl_program_destroy(np);
}

/* ------------------------------------------------------------------------ */
/* Derivative stencils                                                       */

#define SNU 9
#define SNV 7
#define SN (SNU * SNV)

/*
 * Derivatives of Q, an affine function of P (a matrix, an offset and a
 * uniform factor), in every form the interpreter takes them.
 */
static const char probe_src[] =
	"surface probe(float k = 1.5;\n"
	"	output varying vector dQu = 0; output varying vector dQv = 0;\n"
	"	output varying float ar = 0; output varying normal nq = 0;\n"
	"	output varying float dg = 0; output varying float fs = 0;\n"
	"	output varying float tx = 0; output varying float sh = 0;\n"
	"	output varying vector ddQ = 0)\n"
	"{\n"
	"	matrix M = matrix(0.8, 0.1, -0.3, 0,  0.2, 1.1, 0.4, 0,\n"
	"			  -0.5, 0.3, 0.9, 0,  0.4, -0.7, 0.5, 1);\n"
	"	point Q = transform(M, P) * k + point(0.3, -0.2, 0.5);\n"
	"	dQu = Du(Q);\n"
	"	dQv = Dv(Q);\n"
	"	ar = area(Q);\n"
	"	nq = calculatenormal(Q);\n"
	"	float g = xcomp(Q) - 2 * zcomp(Q), h = ycomp(P) - xcomp(P) - 2 * zcomp(P);\n"
	"	dg = Deriv(g, h);\n"
	"	fs = filterstep(2.4, xcomp(Q));\n"
	"	tx = texture(\"map\", xcomp(Q), ycomp(Q));\n"
	"	sh = shadow(\"smap\", Q);\n"
	"	ddQ = Du(dQu) + Dv(dQv);\n"
	"	Oi = 1;\n"
	"	Ci = 0;\n"
	"}\n";

/* Filter regions a host was asked for: corner k of point i (texture s, t; shadow x, y, z). */
struct seen {
	float s[4][3 * SN], t[4][3 * SN];
	float pos[4][3][3 * SN];
	int ntex, nshadow;
};

static bool seen_texture(void *user, const struct sl_tex_lookup *q)
{
	struct seen *w = user;
	w->ntex++;
	for (int k = 0; k < 4; k++)
		for (uint32_t i = 0; i < q->n && i < 3 * SN; i++) {
			w->s[k][i] = q->s[k][i];
			w->t[k][i] = q->t[k][i];
		}
	for (uint32_t i = 0; i < q->n; i++)
		q->out[i] = 0.25f;
	return true;
}

/* A shadow lookup: records its corners, answers with the size of the region. */
static bool seen_shadow(struct seen *w, const struct sl_tex_lookup *q)
{
	w->nshadow++;
	for (uint32_t i = 0; i < q->n; i++) {
		float e[2] = { 0, 0 };
		for (int c = 0; c < 3; c++) {
			for (int k = 0; k < 4; k++)
				if (i < 3 * SN)
					w->pos[k][c][i] = q->pos[k][(size_t)c * q->stride + i];
			float a = q->pos[1][(size_t)c * q->stride + i] - q->pos[0][(size_t)c * q->stride + i];
			float b = q->pos[3][(size_t)c * q->stride + i] - q->pos[0][(size_t)c * q->stride + i];
			e[0] += a * a;
			e[1] += b * b;
		}
		q->out[i] = fminf(1.0f, sqrtf(e[0]) + sqrtf(e[1]));
	}
	return true;
}

static bool seen_shadow_host(void *user, const struct sl_tex_lookup *q)
{
	return seen_shadow(user, q);
}

/* The light host's shadow callback: what it saw goes to the host's owner. */
static bool seen_shadow_lh(void *user, const struct sl_tex_lookup *q)
{
	return seen_shadow(((struct sl_lighthost *)user)->owner, q);
}

/* A permutation of 0..n-1 drawn from @seed (xorshift32). */
static void shuffle_order(uint32_t *order, uint32_t n, uint32_t seed)
{
	uint32_t r = seed ? seed : 1;
	for (uint32_t i = 0; i < n; i++)
		order[i] = i;
	for (uint32_t i = n; i-- > 1;) {
		r ^= r << 13;
		r ^= r >> 17;
		r ^= r << 5;
		uint32_t j = r % (i + 1);
		uint32_t t = order[i];
		order[i] = order[j];
		order[j] = t;
	}
}

/* A sphere patch on an SNU x SNV grid: P and N (planar, SN floats per component). */
static void sphere_patch(float *P, float *N)
{
	for (uint32_t iv = 0; iv < SNV; iv++)
		for (uint32_t iu = 0; iu < SNU; iu++) {
			uint32_t i = iv * SNU + iu;
			float th = 0.5f + 0.6f * (float)iv / (SNV - 1);
			float ph = 0.3f + 0.8f * (float)iu / (SNU - 1);
			float n[3] = { sinf(th) * cosf(ph), sinf(th) * sinf(ph), cosf(th) };
			for (int c = 0; c < 3; c++) {
				N[c * SN + i] = n[c];
				P[c * SN + i] = 2 * n[c] + (c == 2 ? 1.0f : 0.0f);
			}
		}
}

/* Write planar @v (SN per component, @nc components) into global @g at points order[j]. */
static void put_global(struct sl_exec *x, enum sl_global g, int nc, const float *v,
		       const uint32_t *order, uint32_t n, uint32_t at)
{
	bool vary;
	float *d = sl_exec_global(x, g, &vary);
	if (!d || !vary)
		return;
	for (int c = 0; c < nc; c++)
		for (uint32_t j = 0; j < n; j++)
			d[(size_t)c * x->stride + at + j] = v[c * SN + (order ? order[j] : j)];
}

static void set_uniform(struct sl_exec *x, enum sl_global g, float v)
{
	bool vary;
	float *d = sl_exec_global(x, g, &vary);
	if (d && !vary)
		d[0] = v;
}

/*
 * The changes of P over one grid step as the bake computes them
 * (sl_exec_delta on the real grid): dPu, dPv planar, SN per component.
 */
static void grid_deltas(struct sl_exec *x, const float *P, float *dPu, float *dPv)
{
	CHECK(sl_exec_set_grid(x, SNU, SNV));
	CHECK(sl_exec_stencil(x) == 0);
	for (int c = 0; c < 3; c++)
		sl_exec_delta(x, P + c * SN, dPu + c * SN, dPv + c * SN);
}

/* The stencil inputs of global @g from grid values @v and grid changes @du, @dv (NULL: copies). */
static void put_stencil(struct sl_exec *x, enum sl_global g, int nc, const float *v,
			const float *du, const float *dv, const uint32_t *order, uint32_t m,
			const float *scale)
{
	bool vary;
	float *d = sl_exec_global(x, g, &vary);
	if (!d || !vary)
		return;
	for (int c = 0; c < nc; c++)
		for (uint32_t j = 0; j < m; j++) {
			uint32_t i = order[j];
			float f = scale ? scale[j] : 1.0f;
			float *p = d + (size_t)c * x->stride;
			p[j] = v[c * SN + i];
			p[m + j] = v[c * SN + i] + (du ? f * du[c * SN + i] : 0.0f);
			p[2 * m + j] = v[c * SN + i] + (dv ? dv[c * SN + i] : 0.0f);
		}
}

/* Outputs of the probe, per name: ncomp planes of SN (grid) or 3 SN (stencil) values. */
static const char *const probe_outs[] = { "dQu", "dQv", "ar", "nq", "dg", "fs", "ddQ" };
#define NPROBE (sizeof(probe_outs) / sizeof(probe_outs[0]))

static float probe_out(struct sl_exec *x, const char *name, int c, uint32_t i)
{
	const struct sl_program *p = sl_exec_program(x);
	int k = sl_program_find_param(p, name);
	if (k < 0)
		return NAN;
	int32_t r = p->params[k].reg;
	int nc = sl_reg_ncomp(&p->regs[r]);
	return sl_x_get(x, r, c < nc ? c : 0, i);
}

static int probe_ncomp(struct sl_exec *x, const char *name)
{
	const struct sl_program *p = sl_exec_program(x);
	int k = sl_program_find_param(p, name);
	return k < 0 ? 0 : sl_reg_ncomp(&p->regs[p->params[k].reg]);
}

/*
 * Largest difference of the stencil run's samples from the grid run's
 * points order[j], relative to the largest magnitude of that output on the
 * grid; @scale[j] multiplies the grid value (NULL: 1).
 */
static double probe_diff(struct sl_exec *sx, float grid[NPROBE][3][SN], size_t o,
			 const uint32_t *order, uint32_t m, const float *scale)
{
	int nc = probe_ncomp(sx, probe_outs[o]);
	double big = 0, err = 0;
	for (int c = 0; c < nc; c++)
		for (uint32_t i = 0; i < SN; i++)
			big = fmax(big, fabs(grid[o][c][i]));
	for (int c = 0; c < nc; c++)
		for (uint32_t j = 0; j < m; j++) {
			double want = grid[o][c][order[j]] * (scale ? scale[j] : 1.0f);
			double e = fabs(probe_out(sx, probe_outs[o], c, j) - want) / fmax(big, 1e-30);
			if (!(e <= err))
				err = e;
		}
	return err;
}

struct stencil_run {
	struct sl_exec *x;
	const struct sl_host *host;
};

static bool run_stencil_case(void *arg)
{
	struct stencil_run *r = arg;
	return sl_exec_run(r->x, r->host);
}

/*
 * Du, Dv, Deriv, area, calculatenormal, filterstep and the texture and
 * shadow filter regions of an affine function of P: on a sphere patch's
 * grid, then on stencils of its samples in a shuffled order (moved inputs
 * P + Du(P) du and P + Dv(P) dv from the grid). The samples' results
 * equal the grid's (to 1e-5 of each output's magnitude).
 */
static void test_stencil_deriv(void)
{
	struct sl_program *prog = sl_compile_string("probe.sl", probe_src, strlen(probe_src), NULL);
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, 3 * SN);
	CHECK(x != NULL);
	if (!x) {
		sl_program_destroy(prog);
		return;
	}
	static struct seen seen, grid_seen;
	struct sl_host host = { .user = &seen, .texture = seen_texture, .shadow = seen_shadow_host };
	static float P[3 * SN], N[3 * SN], dPu[3 * SN], dPv[3 * SN];
	static float grid[NPROBE][3][SN];
	sphere_patch(P, N);
	const float du = 1.0f / (SNU - 1), dv = 1.0f / (SNV - 1);

	/* the grid */
	CHECK(sl_exec_set_grid(x, SNU, SNV));
	put_global(x, SL_GLOBAL_P, 3, P, NULL, SN, 0);
	set_uniform(x, SL_GLOBAL_DU, du);
	set_uniform(x, SL_GLOBAL_DV, dv);
	memset(&seen, 0, sizeof(seen));
	CHECK(sl_exec_run(x, &host));
	CHECK(seen.ntex == 1 && seen.nshadow == 1);
	grid_seen = seen;
	for (size_t o = 0; o < NPROBE; o++)
		for (int c = 0; c < probe_ncomp(x, probe_outs[o]); c++)
			for (uint32_t i = 0; i < SN; i++)
				grid[o][c][i] = probe_out(x, probe_outs[o], c, i);
	/* sanity: the derivative of Q along u is M k applied to Du(P), not 0 */
	CHECK(fabsf(grid[0][0][SN / 2]) > 0.1f && grid[2][0][SN / 2] > 0.01f);
	grid_deltas(x, P, dPu, dPv);

	/* stencils of every sample, shuffled; the uniform du, dv are wrong on purpose */
	uint32_t order[SN];
	shuffle_order(order, SN, 7);
	float hu[SN], hv[SN];
	for (uint32_t j = 0; j < SN; j++) {
		hu[j] = du;
		hv[j] = dv;
	}
	const uint32_t m = SN;
	CHECK(sl_exec_set_grid(x, 3 * m, 1));
	CHECK(sl_exec_set_stencil(x, m, hu, hv));
	CHECK(sl_exec_stencil(x) == m);
	put_stencil(x, SL_GLOBAL_P, 3, P, dPu, dPv, order, m, NULL);
	set_uniform(x, SL_GLOBAL_DU, 0.37f);
	set_uniform(x, SL_GLOBAL_DV, 0.29f);
	memset(&seen, 0, sizeof(seen));
	CHECK(sl_exec_run(x, &host));
	double worst = 0;
	for (size_t o = 0; o < NPROBE; o++) {
		if (!strcmp(probe_outs[o], "ddQ"))
			continue;
		double e = probe_diff(x, grid, o, order, m, NULL);
		if (!(e <= 1e-5))
			fprintf(stderr, "stencil %s: relative difference %g\n", probe_outs[o], e);
		CHECK(e <= 1e-5);
		worst = fmax(worst, e);
	}
	printf("stencils: Du, Dv, Deriv, area, calculatenormal, filterstep within %.3g "
	       "of their magnitudes\n", worst);
	/* second derivatives vanish: the moved points carry their sample's derivative */
	for (uint32_t j = 0; j < 3 * m; j++)
		for (int c = 0; c < 3; c++)
			CHECK(probe_out(x, "ddQ", c, j) == 0.0f);
	for (uint32_t j = 0; j < m; j++)
		CHECK(probe_out(x, "dQu", 1, m + j) == probe_out(x, "dQu", 1, j));
	/* the filter regions the host saw */
	double terr = 0, serr = 0;
	for (int k = 0; k < 4; k++)
		for (uint32_t j = 0; j < m; j++) {
			uint32_t i = order[j];
			terr = fmax(terr, fabs(seen.s[k][j] - grid_seen.s[k][i]));
			terr = fmax(terr, fabs(seen.t[k][j] - grid_seen.t[k][i]));
			for (int c = 0; c < 3; c++)
				serr = fmax(serr, fabs(seen.pos[k][c][j] - grid_seen.pos[k][c][i]));
		}
	printf("stencils: texture corners within %.3g, shadow corners within %.3g\n", terr, serr);
	CHECK(terr <= 2e-5);
	CHECK(serr <= 2e-5);
	/* ... which are not points: the corners differ from the centre by the grid's steps */
	CHECK(fabs(grid_seen.s[1][SN / 2] - grid_seen.s[0][SN / 2]) > 0.05);

	/* per-sample steps: twice the step (and twice the move) along u for every third
	 * sample gives the same derivatives and twice the area */
	float scale[SN];
	for (uint32_t j = 0; j < m; j++) {
		scale[j] = j % 3 ? 1.0f : 2.0f;
		hu[j] = du * scale[j];
	}
	CHECK(sl_exec_set_stencil(x, m, hu, hv));
	put_stencil(x, SL_GLOBAL_P, 3, P, dPu, dPv, order, m, scale);
	CHECK(sl_exec_run(x, &host));
	CHECK(probe_diff(x, grid, 0, order, m, NULL) <= 1e-5);  /* dQu */
	CHECK(probe_diff(x, grid, 3, order, m, NULL) <= 1e-5);  /* nq */
	CHECK(probe_diff(x, grid, 2, order, m, scale) <= 1e-5); /* ar */

	/* a subset of the samples: the interior ones, in reverse */
	uint32_t inner[SN], ni = 0;
	for (uint32_t iv = SNV - 1; iv-- > 1;)
		for (uint32_t iu = SNU - 1; iu-- > 1;)
			inner[ni++] = iv * SNU + iu;
	for (uint32_t j = 0; j < ni; j++) {
		hu[j] = du;
		hv[j] = dv;
	}
	CHECK(sl_exec_set_grid(x, 3 * ni, 1));
	CHECK(sl_exec_set_stencil(x, ni, hu, hv));
	put_stencil(x, SL_GLOBAL_P, 3, P, dPu, dPv, inner, ni, NULL);
	CHECK(sl_exec_run(x, &host));
	for (size_t o = 0; o + 1 < NPROBE; o++)
		CHECK(probe_diff(x, grid, o, inner, ni, NULL) <= 1e-5);

	/* m = 0: grid derivatives again */
	CHECK(sl_exec_set_stencil(x, 0, NULL, NULL));
	CHECK(sl_exec_stencil(x) == 0);
	CHECK(sl_exec_set_grid(x, SNU, SNV));
	put_global(x, SL_GLOBAL_P, 3, P, NULL, SN, 0);
	set_uniform(x, SL_GLOBAL_DU, du);
	set_uniform(x, SL_GLOBAL_DV, dv);
	CHECK(sl_exec_run(x, &host));
	uint32_t ident[SN];
	for (uint32_t i = 0; i < SN; i++)
		ident[i] = i;
	for (size_t o = 0; o < NPROBE; o++)
		CHECK(probe_diff(x, grid, o, ident, SN, NULL) == 0);

	/* without stencils the same samples in a row give other derivatives */
	CHECK(sl_exec_set_grid(x, SN, 1));
	put_global(x, SL_GLOBAL_P, 3, P, order, SN, 0);
	CHECK(sl_exec_run(x, &host));
	CHECK(probe_diff(x, grid, 0, order, SN, NULL) > 0.1);

	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/* Wrong grids and steps are refused with a message; the stencil stays as it was. */
static void test_stencil_errors(void)
{
	struct sl_program *prog = sl_compile_string("probe.sl", probe_src, strlen(probe_src), NULL);
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, 30);
	CHECK(x != NULL);
	if (!x) {
		sl_program_destroy(prog);
		return;
	}
	float h[11], bad[11];
	for (int i = 0; i < 11; i++)
		h[i] = bad[i] = 0.125f;
	fprintf(stderr, "(four error messages expected)\n");
	CHECK(!sl_exec_set_stencil(x, 11, h, h));   /* 33 points > 30 */
	CHECK(sl_exec_stencil(x) == 0);
	CHECK(sl_exec_set_stencil(x, 10, h, h));
	CHECK(!sl_exec_set_stencil(x, 5, h, NULL));
	bad[3] = NAN;
	CHECK(!sl_exec_set_stencil(x, 4, bad, h));
	bad[3] = INFINITY;
	CHECK(!sl_exec_set_stencil(x, 4, h, bad));
	CHECK(sl_exec_stencil(x) == 10);
	CHECK(sl_exec_stencil(NULL) == 0);
	CHECK(!sl_exec_set_stencil(NULL, 1, h, h));

	/* the grid must be 3m x 1 */
	struct sl_host host = { 0 };
	struct stencil_run r = { x, &host };
	char msg[512];
	bool ok = true;
	CHECK(sl_exec_set_grid(x, 29, 1));
	capture_stderr(msg, sizeof(msg), run_stencil_case, &r, &ok);
	CHECK(!ok);
	CHECK(strstr(msg, "derivative stencils of 10 samples") != NULL);
	CHECK(sl_exec_set_grid(x, 10, 3));
	capture_stderr(msg, sizeof(msg), run_stencil_case, &r, &ok);
	CHECK(!ok);
	CHECK(sl_exec_set_grid(x, 30, 1));
	capture_stderr(msg, sizeof(msg), run_stencil_case, &r, &ok);
	CHECK(ok);
	/* m = 0 ignores the steps: grid derivatives on any grid */
	CHECK(sl_exec_set_stencil(x, 0, bad, NULL));
	CHECK(sl_exec_set_grid(x, 5, 6));
	capture_stderr(msg, sizeof(msg), run_stencil_case, &r, &ok);
	CHECK(ok);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/* A light whose shadow filter region comes from Ps. */
static const char shadowlight_src[] =
	"light shl(float intensity = 1; string map = \"smap\")\n"
	"{\n"
	"	illuminate(point(0.5, 0.5, 9)) {\n"
	"		Cl = intensity * (1 - shadow(map, Ps));\n"
	"	}\n"
	"}\n";

static const char litsurf_src[] =
	"surface lit(float Kd = 0.8)\n"
	"{\n"
	"	Oi = 1;\n"
	"	Ci = Kd * diffuse(normalize(N));\n"
	"}\n";

struct lit_case {
	struct sl_exec *x;
	struct sl_lighthost *lh;
	int runs;
};

static bool run_lit_case(void *arg)
{
	struct lit_case *c = arg;
	bool ok = true;
	for (int k = 0; k < c->runs; k++)
		ok = sl_exec_run(c->x, &c->lh->host) && ok;
	return ok;
}

/*
 * Lights run through the light host take the surface's stencils: a shadow's
 * filter region of Ps is the grid's for every sample, and the light goes
 * back to grid derivatives with the surface.
 */
static void test_stencil_lights(void)
{
	struct sl_program *lp = sl_compile_string("shl.sl", shadowlight_src,
						  strlen(shadowlight_src), NULL);
	struct sl_program *sp = sl_compile_string("lit.sl", litsurf_src, strlen(litsurf_src), NULL);
	CHECK(lp && sp);
	struct sl_exec *sx = sp ? sl_exec_create(sp, 3 * SN) : NULL;
	struct sl_exec *lx = lp ? sl_exec_create(lp, 3 * SN) : NULL;
	struct sl_exec *small = lp ? sl_exec_create(lp, SN) : NULL;
	CHECK(sx && lx && small);
	if (!sx || !lx || !small)
		goto out;
	static struct seen seen, grid_seen;
	static float P[3 * SN], N[3 * SN], dPu[3 * SN], dPv[3 * SN], grid_ci[3][SN];
	sphere_patch(P, N);
	const float du = 1.0f / (SNU - 1), dv = 1.0f / (SNV - 1);
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, &lx, 1);
	lh.owner = &seen;
	lh.host.shadow = seen_shadow_lh;

	CHECK(sl_exec_set_grid(sx, SNU, SNV));
	put_global(sx, SL_GLOBAL_P, 3, P, NULL, SN, 0);
	put_global(sx, SL_GLOBAL_N, 3, N, NULL, SN, 0);
	memset(&seen, 0, sizeof(seen));
	CHECK(sl_exec_run(sx, &lh.host));
	CHECK(seen.nshadow == 1);
	CHECK(sl_exec_stencil(lx) == 0);
	grid_seen = seen;
	bool vary;
	const float *ci = sl_exec_global(sx, SL_GLOBAL_CI, &vary);
	for (int c = 0; c < 3; c++)
		for (uint32_t i = 0; i < SN; i++)
			grid_ci[c][i] = ci[(size_t)c * sx->stride + i];
	CHECK(grid_ci[0][SN / 2] > 0.05f && grid_ci[0][SN / 2] < 0.8f);  /* shadowed in part */
	grid_deltas(sx, P, dPu, dPv);

	uint32_t order[SN];
	shuffle_order(order, SN, 11);
	float hu[SN], hv[SN];
	for (uint32_t j = 0; j < SN; j++) {
		hu[j] = du;
		hv[j] = dv;
	}
	const uint32_t m = SN;
	CHECK(sl_exec_set_grid(sx, 3 * m, 1));
	CHECK(sl_exec_set_stencil(sx, m, hu, hv));
	put_stencil(sx, SL_GLOBAL_P, 3, P, dPu, dPv, order, m, NULL);
	put_stencil(sx, SL_GLOBAL_N, 3, N, NULL, NULL, order, m, NULL);
	memset(&seen, 0, sizeof(seen));
	CHECK(sl_exec_run(sx, &lh.host));
	CHECK(seen.nshadow == 1);
	CHECK(sl_exec_stencil(lx) == m);
	double perr = 0, cerr = 0;
	for (uint32_t j = 0; j < m; j++) {
		uint32_t i = order[j];
		for (int c = 0; c < 3; c++) {
			for (int k = 0; k < 4; k++)
				perr = fmax(perr, fabs(seen.pos[k][c][j] - grid_seen.pos[k][c][i]));
			cerr = fmax(cerr, fabs(ci[(size_t)c * sx->stride + j] - grid_ci[c][i]));
		}
	}
	printf("stencils through the light host: shadow corners within %.3g, Ci within %.3g\n",
	       perr, cerr);
	CHECK(perr <= 2e-5);
	CHECK(cerr <= 1e-5);

	/* back to the grid: the light follows */
	CHECK(sl_exec_set_stencil(sx, 0, NULL, NULL));
	CHECK(sl_exec_set_grid(sx, SNU, SNV));
	put_global(sx, SL_GLOBAL_P, 3, P, NULL, SN, 0);
	put_global(sx, SL_GLOBAL_N, 3, N, NULL, SN, 0);
	CHECK(sl_exec_run(sx, &lh.host));
	CHECK(sl_exec_stencil(lx) == 0);
	for (uint32_t i = 0; i < SN; i++)
		CHECK(ci[i] == grid_ci[0][i]);

	/* a light too small for the stencils' 3m points: left out, with one warning */
	struct sl_lighthost lh2;
	sl_lighthost_init(&lh2, &small, 1);
	lh2.owner = &seen;
	lh2.host.shadow = seen_shadow_lh;
	CHECK(sl_exec_set_grid(sx, 3 * m, 1));
	CHECK(sl_exec_set_stencil(sx, m, hu, hv));
	put_stencil(sx, SL_GLOBAL_P, 3, P, dPu, dPv, order, m, NULL);
	put_stencil(sx, SL_GLOBAL_N, 3, N, NULL, NULL, order, m, NULL);
	struct lit_case lc = { sx, &lh2, 2 };
	char msg[1024];
	bool ok = false;
	capture_stderr(msg, sizeof(msg), run_lit_case, &lc, &ok);
	CHECK(ok);
	const char *w = strstr(msg, "has room for 63 points");
	CHECK(w != NULL);
	CHECK(w && !strstr(w + 1, "has room for"));
	CHECK(strstr(msg, "shl") != NULL);
	CHECK(ci[0] == 0.0f);
out:
	sl_exec_destroy(sx);
	sl_exec_destroy(lx);
	sl_exec_destroy(small);
	sl_program_destroy(sp);
	sl_program_destroy(lp);
}

/* ------------------------------------------------------------------------ */
/* Counting float operations                                                 */

static const char countsurf_src[] =
	"surface t(float a = 1)\n"
	"{\n"
	"	if (s < 0.5)\n"
	"		Ci = color(a * 2 + 1);\n"
	"}\n";

static const char countlight_src[] =
	"light pl(float intensity = 1)\n"
	"{\n"
	"	illuminate(point(0, 0, 5)) {\n"
	"		Cl = intensity * color(1, 1, 1);\n"
	"	}\n"
	"}\n";

static const char countdiff_src[] =
	"surface d()\n"
	"{\n"
	"	Ci = diffuse(N);\n"
	"}\n";

/*
 * Exact counts (exec.h's table) over a 8 x 4 grid: the comparison runs on
 * all 32 points, the multiply and add only on the 16 with s < 0.5, the
 * copies into Ci count nothing. Counting off leaves the total alone; never
 * turned on, it is 0. A surface's diffuse() counts its own lighting
 * arithmetic, and the light's executor its illuminate and body.
 */
static void test_count_ops(void)
{
	enum { NU = 8, NV = 4, N = NU * NV };
	struct sl_program *prog = sl_compile_string("count.sl", countsurf_src,
						    strlen(countsurf_src), NULL);
	CHECK(prog != NULL);
	struct sl_exec *x = prog ? sl_exec_create(prog, N) : NULL;
	CHECK(x != NULL);
	if (!x) {
		sl_program_destroy(prog);
		return;
	}
	CHECK(sl_exec_set_grid(x, NU, NV));
	float sv[N];
	for (uint32_t i = 0; i < N; i++)
		sv[i] = (float)(i % NU) / (NU - 1);   /* 4 of each row's 8 below 0.5 */
	set_global1(x, SL_GLOBAL_S, sv);

	CHECK(sl_exec_run(x, NULL));
	CHECK(sl_exec_ops(x) == 0);              /* never turned on */
	const uint64_t per_run = N + 2 * (N / 2);
	sl_exec_count_ops(x, true);
	CHECK(sl_exec_ops(x) == 0);
	CHECK(sl_exec_run(x, NULL));
	CHECK(sl_exec_ops(x) == per_run);
	if (sl_exec_ops(x) != per_run) {
		printf("counted %llu, expected %llu, in:\n", (unsigned long long)sl_exec_ops(x),
		       (unsigned long long)per_run);
		sl_ir_dump(prog, stdout);
	}
	bool vary;
	const float *ci = sl_exec_global(x, SL_GLOBAL_CI, &vary);
	CHECK(ci && vary && ci[0] == 3.0f && ci[NU - 1] == 0.0f);
	/* a parameter changes values, not the count; runs add up */
	float a = 5.0f;
	CHECK(sl_exec_set_param(x, "a", &a, 1));
	CHECK(sl_exec_run(x, NULL));
	CHECK(sl_exec_ops(x) == 2 * per_run);
	/* off: the total stays, runs add nothing */
	sl_exec_count_ops(x, false);
	CHECK(sl_exec_run(x, NULL));
	CHECK(sl_exec_ops(x) == 2 * per_run);
	/* on again: from 0 */
	sl_exec_count_ops(x, true);
	CHECK(sl_exec_ops(x) == 0);
	/* all points take the branch: 32 compares, 64 for the multiply-add */
	for (uint32_t i = 0; i < N; i++)
		sv[i] = 0.25f;
	set_global1(x, SL_GLOBAL_S, sv);
	CHECK(sl_exec_run(x, NULL));
	CHECK(sl_exec_ops(x) == (uint64_t)N + 2 * N);
	sl_exec_destroy(x);
	sl_program_destroy(prog);

	/* Lights: each executor counts its own work, the caller adds them. */
	struct sl_program *lp = sl_compile_string("pl.sl", countlight_src,
						  strlen(countlight_src), NULL);
	struct sl_program *sp = sl_compile_string("d.sl", countdiff_src,
						  strlen(countdiff_src), NULL);
	CHECK(lp && sp);
	struct sl_exec *sx = sp ? sl_exec_create(sp, N) : NULL;
	struct sl_exec *lx = lp ? sl_exec_create(lp, N) : NULL;
	CHECK(sx && lx);
	if (sx && lx) {
		CHECK(sl_exec_set_grid(sx, NU, NV));
		/* a patch at z = 0 facing the light at z = 5 */
		for (uint32_t i = 0; i < N; i++) {
			set_global3(sx, SL_GLOBAL_P, i, (float)(i % NU) * 0.1f,
				    (float)(i / NU) * 0.1f, 0.0f);
			set_global3(sx, SL_GLOBAL_N, i, 0.0f, 0.0f, 1.0f);
		}
		struct sl_lighthost lh;
		sl_lighthost_init(&lh, &lx, 1);
		sl_exec_count_ops(sx, true);
		sl_exec_count_ops(lx, true);
		CHECK(sl_exec_run(sx, &lh.host));
		/* diffuse: 24 to normalize and test, 6 to add the light's colour */
		CHECK(sl_exec_ops(sx) == 30u * N);
		/* illuminate: L = Ps - P, 3; the body's colour multiply, 3 */
		CHECK(sl_exec_ops(lx) == 6u * N);
		if (sl_exec_ops(lx) != 6u * N) {
			printf("light counted %llu, expected %u, in:\n",
			       (unsigned long long)sl_exec_ops(lx), 6u * N);
			sl_ir_dump(lp, stdout);
		}
		const float *dc = sl_exec_global(sx, SL_GLOBAL_CI, &vary);
		CHECK(dc && dc[0] > 0.9f && dc[0] <= 1.0f);
	}
	sl_exec_destroy(sx);
	sl_exec_destroy(lx);
	sl_program_destroy(sp);
	sl_program_destroy(lp);
}

int main(void)
{
	RUN(test_arith);
	RUN(test_compare_logic);
	RUN(test_triples);
	RUN(test_matrix);
	RUN(test_if_else);
	RUN(test_while);
	RUN(test_break_continue);
	RUN(test_func_return);
	RUN(test_arrays);
	RUN(test_params);
	RUN(test_deriv);
	RUN(test_space_scratch);
	RUN(test_invalid);
	RUN(test_category_match);
	RUN(test_illuminance);
	RUN(test_illuminance_flow);
	RUN(test_light_recursion);
	RUN(test_solar_all);
	RUN(test_loop_guard);
	RUN(test_stencil_deriv);
	RUN(test_stencil_errors);
	RUN(test_stencil_lights);
	RUN(test_count_ops);
	return test_finish();
}

/*
 * The grid interpreter's core: register storage, parameters, the running
 * state mask with its frame stack for structured control flow, arithmetic,
 * the illuminance / illuminate / solar blocks, derivatives and diagnostics.
 * Built-in functions live in exec_builtins.c.
 *
 * Control flow. Every block opener pushes a frame that remembers masks of
 * points waiting to come back on: an IF its entry mask and the points that
 * take the else-part; a LOOP the points that finished (failed LOOPTEST),
 * broke to it and continued to it; a FUNC, ILLUMINATE or SOLAR its entry
 * mask; an ILLUMINANCE its entry mask and the points that broke out of it.
 * Points leaving by BREAK, CONTINUE or RETURN are cleared from every frame
 * they cross, so no closer can switch them back on early. When no point is
 * active the interpreter jumps straight to the innermost frame's next
 * closer, so dead code (uniform code included) never runs.
 */
#include "exec_impl.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Float operations of a cone test (see in_cone()). */
#define CONE_COST 20u
/* Grids bigger than this are refused (register storage grows with them). */
#define MAX_POINTS (1u << 24)
/* One LOOP may go round this often in one run before the run fails. */
#define MAX_LOOP_ITERS 10000000u
#define NONE UINT32_MAX
#define PI 3.14159265358979323846

enum frame_kind { F_IF, F_LOOP, F_FUNC, F_ILLUM, F_BLOCK };

struct frame {
	uint8_t kind;           /* enum frame_kind */
	bool in_else;           /* IF: past its ELSE */
	uint32_t open;          /* the opener's instruction index */
	/*
	 * IF: entry, else-part. LOOP: finished, broken, continued.
	 * FUNC, BLOCK: entry. ILLUM: entry, broken.
	 */
	uint8_t *m[3];
	/* ILLUMINANCE */
	int light, nlights, saved_light;
	const char *cat;        /* category, or NULL for all lights */
	bool cone;              /* axis and angle given */
	float *buf;             /* P (3 planes), axis (3 planes), angle (1 plane) */
};

/* A parameter value set by the host. */
struct pval {
	float *v;               /* floats, uniform layout or planar with stride npts */
	uint32_t count;
	uint32_t npts;          /* 0: one value for all points */
	char *s;                /* string parameters */
};

struct sl_exec_private {
	struct frame *frames;
	uint32_t nframes, maxframes;
	uint8_t *maskpool;
	uint32_t *loopcont;     /* per LOOP instruction: its LOOPCONT, or NONE */
	uint32_t *iters;        /* per LOOP instruction: iterations in this run */
	struct pval *pvals;     /* per parameter */
	float **oldscratch;     /* scratch blocks outgrown during the current instruction */
	size_t noldscratch, capoldscratch;
	float *lbuf[2];         /* sl_exec_light() slots: L, Cl, Ol (3 planes each) */
	uint8_t *llit[2];
	float *regblock;        /* storage of all numeric registers */
	const char **strblock;  /* storage of all string registers */
	uint8_t *held;          /* per register: its value is the host's (sl_exec_hold) */
	uint32_t *cost;         /* per instruction: float operations per active point (exec.h) */
	bool running;
	bool warned_noloc;
};

/* Components per global variable (all are floats or triples). */
const uint8_t sl_exec_global_ncomp[SL_GLOBAL_COUNT] = {
	[SL_GLOBAL_P] = 3, [SL_GLOBAL_N] = 3, [SL_GLOBAL_NG] = 3, [SL_GLOBAL_I] = 3,
	[SL_GLOBAL_E] = 3, [SL_GLOBAL_CS] = 3, [SL_GLOBAL_OS] = 3, [SL_GLOBAL_CI] = 3,
	[SL_GLOBAL_OI] = 3, [SL_GLOBAL_S] = 1, [SL_GLOBAL_T] = 1, [SL_GLOBAL_U] = 1,
	[SL_GLOBAL_V] = 1, [SL_GLOBAL_DU] = 1, [SL_GLOBAL_DV] = 1, [SL_GLOBAL_DPDU] = 3,
	[SL_GLOBAL_DPDV] = 3, [SL_GLOBAL_L] = 3, [SL_GLOBAL_CL] = 3, [SL_GLOBAL_OL] = 3,
	[SL_GLOBAL_PS] = 3, [SL_GLOBAL_NCOMPS] = 1, [SL_GLOBAL_TIME] = 1,
	[SL_GLOBAL_DTIME] = 1, [SL_GLOBAL_DPDTIME] = 3,
	[SL_GLOBAL_ALPHA] = 1, [SL_GLOBAL_NS] = 3,
};

/* ------------------------------------------------------------------------ */
/* Small helpers                                                             */

const char *sl_exec_label(const struct sl_program *prog)
{
	if (prog->source_path)
		return prog->source_path;
	return prog->name ? prog->name : "shader";
}

/* Floats (or string pointers) per point of register @r. */
uint32_t sl_exec_reg_total(const struct sl_reg *r)
{
	uint32_t nc = r->type == SL_TYPE_STRING ? 1 : (uint32_t)sl_reg_ncomp(r);
	return nc * (r->arraylen > 0 ? (uint32_t)r->arraylen : 1);
}

/* Clamp to the finite range: overflow never produces Inf. */
static inline float fin(float r)
{
	return r > FLT_MAX ? FLT_MAX : (r < -FLT_MAX ? -FLT_MAX : r);
}

static inline float fdiv(float p, float q)
{
	return q == 0.0f ? 0.0f : fin(p / q);
}

static uint32_t count_mask(const uint8_t *m, uint32_t n)
{
	uint32_t c = 0;
	for (uint32_t i = 0; i < n; i++)
		c += m[i];
	return c;
}

static void set_mask(struct sl_exec *x, const uint8_t *m)
{
	memcpy(x->mask, m, x->n);
	x->nactive = count_mask(x->mask, x->n);
}

static void recount(struct sl_exec *x)
{
	x->nactive = count_mask(x->mask, x->n);
}

/* The first active point (0 if none). */
static uint32_t first_lane(const struct sl_exec *x)
{
	if (x->nactive == x->n)
		return 0;
	for (uint32_t i = 0; i < x->n; i++)
		if (x->mask[i])
			return i;
	return 0;
}

static inline float ld(const struct sl_exec *x, int32_t r, int c, uint32_t i)
{
	return sl_x_get(x, r, c, i);
}

static inline const char *sget(const struct sl_exec *x, int32_t r, int e, uint32_t i)
{
	const char **d = x->sdata[r];
	const char *s = x->prog->regs[r].varying ? d[(size_t)e * x->stride + i] : d[e];
	return s ? s : "";
}

static inline void sset(struct sl_exec *x, int32_t r, int e, uint32_t i, const char *s)
{
	const char **d = x->sdata[r];
	if (x->prog->regs[r].varying)
		d[(size_t)e * x->stride + i] = s;
	else
		d[e] = s;
}

/*
 * The points an instruction writing @dst works on: the active ones when @dst
 * is varying, else the first active one (whose values any varying operand
 * supplies).
 */
#define EACH_LANE(x, dst, i) \
	for (uint32_t u_ = !sl_x_varying((x), (dst)), i = u_ ? first_lane(x) : 0, \
		      e_ = u_ ? i + 1 : (x)->n; i < e_; i++) \
		if (u_ || (x)->mask[i])

static void identity(float m[16])
{
	for (int i = 0; i < 16; i++)
		m[i] = (i % 5 == 0) ? 1.0f : 0.0f;
}

static bool is_identity(const float m[16])
{
	for (int i = 0; i < 16; i++)
		if (m[i] != ((i % 5 == 0) ? 1.0f : 0.0f))
			return false;
	return true;
}

/* Inverse of a 4x4 matrix by Gauss-Jordan elimination; false when singular. */
static bool invert4(const float m[16], float out[16])
{
	double a[4][8];
	double big = 0;
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++) {
			a[r][c] = m[r * 4 + c];
			a[r][c + 4] = r == c;
			if (fabs(a[r][c]) > big)
				big = fabs(a[r][c]);
		}
	if (!(big > 0) || !isfinite(big))
		return false;
	for (int c = 0; c < 4; c++) {
		int piv = c;
		for (int r = c + 1; r < 4; r++)
			if (fabs(a[r][c]) > fabs(a[piv][c]))
				piv = r;
		if (fabs(a[piv][c]) <= big * 1e-10)
			return false;
		if (piv != c)
			for (int k = 0; k < 8; k++) {
				double t = a[c][k];
				a[c][k] = a[piv][k];
				a[piv][k] = t;
			}
		double inv = 1.0 / a[c][c];
		for (int k = 0; k < 8; k++)
			a[c][k] *= inv;
		for (int r = 0; r < 4; r++) {
			if (r == c || a[r][c] == 0)
				continue;
			double f = a[r][c];
			for (int k = 0; k < 8; k++)
				a[r][k] -= f * a[c][k];
		}
	}
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++) {
			double v = a[r][c + 4];
			if (!isfinite(v) || fabs(v) > FLT_MAX)
				return false;
			out[r * 4 + c] = (float)v;
		}
	return true;
}

static void matmul4(const float a[16], const float b[16], float out[16])
{
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++) {
			float s = 0;
			for (int k = 0; k < 4; k++)
				s += a[r * 4 + k] * b[k * 4 + c];
			out[r * 4 + c] = fin(s);
		}
}

/* ------------------------------------------------------------------------ */
/* Diagnostics, scratch, strings                                             */

/*
 * "FILE:LINE:COL: WHAT: MESSAGE" on stderr in one write of the whole line:
 * executors of other threads report at the same time. A warning already
 * printed (by any executor) is counted, not printed again.
 */
static void report(struct sl_exec *x, const struct sl_insn *in, const char *what,
		   const char *fmt, va_list ap)
{
	const struct sl_program *prog = x->prog;
	char line[1024];
	int n;
	if (in) {
		const char *file = sl_exec_label(prog);
		if (prog->files && in->loc.file < prog->nfiles && prog->files[in->loc.file])
			file = prog->files[in->loc.file];
		n = snprintf(line, sizeof(line), "%s:%u:%u: %s: ", file, in->loc.line, in->loc.col,
			     what);
	} else {
		n = snprintf(line, sizeof(line), "%s: %s: ", sl_exec_label(prog), what);
	}
	if (n < 0)
		return;
	size_t len = (size_t)n < sizeof(line) - 1 ? (size_t)n : sizeof(line) - 1;
	n = vsnprintf(line + len, sizeof(line) - len, fmt, ap);
	len = n < 0 ? len : len + (size_t)n < sizeof(line) - 1 ? len + (size_t)n : sizeof(line) - 1;
	if (!strcmp(what, "warning") && sl_exec_warning_seen(line))
		return;
	line[len] = '\n';
	flockfile(stderr);
	fwrite(line, 1, len + 1, stderr);
	funlockfile(stderr);
}

/* Index of @in in the program's code, or NONE when it is not one of them. */
static uint32_t insn_index(const struct sl_exec *x, const struct sl_insn *in)
{
	uintptr_t p = (uintptr_t)in, b = (uintptr_t)x->prog->code;
	if (!in || p < b || (p - b) / sizeof(*in) >= x->prog->ncode)
		return NONE;
	return (uint32_t)((p - b) / sizeof(*in));
}

void sl_exec_warn_once(struct sl_exec *x, const struct sl_insn *in, const char *fmt, ...)
{
	uint32_t k = insn_index(x, in);
	if (k != NONE) {
		if (x->warned[k])
			return;
		x->warned[k] = 1;
	} else {
		if (x->priv->warned_noloc)
			return;
		x->priv->warned_noloc = true;
	}
	va_list ap;
	va_start(ap, fmt);
	report(x, in, "warning", fmt, ap);
	va_end(ap);
}

void sl_exec_fail(struct sl_exec *x, const struct sl_insn *in, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	report(x, in, "error", fmt, ap);
	va_end(ap);
	x->failed = true;
}

float *sl_exec_scratch(struct sl_exec *x, size_t n)
{
	struct sl_exec_private *p = x->priv;
	/* Keep every piece 64-byte aligned relative to the block. */
	size_t need = (n + 15) & ~(size_t)15;
	if (need == 0)
		need = 16;
	if (need > x->scratch_cap - x->scratch_used) {
		/* Pointers handed out earlier stay valid: the old block is kept. */
		if (x->scratch) {
			if (p->noldscratch == p->capoldscratch) {
				p->capoldscratch = p->capoldscratch ? 2 * p->capoldscratch : 8;
				p->oldscratch = rl_xrealloc(p->oldscratch,
							    p->capoldscratch * sizeof(float *));
			}
			p->oldscratch[p->noldscratch++] = x->scratch;
		}
		size_t cap = x->scratch_cap * 2;
		if (cap < need)
			cap = need;
		x->scratch = rl_xmalloc(cap * sizeof(float));
		x->scratch_cap = cap;
		x->scratch_used = 0;
	}
	float *r = x->scratch + x->scratch_used;
	x->scratch_used += need;
	return r;
}

/* Start of an instruction: all scratch is free again. */
static inline void scratch_reset(struct sl_exec *x)
{
	struct sl_exec_private *p = x->priv;
	x->scratch_used = 0;
	if (p->noldscratch) {
		for (size_t i = 0; i < p->noldscratch; i++)
			free(p->oldscratch[i]);
		p->noldscratch = 0;
	}
}

const char *sl_exec_strdup(struct sl_exec *x, const char *s)
{
	return rl_arena_strdup(x->strings, s ? s : "");
}

/* ------------------------------------------------------------------------ */
/* Creation                                                                  */

/*
 * Float operations per active point of instruction @in (the table in
 * exec.h), apart from what illuminance, illuminate and the lighting
 * built-ins count while they run.
 */
static uint32_t insn_cost(const struct sl_program *prog, const struct sl_insn *in)
{
	int32_t d = in->dst;
	switch ((enum sl_op)in->op) {
	case SL_OP_NEG: case SL_OP_ADD: case SL_OP_SUB:
		return (uint32_t)ncomp_of(prog, d);
	case SL_OP_MUL: case SL_OP_DIV:
		if (ncomp_of(prog, in->args[0]) == 16 && ncomp_of(prog, in->args[1]) == 16)
			return in->op == SL_OP_MUL ? 112 : 256;
		return (uint32_t)ncomp_of(prog, d);
	case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE:
		return 1;
	case SL_OP_EQ: case SL_OP_NE: {
		if (is_str(prog, in->args[0]))
			return 0;
		int na = ncomp_of(prog, in->args[0]), nb = ncomp_of(prog, in->args[1]);
		return (uint32_t)(na > nb ? na : nb);
	}
	case SL_OP_DOT:
		return 5;
	case SL_OP_CROSS:
		return 9;
	case SL_OP_CALL:
		return sl_exec_builtin_cost(prog, in);
	default:
		return 0;
	}
}

struct sl_exec *sl_exec_create(const struct sl_program *prog, uint32_t maxpoints)
{
	if (!prog || maxpoints == 0 || maxpoints > MAX_POINTS)
		return NULL;
	uint32_t *loopcont = rl_xmalloc(((size_t)prog->ncode + 1) * sizeof(uint32_t));
	for (uint32_t i = 0; i <= prog->ncode; i++)
		loopcont[i] = NONE;
	uint32_t maxdepth = 0;
	if (!sl_exec_check_program(prog, loopcont, &maxdepth)) {
		free(loopcont);
		return NULL;
	}

	struct sl_exec *x = rl_xcalloc(1, sizeof(*x));
	struct sl_exec_private *p = rl_xcalloc(1, sizeof(*p));
	x->priv = p;
	p->loopcont = loopcont;
	x->prog = prog;
	x->maxn = maxpoints;
	x->stride = maxpoints;
	x->nu = maxpoints;
	x->nv = 1;
	x->n = maxpoints;
	x->cur_light = -1;

	/* Register storage: one block of floats, one of string pointers. */
	size_t nfloats = 0, nstrs = 0;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *g = &prog->regs[r];
		size_t per = g->varying ? maxpoints : 1;
		if (g->type == SL_TYPE_STRING)
			nstrs += sl_exec_reg_total(g) * per;
		else
			nfloats += (sl_exec_reg_total(g) * per + 15) & ~(size_t)15;
	}
	if (nfloats > SIZE_MAX / sizeof(float) / 2 || nstrs > SIZE_MAX / sizeof(char *) / 2)
		goto fail;
	p->regblock = calloc(nfloats ? nfloats : 1, sizeof(float));
	p->strblock = calloc(nstrs ? nstrs : 1, sizeof(char *));
	if (!p->regblock || !p->strblock)
		goto fail;
	x->data = rl_xcalloc(prog->nregs + 1, sizeof(float *));
	x->sdata = rl_xcalloc(prog->nregs + 1, sizeof(const char **));
	size_t fo = 0, so = 0;
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *g = &prog->regs[r];
		size_t per = g->varying ? maxpoints : 1;
		size_t tot = sl_exec_reg_total(g);
		if (g->type == SL_TYPE_STRING) {
			const char **d = p->strblock + so;
			x->sdata[r] = d;
			so += tot * per;
			for (size_t e = 0; e < tot; e++) {
				const char *s = "";
				if (g->kind == SL_REG_CONST && prog->strings[g->cindex + e])
					s = prog->strings[g->cindex + e];
				for (size_t i = 0; i < per; i++)
					d[e * per + i] = s;
			}
		} else {
			float *d = p->regblock + fo;
			x->data[r] = d;
			fo += (tot * per + 15) & ~(size_t)15;
			if (g->kind == SL_REG_CONST)
				for (size_t c = 0; c < tot; c++)
					for (size_t i = 0; i < per; i++)
						d[c * per + i] = prog->consts[g->cindex + c];
		}
	}

	x->mask = rl_xcalloc(maxpoints, 1);
	x->lit = rl_xcalloc(maxpoints, 1);
	x->param_set = rl_xcalloc(prog->nparams + 1, sizeof(bool));
	x->warned = rl_xcalloc(prog->ncode + 1, 1);
	x->strings = rl_arena_create();
	p->pvals = rl_xcalloc(prog->nparams + 1, sizeof(struct pval));
	p->held = rl_xcalloc(prog->nregs + 1, 1);
	p->iters = rl_xcalloc(prog->ncode + 1, sizeof(uint32_t));
	p->cost = rl_xcalloc(prog->ncode + 1, sizeof(uint32_t));
	for (uint32_t i = 0; i < prog->ncode; i++)
		p->cost[i] = insn_cost(prog, &prog->code[i]);

	p->maxframes = maxdepth;
	p->frames = rl_xcalloc(maxdepth + 1, sizeof(struct frame));
	if ((size_t)maxdepth * 3 > SIZE_MAX / maxpoints)
		goto fail;
	p->maskpool = calloc((size_t)maxdepth * 3 * maxpoints + 1, 1);
	if (!p->maskpool)
		goto fail;
	for (uint32_t k = 0; k < maxdepth; k++)
		for (int j = 0; j < 3; j++)
			p->frames[k].m[j] = p->maskpool + ((size_t)k * 3 + j) * maxpoints;

	x->scratch_cap = (size_t)64 * maxpoints;
	x->scratch = rl_xmalloc(x->scratch_cap * sizeof(float));
	return x;

fail:
	fprintf(stderr, "%s: error: not enough memory for a grid of %u points\n",
		sl_exec_label(prog), maxpoints);
	sl_exec_destroy(x);
	return NULL;
}

void sl_exec_destroy(struct sl_exec *x)
{
	if (!x)
		return;
	struct sl_exec_private *p = x->priv;
	if (p) {
		for (uint32_t k = 0; k < x->prog->nparams; k++) {
			free(p->pvals ? p->pvals[k].v : NULL);
			free(p->pvals ? p->pvals[k].s : NULL);
		}
		free(p->pvals);
		if (p->frames)
			for (uint32_t k = 0; k < p->maxframes; k++)
				free(p->frames[k].buf);
		free(p->frames);
		free(p->maskpool);
		free(p->loopcont);
		free(p->iters);
		free(p->cost);
		for (size_t i = 0; i < p->noldscratch; i++)
			free(p->oldscratch[i]);
		free(p->oldscratch);
		for (int s = 0; s < 2; s++) {
			free(p->lbuf[s]);
			free(p->llit[s]);
		}
		free(p->regblock);
		free(p->strblock);
		free(p->held);
		free(p);
	}
	free(x->data);
	free(x->sdata);
	free(x->mask);
	free(x->lit);
	free(x->param_set);
	free(x->warned);
	free(x->scratch);
	free(x->stencil_du);
	free(x->stencil_dv);
	rl_arena_destroy(x->strings);
	free(x);
}

const struct sl_program *sl_exec_program(const struct sl_exec *x)
{
	return x->prog;
}

uint32_t sl_exec_stride(const struct sl_exec *x)
{
	return x->stride;
}

bool sl_exec_set_grid(struct sl_exec *x, uint32_t nu, uint32_t nv)
{
	if (!x || nu == 0 || nv == 0 || (uint64_t)nu * nv > x->maxn)
		return false;
	x->nu = nu;
	x->nv = nv;
	x->n = nu * nv;
	return true;
}

bool sl_exec_set_stencil(struct sl_exec *x, uint32_t m, const float *du, const float *dv)
{
	if (!x)
		return false;
	if (m == 0) {
		x->stencil_m = 0;
		return true;
	}
	if (m > x->maxn / 3 || !du || !dv) {
		fprintf(stderr, "%s: error: derivative stencils of %u samples need %llu points, "
			"the executor has %u\n", sl_exec_label(x->prog), m, 3ull * m, x->maxn);
		return false;
	}
	for (uint32_t i = 0; i < m; i++)
		if (!isfinite(du[i]) || !isfinite(dv[i])) {
			fprintf(stderr, "%s: error: derivative stencil %u: the step along %s is "
				"not finite\n", sl_exec_label(x->prog), i, isfinite(du[i]) ? "v" : "u");
			return false;
		}
	if (!x->stencil_du) {
		size_t cap = x->maxn / 3;
		x->stencil_du = rl_xmalloc(cap * sizeof(float));
		x->stencil_dv = rl_xmalloc(cap * sizeof(float));
	}
	/* The caller may hand back this executor's own steps. */
	memmove(x->stencil_du, du, m * sizeof(float));
	memmove(x->stencil_dv, dv, m * sizeof(float));
	x->stencil_m = m;
	return true;
}

uint32_t sl_exec_stencil(const struct sl_exec *x)
{
	return x ? x->stencil_m : 0;
}

float *sl_exec_global(struct sl_exec *x, enum sl_global g, bool *varying)
{
	if (!x || (int)g < 0 || g >= SL_GLOBAL_COUNT || x->prog->global_reg[g] < 0)
		return NULL;
	int32_t r = x->prog->global_reg[g];
	if (varying)
		*varying = x->prog->regs[r].varying;
	return x->data[r];
}

float *sl_exec_reg(struct sl_exec *x, int32_t reg)
{
	if (!x || !reg_ok(x->prog, reg))
		return NULL;
	return x->data[reg];
}

const char **sl_exec_reg_strings(struct sl_exec *x, int32_t reg)
{
	if (!x || !reg_ok(x->prog, reg))
		return NULL;
	return x->sdata[reg];
}

void sl_exec_set_peer(struct sl_exec *x, enum sl_peer which, struct sl_exec *peer)
{
	if (x && (int)which >= 0 && which < SL_PEER_COUNT)
		x->peer[which] = peer;
}

const uint8_t *sl_exec_lit_mask(const struct sl_exec *x)
{
	return x->lit;
}

bool sl_exec_is_ambient(const struct sl_exec *x)
{
	return !x->ran_illuminate;
}

bool sl_exec_hold(struct sl_exec *x, int32_t reg, bool hold)
{
	if (!x || !reg_ok(x->prog, reg) || x->prog->regs[reg].kind == SL_REG_CONST)
		return false;
	x->priv->held[reg] = hold;
	return true;
}

/* ------------------------------------------------------------------------ */
/* Parameters                                                                */

static int find_param(const struct sl_program *prog, const char *name)
{
	for (uint32_t k = 0; k < prog->nparams; k++)
		if (!strcmp(prog->params[k].name, name))
			return (int)k;
	return -1;
}

bool sl_exec_set_param(struct sl_exec *x, const char *name, const float *values,
		       uint32_t nvalues)
{
	if (!x || !name || (!values && nvalues))
		return false;
	const struct sl_program *prog = x->prog;
	int k = find_param(prog, name);
	if (k < 0) {
		fprintf(stderr, "%s: error: no parameter named '%s'\n", sl_exec_label(prog), name);
		return false;
	}
	const struct sl_reg *g = &prog->regs[prog->params[k].reg];
	if (g->type == SL_TYPE_STRING) {
		fprintf(stderr, "%s: error: parameter '%s' is a string\n", sl_exec_label(prog), name);
		return false;
	}
	uint32_t base = sl_exec_reg_total(g), npts = 0;
	if (nvalues != base) {
		if (!g->varying || x->n < 1 || nvalues / x->n != base || nvalues % x->n) {
			fprintf(stderr,
				"%s: error: parameter '%s' takes %u values%s, not %u\n",
				sl_exec_label(prog), name, base,
				g->varying ? " (or that many per point)" : "", nvalues);
			return false;
		}
		npts = x->n;
	}
	struct pval *v = &x->priv->pvals[k];
	free(v->v);
	v->v = rl_xmalloc((size_t)nvalues * sizeof(float) + 1);
	memcpy(v->v, values, (size_t)nvalues * sizeof(float));
	v->count = nvalues;
	v->npts = npts;
	x->param_set[k] = true;
	return true;
}

bool sl_exec_set_param_string(struct sl_exec *x, const char *name, const char *value)
{
	if (!x || !name || !value)
		return false;
	const struct sl_program *prog = x->prog;
	int k = find_param(prog, name);
	if (k < 0) {
		fprintf(stderr, "%s: error: no parameter named '%s'\n", sl_exec_label(prog), name);
		return false;
	}
	int32_t r = prog->params[k].reg;
	const struct sl_reg *g = &prog->regs[r];
	if (g->type != SL_TYPE_STRING || g->arraylen) {
		fprintf(stderr, "%s: error: parameter '%s' is not a string\n", sl_exec_label(prog),
			name);
		return false;
	}
	struct pval *v = &x->priv->pvals[k];
	free(v->s);
	v->s = rl_xstrdup(value);
	x->param_set[k] = true;
	/* Visible at once (light categories are read before the first run). */
	const char **d = x->sdata[r];
	for (uint32_t i = 0, e = g->varying ? x->stride : 1; i < e; i++)
		d[i] = v->s;
	return true;
}

void sl_exec_reset_params(struct sl_exec *x)
{
	if (!x)
		return;
	for (uint32_t k = 0; k < x->prog->nparams; k++) {
		struct pval *v = &x->priv->pvals[k];
		free(v->v);
		free(v->s);
		memset(v, 0, sizeof(*v));
		x->param_set[k] = false;
	}
}

/* The matrices taking "shader" space values to "current" space. */
struct xform {
	bool id;
	float m[16];
	float ninv[9];     /* inverse of the 3x3 part (normals use its transpose) */
	bool nok;
};

static void xform_init(struct sl_exec *x, struct xform *t)
{
	const struct sl_host *h = x->host;
	identity(t->m);
	if (!h || !h->space || !h->space(h->user, "shader", t->m))
		identity(t->m);
	t->id = is_identity(t->m);
	const float *m = t->m;
	double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], hh = m[9],
	       i = m[10];
	double det = a * (e * i - f * hh) - b * (d * i - f * g) + c * (d * hh - e * g);
	t->nok = fabs(det) > 1e-20;
	if (t->nok) {
		double inv[9] = {
			(e * i - f * hh), -(b * i - c * hh), (b * f - c * e),
			-(d * i - f * g), (a * i - c * g), -(a * f - c * d),
			(d * hh - e * g), -(a * hh - b * g), (a * e - b * d),
		};
		for (int k = 0; k < 9; k++)
			t->ninv[k] = (float)(inv[k] / det);
	}
}

static void xform_triple(const struct xform *t, int type, float v[3])
{
	const float *m = t->m;
	float r[3];
	for (int j = 0; j < 3; j++) {
		if (type == SL_TYPE_NORMAL) {
			/* n' = n (A^-1)^T */
			r[j] = t->nok ? v[0] * t->ninv[j * 3 + 0] + v[1] * t->ninv[j * 3 + 1] +
						v[2] * t->ninv[j * 3 + 2]
				      : v[j];
		} else {
			r[j] = v[0] * m[j] + v[1] * m[4 + j] + v[2] * m[8 + j];
			if (type == SL_TYPE_POINT)
				r[j] += m[12 + j];
		}
	}
	for (int j = 0; j < 3; j++)
		v[j] = fin(r[j]);
}

/* Put the host's value of parameter @k into its register. */
static void load_param(struct sl_exec *x, uint32_t k, struct xform *t, bool *have_t)
{
	const struct sl_program *prog = x->prog;
	int32_t r = prog->params[k].reg;
	const struct sl_reg *g = &prog->regs[r];
	const struct pval *v = &x->priv->pvals[k];
	uint32_t per = g->varying ? x->n : 1;
	if (g->type == SL_TYPE_STRING) {
		for (uint32_t e = 0; e < sl_exec_reg_total(g); e++)
			for (uint32_t i = 0; i < per; i++)
				sset(x, r, (int)e, i, v->s ? v->s : "");
		return;
	}
	float *d = x->data[r];
	uint32_t tot = sl_exec_reg_total(g);
	if (v->npts && v->npts != x->n) {
		sl_exec_fail(x, NULL, "parameter '%s' was set for %u points but the grid has %u",
			     prog->params[k].name, v->npts, x->n);
		return;
	}
	for (uint32_t c = 0; c < tot; c++) {
		if (!g->varying)
			d[c] = v->v[c];
		else if (v->npts)
			memcpy(d + (size_t)c * x->stride, v->v + (size_t)c * v->npts,
			       (size_t)x->n * sizeof(float));
		else
			for (uint32_t i = 0; i < x->n; i++)
				d[(size_t)c * x->stride + i] = v->v[c];
	}
	if (g->type != SL_TYPE_POINT && g->type != SL_TYPE_VECTOR && g->type != SL_TYPE_NORMAL)
		return;
	if (!*have_t) {
		xform_init(x, t);
		*have_t = true;
	}
	if (t->id)
		return;
	size_t s = g->varying ? x->stride : 1;
	uint32_t nel = g->arraylen > 0 ? (uint32_t)g->arraylen : 1;
	for (uint32_t e = 0; e < nel; e++)
		for (uint32_t i = 0; i < per; i++) {
			float *base = d + (size_t)e * 3 * s + i;
			float p3[3] = { base[0], base[s], base[2 * s] };
			xform_triple(t, g->type, p3);
			base[0] = p3[0];
			base[s] = p3[1];
			base[2 * s] = p3[2];
		}
}

/* ------------------------------------------------------------------------ */
/* Arithmetic                                                                */

enum kop {
	K_MOV, K_NEG, K_NOT,
	K_ADD, K_SUB, K_MUL, K_DIV, K_LT, K_LE, K_GT, K_GE, K_EQ, K_NE, K_AND, K_OR,
};

/* d[i] = E(p) with p = a[i] (or a[0] when !va) over n points, under mask m. */
#define KLOOP1(E) \
	do { \
		if (!m) { \
			if (va) { \
				for (uint32_t i = 0; i < n; i++) { \
					const float p = a[i]; \
					d[i] = (E); \
				} \
			} else { \
				const float p = a[0], r_ = (E); \
				for (uint32_t i = 0; i < n; i++) \
					d[i] = r_; \
			} \
		} else { \
			if (va) { \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) { \
						const float p = a[i]; \
						d[i] = (E); \
					} \
			} else { \
				const float p = a[0], r_ = (E); \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) \
						d[i] = r_; \
			} \
		} \
	} while (0)

/* d[i] = E(p, q) with p from a, q from b. */
#define KLOOP2(E) \
	do { \
		if (!m) { \
			if (va && vb) { \
				for (uint32_t i = 0; i < n; i++) { \
					const float p = a[i], q = b[i]; \
					d[i] = (E); \
				} \
			} else if (va) { \
				const float q = b[0]; \
				for (uint32_t i = 0; i < n; i++) { \
					const float p = a[i]; \
					d[i] = (E); \
				} \
			} else if (vb) { \
				const float p = a[0]; \
				for (uint32_t i = 0; i < n; i++) { \
					const float q = b[i]; \
					d[i] = (E); \
				} \
			} else { \
				const float p = a[0], q = b[0], r_ = (E); \
				for (uint32_t i = 0; i < n; i++) \
					d[i] = r_; \
			} \
		} else { \
			if (va && vb) { \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) { \
						const float p = a[i], q = b[i]; \
						d[i] = (E); \
					} \
			} else if (va) { \
				const float q = b[0]; \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) { \
						const float p = a[i]; \
						d[i] = (E); \
					} \
			} else if (vb) { \
				const float p = a[0]; \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) { \
						const float q = b[i]; \
						d[i] = (E); \
					} \
			} else { \
				const float p = a[0], q = b[0], r_ = (E); \
				for (uint32_t i = 0; i < n; i++) \
					if (m[i]) \
						d[i] = r_; \
			} \
		} \
	} while (0)

/*
 * One plane of an elementwise op: d = op(a, b) for n points under mask m
 * (NULL: all). va/vb: the operand is a plane (else a single value).
 * d may be a or b.
 */
static void kernel(int op, float *d, const float *a, bool va, const float *b, bool vb,
		   const uint8_t *m, uint32_t n)
{
	switch (op) {
	case K_MOV: KLOOP1(p); break;
	case K_NEG: KLOOP1(-p); break;
	case K_NOT: KLOOP1(p == 0.0f ? 1.0f : 0.0f); break;
	case K_ADD: KLOOP2(fin(p + q)); break;
	case K_SUB: KLOOP2(fin(p - q)); break;
	case K_MUL: KLOOP2(fin(p * q)); break;
	case K_DIV: KLOOP2(fdiv(p, q)); break;
	case K_LT: KLOOP2(p < q ? 1.0f : 0.0f); break;
	case K_LE: KLOOP2(p <= q ? 1.0f : 0.0f); break;
	case K_GT: KLOOP2(p > q ? 1.0f : 0.0f); break;
	case K_GE: KLOOP2(p >= q ? 1.0f : 0.0f); break;
	case K_EQ: KLOOP2(p == q ? 1.0f : 0.0f); break;
	case K_NE: KLOOP2(p != q ? 1.0f : 0.0f); break;
	case K_AND: KLOOP2((p != 0.0f && q != 0.0f) ? 1.0f : 0.0f); break;
	case K_OR: KLOOP2((p != 0.0f || q != 0.0f) ? 1.0f : 0.0f); break;
	default: break;
	}
}

/* Component @c's values of register @r: a plane (varying) or one float. */
static inline float *plane(const struct sl_exec *x, int32_t r, int c)
{
	return x->data[r] + (x->prog->regs[r].varying ? (size_t)c * x->stride : (size_t)c);
}

/*
 * Component @cd of @dst = op(component @ca of @a, component @cb of @b) over
 * the active points, broadcasting uniform operands. For unary ops b = a.
 */
static void apply(struct sl_exec *x, int op, int32_t dst, int cd, int32_t a, int ca, int32_t b,
		  int cb)
{
	const float *pa = plane(x, a, ca), *pb = plane(x, b, cb);
	bool va = sl_x_varying(x, a), vb = sl_x_varying(x, b);
	float *pd = plane(x, dst, cd);
	if (!sl_x_varying(x, dst)) {
		if (va || vb) {
			uint32_t l = first_lane(x);
			pa += va ? l : 0;
			pb += vb ? l : 0;
		}
		kernel(op, pd, pa, false, pb, false, NULL, 1);
		return;
	}
	kernel(op, pd, pa, va, pb, vb, x->nactive == x->n ? NULL : x->mask, x->n);
}

static const int8_t kop_of[SL_OP_COUNT] = {
	[SL_OP_MOV] = K_MOV, [SL_OP_NEG] = K_NEG, [SL_OP_NOT] = K_NOT,
	[SL_OP_ADD] = K_ADD, [SL_OP_SUB] = K_SUB, [SL_OP_MUL] = K_MUL, [SL_OP_DIV] = K_DIV,
	[SL_OP_LT] = K_LT, [SL_OP_LE] = K_LE, [SL_OP_GT] = K_GT, [SL_OP_GE] = K_GE,
	[SL_OP_EQ] = K_EQ, [SL_OP_NE] = K_NE, [SL_OP_AND] = K_AND, [SL_OP_OR] = K_OR,
};

static void op_mov(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0];
	const struct sl_reg *rd = &prog->regs[d];
	if (rd->type == SL_TYPE_STRING) {
		uint32_t tot = sl_exec_reg_total(rd);
		if (a == d)
			return;
		EACH_LANE(x, d, i)
			for (uint32_t e = 0; e < tot; e++)
				sset(x, d, (int)e, i, sget(x, a, (int)e, i));
		return;
	}
	if (a == d)
		return;
	uint32_t tot = sl_exec_reg_total(rd), ta = sl_exec_reg_total(&prog->regs[a]);
	if (ta == tot) {
		for (uint32_t c = 0; c < tot; c++)
			apply(x, K_MOV, d, (int)c, a, (int)c, a, (int)c);
	} else if (rd->type == SL_TYPE_MATRIX) {
		/* A float becomes that multiple of the identity. */
		static const float zero = 0.0f;
		bool dv = sl_x_varying(x, d);
		const uint8_t *m = dv && x->nactive != x->n ? x->mask : NULL;
		for (int c = 0; c < 16; c++) {
			if (c % 5 == 0)
				apply(x, K_MOV, d, c, a, 0, a, 0);
			else
				kernel(K_MOV, plane(x, d, c), &zero, false, &zero, false, m,
				       dv ? x->n : 1);
		}
	} else {
		for (uint32_t c = 0; c < tot; c++)
			apply(x, K_MOV, d, (int)c, a, 0, a, 0);
	}
}

static void op_matrix_muldiv(struct sl_exec *x, const struct sl_insn *in, bool div)
{
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	float A[16], B[16], R[16], binv[16];
	bool singular = false, binv_ok = false;
	if (div && !sl_x_varying(x, b)) {
		for (int c = 0; c < 16; c++)
			B[c] = x->data[b][c];
		binv_ok = invert4(B, binv);
		if (!binv_ok) {
			memset(binv, 0, sizeof(binv));
			singular = true;
		}
	}
	EACH_LANE(x, d, i) {
		for (int c = 0; c < 16; c++) {
			A[c] = ld(x, a, c, i);
			B[c] = ld(x, b, c, i);
		}
		if (div) {
			if (sl_x_varying(x, b)) {
				if (!invert4(B, binv)) {
					memset(binv, 0, sizeof(binv));
					singular = true;
				}
			}
			matmul4(A, binv, R);
		} else {
			matmul4(A, B, R);
		}
		for (int c = 0; c < 16; c++)
			sl_x_set(x, d, c, i, R[c]);
	}
	if (singular)
		sl_exec_warn_once(x, in, "division by a singular matrix (result is zero)");
}

static void op_arith(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0];
	int32_t b = in->nargs > 1 ? in->args[1] : a;
	int nd = ncomp_of(prog, d), na = ncomp_of(prog, a), nb = ncomp_of(prog, b);
	if ((in->op == SL_OP_MUL || in->op == SL_OP_DIV) && na == 16 && nb == 16) {
		op_matrix_muldiv(x, in, in->op == SL_OP_DIV);
		return;
	}
	int op = kop_of[in->op];
	for (int c = 0; c < nd; c++)
		apply(x, op, d, c, a, na == 1 ? 0 : c, b, nb == 1 ? 0 : c);
}

static void op_dot(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	int na = ncomp_of(prog, a), nb = ncomp_of(prog, b);
	if (na == 3 && nb == 3 && sl_x_varying(x, d) && sl_x_varying(x, a) &&
	    sl_x_varying(x, b) && x->nactive == x->n) {
		size_t s = x->stride;
		const float *pa = x->data[a], *pb = x->data[b];
		float *pd = x->data[d];
		for (uint32_t i = 0; i < x->n; i++)
			pd[i] = fin(pa[i] * pb[i] + pa[s + i] * pb[s + i] +
				    pa[2 * s + i] * pb[2 * s + i]);
		return;
	}
	EACH_LANE(x, d, i) {
		float s = 0;
		for (int c = 0; c < 3; c++)
			s += ld(x, a, na == 1 ? 0 : c, i) * ld(x, b, nb == 1 ? 0 : c, i);
		sl_x_set(x, d, 0, i, fin(s));
	}
}

static void op_cross(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	int na = ncomp_of(prog, a), nb = ncomp_of(prog, b);
	EACH_LANE(x, d, i) {
		float u[3], v[3];
		for (int c = 0; c < 3; c++) {
			u[c] = ld(x, a, na == 1 ? 0 : c, i);
			v[c] = ld(x, b, nb == 1 ? 0 : c, i);
		}
		sl_x_set(x, d, 0, i, fin(u[1] * v[2] - u[2] * v[1]));
		sl_x_set(x, d, 1, i, fin(u[2] * v[0] - u[0] * v[2]));
		sl_x_set(x, d, 2, i, fin(u[0] * v[1] - u[1] * v[0]));
	}
}

static void op_eq(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	bool want = in->op == SL_OP_EQ;
	if (is_str(prog, a)) {
		EACH_LANE(x, d, i) {
			bool eq = !strcmp(sget(x, a, 0, i), sget(x, b, 0, i));
			sl_x_set(x, d, 0, i, eq == want ? 1.0f : 0.0f);
		}
		return;
	}
	int na = ncomp_of(prog, a), nb = ncomp_of(prog, b);
	if (na == 1 && nb == 1) {
		apply(x, kop_of[in->op], d, 0, a, 0, b, 0);
		return;
	}
	int nc = na > nb ? na : nb;
	EACH_LANE(x, d, i) {
		bool eq = true;
		for (int c = 0; c < nc && eq; c++)
			eq = ld(x, a, na == 1 ? 0 : c, i) == ld(x, b, nb == 1 ? 0 : c, i);
		sl_x_set(x, d, 0, i, eq == want ? 1.0f : 0.0f);
	}
}

/* A float index into an array of @len: truncated toward zero, clamped (setting *bad). */
static int32_t array_index(float f, int32_t len, bool *bad)
{
	if (f > -1.0f && f < (float)len)
		return (int32_t)f;
	*bad = true;
	return f >= (float)len ? len - 1 : 0;
}

static void op_aref(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	int32_t len = prog->regs[a].arraylen;
	bool str = is_str(prog, a), bad = false;
	int nc = str ? 1 : ncomp_of(prog, a);
	if (!sl_x_varying(x, b)) {
		int32_t k = array_index(x->data[b][0], len, &bad);
		if (str) {
			EACH_LANE(x, d, i)
				sset(x, d, 0, i, sget(x, a, k, i));
		} else {
			for (int c = 0; c < nc; c++)
				apply(x, K_MOV, d, c, a, k * nc + c, a, k * nc + c);
		}
	} else {
		EACH_LANE(x, d, i) {
			int32_t k = array_index(ld(x, b, 0, i), len, &bad);
			if (str)
				sset(x, d, 0, i, sget(x, a, k, i));
			else
				for (int c = 0; c < nc; c++)
					sl_x_set(x, d, c, i, ld(x, a, k * nc + c, i));
		}
	}
	if (bad)
		sl_exec_warn_once(x, in, "array index out of range (array of %d elements)", len);
}

static void op_aset(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1];
	int32_t len = prog->regs[d].arraylen;
	bool str = is_str(prog, d), bad = false;
	int nc = str ? 1 : ncomp_of(prog, d);
	if (!sl_x_varying(x, b)) {
		int32_t k = array_index(x->data[b][0], len, &bad);
		if (str) {
			EACH_LANE(x, d, i)
				sset(x, d, k, i, sget(x, a, 0, i));
		} else {
			for (int c = 0; c < nc; c++)
				apply(x, K_MOV, d, k * nc + c, a, c, a, c);
		}
	} else {
		EACH_LANE(x, d, i) {
			int32_t k = array_index(ld(x, b, 0, i), len, &bad);
			if (str)
				sset(x, d, k, i, sget(x, a, 0, i));
			else
				for (int c = 0; c < nc; c++)
					sl_x_set(x, d, k * nc + c, i, ld(x, a, c, i));
		}
	}
	if (bad)
		sl_exec_warn_once(x, in, "array index out of range (array of %d elements)", len);
}

static void op_select(struct sl_exec *x, const struct sl_insn *in)
{
	const struct sl_program *prog = x->prog;
	int32_t d = in->dst, a = in->args[0], b = in->args[1], c = in->args[2];
	const struct sl_reg *rd = &prog->regs[d];
	uint32_t tot = sl_exec_reg_total(rd);
	if (rd->type == SL_TYPE_STRING) {
		EACH_LANE(x, d, i) {
			int32_t src = ld(x, a, 0, i) != 0.0f ? b : c;
			for (uint32_t e = 0; e < tot; e++)
				sset(x, d, (int)e, i, sget(x, src, (int)e, i));
		}
		return;
	}
	bool sb = sl_exec_reg_total(&prog->regs[b]) == 1, sc = sl_exec_reg_total(&prog->regs[c]) == 1;
	for (uint32_t k = 0; k < tot; k++) {
		int kb = sb ? 0 : (int)k, kc = sc ? 0 : (int)k;
		if (sl_x_varying(x, d) && sl_x_varying(x, a) && sl_x_varying(x, b) &&
		    sl_x_varying(x, c) && x->nactive == x->n) {
			const float *pa = x->data[a], *pb = plane(x, b, kb), *pc = plane(x, c, kc);
			float *pd = plane(x, d, (int)k);
			for (uint32_t i = 0; i < x->n; i++)
				pd[i] = pa[i] != 0.0f ? pb[i] : pc[i];
			continue;
		}
		EACH_LANE(x, d, i)
			sl_x_set(x, d, (int)k, i,
				 ld(x, a, 0, i) != 0.0f ? ld(x, b, kb, i) : ld(x, c, kc, i));
	}
}

/* ------------------------------------------------------------------------ */
/* Lights                                                                    */

int sl_exec_nlights(struct sl_exec *x)
{
	const struct sl_host *h = x->host;
	if (!h || !h->nlights)
		return 0;
	int n = h->nlights(h->user);
	return n > 0 ? n : 0;
}

const char *sl_exec_light_category(struct sl_exec *x, int i)
{
	const struct sl_host *h = x->host;
	if (!h || !h->light_category)
		return "";
	const char *s = h->light_category(h->user, i);
	return s ? s : "";
}

bool sl_exec_light(struct sl_exec *x, int i, int slot, const float *Ps, const float *Ns,
		   struct sl_light_result *res)
{
	const struct sl_host *h = x->host;
	if (!h || !h->light || i < 0 || slot < 0 || slot > 1 || !Ps || !res)
		return false;
	struct sl_exec_private *p = x->priv;
	size_t s = x->stride;
	if (!p->lbuf[slot]) {
		p->lbuf[slot] = rl_xcalloc(9 * s, sizeof(float));
		p->llit[slot] = rl_xcalloc(s, 1);
	}
	float *L = p->lbuf[slot], *Cl = L + 3 * s, *Ol = L + 6 * s;
	uint8_t *lit = p->llit[slot];
	for (int c = 0; c < 9; c++)
		memset(L + c * s, 0, x->n * sizeof(float));
	memset(lit, 0, x->n);
	bool ambient = false;
	if (!h->light(h->user, i, x, x->n, x->stride, x->mask, Ps, Ns, L, Cl, Ol, lit, &ambient))
		return false;
	res->L = L;
	res->Cl = Cl;
	res->Ol = Ol;
	res->lit = lit;
	res->ambient = ambient;
	return true;
}

/* Is the name [s, s + len) in the comma-separated list @list? */
static bool list_has(const char *list, const char *s, size_t len)
{
	while (*list) {
		const char *e = strchr(list, ',');
		if (!e)
			e = list + strlen(list);
		const char *b = list, *t = e;
		while (b < t && (*b == ' ' || *b == '\t'))
			b++;
		while (t > b && (t[-1] == ' ' || t[-1] == '\t'))
			t--;
		if ((size_t)(t - b) == len && !memcmp(b, s, len))
			return true;
		list = *e ? e + 1 : e;
	}
	return false;
}

bool sl_category_match(const char *cat, const char *light_cat)
{
	if (!cat)
		return true;
	if (!light_cat)
		light_cat = "";
	bool any = false;
	const char *s = cat;
	while (*s) {
		const char *e = strchr(s, ',');
		if (!e)
			e = s + strlen(s);
		const char *b = s, *t = e;
		while (b < t && (*b == ' ' || *b == '\t'))
			b++;
		while (t > b && (t[-1] == ' ' || t[-1] == '\t'))
			t--;
		bool neg = b < t && *b == '-';
		if (neg)
			b++;
		if (b < t) {
			any = true;
			if (list_has(light_cat, b, (size_t)(t - b)) != neg)
				return true;
		}
		s = *e ? e + 1 : e;
	}
	return !any;
}

/* Is the direction @L within @angle of @axis? A zero-length L (or axis) is. */
static bool in_cone(const float L[3], const float axis[3], float angle)
{
	double ll = (double)L[0] * L[0] + (double)L[1] * L[1] + (double)L[2] * L[2];
	double aa = (double)axis[0] * axis[0] + (double)axis[1] * axis[1] +
		    (double)axis[2] * axis[2];
	if (ll == 0 || aa == 0 || angle >= PI)
		return true;
	if (!(angle >= 0))
		return false;
	double dot = (double)L[0] * axis[0] + (double)L[1] * axis[1] + (double)L[2] * axis[2];
	return dot / sqrt(ll * aa) >= cos((double)angle) - 1e-7;
}

/* Write the 3-plane buffer @src into triple register @r at the active points. */
static void store_triple(struct sl_exec *x, int32_t r, const float *src)
{
	if (r < 0)
		return;
	EACH_LANE(x, r, i)
		for (int c = 0; c < 3; c++)
			sl_x_set(x, r, c, i, src[(size_t)c * x->stride + i]);
}

/* ------------------------------------------------------------------------ */
/* Control flow                                                              */

static struct frame *push_frame(struct sl_exec *x, int kind, uint32_t pc)
{
	struct sl_exec_private *p = x->priv;
	/* The checks bound the nesting depth. */
	struct frame *f = &p->frames[p->nframes++];
	f->kind = (uint8_t)kind;
	f->open = pc;
	f->in_else = false;
	return f;
}

static struct frame *top_frame(struct sl_exec *x)
{
	struct sl_exec_private *p = x->priv;
	return &p->frames[p->nframes - 1];
}

/* Switch @lanes off in every mask a frame keeps to turn points back on. */
static void frame_clear(struct sl_exec *x, struct frame *f, const uint8_t *lanes)
{
	int nm = f->kind == F_LOOP ? 3 : (f->kind == F_IF || f->kind == F_ILLUM) ? 2 : 1;
	for (int j = 0; j < nm; j++) {
		uint8_t *m = f->m[j];
		for (uint32_t i = 0; i < x->n; i++)
			m[i] &= (uint8_t)~lanes[i];
	}
}

static void mask_or(uint8_t *d, const uint8_t *s, uint32_t n)
{
	for (uint32_t i = 0; i < n; i++)
		d[i] |= s[i];
}

/*
 * No point is active at @pc: where to go on. The innermost frame's next
 * closer, which switches points back on (or closes the block); past the end
 * of the range when no frame is open.
 */
static uint32_t dead_pc(struct sl_exec *x, uint32_t pc, uint32_t base, uint32_t end)
{
	struct sl_exec_private *p = x->priv;
	if (p->nframes == base)
		return end;
	const struct frame *f = &p->frames[p->nframes - 1];
	const struct sl_insn *o = &x->prog->code[f->open];
	switch (f->kind) {
	case F_IF:
		return (uint32_t)(f->in_else ? o->jump[1] : o->jump[0]);
	case F_LOOP: {
		uint32_t test = (uint32_t)o->jump[0], cont = p->loopcont[f->open];
		if (pc <= test)
			return test;
		if (cont != NONE && pc <= cont)
			return cont;
		return (uint32_t)o->jump[1];
	}
	default:
		return (uint32_t)o->jump[0];
	}
}

/* Go on at @pc, or to the next closer when no point is active. */
static inline uint32_t next_pc(struct sl_exec *x, uint32_t pc, uint32_t base, uint32_t end)
{
	return x->nactive ? pc : dead_pc(x, pc, base, end);
}

static uint32_t op_if(struct sl_exec *x, const struct sl_insn *in, uint32_t pc, uint32_t base,
		      uint32_t end)
{
	struct frame *f = push_frame(x, F_IF, pc);
	int32_t a = in->args[0];
	uint32_t n = x->n;
	uint8_t *entry = f->m[0], *els = f->m[1];
	memcpy(entry, x->mask, n);
	if (!sl_x_varying(x, a)) {
		if (x->data[a][0] != 0.0f) {
			memset(els, 0, n);
		} else {
			memcpy(els, x->mask, n);
			memset(x->mask, 0, n);
			x->nactive = 0;
		}
	} else {
		const float *c = x->data[a];
		uint32_t cnt = 0;
		for (uint32_t i = 0; i < n; i++) {
			uint8_t on = c[i] != 0.0f;
			uint8_t m = x->mask[i];
			els[i] = m & (uint8_t)!on;
			x->mask[i] = m & on;
			cnt += x->mask[i];
		}
		x->nactive = cnt;
	}
	return next_pc(x, pc + 1, base, end);
}

static void exit_loop_mask(struct sl_exec *x, struct frame *f)
{
	uint32_t n = x->n;
	for (uint32_t i = 0; i < n; i++)
		x->mask[i] = f->m[0][i] | f->m[1][i];
	recount(x);
	x->priv->nframes--;
}

static uint32_t op_looptest(struct sl_exec *x, const struct sl_insn *in, uint32_t pc,
			    uint32_t base, uint32_t end)
{
	struct frame *f = top_frame(x);
	int32_t a = in->args[0];
	uint32_t n = x->n;
	if (!sl_x_varying(x, a)) {
		if (x->data[a][0] == 0.0f) {
			mask_or(f->m[0], x->mask, n);
			memset(x->mask, 0, n);
			x->nactive = 0;
		}
	} else {
		const float *c = x->data[a];
		uint8_t *done = f->m[0];
		uint32_t cnt = 0;
		for (uint32_t i = 0; i < n; i++) {
			uint8_t on = c[i] != 0.0f;
			uint8_t m = x->mask[i];
			done[i] |= m & (uint8_t)!on;
			x->mask[i] = m & on;
			cnt += x->mask[i];
		}
		x->nactive = cnt;
	}
	if (x->nactive)
		return pc + 1;
	exit_loop_mask(x, f);
	return next_pc(x, (uint32_t)in->jump[1] + 1, base, end);
}

static uint32_t op_loopend(struct sl_exec *x, const struct sl_insn *in, uint32_t pc,
			   uint32_t base, uint32_t end)
{
	struct frame *f = top_frame(x);
	mask_or(x->mask, f->m[2], x->n);
	memset(f->m[2], 0, x->n);
	recount(x);
	if (x->nactive) {
		uint32_t *it = &x->priv->iters[f->open];
		if (++*it >= MAX_LOOP_ITERS) {
			sl_exec_fail(x, &x->prog->code[f->open], "loop runs too long (%u iterations)",
				     *it);
			return end;
		}
		return f->open + 1;
	}
	exit_loop_mask(x, f);
	return next_pc(x, pc + 1, base, end);
}

/* BREAK (@cont false) or CONTINUE: the active points leave for loop level imm. */
static uint32_t op_break(struct sl_exec *x, const struct sl_insn *in, uint32_t pc,
			 uint32_t base, uint32_t end, bool cont)
{
	struct sl_exec_private *p = x->priv;
	int32_t levels = in->imm;
	const uint8_t *lanes = x->mask;
	for (uint32_t k = p->nframes; k-- > base;) {
		struct frame *f = &p->frames[k];
		if (f->kind == F_FUNC)
			break;
		if ((f->kind == F_LOOP || f->kind == F_ILLUM) && --levels == 0) {
			if (f->kind == F_LOOP)
				mask_or(cont ? f->m[2] : f->m[1], lanes, x->n);
			else if (!cont)
				mask_or(f->m[1], lanes, x->n);
			memset(x->mask, 0, x->n);
			x->nactive = 0;
			return dead_pc(x, pc + 1, base, end);
		}
		frame_clear(x, f, lanes);
	}
	sl_exec_fail(x, in, "%s outside a loop", cont ? "continue" : "break");
	return end;
}

static uint32_t op_return(struct sl_exec *x, uint32_t pc, uint32_t base, uint32_t end)
{
	struct sl_exec_private *p = x->priv;
	for (uint32_t k = p->nframes; k-- > base;) {
		struct frame *f = &p->frames[k];
		if (f->kind == F_FUNC)
			break;
		frame_clear(x, f, x->mask);
	}
	memset(x->mask, 0, x->n);
	x->nactive = 0;
	return dead_pc(x, pc + 1, base, end);
}

/* Copy register @r (triple or float) into @n planes of @dst, broadcasting. */
static void snapshot(struct sl_exec *x, int32_t r, float *dst, int nc)
{
	for (int c = 0; c < nc; c++) {
		float *d = dst + (size_t)c * x->stride;
		if (sl_x_varying(x, r))
			memcpy(d, x->data[r] + (size_t)c * x->stride, x->n * sizeof(float));
		else
			for (uint32_t i = 0; i < x->n; i++)
				d[i] = x->data[r][c];
	}
}

/*
 * Visit the next light of illuminance frame @f that lights some point: set
 * L, Cl, Ol and the body's mask and go into the body; or close the block.
 */
static uint32_t next_light(struct sl_exec *x, struct frame *f, uint32_t base, uint32_t end)
{
	const struct sl_program *prog = x->prog;
	uint32_t n = x->n;
	size_t s = x->stride;
	for (int li = f->light + 1; li < f->nlights && !x->failed; li++) {
		if (f->cat && !sl_category_match(f->cat, sl_exec_light_category(x, li)))
			continue;
		for (uint32_t i = 0; i < n; i++)
			x->mask[i] = f->m[0][i] & (uint8_t)~f->m[1][i];
		recount(x);
		if (!x->nactive)
			break;
		struct sl_light_result r;
		if (!sl_exec_light(x, li, 0, f->buf, f->buf + 3 * s, &r) || r.ambient)
			continue;
		store_triple(x, prog->global_reg[SL_GLOBAL_L], r.L);
		store_triple(x, prog->global_reg[SL_GLOBAL_CL], r.Cl);
		store_triple(x, prog->global_reg[SL_GLOBAL_OL], r.Ol);
		const float *ax = f->buf + 3 * s, *ang = f->buf + 6 * s;
		uint32_t tested = 0;
		for (uint32_t i = 0; i < n; i++) {
			if (!x->mask[i])
				continue;
			bool on = r.lit[i] != 0;
			if (on && f->cone) {
				float Lv[3] = { r.L[i], r.L[s + i], r.L[2 * s + i] };
				float av[3] = { ax[i], ax[s + i], ax[2 * s + i] };
				on = in_cone(Lv, av, ang[i]);
				tested++;
			}
			x->mask[i] = on;
		}
		sl_exec_add_ops(x, CONE_COST, tested);
		recount(x);
		if (!x->nactive)
			continue;
		f->light = li;
		x->cur_light = li;
		return f->open + 1;
	}
	/* All lights visited. */
	const struct sl_insn *o = &prog->code[f->open];
	set_mask(x, f->m[0]);
	x->cur_light = f->saved_light;
	x->priv->nframes--;
	return next_pc(x, (uint32_t)o->jump[0] + 1, base, end);
}

static uint32_t op_illuminance(struct sl_exec *x, const struct sl_insn *in, uint32_t pc,
			       uint32_t base, uint32_t end)
{
	struct frame *f = push_frame(x, F_ILLUM, pc);
	size_t s = x->stride;
	memcpy(f->m[0], x->mask, x->n);
	memset(f->m[1], 0, x->n);
	if (!f->buf)
		f->buf = rl_xcalloc(7 * s, sizeof(float));
	uint32_t k = (uint32_t)in->imm;
	f->cat = k ? sget(x, in->args[0], 0, first_lane(x)) : NULL;
	snapshot(x, in->args[k], f->buf, 3);
	f->cone = in->nargs == k + 3;
	/* The lights' Ns: the cone's axis, else the surface's N (zero without one). */
	int32_t Nr = x->prog->global_reg[SL_GLOBAL_N];
	if (f->cone) {
		snapshot(x, in->args[k + 1], f->buf + 3 * s, 3);
		snapshot(x, in->args[k + 2], f->buf + 6 * s, 1);
	} else if (Nr >= 0) {
		snapshot(x, Nr, f->buf + 3 * s, 3);
	} else {
		memset(f->buf + 3 * s, 0, 3 * s * sizeof(float));
	}
	f->saved_light = x->cur_light;
	f->light = -1;
	f->nlights = sl_exec_nlights(x);
	return next_light(x, f, base, end);
}

/*
 * solar() without arguments: light from every direction, as prman and Aqsis
 * run it. L is -Ns, so the surface sees L along the normal it evaluates the
 * lights with: every point is lit and no illuminance cone about that normal
 * culls it. Such a light integrates over directions itself.
 */
static uint32_t op_solar_all(struct sl_exec *x, uint32_t pc, uint32_t base, uint32_t end)
{
	const struct sl_program *prog = x->prog;
	int32_t Lr = prog->global_reg[SL_GLOBAL_L], Nsr = prog->global_reg[SL_GLOBAL_NS];
	sl_exec_add_ops(x, 3u, x->nactive);
	uint32_t first = first_lane(x);
	for (uint32_t i = 0; i < x->n; i++) {
		if (!x->mask[i])
			continue;
		if (Lr >= 0 && (sl_x_varying(x, Lr) || i == first))
			for (int c = 0; c < 3; c++)
				sl_x_set(x, Lr, c, i, Nsr >= 0 ? -ld(x, Nsr, c, i) : 0.0f);
		x->lit[i] = 1;
	}
	x->ran_illuminate = true;
	return next_pc(x, pc + 1, base, end);
}

/* ILLUMINATE and SOLAR: choose the points the body runs for, mark them lit. */
static uint32_t op_emit(struct sl_exec *x, const struct sl_insn *in, uint32_t pc, uint32_t base,
			uint32_t end)
{
	const struct sl_program *prog = x->prog;
	struct frame *f = push_frame(x, F_BLOCK, pc);
	memcpy(f->m[0], x->mask, x->n);
	int32_t Lr = prog->global_reg[SL_GLOBAL_L], Psr = prog->global_reg[SL_GLOBAL_PS];
	bool solar = in->op == SL_OP_SOLAR;
	if (solar && in->nargs == 0)
		return op_solar_all(x, pc, base, end); /* in the block frame just opened */
	bool cone = !solar && in->nargs == 3;
	int32_t Pa = solar ? -1 : in->args[0];
	int32_t axr = solar ? in->args[0] : cone ? in->args[1] : -1;
	int32_t angr = cone ? in->args[2] : -1;
	/* Each point's L, its cone test, then L is stored (uniform L: first point's). */
	sl_exec_add_ops(x, (solar ? 0u : 3u) + (cone ? CONE_COST : 0u), x->nactive);
	uint32_t first = first_lane(x);
	for (uint32_t i = 0; i < x->n; i++) {
		if (!x->mask[i])
			continue;
		float Lv[3];
		for (int c = 0; c < 3; c++) {
			if (solar)
				Lv[c] = ld(x, axr, c, i);
			else
				Lv[c] = fin((Psr >= 0 ? ld(x, Psr, c, i) : 0.0f) - ld(x, Pa, c, i));
		}
		bool on = true;
		if (cone) {
			float av[3] = { ld(x, axr, 0, i), ld(x, axr, 1, i), ld(x, axr, 2, i) };
			on = in_cone(Lv, av, ld(x, angr, 0, i));
		}
		if (Lr >= 0 && (sl_x_varying(x, Lr) || i == first))
			for (int c = 0; c < 3; c++)
				sl_x_set(x, Lr, c, i, Lv[c]);
		x->mask[i] = on;
		if (on)
			x->lit[i] = 1;
	}
	x->ran_illuminate = true;
	recount(x);
	return next_pc(x, pc + 1, base, end);
}

/* Restore the entry mask of the innermost frame and close it. */
static uint32_t close_block(struct sl_exec *x, uint32_t pc, uint32_t base, uint32_t end)
{
	set_mask(x, top_frame(x)->m[0]);
	x->priv->nframes--;
	return next_pc(x, pc + 1, base, end);
}

static bool is_closer(int op)
{
	switch (op) {
	case SL_OP_ELSE: case SL_OP_ENDIF:
	case SL_OP_LOOPTEST: case SL_OP_LOOPCONT: case SL_OP_LOOPEND:
	case SL_OP_FUNCEND: case SL_OP_ILLUMINANCE_END:
	case SL_OP_ILLUMINATE_END: case SL_OP_SOLAR_END:
		return true;
	default:
		return false;
	}
}

/* Run instructions [pc, end) with all points active. */
static void run_range(struct sl_exec *x, uint32_t pc, uint32_t end)
{
	const struct sl_program *prog = x->prog;
	struct sl_exec_private *p = x->priv;
	uint32_t base = p->nframes;
	memset(x->mask, 1, x->n);
	x->nactive = x->n;
	while (pc < end && !x->failed) {
		const struct sl_insn *in = &prog->code[pc];
		scratch_reset(x);
		if (!x->nactive && !is_closer(in->op)) {
			pc = dead_pc(x, pc, base, end);
			continue;
		}
		/* Work done, for benchmarks: points written by this instruction. */
		if (in->dst >= 0)
			x->ops += prog->regs[in->dst].varying ? x->nactive : 1;
		if (x->count_flops)
			x->flops += (uint64_t)p->cost[pc] * x->nactive;
		switch ((enum sl_op)in->op) {
		case SL_OP_NOP:
			pc++;
			break;
		case SL_OP_MOV:
			op_mov(x, in);
			pc++;
			break;
		case SL_OP_NEG:
		case SL_OP_ADD: case SL_OP_SUB: case SL_OP_MUL: case SL_OP_DIV:
			op_arith(x, in);
			pc++;
			break;
		case SL_OP_DOT:
			op_dot(x, in);
			pc++;
			break;
		case SL_OP_CROSS:
			op_cross(x, in);
			pc++;
			break;
		case SL_OP_LT: case SL_OP_LE: case SL_OP_GT: case SL_OP_GE:
		case SL_OP_AND: case SL_OP_OR:
			apply(x, kop_of[in->op], in->dst, 0, in->args[0], 0, in->args[1], 0);
			pc++;
			break;
		case SL_OP_NOT:
			apply(x, K_NOT, in->dst, 0, in->args[0], 0, in->args[0], 0);
			pc++;
			break;
		case SL_OP_EQ: case SL_OP_NE:
			op_eq(x, in);
			pc++;
			break;
		case SL_OP_TRIPLE: case SL_OP_MATRIX:
			for (uint32_t c = 0; c < in->nargs; c++)
				apply(x, K_MOV, in->dst, (int)c, in->args[c], 0, in->args[c], 0);
			pc++;
			break;
		case SL_OP_COMP:
			apply(x, K_MOV, in->dst, 0, in->args[0], in->imm, in->args[0], in->imm);
			pc++;
			break;
		case SL_OP_SETCOMP:
			apply(x, K_MOV, in->dst, in->imm, in->args[0], 0, in->args[0], 0);
			pc++;
			break;
		case SL_OP_AREF:
			op_aref(x, in);
			pc++;
			break;
		case SL_OP_ASET:
			op_aset(x, in);
			pc++;
			break;
		case SL_OP_SELECT:
			op_select(x, in);
			pc++;
			break;
		case SL_OP_CALL:
			sl_exec_builtin(x, in);
			pc++;
			break;
		case SL_OP_IF:
			pc = op_if(x, in, pc, base, end);
			break;
		case SL_OP_ELSE: {
			struct frame *f = top_frame(x);
			f->in_else = true;
			set_mask(x, f->m[1]);
			pc = next_pc(x, pc + 1, base, end);
			break;
		}
		case SL_OP_ENDIF:
			pc = close_block(x, pc, base, end);
			break;
		case SL_OP_LOOP: {
			struct frame *f = push_frame(x, F_LOOP, pc);
			for (int j = 0; j < 3; j++)
				memset(f->m[j], 0, x->n);
			pc++;
			break;
		}
		case SL_OP_LOOPTEST:
			pc = op_looptest(x, in, pc, base, end);
			break;
		case SL_OP_LOOPCONT: {
			struct frame *f = top_frame(x);
			mask_or(x->mask, f->m[2], x->n);
			memset(f->m[2], 0, x->n);
			recount(x);
			pc = next_pc(x, pc + 1, base, end);
			break;
		}
		case SL_OP_LOOPEND:
			pc = op_loopend(x, in, pc, base, end);
			break;
		case SL_OP_BREAK:
			pc = op_break(x, in, pc, base, end, false);
			break;
		case SL_OP_CONTINUE:
			pc = op_break(x, in, pc, base, end, true);
			break;
		case SL_OP_FUNC: {
			struct frame *f = push_frame(x, F_FUNC, pc);
			memcpy(f->m[0], x->mask, x->n);
			pc++;
			break;
		}
		case SL_OP_RETURN:
			pc = op_return(x, pc, base, end);
			break;
		case SL_OP_FUNCEND:
		case SL_OP_ILLUMINATE_END:
		case SL_OP_SOLAR_END:
			pc = close_block(x, pc, base, end);
			break;
		case SL_OP_ILLUMINANCE:
			pc = op_illuminance(x, in, pc, base, end);
			break;
		case SL_OP_ILLUMINANCE_END:
			pc = next_light(x, top_frame(x), base, end);
			break;
		case SL_OP_ILLUMINATE:
		case SL_OP_SOLAR:
			pc = op_emit(x, in, pc, base, end);
			break;
		default:
			sl_exec_fail(x, in, "unknown instruction %u", in->op);
			break;
		}
	}
	/* Frames of a failed run are abandoned. */
	p->nframes = base;
	x->cur_light = -1;
}

/* Fill every point and component of global @g with @v. */
static void fill_global(struct sl_exec *x, enum sl_global g, float v)
{
	int32_t r = x->prog->global_reg[g];
	if (r < 0 || x->priv->held[r])
		return;
	uint32_t per = sl_x_varying(x, r) ? x->n : 1;
	for (int c = 0; c < sl_exec_global_ncomp[g]; c++) {
		float *d = plane(x, r, c);
		for (uint32_t i = 0; i < per; i++)
			d[i] = v;
	}
}

bool sl_exec_run(struct sl_exec *x, const struct sl_host *host)
{
	if (!x)
		return false;
	const struct sl_program *prog = x->prog;
	struct sl_exec_private *p = x->priv;
	if (p->running) {
		fprintf(stderr, "%s: error: shader evaluated again while it runs\n",
			sl_exec_label(prog));
		return false;
	}
	if (x->stencil_m && (x->nv != 1 || x->nu != 3 * x->stencil_m)) {
		fprintf(stderr, "%s: error: derivative stencils of %u samples run on a %u x 1 "
			"grid, not %u x %u\n", sl_exec_label(prog), x->stencil_m, 3 * x->stencil_m,
			x->nu, x->nv);
		return false;
	}
	p->running = true;
	x->host = host;
	x->failed = false;
	x->random_calls = 0;
	x->cur_light = -1;
	x->ran_illuminate = false;
	memset(x->lit, 0, x->stride);
	memset(p->iters, 0, ((size_t)prog->ncode + 1) * sizeof(uint32_t));
	if (rl_arena_used(x->strings)) {
		rl_arena_destroy(x->strings);
		x->strings = rl_arena_create();
	}

	/* No string register may keep a pointer into the strings just freed. */
	for (uint32_t r = 0; r < prog->nregs; r++) {
		const struct sl_reg *g = &prog->regs[r];
		if (g->type != SL_TYPE_STRING || g->kind == SL_REG_CONST || p->held[r])
			continue;
		size_t cnt = (size_t)sl_exec_reg_total(g) * (g->varying ? x->stride : 1);
		for (size_t i = 0; i < cnt; i++)
			x->sdata[r][i] = "";
	}

	if (prog->kind == SL_SHADER_SURFACE) {
		fill_global(x, SL_GLOBAL_CI, 0.0f);
		fill_global(x, SL_GLOBAL_OI, 1.0f);
	}
	if (prog->kind == SL_SHADER_SURFACE || prog->kind == SL_SHADER_LIGHT ||
	    prog->kind == SL_SHADER_VOLUME) {
		fill_global(x, SL_GLOBAL_L, 0.0f);
		fill_global(x, SL_GLOBAL_CL, 0.0f);
		fill_global(x, SL_GLOBAL_OL, 0.0f);
	}

	struct xform t;
	bool have_t = false;
	for (uint32_t k = 0; k < prog->nparams && !x->failed; k++) {
		if (p->held[prog->params[k].reg])
			continue;
		if (x->param_set[k])
			load_param(x, k, &t, &have_t);
		else
			run_range(x, prog->params[k].init_begin, prog->params[k].init_end);
	}
	if (!x->failed)
		run_range(x, prog->body_begin, prog->ncode);
	scratch_reset(x);
	p->running = false;
	return !x->failed;
}

/* ------------------------------------------------------------------------ */
/* Derivatives and spaces                                                    */

float sl_exec_du(const struct sl_exec *x)
{
	int32_t r = x->prog->global_reg[SL_GLOBAL_DU];
	if (r >= 0) {
		float v = x->data[r][0];
		if (v != 0.0f && isfinite(v))
			return v;
	}
	return x->nu > 1 ? 1.0f / (float)(x->nu - 1) : 1.0f;
}

float sl_exec_dv(const struct sl_exec *x)
{
	int32_t r = x->prog->global_reg[SL_GLOBAL_DV];
	if (r >= 0) {
		float v = x->data[r][0];
		if (v != 0.0f && isfinite(v))
			return v;
	}
	return x->nv > 1 ? 1.0f / (float)(x->nv - 1) : 1.0f;
}

/* Derivative along one line of @m values @fs apart, written @ds apart. */
static void deriv_line(const float *f, size_t fs, uint32_t m, float h, float *d, size_t ds)
{
	if (m < 2 || h == 0.0f) {
		for (uint32_t i = 0; i < m; i++)
			d[i * ds] = 0.0f;
		return;
	}
	if (m == 2) {
		float v = fdiv(f[fs] - f[0], h);
		d[0] = v;
		d[ds] = v;
		return;
	}
	float h2 = 2.0f * h;
	d[0] = fdiv(-3.0f * f[0] + 4.0f * f[fs] - f[2 * fs], h2);
	for (uint32_t i = 1; i + 1 < m; i++)
		d[i * ds] = fdiv(f[(i + 1) * fs] - f[(i - 1) * fs], h2);
	size_t l = m - 1;
	d[l * ds] = fdiv(3.0f * f[l * fs] - 4.0f * f[(l - 1) * fs] + f[(l - 2) * fs], h2);
}

/*
 * One derivative within the stencils of @m samples: d[i] = (f[off + i] -
 * f[i]) / h[i], or the plain difference when @h is NULL; the moved points
 * [m, 3m) take their sample's value (so a second derivative is 0).
 */
static void stencil_line(const float *f, uint32_t m, uint32_t off, const float *h, float *d)
{
	if (h)
		for (uint32_t i = 0; i < m; i++)
			d[i] = fdiv(f[off + i] - f[i], h[i]);
	else
		for (uint32_t i = 0; i < m; i++)
			d[i] = fin(f[off + i] - f[i]);
	memcpy(d + m, d, m * sizeof(float));
	memcpy(d + 2 * (size_t)m, d, m * sizeof(float));
}

/* Derivatives (@divide) or differences within the stencils. */
static void stencil_deriv(struct sl_exec *x, const float *f, float *du, float *dv, bool divide)
{
	uint32_t m = x->stencil_m;
	if (f == du || f == dv) {
		float *copy = sl_exec_scratch(x, 3 * (size_t)m);
		memcpy(copy, f, 3 * (size_t)m * sizeof(float));
		f = copy;
	}
	if (du)
		stencil_line(f, m, m, divide ? x->stencil_du : NULL, du);
	if (dv)
		stencil_line(f, m, 2 * m, divide ? x->stencil_dv : NULL, dv);
}

void sl_exec_deriv(struct sl_exec *x, const float *f, float *dfdu, float *dfdv)
{
	if (x->stencil_m) {
		stencil_deriv(x, f, dfdu, dfdv, true);
		return;
	}
	uint32_t nu = x->nu, nv = x->nv;
	if (f == dfdu || f == dfdv) {
		float *copy = sl_exec_scratch(x, x->n);
		memcpy(copy, f, x->n * sizeof(float));
		f = copy;
	}
	if (dfdu) {
		float h = sl_exec_du(x);
		for (uint32_t v = 0; v < nv; v++)
			deriv_line(f + (size_t)v * nu, 1, nu, h, dfdu + (size_t)v * nu, 1);
	}
	if (dfdv) {
		float h = sl_exec_dv(x);
		for (uint32_t u = 0; u < nu; u++)
			deriv_line(f + u, nu, nv, h, dfdv + u, nu);
	}
}

void sl_exec_deriv_steps(struct sl_exec *x, const float *f, float *du, float *dv, float *hu,
			 float *hv)
{
	if (x->stencil_m) {
		/* the differences themselves: Du(f) du[i] = f[m + i] - f[i] exactly */
		stencil_deriv(x, f, du, dv, false);
		*hu = *hv = 1.0f;
		return;
	}
	sl_exec_deriv(x, f, du, dv);
	*hu = sl_exec_du(x);
	*hv = sl_exec_dv(x);
}

void sl_exec_delta(struct sl_exec *x, const float *f, float *deltau, float *deltav)
{
	float hu, hv;
	sl_exec_deriv_steps(x, f, deltau, deltav, &hu, &hv);
	if (x->stencil_m)
		return;
	for (uint32_t i = 0; deltau && i < x->n; i++)
		deltau[i] = fin(deltau[i] * hu);
	for (uint32_t i = 0; deltav && i < x->n; i++)
		deltav[i] = fin(deltav[i] * hv);
}

bool sl_exec_reg_delta(struct sl_exec *x, int32_t reg, int c, float *deltau, float *deltav)
{
	const struct sl_program *p = x->prog;
	if (reg < 0 || (uint32_t)reg >= p->nregs || !x->data[reg] || c < 0)
		return false;
	const struct sl_reg *r = &p->regs[reg];
	uint32_t ncomp = sl_type_ncomp(r->type) * (r->arraylen ? r->arraylen : 1);
	if ((uint32_t)c >= ncomp)
		return false;
	if (!r->varying) {
		memset(deltau, 0, x->n * sizeof(float));
		memset(deltav, 0, x->n * sizeof(float));
		return true;
	}
	sl_exec_delta(x, x->data[reg] + (size_t)c * x->stride, deltau, deltav);
	return true;
}

void sl_exec_grid_steps(const struct sl_exec *x, float *du, float *dv)
{
	*du = sl_exec_du(x);
	*dv = sl_exec_dv(x);
}

bool sl_exec_space(struct sl_exec *x, const struct sl_insn *in, const char *name, float m[16])
{
	const struct sl_host *h = x->host;
	if (!name || !*name)
		name = "current";
	identity(m);
	if (h && h->space && h->space(h->user, name, m))
		return true;
	identity(m);
	if (!strcmp(name, "current") || !strcmp(name, "camera"))
		return true;
	sl_exec_warn_once(x, in, "unknown coordinate system '%s' (identity used)", name);
	return false;
}

void sl_exec_count_ops(struct sl_exec *x, bool on)
{
	if (!x)
		return;
	if (on)
		x->flops = 0;
	x->count_flops = on;
}

uint64_t sl_exec_ops(const struct sl_exec *x)
{
	return x ? x->flops : 0;
}

uint64_t sl_exec_op_count(const struct sl_exec *x)
{
	return x->ops;
}

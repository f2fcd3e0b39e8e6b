/*
 * Internals of the grid interpreter shared by its core (exec.c: storage,
 * control flow, arithmetic) and its built-in library (exec_builtins.c).
 */
#ifndef SL_EXEC_IMPL_H
#define SL_EXEC_IMPL_H

#include "builtin.h"
#include "exec.h"

struct sl_exec {
	const struct sl_program *prog;
	uint32_t maxn;          /* capacity in points */
	uint32_t stride;        /* plane stride of varying registers (= maxn) */
	uint32_t nu, nv, n;     /* current grid; n = nu * nv */
	/*
	 * Derivative stencils (sl_exec_set_stencil): stencil_m samples, each
	 * with its steps stencil_du[i], stencil_dv[i]; 0 for grid derivatives.
	 * The arrays hold maxn / 3 floats each once a stencil was set.
	 */
	uint32_t stencil_m;
	float *stencil_du, *stencil_dv;
	bool warned_small;      /* a light host said once that this light is too small */

	float **data;           /* per register; NULL for string registers */
	const char ***sdata;    /* per string register: 1 (uniform) or stride pointers */
	bool *param_set;        /* per parameter: set by the host, skip its default */

	uint8_t *mask;          /* running state: mask[i] != 0 when point i is active */
	uint32_t nactive;       /* number of active points */

	const struct sl_host *host;
	struct sl_exec *peer[SL_PEER_COUNT];
	int cur_light;          /* light being visited by the innermost illuminance, or -1 */

	uint8_t *lit;           /* light shaders: points an illuminate/solar body ran for */
	bool ran_illuminate;    /* light shaders: some illuminate/solar was executed */

	bool failed;            /* a run-time error stopped the run */
	uint32_t random_calls;  /* random() calls so far in this run */
	uint64_t ops;           /* operations executed (see sl_exec_op_count) */
	bool count_flops;       /* float operations are being counted (sl_exec_count_ops) */
	uint64_t flops;         /* float operations counted (sl_exec_ops) */
	uint8_t *warned;        /* per instruction: a warning was printed already */

	/* Scratch floats, reset before each instruction (sl_exec_scratch). */
	float *scratch;
	size_t scratch_cap, scratch_used;
	/* Strings made while running (format, concat): freed at the next run. */
	struct rl_arena *strings;

	/* Private state of exec.c (control-flow frames etc.). */
	struct sl_exec_private *priv;
};

/** Is register @r varying? */
static inline bool sl_x_varying(const struct sl_exec *x, int32_t r)
{
	return x->prog->regs[r].varying;
}

/** Component @c (counting across array elements: e * ncomp + c) of @r at point @i. */
static inline float sl_x_get(const struct sl_exec *x, int32_t r, int c, uint32_t i)
{
	const float *d = x->data[r];
	return x->prog->regs[r].varying ? d[(size_t)c * x->stride + i] : d[c];
}

static inline void sl_x_set(struct sl_exec *x, int32_t r, int c, uint32_t i, float v)
{
	float *d = x->data[r];
	if (x->prog->regs[r].varying)
		d[(size_t)c * x->stride + i] = v;
	else
		d[c] = v;
}

/** String value of @r at point @i. */
static inline const char *sl_x_str(const struct sl_exec *x, int32_t r, uint32_t i)
{
	const char **d = x->sdata[r];
	return x->prog->regs[r].varying ? d[i] : d[0];
}

static inline void sl_x_set_str(struct sl_exec *x, int32_t r, uint32_t i, const char *s)
{
	const char **d = x->sdata[r];
	if (x->prog->regs[r].varying)
		d[i] = s;
	else
		d[0] = s;
}

/**
 * The points an instruction writing @dst works on: all grid points, tested
 * with the mask, when @dst is varying; just point 0 (if any is active) when
 * it is uniform (then all its operands are uniform too).
 *
 *   SL_X_EACH(x, in->dst, i) { ... sl_x_set(x, in->dst, 0, i, v); }
 */
#define SL_X_EACH(x, dst, i) \
	for (uint32_t i = 0, u_ = ((dst) >= 0 && !sl_x_varying((x), (dst))), \
		      n_ = u_ ? ((x)->nactive != 0) : (x)->n; i < n_; i++) \
		if (u_ || (x)->mask[i])

/** @n floats of scratch, valid until the next instruction. Aborts when memory is out. */
float *sl_exec_scratch(struct sl_exec *x, size_t n);

/** A string that lives until the next run. */
const char *sl_exec_strdup(struct sl_exec *x, const char *s);

/**
 * Print "FILE:LINE:COL: warning: MESSAGE" once per instruction, and once a
 * process for all the executors of every thread (counted: sl_exec_warning_counts).
 */
/* The ray-tracing built-ins (exec_raytrace.c): trace, transmission, occlusion,
 * indirectdiffuse, raylevel, isshadowray, by id. */
void sl_exec_ray_builtin(struct sl_exec *x, const struct sl_insn *in, int id);

/* shadow() (@shadow) or environment() of the map "raytrace", the lookup
 * point or direction at argument 2, @ncoord coordinates before the options. */
void sl_exec_ray_lookup(struct sl_exec *x, const struct sl_insn *in, bool shadow, int ncoord);

void sl_exec_warn_once(struct sl_exec *x, const struct sl_insn *in, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/**
 * Has the shading warning @line ("FILE:LINE:COL: warning: MESSAGE") been
 * printed already in this process? Counts it either way (exec_warnings.c).
 */
bool sl_exec_warning_seen(const char *line);

/** Print "FILE:LINE:COL: error: MESSAGE" and stop the run (x->failed). */
void sl_exec_fail(struct sl_exec *x, const struct sl_insn *in, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/**
 * Derivatives of the plane @f (n values, point layout) with respect to the
 * surface parameters u and v: central differences inside the grid, one-sided
 * second-order ones at its edges, divided by du and dv (the globals' values).
 * A grid one point wide in u (or v) gives 0 for that derivative. With a
 * stencil (sl_exec_set_stencil) the differences within each sample's
 * stencil instead, divided by the sample's own steps; the moved points get
 * their sample's derivative. @dfdu or @dfdv may be NULL; either may be @f.
 */
void sl_exec_deriv(struct sl_exec *x, const float *f, float *dfdu, float *dfdv);

/**
 * For code that turns derivatives back into changes over one step (filter
 * regions, area()): fills @du and @dv (as sl_exec_deriv() does) with what,
 * multiplied by *hu and *hv, gives Du(f) du and Dv(f) dv. Over the grid the
 * derivatives and its uniform steps (sl_exec_du(), _dv()); with a stencil
 * each sample's differences f[m + i] - f[i] and f[2m + i] - f[i] and 1, so
 * the change is exact whatever the sample's own step.
 */
void sl_exec_deriv_steps(struct sl_exec *x, const float *f, float *du, float *dv, float *hu,
			 float *hv);

/**
 * The changes of @f over one step along u and along v, Du(f) du and
 * Dv(f) dv, per point: sl_exec_deriv_steps() multiplied out (what a bake
 * stores for the moved blocks of a stencil). Same arguments as
 * sl_exec_deriv().
 */
void sl_exec_delta(struct sl_exec *x, const float *f, float *deltau, float *deltav);

/**
 * The global du and dv of this run (uniform values; 1 when the program has
 * none): the grid's steps. A stencil's steps are per sample (sl_exec_delta).
 */
float sl_exec_du(const struct sl_exec *x);
float sl_exec_dv(const struct sl_exec *x);

/**
 * Matrix taking space @name to "current" space: "current" and "camera" are
 * the identity unless the host says otherwise; other names ask the host.
 * Unknown names warn once (at @in) and give the identity; returns false then.
 */
bool sl_exec_space(struct sl_exec *x, const struct sl_insn *in, const char *name, float m[16]);

/** Results of one light at the active points (planar, stride x->stride). */
struct sl_light_result {
	float *L;        /* surface point -> light */
	float *Cl, *Ol;
	uint8_t *lit;    /* reaches the point */
	bool ambient;    /* ambient light: contributes to ambient() only */
};

/** Number of lights the host offers (0 without a host). */
int sl_exec_nlights(struct sl_exec *x);

/**
 * Evaluate light @i at positions @Ps with normals @Ns (3 planes each, stride
 * x->stride; @Ns may be NULL: zero) for the active points. Buffers in @res
 * are scratch owned by @x and stay valid until the next call of
 * sl_exec_light() with the same @slot (0 or 1).
 * False if the host failed or has no lights.
 */
bool sl_exec_light(struct sl_exec *x, int i, int slot, const float *Ps, const float *Ns,
		   struct sl_light_result *res);

/** Light @i's category ("" when none). */
const char *sl_exec_light_category(struct sl_exec *x, int i);

/**
 * Does category string @cat (as written in illuminance: "name", "-name",
 * "a,b", "" for all) select a light whose __category is @light_cat?
 */
bool sl_category_match(const char *cat, const char *light_cat);

/**
 * With counting on (sl_exec_count_ops), add @per_point float operations for
 * each of @points points: for work whose amount is known only while running
 * (per light, per point reaching a test).
 */
static inline void sl_exec_add_ops(struct sl_exec *x, uint32_t per_point, uint32_t points)
{
	if (x->count_flops)
		x->flops += (uint64_t)per_point * points;
}

/**
 * Float operations per active point of built-in call @in, as tabled in
 * exec.h, except the per-light work of the lighting built-ins, which
 * sl_exec_builtin() adds itself. Implemented in exec_builtins.c.
 */
uint32_t sl_exec_builtin_cost(const struct sl_program *prog, const struct sl_insn *in);

/** Run built-in call @in (SL_OP_CALL). Implemented in exec_builtins.c. */
void sl_exec_builtin(struct sl_exec *x, const struct sl_insn *in);

/* ---- shared by exec.c and exec_check.c ---------------------------------- */

/* Longest array register accepted. */
#define SL_EXEC_MAX_ARRAY (1 << 20)

/* Components per global variable (all are floats or triples). */
extern const uint8_t sl_exec_global_ncomp[SL_GLOBAL_COUNT];

/* The program's file, or its name, for messages. */
const char *sl_exec_label(const struct sl_program *prog);

/* Floats (or string pointers) per point of register @r. */
uint32_t sl_exec_reg_total(const struct sl_reg *r);

/*
 * Everything the interpreter relies on for memory safety, checked once per
 * program before it runs (exec_check.c): false, reported on stderr, when
 * the program breaks a rule. Fills @loopcont (per LOOP instruction: its
 * LOOPCONT) and *@maxdepth (the deepest nesting of blocks).
 */
bool sl_exec_check_program(const struct sl_program *prog, uint32_t *loopcont,
			   uint32_t *maxdepth);

static inline bool reg_ok(const struct sl_program *prog, int32_t r)
{
	return r >= 0 && (uint32_t)r < prog->nregs;
}

static inline const struct sl_reg *creg(const struct sl_program *prog, int32_t r)
{
	return &prog->regs[r];
}

static inline bool is_str(const struct sl_program *prog, int32_t r)
{
	return creg(prog, r)->type == SL_TYPE_STRING;
}

static inline int ncomp_of(const struct sl_program *prog, int32_t r)
{
	return sl_reg_ncomp(creg(prog, r));
}

#endif

/*
 * The grid interpreter: runs a compiled shader over a grid of points at once,
 * REYES-style. Varying registers hold one value per point, uniform ones a
 * single value; varying control flow runs under a running-state mask;
 * derivatives are finite differences over the grid's u/v topology.
 *
 * Data layout. A register's storage is floats. Uniform: element e, component
 * c at data[e * ncomp + c]. Varying: data[(e * ncomp + c) * stride + i] for
 * point i, where stride = sl_exec_stride(). Point (iu, iv) of an nu x nv grid
 * is i = iv * nu + iu.
 */
#ifndef SL_EXEC_H
#define SL_EXEC_H

#include "ir.h"

struct sl_exec;
struct sl_tex_lookup;

/** What the renderer (or a test) provides to a running shader. All callbacks may be NULL. */
struct sl_host {
	void *user;

	/* ---- lights, for illuminance, ambient(), diffuse(), specular(), phong() ---- */
	/** Number of lights visible to the shaded surface. */
	int (*nlights)(void *user);
	/**
	 * Run light @i for the points of @surface where mask[i] is set (n points,
	 * planar with @stride). Ps: surface positions (3 planes). Fill, for those
	 * points: L: vector from the surface point to the light (3 planes);
	 * Cl, Ol (3 planes each); lit[i] = 1 where the light reaches the point
	 * (inside its illuminate cone), else 0. *ambient = true for a light with
	 * no illuminate or solar (it only adds to ambient(): Cl is its colour).
	 * Return false on failure (treated as no light).
	 */
	bool (*light)(void *user, int i, struct sl_exec *surface, uint32_t n, uint32_t stride,
		      const uint8_t *mask, const float *Ps, float *L, float *Cl, float *Ol,
		      uint8_t *lit, bool *ambient);
	/** Light @i's __category string ("" when none). */
	const char *(*light_category)(void *user, int i);
	/**
	 * lightsource(): read light @i's parameter @name (type @type, a enum
	 * sl_basetype; @arraylen elements, 0 for a non-array) into @out (floats, uniform layout if *varying is set to
	 * false, else planar with stride) or @sout for strings. False if absent.
	 */
	bool (*light_message)(void *user, int i, const char *name, int type, int arraylen,
			      float *out, const char **sout, bool *varying, uint32_t stride);

	/* ---- coordinate systems ---- */
	/** Matrix taking points in space @name to "current" space (row vectors, p' = p M). */
	bool (*space)(void *user, const char *name, float m[16]);

	/* ---- textures (see struct sl_tex_lookup) ---- */
	bool (*texture)(void *user, const struct sl_tex_lookup *q);
	bool (*environment)(void *user, const struct sl_tex_lookup *q);
	bool (*shadow)(void *user, const struct sl_tex_lookup *q);
	/** textureinfo(): "resolution" (2 floats), "type", "channels", "viewingmatrix", ... */
	bool (*textureinfo)(void *user, const char *name, const char *query, int type,
			    int arraylen, float *out, const char **sout);

	/* ---- attribute(), option(), rendererinfo() ---- */
	bool (*attribute)(void *user, const char *name, int type, int arraylen, float *out,
			  const char **sout);
	bool (*option)(void *user, const char *name, int type, int arraylen, float *out,
		       const char **sout);
	bool (*rendererinfo)(void *user, const char *name, int type, int arraylen, float *out,
			     const char **sout);

	/** printf() output; NULL prints to stdout. */
	void (*print)(void *user, const char *text);
};

/** One filtered texture, environment or shadow lookup over the active points. */
struct sl_tex_lookup {
	const char *name;
	int channel;        /* first channel */
	int nchannels;      /* 1 (float result) or 3 (color) */
	uint32_t n, stride;
	const uint8_t *mask;
	/*
	 * The filter region's four corners per point (planar arrays of n floats).
	 * texture: s[k], t[k]. environment: dir[k] (3 planes each, stride).
	 * shadow: pos[k] (3 planes each, stride), in "current" space.
	 */
	const float *s[4], *t[4];
	const float *dir[4];
	const float *pos[4];
	/*
	 * shadow: the lookup point itself (3 planes, stride) when the corners
	 * come from its derivatives, else NULL. Stochastic filters seed from
	 * it: the same point gives the same answer whatever grid or batch it
	 * is shaded in (its corners may differ in the last bits).
	 */
	const float *center;
	/* Options ("blur", ...); defaults in brackets. */
	float blur, sblur, tblur;   /* [0] */
	float width, swidth, twidth; /* [1] multiplies the filter region */
	float samples;              /* [16 for shadow, 1 otherwise] */
	float bias;                 /* [-1: the map's own] */
	float fill;                 /* [0] value of missing channels */
	const char *filter;         /* ["gaussian"] */
	float *out;                 /* nchannels planes with stride */
};

/**
 * An executor of @prog for grids of up to @maxpoints points. Owns register
 * storage; @prog must outlive it. Returns NULL if @maxpoints is 0 or too big.
 */
struct sl_exec *sl_exec_create(const struct sl_program *prog, uint32_t maxpoints);
void sl_exec_destroy(struct sl_exec *x);

const struct sl_program *sl_exec_program(const struct sl_exec *x);
uint32_t sl_exec_stride(const struct sl_exec *x);

/** Grid shape for the next run: nu * nv <= maxpoints. nu or nv may be 1. */
bool sl_exec_set_grid(struct sl_exec *x, uint32_t nu, uint32_t nv);

/**
 * Storage of a global, or NULL if the program does not use it. *varying says
 * which layout. The host fills inputs (P, N, s, t, ...) before sl_exec_run()
 * and reads outputs (Ci, Oi, P, N, L, Cl, ...) after.
 */
float *sl_exec_global(struct sl_exec *x, enum sl_global g, bool *varying);

/** Storage of a register (see layout above). Strings: use sl_exec_reg_strings(). */
float *sl_exec_reg(struct sl_exec *x, int32_t reg);
const char **sl_exec_reg_strings(struct sl_exec *x, int32_t reg);

/**
 * Set parameter @name from @nvalues floats: one value for all points
 * (uniform layout; nvalues = ncomp * max(1, arraylen)), or, for a varying
 * parameter, nvalues = that times n, planar with stride n (copied into
 * place). Point, vector and normal values are taken to be in "shader" space
 * and transformed to "current" space. The default initializer then does not
 * run. False (and a message on stderr) if there is no such parameter or the
 * count does not fit.
 */
bool sl_exec_set_param(struct sl_exec *x, const char *name, const float *values,
		       uint32_t nvalues);
bool sl_exec_set_param_string(struct sl_exec *x, const char *name, const char *value);
/** Forget all values set by sl_exec_set_param*(): defaults apply again. */
void sl_exec_reset_params(struct sl_exec *x);

/**
 * Hold register @reg (@hold true) or release it: the host writes a held
 * register's value itself, through sl_exec_reg() or sl_exec_reg_strings(),
 * and sl_exec_run() leaves it as written: a held parameter's default does
 * not run and a value set with sl_exec_set_param() is ignored; a held Ci or
 * Oi is not reset; a held string register is not cleared (its strings must
 * outlive the run). The program's own instructions may still write it.
 * Used to run code that reads values computed elsewhere (the dynamic part
 * of a specialized shader, spec.h). False for a constant or a register
 * the program does not have.
 */
bool sl_exec_hold(struct sl_exec *x, int32_t reg, bool hold);

/**
 * Derivative stencils, for samples that do not lie on a grid (a baked shot's
 * shading samples, run in any order). With @m > 0 the next runs of @x are
 * over 3 m points laid out as three blocks: the samples [0, m), the same
 * samples moved one grid step along u [m, 2m) and one step along v [2m, 3m)
 * (the host writes the moved inputs: value + Du(value) du, value + Dv(value)
 * dv, as cached at bake time). Every derivative then is a one-sided
 * difference within a sample's stencil: Du(f) at i = (f[m + i] - f[i]) /
 * du[i], Dv(f) = (f[2m + i] - f[i]) / dv[i], the moved points taking their
 * sample's values, so area(), calculatenormal() and texture filter regions
 * see the grid's step of the sample: exact where the derivative's operand
 * is linear in the moved inputs (shadow(map, Ps) after a transform).
 * @du and @dv are m spacings each (du, dv of the grid each sample came
 * from); they are copied. The grid must be 3m x 1 (sl_exec_set_grid) and
 * lights run through sl_lighthost get the same stencil. @m = 0 returns to
 * grid derivatives. False if 3m exceeds the executor's points or a spacing
 * is not finite.
 */
bool sl_exec_set_stencil(struct sl_exec *x, uint32_t m, const float *du, const float *dv);
/**
 * After a run over a grid: the change of component @c of register @reg (c
 * counts across array elements as in the register layout) over one grid
 * step along u and along v, Du(f) du and Dv(f) dv, per point (n floats
 * each), as the derivative-taking built-ins see it: what a bake stores for
 * derivative stencils. Zeros for a uniform register. False for a string or
 * an unknown register or component.
 */
bool sl_exec_reg_delta(struct sl_exec *x, int32_t reg, int c, float *deltau, float *deltav);
/** The grid steps du and dv of the last run (1 / (n - 1) when the program has no du, dv). */
void sl_exec_grid_steps(const struct sl_exec *x, float *du, float *dv);
/** The stencil's m (0: derivatives over the grid). */
uint32_t sl_exec_stencil(const struct sl_exec *x);

/** Which shader a message-passing call reaches: surface(), displacement(), ... */
enum sl_peer { SL_PEER_SURFACE, SL_PEER_DISPLACEMENT, SL_PEER_ATMOSPHERE, SL_PEER_COUNT };
/** Let this shader read @peer's parameters by message passing (NULL to unset). */
void sl_exec_set_peer(struct sl_exec *x, enum sl_peer which, struct sl_exec *peer);

/**
 * Run the shader over the grid (all points active) with @host (may be NULL).
 * Returns false if it stopped on a run-time error (reported on stderr with
 * the source location); outputs are then undefined. Never produces NaN or
 * Inf from its own arithmetic (division by zero gives 0; domain errors give
 * the nearest valid result).
 */
bool sl_exec_run(struct sl_exec *x, const struct sl_host *host);

/**
 * Operations executed by all runs so far: each executed instruction that
 * writes a result counts one per active point when the result is varying, one
 * when it is uniform (a benchmark's unit of work).
 */
uint64_t sl_exec_op_count(const struct sl_exec *x);

/** After a light shader's run: lit[i] is 1 where an illuminate/solar body ran for point i. */
const uint8_t *sl_exec_lit_mask(const struct sl_exec *x);
/** After a light shader's run: true if it executed no illuminate or solar (an ambient light). */
bool sl_exec_is_ambient(const struct sl_exec *x);

#endif

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
#include "mathlib.h"

struct sl_exec;
struct sl_tex_lookup;
struct sl_ray_query;

/** What the renderer (or a test) provides to a running shader. All callbacks may be NULL. */
struct sl_host {
	void *user;

	/* ---- lights, for illuminance, ambient(), diffuse(), specular(), phong() ---- */
	/** Number of lights visible to the shaded surface. */
	int (*nlights)(void *user);
	/**
	 * Run light @i for the points of @surface where mask[i] is set (n points,
	 * planar with @stride). Ps: surface positions (3 planes). Ns: the normal
	 * the lights are evaluated with (3 planes; NULL: zero), the light's Ns:
	 * the axis of an illuminance, the surface's N for an illuminance without
	 * one, the normal given to diffuse(), specular() or phong(), zero for
	 * ambient(). Fill, for those
	 * points: L: vector from the surface point to the light (3 planes);
	 * Cl, Ol (3 planes each); lit[i] = 1 where the light reaches the point
	 * (inside its illuminate cone), else 0. *ambient = true for a light with
	 * no illuminate or solar (it only adds to ambient(): Cl is its colour).
	 * Return false on failure (treated as no light).
	 */
	bool (*light)(void *user, int i, struct sl_exec *surface, uint32_t n, uint32_t stride,
		      const uint8_t *mask, const float *Ps, const float *Ns, float *L,
		      float *Cl, float *Ol, uint8_t *lit, bool *ambient);
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

	/* ---- ray tracing (struct sl_ray_query) ---- */
	/**
	 * Cast @q->n rays and fill the outputs @q asks for. trace(),
	 * transmission(), occlusion(), indirectdiffuse(), gather(),
	 * environment("raytrace") and shadow("raytrace") all come here. NULL
	 * (a host that cannot ray trace): those built-ins give what a ray that
	 * hits nothing gives, with a warning at the call.
	 */
	bool (*trace)(void *user, struct sl_ray_query *q);
	/**
	 * rayinfo(): "depth" (float: 0 for a camera-ray shading, +1 per ray
	 * level), "type" (string: "camera", "specular", "diffuse",
	 * "transmission"), "speculardepth", "diffusedepth" (float), "origin",
	 * "direction" (point, vector of the ray whose hit is shaded, "current"
	 * space), "length" (float). raylevel() is rayinfo("depth") and
	 * isshadowray() is rayinfo("type") == "transmission". False when the
	 * host does not know @name (NULL: depth 0, type "camera").
	 */
	bool (*rayinfo)(void *user, const char *name, int type, int arraylen, float *out,
			const char **sout);

	/** printf() output; NULL prints to stdout. */
	void (*print)(void *user, const char *text);

	/** The highlight of specular() and specularbrdf(); zero is PRMan's (mathlib.h). */
	enum sl_specular_model specular_model;
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

/** Which rays a query casts: what they may hit and how hits are shaded. */
enum sl_ray_type {
	SL_RAY_SPECULAR,     /* trace(), environment("raytrace"), gather(): reflection, refraction */
	SL_RAY_DIFFUSE,      /* occlusion(), indirectdiffuse() */
	SL_RAY_TRANSMISSION, /* transmission(), shadow("raytrace"): only opacity matters */
	SL_RAY_TYPE_COUNT
};

/**
 * A batch of rays for struct sl_host's trace. Rays are packed (ray k's
 * origin at org[3k .. 3k + 2]), in "current" space, each from the shaded
 * point that casts it. The host offsets each origin by the bias along its
 * ray, finds what the ray reaches among the objects visible to its type
 * within [0, maxdist], and fills the outputs that are not NULL.
 */
struct sl_ray_query {
	enum sl_ray_type type;
	uint32_t n;                /* rays */
	const float *org;          /* 3n */
	const float *dir;          /* 3n, any length but zero (normalized by the host) */
	const float *maxdist;      /* n: distance along the normalized ray; NULL: unbounded */
	const float *time;         /* n: in [0, 1] over the shutter; NULL: shutter open */
	float bias;                /* < 0: the casting object's Attribute "trace" "bias" */
	const char *subset;        /* "subset": only objects in these trace groups; NULL: all */
	const char *hitmode;       /* "hitmode": "primitive", "shader"; NULL: the hit object's */
	/*
	 * Outputs, per ray. dist: the distance to the first hit, 1e30 where it
	 * reaches nothing. Ci, Oi (3n each): the colour and opacity it brings
	 * back: hits shaded as their hit mode says (the object's surface shader
	 * with its lights, at ray depth + 1, or its Cs and Os), composited front
	 * to back through semi-transparent hits until opaque (black, 0 where
	 * nothing is hit). trans (3n): what reaches maxdist: the product of
	 * (1 - Oi) over every hit in [0, maxdist] (1 where none).
	 */
	float *dist;
	float *Ci, *Oi;
	float *trans;
	/*
	 * gather()'s named values of each ray's first hit (packed, out_ncomp[i]
	 * floats per ray in outs[i]): "surface:NAME" (the hit shader's output
	 * parameter or global NAME after it ran), "primitive:NAME" (the hit
	 * point's P, N, Ng, Cs, Os, s, t, u, v, in "current" space). Zero
	 * where the ray reaches nothing or the hit has no such value. Names
	 * the host does not know are zero too.
	 */
	uint32_t nouts;
	const char *const *out_names;
	const int *out_ncomp;
	float *const *outs;
};

/**
 * An executor of @prog for grids of up to @maxpoints points. Owns register
 * storage; @prog must outlive it. Returns NULL if @maxpoints is 0 or too big.
 */
struct sl_exec *sl_exec_create(const struct sl_program *prog, uint32_t maxpoints);
void sl_exec_destroy(struct sl_exec *x);

/**
 * The shading warnings of the process so far: @printed, and @repeats not
 * printed because the same one (text and place) was, by any executor.
 */
void sl_exec_warning_counts(uint64_t *printed, uint64_t *repeats);

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
 * Instructions executed by all runs so far: each executed instruction that
 * writes a result counts one per active point when the result is varying, one
 * when it is uniform (the interpreter's unit of work; for float operations
 * see sl_exec_count_ops()).
 */
uint64_t sl_exec_op_count(const struct sl_exec *x);

/**
 * Count the float arithmetic that runs execute (@on), or stop counting. Turning
 * it on sets the total to 0; turning it off keeps the total for
 * sl_exec_ops(). A run with counting off costs one branch per instruction.
 *
 * What counts. Each executed instruction adds its cost below once for every
 * point active when it runs, whether its result is varying or uniform (a
 * kernel that shades one sample per invocation does the uniform arithmetic
 * for each sample); code skipped because no point is active adds nothing,
 * and a loop adds its body's cost on each trip. The unit is one float
 * operation per component; a transcendental or a square root counts 1, like
 * an add, which is the conservative choice when the count is set against a
 * multiply-add rate (where a multiply-add counts 2).
 *
 *   copies, moves, loads, component and array access, triple / matrix
 *   construction, select, not / and / or, control flow           0
 *   neg, add, sub, mul, div                     1 per result component
 *   matrix * matrix 112 (64 mul + 48 add); matrix / matrix 256 (a 144-op
 *   inverse and a product)
 *   lt le gt ge 1; eq ne 1 per compared component (strings 0)
 *   dot 5 (3 mul + 2 add); cross 9 (6 mul + 3 sub)
 *   illuminance with axis and angle: 20 per point and visited light that
 *   reaches the cone test (three dots, mul, sqrt, div, cos, compare)
 *   illuminate: 3 (L = Ps - P), + 20 with a cone; solar 0 (L is its axis)
 *
 *   Built-ins, per point, nc = components of the result:
 *   radians degrees 1; sin cos tan asin acos atan sinh cosh tanh exp sqrt
 *   inversesqrt pow log abs sign floor ceil round step 1 per nc;
 *   log(x, base) 3; mod 4 per nc (div, floor, mul, sub); min max
 *   (arguments - 1) per nc; clamp 2 per nc; mix 3 per nc; smoothstep 9;
 *   filterstep 19 (14 with two edges s1, s2); spline 29 + 7 per nc (one
 *   evaluation, whatever the basis); noise / pnoise of 1, 2, 3, 4 dimensions
 *   27, 52, 85, 182 per nc; cellnoise dimensions + 1 per nc; random 0
 *   (integer hashing); length 6; normalize 9; distance 9; ptlined 31;
 *   faceforward 9; reflect 12; refract 24; fresnel 52, 88 with R and T;
 *   specularbrdf 20; rotate 63 (a point) or 151 (a matrix); area 33;
 *   calculatenormal 21; Du Dv 2 per nc; Deriv 4 + 7 per nc; transform of a
 *   point 27, of a vector or normal 15 (space matrices are the host's and
 *   count 0); depth 30; ctransform 9 per conversion to or from a space
 *   other than "rgb"; determinant 63; translate scale spacematrix 112;
 *   xcomp setxcomp comp setcomp 0; texture environment shadow 0 (filtering
 *   is memory work done by the host); queries, message passing, strings 0.
 *   ambient 3 per point and ambient light; diffuse, specular, phong per
 *   point lit by a light (not __nondiffuse / __nonspecular): 24 to
 *   normalize L and N and test the hemisphere, then, where the point faces
 *   the light, 6 for diffuse, 26 for specular (specularbrdf + 6), 37 for
 *   phong.
 *
 * Lights. A surface's lights run on their own executors (sl_lighthost), and
 * their arithmetic is counted there: turn counting on for the surface and
 * for every light executor, and add sl_exec_ops() of all of them. A light
 * runs over the surface's whole grid once for each illuminance loop or
 * lighting built-in that visits it, and counts each of those runs.
 */
void sl_exec_count_ops(struct sl_exec *x, bool on);

/** Float operations counted since sl_exec_count_ops() last turned counting on (0 if never). */
uint64_t sl_exec_ops(const struct sl_exec *x);

/** After a light shader's run: lit[i] is 1 where an illuminate/solar body ran for point i. */
const uint8_t *sl_exec_lit_mask(const struct sl_exec *x);
/** After a light shader's run: true if it executed no illuminate or solar (an ambient light). */
bool sl_exec_is_ambient(const struct sl_exec *x);

#endif

/*
 * Geometry: every primitive is cut into parametric pieces (struct
 * reyes_patch) that can be bounded, split in half and diced into grids of
 * points, the REYES way. Quadrics are one piece over their (u, v) range;
 * polygons are triangulated (GeneralPolygon holes included) and each
 * triangle or planar quad is a bilinear piece; patch meshes give one piece
 * per cell (bicubic cells through their basis matrices, with periodic wrap).
 */
#ifndef REYES_GEOM_H
#define REYES_GEOM_H

#include "scene.h"

/** A part of a primitive over a range of its parameters. */
struct reyes_patch {
	const struct reyes_prim *prim;
	uint32_t piece;        /* which piece of the primitive (face triangle, mesh cell) */
	float u0, u1, v0, v1;  /* parameter range within the piece, [0,1] x [0,1] at first */
	uint16_t depth;        /* times split */
};

/**
 * The pieces of @p, appended to *out (grown with rl_xrealloc; *n updated).
 * Degenerate input (a polygon with fewer than 3 distinct points, a zero
 * radius) gives no piece and is not an error. Returns false, with a message
 * on @diag naming the primitive's RIB line if known, for input that cannot be
 * diced (vertex indices out of range are caught by the scene builder).
 */
bool reyes_prim_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
		       size_t *cap);

/** Does @p deform over the shutter (positions or quadric parameters given at close)? */
bool reyes_prim_deforms(const struct reyes_prim *p);

/**
 * A conservative object-space bounding box of @pa at shutter time index @t
 * (0: open, 1: close; the same when the primitive does not deform).
 */
void reyes_patch_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3]);

/** Split in half along u (@along_u) or v. */
void reyes_patch_split(const struct reyes_patch *pa, bool along_u, struct reyes_patch out[2]);

/**
 * A diced grid in object space: nu x nv points (point (i, j) at j * nu + i),
 * planar layout (component c of point k at data[c * n + k]). Buffers belong
 * to the grid (freed by reyes_grid_finish). Optional ones are NULL when the
 * primitive has no such data (the renderer then uses the attribute's Cs/Os,
 * Ng for N, and u, v for s, t).
 */
struct reyes_grid {
	uint32_t nu, nv, n;
	float *P[2];            /* position at shutter open and close (P[1] == P[0] if static) */
	float *dPdu, *dPdv;     /* derivatives with respect to u and v (the primitive's
				   parameters: for quadrics, u and v as RISpec defines them) */
	float *Ng;              /* geometric normal, dPdu ^ dPdv, oriented by the attributes */
	float *N;               /* shading normal from the "N" primvar, or NULL */
	float *u, *v;           /* surface parameters of each point */
	float du, dv;           /* spacing of u and v between neighbouring points */
	float *s, *t;           /* texture coordinates, or NULL */
	float *Cs, *Os;         /* per-point colour/opacity primvars, or NULL */
	/* Other primitive variables, by name, for shader parameters of that name. */
	struct reyes_grid_var {
		const char *name;
		int type;       /* enum sl_basetype */
		uint32_t arraylen;
		float *data;    /* n points, planar, ncomp * max(1, arraylen) planes */
	} *vars;
	uint32_t nvars;
};

/**
 * Dice @pa into an nu x nv grid (both >= 2), evaluating positions,
 * derivatives, normals and interpolating primitive variables (constant and
 * uniform: one value; varying and facevarying: bilinear over the piece's
 * corners; vertex: as P is interpolated, through the basis for bicubic
 * patches). Returns false only when memory runs out.
 */
bool reyes_patch_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		      struct reyes_grid *g);

/* ---- for the primitives diced in files of their own (geom_*.c) ---- */

/**
 * A bound computed in double as a float box that holds every point diced
 * inside it once rounded to float (padded by a millionth of its largest
 * coordinate); an empty or non-finite range becomes [0, 0], padded.
 */
void reyes_bound_to_float(const double blo[3], const double bhi[3], float lo[3], float hi[3]);

/**
 * The buffers every grid has, for @n points: P (P[1] its own only when
 * @moving, else P[0]), dPdu, dPdv, Ng, u and v. False when memory runs out
 * (what was allocated stays for reyes_grid_finish).
 */
bool reyes_grid_alloc(struct reyes_grid *g, uint32_t n, bool moving);

/** Floats per item of a primitive variable (0 for strings). */
size_t reyes_primvar_stride(const struct reyes_primvar *v);

/**
 * A primitive kind's interpolation of variable @v over a grid's points into
 * @dst (planar, reyes_primvar_stride(v) planes of the grid's n points).
 * False when @v does not fit the primitive: it is then left out of the grid.
 */
typedef bool (*reyes_var_fill)(const void *ctx, const struct reyes_primvar *v, float *dst);

/**
 * The primitive variables of @p on grid @g (g->n points), each through
 * @fill: "N" when @with_N (normalised), "Cs", "Os", "s" and "t" (from "st"
 * where not given alone), and every other variable by name in g->vars,
 * for shader parameters. False when memory ran out (what was filled
 * stays in @g for reyes_grid_finish).
 */
bool reyes_grid_fill_vars(struct reyes_grid *g, const struct reyes_prim *p, bool with_N,
			  reyes_var_fill fill, const void *ctx);

/** Free a grid's buffers. Accepts a zeroed grid. */
void reyes_grid_finish(struct reyes_grid *g);

#endif

/*
 * NuPatch (non-uniform rational B-spline surfaces of any order) and
 * TrimCurve. A NuPatch is cut into one piece per non-empty pair of knot
 * spans inside [umin, umax] x [vmin, vmax]; pieces bound by the hull of
 * their sub-range's Bezier points (blossoms of the span) and dice through
 * the B-spline basis. The surface parameters u, v are the knot parameters
 * (RISpec). A trim curve (an attribute) is a set of closed loops of 2-D
 * rational B-spline curves in (u, v); it is flattened into edges once, and
 * the hider asks per subpixel sample whether the (u, v) it hits is kept.
 */
#ifndef REYES_NURBS_H
#define REYES_NURBS_H

#include "geom.h"

#include <stdbool.h>
#include <stdint.h>

#define REYES_NURBS_MAX_ORDER 32

/** A trim region: flattened loops in (u, v), with a band index for the crossing test. */
struct reyes_trim {
	uint32_t nedges;
	const float *edges;        /* u0 v0 u1 v1 per edge */
	float lo[2], hi[2];        /* bound of the edges */
	/* Kept: an odd number of crossings (RISpec's odd rule), or an even one
	   when the loops run clockwise on the whole (then the region to their
	   left, RISpec's orientation rule, is the outside). */
	bool keep_even;
	uint32_t nbands;           /* bands of equal height in v over [lo[1], hi[1]] */
	const uint32_t *band_off;  /* nbands + 1 offsets into band_edges */
	const uint32_t *band_edges;
};

/** What a REYES_NUPATCH primitive holds beyond its primitive variables. */
struct reyes_nurbs {
	uint32_t nu, nv;           /* control points along u and v */
	uint32_t uorder, vorder;   /* 2 .. REYES_NURBS_MAX_ORDER */
	const float *uknot, *vknot; /* nu + uorder, nv + vorder, non-decreasing */
	float umin, umax, vmin, vmax;
	const float *w;            /* a weight per control point ("Pw"), or NULL: all 1 */
	uint32_t nus, nvs;         /* non-empty spans within the ranges */
	const uint32_t *uspan, *vspan; /* their knot index i (knot[i] < knot[i + 1]) */
	const struct reyes_trim *trim; /* NULL: untrimmed */
};

/** Does @t keep the surface at (u, v)? */
bool reyes_trim_keeps(const struct reyes_trim *t, float u, float v);

/**
 * Check @n's knots, orders and ranges and fill its span lists (arena
 * memory from @alloc). NULL when fine, else what is wrong.
 */
const char *reyes_nurbs_prepare(struct reyes_nurbs *n, void *(*alloc)(void *, size_t),
				void *ctx);

/** Build a trim region from TrimCurve's arrays; NULL when fine, else what is wrong. */
struct reyes_trim_curves {
	uint32_t nloops;
	const uint32_t *ncurves;   /* per loop */
	uint32_t ntotal;           /* sum of ncurves */
	const uint32_t *order, *n; /* per curve */
	const float *knot, *min, *max, *u, *v, *w;
	uint32_t nknots, npoints;  /* lengths of knot and of u, v, w */
};
const char *reyes_trim_build(const struct reyes_trim_curves *c, void *(*alloc)(void *, size_t),
			     void *ctx, const struct reyes_trim **out);

/* geom.c's dispatch for REYES_NUPATCH. */
bool reyes_nurbs_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
			size_t *cap);
void reyes_nurbs_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3]);
bool reyes_nurbs_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		      struct reyes_grid *g);

#endif

/*
 * Curves and Points as pieces (geom_curves.c): what geom.c's entry points
 * call for REYES_CURVES and REYES_POINTS primitives.
 */
#ifndef REYES_GEOM_CURVES_H
#define REYES_GEOM_CURVES_H

#include "geom.h"

#include <stddef.h>

/*
 * The number of pieces of curves or points @p (one per curve segment, one
 * per point) into *count; false, with a message, when its data cannot be
 * diced.
 */
bool reyes_curves_count(const struct reyes_prim *p, size_t *count);

/* As reyes_prim_deforms: points or widths given at close, or an eye that moves. */
bool reyes_curves_deform(const struct reyes_prim *p);

/* As reyes_patch_bound, for a piece of curves or points. */
void reyes_curves_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3]);

/* As reyes_patch_dice, for a piece of curves or points. */
bool reyes_curves_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		       struct reyes_grid *g);

#endif

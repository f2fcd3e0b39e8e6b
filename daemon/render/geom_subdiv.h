/*
 * Subdivision meshes' pieces, bounds and grids (geom_subdiv.c), for geom.c's
 * dispatch: the same contracts as reyes_prim_pieces, reyes_patch_bound and
 * reyes_patch_dice (geom.h) for a REYES_SUBDIV primitive.
 */
#ifndef REYES_GEOM_SUBDIV_H
#define REYES_GEOM_SUBDIV_H

#include "geom.h"

bool reyes_subdiv_pieces(const struct reyes_prim *p, struct reyes_patch **out, size_t *n,
			 size_t *cap);
void reyes_subdiv_bound(const struct reyes_patch *pa, int t, float lo[3], float hi[3]);
bool reyes_subdiv_dice(const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		       struct reyes_grid *g);

/*
 * Can OpenSubdiv make a limit surface of @p's faces and tags? False with the
 * reason in @why (the mesh is built and cached either way).
 */
bool reyes_subdiv_check(const struct reyes_prim *p, char *why, size_t whylen);

/*
 * The limit points of face @face (sub-face @sub) of @p at n normalized
 * (u, v) pairs @uv, positions at shutter open into @P (3 doubles each).
 * False for a hole or a primitive that is not a valid subdivision mesh. For
 * tests that check the renderer against OpenSubdiv's own limit surface.
 */
bool reyes_subdiv_limit(const struct reyes_prim *p, uint32_t face, uint32_t sub, uint32_t n,
			const double *uv, double *P);

#endif

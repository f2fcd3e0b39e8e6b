/*
 * Shadow geometry (lightspeed-2007 §6.1): the scene's surfaces as
 * micropolygons, after displacement, for the GPU runtime to render shadow
 * maps from when a shadow-casting light moves. Diced at a rate of its own
 * (coarser than shading: a shadow map needs less), with no culling against
 * the camera: a caster out of the frame still shadows what is in it.
 */
#ifndef BAKE_SHADOWGEO_H
#define BAKE_SHADOWGEO_H

#include "scene.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/**
 * Micropolygon meshes in world space, one grid after another: a grid of
 * nu x nv points adds its points row by row and its (nu-1)(nv-1)
 * micropolygons. Quads are not oriented (their winding follows the
 * primitive's parameters, not its normal) and may be non-planar or
 * degenerate (at a sphere's poles). A point that came out non-finite is
 * stored as (0, 0, 0) and no micropolygon uses it. The four arrays are
 * malloc'd and belong to the struct (bake_shadow_geometry_free).
 */
struct bake_shadow_geometry {
	float *P;            /* 3 floats per point (x, y, z), world space */
	uint64_t npoints;    /* at most UINT32_MAX */
	uint32_t *quads;     /* 4 point indices per micropolygon, in grid order
				(i, i+1, i+nu+1, i+nu) */
	uint32_t *object;    /* per micropolygon: its primitive's id (reyes_prim.id) */
	float *opacity;      /* per micropolygon: the opacity a deep shadow map sees, in
				[0, 1] (see bake_shadow_geometry) */
	uint64_t nquads;
	uint32_t ngrids;
};

/**
 * Is light @light of @scene a shadow caster's light: does its shader call
 * shadow() with a map name that is not empty? The map argument is read
 * where it comes from: a parameter (its value in the scene, else its
 * default; a default computed at run time counts as a name), a constant,
 * or, when it is computed, any string parameter that is set to a name.
 * False for an index out of range.
 */
bool bake_light_casts_shadows(const struct reyes_scene *scene, uint32_t light);

/**
 * Dice every primitive of @scene that casts shadows (matte ones too; not
 * those with Attribute "visibility" "transmission" off) at @rate (> 0):
 * the largest micropolygon area, in pixels of the scene's camera, as
 * ShadingRate (the primitives' own ShadingRate is not used), for geometry
 * in the view; behind the eye or off the screen, in units of the size a
 * pixel has at its distance from the eye (no nearer than the near clipping
 * plane). Nothing is culled. Displacement shaders run; surfaces are not
 * shaded. Positions are taken at shutter open. One thread.
 *
 * Opacity: a micropolygon's is the grey (mean of the three channels, as
 * the renderer's deep maps take Oi) of its surface's Oi: 1 for a matte
 * primitive or a surface that never sets Oi (the renderer's default), the
 * Opacity attribute or "Os" primitive variable (the mean of its four
 * corners) for one that sets Oi = Os, as the library's surfaces do. A
 * surface that computes Oi otherwise is not shaded for it: its Os is
 * taken, and a warning names the shader's assignment (once per shader).
 * False on
 * failure (a bad rate, out of memory, more than 2^32 - 1 points), reported
 * on @diag (NULL: stderr); @out is then empty.
 */
bool bake_shadow_geometry(const struct reyes_scene *scene, float rate, FILE *diag,
			  struct bake_shadow_geometry *out);

/** Free @g's arrays and zero it (a zeroed struct is fine). */
void bake_shadow_geometry_free(struct bake_shadow_geometry *g);

#endif

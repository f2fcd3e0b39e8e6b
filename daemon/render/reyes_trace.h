/*
 * Ray tracing in the REYES renderer (reyes_trace.c): the scene rays see,
 * built on a frame's first ray, and the host calls the shading language's
 * ray-tracing built-ins reach (struct sl_host's trace and rayinfo).
 * Private to daemon/render.
 */
#ifndef REYES_TRACE_H
#define REYES_TRACE_H

#include "reyes_impl.h"

/** Cast @q's rays from a grid @t shades (exec.h's contract). False on a failure (said). */
bool reyes_rt_trace(struct tctx *t, struct sl_ray_query *q);

/** rayinfo() for what @t shades: depth, type, speculardepth, diffusedepth, origin, direction, length. */
bool reyes_rt_rayinfo(struct tctx *t, const char *name, int type, int arraylen, float *out,
		      const char **sout);

/** Free the scene rays saw (NULL is fine). */
void reyes_rt_destroy(struct reyes_rt *rt);

/** Free the contexts that shaded @t's hits, adding their rays to @t's. */
void reyes_rt_free_sub(struct tctx *t);

/** Memory the rays' scene holds (grids kept for shading, Embree's buffers), its micropolygons. */
uint64_t reyes_rt_bytes(const struct reyes_rt *rt);
uint64_t reyes_rt_micropolygons(const struct reyes_rt *rt);

#endif

/*
 * A ready-made struct sl_host that offers a list of light shader executors to
 * a surface shader: illuminance, lightsource() and light categories work
 * through it. Used by the tests and the CPU renderer.
 */
#ifndef SL_LIGHTHOST_H
#define SL_LIGHTHOST_H

#include "exec.h"

/**
 * Lights for a shaded surface. Fill it with sl_lighthost_init(), then set the
 * optional fields; pass &lh->host to sl_exec_run(). Further callbacks of
 * .host (texture, attribute, ...) may be set after init. Nothing is owned:
 * the light executors, names, matrices and categories must outlive their use.
 */
struct sl_lighthost {
	struct sl_host host;            /* .user points back at this struct */
	struct sl_exec **lights;        /* executors of light shaders */
	int nlights;
	/* Optional coordinate systems for host.space: matrix taking each named space to
	 * "current" (row vectors, p' = p M). */
	const char *const *space_names;
	const float (*space_mats)[16];
	int nspaces;
	/* Optional per-light categories, used for lights without a __category parameter. */
	const char *const *categories;
	/*
	 * Optional per-light "shader" space (that light's coordinate system to
	 * "current"), answered for "shader" while that light runs.
	 */
	const float (*light_shader_mats)[16];
	/* Free for the code that embeds the light host (its own callbacks reach it here). */
	void *owner;
	/* Private: the light being run, or -1. */
	int running;
};

/**
 * Set up @lh over @nlights light executors (@lights may be NULL when
 * @nlights is 0). Each light is run on demand, on the surface's grid shape,
 * with Ps and Ns (the normal the surface evaluates the lights with, see
 * struct sl_host) and E, time and dtime (when both shaders have them) copied from
 * the surface; it therefore needs at least as many points as the surface grid
 * (else it is left out, with a warning). A surface running on derivative
 * stencils (sl_exec_set_stencil) passes its stencil to every light it runs.
 */
void sl_lighthost_init(struct sl_lighthost *lh, struct sl_exec **lights, int nlights);

#endif

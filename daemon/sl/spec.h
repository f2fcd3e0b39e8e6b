/*
 * Specialization (lightspeed-2007 §3.1): with respect to a set of dynamic
 * parameters (every light parameter, plus the surface parameters a user
 * marks editable), split a surface shader into a static part, computed once
 * and cached per shading sample, and a dynamic part recomputed for every
 * edit. One dependence graph answers both questions: an instruction is
 * dynamic iff it depends on a dynamic parameter or on the lights; it is live
 * iff it reaches an output (Ci, Oi, output parameters, side effects).
 */
#ifndef SL_SPEC_H
#define SL_SPEC_H

#include "glsl.h"

struct sl_spec {
	const struct sl_program *prog;
	uint8_t *dynamic;        /* per instruction */
	uint8_t *live;           /* per instruction */
	uint8_t *reg_dynamic;    /* per register */
	/* The static values the dynamic part reads: the caching program's
	 * outputs and the dynamic program's inputs, in this order. */
	int32_t *cached;
	uint32_t ncached;
	/* Instructions the GPU cannot run whose results are light-dependent
	 * (computed at bake time anyway; a warning, an error with --strict). */
	uint32_t *cache_required;
	uint32_t ncache_required;
	uint32_t nstatic, ndynamic, ndead; /* instruction counts */
	/* The dynamic part as a slice for sl_glsl_emit (keep = live & dynamic,
	 * plus enclosing blocks; inputs = cached; outputs = Ci, Oi and output
	 * parameters). */
	struct sl_slice slice;
	uint8_t *keep;
	int32_t *outputs;
	/* The caching program: the live static instructions, with dynamic
	 * branch conditions dropped so both sides of such a branch run. Owned. */
	struct sl_program *caching;
};

/**
 * Specialize @prog (a surface shader) for the parameters named in
 * @dynamic_params (unknown names: an error on @diag). NULL on errors.
 */
struct sl_spec *sl_specialize(const struct sl_program *prog, const char *const *dynamic_params,
			      size_t ndynamic, FILE *diag);
void sl_spec_destroy(struct sl_spec *s);

/**
 * JSON object members describing the specialization (for relight compile's
 * report): dynamic_params, cached_channels (name, type, components),
 * cached_scalars, cache_required, static/dynamic/dead instruction counts and
 * glsl_lines (null when @glsl_lines < 0). free() the result.
 */
char *sl_spec_report_fields(const struct sl_spec *s, const char *const *dynamic_params,
			    size_t ndynamic, long glsl_lines);

#endif

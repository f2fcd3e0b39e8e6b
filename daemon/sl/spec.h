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

#include "exec.h"
#include "glsl.h"

struct sl_spec {
	const struct sl_program *prog;
	uint8_t *insn_dynamic;   /* per instruction */
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
	/*
	 * The dynamic program: what the GLSL of the slice computes, for the
	 * interpreter (the CPU reference of the GPU runtime). Owned. It has
	 * the kept instructions (keep), reads every cached value from the
	 * cache instead of computing it, and writes Ci, Oi and the dynamic
	 * output parameters.
	 *
	 * Its registers are numbered as @prog's. sl_spec_bind_cache() or
	 * sl_spec_copy_cache() sets the grid to n x 1 (samples in any order,
	 * from any grids: nothing reads a neighbour; derivatives of static
	 * values are cached, those taken through cached values in the dynamic
	 * code, such as a light's shadow() of Ps, run on derivative stencils:
	 * cached_deriv, sl_exec_set_stencil),
	 * holds the cached registers (sl_exec_hold) and writes their values.
	 * The globals the kept code reads (P, N, I, s, t, Cs, Os, and E and
	 * time when lights run) are cached values like the others; a global
	 * only a parameter default reads is set with sl_exec_global(). Every
	 * cached number is varying here, so samples whose uniform values
	 * differ (du, E of different grids) run together; if the code needs
	 * one uniform (a texture channel), none is made varying and uniform
	 * cached values come from the first sample (dynamic->regs[r].varying
	 * tells).
	 *
	 * Parameters are bound by name as for @prog: dynamic ones with their
	 * new values, the others as at bake time (cached parameters ignore
	 * what is set). Defaults of parameters that are not cached run as in
	 * @prog (one that reads a cached parameter sees its cached, final
	 * value). Lights run whole through the light host, as for @prog.
	 */
	struct sl_program *dynamic;
	/*
	 * Per cached value (s->cached order): the dynamic part takes a
	 * derivative through it (Du, Dv, Deriv, area, calculatenormal, a
	 * texture filter region, ... of a value computed from it), so a shot
	 * keeps its steps along u and v with it and the dynamic program runs on
	 * derivative stencils (sl_exec_set_stencil). With
	 * SL_SPEC_LIGHT_DERIVATIVES the surface position P that lights see as
	 * Ps counts too.
	 */
	uint8_t *cached_deriv;
	bool needs_stencil;      /* some cached_deriv is set */
};

/**
 * Specialize @prog (a surface shader) for the parameters named in
 * @dynamic_params (unknown names: an error on @diag). NULL on errors.
 */
struct sl_spec *sl_specialize(const struct sl_program *prog, const char *const *dynamic_params,
			      size_t ndynamic, FILE *diag);

/** Flags of sl_specialize_ex. */
enum {
	/*
	 * Cache the uniform parameters the dynamic part reads (by default they
	 * stay uniforms, set per shader instance): for a shot, whose samples
	 * come from many instances with their own values, one dispatch per
	 * surface shader needs them per sample.
	 */
	SL_SPEC_CACHE_PARAMS = 1,
	/*
	 * The lights take derivatives of Ps (shadow(), texture() in a light,
	 * see sl_program_takes_derivatives): mark the cached P the lights get
	 * in cached_deriv.
	 */
	SL_SPEC_LIGHT_DERIVATIVES = 2,
};

/**
 * Does @prog take derivatives of a varying value anywhere (Du, Dv, Deriv,
 * area, calculatenormal, texture/environment/shadow filter regions,
 * filterstep widths)? A light shader that does needs Ps's derivatives.
 */
bool sl_program_takes_derivatives(const struct sl_program *prog);

/**
 * The values whose derivatives call @in takes, as the interpreter does: the
 * operand of Du, Dv, area and calculatenormal, both of Deriv, filterstep's
 * s1 when no s2 gives the width, and the coordinates a texture, environment
 * or shadow lookup of a map builds its filter region around. Writes up to
 * 2 registers to @r and returns how many.
 */
int sl_spec_deriv_operands(const struct sl_program *prog, const struct sl_insn *in, int32_t r[2]);

/** sl_specialize with @flags (SL_SPEC_*). */
struct sl_spec *sl_specialize_ex(const struct sl_program *prog, const char *const *dynamic_params,
				 size_t ndynamic, unsigned flags, FILE *diag);

void sl_spec_destroy(struct sl_spec *s);

/**
 * The cache as packed records: fills @offset (s->ncached entries, may be
 * NULL) with each cached value's first float in a sample's record, in
 * s->cached order, and returns the floats per sample. A value has
 * ncomp * max(1, arraylen) floats, components of an element consecutive;
 * strings take none (they are set with sl_exec_reg_strings()).
 */
uint32_t sl_spec_cache_layout(const struct sl_spec *s, uint32_t *offset);

/**
 * Prepare @x, an executor of s->dynamic, to run over @n samples whose
 * cached values are @records: sample i's value k at records[i * stride +
 * offset[k]] (@offset NULL: the packed layout of sl_spec_cache_layout();
 * sl_glsl_layout's in_offset and in_stride also fit). Sets the grid to
 * n x 1 and holds every cached register. Cached strings keep what the
 * caller wrote with sl_exec_reg_strings() (they must outlive the run).
 * False (message on stderr) if @x is not s->dynamic's, @n does not fit or
 * a value lies outside the records.
 */
bool sl_spec_bind_cache(const struct sl_spec *s, struct sl_exec *x, uint32_t n,
			const float *records, uint32_t stride, const uint32_t *offset);

/**
 * The same from @from, an executor of s->caching (or of s->prog) after its
 * run: dynamic sample j takes the cached values of @from's point order[j]
 * (@order NULL: point j). Strings are shared with @from: valid until its
 * next run. False (message on stderr) on a wrong executor or sample.
 */
bool sl_spec_copy_cache(const struct sl_spec *s, struct sl_exec *x, const struct sl_exec *from,
			const uint32_t *order, uint32_t n);

/**
 * JSON object members describing the specialization (for relight compile's
 * report): dynamic_params, cached_channels (name, type, components),
 * cached_scalars, cache_required, static/dynamic/dead instruction counts and
 * glsl_lines (null when @glsl_lines < 0). free() the result.
 */
char *sl_spec_report_fields(const struct sl_spec *s, const char *const *dynamic_params,
			    size_t ndynamic, long glsl_lines);

#endif

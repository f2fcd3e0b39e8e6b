/*
 * GLSL generation: the IR of a shader (or the part of it a specialization
 * keeps) as a GLSL 4.30 compute shader running one shading sample per
 * invocation, with the scene's light shaders translated whole. Parameters
 * are uniforms, so an edit never recompiles: only structure is in the
 * source.
 */
#ifndef SL_GLSL_H
#define SL_GLSL_H

#include "ir.h"
#include "mathlib.h"

#include <stdio.h>

/** The part of a program to emit, and where its data comes from. */
/** Bumped whenever the generated code changes for the same input. */
#define SL_GLSL_GENERATOR_VERSION 6

struct sl_slice {
	const struct sl_program *prog;
	/* Per instruction: 1 to emit it. NULL: every instruction. Block openers
	 * and closers of emitted instructions are kept by the caller. */
	const uint8_t *keep;
	/* Registers read per sample from the input buffer (cached values and
	 * the globals the kept code reads), in this order. */
	const int32_t *inputs;
	uint32_t ninputs;
	/* Registers written per sample to the output buffer, in this order. */
	const int32_t *outputs;
	uint32_t noutputs;
	/*
	 * Derivative stencils (spec.h cached_deriv). Per input (NULL: none):
	 * 1 when each sample's record also holds the input's change over one
	 * grid step along u and along v (a shot's uKKK.CC / vKKK.CC channels),
	 * and then the record holds the grid's steps du and dv too. Derivatives
	 * (Du, Dv, Deriv, area, calculatenormal, filter regions of texture(),
	 * environment(), shadow(), filterstep()) of values computed from such
	 * inputs are taken as the interpreter does on a stencil
	 * (sl_exec_set_stencil): what they are computed from is evaluated again
	 * on the inputs moved one step along u and along v, in the same
	 * invocation. A light's Ps is the surface position it is called with.
	 * A moved input is the input plus its step (one float add, as the
	 * interpreter's moved blocks are made); the moved copies follow the
	 * sample's control flow. The derivative of a value that depends on
	 * per-sample data without steps (an input without them, a light's
	 * result, a texture) is an error; one of a value the same for all
	 * samples is 0. NULL: no derivatives (an error, as before) and shadow()
	 * as texture() below.
	 */
	const uint8_t *input_steps;
	/*
	 * Lights' shadow() sites whose map is a string parameter (or the
	 * constant "raytrace") carry the ray-traced lookup as well (struct
	 * sl_glsl_shadow_site's raytrace): for shots some light of which traces
	 * its shadows; the lookup costs compile time in every such kernel.
	 */
	bool raytrace_shadows;
	/*
	 * One pass per light: the slice runs once for each light alone, as
	 * the kernel with that light only would, all passes in the same
	 * invocation on the inputs read once (the compiler merges the
	 * fetches and whatever does not depend on the light). Pass k writes
	 * its outputs at ((sample - u_first) * nlights + k) * out_stride,
	 * or, with @sink, hands them to the caller's code instead.
	 * False: one run with every light, outputs at sample * out_stride.
	 */
	bool per_light;
	/*
	 * With per_light and a single output of three floats: GLSL defining
	 * void rl_sink(uint sample, uint k, vec3 v), called with pass k's
	 * output, and void rl_sink_end(uint sample), called after the last
	 * pass. It may use texture units 1 and SSBO bindings from 2 on, and
	 * its own uniforms. NULL: outputs go to the buffer.
	 */
	const char *sink;
	/* The highlight of specular() and specularbrdf(), as the interpreter's
	 * host says it (struct sl_host); zero is PRMan's. */
	enum sl_specular_model specular_model;
};

/* A shadow() call of the generated code (with input_steps): which map it
 * reads is chosen when the kernel runs (see sl_glsl_emit). */
struct sl_glsl_shadow_site {
	int light;                 /* the light (0 .. nlights - 1) whose code calls it; -1: the slice */
	const char *param;         /* the string parameter of that shader naming the map, or NULL */
	const char *name;          /* with no @param: the constant map name */
	/*
	 * The site is in a light and its map may be named "raytrace": the
	 * uniform int "u_shadow<k>_rt", when not 0, makes it a ray-traced
	 * shadow through the shadow geometry's hierarchy (sl_glsl_bvh_source,
	 * at the layout's bvh_unit), its start moved by the shadow()'s "bias"
	 * or else the uniform float "u_trace_bias".
	 */
	bool raytrace;
};

/** The texture unit of shadow() site 0; site k uses SL_GLSL_SHADOW_UNIT0 + k. */
#define SL_GLSL_SHADOW_UNIT0 2

enum sl_glsl_map_kind { SL_GLSL_MAP_TEXTURE, SL_GLSL_MAP_ENVIRONMENT };

/* A texture() or environment() call of a named map in the generated code
 * (with input_steps): which map it reads is chosen when the kernel runs. */
struct sl_glsl_map_site {
	int light;                 /* the light whose code calls it; -1: the slice */
	const char *param;         /* the string parameter of that shader naming the map, or NULL */
	const char *name;          /* with no @param: the constant map name */
	enum sl_glsl_map_kind kind;
};

/** Where each input and output lives in the buffers, in floats. */
struct sl_glsl_layout {
	uint32_t in_stride;    /* floats per sample in the input buffer */
	uint32_t out_stride;   /* floats per sample in the output buffer */
	uint32_t *in_offset;   /* per input: its first float (components consecutive) */
	uint32_t *out_offset;  /* per output */
	/* String constants and string parameters become token ids (floats):
	 * strings[id] is the string of token id. */
	const char **strings;
	uint32_t nstrings;
	/* With input_steps: per input, the first float of its u step and of its
	 * v step (UINT32_MAX for an input without steps); where du and dv are
	 * (UINT32_MAX when no input has steps). The steps follow the plain
	 * inputs, input by input (u step, then v step, each as many floats as
	 * the input), then du and dv, the record's last two floats. */
	uint32_t *in_step_u, *in_step_v;
	uint32_t du_offset, dv_offset;
	/* The shadow() call sites, in the order of their uniforms (with
	 * input_steps only; one block the layout owns). */
	struct sl_glsl_shadow_site *shadows;
	uint32_t nshadows;
	/* The texture() and environment() sites of named maps (with
	 * input_steps only; one block the layout owns). Site k reads the
	 * samplerBuffer "u_map<k>", bound to texture unit
	 * SL_GLSL_SHADOW_UNIT0 + nshadows + k by its sampler uniform. */
	struct sl_glsl_map_site *maps;
	uint32_t nmaps;
	/* With a raytrace site: the texture unit of the hierarchy's nodes
	 * ("u_bvh_nodes"; its triangles at + 1, "u_bvh_tris", and its cast
	 * flags at + 2, "u_bvh_casts"), after the maps'. 0: none. */
	uint32_t bvh_unit;
};

/**
 * Emit a compute shader for @s with @nlights light shaders (their count and
 * order are fixed in the source; each light's parameters are uniforms
 * "l<k>_NAME" and its "shader" space is the uniform mat4 "l<k>_shader",
 * shader -> current). The slice's own parameters that are not inputs are
 * uniforms "p_NAME"; a coordinate system named in the code is the uniform
 * mat4 "space_NAME" (NAME -> current). Inputs come from samplerBuffer u_in
 * (texture unit 0) bound as RGBA32F texels (gpu.h: gpu_binding.rgba), float
 * sample * in_stride + offset (in_stride is a multiple of 4); outputs go to the SSBO at binding 1
 * at sample * out_stride. The sample is the uniform int u_first (0 unless
 * set) plus the invocation index as gpu.h's gpu_dispatch() describes, which
 * the uniform int u_count bounds: a dispatch of n runs samples
 * [u_first, u_first + n).
 * With input_steps, shadow() site k reads the depth map bound as
 * samplerBuffer "u_shadow<k>" (texture unit SL_GLSL_SHADOW_UNIT0 + k;
 * width * height depths, row-major) with the uniforms int
 * "u_shadow<k>_size[2]" (width, height; 0 x 0: no map, the lookup gives
 * what a missing file gives, the "fill" option), mat4 "u_shadow<k>_to_camera"
 * (world -> the map's camera), mat4 "u_shadow<k>_to_ndc" (world -> the map's
 * NDC) and float "u_shadow<k>_bias" (the map's own bias, used when the call
 * gives none); the uniform mat4 "u_to_world" takes current space to world
 * (gpu/shadowmap.h gpu_shadow_map_bind sets them all). The filter, its
 * samples and their jitter are the renderer's (render/texture.c
 * reyes_tex_shadow), in the same arithmetic. The constant empty name is the
 * fill, with no site. With input_steps, texture() and environment() of a
 * map named by a string parameter or a constant read map site k's
 * samplerBuffer "u_map<k>" (one R32F buffer: a header with the level table
 * and wrap modes, then every level, row-major, channels interleaved, as
 * glsl_texmap.c says and gpu/texmap.c writes; a buffer of zeros is no map,
 * the fill), filtered as render/texture.c filters; so do a light's
 * texture() of four s, t corners and environment() of four directions
 * without input_steps. Otherwise, without input_steps, they read no file: a
 * name known only at run time gives the fill (a warning), a constant one is
 * an error; shadow() is treated the same way. A space a light's transform
 * names by its string parameter P is the uniform mat4 sl_glsl_space_uniform()
 * names (that space -> current).
 * Every built-in the code uses is emitted with the interpreter's numerics.
 * Returns the source (free() it) and fills @layout (free with
 * sl_glsl_layout_finish), or NULL with "FILE:LINE:COL: error: ..." on @diag
 * for what the GPU cannot run (texture files, derivatives without
 * stencils...).
 */
char *sl_glsl_emit(const struct sl_slice *s, const struct sl_program *const *lights,
		   uint32_t nlights, struct sl_glsl_layout *layout, FILE *diag);

void sl_glsl_layout_finish(struct sl_glsl_layout *layout);

/** Globals an imager kernel may read, at most. */
#define SL_GLSL_IMAGER_INPUTS 7

/**
 * The kernel of imager shader @im (the GPU runtime's imager pass): the
 * whole program, one pixel per invocation, no lights, its parameters
 * uniforms "p_NAME". Its inputs are those of Ci, Oi, alpha, P, ncomps, time
 * and dtime the program has, in that order: @globals receives them
 * (SL_GLSL_IMAGER_INPUTS at most) and *@nin their count; its outputs are Ci
 * and alpha. Otherwise as sl_glsl_emit.
 */
char *sl_glsl_emit_imager(const struct sl_program *im, enum sl_global *globals, uint32_t *nin,
			  struct sl_glsl_layout *layout, FILE *diag);

/**
 * The name of the uniform holding parameter @name of light @light (0, 1, ...
 * in the order given to sl_glsl_emit) or, with @light < 0, of the surface:
 * "l0_intensity", "p_Kd". GLSL reserves every name containing "__", so a
 * parameter whose uniform would contain one ("__category", "_x") is written
 * with 'U' for the separator and each '_' as "_0": "l0U_0_0category".
 * The two forms never meet, and neither contains "__".
 */
void sl_glsl_param_uniform(char *out, size_t cap, int light, const char *name);
/**
 * The uniform mat4 that holds, for light @light, the space its string
 * parameter @param names when a transform names the space by it: that space
 * -> current. "l<k>S" and the name with each character but letters and
 * digits as "_%02x" (hex): no parameter's uniform has that form.
 */
void sl_glsl_space_uniform(char *out, size_t cap, int light, const char *param);

/*
 * Ray-traced shadows. sl_glsl_bvh_source is GLSL defining
 *   float rl_bvh_transmission(samplerBuffer nodes, samplerBuffer tris,
 *                             samplerBuffer casts, vec3 org, vec3 dir, float tmax)
 * the light that gets through the shadow geometry along org + t dir for t in
 * (0, tmax) (t in units of dir, which need not be normalized): the product
 * of 1 - opacity over the triangles hit there whose object casts. The
 * layout it reads (gpu/shadowbvh.c writes it), all RGBA32F texels but casts
 * (R32F), indices as their value plus 0x00800000 in a float's bits:
 *   nodes: two texels a node, depth first from the root (node 0), a node's
 *     first child right after it: (lower x, y, z, a), (upper x, y, z,
 *     count); count 0: an inner node whose second child is node a; else a
 *     leaf of triangles a .. a + count - 1.
 *   tris: three texels a triangle: (v0, object slot), (v1 - v0, opacity),
 *     (v2 - v0, 0), world space.
 *   casts: per object slot, 0 where the object casts no shadow.
 * An empty nodes buffer lets all light through.
 */
extern const char sl_glsl_bvh_source[];

#endif

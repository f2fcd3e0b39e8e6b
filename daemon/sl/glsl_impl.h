/*
 * Internals of the GLSL generator shared by its core (glsl.c: sections,
 * names, control flow, lights) and its built-in library (glsl_builtins.c).
 */
#ifndef SL_GLSL_IMPL_H
#define SL_GLSL_IMPL_H

#include "glsl.h"
#include "builtin.h"
#include "../common/arena.h"
#include "../common/strbuf.h"

#include <stdbool.h>
#include <stdint.h>

/* Hand-written GLSL functions, emitted once each when some code needs them. */
enum glsl_helper {
	GH_CORE,        /* rl_c, rl_fin, rl_div, rl_fill */
	GH_MATDIV,      /* matrix / matrix */
	GH_INVERSE,     /* Gauss-Jordan inverse */
	GH_XFORM,       /* point, vector and normal transforms */
	GH_AIDX,        /* array index clamping */
	GH_CIDX,        /* comp()/setcomp() index clamping */
	GH_VEC,         /* length, normalize */
	GH_MATH,        /* the componentwise math library */
	GH_NOISE,       /* noise, pnoise, cellnoise */
	GH_GEOM,        /* ptlined, faceforward, reflect, refract, rotation */
	GH_FRESNEL,
	GH_SPECBRDF,
	GH_CONE,        /* illuminance cone test */
	GH_COLOR,       /* ctransform */
	GH_SPLINE,      /* spline bases */
	GH_FILTERSTEP,
	GH_DERIV,       /* derivative stencils: corners, area, normals, filterstep widths */
	GH_SHADOW,      /* shadow(): the renderer's depth map filter */
	GH_TEXMAP,      /* texture(), environment() of named maps (glsl_texmap.c) */
	GH_RTSHADOW,    /* shadow("raytrace"): the shadow geometry's hierarchy (glsl_bvh.c) */
	GH_COUNT
};

/* Generated functions that loop over the lights: ambient(), diffuse(), ... */
enum glsl_lighting { GL_AMBIENT, GL_DIFFUSE, GL_SPECULAR, GL_PHONG, GL_COUNT };

/* Sections of the generated source, in output order. */
enum glsl_section {
	GS_PRELUDE,     /* version, layout, buffers, built-in uniforms */
	GS_UNIFORMS,    /* parameters and coordinate systems */
	GS_GLOBALS,     /* registers and control-flow flags (per invocation) */
	GS_HELPERS,     /* hand-written functions */
	GS_GENERATED,   /* spline instances */
	GS_LIGHTS,      /* light_k() */
	GS_LIGHTING,    /* ambient(), diffuse(), specular(), phong() over the lights */
	GS_MAIN,
	GS_COUNT
};

/*
 * What a value's derivatives can be taken from on derivative stencils
 * (slice->input_steps): GC_STEP, it changes with inputs that have steps (its
 * copies moved one step along u and v can be computed); GC_OPAQUE, it
 * changes per sample in a way that cannot be followed (inputs without steps,
 * lights, textures). Neither: it is the same for every sample.
 */
enum { GC_STEP = 1, GC_OPAQUE = 2 };

/* Per emitted program (the surface slice, or one light): its names and analyses. */
struct glsl_prog {
	const struct sl_program *prog;
	int light;               /* -1 for the surface, else the light's index */
	const char **name;       /* per register: its GLSL name (constants: NULL) */
	const char **cstr;       /* per register: its string when known at compile time */
	int32_t *target;         /* per instruction: the construct a break/continue/return leaves */
	uint32_t *exit_lo, *exit_hi; /* per construct: the range of its exits' instructions */
	uint8_t *exits;          /* per construct: 1 break, 2 continue, 4 return (bits) */
	uint32_t *loopcont;      /* per LOOP: its LOOPCONT, or UINT32_MAX */
	uint8_t *declared;       /* per instruction: its variables declared (bits) */
	bool static_ambient;     /* a light without illuminate or solar */
	/* Derivative stencils (NULL without input_steps). */
	uint8_t *cls;            /* per register: GC_* bits */
	uint8_t *need;           /* per register: kept with copies moved along u and v */
	uint8_t *mdecl;          /* per register: moved copies declared (bit 1 u, bit 2 v) */
	uint8_t *decl;           /* per register: declared (the temporaries the code names) */
	int32_t *copy_of;        /* per register: the one register a MOV copies into it, or -1 */
	int32_t *site;           /* per instruction: its shadow() site, or -1 */
	int32_t *msite;          /* per instruction: its texture() / environment() site, or -1 */
	bool moved_ps;           /* a light called with Ps moved along u and v too */
};

struct glsl_gen {
	const struct sl_slice *slice;
	const struct sl_program *surf;
	const struct sl_program *const *lights;
	uint32_t nlights;
	FILE *diag;
	bool failed;
	struct rl_arena *arena;           /* names and expressions of this emit */
	struct rl_strbuf sec[GS_COUNT];
	struct rl_strbuf *out;            /* the section code is going to */
	int indent;
	bool need[GH_COUNT];
	bool lighting[GL_COUNT];
	RL_VEC(const char *) strings;     /* the string table: id -> string */
	uint32_t *shash;                  /* open hash of the table: id + 1, 0 free */
	size_t shcap;
	RL_VEC(uint32_t) spaces;          /* string ids of coordinate systems with a uniform */
	RL_VEC(uint8_t) space_on;         /* per string id: in spaces */
	RL_VEC(uint64_t) splines;         /* instantiated spline functions (kind, count) */

	struct glsl_prog sp;              /* the surface */
	struct glsl_prog *lp;             /* per light */
	struct glsl_prog *cur;            /* the program being emitted */
	int cur_light;                    /* the light an illuminance body is emitted for, or -1 */
	int32_t *stack;                   /* constructs open around the code being emitted */
	uint32_t nstack, maxstack;
	/* Derivative stencils and shadow maps. */
	bool stencil;                     /* the slice has input_steps */
	int moved;                        /* emitting the copy moved along u (1) or v (2); 0 */
	bool any_moved_ps;                /* some light takes Ps moved */
	RL_VEC(struct sl_glsl_shadow_site) sites;
	RL_VEC(struct sl_glsl_map_site) msites;
};

/** GH_TEXMAP's text: the renderer's texture and environment filters (glsl_texmap.c). */
extern const char sl_glsl_texmap_src[];

/** Report "FILE:LINE:COL: error: ..." at instruction @in of the current program. */
void sl_glsl_error(struct glsl_gen *g, const struct sl_insn *in, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
void sl_glsl_warning(struct glsl_gen *g, const struct sl_insn *in, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/** Append one indented line of code to the current section. */
void sl_glsl_line(struct glsl_gen *g, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/**
 * Register @r of the current program as an expression of @want components:
 * 0 as it is, 1 float, 3 vec3 (floats broadcast), 16 mat4 (a float on the
 * diagonal), -16 mat4 (a float in every element). Strings are float ids.
 */
const char *sl_glsl_op(struct glsl_gen *g, int32_t r, int want);
/** Register @r as an assignable name (NULL for a constant: the caller reports). */
const char *sl_glsl_lv(struct glsl_gen *g, int32_t r);
/** An expression string printed into the emitter's arena. */
#define SL_GLSL_FMT(g, ...) rl_arena_printf((g)->arena, __VA_ARGS__)

/** A float literal that reads back as exactly @v. */
const char *sl_glsl_float(struct glsl_gen *g, float v);
/** The compile-time string in @r, or NULL. */
const char *sl_glsl_cstr(struct glsl_gen *g, int32_t r);
/** Token id of string @s (added to the table). */
uint32_t sl_glsl_string_id(struct glsl_gen *g, const char *s);
/** Matrix expression of coordinate system @name to "current" (NULL: identity). */
const char *sl_glsl_space(struct glsl_gen *g, const struct sl_insn *in, const char *name);

void sl_glsl_need(struct glsl_gen *g, enum glsl_helper h);
/** Name of the spline function for @nvals values of @ncomp (1 or 3) components. */
const char *sl_glsl_spline_fn(struct glsl_gen *g, int nvals, int ncomp);

/** Emit a CALL instruction (glsl_builtins.c). */
void sl_glsl_call(struct glsl_gen *g, const struct sl_insn *in);
/** Append the hand-written functions marked needed, dependencies first. */
void sl_glsl_emit_helpers(struct glsl_gen *g);
/** Append the generated spline function for (@nvals, @ncomp). */
void sl_glsl_emit_spline(struct glsl_gen *g, int nvals, int ncomp);
/** Append the lighting function @which over the lights. */
void sl_glsl_emit_lighting(struct glsl_gen *g, enum glsl_lighting which);

/** GC_* bits of register @r of the current program (0 without stencils). */
int sl_glsl_class(const struct glsl_gen *g, int32_t r);
/**
 * Register @r of the current program moved one grid step along u (@dir 1)
 * or v (2), as an expression of @want components (sl_glsl_op): its moved
 * copy when it has one, else its own value (a value the same for all samples).
 */
const char *sl_glsl_moved(struct glsl_gen *g, int32_t r, int want, int dir);
/** The site index of shadow() CALL @in of the current program, adding it (-1 on errors). */
int sl_glsl_shadow_site(struct glsl_gen *g, const struct sl_insn *in);

/** The map site index of texture() or environment() CALL @in (@kind), adding it (-1 on errors). */
int sl_glsl_map_site(struct glsl_gen *g, const struct sl_insn *in, enum sl_glsl_map_kind kind);
/* The string parameter register @r holds (through copies), or NULL. */
const char *sl_glsl_string_param(struct glsl_gen *g, int32_t r);
/* The uniform mat4 of the space a light's string parameter @param names
 * (that space -> current), declared on first use; the runtime binds it. */
const char *sl_glsl_space_param(struct glsl_gen *g, const char *param);

/** Floats per element of register @r (strings: 1, a token id). */
int sl_glsl_ncomp(const struct sl_program *prog, int32_t r);

#endif

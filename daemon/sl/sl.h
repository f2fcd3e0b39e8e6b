/*
 * relight's RenderMan Shading Language front end: compile a shader to a
 * typed IR (struct sl_program), inspect it, and run it on grids of points
 * with the grid interpreter (exec.h).
 */
#ifndef SL_H
#define SL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

/** Options for one compilation. Zero-initialized options are valid. */
struct sl_options {
	/** Directories searched by #include "x" after the including file's own. */
	const char *const *include_dirs;
	size_t n_include_dirs;
	/** -D definitions: "NAME" (defined as 1) or "NAME=VALUE". */
	const char *const *defines;
	size_t n_defines;
	/** Where diagnostics go; NULL means stderr. */
	FILE *diag;
	/** Stop after this many errors; 0 means 20. */
	int max_errors;
};

enum sl_shader_kind {
	SL_SHADER_SURFACE,
	SL_SHADER_LIGHT,
	SL_SHADER_DISPLACEMENT,
	SL_SHADER_VOLUME,
	SL_SHADER_IMAGER,
};

/** A compiled shader: its IR, parameters and metadata. Immutable once built. */
struct sl_program;

/**
 * Compile the shader in the file at @path. Diagnostics go to opts->diag as
 * "FILE:LINE:COL: error: MESSAGE". Returns NULL when there were errors.
 * The file must define exactly one shader (plus any functions).
 */
struct sl_program *sl_compile_file(const char *path, const struct sl_options *opts);

/** Same as sl_compile_file() for source held in memory; @name is used in diagnostics. */
struct sl_program *sl_compile_string(const char *name, const char *src, size_t len,
				     const struct sl_options *opts);

/**
 * The name of the shader that the source @src of file @path declares: the
 * identifier after its shader kind (surface, light, ...) as the
 * preprocessor leaves it, so that a name made by a macro counts. Includes
 * are looked up as sl_compile_file() does; nothing is reported. Returns a
 * malloc'd name, or NULL when no shader is declared.
 */
char *sl_declared_name(const char *path, const char *src, size_t len,
		       const struct sl_options *opts);

/** Free a program. Accepts NULL. */
void sl_program_destroy(struct sl_program *prog);

/**
 * The surface shader @surf followed, on every shading sample, by the volume
 * shader @atm as its atmosphere (RISpec: the atmosphere reads and changes the
 * surface's Ci and Oi; its P and I are the surface's): one surface program,
 * named "SURFACE+ATMOSPHERE", with the surface's parameters then the
 * atmosphere's. An atmosphere parameter whose name the surface has too is
 * renamed SL_ATMOSPHERE_PREFIX + name. @surf and @atm must outlive the
 * result. NULL when @surf is no surface or @atm no volume shader.
 */
struct sl_program *sl_program_compose(const struct sl_program *surf,
				      const struct sl_program *atm);
#define SL_ATMOSPHERE_PREFIX "atmosphere_"

/** Make the joined program @joined destroy its two parts when it is destroyed. */
void sl_program_own_parts(struct sl_program *joined);

/** The atmosphere a program of sl_program_compose() runs (NULL: none), and its surface. */
const struct sl_program *sl_program_atmosphere(const struct sl_program *prog);
const struct sl_program *sl_program_surface_part(const struct sl_program *prog);

/** What to print with sl_emit(). */
enum sl_emit_kind {
	SL_EMIT_AST,    /* the parsed tree, one node a line */
	SL_EMIT_IR,     /* the IR, one instruction a line */
	SL_EMIT_REPORT, /* JSON: name, type, parameters, instruction counts */
};

/**
 * Parse only (no semantic checks) and print the AST of the file at @path to
 * @out. Returns false on errors (reported to opts->diag).
 */
bool sl_emit_ast_file(const char *path, const struct sl_options *opts, FILE *out);

/** Print @prog's IR or JSON report to @out. */
void sl_emit(const struct sl_program *prog, enum sl_emit_kind kind, FILE *out);

/**
 * The JSON report, with @extra (JSON object members, e.g. "\"a\": 1, \"b\": 2",
 * or NULL) added at its end.
 */
void sl_emit_report(const struct sl_program *prog, const char *extra, FILE *out);

/** The shader's name and kind. */
const char *sl_program_name(const struct sl_program *prog);
enum sl_shader_kind sl_program_kind(const struct sl_program *prog);
const char *sl_shader_kind_name(enum sl_shader_kind kind);

/**
 * A hash of everything the program was compiled from (its source, the files
 * it included, the -D definitions), as 32 hex digits: with the dynamic set
 * and the compiler version, the key of generated programs cached on disk.
 */
const char *sl_program_source_hash(const struct sl_program *prog);

/**
 * A hash of the program itself, as 32 hex digits: of the tokens compiled,
 * after preprocessing (includes and macros expanded, comments, layout and
 * unused definitions gone). A shader edited only in its comments or white
 * space keeps it; one whose code changed does not. Shot files record it.
 */
const char *sl_program_hash(const struct sl_program *prog);

#endif

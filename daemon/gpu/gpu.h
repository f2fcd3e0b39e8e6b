/*
 * The GPU: a headless OpenGL 4.3 core context through EGL (the device
 * platform when a GPU is there, Mesa's surfaceless platform otherwise, so the
 * same code runs on llvmpipe), compute programs, buffers, dispatch and
 * readback. Programs are cached in memory by a hash of their source, and
 * their compiled binaries on disk (see gpu_set_program_cache).
 */
#ifndef GPU_H
#define GPU_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

struct gpu_ctx;
struct gpu_program;
struct gpu_buffer;

/**
 * Create a context, made current on the calling thread. NULL when no EGL
 * display or no OpenGL 4.3 core context can be had; the reason is written
 * to @err (always NUL-terminated). Logs loudly when the renderer is
 * software (llvmpipe).
 */
struct gpu_ctx *gpu_create(char *err, size_t errlen);
void gpu_destroy(struct gpu_ctx *ctx);

/**
 * Make @ctx current on the calling thread (a context is current on one
 * thread at a time; every other call needs it current). False on failure.
 */
bool gpu_make_current(struct gpu_ctx *ctx);

/** GL_RENDERER, and whether it is a software rasterizer. */
const char *gpu_renderer(const struct gpu_ctx *ctx);
bool gpu_is_software(const struct gpu_ctx *ctx);

/**
 * Compile and link a compute shader (GLSL source, "#version 430 core"
 * included by the caller). On failure returns NULL and writes the info log
 * followed by the numbered source to @log (NULL: stderr). The same source
 * twice gives the cached program (the context owns programs).
 */
struct gpu_program *gpu_program(struct gpu_ctx *ctx, const char *source, FILE *log);

/**
 * Keep compiled program binaries in directory @dir (created if missing; NULL
 * or "" turns the disk cache off). A context starts with rl_cache_dir("gl")
 * ($RELIGHT_CACHE_DIR/gl, else ~/.cache/relight/gl; RELIGHT_CACHE_DIR=off
 * disables it). An entry is keyed by a hash of the program's source, the
 * driver (vendor, renderer, GL version) and relight's version; a damaged or
 * refused entry is removed and the program compiled again. Without this,
 * a cold compile of a large generated program costs seconds on llvmpipe.
 */
void gpu_set_program_cache(struct gpu_ctx *ctx, const char *dir);

/** Programs this context loaded from the disk cache, and compiled from source. */
void gpu_program_stats(const struct gpu_ctx *ctx, unsigned *disk_hits, unsigned *compiled);

/** Set a uniform by name (float, vec2/3/4 by @n, or arrays): false if absent. */
bool gpu_uniform_float(struct gpu_program *p, const char *name, const float *v, int n);
bool gpu_uniform_int(struct gpu_program *p, const char *name, int v);
/** Set an int or ivec4 uniform or array from @n ints (the elements the program keeps): false if absent. */
bool gpu_uniform_ints(struct gpu_program *p, const char *name, const int *v, int n);
bool gpu_uniform_mat4(struct gpu_program *p, const char *name, const float m[16]);

/** A buffer of @bytes bytes, filled from @data when not NULL. */
struct gpu_buffer *gpu_buffer_create(struct gpu_ctx *ctx, size_t bytes, const void *data);
void gpu_buffer_destroy(struct gpu_buffer *b);
bool gpu_buffer_write(struct gpu_buffer *b, size_t offset, size_t bytes, const void *data);
bool gpu_buffer_read(struct gpu_buffer *b, size_t offset, size_t bytes, void *out);

/** Inputs read through texture buffers (samplerBuffer, R32F) and outputs as SSBOs. */
struct gpu_binding {
	uint32_t unit;             /* texture unit / SSBO binding point */
	bool ssbo;                 /* else a samplerBuffer of R32F texels */
	struct gpu_buffer *buffer;
	bool rgba;                 /* a samplerBuffer of RGBA32F texels (4 floats each) */
};

/**
 * Run @p over @n invocations (local size 64 in x, dispatched in 2D when n
 * needs more than 65535 groups: the shader gets gl_GlobalInvocationID.x +
 * gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64 as its index and must
 * skip indices >= the uniform "u_count", which this call sets). Waits for
 * the results to be visible to gpu_buffer_read.
 */
bool gpu_dispatch(struct gpu_ctx *ctx, struct gpu_program *p, const struct gpu_binding *b,
		  uint32_t nb, uint32_t n);

/** Wait until every command issued to @ctx has finished (for timing). */
bool gpu_finish(struct gpu_ctx *ctx);

/**
 * Check GLSL source offline with glslangValidator (package glslang-tools):
 * 1 valid, 0 invalid (messages to @log), -1 when the validator is missing.
 */
int gpu_validate_glsl(const char *source, FILE *log);

#endif

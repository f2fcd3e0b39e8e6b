/*
 * The imager pass of the GPU runtime: the shot's imager shader (metadata
 * "imager", render/imager.h) as a compute kernel generated from its IR
 * (sl/glsl.h), run over a resolved image, one invocation per pixel. Its
 * parameters are uniforms: an edit never recompiles.
 */
#ifndef GPU_IMAGERPASS_H
#define GPU_IMAGERPASS_H

#include "gpu.h"

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

struct gpu_imager;

/**
 * The imager of metadata entry @im of shot @shot (for messages and to find
 * the shader's source) over images of @w x @h pixels, compiled and run once
 * (llvmpipe compiles at first use). NULL with a message on @diag when the
 * shader is not found, changed since the bake, or cannot run on the GPU.
 */
struct gpu_imager *gpu_imager_create(struct gpu_ctx *ctx, const cJSON *im, const char *shot,
				     uint32_t w, uint32_t h, FILE *diag);
void gpu_imager_destroy(struct gpu_imager *im);

/** The imager shader's name. */
const char *gpu_imager_shader(const struct gpu_imager *im);
/** Bytes of GPU memory the pass holds (its two per-pixel buffers). */
size_t gpu_imager_bytes(const struct gpu_imager *im);

/**
 * Set parameter @param to @values (@n floats), checked as a light's edit is
 * (shotmeta.h shot_meta_check_edit). False, with the reason in @err and
 * nothing changed, otherwise.
 */
bool gpu_imager_set(struct gpu_imager *im, const char *param, const float *values, uint32_t n,
		    char *err, size_t errlen);

/** The current value of parameter @param (@out: 16 floats); false if none. */
bool gpu_imager_get(const struct gpu_imager *im, const char *param, float out[16], uint32_t *n);

/**
 * Parameter @k of those an edit can set (not strings or arrays): its name,
 * type (enum sl_basetype), value count and current value. False past the
 * last.
 */
bool gpu_imager_param(const struct gpu_imager *im, uint32_t k, const char **name, int *type,
		      uint32_t *n, float value[16]);

/**
 * Run the imager over @src (an SSBO of w * h premultiplied linear RGBA
 * floats) into @dst (the same layout), as the CPU's reyes_imager_run does:
 * per pixel Ci = RGB, Oi = A, alpha = A, P = (x + 0.5, y + 0.5, 0); the
 * pixel becomes (Ci, alpha), a value that is not finite 0. Three dispatches.
 */
bool gpu_imager_run(struct gpu_imager *im, struct gpu_buffer *src, struct gpu_buffer *dst);

#endif

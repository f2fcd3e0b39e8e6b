/*
 * The resolve on the GPU (lightspeed-2007 §4.1, §5.2): pixels from shaded
 * samples through the indirect framebuffer, as a compute gather, one
 * invocation per pixel summing its entries (on llvmpipe ~30x faster than
 * scattering points with blending: ../shared/PLATFORM.md), and the coarse
 * refinement levels, one entry per 4x4 block, 2x2 block or pixel. The
 * numbers are the CPU resolver's (daemon/bake/resolve.c): the GPU runtime is
 * held to it.
 */
#ifndef GPU_RESOLVE_H
#define GPU_RESOLVE_H

#include "gpu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/** Refinement levels: 0..2 coarse (blocks of 4, 2, 1 pixels), 3 all entries. */
#define GPU_LEVELS 4

/** An indirect framebuffer as a shot holds it (the parts `ifb`, `pixels`, `level0..2`). */
struct gpu_ifb_desc {
	uint32_t width, height;
	const uint64_t *offsets;     /* width * height + 1 cumulative entry counts, row-major */
	const uint32_t *sample;      /* per entry: a sample id */
	const float *weight;         /* per entry */
	const float *alpha;          /* per pixel */
	/* Level L < 3: ceil(width / B) x ceil(height / B) blocks (B = 4, 2, 1),
	 * row-major; sample UINT32_MAX for an empty block. A level left NULL
	 * (both arrays) is not uploaded, and resolving it is refused. */
	const uint32_t *level_sample[GPU_LEVELS - 1];
	const float *level_weight[GPU_LEVELS - 1];
};

struct gpu_ifb;

/**
 * Upload @d to the GPU of @ctx (current on the calling thread). NULL with
 * the reason in @err (more than 2^32 - 1 entries, offsets that do not start
 * at 0 or decrease, a level with ids but no weights, out of GPU memory).
 * Non-finite alphas and block weights are stored as 0, as the CPU reads
 * them. Destroy it before its context.
 */
struct gpu_ifb *gpu_ifb_create(struct gpu_ctx *ctx, const struct gpu_ifb_desc *d, char *err,
			       size_t errlen);
void gpu_ifb_destroy(struct gpu_ifb *f);

/** Bytes the indirect framebuffer takes in GPU memory. */
size_t gpu_ifb_bytes(const struct gpu_ifb *f);

/**
 * Resolve level @level into @rgba (an SSBO of width * height * 4 floats:
 * premultiplied linear RGB and alpha, row-major) from @colors (a buffer of
 * 3 floats per sample id, @nsamples ids, read as a samplerBuffer).
 *  - Level 3: colour = sum of weight * colour over the pixel's entries (in
 *    entry order, float accumulation), alpha = the pixel's alpha.
 *  - Levels 0-2: every pixel of a block takes weight * colour of the block's
 *    sample; alpha is the mean alpha of the block's pixels (inside the image).
 * An id >= @nsamples contributes nothing; a non-finite result is written as
 * 0. False on a GPU error, a bad level, or @nsamples over INT32_MAX / 3.
 * The buffers' sizes cannot be checked here: @colors must hold 3 x
 * @nsamples floats and @rgba the image.
 */
bool gpu_ifb_resolve(struct gpu_ifb *f, struct gpu_buffer *colors, uint64_t nsamples, int level,
		     struct gpu_buffer *rgba);

/**
 * Display-referred 8-bit output: @rgba (as written by gpu_ifb_resolve, n
 * pixels) to @out (an SSBO of n uint32, one RGBA8 pixel each, R in the low
 * byte): the colour as seen over black, each channel as the CPU's
 * reyes_srgb8() gives it (render/png.h: clamp, the sRGB transfer,
 * floor(255 x + 0.5)), alpha as reyes_unorm8(). Bit-identical to the CPU.
 */
bool gpu_encode_srgb8(struct gpu_ctx *ctx, struct gpu_buffer *rgba, uint32_t n,
		      struct gpu_buffer *out);

#endif

/*
 * The resolve on the GPU: see resolve.h.
 *
 * Layout in GPU memory. Offsets are an SSBO of uint (two reads a pixel).
 * Per-entry sample ids and weights, and the per-pixel and per-block alphas,
 * are read through R32F texture buffers, which llvmpipe streams ~2.5x faster
 * than SSBOs. A sample id travels in a float's bits, shifted up by the
 * smallest normal float's bits (ID_BIAS) so that every stored pattern is a
 * positive, normal, finite float: no denormal flush or NaN canonicalization
 * on the way through the texture unit can change it. Ids past ID_NONE (an id
 * no colour buffer can reach) are stored as ID_NONE.
 *
 * What is fixed per framebuffer is prepared once on the CPU at upload, in
 * the CPU resolver's arithmetic: non-finite alphas and block weights become
 * 0, and the block-mean alphas of levels 0 and 1 are summed in the CPU's
 * order (row-major over the image) and divided as it does, so the coarse
 * levels' alphas are the CPU's bits.
 *
 * The 8-bit encoding compares each value with the 255 smallest floats at
 * which the CPU's code (render/png.c) steps to the next byte, found once on
 * the CPU by bisection over float bit patterns. A table indexed by a
 * float's top 16 bits gives the byte where its bucket starts, and at most
 * two comparisons finish it. Comparisons are exact, so the bytes are the
 * CPU's for every input (NaN fails every comparison and gives 0, +Inf gives
 * 255), whatever the GPU's pow() precision. Bisecting all 255 steps in the
 * shader instead took 2-3x the time on llvmpipe.
 */
#include "resolve.h"

#include "color.h"
#include "log.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* Sample ids as float bits: id + ID_BIAS, at most ID_NONE + ID_BIAS (FLT_MAX). */
#define ID_BIAS 0x00800000u
#define ID_NONE 0x7effffffu

/* Block side of coarse level L. */
static const uint32_t block_side[GPU_LEVELS - 1] = { 4, 2, 1 };

struct gpu_ifb {
	struct gpu_ctx *ctx;
	uint32_t width, height;
	uint64_t entries;
	size_t bytes;
	struct gpu_buffer *offsets;      /* SSBO: width * height + 1 uint */
	struct gpu_buffer *sample;       /* texels: biased ids, per entry */
	struct gpu_buffer *weight;       /* texels: per entry */
	struct gpu_buffer *alpha;        /* texels: per pixel, finite */
	/* Coarse levels (NULL where the description had none); level_alpha[2]
	 * stays NULL: a 1x1 block's mean is the pixel's alpha. */
	struct gpu_buffer *level_sample[GPU_LEVELS - 1];
	struct gpu_buffer *level_weight[GPU_LEVELS - 1];
	struct gpu_buffer *level_alpha[GPU_LEVELS - 1];
};

/* ---- shaders ---- */

#define SHADER_PRELUDE \
	"#version 430 core\n" \
	"layout(local_size_x = 64) in;\n" \
	"uniform uint u_count;\n" \
	"uint invocation()\n" \
	"{\n" \
	"	return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n" \
	"}\n" \
	"float finite_or_zero(float v)\n" \
	"{\n" \
	"	return (floatBitsToUint(v) & 0x7f800000u) == 0x7f800000u ? 0.0 : v;\n" \
	"}\n"

/* Ids and colours, shared by both resolve programs. */
#define SHADER_SAMPLES \
	"layout(binding = 3) uniform samplerBuffer u_colors;\n" \
	"uniform int u_nsamples;\n" \
	"uint sample_id(float bits)\n" \
	"{\n" \
	"	return floatBitsToUint(bits) - 0x00800000u;\n" \
	"}\n" \
	"vec3 color(uint id)\n" \
	"{\n" \
	"	int k = int(id) * 3;\n" \
	"	return vec3(texelFetch(u_colors, k).r, texelFetch(u_colors, k + 1).r,\n" \
	"		    texelFetch(u_colors, k + 2).r);\n" \
	"}\n"

/* Level 3: each pixel sums its entries in order. */
static const char final_src[] =
	SHADER_PRELUDE
	SHADER_SAMPLES
	"layout(std430, binding = 0) readonly buffer Offsets { uint offsets[]; };\n"
	"layout(std430, binding = 1) writeonly buffer Out { vec4 rgba[]; };\n"
	"layout(binding = 0) uniform samplerBuffer u_sample;\n"
	"layout(binding = 1) uniform samplerBuffer u_weight;\n"
	"layout(binding = 2) uniform samplerBuffer u_alpha;\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	uint end = offsets[p + 1u];\n"
	"	vec3 c = vec3(0.0);\n"
	"	for (uint e = offsets[p]; e < end; e++) {\n"
	"		uint id = sample_id(texelFetch(u_sample, int(e)).r);\n"
	"		if (id < uint(u_nsamples))\n"
	"			c += texelFetch(u_weight, int(e)).r * color(id);\n"
	"	}\n"
	"	rgba[p] = vec4(finite_or_zero(c.r), finite_or_zero(c.g), finite_or_zero(c.b),\n"
	"		       texelFetch(u_alpha, int(p)).r);\n"
	"}\n";

/* Levels 0-2: each pixel takes its block's sample; alphas come per block
 * (u_block_alpha set) or per pixel. */
static const char coarse_src[] =
	SHADER_PRELUDE
	SHADER_SAMPLES
	"layout(std430, binding = 1) writeonly buffer Out { vec4 rgba[]; };\n"
	"layout(binding = 0) uniform samplerBuffer u_sample;\n"
	"layout(binding = 1) uniform samplerBuffer u_weight;\n"
	"layout(binding = 2) uniform samplerBuffer u_alpha;\n"
	"uniform int u_width;\n"
	"uniform int u_block;\n"
	"uniform int u_blocks_x;\n"
	"uniform int u_block_alpha;\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	uint x = p % uint(u_width), y = p / uint(u_width);\n"
	"	int b = int(y / uint(u_block)) * u_blocks_x + int(x / uint(u_block));\n"
	"	uint id = sample_id(texelFetch(u_sample, b).r);\n"
	"	vec3 c = vec3(0.0);\n"
	"	if (id < uint(u_nsamples))\n"
	"		c = texelFetch(u_weight, b).r * color(id);\n"
	"	float a = texelFetch(u_alpha, u_block_alpha != 0 ? b : int(p)).r;\n"
	"	rgba[p] = vec4(finite_or_zero(c.r), finite_or_zero(c.g), finite_or_zero(c.b), a);\n"
	"}\n";

/*
 * RGBA floats to RGBA8 (see the tables below). A value under the first step
 * (NaN too) is 0, one at 1 or over is 255; otherwise the bucket of its top
 * 16 bits gives the byte at the bucket's start, and the next two steps are
 * compared with it (no bucket holds more than two steps).
 */
static const char encode_src[] =
	SHADER_PRELUDE
	"layout(binding = 0) uniform samplerBuffer u_rgba;\n"
	"layout(binding = 1) uniform samplerBuffer u_steps;\n"
	"layout(std430, binding = 0) writeonly buffer Out { uint rgba8[]; };\n"
	"uniform int u_first[2];\n"
	"uniform int u_bucket0[2];\n"
	"uint byte_of(float v, int t)\n"
	"{\n"
	"	int steps = t * 257;\n"
	"	if (!(v >= texelFetch(u_steps, steps + 1).r))\n"
	"		return 0u;\n"
	"	if (v >= 1.0)\n"
	"		return 255u;\n"
	"	int bucket = int(floatBitsToUint(v) >> 16) - u_bucket0[t];\n"
	"	int k = int(texelFetch(u_steps, u_first[t] + bucket).r);\n"
	"	k += v >= texelFetch(u_steps, steps + k + 1).r ? 1 : 0;\n"
	"	k += v >= texelFetch(u_steps, steps + k + 1).r ? 1 : 0;\n"
	"	return uint(k);\n"
	"}\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	int i = int(p) * 4;\n"
	"	uint r = byte_of(texelFetch(u_rgba, i).r, 0);\n"
	"	uint g = byte_of(texelFetch(u_rgba, i + 1).r, 0);\n"
	"	uint b = byte_of(texelFetch(u_rgba, i + 2).r, 0);\n"
	"	uint a = byte_of(texelFetch(u_rgba, i + 3).r, 1);\n"
	"	rgba8[p] = r | (g << 8) | (b << 16) | (a << 24);\n"
	"}\n";

/* ---- the CPU's 8-bit encoding, and where it steps ---- */

static float float_of(uint32_t bits)
{
	float f;
	memcpy(&f, &bits, sizeof(f));
	return f;
}

/* The smallest float in [0, 1] where @enc reaches @k (both encodings are
 * non-decreasing there, 0 at 0.0f and 255 at 1.0f). */
static float first_at(uint8_t (*enc)(float), unsigned k)
{
	uint32_t lo = 0, hi = 0x3f800000u;  /* enc(lo) < k <= enc(hi) */
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (enc(float_of(mid)) >= k)
			hi = mid;
		else
			lo = mid;
	}
	return float_of(hi);
}

/*
 * The tables, as float texels: for each encoding t (0 sRGB, 1 unorm), 257
 * steps at 257 t (entry k the first float giving byte k; entry 0 unused,
 * entry 256 +Inf), then from first[t] the byte at the start of each bucket
 * of floats sharing their top 16 bits, from bucket0[t] (the first step's)
 * to 1.0f's.
 */
enum { NBYTES = 256, MAX_TABLE = 2 * 257 + 2 * 0x800 };
struct encode_table {
	bool ok;
	int first[2], bucket0[2];
	uint32_t n;
	float texel[MAX_TABLE];
};
static struct encode_table table;
static pthread_once_t table_once = PTHREAD_ONCE_INIT;

static uint32_t bits_of(float f)
{
	uint32_t u;
	memcpy(&u, &f, sizeof(u));
	return u;
}

static void make_table(void)
{
	uint8_t (*const enc[2])(float) = { rl_srgb8, rl_unorm8 };
	uint32_t n = 2 * 257;
	table.ok = true;
	for (int t = 0; t < 2; t++) {
		float *step = table.texel + 257 * t;
		step[0] = 0.0f;
		for (unsigned k = 1; k < NBYTES; k++)
			step[k] = first_at(enc[t], k);
		step[256] = INFINITY;
		uint32_t lo = bits_of(step[1]) >> 16, hi = bits_of(1.0f) >> 16;
		table.first[t] = (int)n;
		table.bucket0[t] = (int)lo;
		for (uint32_t b = lo; b <= hi && n < MAX_TABLE; b++) {
			uint32_t start = b == lo ? bits_of(step[1]) : b << 16;
			unsigned k = enc[t](float_of(start));
			table.texel[n++] = (float)k;
			/* The bucket's last float must be short of the third step from k. */
			uint32_t last = b == hi ? bits_of(1.0f) - 1 : (b << 16) | 0xffffu;
			if (k + 3 <= 256 && float_of(last) >= step[k + 3])
				table.ok = false;
		}
		if (n >= MAX_TABLE)
			table.ok = false;
	}
	table.n = n;
}

/* ---- upload ---- */

static struct gpu_buffer *upload(struct gpu_ifb *f, size_t bytes, const void *data)
{
	/* Never empty: a zero-sized buffer cannot back a texture. */
	if (!bytes) {
		static const uint32_t zero;
		bytes = sizeof(zero);
		data = &zero;
	}
	struct gpu_buffer *b = gpu_buffer_create(f->ctx, bytes, data);
	if (b)
		f->bytes += bytes;
	return b;
}

static uint32_t biased_id(uint32_t id)
{
	return (id < ID_NONE ? id : ID_NONE) + ID_BIAS;
}

static float finite_or_zero(float v)
{
	return isfinite(v) ? v : 0.0f;
}

/* Level @L's ids, weights and (blocks over 1 pixel) mean alphas. */
static bool upload_level(struct gpu_ifb *f, const struct gpu_ifb_desc *d, int L,
			 const float *alpha, char *err, size_t errlen)
{
	uint32_t B = block_side[L], W = f->width, H = f->height;
	uint32_t nx = W / B + (W % B != 0), ny = H / B + (H % B != 0);
	size_t nb = (size_t)nx * ny;
	uint32_t *ids = malloc((nb + 1) * sizeof(*ids));
	float *w = malloc((nb + 1) * sizeof(*w));
	float *ba = B > 1 ? calloc(nb + 1, sizeof(*ba)) : NULL;
	bool ok = ids && w && (B == 1 || ba);
	if (!ok) {
		snprintf(err, errlen, "out of memory for refinement level %d", L);
		goto done;
	}
	for (size_t b = 0; b < nb; b++) {
		ids[b] = biased_id(d->level_sample[L][b]);
		w[b] = finite_or_zero(d->level_weight[L][b]);
	}
	if (ba) {
		/* The CPU resolver's order and arithmetic: row-major sums, then one division. */
		for (uint32_t y = 0; y < H; y++)
			for (uint32_t x = 0; x < W; x++)
				ba[(size_t)(y / B) * nx + x / B] += alpha[(size_t)y * W + x];
		for (uint32_t by = 0; by < ny; by++)
			for (uint32_t bx = 0; bx < nx; bx++) {
				uint32_t bw = (bx + 1) * B <= W ? B : W - bx * B;
				uint32_t bh = (by + 1) * B <= H ? B : H - by * B;
				ba[(size_t)by * nx + bx] /= (float)(bw * bh);
			}
	}
	f->level_sample[L] = upload(f, nb * sizeof(*ids), ids);
	f->level_weight[L] = upload(f, nb * sizeof(*w), w);
	if (ba)
		f->level_alpha[L] = upload(f, nb * sizeof(*ba), ba);
	ok = f->level_sample[L] && f->level_weight[L] && (!ba || f->level_alpha[L]);
	if (!ok)
		snprintf(err, errlen, "no GPU memory for refinement level %d (%zu blocks)", L, nb);
done:
	free(ids);
	free(w);
	free(ba);
	return ok;
}

struct gpu_ifb *gpu_ifb_create(struct gpu_ctx *ctx, const struct gpu_ifb_desc *d, char *err,
			       size_t errlen)
{
	char scratch[256];
	if (!err || !errlen) {
		err = scratch;
		errlen = sizeof(scratch);
	}
	err[0] = '\0';
	if (!ctx || !d || !d->offsets || !d->alpha) {
		snprintf(err, errlen, "gpu_ifb_create: %s is NULL",
			 !ctx ? "the context" : !d ? "the description" : !d->offsets ? "offsets"
											: "alpha");
		return NULL;
	}
	uint64_t npix = (uint64_t)d->width * d->height;
	/* Pixel and texel indices are GLSL ints. */
	if (npix >= (uint64_t)INT32_MAX / 4) {
		snprintf(err, errlen, "gpu_ifb_create: %ux%u pixels is too many for the GPU",
			 d->width, d->height);
		return NULL;
	}
	if (d->offsets[0] != 0) {
		snprintf(err, errlen, "gpu_ifb_create: the first offset is %llu, not 0",
			 (unsigned long long)d->offsets[0]);
		return NULL;
	}
	for (uint64_t p = 0; p < npix; p++)
		if (d->offsets[p + 1] < d->offsets[p]) {
			snprintf(err, errlen, "gpu_ifb_create: the offsets decrease at pixel %llu",
				 (unsigned long long)p);
			return NULL;
		}
	uint64_t entries = d->offsets[npix];
	if (entries > UINT32_MAX) {
		snprintf(err, errlen, "gpu_ifb_create: %llu entries; the GPU resolve takes at most "
			 "2^32 - 1", (unsigned long long)entries);
		return NULL;
	}
	if (entries && (!d->sample || !d->weight)) {
		snprintf(err, errlen, "gpu_ifb_create: %llu entries but no %s",
			 (unsigned long long)entries, d->sample ? "weights" : "sample ids");
		return NULL;
	}
	for (int L = 0; L < GPU_LEVELS - 1; L++)
		if (!d->level_sample[L] != !d->level_weight[L]) {
			snprintf(err, errlen, "gpu_ifb_create: refinement level %d has %s but no %s", L,
				 d->level_sample[L] ? "sample ids" : "weights",
				 d->level_sample[L] ? "weights" : "sample ids");
			return NULL;
		}

	struct gpu_ifb *f = calloc(1, sizeof(*f));
	uint32_t *u32 = malloc((size_t)(entries > npix + 1 ? entries : npix + 1) * sizeof(uint32_t));
	float *alpha = malloc((size_t)(npix + 1) * sizeof(float));
	if (!f || !u32 || !alpha) {
		snprintf(err, errlen, "gpu_ifb_create: out of memory");
		goto fail;
	}
	f->ctx = ctx;
	f->width = d->width;
	f->height = d->height;
	f->entries = entries;
	for (uint64_t p = 0; p <= npix; p++)
		u32[p] = (uint32_t)d->offsets[p];
	f->offsets = upload(f, (size_t)(npix + 1) * sizeof(uint32_t), u32);
	for (uint64_t e = 0; e < entries; e++)
		u32[e] = biased_id(d->sample[e]);
	f->sample = upload(f, (size_t)entries * sizeof(uint32_t), u32);
	f->weight = upload(f, (size_t)entries * sizeof(float), d->weight);
	for (uint64_t p = 0; p < npix; p++)
		alpha[p] = finite_or_zero(d->alpha[p]);
	f->alpha = upload(f, (size_t)npix * sizeof(float), alpha);
	if (!f->offsets || !f->sample || !f->weight || !f->alpha) {
		snprintf(err, errlen, "gpu_ifb_create: no GPU memory for %ux%u pixels and %llu "
			 "entries", d->width, d->height, (unsigned long long)entries);
		goto fail;
	}
	for (int L = 0; L < GPU_LEVELS - 1; L++) {
		if (!d->level_sample[L])
			continue;
		char why[128];
		if (!upload_level(f, d, L, alpha, why, sizeof(why))) {
			snprintf(err, errlen, "gpu_ifb_create: %s", why);
			goto fail;
		}
	}
	free(u32);
	free(alpha);
	return f;

fail:
	free(u32);
	free(alpha);
	gpu_ifb_destroy(f);
	return NULL;
}

void gpu_ifb_destroy(struct gpu_ifb *f)
{
	if (!f)
		return;
	for (int L = 0; L < GPU_LEVELS - 1; L++) {
		gpu_buffer_destroy(f->level_sample[L]);
		gpu_buffer_destroy(f->level_weight[L]);
		gpu_buffer_destroy(f->level_alpha[L]);
	}
	gpu_buffer_destroy(f->alpha);
	gpu_buffer_destroy(f->weight);
	gpu_buffer_destroy(f->sample);
	gpu_buffer_destroy(f->offsets);
	free(f);
}

size_t gpu_ifb_bytes(const struct gpu_ifb *f)
{
	return f ? f->bytes : 0;
}

/* ---- resolve ---- */

bool gpu_ifb_resolve(struct gpu_ifb *f, struct gpu_buffer *colors, uint64_t nsamples, int level,
		     struct gpu_buffer *rgba)
{
	if (!f || !colors || !rgba) {
		rl_log(RL_LOG_ERROR, "gpu_ifb_resolve: %s is NULL",
		       !f ? "the framebuffer" : !colors ? "the colour buffer" : "the output buffer");
		return false;
	}
	if (level < 0 || level >= GPU_LEVELS) {
		rl_log(RL_LOG_ERROR, "gpu_ifb_resolve: no refinement level %d (0 to %d)", level,
		       GPU_LEVELS - 1);
		return false;
	}
	/* Colour texel indices (3 per id) are GLSL ints. */
	if (nsamples > (uint64_t)(INT32_MAX / 3)) {
		rl_log(RL_LOG_ERROR, "gpu_ifb_resolve: %llu samples; at most %d fit a colour buffer",
		       (unsigned long long)nsamples, INT32_MAX / 3);
		return false;
	}
	if (level < GPU_LEVELS - 1 && !f->level_sample[level]) {
		rl_log(RL_LOG_ERROR, "gpu_ifb_resolve: the framebuffer has no refinement level %d",
		       level);
		return false;
	}
	uint32_t npix = f->width * f->height;
	struct gpu_program *p = gpu_program(f->ctx, level == GPU_LEVELS - 1 ? final_src : coarse_src,
					    NULL);
	if (!p || !gpu_uniform_int(p, "u_nsamples", (int)nsamples))
		return false;
	if (level == GPU_LEVELS - 1) {
		const struct gpu_binding b[] = {
			{ .unit = 0, .ssbo = true, .buffer = f->offsets },
			{ .unit = 1, .ssbo = true, .buffer = rgba },
			{ .unit = 0, .buffer = f->sample },
			{ .unit = 1, .buffer = f->weight },
			{ .unit = 2, .buffer = f->alpha },
			{ .unit = 3, .buffer = colors },
		};
		return gpu_dispatch(f->ctx, p, b, sizeof(b) / sizeof(b[0]), npix);
	}
	uint32_t B = block_side[level];
	bool block_alpha = f->level_alpha[level] != NULL;
	if (!gpu_uniform_int(p, "u_width", (int)f->width) ||
	    !gpu_uniform_int(p, "u_block", (int)B) ||
	    !gpu_uniform_int(p, "u_blocks_x", (int)(f->width / B + (f->width % B != 0))) ||
	    !gpu_uniform_int(p, "u_block_alpha", block_alpha))
		return false;
	const struct gpu_binding b[] = {
		{ .unit = 1, .ssbo = true, .buffer = rgba },
		{ .unit = 0, .buffer = f->level_sample[level] },
		{ .unit = 1, .buffer = f->level_weight[level] },
		{ .unit = 2, .buffer = block_alpha ? f->level_alpha[level] : f->alpha },
		{ .unit = 3, .buffer = colors },
	};
	return gpu_dispatch(f->ctx, p, b, sizeof(b) / sizeof(b[0]), npix);
}

/* ---- 8-bit output ---- */

bool gpu_encode_srgb8(struct gpu_ctx *ctx, struct gpu_buffer *rgba, uint32_t n,
		      struct gpu_buffer *out)
{
	if (!ctx || !rgba || !out) {
		rl_log(RL_LOG_ERROR, "gpu_encode_srgb8: %s is NULL",
		       !ctx ? "the context" : !rgba ? "the input buffer" : "the output buffer");
		return false;
	}
	if (n > (uint32_t)(INT32_MAX / 4)) {
		rl_log(RL_LOG_ERROR, "gpu_encode_srgb8: %u pixels is too many", n);
		return false;
	}
	if (pthread_once(&table_once, make_table) != 0 || !table.ok) {
		rl_log(RL_LOG_ERROR, "gpu_encode_srgb8: cannot build the encoding table");
		return false;
	}
	struct gpu_program *p = gpu_program(ctx, encode_src, NULL);
	if (!p || !gpu_uniform_int(p, "u_first[0]", table.first[0]) ||
	    !gpu_uniform_int(p, "u_first[1]", table.first[1]) ||
	    !gpu_uniform_int(p, "u_bucket0[0]", table.bucket0[0]) ||
	    !gpu_uniform_int(p, "u_bucket0[1]", table.bucket0[1]))
		return false;
	struct gpu_buffer *steps = gpu_buffer_create(ctx, table.n * sizeof(float), table.texel);
	if (!steps)
		return false;
	const struct gpu_binding b[] = {
		{ .unit = 0, .ssbo = true, .buffer = out },
		{ .unit = 0, .buffer = rgba },
		{ .unit = 1, .buffer = steps },
	};
	bool ok = gpu_dispatch(ctx, p, b, sizeof(b) / sizeof(b[0]), n);
	gpu_buffer_destroy(steps);
	return ok;
}

/*
 * Images in OpenEXR files, through the OpenEXR Core C API.
 *
 * Writing: the file goes to PATH.tmp-XXXXXX in the same directory through
 * our own pwrite() callback, and is renamed over PATH only once complete,
 * so a failure leaves any old file as it was. Pixels are converted to the
 * file's types here (float to half included) and handed to the library's
 * encoder in the types it stores, one planar buffer per channel per chunk.
 * Scanline images use ZIP (16-line chunks); textures are tiled 64x64 with
 * mip-map levels rounded down, also ZIP.
 *
 * Reading: scanline or tiled files, any pixel type, decoded by the library
 * straight into the interleaved float image. Channels keep the file's order
 * (OpenEXR sorts them by name).
 */
#include "exr_internal.h"
#include "mathlib.h"
#include "fileutil.h"

#include <openexr.h>

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* More floats than this in one image (4 GiB) is taken for a corrupt header. */
#define MAX_IMAGE_FLOATS ((uint64_t)1 << 30)
/* OpenEXR's channel count is a 16-bit field in the coding pipelines. */
#define MAX_CHANNELS 4096
#define TILE_SIZE 64
#define HALF_MAX 65504.0f

/* ------------------------------------------------------------------------ */
/* Images                                                                    */

/* Channel @c's name: the caller's, else R, G, B, A, C4, C5... (@buf holds the latter). */
static const char *channel_name(const char *const *names, uint32_t c, char buf[16])
{
	static const char *const rgba[] = { "R", "G", "B", "A" };
	if (names && names[c] && names[c][0])
		return names[c];
	if (c < 4)
		return rgba[c];
	snprintf(buf, 16, "C%u", c);
	return buf;
}

bool reyes_image_init(struct reyes_image *im, uint32_t w, uint32_t h, uint32_t nch,
		      const char *const *names)
{
	memset(im, 0, sizeof(*im));
	if (w == 0 || h == 0 || nch == 0 || nch > MAX_CHANNELS)
		return false;
	uint64_t n = (uint64_t)w * h * nch;
	if (n > MAX_IMAGE_FLOATS || n > SIZE_MAX / sizeof(float))
		return false;

	/* The names live in one block after the pointer array: one free() for all. */
	char buf[16];
	size_t bytes = (size_t)nch * sizeof(char *);
	for (uint32_t c = 0; c < nch; c++)
		bytes += strlen(channel_name(names, c, buf)) + 1;
	char *block = malloc(bytes);
	float *data = calloc((size_t)n, sizeof(float));
	if (!block || !data) {
		free(block);
		free(data);
		return false;
	}
	const char **ptrs = (const char **)(void *)block;
	char *p = block + (size_t)nch * sizeof(char *);
	for (uint32_t c = 0; c < nch; c++) {
		const char *s = channel_name(names, c, buf);
		size_t len = strlen(s) + 1;
		memcpy(p, s, len);
		ptrs[c] = p;
		p += len;
	}
	im->width = w;
	im->height = h;
	im->nchannels = nch;
	im->channel_names = ptrs;
	im->data = data;
	sl_m44_identity(im->world_to_camera);
	sl_m44_identity(im->world_to_ndc);
	return true;
}

void reyes_image_finish(struct reyes_image *im)
{
	if (!im)
		return;
	free((void *)im->channel_names);
	free(im->data);
	memset(im, 0, sizeof(*im));
}

/* ------------------------------------------------------------------------ */
/* Library plumbing                                                          */

/* Per-call state: the write callback gets it as its user_data. */
struct io {
	int fd;                 /* writing: the temporary file */
	int write_errno;        /* first failing pwrite()'s errno */
	char msg[256];          /* the library's last error message */
};

/*
 * The call in progress on this thread, for on_error(). The library calls
 * its error handler with a write context's lock held, and
 * exr_get_user_data() takes that lock again (a non-recursive mutex): asking
 * the context from inside the handler hangs the thread for ever on the
 * first failed write. The Core API is synchronous, so the handler runs on
 * the thread that made the call and a thread-local pointer reaches the state.
 */
static _Thread_local struct io *current_io;

static void on_error(exr_const_context_t ctx, exr_result_t code, const char *msg)
{
	(void)ctx;
	struct io *io = current_io;
	if (io)
		snprintf(io->msg, sizeof(io->msg), "%s",
			 msg ? msg : exr_get_default_error_message(code));
}

static int64_t write_fd(exr_const_context_t ctx, void *ud, const void *buf, uint64_t sz,
			uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
	struct io *io = ud;
	int e = rl_pwrite_all(io->fd, buf, (size_t)sz, (off_t)offset);
	if (e) {
		if (!io->write_errno)
			io->write_errno = e;
		if (error_cb)
			error_cb(ctx, EXR_ERR_WRITE_IO, "write failed");
		return -1;
	}
	return (int64_t)sz;
}

static FILE *out_of(FILE *diag)
{
	return diag ? diag : stderr;
}

/* The best description of a library failure: its own message, else the code's. */
static const char *why(const struct io *io, exr_result_t rv)
{
	if (io->write_errno)
		return strerror(io->write_errno);
	return io->msg[0] ? io->msg : exr_get_default_error_message(rv);
}

/* ------------------------------------------------------------------------ */
/* Half floats                                                               */

/* Round to nearest even; @f must be finite and within +-HALF_MAX. */
static uint16_t float_to_half(float f)
{
	uint32_t x;
	memcpy(&x, &f, sizeof(x));
	uint32_t sign = (x >> 16) & 0x8000u;
	uint32_t ax = x & 0x7fffffffu;
	if (ax >= 0x477fe000u)                  /* HALF_MAX and beyond */
		return (uint16_t)(sign | 0x7bffu);
	if (ax < 0x38800000u) {                 /* below 2^-14: a subnormal half */
		if (ax < 0x33000000u)           /* below 2^-25: rounds to zero */
			return (uint16_t)sign;
		uint32_t e = ax >> 23;
		uint32_t m = (ax & 0x7fffffu) | 0x800000u;
		uint32_t shift = 126 - e;       /* 14..24 */
		uint32_t k = m >> shift;
		uint32_t rem = m & ((1u << shift) - 1);
		uint32_t halfway = 1u << (shift - 1);
		if (rem > halfway || (rem == halfway && (k & 1)))
			k++;
		return (uint16_t)(sign | k);
	}
	uint32_t h = (ax - 0x38000000u) >> 13;  /* rebias the exponent from 127 to 15 */
	uint32_t rem = ax & 0x1fffu;
	if (rem > 0x1000u || (rem == 0x1000u && (h & 1)))
		h++;
	return (uint16_t)(sign | h);
}

/* ------------------------------------------------------------------------ */
/* Writing                                                                   */

struct enc {
	const struct reyes_image *im;
	const bool *is_half;      /* per image channel */
	uint8_t *planes;          /* per image channel: a plane of the chunk in file type */
	size_t plane_bytes;       /* bytes per plane */
	int *order;               /* encoder channel j -> image channel */
	uint64_t nonfinite, clamped;
};

/*
 * Convert the rectangle (x0, y0, w, h) of @e->im into the chunk's planes, in
 * the file's channel order and packed one after another (the unpacked chunk
 * layout): OpenEXR 3.1's packer takes that layout for granted when every
 * channel has the same type, whatever the per-channel pointers say.
 * Returns each file channel's plane in @ptr.
 */
static void fill_planes(struct enc *e, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h,
			int nfile, uint8_t **ptr)
{
	const struct reyes_image *im = e->im;
	uint32_t nch = im->nchannels;
	uint8_t *plane = e->planes;
	for (int j = 0; j < nfile; j++) {
		int c = e->order[j];
		ptr[j] = plane;
		for (uint32_t y = 0; y < h; y++) {
			const float *src = im->data + (((size_t)(y0 + y) * im->width + x0) * nch + (size_t)c);
			for (uint32_t x = 0; x < w; x++) {
				float v = src[(size_t)x * nch];
				if (!isfinite(v)) {
					v = 0.0f;
					e->nonfinite++;
				}
				size_t k = (size_t)y * w + x;
				if (e->is_half[c]) {
					if (fabsf(v) > HALF_MAX) {
						v = v > 0.0f ? HALF_MAX : -HALF_MAX;
						e->clamped++;
					}
					uint16_t hv = float_to_half(v);
					memcpy(plane + k * 2, &hv, 2);
				} else {
					memcpy(plane + k * 4, &v, 4);
				}
			}
		}
		plane += (size_t)w * h * (e->is_half[c] ? 2 : 4);
	}
}

/* Encode and write one chunk whose info @ci was just set up. */
static exr_result_t encode_chunk(exr_context_t ctx, exr_encode_pipeline_t *pipe, bool *started,
				 const exr_chunk_info_t *ci, struct enc *e, uint32_t x0, uint32_t y0)
{
	exr_result_t rv = *started ? exr_encoding_update(ctx, 0, ci, pipe)
				   : exr_encoding_initialize(ctx, 0, ci, pipe);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	uint32_t w = (uint32_t)ci->width, h = (uint32_t)ci->height;
	if (ci->width <= 0 || ci->height <= 0 || (size_t)w * h * 4 > e->plane_bytes ||
	    x0 + w > e->im->width || y0 + h > e->im->height)
		return EXR_ERR_INVALID_ARGUMENT;
	uint8_t *ptr[256];
	if (pipe->channel_count > 256 || pipe->channel_count != (int)e->im->nchannels)
		return EXR_ERR_INVALID_ARGUMENT;
	fill_planes(e, x0, y0, w, h, pipe->channel_count, ptr);
	for (int j = 0; j < pipe->channel_count; j++) {
		exr_coding_channel_info_t *ch = &pipe->channels[j];
		int c = e->order[j];
		int bpe = e->is_half[c] ? 2 : 4;
		ch->user_bytes_per_element = (int16_t)bpe;
		ch->user_data_type = (uint16_t)(e->is_half[c] ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT);
		ch->user_pixel_stride = bpe;
		ch->user_line_stride = (int32_t)w * bpe;
		ch->encode_from_ptr = ptr[j];
	}
	if (!*started) {
		rv = exr_encoding_choose_default_routines(ctx, 0, pipe);
		if (rv != EXR_ERR_SUCCESS)
			return rv;
		*started = true;
	}
	return exr_encoding_run(ctx, 0, pipe);
}

/*
 * OpenEXR 3.1's exr_write_tile_chunk_info() clips edge tiles against level
 * 0's data window whatever the level, so a level's last column or row of
 * tiles can come out too wide. Clip against the level being written.
 */
static void fix_tile_size(exr_chunk_info_t *ci, const struct enc *e, uint32_t tx, uint32_t ty)
{
	const struct reyes_image *lv = e->im;
	uint32_t x0 = tx * TILE_SIZE, y0 = ty * TILE_SIZE;
	uint32_t w = lv->width - x0 < TILE_SIZE ? lv->width - x0 : TILE_SIZE;
	uint32_t h = lv->height - y0 < TILE_SIZE ? lv->height - y0 : TILE_SIZE;
	uint64_t bytes = 0;
	for (uint32_t c = 0; c < lv->nchannels; c++)
		bytes += e->is_half[c] ? 2 : 4;
	ci->width = (int32_t)w;
	ci->height = (int32_t)h;
	ci->unpacked_size = (uint64_t)w * h * bytes;
}

static bool valid_name(const char *s)
{
	size_t n = s ? strlen(s) : 0;
	return n > 0 && n < 256;
}

static void put_matrix(exr_context_t ctx, const char *name, const float m[16])
{
	exr_attr_m44f_t a;
	for (int k = 0; k < 16; k++)
		a.m[k] = sl_finite(m[k]);
	exr_attr_set_m44f(ctx, 0, name, &a);
}

/* Define the part, write the header and all chunks to an open context. */
static exr_result_t write_all(exr_context_t ctx, const struct reyes_image *levels, uint32_t nlevels,
			      const struct reyes_exr_write_opts *o, struct enc *e)
{
	const struct reyes_image *im = &levels[0];
	int part = 0;
	exr_result_t rv = exr_add_part(ctx, NULL, o->mipmap ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE,
				       &part);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_initialize_required_attr_simple(ctx, part, (int32_t)im->width,
							 (int32_t)im->height, EXR_COMPRESSION_ZIP);
	for (uint32_t c = 0; c < im->nchannels && rv == EXR_ERR_SUCCESS; c++)
		rv = exr_add_channel(ctx, part, im->channel_names[c],
				     e->is_half[c] ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT,
				     EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
	if (rv == EXR_ERR_SUCCESS && o->mipmap)
		rv = exr_set_tile_descriptor(ctx, part, TILE_SIZE, TILE_SIZE, EXR_TILE_MIPMAP_LEVELS,
					     EXR_TILE_ROUND_DOWN);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (im->has_matrices) {
		put_matrix(ctx, "worldToCamera", im->world_to_camera);
		put_matrix(ctx, "worldToNDC", im->world_to_ndc);
	}
	exr_attr_set_string(ctx, part, "software", "relight");
	if (o->wrapmodes)
		exr_attr_set_string(ctx, part, "wrapmodes", o->wrapmodes);
	if (o->envmap == REYES_ENVMAP_LATLONG || o->envmap == REYES_ENVMAP_CUBE)
		exr_attr_set_envmap(ctx, part, "envmap", o->envmap == REYES_ENVMAP_CUBE ?
								 EXR_ENVMAP_CUBE : EXR_ENVMAP_LATLONG);
	if (o->fov > 0.0f)
		exr_attr_set_float(ctx, part, "fov", o->fov);
	for (uint32_t k = 0; k < o->nstrattrs; k++)
		if (valid_name(o->strattrs[2 * k]) && o->strattrs[2 * k + 1])
			exr_attr_set_string(ctx, part, o->strattrs[2 * k], o->strattrs[2 * k + 1]);

	/* The levels must be the ones the library derives from the header. */
	if (o->mipmap) {
		int32_t lx = 0, ly = 0;
		rv = exr_get_tile_levels(ctx, part, &lx, &ly);
		if (rv != EXR_ERR_SUCCESS)
			return rv;
		if (lx != (int32_t)nlevels || ly != (int32_t)nlevels)
			return EXR_ERR_INVALID_ARGUMENT;
		for (uint32_t l = 0; l < nlevels; l++) {
			int32_t lw = 0, lh = 0;
			rv = exr_get_level_sizes(ctx, part, (int)l, (int)l, &lw, &lh);
			if (rv != EXR_ERR_SUCCESS)
				return rv;
			if ((uint32_t)lw != levels[l].width || (uint32_t)lh != levels[l].height)
				return EXR_ERR_INVALID_ARGUMENT;
		}
	}

	rv = exr_write_header(ctx);
	if (rv != EXR_ERR_SUCCESS)
		return rv;

	/* Encoder channels come sorted by name: map each to the image's channel. */
	const exr_attr_chlist_t *chl = NULL;
	rv = exr_get_channels(ctx, part, &chl);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (!chl || chl->num_channels != (int)im->nchannels)
		return EXR_ERR_INVALID_ARGUMENT;
	for (int j = 0; j < chl->num_channels; j++) {
		e->order[j] = -1;
		for (uint32_t c = 0; c < im->nchannels; c++)
			if (!strcmp(chl->entries[j].name.str, im->channel_names[c]))
				e->order[j] = (int)c;
		if (e->order[j] < 0)
			return EXR_ERR_INVALID_ARGUMENT;
	}

	exr_encode_pipeline_t pipe = EXR_ENCODE_PIPELINE_INITIALIZER;
	bool started = false;
	if (!o->mipmap) {
		int32_t lpc = 1;
		rv = exr_get_scanlines_per_chunk(ctx, part, &lpc);
		for (uint32_t y = 0; y < im->height && rv == EXR_ERR_SUCCESS; y += (uint32_t)lpc) {
			exr_chunk_info_t ci;
			rv = exr_write_scanline_chunk_info(ctx, part, (int)y, &ci);
			if (rv == EXR_ERR_SUCCESS)
				rv = encode_chunk(ctx, &pipe, &started, &ci, e, 0, y);
		}
	} else {
		for (uint32_t l = 0; l < nlevels && rv == EXR_ERR_SUCCESS; l++) {
			e->im = &levels[l];
			uint32_t nx = (levels[l].width + TILE_SIZE - 1) / TILE_SIZE;
			uint32_t ny = (levels[l].height + TILE_SIZE - 1) / TILE_SIZE;
			for (uint32_t ty = 0; ty < ny && rv == EXR_ERR_SUCCESS; ty++) {
				for (uint32_t tx = 0; tx < nx && rv == EXR_ERR_SUCCESS; tx++) {
					exr_chunk_info_t ci;
					rv = exr_write_tile_chunk_info(ctx, part, (int)tx, (int)ty, (int)l,
								       (int)l, &ci);
					if (rv == EXR_ERR_SUCCESS)
						fix_tile_size(&ci, e, tx, ty);
					if (rv == EXR_ERR_SUCCESS)
						rv = encode_chunk(ctx, &pipe, &started, &ci, e,
								  tx * TILE_SIZE, ty * TILE_SIZE);
				}
			}
		}
		e->im = &levels[0];
	}
	if (started)
		exr_encoding_destroy(ctx, &pipe);
	return rv;
}

/* Check what reyes_exr_write() is given; false with @msg set when unusable. */
static bool check_levels(const struct reyes_image *levels, uint32_t nlevels, bool mipmap,
			 char *msg, size_t msgsize)
{
	if (!levels || nlevels == 0 || (!mipmap && nlevels != 1)) {
		snprintf(msg, msgsize, "no image");
		return false;
	}
	const struct reyes_image *im = &levels[0];
	if (im->width == 0 || im->height == 0 || im->nchannels == 0 || !im->channel_names ||
	    im->width > INT32_MAX / 2 || im->height > INT32_MAX / 2 ||
	    im->nchannels > MAX_CHANNELS) {
		snprintf(msg, msgsize, "invalid image (%ux%u, %u channels)", im->width, im->height,
			 im->nchannels);
		return false;
	}
	for (uint32_t c = 0; c < im->nchannels; c++) {
		if (!valid_name(im->channel_names[c])) {
			snprintf(msg, msgsize, "invalid name for channel %u", c);
			return false;
		}
		for (uint32_t d = 0; d < c; d++) {
			if (!strcmp(im->channel_names[c], im->channel_names[d])) {
				snprintf(msg, msgsize, "channel '%s' appears twice",
					 im->channel_names[c]);
				return false;
			}
		}
	}
	for (uint32_t l = 0; l < nlevels; l++) {
		const struct reyes_image *lv = &levels[l];
		uint32_t ew = l < 32 ? im->width >> l : 0, eh = l < 32 ? im->height >> l : 0;
		if (l >= 32 || !lv->data || lv->width != (ew ? ew : 1) ||
		    lv->height != (eh ? eh : 1) || lv->nchannels != im->nchannels) {
			snprintf(msg, msgsize, "level %u has the wrong size", l);
			return false;
		}
	}
	return true;
}

bool reyes_exr_write(const char *path, const struct reyes_image *levels, uint32_t nlevels,
		     const struct reyes_exr_write_opts *o, FILE *diag)
{
	FILE *out = out_of(diag);
	if (!path || !path[0]) {
		fprintf(out, "(no name): error: cannot write: empty file name\n");
		return false;
	}
	char msg[320];
	if (!check_levels(levels, nlevels, o->mipmap, msg, sizeof(msg))) {
		fprintf(out, "%s: error: cannot write: %s\n", path, msg);
		return false;
	}
	const struct reyes_image *im = &levels[0];
	uint32_t nch = im->nchannels;

	size_t plane_elems = o->mipmap ? (size_t)TILE_SIZE * TILE_SIZE : (size_t)16 * im->width;
	struct enc e = { .im = im };
	bool *is_half = calloc(nch, sizeof(bool));
	int *order = calloc(nch, sizeof(int));
	e.plane_bytes = plane_elems * 4;
	e.planes = malloc(nch * e.plane_bytes);
	if (!is_half || !order || !e.planes) {
		fprintf(out, "%s: error: cannot write: out of memory\n", path);
		free(is_half);
		free(order);
		free(e.planes);
		return false;
	}
	for (uint32_t c = 0; c < nch; c++)
		is_half[c] = o->half && strcmp(im->channel_names[c], "Z") != 0;
	e.is_half = is_half;
	e.order = order;

	bool ok = false;
	struct rl_atomic file;
	if (!rl_atomic_open(&file, path)) {
		fprintf(out, "%s: error: cannot write: cannot create a temporary file: %s\n", path,
			strerror(errno));
		goto done;
	}
	struct io io = { .fd = file.fd };

	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	init.error_handler_fn = on_error;
	init.user_data = &io;
	init.write_fn = write_fd;
	exr_context_t ctx = NULL;
	current_io = &io;
	exr_result_t rv = exr_start_write(&ctx, file.tmp, EXR_WRITE_FILE_DIRECTLY, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = write_all(ctx, levels, nlevels, o, &e);
	if (ctx) {
		exr_result_t frv = exr_finish(&ctx);
		if (rv == EXR_ERR_SUCCESS)
			rv = frv;
	}
	current_io = NULL;
	if (rv != EXR_ERR_SUCCESS) {
		fprintf(out, "%s: error: cannot write: %s\n", path, why(&io, rv));
		rl_atomic_abort(&file);
		goto done;
	}
	if (!rl_atomic_commit(&file)) {
		fprintf(out, "%s: error: cannot write: %s\n", path, strerror(errno));
		goto done;
	}
	if (e.nonfinite)
		fprintf(out, "%s: warning: %llu NaN or infinite values written as 0\n", path,
			(unsigned long long)e.nonfinite);
	if (e.clamped)
		fprintf(out, "%s: warning: %llu values beyond the half-float range clamped\n", path,
			(unsigned long long)e.clamped);
	ok = true;
done:
	free(is_half);
	free(order);
	free(e.planes);
	return ok;
}

bool reyes_image_write_exr(const char *path, const struct reyes_image *im, bool half,
			   FILE *diag)
{
	struct reyes_exr_write_opts o = { .half = half };
	return reyes_exr_write(path, im, 1, &o, diag);
}

/* ------------------------------------------------------------------------ */
/* Reading                                                                   */

static bool get_matrix(exr_context_t ctx, const char *name, float m[16])
{
	const exr_attribute_t *a = NULL;
	if (exr_get_attribute_by_name(ctx, 0, name, &a) != EXR_ERR_SUCCESS || !a)
		return false;
	if (a->type == EXR_ATTR_M44F && a->m44f) {
		for (int k = 0; k < 16; k++)
			m[k] = a->m44f->m[k];
		return true;
	}
	if (a->type == EXR_ATTR_M44D && a->m44d) {
		for (int k = 0; k < 16; k++)
			m[k] = (float)a->m44d->m[k];
		return true;
	}
	return false;
}

/* IEEE half to float (exact). */
static float half_to_float(uint16_t h)
{
	uint32_t sign = (uint32_t)(h & 0x8000u) << 16, exp = (h >> 10) & 0x1fu, man = h & 0x3ffu;
	uint32_t bits;
	if (exp == 0) {
		if (man == 0) {
			bits = sign;
		} else {
			/* subnormal: normalise */
			int e = -1;
			do {
				man <<= 1;
				e++;
			} while (!(man & 0x400u));
			bits = sign | (uint32_t)(127 - 15 - e) << 23 | (man & 0x3ffu) << 13;
		}
	} else if (exp == 31) {
		bits = sign | 0x7f800000u | man << 13;
	} else {
		bits = sign | (exp + 127 - 15) << 23 | man << 13;
	}
	float f;
	memcpy(&f, &bits, sizeof(f));
	return f;
}

/*
 * Decode one chunk into image @im at the chunk's origin (x, y). The library
 * decodes into packed planes in the file's channel order and in the file's
 * own types (OpenEXR 3.1's specialised unpackers assume such layouts and
 * reorder interleaved 4-channel half data on their own); the conversion to
 * interleaved float is done here.
 */
static exr_result_t decode_chunk(exr_context_t ctx, exr_decode_pipeline_t *pipe, bool *started,
				 const exr_chunk_info_t *ci, struct reyes_image *im, int64_t x,
				 int64_t y)
{
	if (x < 0 || y < 0 || ci->width <= 0 || ci->height <= 0 ||
	    x + ci->width > (int64_t)im->width || y + ci->height > (int64_t)im->height)
		return EXR_ERR_CORRUPT_CHUNK;
	exr_result_t rv = *started ? exr_decoding_update(ctx, 0, ci, pipe)
				   : exr_decoding_initialize(ctx, 0, ci, pipe);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (pipe->channel_count != (int)im->nchannels)
		return EXR_ERR_CORRUPT_CHUNK;
	uint32_t nch = im->nchannels;
	size_t w = (size_t)ci->width, h = (size_t)ci->height;
	uint8_t *buf = malloc(w * h * 4 * nch + 1);
	if (!buf)
		return EXR_ERR_OUT_OF_MEMORY;
	size_t off = 0;
	for (int j = 0; j < pipe->channel_count; j++) {
		exr_coding_channel_info_t *ch = &pipe->channels[j];
		if (ch->width != ci->width || ch->height != ci->height ||
		    (ch->bytes_per_element != 2 && ch->bytes_per_element != 4)) {
			free(buf);
			return EXR_ERR_CORRUPT_CHUNK;
		}
		int bpe = ch->bytes_per_element;
		ch->user_bytes_per_element = (int16_t)bpe;
		ch->user_data_type = ch->data_type;
		ch->user_pixel_stride = bpe;
		ch->user_line_stride = (int32_t)(w * (size_t)bpe);
		ch->decode_to_ptr = buf + off;
		off += w * h * (size_t)bpe;
	}
	if (!*started) {
		rv = exr_decoding_choose_default_routines(ctx, 0, pipe);
		if (rv != EXR_ERR_SUCCESS) {
			free(buf);
			return rv;
		}
		*started = true;
	}
	rv = exr_decoding_run(ctx, 0, pipe);
	if (rv == EXR_ERR_SUCCESS) {
		off = 0;
		for (int j = 0; j < pipe->channel_count; j++) {
			const exr_coding_channel_info_t *ch = &pipe->channels[j];
			const uint8_t *plane = buf + off;
			for (size_t yy = 0; yy < h; yy++)
				for (size_t xx = 0; xx < w; xx++) {
					size_t k = yy * w + xx;
					float v;
					if (ch->data_type == EXR_PIXEL_HALF) {
						uint16_t hv;
						memcpy(&hv, plane + k * 2, 2);
						v = half_to_float(hv);
					} else if (ch->data_type == EXR_PIXEL_UINT) {
						uint32_t u;
						memcpy(&u, plane + k * 4, 4);
						v = (float)u;
					} else {
						memcpy(&v, plane + k * 4, 4);
					}
					im->data[(((size_t)y + yy) * im->width + (size_t)x + xx) * nch +
						 (size_t)j] = v;
				}
			off += w * h * (size_t)ch->bytes_per_element;
		}
	}
	free(buf);
	return rv;
}

static uint64_t box_w(const exr_attr_box2i_t *b)
{
	return (uint64_t)((int64_t)b->max.x - b->min.x + 1);
}

static uint64_t box_h(const exr_attr_box2i_t *b)
{
	return (uint64_t)((int64_t)b->max.y - b->min.y + 1);
}

/* Read the pixels of an open file into f->levels; @msg gets a reason on failure. */
static exr_result_t read_pixels(exr_context_t ctx, bool all_levels, struct reyes_exr_file *f,
				char *msg, size_t msgsize)
{
	exr_storage_t storage;
	exr_result_t rv = exr_get_storage(ctx, 0, &storage);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
		snprintf(msg, msgsize, "deep images are not supported");
		return EXR_ERR_FEATURE_NOT_IMPLEMENTED;
	}
	const exr_attr_chlist_t *chl = NULL;
	exr_attr_box2i_t dw, disp;
	rv = exr_get_channels(ctx, 0, &chl);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_data_window(ctx, 0, &dw);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_get_display_window(ctx, 0, &disp);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (!chl || chl->num_channels <= 0 || chl->num_channels > MAX_CHANNELS) {
		snprintf(msg, msgsize, "no channels, or too many");
		return EXR_ERR_INVALID_ATTR;
	}
	uint32_t nch = (uint32_t)chl->num_channels;
	const char **names = calloc(nch, sizeof(char *));
	if (!names)
		return EXR_ERR_OUT_OF_MEMORY;
	bool half = true;
	for (uint32_t c = 0; c < nch; c++) {
		const exr_attr_chlist_entry_t *en = &chl->entries[c];
		names[c] = en->name.str;
		if (en->x_sampling != 1 || en->y_sampling != 1) {
			snprintf(msg, msgsize, "channel '%s' is subsampled: not supported",
				 en->name.str);
			free(names);
			return EXR_ERR_FEATURE_NOT_IMPLEMENTED;
		}
		if (strcmp(en->name.str, "Z") != 0 && en->pixel_type != EXR_PIXEL_HALF)
			half = false;
	}
	f->half = half;

	uint32_t tile_w = 0, tile_h = 0;
	uint32_t nlevels = 1;
	if (storage == EXR_STORAGE_TILED) {
		exr_tile_level_mode_t lmode;
		exr_tile_round_mode_t rmode;
		int32_t lx = 1, ly = 1;
		rv = exr_get_tile_descriptor(ctx, 0, &tile_w, &tile_h, &lmode, &rmode);
		if (rv == EXR_ERR_SUCCESS)
			rv = exr_get_tile_levels(ctx, 0, &lx, &ly);
		if (rv != EXR_ERR_SUCCESS || tile_w == 0 || tile_h == 0) {
			free(names);
			return rv != EXR_ERR_SUCCESS ? rv : EXR_ERR_INVALID_ATTR;
		}
		if (all_levels && lmode != EXR_TILE_ONE_LEVEL)
			nlevels = (uint32_t)(lx < ly ? lx : ly);
		if (nlevels < 1 || nlevels > 32)
			nlevels = 1;
	}

	/* Level 0's size and where the data window lands in it. */
	uint64_t W = box_w(&dw), H = box_h(&dw);
	int64_t ox = 0, oy = 0;
	bool inside = dw.min.x >= disp.min.x && dw.min.y >= disp.min.y && dw.max.x <= disp.max.x &&
		      dw.max.y <= disp.max.y;
	if (nlevels == 1 && inside) {
		W = box_w(&disp);
		H = box_h(&disp);
		ox = (int64_t)dw.min.x - disp.min.x;
		oy = (int64_t)dw.min.y - disp.min.y;
	}
	if (dw.max.x < dw.min.x || dw.max.y < dw.min.y || W == 0 || H == 0 ||
	    W * H > MAX_IMAGE_FLOATS / nch) {
		snprintf(msg, msgsize, "invalid or too large image size");
		free(names);
		return EXR_ERR_INVALID_ATTR;
	}

	f->levels = calloc(nlevels, sizeof(*f->levels));
	if (!f->levels) {
		free(names);
		return EXR_ERR_OUT_OF_MEMORY;
	}
	uint64_t total = 0;
	for (uint32_t l = 0; l < nlevels; l++) {
		uint64_t lw = W, lh = H;
		if (nlevels > 1) {
			int32_t w32 = 0, h32 = 0;
			rv = exr_get_level_sizes(ctx, 0, (int)l, (int)l, &w32, &h32);
			if (rv != EXR_ERR_SUCCESS || w32 <= 0 || h32 <= 0) {
				free(names);
				return rv != EXR_ERR_SUCCESS ? rv : EXR_ERR_INVALID_ATTR;
			}
			lw = (uint64_t)w32;
			lh = (uint64_t)h32;
		}
		total += lw * lh * nch;
		if (total > MAX_IMAGE_FLOATS ||
		    !reyes_image_init(&f->levels[l], (uint32_t)lw, (uint32_t)lh, nch, names)) {
			snprintf(msg, msgsize, "image too large");
			free(names);
			return EXR_ERR_OUT_OF_MEMORY;
		}
		f->nlevels = l + 1;
	}
	free(names);

	exr_decode_pipeline_t pipe = EXR_DECODE_PIPELINE_INITIALIZER;
	bool started = false;
	if (storage == EXR_STORAGE_SCANLINE) {
		int32_t lpc = 1;
		rv = exr_get_scanlines_per_chunk(ctx, 0, &lpc);
		if (rv == EXR_ERR_SUCCESS && lpc <= 0)
			rv = EXR_ERR_INVALID_ATTR;
		for (int64_t y = dw.min.y; y <= dw.max.y && rv == EXR_ERR_SUCCESS; y += lpc) {
			exr_chunk_info_t ci;
			rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &ci);
			if (rv == EXR_ERR_SUCCESS)
				rv = decode_chunk(ctx, &pipe, &started, &ci, &f->levels[0],
						  (int64_t)ci.start_x - dw.min.x + ox,
						  (int64_t)ci.start_y - dw.min.y + oy);
		}
	} else {
		for (uint32_t l = 0; l < nlevels && rv == EXR_ERR_SUCCESS; l++) {
			struct reyes_image *lv = &f->levels[l];
			int64_t lox = l == 0 ? ox : 0, loy = l == 0 ? oy : 0;
			uint64_t lw = box_w(&dw), lh = box_h(&dw);
			if (nlevels > 1) {
				lw = lv->width;
				lh = lv->height;
			}
			uint64_t nx = (lw + tile_w - 1) / tile_w, ny = (lh + tile_h - 1) / tile_h;
			for (uint64_t ty = 0; ty < ny && rv == EXR_ERR_SUCCESS; ty++) {
				for (uint64_t tx = 0; tx < nx && rv == EXR_ERR_SUCCESS; tx++) {
					exr_chunk_info_t ci;
					rv = exr_read_tile_chunk_info(ctx, 0, (int)tx, (int)ty, (int)l,
								      (int)l, &ci);
					if (rv == EXR_ERR_SUCCESS)
						rv = decode_chunk(ctx, &pipe, &started, &ci, lv,
								  (int64_t)(tx * tile_w) + lox,
								  (int64_t)(ty * tile_h) + loy);
				}
			}
		}
	}
	if (started)
		exr_decoding_destroy(ctx, &pipe);
	if (rv != EXR_ERR_SUCCESS)
		return rv;

	struct reyes_image *im0 = &f->levels[0];
	im0->has_matrices = get_matrix(ctx, "worldToCamera", im0->world_to_camera) &&
			    get_matrix(ctx, "worldToNDC", im0->world_to_ndc);
	if (!im0->has_matrices) {
		sl_m44_identity(im0->world_to_camera);
		sl_m44_identity(im0->world_to_ndc);
	}
	const exr_attribute_t *a = NULL;
	if (exr_get_attribute_by_name(ctx, 0, "wrapmodes", &a) == EXR_ERR_SUCCESS && a &&
	    a->type == EXR_ATTR_STRING && a->string && a->string->str)
		snprintf(f->wrapmodes, sizeof(f->wrapmodes), "%.*s", (int)a->string->length,
			 a->string->str);
	if (exr_get_attribute_by_name(ctx, 0, "envmap", &a) == EXR_ERR_SUCCESS && a &&
	    a->type == EXR_ATTR_ENVMAP) {
		f->latlong = a->uc == EXR_ENVMAP_LATLONG;
		f->cube = a->uc == EXR_ENVMAP_CUBE;
	}
	f->fov = 90.0f;
	if (exr_get_attribute_by_name(ctx, 0, "fov", &a) == EXR_ERR_SUCCESS && a &&
	    a->type == EXR_ATTR_FLOAT && isfinite(a->f) && a->f > 0.0f && a->f < 180.0f)
		f->fov = a->f;
	if (exr_get_attribute_by_name(ctx, 0, "deepshadow", &a) == EXR_ERR_SUCCESS && a &&
	    a->type == EXR_ATTR_STRING && a->string && a->string->str)
		snprintf(f->deepshadow, sizeof(f->deepshadow), "%.*s", (int)a->string->length,
			 a->string->str);
	if (exr_get_attribute_by_name(ctx, 0, "bias", &a) == EXR_ERR_SUCCESS && a &&
	    a->type == EXR_ATTR_FLOAT && isfinite(a->f)) {
		f->has_bias = true;
		f->bias = a->f;
	}
	return EXR_ERR_SUCCESS;
}

void reyes_exr_file_finish(struct reyes_exr_file *f)
{
	if (!f)
		return;
	for (uint32_t l = 0; l < f->nlevels; l++)
		reyes_image_finish(&f->levels[l]);
	free(f->levels);
	memset(f, 0, sizeof(*f));
}

bool reyes_exr_read(const char *path, bool all_levels, struct reyes_exr_file *f, FILE *diag)
{
	FILE *out = out_of(diag);
	memset(f, 0, sizeof(*f));
	if (!path || !path[0]) {
		fprintf(out, "(no name): error: cannot read: empty file name\n");
		return false;
	}
	/* The library's message for a missing file is vague: ask the system first. */
	int fd = open(path, O_RDONLY);
	if (fd < 0) {
		fprintf(out, "%s: error: cannot read: %s\n", path, strerror(errno));
		return false;
	}
	close(fd);

	struct io io = { .fd = -1 };
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	init.error_handler_fn = on_error;
	init.user_data = &io;
	init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
	exr_context_t ctx = NULL;
	char msg[256] = "";
	current_io = &io;
	exr_result_t rv = exr_start_read(&ctx, path, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = read_pixels(ctx, all_levels, f, msg, sizeof(msg));
	if (ctx)
		exr_finish(&ctx);
	current_io = NULL;
	if (rv != EXR_ERR_SUCCESS) {
		fprintf(out, "%s: error: cannot read: %s\n", path,
			msg[0] ? msg : why(&io, rv));
		reyes_exr_file_finish(f);
		return false;
	}
	return true;
}

bool reyes_image_read_exr(const char *path, struct reyes_image *im, FILE *diag)
{
	struct reyes_exr_file f;
	memset(im, 0, sizeof(*im));
	if (!reyes_exr_read(path, false, &f, diag))
		return false;
	*im = f.levels[0];
	memset(&f.levels[0], 0, sizeof(f.levels[0]));
	reyes_exr_file_finish(&f);
	return true;
}

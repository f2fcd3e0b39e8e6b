/*
 * PNG writing: signature, IHDR, the zlib stream of the filtered rows split
 * into IDAT chunks as the compressor fills its output buffer, IEND. Each
 * chunk is length, type, data and the CRC-32 of type + data (zlib's
 * crc32(), which is the CRC PNG specifies).
 *
 * And the sRGB transfer function for display values.
 */
#include "png.h"

#include "color.h"
#include "fileutil.h"
#include "texture.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

/* The largest width or height PNG allows. */
#define PNG_MAX_DIM 0x7fffffffu

/* Compressed bytes gathered before they are written out as one IDAT chunk. */
#define IDAT_SIZE 65536

/* zlib counts input in uInt: feed long rows in pieces no larger than this. */
#define FEED_MAX (1u << 30)

static const uint8_t png_signature[8] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n' };

struct writer {
	FILE *f;
	z_stream z;
	uint8_t idat[IDAT_SIZE];
	int err;                /* errno of the first failed write, or 0 */
	const char *zmsg;       /* a compressor failure, or NULL */
};

static void put_be32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v >> 24);
	p[1] = (uint8_t)(v >> 16);
	p[2] = (uint8_t)(v >> 8);
	p[3] = (uint8_t)v;
}

static void put_bytes(struct writer *w, const void *p, size_t n)
{
	if (w->err || n == 0)
		return;
	if (fwrite(p, 1, n, w->f) != n)
		w->err = errno ? errno : EIO;
}

static void put_chunk(struct writer *w, const char type[4], const uint8_t *data, uint32_t len)
{
	uint8_t head[8], tail[4];
	put_be32(head, len);
	memcpy(head + 4, type, 4);
	uLong crc = crc32(0L, Z_NULL, 0);
	crc = crc32(crc, (const Bytef *)type, 4);
	if (len)
		crc = crc32(crc, data, len);
	put_be32(tail, (uint32_t)crc);
	put_bytes(w, head, sizeof(head));
	put_bytes(w, data, len);
	put_bytes(w, tail, sizeof(tail));
}

/* Write what the compressor has produced as an IDAT chunk; give it an empty buffer. */
static void flush_idat(struct writer *w)
{
	uint32_t n = (uint32_t)(IDAT_SIZE - w->z.avail_out);
	if (n)
		put_chunk(w, "IDAT", w->idat, n);
	w->z.next_out = w->idat;
	w->z.avail_out = IDAT_SIZE;
}

/* Compress @n bytes (@flush Z_NO_FLUSH), or finish the stream (Z_FINISH, @n 0). */
static void compress_bytes(struct writer *w, const uint8_t *p, size_t n, int flush)
{
	do {
		uInt piece = n > FEED_MAX ? FEED_MAX : (uInt)n;
		w->z.next_in = (Bytef *)(uintptr_t)p;
		w->z.avail_in = piece;
		n -= piece;
		if (n)
			p += piece;
		int f = n ? Z_NO_FLUSH : flush;
		for (;;) {
			int rv = deflate(&w->z, f);
			if (rv == Z_STREAM_ERROR) {
				w->zmsg = "compression failed";
				return;
			}
			bool full = w->z.avail_out == 0;
			if (full)
				flush_idat(w);
			if (w->err || rv == Z_STREAM_END)
				break;
			/* Output room left over: all the input has been taken. */
			if (!full) {
				if (f == Z_FINISH)
					w->zmsg = "compression failed";
				break;
			}
		}
	} while (n && !w->err && !w->zmsg);
}

static bool write_png(struct writer *w, const uint8_t *pixels, uint32_t width, uint32_t height,
		      uint32_t nch)
{
	static const uint8_t colour_type[5] = { 0, 0, 4, 2, 6 };
	uint8_t ihdr[13];
	put_be32(ihdr, width);
	put_be32(ihdr + 4, height);
	ihdr[8] = 8;                    /* bits per sample */
	ihdr[9] = colour_type[nch];
	ihdr[10] = 0;                   /* compression: deflate */
	ihdr[11] = 0;                   /* filter method 0 */
	ihdr[12] = 0;                   /* not interlaced */
	put_bytes(w, png_signature, sizeof(png_signature));
	put_chunk(w, "IHDR", ihdr, sizeof(ihdr));

	if (deflateInit(&w->z, Z_DEFAULT_COMPRESSION) != Z_OK) {
		w->zmsg = "cannot start the compressor (out of memory)";
		return false;
	}
	w->z.next_out = w->idat;
	w->z.avail_out = IDAT_SIZE;
	size_t row = (size_t)width * nch;
	static const uint8_t filter_none = 0;
	for (uint32_t y = 0; y < height && !w->err && !w->zmsg; y++) {
		compress_bytes(w, &filter_none, 1, Z_NO_FLUSH);
		compress_bytes(w, pixels + (size_t)y * row, row, Z_NO_FLUSH);
	}
	if (!w->err && !w->zmsg)
		compress_bytes(w, NULL, 0, Z_FINISH);
	if (!w->err && !w->zmsg)
		flush_idat(w);
	deflateEnd(&w->z);
	put_chunk(w, "IEND", NULL, 0);
	return !w->err && !w->zmsg;
}

bool reyes_png_write(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
		     uint32_t nchannels, FILE *diag)
{
	FILE *out = diag ? diag : stderr;
	if (!path || !path[0]) {
		fprintf(out, "(no name): error: cannot write: empty file name\n");
		return false;
	}
	if (!pixels || nchannels < 1 || nchannels > 4 || width < 1 || height < 1 ||
	    width > PNG_MAX_DIM || height > PNG_MAX_DIM) {
		fprintf(out, "%s: error: cannot write: invalid image (%" PRIu32 "x%" PRIu32
			", %" PRIu32 " channels)\n", path, width, height, nchannels);
		return false;
	}

	struct writer *w = calloc(1, sizeof(*w));
	struct rl_atomic file;
	if (!w) {
		fprintf(out, "%s: error: cannot write: out of memory\n", path);
		return false;
	}
	if (!rl_atomic_open(&file, path)) {
		fprintf(out, "%s: error: cannot write: cannot create a temporary file: %s\n", path,
			strerror(errno));
		free(w);
		return false;
	}
	w->f = rl_atomic_stdio(&file);
	if (!w->f)
		w->err = errno ? errno : ENOMEM;
	errno = 0;
	if (w->f)
		write_png(w, pixels, width, height, nchannels);
	bool ok = !w->err && !w->zmsg;
	if (ok && !rl_atomic_commit(&file)) {
		w->err = errno ? errno : EIO;
		ok = false;
	}
	if (!ok) {
		rl_atomic_abort(&file);
		fprintf(out, "%s: error: cannot write: %s\n", path,
			w->zmsg ? w->zmsg : strerror(w->err));
	}
	free(w);
	return ok;
}

/* ------------------------------------------------------------------------ */
/* sRGB                                                                      */

float reyes_srgb_encode(float linear)
{
	return rl_srgb_encode(linear);
}

uint8_t reyes_srgb8(float linear)
{
	return rl_srgb8(linear);
}

uint8_t reyes_unorm8(float value)
{
	return rl_unorm8(value);
}

void reyes_srgb8_rgba(const float *rgba, size_t npixels, bool with_alpha, uint8_t *out)
{
	for (size_t i = 0; i < npixels; i++) {
		const float *p = rgba + 4 * i;
		if (!with_alpha) {
			for (int c = 0; c < 3; c++)
				*out++ = reyes_srgb8(p[c]);
			continue;
		}
		float a = p[3];
		/* Straight colour for the PNG; where alpha is 0 (or not a number) keep it. */
		float inv = a > 0.0f && isfinite(a) ? 1.0f / a : 1.0f;
		for (int c = 0; c < 3; c++)
			*out++ = reyes_srgb8(p[c] * inv);
		*out++ = reyes_unorm8(a);
	}
}

bool reyes_png_write_image(const char *path, const struct reyes_image *im, FILE *diag)
{
	FILE *out = diag ? diag : stderr;
	uint32_t nch = im->nchannels;
	if (nch == 0 || nch > 4) {
		fprintf(out, "%s: error: cannot write: a PNG holds 1 to 4 channels, not %u\n", path,
			nch);
		return false;
	}
	size_t npix = (size_t)im->width * im->height;
	uint8_t *px = malloc(npix * nch);
	if (!px) {
		fprintf(out, "%s: error: cannot write: out of memory\n", path);
		return false;
	}
	const char *last = im->channel_names ? im->channel_names[nch - 1] : NULL;
	bool alpha = (nch == 2 || nch == 4) && last && strcmp(last, "A") == 0;
	bool linear[4];
	for (uint32_t c = 0; c < nch; c++) {
		const char *name = im->channel_names ? im->channel_names[c] : "";
		linear[c] = strcmp(name, "A") == 0 || strcmp(name, "Z") == 0;
	}
	for (size_t p = 0; p < npix; p++) {
		const float *v = im->data + p * nch;
		uint8_t *o = px + p * nch;
		uint32_t ncolour = alpha ? nch - 1 : nch;
		float a = alpha ? v[nch - 1] : 1.0f;
		for (uint32_t c = 0; c < ncolour; c++) {
			float x = alpha && a > 0 ? v[c] / a : v[c];
			o[c] = linear[c] ? reyes_unorm8(x) : reyes_srgb8(x);
		}
		if (alpha)
			o[nch - 1] = reyes_unorm8(a);
	}
	bool ok = reyes_png_write(path, px, im->width, im->height, nch, diag);
	free(px);
	return ok;
}

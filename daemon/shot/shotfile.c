/*
 * The shot file container: a multi-part OpenEXR file (see shotfile.h).
 *
 * The OpenEXR Core library writes and parses the headers and the chunk
 * offset tables; the chunks themselves are packed, compressed, decompressed
 * and unpacked here (NONE, RLE, ZIPS and ZIP as OpenEXR defines them: byte
 * reordering, a delta predictor, then run-length coding or zlib). Doing it
 * here sidesteps the 3.1 encoders' gaps (no deep encoding, channel
 * reordering of all-half data) and keeps every size under our own checks.
 *
 * Layout of the parts:
 *  - table: scanline, data window (0, 0) - (SHOT_TABLE_WIDTH - 1, H - 1)
 *    with H = max(1, ceil(nrows / SHOT_TABLE_WIDTH)); record r is pixel
 *    (r % W, r / W); the padding after the last record is zero. ZIP chunks
 *    hold 16 lines, the other modes one.
 *  - deep: deep scanline, data window (0, 0) - (width - 1, height - 1),
 *    one line per chunk: the line's cumulative int32 sample counts, then for
 *    each channel (in file order, sorted by name) all the line's entries.
 * Attributes: every part has "relight.format" (int) and "relight.checksum"
 * (16 hex digits: shot_hash, seed 0, of the part's per-pixel counts as
 * uint32 for deep parts, followed by each channel's values as stored, little
 * endian, in file order); tables have "relight.rows" (decimal). Part 0 holds
 * "relight.metadata" and "relight.header.checksum", a hash of the metadata
 * and of each part's name, kind, compression, size and channel list, so that
 * a damaged header is refused as surely as damaged data.
 *
 * Reading trusts nothing: every chunk must lie inside the file, chunks may
 * not overlap, and no buffer is allocated before its size has been checked
 * against the bytes that must encode it (a compressed chunk expands at most
 * ~1000 times), so memory stays proportional to the file.
 */
#include "shotfile.h"
#include "fileutil.h"

#include <openexr.h>
#include <zlib.h>

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(__BYTE_ORDER__) && defined(__ORDER_BIG_ENDIAN__)
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
#error "shot files are read and written with little-endian loads and stores"
#endif
#endif

#define ATTR_FORMAT "relight.format"
#define ATTR_CHECKSUM "relight.checksum"
#define ATTR_ROWS "relight.rows"
#define ATTR_METADATA "relight.metadata"
#define ATTR_HEADER_CHECKSUM "relight.header.checksum"

#define MAX_CHANNELS 1024
#define MAX_PARTS 65536
#define MAX_NAME 255
/* OpenEXR refuses data windows beyond this many lines or columns. */
#define MAX_EXTENT (INT32_MAX / 2)
#define MAX_METADATA ((size_t)INT32_MAX / 2)
#define HALF_MAX 65504.0f
#define ZIP_LINES 16
#define ZLIB_LEVEL 4
/* Upper bounds of what one packed byte can expand to. */
#define ZLIB_MAX_RATIO 1032
#define RLE_MAX_RATIO 64
#define RLE_MAX_RUN 127
/* Values converted per step when hashing or packing. */
#define BLOCK 2048

/*
 * Fuzzing builds accept wrong checksums (and report nothing), so that the
 * fuzzer's mutated headers and chunks reach the code behind the checks.
 */
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
#define CHECKSUMS_ENFORCED false
#else
#define CHECKSUMS_ENFORCED true
#endif

/* ------------------------------------------------------------------------ */
/* Hash                                                                      */

#define K1 UINT64_C(0x9e3779b97f4a7c15)
#define K2 UINT64_C(0xd6e8feb86659fd93)
#define K3 UINT64_C(0xbf58476d1ce4e5b9)
#define K4 UINT64_C(0x94d049bb133111eb)

/* Streaming state: four independent lanes over 32-byte blocks. */
struct hasher {
	uint64_t lane[4];
	uint64_t seed;
	uint64_t total;
	uint8_t buf[32];
	size_t nbuf;
};

static uint64_t rotl64(uint64_t x, unsigned r)
{
	return x << r | x >> (64 - r);
}

static uint64_t load64(const uint8_t *p)
{
	uint64_t v;
	memcpy(&v, p, sizeof(v));
	return v;
}

static uint64_t mix64(uint64_t h)
{
	h ^= h >> 31;
	h *= K3;
	h ^= h >> 27;
	h *= K4;
	h ^= h >> 33;
	return h;
}

static uint64_t lane_step(uint64_t v, uint64_t w)
{
	v ^= w * K2;
	v = rotl64(v, 29);
	return v * K1;
}

static void hasher_init(struct hasher *s, uint64_t seed)
{
	s->seed = seed;
	s->total = 0;
	s->nbuf = 0;
	for (unsigned i = 0; i < 4; i++)
		s->lane[i] = mix64(seed + K1 * (i + 1));
}

static void hasher_block(struct hasher *s, const uint8_t *p)
{
	s->lane[0] = lane_step(s->lane[0], load64(p));
	s->lane[1] = lane_step(s->lane[1], load64(p + 8));
	s->lane[2] = lane_step(s->lane[2], load64(p + 16));
	s->lane[3] = lane_step(s->lane[3], load64(p + 24));
}

static void hasher_update(struct hasher *s, const void *data, size_t n)
{
	const uint8_t *p = data;
	s->total += n;
	if (s->nbuf) {
		size_t take = 32 - s->nbuf < n ? 32 - s->nbuf : n;
		memcpy(s->buf + s->nbuf, p, take);
		s->nbuf += take;
		p += take;
		n -= take;
		if (s->nbuf < 32)
			return;
		hasher_block(s, s->buf);
		s->nbuf = 0;
	}
	for (; n >= 32; p += 32, n -= 32)
		hasher_block(s, p);
	if (n) {
		memcpy(s->buf, p, n);
		s->nbuf = n;
	}
}

static uint64_t hasher_final(const struct hasher *s)
{
	uint64_t h = s->seed ^ s->total * K3;
	for (unsigned i = 0; i < 4; i++)
		h = rotl64(h ^ mix64(s->lane[i]), 27) * K1 + K2;
	size_t k = 0;
	for (; k + 8 <= s->nbuf; k += 8)
		h = rotl64(h ^ load64(s->buf + k) * K2, 31) * K1 + K4;
	if (k < s->nbuf) {
		uint8_t last[8] = { 0 };
		memcpy(last, s->buf + k, s->nbuf - k);
		h = rotl64(h ^ load64(last) * K3, 23) * K2 + K1;
	}
	return mix64(h ^ s->total);
}

uint64_t shot_hash(const void *data, size_t len, uint64_t seed)
{
	struct hasher s;
	hasher_init(&s, seed);
	if (len)
		hasher_update(&s, data, len);
	return hasher_final(&s);
}

static void hash_u32(struct hasher *s, uint32_t v)
{
	hasher_update(s, &v, sizeof(v));
}

static void hash_u64(struct hasher *s, uint64_t v)
{
	hasher_update(s, &v, sizeof(v));
}

static void hash_str(struct hasher *s, const char *str)
{
	size_t n = strlen(str);
	hash_u64(s, n);
	hasher_update(s, str, n);
}

/* ------------------------------------------------------------------------ */
/* Values as stored                                                          */

static size_t type_size(enum shot_type t)
{
	return t == SHOT_HALF ? 2 : 4;
}

/*
 * Round to nearest even; NaN becomes 0 and magnitudes beyond HALF_MAX
 * (infinities included) become HALF_MAX. Branch-free, so that loops over
 * it vectorize: both roundings are computed and one is selected.
 */
static uint16_t float_to_half(float f)
{
	uint32_t x;
	memcpy(&x, &f, sizeof(x));
	uint32_t sign = (x >> 16) & 0x8000u;
	uint32_t a = x & 0x7fffffffu;
	bool nan = a > 0x7f800000u;
	a = a < 0x477fe000u ? a : 0x477fe000u;
	/* Normal halves: rebias the exponent (127 to 15), round away the 13 low bits to even. */
	uint32_t normal = (a - 0x38000000u + 0x0fffu + ((a >> 13) & 1u)) >> 13;
	/*
	 * Below 2^-14 the half is a multiple of 2^-24, which is the float spacing
	 * at 0.5: adding 0.5 makes the FPU round the value to it, to even.
	 */
	float small;
	memcpy(&small, &a, sizeof(small));
	small += 0.5f;
	uint32_t sb;
	memcpy(&sb, &small, sizeof(sb));
	uint32_t h = a < 0x38800000u ? sb - 0x3f000000u : normal;
	return (uint16_t)(nan ? 0u : (sign | h));
}

/* Exact; false for infinities and NaNs, which a shot file never holds. */
static bool half_to_float(uint16_t h, float *out)
{
	uint32_t e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
	if (e == 31)
		return false;
	if (e == 0) {
		float v = (float)m * 0x1p-24f;
		*out = h & 0x8000u ? -v : v;
		return true;
	}
	uint32_t bits = (uint32_t)(h & 0x8000u) << 16 | (e + 112u) << 23 | m << 13;
	memcpy(out, &bits, sizeof(*out));
	return true;
}

float shot_half_value(uint16_t h)
{
	float v;
	if (half_to_float(h, &v))
		return v;
	if (h & 0x3ffu)
		return NAN;
	return h & 0x8000u ? -INFINITY : INFINITY;
}

float shot_half_round(float v)
{
	float out = 0.0f;
	half_to_float(float_to_half(v), &out);
	return out;
}

/* Float channels are stored as given, except NaN (0) and infinities (+-FLT_MAX). */
static uint32_t sanitize(uint32_t x)
{
	uint32_t a = x & 0x7fffffffu;
	x = a == 0x7f800000u ? x - 1 : x;
	return a > 0x7f800000u ? 0u : x;
}

/* Store values [first, first + n) of channel @c at @out in the file's type. */
static void store_values(const struct shot_channel *c, uint64_t first, size_t n, uint8_t *out)
{
	if (c->type == SHOT_UINT) {
		memcpy(out, (const uint32_t *)c->data + first, n * 4);
		return;
	}
	if (c->type == SHOT_HALF) {
		const float *src = (const float *)c->data + first;
		for (size_t i = 0; i < n; i++) {
			uint16_t h = float_to_half(src[i]);
			memcpy(out + 2 * i, &h, 2);
		}
	} else {
		const uint32_t *src = (const uint32_t *)c->data + first;
		for (size_t i = 0; i < n; i++) {
			uint32_t v = sanitize(src[i]);
			memcpy(out + 4 * i, &v, 4);
		}
	}
}

/* Load @n stored values into channel @c from value @first on; false on a non-finite value. */
static bool load_values(struct shot_channel *c, uint64_t first, size_t n, const uint8_t *in)
{
	if (c->type == SHOT_UINT) {
		memcpy((uint32_t *)c->data + first, in, n * 4);
		return true;
	}
	float *dst = (float *)c->data + first;
	if (c->type == SHOT_HALF) {
		for (size_t i = 0; i < n; i++) {
			uint16_t h;
			memcpy(&h, in + 2 * i, 2);
			if (!half_to_float(h, &dst[i]))
				return false;
		}
		return true;
	}
	memcpy(dst, in, n * 4);
	for (size_t i = 0; i < n; i++)
		if (!isfinite(dst[i]))
			return false;
	return true;
}

static bool all_zero(const uint8_t *p, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (p[i])
			return false;
	return true;
}

/*
 * The checksum of a part: per-pixel counts (deep parts; NULL for tables),
 * then each channel's @n values as stored, channels in file order.
 */
static uint64_t data_checksum(const struct shot_channel *const *ch, uint32_t nch, uint64_t n,
			      const uint64_t *offsets, uint64_t npixels)
{
	struct hasher s;
	uint8_t buf[BLOCK * 4];
	hasher_init(&s, 0);
	for (uint64_t p = 0; offsets && p < npixels; p += BLOCK) {
		size_t k = npixels - p < BLOCK ? (size_t)(npixels - p) : BLOCK;
		for (size_t i = 0; i < k; i++) {
			uint32_t cnt = (uint32_t)(offsets[p + i + 1] - offsets[p + i]);
			memcpy(buf + 4 * i, &cnt, 4);
		}
		hasher_update(&s, buf, k * 4);
	}
	for (uint32_t c = 0; c < nch; c++) {
		size_t sz = type_size(ch[c]->type);
		for (uint64_t v = 0; v < n; v += BLOCK) {
			size_t k = n - v < BLOCK ? (size_t)(n - v) : BLOCK;
			store_values(ch[c], v, k, buf);
			hasher_update(&s, buf, k * sz);
		}
	}
	return hasher_final(&s);
}

/* ------------------------------------------------------------------------ */
/* Chunk compression                                                         */

/* Scratch buffers and zlib streams, reused across chunks. */
struct coder {
	uint8_t *tmp, *out;
	size_t tmp_cap, out_cap;
	z_stream def, inf;
	bool def_ready, inf_ready;
};

static bool grow(uint8_t **buf, size_t *cap, size_t need)
{
	if (need <= *cap)
		return true;
	size_t n = *cap ? *cap : 4096;
	while (n < need)
		n = n > SIZE_MAX / 2 ? need : n * 2;
	uint8_t *p = realloc(*buf, n);
	if (!p)
		return false;
	*buf = p;
	*cap = n;
	return true;
}

static void coder_finish(struct coder *c)
{
	if (c->def_ready)
		deflateEnd(&c->def);
	if (c->inf_ready)
		inflateEnd(&c->inf);
	free(c->tmp);
	free(c->out);
	memset(c, 0, sizeof(*c));
}

/* OpenEXR's preprocessing for RLE and ZIP: even bytes then odd bytes, then byte deltas. */
static void reorder_delta(const uint8_t *src, size_t n, uint8_t *dst)
{
	uint8_t *a = dst, *b = dst + (n + 1) / 2;
	size_t i = 0;
	for (; i + 1 < n; i += 2) {
		*a++ = src[i];
		*b++ = src[i + 1];
	}
	if (i < n)
		*a = src[i];
	uint8_t prev = n ? dst[0] : 0;
	for (i = 1; i < n; i++) {
		uint8_t cur = dst[i];
		dst[i] = (uint8_t)(cur - prev + 128u);
		prev = cur;
	}
}

/* The inverse of reorder_delta(); @src is modified. */
static void undelta_interleave(uint8_t *src, size_t n, uint8_t *dst)
{
	for (size_t i = 1; i < n; i++)
		src[i] = (uint8_t)(src[i - 1] + src[i] - 128u);
	const uint8_t *a = src, *b = src + (n + 1) / 2;
	size_t i = 0;
	for (; i + 1 < n; i += 2) {
		dst[i] = *a++;
		dst[i + 1] = *b++;
	}
	if (i < n)
		dst[i] = *a;
}

/*
 * Run-length coding as OpenEXR reads it: a byte c < 128 is followed by one
 * byte repeated c + 1 times; c >= 128 by 256 - c literal bytes.
 */
static size_t rle_encode(const uint8_t *in, size_t n, uint8_t *out)
{
	size_t i = 0, o = 0;
	while (i < n) {
		size_t run = 1;
		while (i + run < n && run < RLE_MAX_RUN && in[i + run] == in[i])
			run++;
		if (run >= 3) {
			out[o++] = (uint8_t)(run - 1);
			out[o++] = in[i];
			i += run;
			continue;
		}
		size_t start = i, len = 0;
		while (i < n && len < RLE_MAX_RUN) {
			if (i + 2 < n && in[i] == in[i + 1] && in[i] == in[i + 2])
				break;
			i++;
			len++;
		}
		out[o++] = (uint8_t)(256 - len);
		memcpy(out + o, in + start, len);
		o += len;
	}
	return o;
}

static bool rle_decode(const uint8_t *in, size_t n, uint8_t *out, size_t outn)
{
	size_t i = 0, o = 0;
	while (i < n) {
		unsigned c = in[i++];
		if (c < 128) {
			size_t run = (size_t)c + 1;
			if (i >= n || run > outn - o)
				return false;
			memset(out + o, in[i++], run);
			o += run;
		} else {
			size_t len = 256 - (size_t)c;
			if (len > n - i || len > outn - o)
				return false;
			memcpy(out + o, in + i, len);
			i += len;
			o += len;
		}
	}
	return o == outn;
}

/*
 * Compress @n raw bytes with @mode. Sets @packed to the bytes to store:
 * the raw bytes themselves when compression does not make them smaller
 * (OpenEXR's rule: a chunk whose packed size equals its unpacked size is
 * stored raw). Returns the packed size, or SIZE_MAX on failure.
 */
static size_t pack(struct coder *c, enum shot_compression mode, const uint8_t *raw, size_t n,
		   const uint8_t **packed)
{
	*packed = raw;
	if (mode == SHOT_COMPRESS_NONE || n == 0)
		return n;
	if (!grow(&c->tmp, &c->tmp_cap, n))
		return SIZE_MAX;
	reorder_delta(raw, n, c->tmp);
	size_t got;
	if (mode == SHOT_COMPRESS_RLE) {
		if (!grow(&c->out, &c->out_cap, n + n / RLE_MAX_RUN + 16))
			return SIZE_MAX;
		got = rle_encode(c->tmp, n, c->out);
	} else {
		if (!c->def_ready) {
			if (deflateInit(&c->def, ZLIB_LEVEL) != Z_OK)
				return SIZE_MAX;
			c->def_ready = true;
		} else if (deflateReset(&c->def) != Z_OK) {
			return SIZE_MAX;
		}
		/* Chunks are far below 4 GiB: zlib's 32-bit counts hold them. */
		uLong bound = deflateBound(&c->def, (uLong)n);
		if (!grow(&c->out, &c->out_cap, bound))
			return SIZE_MAX;
		c->def.next_in = c->tmp;
		c->def.avail_in = (uInt)n;
		c->def.next_out = c->out;
		c->def.avail_out = (uInt)bound;
		if (deflate(&c->def, Z_FINISH) != Z_STREAM_END)
			return SIZE_MAX;
		got = (size_t)c->def.total_out;
	}
	if (got < n)
		*packed = c->out;
	return got < n ? got : n;
}

/*
 * Unpack @packed (@np bytes) into exactly @n bytes at @out. A chunk stored
 * raw (np == n) is copied. False when the data does not decode to exactly
 * @n bytes.
 */
static bool unpack(struct coder *c, exr_compression_t mode, const uint8_t *packed, size_t np,
		   uint8_t *out, size_t n)
{
	if (np == n) {
		memcpy(out, packed, n);
		return true;
	}
	if (mode == EXR_COMPRESSION_NONE || np > n)
		return false;
	if (!grow(&c->tmp, &c->tmp_cap, n))
		return false;
	if (mode == EXR_COMPRESSION_RLE) {
		if (!rle_decode(packed, np, c->tmp, n))
			return false;
	} else {
		if (!c->inf_ready) {
			if (inflateInit(&c->inf) != Z_OK)
				return false;
			c->inf_ready = true;
		} else if (inflateReset(&c->inf) != Z_OK) {
			return false;
		}
		if (np > UINT_MAX || n > UINT_MAX)
			return false;
		c->inf.next_in = (Bytef *)(uintptr_t)packed;
		c->inf.avail_in = (uInt)np;
		c->inf.next_out = c->tmp;
		c->inf.avail_out = (uInt)n;
		int zr = inflate(&c->inf, Z_FINISH);
		if (zr != Z_STREAM_END || c->inf.total_out != n)
			return false;
	}
	undelta_interleave(c->tmp, n, out);
	return true;
}

/* ------------------------------------------------------------------------ */
/* Names and errors                                                          */

static void say(char *err, size_t errlen, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

static void say(char *err, size_t errlen, const char *fmt, ...)
{
	if (!err || !errlen)
		return;
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(err, errlen, fmt, ap);
	va_end(ap);
}

static bool valid_channel_name(const char *s)
{
	size_t n = 0;
	for (; s[n]; n++) {
		char ch = s[n];
		bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
			  (ch >= '0' && ch <= '9') || ch == '.' || ch == '_';
		if (!ok || n >= MAX_NAME)
			return false;
	}
	return n > 0;
}

/* Part names: 1 to 255 bytes, no control characters. */
static bool valid_part_name(const char *s, size_t n)
{
	if (n == 0 || n > MAX_NAME)
		return false;
	for (size_t i = 0; i < n; i++) {
		unsigned char ch = (unsigned char)s[i];
		if (ch < 0x20 || ch == 0x7f)
			return false;
	}
	return true;
}

static exr_compression_t exr_mode(enum shot_compression c)
{
	switch (c) {
	case SHOT_COMPRESS_RLE:
		return EXR_COMPRESSION_RLE;
	case SHOT_COMPRESS_ZIPS:
		return EXR_COMPRESSION_ZIPS;
	case SHOT_COMPRESS_ZIP:
		return EXR_COMPRESSION_ZIP;
	default:
		return EXR_COMPRESSION_NONE;
	}
}

static int cmp_channel(const void *a, const void *b)
{
	const struct shot_channel *const *x = a, *const *y = b;
	return strcmp((*x)->name, (*y)->name);
}

/* ------------------------------------------------------------------------ */
/* Writing                                                                   */

/* A part as written: the caller's table or deep part, channels in file order. */
struct wpart {
	const struct shot_table *t;
	const struct shot_deep *d;
	const char *name;
	const struct shot_channel **ch;
	uint32_t nch;
	size_t bpe;              /* stored bytes of one record / entry, all channels */
	uint64_t checksum;
	int32_t width, height;
	enum shot_compression mode;
	int index;
};

struct writer {
	char libmsg[256];        /* the library's last error message */
	const char *path;
	char *err;
	size_t errlen;
	int fd;
	int write_errno;
	struct coder cod;
	uint8_t *raw;            /* a chunk as stored, before compression */
	size_t raw_cap;
	uint8_t *aside;          /* a deep line's packed counts */
	size_t aside_cap;
};

/*
 * Where on_error() puts the library's message: the buffer of the write or
 * read in progress on this thread. The library calls its error handler with
 * a write context's lock held, and exr_get_user_data() takes that lock again
 * (a non-recursive mutex), so asking the context from inside the handler
 * hangs the thread for ever on the first failed write. The Core API is
 * synchronous: the handler runs on the thread that made the call.
 */
static _Thread_local char *current_libmsg;

static void on_error(exr_const_context_t ctx, exr_result_t code, const char *msg)
{
	(void)ctx;
	if (current_libmsg)
		snprintf(current_libmsg, 256, "%s", msg ? msg : exr_get_default_error_message(code));
}

static int64_t write_fd(exr_const_context_t ctx, void *ud, const void *buf, uint64_t sz,
			uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
	struct writer *w = ud;
	int e = rl_pwrite_all(w->fd, buf, (size_t)sz, (off_t)offset);
	if (e) {
		if (!w->write_errno)
			w->write_errno = e;
		if (error_cb)
			error_cb(ctx, EXR_ERR_WRITE_IO, "write failed");
		return -1;
	}
	return (int64_t)sz;
}

/* Check one part's channels and put them in file (name) order into @p. */
static bool check_channels(struct writer *w, struct wpart *p, const struct shot_channel *chs,
			   uint32_t nch, uint64_t nvalues)
{
	if (nch == 0 || nch > MAX_CHANNELS || !chs) {
		say(w->err, w->errlen, "%s: cannot write: part '%s' has %u channels (1 to %d)",
		    w->path, p->name, nch, MAX_CHANNELS);
		return false;
	}
	p->ch = malloc(nch * sizeof(*p->ch));
	if (!p->ch) {
		say(w->err, w->errlen, "%s: cannot write: out of memory", w->path);
		return false;
	}
	p->nch = nch;
	p->bpe = 0;
	for (uint32_t c = 0; c < nch; c++) {
		const struct shot_channel *ch = &chs[c];
		if (!ch->name || !valid_channel_name(ch->name)) {
			say(w->err, w->errlen,
			    "%s: cannot write: part '%s': invalid channel name '%s' (1 to %d letters, "
			    "digits, '.', '_')",
			    w->path, p->name, ch->name ? ch->name : "(null)", MAX_NAME);
			return false;
		}
		if (ch->type != SHOT_HALF && ch->type != SHOT_FLOAT && ch->type != SHOT_UINT) {
			say(w->err, w->errlen, "%s: cannot write: part '%s': channel '%s' has no valid type",
			    w->path, p->name, ch->name);
			return false;
		}
		if (nvalues && !ch->data) {
			say(w->err, w->errlen, "%s: cannot write: part '%s': channel '%s' has no data",
			    w->path, p->name, ch->name);
			return false;
		}
		p->ch[c] = ch;
		p->bpe += type_size(ch->type);
	}
	qsort(p->ch, nch, sizeof(*p->ch), cmp_channel);
	for (uint32_t c = 1; c < nch; c++) {
		if (!strcmp(p->ch[c]->name, p->ch[c - 1]->name)) {
			say(w->err, w->errlen, "%s: cannot write: part '%s': channel '%s' appears twice",
			    w->path, p->name, p->ch[c]->name);
			return false;
		}
	}
	return true;
}

static bool check_deep_offsets(struct writer *w, const struct shot_deep *d)
{
	if (!d->offsets) {
		say(w->err, w->errlen, "%s: cannot write: part '%s' has no offsets", w->path, d->name);
		return false;
	}
	if (d->offsets[0] != 0) {
		say(w->err, w->errlen, "%s: cannot write: part '%s': offsets[0] is not 0", w->path,
		    d->name);
		return false;
	}
	for (uint32_t y = 0; y < d->height; y++) {
		const uint64_t *o = d->offsets + (uint64_t)y * d->width;
		for (uint32_t x = 0; x < d->width; x++) {
			if (o[x + 1] < o[x]) {
				say(w->err, w->errlen,
				    "%s: cannot write: part '%s': offsets decrease at pixel (%u, %u)",
				    w->path, d->name, x, y);
				return false;
			}
		}
		if (o[d->width] - o[0] > INT32_MAX) {
			say(w->err, w->errlen,
			    "%s: cannot write: part '%s': line %u has more than 2^31 - 1 entries",
			    w->path, d->name, y);
			return false;
		}
	}
	return true;
}

/* Validate @f and build the parts to write; false with the reason in w->err. */
static bool plan(struct writer *w, const struct shot_file *f, const struct shot_write_options *o,
		 struct wpart *parts, uint32_t nparts)
{
	if (!f->metadata) {
		say(w->err, w->errlen, "%s: cannot write: no metadata", w->path);
		return false;
	}
	if (strlen(f->metadata) > MAX_METADATA) {
		say(w->err, w->errlen, "%s: cannot write: metadata larger than %zu bytes", w->path,
		    MAX_METADATA);
		return false;
	}
	if (o->tables > SHOT_COMPRESS_ZIP) {
		say(w->err, w->errlen, "%s: cannot write: unknown table compression %d", w->path,
		    (int)o->tables);
		return false;
	}
	if (o->deep != SHOT_COMPRESS_NONE && o->deep != SHOT_COMPRESS_RLE &&
	    o->deep != SHOT_COMPRESS_ZIPS) {
		say(w->err, w->errlen, "%s: cannot write: deep parts take NONE, RLE or ZIPS compression",
		    w->path);
		return false;
	}
	for (uint32_t i = 0; i < nparts; i++) {
		struct wpart *p = &parts[i];
		bool deep = i >= f->ntables;
		p->t = deep ? NULL : &f->tables[i];
		p->d = deep ? &f->deeps[i - f->ntables] : NULL;
		p->name = deep ? p->d->name : p->t->name;
		p->mode = deep ? o->deep : o->tables;
		if (!p->name || !valid_part_name(p->name, strlen(p->name))) {
			say(w->err, w->errlen,
			    "%s: cannot write: part %u has an invalid name (1 to %d characters, no "
			    "control characters)",
			    w->path, i, MAX_NAME);
			return false;
		}
		for (uint32_t j = 0; j < i; j++) {
			if (!strcmp(parts[j].name, p->name)) {
				say(w->err, w->errlen, "%s: cannot write: part name '%s' appears twice",
				    w->path, p->name);
				return false;
			}
		}
		if (!deep) {
			uint64_t h = p->t->nrows / SHOT_TABLE_WIDTH +
				     (p->t->nrows % SHOT_TABLE_WIDTH != 0);
			if (h > MAX_EXTENT) {
				say(w->err, w->errlen, "%s: cannot write: part '%s' has too many rows",
				    w->path, p->name);
				return false;
			}
			p->width = SHOT_TABLE_WIDTH;
			p->height = h ? (int32_t)h : 1;
			if (!check_channels(w, p, p->t->channels, p->t->nchannels, p->t->nrows))
				return false;
		} else {
			if (p->d->width == 0 || p->d->height == 0 || p->d->width > MAX_EXTENT ||
			    p->d->height > MAX_EXTENT) {
				say(w->err, w->errlen, "%s: cannot write: part '%s' has size %ux%u",
				    w->path, p->name, p->d->width, p->d->height);
				return false;
			}
			p->width = (int32_t)p->d->width;
			p->height = (int32_t)p->d->height;
			if (!check_deep_offsets(w, p->d))
				return false;
			uint64_t n = p->d->offsets[(uint64_t)p->d->width * p->d->height];
			if (!check_channels(w, p, p->d->channels, p->d->nchannels, n))
				return false;
		}
	}
	return true;
}

/* The header checksum's view of one part (file order); shared by writer and reader. */
static void hash_part(struct hasher *s, bool deep, const char *name, exr_compression_t comp,
		      uint64_t nrows, uint32_t width, uint32_t height,
		      const struct shot_channel *const *ch, uint32_t nch)
{
	hash_u32(s, deep);
	hash_str(s, name);
	hash_u32(s, (uint32_t)comp);
	if (deep) {
		hash_u32(s, width);
		hash_u32(s, height);
	} else {
		hash_u64(s, nrows);
	}
	hash_u32(s, nch);
	for (uint32_t c = 0; c < nch; c++) {
		hash_str(s, ch[c]->name);
		hash_u32(s, (uint32_t)ch[c]->type);
	}
}

static void hex64(char out[17], uint64_t v)
{
	snprintf(out, 17, "%016" PRIx64, v);
}

static void set_box(exr_attr_box2i_t *b, int32_t w, int32_t h)
{
	memset(b, 0, sizeof(*b));
	b->max.x = w - 1;
	b->max.y = h - 1;
}

/*
 * Define part @p. OpenEXR wants the parts of a file to share their display
 * window (@disp): the first deep part's image, else the first table.
 */
static exr_result_t define_part(exr_context_t ctx, struct wpart *p, const struct shot_file *f,
				const exr_attr_box2i_t *disp, bool first, uint64_t header_sum)
{
	exr_result_t rv = exr_add_part(ctx, p->name,
				       p->d ? EXR_STORAGE_DEEP_SCANLINE : EXR_STORAGE_SCANLINE,
				       &p->index);
	exr_attr_box2i_t data;
	exr_attr_v2f_t center;
	memset(&center, 0, sizeof(center));
	set_box(&data, p->width, p->height);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_initialize_required_attr(ctx, p->index, disp, &data, 1.0f, &center, 1.0f,
						  EXR_LINEORDER_INCREASING_Y, exr_mode(p->mode));
	for (uint32_t c = 0; c < p->nch && rv == EXR_ERR_SUCCESS; c++) {
		exr_pixel_type_t pt = p->ch[c]->type == SHOT_HALF    ? EXR_PIXEL_HALF
				      : p->ch[c]->type == SHOT_FLOAT ? EXR_PIXEL_FLOAT
								     : EXR_PIXEL_UINT;
		rv = exr_add_channel(ctx, p->index, p->ch[c]->name, pt, EXR_PERCEPTUALLY_LINEAR, 1, 1);
	}
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_set_version(ctx, p->index, 1);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_attr_set_int(ctx, p->index, ATTR_FORMAT, SHOT_FORMAT_VERSION);
	char hex[17];
	hex64(hex, p->checksum);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_attr_set_string(ctx, p->index, ATTR_CHECKSUM, hex);
	if (rv == EXR_ERR_SUCCESS && p->t) {
		char rows[24];
		snprintf(rows, sizeof(rows), "%" PRIu64, p->t->nrows);
		rv = exr_attr_set_string(ctx, p->index, ATTR_ROWS, rows);
	}
	if (rv == EXR_ERR_SUCCESS && first) {
		rv = exr_attr_set_string(ctx, p->index, ATTR_METADATA, f->metadata);
		hex64(hex, header_sum);
		if (rv == EXR_ERR_SUCCESS)
			rv = exr_attr_set_string(ctx, p->index, ATTR_HEADER_CHECKSUM, hex);
	}
	return rv;
}

/* The library keeps channels sorted by name: make sure that is our order. */
static exr_result_t check_order(exr_context_t ctx, const struct wpart *p)
{
	const exr_attr_chlist_t *chl = NULL;
	exr_result_t rv = exr_get_channels(ctx, p->index, &chl);
	if (rv != EXR_ERR_SUCCESS)
		return rv;
	if (!chl || chl->num_channels != (int)p->nch)
		return EXR_ERR_INVALID_ARGUMENT;
	for (uint32_t c = 0; c < p->nch; c++)
		if (strcmp(chl->entries[c].name.str, p->ch[c]->name) != 0)
			return EXR_ERR_INVALID_ARGUMENT;
	return EXR_ERR_SUCCESS;
}

static exr_result_t write_table(struct writer *w, exr_context_t ctx, const struct wpart *p)
{
	const uint64_t nrows = p->t->nrows;
	const int lpc = p->mode == SHOT_COMPRESS_ZIP ? ZIP_LINES : 1;
	const size_t line = (size_t)SHOT_TABLE_WIDTH * p->bpe;
	if (!grow(&w->raw, &w->raw_cap, line * (size_t)lpc))
		return EXR_ERR_OUT_OF_MEMORY;
	for (int32_t y = 0; y < p->height; y += lpc) {
		int32_t lines = p->height - y < lpc ? p->height - y : lpc;
		uint8_t *dst = w->raw;
		for (int32_t l = 0; l < lines; l++) {
			uint64_t row0 = (uint64_t)(y + l) * SHOT_TABLE_WIDTH;
			size_t valid = row0 >= nrows ? 0
				       : nrows - row0 < SHOT_TABLE_WIDTH ? (size_t)(nrows - row0)
									 : SHOT_TABLE_WIDTH;
			for (uint32_t c = 0; c < p->nch; c++) {
				size_t sz = type_size(p->ch[c]->type);
				if (valid)
					store_values(p->ch[c], row0, valid, dst);
				memset(dst + valid * sz, 0, (SHOT_TABLE_WIDTH - valid) * sz);
				dst += SHOT_TABLE_WIDTH * sz;
			}
		}
		size_t n = (size_t)(dst - w->raw);
		const uint8_t *packed;
		size_t np = pack(&w->cod, p->mode, w->raw, n, &packed);
		if (np == SIZE_MAX)
			return EXR_ERR_OUT_OF_MEMORY;
		exr_result_t rv = exr_write_scanline_chunk(ctx, p->index, y, packed, np);
		if (rv != EXR_ERR_SUCCESS)
			return rv;
	}
	return EXR_ERR_SUCCESS;
}

static exr_result_t write_deep(struct writer *w, exr_context_t ctx, const struct wpart *p)
{
	const struct shot_deep *d = p->d;
	const size_t count_bytes = (size_t)d->width * 4;
	/* The counts are packed after the line's data, in the same buffer. */
	for (uint32_t y = 0; y < d->height; y++) {
		const uint64_t *o = d->offsets + (uint64_t)y * d->width;
		uint64_t first = o[0], nent = o[d->width] - o[0];
		if (nent > (SIZE_MAX - count_bytes) / p->bpe)
			return EXR_ERR_OUT_OF_MEMORY;
		size_t data_bytes = (size_t)nent * p->bpe;
		if (!grow(&w->raw, &w->raw_cap, data_bytes + count_bytes))
			return EXR_ERR_OUT_OF_MEMORY;
		uint8_t *dst = w->raw;
		for (uint32_t c = 0; c < p->nch; c++) {
			if (nent)
				store_values(p->ch[c], first, (size_t)nent, dst);
			dst += (size_t)nent * type_size(p->ch[c]->type);
		}
		uint8_t *counts = w->raw + data_bytes;
		for (uint32_t x = 0; x < d->width; x++) {
			int32_t cum = (int32_t)(o[x + 1] - first);
			memcpy(counts + 4 * (size_t)x, &cum, 4);
		}
		/* pack() reuses its buffers: set the packed counts aside first. */
		const uint8_t *pc;
		size_t npc = pack(&w->cod, p->mode, counts, count_bytes, &pc);
		if (npc == SIZE_MAX)
			return EXR_ERR_OUT_OF_MEMORY;
		if (pc != counts) {
			if (!grow(&w->aside, &w->aside_cap, npc))
				return EXR_ERR_OUT_OF_MEMORY;
			memcpy(w->aside, pc, npc);
			pc = w->aside;
		}
		const uint8_t *pd;
		size_t npd = pack(&w->cod, p->mode, w->raw, data_bytes, &pd);
		if (npd == SIZE_MAX)
			return EXR_ERR_OUT_OF_MEMORY;
		exr_result_t rv = exr_write_deep_scanline_chunk(ctx, p->index, (int)y, pd, npd,
								data_bytes, pc, npc);
		if (rv != EXR_ERR_SUCCESS)
			return rv;
	}
	return EXR_ERR_SUCCESS;
}

static exr_result_t write_parts(struct writer *w, exr_context_t ctx, const struct shot_file *f,
				struct wpart *parts, uint32_t nparts, uint64_t header_sum)
{
	exr_result_t rv = EXR_ERR_SUCCESS;
	bool longnames = false;
	for (uint32_t i = 0; i < nparts; i++)
		for (uint32_t c = 0; c < parts[i].nch; c++)
			longnames = longnames || strlen(parts[i].ch[c]->name) > 31;
	if (longnames)
		rv = exr_set_longname_support(ctx, 1);
	const struct wpart *shown = &parts[0];
	for (uint32_t i = 0; i < nparts; i++) {
		if (parts[i].d) {
			shown = &parts[i];
			break;
		}
	}
	exr_attr_box2i_t disp;
	set_box(&disp, shown->width, shown->height);
	for (uint32_t i = 0; i < nparts && rv == EXR_ERR_SUCCESS; i++)
		rv = define_part(ctx, &parts[i], f, &disp, i == 0, header_sum);
	for (uint32_t i = 0; i < nparts && rv == EXR_ERR_SUCCESS; i++)
		rv = check_order(ctx, &parts[i]);
	if (rv == EXR_ERR_SUCCESS)
		rv = exr_write_header(ctx);
	for (uint32_t i = 0; i < nparts && rv == EXR_ERR_SUCCESS; i++)
		rv = parts[i].d ? write_deep(w, ctx, &parts[i]) : write_table(w, ctx, &parts[i]);
	return rv;
}

bool shot_write(const char *path, const struct shot_file *f, const struct shot_write_options *opts,
		char *err, size_t errlen)
{
	if (err && errlen)
		err[0] = '\0';
	if (!path || !path[0]) {
		say(err, errlen, "(no name): cannot write: empty file name");
		return false;
	}
	if (!f) {
		say(err, errlen, "%s: cannot write: no shot", path);
		return false;
	}
	struct shot_write_options o = { 0 };
	if (opts)
		o = *opts;
	uint64_t nparts64 = (uint64_t)f->ntables + f->ndeeps;
	if (nparts64 == 0 || nparts64 > MAX_PARTS || (f->ntables && !f->tables) ||
	    (f->ndeeps && !f->deeps)) {
		say(err, errlen, "%s: cannot write: %" PRIu64 " parts (1 to %d)", path, nparts64,
		    MAX_PARTS);
		return false;
	}
	uint32_t nparts = (uint32_t)nparts64;
	struct writer w = { .path = path, .err = err, .errlen = errlen, .fd = -1 };
	struct wpart *parts = calloc(nparts, sizeof(*parts));
	bool ok = false;
	if (!parts) {
		say(err, errlen, "%s: cannot write: out of memory", path);
		goto done;
	}
	if (!plan(&w, f, &o, parts, nparts))
		goto done;

	struct hasher hs;
	hasher_init(&hs, 0);
	hash_u32(&hs, nparts);
	for (uint32_t i = 0; i < nparts; i++) {
		struct wpart *p = &parts[i];
		if (p->t) {
			p->checksum = data_checksum(p->ch, p->nch, p->t->nrows, NULL, 0);
		} else {
			uint64_t npix = (uint64_t)p->d->width * p->d->height;
			p->checksum = data_checksum(p->ch, p->nch, p->d->offsets[npix], p->d->offsets,
						    npix);
		}
		hash_part(&hs, p->d != NULL, p->name, exr_mode(p->mode), p->t ? p->t->nrows : 0,
			  p->d ? p->d->width : 0, p->d ? p->d->height : 0, p->ch, p->nch);
	}
	hash_str(&hs, f->metadata);
	uint64_t header_sum = hasher_final(&hs);

	struct rl_atomic file;
	if (!rl_atomic_open(&file, path)) {
		say(err, errlen, "%s: cannot write: cannot create a temporary file: %s", path,
		    strerror(errno));
		goto done;
	}
	w.fd = file.fd;

	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	init.error_handler_fn = on_error;
	init.user_data = &w;
	init.write_fn = write_fd;
	exr_context_t ctx = NULL;
	current_libmsg = w.libmsg;
	exr_result_t rv = exr_start_write(&ctx, file.tmp, EXR_WRITE_FILE_DIRECTLY, &init);
	if (rv == EXR_ERR_SUCCESS)
		rv = write_parts(&w, ctx, f, parts, nparts, header_sum);
	if (ctx) {
		exr_result_t frv = exr_finish(&ctx);
		if (rv == EXR_ERR_SUCCESS)
			rv = frv;
	}
	current_libmsg = NULL;
	if (rv != EXR_ERR_SUCCESS) {
		say(err, errlen, "%s: cannot write: %s", path,
		    w.write_errno ? strerror(w.write_errno)
		    : w.libmsg[0] ? w.libmsg
				  : exr_get_default_error_message(rv));
		rl_atomic_abort(&file);
		goto done;
	}
	if (!rl_atomic_commit(&file)) {
		say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
		goto done;
	}
	ok = true;
done:
	if (parts)
		for (uint32_t i = 0; i < nparts; i++)
			free(parts[i].ch);
	free(parts);
	free(w.raw);
	free(w.aside);
	coder_finish(&w.cod);
	return ok;
}

/* ------------------------------------------------------------------------ */
/* Reading                                                                   */

/* One chunk of a part as found in the file. */
struct chunk {
	uint64_t start, end;        /* its bytes in the file, leader included */
	uint64_t counts_off, counts_size;  /* deep: the packed sample counts */
	uint64_t data_off, packed, unpacked;
};

/* A part being read. */
struct rpart {
	int index;
	bool deep;
	exr_compression_t comp;
	const char *name;           /* the file's copy, for messages */
	struct shot_channel *ch;    /* in the table or deep part being filled */
	uint32_t nch;
	size_t bpe;
	int32_t width, height;
	uint64_t checksum;
	int lpc;                    /* lines per chunk */
	int32_t nchunks;
	struct chunk *chunks;
	uint64_t unpacked_total;
};

struct reader {
	char libmsg[256];           /* the library's last error message */
	const char *name;
	int fd;
	const uint8_t *mem;
	uint64_t size;
	uint64_t max_end;           /* furthest byte any read asked for */
	char *err;
	size_t errlen;
	exr_context_t ctx;
	struct coder cod;
	uint8_t *buf;
	size_t buf_cap;
};

static void fail(struct reader *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void fail(struct reader *r, const char *fmt, ...)
{
	if (!r->err || !r->errlen)
		return;
	char msg[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	snprintf(r->err, r->errlen, "%s: %s", r->name, msg);
}

/* Read @n bytes at @off; the caller has checked that they lie inside the file. */
static bool src_get(struct reader *r, uint64_t off, void *dst, size_t n)
{
	if (r->mem) {
		memcpy(dst, r->mem + off, n);
		return true;
	}
	uint8_t *p = dst;
	size_t done = 0;
	while (done < n) {
		ssize_t k = pread(r->fd, p + done, n - done, (off_t)(off + done));
		if (k < 0 && errno == EINTR)
			continue;
		if (k <= 0)
			return false;
		done += (size_t)k;
	}
	return true;
}

static int64_t read_src(exr_const_context_t ctx, void *ud, void *buf, uint64_t sz, uint64_t off,
			exr_stream_error_func_ptr_t error_cb)
{
	struct reader *r = ud;
	uint64_t end = sz > UINT64_MAX - off ? UINT64_MAX : off + sz;
	if (end > r->max_end)
		r->max_end = end;
	if (off >= r->size)
		return 0;
	uint64_t n = r->size - off < sz ? r->size - off : sz;
	if (n > SIZE_MAX || !src_get(r, off, buf, (size_t)n)) {
		if (error_cb)
			error_cb(ctx, EXR_ERR_READ_IO, "read failed");
		return -1;
	}
	return (int64_t)n;
}

static int64_t size_src(exr_const_context_t ctx, void *ud)
{
	const struct reader *r = ud;
	return (int64_t)r->size;
}

static const exr_attribute_t *find_attr(struct reader *r, int part, const char *name,
					exr_attribute_type_t type)
{
	const exr_attribute_t *a = NULL;
	if (exr_get_attribute_by_name(r->ctx, part, name, &a) != EXR_ERR_SUCCESS || !a ||
	    a->type != type)
		return NULL;
	if (type == EXR_ATTR_STRING && (!a->string || (a->string->length && !a->string->str) ||
					a->string->length < 0))
		return NULL;
	return a;
}

/* A string attribute's exact bytes (no NUL inside) as a new C string, or NULL. */
static char *attr_dup(const exr_attribute_t *a)
{
	size_t n = (size_t)a->string->length;
	if (n && memchr(a->string->str, '\0', n))
		return NULL;
	char *s = malloc(n + 1);
	if (!s)
		return NULL;
	if (n)
		memcpy(s, a->string->str, n);
	s[n] = '\0';
	return s;
}

static bool parse_hex64(const exr_attribute_t *a, uint64_t *out)
{
	if (!a || a->string->length != 16)
		return false;
	uint64_t v = 0;
	for (int i = 0; i < 16; i++) {
		char ch = a->string->str[i];
		unsigned d;
		if (ch >= '0' && ch <= '9')
			d = (unsigned)(ch - '0');
		else if (ch >= 'a' && ch <= 'f')
			d = (unsigned)(ch - 'a' + 10);
		else
			return false;
		v = v << 4 | d;
	}
	*out = v;
	return true;
}

static bool parse_rows(const exr_attribute_t *a, uint64_t *out)
{
	if (!a || a->string->length < 1 || a->string->length > 20)
		return false;
	const char *s = a->string->str;
	int n = a->string->length;
	if (n > 1 && s[0] == '0')
		return false;
	uint64_t v = 0;
	for (int i = 0; i < n; i++) {
		if (s[i] < '0' || s[i] > '9')
			return false;
		unsigned d = (unsigned)(s[i] - '0');
		if (v > (UINT64_MAX - d) / 10)
			return false;
		v = v * 10 + d;
	}
	*out = v;
	return true;
}

/* Parse part @p's header into @t or @d (exactly one is non-NULL). */
static bool parse_part(struct reader *r, struct rpart *p, struct shot_table *t, struct shot_deep *d)
{
	exr_context_t ctx = r->ctx;
	const exr_attr_chlist_t *chl = NULL;
	exr_attr_box2i_t dw;
	exr_lineorder_t lo;
	if (exr_get_compression(ctx, p->index, &p->comp) != EXR_ERR_SUCCESS ||
	    exr_get_channels(ctx, p->index, &chl) != EXR_ERR_SUCCESS || !chl ||
	    exr_get_data_window(ctx, p->index, &dw) != EXR_ERR_SUCCESS ||
	    exr_get_lineorder(ctx, p->index, &lo) != EXR_ERR_SUCCESS) {
		fail(r, "part '%s': incomplete header", p->name);
		return false;
	}
	bool comp_ok = p->comp == EXR_COMPRESSION_NONE || p->comp == EXR_COMPRESSION_RLE ||
		       p->comp == EXR_COMPRESSION_ZIPS || (!p->deep && p->comp == EXR_COMPRESSION_ZIP);
	if (!comp_ok) {
		fail(r, "part '%s': compression %d is not one a shot file uses", p->name, (int)p->comp);
		return false;
	}
	if (lo != EXR_LINEORDER_INCREASING_Y) {
		fail(r, "part '%s': line order is not increasing", p->name);
		return false;
	}
	if (chl->num_channels < 1 || chl->num_channels > MAX_CHANNELS || !chl->entries) {
		fail(r, "part '%s': %d channels (1 to %d)", p->name, chl->num_channels, MAX_CHANNELS);
		return false;
	}
	if (dw.min.x != 0 || dw.min.y != 0 || dw.max.x < 0 || dw.max.y < 0 ||
	    dw.max.x >= MAX_EXTENT || dw.max.y >= MAX_EXTENT) {
		fail(r, "part '%s': invalid data window", p->name);
		return false;
	}
	p->width = dw.max.x + 1;
	p->height = dw.max.y + 1;

	p->nch = (uint32_t)chl->num_channels;
	p->ch = calloc(p->nch, sizeof(*p->ch));
	if (!p->ch) {
		fail(r, "out of memory");
		return false;
	}
	if (t) {
		t->channels = p->ch;
		t->nchannels = p->nch;
	} else {
		d->channels = p->ch;
		d->nchannels = p->nch;
	}
	p->bpe = 0;
	for (uint32_t c = 0; c < p->nch; c++) {
		const exr_attr_chlist_entry_t *e = &chl->entries[c];
		int len = e->name.length;
		if (len < 1 || len > MAX_NAME || !e->name.str || memchr(e->name.str, '\0', (size_t)len) ||
		    e->name.str[len] != '\0' || !valid_channel_name(e->name.str)) {
			fail(r, "part '%s': invalid channel name", p->name);
			return false;
		}
		if (c > 0 && strcmp(chl->entries[c - 1].name.str, e->name.str) >= 0) {
			fail(r, "part '%s': channels not in order", p->name);
			return false;
		}
		if (e->x_sampling != 1 || e->y_sampling != 1) {
			fail(r, "part '%s': channel '%s' is subsampled", p->name, e->name.str);
			return false;
		}
		switch (e->pixel_type) {
		case EXR_PIXEL_HALF:
			p->ch[c].type = SHOT_HALF;
			break;
		case EXR_PIXEL_FLOAT:
			p->ch[c].type = SHOT_FLOAT;
			break;
		case EXR_PIXEL_UINT:
			p->ch[c].type = SHOT_UINT;
			break;
		default:
			fail(r, "part '%s': channel '%s' has an unknown type", p->name, e->name.str);
			return false;
		}
		p->ch[c].name = malloc((size_t)len + 1);
		if (!p->ch[c].name) {
			fail(r, "out of memory");
			return false;
		}
		memcpy(p->ch[c].name, e->name.str, (size_t)len + 1);
		p->bpe += type_size(p->ch[c].type);
	}

	if (!parse_hex64(find_attr(r, p->index, ATTR_CHECKSUM, EXR_ATTR_STRING), &p->checksum)) {
		fail(r, "part '%s': missing or invalid %s", p->name, ATTR_CHECKSUM);
		return false;
	}
	p->lpc = p->comp == EXR_COMPRESSION_ZIP ? ZIP_LINES : 1;
	if (t) {
		if (!parse_rows(find_attr(r, p->index, ATTR_ROWS, EXR_ATTR_STRING), &t->nrows)) {
			fail(r, "part '%s': missing or invalid %s", p->name, ATTR_ROWS);
			return false;
		}
		uint64_t h = t->nrows / SHOT_TABLE_WIDTH + (t->nrows % SHOT_TABLE_WIDTH != 0);
		if (p->width != SHOT_TABLE_WIDTH || (uint64_t)p->height != (h ? h : 1)) {
			fail(r, "part '%s': data window does not match %" PRIu64 " rows", p->name,
			     t->nrows);
			return false;
		}
	} else {
		d->width = (uint32_t)p->width;
		d->height = (uint32_t)p->height;
	}
	p->nchunks = (p->height + p->lpc - 1) / p->lpc;
	int32_t count = 0;
	if (exr_get_chunk_count(ctx, p->index, &count) != EXR_ERR_SUCCESS || count != p->nchunks) {
		fail(r, "part '%s': wrong chunk count", p->name);
		return false;
	}
	/* Each chunk takes at least its offset and its leader: refuse sizes the file cannot hold. */
	uint64_t least = p->deep ? 8 + 28 : 8 + 8;
	if ((uint64_t)p->nchunks * least > r->size) {
		fail(r, "truncated (part '%s')", p->name);
		return false;
	}
	return true;
}

static uint64_t max_ratio(exr_compression_t c)
{
	return c == EXR_COMPRESSION_NONE ? 1 : c == EXR_COMPRESSION_RLE ? RLE_MAX_RATIO : ZLIB_MAX_RATIO;
}

/* Does @unpacked bytes stored in @packed bytes make sense for compression @c? */
static bool plausible(exr_compression_t c, uint64_t packed, uint64_t unpacked)
{
	if (packed == unpacked)
		return true;
	if (c == EXR_COMPRESSION_NONE || packed > unpacked)
		return false;
	return unpacked / max_ratio(c) <= packed;
}

/* Read @n bytes at @off (inside the file) into the reader's buffer. */
static uint8_t *fetch(struct reader *r, uint64_t off, uint64_t n)
{
	if (n > SIZE_MAX - 1 || !grow(&r->buf, &r->buf_cap, (size_t)n + 1))
		return NULL;
	if (n && !src_get(r, off, r->buf, (size_t)n))
		return NULL;
	return r->buf;
}

static uint32_t get32(const uint8_t *p)
{
	uint32_t v;
	memcpy(&v, p, 4);
	return v;
}

static uint64_t get64(const uint8_t *p)
{
	uint64_t v;
	memcpy(&v, p, 8);
	return v;
}

/*
 * Find where the chunk offset tables start: right after the header, which
 * is walked here (name, type, size, value per attribute; an empty name ends
 * a part's header, and another one the list of headers of a multi-part
 * file). The library has parsed the header already; this only measures it.
 */
static bool find_offset_tables(struct reader *r, uint32_t nparts, bool *multi, uint64_t *pos)
{
	uint8_t v[4], buf[2 * (MAX_NAME + 1) + 4];
	if (!src_get(r, 4, v, 4))
		return false;
	*multi = (get32(v) & 0x1000u) != 0;
	uint64_t at = 8;
	for (uint32_t part = 0; part < nparts; part++) {
		for (;;) {
			if (at >= r->size)
				return false;
			size_t n = r->size - at < sizeof(buf) ? (size_t)(r->size - at) : sizeof(buf);
			if (!src_get(r, at, buf, n))
				return false;
			if (buf[0] == '\0') {
				at++;
				break;
			}
			const uint8_t *e1 = memchr(buf, '\0', n);
			const uint8_t *e2 = e1 ? memchr(e1 + 1, '\0', (size_t)(buf + n - e1 - 1)) : NULL;
			if (!e2 || buf + n - e2 - 1 < 4)
				return false;
			int32_t size = (int32_t)get32(e2 + 1);
			at += (uint64_t)(e2 + 1 - buf) + 4;
			if (size < 0 || (uint64_t)size > r->size - at)
				return false;
			at += (uint64_t)size;
		}
	}
	if (*multi) {
		uint8_t end;
		if (at >= r->size || !src_get(r, at, &end, 1) || end != '\0')
			return false;
		at++;
	}
	*pos = at;
	return true;
}

/*
 * Read part @p's chunk offsets (at @table) and every chunk's leader; check
 * that each chunk is the one expected, lies inside the file and holds sizes
 * that make sense. Sets @part_bytes: the chunks, leaders and offsets.
 */
static bool read_chunks(struct reader *r, struct rpart *p, bool multi, uint64_t table,
			uint64_t *part_bytes)
{
	uint64_t n = (uint64_t)p->nchunks;
	if (table > r->size || n * 8 > r->size - table) {
		fail(r, "truncated (part '%s')", p->name);
		return false;
	}
	p->chunks = calloc((size_t)n, sizeof(*p->chunks));
	uint8_t *offsets = fetch(r, table, n * 8);
	if (!p->chunks || !offsets) {
		fail(r, "out of memory");
		return false;
	}
	const uint64_t leader = (multi ? 4 : 0) + (p->deep ? 4 + 24 : 4 + 4);
	const uint64_t line_bytes = (uint64_t)p->width * p->bpe;
	uint64_t total = 0;
	p->unpacked_total = 0;
	for (int32_t k = 0; k < p->nchunks; k++) {
		struct chunk *c = &p->chunks[k];
		int32_t y = k * p->lpc;
		int32_t lines = p->height - y < p->lpc ? p->height - y : p->lpc;
		uint64_t off = get64(offsets + 8 * (size_t)k);
		uint8_t lead[32];
		if (off > r->size || leader > r->size - off) {
			fail(r, "truncated (part '%s')", p->name);
			return false;
		}
		if (!src_get(r, off, lead, (size_t)leader)) {
			fail(r, "cannot read part '%s': I/O error", p->name);
			return false;
		}
		const uint8_t *q = lead;
		if (multi) {
			if (get32(q) != (uint32_t)p->index) {
				fail(r, "corrupt chunk table in part '%s' (chunk %d)", p->name, k);
				return false;
			}
			q += 4;
		}
		if ((int32_t)get32(q) != y) {
			fail(r, "corrupt chunk table in part '%s' (chunk %d)", p->name, k);
			return false;
		}
		q += 4;
		if (p->deep) {
			c->counts_size = get64(q);
			c->packed = get64(q + 8);
			c->unpacked = get64(q + 16);
		} else {
			int32_t size = (int32_t)get32(q);
			if (size < 0) {
				fail(r, "corrupt chunk in part '%s' (line %d)", p->name, y);
				return false;
			}
			c->packed = (uint64_t)size;
			c->unpacked = (uint64_t)lines * line_bytes;
		}
		c->start = off;
		c->counts_off = off + leader;
		uint64_t avail = r->size - c->counts_off;
		if (c->counts_size > avail || c->packed > avail - c->counts_size) {
			fail(r, "truncated (part '%s')", p->name);
			return false;
		}
		c->data_off = c->counts_off + c->counts_size;
		c->end = c->data_off + c->packed;
		bool ok = plausible(p->comp, c->packed, c->unpacked);
		if (p->deep)
			ok = ok && c->unpacked % p->bpe == 0 &&
			     plausible(p->comp, c->counts_size, (uint64_t)p->width * 4);
		if (!ok) {
			fail(r, "corrupt chunk in part '%s' (line %d)", p->name, y);
			return false;
		}
		p->unpacked_total += c->unpacked;
		total += c->end - c->start + 8;
	}
	*part_bytes = total;
	return true;
}

static int cmp_range(const void *a, const void *b)
{
	const struct chunk *x = *(const struct chunk *const *)a, *y = *(const struct chunk *const *)b;
	return x->start < y->start ? -1 : x->start > y->start;
}

/* No two chunks may share bytes: the work of reading stays proportional to the file. */
static bool check_overlap(struct reader *r, struct rpart *parts, uint32_t nparts)
{
	uint64_t n = 0;
	for (uint32_t i = 0; i < nparts; i++)
		n += (uint64_t)parts[i].nchunks;
	if (n < 2)
		return true;
	const struct chunk **v = malloc((size_t)n * sizeof(*v));
	if (!v) {
		fail(r, "out of memory");
		return false;
	}
	size_t k = 0;
	for (uint32_t i = 0; i < nparts; i++)
		for (int32_t j = 0; j < parts[i].nchunks; j++)
			v[k++] = &parts[i].chunks[j];
	qsort(v, k, sizeof(*v), cmp_range);
	bool ok = true;
	for (size_t i = 1; i < k && ok; i++)
		ok = v[i - 1]->end <= v[i]->start;
	free(v);
	if (!ok)
		fail(r, "corrupt chunk table (chunks overlap)");
	return ok;
}

/* Allocate each channel's values: @n of them (at least one, so that data is never NULL). */
static bool alloc_values(struct reader *r, struct rpart *p, uint64_t n)
{
	if (n > SIZE_MAX / 4 - 1) {
		fail(r, "out of memory");
		return false;
	}
	for (uint32_t c = 0; c < p->nch; c++) {
		p->ch[c].data = malloc(((size_t)n + 1) * 4);
		if (!p->ch[c].data) {
			fail(r, "out of memory");
			return false;
		}
	}
	return true;
}

static bool read_table_data(struct reader *r, struct rpart *p, struct shot_table *t)
{
	/* Every stored value was checked against the packed bytes in read_chunks(). */
	if (!alloc_values(r, p, t->nrows))
		return false;
	size_t line = (size_t)SHOT_TABLE_WIDTH * p->bpe;
	uint8_t *raw = malloc(line * (size_t)p->lpc);
	if (!raw) {
		fail(r, "out of memory");
		return false;
	}
	bool ok = true;
	for (int32_t k = 0; k < p->nchunks && ok; k++) {
		const struct chunk *c = &p->chunks[k];
		int32_t y = k * p->lpc;
		uint8_t *packed = fetch(r, c->data_off, c->packed);
		if (!packed) {
			fail(r, "cannot read part '%s': I/O error", p->name);
			ok = false;
			break;
		}
		if (!unpack(&r->cod, p->comp, packed, (size_t)c->packed, raw, (size_t)c->unpacked)) {
			fail(r, "corrupt data in part '%s' (line %d)", p->name, y);
			ok = false;
			break;
		}
		const uint8_t *src = raw;
		for (uint64_t l = 0; l < c->unpacked / line && ok; l++) {
			uint64_t row0 = ((uint64_t)y + l) * SHOT_TABLE_WIDTH;
			size_t valid = row0 >= t->nrows ? 0
				       : t->nrows - row0 < SHOT_TABLE_WIDTH ? (size_t)(t->nrows - row0)
									    : SHOT_TABLE_WIDTH;
			for (uint32_t ch = 0; ch < p->nch && ok; ch++) {
				size_t sz = type_size(p->ch[ch].type);
				if (valid && !load_values(&p->ch[ch], row0, valid, src)) {
					fail(r, "part '%s': channel '%s' holds infinite or NaN values",
					     p->name, p->ch[ch].name);
					ok = false;
				} else if (!all_zero(src + valid * sz, (SHOT_TABLE_WIDTH - valid) * sz)) {
					fail(r, "corrupt data in part '%s' (padding is not zero)", p->name);
					ok = false;
				}
				src += SHOT_TABLE_WIDTH * sz;
			}
		}
	}
	free(raw);
	return ok;
}

static bool read_deep_data(struct reader *r, struct rpart *p, struct shot_deep *d)
{
	uint64_t npix = (uint64_t)d->width * d->height;
	/* read_chunks() bounded width * 4 by the packed counts and the entries by the packed data. */
	if (npix > SIZE_MAX / 8 - 1) {
		fail(r, "out of memory");
		return false;
	}
	uint64_t total = p->unpacked_total / p->bpe;
	d->offsets = malloc(((size_t)npix + 1) * 8);
	if (!d->offsets || !alloc_values(r, p, total)) {
		fail(r, "out of memory");
		return false;
	}
	d->offsets[0] = 0;
	size_t count_bytes = (size_t)d->width * 4;
	uint8_t *counts = malloc(count_bytes);
	uint8_t *raw = NULL;
	size_t raw_cap = 0;
	bool ok = counts != NULL;
	if (!ok)
		fail(r, "out of memory");
	uint64_t done = 0;
	for (uint32_t y = 0; y < d->height && ok; y++) {
		const struct chunk *c = &p->chunks[y];
		uint8_t *packed = fetch(r, c->counts_off, c->counts_size + c->packed);
		if (!packed) {
			fail(r, "cannot read part '%s': I/O error", p->name);
			ok = false;
			break;
		}
		if (!unpack(&r->cod, p->comp, packed, (size_t)c->counts_size, counts, count_bytes)) {
			fail(r, "corrupt sample counts in part '%s' (line %u)", p->name, y);
			ok = false;
			break;
		}
		uint64_t *o = d->offsets + (uint64_t)y * d->width;
		int32_t prev = 0;
		for (uint32_t x = 0; x < d->width; x++) {
			int32_t cum;
			memcpy(&cum, counts + 4 * (size_t)x, 4);
			if (cum < prev) {
				ok = false;
				break;
			}
			o[x + 1] = o[0] + (uint64_t)cum;
			prev = cum;
		}
		uint64_t nent = (uint64_t)prev;
		if (!ok || nent * p->bpe != c->unpacked || nent > total - done) {
			fail(r, "corrupt sample counts in part '%s' (line %u)", p->name, y);
			ok = false;
			break;
		}
		size_t n = (size_t)c->unpacked;
		if (!grow(&raw, &raw_cap, n ? n : 1)) {
			fail(r, "out of memory");
			ok = false;
			break;
		}
		if (!unpack(&r->cod, p->comp, packed + c->counts_size, (size_t)c->packed, raw, n)) {
			fail(r, "corrupt data in part '%s' (line %u)", p->name, y);
			ok = false;
			break;
		}
		const uint8_t *src = raw;
		for (uint32_t ch = 0; ch < p->nch && ok && nent; ch++) {
			if (!load_values(&p->ch[ch], done, (size_t)nent, src)) {
				fail(r, "part '%s': channel '%s' holds infinite or NaN values", p->name,
				     p->ch[ch].name);
				ok = false;
			}
			src += (size_t)nent * type_size(p->ch[ch].type);
		}
		done += nent;
	}
	free(counts);
	free(raw);
	return ok;
}

static void free_table(struct shot_table *t)
{
	free(t->name);
	for (uint32_t c = 0; t->channels && c < t->nchannels; c++) {
		free(t->channels[c].name);
		free(t->channels[c].data);
	}
	free(t->channels);
}

static void free_deep(struct shot_deep *d)
{
	free(d->name);
	free(d->offsets);
	for (uint32_t c = 0; d->channels && c < d->nchannels; c++) {
		free(d->channels[c].name);
		free(d->channels[c].data);
	}
	free(d->channels);
}

void shot_free(struct shot_file *f)
{
	if (!f)
		return;
	free(f->metadata);
	for (uint32_t i = 0; f->tables && i < f->ntables; i++)
		free_table(&f->tables[i]);
	for (uint32_t i = 0; f->deeps && i < f->ndeeps; i++)
		free_deep(&f->deeps[i]);
	free(f->tables);
	free(f->deeps);
	free(f->part_bytes);
	free(f);
}

/* Everything after the library has parsed the header. */
static struct shot_file *read_parts(struct reader *r, bool with_data, struct rpart **partsp,
				    uint32_t *npartsp)
{
	exr_context_t ctx = r->ctx;
	int count = 0;
	if (exr_get_count(ctx, &count) != EXR_ERR_SUCCESS || count < 1 || count > MAX_PARTS) {
		fail(r, "not a shot file (%d parts)", count);
		return NULL;
	}
	uint32_t nparts = (uint32_t)count;
	/* Identity and version first: a foreign or newer file gets the right message. */
	for (uint32_t i = 0; i < nparts; i++) {
		const exr_attribute_t *a = find_attr(r, (int)i, ATTR_FORMAT, EXR_ATTR_INT);
		if (!a) {
			fail(r, "not a shot file (part %u has no %s attribute)", i, ATTR_FORMAT);
			return NULL;
		}
		if (a->i != SHOT_FORMAT_VERSION) {
			fail(r, "format version %d, this relight reads %d", a->i, SHOT_FORMAT_VERSION);
			return NULL;
		}
	}
	const exr_attribute_t *meta = find_attr(r, 0, ATTR_METADATA, EXR_ATTR_STRING);
	uint64_t header_sum = 0;
	if (!meta || !parse_hex64(find_attr(r, 0, ATTR_HEADER_CHECKSUM, EXR_ATTR_STRING),
				  &header_sum)) {
		fail(r, "not a shot file (no %s or %s attribute)", ATTR_METADATA,
		     ATTR_HEADER_CHECKSUM);
		return NULL;
	}

	struct shot_file *f = calloc(1, sizeof(*f));
	struct rpart *parts = calloc(nparts, sizeof(*parts));
	*partsp = parts;
	*npartsp = nparts;
	if (!f || !parts) {
		free(f);
		fail(r, "out of memory");
		return NULL;
	}
	f->metadata = attr_dup(meta);
	if (!f->metadata) {
		fail(r, "corrupt metadata (a NUL byte inside)");
		goto bad;
	}
	for (uint32_t i = 0; i < nparts; i++) {
		struct rpart *p = &parts[i];
		exr_storage_t st;
		p->index = (int)i;
		if (exr_get_storage(ctx, p->index, &st) != EXR_ERR_SUCCESS ||
		    (st != EXR_STORAGE_SCANLINE && st != EXR_STORAGE_DEEP_SCANLINE)) {
			fail(r, "not a shot file (part %u is tiled)", i);
			goto bad;
		}
		p->deep = st == EXR_STORAGE_DEEP_SCANLINE;
		if (p->deep)
			f->ndeeps++;
		else
			f->ntables++;
	}
	f->tables = calloc(f->ntables ? f->ntables : 1, sizeof(*f->tables));
	f->deeps = calloc(f->ndeeps ? f->ndeeps : 1, sizeof(*f->deeps));
	f->part_bytes = calloc(nparts, sizeof(*f->part_bytes));
	if (!f->tables || !f->deeps || !f->part_bytes) {
		fail(r, "out of memory");
		goto bad;
	}

	struct hasher hs;
	hasher_init(&hs, 0);
	hash_u32(&hs, nparts);
	uint32_t nt = 0, nd = 0;
	for (uint32_t i = 0; i < nparts; i++) {
		struct rpart *p = &parts[i];
		struct shot_table *t = p->deep ? NULL : &f->tables[nt];
		struct shot_deep *d = p->deep ? &f->deeps[nd] : NULL;
		const exr_attribute_t *na = find_attr(r, p->index, "name", EXR_ATTR_STRING);
		char *name = na && valid_part_name(na->string->str, (size_t)na->string->length)
				     ? attr_dup(na)
				     : NULL;
		if (!name) {
			fail(r, "part %u has no valid name", i);
			goto bad;
		}
		/* Count the part before it may fail, so that shot_free() frees what it holds. */
		if (t) {
			t->name = name;
			nt++;
		} else {
			d->name = name;
			nd++;
		}
		p->name = name;
		for (uint32_t j = 0; j < i; j++) {
			if (!strcmp(parts[j].name, name)) {
				fail(r, "part name '%s' appears twice", name);
				goto bad;
			}
		}
		if (!parse_part(r, p, t, d))
			goto bad;
		const struct shot_channel *chp[MAX_CHANNELS];
		for (uint32_t c = 0; c < p->nch; c++)
			chp[c] = &p->ch[c];
		hash_part(&hs, p->deep, name, p->comp, t ? t->nrows : 0, d ? d->width : 0,
			  d ? d->height : 0, chp, p->nch);
	}
	hash_str(&hs, f->metadata);
	if (hasher_final(&hs) != header_sum && CHECKSUMS_ENFORCED) {
		fail(r, "header checksum mismatch (corrupt header)");
		goto bad;
	}

	/* Where the chunks are: tables' bytes first, then deep parts', as in struct shot_file. */
	bool multi = false;
	uint64_t table = 0;
	if (!find_offset_tables(r, nparts, &multi, &table)) {
		fail(r, "corrupt OpenEXR header");
		goto bad;
	}
	nt = 0;
	nd = 0;
	for (uint32_t i = 0; i < nparts; i++) {
		struct rpart *p = &parts[i];
		uint32_t slot = p->deep ? f->ntables + nd++ : nt++;
		if (!read_chunks(r, p, multi, table, &f->part_bytes[slot]))
			goto bad;
		table += (uint64_t)p->nchunks * 8;
	}
	if (!check_overlap(r, parts, nparts))
		goto bad;
	if (!with_data)
		return f;

	nt = 0;
	nd = 0;
	for (uint32_t i = 0; i < nparts; i++) {
		struct rpart *p = &parts[i];
		const struct shot_channel *chp[MAX_CHANNELS];
		for (uint32_t c = 0; c < p->nch; c++)
			chp[c] = &p->ch[c];
		uint64_t sum;
		if (p->deep) {
			struct shot_deep *d = &f->deeps[nd++];
			if (!read_deep_data(r, p, d))
				goto bad;
			uint64_t npix = (uint64_t)d->width * d->height;
			sum = data_checksum(chp, p->nch, d->offsets[npix], d->offsets, npix);
		} else {
			struct shot_table *t = &f->tables[nt++];
			if (!read_table_data(r, p, t))
				goto bad;
			sum = data_checksum(chp, p->nch, t->nrows, NULL, 0);
		}
		if (sum != p->checksum && CHECKSUMS_ENFORCED) {
			fail(r, "checksum mismatch in part '%s'", p->name);
			goto bad;
		}
	}
	return f;
bad:
	shot_free(f);
	return NULL;
}

static struct shot_file *read_source(struct reader *r, bool with_data)
{
	if (r->err && r->errlen)
		r->err[0] = '\0';
	uint8_t magic[4];
	if (r->size < 8 || !src_get(r, 0, magic, 4) || memcmp(magic, "\x76\x2f\x31\x01", 4) != 0) {
		fail(r, "not an OpenEXR file");
		return NULL;
	}
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	init.error_handler_fn = on_error;
	init.user_data = r;
	init.read_fn = read_src;
	init.size_fn = size_src;
	init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
	current_libmsg = r->libmsg;
	exr_result_t rv = exr_start_read(&r->ctx, r->name, &init);
	if (rv != EXR_ERR_SUCCESS) {
		if (r->max_end > r->size)
			fail(r, "truncated (in the header)");
		else
			fail(r, "corrupt OpenEXR header (%s)",
			     r->libmsg[0] ? r->libmsg : exr_get_default_error_message(rv));
		if (r->ctx)
			exr_finish(&r->ctx);
		current_libmsg = NULL;
		return NULL;
	}
	struct rpart *parts = NULL;
	uint32_t nparts = 0;
	struct shot_file *f = read_parts(r, with_data, &parts, &nparts);
	for (uint32_t i = 0; parts && i < nparts; i++)
		free(parts[i].chunks);
	free(parts);
	exr_finish(&r->ctx);
	current_libmsg = NULL;
	coder_finish(&r->cod);
	free(r->buf);
	r->buf = NULL;
	return f;
}

static struct shot_file *read_path(const char *path, bool with_data, char *err, size_t errlen)
{
	if (err && errlen)
		err[0] = '\0';
	if (!path || !path[0]) {
		say(err, errlen, "(no name): cannot read: empty file name");
		return NULL;
	}
	struct reader r = { .name = path, .err = err, .errlen = errlen };
	r.fd = open(path, O_RDONLY);
	if (r.fd < 0) {
		say(err, errlen, "%s: cannot read: %s", path, strerror(errno));
		return NULL;
	}
	struct stat st;
	if (fstat(r.fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		say(err, errlen, "%s: cannot read: not a regular file", path);
		close(r.fd);
		return NULL;
	}
	r.size = (uint64_t)st.st_size;
	struct shot_file *f = read_source(&r, with_data);
	close(r.fd);
	return f;
}

struct shot_file *shot_read(const char *path, char *err, size_t errlen)
{
	return read_path(path, true, err, errlen);
}

struct shot_file *shot_read_header(const char *path, char *err, size_t errlen)
{
	return read_path(path, false, err, errlen);
}

struct shot_file *shot_read_buffer(const char *name, const void *data, size_t size,
				   bool header_only, char *err, size_t errlen)
{
	static const uint8_t empty[1];
	struct reader r = { .name = name && name[0] ? name : "(buffer)", .fd = -1,
			    .mem = data ? data : empty, .size = data ? size : 0,
			    .err = err, .errlen = errlen };
	return read_source(&r, !header_only);
}

const struct shot_table *shot_find_table(const struct shot_file *f, const char *name)
{
	for (uint32_t i = 0; f && name && i < f->ntables; i++)
		if (f->tables[i].name && !strcmp(f->tables[i].name, name))
			return &f->tables[i];
	return NULL;
}

const struct shot_deep *shot_find_deep(const struct shot_file *f, const char *name)
{
	for (uint32_t i = 0; f && name && i < f->ndeeps; i++)
		if (f->deeps[i].name && !strcmp(f->deeps[i].name, name))
			return &f->deeps[i];
	return NULL;
}

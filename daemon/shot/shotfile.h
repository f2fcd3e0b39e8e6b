/*
 * The shot file container: what `relight bake` writes and the preview reads,
 * as one multi-part OpenEXR file that exrheader and oiiotool can open.
 *
 * A shot file holds
 *  - a JSON metadata document (lights, shader table, generated GLSL, channel
 *    map, batches, tiles, content hashes), stored as the string attribute
 *    "relight.metadata" of part 0;
 *  - tables: records of typed channels (shading samples, shadow geometry),
 *    each a scanline part of SHOT_TABLE_WIDTH columns whose last row is
 *    padded with zeros; the record count is the part's "relight.rows";
 *  - deep parts (the indirect framebuffer): per pixel a list of entries of
 *    typed channels.
 * Every part carries "relight.format" (SHOT_FORMAT_VERSION) and
 * "relight.checksum", a 64-bit hash of its channel data as stored (half
 * values as their 16 bits), so that a truncated, corrupted or foreign file is
 * refused with a clear error instead of read as wrong data. Files are written
 * to a temporary file in the same directory and renamed over the target: a
 * crash mid-write leaves any old file intact.
 */
#ifndef SHOT_FILE_H
#define SHOT_FILE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/** The format version this code writes; files of any other version are refused. */
#define SHOT_FORMAT_VERSION 1
/** Columns of a table part. */
#define SHOT_TABLE_WIDTH 1024

enum shot_type {
	SHOT_HALF,   /* stored as 16-bit float; float in memory */
	SHOT_FLOAT,  /* 32-bit float */
	SHOT_UINT,   /* 32-bit unsigned; uint32_t in memory */
};

enum shot_compression {
	SHOT_COMPRESS_NONE,
	SHOT_COMPRESS_RLE,
	SHOT_COMPRESS_ZIPS,  /* zlib, one scanline at a time (the only zlib mode of deep parts) */
	SHOT_COMPRESS_ZIP,   /* zlib, 16 scanlines at a time (tables only; deep parts use ZIPS) */
};

struct shot_channel {
	char *name;          /* EXR channel name (letters, digits, '.', '_'), unique in its part */
	enum shot_type type;
	/* The values: float (SHOT_HALF, SHOT_FLOAT) or uint32_t (SHOT_UINT), one per
	 * record of a table or per entry of a deep part, in order. */
	void *data;
};

/** Records of typed channels: the shading samples of one group, the shadow geometry, ... */
struct shot_table {
	char *name;          /* part name, unique in the file */
	uint64_t nrows;      /* may be 0 */
	uint32_t nchannels;  /* >= 1 */
	struct shot_channel *channels;
};

/** Per-pixel lists of entries (the indirect framebuffer). */
struct shot_deep {
	char *name;          /* part name, unique in the file */
	uint32_t width, height;
	/* width * height + 1 cumulative entry counts, row-major: pixel (x, y)'s
	 * entries are [offsets[y * width + x], offsets[y * width + x + 1]). */
	uint64_t *offsets;
	uint32_t nchannels;  /* >= 1 */
	struct shot_channel *channels;  /* offsets[width * height] values each */
};

struct shot_file {
	char *metadata;      /* JSON text, NUL-terminated */
	struct shot_table *tables;
	uint32_t ntables;
	struct shot_deep *deeps;
	uint32_t ndeeps;
	/* Filled by shot_read/shot_read_header: bytes each part takes in the file
	 * (tables first, then deep parts, in the order above). */
	uint64_t *part_bytes;
};

struct shot_write_options {
	enum shot_compression tables;   /* default (zero): SHOT_COMPRESS_NONE */
	enum shot_compression deep;     /* NONE, RLE or ZIPS */
};

/**
 * Write @f to @path atomically (temporary file + rename). @opts may be NULL.
 * On failure returns false with the reason in @err (always NUL-terminated)
 * and leaves any existing file at @path untouched.
 */
bool shot_write(const char *path, const struct shot_file *f, const struct shot_write_options *opts,
		char *err, size_t errlen);

/**
 * Read a whole shot file, verifying versions and checksums. NULL on failure
 * with a message naming the file and what is wrong ("truncated", "checksum
 * mismatch in part 'X'", "format version 7, this relight reads 1", "not a
 * shot file") in @err.
 */
struct shot_file *shot_read(const char *path, char *err, size_t errlen);

/**
 * Read the metadata, the part names, channel lists, sizes (nrows, width,
 * height) and part_bytes, but no channel data (data and offsets stay NULL).
 * Checks the format version, the header checksum and the chunk tables,
 * not the channel data.
 */
struct shot_file *shot_read_header(const char *path, char *err, size_t errlen);

/** Free a shot_file returned by shot_read or shot_read_header. Accepts NULL. */
void shot_free(struct shot_file *f);

/** The table / deep part named @name, or NULL. */
const struct shot_table *shot_find_table(const struct shot_file *f, const char *name);
const struct shot_deep *shot_find_deep(const struct shot_file *f, const char *name);

/**
 * The value a SHOT_HALF channel gives back for @v: rounded to the nearest
 * half as shot_write() stores it (NaN -> 0, beyond 65504 -> +-65504).
 */
float shot_half_round(float v);

/** The value of half-float bits @h (exact; infinities and NaN as themselves). */
float shot_half_value(uint16_t h);

/** The 64-bit content hash used for checksums (exposed for tests and content hashes). */
uint64_t shot_hash(const void *data, size_t len, uint64_t seed);

/*
 * How values are stored. shot_write() never modifies the caller's data.
 *  - SHOT_HALF: rounded to the nearest half, ties to even; NaN is stored as
 *    0 and magnitudes beyond 65504 (infinities included) as +-65504, the
 *    largest half: never as infinity.
 *  - SHOT_FLOAT: as given, except NaN (stored as 0) and infinities (stored
 *    as +-FLT_MAX).
 *  - SHOT_UINT: as given.
 * A file that holds an infinite or NaN value is refused when read.
 *
 * "relight.checksum" is shot_hash() (seed 0) of, for deep parts, each
 * pixel's entry count as a little-endian uint32, then of each channel's
 * values as stored (little-endian), channels in file order, which is sorted
 * by name. Part 0 also carries "relight.header.checksum", the hash of the
 * metadata and of every part's name, kind, compression, size and channel
 * list, so that a damaged header is refused like damaged data;
 * shot_read_header() checks it too. part_bytes counts each chunk with its
 * leader and its entry in the chunk offset table.
 */

/**
 * shot_read() of a file held in memory (@size bytes at @data, called @name
 * in messages), or, with @header_only, shot_read_header() of it. The bytes
 * stay the caller's. For fuzzing and tests.
 */
struct shot_file *shot_read_buffer(const char *name, const void *data, size_t size,
				   bool header_only, char *err, size_t errlen);

#endif

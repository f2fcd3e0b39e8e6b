/*
 * The OpenEXR file layer behind texture.h, shared by exr.c (which owns the
 * file format) and texture.c (MakeTexture, MakeShadow, lookups): files with
 * several levels (tiled mip-maps) and the attributes the texture system
 * reads besides the pixels.
 */
#ifndef REYES_EXR_INTERNAL_H
#define REYES_EXR_INTERNAL_H

#include "texture.h"

/** What reyes_exr_write() writes besides the pixels. */
struct reyes_exr_write_opts {
	bool half;                   /* channels other than "Z" as half, else float */
	bool mipmap;                 /* tiled 64x64, mip-mapped, level sizes rounded down */
	const char *wrapmodes;       /* "wrapmodes" string attribute; NULL: none */
	const char *const *strattrs; /* more string attributes: name, value, name, value... */
	uint32_t nstrattrs;          /* number of pairs */
	int envmap;                  /* REYES_ENVMAP_*: the "envmap" attribute, or none */
	float fov;                   /* a cube map's "fov" attribute (degrees), 0: none */
};

/* Kinds of environment map, as OpenEXR's "envmap" attribute has them. */
enum { REYES_ENVMAP_NONE, REYES_ENVMAP_LATLONG, REYES_ENVMAP_CUBE };

/**
 * Write @nlevels images as one OpenEXR file: scanline with ZIP compression
 * when @o->mipmap is false (then @nlevels must be 1), else tiled and
 * mip-mapped, levels[l] being level l (each level's size max(1, floor(size
 * of level 0 / 2^l)), all levels present). Level 0's matrices become the
 * worldToCamera / worldToNDC attributes. NaN and Inf are written as 0 (and
 * counted in a warning); values beyond the half range are clamped.
 * Atomic: PATH.tmp-XXXXXX, then rename(). Errors on @diag (NULL: stderr).
 */
bool reyes_exr_write(const char *path, const struct reyes_image *levels, uint32_t nlevels,
		     const struct reyes_exr_write_opts *o, FILE *diag);

/** An OpenEXR file as read, with what the texture system needs to know of it. */
struct reyes_exr_file {
	struct reyes_image *levels;  /* nlevels images, level 0 first; matrices on level 0 */
	uint32_t nlevels;
	bool half;                   /* every channel other than "Z" is stored as half */
	char wrapmodes[64];          /* the "wrapmodes" attribute, "" when absent */
	bool latlong;                /* an "envmap" attribute says latitude-longitude */
	bool cube;                   /* an "envmap" attribute says cube faces (see texture.c) */
	float fov;                   /* a cube map's "fov" attribute, 90 when absent */
	bool has_bias;               /* a float "bias" attribute (shadow maps) */
	float bias;
	char deepshadow[96];         /* the "deepshadow" attribute (deepshadow.h), "" when absent */
};

/**
 * Read @path: level 0 only, placed in the display window as
 * reyes_image_read_exr() does, or, with @all_levels, every level of a
 * mip-mapped (or the diagonal of a rip-mapped) tiled file, each as large
 * as its level. Values are converted to float but not otherwise changed.
 * False on any error (reported on @diag, NULL: stderr); @f is then empty.
 */
bool reyes_exr_read(const char *path, bool all_levels, struct reyes_exr_file *f, FILE *diag);

/** Free what reyes_exr_read() allocated (accepts an empty or zeroed @f). */
void reyes_exr_file_finish(struct reyes_exr_file *f);

#endif

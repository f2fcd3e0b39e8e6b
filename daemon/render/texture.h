/*
 * Images, textures and shadow maps, all OpenEXR files through the OpenEXR
 * C API (readable with exrheader, oiiotool...).
 *
 *  - Rendered images: scanline RGBA (+ Z, + AOVs), half or float, with
 *    worldToCamera / worldToNDC matrices as header attributes. Written to a
 *    temporary file and renamed, so a crash leaves any old file intact.
 *  - MakeTexture: a tiled, mip-mapped OpenEXR (levels by box-filtered
 *    halving), with the wrap modes as attributes.
 *  - MakeShadow: a depth map ("Z", float) with the light's worldToCamera and
 *    worldToNDC matrices, from a zfile/shadow display's output.
 *  - The texture system: open files once (cached by name, searched along the
 *    texture path), then filtered lookups for texture(), environment() and
 *    shadow() (percentage-closer filtering with samples, blur, bias, width).
 */
#ifndef REYES_TEXTURE_H
#define REYES_TEXTURE_H

#include "exec.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/** A float image, channels interleaved: pixel (x, y) channel c at data[(y*w + x)*nch + c]. */
struct reyes_image {
	uint32_t width, height, nchannels;
	const char **channel_names;      /* e.g. "R", "G", "B", "A", "Z", "diffuse.R" */
	float *data;
	bool has_matrices;
	float world_to_camera[16];       /* row-vector convention */
	float world_to_ndc[16];
};

/** Allocate width*height*nch zeroed floats and names (copied). False when too big. */
bool reyes_image_init(struct reyes_image *im, uint32_t w, uint32_t h, uint32_t nch,
		      const char *const *names);
void reyes_image_finish(struct reyes_image *im);

/**
 * Write @im as a scanline OpenEXR (ZIP compression; @half stores colour
 * channels as half, "Z" always float). Atomic: temporary file + rename.
 * Errors go to @diag (NULL: stderr) as "PATH: error: MESSAGE".
 */
bool reyes_image_write_exr(const char *path, const struct reyes_image *im, bool half,
			   FILE *diag);

/** Read any scanline or tiled OpenEXR (level 0) as float. */
bool reyes_image_read_exr(const char *path, struct reyes_image *im, FILE *diag);

/** MakeTexture: @swrap/@twrap "periodic", "clamp" or "black". */
bool reyes_make_texture(const char *in, const char *out, const char *swrap, const char *twrap,
			const char *filter, float swidth, float twidth, FILE *diag);

/**
 * MakeLatLongEnvironment: a latitude-longitude picture @in as an
 * environment map @out (a tiled, mip-mapped OpenEXR with "envmap"
 * latlong, periodic in s and clamped in t). Errors on @diag (NULL: stderr).
 */
bool reyes_make_latlong_environment(const char *in, const char *out, const char *filter,
				    float swidth, float twidth, FILE *diag);

/**
 * MakeCubeFaceEnvironment: six square pictures of one size, @faces in the
 * order px nx py ny pz nz, rendered with field of view @fov degrees (90:
 * the faces just meet), as one cube environment map @out (a tiled,
 * mip-mapped OpenEXR with "envmap" cube and a "fov" attribute; the faces
 * stacked in that order). Errors on @diag (NULL: stderr).
 */
bool reyes_make_cube_environment(const char *const faces[6], const char *out, float fov,
				 const char *filter, float swidth, float twidth, FILE *diag);

/** MakeShadow: @in is a depth image with matrices (a zfile or shadow display's output). */
bool reyes_make_shadow(const char *in, const char *out, FILE *diag);

struct reyes_texsys;

/**
 * A cache of opened textures and shadow maps. @searchpath: colon-separated
 * directories tried for relative names (NULL: the current directory only).
 * @camera_to_world: the renderer's "current" (camera) space to world, so
 * shadow() can take points from current space into the light's.
 */
struct reyes_texsys *reyes_texsys_create(const char *searchpath,
					 const float camera_to_world[16], FILE *diag);
void reyes_texsys_destroy(struct reyes_texsys *ts);

/* Lookups with the semantics of struct sl_host's callbacks (exec.h). Thread-safe. */
bool reyes_tex_texture(struct reyes_texsys *ts, const struct sl_tex_lookup *q);
bool reyes_tex_environment(struct reyes_texsys *ts, const struct sl_tex_lookup *q);
bool reyes_tex_shadow(struct reyes_texsys *ts, const struct sl_tex_lookup *q);
struct sl_lighthost;

/**
 * Answer @lh's texture(), environment() and shadow() lookups from @ts: sets
 * lh->owner to @ts and the three host callbacks (for code that runs shaders
 * through a light host outside the renderer: the CPU resolver, the GPU
 * runtime's checks).
 */
void reyes_tex_serve(struct sl_lighthost *lh, struct reyes_texsys *ts);

bool reyes_tex_info(struct reyes_texsys *ts, const char *name, const char *query, int type,
		    int arraylen, float *out, const char **sout);

/**
 * How many maps (textures, environments, shadow maps) the texture systems
 * of this process could not read, each name counted once per texture
 * system: lookups in them gave the fill value, so an image shaded with
 * them is not the scene's (relight preview's exit status says so).
 */
uint64_t reyes_tex_unread_maps(void);

/** A shadow map as reyes_tex_shadow() reads it (see reyes_tex_shadow_map). */
struct reyes_shadow_map_info {
	uint32_t width, height;
	/* Texel (x, y)'s depth at depth[(y * width + x) * stride]; valid while the texsys lives.
	 * NULL for a deep shadow map (deepshadow.h), whose texel p has the nodes
	 * [deep_offsets[p], deep_offsets[p + 1]) of deep_nodes, (z, T) pairs. */
	const float *depth;
	uint32_t stride;
	const uint32_t *deep_offsets;
	const float *deep_nodes;
	float world_to_camera[16];      /* row-vector convention, as struct reyes_image */
	float world_to_ndc[16];
	float bias;                     /* the map's own bias, else the default */
	float camera_to_world[16];      /* the texsys's "current" to world */
};

/**
 * Shadow map @name as shadow() finds it through @ts (loaded on first use).
 * False when it is missing, unreadable or not a shadow map (no depth
 * channel or no camera matrices): then shadow() gives the fill.
 */
bool reyes_tex_shadow_map(struct reyes_texsys *ts, const char *name,
			  struct reyes_shadow_map_info *out);

/** Wrap modes as struct reyes_tex_map_info gives them. */
enum reyes_wrap { REYES_WRAP_BLACK, REYES_WRAP_CLAMP, REYES_WRAP_PERIODIC, REYES_WRAP_MIRROR };

/** A texture or environment map as texture() and environment() read it (see reyes_tex_map). */
struct reyes_tex_map_info {
	/* Levels 0 .. nlevels - 1 as lookups read them (a cube map: those that
	 * still hold six faces), channels reordered R, G, B, A first; valid
	 * while the texsys lives. */
	const struct reyes_image *levels;
	uint32_t nlevels;
	uint32_t nchannels;
	enum reyes_wrap swrap, twrap;   /* texture()'s; environment() wraps periodic, clamp */
	bool cube;                      /* environment(): cube faces, else latitude-longitude */
	float fov;                      /* a cube map's field of view in degrees */
	uint32_t face_size[32];         /* a cube map: per level, the size of a face */
};

/**
 * Map @name as texture() and environment() find it through @ts (loaded on
 * first use, counted as unread when it cannot be). False when it is
 * missing or unreadable: lookups then give the fill.
 */
bool reyes_tex_map(struct reyes_texsys *ts, const char *name, struct reyes_tex_map_info *out);

#endif

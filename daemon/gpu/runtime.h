/*
 * The GPU runtime (lightspeed-2007 §5-§6): a shot file held in GPU memory
 * and relit there. Loading compiles every program the shot needs (one
 * kernel per surface shader and light shader it pairs with, and one per
 * surface with no light), so that no edit ever compiles: parameters are
 * uniforms.
 *
 * The work is a computation graph (graph.h) built from what the shot holds:
 * a source node per light and per surface with editable parameters; a
 * shadow-map node per light whose shader reads one (none when no light
 * casts shadows); a shading node per refinement band, holding the light
 * cache of its samples; a resolve node per refinement level; an 8-bit node
 * per level. Pulling a level runs only what changed upstream of it.
 *
 * Refinement bands: level 0 needs band 0 (one sample per 4x4 block), level
 * 1 bands 0-1, level 2 bands 0-2, level 3 (the final frame) all four. Each
 * band's samples are shaded once per change, so refining from one level to
 * the next shades only the new band.
 *
 * The light cache (§5.3): per band, the sum of the contributions of the
 * frozen lights, and per band and light the parameters that sum was made
 * with. Editing a frozen light unfreezes it: its cached contribution is
 * shaded again with the cached parameters and subtracted. Unfrozen lights
 * are shaded on every change; freezing one adds its current contribution.
 * A sample's colour is its surface with no light, plus the cache, plus the
 * unfrozen lights. The cache is float64: subtracting a contribution gives
 * back the sum before it exactly. This relies on surfaces being linear in
 * their lights; loading checks it on a few samples of each surface on the
 * CPU and warns about a surface that is not.
 */
#ifndef GPU_RUNTIME_H
#define GPU_RUNTIME_H

#include "gpu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

struct graph;
struct gpu_shot;

#define GPU_SHOT_LEVELS 4
#define GPU_SHOT_FINAL 3

struct gpu_shot_opts {
	FILE *diag;                /* messages; NULL: stderr */
	const char *texture_path;  /* where shadow maps are found; NULL: "." */
	size_t budget;             /* GPU bytes the shot may take; 0: 2 GiB */
	bool progress;             /* a progress bar on stderr while loading */
	const char *shader_path;   /* colon-separated folders where gpu_shot_add_light looks
				      for light shaders the shot lacks (then the folders of
				      the shot's own shaders); NULL: those alone */
};

/**
 * Load the shot at @path into @ctx (current on the calling thread): read
 * it, upload it tile by tile, compile its programs. NULL with a clear
 * message on opts->diag on failure (unreadable shot, a shader that changed
 * since the bake, over the budget: how much it needs).
 */
struct gpu_shot *gpu_shot_open(struct gpu_ctx *ctx, const char *path,
			       const struct gpu_shot_opts *opts);
void gpu_shot_close(struct gpu_shot *s);

uint32_t gpu_shot_width(const struct gpu_shot *s);
uint32_t gpu_shot_height(const struct gpu_shot *s);
/** Bytes of GPU memory the shot holds. */
size_t gpu_shot_bytes(const struct gpu_shot *s);
/** Shading samples of the shot. */
uint64_t gpu_shot_samples(const struct gpu_shot *s);
/** The graph (for inspection: nodes, how often each ran). */
const struct graph *gpu_shot_graph(const struct gpu_shot *s);

/* ---- lights ---- */

uint32_t gpu_shot_light_count(const struct gpu_shot *s);
/** Light @i's name (its RIB handle) and shader name. */
const char *gpu_shot_light_name(const struct gpu_shot *s, uint32_t i);
const char *gpu_shot_light_shader(const struct gpu_shot *s, uint32_t i);
/** The index of the light named @name, or -1. */
int gpu_shot_find_light(const struct gpu_shot *s, const char *name);

/**
 * Set parameter @param of light @light to @values (@n floats; one value
 * broadcasts to a colour; points and vectors in the light's shader space, as
 * in the RIB). Refused, with the reason in @err and nothing changed, for an
 * unknown light or parameter, a string or array parameter, a wrong count, a
 * value that is not finite or out of the parameter's range
 * (shotmeta.h shot_meta_check_edit).
 */
bool gpu_shot_set(struct gpu_shot *s, const char *light, const char *param,
		  const float *values, uint32_t n, char *err, size_t errlen);

/**
 * Set string parameter @param of light @light to @value, such as the map
 * uberlight's "slidename" names: a map that texture() or environment()
 * reads is loaded if it is new and bound, never compiled for. Refused, with
 * the reason in @err and nothing changed, for an unknown light or
 * parameter, a parameter that is not a string, or a value over 4095 bytes.
 */
bool gpu_shot_set_string(struct gpu_shot *s, const char *light, const char *param,
			 const char *value, char *err, size_t errlen);

/** The value of string parameter @param of light @light (free() it), or NULL if none. */
char *gpu_shot_get_string(const struct gpu_shot *s, const char *light, const char *param);

/** Is @param a string parameter of light @light? */
bool gpu_shot_param_is_string(const struct gpu_shot *s, const char *light, const char *param);

/** How many texture and environment maps the shot holds in GPU memory, and their bytes. */
uint32_t gpu_shot_texmaps(const struct gpu_shot *s, size_t *bytes);

/** The current value of a light's parameter (@out: 16 floats); false if none. */
bool gpu_shot_get(const struct gpu_shot *s, const char *light, const char *param, float out[16],
		  uint32_t *n);

/** A light parameter as a client shows it. */
struct gpu_shot_param {
	const char *name;
	const char *type;          /* "float", "color", "point", "vector", "normal", "matrix" */
	uint32_t n;                /* values: 1, 3 or 16 */
	float value[16];           /* current value, in the light's shader space (as edits take it) */
	float min, max;            /* the range edits must keep to (shot_meta_param_range) */
};

/**
 * Parameter @k of light @light (index) among those an edit can set (strings
 * and arrays are left out): false when @k is past the last one.
 */
bool gpu_shot_light_param(const struct gpu_shot *s, uint32_t light, uint32_t k,
			  struct gpu_shot_param *out);

/**
 * What pixel (@x, @y) shows (0, 0 the top left): the object (primitive id of
 * the bake) of the sample that weighs most in it, UINT32_MAX for none. False
 * for a pixel outside the image.
 */
bool gpu_shot_pick(const struct gpu_shot *s, uint32_t x, uint32_t y, uint32_t *object);

/** Whether light @light (index) reaches object @object: on, and linked to it. */
bool gpu_shot_light_reaches(const struct gpu_shot *s, uint32_t light, uint32_t object);

/** Mute or unmute a light (a muted light contributes nothing). */
bool gpu_shot_mute(struct gpu_shot *s, const char *light, bool muted, char *err, size_t errlen);

/** Solo a light (every other light is muted while it is), or none with NULL. */
bool gpu_shot_solo(struct gpu_shot *s, const char *light, char *err, size_t errlen);

/**
 * Light linking: whether @light illuminates object @object (the primitive
 * ids of the bake, see `relight info`). Objects start linked as the RIB's
 * Illuminate calls left them.
 */
bool gpu_shot_link(struct gpu_shot *s, const char *light, uint32_t object, bool linked,
		   char *err, size_t errlen);

/**
 * Freeze a light into the light cache, or unfreeze it. An edit of a frozen
 * light unfreezes it and freezes the lights unfrozen by earlier edits (not
 * those unfrozen here).
 */
bool gpu_shot_freeze(struct gpu_shot *s, const char *light, bool frozen, char *err,
		     size_t errlen);

/**
 * Shadows of light @light on or off (rerendering-2007 §5.4.1). Refused for a
 * light whose shader reads no shadow map.
 */
bool gpu_shot_shadows(struct gpu_shot *s, const char *light, bool on, char *err, size_t errlen);

/**
 * The look of a light's shadows (rerendering-2007 §5.4.2-5.4.3): of the
 * light its shadow maps block, the fraction @density in [0, 1] is taken away
 * (1, the default: as the shader casts them; 0: no shadow), tinted by
 * @color (each channel in [0, 1]; black, the default: all of it; a colour
 * lets that colour through). Per channel the light is the unshadowed light
 * times 1 - w plus the shadowed light times w, w = density * (1 - color):
 * two passes of the light's kernels, with and without its maps.
 */
bool gpu_shot_shadow_look(struct gpu_shot *s, const char *light, float density,
			  const float color[3], char *err, size_t errlen);

/**
 * Whether object @object receives the shadows of light @light (all do at
 * first): an object that does not is lit as with the light's shadows off.
 * Refused for a light whose shader reads no shadow map.
 */
bool gpu_shot_receive_shadows(struct gpu_shot *s, const char *light, uint32_t object,
			      bool receives, char *err, size_t errlen);

/**
 * Whether object @object casts the shadows of light @light (all do at
 * first). While some object does not, the light's maps are rendered on the
 * GPU from the shot's shadow geometry (gpu/shadowrender.h) with each map's
 * camera, size and bias, without those objects. Refused for a light whose
 * shader reads no shadow map, or a shot without shadow geometry.
 */
bool gpu_shot_cast_shadows(struct gpu_shot *s, const char *light, uint32_t object, bool casts,
			   char *err, size_t errlen);

/**
 * Let light @light's shadow maps follow it (lightspeed-2007 §6.1): each map
 * is rendered on the GPU from the shot's shadow geometry with a camera at
 * the light's "from" looking at its "to", keeping the projection, size and
 * bias of the map file (and its up direction, as far as it can). Off (the
 * default), a moved light keeps its map's camera, as a render of the RIB
 * edited the same way does. Refused for a light without shadow maps, without
 * "from" and "to" points, or a shot without shadow geometry.
 */
bool gpu_shot_shadow_follow(struct gpu_shot *s, const char *light, bool follow, char *err,
			    size_t errlen);

struct gpu_deep_stats;

/**
 * How many deep shadow maps were rendered from the shadow geometry since
 * the shot was opened (lights whose maps follow them, or whose casting is
 * edited); @last (may be NULL) gets what the last one took or, when it
 * failed, how far it got (gpu/shadowrender.h).
 */
uint32_t gpu_shot_deep_stats(const struct gpu_shot *s, struct gpu_deep_stats *last);

/**
 * The ray-traced shadows' hierarchy over the shadow geometry: its GPU bytes
 * (0 until a light's shadow is "raytrace"), and its nodes and triangles.
 */
size_t gpu_shot_shadow_bvh(const struct gpu_shot *s, uint32_t *nodes, uint32_t *tris);

/**
 * Set surface parameter @param, baked as editable (`relight bake
 * --dynamic-surface`), to @values on every object whose surface shader is
 * @shader (checked as light values are). The light cache is summed again.
 */
bool gpu_shot_set_surface(struct gpu_shot *s, const char *shader, const char *param,
			  const float *values, uint32_t n, char *err, size_t errlen);

/**
 * Add light @name of shader @shader (a light shader of the shot, or one
 * found on the shader path: then its kernels are compiled now, the one time
 * an edit compiles) with its parameters' defaults and @shader_to_world (NULL:
 * identity), reaching every object, unfrozen. Returns its index, or -1 with
 * the reason in @err.
 */
int gpu_shot_add_light(struct gpu_shot *s, const char *name, const char *shader,
		       const float shader_to_world[16], char *err, size_t errlen);

/** Remove a light (its index stays taken; gpu_shot_light_name gives NULL for it). */
bool gpu_shot_remove_light(struct gpu_shot *s, const char *light, char *err, size_t errlen);

/* ---- the imager ---- */

/*
 * A shot baked with an RIB Imager runs it on every level's image after the
 * resolve (imagerpass.h). gpu_shot_set and gpu_shot_get take its parameters
 * with SHOT_IMAGER ("imager", shotmeta.h) in place of a light's name.
 */

/** The shot's imager shader's name, or NULL when it has none. */
const char *gpu_shot_imager_shader(const struct gpu_shot *s);

/** Parameter @k of the imager among those an edit can set; false past the last. */
bool gpu_shot_imager_param(const struct gpu_shot *s, uint32_t k, struct gpu_shot_param *out);

/* ---- rendering ---- */

struct gpu_shot_stats {
	double ms;                 /* wall time of this call, the GPU finished */
	uint64_t entries;          /* indirect-framebuffer entries the level resolves */
	uint64_t shaded;           /* (sample, light) pairs shaded by this call */
	uint64_t batched;          /* those of them shaded in batches (GPU_SHOT_BATCH) */
	uint32_t dispatches;       /* kernels run */
};

/**
 * Bring refinement level @level (0..3) up to date with every edit so far:
 * shade what changed in bands 0..level and resolve the level. Its image
 * can then be read. False on a GPU error (message on opts->diag).
 */
bool gpu_shot_render(struct gpu_shot *s, int level, struct gpu_shot_stats *st);

/** Level @level's image: width * height premultiplied linear RGBA floats. */
bool gpu_shot_read_rgba(struct gpu_shot *s, int level, float *rgba);

/**
 * Level @level's image as linear half floats, RGBA (IEEE 754 binary16 bit
 * patterns, converted on the GPU; beyond 65504 clamped to it).
 */
bool gpu_shot_read_half(struct gpu_shot *s, int level, uint16_t *rgba);

/** Level @level's image as 8-bit sRGB (RGBA8, R in the low byte), encoded on the GPU. */
bool gpu_shot_read_srgb8(struct gpu_shot *s, int level, uint32_t *px);

/* ---- measuring ---- */

/** Lights one batch kernel shades (lights of one shader entering the light cache together). */
#define GPU_SHOT_BATCH 8

struct gpu_shot_profile {
	uint64_t samples;          /* shading samples the kernels ran over */
	double kernel_ms;          /* the shading kernels alone, best of three runs */
	double base_ms;            /* the same for the surfaces with no light: what reading
				      the records and writing the colours costs */
	double flops_per_sample;   /* float operations a sample takes (surface and light),
				      counted on the interpreter (exec.h sl_exec_ops) over up
				      to 1024 samples of each surface */
	double flops;              /* samples * flops_per_sample / kernel time */
	/*
	 * The batch kernels of the light's shader (when the shot has two
	 * lights of it or more): GPU_SHOT_BATCH passes, one light each, on one
	 * read of each record, adding into a light cache (one set aside, so
	 * the shot is untouched). 0 when there are none.
	 */
	uint32_t batch_lights;     /* lights a batch shades: GPU_SHOT_BATCH, or 0 */
	double batch_ms;           /* every sample, best of three runs */
	double batch_flops_per_sample; /* the surface once and the light's part per pass */
	double batch_flops;        /* samples * batch_flops_per_sample / batch_ms */
};

/**
 * Time the shading kernels of light @light over every sample of the shot,
 * without the light cache, the resolve or anything else, and count the
 * arithmetic they do: the shading rate to set beside the device's
 * arithmetic rate (microbench.h). The counts use the light's baked
 * parameters. False with the reason in @err.
 */
bool gpu_shot_profile(struct gpu_shot *s, const char *light, struct gpu_shot_profile *out,
		      char *err, size_t errlen);

#endif

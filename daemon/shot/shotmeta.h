/*
 * Reading a shot's metadata (the JSON of `relight bake`): its shaders,
 * light parameters and channels, and checking light edits against a
 * light's shader. Shared by the CPU resolver and the GPU runtime, so that
 * both read a shot, and refuse an edit, the same way.
 */
#ifndef SHOT_META_H
#define SHOT_META_H

#include "shotfile.h"
#include "mathlib.h"

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

struct sl_program;
struct sl_exec;
struct sl_spec;

/** The string member @key of @o, or NULL. */
const char *shot_meta_str(const cJSON *o, const char *key);

/** The 16 finite numbers of array member @key of @o into @m; false otherwise. */
bool shot_meta_matrix(const cJSON *o, const char *key, float m[16]);

/**
 * Compile the shader of entry @o as it was at bake time, found beside shot
 * file @shot ("source_relative"), at its absolute path ("source"), or by
 * its file name along $RELIGHT_SHADER_PATH, the shot's folder and the
 * standard library, the first whose program is the one baked
 * ("program_hash": comments and white space do not count; "source_hash" for
 * shots that have none). NULL with "relight: error: SHOT: ..." on @diag
 * when none is found, compiles, or is the same program. A surface entry with
 * an "atmosphere" (an entry of the same form) gives the surface joined with
 * it (sl_program_compose), which owns both.
 */
struct sl_program *shot_meta_shader(const cJSON *o, const char *shot, FILE *diag);

/**
 * Specialize surface shader @prog of surface entry @surface as the bake did:
 * its "dynamic_params" editable, uniform parameters cached
 * (SL_SPEC_CACHE_PARAMS), Ps's derivatives kept when the shot's lights
 * take them (@meta "light_derivatives"), and the slice's specular model
 * the shot's (shot_meta_specular_model). NULL with messages on @diag.
 */
struct sl_spec *shot_meta_specialize(const cJSON *meta, const cJSON *surface,
				     const struct sl_program *prog, FILE *diag);

/**
 * The specular model the shot was baked with (@meta "specular_model":
 * "prman" or "rispec"; a shot without the key is from before it and was
 * baked with "rispec"). shot_meta_specialize puts it in the spec's slice;
 * a CPU host shading the shot sets it too. False for another value.
 */
bool shot_meta_specular_model(const cJSON *meta, enum sl_specular_model *m);

/**
 * Set the parameters of a "params" array ({name, type, value}) on @x. False
 * with a message on @diag when an entry is malformed; values that are not
 * finite numbers read as 0.
 */
bool shot_meta_set_params(struct sl_exec *x, const cJSON *params, const char *shot, FILE *diag);

/**
 * A channel of surface table @t by name: stored, a constant of @chans
 * ("constants") or an alias ("aliases"). A constant is expanded into a new
 * array of t->nrows floats returned in *@owned (free() it). NULL when absent
 * or a UINT channel.
 */
const float *shot_meta_channel(const struct shot_table *t, const cJSON *chans, const char *name,
			       float **owned);

/**
 * The range the values of a light parameter named @name must lie in (what
 * shot_meta_check_edit enforces, and what a client shows): angles of cones
 * ("...angle") in [0, pi], "samples" in [1, 1024], anything else at most
 * 1e18 in magnitude.
 */
void shot_meta_param_range(const char *name, float *lo, float *hi);

/**
 * Check an edit of parameter @param of shader @light (@who names it in
 * messages: "light '3'", "surface 'plastic'") to
 * @values (@n of them): the parameter must exist, be a float, colour, point,
 * vector, normal or matrix (not a string or an array), take @n values (one
 * value broadcasts to a colour) that are finite and within the range the
 * parameter allows (angles of cones in [0, pi], sample counts in [1, 1024],
 * any value at most 1e18 in magnitude). On success the values as the
 * parameter takes them are written to @out (16 floats) and their count to
 * *@nout; otherwise false with the reason, naming the light and the
 * parameter, in @err (always NUL-terminated).
 */
bool shot_meta_check_edit(const struct sl_program *light, const char *who, const char *param,
			  const float *values, uint32_t n, float out[16], uint32_t *nout,
			  char *err, size_t errlen);

/**
 * What edits call the shot's imager (metadata "imager"), in place of a
 * light's name: `--set imager.PARAM=V`, {"light": "imager", ...}. A shot
 * with an imager and a light of that name refuses edits of either by it.
 */
#define SHOT_IMAGER "imager"

#endif

/*
 * The RIB scene builder: the meaning of RIB requests. It keeps the
 * graphics state (options, attribute and transform stacks, named
 * coordinate systems, lights, object instances, motion blocks), compiles the
 * shaders a scene names (once each), types parameter lists (inline
 * declarations, Declare, or the shader's own parameter types), and hands
 * each finished frame (at WorldEnd) to the caller. MakeTexture and
 * MakeShadow run where they appear, so a shadow pass's map exists before the
 * frame that uses it.
 */
#ifndef REYES_RI_H
#define REYES_RI_H

#include "rib.h"
#include "scene.h"

/**
 * An edit of a light's parameter, as 'relight preview --set' applies it to
 * a shot (struct resolve_edit): every LightSource whose handle is @light
 * gets @param set to @values, replacing the value the RIB gives, if any.
 * The values are in the light's shader space, as the RIB would give them:
 * one for a float, three for a colour, point, vector or normal (one value
 * broadcasts to a colour's three), sixteen for a matrix.
 */
struct reyes_light_edit {
	const char *light;             /* the RIB handle: "3", "key" */
	const char *param;
	float values[16];
	uint32_t nvalues;              /* 0: the value is @text, for a string parameter */
	const char *text;              /* the value as written */
};

/** What a read reported (struct reyes_ri_opts's counts). */
struct reyes_ri_counts {
	int errors;                    /* all errors printed, the reader's included */
	int fatal;                     /* of those, the ones that held back a frame or the read */
	int dropped;                   /* primitives dropped for their errors (the others rendered) */
	int warnings;                  /* warnings printed */
	int repeats;                   /* diagnostics not printed again at the same place */
	uint32_t frames;               /* frames read (WorldEnd), rendered or held back */
};

struct reyes_ri_opts {
	FILE *diag;                    /* diagnostics, NULL: stderr */
	int max_errors;                /* 0: 20 */
	/** Every warning is an error (relight render --strict). */
	bool strict;
	/** Where the read's counts go at its end; NULL: nowhere. */
	struct reyes_ri_counts *counts;
	/*
	 * The default shader search path ('@' in a searchpath option stands for
	 * it): colon-separated; the project's shaders/ directory comes last.
	 */
	const char *default_shader_path;
	const char *default_texture_path;
	/**
	 * Where a shader's #include looks after the shader's own folder
	 * (relight render -I): colon-separated, NULL for none; '@' in
	 * Option "searchpath" "include" stands for it.
	 */
	const char *default_include_path;
	/**
	 * Compiled shaders kept across reads (relight render's two reads of a
	 * scene), owned by the caller; NULL: each read compiles its own.
	 */
	struct reyes_shader_cache *shader_cache;
	/** Replace the file name of the frame's first image display (relight render -o). */
	const char *output_override;
	/**
	 * Light edits applied at each LightSource request of every frame, in
	 * order, after its parameter list (NULL when nlight_edits is 0; owned
	 * by the caller). An edit of a parameter the light's shader lacks, of
	 * a string or array parameter, with the wrong number of values or a
	 * value that is not finite is an error at that request; an edit whose
	 * light no LightSource declares is an error at the end of the read.
	 */
	const struct reyes_light_edit *light_edits;
	uint32_t nlight_edits;
	/**
	 * Read and check only: frames still go to @frame (to plan their
	 * outputs, say), but MakeTexture and MakeShadow are not run, as their
	 * input may be a file an earlier frame writes when rendered.
	 */
	bool check_only;
	/**
	 * Called at each WorldEnd with the finished scene (owned by the builder,
	 * valid during the call). Return false to stop (an error was reported).
	 */
	bool (*frame)(void *user, const struct reyes_scene *scene);
	void *user;
};

/**
 * Read the RIB file at @path and render its frames through opts->frame.
 * The error policy (docs/renderer.md, "Errors and warnings"):
 *  - "FILE:LINE: warning: MESSAGE" for what is ignored: requests,
 *    options, attributes and parameters relight does not know or support,
 *    shader parameters the shader does not declare. The frame renders.
 *  - "FILE:LINE: error: MESSAGE" inside a primitive's request (malformed
 *    data): that primitive is dropped, the rest of the frame renders.
 *  - any other error (syntax, unbalanced blocks, missing shaders or
 *    archives, options that cannot work) holds back its frame.
 * Each message is printed once per place; opts->strict makes warnings
 * errors. Returns false if there was any error; *nerrors gets the count
 * (may be NULL), opts->counts the details.
 */
bool reyes_ri_read(const char *path, const struct reyes_ri_opts *opts, int *nerrors);

#endif

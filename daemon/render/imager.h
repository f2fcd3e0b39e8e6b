/*
 * Imager shaders (RISpec 3.2, Imager): a shader run once per output pixel,
 * after the pixel filter and before exposure and quantization, on the
 * final colour of the frame. `relight render` runs the scene's on its
 * image; the CPU preview runs the shot's the same way (bake/resolve.c).
 */
#ifndef REYES_IMAGER_H
#define REYES_IMAGER_H

#include "scene.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

struct sl_exec;
struct reyes_texsys;

/** The frame an imager runs in: the globals that do not vary over its pixels. */
struct reyes_imager_frame {
	float time;    /* shutter open */
	float dtime;   /* shutter close - open */
};

/**
 * Run the imager @x (an executor of an imager program with its parameters
 * set, for grids of at least @w points) over @rgba: @w x @h pixels of
 * premultiplied linear RGBA, row-major from the top row. Per pixel it sees
 * Ci = RGB, Oi = (A, A, A), alpha = A, P = the pixel's centre in raster
 * space (x + 0.5, y + 0.5, 0), ncomps = 3 and @fr's time and dtime; the
 * pixel becomes (Ci, alpha). A value that is not finite is written as 0.
 * One row is one grid, so Du() runs along the row and Dv() is 0.
 * texture(), environment() and shadow() read files through @tex (NULL:
 * every file is missing). False when the shader stopped on a run-time error
 * (reported on stderr).
 */
bool reyes_imager_run(struct sl_exec *x, float *rgba, uint32_t w, uint32_t h,
		      const struct reyes_imager_frame *fr, struct reyes_texsys *tex);

/**
 * Give @x the parameter values of the instance @sh (the RIB's Imager
 * request); the others keep their defaults.
 */
void reyes_imager_set_params(struct sl_exec *x, const struct reyes_shader *sh);

/**
 * The renderer's pass: the imager @sh over the frame @rgba, as
 * reyes_imager_run. False (a message on @diag) when it cannot run.
 */
bool reyes_imager_apply(const struct reyes_shader *sh, float *rgba, uint32_t w, uint32_t h,
			const struct reyes_imager_frame *fr, struct reyes_texsys *tex, FILE *diag);

#endif

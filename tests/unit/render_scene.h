/*
 * What the end-to-end rendering tests share (test_render, test_lens,
 * test_render_attrs): a scratch folder, a RIB scene rendered through the
 * scene builder and the REYES pipeline to OpenEXR and read back, and the
 * image's pixels.
 */
#ifndef RELIGHT_TEST_RENDER_SCENE_H
#define RELIGHT_TEST_RENDER_SCENE_H

#include "texture.h"

#include <stdbool.h>
#include <stdint.h>

/* The scratch folder: scenes are written and rendered there. */
extern char tmpdir[256];

/* The diagnostics of the last render. A failed render prints them, unless
   failure_expected is set. */
extern char diag_text[8192];
extern bool failure_expected;

/* Make the scratch folder "/tmp/PREFIX-XXXXXX"; false (reported) on failure. */
bool scene_dir_create(const char *prefix);

/* Remove it, unless $RELIGHT_KEEP_TMP is set. */
void scene_dir_remove(void);

/* "tmpdir/NAME", in one of four rotating buffers. */
const char *tmp_path(const char *name);

/* Write @text to the file @name in the scratch folder (a shader, a map). */
bool scene_write_file(const char *name, const char *text);

/* Write @rib to a file and render it on two threads; the image named @out is
   read into @im. False when the scene has an error or the image is missing. */
bool render(const char *rib, const char *out, struct reyes_image *im);

/* The index of channel @name of @im, or -1. */
int channel(const struct reyes_image *im, const char *name);

/* Channel @c of pixel (@x, @y). */
float px(const struct reyes_image *im, int c, uint32_t x, uint32_t y);

/* The area of the disk (cx, cy, rad) inside pixel (x, y), by 256x256 subsamples. */
double disk_pixel(double cx, double cy, double rad, uint32_t x, uint32_t y);

#endif

/*
 * PNG output for display images (heat maps, previews, thumbnails), and the
 * sRGB transfer function that turns linear renderer values into the 8-bit
 * values such images hold.
 *
 * Files are 8 bits per sample, non-interlaced, every row with filter type 0
 * (None), compressed with zlib. They are written to a temporary file in the
 * destination's directory, synced and renamed over the destination, so a
 * failure leaves any old file intact.
 */
#ifndef REYES_PNG_H
#define REYES_PNG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/**
 * Write @pixels, @width x @height pixels of @nchannels bytes each, rows top
 * to bottom and tightly packed (row y starts at y * width * nchannels), as
 * an 8-bit PNG: @nchannels 1 is grey, 2 grey + alpha, 3 RGB, 4 RGBA (alpha
 * straight, not premultiplied). Width and height must be 1 to 2^31 - 1.
 * Errors go to @diag (NULL: stderr) as "PATH: error: cannot write: WHY".
 * The caller keeps @pixels.
 */
bool reyes_png_write(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
		     uint32_t nchannels, FILE *diag);

struct reyes_image;

/**
 * Write a renderer image of 1 to 4 float channels as an 8-bit PNG (grey,
 * grey + alpha, RGB, RGBA by the channel count). A channel named "A" that
 * comes last in a 2- or 4-channel image is the alpha: the other channels
 * are divided by it where it is above 0 (the renderer's colour is
 * premultiplied; PNG's alpha is straight) and it is stored through
 * reyes_unorm8(). Channels named "A" or "Z" otherwise go through
 * reyes_unorm8(), every other channel through reyes_srgb8(). Errors as
 * reyes_png_write().
 */
bool reyes_png_write_image(const char *path, const struct reyes_image *im, FILE *diag);

/**
 * The sRGB transfer function (IEC 61966-2-1) of a linear value, as a
 * continuous value in [0, 1]: 12.92 x up to x = 0.0031308, then
 * 1.055 x^(1/2.4) - 0.055. Values at or below 0, NaN included, give 0;
 * values at or above 1, +Inf included, give 1.
 */
float reyes_srgb_encode(float linear);

/**
 * reyes_srgb_encode() scaled to 0..255 and rounded to the nearest integer,
 * halves rounded up: floor(255 * encode + 0.5). So 0 -> 0, 1 -> 255,
 * 0.5 -> 188 (255 * 0.735357 = 187.52), NaN -> 0.
 */
uint8_t reyes_srgb8(float linear);

/**
 * A linear alpha or other non-colour value in 0..255: clamped to [0, 1]
 * (NaN -> 0), scaled by 255 and rounded as reyes_srgb8() does, with no
 * transfer function.
 */
uint8_t reyes_unorm8(float value);

/**
 * Convert @npixels pixels of linear RGBA floats (4 per pixel, colour
 * premultiplied by alpha as the renderer writes it) to display bytes.
 * Without @with_alpha, @out receives 3 bytes a pixel: the colour as seen
 * over black, each channel through reyes_srgb8(). With @with_alpha, @out
 * receives 4 bytes a pixel for a straight-alpha RGBA PNG: the colour
 * divided by alpha where alpha > 0 (left as it is otherwise) before the
 * transfer, and alpha through reyes_unorm8().
 */
void reyes_srgb8_rgba(const float *rgba, size_t npixels, bool with_alpha, uint8_t *out);

#endif

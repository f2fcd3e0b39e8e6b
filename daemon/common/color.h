/*
 * Display encoding shared by the CPU image writers and the GPU runtime: the
 * sRGB transfer and 8-bit rounding, defined once so that every path gives
 * the same bytes.
 */
#ifndef RL_COLOR_H
#define RL_COLOR_H

#include <stdint.h>

/** The sRGB transfer of a linear value clamped to [0, 1] (NaN -> 0). */
float rl_srgb_encode(float linear);

/** rl_srgb_encode() scaled to 0..255 and rounded: floor(255 * encode + 0.5). */
uint8_t rl_srgb8(float linear);

/** A linear value clamped to [0, 1] (NaN -> 0) in 0..255, rounded as rl_srgb8(). */
uint8_t rl_unorm8(float value);

#endif

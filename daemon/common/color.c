/*
 * Display encoding: see color.h.
 */
#include "color.h"

#include <math.h>

float rl_srgb_encode(float linear)
{
	/* Written so that NaN takes the first branch and +Inf the second. */
	if (!(linear > 0.0f))
		return 0.0f;
	if (linear >= 1.0f)
		return 1.0f;
	double x = linear;
	double v = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
	return (float)v;
}

uint8_t rl_srgb8(float linear)
{
	/* encode() is in [0, 1], so the sum is in [0.5, 255.5] and truncation is floor. */
	return (uint8_t)(rl_srgb_encode(linear) * 255.0f + 0.5f);
}

uint8_t rl_unorm8(float value)
{
	if (!(value > 0.0f))
		return 0;
	if (value >= 1.0f)
		return 255;
	return (uint8_t)(value * 255.0f + 0.5f);
}

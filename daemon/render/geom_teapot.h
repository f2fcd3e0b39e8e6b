/*
 * The Newell teapot (Geometry "teapot"): Martin Newell's 32 bicubic Bezier
 * patches (the public dataset, its 290 distinct control points), z up, its
 * base on z = 0, its lid's knob at z = 3.15, its spout towards +x, its
 * handle reaching x = -3, its body y = -2 to 2.
 */
#ifndef REYES_GEOM_TEAPOT_H
#define REYES_GEOM_TEAPOT_H

#include <stdint.h>

#define REYES_TEAPOT_PATCHES 32

/** The 16 control points of patch @i (row after row, 4 x 4, x y z each) into @P. */
void reyes_teapot_patch(uint32_t i, float P[48]);

#endif

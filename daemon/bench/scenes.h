/*
 * Scenes the benchmarks generate: a street of spheres lit by a chosen
 * number of lights, the shot bench_runtime and `relight bench`'s light-count
 * sweep time edits on.
 */
#ifndef BENCH_SCENES_H
#define BENCH_SCENES_H

#include <stdbool.h>
#include <stddef.h>

/**
 * Light @k (1-based) of the street, in the RIB's world space: 1 is the
 * spot light every benchmark edits, 2 an ambient light, 3 a distant light,
 * 4 and up point lights on a ring of @ring places (their angle is
 * 2 pi k / ring). Writes the RIB request into @buf ("LightSource ...").
 */
void bench_street_light(int k, int ring, float spot_intensity, char *buf, size_t size);

/** The same light's shader name and its parameters as edits take them. */
struct bench_light {
	const char *shader;
	float intensity;
	float from[3], to[3];      /* "from" and "to" where the shader has them */
	float color[3];            /* "lightcolor" */
};
void bench_street_light_params(int k, int ring, float spot_intensity, struct bench_light *out);

/**
 * Write the street RIB to @path: a ground, 8 x 4 spheres of three surface
 * shaders, @width x @height pixels (960 x 540: about half a million
 * shading samples), lights 1 to @nlights of a ring of @ring. False with
 * the reason in @err.
 */
bool bench_street_rib(const char *path, int width, int height, int nlights, int ring,
		      float spot_intensity, char *err, size_t errlen);

#endif

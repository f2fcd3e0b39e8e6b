/*
 * Noise and random numbers for RSL's noise(), pnoise(), cellnoise() and
 * random(). Everything is computed from an integer hash of the lattice
 * coordinates in 32-bit unsigned arithmetic and single-precision floats, with
 * no lookup tables, so that a GLSL 4.30 port computes the same values (the
 * hash bit for bit; the interpolation to float rounding).
 *
 * Ranges: noise is clamped to [0,1], is exactly 0.5 on the integer lattice
 * and averages 0.5. Extremes observed over 2^24 random points in [-32,32)^dim:
 * 1D [0.110, 0.926], 2D [0.032, 0.968], 3D [0.025, 0.973], 4D [0.027, 0.991]
 * (tests/unit/test_noise.c checks a 2^20-point sample against these).
 * cellnoise and random are uniform in [0,1) in steps of 2^-24.
 */
#ifndef SL_NOISE_H
#define SL_NOISE_H

#include <stdint.h>

/** Mix the bits of @h (an invertible avalanche permutation of 32-bit values). */
uint32_t sl_hash_mix(uint32_t h);

/**
 * Hash of the integer lattice point @ip (@dim coordinates, 1 to 4) under
 * @seed. Coordinates are reinterpreted as unsigned 32-bit values.
 */
uint32_t sl_hash_lattice(int dim, const int32_t *ip, uint32_t seed);

/** The top 24 bits of @h as a float in [0,1). */
float sl_hash_unit(uint32_t h);

/**
 * Gradient (Perlin) noise at @p (@dim coordinates, 1 to 4), in [0,1] around
 * 0.5. @period (may be NULL) gives an integer period per dimension; a period
 * <= 0 leaves that dimension non-periodic. @seed selects an independent noise
 * field (0 for the float-valued noise()). NaN coordinates count as 0 and
 * coordinates beyond +-2^30 are clamped.
 */
float sl_noise(int dim, const float *p, const int32_t *period, uint32_t seed);

/** noise() of one to four floats (seed 0, non-periodic). */
float sl_noise1(float x);
float sl_noise2(float x, float y);
float sl_noise3(float x, float y, float z);
float sl_noise4(float x, float y, float z, float w);

/**
 * Vector-valued noise (color noise, point noise): three decorrelated
 * channels, using seeds 1, 2 and 3. @period may be NULL.
 */
void sl_vnoise(int dim, const float *p, const int32_t *period, float out[3]);

/**
 * A value per integer cell in [0,1): constant for all points whose
 * coordinates have the same floors, different (as a hash is) across cells.
 */
float sl_cellnoise(int dim, const float *p, uint32_t seed);

/** Three decorrelated cellnoise channels (seeds 1, 2, 3). */
void sl_vcellnoise(int dim, const float *p, float out[3]);

/**
 * A pseudo-random number in [0,1), a pure function of (@seed, @index,
 * @counter): the grid interpreter passes the call site as the seed, the point
 * index, and the number of random() calls made so far in the run.
 */
float sl_random(uint32_t seed, uint32_t index, uint32_t counter);

/** Round a float period to the integer used by the periodic noises (<= 0: none). */
int32_t sl_noise_period(float period);

#endif

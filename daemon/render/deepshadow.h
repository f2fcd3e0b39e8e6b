/*
 * Deep shadow maps (Lokovic & Veach 2000): per pixel of a shadow camera, the
 * visibility function, the fraction of light that gets past depth z. The
 * renderer builds it from the hider's samples (a `Display "deepshad"
 * "deepopacity"`), the texture system loads it for shadow(), the GPU runtime
 * uploads the same arrays.
 *
 * A function is a list of nodes (z, T) with z nondecreasing: T is 1 before
 * the first node, the last node's T after the last one, and linear between
 * neighbouring nodes; two nodes at one depth are a step.
 *
 * The file: a scanline OpenEXR (the container of our depth maps) with two
 * float channels "T" and "Z", worldToCamera / worldToNDC like a depth map,
 * and a string attribute "deepshadow" = "relight-dsm 1 W H N": version 1, a
 * W x H map of N nodes in all. The image is W wide and H + ceil(N / W) high:
 * row y < H holds pixel (x, y)'s node count in Z and its final
 * transmittance in T; the rows after hold every pixel's nodes in pixel
 * order, W to a row, as (Z, T) pairs (the last row padded with zeros).
 */
#ifndef REYES_DEEPSHADOW_H
#define REYES_DEEPSHADOW_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

struct reyes_hider;
struct reyes_image;

/** The default error bound of the compressed functions (in transmittance). */
#define REYES_DEEP_DEFAULT_ERROR 0.005f

/** One pixel's function as the renderer builds it: @n nodes, zt[2k] = z, zt[2k + 1] = T. */
struct reyes_deep_pixel {
	uint32_t n;
	float *zt;
};

/** A loaded map: pixel p's nodes are [offsets[p], offsets[p + 1]) of zt (pairs). */
struct reyes_deep_map {
	uint32_t width, height;
	uint32_t *offsets;           /* width * height + 1 */
	float *zt;                   /* 2 * offsets[width * height] */
};

/** Scratch a thread reuses from pixel to pixel (zero it before the first use). */
struct reyes_deep_scratch {
	float *z, *o;                /* one sample's hits */
	size_t cap;
	struct deep_event *ev;       /* the pixel's hits, all samples */
	size_t evcap;
	double *ts;                  /* each sample's transmittance so far */
	size_t tscap;
};
void reyes_deep_scratch_finish(struct reyes_deep_scratch *s);

/**
 * Pixel (x, y) of the hider's current bucket: the mean over its own
 * xsamples x ysamples samples (a box over the pixel, as Lokovic and Veach
 * do) of each sample's transmittance step function, compressed so that no
 * depth is off by more than @error. Replaces @px's nodes. False when out
 * of memory.
 */
bool reyes_deep_build_pixel(const struct reyes_hider *h, uint32_t nsamples, uint32_t x,
			    uint32_t y, float error, struct reyes_deep_scratch *s,
			    struct reyes_deep_pixel *px);

/** Write @w x @h pixels as a deep map file (see above). Errors on @diag. */
bool reyes_deep_write(const char *path, uint32_t w, uint32_t h,
		      const struct reyes_deep_pixel *px, const float world_to_camera[16],
		      const float world_to_ndc[16], FILE *diag);

/**
 * Take the map out of @im, read from @path with "deepshadow" attribute
 * @attr: checked (sizes, counts, finite nondecreasing depths,
 * transmittances in [0, 1]), else "PATH: error: ..." on @diag and false.
 */
bool reyes_deep_from_image(const struct reyes_image *im, const char *attr, const char *path,
			   struct reyes_deep_map *m, FILE *diag);
void reyes_deep_map_finish(struct reyes_deep_map *m);

/** Texel (x, y)'s transmittance at depth @z. */
double reyes_deep_eval(const struct reyes_deep_map *m, uint32_t x, uint32_t y, double z);

#endif

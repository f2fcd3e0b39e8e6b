/*
 * libFuzzer target for the deep shadow map reader (render/deepshadow.c):
 * what a map file holds once OpenEXR has decoded it, fed to
 * reyes_deep_from_image as it is, then every texel of an accepted map
 * evaluated at a few depths. The input: the "deepshadow" attribute up to
 * the first newline (at most 95 bytes), a byte each for the image's width
 * and height (1 to 256), then its (T, Z) floats, little endian, zero when
 * the input ends early. Crashes, sanitizer reports and a transmittance
 * outside [0, 1] are failures; refusals are expected and discarded.
 */
#include "deepshadow.h"
#include "texture.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	char attr[96];
	size_t n = 0;
	while (n < size && n < sizeof(attr) - 1 && data[n] != '\n') {
		attr[n] = (char)data[n];
		n++;
	}
	attr[n] = '\0';
	size_t at = n < size ? n + 1 : n;
	uint32_t w = at < size ? data[at] + 1u : 1, h = at + 1 < size ? data[at + 1] + 1u : 1;
	at += 2;
	static const char *const names[2] = { "T", "Z" };
	struct reyes_image im;
	if (!reyes_image_init(&im, w, h, 2, names))
		return 0;
	size_t nf = (size_t)w * h * 2;
	for (size_t k = 0; k < nf && at + 4 <= size; k++, at += 4) {
		uint32_t u = (uint32_t)data[at] | (uint32_t)data[at + 1] << 8 |
			     (uint32_t)data[at + 2] << 16 | (uint32_t)data[at + 3] << 24;
		memcpy(&im.data[k], &u, sizeof(float));
	}
	im.has_matrices = true;
	FILE *diag = fopen("/dev/null", "w");
	struct reyes_deep_map m;
	if (reyes_deep_from_image(&im, attr, "fuzz.dsm", &m, diag)) {
		static const double depths[] = { -1e30, 0, 0.5, 1, 2, 1e30 };
		for (uint32_t y = 0; y < m.height; y++)
			for (uint32_t x = 0; x < m.width; x++)
				for (size_t k = 0; k < sizeof(depths) / sizeof(depths[0]); k++) {
					double t = reyes_deep_eval(&m, x, y, depths[k]);
					if (!(t >= 0.0 && t <= 1.0))
						abort();
				}
		reyes_deep_map_finish(&m);
	}
	if (diag)
		fclose(diag);
	reyes_image_finish(&im);
	return 0;
}

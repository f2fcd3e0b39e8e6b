/*
 * libFuzzer target for the shot file reader: every input is read from
 * memory as a shot file, first its header only, then whole. Every value of
 * a file that is accepted is read and the reader's promises are checked
 * (finite floats, non-decreasing offsets, data present), so that a bad
 * pointer, a length or a broken promise shows. Refusals are expected;
 * crashes, sanitizer reports, hangs and leaks are failures.
 */
#include "shotfile.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static uint64_t touch_channels(const struct shot_channel *ch, uint32_t nch, uint64_t n)
{
	uint64_t h = 0;
	for (uint32_t c = 0; c < nch; c++) {
		h += strlen(ch[c].name);
		if (!ch[c].data)
			continue;
		for (uint64_t i = 0; i < n; i++) {
			if (ch[c].type == SHOT_UINT) {
				h += ((const uint32_t *)ch[c].data)[i];
			} else {
				float v = ((const float *)ch[c].data)[i];
				if (!isfinite(v))
					abort();
				h += v > 0.0f;
			}
		}
	}
	return h;
}

static uint64_t touch(const struct shot_file *f, bool with_data)
{
	if (!f)
		return 0;
	uint64_t h = strlen(f->metadata);
	for (uint32_t i = 0; i < f->ntables; i++) {
		const struct shot_table *t = &f->tables[i];
		h += strlen(t->name) + f->part_bytes[i];
		if (with_data && (t->nchannels == 0 || !t->channels[0].data))
			abort();
		h += touch_channels(t->channels, t->nchannels, with_data ? t->nrows : 0);
	}
	for (uint32_t i = 0; i < f->ndeeps; i++) {
		const struct shot_deep *d = &f->deeps[i];
		h += strlen(d->name) + f->part_bytes[f->ntables + i];
		if (!with_data)
			continue;
		uint64_t npix = (uint64_t)d->width * d->height;
		if (!d->offsets || d->offsets[0] != 0)
			abort();
		for (uint64_t p = 0; p < npix; p++)
			if (d->offsets[p + 1] < d->offsets[p])
				abort();
		h += touch_channels(d->channels, d->nchannels, d->offsets[npix]);
	}
	return h;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	char err[512];
	volatile uint64_t sink = 0;
	struct shot_file *f = shot_read_buffer("fuzz.exr", data, size, true, err, sizeof(err));
	sink += touch(f, false);
	if (!f && strncmp(err, "fuzz.exr: ", 10) != 0)
		abort();
	shot_free(f);
	f = shot_read_buffer("fuzz.exr", data, size, false, err, sizeof(err));
	sink += touch(f, true);
	if (!f && strncmp(err, "fuzz.exr: ", 10) != 0)
		abort();
	shot_free(f);
	(void)sink;
	return 0;
}

/*
 * libFuzzer target for the RIB reader: every input is read as one RIB file
 * (plain or gzip-compressed). The handler reads every value it is given, so
 * that a bad pointer or length shows under the sanitizers. Crashes, sanitizer
 * reports, hangs and leaks are failures; diagnostics are expected and
 * discarded.
 */
#include "rib.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static size_t touch_value(const struct rib_value *v)
{
	size_t h = v->n + v->loc.line + strlen(v->loc.file);
	switch (v->type) {
	case RIB_NUMBER:
	case RIB_NUMBERS:
		for (uint32_t i = 0; i < v->n; i++)
			h += v->nums[i] != v->nums[i] ? 1 : (size_t)(v->nums[i] > 0);
		break;
	case RIB_STRING:
	case RIB_STRINGS:
		for (uint32_t i = 0; i < v->n; i++)
			h += strlen(v->strs[i]);
		break;
	}
	return h;
}

static bool touch(void *user, const struct rib_request *req)
{
	size_t *sink = user;
	size_t h = strlen(req->name) + req->loc.line;
	for (uint32_t i = 0; i < req->nargs; i++)
		h += touch_value(&req->args[i]);
	for (uint32_t i = 0; i < req->nparams; i++)
		h += strlen(req->params[i].token) + touch_value(&req->params[i].value);
	*sink += h;
	return true;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static FILE *devnull;
	if (!devnull) {
		devnull = fopen("/dev/null", "w");
		if (!devnull)
			return 0;
	}
	/* Small limits keep memory bounded whatever the input inflates to. */
	struct rib_reader_opts opts = {.diag = devnull, .max_array = 1 << 16};
	size_t sink = 0;
	rib_read_buffer("fuzz.rib", (const char *)data, size, &opts, touch, &sink, NULL);
	return 0;
}

/*
 * libFuzzer target for the protocol codec: every input is parsed as a text
 * frame (a request) and as a binary tile frame. An accepted request must
 * keep the codec's promises (an op in range, finite parameter values, 1 to
 * 16 of them, strings that are not NULL where the op needs them); an
 * accepted tile frame must hold exactly its pixels. Error replies are
 * printed as JSON. Refusals are expected; crashes, sanitizer reports, hangs
 * and leaks are failures.
 */
#include "proto.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct proto_request r;
	struct proto_error e;
	if (proto_parse_request((const char *)data, size, NULL, &r, &e)) {
		if ((unsigned)r.op >= PROTO_OP_COUNT)
			abort();
		for (uint32_t i = 0; i < r.nparams; i++) {
			if (!r.params[i].name || r.params[i].n < 1 || r.params[i].n > 16)
				abort();
			for (uint32_t k = 0; k < r.params[i].n; k++)
				if (!isfinite(r.params[i].values[k]))
					abort();
		}
		if ((r.op == PROTO_OPEN && !r.shot) || (r.op == PROTO_SET && (!r.light || !r.nparams)))
			abort();
		proto_request_free(&r);
	} else {
		char *j = proto_error_json(&e);
		if (!j || !strstr(j, "\"op\":\"error\""))
			abort();
		free(j);
	}
	struct proto_tile t;
	const uint8_t *px;
	char err[128];
	if (proto_tile_parse(data, size, &t, &px, err, sizeof(err)) &&
	    (px != data + PROTO_TILE_HEADER_BYTES ||
	     size - PROTO_TILE_HEADER_BYTES != proto_tile_pixel_bytes(&t)))
		abort();
	return 0;
}

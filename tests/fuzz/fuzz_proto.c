/*
 * libFuzzer target for the protocol codec: every input is parsed as a text
 * frame (a request), as a message before hello, as a binary tile frame, and
 * as the payload of a permessage-deflate frame (raw deflate; RFC 7692's
 * 00 00 ff ff tail appended), inflated in chunks as libwebsockets hands them
 * over and reassembled by proto_rx_feed under a message limit, as relightd
 * does, then parsed both ways.
 *
 * An accepted request must keep the codec's promises (an op in range, finite
 * parameter values, 1 to 16 of them, strings that are not NULL where the op
 * needs them); a hello that both readers accept must read the same in both;
 * reassembly never holds more than its limit and says so once; an accepted
 * tile frame must hold exactly its pixels. Error replies are printed as
 * JSON. Refusals are expected; crashes, sanitizer reports, hangs and leaks
 * are failures.
 */
#include "proto.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The message limit of the reassembly: relightd's default --max-message. */
#define MAX_MESSAGE (64u << 10)
/* Bytes of each inflated piece: libwebsockets' rx buffer in relightd is 64 KB;
 * smaller pieces reach the reassembly's edges faster. */
#define PIECE 1000

static void check_request(const char *text, size_t len)
{
	struct proto_request r;
	struct proto_error e;
	if (proto_parse_request(text, len, NULL, &r, &e)) {
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
		if (r.op == PROTO_ADD_LIGHT && !proto_shader_name_ok(r.shader))
			abort();
	} else {
		char *j = proto_error_json(&e);
		if (!j || !strstr(j, "\"op\":\"error\""))
			abort();
		free(j);
	}
	struct proto_request p;
	struct proto_error pe;
	bool pre = proto_parse_preauth(text, len, &p, &pe);
	if (pre && (unsigned)p.op >= PROTO_OP_COUNT)
		abort();
	if (pre && len > PROTO_PREAUTH_MAX)
		abort();
	/* Where both accept a hello they read the same id, version and token. */
	if (pre && e.code == 0 && r.op == PROTO_HELLO && p.op == PROTO_HELLO &&
	    (p.has_id != r.has_id || p.id != r.id || p.version != r.version ||
	     !p.token != !r.token || (p.token && strcmp(p.token, r.token))))
		abort();
	if (!pre) {
		char *j = proto_error_json(&pe);
		if (!j)
			abort();
		free(j);
	}
	proto_request_free(&p);
	if (e.code == 0)
		proto_request_free(&r);
}

/* Inflate @data as one permessage-deflate message and reassemble it; parse it when whole. */
static void check_deflated(const uint8_t *data, size_t size)
{
	z_stream z;
	memset(&z, 0, sizeof(z));
	if (inflateInit2(&z, -15) != Z_OK)
		return;
	uint8_t *in = malloc(size + 4);
	if (!in) {
		inflateEnd(&z);
		return;
	}
	memcpy(in, data, size);
	memcpy(in + size, "\x00\x00\xff\xff", 4);
	z.next_in = in;
	z.avail_in = (uInt)(size + 4);
	struct proto_rx rx = { 0 };
	uint8_t piece[PIECE];
	bool first = true, said = false, whole = false;
	size_t total = 0;
	for (int rounds = 0; rounds < 1 << 16; rounds++) {
		z.next_out = piece;
		z.avail_out = sizeof(piece);
		int zr = inflate(&z, Z_SYNC_FLUSH);
		size_t got = sizeof(piece) - z.avail_out;
		bool final = zr == Z_STREAM_END || (z.avail_in == 0 && z.avail_out != 0) ||
			     (zr != Z_OK && zr != Z_BUF_ERROR);
		total += got;
		enum proto_rx_result res = proto_rx_feed(&rx, piece, got, first, final, MAX_MESSAGE);
		first = false;
		if (rx.len > MAX_MESSAGE)
			abort();
		if (res == PROTO_RX_TOO_BIG) {
			if (said || total <= MAX_MESSAGE)
				abort();
			said = true;
		} else if (res == PROTO_RX_DISCARD) {
			if (!said)
				abort();
		} else if (res == PROTO_RX_MESSAGE) {
			if (rx.len != total)
				abort();
			whole = true;
		}
		if (final || zr == Z_BUF_ERROR)
			break;
	}
	if (whole)
		check_request(rx.buf, rx.len);
	proto_rx_finish(&rx);
	inflateEnd(&z);
	free(in);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	check_request((const char *)data, size);
	check_deflated(data, size);
	struct proto_tile t;
	const uint8_t *px;
	char err[128];
	if (proto_tile_parse(data, size, &t, &px, err, sizeof(err)) &&
	    (px != data + PROTO_TILE_HEADER_BYTES ||
	     size - PROTO_TILE_HEADER_BYTES != proto_tile_pixel_bytes(&t)))
		abort();
	return 0;
}

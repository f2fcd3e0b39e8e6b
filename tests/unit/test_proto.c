/*
 * The protocol codec: every request of the contract parses into what it
 * says; malformed, mistyped, out-of-range and oversized requests give the
 * right error code with the request's id; tile headers round-trip and bad
 * tile frames are refused.
 */
#include "proto.h"
#include "test.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static bool parse(const char *text, struct proto_request *r, struct proto_error *e)
{
	return proto_parse_request(text, strlen(text), NULL, r, e);
}

static void test_requests(void)
{
	struct proto_request r;
	struct proto_error e;
	CHECK(parse("{\"op\":\"hello\",\"version\":1,\"token\":\"abc\"}", &r, &e));
	CHECK(r.op == PROTO_HELLO && r.version == 1 && r.token && !strcmp(r.token, "abc") &&
	      !r.has_id);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"list\",\"id\":1}", &r, &e));
	CHECK(r.op == PROTO_LIST && r.has_id && r.id == 1);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"open\",\"id\":2,\"shot\":\"crowd\",\"format\":\"rgba16f\"}", &r, &e));
	CHECK(r.op == PROTO_OPEN && r.id == 2 && !strcmp(r.shot, "crowd") &&
	      r.format == PROTO_RGBA16F);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"open\",\"shot\":\"crowd\"}", &r, &e));
	CHECK(r.format == PROTO_RGBA8);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"set\",\"id\":3,\"light\":\"key\",\"params\":{\"intensity\":2.0,"
		    "\"from\":[1,2,3]}}", &r, &e));
	CHECK(r.op == PROTO_SET && r.id == 3 && !strcmp(r.light, "key") && r.nparams == 2);
	if (r.nparams == 2) {
		CHECK(!strcmp(r.params[0].name, "intensity") && r.params[0].n == 1 &&
		      r.params[0].values[0] == 2.0f);
		CHECK(!strcmp(r.params[1].name, "from") && r.params[1].n == 3 &&
		      r.params[1].values[2] == 3.0f);
	}
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"add_light\",\"light\":\"fill\",\"shader\":\"pointlight\"}", &r, &e));
	CHECK(r.op == PROTO_ADD_LIGHT && !strcmp(r.shader, "pointlight") && r.nparams == 0);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"solo\"}", &r, &e) && r.op == PROTO_SOLO && !r.light);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"solo\",\"light\":null}", &r, &e) && !r.light);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"mute\",\"light\":\"key\"}", &r, &e) && r.on);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"mute\",\"light\":\"key\",\"mute\":false}", &r, &e) && !r.on);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"freeze\",\"light\":\"key\",\"freeze\":false}", &r, &e) && !r.on);
	proto_request_free(&r);
	for (int op = 0; op < PROTO_OP_COUNT; op++)
		CHECK(strcmp(proto_op_name((enum proto_op)op), "?"));
	/* not NUL-terminated: only @len bytes count */
	const char *two = "{\"op\":\"stats\"}{\"op\":\"list\"}";
	CHECK(proto_parse_request(two, 14, NULL, &r, &e) && r.op == PROTO_STATS);
	proto_request_free(&r);
}

static void expect_error(const char *text, enum proto_error_code code, bool has_id)
{
	struct proto_request r;
	struct proto_error e;
	bool ok = parse(text, &r, &e);
	CHECK(!ok);
	if (ok) {
		fprintf(stderr, "accepted: %s\n", text);
		proto_request_free(&r);
		return;
	}
	if (e.code != code || e.has_id != has_id)
		fprintf(stderr, "%s: got %s (%s), id %d\n", text, proto_error_name(e.code), e.message,
			e.has_id);
	CHECK(e.code == code);
	CHECK(e.has_id == has_id);
	CHECK(e.message[0] != '\0');
	CHECK(r.params == NULL && r.priv == NULL);
	char *j = proto_error_json(&e);
	CHECK(j && strstr(j, "\"op\":\"error\"") && strstr(j, proto_error_name(code)));
	free(j);
}

static void test_errors(void)
{
	expect_error("", PROTO_E_MALFORMED, false);
	expect_error("{", PROTO_E_MALFORMED, false);
	expect_error("[1,2]", PROTO_E_MALFORMED, false);
	expect_error("{\"id\":4}", PROTO_E_MALFORMED, true);
	expect_error("{\"op\":7,\"id\":4}", PROTO_E_MALFORMED, true);
	expect_error("{\"op\":\"fly\",\"id\":5}", PROTO_E_UNKNOWN_OP, true);
	expect_error("{\"op\":\"list\",\"id\":1.5}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"list\",\"id\":1e300}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"hello\",\"version\":2}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"hello\"}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"hello\",\"version\":1,\"token\":5}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"open\",\"id\":6}", PROTO_E_TYPE, true);
	expect_error("{\"op\":\"open\",\"shot\":\"\"}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"open\",\"shot\":\"a\",\"format\":\"rgb\"}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"set\",\"id\":7,\"light\":\"k\"}", PROTO_E_TYPE, true);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{}}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":\"x\"}}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":1e39}}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":1e999}}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":[]}}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":[1,2,3,4,5,6,7,8,9,10,11,12,"
		     "13,14,15,16,17]}}", PROTO_E_RANGE, false);
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":[1,\"a\"]}}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"mute\",\"light\":\"k\",\"mute\":1}", PROTO_E_TYPE, false);
	expect_error("{\"op\":\"add_light\",\"light\":\"k\"}", PROTO_E_TYPE, false);
	/* limits */
	char big[600] = "{\"op\":\"open\",\"shot\":\"";
	size_t n = strlen(big);
	memset(big + n, 'a', 300);
	strcpy(big + n + 300, "\"}");
	expect_error(big, PROTO_E_LIMIT, false);
	char many[4096] = "{\"op\":\"set\",\"light\":\"k\",\"params\":{";
	for (int i = 0; i < 70; i++) {
		char p[32];
		snprintf(p, sizeof(p), "%s\"p%d\":1", i ? "," : "", i);
		strcat(many, p);
	}
	strcat(many, "}}");
	expect_error(many, PROTO_E_LIMIT, false);
}

/* Text frames are UTF-8 with no NUL, and one JSON object with nothing after it. */
static void test_text(void)
{
	expect_error("{\"op\":\"\xed\xa0\x80\"}", PROTO_E_MALFORMED, false);   /* a surrogate */
	expect_error("{\"op\":\"\xc0\xaf\"}", PROTO_E_MALFORMED, false);       /* overlong '/' */
	expect_error("{\"op\":\"\xf4\x90\x80\x80\"}", PROTO_E_MALFORMED, false); /* past U+10FFFF */
	expect_error("{\"op\":\"list\"}\xff", PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"li\xe2\x82\"}", PROTO_E_MALFORMED, false);     /* cut short */
	expect_error("{\"op\":\"list\"} x", PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"list\"}{}", PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"hello\",\"version\":1,\"token\":\"editor-token\\u0000x\"}",
		     PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"open\",\"shot\":\"shadows\\u0000\"}", PROTO_E_MALFORMED, false);
	struct proto_request r;
	struct proto_error e;
	/* a raw NUL inside the frame */
	CHECK(!proto_parse_request("{\"op\":\"list\"}\0", 15, NULL, &r, &e));
	CHECK(e.code == PROTO_E_MALFORMED);
	/* whitespace after the object, and text that is UTF-8 but not ASCII, are fine */
	CHECK(parse("{\"op\":\"list\"} \r\n", &r, &e) && r.op == PROTO_LIST);
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"open\",\"shot\":\"caf\xc3\xa9-\xf0\x9f\x92\xa1\"}", &r, &e) &&
	      r.op == PROTO_OPEN && !strcmp(r.shot, "caf\xc3\xa9-\xf0\x9f\x92\xa1"));
	proto_request_free(&r);
	/* an escaped backslash before "u0000" is no NUL */
	CHECK(parse("{\"op\":\"open\",\"shot\":\"a\\\\u0000\"}", &r, &e) && r.op == PROTO_OPEN);
	proto_request_free(&r);
}

/* Replies: ids printed exactly, text made UTF-8. */
static void test_reply_text(void)
{
	static const int64_t ids[] = { 0, -1, 9007199254740992LL, -9007199254740992LL,
				       6000000000000001LL, 4503599627370497LL };
	for (size_t i = 0; i < sizeof(ids) / sizeof(ids[0]); i++) {
		struct proto_error e = { .code = PROTO_E_RANGE, .has_id = true, .id = ids[i] };
		snprintf(e.message, sizeof(e.message), "x");
		char *j = proto_error_json(&e), want[64];
		snprintf(want, sizeof(want), "\"id\":%lld,", (long long)ids[i]);
		CHECK(j && strstr(j, want));
		free(j);
	}
	char a[] = "ok \xc3\xa9 cut \xe2\x82", b[] = "\xed\xa0\x80x", c[] = "caf\xc3\xa9";
	proto_utf8_clean(a);
	proto_utf8_clean(b);
	proto_utf8_clean(c);
	CHECK_STR(a, "ok \xc3\xa9 cut ??");
	CHECK_STR(b, "???x");
	CHECK_STR(c, "caf\xc3\xa9");
	/* a message cut in the middle of a character comes out as UTF-8 */
	struct proto_error e = { .code = PROTO_E_UNKNOWN_OP };
	memset(e.message, 'a', sizeof(e.message));
	e.message[sizeof(e.message) - 2] = (char)0xe2;
	e.message[sizeof(e.message) - 1] = '\0';
	char *j = proto_error_json(&e);
	CHECK(j && !strchr(j, (char)0xe2) && strstr(j, "a?\""));
	free(j);
}

static void test_tiles(void)
{
	struct proto_tile t = { 7, 2, PROTO_RGBA16F, 64, 32, 16, 8 }, u;
	size_t nb = proto_tile_pixel_bytes(&t);
	CHECK(nb == 16 * 8 * 8);
	uint8_t *frame = calloc(PROTO_TILE_HEADER_BYTES + nb + 1, 1);
	proto_tile_header(&t, frame);
	CHECK(!memcmp(frame, "RLT1", 4) && frame[4] == PROTO_TILE_HEADER_BYTES && frame[8] == 7);
	const uint8_t *px;
	char err[128];
	CHECK(proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb, &u, &px, err, sizeof(err)));
	CHECK(!memcmp(&t, &u, sizeof(t)) && px == frame + PROTO_TILE_HEADER_BYTES);
	/* short, long, bad magic, bad header size, unknown format, empty, overflowing */
	CHECK(!proto_tile_parse(frame, 10, &u, &px, err, sizeof(err)) && !px);
	CHECK(!proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb - 1, &u, &px, err, sizeof(err)));
	CHECK(!proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb + 1, &u, &px, err, sizeof(err)));
	frame[0] = 'X';
	CHECK(!proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb, &u, &px, err, sizeof(err)));
	frame[0] = 'R';
	frame[4] = 40;
	CHECK(!proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb, &u, &px, err, sizeof(err)));
	frame[4] = PROTO_TILE_HEADER_BYTES;
	struct proto_tile bad = t;
	bad.format = 9;
	proto_tile_header(&bad, frame);
	CHECK(!proto_tile_parse(frame, PROTO_TILE_HEADER_BYTES + nb, &u, &px, err, sizeof(err)));
	bad = t;
	bad.width = 0;
	CHECK(proto_tile_pixel_bytes(&bad) == 0);
	bad.width = bad.height = 0xffffffffu;
	CHECK(sizeof(size_t) < 8 || proto_tile_pixel_bytes(&bad) == (size_t)0xffffffffu * 0xffffffffu * 8 ||
	      proto_tile_pixel_bytes(&bad) == 0);
	free(frame);
}

int main(void)
{
	RUN(test_requests);
	RUN(test_errors);
	RUN(test_text);
	RUN(test_reply_text);
	RUN(test_tiles);
	return test_finish();
}

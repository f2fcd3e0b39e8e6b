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
	/* a string parameter's value: its text, no numbers */
	CHECK(parse("{\"op\":\"set\",\"light\":\"2\",\"params\":{\"slidename\":\"b.tx\"}}", &r,
		    &e) && r.nparams == 1 && r.params[0].n == 0 && r.params[0].text &&
	      !strcmp(r.params[0].text, "b.tx"));
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"set\",\"light\":\"2\",\"params\":{\"i\":2}}", &r, &e) &&
	      r.nparams == 1 && r.params[0].n == 1 && !r.params[0].text);
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
	expect_error("{\"op\":\"set\",\"light\":\"k\",\"params\":{\"i\":true}}", PROTO_E_TYPE, false);
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

/* Repeated member names are refused wherever they are, however they are spelled. */
static void test_duplicates(void)
{
	expect_error("{\"op\":\"hello\",\"version\":1,\"token\":\"aaaaaaaa\",\"token\":\"bbbbbbbb\"}",
		     PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"list\",\"op\":\"bogus\"}", PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"list\",\"\\u006fp\":\"list\"}", PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"set\",\"light\":\"a\",\"params\":{\"i\":1,\"i\":2}}",
		     PROTO_E_MALFORMED, false);
	expect_error("{\"op\":\"list\",\"x\":[{\"a\":1,\"a\":1}]}", PROTO_E_MALFORMED, false);
	/* the same name in two objects is no repeat */
	struct proto_request r;
	struct proto_error e;
	CHECK(parse("{\"op\":\"set\",\"light\":\"a\",\"params\":{\"light\":1,\"op\":2}}", &r, &e));
	proto_request_free(&r);
	/* a large object: sorted, not compared pairwise */
	char big[70000];
	size_t n = (size_t)snprintf(big, sizeof(big), "{\"op\":\"list\"");
	for (int i = 0; i < 5000; i++)
		n += (size_t)snprintf(big + n, sizeof(big) - n, ",\"k%d\":0", i);
	snprintf(big + n, sizeof(big) - n, ",\"k4999\":1}");
	expect_error(big, PROTO_E_MALFORMED, false);
}

/* add_light's shader is a name: no path gets as far as the daemon. */
static void test_shader_names(void)
{
	struct proto_request r;
	struct proto_error e;
	CHECK(parse("{\"op\":\"add_light\",\"light\":\"k\",\"shader\":\"pointlight\"}", &r, &e));
	CHECK(r.shader && !strcmp(r.shader, "pointlight"));
	proto_request_free(&r);
	CHECK(parse("{\"op\":\"add_light\",\"light\":\"k\",\"shader\":\"_spot2\"}", &r, &e));
	proto_request_free(&r);
	static const char *const bad[] = { "../../../tmp/x/evil", "/tmp/x/evil", "a/b", "..",
					   ".hidden", "evil.sl", "2light", "a b", "a\\\\b", "x-y" };
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		char text[256];
		snprintf(text, sizeof(text), "{\"op\":\"add_light\",\"id\":4,\"light\":\"k\","
			 "\"shader\":\"%s\"}", bad[i]);
		expect_error(text, PROTO_E_RANGE, true);
		CHECK(!proto_shader_name_ok(bad[i]));
	}
	CHECK(proto_shader_name_ok("spotlight") && !proto_shader_name_ok("") &&
	      !proto_shader_name_ok(NULL));
}

static bool preauth(const char *text, struct proto_request *r, struct proto_error *e)
{
	return proto_parse_preauth(text, strlen(text), r, e);
}

/* Before hello: op, id, version and token only, from one flat object of 4 KB at most. */
static void test_preauth(void)
{
	struct proto_request r;
	struct proto_error e;
	CHECK(preauth(" {\"op\":\"hello\",\"id\":-3,\"version\":1,\"token\":\"a\\u00e9\\ud83d\\ude00\\n\"} ", &r,
		      &e));
	CHECK(r.op == PROTO_HELLO && r.has_id && r.id == -3 && r.version == 1);
	CHECK(r.token && !strcmp(r.token, "a\xc3\xa9\xf0\x9f\x98\x80\n"));
	proto_request_free(&r);
	/* other members are stepped over, nested ones too */
	CHECK(preauth("{\"x\":[1,{\"a\":[true,false,null,-1.5e3]}],\"op\":\"hello\",\"version\":1}",
		      &r, &e));
	CHECK(r.op == PROTO_HELLO && !r.token);
	proto_request_free(&r);
	CHECK(preauth("{\"op\":\"hello\",\"version\":1,\"token\":null}", &r, &e) && !r.token);
	proto_request_free(&r);
	/* another op: its op and id, for the "say hello first" reply */
	CHECK(preauth("{\"op\":\"set\",\"id\":9,\"params\":{\"a\":[1,2]}}", &r, &e));
	CHECK(r.op == PROTO_SET && r.has_id && r.id == 9 && !r.params && !r.priv);
	proto_request_free(&r);

	/* the same verdicts as the full parser */
	static const struct { const char *text; enum proto_error_code code; bool has_id; } bad[] = {
		{ "", PROTO_E_MALFORMED, false },
		{ "{", PROTO_E_MALFORMED, false },
		{ "[1]", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1,}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":01}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1}x", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1} {}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1,\"token\":\"\\ud800\"}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1,\"token\":\"a\\u0000b\"}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"id\":1,\"version\":1,\"token\":\"\xff\"}", PROTO_E_MALFORMED, true },
		{ "{\"op\":\"hello\",\"version\":1,\"op\":\"hello\"}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"hello\",\"version\":1,\"t\\u006fken\":\"a\",\"token\":\"b\"}", PROTO_E_MALFORMED, false },
		{ "{\"id\":2}", PROTO_E_MALFORMED, true },
		{ "{\"op\":7}", PROTO_E_MALFORMED, false },
		{ "{\"op\":\"bogus\",\"id\":5}", PROTO_E_UNKNOWN_OP, true },
		{ "{\"op\":\"hello\",\"id\":1.5}", PROTO_E_TYPE, false },
		{ "{\"op\":\"hello\"}", PROTO_E_TYPE, false },
		{ "{\"op\":\"hello\",\"version\":2}", PROTO_E_RANGE, false },
		{ "{\"op\":\"hello\",\"version\":1,\"token\":5}", PROTO_E_TYPE, false },
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		bool ok = preauth(bad[i].text, &r, &e);
		if (ok || e.code != bad[i].code || e.has_id != bad[i].has_id)
			fprintf(stderr, "preauth %s: %s %s (%s)\n", bad[i].text, ok ? "accepted" : "refused",
				proto_error_name(e.code), e.message);
		CHECK(!ok && e.code == bad[i].code && e.has_id == bad[i].has_id);
		CHECK(!r.owned && !r.token);
		/* the full parser agrees, but for a leading zero that cJSON reads */
		if (strstr(bad[i].text, ":01"))
			continue;
		struct proto_error e2;
		bool ok2 = parse(bad[i].text, &r, &e2);
		if (ok2 || e2.code != e.code)
			fprintf(stderr, "full parser on %s: %s\n", bad[i].text, ok2 ? "ok" : e2.message);
		CHECK(!ok2 && e2.code == e.code);
		if (ok2)
			proto_request_free(&r);
	}
	/* too deep, too long, a token too long */
	char deep[400];
	size_t n = (size_t)snprintf(deep, sizeof(deep), "{\"op\":\"hello\",\"version\":1,\"x\":");
	for (int i = 0; i < 100; i++)
		deep[n++] = '[';
	for (int i = 0; i < 100; i++)
		deep[n++] = ']';
	snprintf(deep + n, sizeof(deep) - n, "}");
	CHECK(!preauth(deep, &r, &e) && e.code == PROTO_E_MALFORMED);
	char *big = malloc(PROTO_PREAUTH_MAX + 64);
	n = (size_t)snprintf(big, 64, "{\"op\":\"hello\",\"version\":1,\"pad\":\"");
	memset(big + n, 'x', PROTO_PREAUTH_MAX - n - 2);
	memcpy(big + PROTO_PREAUTH_MAX - 2, "\"}", 3);
	CHECK(strlen(big) == PROTO_PREAUTH_MAX && preauth(big, &r, &e));
	proto_request_free(&r);
	memcpy(big + PROTO_PREAUTH_MAX - 2, "x\"}", 4);
	CHECK(!preauth(big, &r, &e) && e.code == PROTO_E_LIMIT);
	free(big);
	char tok[400];
	n = (size_t)snprintf(tok, sizeof(tok), "{\"op\":\"hello\",\"version\":1,\"token\":\"");
	memset(tok + n, 'a', 257);
	snprintf(tok + n + 257, sizeof(tok) - n - 257, "\"}");
	CHECK(!preauth(tok, &r, &e) && e.code == PROTO_E_LIMIT);
	CHECK(!parse(tok, &r, &e) && e.code == PROTO_E_LIMIT);
}

/* Reassembly: the limit holds on the whole message, and is said once. */
static void test_rx(void)
{
	struct proto_rx rx = { 0 };
	char chunk[1000];
	memset(chunk, 'a', sizeof(chunk));
	CHECK(proto_rx_feed(&rx, "{\"op\"", 5, true, false, 100) == PROTO_RX_MORE);
	CHECK(proto_rx_feed(&rx, ":\"list\"}", 8, false, true, 100) == PROTO_RX_MESSAGE);
	CHECK(rx.len == 13 && !strcmp(rx.buf, "{\"op\":\"list\"}"));
	/* the next message starts afresh */
	CHECK(proto_rx_feed(&rx, "{}", 2, true, true, 100) == PROTO_RX_MESSAGE && rx.len == 2);
	/* exactly the limit, then one byte over */
	CHECK(proto_rx_feed(&rx, chunk, 60, true, false, 100) == PROTO_RX_MORE);
	CHECK(proto_rx_feed(&rx, chunk, 40, false, true, 100) == PROTO_RX_MESSAGE && rx.len == 100);
	CHECK(proto_rx_feed(&rx, chunk, 60, true, false, 100) == PROTO_RX_MORE);
	CHECK(proto_rx_feed(&rx, chunk, 41, false, false, 100) == PROTO_RX_TOO_BIG);
	CHECK(rx.len == 60 && rx.cap <= 4096);
	/* every chunk after it (inflated pieces of the same frame, a new frame) is dropped */
	for (int i = 0; i < 1000; i++)
		CHECK(proto_rx_feed(&rx, chunk, sizeof(chunk), i % 2 == 0, false, 100) ==
		      PROTO_RX_DISCARD);
	CHECK(rx.len == 60);
	proto_rx_finish(&rx);
	CHECK(!rx.buf && !rx.len);
	proto_rx_finish(NULL);
	/* one chunk over the limit on its own, and SIZE_MAX arithmetic */
	CHECK(proto_rx_feed(&rx, chunk, 101, true, true, 100) == PROTO_RX_TOO_BIG && !rx.buf);
	proto_rx_finish(&rx);
	CHECK(proto_rx_feed(&rx, chunk, 10, true, false, 100) == PROTO_RX_MORE);
	CHECK(proto_rx_feed(&rx, chunk, SIZE_MAX - 5, false, false, 100) == PROTO_RX_TOO_BIG);
	proto_rx_finish(&rx);
}

int main(void)
{
	RUN(test_requests);
	RUN(test_errors);
	RUN(test_text);
	RUN(test_reply_text);
	RUN(test_tiles);
	RUN(test_duplicates);
	RUN(test_shader_names);
	RUN(test_preauth);
	RUN(test_rx);
	return test_finish();
}

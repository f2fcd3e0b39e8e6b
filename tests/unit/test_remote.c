/*
 * The C client library (clients/remote) against a small scripted WebSocket
 * server run in this process on another thread: bad URLs and refused
 * connections give clear errors; hello carries the token and gives the
 * role; a request's reply is found by its id while the messages before it
 * (progress, tiles, a message sent in several WebSocket fragments, a tile
 * larger than the receive buffer) stay queued in order; bad frames are
 * reported, not fatal; timeouts, the server's close code and reason, and a
 * message over the client's size limit (closed with 1009); the same with
 * permessage-deflate; clients on several threads at once.
 */
#include "remote.h"
#include "test.h"

#include <libwebsockets.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* ---- the scripted server ---- */

struct frame {
	struct frame *next;
	int flags;                  /* enum lws_write_protocol, NO_FIN included */
	size_t len;
	unsigned char *buf;         /* LWS_PRE bytes of room, then the payload */
};

struct session {
	struct frame *head, *tail;
	char *rx;
	size_t rx_len;
	int close_code;             /* close after the queued frames (0: no) */
	char last_token[64];
};

struct server {
	struct lws_context *ctx;
	pthread_t thread;
	volatile int stop;
	int port;
	char last_token[64];        /* the token of the last hello, "-" when none */
};

static struct server srv;

static void push(struct session *s, int flags, const void *data, size_t len)
{
	struct frame *f = calloc(1, sizeof(*f));
	f->buf = malloc(LWS_PRE + len + 1);
	memcpy(f->buf + LWS_PRE, data, len);
	f->len = len;
	f->flags = flags;
	if (s->tail)
		s->tail->next = f;
	else
		s->head = f;
	s->tail = f;
}

static void push_text(struct session *s, const char *text)
{
	push(s, LWS_WRITE_TEXT, text, strlen(text));
}

static size_t tile_frame(uint8_t *out, uint32_t edit, uint32_t level, uint32_t w, uint32_t h,
			 uint8_t fill)
{
	struct proto_tile t = { .edit = edit, .level = level, .format = PROTO_RGBA8, .x = 16,
				.y = 32, .width = w, .height = h };
	proto_tile_header(&t, out);
	size_t n = proto_tile_pixel_bytes(&t);
	memset(out + PROTO_TILE_HEADER_BYTES, fill, n);
	return PROTO_TILE_HEADER_BYTES + n;
}

/* Answer one request of the script. */
static void script(struct session *s, const char *text, size_t len)
{
	cJSON *j = cJSON_ParseWithLength(text, len);
	const cJSON *op = cJSON_GetObjectItemCaseSensitive(j, "op");
	const cJSON *idj = cJSON_GetObjectItemCaseSensitive(j, "id");
	long long id = cJSON_IsNumber(idj) ? (long long)idj->valuedouble : -1;
	const char *o = cJSON_IsString(op) ? op->valuestring : "";
	char buf[512];
	if (!strcmp(o, "hello")) {
		const cJSON *tok = cJSON_GetObjectItemCaseSensitive(j, "token");
		snprintf(srv.last_token, sizeof(srv.last_token), "%s",
			 cJSON_IsString(tok) ? tok->valuestring : "-");
		if (cJSON_IsString(tok) && !strcmp(tok->valuestring, "bad")) {
			push_text(s, "{\"op\":\"error\",\"code\":\"auth\",\"message\":\"bad token\"}");
			s->close_code = 1008;
		} else {
			snprintf(buf, sizeof(buf), "{\"op\":\"hello\",\"version\":1,\"role\":\"%s\","
				 "\"server\":\"mock\",\"limits\":{\"tile_size\":128}}",
				 cJSON_IsString(tok) && !strcmp(tok->valuestring, "view") ?
				 "viewer" : "editor");
			push_text(s, buf);
		}
	} else if (!strcmp(o, "burst")) {
		/* before the reply: progress with the id, a tile, an unrelated message, a
		 * message in three fragments, a big tile, bad frames */
		snprintf(buf, sizeof(buf), "{\"op\":\"progress\",\"id\":%lld,\"fraction\":0.5}", id);
		push_text(s, buf);
		uint8_t *tile = malloc(PROTO_TILE_HEADER_BYTES + 300 * 300 * 4);
		size_t n = tile_frame(tile, 7, 2, 8, 4, 0xab);
		push(s, LWS_WRITE_BINARY, tile, n);
		push_text(s, "{\"op\":\"level\",\"edit\":7,\"level\":2,\"ms\":1.5}");
		push(s, LWS_WRITE_TEXT | LWS_WRITE_NO_FIN, "{\"op\":\"frag", 11);
		push(s, LWS_WRITE_CONTINUATION | LWS_WRITE_NO_FIN, "mented\",\"n\"", 11);
		push(s, LWS_WRITE_CONTINUATION, ":42}", 4);
		n = tile_frame(tile, 8, 3, 300, 300, 0x5c);
		push(s, LWS_WRITE_BINARY, tile, n);
		push(s, LWS_WRITE_BINARY, "RLT0short", 9);
		push_text(s, "[1,2]");
		free(tile);
		snprintf(buf, sizeof(buf), "{\"op\":\"ack\",\"id\":%lld,\"edit\":9}", id);
		push_text(s, buf);
	} else if (!strcmp(o, "fail")) {
		snprintf(buf, sizeof(buf), "{\"op\":\"error\",\"id\":%lld,\"code\":\"unknown_light\","
			 "\"message\":\"set: no light 'x'\"}", id);
		push_text(s, buf);
	} else if (!strcmp(o, "huge")) {
		size_t big = 200000;
		uint8_t *b = malloc(big);
		memset(b, 'x', big);
		push(s, LWS_WRITE_BINARY, b, big);
		free(b);
	} else if (!strcmp(o, "bye")) {
		s->close_code = 4000;
	}
	/* "silent": no answer */
	cJSON_Delete(j);
}

static int server_cb(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
		     size_t len)
{
	struct session *s = user;
	switch (reason) {
	case LWS_CALLBACK_ESTABLISHED:
		memset(s, 0, sizeof(*s));
		break;
	case LWS_CALLBACK_RECEIVE: {
		char *p = realloc(s->rx, s->rx_len + len + 1);
		if (!p)
			return -1;
		s->rx = p;
		memcpy(s->rx + s->rx_len, in, len);
		s->rx_len += len;
		if (lws_is_final_fragment(wsi)) {
			script(s, s->rx, s->rx_len);
			s->rx_len = 0;
			lws_callback_on_writable(wsi);
		}
		break;
	}
	case LWS_CALLBACK_SERVER_WRITEABLE:
		if (s->head) {
			struct frame *f = s->head;
			s->head = f->next;
			if (!s->head)
				s->tail = NULL;
			lws_write(wsi, f->buf + LWS_PRE, f->len, (enum lws_write_protocol)f->flags);
			free(f->buf);
			free(f);
			lws_callback_on_writable(wsi);
		} else if (s->close_code) {
			lws_close_reason(wsi, (enum lws_close_status)s->close_code,
					 (unsigned char *)"bye now", 7);
			return -1;
		}
		break;
	case LWS_CALLBACK_CLOSED:
		while (s->head) {
			struct frame *f = s->head;
			s->head = f->next;
			free(f->buf);
			free(f);
		}
		free(s->rx);
		s->rx = NULL;
		break;
	default:
		break;
	}
	return 0;
}

static void *server_main(void *arg)
{
	(void)arg;
	while (!srv.stop)
		lws_service(srv.ctx, 0);
	return NULL;
}

static bool server_start(void)
{
	static const struct lws_protocols protocols[] = {
		{ "relight.v1", server_cb, sizeof(struct session), 0, 0, NULL, 0 },
		{ NULL, NULL, 0, 0, 0, NULL, 0 },
	};
	static const struct lws_extension exts[] = {
		{ "permessage-deflate", lws_extension_callback_pm_deflate,
		  "permessage-deflate; client_no_context_takeover" },
		{ NULL, NULL, NULL },
	};
	struct lws_context_creation_info info;
	memset(&info, 0, sizeof(info));
	info.port = 0;
	info.iface = "127.0.0.1";
	info.protocols = protocols;
	info.extensions = exts;
	info.gid = -1;
	info.uid = -1;
	lws_set_log_level(0, NULL);
	srv.ctx = lws_create_context(&info);
	if (!srv.ctx)
		return false;
	srv.port = lws_get_vhost_listen_port(lws_get_vhost_by_name(srv.ctx, "default"));
	return srv.port > 0 && pthread_create(&srv.thread, NULL, server_main, NULL) == 0;
}

static void server_stop(void)
{
	srv.stop = 1;
	lws_cancel_service(srv.ctx);
	pthread_join(srv.thread, NULL);
	lws_context_destroy(srv.ctx);
}

static void url(char *buf, size_t n)
{
	snprintf(buf, n, "ws://127.0.0.1:%d/ws", srv.port);
}

/* ---- the tests ---- */

static void test_bad_urls(void)
{
	static const char *const bad[] = {
		"http://127.0.0.1:1/ws", "127.0.0.1:80", "ws://", "ws://:80/ws", "ws://host:0/",
		"ws://host:65536/", "ws://host:12x/", "ws://host:/", "ws://us@host/",
		"ws://host/a b", "ws://[::1/ws", "ws://[zz]/ws", "wss://",
	};
	char err[512];
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		err[0] = '\0';
		struct remote *r = remote_connect(bad[i], NULL, NULL, err, sizeof(err));
		CHECK(r == NULL);
		remote_close(r);
		CHECK(strstr(err, "bad URL") != NULL);
		CHECK(strstr(err, bad[i]) != NULL);
	}
}

static void test_refused(void)
{
	/* a port that nothing listens on: bind one, take its number, close it */
	int fd = socket(AF_INET, SOCK_STREAM, 0);
	struct sockaddr_in a = { .sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
	socklen_t alen = sizeof(a);
	CHECK(bind(fd, (struct sockaddr *)&a, sizeof(a)) == 0);
	CHECK(getsockname(fd, (struct sockaddr *)&a, &alen) == 0);
	close(fd);
	char u[128], err[512] = "";
	snprintf(u, sizeof(u), "ws://127.0.0.1:%d/ws", ntohs(a.sin_port));
	double t0 = remote_now_ms();
	struct remote *r = remote_connect(u, NULL, NULL, err, sizeof(err));
	CHECK(r == NULL);
	remote_close(r);
	CHECK(strstr(err, u) != NULL);
	CHECK(remote_now_ms() - t0 < 5000);
	if (r || !strstr(err, u))
		fprintf(stderr, "  error: %s\n", err);
}

static void test_hello(void)
{
	char u[128], err[512] = "";
	url(u, sizeof(u));
	struct remote *r = remote_connect(u, NULL, NULL, err, sizeof(err));
	CHECK(r != NULL);
	if (!r) {
		fprintf(stderr, "  error: %s\n", err);
		return;
	}
	CHECK_STR(remote_role(r), "editor");
	CHECK_STR(srv.last_token, "-");
	const cJSON *h = remote_hello(r);
	CHECK_STR(cJSON_GetStringValue(cJSON_GetObjectItem(h, "server")), "mock");
	remote_close(r);

	r = remote_connect(u, "view", NULL, err, sizeof(err));
	CHECK(r != NULL);
	CHECK_STR(srv.last_token, "view");
	if (r)
		CHECK_STR(remote_role(r), "viewer");
	remote_close(r);

	err[0] = '\0';
	r = remote_connect(u, "bad", NULL, err, sizeof(err));
	CHECK(r == NULL);
	CHECK(strstr(err, "auth: bad token") != NULL);
	remote_close(r);
}

static void test_request(void)
{
	char u[128], err[512] = "";
	url(u, sizeof(u));
	struct remote *r = remote_connect(u, NULL, NULL, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	cJSON *req = cJSON_CreateObject(), *reply = NULL;
	cJSON_AddStringToObject(req, "op", "burst");
	CHECK(remote_request(r, req, &reply, 5000));
	const cJSON *id = cJSON_GetObjectItem(req, "id");
	CHECK(cJSON_IsNumber(id));
	CHECK_STR(cJSON_GetStringValue(cJSON_GetObjectItem(reply, "op")), "ack");
	CHECK(cJSON_IsNumber(id) && cJSON_GetObjectItem(reply, "id") &&
	      cJSON_GetObjectItem(reply, "id")->valuedouble == id->valuedouble);
	CHECK(!remote_reply_error(reply, NULL, NULL));
	cJSON_Delete(reply);

	/* what came before the reply, in order */
	struct remote_event ev;
	CHECK(remote_next(r, &ev, 1000) == REMOTE_TEXT);
	CHECK_STR(ev.op, "progress");
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_TILE);
	CHECK(ev.tile.edit == 7 && ev.tile.level == 2 && ev.tile.width == 8 &&
	      ev.tile.height == 4 && ev.tile.x == 16 && ev.tile.y == 32);
	CHECK(ev.pixels && ev.pixels[0] == 0xab && ev.pixels[8 * 4 * 4 - 1] == 0xab);
	CHECK(ev.t_ms > 0 && ev.t_ms <= remote_now_ms());
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_TEXT);
	CHECK_STR(ev.op, "level");
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_TEXT);
	CHECK_STR(ev.op, "fragmented");
	CHECK(cJSON_GetObjectItem(ev.json, "n") &&
	      cJSON_GetObjectItem(ev.json, "n")->valuedouble == 42);
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_TILE);
	CHECK(ev.tile.width == 300 && ev.tile.height == 300 && ev.tile.edit == 8);
	bool same = ev.pixels != NULL;
	for (size_t i = 0; same && i < 300 * 300 * 4; i++)
		same = ev.pixels[i] == 0x5c;
	CHECK(same);
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_INVALID);
	CHECK(strstr(ev.reason, "tile frame") != NULL);
	remote_event_finish(&ev);
	CHECK(remote_next(r, &ev, 1000) == REMOTE_INVALID);
	CHECK(strstr(ev.reason, "not a JSON object") != NULL);
	remote_event_finish(&ev);
	double t0 = remote_now_ms();
	CHECK(remote_next(r, &ev, 150) == REMOTE_TIMEOUT);
	double waited = remote_now_ms() - t0;
	CHECK(waited >= 140 && waited < 1000);
	CHECK(remote_next(r, &ev, 0) == REMOTE_TIMEOUT);

	/* an error reply is a reply */
	cJSON_DeleteItemFromObject(req, "op");
	cJSON_AddStringToObject(req, "op", "fail");
	CHECK(remote_request(r, req, &reply, 5000));
	const char *code = NULL, *msg = NULL;
	CHECK(remote_reply_error(reply, &code, &msg));
	CHECK_STR(code, "unknown_light");
	CHECK_STR(msg, "set: no light 'x'");
	cJSON_Delete(reply);

	/* no reply: a timeout, and the connection stays usable */
	cJSON_DeleteItemFromObject(req, "op");
	cJSON_AddStringToObject(req, "op", "silent");
	t0 = remote_now_ms();
	CHECK(!remote_request(r, req, &reply, 200));
	CHECK(reply == NULL);
	CHECK(strstr(remote_error(r), "no reply to silent") != NULL);
	CHECK(remote_now_ms() - t0 >= 190);
	CHECK(!remote_closed(r));

	/* the server closes: its code and reason */
	CHECK(remote_send(r, "{\"op\":\"bye\"}"));
	CHECK(remote_next(r, &ev, 5000) == REMOTE_CLOSED);
	CHECK(ev.close_code == 4000);
	CHECK_STR(ev.reason, "bye now");
	CHECK(remote_closed(r));
	CHECK(!remote_send(r, "{\"op\":\"list\"}"));
	CHECK(remote_next(r, &ev, 0) == REMOTE_CLOSED);
	cJSON_Delete(req);
	remote_close(r);
}

static void test_too_big(void)
{
	char u[128], err[512] = "";
	url(u, sizeof(u));
	struct remote_opts o = { .max_message = 100000 };
	struct remote *r = remote_connect(u, NULL, &o, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	CHECK(remote_send(r, "{\"op\":\"huge\"}"));
	struct remote_event ev;
	CHECK(remote_next(r, &ev, 5000) == REMOTE_CLOSED);
	CHECK(strstr(remote_error(r), "over 100000 bytes") != NULL);
	remote_close(r);
}

/* permessage-deflate, when offered: the same messages come through. */
static void test_deflate(void)
{
	char u[128], err[512] = "";
	url(u, sizeof(u));
	struct remote_opts o = { .deflate = true };
	struct remote *r = remote_connect(u, NULL, &o, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	for (int round = 0; round < 3; round++) {
		cJSON *req = cJSON_CreateObject(), *reply = NULL;
		cJSON_AddStringToObject(req, "op", "burst");
		CHECK(remote_request(r, req, &reply, 5000));
		CHECK_STR(cJSON_GetStringValue(cJSON_GetObjectItem(reply, "op")), "ack");
		cJSON_Delete(req);
		cJSON_Delete(reply);
		struct remote_event ev;
		int tiles = 0, texts = 0;
		bool same = true;
		while (remote_next(r, &ev, 0) != REMOTE_TIMEOUT && ev.kind != REMOTE_CLOSED) {
			if (ev.kind == REMOTE_TILE && ev.tile.width == 300) {
				for (size_t i = 0; same && i < 300 * 300 * 4; i++)
					same = ev.pixels[i] == 0x5c;
			}
			tiles += ev.kind == REMOTE_TILE;
			texts += ev.kind == REMOTE_TEXT && !strcmp(ev.op, "fragmented");
			remote_event_finish(&ev);
		}
		CHECK(tiles == 2 && texts == 1 && same);
	}
	remote_close(r);
}

/* A client per thread, all at once: each owns its context. */
static void *client_thread(void *arg)
{
	int *ok = arg;
	char u[128], err[512];
	url(u, sizeof(u));
	*ok = 0;
	for (int i = 0; i < 5; i++) {
		struct remote *r = remote_connect(u, NULL, NULL, err, sizeof(err));
		if (!r)
			return NULL;
		cJSON *req = cJSON_CreateObject(), *reply = NULL;
		cJSON_AddStringToObject(req, "op", "burst");
		bool got = remote_request(r, req, &reply, 5000);
		cJSON_Delete(req);
		cJSON_Delete(reply);
		int tiles = 0;
		struct remote_event ev;
		while (remote_next(r, &ev, 0) != REMOTE_TIMEOUT && ev.kind != REMOTE_CLOSED) {
			tiles += ev.kind == REMOTE_TILE;
			remote_event_finish(&ev);
		}
		remote_close(r);
		if (!got || tiles != 2)
			return NULL;
	}
	*ok = 1;
	return NULL;
}

static void test_threads(void)
{
	pthread_t t[4];
	int ok[4];
	for (int i = 0; i < 4; i++)
		CHECK(pthread_create(&t[i], NULL, client_thread, &ok[i]) == 0);
	for (int i = 0; i < 4; i++) {
		pthread_join(t[i], NULL);
		CHECK(ok[i] == 1);
	}
}

int main(void)
{
	RUN(test_bad_urls);
	RUN(test_refused);
	if (!server_start()) {
		fprintf(stderr, "test_remote: cannot start the test server\n");
		return 1;
	}
	RUN(test_hello);
	RUN(test_request);
	RUN(test_too_big);
	RUN(test_deflate);
	RUN(test_threads);
	server_stop();
	return test_finish();
}

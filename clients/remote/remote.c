/*
 * The C client of the relight protocol on libwebsockets (client mode).
 *
 * libwebsockets is callback-driven; this module turns it into blocking
 * calls: every call that waits runs the context's event loop (lws_service)
 * until what it waits for is in the queue or its deadline passes. The
 * timeout argument of lws_service is ignored in 4.1 (it sleeps until the
 * next scheduled timer), so each wait schedules a timer at its deadline to
 * wake the loop.
 */
#include "remote.h"

#include <libwebsockets.h>

#include <ctype.h>
#include <netdb.h>
#include <stddef.h>
#include <stdarg.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <time.h>

#define SUBPROTOCOL "relight.v1"
#define DEFAULT_TIMEOUT_MS 10000
#define DEFAULT_MAX_MESSAGE ((size_t)256 << 20)
#define CLOSE_WAIT_MS 1000

/* A parsed URL. */
struct url {
	bool tls;
	char host[256];       /* without the brackets of an IPv6 address */
	char host_header[272];
	int port;
	char path[1024];
};

/* An event in the queue. */
struct item {
	struct item *next;
	struct remote_event ev;
};

/* A message waiting to be written: LWS_PRE bytes of room, then the text. */
struct out_msg {
	struct out_msg *next;
	size_t len;
	unsigned char *buf;
};

enum conn_state { ST_CONNECTING, ST_OPEN, ST_CLOSED };

struct remote {
	struct lws_context *ctx;
	struct lws *wsi;
	enum conn_state state;
	struct remote_opts opts;
	struct url url;
	lws_sorted_usec_list_t wake;

	/* the message being received */
	uint8_t *rx;
	size_t rx_len, rx_cap;
	bool rx_binary;

	/* events, oldest first */
	struct item *head, *tail;

	/* messages to write; the last one written stays alive until the next
	 * WRITEABLE callback, as permessage-deflate keeps a pointer into it */
	struct out_msg *out_head, *out_tail;
	unsigned char *written;
	bool closing;
	int close_status;           /* the close code the client sends when closing */

	int close_code;
	char close_reason[256];
	bool peer_closed;

	char error[512];
	char role[16];
	cJSON *hello;
	int64_t next_id;
	double reply_ms;
};

static const struct lws_extension deflate_exts[] = {
	{ "permessage-deflate", lws_extension_callback_pm_deflate,
	  "permessage-deflate; client_max_window_bits" },
	{ NULL, NULL, NULL },
};

double remote_now_ms(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

static pthread_once_t log_once = PTHREAD_ONCE_INIT;

/*
 * libwebsockets logs notices to stderr by default; a client library must
 * stay quiet, and reports what went wrong through its own errors. The log
 * level is global, hence set once for every thread.
 */
static void quiet_lws(void)
{
	lws_set_log_level(getenv("RELIGHT_REMOTE_LWS_LOG") ? LLL_ERR | LLL_WARN : 0, NULL);
}

static void set_error(struct remote *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void set_error(struct remote *r, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(r->error, sizeof(r->error), fmt, ap);
	va_end(ap);
}

/* ---- URLs ---- */

static bool host_char_ok(int c)
{
	return isalnum(c) || c == '.' || c == '-' || c == '_';
}

/*
 * url := ("ws" | "wss") "://" host [":" port] [path]
 * host := name | "[" ipv6 "]"
 */
static bool parse_url(const char *s, struct url *u, char *err, size_t errlen)
{
	memset(u, 0, sizeof(*u));
	const char *p;
	if (!strncasecmp(s, "ws://", 5)) {
		p = s + 5;
		u->port = 80;
	} else if (!strncasecmp(s, "wss://", 6)) {
		p = s + 6;
		u->tls = true;
		u->port = 443;
	} else {
		snprintf(err, errlen, "bad URL '%s': it must start with ws:// or wss://", s);
		return false;
	}
	const char *h = p;
	size_t hlen;
	if (*p == '[') {
		const char *close = strchr(p, ']');
		h = p + 1;
		hlen = close ? (size_t)(close - h) : 0;
		for (size_t i = 0; i < hlen; i++)
			if (!isxdigit((unsigned char)h[i]) && h[i] != ':' && h[i] != '.')
				hlen = 0;
		if (!close || !hlen) {
			snprintf(err, errlen, "bad URL '%s': a bad IPv6 address", s);
			return false;
		}
		p = close + 1;
	} else {
		while (host_char_ok((unsigned char)*p))
			p++;
		hlen = (size_t)(p - h);
	}
	if (!hlen || hlen >= sizeof(u->host)) {
		snprintf(err, errlen, "bad URL '%s': %s host name", s, hlen ? "too long a" : "no");
		return false;
	}
	memcpy(u->host, h, hlen);
	if (*p == ':') {
		p++;
		long port = 0;
		const char *d = p;
		while (isdigit((unsigned char)*p) && port <= 65535)
			port = port * 10 + (*p++ - '0');
		if (p == d || port < 1 || port > 65535 || isdigit((unsigned char)*p)) {
			snprintf(err, errlen, "bad URL '%s': the port must be 1 to 65535", s);
			return false;
		}
		u->port = (int)port;
	}
	if (*p && *p != '/') {
		snprintf(err, errlen, "bad URL '%s': unexpected '%c' after the host", s, *p);
		return false;
	}
	const char *path = *p ? p : "/ws";
	for (const char *c = path; *c; c++)
		if ((unsigned char)*c <= ' ' || *c == 0x7f || *c == '#') {
			snprintf(err, errlen, "bad URL '%s': a space, control character or '#' "
				 "in the path", s);
			return false;
		}
	if (strlen(path) >= sizeof(u->path)) {
		snprintf(err, errlen, "bad URL '%s': the path is too long", s);
		return false;
	}
	snprintf(u->path, sizeof(u->path), "%s", path);
	bool v6 = strchr(u->host, ':') != NULL;
	snprintf(u->host_header, sizeof(u->host_header), "%s%s%s:%d", v6 ? "[" : "", u->host,
		 v6 ? "]" : "", u->port);
	return true;
}

bool remote_url_check(const char *url, char *err, size_t errlen)
{
	struct url u;
	if (!url) {
		snprintf(err, errlen, "no URL");
		return false;
	}
	return parse_url(url, &u, err, errlen);
}

/* ---- the queue ---- */

static void enqueue(struct remote *r, struct item *it)
{
	if (r->tail)
		r->tail->next = it;
	else
		r->head = it;
	r->tail = it;
}

/* Take @it (after @prev, NULL for the head) out of the queue. */
static void unlink_item(struct remote *r, struct item *prev, struct item *it)
{
	if (prev)
		prev->next = it->next;
	else
		r->head = it->next;
	if (r->tail == it)
		r->tail = prev;
	it->next = NULL;
}

void remote_event_finish(struct remote_event *ev)
{
	if (!ev)
		return;
	cJSON_Delete(ev->json);
	free(ev->buf_);
	memset(ev, 0, sizeof(*ev));
}

/* The received message is complete: parse it into an event at the queue's end. */
static bool rx_finish(struct remote *r)
{
	struct item *it = calloc(1, sizeof(*it));
	if (!it) {
		set_error(r, "out of memory");
		return false;
	}
	struct remote_event *ev = &it->ev;
	ev->t_ms = remote_now_ms();
	if (r->rx_binary) {
		char why[200];
		if (proto_tile_parse(r->rx, r->rx_len, &ev->tile, &ev->pixels, why, sizeof(why))) {
			ev->kind = REMOTE_TILE;
			ev->buf_ = r->rx;
			r->rx = NULL;
		} else {
			ev->kind = REMOTE_INVALID;
			snprintf(ev->reason, sizeof(ev->reason), "a bad tile frame of %zu bytes: %s",
				 r->rx_len, why);
		}
	} else {
		cJSON *j = cJSON_ParseWithLength((const char *)r->rx, r->rx_len);
		if (j && cJSON_IsObject(j)) {
			const cJSON *op = cJSON_GetObjectItemCaseSensitive(j, "op");
			ev->kind = REMOTE_TEXT;
			ev->json = j;
			ev->op = cJSON_IsString(op) ? op->valuestring : "";
		} else {
			cJSON_Delete(j);
			ev->kind = REMOTE_INVALID;
			/* its start, printable */
			char start[61];
			size_t n = r->rx_len < 60 ? r->rx_len : 60;
			for (size_t i = 0; i < n; i++)
				start[i] = r->rx[i] >= 0x20 && r->rx[i] < 0x7f ? (char)r->rx[i] : '?';
			start[n] = '\0';
			snprintf(ev->reason, sizeof(ev->reason), "a text frame that is not a JSON "
				 "object: '%s%s'", start, r->rx_len > 60 ? "..." : "");
		}
	}
	free(r->rx);
	r->rx = NULL;
	r->rx_len = r->rx_cap = 0;
	enqueue(r, it);
	return true;
}

/* Append a fragment of @len bytes; @more is how many the frame still has to come. */
static bool rx_append(struct remote *r, const void *in, size_t len, size_t more)
{
	size_t max = r->opts.max_message;
	if (len > max - r->rx_len) {
		set_error(r, "the server sent a message over %zu bytes", max);
		return false;
	}
	size_t need = r->rx_len + len;
	if (need + 1 > r->rx_cap) {
		/* the rest of the frame is known: take it in one allocation */
		size_t cap = need + (more < max - need ? more : max - need) + 1;
		if (cap < 2 * r->rx_cap && 2 * r->rx_cap <= max + 1)
			cap = 2 * r->rx_cap;
		uint8_t *p = realloc(r->rx, cap);
		if (!p) {
			set_error(r, "out of memory for a message of %zu bytes", need);
			return false;
		}
		r->rx = p;
		r->rx_cap = cap;
	}
	if (len)
		memcpy(r->rx + r->rx_len, in, len);
	r->rx_len = need;
	r->rx[need] = 0;
	return true;
}

static void free_out(struct remote *r)
{
	while (r->out_head) {
		struct out_msg *m = r->out_head;
		r->out_head = m->next;
		free(m->buf);
		free(m);
	}
	r->out_tail = NULL;
	free(r->written);
	r->written = NULL;
}

/* The connection has ended: keep why. */
static void ended(struct remote *r)
{
	if (r->state == ST_CLOSED)
		return;
	if (r->state == ST_OPEN && !r->peer_closed && !r->closing) {
		r->close_code = LWS_CLOSE_STATUS_ABNORMAL_CLOSE;
		snprintf(r->close_reason, sizeof(r->close_reason), "the connection ended without a "
			 "close frame");
	} else if (r->closing && !r->peer_closed) {
		r->close_code = r->close_status;
	}
	if (r->state == ST_OPEN && !r->error[0])
		set_error(r, "the connection was closed (%d%s%s)", r->close_code,
			  r->close_reason[0] ? ": " : "", r->close_reason);
	r->state = ST_CLOSED;
	r->wsi = NULL;
}

/* Close the connection with @status, from the next WRITEABLE callback. */
static void give_up(struct remote *r, struct lws *wsi, int status)
{
	r->closing = true;
	r->close_status = status;
	lws_callback_on_writable(wsi);
}

static int callback(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
		    size_t len)
{
	struct lws_context *ctx = lws_get_context(wsi);
	struct remote *r = ctx ? lws_context_user(ctx) : NULL;
	if (!r)
		return 0;
	switch (reason) {
	case LWS_CALLBACK_CLIENT_CONNECTION_ERROR:
		if (in && len)
			set_error(r, "%.*s", (int)len, (const char *)in);
		else if (in)
			set_error(r, "%s", (const char *)in);
		else
			set_error(r, "the connection failed");
		r->state = ST_CLOSED;
		r->wsi = NULL;
		break;
	case LWS_CALLBACK_CLIENT_ESTABLISHED:
		r->state = ST_OPEN;
		r->wsi = wsi;
		break;
	case LWS_CALLBACK_CLIENT_RECEIVE:
		/*
		 * Once the client has given up on the connection, what still comes
		 * is dropped. The close is sent from the WRITEABLE callback:
		 * libwebsockets 4.1 goes on parsing the frame when RECEIVE returns
		 * nonzero and writes past its buffer.
		 */
		if (r->closing)
			break;
		if (lws_is_first_fragment(wsi)) {
			r->rx_len = 0;
			r->rx_binary = lws_frame_is_binary(wsi);
		}
		if (!rx_append(r, in, len, lws_remaining_packet_payload(wsi))) {
			free(r->rx);
			r->rx = NULL;
			r->rx_len = r->rx_cap = 0;
			give_up(r, wsi, LWS_CLOSE_STATUS_MESSAGE_TOO_LARGE);
			break;
		}
		if (lws_is_final_fragment(wsi) && !rx_finish(r))
			give_up(r, wsi, LWS_CLOSE_STATUS_UNEXPECTED_CONDITION);
		break;
	case LWS_CALLBACK_CLIENT_WRITEABLE:
		free(r->written);
		r->written = NULL;
		if (r->out_head) {
			struct out_msg *m = r->out_head;
			r->out_head = m->next;
			if (!r->out_head)
				r->out_tail = NULL;
			int n = lws_write(wsi, m->buf + LWS_PRE, m->len, LWS_WRITE_TEXT);
			r->written = m->buf;
			size_t mlen = m->len;
			free(m);
			if (n < 0 || (size_t)n < mlen) {
				set_error(r, "the message could not be written");
				return -1;
			}
			if (r->out_head || r->closing)
				lws_callback_on_writable(wsi);
			break;
		}
		if (r->closing) {
			lws_close_reason(wsi, (enum lws_close_status)r->close_status, NULL, 0);
			return -1;
		}
		break;
	case LWS_CALLBACK_WS_PEER_INITIATED_CLOSE:
		r->peer_closed = true;
		r->close_code = LWS_CLOSE_STATUS_NOSTATUS;
		r->close_reason[0] = '\0';
		if (in && len >= 2) {
			const unsigned char *b = in;
			r->close_code = b[0] << 8 | b[1];
			size_t n = len - 2 < sizeof(r->close_reason) - 1 ? len - 2 :
				   sizeof(r->close_reason) - 1;
			memcpy(r->close_reason, b + 2, n);
			r->close_reason[n] = '\0';
		}
		break;
	case LWS_CALLBACK_CLIENT_CLOSED:
		ended(r);
		break;
	case LWS_CALLBACK_WSI_DESTROY:
		if (r->wsi == wsi || r->state != ST_CLOSED) {
			if (r->state == ST_CONNECTING && !r->error[0])
				set_error(r, "the connection closed during the handshake");
			ended(r);
		}
		break;
	default:
		break;
	}
	(void)user;
	return 0;
}

/*
 * The deadline's timer. lws_service runs the timers that are due before it
 * polls and then sleeps until the next one, so a timer that came due just
 * before would not end this sleep: cancelling the service makes the poll
 * return at once.
 */
static void wake(lws_sorted_usec_list_t *sul)
{
	struct remote *r = (struct remote *)(void *)((char *)sul - offsetof(struct remote, wake));
	lws_cancel_service(r->ctx);
}

/* One round of the event loop, sleeping at most until @deadline (remote_now_ms; < 0: none). */
static void pump(struct remote *r, double deadline)
{
	int n;
	double left = deadline - remote_now_ms();
	if (deadline >= 0 && left <= 0) {
		/* a negative timeout: poll without sleeping */
		n = lws_service(r->ctx, -1);
	} else {
		if (deadline >= 0)
			lws_sul_schedule(r->ctx, 0, &r->wake, wake, (lws_usec_t)(left * 1e3) + 1);
		n = lws_service(r->ctx, 0);
	}
	if (n < 0 && r->state != ST_CLOSED) {
		if (!r->error[0])
			set_error(r, "the event loop failed");
		r->state = ST_CLOSED;
		r->wsi = NULL;
	}
	lws_sul_cancel(&r->wake);
}

static double deadline_after(int timeout_ms)
{
	return timeout_ms < 0 ? -1.0 : remote_now_ms() + timeout_ms;
}

static bool past(double deadline)
{
	return deadline >= 0 && remote_now_ms() >= deadline;
}

/* ---- sending ---- */

static bool queue_text(struct remote *r, const char *json, size_t len)
{
	struct out_msg *m = calloc(1, sizeof(*m));
	unsigned char *buf = malloc(LWS_PRE + len + 1);
	if (!m || !buf) {
		free(m);
		free(buf);
		set_error(r, "out of memory");
		return false;
	}
	memcpy(buf + LWS_PRE, json, len);
	buf[LWS_PRE + len] = 0;
	m->buf = buf;
	m->len = len;
	if (r->out_tail)
		r->out_tail->next = m;
	else
		r->out_head = m;
	r->out_tail = m;
	lws_callback_on_writable(r->wsi);
	return true;
}

bool remote_send(struct remote *r, const char *json)
{
	if (r->state != ST_OPEN || r->closing) {
		/* keep the reason the connection ended for, when there is one */
		if (!r->error[0])
			set_error(r, "the connection is closed (%d%s%s)", r->close_code,
				  r->close_reason[0] ? ": " : "", r->close_reason);
		return false;
	}
	if (!queue_text(r, json, strlen(json)))
		return false;
	double deadline = deadline_after(r->opts.timeout_ms);
	while (r->out_head && r->state == ST_OPEN) {
		if (past(deadline)) {
			set_error(r, "timed out after %.1f s waiting to send", r->opts.timeout_ms / 1e3);
			return false;
		}
		pump(r, deadline);
	}
	if (r->out_head) {
		if (!r->error[0])
			set_error(r, "the connection closed before the message was sent");
		return false;
	}
	return true;
}

/* ---- receiving ---- */

static void closed_event(const struct remote *r, struct remote_event *ev)
{
	ev->kind = REMOTE_CLOSED;
	ev->t_ms = remote_now_ms();
	ev->close_code = r->close_code;
	snprintf(ev->reason, sizeof(ev->reason), "%.*s", (int)sizeof(ev->reason) - 1,
		 r->close_reason[0] ? r->close_reason : r->error);
}

enum remote_kind remote_next(struct remote *r, struct remote_event *ev, int timeout_ms)
{
	memset(ev, 0, sizeof(*ev));
	double deadline = deadline_after(timeout_ms);
	bool pumped = false;
	for (;;) {
		if (r->head) {
			struct item *it = r->head;
			unlink_item(r, NULL, it);
			*ev = it->ev;
			free(it);
			return ev->kind;
		}
		if (r->state == ST_CLOSED) {
			closed_event(r, ev);
			return ev->kind;
		}
		/* look at the socket at least once, even with no time to wait */
		if (pumped && past(deadline)) {
			ev->kind = REMOTE_TIMEOUT;
			ev->t_ms = remote_now_ms();
			return ev->kind;
		}
		pump(r, deadline);
		pumped = true;
	}
}

static bool is_id(const cJSON *j, int64_t id)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, "id");
	return cJSON_IsNumber(v) && v->valuedouble == (double)id;
}

bool remote_request(struct remote *r, cJSON *req, cJSON **reply, int timeout_ms)
{
	*reply = NULL;
	if (!cJSON_IsObject(req)) {
		set_error(r, "the request is not a JSON object");
		return false;
	}
	int64_t id = ++r->next_id;
	cJSON_DeleteItemFromObjectCaseSensitive(req, "id");
	if (!cJSON_AddNumberToObject(req, "id", (double)id)) {
		set_error(r, "out of memory");
		return false;
	}
	const cJSON *opj = cJSON_GetObjectItemCaseSensitive(req, "op");
	char op[64];
	snprintf(op, sizeof(op), "%s", cJSON_IsString(opj) ? opj->valuestring : "request");
	char *text = cJSON_PrintUnformatted(req);
	if (!text) {
		set_error(r, "out of memory");
		return false;
	}
	/* remember what was queued before: the reply can only come after it */
	struct item *prev = r->tail;
	bool ok = remote_send(r, text);
	cJSON_free(text);
	if (!ok)
		return false;
	double deadline = deadline_after(timeout_ms);
	for (;;) {
		struct item *it = prev ? prev->next : r->head;
		while (it) {
			if (it->ev.kind != REMOTE_TEXT || !is_id(it->ev.json, id)) {
				prev = it;
				it = it->next;
				continue;
			}
			if (strcmp(it->ev.op, "progress") == 0) {
				deadline = deadline_after(timeout_ms);
				if (!r->opts.progress) {
					prev = it;
					it = it->next;
					continue;
				}
				struct item *next = it->next;
				r->opts.progress(r->opts.progress_user, it->ev.json);
				unlink_item(r, prev, it);
				remote_event_finish(&it->ev);
				free(it);
				it = next;
				continue;
			}
			unlink_item(r, prev, it);
			*reply = it->ev.json;
			r->reply_ms = it->ev.t_ms;
			free(it);
			return true;
		}
		if (r->state == ST_CLOSED) {
			set_error(r, "the connection closed before the reply to %s (%d%s%s)", op,
				  r->close_code, r->close_reason[0] ? ": " : "", r->close_reason);
			return false;
		}
		if (past(deadline)) {
			set_error(r, "no reply to %s in %.1f s", op, timeout_ms / 1e3);
			return false;
		}
		pump(r, deadline);
	}
}

bool remote_reply_error(const cJSON *reply, const char **code, const char **message)
{
	const cJSON *op = cJSON_GetObjectItemCaseSensitive(reply, "op");
	if (!cJSON_IsString(op) || strcmp(op->valuestring, "error") != 0)
		return false;
	const cJSON *c = cJSON_GetObjectItemCaseSensitive(reply, "code");
	const cJSON *m = cJSON_GetObjectItemCaseSensitive(reply, "message");
	if (code)
		*code = cJSON_IsString(c) ? c->valuestring : "";
	if (message)
		*message = cJSON_IsString(m) ? m->valuestring : "";
	return true;
}

/* ---- connecting ---- */

/* Wait for the hello reply: the first text message whose op is hello or error. */
static bool await_hello(struct remote *r, double deadline, char *err, size_t errlen)
{
	for (;;) {
		struct item *prev = NULL;
		for (struct item *it = r->head; it; prev = it, it = it->next) {
			if (it->ev.kind != REMOTE_TEXT)
				continue;
			const char *code, *msg;
			if (remote_reply_error(it->ev.json, &code, &msg)) {
				snprintf(err, errlen, "refused by the server: %s: %s", code, msg);
				return false;
			}
			if (strcmp(it->ev.op, "hello") != 0)
				continue;
			unlink_item(r, prev, it);
			r->hello = it->ev.json;
			free(it);
			const cJSON *role = cJSON_GetObjectItemCaseSensitive(r->hello, "role");
			snprintf(r->role, sizeof(r->role), "%s",
				 cJSON_IsString(role) ? role->valuestring : "editor");
			return true;
		}
		if (r->state == ST_CLOSED) {
			snprintf(err, errlen, "the server closed the connection before its hello "
				 "(%d%s%s)", r->close_code, r->close_reason[0] ? ": " : "",
				 r->close_reason);
			return false;
		}
		if (past(deadline)) {
			snprintf(err, errlen, "no hello from the server in %.1f s",
				 r->opts.timeout_ms / 1e3);
			return false;
		}
		pump(r, deadline);
	}
}

/*
 * libwebsockets gives no reason when a connection cannot even start; the
 * usual one is a host name that does not resolve, so look it up to say so.
 */
static void explain_no_start(struct remote *r)
{
	struct addrinfo hints = { .ai_socktype = SOCK_STREAM }, *res = NULL;
	int rc = getaddrinfo(r->url.host, NULL, &hints, &res);
	if (rc)
		set_error(r, "cannot resolve host '%s': %s", r->url.host, gai_strerror(rc));
	else
		set_error(r, "the connection could not be started");
	if (res)
		freeaddrinfo(res);
}

struct remote *remote_connect(const char *url, const char *token, const struct remote_opts *opts,
			      char *err, size_t errlen)
{
	static const struct lws_protocols protocols[] = {
		{ SUBPROTOCOL, callback, 0, 0, 0, NULL, 0 },
		{ NULL, NULL, 0, 0, 0, NULL, 0 },
	};
	char why[512] = "";
	cJSON *hello = NULL;
	char *text = NULL;

	if (!url) {
		snprintf(err, errlen, "no URL");
		return NULL;
	}
	pthread_once(&log_once, quiet_lws);
	struct remote *r = calloc(1, sizeof(*r));
	if (!r) {
		snprintf(err, errlen, "out of memory");
		return NULL;
	}
	if (opts)
		r->opts = *opts;
	if (r->opts.timeout_ms <= 0)
		r->opts.timeout_ms = DEFAULT_TIMEOUT_MS;
	if (!r->opts.max_message)
		r->opts.max_message = DEFAULT_MAX_MESSAGE;
	snprintf(r->role, sizeof(r->role), "editor");
	if (!parse_url(url, &r->url, err, errlen))
		goto fail_free;

	struct lws_context_creation_info info;
	memset(&info, 0, sizeof(info));
	info.port = CONTEXT_PORT_NO_LISTEN;
	info.protocols = protocols;
	info.gid = -1;
	info.uid = -1;
	info.user = r;
	if (r->opts.deflate)
		info.extensions = deflate_exts;
	if (r->url.tls) {
		info.options |= LWS_SERVER_OPTION_DO_SSL_GLOBAL_INIT;
		info.client_ssl_ca_filepath = r->opts.ca_file;
	}
	r->ctx = lws_create_context(&info);
	if (!r->ctx) {
		snprintf(err, errlen, "%s: cannot create the libwebsockets context", url);
		goto fail_free;
	}

	struct lws_client_connect_info ci;
	memset(&ci, 0, sizeof(ci));
	ci.context = r->ctx;
	ci.address = r->url.host;
	ci.port = r->url.port;
	ci.path = r->url.path;
	ci.host = r->url.host_header;
	ci.origin = r->opts.origin;
	ci.protocol = SUBPROTOCOL;
	ci.pwsi = &r->wsi;
	if (r->url.tls) {
		ci.ssl_connection = LCCSCF_USE_SSL;
		if (r->opts.insecure)
			ci.ssl_connection |= LCCSCF_ALLOW_SELFSIGNED | LCCSCF_ALLOW_EXPIRED |
					     LCCSCF_SKIP_SERVER_CERT_HOSTNAME_CHECK |
					     LCCSCF_ALLOW_INSECURE;
	}
	double deadline = deadline_after(r->opts.timeout_ms);
	if (!lws_client_connect_via_info(&ci) && r->state != ST_CLOSED) {
		if (!r->error[0])
			explain_no_start(r);
		r->state = ST_CLOSED;
	}
	while (r->state == ST_CONNECTING && !past(deadline))
		pump(r, deadline);
	if (r->state != ST_OPEN) {
		if (r->state == ST_CONNECTING)
			snprintf(why, sizeof(why), "no connection in %.1f s", r->opts.timeout_ms / 1e3);
		else
			snprintf(why, sizeof(why), "%s", r->error[0] ? r->error : "connection failed");
		snprintf(err, errlen, "%s: %s", url, why);
		goto fail_ctx;
	}

	hello = cJSON_CreateObject();
	if (!hello || !cJSON_AddStringToObject(hello, "op", "hello") ||
	    !cJSON_AddNumberToObject(hello, "version", PROTO_VERSION) ||
	    (token && !cJSON_AddStringToObject(hello, "token", token)) ||
	    !(text = cJSON_PrintUnformatted(hello))) {
		snprintf(err, errlen, "out of memory");
		goto fail_ctx;
	}
	if (!remote_send(r, text)) {
		snprintf(err, errlen, "%s: %s", url, r->error);
		goto fail_ctx;
	}
	if (!await_hello(r, deadline, why, sizeof(why))) {
		snprintf(err, errlen, "%s: %s", url, why);
		goto fail_ctx;
	}
	cJSON_free(text);
	cJSON_Delete(hello);
	r->error[0] = '\0';
	return r;

fail_ctx:
	cJSON_free(text);
	cJSON_Delete(hello);
	remote_close(r);
	return NULL;
fail_free:
	free(r);
	return NULL;
}

void remote_close(struct remote *r)
{
	if (!r)
		return;
	if (r->ctx && r->state == ST_OPEN && r->wsi) {
		give_up(r, r->wsi, LWS_CLOSE_STATUS_NORMAL);
		double deadline = deadline_after(CLOSE_WAIT_MS);
		while (r->state != ST_CLOSED && !past(deadline))
			pump(r, deadline);
	}
	if (r->ctx)
		lws_context_destroy(r->ctx);
	while (r->head) {
		struct item *it = r->head;
		r->head = it->next;
		remote_event_finish(&it->ev);
		free(it);
	}
	free_out(r);
	free(r->rx);
	cJSON_Delete(r->hello);
	free(r);
}

const char *remote_role(const struct remote *r)
{
	return r->role;
}

const cJSON *remote_hello(const struct remote *r)
{
	return r->hello;
}

double remote_reply_ms(const struct remote *r)
{
	return r->reply_ms;
}

const char *remote_error(const struct remote *r)
{
	return r->error;
}

bool remote_closed(const struct remote *r)
{
	return r->state == ST_CLOSED;
}

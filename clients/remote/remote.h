/*
 * The C client of the relight protocol (protocol/README.md): a blocking
 * client of relightd on libwebsockets, for `relight remote`, tests and
 * benchmarks.
 *
 * Each struct remote owns its own libwebsockets context and runs its event
 * loop only inside its own calls (remote_connect, remote_send, remote_next,
 * remote_request, remote_close), so it must be used from one thread at a
 * time; several of them may run on several threads at once (a benchmark
 * opens one per thread).
 *
 * Everything the server sends is kept, in arrival order, in the client's
 * queue of events: JSON text messages, parsed, and tile frames, checked with
 * proto_tile_parse. remote_next takes the oldest; remote_request takes the
 * reply to its own request out of the queue and leaves the rest for later
 * remote_next calls. Messages split into fragments are joined before they
 * are queued.
 */
#ifndef REMOTE_H
#define REMOTE_H

#include "proto.h"

#include <cjson/cJSON.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

struct remote;

/** How to connect. Every field may be left zero. */
struct remote_opts {
	int timeout_ms;          /* connecting and the hello exchange; also how long a send
				    may wait for the socket (0: 10000) */
	size_t max_message;      /* largest message taken from the server, in bytes; a larger
				    one closes the connection with 1009 (0: 256 MiB) */
	bool deflate;            /* offer permessage-deflate (slower for tiles on loopback) */
	const char *origin;      /* the Origin header; NULL: none is sent */
	const char *ca_file;     /* wss: a PEM file of trusted CAs; NULL: the system's */
	bool insecure;           /* wss: accept any certificate (self-signed, other host) */
	/* called by remote_request for each progress message answering its request,
	 * which then leaves the queue; NULL: progress messages stay queued */
	void (*progress)(void *user, const cJSON *msg);
	void *progress_user;
};

/** What remote_next returns. */
enum remote_kind {
	REMOTE_TEXT = 1,  /* a JSON message: event.json, event.op */
	REMOTE_TILE,      /* a tile frame: event.tile, event.pixels */
	REMOTE_INVALID,   /* a frame the client refused (not JSON, a bad tile): event.reason */
	REMOTE_TIMEOUT,   /* nothing came in time */
	REMOTE_CLOSED,    /* the connection is closed: event.close_code, event.reason */
};

/**
 * One event. The event owns what it points to until remote_event_finish.
 * @t_ms is when its frame's last fragment was read off the socket, on the
 * clock of remote_now_ms, whenever the caller takes it out of the queue.
 */
struct remote_event {
	enum remote_kind kind;
	double t_ms;
	cJSON *json;                /* TEXT: the message (an object) */
	const char *op;             /* TEXT: its "op" member ("" when it has none) */
	struct proto_tile tile;     /* TILE: the header */
	const uint8_t *pixels;      /* TILE: proto_tile_pixel_bytes(&tile) bytes */
	int close_code;             /* CLOSED: the server's close code; 1006 when the
				       connection ended without one, 1000 after remote_close */
	char reason[256];           /* CLOSED: the close reason; INVALID: what was wrong */
	void *buf_;                 /* private: the frame's bytes */
};

/**
 * Connect to @url ("ws://HOST[:PORT][/PATH]" or "wss://...", PATH
 * defaulting to "/ws"; HOST may be "[IPv6]"), with the subprotocol
 * "relight.v1", send hello (with @token unless NULL) and wait for the hello
 * reply. @opts may be NULL. NULL on failure with the reason in @err: a bad
 * URL, a connection that failed (the reason libwebsockets gives), a timeout,
 * or the server's refusal ("auth: MESSAGE" for an error reply, or its close
 * code and reason).
 */
struct remote *remote_connect(const char *url, const char *token, const struct remote_opts *opts,
			      char *err, size_t errlen);

/**
 * Whether @url is a URL remote_connect takes (see there), without
 * connecting. False with "bad URL 'URL': why" in @err.
 */
bool remote_url_check(const char *url, char *err, size_t errlen);

/** Close the connection politely (waiting at most a second) and free @r. NULL is fine. */
void remote_close(struct remote *r);

/** The role the server gave: "editor" or "viewer" (never NULL). */
const char *remote_role(const struct remote *r);

/** The server's hello reply (owned by @r): "server", "limits", ... */
const cJSON *remote_hello(const struct remote *r);

/** Why the last call that failed failed (empty when none did). */
const char *remote_error(const struct remote *r);

/** Whether the connection has ended (the queue may still hold events). */
bool remote_closed(const struct remote *r);

/**
 * Send one text message (@json, a JSON object's text). Waits until
 * libwebsockets has taken it, at most opts.timeout_ms. False when the
 * connection is closed or the wait timed out (remote_error says which).
 */
bool remote_send(struct remote *r, const char *json);

/**
 * The oldest event of the queue, waiting for one at most @timeout_ms
 * milliseconds (0: only what has arrived; negative: no limit). Returns
 * ev->kind. Once the connection has closed and the queue is empty, every
 * call returns REMOTE_CLOSED. Call remote_event_finish on every event.
 */
enum remote_kind remote_next(struct remote *r, struct remote_event *ev, int timeout_ms);

/** Free what @ev holds and empty it (an empty or finished event is fine). */
void remote_event_finish(struct remote_event *ev);

/**
 * Send @req (a JSON object, modified: its "id" is set to a fresh number) and
 * wait for the message that answers it: the first text message with that
 * id, other than a "progress" message. Everything else that arrives
 * meanwhile stays queued for remote_next, progress messages included unless
 * opts.progress takes them. The
 * wait ends after @timeout_ms milliseconds (negative: no limit) without a
 * message of that id: each progress message starts it anew.
 *
 * True with the reply in *@reply (the caller's, cJSON_Delete it), which may
 * be an error reply (remote_reply_error). False when the send failed, the
 * wait timed out or the connection closed (remote_error says which).
 */
bool remote_request(struct remote *r, cJSON *req, cJSON **reply, int timeout_ms);

/**
 * When the reply the last successful remote_request returned was received
 * (remote_now_ms's clock): the events still queued with an earlier t_ms
 * came before it.
 */
double remote_reply_ms(const struct remote *r);

/**
 * Whether @reply is an error reply ({"op":"error",...}): then *@code and
 * *@message (either pointer may be NULL) point into it ("" when missing).
 */
bool remote_reply_error(const cJSON *reply, const char **code, const char **message);

/** A monotonic clock in milliseconds, the one of remote_event.t_ms. */
double remote_now_ms(void);

#endif

/*
 * A client's send queue: the frames waiting for its socket, bounded in
 * bytes. Tiles of an edit that a newer edit supersedes are dropped when the
 * newer edit's tiles arrive; under pressure a tile also drops the queued
 * tiles of coarser levels it covers, then the oldest tiles. Text frames are
 * never dropped; a client whose text alone passes the bound is to be cut
 * off (sendq_push says so). A slow client costs its bound, never more.
 *
 * Frames are reference counted so that one tile serves every client that
 * shows the same shot in the same format. Not thread-safe: the daemon holds
 * its lock around every call.
 */
#ifndef SRV_SENDQ_H
#define SRV_SENDQ_H

#include <libwebsockets.h>

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/** A message to send: LWS_PRE bytes of headroom, then the payload. */
struct srv_frame {
	atomic_int refs;
	bool binary;               /* a tile; otherwise JSON text */
	uint32_t edit, level;      /* tiles: what they show */
	uint32_t x, y;             /* tiles: where */
	double t0;                 /* > 0: the edit's receipt time, counted at the first write */
	size_t len;                /* payload bytes */
	unsigned char buf[];       /* LWS_PRE + len */
};

/** A frame of @len payload bytes, one reference; NULL when out of memory. */
struct srv_frame *srv_frame_new(size_t len, bool binary);
/** A text frame holding @text (@len bytes). */
struct srv_frame *srv_frame_text(const char *text, size_t len);
static inline unsigned char *srv_frame_payload(struct srv_frame *f) { return f->buf + LWS_PRE; }
struct srv_frame *srv_frame_ref(struct srv_frame *f);
void srv_frame_unref(struct srv_frame *f);

struct sendq {
	struct srv_frame **v;      /* ring of frames, oldest at head */
	size_t head, len, cap;
	size_t bytes;              /* payload bytes queued */
	size_t text_bytes;
	size_t limit;              /* bound on bytes */
	uint64_t dropped;          /* tiles dropped so far */
};

void sendq_init(struct sendq *q, size_t limit);
void sendq_finish(struct sendq *q);

enum sendq_result {
	SENDQ_OK,
	SENDQ_OVER,                /* text past the bound: cut the client off */
	SENDQ_NOMEM,
};

/**
 * Queue @f (takes a reference). Returns how many tiles it dropped in
 * *@dropped (may be NULL).
 */
enum sendq_result sendq_push(struct sendq *q, struct srv_frame *f, uint64_t *dropped);

/** The oldest frame, still queued (NULL: empty). */
struct srv_frame *sendq_peek(const struct sendq *q);
/** Take the oldest frame off (the caller now holds its reference). */
struct srv_frame *sendq_pop(struct sendq *q);

#endif

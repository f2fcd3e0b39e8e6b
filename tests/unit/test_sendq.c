/*
 * relightd's send queues (daemon/server/sendq.h): bounded in bytes, tiles of
 * superseded edits dropped, coarser levels dropped under pressure, text
 * never dropped, and a client whose text alone passes the bound reported.
 */
#include "test.h"

#include "sendq.h"

static struct srv_frame *tile(uint32_t edit, uint32_t level, uint32_t x, uint32_t y, size_t len)
{
	struct srv_frame *f = srv_frame_new(len, true);
	f->edit = edit;
	f->level = level;
	f->x = x;
	f->y = y;
	memset(srv_frame_payload(f), (int)(edit * 16 + level), len);
	return f;
}

/* Push and drop our reference: the queue holds the frame alone. */
static enum sendq_result push(struct sendq *q, struct srv_frame *f, uint64_t *dropped)
{
	enum sendq_result r = sendq_push(q, f, dropped);
	srv_frame_unref(f);
	return r;
}

static size_t count_edit(const struct sendq *q, uint32_t edit)
{
	size_t n = 0;
	for (size_t i = 0; i < q->len; i++) {
		const struct srv_frame *f = q->v[(q->head + i) % q->cap];
		n += f->binary && f->edit == edit;
	}
	return n;
}

static void test_order_and_bytes(void)
{
	struct sendq q;
	sendq_init(&q, 1 << 20);
	for (uint32_t i = 0; i < 200; i++)   /* past the first capacity: the ring grows */
		CHECK(push(&q, tile(1, 0, i, 0, 100), NULL) == SENDQ_OK);
	CHECK(q.len == 200);
	CHECK(q.bytes == 200 * 100);
	for (uint32_t i = 0; i < 200; i++) {
		struct srv_frame *f = sendq_pop(&q);
		CHECK(f && f->x == i);
		srv_frame_unref(f);
	}
	CHECK(q.len == 0 && q.bytes == 0);
	CHECK(sendq_pop(&q) == NULL);
	sendq_finish(&q);
}

static void test_superseded(void)
{
	struct sendq q;
	sendq_init(&q, 1 << 20);
	struct srv_frame *t = srv_frame_text("{\"op\":\"ack\"}", 12);
	push(&q, tile(1, 0, 0, 0, 100), NULL);
	push(&q, t, NULL);
	push(&q, tile(1, 0, 128, 0, 100), NULL);
	uint64_t dropped = 0;
	/* A tile of edit 2 drops every queued tile of edit 1, never the text. */
	CHECK(push(&q, tile(2, 0, 0, 0, 100), &dropped) == SENDQ_OK);
	CHECK(dropped == 2);
	CHECK(q.dropped == 2);
	CHECK(count_edit(&q, 1) == 0);
	CHECK(q.len == 2);
	struct srv_frame *f = sendq_pop(&q);
	CHECK(f && !f->binary);
	srv_frame_unref(f);
	CHECK(q.bytes == 100);
	sendq_finish(&q);
}

static void test_pressure(void)
{
	/* Room for 10 tiles of 100 bytes. */
	struct sendq q;
	sendq_init(&q, 1000);
	for (uint32_t i = 0; i < 10; i++)
		push(&q, tile(5, 0, i * 128, 0, 100), NULL);
	CHECK(q.bytes == 1000);
	/* Level 1 at x = 0 replaces level 0 at x = 0 only when the queue is full. */
	uint64_t dropped = 0;
	push(&q, tile(5, 1, 0, 0, 100), &dropped);
	CHECK(dropped == 1);
	CHECK(q.bytes <= q.limit);
	/* A tile with nothing it covers: the oldest tile goes. */
	push(&q, tile(5, 1, 9999, 0, 100), &dropped);
	CHECK(dropped == 1);
	CHECK(q.bytes <= q.limit);
	struct srv_frame *f = sendq_peek(&q);
	CHECK(f && f->x == 2 * 128 && f->level == 0);   /* x = 128 was the oldest left */
	/* With room, nothing of the same edit is dropped. */
	struct sendq r;
	sendq_init(&r, 1 << 20);
	push(&r, tile(5, 0, 0, 0, 100), NULL);
	push(&r, tile(5, 1, 0, 0, 100), &dropped);
	CHECK(dropped == 0 && r.len == 2);
	sendq_finish(&r);
	sendq_finish(&q);
}

static void test_never_reading(void)
{
	/* A client that never reads: tiles of 200 edits, with text replies. */
	struct sendq q;
	sendq_init(&q, 64 * 1024);
	size_t most = 0;
	enum sendq_result r = SENDQ_OK;
	uint32_t e;
	for (e = 1; e <= 200 && r == SENDQ_OK; e++) {
		for (uint32_t L = 0; L < 4; L++)
			for (uint32_t i = 0; i < 8; i++)
				push(&q, tile(e, L, i * 128, 0, 4096), NULL);
		char msg[64];
		int n = snprintf(msg, sizeof(msg), "{\"op\":\"level\",\"edit\":%u}", e);
		r = push(&q, srv_frame_text(msg, (size_t)n), NULL);
		if (q.bytes > most)
			most = q.bytes;
	}
	CHECK(most <= q.limit + 4096);
	CHECK(r == SENDQ_OK);          /* 200 short replies fit in 64 KB */
	CHECK(count_edit(&q, 200) > 0);
	CHECK(count_edit(&q, 199) == 0);
	/* Text past the bound: the queue says to cut the client off. */
	struct srv_frame *big = srv_frame_new(q.limit, false);
	CHECK(push(&q, big, NULL) == SENDQ_OVER);
	sendq_finish(&q);
}

static void test_shared_frames(void)
{
	/* One frame in two queues: freed when both let go (ASan checks). */
	struct sendq a, b;
	sendq_init(&a, 1 << 20);
	sendq_init(&b, 1 << 20);
	struct srv_frame *f = tile(1, 0, 0, 0, 64);
	sendq_push(&a, f, NULL);
	sendq_push(&b, f, NULL);
	srv_frame_unref(f);
	CHECK(atomic_load(&f->refs) == 2);
	sendq_finish(&a);
	CHECK(atomic_load(&f->refs) == 1);
	CHECK(srv_frame_payload(f)[63] == 16);
	sendq_finish(&b);
}

int main(void)
{
	RUN(test_order_and_bytes);
	RUN(test_superseded);
	RUN(test_pressure);
	RUN(test_never_reading);
	RUN(test_shared_frames);
	return test_finish();
}

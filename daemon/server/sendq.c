/*
 * Send queues with superseded tiles dropped (sendq.h).
 */
#include "sendq.h"

#include <stdlib.h>
#include <string.h>

struct srv_frame *srv_frame_new(size_t len, bool binary)
{
	if (len > SIZE_MAX - sizeof(struct srv_frame) - LWS_PRE)
		return NULL;
	struct srv_frame *f = malloc(sizeof(*f) + LWS_PRE + len);
	if (!f)
		return NULL;
	memset(f, 0, sizeof(*f));
	atomic_init(&f->refs, 1);
	f->binary = binary;
	f->len = len;
	return f;
}

struct srv_frame *srv_frame_text(const char *text, size_t len)
{
	struct srv_frame *f = srv_frame_new(len, false);
	if (f)
		memcpy(srv_frame_payload(f), text, len);
	return f;
}

struct srv_frame *srv_frame_ref(struct srv_frame *f)
{
	atomic_fetch_add_explicit(&f->refs, 1, memory_order_relaxed);
	return f;
}

void srv_frame_unref(struct srv_frame *f)
{
	if (f && atomic_fetch_sub_explicit(&f->refs, 1, memory_order_acq_rel) == 1)
		free(f);
}

void sendq_init(struct sendq *q, size_t limit)
{
	memset(q, 0, sizeof(*q));
	q->limit = limit;
}

void sendq_finish(struct sendq *q)
{
	while (q->len)
		srv_frame_unref(sendq_pop(q));
	free(q->v);
	memset(q, 0, sizeof(*q));
}

static struct srv_frame **at(const struct sendq *q, size_t i)
{
	return &q->v[(q->head + i) % q->cap];
}

/* Keep the frames for which @drop says no, in order; count and free the rest. */
static uint64_t filter(struct sendq *q, bool (*drop)(const struct srv_frame *, const struct srv_frame *),
		       const struct srv_frame *by)
{
	size_t kept = 0;
	uint64_t n = 0;
	for (size_t i = 0; i < q->len; i++) {
		struct srv_frame *f = *at(q, i);
		if (f->binary && drop(f, by)) {
			q->bytes -= f->len;
			srv_frame_unref(f);
			n++;
			continue;
		}
		*at(q, kept++) = f;
	}
	q->len = kept;
	q->dropped += n;
	return n;
}

static bool older_edit(const struct srv_frame *f, const struct srv_frame *by)
{
	return f->edit < by->edit;
}

static bool covered(const struct srv_frame *f, const struct srv_frame *by)
{
	return f->edit == by->edit && f->level < by->level && f->x == by->x && f->y == by->y;
}

static bool grow(struct sendq *q)
{
	size_t cap = q->cap ? q->cap * 2 : 64;
	struct srv_frame **v = malloc(cap * sizeof(*v));
	if (!v)
		return false;
	for (size_t i = 0; i < q->len; i++)
		v[i] = *at(q, i);
	free(q->v);
	q->v = v;
	q->cap = cap;
	q->head = 0;
	return true;
}

enum sendq_result sendq_push(struct sendq *q, struct srv_frame *f, uint64_t *dropped)
{
	uint64_t n = 0;
	if (f->binary) {
		n += filter(q, older_edit, f);
		if (q->bytes + f->len > q->limit)
			n += filter(q, covered, f);
		/* Still over: the oldest tiles go first (they are the coarsest). */
		while (q->bytes + f->len > q->limit && q->bytes > q->text_bytes) {
			size_t i = 0;
			while (i < q->len && !(*at(q, i))->binary)
				i++;
			if (i == q->len)
				break;
			struct srv_frame *old = *at(q, i);
			for (size_t j = i; j + 1 < q->len; j++)
				*at(q, j) = *at(q, j + 1);
			q->len--;
			q->bytes -= old->len;
			q->dropped++;
			n++;
			srv_frame_unref(old);
		}
	}
	if (dropped)
		*dropped = n;
	if (!f->binary && q->text_bytes + f->len > q->limit)
		return SENDQ_OVER;
	if (q->len == q->cap && !grow(q))
		return SENDQ_NOMEM;
	*at(q, q->len++) = srv_frame_ref(f);
	q->bytes += f->len;
	if (!f->binary)
		q->text_bytes += f->len;
	return SENDQ_OK;
}

struct srv_frame *sendq_peek(const struct sendq *q)
{
	return q->len ? *at(q, 0) : NULL;
}

struct srv_frame *sendq_pop(struct sendq *q)
{
	if (!q->len)
		return NULL;
	struct srv_frame *f = *at(q, 0);
	q->head = (q->head + 1) % q->cap;
	q->len--;
	q->bytes -= f->len;
	if (!f->binary)
		q->text_bytes -= f->len;
	return f;
}

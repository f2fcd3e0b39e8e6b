/*
 * relightd's counters, written as Prometheus text (GET /metrics). Every
 * update is atomic: the service thread and the render workers both count.
 */
#ifndef SRV_METRICS_H
#define SRV_METRICS_H

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

/* Upper bounds, in seconds, of the edit-to-first-tile histogram's buckets. */
#define SRV_LATENCY_BUCKETS 12

struct srv_metrics {
	atomic_int_fast64_t clients;           /* gauge: connected WebSocket clients */
	atomic_int_fast64_t shots_resident;    /* gauge: shots in GPU memory */
	atomic_int_fast64_t gpu_bytes;         /* gauge: GPU bytes the resident shots hold */
	atomic_uint_fast64_t connections;      /* counter: WebSocket connections accepted */
	atomic_uint_fast64_t refused;          /* counter: connections refused (auth, origin, limit) */
	atomic_uint_fast64_t messages;         /* counter: text frames received */
	atomic_uint_fast64_t errors;           /* counter: error replies sent */
	atomic_uint_fast64_t edits;            /* counter: edits applied */
	atomic_uint_fast64_t levels;           /* counter: refinement levels rendered */
	atomic_uint_fast64_t preempted;        /* counter: refinements cut short by a newer edit */
	atomic_uint_fast64_t tiles_sent;       /* counter */
	atomic_uint_fast64_t tiles_dropped;    /* counter: superseded before they were sent */
	atomic_uint_fast64_t bytes_sent;       /* counter: bytes of frames written */
	atomic_uint_fast64_t loads;            /* counter: shots loaded into GPU memory */
	atomic_uint_fast64_t evictions;        /* counter: shots evicted to stay in the budget */
	atomic_uint_fast64_t bakes;            /* counter: RIBs baked on demand */
	/* histogram: edit received to its first tile written, in seconds */
	atomic_uint_fast64_t latency_bucket[SRV_LATENCY_BUCKETS]; /* not cumulative */
	atomic_uint_fast64_t latency_count;
	atomic_uint_fast64_t latency_sum_us;
};

/** The buckets' upper bounds in seconds (SRV_LATENCY_BUCKETS of them, then +Inf). */
extern const double srv_latency_bounds[SRV_LATENCY_BUCKETS];

void srv_metrics_init(struct srv_metrics *m);

/** Count one edit-to-first-tile latency of @seconds. */
void srv_metrics_latency(struct srv_metrics *m, double seconds);

/**
 * The Prometheus text exposition (version 0.0.4) of @m: HELP and TYPE lines,
 * names prefixed relight_, the histogram with cumulative buckets, _sum and
 * _count. Returns a malloc'd string (NULL when out of memory).
 */
char *srv_metrics_text(const struct srv_metrics *m);

#endif

/*
 * relightd's counters and their Prometheus text exposition (format 0.0.4).
 * Updates use relaxed atomics: each counter only needs to be exact on its
 * own, and a scrape that sees one counter a moment before another is fine.
 */
#include "metrics.h"

#include "strbuf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

const double srv_latency_bounds[SRV_LATENCY_BUCKETS] = {
	0.001, 0.002, 0.005, 0.01, 0.02, 0.04, 0.06, 0.1, 0.25, 0.5, 1, 2.5,
};

#define LOAD(x) atomic_load_explicit(&(x), memory_order_relaxed)

void srv_metrics_init(struct srv_metrics *m)
{
	atomic_init(&m->clients, 0);
	atomic_init(&m->shots_resident, 0);
	atomic_init(&m->gpu_bytes, 0);
	atomic_init(&m->connections, 0);
	atomic_init(&m->refused, 0);
	atomic_init(&m->messages, 0);
	atomic_init(&m->errors, 0);
	atomic_init(&m->edits, 0);
	atomic_init(&m->levels, 0);
	atomic_init(&m->preempted, 0);
	atomic_init(&m->tiles_sent, 0);
	atomic_init(&m->tiles_dropped, 0);
	atomic_init(&m->bytes_sent, 0);
	atomic_init(&m->loads, 0);
	atomic_init(&m->evictions, 0);
	atomic_init(&m->bakes, 0);
	for (int i = 0; i < SRV_LATENCY_BUCKETS; i++)
		atomic_init(&m->latency_bucket[i], 0);
	atomic_init(&m->latency_count, 0);
	atomic_init(&m->latency_sum_us, 0);
}

void srv_metrics_latency(struct srv_metrics *m, double seconds)
{
	/* A clock step can make a latency negative; NaN is no latency either. */
	if (!(seconds >= 0))
		seconds = 0;
	/* Buckets are "less than or equal" (Prometheus' le); past the last one only +Inf counts it. */
	for (int i = 0; i < SRV_LATENCY_BUCKETS; i++) {
		if (seconds <= srv_latency_bounds[i]) {
			atomic_fetch_add_explicit(&m->latency_bucket[i], 1, memory_order_relaxed);
			break;
		}
	}
	/* Cap one sample at ~11.6 days so the microsecond sum cannot wrap on nonsense. */
	double us = seconds < 1e12 ? floor(seconds * 1e6 + 0.5) : 1e12;
	atomic_fetch_add_explicit(&m->latency_sum_us, (uint_fast64_t)us, memory_order_relaxed);
	atomic_fetch_add_explicit(&m->latency_count, 1, memory_order_relaxed);
}

static void header(struct rl_strbuf *b, const char *name, const char *type, const char *help)
{
	rl_strbuf_printf(b, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

static void gauge(struct rl_strbuf *b, const char *name, const char *help, int_fast64_t v)
{
	header(b, name, "gauge", help);
	rl_strbuf_printf(b, "%s %lld\n", name, (long long)v);
}

static void counter(struct rl_strbuf *b, const char *name, const char *help, uint_fast64_t v)
{
	header(b, name, "counter", help);
	rl_strbuf_printf(b, "%s %llu\n", name, (unsigned long long)v);
}

char *srv_metrics_text(const struct srv_metrics *m)
{
	struct rl_strbuf b = { 0 };
	gauge(&b, "relight_clients", "Connected WebSocket clients.", LOAD(m->clients));
	gauge(&b, "relight_shots_resident", "Shots resident in GPU memory.",
	      LOAD(m->shots_resident));
	gauge(&b, "relight_gpu_bytes", "GPU memory held by the resident shots, in bytes.",
	      LOAD(m->gpu_bytes));
	counter(&b, "relight_connections_total", "WebSocket connections accepted.",
		LOAD(m->connections));
	counter(&b, "relight_connections_refused_total",
		"Connections refused: a bad token or origin, or too many clients.",
		LOAD(m->refused));
	counter(&b, "relight_messages_total", "Text messages received from clients.",
		LOAD(m->messages));
	counter(&b, "relight_errors_total", "Error replies sent to clients.", LOAD(m->errors));
	counter(&b, "relight_edits_total", "Light edits applied.", LOAD(m->edits));
	counter(&b, "relight_levels_total", "Refinement levels rendered.", LOAD(m->levels));
	counter(&b, "relight_refinements_preempted_total",
		"Refinements cut short by a newer edit.", LOAD(m->preempted));
	counter(&b, "relight_tiles_sent_total", "Image tiles sent to clients.",
		LOAD(m->tiles_sent));
	counter(&b, "relight_tiles_dropped_total",
		"Image tiles dropped unsent because a newer one superseded them.",
		LOAD(m->tiles_dropped));
	counter(&b, "relight_bytes_sent_total", "Bytes of WebSocket frames written.",
		LOAD(m->bytes_sent));
	counter(&b, "relight_shot_loads_total", "Shots loaded into GPU memory.", LOAD(m->loads));
	counter(&b, "relight_shot_evictions_total",
		"Shots evicted from GPU memory to stay within the budget.", LOAD(m->evictions));
	counter(&b, "relight_bakes_total", "RIB scenes baked into shot files on demand.",
		LOAD(m->bakes));

	/*
	 * The buckets, count and sum are read one by one while workers may be
	 * adding to them. Prometheus wants the +Inf bucket equal to _count and
	 * every bucket no smaller than the one before; cumulating here and
	 * raising the count to the last finite bucket keeps both true.
	 */
	const char *h = "relight_edit_first_tile_seconds";
	header(&b, h, "histogram", "Time from an edit received to its first tile written.");
	uint64_t cum = 0;
	for (int i = 0; i < SRV_LATENCY_BUCKETS; i++) {
		cum += LOAD(m->latency_bucket[i]);
		rl_strbuf_printf(&b, "%s_bucket{le=\"%g\"} %llu\n", h, srv_latency_bounds[i],
				 (unsigned long long)cum);
	}
	uint64_t count = LOAD(m->latency_count);
	if (count < cum)
		count = cum;
	uint64_t sum_us = LOAD(m->latency_sum_us);
	rl_strbuf_printf(&b, "%s_bucket{le=\"+Inf\"} %llu\n", h, (unsigned long long)count);
	rl_strbuf_printf(&b, "%s_sum %llu.%06llu\n", h, (unsigned long long)(sum_us / 1000000),
			 (unsigned long long)(sum_us % 1000000));
	rl_strbuf_printf(&b, "%s_count %llu\n", h, (unsigned long long)count);
	return b.data;
}

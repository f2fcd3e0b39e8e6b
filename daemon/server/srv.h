/*
 * relightd's insides, shared by the service thread (relightd.c: libwebsockets,
 * sessions, requests that need no GPU) and the render worker (worker.c: the
 * one thread that holds the GPU context and every shot in GPU memory).
 *
 * One lock guards what both threads touch: the clients and their send
 * queues, the shots' job queues and refinement state. The worker never
 * calls libwebsockets except lws_cancel_service(), the one call that is safe
 * from another thread (LWS_MAX_SMP is 1); the service thread then asks for
 * WRITEABLE callbacks on the clients with frames queued.
 */
#ifndef SRV_H
#define SRV_H

#include "config.h"
#include "metrics.h"
#include "proto.h"
#include "sendq.h"
#include "shots.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

struct cJSON;
struct gpu_shot;

/*
 * Lights a shot may have had in its life on the daemon, added and removed
 * ones included, per --max-lights: a removed light keeps its index in the
 * runtime and its add and remove in the edit log.
 */
#define SRV_LIGHT_SLOTS_PER_LIGHT 4u

struct srv_client {
	uint64_t id;
	struct lws *wsi;
	enum srv_role role;
	bool hello;                /* hello accepted */
	struct srv_shot *shot;     /* the open shot, or NULL */
	enum proto_format format;
	struct sendq q;
	struct srv_frame *inflight; /* written; freed at the next WRITEABLE (deflate keeps a pointer) */
	bool cut_off;              /* close once what is queued has gone out */
	bool overflow;             /* its replies passed the queue's bound: close at once */
	struct proto_rx rx;        /* a message being reassembled from fragments */
	bool rx_binary;
	unsigned short close_code; /* the close frame's code when cut off (0: 1008) */
	const char *close_why;     /* and its reason (static text) */
	double snap_debt, snap_t;  /* snapshot rate: the bucket's debt, as of srv_now() @snap_t */
	/* counters for "stats" */
	uint64_t messages, errors, edits, tiles_sent, tiles_dropped, bytes_sent;
	struct srv_client *next;
};

/* A request for the worker, copied out of the client's frame. */
struct srv_job {
	enum proto_op op;
	uint64_t client;           /* who asked (0: a replay after a reload) */
	bool has_id;
	int64_t id;
	double t0;                 /* when it was received (srv_now) */
	char *light, *shader;
	struct proto_param *params;
	uint32_t nparams;
	bool on;
	enum proto_format format;
	uint32_t x, y;             /* pick */
	uint32_t gen;              /* the shot's generation when it was queued */
	struct srv_job *next;
};

/*
 * A shot's edits as the state they produce (editlog.c): entries that later
 * edits void are dropped, so it grows with the lights and parameters
 * touched, not with the number of edits.
 */
struct srv_editlog {
	struct srv_job **v;        /* in the order they are to be replayed */
	size_t n, cap;
	size_t bytes;              /* what the entries hold (srv_job_bytes) */
};

struct srv_shot {
	char name[SRV_SHOT_NAME_MAX + 1];
	char path[4096];
	struct gpu_shot *gpu;      /* the worker's; NULL when not resident */
	FILE *diag;                /* the runtime's messages about it (kept while it lives) */
	char *diag_buf;
	size_t diag_len;
	bool failed;               /* its last load failed */
	bool baking;
	struct srv_job *jobs, **jobs_tail;
	uint32_t edit;             /* the newest edit */
	int next_level;            /* the next level of edit to render; GPU_SHOT_LEVELS: done */
	double edit_t0;            /* receipt time of the newest edit */
	uint64_t used;             /* LRU clock of its last use */
	size_t bytes;
	uint32_t width, height;
	uint32_t gen;              /* counts the times its file changed size under its clients */
	/* Edits applied so far, replayed when an evicted shot is loaded again. */
	struct srv_editlog log;
	struct srv_shot *next;
};

struct srv {
	struct srv_config cfg;
	struct srv_tokens *tokens;
	struct srv_metrics metrics;
	struct srv_shots *registry;
	struct lws_context *lws;

	pthread_mutex_t lock;
	pthread_cond_t wake;       /* the worker's: jobs or refinement to do, or stop */
	struct srv_client *clients;
	uint32_t nclients;         /* connected, hello or not */
	uint32_t npreauth;         /* of them, those whose hello is not accepted yet */
	uint64_t next_client;
	struct srv_shot *shots;    /* every shot a client opened (resident or not) */
	uint64_t clock;
	bool stop;

	/* the worker */
	struct gpu_ctx *gpu;       /* the worker thread's */
	pthread_t worker;
	bool worker_running;
	bool gpu_ready, gpu_failed;
	double worker_beat;        /* when the worker last finished a job or level, or woke to work */
	char gpu_err[512];
	char gpu_renderer[256];
};

/** Monotonic seconds. */
double srv_now(void);

/* ---- relightd.c: for the worker (lock held) ---- */

struct srv_client *srv_client_find(struct srv *s, uint64_t id);
/** Queue @f for @c and have it written; cuts off a client whose queue is full of text. */
void srv_send(struct srv *s, struct srv_client *c, struct srv_frame *f);
/** Queue JSON @j (not consumed) for @c. */
void srv_send_json(struct srv *s, struct srv_client *c, const struct cJSON *j);
/** An error reply to @c for the request @id. */
void srv_send_error(struct srv *s, struct srv_client *c, bool has_id, int64_t id,
		    enum proto_error_code code, const char *fmt, ...)
	__attribute__((format(printf, 6, 7)));
/** Wake the service thread to write what was queued (any thread, lock held or not). */
void srv_kick(struct srv *s);

/* ---- editlog.c ---- */

void srv_job_free(struct srv_job *j);
/** A copy of request @r as a job of client @client. NULL when out of memory. */
struct srv_job *srv_job_from(const struct proto_request *r, uint64_t client, double t0);
/** Bytes job @j holds, its strings and parameters included. */
size_t srv_job_bytes(const struct srv_job *j);
/**
 * Append edit @j, applied successfully, to @log (which takes it), dropping
 * the entries it voids (see editlog.c). False when out of memory: @j is
 * freed and the log is as it was.
 */
bool srv_editlog_add(struct srv_editlog *log, struct srv_job *j);
/** Free every entry; @log is empty afterwards. */
void srv_editlog_finish(struct srv_editlog *log);

/* ---- worker.c ---- */

/** Start the worker and wait until it has a GPU context: false with the reason in s->gpu_err. */
bool srv_worker_start(struct srv *s);
/** Stop the worker (after the work in hand) and free every shot. */
void srv_worker_stop(struct srv *s);
/**
 * Queue @j for shot @shot (lock held); the worker takes it from there. A
 * snapshot past its client's --snapshot-rate is refused here instead: the
 * client gets the error and @j is freed.
 */
void srv_submit(struct srv *s, struct srv_shot *shot, struct srv_job *j);
/**
 * Whether the render worker is alive: false, with the reason in @why, when
 * jobs wait and it has finished none for --worker-stall seconds. Any thread.
 */
bool srv_worker_healthy(struct srv *s, char *why, size_t whylen);
/** The shot named @name, created (not loaded) on first use (lock held). */
struct srv_shot *srv_shot_get(struct srv *s, const char *name);

#endif

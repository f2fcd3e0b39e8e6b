/*
 * relightd: serves shots to WebSocket clients. JSON requests in (protocol/),
 * progressively refined image tiles out; HTTP on the same port for
 * /healthz, /metrics and the viewer's files.
 *
 * This file is the service thread: libwebsockets, sessions, and the
 * requests that need no GPU (hello, list, close, stats). Everything that
 * touches a shot goes to the render worker (worker.c) as a job; RIBs are
 * baked on threads of their own. Nothing slow runs in a libwebsockets
 * callback.
 */
/* realpath() is an X/Open part of POSIX 2008. */
#define _XOPEN_SOURCE 700

#include "srv.h"

#include "config.h"
#include "fileutil.h"
#include "log.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <libwebsockets.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define WS_PROTOCOL "relight.v1"
#define WS_PATH "/ws"

static struct srv g_srv;
static volatile sig_atomic_t g_signal;
/* The shots folder with its links resolved, as the registry names files in it. */
static char g_shots_real[4096];

double srv_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* ---- sending (lock held) ---- */

struct srv_client *srv_client_find(struct srv *s, uint64_t id)
{
	for (struct srv_client *c = s->clients; c; c = c->next)
		if (c->id == id)
			return c;
	return NULL;
}

void srv_kick(struct srv *s)
{
	if (s->lws)
		lws_cancel_service(s->lws);
}

void srv_send(struct srv *s, struct srv_client *c, struct srv_frame *f)
{
	if (!f || c->cut_off)
		return;
	uint64_t dropped = 0;
	enum sendq_result r = sendq_push(&c->q, f, &dropped);
	if (dropped) {
		c->tiles_dropped += dropped;
		atomic_fetch_add(&s->metrics.tiles_dropped, dropped);
	}
	if (r != SENDQ_OK) {
		rl_log_limited(RL_LOG_WARN, "client %llu: send queue over %zu bytes of replies it "
			       "does not read: cut off", (unsigned long long)c->id, c->q.limit);
		c->cut_off = c->overflow = true;
	}
	/* Replies go out at once; tiles come in batches that wake the service once. */
	if (!f->binary)
		srv_kick(s);
}

void srv_send_json(struct srv *s, struct srv_client *c, const cJSON *j)
{
	char *text = cJSON_PrintUnformatted(j);
	if (!text)
		return;
	/* Names from RIBs and messages quoting clients need not be UTF-8. */
	proto_utf8_clean(text);
	struct srv_frame *f = srv_frame_text(text, strlen(text));
	free(text);
	srv_send(s, c, f);
	srv_frame_unref(f);
}

/* Cut every "@dir/" out of @msg. */
static void cut_prefix(char *msg, const char *dir)
{
	size_t n = strlen(dir);
	if (!n || dir[0] != '/')
		return;
	char pre[4096 + 2];
	snprintf(pre, sizeof(pre), "%s%s", dir, dir[n - 1] == '/' ? "" : "/");
	size_t pn = strlen(pre);
	for (char *at; (at = strstr(msg, pre)) != NULL;)
		memmove(at, at + pn, strlen(at + pn) + 1);
}

/*
 * Replies name files relative to the shots and snapshots folders, never by
 * the server's absolute paths: those prefixes go, and any other absolute
 * path (a shader's, a library's) keeps its last component only.
 */
static void hide_paths(const struct srv *s, char *msg)
{
	cut_prefix(msg, s->cfg.snapshot_dir);
	cut_prefix(msg, g_shots_real);
	cut_prefix(msg, s->cfg.shots_dir);
	for (char *p = msg; *p; p++) {
		if (*p != '/' || (p > msg && !strchr(" \t'\"(=[", p[-1])))
			continue;
		size_t n = strcspn(p, " \t'\"()[],;");
		char *last = p;
		for (char *q = p; q < p + n; q++)
			if (*q == '/')
				last = q;
		memmove(p, last + 1, strlen(last + 1) + 1);
	}
}

void srv_send_error(struct srv *s, struct srv_client *c, bool has_id, int64_t id,
		    enum proto_error_code code, const char *fmt, ...)
{
	struct proto_error e = { .code = code, .has_id = has_id, .id = id };
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(e.message, sizeof(e.message), fmt, ap);
	va_end(ap);
	hide_paths(s, e.message);
	char *text = proto_error_json(&e);
	if (!text)
		return;
	struct srv_frame *f = srv_frame_text(text, strlen(text));
	free(text);
	srv_send(s, c, f);
	srv_frame_unref(f);
	c->errors++;
	atomic_fetch_add(&s->metrics.errors, 1);
}

/* ---- baking RIBs on demand ---- */

struct bake_task {
	struct srv *s;
	struct srv_shot *sh;
	double last;
	pthread_t thread;
	struct bake_task *next;
};

static pthread_mutex_t g_bakes_lock = PTHREAD_MUTEX_INITIALIZER;
static struct bake_task *g_bakes;

/* Tell the clients waiting on @sh's opens (lock held). */
static void to_waiting(struct srv *s, struct srv_shot *sh, const cJSON *(*make)(void *, int64_t, bool),
		       void *user)
{
	for (struct srv_job *j = sh->jobs; j; j = j->next) {
		if (j->op != PROTO_OPEN)
			continue;
		struct srv_client *c = srv_client_find(s, j->client);
		if (!c)
			continue;
		const cJSON *o = make(user, j->id, j->has_id);
		if (o)
			srv_send_json(s, c, o);
	}
}

struct progress_msg {
	cJSON *o;
	const char *shot, *what;
	double fraction;
};

static const cJSON *make_progress(void *user, int64_t id, bool has_id)
{
	struct progress_msg *m = user;
	cJSON_Delete(m->o);
	m->o = cJSON_CreateObject();
	cJSON_AddStringToObject(m->o, "op", "progress");
	if (has_id)
		proto_add_id(m->o, id);
	cJSON_AddStringToObject(m->o, "shot", m->shot);
	cJSON_AddNumberToObject(m->o, "fraction", m->fraction);
	cJSON_AddStringToObject(m->o, "what", m->what);
	return m->o;
}

static void bake_progress(void *user, double fraction, const char *what)
{
	struct bake_task *t = user;
	double now = srv_now();
	if (fraction < 1 && fraction > 0 && now - t->last < 0.1)
		return;
	t->last = now;
	struct progress_msg m = { .shot = t->sh->name, .what = what ? what : "", .fraction = fraction };
	pthread_mutex_lock(&t->s->lock);
	to_waiting(t->s, t->sh, make_progress, &m);
	srv_kick(t->s);
	pthread_mutex_unlock(&t->s->lock);
	cJSON_Delete(m.o);
}

static void *bake_main(void *arg)
{
	struct bake_task *t = arg;
	struct srv *s = t->s;
	char path[4096], err[1024];
	rl_log_limited(RL_LOG_INFO, "shot '%s': baking its RIB", t->sh->name);
	double t0 = srv_now();
	bool ok = srv_shots_bake(s->registry, t->sh->name, bake_progress, t, path, sizeof(path),
				 err, sizeof(err));
	atomic_fetch_add(&s->metrics.bakes, 1);
	pthread_mutex_lock(&s->lock);
	t->sh->baking = false;
	if (ok) {
		rl_log(RL_LOG_INFO, "shot '%s': baked in %.1f s", t->sh->name, srv_now() - t0);
		snprintf(t->sh->path, sizeof(t->sh->path), "%s", path);
	} else {
		rl_log_limited(RL_LOG_ERROR, "shot '%s': the bake failed: %s", t->sh->name, err);
		/* The opens waiting on it fail; edits queued after them go too. */
		while (t->sh->jobs) {
			struct srv_job *j = t->sh->jobs;
			t->sh->jobs = j->next;
			struct srv_client *c = srv_client_find(s, j->client);
			if (c && j->op == PROTO_OPEN)
				srv_send_error(s, c, j->has_id, j->id, PROTO_E_INTERNAL,
					       "baking shot '%s' failed: %s", t->sh->name, err);
			srv_job_free(j);
		}
		t->sh->jobs_tail = &t->sh->jobs;
	}
	pthread_cond_broadcast(&s->wake);
	srv_kick(s);
	pthread_mutex_unlock(&s->lock);
	return NULL;
}

/* Start baking @sh (lock held). */
static bool start_bake(struct srv *s, struct srv_shot *sh)
{
	struct bake_task *t = calloc(1, sizeof(*t));
	if (!t)
		return false;
	t->s = s;
	t->sh = sh;
	sh->baking = true;
	if (pthread_create(&t->thread, NULL, bake_main, t)) {
		sh->baking = false;
		free(t);
		return false;
	}
	pthread_mutex_lock(&g_bakes_lock);
	t->next = g_bakes;
	g_bakes = t;
	pthread_mutex_unlock(&g_bakes_lock);
	return true;
}

static void join_bakes(void)
{
	pthread_mutex_lock(&g_bakes_lock);
	struct bake_task *t = g_bakes;
	g_bakes = NULL;
	pthread_mutex_unlock(&g_bakes_lock);
	while (t) {
		struct bake_task *n = t->next;
		pthread_join(t->thread, NULL);
		free(t);
		t = n;
	}
}

/* ---- requests (service thread) ---- */

static void reply(struct srv *s, struct srv_client *c, cJSON *o)
{
	pthread_mutex_lock(&s->lock);
	srv_send_json(s, c, o);
	pthread_mutex_unlock(&s->lock);
	cJSON_Delete(o);
}

static cJSON *reply_to(const char *op, const struct proto_request *r)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", op);
	if (r->has_id)
		proto_add_id(o, r->id);
	return o;
}

static void error(struct srv *s, struct srv_client *c, const struct proto_request *r,
		  enum proto_error_code code, const char *fmt, ...)
	__attribute__((format(printf, 5, 6)));

static void error(struct srv *s, struct srv_client *c, const struct proto_request *r,
		  enum proto_error_code code, const char *fmt, ...)
{
	char msg[256];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	pthread_mutex_lock(&s->lock);
	srv_send_error(s, c, r && r->has_id, r ? r->id : 0, code, "%s", msg);
	pthread_mutex_unlock(&s->lock);
}

static void do_hello(struct srv *s, struct srv_client *c, const struct proto_request *r)
{
	enum srv_role role = s->tokens ? srv_tokens_check(s->tokens, r->token) : SRV_ROLE_EDITOR;
	if (role == SRV_ROLE_NONE) {
		error(s, c, r, PROTO_E_AUTH, r->token ? "hello: the token is not valid"
						      : "hello: a token is required");
		pthread_mutex_lock(&s->lock);
		c->cut_off = true;
		pthread_mutex_unlock(&s->lock);
		atomic_fetch_add(&s->metrics.refused, 1);
		return;
	}
	pthread_mutex_lock(&s->lock);
	bool full = s->nclients - s->npreauth >= s->cfg.max_clients;
	if (!full) {
		c->hello = true;
		s->npreauth--;
	}
	pthread_mutex_unlock(&s->lock);
	if (full) {
		error(s, c, r, PROTO_E_LIMIT, "hello: %u clients are connected, the most there may be",
		      s->cfg.max_clients);
		pthread_mutex_lock(&s->lock);
		c->cut_off = true;
		pthread_mutex_unlock(&s->lock);
		atomic_fetch_add(&s->metrics.refused, 1);
		return;
	}
	lws_set_timer_usecs(c->wsi, LWS_SET_TIMER_USEC_CANCEL);
	c->role = role;
	cJSON *o = reply_to("hello", r);
	cJSON_AddNumberToObject(o, "version", PROTO_VERSION);
	cJSON_AddStringToObject(o, "role", srv_role_name(role));
	cJSON_AddStringToObject(o, "server", "relightd " RELIGHTD_VERSION);
	cJSON_AddStringToObject(o, "gpu", s->gpu_renderer);
	cJSON *lim = cJSON_AddObjectToObject(o, "limits");
	cJSON_AddNumberToObject(lim, "max_message", (double)s->cfg.max_message);
	cJSON_AddNumberToObject(lim, "tile_size", s->cfg.tile_size);
	cJSON_AddNumberToObject(lim, "max_lights", s->cfg.max_lights);
	reply(s, c, o);
}

static void do_list(struct srv *s, struct srv_client *c, const struct proto_request *r)
{
	struct srv_shot_entry e[256];
	size_t n = srv_shots_list(s->registry, e, 256);
	if (n > 256)
		n = 256;
	cJSON *o = reply_to("shots", r);
	cJSON *a = cJSON_AddArrayToObject(o, "shots");
	for (size_t i = 0; i < n; i++) {
		cJSON *x = cJSON_CreateObject();
		cJSON_AddStringToObject(x, "name", e[i].name);
		cJSON_AddNumberToObject(x, "width", e[i].width);
		cJSON_AddNumberToObject(x, "height", e[i].height);
		cJSON_AddBoolToObject(x, "baked", e[i].baked);
		cJSON_AddItemToArray(a, x);
	}
	reply(s, c, o);
}

static void do_open(struct srv *s, struct srv_client *c, const struct proto_request *r, double t0)
{
	char path[4096];
	enum srv_shot_state st = srv_shots_find(s->registry, r->shot, path, sizeof(path));
	if (st == SRV_SHOT_INVALID) {
		error(s, c, r, PROTO_E_UNKNOWN_SHOT, "open: '%.64s' is not a shot name (letters, "
		      "digits, '_', '-', '.'; no folders)", r->shot);
		return;
	}
	if (st == SRV_SHOT_MISSING) {
		error(s, c, r, PROTO_E_UNKNOWN_SHOT, "open: no shot '%.64s'", r->shot);
		return;
	}
	struct srv_job *j = srv_job_from(r, c->id, t0);
	pthread_mutex_lock(&s->lock);
	struct srv_shot *sh = j ? srv_shot_get(s, r->shot) : NULL;
	if (!sh) {
		pthread_mutex_unlock(&s->lock);
		srv_job_free(j);
		error(s, c, r, PROTO_E_INTERNAL, "open: out of memory");
		return;
	}
	c->shot = NULL;            /* the shot open before stops here */
	if (st == SRV_SHOT_READY && !sh->baking)
		snprintf(sh->path, sizeof(sh->path), "%s", path);
	else if (!sh->baking && !start_bake(s, sh)) {
		pthread_mutex_unlock(&s->lock);
		srv_job_free(j);
		error(s, c, r, PROTO_E_INTERNAL, "open: cannot start baking '%s'", r->shot);
		return;
	}
	srv_submit(s, sh, j);
	pthread_mutex_unlock(&s->lock);
}

static void do_stats(struct srv *s, struct srv_client *c, const struct proto_request *r)
{
	cJSON *o = reply_to("stats", r);
	pthread_mutex_lock(&s->lock);
	cJSON_AddNumberToObject(o, "messages", (double)c->messages);
	cJSON_AddNumberToObject(o, "errors", (double)c->errors);
	cJSON_AddNumberToObject(o, "edits", (double)c->edits);
	cJSON_AddNumberToObject(o, "tiles_sent", (double)c->tiles_sent);
	cJSON_AddNumberToObject(o, "tiles_dropped", (double)c->tiles_dropped);
	cJSON_AddNumberToObject(o, "bytes_sent", (double)c->bytes_sent);
	cJSON_AddNumberToObject(o, "queued_bytes", (double)c->q.bytes);
	if (c->shot) {
		cJSON_AddStringToObject(o, "shot", c->shot->name);
		cJSON_AddNumberToObject(o, "edit", c->shot->edit);
		cJSON_AddNumberToObject(o, "log_entries", (double)c->shot->log.n);
		cJSON_AddNumberToObject(o, "log_bytes", (double)c->shot->log.bytes);
	}
	cJSON_AddNumberToObject(o, "clients", s->nclients);
	cJSON_AddNumberToObject(o, "shots_resident", (double)atomic_load(&s->metrics.shots_resident));
	cJSON_AddNumberToObject(o, "gpu_bytes", (double)atomic_load(&s->metrics.gpu_bytes));
	cJSON_AddStringToObject(o, "gpu", s->gpu_renderer);
	pthread_mutex_unlock(&s->lock);
	reply(s, c, o);
}

static bool is_edit(enum proto_op op)
{
	return op == PROTO_SET || op == PROTO_ADD_LIGHT || op == PROTO_REMOVE_LIGHT ||
	       op == PROTO_SOLO || op == PROTO_MUTE || op == PROTO_FREEZE;
}

static void handle_text(struct srv *s, struct srv_client *c, const char *text, size_t len)
{
	double t0 = srv_now();
	c->messages++;
	atomic_fetch_add(&s->metrics.messages, 1);
	struct proto_request r;
	struct proto_error e;
	struct proto_limits lim = { 0 };
	/* Before hello, nothing is built from what a stranger sends. */
	bool parsed = c->hello ? proto_parse_request(text, len, &lim, &r, &e)
			       : proto_parse_preauth(text, len, &r, &e);
	if (!parsed) {
		char *t = proto_error_json(&e);
		pthread_mutex_lock(&s->lock);
		if (t) {
			struct srv_frame *f = srv_frame_text(t, strlen(t));
			srv_send(s, c, f);
			srv_frame_unref(f);
		}
		c->errors++;
		atomic_fetch_add(&s->metrics.errors, 1);
		/* Nothing but a good hello from a client that has no token yet. */
		if (!c->hello && s->tokens) {
			c->cut_off = true;
			atomic_fetch_add(&s->metrics.refused, 1);
		}
		pthread_mutex_unlock(&s->lock);
		free(t);
		return;
	}
	if (!c->hello && r.op != PROTO_HELLO) {
		error(s, c, &r, PROTO_E_AUTH, "%s: say hello first", proto_op_name(r.op));
		if (s->tokens) {
			pthread_mutex_lock(&s->lock);
			c->cut_off = true;
			pthread_mutex_unlock(&s->lock);
			atomic_fetch_add(&s->metrics.refused, 1);
		}
		goto out;
	}
	if (is_edit(r.op) && c->role != SRV_ROLE_EDITOR) {
		error(s, c, &r, PROTO_E_FORBIDDEN, "%s: a viewer cannot edit", proto_op_name(r.op));
		goto out;
	}
	switch (r.op) {
	case PROTO_HELLO:
		if (c->hello)
			error(s, c, &r, PROTO_E_STATE, "hello: said already");
		else
			do_hello(s, c, &r);
		break;
	case PROTO_LIST:
		do_list(s, c, &r);
		break;
	case PROTO_OPEN:
		do_open(s, c, &r, t0);
		break;
	case PROTO_CLOSE: {
		pthread_mutex_lock(&s->lock);
		c->shot = NULL;
		pthread_mutex_unlock(&s->lock);
		reply(s, c, reply_to("closed", &r));
		break;
	}
	case PROTO_STATS:
		do_stats(s, c, &r);
		break;
	default: {
		/* Edits and snapshots: the worker's, in order, on the open shot. */
		pthread_mutex_lock(&s->lock);
		struct srv_shot *sh = c->shot;
		struct srv_job *j = sh ? srv_job_from(&r, c->id, t0) : NULL;
		if (j)
			srv_submit(s, sh, j);
		pthread_mutex_unlock(&s->lock);
		if (!sh)
			error(s, c, &r, PROTO_E_STATE, "%s: no shot is open", proto_op_name(r.op));
		else if (!j)
			error(s, c, &r, PROTO_E_INTERNAL, "%s: out of memory", proto_op_name(r.op));
		break;
	}
	}
out:
	proto_request_free(&r);
}

/* ---- HTTP ---- */

static int http_reply(struct lws *wsi, unsigned status, const char *type, const char *body,
		      size_t len)
{
	size_t cap = LWS_PRE + 1024 + len;
	unsigned char *buf = malloc(cap);
	if (!buf)
		return -1;
	unsigned char *start = buf + LWS_PRE, *p = start, *end = buf + cap - 1;
	if (lws_add_http_common_headers(wsi, status, type, len, &p, end) ||
	    lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL,
					 (const unsigned char *)"no-store", 8, &p, end) ||
	    lws_finalize_write_http_header(wsi, start, &p, end)) {
		free(buf);
		return -1;
	}
	memcpy(buf + LWS_PRE, body, len);
	int n = lws_write(wsi, buf + LWS_PRE, len, LWS_WRITE_HTTP_FINAL);
	free(buf);
	if (n < 0)
		return -1;
	return lws_http_transaction_completed(wsi) ? -1 : 0;
}

static const char *mime_of(const char *path)
{
	static const struct { const char *ext, *type; } types[] = {
		{ ".html", "text/html; charset=utf-8" }, { ".js", "text/javascript" },
		{ ".mjs", "text/javascript" }, { ".css", "text/css" }, { ".png", "image/png" },
		{ ".svg", "image/svg+xml" }, { ".json", "application/json" },
		{ ".ico", "image/x-icon" }, { ".wasm", "application/wasm" },
	};
	const char *dot = strrchr(path, '.');
	for (size_t i = 0; dot && i < sizeof(types) / sizeof(types[0]); i++)
		if (!strcmp(dot, types[i].ext))
			return types[i].type;
	return "application/octet-stream";
}

/* Whether the request's "Authorization: Bearer TOKEN" names a token of the token file. */
static bool bearer_ok(struct srv *s, struct lws *wsi)
{
	char auth[SRV_TOKEN_MAX + 64] = "";
	int n = lws_hdr_total_length(wsi, WSI_TOKEN_HTTP_AUTHORIZATION);
	if (n <= 0 || n >= (int)sizeof(auth) ||
	    lws_hdr_copy(wsi, auth, sizeof(auth), WSI_TOKEN_HTTP_AUTHORIZATION) < 0)
		return false;
	static const char bearer[] = "Bearer ";
	bool ok = !strncmp(auth, bearer, sizeof(bearer) - 1) &&
		  srv_tokens_check(s->tokens, auth + sizeof(bearer) - 1) != SRV_ROLE_NONE;
	memset(auth, 0, sizeof(auth));
	return ok;
}

static int http_request(struct srv *s, struct lws *wsi, const char *uri)
{
	if (!strcmp(uri, "/healthz")) {
		char why[256];
		if (!srv_worker_healthy(s, why, sizeof(why) - 1)) {
			strcat(why, "\n");
			return http_reply(wsi, HTTP_STATUS_SERVICE_UNAVAILABLE, "text/plain", why,
					  strlen(why));
		}
		return http_reply(wsi, HTTP_STATUS_OK, "text/plain", "ok\n", 3);
	}
	if (!strcmp(uri, "/metrics")) {
		if (s->cfg.metrics_token && !bearer_ok(s, wsi))
			return http_reply(wsi, HTTP_STATUS_UNAUTHORIZED, "text/plain",
					  "/metrics needs \"Authorization: Bearer TOKEN\"\n", 45);
		char *t = srv_metrics_text(&s->metrics);
		if (!t)
			return http_reply(wsi, HTTP_STATUS_INTERNAL_SERVER_ERROR, "text/plain",
					  "out of memory\n", 14);
		int r = http_reply(wsi, HTTP_STATUS_OK, "text/plain; version=0.0.4", t, strlen(t));
		free(t);
		return r;
	}
	/* The viewer's files: no "..", no hidden files, nothing but the folder. */
	if (s->cfg.viewer_dir[0] && uri[0] == '/' && !strstr(uri, "..") && !strstr(uri, "/.") &&
	    strlen(uri) < 512) {
		char path[4096 + 600];
		snprintf(path, sizeof(path), "%s%s%s", s->cfg.viewer_dir, uri,
			 uri[strlen(uri) - 1] == '/' ? "index.html" : "");
		struct stat st;
		if (!stat(path, &st) && S_ISREG(st.st_mode)) {
			int n = lws_serve_http_file(wsi, path, mime_of(path), NULL, 0);
			if (n < 0 || (n > 0 && lws_http_transaction_completed(wsi)))
				return -1;
			return 0;
		}
	}
	if (!strcmp(uri, "/")) {
		static const char page[] =
			"relightd: no viewer is served (relightd --viewer DIR). WebSocket "
			"clients connect to /ws with subprotocol " WS_PROTOCOL ".\n";
		return http_reply(wsi, HTTP_STATUS_OK, "text/plain", page, sizeof(page) - 1);
	}
	return http_reply(wsi, HTTP_STATUS_NOT_FOUND, "text/plain", "not found\n", 10);
}

/* ---- libwebsockets ---- */

static bool origin_ok(struct srv *s, struct lws *wsi)
{
	char origin[512] = "";
	if (lws_hdr_total_length(wsi, WSI_TOKEN_ORIGIN) >= (int)sizeof(origin))
		return false;
	if (lws_hdr_total_length(wsi, WSI_TOKEN_ORIGIN) > 0 &&
	    lws_hdr_copy(wsi, origin, sizeof(origin), WSI_TOKEN_ORIGIN) < 0)
		return false;
	return srv_origin_allowed(&s->cfg, origin[0] ? origin : NULL);
}

/* Whether the upgrade asks for WS_PATH (a query string allowed) and offers WS_PROTOCOL. */
static bool upgrade_ok(struct lws *wsi)
{
	char uri[256] = "", offered[512] = "";
	if (lws_hdr_total_length(wsi, WSI_TOKEN_GET_URI) >= (int)sizeof(uri) ||
	    lws_hdr_copy(wsi, uri, sizeof(uri), WSI_TOKEN_GET_URI) < 0 || strcmp(uri, WS_PATH))
		return false;
	if (lws_hdr_total_length(wsi, WSI_TOKEN_PROTOCOL) >= (int)sizeof(offered) ||
	    lws_hdr_copy(wsi, offered, sizeof(offered), WSI_TOKEN_PROTOCOL) <= 0)
		return false;
	/* Sec-WebSocket-Protocol: a comma-separated list. */
	char *save = NULL;
	for (char *t = strtok_r(offered, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
		t += strspn(t, " \t");
		size_t n = strcspn(t, " \t");
		if (n == strlen(WS_PROTOCOL) && !memcmp(t, WS_PROTOCOL, n))
			return true;
	}
	return false;
}

static void client_free(struct srv_client *c)
{
	sendq_finish(&c->q);
	srv_frame_unref(c->inflight);
	proto_rx_finish(&c->rx);
	free(c);
}

static int on_receive(struct srv *s, struct srv_client *c, struct lws *wsi, const void *in,
		      size_t len)
{
	/* Until its hello is accepted a connection may hold one small message. */
	size_t max = s->cfg.max_message;
	if (!c->hello && max > PROTO_PREAUTH_MAX)
		max = PROTO_PREAUTH_MAX;
	bool first = lws_is_first_fragment(wsi);
	if (first && !c->rx.too_big)
		c->rx_binary = lws_frame_is_binary(wsi);
	/* With permessage-deflate the pieces are inflated chunks: the limit holds on
	 * what they inflate to, and the first chunk past it ends the connection. */
	switch (proto_rx_feed(&c->rx, in, len, first, lws_is_final_fragment(wsi), max)) {
	case PROTO_RX_MORE:
		return 0;
	case PROTO_RX_MESSAGE:
		break;
	case PROTO_RX_TOO_BIG: {
		static const char reason[] = "message too big";
		lws_close_reason(wsi, LWS_CLOSE_STATUS_MESSAGE_TOO_LARGE,
				 (unsigned char *)reason, sizeof(reason) - 1);
		rl_log_limited(RL_LOG_INFO, "client %llu: a message over %zu bytes%s: closed (1009)",
			       (unsigned long long)c->id, max, c->hello ? "" : " before hello");
		pthread_mutex_lock(&s->lock);
		c->cut_off = true;
		c->close_code = LWS_CLOSE_STATUS_MESSAGE_TOO_LARGE;
		c->close_why = reason;
		pthread_mutex_unlock(&s->lock);
		lws_callback_on_writable(wsi);
		return -1;
	}
	case PROTO_RX_DISCARD:
	case PROTO_RX_NOMEM:
		return -1;
	}
	if (c->rx_binary) {
		c->messages++;
		error(s, c, NULL, PROTO_E_MALFORMED, "binary frames are not requests");
	} else {
		handle_text(s, c, c->rx.buf, c->rx.len);
	}
	return 0;
}

static int on_writeable(struct srv *s, struct srv_client *c, struct lws *wsi)
{
	/* permessage-deflate may still point into the frame written last. */
	srv_frame_unref(c->inflight);
	c->inflight = NULL;
	pthread_mutex_lock(&s->lock);
	if (c->cut_off && !c->q.len) {
		enum lws_close_status code = c->close_code ? (enum lws_close_status)c->close_code
							   : LWS_CLOSE_STATUS_POLICY_VIOLATION;
		const char *why = c->close_why ? c->close_why : "policy";
		pthread_mutex_unlock(&s->lock);
		lws_close_reason(wsi, code, (unsigned char *)why, strlen(why));
		return -1;
	}
	if (c->overflow) {
		/* Cut off for not reading: nothing more goes out. */
		pthread_mutex_unlock(&s->lock);
		lws_close_reason(wsi, LWS_CLOSE_STATUS_POLICY_VIOLATION, NULL, 0);
		return -1;
	}
	if (g_signal && !c->q.len) {
		/* Stopping, and everything queued went out: say goodbye. */
		pthread_mutex_unlock(&s->lock);
		static const char reason[] = "relightd is stopping";
		lws_close_reason(wsi, LWS_CLOSE_STATUS_GOINGAWAY, (unsigned char *)reason,
				 sizeof(reason) - 1);
		return -1;
	}
	struct srv_frame *f = sendq_pop(&c->q);
	bool more = c->q.len > 0;
	if (f && f->binary) {
		c->tiles_sent++;
		atomic_fetch_add(&s->metrics.tiles_sent, 1);
	}
	if (f) {
		c->bytes_sent += f->len;
		if (f->t0 > 0) {
			srv_metrics_latency(&s->metrics, srv_now() - f->t0);
			f->t0 = 0;
		}
	}
	pthread_mutex_unlock(&s->lock);
	if (!f)
		return 0;
	atomic_fetch_add(&s->metrics.bytes_sent, f->len);
	int n = lws_write(wsi, srv_frame_payload(f), f->len,
			  f->binary ? LWS_WRITE_BINARY : LWS_WRITE_TEXT);
	c->inflight = f;
	if (n < (int)f->len)
		return -1;
	if (more || c->cut_off || g_signal)
		lws_callback_on_writable(wsi);
	return 0;
}

static int callback(struct lws *wsi, enum lws_callback_reasons reason, void *user, void *in,
		    size_t len)
{
	struct srv *s = &g_srv;
	struct srv_client **pc = user;
	switch (reason) {
	case LWS_CALLBACK_HTTP:
		return http_request(s, wsi, in ? in : "/");
	case LWS_CALLBACK_HTTP_FILE_COMPLETION:
		return lws_http_transaction_completed(wsi) ? -1 : 0;
	case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION: {
		/* Connections awaiting hello have their own limit, so silent ones
		 * cannot keep clients with a token out. */
		pthread_mutex_lock(&s->lock);
		bool full = s->nclients - s->npreauth >= s->cfg.max_clients;
		bool waiting = s->npreauth >= s->cfg.max_preauth;
		pthread_mutex_unlock(&s->lock);
		const char *why = g_signal ? "stopping" : !upgrade_ok(wsi) ?
				  "not an upgrade to " WS_PATH " with subprotocol " WS_PROTOCOL :
				  full ? "too many clients" :
				  waiting ? "too many connections waiting for their hello" :
				  !origin_ok(s, wsi) ? "its Origin is not allowed" : NULL;
		if (why) {
			atomic_fetch_add(&s->metrics.refused, 1);
			rl_log_limited(RL_LOG_INFO, "a connection refused: %s", why);
			return 1;
		}
		return 0;
	}
	case LWS_CALLBACK_ESTABLISHED: {
		struct srv_client *c = calloc(1, sizeof(*c));
		if (!c)
			return -1;
		c->wsi = wsi;
		c->format = PROTO_RGBA8;
		sendq_init(&c->q, s->cfg.client_queue);
		pthread_mutex_lock(&s->lock);
		c->id = ++s->next_client;
		c->next = s->clients;
		s->clients = c;
		s->nclients++;
		s->npreauth++;
		pthread_mutex_unlock(&s->lock);
		*pc = c;
		lws_set_timer_usecs(wsi, (lws_usec_t)s->cfg.hello_timeout * LWS_US_PER_SEC);
		atomic_fetch_add(&s->metrics.clients, 1);
		atomic_fetch_add(&s->metrics.connections, 1);
		return 0;
	}
	case LWS_CALLBACK_RECEIVE:
		if (!pc || !*pc)
			return -1;
		return on_receive(s, *pc, wsi, in, len);
	case LWS_CALLBACK_SERVER_WRITEABLE:
		if (!pc || !*pc)
			return 0;
		return on_writeable(s, *pc, wsi);
	case LWS_CALLBACK_TIMER: {
		/* The hello deadline. */
		struct srv_client *c = pc ? *pc : NULL;
		if (!c || c->hello)
			return 0;
		rl_log_limited(RL_LOG_INFO, "client %llu: no hello within %u s: closed",
			       (unsigned long long)c->id, s->cfg.hello_timeout);
		pthread_mutex_lock(&s->lock);
		c->cut_off = true;
		c->close_why = "no hello in time";
		pthread_mutex_unlock(&s->lock);
		atomic_fetch_add(&s->metrics.refused, 1);
		lws_callback_on_writable(wsi);
		return 0;
	}
	case LWS_CALLBACK_CLOSED: {
		if (!pc || !*pc)
			return 0;
		struct srv_client *c = *pc;
		*pc = NULL;
		pthread_mutex_lock(&s->lock);
		if (!c->hello)
			s->npreauth--;
		for (struct srv_client **p = &s->clients; *p; p = &(*p)->next)
			if (*p == c) {
				*p = c->next;
				break;
			}
		s->nclients--;
		pthread_mutex_unlock(&s->lock);
		atomic_fetch_sub(&s->metrics.clients, 1);
		client_free(c);
		return 0;
	}
	case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
		pthread_mutex_lock(&s->lock);
		for (struct srv_client *c = s->clients; c; c = c->next)
			if (c->q.len || c->cut_off || g_signal)
				lws_callback_on_writable(c->wsi);
		pthread_mutex_unlock(&s->lock);
		return 0;
	default:
		return lws_callback_http_dummy(wsi, reason, user, in, len);
	}
}

static const struct lws_protocols protocols[] = {
	{ WS_PROTOCOL, callback, sizeof(struct srv_client *), 65536, 0, NULL, 0 },
	{ NULL, NULL, 0, 0, 0, NULL, 0 },
};

static const struct lws_extension extensions[] = {
	{ "permessage-deflate", lws_extension_callback_pm_deflate,
	  "permessage-deflate; client_no_context_takeover; client_max_window_bits" },
	{ NULL, NULL, NULL },
};

/* SIGTERM and SIGINT arrive here, on a thread of their own. */
static void *signal_main(void *arg)
{
	sigset_t *set = arg;
	int sig = 0;
	if (sigwait(set, &sig) == 0) {
		g_signal = sig;
		if (g_srv.lws)
			lws_cancel_service(g_srv.lws);
	}
	return NULL;
}

/* libwebsockets logs what peers do wrong: a line per peer, so limited too. */
static void lws_to_log(int level, const char *line)
{
	rl_log_limited(level == LLL_ERR ? RL_LOG_ERROR : RL_LOG_WARN, "libwebsockets: %.*s",
		       (int)strcspn(line, "\n"), line);
}

/* Make the folder @path (@cap bytes) absolute; it need not exist. */
static bool absolute(char *path, size_t cap)
{
	if (!path[0])
		return true;
	char *abs = rl_path_absolute(path);
	bool fits = abs && strlen(abs) < cap;
	if (fits)
		memcpy(path, abs, strlen(abs) + 1);
	else if (abs)
		errno = ENAMETOOLONG;
	free(abs);
	return fits;
}

static uint32_t clients_left(struct srv *s)
{
	pthread_mutex_lock(&s->lock);
	uint32_t n = s->nclients;
	pthread_mutex_unlock(&s->lock);
	return n;
}

int main(int argc, char **argv)
{
	struct srv *s = &g_srv;
	char err[1024];
	int status = 1;
	srv_config_defaults(&s->cfg);
	if (!srv_config_parse_args(&s->cfg, argc, argv, stdout, err, sizeof(err))) {
		fprintf(stderr, "relightd: %s\nRun 'relightd --help' for usage.\n", err);
		srv_config_free(&s->cfg);
		return 2;
	}
	if (s->cfg.help) {
		srv_config_free(&s->cfg);
		return 0;
	}
	if (s->cfg.version) {
		printf("relightd %s (protocol %d)\n", RELIGHTD_VERSION, PROTO_VERSION);
		srv_config_free(&s->cfg);
		return 0;
	}
	rl_log_set_level((enum rl_log_level)s->cfg.log_level);
	rl_log_set_rate(s->cfg.log_rate);
	pthread_mutex_init(&s->lock, NULL);
	pthread_cond_init(&s->wake, NULL);
	srv_metrics_init(&s->metrics);

	/* Signals go to one thread, which wakes the service loop. */
	sigset_t set;
	sigemptyset(&set);
	sigaddset(&set, SIGTERM);
	sigaddset(&set, SIGINT);
	pthread_sigmask(SIG_BLOCK, &set, NULL);
	signal(SIGPIPE, SIG_IGN);
	pthread_t sig_thread;
	bool sig_started = pthread_create(&sig_thread, NULL, signal_main, &set) == 0;

	if (s->cfg.token_file[0]) {
		s->tokens = srv_tokens_load(s->cfg.token_file, err, sizeof(err));
		if (!s->tokens) {
			fprintf(stderr, "relightd: %s\n", err);
			goto out;
		}
		if (!srv_tokens_count(s->tokens))
			rl_log(RL_LOG_WARN, "%s holds no token: no client can connect",
			       s->cfg.token_file);
	} else if (!s->cfg.host[0] || (strcmp(s->cfg.host, "127.0.0.1") &&
					 strcmp(s->cfg.host, "localhost") &&
					 strcmp(s->cfg.host, "::1"))) {
		rl_log(RL_LOG_WARN, "listening on %s with no --token-file: anyone who can reach "
		       "it may edit", s->cfg.host[0] ? s->cfg.host : "every interface");
	}
	s->registry = srv_shots_open(s->cfg.shots_dir, err, sizeof(err));
	if (!s->registry) {
		fprintf(stderr, "relightd: %s\n", err);
		goto out;
	}
	/* The viewer: relight's own, from the source tree or where it is installed. */
	static const char *const viewers[] = { RELIGHTD_SOURCE_WEB_DIR, RELIGHTD_WEB_DIR };
	for (size_t i = 0; !s->cfg.viewer_dir[0] && i < 2; i++) {
		char index[4096 + 16];
		snprintf(index, sizeof(index), "%s/index.html", viewers[i]);
		if (!access(index, R_OK))
			snprintf(s->cfg.viewer_dir, sizeof(s->cfg.viewer_dir), "%s", viewers[i]);
	}
	/* RIBs name shadow maps and textures relative to their folder: work there,
	 * as `relight bake` run in it would (before any thread that opens files). */
	if (!absolute(s->cfg.shots_dir, sizeof(s->cfg.shots_dir)) ||
	    !absolute(s->cfg.snapshot_dir, sizeof(s->cfg.snapshot_dir)) ||
	    !absolute(s->cfg.cert, sizeof(s->cfg.cert)) ||
	    !absolute(s->cfg.key, sizeof(s->cfg.key)) ||
	    !absolute(s->cfg.viewer_dir, sizeof(s->cfg.viewer_dir)) ||
	    chdir(s->cfg.shots_dir)) {
		fprintf(stderr, "relightd: cannot work in %s: %s\n", s->cfg.shots_dir,
			strerror(errno));
		goto out;
	}
	if (!srv_worker_start(s)) {
		fprintf(stderr, "relightd: no GPU context (EGL): %s\n", s->gpu_err);
		goto out;
	}
	rl_log(RL_LOG_INFO, "GPU: %s", s->gpu_renderer);

	lws_set_log_level(s->cfg.quiet ? LLL_ERR : LLL_ERR | LLL_WARN, lws_to_log);
	char *real = realpath(s->cfg.shots_dir, NULL);
	if (real && strlen(real) < sizeof(g_shots_real))
		memcpy(g_shots_real, real, strlen(real) + 1);
	free(real);
	struct lws_context_creation_info info;
	memset(&info, 0, sizeof(info));
	char iface[sizeof(s->cfg.host)];
	memcpy(iface, s->cfg.host, sizeof(iface));
	iface[sizeof(iface) - 1] = '\0';
	if (iface[0] == '[') {
		memmove(iface, iface + 1, strlen(iface));
		iface[strcspn(iface, "]")] = '\0';
	}
	info.iface = iface[0] ? iface : NULL;
	info.port = s->cfg.port;
	info.protocols = protocols;
	info.extensions = extensions;
	if (s->cfg.cert[0]) {
		info.options |= LWS_SERVER_OPTION_DO_SSL_GLOBAL_INIT;
		info.ssl_cert_filepath = s->cfg.cert;
		info.ssl_private_key_filepath = s->cfg.key;
	}
	info.pt_serv_buf_size = 64 * 1024;
	info.timeout_secs = 30;
	s->lws = lws_create_context(&info);
	if (!s->lws) {
		if (s->cfg.cert[0])
			fprintf(stderr, "relightd: cannot listen on %s:%d with TLS (the address in "
				"use or not this machine's, or %s / %s unreadable or not a "
				"matching PEM certificate and key)\n", s->cfg.host, s->cfg.port,
				s->cfg.cert, s->cfg.key);
		else
			fprintf(stderr, "relightd: cannot listen on %s:%d (in use, or not an address "
				"of this machine)\n", s->cfg.host, s->cfg.port);
		goto out;
	}
	struct lws_vhost *vh = lws_get_vhost_by_name(s->lws, "default");
	int port = vh ? lws_get_vhost_listen_port(vh) : s->cfg.port;
	bool v6 = strchr(iface, ':') != NULL;
	printf("relightd: listening on %s://%s%s%s:%d/\n", s->cfg.cert[0] ? "https" : "http",
	       v6 ? "[" : "", iface[0] ? iface : "0.0.0.0", v6 ? "]" : "", port);
	fflush(stdout);
	rl_log(RL_LOG_INFO, "serving the shots in %s; WebSocket at /ws (%s)", s->cfg.shots_dir,
	       WS_PROTOCOL);

	while (!g_signal)
		if (lws_service(s->lws, 0) < 0)
			break;
	rl_log(RL_LOG_INFO, "%s: finishing", g_signal == SIGINT ? "SIGINT" : "SIGTERM");

	/* Drain: the worker finishes the job in hand, the queues go out and each
	 * client gets a close frame (going away), 2 s at most. */
	srv_worker_stop(s);
	double until = srv_now() + 2;
	while (clients_left(s) && srv_now() < until) {
		lws_cancel_service(s->lws);
		if (lws_service(s->lws, 0) < 0)
			break;
	}
	status = 0;
out:
	srv_worker_stop(s);
	join_bakes();
	if (s->lws)
		lws_context_destroy(s->lws);
	s->lws = NULL;
	if (sig_started) {
		if (!g_signal)
			pthread_kill(sig_thread, SIGTERM);
		pthread_join(sig_thread, NULL);
	}
	srv_shots_close(s->registry);
	srv_tokens_free(s->tokens);
	srv_config_free(&s->cfg);
	pthread_cond_destroy(&s->wake);
	pthread_mutex_destroy(&s->lock);
	return status;
}

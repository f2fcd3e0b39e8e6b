/*
 * relightd's render worker: the one thread that holds the GPU context, the
 * shots in GPU memory and their light caches. It takes the jobs the service
 * thread queues per shot (open, edits, snapshots), applies them in order,
 * and refines the newest edit of each shot level by level, cutting each
 * level into tiles for every client that shows the shot. A new edit
 * preempts refinement: jobs are always taken before the next level is
 * rendered, so a level of a superseded edit is never started.
 *
 * Shots stay resident within --gpu-budget and --max-shots, the least
 * recently used evicted first; an evicted shot keeps its log of edits (the
 * state they produce, editlog.c) and is loaded again, looked up in the
 * shots folder again and its edits replayed, when a client next needs it.
 * Snapshots, opens and picks of a client that has gone are dropped.
 */
#include "srv.h"

#include "fileutil.h"
#include "log.h"
#include "runtime.h"
#include "shotfile.h"
#include "shotmeta.h"
#include "texture.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

/* ---- shots ---- */

struct srv_shot *srv_shot_get(struct srv *s, const char *name)
{
	for (struct srv_shot *sh = s->shots; sh; sh = sh->next)
		if (!strcmp(sh->name, name))
			return sh;
	struct srv_shot *sh = calloc(1, sizeof(*sh));
	if (!sh)
		return NULL;
	snprintf(sh->name, sizeof(sh->name), "%s", name);
	sh->jobs_tail = &sh->jobs;
	sh->next_level = GPU_SHOT_LEVELS;
	sh->next = s->shots;
	s->shots = sh;
	return sh;
}

/*
 * Whether client @c may have one more snapshot now: a bucket of
 * --snapshot-rate snapshots that refills at that many a minute. Lock held.
 */
static bool snapshot_allowed(struct srv *s, struct srv_client *c, double *wait)
{
	double rate = s->cfg.snapshot_rate / 60.0, now = srv_now();
	c->snap_debt -= (now - c->snap_t) * rate;
	if (c->snap_debt < 0)
		c->snap_debt = 0;
	c->snap_t = now;
	if (c->snap_debt + 1 > s->cfg.snapshot_rate) {
		*wait = (c->snap_debt + 1 - s->cfg.snapshot_rate) / rate;
		return false;
	}
	c->snap_debt += 1;
	return true;
}

void srv_submit(struct srv *s, struct srv_shot *shot, struct srv_job *j)
{
	struct srv_client *c = j->op == PROTO_SNAPSHOT ? srv_client_find(s, j->client) : NULL;
	double wait;
	if (c && !snapshot_allowed(s, c, &wait)) {
		srv_send_error(s, c, j->has_id, j->id, PROTO_E_LIMIT,
			       "snapshot: over the limit of %u a minute (--snapshot-rate); the next "
			       "in %.1f s", s->cfg.snapshot_rate, wait);
		srv_job_free(j);
		return;
	}
	j->next = NULL;
	j->gen = shot->gen;
	*shot->jobs_tail = j;
	shot->jobs_tail = &j->next;
	pthread_cond_broadcast(&s->wake);
}

/* ---- loading and eviction (worker thread) ---- */

static void shot_evict(struct srv *s, struct srv_shot *sh)
{
	if (!sh->gpu)
		return;
	rl_log(RL_LOG_INFO, "shot '%s': evicted from GPU memory (%.1f MiB)", sh->name,
	       (double)sh->bytes / (1 << 20));
	gpu_shot_close(sh->gpu);
	sh->gpu = NULL;
	atomic_fetch_sub(&s->metrics.shots_resident, 1);
	atomic_fetch_sub(&s->metrics.gpu_bytes, (int_fast64_t)sh->bytes);
	atomic_fetch_add(&s->metrics.evictions, 1);
	sh->bytes = 0;
}

/* Evict least recently used shots but @keep until the budget and the count hold. */
static void make_room(struct srv *s, struct srv_shot *keep)
{
	for (;;) {
		size_t bytes = 0;
		uint32_t n = 0;
		struct srv_shot *lru = NULL;
		pthread_mutex_lock(&s->lock);
		for (struct srv_shot *sh = s->shots; sh; sh = sh->next) {
			if (!sh->gpu)
				continue;
			bytes += sh->bytes;
			n++;
			if (sh != keep && (!lru || sh->used < lru->used))
				lru = sh;
		}
		pthread_mutex_unlock(&s->lock);
		if (!lru || (bytes <= s->cfg.gpu_budget && n <= s->cfg.max_shots))
			return;
		shot_evict(s, lru);
	}
}

static bool apply_job(struct srv *s, struct srv_shot *sh, const struct srv_job *j, char *err,
		      size_t errlen, enum proto_error_code *code);

/*
 * What the runtime said about @sh since the last call (NULL: nothing), and
 * forget it. The runtime keeps the FILE it was opened with for every later
 * message, so the stream lives as long as the shot does.
 */
static const char *diag_take(struct srv_shot *sh)
{
	if (!sh->diag || fflush(sh->diag) || !sh->diag_len || !sh->diag_buf)
		return NULL;
	size_t n = sh->diag_len;
	while (n && (sh->diag_buf[n - 1] == '\n' || sh->diag_buf[n - 1] == ' '))
		sh->diag_buf[--n] = '\0';
	rewind(sh->diag);
	return n ? sh->diag_buf : NULL;
}

/* Log what the runtime said about @sh. */
static void diag_log(struct srv_shot *sh, enum rl_log_level level)
{
	const char *m = diag_take(sh);
	if (m)
		rl_log(level, "shot '%s': %s", sh->name, m);
}

/*
 * The shot file of @sh, loaded again, is not the size it was (@w x @h): the
 * clients showing it are told and let go of it, so that none is sent tiles
 * of an image of another size; an open after this shows the new one.
 */
static void size_changed(struct srv *s, struct srv_shot *sh, uint32_t w, uint32_t h)
{
	rl_log(RL_LOG_WARN, "shot '%s': its shot file changed size on disk (%ux%u, now %ux%u)",
	       sh->name, w, h, sh->width, sh->height);
	pthread_mutex_lock(&s->lock);
	sh->gen++;
	for (struct srv_client *c = s->clients; c; c = c->next) {
		if (c->shot != sh)
			continue;
		c->shot = NULL;
		srv_send_error(s, c, false, 0, PROTO_E_STATE,
			       "shot '%s' changed on disk: it was %ux%u, it is %ux%u now; open it "
			       "again", sh->name, w, h, sh->width, sh->height);
	}
	pthread_mutex_unlock(&s->lock);
}

/* Load @sh into GPU memory (and replay its edits): false with the reason in @err. */
static bool shot_load(struct srv *s, struct srv_shot *sh, char *err, size_t errlen)
{
	if (sh->gpu)
		return true;
	if (!sh->diag)
		sh->diag = open_memstream(&sh->diag_buf, &sh->diag_len);
	struct gpu_shot_opts o = {
		.diag = sh->diag ? sh->diag : stderr,
		.texture_path = s->cfg.shots_dir,
		.budget = s->cfg.gpu_budget,
	};
	/*
	 * The folder is looked at again at every load, a reload after an
	 * eviction too: the file may have become a link out of the folder, or
	 * gone, since the shot was opened.
	 */
	char path[sizeof(sh->path)];
	enum srv_shot_state state = srv_shots_find(s->registry, sh->name, path, sizeof(path));
	if (state != SRV_SHOT_READY) {
		snprintf(err, errlen, "shot '%s' cannot be loaded: %s", sh->name,
			 state == SRV_SHOT_NEEDS_BAKE
				 ? "its RIB is newer than its shot file: open it again to bake it"
				 : "its shot file is no longer in the shots folder (gone, or a link "
				   "out of the folder)");
		sh->failed = true;
		return false;
	}
	snprintf(sh->path, sizeof(sh->path), "%s", path);
	double t = srv_now();
	sh->gpu = gpu_shot_open(s->gpu, sh->path, &o);
	if (!sh->gpu) {
		const char *m = diag_take(sh);
		snprintf(err, errlen, "shot '%s' cannot be loaded: %s", sh->name,
			 m ? m : "unknown reason");
		sh->failed = true;
		return false;
	}
	diag_log(sh, RL_LOG_WARN);
	sh->failed = false;
	sh->bytes = gpu_shot_bytes(sh->gpu);
	uint32_t was_w = sh->width, was_h = sh->height;
	sh->width = gpu_shot_width(sh->gpu);
	sh->height = gpu_shot_height(sh->gpu);
	if (was_w && (was_w != sh->width || was_h != sh->height))
		size_changed(s, sh, was_w, was_h);
	if (gpu_shot_light_count(sh->gpu) > s->cfg.max_lights) {
		snprintf(err, errlen, "shot '%s' has %u lights, over the limit of %u", sh->name,
			 gpu_shot_light_count(sh->gpu), s->cfg.max_lights);
		gpu_shot_close(sh->gpu);
		sh->gpu = NULL;
		return false;
	}
	atomic_fetch_add(&s->metrics.shots_resident, 1);
	atomic_fetch_add(&s->metrics.gpu_bytes, (int_fast64_t)sh->bytes);
	atomic_fetch_add(&s->metrics.loads, 1);
	/* Edits made before an eviction come back. */
	for (size_t i = 0; i < sh->log.n; i++) {
		char e2[256];
		enum proto_error_code c;
		if (!apply_job(s, sh, sh->log.v[i], e2, sizeof(e2), &c))
			rl_log(RL_LOG_WARN, "shot '%s': replaying an edit failed: %s", sh->name, e2);
	}
	rl_log(RL_LOG_INFO, "shot '%s': loaded, %ux%u, %.1f MiB, %u lights, %.0f ms%s", sh->name,
	       sh->width, sh->height, (double)sh->bytes / (1 << 20),
	       gpu_shot_light_count(sh->gpu), (srv_now() - t) * 1e3,
	       sh->log.n ? ", edits replayed" : "");
	pthread_mutex_lock(&s->lock);
	sh->used = ++s->clock;
	sh->next_level = 0;
	pthread_mutex_unlock(&s->lock);
	make_room(s, sh);
	return true;
}

/* ---- applying requests ---- */

/* Whether @light names the shot's imager (shotmeta.h SHOT_IMAGER). */
static bool is_imager(const struct gpu_shot *g, const char *light)
{
	return light && gpu_shot_imager_shader(g) && !strcmp(light, SHOT_IMAGER);
}

/* Parameter @name of light @light as an edit would give it (its shader space). */
static bool param_value(struct gpu_shot *g, const char *light, const char *name, float v[16],
			uint32_t *n)
{
	if (is_imager(g, light))
		return gpu_shot_get(g, light, name, v, n);
	int i = gpu_shot_find_light(g, light);
	struct gpu_shot_param p;
	for (uint32_t k = 0; i >= 0 && gpu_shot_light_param(g, (uint32_t)i, k, &p); k++)
		if (!strcmp(p.name, name)) {
			memcpy(v, p.value, sizeof(p.value));
			*n = p.n;
			return true;
		}
	return false;
}

/* Set one parameter: a string (a map's name) or numbers. */
static bool set_one(struct gpu_shot *g, const char *light, const struct proto_param *p, char *err,
		    size_t errlen)
{
	if (p->text)
		return gpu_shot_set_string(g, light, p->name, p->text, err, errlen);
	return gpu_shot_set(g, light, p->name, p->values, p->n, err, errlen);
}

static bool apply_set(struct gpu_shot *g, const struct srv_job *j, char *err, size_t errlen)
{
	/* All or nothing: a refused parameter puts back those set before it. */
	float old[64][16];
	uint32_t oldn[64];
	char *olds[64];
	uint32_t n = j->nparams < 64 ? j->nparams : 64;
	bool ok = true;
	uint32_t k = 0;
	for (; k < n; k++) {
		olds[k] = gpu_shot_get_string(g, j->light, j->params[k].name);
		if (olds[k] || !param_value(g, j->light, j->params[k].name, old[k], &oldn[k]))
			oldn[k] = 0;
		if (!set_one(g, j->light, &j->params[k], err, errlen)) {
			ok = false;
			break;
		}
	}
	for (uint32_t b = 0; b < k && !ok; b++) {
		char e2[64];
		if (olds[b])
			gpu_shot_set_string(g, j->light, j->params[b].name, olds[b], e2, sizeof(e2));
		else if (oldn[b])
			gpu_shot_set(g, j->light, j->params[b].name, old[b], oldn[b], e2, sizeof(e2));
	}
	for (uint32_t b = 0; b < k + (ok ? 0 : 1) && b < n; b++)
		free(olds[b]);
	return ok;
}

/* The code of a refused parameter (the light was checked already): a name the
 * shader lacks, or a value it does not take. */
static enum proto_error_code code_of(const char *err)
{
	if (strstr(err, "has no parameter"))
		return PROTO_E_UNKNOWN_PARAM;
	/* a string for a number, or numbers for a string */
	if (strstr(err, "not a string") || strstr(err, "is a string"))
		return PROTO_E_TYPE;
	return PROTO_E_RANGE;
}

static bool apply_job(struct srv *s, struct srv_shot *sh, const struct srv_job *j, char *err,
		      size_t errlen, enum proto_error_code *code)
{
	struct gpu_shot *g = sh->gpu;
	bool ok = false;
	*code = PROTO_E_RANGE;
	/* the imager takes "set" edits alone */
	if (j->light && j->op != PROTO_ADD_LIGHT && gpu_shot_find_light(g, j->light) < 0 &&
	    !(j->op == PROTO_SET && is_imager(g, j->light))) {
		snprintf(err, errlen, "shot '%s' has no light '%s'", sh->name, j->light);
		*code = PROTO_E_UNKNOWN_LIGHT;
		return false;
	}
	switch (j->op) {
	case PROTO_SET:
		ok = apply_set(g, j, err, errlen);
		break;
	case PROTO_MUTE:
		ok = gpu_shot_mute(g, j->light, j->on, err, errlen);
		break;
	case PROTO_SOLO:
		ok = gpu_shot_solo(g, j->light, err, errlen);
		break;
	case PROTO_FREEZE:
		ok = gpu_shot_freeze(g, j->light, j->on, err, errlen);
		break;
	case PROTO_REMOVE_LIGHT:
		ok = gpu_shot_remove_light(g, j->light, err, errlen);
		break;
	case PROTO_ADD_LIGHT: {
		if (gpu_shot_find_light(g, j->light) >= 0) {
			snprintf(err, errlen, "shot '%s' has a light '%s' already", sh->name, j->light);
			*code = PROTO_E_STATE;
			return false;
		}
		uint32_t live = 0;
		for (uint32_t i = 0; i < gpu_shot_light_count(g); i++)
			live += gpu_shot_light_name(g, i) != NULL;
		if (live >= s->cfg.max_lights) {
			snprintf(err, errlen, "shot '%s' has %u lights, the limit", sh->name, live);
			*code = PROTO_E_LIMIT;
			return false;
		}
		/* A removed light keeps its place in the runtime and in the edit log:
		 * bound what adding and removing lights for ever would grow. */
		uint64_t slots = (uint64_t)SRV_LIGHT_SLOTS_PER_LIGHT * s->cfg.max_lights;
		if (gpu_shot_light_count(g) >= slots) {
			snprintf(err, errlen, "shot '%s' has had %u lights, added and removed ones "
				 "included; the most is %u x --max-lights (%llu)", sh->name,
				 gpu_shot_light_count(g), SRV_LIGHT_SLOTS_PER_LIGHT,
				 (unsigned long long)slots);
			*code = PROTO_E_LIMIT;
			return false;
		}
		ok = gpu_shot_add_light(g, j->light, j->shader, NULL, err, errlen) >= 0;
		if (!ok) {
			*code = PROTO_E_UNKNOWN_PARAM;   /* a shader neither the shot nor the path has */
			return false;
		}
		if (j->nparams && !apply_set(g, j, err, errlen)) {
			char e2[64];
			gpu_shot_remove_light(g, j->light, e2, sizeof(e2));
			*code = code_of(err);
			return false;
		}
		return true;
	}
	default:
		snprintf(err, errlen, "'%s' is not an edit", proto_op_name(j->op));
		*code = PROTO_E_INTERNAL;
		return false;
	}
	if (!ok)
		*code = code_of(err);
	return ok;
}

/* ---- replies ---- */

/* A parameter as a client shows it: name, type, value, range. */
static cJSON *param_json(const struct gpu_shot_param *p)
{
	cJSON *pj = cJSON_CreateObject();
	cJSON_AddStringToObject(pj, "name", p->name);
	cJSON_AddStringToObject(pj, "type", p->type);
	if (p->n == 1) {
		cJSON_AddNumberToObject(pj, "value", p->value[0]);
	} else {
		cJSON *v = cJSON_AddArrayToObject(pj, "value");
		for (uint32_t c = 0; c < p->n; c++)
			cJSON_AddItemToArray(v, cJSON_CreateNumber(p->value[c]));
	}
	cJSON_AddNumberToObject(pj, "min", p->min);
	cJSON_AddNumberToObject(pj, "max", p->max);
	return pj;
}

static cJSON *opened_json(const struct srv_shot *sh, const struct srv_job *j)
{
	struct gpu_shot *g = sh->gpu;
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", "opened");
	if (j->has_id)
		proto_add_id(o, j->id);
	cJSON_AddStringToObject(o, "shot", sh->name);
	cJSON_AddNumberToObject(o, "width", gpu_shot_width(g));
	cJSON_AddNumberToObject(o, "height", gpu_shot_height(g));
	cJSON_AddNumberToObject(o, "levels", GPU_SHOT_LEVELS);
	cJSON_AddNumberToObject(o, "edit", sh->edit);
	cJSON_AddNumberToObject(o, "samples", (double)gpu_shot_samples(g));
	cJSON *lights = cJSON_AddArrayToObject(o, "lights");
	for (uint32_t i = 0; i < gpu_shot_light_count(g); i++) {
		if (!gpu_shot_light_name(g, i))
			continue;
		cJSON *l = cJSON_CreateObject();
		cJSON_AddStringToObject(l, "name", gpu_shot_light_name(g, i));
		cJSON_AddStringToObject(l, "shader", gpu_shot_light_shader(g, i));
		cJSON *ps = cJSON_AddArrayToObject(l, "params");
		struct gpu_shot_param p;
		for (uint32_t k = 0; gpu_shot_light_param(g, i, k, &p); k++)
			cJSON_AddItemToArray(ps, param_json(&p));
		cJSON_AddItemToArray(lights, l);
	}
	if (gpu_shot_imager_shader(g)) {
		cJSON *im = cJSON_AddObjectToObject(o, "imager");
		cJSON_AddStringToObject(im, "name", SHOT_IMAGER);
		cJSON_AddStringToObject(im, "shader", gpu_shot_imager_shader(g));
		cJSON *ps = cJSON_AddArrayToObject(im, "params");
		struct gpu_shot_param p;
		for (uint32_t k = 0; gpu_shot_imager_param(g, k, &p); k++)
			cJSON_AddItemToArray(ps, param_json(&p));
	}
	return o;
}

/* Send @o (consumed) to client @client if it is still connected. */
static void reply_json(struct srv *s, uint64_t client, cJSON *o)
{
	pthread_mutex_lock(&s->lock);
	struct srv_client *c = srv_client_find(s, client);
	if (c)
		srv_send_json(s, c, o);
	pthread_mutex_unlock(&s->lock);
	cJSON_Delete(o);
}

static void reply_simple(struct srv *s, uint64_t client, const char *op, const struct srv_job *j,
			 int64_t edit)
{
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", op);
	if (j->has_id)
		proto_add_id(o, j->id);
	if (edit >= 0)
		cJSON_AddNumberToObject(o, "edit", (double)edit);
	reply_json(s, client, o);
}

static void reply_error(struct srv *s, const struct srv_job *j, enum proto_error_code code,
			const char *msg)
{
	pthread_mutex_lock(&s->lock);
	struct srv_client *c = srv_client_find(s, j->client);
	if (c)
		srv_send_error(s, c, j->has_id, j->id, code, "%s", msg);
	pthread_mutex_unlock(&s->lock);
}

/* ---- images to tiles ---- */

struct images {
	uint32_t w, h;
	uint32_t *px8;       /* w * h, RGBA8 */
	uint16_t *px16;      /* w * h * 4 halves */
	size_t cap;          /* pixels both can hold */
};

static bool images_fit(struct images *im, uint32_t w, uint32_t h)
{
	size_t n = (size_t)w * h;
	im->w = w;
	im->h = h;
	if (n <= im->cap)
		return true;
	free(im->px8);
	free(im->px16);
	im->px8 = malloc(n * sizeof(uint32_t));
	im->px16 = malloc(n * 4 * sizeof(uint16_t));
	im->cap = im->px8 && im->px16 ? n : 0;
	return im->cap != 0;
}

/* The tiles of level @level of @im in @format, in the queue order: row by row. */
static struct srv_frame **make_tiles(const struct images *im, enum proto_format format,
				     uint32_t edit, uint32_t level, uint32_t ts, size_t *count)
{
	uint32_t nx = (im->w + ts - 1) / ts, ny = (im->h + ts - 1) / ts;
	struct srv_frame **v = calloc((size_t)nx * ny, sizeof(*v));
	if (!v)
		return NULL;
	size_t bpp = format == PROTO_RGBA8 ? 4 : 8, n = 0;
	for (uint32_t ty = 0; ty < ny; ty++) {
		for (uint32_t tx = 0; tx < nx; tx++) {
			struct proto_tile t = {
				.edit = edit, .level = level, .format = format,
				.x = tx * ts, .y = ty * ts,
			};
			t.width = im->w - t.x < ts ? im->w - t.x : ts;
			t.height = im->h - t.y < ts ? im->h - t.y : ts;
			size_t row = t.width * bpp;
			struct srv_frame *f =
				srv_frame_new(PROTO_TILE_HEADER_BYTES + row * t.height, true);
			if (!f)
				continue;
			f->edit = edit;
			f->level = level;
			f->x = t.x;
			f->y = t.y;
			unsigned char *p = srv_frame_payload(f);
			proto_tile_header(&t, p);
			p += PROTO_TILE_HEADER_BYTES;
			for (uint32_t y = 0; y < t.height; y++) {
				size_t at = ((size_t)(t.y + y) * im->w + t.x);
				const void *src = format == PROTO_RGBA8 ? (const void *)(im->px8 + at)
									: (const void *)(im->px16 + at * 4);
				memcpy(p + y * row, src, row);
			}
			v[n++] = f;
		}
	}
	*count = n;
	return v;
}

/* Read level @level of @sh in the formats asked for. */
static bool read_level(struct gpu_shot *g, int level, struct images *im, bool need8, bool need16)
{
	if (!images_fit(im, gpu_shot_width(g), gpu_shot_height(g)))
		return false;
	if (need8 && !gpu_shot_read_srgb8(g, level, im->px8))
		return false;
	if (need16 && !gpu_shot_read_half(g, level, im->px16))
		return false;
	return true;
}

/* A level's frames: its tiles per format and the "level" message after them. */
struct level_frames {
	struct srv_frame **tiles[3];   /* by enum proto_format */
	size_t count[3];
	struct srv_frame *done;
};

/*
 * Cut level @level of edit @edit (read into @im) into tiles for the formats
 * asked for, and make its message; @t0 > 0 marks the first tile for the
 * latency histogram. No lock needed: the frames are not shared yet.
 */
static void level_build(struct srv *s, const struct srv_shot *sh, const struct images *im,
			bool need8, bool need16, uint32_t edit, int level, double ms, double t0,
			struct level_frames *out)
{
	memset(out, 0, sizeof(*out));
	uint32_t ts = s->cfg.tile_size;
	if (need8)
		out->tiles[PROTO_RGBA8] = make_tiles(im, PROTO_RGBA8, edit, (uint32_t)level, ts,
						     &out->count[PROTO_RGBA8]);
	if (need16)
		out->tiles[PROTO_RGBA16F] = make_tiles(im, PROTO_RGBA16F, edit, (uint32_t)level, ts,
						       &out->count[PROTO_RGBA16F]);
	for (int f = 1; f <= 2; f++)
		if (t0 > 0 && out->count[f])
			out->tiles[f][0]->t0 = t0;
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", "level");
	cJSON_AddStringToObject(o, "shot", sh->name);
	cJSON_AddNumberToObject(o, "edit", edit);
	cJSON_AddNumberToObject(o, "level", level);
	cJSON_AddNumberToObject(o, "ms", ms);
	char *msg = cJSON_PrintUnformatted(o);
	cJSON_Delete(o);
	out->done = msg ? srv_frame_text(msg, strlen(msg)) : NULL;
	free(msg);
}

/* Queue @lf for the clients that show @sh, or client @only alone when it is not 0. Lock held. */
static void level_post(struct srv *s, const struct srv_shot *sh, const struct level_frames *lf,
		       uint64_t only)
{
	for (struct srv_client *c = s->clients; c; c = c->next) {
		if (c->shot != sh || (only && c->id != only))
			continue;
		for (size_t i = 0; i < lf->count[c->format]; i++)
			srv_send(s, c, lf->tiles[c->format][i]);
		if (lf->done)
			srv_send(s, c, lf->done);
	}
	srv_kick(s);
}

static void level_free(struct level_frames *lf)
{
	for (int f = 1; f <= 2; f++) {
		for (size_t i = 0; i < lf->count[f]; i++)
			srv_frame_unref(lf->tiles[f][i]);
		free(lf->tiles[f]);
	}
	srv_frame_unref(lf->done);
}

/* Which formats the clients showing @sh need (lock held). */
static bool formats(struct srv *s, struct srv_shot *sh, bool *need8, bool *need16)
{
	*need8 = *need16 = false;
	for (struct srv_client *c = s->clients; c; c = c->next) {
		if (c->shot != sh)
			continue;
		*need8 |= c->format == PROTO_RGBA8;
		*need16 |= c->format == PROTO_RGBA16F;
	}
	return *need8 || *need16;
}

/* ---- jobs (worker thread, lock not held) ---- */

/* What folder @dir holds of snapshots: its .exr files, and their bytes. */
static void snapshots_held(const char *dir, uint32_t *count, uint64_t *bytes)
{
	*count = 0;
	*bytes = 0;
	DIR *d = opendir(dir);
	if (!d)
		return;
	for (struct dirent *e; (e = readdir(d));) {
		size_t n = strlen(e->d_name);
		struct stat st;
		if (n < 5 || strcmp(e->d_name + n - 4, ".exr") ||
		    fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) || !S_ISREG(st.st_mode))
			continue;
		(*count)++;
		*bytes += (uint64_t)st.st_size;
	}
	closedir(d);
}

/*
 * Whether the snapshots folder has room for one more snapshot of @sh
 * (--snapshot-max-count, --snapshot-max-bytes): a new one is refused at the
 * quota, nothing is deleted. It is counted at its size uncompressed (RGBA
 * halves), the most it can take.
 */
static bool snapshot_room(struct srv *s, const struct srv_shot *sh, char *err, size_t errlen)
{
	uint32_t count;
	uint64_t bytes, need = (uint64_t)sh->width * sh->height * 8 + 65536;
	snapshots_held(s->cfg.snapshot_dir, &count, &bytes);
	if (count >= s->cfg.snapshot_max_count) {
		snprintf(err, errlen, "snapshot: the snapshots folder holds %u snapshots, its quota "
			 "(--snapshot-max-count); remove some first", count);
		return false;
	}
	if (bytes + need > s->cfg.snapshot_max_bytes) {
		snprintf(err, errlen, "snapshot: the snapshots folder holds %.1f MB, and this one may "
			 "take %.1f MB of the quota of %.0f MB (--snapshot-max-bytes); remove some "
			 "first", (double)bytes / (1 << 20), (double)need / (1 << 20),
			 (double)s->cfg.snapshot_max_bytes / (1 << 20));
		return false;
	}
	return true;
}

static void write_snapshot(struct srv *s, struct srv_shot *sh, const struct srv_job *j,
			   struct images *im)
{
	struct gpu_shot_stats st;
	char path[4096 + 256], err[256] = "";
	if (!snapshot_room(s, sh, err, sizeof(err))) {
		reply_error(s, j, PROTO_E_LIMIT, err);
		return;
	}
	bool ok = gpu_shot_render(sh->gpu, GPU_SHOT_FINAL, &st) &&
		  read_level(sh->gpu, GPU_SHOT_FINAL, im, false, true);
	if (ok && !rl_mkdir_p(s->cfg.snapshot_dir)) {
		snprintf(err, sizeof(err), "cannot make the snapshot folder: %s", strerror(errno));
		ok = false;
	}
	float *f = ok ? malloc((size_t)im->w * im->h * 4 * sizeof(float)) : NULL;
	if (ok && !f)
		ok = false;
	if (ok) {
		for (size_t i = 0; i < (size_t)im->w * im->h * 4; i++)
			f[i] = shot_half_value(im->px16[i]);
		struct timespec ts;
		clock_gettime(CLOCK_REALTIME, &ts);
		snprintf(path, sizeof(path), "%s/%s-edit%u-%lld%03ld.exr", s->cfg.snapshot_dir,
			 sh->name, sh->edit, (long long)ts.tv_sec, ts.tv_nsec / 1000000);
		static const char *const names[4] = { "R", "G", "B", "A" };
		struct reyes_image ri = { .width = im->w, .height = im->h, .nchannels = 4,
					  .channel_names = (const char **)names, .data = f };
		char *dbuf = NULL;
		size_t dlen = 0;
		FILE *diag = open_memstream(&dbuf, &dlen);
		ok = reyes_image_write_exr(path, &ri, true, diag ? diag : stderr);
		if (diag)
			fclose(diag);
		if (!ok)
			snprintf(err, sizeof(err), "%s", dbuf ? dbuf : "the EXR was not written");
		free(dbuf);
	}
	free(f);
	if (!ok) {
		reply_error(s, j, PROTO_E_INTERNAL, *err ? err : "the snapshot failed");
		return;
	}
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", "snapshot");
	if (j->has_id)
		proto_add_id(o, j->id);
	/* The file's name in the snapshots folder: the server's paths are its own. */
	cJSON_AddStringToObject(o, "path", strrchr(path, '/') + 1);
	cJSON_AddNumberToObject(o, "edit", sh->edit);
	reply_json(s, j->client, o);
}

/* What is under a pixel: the object, and the lights that reach it. */
static void do_pick(struct srv *s, struct srv_shot *sh, const struct srv_job *j)
{
	struct gpu_shot *g = sh->gpu;
	uint32_t obj;
	if (!gpu_shot_pick(g, j->x, j->y, &obj)) {
		char msg[128];
		snprintf(msg, sizeof(msg), "pick: (%u, %u) is outside the %ux%u image", j->x, j->y,
			 gpu_shot_width(g), gpu_shot_height(g));
		reply_error(s, j, PROTO_E_RANGE, msg);
		return;
	}
	cJSON *o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "op", "picked");
	if (j->has_id)
		proto_add_id(o, j->id);
	cJSON_AddNumberToObject(o, "x", j->x);
	cJSON_AddNumberToObject(o, "y", j->y);
	if (obj == UINT32_MAX)
		cJSON_AddNullToObject(o, "object");
	else
		cJSON_AddNumberToObject(o, "object", obj);
	cJSON *lights = cJSON_AddArrayToObject(o, "lights");
	for (uint32_t i = 0; obj != UINT32_MAX && i < gpu_shot_light_count(g); i++)
		if (gpu_shot_light_reaches(g, i, obj))
			cJSON_AddItemToArray(lights, cJSON_CreateString(gpu_shot_light_name(g, i)));
	reply_json(s, j->client, o);
}

static void do_open(struct srv *s, struct srv_shot *sh, const struct srv_job *j, struct images *im)
{
	cJSON *o = opened_json(sh, j);
	/* The current state: its final level when refinement is done (the
	 * refinement under way reaches the client otherwise). */
	pthread_mutex_lock(&s->lock);
	bool done = sh->next_level >= GPU_SHOT_LEVELS;
	uint32_t edit = sh->edit;
	pthread_mutex_unlock(&s->lock);
	bool need8 = j->format == PROTO_RGBA8, need16 = !need8;
	struct gpu_shot_stats st = { 0 };
	bool have = done && gpu_shot_render(sh->gpu, GPU_SHOT_FINAL, &st) &&
		    read_level(sh->gpu, GPU_SHOT_FINAL, im, need8, need16);
	struct level_frames lf = { 0 };
	if (have)
		level_build(s, sh, im, need8, need16, edit, GPU_SHOT_FINAL, st.ms, 0, &lf);
	pthread_mutex_lock(&s->lock);
	struct srv_client *c = srv_client_find(s, j->client);
	if (c) {
		c->shot = sh;
		c->format = j->format;
		srv_send_json(s, c, o);
		if (have && sh->edit == edit)
			level_post(s, sh, &lf, c->id);
	}
	sh->used = ++s->clock;
	pthread_mutex_unlock(&s->lock);
	level_free(&lf);
	cJSON_Delete(o);
}

static void do_job_(struct srv *s, struct srv_shot *sh, struct srv_job *j, struct images *im);

static void do_job(struct srv *s, struct srv_shot *sh, struct srv_job *j, struct images *im)
{
	do_job_(s, sh, j, im);
	diag_log(sh, RL_LOG_WARN);
}

/*
 * Whether @j is a request that only its client wants (an open, a snapshot,
 * a pick: not an edit, which changes the shot for everyone) from a client
 * that has gone.
 */
static bool orphaned(struct srv *s, const struct srv_job *j)
{
	if (j->op != PROTO_OPEN && j->op != PROTO_SNAPSHOT && j->op != PROTO_PICK)
		return false;
	pthread_mutex_lock(&s->lock);
	bool gone = !srv_client_find(s, j->client);
	pthread_mutex_unlock(&s->lock);
	return gone;
}

static void do_job_(struct srv *s, struct srv_shot *sh, struct srv_job *j, struct images *im)
{
	char err[1024];
	if (orphaned(s, j)) {
		rl_log(RL_LOG_DEBUG, "shot '%s': a %s of a client that has gone: dropped", sh->name,
		       proto_op_name(j->op));
		srv_job_free(j);
		return;
	}
	if (!sh->gpu) {
		if (!shot_load(s, sh, err, sizeof(err))) {
			rl_log_limited(RL_LOG_ERROR, "%s", err);
			reply_error(s, j, PROTO_E_INTERNAL, err);
			srv_job_free(j);
			return;
		}
	}
	if (j->op != PROTO_OPEN && j->gen != sh->gen) {
		reply_error(s, j, PROTO_E_STATE, "the shot changed on disk since this was sent: "
			    "open it again");
		srv_job_free(j);
		return;
	}
	switch (j->op) {
	case PROTO_OPEN:
		do_open(s, sh, j, im);
		srv_job_free(j);
		return;
	case PROTO_SNAPSHOT:
		write_snapshot(s, sh, j, im);
		srv_job_free(j);
		return;
	case PROTO_PICK:
		do_pick(s, sh, j);
		srv_job_free(j);
		return;
	default:
		break;
	}
	enum proto_error_code code;
	if (!apply_job(s, sh, j, err, sizeof(err), &code)) {
		reply_error(s, j, code, err);
		srv_job_free(j);
		return;
	}
	pthread_mutex_lock(&s->lock);
	bool refine = j->op != PROTO_FREEZE;
	if (refine) {
		sh->edit++;
		sh->next_level = 0;
		sh->edit_t0 = j->t0;
		atomic_fetch_add(&s->metrics.edits, 1);
	}
	struct srv_client *c = srv_client_find(s, j->client);
	if (c)
		c->edits += refine;
	sh->used = ++s->clock;
	uint32_t edit = sh->edit;
	pthread_mutex_unlock(&s->lock);
	reply_simple(s, j->client, "ack", j, edit);
	/* Kept for a reload after an eviction (under the lock: "stats" reads its size). */
	pthread_mutex_lock(&s->lock);
	bool kept = srv_editlog_add(&sh->log, j);
	pthread_mutex_unlock(&s->lock);
	if (!kept)
		rl_log(RL_LOG_ERROR, "shot '%s': out of memory: an edit will not survive an eviction",
		       sh->name);
}

/* ---- the loop ---- */

static void *worker_main(void *arg)
{
	struct srv *s = arg;
	char err[512];
	struct gpu_ctx *ctx = gpu_create(err, sizeof(err));
	pthread_mutex_lock(&s->lock);
	if (!ctx) {
		snprintf(s->gpu_err, sizeof(s->gpu_err), "%s", err);
		s->gpu_failed = true;
		pthread_cond_broadcast(&s->wake);
		pthread_mutex_unlock(&s->lock);
		return NULL;
	}
	s->gpu = ctx;
	s->worker_beat = srv_now();
	snprintf(s->gpu_renderer, sizeof(s->gpu_renderer), "%s", gpu_renderer(ctx));
	s->gpu_ready = true;
	pthread_cond_broadcast(&s->wake);

	struct images im = { 0 };
	struct srv_shot *cursor = NULL;
	while (!s->stop) {
		/* Jobs first, round robin over the shots: edits preempt refinement. */
		struct srv_shot *sh = NULL;
		for (int pass = 0; pass < 2 && !sh; pass++)
			for (struct srv_shot *x = pass ? s->shots : (cursor ? cursor->next : NULL); x;
			     x = x->next)
				if (x->jobs && !x->baking) {
					sh = x;
					break;
				}
		if (sh) {
			cursor = sh;
			struct srv_job *j = sh->jobs;
			sh->jobs = j->next;
			if (!sh->jobs)
				sh->jobs_tail = &sh->jobs;
			pthread_mutex_unlock(&s->lock);
			do_job(s, sh, j, &im);
			pthread_mutex_lock(&s->lock);
			s->worker_beat = srv_now();
			continue;
		}
		/* Then the next level of the shot whose edit is oldest. */
		bool need8 = false, need16 = false;
		for (struct srv_shot *x = s->shots; x; x = x->next) {
			bool n8, n16;
			if (!x->gpu || x->next_level >= GPU_SHOT_LEVELS || !formats(s, x, &n8, &n16))
				continue;
			if (!sh || x->used < sh->used) {
				sh = x;
				need8 = n8;
				need16 = n16;
			}
		}
		if (!sh) {
			pthread_cond_wait(&s->wake, &s->lock);
			s->worker_beat = srv_now();   /* idle until now: not stalled */
			continue;
		}
		int level = sh->next_level;
		uint32_t edit = sh->edit;
		double t0 = level == 0 ? sh->edit_t0 : 0;
		pthread_mutex_unlock(&s->lock);

		struct gpu_shot_stats st = { 0 };
		struct level_frames lf = { 0 };
		bool ok = gpu_shot_render(sh->gpu, level, &st) &&
			  read_level(sh->gpu, level, &im, need8, need16);
		if (ok)
			level_build(s, sh, &im, need8, need16, edit, level, st.ms, t0, &lf);
		/* maps a swapped slide loaded, or freed, change what the shot holds */
		size_t bytes = gpu_shot_bytes(sh->gpu);
		pthread_mutex_lock(&s->lock);
		atomic_fetch_add(&s->metrics.gpu_bytes, (int_fast64_t)bytes - (int_fast64_t)sh->bytes);
		sh->bytes = bytes;
		s->worker_beat = srv_now();
		if (!ok) {
			diag_log(sh, RL_LOG_ERROR);
			rl_log(RL_LOG_ERROR, "shot '%s': level %d failed", sh->name, level);
			sh->next_level = GPU_SHOT_LEVELS;
			continue;
		}
		atomic_fetch_add(&s->metrics.levels, 1);
		if (sh->jobs && level + 1 < GPU_SHOT_LEVELS)
			atomic_fetch_add(&s->metrics.preempted, 1);
		if (sh->edit == edit && sh->next_level == level) {
			level_post(s, sh, &lf, 0);
			sh->next_level = level + 1;
			if (level == 0)
				sh->edit_t0 = 0;
		}
		level_free(&lf);
	}
	pthread_mutex_unlock(&s->lock);

	for (struct srv_shot *sh = s->shots; sh; sh = sh->next)
		shot_evict(s, sh);
	free(im.px8);
	free(im.px16);
	gpu_destroy(ctx);
	s->gpu = NULL;
	return NULL;
}

bool srv_worker_healthy(struct srv *s, char *why, size_t whylen)
{
	pthread_mutex_lock(&s->lock);
	uint32_t waiting = 0;
	for (struct srv_shot *sh = s->shots; sh; sh = sh->next)
		for (struct srv_job *j = sh->baking ? NULL : sh->jobs; j; j = j->next)
			waiting++;
	double idle = srv_now() - s->worker_beat;
	bool ok = !s->worker_running || !waiting || idle < s->cfg.worker_stall;
	if (!ok)
		snprintf(why, whylen, "the render worker has finished nothing for %.0f s while %u "
			 "job%s wait (--worker-stall %u)", idle, waiting, waiting == 1 ? "" : "s",
			 s->cfg.worker_stall);
	pthread_mutex_unlock(&s->lock);
	return ok;
}

bool srv_worker_start(struct srv *s)
{
	/* What a snapshot killed mid-write left (the worker is the folder's one writer). */
	size_t stale = rl_remove_stale_temps(s->cfg.snapshot_dir, NULL);
	if (stale)
		rl_log(RL_LOG_INFO, "snapshots folder: removed %zu temporary file%s of interrupted "
		       "writes", stale, stale == 1 ? "" : "s");
	pthread_mutex_lock(&s->lock);
	if (pthread_create(&s->worker, NULL, worker_main, s)) {
		snprintf(s->gpu_err, sizeof(s->gpu_err), "cannot start the render thread");
		pthread_mutex_unlock(&s->lock);
		return false;
	}
	s->worker_running = true;
	while (!s->gpu_ready && !s->gpu_failed)
		pthread_cond_wait(&s->wake, &s->lock);
	bool ok = s->gpu_ready;
	pthread_mutex_unlock(&s->lock);
	if (!ok) {
		pthread_join(s->worker, NULL);
		s->worker_running = false;
	}
	return ok;
}

void srv_worker_stop(struct srv *s)
{
	if (s->worker_running) {
		pthread_mutex_lock(&s->lock);
		s->stop = true;
		pthread_cond_broadcast(&s->wake);
		pthread_mutex_unlock(&s->lock);
		pthread_join(s->worker, NULL);
		s->worker_running = false;
	}
	while (s->shots) {
		struct srv_shot *sh = s->shots;
		s->shots = sh->next;
		while (sh->jobs) {
			struct srv_job *j = sh->jobs;
			sh->jobs = j->next;
			srv_job_free(j);
		}
		srv_editlog_finish(&sh->log);
		if (sh->diag)
			fclose(sh->diag);
		free(sh->diag_buf);
		free(sh);
	}
}

/*
 * The shot registry: what the --shots folder holds, resolved name by name
 * (a shot file, a RIB scene, or both), with each shot file's header read
 * once per version of the file, and RIB scenes baked on demand, once per
 * name however many clients ask at the same time.
 *
 * One mutex guards everything (the header cache, the bakes in flight, the
 * counters); directory scans and header reads happen under it, bakes do
 * not. A bake in flight is a slot that later callers for the same name wait
 * on (a condition variable), following its progress, and whose result they
 * share.
 */
/* realpath() is an X/Open part of POSIX 2008. */
#define _XOPEN_SOURCE 700

#include "shots.h"

#include "bake.h"
#include "fileutil.h"
#include "log.h"
#include "shotfile.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

/* Room for a shot name and the longest suffix (".shot.exr"). */
#define FILE_NAME_MAX (SRV_SHOT_NAME_MAX + 16)
/* How much of a failed bake's diagnostics is kept. */
#define BAKE_ERR_MAX 1024

/* A file's verdict: a shot file of that size, or not a shot file. */
struct header_cache {
	char *file;               /* file name in the folder */
	struct timespec mtime;
	off_t size;
	ino_t ino;
	bool is_shot;
	uint32_t width, height;
	bool seen;                /* by the scan in progress */
};

/* A bake in flight (or just ended, while waiters collect its result). */
struct bake_slot {
	struct bake_slot *next;
	char name[SRV_SHOT_NAME_MAX + 1];
	bool done, ok;
	double fraction;          /* the latest progress, -1 before any */
	char what[32];
	char err[BAKE_ERR_MAX];
	unsigned waiters;         /* callers waiting for it besides the one baking */
};

struct srv_shots {
	char *dir;                /* the folder, absolute, links resolved */
	char *prefix;             /* dir with a trailing '/' */
	pthread_mutex_t lock;
	pthread_cond_t changed;   /* a bake progressed or ended */
	struct header_cache *cache;
	size_t ncache, cache_cap;
	struct bake_slot *bakes;
	uint64_t tmp_serial;
	uint64_t bakes_run;
};

bool srv_shot_name_ok(const char *name)
{
	if (!name || !name[0] || name[0] == '.')
		return false;
	size_t n = 0;
	for (const char *p = name; *p; p++, n++) {
		char c = *p;
		bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
			  c == '_' || c == '-' || c == '.';
		if (!ok || n >= SRV_SHOT_NAME_MAX)
			return false;
	}
	return true;
}

static bool ends_with(const char *s, size_t n, const char *suffix)
{
	size_t k = strlen(suffix);
	return n > k && !memcmp(s + n - k, suffix, k);
}

/* "@dir/@file" into @out; false when it does not fit. */
static bool join(const struct srv_shots *r, const char *file, char *out, size_t cap)
{
	int n = snprintf(out, cap, "%s%s", r->prefix, file);
	return n >= 0 && (size_t)n < cap;
}

enum where {
	FILE_NONE,                /* no such regular file */
	FILE_HERE,                /* a regular file in the folder (or a link to one in it) */
	FILE_OUTSIDE,             /* a link to somewhere outside the folder: refused */
};

/*
 * Is @file a regular file of the folder? Names hold no '/', so only the
 * last component can lead elsewhere: a symbolic link, followed here and
 * kept only if it ends inside the folder.
 */
static enum where locate(const struct srv_shots *r, const char *file, struct stat *st)
{
	char path[PATH_MAX];
	if (!join(r, file, path, sizeof(path)) || lstat(path, st) != 0)
		return FILE_NONE;
	if (S_ISLNK(st->st_mode)) {
		char *real = realpath(path, NULL);
		if (!real)
			return FILE_NONE;
		bool inside = !strncmp(real, r->prefix, strlen(r->prefix));
		free(real);
		if (!inside)
			return FILE_OUTSIDE;
		if (stat(path, st) != 0)
			return FILE_NONE;
	}
	return S_ISREG(st->st_mode) ? FILE_HERE : FILE_NONE;
}

/* A new entry for @file (its verdict to be filled in), or NULL. Lock held. */
static struct header_cache *cache_add(struct srv_shots *r, const char *file)
{
	if (r->ncache == r->cache_cap) {
		size_t cap = r->cache_cap ? r->cache_cap * 2 : 16;
		struct header_cache *grown = realloc(r->cache, cap * sizeof(*grown));
		if (!grown)
			return NULL;
		r->cache = grown;
		r->cache_cap = cap;
	}
	char *name = strdup(file);
	if (!name)
		return NULL;
	struct header_cache *c = &r->cache[r->ncache++];
	*c = (struct header_cache){ .file = name };
	return c;
}

static bool same_version(const struct header_cache *c, const struct stat *st)
{
	return c->mtime.tv_sec == st->st_mtim.tv_sec && c->mtime.tv_nsec == st->st_mtim.tv_nsec &&
	       c->size == st->st_size && c->ino == st->st_ino;
}

/*
 * Is @file (just located, @st) a shot file, and of what size? The header
 * is read once per version (modification time, size, inode) of the file;
 * files that are no shot files (rendered images, junk) are remembered too.
 * Lock held.
 */
static bool header_of(struct srv_shots *r, const char *file, const struct stat *st,
		      uint32_t *width, uint32_t *height)
{
	struct header_cache *c = NULL;
	for (size_t i = 0; i < r->ncache; i++)
		if (!strcmp(r->cache[i].file, file)) {
			c = &r->cache[i];
			break;
		}
	if (!c || !same_version(c, st)) {
		char path[PATH_MAX], err[256];
		bool is_shot = false;
		uint32_t w = 0, h = 0;
		if (join(r, file, path, sizeof(path))) {
			struct shot_file *f = shot_read_header(path, err, sizeof(err));
			const struct shot_deep *ifb = f ? shot_find_deep(f, "ifb") : NULL;
			if (ifb && ifb->width && ifb->height) {
				is_shot = true;
				w = ifb->width;
				h = ifb->height;
			}
			shot_free(f);
		}
		if (!c)
			c = cache_add(r, file);
		if (!c) {
			/* out of memory: the verdict holds, it is just not kept */
			*width = w;
			*height = h;
			return is_shot;
		}
		c->mtime = st->st_mtim;
		c->size = st->st_size;
		c->ino = st->st_ino;
		c->is_shot = is_shot;
		c->width = w;
		c->height = h;
	}
	c->seen = true;
	*width = c->width;
	*height = c->height;
	return c->is_shot;
}

/* What the folder holds under a name. */
struct resolved {
	bool shot;                /* a shot file, read as one */
	char file[FILE_NAME_MAX]; /* its file name */
	struct timespec shot_mtime;
	uint32_t width, height;
	bool rib;                 /* NAME.rib */
	bool rib_outside;         /* NAME.rib is a link out of the folder */
	struct timespec rib_mtime;
};

static bool older(struct timespec a, struct timespec b)
{
	return a.tv_sec < b.tv_sec || (a.tv_sec == b.tv_sec && a.tv_nsec < b.tv_nsec);
}

/* Look @name up (valid). Lock held. */
static void resolve(struct srv_shots *r, const char *name, struct resolved *out)
{
	memset(out, 0, sizeof(*out));
	struct stat st;
	char file[FILE_NAME_MAX];
	size_t n = strlen(name);
	/* NAME.shot.exr, then NAME.exr (unless that is NAME.shot.exr's other name) */
	for (int k = 0; k < 2 && !out->shot; k++) {
		if (k == 1 && ends_with(name, n, ".shot"))
			break;
		snprintf(file, sizeof(file), "%s%s", name, k ? ".exr" : ".shot.exr");
		if (locate(r, file, &st) == FILE_HERE &&
		    header_of(r, file, &st, &out->width, &out->height)) {
			out->shot = true;
			out->shot_mtime = st.st_mtim;
			memcpy(out->file, file, sizeof(file));
		}
	}
	snprintf(file, sizeof(file), "%s.rib", name);
	enum where w = locate(r, file, &st);
	out->rib = w == FILE_HERE;
	out->rib_outside = w == FILE_OUTSIDE;
	if (out->rib)
		out->rib_mtime = st.st_mtim;
}

static enum srv_shot_state state_of(const struct resolved *s)
{
	if (s->rib && (!s->shot || older(s->shot_mtime, s->rib_mtime)))
		return SRV_SHOT_NEEDS_BAKE;
	return s->shot ? SRV_SHOT_READY : SRV_SHOT_MISSING;
}

struct srv_shots *srv_shots_open(const char *dir, char *err, size_t errlen)
{
	if (!dir || !*dir) {
		snprintf(err, errlen, "no shots folder given");
		return NULL;
	}
	struct srv_shots *r = calloc(1, sizeof(*r));
	if (!r) {
		snprintf(err, errlen, "out of memory");
		return NULL;
	}
	struct stat st;
	DIR *d = NULL;
	r->dir = realpath(dir, NULL);
	if (!r->dir || stat(r->dir, &st) != 0) {
		snprintf(err, errlen, "%s: %s", dir, strerror(errno));
		goto fail_dir;
	}
	if (!S_ISDIR(st.st_mode)) {
		snprintf(err, errlen, "%s: not a folder", dir);
		goto fail_dir;
	}
	d = opendir(r->dir);
	if (!d) {
		snprintf(err, errlen, "%s: %s", dir, strerror(errno));
		goto fail_dir;
	}
	closedir(d);
	size_t n = strlen(r->dir);
	r->prefix = malloc(n + 2);
	if (!r->prefix) {
		snprintf(err, errlen, "out of memory");
		goto fail_dir;
	}
	/* "/" as the folder is its own prefix */
	snprintf(r->prefix, n + 2, "%s%s", r->dir, n && r->dir[n - 1] == '/' ? "" : "/");
	if (pthread_mutex_init(&r->lock, NULL) != 0) {
		snprintf(err, errlen, "cannot create a mutex");
		goto fail_prefix;
	}
	if (pthread_cond_init(&r->changed, NULL) != 0) {
		snprintf(err, errlen, "cannot create a condition variable");
		goto fail_mutex;
	}
	/* What a writer killed mid-write left here (bakes, by this daemon or `relight bake`). */
	size_t stale = rl_remove_stale_temps(r->dir, NULL);
	if (stale)
		rl_log(RL_LOG_INFO, "shots folder: removed %zu temporary file%s of interrupted writes",
		       stale, stale == 1 ? "" : "s");
	return r;

fail_mutex:
	pthread_mutex_destroy(&r->lock);
fail_prefix:
	free(r->prefix);
fail_dir:
	free(r->dir);
	free(r);
	return NULL;
}

void srv_shots_close(struct srv_shots *r)
{
	if (!r)
		return;
	for (size_t i = 0; i < r->ncache; i++)
		free(r->cache[i].file);
	free(r->cache);
	pthread_cond_destroy(&r->changed);
	pthread_mutex_destroy(&r->lock);
	free(r->prefix);
	free(r->dir);
	free(r);
}

/* The shot name a folder entry stands for, or false if none. */
static bool name_of_file(const char *file, char name[SRV_SHOT_NAME_MAX + 1])
{
	static const char *const suffixes[] = { ".shot.exr", ".exr", ".rib" };
	size_t n = strlen(file);
	for (size_t k = 0; k < sizeof(suffixes) / sizeof(suffixes[0]); k++) {
		if (!ends_with(file, n, suffixes[k]))
			continue;
		size_t base = n - strlen(suffixes[k]);
		if (base > SRV_SHOT_NAME_MAX)
			return false;
		memcpy(name, file, base);
		name[base] = '\0';
		return srv_shot_name_ok(name);
	}
	return false;
}

static int cmp_entry(const void *a, const void *b)
{
	return strcmp(((const struct srv_shot_entry *)a)->name,
		      ((const struct srv_shot_entry *)b)->name);
}

size_t srv_shots_list(struct srv_shots *r, struct srv_shot_entry *out, size_t cap)
{
	if (!r)
		return 0;
	pthread_mutex_lock(&r->lock);
	struct srv_shot_entry *names = NULL;
	size_t nnames = 0, names_cap = 0, count = 0;
	DIR *d = opendir(r->dir);
	if (!d)
		goto out;
	for (size_t i = 0; i < r->ncache; i++)
		r->cache[i].seen = false;
	for (struct dirent *e; (e = readdir(d));) {
		char name[SRV_SHOT_NAME_MAX + 1];
		if (!name_of_file(e->d_name, name))
			continue;
		if (nnames == names_cap) {
			size_t ncap = names_cap ? names_cap * 2 : 32;
			struct srv_shot_entry *grown = realloc(names, ncap * sizeof(*grown));
			if (!grown)
				break;
			names = grown;
			names_cap = ncap;
		}
		memcpy(names[nnames++].name, name, sizeof(name));
	}
	closedir(d);
	if (nnames)
		qsort(names, nnames, sizeof(*names), cmp_entry);
	for (size_t i = 0; i < nnames; i++) {
		/* a name can come from several files: its shot file, its RIB */
		if (i && !strcmp(names[i].name, names[i - 1].name))
			continue;
		struct resolved s;
		resolve(r, names[i].name, &s);
		enum srv_shot_state state = state_of(&s);
		if (state == SRV_SHOT_MISSING)
			continue;
		if (count < cap) {
			struct srv_shot_entry *o = &out[count];
			memcpy(o->name, names[i].name, sizeof(o->name));
			o->baked = state == SRV_SHOT_READY;
			o->has_rib = s.rib;
			o->width = o->baked ? s.width : 0;
			o->height = o->baked ? s.height : 0;
		}
		count++;
	}
	/* Forget the verdicts on files that are gone. */
	size_t kept = 0;
	for (size_t i = 0; i < r->ncache; i++) {
		if (r->cache[i].seen)
			r->cache[kept++] = r->cache[i];
		else
			free(r->cache[i].file);
	}
	r->ncache = kept;
out:
	pthread_mutex_unlock(&r->lock);
	free(names);
	return count;
}

enum srv_shot_state srv_shots_find(struct srv_shots *r, const char *name, char *path,
				   size_t cap)
{
	if (!r || !srv_shot_name_ok(name))
		return SRV_SHOT_INVALID;
	struct resolved s;
	pthread_mutex_lock(&r->lock);
	resolve(r, name, &s);
	pthread_mutex_unlock(&r->lock);
	enum srv_shot_state state = state_of(&s);
	if (state == SRV_SHOT_READY && path && cap && !join(r, s.file, path, cap))
		return SRV_SHOT_MISSING;  /* a path that does not fit cannot be opened */
	return state;
}

uint64_t srv_shots_bakes_run(struct srv_shots *r)
{
	if (!r)
		return 0;
	pthread_mutex_lock(&r->lock);
	uint64_t n = r->bakes_run;
	pthread_mutex_unlock(&r->lock);
	return n;
}

/* ---- baking ---- */

struct bake_call {
	struct srv_shots *r;
	struct bake_slot *slot;
	srv_bake_progress_fn progress;
	void *user;
};

/* The bake's progress: published for the waiters, then the caller's own. */
static void owner_progress(void *user, double fraction, const char *what)
{
	struct bake_call *c = user;
	pthread_mutex_lock(&c->r->lock);
	c->slot->fraction = fraction;
	snprintf(c->slot->what, sizeof(c->slot->what), "%s", what ? what : "");
	pthread_cond_broadcast(&c->r->changed);
	pthread_mutex_unlock(&c->r->lock);
	if (c->progress)
		c->progress(c->user, fraction, what);
}

/*
 * The reason a bake failed, from its diagnostics @text: the lines that are
 * errors (all of it if none says so), with the folder's path left out of
 * file names so that a client sees "scene.rib:12: error: ...".
 */
static void bake_reason(const struct srv_shots *r, const char *text, char *err, size_t errlen)
{
	static const char mark[] = ": error";
	size_t mlen = sizeof(mark) - 1;
	bool any_error = text && strstr(text, mark);
	size_t plen = strlen(r->prefix), o = 0;
	err[0] = '\0';
	for (const char *line = text; line && *line && o + 1 < errlen;) {
		const char *end = strchr(line, '\n');
		size_t n = end ? (size_t)(end - line) : strlen(line);
		bool keep = !any_error;
		for (size_t i = 0; !keep && i + mlen <= n; i++)
			keep = !memcmp(line + i, mark, mlen);
		for (size_t i = 0; keep && i < n && o + 1 < errlen;) {
			if (n - i >= plen && !memcmp(line + i, r->prefix, plen)) {
				i += plen;
				continue;
			}
			err[o++] = line[i++];
		}
		if (keep && o + 1 < errlen)
			err[o++] = '\n';
		line = end ? end + 1 : line + n;
	}
	while (o && err[o - 1] == '\n')
		o--;
	err[o] = '\0';
	if (!o)
		snprintf(err, errlen, "the bake failed");
}

/* Bake @name's RIB into a temporary file and rename it into place. */
static bool bake_now(struct bake_call *c, const char *name, uint64_t serial, char *err,
		     size_t errlen)
{
	struct srv_shots *r = c->r;
	char rib[PATH_MAX], final[PATH_MAX], tmp[PATH_MAX + 64], file[FILE_NAME_MAX];
	snprintf(file, sizeof(file), "%s.rib", name);
	bool fits = join(r, file, rib, sizeof(rib));
	snprintf(file, sizeof(file), "%s.shot.exr", name);
	fits = fits && join(r, file, final, sizeof(final));
	int n = snprintf(tmp, sizeof(tmp), "%s.tmp.%ld.%llu", final, (long)getpid(),
			 (unsigned long long)serial);
	if (!fits || n < 0 || (size_t)n >= sizeof(tmp)) {
		snprintf(err, errlen, "%s: the path is too long", name);
		return false;
	}
	char *text = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&text, &len);
	if (!diag) {
		snprintf(err, errlen, "%s: cannot capture the bake's messages: out of memory", name);
		return false;
	}
	struct bake_opts bo = {
		.diag = diag, .progress_fn = owner_progress, .progress_user = c,
	};
	bool ok = bake_rib_file(rib, tmp, &bo, false, NULL);
	fclose(diag);
	if (!ok) {
		bake_reason(r, text, err, errlen);
	} else if (rename(tmp, final) != 0) {
		char why[128];
		if (strerror_r(errno, why, sizeof(why)) != 0)
			snprintf(why, sizeof(why), "error %d", errno);
		snprintf(err, errlen, "%s: cannot put the shot file in place: %s", file, why);
		ok = false;
	}
	if (!ok)
		unlink(tmp);
	free(text);
	return ok;
}

/* Wait for another caller's bake of the same name to end. Lock held. */
static bool wait_for(struct srv_shots *r, struct bake_slot *slot, srv_bake_progress_fn progress,
		     void *user, char *err, size_t errlen)
{
	slot->waiters++;
	double seen = -1.0;
	while (!slot->done) {
		if (progress && slot->fraction > seen) {
			char what[sizeof(slot->what)];
			seen = slot->fraction;
			memcpy(what, slot->what, sizeof(what));
			pthread_mutex_unlock(&r->lock);
			progress(user, seen, what);
			pthread_mutex_lock(&r->lock);
			continue;
		}
		pthread_cond_wait(&r->changed, &r->lock);
	}
	bool ok = slot->ok;
	if (!ok)
		snprintf(err, errlen, "%s", slot->err);
	/* the baker has unlinked the slot; the last one out frees it */
	if (--slot->waiters == 0)
		free(slot);
	if (ok && progress && seen < 1.0) {
		pthread_mutex_unlock(&r->lock);
		progress(user, 1.0, "done");
		pthread_mutex_lock(&r->lock);
	}
	return ok;
}

/* @file's path into @path (may be NULL); false with the reason if it does not fit. */
static bool put_path(const struct srv_shots *r, const char *file, char *path, size_t cap,
		     char *err, size_t errlen)
{
	if (path && cap && !join(r, file, path, cap)) {
		snprintf(err, errlen, "%s: the path does not fit", file);
		return false;
	}
	return true;
}

/* Where a bake puts shot @name. */
static bool shot_path(const struct srv_shots *r, const char *name, char *path, size_t cap,
		      char *err, size_t errlen)
{
	char file[FILE_NAME_MAX];
	snprintf(file, sizeof(file), "%s.shot.exr", name);
	return put_path(r, file, path, cap, err, errlen);
}

bool srv_shots_bake(struct srv_shots *r, const char *name, srv_bake_progress_fn progress,
		    void *user, char *path, size_t cap, char *err, size_t errlen)
{
	char dummy[1];
	if (!err || !errlen) {
		err = dummy;
		errlen = sizeof(dummy);
	}
	err[0] = '\0';
	if (!r || !srv_shot_name_ok(name)) {
		snprintf(err, errlen, "'%.*s' is not a valid shot name", SRV_SHOT_NAME_MAX,
			 name ? name : "");
		return false;
	}
	pthread_mutex_lock(&r->lock);
	for (struct bake_slot *s = r->bakes; s; s = s->next)
		if (!strcmp(s->name, name)) {
			bool ok = wait_for(r, s, progress, user, err, errlen);
			pthread_mutex_unlock(&r->lock);
			return ok && shot_path(r, name, path, cap, err, errlen);
		}

	/* Decided under the lock: a bake that just ended is not run again. */
	struct resolved s;
	resolve(r, name, &s);
	enum srv_shot_state state = state_of(&s);
	if (state != SRV_SHOT_NEEDS_BAKE) {
		pthread_mutex_unlock(&r->lock);
		if (state == SRV_SHOT_READY) {
			if (!put_path(r, s.file, path, cap, err, errlen))
				return false;
			if (progress)
				progress(user, 1.0, "up to date");
			return true;
		}
		if (s.rib_outside)
			snprintf(err, errlen, "%s.rib: a link out of the shots folder, refused", name);
		else
			snprintf(err, errlen, "no scene '%s.rib' in the shots folder", name);
		return false;
	}
	struct bake_slot *slot = calloc(1, sizeof(*slot));
	if (!slot) {
		pthread_mutex_unlock(&r->lock);
		snprintf(err, errlen, "out of memory");
		return false;
	}
	snprintf(slot->name, sizeof(slot->name), "%s", name);
	slot->fraction = -1.0;
	slot->next = r->bakes;
	r->bakes = slot;
	uint64_t serial = ++r->tmp_serial;
	r->bakes_run++;
	pthread_mutex_unlock(&r->lock);

	struct bake_call call = { .r = r, .slot = slot, .progress = progress, .user = user };
	bool ok = bake_now(&call, name, serial, slot->err, sizeof(slot->err));
	if (!ok)
		snprintf(err, errlen, "%s", slot->err);

	pthread_mutex_lock(&r->lock);
	for (struct bake_slot **p = &r->bakes; *p; p = &(*p)->next)
		if (*p == slot) {
			*p = slot->next;
			break;
		}
	slot->ok = ok;
	slot->done = true;
	pthread_cond_broadcast(&r->changed);
	if (slot->waiters == 0)
		free(slot);
	pthread_mutex_unlock(&r->lock);
	return ok && shot_path(r, name, path, cap, err, errlen);
}

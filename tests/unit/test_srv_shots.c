/*
 * The shot registry of relightd (daemon/server/shots.h): name confinement,
 * listing a folder of RIB scenes and shot files, baking on demand (progress,
 * errors with the RIB's line, no temporary file left behind), one bake for
 * concurrent requests of a name, links out of the folder refused, foreign
 * .exr files skipped, and a RIB edited after its bake baked again.
 */
#include "shots.h"
#include "test.h"
#include "texture.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <stdint.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static char dir[256], outside[256];

static const char *in(const char *base, const char *name)
{
	static char buf[4][600];
	static int k;
	k = (k + 1) % 4;
	snprintf(buf[k], sizeof(buf[k]), "%s/%s", base, name);
	return buf[k];
}

static bool write_text(const char *path, const char *text)
{
	FILE *f = fopen(path, "w");
	if (!f)
		return false;
	bool ok = fputs(text, f) >= 0;
	return fclose(f) == 0 && ok;
}

static bool exists(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0;
}

/* Files of @base whose name contains "tmp" (a bake's leftovers). */
static int count_tmp(const char *base)
{
	DIR *d = opendir(base);
	int n = 0;
	if (!d)
		return -1;
	for (struct dirent *e; (e = readdir(d));)
		n += strstr(e->d_name, "tmp") != NULL;
	closedir(d);
	return n;
}

/* A sphere lit by a distant light and a point light, with the standard shaders. */
static const char scene_rib[] =
	"Format 24 18 1\n"
	"PixelSamples 2 2\n"
	"Display \"scene.exr\" \"file\" \"rgba\"\n"
	"WorldBegin\n"
	"  LightSource \"distantlight\" 1 \"from\" [0 1 -1] \"to\" [0 0 0]\n"
	"  LightSource \"pointlight\" 2 \"from\" [1 2 2] \"intensity\" 6\n"
	"  AttributeBegin\n"
	"    Surface \"plastic\" \"Kd\" 0.7\n"
	"    Translate 0 0 5\n"
	"    Sphere 1.5 -1.5 1.5 360\n"
	"  AttributeEnd\n"
	"WorldEnd\n";

/* ------------------------------------------------------------------------- */

static void test_names(void)
{
	CHECK(srv_shot_name_ok("scene"));
	CHECK(srv_shot_name_ok("Scene_2-final.v3"));
	CHECK(srv_shot_name_ok("a"));
	CHECK(srv_shot_name_ok("a..b"));
	CHECK(!srv_shot_name_ok(NULL));
	CHECK(!srv_shot_name_ok(""));
	CHECK(!srv_shot_name_ok("../x"));
	CHECK(!srv_shot_name_ok(".."));
	CHECK(!srv_shot_name_ok("a/b"));
	CHECK(!srv_shot_name_ok("/etc/passwd"));
	CHECK(!srv_shot_name_ok(".hidden"));
	CHECK(!srv_shot_name_ok("a b"));
	CHECK(!srv_shot_name_ok("a\\b"));
	CHECK(!srv_shot_name_ok("caf\xc3\xa9"));
	CHECK(!srv_shot_name_ok("a:b"));
	CHECK(!srv_shot_name_ok("a*"));
	CHECK(!srv_shot_name_ok("x\n"));
	CHECK(!srv_shot_name_ok("~root"));
	char name[SRV_SHOT_NAME_MAX + 2];
	memset(name, 'n', sizeof(name));
	name[SRV_SHOT_NAME_MAX] = '\0';
	CHECK(srv_shot_name_ok(name));           /* 128 bytes */
	name[SRV_SHOT_NAME_MAX] = 'n';
	name[SRV_SHOT_NAME_MAX + 1] = '\0';
	CHECK(!srv_shot_name_ok(name));          /* 129 bytes */

	char err[256] = "";
	CHECK(srv_shots_open(in(dir, "none"), err, sizeof(err)) == NULL);
	CHECK(strstr(err, "none") != NULL);
	CHECK(write_text(in(dir, "plain"), "x"));
	err[0] = '\0';
	CHECK(srv_shots_open(in(dir, "plain"), err, sizeof(err)) == NULL);
	CHECK(strstr(err, "not a folder") != NULL);
	unlink(in(dir, "plain"));

	/* bad names never reach the file system */
	struct srv_shots *r = srv_shots_open(dir, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	char path[PATH_MAX];
	CHECK(srv_shots_find(r, "../x", path, sizeof(path)) == SRV_SHOT_INVALID);
	CHECK(srv_shots_find(r, "/etc/passwd", path, sizeof(path)) == SRV_SHOT_INVALID);
	CHECK(srv_shots_find(r, "", path, sizeof(path)) == SRV_SHOT_INVALID);
	CHECK(srv_shots_find(r, "nothing", path, sizeof(path)) == SRV_SHOT_MISSING);
	err[0] = '\0';
	CHECK(!srv_shots_bake(r, "../etc/x", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "not a valid shot name") != NULL);
	err[0] = '\0';
	CHECK(!srv_shots_bake(r, "nothing", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "nothing.rib") != NULL);
	CHECK(srv_shots_bakes_run(r) == 0);
	srv_shots_close(r);
}

/* ------------------------------------------------------------------------- */

struct progress_log {
	int calls;
	double first, last;
	bool monotone, in_range;
};

static void log_progress(void *user, double fraction, const char *what)
{
	struct progress_log *p = user;
	if (!p->calls)
		p->first = fraction;
	else if (fraction < p->last)
		p->monotone = false;
	if (!(fraction >= 0.0 && fraction <= 1.0) || !what)
		p->in_range = false;
	p->last = fraction;
	p->calls++;
}

static struct srv_shot_entry *entry(struct srv_shot_entry *e, size_t n, const char *name)
{
	for (size_t i = 0; i < n; i++)
		if (!strcmp(e[i].name, name))
			return &e[i];
	return NULL;
}

static void test_bake(void)
{
	char err[1024] = "", path[PATH_MAX] = "";
	CHECK(write_text(in(dir, "scene.rib"), scene_rib));
	struct srv_shots *r = srv_shots_open(dir, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;

	struct srv_shot_entry e[8];
	memset(e, 0xff, sizeof(e));
	CHECK(srv_shots_list(r, e, 8) == 1);
	CHECK_STR(e[0].name, "scene");
	CHECK(e[0].has_rib && !e[0].baked);
	CHECK(e[0].width == 0 && e[0].height == 0);
	CHECK(srv_shots_find(r, "scene", path, sizeof(path)) == SRV_SHOT_NEEDS_BAKE);

	struct progress_log p = { .monotone = true, .in_range = true };
	CHECK(srv_shots_bake(r, "scene", log_progress, &p, path, sizeof(path), err, sizeof(err)));
	CHECK_STR(path, in(dir, "scene.shot.exr"));
	CHECK(exists(in(dir, "scene.shot.exr")));
	CHECK(count_tmp(dir) == 0);
	CHECK(p.calls >= 3);
	CHECK(p.first == 0.0);
	CHECK(p.last == 1.0);
	CHECK(p.monotone && p.in_range);
	CHECK(srv_shots_bakes_run(r) == 1);

	CHECK(srv_shots_list(r, e, 8) == 1);
	CHECK(e[0].has_rib && e[0].baked);
	CHECK(e[0].width == 24 && e[0].height == 18);
	path[0] = '\0';
	CHECK(srv_shots_find(r, "scene", path, sizeof(path)) == SRV_SHOT_READY);
	CHECK_STR(path, in(dir, "scene.shot.exr"));

	/* up to date: asking again bakes nothing */
	struct progress_log q = { .monotone = true, .in_range = true };
	CHECK(srv_shots_bake(r, "scene", log_progress, &q, path, sizeof(path), err, sizeof(err)));
	CHECK(srv_shots_bakes_run(r) == 1);
	CHECK(q.calls >= 1 && q.last == 1.0);

	/* a RIB edited after its bake (the shot now older than it) is baked again */
	struct stat st;
	CHECK(stat(in(dir, "scene.rib"), &st) == 0);
	struct timespec times[2] = { st.st_atim, st.st_mtim };
	times[0].tv_sec -= 10;
	times[1].tv_sec -= 10;
	CHECK(utimensat(AT_FDCWD, in(dir, "scene.shot.exr"), times, 0) == 0);
	CHECK(srv_shots_find(r, "scene", path, sizeof(path)) == SRV_SHOT_NEEDS_BAKE);
	CHECK(srv_shots_list(r, e, 8) == 1);
	CHECK(!e[0].baked && e[0].has_rib && e[0].width == 0);
	CHECK(srv_shots_bake(r, "scene", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(srv_shots_bakes_run(r) == 2);
	CHECK(srv_shots_find(r, "scene", path, sizeof(path)) == SRV_SHOT_READY);

	/* a shot file without its RIB is a shot too (and needs no bake) */
	CHECK(rename(in(dir, "scene.rib"), in(dir, "scene.rib.off")) == 0);
	CHECK(srv_shots_list(r, e, 8) == 1);
	CHECK(e[0].baked && !e[0].has_rib && e[0].width == 24);
	CHECK(srv_shots_find(r, "scene", path, sizeof(path)) == SRV_SHOT_READY);
	CHECK(rename(in(dir, "scene.rib.off"), in(dir, "scene.rib")) == 0);
	srv_shots_close(r);
}

/* ------------------------------------------------------------------------- */

static void test_errors(void)
{
	char err[1024] = "", path[PATH_MAX] = "";
	/* line 3: a transformation short of arguments, which holds the frame back */
	CHECK(write_text(in(dir, "bad.rib"), "Format 8 8 1\nWorldBegin\nTranslate 1 2\nWorldEnd\n"));
	/* line 3: a sphere short of arguments, which drops that sphere alone */
	CHECK(write_text(in(dir, "dropped.rib"), "Format 8 8 1\nWorldBegin\nSphere 1 -1\n"
			 "Sphere 1 -1 1 360\nWorldEnd\n"));
	/* no frame besides a shadow pass */
	CHECK(write_text(in(dir, "empty.rib"), "Format 8 8 1\n"));
	struct srv_shots *r = srv_shots_open(dir, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	CHECK(srv_shots_find(r, "bad", path, sizeof(path)) == SRV_SHOT_NEEDS_BAKE);
	struct progress_log p = { .monotone = true, .in_range = true };
	CHECK(!srv_shots_bake(r, "bad", log_progress, &p, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "bad.rib:3") != NULL);
	CHECK(strstr(err, "error") != NULL);
	/* the folder's own path stays out of what a client sees */
	CHECK(strstr(err, dir) == NULL);
	CHECK(p.monotone && p.in_range && p.last < 1.0);
	CHECK(!exists(in(dir, "bad.shot.exr")));
	CHECK(count_tmp(dir) == 0);
	CHECK(srv_shots_find(r, "bad", path, sizeof(path)) == SRV_SHOT_NEEDS_BAKE);

	/* A scene that lost a primitive to an error is not served as its shot: the
	   error goes back with its line. */
	err[0] = '\0';
	CHECK(!srv_shots_bake(r, "dropped", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "dropped.rib:3") != NULL);
	CHECK(!exists(in(dir, "dropped.shot.exr")));
	CHECK(count_tmp(dir) == 0);

	err[0] = '\0';
	CHECK(!srv_shots_bake(r, "empty", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "empty.rib") != NULL && strstr(err, "no frame to bake") != NULL);
	CHECK(count_tmp(dir) == 0);

	/* an error message is cut to the room given, never overflowing */
	char small[12];
	memset(small, 'x', sizeof(small));
	CHECK(!srv_shots_bake(r, "bad", NULL, NULL, path, sizeof(path), small, sizeof(small)));
	CHECK(memchr(small, '\0', sizeof(small)) != NULL);
	CHECK(srv_shots_bakes_run(r) == 4);
	unlink(in(dir, "bad.rib"));
	unlink(in(dir, "dropped.rib"));
	unlink(in(dir, "empty.rib"));
	srv_shots_close(r);
}

/* ------------------------------------------------------------------------- */

/* Two callers of the same name meet: each one's first progress report
 * waits (a while at most) until the other has had one. The baker's first
 * report comes before any rendering, so the other caller can only have one
 * by waiting for that bake. */
struct meeting {
	pthread_mutex_t lock;
	pthread_cond_t cond;
	int calls[2];
};

struct twin {
	struct meeting *m;
	struct srv_shots *r;
	const char *name;
	int me;
	bool ok;
	char path[PATH_MAX], err[512];
	struct progress_log log;
	bool met;
};

static void twin_progress(void *user, double fraction, const char *what)
{
	struct twin *t = user;
	log_progress(&t->log, fraction, what);
	struct meeting *m = t->m;
	if (!m)
		return;
	pthread_mutex_lock(&m->lock);
	m->calls[t->me]++;
	pthread_cond_broadcast(&m->cond);
	struct timespec until;
	clock_gettime(CLOCK_REALTIME, &until);
	until.tv_sec += 30;
	while (!m->calls[1 - t->me])
		if (pthread_cond_timedwait(&m->cond, &m->lock, &until) == ETIMEDOUT)
			break;
	if (m->calls[1 - t->me])
		t->met = true;
	pthread_mutex_unlock(&m->lock);
}

static void *twin_main(void *arg)
{
	struct twin *t = arg;
	t->ok = srv_shots_bake(t->r, t->name, twin_progress, t, t->path, sizeof(t->path), t->err,
			       sizeof(t->err));
	return NULL;
}

static void test_concurrent(void)
{
	char err[256] = "";
	CHECK(write_text(in(dir, "twin.rib"), scene_rib));
	CHECK(write_text(in(dir, "other.rib"), scene_rib));
	struct srv_shots *r = srv_shots_open(dir, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	uint64_t before = srv_shots_bakes_run(r);

	struct meeting m = { .lock = PTHREAD_MUTEX_INITIALIZER, .cond = PTHREAD_COND_INITIALIZER };
	struct twin t[2];
	pthread_t th[2];
	for (int i = 0; i < 2; i++) {
		t[i] = (struct twin){ .m = &m, .r = r, .name = "twin", .me = i };
		t[i].log = (struct progress_log){ .monotone = true, .in_range = true };
		CHECK(pthread_create(&th[i], NULL, twin_main, &t[i]) == 0);
	}
	for (int i = 0; i < 2; i++)
		pthread_join(th[i], NULL);
	CHECK(t[0].met && t[1].met);
	CHECK(t[0].ok && t[1].ok);
	CHECK_STR(t[0].path, in(dir, "twin.shot.exr"));
	CHECK_STR(t[1].path, in(dir, "twin.shot.exr"));
	CHECK(srv_shots_bakes_run(r) == before + 1);
	for (int i = 0; i < 2; i++)
		CHECK(t[i].log.monotone && t[i].log.in_range && t[i].log.last == 1.0);
	CHECK(count_tmp(dir) == 0);

	/* different names bake side by side */
	CHECK(unlink(in(dir, "twin.shot.exr")) == 0);
	const char *names[2] = { "twin", "other" };
	for (int i = 0; i < 2; i++) {
		t[i] = (struct twin){ .r = r, .name = names[i], .me = i };
		t[i].log = (struct progress_log){ .monotone = true, .in_range = true };
		CHECK(pthread_create(&th[i], NULL, twin_main, &t[i]) == 0);
	}
	for (int i = 0; i < 2; i++)
		pthread_join(th[i], NULL);
	CHECK(t[0].ok && t[1].ok);
	CHECK_STR(t[1].path, in(dir, "other.shot.exr"));
	CHECK(srv_shots_bakes_run(r) == before + 3);
	CHECK(srv_shots_find(r, "twin", NULL, 0) == SRV_SHOT_READY);
	CHECK(srv_shots_find(r, "other", NULL, 0) == SRV_SHOT_READY);
	unlink(in(dir, "twin.rib"));
	unlink(in(dir, "twin.shot.exr"));
	unlink(in(dir, "other.rib"));
	unlink(in(dir, "other.shot.exr"));
	srv_shots_close(r);
}

/* ------------------------------------------------------------------------- */

static bool copy_file(const char *from, const char *to)
{
	FILE *a = fopen(from, "rb"), *b = fopen(to, "wb");
	bool ok = a && b;
	char buf[65536];
	for (size_t n; ok && (n = fread(buf, 1, sizeof(buf), a)) > 0;)
		ok = fwrite(buf, 1, n, b) == n;
	if (a)
		fclose(a);
	if (b && fclose(b) != 0)
		ok = false;
	return ok;
}

static void test_links_and_foreign(void)
{
	char err[256] = "", path[PATH_MAX];
	/* a real shot and a RIB outside the folder, linked from inside */
	CHECK(copy_file(in(dir, "scene.shot.exr"), in(outside, "away.shot.exr")));
	CHECK(write_text(in(outside, "away.rib"), scene_rib));
	CHECK(symlink(in(outside, "away.shot.exr"), in(dir, "away.shot.exr")) == 0);
	CHECK(symlink(in(outside, "away.rib"), in(dir, "farscene.rib")) == 0);
	CHECK(symlink("../../etc/passwd", in(dir, "up.rib")) == 0);
	/* a link that stays inside the folder is fine */
	CHECK(symlink("scene.shot.exr", in(dir, "alias.shot.exr")) == 0);

	/* an OpenEXR image that is no shot file, and junk named .exr */
	struct reyes_image im;
	CHECK(reyes_image_init(&im, 8, 4, 4, NULL));
	for (size_t i = 0; i < 8 * 4 * 4; i++)
		im.data[i] = (float)i / 128.0f;
	FILE *devnull = fopen("/dev/null", "w");
	CHECK(reyes_image_write_exr(in(dir, "render.exr"), &im, true, devnull));
	if (devnull)
		fclose(devnull);
	reyes_image_finish(&im);
	CHECK(exists(in(dir, "render.exr")));
	CHECK(write_text(in(dir, "junk.exr"), "not an exr"));
	CHECK(write_text(in(dir, "broken.shot.exr"), "not an exr either"));
	/* a shot file under a plain .exr name is a shot */
	CHECK(copy_file(in(dir, "scene.shot.exr"), in(dir, "plain.exr")));
	/* files whose names make no shot name */
	CHECK(write_text(in(dir, ".hidden.rib"), scene_rib));
	CHECK(write_text(in(dir, "with space.rib"), scene_rib));

	struct srv_shots *r = srv_shots_open(dir, err, sizeof(err));
	CHECK(r != NULL);
	if (!r)
		return;
	struct srv_shot_entry e[16];
	for (int pass = 0; pass < 2; pass++) {  /* the second from the header cache */
		size_t n = srv_shots_list(r, e, 16);
		CHECK(n == 3);
		if (n != 3)
			for (size_t i = 0; i < n && i < 16; i++)
				fprintf(stderr, "  listed '%s'\n", e[i].name);
		CHECK(n >= 3 && !strcmp(e[0].name, "alias") && !strcmp(e[1].name, "plain") &&
		      !strcmp(e[2].name, "scene"));
		struct srv_shot_entry *a = entry(e, n < 16 ? n : 16, "alias");
		CHECK(a && a->baked && !a->has_rib && a->width == 24 && a->height == 18);
		a = entry(e, n < 16 ? n : 16, "plain");
		CHECK(a && a->baked && !a->has_rib && a->width == 24 && a->height == 18);
	}
	/* a list cut short still counts every shot */
	CHECK(srv_shots_list(r, e, 1) == 3);
	CHECK_STR(e[0].name, "alias");

	CHECK(srv_shots_find(r, "away", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "farscene", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "up", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "render", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "junk", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "broken", path, sizeof(path)) == SRV_SHOT_MISSING);
	CHECK(srv_shots_find(r, "alias", path, sizeof(path)) == SRV_SHOT_READY);
	CHECK_STR(path, in(dir, "alias.shot.exr"));
	CHECK(srv_shots_find(r, "plain", path, sizeof(path)) == SRV_SHOT_READY);
	CHECK_STR(path, in(dir, "plain.exr"));
	/* "scene.shot" is no other name of scene.shot.exr */
	CHECK(srv_shots_find(r, "scene.shot", path, sizeof(path)) == SRV_SHOT_MISSING);

	uint64_t before = srv_shots_bakes_run(r);
	err[0] = '\0';
	CHECK(!srv_shots_bake(r, "farscene", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(strstr(err, "refused") != NULL);
	CHECK(!srv_shots_bake(r, "up", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(srv_shots_bakes_run(r) == before);
	CHECK(!exists(in(dir, "farscene.shot.exr")));

	/* a broken shot file beside its RIB is baked over */
	CHECK(write_text(in(dir, "broken.rib"), scene_rib));
	CHECK(srv_shots_find(r, "broken", path, sizeof(path)) == SRV_SHOT_NEEDS_BAKE);
	CHECK(srv_shots_bake(r, "broken", NULL, NULL, path, sizeof(path), err, sizeof(err)));
	CHECK(srv_shots_find(r, "broken", path, sizeof(path)) == SRV_SHOT_READY);
	CHECK(srv_shots_list(r, e, 16) == 4);
	srv_shots_close(r);

	static const char *const gone[] = {
		"away.shot.exr", "farscene.rib", "up.rib", "alias.shot.exr", "render.exr",
		"junk.exr", "broken.shot.exr", "broken.rib", "plain.exr", ".hidden.rib",
		"with space.rib",
	};
	for (size_t i = 0; i < sizeof(gone) / sizeof(gone[0]); i++)
		unlink(in(dir, gone[i]));
	unlink(in(outside, "away.shot.exr"));
	unlink(in(outside, "away.rib"));
}

/* Remove what the tests left in @base (the shot folder, the outside folder). */
static void clean(const char *base)
{
	DIR *d = opendir(base);
	if (d) {
		for (struct dirent *e; (e = readdir(d));)
			if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
				unlink(in(base, e->d_name));
		closedir(d);
	}
	rmdir(base);
}

int main(void)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(dir, sizeof(dir), "%s/relight-shots-XXXXXX", tmp && *tmp ? tmp : "/tmp");
	snprintf(outside, sizeof(outside), "%s/relight-away-XXXXXX", tmp && *tmp ? tmp : "/tmp");
	if (!mkdtemp(dir) || !mkdtemp(outside)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_names);
	RUN(test_bake);
	RUN(test_errors);
	RUN(test_concurrent);
	RUN(test_links_and_foreign);
	clean(dir);
	clean(outside);
	return test_finish();
}

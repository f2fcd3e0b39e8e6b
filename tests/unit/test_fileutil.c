/*
 * Copying a file, removing a folder tree, relative paths and stale temporary
 * files (common/fileutil.h).
 */
#include "fileutil.h"
#include "test.h"

#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

static char root[] = "/tmp/relight-test-fileutil-XXXXXX";

static bool exists(const char *path)
{
	struct stat st;
	return lstat(path, &st) == 0;
}

static void test_copy(void)
{
	char a[256], b[256], missing[256];
	snprintf(a, sizeof(a), "%s/a.bin", root);
	snprintf(b, sizeof(b), "%s/b.bin", root);
	snprintf(missing, sizeof(missing), "%s/nosuch", root);
	/* larger than the copy's buffer, with every byte value */
	size_t n = 200000;
	unsigned char *data = malloc(n);
	for (size_t i = 0; i < n; i++)
		data[i] = (unsigned char)(i * 7 + i / 256);
	char err[256];
	CHECK(rl_write_file_atomic(a, data, n, err, sizeof(err)));
	/* an existing, longer destination is truncated */
	CHECK(rl_write_file_atomic(b, data, n, err, sizeof(err)));
	CHECK(rl_write_file_atomic(a, data, n - 1000, err, sizeof(err)));
	CHECK(rl_copy_file(a, b));
	size_t len = 0;
	char *back = rl_read_file(b, 1 << 20, &len, err, sizeof(err));
	CHECK(back && len == n - 1000 && !memcmp(back, data, len));
	free(back);
	errno = 0;
	CHECK(!rl_copy_file(missing, b));
	CHECK(errno == ENOENT);
	CHECK(!rl_copy_file(a, "/nonexistent-dir/x"));
	free(data);
}

static void test_remove_tree(void)
{
	char d[256], f[320], g[320], link[320];
	snprintf(d, sizeof(d), "%s/tree/a/b", root);
	CHECK(rl_mkdir_p(d));
	snprintf(f, sizeof(f), "%s/tree/a/b/file", root);
	snprintf(g, sizeof(g), "%s/tree/top", root);
	char err[64];
	CHECK(rl_write_file_atomic(f, "x", 1, err, sizeof(err)));
	CHECK(rl_write_file_atomic(g, "y", 1, err, sizeof(err)));
	/* a link to a folder outside: removed, not followed */
	char outside[256], kept[320];
	snprintf(outside, sizeof(outside), "%s/outside", root);
	snprintf(kept, sizeof(kept), "%s/outside/kept", root);
	CHECK(rl_mkdir_p(outside));
	CHECK(rl_write_file_atomic(kept, "z", 1, err, sizeof(err)));
	snprintf(link, sizeof(link), "%s/tree/link", root);
	CHECK(symlink(outside, link) == 0);
	snprintf(d, sizeof(d), "%s/tree", root);
	rl_remove_tree(d);
	CHECK(!exists(d));
	CHECK(exists(kept));
	rl_remove_tree(d); /* gone already: nothing happens */
	CHECK(!exists(d));
}

static void check_relative(const char *path, const char *dir, const char *want)
{
	char *got = rl_path_relative(path, dir);
	CHECK_STR(got, want);
	free(got);
}

static void test_relative(void)
{
	check_relative("/a/b/shaders/key.sl", "/a/b", "shaders/key.sl");
	check_relative("/a/b/shaders/key.sl", "/a/b/", "shaders/key.sl");
	check_relative("/a/shaders/key.sl", "/a/b/shots", "../../shaders/key.sl");
	check_relative("/a/b", "/a/b", ".");
	check_relative("/x/./y.sl", "/x/z/.", "../y.sl");
	check_relative("/ab/c.sl", "/a", "../ab/c.sl");
	check_relative("/a/c.sl", "/", "a/c.sl");
}

/* A temporary file's name has the writer's pid; stale ones go, nothing else does. */
static void test_stale_temps(void)
{
	char d[256], path[400], err[64];
	snprintf(d, sizeof(d), "%s/temps", root);
	CHECK(rl_mkdir_p(d));
	/* a write names its temporary file with this process's pid */
	struct rl_atomic a;
	snprintf(path, sizeof(path), "%s/x.exr", d);
	CHECK(rl_atomic_open(&a, path));
	char want[512];
	snprintf(want, sizeof(want), "%s.tmp.%ld.", path, (long)getpid());
	CHECK(!strncmp(a.tmp, want, strlen(want)));
	rl_atomic_abort(&a);
	static const char *const names[] = {
		"x.exr.tmp.999999999.abcDEF", /* a pid no process has: stale */
		"x.exr.tmp.1.abcdef",         /* init: alive */
		"y.exr.tmp.999999999.abc123", /* stale, of another target */
		"x.exr.tmp.abc",              /* no pid */
		"x.exr.tmp.999999999.ab-c",   /* not the pattern */
		"x.exr",
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		snprintf(path, sizeof(path), "%s/%s", d, names[i]);
		CHECK(rl_write_file_atomic(path, "x", 1, err, sizeof(err)));
	}
	CHECK(rl_remove_stale_temps(d, "x.exr") == 1);
	snprintf(path, sizeof(path), "%s/%s", d, names[0]);
	CHECK(!exists(path));
	CHECK(rl_remove_stale_temps(d, NULL) == 1);
	for (size_t i = 1; i < sizeof(names) / sizeof(names[0]); i++) {
		snprintf(path, sizeof(path), "%s/%s", d, names[i]);
		CHECK(exists(path) == (i != 2));
	}
}

int main(void)
{
	if (!mkdtemp(root)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_copy);
	RUN(test_remove_tree);
	RUN(test_relative);
	RUN(test_stale_temps);
	rl_remove_tree(root);
	CHECK(!exists(root));
	return test_finish();
}

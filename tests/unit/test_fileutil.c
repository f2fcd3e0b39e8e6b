/* Copying a file and removing a folder tree (common/fileutil.h). */
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

int main(void)
{
	if (!mkdtemp(root)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_copy);
	RUN(test_remove_tree);
	rl_remove_tree(root);
	CHECK(!exists(root));
	return test_finish();
}

/* Tests of the common utilities: arena, RL_VEC, strbuf and log. */
#include "test.h"

#include "arena.h"
#include "log.h"
#include "strbuf.h"

#include <stdint.h>
#include <unistd.h>

static void test_arena_basics(void)
{
	struct rl_arena *a = rl_arena_create();
	CHECK(a != NULL);
	CHECK(rl_arena_used(a) == 0);

	/* Every block is zeroed and aligned for any type (16 bytes here). */
	for (size_t size = 1; size <= 100; size += 7) {
		unsigned char *p = rl_arena_alloc(a, size);
		CHECK(((uintptr_t)p % 16) == 0);
		size_t nonzero = 0;
		for (size_t i = 0; i < size; i++)
			nonzero += p[i] != 0;
		CHECK(nonzero == 0);
		memset(p, 0xab, size);
	}
	/* 15 sizes, each rounded up to a multiple of 16. */
	size_t expect = 0;
	for (size_t size = 1; size <= 100; size += 7)
		expect += (size + 15) / 16 * 16;
	CHECK(rl_arena_used(a) == expect);

	char *s = rl_arena_strdup(a, "hello");
	CHECK_STR(s, "hello");
	char *n = rl_arena_strndup(a, "abcdef", 3);
	CHECK_STR(n, "abc");
	char *z = rl_arena_strndup(a, "", 0);
	CHECK_STR(z, "");
	char *f = rl_arena_printf(a, "%s-%d-%.2f", "x", 42, 1.5);
	CHECK_STR(f, "x-42-1.50");
	rl_arena_destroy(a);
	rl_arena_destroy(NULL); /* accepted */
}

/* Many blocks over many chunks, big ones among them: each keeps its contents. */
static void test_arena_many(void)
{
	struct rl_arena *a = rl_arena_create();
	enum { N = 5000 };
	static unsigned char *blocks[N];
	static size_t sizes[N];

	for (size_t i = 0; i < N; i++) {
		/* Every 500th block is bigger than a chunk (64 KiB). */
		sizes[i] = (i % 500 == 499) ? 100000 + i : 1 + (i * 37) % 200;
		blocks[i] = rl_arena_alloc(a, sizes[i]);
		memset(blocks[i], (int)(i & 0xff), sizes[i]);
	}
	size_t bad = 0;
	for (size_t i = 0; i < N; i++)
		for (size_t j = 0; j < sizes[i]; j++)
			bad += blocks[i][j] != (unsigned char)(i & 0xff);
	CHECK(bad == 0);
	/* Blocks allocated one after the other do not overlap. */
	size_t overlaps = 0;
	for (size_t i = 1; i < N; i++)
		if (blocks[i] < blocks[i - 1] + sizes[i - 1] && blocks[i - 1] < blocks[i] + sizes[i])
			overlaps++;
	CHECK(overlaps == 0);
	CHECK(rl_arena_used(a) >= 10 * 100000);
	rl_arena_destroy(a);
}

static void test_vec(void)
{
	RL_VEC(int) v = { 0 };
	CHECK(v.data == NULL && v.len == 0 && v.cap == 0);
	for (int i = 0; i < 1000; i++)
		rl_vec_push(v, i * 3);
	CHECK(v.len == 1000);
	CHECK(v.cap >= 1000);
	long sum = 0;
	size_t wrong = 0;
	for (size_t i = 0; i < v.len; i++) {
		sum += v.data[i];
		wrong += v.data[i] != (int)i * 3;
	}
	CHECK(wrong == 0);
	CHECK(sum == 3L * 999 * 1000 / 2);

	rl_vec_reserve(v, 5000);
	CHECK(v.cap >= 5000 && v.len == 1000);
	CHECK(v.data[999] == 2997);
	rl_vec_free(v);
	CHECK(v.data == NULL && v.len == 0 && v.cap == 0);

	/* A vector of structs, pushed with a compound literal. */
	struct pt { double x, y; };
	RL_VEC(struct pt) pts = { 0 };
	rl_vec_push(pts, (struct pt){ 1.5, -2 });
	rl_vec_push(pts, (struct pt){ 3, 4 });
	CHECK(pts.len == 2);
	CHECK_NEAR(pts.data[0].x, 1.5, 0);
	CHECK_NEAR(pts.data[1].y, 4, 0);
	rl_vec_free(pts);

	char *d = rl_xstrdup("copy");
	CHECK_STR(d, "copy");
	free(d);
	int *c = rl_xcalloc(10, sizeof(int));
	CHECK(c[0] == 0 && c[9] == 0);
	c = rl_xrealloc(c, 20 * sizeof(int));
	CHECK(c[9] == 0);
	free(c);
}

static void test_strbuf(void)
{
	struct rl_strbuf b = { 0 };
	CHECK_STR(rl_strbuf_str(&b), "");
	rl_strbuf_puts(&b, "abc");
	rl_strbuf_putc(&b, '-');
	rl_strbuf_add(&b, "xyz", 2);
	rl_strbuf_printf(&b, "%d/%s", 7, "q");
	CHECK_STR(rl_strbuf_str(&b), "abc-xy7/q");
	CHECK(b.len == 9);

	rl_strbuf_reset(&b);
	CHECK_STR(rl_strbuf_str(&b), "");
	CHECK(b.len == 0);

	/* Growing far past the first allocation. */
	for (int i = 0; i < 10000; i++)
		rl_strbuf_putc(&b, (char)('a' + i % 26));
	CHECK(b.len == 10000);
	CHECK(strlen(rl_strbuf_str(&b)) == 10000);
	CHECK(b.data[9999] == 'a' + 9999 % 26);
	rl_strbuf_reset(&b);

	rl_strbuf_json_string(&b, "a\"b\\c\nd\te\x01");
	CHECK_STR(rl_strbuf_str(&b), "\"a\\\"b\\\\c\\nd\\te\\u0001\"");
	rl_strbuf_reset(&b);
	rl_strbuf_json_string(&b, "");
	CHECK_STR(rl_strbuf_str(&b), "\"\"");
	rl_strbuf_reset(&b);
	rl_strbuf_json_string(&b, "caf\xc3\xa9"); /* UTF-8 passes through */
	CHECK_STR(rl_strbuf_str(&b), "\"caf\xc3\xa9\"");

	rl_strbuf_finish(&b);
	CHECK(b.data == NULL && b.len == 0);
	CHECK_STR(rl_strbuf_str(&b), "");
}

/* Run rl_log with stderr sent to a file; return what was printed (static buffer). */
static const char *capture_log(enum rl_log_level level, const char *msg)
{
	static char text[4096];
	FILE *tmp = tmpfile();
	if (!tmp)
		return "";
	fflush(stderr);
	int saved = dup(fileno(stderr));
	dup2(fileno(tmp), fileno(stderr));
	rl_log(level, "%s", msg);
	fflush(stderr);
	dup2(saved, fileno(stderr));
	close(saved);

	rewind(tmp);
	size_t n = fread(text, 1, sizeof(text) - 1, tmp);
	text[n] = '\0';
	fclose(tmp);
	return text;
}

static void test_log(void)
{
	/* main() set RELIGHT_LOG=info before the first use. */
	CHECK(rl_log_get_level() == RL_LOG_INFO);

	/* The location printed is capture_log's call of rl_log. */
	const char *expect = "relight: info: [test_arena.c:";
	const char *out = capture_log(RL_LOG_INFO, "hello 1");
	CHECK(strncmp(out, expect, strlen(expect)) == 0);
	CHECK(strstr(out, "] hello 1\n") != NULL);

	out = capture_log(RL_LOG_DEBUG, "hidden");
	CHECK_STR(out, "");

	rl_log_set_level(RL_LOG_ERROR);
	CHECK(rl_log_get_level() == RL_LOG_ERROR);
	out = capture_log(RL_LOG_WARN, "also hidden");
	CHECK_STR(out, "");
	out = capture_log(RL_LOG_ERROR, "shown");
	expect = "relight: error: [test_arena.c:";
	CHECK(strncmp(out, expect, strlen(expect)) == 0);
	CHECK(strstr(out, "] shown\n") != NULL);

	/* A message longer than the internal buffer is cut, never overflows. */
	rl_log_set_level(RL_LOG_DEBUG);
	static char big[10000];
	memset(big, 'x', sizeof(big) - 1);
	out = capture_log(RL_LOG_WARN, big);
	CHECK(strncmp(out, "relight: warning: ", 18) == 0);
	CHECK(strlen(out) > 1000 && strlen(out) < sizeof(big));

	rl_log_set_level(RL_LOG_SILENT);
	out = capture_log(RL_LOG_ERROR, "silent");
	CHECK_STR(out, "");
}

int main(void)
{
	setenv("RELIGHT_LOG", "info", 1);
	RUN(test_arena_basics);
	RUN(test_arena_many);
	RUN(test_vec);
	RUN(test_strbuf);
	RUN(test_log);
	return test_finish();
}

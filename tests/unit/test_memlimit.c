/*
 * The memory limit's sizes: parsing what --memory-limit accepts, printing
 * figures for messages, and the default limit against the machine's memory.
 */
#include "memlimit.h"

#include "test.h"

#include <unistd.h>

static void test_parse(void)
{
	static const struct {
		const char *s;
		uint64_t bytes;
	} ok[] = {
		{ "1", 1 }, { "4096", 4096 }, { "1K", 1024 }, { "1k", 1024 }, { "512M", 512u << 20 },
		{ "8G", 8ull << 30 }, { "8GB", 8ull << 30 }, { "8GiB", 8ull << 30 },
		{ "1.5G", 3ull << 29 }, { "2T", 2ull << 40 }, { ".5M", 512u << 10 },
	};
	for (size_t i = 0; i < sizeof(ok) / sizeof(ok[0]); i++) {
		uint64_t b = 0;
		CHECK(reyes_mem_parse_size(ok[i].s, &b));
		CHECK(b == ok[i].bytes);
	}
	static const char *const bad[] = { "", "0", "-1G", "G", "1.5.3M", "12Q", "8 G", "1GG",
					   "0.1", "1e30T", "nan", "inf", NULL };
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		uint64_t b = 7;
		CHECK(!reyes_mem_parse_size(bad[i], &b));
		CHECK(b == 7);
	}
}

static void test_format(void)
{
	char buf[32];
	CHECK(!strcmp(reyes_mem_format(buf, sizeof(buf), 900), "900 B"));
	CHECK(!strcmp(reyes_mem_format(buf, sizeof(buf), 1536), "1.5 KiB"));
	CHECK(!strcmp(reyes_mem_format(buf, sizeof(buf), 8ull << 30), "8.0 GiB"));
	CHECK(!strcmp(reyes_mem_format(buf, sizeof(buf), 3ull << 40), "3.0 TiB"));
}

/* The default is 3/4 of the physical memory, or less under a cgroup limit. */
static void test_default(void)
{
	long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
	uint64_t phys = (uint64_t)pages * (uint64_t)page;
	uint64_t lim = reyes_mem_default_limit();
	CHECK(lim > 0);
	CHECK(lim <= phys / 4 * 3);
	printf("default memory limit: %llu bytes of %llu physical\n", (unsigned long long)lim,
	       (unsigned long long)phys);
}

int main(void)
{
	RUN(test_parse);
	RUN(test_format);
	RUN(test_default);
	return test_finish();
}

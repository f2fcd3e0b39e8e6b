/* The renderer's memory limit (memlimit.h). */
#include "memlimit.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The first number in file @path, or 0 (absent, unreadable, "max"). */
static uint64_t read_number(const char *path)
{
	FILE *f = fopen(path, "r");
	if (!f)
		return 0;
	char line[64] = { 0 };
	bool got = fgets(line, sizeof(line), f) != NULL;
	fclose(f);
	if (!got || !isdigit((unsigned char)line[0]))
		return 0;
	errno = 0;
	unsigned long long v = strtoull(line, NULL, 10);
	return errno ? 0 : (uint64_t)v;
}

uint64_t reyes_mem_default_limit(void)
{
	long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
	uint64_t phys = pages > 0 && page > 0 ? (uint64_t)pages * (uint64_t)page : 0;
	uint64_t cg = read_number("/sys/fs/cgroup/memory.max");
	if (!cg)
		cg = read_number("/sys/fs/cgroup/memory/memory.limit_in_bytes");
	uint64_t m = phys;
	if (cg && (!m || cg < m))
		m = cg;
	return m / 4 * 3;
}

bool reyes_mem_parse_size(const char *s, uint64_t *bytes)
{
	if (!s || !(isdigit((unsigned char)*s) || *s == '.'))
		return false;
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (errno || end == s || !(v > 0))
		return false;
	double unit = 1;
	switch (toupper((unsigned char)*end)) {
	case 'K': unit = 1024.0; end++; break;
	case 'M': unit = 1024.0 * 1024; end++; break;
	case 'G': unit = 1024.0 * 1024 * 1024; end++; break;
	case 'T': unit = 1024.0 * 1024 * 1024 * 1024; end++; break;
	default: break;
	}
	if (unit > 1 && (*end == 'i' || *end == 'I'))
		end++;
	if (*end == 'B' || *end == 'b')
		end++;
	if (*end)
		return false;
	double b = floor(v * unit);
	if (!(b >= 1 && b <= 4611686018427387904.0))
		return false;
	*bytes = (uint64_t)b;
	return true;
}

const char *reyes_mem_format(char *buf, size_t cap, uint64_t bytes)
{
	static const char *const units[] = { "KiB", "MiB", "GiB", "TiB", "PiB", "EiB" };
	if (bytes < 1024) {
		snprintf(buf, cap, "%llu B", (unsigned long long)bytes);
		return buf;
	}
	double v = (double)bytes / 1024;
	int u = 0;
	while (v >= 1024 && u < 5) {
		v /= 1024;
		u++;
	}
	snprintf(buf, cap, "%.1f %s", v, units[u]);
	return buf;
}

/*
 * The renderer's memory limit: how much a frame may take before it is
 * refused, its default from the machine, and sizes as people write them.
 */
#ifndef REYES_MEMLIMIT_H
#define REYES_MEMLIMIT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/**
 * The default limit: 3/4 of the memory this process can have, the smaller
 * of the physical memory and the cgroup's limit (/sys/fs/cgroup/memory.max,
 * or memory.limit_in_bytes of cgroup v1) where one is set. 0 when neither
 * can be read.
 */
uint64_t reyes_mem_default_limit(void);

/**
 * Parse a size: a number of bytes, or a number with a suffix K, M, G or T
 * (powers of 1024, upper or lower case, an optional trailing B or iB), such
 * as 8G, 512M, 1.5G. False for anything else, zero or over 2^62 bytes.
 */
bool reyes_mem_parse_size(const char *s, uint64_t *bytes);

/** @bytes as "12.3 GiB", "512.0 MiB", "900 B" in @buf (at least 32 bytes). */
const char *reyes_mem_format(char *buf, size_t cap, uint64_t bytes);

#endif

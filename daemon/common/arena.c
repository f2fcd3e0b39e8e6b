#include "arena.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHUNK_SIZE (64 * 1024)
#define ALIGN 16

struct chunk {
	struct chunk *next;
	size_t size, used;
	_Alignas(ALIGN) unsigned char data[];
};

struct rl_arena {
	struct chunk *head;
	size_t total;
};

static void out_of_memory(size_t size)
{
	fprintf(stderr, "relight: out of memory (allocating %zu bytes)\n", size);
	abort();
}

void *rl_xmalloc(size_t size)
{
	void *p = malloc(size ? size : 1);
	if (!p)
		out_of_memory(size);
	return p;
}

void *rl_xcalloc(size_t n, size_t size)
{
	void *p = calloc(n ? n : 1, size ? size : 1);
	if (!p)
		out_of_memory(n * size);
	return p;
}

void *rl_xrealloc(void *p, size_t size)
{
	void *q = realloc(p, size ? size : 1);
	if (!q)
		out_of_memory(size);
	return q;
}

char *rl_xstrdup(const char *s)
{
	size_t n = strlen(s) + 1;
	char *d = rl_xmalloc(n);
	memcpy(d, s, n);
	return d;
}

void *rl_vec_grow_(void *data, size_t *cap, size_t elem, size_t need)
{
	size_t c = *cap ? *cap : 8;
	while (c < need) {
		if (c > SIZE_MAX / 2 / elem)
			out_of_memory(SIZE_MAX);
		c *= 2;
	}
	*cap = c;
	return rl_xrealloc(data, c * elem);
}

struct rl_arena *rl_arena_create(void)
{
	return rl_xcalloc(1, sizeof(struct rl_arena));
}

void rl_arena_destroy(struct rl_arena *arena)
{
	if (!arena)
		return;
	struct chunk *c = arena->head;
	while (c) {
		struct chunk *next = c->next;
		free(c);
		c = next;
	}
	free(arena);
}

void *rl_arena_alloc(struct rl_arena *arena, size_t size)
{
	size = (size + ALIGN - 1) & ~(size_t)(ALIGN - 1);
	struct chunk *c = arena->head;
	if (!c || c->size - c->used < size) {
		/* Big requests get a chunk of their own, behind the current one, so
		 * the current chunk's free space is not wasted. */
		size_t csize = size > CHUNK_SIZE / 4 ? size : CHUNK_SIZE;
		if (csize > SIZE_MAX - sizeof(struct chunk))
			out_of_memory(size);
		struct chunk *n = rl_xmalloc(sizeof(struct chunk) + csize);
		n->size = csize;
		n->used = 0;
		if (c && csize != CHUNK_SIZE) {
			n->next = c->next;
			c->next = n;
		} else {
			n->next = c;
			arena->head = n;
		}
		c = n;
	}
	void *p = c->data + c->used;
	c->used += size;
	arena->total += size;
	memset(p, 0, size);
	return p;
}

char *rl_arena_strndup(struct rl_arena *arena, const char *s, size_t len)
{
	char *d = rl_arena_alloc(arena, len + 1);
	memcpy(d, s, len);
	d[len] = '\0';
	return d;
}

char *rl_arena_strdup(struct rl_arena *arena, const char *s)
{
	return rl_arena_strndup(arena, s, strlen(s));
}

char *rl_arena_printf(struct rl_arena *arena, const char *fmt, ...)
{
	/* Most results fit a small buffer: format once there, again only if not. */
	char small[256];
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(small, sizeof(small), fmt, ap);
	va_end(ap);
	if (n < 0)
		return rl_arena_strdup(arena, "");
	if ((size_t)n < sizeof(small))
		return rl_arena_strndup(arena, small, (size_t)n);
	char *d = rl_arena_alloc(arena, (size_t)n + 1);
	va_start(ap, fmt);
	vsnprintf(d, (size_t)n + 1, fmt, ap);
	va_end(ap);
	return d;
}

size_t rl_arena_used(const struct rl_arena *arena)
{
	return arena->total;
}

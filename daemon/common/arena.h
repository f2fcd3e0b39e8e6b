/* Arena allocation and growable arrays shared by every relight module. */
#ifndef RL_ARENA_H
#define RL_ARENA_H

#include <stddef.h>

/**
 * A bump allocator: many small allocations, freed all at once by
 * rl_arena_destroy(). Compiler data (tokens, AST, types, IR) lives in one
 * arena per compilation.
 */
struct rl_arena;

/** Create an empty arena. Never returns NULL (aborts when memory is out). */
struct rl_arena *rl_arena_create(void);

/** Free the arena and everything allocated from it. Accepts NULL. */
void rl_arena_destroy(struct rl_arena *arena);

/** Zeroed memory, aligned for any type; lives as long as the arena. */
void *rl_arena_alloc(struct rl_arena *arena, size_t size);

/** Copy @len bytes of @s into the arena and NUL-terminate them. */
char *rl_arena_strndup(struct rl_arena *arena, const char *s, size_t len);

/** Copy a NUL-terminated string into the arena. */
char *rl_arena_strdup(struct rl_arena *arena, const char *s);

/** printf into arena memory. */
char *rl_arena_printf(struct rl_arena *arena, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/** Total bytes handed out by the arena (for reports and tests). */
size_t rl_arena_used(const struct rl_arena *arena);

/** malloc/calloc/realloc that abort with a message when memory is out. */
void *rl_xmalloc(size_t size);
void *rl_xcalloc(size_t n, size_t size);
void *rl_xrealloc(void *p, size_t size);
char *rl_xstrdup(const char *s);

/**
 * A growable array of T on the heap: `RL_VEC(int) v = {0};`, then
 * rl_vec_push(v, x), v.data[i], v.len, and rl_vec_free(v).
 */
#define RL_VEC(T) struct { T *data; size_t len, cap; }

/** Returns @data grown so that it holds at least @need elements of @elem bytes. */
void *rl_vec_grow_(void *data, size_t *cap, size_t elem, size_t need);

#define rl_vec_reserve(v, n) \
	do { \
		if ((n) > (v).cap) \
			(v).data = rl_vec_grow_((v).data, &(v).cap, sizeof(*(v).data), (n)); \
	} while (0)

#define rl_vec_push(v, ...) \
	do { \
		rl_vec_reserve((v), (v).len + 1); \
		(v).data[(v).len++] = (__VA_ARGS__); \
	} while (0)

#define rl_vec_free(v) \
	do { \
		free((v).data); \
		(v).data = NULL; \
		(v).len = (v).cap = 0; \
	} while (0)

#endif

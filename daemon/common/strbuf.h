/* A growable, always NUL-terminated string builder. */
#ifndef RL_STRBUF_H
#define RL_STRBUF_H

#include <stdarg.h>
#include <stddef.h>

/** Start as `struct rl_strbuf b = {0};`; b.data is NULL until something is added. */
struct rl_strbuf {
	char *data;
	size_t len, cap;
};

void rl_strbuf_add(struct rl_strbuf *b, const char *s, size_t len);
void rl_strbuf_puts(struct rl_strbuf *b, const char *s);
void rl_strbuf_putc(struct rl_strbuf *b, char c);
void rl_strbuf_printf(struct rl_strbuf *b, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
void rl_strbuf_vprintf(struct rl_strbuf *b, const char *fmt, va_list ap);
/** Append @s as a JSON string literal, quotes included. */
void rl_strbuf_json_string(struct rl_strbuf *b, const char *s);
/** The text so far; "" when empty. Owned by @b. */
const char *rl_strbuf_str(const struct rl_strbuf *b);
void rl_strbuf_reset(struct rl_strbuf *b);
void rl_strbuf_finish(struct rl_strbuf *b);

#endif

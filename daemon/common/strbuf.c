#include "strbuf.h"
#include "arena.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void reserve(struct rl_strbuf *b, size_t extra)
{
	if (b->len + extra + 1 > b->cap)
		b->data = rl_vec_grow_(b->data, &b->cap, 1, b->len + extra + 1);
}

void rl_strbuf_add(struct rl_strbuf *b, const char *s, size_t len)
{
	reserve(b, len);
	memcpy(b->data + b->len, s, len);
	b->len += len;
	b->data[b->len] = '\0';
}

void rl_strbuf_puts(struct rl_strbuf *b, const char *s)
{
	rl_strbuf_add(b, s, strlen(s));
}

void rl_strbuf_putc(struct rl_strbuf *b, char c)
{
	rl_strbuf_add(b, &c, 1);
}

void rl_strbuf_vprintf(struct rl_strbuf *b, const char *fmt, va_list ap)
{
	va_list ap2;
	va_copy(ap2, ap);
	int n = vsnprintf(NULL, 0, fmt, ap2);
	va_end(ap2);
	if (n <= 0)
		return;
	reserve(b, (size_t)n);
	vsnprintf(b->data + b->len, (size_t)n + 1, fmt, ap);
	b->len += (size_t)n;
}

void rl_strbuf_printf(struct rl_strbuf *b, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(b, fmt, ap);
	va_end(ap);
}

void rl_strbuf_json_string(struct rl_strbuf *b, const char *s)
{
	rl_strbuf_putc(b, '"');
	for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
		switch (*p) {
		case '"': rl_strbuf_puts(b, "\\\""); break;
		case '\\': rl_strbuf_puts(b, "\\\\"); break;
		case '\n': rl_strbuf_puts(b, "\\n"); break;
		case '\t': rl_strbuf_puts(b, "\\t"); break;
		case '\r': rl_strbuf_puts(b, "\\r"); break;
		default:
			if (*p < 0x20)
				rl_strbuf_printf(b, "\\u%04x", *p);
			else
				rl_strbuf_putc(b, (char)*p);
		}
	}
	rl_strbuf_putc(b, '"');
}

const char *rl_strbuf_str(const struct rl_strbuf *b)
{
	return b->data ? b->data : "";
}

void rl_strbuf_reset(struct rl_strbuf *b)
{
	b->len = 0;
	if (b->data)
		b->data[0] = '\0';
}

void rl_strbuf_finish(struct rl_strbuf *b)
{
	free(b->data);
	b->data = NULL;
	b->len = b->cap = 0;
}

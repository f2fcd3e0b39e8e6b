/*
 * libFuzzer target for relightd's settings files: every input is read as a
 * config file and as a token file. An accepted config must keep its
 * invariants (fields within their ranges, origins counted and allocated);
 * an accepted token file must let every token it holds back in with its
 * role. A refusal must say which line. Crashes, sanitizer reports, hangs
 * and leaks are failures.
 */
#include "server/config.h"

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Each line of an accepted token file, checked back: its first word and its role. */
static void check_tokens(const struct srv_tokens *t, const char *text, size_t size)
{
	uint32_t seen = 0;
	const char *p = text, *end = text + size;
	while (p < end) {
		const char *nl = memchr(p, '\n', (size_t)(end - p));
		const char *e = nl ? nl : end;
		while (p < e && strchr(" \t\r\v\f", *p) && *p)
			p++;
		if (p < e && *p != '#') {
			char tok[SRV_TOKEN_MAX + 1];
			size_t n = 0;
			while (p + n < e && !strchr(" \t\r\v\f", p[n]) && n < SRV_TOKEN_MAX)
				n++;
			memcpy(tok, p, n);
			tok[n] = '\0';
			enum srv_role r = srv_tokens_check(t, tok);
			if (r != SRV_ROLE_EDITOR && r != SRV_ROLE_VIEWER)
				abort();
			seen++;
		}
		p = nl ? nl + 1 : end;
	}
	if (seen != srv_tokens_count(t))
		abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	const char *text = (const char *)data;
	char err[512];

	struct srv_config c;
	srv_config_defaults(&c);
	err[0] = '\0';
	if (srv_config_parse_text(&c, "f", text, size, err, sizeof(err))) {
		if (c.port < 0 || c.port > 65535 || c.tile_size < 16 || c.tile_size > 1024 ||
		    !c.max_clients || !c.max_shots || !c.max_lights || !c.gpu_budget ||
		    !c.max_message || !c.client_queue || c.norigins > SRV_MAX_ORIGINS ||
		    !c.shots_dir[0] || memchr(c.host, '\0', sizeof(c.host)) == NULL)
			abort();
		for (uint32_t i = 0; i < c.norigins; i++)
			if (!c.origins[i] || !srv_origin_allowed(&c, c.origins[i]))
				abort();
	} else if (strncmp(err, "f:", 2) != 0) {
		abort();
	}
	srv_config_free(&c);

	struct srv_tokens *t = srv_tokens_parse("f", text, size, err, sizeof(err));
	if (t) {
		check_tokens(t, text, size);
		if (srv_tokens_check(t, NULL) != SRV_ROLE_NONE)
			abort();
		srv_tokens_free(t);
	} else if (strncmp(err, "f:", 2) != 0) {
		abort();
	}
	return 0;
}

#include "log.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int current_level = -1;

static enum rl_log_level level_from_env(void)
{
	const char *e = getenv("RELIGHT_LOG");
	if (!e)
		return RL_LOG_WARN;
	if (!strcmp(e, "debug"))
		return RL_LOG_DEBUG;
	if (!strcmp(e, "info"))
		return RL_LOG_INFO;
	if (!strcmp(e, "error"))
		return RL_LOG_ERROR;
	if (!strcmp(e, "silent"))
		return RL_LOG_SILENT;
	return RL_LOG_WARN;
}

void rl_log_set_level(enum rl_log_level level)
{
	current_level = (int)level;
}

enum rl_log_level rl_log_get_level(void)
{
	if (current_level < 0)
		current_level = (int)level_from_env();
	return (enum rl_log_level)current_level;
}

void rl_log_(enum rl_log_level level, const char *file, int line, const char *fmt, ...)
{
	if (level > rl_log_get_level())
		return;
	static const char *const names[] = { "", "error", "warning", "info", "debug" };
	const char *base = strrchr(file, '/');
	base = base ? base + 1 : file;
	char msg[2048];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	fprintf(stderr, "relight: %s: [%s:%d] %s\n", names[level], base, line, msg);
}

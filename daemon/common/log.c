#include "log.h"

#include "clock.h"

#include <pthread.h>

#include <stdarg.h>
#include <stdbool.h>
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

static void emit(enum rl_log_level level, const char *file, int line, const char *fmt,
		 va_list ap, unsigned dropped, double seconds)
{
	static const char *const names[] = { "", "error", "warning", "info", "debug" };
	const char *base = strrchr(file, '/');
	base = base ? base + 1 : file;
	char msg[2048];
	vsnprintf(msg, sizeof(msg), fmt, ap);
	if (dropped)
		fprintf(stderr, "relight: %s: [%s:%d] %s (%u more lines from here dropped in the "
			"last %.0f s)\n", names[level], base, line, msg, dropped, seconds);
	else
		fprintf(stderr, "relight: %s: [%s:%d] %s\n", names[level], base, line, msg);
}

void rl_log_(enum rl_log_level level, const char *file, int line, const char *fmt, ...)
{
	if (level > rl_log_get_level())
		return;
	va_list ap;
	va_start(ap, fmt);
	emit(level, file, line, fmt, ap, 0, 0);
	va_end(ap);
}

static pthread_mutex_t limit_lock = PTHREAD_MUTEX_INITIALIZER;
static unsigned limit_rate = 10;

void rl_log_set_rate(unsigned per_second)
{
	pthread_mutex_lock(&limit_lock);
	limit_rate = per_second;
	pthread_mutex_unlock(&limit_lock);
}

void rl_log_limited_(struct rl_log_limit *limit, enum rl_log_level level, const char *file,
		     int line, const char *fmt, ...)
{
	if (level > rl_log_get_level())
		return;
	double now = rl_now_ms();
	pthread_mutex_lock(&limit_lock);
	if (now - limit->window >= 1000 || limit->window == 0) {
		limit->window = now;
		limit->lines = 0;
	}
	bool print = !limit_rate || limit->lines < limit_rate;
	unsigned dropped = 0;
	double seconds = 0;
	if (print) {
		limit->lines++;
		dropped = limit->dropped;
		seconds = (now - limit->since) / 1000;
		limit->dropped = 0;
	} else {
		if (!limit->dropped)
			limit->since = now;
		limit->dropped++;
	}
	pthread_mutex_unlock(&limit_lock);
	if (!print)
		return;
	va_list ap;
	va_start(ap, fmt);
	emit(level, file, line, fmt, ap, dropped, seconds);
	va_end(ap);
}

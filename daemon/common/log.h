/* Logging for relight's programs: one macro, a level, and [file:line]. */
#ifndef RL_LOG_H
#define RL_LOG_H

enum rl_log_level {
	RL_LOG_SILENT = 0,
	RL_LOG_ERROR,
	RL_LOG_WARN,
	RL_LOG_INFO,
	RL_LOG_DEBUG,
};

/** Messages above @level are dropped. Default RL_LOG_WARN; RELIGHT_LOG=debug|info|warn|error overrides. */
void rl_log_set_level(enum rl_log_level level);
enum rl_log_level rl_log_get_level(void);

void rl_log_(enum rl_log_level level, const char *file, int line, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));

/** rl_log(RL_LOG_INFO, "loaded %s", path); prints "relight: info: [file.c:12] loaded x". */
#define rl_log(level, ...) rl_log_((level), __FILE__, __LINE__, __VA_ARGS__)

#endif

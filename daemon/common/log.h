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

/** One call site's allowance of lines (rl_log_limited keeps one per site). */
struct rl_log_limit {
	double window;        /* start of the current second, in ms of rl_now_ms */
	unsigned lines;       /* lines printed in it */
	unsigned dropped;     /* lines dropped since the last one printed */
	double since;         /* when the first of them was dropped */
};

/**
 * Lines a second that each rl_log_limited call site may print (default 10;
 * 0: no limit). The lines past it are counted, and the next line printed
 * says how many were dropped.
 */
void rl_log_set_rate(unsigned per_second);

void rl_log_limited_(struct rl_log_limit *limit, enum rl_log_level level, const char *file,
		     int line, const char *fmt, ...) __attribute__((format(printf, 5, 6)));

/**
 * rl_log for lines that outside input can repeat at will (a line per client
 * or per message): at most the rate of rl_log_set_rate a second from this
 * call site, whatever the number of clients. Thread-safe.
 */
#define rl_log_limited(level, ...)                                                          \
	do {                                                                                \
		static struct rl_log_limit rl_log_limit_;                                   \
		rl_log_limited_(&rl_log_limit_, (level), __FILE__, __LINE__, __VA_ARGS__); \
	} while (0)

#endif

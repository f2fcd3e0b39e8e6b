/*
 * The shading warnings of a process, printed once each: every thread's
 * executors of a program, and every shader instance, warn at the same
 * places (exec.c's report). A warning is known by its text, "FILE:LINE:COL:
 * warning: MESSAGE"; up to MAX_WARNED of them are remembered, and past that
 * they are printed each time.
 */
#include "exec_impl.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_WARNED = 4096 };

static pthread_mutex_t warned_lock = PTHREAD_MUTEX_INITIALIZER;
static char *warned_lines[2 * MAX_WARNED];   /* open addressing, by the text's hash */
static size_t nwarned;
static uint64_t warned_printed, warned_repeats;

/* Was @line seen already? Records it if not. Under warned_lock. */
static bool seen(const char *line)
{
	uint64_t h = 1469598103934665603u;
	for (const char *c = line; *c; c++)
		h = (h ^ (unsigned char)*c) * 1099511628211u;
	size_t mask = 2 * MAX_WARNED - 1;
	for (size_t i = (size_t)h & mask;; i = (i + 1) & mask) {
		if (!warned_lines[i]) {
			if (nwarned < MAX_WARNED) {
				char *copy = strdup(line);
				if (copy) {
					warned_lines[i] = copy;
					nwarned++;
				}
			}
			return false;
		}
		if (strcmp(warned_lines[i], line) == 0)
			return true;
	}
}

bool sl_exec_warning_seen(const char *line)
{
	pthread_mutex_lock(&warned_lock);
	bool repeat = seen(line);
	warned_repeats += repeat;
	warned_printed += !repeat;
	pthread_mutex_unlock(&warned_lock);
	return repeat;
}

void sl_exec_warning_counts(uint64_t *printed, uint64_t *repeats)
{
	pthread_mutex_lock(&warned_lock);
	*printed = warned_printed;
	*repeats = warned_repeats;
	pthread_mutex_unlock(&warned_lock);
}

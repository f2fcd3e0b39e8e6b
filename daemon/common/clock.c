/*
 * Clocks for timing work: see clock.h.
 */
#include "clock.h"

#include <time.h>

static double clock_ms(clockid_t c)
{
	struct timespec t;
	clock_gettime(c, &t);
	return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

double rl_now_ms(void)
{
	return clock_ms(CLOCK_MONOTONIC);
}

double rl_thread_cpu_ms(void)
{
	return clock_ms(CLOCK_THREAD_CPUTIME_ID);
}

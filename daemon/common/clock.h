/*
 * Clocks for timing work: the monotonic wall clock and the calling thread's
 * CPU time, in milliseconds.
 */
#ifndef RL_CLOCK_H
#define RL_CLOCK_H

/** Milliseconds of the monotonic clock (an arbitrary origin: take differences). */
double rl_now_ms(void);

/** Milliseconds of CPU time the calling thread has used. */
double rl_thread_cpu_ms(void);

#endif

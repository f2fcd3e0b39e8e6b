/*
 * A minimal test harness. Each test file defines test functions and lists
 * them in main() with RUN(fn). Checks print "file:line: check failed: ..."
 * and the program exits 1 if any failed (77 for a skip, as meson expects).
 */
#ifndef RL_TEST_H
#define RL_TEST_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int test_failures;
static int test_checks;
static const char *test_current = "";

#define CHECK(cond) \
	do { \
		test_checks++; \
		if (!(cond)) { \
			test_failures++; \
			fprintf(stderr, "%s:%d: [%s] check failed: %s\n", __FILE__, __LINE__, \
				test_current, #cond); \
		} \
	} while (0)

/** |a - b| <= tol (absolute). */
#define CHECK_NEAR(a, b, tol) \
	do { \
		double a_ = (a), b_ = (b), t_ = (tol); \
		test_checks++; \
		if (!(fabs(a_ - b_) <= t_)) { \
			test_failures++; \
			fprintf(stderr, "%s:%d: [%s] %s = %.9g, expected %s = %.9g (tolerance %g)\n", \
				__FILE__, __LINE__, test_current, #a, a_, #b, b_, t_); \
		} \
	} while (0)

#define CHECK_STR(a, b) \
	do { \
		const char *a_ = (a), *b_ = (b); \
		test_checks++; \
		if (!a_ || !b_ || strcmp(a_, b_) != 0) { \
			test_failures++; \
			fprintf(stderr, "%s:%d: [%s] %s = \"%s\", expected \"%s\"\n", __FILE__, \
				__LINE__, test_current, #a, a_ ? a_ : "(null)", b_ ? b_ : "(null)"); \
		} \
	} while (0)

#define RUN(fn) \
	do { \
		test_current = #fn; \
		fn(); \
	} while (0)

/** Print the summary and return the exit status for main(). */
static inline int test_finish(void)
{
	printf("%d checks, %d failed\n", test_checks, test_failures);
	return test_failures ? 1 : 0;
}

static inline const char *test_fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));

/* printf into one of four rotating static buffers, for paths and RIB text. */
static inline const char *test_fmt(const char *f, ...)
{
	static char bufs[4][512];
	static int k;
	char *b = bufs[k++ & 3];
	va_list ap;
	va_start(ap, f);
	vsnprintf(b, sizeof(bufs[0]), f, ap);
	va_end(ap);
	return b;
}

#endif

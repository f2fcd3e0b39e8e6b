/*
 * relightd's metrics: latencies land in the right buckets (edges
 * included), the exposition is well-formed Prometheus text line by line,
 * every family is announced by HELP and TYPE before its samples, and
 * concurrent updates from several threads are all counted.
 */
#include "server/metrics.h"
#include "test.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The value of the sample line "@name @value" in @text (-1 when absent). */
static double sample(const char *text, const char *name)
{
	size_t n = strlen(name);
	for (const char *p = text; p && *p; p = strchr(p, '\n'), p = p ? p + 1 : NULL) {
		if (!strncmp(p, name, n) && p[n] == ' ')
			return strtod(p + n + 1, NULL);
	}
	return -1;
}

static bool is_name_char(char c, bool first)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':' ||
	       (!first && c >= '0' && c <= '9');
}

/* A metric name at @p: its length, 0 when none. */
static size_t name_len(const char *p)
{
	size_t n = 0;
	while (is_name_char(p[n], n == 0))
		n++;
	return n;
}

struct family {
	char name[128];
	char type[16];
	bool help;
	int samples;
};

/*
 * Check every line of @text against the text format: "# HELP name text",
 * "# TYPE name type" or "name[{label="value",...}] value". Returns the
 * number of families, or -1 after reporting the first bad line.
 */
static int check_format(const char *text, struct family *fam, int maxfam)
{
	int nfam = 0, lineno = 0;
	const char *p = text;
	CHECK(text[0] && text[strlen(text) - 1] == '\n');
	while (*p) {
		lineno++;
		const char *nl = strchr(p, '\n');
		if (!nl) {
			fprintf(stderr, "  line %d: no newline at the end\n", lineno);
			return -1;
		}
		char line[512];
		size_t len = (size_t)(nl - p);
		if (len >= sizeof(line)) {
			fprintf(stderr, "  line %d: too long\n", lineno);
			return -1;
		}
		memcpy(line, p, len);
		line[len] = '\0';
		p = nl + 1;
		if (!strncmp(line, "# HELP ", 7) || !strncmp(line, "# TYPE ", 7)) {
			const char *nm = line + 7;
			size_t n = name_len(nm);
			if (!n || nm[n] != ' ' || !nm[n + 1] || strncmp(nm, "relight_", 8) ||
			    n >= sizeof(fam[0].name)) {
				fprintf(stderr, "  line %d: bad comment '%s'\n", lineno, line);
				return -1;
			}
			struct family *f = nfam ? &fam[nfam - 1] : NULL;
			if (line[2] == 'H') {
				/* HELP opens a new family: a name not seen before. */
				for (int i = 0; i < nfam; i++)
					if (strlen(fam[i].name) == n && !strncmp(fam[i].name, nm, n)) {
						fprintf(stderr, "  line %d: family again\n", lineno);
						return -1;
					}
				if (nfam == maxfam)
					return -1;
				f = &fam[nfam++];
				memset(f, 0, sizeof(*f));
				memcpy(f->name, nm, n);
				f->help = true;
			} else {
				const char *type = nm + n + 1;
				if (!f || strlen(f->name) != n || strncmp(f->name, nm, n) ||
				    f->type[0] || f->samples ||
				    (strcmp(type, "counter") && strcmp(type, "gauge") &&
				     strcmp(type, "histogram"))) {
					fprintf(stderr, "  line %d: TYPE out of place '%s'\n", lineno,
						line);
					return -1;
				}
				snprintf(f->type, sizeof(f->type), "%s", type);
			}
			continue;
		}
		if (line[0] == '#') {
			fprintf(stderr, "  line %d: unknown comment '%s'\n", lineno, line);
			return -1;
		}
		/* A sample: name, labels, a space, a value that parses whole. */
		size_t n = name_len(line);
		const char *q = line + n;
		if (!n || strncmp(line, "relight_", 8)) {
			fprintf(stderr, "  line %d: bad name '%s'\n", lineno, line);
			return -1;
		}
		if (*q == '{') {
			q++;
			while (*q != '}') {
				size_t ln = name_len(q);
				if (!ln || q[ln] != '=' || q[ln + 1] != '"') {
					fprintf(stderr, "  line %d: bad label '%s'\n", lineno, line);
					return -1;
				}
				q += ln + 2;
				while (*q && *q != '"')
					q += *q == '\\' && q[1] ? 2 : 1;
				if (*q != '"') {
					fprintf(stderr, "  line %d: open label '%s'\n", lineno, line);
					return -1;
				}
				q++;
				if (*q == ',')
					q++;
				else if (*q != '}') {
					fprintf(stderr, "  line %d: bad labels '%s'\n", lineno, line);
					return -1;
				}
			}
			q++;
		}
		char *end;
		if (*q != ' ' || !q[1]) {
			fprintf(stderr, "  line %d: no value '%s'\n", lineno, line);
			return -1;
		}
		strtod(q + 1, &end);
		if (*end || end == q + 1) {
			fprintf(stderr, "  line %d: bad value '%s'\n", lineno, line);
			return -1;
		}
		/* It belongs to the current family, after its TYPE. */
		struct family *f = nfam ? &fam[nfam - 1] : NULL;
		size_t fl = f ? strlen(f->name) : 0;
		const char *suffix = line + fl;
		bool belongs = f && f->type[0] && !strncmp(line, f->name, fl) &&
			       (fl == n || (!strcmp(f->type, "histogram") &&
					    ((n == fl + 7 && !strncmp(suffix, "_bucket", 7)) ||
					     (n == fl + 4 && !strncmp(suffix, "_sum", 4)) ||
					     (n == fl + 6 && !strncmp(suffix, "_count", 6)))));
		if (!belongs) {
			fprintf(stderr, "  line %d: sample outside its family '%s'\n", lineno, line);
			return -1;
		}
		f->samples++;
	}
	return nfam;
}

static void test_format(void)
{
	struct srv_metrics m;
	srv_metrics_init(&m);
	atomic_store(&m.clients, 3);
	atomic_store(&m.gpu_bytes, 123456789012);
	atomic_store(&m.edits, 42);
	atomic_store(&m.tiles_sent, 7);
	atomic_store(&m.refused, 2);
	srv_metrics_latency(&m, 0.003);
	char *text = srv_metrics_text(&m);
	CHECK(text != NULL);
	if (!text)
		return;
	struct family fam[64];
	int n = check_format(text, fam, 64);
	CHECK(n == 17);
	int counters = 0, gauges = 0, histograms = 0;
	for (int i = 0; i < n; i++) {
		CHECK(fam[i].help && fam[i].type[0] && fam[i].samples > 0);
		size_t len = strlen(fam[i].name);
		bool total = len > 6 && !strcmp(fam[i].name + len - 6, "_total");
		if (!strcmp(fam[i].type, "counter")) {
			counters++;
			CHECK(total && fam[i].samples == 1);
		} else if (!strcmp(fam[i].type, "gauge")) {
			gauges++;
			CHECK(!total && fam[i].samples == 1);
		} else {
			histograms++;
			CHECK(fam[i].samples == SRV_LATENCY_BUCKETS + 3);
		}
	}
	CHECK(counters == 13 && gauges == 3 && histograms == 1);
	CHECK(sample(text, "relight_clients") == 3);
	CHECK(sample(text, "relight_shots_resident") == 0);
	CHECK(sample(text, "relight_gpu_bytes") == 123456789012.0);
	CHECK(sample(text, "relight_edits_total") == 42);
	CHECK(sample(text, "relight_tiles_sent_total") == 7);
	CHECK(sample(text, "relight_connections_refused_total") == 2);
	CHECK(sample(text, "relight_connections_total") == 0);
	CHECK(strstr(text, "# TYPE relight_edit_first_tile_seconds histogram\n") != NULL);
	CHECK(strstr(text, "# TYPE relight_edits_total counter\n") != NULL);
	CHECK(strstr(text, "# TYPE relight_clients gauge\n") != NULL);
	free(text);

	/* A gauge briefly below zero (a decrement seen before its increment) still parses. */
	atomic_store(&m.clients, -1);
	text = srv_metrics_text(&m);
	CHECK(check_format(text, fam, 64) == 17);
	CHECK(sample(text, "relight_clients") == -1);
	free(text);
}

static void test_histogram(void)
{
	/* The bounds are the documented ones, ascending. */
	const double want[SRV_LATENCY_BUCKETS] = { 0.001, 0.002, 0.005, 0.01, 0.02, 0.04,
						   0.06,  0.1,   0.25,  0.5,  1,    2.5 };
	for (int i = 0; i < SRV_LATENCY_BUCKETS; i++)
		CHECK(srv_latency_bounds[i] == want[i]);

	struct srv_metrics m;
	srv_metrics_init(&m);
	/*
	 * Samples: each bound exactly (le is inclusive), just above some,
	 * beyond the last (only +Inf), and nonsense (negative, NaN: counted as 0).
	 */
	const double samples[] = { 0.001, 0.0005, 0.0011, 0.002, 0.0049, 0.04, 0.0401,
				   0.1,   0.3,    1.0,    2.5,   2.6,    10.0, -0.5, NAN };
	double sum = 0;
	for (size_t i = 0; i < sizeof(samples) / sizeof(samples[0]); i++) {
		srv_metrics_latency(&m, samples[i]);
		if (samples[i] > 0)
			sum += samples[i];
	}
	/* Cumulative: <=0.001: 0.001, 0.0005, -0.5, NaN. */
	const char *lines[] = {
		"relight_edit_first_tile_seconds_bucket{le=\"0.001\"} 4\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.002\"} 6\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.005\"} 7\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.01\"} 7\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.02\"} 7\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.04\"} 8\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.06\"} 9\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.1\"} 10\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.25\"} 10\n",
		"relight_edit_first_tile_seconds_bucket{le=\"0.5\"} 11\n",
		"relight_edit_first_tile_seconds_bucket{le=\"1\"} 12\n",
		"relight_edit_first_tile_seconds_bucket{le=\"2.5\"} 13\n",
		"relight_edit_first_tile_seconds_bucket{le=\"+Inf\"} 15\n",
		"relight_edit_first_tile_seconds_sum 16.589600\n",
		"relight_edit_first_tile_seconds_count 15\n",
	};
	CHECK_NEAR(sum, 16.5896, 1e-9);
	char *text = srv_metrics_text(&m);
	CHECK(text != NULL);
	if (!text)
		return;
	/* The histogram's lines, in this order, one after another. */
	const char *p = strstr(text, lines[0]);
	CHECK(p != NULL);
	for (size_t i = 0; p && i < sizeof(lines) / sizeof(lines[0]); i++) {
		size_t n = strlen(lines[i]);
		CHECK(!strncmp(p, lines[i], n));
		if (strncmp(p, lines[i], n)) {
			fprintf(stderr, "  expected %s  got      %.*s\n", lines[i],
				(int)(strcspn(p, "\n") + 1), p);
			break;
		}
		p += n;
	}
	CHECK(atomic_load(&m.latency_sum_us) == 16589600);
	free(text);

	/* A sample too large for the microsecond sum is capped, not wrapped. */
	srv_metrics_init(&m);
	srv_metrics_latency(&m, 1e300);
	srv_metrics_latency(&m, 1e300);
	CHECK(atomic_load(&m.latency_sum_us) == 2000000000000ull);
	CHECK(atomic_load(&m.latency_count) == 2);

	/* A scrape between a worker's bucket and count updates still has +Inf == _count >= buckets. */
	srv_metrics_init(&m);
	atomic_store(&m.latency_bucket[0], 5);
	atomic_store(&m.latency_count, 3);
	text = srv_metrics_text(&m);
	CHECK(strstr(text, "_bucket{le=\"2.5\"} 5\n") && strstr(text, "_bucket{le=\"+Inf\"} 5\n") &&
	      strstr(text, "relight_edit_first_tile_seconds_count 5\n"));
	free(text);
}

#define THREADS 4
#define PER_THREAD 20000

static void *hammer(void *arg)
{
	struct srv_metrics *m = arg;
	for (int i = 0; i < PER_THREAD; i++) {
		atomic_fetch_add_explicit(&m->edits, 1, memory_order_relaxed);
		atomic_fetch_add_explicit(&m->clients, 1, memory_order_relaxed);
		atomic_fetch_sub_explicit(&m->clients, 1, memory_order_relaxed);
		srv_metrics_latency(m, (i % 4) * 0.01); /* 0, 0.01, 0.02, 0.03 */
		if (i % 1000 == 0)
			free(srv_metrics_text(m));
	}
	return NULL;
}

static void test_threads(void)
{
	struct srv_metrics m;
	srv_metrics_init(&m);
	pthread_t th[THREADS];
	int started = 0;
	for (int i = 0; i < THREADS; i++)
		if (pthread_create(&th[i], NULL, hammer, &m) == 0)
			started++;
	CHECK(started == THREADS);
	for (int i = 0; i < started; i++)
		pthread_join(th[i], NULL);
	uint64_t n = (uint64_t)started * PER_THREAD;
	CHECK(atomic_load(&m.edits) == n);
	CHECK(atomic_load(&m.clients) == 0);
	CHECK(atomic_load(&m.latency_count) == n);
	CHECK(atomic_load(&m.latency_bucket[0]) == n / 4);  /* 0 */
	CHECK(atomic_load(&m.latency_bucket[3]) == n / 4);  /* 0.01 */
	CHECK(atomic_load(&m.latency_bucket[4]) == n / 4);  /* 0.02 */
	CHECK(atomic_load(&m.latency_bucket[5]) == n / 4);  /* 0.03 <= 0.04 */
	CHECK(atomic_load(&m.latency_sum_us) == n / 4 * (10000 + 20000 + 30000));
	char *text = srv_metrics_text(&m);
	char line[128];
	snprintf(line, sizeof(line), "relight_edit_first_tile_seconds_count %llu\n",
		 (unsigned long long)n);
	CHECK(strstr(text, line) != NULL);
	snprintf(line, sizeof(line), "relight_edits_total %llu\n", (unsigned long long)n);
	CHECK(strstr(text, line) != NULL);
	free(text);
}

int main(void)
{
	RUN(test_format);
	RUN(test_histogram);
	RUN(test_threads);
	return test_finish();
}

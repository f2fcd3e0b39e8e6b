/*
 * Edit-to-tile latency through relightd, as a client sees it: from the
 * moment an edit is sent to the moment the first tile of that edit (its
 * coarsest level) is read off the client's socket. Used by `relight bench`
 * and by tests/bench/bench_latency.
 *
 * relightd (the executable @relightd) is started on 127.0.0.1 with a free
 * port on a folder of shot files. For each shot one editor client opens it
 * (rgba8 tiles) and makes @edits edits of one light's intensity (or its
 * position), alternating between two values, each time waiting for the
 * final level before the next; a few edits before are not counted (the
 * first edit of a light takes it out of the light cache). Then, with
 * @viewers > 0, the same with that many more clients, each on its own
 * thread and connection, that have the shot open and read every tile.
 *
 * relightd's stderr goes to a log in a fresh folder of $TMPDIR (or /tmp),
 * removed after the call unless it failed once the daemon was running
 * (then the log's path is printed on opts.log). The daemon is always
 * stopped and waited for before latency_run returns.
 *
 * SIGPIPE is ignored while latency_run runs (libwebsockets ignores it on
 * its own anyway whenever a connection is made) and its disposition is put
 * back as it was on return; relightd starts with the caller's disposition.
 * Since that is process-wide, a caller whose other threads rely on SIGPIPE
 * meanwhile should ignore it itself.
 */
#ifndef BENCH_LATENCY_H
#define BENCH_LATENCY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

struct latency_opts {
	const char *relightd;        /* the daemon's executable */
	const char *shots;           /* folder of NAME.shot.exr files (and their textures) */
	const char *const *names;    /* NULL: every shot of the folder; else these NAMEs */
	size_t nnames;
	int edits;                   /* 0: 60; else 1 to 10000 */
	int viewers;                 /* extra clients of the second run (at most 256);
					0: none, no second run */
	bool move;                   /* edit "from" instead of "intensity" */
	FILE *log;                   /* progress (lines that start "latency: "); NULL: stderr */
};

/** One row: a shot with one client or with 1 + viewers. */
struct latency_row {
	char shot[128];
	int clients;
	int edits;
	double median, p99, final_median;   /* the editor's, ms */
	double viewer_median, viewer_p99;   /* the viewers' (clients > 1), ms */
	int not_level0;                     /* edits whose first tile was not level 0 */
	bool ok;                            /* latency_meets_targets */
};

/** Targets: one client median <= 20 ms and p99 <= 60 ms; with 16 clients median <= 40 ms. */
bool latency_meets_targets(const struct latency_row *r);

/**
 * Run the measurement. Returns the rows written to @rows (at most @cap), or
 * -1 with the reason in @err when it could not run (daemon would not start,
 * a connection or timeout failed), or -77 when relightd has no GPU context.
 * Each shot gives one row, two with viewers, in shot order (the folder's
 * sorted, or @names's, each of which must have its file); a @cap too
 * small for them all is an error, found before the daemon starts. After
 * -1, the rows measured before the failure are still there: the first rows
 * whose clients is not 0 (latency_run zeroes all @cap rows first).
 */
int latency_run(const struct latency_opts *o, struct latency_row *rows, int cap, char *err,
		size_t errlen);

#endif

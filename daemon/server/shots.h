/*
 * The shots relightd serves: the shot files under --shots, named by their
 * file name without ".shot.exr" (or ".exr"), and the RIB scenes there, which
 * are baked on demand into shot files in the same folder. Names are confined
 * to that folder: a name is letters, digits, '_', '-' and '.', at most 128
 * bytes, not starting with '.', so "../x", "a/b" or an absolute path never
 * reach the file system.
 *
 * Thread-safe: the service thread lists and resolves, bake threads bake.
 */
#ifndef SRV_SHOTS_H
#define SRV_SHOTS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define SRV_SHOT_NAME_MAX 128

struct srv_shots;

struct srv_shot_entry {
	char name[SRV_SHOT_NAME_MAX + 1];
	uint32_t width, height;   /* 0 for a RIB not baked yet */
	bool baked;               /* a shot file exists (and is newer than its RIB, if any) */
	bool has_rib;             /* a RIB of that name exists */
};

/** Whether @name is a valid shot name (see above). */
bool srv_shot_name_ok(const char *name);

/** Open the registry of folder @dir. NULL with the reason in @err if it is no readable folder. */
struct srv_shots *srv_shots_open(const char *dir, char *err, size_t errlen);
void srv_shots_close(struct srv_shots *r);

/**
 * Scan the folder now (shot files' sizes read from their headers, cached by
 * modification time). Fills up to @cap entries sorted by name; returns how
 * many shots there are (may exceed @cap).
 */
size_t srv_shots_list(struct srv_shots *r, struct srv_shot_entry *out, size_t cap);

enum srv_shot_state {
	SRV_SHOT_INVALID,      /* a bad name */
	SRV_SHOT_MISSING,      /* neither a shot file nor a RIB of that name */
	SRV_SHOT_READY,        /* a shot file, up to date: *path set */
	SRV_SHOT_NEEDS_BAKE,   /* a RIB and no shot file, or one older than the RIB */
};

/** Where shot @name is: its shot file's path in @path (@cap bytes) when READY. */
enum srv_shot_state srv_shots_find(struct srv_shots *r, const char *name, char *path,
				   size_t cap);

/** Progress of a bake: @fraction in [0, 1], @what a short phrase ("rendering", "writing"). */
typedef void (*srv_bake_progress_fn)(void *user, double fraction, const char *what);

/**
 * Bake RIB @name into its shot file (written atomically: a temporary file
 * renamed into place). Blocks; call it off the service thread. If another
 * thread is baking the same name, waits for that bake instead of baking
 * twice. True with the shot file's path in @path; false with the reason
 * (the RIB's file and line for scene errors) in @err.
 */
bool srv_shots_bake(struct srv_shots *r, const char *name, srv_bake_progress_fn progress,
		    void *user, char *path, size_t cap, char *err, size_t errlen);

/*
 * More on srv_shots_bake: a shot already up to date (READY) is not baked
 * again (progress reports 1 at once), so callers that raced past
 * srv_shots_find bake it once. @progress runs on the calling thread, with
 * fractions that never decrease: from 0 to 1 for a successful bake; a
 * caller waiting for another's bake follows that bake's progress. The
 * scene's own relative file names (shadow maps, textures) are relative to
 * the process's working directory, as for `relight bake`.
 * srv_shots_close() must wait until every bake has returned.
 */

/** How many bakes this registry has started (whatever their outcome): for metrics and tests. */
uint64_t srv_shots_bakes_run(struct srv_shots *r);

#endif

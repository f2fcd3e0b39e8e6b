/*
 * Files: atomic writes, bounded reads, content hashes, and relight's cache
 * directory. Nothing is lost: a write goes to a temporary file in the target's
 * directory, is flushed to disk, and is renamed over the target, so a crash
 * mid-write leaves the old file intact.
 */
#ifndef RL_FILEUTIL_H
#define RL_FILEUTIL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/types.h>

/**
 * A file being written atomically: open it next to its target, write through
 * @fd (or the FILE of rl_atomic_stdio), then commit (rename over the target)
 * or abort (the temporary goes, the old file stays).
 */
struct rl_atomic {
	int fd;              /* the temporary file; -1 once closed */
	FILE *fp;            /* set by rl_atomic_stdio, which then owns @fd */
	char *tmp;           /* its name: PATH.tmp.XXXXXX */
	char *path;
};

/**
 * Create the temporary file for @path in the same directory, with the old
 * file's mode (else 0666 minus the umask). False with errno set.
 */
bool rl_atomic_open(struct rl_atomic *a, const char *path);

/** A stdio stream over the temporary file (NULL with errno set). */
FILE *rl_atomic_stdio(struct rl_atomic *a);

/**
 * Flush, fsync and close the temporary file, rename it over the target and
 * sync the directory. False with errno set; the temporary is removed either way.
 */
bool rl_atomic_commit(struct rl_atomic *a);

/** Close and remove the temporary file (after a failed write). Accepts a closed one. */
void rl_atomic_abort(struct rl_atomic *a);

/**
 * Remove what writers killed mid-write left in folder @dir: the temporary
 * files of atomic writes, named TARGET.tmp.PID.SUFFIX (PID the writer's
 * process id, SUFFIX letters and digits; rl_atomic_open names them so),
 * whose TARGET is @prefix or a temporary of it (NULL: any), whose writer is not a live
 * process, and which are regular files (links and folders stay). A file of
 * this process's own pid counts as stale (a pid is reused, e.g. in a
 * container): call it before this process writes in @dir. Nothing else is
 * touched, nothing below @dir. Returns how many were removed.
 */
size_t rl_remove_stale_temps(const char *dir, const char *prefix);

/** pwrite() all of @len bytes at @offset, retrying on EINTR: 0, or the errno. */
int rl_pwrite_all(int fd, const void *data, size_t len, off_t offset);

/**
 * Write @len bytes to @path atomically (temporary file, fsync, rename). On
 * failure returns false with "PATH: reason" in @err (always NUL-terminated
 * when @errlen > 0) and leaves any old file at @path untouched.
 */
bool rl_write_file_atomic(const char *path, const void *data, size_t len, char *err,
			  size_t errlen);

/**
 * Read the whole file at @path (at most @maxlen bytes; larger files fail) into
 * a malloc'd buffer with a NUL byte after its end. NULL on failure, with the
 * reason in @err.
 */
char *rl_read_file(const char *path, size_t maxlen, size_t *len, char *err, size_t errlen);

/**
 * @path made absolute against the current directory (a leading "./"
 * dropped), malloc'd; an absolute path is copied. NULL when out of memory
 * or the current directory cannot be read.
 */
char *rl_path_absolute(const char *path);

/**
 * @path as seen from folder @dir ("../shaders/key.sl"), malloc'd: both made
 * absolute (rl_path_absolute), compared name by name ("." names skipped;
 * "..", and links, taken as names).
 * NULL when out of memory or the current directory cannot be read.
 */
char *rl_path_relative(const char *path, const char *dir);

/** Create directory @path and its missing parents (mode 0777 & ~umask). */
bool rl_mkdir_p(const char *path);

/** Copy the file @from to @to (created or truncated, mode 0644). False with errno set. */
bool rl_copy_file(const char *from, const char *to);

/**
 * Remove @dir with everything below it (links are removed, not followed).
 * Best effort: what cannot be removed stays.
 */
void rl_remove_tree(const char *dir);

/**
 * relight's cache directory for @what (a subdirectory name such as "gl"),
 * malloc'd, created if missing: $RELIGHT_CACHE_DIR/@what, else
 * $XDG_CACHE_HOME/relight/@what, else $HOME/.cache/relight/@what. NULL when
 * caching is off (RELIGHT_CACHE_DIR set to "" or "off") or no directory can
 * be made.
 */
char *rl_cache_dir(const char *what);

/** A 128-bit content hash, streamed: init, add bytes any number of times, finish. */
struct rl_hash128 {
	uint64_t a, b;
	uint64_t len;
};
void rl_hash128_init(struct rl_hash128 *h);
void rl_hash128_add(struct rl_hash128 *h, const void *data, size_t len);
/** Add a NUL-terminated string and its terminator (so "ab","c" differs from "a","bc"). */
void rl_hash128_str(struct rl_hash128 *h, const char *s);
/** The hash as 32 lowercase hex digits and a NUL. */
void rl_hash128_hex(const struct rl_hash128 *h, char out[33]);

#endif

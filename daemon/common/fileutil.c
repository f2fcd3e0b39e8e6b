/* Atomic writes, bounded reads, content hashes and the cache directory. */
#include "fileutil.h"
#include "arena.h"

#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <fcntl.h>
#include <signal.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void set_err(char *err, size_t errlen, const char *path, const char *what)
{
	if (err && errlen)
		snprintf(err, errlen, "%s: %s", path, what);
}

/* The umask, read once: reading it means setting it, which must not race
 * with another thread's file creation (the daemon bakes on several). */
static mode_t umask_value;
static void read_umask(void)
{
	umask_value = umask(0);
	umask(umask_value);
}

static mode_t process_umask(void)
{
	static pthread_once_t once = PTHREAD_ONCE_INIT;
	pthread_once(&once, read_umask);
	return umask_value;
}

bool rl_atomic_open(struct rl_atomic *a, const char *path)
{
	memset(a, 0, sizeof(*a));
	a->fd = -1;
	size_t n = strlen(path);
	a->path = rl_xstrdup(path);
	/* PATH.tmp.PID.XXXXXX: the writer's pid tells a stale one (rl_remove_stale_temps) */
	size_t cap = n + 64;
	a->tmp = rl_xmalloc(cap);
	snprintf(a->tmp, cap, "%s.tmp.%ld.XXXXXX", path, (long)getpid());
	a->fd = mkstemp(a->tmp);
	if (a->fd < 0) {
		int e = errno;
		free(a->path);
		free(a->tmp);
		a->path = a->tmp = NULL;
		errno = e;
		return false;
	}
	/* mkstemp makes the file private: give it the old file's mode, or the usual one */
	struct stat st;
	mode_t mask = process_umask();
	mode_t mode = stat(path, &st) == 0 && S_ISREG(st.st_mode) ? (st.st_mode & 07777)
								   : (0666 & ~mask);
	if (fchmod(a->fd, mode) != 0) {
		int e = errno;
		rl_atomic_abort(a);
		errno = e;
		return false;
	}
	return true;
}

FILE *rl_atomic_stdio(struct rl_atomic *a)
{
	if (!a->fp && a->fd >= 0)
		a->fp = fdopen(a->fd, "wb");
	return a->fp;
}

/* Flush the directory entry of @path's directory (best effort). */
static void sync_dir(const char *path)
{
	const char *slash = strrchr(path, '/');
	char *dir = NULL;
	if (slash) {
		size_t n = slash == path ? 1 : (size_t)(slash - path);
		dir = malloc(n + 1);
		if (!dir)
			return;
		memcpy(dir, path, n);
		dir[n] = '\0';
	}
	int fd = open(dir ? dir : ".", O_RDONLY);
	if (fd >= 0) {
		fsync(fd);
		close(fd);
	}
	free(dir);
}

/* Close the temporary file; 0 or the first errno. */
static int close_tmp(struct rl_atomic *a, bool sync)
{
	int failure = 0;
	if (a->fp) {
		if (fflush(a->fp) != 0)
			failure = errno ? errno : EIO;
		if (!failure && sync && fsync(fileno(a->fp)) != 0)
			failure = errno;
		if (fclose(a->fp) != 0 && !failure)
			failure = errno ? errno : EIO;
	} else if (a->fd >= 0) {
		if (sync && fsync(a->fd) != 0)
			failure = errno;
		if (close(a->fd) != 0 && !failure)
			failure = errno;
	}
	a->fp = NULL;
	a->fd = -1;
	return failure;
}

static void release(struct rl_atomic *a)
{
	free(a->tmp);
	free(a->path);
	a->tmp = a->path = NULL;
}

bool rl_atomic_commit(struct rl_atomic *a)
{
	if (!a->tmp) {
		errno = EBADF;
		return false;
	}
	int failure = close_tmp(a, true);
	if (!failure && rename(a->tmp, a->path) != 0)
		failure = errno;
	if (failure)
		unlink(a->tmp);
	else
		sync_dir(a->path);
	release(a);
	errno = failure;
	return !failure;
}

void rl_atomic_abort(struct rl_atomic *a)
{
	int e = errno;
	close_tmp(a, false);
	if (a->tmp)
		unlink(a->tmp);
	release(a);
	errno = e;
}

/*
 * The writer's pid if @name is a temporary file of an atomic write of a file
 * named @prefix (NULL: any), or of a temporary file of one:
 *   name := target ".tmp." digits "." alnum+      (the last ".tmp." in it)
 * 0 if it is not one.
 */
static long temp_writer(const char *name, const char *prefix)
{
	const char *t = NULL;
	for (const char *p = strstr(name, ".tmp."); p; p = strstr(p + 1, ".tmp."))
		t = p;
	if (!t || t == name)
		return 0;
	size_t np = prefix ? strlen(prefix) : 0;
	if (prefix && (strncmp(name, prefix, np) || name[np] != '.' || (size_t)(t - name) < np))
		return 0;
	const char *d = t + 5, *e = d;
	long pid = 0;
	while (*e >= '0' && *e <= '9' && e - d < 10)
		pid = pid * 10 + (*e++ - '0');
	if (e == d || *e != '.' || !e[1] || pid <= 0)
		return 0;
	for (const char *c = e + 1; *c; c++)
		if (!((*c >= '0' && *c <= '9') || (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z')))
			return 0;
	return pid;
}

/* Whether process @pid may still be writing: alive, and not this process. */
static bool writer_alive(long pid)
{
	if ((pid_t)pid == getpid())
		return false;
	return kill((pid_t)pid, 0) == 0 || errno == EPERM;
}

size_t rl_remove_stale_temps(const char *dir, const char *prefix)
{
	DIR *d = opendir(dir && *dir ? dir : ".");
	if (!d)
		return 0;
	size_t removed = 0;
	for (struct dirent *e; (e = readdir(d));) {
		long pid = temp_writer(e->d_name, prefix);
		struct stat st;
		if (!pid || fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 ||
		    !S_ISREG(st.st_mode) || writer_alive(pid))
			continue;
		if (unlinkat(dirfd(d), e->d_name, 0) == 0)
			removed++;
	}
	closedir(d);
	return removed;
}

int rl_pwrite_all(int fd, const void *data, size_t len, off_t offset)
{
	const char *p = data;
	while (len > 0) {
		size_t chunk = len > ((size_t)1 << 30) ? (size_t)1 << 30 : len;
		ssize_t w = pwrite(fd, p, chunk, offset);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0)
			return w < 0 ? errno : EIO;
		p += w;
		len -= (size_t)w;
		offset += w;
	}
	return 0;
}

bool rl_write_file_atomic(const char *path, const void *data, size_t len, char *err,
			  size_t errlen)
{
	struct rl_atomic a;
	if (!rl_atomic_open(&a, path)) {
		set_err(err, errlen, path, strerror(errno));
		return false;
	}
	int failure = rl_pwrite_all(a.fd, data, len, 0);
	if (failure) {
		rl_atomic_abort(&a);
	} else if (!rl_atomic_commit(&a)) {
		failure = errno;
	}
	if (failure)
		set_err(err, errlen, path, strerror(failure));
	return !failure;
}

char *rl_read_file(const char *path, size_t maxlen, size_t *len, char *err, size_t errlen)
{
	FILE *f = fopen(path, "rb");
	if (!f) {
		set_err(err, errlen, path, strerror(errno));
		return NULL;
	}
	size_t cap = 4096, n = 0;
	char *buf = malloc(cap + 1);
	while (buf) {
		if (n == cap) {
			if (cap >= maxlen) {
				set_err(err, errlen, path, "file too large");
				free(buf);
				buf = NULL;
				break;
			}
			cap = cap * 2 > maxlen ? maxlen : cap * 2;
			char *nb = realloc(buf, cap + 1);
			if (!nb) {
				free(buf);
				buf = NULL;
				break;
			}
			buf = nb;
		}
		size_t r = fread(buf + n, 1, cap - n, f);
		n += r;
		if (r == 0) {
			if (ferror(f)) {
				set_err(err, errlen, path, "read error");
				free(buf);
				buf = NULL;
			}
			break;
		}
	}
	fclose(f);
	if (!buf) {
		if (err && errlen && !err[0])
			set_err(err, errlen, path, "out of memory");
		return NULL;
	}
	buf[n] = '\0';
	if (len)
		*len = n;
	return buf;
}

char *rl_path_absolute(const char *path)
{
	char cwd[4096];
	if (path[0] == '/')
		return strdup(path);
	if (!getcwd(cwd, sizeof(cwd)))
		return NULL;
	if (path[0] == '.' && path[1] == '/')
		path += 2;
	size_t n = strlen(cwd) + strlen(path) + 2;
	char *abs = malloc(n);
	if (abs)
		snprintf(abs, n, "%s/%s", cwd, path);
	return abs;
}

/* The length of the first name of @p (up to a '/' or the end). */
static size_t name_len(const char *p)
{
	const char *s = strchr(p, '/');
	return s ? (size_t)(s - p) : strlen(p);
}

/* @p past its leading slashes and "." names. */
static const char *skip_slashes(const char *p)
{
	for (;;) {
		while (*p == '/')
			p++;
		if (p[0] != '.' || (p[1] != '/' && p[1]))
			return p;
		p++;
	}
}

char *rl_path_relative(const char *path, const char *dir)
{
	char *a = rl_path_absolute(path), *b = rl_path_absolute(dir);
	char *out = NULL;
	if (!a || !b)
		goto done;
	/* the names both start with */
	const char *p = skip_slashes(a), *q = skip_slashes(b);
	for (;;) {
		size_t n = name_len(p), m = name_len(q);
		if (!n || n != m || memcmp(p, q, n))
			break;
		p = skip_slashes(p + n);
		q = skip_slashes(q + m);
	}
	/* one ".." for each name of @dir left, then the rest of @path */
	size_t ups = 0;
	for (const char *r = q; *r; r = skip_slashes(r + name_len(r)))
		ups++;
	size_t cap = ups * 3 + strlen(p) + 2;
	out = malloc(cap);
	if (!out)
		goto done;
	out[0] = '\0';
	for (size_t i = 0; i < ups; i++)
		strcat(out, "../");
	strcat(out, p);
	size_t n = strlen(out);
	if (!n)
		strcpy(out, ".");
	else if (out[n - 1] == '/')
		out[n - 1] = '\0';
done:
	free(a);
	free(b);
	return out;
}

bool rl_mkdir_p(const char *path)
{
	size_t n = strlen(path);
	if (n == 0)
		return false;
	char *p = malloc(n + 1);
	if (!p)
		return false;
	memcpy(p, path, n + 1);
	bool ok = true;
	for (size_t i = 1; i <= n && ok; i++) {
		if (p[i] != '/' && p[i] != '\0')
			continue;
		char c = p[i];
		p[i] = '\0';
		if (mkdir(p, 0777) != 0 && errno != EEXIST)
			ok = false;
		p[i] = c;
	}
	struct stat st;
	ok = ok && stat(path, &st) == 0 && S_ISDIR(st.st_mode);
	free(p);
	return ok;
}

char *rl_cache_dir(const char *what)
{
	const char *root = getenv("RELIGHT_CACHE_DIR");
	const char *suffix = "";
	if (root && (!*root || !strcmp(root, "off")))
		return NULL;
	if (!root || !*root) {
		root = getenv("XDG_CACHE_HOME");
		suffix = "/relight";
		if (!root || root[0] != '/') {
			root = getenv("HOME");
			suffix = "/.cache/relight";
		}
		if (!root || root[0] != '/')
			return NULL;
	}
	size_t n = strlen(root) + strlen(suffix) + strlen(what) + 2;
	char *dir = malloc(n);
	if (!dir)
		return NULL;
	snprintf(dir, n, "%s%s/%s", root, suffix, what);
	if (!rl_mkdir_p(dir)) {
		free(dir);
		return NULL;
	}
	return dir;
}

/* ---- hashing ---- */

/* Two 64-bit lanes with different multipliers, mixed by a strong finalizer. */
static uint64_t mix64(uint64_t x)
{
	x ^= x >> 30;
	x *= 0xbf58476d1ce4e5b9u;
	x ^= x >> 27;
	x *= 0x94d049bb133111ebu;
	x ^= x >> 31;
	return x;
}

void rl_hash128_init(struct rl_hash128 *h)
{
	h->a = 0x6a09e667f3bcc908u;
	h->b = 0xbb67ae8584caa73bu;
	h->len = 0;
}

void rl_hash128_add(struct rl_hash128 *h, const void *data, size_t len)
{
	const unsigned char *p = data;
	for (size_t i = 0; i < len; i++) {
		h->a = (h->a ^ p[i]) * 0x100000001b3u;
		h->b = (h->b + p[i] + 1) * 0x9e3779b97f4a7c15u;
		h->b ^= h->b >> 29;
	}
	h->len += len;
}

void rl_hash128_str(struct rl_hash128 *h, const char *s)
{
	rl_hash128_add(h, s ? s : "", (s ? strlen(s) : 0) + 1);
}

void rl_hash128_hex(const struct rl_hash128 *h, char out[33])
{
	uint64_t a = mix64(h->a ^ mix64(h->len)), b = mix64(h->b ^ a);
	snprintf(out, 33, "%016llx%016llx", (unsigned long long)a, (unsigned long long)b);
}

bool rl_copy_file(const char *from, const char *to)
{
	int in = open(from, O_RDONLY | O_CLOEXEC);
	if (in < 0)
		return false;
	int out = open(to, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
	if (out < 0) {
		int e = errno;
		close(in);
		errno = e;
		return false;
	}
	char buf[65536];
	bool ok = true;
	off_t at = 0;
	for (;;) {
		ssize_t n = read(in, buf, sizeof(buf));
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0) {
			ok = n == 0;
			break;
		}
		int werr = rl_pwrite_all(out, buf, (size_t)n, at);
		if (werr) {
			errno = werr;
			ok = false;
			break;
		}
		at += n;
	}
	int e = errno;
	close(in);
	if (close(out) != 0)
		ok = false;
	else
		errno = e;
	return ok;
}

void rl_remove_tree(const char *dir)
{
	DIR *d = opendir(dir);
	if (d) {
		struct dirent *e;
		while ((e = readdir(d))) {
			if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
				continue;
			char p[PATH_MAX];
			if (snprintf(p, sizeof(p), "%s/%s", dir, e->d_name) >= (int)sizeof(p))
				continue;
			struct stat st;
			if (lstat(p, &st) == 0 && S_ISDIR(st.st_mode))
				rl_remove_tree(p);
			else
				unlink(p);
		}
		closedir(d);
	}
	rmdir(dir);
}

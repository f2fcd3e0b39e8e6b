/*
 * The RIB reader: ASCII RenderMan Interface Bytestream (plain or gzip
 * compressed) to a stream of checked requests. It knows every request's
 * positional arguments (rib.c's table) and checks their count and types; the
 * meaning of requests is the scene builder's (ri.h).
 */
#ifndef RIB_H
#define RIB_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/** Where a request or value was written: file name (owned by the reader) and 1-based line. */
struct rib_loc {
	const char *file;
	uint32_t line;
};

enum rib_vtype {
	RIB_NUMBER,       /* one number */
	RIB_STRING,       /* one string */
	RIB_NUMBERS,      /* [ n1 n2 ... ] (possibly empty) */
	RIB_STRINGS,      /* [ "a" "b" ... ] */
};

/** A value: positional argument or parameter value. Arrays own their storage (reader's arena). */
struct rib_value {
	enum rib_vtype type;
	uint32_t n;            /* element count (1 for NUMBER/STRING) */
	const double *nums;    /* NUMBER, NUMBERS (for NUMBER: &num) */
	const char *const *strs; /* STRING, STRINGS */
	struct rib_loc loc;
};

/** A parameter of a parameter list: "token" value. */
struct rib_param {
	const char *token;     /* as written, e.g. "Kd" or "uniform float Kd" */
	struct rib_value value; /* a single number/string is promoted to a 1-element array */
	struct rib_loc loc;
};

/** Is a request one of the reader's table? */
enum rib_known {
	RIB_KNOWN,             /* a request of the table, its arguments checked */
	RIB_UNSUPPORTED,       /* a request of the RenderMan Interface the table lacks */
	RIB_UNKNOWN,           /* any other name */
	RIB_MALFORMED,         /* a primitive of the table whose arguments were in error */
};

struct rib_request {
	/* canonical name from the table, e.g. "WorldBegin"; as written when not known */
	const char *name;
	struct rib_loc loc;
	const struct rib_value *args;   /* positional arguments, checked against the table */
	uint32_t nargs;
	const struct rib_param *params; /* the parameter list, for requests that take one */
	uint32_t nparams;
	/*
	 * RIB_UNSUPPORTED and RIB_UNKNOWN requests come by name only: their
	 * arguments were read as tokens (lexical errors reported) and skipped,
	 * nargs and nparams are 0. @near: for RIB_UNKNOWN, the known request
	 * whose name is closest (a misspelling), or NULL. RIB_MALFORMED: a
	 * geometric primitive whose arguments or parameter list had an error
	 * (reported), passed by name only so that the handler can drop what it
	 * stood for (a motion block's sample) and go on; such errors do not count
	 * towards max_errors.
	 */
	enum rib_known known;
	const char *near;
};

/**
 * Called for each request in order. Return false to stop reading (the reader
 * then returns false too). The request and its values are valid only during
 * the call.
 */
typedef bool (*rib_handler_fn)(void *user, const struct rib_request *req);

struct rib_reader_opts {
	FILE *diag;            /* diagnostics ("FILE:LINE: error: MESSAGE"); NULL: stderr */
	int max_errors;        /* stop after this many errors; 0: 20 */
	size_t max_array;      /* largest array accepted, in elements; 0: 64M */
};

/**
 * Read the RIB file at @path (gzip-compressed files are recognised by their
 * magic bytes), calling @fn for each request. A name the table lacks (a
 * request relight does not implement, or an unknown one) goes to @fn too, by
 * name only (struct rib_request's known), for the handler to warn about: the
 * reader itself has no warnings. Syntax errors, wrong argument counts or
 * types, NaN/Inf numbers,
 * arrays over max_array and truncated files are reported as
 * "FILE:LINE: error: MESSAGE"; reading skips to the next request and goes on
 * (up to max_errors). ReadArchive is not followed here (the scene builder
 * calls rib_read_file again with its search path). Comments (#...) are
 * skipped; "##" structure comments too. Returns false if there was any error
 * or the handler stopped the read. *nerrors (if not NULL) gets the count.
 */
bool rib_read_file(const char *path, const struct rib_reader_opts *opts, rib_handler_fn fn,
		   void *user, int *nerrors);

/** Same, from memory; @name is used in diagnostics. */
bool rib_read_buffer(const char *name, const char *data, size_t len,
		     const struct rib_reader_opts *opts, rib_handler_fn fn, void *user,
		     int *nerrors);

/** Report "FILE:LINE: error: MESSAGE" at @loc to @diag (NULL: stderr). */
void rib_error(FILE *diag, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
void rib_warning(FILE *diag, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/** The number at args[i] (the caller checked the table's type). */
static inline double rib_num(const struct rib_request *r, uint32_t i)
{
	return r->args[i].nums[0];
}

static inline const char *rib_str(const struct rib_request *r, uint32_t i)
{
	return r->args[i].strs[0];
}

#endif

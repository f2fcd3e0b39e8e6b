/*
 * The relight protocol's codec (protocol/README.md), shared by relightd and
 * the C client: requests parsed and checked from JSON text frames, error
 * replies, and the header of binary tile frames. It depends on cJSON alone,
 * nothing of the daemon.
 */
#ifndef PROTO_H
#define PROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define PROTO_VERSION 1

/** Requests a client sends. */
enum proto_op {
	PROTO_HELLO,
	PROTO_LIST,
	PROTO_OPEN,
	PROTO_SET,
	PROTO_ADD_LIGHT,
	PROTO_REMOVE_LIGHT,
	PROTO_SOLO,
	PROTO_MUTE,
	PROTO_FREEZE,
	PROTO_CLOSE,
	PROTO_SNAPSHOT,
	PROTO_STATS,
	PROTO_PICK,
	PROTO_OP_COUNT
};

/** The op's name on the wire ("hello", "set", ...). */
const char *proto_op_name(enum proto_op op);

/** Pixel formats of tiles. */
enum proto_format {
	PROTO_RGBA8 = 1,    /* 8-bit sRGB, colour over black, and alpha: 4 bytes a pixel */
	PROTO_RGBA16F = 2,  /* linear premultiplied half floats: 8 bytes a pixel */
};

/** Error codes, written as their names ("malformed", "unknown_op", ...). */
enum proto_error_code {
	PROTO_E_MALFORMED = 1,   /* not JSON, not an object, no "op" */
	PROTO_E_UNKNOWN_OP,
	PROTO_E_TYPE,            /* a field of the wrong type, or missing */
	PROTO_E_RANGE,           /* a value out of range or not finite */
	PROTO_E_UNKNOWN_SHOT,
	PROTO_E_UNKNOWN_LIGHT,
	PROTO_E_UNKNOWN_PARAM,
	PROTO_E_AUTH,            /* no hello, or a bad token */
	PROTO_E_FORBIDDEN,       /* a viewer's edit */
	PROTO_E_LIMIT,           /* too many clients, shots, lights, or too large */
	PROTO_E_STATE,           /* a request that needs an open shot, or the like */
	PROTO_E_INTERNAL,
};

const char *proto_error_name(enum proto_error_code code);

/** An error reply: the request's id when it had one. */
struct proto_error {
	enum proto_error_code code;
	bool has_id;
	int64_t id;
	char message[256];
};

/** A parameter of a "set" (or of an "add_light"): one to 16 finite numbers, or a string. */
struct proto_param {
	const char *name;
	float values[16];
	uint32_t n;                /* 0 for a string */
	const char *text;          /* a string's value (a map's name), else NULL */
};

/** How much a request may hold. */
struct proto_limits {
	size_t max_string;       /* bytes in a name, token or shader (0: 256) */
	uint32_t max_params;     /* parameters in one set (0: 64) */
};

/**
 * A request, checked. Strings point into the parsed text's copy that the
 * request owns (proto_request_free).
 */
struct proto_request {
	enum proto_op op;
	bool has_id;
	int64_t id;               /* an integer in [-2^53, 2^53] */
	int version;              /* hello */
	const char *token;        /* hello; NULL when absent */
	const char *shot;         /* open */
	enum proto_format format; /* open; RGBA8 when absent */
	const char *light;        /* set, add_light, remove_light, solo (NULL: none), mute, freeze */
	const char *shader;       /* add_light */
	bool on;                  /* mute (default true), freeze (default true) */
	uint32_t x, y;            /* pick: a pixel, 0 at the top left */
	struct proto_param *params;   /* set, add_light */
	uint32_t nparams;
	void *priv;
	char *owned;
};

/**
 * Parse and check the text frame @text (@len bytes, not NUL-terminated
 * necessarily) against the protocol: op names, field types, ranges, limits
 * (@lim may be NULL). On failure returns false and fills @err (with the id
 * when the frame had a usable one); @out is then empty.
 */
bool proto_parse_request(const char *text, size_t len, const struct proto_limits *lim,
			 struct proto_request *out, struct proto_error *err);
void proto_request_free(struct proto_request *r);

/** Bytes a message may hold before its connection's hello is accepted. */
#define PROTO_PREAUTH_MAX 4096

/**
 * Read a message sent before hello: only far enough to know its op and, for
 * a hello, its id, version and token, checked as proto_parse_request checks
 * them. The text must be one flat JSON object of at most PROTO_PREAUTH_MAX
 * bytes; other members are stepped over, never built into a tree. A request
 * other than hello comes back with its op and id only (the caller refuses
 * it). False with @err filled as proto_parse_request does.
 */
bool proto_parse_preauth(const char *text, size_t len, struct proto_request *out,
			 struct proto_error *err);

/**
 * Whether @name is a shader's name as add_light takes it: a letter or '_',
 * then letters, digits and '_'. No path: no '/', no '.', nothing leading.
 */
bool proto_shader_name_ok(const char *name);

/* ---- reassembling messages from fragments ---- */

/** A message being put together from the fragments (or inflated chunks) it arrives in. */
struct proto_rx {
	char *buf;               /* the message so far, NUL-terminated */
	size_t len, cap;
	bool too_big;            /* it passed the limit: everything more is discarded */
};

enum proto_rx_result {
	PROTO_RX_MORE,           /* appended; the message goes on */
	PROTO_RX_MESSAGE,        /* appended; buf holds a whole message of len bytes */
	PROTO_RX_TOO_BIG,        /* this chunk took the message past @max (said once) */
	PROTO_RX_DISCARD,        /* after TOO_BIG: dropped unread */
	PROTO_RX_NOMEM,
};

/**
 * Append @len bytes of @data to @rx: @first starts a message (what was there
 * is dropped), @final ends it. A message over @max bytes is refused once
 * with PROTO_RX_TOO_BIG, before anything past @max is stored; every later
 * call answers PROTO_RX_DISCARD. The buffer grows to the message's size
 * (at most @max + 1 bytes) only as data arrives.
 */
enum proto_rx_result proto_rx_feed(struct proto_rx *rx, const void *data, size_t len, bool first,
				   bool final, size_t max);
/** Free @rx's buffer (NULL allowed). */
void proto_rx_finish(struct proto_rx *rx);

struct cJSON;

/**
 * Add member "id" to reply @o as a whole number, exactly (cJSON prints
 * numbers past about 4.5e15 with 15 significant digits). False when out of
 * memory.
 */
bool proto_add_id(struct cJSON *o, int64_t id);

/**
 * Make @s valid UTF-8 in place: every byte of a malformed or cut-short
 * sequence becomes '?'. Text frames must be UTF-8, and messages the daemon
 * writes may quote what a client sent or cut a name in the middle.
 */
void proto_utf8_clean(char *s);

/** The JSON text of an error reply (free() it); NULL when out of memory. */
char *proto_error_json(const struct proto_error *e);

/* ---- binary tile frames ---- */

/** Bytes of a tile frame's header: "RLT1", then eight little-endian uint32. */
#define PROTO_TILE_HEADER_BYTES 36

/** A tile: where it goes and what it holds. */
struct proto_tile {
	uint32_t edit;            /* the edit it shows (0: the state when opened) */
	uint32_t level;           /* refinement level, 0 coarsest */
	uint32_t format;          /* enum proto_format */
	uint32_t x, y;            /* its top left pixel in the image */
	uint32_t width, height;
};

/** Bytes of the pixels of @t (0 for an unknown format or on overflow past SIZE_MAX). */
size_t proto_tile_pixel_bytes(const struct proto_tile *t);

/** Write @t's header: magic, header size, edit, level, format, x, y, width, height. */
void proto_tile_header(const struct proto_tile *t, uint8_t out[PROTO_TILE_HEADER_BYTES]);

/**
 * Read a tile frame of @len bytes: its header into @t and its pixels' start
 * into *@pixels. False with the reason in @err when the frame is too short,
 * has another magic or header size, an unknown format, an empty or
 * overflowing size, or fewer or more pixel bytes than its size says.
 */
bool proto_tile_parse(const uint8_t *buf, size_t len, struct proto_tile *t,
		      const uint8_t **pixels, char *err, size_t errlen);

#endif

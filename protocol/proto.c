/*
 * The protocol codec: see proto.h and README.md.
 */
#include "proto.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const op_names[PROTO_OP_COUNT] = {
	[PROTO_HELLO] = "hello",
	[PROTO_LIST] = "list",
	[PROTO_OPEN] = "open",
	[PROTO_SET] = "set",
	[PROTO_ADD_LIGHT] = "add_light",
	[PROTO_REMOVE_LIGHT] = "remove_light",
	[PROTO_SOLO] = "solo",
	[PROTO_MUTE] = "mute",
	[PROTO_FREEZE] = "freeze",
	[PROTO_CLOSE] = "close",
	[PROTO_SNAPSHOT] = "snapshot",
	[PROTO_STATS] = "stats",
	[PROTO_PICK] = "pick",
};

const char *proto_op_name(enum proto_op op)
{
	return (unsigned)op < PROTO_OP_COUNT ? op_names[op] : "?";
}

const char *proto_error_name(enum proto_error_code code)
{
	switch (code) {
	case PROTO_E_MALFORMED: return "malformed";
	case PROTO_E_UNKNOWN_OP: return "unknown_op";
	case PROTO_E_TYPE: return "type";
	case PROTO_E_RANGE: return "range";
	case PROTO_E_UNKNOWN_SHOT: return "unknown_shot";
	case PROTO_E_UNKNOWN_LIGHT: return "unknown_light";
	case PROTO_E_UNKNOWN_PARAM: return "unknown_param";
	case PROTO_E_AUTH: return "auth";
	case PROTO_E_FORBIDDEN: return "forbidden";
	case PROTO_E_LIMIT: return "limit";
	case PROTO_E_STATE: return "state";
	case PROTO_E_INTERNAL: return "internal";
	}
	return "internal";
}

static bool set_error(struct proto_error *e, enum proto_error_code code, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static bool set_error(struct proto_error *e, enum proto_error_code code, const char *fmt, ...)
{
	e->code = code;
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(e->message, sizeof(e->message), fmt, ap);
	va_end(ap);
	return false;
}

/* Largest integer a double (and JavaScript) holds exactly. */
#define MAX_ID 9007199254740992.0

/* An optional string member: NULL when absent; false (an error) when not a string or too long. */
static bool opt_string(const cJSON *o, const char *key, size_t max, const char *op,
		       const char **out, struct proto_error *e)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	*out = NULL;
	if (!v || cJSON_IsNull(v))
		return true;
	if (!cJSON_IsString(v) || !v->valuestring)
		return set_error(e, PROTO_E_TYPE, "%s: '%s' must be a string", op, key);
	size_t n = strlen(v->valuestring);
	if (n > max)
		return set_error(e, PROTO_E_LIMIT, "%s: '%s' is longer than %zu bytes", op, key, max);
	*out = v->valuestring;
	return true;
}

static bool need_string(const cJSON *o, const char *key, size_t max, const char *op,
			const char **out, struct proto_error *e)
{
	if (!opt_string(o, key, max, op, out, e))
		return false;
	if (!*out || !**out)
		return set_error(e, PROTO_E_TYPE, "%s needs '%s', a non-empty string", op, key);
	return true;
}

static bool opt_bool(const cJSON *o, const char *key, bool dflt, const char *op, bool *out,
		     struct proto_error *e)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	*out = dflt;
	if (!v)
		return true;
	if (!cJSON_IsBool(v))
		return set_error(e, PROTO_E_TYPE, "%s: '%s' must be true or false", op, key);
	*out = cJSON_IsTrue(v);
	return true;
}

/* A parameter's value: a number or an array of 1 to 16 numbers, all finite floats. */
static bool param_value(const cJSON *v, const char *op, struct proto_param *p,
			struct proto_error *e)
{
	p->n = 0;
	if (cJSON_IsNumber(v)) {
		if (!isfinite(v->valuedouble) || fabs(v->valuedouble) > 3.4e38)
			return set_error(e, PROTO_E_RANGE, "%s: '%s' is not a finite float", op, p->name);
		p->values[p->n++] = (float)v->valuedouble;
		return true;
	}
	if (!cJSON_IsArray(v))
		return set_error(e, PROTO_E_TYPE, "%s: '%s' must be a number or an array of numbers",
				 op, p->name);
	int n = cJSON_GetArraySize(v);
	if (n < 1 || n > 16)
		return set_error(e, PROTO_E_RANGE, "%s: '%s' has %d values (1 to 16)", op, p->name, n);
	const cJSON *x;
	cJSON_ArrayForEach(x, v) {
		if (!cJSON_IsNumber(x))
			return set_error(e, PROTO_E_TYPE, "%s: '%s' must hold numbers only", op,
					 p->name);
		if (!isfinite(x->valuedouble) || fabs(x->valuedouble) > 3.4e38)
			return set_error(e, PROTO_E_RANGE, "%s: '%s' holds a value that is not a "
					 "finite float", op, p->name);
		p->values[p->n++] = (float)x->valuedouble;
	}
	return true;
}

/* "params": an object of name -> value. */
static bool params(const cJSON *o, const char *op, bool required, const struct proto_limits *lim,
		   struct proto_request *r, struct proto_error *e)
{
	const cJSON *ps = cJSON_GetObjectItemCaseSensitive(o, "params");
	if (!ps && !required)
		return true;
	if (!cJSON_IsObject(ps))
		return set_error(e, PROTO_E_TYPE, "%s needs 'params', an object of parameter "
				 "values", op);
	int n = cJSON_GetArraySize(ps);
	if (required && n < 1)
		return set_error(e, PROTO_E_TYPE, "%s: 'params' is empty", op);
	if ((uint32_t)n > lim->max_params)
		return set_error(e, PROTO_E_LIMIT, "%s: %d parameters, at most %u", op, n,
				 lim->max_params);
	r->params = calloc((size_t)n + 1, sizeof(*r->params));
	if (!r->params)
		return set_error(e, PROTO_E_INTERNAL, "out of memory");
	const cJSON *p;
	cJSON_ArrayForEach(p, ps) {
		struct proto_param *q = &r->params[r->nparams];
		q->name = p->string;
		if (!q->name || !*q->name || strlen(q->name) > lim->max_string)
			return set_error(e, PROTO_E_TYPE, "%s: a parameter name is empty or too long",
					 op);
		if (!param_value(p, op, q, e))
			return false;
		r->nparams++;
	}
	return true;
}

/* A pixel coordinate: a whole number in [0, 2^31). */
static bool need_coord(const cJSON *o, const char *key, const char *op, uint32_t *out,
		       struct proto_error *e)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
	if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble))
		return set_error(e, PROTO_E_TYPE, "%s needs '%s', a whole number", op, key);
	if (v->valuedouble < 0 || v->valuedouble >= 2147483648.0)
		return set_error(e, PROTO_E_RANGE, "%s: '%s' is not a pixel (0 to 2^31 - 1)", op, key);
	*out = (uint32_t)v->valuedouble;
	return true;
}

static bool parse_body(const cJSON *o, const struct proto_limits *lim, struct proto_request *r,
		       struct proto_error *e)
{
	const char *op = proto_op_name(r->op);
	size_t ms = lim->max_string;
	switch (r->op) {
	case PROTO_HELLO: {
		const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, "version");
		if (!cJSON_IsNumber(v) || v->valuedouble != floor(v->valuedouble) ||
		    v->valuedouble < 0 || v->valuedouble > 1e6)
			return set_error(e, PROTO_E_TYPE, "hello needs 'version', a whole number (this "
					 "server speaks %d)", PROTO_VERSION);
		r->version = (int)v->valuedouble;
		if (r->version != PROTO_VERSION)
			return set_error(e, PROTO_E_RANGE, "protocol version %d; this server speaks %d",
					 r->version, PROTO_VERSION);
		return opt_string(o, "token", ms, op, &r->token, e);
	}
	case PROTO_PICK:
		return need_coord(o, "x", op, &r->x, e) && need_coord(o, "y", op, &r->y, e);
	case PROTO_LIST:
	case PROTO_CLOSE:
	case PROTO_SNAPSHOT:
	case PROTO_STATS:
		return true;
	case PROTO_OPEN: {
		if (!need_string(o, "shot", ms, op, &r->shot, e))
			return false;
		const char *f = NULL;
		if (!opt_string(o, "format", ms, op, &f, e))
			return false;
		r->format = PROTO_RGBA8;
		if (f && !strcmp(f, "rgba16f"))
			r->format = PROTO_RGBA16F;
		else if (f && strcmp(f, "rgba8"))
			return set_error(e, PROTO_E_RANGE, "open: format '%s'; the formats are rgba8 "
					 "and rgba16f", f);
		return true;
	}
	case PROTO_SET:
		return need_string(o, "light", ms, op, &r->light, e) &&
		       params(o, op, true, lim, r, e);
	case PROTO_ADD_LIGHT:
		return need_string(o, "light", ms, op, &r->light, e) &&
		       need_string(o, "shader", ms, op, &r->shader, e) &&
		       params(o, op, false, lim, r, e);
	case PROTO_REMOVE_LIGHT:
		return need_string(o, "light", ms, op, &r->light, e);
	case PROTO_SOLO:
		/* no light (or null): solo off */
		return opt_string(o, "light", ms, op, &r->light, e);
	case PROTO_MUTE:
	case PROTO_FREEZE:
		return need_string(o, "light", ms, op, &r->light, e) &&
		       opt_bool(o, r->op == PROTO_MUTE ? "mute" : "freeze", true, op, &r->on, e);
	case PROTO_OP_COUNT:
		break;
	}
	return set_error(e, PROTO_E_INTERNAL, "unhandled op");
}

/*
 * The length of the UTF-8 sequence at @s (@n bytes left) as RFC 3629 has it
 * (no overlong forms, no surrogates, nothing past U+10FFFF), or 0 when it is
 * malformed or cut short. A NUL byte is malformed here.
 */
static size_t utf8_seq(const unsigned char *s, size_t n)
{
	unsigned char c = s[0];
	if (c == 0)
		return 0;
	if (c < 0x80)
		return 1;
	size_t len;
	uint32_t cp, min;
	if ((c & 0xe0) == 0xc0) {
		len = 2, cp = c & 0x1f, min = 0x80;
	} else if ((c & 0xf0) == 0xe0) {
		len = 3, cp = c & 0x0f, min = 0x800;
	} else if ((c & 0xf8) == 0xf0) {
		len = 4, cp = c & 0x07, min = 0x10000;
	} else {
		return 0;
	}
	if (n < len)
		return 0;
	for (size_t k = 1; k < len; k++) {
		if ((s[k] & 0xc0) != 0x80)
			return 0;
		cp = (cp << 6) | (s[k] & 0x3f);
	}
	if (cp < min || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff))
		return 0;
	return len;
}

/* Is @s (@n bytes) UTF-8 with no NUL byte? A WebSocket text frame must be. */
static bool valid_utf8(const unsigned char *s, size_t n)
{
	for (size_t i = 0, k; i < n; i += k)
		if (!(k = utf8_seq(s + i, n - i)))
			return false;
	return true;
}

void proto_utf8_clean(char *s)
{
	size_t n = strlen(s);
	for (size_t i = 0; i < n;) {
		size_t k = utf8_seq((const unsigned char *)s + i, n - i);
		if (!k) {
			s[i++] = '?';
			continue;
		}
		i += k;
	}
}

bool proto_add_id(cJSON *o, int64_t id)
{
	char text[32];
	snprintf(text, sizeof(text), "%lld", (long long)id);
	return cJSON_AddRawToObject(o, "id", text) != NULL;
}

/* Does a string of the JSON text @s hold the escape \u0000 (a NUL that C strings would cut at)? */
static bool escaped_nul(const char *s, size_t n)
{
	bool in = false;
	for (size_t i = 0; i < n; i++) {
		if (!in) {
			in = s[i] == '"';
			continue;
		}
		if (s[i] == '"') {
			in = false;
		} else if (s[i] == '\\' && i + 1 < n) {
			if (s[i + 1] == 'u' && i + 5 < n && !memcmp(s + i + 2, "0000", 4))
				return true;
			i++;
		}
	}
	return false;
}

bool proto_parse_request(const char *text, size_t len, const struct proto_limits *lim,
			 struct proto_request *out, struct proto_error *err)
{
	memset(out, 0, sizeof(*out));
	memset(err, 0, sizeof(*err));
	struct proto_limits l = { 256, 64 };
	if (lim) {
		l.max_string = lim->max_string ? lim->max_string : 256;
		l.max_params = lim->max_params ? lim->max_params : 64;
	}
	if (!text)
		return set_error(err, PROTO_E_MALFORMED, "empty message");
	const char *end = NULL;
	cJSON *o = cJSON_ParseWithLengthOpts(text, len, &end, false);
	if (!o)
		return set_error(err, PROTO_E_MALFORMED, "not JSON");
	out->priv = o;
	while (end && end < text + len && (*end == ' ' || *end == '\t' || *end == '\r' || *end == '\n'))
		end++;
	bool ok = true;
	if (!cJSON_IsObject(o))
		ok = set_error(err, PROTO_E_MALFORMED, "a request is a JSON object");
	/* Checked after the parse so that the reply can carry the request's id. */
	bool text_ok = valid_utf8((const unsigned char *)text, len) && !escaped_nul(text, len) &&
		       !(end && end < text + len);
	const cJSON *id = ok ? cJSON_GetObjectItemCaseSensitive(o, "id") : NULL;
	if (id) {
		if (!cJSON_IsNumber(id) || id->valuedouble != floor(id->valuedouble) ||
		    fabs(id->valuedouble) > MAX_ID)
			ok = set_error(err, PROTO_E_TYPE, "'id' must be a whole number within 2^53");
		else {
			out->has_id = err->has_id = true;
			out->id = err->id = (int64_t)id->valuedouble;
		}
	}
	if (ok && !text_ok)
		ok = set_error(err, PROTO_E_MALFORMED, "not one JSON object of UTF-8 text (no NUL, "
			       "nothing after it)");
	const cJSON *op = ok ? cJSON_GetObjectItemCaseSensitive(o, "op") : NULL;
	if (ok && (!cJSON_IsString(op) || !op->valuestring))
		ok = set_error(err, PROTO_E_MALFORMED, "a request needs 'op', a string");
	if (ok) {
		int k = 0;
		while (k < PROTO_OP_COUNT && strcmp(op_names[k], op->valuestring))
			k++;
		if (k == PROTO_OP_COUNT) {
			char shown[40];
			snprintf(shown, sizeof(shown), "%s", op->valuestring);
			ok = set_error(err, PROTO_E_UNKNOWN_OP, "unknown op '%s'", shown);
		} else {
			out->op = (enum proto_op)k;
			ok = parse_body(o, &l, out, err);
		}
	}
	if (!ok) {
		bool has_id = err->has_id;
		int64_t idv = err->id;
		proto_request_free(out);
		err->has_id = has_id;
		err->id = idv;
	}
	return ok;
}

void proto_request_free(struct proto_request *r)
{
	if (!r)
		return;
	free(r->params);
	cJSON_Delete(r->priv);
	memset(r, 0, sizeof(*r));
}

char *proto_error_json(const struct proto_error *e)
{
	cJSON *o = cJSON_CreateObject();
	if (!o)
		return NULL;
	cJSON_AddStringToObject(o, "op", "error");
	if (e->has_id)
		proto_add_id(o, e->id);
	cJSON_AddStringToObject(o, "code", proto_error_name(e->code));
	char msg[sizeof(e->message)];
	memcpy(msg, e->message, sizeof(msg));
	msg[sizeof(msg) - 1] = '\0';
	proto_utf8_clean(msg);
	cJSON_AddStringToObject(o, "message", msg);
	char *s = cJSON_PrintUnformatted(o);
	cJSON_Delete(o);
	return s;
}

/* ---- tiles ---- */

static void put_u32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
	p[2] = (uint8_t)(v >> 16);
	p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

size_t proto_tile_pixel_bytes(const struct proto_tile *t)
{
	size_t px = t->format == PROTO_RGBA8 ? 4 : t->format == PROTO_RGBA16F ? 8 : 0;
	if (!px || !t->width || !t->height)
		return 0;
	if ((size_t)t->width > SIZE_MAX / px / t->height)
		return 0;
	return (size_t)t->width * t->height * px;
}

void proto_tile_header(const struct proto_tile *t, uint8_t out[PROTO_TILE_HEADER_BYTES])
{
	memcpy(out, "RLT1", 4);
	const uint32_t v[8] = { PROTO_TILE_HEADER_BYTES, t->edit, t->level, t->format,
				t->x, t->y, t->width, t->height };
	for (int i = 0; i < 8; i++)
		put_u32(out + 4 + 4 * i, v[i]);
}

bool proto_tile_parse(const uint8_t *buf, size_t len, struct proto_tile *t,
		      const uint8_t **pixels, char *err, size_t errlen)
{
	memset(t, 0, sizeof(*t));
	*pixels = NULL;
	if (!buf || len < PROTO_TILE_HEADER_BYTES) {
		snprintf(err, errlen, "a tile frame of %zu bytes is shorter than its header", len);
		return false;
	}
	if (memcmp(buf, "RLT1", 4)) {
		snprintf(err, errlen, "not a tile frame (no RLT1 magic)");
		return false;
	}
	uint32_t hs = get_u32(buf + 4);
	if (hs != PROTO_TILE_HEADER_BYTES) {
		snprintf(err, errlen, "tile header of %u bytes; this codec reads %d", hs,
			 PROTO_TILE_HEADER_BYTES);
		return false;
	}
	t->edit = get_u32(buf + 8);
	t->level = get_u32(buf + 12);
	t->format = get_u32(buf + 16);
	t->x = get_u32(buf + 20);
	t->y = get_u32(buf + 24);
	t->width = get_u32(buf + 28);
	t->height = get_u32(buf + 32);
	size_t need = proto_tile_pixel_bytes(t);
	if (!need) {
		snprintf(err, errlen, "tile of %ux%u in format %u: empty, too large or unknown format",
			 t->width, t->height, t->format);
		return false;
	}
	if (len - PROTO_TILE_HEADER_BYTES != need) {
		snprintf(err, errlen, "tile of %ux%u holds %zu pixel bytes, not %zu", t->width,
			 t->height, len - PROTO_TILE_HEADER_BYTES, need);
		return false;
	}
	*pixels = buf + PROTO_TILE_HEADER_BYTES;
	return true;
}

/*
 * The protocol codec: see proto.h and README.md.
 */
#include "proto.h"

#include <cjson/cJSON.h>
#include <ctype.h>
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

/* A parameter's value: a number or an array of 1 to 16 numbers, all finite
 * floats, or a string of at most 4095 bytes (a string parameter's: a map). */
static bool param_value(const cJSON *v, const char *op, struct proto_param *p,
			struct proto_error *e)
{
	p->n = 0;
	p->text = NULL;
	if (cJSON_IsString(v)) {
		if (strlen(v->valuestring) > 4095)
			return set_error(e, PROTO_E_RANGE, "%s: '%s' is a string over 4095 bytes", op,
					 p->name);
		p->text = v->valuestring;
		return true;
	}
	if (cJSON_IsNumber(v)) {
		if (!isfinite(v->valuedouble) || fabs(v->valuedouble) > 3.4e38)
			return set_error(e, PROTO_E_RANGE, "%s: '%s' is not a finite float", op, p->name);
		p->values[p->n++] = (float)v->valuedouble;
		return true;
	}
	if (!cJSON_IsArray(v))
		return set_error(e, PROTO_E_TYPE, "%s: '%s' must be a number, an array of numbers "
				 "or a string", op, p->name);
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
		if (!need_string(o, "light", ms, op, &r->light, e) ||
		    !need_string(o, "shader", ms, op, &r->shader, e))
			return false;
		/* One message for every name that is not a shader's: nothing tells the
		 * client what lies outside the shader path. */
		if (!proto_shader_name_ok(r->shader))
			return set_error(e, PROTO_E_RANGE, "add_light: 'shader' must be a shader's "
					 "name (a letter or '_', then letters, digits, '_'), not a path");
		return params(o, op, false, lim, r, e);
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

bool proto_shader_name_ok(const char *name)
{
	if (!name || !(isalpha((unsigned char)name[0]) || name[0] == '_'))
		return false;
	for (const char *p = name + 1; *p; p++)
		if (!isalnum((unsigned char)*p) && *p != '_')
			return false;
	return true;
}

static int compare_keys(const void *a, const void *b)
{
	return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/*
 * The first member name that @v or a value inside it holds twice, or NULL.
 * cJSON keeps every member and lookups find the first; a proxy reading the
 * same text may keep the last, so a repeated name is refused, not resolved.
 * Sorting the names makes a large object cost n log n, not n^2.
 */
static const char *repeated_key(const cJSON *v, bool *nomem)
{
	if (!cJSON_IsObject(v) && !cJSON_IsArray(v))
		return NULL;
	size_t n = 0;
	for (const cJSON *x = v->child; x; x = x->next)
		n++;
	if (cJSON_IsObject(v) && n > 1) {
		const char **keys = malloc(n * sizeof(*keys));
		if (!keys) {
			*nomem = true;
			return NULL;
		}
		size_t k = 0;
		for (const cJSON *x = v->child; x; x = x->next)
			keys[k++] = x->string ? x->string : "";
		qsort(keys, n, sizeof(*keys), compare_keys);
		const char *dup = NULL;
		for (size_t i = 1; i < n && !dup; i++)
			if (!strcmp(keys[i - 1], keys[i]))
				dup = keys[i];
		free(keys);
		if (dup)
			return dup;
	}
	for (const cJSON *x = v->child; x; x = x->next) {
		const char *dup = repeated_key(x, nomem);
		if (dup || *nomem)
			return dup;
	}
	return NULL;
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
	bool ok = true, nomem = false;
	const char *dup = NULL;
	if (!cJSON_IsObject(o))
		ok = set_error(err, PROTO_E_MALFORMED, "a request is a JSON object");
	else if ((dup = repeated_key(o, &nomem)) != NULL) {
		char shown[40];
		snprintf(shown, sizeof(shown), "%s", dup);
		ok = set_error(err, PROTO_E_MALFORMED, "the member '%s' appears twice in one object",
			       shown);
	} else if (nomem)
		ok = set_error(err, PROTO_E_INTERNAL, "out of memory");
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
	free(r->owned);
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

/* ---- before hello ---- */

/*
 * A reader of the one flat object a client sends before hello. It keeps the
 * four members that matter then (op, id, version, token) and steps over any
 * other value without building it, so an unauthenticated peer costs a scan
 * of at most PROTO_PREAUTH_MAX bytes and no allocation but the token's copy.
 */
struct scan {
	const char *p, *end;
	char *scratch;         /* decoded strings go here, one after another */
	size_t used, cap;
};

enum scalar_kind { V_NONE, V_STRING, V_NUMBER, V_TRUE, V_FALSE, V_NULL, V_NESTED };

struct scalar {
	enum scalar_kind kind;
	const char *s;         /* V_STRING: decoded, NUL-terminated, in scratch */
	size_t len;
	double number;
};

static void skip_ws(struct scan *sc)
{
	while (sc->p < sc->end && (*sc->p == ' ' || *sc->p == '\t' || *sc->p == '\n' ||
				   *sc->p == '\r'))
		sc->p++;
}

static int hex_digit(char c)
{
	return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 :
	       c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

static bool hex4(struct scan *sc, uint32_t *out)
{
	if (sc->end - sc->p < 4)
		return false;
	uint32_t v = 0;
	for (int i = 0; i < 4; i++) {
		int d = hex_digit(sc->p[i]);
		if (d < 0)
			return false;
		v = v << 4 | (uint32_t)d;
	}
	sc->p += 4;
	*out = v;
	return true;
}

static bool put_byte(struct scan *sc, unsigned char b)
{
	if (sc->used + 1 >= sc->cap)
		return false;
	sc->scratch[sc->used++] = (char)b;
	return true;
}

static bool put_code_point(struct scan *sc, uint32_t cp)
{
	if (cp < 0x80)
		return put_byte(sc, (unsigned char)cp);
	if (cp < 0x800)
		return put_byte(sc, (unsigned char)(0xc0 | cp >> 6)) &&
		       put_byte(sc, (unsigned char)(0x80 | (cp & 0x3f)));
	if (cp < 0x10000)
		return put_byte(sc, (unsigned char)(0xe0 | cp >> 12)) &&
		       put_byte(sc, (unsigned char)(0x80 | ((cp >> 6) & 0x3f))) &&
		       put_byte(sc, (unsigned char)(0x80 | (cp & 0x3f)));
	return put_byte(sc, (unsigned char)(0xf0 | cp >> 18)) &&
	       put_byte(sc, (unsigned char)(0x80 | ((cp >> 12) & 0x3f))) &&
	       put_byte(sc, (unsigned char)(0x80 | ((cp >> 6) & 0x3f))) &&
	       put_byte(sc, (unsigned char)(0x80 | (cp & 0x3f)));
}

/*
 * string := '"' { char | '\' ( '"' | '\' | '/' | 'b' | 'f' | 'n' | 'r' | 't' | 'u' hex4 ) } '"'
 * Decoded into scratch when @keep (a \u pair of surrogates is one code point).
 */
static bool scan_string(struct scan *sc, bool keep, struct scalar *v)
{
	if (sc->p >= sc->end || *sc->p != '"')
		return false;
	sc->p++;
	size_t start = sc->used;
	while (sc->p < sc->end && *sc->p != '"') {
		unsigned char c = (unsigned char)*sc->p++;
		if (c < 0x20)
			return false;
		if (c != '\\') {
			if (keep && !put_byte(sc, c))
				return false;
			continue;
		}
		if (sc->p >= sc->end)
			return false;
		char e = *sc->p++;
		uint32_t cp;
		switch (e) {
		case '"': case '\\': case '/': cp = (uint32_t)e; break;
		case 'b': cp = '\b'; break;
		case 'f': cp = '\f'; break;
		case 'n': cp = '\n'; break;
		case 'r': cp = '\r'; break;
		case 't': cp = '\t'; break;
		case 'u': {
			if (!hex4(sc, &cp) || (cp >= 0xdc00 && cp <= 0xdfff))
				return false;
			if (cp >= 0xd800 && cp <= 0xdbff) {
				uint32_t lo;
				if (sc->end - sc->p < 2 || sc->p[0] != '\\' || sc->p[1] != 'u')
					return false;
				sc->p += 2;
				if (!hex4(sc, &lo) || lo < 0xdc00 || lo > 0xdfff)
					return false;
				cp = 0x10000 + ((cp - 0xd800) << 10) + (lo - 0xdc00);
			}
			break;
		}
		default:
			return false;
		}
		if (keep && !put_code_point(sc, cp))
			return false;
	}
	if (sc->p >= sc->end)
		return false;
	sc->p++;
	if (keep) {
		if (!put_byte(sc, 0))
			return false;
		v->kind = V_STRING;
		v->s = sc->scratch + start;
		v->len = sc->used - start - 1;
	}
	return true;
}

/* number := [ '-' ] ( '0' | digit1-9 { digit } ) [ '.' digit { digit } ] [ ( 'e' | 'E' ) [ '+' | '-' ] digit { digit } ] */
static bool scan_number(struct scan *sc, struct scalar *v)
{
	const char *b = sc->p, *q = sc->p;
	if (q < sc->end && *q == '-')
		q++;
	if (q >= sc->end || !isdigit((unsigned char)*q))
		return false;
	if (*q == '0')
		q++;
	else
		while (q < sc->end && isdigit((unsigned char)*q))
			q++;
	if (q < sc->end && *q == '.') {
		q++;
		if (q >= sc->end || !isdigit((unsigned char)*q))
			return false;
		while (q < sc->end && isdigit((unsigned char)*q))
			q++;
	}
	if (q < sc->end && (*q == 'e' || *q == 'E')) {
		q++;
		if (q < sc->end && (*q == '+' || *q == '-'))
			q++;
		if (q >= sc->end || !isdigit((unsigned char)*q))
			return false;
		while (q < sc->end && isdigit((unsigned char)*q))
			q++;
	}
	/* cJSON reads at most 63 characters of a number; so does this. */
	char buf[64];
	size_t n = (size_t)(q - b);
	if (n >= sizeof(buf))
		return false;
	memcpy(buf, b, n);
	buf[n] = '\0';
	v->kind = V_NUMBER;
	v->number = strtod(buf, NULL);
	sc->p = q;
	return true;
}

static bool scan_word(struct scan *sc, const char *w)
{
	size_t n = strlen(w);
	if ((size_t)(sc->end - sc->p) < n || memcmp(sc->p, w, n))
		return false;
	sc->p += n;
	return true;
}

/*
 * value := string | number | 'true' | 'false' | 'null' | object | array
 * Objects and arrays are stepped over, @depth levels at most; strings are
 * decoded only when @keep.
 */
static bool scan_value(struct scan *sc, bool keep, int depth, struct scalar *v)
{
	v->kind = V_NONE;
	if (sc->p >= sc->end)
		return false;
	char c = *sc->p;
	if (c == '"')
		return scan_string(sc, keep, v);
	if (c == '-' || isdigit((unsigned char)c))
		return scan_number(sc, v);
	if (c == 't')
		return (v->kind = V_TRUE, scan_word(sc, "true"));
	if (c == 'f')
		return (v->kind = V_FALSE, scan_word(sc, "false"));
	if (c == 'n')
		return (v->kind = V_NULL, scan_word(sc, "null"));
	if ((c != '{' && c != '[') || depth <= 0)
		return false;
	char close = c == '{' ? '}' : ']';
	sc->p++;
	skip_ws(sc);
	if (sc->p < sc->end && *sc->p == close) {
		sc->p++;
		v->kind = V_NESTED;
		return true;
	}
	for (;;) {
		struct scalar inner;
		skip_ws(sc);
		if (c == '{') {
			if (!scan_string(sc, false, &inner))
				return false;
			skip_ws(sc);
			if (sc->p >= sc->end || *sc->p++ != ':')
				return false;
			skip_ws(sc);
		}
		if (!scan_value(sc, false, depth - 1, &inner))
			return false;
		skip_ws(sc);
		if (sc->p >= sc->end)
			return false;
		if (*sc->p == close) {
			sc->p++;
			v->kind = V_NESTED;
			return true;
		}
		if (*sc->p++ != ',')
			return false;
	}
}

/* Member names at the top level, decoded, for the repeated-name check. */
#define PREAUTH_KEYS 256

bool proto_parse_preauth(const char *text, size_t len, struct proto_request *out,
			 struct proto_error *err)
{
	memset(out, 0, sizeof(*out));
	memset(err, 0, sizeof(*err));
	if (!text)
		return set_error(err, PROTO_E_MALFORMED, "empty message");
	if (len > PROTO_PREAUTH_MAX)
		return set_error(err, PROTO_E_LIMIT, "a message before hello is at most %d bytes; "
				 "this one has %zu", PROTO_PREAUTH_MAX, len);
	/* Decoded text is never longer than its source. */
	char scratch[PROTO_PREAUTH_MAX + 1];
	const char *keys[PREAUTH_KEYS];
	size_t nkeys = 0;
	struct scan sc = { .p = text, .end = text + len, .scratch = scratch, .cap = sizeof(scratch) };
	struct scalar op = { 0 }, id = { 0 }, version = { 0 }, token = { 0 };
	bool ok = true, nested_top = false;

	/* request := ws '{' ws [ member { ws ',' ws member } ] ws '}' ws ;  member := string ws ':' ws value */
	skip_ws(&sc);
	if (sc.p < sc.end && *sc.p == '{') {
		sc.p++;
		skip_ws(&sc);
		if (sc.p < sc.end && *sc.p == '}') {
			sc.p++;
		} else {
			for (;;) {
				struct scalar key, v;
				skip_ws(&sc);
				if (!scan_string(&sc, true, &key)) {
					ok = false;
					break;
				}
				skip_ws(&sc);
				if (sc.p >= sc.end || *sc.p++ != ':') {
					ok = false;
					break;
				}
				skip_ws(&sc);
				struct scalar *slot = !strcmp(key.s, "op") ? &op :
						      !strcmp(key.s, "id") ? &id :
						      !strcmp(key.s, "version") ? &version :
						      !strcmp(key.s, "token") ? &token : NULL;
				if (!scan_value(&sc, slot != NULL, 64, &v)) {
					ok = false;
					break;
				}
				if (slot)
					*slot = v;
				if (nkeys == PREAUTH_KEYS) {
					ok = set_error(err, PROTO_E_LIMIT, "a message before hello has at "
						       "most %d members", PREAUTH_KEYS);
					break;
				}
				keys[nkeys++] = key.s;
				skip_ws(&sc);
				if (sc.p < sc.end && *sc.p == '}') {
					sc.p++;
					break;
				}
				if (sc.p >= sc.end || *sc.p++ != ',') {
					ok = false;
					break;
				}
			}
		}
		skip_ws(&sc);
		if (ok && sc.p != sc.end)
			return set_error(err, PROTO_E_MALFORMED, "not one JSON object of UTF-8 text "
					 "(no NUL, nothing after it)");
		if (!ok)
			return err->code ? false : set_error(err, PROTO_E_MALFORMED, "not JSON");
	} else {
		struct scalar v;
		ok = scan_value(&sc, false, 64, &v);
		skip_ws(&sc);
		if (!ok || sc.p != sc.end)
			return set_error(err, PROTO_E_MALFORMED, "not JSON");
		nested_top = true;
	}
	if (nested_top)
		return set_error(err, PROTO_E_MALFORMED, "a request is a JSON object");
	qsort(keys, nkeys, sizeof(*keys), compare_keys);
	for (size_t i = 1; i < nkeys; i++) {
		if (!strcmp(keys[i - 1], keys[i])) {
			char shown[40];
			snprintf(shown, sizeof(shown), "%s", keys[i]);
			return set_error(err, PROTO_E_MALFORMED, "the member '%s' appears twice in one "
					 "object", shown);
		}
	}
	/* The same order of checks as proto_parse_request, so the replies match. */
	if (id.kind != V_NONE) {
		if (id.kind != V_NUMBER || id.number != floor(id.number) || fabs(id.number) > MAX_ID)
			return set_error(err, PROTO_E_TYPE, "'id' must be a whole number within 2^53");
		out->has_id = err->has_id = true;
		out->id = err->id = (int64_t)id.number;
	}
	if (!valid_utf8((const unsigned char *)text, len) || escaped_nul(text, len))
		return set_error(err, PROTO_E_MALFORMED, "not one JSON object of UTF-8 text (no NUL, "
				 "nothing after it)");
	if (op.kind != V_STRING)
		return set_error(err, PROTO_E_MALFORMED, "a request needs 'op', a string");
	int k = 0;
	while (k < PROTO_OP_COUNT && strcmp(op_names[k], op.s))
		k++;
	if (k == PROTO_OP_COUNT) {
		char shown[40];
		snprintf(shown, sizeof(shown), "%s", op.s);
		return set_error(err, PROTO_E_UNKNOWN_OP, "unknown op '%s'", shown);
	}
	out->op = (enum proto_op)k;
	if (out->op != PROTO_HELLO)
		return true;     /* the caller answers "say hello first" */
	if (version.kind != V_NUMBER || version.number != floor(version.number) ||
	    version.number < 0 || version.number > 1e6)
		return set_error(err, PROTO_E_TYPE, "hello needs 'version', a whole number (this "
				 "server speaks %d)", PROTO_VERSION);
	out->version = (int)version.number;
	if (out->version != PROTO_VERSION)
		return set_error(err, PROTO_E_RANGE, "protocol version %d; this server speaks %d",
				 out->version, PROTO_VERSION);
	if (token.kind == V_NONE || token.kind == V_NULL)
		return true;
	if (token.kind != V_STRING)
		return set_error(err, PROTO_E_TYPE, "hello: 'token' must be a string");
	if (token.len > 256)
		return set_error(err, PROTO_E_LIMIT, "hello: 'token' is longer than 256 bytes");
	out->owned = malloc(token.len + 1);
	if (!out->owned)
		return set_error(err, PROTO_E_INTERNAL, "out of memory");
	memcpy(out->owned, token.s, token.len + 1);
	out->token = out->owned;
	return true;
}

/* ---- reassembly ---- */

void proto_rx_finish(struct proto_rx *rx)
{
	if (!rx)
		return;
	free(rx->buf);
	memset(rx, 0, sizeof(*rx));
}

enum proto_rx_result proto_rx_feed(struct proto_rx *rx, const void *data, size_t len, bool first,
				   bool final, size_t max)
{
	if (rx->too_big)
		return PROTO_RX_DISCARD;
	if (first)
		rx->len = 0;
	if (len > max || rx->len > max - len) {
		rx->too_big = true;
		return PROTO_RX_TOO_BIG;
	}
	if (rx->len + len + 1 > rx->cap) {
		size_t cap = rx->cap ? rx->cap : 4096;
		while (cap < rx->len + len + 1)
			cap *= 2;
		char *buf = realloc(rx->buf, cap);
		if (!buf)
			return PROTO_RX_NOMEM;
		rx->buf = buf;
		rx->cap = cap;
	}
	if (len)
		memcpy(rx->buf + rx->len, data, len);
	rx->len += len;
	rx->buf[rx->len] = '\0';
	return final ? PROTO_RX_MESSAGE : PROTO_RX_MORE;
}

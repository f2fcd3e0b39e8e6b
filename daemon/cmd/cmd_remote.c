/*
 * relight remote: drive a running relightd over one WebSocket connection
 * (clients/remote/remote.h) with a script of commands given on the command
 * line, run in order: open a shot, edit its lights, wait for the
 * refinement, write snapshots assembled from the tiles received, print
 * stats or watch the events go by.
 *
 * The client keeps what it needs of the session: the newest edit it has
 * heard of (its own acks, and the tiles and level messages of every edit,
 * other clients' included), the highest level that edit has reached, and
 * the final-level tiles of that edit, assembled into an image.
 */
#include "cmd.h"
#include "png.h"
#include "remote.h"
#include "shotfile.h"
#include "texture.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight remote [OPTIONS] URL COMMAND [ARGS]... [COMMAND [ARGS]...]...\n"
		"\n"
		"Connect to a running relightd at URL (ws://HOST:PORT/ws, or wss:// for TLS;\n"
		"the path defaults to /ws) and run the commands in order over that one\n"
		"connection. The first failing command ends the run.\n"
		"\n"
		"Commands:\n"
		"  list                  Print the shots the server has: name, size, baked\n"
		"  open SHOT             Open a shot (a RIB not baked yet is baked first)\n"
		"  set LIGHT.PARAM=V[,V...]...\n"
		"                        Edit light parameters: one value for a float (or a\n"
		"                        grey colour), three for a colour or a point. Several\n"
		"                        assignments naming the same light are one edit; each\n"
		"                        other light named makes an edit of its own\n"
		"  mute LIGHT            Turn a light off\n"
		"  unmute LIGHT          Turn it on again\n"
		"  solo LIGHT|none       Light the shot with that light alone; none: all again\n"
		"  freeze LIGHT          Put the light into the light cache: its contribution\n"
		"                        is summed once, not shaded again on each change\n"
		"  unfreeze LIGHT        Take it out: shade it on every change\n"
		"  add-light NAME SHADER [PARAM=V[,V...]]...\n"
		"                        Add a light of light shader SHADER\n"
		"  remove-light NAME     Remove a light\n"
		"  wait [LEVEL|final]    Wait until the newest edit has reached refinement\n"
		"                        level LEVEL (0 coarsest to 3, final; default final)\n"
		"  snapshot OUT.exr|OUT.png\n"
		"                        Wait for the newest edit's final level and write it,\n"
		"                        assembled from the tiles received: OpenEXR of the\n"
		"                        linear half floats (rgba16f tiles), or PNG of the\n"
		"                        8-bit sRGB pixels (rgba8 tiles)\n"
		"  server-snapshot       Have the server write an OpenEXR of the current state;\n"
		"                        print its name in the server's --snapshots folder\n"
		"  stats                 Print the session's counters\n"
		"  watch SECONDS         For SECONDS, print every message from the server\n"
		"                        (levels, progress, stats, ...), one line each\n"
		"\n"
		"Options:\n"
		"  --token T             Send token T in the hello (the server's --token-file)\n"
		"  --token-file F        Send the first token in file F (one a line, as the\n"
		"                        server's token file: '#' comments, a role after it)\n"
		"  --format rgba8|rgba16f\n"
		"                        The tiles to ask for when opening a shot (default:\n"
		"                        rgba16f when a snapshot to .exr is asked, else rgba8)\n"
		"  --ca-file F           wss://: trust the certificates of PEM file F (a\n"
		"                        self-signed server's, say) instead of the system's\n"
		"  --insecure            wss://: accept any certificate, for any host name\n"
		"  --timeout S           Seconds one command may take (default 60); a bake's\n"
		"                        progress messages restart the wait of 'open'\n"
		"  --json                Print the server's replies as JSON, one a line, and\n"
		"                        a JSON line for each wait and snapshot\n"
		"  -q, --quiet           Print only what a command is for (list, stats,\n"
		"                        server-snapshot, watch), no confirmations or progress\n"
		"                        (the lines of --json are printed all the same)\n"
		"  -h, --help            Show this help and exit\n"
		"\n"
		"Example:\n"
		"  relight remote ws://127.0.0.1:7878/ws open shadows set 2.intensity=40 \\\n"
		"      set 2.lightcolor=1,0.8,0.6 wait final snapshot key.exr\n"
		"\n"
		"Exit status: 0 when every command succeeded; 1 when the connection failed,\n"
		"a command timed out or the server answered with an error (printed as\n"
		"'relight remote: COMMAND: CODE: MESSAGE'); 2 on a usage error.\n");
}

#define usage_error(...) cmd_usage_error("remote", __VA_ARGS__)

enum step_kind {
	STEP_LIST,
	STEP_OPEN,
	STEP_SET,
	STEP_MUTE,
	STEP_UNMUTE,
	STEP_SOLO,
	STEP_FREEZE,
	STEP_UNFREEZE,
	STEP_ADD_LIGHT,
	STEP_REMOVE_LIGHT,
	STEP_WAIT,
	STEP_SNAPSHOT,
	STEP_SERVER_SNAPSHOT,
	STEP_STATS,
	STEP_WATCH,
};

/* The commands: their names and how many fixed arguments they take. */
static const struct {
	const char *name;
	enum step_kind kind;
	int nargs;
} step_table[] = {
	{ "list", STEP_LIST, 0 },
	{ "open", STEP_OPEN, 1 },
	{ "set", STEP_SET, 0 },
	{ "mute", STEP_MUTE, 1 },
	{ "unmute", STEP_UNMUTE, 1 },
	{ "solo", STEP_SOLO, 1 },
	{ "freeze", STEP_FREEZE, 1 },
	{ "unfreeze", STEP_UNFREEZE, 1 },
	{ "add-light", STEP_ADD_LIGHT, 2 },
	{ "remove-light", STEP_REMOVE_LIGHT, 1 },
	{ "wait", STEP_WAIT, 0 },
	{ "snapshot", STEP_SNAPSHOT, 1 },
	{ "server-snapshot", STEP_SERVER_SNAPSHOT, 0 },
	{ "stats", STEP_STATS, 0 },
	{ "watch", STEP_WATCH, 1 },
};

#define NSTEP_NAMES (sizeof(step_table) / sizeof(step_table[0]))
#define FINAL_LEVEL 3

/* An assignment [LIGHT.]PARAM=V[,V...], pointing into a copy of the argument. */
struct assign {
	char *light;
	char *param;
	float values[16];
	uint32_t n;
};

struct step {
	enum step_kind kind;
	const char *name;       /* as typed, for messages */
	const char *arg;        /* shot, light, file or seconds */
	const char *shader;     /* add-light */
	struct assign *assigns; /* set, add-light */
	int nassigns;
	int level;              /* wait */
	double seconds;         /* watch */
};

struct options {
	const char *token;
	const char *ca_file;
	bool insecure;
	bool json, quiet;
	double timeout_s;
	enum proto_format format;
};

/* The session as the client sees it. */
struct session {
	struct remote *r;
	const struct options *o;
	const char *cmd;         /* the command running, for messages */
	bool open;
	double open_ms;          /* when the open shot's reply came: what came before
				    belongs to the shot open before it */
	uint32_t width, height, final_level;
	int64_t newest;          /* the newest edit heard of; -1: none */
	int level;               /* the highest level it has reached; -1: none */
	double level_ms;         /* the server's time of that level */
	uint8_t *image;          /* the final level of edit image_edit, being assembled */
	int64_t image_edit;
	uint64_t image_pixels;   /* pixels its tiles have covered */
	bool image_done;         /* its final level message came, every pixel covered */
};

static int fail(struct session *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Print "relight remote: COMMAND: MESSAGE"; returns CMD_FAILED. */
static int fail(struct session *s, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "relight remote: %s: ", s->cmd);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	return CMD_FAILED;
}

/*
 * The server's error messages begin with the request's op ("open: no shot
 * 'x'"), which fail() has already printed as the command: the text after
 * that prefix, when it names @op (an op, or a command where '-' stands for
 * '_').
 */
static const char *without_op(const char *msg, const char *op)
{
	size_t n = strlen(op);
	if (n == 0)
		return msg;
	for (size_t i = 0; i < n; i++) {
		char a = msg[i] == '-' ? '_' : msg[i], b = op[i] == '-' ? '_' : op[i];
		if (a == '\0' || a != b)
			return msg;
	}
	return msg[n] == ':' && msg[n + 1] == ' ' ? msg + n + 2 : msg;
}

/* ---- the command line ---- */

/*
 * assignment := [LIGHT "."] PARAM "=" number ("," number)*
 * The light is what comes before the last dot, as in `relight preview --set`.
 */
static bool parse_assign(const char *arg, bool with_light, struct assign *a, char *why,
			 size_t whylen)
{
	memset(a, 0, sizeof(*a));
	char *copy = strdup(arg);
	if (!copy) {
		snprintf(why, whylen, "out of memory");
		return false;
	}
	char *eq = strchr(copy, '=');
	if (!eq) {
		snprintf(why, whylen, "'%s' has no '='", arg);
		goto bad;
	}
	*eq = '\0';
	a->param = copy;
	if (with_light) {
		char *dot = strrchr(copy, '.');
		if (!dot || dot == copy || !dot[1]) {
			snprintf(why, whylen, "'%s' is not LIGHT.PARAM=V[,V...]", arg);
			goto bad;
		}
		*dot = '\0';
		a->light = copy;
		a->param = dot + 1;
	} else if (!*copy) {
		snprintf(why, whylen, "'%s' has no parameter name", arg);
		goto bad;
	}
	for (char *p = eq + 1;;) {
		char *end;
		errno = 0;
		float v = strtof(p, &end);
		if (end == p || (*end && *end != ',')) {
			snprintf(why, whylen, "'%s': the values must be numbers separated by commas",
				 arg);
			goto bad;
		}
		if (errno == ERANGE || !isfinite(v)) {
			snprintf(why, whylen, "'%s': '%.*s' is not a finite float", arg,
				 (int)(end - p), p);
			goto bad;
		}
		if (a->n == 16) {
			snprintf(why, whylen, "'%s': at most 16 values", arg);
			goto bad;
		}
		a->values[a->n++] = v;
		if (!*end)
			return true;
		p = end + 1;
	}
bad:
	free(copy);
	a->light = a->param = NULL;
	return false;
}

static void free_steps(struct step *steps, int n)
{
	for (int i = 0; i < n; i++) {
		for (int j = 0; j < steps[i].nassigns; j++)
			free(steps[i].assigns[j].light ? steps[i].assigns[j].light :
			     steps[i].assigns[j].param);
		free(steps[i].assigns);
	}
	free(steps);
}

static bool ends_with(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && !strcmp(s + n - m, suffix);
}

/* The commands from argv[i...]; a usage error prints and returns NULL. */
static struct step *parse_steps(int argc, char **argv, int i, int *nsteps)
{
	struct step *steps = calloc((size_t)(argc - i) + 1, sizeof(*steps));
	int n = 0;
	char why[512];
	if (!steps) {
		usage_error("out of memory");
		return NULL;
	}
	while (i < argc) {
		const char *word = argv[i++];
		size_t k = 0;
		while (k < NSTEP_NAMES && strcmp(step_table[k].name, word))
			k++;
		if (k == NSTEP_NAMES) {
			usage_error("unknown command '%s'", word);
			goto bad;
		}
		struct step *st = &steps[n++];
		st->kind = step_table[k].kind;
		st->name = step_table[k].name;
		if (argc - i < step_table[k].nargs) {
			usage_error("%s needs %d argument%s", word, step_table[k].nargs,
				    step_table[k].nargs > 1 ? "s" : "");
			goto bad;
		}
		if (step_table[k].nargs >= 1)
			st->arg = argv[i++];
		if (step_table[k].nargs >= 2)
			st->shader = argv[i++];
		switch (st->kind) {
		case STEP_SET:
		case STEP_ADD_LIGHT: {
			/* the assignments: the arguments that follow with an '=' in them */
			int first = i;
			while (i < argc && strchr(argv[i], '='))
				i++;
			if (st->kind == STEP_SET && i == first) {
				usage_error("set needs LIGHT.PARAM=V[,V...]");
				goto bad;
			}
			st->assigns = calloc((size_t)(i - first) + 1, sizeof(*st->assigns));
			if (!st->assigns) {
				usage_error("out of memory");
				goto bad;
			}
			for (int j = first; j < i; j++) {
				if (!parse_assign(argv[j], st->kind == STEP_SET,
						  &st->assigns[st->nassigns], why, sizeof(why))) {
					usage_error("%s: %s", word, why);
					goto bad;
				}
				st->nassigns++;
			}
			break;
		}
		case STEP_WAIT:
			st->level = FINAL_LEVEL;
			if (i < argc && !strcmp(argv[i], "final")) {
				i++;
			} else if (i < argc && argv[i][0] >= '0' && argv[i][0] <= '0' + FINAL_LEVEL &&
				   !argv[i][1]) {
				st->level = argv[i++][0] - '0';
			}
			break;
		case STEP_SNAPSHOT:
			if (!ends_with(st->arg, ".exr") && !ends_with(st->arg, ".png")) {
				usage_error("snapshot writes OUT.exr or OUT.png, not '%s'", st->arg);
				goto bad;
			}
			break;
		case STEP_WATCH:
			if (!cmd_parse_double(st->arg, 0.0, 1e6, &st->seconds)) {
				usage_error("watch needs a number of seconds, not '%s'", st->arg);
				goto bad;
			}
			break;
		default:
			break;
		}
	}
	*nsteps = n;
	return steps;
bad:
	free_steps(steps, n);
	return NULL;
}

/* The first token of a token file: its first word that is not in a comment. */
static bool read_token(const char *path, char *out, size_t cap)
{
	FILE *f = fopen(path, "r");
	if (!f) {
		fprintf(stderr, "relight remote: cannot read token file %s: %s\n", path,
			strerror(errno));
		return false;
	}
	char line[1024];
	bool found = false;
	while (!found && fgets(line, sizeof(line), f)) {
		char *p = line + strspn(line, " \t\r\n");
		size_t n = strcspn(p, " \t\r\n");
		if (!n || *p == '#')
			continue;
		if (n >= cap) {
			fprintf(stderr, "relight remote: %s: the token is too long\n", path);
			fclose(f);
			return false;
		}
		memcpy(out, p, n);
		out[n] = '\0';
		found = true;
	}
	fclose(f);
	if (!found)
		fprintf(stderr, "relight remote: %s: no token in it\n", path);
	return found;
}

/* ---- the session ---- */

static void print_json(const cJSON *j)
{
	char *text = cJSON_PrintUnformatted(j);
	if (text) {
		printf("%s\n", text);
		cJSON_free(text);
	}
	fflush(stdout);
}

static double num(const cJSON *j, const char *name, double dflt)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, name);
	return cJSON_IsNumber(v) ? v->valuedouble : dflt;
}

/* An edit number: a whole number in [0, 2^53]; -1 when it is none. */
static int64_t edit_of(const cJSON *j, const char *name)
{
	double e = num(j, name, -1);
	return e >= 0 && e <= 9007199254740992.0 && e == floor(e) ? (int64_t)e : -1;
}

static const char *str(const cJSON *j, const char *name)
{
	const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, name);
	return cJSON_IsString(v) ? v->valuestring : "";
}

/* A message as one line: its op, then NAME=VALUE for each other member. */
static void print_line(const cJSON *j)
{
	printf("%s", str(j, "op"));
	for (const cJSON *m = j->child; m; m = m->next) {
		if (!m->string || !strcmp(m->string, "op"))
			continue;
		if (cJSON_IsString(m)) {
			printf(" %s=%s", m->string, m->valuestring);
		} else {
			char *t = cJSON_PrintUnformatted(m);
			printf(" %s=%s", m->string, t ? t : "?");
			cJSON_free(t);
		}
	}
	printf("\n");
	fflush(stdout);
}

static size_t pixel_bytes(const struct session *s)
{
	return s->o->format == PROTO_RGBA16F ? 8 : 4;
}

/* A newer edit than any before: its levels start from nothing. */
static void new_edit(struct session *s, int64_t edit)
{
	if (edit > s->newest) {
		s->newest = edit;
		s->level = -1;
	}
}

static int on_tile(struct session *s, const struct proto_tile *t, const uint8_t *px)
{
	if (!s->open)
		return CMD_OK;
	if (t->format != (uint32_t)s->o->format)
		return fail(s, "the server sent a tile of format %u; the shot was opened as %s",
			    t->format, s->o->format == PROTO_RGBA16F ? "rgba16f" : "rgba8");
	if (t->x > s->width || t->width > s->width - t->x || t->y > s->height ||
	    t->height > s->height - t->y)
		return fail(s, "the server sent a tile at (%u, %u) of %ux%u, outside the %ux%u "
			    "image", t->x, t->y, t->width, t->height, s->width, s->height);
	new_edit(s, t->edit);
	if (t->level != s->final_level || t->edit != s->newest)
		return CMD_OK;
	if (t->edit != s->image_edit) {
		s->image_edit = t->edit;
		s->image_pixels = 0;
		s->image_done = false;
	}
	size_t bpp = pixel_bytes(s), row = (size_t)t->width * bpp;
	for (uint32_t y = 0; y < t->height; y++)
		memcpy(s->image + ((size_t)(t->y + y) * s->width + t->x) * bpp, px + y * row, row);
	s->image_pixels += (uint64_t)t->width * t->height;
	return CMD_OK;
}

static int on_level(struct session *s, const cJSON *j)
{
	int64_t edit = edit_of(j, "edit");
	double l = num(j, "level", -1);
	if (edit < 0 || !(l >= 0 && l <= 16))
		return CMD_OK;
	new_edit(s, edit);
	if (edit != s->newest || (int)l <= s->level)
		return CMD_OK;
	s->level = (int)l;
	s->level_ms = num(j, "ms", 0);
	if ((uint32_t)l == s->final_level && s->open) {
		uint64_t want = (uint64_t)s->width * s->height;
		uint64_t got = s->image_edit == edit ? s->image_pixels : 0;
		if (got != want)
			return fail(s, "the final level of edit %lld came with tiles covering %llu "
				    "pixels of %llu", (long long)edit, (unsigned long long)got,
				    (unsigned long long)want);
		s->image_done = true;
	}
	return CMD_OK;
}

/*
 * One event from the server, whatever command runs: tiles into the image,
 * levels and edits into the state, progress shown, errors reported.
 * @watching prints every message.
 */
static int on_event(struct session *s, struct remote_event *ev, bool watching)
{
	switch (ev->kind) {
	case REMOTE_TILE:
		return ev->t_ms < s->open_ms ? CMD_OK : on_tile(s, &ev->tile, ev->pixels);
	case REMOTE_INVALID:
		return fail(s, "the server sent %s", ev->reason);
	case REMOTE_CLOSED:
		return fail(s, "the server closed the connection (%d%s%s)", ev->close_code,
			    ev->reason[0] ? ": " : "", ev->reason);
	case REMOTE_TEXT:
		break;
	default:
		return CMD_OK;
	}
	const cJSON *j = ev->json;
	if (watching) {
		if (s->o->json)
			print_json(j);
		else
			print_line(j);
	}
	if (!strcmp(ev->op, "level"))
		return ev->t_ms < s->open_ms ? CMD_OK : on_level(s, j);
	if (!strcmp(ev->op, "progress") && !watching && !s->o->quiet && !s->o->json)
		fprintf(stderr, "%s: %.0f %% %s\n", str(j, "shot"), 100.0 * num(j, "fraction", 0),
			str(j, "what"));
	if (!strcmp(ev->op, "closed"))
		s->open = false;
	const char *code, *msg;
	if (!watching && remote_reply_error(j, &code, &msg))
		return fail(s, "%s: %s", code, without_op(msg, s->cmd));
	return CMD_OK;
}

/* A bake's progress while `open` waits for its reply. */
static void on_progress(void *user, const cJSON *msg)
{
	const struct options *o = user;
	if (o->json)
		print_json(msg);
	else if (!o->quiet)
		fprintf(stderr, "%s: %.0f %% %s\n", str(msg, "shot"), 100.0 * num(msg, "fraction", 0),
			str(msg, "what"));
}

/* Take in what has arrived, without waiting. */
static int drain(struct session *s)
{
	struct remote_event ev;
	int rc = CMD_OK;
	while (rc == CMD_OK && remote_next(s->r, &ev, 0) != REMOTE_TIMEOUT) {
		rc = on_event(s, &ev, false);
		remote_event_finish(&ev);
	}
	return rc;
}

static int timeout_ms(const struct session *s)
{
	return (int)(s->o->timeout_s * 1e3);
}

/* Send @req and take its reply (the caller's); an error reply is reported. */
static int request(struct session *s, cJSON *req, cJSON **reply)
{
	*reply = NULL;
	if (!req)
		return fail(s, "out of memory");
	bool ok = remote_request(s->r, req, reply, timeout_ms(s));
	char op[32];
	snprintf(op, sizeof(op), "%s", str(req, "op"));
	cJSON_Delete(req);
	if (!ok)
		return fail(s, "%s", remote_error(s->r));
	const char *code, *msg;
	if (remote_reply_error(*reply, &code, &msg)) {
		int rc = fail(s, "%s: %s", code, without_op(msg, op));
		cJSON_Delete(*reply);
		*reply = NULL;
		return rc;
	}
	if (s->o->json)
		print_json(*reply);
	return CMD_OK;
}

static cJSON *new_request(const char *op)
{
	cJSON *j = cJSON_CreateObject();
	if (j && !cJSON_AddStringToObject(j, "op", op)) {
		cJSON_Delete(j);
		return NULL;
	}
	return j;
}

/* A request naming a light: {"op":OP,"light":LIGHT} (LIGHT NULL: null). */
static cJSON *light_request(const char *op, const char *light)
{
	cJSON *j = new_request(op);
	if (j && !(light ? cJSON_AddStringToObject(j, "light", light) :
			   cJSON_AddNullToObject(j, "light"))) {
		cJSON_Delete(j);
		return NULL;
	}
	return j;
}

/* {"PARAM": V or [V, ...], ...} from the assignments to @light (NULL: all). */
static cJSON *params_object(const struct step *st, const char *light)
{
	cJSON *p = cJSON_CreateObject();
	for (int i = 0; p && i < st->nassigns; i++) {
		const struct assign *a = &st->assigns[i];
		if (light && strcmp(a->light, light))
			continue;
		cJSON *v = a->n == 1 ? cJSON_CreateNumber(a->values[0]) : cJSON_CreateArray();
		for (uint32_t k = 0; v && a->n > 1 && k < a->n; k++) {
			cJSON *x = cJSON_CreateNumber(a->values[k]);
			if (!x || !cJSON_AddItemToArray(v, x)) {
				cJSON_Delete(x);
				cJSON_Delete(v);
				v = NULL;
			}
		}
		cJSON_DeleteItemFromObjectCaseSensitive(p, a->param);
		if (!v || !cJSON_AddItemToObject(p, a->param, v)) {
			cJSON_Delete(v);
			cJSON_Delete(p);
			p = NULL;
		}
	}
	return p;
}

/* An edit request: its ack's edit becomes the newest. */
static int edit(struct session *s, cJSON *req, const char *what, bool tiles)
{
	cJSON *reply;
	int rc = request(s, req, &reply);
	if (rc != CMD_OK)
		return rc;
	int64_t e = edit_of(reply, "edit");
	/* a freeze is acknowledged with no tiles to come: its edit is not waited for */
	if (tiles && e >= 0)
		new_edit(s, e);
	if (!s->o->json && !s->o->quiet) {
		if (e >= 0)
			fprintf(stderr, "%s: edit %lld\n", what, (long long)e);
		else
			fprintf(stderr, "%s: done\n", what);
	}
	cJSON_Delete(reply);
	return CMD_OK;
}

static int do_set(struct session *s, const struct step *st)
{
	/* one request per light, in the order the lights first appear */
	for (int i = 0; i < st->nassigns; i++) {
		const char *light = st->assigns[i].light;
		bool seen = false;
		for (int k = 0; k < i && !seen; k++)
			seen = !strcmp(st->assigns[k].light, light);
		if (seen)
			continue;
		cJSON *req = light_request("set", light);
		cJSON *p = req ? params_object(st, light) : NULL;
		if (req && (!p || !cJSON_AddItemToObject(req, "params", p))) {
			cJSON_Delete(p);
			cJSON_Delete(req);
			req = NULL;
		}
		char what[300];
		snprintf(what, sizeof(what), "set %s", light);
		int rc = edit(s, req, what, true);
		if (rc != CMD_OK)
			return rc;
	}
	return CMD_OK;
}

static int do_add_light(struct session *s, const struct step *st)
{
	cJSON *req = light_request("add_light", st->arg);
	cJSON *p = req ? params_object(st, NULL) : NULL;
	if (req && (!cJSON_AddStringToObject(req, "shader", st->shader) || !p ||
		    !cJSON_AddItemToObject(req, "params", p))) {
		cJSON_Delete(p);
		cJSON_Delete(req);
		req = NULL;
	}
	char what[300];
	snprintf(what, sizeof(what), "add-light %s", st->arg);
	return edit(s, req, what, true);
}

/* mute/unmute, freeze/unfreeze: {"op":OP,"light":L,FLAG:on}. */
static int do_flag(struct session *s, const struct step *st, const char *op, bool on)
{
	cJSON *req = light_request(op, st->arg);
	if (req && !cJSON_AddBoolToObject(req, op, on)) {
		cJSON_Delete(req);
		req = NULL;
	}
	char what[300];
	snprintf(what, sizeof(what), "%s %s", st->name, st->arg);
	return edit(s, req, what, strcmp(op, "freeze") != 0);
}

static int do_open(struct session *s, const struct step *st)
{
	cJSON *req = new_request("open"), *reply;
	/* a shot open before is closed by this one: its tiles are not this one's */
	s->open = false;
	if (req && (!cJSON_AddStringToObject(req, "shot", st->arg) ||
		    !cJSON_AddStringToObject(req, "format", s->o->format == PROTO_RGBA16F ?
					     "rgba16f" : "rgba8"))) {
		cJSON_Delete(req);
		req = NULL;
	}
	int rc = request(s, req, &reply);
	if (rc != CMD_OK)
		return rc;
	double w = num(reply, "width", 0), h = num(reply, "height", 0);
	double levels = num(reply, "levels", FINAL_LEVEL + 1);
	if (!(w >= 1 && h >= 1 && w * h <= 1 << 28 && levels >= 1 && levels <= 16)) {
		cJSON_Delete(reply);
		return fail(s, "the server's reply gives no sensible image size (%gx%g, %g levels)",
			    w, h, levels);
	}
	free(s->image);
	s->width = (uint32_t)w;
	s->height = (uint32_t)h;
	s->final_level = (uint32_t)levels - 1;
	s->image = calloc((size_t)s->width * s->height, pixel_bytes(s));
	if (!s->image) {
		cJSON_Delete(reply);
		return fail(s, "out of memory for a %ux%u image", s->width, s->height);
	}
	s->open = true;
	s->open_ms = remote_reply_ms(s->r);
	s->newest = -1;
	s->level = -1;
	s->image_edit = -1;
	s->image_pixels = 0;
	s->image_done = false;
	new_edit(s, edit_of(reply, "edit") >= 0 ? edit_of(reply, "edit") : 0);
	if (!s->o->json && !s->o->quiet) {
		fprintf(stderr, "opened %s: %ux%u, edit %lld; lights:", st->arg, s->width,
			s->height, (long long)s->newest);
		const cJSON *lights = cJSON_GetObjectItemCaseSensitive(reply, "lights");
		const cJSON *l;
		cJSON_ArrayForEach(l, lights)
			fprintf(stderr, " %s (%s)", str(l, "name"), str(l, "shader"));
		fprintf(stderr, "\n");
	}
	cJSON_Delete(reply);
	return CMD_OK;
}

static bool reached(const struct session *s, int level, bool image)
{
	if (s->newest < 0 || s->level < level)
		return false;
	return !image || (s->image_done && s->image_edit == s->newest);
}

/* Wait until the newest edit reaches @level (and, with @image, its final image is whole). */
static int wait_for(struct session *s, int level, bool image)
{
	if (!s->open)
		return fail(s, "no shot is open");
	if (level > (int)s->final_level)
		level = (int)s->final_level;
	double deadline = remote_now_ms() + s->o->timeout_s * 1e3;
	while (!reached(s, level, image)) {
		double left = deadline - remote_now_ms();
		struct remote_event ev;
		enum remote_kind k = remote_next(s->r, &ev, left > 0 ? (int)left + 1 : 0);
		if (k == REMOTE_TIMEOUT)
			return fail(s, "timed out after %g s waiting for edit %lld to reach level %d "
				    "(it is at %d)", s->o->timeout_s, (long long)s->newest, level,
				    s->level);
		int rc = on_event(s, &ev, false);
		remote_event_finish(&ev);
		if (rc != CMD_OK)
			return rc;
	}
	return CMD_OK;
}

static int do_wait(struct session *s, const struct step *st)
{
	int rc = wait_for(s, st->level, false);
	if (rc != CMD_OK)
		return rc;
	if (s->o->json)
		printf("{\"op\":\"wait\",\"edit\":%lld,\"level\":%d,\"ms\":%.3f}\n",
		       (long long)s->newest, s->level, s->level_ms);
	else if (!s->o->quiet)
		fprintf(stderr, "edit %lld: level %d (%.1f ms on the server)\n", (long long)s->newest,
			s->level, s->level_ms);
	return CMD_OK;
}

static int do_snapshot(struct session *s, const struct step *st)
{
	int rc = wait_for(s, (int)s->final_level, true);
	if (rc != CMD_OK)
		return rc;
	size_t n = (size_t)s->width * s->height;
	bool ok;
	if (s->o->format == PROTO_RGBA8) {
		ok = reyes_png_write(st->arg, s->image, s->width, s->height, 4, stderr);
	} else {
		/* the half floats as they came, through float, to the same EXR writer as
		 * `relight preview --half` */
		float *f = malloc(n * 4 * sizeof(float));
		ok = f != NULL;
		for (size_t i = 0; ok && i < n * 4; i++)
			f[i] = shot_half_value((uint16_t)(s->image[2 * i] | s->image[2 * i + 1] << 8));
		static const char *const names[4] = { "R", "G", "B", "A" };
		struct reyes_image im = { .width = s->width, .height = s->height, .nchannels = 4,
					  .channel_names = (const char **)names, .data = f };
		ok = ok && reyes_image_write_exr(st->arg, &im, true, stderr);
		free(f);
	}
	if (!ok)
		return fail(s, "cannot write %s", st->arg);
	if (s->o->json) {
		cJSON *j = new_request("snapshot");
		if (j && cJSON_AddStringToObject(j, "file", st->arg) &&
		    cJSON_AddNumberToObject(j, "edit", (double)s->newest) &&
		    cJSON_AddNumberToObject(j, "width", s->width) &&
		    cJSON_AddNumberToObject(j, "height", s->height))
			print_json(j);
		cJSON_Delete(j);
	} else if (!s->o->quiet) {
		fprintf(stderr, "wrote %s: %ux%u, edit %lld, final level\n", st->arg, s->width,
			s->height, (long long)s->newest);
	}
	return CMD_OK;
}

static int do_list(struct session *s)
{
	cJSON *reply;
	int rc = request(s, new_request("list"), &reply);
	if (rc != CMD_OK || s->o->json) {
		cJSON_Delete(reply);
		return rc;
	}
	const cJSON *shot;
	cJSON_ArrayForEach(shot, cJSON_GetObjectItemCaseSensitive(reply, "shots")) {
		const cJSON *baked = cJSON_GetObjectItemCaseSensitive(shot, "baked");
		printf("%-24s %5.0fx%-5.0f %s\n", str(shot, "name"), num(shot, "width", 0),
		       num(shot, "height", 0), cJSON_IsFalse(baked) ? "not baked" : "baked");
	}
	fflush(stdout);
	cJSON_Delete(reply);
	return CMD_OK;
}

static int do_stats(struct session *s)
{
	cJSON *reply;
	int rc = request(s, new_request("stats"), &reply);
	if (rc != CMD_OK || s->o->json) {
		cJSON_Delete(reply);
		return rc;
	}
	for (const cJSON *m = reply->child; m; m = m->next) {
		if (!m->string || !strcmp(m->string, "op") || !strcmp(m->string, "id"))
			continue;
		char *t = cJSON_IsString(m) ? NULL : cJSON_PrintUnformatted(m);
		printf("%s: %s\n", m->string, t ? t : cJSON_IsString(m) ? m->valuestring : "?");
		cJSON_free(t);
	}
	fflush(stdout);
	cJSON_Delete(reply);
	return CMD_OK;
}

static int do_server_snapshot(struct session *s)
{
	cJSON *reply;
	int rc = request(s, new_request("snapshot"), &reply);
	if (rc == CMD_OK && !s->o->json) {
		printf("%s\n", str(reply, "path"));
		fflush(stdout);
	}
	cJSON_Delete(reply);
	return rc;
}

static int do_watch(struct session *s, const struct step *st)
{
	double deadline = remote_now_ms() + st->seconds * 1e3;
	for (;;) {
		double left = deadline - remote_now_ms();
		if (left <= 0)
			return CMD_OK;
		struct remote_event ev;
		if (remote_next(s->r, &ev, (int)left + 1) == REMOTE_TIMEOUT)
			return CMD_OK;
		int rc = on_event(s, &ev, true);
		remote_event_finish(&ev);
		if (rc != CMD_OK)
			return rc;
	}
}

static int run_step(struct session *s, const struct step *st)
{
	s->cmd = st->name;
	int rc = drain(s);
	if (rc != CMD_OK)
		return rc;
	switch (st->kind) {
	case STEP_LIST:
		rc = do_list(s);
		break;
	case STEP_OPEN:
		rc = do_open(s, st);
		break;
	case STEP_SET:
		rc = do_set(s, st);
		break;
	case STEP_MUTE:
	case STEP_UNMUTE:
		rc = do_flag(s, st, "mute", st->kind == STEP_MUTE);
		break;
	case STEP_FREEZE:
	case STEP_UNFREEZE:
		rc = do_flag(s, st, "freeze", st->kind == STEP_FREEZE);
		break;
	case STEP_SOLO: {
		char what[300];
		snprintf(what, sizeof(what), "solo %s", st->arg);
		rc = edit(s, light_request("solo", strcmp(st->arg, "none") ? st->arg : NULL), what,
			  true);
		break;
	}
	case STEP_ADD_LIGHT:
		rc = do_add_light(s, st);
		break;
	case STEP_REMOVE_LIGHT: {
		char what[300];
		snprintf(what, sizeof(what), "remove-light %s", st->arg);
		rc = edit(s, light_request("remove_light", st->arg), what, true);
		break;
	}
	case STEP_WAIT:
		rc = do_wait(s, st);
		break;
	case STEP_SNAPSHOT:
		rc = do_snapshot(s, st);
		break;
	case STEP_SERVER_SNAPSHOT:
		rc = do_server_snapshot(s);
		break;
	case STEP_STATS:
		rc = do_stats(s);
		break;
	case STEP_WATCH:
		rc = do_watch(s, st);
		break;
	}
	return rc == CMD_OK ? drain(s) : rc;
}

int cmd_remote(int argc, char **argv)
{
	struct options o = { .timeout_s = 60.0 };
	const char *token_file = NULL, *format = NULL;
	static const struct option long_opts[] = {
		{ "help", no_argument, NULL, 'h' },
		{ "token", required_argument, NULL, 't' },
		{ "token-file", required_argument, NULL, 'T' },
		{ "format", required_argument, NULL, 'f' },
		{ "timeout", required_argument, NULL, 's' },
		{ "ca-file", required_argument, NULL, 'C' },
		{ "insecure", no_argument, NULL, 'I' },
		{ "json", no_argument, NULL, 'j' },
		{ "quiet", no_argument, NULL, 'q' },
		{ NULL, 0, NULL, 0 },
	};
	optind = 1;
	opterr = 0;
	int opt;
	/* '+': options end at the URL, so that the commands' arguments (a negative
	 * value, say) are never taken for options */
	while ((opt = getopt_long(argc, argv, "+:hq", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 't':
			o.token = optarg;
			break;
		case 'T':
			token_file = optarg;
			break;
		case 'f':
			if (strcmp(optarg, "rgba8") && strcmp(optarg, "rgba16f"))
				return usage_error("--format needs rgba8 or rgba16f, not '%s'", optarg);
			format = optarg;
			break;
		case 's':
			if (!cmd_parse_double(optarg, 0.001, 1e6, &o.timeout_s))
				return usage_error("--timeout needs a number of seconds, not '%s'",
						   optarg);
			break;
		case 'C':
			o.ca_file = optarg;
			break;
		case 'I':
			o.insecure = true;
			break;
		case 'j':
			o.json = true;
			break;
		case 'q':
			o.quiet = true;
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}
	if (o.token && token_file)
		return usage_error("--token and --token-file are exclusive");
	if (optind >= argc)
		return usage_error("no URL");
	const char *url = argv[optind++];
	char err[1024];
	if (!remote_url_check(url, err, sizeof(err)))
		return usage_error("%s", err);
	if (optind >= argc)
		return usage_error("no command after the URL");
	int nsteps = 0;
	struct step *steps = parse_steps(argc, argv, optind, &nsteps);
	if (!steps)
		return CMD_USAGE;

	/* the tile format: what the snapshots need, unless given */
	bool want_exr = false, want_png = false;
	for (int i = 0; i < nsteps; i++)
		if (steps[i].kind == STEP_SNAPSHOT) {
			want_exr |= ends_with(steps[i].arg, ".exr");
			want_png |= ends_with(steps[i].arg, ".png");
		}
	o.format = format ? (strcmp(format, "rgba16f") ? PROTO_RGBA8 : PROTO_RGBA16F) :
		   want_exr ? PROTO_RGBA16F : PROTO_RGBA8;
	int rc = CMD_OK;
	if ((want_exr && o.format != PROTO_RGBA16F) || (want_png && o.format != PROTO_RGBA8)) {
		rc = usage_error("a snapshot to .exr needs rgba16f tiles and one to .png rgba8 "
				 "tiles: one connection gets one format (see --format)");
		goto out_steps;
	}

	char token[512];
	if (token_file) {
		if (!read_token(token_file, token, sizeof(token))) {
			rc = CMD_FAILED;
			goto out_steps;
		}
		o.token = token;
	}
	struct remote_opts ro = { .timeout_ms = (int)(o.timeout_s * 1e3), .ca_file = o.ca_file,
				  .insecure = o.insecure, .progress = on_progress,
				  .progress_user = &o };
	struct remote *r = remote_connect(url, o.token, &ro, err, sizeof(err));
	if (!r) {
		fprintf(stderr, "relight remote: cannot connect: %s\n", err);
		rc = CMD_FAILED;
		goto out_steps;
	}
	struct session s = { .r = r, .o = &o, .cmd = "", .newest = -1, .level = -1,
			     .image_edit = -1 };
	for (int i = 0; rc == CMD_OK && i < nsteps; i++)
		rc = run_step(&s, &steps[i]);
	free(s.image);
	remote_close(r);
out_steps:
	free_steps(steps, nsteps);
	return rc;
}

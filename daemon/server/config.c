/*
 * relightd's settings. One table below describes every setting once: its
 * name (the long option and the config file's key), the field it fills, its
 * range and its line of help. The command line, the config file and the
 * usage text all read that table, so they cannot disagree.
 *
 * The token file is read here too, and the Origin check, since both are
 * plain functions of the settings.
 */
#include "config.h"

#include "fileutil.h"
#include "log.h"

#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

/* Config and token files are small; a bigger one is a mistake (a wrong path). */
#define SETTINGS_FILE_MAX (1u << 20)

/* getopt_long values of the long options: past every single-character option. */
#define OPT_BASE 256

enum kind {
	K_LISTEN,  /* host[] and port */
	K_PATH,    /* a char[] field holding a path */
	K_SIZE,    /* a size_t field: a number of units of @scale bytes */
	K_COUNT,   /* a uint32_t field */
	K_LOG,     /* log_level */
	K_ORIGIN,  /* appended to origins[] */
	K_METRICS, /* metrics_token: "open" or "token" */
	K_CONFIG,  /* command line only: read a config file first */
	K_HELP,    /* command line only */
	K_VERSION, /* command line only */
	K_QUIET,   /* quiet; -q as well */
};

struct setting {
	const char *name;  /* long option, config key */
	enum kind kind;
	size_t off, size;  /* the field in struct srv_config, and its size */
	uint64_t min, max; /* numbers: the accepted range, in units */
	uint64_t scale;    /* K_SIZE: bytes per unit */
	const char *unit;  /* numbers: what one is a number of, for messages */
	bool nonempty;     /* K_PATH: "" is refused */
	const char *arg;   /* the argument's name in the usage text */
	const char *dflt;  /* the default, as the usage text shows it */
	const char *help;
};

#define FIELD(f) .off = offsetof(struct srv_config, f), .size = sizeof(((struct srv_config *)0)->f)

static const struct setting settings[] = {
	{ .name = "listen", .kind = K_LISTEN, .arg = "HOST:PORT", .dflt = "127.0.0.1:7878",
	  .help = "Address to listen on: HOST:PORT, :PORT (every interface) or "
		  "[IPV6]:PORT. Port 0 takes any free port and logs its number." },
	{ .name = "shots", .kind = K_PATH, FIELD(shots_dir), .nonempty = true, .arg = "DIR",
	  .dflt = ".",
	  .help = "Folder of the shot files (NAME.shot.exr) and the RIB scenes clients may "
		  "open; a RIB is baked into a shot file there when first opened." },
	{ .name = "token-file", .kind = K_PATH, FIELD(token_file), .arg = "FILE",
	  .dflt = "none: every client is an editor",
	  .help = "Tokens of the clients allowed in, with their roles (see Token file below)." },
	{ .name = "config", .kind = K_CONFIG, .arg = "FILE", .dflt = "none",
	  .help = "Read settings from FILE (see Config file below) before the other options, "
		  "wherever it appears; the command line overrides the file." },
	{ .name = "gpu-budget", .kind = K_SIZE, FIELD(gpu_budget), .min = 1, .max = 1u << 24,
	  .scale = 1u << 20, .unit = "megabytes", .arg = "MB", .dflt = "2048",
	  .help = "GPU memory the resident shots may hold; shots are evicted to stay "
		  "within it." },
	{ .name = "tls-cert", .kind = K_PATH, FIELD(cert), .arg = "FILE", .dflt = "none: plain ws://",
	  .help = "PEM certificate chain: serve wss:// and https:// (needs --tls-key)." },
	{ .name = "tls-key", .kind = K_PATH, FIELD(key), .arg = "FILE", .dflt = "none",
	  .help = "PEM private key of --tls-cert." },
	{ .name = "viewer", .kind = K_PATH, FIELD(viewer_dir), .arg = "DIR",
	  .dflt = "relight's own viewer (clients/web)",
	  .help = "Folder of the browser viewer's static files, served over HTTP GET." },
	{ .name = "snapshots", .kind = K_PATH, FIELD(snapshot_dir), .arg = "DIR",
	  .dflt = "SHOTS/snapshots",
	  .help = "Folder the OpenEXR snapshots that clients ask for are written to." },
	{ .name = "allow-origin", .kind = K_ORIGIN, .arg = "ORIGIN", .dflt = "any origin",
	  .help = "Let browser pages of ORIGIN (scheme://host[:port], compared exactly, "
		  "ignoring case) connect. Repeat it for more, up to 32. Clients that send "
		  "no Origin header are always let in." },
	{ .name = "max-message", .kind = K_SIZE, FIELD(max_message), .min = 1, .max = 16384,
	  .scale = 1024, .unit = "kilobytes", .arg = "KB", .dflt = "64",
	  .help = "Largest incoming WebSocket message (1 to 16384)." },
	{ .name = "max-clients", .kind = K_COUNT, FIELD(max_clients), .min = 1, .max = 65536,
	  .unit = "clients", .arg = "N", .dflt = "256",
	  .help = "Clients connected at once; more are refused (1 to 65536)." },
	{ .name = "max-shots", .kind = K_COUNT, FIELD(max_shots), .min = 1, .max = 4096,
	  .unit = "shots", .arg = "N", .dflt = "16",
	  .help = "Shots resident in GPU memory at once (1 to 4096)." },
	{ .name = "max-lights", .kind = K_COUNT, FIELD(max_lights), .min = 1, .max = 65536,
	  .unit = "lights", .arg = "N", .dflt = "1024",
	  .help = "Lights in one shot, added ones included (1 to 65536); a shot may have had "
		  "4 x N lights in all, removed ones included." },
	{ .name = "client-queue", .kind = K_SIZE, FIELD(client_queue), .min = 1, .max = 65536,
	  .scale = 1u << 20, .unit = "megabytes", .arg = "MB", .dflt = "64",
	  .help = "Frames queued for one slow client, at most (1 to 65536). Tiles that a "
		  "newer edit has superseded are dropped unsent." },
	{ .name = "tile-size", .kind = K_COUNT, FIELD(tile_size), .min = 16, .max = 1024,
	  .unit = "pixels", .arg = "N", .dflt = "128",
	  .help = "Width and height of the image tiles sent (16 to 1024)." },
	{ .name = "hello-timeout", .kind = K_COUNT, FIELD(hello_timeout), .min = 1, .max = 3600,
	  .unit = "seconds", .arg = "S", .dflt = "10",
	  .help = "A connection that has not had its hello accepted this many seconds after "
		  "the upgrade is closed (1008) (1 to 3600)." },
	{ .name = "max-preauth", .kind = K_COUNT, FIELD(max_preauth), .min = 1, .max = 65536,
	  .unit = "connections", .arg = "N", .dflt = "128",
	  .help = "Connections waiting for their hello at once; more are refused at the "
		  "upgrade (1 to 65536). They do not count against --max-clients, and each "
		  "may send one message of at most 4 KB until its hello is accepted." },
	{ .name = "metrics", .kind = K_METRICS, .arg = "open|token", .dflt = "open",
	  .help = "Who may GET /metrics: anyone, or (token) requests with the header "
		  "\"Authorization: Bearer TOKEN\" naming a token of --token-file." },
	{ .name = "snapshot-max-count", .kind = K_COUNT, FIELD(snapshot_max_count), .min = 1,
	  .max = 1000000, .unit = "snapshots", .arg = "N", .dflt = "1000",
	  .help = "Snapshots (.exr files) the snapshots folder may hold; a snapshot past it "
		  "is refused, nothing is deleted (1 to 1000000)." },
	{ .name = "snapshot-max-bytes", .kind = K_SIZE, FIELD(snapshot_max_bytes), .min = 1,
	  .max = 1u << 24, .scale = 1u << 20, .unit = "megabytes", .arg = "MB", .dflt = "10240",
	  .help = "Megabytes of .exr files the snapshots folder may hold; a snapshot that "
		  "would pass it (counted uncompressed) is refused, nothing is deleted." },
	{ .name = "snapshot-rate", .kind = K_COUNT, FIELD(snapshot_rate), .min = 1, .max = 100000,
	  .unit = "snapshots", .arg = "N", .dflt = "20",
	  .help = "Snapshots one client may ask for per minute (a burst of N, then one every "
		  "60/N s); more are refused (1 to 100000)." },
	{ .name = "worker-stall", .kind = K_COUNT, FIELD(worker_stall), .min = 1, .max = 86400,
	  .unit = "seconds", .arg = "S", .dflt = "60",
	  .help = "/healthz answers 503 when the render worker has finished no job for S "
		  "seconds while jobs wait (1 to 86400)." },
	{ .name = "log-level", .kind = K_LOG, .arg = "LEVEL", .dflt = "info",
	  .help = "error, warn, info or debug." },
	{ .name = "log-rate", .kind = K_COUNT, FIELD(log_rate), .min = 0, .max = 1000000,
	  .unit = "lines", .arg = "N", .dflt = "10",
	  .help = "Lines a second that each line of the log about a client or its messages "
		  "may print; the rest are counted in the next one printed (0: no limit)." },
	{ .name = "quiet", .kind = K_QUIET,
	  .help = "Errors only (no warnings, no information), whatever --log-level says." },
	{ .name = "version", .kind = K_VERSION, .help = "Print the version and exit." },
	{ .name = "help", .kind = K_HELP, .help = "Print this text and exit." },
};

#define NSETTINGS (sizeof(settings) / sizeof(settings[0]))

static const char *const log_names[] = {
	[RL_LOG_ERROR] = "error",
	[RL_LOG_WARN] = "warn",
	[RL_LOG_INFO] = "info",
	[RL_LOG_DEBUG] = "debug",
};

void srv_config_defaults(struct srv_config *c)
{
	memset(c, 0, sizeof(*c));
	snprintf(c->host, sizeof(c->host), "127.0.0.1");
	c->port = 7878;
	snprintf(c->shots_dir, sizeof(c->shots_dir), ".");
	c->gpu_budget = (size_t)2048 << 20;
	c->max_message = (size_t)64 << 10;
	c->max_clients = 256;
	c->max_shots = 16;
	c->max_lights = 1024;
	c->client_queue = (size_t)64 << 20;
	c->tile_size = 128;
	c->hello_timeout = 10;
	c->max_preauth = 128;
	c->log_rate = 10;
	c->snapshot_max_count = 1000;
	c->snapshot_max_bytes = (size_t)10240 << 20;
	c->snapshot_rate = 20;
	c->worker_stall = 60;
	c->log_level = RL_LOG_INFO;
	/* snapshot_dir stays empty: srv_config_parse_args derives it from the final shots_dir. */
}

void srv_config_free(struct srv_config *c)
{
	if (!c)
		return;
	for (uint32_t i = 0; i < c->norigins && i < SRV_MAX_ORIGINS; i++) {
		free(c->origins[i]);
		c->origins[i] = NULL;
	}
	c->norigins = 0;
}

/* ---- values ---- */

/* A decimal number: digits only (strtoull alone would take "-1", " 7" and "0x10"). */
static bool parse_number(const char *s, uint64_t *out, bool *overflow)
{
	*overflow = false;
	if (!isdigit((unsigned char)s[0]))
		return false;
	char *end;
	errno = 0;
	unsigned long long v = strtoull(s, &end, 10);
	if (*end)
		return false;
	if (errno == ERANGE) {
		*overflow = true;
		return false;
	}
	*out = v;
	return true;
}

/* Whether @s (@len bytes) holds a space or a control character. */
static bool has_space_or_control(const char *s, size_t len)
{
	for (size_t i = 0; i < len; i++) {
		unsigned char ch = (unsigned char)s[i];
		if (ch <= ' ' || ch == 0x7f)
			return true;
	}
	return false;
}

/*
 * listen := host ':' port | ':' port | '[' address ']' ':' port
 * The host is taken up to the last colon, so an IPv6 address needs brackets.
 */
static bool set_listen(struct srv_config *c, const char *v, char *why, size_t n)
{
	const char *host, *port;
	size_t hostlen;
	if (v[0] == '[') {
		const char *close = strchr(v, ']');
		if (!close || close[1] != ':' || close == v + 1) {
			snprintf(why, n, "'%.80s' is not [ADDRESS]:PORT", v);
			return false;
		}
		host = v + 1;
		hostlen = (size_t)(close - host);
		port = close + 2;
	} else {
		const char *colon = strrchr(v, ':');
		if (!colon) {
			snprintf(why, n, "'%.80s' is not HOST:PORT, :PORT or [ADDRESS]:PORT", v);
			return false;
		}
		host = v;
		hostlen = (size_t)(colon - v);
		port = colon + 1;
		if (memchr(host, ':', hostlen)) {
			snprintf(why, n, "'%.80s': put an IPv6 address in brackets, as [::1]:7878", v);
			return false;
		}
	}
	if (hostlen >= sizeof(c->host)) {
		snprintf(why, n, "host name longer than %zu bytes", sizeof(c->host) - 1);
		return false;
	}
	if (has_space_or_control(host, hostlen) || memchr(host, '/', hostlen) ||
	    memchr(host, '[', hostlen) || memchr(host, ']', hostlen)) {
		snprintf(why, n, "'%.80s': bad character in the host", v);
		return false;
	}
	uint64_t p;
	bool overflow;
	if (!parse_number(port, &p, &overflow) || p > 65535) {
		snprintf(why, n, "'%.80s': the port must be a number from 0 to 65535", v);
		return false;
	}
	memcpy(c->host, host, hostlen);
	c->host[hostlen] = '\0';
	c->port = (int)p;
	return true;
}

/*
 * origin := scheme "://" host [ ':' port ]
 * What browsers send in the Origin header: no path, no user, no trailing slash.
 */
static bool origin_ok(const char *o)
{
	if (!isalpha((unsigned char)o[0]))
		return false;
	const char *p = o;
	while (isalnum((unsigned char)*p) || *p == '+' || *p == '-' || *p == '.')
		p++;
	if (strncmp(p, "://", 3) != 0)
		return false;
	const char *host = p + 3;
	size_t len = strlen(host);
	if (!len || has_space_or_control(host, len) || strpbrk(host, "/?#@\\"))
		return false;
	/* An IPv6 host is bracketed; the port, if any, follows the brackets. */
	const char *rest = host;
	if (host[0] == '[') {
		const char *close = strchr(host, ']');
		if (!close || close == host + 1)
			return false;
		rest = close + 1;
		if (*rest && *rest != ':')
			return false;
	}
	const char *colon = strchr(rest, ':');
	if (!colon)
		return true;
	if (colon == host)
		return false;
	uint64_t port;
	bool overflow;
	return strchr(colon + 1, ':') == NULL && strlen(colon + 1) <= 5 &&
	       parse_number(colon + 1, &port, &overflow) && port >= 1 && port <= 65535;
}

static bool add_origin(struct srv_config *c, const char *v, char *why, size_t n)
{
	if (!origin_ok(v)) {
		snprintf(why, n,
			 "'%.80s' is not an origin: scheme://host[:port] without a path, as "
			 "https://viewer.example.com",
			 v);
		return false;
	}
	for (uint32_t i = 0; i < c->norigins; i++)
		if (!strcasecmp(c->origins[i], v))
			return true;
	if (c->norigins >= SRV_MAX_ORIGINS) {
		snprintf(why, n, "more than %d origins", SRV_MAX_ORIGINS);
		return false;
	}
	char *dup = strdup(v);
	if (!dup) {
		snprintf(why, n, "out of memory");
		return false;
	}
	c->origins[c->norigins++] = dup;
	return true;
}

/* Set @s from value @v; the reason, without the setting's name, in @why. */
static bool apply(struct srv_config *c, const struct setting *s, const char *v, char *why,
		  size_t n)
{
	char *field = (char *)c + s->off;
	uint64_t x;
	bool overflow;
	switch (s->kind) {
	case K_LISTEN:
		return set_listen(c, v, why, n);
	case K_PATH: {
		size_t len = strlen(v);
		if (s->nonempty && !len) {
			snprintf(why, n, "needs a path");
			return false;
		}
		if (len >= s->size) {
			snprintf(why, n, "path longer than %zu bytes", s->size - 1);
			return false;
		}
		memcpy(field, v, len + 1);
		return true;
	}
	case K_SIZE:
	case K_COUNT:
		if (!parse_number(v, &x, &overflow) && !overflow) {
			snprintf(why, n, "'%.80s' is not a number of %s", v, s->unit);
			return false;
		}
		if (overflow || x < s->min || x > s->max) {
			snprintf(why, n, "%.80s is out of range (%" PRIu64 " to %" PRIu64 " %s)", v,
				 s->min, s->max, s->unit);
			return false;
		}
		if (s->kind == K_SIZE) {
			/* The largest budgets exceed a 32-bit size_t. */
			if (x > SIZE_MAX / s->scale) {
				snprintf(why, n, "%.80s %s do not fit in memory here", v, s->unit);
				return false;
			}
			*(size_t *)(void *)field = (size_t)(x * s->scale);
		} else {
			*(uint32_t *)(void *)field = (uint32_t)x;
		}
		return true;
	case K_LOG:
		for (int i = RL_LOG_ERROR; i <= RL_LOG_DEBUG; i++) {
			if (!strcasecmp(v, log_names[i])) {
				c->log_level = i;
				return true;
			}
		}
		snprintf(why, n, "'%.80s' is not a log level (error, warn, info or debug)", v);
		return false;
	case K_ORIGIN:
		return add_origin(c, v, why, n);
	case K_METRICS:
		if (strcmp(v, "open") && strcmp(v, "token")) {
			snprintf(why, n, "'%.80s' is neither open nor token", v);
			return false;
		}
		c->metrics_token = !strcmp(v, "token");
		return true;
	case K_QUIET:
		if (strcasecmp(v, "true") && strcasecmp(v, "false") && strcmp(v, "1") &&
		    strcmp(v, "0")) {
			snprintf(why, n, "'%.80s' is not true or false", v);
			return false;
		}
		c->quiet = !strcasecmp(v, "true") || !strcmp(v, "1");
		return true;
	case K_CONFIG:
	case K_HELP:
	case K_VERSION:
		break;
	}
	snprintf(why, n, "not a setting");
	return false;
}

/* ---- config file ---- */

static bool is_blank(char ch)
{
	return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\v' || ch == '\f';
}

/* Trim blanks from both ends of [*b, *e). */
static void trim(const char **b, const char **e)
{
	while (*b < *e && is_blank(**b))
		(*b)++;
	while (*e > *b && is_blank((*e)[-1]))
		(*e)--;
}

/*
 * file := { line '\n' }
 * line := [ name '=' value ] [ comment ]      (blanks around each part ignored)
 * comment := '#' ...   at the start of a line or after a blank
 */
bool srv_config_parse_text(struct srv_config *c, const char *name, const char *text, size_t len,
			   char *err, size_t errlen)
{
	if (!name)
		name = "(config)";
	const char *p = text, *end = text + len;
	unsigned line = 0;
	char key[64], value[4200], why[512];
	while (p < end) {
		line++;
		const char *nl = memchr(p, '\n', (size_t)(end - p));
		const char *b = p, *e = nl ? nl : end;
		p = nl ? nl + 1 : end;
		if (memchr(b, '\0', (size_t)(e - b))) {
			snprintf(err, errlen, "%s:%u: NUL byte in the line", name, line);
			return false;
		}
		/* Cut the comment: a '#' first on the line or after a blank. */
		for (const char *q = b; q < e; q++) {
			if (*q == '#' && (q == b || is_blank(q[-1]))) {
				e = q;
				break;
			}
		}
		trim(&b, &e);
		if (b == e)
			continue;
		const char *eq = memchr(b, '=', (size_t)(e - b));
		const char *kb = b, *ke = eq ? eq : e;
		trim(&kb, &ke);
		if (!eq || kb == ke) {
			snprintf(err, errlen, "%s:%u: expected 'name = value'", name, line);
			return false;
		}
		const struct setting *s = NULL;
		size_t klen = (size_t)(ke - kb);
		if (klen < sizeof(key)) {
			memcpy(key, kb, klen);
			key[klen] = '\0';
			for (size_t i = 0; i < NSETTINGS; i++)
				if (!strcmp(settings[i].name, key))
					s = &settings[i];
		} else {
			snprintf(key, sizeof(key), "%.40s...", kb);
		}
		if (!s || s->kind == K_HELP || s->kind == K_VERSION) {
			snprintf(err, errlen, "%s:%u: unknown setting '%s'", name, line, key);
			return false;
		}
		if (s->kind == K_CONFIG) {
			snprintf(err, errlen, "%s:%u: config: a config file cannot name another",
				 name, line);
			return false;
		}
		const char *vb = eq + 1, *ve = e;
		trim(&vb, &ve);
		size_t vlen = (size_t)(ve - vb);
		if (vlen >= sizeof(value)) {
			snprintf(err, errlen, "%s:%u: %s: value longer than %zu bytes", name, line,
				 key, sizeof(value) - 1);
			return false;
		}
		memcpy(value, vb, vlen);
		value[vlen] = '\0';
		if (!apply(c, s, value, why, sizeof(why))) {
			snprintf(err, errlen, "%s:%u: %s: %s", name, line, key, why);
			return false;
		}
	}
	return true;
}

bool srv_config_load_file(struct srv_config *c, const char *path, char *err, size_t errlen)
{
	size_t len;
	char *text = rl_read_file(path, SETTINGS_FILE_MAX, &len, err, errlen);
	if (!text)
		return false;
	bool ok = srv_config_parse_text(c, path, text, len, err, errlen);
	free(text);
	return ok;
}

/* ---- command line ---- */

static void build_longopts(struct option *o)
{
	for (size_t i = 0; i < NSETTINGS; i++) {
		enum kind k = settings[i].kind;
		o[i] = (struct option){
			.name = settings[i].name,
			.has_arg = k == K_HELP || k == K_VERSION || k == K_QUIET ? no_argument
										    : required_argument,
			.flag = NULL,
			.val = k == K_HELP ? 'h' : k == K_QUIET ? 'q' : OPT_BASE + (int)i,
		};
	}
	o[NSETTINGS] = (struct option){ 0 };
}

/* The name of what getopt_long refused: the word it stopped at. */
static const char *offending(int argc, char **argv)
{
	int i = optind - 1;
	return i >= 1 && i < argc && argv[i] ? argv[i] : "?";
}

/* Fill what depends on several settings, and check what they must agree on. */
static bool finish(struct srv_config *c, char *err, size_t errlen)
{
	if (c->cert[0] && !c->key[0]) {
		snprintf(err, errlen, "--tls-cert: needs --tls-key (the certificate's private key)");
		return false;
	}
	if (c->key[0] && !c->cert[0]) {
		snprintf(err, errlen, "--tls-key: needs --tls-cert");
		return false;
	}
	if (c->metrics_token && !c->token_file[0]) {
		snprintf(err, errlen, "--metrics token: needs --token-file (the tokens it takes)");
		return false;
	}
	if (c->quiet)
		c->log_level = RL_LOG_ERROR;
	if (!c->snapshot_dir[0]) {
		size_t len = strlen(c->shots_dir);
		const char *sep = len && c->shots_dir[len - 1] == '/' ? "" : "/";
		int w = snprintf(c->snapshot_dir, sizeof(c->snapshot_dir), "%s%ssnapshots",
				 c->shots_dir, sep);
		if (w < 0 || (size_t)w >= sizeof(c->snapshot_dir)) {
			c->snapshot_dir[0] = '\0';
			snprintf(err, errlen,
				 "--shots: path too long to add /snapshots to (give --snapshots)");
			return false;
		}
	}
	return true;
}

bool srv_config_parse_args(struct srv_config *c, int argc, char **argv, FILE *out, char *err,
			   size_t errlen)
{
	struct option longopts[NSETTINGS + 1];
	build_longopts(longopts);
	/* Messages are ours (with the option's name); getopt prints nothing. */
	opterr = 0;
	int ch;

	/* First pass: --help wins over everything; --config files come before the options. */
	optind = 1;
	bool help = false, version = false;
	while ((ch = getopt_long(argc, argv, ":hq", longopts, NULL)) != -1) {
		if (ch == 'h')
			help = true;
		else if (ch >= OPT_BASE && settings[ch - OPT_BASE].kind == K_VERSION)
			version = true;
	}
	if (help) {
		srv_config_usage(out ? out : stdout);
		c->help = true;
		return true;
	}
	if (version) {
		c->version = true;
		return true;
	}
	optind = 1;
	while ((ch = getopt_long(argc, argv, ":hq", longopts, NULL)) != -1) {
		if (ch >= OPT_BASE && settings[ch - OPT_BASE].kind == K_CONFIG &&
		    !srv_config_load_file(c, optarg, err, errlen))
			return false;
	}

	/* Second pass: the options themselves. */
	optind = 1;
	bool cli_origins = false;
	char why[512];
	while ((ch = getopt_long(argc, argv, ":hq", longopts, NULL)) != -1) {
		if (ch == 'q') {
			c->quiet = true;
			continue;
		}
		if (ch == '?') {
			if (optopt >= OPT_BASE)
				snprintf(err, errlen, "--%s: takes no value",
					 settings[optopt - OPT_BASE].name);
			else if (optopt == 'h')
				snprintf(err, errlen, "--help: takes no value");
			else if (optopt == 'q')
				snprintf(err, errlen, "--quiet: takes no value");
			else if (optopt)
				snprintf(err, errlen, "unknown option '-%c' (see --help)", optopt);
			else
				snprintf(err, errlen, "unknown or ambiguous option '%.80s' (see --help)",
					 offending(argc, argv));
			return false;
		}
		if (ch == ':') {
			if (optopt >= OPT_BASE)
				snprintf(err, errlen, "--%s: needs a value",
					 settings[optopt - OPT_BASE].name);
			else
				snprintf(err, errlen, "'%.80s' needs a value", offending(argc, argv));
			return false;
		}
		if (ch < OPT_BASE || (size_t)(ch - OPT_BASE) >= NSETTINGS)
			continue;
		const struct setting *s = &settings[ch - OPT_BASE];
		if (s->kind == K_CONFIG || s->kind == K_VERSION)
			continue;
		if (s->kind == K_ORIGIN && !cli_origins) {
			/* The command line's list replaces the config file's. */
			srv_config_free(c);
			cli_origins = true;
		}
		if (!apply(c, s, optarg, why, sizeof(why))) {
			snprintf(err, errlen, "--%s: %s", s->name, why);
			return false;
		}
	}
	if (optind < argc) {
		snprintf(err, errlen, "unexpected argument '%.80s' (relightd takes options only)",
			 argv[optind]);
		return false;
	}
	return finish(c, err, errlen);
}

/* ---- usage ---- */

#define USAGE_INDENT 26
#define USAGE_WIDTH 79

/* A space that wrap() never breaks a line at. */
#define NBSP '\x1f'

/* Print @text word-wrapped from column @col (already reached) to USAGE_WIDTH. */
static void wrap(FILE *out, const char *text, int col, int indent)
{
	const char *p = text;
	while (*p) {
		while (*p == ' ')
			p++;
		size_t w = strcspn(p, " ");
		if (!w)
			break;
		if (col > indent && col + 1 + (int)w > USAGE_WIDTH) {
			fprintf(out, "\n%*s", indent, "");
			col = indent;
		} else if (col > indent) {
			fputc(' ', out);
			col++;
		}
		for (size_t i = 0; i < w; i++)
			fputc(p[i] == NBSP ? ' ' : p[i], out);
		col += (int)w;
		p += w;
	}
	fputc('\n', out);
}

static void paragraph(FILE *out, const char *text)
{
	fputs("  ", out);
	wrap(out, text, 2, 2);
}

void srv_config_usage(FILE *out)
{
	fputs("Usage: relightd [OPTIONS]\n\n", out);
	fputs("relightd serves the shot files under --shots to WebSocket clients: a client\n"
	      "opens a shot, sends light edits as JSON messages and gets back image tiles,\n"
	      "refined progressively, of the relit frame (protocol/README.md). Over HTTP\n"
	      "it answers GET /healthz (liveness), GET /metrics (Prometheus text) and,\n"
	      "the browser viewer's files.\n\nOptions:\n",
	      out);
	for (size_t i = 0; i < NSETTINGS; i++) {
		const struct setting *s = &settings[i];
		char head[64];
		if (s->kind == K_HELP)
			snprintf(head, sizeof(head), "  -h, --help");
		else if (s->kind == K_QUIET)
			snprintf(head, sizeof(head), "  -q, --quiet");
		else if (s->kind == K_VERSION)
			snprintf(head, sizeof(head), "  --version");
		else
			snprintf(head, sizeof(head), "  --%s %s", s->name, s->arg);
		int col = (int)strlen(head);
		fputs(head, out);
		if (col + 2 > USAGE_INDENT) {
			fprintf(out, "\n%*s", USAGE_INDENT, "");
		} else {
			fprintf(out, "%*s", USAGE_INDENT - col, "");
		}
		/* The default stays on one line when it fits. */
		char text[512];
		int len = snprintf(text, sizeof(text), "%s", s->help);
		if (s->dflt && len > 0 && (size_t)len < sizeof(text) &&
		    (size_t)snprintf(text + len, sizeof(text) - (size_t)len, " (default: %s)",
				     s->dflt) < sizeof(text) - (size_t)len &&
		    strlen(s->dflt) < 30) {
			for (char *q = text + len + 2; *q; q++)
				if (*q == ' ')
					*q = NBSP;
		}
		wrap(out, text, USAGE_INDENT, USAGE_INDENT);
	}
	fputs("\nToken file:\n", out);
	paragraph(out, "One token a line, then optionally a blank and a role: \"editor\" (may "
		       "edit lights; the default) or \"viewer\" (may only watch). A token is 8 "
		       "to 256 bytes without blanks; at most 4096 tokens. Lines starting with "
		       "'#' and blank lines are skipped. A client gives its token in its "
		       "\"hello\" message; an unknown token is refused. Keep the file readable "
		       "by relightd's user alone.");
	fputs("\nConfig file:\n", out);
	paragraph(out, "Lines \"name = value\" with the long option names above, without the "
		       "dashes (listen = :7878, allow-origin = https://viewer.example.com, quiet "
		       "= true); '#' "
		       "at the start of a line or after a blank starts a comment. The command "
		       "line overrides the file, and --allow-origin given on the command line "
		       "replaces the file's list.");
	fputs("\nSignals:\n", out);
	paragraph(out, "SIGTERM, SIGINT: stop accepting clients, drain the frames already "
		       "queued, and exit.");
	fputs("\nExit status:\n", out);
	fputs("  0  clean exit (after a signal, --help or --version)\n"
	      "  1  runtime failure, such as the port in use or no GPU context\n"
	      "  2  usage error: a bad option, value or config file\n",
	      out);
}

/* ---- tokens ---- */

struct token {
	unsigned char bytes[SRV_TOKEN_MAX]; /* zero-padded, so every compare reads all of it */
	size_t len;
	enum srv_role role;
	unsigned line;
};

struct srv_tokens {
	struct token *v;
	uint32_t n, cap;
};

const char *srv_role_name(enum srv_role r)
{
	switch (r) {
	case SRV_ROLE_NONE: return "none";
	case SRV_ROLE_VIEWER: return "viewer";
	case SRV_ROLE_EDITOR: return "editor";
	}
	return "unknown";
}

/* Tokens are secrets: memory that held them is cleared before it is freed. */
static void wipe(void *p, size_t n)
{
	volatile unsigned char *w = p;
	for (size_t i = 0; i < n; i++)
		w[i] = 0;
}

void srv_tokens_free(struct srv_tokens *t)
{
	if (!t)
		return;
	if (t->v)
		wipe(t->v, (size_t)t->cap * sizeof(*t->v));
	free(t->v);
	free(t);
}

uint32_t srv_tokens_count(const struct srv_tokens *t)
{
	return t ? t->n : 0;
}

/*
 * file := { line '\n' }
 * line := [ token [ blanks role ] ] | '#' ...      (blanks around it ignored)
 * Messages never quote a token: they end up in logs.
 */
struct srv_tokens *srv_tokens_parse(const char *name, const char *text, size_t len, char *err,
				    size_t errlen)
{
	if (!name)
		name = "(tokens)";
	struct srv_tokens *t = calloc(1, sizeof(*t));
	if (!t) {
		snprintf(err, errlen, "%s: out of memory", name);
		return NULL;
	}
	const char *p = text, *end = text + len;
	unsigned line = 0;
	while (p < end) {
		line++;
		const char *nl = memchr(p, '\n', (size_t)(end - p));
		const char *b = p, *e = nl ? nl : end;
		p = nl ? nl + 1 : end;
		trim(&b, &e);
		if (b == e || *b == '#')
			continue;
		const char *tb = b, *te = b;
		while (te < e && !is_blank(*te))
			te++;
		const char *rb = te, *re = e;
		trim(&rb, &re);
		size_t tlen = (size_t)(te - tb);
		if (tlen < SRV_TOKEN_MIN || tlen > SRV_TOKEN_MAX) {
			snprintf(err, errlen, "%s:%u: a token of %zu bytes (%d to %d allowed)", name,
				 line, tlen, SRV_TOKEN_MIN, SRV_TOKEN_MAX);
			goto fail;
		}
		for (const char *q = tb; q < te; q++) {
			unsigned char ch = (unsigned char)*q;
			if (ch < ' ' || ch == 0x7f) {
				snprintf(err, errlen, "%s:%u: a control character in the token",
					 name, line);
				goto fail;
			}
		}
		enum srv_role role = SRV_ROLE_EDITOR;
		size_t rlen = (size_t)(re - rb);
		if (rlen == 6 && !memcmp(rb, "viewer", 6)) {
			role = SRV_ROLE_VIEWER;
		} else if (rlen && !(rlen == 6 && !memcmp(rb, "editor", 6))) {
			char shown[48];
			size_t k = 0;
			for (const char *q = rb; q < re && k + 1 < sizeof(shown); q++)
				shown[k++] = isprint((unsigned char)*q) ? *q : '?';
			shown[k] = '\0';
			snprintf(err, errlen, "%s:%u: unknown role '%s' (editor or viewer)", name,
				 line, shown);
			goto fail;
		}
		for (uint32_t i = 0; i < t->n; i++) {
			if (t->v[i].len == tlen && !memcmp(t->v[i].bytes, tb, tlen)) {
				snprintf(err, errlen, "%s:%u: the same token as on line %u", name,
					 line, t->v[i].line);
				goto fail;
			}
		}
		if (t->n >= SRV_MAX_TOKENS) {
			snprintf(err, errlen, "%s:%u: more than %d tokens", name, line,
				 SRV_MAX_TOKENS);
			goto fail;
		}
		if (t->n == t->cap) {
			uint32_t cap = t->cap ? t->cap * 2 : 8;
			struct token *v = calloc(cap, sizeof(*v));
			if (!v) {
				snprintf(err, errlen, "%s: out of memory", name);
				goto fail;
			}
			/* Not realloc: the old array is wiped before it is freed. */
			if (t->n) {
				memcpy(v, t->v, (size_t)t->n * sizeof(*v));
				wipe(t->v, (size_t)t->cap * sizeof(*t->v));
			}
			free(t->v);
			t->v = v;
			t->cap = cap;
		}
		struct token *k = &t->v[t->n++];
		memset(k->bytes, 0, sizeof(k->bytes));
		memcpy(k->bytes, tb, tlen);
		k->len = tlen;
		k->role = role;
		k->line = line;
	}
	return t;
fail:
	srv_tokens_free(t);
	return NULL;
}

struct srv_tokens *srv_tokens_load(const char *path, char *err, size_t errlen)
{
	size_t len;
	char *text = rl_read_file(path, SETTINGS_FILE_MAX, &len, err, errlen);
	if (!text)
		return NULL;
	struct stat st;
	if (stat(path, &st) == 0 && (st.st_mode & (S_IRWXG | S_IRWXO)))
		rl_log(RL_LOG_WARN, "%s: the token file is open to other users (chmod 600 it)",
		       path);
	struct srv_tokens *t = srv_tokens_parse(path, text, len, err, errlen);
	wipe(text, len);
	free(text);
	return t;
}

enum srv_role srv_tokens_check(const struct srv_tokens *t, const char *token)
{
	if (!t || !token)
		return SRV_ROLE_NONE;
	/*
	 * Every stored token is compared over all SRV_TOKEN_MAX bytes, match or
	 * not, and the result is folded in without a branch: the time taken
	 * depends on the number of tokens only, never on which one matched or
	 * how many leading bytes a guess got right.
	 */
	unsigned char in[SRV_TOKEN_MAX] = { 0 };
	size_t len = strnlen(token, SRV_TOKEN_MAX + 1);
	memcpy(in, token, len > SRV_TOKEN_MAX ? SRV_TOKEN_MAX : len);
	unsigned role = SRV_ROLE_NONE;
	for (uint32_t i = 0; i < t->n; i++) {
		const struct token *k = &t->v[i];
		uint64_t diff = (uint64_t)(k->len ^ len);
		for (size_t j = 0; j < SRV_TOKEN_MAX; j++)
			diff |= (uint64_t)(k->bytes[j] ^ in[j]);
		/* 1 when diff is 0: the top bit of diff | -diff is set for any nonzero diff. */
		uint64_t same = ((diff | (0 - diff)) >> 63) ^ 1;
		role |= (unsigned)((0 - same) & (uint64_t)k->role);
	}
	wipe(in, sizeof(in));
	return (enum srv_role)role;
}

/* ---- origins ---- */

bool srv_origin_allowed(const struct srv_config *c, const char *origin)
{
	if (!c->norigins || !origin || !origin[0])
		return true;
	for (uint32_t i = 0; i < c->norigins && i < SRV_MAX_ORIGINS; i++)
		if (c->origins[i] && !strcasecmp(c->origins[i], origin))
			return true;
	return false;
}

/*
 * relightd's settings: defaults, every option, every refusal with its
 * message, the config file and its precedence, the forms of --listen, the
 * token file and role checks, and the Origin list.
 */
#include "server/config.h"
#include "log.h"
#include "test.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/relight-srvcfg-XXXXXX";

/* Write @text to a new file in tmpdir; its path in a static buffer of @slot. */
static const char *write_file(int slot, const char *text)
{
	static char paths[4][512];
	snprintf(paths[slot], sizeof(paths[slot]), "%s/file%d", tmpdir, slot);
	FILE *f = fopen(paths[slot], "wb");
	if (!f) {
		perror(paths[slot]);
		exit(1);
	}
	fputs(text, f);
	fclose(f);
	/* Token files open to others draw a warning; these are private. */
	chmod(paths[slot], 0600);
	return paths[slot];
}

/* Parse a NULL-terminated list of arguments after "relightd" into a fresh config. */
static bool args(struct srv_config *c, char *err, size_t errlen, ...)
{
	char *argv[64];
	int argc = 0;
	argv[argc++] = "relightd";
	va_list ap;
	va_start(ap, errlen);
	const char *a;
	while ((a = va_arg(ap, const char *)) && argc < 63)
		argv[argc++] = (char *)a;
	va_end(ap);
	argv[argc] = NULL;
	srv_config_defaults(c);
	err[0] = '\0';
	FILE *out = fopen("/dev/null", "w");
	bool ok = srv_config_parse_args(c, argc, argv, out, err, errlen);
	if (out)
		fclose(out);
	return ok;
}

/* The option list must be refused with exactly @want as the message. */
#define REFUSED(want, ...) \
	do { \
		struct srv_config c_; \
		char e_[512]; \
		CHECK(!args(&c_, e_, sizeof(e_), __VA_ARGS__, (const char *)NULL)); \
		CHECK_STR(e_, want); \
		srv_config_free(&c_); \
	} while (0)

static void test_defaults(void)
{
	struct srv_config c;
	char err[512];
	CHECK(args(&c, err, sizeof(err), (const char *)NULL));
	CHECK_STR(c.host, "127.0.0.1");
	CHECK(c.port == 7878);
	CHECK_STR(c.shots_dir, ".");
	CHECK_STR(c.snapshot_dir, "./snapshots");
	CHECK_STR(c.token_file, "");
	CHECK(!c.cert[0] && !c.key[0] && !c.viewer_dir[0]);
	CHECK(c.norigins == 0);
	CHECK(c.gpu_budget == (size_t)2048 * 1024 * 1024);
	CHECK(c.max_message == 64 * 1024);
	CHECK(c.max_clients == 256 && c.max_shots == 16 && c.max_lights == 1024);
	CHECK(c.client_queue == (size_t)64 * 1024 * 1024);
	CHECK(c.tile_size == 128);
	CHECK(c.log_level == RL_LOG_INFO);
	CHECK(!c.help);
	srv_config_free(&c);
}

static void test_options(void)
{
	struct srv_config c;
	char err[512];
	bool ok = args(&c, err, sizeof(err), "--listen", "0.0.0.0:9000", "--shots", "/srv/shots",
		       "--token-file", "/etc/relight/tokens", "--gpu-budget", "512", "--tls-cert",
		       "c.pem", "--tls-key=k.pem", "--viewer", "/usr/share/relight/viewer",
		       "--allow-origin", "https://a.example.com", "--allow-origin",
		       "http://localhost:8080", "--max-message", "128", "--max-clients", "10",
		       "--max-shots", "3", "--max-lights", "99", "--client-queue", "8",
		       "--tile-size", "16", "--log-level", "debug", (const char *)NULL);
	CHECK(ok);
	if (!ok)
		fprintf(stderr, "  error: %s\n", err);
	CHECK_STR(c.host, "0.0.0.0");
	CHECK(c.port == 9000);
	CHECK_STR(c.shots_dir, "/srv/shots");
	CHECK_STR(c.snapshot_dir, "/srv/shots/snapshots");
	CHECK_STR(c.token_file, "/etc/relight/tokens");
	CHECK(c.gpu_budget == (size_t)512 << 20);
	CHECK_STR(c.cert, "c.pem");
	CHECK_STR(c.key, "k.pem");
	CHECK_STR(c.viewer_dir, "/usr/share/relight/viewer");
	CHECK(c.norigins == 2);
	if (c.norigins == 2) {
		CHECK_STR(c.origins[0], "https://a.example.com");
		CHECK_STR(c.origins[1], "http://localhost:8080");
	}
	CHECK(c.max_message == 128 * 1024);
	CHECK(c.max_clients == 10 && c.max_shots == 3 && c.max_lights == 99);
	CHECK(c.client_queue == (size_t)8 << 20);
	CHECK(c.tile_size == 16);
	CHECK(c.log_level == RL_LOG_DEBUG);
	srv_config_free(&c);
	CHECK(c.norigins == 0);

	/* Range ends, the snapshot folder given, a trailing slash on --shots. */
	CHECK(args(&c, err, sizeof(err), "--tile-size", "1024", "--log-level", "ERROR",
		   "--snapshots", "/var/snap", "--shots", "/data/", (const char *)NULL));
	CHECK(c.tile_size == 1024 && c.log_level == RL_LOG_ERROR);
	CHECK_STR(c.snapshot_dir, "/var/snap");
	srv_config_free(&c);
	CHECK(args(&c, err, sizeof(err), "--shots", "/data/", (const char *)NULL));
	CHECK_STR(c.snapshot_dir, "/data/snapshots");
	srv_config_free(&c);
	CHECK(args(&c, err, sizeof(err), "--gpu-budget", "16777216", "--max-message", "1",
		   (const char *)NULL));
	CHECK(c.max_message == 1024);
	if (sizeof(size_t) >= 8)
		CHECK(c.gpu_budget == (size_t)1 << 44);
	srv_config_free(&c);

	/* An unambiguous prefix of a long option is that option (getopt_long). */
	CHECK(args(&c, err, sizeof(err), "--max-c", "7", (const char *)NULL));
	CHECK(c.max_clients == 7);
	srv_config_free(&c);
	/* A repeated origin (in any case) is kept once. */
	CHECK(args(&c, err, sizeof(err), "--allow-origin", "https://a.example",
		   "--allow-origin", "HTTPS://A.example", (const char *)NULL));
	CHECK(c.norigins == 1);
	srv_config_free(&c);
}

static void test_help(void)
{
	/* --help wins over a bad option, and the usage goes to the stream given. */
	char path[600];
	snprintf(path, sizeof(path), "%s/usage", tmpdir);
	FILE *out = fopen(path, "w+");
	CHECK(out != NULL);
	if (!out)
		return;
	struct srv_config c;
	srv_config_defaults(&c);
	char *argv[] = { "relightd", "--bogus", "-h", NULL };
	char err[256] = "";
	CHECK(srv_config_parse_args(&c, 3, argv, out, err, sizeof(err)));
	CHECK(c.help);
	long size = ftell(out);
	rewind(out);
	static char text[16384];
	size_t n = fread(text, 1, sizeof(text) - 1, out);
	text[n] = '\0';
	fclose(out);
	CHECK(size > 1000 && (long)n == size);
	CHECK(strstr(text, "Usage: relightd [OPTIONS]") == text);
	/* Every option appears, with its default where it has one. */
	const char *names[] = { "--listen HOST:PORT", "--shots DIR", "--token-file FILE",
				"--config FILE", "--gpu-budget MB", "--tls-cert FILE",
				"--tls-key FILE", "--viewer DIR", "--snapshots DIR",
				"--allow-origin ORIGIN", "--max-message KB", "--max-clients N",
				"--max-shots N", "--max-lights N", "--client-queue MB",
				"--tile-size N", "--log-level LEVEL", "-h, --help" };
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		CHECK(strstr(text, names[i]) != NULL);
		if (!strstr(text, names[i]))
			fprintf(stderr, "  missing from usage: %s\n", names[i]);
	}
	const char *facts[] = { "(default: 127.0.0.1:7878)", "(default: 2048)", "(default: 64)",
				"(default: 256)", "(default: 16)", "(default: 1024)",
				"(default: 128)", "(default: info)", "(default: SHOTS/snapshots)",
				"/healthz", "/metrics", "SIGTERM", "Exit status", "2  usage error",
				"Token file", "\"viewer\"" };
	for (size_t i = 0; i < sizeof(facts) / sizeof(facts[0]); i++) {
		CHECK(strstr(text, facts[i]) != NULL);
		if (!strstr(text, facts[i]))
			fprintf(stderr, "  missing from usage: %s\n", facts[i]);
	}
	/* No line runs past 79 columns. */
	size_t col = 0, widest = 0;
	for (const char *p = text; *p; p++) {
		col = *p == '\n' ? 0 : col + 1;
		if (col > widest)
			widest = col;
	}
	CHECK(widest <= 79);
	srv_config_free(&c);
	remove(path);

	/* A second call works the same (getopt's state is reset). */
	char err2[256];
	CHECK(args(&c, err2, sizeof(err2), "--help", (const char *)NULL) && c.help);
	srv_config_free(&c);
}

static void test_errors(void)
{
	REFUSED("--gpu-budget: 'abc' is not a number of megabytes", "--gpu-budget", "abc");
	REFUSED("--gpu-budget: '-1' is not a number of megabytes", "--gpu-budget", "-1");
	REFUSED("--gpu-budget: '12MB' is not a number of megabytes", "--gpu-budget", "12MB");
	REFUSED("--gpu-budget: ' 12' is not a number of megabytes", "--gpu-budget", " 12");
	REFUSED("--gpu-budget: '' is not a number of megabytes", "--gpu-budget", "");
	REFUSED("--gpu-budget: 0 is out of range (1 to 16777216 megabytes)", "--gpu-budget", "0");
	REFUSED("--gpu-budget: 16777217 is out of range (1 to 16777216 megabytes)",
		"--gpu-budget", "16777217");
	REFUSED("--gpu-budget: 99999999999999999999999 is out of range (1 to 16777216 megabytes)",
		"--gpu-budget", "99999999999999999999999");
	REFUSED("--max-message: '0x10' is not a number of kilobytes", "--max-message", "0x10");
	REFUSED("--max-message: 16385 is out of range (1 to 16384 kilobytes)", "--max-message",
		"16385");
	REFUSED("--max-clients: 0 is out of range (1 to 65536 clients)", "--max-clients", "0");
	REFUSED("--max-shots: '+3' is not a number of shots", "--max-shots", "+3");
	REFUSED("--max-lights: 65537 is out of range (1 to 65536 lights)", "--max-lights", "65537");
	REFUSED("--client-queue: '1.5' is not a number of megabytes", "--client-queue", "1.5");
	REFUSED("--tile-size: 15 is out of range (16 to 1024 pixels)", "--tile-size", "15");
	REFUSED("--tile-size: 1025 is out of range (16 to 1024 pixels)", "--tile-size", "1025");
	REFUSED("--tile-size: 4294967312 is out of range (16 to 1024 pixels)", "--tile-size",
		"4294967312");
	REFUSED("--log-level: 'loud' is not a log level (error, warn, info or debug)",
		"--log-level", "loud");
	REFUSED("--tls-cert: needs --tls-key (the certificate's private key)", "--tls-cert",
		"c.pem");
	REFUSED("--tls-key: needs --tls-cert", "--tls-key", "k.pem");
	REFUSED("--shots: needs a path", "--shots", "");
	REFUSED("--listen: needs a value", "--listen");
	REFUSED("--help: takes no value", "--help=yes");
	REFUSED("unknown or ambiguous option '--bogus' (see --help)", "--bogus");
	REFUSED("unknown or ambiguous option '--max' (see --help)", "--max", "3");
	REFUSED("unknown option '-x' (see --help)", "-x");
	REFUSED("unexpected argument 'extra' (relightd takes options only)", "extra");
	REFUSED("--allow-origin: 'https://a.example/' is not an origin: scheme://host[:port] "
		"without a path, as https://viewer.example.com",
		"--allow-origin", "https://a.example/");
}

static void test_error_paths(void)
{
	/* Paths must fit their fields. */
	static char longpath[5000];
	memset(longpath, 'a', sizeof(longpath) - 1);
	longpath[sizeof(longpath) - 1] = '\0';
	REFUSED("--viewer: path longer than 4095 bytes", "--viewer", longpath);

	/* Origins: the forms refused, and the limit of 32. */
	const char *bad[] = { "a.example.com", "https://", "https://a b", "https://u@a.example",
			      "https://a.example:0", "https://a.example:65536", "https://:80",
			      "https://a.example:80:80", "https://a.example?x", "null", "*",
			      "https://[]:80", "https://[::1]x", "1http://a.example" };
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		struct srv_config c;
		char err[512];
		CHECK(!args(&c, err, sizeof(err), "--allow-origin", bad[i], (const char *)NULL));
		CHECK(strstr(err, "is not an origin") != NULL);
		srv_config_free(&c);
	}
	const char *good[] = { "https://a.example", "http://127.0.0.1:8080", "http://[::1]:8080",
			       "https://[::1]", "app+x://host.example" };
	for (size_t i = 0; i < sizeof(good) / sizeof(good[0]); i++) {
		struct srv_config c;
		char err[512];
		CHECK(args(&c, err, sizeof(err), "--allow-origin", good[i], (const char *)NULL));
		CHECK(c.norigins == 1);
		srv_config_free(&c);
	}
	char *argv[80];
	char names[33][64];
	int argc = 0;
	argv[argc++] = "relightd";
	for (int i = 0; i < 33; i++) {
		snprintf(names[i], sizeof(names[i]), "https://h%d.example", i);
		argv[argc++] = "--allow-origin";
		argv[argc++] = names[i];
	}
	argv[argc] = NULL;
	struct srv_config c;
	char err[512];
	srv_config_defaults(&c);
	CHECK(!srv_config_parse_args(&c, argc, argv, NULL, err, sizeof(err)));
	CHECK_STR(err, "--allow-origin: more than 32 origins");
	CHECK(c.norigins == 32);
	srv_config_free(&c); /* the 32 strings kept so far are freed (ASan checks) */
	srv_config_defaults(&c);
	CHECK(srv_config_parse_args(&c, argc - 2, argv, NULL, err, sizeof(err)));
	CHECK(c.norigins == 32);
	srv_config_free(&c);
}

static void test_listen(void)
{
	struct {
		const char *arg, *host;
		int port;
	} ok[] = {
		{ "127.0.0.1:7000", "127.0.0.1", 7000 },
		{ ":8080", "", 8080 },
		{ "[::1]:9000", "::1", 9000 },
		{ "[fe80::1%eth0]:1", "fe80::1%eth0", 1 },
		{ "relight.example.com:443", "relight.example.com", 443 },
		{ "localhost:0", "localhost", 0 },
		{ "h:65535", "h", 65535 },
	};
	for (size_t i = 0; i < sizeof(ok) / sizeof(ok[0]); i++) {
		struct srv_config c;
		char err[512];
		CHECK(args(&c, err, sizeof(err), "--listen", ok[i].arg, (const char *)NULL));
		CHECK_STR(c.host, ok[i].host);
		CHECK(c.port == ok[i].port);
		srv_config_free(&c);
	}
	REFUSED("--listen: '7878' is not HOST:PORT, :PORT or [ADDRESS]:PORT", "--listen", "7878");
	REFUSED("--listen: '::1:7878': put an IPv6 address in brackets, as [::1]:7878", "--listen",
		"::1:7878");
	REFUSED("--listen: '[::1]7878' is not [ADDRESS]:PORT", "--listen", "[::1]7878");
	REFUSED("--listen: '[]:80' is not [ADDRESS]:PORT", "--listen", "[]:80");
	REFUSED("--listen: 'h:65536': the port must be a number from 0 to 65535", "--listen",
		"h:65536");
	REFUSED("--listen: 'h:': the port must be a number from 0 to 65535", "--listen", "h:");
	REFUSED("--listen: 'h:-1': the port must be a number from 0 to 65535", "--listen", "h:-1");
	REFUSED("--listen: 'a b:80': bad character in the host", "--listen", "a b:80");
	/* A refused value leaves the setting as it was. */
	struct srv_config c;
	srv_config_defaults(&c);
	char err[512];
	char *argv[] = { "relightd", "--listen", "x:99999", NULL };
	CHECK(!srv_config_parse_args(&c, 3, argv, NULL, err, sizeof(err)));
	CHECK_STR(c.host, "127.0.0.1");
	CHECK(c.port == 7878);
}

static void test_config_file(void)
{
	const char *file = write_file(0, "# relightd settings\n"
					 "\n"
					 "listen = [::]:7001\r\n"
					 "  shots=/srv/shots   # where the shots are\n"
					 "gpu-budget = 1024\n"
					 "max-clients = 5\n"
					 "viewer = /opt/viewer#1\n"
					 "allow-origin = https://one.example\n"
					 "allow-origin = https://two.example\n"
					 "log-level = warn\n"
					 "tls-cert = /etc/c.pem");
	struct srv_config c;
	char err[512];
	/* --config comes last but is applied first: the command line wins. */
	CHECK(args(&c, err, sizeof(err), "--max-clients", "9", "--tls-key", "/etc/k.pem",
		   "--config", file, (const char *)NULL));
	if (err[0])
		fprintf(stderr, "  error: %s\n", err);
	CHECK_STR(c.host, "::");
	CHECK(c.port == 7001);
	CHECK_STR(c.shots_dir, "/srv/shots");
	CHECK_STR(c.snapshot_dir, "/srv/shots/snapshots");
	CHECK(c.gpu_budget == (size_t)1024 << 20);
	CHECK(c.max_clients == 9);
	CHECK_STR(c.viewer_dir, "/opt/viewer#1");
	CHECK(c.log_level == RL_LOG_WARN);
	CHECK_STR(c.cert, "/etc/c.pem");
	CHECK_STR(c.key, "/etc/k.pem");
	CHECK(c.norigins == 2);
	srv_config_free(&c);

	/* Origins on the command line replace the file's; --config=F works too. */
	char opt[600];
	snprintf(opt, sizeof(opt), "--config=%s", file);
	CHECK(args(&c, err, sizeof(err), "--allow-origin", "https://cli.example", opt,
		   "--tls-key", "k", (const char *)NULL));
	CHECK(c.norigins == 1 && c.norigins && !strcmp(c.origins[0], "https://cli.example"));
	CHECK(srv_origin_allowed(&c, "https://cli.example"));
	CHECK(!srv_origin_allowed(&c, "https://one.example"));
	srv_config_free(&c);

	/* The file's error, with its line; the file's own refusal of a tls pair comes at the end. */
	const char *bad = write_file(1, "listen = :1\n\n# note\ngpu-budget = lots\n");
	snprintf(opt, sizeof(opt), "%s:4: gpu-budget: 'lots' is not a number of megabytes", bad);
	REFUSED(opt, "--config", bad);
	CHECK(args(&c, err, sizeof(err), "--config", file, (const char *)NULL) == false);
	CHECK_STR(err, "--tls-cert: needs --tls-key (the certificate's private key)");
	srv_config_free(&c);
	snprintf(opt, sizeof(opt), "%s/missing.conf", tmpdir);
	CHECK(!args(&c, err, sizeof(err), "--config", opt, (const char *)NULL));
	CHECK(strncmp(err, opt, strlen(opt)) == 0 && err[strlen(opt)] == ':');
	srv_config_free(&c);
	REFUSED("--config: needs a value", "--config");

	/* srv_config_parse_text directly: each refusal, named by file and line. */
	struct {
		const char *text, *err;
	} cases[] = {
		{ "bogus = 1\n", "t.conf:1: unknown setting 'bogus'" },
		{ "\nhelp = 1\n", "t.conf:2: unknown setting 'help'" },
		{ "config = other.conf\n", "t.conf:1: config: a config file cannot name another" },
		{ "listen\n", "t.conf:1: expected 'name = value'" },
		{ " = 5\n", "t.conf:1: expected 'name = value'" },
		{ "a\n\n\nmax-shots = 0\n", "t.conf:1: expected 'name = value'" },
		{ "max-shots = 4\nmax-shots = 0\n",
		  "t.conf:2: max-shots: 0 is out of range (1 to 4096 shots)" },
		{ "tile-size = 64 # a comment\ntile-size = 8\n",
		  "t.conf:2: tile-size: 8 is out of range (16 to 1024 pixels)" },
		{ "shots =\n", "t.conf:1: shots: needs a path" },
		{ "max-lights = 1 2\n", "t.conf:1: max-lights: '1 2' is not a number of lights" },
		{ "--listen = :80\n", "t.conf:1: unknown setting '--listen'" },
		{ "listen = :80\nlisten = 80\n",
		  "t.conf:2: listen: '80' is not HOST:PORT, :PORT or [ADDRESS]:PORT" },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		srv_config_defaults(&c);
		err[0] = '\0';
		CHECK(!srv_config_parse_text(&c, "t.conf", cases[i].text, strlen(cases[i].text), err,
					     sizeof(err)));
		CHECK_STR(err, cases[i].err);
		srv_config_free(&c);
	}
	/* A NUL byte inside the text is refused, not read as the end. */
	srv_config_defaults(&c);
	const char nul[] = "max-shots = 4\nmax-shots = 5\0\n";
	CHECK(!srv_config_parse_text(&c, "t.conf", nul, sizeof(nul) - 1, err, sizeof(err)));
	CHECK_STR(err, "t.conf:2: NUL byte in the line");
	/* The lines before the bad one were applied; and the length is respected. */
	CHECK(c.max_shots == 4);
	CHECK(srv_config_parse_text(&c, "t.conf", nul, 27, err, sizeof(err)) && c.max_shots == 5);
	CHECK(srv_config_parse_text(&c, "t.conf", "", 0, err, sizeof(err)));
	/* Empty values of optional paths clear them; the text need not end in a newline. */
	const char *t = "viewer = /v\nviewer =\ntoken-file = /t";
	CHECK(srv_config_parse_text(&c, "t.conf", t, strlen(t), err, sizeof(err)));
	CHECK_STR(c.viewer_dir, "");
	CHECK_STR(c.token_file, "/t");
	srv_config_free(&c);
}

static struct srv_tokens *tokens(const char *text, char *err, size_t errlen)
{
	err[0] = '\0';
	return srv_tokens_parse("tokens", text, strlen(text), err, errlen);
}

static void test_tokens(void)
{
	char err[512];
	struct srv_tokens *t = tokens("# who may connect\n"
				      "editor-secret-1\n"
				      "viewer-secret-22 viewer\r\n"
				      "  editor-secret-3\teditor  \n"
				      "\n"
				      "viewer-secret-4    viewer   \r\n"
				      "12345678",
				      err, sizeof(err));
	CHECK(t != NULL);
	if (!t) {
		fprintf(stderr, "  error: %s\n", err);
		return;
	}
	CHECK(srv_tokens_count(t) == 5);
	CHECK(srv_tokens_check(t, "editor-secret-1") == SRV_ROLE_EDITOR);
	CHECK(srv_tokens_check(t, "viewer-secret-22") == SRV_ROLE_VIEWER);
	CHECK(srv_tokens_check(t, "editor-secret-3") == SRV_ROLE_EDITOR);
	CHECK(srv_tokens_check(t, "viewer-secret-4") == SRV_ROLE_VIEWER);
	CHECK(srv_tokens_check(t, "12345678") == SRV_ROLE_EDITOR);
	/* Prefixes, extensions, case changes and what the file's syntax strips are no match. */
	CHECK(srv_tokens_check(t, "editor-secret-") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, "editor-secret-11") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, "Editor-secret-1") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, "viewer-secret-22 viewer") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, "viewer-secret-22\r") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, "") == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(t, NULL) == SRV_ROLE_NONE);
	CHECK(srv_tokens_check(NULL, "editor-secret-1") == SRV_ROLE_NONE);
	srv_tokens_free(t);

	static char max[SRV_TOKEN_MAX + 1];
	memset(max, 'k', SRV_TOKEN_MAX);
	char text[600];
	snprintf(text, sizeof(text), "%s viewer\n", max);
	t = tokens(text, err, sizeof(err));
	CHECK(t && srv_tokens_count(t) == 1);
	CHECK(srv_tokens_check(t, max) == SRV_ROLE_VIEWER);
	/* A guess whose first 256 bytes are the token, and more, is no match. */
	static char longer[400];
	memset(longer, 'k', SRV_TOKEN_MAX + 10);
	CHECK(srv_tokens_check(t, longer) == SRV_ROLE_NONE);
	max[SRV_TOKEN_MAX - 1] = 'j';
	CHECK(srv_tokens_check(t, max) == SRV_ROLE_NONE);
	srv_tokens_free(t);

	/* Empty and comment-only files hold no tokens: nobody is let in. */
	t = tokens("# all revoked\n\n", err, sizeof(err));
	CHECK(t && srv_tokens_count(t) == 0);
	CHECK(srv_tokens_check(t, "anything-at-all") == SRV_ROLE_NONE);
	srv_tokens_free(t);
	CHECK(srv_tokens_count(NULL) == 0);

	/* Refusals: the line, and never the token itself. */
	struct {
		const char *text, *err;
	} bad[] = {
		{ "good-token-1\nshort\n", "tokens:2: a token of 5 bytes (8 to 256 allowed)" },
		{ "good-token-1 admin\n", "tokens:1: unknown role 'admin' (editor or viewer)" },
		{ "good-token-1 Viewer\n", "tokens:1: unknown role 'Viewer' (editor or viewer)" },
		{ "good-token-1 viewer extra\n",
		  "tokens:1: unknown role 'viewer extra' (editor or viewer)" },
		{ "good-token-1\n# c\ngood-token-2\r\ngood-token-1 viewer\r\n",
		  "tokens:4: the same token as on line 1" },
		{ "good\x01token\n", "tokens:1: a control character in the token" },
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		t = tokens(bad[i].text, err, sizeof(err));
		CHECK(t == NULL);
		CHECK_STR(err, bad[i].err);
		srv_tokens_free(t);
	}
	snprintf(text, sizeof(text), "%sk\n", max);
	t = tokens(text, err, sizeof(err));
	CHECK(t == NULL);
	CHECK_STR(err, "tokens:1: a token of 257 bytes (8 to 256 allowed)");
	/* A NUL byte is part of a line, not its end. */
	const char nul[] = "token-one\0x\n";
	t = srv_tokens_parse("tokens", nul, sizeof(nul) - 1, err, sizeof(err));
	CHECK(t == NULL);
	CHECK_STR(err, "tokens:1: a control character in the token");

	/* More than SRV_MAX_TOKENS. */
	char *many = malloc((size_t)(SRV_MAX_TOKENS + 1) * 16);
	size_t len = 0;
	for (int i = 0; i <= SRV_MAX_TOKENS; i++)
		len += (size_t)sprintf(many + len, "token-%08d\n", i);
	t = srv_tokens_parse("tokens", many, len, err, sizeof(err));
	CHECK(t == NULL);
	CHECK_STR(err, "tokens:4097: more than 4096 tokens");
	t = srv_tokens_parse("tokens", many, len - 15, err, sizeof(err));
	CHECK(t && srv_tokens_count(t) == SRV_MAX_TOKENS);
	CHECK(srv_tokens_check(t, "token-00004095") == SRV_ROLE_EDITOR);
	CHECK(srv_tokens_check(t, "token-00000000") == SRV_ROLE_EDITOR);
	CHECK(srv_tokens_check(t, "token-00004096") == SRV_ROLE_NONE);
	srv_tokens_free(t);
	free(many);

	/* From a file, with its name in errors. */
	const char *path = write_file(2, "reader-token viewer\n");
	t = srv_tokens_load(path, err, sizeof(err));
	CHECK(t && srv_tokens_check(t, "reader-token") == SRV_ROLE_VIEWER);
	srv_tokens_free(t);
	path = write_file(3, "reader-token\nreader-token\n");
	t = srv_tokens_load(path, err, sizeof(err));
	CHECK(t == NULL);
	char want[600];
	snprintf(want, sizeof(want), "%s:2: the same token as on line 1", path);
	CHECK_STR(err, want);
	snprintf(want, sizeof(want), "%s/none", tmpdir);
	CHECK(srv_tokens_load(want, err, sizeof(err)) == NULL);
	CHECK(strncmp(err, want, strlen(want)) == 0);

	CHECK_STR(srv_role_name(SRV_ROLE_NONE), "none");
	CHECK_STR(srv_role_name(SRV_ROLE_VIEWER), "viewer");
	CHECK_STR(srv_role_name(SRV_ROLE_EDITOR), "editor");
	CHECK_STR(srv_role_name((enum srv_role)7), "unknown");
}

static void test_origins(void)
{
	struct srv_config c;
	srv_config_defaults(&c);
	/* No list: everything is allowed. */
	CHECK(srv_origin_allowed(&c, "https://anything.example"));
	CHECK(srv_origin_allowed(&c, NULL));
	char err[512];
	const char *t = "allow-origin = https://viewer.example.com\n"
			"allow-origin = http://localhost:8080\n";
	CHECK(srv_config_parse_text(&c, "o.conf", t, strlen(t), err, sizeof(err)));
	CHECK(c.norigins == 2);
	CHECK(srv_origin_allowed(&c, "https://viewer.example.com"));
	CHECK(srv_origin_allowed(&c, "HTTPS://Viewer.Example.COM"));
	CHECK(srv_origin_allowed(&c, "http://localhost:8080"));
	/* Non-browser clients send no Origin. */
	CHECK(srv_origin_allowed(&c, NULL));
	CHECK(srv_origin_allowed(&c, ""));
	/* Exact: no other scheme, port, subdomain, suffix or path. */
	CHECK(!srv_origin_allowed(&c, "http://viewer.example.com"));
	CHECK(!srv_origin_allowed(&c, "https://viewer.example.com:443"));
	CHECK(!srv_origin_allowed(&c, "https://evil.viewer.example.com"));
	CHECK(!srv_origin_allowed(&c, "https://viewer.example.com.evil.net"));
	CHECK(!srv_origin_allowed(&c, "https://viewer.example.com/"));
	CHECK(!srv_origin_allowed(&c, "http://localhost"));
	CHECK(!srv_origin_allowed(&c, "http://localhost:80800"));
	CHECK(!srv_origin_allowed(&c, "null"));
	srv_config_free(&c);
}

int main(void)
{
	if (!mkdtemp(tmpdir)) {
		perror(tmpdir);
		return 1;
	}
	RUN(test_defaults);
	RUN(test_options);
	RUN(test_help);
	RUN(test_errors);
	RUN(test_error_paths);
	RUN(test_listen);
	RUN(test_config_file);
	RUN(test_tokens);
	RUN(test_origins);
	for (int i = 0; i < 4; i++) {
		char p[600];
		snprintf(p, sizeof(p), "%s/file%d", tmpdir, i);
		remove(p);
	}
	rmdir(tmpdir);
	return test_finish();
}

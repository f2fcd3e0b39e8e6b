/*
 * relightd's settings: the command line, an optional config file of the same
 * names, and the token file of who may connect and in which role.
 */
#ifndef SRV_CONFIG_H
#define SRV_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#define SRV_MAX_ORIGINS 32

struct srv_config {
	char host[256];             /* --listen HOST:PORT (default 127.0.0.1:7878) */
	int port;                   /* 0: any free port (its number is logged) */
	char shots_dir[4096];       /* --shots DIR (default "."): shot files and RIBs */
	char token_file[4096];      /* --token-file F ("": no tokens, every client an editor) */
	char cert[4096], key[4096]; /* --tls-cert F --tls-key F: TLS when both are given */
	char viewer_dir[4096];      /* --viewer DIR: static files served over HTTP ("": none) */
	char snapshot_dir[4096];    /* --snapshots DIR (default: SHOTS/snapshots) */
	char *origins[SRV_MAX_ORIGINS]; /* --allow-origin O (repeatable; none: any Origin) */
	uint32_t norigins;
	size_t gpu_budget;          /* --gpu-budget MB, in bytes (default 2048 MB) */
	size_t max_message;         /* --max-message KB, bytes of one incoming frame (default 64 KB) */
	uint32_t max_clients;       /* --max-clients N (default 256) */
	uint32_t max_shots;         /* --max-shots N resident at once (default 16) */
	uint32_t max_lights;        /* --max-lights N per shot (default 1024) */
	size_t client_queue;        /* --client-queue MB of queued frames per client (default 64 MB) */
	uint32_t tile_size;         /* --tile-size N pixels (default 128) */
	uint32_t hello_timeout;     /* --hello-timeout S: seconds a connection has for its hello (default 10) */
	uint32_t max_preauth;       /* --max-preauth N connections before hello (default 128) */
	bool metrics_token;         /* --metrics token: /metrics needs a token of the token file */
	uint32_t snapshot_max_count; /* --snapshot-max-count N snapshots in the folder (default 1000) */
	size_t snapshot_max_bytes;  /* --snapshot-max-bytes MB of snapshots in the folder (default 10240 MB) */
	uint32_t snapshot_rate;     /* --snapshot-rate N snapshots per minute per client (default 20) */
	uint32_t worker_stall;      /* --worker-stall S seconds without a finished job: unhealthy (default 60) */
	int log_level;              /* --log-level error|warn|info|debug (enum rl_log_level; default info) */
	uint32_t log_rate;          /* --log-rate N lines a second per client log line (0: no limit; default 10) */
	bool quiet;                 /* -q, --quiet: log_level error, whatever --log-level says */
	bool help;                  /* --help was given: usage printed, nothing else to do */
	bool version;               /* --version was given: nothing else to do */
};

/** Defaults for every field. */
void srv_config_defaults(struct srv_config *c);

/**
 * Apply the command line (argv[0] is the program). A --config F among the
 * options is read first (srv_config_load_file), so the command line wins.
 * On --help prints the usage to @out and sets c->help. False with the
 * reason (naming the option) in @err on a bad option or value.
 */
bool srv_config_parse_args(struct srv_config *c, int argc, char **argv, FILE *out, char *err,
			   size_t errlen);

/**
 * Read a config file: lines "name = value" with the long option names
 * (listen, shots, token-file, gpu-budget, allow-origin, ...), '#' comments,
 * blank lines. False with "FILE:LINE: reason" in @err.
 */
bool srv_config_load_file(struct srv_config *c, const char *path, char *err, size_t errlen);

/**
 * Apply config file text (@len bytes, not NUL-terminated, NUL bytes refused)
 * as srv_config_load_file does; @name stands for the file in messages. On
 * failure the lines before the bad one stay applied. Strings the settings
 * allocate belong to @c (srv_config_free).
 *
 * Notes on the values, for all three entry points: ":PORT" leaves c->host
 * empty, meaning every interface; "[::1]:PORT" stores "::1" without the
 * brackets. srv_config_parse_args fills an unset snapshot_dir with
 * SHOTS/snapshots at the end and checks --tls-cert and --tls-key come
 * together; the other two leave that to it. Origins given on the command
 * line replace those of config files.
 */
bool srv_config_parse_text(struct srv_config *c, const char *name, const char *text, size_t len,
			   char *err, size_t errlen);

void srv_config_free(struct srv_config *c);

/** The usage text (what --help prints). */
void srv_config_usage(FILE *out);

/* ---- tokens ---- */

enum srv_role { SRV_ROLE_NONE = 0, SRV_ROLE_VIEWER, SRV_ROLE_EDITOR };

const char *srv_role_name(enum srv_role r);

struct srv_tokens;

/* Tokens are 8 to 256 bytes; a token file holds at most 4096 of them. */
#define SRV_TOKEN_MIN 8
#define SRV_TOKEN_MAX 256
#define SRV_MAX_TOKENS 4096

/**
 * Read a token file: one token a line, optionally followed by a space and a
 * role ("editor" or "viewer"; editor when omitted); '#' comments and blank
 * lines skipped. NULL with "FILE:LINE: reason" in @err (unreadable, a bad
 * role, a token shorter than 8 or longer than 256 bytes, a duplicate).
 */
struct srv_tokens *srv_tokens_load(const char *path, char *err, size_t errlen);

/** Parse token file text (@len bytes) as srv_tokens_load does; @name stands for the file. */
struct srv_tokens *srv_tokens_parse(const char *name, const char *text, size_t len, char *err,
				    size_t errlen);

void srv_tokens_free(struct srv_tokens *t);
uint32_t srv_tokens_count(const struct srv_tokens *t);

/** The role of @token (NULL or unknown: SRV_ROLE_NONE), compared in constant time. */
enum srv_role srv_tokens_check(const struct srv_tokens *t, const char *token);

/** Whether a browser Origin header is allowed (no list: all; no header: allowed). */
bool srv_origin_allowed(const struct srv_config *c, const char *origin);

#endif

/*
 * The subcommands of the `relight` program. Each takes the arguments that
 * follow `relight` (argv[0] is the subcommand's own name), prints its own
 * messages, and returns the process exit status: 0 on success, 1 when the
 * work failed (for example a shader with errors), 2 on a usage error.
 */
#ifndef CMD_H
#define CMD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/** Exit statuses shared by every subcommand. */
enum {
	CMD_OK = 0,
	CMD_FAILED = 1,
	CMD_USAGE = 2,
};

/**
 * Print "relight CMD: MESSAGE" and a pointer to --help on stderr; returns
 * CMD_USAGE.
 */
int cmd_usage_error(const char *cmd, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/** A decimal number from 0 to @max (no sign, nothing after it). */
bool cmd_parse_uint(const char *s, uint32_t max, uint32_t *out);

/**
 * Can @path be written as an output file? Its folder must exist and be
 * writable and @path must not be a folder, nor an existing file that cannot
 * be written. Checked before rendering. False with "@who: error: ..." on
 * stderr.
 */
bool cmd_check_output(const char *path, const char *who);

/** A finite decimal number in [@min, @max] (nothing after it). */
bool cmd_parse_double(const char *s, double min, double max, double *out);

/**
 * A light edit LIGHT.PARAM=V[,V...] (the argument of --set in 'relight
 * preview' and 'relight render'): 1 to 16 numbers parsed as floats (NaN and
 * infinities are accepted here; the light's parameter decides). @arg is
 * modified: *@light and *@param point into it. The last '.' before the '='
 * splits LIGHT from PARAM, so a light's name may hold dots. False when the
 * '=', the '.', LIGHT, PARAM or a number is missing, a number is malformed or
 * beyond the float range, or there are more than 16.
 */
bool cmd_parse_light_edit(char *arg, const char **light, const char **param, float values[16],
			  uint32_t *n);

/**
 * The same for an edit whose value may be a string (a map's name): *@text
 * is the value as written; *@n is 0 when it is a string: not numbers, and
 * beginning with neither a digit, a sign, a dot nor a comma (so that "1x" or
 * "1,,2" stay malformed numbers), or beginning with "./" or "../".
 */
bool cmd_parse_light_edit_text(char *arg, const char **light, const char **param,
			       float values[16], uint32_t *n, const char **text);

/**
 * The --set option of command @cmd ("render", "preview"): @arg copied into
 * @copy (@cap bytes, which the caller keeps: *@light and *@param point into
 * it) and parsed by cmd_parse_light_edit_text: a value that is not numbers is
 * a string, for string parameters (*@n 0, *@text the value). CMD_OK, or the
 * usage error, printed.
 */
int cmd_set_option(const char *cmd, const char *arg, char *copy, size_t cap, const char **light,
		   const char **param, float values[16], uint32_t *n, const char **text);

/**
 * The default shader search path: $RELIGHT_SHADER_PATH, then
 * $RMAN_SHADERPATH, then the project's library.
 */
void cmd_shader_path(char *buf, size_t size);

/**
 * Append -I @dir to the colon-separated include path in @buf (@size bytes,
 * "" at first). Returns CMD_OK, or reports a usage error of @cmd (a folder
 * holding ':' or too many) and returns its status.
 */
int cmd_add_include(const char *cmd, char *buf, size_t size, const char *dir);

/** `relight compile`: check an RSL shader; optionally print its AST, IR or a report. */
int cmd_compile(int argc, char **argv);

/** `relight render`: render a RIB scene's frames to OpenEXR with the REYES renderer. */
int cmd_render(int argc, char **argv);

/** `relight diff`: compare two rendered images; print the errors, optionally a heat map PNG. */
int cmd_diff(int argc, char **argv);

/** `relight remote`: drive a running relightd over WebSocket (clients/remote/remote.h). */
int cmd_remote(int argc, char **argv);

/** `relight bake`: bake a RIB scene into a shot file for the preview. */
int cmd_bake(int argc, char **argv);

/** `relight info`: describe a shot file. */
int cmd_info(int argc, char **argv);

/** `relight preview`: relight a shot file headless (the CPU reference with --cpu). */
int cmd_preview(int argc, char **argv);

/* relight bench: speed against error on the examples, the stability suite, a report. */
int cmd_bench(int argc, char **argv);

#endif

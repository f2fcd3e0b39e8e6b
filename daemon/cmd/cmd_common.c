/*
 * What the subcommands share: usage errors, numbers on the command line,
 * light edits (--set), the shader path.
 */
#include "cmd.h"
#include "config.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int cmd_usage_error(const char *cmd, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "relight %s: ", cmd);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	fprintf(stderr, "\nRun 'relight %s --help' for usage.\n", cmd);
	return CMD_USAGE;
}

bool cmd_parse_uint(const char *s, uint32_t max, uint32_t *out)
{
	char *end;
	errno = 0;
	unsigned long v = strtoul(s, &end, 10);
	if (errno || end == s || *end || s[0] == '-' || v > max)
		return false;
	*out = (uint32_t)v;
	return true;
}

bool cmd_check_output(const char *path, const char *who)
{
	struct stat st;
	if (!*path || path[strlen(path) - 1] == '/' || (stat(path, &st) == 0 && S_ISDIR(st.st_mode))) {
		fprintf(stderr, "%s: error: cannot write '%s': it is a folder, not a file\n", who,
			path);
		return false;
	}
	const char *slash = strrchr(path, '/');
	char *dir = slash ? strndup(path, (size_t)(slash - path) + (slash == path)) : strdup(".");
	if (!dir) {
		fprintf(stderr, "%s: error: out of memory\n", who);
		return false;
	}
	bool ok = false;
	if (stat(dir, &st) != 0)
		fprintf(stderr, "%s: error: cannot write '%s': the folder '%s' does not exist\n",
			who, path, dir);
	else if (!S_ISDIR(st.st_mode))
		fprintf(stderr, "%s: error: cannot write '%s': '%s' is not a folder\n", who, path,
			dir);
	else if (access(dir, W_OK | X_OK) != 0)
		fprintf(stderr, "%s: error: cannot write '%s': the folder '%s' is not writable\n",
			who, path, dir);
	else if (access(path, F_OK) == 0 && access(path, W_OK) != 0)
		fprintf(stderr, "%s: error: cannot write '%s': the file is not writable\n", who,
			path);
	else
		ok = true;
	free(dir);
	return ok;
}

bool cmd_parse_double(const char *s, double min, double max, double *out)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	if (errno || end == s || *end || !(v >= min && v <= max))
		return false;
	*out = v;
	return true;
}

/* LIGHT.PARAM=V[,V...]: the last '.' before the '=' ends LIGHT, ',' separates the numbers. */
bool cmd_parse_light_edit(char *arg, const char **light, const char **param, float values[16],
			  uint32_t *n)
{
	char *eq = strchr(arg, '=');
	if (!eq)
		return false;
	*eq = '\0';
	char *dot = strrchr(arg, '.');
	if (!dot || dot == arg || !dot[1])
		return false;
	*dot = '\0';
	*light = arg;
	*param = dot + 1;
	*n = 0;
	char *p = eq + 1;
	for (;;) {
		char *end;
		errno = 0;
		float v = strtof(p, &end);
		if (end == p || errno == ERANGE || *n == 16)
			return false;
		values[(*n)++] = v;
		if (*end == '\0')
			return true;
		if (*end != ',')
			return false;
		p = end + 1;
	}
}

void cmd_shader_path(char *buf, size_t size)
{
	const char *env = getenv("RELIGHT_SHADER_PATH");
	const char *rman = getenv("RMAN_SHADERPATH");
	snprintf(buf, size, "%s%s%s%s%s", env ? env : "", env && *env ? ":" : "",
		 rman ? rman : "", rman && *rman ? ":" : "", RELIGHT_SOURCE_SHADER_DIR);
}

int cmd_add_include(const char *cmd, char *buf, size_t size, const char *dir)
{
	size_t len = strlen(buf);
	if (!*dir || strchr(dir, ':'))
		return cmd_usage_error(cmd, "-I needs a folder without ':', not '%s'", dir);
	if (len + strlen(dir) + 2 > size)
		return cmd_usage_error(cmd, "-I folders exceed %zu bytes in all", size - 1);
	snprintf(buf + len, size - len, "%s%s", len ? ":" : "", dir);
	return CMD_OK;
}

bool cmd_parse_light_edit_text(char *arg, const char **light, const char **param,
			       float values[16], uint32_t *n, const char **text)
{
	char *eq = strchr(arg, '=');
	if (!eq)
		return false;
	/* the numbers are parsed from a copy: the text stays as written */
	size_t len = strlen(eq + 1);
	char *num = malloc(len + 2 + (size_t)(eq - arg));
	if (!num)
		return false;
	memcpy(num, arg, (size_t)(eq - arg) + len + 2);
	const char *l2, *p2;
	bool numbers = cmd_parse_light_edit(num, &l2, &p2, values, n);
	free(num);
	*eq = '\0';
	char *dot = strrchr(arg, '.');
	if (!dot || dot == arg || !dot[1])
		return false;
	*dot = '\0';
	*light = arg;
	*param = dot + 1;
	*text = eq + 1;
	if (numbers)
		return true;
	/* not numbers: a string (nothing: the empty one, no map), unless it is a
	   number gone wrong ("1x", "1,,2") */
	const char *t = *text;
	bool numeric = t[0] && strchr("0123456789+-.,", t[0]);
	if (numeric && strncmp(t, "./", 2) && strncmp(t, "../", 3))
		return false;
	*n = 0;
	return true;
}

int cmd_set_option(const char *cmd, const char *arg, char *copy, size_t cap, const char **light,
		   const char **param, float values[16], uint32_t *n, const char **text)
{
	if (strlen(arg) >= cap)
		return cmd_usage_error(cmd, "--set '%.40s...' is too long", arg);
	memcpy(copy, arg, strlen(arg) + 1);
	if (!cmd_parse_light_edit_text(copy, light, param, values, n, text))
		return cmd_usage_error(cmd, "--set needs LIGHT.PARAM=V[,V,...] with up to 16 "
				       "numbers, or LIGHT.PARAM=TEXT for a string, not '%s'", arg);
	return CMD_OK;
}

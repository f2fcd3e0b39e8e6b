/* What the subcommands share: usage errors, numbers on the command line, the shader path. */
#include "cmd.h"
#include "config.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

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

void cmd_shader_path(char *buf, size_t size)
{
	const char *env = getenv("RELIGHT_SHADER_PATH");
	snprintf(buf, size, "%s%s%s", env ? env : "", env && *env ? ":" : "",
		 RELIGHT_SOURCE_SHADER_DIR);
}

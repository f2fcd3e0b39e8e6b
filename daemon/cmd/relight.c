/*
 * relight: the command-line entry point. A git-style dispatcher: global
 * options, then a subcommand name and its own arguments.
 */
#include "cmd.h"
#include "config.h"

#include <stdio.h>
#include <string.h>

typedef int (*cmd_fn)(int argc, char **argv);

struct command {
	const char *name;
	cmd_fn run;
	const char *summary;
};

static const struct command commands[] = {
	{ "compile", cmd_compile, "Check an RSL shader; print its AST, IR or a JSON report" },
	{ "render", cmd_render, "Render a RIB scene to OpenEXR with the reference renderer" },
	{ "bake", cmd_bake, "Bake a RIB scene into a shot file for interactive relighting" },
	{ "info", cmd_info, "Describe a shot file: lights, surfaces, samples, entries, bytes" },
	{ "preview", cmd_preview, "Relight a shot file and write the image (--cpu: the reference)" },
	{ "diff", cmd_diff, "Compare two rendered images: errors, PSNR, a heat map" },
	{ "remote", cmd_remote, "Drive a running relightd: scripted edits, snapshots, stats" },
	{ "bench", cmd_bench, "Measure speed against error on the examples; the stability suite" },
};

static const size_t ncommands = sizeof(commands) / sizeof(commands[0]);

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight [--help] [--version] COMMAND [ARGS]\n"
		"\n"
		"relight previews the lighting of RenderMan scenes (RIB and RSL shaders)\n"
		"interactively.\n"
		"\n"
		"Commands:\n");
	for (size_t i = 0; i < ncommands; i++)
		fprintf(out, "  %-10s %s\n", commands[i].name, commands[i].summary);
	fprintf(out, "  %-10s %s\n", "help", "Show the help of a command");
	fprintf(out,
		"\n"
		"Options:\n"
		"  -h, --help     Show this help and exit\n"
		"  --version      Print the version and exit\n"
		"\n"
		"Run 'relight COMMAND --help' for the options of a command.\n");
}

static const struct command *find_command(const char *name)
{
	for (size_t i = 0; i < ncommands; i++)
		if (strcmp(commands[i].name, name) == 0)
			return &commands[i];
	return NULL;
}

/* Levenshtein distance, capped: names longer than 31 characters are not compared. */
static size_t edit_distance(const char *a, const char *b)
{
	size_t la = strlen(a), lb = strlen(b);
	size_t prev[32], cur[32];

	if (la > 31 || lb > 31)
		return (size_t)-1;
	for (size_t j = 0; j <= lb; j++)
		prev[j] = j;
	for (size_t i = 1; i <= la; i++) {
		cur[0] = i;
		for (size_t j = 1; j <= lb; j++) {
			size_t sub = prev[j - 1] + (a[i - 1] != b[j - 1]);
			size_t del = prev[j] + 1, ins = cur[j - 1] + 1;
			size_t best = sub < del ? sub : del;
			cur[j] = best < ins ? best : ins;
		}
		memcpy(prev, cur, (lb + 1) * sizeof(prev[0]));
	}
	return prev[lb];
}

static int unknown_command(const char *name)
{
	fprintf(stderr, "relight: '%s' is not a relight command.\n", name);
	for (size_t i = 0; i < ncommands; i++) {
		if (edit_distance(name, commands[i].name) <= 2) {
			fprintf(stderr, "Did you mean '%s'?\n", commands[i].name);
			break;
		}
	}
	fprintf(stderr, "Run 'relight --help' for the list of commands.\n");
	return CMD_USAGE;
}

/* `relight help [COMMAND]`: the same as `relight COMMAND --help`. */
static int run_help(int argc, char **argv)
{
	if (argc < 2) {
		usage(stdout);
		return CMD_OK;
	}
	const struct command *c = find_command(argv[1]);
	if (!c)
		return unknown_command(argv[1]);
	static char help_opt[] = "--help";
	char *args[] = { argv[1], help_opt, NULL };
	return c->run(2, args);
}

int main(int argc, char **argv)
{
	int i = 1;

	for (; i < argc && argv[i][0] == '-'; i++) {
		const char *opt = argv[i];
		if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) {
			usage(stdout);
			return CMD_OK;
		} else if (strcmp(opt, "--version") == 0) {
			printf("relight %s\n", RELIGHT_VERSION);
			return CMD_OK;
		} else if (strcmp(opt, "--") == 0) {
			i++;
			break;
		} else {
			fprintf(stderr, "relight: unknown option '%s'\n", opt);
			fprintf(stderr, "Run 'relight --help' for usage.\n");
			return CMD_USAGE;
		}
	}

	if (i >= argc) {
		usage(stderr);
		return CMD_USAGE;
	}

	const char *name = argv[i];
	if (strcmp(name, "help") == 0)
		return run_help(argc - i, argv + i);
	const struct command *c = find_command(name);
	if (!c)
		return unknown_command(name);
	return c->run(argc - i, argv + i);
}

/*
 * `relight compile`: compile an RSL shader with the library's public API
 * (sl.h) and, on request, print its AST, IR or a JSON report.
 */
#include "cmd.h"
#include "config.h"
#include "sl.h"
#include "spec.h"
#include "glsl.h"

#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

enum emit_mode { EMIT_NONE, EMIT_AST, EMIT_IR, EMIT_REPORT, EMIT_CACHE, EMIT_GLSL };

static void usage(FILE *out)
{
	fprintf(out,
		"usage: relight compile [OPTIONS] FILE.sl\n"
		"\n"
		"Compile an RSL shader: preprocess, parse, check types and lower it to the\n"
		"IR. Errors are printed as FILE:LINE:COL: error: MESSAGE. With no --emit,\n"
		"nothing is printed on success.\n"
		"\n"
		"Options:\n"
		"  --emit KIND           Print a result on success; KIND is one of:\n"
		"                          ast     the parse tree, one node a line (parsing\n"
		"                                  only: types are not checked)\n"
		"                          ir      the typed IR, one instruction a line\n"
		"                          report  JSON: name, type, parameters and\n"
		"                                  instruction counts; for a surface shader\n"
		"                                  also its specialization: dynamic_params,\n"
		"                                  cached_channels, cached_scalars,\n"
		"                                  cache_required, static/dynamic/dead\n"
		"                                  instruction counts\n"
		"                          cache   the caching program of a surface shader\n"
		"                                  (its static part, as IR)\n"
		"                          glsl    the GLSL compute shader of a surface's\n"
		"                                  dynamic part (with no lights), of a light\n"
		"                                  shader's translation, or of an imager's\n"
		"                                  pass over the pixels\n"
		"  --dynamic P1,P2,...   Surface parameters a user may edit: specialize with\n"
		"                        them dynamic as well as the lights\n"
		"  --atmosphere VOLUME   Join the surface shader with the volume shader VOLUME\n"
		"                        run after it (as RIB's Atmosphere does; looked up as\n"
		"                        FILE.sl is) and print what --emit asks of the pair\n"
		"  --strict              Light-dependent values the GPU cannot compute (they\n"
		"                        are cached at bake time, a warning) are errors\n"
		"  -I DIR, --include DIR\n"
		"                        Search DIR for #include files (after the including\n"
		"                        file's own directory); may be repeated\n"
		"  -D NAME[=VALUE], --define NAME[=VALUE]\n"
		"                        Define a preprocessor macro (VALUE defaults to 1);\n"
		"                        may be repeated\n"
		"  -o FILE, --output FILE\n"
		"                        Write the --emit result to FILE instead of standard\n"
		"                        output (only written when compilation succeeds)\n"
		"  -h, --help            Show this help and exit\n"
		"\n"
		"-IDIR and -DNAME may also be written joined. If FILE.sl does not exist and\n"
		"contains no '/', it is looked for (also with .sl appended) in each directory\n"
		"of $RELIGHT_SHADER_PATH, then of $RMAN_SHADERPATH (both colon-separated),\n"
		"then in the project's shader library (%s).\n"
		"\n"
		"Exit status: 0 on success, 1 if the shader has errors or cannot be read or\n"
		"the output cannot be written, 2 on a usage error.\n",
		RELIGHT_SOURCE_SHADER_DIR);
}

#define usage_error(...) cmd_usage_error("compile", __VA_ARGS__)

static bool is_file(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0 && !S_ISDIR(st.st_mode);
}

static bool ends_with(const char *s, const char *suffix)
{
	size_t ls = strlen(s), lx = strlen(suffix);
	return ls >= lx && strcmp(s + ls - lx, suffix) == 0;
}

/*
 * Look for @name as "DIR/name" (and "DIR/name.sl" when @name lacks the
 * suffix) in directory @dir of length @dirlen. Returns a malloc'd path or NULL.
 */
static char *try_dir(const char *dir, size_t dirlen, const char *name)
{
	if (dirlen == 0)
		return NULL;
	for (int pass = 0; pass < 2; pass++) {
		const char *ext = pass ? ".sl" : "";
		if (pass && ends_with(name, ".sl"))
			break;
		size_t size = dirlen + 1 + strlen(name) + strlen(ext) + 1;
		char *path = malloc(size);
		if (!path)
			return NULL;
		snprintf(path, size, "%.*s/%s%s", (int)dirlen, dir, name, ext);
		if (is_file(path))
			return path;
		free(path);
	}
	return NULL;
}

/*
 * Where the shader named on the command line is: the path as given if it
 * exists; for a bare name, the search path. Returns a malloc'd path or NULL.
 */
static char *find_shader(const char *name)
{
	if (is_file(name) || strchr(name, '/'))
		return strdup(name);

	const char *const vars[] = { "RELIGHT_SHADER_PATH", "RMAN_SHADERPATH" };
	for (size_t v = 0; v < sizeof(vars) / sizeof(vars[0]); v++) {
		const char *path = getenv(vars[v]);
		for (const char *p = path; p;) {
			const char *colon = strchr(p, ':');
			size_t len = colon ? (size_t)(colon - p) : strlen(p);
			char *found = try_dir(p, len, name);
			if (found)
				return found;
			p = colon ? colon + 1 : NULL;
		}
	}
	return try_dir(RELIGHT_SOURCE_SHADER_DIR, strlen(RELIGHT_SOURCE_SHADER_DIR), name);
}

/* A -D argument is NAME or NAME=VALUE, NAME an identifier. */
static bool valid_define(const char *def)
{
	const char *p = def;
	if (!(*p == '_' || (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z')))
		return false;
	for (p++; *p && *p != '='; p++)
		if (!(*p == '_' || (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		      (*p >= '0' && *p <= '9')))
			return false;
	return true;
}

/* Copy the buffered result to @out_path (or stdout). */
static int write_output(const char *out_path, const char *data, size_t len)
{
	FILE *f = out_path ? fopen(out_path, "w") : stdout;
	if (!f) {
		fprintf(stderr, "relight compile: cannot write '%s': %s\n", out_path,
			strerror(errno));
		return CMD_FAILED;
	}
	bool ok = fwrite(data, 1, len, f) == len;
	ok = (out_path ? fclose(f) == 0 : fflush(f) == 0) && ok;
	if (!ok) {
		fprintf(stderr, "relight compile: error writing '%s': %s\n",
			out_path ? out_path : "standard output", strerror(errno));
		return CMD_FAILED;
	}
	return CMD_OK;
}

/* The parsed command line. The strings point into argv. */
struct compile_args {
	enum emit_mode emit;
	bool strict;                /* --strict */
	const char **dyn;           /* --dynamic names */
	size_t ndyn;
	char *dyn_buf;
	const char *out_path;
	const char *input;
	const char *atmosphere;     /* --atmosphere */
	const char **incs, **defs;
	size_t nincs, ndefs;
};

/* Parse the options of `relight compile`; returns -1 to go on, else the exit status. */
static int parse_args(int argc, char **argv, struct compile_args *args)
{
	static const struct option long_opts[] = {
		{ "emit", required_argument, NULL, 'e' },
		{ "include", required_argument, NULL, 'I' },
		{ "define", required_argument, NULL, 'D' },
		{ "output", required_argument, NULL, 'o' },
		{ "dynamic", required_argument, NULL, 'y' },
		{ "strict", no_argument, NULL, 's' },
		{ "atmosphere", required_argument, NULL, 'a' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	int opt;

	opterr = 0;
	optind = 1;
	while ((opt = getopt_long(argc, argv, ":hI:D:o:", long_opts, NULL)) != -1) {
		switch (opt) {
		case 'h':
			usage(stdout);
			return CMD_OK;
		case 'e':
			if (strcmp(optarg, "ast") == 0)
				args->emit = EMIT_AST;
			else if (strcmp(optarg, "ir") == 0)
				args->emit = EMIT_IR;
			else if (strcmp(optarg, "report") == 0)
				args->emit = EMIT_REPORT;
			else if (strcmp(optarg, "cache") == 0)
				args->emit = EMIT_CACHE;
			else if (strcmp(optarg, "glsl") == 0)
				args->emit = EMIT_GLSL;
			else
				return usage_error("unknown --emit kind '%s' (expected ast, ir, "
						   "report, cache or glsl)", optarg);
			break;
		case 's':
			args->strict = true;
			break;
		case 'a':
			args->atmosphere = optarg;
			break;
		case 'y': {
			/* a comma-separated list of parameter names */
			free(args->dyn_buf);
			free(args->dyn);
			args->dyn_buf = strdup(optarg);
			args->dyn = calloc(strlen(optarg) + 2, sizeof(char *));
			args->ndyn = 0;
			if (!args->dyn_buf || !args->dyn)
				return usage_error("out of memory");
			for (char *t = strtok(args->dyn_buf, ","); t; t = strtok(NULL, ","))
				args->dyn[args->ndyn++] = t;
			if (args->ndyn == 0)
				return usage_error("--dynamic needs parameter names, e.g. Kd,roughness");
			break;
		}
		case 'I':
			if (!*optarg)
				return usage_error("-I needs a directory");
			args->incs[args->nincs++] = optarg;
			break;
		case 'D':
			if (!valid_define(optarg))
				return usage_error("bad definition '%s' for -D (expected NAME or "
						   "NAME=VALUE)", optarg);
			args->defs[args->ndefs++] = optarg;
			break;
		case 'o':
			args->out_path = optarg;
			break;
		case ':':
			return usage_error("option '%s' needs an argument", argv[optind - 1]);
		default:
			if (optopt && optopt != '?') {
				char bad[3] = { '-', (char)optopt, 0 };
				return usage_error("unknown option '%s'", bad);
			}
			return usage_error("unknown option '%s'", argv[optind - 1]);
		}
	}

	if (optind >= argc)
		return usage_error("no input file");
	if (argc - optind > 1)
		return usage_error("one input file expected; extra argument '%s'",
				   argv[optind + 1]);
	if (args->atmosphere && args->emit == EMIT_AST)
		return usage_error("--atmosphere needs the IR: not with --emit ast");
	if (args->out_path && args->emit == EMIT_NONE)
		return usage_error("-o needs --emit (there is nothing to write otherwise)");
	args->input = argv[optind];
	return -1;
}

/* Lines of @s (a NUL-terminated text). */
static long count_lines(const char *s)
{
	long n = 0;
	for (; *s; s++)
		n += *s == '\n';
	return n;
}

/*
 * The GLSL of a light shader: its translation, inside a kernel whose surface
 * adds up the light's Cl over an illuminance loop.
 */
static bool emit_light_glsl(const struct sl_program *light, FILE *mem)
{
	static const char wrapper[] =
		"surface lightpreview() { Oi = 1; Ci = 0; illuminance(P) { Ci += Cl; } }\n";
	struct sl_options o = { .diag = stderr };
	struct sl_program *surf = sl_compile_string("<light preview>", wrapper, sizeof(wrapper) - 1,
						    &o);
	if (!surf)
		return false;
	int32_t inputs[SL_GLOBAL_COUNT], outputs[2];
	uint32_t nin = 0;
	static const enum sl_global in_globals[] = { SL_GLOBAL_P, SL_GLOBAL_N, SL_GLOBAL_I,
						     SL_GLOBAL_E };
	for (size_t g = 0; g < sizeof(in_globals) / sizeof(in_globals[0]); g++)
		if (surf->global_reg[in_globals[g]] >= 0)
			inputs[nin++] = surf->global_reg[in_globals[g]];
	outputs[0] = surf->global_reg[SL_GLOBAL_CI];
	outputs[1] = surf->global_reg[SL_GLOBAL_OI];
	struct sl_slice slice = { surf, NULL, inputs, nin, outputs, 2 };
	struct sl_glsl_layout lay;
	const struct sl_program *lights[1] = { light };
	char *src = sl_glsl_emit(&slice, lights, 1, &lay, stderr);
	if (src) {
		fputs(src, mem);
		sl_glsl_layout_finish(&lay);
	}
	free(src);
	sl_program_destroy(surf);
	return src != NULL;
}

/*
 * The GLSL of an imager shader: the kernel the GPU runtime runs after its
 * resolve (gpu/imagerpass.c), a pixel per invocation, reading the globals
 * the shader uses and writing Ci and alpha.
 */
static bool emit_imager_glsl(const struct sl_program *im, FILE *mem)
{
	enum sl_global globals[SL_GLSL_IMAGER_INPUTS];
	uint32_t nin;
	struct sl_glsl_layout lay;
	char *src = sl_glsl_emit_imager(im, globals, &nin, &lay, stderr);
	if (src) {
		fputs(src, mem);
		sl_glsl_layout_finish(&lay);
	}
	free(src);
	return src != NULL;
}

/* The report (with the specialization of a surface shader), the caching program or GLSL. */
static bool emit_specialized(const struct sl_program *prog, const struct compile_args *args,
			     FILE *mem)
{
	if (sl_program_kind(prog) == SL_SHADER_LIGHT && args->emit == EMIT_GLSL && !args->ndyn)
		return emit_light_glsl(prog, mem);
	if (sl_program_kind(prog) == SL_SHADER_VOLUME &&
	    (args->emit == EMIT_CACHE || args->emit == EMIT_GLSL || args->ndyn)) {
		fprintf(stderr, "relight compile: %s is a volume shader; it is specialized with the "
			"surface it follows (relight compile --atmosphere %s SURFACE)\n",
			args->input, sl_program_name(prog));
		return false;
	}
	if (sl_program_kind(prog) == SL_SHADER_IMAGER && args->emit == EMIT_GLSL && !args->ndyn)
		return emit_imager_glsl(prog, mem);
	if (sl_program_kind(prog) != SL_SHADER_SURFACE) {
		if (args->emit == EMIT_CACHE || args->ndyn) {
			fprintf(stderr, "relight compile: %s is a %s shader; only surface shaders "
				"are specialized (light and imager shaders run whole on the GPU)\n",
				args->input, sl_shader_kind_name(sl_program_kind(prog)));
			return false;
		}
		sl_emit_report(prog, NULL, mem);
		return true;
	}
	struct sl_spec *s = sl_specialize(prog, args->dyn, args->ndyn, stderr);
	if (!s)
		return false;
	for (uint32_t k = 0; k < s->ncache_required; k++) {
		const struct sl_insn *in = &prog->code[s->cache_required[k]];
		fprintf(stderr, "%s:%u:%u: %s: this light-dependent value cannot be computed "
			"on the GPU; it is cached at bake time\n",
			in->loc.file < prog->nfiles ? prog->files[in->loc.file] : "?", in->loc.line,
			in->loc.col, args->strict ? "error" : "warning");
	}
	if (args->strict && s->ncache_required) {
		sl_spec_destroy(s);
		return false;
	}
	/* The dynamic part's GLSL, with no lights (their count is fixed per kernel). */
	struct sl_glsl_layout lay;
	bool ok = true;
	char *glsl = NULL;
	if (args->emit == EMIT_GLSL || args->emit == EMIT_REPORT) {
		glsl = sl_glsl_emit(&s->slice, NULL, 0, &lay,
				    args->emit == EMIT_GLSL ? stderr : NULL);
		if (glsl)
			sl_glsl_layout_finish(&lay);
		else if (args->emit == EMIT_GLSL)
			ok = false;
	}
	if (args->emit == EMIT_CACHE) {
		sl_ir_dump(s->caching, mem);
	} else if (args->emit == EMIT_GLSL && glsl) {
		fputs(glsl, mem);
	} else if (args->emit == EMIT_REPORT) {
		char *fields = sl_spec_report_fields(s, args->dyn, args->ndyn,
						     glsl ? count_lines(glsl) : -1);
		sl_emit_report(prog, fields, mem);
		free(fields);
	}
	free(glsl);
	sl_spec_destroy(s);
	return ok;
}

/*
 * @surf joined with the volume shader named by --atmosphere (the pair owns
 * both), or @surf itself without one; NULL (reported, @surf destroyed) when
 * the volume shader is missing, does not compile, or either is of the wrong kind.
 */
static struct sl_program *with_atmosphere(struct sl_program *surf, const struct compile_args *args,
					  const struct sl_options *opts)
{
	if (!surf || !args->atmosphere)
		return surf;
	char *path = find_shader(args->atmosphere);
	struct sl_program *atm = path && is_file(path) ? sl_compile_file(path, opts) : NULL;
	if (!path || !is_file(path))
		fprintf(stderr, "relight compile: cannot open '%s': %s\n", args->atmosphere,
			strerror(ENOENT));
	free(path);
	struct sl_program *j = atm ? sl_program_compose(surf, atm) : NULL;
	if (atm && !j)
		fprintf(stderr, "relight compile: --atmosphere joins a surface shader and a volume "
			"shader; '%s' is a %s shader and '%s' a %s shader\n", sl_program_name(surf),
			sl_shader_kind_name(sl_program_kind(surf)), sl_program_name(atm),
			sl_shader_kind_name(sl_program_kind(atm)));
	if (!j) {
		sl_program_destroy(atm);
		sl_program_destroy(surf);
		return NULL;
	}
	sl_program_own_parts(j);
	sl_program_report_nonaffine(j, stderr, args->strict);
	return j;
}

/* Compile (or parse, for --emit ast) and print or write the result. */
static int run(const struct compile_args *args)
{
	char *path = find_shader(args->input);
	if (!path || !is_file(path)) {
		struct stat st;
		if (path && stat(path, &st) == 0)
			fprintf(stderr, "relight compile: '%s' is a directory\n", path);
		else
			fprintf(stderr, "relight compile: cannot open '%s': %s\n", args->input,
				strerror(ENOENT));
		free(path);
		return CMD_FAILED;
	}

	struct sl_options opts = {
		.include_dirs = args->incs,
		.n_include_dirs = args->nincs,
		.defines = args->defs,
		.n_defines = args->ndefs,
		.diag = stderr,
	};

	/* The result is buffered so that nothing is printed or written on failure. */
	char *buf = NULL;
	size_t buflen = 0;
	FILE *mem = open_memstream(&buf, &buflen);
	if (!mem) {
		fprintf(stderr, "relight compile: %s\n", strerror(errno));
		free(path);
		return CMD_FAILED;
	}

	bool ok;
	if (args->emit == EMIT_AST) {
		ok = sl_emit_ast_file(path, &opts, mem);
	} else {
		struct sl_program *prog = with_atmosphere(sl_compile_file(path, &opts), args, &opts);
		ok = prog != NULL;
		if (prog && args->emit == EMIT_IR)
			sl_emit(prog, SL_EMIT_IR, mem);
		else if (prog && (args->emit == EMIT_REPORT || args->emit == EMIT_CACHE ||
				  args->emit == EMIT_GLSL || args->ndyn || args->strict))
			ok = emit_specialized(prog, args, mem);
		sl_program_destroy(prog);
	}
	fclose(mem);

	int status = CMD_FAILED;
	if (ok)
		status = args->emit == EMIT_NONE ? CMD_OK
						 : write_output(args->out_path, buf, buflen);
	free(buf);
	free(path);
	return status;
}

int cmd_compile(int argc, char **argv)
{
	/* At most argc of each. */
	struct compile_args args = {
		.emit = EMIT_NONE,
		.incs = calloc((size_t)argc + 1, sizeof(char *)),
		.defs = calloc((size_t)argc + 1, sizeof(char *)),
	};
	int status = CMD_FAILED;

	if (!args.incs || !args.defs)
		fprintf(stderr, "relight compile: out of memory\n");
	else if ((status = parse_args(argc, argv, &args)) < 0)
		status = run(&args);
	free(args.incs);
	free(args.defs);
	free(args.dyn);
	free(args.dyn_buf);
	return status;
}

/*
 * Library-level tests of compilation (sl.h): diagnostics and their format,
 * options, the shader library in shaders/, and the JSON report.
 */
#include "test.h"

#include "ir.h"
#include "sl.h"

#include <dirent.h>
#include <stdbool.h>

/* The output of one compilation's diagnostics. */
struct diag {
	char *text;
	size_t len;
	FILE *f;
};

static void diag_open(struct diag *d)
{
	d->text = NULL;
	d->len = 0;
	d->f = open_memstream(&d->text, &d->len);
}

static void diag_close(struct diag *d)
{
	fclose(d->f);
	d->f = NULL;
}

/* Lines of @text containing @needle. */
static int count_lines(const char *text, const char *needle)
{
	int n = 0;
	for (const char *p = text; p && *p;) {
		const char *eol = strchr(p, '\n');
		size_t len = eol ? (size_t)(eol - p) : strlen(p);
		const char *hit = strstr(p, needle);
		if (hit && hit < p + len)
			n++;
		p = eol ? eol + 1 : p + len;
	}
	return n;
}

/*
 * Compile @src named @name; return the program (or NULL) and the diagnostics
 * in *diag_text (malloc'd, caller frees).
 */
static struct sl_program *compile(const char *name, const char *src, struct sl_options *opts,
				  char **diag_text)
{
	struct sl_options o = opts ? *opts : (struct sl_options){ 0 };
	struct diag d;
	diag_open(&d);
	o.diag = d.f;
	struct sl_program *prog = sl_compile_string(name, src, strlen(src), &o);
	diag_close(&d);
	*diag_text = d.text;
	return prog;
}

/*
 * A bad shader fails with a first diagnostic "NAME:LINE:COL: error: " at the
 * expected line and column, and the message contains @words.
 */
static void expect_error(const char *name, const char *src, int line, int col, const char *words)
{
	char *text;
	struct sl_program *prog = compile(name, src, NULL, &text);
	CHECK(prog == NULL);
	char prefix[256];
	snprintf(prefix, sizeof(prefix), "%s:%d:%d: error: ", name, line, col);
	if (strncmp(text, prefix, strlen(prefix)) != 0) {
		test_failures++;
		fprintf(stderr, "[%s] expected a diagnostic starting \"%s\", got:\n%s\n", test_current,
			prefix, text);
	}
	test_checks++;
	if (words)
		CHECK(strstr(text, words) != NULL);
	free(text);
	sl_program_destroy(prog);
}

static void test_diagnostics(void)
{
	/* Columns count from 1; the tab before Ci counts as one column. */
	expect_error("undeclared.sl", "surface s()\n{\n\tCi = nosuch;\n}\n", 3, 7, "nosuch");
	expect_error("syntax.sl", "surface s()\n{\n  Ci = Cs * ;\n}\n", 3, 13, "near ';'");
	expect_error("call.sl", "surface s() { Ci = mix(Cs, \"x\", 1); }\n", 1, 20, "mix");
	expect_error("type.sl", "surface s() {\n float f = \"text\";\n}\n", 2, 0 + 12, NULL);
	expect_error("gather.sl",
		     "surface s() {\n  gather(\"illuminance\", P, N, 1, 4) { Ci = 1; }\n}\n", 2, 3,
		     "gather");
	/* A uniform local that varies is promoted; a uniform parameter is not. */
	expect_error("uniform.sl", "surface s(float x = 0) {\n  x = s;\n  Ci = x;\n}\n",
		     2, 0 + 5, "uniform parameter 'x' is assigned a varying value");
	expect_error("ns.sl", "surface s() {\n  Ci = color(xcomp(Ns), 0, 0);\n}\n", 2, 20,
		     "'Ns' is defined only in light shaders");
	expect_error("empty.sl", "", 1, 1, NULL);
	expect_error("two.sl", "surface a() { }\nsurface b() { }\n", 2, 9, "second shader");
	expect_error("noparam.sl", "surface s(float Kd) { Ci = Kd; }\n", 1, 17, "default");
}

/* Compilation goes on after an error, and stops after max_errors. */
static void test_many_errors(void)
{
	char *text;
	struct sl_program *prog = compile("three.sl",
					  "surface s() {\n"
					  "  float a = bad1;\n"
					  "  float b = bad2;\n"
					  "  float c = bad3;\n"
					  "}\n",
					  NULL, &text);
	CHECK(prog == NULL);
	CHECK(count_lines(text, ": error: ") == 3);
	CHECK(strstr(text, "three.sl:2:") && strstr(text, "three.sl:3:") &&
	      strstr(text, "three.sl:4:"));
	free(text);

	/* 40 errors, stopped at 5. */
	char src[4096];
	size_t n = (size_t)snprintf(src, sizeof(src), "surface s() {\n");
	for (int i = 0; i < 40; i++)
		n += (size_t)snprintf(src + n, sizeof(src) - n, "  float v%d = undef%d;\n", i, i);
	snprintf(src + n, sizeof(src) - n, "}\n");
	struct sl_options o = { .max_errors = 5 };
	prog = compile("forty.sl", src, &o, &text);
	CHECK(prog == NULL);
	int nerr = count_lines(text, ": error: ");
	CHECK(nerr >= 5 && nerr <= 6); /* 5, plus perhaps one "too many errors" line */
	CHECK(strstr(text, "undef5") == NULL);
	free(text);
}

static void test_options(void)
{
	const char *src = "#ifdef FANCY\n"
			  "surface fancy(float k = GAIN) { Ci = Cs * k; }\n"
			  "#else\n"
			  "surface plain() { Ci = Cs; }\n"
			  "#endif\n";
	char *text;
	struct sl_program *prog = compile("opt.sl", src, NULL, &text);
	CHECK(prog != NULL);
	CHECK_STR(text, "");
	if (prog)
		CHECK_STR(sl_program_name(prog), "plain");
	sl_program_destroy(prog);
	free(text);

	const char *defs[] = { "FANCY", "GAIN=0.25" };
	struct sl_options o = { .defines = defs, .n_defines = 2 };
	prog = compile("opt.sl", src, &o, &text);
	CHECK(prog != NULL);
	if (prog) {
		CHECK_STR(sl_program_name(prog), "fancy");
		CHECK(sl_program_kind(prog) == SL_SHADER_SURFACE);
		int k = sl_program_find_param(prog, "k");
		CHECK(k == 0);
		CHECK(sl_program_find_param(prog, "nosuch") == -1);
	}
	sl_program_destroy(prog);
	free(text);

	CHECK_STR(sl_shader_kind_name(SL_SHADER_SURFACE), "surface");
	CHECK_STR(sl_shader_kind_name(SL_SHADER_LIGHT), "light");
	CHECK_STR(sl_shader_kind_name(SL_SHADER_DISPLACEMENT), "displacement");
}

/* The shader library: every .sl file in shaders/ compiles cleanly, named after its file. */
static const struct {
	const char *name;
	enum sl_shader_kind kind;
	const char *params; /* space-separated, in order */
} library[] = {
	{ "constant", SL_SHADER_SURFACE, "" },
	{ "matte", SL_SHADER_SURFACE, "Ka Kd" },
	{ "metal", SL_SHADER_SURFACE, "Ka Ks roughness" },
	{ "shinymetal", SL_SHADER_SURFACE, "Ka Ks Kr roughness texturename" },
	{ "plastic", SL_SHADER_SURFACE, "Ka Kd Ks roughness specularcolor" },
	{ "paintedplastic", SL_SHADER_SURFACE, "Ka Kd Ks roughness specularcolor texturename" },
	{ "defaultsurface", SL_SHADER_SURFACE, "Kd Ka" },
	{ "hair", SL_SHADER_SURFACE, "Ka Kd Ks roughness rootdarken specularcolor" },
	{ "ambientlight", SL_SHADER_LIGHT, "intensity lightcolor" },
	{ "distantlight", SL_SHADER_LIGHT, "intensity lightcolor from to" },
	{ "pointlight", SL_SHADER_LIGHT, "intensity lightcolor from" },
	{ "spotlight", SL_SHADER_LIGHT,
	  "intensity lightcolor from to coneangle conedeltaangle beamdistribution" },
	{ "shadowspot", SL_SHADER_LIGHT,
	  "intensity lightcolor from to coneangle conedeltaangle beamdistribution shadowname "
	  "samples blur bias width" },
	{ "uberlight", SL_SHADER_LIGHT, NULL },
	{ "fog", SL_SHADER_VOLUME, "distance background" },
	{ "depthcue", SL_SHADER_VOLUME, "mindistance maxdistance background" },
};

static void shader_dir(char *buf, size_t size)
{
	const char *src = getenv("RELIGHT_SOURCE_DIR");
	snprintf(buf, size, "%s/shaders", src ? src : ".");
}

static void test_library(void)
{
	char dir[1024];
	shader_dir(dir, sizeof(dir));
	DIR *d = opendir(dir);
	CHECK(d != NULL);
	if (!d)
		return;
	int nfiles = 0;
	struct dirent *ent;
	while ((ent = readdir(d))) {
		size_t len = strlen(ent->d_name);
		if (len < 4 || strcmp(ent->d_name + len - 3, ".sl") != 0)
			continue;
		nfiles++;
		char path[2048];
		snprintf(path, sizeof(path), "%s/%s", dir, ent->d_name);
		struct diag dg;
		diag_open(&dg);
		struct sl_options o = { .diag = dg.f };
		struct sl_program *prog = sl_compile_file(path, &o);
		diag_close(&dg);
		test_current = ent->d_name;
		CHECK(prog != NULL);
		/* No warnings either. */
		CHECK_STR(dg.text, "");
		if (prog) {
			/* The shader is named after its file. */
			CHECK(strncmp(sl_program_name(prog), ent->d_name, len - 3) == 0 &&
			      strlen(sl_program_name(prog)) == len - 3);
		}
		sl_program_destroy(prog);
		free(dg.text);
	}
	closedir(d);
	test_current = "test_library";
	CHECK(nfiles >= (int)(sizeof(library) / sizeof(library[0])));

	/* The standard shaders are all there, of the right kind, with the RISpec parameters. */
	for (size_t i = 0; i < sizeof(library) / sizeof(library[0]); i++) {
		char path[2048];
		snprintf(path, sizeof(path), "%s/%s.sl", dir, library[i].name);
		struct sl_program *prog = sl_compile_file(path, NULL);
		test_current = library[i].name;
		CHECK(prog != NULL);
		if (!prog)
			continue;
		CHECK(sl_program_kind(prog) == library[i].kind);
		if (library[i].params) {
			char names[512] = "";
			for (uint32_t k = 0; k < prog->nparams; k++) {
				strncat(names, k ? " " : "", sizeof(names) - strlen(names) - 1);
				strncat(names, prog->params[k].name, sizeof(names) - strlen(names) - 1);
			}
			CHECK_STR(names, library[i].params);
		}
		sl_program_destroy(prog);
	}
	test_current = "test_library";
}

/* The uberlight's output parameters, which other shaders read by message passing. */
static void test_uberlight_outputs(void)
{
	char dir[1024], path[2048];
	shader_dir(dir, sizeof(dir));
	snprintf(path, sizeof(path), "%s/uberlight.sl", dir);
	struct sl_program *prog = sl_compile_file(path, NULL);
	CHECK(prog != NULL);
	if (!prog)
		return;
	static const char *const outputs[] = { "__category", "__nondiffuse", "__nonspecular" };
	for (int i = 0; i < 3; i++) {
		int k = sl_program_find_param(prog, outputs[i]);
		CHECK(k >= 0);
		if (k >= 0) {
			CHECK(prog->params[k].output);
			CHECK(prog->params[k].type.detail == SL_DETAIL_UNIFORM);
		}
	}
	static const char *const controls[] = {
		"lighttype", "cuton", "cutoff", "nearedge", "faredge", "falloff", "falloffdist",
		"width", "height", "wedge", "hedge", "roundness", "barnleft", "barnright", "barntop",
		"barnbottom", "barnedge", "slidename", "shadowname",
	};
	for (size_t i = 0; i < sizeof(controls) / sizeof(controls[0]); i++) {
		int k = sl_program_find_param(prog, controls[i]);
		CHECK(k >= 0);
		if (k >= 0)
			CHECK(!prog->params[k].output);
	}
	sl_program_destroy(prog);
}

/*
 * In JSON text @json, the value after the first "key": starts with @value
 * (spaces after the colon skipped).
 */
static bool json_field(const char *json, const char *key, const char *value)
{
	char quoted[128];
	snprintf(quoted, sizeof(quoted), "\"%s\"", key);
	const char *p = strstr(json, quoted);
	if (!p)
		return false;
	p += strlen(quoted);
	while (*p == ' ' || *p == '\n')
		p++;
	if (*p++ != ':')
		return false;
	while (*p == ' ' || *p == '\n')
		p++;
	return strncmp(p, value, strlen(value)) == 0;
}

static void test_report(void)
{
	const char *src = "surface rep(float Kd = 0.5; color tint = color (1, 0.5, 0.25);\n"
			  "            string map = \"a.tex\"; output varying float mask = 0)\n"
			  "{\n"
			  "  mask = s;\n"
			  "  Ci = Cs * tint * Kd * mask;\n"
			  "}\n";
	char *text;
	struct sl_program *prog = compile("rep.sl", src, NULL, &text);
	CHECK(prog != NULL);
	CHECK_STR(text, "");
	free(text);
	if (!prog)
		return;

	char *json = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&json, &len);
	sl_emit(prog, SL_EMIT_REPORT, f);
	fclose(f);

	CHECK(len > 0 && json[0] == '{' && json[len - 2] == '}' && json[len - 1] == '\n');
	CHECK(json_field(json, "name", "\"rep\""));
	CHECK(json_field(json, "type", "\"surface\""));
	CHECK(json_field(json, "parameters", "["));
	/* Parameters in order, with their types and folded defaults. */
	const char *kd = strstr(json, "{\"name\": \"Kd\"");
	const char *tint = strstr(json, "{\"name\": \"tint\"");
	const char *map = strstr(json, "{\"name\": \"map\"");
	const char *mask = strstr(json, "{\"name\": \"mask\"");
	CHECK(kd && tint && map && mask && kd < tint && tint < map && map < mask);
	if (kd && tint && map && mask) {
		CHECK(json_field(kd, "type", "\"float\""));
		CHECK(json_field(kd, "default", "0.5"));
		CHECK(json_field(tint, "type", "\"color\""));
		CHECK(json_field(tint, "default", "[1, 0.5, 0.25]"));
		CHECK(json_field(map, "type", "\"string\""));
		CHECK(json_field(map, "default", "\"a.tex\""));
		CHECK(json_field(mask, "output", "true"));
		CHECK(json_field(mask, "detail", "\"varying\""));
		CHECK(json_field(kd, "detail", "\"uniform\""));
	}
	CHECK(json_field(json, "instructions", "{"));
	/* The instruction count is the program's. */
	char total[64];
	snprintf(total, sizeof(total), "%u", prog->ncode);
	const char *insns = strstr(json, "\"instructions\"");
	CHECK(insns && json_field(insns, "total", total));
	/* Braces and brackets balance outside strings. */
	int depth = 0, min_depth = 0;
	bool in_str = false;
	for (size_t i = 0; i < len; i++) {
		char c = json[i];
		if (in_str) {
			if (c == '\\')
				i++;
			else if (c == '"')
				in_str = false;
		} else if (c == '"') {
			in_str = true;
		} else if (c == '{' || c == '[') {
			depth++;
		} else if (c == '}' || c == ']') {
			depth--;
			if (depth < min_depth)
				min_depth = depth;
		}
	}
	CHECK(depth == 0 && min_depth == 0 && !in_str);
	free(json);
	sl_program_destroy(prog);
}

/* The AST printer and compile_file on a missing file. */
static void test_files(void)
{
	char dir[1024], path[2048];
	shader_dir(dir, sizeof(dir));
	snprintf(path, sizeof(path), "%s/matte.sl", dir);

	char *out = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&out, &len);
	CHECK(sl_emit_ast_file(path, NULL, f));
	fclose(f);
	CHECK(out && strstr(out, "SHADER") != NULL);
	CHECK(out && strstr(out, "matte") != NULL);
	free(out);

	struct diag d;
	diag_open(&d);
	struct sl_options o = { .diag = d.f };
	struct sl_program *prog = sl_compile_file("/nonexistent/dir/x.sl", &o);
	diag_close(&d);
	CHECK(prog == NULL);
	CHECK(d.text && strstr(d.text, "/nonexistent/dir/x.sl") != NULL);
	CHECK(d.text && strstr(d.text, "error") != NULL);
	free(d.text);
}

int main(void)
{
	RUN(test_diagnostics);
	RUN(test_many_errors);
	RUN(test_options);
	RUN(test_library);
	RUN(test_uberlight_outputs);
	RUN(test_report);
	RUN(test_files);
	return test_finish();
}

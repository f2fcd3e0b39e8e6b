/*
 * Tests of shader lookup and the shader cache: a shader found by the name
 * it declares, the file of the name first, the built-in "null", #include
 * along the include path, and compiled shaders reused across reads of a
 * scene until a file they were compiled from changes.
 */
#include "config.h"
#include "ir.h"
#include "ri.h"
#include "shader_cache.h"
#include "sl.h"
#include "test.h"

#include <stdarg.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[64];
static char diag[1 << 16];
static char names[8][64];      /* the surface shaders of the last frame's primitives */
static int nnames;

static const char *put(const char *name, const char *text)
{
	const char *path = test_fmt("%s/%s", dir, name);
	FILE *f = fopen(path, "w");
	if (!f) {
		fprintf(stderr, "cannot write %s\n", path);
		exit(1);
	}
	fputs(text, f);
	fclose(f);
	return path;
}

static bool on_frame(void *user, const struct reyes_scene *sc)
{
	(void)user;
	nnames = 0;
	for (uint32_t i = 0; i < sc->nprims && nnames < 8; i++) {
		const struct reyes_shader *s = sc->prims[i].attrs->surface;
		snprintf(names[nnames++], sizeof(names[0]), "%s",
			 s ? sl_program_name(s->prog) : "(default)");
	}
	return true;
}

/* Reads @rib (a file in dir) with @cache and @inc; diagnostics in diag[]. */
static bool read_rib(const char *rib, struct reyes_shader_cache *cache, const char *inc)
{
	FILE *d = tmpfile();
	struct reyes_ri_opts o = {
		.diag = d, .frame = on_frame, .shader_cache = cache,
		.default_shader_path = test_fmt("%s/a:%s/b", dir, dir), .default_include_path = inc,
	};
	int nerrors = 0;
	nnames = 0;
	bool ok = reyes_ri_read(test_fmt("%s/%s", dir, rib), &o, &nerrors);
	rewind(d);
	size_t n = fread(diag, 1, sizeof(diag) - 1, d);
	diag[n] = '\0';
	fclose(d);
	return ok;
}

static void test_declared_name(void)
{
	put("a/plastic.sl", "// surface Wrong() in a comment\n"
			    "surface RCPlastic(float Kd = 1) { Ci = Cs * Kd; }\n");
	put("b/zzz.sl", "surface Later() { Ci = Cs; }\n");
	put("b/Both.sl", "surface Both() { Ci = 1; }\n");
	put("a/aaa.sl", "surface Both() { Ci = 0; }\n");
	put("t.rib", "WorldBegin\n"
		     "Surface \"RCPlastic\" \"Kd\" 0.5\nSphere 1 -1 1 360\n"
		     "Surface \"Later\"\nSphere 1 -1 1 360\n"
		     "Surface \"Both\"\nSphere 1 -1 1 360\n"
		     "Surface \"null\"\nSphere 1 -1 1 360\n"
		     "WorldEnd\n");
	CHECK(read_rib("t.rib", NULL, NULL));
	CHECK(nnames == 4);
	CHECK_STR(names[0], "RCPlastic");
	CHECK_STR(names[1], "Later");
	/* Both.sl (in the later folder b) wins over a/aaa.sl, which declares Both too. */
	CHECK_STR(names[2], "Both");
	CHECK_STR(names[3], "null_surface");
	put("u.rib", "WorldBegin\nSurface \"Wrong\"\nSphere 1 -1 1 360\nWorldEnd\n");
	CHECK(!read_rib("u.rib", NULL, NULL));
	CHECK(strstr(diag, "cannot find shader 'Wrong'") != NULL);
	/* The name as the preprocessor leaves it: made by a macro, or not
	   compiled at all inside #if 0. */
	put("a/made.sl", "#define NAME(x) Made##x\n"
			 "#if 0\nsurface Hidden() { Ci = 0; }\n#endif\n"
			 "surface NAME(Here)() { Ci = 1; }\n");
	put("m.rib", "WorldBegin\nSurface \"MadeHere\"\nSphere 1 -1 1 360\nWorldEnd\n");
	CHECK(read_rib("m.rib", NULL, NULL));
	CHECK(nnames == 1);
	CHECK_STR(names[0], "MadeHere");
	put("h.rib", "WorldBegin\nSurface \"Hidden\"\nSphere 1 -1 1 360\nWorldEnd\n");
	CHECK(!read_rib("h.rib", NULL, NULL));
	CHECK(strstr(diag, "cannot find shader 'Hidden'") != NULL);
}

static void test_includes(void)
{
	put("a/inc.sl", "#include \"k.h\"\nsurface inc() { Ci = K; }\n");
	put("h/k.h", "#define K 1\n");
	put("v.rib", "WorldBegin\nSurface \"inc\"\nSphere 1 -1 1 360\nWorldEnd\n");
	CHECK(!read_rib("v.rib", NULL, NULL));
	CHECK(strstr(diag, "cannot find include file 'k.h'") != NULL);
	CHECK(read_rib("v.rib", NULL, test_fmt("%s/h", dir)));
	CHECK_STR(names[0], "inc");
	put("w.rib", test_fmt("Option \"searchpath\" \"include\" [\"%s/none:%s/h\"]\n"
			 "WorldBegin\nSurface \"inc\"\nSphere 1 -1 1 360\nWorldEnd\n", dir, dir));
	CHECK(read_rib("w.rib", NULL, NULL));
}

static void test_cache(void)
{
	struct reyes_shader_cache *c = reyes_shader_cache_create();
	uint64_t compiled, reused;
	/* Two reads of four shaders (null's file included): each compiled once. */
	CHECK(read_rib("t.rib", c, NULL));
	CHECK(read_rib("t.rib", c, NULL));
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 4);
	CHECK(reused == 4);
	/* An include's change is seen: compiled again, and the new text used. */
	CHECK(read_rib("v.rib", c, test_fmt("%s/h", dir)));
	CHECK(read_rib("v.rib", c, test_fmt("%s/h", dir)));
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 5 && reused == 5);
	put("h/k.h", "#define K ((\n");
	CHECK(!read_rib("v.rib", c, test_fmt("%s/h", dir)));
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 6 && reused == 5);
	put("h/k.h", "#define K 0.5\n");
	CHECK(read_rib("v.rib", c, test_fmt("%s/h", dir)));
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 7 && reused == 5);
	/* Another include path is another compilation. */
	put("h2/k.h", "#define K 0.25\n");
	CHECK(read_rib("v.rib", c, test_fmt("%s/h2", dir)));
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 8 && reused == 5);
	/* A warning of the compilation is repeated when the program is reused. */
	put("a/warn.sl", "#include \"k.h\" extra\nsurface warn() { Ci = K; }\n");
	put("x.rib", "WorldBegin\nSurface \"warn\"\nSphere 1 -1 1 360\nWorldEnd\n");
	CHECK(read_rib("x.rib", c, test_fmt("%s/h", dir)));
	CHECK(strstr(diag, "warning: extra tokens") != NULL);
	CHECK(read_rib("x.rib", c, test_fmt("%s/h", dir)));
	CHECK(strstr(diag, "warning: extra tokens") != NULL);
	reyes_shader_cache_counts(c, &compiled, &reused);
	CHECK(compiled == 9 && reused == 6);
	reyes_shader_cache_destroy(c);
	reyes_shader_cache_destroy(NULL);
}

int main(void)
{
	snprintf(dir, sizeof(dir), "/tmp/test_shader_lookup.XXXXXX");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	mkdir(test_fmt("%s/a", dir), 0755);
	mkdir(test_fmt("%s/b", dir), 0755);
	mkdir(test_fmt("%s/h", dir), 0755);
	mkdir(test_fmt("%s/h2", dir), 0755);
	RUN(test_declared_name);
	RUN(test_includes);
	RUN(test_cache);
	int rc = test_finish();
	if (system(test_fmt("rm -rf '%s'", dir)) != 0)
		fprintf(stderr, "cannot remove %s\n", dir);
	return rc;
}

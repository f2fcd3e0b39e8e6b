/*
 * Tests for the RIB reader: every request of the table with its values,
 * parameter lists, strings, comments, line numbers, gzip input, every kind of
 * error with its exact message and the recovery after it, limits, and
 * garbage input.
 */
#include "rib.h"

#include "strbuf.h"
#include "test.h"

#include <stdint.h>
#include <unistd.h>
#include <zlib.h>

/* ---- a handler that writes each request as one line of text ---------------- */

struct capture {
	struct rl_strbuf out;
	int count;
	int malformed;         /* primitives dropped for their arguments' errors */
	int stop_at;           /* return false at this request (1-based); 0: never */
	char first_file[256];  /* loc.file of the first request */
};

static void put_value(struct rl_strbuf *b, const struct rib_value *v)
{
	switch (v->type) {
	case RIB_NUMBER:
		rl_strbuf_printf(b, "%g", v->nums[0]);
		break;
	case RIB_STRING:
		rl_strbuf_printf(b, "\"%s\"", v->strs[0]);
		break;
	case RIB_NUMBERS:
		rl_strbuf_putc(b, '[');
		for (uint32_t i = 0; i < v->n; i++)
			rl_strbuf_printf(b, i ? " %g" : "%g", v->nums[i]);
		rl_strbuf_putc(b, ']');
		break;
	case RIB_STRINGS:
		rl_strbuf_putc(b, '[');
		for (uint32_t i = 0; i < v->n; i++)
			rl_strbuf_printf(b, i ? " \"%s\"" : "\"%s\"", v->strs[i]);
		rl_strbuf_putc(b, ']');
		break;
	}
}

static bool capture_fn(void *user, const struct rib_request *req)
{
	struct capture *c = user;
	if (req->known == RIB_MALFORMED) {
		c->malformed++;  /* a primitive the reader dropped: see test_unhandled */
		return true;
	}
	c->count++;
	if (c->count == 1)
		snprintf(c->first_file, sizeof(c->first_file), "%s", req->loc.file);
	rl_strbuf_printf(&c->out, "%s@%u", req->name, (unsigned)req->loc.line);
	for (uint32_t i = 0; i < req->nargs; i++) {
		rl_strbuf_putc(&c->out, ' ');
		put_value(&c->out, &req->args[i]);
	}
	for (uint32_t i = 0; i < req->nparams; i++) {
		rl_strbuf_printf(&c->out, " \"%s\"=", req->params[i].token);
		put_value(&c->out, &req->params[i].value);
	}
	rl_strbuf_putc(&c->out, '\n');
	return c->stop_at == 0 || c->count < c->stop_at;
}

/* The result of one read: the requests as text, the diagnostics, the counts. */
struct run {
	char out[16384];
	char diag[8192];
	int nerrors;
	int count;
	int malformed;
	bool ok;
};

static struct run *run_opts(const char *text, size_t len, const struct rib_reader_opts *o,
			    int stop_at)
{
	static struct run run;
	memset(&run, 0, sizeof(run));
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	struct rib_reader_opts opts = o ? *o : (struct rib_reader_opts){0};
	opts.diag = diag;
	struct capture c = {.stop_at = stop_at};
	run.nerrors = -1;
	run.ok = rib_read_buffer("t.rib", text, len, &opts, capture_fn, &c, &run.nerrors);
	fclose(diag);
	snprintf(run.out, sizeof(run.out), "%s", rl_strbuf_str(&c.out));
	snprintf(run.diag, sizeof(run.diag), "%s", dbuf ? dbuf : "");
	run.count = c.count;
	run.malformed = c.malformed;
	free(dbuf);
	rl_strbuf_finish(&c.out);
	return &run;
}

static struct run *run_text(const char *text)
{
	return run_opts(text, strlen(text), NULL, 0);
}

/* ---- every request of the table -------------------------------------------- */

static const char all_requests_rib[] =
	"version 3.04\n"
	"FrameBegin 1\n"
	"Format 640 480 1\n"
	"FrameAspectRatio 1.333\n"
	"ScreenWindow -1 1 -0.75 0.75\n"
	"CropWindow 0 1 0 0.5\n"
	"Projection \"perspective\" \"fov\" 45\n"
	"Clipping 0.1 1000\n"
	"Shutter 0 1\n"
	"PixelSamples 4 4\n"                                    /* 10 */
	"PixelVariance 0.01\n"
	"PixelFilter \"gaussian\" 2 2\n"
	"Exposure 1 2.2\n"
	"Quantize \"rgba\" 255 0 255 0.5\n"
	"Display \"out.exr\" \"file\" \"rgba\" \"compression\" \"zip\"\n"
	"Hider \"hidden\" \"jitter\" 1\n"
	"Option \"searchpath\" \"shader\" [\"@:.\"]\n"
	"Declare \"Kd\" \"uniform float\"\n"
	"WorldBegin\n"
	"Identity\n"                                             /* 20 */
	"Transform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1]\n"
	"ConcatTransform [2 0 0 0 0 2 0 0 0 0 2 0 1 2 3 1]\n"
	"Translate 1 2 3\n"
	"Rotate 90 0 0 1\n"
	"Scale 1 2 3\n"
	"Skew 45 0 1 0 1 0 0\n"
	"CoordinateSystem \"mycs\"\n"
	"CoordSysTransform \"mycs\"\n"
	"LightSource \"pointlight\" 1 \"from\" [0 5 0] \"intensity\" 10\n"
	"LightSource \"spotlight\" \"key\"\n"                    /* 30 */
	"Illuminate 1 0\n"
	"Illuminate \"key\" 1\n"
	"AttributeBegin\n"
	"Attribute \"identifier\" \"name\" [\"ball\"]\n"
	"Color 1 0.5 0.25\n"
	"Opacity [1 1 1]\n"
	"Surface \"plastic\" \"Kd\" 0.8 \"specularcolor\" [1 1 1]\n"
	"Displacement \"bumpy\" \"Km\" 0.1\n"
	"Sides 2\n"
	"Orientation \"rh\"\n"                                   /* 40 */
	"ReverseOrientation\n"
	"ShadingRate 0.5\n"
	"ShadingInterpolation \"smooth\"\n"
	"Basis \"bezier\" 3 [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] 1\n"
	"TransformBegin\n"
	"MotionBegin [0 0.5 1]\n"
	"Translate 0 0 0\n"
	"MotionEnd\n"
	"TransformEnd\n"
	"Sphere 1 -1 1 360\n"                                    /* 50 */
	"Cylinder 1 0 2 180\n"
	"Cone 2 1 360\n"
	"Disk 0 1 360\n"
	"Hyperboloid 1 0 0 1 1 2 360\n"
	"Paraboloid 1 0 2 360\n"
	"Torus 1 0.25 0 360 360\n"
	"Polygon \"P\" [0 0 0 1 0 0 1 1 0]\n"
	"GeneralPolygon [3 3] \"P\" [0 0 0 1 0 0 1 1 0 .1 .1 0 .5 .1 0 .5 .5 0]\n"
	"PointsPolygons [3 3] [0 1 2 0 2 3] \"P\" [0 0 0 1 0 0 1 1 0 0 1 0]\n"
	"PointsGeneralPolygons [1 2] [3 3 3] [0 1 2 0 1 2 3 4 5] \"P\" [0]\n" /* 60 */
	"Patch \"bilinear\" \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
	"PatchMesh \"bicubic\" 4 \"nonperiodic\" 7 \"periodic\" \"Pz\" [1 2]\n"
	"AttributeEnd\n"
	"ObjectBegin 7\n"
	"ObjectEnd\n"
	"ObjectInstance 7\n"
	"ObjectBegin \"obj\"\n"
	"ObjectEnd\n"
	"ObjectInstance \"obj\"\n"
	"ReadArchive \"inc.rib\"\n"                              /* 70 */
	"WorldEnd\n"
	"MakeTexture \"in.tif\" \"out.tx\" \"periodic\" \"clamp\" \"gaussian\" 2 2 \"fov\" 1\n"
	"MakeShadow \"depth.z\" \"shadow.tx\"\n"
	"TextureCoordinates [0 0 2 0 0 2 2 2]\n"
	"Matte 1\n"
	"Detail -1 1 -1 1 0 0\n"
	"Detail [-1 1 -1 1 0 1]\n"
	"DetailRange 0 0 10 20\n"
	"RelativeDetail 0.5\n"
	"GeometricApproximation \"flatness\" 0.5\n"
	"GeometricRepresentation \"primitive\"\n"                /* 81 */
	"FrameEnd\n";

static const char all_requests_out[] =
	"version@1 3.04\n"
	"FrameBegin@2 1\n"
	"Format@3 640 480 1\n"
	"FrameAspectRatio@4 1.333\n"
	"ScreenWindow@5 -1 1 -0.75 0.75\n"
	"CropWindow@6 0 1 0 0.5\n"
	"Projection@7 \"perspective\" \"fov\"=[45]\n"
	"Clipping@8 0.1 1000\n"
	"Shutter@9 0 1\n"
	"PixelSamples@10 4 4\n"
	"PixelVariance@11 0.01\n"
	"PixelFilter@12 \"gaussian\" 2 2\n"
	"Exposure@13 1 2.2\n"
	"Quantize@14 \"rgba\" 255 0 255 0.5\n"
	"Display@15 \"out.exr\" \"file\" \"rgba\" \"compression\"=[\"zip\"]\n"
	"Hider@16 \"hidden\" \"jitter\"=[1]\n"
	"Option@17 \"searchpath\" \"shader\"=[\"@:.\"]\n"
	"Declare@18 \"Kd\" \"uniform float\"\n"
	"WorldBegin@19\n"
	"Identity@20\n"
	"Transform@21 [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1]\n"
	"ConcatTransform@22 [2 0 0 0 0 2 0 0 0 0 2 0 1 2 3 1]\n"
	"Translate@23 1 2 3\n"
	"Rotate@24 90 0 0 1\n"
	"Scale@25 1 2 3\n"
	"Skew@26 45 0 1 0 1 0 0\n"
	"CoordinateSystem@27 \"mycs\"\n"
	"CoordSysTransform@28 \"mycs\"\n"
	"LightSource@29 \"pointlight\" 1 \"from\"=[0 5 0] \"intensity\"=[10]\n"
	"LightSource@30 \"spotlight\" \"key\"\n"
	"Illuminate@31 1 0\n"
	"Illuminate@32 \"key\" 1\n"
	"AttributeBegin@33\n"
	"Attribute@34 \"identifier\" \"name\"=[\"ball\"]\n"
	"Color@35 1 0.5 0.25\n"
	"Opacity@36 1 1 1\n"
	"Surface@37 \"plastic\" \"Kd\"=[0.8] \"specularcolor\"=[1 1 1]\n"
	"Displacement@38 \"bumpy\" \"Km\"=[0.1]\n"
	"Sides@39 2\n"
	"Orientation@40 \"rh\"\n"
	"ReverseOrientation@41\n"
	"ShadingRate@42 0.5\n"
	"ShadingInterpolation@43 \"smooth\"\n"
	"Basis@44 \"bezier\" 3 [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] 1\n"
	"TransformBegin@45\n"
	"MotionBegin@46 [0 0.5 1]\n"
	"Translate@47 0 0 0\n"
	"MotionEnd@48\n"
	"TransformEnd@49\n"
	"Sphere@50 1 -1 1 360\n"
	"Cylinder@51 1 0 2 180\n"
	"Cone@52 2 1 360\n"
	"Disk@53 0 1 360\n"
	"Hyperboloid@54 1 0 0 1 1 2 360\n"
	"Paraboloid@55 1 0 2 360\n"
	"Torus@56 1 0.25 0 360 360\n"
	"Polygon@57 \"P\"=[0 0 0 1 0 0 1 1 0]\n"
	"GeneralPolygon@58 [3 3] \"P\"=[0 0 0 1 0 0 1 1 0 0.1 0.1 0 0.5 0.1 0 0.5 0.5 0]\n"
	"PointsPolygons@59 [3 3] [0 1 2 0 2 3] \"P\"=[0 0 0 1 0 0 1 1 0 0 1 0]\n"
	"PointsGeneralPolygons@60 [1 2] [3 3 3] [0 1 2 0 1 2 3 4 5] \"P\"=[0]\n"
	"Patch@61 \"bilinear\" \"P\"=[0 0 0 1 0 0 0 1 0 1 1 0]\n"
	"PatchMesh@62 \"bicubic\" 4 \"nonperiodic\" 7 \"periodic\" \"Pz\"=[1 2]\n"
	"AttributeEnd@63\n"
	"ObjectBegin@64 7\n"
	"ObjectEnd@65\n"
	"ObjectInstance@66 7\n"
	"ObjectBegin@67 \"obj\"\n"
	"ObjectEnd@68\n"
	"ObjectInstance@69 \"obj\"\n"
	"ReadArchive@70 \"inc.rib\"\n"
	"WorldEnd@71\n"
	"MakeTexture@72 \"in.tif\" \"out.tx\" \"periodic\" \"clamp\" \"gaussian\" 2 2 \"fov\"=[1]\n"
	"MakeShadow@73 \"depth.z\" \"shadow.tx\"\n"
	"TextureCoordinates@74 0 0 2 0 0 2 2 2\n"
	"Matte@75 1\n"
	"Detail@76 -1 1 -1 1 0 0\n"
	"Detail@77 -1 1 -1 1 0 1\n"
	"DetailRange@78 0 0 10 20\n"
	"RelativeDetail@79 0.5\n"
	"GeometricApproximation@80 \"flatness\" 0.5\n"
	"GeometricRepresentation@81 \"primitive\"\n"
	"FrameEnd@82\n";

/* The requests the reader must know: the table, exactly. */
static const char *const table_names[] = {
	"version", "FrameBegin", "FrameEnd", "WorldBegin", "WorldEnd", "AttributeBegin",
	"AttributeEnd", "TransformBegin", "TransformEnd", "Format", "FrameAspectRatio",
	"ScreenWindow", "CropWindow", "Projection", "Clipping", "Shutter", "PixelSamples",
	"PixelVariance", "PixelFilter", "Exposure", "Quantize", "Display", "Hider", "Option",
	"Attribute", "Color", "Opacity", "Surface", "Displacement", "LightSource", "Illuminate",
	"Sides", "Orientation", "ReverseOrientation", "ShadingRate", "ShadingInterpolation",
	"Basis", "Declare", "Identity", "Transform", "ConcatTransform", "Translate", "Rotate",
	"Scale", "Skew", "CoordinateSystem", "CoordSysTransform", "MotionBegin", "MotionEnd",
	"ObjectBegin", "ObjectEnd", "ObjectInstance", "ReadArchive", "MakeTexture", "MakeShadow",
	"Sphere", "Cylinder", "Cone", "Disk", "Hyperboloid", "Paraboloid", "Torus", "Polygon",
	"GeneralPolygon", "PointsPolygons", "PointsGeneralPolygons", "Patch", "PatchMesh",
	"TextureCoordinates", "Matte", "Detail", "DetailRange", "RelativeDetail",
	"GeometricApproximation", "GeometricRepresentation",
};

static void test_all_requests(void)
{
	struct run *r = run_text(all_requests_rib);
	CHECK(r->ok);
	CHECK(r->nerrors == 0);
	CHECK_STR(r->diag, "");
	CHECK_STR(r->out, all_requests_out);
	CHECK(r->count == 82);
	/* Each table name is in the input (so parsed above) as a whole word at a line start. */
	for (size_t i = 0; i < sizeof(table_names) / sizeof(table_names[0]); i++) {
		char key[64];
		snprintf(key, sizeof(key), "\n%s@", table_names[i]);
		char out[sizeof(r->out) + 1];
		snprintf(out, sizeof(out), "\n%s", r->out);
		if (!strstr(out, key))
			fprintf(stderr, "request %s not seen\n", table_names[i]);
		CHECK(strstr(out, key) != NULL);
	}
}

/* Types, counts and locations as the handler sees them. */
struct typed_check {
	int calls;
	bool good;
};

static bool typed_fn(void *user, const struct rib_request *req)
{
	struct typed_check *t = user;
	t->calls++;
	bool g = true;
	if (strcmp(req->name, "Surface") == 0) {
		g &= req->nargs == 1 && req->args[0].type == RIB_STRING &&
		     strcmp(rib_str(req, 0), "plastic") == 0 && req->args[0].loc.line == 2;
		g &= req->nparams == 4;
		if (req->nparams == 4) {
			const struct rib_param *p = req->params;
			g &= strcmp(p[0].token, "uniform float Kd") == 0;
			g &= p[0].value.type == RIB_NUMBERS && p[0].value.n == 1 &&
			     p[0].value.nums[0] == 0.5 && p[0].loc.line == 2;
			g &= p[1].value.type == RIB_STRINGS && p[1].value.n == 1 &&
			     strcmp(p[1].value.strs[0], "tex.tx") == 0 && p[1].loc.line == 3;
			g &= p[2].value.type == RIB_NUMBERS && p[2].value.n == 3 &&
			     p[2].value.nums[2] == -3e-2 && p[2].value.loc.line == 4 &&
			     p[2].loc.line == 4;
			g &= p[3].value.type == RIB_STRINGS && p[3].value.n == 2 &&
			     strcmp(p[3].value.strs[1], "b") == 0 && p[3].value.loc.line == 5 &&
			     p[3].loc.line == 5;
		}
	} else if (strcmp(req->name, "Sphere") == 0) {
		g &= req->nargs == 4 && req->args[0].type == RIB_NUMBER &&
		     rib_num(req, 0) == 1.5 && rib_num(req, 1) == -1e3 && rib_num(req, 2) == 250 &&
		     rib_num(req, 3) == 0.125 && req->nparams == 1 && req->params[0].value.n == 0 &&
		     req->params[0].value.type == RIB_NUMBERS;
		g &= req->loc.line == 7 && req->args[3].loc.line == 8;
	} else {
		g = false;
	}
	t->good &= g;
	return true;
}

static void test_params_and_types(void)
{
	const char *text =
		"# typed values\n"
		"Surface \"plastic\" \"uniform float Kd\" .5\n"
		"  \"texname\" \"tex.tx\"\n"
		"  \"v\" [1 +2 -3e-2]\n"
		"  \"names\" [\"a\"\n"
		"\"b\"]\n"
		"Sphere 1.5 -1E3 2.5e+2\n"
		"  0.125 \"empty\" []\n";
	struct typed_check t = {.good = true};
	int nerr = -1;
	CHECK(rib_read_buffer("t.rib", text, strlen(text), NULL, typed_fn, &t, &nerr));
	CHECK(nerr == 0);
	CHECK(t.calls == 2);
	CHECK(t.good);
}

static void test_strings(void)
{
	struct run *r = run_text("Surface \"a\\tb\\\\c\\\"d\\101\\60\\0609\\nx\\\ny\" \"k\" \"\"\n"
				 "Option \"o\" \"s\" [\"\" \"x y\" \"#not a comment\" \"[\"]\n");
	CHECK(r->ok);
	CHECK_STR(r->out, "Surface@1 \"a\tb\\c\"dA009\nxy\" \"k\"=[\"\"]\n"
			  "Option@3 \"o\" \"s\"=[\"\" \"x y\" \"#not a comment\" \"[\"]\n");
}

/*
 * A string may hold newlines, as prman reads it (a long path or Display name
 * broken over lines): they are part of the string, and the requests after it
 * keep their own line numbers, as do errors after it.
 */
static void test_strings_over_lines(void)
{
	struct run *r = run_text("Display \"long/path/\nto/image.exr\" \"file\" \"rgba\"\n"
				 "Surface \"s\" \"string map\" [\"a\n\nb\" \"c\"]\n"
				 "Option \"searchpath\" \"shader\" \"x:\r\n@\"\n"
				 "WorldBegin\n");
	CHECK(r->ok);
	CHECK_STR(r->diag, "");
	CHECK_STR(r->out, "Display@1 \"long/path/\nto/image.exr\" \"file\" \"rgba\"\n"
			  "Surface@3 \"s\" \"string map\"=[\"a\n\nb\" \"c\"]\n"
			  "Option@6 \"searchpath\" \"shader\"=[\"x:\r\n@\"]\n"
			  "WorldBegin@8\n");
	/* an error after such a string names its own line */
	r = run_text("Attribute \"identifier\" \"name\" \"one\ntwo\nthree\"\n"
		     "Sphere 1 2\nWorldEnd\n");
	CHECK(!r->ok);
	CHECK_STR(r->diag,
		  "t.rib:4: error: Sphere expects 4 numbers before its parameter list, got 2\n");
	CHECK_STR(r->out, "Attribute@1 \"identifier\" \"name\"=[\"one\ntwo\nthree\"]\n"
			  "WorldEnd@5\n");
}

static void test_comments_and_lines(void)
{
	const char *text =
		"##RenderMan RIB\n"
		"# a comment with \"quotes\" and [brackets] and WorldBegin\n"
		"version 3.03 # trailing comment\n"
		"\n"
		"Display \"x.exr\"\n"
		"        \"file\"\r\n"
		"        \"rgb\"#no space before the comment\n"
		"Translate\n"
		"1\n"
		"2 3 WorldBegin Sphere 1 -1 1 360 \"Kd\"\t[\n"
		"0.5\n"
		"]\n"
		"\n"
		"# the end";
	struct run *r = run_text(text);
	CHECK(r->ok);
	CHECK_STR(r->diag, "");
	CHECK_STR(r->out, "version@3 3.03\n"
			  "Display@5 \"x.exr\" \"file\" \"rgb\"\n"
			  "Translate@8 1 2 3\n"
			  "WorldBegin@10\n"
			  "Sphere@10 1 -1 1 360 \"Kd\"=[0.5]\n");
	/* Nothing but comments and blanks. */
	r = run_text("# only\n\n  ## comments\n");
	CHECK(r->ok && r->count == 0 && r->nerrors == 0);
	r = run_opts("", 0, NULL, 0);
	CHECK(r->ok && r->count == 0 && r->nerrors == 0);
	r = run_opts(NULL, 0, NULL, 0);
	CHECK(r->ok && r->count == 0);
}

static void test_bracket_forms(void)
{
	struct run *r = run_text("Color [0.1 0.2 0.3]\nSkew [30 1 0 0 0 1 0]\n"
				 "Basis [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] 1 \"catmull-rom\" 2\n");
	CHECK(r->ok);
	CHECK_STR(r->out, "Color@1 0.1 0.2 0.3\nSkew@2 30 1 0 0 0 1 0\n"
			  "Basis@3 [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] 1 \"catmull-rom\" 2\n");
}

/* ---- errors ------------------------------------------------------------------ */

struct error_case {
	const char *text;
	const char *diag;  /* exact diagnostics */
	const char *out;   /* the requests that got through */
};

static const struct error_case error_cases[] = {
	{"Foo 1 2 \"x\\qy\"\nWorldBegin\n",
	 "t.rib:1: error: unknown escape '\\q' in string\n", "WorldBegin@2\n"},
	{"Sphere 1 2\nWorldEnd\n",
	 "t.rib:1: error: Sphere expects 4 numbers before its parameter list, got 2\n",
	 "WorldEnd@2\n"},
	{"Sphere [1 -1 1 360]\nWorldEnd\n",
	 "t.rib:1: error: Sphere expects 4 numbers before its parameter list, got an array\n",
	 "WorldEnd@2\n"},
	{"Translate 1 2 3 4\nShadingRate\nScale 1 1 1\n",
	 "t.rib:1: error: Translate expects 3 numbers, got 4\n"
	 "t.rib:2: error: ShadingRate expects 1 number, got 0\n",
	 "Scale@3 1 1 1\n"},
	{"Surface \"plastic\" \"Kd\"\nWorldEnd\n",
	 "t.rib:1: error: parameter 'Kd' has no value\n", "WorldEnd@2\n"},
	{"Surface \"plastic\" \"Kd\" 1 \"Ks\" ]\nWorldEnd\n",
	 "t.rib:1: error: parameter 'Ks' has no value\n", "WorldEnd@2\n"},
	{"Surface \"plastic\" 1\nWorldEnd\n",
	 "t.rib:1: error: expected a parameter name (a string) in Surface's parameter list, "
	 "got number 1\n",
	 "WorldEnd@2\n"},
	/* A string may span lines: a forgotten quote runs to the end of the file. */
	{"Surface \"plastic\nWorldEnd\n",
	 "t.rib:1: error: unterminated string: it runs from here over 2 lines to the end of the "
	 "file\n", ""},
	{"Surface \"a\\qb\" \"Kd\" 1\nWorldEnd\n",
	 "t.rib:1: error: unknown escape '\\q' in string\n", "WorldEnd@2\n"},
	{"Sphere 1e999 1 1 1\nSphere 1 1 1 -3.5e38\nWorldEnd\n",
	 "t.rib:1: error: number out of range: 1e999\n"
	 "t.rib:2: error: number out of range: -3.5e38\n",
	 "WorldEnd@3\n"},
	{"Sphere nan 1 1 1\nSphere 1 1 1 -Inf\nSurface \"s\" \"Kd\" [1 INFINITY]\n"
	 "Translate 1e-400 -0 +.5\n",
	 "t.rib:1: error: 'nan' is not a finite number\n"
	 "t.rib:2: error: '-Inf' is not a finite number\n"
	 "t.rib:3: error: 'INFINITY' is not a finite number\n",
	 "Translate@4 0 -0 0.5\n"},
	{"Scale 1.2.3 1 1\nScale 1e 1 1\nScale - 1 1\nWorldEnd\n",
	 "t.rib:1: error: malformed number '1.2.3'\n"
	 "t.rib:2: error: malformed number '1e'\n"
	 "t.rib:3: error: malformed number '-'\n",
	 "WorldEnd@4\n"},
	{"Polygon \"P\" [1 \"a\"]\nPolygon \"P\" [[1]]\nWorldEnd\n",
	 "t.rib:1: error: array mixes numbers and strings (string \"a\")\n"
	 "t.rib:2: error: arrays cannot be nested\n",
	 "WorldEnd@3\n"},
	{"Polygon \"P\" [1 2\nWorldEnd\n",
	 "t.rib:2: error: unexpected 'WorldEnd' inside an array (missing ']'?)\n",
	 "WorldEnd@2\n"},
	{"FrameBegin 1.5\nFormat 640.5 480 1\nSides 2\n",
	 "t.rib:1: error: FrameBegin expects an integer for 'frame', got 1.5\n"
	 "t.rib:2: error: Format expects an integer for 'xresolution', got 640.5\n",
	 "Sides@3 2\n"},
	{"PointsPolygons [3 3.5] [0 1 2 0 2 3] \"P\" [0]\nFrameBegin 3e9\nWorldEnd\n",
	 "t.rib:1: error: PointsPolygons expects integers in 'nvertices', got 3.5 (element 1)\n"
	 "t.rib:2: error: FrameBegin expects an integer for 'frame', got 3e+09\n",
	 "WorldEnd@3\n"},
	{"Display \"x\" \"file\"\nWorldBegin\n",
	 "t.rib:1: error: Display is missing its 'mode' argument (a string)\n",
	 "WorldBegin@2\n"},
	{"Display \"x\" \"file\" 3\nWorldBegin\n",
	 "t.rib:1: error: Display expects a string for 'mode', got number 3\n",
	 "WorldBegin@2\n"},
	{"Transform [1 2 3]\nConcatTransform 1 0 0 0\nMotionBegin [\"a\"]\nWorldBegin\n",
	 "t.rib:1: error: Transform expects 16 numbers for 'matrix', got 3\n"
	 "t.rib:2: error: ConcatTransform expects an array of 16 numbers for 'matrix', "
	 "got number 1\n"
	 "t.rib:3: error: MotionBegin expects an array of numbers for 'times', "
	 "got an array of strings\n",
	 "WorldBegin@4\n"},
	{"Color [1 2]\nOpacity 1 1\nColor [\"r\" \"g\" \"b\"]\nWorldBegin\n",
	 "t.rib:1: error: Color expects 3 numbers, got an array of 2 numbers\n"
	 "t.rib:2: error: Opacity expects 3 numbers, got 2\n"
	 "t.rib:3: error: Color expects 3 numbers, got an array of 3 strings\n",
	 "WorldBegin@4\n"},
	{"Basis [1 2] 3 \"bezier\" 3\nBasis \"bezier\" 3 \"bezier\"\nWorldEnd\n",
	 "t.rib:1: error: Basis expects 16 numbers for 'ubasis', got 2\n"
	 "t.rib:2: error: Basis is missing its 'vstep' argument (an integer)\n",
	 "WorldEnd@3\n"},
	{"LightSource \"spotlight\" 1.5\nIlluminate [1] 1\nLightSource \"l\"\nWorldEnd\n",
	 "t.rib:1: error: LightSource expects an integer or a string for 'light', got 1.5\n"
	 "t.rib:2: error: Illuminate expects an integer or a string for 'light', got '['\n"
	 "t.rib:3: error: LightSource is missing its 'light' argument (an integer or a string)\n",
	 "WorldEnd@4\n"},
	{"WorldBegin 1\nAttributeBegin \"x\"\nAttributeEnd\n",
	 "t.rib:1: error: unexpected number 1 after the arguments of WorldBegin\n"
	 "t.rib:2: error: unexpected string \"x\" after the arguments of AttributeBegin\n",
	 "WorldBegin@1\nAttributeBegin@2\nAttributeEnd@3\n"},
	{"1 2 3\n\"Surface\" [ ]\nWorldBegin\n]\nWorldEnd\n",
	 "t.rib:1: error: expected a request name, got number 1\n"
	 "t.rib:4: error: unexpected ']' after the arguments of WorldBegin\n",
	 "WorldBegin@3\nWorldEnd@5\n"},
	{"WorldBegin\n@ { }\nWorldEnd\n",
	 "t.rib:2: error: unexpected '@'\n", "WorldBegin@1\nWorldEnd@3\n"},
	{"WorldBegin\n\x80\x01\nWorldEnd\x7f\n",
	 "t.rib:2: error: unexpected byte 0x80 (binary RIB is not supported)\n"
	 "t.rib:3: error: unexpected control character 0x7f\n",
	 "WorldBegin@1\nWorldEnd@3\n"},
	/* Errors in tokens skipped after an error are not reported again. */
	{"Sphere 1 2 @ \"x\\q\" $ 1e999\nWorldEnd\n",
	 "t.rib:1: error: unexpected '@'\n", "WorldEnd@2\n"},
	/* A bad token after a complete request leaves the request standing... */
	{"Translate 1 2 3 %\nWorldEnd\n",
	 "t.rib:1: error: unexpected '%'\n", "Translate@1 1 2 3\nWorldEnd@2\n"},
	/* ...unless it could be part of a parameter list. */
	{"Sphere 1 -1 1 360 %\nWorldEnd\n",
	 "t.rib:1: error: unexpected '%'\n", "WorldEnd@2\n"},
	{"Surface \"plastic\" \"Kd\" [0.5",
	 "t.rib:1: error: truncated file (inside an array)\n", ""},
	{"WorldBegin\nPolygon \"P\" [0 0 0\n1 1 1\n",
	 "t.rib:2: error: truncated file (inside an array)\n", "WorldBegin@1\n"},
	{"WorldBegin\nSurface \"plas",
	 "t.rib:2: error: truncated file (inside a string)\n", "WorldBegin@1\n"},
	{"Surface \"plas\\",
	 "t.rib:1: error: truncated file (inside a string)\n", ""},
};

static void test_errors(void)
{
	for (size_t i = 0; i < sizeof(error_cases) / sizeof(error_cases[0]); i++) {
		const struct error_case *e = &error_cases[i];
		struct run *r = run_text(e->text);
		int lines = 0;
		for (const char *p = e->diag; *p; p++)
			lines += *p == '\n';
		if (strcmp(r->diag, e->diag) != 0 || strcmp(r->out, e->out) != 0)
			fprintf(stderr, "error case %zu: %s\n", i, e->text);
		CHECK_STR(r->diag, e->diag);
		CHECK_STR(r->out, e->out);
		CHECK(!r->ok);
		CHECK(r->nerrors == lines);
	}
}

/*
 * Requests the table lacks go to the handler by name, without arguments,
 * marked unsupported (a RenderMan request relight does not implement) or
 * unknown (with the closest known name): the reader reports nothing.
 */
static bool unhandled_fn(void *user, const struct rib_request *req)
{
	struct rl_strbuf *b = user;
	static const char *const kinds[] = {"known", "unsupported", "unknown", "malformed"};
	rl_strbuf_printf(b, "%s@%u %s %u %u %s\n", req->name, (unsigned)req->loc.line,
			 kinds[req->known], req->nargs, req->nparams, req->near ? req->near : "-");
	return true;
}

static void test_unhandled(void)
{
	static const char text[] =
		"Foo 1 2 \"x\" [3]\nWorldBegin\n"
		"WorldBgin\nworldend \"a\" [\"b\" 1]\nVersion 3\n"
		"Deformation \"twist\" \"angle\" [0 0 0 1]\nWorldEnd\n"
		"MakeBump \"teapot\" \"background\" [0 0 0]\n";
	struct rl_strbuf b = {0};
	int nerr = -1;
	CHECK(rib_read_buffer("t.rib", text, strlen(text), NULL, unhandled_fn, &b, &nerr));
	CHECK(nerr == 0);
	CHECK_STR(rl_strbuf_str(&b), "Foo@1 unknown 0 0 -\n"
				     "WorldBegin@2 known 0 0 -\n"
				     "WorldBgin@3 unknown 0 0 WorldBegin\n"
				     "worldend@4 unknown 0 0 WorldEnd\n"
				     "Version@5 unknown 0 0 version\n"
				     "Deformation@6 unsupported 0 0 -\n"
				     "WorldEnd@7 known 0 0 -\n"
				     "MakeBump@8 unsupported 0 0 -\n");
	rl_strbuf_finish(&b);

	/* A primitive whose arguments are wrong goes by name, marked malformed,
	   after its error; such errors do not end the read. */
	struct rl_strbuf m = {0};
	for (int i = 0; i < 30; i++)
		rl_strbuf_printf(&m, "Sphere 1 -1\n");
	rl_strbuf_printf(&m, "Polygon \"P\" [0 0 0\nWorldEnd\n");
	FILE *devnull = fopen("/dev/null", "w");
	struct rib_reader_opts mo = {.diag = devnull, .max_errors = 5};
	CHECK(!rib_read_buffer("m.rib", rl_strbuf_str(&m), m.len, &mo, unhandled_fn, &b, &nerr));
	if (devnull)
		fclose(devnull);
	CHECK(nerr == 31);
	const char *got = rl_strbuf_str(&b);
	CHECK(strncmp(got, "Sphere@1 malformed 0 0 -\nSphere@2 malformed 0 0 -\n", 50) == 0);
	CHECK(strstr(got, "Sphere@30 malformed 0 0 -\nPolygon@31 malformed 0 0 -\n"
			  "WorldEnd@32 known 0 0 -\n") != NULL);
	rl_strbuf_finish(&m);
	rl_strbuf_finish(&b);
	/* A lexical error in their arguments is still an error. */
	struct run *r = run_text("MakeBump \"bg\" [1 nan 1]\nWorldBegin\n");
	CHECK(!r->ok);
	CHECK_STR(r->diag, "t.rib:1: error: 'nan' is not a finite number\n");
	CHECK_STR(r->out, "WorldBegin@2\n");
}

#define TRANSLATE_1 "Translate expects 3 numbers, got 1"

static void test_max_errors(void)
{
	char text[4096] = "";
	for (int i = 0; i < 30; i++)
		strcat(text, "Translate 1\n");
	strcat(text, "WorldBegin\n");
	struct rib_reader_opts o = {.max_errors = 3};
	struct run *r = run_opts(text, strlen(text), &o, 0);
	CHECK(!r->ok);
	CHECK(r->nerrors == 3);
	CHECK_STR(r->diag, "t.rib:1: error: " TRANSLATE_1 "\n"
			   "t.rib:2: error: " TRANSLATE_1 "\n"
			   "t.rib:3: error: " TRANSLATE_1 "\n"
			   "t.rib: note: too many errors, stopping\n");
	CHECK(r->count == 0);
	/* The default is 20. (Errors in primitives, which drop them alone, do not
	   count: test_unhandled.) */
	r = run_text(text);
	CHECK(r->nerrors == 20);
	CHECK(r->count == 0);
}

static void test_handler_stops(void)
{
	const char *text = "WorldBegin\nSphere 1 -1 1 360\nWorldEnd\nBogus\n";
	struct run *r = run_opts(text, strlen(text), NULL, 2);
	CHECK(!r->ok);
	CHECK(r->nerrors == 0);
	CHECK(r->count == 2);
	CHECK_STR(r->out, "WorldBegin@1\nSphere@2 1 -1 1 360\n");
	CHECK_STR(r->diag, "");
	/* Without a handler the reader only checks. */
	int nerr = -1;
	CHECK(rib_read_buffer("t.rib", text, strlen(text) - 6, NULL, NULL, NULL, &nerr));
	CHECK(nerr == 0);
}

static void test_max_array(void)
{
	struct rib_reader_opts o = {.max_array = 4};
	const char *text = "Polygon \"P\" [1 2 3 4]\nPolygon \"P\" [1 2 3 4 5]\n"
			   "Option \"o\" \"s\" [\"a\" \"b\" \"c\" \"d\" \"e\"]\nWorldBegin\n";
	struct run *r = run_opts(text, strlen(text), &o, 0);
	CHECK_STR(r->diag, "t.rib:2: error: array too long (more than 4 elements)\n"
			   "t.rib:3: error: array too long (more than 4 elements)\n");
	CHECK_STR(r->out, "Polygon@1 \"P\"=[1 2 3 4]\nWorldBegin@4\n");
	CHECK(r->nerrors == 2);

	/* A request's values together may be 4 x max_array (strings count too). */
	text = "Polygon \"P\" [1 2 3 4] \"N\" [1 2 3 4] \"Cs\" [1 2 3] \"s\" 1\n"
	       "Polygon \"P\" [1 2 3 4] \"N\" [1 2 3 4] \"Cs\" [1 2 3] \"s\" [1 2]\nWorldEnd\n";
	r = run_opts(text, strlen(text), &o, 0);
	CHECK_STR(r->diag, "t.rib:2: error: request holds more than 16 values\n");
	CHECK_STR(r->out, "Polygon@1 \"P\"=[1 2 3 4] \"N\"=[1 2 3 4] \"Cs\"=[1 2 3] \"s\"=[1]\n"
			  "WorldEnd@3\n");

}

static bool sum_fn(void *user, const struct rib_request *req)
{
	double *sum = user;
	if (req->nparams == 1 && req->params[0].value.type == RIB_NUMBERS) {
		for (uint32_t i = 0; i < req->params[0].value.n; i++)
			sum[0] += req->params[0].value.nums[i];
		sum[1] += req->params[0].value.n;
	}
	return true;
}

static void test_large_array(void)
{
	struct rl_strbuf b = {0};
	rl_strbuf_puts(&b, "Polygon \"P\" [");
	const int n = 300000;
	double expect = 0;
	for (int i = 0; i < n; i++) {
		rl_strbuf_printf(&b, "%d.25 ", i % 1000);
		expect += i % 1000 + 0.25;
	}
	rl_strbuf_puts(&b, "]\nPolygon \"P\" [1]\n");
	double sum[2] = {0, 0};
	int nerr = -1;
	CHECK(rib_read_buffer("big.rib", b.data, b.len, NULL, sum_fn, sum, &nerr));
	CHECK(nerr == 0);
	CHECK_NEAR(sum[1], n + 1, 0);
	CHECK_NEAR(sum[0], expect + 1, 1e-6);
	rl_strbuf_finish(&b);
}

/* ---- files and gzip -------------------------------------------------------------- */

static char tmpdir[64];

static void write_file(const char *path, const void *data, size_t len)
{
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (f) {
		CHECK(fwrite(data, 1, len, f) == len);
		fclose(f);
	}
}

static void write_gz(const char *path, const char *text)
{
	gzFile g = gzopen(path, "wb");
	CHECK(g != NULL);
	if (g) {
		CHECK(gzwrite(g, text, (unsigned)strlen(text)) == (int)strlen(text));
		gzclose(g);
	}
}

static size_t read_whole(const char *path, unsigned char *buf, size_t cap)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	size_t n = fread(buf, 1, cap, f);
	fclose(f);
	return n;
}

static struct run *run_file(const char *path)
{
	static struct run run;
	memset(&run, 0, sizeof(run));
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	struct rib_reader_opts opts = {.diag = diag};
	struct capture c = {0};
	run.nerrors = -1;
	run.ok = rib_read_file(path, &opts, capture_fn, &c, &run.nerrors);
	fclose(diag);
	snprintf(run.out, sizeof(run.out), "%s", rl_strbuf_str(&c.out));
	snprintf(run.diag, sizeof(run.diag), "%s", dbuf ? dbuf : "");
	run.count = c.count;
	if (c.count)
		CHECK_STR(c.first_file, path);
	free(dbuf);
	rl_strbuf_finish(&c.out);
	return &run;
}

static void test_files(void)
{
	char path[128], expect[256];
	snprintf(path, sizeof(path), "%s/plain.rib", tmpdir);
	write_file(path, all_requests_rib, strlen(all_requests_rib));
	struct run *r = run_file(path);
	CHECK(r->ok);
	CHECK_STR(r->out, all_requests_out);

	snprintf(path, sizeof(path), "%s/missing.rib", tmpdir);
	r = run_file(path);
	CHECK(!r->ok && r->nerrors == 1);
	snprintf(expect, sizeof(expect), "%s: error: cannot open: No such file or directory\n",
		 path);
	CHECK_STR(r->diag, expect);

	/* A file longer than the reader's 64 KiB window, error on its last line. */
	struct rl_strbuf b = {0};
	for (int i = 0; i < 20000; i++)
		rl_strbuf_puts(&b, "Translate 1 2 3\n");
	rl_strbuf_puts(&b, "Sphere 1\n");
	snprintf(path, sizeof(path), "%s/long.rib", tmpdir);
	write_file(path, b.data, b.len);
	r = run_file(path);
	CHECK(r->count == 20000);
	snprintf(expect, sizeof(expect),
		 "%s:20001: error: Sphere expects 4 numbers before its parameter list, got 1\n",
		 path);
	CHECK_STR(r->diag, expect);

	/* The same file, gzip-compressed. */
	snprintf(path, sizeof(path), "%s/long.rib.gz", tmpdir);
	write_gz(path, b.data);
	r = run_file(path);
	CHECK(r->count == 20000);
	snprintf(expect, sizeof(expect),
		 "%s:20001: error: Sphere expects 4 numbers before its parameter list, got 1\n",
		 path);
	CHECK_STR(r->diag, expect);
	rl_strbuf_finish(&b);
}

/* "FILE:N: error: truncated gzip data\n": returns N, or -1. */
static int check_truncated(const char *diag, const char *file)
{
	size_t fl = strlen(file);
	if (strncmp(diag, file, fl) != 0 || diag[fl] != ':') {
		CHECK_STR(diag, "FILE:N: error: truncated gzip data");
		return -1;
	}
	char *end;
	long line = strtol(diag + fl + 1, &end, 10);
	CHECK_STR(end, ": error: truncated gzip data\n");
	return (int)line;
}

/* 1 + the newlines in what zlib inflates from a damaged or cut gzip stream. */
static int line_reached(const unsigned char *gz, size_t n)
{
	static unsigned char out[1 << 18];
	z_stream zs = {0};
	if (inflateInit2(&zs, 16 + MAX_WBITS) != Z_OK)
		return -1;
	zs.next_in = (unsigned char *)gz;
	zs.avail_in = (unsigned)n;
	zs.next_out = out;
	zs.avail_out = sizeof(out);
	inflate(&zs, Z_NO_FLUSH);
	int line = 1;
	for (size_t i = 0; i < sizeof(out) - zs.avail_out; i++)
		line += out[i] == '\n';
	inflateEnd(&zs);
	return line;
}

static void test_gzip(void)
{
	char path[128];
	snprintf(path, sizeof(path), "%s/scene.rib.gz", tmpdir);
	write_gz(path, all_requests_rib);
	struct run *r = run_file(path);
	CHECK(r->ok);
	CHECK_STR(r->diag, "");
	CHECK_STR(r->out, all_requests_out);

	/* From memory too. */
	static unsigned char gz[65536];
	size_t n = read_whole(path, gz, sizeof(gz));
	CHECK(n > 20 && gz[0] == 0x1f && gz[1] == 0x8b);
	r = run_opts((const char *)gz, n, NULL, 0);
	CHECK(r->ok);
	CHECK_STR(r->out, all_requests_out);

	/* Two gzip members one after the other read as one stream. */
	snprintf(path, sizeof(path), "%s/a.gz", tmpdir);
	write_gz(path, "WorldBegin\nSphere 1 -1 ");
	size_t na = read_whole(path, gz, sizeof(gz));
	write_gz(path, "1 360\nWorldEnd\n");
	size_t nb = read_whole(path, gz + na, sizeof(gz) - na);
	r = run_opts((const char *)gz, na + nb, NULL, 0);
	CHECK(r->ok);
	CHECK_STR(r->out, "WorldBegin@1\nSphere@2 1 -1 1 360\nWorldEnd@3\n");

	/* Truncated: the requests before the cut are read, then one error. */
	struct rl_strbuf b = {0};
	for (int i = 0; i < 5000; i++)
		rl_strbuf_printf(&b, "Translate %d 0 0\n", i);
	snprintf(path, sizeof(path), "%s/cut.rib.gz", tmpdir);
	write_gz(path, b.data);
	static unsigned char big[1 << 17];
	n = read_whole(path, big, sizeof(big));
	CHECK(n > 1000);
	write_file(path, big, n / 2);
	r = run_file(path);
	CHECK(!r->ok);
	CHECK(r->nerrors == 1);
	CHECK(r->count > 100 && r->count < 5000);
	/*
	 * The error is at the line reached. The request being read there is
	 * dropped, and so is the one before it when the cut is inside the next
	 * request's name (it waits for the next token).
	 */
	int line = check_truncated(r->diag, path);
	CHECK(line == line_reached(big, n / 2));
	CHECK(line == r->count + 1 || line == r->count + 2);
	/* The same from memory. */
	r = run_opts((const char *)big, n / 2, NULL, 0);
	CHECK(r->nerrors == 1 && r->count > 100);
	line = check_truncated(r->diag, "t.rib");
	CHECK(line == r->count + 1 || line == r->count + 2);
	/* Cut inside the header: nothing at all. */
	r = run_opts((const char *)big, 5, NULL, 0);
	CHECK_STR(r->diag, "t.rib:1: error: truncated gzip data\n");

	/* A damaged checksum: everything is read, then the error at the last line. */
	memcpy(gz, big, n);
	gz[n - 6] ^= 0x55;
	r = run_opts((const char *)gz, n, NULL, 0);
	CHECK(r->count == 4999);
	CHECK_STR(r->diag, "t.rib:5001: error: corrupt gzip data (incorrect data check)\n");

	/* Damaged compressed data: an error, and no crash, wherever the damage is. */
	int corrupt_errors = 0;
	for (size_t at = 10; at < n - 8; at += n / 37) {
		memcpy(gz, big, n);
		gz[at] ^= 0xa5;
		gz[at + 1] ^= 0x3c;
		r = run_opts((const char *)gz, n, NULL, 0);
		corrupt_errors += r->nerrors > 0;
		CHECK(strstr(r->diag, "error: ") != NULL || r->nerrors == 0);
	}
	CHECK(corrupt_errors > 30);

	/* Garbage after the gzip stream. */
	memcpy(gz, big, n);
	memcpy(gz + n, "WorldEnd", 8);
	r = run_opts((const char *)gz, n + 8, NULL, 0);
	CHECK(r->count == 4999);
	CHECK(strncmp(r->diag, "t.rib:5001: error: corrupt gzip data (", 38) == 0);
	rl_strbuf_finish(&b);
}

/* ---- garbage ------------------------------------------------------------------------ */

static uint64_t rng = 0x9e3779b97f4a7c15u;

static uint32_t next_rand(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (uint32_t)(rng >> 16);
}

static void test_garbage(void)
{
	static const char *const pieces[] = {
		"Sphere", "Polygon", "\"P\"", "[", "]", "1", "-2.5e3", "\"", "\\", "#", "\n", " ",
		"Color", "Basis", "\"bezier\"", "nan", "1e999", "WorldBegin", "\"a\\", "LightSource",
		"PointsPolygons", "Transform", "MakeTexture", "\x1f\x8b", "\x80", "Option", "16",
	};
	static char buf[4096];
	struct rib_reader_opts o = {.max_array = 64};
	for (int iter = 0; iter < 3000; iter++) {
		size_t len = next_rand() % sizeof(buf);
		size_t n = 0;
		bool tokens = iter % 2 == 0;
		while (n < len) {
			if (tokens) {
				const char *p = pieces[next_rand() % (sizeof(pieces) / sizeof(pieces[0]))];
				size_t pl = strlen(p);
				if (n + pl + 1 > len)
					break;
				memcpy(buf + n, p, pl);
				n += pl;
				buf[n++] = next_rand() % 4 ? ' ' : '\n';
			} else {
				buf[n++] = (char)(next_rand() & 0xff);
			}
		}
		struct run *r = run_opts(buf, n, &o, 0);
		/* the errors that dropped a primitive alone do not end the read */
		CHECK(r->nerrors >= 0 && r->nerrors - r->malformed <= 20);
		CHECK(r->ok == (r->nerrors == 0));
	}
	/* A big file of junk ends at max_errors, quickly. */
	size_t big = 8 << 20;
	char *junk = malloc(big);
	CHECK(junk != NULL);
	if (junk) {
		for (size_t i = 0; i < big; i++)
			junk[i] = "x1 ]\001\n"[i % 6];
		int nerr = -1;
		FILE *devnull = fopen("/dev/null", "w");
		struct rib_reader_opts jo = {.diag = devnull, .max_errors = 5};
		CHECK(!rib_read_buffer("junk", junk, big, &jo, NULL, NULL, &nerr));
		CHECK(nerr == 5);
		/* Numbers only: one error, the rest is skipped in linear time. */
		for (size_t i = 0; i < big; i++)
			junk[i] = "12 "[i % 3];
		jo.max_errors = 0;
		CHECK(!rib_read_buffer("junk", junk, big, &jo, NULL, NULL, &nerr));
		CHECK(nerr == 1);
		if (devnull)
			fclose(devnull);
		free(junk);
	}
}

int main(void)
{
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/test_rib_XXXXXX");
	if (!mkdtemp(tmpdir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_all_requests);
	RUN(test_params_and_types);
	RUN(test_strings);
	RUN(test_strings_over_lines);
	RUN(test_comments_and_lines);
	RUN(test_bracket_forms);
	RUN(test_errors);
	RUN(test_unhandled);
	RUN(test_max_errors);
	RUN(test_handler_stops);
	RUN(test_max_array);
	RUN(test_large_array);
	RUN(test_files);
	RUN(test_gzip);
	RUN(test_garbage);
	char cmd[128];
	snprintf(cmd, sizeof(cmd), "rm -rf %s", tmpdir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", tmpdir);
	return test_finish();
}

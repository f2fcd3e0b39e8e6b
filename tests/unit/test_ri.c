/*
 * Tests of the RIB scene builder: RIB snippets written to a temporary
 * directory are read with a frame callback that inspects the scene.
 */
#include "config.h"
#include "ir.h"
#include "mathlib.h"
#include "ri.h"
#include "strbuf.h"
#include "test.h"

#include <stdarg.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[64];
static char rib_path[128];
static char diag[1 << 16];
static int frames;
static void (*inspect)(const struct reyes_scene *sc);

/* Files written, removed at the end. */
static char written[128][160];
static int nwritten;

/* Writes @text to DIR/@name (subdirectories must exist); returns the path. */
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
	bool known = false;
	for (int i = 0; i < nwritten; i++)
		known |= strcmp(written[i], path) == 0;
	if (!known && nwritten < 128)
		snprintf(written[nwritten++], sizeof(written[0]), "%s", path);
	return path;
}

static bool on_frame(void *user, const struct reyes_scene *sc)
{
	(void)user;
	frames++;
	if (inspect)
		inspect(sc);
	return true;
}

/* Reads @text as DIR/t.rib; diagnostics land in diag[], frames are counted. */
static bool run_opts(const char *text, void (*fn)(const struct reyes_scene *),
		     const struct reyes_ri_opts *base, int *nerrors)
{
	snprintf(rib_path, sizeof(rib_path), "%s", put("t.rib", text));
	FILE *d = tmpfile();
	struct reyes_ri_opts o = base ? *base : (struct reyes_ri_opts){0};
	o.diag = d;
	o.frame = on_frame;
	frames = 0;
	inspect = fn;
	bool ok = reyes_ri_read(rib_path, &o, nerrors);
	rewind(d);
	size_t n = fread(diag, 1, sizeof(diag) - 1, d);
	diag[n] = '\0';
	fclose(d);
	return ok;
}

static bool run(const char *text, void (*fn)(const struct reyes_scene *))
{
	int n;
	return run_opts(text, fn, NULL, &n);
}

#define CHECK_DIAG(s) \
	do { \
		const char *s_ = (s); \
		test_checks++; \
		if (!strstr(diag, s_)) { \
			test_failures++; \
			fprintf(stderr, "%s:%d: [%s] diagnostics lack \"%s\"; they are:\n%s", \
				__FILE__, __LINE__, test_current, s_, diag); \
		} \
	} while (0)

#define CHECK_NO_DIAG() \
	do { \
		test_checks++; \
		if (diag[0]) { \
			test_failures++; \
			fprintf(stderr, "%s:%d: [%s] unexpected diagnostics:\n%s", __FILE__, \
				__LINE__, test_current, diag); \
		} \
	} while (0)

/* Where @m takes the point (x, y, z). */
#define CHECK_XFORM(m, x, y, z, ex, ey, ez) \
	do { \
		float p_[3] = {(x), (y), (z)}, q_[3]; \
		sl_xform_point(q_, (m), p_); \
		CHECK_NEAR(q_[0], (ex), 1e-5); \
		CHECK_NEAR(q_[1], (ey), 1e-5); \
		CHECK_NEAR(q_[2], (ez), 1e-5); \
	} while (0)

static const struct reyes_param_value *param(const struct reyes_shader *sh, const char *name)
{
	for (uint32_t i = 0; sh && i < sh->nparams; i++)
		if (strcmp(sh->params[i].name, name) == 0)
			return &sh->params[i];
	return NULL;
}

static const struct reyes_primvar *var(const struct reyes_prim *p, const char *name)
{
	for (uint32_t i = 0; i < p->nvars; i++)
		if (strcmp(p->vars[i].name, name) == 0)
			return &p->vars[i];
	return NULL;
}

/* ---- options ---- */

static void check_defaults(const struct reyes_scene *sc)
{
	const struct reyes_options *o = &sc->opts;
	CHECK(o->xres == 640 && o->yres == 480);
	CHECK_NEAR(o->pixel_aspect, 1, 0);
	CHECK_NEAR(o->frame_aspect, 640.0 / 480.0, 1e-6);
	CHECK(!o->screen_set);
	CHECK_NEAR(o->screen[0], -640.0 / 480.0, 1e-6);
	CHECK_NEAR(o->screen[1], 640.0 / 480.0, 1e-6);
	CHECK_NEAR(o->screen[2], -1, 0);
	CHECK_NEAR(o->screen[3], 1, 0);
	CHECK(o->crop[0] == 0 && o->crop[1] == 1 && o->crop[2] == 0 && o->crop[3] == 1);
	CHECK(!o->perspective);
	CHECK_NEAR(o->fov, 90, 0);
	CHECK(o->clip_near > 0 && o->clip_near < 1e-6);
	CHECK_NEAR(o->clip_far, 1e30, 1e24);
	CHECK(o->shutter[0] == 0 && o->shutter[1] == 0);
	CHECK(o->xsamples == 2 && o->ysamples == 2);
	CHECK(o->filter == REYES_FILTER_GAUSSIAN);
	CHECK(o->filter_width[0] == 2 && o->filter_width[1] == 2);
	CHECK(o->gain == 1 && o->gamma == 1);
	CHECK(o->ndisplays == 1);
	if (o->ndisplays == 1) {
		CHECK_STR(o->displays[0].name, "ri.exr");
		CHECK_STR(o->displays[0].type, "file");
		CHECK_STR(o->displays[0].mode, "rgba");
		CHECK(o->displays[0].half);
	}
	CHECK(o->depthfilter == REYES_DEPTH_MIN);
	CHECK(o->jitter);
	CHECK_NEAR(o->opacity_threshold, 0.996, 1e-6);
	CHECK_STR(o->shader_path, RELIGHT_SOURCE_SHADER_DIR);
	CHECK_STR(o->texture_path, ".");
	CHECK_STR(o->archive_path, ".");
	float id[16];
	sl_m44_identity(id);
	CHECK(memcmp(o->world_to_camera, id, sizeof(id)) == 0);
	/* Orthographic: x and y pass, near..far map to 0..1. */
	CHECK_XFORM(o->camera_to_screen, 0.5f, -0.25f, 0, 0.5f, -0.25f, 0);
	CHECK(sc->nprims == 0 && sc->nlights == 0 && sc->nspaces == 0);
}

static void test_defaults(void)
{
	CHECK(run("WorldBegin\nWorldEnd\n", check_defaults));
	CHECK(frames == 1);
	CHECK_NO_DIAG();
}

static void check_all_options(const struct reyes_scene *sc)
{
	const struct reyes_options *o = &sc->opts;
	CHECK(o->xres == 320 && o->yres == 200);
	CHECK_NEAR(o->pixel_aspect, 2, 0);
	CHECK_NEAR(o->frame_aspect, 1.5, 1e-6);
	CHECK(o->screen_set);
	CHECK(o->screen[0] == -2 && o->screen[1] == 2 && o->screen[2] == -1 && o->screen[3] == 1);
	CHECK(o->crop[0] == 0.25f && o->crop[1] == 0.75f && o->crop[2] == 0 && o->crop[3] == 0.5f);
	CHECK(o->perspective);
	CHECK_NEAR(o->fov, 45, 0);
	CHECK_NEAR(o->clip_near, 0.1, 1e-7);
	CHECK_NEAR(o->clip_far, 100, 1e-4);
	CHECK(o->shutter[0] == 0 && o->shutter[1] == 1);
	CHECK(o->xsamples == 4 && o->ysamples == 3);
	CHECK(o->filter == REYES_FILTER_BOX);
	CHECK(o->filter_width[0] == 1 && o->filter_width[1] == 1.5f);
	CHECK_NEAR(o->gain, 2, 0);
	CHECK_NEAR(o->gamma, 2.2, 1e-6);
	CHECK(o->depthfilter == REYES_DEPTH_MAX);
	CHECK(!o->jitter);
	CHECK_STR(o->texture_path, "/tmp/tex:.");
	/* Perspective: x/z and y/z scaled by 1/tan(fov/2); z from near..far to 0..1. */
	float d = 1 / tanf(22.5f * 3.14159265f / 180);
	CHECK_XFORM(o->camera_to_screen, 1, 0.5f, 2, d / 2, d / 4, (2 - 0.1f) * 100 / (2 * 99.9f));
	CHECK_XFORM(o->camera_to_screen, 0, 0, 0.1f, 0, 0, 0);
	CHECK_XFORM(o->camera_to_screen, 0, 0, 100, 0, 0, 1);
	/* The camera: the transformation at WorldBegin. */
	CHECK_XFORM(o->world_to_camera, 0, 0, 0, 0, 0, 5);
	CHECK(o->ndisplays == 3);
	if (o->ndisplays != 3)
		return;
	CHECK_STR(o->displays[0].name, "a.exr");
	CHECK(o->displays[0].half);
	CHECK_STR(o->displays[0].mode, "rgba");
	CHECK_STR(o->displays[1].name, "z.exr");
	CHECK_STR(o->displays[1].type, "zfile");
	CHECK_STR(o->displays[1].mode, "z");
	CHECK(!o->displays[1].half);
	CHECK_STR(o->displays[2].name, "d.exr");
	CHECK_STR(o->displays[2].mode, "diffuse");
	CHECK(!o->displays[2].half);
	CHECK(o->displays[2].line == 11);
	CHECK_STR(o->displays[2].file, rib_path);
}

static void check_one_display(const struct reyes_scene *sc)
{
	CHECK(sc->opts.ndisplays == 1);
	CHECK_STR(sc->opts.displays[0].name, "second.exr");
	CHECK_STR(sc->opts.displays[0].mode, "rgb");
	/* Format's aspect ratio with a tall frame: the screen is [-1,1] x [-1/a,1/a]. */
	CHECK_NEAR(sc->opts.frame_aspect, 0.5, 1e-6);
	CHECK_NEAR(sc->opts.screen[0], -1, 0);
	CHECK_NEAR(sc->opts.screen[3], 2, 1e-6);
}

static void check_override(const struct reyes_scene *sc)
{
	CHECK(sc->opts.ndisplays == 2);
	CHECK_STR(sc->opts.displays[0].name, "depth.z");
	CHECK_STR(sc->opts.displays[1].name, "override.exr");
}

static void test_options(void)
{
	CHECK(run("Format 320 200 2\n"
		  "FrameAspectRatio 1.5\n"
		  "ScreenWindow -2 2 -1 1\n"
		  "CropWindow 0.25 0.75 0 0.5\n"
		  "Projection \"perspective\" \"fov\" 45\n"
		  "Clipping 0.1 100\n"
		  "Shutter 0 1\n"
		  "PixelSamples 4 3 PixelFilter \"box\" 1 1.5 Exposure 2 2.2\n"
		  "Display \"a.exr\" \"file\" \"rgba\"\n"
		  "Display \"+z.exr\" \"zfile\" \"z\"\n"
		  "Display \"+d.exr\" \"file\" \"color diffuse\" \"quantize\" [0 0 0 0]\n"
		  "Hider \"hidden\" \"depthfilter\" \"max\" \"int jitter\" 0\n"
		  "Option \"searchpath\" \"texture\" \"/tmp/tex:&\"\n"
		  "Translate 0 0 5\n"
		  "WorldBegin\nWorldEnd\n",
		  check_all_options));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(run("Format 100 200 1\n"
		  "Display \"first.exr\" \"file\" \"rgba\"\n"
		  "Display \"second.exr\" \"file\" \"rgb\"\n"
		  "WorldBegin\nWorldEnd\n",
		  check_one_display));
	CHECK(frames == 1);

	/* Unknown options are warnings. */
	CHECK(run("Option \"limits\" \"bucketsize\" [16 16]\nWorldBegin\nWorldEnd\n", NULL));
	CHECK(frames == 1);
	CHECK_DIAG(test_fmt("%s:1: warning: unknown option 'limits' ignored", rib_path));

	/* Options inside the world are errors, and the frame is not rendered. */
	int n = 0;
	CHECK(!run_opts("WorldBegin\nFormat 10 10 1\nWorldEnd\n", NULL, NULL, &n));
	CHECK(frames == 0);
	CHECK(n == 1);
	CHECK_DIAG(test_fmt("%s:2: error: Format is an option: it must come before WorldBegin",
		       rib_path));

	CHECK(!run("Projection \"fisheye\"\nWorldBegin\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:1: error: unsupported projection 'fisheye'", rib_path));
	CHECK(frames == 0);

	CHECK(!run("PixelFilter \"blurry\" 2 2\nWorldBegin\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:1: error: unknown pixel filter 'blurry'", rib_path));

	/* The output override renames the first image display, not a depth one. */
	struct reyes_ri_opts o = {.output_override = "override.exr"};
	CHECK(run_opts("Display \"depth.z\" \"zfile\" \"z\"\n"
		       "Display \"+img.exr\" \"file\" \"rgba\"\n"
		       "WorldBegin\nWorldEnd\n",
		       check_override, &o, &n));
	CHECK(frames == 1);

	/* Options set inside a frame end with it. */
	CHECK(run("FrameBegin 1\nFormat 20 10 1\nWorldBegin\nWorldEnd\nFrameEnd\n"
		  "WorldBegin\nWorldEnd\n", NULL));
	CHECK(frames == 2);
}

/* ---- transformations ---- */

static void check_translate_rotate(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 7);
	if (sc->nprims != 7)
		return;
	/* Translate 1 0 0, Rotate 90 0 0 1: the rotation applies first. */
	CHECK_XFORM(sc->prims[0].attrs->object_to_world[0], 1, 0, 0, 1, 1, 0);
	/* Scale 2 then Translate: the translation is scaled. */
	CHECK_XFORM(sc->prims[1].attrs->object_to_world[0], 0, 0, 0, 2, 0, 0);
	/* After TransformEnd: back to the world. */
	CHECK_XFORM(sc->prims[2].attrs->object_to_world[0], 3, 4, 5, 3, 4, 5);
	/* Transform replaces, ConcatTransform concatenates. */
	CHECK_XFORM(sc->prims[3].attrs->object_to_world[0], 1, 1, 1, 2, 2, 2);
	CHECK_XFORM(sc->prims[4].attrs->object_to_world[0], 1, 1, 1, 2, 2, 12);
	/* Skew 45 0 1 0 1 0 0: the y axis leans 45 degrees towards x. */
	CHECK_XFORM(sc->prims[5].attrs->object_to_world[0], 0, 1, 0, 1, 1, 0);
	CHECK_XFORM(sc->prims[5].attrs->object_to_world[0], 1, 0, 0, 1, 0, 0);
	/* CoordSysTransform "lamp": the space recorded by CoordinateSystem. */
	CHECK_XFORM(sc->prims[6].attrs->object_to_world[0], 0, 0, 0, 0, 2, 0);
	CHECK(sc->nspaces == 2);
	for (uint32_t i = 0; i < sc->nspaces; i++) {
		if (strcmp(sc->space_names[i], "lamp") == 0)
			CHECK_XFORM(sc->space_to_world[i], 0, 0, 0, 0, 2, 0);
		else if (strcmp(sc->space_names[i], "eye") == 0)
			/* named before WorldBegin in camera space: the camera sits at z = -5 */
			CHECK_XFORM(sc->space_to_world[i], 0, 0, 0, 0, 0, -5);
		else
			CHECK(!"unexpected space");
	}
	for (uint32_t i = 0; i < sc->nprims; i++)
		CHECK(!sc->prims[i].attrs->moving && sc->prims[i].id == i);
}

static void test_transforms(void)
{
	CHECK(run("CoordinateSystem \"eye\"\n"
		  "Translate 0 0 5\n"
		  "WorldBegin\n"
		  "TransformBegin\n"
		  " Translate 1 0 0\n Rotate 90 0 0 1\n Sphere 1 -1 1 360\n"
		  "TransformEnd\n"
		  "TransformBegin\n Scale 2 2 2\n Translate 1 0 0\n Sphere 1 -1 1 360\n"
		  "TransformEnd\n"
		  "Sphere 1 -1 1 360\n"
		  "TransformBegin\n"
		  " Translate 5 5 5\n Transform [2 0 0 0 0 2 0 0 0 0 2 0 0 0 0 1]\n"
		  " Sphere 1 -1 1 360\n"
		  " ConcatTransform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 5 1]\n Sphere 1 -1 1 360\n"
		  "TransformEnd\n"
		  "TransformBegin\n Skew 45 0 1 0 1 0 0\n Sphere 1 -1 1 360\nTransformEnd\n"
		  "AttributeBegin\n Translate 0 2 0\n CoordinateSystem \"lamp\"\nAttributeEnd\n"
		  "CoordSysTransform \"lamp\"\nSphere 1 -1 1 360\n"
		  "WorldEnd\n",
		  check_translate_rotate));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(!run("WorldBegin\nCoordSysTransform \"nowhere\"\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: unknown coordinate system 'nowhere'", rib_path));
}

static void check_flips(const struct reyes_scene *sc)
{
	static const bool want[] = {false, false, true, false, true, true, false};
	CHECK(sc->nprims == 7);
	for (uint32_t i = 0; i < sc->nprims && i < 7; i++) {
		CHECK(sc->prims[i].attrs->flip_normals == want[i]);
		if (sc->prims[i].attrs->flip_normals != want[i])
			fprintf(stderr, "  primitive %u\n", i);
	}
}

static void check_camera_flip(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 3);
	if (sc->nprims == 3) {
		CHECK(!sc->prims[0].attrs->flip_normals);
		CHECK(!sc->prims[1].attrs->flip_normals);
		CHECK(sc->prims[2].attrs->flip_normals);
	}
}

static void test_handedness(void)
{
	/*
	 * RISpec: the orientation flips with the coordinate system, so a mirror
	 * alone does not turn a primitive inside out; asking for "lh" where
	 * Scale -1 made the space right-handed does.
	 */
	CHECK(run("WorldBegin\n"
		  "Sphere 1 -1 1 360\n"
		  "AttributeBegin Scale 1 1 -1 Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin Scale 1 1 -1 Orientation \"lh\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin Scale 1 1 -1 Orientation \"rh\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin Orientation \"inside\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin ReverseOrientation Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin Orientation \"lh\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "WorldEnd\n",
		  check_flips));
	CHECK(frames == 1);
	/* A mirroring camera makes the world right-handed. */
	CHECK(run("Scale 1 1 -1\nWorldBegin\n"
		  "Sphere 1 -1 1 360\n"
		  "AttributeBegin Orientation \"rh\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "AttributeBegin Orientation \"lh\" Sphere 1 -1 1 360 AttributeEnd\n"
		  "WorldEnd\n",
		  check_camera_flip));
	CHECK(frames == 1);
}

/* ---- attributes and lights ---- */

static void check_ray_attributes(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 3);
	if (sc->nprims != 3)
		return;
	CHECK(sc->opts.trace_maxdepth == 4);
	const struct reyes_ray_attrs *a = &sc->prims[0].attrs->ray, *b = &sc->prims[1].attrs->ray;
	const struct reyes_ray_attrs *c = &sc->prims[2].attrs->ray;
	CHECK(!a->camera && a->specular && !a->diffuse && a->transmission == REYES_TRANS_OPAQUE);
	CHECK(a->hitmode[SL_RAY_SPECULAR] == REYES_HIT_PRIMITIVE);
	CHECK(a->hitmode[SL_RAY_DIFFUSE] == REYES_HIT_SHADER);
	CHECK(a->bias == 0.5f && a->max_specular_depth == 3 && a->max_diffuse_depth == 0);
	CHECK(b->specular && b->diffuse && b->transmission == REYES_TRANS_NONE && !b->camera);
	/* the defaults: the camera sees it, no reflection or diffuse rays do; shadow
	 * rays see its Os (relight casts every object's shadow by default) */
	CHECK(c->camera && !c->specular && !c->diffuse && c->transmission == REYES_TRANS_OS);
	CHECK(c->hitmode[SL_RAY_SPECULAR] == REYES_HIT_SHADER);
	CHECK(c->hitmode[SL_RAY_DIFFUSE] == REYES_HIT_PRIMITIVE);
	CHECK(c->bias == 0.01f && c->max_specular_depth == 2 && c->max_diffuse_depth == 1);
}

static void check_attributes(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 4 && sc->nlights == 1);
	if (sc->nprims != 4 || sc->nlights != 1)
		return;
	const struct reyes_attrs *a = sc->prims[0].attrs, *b = sc->prims[2].attrs;
	CHECK(a->Cs[0] == 1 && a->Cs[1] == 0 && a->Cs[2] == 0);
	CHECK(a->Os[0] == 0.5f && a->Os[1] == 0.5f && a->Os[2] == 0.5f);
	CHECK(a->surface && strcmp(a->surface->name, "matte") == 0);
	CHECK(a->surface && sl_program_kind(a->surface->prog) == SL_SHADER_SURFACE);
	CHECK(a->nlights == 1 && a->lights[0] == 0);
	CHECK(a->sides == 1);
	CHECK_NEAR(a->shading_rate, 4, 0);
	CHECK(a->smooth);
	CHECK_STR(a->identifier, "ball");
	CHECK_NEAR(a->displacement_bound, 0.5, 0);
	CHECK_STR(a->displacement_bound_space, "world");
	CHECK(!a->casts_shadows);
	/* Two primitives under the same attributes share one bundle. */
	CHECK(sc->prims[1].attrs == a);
	/* After AttributeEnd: the defaults again, and the light is off. */
	CHECK(b != a);
	CHECK(b->Cs[0] == 1 && b->Cs[1] == 1 && b->Cs[2] == 1);
	CHECK(b->Os[0] == 1);
	CHECK(b->surface == NULL && b->displacement == NULL);
	CHECK(b->nlights == 0);
	CHECK(b->sides == 2);
	CHECK_NEAR(b->shading_rate, 1, 0);
	CHECK(!b->smooth);
	CHECK(b->identifier == NULL);
	CHECK(b->displacement_bound == 0);
	CHECK_STR(b->displacement_bound_space, "object");
	CHECK(b->casts_shadows);
	CHECK(!b->flip_normals);
	/* A colour change makes a new bundle. */
	CHECK(sc->prims[3].attrs != b && sc->prims[3].attrs->Cs[1] == 0.25f);
	CHECK_STR(sc->lights[0].handle, "1");
	CHECK(sc->lights[0].index == 0 && sc->lights[0].default_on);
	CHECK_STR(sc->lights[0].shader.name, "pointlight");
}

static void test_attributes(void)
{
	CHECK(run("WorldBegin\n"
		  "AttributeBegin\n"
		  " Color [1 0 0]\n Opacity 0.5 0.5 0.5\n Surface \"matte\"\n"
		  " LightSource \"pointlight\" 1\n"
		  " Sides 1\n ShadingRate 4\n ShadingInterpolation \"smooth\"\n"
		  " Attribute \"identifier\" \"name\" \"ball\"\n"
		  " Attribute \"displacementbound\" \"sphere\" 0.5 \"coordinatesystem\" \"world\"\n"
		  " Attribute \"visibility\" \"int transmission\" 0\n"
		  " Sphere 1 -1 1 360\n Disk 0 1 360\n"
		  "AttributeEnd\n"
		  "Sphere 1 -1 1 360\n"
		  "Color 1 0.25 1\nSphere 1 -1 1 360\n"
		  "WorldEnd\n",
		  check_attributes));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(run("WorldBegin\nAttribute \"photonic\" \"maxdepth\" 2\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: unknown attribute 'photonic' ignored", rib_path));
	CHECK(frames == 1);

	/* ray tracing: visibility, hit modes, bias and depths, Option "trace" */
	CHECK(run("Option \"trace\" \"maxdepth\" 4\n"
		  "WorldBegin\nAttributeBegin\n"
		  " Attribute \"visibility\" \"int camera\" 0 \"int specular\" 1 "
		  "\"string transmission\" \"opaque\"\n"
		  " Attribute \"shade\" \"string specularhitmode\" \"primitive\" "
		  "\"string diffusehitmode\" \"shader\"\n"
		  " Attribute \"trace\" \"float bias\" 0.5 \"int maxspeculardepth\" 3 "
		  "\"int maxdiffusedepth\" 0\n"
		  " Sphere 1 -1 1 360\n"
		  " Attribute \"visibility\" \"int trace\" 1 \"int transmission\" 0\n"
		  " Sphere 1 -1 1 360\n"
		  "AttributeEnd\nSphere 1 -1 1 360\nWorldEnd\n", check_ray_attributes));
	CHECK_NO_DIAG();
	CHECK(run("WorldBegin\nAttribute \"visibility\" \"string transmission\" \"fuzzy\"\n"
		  "Attribute \"shade\" \"string specularhitmode\" \"cache\" "
		  "\"string diffusehitmode\" \"x\"\nAttribute \"trace\" \"float bias\" -1\n"
		  "WorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: visibility \"transmission\" \"fuzzy\" is not", rib_path));
	CHECK_DIAG("relight keeps no radiance cache");
	CHECK_DIAG("must be \"primitive\" or \"shader\"");
	CHECK_DIAG("trace \"bias\" takes one number, at least 0: ignored");
}

static void check_illuminate(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 6 && sc->nlights == 2);
	if (sc->nprims != 6 || sc->nlights != 2)
		return;
	static const uint32_t n[6] = {1, 2, 1, 2, 1, 1};
	static const uint32_t first[6] = {0, 0, 1, 0, 1, 0};
	for (int i = 0; i < 6; i++) {
		const struct reyes_attrs *a = sc->prims[i].attrs;
		CHECK(a->nlights == n[i] && a->lights[0] == first[i]);
		if (a->nlights == 2)
			CHECK(a->lights[1] == 1);
	}
	CHECK_STR(sc->lights[1].handle, "key");
	CHECK_STR(sc->lights[1].shader.name, "spotlight");
}

static void test_illuminate(void)
{
	CHECK(run("WorldBegin\n"
		  "LightSource \"pointlight\" 1\n"
		  "Sphere 1 -1 1 360\n"
		  "LightSource \"spotlight\" \"key\"\n"
		  "Sphere 1 -1 1 360\n"
		  "Illuminate 1 0\n"
		  "Sphere 1 -1 1 360\n"
		  "AttributeBegin\n Illuminate 1 1\n Sphere 1 -1 1 360\nAttributeEnd\n"
		  "Sphere 1 -1 1 360\n"
		  "Illuminate \"key\" 0\nIlluminate 1 1\nSphere 1 -1 1 360\n"
		  "WorldEnd\n",
		  check_illuminate));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(!run("WorldBegin\nIlluminate \"fill\" 1\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Illuminate: unknown light 'fill'", rib_path));
}

/* ---- shaders ---- */

static void check_shader_params(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 2 && sc->nlights == 2);
	if (sc->nprims != 2 || sc->nlights != 2)
		return;
	const struct reyes_shader *s = sc->prims[0].attrs->surface;
	CHECK(s && strcmp(s->name, "plastic") == 0 && s->nparams == 4);
	const struct reyes_param_value *v = param(s, "Kd");
	/* From the shader's own declaration. */
	CHECK(v && v->type == SL_TYPE_FLOAT && v->nvalues == 1 && v->values[0] == 0.8f);
	/* Inline declarations. */
	v = param(s, "Ks");
	CHECK(v && v->type == SL_TYPE_FLOAT && v->nvalues == 1 && v->values[0] == 0.25f);
	v = param(s, "specularcolor");
	CHECK(v && v->type == SL_TYPE_COLOR && v->nvalues == 3 && v->values[0] == 1 &&
	      v->values[1] == 0 && v->values[2] == 0.5f);
	/* Declare. */
	v = param(s, "roughness");
	CHECK(v && v->type == SL_TYPE_FLOAT && v->nvalues == 1 && v->values[0] == 0.3f);
	/* shader space: the transformation at the request. */
	CHECK_XFORM(s->shader_to_world, 0, 0, 0, 0, 0, 1);
	/* The same file is compiled once. */
	CHECK(sc->prims[1].attrs->surface && sc->prims[1].attrs->surface->prog == s->prog);
	CHECK_STR(sc->prims[1].attrs->surface->name, "plastic.sl");

	const struct reyes_shader *l = &sc->lights[0].shader;
	v = param(l, "from");
	CHECK(v && v->type == SL_TYPE_POINT && v->nvalues == 3 && v->values[1] == 2);
	v = param(l, "intensity");
	CHECK(v && v->type == SL_TYPE_FLOAT && v->values[0] == 5);
	l = &sc->lights[1].shader;
	v = param(l, "shadowname");
	CHECK(v && v->type == SL_TYPE_STRING && v->nvalues == 1 && v->strings &&
	      strcmp(v->strings[0], "key.shd") == 0);
}

static void test_shader_params(void)
{
	CHECK(run("Declare \"roughness\" \"uniform float\"\n"
		  "WorldBegin\n"
		  "LightSource \"pointlight\" 1 \"intensity\" 5 \"from\" [0 2 0]\n"
		  "LightSource \"shadowspot\" 2 \"string shadowname\" \"key.shd\"\n"
		  "Translate 0 0 1\n"
		  "Surface \"plastic\" \"Kd\" 0.8 \"uniform float Ks\" 0.25\n"
		  "  \"color specularcolor\" [1 0 0.5] \"roughness\" 0.3\n"
		  "Sphere 1 -1 1 360\n"
		  "Surface \"plastic.sl\"\n"
		  "Sphere 1 -1 1 360\n"
		  "WorldEnd\n",
		  check_shader_params));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	/* A declared type must agree with the shader's, or the value is ignored. */
	CHECK(run("WorldBegin\nSurface \"plastic\" \"color Kd\" [1 1 1]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: parameter 'Kd' of shader 'plastic' is float, but it is "
		       "given as color: ignored", rib_path));
	CHECK(frames == 1);
}

/* ---- primitives ---- */

static void check_quadrics(const struct reyes_scene *sc)
{
	static const enum reyes_prim_kind kinds[] = {
		REYES_SPHERE, REYES_CYLINDER, REYES_CONE, REYES_DISK, REYES_HYPERBOLOID,
		REYES_PARABOLOID, REYES_TORUS,
	};
	static const float q[7][8] = {
		{1, -0.5f, 0.5f, 270}, {2, 0, 1, 180}, {3, 1, 90}, {0.5f, 2, 360},
		{1, 0, 0, 0, 1, 1, 360}, {1, 0, 2, 360}, {2, 0.5f, 0, 360, 360},
	};
	CHECK(sc->nprims == 7);
	for (uint32_t i = 0; i < sc->nprims && i < 7; i++) {
		CHECK(sc->prims[i].kind == kinds[i]);
		CHECK(memcmp(sc->prims[i].q, q[i], sizeof(q[i])) == 0);
		CHECK(sc->prims[i].id == i);
	}
	if (sc->nprims == 7) {
		const struct reyes_primvar *v = var(&sc->prims[0], "Cs");
		CHECK(v && v->cls == REYES_VARYING && v->count == 4 && v->type == SL_TYPE_COLOR);
		CHECK(v && v->values[3] == 0 && v->values[11] == 1);
		v = var(&sc->prims[1], "s");
		CHECK(v && v->cls == REYES_VARYING && v->count == 4 && v->values[1] == 1);
		v = var(&sc->prims[1], "t");
		CHECK(v && v->count == 4 && v->values[2] == 1);
		CHECK(sc->prims[1].nvars == 2);
	}
}

static void test_quadrics(void)
{
	CHECK(run("WorldBegin\n"
		  "Sphere 1 -0.5 0.5 270 \"Cs\" [1 0 0 0 1 0 0 0 1 1 1 1]\n"
		  "Cylinder 2 0 1 180 \"st\" [0 0 1 0 0 1 1 1]\n"
		  "Cone 3 1 90\nDisk 0.5 2 360\n"
		  "Hyperboloid 1 0 0 0 1 1 360\nParaboloid 1 0 2 360\nTorus 2 0.5 0 360 360\n"
		  "WorldEnd\n",
		  check_quadrics));
	CHECK(frames == 1);
	CHECK_NO_DIAG();
}

static void check_polygons(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 4);
	if (sc->nprims != 4)
		return;
	const struct reyes_prim *p = &sc->prims[0];
	CHECK(p->kind == REYES_POLYGONS && p->nfaces == 1 && p->nloops[0] == 1 &&
	      p->nverts[0] == 4 && p->npoints == 4);
	for (uint32_t i = 0; i < 4; i++)
		CHECK(p->verts[i] == i);
	const struct reyes_primvar *P = var(p, "P");
	CHECK(P && P->cls == REYES_VERTEX && P->type == SL_TYPE_POINT && P->count == 4);
	CHECK(P && P->values[3] == 1 && P->values[4] == 0);
	CHECK(P && P->values1 == NULL);

	/* Pw: divided by w. */
	p = &sc->prims[1];
	P = var(p, "P");
	CHECK(P && P->count == 3 && P->values[0] == 1 && P->values[4] == 2 && P->values[8] == 0);
	CHECK(var(p, "Pw") == NULL);

	/* GeneralPolygon: an outline and a hole. */
	p = &sc->prims[2];
	CHECK(p->nfaces == 1 && p->nloops[0] == 2 && p->nverts[0] == 4 && p->nverts[1] == 3);
	CHECK(p->npoints == 7 && p->verts[6] == 6);

	/* PointsGeneralPolygons. */
	p = &sc->prims[3];
	CHECK(p->nfaces == 2 && p->nloops[0] == 2 && p->nloops[1] == 1);
	CHECK(p->nverts[0] == 4 && p->nverts[1] == 3 && p->nverts[2] == 3);
	CHECK(p->verts[0] == 0 && p->verts[9] == 8 && p->npoints == 9);
	const struct reyes_primvar *u = var(p, "id");
	CHECK(u && u->cls == REYES_UNIFORM && u->count == 2 && u->values[1] == 7);
}

static void test_polygons(void)
{
	CHECK(run("WorldBegin\n"
		  "Polygon \"P\" [0 0 0 1 0 0 1 1 0 0 1 0]\n"
		  "Polygon \"Pw\" [2 0 0 2  0 4 0 2  0 0 0 1]\n"
		  "GeneralPolygon [4 3] \"P\" [0 0 0 4 0 0 4 4 0 0 4 0 1 1 0 2 1 0 1 2 0]\n"
		  "PointsGeneralPolygons [2 1] [4 3 3] [0 1 2 3 4 5 6 6 7 8]\n"
		  "  \"P\" [0 0 0 4 0 0 4 4 0 0 4 0 1 1 0 2 1 0 1 2 0 5 0 0 6 0 0]\n"
		  "  \"uniform float id\" [3 7]\n"
		  "WorldEnd\n",
		  check_polygons));
	CHECK(frames == 1);
	CHECK_NO_DIAG();
}

static void check_primvars(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	if (sc->nprims != 1)
		return;
	const struct reyes_prim *p = &sc->prims[0];
	CHECK(p->nfaces == 2 && p->npoints == 6 && p->nloops[1] == 1 && p->nverts[1] == 4);
	CHECK(p->verts[4] == 1 && p->verts[7] == 4);
	const struct reyes_primvar *v = var(p, "Cs");
	CHECK(v && v->cls == REYES_VERTEX && v->count == 6 && v->type == SL_TYPE_COLOR);
	v = var(p, "foo");
	CHECK(v && v->cls == REYES_UNIFORM && v->count == 2 && v->type == SL_TYPE_FLOAT);
	v = var(p, "bar");
	CHECK(v && v->cls == REYES_FACEVARYING && v->count == 8 && v->values[7] == 8);
	v = var(p, "N");
	CHECK(v && v->cls == REYES_VARYING && v->count == 6 && v->type == SL_TYPE_NORMAL);
	v = var(p, "dir");
	CHECK(v && v->cls == REYES_CONSTANT && v->count == 1 && v->type == SL_TYPE_VECTOR);
	v = var(p, "arr");
	CHECK(v && v->cls == REYES_CONSTANT && v->arraylen == 2 && v->values[1] == 2);
	CHECK(p->nvars == 7);
}

#define TWO_QUADS \
	"PointsPolygons [4 4] [0 1 4 3 1 2 5 4]\n" \
	"  \"P\" [0 0 0 1 0 0 2 0 0 0 1 0 1 1 0 2 1 0]\n"

/* TWO_QUADS with an ignored primitive variable: P alone. */
static void check_two_quads(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	for (uint32_t i = 0; i < sc->nprims; i++)
		for (uint32_t k = 0; k < sc->prims[i].nvars; k++)
			CHECK(strcmp(sc->prims[i].vars[k].name, "mystery") != 0);
}

static void test_primvars(void)
{
	CHECK(run("Declare \"bar\" \"facevarying float\"\n"
		  "WorldBegin\n" TWO_QUADS
		  "  \"vertex color Cs\" [1 0 0 1 0 0 1 0 0 0 1 0 0 1 0 0 1 0]\n"
		  "  \"uniform float foo\" [1 2]\n"
		  "  \"bar\" [1 2 3 4 5 6 7 8]\n"
		  "  \"N\" [0 0 1 0 0 1 0 0 1 0 0 1 0 0 1 0 0 1]\n"
		  "  \"constant vector dir\" [0 1 0]\n"
		  "  \"constant float[2] arr\" [1 2]\n"
		  "  \"constant string label\" \"quads\"\n"
		  "WorldEnd\n",
		  check_primvars));
	CHECK(frames == 1);
	CHECK_DIAG(test_fmt("%s:11: warning: PointsPolygons: string primitive variable 'label' ignored",
		       rib_path));

	CHECK(!run("WorldBegin\n" TWO_QUADS "  \"uniform float foo\" [1 2 3]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: PointsPolygons: primitive variable \"foo\" (uniform float) "
		       "needs 2 values, got 3", rib_path));
	CHECK(!run("WorldBegin\n" TWO_QUADS "  \"Cs\" [1 0 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: PointsPolygons: primitive variable \"Cs\" (varying color) "
		       "needs 18 values, got 3", rib_path));
	CHECK(run("WorldBegin\n" TWO_QUADS "  \"mystery\" [1]\nWorldEnd\n", check_two_quads));
	CHECK_DIAG(test_fmt("%s:4: warning: PointsPolygons: primitive variable 'mystery' has no type "
		       "(declare it with Declare or an inline type): ignored", rib_path));
	CHECK(frames == 1);
}

static void check_patches(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 2);
	if (sc->nprims != 2)
		return;
	const struct reyes_prim *p = &sc->prims[0];
	CHECK(p->kind == REYES_PATCHES && !p->bicubic && p->nu == 2 && p->nv == 2 &&
	      p->npoints == 4);
	p = &sc->prims[1];
	CHECK(p->kind == REYES_PATCHES && p->bicubic && p->nu == 5 && p->nv == 4);
	CHECK(!p->uperiodic && p->vperiodic);
	CHECK(p->ustep == 1 && p->vstep == 2);
	/* catmull-rom in u, b-spline in v */
	CHECK(p->ubasis[0] == -0.5f && p->ubasis[4] == 1);
	CHECK_NEAR(p->vbasis[13], 4.0 / 6.0, 1e-7);
	CHECK(p->npoints == 20);
	const struct reyes_primvar *v = var(p, "t");
	/* 2 x 2 patches (u nonperiodic, v periodic): 3 x 2 varying values */
	CHECK(v && v->count == 6);
	v = var(p, "w");
	CHECK(v && v->cls == REYES_UNIFORM && v->count == 4);
}

static void test_patches(void)
{
	char mesh[2048];
	int n = snprintf(mesh, sizeof(mesh), "PatchMesh \"bicubic\" 5 \"nonperiodic\" 4 "
			 "\"periodic\" \"P\" [");
	for (int i = 0; i < 20; i++)
		n += snprintf(mesh + n, sizeof(mesh) - (size_t)n, " %d %d 0", i % 5, i / 5);
	snprintf(mesh + n, sizeof(mesh) - (size_t)n,
		 "] \"t\" [0 1 2 3 4 5] \"uniform float w\" [1 2 3 4]\n");
	char rib[4096];
	snprintf(rib, sizeof(rib),
		 "WorldBegin\n"
		 "Patch \"bilinear\" \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\n"
		 "Basis \"catmull-rom\" 1 \"b-spline\" 2\n%s"
		 "WorldEnd\n", mesh);
	CHECK(run(rib, check_patches));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(!run("WorldBegin\nPatchMesh \"bicubic\" 5 \"nonperiodic\" 4 \"nonperiodic\" "
		   "\"P\" [0 0 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: PatchMesh: 5 x 4 points do not make whole bicubic patches "
		       "with steps 3 and 3", rib_path));
}

static void check_height_field(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 2);
	if (sc->nprims != 2)
		return;
	for (uint32_t k = 0; k < 2; k++) {
		const struct reyes_prim *p = &sc->prims[k];
		CHECK(p->kind == REYES_PATCHES && p->heightfield);
		const struct reyes_primvar *P = var(p, "P");
		CHECK(P && P->type == SL_TYPE_POINT && P->cls == REYES_VERTEX);
		/* z from "Pz"; x and y are the surface's u and v, put in when it is diced */
		if (P && P->count == 4)
			CHECK(P->values[2] == 1 && P->values[5] == 2 && P->values[11] == 4);
	}
	CHECK(sc->prims[1].nu == 3 && sc->prims[1].nv == 2 && sc->prims[1].npoints == 6);
}

/*
 * "Pz": a vertex float, on Patch and PatchMesh only (height fields, RISpec);
 * "nowrap" is "nonperiodic" with a warning, other wrap words an error.
 */
static void test_height_fields(void)
{
	CHECK(run("WorldBegin\nPatch \"bilinear\" \"Pz\" [1 2 3 4]\n"
		  "PatchMesh \"bilinear\" 3 \"nonperiodic\" 2 \"nonperiodic\" \"Pz\" [1 2 3 4 5 6]\n"
		  "WorldEnd\n", check_height_field));
	CHECK(frames == 1);
	CHECK_NO_DIAG();
	CHECK(!run("WorldBegin\nPolygon \"Pz\" [1 2 3]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Polygon does not take \"Pz\"", rib_path));
	/* A quadric has no control points: its "Pz" is ignored, as any variable it cannot use. */
	CHECK(run("WorldBegin\nSphere 1 -1 1 360 \"Pz\" [1 2 3 4]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: Sphere does not take \"Pz\": ignored", rib_path));
	CHECK(!run("WorldBegin\nPatch \"bilinear\" \"vertex point Pz\" [1 2 3 4 5 6 7 8 9 10 11 12]\n"
		   "WorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Patch: \"Pz\" must be a vertex float", rib_path));
	CHECK(!run("WorldBegin\nPatch \"bilinear\" \"Pz\" [1 2 3] \"P\" [0 0 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: a bilinear Patch has 4 points, got 3", rib_path));
	CHECK(!run("WorldBegin\nPatch \"bilinear\" \"Pz\" [1 2 3 4] "
		   "\"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Patch: primitive variable \"P\" is given twice",
			    rib_path));

	CHECK(run("WorldBegin\nPatchMesh \"bilinear\" 2 \"nowrap\" 2 \"periodic\" "
		  "\"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: PatchMesh wrap mode \"nowrap\" taken as "
			    "\"nonperiodic\"", rib_path));
	CHECK(!run("WorldBegin\nPatchMesh \"bilinear\" 2 \"wrap\" 2 \"periodic\" "
		   "\"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: PatchMesh wrap modes must be \"periodic\" or "
			    "\"nonperiodic\", got 'wrap'", rib_path));
}

/* ---- objects, motion, archives ---- */

static void check_instances(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 4);
	if (sc->nprims != 4)
		return;
	/* Geometry relative to ObjectBegin's transformation, placed by the instance's. */
	CHECK_XFORM(sc->prims[0].attrs->object_to_world[0], 0, 0, 0, 1, 0, 3);
	CHECK_XFORM(sc->prims[1].attrs->object_to_world[0], 0, 0, 0, 0, 0, 3);
	CHECK(sc->prims[0].kind == REYES_SPHERE && sc->prims[1].kind == REYES_DISK);
	/* ... with the instance's attributes. */
	CHECK(sc->prims[0].attrs->Cs[1] == 1 && sc->prims[0].attrs->Cs[0] == 0);
	CHECK_XFORM(sc->prims[2].attrs->object_to_world[0], 0, 0, 0, 1, 0, -3);
	CHECK(sc->prims[2].attrs->Cs[0] == 1);
	CHECK(sc->prims[3].kind == REYES_DISK && sc->prims[3].id == 3);
	CHECK(sc->prims[2].q[0] == 0.5f);
}

static void test_objects(void)
{
	CHECK(run("WorldBegin\n"
		  "Translate 0 5 0\n"
		  "ObjectBegin \"ball\"\n"
		  " AttributeBegin Translate 1 0 0 Sphere 0.5 -1 1 360 AttributeEnd\n"
		  " Disk 0 1 360\n"
		  "ObjectEnd\n"
		  "Identity\n"
		  "AttributeBegin Color 0 1 0 Translate 0 0 3 ObjectInstance \"ball\" AttributeEnd\n"
		  "AttributeBegin Translate 0 0 -3 ObjectInstance \"ball\" AttributeEnd\n"
		  "WorldEnd\n",
		  check_instances));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(!run("WorldBegin\nObjectInstance 7\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: ObjectInstance: unknown object '7'", rib_path));
}

/* Frame 1: the light before FrameBegin, the frame's own, and one in the world. */
static void check_pre_lights1(const struct reyes_scene *sc)
{
	CHECK(sc->nlights == 3 && sc->nprims == 1);
	if (sc->nlights != 3 || sc->nprims != 1)
		return;
	CHECK_STR(sc->lights[0].handle, "outer");
	CHECK_STR(sc->lights[1].handle, "2");
	CHECK_STR(sc->lights[2].handle, "3");
	for (uint32_t i = 0; i < 3; i++)
		CHECK(sc->lights[i].index == i);
	/* declared before the camera's Translate 0 0 5: shader space is camera
	   space, 5 units behind the world's origin seen from the world */
	CHECK_XFORM(sc->lights[0].shader.shader_to_world, 0, 0, 0, 0, 0, -5);
	/* declared after it: the world's origin */
	CHECK_XFORM(sc->lights[1].shader.shader_to_world, 0, 0, 0, 0, 0, 0);
	/* outer was switched off before WorldBegin, 2 and 3 are on */
	const struct reyes_attrs *a = sc->prims[0].attrs;
	CHECK(a->nlights == 2 && a->lights[0] == 1 && a->lights[1] == 2);
	CHECK(!sc->lights[0].default_on);
}

/* Frame 2: the light before FrameBegin alone, on again (the frame restored it). */
static void check_pre_lights2(const struct reyes_scene *sc)
{
	CHECK(sc->nlights == 1 && sc->nprims == 1);
	if (sc->nlights != 1 || sc->nprims != 1)
		return;
	CHECK_STR(sc->lights[0].handle, "outer");
	const struct reyes_attrs *a = sc->prims[0].attrs;
	CHECK(a->nlights == 1 && a->lights[0] == 0);
}

static void check_pre_lights(const struct reyes_scene *sc)
{
	if (frames == 1)
		check_pre_lights1(sc);
	else
		check_pre_lights2(sc);
}

/*
 * LightSource and Illuminate before WorldBegin and before FrameBegin: the
 * light belongs to the worlds that follow until its frame ends, in the
 * space current at the request (camera-relative), on or off as an
 * attribute.
 */
static void test_lights_before_world(void)
{
	CHECK(run("LightSource \"pointlight\" \"outer\"\n"
		  "FrameBegin 1\n"
		  " Translate 0 0 5\n"
		  " LightSource \"distantlight\" 2\n"
		  " Illuminate \"outer\" 0\n"
		  " WorldBegin\n"
		  "  LightSource \"pointlight\" 3\n"
		  "  Sphere 1 -1 1 360\n"
		  " WorldEnd\n"
		  "FrameEnd\n"
		  "FrameBegin 2\n"
		  " WorldBegin\n"
		  "  Sphere 1 -1 1 360\n"
		  " WorldEnd\n"
		  "FrameEnd\n",
		  check_pre_lights));
	CHECK(frames == 2);
	CHECK_NO_DIAG();

	/* the frame's own light ends with it */
	CHECK(!run("FrameBegin 1\nLightSource \"pointlight\" 2\nWorldBegin\nWorldEnd\nFrameEnd\n"
		   "FrameBegin 2\nIlluminate 2 1\nWorldBegin\nWorldEnd\nFrameEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:7: error: Illuminate: unknown light '2'", rib_path));
}

/* The object's own Color and Surface; the instance's Opacity and Sides. */
static void check_object_attrs(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 3);
	if (sc->nprims != 3)
		return;
	for (uint32_t i = 1; i < 3; i++) {
		const struct reyes_attrs *a = sc->prims[i].attrs;
		CHECK(a->Cs[0] == 1 && a->Cs[1] == 0 && a->Cs[2] == 0);
		CHECK(a->Os[0] == 0.5f && a->sides == 1);
		CHECK(a->surface && strcmp(a->surface->name, "constant") == 0);
	}
	/* the primitives under the same recorded attributes share a bundle */
	CHECK(sc->prims[1].attrs == sc->prims[2].attrs);
	/* declared before the definition's Color: the instance's */
	const struct reyes_attrs *b = sc->prims[0].attrs;
	CHECK(b->Cs[0] == 0 && b->Cs[1] == 0 && b->Cs[2] == 1);
	CHECK(b->surface && strcmp(b->surface->name, "matte") == 0);
	CHECK(b->Os[0] == 0.5f && b->sides == 1);
}

/* Attributes set inside ObjectBegin are recorded with the object's primitives. */
static void test_object_attributes(void)
{
	CHECK(run("ObjectBegin 1\n"
		  " Disk 0 1 360\n"
		  " Color [1 0 0]\n"
		  " Surface \"constant\"\n"
		  " Sphere 1 -1 1 360\n"
		  " Disk 0 2 360\n"
		  "ObjectEnd\n"
		  "WorldBegin\n"
		  " Color [0 0 1]\n"
		  " Opacity [0.5 0.5 0.5]\n"
		  " Sides 1\n"
		  " Surface \"matte\"\n"
		  " ObjectInstance 1\n"
		  "WorldEnd\n",
		  check_object_attrs));
	CHECK(frames == 1);
	CHECK_NO_DIAG();
}

static void check_motion(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 3);
	if (sc->nprims != 3)
		return;
	const struct reyes_attrs *a = sc->prims[0].attrs;
	CHECK(a->moving);
	CHECK_XFORM(a->object_to_world[0], 0, 0, 0, 0, 0, 0);
	CHECK_XFORM(a->object_to_world[1], 0, 0, 0, 1, 0, 0);
	/* Transformations after the motion block apply to both samples. */
	a = sc->prims[1].attrs;
	CHECK(a->moving);
	CHECK_XFORM(a->object_to_world[0], 0, 0, 0, 0, 2, 0);
	CHECK_XFORM(a->object_to_world[1], 0, 0, 0, 1, 2, 0);
	/* A deforming polygon, outside the moving transformation. */
	const struct reyes_prim *p = &sc->prims[2];
	CHECK(!p->attrs->moving);
	const struct reyes_primvar *P = var(p, "P");
	CHECK(P && P->values1 && P->values1[3] == 2 && P->values[3] == 1);
	const struct reyes_primvar *Cs = var(p, "Cs");
	CHECK(Cs && Cs->values1 == NULL);
}

static void check_deforming_quadrics(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 2);
	if (sc->nprims != 2)
		return;
	const struct reyes_prim *p = &sc->prims[0];
	CHECK(p->kind == REYES_SPHERE && p->qmoving && !p->attrs->moving);
	CHECK(p->q[0] == 1 && p->q[3] == 360 && p->q1[0] == 2 && p->q1[2] == 2 && p->q1[3] == 180);
	/* the same parameters twice: nothing moves */
	CHECK(sc->prims[1].kind == REYES_DISK && !sc->prims[1].qmoving);
}

static void test_motion(void)
{
	CHECK(run("Shutter 0 1\nWorldBegin\n"
		  "AttributeBegin\n"
		  "MotionBegin [0 1]\n Translate 0 0 0\n Translate 1 0 0\nMotionEnd\n"
		  "Sphere 1 -1 1 360\n"
		  "Translate 0 2 0\nSphere 1 -1 1 360\n"
		  "AttributeEnd\n"
		  "MotionBegin [0 1]\n"
		  " Polygon \"P\" [0 0 0 1 0 0 0 1 0] \"constant color Cs\" [1 0 0]\n"
		  " Polygon \"P\" [0 0 0 2 0 0 0 1 0] \"constant color Cs\" [1 0 0]\n"
		  "MotionEnd\n"
		  "WorldEnd\n",
		  check_motion));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(!run("WorldBegin\nMotionBegin [0 0.5 1]\nTranslate 0 0 0\nTranslate 1 0 0\n"
		   "Translate 2 0 0\nMotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: only 2 motion samples are supported", rib_path));
	CHECK(frames == 0);

	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nTranslate 0 0 0\nScale 1 1 1\nMotionEnd\n"
		   "WorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: Scale does not match the Translate before it in the "
		       "MotionBegin at line 2", rib_path));

	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nPolygon \"P\" [0 0 0 1 0 0 0 1 0]\n"
		   "Polygon \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\nMotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: the Polygon samples of the MotionBegin at line 2 differ",
		       rib_path));

	/* Deforming quadrics: the second sample's parameters at shutter close; the
	   samples must be one request with the same parameter list. */
	CHECK(run("Shutter 0 1\nWorldBegin\nMotionBegin [0 1]\nSphere 1 -1 1 360\n"
		  "Sphere 2 -2 2 180\nMotionEnd\nMotionBegin [0 1]\nDisk 0 1 360\nDisk 0 1 360\n"
		  "MotionEnd\nWorldEnd\n", check_deforming_quadrics));
	CHECK_NO_DIAG();
	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nSphere 1 -1 1 360\nCylinder 1 -1 1 360\n"
		   "MotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: Cylinder does not match the Sphere before it in the "
			    "MotionBegin at line 2", rib_path));
	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nSphere 1 -1 1 360\n"
		   "Sphere 2 -2 2 360 \"constant color Cs\" [1 0 0]\nMotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: the Sphere samples of the MotionBegin at line 2 differ "
			    "in their primitive variables", rib_path));
	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nPatch \"bilinear\" \"Pz\" [1 2 3 4]\n"
		   "Patch \"bilinear\" \"P\" [0 0 0 1 0 0 0 1 0 1 1 0]\nMotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:4: error: the Patch samples of the MotionBegin at line 2 differ "
			    "in their patch mesh", rib_path));

	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nColor 1 0 0\nColor 0 1 0\nMotionEnd\n"
		   "WorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:3: error: Color cannot be inside the MotionBegin at line 2",
		       rib_path));
}

static void check_archive(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 2);
	if (sc->nprims == 2) {
		CHECK(sc->prims[0].kind == REYES_DISK);
		CHECK(sc->prims[1].kind == REYES_SPHERE);
	}
	CHECK_STR(sc->opts.archive_path, test_fmt("/nonexistent:%s/arch", dir));
}

static void check_archive_default(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	CHECK_STR(sc->opts.archive_path, test_fmt("%s/arch:.", dir));
	CHECK_STR(sc->opts.shader_path, test_fmt("/nowhere:%s", RELIGHT_SOURCE_SHADER_DIR));
}

static void test_archives(void)
{
	mkdir(test_fmt("%s/arch", dir), 0700);
	put("arch/geo.rib", "Sphere 1 -1 1 360\n");
	put("arch/nested.rib", "Disk 0 1 360\nReadArchive \"geo.rib\"\n");
	put("arch/self.rib", "ReadArchive \"self.rib\"\n");
	put("arch/open.rib", "AttributeBegin\n");
	CHECK(run(test_fmt("Option \"searchpath\" \"archive\" \"/nonexistent\"\n"
		      "Option \"searchpath\" \"archive\" \"&:%s/arch\"\n"
		      "WorldBegin\nReadArchive \"nested.rib\"\nWorldEnd\n", dir),
		  check_archive));
	CHECK(frames == 1);
	CHECK_NO_DIAG();

	CHECK(run(test_fmt("Option \"searchpath\" \"archive\" \"%s/arch:@\" \"shader\" \"/nowhere:@\"\n"
		      "WorldBegin\nReadArchive \"geo.rib\"\nWorldEnd\n", dir),
		  check_archive_default));
	CHECK(frames == 1);

	CHECK(!run("WorldBegin\nReadArchive \"geo.rib\"\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: cannot find archive 'geo.rib'", rib_path));
	CHECK(frames == 0);

	CHECK(!run(test_fmt("WorldBegin\nReadArchive \"%s/arch/self.rib\"\nWorldEnd\n", dir), NULL));
	CHECK_DIAG(test_fmt("%s/arch/self.rib:1: error: ReadArchive 'self.rib' would read itself again",
		       dir));

	/* A chain of 70 archives, each reading the next: nesting stops at 64. */
	for (int i = 0; i < 70; i++)
		put(test_fmt("arch/c%d.rib", i), test_fmt("ReadArchive \"c%d.rib\"\n", i + 1));
	put("arch/c70.rib", "Sphere 1 -1 1 360\n");
	int n = 0;
	CHECK(!run_opts(test_fmt("WorldBegin\nReadArchive \"%s/arch/c0.rib\"\nWorldEnd\n", dir), NULL,
			NULL, &n));
	CHECK_DIAG(test_fmt("%s/arch/c63.rib:1: error: ReadArchive 'c64.rib': archives nested too "
		       "deeply (limit 64)", dir));
	CHECK(n == 1 && frames == 0);

	CHECK(!run(test_fmt("WorldBegin\nReadArchive \"%s/arch/open.rib\"\nWorldEnd\n", dir), NULL));
	CHECK_DIAG(test_fmt("%s/arch/open.rib:1: error: the file ends inside the AttributeBegin at "
		       "line 1", dir));
	CHECK(frames == 0);
}

/* ---- the error policy ---- */

static uint32_t last_nprims;

static void count_prims(const struct reyes_scene *sc)
{
	last_nprims = sc->nprims;
}

/* The sphere's primitive variables bind no "Kd" to the shader. */
static void check_no_kd(const struct reyes_scene *sc)
{
	CHECK(sc->nprims == 1);
	for (uint32_t i = 0; i < sc->nprims; i++)
		for (uint32_t k = 0; k < sc->prims[i].nvars; k++)
			CHECK(strcmp(sc->prims[i].vars[k].name, "Kd") != 0);
}

/*
 * Warnings (what is ignored: the frame renders), errors that drop one
 * primitive (the rest renders) and errors that hold back the frame; each
 * message once per place; --strict.
 */
static void test_error_policy(void)
{
	struct reyes_ri_counts c;
	struct reyes_ri_opts o = {.counts = &c};
	int n;

	/* An unsupported and an unknown request: warnings, the frame renders. */
	CHECK(run_opts("WorldBegin\nShader \"plastic\" \"co\"\nSphre 1 -1 1 360\nSphere 1 -1 1 360\n"
		       "WorldEnd\n", count_prims, &o, &n));
	CHECK_DIAG(test_fmt("%s:2: warning: Shader is not supported: ignored\n"
			    "%s:3: warning: unknown request 'Sphre' ignored; did you mean "
			    "'Sphere'?\n", rib_path, rib_path));
	CHECK(frames == 1 && last_nprims == 1);
	CHECK(n == 0 && c.errors == 0 && c.warnings == 2 && c.repeats == 0 && c.dropped == 0);

	/* A malformed primitive among good ones: dropped with an error, the rest renders. */
	CHECK(!run_opts("WorldBegin\nPolygon \"P\" [0 0 0 1 0 0 1 1 0]\n"
			"Polygon \"P\" [0 0 0 1 0 0 1 1]\nSphere 1 -1 1 360\nWorldEnd\n",
			count_prims, &o, &n));
	CHECK_DIAG(test_fmt("%s:3: error: Polygon: \"P\" has 8 values, not a multiple of 3\n",
			    rib_path));
	CHECK(frames == 1 && last_nprims == 2);
	CHECK(n == 1 && c.errors == 1 && c.fatal == 0 && c.dropped == 1);

	/* Dropped primitives do not count towards the limit of errors that ends the read. */
	struct rl_strbuf many = {0};
	rl_strbuf_printf(&many, "WorldBegin\n");
	for (int i = 0; i < 30; i++)
		rl_strbuf_printf(&many, "Polygon \"P\" [0 0 0 1 0 0 1 %d]\n", i);
	rl_strbuf_printf(&many, "Sphere 1 -1 1 360\nWorldEnd\n");
	CHECK(!run_opts(rl_strbuf_str(&many), count_prims, &o, &n));
	CHECK(frames == 1 && last_nprims == 1 && c.dropped == 30 && c.errors == 30 && c.fatal == 0);
	CHECK(c.frames == 1);
	rl_strbuf_finish(&many);

	/* A deforming primitive goes with its malformed sample. */
	CHECK(!run_opts("WorldBegin\nMotionBegin [0 1]\nPolygon \"P\" [0 0 0 1 0 0 1 1]\n"
			"Polygon \"P\" [0 0 0 1 0 0 1 1 0]\nMotionEnd\nSphere 1 -1 1 360\nWorldEnd\n",
			count_prims, &o, &n));
	CHECK_STR(diag, test_fmt("%s:3: error: Polygon: \"P\" has 8 values, not a multiple of 3\n",
				 rib_path));
	CHECK(frames == 1 && last_nprims == 1 && c.fatal == 0 && c.dropped == 1);

	/* An error outside a primitive still holds back its frame. */
	CHECK(!run_opts("WorldBegin\nSurface \"nosuch\"\nSphere 1 -1 1 360\nWorldEnd\n", NULL, &o,
			&n));
	CHECK(frames == 0 && c.fatal == 1 && c.dropped == 0);
	/* So do the requests whose absence would change the meaning of the rest. */
	CHECK(!run_opts("WorldBegin\nIfBegin \"true\"\nSphere 1 -1 1 360\nIfEnd\nWorldEnd\n", NULL,
			&o, &n));
	CHECK_DIAG(test_fmt("%s:2: error: IfBegin is not supported, and the frame would be wrong "
			    "without it\n", rib_path));
	CHECK(frames == 0 && c.fatal == 2);

	/* One line per message and place: an archive read 50 times reports once. */
	put("arch/fog.rib", "Shader \"plastic\" \"co\"\nSurface \"plastic\" \"Kdd\" 1\n");
	struct rl_strbuf b = {0};
	rl_strbuf_printf(&b, "WorldBegin\n");
	for (int i = 0; i < 50; i++)
		rl_strbuf_printf(&b, "ReadArchive \"%s/arch/fog.rib\"\n", dir);
	rl_strbuf_printf(&b, "Sphere 1 -1 1 360\nWorldEnd\n");
	CHECK(run_opts(rl_strbuf_str(&b), count_prims, &o, &n));
	CHECK_STR(diag, test_fmt("%s/arch/fog.rib:1: warning: Shader is not supported: ignored\n"
			    "%s/arch/fog.rib:2: warning: shader 'plastic' has no parameter 'Kdd': "
			    "ignored\n", dir, dir));
	CHECK(frames == 1 && c.warnings == 2 && c.repeats == 98 && c.errors == 0);

	/* --strict: every warning an error, the frame held back. */
	o.strict = true;
	CHECK(!run_opts(rl_strbuf_str(&b), NULL, &o, &n));
	CHECK_DIAG(test_fmt("%s/arch/fog.rib:1: error: Shader is not supported: ignored (an "
			    "error under --strict)\n", dir));
	CHECK(frames == 0 && c.warnings == 0 && c.errors == 2 && c.fatal == 2);
	o.strict = false;
	rl_strbuf_finish(&b);

	/* A primitive variable that does not fit the shader's parameter of its name. */
	CHECK(run_opts("WorldBegin\nSurface \"plastic\"\n"
		       "Sphere 1 -1 1 360 \"uniform color Kd\" [1 0 0]\nWorldEnd\n", check_no_kd,
		       &o, &n));
	CHECK_DIAG(test_fmt("%s:3: warning: Sphere: primitive variable 'Kd' (color) does not fit "
			    "parameter 'Kd' of shader 'plastic' (float): ignored\n", rib_path));
	CHECK(frames == 1 && c.warnings == 1);
	/* In an object, against the shaders its instances give it, at each ObjectInstance. */
	CHECK(run_opts("WorldBegin\nObjectBegin \"ball\"\n"
		       "Sphere 1 -1 1 360 \"uniform color Kd\" [1 0 0]\nObjectEnd\n"
		       "Surface \"plastic\"\nObjectInstance \"ball\"\nWorldEnd\n", NULL, &o, &n));
	CHECK_STR(diag, test_fmt("%s:6: warning: ObjectInstance ball: primitive variable 'Kd' "
				 "(color) does not fit parameter 'Kd' of shader 'plastic' (float): "
				 "ignored\n", rib_path));
	CHECK(frames == 1 && c.warnings == 1);
}

/* ---- errors ---- */

static void test_errors(void)
{
	const char *sh = RELIGHT_SOURCE_SHADER_DIR;
	CHECK(run("WorldBegin\nSurface \"plastic\" \"Kdd\" 1\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: shader 'plastic' has no parameter 'Kdd': ignored\n",
		       rib_path));
	CHECK(frames == 1);

	CHECK(!run("WorldBegin\nSurface \"plastic\" \"Kd\" [1 2]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: parameter 'Kd' of shader 'plastic' needs 1 value, got 2\n",
		       rib_path));

	CHECK(!run("WorldBegin\nSurface \"nosuch\"\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: cannot find shader 'nosuch' (searched: %s)\n", rib_path, sh));

	CHECK(!run("WorldBegin\nSurface \"pointlight\"\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Surface needs a surface shader, but 'pointlight' is a light "
		       "shader\n", rib_path));

	CHECK(!run("WorldBegin\nPointsPolygons [3] [0 1 5] \"P\" [0 0 0 1 0 0 0 1 0]\nWorldEnd\n",
		   NULL));
	CHECK_DIAG(test_fmt("%s:2: error: PointsPolygons: vertex index 5 (element 2) is out of range "
		       "(3 points)\n", rib_path));

	CHECK(!run("WorldBegin\nPolygon \"P\" [0 0 0 1 0 0 0 1]\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: Polygon: \"P\" has 8 values, not a multiple of 3\n",
		       rib_path));

	/* Unbalanced blocks name both lines. */
	int n = 0;
	CHECK(!run_opts("WorldBegin\nTransformBegin\nSphere 1 -1 1 360\nAttributeEnd\n"
			"TransformEnd\nWorldEnd\n", NULL, NULL, &n));
	CHECK_DIAG(test_fmt("%s:4: error: AttributeEnd at line 4 does not close the TransformBegin at "
		       "line 2\n", rib_path));
	CHECK(n == 1 && frames == 0);

	CHECK(!run("AttributeEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:1: error: AttributeEnd without a matching AttributeBegin\n", rib_path));

	CHECK(!run_opts("WorldBegin\nAttributeBegin\nSphere 1 -1 1 360\n", NULL, NULL, &n));
	CHECK_DIAG(test_fmt("%s:3: error: the file ends inside the AttributeBegin at line 2\n",
		       rib_path));
	CHECK_DIAG(test_fmt("%s:3: error: the file ends inside the WorldBegin at line 1\n", rib_path));
	CHECK(n == 2 && frames == 0);

	CHECK(!run("Sphere 1 -1 1 360\n", NULL));
	CHECK_DIAG(test_fmt("%s:1: error: Sphere outside WorldBegin/WorldEnd\n", rib_path));

	/* A frame with an error is not rendered; the next one is. */
	CHECK(!run_opts("FrameBegin 1\nWorldBegin\nSurface \"nosuch\"\nWorldEnd\nFrameEnd\n"
			"FrameBegin 2\nWorldBegin\nWorldEnd\nFrameEnd\n", NULL, NULL, &n));
	CHECK(frames == 1 && n == 1);

	/* So is a frame with a syntax error the reader found... */
	CHECK(!run_opts("WorldBegin\nTranslate 1 2\nWorldEnd\n", NULL, NULL, &n));
	CHECK(frames == 0 && n == 1);
	CHECK_DIAG(test_fmt("%s:2: error: ", rib_path));
	/* ... unless it is in a primitive's arguments: that primitive is dropped. */
	CHECK(!run_opts("WorldBegin\nSphere 1 -1\nSphere 1 -1 1 360\nWorldEnd\n", NULL, NULL, &n));
	CHECK(frames == 1 && n == 1);
	CHECK_DIAG(test_fmt("%s:2: error: Sphere expects 4 numbers", rib_path));

	/* MakeTexture's failures are reported at its line. */
	CHECK(!run("MakeTexture \"missing.exr\" \"out.tex\" \"periodic\" \"clamp\" \"box\" 1 1\n",
		   NULL));
	CHECK_DIAG(test_fmt("%s:1: error: MakeTexture 'missing.exr' -> 'out.tex' failed\n", rib_path));

	CHECK(!run("MakeShadow \"missing.z\" \"out.shd\"\n", NULL));
	CHECK_DIAG(test_fmt("%s:1: error: MakeShadow 'missing.z' -> 'out.shd' failed\n", rib_path));

	CHECK(run("WorldBegin\nSurface \"plastic\" \"Kd\" 1 \"Kd\" 2\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: warning: parameter 'Kd' of shader 'plastic' is given twice: the "
		       "first value is kept\n", rib_path));

	CHECK(!run("WorldBegin\nMotionBegin [0 1]\nTranslate 1 0 0\nMotionEnd\nWorldEnd\n", NULL));
	CHECK_DIAG(test_fmt("%s:2: error: MotionBegin has 2 times but 1 sample\n", rib_path));

	/* Errors stop at max_errors. */
	struct reyes_ri_opts o = {.max_errors = 3};
	CHECK(!run_opts("Sides 3\nSides 3\nSides 3\nSides 3\nSides 3\n", NULL, &o, &n));
	CHECK(n == 3);
	CHECK(!strstr(diag, test_fmt("%s:4:", rib_path)));

	/* A missing file. */
	CHECK(!reyes_ri_read(test_fmt("%s/no-such.rib", dir),
			     &(struct reyes_ri_opts){.diag = fopen("/dev/null", "w")}, &n));
	CHECK(n == 1);
}

static bool refuse(void *user, const struct reyes_scene *sc)
{
	(void)sc;
	++*(int *)user;
	return false;
}

static void test_frame_refused(void)
{
	/* A callback that refuses a frame stops the read. */
	int calls = 0, n = 0;
	struct reyes_ri_opts o = {.diag = tmpfile(), .frame = refuse, .user = &calls};
	const char *path = put("t.rib", "WorldBegin\nWorldEnd\nWorldBegin\nWorldEnd\n");
	CHECK(!reyes_ri_read(path, &o, &n));
	CHECK(calls == 1 && n == 1);
	fclose(o.diag);

	/* No callback: the scene is built and dropped. */
	o = (struct reyes_ri_opts){.diag = tmpfile()};
	CHECK(reyes_ri_read(path, &o, &n));
	CHECK(n == 0);
	fclose(o.diag);
}

int main(void)
{
	snprintf(dir, sizeof(dir), "/tmp/test_ri.XXXXXX");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_defaults);
	RUN(test_options);
	RUN(test_transforms);
	RUN(test_handedness);
	RUN(test_attributes);
	RUN(test_illuminate);
	RUN(test_shader_params);
	RUN(test_quadrics);
	RUN(test_polygons);
	RUN(test_primvars);
	RUN(test_patches);
	RUN(test_objects);
	RUN(test_lights_before_world);
	RUN(test_object_attributes);
	RUN(test_motion);
	RUN(test_height_fields);
	RUN(test_archives);
	RUN(test_errors);
	RUN(test_error_policy);
	RUN(test_frame_refused);
	for (int i = 0; i < nwritten; i++)
		unlink(written[i]);
	rmdir(test_fmt("%s/arch", dir));
	rmdir(dir);
	return test_finish();
}

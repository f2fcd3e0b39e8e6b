/*
 * Shadow geometry against closed forms: each test writes a RIB scene, reads
 * it through the scene builder, dices it for shadows and checks the
 * world-space micropolygons (positions, coverage, ids) and the choice of
 * shadow-casting lights.
 */
#include "shadowgeo.h"
#include "reyes.h"
#include "ri.h"
#include "config.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static const char *tmp_path(const char *name)
{
	static char buf[4][512];
	static int k;
	char *b = buf[k++ & 3];
	snprintf(b, 512, "%s/%s", tmpdir, name);
	return b;
}

/* What a frame gave: its shadow geometry, the lights that cast shadows, a culled count. */
struct result {
	float rate;
	bool ok;
	struct bake_shadow_geometry geo;
	uint32_t nlights;
	bool casts[8];
	uint64_t culled_grids;          /* grids reyes_dice gives when it culls to the view */
	FILE *diag;                     /* NULL: stderr */
};

static bool count_grid(void *user, const struct reyes_prim *prim, const float *P, uint32_t nu,
		       uint32_t nv, const uint8_t *keep, const float *Os)
{
	(void)Os;
	(void)keep;
	(void)prim;
	(void)P;
	(void)nu;
	(void)nv;
	(*(uint64_t *)user)++;
	return true;
}

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct result *res = user;
	res->ok = bake_shadow_geometry(scene, res->rate, res->diag ? res->diag : stderr, &res->geo);
	res->nlights = scene->nlights;
	for (uint32_t i = 0; i < scene->nlights && i < 8; i++)
		res->casts[i] = bake_light_casts_shadows(scene, i);
	struct reyes_dice_opts o = { .rate = res->rate, .cull_to_view = true,
				     .grid = count_grid, .user = &res->culled_grids };
	return reyes_dice(scene, &o) && res->ok;
}

/* Write @rib to a file in the temporary directory and dice it at @rate. */
static bool dice_to(const char *rib, float rate, FILE *diag, struct result *res)
{
	memset(res, 0, sizeof(*res));
	res->rate = rate;
	res->diag = diag;
	const char *path = tmp_path("scene.rib");
	FILE *f = fopen(path, "w");
	if (!f)
		return false;
	fputs(rib, f);
	fclose(f);
	char shaders[600];
	snprintf(shaders, sizeof(shaders), "%s:%s", tmpdir, RELIGHT_SOURCE_SHADER_DIR);
	struct reyes_ri_opts o = {
		.default_shader_path = shaders,
		.frame = on_frame,
		.user = res,
	};
	int nerr = 0;
	if (!reyes_ri_read(path, &o, &nerr)) {
		fprintf(stderr, "dicing failed (%d errors)\n", nerr);
		return false;
	}
	return res->ok;
}

static bool dice(const char *rib, float rate, struct result *res)
{
	return dice_to(rib, rate, NULL, res);
}

static const float *point(const struct bake_shadow_geometry *g, uint32_t i)
{
	return g->P + 3 * (size_t)i;
}

/* Vector area of a (possibly non-planar) quad: half the cross product of its diagonals. */
static double quad_area(const struct bake_shadow_geometry *g, uint64_t q)
{
	const uint32_t *v = g->quads + 4 * q;
	const float *a = point(g, v[0]), *b = point(g, v[1]), *c = point(g, v[2]),
		    *d = point(g, v[3]);
	double e[3], f[3];
	for (int k = 0; k < 3; k++) {
		e[k] = (double)c[k] - a[k];
		f[k] = (double)d[k] - b[k];
	}
	double x = e[1] * f[2] - e[2] * f[1], y = e[2] * f[0] - e[0] * f[2],
	       z = e[0] * f[1] - e[1] * f[0];
	return 0.5 * sqrt(x * x + y * y + z * z);
}

/* Indices in range, ids as many as quads. */
static bool well_formed(const struct bake_shadow_geometry *g)
{
	for (uint64_t q = 0; q < 4 * g->nquads; q++)
		if (g->quads[q] >= g->npoints)
			return false;
	return g->npoints > 0 && g->nquads > 0 && g->ngrids > 0 && g->object;
}

/* Largest |distance from @c - 1| over the points of the quads of object @id (all: UINT32_MAX). */
static double sphere_error(const struct bake_shadow_geometry *g, const double c[3], uint32_t id)
{
	double worst = 0;
	for (uint64_t q = 0; q < g->nquads; q++) {
		if (id != UINT32_MAX && g->object[q] != id)
			continue;
		for (int k = 0; k < 4; k++) {
			const float *p = point(g, g->quads[4 * q + (uint64_t)k]);
			double d = sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
					(p[2] - c[2]) * (p[2] - c[2]));
			if (fabs(d - 1) > worst)
				worst = fabs(d - 1);
		}
	}
	return worst;
}

/*
 * A camera turned and moved (world (1, 2, 3) lands at camera (0, 0, 6)),
 * then a unit sphere centred at world (1, 2, 3).
 */
#define CAMERA \
	"Format 320 240 1\n" \
	"Projection \"perspective\" \"fov\" 45\n" \
	"Translate 0 0 6\n" \
	"Rotate 30 0 1 0\n" \
	"Rotate -20 1 0 0\n" \
	"Translate -1 -2 -3\n"

static const char *sphere_rib =
	CAMERA
	"WorldBegin\n"
	"  AttributeBegin\n"
	"    Translate 1 2 3\n"
	"    Sphere 1 -1 1 360\n"
	"  AttributeEnd\n"
	"WorldEnd\n";

/*
 * Every point of a unit sphere lies at distance 1 from its centre in world
 * space (within 1e-4: float transforms through camera space and back), the
 * micropolygons cover it (their areas sum to 4 pi within 2%: flat facets
 * of a few pixels on a sphere 50 pixels across lose far less), and all
 * carry the sphere's id.
 */
static void test_sphere(void)
{
	struct result res;
	CHECK(dice(sphere_rib, 1, &res));
	struct bake_shadow_geometry *g = &res.geo;
	CHECK(well_formed(g));
	if (!g->nquads)
		return;
	double c[3] = { 1, 2, 3 };
	double worst = 0;
	for (uint64_t i = 0; i < g->npoints; i++) {
		const float *p = point(g, (uint32_t)i);
		double d = sqrt((p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
				(p[2] - c[2]) * (p[2] - c[2]));
		if (fabs(d - 1) > worst)
			worst = fabs(d - 1);
	}
	double area = 0;
	bool ids = true;
	for (uint64_t q = 0; q < g->nquads; q++) {
		area += quad_area(g, q);
		ids = ids && g->object[q] == 0;
	}
	double want = 4 * 3.14159265358979;
	printf("sphere: %llu points, %llu quads, %u grids; worst radius error %.2e "
	       "(tolerance 1e-4); area %.4f vs %.4f (%.3f%%, tolerance 2%%)\n",
	       (unsigned long long)g->npoints, (unsigned long long)g->nquads, g->ngrids, worst,
	       area, want, 100 * fabs(area - want) / want);
	CHECK(worst <= 1e-4);
	CHECK_NEAR(area, want, 0.02 * want);
	CHECK(ids);
	/* the sphere is in view: dicing with culling keeps it too */
	CHECK(res.culled_grids == g->ngrids);
	bake_shadow_geometry_free(g);
	CHECK(g->P == NULL && g->npoints == 0);
}

/*
 * Half the micropolygon area, twice the micropolygons: the ratio of quad
 * counts at rates 2 and 4 lies in [1.5, 2.6] (grids are whole numbers of
 * rows and columns, rounded up, so it is not exactly 2).
 */
static void test_rate(void)
{
	struct result coarse, fine;
	CHECK(dice(sphere_rib, 4, &coarse));
	CHECK(dice(sphere_rib, 2, &fine));
	double ratio = coarse.geo.nquads ? (double)fine.geo.nquads / (double)coarse.geo.nquads : 0;
	printf("rate: %llu quads at rate 4, %llu at rate 2: ratio %.3f (want 1.5 to 2.6)\n",
	       (unsigned long long)coarse.geo.nquads, (unsigned long long)fine.geo.nquads, ratio);
	CHECK(ratio >= 1.5 && ratio <= 2.6);
	bake_shadow_geometry_free(&coarse.geo);
	bake_shadow_geometry_free(&fine.geo);
}

/*
 * Spheres behind the camera and far off to its side are diced all the
 * same, on the sphere, and about as finely as the same sphere at the same
 * distance in front (within a factor 4 either way: the pixel size at a
 * distance stands in for the projection). Culling to the view drops them.
 */
static void test_unseen(void)
{
	static const char *const placements[3] = { "0 0 5", "0 0 -5", "-5 0 0.5" };
	uint64_t quads[3] = { 0, 0, 0 };
	for (int k = 0; k < 3; k++) {
		char rib[512];
		snprintf(rib, sizeof(rib),
			 "Format 320 240 1\n"
			 "Projection \"perspective\" \"fov\" 45\n"
			 "WorldBegin\n"
			 "  Translate %s\n"
			 "  Sphere 1 -1 1 360\n"
			 "WorldEnd\n", placements[k]);
		struct result res;
		CHECK(dice(rib, 1, &res));
		CHECK(well_formed(&res.geo));
		double c[3];
		sscanf(placements[k], "%lf %lf %lf", &c[0], &c[1], &c[2]);
		double worst = sphere_error(&res.geo, c, 0);
		double area = 0;
		for (uint64_t q = 0; q < res.geo.nquads; q++)
			area += quad_area(&res.geo, q);
		double want = 4 * 3.14159265358979;
		quads[k] = res.geo.nquads;
		printf("unseen: sphere at (%s): %llu quads, %llu grids when culled to the view, "
		       "radius error %.2e, area %.3f%% off\n", placements[k],
		       (unsigned long long)res.geo.nquads, (unsigned long long)res.culled_grids, worst,
		       100 * fabs(area - want) / want);
		CHECK(worst <= 1e-4);
		CHECK_NEAR(area, want, 0.02 * want);
		if (k > 0)
			CHECK(res.culled_grids == 0);
		else
			CHECK(res.culled_grids == res.geo.ngrids);
		bake_shadow_geometry_free(&res.geo);
	}
	for (int k = 1; k < 3; k++) {
		double ratio = quads[0] ? (double)quads[k] / (double)quads[0] : 0;
		CHECK(ratio >= 0.25 && ratio <= 4);
	}
}

/*
 * A plane y = 0 under a displacement shader that pushes P by 0.25 along N:
 * every point ends at |y| = 0.25 (within 1e-5), all on the same side, and
 * without the shader at y = 0.
 */
static void test_displacement(void)
{
	FILE *f = fopen(tmp_path("lift.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("displacement lift(float amount = 0.25) {\n"
	      "\tP += amount * normalize(N);\n\tN = calculatenormal(P);\n}\n", f);
	fclose(f);
	for (int displaced = 0; displaced < 2; displaced++) {
		char rib[1024];
		snprintf(rib, sizeof(rib),
			 "Format 320 240 1\n"
			 "Projection \"perspective\" \"fov\" 45\n"
			 "Translate 0 0 5\n"
			 "Rotate -30 1 0 0\n"
			 "WorldBegin\n"
			 "  %s\n"
			 "  Polygon \"P\" [-1 0 -1  -1 0 1  1 0 1  1 0 -1]\n"
			 "WorldEnd\n",
			 displaced ? "Attribute \"displacementbound\" \"sphere\" 0.25 "
				     "Displacement \"lift\"" : "");
		struct result res;
		CHECK(dice(rib, 1, &res));
		CHECK(well_formed(&res.geo));
		double want = displaced ? 0.25 : 0, worst = 0, sign = 0;
		bool same_side = true, inside = true;
		for (uint64_t i = 0; i < res.geo.npoints; i++) {
			const float *p = point(&res.geo, (uint32_t)i);
			worst = fmax(worst, fabs(fabs(p[1]) - want));
			if (displaced) {
				if (sign == 0)
					sign = p[1] > 0 ? 1 : -1;
				same_side = same_side && p[1] * sign > 0;
			}
			inside = inside && fabs(p[0]) <= 1 + 1e-5 && fabs(p[2]) <= 1 + 1e-5;
		}
		printf("displacement %s: %llu points, worst |y| error %.2e (tolerance 1e-5)\n",
		       displaced ? "on" : "off", (unsigned long long)res.geo.npoints, worst);
		CHECK(worst <= 1e-5);
		CHECK(same_side);
		CHECK(inside);
		bake_shadow_geometry_free(&res.geo);
	}
}

/*
 * Lights: a shadowspot with a map name casts shadows, without one (or with
 * an empty one) it does not; neither does a point light; an uberlight with
 * a map does.
 */
static void test_lights(void)
{
	const char *rib =
		"Format 64 64 1\n"
		"WorldBegin\n"
		"  LightSource \"shadowspot\" 1 \"shadowname\" \"x.shd\"\n"
		"  LightSource \"shadowspot\" 2\n"
		"  LightSource \"shadowspot\" 3 \"shadowname\" \"\"\n"
		"  LightSource \"pointlight\" 4\n"
		"  LightSource \"uberlight\" 5 \"shadowname\" \"key.shd\"\n"
		"  LightSource \"uberlight\" 6\n"
		"  Translate 0 0 5\n"
		"  Sphere 1 -1 1 360\n"
		"WorldEnd\n";
	struct result res;
	CHECK(dice(rib, 16, &res));
	CHECK(res.nlights == 6);
	static const bool want[6] = { true, false, false, false, true, false };
	for (uint32_t i = 0; i < 6 && i < res.nlights; i++) {
		if (res.casts[i] != want[i])
			fprintf(stderr, "light %u: casts shadows %d, expected %d\n", i + 1,
				res.casts[i], want[i]);
		CHECK(res.casts[i] == want[i]);
	}
	bake_shadow_geometry_free(&res.geo);
}

/*
 * Two spheres get their own ids (their order of declaration), each id's
 * points lie on its own sphere; an object that casts no shadows is left
 * out.
 */
static void test_ids(void)
{
	const char *rib =
		"Format 320 240 1\n"
		"Projection \"perspective\" \"fov\" 45\n"
		"WorldBegin\n"
		"  AttributeBegin\n"
		"    Translate -1.5 0 6\n"
		"    Sphere 1 -1 1 360\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Attribute \"visibility\" \"transmission\" 0\n"
		"    Translate 0 2 6\n"
		"    Sphere 1 -1 1 360\n"
		"  AttributeEnd\n"
		"  AttributeBegin\n"
		"    Translate 1.5 0 6\n"
		"    Sphere 1 -1 1 360\n"
		"  AttributeEnd\n"
		"WorldEnd\n";
	struct result res;
	CHECK(dice(rib, 2, &res));
	CHECK(well_formed(&res.geo));
	uint64_t count[3] = { 0, 0, 0 }, other = 0;
	for (uint64_t q = 0; q < res.geo.nquads; q++) {
		if (res.geo.object[q] < 3)
			count[res.geo.object[q]]++;
		else
			other++;
	}
	double a[3] = { -1.5, 0, 6 }, b[3] = { 1.5, 0, 6 };
	double ea = sphere_error(&res.geo, a, 0), eb = sphere_error(&res.geo, b, 2);
	printf("ids: %llu quads of object 0, %llu of 1 (casts no shadow), %llu of 2; "
	       "radius errors %.2e %.2e\n", (unsigned long long)count[0],
	       (unsigned long long)count[1], (unsigned long long)count[2], ea, eb);
	CHECK(count[0] > 100 && count[2] > 100);
	CHECK(count[1] == 0 && other == 0);
	CHECK(ea <= 1e-4 && eb <= 1e-4);
	bake_shadow_geometry_free(&res.geo);
}

/* Bad arguments are refused with a message, and leave the result empty. */
/*
 * Opacity, what deep maps see (the grey of Oi): the Opacity attribute and a
 * constant "Os" for surfaces that set Oi = Os (plastic, the default
 * surface), the mean of a varying "Os" over a micropolygon's corners, 1 for
 * a matte object and for a surface that never sets Oi, and Os with a
 * warning at the assignment for one that computes Oi.
 */
static void test_opacity(void)
{
	FILE *f = fopen(tmp_path("noopacity.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("surface noopacity() {\n\tCi = Cs;\n}\n", f);
	fclose(f);
	f = fopen(tmp_path("halfopacity.sl"), "w");
	CHECK(f != NULL);
	if (!f)
		return;
	fputs("surface halfopacity(float k = 0.5) {\n\tCi = Cs;\n\tOi = Os * k;\n}\n", f);
	fclose(f);
	const char *rib =
		"Format 64 64 1\n"
		"Projection \"perspective\" \"fov\" 45\n"
		"Translate 0 0 5\n"
		"WorldBegin\n"
		"  LightSource \"shadowspot\" 1 \"shadowname\" \"x.shd\"\n"
		"  Surface \"plastic\"\n"
		"  AttributeBegin Opacity [0.3 0.6 0.9]\n"
		"    Polygon \"P\" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] AttributeEnd\n"
		"  Polygon \"P\" [-1 -1 1  1 -1 1  1 1 1  -1 1 1] \"constant color Os\" [0.2 0.2 0.2]\n"
		"  Polygon \"P\" [-1 -1 2  1 -1 2  1 1 2  -1 1 2]\n"
		"    \"varying color Os\" [0 0 0  0 0 0  1 1 1  1 1 1]\n"
		"  AttributeBegin Matte 1 Opacity [0.3 0.3 0.3]\n"
		"    Polygon \"P\" [-1 -1 3  1 -1 3  1 1 3  -1 1 3] AttributeEnd\n"
		"  AttributeBegin Surface \"noopacity\" Opacity [0.3 0.3 0.3]\n"
		"    Polygon \"P\" [-1 -1 4  1 -1 4  1 1 4  -1 1 4] AttributeEnd\n"
		"  AttributeBegin Surface \"halfopacity\" Opacity [0.4 0.4 0.4]\n"
		"    Polygon \"P\" [-1 -1 5  1 -1 5  1 1 5  -1 1 5] AttributeEnd\n"
		"WorldEnd\n";
	char *buf = NULL;
	size_t len = 0;
	FILE *mem = open_memstream(&buf, &len);
	struct result res;
	CHECK(dice_to(rib, 1, mem, &res));
	fclose(mem);
	CHECK(well_formed(&res.geo));
	/* per object: the smallest and largest opacity, the sum, the count */
	double lo[6], hi[6], sum[6];
	uint64_t n[6] = { 0 };
	for (int k = 0; k < 6; k++) {
		lo[k] = 2;
		hi[k] = -1;
		sum[k] = 0;
	}
	bool varying_ok = true;
	for (uint64_t q = 0; q < res.geo.nquads; q++) {
		uint32_t id = res.geo.object[q];
		if (id >= 6)
			continue;
		double o = res.geo.opacity[q];
		lo[id] = fmin(lo[id], o);
		hi[id] = fmax(hi[id], o);
		sum[id] += o;
		n[id]++;
		if (id == 2) {
			/* Os runs from 0 at y = -1 to 1 at y = 1: the corners' mean */
			double y = 0;
			for (int c = 0; c < 4; c++)
				y += point(&res.geo, res.geo.quads[4 * q + (uint64_t)c])[1] / 4.0;
			varying_ok = varying_ok && fabs(o - 0.5 * (y + 1)) <= 1e-5;
		}
	}
	static const double want[6] = { 0.6, 0.2, -1, 1, 1, 0.4 };
	for (int k = 0; k < 6; k++) {
		printf("opacity of object %d: %llu micropolygons, %.6g to %.6g, mean %.6g (want %s%g)\n",
		       k, (unsigned long long)n[k], lo[k], hi[k], n[k] ? sum[k] / (double)n[k] : 0,
		       want[k] < 0 ? "0 to 1, " : "", want[k] < 0 ? 0.5 : want[k]);
		CHECK(n[k] > 0);
		if (want[k] >= 0)
			CHECK(fabs(lo[k] - want[k]) <= 1e-6 && fabs(hi[k] - want[k]) <= 1e-6);
	}
	CHECK(varying_ok && lo[2] < 0.2 && hi[2] > 0.8);
	/* one warning, at the shader's assignment */
	const char *said = "halfopacity.sl:3: warning: surface 'halfopacity' computes Oi";
	const char *w = buf ? strstr(buf, said) : NULL;
	CHECK(w && !strstr(w + strlen(said), "computes Oi") && !strstr(buf, "plastic"));
	if (!w)
		fprintf(stderr, "the dicing said: %s\n", buf ? buf : "");
	free(buf);
	bake_shadow_geometry_free(&res.geo);
}

static void test_errors(void)
{
	struct result res;
	CHECK(!dice(sphere_rib, 0, &res));
	CHECK(res.geo.P == NULL && res.geo.npoints == 0 && res.geo.nquads == 0);
	CHECK(!dice(sphere_rib, NAN, &res));
	CHECK(res.geo.P == NULL);
	CHECK(!dice(sphere_rib, -1, &res));
}

int main(void)
{
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/relight-shadowgeo-XXXXXX");
	if (!mkdtemp(tmpdir)) {
		perror("mkdtemp");
		return 1;
	}
	if (chdir(tmpdir) != 0) {
		perror(tmpdir);
		return 1;
	}
	RUN(test_sphere);
	RUN(test_rate);
	RUN(test_unseen);
	RUN(test_displacement);
	RUN(test_lights);
	RUN(test_ids);
	RUN(test_opacity);
	RUN(test_errors);
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", tmpdir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", tmpdir);
	return test_finish();
}

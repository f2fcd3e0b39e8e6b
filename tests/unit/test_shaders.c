/*
 * The standard shader library (the .sl files in shaders/) run by the grid interpreter on
 * small grids, compared with values worked out by hand.
 *
 * Surface shaders are lit by a test host whose lights are analytic: each
 * gives a fixed direction to the light (L, from the surface point towards
 * the light) and colour (Cl), so the expected result follows from the
 * RenderMan Interface Specification's definitions alone:
 *   ambient()             = sum of Cl over ambient lights
 *   diffuse(Nf)           = sum of Cl * max(0, Nf . normalize(L))
 *   specular(Nf, V, r)    = sum of Cl * max(0, Nf . H)^(1/r), H = normalize(normalize(L) + V)
 * (diffuse and specular over the lights within 90 degrees of Nf). The test
 * host asks for that RiSpec specular model; test_plastic_prman checks
 * PRMan's, the renderer's default, where the exponent is 8/r. Light
 * shaders are run on their own: the test sets Ps and reads Cl and the lit
 * mask. Last, surfaces and light shaders run together through lighthost.h,
 * as the renderer runs them.
 *
 * Tolerance: values are computed in single precision, so results in [0, 4]
 * are compared with an absolute tolerance of TOL = 2e-5 unless noted.
 */
#include "test.h"

#include "exec.h"
#include "ir.h"
#include "lighthost.h"
#include "sl.h"

#include <stdbool.h>
#include <stdint.h>

#define TOL 2e-5
#define MAXN 8
#define DEG (3.14159265358979323846 / 180)

/* ---- the test host ---- */

struct test_light {
	bool ambient;
	float dir[3];   /* towards the light, unit length */
	float color[3];
};

struct test_host {
	struct test_light lights[4];
	int nlights;
	float texture_value[3];
	float environment_value[3];
	float shadow_value;
	int ntexture, nenvironment, nshadow;
	struct sl_tex_lookup shadow_q;   /* the last shadow lookup's options */
	char shadow_name[64];
	float env_dir[3];                /* first active point's direction */
	float tex_s[MAXN], tex_t[MAXN];  /* texture coordinates: centres of the filter regions */
	bool shader_moved;               /* "shader" space is translated by (0, 0, -1) */
};

static int host_nlights(void *user)
{
	return ((struct test_host *)user)->nlights;
}

static bool host_light(void *user, int i, struct sl_exec *surface, uint32_t n, uint32_t stride,
		       const uint8_t *mask, const float *Ps, const float *Ns, float *L, float *Cl,
		       float *Ol, uint8_t *lit, bool *ambient)
{
	const struct test_light *l = &((struct test_host *)user)->lights[i];
	(void)surface;
	(void)Ps;
	(void)Ns;
	for (uint32_t k = 0; k < n; k++) {
		if (!mask[k])
			continue;
		for (int c = 0; c < 3; c++) {
			L[c * stride + k] = l->ambient ? 0 : l->dir[c];
			Cl[c * stride + k] = l->color[c];
			Ol[c * stride + k] = 1;
		}
		lit[k] = !l->ambient;
	}
	*ambient = l->ambient;
	return true;
}

static const char *host_category(void *user, int i)
{
	(void)user;
	(void)i;
	return "";
}

/* Every space is "current" except a moved "shader" space (points: p' = p M). */
static bool host_space(void *user, const char *name, float m[16])
{
	const struct test_host *h = user;
	for (int k = 0; k < 16; k++)
		m[k] = (k % 5 == 0) ? 1.0f : 0.0f;
	if (h->shader_moved && strcmp(name, "shader") == 0)
		m[14] = -1; /* translation row: z - 1 */
	return true;
}

static void fill_lookup(const struct sl_tex_lookup *q, const float value[3])
{
	for (uint32_t k = 0; k < q->n; k++)
		if (q->mask[k])
			for (int c = 0; c < q->nchannels; c++)
				q->out[c * q->stride + k] = value[c];
}

static bool host_texture(void *user, const struct sl_tex_lookup *q)
{
	struct test_host *h = user;
	h->ntexture++;
	for (uint32_t k = 0; k < q->n && k < MAXN; k++) {
		if (!q->mask[k])
			continue;
		h->tex_s[k] = h->tex_t[k] = 0;
		for (int c = 0; c < 4; c++) {
			h->tex_s[k] += q->s[c][k] / 4;
			h->tex_t[k] += q->t[c][k] / 4;
		}
	}
	fill_lookup(q, h->texture_value);
	return true;
}

static bool host_environment(void *user, const struct sl_tex_lookup *q)
{
	struct test_host *h = user;
	h->nenvironment++;
	for (uint32_t k = 0; k < q->n; k++) {
		if (q->mask[k]) {
			for (int c = 0; c < 3; c++)
				h->env_dir[c] = q->dir[0][c * q->stride + k];
			break;
		}
	}
	fill_lookup(q, h->environment_value);
	return true;
}

static bool host_shadow(void *user, const struct sl_tex_lookup *q)
{
	struct test_host *h = user;
	h->nshadow++;
	h->shadow_q = *q;
	snprintf(h->shadow_name, sizeof(h->shadow_name), "%s", q->name ? q->name : "");
	float v[3] = { h->shadow_value, h->shadow_value, h->shadow_value };
	fill_lookup(q, v);
	return true;
}

static struct sl_host make_host(struct test_host *h)
{
	return (struct sl_host){
		.user = h,
		.nlights = host_nlights,
		.light = host_light,
		.light_category = host_category,
		.space = host_space,
		.texture = host_texture,
		.environment = host_environment,
		.shadow = host_shadow,
		.specular_model = SL_SPECULAR_RISPEC,
	};
}

/* ---- grids ---- */

/* One grid of points, as the renderer would give it (the eye at the origin). */
struct scene {
	uint32_t nu, nv;
	float P[MAXN][3], N[MAXN][3], Cs[MAXN][3], Os[MAXN][3];
	float s[MAXN], t[MAXN];
};

static struct sl_program *load(const char *name)
{
	const char *src = getenv("RELIGHT_SOURCE_DIR");
	char path[1024];
	snprintf(path, sizeof(path), "%s/shaders/%s.sl", src ? src : ".", name);
	struct sl_program *prog = sl_compile_file(path, NULL);
	if (!prog)
		fprintf(stderr, "cannot compile %s\n", path);
	return prog;
}

/* Write per-point triples into global @g (either layout); skipped if unused. */
static void put3(struct sl_exec *x, enum sl_global g, uint32_t n, const float (*v)[3])
{
	bool varying;
	float *d = sl_exec_global(x, g, &varying);
	if (!d)
		return;
	uint32_t stride = sl_exec_stride(x);
	for (int c = 0; c < 3; c++) {
		if (!varying)
			d[c] = v[0][c];
		else
			for (uint32_t i = 0; i < n; i++)
				d[c * stride + i] = v[i][c];
	}
}

static void put1(struct sl_exec *x, enum sl_global g, uint32_t n, const float *v)
{
	bool varying;
	float *d = sl_exec_global(x, g, &varying);
	if (!d)
		return;
	if (!varying)
		d[0] = v[0];
	else
		for (uint32_t i = 0; i < n; i++)
			d[i] = v[i];
}

/* Component @c of global @g at point @i (NaN when the program lacks @g). */
static float get(struct sl_exec *x, enum sl_global g, uint32_t i, int c)
{
	bool varying;
	float *d = sl_exec_global(x, g, &varying);
	if (!d)
		return NAN;
	return varying ? d[(size_t)c * sl_exec_stride(x) + i] : d[c];
}

/* Set the globals a surface shader reads from @sc. */
static void setup_surface(struct sl_exec *x, const struct scene *sc)
{
	uint32_t n = sc->nu * sc->nv;
	float zero[MAXN][3] = { { 0 } };
	float u[MAXN], v[MAXN], du[MAXN], dv[MAXN];
	float dpdu[MAXN][3], dpdv[MAXN][3];
	for (uint32_t i = 0; i < n; i++) {
		u[i] = sc->nu > 1 ? (float)(i % sc->nu) / (float)(sc->nu - 1) : 0;
		v[i] = sc->nv > 1 ? (float)(i / sc->nu) / (float)(sc->nv - 1) : 0;
		du[i] = sc->nu > 1 ? 1.0f / (float)(sc->nu - 1) : 1;
		dv[i] = sc->nv > 1 ? 1.0f / (float)(sc->nv - 1) : 1;
		dpdu[i][0] = 1, dpdu[i][1] = 0, dpdu[i][2] = 0;
		dpdv[i][0] = 0, dpdv[i][1] = 1, dpdv[i][2] = 0;
	}
	put3(x, SL_GLOBAL_P, n, sc->P);
	put3(x, SL_GLOBAL_N, n, sc->N);
	put3(x, SL_GLOBAL_NG, n, sc->N);
	put3(x, SL_GLOBAL_I, n, sc->P); /* eye at the origin: I = P - E = P */
	put3(x, SL_GLOBAL_E, n, zero);
	put3(x, SL_GLOBAL_CS, n, sc->Cs);
	put3(x, SL_GLOBAL_OS, n, sc->Os);
	put1(x, SL_GLOBAL_S, n, sc->s);
	put1(x, SL_GLOBAL_T, n, sc->t);
	put1(x, SL_GLOBAL_U, n, u);
	put1(x, SL_GLOBAL_V, n, v);
	put1(x, SL_GLOBAL_DU, n, du);
	put1(x, SL_GLOBAL_DV, n, dv);
	put3(x, SL_GLOBAL_DPDU, n, dpdu);
	put3(x, SL_GLOBAL_DPDV, n, dpdv);
}

/* Points on the plane z = 5 facing the eye, normals tilted about y by @tilt_deg[i]. */
static struct scene facing_scene(uint32_t n, const double *tilt_deg)
{
	struct scene sc = { .nu = n, .nv = 1 };
	for (uint32_t i = 0; i < n; i++) {
		double b = tilt_deg[i] * DEG;
		sc.P[i][0] = 0, sc.P[i][1] = 0, sc.P[i][2] = 5;
		sc.N[i][0] = (float)sin(b), sc.N[i][1] = 0, sc.N[i][2] = (float)-cos(b);
		sc.Cs[i][0] = 1, sc.Cs[i][1] = 0.5f, sc.Cs[i][2] = 0.25f;
		sc.Os[i][0] = sc.Os[i][1] = sc.Os[i][2] = 1;
		sc.s[i] = 0.5f, sc.t[i] = 0.5f;
	}
	return sc;
}

/* A distant light whose direction towards the light is @angle_deg off -z, about y. */
static struct test_light distant(double angle_deg, float r, float g, float b)
{
	double a = angle_deg * DEG;
	return (struct test_light){
		.dir = { (float)sin(a), 0, (float)-cos(a) },
		.color = { r, g, b },
	};
}

static struct test_light ambient_light(float r, float g, float b)
{
	return (struct test_light){ .ambient = true, .color = { r, g, b } };
}

static bool set(struct sl_exec *x, const char *name, float v)
{
	return sl_exec_set_param(x, name, &v, 1);
}

/* Run surface shader @prog over @sc; false if it did not run. */
static bool run_surface_host(struct sl_exec *x, const struct scene *sc,
			     const struct sl_host *host)
{
	if (!sl_exec_set_grid(x, sc->nu, sc->nv))
		return false;
	setup_surface(x, sc);
	return sl_exec_run(x, host);
}

static bool run_surface(struct sl_exec *x, const struct scene *sc, struct test_host *th)
{
	struct sl_host host = make_host(th);
	return run_surface_host(x, sc, &host);
}

static void check_color(struct sl_exec *x, enum sl_global g, uint32_t i, double r, double gg,
			double b, double tol)
{
	CHECK_NEAR(get(x, g, i, 0), r, tol);
	CHECK_NEAR(get(x, g, i, 1), gg, tol);
	CHECK_NEAR(get(x, g, i, 2), b, tol);
}

/* ---- surface shaders ---- */

static void test_constant(void)
{
	struct sl_program *prog = load("constant");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	double tilt[2] = { 0, 0 };
	struct scene sc = facing_scene(2, tilt);
	/* Point 1: another colour and half opacity. */
	sc.Cs[1][0] = 0.2f, sc.Cs[1][1] = 0.4f, sc.Cs[1][2] = 0.6f;
	sc.Os[1][0] = sc.Os[1][1] = sc.Os[1][2] = 0.5f;
	struct test_host th = { .nlights = 1, .lights = { distant(0, 5, 5, 5) } };
	CHECK(run_surface(x, &sc, &th));
	/* Ci = Os * Cs, whatever the lights. */
	check_color(x, SL_GLOBAL_CI, 0, 1, 0.5, 0.25, TOL);
	check_color(x, SL_GLOBAL_CI, 1, 0.1, 0.2, 0.3, TOL);
	check_color(x, SL_GLOBAL_OI, 1, 0.5, 0.5, 0.5, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_matte(void)
{
	struct sl_program *prog = load("matte");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	/*
	 * One distant light straight along -N (L = (0, 0, -1)), intensity 1, and
	 * an ambient light of 0.1. Normals tilted by b from -z, so Nf . L = cos b:
	 *   Ci = Cs * (Ka * 0.1 + Kd * cos b), Ka = 1, Kd = 0.8
	 *   b = 0: 0.9; b = 60: 0.5; b = 85: 0.1 + 0.8 * 0.0871557 = 0.1697246
	 * The fourth normal points away from the eye (tilt 180: N = (0, 0, 1)):
	 * faceforward flips it back to -z, so it is lit like b = 0.
	 */
	double tilt[4] = { 0, 60, 85, 180 };
	struct scene sc = facing_scene(4, tilt);
	struct test_host th = { .nlights = 2,
				.lights = { distant(0, 1, 1, 1), ambient_light(0.1f, 0.1f, 0.1f) } };
	CHECK(set(x, "Kd", 0.8f));
	CHECK(run_surface(x, &sc, &th));
	const double k[4] = { 0.9, 0.5, 0.1 + 0.8 * 0.0871557427, 0.9 };
	for (uint32_t i = 0; i < 4; i++)
		check_color(x, SL_GLOBAL_CI, i, k[i] * 1, k[i] * 0.5, k[i] * 0.25, TOL);
	check_color(x, SL_GLOBAL_OI, 0, 1, 1, 1, TOL);

	/* A light behind the surface (100 degrees off the normal) adds nothing. */
	th.lights[0] = distant(100, 1, 1, 1);
	CHECK(run_surface(x, &sc, &th));
	check_color(x, SL_GLOBAL_CI, 0, 0.1, 0.05, 0.025, TOL);

	/* No lights at all: black. */
	th.nlights = 0;
	CHECK(run_surface(x, &sc, &th));
	check_color(x, SL_GLOBAL_CI, 0, 0, 0, 0, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/*
 * The plastic scene: a light 60 degrees off the view axis (L = (sin 60, 0,
 * -cos 60)), V = (0, 0, -1), normals tilted by b. Then Nf . L = cos(60 - b)
 * and H lies 30 degrees off the axis, so Nf . H = cos(30 - b); with
 * roughness 0.1 the specular term is cos(30 - b)^10:
 *   b = 30 (the mirror direction): diffuse cos 30 = 0.8660254, specular 1
 *   b = 0:   diffuse 0.5,        specular cos(30)^10 = 0.2373047
 *   b = -20: diffuse cos 80 = 0.1736482, specular cos(50)^10 = 0.0120413
 */
static const double plastic_tilt[3] = { 30, 0, -20 };
static const double plastic_diffuse[3] = { 0.8660254038, 0.5, 0.1736481777 };
static const double plastic_specular[3] = { 1.0, 0.2373046875, 0.0120413441 };

static void test_plastic(void)
{
	struct sl_program *prog = load("plastic");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	struct scene sc = facing_scene(3, plastic_tilt);
	struct test_host th = { .nlights = 1, .lights = { distant(60, 1, 1, 1) } };
	CHECK(run_surface(x, &sc, &th));
	/* Ci = Cs * Kd * diffuse + specularcolor * Ks * specular, Kd = Ks = 0.5, no ambient. */
	for (uint32_t i = 0; i < 3; i++) {
		double d = 0.5 * plastic_diffuse[i], sp = 0.5 * plastic_specular[i];
		check_color(x, SL_GLOBAL_CI, i, d * 1 + sp, d * 0.5 + sp, d * 0.25 + sp, TOL);
	}

	/* A red specular colour and roughness 0.2 (exponent 5): at b = 0,
	 * specular = cos(30)^5 = 0.4871393. */
	float red[3] = { 1, 0, 0 };
	CHECK(sl_exec_set_param(x, "specularcolor", red, 3));
	CHECK(set(x, "roughness", 0.2f));
	CHECK(run_surface(x, &sc, &th));
	double sp = 0.5 * 0.4871392896, d = 0.5 * 0.5;
	check_color(x, SL_GLOBAL_CI, 1, d + sp, d * 0.5, d * 0.25, TOL);
	/* At the mirror direction the highlight is the light's colour times Ks. */
	d = 0.5 * plastic_diffuse[0];
	check_color(x, SL_GLOBAL_CI, 0, d + 0.5, d * 0.5, d * 0.25, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/*
 * plastic under PRMan's specular model (exponent 8 / roughness), the
 * renderer's default, in the plastic scene with normals tilted by b = 30,
 * 20 and 25 degrees: Nf . H = cos(30 - b), and at roughness 0.1 the
 * specular term is cos(30 - b)^80: 1, cos(10)^80 = 0.2938439,
 * cos(5)^80 = 0.7371198. At roughness 0.8 it is cos(30 - b)^10, the RiSpec
 * model's highlight at 0.1.
 */
static void test_plastic_prman(void)
{
	struct sl_program *prog = load("plastic");
	CHECK(prog != NULL);
	if (!prog)
		return;
	static const double tilt[3] = { 30, 20, 25 };
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	struct scene sc = facing_scene(3, tilt);
	struct test_host th = { .nlights = 1, .lights = { distant(60, 1, 1, 1) } };
	struct sl_host host = make_host(&th);
	host.specular_model = SL_SPECULAR_PRMAN;
	static const float rough[2] = { 0.1f, 0.8f };
	static const double exponent[2] = { 80, 10 };
	for (int k = 0; k < 2; k++) {
		CHECK(set(x, "roughness", rough[k]));
		CHECK(run_surface_host(x, &sc, &host));
		for (uint32_t i = 0; i < 3; i++) {
			double b = tilt[i] * DEG;
			double d = 0.5 * cos(60 * DEG - b);
			double sp = 0.5 * pow(cos(30 * DEG - b), exponent[k]);
			check_color(x, SL_GLOBAL_CI, i, d * 1 + sp, d * 0.5 + sp, d * 0.25 + sp, TOL);
		}
	}
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_metal(void)
{
	struct sl_program *prog = load("metal");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	struct scene sc = facing_scene(3, plastic_tilt);
	struct test_host th = { .nlights = 2,
				.lights = { distant(60, 2, 2, 2), ambient_light(0.1f, 0.1f, 0.1f) } };
	CHECK(run_surface(x, &sc, &th));
	/* Ci = Cs * (Ka * 0.1 + Ks * 2 * specular), Ka = Ks = 1: metal highlights take Cs. */
	for (uint32_t i = 0; i < 3; i++) {
		double k = 0.1 + 2 * plastic_specular[i];
		check_color(x, SL_GLOBAL_CI, i, k, k * 0.5, k * 0.25, 4 * TOL);
	}
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_shinymetal(void)
{
	struct sl_program *prog = load("shinymetal");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	double tilt[2] = { 0, 0 };
	struct scene sc = facing_scene(2, tilt);
	struct test_host th = { .environment_value = { 0.2f, 0.4f, 0.8f } };

	/* No map: the environment is not looked up; no lights: black. */
	CHECK(run_surface(x, &sc, &th));
	CHECK(th.nenvironment == 0);
	check_color(x, SL_GLOBAL_CI, 0, 0, 0, 0, TOL);

	/* With a map and Kr = 0.5: Ci = Cs * Kr * env = (0.1, 0.1, 0.1). */
	CHECK(sl_exec_set_param_string(x, "texturename", "studio.env"));
	CHECK(set(x, "Kr", 0.5f));
	CHECK(run_surface(x, &sc, &th));
	CHECK(th.nenvironment >= 1);
	check_color(x, SL_GLOBAL_CI, 0, 0.1, 0.1, 0.1, TOL);
	/* Head-on, I = (0, 0, 5) reflects straight back: the lookup direction is -z. */
	double len = sqrt(th.env_dir[0] * th.env_dir[0] + th.env_dir[1] * th.env_dir[1] +
			  th.env_dir[2] * th.env_dir[2]);
	CHECK(len > 0);
	if (len > 0) {
		CHECK_NEAR(th.env_dir[0] / len, 0, 1e-5);
		CHECK_NEAR(th.env_dir[2] / len, -1, 1e-5);
	}
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_paintedplastic(void)
{
	struct sl_program *prog = load("paintedplastic");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	/* A 2x2 grid (texture filtering takes derivatives of s and t). */
	double tilt[4] = { 0, 0, 0, 0 };
	struct scene sc = facing_scene(4, tilt);
	sc.nu = 2, sc.nv = 2;
	for (uint32_t i = 0; i < 4; i++)
		sc.s[i] = (float)(i % 2) * 0.1f, sc.t[i] = (float)(i / 2) * 0.1f;
	struct test_host th = { .nlights = 1, .lights = { distant(0, 1, 1, 1) },
				.texture_value = { 0.5f, 1, 0.2f } };

	/* Without a map it is plastic: head-on, diffuse = specular = 1:
	 * Ci = 0.5 * Cs + 0.5. */
	CHECK(run_surface(x, &sc, &th));
	CHECK(th.ntexture == 0);
	check_color(x, SL_GLOBAL_CI, 3, 1.0, 0.75, 0.625, TOL);

	/* With a map the base colour is Cs * texture = (0.5, 0.5, 0.05):
	 * Ci = 0.5 * (0.5, 0.5, 0.05) + 0.5. */
	CHECK(sl_exec_set_param_string(x, "texturename", "paint.tex"));
	CHECK(run_surface(x, &sc, &th));
	CHECK(th.ntexture >= 1);
	for (uint32_t i = 0; i < 4; i++)
		check_color(x, SL_GLOBAL_CI, i, 0.75, 0.75, 0.525, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_defaultsurface(void)
{
	struct sl_program *prog = load("defaultsurface");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	/*
	 * No lights needed. d = normalize(I) . normalize(N) = -cos b:
	 * Ci = Cs * (Ka + Kd * d^2) = Cs * (0.2 + 0.8 cos^2 b):
	 *   b = 0: 1; b = 60: 0.4; b = 90: 0.2
	 */
	double tilt[3] = { 0, 60, 90 };
	struct scene sc = facing_scene(3, tilt);
	struct test_host th = { 0 };
	CHECK(run_surface(x, &sc, &th));
	const double k[3] = { 1, 0.4, 0.2 };
	for (uint32_t i = 0; i < 3; i++)
		check_color(x, SL_GLOBAL_CI, i, k[i], k[i] * 0.5, k[i] * 0.25, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/* ---- light shaders ---- */

/* Run light @x at the points @Ps; the host answers "shader" space queries. */
static bool run_light(struct sl_exec *x, uint32_t n, const float (*Ps)[3], struct test_host *th)
{
	struct sl_host host = make_host(th);
	if (!sl_exec_set_grid(x, n, 1))
		return false;
	put3(x, SL_GLOBAL_PS, n, Ps);
	return sl_exec_run(x, &host);
}

/* Cl at point @i, 0 where the light did not reach it. */
static float light_cl(struct sl_exec *x, uint32_t i, int c)
{
	const uint8_t *lit = sl_exec_lit_mask(x);
	if (!lit || !lit[i])
		return 0;
	return get(x, SL_GLOBAL_CL, i, c);
}

static void test_ambientlight(void)
{
	struct sl_program *prog = load("ambientlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	const float Ps[1][3] = { { 1, 2, 3 } };
	struct test_host th = { 0 };
	float color[3] = { 1, 0.5f, 0.25f };
	CHECK(set(x, "intensity", 0.4f));
	CHECK(sl_exec_set_param(x, "lightcolor", color, 3));
	CHECK(run_light(x, 1, Ps, &th));
	/* No illuminate or solar: an ambient light. Cl = intensity * lightcolor. */
	CHECK(sl_exec_is_ambient(x));
	check_color(x, SL_GLOBAL_CL, 0, 0.4, 0.2, 0.1, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_distantlight(void)
{
	struct sl_program *prog = load("distantlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	/* Light travelling along +x (from the origin to (1, 0, 0)), intensity 2. */
	const float Ps[3][3] = { { 0, 0, 1 }, { 5, -3, 2 }, { -100, 0, 0 } };
	float to[3] = { 1, 0, 0 };
	CHECK(sl_exec_set_param(x, "to", to, 3));
	CHECK(set(x, "intensity", 2));
	struct test_host th = { 0 };
	CHECK(run_light(x, 3, Ps, &th));
	CHECK(!sl_exec_is_ambient(x));
	/* No falloff: Cl = 2 everywhere; L is along the direction of travel. */
	for (uint32_t i = 0; i < 3; i++) {
		check_color(x, SL_GLOBAL_CL, i, 2, 2, 2, TOL);
		float lx = get(x, SL_GLOBAL_L, i, 0), ly = get(x, SL_GLOBAL_L, i, 1),
		      lz = get(x, SL_GLOBAL_L, i, 2);
		CHECK(lx > 0);
		CHECK_NEAR(ly, 0, TOL);
		CHECK_NEAR(lz, 0, TOL);
	}
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_pointlight(void)
{
	struct sl_program *prog = load("pointlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	/* At (0, 0, 1), lightcolor (1, 0.5, 0.25), intensity 1: Cl = lightcolor / d^2. */
	float from[3] = { 0, 0, 1 };
	float color[3] = { 1, 0.5f, 0.25f };
	CHECK(sl_exec_set_param(x, "from", from, 3));
	CHECK(sl_exec_set_param(x, "lightcolor", color, 3));
	/* d = 2, 0.5, 3 (behind the light: a point light shines everywhere), 5 */
	const float Ps[4][3] = { { 0, 0, 3 }, { 0.5f, 0, 1 }, { 0, 0, -2 }, { 3, 4, 1 } };
	const double inv_d2[4] = { 0.25, 4, 1.0 / 9, 1.0 / 25 };
	struct test_host th = { 0 };
	CHECK(run_light(x, 4, Ps, &th));
	for (uint32_t i = 0; i < 4; i++) {
		CHECK_NEAR(light_cl(x, i, 0), inv_d2[i], TOL * 4 * inv_d2[i]);
		CHECK_NEAR(light_cl(x, i, 2), 0.25 * inv_d2[i], TOL * inv_d2[i]);
	}
	/* L runs from the light to the surface point: at point 0, (0, 0, 2). */
	CHECK_NEAR(get(x, SL_GLOBAL_L, 0, 2), 2, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/*
 * A spot light at the origin aimed down +z, coneangle 30, conedeltaangle 5,
 * beamdistribution 2 (the defaults). At angle a off the axis and distance d:
 *   Cl = cos(a)^2 / d^2 * smoothstep(cos 30, cos 25, cos a)
 *   a = 0,    d = 2: 0.25
 *   a = 10,   d = 2: cos^2(10) / 4 = 0.2424616 (inside the inner cone)
 *   a = 27.5, d = 2: smoothstep's t = (0.8870108 - 0.8660254) / (0.9063078 -
 *                    0.8660254) = 0.5209565, weight 0.5314217:
 *                    0.7867882 * 0.5314217 / 4 = 0.1045285
 *   a = 29,   d = 1: 0.0896024
 *   a = 35:          outside the cone: not lit
 */
static const double spot_angle[5] = { 0, 10, 27.5, 29, 35 };
static const double spot_dist[5] = { 2, 2, 2, 1, 2 };
static const double spot_cl[5] = { 0.25, 0.2424615776, 0.1045284681, 0.0896023716, 0 };

static void spot_points(float (*Ps)[3])
{
	for (int i = 0; i < 5; i++) {
		double a = spot_angle[i] * DEG;
		Ps[i][0] = (float)(spot_dist[i] * sin(a));
		Ps[i][1] = 0;
		Ps[i][2] = (float)(spot_dist[i] * cos(a));
	}
}

static void test_spotlight(void)
{
	struct sl_program *prog = load("spotlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	float Ps[5][3];
	spot_points(Ps);
	struct test_host th = { 0 };
	CHECK(run_light(x, 5, (const float (*)[3])Ps, &th));
	const uint8_t *lit = sl_exec_lit_mask(x);
	CHECK(lit != NULL);
	if (lit) {
		CHECK(lit[0] && lit[1] && lit[2] && lit[3]);
		CHECK(!lit[4]);
	}
	for (int i = 0; i < 5; i++)
		CHECK_NEAR(light_cl(x, (uint32_t)i, 1), spot_cl[i], TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_shadowspot(void)
{
	struct sl_program *prog = load("shadowspot");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	float Ps[5][3];
	spot_points(Ps);
	struct test_host th = { .shadow_value = 0.25f };

	/* With no map it is the spotlight, and no shadow lookup is made. */
	CHECK(run_light(x, 5, (const float (*)[3])Ps, &th));
	CHECK(th.nshadow == 0);
	for (int i = 0; i < 5; i++)
		CHECK_NEAR(light_cl(x, (uint32_t)i, 0), spot_cl[i], TOL);

	/* A map that shadows a quarter of each point: Cl * 0.75, with the options passed on. */
	CHECK(sl_exec_set_param_string(x, "shadowname", "key.shd"));
	CHECK(set(x, "samples", 32));
	CHECK(set(x, "blur", 0.01f));
	CHECK(set(x, "bias", 0.05f));
	CHECK(set(x, "width", 2));
	CHECK(run_light(x, 5, (const float (*)[3])Ps, &th));
	CHECK(th.nshadow >= 1);
	CHECK_STR(th.shadow_name, "key.shd");
	CHECK_NEAR(th.shadow_q.samples, 32, 0);
	CHECK_NEAR(th.shadow_q.blur, 0.01, 1e-7);
	CHECK_NEAR(th.shadow_q.bias, 0.05, 1e-7);
	CHECK_NEAR(th.shadow_q.width, 2, 0);
	for (int i = 0; i < 5; i++)
		CHECK_NEAR(light_cl(x, (uint32_t)i, 0), 0.75 * spot_cl[i], TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/* ---- uberlight ---- */

/*
 * The uberlight's factors checked one at a time, each with the others made
 * neutral: a spot at the origin of "shader" space aimed down +z, intensity
 * 1, no falloff, beamdistribution 0, cut-on 0.01.
 */
static struct sl_exec *uberlight(struct sl_program *prog)
{
	struct sl_exec *x = sl_exec_create(prog, MAXN);
	return x;
}

static void test_uberlight_cut(void)
{
	struct sl_program *prog = load("uberlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = uberlight(prog);
	/*
	 * cuton 1 with nearedge 0.5, cutoff 4 with faredge 2, points on the axis
	 * (wide shape so it does not interfere):
	 *   z = 0.4: before cuton - nearedge: 0
	 *   z = 0.75: smoothstep(0.5, 1, 0.75) = 0.5
	 *   z = 2: 1
	 *   z = 5: 1 - smoothstep(4, 6, 5) = 0.5
	 *   z = 6.5: past cutoff + faredge: 0
	 */
	CHECK(set(x, "cuton", 1));
	CHECK(set(x, "nearedge", 0.5f));
	CHECK(set(x, "cutoff", 4));
	CHECK(set(x, "faredge", 2));
	const float Ps[5][3] = { { 0, 0, 0.4f }, { 0, 0, 0.75f }, { 0, 0, 2 }, { 0, 0, 5 },
				 { 0, 0, 6.5f } };
	const double expect[5] = { 0, 0.5, 1, 0.5, 0 };
	struct test_host th = { 0 };
	CHECK(run_light(x, 5, Ps, &th));
	for (uint32_t i = 0; i < 5; i++)
		CHECK_NEAR(light_cl(x, i, 0), expect[i], TOL);

	/*
	 * Hard cuts (no edges): z = 0.99 is dark, z = 1.01 lit, z = 4.01 dark.
	 * A spot cuts by depth along its axis, not by distance: (3, 0, 3), at
	 * distance 4.24 but depth 3, is lit (the shape made wide enough).
	 */
	CHECK(set(x, "nearedge", 0));
	CHECK(set(x, "faredge", 0));
	CHECK(set(x, "width", 10));
	CHECK(set(x, "height", 10));
	const float Ps2[4][3] = { { 0, 0, 0.99f }, { 0, 0, 1.01f }, { 0, 0, 4.01f }, { 3, 0, 3 } };
	CHECK(run_light(x, 4, Ps2, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 0, TOL);
	CHECK_NEAR(light_cl(x, 1, 0), 1, TOL);
	CHECK_NEAR(light_cl(x, 2, 0), 0, TOL);
	CHECK_NEAR(light_cl(x, 3, 0), 1, TOL);

	/* An omni light cuts by distance: (3, 0, 3) is past cutoff 4; (0, 3, 0) is lit. */
	CHECK(sl_exec_set_param_string(x, "lighttype", "omni"));
	const float Ps2b[2][3] = { { 3, 0, 3 }, { 0, 3, 0 } };
	CHECK(run_light(x, 2, Ps2b, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 0, TOL);
	CHECK_NEAR(light_cl(x, 1, 0), 1, TOL);
	CHECK(sl_exec_set_param_string(x, "lighttype", "spot"));

	/*
	 * The light moved to z = -1 by its "shader" space: the same depths are
	 * now measured from there, so z = 1 in current space is depth 2 (lit)
	 * and z = -0.5 is depth 0.5 (dark, before cuton).
	 */
	th.shader_moved = true;
	const float Ps3[2][3] = { { 0, 0, 1 }, { 0, 0, -0.5f } };
	CHECK(run_light(x, 2, Ps3, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 1, TOL);
	CHECK_NEAR(light_cl(x, 1, 0), 0, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_uberlight_shape(void)
{
	struct sl_program *prog = load("uberlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = uberlight(prog);
	struct test_host th = { 0 };
	/*
	 * Points on the plane z = 1, so (x, y) is the projected position.
	 * width = height = 1, wedge = hedge = 1, roundness 1 (ellipses):
	 *   (0.5, 0):  inside the inner circle: 1
	 *   (1.5, 0):  inner radius 1.5, outer 0.75; the fraction along the ray
	 *              between the curves is 0.75 * 0.5 / 0.75 = 0.5: 1 -
	 *              smoothstep(0.5) = 0.5
	 *   (0.9, 0.9): inner 1.2727922, outer 0.6363961, fraction 0.2727922:
	 *              1 - 0.2727922^2 * (3 - 2 * 0.2727922) = 0.8173532
	 *   (2.5, 0):  outside the outer circle: 0
	 */
	CHECK(set(x, "wedge", 1));
	CHECK(set(x, "hedge", 1));
	const float Ps[4][3] = { { 0.5f, 0, 1 }, { 1.5f, 0, 1 }, { 0.9f, 0.9f, 1 }, { 2.5f, 0, 1 } };
	const double round_expect[4] = { 1, 0.5, 0.8173532215, 0 };
	CHECK(run_light(x, 4, Ps, &th));
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(light_cl(x, i, 0), round_expect[i], 1e-4);

	/*
	 * roundness 0 (rectangles): the radius is max(|x|, |y|), so (0.9, 0.9)
	 * is fully inside; (1.2, 0.5) has inner 1.2, outer 0.6, fraction 0.2:
	 * 1 - 0.04 * 2.6 = 0.896.
	 */
	CHECK(set(x, "roundness", 0));
	const float Ps2[2][3] = { { 0.9f, 0.9f, 1 }, { 1.2f, 0.5f, 1 } };
	CHECK(run_light(x, 2, Ps2, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 1, 1e-4);
	CHECK_NEAR(light_cl(x, 1, 0), 0.896, 1e-4);

	/* Behind a spot light (z < 0): not lit at all. */
	const float Ps3[1][3] = { { 0.1f, 0, -1 } };
	CHECK(run_light(x, 1, Ps3, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 0, TOL);

	/* An omni light ignores the shape and lights all round: 1 behind it too. */
	CHECK(sl_exec_set_param_string(x, "lighttype", "omni"));
	CHECK(run_light(x, 1, Ps3, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 1, TOL);
	const float Ps4[1][3] = { { 2.5f, 0, 1 } };
	CHECK(run_light(x, 1, Ps4, &th));
	CHECK_NEAR(light_cl(x, 0, 0), 1, TOL);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_uberlight_barndoors(void)
{
	struct sl_program *prog = load("uberlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = uberlight(prog);
	struct test_host th = { 0 };
	/*
	 * A wide shape (width = height = 10) and barn doors on the plane z = 1:
	 * right flap at x = 0.4 and top flap at y = 0.2, softened over 0.2; the
	 * left and bottom flaps open (their defaults):
	 *   (0.3, 0):   inside: 1
	 *   (0.5, 0):   halfway through the right edge: 1 - smoothstep(0.4, 0.6, 0.5) = 0.5
	 *   (0.6, 0):   past it: 0
	 *   (-3, 0):    far left, left flap open: 1
	 *   (0, 0.25):  a quarter into the top edge: 1 - smoothstep(0.2, 0.4, 0.25)
	 *               = 1 - 0.25^2 * 2.5 = 0.84375
	 *   (0.5, 0.25): both edges: 0.5 * 0.84375 = 0.421875
	 * The same on the plane z = 2 at twice the x and y: the flaps cut angles.
	 */
	CHECK(set(x, "width", 10));
	CHECK(set(x, "height", 10));
	CHECK(set(x, "barnright", 0.4f));
	CHECK(set(x, "barntop", 0.2f));
	CHECK(set(x, "barnedge", 0.2f));
	const float Ps[7][3] = { { 0.3f, 0, 1 }, { 0.5f, 0, 1 }, { 0.6f, 0, 1 }, { -3, 0, 1 },
				 { 0, 0.25f, 1 }, { 0.5f, 0.25f, 1 }, { 1.0f, 0.5f, 2 } };
	const double expect[7] = { 1, 0.5, 0, 1, 0.84375, 0.421875, 0.421875 };
	CHECK(run_light(x, 7, Ps, &th));
	for (uint32_t i = 0; i < 7; i++)
		CHECK_NEAR(light_cl(x, i, 0), expect[i], 1e-4);

	/*
	 * The left flap at x = -0.3 and the bottom one at y = -0.1:
	 *   (-0.4, 0):   halfway through the left edge: smoothstep(-0.5, -0.3, -0.4) = 0.5
	 *   (-3, 0):     now blocked: 0
	 *   (0, -0.15):  a quarter into the bottom edge: 0.84375
	 */
	CHECK(set(x, "barnleft", 0.3f));
	CHECK(set(x, "barnbottom", 0.1f));
	const float Ps2[3][3] = { { -0.4f, 0, 1 }, { -3, 0, 1 }, { 0, -0.15f, 1 } };
	const double expect2[3] = { 0.5, 0, 0.84375 };
	CHECK(run_light(x, 3, Ps2, &th));
	for (uint32_t i = 0; i < 3; i++)
		CHECK_NEAR(light_cl(x, i, 0), expect2[i], 1e-4);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_uberlight_falloff(void)
{
	struct sl_program *prog = load("uberlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = uberlight(prog);
	struct test_host th = { .shadow_value = 1 };
	/*
	 * falloff 2 (inverse square) from falloffdist 1, capped at maxintensity
	 * 2, on the axis: d = 2: 0.25; d = 4: 0.0625; d = 0.5: 4 capped to 2.
	 * beamdistribution 4 off the axis: (0.6, 0, 0.8) at d = 1 has cos 0.8,
	 * 0.8^4 = 0.4096.
	 */
	CHECK(set(x, "falloff", 2));
	CHECK(set(x, "maxintensity", 2));
	CHECK(set(x, "beamdistribution", 4));
	const float Ps[4][3] = { { 0, 0, 2 }, { 0, 0, 4 }, { 0, 0, 0.5f }, { 0.6f, 0, 0.8f } };
	const double expect[4] = { 0.25, 0.0625, 2, 0.4096 };
	CHECK(run_light(x, 4, Ps, &th));
	for (uint32_t i = 0; i < 4; i++)
		CHECK_NEAR(light_cl(x, i, 0), expect[i], 1e-4);

	/*
	 * A full shadow tinted by shadowcolor (0.2, 0.3, 0.4): Cl *= shadowcolor.
	 * intensity 3, lightcolor (1, 0.5, 1), at d = 2 on the axis:
	 * 3 * (1, 0.5, 1) * 0.25 * (0.2, 0.3, 0.4) = (0.15, 0.1125, 0.3).
	 */
	float shadowcolor[3] = { 0.2f, 0.3f, 0.4f }, color[3] = { 1, 0.5f, 1 };
	CHECK(sl_exec_set_param(x, "shadowcolor", shadowcolor, 3));
	CHECK(sl_exec_set_param(x, "lightcolor", color, 3));
	CHECK(set(x, "intensity", 3));
	CHECK(sl_exec_set_param_string(x, "shadowname", "spot.shd"));
	CHECK(run_light(x, 1, Ps, &th));
	CHECK(th.nshadow >= 1);
	CHECK_NEAR(light_cl(x, 0, 0), 0.15, 1e-4);
	CHECK_NEAR(light_cl(x, 0, 1), 0.1125, 1e-4);
	CHECK_NEAR(light_cl(x, 0, 2), 0.3, 1e-4);
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

static void test_uberlight_slide(void)
{
	struct sl_program *prog = load("uberlight");
	CHECK(prog != NULL);
	if (!prog)
		return;
	struct sl_exec *x = uberlight(prog);
	/*
	 * A slide tints the beam by the texture's colour: Cl = (0.5, 1, 0.25).
	 * It spans the shape's width x height rectangle, s left to right and t
	 * top to bottom: with width = height = 1, (x, y) = (0, 0) reads
	 * (s, t) = (0.5, 0.5); (0.5, 0.5) reads (0.75, 0.25); (-0.5, 0) reads
	 * (0.25, 0.5). Tolerance 1e-5 (centres of the filter regions).
	 */
	struct test_host th = { .texture_value = { 0.5f, 1, 0.25f } };
	CHECK(sl_exec_set_param_string(x, "slidename", "gobo.tex"));
	const float Ps[3][3] = { { 0, 0, 1 }, { 0.5f, 0.5f, 1 }, { -0.5f, 0, 1 } };
	CHECK(run_light(x, 3, Ps, &th));
	CHECK(th.ntexture >= 1);
	check_color(x, SL_GLOBAL_CL, 0, 0.5, 1, 0.25, 1e-4);
	const double es[3] = { 0.5, 0.75, 0.25 }, et[3] = { 0.5, 0.25, 0.5 };
	for (int i = 0; i < 3; i++) {
		CHECK_NEAR(th.tex_s[i], es[i], 1e-5);
		CHECK_NEAR(th.tex_t[i], et[i], 1e-5);
	}
	sl_exec_destroy(x);
	sl_program_destroy(prog);
}

/* ---- surfaces and light shaders together, through lighthost.h ---- */

static const char *const lh_space_names[] = { "shader", "world", "object" };
static const float lh_space_mats[3][16] = {
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 },
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 },
	{ 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1 },
};

/* Run surface @x over @sc lit by the light executors @lights. */
static bool run_lit(struct sl_exec *x, const struct scene *sc, struct sl_exec **lights, int n)
{
	struct sl_lighthost lh;
	sl_lighthost_init(&lh, lights, n);
	lh.space_names = lh_space_names;
	lh.space_mats = lh_space_mats;
	lh.nspaces = 3;
	if (!sl_exec_set_grid(x, sc->nu, sc->nv))
		return false;
	setup_surface(x, sc);
	return sl_exec_run(x, &lh.host);
}

static void test_matte_distantlight(void)
{
	struct sl_program *matte = load("matte"), *dist = load("distantlight"),
			  *amb = load("ambientlight");
	CHECK(matte && dist && amb);
	if (!matte || !dist || !amb)
		goto out;
	struct sl_exec *x = sl_exec_create(matte, MAXN);
	struct sl_exec *lights[2] = { sl_exec_create(dist, MAXN), sl_exec_create(amb, MAXN) };
	/*
	 * distantlight with its defaults shines along +z (from (0, 0, 0) to
	 * (0, 0, 1)), so towards the light is -z, along the unflipped normal:
	 * the same numbers as test_matte. ambientlight at intensity 0.1.
	 *   Ci = Cs * (0.1 + 0.8 cos b): b = 0: 0.9; 60: 0.5; 85: 0.1697246
	 */
	CHECK(set(lights[1], "intensity", 0.1f));
	CHECK(set(x, "Kd", 0.8f));
	double tilt[3] = { 0, 60, 85 };
	struct scene sc = facing_scene(3, tilt);
	CHECK(run_lit(x, &sc, lights, 2));
	const double k[3] = { 0.9, 0.5, 0.1 + 0.8 * 0.0871557427 };
	for (uint32_t i = 0; i < 3; i++)
		check_color(x, SL_GLOBAL_CI, i, k[i], k[i] * 0.5, k[i] * 0.25, TOL);

	/* Turned to shine along -z (towards the eye), it lights the back: only ambient is left. */
	float to[3] = { 0, 0, -1 };
	CHECK(sl_exec_set_param(lights[0], "to", to, 3));
	CHECK(run_lit(x, &sc, lights, 2));
	check_color(x, SL_GLOBAL_CI, 0, 0.1, 0.05, 0.025, TOL);
	sl_exec_destroy(lights[0]);
	sl_exec_destroy(lights[1]);
	sl_exec_destroy(x);
out:
	sl_program_destroy(matte);
	sl_program_destroy(dist);
	sl_program_destroy(amb);
}

static void test_plastic_pointlight(void)
{
	struct sl_program *plastic = load("plastic"), *point = load("pointlight");
	CHECK(plastic && point);
	if (!plastic || !point)
		goto out;
	struct sl_exec *x = sl_exec_create(plastic, MAXN);
	struct sl_exec *light = sl_exec_create(point, MAXN);
	/*
	 * A point light at the eye with intensity 25 lights the surface at
	 * distance 5 with Cl = 25 / 25 = 1, head-on: diffuse = specular = 1,
	 * Ci = 0.5 * Cs + 0.5 = (1, 0.75, 0.625). At twice the distance (a
	 * second point at z = 10) Cl = 0.25: Ci = 0.25 * (0.5 * Cs + 0.5).
	 */
	CHECK(set(light, "intensity", 25));
	double tilt[2] = { 0, 0 };
	struct scene sc = facing_scene(2, tilt);
	sc.P[1][2] = 10;
	CHECK(run_lit(x, &sc, &light, 1));
	check_color(x, SL_GLOBAL_CI, 0, 1, 0.75, 0.625, TOL);
	check_color(x, SL_GLOBAL_CI, 1, 0.25, 0.1875, 0.15625, TOL);
	sl_exec_destroy(light);
	sl_exec_destroy(x);
out:
	sl_program_destroy(plastic);
	sl_program_destroy(point);
}

/* __nondiffuse and __nonspecular keep an uberlight out of diffuse() or specular(). */
static void test_plastic_uberlight_flags(void)
{
	struct sl_program *plastic = load("plastic"), *uber = load("uberlight");
	CHECK(plastic && uber);
	if (!plastic || !uber)
		goto out;
	struct sl_exec *x = sl_exec_create(plastic, MAXN);
	struct sl_exec *light = sl_exec_create(uber, MAXN);
	/*
	 * The uberlight at the eye aims down +z: on its axis, with no falloff,
	 * Cl = 1 at the surface (0, 0, 5), head-on.
	 *   both:           Ci = 0.5 * Cs + 0.5 = (1, 0.75, 0.625)
	 *   __nondiffuse:   Ci = 0.5 (the highlight only)
	 *   __nonspecular:  Ci = 0.5 * Cs = (0.5, 0.25, 0.125)
	 */
	double tilt[1] = { 0 };
	struct scene sc = facing_scene(1, tilt);
	CHECK(run_lit(x, &sc, &light, 1));
	check_color(x, SL_GLOBAL_CI, 0, 1, 0.75, 0.625, TOL);
	CHECK(set(light, "__nondiffuse", 1));
	CHECK(run_lit(x, &sc, &light, 1));
	check_color(x, SL_GLOBAL_CI, 0, 0.5, 0.5, 0.5, TOL);
	CHECK(set(light, "__nondiffuse", 0));
	CHECK(set(light, "__nonspecular", 1));
	CHECK(run_lit(x, &sc, &light, 1));
	check_color(x, SL_GLOBAL_CI, 0, 0.5, 0.25, 0.125, TOL);
	sl_exec_destroy(light);
	sl_exec_destroy(x);
out:
	sl_program_destroy(plastic);
	sl_program_destroy(uber);
}

int main(void)
{
	RUN(test_constant);
	RUN(test_matte);
	RUN(test_plastic);
	RUN(test_plastic_prman);
	RUN(test_metal);
	RUN(test_shinymetal);
	RUN(test_paintedplastic);
	RUN(test_defaultsurface);
	RUN(test_ambientlight);
	RUN(test_distantlight);
	RUN(test_pointlight);
	RUN(test_spotlight);
	RUN(test_shadowspot);
	RUN(test_uberlight_cut);
	RUN(test_uberlight_shape);
	RUN(test_uberlight_barndoors);
	RUN(test_uberlight_falloff);
	RUN(test_uberlight_slide);
	RUN(test_matte_distantlight);
	RUN(test_plastic_pointlight);
	RUN(test_plastic_uberlight_flags);
	return test_finish();
}

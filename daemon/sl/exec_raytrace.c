/*
 * The ray-tracing built-ins of the grid interpreter: trace(), transmission(),
 * occlusion(), indirectdiffuse(), raylevel(), isshadowray(), and
 * environment() and shadow() of the map name "raytrace". Every ray goes
 * through struct sl_host's trace (exec.h), in batches of at most RAY_CHUNK
 * rays; a host without it (no renderer) gives what a ray that hits nothing
 * gives, with one warning at the call.
 *
 * Sampling. occlusion() and indirectdiffuse() sample the cosine-weighted
 * cone of "coneangle" (default pi/2, the hemisphere) about N, so that the
 * mean of what the rays bring back is the cosine-weighted integral; a
 * "samples" > 1 trace() or transmission() with a "samplecone" samples that
 * cone uniformly in solid angle. The directions are a Hammersley set (i +
 * 1/2) / n, radical inverse of i, shifted modulo 1 by two numbers hashed
 * from the point's position bits (Cranley-Patterson rotation): the same
 * point gives the same rays in any grid or batch, and neighbouring points
 * decorrelate.
 */
#include "exec_impl.h"
#include "mathlib.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RAY_CHUNK 2048
#define MAX_SAMPLES 65536
#define PI_D 3.14159265358979323846

/* ---- register access ---- */

static int ncomp(const struct sl_exec *x, int32_t r)
{
	return sl_type_ncomp(x->prog->regs[r].type);
}

static bool is_string_reg(const struct sl_exec *x, int32_t r)
{
	return x->prog->regs[r].type == SL_TYPE_STRING;
}

static float arg(const struct sl_exec *x, int32_t r, int c, uint32_t i)
{
	return sl_x_get(x, r, ncomp(x, r) == 1 ? 0 : c, i);
}

static const char *str(const struct sl_exec *x, int32_t r, uint32_t i)
{
	if (!x->sdata[r])
		return "";
	const char *s = sl_x_str(x, r, i);
	return s ? s : "";
}

static uint32_t first_on(const struct sl_exec *x)
{
	for (uint32_t i = 0; i < x->n; i++)
		if (x->mask[i])
			return i;
	return 0;
}

static void put(struct sl_exec *x, int32_t r, int c, uint32_t i, float v)
{
	if (c < ncomp(x, r))
		sl_x_set(x, r, c, i, sl_finite(v));
}

/* ---- options ---- */

struct ray_opts {
	float samples, maxdist, coneangle, samplecone, bias, blur;
	const char *subset, *hitmode;
};

/* "name", value pairs from argument @k on; @what names the call in warnings. */
static void ray_options(struct sl_exec *x, const struct sl_insn *in, int k, struct ray_opts *o)
{
	const char *what = sl_builtins[in->bi].name;
	uint32_t i0 = first_on(x);
	for (; k < in->nargs; k += 2) {
		const int32_t *a = in->args;
		if (!is_string_reg(x, a[k]) || k + 1 >= in->nargs) {
			sl_exec_warn_once(x, in, "%s: options must be \"name\", value pairs", what);
			return;
		}
		const char *name = str(x, a[k], i0);
		int32_t v = a[k + 1];
		if (is_string_reg(x, v)) {
			if (!strcmp(name, "subset"))
				o->subset = str(x, v, i0);
			else if (!strcmp(name, "hitmode"))
				o->hitmode = str(x, v, i0);
			else if (strcmp(name, "label") && strcmp(name, "hitsides") &&
				 strcmp(name, "filter"))
				sl_exec_warn_once(x, in, "%s: unknown option '%s' ignored", what, name);
			continue;
		}
		float f = sl_x_get(x, v, 0, i0);
		if (!strcmp(name, "samples"))
			o->samples = f;
		else if (!strcmp(name, "maxdist"))
			o->maxdist = f;
		else if (!strcmp(name, "coneangle"))
			o->coneangle = f;
		else if (!strcmp(name, "samplecone"))
			o->samplecone = f;
		else if (!strcmp(name, "bias"))
			o->bias = f;
		else if (!strcmp(name, "blur"))
			o->blur = f;
		else if (strcmp(name, "samplebase") && strcmp(name, "width") &&
			 strcmp(name, "swidth") && strcmp(name, "twidth") && strcmp(name, "fill"))
			sl_exec_warn_once(x, in, "%s: unknown option '%s' ignored", what, name);
	}
}

static uint32_t sample_count(float s)
{
	if (!(s >= 1))
		return 1;
	return s >= MAX_SAMPLES ? MAX_SAMPLES : (uint32_t)(s + 0.5f);
}

/* ---- sampling ---- */

static uint32_t mix32(uint32_t h)
{
	h ^= h >> 16;
	h *= 0x7feb352du;
	h ^= h >> 15;
	h *= 0x846ca68bu;
	h ^= h >> 16;
	return h;
}

/* Two numbers in [0, 1) from a position's bits. */
static void point_hash(const float p[3], double r[2])
{
	uint32_t b[3];
	memcpy(b, p, sizeof(b));
	uint32_t h = mix32(b[0] ^ mix32(b[1] ^ mix32(b[2] + 0x9e3779b9u)));
	uint32_t g = mix32(h + 0x632be5abu);
	r[0] = (h >> 8) * (1.0 / 16777216.0);
	r[1] = (g >> 8) * (1.0 / 16777216.0);
}

static double radical_inverse(uint32_t i)
{
	i = (i << 16) | (i >> 16);
	i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
	i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
	i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
	i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
	return i * (1.0 / 4294967296.0);
}

/* An orthonormal frame t, b around the unit vector n. */
static void frame(const double n[3], double t[3], double b[3])
{
	double s = n[2] >= 0 ? 1.0 : -1.0;
	double a = -1.0 / (s + n[2]), c = n[0] * n[1] * a;
	t[0] = 1 + s * n[0] * n[0] * a;
	t[1] = s * c;
	t[2] = -s * n[0];
	b[0] = c;
	b[1] = s + n[1] * n[1] * a;
	b[2] = -n[1];
}

/*
 * Sample @k of @n about the unit axis @n3 within half-angle @cone: cosine
 * weighted (@cosine) or uniform in solid angle; @rot the point's rotation.
 */
static void cone_dir(const double n3[3], double cone, bool cosine, uint32_t k, uint32_t n,
		     const double rot[2], float out[3])
{
	double u1 = (k + 0.5) / n + rot[0], u2 = radical_inverse(k) + rot[1];
	u1 -= floor(u1);
	u2 -= floor(u2);
	double ct, st;
	if (cosine) {
		double sm = sin(cone);
		double s2 = u1 * sm * sm;
		st = sqrt(s2);
		ct = sqrt(fmax(0.0, 1 - s2));
	} else {
		ct = 1 - u1 * (1 - cos(cone));
		st = sqrt(fmax(0.0, 1 - ct * ct));
	}
	double phi = 2 * PI_D * u2, t[3], b[3];
	frame(n3, t, b);
	for (int c = 0; c < 3; c++)
		out[c] = (float)(st * cos(phi) * t[c] + st * sin(phi) * b[c] + ct * n3[c]);
}

static bool unit(const float v[3], double out[3])
{
	double l = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
	if (!(l > 0) || !isfinite(l))
		return false;
	for (int c = 0; c < 3; c++)
		out[c] = v[c] / l;
	return true;
}

/* ---- batches of rays ---- */

/* What a ray brings back, per ray: dist, Ci, Oi, trans. */
struct batch {
	struct sl_exec *x;
	const struct sl_insn *in;
	struct sl_ray_query q;
	float org[3 * RAY_CHUNK], dir[3 * RAY_CHUNK], maxdist[RAY_CHUNK];
	float dist[RAY_CHUNK], Ci[3 * RAY_CHUNK], Oi[3 * RAY_CHUNK], trans[3 * RAY_CHUNK];
	uint32_t owner[RAY_CHUNK];  /* the point a ray belongs to */
	float weight[RAY_CHUNK];    /* its weight in the point's result */
	uint32_t n;
	/* per point: the sums of what its rays bring back (4 floats a point) */
	double *sum;
	int what;                   /* 0 Ci, 1 trans, 2 dist, 3 1 - trans (occlusion) */
};

static void batch_init(struct batch *b, struct sl_exec *x, const struct sl_insn *in,
		       enum sl_ray_type type, const struct ray_opts *o, int what)
{
	memset(&b->q, 0, sizeof(b->q));
	b->x = x;
	b->in = in;
	b->q.type = type;
	b->q.org = b->org;
	b->q.dir = b->dir;
	b->q.maxdist = b->maxdist;
	b->q.bias = o->bias;
	b->q.subset = o->subset && o->subset[0] ? o->subset : NULL;
	b->q.hitmode = o->hitmode && o->hitmode[0] && strcmp(o->hitmode, "default") ?
			       o->hitmode : NULL;
	b->q.dist = what == 2 ? b->dist : NULL;
	b->q.Ci = what == 0 ? b->Ci : NULL;
	b->q.Oi = what == 0 ? b->Oi : NULL;
	b->q.trans = what == 1 || what == 3 ? b->trans : NULL;
	b->n = 0;
	b->what = what;
	size_t npts = (size_t)x->n * 4;
	b->sum = calloc(npts ? npts : 1, sizeof(double));
}

/* Cast what is queued and add it to the owners' sums. */
static void batch_flush(struct batch *b)
{
	if (!b->n)
		return;
	struct sl_exec *x = b->x;
	const struct sl_host *h = x->host;
	b->q.n = b->n;
	bool ok = h && h->trace && h->trace(h->user, &b->q);
	if (!ok) {
		if (!h || !h->trace)
			sl_exec_warn_once(x, b->in, "%s: this renderer cannot ray trace: its rays "
					  "hit nothing", sl_builtins[b->in->bi].name);
		for (uint32_t k = 0; k < b->n; k++) {
			b->dist[k] = 1e30f;
			for (int c = 0; c < 3; c++) {
				b->Ci[3 * k + (uint32_t)c] = b->Oi[3 * k + (uint32_t)c] = 0;
				b->trans[3 * k + (uint32_t)c] = 1;
			}
		}
	}
	for (uint32_t k = 0; k < b->n; k++) {
		double *s = b->sum + 4 * (size_t)b->owner[k];
		double w = b->weight[k];
		for (int c = 0; c < 3; c++) {
			float v = b->what == 0 ? b->Ci[3 * k + (uint32_t)c]
				: b->what == 2 ? b->dist[k]
				: b->what == 1 ? b->trans[3 * k + (uint32_t)c]
					       : 1 - b->trans[3 * k + (uint32_t)c];
			s[c] += w * (isfinite(v) ? v : 0);
		}
		s[3] += w;
	}
	b->n = 0;
}

static void batch_add(struct batch *b, uint32_t owner, const float org[3], const float dir[3],
		      float maxdist, float weight)
{
	uint32_t k = b->n;
	memcpy(b->org + 3 * k, org, 3 * sizeof(float));
	memcpy(b->dir + 3 * k, dir, 3 * sizeof(float));
	b->maxdist[k] = maxdist;
	b->owner[k] = owner;
	b->weight[k] = weight;
	if (++b->n == RAY_CHUNK)
		batch_flush(b);
}

/* Flush and write each active point's mean into @dst (1 or 3 components), then free. */
static void batch_finish(struct batch *b, int32_t dst, float empty)
{
	batch_flush(b);
	struct sl_exec *x = b->x;
	if (dst >= 0)
		SL_X_EACH(x, dst, i) {
			const double *s = b->sum + 4 * (size_t)i;
			for (int c = 0; c < 3; c++) {
				double v = s[3] > 0 ? s[c] / s[3] : empty;
				put(x, dst, c, i, (float)(ncomp(x, dst) == 1 ?
					(s[3] > 0 ? (s[0] + s[1] + s[2]) / (3 * s[3]) : empty) : v));
			}
		}
	free(b->sum);
	b->sum = NULL;
}

static struct batch *batch_new(void)
{
	struct batch *b = malloc(sizeof(*b));
	if (!b) {
		fprintf(stderr, "relight: fatal: out of memory\n");
		abort();
	}
	return b;
}

static float default_maxdist(float m)
{
	return m > 0 && isfinite(m) ? m : 1e30f;
}

/* ---- the built-ins ---- */

/* occlusion(P, N[, samples], ...) and indirectdiffuse(P, N[, samples], ...) */
static void do_hemisphere(struct sl_exec *x, const struct sl_insn *in, bool occlusion)
{
	const int32_t *a = in->args;
	if (in->nargs < 2)
		return;
	int k = 2;
	struct ray_opts o = { .samples = 1, .coneangle = (float)(PI_D / 2), .bias = -1 };
	if (in->nargs > 2 && !is_string_reg(x, a[2])) {
		o.samples = sl_x_get(x, a[2], 0, first_on(x));
		k = 3;
	}
	ray_options(x, in, k, &o);
	uint32_t ns = sample_count(o.samples);
	double cone = o.coneangle > 0 ? fmin(o.coneangle, PI_D / 2) : PI_D / 2;
	float maxdist = default_maxdist(o.maxdist);
	struct batch *b = batch_new();
	batch_init(b, x, in, SL_RAY_DIFFUSE, &o, occlusion ? 3 : 0);
	for (uint32_t i = 0; i < x->n; i++) {
		if (!x->mask[i])
			continue;
		float p[3], nn[3], d[3];
		double n3[3], rot[2];
		for (int c = 0; c < 3; c++) {
			p[c] = arg(x, a[0], c, i);
			nn[c] = arg(x, a[1], c, i);
		}
		if (!unit(nn, n3))
			continue;    /* no normal: no rays, the result of none */
		point_hash(p, rot);
		for (uint32_t s = 0; s < ns; s++) {
			cone_dir(n3, cone, true, s, ns, rot, d);
			batch_add(b, i, p, d, maxdist, 1.0f);
		}
	}
	batch_finish(b, in->dst, 0.0f);
	free(b);
}

/* trace(P, R, ...): the colour brought back, or (float) the distance to the hit */
static void do_trace(struct sl_exec *x, const struct sl_insn *in)
{
	const int32_t *a = in->args;
	if (in->nargs < 2)
		return;
	bool dist = in->dst >= 0 && ncomp(x, in->dst) == 1;
	struct ray_opts o = { .samples = 1, .bias = -1 };
	ray_options(x, in, 2, &o);
	uint32_t ns = o.samplecone > 0 ? sample_count(o.samples) : 1;
	double cone = fmin(fmax(o.samplecone, 0), PI_D / 2);
	struct batch *b = batch_new();
	batch_init(b, x, in, SL_RAY_SPECULAR, &o, dist ? 2 : 0);
	for (uint32_t i = 0; i < x->n; i++) {
		if (!x->mask[i])
			continue;
		float p[3], r[3], d[3];
		double r3[3], rot[2];
		for (int c = 0; c < 3; c++) {
			p[c] = arg(x, a[0], c, i);
			r[c] = arg(x, a[1], c, i);
		}
		if (!unit(r, r3))
			continue;
		point_hash(p, rot);
		for (uint32_t s = 0; s < ns; s++) {
			if (ns > 1)
				cone_dir(r3, cone, false, s, ns, rot, d);
			else
				memcpy(d, r, sizeof(d));
			batch_add(b, i, p, d, default_maxdist(o.maxdist), 1.0f);
		}
	}
	batch_finish(b, in->dst, dist ? 1e30f : 0.0f);
	free(b);
}

/* The light getting from @from to @to (a segment; cone sampled with samplecone). */
static void segment_rays(struct batch *b, uint32_t i, const float from[3], const float to[3],
			 uint32_t ns, double cone)
{
	float d[3], s[3];
	for (int c = 0; c < 3; c++)
		d[c] = to[c] - from[c];
	double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
	if (!(len > 0) || !isfinite(len))
		return;
	double d3[3] = { d[0] / len, d[1] / len, d[2] / len }, rot[2];
	point_hash(from, rot);
	for (uint32_t k = 0; k < ns; k++) {
		if (ns > 1)
			cone_dir(d3, cone, false, k, ns, rot, s);
		else
			memcpy(s, d, sizeof(s));
		batch_add(b, i, from, s, (float)len, 1.0f);
	}
}

/* transmission(Psrc, Pdst, ...) */
static void do_transmission(struct sl_exec *x, const struct sl_insn *in)
{
	const int32_t *a = in->args;
	if (in->nargs < 2)
		return;
	struct ray_opts o = { .samples = 1, .bias = -1 };
	ray_options(x, in, 2, &o);
	uint32_t ns = o.samplecone > 0 ? sample_count(o.samples) : 1;
	double cone = fmin(fmax(o.samplecone, 0), PI_D / 2);
	struct batch *b = batch_new();
	batch_init(b, x, in, SL_RAY_TRANSMISSION, &o, 1);
	for (uint32_t i = 0; i < x->n; i++) {
		if (!x->mask[i])
			continue;
		float p[3], q[3];
		for (int c = 0; c < 3; c++) {
			p[c] = arg(x, a[0], c, i);
			q[c] = arg(x, a[1], c, i);
		}
		segment_rays(b, i, p, q, ns, cone);
	}
	batch_finish(b, in->dst, 1.0f);
	free(b);
}

/* The global @g's component @c at point @i (0 when the program has none). */
static float global(const struct sl_exec *x, enum sl_global g, int c, uint32_t i)
{
	int32_t r = x->prog->global_reg[g];
	return r >= 0 ? arg(x, r, c, i) : 0.0f;
}

void sl_exec_ray_lookup(struct sl_exec *x, const struct sl_insn *in, bool shadow, int ncoord)
{
	const int32_t *a = in->args;
	struct ray_opts o = { .samples = 1, .bias = -1 };
	ray_options(x, in, 2 + ncoord, &o);
	if (o.blur > 0)
		sl_exec_warn_once(x, in, "%s(\"raytrace\"): \"blur\" is not built: a sharp %s",
				  shadow ? "shadow" : "environment",
				  shadow ? "shadow" : "reflection");
	struct batch *b = batch_new();
	if (shadow) {
		/* the segment from the point to the light's position, Ps - L */
		if (x->prog->global_reg[SL_GLOBAL_L] < 0 || x->prog->global_reg[SL_GLOBAL_PS] < 0) {
			sl_exec_warn_once(x, in, "shadow(\"raytrace\") outside an illuminate or solar "
					  "statement: no light position to trace toward (no shadow)");
			free(b);
			SL_X_EACH(x, in->dst, i)
				put(x, in->dst, 0, i, 0.0f);
			return;
		}
		batch_init(b, x, in, SL_RAY_TRANSMISSION, &o, 3);
		for (uint32_t i = 0; i < x->n; i++) {
			if (!x->mask[i])
				continue;
			float p[3], l[3];
			for (int c = 0; c < 3; c++) {
				p[c] = arg(x, a[2], c, i);
				l[c] = global(x, SL_GLOBAL_PS, c, i) - global(x, SL_GLOBAL_L, c, i);
			}
			segment_rays(b, i, p, l, 1, 0);
		}
		batch_finish(b, in->dst, 0.0f);
	} else {
		batch_init(b, x, in, SL_RAY_SPECULAR, &o, 0);
		for (uint32_t i = 0; i < x->n; i++) {
			if (!x->mask[i])
				continue;
			float p[3], r[3];
			for (int c = 0; c < 3; c++) {
				p[c] = global(x, SL_GLOBAL_P, c, i);
				r[c] = arg(x, a[2], c, i);
			}
			double r3[3];
			if (unit(r, r3))
				batch_add(b, i, p, r, default_maxdist(o.maxdist), 1.0f);
		}
		batch_finish(b, in->dst, 0.0f);
	}
	free(b);
}

/* raylevel(), isshadowray(): the host's "depth" and "type" */
static void do_rayquery(struct sl_exec *x, const struct sl_insn *in, int id)
{
	const struct sl_host *h = x->host;
	float v = 0;
	if (id == SL_BI_RAYLEVEL) {
		float d = 0;
		if (h && h->rayinfo && h->rayinfo(h->user, "depth", SL_TYPE_FLOAT, 0, &d, NULL))
			v = d;
	} else {
		const char *t = NULL;
		if (h && h->rayinfo && h->rayinfo(h->user, "type", SL_TYPE_STRING, 0, NULL, &t) && t)
			v = strcmp(t, "transmission") == 0 ? 1.0f : 0.0f;
	}
	if (in->dst >= 0)
		SL_X_EACH(x, in->dst, i)
			put(x, in->dst, 0, i, v);
}

void sl_exec_ray_builtin(struct sl_exec *x, const struct sl_insn *in, int id)
{
	switch (id) {
	case SL_BI_TRACE:
		do_trace(x, in);
		break;
	case SL_BI_TRANSMISSION:
		do_transmission(x, in);
		break;
	case SL_BI_OCCLUSION:
		do_hemisphere(x, in, true);
		break;
	case SL_BI_INDIRECTDIFFUSE:
		do_hemisphere(x, in, false);
		break;
	default:
		do_rayquery(x, in, id);
		break;
	}
}

/*
 * Deep shadow maps: see deepshadow.h.
 *
 * Building. A pixel's samples each see their hits front to back with an
 * opacity o: the sample's transmittance steps down by the factor 1 - o at
 * each. The pixel's function is the mean of its samples' (box filter over
 * the pixel), so walking all the pixel's hits in depth order, a hit of
 * sample s lowers the mean by T_s o / S. Compression: a run of consecutive
 * steps whose drops add up to at most the error bound becomes one linear
 * ramp from the run's first depth and value to its last; exact and ramp
 * both stay between the run's first and last values, so they differ by no
 * more than the bound anywhere. A single step bigger than the bound stays a
 * step (two nodes at one depth). This is simpler than Lokovic and Veach's
 * slope-window fit and keeps more nodes on smooth falls; both bound the
 * error the same way.
 */
#include "deepshadow.h"

#include "exr_internal.h"
#include "hider.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DSM_VERSION 1
/* Beyond this many nodes in one map the file's rows would not fit a 32-bit image. */
#define MAX_NODES 0x40000000u

struct deep_event {
	float z, o;
	uint32_t s;
};

void reyes_deep_scratch_finish(struct reyes_deep_scratch *s)
{
	if (!s)
		return;
	free(s->z);
	free(s->o);
	free(s->ev);
	free(s->ts);
	memset(s, 0, sizeof(*s));
}

static int event_cmp(const void *a, const void *b)
{
	const struct deep_event *x = a, *y = b;
	if (x->z != y->z)
		return x->z < y->z ? -1 : 1;
	return x->s < y->s ? -1 : x->s > y->s;
}

static bool grow(void **p, size_t *cap, size_t need, size_t size)
{
	if (need <= *cap)
		return true;
	size_t n = *cap ? *cap : 64;
	while (n < need)
		n *= 2;
	void *q = realloc(*p, n * size);
	if (!q)
		return false;
	*p = q;
	*cap = n;
	return true;
}

/* Every hit of the pixel's samples, into s->ev; the count in *nev. */
static bool gather(const struct reyes_hider *h, uint32_t nsamples, uint32_t x, uint32_t y,
		   struct reyes_deep_scratch *s, size_t *nev)
{
	size_t n = 0;
	for (uint32_t k = 0; k < nsamples; k++) {
		uint32_t cap = s->cap < UINT32_MAX ? (uint32_t)s->cap : UINT32_MAX;
		uint32_t m = reyes_hider_sample_hits(h, x, y, k, s->z, s->o, cap);
		if (m > cap) {
			size_t c = s->cap;
			if (!grow((void **)&s->o, &c, m, sizeof(float)))
				return false;
			c = s->cap;
			if (!grow((void **)&s->z, &c, m, sizeof(float)))
				return false;
			s->cap = c;
			m = reyes_hider_sample_hits(h, x, y, k, s->z, s->o, m);
		}
		if (!grow((void **)&s->ev, &s->evcap, n + m, sizeof(*s->ev)))
			return false;
		for (uint32_t i = 0; i < m; i++)
			if (s->o[i] > 0.0f && isfinite(s->z[i]) && s->z[i] > 0.0f)
				s->ev[n++] = (struct deep_event){ s->z[i], fminf(s->o[i], 1.0f), k };
	}
	*nev = n;
	return true;
}

/* Append node (z, T) to @px unless it repeats the last one or extends a step. */
static bool put_node(struct reyes_deep_pixel *px, size_t *cap, float z, double t)
{
	float tf = (float)(t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t);
	if (px->n && px->zt[2 * px->n - 2] == z && px->zt[2 * px->n - 1] == tf)
		return true;
	/* a step continuing a step at the same depth: one step */
	if (px->n >= 2 && px->zt[2 * px->n - 2] == z && px->zt[2 * px->n - 4] == z) {
		px->zt[2 * px->n - 1] = tf;
		return true;
	}
	if (!grow((void **)&px->zt, cap, 2 * ((size_t)px->n + 1), sizeof(float)))
		return false;
	px->zt[2 * px->n] = z;
	px->zt[2 * px->n + 1] = tf;
	px->n++;
	return true;
}

bool reyes_deep_build_pixel(const struct reyes_hider *h, uint32_t nsamples, uint32_t x,
			    uint32_t y, float error, struct reyes_deep_scratch *s,
			    struct reyes_deep_pixel *px)
{
	free(px->zt);
	px->zt = NULL;
	px->n = 0;
	size_t nev;
	if (!nsamples || !gather(h, nsamples, x, y, s, &nev))
		return nsamples == 0;
	if (!nev)
		return true;
	qsort(s->ev, nev, sizeof(*s->ev), event_cmp);
	if (!grow((void **)&s->ts, &s->tscap, nsamples, sizeof(double)))
		return false;
	for (uint32_t k = 0; k < nsamples; k++)
		s->ts[k] = 1.0;
	double err = isfinite(error) && error > 0.0f ? error : 0.0;
	double v = 1.0, inv = 1.0 / nsamples;
	double va = 1.0, drop = 0.0;     /* the open run: first value, drops so far */
	float za = 0.0f, zl = 0.0f;      /* its first and last depths */
	bool open = false;
	size_t cap = 0;
	for (size_t i = 0; i < nev; i++) {
		const struct deep_event *e = &s->ev[i];
		double d = s->ts[e->s] * e->o * inv;
		s->ts[e->s] *= 1.0 - e->o;
		if (open && drop + d > err) {
			if (!put_node(px, &cap, za, va) || !put_node(px, &cap, zl, v))
				return false;
			open = false;
		}
		if (!open) {
			open = true;
			za = e->z;
			va = v;
			drop = 0.0;
		}
		v -= d;
		drop += d;
		zl = e->z;
	}
	if (open && (!put_node(px, &cap, za, va) || !put_node(px, &cap, zl, v)))
		return false;
	return true;
}

bool reyes_deep_write(const char *path, uint32_t w, uint32_t h,
		      const struct reyes_deep_pixel *px, const float world_to_camera[16],
		      const float world_to_ndc[16], FILE *diag)
{
	FILE *d = diag ? diag : stderr;
	uint64_t total = 0;
	for (size_t p = 0; p < (size_t)w * h; p++)
		total += px[p].n;
	uint64_t rows = h + (total + w - 1) / w;
	if (!w || !h || total > MAX_NODES || rows > INT32_MAX) {
		fprintf(d, "%s: error: a %ux%u deep shadow map of %" PRIu64 " nodes is too big to "
			"write\n", path, w, h, total);
		return false;
	}
	static const char *const names[2] = { "T", "Z" };
	struct reyes_image im;
	if (!reyes_image_init(&im, w, (uint32_t)rows, 2, names)) {
		fprintf(d, "%s: error: out of memory for a deep shadow map\n", path);
		return false;
	}
	size_t at = (size_t)w * h;
	for (size_t p = 0; p < (size_t)w * h; p++) {
		im.data[2 * p] = px[p].n ? px[p].zt[2 * px[p].n - 1] : 1.0f;
		im.data[2 * p + 1] = (float)px[p].n;
		for (uint32_t k = 0; k < px[p].n; k++, at++) {
			im.data[2 * at] = px[p].zt[2 * k + 1];
			im.data[2 * at + 1] = px[p].zt[2 * k];
		}
	}
	im.has_matrices = true;
	memcpy(im.world_to_camera, world_to_camera, sizeof(im.world_to_camera));
	memcpy(im.world_to_ndc, world_to_ndc, sizeof(im.world_to_ndc));
	char attr[96];
	snprintf(attr, sizeof(attr), "relight-dsm %d %u %u %" PRIu64, DSM_VERSION, w, h, total);
	const char *sa[2] = { "deepshadow", attr };
	struct reyes_exr_write_opts o = { .strattrs = sa, .nstrattrs = 1 };
	bool ok = reyes_exr_write(path, &im, 1, &o, diag);
	reyes_image_finish(&im);
	return ok;
}

static int channel(const struct reyes_image *im, const char *name)
{
	for (uint32_t c = 0; c < im->nchannels; c++)
		if (!strcmp(im->channel_names[c], name))
			return (int)c;
	return -1;
}

static bool bad(FILE *d, const char *path, const char *why, struct reyes_deep_map *m)
{
	fprintf(d, "%s: error: not a valid deep shadow map: %s\n", path, why);
	reyes_deep_map_finish(m);
	return false;
}

bool reyes_deep_from_image(const struct reyes_image *im, const char *attr, const char *path,
			   struct reyes_deep_map *m, FILE *diag)
{
	FILE *d = diag ? diag : stderr;
	memset(m, 0, sizeof(*m));
	int version;
	unsigned w, h;
	unsigned long long total;
	char tail;
	if (sscanf(attr, "relight-dsm %d %u %u %llu %c", &version, &w, &h, &total, &tail) != 4)
		return bad(d, path, "the \"deepshadow\" attribute is not 'relight-dsm 1 W H N'", m);
	if (version != DSM_VERSION)
		return bad(d, path, "an unknown version", m);
	int tc = channel(im, "T"), zc = channel(im, "Z");
	if (tc < 0 || zc < 0 || !im->has_matrices)
		return bad(d, path, "no T and Z channels, or no camera matrices", m);
	if (!w || !h || total > MAX_NODES || im->width != w ||
	    (uint64_t)im->height != h + (total + w - 1) / w)
		return bad(d, path, "its size does not match its \"deepshadow\" attribute", m);
	size_t npix = (size_t)w * h, nch = im->nchannels;
	m->width = w;
	m->height = h;
	m->offsets = malloc((npix + 1) * sizeof(*m->offsets));
	m->zt = malloc((total ? total : 1) * 2 * sizeof(float));
	if (!m->offsets || !m->zt)
		return bad(d, path, "out of memory", m);
	uint64_t at = 0;
	for (size_t p = 0; p < npix; p++) {
		float c = im->data[p * nch + (size_t)zc];
		if (!(c >= 0.0f && c <= (float)MAX_NODES && c == floorf(c)) ||
		    at + (uint64_t)c > total)
			return bad(d, path, "a pixel's node count is wrong", m);
		m->offsets[p] = (uint32_t)at;
		for (uint32_t k = 0; k < (uint32_t)c; k++) {
			size_t q = (npix + at + k) * nch;
			float z = im->data[q + (size_t)zc], t = im->data[q + (size_t)tc];
			if (!isfinite(z) || !(t >= 0.0f && t <= 1.0f) ||
			    (k && z < m->zt[2 * (at + k) - 2]))
				return bad(d, path, "a node's depth or transmittance is out of order or "
					   "range", m);
			m->zt[2 * (at + k)] = z;
			m->zt[2 * (at + k) + 1] = t;
		}
		at += (uint64_t)c;
	}
	if (at != total)
		return bad(d, path, "the node counts do not add up to its \"deepshadow\" attribute",
			   m);
	m->offsets[npix] = (uint32_t)at;
	return true;
}

void reyes_deep_map_finish(struct reyes_deep_map *m)
{
	if (!m)
		return;
	free(m->offsets);
	free(m->zt);
	memset(m, 0, sizeof(*m));
}

double reyes_deep_eval(const struct reyes_deep_map *m, uint32_t x, uint32_t y, double z)
{
	size_t p = (size_t)y * m->width + x;
	uint32_t lo = m->offsets[p], hi = m->offsets[p + 1];
	/* the first node deeper than z */
	uint32_t a = lo, b = hi;
	while (a < b) {
		uint32_t mid = a + (b - a) / 2;
		if ((double)m->zt[2 * (size_t)mid] > z)
			b = mid;
		else
			a = mid + 1;
	}
	if (a == lo)
		return 1.0;
	if (a == hi)
		return m->zt[2 * (size_t)hi - 1];
	double z0 = m->zt[2 * (size_t)a - 2], t0 = m->zt[2 * (size_t)a - 1];
	double z1 = m->zt[2 * (size_t)a], t1 = m->zt[2 * (size_t)a + 1];
	return t0 + (t1 - t0) * ((z - z0) / (z1 - z0));
}

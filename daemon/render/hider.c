/*
 * The stochastic hider: point samples, per-sample depth-sorted hit lists,
 * front-to-back compositing and the pixel filter.
 *
 * Samples. Sample (gx, gy) of the image is stratum i = gx mod xsamples,
 * j = gy mod ysamples of pixel (gx / xsamples, gy / ysamples). Its position
 * is jittered inside the stratum and its time inside one of the pixel's
 * xsamples * ysamples time strata, chosen by a per-pixel permutation so that
 * time does not follow position. Everything comes from a hash of (gx, gy,
 * seed) and of (pixel, seed), never from the bucket, so the filter margin
 * that neighbouring buckets both sample is sampled identically. Positions
 * lie strictly inside their pixel (never on an integer coordinate).
 *
 * Lens. With depth of field a sample also takes a lens position: one of
 * the pixel's xsamples x ysamples cells of the unit square, chosen by a
 * second per-pixel permutation (so that the lens follows neither position
 * nor time), jittered inside the cell and carried to the unit disk by the
 * concentric map, which keeps the strata's areas. A thin lens at the eye,
 * focused at distance d, shows a camera-space point P from lens point L at
 * the screen position where the ray from L through P meets the plane z = d,
 * seen from the eye: P.xy / z + L (1/d - 1/z). So a vertex at depth z moves
 * by the lens position times the aperture radius in pixels (at unit
 * distance) times (1/d - 1/z): nothing on the focal plane, a disk whose
 * diameter is proportional to |1/d - 1/z| elsewhere. Each sample moves the
 * micropolygon's vertices for its lens position (and time) and tests the
 * moved quad, as motion blur does; the depth it records is the camera depth
 * of the point it hits.
 *
 * Micropolygons. Each quad (i, j), (i+1, j), (i+1, j+1), (i, j+1) is cut
 * along the diagonal (i, j)-(i+1, j+1) into two triangles. A sample is inside
 * a triangle when it is strictly inside every edge; a sample exactly on an
 * edge belongs to the triangle it would fall into if it were moved an
 * infinitesimal amount right, then down (the top-left rule). Edge functions
 * are evaluated from the edge's lexicographically smaller endpoint, so the
 * two triangles sharing an edge compute exactly opposite values: a sample on
 * a shared edge or vertex counts once, and there are no cracks.
 *
 * Facing. RenderMan's camera space is left-handed (x right, y up, z into the
 * screen) and raster space has y down. For Ng = dPdu x dPdv (u along i, v
 * along j), the signed raster area of a micropolygon,
 * cross(P(i+1,j) - P(i,j), P(i,j+1) - P(i,j)) summed over its two triangles
 * with raster y pointing down, is -(Ng . P) / z^3 times positive scales under
 * perspective (-Ng.z under orthographic). So a micropolygon whose Ng points
 * toward the camera (Ng . P < 0) has a positive raster area: positive area is
 * front-facing, and flip reverses that.
 *
 * Hits. A sample keeps the hits nearer than the depth at which it became
 * opaque (accumulated opacity >= opacity_threshold in every channel), sorted
 * front to back in a singly linked list whose nodes come from a per-bucket
 * pool with a free list. A hit that becomes the opaque point frees the nodes
 * behind it, and hits behind the opaque point are rejected at once.
 *
 * Dissolves. Each sample also has a dissolve number, uniform in [0, 1) from
 * its own hash; a grid that is a representation in a DetailRange cross-fade
 * is seen only by the samples whose number lies in its interval, so that two
 * representations fading into each other over complementary intervals
 * share the samples between them without overlap.
 *
 * Resolving. Each sample composites its hits front to back per channel,
 * C += T Ci and T *= 1 - Oi (Ci is premultiplied); a matte hit adds neither
 * colour nor alpha but still attenuates T. Alpha is the mean over the three
 * channels of the non-matte opacity accumulated (1 - T without matte). AOV
 * planes composite like colour, with the mean of the three channels' T. A
 * sample's depth is where it became opaque (1e30 if it never did); for the
 * midpoint depthfilter it is halfway between the two nearest hits that are
 * opaque by themselves (1e30 with fewer than two: the midpoint between a
 * surface and nothing is at infinity). A pixel's depth combines its own
 * samples: min, max, the average over samples that have a depth, or for
 * midpoint their minimum. Colour, alpha and AOVs are sum(w s) / sum(w) over
 * the samples whose offset from the pixel centre lies in [-w/2, w/2) on both
 * axes, with weights from tables of reyes_filter_eval; the margin a bucket
 * samples is the pixels that can hold such samples, ceil(w/2 + 1/2) - 1 on
 * each side.
 *
 * Record mode (the bake's indirect framebuffer). A hit keeps, in place of
 * colour and AOVs, the shading samples it interpolates: the ids id0 + k of
 * the vertices of the triangle it lies in with their barycentric weights
 * (the w[4] a smooth grid interpolates with, less the vertex that is 0), or
 * vertex (i, j) alone with weight 1 when the grid is flat. Compositing gives
 * each non-matte hit's vertices T times their weight, T the mean over the
 * three channels of the transmittance in front of the hit (how AOVs
 * composite); matte hits only attenuate. For grey opacity the three
 * channels' transmittances are equal and sum(weight Ci) is the composited
 * colour up to rounding; for coloured opacity it is what an AOV carrying
 * Ci gives, not the per-channel colour. A pixel sums its samples'
 * contributions with the filter weights, merging equal ids in a small
 * open-addressing table, divides by the weight sum, drops exact zeros and
 * sorts by id. Negative filter lobes (Catmull-Rom, sinc) give negative
 * weights. A vertex whose id would pass 2^32 - 1 drops the micropolygons
 * that use it (reported once). Alpha and depth go through the same
 * arithmetic as in normal mode and come out bit-identical.
 *
 * Solids (SolidBegin/SolidEnd, csg.h). A hit of a grid inside a solid
 * records its leaf and whether the ray enters the leaf there (the
 * micropolygon faces the camera, flip taken into account: outward normals)
 * or leaves it; such grids are not culled. Whether a solid's hit is seen
 * depends on every crossing in front of it, which arrive in any order, so
 * solid hits never make a sample opaque while it is sampled: they are kept
 * up to the opaque point of the other hits. Before compositing (both
 * modes), a sample holding solid hits walks them front to back with a
 * crossing count per leaf, evaluates the hit's tree before and after each
 * crossing and unlinks the hits where its value does not change (inner
 * surfaces, cuts); then its opaque point (and the midpoint depths) are
 * found again over what is left. A leaf whose first crossing along the ray
 * is an exit is taken as holding the eye (its count starts at 1): a camera
 * inside a solid, or a solid cut by the near clipping plane, sees the
 * solid's far boundary. Grids outside solids cost nothing more (a bucket
 * with no solid hit skips the pass).
 */
#include "hider.h"
#include "nurbs.h"

#include "csg.h"

#include "arena.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NIL 0xffffffffu
#define NO_DEPTH 1e30f
#define TAB_N 1024
#define MAX_SAMPLES_AXIS 256u
#define MAX_FILTER_WIDTH 64.0f
#define MAX_AOV 4096u

struct sample {
	float x, y, t;        /* raster position, time in [0, 1) */
	float lu, lv;         /* lens position on the unit disk (0, 0 without depth of field) */
	float zopq;           /* depth at which the sample became opaque, INFINITY if not */
	uint32_t head;        /* nearest hit, NIL when none */
	float zo[2];          /* midpoint depthfilter: the two nearest opaque hits */
	float lod;            /* dissolve number in [0, 1) for DetailRange's cross-fades */
};

struct hit {
	float z;
	uint32_t next;
	float c[3], o[3];
	bool matte;
	uint32_t csg;         /* 1 + leaf | CSG_ENTER where the ray enters it; 0: in no solid */
};

#define CSG_ENTER 0x80000000u

/* Record mode: the shading samples a hit interpolates (weight 0: unused). */
struct hit_ref {
	uint32_t id[3];
	float w[3];
};

/* Record mode: a pixel's table of ids, from id to its place in the dense list. */
struct slot {
	uint32_t id, gen, idx;
};

/* An edge function from the canonical (smaller) endpoint: cross(d, p - a). */
struct edge {
	double ax, ay, dx, dy;
	double sign;          /* +1 when the edge as defined starts at (ax, ay) */
};

/*
 * One triangle: for the edge opposite each vertex a, b, c, the edge function
 * made positive inside, v = A (py - ay) - B (px - ax): the canonical edge's
 * (dx, dy) times +-1, which is exact, so triangles sharing an edge get
 * exactly opposite values.
 */
struct tri {
	double ax[3], ay[3], A[3], B[3];
	bool own[3];          /* samples exactly on the edge are inside */
	uint8_t v[3];         /* quad vertices a, b, c */
	bool ok;
};

struct quad {
	struct edge e[5];     /* around the quad, then the diagonal v0-v2 */
	struct tri t[2];
	float x0, y0, x1, y1; /* bound */
	bool front;           /* faces the camera (flip taken into account) */
};

struct reyes_hider {
	struct reyes_hider_opts o;
	uint32_t nps;         /* samples per pixel */
	uint32_t mx, my;      /* filter margin in pixels */
	uint32_t *perm;       /* scratch for the time permutation */
	uint32_t *lperm;      /* scratch for the lens permutation */
	bool dof;             /* depth of field: samples have lens positions */
	float hw, hh;         /* half widths */
	bool radial;          /* the radial Catmull-Rom; else separable */
	float tabx[TAB_N + 2], taby[TAB_N + 2], tabr[TAB_N + 2];
	float scx, scy, scr, r2max;

	/* the current bucket */
	bool active;
	uint32_t px0, py0, px1, py1;
	uint32_t rx0, ry0, rx1, ry1;  /* sampled pixels */
	uint32_t gx0, gy0, sw, sh;    /* sample grid of the region */
	struct sample *samp;
	size_t samp_cap;
	struct hit *hits;
	float *hit_aov;
	uint32_t nhits, hits_cap, freelist;
	uint64_t inserted;

	/* reyes_hider_end scratch */
	float *scol, *saov, *sz;
	float *swx, *swy;     /* separable filter factors per sample */
	size_t scratch_cap;
	double *acc_aov;

	/* record mode */
	struct hit_ref *hit_ref;          /* per hit, beside hits */
	float *salpha;                    /* per sample */
	size_t *roff;                     /* sample si's contributions: [roff[si], roff[si + 1]) */
	uint32_t *rid;
	float *rw;
	size_t rcap;
	struct slot *slots;               /* the current pixel's ids, open addressing */
	uint32_t slot_bits, gen;
	uint32_t *cid;                    /* the current pixel's distinct ids and sums */
	double *cw;
	uint32_t cn;
	uint32_t *off;                    /* reyes_hider_end_record's output */
	size_t off_cap;
	struct reyes_vis_entry *ent;
	size_t ent_cap, nent;
	bool warned_overflow, warned_entries, warned_mode;

	/* solid modeling: the scene's trees, per-leaf scratch of the resolve */
	const struct reyes_csg *csg;
	bool csg_bucket;                  /* the bucket has hits of solids */
	int32_t *csg_count;               /* per node: crossings in front */
	uint8_t *csg_seen;                /* per node: the sample has crossed the leaf */
	uint32_t csg_cap;
	uint32_t *csg_touched;            /* the leaves the current sample crossed */
	size_t touched_cap;
};

/* ---- hashing ---- */

/* A 64-bit finaliser: a bijection with full avalanche. */
static uint64_t mix64(uint64_t h)
{
	h ^= h >> 30;
	h *= 0xbf58476d1ce4e5b9u;
	h ^= h >> 27;
	h *= 0x94d049bb133111ebu;
	h ^= h >> 31;
	return h;
}

static uint64_t key2(uint32_t a, uint32_t b, uint64_t salt)
{
	return mix64(((uint64_t)a << 32 | b) ^ salt);
}

/* ---- creation ---- */

static bool bad_opt(const char *what)
{
	fprintf(stderr, "relight: error: hider: %s\n", what);
	return false;
}

static bool check_opts(const struct reyes_hider_opts *o)
{
	if (o->xres == 0 || o->yres == 0)
		return bad_opt("image size is zero");
	if (o->xsamples == 0 || o->ysamples == 0 || o->xsamples > MAX_SAMPLES_AXIS ||
	    o->ysamples > MAX_SAMPLES_AXIS)
		return bad_opt("pixel samples out of range (1 to 256 per axis)");
	if ((uint64_t)o->xres * o->xsamples >= (1u << 30) ||
	    (uint64_t)o->yres * o->ysamples >= (1u << 30))
		return bad_opt("image too large for its pixel samples");
	if ((unsigned)o->filter > REYES_FILTER_SEP_GAUSSIAN)
		return bad_opt("unknown pixel filter");
	for (int i = 0; i < 2; i++) {
		if (!(o->filter_width[i] > 0.0f && o->filter_width[i] <= MAX_FILTER_WIDTH))
			return bad_opt("filter width out of range (0 to 64 pixels)");
	}
	if (!(o->opacity_threshold > 0.0f && o->opacity_threshold <= 1.0f))
		return bad_opt("opacity threshold out of range (0 to 1]");
	if ((unsigned)o->depthfilter > REYES_DEPTH_MIDPOINT)
		return bad_opt("unknown depth filter");
	if (o->naov > MAX_AOV)
		return bad_opt("too many output channels");
	if (!(o->lens[0] >= 0.0f && o->lens[1] >= 0.0f && isfinite(o->lens[0]) &&
	      isfinite(o->lens[1]) && o->focus >= 0.0f && isfinite(o->focus)))
		return bad_opt("lens out of range (aperture and 1 / focal distance finite, >= 0)");
	return true;
}

/*
 * Weights come from tables of reyes_filter_eval: per axis for the separable
 * filters (box, triangle, the Gaussians and sinc, whose value is
 * f(dx, 0) f(0, dy) / f(0, 0), and the constant divides out), and over r^2
 * for the radial Catmull-Rom.
 */
static void build_tables(struct reyes_hider *h)
{
	const struct reyes_hider_opts *o = &h->o;
	float xw = o->filter_width[0], yw = o->filter_width[1];

	h->hw = 0.5f * xw;
	h->hh = 0.5f * yw;
	h->radial = o->filter == REYES_FILTER_CATMULLROM;
	h->scx = (float)TAB_N / h->hw;
	h->scy = (float)TAB_N / h->hh;
	for (int i = 0; i <= TAB_N; i++) {
		float fx = h->hw * (float)i / (float)TAB_N;
		float fy = h->hh * (float)i / (float)TAB_N;
		h->tabx[i] = reyes_filter_eval(o->filter, fx < h->hw ? fx : h->hw, 0.0f, xw, yw);
		h->taby[i] = reyes_filter_eval(o->filter, 0.0f, fy < h->hh ? fy : h->hh, xw, yw);
	}
	h->tabx[TAB_N + 1] = h->tabx[TAB_N];
	h->taby[TAB_N + 1] = h->taby[TAB_N];

	h->r2max = h->hw * h->hw + h->hh * h->hh;
	if (h->r2max > 4.0f)
		h->r2max = 4.0f; /* the cubic is 0 beyond r = 2 */
	h->scr = (float)TAB_N / h->r2max;
	for (int i = 0; i <= TAB_N; i++) {
		float r = sqrtf(h->r2max * (float)i / (float)TAB_N);
		h->tabr[i] = reyes_filter_eval(REYES_FILTER_CATMULLROM, r, 0.0f, 8.0f, 8.0f);
	}
	h->tabr[TAB_N + 1] = h->tabr[TAB_N];

	/* Pixels whose samples (strictly inside the pixel) can lie in
	 * [-hw, hw) of a neighbour's centre: m < hw + 1/2. */
	h->mx = (uint32_t)(ceil((double)h->hw + 0.5) - 1.0);
	h->my = (uint32_t)(ceil((double)h->hh + 0.5) - 1.0);
}

struct reyes_hider *reyes_hider_create(const struct reyes_hider_opts *opts)
{
	if (!opts || !check_opts(opts))
		return NULL;
	struct reyes_hider *h = rl_xcalloc(1, sizeof(*h));
	h->o = *opts;
	h->nps = opts->xsamples * opts->ysamples;
	h->perm = rl_xmalloc(h->nps * sizeof(*h->perm));
	h->lperm = rl_xmalloc(h->nps * sizeof(*h->lperm));
	h->dof = opts->lens[0] > 0.0f || opts->lens[1] > 0.0f;
	h->acc_aov = rl_xcalloc(opts->naov ? opts->naov : 1, sizeof(*h->acc_aov));
	h->freelist = NIL;
	build_tables(h);
	return h;
}

size_t reyes_hider_sample_bytes(const struct reyes_hider *h)
{
	size_t K = 2 * h->mx + 1, L = 2 * h->my + 1, naov = h->o.naov;
	size_t b = sizeof(struct sample) + sizeof(float) + (K + L) * sizeof(float) +
		   sizeof(struct hit);
	if (h->o.record)
		b += sizeof(float) + sizeof(size_t) + sizeof(struct hit_ref);
	else
		b += (4 + 2 * naov) * sizeof(float);
	return b;
}

void reyes_hider_destroy(struct reyes_hider *h)
{
	if (!h)
		return;
	free(h->perm);
	free(h->lperm);
	free(h->samp);
	free(h->hits);
	free(h->hit_aov);
	free(h->scol);
	free(h->saov);
	free(h->sz);
	free(h->swx);
	free(h->swy);
	free(h->acc_aov);
	free(h->hit_ref);
	free(h->salpha);
	free(h->roff);
	free(h->rid);
	free(h->rw);
	free(h->slots);
	free(h->cid);
	free(h->cw);
	free(h->off);
	free(h->ent);
	free(h->csg_count);
	free(h->csg_seen);
	free(h->csg_touched);
	free(h);
}

/* ---- buckets ---- */

/* A float strictly inside (lo, lo + 1) for integer @lo. */
static float inside_pixel(double v, uint32_t lo)
{
	float f = (float)v, a = (float)lo, b = (float)(lo + 1);
	if (!(f > a))
		f = nextafterf(a, b);
	if (!(f < b))
		f = nextafterf(b, a);
	return f;
}

/* A Fisher-Yates shuffle of 0 .. n-1 into @perm, driven by the hash state @st. */
static void shuffle(uint32_t *perm, uint32_t n, uint64_t st)
{
	for (uint32_t k = 0; k < n; k++)
		perm[k] = k;
	for (uint32_t k = n; k > 1; k--) {
		st = mix64(st + 0x9e3779b97f4a7c15u);
		uint32_t r = (uint32_t)(((st >> 32) * k) >> 32);
		uint32_t tmp = perm[k - 1];
		perm[k - 1] = perm[r];
		perm[r] = tmp;
	}
}

/*
 * The concentric map of the unit square onto the unit disk (Shirley and
 * Chiu): squares around the centre go to rings, so strata keep their area
 * and stay compact.
 */
static void square_to_disk(double u, double v, float *x, float *y)
{
	double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0, r, phi;
	if (a == 0.0 && b == 0.0) {
		*x = *y = 0.0f;
		return;
	}
	if (fabs(a) > fabs(b)) {
		r = a;
		phi = 0.78539816339744831 * (b / a);
	} else {
		r = b;
		phi = 1.5707963267948966 - 0.78539816339744831 * (a / b);
	}
	*x = (float)(r * cos(phi));
	*y = (float)(r * sin(phi));
}

static void fill_samples(struct reyes_hider *h)
{
	const struct reyes_hider_opts *o = &h->o;
	uint32_t xs = o->xsamples, ys = o->ysamples, n = h->nps;
	uint64_t pixel_salt = mix64(o->seed + 0x9e3779b97f4a7c15u);
	uint64_t sample_salt = mix64(pixel_salt ^ 0x6a09e667f3bcc909u);
	uint64_t lens_pixel_salt = mix64(pixel_salt ^ 0xbb67ae8584caa73bu);
	uint64_t lens_salt = mix64(pixel_salt ^ 0x3c6ef372fe94f82bu);
	uint64_t lod_salt = mix64(sample_salt ^ 0xbb67ae8584caa73bu);
	double ixs = 1.0 / xs, iys = 1.0 / ys, in = 1.0 / n;

	for (uint32_t py = h->ry0; py < h->ry1; py++) {
		for (uint32_t px = h->rx0; px < h->rx1; px++) {
			/* The pixel's time strata, shuffled, and its lens strata. */
			shuffle(h->perm, n, key2(px, py, pixel_salt));
			if (h->dof)
				shuffle(h->lperm, n, key2(px, py, lens_pixel_salt));
			for (uint32_t j = 0; j < ys; j++) {
				uint32_t gy = py * ys + j;
				struct sample *row = h->samp + (size_t)(gy - h->gy0) * h->sw;
				for (uint32_t i = 0; i < xs; i++) {
					uint32_t gx = px * xs + i;
					struct sample *s = row + (gx - h->gx0);
					double u = 0.5, v = 0.5, w = 0.5;
					if (o->jitter) {
						/* 21 + 21 + 22 bits of one hash: x, y, time. */
						uint64_t k = key2(gx, gy, sample_salt);
						u = ((double)(k >> 43) + 0.5) * (1.0 / 2097152.0);
						v = ((double)((k >> 22) & 0x1fffff) + 0.5) *
						    (1.0 / 2097152.0);
						w = ((double)(k & 0x3fffff) + 0.5) *
						    (1.0 / 4194304.0);
					}
					s->x = inside_pixel(((double)gx + u) * ixs, px);
					s->y = inside_pixel(((double)gy + v) * iys, py);
					float t = (float)(((double)h->perm[j * xs + i] + w) * in);
					s->t = t < 1.0f ? t : nextafterf(1.0f, 0.0f);
					s->lu = s->lv = 0.0f;
					if (h->dof) {
						uint32_t c = h->lperm[j * xs + i];
						double a = 0.5, b = 0.5;
						if (o->jitter) {
							uint64_t k = key2(gx, gy, lens_salt);
							a = ((double)(k >> 32) + 0.5) * (1.0 / 4294967296.0);
							b = ((double)(k & 0xffffffffu) + 0.5) *
							    (1.0 / 4294967296.0);
						}
						square_to_disk(((double)(c % xs) + a) * ixs,
							       ((double)(c / xs) + b) * iys, &s->lu,
							       &s->lv);
					}
					s->zopq = INFINITY;
					s->head = NIL;
					s->zo[0] = s->zo[1] = INFINITY;
					/* 24 bits, so that a float holds it exactly */
					s->lod = (float)(key2(gx, gy, lod_salt) >> 40) *
						 (1.0f / 16777216.0f);
				}
			}
		}
	}
}

void reyes_hider_begin(struct reyes_hider *h, uint32_t px0, uint32_t py0, uint32_t px1,
		       uint32_t py1)
{
	if (!h)
		return;
	const struct reyes_hider_opts *o = &h->o;
	h->active = false;
	h->nhits = 0;
	h->freelist = NIL;
	h->inserted = 0;
	h->csg_bucket = false;
	px1 = px1 < o->xres ? px1 : o->xres;
	py1 = py1 < o->yres ? py1 : o->yres;
	if (px0 >= px1 || py0 >= py1) {
		h->px0 = h->px1 = h->py0 = h->py1 = 0;
		return;
	}
	h->px0 = px0;
	h->py0 = py0;
	h->px1 = px1;
	h->py1 = py1;
	h->rx0 = px0 > h->mx ? px0 - h->mx : 0;
	h->ry0 = py0 > h->my ? py0 - h->my : 0;
	h->rx1 = (uint64_t)px1 + h->mx < o->xres ? px1 + h->mx : o->xres;
	h->ry1 = (uint64_t)py1 + h->my < o->yres ? py1 + h->my : o->yres;
	h->gx0 = h->rx0 * o->xsamples;
	h->gy0 = h->ry0 * o->ysamples;
	h->sw = (h->rx1 - h->rx0) * o->xsamples;
	h->sh = (h->ry1 - h->ry0) * o->ysamples;

	size_t n = (size_t)h->sw * h->sh;
	if (n > h->samp_cap) {
		free(h->samp);
		h->samp = rl_xmalloc(n * sizeof(*h->samp));
		h->samp_cap = n;
	}
	fill_samples(h);
	h->active = true;
}

void reyes_hider_region(const struct reyes_hider *h, float *x0, float *y0, float *x1,
			float *y1)
{
	bool on = h && h->active;
	if (x0)
		*x0 = on ? (float)h->rx0 : 0.0f;
	if (y0)
		*y0 = on ? (float)h->ry0 : 0.0f;
	if (x1)
		*x1 = on ? (float)h->rx1 : 0.0f;
	if (y1)
		*y1 = on ? (float)h->ry1 : 0.0f;
}

/* ---- hit lists ---- */

static uint32_t alloc_hit(struct reyes_hider *h)
{
	if (h->freelist != NIL) {
		uint32_t i = h->freelist;
		h->freelist = h->hits[i].next;
		return i;
	}
	if (h->nhits == h->hits_cap) {
		if (h->hits_cap >= (NIL >> 1))
			return NIL;
		uint32_t cap = h->hits_cap ? h->hits_cap * 2 : 4096;
		h->hits = rl_xrealloc(h->hits, (size_t)cap * sizeof(*h->hits));
		if (h->o.record)
			h->hit_ref = rl_xrealloc(h->hit_ref, (size_t)cap * sizeof(*h->hit_ref));
		else if (h->o.naov)
			h->hit_aov = rl_xrealloc(h->hit_aov,
						 (size_t)cap * h->o.naov * sizeof(*h->hit_aov));
		h->hits_cap = cap;
	}
	return h->nhits++;
}

static void free_chain(struct reyes_hider *h, uint32_t i)
{
	while (i != NIL) {
		uint32_t next = h->hits[i].next;
		h->hits[i].next = h->freelist;
		h->freelist = i;
		i = next;
	}
}

static bool opaque3(const float T[3], float thr)
{
	float lim = 1.0f - thr;
	return T[0] <= lim && T[1] <= lim && T[2] <= lim;
}

static float clamp01(float v)
{
	return v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f; /* NaN -> 0 */
}

/* What a micropolygon gives a sample: its grid and the quad's vertex indices. */
struct mp_src {
	const struct reyes_hider_grid *g;
	size_t n;             /* points in the grid: the stride between planes */
	uint32_t q[4];
	uint32_t csg;         /* the grid's solid leaf (1 + node), 0: none */
	bool cull;            /* drop back-facing micropolygons (never in a solid) */
	bool front;           /* the micropolygon faces the camera */
};

/* A plane's value at the hit: weighted over the quad's vertices, or vertex (i, j)'s. */
static inline float plane_value(const float *plane, const struct mp_src *m, const float *w)
{
	if (!w)
		return plane[m->q[0]];
	return w[0] * plane[m->q[0]] + w[1] * plane[m->q[1]] + w[2] * plane[m->q[2]] +
	       w[3] * plane[m->q[3]];
}

static inline void hit_opacity(const struct mp_src *m, const float *w, float o[3])
{
	const float *Oi = m->g->Oi;
	if (!Oi) {
		o[0] = o[1] = o[2] = 1.0f;
		return;
	}
	o[0] = clamp01(plane_value(Oi, m, w));
	o[1] = clamp01(plane_value(Oi + m->n, m, w));
	o[2] = clamp01(plane_value(Oi + 2 * m->n, m, w));
}

static void sample_hit(struct reyes_hider *h, struct sample *s, float z, const struct mp_src *m,
		       const float *w)
{
	const struct reyes_hider_grid *g = m->g;
	float thr = h->o.opacity_threshold;
	float o[3];

	if (!(z > 0.0f))
		return;
	if (g->dissolve && !(s->lod >= g->lod_lo && s->lod < g->lod_hi))
		return;
	if (h->o.depthfilter == REYES_DEPTH_MIDPOINT) {
		hit_opacity(m, w, o);
		/* a solid's hits count once the sample is resolved (csg_resolve) */
		if (!m->csg && o[0] >= thr && o[1] >= thr && o[2] >= thr) {
			if (z < s->zo[0]) {
				s->zo[1] = s->zo[0];
				s->zo[0] = z;
			} else if (z < s->zo[1]) {
				s->zo[1] = z;
			}
		}
		if (!(z < s->zopq))
			return;
	} else {
		if (!(z < s->zopq))
			return;
		hit_opacity(m, w, o);
	}

	uint32_t ni = alloc_hit(h);
	if (ni == NIL)
		return;
	struct hit *nh = &h->hits[ni];
	nh->z = z;
	nh->matte = g->matte;
	nh->csg = m->csg ? m->csg | (m->front ? CSG_ENTER : 0) : 0;
	if (h->o.record) {
		/* The vertices' ids instead of colour; add() checked they fit. */
		struct hit_ref *r = &h->hit_ref[ni];
		int k = 0;
		if (!w) {
			r->id[k] = g->id0 + m->q[0];
			r->w[k++] = 1.0f;
		} else {
			for (int v = 0; v < 4 && k < 3; v++) {
				if (w[v] != 0.0f) {
					r->id[k] = g->id0 + m->q[v];
					r->w[k++] = w[v];
				}
			}
		}
		for (; k < 3; k++) {
			r->id[k] = 0;
			r->w[k] = 0.0f;
		}
		for (int c = 0; c < 3; c++) {
			nh->o[c] = o[c];
			nh->c[c] = 0.0f;
		}
	} else {
		for (int c = 0; c < 3; c++) {
			nh->o[c] = o[c];
			nh->c[c] = g->Ci ? plane_value(g->Ci + c * m->n, m, w) : 0.0f;
		}
	}
	if (h->o.naov && !h->o.record) {
		float *a = h->hit_aov + (size_t)ni * h->o.naov;
		for (uint32_t k = 0; k < h->o.naov; k++)
			a[k] = g->aov && g->aov[k] ? plane_value(g->aov[k], m, w) : 0.0f;
	}
	h->inserted++;

	/* Insert after the hits at or in front of z, tracking transmittance. */
	float T[3] = { 1.0f, 1.0f, 1.0f };
	uint32_t prev = NIL, cur = s->head;
	while (cur != NIL && h->hits[cur].z <= z) {
		const struct hit *c = &h->hits[cur];
		for (int k = 0; k < 3 && !c->csg; k++)
			T[k] *= 1.0f - c->o[k];
		prev = cur;
		cur = c->next;
	}
	nh = &h->hits[ni];
	nh->next = cur;
	if (prev == NIL)
		s->head = ni;
	else
		h->hits[prev].next = ni;

	/* Find where the sample now becomes opaque and drop what is behind
	 * (a solid's hits may yet be cut away: they hide nothing here). */
	for (uint32_t i = ni; i != NIL; i = h->hits[i].next) {
		struct hit *c = &h->hits[i];
		for (int k = 0; k < 3 && !c->csg; k++)
			T[k] *= 1.0f - c->o[k];
		if (opaque3(T, thr)) {
			s->zopq = c->z;
			free_chain(h, c->next);
			c->next = NIL;
			break;
		}
	}
}

/* ---- micropolygons ---- */

static void edge_init(struct edge *e, float x0, float y0, float x1, float y1)
{
	if (x0 < x1 || (x0 == x1 && y0 <= y1)) {
		e->ax = x0;
		e->ay = y0;
		e->dx = (double)x1 - x0;
		e->dy = (double)y1 - y0;
		e->sign = 1.0;
	} else {
		e->ax = x1;
		e->ay = y1;
		e->dx = (double)x0 - x1;
		e->dy = (double)y0 - y1;
		e->sign = -1.0;
	}
}

static double edge_eval(const struct edge *e, double px, double py)
{
	return e->dx * (py - e->ay) - e->dy * (px - e->ax);
}

/*
 * Set up triangle @t from quad edges used as a->b (@ab), b->c, c->a with the
 * direction multipliers @sab... (+1: as the edge is defined). The triangle's
 * area sign comes from the a->b edge function at c. Returns the signed area
 * (twice it), 0 when degenerate.
 */
static double tri_init(struct tri *t, const struct edge *e, int ab, double sab, int bc, double sbc,
		       int ca, double sca, double cx, double cy, uint8_t va, uint8_t vb, uint8_t vc)
{
	double area = sab * e[ab].sign * edge_eval(&e[ab], cx, cy);
	t->ok = area != 0.0 && isfinite(area);
	if (!t->ok)
		return 0.0;
	double o = area > 0.0 ? 1.0 : -1.0;
	/* Edge opposite a is b->c, opposite b is c->a, opposite c is a->b. */
	const int ei[3] = { bc, ca, ab };
	const double sd[3] = { sbc, sca, sab };
	for (int i = 0; i < 3; i++) {
		const struct edge *ed = &e[ei[i]];
		double k = o * sd[i] * ed->sign;
		t->ax[i] = ed->ax;
		t->ay[i] = ed->ay;
		t->A[i] = k * ed->dx;
		t->B[i] = k * ed->dy;
		/* Direction k * (dx, dy); moved right then down, the sample lands inside. */
		t->own[i] = t->B[i] < 0.0 || (t->B[i] == 0.0 && t->A[i] > 0.0);
	}
	t->v[0] = va;
	t->v[1] = vb;
	t->v[2] = vc;
	return area;
}

static float min4(const float v[4])
{
	float a = v[0] < v[1] ? v[0] : v[1], b = v[2] < v[3] ? v[2] : v[3];
	return a < b ? a : b;
}

static float max4(const float v[4])
{
	float a = v[0] > v[1] ? v[0] : v[1], b = v[2] > v[3] ? v[2] : v[3];
	return a > b ? a : b;
}

/* sample_hit, unless the hit's (u, v) is cut away by the grid's trim curve. */
static void trim_hit(struct reyes_hider *h, struct sample *s, float z, const struct mp_src *m,
		     const float *w)
{
	const struct reyes_hider_grid *g = m->g;
	if (g->trim && !reyes_trim_keeps(g->trim, plane_value(g->trim_uv, m, w),
					 plane_value(g->trim_uv + m->n, m, w)))
		return;
	sample_hit(h, s, z, m, g->smooth ? w : NULL);
}

/*
 * Build the quad's edges and triangles from raster vertices v0 = (i, j),
 * v1 = (i+1, j), v2 = (i+1, j+1), v3 = (i, j+1). False when it is culled or
 * has no area.
 */
static bool quad_init(struct quad *q, const float vx[4], const float vy[4], bool cull, bool flip)
{
	struct edge *e = q->e;
	edge_init(&e[0], vx[0], vy[0], vx[1], vy[1]);
	edge_init(&e[1], vx[1], vy[1], vx[2], vy[2]);
	edge_init(&e[2], vx[2], vy[2], vx[3], vy[3]);
	edge_init(&e[3], vx[3], vy[3], vx[0], vy[0]);
	edge_init(&e[4], vx[0], vy[0], vx[2], vy[2]);
	/* (v0, v1, v2): v0->v1, v1->v2, v2->v0 (the diagonal reversed). */
	double a1 = tri_init(&q->t[0], e, 0, 1.0, 1, 1.0, 4, -1.0, vx[2], vy[2], 0, 1, 2);
	/* (v0, v2, v3): v0->v2, v2->v3, v3->v0. */
	double a2 = tri_init(&q->t[1], e, 4, 1.0, 2, 1.0, 3, 1.0, vx[3], vy[3], 0, 2, 3);
	double area = a1 + a2;
	if (!(area != 0.0))
		return false;
	q->front = (area > 0.0) != flip;
	if (cull && !q->front)
		return false;
	/* NaN in the bound lets samples through to the edge tests, which reject them. */
	q->x0 = min4(vx);
	q->x1 = max4(vx);
	q->y0 = min4(vy);
	q->y1 = max4(vy);
	return q->t[0].ok || q->t[1].ok;
}

/*
 * Which triangle of @q holds (px, py): its barycentric weights go to w[4]
 * (per quad vertex) unless @w is NULL, and the interpolated depth of @vz to
 * *z. Returns false when the point is outside both.
 */
static bool quad_test(const struct quad *q, float fx, float fy, const float vz[4], float w[4],
		      float *z)
{
	if (fx < q->x0 || fx > q->x1 || fy < q->y0 || fy > q->y1)
		return false;
	double px = fx, py = fy;
	for (int ti = 0; ti < 2; ti++) {
		const struct tri *t = &q->t[ti];
		if (!t->ok)
			continue;
		double v[3];
		bool in = true;
		for (int i = 0; i < 3; i++) {
			v[i] = t->A[i] * (py - t->ay[i]) - t->B[i] * (px - t->ax[i]);
			in &= v[i] > 0.0 || (v[i] == 0.0 && t->own[i]);
		}
		if (!in)
			continue;
		double sum = v[0] + v[1] + v[2];
		if (!(sum > 0.0))
			continue;
		double inv = 1.0 / sum;
		*z = (float)((v[0] * vz[t->v[0]] + v[1] * vz[t->v[1]] + v[2] * vz[t->v[2]]) * inv);
		if (w) {
			w[0] = w[1] = w[2] = w[3] = 0.0f;
			for (int i = 0; i < 3; i++)
				w[t->v[i]] = (float)(v[i] * inv);
		}
		return true;
	}
	return false;
}

static float lerpf(float a, float b, float t)
{
	return a + (b - a) * t;
}

/* How far a vertex at depth @z moves per unit of lens position: 1/d - 1/z (0 behind the eye). */
static float defocus(const struct reyes_hider *h, float z)
{
	return z > 0.0f ? h->o.focus - 1.0f / z : 0.0f;
}

/* Sample index range [lo, hi] of raster interval [a, b] at @ns samples per pixel. */
static bool sample_range(double a, double b, uint32_t ns, uint32_t g0, uint32_t g1, uint32_t *lo,
			 uint32_t *hi)
{
	double fa = floor(a * ns - 1e-4), fb = floor(b * ns + 1e-4);
	if (!(fb >= (double)g0 && fa < (double)g1))
		return false;
	*lo = fa <= (double)g0 ? g0 : (uint32_t)fa;
	*hi = fb >= (double)(g1 - 1) ? g1 - 1 : (uint32_t)fb;
	return *lo <= *hi;
}

static void id_overflow(struct reyes_hider *h, const struct reyes_hider_grid *g)
{
	if (h->warned_overflow)
		return;
	h->warned_overflow = true;
	fprintf(stderr,
		"relight: error: hider: shading sample ids pass 2^32 - 1 (a %ux%u grid from id "
		"%u); its micropolygons past that are dropped\n",
		g->nu, g->nv, g->id0);
}

/*
 * A still quad seen through the lens: each vertex moves by its own
 * defocus times the sample's lens position. Most samples of the widened
 * bound miss the quad; a bound of the moved quad from the extremes of the
 * vertices' moves (with a margin far above rounding) rejects them before
 * the exact test.
 */
static void add_defocused(struct reyes_hider *h, struct mp_src *m, struct quad *q,
			  const float vx[4], const float vy[4], const float vz[4], uint32_t sx0,
			  uint32_t sx1, uint32_t sy0, uint32_t sy1)
{
	const struct reyes_hider_grid *g = m->g;
	float dx[4], dy[4];
	for (int k = 0; k < 4; k++) {
		float c = defocus(h, vz[k]);
		dx[k] = h->o.lens[0] * c;
		dy[k] = h->o.lens[1] * c;
	}
	const float slack = 1e-3f;
	float x0 = min4(vx) - slack, x1 = max4(vx) + slack;
	float y0 = min4(vy) - slack, y1 = max4(vy) + slack;
	float dx0 = min4(dx), dx1 = max4(dx), dy0 = min4(dy), dy1 = max4(dy);
	for (uint32_t gy = sy0; gy <= sy1; gy++) {
		struct sample *row = h->samp + (size_t)(gy - h->gy0) * h->sw;
		for (uint32_t gx = sx0; gx <= sx1; gx++) {
			struct sample *s = row + (gx - h->gx0);
			float lu = s->lu, lv = s->lv;
			float ax = lu >= 0.0f ? lu * dx0 : lu * dx1, bx = lu >= 0.0f ? lu * dx1 : lu * dx0;
			float ay = lv >= 0.0f ? lv * dy0 : lv * dy1, by = lv >= 0.0f ? lv * dy1 : lv * dy0;
			if (s->x < x0 + ax || s->x > x1 + bx || s->y < y0 + ay || s->y > y1 + by)
				continue;
			float tx[4], ty[4], w[4], z;
			for (int k = 0; k < 4; k++) {
				tx[k] = vx[k] + lu * dx[k];
				ty[k] = vy[k] + lv * dy[k];
			}
			float *wp = g->smooth || g->trim ? w : NULL;
			if (!quad_init(q, tx, ty, m->cull, g->flip) ||
			    !quad_test(q, s->x, s->y, vz, wp, &z))
				continue;
			m->front = q->front;
			trim_hit(h, s, z, m, wp);
		}
	}
}

/*
 * A grid of a solid is about to be sampled: make room for its tree's
 * scratch. False (the grid is then sampled as if in no solid) when its
 * leaf is not a node of its tree.
 */
static bool csg_begin_grid(struct reyes_hider *h, const struct reyes_hider_grid *g)
{
	const struct reyes_csg *csg = g->csg;
	if (!csg || g->csg_leaf > csg->nnodes || g->csg_leaf >= CSG_ENTER)
		return false;
	if (csg->nnodes > h->csg_cap) {
		free(h->csg_count);
		free(h->csg_seen);
		h->csg_count = rl_xcalloc(csg->nnodes, sizeof(*h->csg_count));
		h->csg_seen = rl_xcalloc(csg->nnodes, sizeof(*h->csg_seen));
		h->csg_cap = csg->nnodes;
	}
	h->csg = csg;
	h->csg_bucket = true;
	return true;
}

void reyes_hider_add(struct reyes_hider *h, const struct reyes_hider_grid *g)
{
	if (!h || !h->active || !g || g->nu < 2 || g->nv < 2 || !g->x[0] || !g->y[0] ||
	    !g->z[0])
		return;
	if ((uint64_t)g->nu * g->nv > 0xffffffffu)
		return;
	const struct reyes_hider_opts *o = &h->o;
	const float *X0 = g->x[0], *Y0 = g->y[0], *Z0 = g->z[0];
	const float *X1 = g->x[1] ? g->x[1] : X0;
	const float *Y1 = g->y[1] ? g->y[1] : Y0;
	const float *Z1 = g->z[1] ? g->z[1] : Z0;
	bool dof = h->dof;
	float lx = o->lens[0], ly = o->lens[1];
	double rx0 = h->rx0, rx1 = h->rx1, ry0 = h->ry0, ry1 = h->ry1;
	uint32_t gx1 = h->gx0 + h->sw, gy1 = h->gy0 + h->sh;
	struct mp_src m = { .g = g, .n = (size_t)g->nu * g->nv, .cull = g->cull_backfacing };
	struct quad q;
	if (g->csg_leaf && csg_begin_grid(h, g)) {
		m.csg = g->csg_leaf;
		m.cull = false;
	}
	/* Record mode: vertex k is shading sample id0 + k, so k < nid. */
	bool record = o->record;
	uint64_t nid = (uint64_t)UINT32_MAX - g->id0 + 1;

	for (uint32_t j = 0; j + 1 < g->nv; j++) {
		for (uint32_t i = 0; i + 1 < g->nu; i++) {
			uint32_t base = j * g->nu + i;
			m.q[0] = base;
			m.q[1] = base + 1;
			m.q[2] = base + g->nu + 1;
			m.q[3] = base + g->nu;
			float vx[4], vy[4], vz[4];
			bool moves = false;
			float x1[4], y1[4], z1[4];
			for (int k = 0; k < 4; k++) {
				uint32_t p = m.q[k];
				vx[k] = X0[p];
				vy[k] = Y0[p];
				vz[k] = Z0[p];
				x1[k] = X1[p];
				y1[k] = Y1[p];
				z1[k] = Z1[p];
				moves |= x1[k] != vx[k] || y1[k] != vy[k] || z1[k] != vz[k];
			}
			float xmin = min4(vx), xmax = max4(vx), ymin = min4(vy), ymax = max4(vy);
			if (moves) {
				float a = min4(x1), b = max4(x1), c = min4(y1), d = max4(y1);
				xmin = a < xmin ? a : xmin;
				xmax = b > xmax ? b : xmax;
				ymin = c < ymin ? c : ymin;
				ymax = d > ymax ? d : ymax;
			}
			if (dof) {
				/* 1/z is monotonic along each vertex's path: its extremes are
				 * at the shutter's ends. */
				float c = 0.0f;
				for (int k = 0; k < 4; k++) {
					float c0 = fabsf(defocus(h, vz[k])), c1 = fabsf(defocus(h, z1[k]));
					c = c0 > c ? c0 : c;
					c = c1 > c ? c1 : c;
				}
				xmin -= c * lx;
				xmax += c * lx;
				ymin -= c * ly;
				ymax += c * ly;
			}
			/* A NaN coordinate can hide in the bound; the edge tests,
			 * where NaN compares false, reject its samples. */
			if (!(xmax >= rx0 && xmin <= rx1 && ymax >= ry0 && ymin <= ry1))
				continue;
			uint32_t sx0, sx1, sy0, sy1;
			if (!sample_range(xmin, xmax, o->xsamples, h->gx0, gx1, &sx0, &sx1) ||
			    !sample_range(ymin, ymax, o->ysamples, h->gy0, gy1, &sy0, &sy1))
				continue;
			/* q[2] is the quad's largest vertex index; flat shading uses q[0]. */
			if (record && (g->smooth ? m.q[2] : m.q[0]) >= nid) {
				id_overflow(h, g);
				continue;
			}

			if (!moves && !dof) {
				if (!quad_init(&q, vx, vy, m.cull, g->flip))
					continue;
				m.front = q.front;
				for (uint32_t gy = sy0; gy <= sy1; gy++) {
					size_t row = (size_t)(gy - h->gy0) * h->sw;
					for (uint32_t gx = sx0; gx <= sx1; gx++) {
						struct sample *s = h->samp + row + (gx - h->gx0);
						float w[4], z;
						float *wp = g->smooth || g->trim ? w : NULL;
						if (!quad_test(&q, s->x, s->y, vz, wp, &z))
							continue;
						trim_hit(h, s, z, &m, wp);
					}
				}
				continue;
			}

			if (!moves) {
				add_defocused(h, &m, &q, vx, vy, vz, sx0, sx1, sy0, sy1);
				continue;
			}

			/* Moving (and maybe seen through a lens): each sample sees the
			 * quad at its own time, from its own lens position. Through a
			 * lens, the quad at the sample's time with the extremes of its
			 * vertices' defocus over the shutter (1/z is monotonic along
			 * each path) bounds it, and rejects most samples cheaply. */
			float c0 = 0.0f, c1 = 0.0f;
			if (dof) {
				c0 = c1 = defocus(h, vz[0]);
				for (int k = 0; k < 4; k++) {
					float a = defocus(h, vz[k]), b = defocus(h, z1[k]);
					c0 = fminf(c0, fminf(a, b));
					c1 = fmaxf(c1, fmaxf(a, b));
				}
			}
			for (uint32_t gy = sy0; gy <= sy1; gy++) {
				struct sample *row = h->samp + (size_t)(gy - h->gy0) * h->sw;
				for (uint32_t gx = sx0; gx <= sx1; gx++) {
					struct sample *s = row + (gx - h->gx0);
					float tx[4], ty[4], tz[4], w[4], z;
					for (int k = 0; k < 4; k++) {
						tx[k] = lerpf(vx[k], x1[k], s->t);
						ty[k] = lerpf(vy[k], y1[k], s->t);
					}
					if (dof) {
						const float slack = 1e-3f;
						float ux = s->lu * lx, uy = s->lv * ly;
						float ax = ux >= 0.0f ? ux * c0 : ux * c1;
						float bx = ux >= 0.0f ? ux * c1 : ux * c0;
						float ay = uy >= 0.0f ? uy * c0 : uy * c1;
						float by = uy >= 0.0f ? uy * c1 : uy * c0;
						if (s->x < min4(tx) + ax - slack || s->x > max4(tx) + bx + slack ||
						    s->y < min4(ty) + ay - slack || s->y > max4(ty) + by + slack)
							continue;
					}
					for (int k = 0; k < 4; k++)
						tz[k] = lerpf(vz[k], z1[k], s->t);
					if (dof) {
						for (int k = 0; k < 4; k++) {
							float c = defocus(h, tz[k]);
							tx[k] += s->lu * lx * c;
							ty[k] += s->lv * ly * c;
						}
					}
					/* quad_test's own bound test, before the edges are built:
					 * most samples of a blurred quad's bound miss it. */
					if (s->x < min4(tx) || s->x > max4(tx) || s->y < min4(ty) ||
					    s->y > max4(ty))
						continue;
					float *wp = g->smooth || g->trim ? w : NULL;
					if (!quad_init(&q, tx, ty, m.cull, g->flip) ||
					    !quad_test(&q, s->x, s->y, tz, wp, &z))
						continue;
					m.front = q.front;
					trim_hit(h, s, z, &m, wp);
				}
			}
		}
	}
}

/* ---- resolving the bucket ---- */

static float tab_lookup(const float *tab, float scale, float a)
{
	float f = a * scale;
	int i = (int)f;
	if (i >= TAB_N)
		return tab[TAB_N];
	float r = f - (float)i;
	return tab[i] + (tab[i + 1] - tab[i]) * r;
}

/* The radial Catmull-Rom's weight; (dx, dy) within the support rectangle. */
static float radial_weight(const struct reyes_hider *h, float dx, float dy)
{
	float r2 = dx * dx + dy * dy;
	if (r2 >= h->r2max)
		return h->r2max < 4.0f ? h->tabr[TAB_N] : 0.0f;
	return tab_lookup(h->tabr, h->scr, r2);
}

/*
 * For the separable filters, each sample's weight factors toward the pixel
 * columns and rows around it: wx[si * K + k] for pixel column
 * (the sample's column - mx + k), 0 outside the support [-hw, hw); wy alike.
 */
static void axis_weights(struct reyes_hider *h)
{
	const struct reyes_hider_opts *o = &h->o;
	uint32_t K = 2 * h->mx + 1, L = 2 * h->my + 1;
	float hw = h->hw, hh = h->hh;
	for (uint32_t sy = 0; sy < h->sh; sy++) {
		uint32_t spy = (h->gy0 + sy) / o->ysamples;
		uint32_t spx = h->gx0 / o->xsamples, i = 0;
		for (uint32_t sx = 0; sx < h->sw; sx++) {
			size_t si = (size_t)sy * h->sw + sx;
			const struct sample *s = &h->samp[si];
			float *wx = h->swx + si * K, *wy = h->swy + si * L;
			/* Offsets to the centres of pixels spx - mx + k: bx - k. */
			float bx = (s->x - (float)spx) - 0.5f + (float)h->mx;
			float by = (s->y - (float)spy) - 0.5f + (float)h->my;
			for (uint32_t k = 0; k < K; k++) {
				float dx = bx - (float)k;
				bool in = dx >= -hw && dx < hw;
				wx[k] = in ? tab_lookup(h->tabx, h->scx, fabsf(dx)) : 0.0f;
			}
			for (uint32_t k = 0; k < L; k++) {
				float dy = by - (float)k;
				bool in = dy >= -hh && dy < hh;
				wy[k] = in ? tab_lookup(h->taby, h->scy, fabsf(dy)) : 0.0f;
			}
			if (++i == o->xsamples) {
				i = 0;
				spx++;
			}
		}
	}
}

/* Where the sample became opaque, or for midpoint halfway between its two nearest opaque hits. */
static float sample_depth(const struct reyes_hider *h, const struct sample *s)
{
	if (h->o.depthfilter == REYES_DEPTH_MIDPOINT)
		return s->zo[1] < INFINITY ? 0.5f * (s->zo[0] + s->zo[1]) : INFINITY;
	return s->zopq;
}

/* ---- solids ---- */

/* Seed each leaf the sample crosses with its count in front of the first crossing. */
static uint32_t csg_seed(struct reyes_hider *h, const struct sample *s)
{
	uint32_t nt = 0;
	for (uint32_t i = s->head; i != NIL; i = h->hits[i].next) {
		uint32_t c = h->hits[i].csg;
		uint32_t leaf = (c & ~CSG_ENTER) - 1;
		if (!c || h->csg_seen[leaf])
			continue;
		if (nt == h->touched_cap) {
			h->touched_cap = h->touched_cap ? 2 * h->touched_cap : 64;
			h->csg_touched = rl_xrealloc(h->csg_touched,
						     h->touched_cap * sizeof(*h->csg_touched));
		}
		h->csg_touched[nt++] = leaf;
		h->csg_seen[leaf] = 1;
		/* first crossed on the way out: the eye is inside */
		h->csg_count[leaf] = c & CSG_ENTER ? 0 : 1;
	}
	return nt;
}

/* Does crossing @c change the value of its leaf's tree? */
static bool csg_crosses(struct reyes_hider *h, uint32_t c)
{
	uint32_t leaf = (c & ~CSG_ENTER) - 1, root = h->csg->nodes[leaf].root;
	bool before = reyes_csg_inside(h->csg, root, h->csg_count);
	h->csg_count[leaf] += c & CSG_ENTER ? 1 : -1;
	return reyes_csg_inside(h->csg, root, h->csg_count) != before;
}

/* Unlink the sample's solid hits that do not bound their solid; its opaque point again. */
static void csg_resolve(struct reyes_hider *h, struct sample *s)
{
	uint32_t nt = csg_seed(h, s);
	if (!nt)
		return;
	uint32_t prev = NIL, next;
	for (uint32_t i = s->head; i != NIL; i = next) {
		struct hit *c = &h->hits[i];
		next = c->next;
		if (c->csg && !csg_crosses(h, c->csg)) {
			if (prev == NIL)
				s->head = next;
			else
				h->hits[prev].next = next;
			c->next = h->freelist;
			h->freelist = i;
			continue;
		}
		prev = i;
	}
	for (uint32_t k = 0; k < nt; k++)
		h->csg_seen[h->csg_touched[k]] = 0;

	/* The solid's hits that are opaque by themselves join the midpoint's
	   depths; the opaque point is at or in front of the other hits' (their
	   hits are all still there). */
	float T[3] = { 1.0f, 1.0f, 1.0f }, thr = h->o.opacity_threshold;
	for (uint32_t i = s->head; h->o.depthfilter == REYES_DEPTH_MIDPOINT && i != NIL;
	     i = h->hits[i].next) {
		const struct hit *c = &h->hits[i];
		if (!c->csg || !(c->o[0] >= thr && c->o[1] >= thr && c->o[2] >= thr))
			continue;
		if (c->z < s->zo[0]) {
			s->zo[1] = s->zo[0];
			s->zo[0] = c->z;
		} else if (c->z < s->zo[1]) {
			s->zo[1] = c->z;
		}
	}
	s->zopq = INFINITY;
	for (uint32_t i = s->head; i != NIL; i = h->hits[i].next) {
		struct hit *c = &h->hits[i];
		for (int k = 0; k < 3; k++)
			T[k] *= 1.0f - c->o[k];
		if (opaque3(T, thr)) {
			s->zopq = c->z;
			free_chain(h, c->next);
			c->next = NIL;
			break;
		}
	}
}

/* Resolve the solids of every sample of the region (a bucket with none has no work). */
static void csg_resolve_all(struct reyes_hider *h, size_t n)
{
	if (!h->csg_bucket)
		return;
	for (size_t si = 0; si < n; si++)
		csg_resolve(h, &h->samp[si]);
}

/* Composite every sample of the region front to back. */
static void composite(struct reyes_hider *h, size_t n)
{
	uint32_t naov = h->o.naov;
	csg_resolve_all(h, n);
	for (size_t si = 0; si < n; si++) {
		const struct sample *s = &h->samp[si];
		float *col = h->scol + si * 4;
		float *aov = naov ? h->saov + si * naov : NULL;
		float T[3] = { 1.0f, 1.0f, 1.0f }, C[3] = { 0, 0, 0 }, A[3] = { 0, 0, 0 };
		for (uint32_t k = 0; k < naov; k++)
			aov[k] = 0.0f;
		for (uint32_t i = s->head; i != NIL; i = h->hits[i].next) {
			const struct hit *c = &h->hits[i];
			if (!c->matte) {
				for (int k = 0; k < 3; k++) {
					C[k] += T[k] * c->c[k];
					A[k] += T[k] * c->o[k];
				}
				if (naov) {
					float tm = (T[0] + T[1] + T[2]) * (1.0f / 3.0f);
					const float *ha = h->hit_aov + (size_t)i * naov;
					for (uint32_t k = 0; k < naov; k++)
						aov[k] += tm * ha[k];
				}
			}
			for (int k = 0; k < 3; k++)
				T[k] *= 1.0f - c->o[k];
		}
		col[0] = C[0];
		col[1] = C[1];
		col[2] = C[2];
		col[3] = (A[0] + A[1] + A[2]) * (1.0f / 3.0f);
		h->sz[si] = sample_depth(h, s);
	}
}

/*
 * The samples pixel (x, y) filters: columns [sx0, sx1) and rows [sy0, sy1)
 * of the region's sample grid. kx0 is which of the K pixel columns around
 * sample column sx0 the pixel is (it steps down each time the stratum
 * index, starting at i0, wraps).
 */
struct support {
	uint32_t sx0, sx1, sy0, sy1, kx0, i0;
};

static void pixel_support(const struct reyes_hider *h, uint32_t x, uint32_t y, struct support *sp)
{
	uint32_t xs = h->o.xsamples, ys = h->o.ysamples;
	float hw = h->hw, hh = h->hh;
	float cx = (float)x + 0.5f, cy = (float)y + 0.5f;
	/* Strata overlapping the support, within the region: stratum gx spans
	 * (gx, gx + 1) / xsamples. */
	int64_t gxl = (int64_t)floor(((double)cx - hw) * xs);
	int64_t gxh = (int64_t)ceil(((double)cx + hw) * xs);
	int64_t gyl = (int64_t)floor(((double)cy - hh) * ys);
	int64_t gyh = (int64_t)ceil(((double)cy + hh) * ys);
	sp->sx0 = gxl > (int64_t)h->gx0 ? (uint32_t)gxl - h->gx0 : 0;
	sp->sy0 = gyl > (int64_t)h->gy0 ? (uint32_t)gyl - h->gy0 : 0;
	sp->sx1 = gxh < (int64_t)h->gx0 + h->sw ? (uint32_t)gxh - h->gx0 : h->sw;
	sp->sy1 = gyh < (int64_t)h->gy0 + h->sh ? (uint32_t)gyh - h->gy0 : h->sh;
	sp->kx0 = x + h->mx - (h->gx0 + sp->sx0) / xs;
	sp->i0 = (h->gx0 + sp->sx0) % xs;
}

/*
 * Filter the samples around pixel (x, y) into @rgba (4 floats) and @aov
 * (naov floats); either may be NULL. Samples are visited in row-major image
 * order whatever the bucket, so every bucketing gives the same sums.
 */
static void filter_pixel(struct reyes_hider *h, uint32_t x, uint32_t y, float *rgba, float *aov)
{
	const struct reyes_hider_opts *o = &h->o;
	uint32_t xs = o->xsamples, ys = o->ysamples, naov = aov ? o->naov : 0;
	uint32_t K = 2 * h->mx + 1, L = 2 * h->my + 1;
	const struct sample *samp = h->samp;
	const float *scol = h->scol, *saov = h->saov, *swx = h->swx, *swy = h->swy;
	double *acc_aov = h->acc_aov;
	bool radial = h->radial;
	float hw = h->hw, hh = h->hh;
	float cx = (float)x + 0.5f, cy = (float)y + 0.5f;
	struct support sp;
	pixel_support(h, x, y, &sp);
	uint32_t sx0 = sp.sx0, sx1 = sp.sx1, sy0 = sp.sy0, sy1 = sp.sy1, kx0 = sp.kx0, i0 = sp.i0;
	double acc[4] = { 0, 0, 0, 0 }, wsum = 0.0;

	for (uint32_t k = 0; k < naov; k++)
		acc_aov[k] = 0.0;
	for (uint32_t sy = sy0; sy < sy1; sy++) {
		uint32_t ky = y + h->my - (h->gy0 + sy) / ys;
		size_t rowi = (size_t)sy * h->sw;
		uint32_t kx = kx0, i = i0;
		for (uint32_t sx = sx0; sx < sx1; sx++) {
			size_t si = rowi + sx;
			float w;
			if (radial) {
				float dx = samp[si].x - cx, dy = samp[si].y - cy;
				bool in = dx >= -hw && dx < hw && dy >= -hh && dy < hh;
				w = in ? radial_weight(h, dx, dy) : 0.0f;
			} else {
				w = swx[si * K + kx] * swy[si * L + ky];
			}
			if (++i == xs) {
				i = 0;
				kx--;
			}
			if (w == 0.0f)
				continue;
			const float *c = scol + si * 4;
			acc[0] += (double)w * c[0];
			acc[1] += (double)w * c[1];
			acc[2] += (double)w * c[2];
			acc[3] += (double)w * c[3];
			wsum += w;
			if (naov) {
				const float *a = saov + si * naov;
				for (uint32_t k = 0; k < naov; k++)
					acc_aov[k] += (double)w * a[k];
			}
		}
	}
	double inv = wsum != 0.0 ? 1.0 / wsum : 0.0;
	if (rgba) {
		for (int k = 0; k < 4; k++)
			rgba[k] = (float)(acc[k] * inv);
	}
	for (uint32_t k = 0; k < naov; k++)
		aov[k] = (float)(acc_aov[k] * inv);
}

static float pixel_depth(const struct reyes_hider *h, uint32_t x, uint32_t y)
{
	const struct reyes_hider_opts *o = &h->o;
	uint32_t sx0 = x * o->xsamples - h->gx0, sy0 = y * o->ysamples - h->gy0;
	float zmin = INFINITY, zmax = -INFINITY;
	double sum = 0.0;
	uint32_t nhit = 0;
	for (uint32_t j = 0; j < o->ysamples; j++) {
		const float *row = h->sz + (size_t)(sy0 + j) * h->sw + sx0;
		for (uint32_t i = 0; i < o->xsamples; i++) {
			float z = row[i];
			zmin = z < zmin ? z : zmin;
			zmax = z > zmax ? z : zmax;
			if (z < INFINITY) {
				sum += z;
				nhit++;
			}
		}
	}
	float z;
	switch (o->depthfilter) {
	case REYES_DEPTH_MAX:
		z = zmax;
		break;
	case REYES_DEPTH_AVERAGE:
		z = nhit ? (float)(sum / nhit) : INFINITY;
		break;
	case REYES_DEPTH_MIN:
	case REYES_DEPTH_MIDPOINT:
	default:
		z = zmin;
		break;
	}
	return z < INFINITY ? z : NO_DEPTH;
}

uint32_t reyes_hider_sample_hits(const struct reyes_hider *h, uint32_t x, uint32_t y, uint32_t k,
				 float *z, float *o, uint32_t cap)
{
	if (!h || !h->active || x < h->px0 || x >= h->px1 || y < h->py0 || y >= h->py1 ||
	    k >= h->nps)
		return 0;
	uint32_t xs = h->o.xsamples;
	size_t si = (size_t)(y * h->o.ysamples + k / xs - h->gy0) * h->sw +
		    (x * xs + k % xs - h->gx0);
	uint32_t n = 0;
	for (uint32_t i = h->samp[si].head; i != NIL; i = h->hits[i].next, n++) {
		if (n >= cap)
			continue;
		const struct hit *c = &h->hits[i];
		z[n] = c->z;
		o[n] = (c->o[0] + c->o[1] + c->o[2]) * (1.0f / 3.0f);
	}
	return n;
}

/* Per-sample scratch for resolving @n samples (the mode's own arrays). */
static void grow_scratch(struct reyes_hider *h, size_t n)
{
	if (n <= h->scratch_cap)
		return;
	uint32_t K = 2 * h->mx + 1, L = 2 * h->my + 1, naov = h->o.naov;
	free(h->scol);
	free(h->saov);
	free(h->sz);
	free(h->swx);
	free(h->swy);
	free(h->salpha);
	free(h->roff);
	h->scol = h->saov = h->salpha = NULL;
	h->roff = NULL;
	if (h->o.record) {
		h->salpha = rl_xmalloc(n * sizeof(float));
		h->roff = rl_xmalloc((n + 1) * sizeof(*h->roff));
	} else {
		h->scol = rl_xmalloc(n * 4 * sizeof(float));
		h->saov = naov ? rl_xmalloc(n * naov * sizeof(float)) : NULL;
	}
	h->sz = rl_xmalloc(n * sizeof(float));
	h->swx = rl_xmalloc(n * K * sizeof(float));
	h->swy = rl_xmalloc(n * L * sizeof(float));
	h->scratch_cap = n;
}

/* Report a call the hider's mode does not allow, once per hider. */
static void wrong_mode(struct reyes_hider *h, const char *call)
{
	if (h->warned_mode)
		return;
	h->warned_mode = true;
	fprintf(stderr, "relight: error: hider: %s on a hider %s record mode\n", call,
		h->o.record ? "in" : "not in");
}

uint64_t reyes_hider_end(struct reyes_hider *h, float *rgba, float *zout, float *aovout)
{
	if (!h || !h->active)
		return 0;
	const struct reyes_hider_opts *o = &h->o;
	uint32_t naov = o->naov;
	uint32_t bw = h->px1 - h->px0;
	size_t n = (size_t)h->sw * h->sh;
	h->active = false;

	if (h->inserted == 0 || o->record) {
		/* Nothing was hit (or a record-mode hider, which has no
		 * colours): empty pixels, without the filter. */
		if (o->record)
			wrong_mode(h, "reyes_hider_end");
		for (uint32_t y = h->py0; y < h->py1; y++) {
			for (uint32_t x = h->px0; x < h->px1; x++) {
				size_t p = (size_t)(y - h->py0) * bw + (x - h->px0);
				if (rgba)
					memset(rgba + p * 4, 0, 4 * sizeof(float));
				if (zout)
					zout[p] = NO_DEPTH;
				if (aovout && naov)
					memset(aovout + p * naov, 0, naov * sizeof(float));
			}
		}
		return o->record ? 0 : n;
	}

	grow_scratch(h, n);
	composite(h, n);
	if (!h->radial)
		axis_weights(h);

	for (uint32_t y = h->py0; y < h->py1; y++) {
		for (uint32_t x = h->px0; x < h->px1; x++) {
			size_t p = (size_t)(y - h->py0) * bw + (x - h->px0);
			if (rgba || (aovout && naov))
				filter_pixel(h, x, y, rgba ? rgba + p * 4 : NULL,
					     aovout ? aovout + p * naov : NULL);
			if (zout)
				zout[p] = pixel_depth(h, x, y);
		}
	}
	return n;
}

/* ---- record mode ---- */

/*
 * Composite every sample of the region front to back into its list of
 * (id, weight) contributions, its alpha (as composite() computes it) and
 * its depth.
 */
static void composite_record(struct reyes_hider *h, size_t n)
{
	csg_resolve_all(h, n);
	/* At most three vertices per hit that is still in a list. */
	size_t need = (size_t)h->nhits * 3;
	if (need > h->rcap) {
		free(h->rid);
		free(h->rw);
		h->rid = rl_xmalloc(need * sizeof(*h->rid));
		h->rw = rl_xmalloc(need * sizeof(*h->rw));
		h->rcap = need;
	}
	uint32_t *rid = h->rid;
	float *rw = h->rw;
	size_t nr = 0;
	for (size_t si = 0; si < n; si++) {
		const struct sample *s = &h->samp[si];
		float T[3] = { 1.0f, 1.0f, 1.0f }, A[3] = { 0, 0, 0 };
		h->roff[si] = nr;
		for (uint32_t i = s->head; i != NIL; i = h->hits[i].next) {
			const struct hit *c = &h->hits[i];
			if (!c->matte) {
				float tm = (T[0] + T[1] + T[2]) * (1.0f / 3.0f);
				const struct hit_ref *r = &h->hit_ref[i];
				for (int k = 0; k < 3; k++) {
					A[k] += T[k] * c->o[k];
					float v = tm * r->w[k];
					if (v != 0.0f) {
						rid[nr] = r->id[k];
						rw[nr++] = v;
					}
				}
			}
			for (int k = 0; k < 3; k++)
				T[k] *= 1.0f - c->o[k];
		}
		h->salpha[si] = (A[0] + A[1] + A[2]) * (1.0f / 3.0f);
		h->sz[si] = sample_depth(h, s);
	}
	h->roff[n] = nr;
}

/* Start a pixel's table of ids empty (stale slots are told by their generation). */
static void acc_clear(struct reyes_hider *h)
{
	h->cn = 0;
	if (++h->gen == 0) {
		memset(h->slots, 0, ((size_t)1 << h->slot_bits) * sizeof(*h->slots));
		h->gen = 1;
	}
}

static inline uint32_t slot_of(uint32_t id, uint32_t bits)
{
	return (uint32_t)(id * 0x9e3779b1u) >> (32 - bits);
}

/* Double the table (and the dense list) and put the pixel's ids back. */
static void acc_grow(struct reyes_hider *h)
{
	uint32_t bits = h->slot_bits ? h->slot_bits + 1 : 6;
	size_t cap = (size_t)1 << bits;
	free(h->slots);
	h->slots = rl_xcalloc(cap, sizeof(*h->slots));
	h->slot_bits = bits;
	h->gen = 1;
	h->cid = rl_xrealloc(h->cid, cap / 2 * sizeof(*h->cid));
	h->cw = rl_xrealloc(h->cw, cap / 2 * sizeof(*h->cw));
	uint32_t mask = (uint32_t)cap - 1;
	for (uint32_t k = 0; k < h->cn; k++) {
		uint32_t p = slot_of(h->cid[k], bits);
		while (h->slots[p].gen == h->gen)
			p = (p + 1) & mask;
		h->slots[p] = (struct slot){ .id = h->cid[k], .gen = h->gen, .idx = k };
	}
}

/* Add @w to the pixel's sum for @id. */
static inline void acc_add(struct reyes_hider *h, uint32_t id, double w)
{
	uint32_t bits = h->slot_bits, mask = ((uint32_t)1 << bits) - 1, gen = h->gen;
	struct slot *slots = h->slots;
	for (uint32_t p = slot_of(id, bits);; p = (p + 1) & mask) {
		struct slot *sl = &slots[p];
		if (sl->gen != gen) {
			uint32_t k = h->cn++;
			*sl = (struct slot){ .id = id, .gen = gen, .idx = k };
			h->cid[k] = id;
			h->cw[k] = w;
			/* Keep the table at most half full. */
			if ((size_t)h->cn * 2 >= (size_t)1 << bits)
				acc_grow(h);
			return;
		}
		if (sl->id == id) {
			h->cw[sl->idx] += w;
			return;
		}
	}
}

static int entry_cmp(const void *a, const void *b)
{
	uint32_t x = ((const struct reyes_vis_entry *)a)->id;
	uint32_t y = ((const struct reyes_vis_entry *)b)->id;
	return (x > y) - (x < y);
}

/* Insertion sort for the usual few dozen entries, qsort past that. */
static void sort_entries(struct reyes_vis_entry *e, size_t n)
{
	if (n > 64) {
		qsort(e, n, sizeof(*e), entry_cmp);
		return;
	}
	for (size_t i = 1; i < n; i++) {
		struct reyes_vis_entry v = e[i];
		size_t j = i;
		for (; j > 0 && e[j - 1].id > v.id; j--)
			e[j] = e[j - 1];
		e[j] = v;
	}
}

/*
 * Pixel (x, y)'s entries, appended to h->ent, and its alpha: the samples
 * and weights of filter_pixel, in the same order.
 */
static void record_pixel(struct reyes_hider *h, uint32_t x, uint32_t y, float *alpha)
{
	const struct reyes_hider_opts *o = &h->o;
	uint32_t xs = o->xsamples, ys = o->ysamples;
	uint32_t K = 2 * h->mx + 1, L = 2 * h->my + 1;
	const struct sample *samp = h->samp;
	const float *sa = h->salpha, *swx = h->swx, *swy = h->swy, *rw = h->rw;
	const size_t *roff = h->roff;
	const uint32_t *rid = h->rid;
	bool radial = h->radial;
	float hw = h->hw, hh = h->hh;
	float cx = (float)x + 0.5f, cy = (float)y + 0.5f;
	struct support sp;
	pixel_support(h, x, y, &sp);
	double acc = 0.0, wsum = 0.0;

	acc_clear(h);
	for (uint32_t sy = sp.sy0; sy < sp.sy1; sy++) {
		uint32_t ky = y + h->my - (h->gy0 + sy) / ys;
		size_t rowi = (size_t)sy * h->sw;
		uint32_t kx = sp.kx0, i = sp.i0;
		for (uint32_t sx = sp.sx0; sx < sp.sx1; sx++) {
			size_t si = rowi + sx;
			float w;
			if (radial) {
				float dx = samp[si].x - cx, dy = samp[si].y - cy;
				bool in = dx >= -hw && dx < hw && dy >= -hh && dy < hh;
				w = in ? radial_weight(h, dx, dy) : 0.0f;
			} else {
				w = swx[si * K + kx] * swy[si * L + ky];
			}
			if (++i == xs) {
				i = 0;
				kx--;
			}
			if (w == 0.0f)
				continue;
			acc += (double)w * sa[si];
			wsum += w;
			for (size_t c = roff[si]; c < roff[si + 1]; c++)
				acc_add(h, rid[c], (double)w * rw[c]);
		}
	}
	double inv = wsum != 0.0 ? 1.0 / wsum : 0.0;
	if (alpha)
		*alpha = (float)(acc * inv);

	if (h->nent + h->cn > UINT32_MAX) {
		if (!h->warned_entries)
			fprintf(stderr, "relight: error: hider: more than 2^32 - 1 entries in a "
					"bucket; pixels past that are left empty\n");
		h->warned_entries = true;
		return;
	}
	if (h->nent + h->cn > h->ent_cap) {
		size_t cap = h->ent_cap ? h->ent_cap : 4096;
		while (cap < h->nent + h->cn)
			cap *= 2;
		h->ent = rl_xrealloc(h->ent, cap * sizeof(*h->ent));
		h->ent_cap = cap;
	}
	struct reyes_vis_entry *e = h->ent + h->nent;
	size_t ne = 0;
	for (uint32_t k = 0; k < h->cn; k++) {
		float v = (float)(h->cw[k] * inv);
		if (v != 0.0f && isfinite(v))
			e[ne++] = (struct reyes_vis_entry){ .id = h->cid[k], .weight = v };
	}
	sort_entries(e, ne);
	h->nent += ne;
}

/* Offsets for @npix pixels, all 0 (nothing recorded). */
static void empty_record(struct reyes_hider *h, size_t npix)
{
	if (npix + 1 > h->off_cap) {
		free(h->off);
		h->off = rl_xmalloc((npix + 1) * sizeof(*h->off));
		h->off_cap = npix + 1;
	}
	memset(h->off, 0, (npix + 1) * sizeof(*h->off));
	h->nent = 0;
}

uint64_t reyes_hider_end_record(struct reyes_hider *h, const uint32_t **offsets,
				const struct reyes_vis_entry **entries, float *alpha, float *zout)
{
	static const uint32_t no_offsets[1];
	static const struct reyes_vis_entry no_entries[1];
	if (offsets)
		*offsets = no_offsets;
	if (entries)
		*entries = no_entries;
	if (!h)
		return 0;
	uint32_t bw = h->px1 - h->px0, bh = h->py1 - h->py0;
	size_t npix = (size_t)bw * bh;
	size_t n = (size_t)h->sw * h->sh;
	bool active = h->active;
	h->active = false;

	empty_record(h, npix);
	if (offsets)
		*offsets = h->off;
	if (entries)
		*entries = h->ent ? h->ent : no_entries;
	if (!active)
		return 0;
	if (!h->o.record)
		wrong_mode(h, "reyes_hider_end_record");
	if (h->inserted == 0 || !h->o.record) {
		for (size_t p = 0; p < npix; p++) {
			if (alpha)
				alpha[p] = 0.0f;
			if (zout)
				zout[p] = NO_DEPTH;
		}
		return h->o.record ? n : 0;
	}

	grow_scratch(h, n);
	composite_record(h, n);
	if (!h->radial)
		axis_weights(h);
	if (!h->slots)
		acc_grow(h);
	for (uint32_t y = h->py0; y < h->py1; y++) {
		for (uint32_t x = h->px0; x < h->px1; x++) {
			size_t p = (size_t)(y - h->py0) * bw + (x - h->px0);
			record_pixel(h, x, y, alpha ? alpha + p : NULL);
			h->off[p + 1] = (uint32_t)h->nent;
			if (zout)
				zout[p] = pixel_depth(h, x, y);
		}
	}
	if (entries)
		*entries = h->ent ? h->ent : no_entries;
	return n;
}

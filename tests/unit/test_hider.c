/*
 * The hider and the pixel filters: coverage against closed forms, motion
 * blur, compositing, the top-left rule, culling, depth filters, bucket
 * independence, matte, and a throughput figure.
 */
#include "test.h"

#include "hider.h"

#include <stdint.h>
#include <time.h>
#include <unistd.h>

#define NO_DEPTH 1e30f

/* ---- scene helpers ---- */

/* A grid with its own storage: positions at both shutter times, Ci, Oi, aov. */
struct tgrid {
	uint32_t nu, nv;
	float *x[2], *y[2], *z[2];
	float *Ci, *Oi;
	float *aovp[2];
	const float *aovs[2];
	struct reyes_hider_grid g;
};

static struct tgrid *tgrid_new(uint32_t nu, uint32_t nv)
{
	struct tgrid *t = calloc(1, sizeof(*t));
	size_t n = (size_t)nu * nv;
	t->nu = nu;
	t->nv = nv;
	for (int k = 0; k < 2; k++) {
		t->x[k] = calloc(n, sizeof(float));
		t->y[k] = calloc(n, sizeof(float));
		t->z[k] = calloc(n, sizeof(float));
		t->aovp[k] = calloc(n, sizeof(float));
		t->aovs[k] = t->aovp[k];
	}
	t->Ci = calloc(3 * n, sizeof(float));
	t->Oi = calloc(3 * n, sizeof(float));
	return t;
}

static void tgrid_free(struct tgrid *t)
{
	if (!t)
		return;
	for (int k = 0; k < 2; k++) {
		free(t->x[k]);
		free(t->y[k]);
		free(t->z[k]);
		free(t->aovp[k]);
	}
	free(t->Ci);
	free(t->Oi);
	free(t);
}

/* Make the grid static (time 1 = time 0) and fill in the hider's view. */
static struct reyes_hider_grid *tgrid_static(struct tgrid *t)
{
	size_t n = (size_t)t->nu * t->nv;
	memcpy(t->x[1], t->x[0], n * sizeof(float));
	memcpy(t->y[1], t->y[0], n * sizeof(float));
	memcpy(t->z[1], t->z[0], n * sizeof(float));
	t->g = (struct reyes_hider_grid){
		.nu = t->nu, .nv = t->nv,
		.x = { t->x[0], t->x[0] }, .y = { t->y[0], t->y[0] }, .z = { t->z[0], t->z[0] },
		.Ci = t->Ci, .Oi = t->Oi, .aov = t->aovs,
	};
	return &t->g;
}

static struct reyes_hider_grid *tgrid_moving(struct tgrid *t)
{
	t->g = (struct reyes_hider_grid){
		.nu = t->nu, .nv = t->nv,
		.x = { t->x[0], t->x[1] }, .y = { t->y[0], t->y[1] }, .z = { t->z[0], t->z[1] },
		.Ci = t->Ci, .Oi = t->Oi, .aov = t->aovs,
	};
	return &t->g;
}

static void tgrid_colour(struct tgrid *t, const float c[3], float op)
{
	size_t n = (size_t)t->nu * t->nv;
	for (int k = 0; k < 3; k++) {
		for (size_t i = 0; i < n; i++) {
			t->Ci[k * n + i] = c[k] * op;
			t->Oi[k * n + i] = op;
		}
	}
}

/* Two vertices per side: (x0, y0) (x1, y0) / (x0, y1) (x1, y1); positive raster area. */
static struct tgrid *rect_grid(float x0, float y0, float x1, float y1, float z, const float c[3],
			       float op)
{
	struct tgrid *t = tgrid_new(2, 2);
	float xs[4] = { x0, x1, x0, x1 }, ys[4] = { y0, y0, y1, y1 };
	for (int i = 0; i < 4; i++) {
		t->x[0][i] = xs[i];
		t->y[0][i] = ys[i];
		t->z[0][i] = z;
	}
	tgrid_colour(t, c, op);
	tgrid_static(t);
	return t;
}

/* A triangle a, b, c as a 2x2 grid whose last two vertices coincide. */
static struct tgrid *tri_grid(const float a[2], const float b[2], const float c[2], float z,
			      float op)
{
	static const float white[3] = { 1, 1, 1 };
	struct tgrid *t = tgrid_new(2, 2);
	const float *v[4] = { a, b, c, c };
	/* vertex order (0,0) (1,0) (0,1) (1,1): quad v0=(0,0) v1=(1,0) v2=(1,1) v3=(0,1) */
	const float *order[4] = { v[0], v[1], v[3], v[2] };
	for (int i = 0; i < 4; i++) {
		t->x[0][i] = order[i][0];
		t->y[0][i] = order[i][1];
		t->z[0][i] = z;
	}
	tgrid_colour(t, white, op);
	tgrid_static(t);
	return t;
}

/* A disk of radius r as an nu x nv polar grid (angle along u, radius along v). */
static struct tgrid *disk_grid(float cx, float cy, float r, uint32_t nu, uint32_t nv, float z)
{
	static const float white[3] = { 1, 1, 1 };
	struct tgrid *t = tgrid_new(nu, nv);
	for (uint32_t j = 0; j < nv; j++) {
		double rr = r * (double)j / (nv - 1);
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t ii = i == nu - 1 ? 0 : i; /* close the ring exactly */
			double th = 2.0 * 3.14159265358979323846 * ii / (nu - 1);
			size_t p = (size_t)j * nu + i;
			t->x[0][p] = (float)(cx + rr * cos(th));
			t->y[0][p] = (float)(cy + rr * sin(th));
			t->z[0][p] = z;
		}
	}
	tgrid_colour(t, white, 1.0f);
	tgrid_static(t);
	return t;
}

static struct reyes_hider_opts opts_default(uint32_t xres, uint32_t yres, uint32_t ns)
{
	return (struct reyes_hider_opts){
		.xres = xres, .yres = yres, .xsamples = ns, .ysamples = ns,
		.filter = REYES_FILTER_BOX, .filter_width = { 1, 1 },
		.jitter = true, .seed = 7, .opacity_threshold = 0.996f,
		.depthfilter = REYES_DEPTH_MIN, .naov = 0,
	};
}

/* Render @grids in buckets of bw x bh; images are full size (rgba 4, z 1, aov naov). */
static uint64_t render(const struct reyes_hider_opts *o, struct reyes_hider_grid *const *grids,
		       int ngrids, uint32_t bw, uint32_t bh, float *rgba, float *z, float *aov)
{
	struct reyes_hider *h = reyes_hider_create(o);
	if (!h)
		return 0;
	uint32_t naov = o->naov;
	float *brgba = malloc((size_t)bw * bh * 4 * sizeof(float));
	float *bz = malloc((size_t)bw * bh * sizeof(float));
	float *baov = malloc((size_t)bw * bh * (naov ? naov : 1) * sizeof(float));
	uint64_t total = 0;
	for (uint32_t y0 = 0; y0 < o->yres; y0 += bh) {
		for (uint32_t x0 = 0; x0 < o->xres; x0 += bw) {
			uint32_t x1 = x0 + bw < o->xres ? x0 + bw : o->xres;
			uint32_t y1 = y0 + bh < o->yres ? y0 + bh : o->yres;
			reyes_hider_begin(h, x0, y0, x1, y1);
			for (int g = 0; g < ngrids; g++)
				reyes_hider_add(h, grids[g]);
			total += reyes_hider_end(h, brgba, bz, baov);
			uint32_t w = x1 - x0;
			for (uint32_t y = y0; y < y1; y++) {
				for (uint32_t x = x0; x < x1; x++) {
					size_t src = (size_t)(y - y0) * w + (x - x0);
					size_t dst = (size_t)y * o->xres + x;
					if (rgba)
						memcpy(rgba + dst * 4, brgba + src * 4,
						       4 * sizeof(float));
					if (z)
						z[dst] = bz[src];
					if (aov && naov)
						memcpy(aov + dst * naov, baov + src * naov,
						       naov * sizeof(float));
				}
			}
		}
	}
	free(brgba);
	free(bz);
	free(baov);
	reyes_hider_destroy(h);
	return total;
}

static float *image(uint32_t w, uint32_t h, uint32_t ch)
{
	return calloc((size_t)w * h * ch, sizeof(float));
}

#define A(img, xres, x, y) ((img)[((size_t)(y) * (xres) + (x)) * 4 + 3])
#define C(img, xres, x, y, k) ((img)[((size_t)(y) * (xres) + (x)) * 4 + (k)])

/* ---- filters ---- */

static void test_filter_values(void)
{
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_BOX, 0.4f, -0.4f, 1, 1), 1.0, 0);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_BOX, 0.6f, 0.0f, 1, 1), 0.0, 0);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_TRIANGLE, 0.5f, 0, 2, 2), 0.5, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_TRIANGLE, 0.75f, 0.75f, 3, 3), 0.25, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_TRIANGLE, 1.6f, 0, 3, 3), 0.0, 0);
	/* RISpec's Catmull-Rom: 2 at the centre, 0 at r = 1, -1/8 at r = 1.5. */
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_CATMULLROM, 0, 0, 4, 4), 2.0, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_CATMULLROM, 0.5f, 0, 4, 4), 1.125, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_CATMULLROM, 0.6f, 0.8f, 4, 4), 0.0, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_CATMULLROM, 1.5f, 0, 4, 4), -0.125, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_CATMULLROM, 1.5f, 0, 2, 2), 0.0, 0);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SEP_CATMULLROM, 1.5f, 0, 4, 4), -0.25, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SEP_CATMULLROM, 0.5f, 0.5f, 4, 4),
		   1.125 * 1.125, 1e-5);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_GAUSSIAN, 1, 0, 2, 2), exp(-2.0), 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_GAUSSIAN, 0.5f, 0.5f, 2, 2), exp(-1.0), 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_GAUSSIAN, 1.1f, 0, 2, 2), 0.0, 0);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_GAUSSIAN, 1.5f, 0, 6, 2), exp(-0.5), 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SEP_GAUSSIAN, 1, 1, 2, 2), exp(-4.0), 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SINC, 0, 0, 4, 4), 1.0, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SINC, 1, 0, 4, 4), 0.0, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_SINC, 0.5f, 0, 4, 4),
		   cos(3.14159265358979 / 16) * 2 / 3.14159265358979, 1e-6);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_BOX, NAN, 0, 1, 1), 0.0, 0);
	CHECK_NEAR(reyes_filter_eval(REYES_FILTER_BOX, 0, 0, 0, 1), 0.0, 0);

	enum reyes_filter f = REYES_FILTER_BOX;
	static const char *names[] = { "box", "triangle", "catmull-rom", "gaussian", "sinc",
				       "separable-catmull-rom", "separable-gaussian" };
	for (int i = 0; i < 7; i++) {
		CHECK(reyes_filter_from_name(names[i], &f));
		CHECK(f == (enum reyes_filter)i);
	}
	CHECK(!reyes_filter_from_name("mitchell", &f));
	CHECK(!reyes_filter_from_name("Box", &f));
	CHECK(!reyes_filter_from_name(NULL, &f));

	/* Summed over a fine grid of offsets within the width: positive. */
	static const float widths[][2] = { { 1, 1 }, { 2, 2 }, { 3, 3 }, { 4, 4 }, { 2, 5 } };
	for (int fi = 0; fi < 7; fi++) {
		for (size_t wi = 0; wi < sizeof(widths) / sizeof(widths[0]); wi++) {
			float xw = widths[wi][0], yw = widths[wi][1];
			double sum = 0;
			int n = 101;
			for (int j = 0; j < n; j++) {
				for (int i = 0; i < n; i++) {
					float dx = xw * ((i + 0.5f) / n - 0.5f);
					float dy = yw * ((j + 0.5f) / n - 0.5f);
					sum += reyes_filter_eval((enum reyes_filter)fi, dx, dy, xw,
								 yw);
				}
			}
			CHECK(sum > 0.0);
		}
	}
}

/* A constant opaque colour over the whole image comes back exactly for every filter. */
static void test_constant_image(void)
{
	static const struct {
		enum reyes_filter f;
		float w[2];
	} cases[] = {
		{ REYES_FILTER_BOX, { 1, 1 } },
		{ REYES_FILTER_BOX, { 3, 2 } },
		{ REYES_FILTER_TRIANGLE, { 2, 2 } },
		{ REYES_FILTER_CATMULLROM, { 2, 2 } },
		{ REYES_FILTER_CATMULLROM, { 4, 4 } },
		{ REYES_FILTER_GAUSSIAN, { 2, 2 } },
		{ REYES_FILTER_GAUSSIAN, { 3.3f, 2.5f } },
		{ REYES_FILTER_SINC, { 4, 4 } },
		{ REYES_FILTER_SEP_CATMULLROM, { 4, 4 } },
		{ REYES_FILTER_SEP_GAUSSIAN, { 2, 3 } },
	};
	const float col[3] = { 0.3f, 0.6f, 0.9f };
	struct tgrid *t = rect_grid(-6, -6, 30, 30, 5, col, 1.0f);
	struct reyes_hider_grid *g = &t->g;
	uint32_t W = 16, H = 12;
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct reyes_hider_opts o = opts_default(W, H, 3);
		o.filter = cases[c].f;
		o.filter_width[0] = cases[c].w[0];
		o.filter_width[1] = cases[c].w[1];
		float *img = image(W, H, 4);
		render(&o, &g, 1, 5, 4, img, NULL, NULL);
		double err = 0;
		for (uint32_t p = 0; p < W * H; p++) {
			for (int k = 0; k < 3; k++)
				err = fmax(err, fabs(img[p * 4 + k] - col[k]));
			err = fmax(err, fabs(img[p * 4 + 3] - 1.0));
		}
		CHECK_NEAR(err, 0.0, 2e-6);
		free(img);
	}
	tgrid_free(t);
}

/* ---- coverage ---- */

static void test_square_exact(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *t = rect_grid(2, 2, 6, 6, 3, white, 1.0f);
	struct reyes_hider_grid *g = &t->g;
	struct reyes_hider_opts o = opts_default(10, 10, 4);
	float *img = image(10, 10, 4);
	float *z = image(10, 10, 1);
	render(&o, &g, 1, 10, 10, img, z, NULL);
	int bad_in = 0, bad_out = 0;
	for (int y = 0; y < 10; y++) {
		for (int x = 0; x < 10; x++) {
			bool in = x >= 2 && x < 6 && y >= 2 && y < 6;
			float a = A(img, 10, x, y);
			if (in && (a != 1.0f || C(img, 10, x, y, 0) != 1.0f ||
				   z[y * 10 + x] != 3.0f))
				bad_in++;
			if (!in && (a != 0.0f || C(img, 10, x, y, 1) != 0.0f ||
				    z[y * 10 + x] != NO_DEPTH))
				bad_out++;
		}
	}
	CHECK(bad_in == 0);
	CHECK(bad_out == 0);
	free(img);
	free(z);
	tgrid_free(t);
}

/*
 * Edges at known fractions of pixels. With stratified samples, a straight
 * edge crossing a pixel along one axis misclassifies at most the samples of
 * one column of strata: the error is at most 1/xsamples (1/ysamples for the
 * other axis), and at a corner the sum of both.
 */
static void test_square_fraction(void)
{
	const float white[3] = { 1, 1, 1 };
	float X0 = 2.3f, X1 = 6.55f, Y0 = 3.1f, Y1 = 5.8f;
	struct tgrid *t = rect_grid(X0, Y0, X1, Y1, 3, white, 1.0f);
	struct reyes_hider_grid *g = &t->g;
	uint32_t ns = 8;
	struct reyes_hider_opts o = opts_default(10, 10, ns);
	float *img = image(10, 10, 4);
	render(&o, &g, 1, 4, 4, img, NULL, NULL);
	double worst = 0, total = 0;
	for (int y = 0; y < 10; y++) {
		for (int x = 0; x < 10; x++) {
			double fx = fmax(0, fmin(x + 1, X1) - fmax(x, X0));
			double fy = fmax(0, fmin(y + 1, Y1) - fmax(y, Y0));
			double tol = ((fx > 0 && fx < 1) ? 1.0 / ns : 0) +
				     ((fy > 0 && fy < 1) ? 1.0 / ns : 0);
			double err = fabs(A(img, 10, x, y) - fx * fy);
			CHECK(err <= tol + 1e-6);
			worst = fmax(worst, err);
			total += A(img, 10, x, y);
		}
	}
	/*
	 * Area 4.25 x 2.7. Only the ~110 strata the edges cut are uncertain,
	 * each a coin flip worth 1/64 pixel: the total's standard deviation is
	 * under 0.08, and 2% (0.23) is three of them.
	 */
	CHECK_NEAR(total, (X1 - X0) * (Y1 - Y0), 0.02 * (X1 - X0) * (Y1 - Y0));
	CHECK_NEAR(A(img, 10, 4, 4), 1.0, 0);
	printf("square fractions: worst pixel error %.4f, total %.4f (exact %.4f)\n", worst, total,
	       (double)(X1 - X0) * (Y1 - Y0));
	free(img);
	tgrid_free(t);
}

/* Area of the disk (cx, cy, r) inside the unit pixel at (px, py), by integration in x. */
static double disk_pixel_area(double cx, double cy, double r, int px, int py)
{
	int n = 4000;
	double sum = 0;
	for (int i = 0; i < n; i++) {
		double x = px + (i + 0.5) / n;
		double d = r * r - (x - cx) * (x - cx);
		if (d <= 0)
			continue;
		double hh = sqrt(d);
		double lo = fmax(py, cy - hh), hi = fmin(py + 1, cy + hh);
		if (hi > lo)
			sum += hi - lo;
	}
	return sum / n;
}

static void test_disk(void)
{
	double cx = 8.3, cy = 7.6, r = 6.1;
	uint32_t W = 17, H = 16;
	struct tgrid *t = disk_grid((float)cx, (float)cy, (float)r, 513, 9, 4);
	struct reyes_hider_grid *g = &t->g;
	struct reyes_hider_opts o = opts_default(W, H, 8);
	float *img = image(W, H, 4);
	render(&o, &g, 1, 6, 6, img, NULL, NULL);
	double worst = 0, total = 0;
	for (uint32_t y = 0; y < H; y++) {
		for (uint32_t x = 0; x < W; x++) {
			double exact = disk_pixel_area(cx, cy, r, (int)x, (int)y);
			double a = A(img, W, x, y);
			worst = fmax(worst, fabs(a - exact));
			total += a;
		}
	}
	CHECK_NEAR(worst, 0.0, 0.1);
	double area = 3.14159265358979 * r * r;
	CHECK_NEAR(total, area, 0.005 * area);
	printf("disk: worst pixel error %.4f, total %.4f (pi r^2 %.4f)\n", worst, total, area);
	free(img);
	tgrid_free(t);
}

/* A square moving 4 pixels right over the shutter: time-averaged coverage. */
static void test_motion(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *t = rect_grid(2, 2, 4, 4, 3, white, 1.0f);
	for (int i = 0; i < 4; i++) {
		t->x[1][i] = t->x[0][i] + 4;
		t->y[1][i] = t->y[0][i];
		t->z[1][i] = t->z[0][i];
	}
	struct reyes_hider_grid *g = tgrid_moving(t);
	uint32_t W = 10, H = 6, ns = 16;
	struct reyes_hider_opts o = opts_default(W, H, ns);
	float *img = image(W, H, 4);
	render(&o, &g, 1, 4, 3, img, NULL, NULL);
	double worst = 0;
	for (uint32_t x = 0; x < W; x++) {
		/* Mean over t of the overlap of [x, x+1] with [2 + 4t, 4 + 4t]. */
		int n = 20000;
		double cov = 0;
		for (int i = 0; i < n; i++) {
			double tt = (i + 0.5) / n;
			cov += fmax(0, fmin(x + 1.0, 4 + 4 * tt) - fmax((double)x, 2 + 4 * tt));
		}
		cov /= n;
		for (uint32_t y = 0; y < H; y++) {
			double expect = (y == 2 || y == 3) ? cov : 0.0;
			double err = fabs(A(img, W, x, y) - expect);
			worst = fmax(worst, err);
			if (expect == 0.0)
				CHECK(A(img, W, x, y) == 0.0f);
		}
	}
	/*
	 * Each pixel averages 256 coverage indicators (variance <= 1/4 each), so
	 * even unstratified its error has a standard deviation <= 1/32: allow 3.
	 * Pixels the square never reaches are exactly 0 (checked above).
	 */
	CHECK_NEAR(worst, 0.0, 3.0 / 32);
	printf("motion: worst pixel error %.4f\n", worst);
	free(img);
	tgrid_free(t);
}

/* ---- compositing ---- */

static void test_order_independence(void)
{
	const float red[3] = { 1, 0, 0 }, green[3] = { 0, 1, 0 };
	struct tgrid *front = rect_grid(1, 1, 7, 7, 2, red, 0.5f);
	struct tgrid *back = rect_grid(3, 3, 9, 9, 4, green, 0.5f);
	struct reyes_hider_grid *ab[2] = { &front->g, &back->g };
	struct reyes_hider_grid *ba[2] = { &back->g, &front->g };
	struct reyes_hider_opts o = opts_default(10, 10, 4);
	float *i1 = image(10, 10, 4), *i2 = image(10, 10, 4);
	float *z1 = image(10, 10, 1);
	render(&o, ab, 2, 10, 10, i1, z1, NULL);
	render(&o, ba, 2, 10, 10, i2, NULL, NULL);
	CHECK(memcmp(i1, i2, 10 * 10 * 4 * sizeof(float)) == 0);
	/* Both planes: red*0.5 + 0.5 * green*0.5, alpha 0.5 + 0.5 * 0.5. */
	CHECK_NEAR(C(i1, 10, 4, 4, 0), 0.5, 1e-6);
	CHECK_NEAR(C(i1, 10, 4, 4, 1), 0.25, 1e-6);
	CHECK_NEAR(C(i1, 10, 4, 4, 2), 0.0, 1e-6);
	CHECK_NEAR(A(i1, 10, 4, 4), 0.75, 1e-6);
	/* Front only, back only. */
	CHECK_NEAR(C(i1, 10, 1, 1, 0), 0.5, 1e-6);
	CHECK_NEAR(A(i1, 10, 1, 1), 0.5, 1e-6);
	CHECK_NEAR(C(i1, 10, 8, 8, 1), 0.5, 1e-6);
	CHECK_NEAR(C(i1, 10, 8, 8, 0), 0.0, 1e-6);
	/* Never opaque: no depth. */
	CHECK(z1[4 * 10 + 4] == NO_DEPTH);

	/* An opaque plane behind both: alpha 1, colour adds 0.25 of it, depth is its own. */
	const float blue[3] = { 0, 0, 1 };
	struct tgrid *wall = rect_grid(0, 0, 10, 10, 6, blue, 1.0f);
	struct reyes_hider_grid *three[3] = { &wall->g, &back->g, &front->g };
	render(&o, three, 3, 5, 5, i1, z1, NULL);
	CHECK_NEAR(C(i1, 10, 4, 4, 2), 0.25, 1e-6);
	CHECK_NEAR(A(i1, 10, 4, 4), 1.0, 1e-6);
	CHECK(z1[4 * 10 + 4] == 6.0f);
	free(i1);
	free(i2);
	free(z1);
	tgrid_free(front);
	tgrid_free(back);
	tgrid_free(wall);
}

/*
 * Samples at stratum centres lie exactly on the shared edges and on the
 * vertex where four grids meet: 50% grids show any double count (0.75) or
 * crack (0) in an otherwise exact 0.5.
 */
static void test_top_left(void)
{
	const float white[3] = { 1, 1, 1 };
	float xs[3] = { 1.125f, 4.375f, 7.625f }, ys[3] = { 1.375f, 3.625f, 6.875f };
	struct tgrid *t[4];
	struct reyes_hider_grid *g[4];
	for (int j = 0; j < 2; j++) {
		for (int i = 0; i < 2; i++) {
			t[j * 2 + i] =
				rect_grid(xs[i], ys[j], xs[i + 1], ys[j + 1], 3, white, 0.5f);
			g[j * 2 + i] = &t[j * 2 + i]->g;
		}
	}
	struct reyes_hider_opts o = opts_default(10, 9, 4);
	o.jitter = false;
	float *img = image(10, 9, 4);
	render(&o, g, 4, 10, 9, img, NULL, NULL);
	int bad = 0;
	for (int y = 2; y < 6; y++)
		for (int x = 2; x < 7; x++)
			bad += A(img, 10, x, y) != 0.5f;
	CHECK(bad == 0);
	/* Left and top edges are in, right and bottom edges out. */
	CHECK(A(img, 10, 1, 4) == 0.5f);
	CHECK(A(img, 10, 7, 4) == 0.25f);
	CHECK(A(img, 10, 4, 1) == 0.375f);
	CHECK(A(img, 10, 4, 6) == 0.375f);
	for (int k = 0; k < 4; k++)
		tgrid_free(t[k]);

	/* A diagonal shared edge through sample centres, in both windings of one side. */
	for (int flipb = 0; flipb < 2; flipb++) {
		const float p0[2] = { 2.125f, 2.125f }, p1[2] = { 6.125f, 2.125f };
		const float p2[2] = { 6.125f, 6.125f }, p3[2] = { 2.125f, 6.125f };
		struct tgrid *ta = tri_grid(p0, p1, p2, 3, 0.5f);
		struct tgrid *tb = flipb ? tri_grid(p0, p3, p2, 3, 0.5f)
					 : tri_grid(p0, p2, p3, 3, 0.5f);
		struct reyes_hider_grid *gg[2] = { &ta->g, &tb->g };
		struct reyes_hider_opts o8 = opts_default(8, 8, 4);
		o8.jitter = false;
		float *im = image(8, 8, 4);
		render(&o8, gg, 2, 8, 8, im, NULL, NULL);
		bad = 0;
		for (int y = 3; y < 6; y++)
			for (int x = 3; x < 6; x++)
				bad += A(im, 8, x, y) != 0.5f;
		CHECK(bad == 0);
		free(im);
		tgrid_free(ta);
		tgrid_free(tb);
	}

	/* Opaque: the two halves of a split square give exactly 1 along the seam. */
	struct tgrid *l = rect_grid(1, 1, 4.375f, 6, 3, white, 1.0f);
	struct tgrid *r = rect_grid(4.375f, 1, 8, 6, 3, white, 1.0f);
	struct reyes_hider_grid *lr[2] = { &l->g, &r->g };
	o.jitter = true;
	render(&o, lr, 2, 3, 3, img, NULL, NULL);
	bad = 0;
	for (int y = 1; y < 6; y++)
		for (int x = 1; x < 8; x++)
			bad += A(img, 10, x, y) != 1.0f;
	CHECK(bad == 0);
	free(img);
	tgrid_free(l);
	tgrid_free(r);
}

/*
 * Facing: a grid with u along raster +x and v along raster +y (down) has a
 * positive raster area. In camera space that is dPdu = +x, dPdv = -y, so
 * Ng = dPdu x dPdv = -z: toward the camera, front-facing.
 */
static void test_backface(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *front = rect_grid(2, 2, 6, 6, 3, white, 1.0f);
	struct tgrid *back = rect_grid(6, 2, 2, 6, 3, white, 1.0f); /* mirrored in x */
	struct reyes_hider_opts o = opts_default(8, 8, 2);
	float *img = image(8, 8, 4);
	struct {
		struct tgrid *t;
		bool cull, flip;
		float alpha;
	} cases[] = {
		{ front, true, false, 1 }, { back, true, false, 0 }, { front, true, true, 0 },
		{ back, true, true, 1 },   { front, false, false, 1 }, { back, false, false, 1 },
		{ back, false, true, 1 },
	};
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct reyes_hider_grid *g = &cases[c].t->g;
		g->cull_backfacing = cases[c].cull;
		g->flip = cases[c].flip;
		render(&o, &g, 1, 8, 8, img, NULL, NULL);
		CHECK(A(img, 8, 4, 4) == cases[c].alpha);
		CHECK(A(img, 8, 0, 0) == 0.0f);
	}
	free(img);
	tgrid_free(front);
	tgrid_free(back);
}

/* ---- depth ---- */

static void test_depthfilter(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *a = rect_grid(0.5f, 0.5f, 1.5f, 2.5f, 2, white, 1.0f);
	struct tgrid *b = rect_grid(1.5f, 0.5f, 2.5f, 2.5f, 4, white, 1.0f);
	struct reyes_hider_grid *g[2] = { &a->g, &b->g };
	struct reyes_hider_opts o = opts_default(4, 4, 4);
	o.jitter = false;
	float *z = image(4, 4, 1);
	static const enum reyes_depthfilter df[3] = { REYES_DEPTH_MIN, REYES_DEPTH_MAX,
						       REYES_DEPTH_AVERAGE };
	static const float half[3] = { 2, 4, 3 };    /* pixel (1, 1): half z=2, half z=4 */
	static const float edge[3] = { 2, NO_DEPTH, 2 }; /* pixel (0, 1): half z=2, half empty */
	for (int i = 0; i < 3; i++) {
		o.depthfilter = df[i];
		render(&o, g, 2, 4, 4, NULL, z, NULL);
		CHECK_NEAR(z[1 * 4 + 1], half[i], 1e-6);
		CHECK(z[1 * 4 + 0] == edge[i]);
		CHECK(z[3 * 4 + 3] == NO_DEPTH);
	}

	/* Midpoint: halfway between the first and second opaque surfaces. */
	struct tgrid *near = rect_grid(0, 0, 4, 2, 2, white, 1.0f);
	struct tgrid *far = rect_grid(0, 0, 4, 4, 6, white, 1.0f);
	struct reyes_hider_grid *nf[2] = { &far->g, &near->g };
	o.depthfilter = REYES_DEPTH_MIDPOINT;
	float *img = image(4, 4, 4);
	render(&o, nf, 2, 2, 2, img, z, NULL);
	CHECK_NEAR(z[0 * 4 + 1], 4.0, 1e-6);
	CHECK(z[3 * 4 + 1] == NO_DEPTH); /* one surface: nothing to be halfway to */
	CHECK_NEAR(A(img, 4, 1, 0), 1.0, 0);
	free(img);
	free(z);
	tgrid_free(a);
	tgrid_free(b);
	tgrid_free(near);
	tgrid_free(far);
}

/* Hits at or behind the camera plane are dropped; smooth vs flat shading; AOVs. */
static void test_shading(void)
{
	struct tgrid *t = tgrid_new(2, 2);
	float xs[4] = { 0, 8, 0, 8 }, ys[4] = { 0, 0, 4, 4 };
	for (int i = 0; i < 4; i++) {
		t->x[0][i] = xs[i];
		t->y[0][i] = ys[i];
		t->z[0][i] = 1 + xs[i]; /* depth 1 at x = 0, 9 at x = 8 */
		for (int k = 0; k < 3; k++) {
			t->Ci[k * 4 + i] = xs[i] / 8; /* grey ramp */
			t->Oi[k * 4 + i] = 1;
		}
		t->aovp[0][i] = 10 * xs[i];
		t->aovp[1][i] = 5;
	}
	struct reyes_hider_grid *g = tgrid_static(t);
	struct reyes_hider_opts o = opts_default(8, 4, 4);
	o.naov = 2;
	float *img = image(8, 4, 4), *z = image(8, 4, 1), *aov = image(8, 4, 2);
	g->smooth = true;
	render(&o, &g, 1, 3, 3, img, z, aov);
	/* Pixel (x, 1) has its samples' mean x near x + 0.5: linear values follow. */
	double worst = 0, worst_aov = 0;
	for (int x = 0; x < 8; x++) {
		worst = fmax(worst, fabs(C(img, 8, x, 1, 0) - (x + 0.5) / 8));
		worst_aov = fmax(worst_aov, fabs(aov[(8 + x) * 2] - 10 * (x + 0.5)));
		CHECK_NEAR(aov[(8 + x) * 2 + 1], 5.0, 1e-5);
	}
	/* Stratified mean of 4 jittered columns: within 1/8 pixel of the centre. */
	CHECK_NEAR(worst, 0.0, 0.125 / 8);
	CHECK_NEAR(worst_aov, 0.0, 10 * 0.125);
	CHECK_NEAR(z[1 * 8 + 3], 1 + 3, 0.3); /* min over samples near x = 3 */
	g->smooth = false;
	render(&o, &g, 1, 8, 4, img, NULL, NULL);
	/* Flat: every sample takes vertex (0, 0)'s colour. */
	CHECK(C(img, 8, 6, 2, 0) == 0.0f);
	CHECK(A(img, 8, 6, 2) == 1.0f);

	/* Depth <= 0 everywhere: nothing. */
	for (int i = 0; i < 4; i++)
		t->z[0][i] = -1;
	g = tgrid_static(t);
	render(&o, &g, 1, 8, 4, img, z, NULL);
	CHECK(A(img, 8, 3, 2) == 0.0f);
	CHECK(z[2 * 8 + 3] == NO_DEPTH);
	free(img);
	free(z);
	free(aov);
	tgrid_free(t);
}

/* ---- matte ---- */

static void test_matte(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *wall = rect_grid(0, 0, 8, 8, 5, white, 1.0f);
	struct tgrid *m = rect_grid(2, 2, 5, 5, 2, white, 1.0f);
	m->g.matte = true;
	struct reyes_hider_grid *g[2] = { &m->g, &wall->g };
	struct reyes_hider_opts o = opts_default(8, 8, 4);
	float *img = image(8, 8, 4), *z = image(8, 8, 1);
	render(&o, g, 2, 8, 8, img, z, NULL);
	for (int k = 0; k < 4; k++) {
		CHECK(C(img, 8, 3, 3, k) == 0.0f);
		CHECK(C(img, 8, 6, 6, k) == 1.0f);
	}
	CHECK(z[3 * 8 + 3] == 2.0f); /* the holdout is what the camera sees */

	/* Behind the wall it changes nothing. */
	for (int i = 0; i < 4; i++)
		m->z[0][i] = 9;
	tgrid_static(m);
	m->g.matte = true;
	render(&o, g, 2, 8, 8, img, NULL, NULL);
	CHECK(C(img, 8, 3, 3, 0) == 1.0f);
	CHECK(A(img, 8, 3, 3) == 1.0f);

	/* A 50% matte in front: half the wall shows, alpha 0.5. */
	for (int i = 0; i < 4; i++)
		m->z[0][i] = 2;
	tgrid_static(m);
	tgrid_colour(m, white, 0.5f);
	m->g.matte = true;
	render(&o, g, 2, 8, 8, img, NULL, NULL);
	CHECK_NEAR(C(img, 8, 3, 3, 0), 0.5, 1e-6);
	CHECK_NEAR(A(img, 8, 3, 3), 0.5, 1e-6);
	free(img);
	free(z);
	tgrid_free(wall);
	tgrid_free(m);
}

/* ---- dissolves (DetailRange cross-fades) ---- */

/*
 * Two opaque grids over the whole image at different depths, one seen by
 * the samples whose dissolve number is in [0, 0.3), the other by those in
 * [0.3, 1): every sample sees exactly one (alpha exactly 1, red + green
 * exactly 1 in every pixel), and the near one covers 0.3 of the 64x64x16
 * samples within 0.01 (binomial spread 0.0018). The same grids with
 * [0, 0.3) and [0.2, 1) overlap: the near one hides the far one where both
 * are seen, and nothing leaves a gap.
 */
static void test_dissolve(void)
{
	const float red[3] = { 1, 0, 0 }, green[3] = { 0, 1, 0 };
	uint32_t W = 64, H = 64;
	struct tgrid *a = rect_grid(-1, -1, W + 1, H + 1, 2, red, 1.0f);
	struct tgrid *b = rect_grid(-1, -1, W + 1, H + 1, 5, green, 1.0f);
	struct reyes_hider_grid *g[2] = { &a->g, &b->g };
	struct reyes_hider_opts o = opts_default(W, H, 4);
	o.filter = REYES_FILTER_BOX;
	o.filter_width[0] = o.filter_width[1] = 1;
	float *img = image(W, H, 4);
	for (int overlap = 0; overlap < 2; overlap++) {
		a->g.dissolve = b->g.dissolve = true;
		a->g.lod_lo = 0;
		a->g.lod_hi = 0.3f;
		b->g.lod_lo = overlap ? 0.2f : 0.3f;
		b->g.lod_hi = 1;
		render(&o, g, 2, W, H, img, NULL, NULL);
		double red_mean = 0, worst = 0;
		for (uint32_t y = 0; y < H; y++)
			for (uint32_t x = 0; x < W; x++) {
				red_mean += C(img, W, x, y, 0) / (double)(W * H);
				worst = fmax(worst, fabs(C(img, W, x, y, 0) + C(img, W, x, y, 1) - 1));
				worst = fmax(worst, fabs(A(img, W, x, y) - 1));
			}
		printf("dissolve%s: red %.4f (expected 0.3, tolerance 0.01), worst |R+G-1|, |A-1| "
		       "%.2g (tolerance 1e-6)\n", overlap ? " with overlap" : "", red_mean, worst);
		CHECK_NEAR(red_mean, 0.3, 0.01);
		CHECK(worst <= 1e-6);
	}
	/* Without the flag every sample sees both: the near one alone shows. */
	a->g.dissolve = b->g.dissolve = false;
	render(&o, g, 2, W, H, img, NULL, NULL);
	CHECK(C(img, W, 10, 10, 0) == 1.0f && C(img, W, 10, 10, 1) == 0.0f);
	free(img);
	tgrid_free(a);
	tgrid_free(b);
}

/* ---- buckets ---- */

static void test_determinism(void)
{
	const float red[3] = { 1, 0.2f, 0.1f }, blue[3] = { 0.1f, 0.3f, 1 };
	uint32_t W = 20, H = 14;
	struct tgrid *disk = disk_grid(9.3f, 6.8f, 5.2f, 65, 5, 4);
	struct tgrid *glass = rect_grid(3.3f, 2.2f, 15.7f, 11.9f, 2, blue, 0.4f);
	struct tgrid *mov = rect_grid(1.5f, 8.5f, 4.5f, 12.5f, 3, red, 1.0f);
	for (int i = 0; i < 4; i++) {
		mov->x[1][i] = mov->x[0][i] + 9.5f;
		mov->y[1][i] = mov->y[0][i] - 3.0f;
		mov->z[1][i] = mov->z[0][i] + 2.0f;
	}
	for (int i = 0; i < 4; i++)
		glass->aovp[0][i] = (float)i;
	tgrid_static(glass);
	struct reyes_hider_grid *g[3] = { &disk->g, &glass->g, tgrid_moving(mov) };
	struct reyes_hider_opts o = opts_default(W, H, 3);
	o.filter = REYES_FILTER_GAUSSIAN;
	o.filter_width[0] = 2.5f;
	o.filter_width[1] = 3.0f;
	o.naov = 2;
	o.depthfilter = REYES_DEPTH_AVERAGE;
	float *i1 = image(W, H, 4), *z1 = image(W, H, 1), *a1 = image(W, H, 2);
	float *i2 = image(W, H, 4), *z2 = image(W, H, 1), *a2 = image(W, H, 2);
	uint64_t n1 = render(&o, g, 3, W, H, i1, z1, a1);
	static const uint32_t sizes[][2] = { { 10, 7 }, { 7, 5 }, { 1, 1 }, { 16, 16 } };
	for (size_t s = 0; s < sizeof(sizes) / sizeof(sizes[0]); s++) {
		uint64_t n2 = render(&o, g, 3, sizes[s][0], sizes[s][1], i2, z2, a2);
		CHECK(memcmp(i1, i2, (size_t)W * H * 4 * sizeof(float)) == 0);
		CHECK(memcmp(z1, z2, (size_t)W * H * sizeof(float)) == 0);
		CHECK(memcmp(a1, a2, (size_t)W * H * 2 * sizeof(float)) == 0);
		CHECK(n2 >= n1); /* margins are sampled by each bucket */
	}
	CHECK(n1 == (uint64_t)W * H * 9);
	/* Not trivially empty. */
	CHECK(A(i1, W, 9, 6) > 0.9f);
	free(i1);
	free(z1);
	free(a1);
	free(i2);
	free(z2);
	free(a2);
	tgrid_free(disk);
	tgrid_free(glass);
	tgrid_free(mov);
}

/* ---- entry points ---- */

static void test_bad_input(void)
{
	struct reyes_hider_opts o = opts_default(8, 8, 2);
	struct reyes_hider_opts b = o;
	b.xsamples = 0;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.filter_width[0] = NAN;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.opacity_threshold = 0;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.xres = 0;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.filter = (enum reyes_filter)99;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.lens[0] = -1;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.lens[1] = INFINITY;
	CHECK(reyes_hider_create(&b) == NULL);
	b = o;
	b.focus = NAN;
	CHECK(reyes_hider_create(&b) == NULL);
	CHECK(reyes_hider_create(NULL) == NULL);
	reyes_hider_destroy(NULL);

	struct reyes_hider *h = reyes_hider_create(&o);
	CHECK(h != NULL);
	/* Outside the image, reversed, and add without begin: nothing happens. */
	float rgba[4 * 64];
	const float white[3] = { 1, 1, 1 };
	struct tgrid *t = rect_grid(NAN, 0, 5, INFINITY, 3, white, 1.0f);
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end(h, rgba, NULL, NULL) == 0);
	reyes_hider_begin(h, 9, 9, 12, 12);
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end(h, rgba, NULL, NULL) == 0);
	reyes_hider_begin(h, 0, 0, 8, 8);
	float x0, y0, x1, y1;
	reyes_hider_region(h, &x0, &y0, &x1, &y1);
	CHECK(x0 == 0 && y0 == 0 && x1 == 8 && y1 == 8);
	reyes_hider_add(h, &t->g);
	t->g.nu = 1;
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end(h, rgba, NULL, NULL) == 8 * 8 * 4);
	for (int i = 0; i < 64; i++)
		CHECK(isfinite(rgba[i * 4 + 3]));
	reyes_hider_begin(h, 2, 2, 4, 4);
	reyes_hider_region(h, &x0, &y0, &x1, &y1);
	CHECK(x0 == 2 && x1 == 4); /* box 1: no margin */
	reyes_hider_end(h, NULL, NULL, NULL);
	reyes_hider_destroy(h);
	tgrid_free(t);

	/* A margin of ceil(w/2 + 1/2) - 1 pixels, clipped to the image. */
	o.filter = REYES_FILTER_GAUSSIAN;
	o.filter_width[0] = 2;
	o.filter_width[1] = 4;
	h = reyes_hider_create(&o);
	reyes_hider_begin(h, 0, 2, 4, 4);
	reyes_hider_region(h, &x0, &y0, &x1, &y1);
	CHECK(x0 == 0 && x1 == 5 && y0 == 0 && y1 == 6);
	reyes_hider_end(h, NULL, NULL, NULL);
	reyes_hider_destroy(h);
}

/* ---- record mode (the indirect framebuffer) ---- */

/* A whole image's recipes: pixel p has entries e[start[p]] .. e[start[p] + count[p] - 1]. */
struct recimg {
	uint32_t W, H;
	uint32_t *start, *count;
	struct reyes_vis_entry *e;
	size_t ne, cap;
	float *alpha, *z;
	uint64_t samples;
};

static void recimg_free(struct recimg *r)
{
	free(r->start);
	free(r->count);
	free(r->e);
	free(r->alpha);
	free(r->z);
	memset(r, 0, sizeof(*r));
}

/* Render @grids in record mode (o->record is set here) in buckets of bw x bh. */
static void render_record(const struct reyes_hider_opts *opts,
			  struct reyes_hider_grid *const *grids, int ngrids, uint32_t bw, uint32_t bh,
			  struct recimg *r)
{
	struct reyes_hider_opts o = *opts;
	o.record = true;
	memset(r, 0, sizeof(*r));
	r->W = o.xres;
	r->H = o.yres;
	size_t npix = (size_t)o.xres * o.yres;
	r->start = calloc(npix, sizeof(uint32_t));
	r->count = calloc(npix, sizeof(uint32_t));
	r->alpha = calloc(npix, sizeof(float));
	r->z = calloc(npix, sizeof(float));
	struct reyes_hider *h = reyes_hider_create(&o);
	if (!h)
		return;
	float *ba = malloc((size_t)bw * bh * sizeof(float));
	float *bz = malloc((size_t)bw * bh * sizeof(float));
	for (uint32_t y0 = 0; y0 < o.yres; y0 += bh) {
		for (uint32_t x0 = 0; x0 < o.xres; x0 += bw) {
			uint32_t x1 = x0 + bw < o.xres ? x0 + bw : o.xres;
			uint32_t y1 = y0 + bh < o.yres ? y0 + bh : o.yres;
			reyes_hider_begin(h, x0, y0, x1, y1);
			for (int g = 0; g < ngrids; g++)
				reyes_hider_add(h, grids[g]);
			const uint32_t *off = NULL;
			const struct reyes_vis_entry *ent = NULL;
			r->samples += reyes_hider_end_record(h, &off, &ent, ba, bz);
			uint32_t w = x1 - x0;
			size_t nb = off[(size_t)w * (y1 - y0)];
			if (r->ne + nb > r->cap) {
				r->cap = (r->ne + nb) * 2;
				r->e = realloc(r->e, r->cap * sizeof(*r->e));
			}
			for (uint32_t y = y0; y < y1; y++) {
				for (uint32_t x = x0; x < x1; x++) {
					size_t src = (size_t)(y - y0) * w + (x - x0);
					size_t dst = (size_t)y * o.xres + x;
					r->alpha[dst] = ba[src];
					r->z[dst] = bz[src];
					r->start[dst] = (uint32_t)r->ne;
					r->count[dst] = off[src + 1] - off[src];
					if (r->count[dst])
						memcpy(r->e + r->ne, ent + off[src],
						       r->count[dst] * sizeof(*r->e));
					r->ne += r->count[dst];
				}
			}
		}
	}
	free(ba);
	free(bz);
	reyes_hider_destroy(h);
}

/* Pixel p's colour from the recipe: sum(weight Ci[id - base]) over planes of @nid ids. */
static void recimg_colour(const struct recimg *r, size_t p, const float *Ci, uint32_t base,
			  uint32_t nid, double out[3], double mag[3])
{
	for (int k = 0; k < 3; k++)
		out[k] = mag[k] = 0.0;
	for (uint32_t i = 0; i < r->count[p]; i++) {
		const struct reyes_vis_entry *e = &r->e[r->start[p] + i];
		if (e->id < base || e->id - base >= nid)
			continue; /* reported by the caller's id check */
		for (int k = 0; k < 3; k++) {
			double v = (double)e->weight * Ci[(size_t)k * nid + (e->id - base)];
			out[k] += v;
			mag[k] += fabs(v);
		}
	}
}

static uint64_t rng_state = 0x853c49e6748fea9bu;

static double rnd(void)
{
	rng_state = rng_state * 6364136223846793005u + 1442695040888963407u;
	return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

/*
 * A random grid: nu x nv vertices (2 to 6 each) on a rotated, sheared
 * patch of 2 to 10 pixels with wobble, a depth slope, grey opacity (opaque,
 * or random per vertex), random colours; sometimes matte, moving, culled,
 * flipped or dissolved (seen by part of the samples), smooth or flat.
 */
static struct tgrid *random_grid(uint32_t W, uint32_t H, uint32_t id0)
{
	uint32_t nu = 2 + (uint32_t)(rnd() * 5), nv = 2 + (uint32_t)(rnd() * 5);
	struct tgrid *t = tgrid_new(nu, nv);
	size_t n = (size_t)nu * nv;
	double cx = -2 + rnd() * (W + 4), cy = -2 + rnd() * (H + 4);
	double sx = 2 + rnd() * 8, sy = 2 + rnd() * 8, th = rnd() * 6.2831853;
	double shear = rnd() - 0.5, z0 = 1 + rnd() * 9, dzx = rnd() - 0.5, dzy = rnd() - 0.5;
	int opq = rnd() < 0.4;
	for (uint32_t j = 0; j < nv; j++) {
		for (uint32_t i = 0; i < nu; i++) {
			size_t p = (size_t)j * nu + i;
			double u = ((double)i / (nu - 1) - 0.5) * sx, v = ((double)j / (nv - 1) - 0.5) * sy;
			u += shear * v + 0.15 * (rnd() - 0.5) * sx / nu;
			v += 0.15 * (rnd() - 0.5) * sy / nv;
			t->x[0][p] = (float)(cx + cos(th) * u - sin(th) * v);
			t->y[0][p] = (float)(cy + sin(th) * u + cos(th) * v);
			t->z[0][p] = (float)(z0 + dzx * u + dzy * v + 0.2 * rnd());
			float op = opq ? 1.0f : (float)(0.1 + 0.9 * rnd());
			for (int k = 0; k < 3; k++) {
				t->Oi[k * n + p] = op;
				t->Ci[k * n + p] = (float)rnd();
			}
		}
	}
	tgrid_static(t);
	if (rnd() < 0.3) {
		double dx = 6 * (rnd() - 0.5), dy = 6 * (rnd() - 0.5), dz = rnd() - 0.5;
		for (size_t p = 0; p < n; p++) {
			t->x[1][p] = t->x[0][p] + (float)dx;
			t->y[1][p] = t->y[0][p] + (float)dy;
			t->z[1][p] = t->z[0][p] + (float)dz;
		}
		tgrid_moving(t);
	}
	t->g.smooth = rnd() < 0.5;
	t->g.matte = rnd() < 0.12;
	t->g.cull_backfacing = rnd() < 0.3;
	t->g.flip = rnd() < 0.5;
	t->g.id0 = id0;
	if (rnd() < 0.2) {
		/* a representation in a DetailRange cross-fade */
		double a = rnd(), b = rnd();
		t->g.dissolve = true;
		t->g.lod_lo = (float)fmin(a, b);
		t->g.lod_hi = (float)fmax(a, b);
	}
	return t;
}

/* Every pixel's entries: ids sorted and unique, weights finite and (when @nonneg) >= 0. */
static int check_entries(const struct recimg *r, bool nonneg, uint32_t base, uint32_t nid,
			 const bool *matte_id)
{
	int bad = 0;
	for (size_t p = 0; p < (size_t)r->W * r->H; p++) {
		for (uint32_t i = 0; i < r->count[p]; i++) {
			const struct reyes_vis_entry *e = &r->e[r->start[p] + i];
			if (i > 0 && !(e[-1].id < e->id))
				bad++;
			if (!isfinite(e->weight) || e->weight == 0.0f || (nonneg && e->weight < 0))
				bad++;
			if (e->id < base || e->id - base >= nid)
				bad++;
			else if (matte_id && matte_id[e->id - base])
				bad++;
		}
	}
	return bad;
}

/*
 * The recipe reproduces the normal render: for random scenes (transparent,
 * opaque, matte, smooth, flat, moving, culled, dissolved grids), every filter at widths
 * 1 to 4 and 1x1, 3x3, 4x4 and 2x3 samples, in buckets whose margins cut
 * through the scene, sum(weight Ci[id]) equals reyes_hider_end's colour
 * within 1e-5 of the sum of |weight Ci| plus 1e-6, and alpha and depth are
 * bit-identical.
 */
static void test_record_identity(void)
{
	uint32_t W = 23, H = 17, ngrid = 14, base = 1000;
	static const uint32_t spp[][2] = { { 1, 1 }, { 3, 3 }, { 4, 4 }, { 2, 3 } };
	double worst = 0, worst_rel = 0;
	size_t entries = 0, pixels = 0;
	int bad_ident = 0, bad_alpha = 0, bad_z = 0, bad_entries = 0;
	for (int f = 0; f <= REYES_FILTER_SEP_GAUSSIAN; f++) {
		for (int wi = 1; wi <= 4; wi++) {
			for (size_t si = 0; si < sizeof(spp) / sizeof(spp[0]); si++) {
				struct tgrid *t[16];
				struct reyes_hider_grid *g[16];
				uint32_t id = base;
				for (uint32_t k = 0; k < ngrid; k++) {
					t[k] = random_grid(W, H, id);
					g[k] = &t[k]->g;
					id += t[k]->nu * t[k]->nv;
				}
				uint32_t nid = id - base;
				float *Ci = calloc((size_t)3 * nid, sizeof(float));
				bool *matte = calloc(nid, sizeof(bool));
				for (uint32_t k = 0; k < ngrid; k++) {
					size_t n = (size_t)t[k]->nu * t[k]->nv;
					for (int c = 0; c < 3; c++)
						memcpy(Ci + (size_t)c * nid + (t[k]->g.id0 - base),
						       t[k]->Ci + c * n, n * sizeof(float));
					for (size_t p = 0; p < n; p++)
						matte[t[k]->g.id0 - base + p] = t[k]->g.matte;
				}
				struct reyes_hider_opts o = opts_default(W, H, spp[si][0]);
				o.ysamples = spp[si][1];
				o.filter = (enum reyes_filter)f;
				o.filter_width[0] = o.filter_width[1] = (float)wi;
				o.depthfilter = (enum reyes_depthfilter)((f + wi) % 4);
				o.seed = (uint32_t)(f * 31 + wi * 7 + si);
				if (si % 2) {
					/* Through a lens focused at depth 5: the grids, at
					 * depths 1 to 10, blur by up to 4.8 pixels. */
					o.lens[0] = 6;
					o.lens[1] = 5;
					o.focus = 0.2f;
				}
				float *img = image(W, H, 4), *z = image(W, H, 1);
				render(&o, g, (int)ngrid, 7, 5, img, z, NULL);
				struct recimg r;
				render_record(&o, g, (int)ngrid, 7, 5, &r);
				bool nonneg = f == REYES_FILTER_BOX || f == REYES_FILTER_TRIANGLE ||
					      f == REYES_FILTER_GAUSSIAN ||
					      f == REYES_FILTER_SEP_GAUSSIAN;
				bad_entries += check_entries(&r, nonneg, base, nid, matte);
				for (size_t p = 0; p < (size_t)W * H; p++) {
					double col[3], mag[3];
					recimg_colour(&r, p, Ci, base, nid, col, mag);
					for (int k = 0; k < 3; k++) {
						double err = fabs(col[k] - img[p * 4 + k]);
						worst = fmax(worst, err);
						if (mag[k] > 0)
							worst_rel = fmax(worst_rel, err / mag[k]);
						bad_ident += !(err <= 1e-5 * mag[k] + 1e-6);
					}
					bad_alpha += r.alpha[p] != img[p * 4 + 3];
					bad_z += r.z[p] != z[p];
					entries += r.count[p];
				}
				pixels += (size_t)W * H;
				recimg_free(&r);
				free(img);
				free(z);
				free(Ci);
				free(matte);
				for (uint32_t k = 0; k < ngrid; k++)
					tgrid_free(t[k]);
			}
		}
	}
	CHECK(bad_ident == 0);
	CHECK(bad_alpha == 0);
	CHECK(bad_z == 0);
	CHECK(bad_entries == 0);
	/* Not trivially empty: scenes cover much of the image with several layers. */
	CHECK(entries > pixels * 2);
	printf("record identity: worst colour error %.3g (%.3g of sum |w Ci|), %.2f entries per "
	       "pixel\n",
	       worst, worst_rel, (double)entries / pixels);
}

/* The same recipes whatever the bucket size (margins sampled alike, lens positions too). */
static void test_record_buckets(void)
{
	uint32_t W = 21, H = 15, ngrid = 12;
	struct tgrid *t[12];
	struct reyes_hider_grid *g[12];
	uint32_t id = 5;
	for (uint32_t k = 0; k < ngrid; k++) {
		t[k] = random_grid(W, H, id);
		g[k] = &t[k]->g;
		id += t[k]->nu * t[k]->nv;
	}
	struct reyes_hider_opts o = opts_default(W, H, 3);
	o.filter = REYES_FILTER_CATMULLROM;
	o.filter_width[0] = 3;
	o.filter_width[1] = 4;
	o.lens[0] = o.lens[1] = 4;
	o.focus = 0.25f;
	struct recimg a, b;
	render_record(&o, g, (int)ngrid, W, H, &a);
	static const uint32_t sizes[][2] = { { 1, 1 }, { 4, 3 }, { 16, 16 } };
	for (size_t s = 0; s < sizeof(sizes) / sizeof(sizes[0]); s++) {
		render_record(&o, g, (int)ngrid, sizes[s][0], sizes[s][1], &b);
		CHECK(a.ne == b.ne);
		CHECK(memcmp(a.count, b.count, (size_t)W * H * sizeof(uint32_t)) == 0);
		int bad = 0;
		for (size_t p = 0; p < (size_t)W * H; p++)
			bad += a.count[p] != b.count[p] ||
			       memcmp(a.e + a.start[p], b.e + b.start[p],
				      a.count[p] * sizeof(*a.e)) != 0;
		CHECK(bad == 0);
		CHECK(memcmp(a.alpha, b.alpha, (size_t)W * H * sizeof(float)) == 0);
		CHECK(b.samples >= a.samples);
		recimg_free(&b);
	}
	CHECK(a.ne > 0);
	recimg_free(&a);
	for (uint32_t k = 0; k < ngrid; k++)
		tgrid_free(t[k]);
}

/*
 * Coloured opacity: the recipe composites with the mean of the three
 * channels' transmittance, as AOVs do. It equals an AOV that carries Ci, not
 * the per-channel colour.
 */
static void test_record_coloured_opacity(void)
{
	uint32_t W = 8, H = 8;
	const float grey[3] = { 0.5f, 0.5f, 0.5f };
	struct tgrid *wall = rect_grid(0, 0, 8, 8, 6, grey, 1.0f);
	struct tgrid *glass = rect_grid(1, 1, 7, 7, 2, grey, 1.0f);
	for (int i = 0; i < 4; i++) {
		static const float op[3] = { 0.9f, 0.5f, 0.1f };
		for (int k = 0; k < 3; k++) {
			glass->Oi[k * 4 + i] = op[k];
			glass->Ci[k * 4 + i] = 0.3f * op[k];
		}
	}
	wall->g.id0 = 0;
	glass->g.id0 = 4;
	const float *aov3[2][3];
	struct tgrid *tg[2] = { wall, glass };
	float Ci[3 * 8];
	for (int j = 0; j < 2; j++) {
		for (int k = 0; k < 3; k++) {
			aov3[j][k] = tg[j]->Ci + k * 4;
			memcpy(Ci + k * 8 + j * 4, tg[j]->Ci + k * 4, 4 * sizeof(float));
		}
		tg[j]->g.aov = aov3[j];
	}
	struct reyes_hider_grid *g[2] = { &wall->g, &glass->g };
	struct reyes_hider_opts o = opts_default(W, H, 4);
	o.naov = 3;
	float *img = image(W, H, 4), *aov = image(W, H, 3);
	render(&o, g, 2, W, H, img, NULL, aov);
	struct recimg r;
	o.naov = 0;
	render_record(&o, g, 2, 4, 4, &r);
	size_t p = 4 * W + 4; /* under the glass */
	double col[3], mag[3];
	recimg_colour(&r, p, Ci, 0, 8, col, mag);
	for (int k = 0; k < 3; k++) {
		CHECK_NEAR(col[k], aov[p * 3 + k], 1e-5 * mag[k] + 1e-6);
		/* Per channel: 0.3 op + (1 - op) 0.5; with the mean transmittance
		 * (1 - 0.5) the wall adds 0.25 in every channel. */
		double exact = 0.3 * (k == 0 ? 0.9 : k == 1 ? 0.5 : 0.1);
		CHECK_NEAR(col[k], exact + 0.25, 1e-5);
	}
	CHECK(fabs(col[0] - img[p * 4 + 0]) > 0.1); /* 0.52 against 0.27 + 0.1 x 0.5 */
	CHECK_NEAR(col[1], img[p * 4 + 1], 1e-5);   /* grey channel: the same */
	CHECK(r.alpha[p] == img[p * 4 + 3]);
	recimg_free(&r);
	free(img);
	free(aov);
	tgrid_free(wall);
	tgrid_free(glass);
}

/*
 * Opaque full coverage: every pixel's weights sum to 1 and equal alpha;
 * flat shading of a large quad coalesces 16 samples to 1 entry per pixel;
 * a smooth grid aligned on 2x2-pixel micropolygons touches at most the
 * 4 vertices of the micropolygon a pixel lies in.
 */
static void test_record_coverage(void)
{
	uint32_t W = 12, H = 10;
	const float white[3] = { 1, 1, 1 };
	struct tgrid *big = rect_grid(-3, -3, 20, 20, 5, white, 1.0f);
	big->g.id0 = 77;
	struct reyes_hider_grid *g = &big->g;
	static const struct {
		enum reyes_filter f;
		float w;
	} cases[] = { { REYES_FILTER_BOX, 1 }, { REYES_FILTER_GAUSSIAN, 2 },
		      { REYES_FILTER_CATMULLROM, 3 }, { REYES_FILTER_SINC, 4 } };
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct reyes_hider_opts o = opts_default(W, H, 4);
		o.filter = cases[c].f;
		o.filter_width[0] = o.filter_width[1] = cases[c].w;
		struct recimg r;
		render_record(&o, &g, 1, 5, 4, &r);
		double worst = 0;
		int bad = 0;
		for (size_t p = 0; p < (size_t)W * H; p++) {
			double sum = 0;
			for (uint32_t i = 0; i < r.count[p]; i++)
				sum += r.e[r.start[p] + i].weight;
			worst = fmax(worst, fabs(sum - 1.0));
			worst = fmax(worst, fabs(sum - r.alpha[p]));
			bad += r.count[p] != 1 || r.e[r.start[p]].id != 77;
		}
		CHECK_NEAR(worst, 0.0, 1e-5);
		CHECK(bad == 0);
		recimg_free(&r);
	}

	/* Smooth, micropolygons 2x2 pixels, vertices on even pixel corners. */
	uint32_t nu = 7, nv = 6;
	struct tgrid *t = tgrid_new(nu, nv);
	for (uint32_t j = 0; j < nv; j++) {
		for (uint32_t i = 0; i < nu; i++) {
			size_t p = (size_t)j * nu + i;
			t->x[0][p] = 2.0f * i;
			t->y[0][p] = 2.0f * j;
			t->z[0][p] = 4;
		}
	}
	tgrid_colour(t, white, 1.0f);
	g = tgrid_static(t);
	g->smooth = true;
	struct reyes_hider_opts o = opts_default(W, H, 4);
	struct recimg r;
	render_record(&o, &g, 1, W, H, &r);
	int bad = 0;
	double worst = 0;
	for (uint32_t y = 0; y < H; y++) {
		for (uint32_t x = 0; x < W; x++) {
			size_t p = (size_t)y * W + x;
			uint32_t q0 = (y / 2) * nu + x / 2;
			uint32_t ok[4] = { q0, q0 + 1, q0 + nu, q0 + nu + 1 };
			double sum = 0;
			for (uint32_t i = 0; i < r.count[p]; i++) {
				uint32_t id = r.e[r.start[p] + i].id;
				bad += id != ok[0] && id != ok[1] && id != ok[2] && id != ok[3];
				sum += r.e[r.start[p] + i].weight;
			}
			bad += r.count[p] < 3 || r.count[p] > 4;
			worst = fmax(worst, fabs(sum - 1.0));
		}
	}
	CHECK(bad == 0);
	CHECK_NEAR(worst, 0.0, 1e-5);
	recimg_free(&r);
	tgrid_free(t);
	tgrid_free(big);
}

/* Matte: no entries of its own; an opaque matte hides what is behind. */
static void test_record_matte(void)
{
	uint32_t W = 8, H = 8;
	const float white[3] = { 1, 1, 1 };
	struct tgrid *m = rect_grid(0, 0, 4, 8, 2, white, 1.0f);
	struct tgrid *wall = rect_grid(2, 0, 8, 8, 5, white, 1.0f);
	m->g.matte = true;
	m->g.id0 = 10;
	wall->g.id0 = 20;
	struct reyes_hider_grid *g[2] = { &m->g, &wall->g };
	struct reyes_hider_opts o = opts_default(W, H, 4);
	struct recimg r;
	render_record(&o, g, 1, W, H, &r); /* the matte alone */
	uint32_t total = 0;
	for (size_t p = 0; p < (size_t)W * H; p++)
		total += r.count[p];
	CHECK(total == 0);
	CHECK(r.alpha[3 * W + 1] == 0.0f);
	CHECK(r.z[3 * W + 1] == 2.0f);
	recimg_free(&r);

	render_record(&o, g, 2, 3, 3, &r);
	for (uint32_t y = 0; y < H; y++) {
		CHECK(r.count[y * W + 1] == 0); /* matte only */
		CHECK(r.count[y * W + 3] == 0); /* the wall behind the matte */
		CHECK(r.count[y * W + 5] == 1 && r.e[r.start[y * W + 5]].id == 20);
		CHECK(r.alpha[y * W + 3] == 0.0f && r.alpha[y * W + 5] == 1.0f);
	}
	recimg_free(&r);

	/* Half-transparent matte: the wall behind it gets half weight. */
	tgrid_colour(m, white, 0.5f);
	render_record(&o, g, 2, W, H, &r);
	CHECK(r.count[3 * W + 3] == 1);
	CHECK_NEAR(r.e[r.start[3 * W + 3]].weight, 0.5, 1e-6);
	CHECK_NEAR(r.alpha[3 * W + 3], 0.5, 1e-6);
	recimg_free(&r);
	tgrid_free(m);
	tgrid_free(wall);
}

/*
 * Ids past 2^32 - 1: the micropolygons that would use them are dropped and
 * reported once on stderr; those below still record their ids.
 */
static void test_record_id_overflow(void)
{
	uint32_t W = 8, H = 4;
	/* 3 x 2 vertices over [0, 8) x [0, 4): vertex 0 id 2^32-2, vertex 1 2^32-1, then none. */
	struct tgrid *t = tgrid_new(3, 2);
	static const float xs[6] = { 0, 4, 8, 0, 4, 8 }, ys[6] = { 0, 0, 0, 4, 4, 4 };
	const float white[3] = { 1, 1, 1 };
	for (int i = 0; i < 6; i++) {
		t->x[0][i] = xs[i];
		t->y[0][i] = ys[i];
		t->z[0][i] = 3;
	}
	tgrid_colour(t, white, 1.0f);
	struct reyes_hider_grid *g = tgrid_static(t);
	g->id0 = UINT32_MAX - 1;
	struct reyes_hider_opts o = opts_default(W, H, 2);

	fflush(stderr);
	FILE *tmp = tmpfile();
	int saved = dup(fileno(stderr));
	dup2(fileno(tmp), fileno(stderr));

	struct recimg r;
	render_record(&o, &g, 1, 4, 4, &r); /* flat: vertices 0 and 1 */
	int bad = 0;
	for (uint32_t y = 0; y < H; y++) {
		for (uint32_t x = 0; x < W; x++) {
			size_t p = (size_t)y * W + x;
			uint32_t want = x < 4 ? UINT32_MAX - 1 : UINT32_MAX;
			bad += r.count[p] != 1 || r.e[r.start[p]].id != want;
		}
	}
	CHECK(bad == 0);
	recimg_free(&r);
	g->smooth = true; /* now every quad needs vertices 4 and 5: all dropped */
	render_record(&o, &g, 1, 4, 4, &r);
	uint32_t total = 0;
	for (size_t p = 0; p < (size_t)W * H; p++) {
		total += r.count[p];
		CHECK(r.alpha[p] == 0.0f);
	}
	CHECK(total == 0);
	recimg_free(&r);

	fflush(stderr);
	dup2(saved, fileno(stderr));
	close(saved);
	char msg[1024] = "";
	rewind(tmp);
	size_t len = fread(msg, 1, sizeof(msg) - 1, tmp);
	msg[len] = '\0';
	fclose(tmp);
	/* One hider per render_record call: reported once in the second, not per bucket. */
	const char *hit = strstr(msg, "ids pass 2^32 - 1");
	CHECK(hit != NULL);
	CHECK(hit && strstr(hit + 1, "ids pass 2^32 - 1") == NULL);
	tgrid_free(t);
}

/*
 * The wrong finish: reyes_hider_end on a record-mode hider and
 * reyes_hider_end_record on a normal one return 0, report once, and give
 * empty pixels (offsets all 0, alpha 0, z 1e30); so do a finish with no
 * bucket started and a NULL hider.
 */
static void test_record_wrong_mode(void)
{
	const float white[3] = { 1, 1, 1 };
	struct tgrid *t = rect_grid(0, 0, 8, 8, 3, white, 1.0f);
	struct reyes_hider_opts o = opts_default(8, 8, 2);
	const uint32_t *off = NULL;
	const struct reyes_vis_entry *ent = NULL;
	float rgba[4 * 16], alpha[16], z[16];

	fflush(stderr);
	FILE *tmp = tmpfile();
	int saved = dup(fileno(stderr));
	dup2(fileno(tmp), fileno(stderr));

	struct reyes_hider *h = reyes_hider_create(&o);
	reyes_hider_begin(h, 0, 0, 4, 4);
	reyes_hider_add(h, &t->g);
	for (int i = 0; i < 16; i++)
		alpha[i] = z[i] = NAN;
	CHECK(reyes_hider_end_record(h, &off, &ent, alpha, z) == 0);
	CHECK(off != NULL && ent != NULL);
	int bad = 0;
	for (int i = 0; i < 16; i++)
		bad += off[i + 1] != 0 || alpha[i] != 0.0f || z[i] != NO_DEPTH;
	CHECK(off[0] == 0 && bad == 0);
	/* Still usable in its own mode. */
	reyes_hider_begin(h, 0, 0, 4, 4);
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end(h, rgba, z, NULL) == 4 * 4 * 4);
	CHECK(rgba[3] == 1.0f);
	reyes_hider_destroy(h);

	o.record = true;
	h = reyes_hider_create(&o);
	CHECK(reyes_hider_end_record(h, &off, &ent, alpha, z) == 0); /* no bucket yet */
	CHECK(off != NULL && off[0] == 0 && ent != NULL);
	reyes_hider_begin(h, 0, 0, 4, 4);
	reyes_hider_add(h, &t->g);
	for (int i = 0; i < 64; i++)
		rgba[i] = NAN;
	CHECK(reyes_hider_end(h, rgba, z, NULL) == 0);
	bad = 0;
	for (int i = 0; i < 16; i++)
		bad += rgba[i * 4] != 0.0f || rgba[i * 4 + 3] != 0.0f || z[i] != NO_DEPTH;
	CHECK(bad == 0);
	/* The bucket is finished: a second finish records nothing. */
	CHECK(reyes_hider_end_record(h, &off, &ent, NULL, NULL) == 0);
	CHECK(off[16] == 0);
	reyes_hider_begin(h, 0, 0, 4, 4);
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end_record(h, &off, &ent, NULL, NULL) == 4 * 4 * 4);
	CHECK(off[16] == 16 && ent[0].weight == 1.0f);
	/* Ci may be NULL in record mode. */
	t->g.Ci = NULL;
	reyes_hider_begin(h, 4, 4, 8, 8);
	reyes_hider_add(h, &t->g);
	CHECK(reyes_hider_end_record(h, &off, &ent, alpha, NULL) == 4 * 4 * 4);
	CHECK(off[16] == 16 && alpha[15] == 1.0f);
	reyes_hider_destroy(h);

	CHECK(reyes_hider_end_record(NULL, &off, &ent, alpha, z) == 0);
	CHECK(off != NULL && off[0] == 0 && ent != NULL);

	fflush(stderr);
	dup2(saved, fileno(stderr));
	close(saved);
	char msg[2048] = "";
	rewind(tmp);
	size_t len = fread(msg, 1, sizeof(msg) - 1, tmp);
	msg[len] = '\0';
	fclose(tmp);
	CHECK(strstr(msg, "reyes_hider_end_record on a hider not in record mode") != NULL);
	CHECK(strstr(msg, "reyes_hider_end on a hider in record mode") != NULL);
	tgrid_free(t);
}

/* ---- throughput ---- */

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void bench(void)
{
	uint32_t W = 640, H = 360, B = 16;
	/* 400 x 250 micropolygons over the screen, in 25 x 16 grids of 16 x 16 (rounded). */
	uint32_t QX = 400, QY = 250, T = 16;
	uint32_t gx = (QX + T - 1) / T, gy = (QY + T - 1) / T;
	struct tgrid **grids = calloc((size_t)gx * gy, sizeof(*grids));
	float bx[(size_t)25 * 16][4];
	uint32_t ng = 0;
	for (uint32_t tj = 0; tj < gy; tj++) {
		for (uint32_t ti = 0; ti < gx; ti++) {
			uint32_t i0 = ti * T, j0 = tj * T;
			uint32_t nu = (i0 + T < QX ? T : QX - i0) + 1;
			uint32_t nv = (j0 + T < QY ? T : QY - j0) + 1;
			struct tgrid *t = tgrid_new(nu, nv);
			float lo[2] = { 1e30f, 1e30f }, hi[2] = { -1e30f, -1e30f };
			for (uint32_t j = 0; j < nv; j++) {
				for (uint32_t i = 0; i < nu; i++) {
					size_t p = (size_t)j * nu + i;
					float x = (i0 + i) * (float)W / QX;
					float y = (j0 + j) * (float)H / QY;
					/* a little wobble so micropolygons are not axis-aligned */
					x += 0.3f * sinf(0.37f * y);
					y += 0.3f * sinf(0.23f * x);
					t->x[0][p] = x;
					t->y[0][p] = y;
					t->z[0][p] = 10 + 0.01f * x;
					lo[0] = fminf(lo[0], x);
					lo[1] = fminf(lo[1], y);
					hi[0] = fmaxf(hi[0], x);
					hi[1] = fmaxf(hi[1], y);
					for (int k = 0; k < 3; k++) {
						t->Ci[k * nu * nv + p] = 0.5f;
						t->Oi[k * nu * nv + p] = 1.0f;
					}
				}
			}
			tgrid_static(t);
			bx[ng][0] = lo[0];
			bx[ng][1] = lo[1];
			bx[ng][2] = hi[0];
			bx[ng][3] = hi[1];
			grids[ng++] = t;
		}
	}
	struct reyes_hider_opts o = opts_default(W, H, 4);
	o.filter = REYES_FILTER_GAUSSIAN;
	o.filter_width[0] = o.filter_width[1] = 2;
	struct reyes_hider *h = reyes_hider_create(&o);
	float *rgba = malloc((size_t)B * B * 4 * sizeof(float));
	float *z = malloc((size_t)B * B * sizeof(float));
	double t0 = now(), tadd = 0, tend = 0;
	uint64_t samples = 0;
	double check = 0;
	for (uint32_t y0 = 0; y0 < H; y0 += B) {
		for (uint32_t x0 = 0; x0 < W; x0 += B) {
			uint32_t x1 = x0 + B < W ? x0 + B : W, y1 = y0 + B < H ? y0 + B : H;
			reyes_hider_begin(h, x0, y0, x1, y1);
			float rx0, ry0, rx1, ry1;
			reyes_hider_region(h, &rx0, &ry0, &rx1, &ry1);
			double ta = now();
			for (uint32_t k = 0; k < ng; k++) {
				if (bx[k][2] < rx0 || bx[k][0] > rx1 || bx[k][3] < ry0 ||
				    bx[k][1] > ry1)
					continue;
				reyes_hider_add(h, &grids[k]->g);
			}
			double te = now();
			samples += reyes_hider_end(h, rgba, z, NULL);
			double tf = now();
			tadd += te - ta;
			tend += tf - te;
			check += rgba[3];
		}
	}
	double dt = now() - t0;
	printf("bench: %ux%u, 4x4 samples, %u micropolygons: %.3f s, %.1f M samples/s "
	       "(add %.3f s, end %.3f s, begin %.3f s)\n",
	       W, H, QX * QY, dt, samples / dt * 1e-6, tadd, tend, dt - tadd - tend);
	CHECK(check > 0);
	free(rgba);
	free(z);
	reyes_hider_destroy(h);
	for (uint32_t k = 0; k < ng; k++)
		tgrid_free(grids[k]);
	free(grids);
}

/*
 * Record against normal mode on the same scene: 256x256 in 64x64 buckets,
 * 4x4 samples, Gaussian 2: an opaque smooth ground of ~1-pixel
 * micropolygons in 16x16 grids, a flat 50% layer over half the image and
 * small opaque grids in front. Prints the ratio of the hider's time.
 */
static void bench_record(void)
{
	uint32_t W = 256, H = 256, B = 64, T = 16;
	struct tgrid *grids[1024];
	uint32_t ng = 0, id = 0;
	for (int layer = 0; layer < 3; layer++) {
		float cell = layer == 2 ? 0.7f : 1.0f;
		uint32_t span = layer == 2 ? 40 : W / T;
		for (uint32_t tj = 0; tj < span && ng < 1024; tj++) {
			for (uint32_t ti = 0; ti < span && ng < 1024; ti++) {
				if (layer == 1 && ti >= span / 2)
					continue;
				if (layer == 2 && ((ti * 7 + tj * 3) % 11) != 0)
					continue;
				struct tgrid *t = tgrid_new(T + 1, T + 1);
				size_t n = (size_t)(T + 1) * (T + 1);
				float ox = layer == 2 ? ti * 6.3f : ti * T * cell;
				float oy = layer == 2 ? tj * 6.3f : tj * T * cell;
				for (uint32_t j = 0; j <= T; j++) {
					for (uint32_t i = 0; i <= T; i++) {
						size_t p = (size_t)j * (T + 1) + i;
						float x = ox + i * cell, y = oy + j * cell;
						x += 0.3f * sinf(0.37f * y);
						y += 0.3f * sinf(0.23f * x);
						t->x[0][p] = x;
						t->y[0][p] = y;
						t->z[0][p] = (layer == 0 ? 20 : layer == 1 ? 10 : 5) +
							     0.01f * x;
						for (int k = 0; k < 3; k++) {
							t->Ci[k * n + p] = 0.5f;
							t->Oi[k * n + p] = layer == 1 ? 0.5f : 1.0f;
						}
					}
				}
				tgrid_static(t);
				t->g.smooth = layer == 0;
				t->g.id0 = id;
				id += (uint32_t)n;
				grids[ng++] = t;
			}
		}
	}
	double best[2] = { 1e30, 1e30 }, bend[2] = { 0, 0 };
	uint64_t nent = 0;
	float *rgba = malloc((size_t)B * B * 4 * sizeof(float));
	float *z = malloc((size_t)B * B * sizeof(float));
	for (int rep = 0; rep < 3; rep++) {
		for (int mode = 0; mode < 2; mode++) {
			struct reyes_hider_opts o = opts_default(W, H, 4);
			o.filter = REYES_FILTER_GAUSSIAN;
			o.filter_width[0] = o.filter_width[1] = 2;
			o.record = mode == 1;
			struct reyes_hider *h = reyes_hider_create(&o);
			double t0 = now(), tend = 0;
			nent = 0;
			for (uint32_t y0 = 0; y0 < H; y0 += B) {
				for (uint32_t x0 = 0; x0 < W; x0 += B) {
					reyes_hider_begin(h, x0, y0, x0 + B, y0 + B);
					float rx0, ry0, rx1, ry1;
					reyes_hider_region(h, &rx0, &ry0, &rx1, &ry1);
					for (uint32_t k = 0; k < ng; k++) {
						const float *gx = grids[k]->x[0], *gy = grids[k]->y[0];
						size_t last = (size_t)(T + 1) * (T + 1) - 1;
						if (gx[last] < rx0 || gx[0] > rx1 || gy[last] < ry0 ||
						    gy[0] > ry1)
							continue;
						reyes_hider_add(h, &grids[k]->g);
					}
					double te = now();
					if (mode == 0) {
						reyes_hider_end(h, rgba, z, NULL);
					} else {
						const uint32_t *off;
						const struct reyes_vis_entry *ent;
						reyes_hider_end_record(h, &off, &ent, rgba, z);
						nent += off[B * B];
					}
					tend += now() - te;
				}
			}
			double dt = now() - t0;
			if (dt < best[mode])
				bend[mode] = tend;
			best[mode] = fmin(best[mode], dt);
			reyes_hider_destroy(h);
		}
	}
	printf("bench record: %ux%u, %u grids, 4x4 samples, gaussian 2: normal %.3f s (end %.3f), "
	       "record %.3f s (end %.3f): ratio %.2f, %.2f entries per pixel\n",
	       W, H, ng, best[0], bend[0], best[1], bend[1], best[1] / best[0],
	       (double)nent / (W * H));
	CHECK(nent > (uint64_t)W * H);
	free(rgba);
	free(z);
	for (uint32_t k = 0; k < ng; k++)
		tgrid_free(grids[k]);
}

int main(void)
{
	RUN(test_filter_values);
	RUN(test_constant_image);
	RUN(test_square_exact);
	RUN(test_square_fraction);
	RUN(test_disk);
	RUN(test_motion);
	RUN(test_order_independence);
	RUN(test_top_left);
	RUN(test_backface);
	RUN(test_depthfilter);
	RUN(test_shading);
	RUN(test_matte);
	RUN(test_dissolve);
	RUN(test_determinism);
	RUN(test_bad_input);
	RUN(test_record_identity);
	RUN(test_record_buckets);
	RUN(test_record_coloured_opacity);
	RUN(test_record_coverage);
	RUN(test_record_matte);
	RUN(test_record_id_overflow);
	RUN(test_record_wrong_mode);
	RUN(bench);
	RUN(bench_record);
	return test_finish();
}

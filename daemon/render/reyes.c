/*
 * The REYES pipeline.
 *
 *   pieces --bound, cull--> split until small on screen --> grid jobs
 *   bucket rows, top to bottom:
 *     shade the jobs that first touch the row (threads share the jobs):
 *       dice -> camera space -> displace -> shade (lights, textures) -> raster
 *     hide the row's buckets (threads share the buckets), keep the pixels
 *     free the grids that no later row touches
 *   write the displays
 *
 * Memory stays bounded by the grids that cross one bucket row. Each thread
 * has its own executors (one per shader instance) and its own hider; the
 * texture system is shared.
 *
 * reyes_dice runs the first half alone (pieces, split, dice, camera space,
 * displace) on one thread, primitive by primitive, for the bake's shadow
 * geometry.
 */
#include "reyes.h"
#include "reyes_impl.h"
#include "reyes_trace.h"
#include "imager.h"
#include "geom.h"
#include "nurbs.h"
#include "hider.h"
#include "texture.h"
#include "deepshadow.h"
#include "lighthost.h"
#include "png.h"
#include "mathlib.h"
#include "config.h"
#include "shader_cache.h"
#include "memlimit.h"

#include <math.h>
#include <stdarg.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#define MAX_SPLIT_DEPTH 24
#define NEAR_EPSILON 1e-4f

/* ---- small helpers ---- */

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* Matrix for normals: n' = n * inverse(M)^T, as a 3x3 applied by columns. */
static void normal_matrix(float nm[9], const float m[16])
{
	float inv[16];
	sl_m44_inverse(inv, m);
	for (int j = 0; j < 3; j++)
		for (int i = 0; i < 3; i++)
			nm[j * 3 + i] = inv[j * 4 + i];
}

static void xform_points(float *dst, const float *src, uint32_t n, const float m[16])
{
	for (uint32_t k = 0; k < n; k++) {
		float x = src[k], y = src[n + k], z = src[2 * n + k];
		float w = x * m[3] + y * m[7] + z * m[11] + m[15];
		float r[3];
		for (int c = 0; c < 3; c++)
			r[c] = x * m[c] + y * m[4 + c] + z * m[8 + c] + m[12 + c];
		if (w != 0 && w != 1)
			for (int c = 0; c < 3; c++)
				r[c] /= w;
		dst[k] = r[0];
		dst[n + k] = r[1];
		dst[2 * n + k] = r[2];
	}
}

static void xform_vectors(float *dst, const float *src, uint32_t n, const float m[16])
{
	for (uint32_t k = 0; k < n; k++) {
		float x = src[k], y = src[n + k], z = src[2 * n + k];
		for (int c = 0; c < 3; c++)
			dst[(size_t)c * n + k] = x * m[c] + y * m[4 + c] + z * m[8 + c];
	}
}

static void xform_normals(float *dst, const float *src, uint32_t n, const float nm[9])
{
	for (uint32_t k = 0; k < n; k++) {
		float x = src[k], y = src[n + k], z = src[2 * n + k];
		for (int j = 0; j < 3; j++)
			dst[(size_t)j * n + k] = nm[j * 3] * x + nm[j * 3 + 1] * y + nm[j * 3 + 2] * z;
	}
}

/* ---- the camera ---- */


static void setup_camera(struct camera *cam, const struct reyes_options *o)
{
	memcpy(cam->w2c, o->world_to_camera, sizeof(cam->w2c));
	memcpy(cam->w2c1, o->camera_moving ? o->world_to_camera1 : o->world_to_camera,
	       sizeof(cam->w2c1));
	cam->moving = memcmp(cam->w2c, cam->w2c1, sizeof(cam->w2c)) != 0;
	sl_m44_inverse(cam->c2w, cam->w2c);
	cam->xres = (float)o->xres;
	cam->yres = (float)o->yres;
	if (o->screen_set) {
		memcpy(cam->screen, o->screen, sizeof(cam->screen));
	} else {
		float fa = o->frame_aspect > 0 ? o->frame_aspect
			   : (float)o->xres * (o->pixel_aspect > 0 ? o->pixel_aspect : 1) /
				     (float)(o->yres ? o->yres : 1);
		if (fa >= 1) {
			float s[4] = { -fa, fa, -1, 1 };
			memcpy(cam->screen, s, sizeof(s));
		} else {
			float s[4] = { -1, 1, -1 / fa, 1 / fa };
			memcpy(cam->screen, s, sizeof(s));
		}
	}
	cam->perspective = o->perspective;
	float fov = o->fov > 0 && o->fov < 180 ? o->fov : 90;
	cam->focal = 1.0f / tanf(fov * 3.14159265358979f / 360.0f);
	cam->near = o->clip_near > 0 ? o->clip_near : NEAR_EPSILON;
	cam->far = o->clip_far > cam->near ? o->clip_far : 1e30f;
	/* camera -> screen: perspective divide by z; z maps near..far to 0..1 */
	float c2s[16] = { 0 };
	if (cam->perspective) {
		float a = cam->far / (cam->far - cam->near), b = -cam->near * a;
		c2s[0] = cam->focal;
		c2s[5] = cam->focal;
		c2s[10] = a;
		c2s[11] = 1;
		c2s[14] = b;
	} else {
		c2s[0] = 1;
		c2s[5] = 1;
		c2s[10] = 1 / (cam->far - cam->near);
		c2s[14] = -cam->near / (cam->far - cam->near);
		c2s[15] = 1;
	}
	float l = cam->screen[0], r = cam->screen[1], bt = cam->screen[2], t = cam->screen[3];
	float s2n[16] = { 0 };
	s2n[0] = 1 / (r - l);
	s2n[5] = -1 / (t - bt);
	s2n[10] = 1;
	s2n[12] = -l / (r - l);
	s2n[13] = t / (t - bt);
	s2n[15] = 1;
	sl_m44_mul(cam->c2ndc, c2s, s2n);

	/*
	 * Depth of field: a thin lens of aperture focallength / fstop at the
	 * eye, focused at focaldistance (camera-space units). Its radius, in
	 * screen units at unit distance times the screen-to-raster scale, is
	 * the raster shift per unit of lens position and of (1/d - 1/z); see
	 * hider.c. A pinhole (no fstop) and the orthographic camera have none.
	 */
	cam->lens[0] = cam->lens[1] = cam->lens_screen = 0;
	cam->focus = 0;
	if (cam->perspective && o->fstop > 0 && o->focallength > 0 && o->focaldistance > 0) {
		float radius = 0.5f * o->focallength / o->fstop * cam->focal;
		cam->lens[0] = radius * cam->xres / fabsf(r - l);
		cam->lens[1] = radius * cam->yres / fabsf(t - bt);
		cam->focus = 1 / o->focaldistance;
		cam->lens_screen = radius;
		if (!(isfinite(cam->lens[0]) && isfinite(cam->lens[1])))
			cam->lens[0] = cam->lens[1] = cam->lens_screen = 0;
	}
}

/* The largest raster shift the lens gives a point at camera depth in [z0, z1], per axis. */
static void lens_spread(const struct camera *cam, float z0, float z1, float out[2])
{
	out[0] = out[1] = 0;
	if (cam->lens[0] == 0 && cam->lens[1] == 0)
		return;
	/* 1/z is monotonic: the extremes of |1/d - 1/z| are at the ends. */
	z0 = fmaxf(z0, cam->near);
	z1 = fmaxf(z1, z0);
	float c = fmaxf(fabsf(cam->focus - 1 / z0), fabsf(cam->focus - 1 / z1));
	out[0] = c * cam->lens[0];
	out[1] = c * cam->lens[1];
}

/* Camera-space point to raster x, y (false when not in front of the eye). */
static inline bool to_raster(const struct camera *cam, float x, float y, float z, float *rx,
			     float *ry)
{
	float sx, sy;
	if (cam->perspective) {
		if (z < NEAR_EPSILON)
			return false;
		sx = cam->focal * x / z;
		sy = cam->focal * y / z;
	} else {
		sx = x;
		sy = y;
	}
	*rx = (sx - cam->screen[0]) / (cam->screen[1] - cam->screen[0]) * cam->xres;
	*ry = (cam->screen[3] - sy) / (cam->screen[3] - cam->screen[2]) * cam->yres;
	return true;
}

/* ---- grid jobs ---- */


/* Bytes per shaded point: the hider's grid (x y z at both times, Ci, Oi) and AOVs. */
static double point_bytes(const struct render *r)
{
	return (12.0 + r->naov_planes) * sizeof(float);
}

/* The bake keeps, per shaded point, its cached values: the estimate's guess of their size. */
#define BAKE_POINT_BYTES 64.0

/* "FILE:LINE: error: " for @loc, or "relight: error: " when no request set it. */
static void loc_error(const struct render *r, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void loc_error(const struct render *r, struct rib_loc loc, const char *fmt, ...)
{
	if (loc.file)
		fprintf(r->diag, "%s:%u: error: ", loc.file, loc.line);
	else
		fprintf(r->diag, "relight: error: ");
	va_list ap;
	va_start(ap, fmt);
	vfprintf(r->diag, fmt, ap);
	va_end(ap);
	fputc('\n', r->diag);
}

/* ---- bounding and splitting ---- */

void reyes_obj_to_camera(const struct render *r, const struct reyes_attrs *a, int t,
			  float m[16])
{
	sl_m44_mul(m, a->object_to_world[a->moving ? t : 0], t ? r->cam.w2c1 : r->cam.w2c);
}

/* Largest scale of the upper 3x3 of @m (to carry an object-space distance to camera space). */
static float max_scale(const float m[16])
{
	float s = 0;
	for (int i = 0; i < 3; i++) {
		float l = sqrtf(m[i * 4] * m[i * 4] + m[i * 4 + 1] * m[i * 4 + 1] +
				m[i * 4 + 2] * m[i * 4 + 2]);
		if (l > s)
			s = l;
	}
	return s;
}

enum bound_result { B_CULL, B_OK, B_STRADDLE };

/* Raster bound of a piece over the shutter (camera z range too). */
static enum bound_result piece_bound(const struct render *r, const struct reyes_patch *pa,
				     float rb[4], float *zmin_out)
{
	const struct reyes_attrs *a = pa->prim->attrs;
	float zmin = 1e30f, zmax = -1e30f;
	float x0 = 1e30f, y0 = 1e30f, x1 = -1e30f, y1 = -1e30f;
	bool straddle = false;
	/*
	 * Side planes of the view frustum (through the eye, widened by the filter
	 * margin): a bound with all its corners outside one of them cannot be
	 * seen, whichever side of the eye plane it lies on. Through a lens a
	 * point at depth z is seen up to lens_screen |1/d - 1/z| further out on
	 * the screen (lens_screen |z/d - 1| after multiplying by z): outside a
	 * plane for every lens position is an intersection of half-spaces, so
	 * still convex, and the corner test still holds.
	 */
	const struct camera *cam = &r->cam;
	float sw = (cam->screen[1] - cam->screen[0]) / cam->xres;
	float sh = (cam->screen[3] - cam->screen[2]) / cam->yres;
	float fl = cam->screen[0] + ((float)r->px0 - r->margin) * sw;
	float fr = cam->screen[0] + ((float)r->px1 + r->margin) * sw;
	float ft = cam->screen[3] - ((float)r->py0 - r->margin) * sh;
	float fb = cam->screen[3] - ((float)r->py1 + r->margin) * sh;
	float fo = cam->perspective ? cam->focal : 1;
	uint32_t outside[4] = { 0, 0, 0, 0 }, ncorners = 0;
	for (int t = 0; t < 2; t++) {
		float lo[3], hi[3], m[16];
		reyes_patch_bound(pa, t, lo, hi);
		reyes_obj_to_camera(r, a, t, m);
		float grow = 0;
		if (a->displacement && a->displacement_bound > 0)
			grow = a->displacement_bound * max_scale(m);
		for (int k = 0; k < 8; k++) {
			float p[3] = { k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1],
				       k & 4 ? hi[2] : lo[2] };
			float c[3];
			sl_xform_point(c, m, p);
			for (int g = 0; g < 8; g++) {
				float q[3] = { c[0] + (g & 1 ? grow : -grow), c[1] + (g & 2 ? grow : -grow),
					       c[2] + (g & 4 ? grow : -grow) };
				float w = cam->perspective ? q[2] : 1;
				float e = cam->lens_screen * fabsf(q[2] * cam->focus - 1);
				outside[0] += fo * q[0] + e < fl * w;
				outside[1] += fo * q[0] - e > fr * w;
				outside[2] += fo * q[1] + e < fb * w;
				outside[3] += fo * q[1] - e > ft * w;
				ncorners++;
				if (q[2] < zmin)
					zmin = q[2];
				if (q[2] > zmax)
					zmax = q[2];
				float rx, ry;
				if (!to_raster(&r->cam, q[0], q[1], q[2], &rx, &ry)) {
					straddle = true;
					continue;
				}
				x0 = fminf(x0, rx);
				y0 = fminf(y0, ry);
				x1 = fmaxf(x1, rx);
				y1 = fmaxf(y1, ry);
				if (grow == 0)
					break;
			}
		}
		if (!a->moving && !cam->moving && !reyes_prim_deforms(pa->prim))
			break;
	}
	*zmin_out = zmin;
	if (zmax < r->cam.near || zmin > r->cam.far)
		return B_CULL;
	for (int k = 0; k < 4; k++)
		if (outside[k] == ncorners)
			return B_CULL;
	if (straddle || (r->cam.perspective && zmin < r->cam.near))
		return B_STRADDLE;
	/* what the lens blurs reaches as far as its widest circle of confusion */
	float spread[2];
	lens_spread(cam, zmin, zmax, spread);
	x0 -= spread[0];
	x1 += spread[0];
	y0 -= spread[1];
	y1 += spread[1];
	rb[0] = x0;
	rb[1] = y0;
	rb[2] = x1;
	rb[3] = y1;
	if (x1 < (float)r->px0 - r->margin || x0 > (float)r->px1 + r->margin ||
	    y1 < (float)r->py0 - r->margin || y0 > (float)r->py1 + r->margin)
		return B_CULL;
	return B_OK;
}

/*
 * Raster lengths of a piece along u and v, from a TxT test dice: the longest
 * row and the longest column, at shutter open, and for a deforming
 * primitive the longer of open and close (a sphere growing threefold over
 * the shutter is diced for its size at close). Chords of a coarse test grid
 * underestimate curved edges (a 3x3 grid sees a full circle as two
 * diameters), so the test grid is fine enough to follow curvature.
 */
#define TEST_DICE 9
static bool piece_extent(const struct render *r, const struct reyes_patch *pa, float *lu,
			 float *lv)
{
	enum { T = TEST_DICE, TT = TEST_DICE * TEST_DICE };
	struct reyes_grid g = { 0 };
	if (!reyes_patch_dice(pa, T, T, &g))
		return false;
	int times = reyes_prim_deforms(pa->prim) ? 2 : 1;
	float mu = 0, mv = 0;
	bool ok = true;
	for (int t = 0; t < times && ok; t++) {
		float m[16];
		reyes_obj_to_camera(r, pa->prim->attrs, t, m);
		float rx[TT], ry[TT];
		for (int k = 0; k < TT; k++) {
			float p[3] = { g.P[t][k], g.P[t][TT + k], g.P[t][2 * TT + k] }, c[3];
			sl_xform_point(c, m, p);
			if (!to_raster(&r->cam, c[0], c[1], c[2], &rx[k], &ry[k]))
				ok = false;
		}
		for (int j = 0; j < T && ok; j++) {
			float su = 0, sv = 0;
			for (int i = 0; i + 1 < T; i++) {
				int a = j * T + i, b = a + 1;
				su += hypotf(rx[b] - rx[a], ry[b] - ry[a]);
				a = i * T + j;
				b = a + T;
				sv += hypotf(rx[b] - rx[a], ry[b] - ry[a]);
			}
			mu = fmaxf(mu, su);
			mv = fmaxf(mv, sv);
		}
	}
	reyes_grid_finish(&g);
	if (!ok)
		return false;
	*lu = mu;
	*lv = mv;
	return true;
}

static void add_job(struct render *r, const struct reyes_patch *pa, uint32_t nu, uint32_t nv,
		    const float rb[4])
{
	if (r->njobs == r->capjobs)
		r->jobs = rl_vec_grow_(r->jobs, &r->capjobs, sizeof(*r->jobs), r->njobs + 1);
	struct job *j = &r->jobs[r->njobs++];
	memset(j, 0, sizeof(*j));
	j->piece = *pa;
	j->nu = nu;
	j->nv = nv;
	j->bx0 = rb[0] - 1;
	j->by0 = rb[1] - 1;
	j->bx1 = rb[2] + 1;
	j->by1 = rb[3] + 1;
	float top = fmaxf(j->by0 - r->margin, (float)r->py0);
	float bottom = fminf(j->by1 + r->margin, (float)r->py1 - 1);
	j->row0 = (uint32_t)((top - (float)r->py0) / (float)r->bucket);
	j->row1 = (uint32_t)((fmaxf(bottom, top) - (float)r->py0) / (float)r->bucket);
	if (j->row1 >= r->nby)
		j->row1 = r->nby - 1;
	if (j->row0 > j->row1)
		j->row0 = j->row1;
}

/*
 * Lengths of a piece along u and v for a piece the camera does not see, in
 * units of the size a pixel has at the distance of each edge of a test dice
 * (the distance from the eye, no nearer than the near clipping plane): what
 * is off screen or behind the eye is diced as finely as if the camera turned
 * to face it. False when memory runs out.
 */
static bool piece_extent_unseen(const struct render *r, const struct reyes_patch *pa,
				float *lu, float *lv)
{
	enum { T = TEST_DICE, TT = TEST_DICE * TEST_DICE };
	struct reyes_grid g = { 0 };
	if (!reyes_patch_dice(pa, T, T, &g))
		return false;
	const struct camera *cam = &r->cam;
	float m[16];
	reyes_obj_to_camera(r, pa->prim->attrs, 0, m);
	float c[TT][3], dist[TT];
	for (int k = 0; k < TT; k++) {
		float p[3] = { g.P[0][k], g.P[0][TT + k], g.P[0][2 * TT + k] };
		sl_xform_point(c[k], m, p);
		dist[k] = cam->perspective ? fmaxf(sl_v3_length(c[k]), cam->near) : 1;
	}
	reyes_grid_finish(&g);
	/* a pixel's size at distance 1 (perspective) or anywhere (orthographic) */
	float pw = fabsf(cam->screen[1] - cam->screen[0]) / cam->xres;
	float ph = fabsf(cam->screen[3] - cam->screen[2]) / cam->yres;
	float pix = fminf(pw, ph) / (cam->perspective ? cam->focal : 1);
	float mu = 0, mv = 0;
	for (int j = 0; j < T; j++) {
		float su = 0, sv = 0;
		for (int i = 0; i + 1 < T; i++) {
			int a = j * T + i, b = a + 1;
			float d[3] = { c[b][0] - c[a][0], c[b][1] - c[a][1], c[b][2] - c[a][2] };
			su += sl_v3_length(d) / (pix * fminf(dist[a], dist[b]));
			a = i * T + j;
			b = a + T;
			float e[3] = { c[b][0] - c[a][0], c[b][1] - c[a][1], c[b][2] - c[a][2] };
			sv += sl_v3_length(e) / (pix * fminf(dist[a], dist[b]));
		}
		mu = fmaxf(mu, su);
		mv = fmaxf(mv, sv);
	}
	*lu = mu;
	*lv = mv;
	return true;
}


/* What the frame needs beyond its fixed part: the fullest bucket row's points and the jobs. */
static double working_bytes(const struct render *r)
{
	double b = r->row_most * point_bytes(r) + r->job_bytes;
	if (r->o->bake)
		b += r->total_points * BAKE_POINT_BYTES;
	return b;
}

/*
 * Count what a piece @lu x @lv pixels long asks for at @rate before it is
 * split: (lu / sqrt(rate) + 1) (lv / sqrt(rate) + 1) points, but no more
 * than twice the area of its raster bound on screen (with the filter
 * margin) over the rate: what splitting culls off screen is not diced, and
 * a piece seen in perspective has shorter edges far away than its longest
 * ones (twice: a piece may fold over itself, a sphere's two halves). They
 * are alive from the first bucket row the piece touches to the last (a
 * job's grid spans two rows or so, so a piece over k rows keeps about 2/k
 * of its points alive at once); the jobs it splits into are counted too.
 * False, with the message, when the frame would then need more than the
 * limit: the piece is not split.
 */
static bool predict_piece(struct render *r, const struct reyes_patch *pa, float lu, float lv,
			  float rate, const float rb[4])
{
	if (!r->limit || !r->row_points || atomic_load(&r->failed))
		return !atomic_load(&r->failed);
	double edge = sqrt((double)rate);
	double pts = ((double)lu / edge + 1) * ((double)lv / edge + 1);
	if (rb[2] > rb[0] || rb[3] > rb[1]) {
		double x0 = fmax(rb[0], r->px0 - r->margin), x1 = fmin(rb[2], r->px1 + r->margin);
		double y0 = fmax(rb[1], r->py0 - r->margin), y1 = fmin(rb[3], r->py1 + r->margin);
		double on = fmax(x1 - x0 + 1, 0) * fmax(y1 - y0 + 1, 0);
		pts = fmin(pts, 2 * on / rate + 1);
	}
	double njobs = fmin(ceil(pts / r->max_points), ldexp(1, MAX_SPLIT_DEPTH - pa->depth));
	uint32_t row0 = 0, row1 = r->nby - 1;
	if (rb[3] > rb[1]) {
		double top = fmax(rb[1] - r->margin - r->py0, 0) / r->bucket;
		double bottom = fmax(rb[3] + r->margin - r->py0, 0) / r->bucket;
		row0 = top < r->nby ? (uint32_t)top : r->nby - 1;
		row1 = bottom < r->nby ? (uint32_t)bottom : r->nby - 1;
	}
	double alive = pts * fmin(1.0, 2.0 / (row1 - row0 + 1));
	for (uint32_t k = row0; k <= row1; k++) {
		r->row_points[k] += alive;
		if (r->row_points[k] > r->row_most) {
			r->row_most = r->row_points[k];
			r->row_fullest = k;
		}
	}
	r->total_points += pts;
	r->job_bytes += njobs * sizeof(struct job);
	double need = r->fixed_bytes + working_bytes(r);
	if (need <= (double)r->limit)
		return true;
	const struct reyes_attrs *a = pa->prim->attrs;
	char est[32], lim[32];
	loc_error(r, a->shading_rate_loc,
		  "ShadingRate %g%s asks for about %.3g micropolygons (%s with the rest of the "
		  "frame, the fullest bucket row %u), over the memory limit of %s (--memory-limit): "
		  "raise the ShadingRate%s", (double)(r->rate > 0 ? r->rate : rate),
		  a->shading_rate_loc.file ? "" : " (the default)", r->total_points,
		  reyes_mem_format(est, sizeof(est), (uint64_t)fmin(need, 1.8e19)), r->row_fullest,
		  reyes_mem_format(lim, sizeof(lim), r->limit),
		  r->o->bake ? ", or bake fewer pixels" : "");
	atomic_store(&r->failed, true);
	return false;
}

/*
 * Dice a piece @lu x @lv pixels long at the shading rate, in one grid if it
 * fits, else split it in two.
 */
static void queue_piece(struct render *r, const struct reyes_patch *pa, float lu, float lv,
			const float rb[4])
{
	float rate = r->rate > 0 ? r->rate
		     : pa->prim->attrs->shading_rate > 0 ? pa->prim->attrs->shading_rate : 1;
	float edge = sqrtf(rate);
	float fu = ceilf(lu / edge), fv = ceilf(lv / edge);
	if (!r->predicted && !predict_piece(r, pa, lu, lv, rate, rb))
		return;
	uint32_t nu = (uint32_t)fminf(fmaxf(fu, 1), 4096) + 1;
	uint32_t nv = (uint32_t)fminf(fmaxf(fv, 1), 4096) + 1;
	if ((uint64_t)nu * nv > r->max_points && pa->depth < MAX_SPLIT_DEPTH) {
		struct reyes_patch half[2];
		reyes_patch_split(pa, lu >= lv, half);
		bool outer = !r->predicted;
		r->predicted = true;
		reyes_split_piece(r, &half[0]);
		reyes_split_piece(r, &half[1]);
		r->predicted = !outer;
		return;
	}
	while ((uint64_t)nu * nv > r->max_points) {
		if (nu >= nv)
			nu = nu / 2 + 1;
		else
			nv = nv / 2 + 1;
	}
	add_job(r, pa, nu, nv, rb);
}

/* Split a piece until it can be diced in one grid, then queue it. */
void reyes_split_piece(struct render *r, const struct reyes_patch *pa)
{
	if (atomic_load(&r->failed))
		return;
	float rb[4] = { 0, 0, 0, 0 }, zmin;
	enum bound_result br = piece_bound(r, pa, rb, &zmin);
	if (r->keep_unseen) {
		float lu = 0, lv = 0;
		if (!r->orient_free && br == B_OK && piece_extent(r, pa, &lu, &lv)) {
			queue_piece(r, pa, lu, lv, rb);
		} else if (piece_extent_unseen(r, pa, &lu, &lv)) {
			rb[0] = rb[1] = rb[2] = rb[3] = 0;
			queue_piece(r, pa, lu, lv, rb);
		} else {
			atomic_store(&r->failed, true);
		}
		return;
	}
	if (br == B_CULL)
		return;
	if (br == B_STRADDLE) {
		if (pa->depth >= MAX_SPLIT_DEPTH) {
			r->dropped++;
			return;
		}
		struct reyes_patch half[2];
		reyes_patch_split(pa, pa->depth % 2 == 0, half);
		reyes_split_piece(r, &half[0]);
		reyes_split_piece(r, &half[1]);
		return;
	}
	float lu = 0, lv = 0;
	if (!piece_extent(r, pa, &lu, &lv)) {
		/* some point behind the eye after all */
		if (pa->depth >= MAX_SPLIT_DEPTH) {
			r->dropped++;
			return;
		}
		struct reyes_patch half[2];
		reyes_patch_split(pa, pa->depth % 2 == 0, half);
		reyes_split_piece(r, &half[0]);
		reyes_split_piece(r, &half[1]);
		return;
	}
	queue_piece(r, pa, lu, lv, rb);
}

/* ---- shading ---- */

static struct sl_exec *exec_for(struct tctx *t, const struct reyes_shader *sh)
{
	for (size_t i = 0; i < t->nexecs; i++)
		if (t->execs[i].sh == sh)
			return t->execs[i].x;
	const struct reyes_bake_hooks *bk = t->r->o->bake;
	const struct sl_program *prog = sh->prog;
	if (bk && sh->prog->kind == SL_SHADER_SURFACE) {
		prog = bk->program(bk->user, sh);
		if (!prog)
			return NULL;
	}
	struct sl_exec *x = sl_exec_create(prog, t->r->max_points);
	if (!x)
		return NULL;
	if (t->nexecs == t->capexecs)
		t->execs = rl_vec_grow_(t->execs, &t->capexecs, sizeof(*t->execs), t->nexecs + 1);
	t->execs[t->nexecs].sh = sh;
	t->execs[t->nexecs].x = x;
	t->nexecs++;
	return x;
}

/* Give a shader executor its instance's parameter values (and primvars of the same names). */
static void set_params(struct sl_exec *x, const struct reyes_shader *sh,
		       const struct reyes_grid *g)
{
	sl_exec_reset_params(x);
	const struct sl_program *prog = sl_exec_program(x);
	for (uint32_t i = 0; i < sh->nparams; i++) {
		const struct reyes_param_value *pv = &sh->params[i];
		if (pv->type == SL_TYPE_STRING) {
			if (pv->strings && pv->nvalues)
				sl_exec_set_param_string(x, pv->name, pv->strings[0]);
		} else if (pv->values) {
			sl_exec_set_param(x, pv->name, pv->values, pv->nvalues);
		}
	}
	if (!g)
		return;
	/* Varying values are taken per point of the grid being shaded, whose
	   size must be known first. */
	sl_exec_set_grid(x, g->nu, g->nv);
	for (uint32_t i = 0; i < g->nvars; i++) {
		int k = sl_program_find_param(prog, g->vars[i].name);
		if (k < 0)
			continue;
		const struct sl_param *p = &prog->params[k];
		int nc = sl_type_ncomp(g->vars[i].type) *
			 (int)(g->vars[i].arraylen ? g->vars[i].arraylen : 1);
		/* one that does not fit was ignored with a warning at its request */
		if (p->type.base == SL_TYPE_STRING ||
		    nc != sl_type_ncomp(p->type.base) * (p->type.arraylen > 0 ? p->type.arraylen : 1))
			continue;
		if (p->type.detail == SL_DETAIL_VARYING) {
			sl_exec_set_param(x, p->name, g->vars[i].data, (uint32_t)nc * g->n);
			continue;
		}
		/* A uniform parameter takes the first point's value; the grid's
		   values are planar, a plane of n per component. */
		float *first = malloc(sizeof(float) * (size_t)nc);
		if (!first)
			continue;
		for (int c = 0; c < nc; c++)
			first[c] = g->vars[i].data[(size_t)c * g->n];
		sl_exec_set_param(x, p->name, first, (uint32_t)nc);
		free(first);
	}
}

/* Copy a planar array of @nc components into a global (broadcast for uniform ones). */
static void put_global(struct sl_exec *x, enum sl_global gl, const float *src, int nc,
		       uint32_t n)
{
	bool vary;
	float *d = sl_exec_global(x, gl, &vary);
	if (!d || !src)
		return;
	uint32_t st = sl_exec_stride(x);
	for (int c = 0; c < nc; c++) {
		if (vary)
			memcpy(d + (size_t)c * st, src + (size_t)c * n, n * sizeof(float));
		else
			d[c] = src[(size_t)c * n];
	}
}

static void put_global_const(struct sl_exec *x, enum sl_global gl, const float *v, int nc,
			     uint32_t n)
{
	bool vary;
	float *d = sl_exec_global(x, gl, &vary);
	if (!d)
		return;
	uint32_t st = sl_exec_stride(x);
	for (int c = 0; c < nc; c++) {
		if (vary)
			for (uint32_t k = 0; k < n; k++)
				d[(size_t)c * st + k] = v[c];
		else
			d[c] = v[c];
	}
}

static void get_global(struct sl_exec *x, enum sl_global gl, float *dst, int nc, uint32_t n)
{
	bool vary;
	const float *d = sl_exec_global(x, gl, &vary);
	uint32_t st = sl_exec_stride(x);
	for (int c = 0; c < nc; c++)
		for (uint32_t k = 0; k < n; k++)
			dst[(size_t)c * n + k] = !d ? 0 : vary ? d[(size_t)c * st + k] : d[c];
}


static void fill_globals(struct tctx *t, struct sl_exec *x, const struct cgrid *c,
			 const struct reyes_attrs *a)
{
	uint32_t n = c->n;
	sl_exec_set_grid(x, c->nu, c->nv);
	float zero[3] = { 0, 0, 0 }, three = 3;
	put_global(x, SL_GLOBAL_P, c->P0, 3, n);
	put_global(x, SL_GLOBAL_N, c->N, 3, n);
	put_global(x, SL_GLOBAL_NG, c->Ng, 3, n);
	put_global(x, SL_GLOBAL_DPDU, c->dPdu, 3, n);
	put_global(x, SL_GLOBAL_DPDV, c->dPdv, 3, n);
	put_global(x, SL_GLOBAL_I, c->I, 3, n);
	put_global_const(x, SL_GLOBAL_E, zero, 3, n);
	put_global(x, SL_GLOBAL_U, c->u, 1, n);
	put_global(x, SL_GLOBAL_V, c->v, 1, n);
	put_global(x, SL_GLOBAL_S, c->s, 1, n);
	put_global(x, SL_GLOBAL_T, c->t, 1, n);
	put_global_const(x, SL_GLOBAL_DU, &c->du, 1, n);
	put_global_const(x, SL_GLOBAL_DV, &c->dv, 1, n);
	if (c->Cs)
		put_global(x, SL_GLOBAL_CS, c->Cs, 3, n);
	else
		put_global_const(x, SL_GLOBAL_CS, a->Cs, 3, n);
	if (c->Os)
		put_global(x, SL_GLOBAL_OS, c->Os, 3, n);
	else
		put_global_const(x, SL_GLOBAL_OS, a->Os, 3, n);
	float time = t->r->scene->opts.shutter[0];
	float dtime = t->r->scene->opts.shutter[1] - t->r->scene->opts.shutter[0];
	put_global_const(x, SL_GLOBAL_TIME, &time, 1, n);
	put_global_const(x, SL_GLOBAL_DTIME, &dtime, 1, n);
	put_global_const(x, SL_GLOBAL_NCOMPS, &three, 1, n);
	float dp[3];
	/* dPdtime: motion over the shutter */
	bool vary;
	float *d = sl_exec_global(x, SL_GLOBAL_DPDTIME, &vary);
	if (d) {
		uint32_t st = sl_exec_stride(x);
		for (uint32_t k = 0; k < (vary ? n : 1); k++)
			for (int cc = 0; cc < 3; cc++) {
				dp[cc] = dtime > 0 ? (c->P1[(size_t)cc * n + k] - c->P0[(size_t)cc * n + k]) / dtime
						   : 0;
				if (vary)
					d[(size_t)cc * st + k] = dp[cc];
				else
					d[cc] = dp[cc];
			}
	}
}


static void add_space(struct spaces *sp, const char *name, const float m[16])
{
	if (sp->n >= 64)
		return;
	sp->names[sp->n] = name;
	memcpy(sp->mats[sp->n], m, 16 * sizeof(float));
	sp->n++;
}

static void build_spaces(const struct render *r, const struct reyes_attrs *a,
			 const struct reyes_shader *sh, struct spaces *sp)
{
	sp->n = 0;
	const struct camera *cam = &r->cam;
	float m[16], inv[16];
	add_space(sp, "world", cam->w2c);
	sl_m44_mul(m, a->object_to_world[0], cam->w2c);
	add_space(sp, "object", m);
	if (sh) {
		sl_m44_mul(m, sh->shader_to_world, cam->w2c);
		add_space(sp, "shader", m);
	}
	/* screen, NDC, raster: inverses of the projections from camera space */
	float c2s[16], s2n[16];
	memcpy(c2s, cam->c2ndc, sizeof(c2s));
	sl_m44_inverse(inv, cam->c2ndc);
	add_space(sp, "NDC", inv);
	float n2r[16];
	sl_m44_identity(n2r);
	n2r[0] = cam->xres;
	n2r[5] = cam->yres;
	sl_m44_mul(m, cam->c2ndc, n2r);
	sl_m44_inverse(inv, m);
	add_space(sp, "raster", inv);
	/* screen = NDC before the window mapping */
	float l = cam->screen[0], rr = cam->screen[1], b = cam->screen[2], t = cam->screen[3];
	memset(s2n, 0, sizeof(s2n));
	s2n[0] = 1 / (rr - l);
	s2n[5] = -1 / (t - b);
	s2n[10] = 1;
	s2n[12] = -l / (rr - l);
	s2n[13] = t / (t - b);
	s2n[15] = 1;
	float n2s[16];
	sl_m44_inverse(n2s, s2n);
	sl_m44_mul(m, cam->c2ndc, n2s);
	sl_m44_inverse(inv, m);
	add_space(sp, "screen", inv);
	(void)c2s;
	const struct reyes_scene *sc = r->scene;
	for (uint32_t i = 0; i < sc->nspaces; i++) {
		sl_m44_mul(m, sc->space_to_world[i], cam->w2c);
		add_space(sp, sc->space_names[i], m);
	}
}

static bool host_texture(void *user, const struct sl_tex_lookup *q)
{
	struct tctx *t = ((struct sl_lighthost *)user)->owner;
	return reyes_tex_texture(t->r->tex, q);
}

static bool host_environment(void *user, const struct sl_tex_lookup *q)
{
	struct tctx *t = ((struct sl_lighthost *)user)->owner;
	return reyes_tex_environment(t->r->tex, q);
}

static bool host_shadow(void *user, const struct sl_tex_lookup *q)
{
	struct tctx *t = ((struct sl_lighthost *)user)->owner;
	return reyes_tex_shadow(t->r->tex, q);
}

static bool host_textureinfo(void *user, const char *name, const char *query, int type,
			     int arraylen, float *out, const char **sout)
{
	struct tctx *t = ((struct sl_lighthost *)user)->owner;
	return reyes_tex_info(t->r->tex, name, query, type, arraylen, out, sout);
}

static bool host_option(void *user, const char *name, int type, int arraylen, float *out,
			const char **sout)
{
	struct tctx *t = ((struct sl_lighthost *)user)->owner;
	const struct reyes_options *o = &t->r->scene->opts;
	(void)sout;
	if (!strcmp(name, "Format") && type == SL_TYPE_FLOAT && arraylen == 3) {
		out[0] = (float)o->xres;
		out[1] = (float)o->yres;
		out[2] = o->pixel_aspect;
		return true;
	}
	if (!strcmp(name, "Clipping") && type == SL_TYPE_FLOAT && arraylen == 2) {
		out[0] = t->r->cam.near;
		out[1] = t->r->cam.far;
		return true;
	}
	if (!strcmp(name, "Shutter") && type == SL_TYPE_FLOAT && arraylen == 2) {
		out[0] = o->shutter[0];
		out[1] = o->shutter[1];
		return true;
	}
	return false;
}

static bool host_rendererinfo(void *user, const char *name, int type, int arraylen, float *out,
			      const char **sout)
{
	(void)user;
	(void)out;
	(void)arraylen;
	if (!strcmp(name, "renderer") && type == SL_TYPE_STRING) {
		*sout = "relight";
		return true;
	}
	if (!strcmp(name, "version") && type == SL_TYPE_STRING) {
		*sout = RELIGHT_VERSION;
		return true;
	}
	return false;
}

static bool host_trace(void *user, struct sl_ray_query *q)
{
	return reyes_rt_trace(((struct sl_lighthost *)user)->owner, q);
}

static bool host_rayinfo(void *user, const char *name, int type, int arraylen, float *out,
			 const char **sout)
{
	return reyes_rt_rayinfo(((struct sl_lighthost *)user)->owner, name, type, arraylen, out,
				sout);
}

static void setup_host(struct tctx *t, struct sl_exec **lights, int nlights,
		       const float (*mats)[16], const struct spaces *sp)
{
	sl_lighthost_init(&t->lh, lights, nlights);
	t->lh.owner = t;
	t->lh.light_shader_mats = mats;
	t->lh.space_names = sp->names;
	t->lh.space_mats = (const float (*)[16])sp->mats;
	t->lh.nspaces = sp->n;
	t->lh.host.texture = host_texture;
	t->lh.host.environment = host_environment;
	t->lh.host.shadow = host_shadow;
	t->lh.host.textureinfo = host_textureinfo;
	t->lh.host.option = host_option;
	t->lh.host.rendererinfo = host_rendererinfo;
	t->lh.host.trace = host_trace;
	t->lh.host.rayinfo = host_rayinfo;
	t->lh.host.specular_model = t->r->scene->opts.specular_model;
}

static struct sl_exec *light_exec(struct tctx *t, uint32_t li)
{
	if (!t->light_x[li]) {
		const struct reyes_light *L = &t->r->scene->lights[li];
		t->light_x[li] = sl_exec_create(L->shader.prog, t->r->max_points);
		if (t->light_x[li])
			set_params(t->light_x[li], &L->shader, NULL);
	}
	return t->light_x[li];
}

/* Ng from a displaced grid: central differences of P along u and v. */
static void recompute_ng(struct cgrid *c, bool flip)
{
	uint32_t nu = c->nu, nv = c->nv, n = c->n;
	for (uint32_t j = 0; j < nv; j++)
		for (uint32_t i = 0; i < nu; i++) {
			uint32_t k = j * nu + i;
			uint32_t a = j * nu + (i > 0 ? i - 1 : i), b = j * nu + (i + 1 < nu ? i + 1 : i);
			uint32_t cc = (j > 0 ? j - 1 : j) * nu + i, d = (j + 1 < nv ? j + 1 : j) * nu + i;
			float du[3], dv[3], ng[3];
			for (int q = 0; q < 3; q++) {
				du[q] = c->P0[(size_t)q * n + b] - c->P0[(size_t)q * n + a];
				dv[q] = c->P0[(size_t)q * n + d] - c->P0[(size_t)q * n + cc];
			}
			sl_v3_cross(ng, du, dv);
			float len = sl_v3_length(ng);
			if (len > 0)
				for (int q = 0; q < 3; q++)
					c->Ng[(size_t)q * n + k] = (flip ? -ng[q] : ng[q]) / len;
		}
}

/*
 * TextureCoordinates: s and t bilinear over the (u, v) square between the
 * values at its corners (0, 0), (1, 0), (0, 1), (1, 1), where the primitive
 * gives no s or t of its own.
 */
static void texture_coordinates(struct cgrid *c, const struct reyes_grid *g, const float tc[8])
{
	for (uint32_t k = 0; k < c->n; k++) {
		double u = g->u[k], v = g->v[k];
		double w[4] = {(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v};
		if (!g->s)
			c->s[k] = (float)(w[0] * tc[0] + w[1] * tc[2] + w[2] * tc[4] + w[3] * tc[6]);
		if (!g->t)
			c->t[k] = (float)(w[0] * tc[1] + w[1] * tc[3] + w[2] * tc[5] + w[3] * tc[7]);
	}
}

/*
 * Dice a job into @g and carry it to camera space, displaced, in @c. On
 * success the caller frees c->P0 (one buffer holds all of @c's planes) and
 * finishes @g; on failure nothing is left to free.
 */
bool reyes_dice_job(struct tctx *t, const struct job *job, struct reyes_grid *g,
		     struct cgrid *cg)
{
	struct render *r = t->r;
	const struct reyes_prim *prim = job->piece.prim;
	const struct reyes_attrs *a = prim->attrs;
	if (!reyes_patch_dice(&job->piece, job->nu, job->nv, g))
		return false;
	uint32_t n = g->n;
	struct cgrid c = { .nu = g->nu, .nv = g->nv, .n = n, .u = g->u, .v = g->v, .du = g->du,
			   .dv = g->dv };
	/* camera-space buffers: P0 P1 N Ng dPdu dPdv I s t */
	float *buf = malloc(sizeof(float) * n * 3 * 7 + sizeof(float) * n * 2);
	if (!buf) {
		reyes_grid_finish(g);
		return false;
	}
	c.P0 = buf;
	c.P1 = buf + 3 * n;
	c.N = buf + 6 * n;
	c.Ng = buf + 9 * n;
	c.dPdu = buf + 12 * n;
	c.dPdv = buf + 15 * n;
	c.I = buf + 18 * n;
	c.s = buf + 21 * n;
	c.t = buf + 22 * n;
	float m0[16], m1[16], nm[9];
	reyes_obj_to_camera(r, a, 0, m0);
	reyes_obj_to_camera(r, a, 1, m1);
	normal_matrix(nm, m0);
	xform_points(c.P0, g->P[0], n, m0);
	xform_points(c.P1, g->P[1] ? g->P[1] : g->P[0], n, m1);
	xform_vectors(c.dPdu, g->dPdu, n, m0);
	xform_vectors(c.dPdv, g->dPdv, n, m0);
	xform_normals(c.Ng, g->Ng, n, nm);
	if (g->N)
		xform_normals(c.N, g->N, n, nm);
	else
		memcpy(c.N, c.Ng, sizeof(float) * 3 * n);
	memcpy(c.s, g->s ? g->s : g->u, sizeof(float) * n);
	memcpy(c.t, g->t ? g->t : g->v, sizeof(float) * n);
	if (a->texcoords && prim->kind != REYES_POLYGONS)
		texture_coordinates(&c, g, a->texcoords);
	c.Cs = g->Cs;
	c.Os = g->Os;

	/* displacement */
	if (a->displacement) {
		struct spaces sp;
		for (uint32_t k = 0; k < 3 * n; k++)
			c.I[k] = c.P0[k];
		struct sl_exec *dx = exec_for(t, a->displacement);
		if (!dx)
			goto fail;
		build_spaces(r, a, a->displacement, &sp);
		setup_host(t, NULL, 0, NULL, &sp);
		set_params(dx, a->displacement, g);
		fill_globals(t, dx, &c, a);
		if (!sl_exec_run(dx, &t->lh.host))
			goto fail;
		float *P = malloc(sizeof(float) * 3 * n);
		if (!P)
			goto fail;
		get_global(dx, SL_GLOBAL_P, P, 3, n);
		for (uint32_t k = 0; k < 3 * n; k++) {
			float d = P[k] - c.P0[k];
			c.P1[k] += d;
			c.P0[k] = P[k];
		}
		free(P);
		get_global(dx, SL_GLOBAL_N, c.N, 3, n);
		/* A camera-space cross product turns inside out under a mirroring
		 * transform, where the object-space normal (carried by the normal
		 * matrix) does not. */
		recompute_ng(&c, a->flip_normals != (sl_m44_det(m0) < 0));
	}
	*cg = c;
	return true;
fail:
	free(buf);
	reyes_grid_finish(g);
	return false;
}

/* Run surface shader @surf over the grid @g, @c with the primitive's lights; *@sx ran it. */
bool reyes_shade_surface(struct tctx *t, const struct reyes_attrs *a,
			  const struct reyes_shader *surf, const struct reyes_grid *g,
			  const struct cgrid *c, struct sl_exec **sx)
{
	struct render *r = t->r;
	struct spaces sp;
	t->shading = a;
	*sx = exec_for(t, surf);
	if (!*sx)
		return false;
	for (uint32_t i = 0; i < a->nlights; i++) {
		t->lights_on[i] = light_exec(t, a->lights[i]);
		memcpy(t->light_mats[i], r->light_mats[a->lights[i]], sizeof(t->light_mats[i]));
		if (!t->lights_on[i])
			return false;
	}
	build_spaces(r, a, surf, &sp);
	setup_host(t, t->lights_on, (int)a->nlights, (const float (*)[16])t->light_mats, &sp);
	set_params(*sx, surf, g);
	fill_globals(t, *sx, c, a);
	return sl_exec_run(*sx, &t->lh.host);
}

/* Dice, displace, shade and project one job; fills job->sh. */
static bool shade_job(struct tctx *t, struct job *job)
{
	struct render *r = t->r;
	const struct reyes_prim *prim = job->piece.prim;
	const struct reyes_attrs *a = prim->attrs;
	struct reyes_grid g = { 0 };
	struct cgrid c;
	if (!reyes_dice_job(t, job, &g, &c))
		return false;
	uint32_t n = g.n;
	float *buf = c.P0;
	bool ok = true;
	/* the incident ray, eye at the origin (orthographic: straight ahead) */
	for (uint32_t k = 0; k < n; k++) {
		if (r->cam.perspective) {
			c.I[k] = c.P0[k];
			c.I[n + k] = c.P0[n + k];
			c.I[2 * n + k] = c.P0[2 * n + k];
		} else {
			c.I[k] = 0;
			c.I[n + k] = 0;
			c.I[2 * n + k] = 1;
		}
	}
	/* surface: a matte object is not shaded (RISpec), it is opaque and adds nothing */
	const struct reyes_shader *surf = a->surface ? a->surface : &r->default_surface;
	struct sl_exec *sx = NULL;
	if (!a->matte && !reyes_shade_surface(t, a, surf, &g, &c, &sx)) {
		ok = false;
		goto done;
	}

	/* the hider's grid: x y z at both times, Ci, Oi, aovs */
	const struct reyes_trim *trim = prim->nurbs ? prim->nurbs->trim : NULL;
	size_t planes = 6 + 6 + r->naov_planes + (trim ? 2 : 0);
	struct shaded *sh = calloc(1, sizeof(*sh));
	float *mem = sh ? malloc(sizeof(float) * n * planes + sizeof(float *) * (r->naov_planes + 1))
			: NULL;
	if (!mem) {
		free(sh);
		ok = false;
		goto done;
	}
	sh->mem = mem;
	float *x0 = mem, *y0 = mem + n, *z0 = mem + 2 * n, *x1 = mem + 3 * n, *y1 = mem + 4 * n,
	      *z1 = mem + 5 * n, *ci = mem + 6 * n, *oi = mem + 9 * n;
	float *aovbase = mem + 12 * n;
	const float **aovp = (const float **)(void *)(mem + n * planes);
	bool moving = a->moving || memcmp(c.P0, c.P1, sizeof(float) * 3 * n) != 0;
	for (uint32_t k = 0; k < n; k++) {
		float zz = c.P0[2 * n + k];
		if (!to_raster(&r->cam, c.P0[k], c.P0[n + k], zz, &x0[k], &y0[k])) {
			x0[k] = y0[k] = -1e30f;
			zz = -1;
		}
		z0[k] = zz;
		zz = c.P1[2 * n + k];
		if (!to_raster(&r->cam, c.P1[k], c.P1[n + k], zz, &x1[k], &y1[k])) {
			x1[k] = y1[k] = -1e30f;
			zz = -1;
		}
		z1[k] = zz;
	}
	const struct reyes_bake_hooks *bk = r->o->bake;
	if (a->matte) {
		/* no shading samples: a matte hit is recorded as no entry */
		sh->hg.id0 = 0;
		for (size_t k = 0; k < 3 * (size_t)n; k++) {
			ci[k] = 0;
			oi[k] = 1;
		}
	} else if (bk) {
		sh->hg.id0 = bk->grid(bk->user, surf, prim, sx, n);
		if (sh->hg.id0 == UINT32_MAX) {
			free(mem);
			free(sh);
			ok = false;
			goto done;
		}
	} else {
		get_global(sx, SL_GLOBAL_CI, ci, 3, n);
	}
	if (!a->matte)
		get_global(sx, SL_GLOBAL_OI, oi, 3, n);
	/* the bake records sample ids instead of colours and AOVs */
	for (uint32_t q = 0; !bk && q < r->naov; q++) {
		const struct aov *av = &r->aovs[q];
		float *dst = aovbase + (size_t)av->offset * n;
		if (a->matte) {
			memset(dst, 0, sizeof(float) * n * (size_t)av->ncomp);
			continue;
		}
		const struct sl_program *prog = sl_exec_program(sx);
		int k = sl_program_find_param(prog, av->name);
		int32_t reg = k >= 0 ? prog->params[k].reg : -1;
		for (int gl = 0; reg < 0 && gl < SL_GLOBAL_COUNT; gl++)
			if (!strcmp(sl_global_name((enum sl_global)gl), av->name))
				reg = prog->global_reg[gl];
		if (reg < 0 || sl_reg_ncomp(&prog->regs[reg]) != av->ncomp) {
			memset(dst, 0, sizeof(float) * n * (size_t)av->ncomp);
			continue;
		}
		const float *d = sl_exec_reg(sx, reg);
		bool vary = prog->regs[reg].varying;
		uint32_t st = sl_exec_stride(sx);
		for (int cc = 0; cc < av->ncomp; cc++)
			for (uint32_t p = 0; p < n; p++)
				dst[(size_t)cc * n + p] = vary ? d[(size_t)cc * st + p] : d[cc];
	}
	for (uint32_t q = 0; q < r->naov_planes; q++)
		aovp[q] = aovbase + (size_t)q * n;
	sh->hg.nu = g.nu;
	sh->hg.nv = g.nv;
	sh->hg.x[0] = x0;
	sh->hg.y[0] = y0;
	sh->hg.z[0] = z0;
	sh->hg.x[1] = moving ? x1 : x0;
	sh->hg.y[1] = moving ? y1 : y0;
	sh->hg.z[1] = moving ? z1 : z0;
	sh->hg.Ci = bk ? NULL : ci;
	sh->hg.Oi = oi;
	sh->hg.aov = r->naov_planes && !bk ? aovp : NULL;
	sh->hg.smooth = a->smooth;
	sh->hg.cull_backfacing = a->sides == 1;
	sh->hg.flip = a->flip_normals;
	sh->hg.csg = prim->csg_leaf ? &r->scene->csg : NULL;
	sh->hg.csg_leaf = prim->csg_leaf;
	sh->hg.matte = a->matte;
	sh->hg.dissolve = a->dissolve;
	sh->hg.lod_lo = a->lod_lo;
	sh->hg.lod_hi = a->lod_hi;
	if (trim) {
		/* the hider tests each sample's (u, v) against the trim curve */
		float *uv = aovbase + (size_t)r->naov_planes * n;
		memcpy(uv, g.u, sizeof(float) * n);
		memcpy(uv + n, g.v, sizeof(float) * n);
		sh->hg.trim_uv = uv;
		sh->hg.trim = trim;
	}
	job->sh = sh;
	t->grids++;
	t->points += n;
done:
	free(buf);
	reyes_grid_finish(&g);
	return ok;
}

static void free_shaded(struct job *j)
{
	if (j->sh) {
		free(j->sh->mem);
		free(j->sh);
		j->sh = NULL;
	}
}

/* ---- threads ---- */

static void *shade_worker(void *arg)
{
	struct tctx *t = arg;
	struct render *r = t->r;
	for (;;) {
		size_t i = atomic_fetch_add(&r->next, 1);
		if (i >= r->ntodo || atomic_load(&r->failed))
			break;
		struct job *j = &r->jobs[r->todo[i]];
		if (!shade_job(t, j)) {
			atomic_store(&r->failed, true);
			fprintf(r->diag, "relight: error: shading failed (primitive %u)\n",
				j->piece.prim->id);
		}
	}
	return NULL;
}

static void hide_bucket(struct tctx *t, uint32_t bx)
{
	struct render *r = t->r;
	uint32_t x0 = r->px0 + bx * r->bucket, y0 = r->py0 + r->row * r->bucket;
	uint32_t x1 = x0 + r->bucket < r->px1 ? x0 + r->bucket : r->px1;
	uint32_t y1 = y0 + r->bucket < r->py1 ? y0 + r->bucket : r->py1;
	reyes_hider_begin(t->hider, x0, y0, x1, y1);
	float rx0, ry0, rx1, ry1;
	reyes_hider_region(t->hider, &rx0, &ry0, &rx1, &ry1);
	for (size_t k = 0; k < r->nactive; k++) {
		const struct job *j = &r->jobs[r->active[k]];
		if (j->bx1 < rx0 || j->bx0 > rx1 || j->by1 < ry0 || j->by0 > ry1)
			continue;
		reyes_hider_add(t->hider, &j->sh->hg);
	}
	uint32_t w = x1 - x0;
	const struct reyes_bake_hooks *bk = r->o->bake;
	if (bk) {
		const uint32_t *offsets;
		const struct reyes_vis_entry *entries;
		t->samples += reyes_hider_end_record(t->hider, &offsets, &entries, t->bucket_rgba,
						     t->bucket_z);
		if (!bk->bucket(bk->user, x0, y0, x1, y1, offsets, entries, t->bucket_rgba))
			atomic_store(&r->failed, true);
		return;
	}
	uint32_t W = (uint32_t)r->cam.xres;
	if (r->deep) {
		const struct reyes_options *so = &r->scene->opts;
		uint32_t ns = (so->xsamples ? so->xsamples : 1) * (so->ysamples ? so->ysamples : 1);
		for (uint32_t y = y0; y < y1; y++)
			for (uint32_t x = x0; x < x1; x++)
				if (!reyes_deep_build_pixel(t->hider, ns, x, y, r->deep_error, &t->deep,
							    &r->deep[(size_t)y * W + x]))
					atomic_store(&r->failed, true);
	}
	t->samples += reyes_hider_end(t->hider, t->bucket_rgba, t->bucket_z, t->bucket_aov);
	for (uint32_t y = y0; y < y1; y++) {
		memcpy(r->rgba + ((size_t)y * W + x0) * 4, t->bucket_rgba + (size_t)(y - y0) * w * 4,
		       sizeof(float) * 4 * w);
		memcpy(r->z + (size_t)y * W + x0, t->bucket_z + (size_t)(y - y0) * w,
		       sizeof(float) * w);
		if (r->naov_planes)
			memcpy(r->aov + ((size_t)y * W + x0) * r->naov_planes,
			       t->bucket_aov + (size_t)(y - y0) * w * r->naov_planes,
			       sizeof(float) * w * r->naov_planes);
	}
}

static void *hide_worker(void *arg)
{
	struct tctx *t = arg;
	struct render *r = t->r;
	for (;;) {
		size_t i = atomic_fetch_add(&r->next, 1);
		if (i >= r->nbx)
			break;
		hide_bucket(t, (uint32_t)i);
	}
	return NULL;
}

static void run_threads(struct render *r, void *(*fn)(void *))
{
	atomic_store(&r->next, 0);
	pthread_t th[64];
	uint32_t started = 0;
	for (uint32_t i = 1; i < r->nthreads; i++)
		if (pthread_create(&th[started], NULL, fn, &r->ctx[i]) == 0)
			started++;
	fn(&r->ctx[0]);
	for (uint32_t i = 0; i < started; i++)
		pthread_join(th[i], NULL);
}

/* ---- output ---- */

static void progress(const struct render *r, uint32_t done, uint32_t total, double t0)
{
	if (r->o->progress_fn)
		r->o->progress_fn(r->o->progress_user, total ? (double)done / total : 1.0);
	if (!r->o->progress)
		return;
	int width = 40;
	int fill = total ? (int)((uint64_t)done * (uint64_t)width / total) : width;
	fprintf(r->diag, "\r  [%.*s%*s] %3u%%  %.1fs", fill,
		"########################################", width - fill, "",
		total ? (unsigned)(100u * done / total) : 100u, now() - t0);
	if (done == total)
		fputc('\n', r->diag);
	fflush(r->diag);
}

static float expose(float c, float gain, float gamma)
{
	c *= gain;
	if (gamma != 1 && gamma > 0)
		c = c > 0 ? powf(c, 1 / gamma) : 0;
	return isfinite(c) ? c : 0;
}

static bool is_base_mode(const char *m, size_t n)
{
	static const char *const base[] = { "rgba", "rgb", "a", "z", "rgbaz" };
	for (size_t k = 0; k < sizeof(base) / sizeof(base[0]); k++)
		if (strlen(base[k]) == n && !strncmp(m, base[k], n))
			return true;
	return false;
}

static const struct aov *find_aov(const struct render *r, const char *name, size_t n)
{
	for (uint32_t q = 0; q < r->naov; q++)
		if (strlen(r->aovs[q].name) == n && !strncmp(r->aovs[q].name, name, n))
			return &r->aovs[q];
	return NULL;
}

/*
 * Channels of a display. The mode is a comma-separated list: rgba, rgb, a,
 * z, rgbaz, or output variables (AOVs). A display of a single AOV names its
 * channels R, G, B (Y for a float); with other channels beside it, an AOV's
 * channels are NAME.R, NAME.G, NAME.B (NAME for a float).
 */
static bool write_display(struct render *r, const struct reyes_display *d)
{
	const struct reyes_options *o = &r->scene->opts;
	uint32_t W = o->xres, H = o->yres;
	const char *names[64];
	char *owned[64];
	uint32_t nowned = 0;
	int src[64];           /* -1..-4: R G B A, -5: Z, >= 0: aov plane */
	uint32_t nch = 0;
	bool depth = reyes_display_is_depth(d);
	bool single = !strchr(d->mode, ',');
	if (!strcmp(d->type, "deepshad")) {
		float w2ndc[16];
		sl_m44_mul(w2ndc, r->cam.w2c, r->cam.c2ndc);
		return reyes_deep_write(d->name, W, H, r->deep, r->cam.w2c, w2ndc, r->diag);
	}
	if (depth) {
		names[nch] = "Z";
		src[nch++] = -5;
	}
	for (const char *m = d->mode; !depth && *m;) {
		const char *e = strchr(m, ',');
		size_t n = e ? (size_t)(e - m) : strlen(m);
		if (is_base_mode(m, n)) {
			static const char *const rgba[4] = { "R", "G", "B", "A" };
			/* rgba, rgb, a, z, rgbaz */
			bool has_rgb = n >= 3 && !strncmp(m, "rgb", 3);
			bool has_a = (n == 1 && m[0] == 'a') || (n >= 4 && !strncmp(m, "rgba", 4));
			for (int c = 0; c < 4 && nch < 60; c++) {
				if (c < 3 ? !has_rgb : !has_a)
					continue;
				names[nch] = rgba[c];
				src[nch++] = -1 - c;
			}
			if (m[n - 1] == 'z' && nch < 63) {
				names[nch] = "Z";
				src[nch++] = -5;
			}
		} else {
			const struct aov *av = find_aov(r, m, n);
			if (!av)
				return false;
			static const char *const rgb[3] = { "R", "G", "B" };
			for (int c = 0; c < av->ncomp && nch < 63; c++) {
				if (single) {
					names[nch] = av->ncomp == 1 ? "Y" : rgb[c];
				} else {
					size_t len = n + 3;
					char *nm = malloc(len);
					if (!nm)
						return false;
					if (av->ncomp == 1)
						snprintf(nm, len, "%.*s", (int)n, m);
					else
						snprintf(nm, len, "%.*s.%s", (int)n, m, rgb[c]);
					owned[nowned++] = nm;
					names[nch] = nm;
				}
				src[nch++] = (int)av->offset + c;
			}
		}
		m = e ? e + 1 : m + n;
	}
	struct reyes_image im;
	if (nch == 0 || !reyes_image_init(&im, W, H, nch, names)) {
		for (uint32_t k = 0; k < nowned; k++)
			free(owned[k]);
		return false;
	}
	for (size_t p = 0; p < (size_t)W * H; p++)
		for (uint32_t c = 0; c < nch; c++) {
			float v;
			if (src[c] == -5)
				v = r->z[p];
			else if (src[c] < 0 && src[c] >= -3)
				v = expose(r->rgba[p * 4 + (size_t)(-1 - src[c])], o->gain, o->gamma);
			else if (src[c] == -4)
				v = r->rgba[p * 4 + 3];
			else
				v = r->aov[p * r->naov_planes + (size_t)src[c]];
			im.data[p * nch + c] = isfinite(v) ? v : 0;
		}
	im.has_matrices = true;
	memcpy(im.world_to_camera, r->cam.w2c, sizeof(im.world_to_camera));
	sl_m44_mul(im.world_to_ndc, r->cam.w2c, r->cam.c2ndc);
	bool ok = d->png && !depth ? reyes_png_write_image(d->name, &im, r->diag)
				   : reyes_image_write_exr(d->name, &im, !depth && d->half, r->diag);
	reyes_image_finish(&im);
	for (uint32_t k = 0; k < nowned; k++)
		free(owned[k]);
	return ok;
}

/* Add the AOV @m (@n characters): an output parameter or global of the surface shaders. */
static bool add_aov(struct render *r, const struct reyes_display *d, const char *m, size_t n)
{
	char name[256];
	snprintf(name, sizeof(name), "%.*s", (int)n, m);
	int ncomp = 0;
	for (uint32_t p = 0; p < r->scene->nprims && !ncomp; p++) {
		const struct reyes_shader *s = r->scene->prims[p].attrs->surface;
		if (!s)
			continue;
		int k = sl_program_find_param(s->prog, name);
		if (k >= 0 && s->prog->params[k].output)
			ncomp = sl_type_ncomp(s->prog->params[k].type.base);
	}
	for (int gl = 0; gl < SL_GLOBAL_COUNT && !ncomp; gl++)
		if (!strcmp(sl_global_name((enum sl_global)gl), name))
			ncomp = sl_type_ncomp(sl_global_type((enum sl_global)gl).base);
	if (!ncomp || ncomp > 3) {
		fprintf(r->diag,
			"%s:%u: error: display \"%s\" asks for \"%s\", which no surface shader "
			"outputs\n",
			d->file ? d->file : "?", d->line, d->name, name);
		return false;
	}
	if (r->naov == r->capaov)
		r->aovs = rl_vec_grow_(r->aovs, &r->capaov, sizeof(*r->aovs), r->naov + 1);
	char *copy = malloc(n + 1);
	if (!copy)
		return false;
	memcpy(copy, m, n);
	copy[n] = '\0';
	r->aovs[r->naov].name = copy;
	r->aovs[r->naov].ncomp = ncomp;
	r->aovs[r->naov].offset = r->naov_planes;
	r->naov_planes += (uint32_t)ncomp;
	r->naov++;
	return true;
}

/* The AOVs the displays ask for: output parameters or globals of the surface shaders. */
static bool collect_aovs(struct render *r)
{
	const struct reyes_options *o = &r->scene->opts;
	for (uint32_t i = 0; i < o->ndisplays; i++) {
		const struct reyes_display *d = &o->displays[i];
		if (reyes_display_is_depth(d))
			continue;
		for (const char *m = d->mode; *m;) {
			const char *e = strchr(m, ',');
			size_t n = e ? (size_t)(e - m) : strlen(m);
			if (n && !is_base_mode(m, n) && !find_aov(r, m, n) && !add_aov(r, d, m, n))
				return false;
			m = e ? e + 1 : m + n;
		}
	}
	return true;
}

static bool load_default_surface(struct render *r)
{
	char path[4096];
	const char *dirs[2] = { r->scene->opts.shader_path, RELIGHT_SOURCE_SHADER_DIR };
	for (int k = 0; k < 2; k++) {
		const char *p = dirs[k];
		while (p && *p) {
			const char *e = strchr(p, ':');
			size_t len = e ? (size_t)(e - p) : strlen(p);
			snprintf(path, sizeof(path), "%.*s/defaultsurface.sl", (int)len, p);
			if (access(path, R_OK) == 0) {
				struct sl_options so = { .diag = r->diag };
				struct reyes_shader_cache *cache = r->o->shader_cache;
				struct sl_program *prog =
					cache ? reyes_shader_cache_compile(cache, path, &so)
					      : (r->default_prog = sl_compile_file(path, &so));
				if (prog) {
					r->default_surface.name = "defaultsurface";
					r->default_surface.prog = prog;
					sl_m44_identity(r->default_surface.shader_to_world);
					return true;
				}
			}
			p = e ? e + 1 : NULL;
		}
	}
	fprintf(r->diag, "relight: error: cannot find the default surface shader "
		"(defaultsurface.sl)\n");
	return false;
}

static uint64_t peak_rss(void)
{
	struct rusage ru;
	if (getrusage(RUSAGE_SELF, &ru) != 0)
		return 0;
	return (uint64_t)ru.ru_maxrss * 1024u;
}

bool reyes_scene_is_shadow_pass(const struct reyes_scene *scene)
{
	const struct reyes_options *so = &scene->opts;
	bool shadow_pass = so->ndisplays > 0;
	for (uint32_t i = 0; i < so->ndisplays; i++)
		if (!reyes_display_is_depth(&so->displays[i]))
			shadow_pass = false;
	return shadow_pass;
}

bool reyes_display_is_depth(const struct reyes_display *d)
{
	return !strcmp(d->type, "zfile") || !strcmp(d->type, "shadow") ||
	       !strcmp(d->type, "deepshad") || !strcmp(d->mode, "z");
}

/*
 * What the frame takes whatever is diced, against the limit: the images
 * (colour, depth, AOVs, and a copy to write a display), and each thread's
 * bucket of subpixel samples with its filter margin; a bake also keeps an
 * indirect-framebuffer entry per subpixel sample at least. False, with the
 * message naming Format and PixelSamples, when that alone is over. Sets up
 * the per-row counts predict_piece fills.
 */
static bool frame_fits(struct render *r, const struct reyes_hider_opts *ho)
{
	const struct reyes_options *so = &r->scene->opts;
	r->limit = r->o->memory_limit ? r->o->memory_limit : reyes_mem_default_limit();
	if (!r->limit)
		return true;
	double npix = (double)so->xres * so->yres;
	double nps = (double)ho->xsamples * ho->ysamples;
	double img = npix * (4 + 1 + r->naov_planes + 1) * sizeof(float);
	if (!r->o->bake)
		img += npix * 4 * sizeof(float);
	struct reyes_hider *probe = reyes_hider_create(ho);
	double per_sample = probe ? (double)reyes_hider_sample_bytes(probe) : 64;
	reyes_hider_destroy(probe);
	double side = r->bucket + 2.0 * ceil(r->margin);
	double buckets = r->nthreads * side * side * nps * per_sample;
	double ifb = 0;
	if (r->o->bake) {
		double w = (double)(r->px1 - r->px0), h = (double)(r->py1 - r->py0);
		ifb = w * h * nps * sizeof(struct reyes_vis_entry);
	}
	r->fixed_bytes = img + buckets + ifb;
	if (r->fixed_bytes > (double)r->limit) {
		char est[32], imgs[32], lim[32], smp[96] = "";
		if (so->samples_loc.file)
			snprintf(smp, sizeof(smp), " (%s:%u)", so->samples_loc.file,
				 so->samples_loc.line);
		loc_error(r, so->format_loc,
			  "Format %u %u with PixelSamples %u %u%s needs about %s (images %s), over "
			  "the memory limit of %s (--memory-limit): lower the Format or the "
			  "PixelSamples", so->xres, so->yres, ho->xsamples, ho->ysamples, smp,
			  reyes_mem_format(est, sizeof(est), (uint64_t)fmin(r->fixed_bytes, 1.8e19)),
			  reyes_mem_format(imgs, sizeof(imgs), (uint64_t)img),
			  reyes_mem_format(lim, sizeof(lim), r->limit));
		return false;
	}
	r->row_points = calloc(r->nby ? r->nby : 1, sizeof(*r->row_points));
	return true;
}

/* The warnings of every render of the process (reyes_render_warnings). */
static atomic_uint_fast64_t render_warnings;

uint64_t reyes_render_warnings(void)
{
	return (uint64_t)atomic_load(&render_warnings);
}

void reyes_render_warned(void)
{
	atomic_fetch_add(&render_warnings, 1);
}

/* Pieces that cross the eye plane where a surface passes through the eye
   cannot be projected: they are left out, and said so. */
static void eye_plane_warning(struct render *r)
{
	fprintf(r->diag, "relight: warning: %llu pieces crossing the eye plane were dropped\n",
		(unsigned long long)r->dropped);
	atomic_fetch_add(&render_warnings, 1);
}

bool reyes_render(const struct reyes_scene *scene, const struct reyes_render_opts *opts,
		  struct reyes_stats *stats)
{
	double t0 = now();
	struct render r = { 0 };
	r.scene = scene;
	pthread_mutex_init(&r.rt_lock, NULL);
	r.o = opts;
	r.diag = opts->diag ? opts->diag : stderr;
	const struct reyes_options *so = &scene->opts;
	if (so->xres == 0 || so->yres == 0 || so->xres > 32768 || so->yres > 32768) {
		loc_error(&r, so->format_loc, "image size %ux%u is out of range", so->xres,
			  so->yres);
		return false;
	}
	setup_camera(&r.cam, so);
	/* pixels to render: the crop window */
	if (opts->crop_x1 > opts->crop_x0 && opts->crop_y1 > opts->crop_y0) {
		r.px0 = opts->crop_x0 < so->xres ? opts->crop_x0 : so->xres;
		r.px1 = opts->crop_x1 < so->xres ? opts->crop_x1 : so->xres;
		r.py0 = opts->crop_y0 < so->yres ? opts->crop_y0 : so->yres;
		r.py1 = opts->crop_y1 < so->yres ? opts->crop_y1 : so->yres;
	} else {
		r.px0 = (uint32_t)ceilf(so->crop[0] * (float)so->xres - 0.5f);
		r.px1 = (uint32_t)ceilf(so->crop[1] * (float)so->xres - 0.5f);
		r.py0 = (uint32_t)ceilf(so->crop[2] * (float)so->yres - 0.5f);
		r.py1 = (uint32_t)ceilf(so->crop[3] * (float)so->yres - 0.5f);
		if (r.px1 > so->xres)
			r.px1 = so->xres;
		if (r.py1 > so->yres)
			r.py1 = so->yres;
	}
	if (r.px1 <= r.px0 || r.py1 <= r.py0) {
		loc_error(&r, so->crop_loc, "the crop window is empty");
		return false;
	}
	r.margin = fmaxf(so->filter_width[0], so->filter_width[1]) * 0.5f + 1;
	r.bucket = opts->bucket_size ? opts->bucket_size : 16;
	r.nbx = (r.px1 - r.px0 + r.bucket - 1) / r.bucket;
	r.nby = (r.py1 - r.py0 + r.bucket - 1) / r.bucket;
	r.max_points = opts->max_grid ? opts->max_grid : 1024;
	long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
	r.nthreads = opts->threads ? opts->threads : (uint32_t)(ncpu > 0 ? ncpu : 1);
	if (r.nthreads > 64)
		r.nthreads = 64;

	bool ok = collect_aovs(&r) && load_default_surface(&r);
	float c2w[16];
	sl_m44_inverse(c2w, r.cam.w2c);
	if (ok)
		r.tex = reyes_texsys_create(opts->texture_path ? opts->texture_path
							       : so->texture_path,
					    c2w, r.diag);
	r.light_mats = calloc(scene->nlights + 1, sizeof(*r.light_mats));
	for (uint32_t i = 0; i < scene->nlights; i++)
		sl_m44_mul(r.light_mats[i], scene->lights[i].shader.shader_to_world, r.cam.w2c);

	/*
	 * A frame whose displays are all depth maps is a shadow pass: objects
	 * that cast no shadows (Attribute "visibility" "transmission" 0) stay
	 * out of it.
	 */
	bool shadow_pass = reyes_scene_is_shadow_pass(scene);

	struct reyes_hider_opts ho = {
		.xres = so->xres, .yres = so->yres,
		.xsamples = so->xsamples ? so->xsamples : 1, .ysamples = so->ysamples ? so->ysamples : 1,
		.filter = so->filter, .filter_width = { so->filter_width[0], so->filter_width[1] },
		.jitter = so->jitter, .seed = 1,
		.opacity_threshold = so->opacity_threshold > 0 ? so->opacity_threshold : 0.996f,
		.depthfilter = so->depthfilter, .naov = opts->bake ? 0 : r.naov_planes,
		.lens = { r.cam.lens[0], r.cam.lens[1] }, .focus = r.cam.focus,
		.record = opts->bake != NULL,
	};
	if (ok)
		ok = frame_fits(&r, &ho);

	/* pieces -> jobs */
	struct reyes_patch *pieces = NULL;
	size_t np = 0, capp = 0;
	for (uint32_t p = 0; ok && p < scene->nprims; p++) {
		if (shadow_pass ? !scene->prims[p].attrs->casts_shadows
				: !scene->prims[p].attrs->ray.camera)
			continue;
		np = 0;
		if (!reyes_prim_pieces(&scene->prims[p], &pieces, &np, &capp))
			continue;
		for (size_t k = 0; k < np; k++)
			reyes_split_piece(&r, &pieces[k]);
	}
	free(pieces);
	if (atomic_load(&r.failed))
		ok = false;
	free(r.row_points);
	r.row_points = NULL;
	if (r.dropped)
		eye_plane_warning(&r);

	/* images and threads */
	size_t npix = (size_t)so->xres * so->yres;
	r.rgba = ok ? calloc(npix * 4, sizeof(float)) : NULL;
	r.z = ok ? malloc(npix * sizeof(float)) : NULL;
	r.aov = ok ? calloc(npix * (r.naov_planes + 1), sizeof(float)) : NULL;
	if (ok && (!r.rgba || !r.z || !r.aov)) {
		loc_error(&r, so->format_loc, "out of memory for a %ux%u image", so->xres,
			  so->yres);
		ok = false;
	}
	if (r.z)
		for (size_t i = 0; i < npix; i++)
			r.z[i] = 1e30f;
	r.deep_error = -1.0f;
	for (uint32_t i = 0; i < so->ndisplays; i++)
		if (!strcmp(so->displays[i].type, "deepshad") && !opts->bake &&
		    (r.deep_error < 0.0f || so->displays[i].deep_error < r.deep_error))
			r.deep_error = so->displays[i].deep_error;
	if (ok && r.deep_error >= 0.0f && !(r.deep = calloc(npix, sizeof(*r.deep)))) {
		loc_error(&r, so->format_loc, "out of memory for a %ux%u deep shadow map",
			  so->xres, so->yres);
		ok = false;
	}
	r.ctx = calloc(r.nthreads, sizeof(*r.ctx));
	for (uint32_t i = 0; ok && i < r.nthreads; i++) {
		struct tctx *t = &r.ctx[i];
		t->r = &r;
		t->hider = reyes_hider_create(&ho);
		t->light_x = calloc(scene->nlights + 1, sizeof(*t->light_x));
		t->lights_on = calloc(scene->nlights + 1, sizeof(*t->lights_on));
		t->light_mats = calloc(scene->nlights + 1, sizeof(*t->light_mats));
		size_t bp = (size_t)r.bucket * r.bucket;
		t->bucket_rgba = malloc(bp * 4 * sizeof(float));
		t->bucket_z = malloc(bp * sizeof(float));
		t->bucket_aov = malloc(bp * (r.naov_planes + 1) * sizeof(float));
		if (!t->hider || !t->bucket_rgba || !t->bucket_z || !t->bucket_aov)
			ok = false;
	}

	/* bucket rows */
	r.todo = malloc(sizeof(size_t) * (r.njobs + 1));
	r.active = malloc(sizeof(size_t) * (r.njobs + 1));
	if (!r.todo || !r.active)
		ok = false;
	for (r.row = 0; ok && r.row < r.nby; r.row++) {
		r.ntodo = 0;
		for (size_t i = 0; i < r.njobs; i++)
			if (r.jobs[i].row0 == r.row)
				r.todo[r.ntodo++] = i;
		run_threads(&r, shade_worker);
		if (atomic_load(&r.failed)) {
			ok = false;
			break;
		}
		r.nactive = 0;
		for (size_t i = 0; i < r.njobs; i++)
			if (r.jobs[i].sh && r.jobs[i].row0 <= r.row && r.jobs[i].row1 >= r.row)
				r.active[r.nactive++] = i;
		run_threads(&r, hide_worker);
		if (atomic_load(&r.failed)) {
			ok = false;
			break;
		}
		for (size_t i = 0; i < r.njobs; i++)
			if (r.jobs[i].row1 <= r.row)
				free_shaded(&r.jobs[i]);
		progress(&r, r.row + 1, r.nby, t0);
	}

	uint64_t grids = 0, points = 0, samples = 0, rays = 0;
	for (uint32_t i = 0; r.ctx && i < r.nthreads; i++) {
		struct tctx *t = &r.ctx[i];
		grids += t->grids;
		points += t->points;
		samples += t->samples;
		for (const struct tctx *s = t; s; s = s->sub)
			rays += s->rays;
	}
	/* the imager sees the filtered pixels; exposure comes after it */
	if (ok && !opts->bake && so->imager && !reyes_scene_is_shadow_pass(scene)) {
		struct reyes_imager_frame fr = { so->shutter[0], so->shutter[1] - so->shutter[0] };
		ok = reyes_imager_apply(so->imager, r.rgba, so->xres, so->yres, &fr, r.tex, r.diag);
	}
	/* displays */
	for (uint32_t i = 0; ok && !opts->bake && i < so->ndisplays; i++)
		if (!write_display(&r, &so->displays[i]))
			ok = false;

	if (stats) {
		stats->seconds = now() - t0;
		stats->grids = grids;
		stats->micropolygons = points;
		stats->samples = samples;
		stats->rays = rays;
		stats->ray_bytes = reyes_rt_bytes(r.rt);
		stats->peak_bytes = peak_rss();
		stats->width = so->xres;
		stats->height = so->yres;
	}

	for (size_t i = 0; i < r.njobs; i++)
		free_shaded(&r.jobs[i]);
	for (uint32_t i = 0; r.ctx && i < r.nthreads; i++) {
		struct tctx *t = &r.ctx[i];
		reyes_rt_free_sub(t);
		reyes_hider_destroy(t->hider);
		for (size_t k = 0; k < t->nexecs; k++)
			sl_exec_destroy(t->execs[k].x);
		free(t->execs);
		for (uint32_t k = 0; t->light_x && k < scene->nlights; k++)
			sl_exec_destroy(t->light_x[k]);
		free(t->light_x);
		free(t->lights_on);
		free(t->light_mats);
		free(t->bucket_rgba);
		free(t->bucket_z);
		free(t->bucket_aov);
		reyes_deep_scratch_finish(&t->deep);
	}
	for (size_t i = 0; r.deep && i < npix; i++)
		free(r.deep[i].zt);
	free(r.deep);
	free(r.ctx);
	reyes_rt_destroy(r.rt);
	pthread_mutex_destroy(&r.rt_lock);
	free(r.todo);
	free(r.active);
	free(r.jobs);
	for (uint32_t q = 0; q < r.naov; q++)
		free((char *)r.aovs[q].name);
	free(r.aovs);
	free(r.light_mats);
	free(r.rgba);
	free(r.z);
	free(r.aov);
	reyes_texsys_destroy(r.tex);
	sl_program_destroy(r.default_prog);
	return ok;
}

/*
 * A trimmed NuPatch's micropolygons whose centre (u, v) the trim curve
 * keeps, 1 per kept micropolygon, into *keep (NULL when not trimmed).
 * False when memory runs out.
 */
bool reyes_trim_keep(const struct reyes_prim *prim, const struct reyes_grid *g, uint8_t **keep)
{
	const struct reyes_trim *trim = prim->nurbs ? prim->nurbs->trim : NULL;
	uint32_t nu = g->nu, nv = g->nv;
	*keep = NULL;
	if (!trim || nu < 2 || nv < 2)
		return true;
	*keep = malloc((size_t)(nu - 1) * (nv - 1));
	if (!*keep)
		return false;
	for (uint32_t j = 0; j + 1 < nv; j++)
		for (uint32_t i = 0; i + 1 < nu; i++) {
			uint32_t k = j * nu + i;
			float u = 0.25f * (g->u[k] + g->u[k + 1] + g->u[k + nu] + g->u[k + nu + 1]);
			float v = 0.25f * (g->v[k] + g->v[k + 1] + g->v[k + nu] + g->v[k + nu + 1]);
			(*keep)[j * (nu - 1) + i] = reyes_trim_keeps(trim, u, v);
		}
	return true;
}

bool reyes_dice(const struct reyes_scene *scene, const struct reyes_dice_opts *opts)
{
	struct render r = { 0 };
	struct reyes_render_opts ro = { 0 };
	r.diag = opts && opts->diag ? opts->diag : stderr;
	if (!scene || !opts || !opts->grid) {
		fprintf(r.diag, "relight: error: dicing needs a scene and a grid callback\n");
		return false;
	}
	if (!(opts->rate >= 0) || !isfinite(opts->rate)) {
		fprintf(r.diag, "relight: error: dicing rate %g is not a non-negative number\n",
			(double)opts->rate);
		return false;
	}
	const struct reyes_options *so = &scene->opts;
	if (so->xres == 0 || so->yres == 0 || so->xres > 32768 || so->yres > 32768) {
		loc_error(&r, so->format_loc, "image size %ux%u is out of range", so->xres,
			  so->yres);
		return false;
	}
	r.scene = scene;
	r.rt_tried = true;          /* dicing alone casts no rays */
	ro.diag = r.diag;
	ro.texture_path = opts->texture_path;
	r.o = &ro;
	setup_camera(&r.cam, so);
	float sw = r.cam.screen[1] - r.cam.screen[0], sh = r.cam.screen[3] - r.cam.screen[2];
	if (!(fabsf(sw) > 0) || !(fabsf(sh) > 0) || !isfinite(sw) || !isfinite(sh)) {
		fprintf(r.diag, "relight: error: the screen window [%g %g %g %g] is empty\n",
			(double)r.cam.screen[0], (double)r.cam.screen[1], (double)r.cam.screen[2],
			(double)r.cam.screen[3]);
		return false;
	}
	/* the view is the whole frame: a crop window is a rendering matter */
	r.px1 = so->xres;
	r.py1 = so->yres;
	r.margin = fmaxf(so->filter_width[0], so->filter_width[1]) * 0.5f + 1;
	r.bucket = 16;
	r.nbx = (r.px1 + r.bucket - 1) / r.bucket;
	r.nby = (r.py1 + r.bucket - 1) / r.bucket;
	r.max_points = opts->max_grid ? opts->max_grid : 1024;
	r.nthreads = 1;
	r.keep_unseen = !opts->cull_to_view;
	r.orient_free = opts->orient_free && r.keep_unseen;
	r.rate = opts->rate;
	r.tex = reyes_texsys_create(opts->texture_path ? opts->texture_path : so->texture_path,
				    r.cam.c2w, r.diag);
	struct tctx t = { .r = &r };
	struct reyes_patch *pieces = NULL;
	size_t np = 0, capp = 0;
	bool ok = r.tex != NULL;
	if (!ok)
		fprintf(r.diag, "relight: error: out of memory\n");
	for (uint32_t p = 0; ok && p < scene->nprims; p++) {
		const struct reyes_prim *prim = &scene->prims[p];
		if (opts->casters_only && !prim->attrs->casts_shadows)
			continue;
		np = 0;
		if (!reyes_prim_pieces(prim, &pieces, &np, &capp))
			continue;
		/* one primitive at a time: the jobs never outgrow its pieces */
		r.njobs = 0;
		for (size_t k = 0; k < np; k++)
			reyes_split_piece(&r, &pieces[k]);
		if (atomic_load(&r.failed)) {
			fprintf(r.diag, "relight: error: out of memory dicing primitive %u\n",
				prim->id);
			ok = false;
		}
		for (size_t i = 0; ok && i < r.njobs; i++) {
			struct reyes_grid g = { 0 };
			struct cgrid c;
			if (!reyes_dice_job(&t, &r.jobs[i], &g, &c)) {
				fprintf(r.diag, "relight: error: dicing or displacement failed "
					"(primitive %u)\n", prim->id);
				ok = false;
				break;
			}
			uint8_t *keep;
			if (!reyes_trim_keep(prim, &g, &keep)) {
				fprintf(r.diag, "relight: error: out of memory dicing primitive %u\n",
					prim->id);
				ok = false;
			}
			ok = ok && opts->grid(opts->user, prim, c.P0, c.nu, c.nv, keep, c.Os);
			free(keep);
			free(c.P0);
			reyes_grid_finish(&g);
		}
	}
	free(pieces);
	if (r.dropped)
		eye_plane_warning(&r);
	for (size_t k = 0; k < t.nexecs; k++)
		sl_exec_destroy(t.execs[k].x);
	free(t.execs);
	free(r.jobs);
	reyes_texsys_destroy(r.tex);
	return ok;
}

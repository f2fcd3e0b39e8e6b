/*
 * Level of detail and the attributes of how geometry is seen: Detail,
 * RelativeDetail and DetailRange (which representation of an object
 * renders, with RISpec's cross-fades), TextureCoordinates, Matte,
 * GeometricApproximation and GeometricRepresentation.
 *
 * Detail is measured where it is given: the raster area of the bound's
 * projection (the rectangle around the box clipped to the near plane, not
 * to the screen), times RelativeDetail. DetailRange turns it into the
 * representation's importance, 0 outside [minvisible, maxvisible], rising
 * linearly to 1 over [minvisible, lowertransition], 1 up to
 * uppertransition, falling linearly to 0 at maxvisible. An importance f
 * below 1 is a dissolve, a stochastic cross-fade: on the rising side the
 * subpixel samples whose dissolve number is in [1 - f, 1) see the
 * primitive, on the falling side those in [0, f), so the representation
 * fading out and the one fading in over the same detail share the samples
 * without overlap and blend in exactly the proportion f.
 */
#include "ri_impl.h"

#include "mathlib.h"

#include <float.h>
#include <math.h>

#define PI_D 3.14159265358979323846
#define DETAIL_INFINITE 1e30f   /* a maxvisible this large has no upper limit */

void reyes_ri_detail_init(struct attrstate *a)
{
	static const float st[8] = {0, 0, 1, 0, 0, 1, 1, 1};
	memcpy(a->texcoords, st, sizeof(st));
	a->has_texcoords = false;
	a->matte = false;
	a->detail = -1;
	a->has_detail_range = false;
}

bool reyes_ri_detail_visible(const struct attrstate *a, float *lo, float *hi)
{
	*lo = 0;
	*hi = 1;
	if (!a->has_detail_range || a->detail < 0)
		return true;
	const float *dr = a->detail_range;
	float d = a->detail;
	bool unbounded = dr[3] >= DETAIL_INFINITE;
	if (d < dr[0] || (d > dr[3] && !unbounded))
		return false;
	/* 1 - f on the rising side, computed as f is on the falling side of the
	   range that fades out over the same interval: bit for bit the same
	   bound, so the two representations share the samples exactly. */
	if (d < dr[1]) {
		*lo = (dr[1] - d) / (dr[1] - dr[0]);
		return *lo < 1;
	}
	if (d > dr[2] && !unbounded) {
		*hi = (dr[3] - d) / (dr[3] - dr[2]);
		return *hi > 0;
	}
	return true;
}

void reyes_ri_req_texture_coordinates(struct ri *ri, const struct rib_request *r)
{
	static const float dflt[8] = {0, 0, 1, 0, 0, 1, 1, 1};
	float tc[8];
	if (!reyes_ri_float_args(ri, r, 0, 8, tc))
		return;
	memcpy(ri->gs.a.texcoords, tc, sizeof(tc));
	ri->gs.a.has_texcoords = memcmp(tc, dflt, sizeof(tc)) != 0;
	ri->gs.a.objset |= OBJ_TEXCOORDS;
	ri->gs.bundle = NULL;
}

void reyes_ri_req_matte(struct ri *ri, const struct rib_request *r)
{
	double on;
	if (!reyes_ri_num_arg(ri, r, 0, &on))
		return;
	ri->gs.a.matte = on != 0;
	ri->gs.a.objset |= OBJ_MATTE;
	ri->gs.bundle = NULL;
}

/* The screen window the frame will have (as the scene builder completes it). */
static void screen_window(const struct reyes_options *o, float w[4])
{
	if (o->screen_set) {
		memcpy(w, o->screen, sizeof(float) * 4);
		return;
	}
	float fa = o->frame_aspect > 0 ? o->frame_aspect
				       : (float)o->xres * o->pixel_aspect / (float)o->yres;
	float s[4] = {-fa, fa, -1, 1}, t[4] = {-1, 1, -1 / fa, 1 / fa};
	memcpy(w, fa >= 1 ? s : t, sizeof(s));
}

/* Raster x, y of camera-space point @c (in front of the eye when perspective). */
static void to_raster(const struct reyes_options *o, const float win[4], double d,
		      const double c[3], double *rx, double *ry)
{
	double sx = c[0], sy = c[1];
	if (o->perspective) {
		sx = d * c[0] / c[2];
		sy = d * c[1] / c[2];
	}
	*rx = (sx - win[0]) / (win[1] - win[0]) * o->xres;
	*ry = (win[3] - sy) / (win[3] - win[2]) * o->yres;
}

/*
 * RISpec's detail of bound @b (xmin xmax ymin ymax zmin zmax in the space @m
 * takes to camera space): the raster area of the rectangle around the
 * projection of the box clipped to the near plane (not to the screen, so
 * that the detail grows smoothly as the camera closes in; nor to the far
 * plane). The clipped box's corners are the box's corners in front of the
 * plane and the points where its edges cross it. 0 when none of it is in
 * front of the near plane.
 */
float reyes_ri_raster_area(const struct reyes_options *o, const float m[16], const float b[6])
{
	float win[4];
	screen_window(o, win);
	double d = o->perspective ? 1 / tan(o->fov * (PI_D / 360)) : 1;
	double near = o->perspective ? fmax(o->clip_near, 1e-10) : -INFINITY;
	double c[8][3];
	for (int k = 0; k < 8; k++) {
		float p[3] = {b[k & 1], b[2 + (k >> 1 & 1)], b[4 + (k >> 2)]}, q[3];
		sl_xform_point(q, m, p);
		for (int a = 0; a < 3; a++)
			c[k][a] = q[a];
	}
	double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
	int n = 0;
	for (int k = 0; k < 8; k++) {
		double pts[4][3];
		int np = 0;
		if (c[k][2] >= near)
			memcpy(pts[np++], c[k], sizeof(pts[0]));
		/* the edges from corner k to the corners that differ in one bit above it */
		for (int bit = 1; bit < 8; bit <<= 1) {
			if (k & bit)
				continue;
			const double *e0 = c[k], *e1 = c[k | bit];
			if ((e0[2] < near) == (e1[2] < near))
				continue;
			double t = (near - e0[2]) / (e1[2] - e0[2]);
			for (int a = 0; a < 3; a++)
				pts[np][a] = e0[a] + t * (e1[a] - e0[a]);
			pts[np++][2] = near;
		}
		for (int i = 0; i < np; i++, n++) {
			double rx, ry;
			to_raster(o, win, d, pts[i], &rx, &ry);
			x0 = fmin(x0, rx);
			x1 = fmax(x1, rx);
			y0 = fmin(y0, ry);
			y1 = fmax(y1, ry);
		}
	}
	if (!n)
		return 0;
	double area = (x1 - x0) * (y1 - y0);
	return isfinite(area) && area < FLT_MAX ? (float)area : INFINITY;
}

/* Detail [xmin xmax ymin ymax zmin zmax] */
void reyes_ri_req_detail(struct ri *ri, const struct rib_request *r)
{
	float b[6];
	if (!reyes_ri_float_args(ri, r, 0, 6, b))
		return;
	for (int k = 0; k < 3; k++)
		if (!(b[2 * k] <= b[2 * k + 1]))
			FAIL(ri, r->loc, "Detail: the bound's minimum %g is above its maximum %g",
			     (double)b[2 * k], (double)b[2 * k + 1]);
	if (!ri->world) {
		reyes_ri_warn(ri, r->loc,
			      "Detail outside WorldBegin/WorldEnd is ignored: there is no camera "
			      "to measure it with yet");
		return;
	}
	if (ri->objdef >= 0)
		reyes_ri_warn(ri, r->loc,
			      "Detail inside an object definition is measured where the object "
			      "is defined, not at each ObjectInstance");
	float m[16];
	sl_m44_mul(m, ri->gs.x.m[0], ri->opt.o.world_to_camera);
	float area = reyes_ri_raster_area(&ri->opt.o, m, b) * ri->opt.relative_detail;
	ri->gs.a.detail = isfinite(area) ? area : INFINITY;
	ri->gs.a.objset |= OBJ_DETAIL;
	ri->gs.bundle = NULL;
}

/* RelativeDetail relativedetail */
void reyes_ri_req_relative_detail(struct ri *ri, const struct rib_request *r)
{
	float v;
	if (!reyes_ri_float_args(ri, r, 0, 1, &v))
		return;
	if (ri->world)
		FAIL(ri, r->loc, "RelativeDetail is an option: it must come before WorldBegin");
	if (!(v > 0))
		FAIL(ri, r->loc, "RelativeDetail must be positive, got %g", (double)v);
	ri->opt.relative_detail = v;
}

/* DetailRange minvisible lowertransition uppertransition maxvisible */
void reyes_ri_req_detail_range(struct ri *ri, const struct rib_request *r)
{
	float dr[4];
	if (!reyes_ri_float_args(ri, r, 0, 4, dr))
		return;
	if (!(dr[0] <= dr[1] && dr[1] <= dr[2] && dr[2] <= dr[3]))
		FAIL(ri, r->loc,
		     "DetailRange needs minvisible <= lowertransition <= uppertransition <= "
		     "maxvisible, got %g %g %g %g",
		     (double)dr[0], (double)dr[1], (double)dr[2], (double)dr[3]);
	if (ri->gs.a.detail < 0 && ri->objdef < 0)
		reyes_ri_warn(ri, r->loc,
			      "DetailRange without a Detail bound: the representation renders "
			      "whatever its detail");
	memcpy(ri->gs.a.detail_range, dr, sizeof(dr));
	ri->gs.a.has_detail_range = true;
	ri->gs.a.objset |= OBJ_DETAIL_RANGE;
	ri->gs.bundle = NULL;
}

/*
 * GeometricApproximation "flatness" V | "motionfactor" V. The tessellation
 * is set by ShadingRate alone: micropolygons of that many pixels' area,
 * which at the usual rates deviate from the true surface by far less than
 * any useful flatness. Motion factor (prman's coarser shading of fast motion) is a saving
 * this renderer does not make; the image is the one without it.
 */
void reyes_ri_req_geometric_approximation(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	double v;
	if (!reyes_ri_str_arg(ri, r, 0, &type) || !reyes_ri_num_arg(ri, r, 1, &v))
		return;
	if (strcmp(type, "flatness") != 0 && strcmp(type, "motionfactor") != 0) {
		reyes_ri_warn(ri, r->loc,
			      "GeometricApproximation \"%s\" is not supported: ignored (known: "
			      "\"flatness\", \"motionfactor\")",
			      type);
		return;
	}
	if (!(v >= 0))
		FAIL(ri, r->loc, "GeometricApproximation \"%s\" must not be negative, got %g",
		     type, v);
}

/*
 * GeometricRepresentation "primitive" is how everything renders; "points",
 * "lines" and the others (prman's wireframe and point renders) are not
 * done here: the primitives still render as surfaces, and that is said.
 */
void reyes_ri_req_geometric_representation(struct ri *ri, const struct rib_request *r)
{
	const char *type;
	if (!reyes_ri_str_arg(ri, r, 0, &type))
		return;
	if (strcmp(type, "primitive") != 0)
		reyes_ri_warn(ri, r->loc,
			      "GeometricRepresentation \"%s\" is not supported: the primitives "
			      "that follow render as surfaces",
			      type);
}

/*
 * Is @b (xmin xmax ymin ymax zmin zmax in the current object space) outside
 * what the camera sees, at shutter open and close alike? It is when all its
 * corners, at both times, lie beyond one plane of the viewing volume: the
 * near or far clipping plane, or a side of the screen window widened by the
 * pixel filter's reach and a margin of 8 pixels. Depth of field and a
 * moving camera see more than the window: nothing is outside then, nor
 * before the camera is known (outside a world).
 */
bool reyes_ri_bound_unseen(struct ri *ri, const float b[6])
{
	const struct reyes_options *o = &ri->opt.o;
	if (!ri->world || o->fstop > 0 || o->camera_moving)
		return false;
	float win[4];
	screen_window(o, win);
	double mx = (8 + o->filter_width[0]) * (win[1] - win[0]) / o->xres;
	double my = (8 + o->filter_width[1]) * (win[3] - win[2]) / o->yres;
	double w[4] = {win[0] - mx, win[1] + mx, win[2] - my, win[3] + my};
	double d = o->perspective ? 1 / tan(o->fov * (PI_D / 360)) : 1;
	/* outside[plane]: every corner so far is beyond it */
	bool outside[6] = {true, true, true, true, true, true};
	for (int t = 0; t < 2; t++) {
		float m[16];
		sl_m44_mul(m, ri->gs.x.m[t], o->world_to_camera);
		for (int k = 0; k < 8; k++) {
			float p[3] = {b[k & 1], b[2 + (k >> 1 & 1)], b[4 + (k >> 2)]}, q[3];
			sl_xform_point(q, m, p);
			double x = d * q[0], y = d * q[1], z = o->perspective ? q[2] : 1;
			outside[0] &= x < w[0] * z;
			outside[1] &= x > w[1] * z;
			outside[2] &= y < w[2] * z;
			outside[3] &= y > w[3] * z;
			outside[4] &= q[2] < o->clip_near;
			outside[5] &= q[2] > o->clip_far;
		}
	}
	for (int k = 0; k < 6; k++)
		if (outside[k])
			return true;
	return false;
}

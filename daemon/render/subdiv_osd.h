/*
 * A small C interface to OpenSubdiv: a Catmull-Clark mesh's topology (faces,
 * creases, corners, holes, boundary rules, face-varying channels) in, limit
 * surface evaluation per base face out (Bfr). The only C++ in relight sits
 * behind this header (subdiv_osd.cpp).
 *
 * A face's parameters: a quad is one (u, v) square with (0, 0) at its first
 * vertex and (1, 0) at its second; any other face is cut into one quad
 * sub-face per corner, sub-face k having (0, 0) at corner k, (1, 0) halfway
 * to corner k + 1, (1, 1) at the face's centre and (0, 1) halfway to corner
 * k - 1 (OpenSubdiv's normalized sub-face coordinates).
 */
#ifndef RELIGHT_SUBDIV_OSD_H
#define RELIGHT_SUBDIV_OSD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Vertex boundary rules: interpolateboundary 0, 1, 2 as prman (RenderMan) has them. */
enum osd_boundary { OSD_BOUNDARY_NONE, OSD_BOUNDARY_EDGE_AND_CORNER, OSD_BOUNDARY_EDGE_ONLY };

struct osd_topology {
	uint32_t npoints;                /* control points */
	uint32_t nfaces;
	const uint32_t *face_sizes;      /* vertices per face (>= 3) */
	const uint32_t *face_verts;      /* their indices, face after face */
	uint32_t ncreases;               /* crease edges: vertex pairs and sharpness */
	const uint32_t *crease_verts;    /* 2 * ncreases */
	const float *crease_sharp;
	uint32_t ncorners;
	const uint32_t *corner_verts;
	const float *corner_sharp;
	uint32_t nholes;
	const uint32_t *holes;           /* face indices */
	enum osd_boundary boundary;
	int fvar_boundary;               /* facevaryinginterpolateboundary 0..3 */
	/* Face-varying channels: per face corner, an index into the channel's values. */
	uint32_t nchannels;
	const uint32_t *const *channel_index;
	const uint32_t *channel_nvalues;
};

struct osd_mesh;

/* The mesh of @t, or NULL with a reason in @err (invalid topology, no memory). */
struct osd_mesh *osd_mesh_create(const struct osd_topology *t, char *err, size_t errlen);
void osd_mesh_destroy(struct osd_mesh *m);

/* Is face @f a hole (or part of no limit surface: a face next to nothing smooth)? */
bool osd_face_hole(const struct osd_mesh *m, uint32_t f);

/* What data a face's surface interpolates. */
enum osd_data { OSD_VERTEX, OSD_VARYING, OSD_FACEVARYING };

/*
 * Evaluate face @f's limit surface of @data (channel @channel for
 * face-varying data) at @n points: sub-face @sub (0 for a quad) at
 * normalized (u, v) = uv[2k], uv[2k + 1]. @vals holds the mesh's items of
 * @dim floats each (control points, or the channel's values); out holds n
 * items of dim doubles (position), du and dv (may be NULL) their
 * derivatives with respect to the sub-face's u and v. False if the face has
 * no surface (a hole) or memory runs out.
 */
bool osd_eval(const struct osd_mesh *m, uint32_t f, uint32_t sub, enum osd_data data,
	      uint32_t channel, const float *vals, uint32_t dim, uint32_t n, const double *uv,
	      double *out, double *du, double *dv);

/*
 * The bound of the control points that face @f's vertex surface depends on
 * (its limit lies in their hull), from points @P (3 floats each). False for
 * a hole.
 */
bool osd_face_hull(const struct osd_mesh *m, uint32_t f, const float *P, double lo[3],
		   double hi[3]);

#ifdef __cplusplus
}
#endif

#endif

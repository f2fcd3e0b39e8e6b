/*
 * The C interface of subdiv_osd.h over OpenSubdiv: a Far::TopologyRefiner
 * from the topology, a Bfr surface factory over it, and per face limit
 * evaluation. Nothing here throws across the C boundary: allocation failures
 * end as a NULL mesh or a false evaluation.
 *
 * The factory is built without its internal cache, so that it is read-only
 * once made and the renderer's threads can evaluate faces at once; each
 * evaluation builds its face's Surface (small: the face's neighbourhood).
 */
#include "subdiv_osd.h"

#include <opensubdiv/bfr/refinerSurfaceFactory.h>
#include <opensubdiv/bfr/surface.h>
#include <opensubdiv/far/error.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>

#include <cstdio>
#include <cstring>
#include <mutex>
#include <new>
#include <vector>

using namespace OpenSubdiv;

struct osd_mesh {
	Far::TopologyRefiner *refiner = nullptr;
	Bfr::RefinerSurfaceFactory<> *factory = nullptr;
	uint32_t nfaces = 0;
	uint32_t nchannels = 0;
	std::vector<int> fvar_ids;
};

/* Far reports topology errors through a process-wide callback. */
static std::mutex far_lock;
static char far_message[256];

static void far_error(Far::ErrorType, const char *message)
{
	if (!far_message[0])
		std::snprintf(far_message, sizeof(far_message), "%s", message ? message : "");
}

static Sdc::Options::FVarLinearInterpolation fvar_rule(int fb)
{
	/* prman's facevaryinginterpolateboundary: 0 smooth, 1 edge and corner (the
	   default), 2 always sharp, 3 sharpen corners only. */
	switch (fb) {
	case 0: return Sdc::Options::FVAR_LINEAR_NONE;
	case 2: return Sdc::Options::FVAR_LINEAR_BOUNDARIES;
	case 3: return Sdc::Options::FVAR_LINEAR_CORNERS_ONLY;
	default: return Sdc::Options::FVAR_LINEAR_CORNERS_PLUS1;
	}
}

static Sdc::Options::VtxBoundaryInterpolation vtx_rule(enum osd_boundary b)
{
	switch (b) {
	case OSD_BOUNDARY_EDGE_AND_CORNER: return Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER;
	case OSD_BOUNDARY_EDGE_ONLY: return Sdc::Options::VTX_BOUNDARY_EDGE_ONLY;
	default: return Sdc::Options::VTX_BOUNDARY_NONE;
	}
}

static struct osd_mesh *create(const struct osd_topology *t, char *err, size_t errlen)
{
	typedef Far::TopologyDescriptor Desc;
	std::vector<Desc::FVarChannel> channels(t->nchannels);
	for (uint32_t c = 0; c < t->nchannels; c++) {
		channels[c].numValues = (int)t->channel_nvalues[c];
		channels[c].valueIndices = (const Far::Index *)t->channel_index[c];
	}
	Desc d;
	d.numVertices = (int)t->npoints;
	d.numFaces = (int)t->nfaces;
	d.numVertsPerFace = (const int *)t->face_sizes;
	d.vertIndicesPerFace = (const Far::Index *)t->face_verts;
	d.numCreases = (int)t->ncreases;
	d.creaseVertexIndexPairs = (const Far::Index *)t->crease_verts;
	d.creaseWeights = t->crease_sharp;
	d.numCorners = (int)t->ncorners;
	d.cornerVertexIndices = (const Far::Index *)t->corner_verts;
	d.cornerWeights = t->corner_sharp;
	d.numHoles = (int)t->nholes;
	d.holeIndices = (const Far::Index *)t->holes;
	d.numFVarChannels = (int)t->nchannels;
	d.fvarChannels = t->nchannels ? channels.data() : nullptr;

	Sdc::Options so;
	so.SetVtxBoundaryInterpolation(vtx_rule(t->boundary));
	so.SetFVarLinearInterpolation(fvar_rule(t->fvar_boundary));
	typedef Far::TopologyRefinerFactory<Desc> Factory;
	Far::TopologyRefiner *refiner;
	{
		std::lock_guard<std::mutex> g(far_lock);
		far_message[0] = 0;
		Far::SetErrorCallback(far_error);
		refiner = Factory::Create(d, Factory::Options(Sdc::SCHEME_CATMARK, so));
		Far::SetErrorCallback(nullptr);
		if (!refiner) {
			std::snprintf(err, errlen, "OpenSubdiv refuses the topology%s%s",
				      far_message[0] ? ": " : "", far_message);
			return nullptr;
		}
	}
	osd_mesh *m = new osd_mesh;
	m->refiner = refiner;
	m->nfaces = t->nfaces;
	m->nchannels = t->nchannels;
	Bfr::SurfaceFactory::Options fo;
	fo.EnableCaching(false);
	m->factory = new Bfr::RefinerSurfaceFactory<>(*refiner, fo);
	for (uint32_t c = 0; c < t->nchannels; c++)
		m->fvar_ids.push_back((int)c);
	return m;
}

extern "C" struct osd_mesh *osd_mesh_create(const struct osd_topology *t, char *err,
					      size_t errlen)
{
	try {
		return create(t, err, errlen);
	} catch (const std::bad_alloc &) {
		std::snprintf(err, errlen, "out of memory building the subdivision mesh");
	} catch (...) {
		std::snprintf(err, errlen, "OpenSubdiv failed on the subdivision mesh");
	}
	return nullptr;
}

extern "C" void osd_mesh_destroy(struct osd_mesh *m)
{
	if (!m)
		return;
	delete m->factory;
	delete m->refiner;
	delete m;
}

extern "C" bool osd_face_hole(const struct osd_mesh *m, uint32_t f)
{
	return f >= m->nfaces || !m->factory->FaceHasLimitSurface((Far::Index)f);
}

static bool init_surface(const osd_mesh *m, uint32_t f, enum osd_data data, uint32_t channel,
			 Bfr::Surface<double> *s)
{
	if (f >= m->nfaces)
		return false;
	switch (data) {
	case OSD_VERTEX:
		return m->factory->InitVertexSurface((Far::Index)f, s);
	case OSD_VARYING:
		return m->factory->InitVaryingSurface((Far::Index)f, s);
	case OSD_FACEVARYING:
		return channel < m->nchannels &&
		       m->factory->InitFaceVaryingSurface((Far::Index)f, s, m->fvar_ids[channel]);
	}
	return false;
}

static bool eval(const osd_mesh *m, uint32_t f, uint32_t sub, enum osd_data data,
		 uint32_t channel, const float *vals, uint32_t dim, uint32_t n, const double *uv,
		 double *out, double *du, double *dv)
{
	Bfr::Surface<double> s;
	if (!init_surface(m, f, data, channel, &s))
		return false;
	Bfr::Parameterization param = s.GetParameterization();
	if (param.HasSubFaces() ? sub >= (uint32_t)param.GetFaceSize() : sub != 0)
		return false;
	std::vector<double> pts((size_t)s.GetNumPatchPoints() * dim);
	Bfr::Surface<double>::PointDescriptor desc((int)dim);
	/* (Bfr gathers from a mesh array of its own REAL: widen the items it needs.) */
	std::vector<int> idx((size_t)s.GetNumControlPoints());
	s.GetControlPointIndices(idx.data());
	for (size_t i = 0; i < idx.size(); i++)
		for (uint32_t c = 0; c < dim; c++)
			pts[i * dim + c] = vals[(size_t)idx[i] * dim + c];
	s.ComputePatchPoints(pts.data(), desc);
	std::vector<double> tu(dim), tv(dim);
	for (uint32_t k = 0; k < n; k++) {
		double st[2] = { uv[2 * k], uv[2 * k + 1] }, c[2];
		double scale = 1.0;
		if (param.HasSubFaces()) {
			param.ConvertNormalizedSubFaceToCoord((int)sub, st, c);
			/* normalized sub-face coordinates span half the face's: d/ds = d/du / 2 */
			scale = 0.5;
		} else {
			c[0] = st[0], c[1] = st[1];
		}
		double *o = out + (size_t)k * dim;
		s.Evaluate(c, pts.data(), desc, o, tu.data(), tv.data());
		if (du)
			for (uint32_t e = 0; e < dim; e++)
				du[(size_t)k * dim + e] = tu[e] * scale;
		if (dv)
			for (uint32_t e = 0; e < dim; e++)
				dv[(size_t)k * dim + e] = tv[e] * scale;
	}
	return true;
}

extern "C" bool osd_eval(const struct osd_mesh *m, uint32_t f, uint32_t sub, enum osd_data data,
			 uint32_t channel, const float *vals, uint32_t dim, uint32_t n,
			 const double *uv, double *out, double *du, double *dv)
{
	try {
		return eval(m, f, sub, data, channel, vals, dim, n, uv, out, du, dv);
	} catch (...) {
		return false;
	}
}

extern "C" bool osd_face_hull(const struct osd_mesh *m, uint32_t f, const float *P, double lo[3],
			      double hi[3])
{
	try {
		Bfr::Surface<double> s;
		if (!init_surface(m, f, OSD_VERTEX, 0, &s))
			return false;
		std::vector<int> idx((size_t)s.GetNumControlPoints());
		s.GetControlPointIndices(idx.data());
		for (int c = 0; c < 3; c++)
			lo[c] = 1e300, hi[c] = -1e300;
		for (int i : idx)
			for (int c = 0; c < 3; c++) {
				double x = P[(size_t)i * 3 + c];
				lo[c] = x < lo[c] ? x : lo[c];
				hi[c] = x > hi[c] ? x : hi[c];
			}
		return !idx.empty();
	} catch (...) {
		return false;
	}
}

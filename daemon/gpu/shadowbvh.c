/*
 * The shadow geometry's ray-tracing hierarchy: see shadowbvh.h, and
 * sl/glsl.h for the layout in GPU memory.
 *
 * Embree builds the tree through callbacks that allocate its nodes from
 * Embree's own thread-local allocator (freed with the BVH); the tree is
 * then laid out depth first, a node's first child right after it, leaves'
 * triangles in the order the walk meets them, so a leaf is one run of the
 * triangle table. Empty geometry is one leaf holding one degenerate
 * triangle (never hit), so the traversal needs no special case.
 */
#include "shadowbvh.h"
#include "shadowrender_impl.h"
#include "glsl.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LEAF_MAX 4
#define MAX_TRIS (1u << 30)

struct build_node {
	bool leaf;
	uint32_t count;             /* leaf: triangles */
	float lo[2][3], hi[2][3];   /* inner: the children's bounds */
	struct build_node *child[2];
	uint32_t tri[LEAF_MAX];     /* leaf: triangle indices */
	float box_lo[3], box_hi[3]; /* leaf: its triangles' bounds */
};

static void *create_node(RTCThreadLocalAllocator alloc, unsigned int nchildren, void *user)
{
	(void)nchildren;
	(void)user;
	struct build_node *n = rtcThreadLocalAlloc(alloc, sizeof(*n), 16);
	if (n)
		memset(n, 0, sizeof(*n));
	return n;
}

static void set_children(void *node, void **children, unsigned int nchildren, void *user)
{
	(void)user;
	struct build_node *n = node;
	for (unsigned int i = 0; i < nchildren && i < 2; i++)
		n->child[i] = children[i];
}

static void set_bounds(void *node, const struct RTCBounds **bounds, unsigned int nchildren,
		       void *user)
{
	(void)user;
	struct build_node *n = node;
	for (unsigned int i = 0; i < nchildren && i < 2; i++) {
		n->lo[i][0] = bounds[i]->lower_x;
		n->lo[i][1] = bounds[i]->lower_y;
		n->lo[i][2] = bounds[i]->lower_z;
		n->hi[i][0] = bounds[i]->upper_x;
		n->hi[i][1] = bounds[i]->upper_y;
		n->hi[i][2] = bounds[i]->upper_z;
	}
}

static void *create_leaf(RTCThreadLocalAllocator alloc, const struct RTCBuildPrimitive *prims,
			 size_t nprims, void *user)
{
	(void)user;
	struct build_node *n = rtcThreadLocalAlloc(alloc, sizeof(*n), 16);
	if (!n)
		return NULL;
	memset(n, 0, sizeof(*n));
	n->leaf = true;
	n->count = (uint32_t)(nprims < LEAF_MAX ? nprims : LEAF_MAX);
	for (int k = 0; k < 3; k++) {
		n->box_lo[k] = INFINITY;
		n->box_hi[k] = -INFINITY;
	}
	for (uint32_t i = 0; i < n->count; i++) {
		n->tri[i] = prims[i].primID;
		const float lo[3] = { prims[i].lower_x, prims[i].lower_y, prims[i].lower_z };
		const float hi[3] = { prims[i].upper_x, prims[i].upper_y, prims[i].upper_z };
		for (int k = 0; k < 3; k++) {
			n->box_lo[k] = fminf(n->box_lo[k], lo[k]);
			n->box_hi[k] = fmaxf(n->box_hi[k], hi[k]);
		}
	}
	return n;
}

static float bits(uint32_t v)
{
	float f;
	v += IDX_BIAS;
	memcpy(&f, &v, sizeof(f));
	return f;
}

/* The layout being written: nodes (8 floats each) and triangles (12). */
struct layout {
	float *nodes, *tris;
	uint32_t nnodes, ntris, cap_nodes;
	const float *src;           /* 9 floats a source triangle, then its slot and opacity */
	const uint32_t *slot;
	const float *opacity;
	bool overflow;
};

static void put_node(struct layout *l, uint32_t at, const float lo[3], const float hi[3],
		     uint32_t a, uint32_t count)
{
	float *n = l->nodes + 8 * (uint64_t)at;
	for (int k = 0; k < 3; k++) {
		n[k] = lo[k];
		n[4 + k] = hi[k];
	}
	n[3] = bits(a);
	n[7] = bits(count);
}

/* Lay out @n, whose bounds are @lo, @hi, at the next node; depth first, iteratively. */
static void lay_out(struct layout *l, const struct build_node *root, const float rlo[3],
		    const float rhi[3])
{
	struct item {
		const struct build_node *n;
		float lo[3], hi[3];
		uint32_t parent;    /* node whose a is this one's index (UINT32_MAX: none) */
	} stack[80];
	int top = 0;
	stack[top].n = root;
	memcpy(stack[top].lo, rlo, sizeof(stack[top].lo));
	memcpy(stack[top].hi, rhi, sizeof(stack[top].hi));
	stack[top++].parent = UINT32_MAX;
	while (top > 0) {
		struct item it = stack[--top];
		if (l->nnodes >= l->cap_nodes) {
			l->overflow = true;
			return;
		}
		uint32_t at = l->nnodes++;
		if (it.parent != UINT32_MAX)
			l->nodes[8 * (uint64_t)it.parent + 3] = bits(at);
		if (it.n->leaf) {
			uint32_t first = l->ntris;
			for (uint32_t i = 0; i < it.n->count; i++) {
				uint32_t t = it.n->tri[i];
				const float *v = l->src + 9 * (uint64_t)t;
				float *o = l->tris + 12 * (uint64_t)l->ntris++;
				for (int k = 0; k < 3; k++) {
					o[k] = v[k];
					o[4 + k] = v[3 + k] - v[k];
					o[8 + k] = v[6 + k] - v[k];
				}
				o[3] = bits(l->slot[t / 2]);
				o[7] = l->opacity ? l->opacity[t / 2] : 1.0f;
				o[11] = 0.0f;
			}
			put_node(l, at, it.n->box_lo, it.n->box_hi, first, it.n->count);
			continue;
		}
		put_node(l, at, it.lo, it.hi, 0, 0);
		if (top + 2 > (int)(sizeof(stack) / sizeof(stack[0]))) {
			l->overflow = true;
			return;
		}
		/* the second child is laid out after the whole first subtree; its index goes to a */
		stack[top].n = it.n->child[1];
		memcpy(stack[top].lo, it.n->lo[1], sizeof(stack[top].lo));
		memcpy(stack[top].hi, it.n->hi[1], sizeof(stack[top].hi));
		stack[top++].parent = at;
		stack[top].n = it.n->child[0];
		memcpy(stack[top].lo, it.n->lo[0], sizeof(stack[top].lo));
		memcpy(stack[top].hi, it.n->hi[0], sizeof(stack[top].hi));
		stack[top++].parent = UINT32_MAX;
	}
}

static bool read_back(struct gpu_buffer *b, size_t bytes, void *out)
{
	return !bytes || gpu_buffer_read(b, 0, bytes, out);
}

bool gpu_shadow_bvh_build(struct gpu_shadow_geometry *g, char *err, size_t errlen)
{
	char dummy[1];
	if (!err || !errlen) {
		err = dummy;
		errlen = sizeof(dummy);
	}
	err[0] = '\0';
	if (!g) {
		snprintf(err, errlen, "shadow hierarchy: no shadow geometry");
		return false;
	}
	if (g->bvh_nodes)
		return true;
	uint64_t ntris = 2 * (uint64_t)g->nquads;
	if (ntris > MAX_TRIS) {
		snprintf(err, errlen, "shadow hierarchy: %llu triangles are too many (at most %u)",
			 (unsigned long long)ntris, MAX_TRIS);
		return false;
	}

	float *P = malloc((size_t)(g->npoints ? g->npoints : 1) * 3 * sizeof(float));
	uint32_t *quads = malloc((size_t)(g->nquads ? g->nquads : 1) * 4 * sizeof(uint32_t));
	uint32_t *slot = malloc((size_t)(g->nquads ? g->nquads : 1) * sizeof(uint32_t));
	float *opacity = g->opacity ? malloc((size_t)(g->nquads ? g->nquads : 1) * sizeof(float))
				    : NULL;
	float *src = malloc((size_t)(ntris ? ntris : 1) * 9 * sizeof(float));
	/* the builder's primitives are 32-byte aligned (RTC_ALIGN(32)) */
	struct RTCBuildPrimitive *prims = aligned_alloc(
		32, (size_t)(ntris ? ntris : 1) * sizeof(struct RTCBuildPrimitive));
	struct layout l = { 0 };
	/* a binary tree over ntris leaves of at least one triangle has < 2 ntris nodes */
	l.cap_nodes = (uint32_t)(ntris ? 2 * ntris : 1);
	l.nodes = malloc((size_t)l.cap_nodes * 8 * sizeof(float));
	l.tris = calloc((size_t)(ntris ? ntris : 1) * 12, sizeof(float));
	RTCDevice dev = NULL;
	RTCBVH bvh = NULL;
	bool ok = false;
	if (!P || !quads || !slot || (g->opacity && !opacity) || !src || !prims || !l.nodes ||
	    !l.tris) {
		snprintf(err, errlen, "shadow hierarchy: out of memory for %llu triangles",
			 (unsigned long long)ntris);
		goto done;
	}
	if (!read_back(g->points, (size_t)g->npoints * 3 * sizeof(float), P) ||
	    !read_back(g->quads, (size_t)g->nquads * 4 * sizeof(uint32_t), quads) ||
	    !read_back(g->slots, (size_t)g->nquads * sizeof(uint32_t), slot) ||
	    (opacity && !read_back(g->opacity, (size_t)g->nquads * sizeof(float), opacity))) {
		snprintf(err, errlen, "shadow hierarchy: cannot read the shadow geometry back");
		goto done;
	}

	/* Two triangles a micropolygon, the hider's cut; their bounds for the builder. */
	for (uint64_t q = 0; q < g->nquads; q++) {
		uint32_t v[4];
		for (int c = 0; c < 4; c++)
			v[c] = quads[4 * q + (uint64_t)c] - IDX_BIAS;
		slot[q] -= IDX_BIAS;
		const uint32_t corner[2][3] = { { v[0], v[1], v[2] }, { v[0], v[2], v[3] } };
		for (int h = 0; h < 2; h++) {
			uint64_t t = 2 * q + (uint64_t)h;
			float lo[3] = { INFINITY, INFINITY, INFINITY };
			float hi[3] = { -INFINITY, -INFINITY, -INFINITY };
			for (int c = 0; c < 3; c++)
				for (int k = 0; k < 3; k++) {
					float x = P[3 * (uint64_t)corner[h][c] + (uint64_t)k];
					src[9 * t + 3 * (uint64_t)c + (uint64_t)k] = x;
					lo[k] = fminf(lo[k], x);
					hi[k] = fmaxf(hi[k], x);
				}
			prims[t] = (struct RTCBuildPrimitive){
				.lower_x = lo[0], .lower_y = lo[1], .lower_z = lo[2], .geomID = 0,
				.upper_x = hi[0], .upper_y = hi[1], .upper_z = hi[2],
				.primID = (unsigned int)t,
			};
		}
	}
	l.src = src;
	l.slot = slot;
	l.opacity = opacity;

	if (ntris == 0) {
		/* one leaf of one degenerate triangle at the origin: nothing is ever hit */
		const float zero[3] = { 0, 0, 0 };
		l.nnodes = 1;
		l.ntris = 1;
		l.tris[3] = bits(0);
		put_node(&l, 0, zero, zero, 0, 1);
	} else {
		dev = rtcNewDevice(NULL);
		bvh = dev ? rtcNewBVH(dev) : NULL;
		if (!bvh) {
			snprintf(err, errlen, "shadow hierarchy: Embree cannot start (error %d)",
				 dev ? (int)rtcGetDeviceError(dev) : -1);
			goto done;
		}
		struct RTCBuildArguments a = rtcDefaultBuildArguments();
		a.buildQuality = RTC_BUILD_QUALITY_HIGH;
		a.maxBranchingFactor = 2;
		a.maxDepth = 32;
		a.minLeafSize = 1;
		a.maxLeafSize = LEAF_MAX;
		a.bvh = bvh;
		a.primitives = prims;
		a.primitiveCount = (size_t)ntris;
		a.primitiveArrayCapacity = (size_t)ntris;
		a.createNode = create_node;
		a.setNodeChildren = set_children;
		a.setNodeBounds = set_bounds;
		a.createLeaf = create_leaf;
		struct build_node *root = rtcBuildBVH(&a);
		if (!root) {
			snprintf(err, errlen, "shadow hierarchy: Embree's builder failed (error %d)",
				 (int)rtcGetDeviceError(dev));
			goto done;
		}
		float lo[3] = { INFINITY, INFINITY, INFINITY };
		float hi[3] = { -INFINITY, -INFINITY, -INFINITY };
		for (uint64_t t = 0; t < ntris; t++) {
			/* prims may have been reordered by the builder: take the bounds from src */
			for (int c = 0; c < 3; c++)
				for (int k = 0; k < 3; k++) {
					float x = src[9 * t + 3 * (uint64_t)c + (uint64_t)k];
					lo[k] = fminf(lo[k], x);
					hi[k] = fmaxf(hi[k], x);
				}
		}
		lay_out(&l, root, lo, hi);
		if (l.overflow || l.ntris != ntris) {
			snprintf(err, errlen, "shadow hierarchy: the tree does not fit its layout "
				 "(%u nodes, %u of %llu triangles)", l.nnodes, l.ntris,
				 (unsigned long long)ntris);
			goto done;
		}
	}

	g->bvh_nodes = gpu_shadow_upload(g, (size_t)l.nnodes * 8 * sizeof(float), l.nodes);
	g->bvh_tris = gpu_shadow_upload(g, (size_t)l.ntris * 12 * sizeof(float), l.tris);
	if (!g->bvh_nodes || !g->bvh_tris) {
		gpu_buffer_destroy(g->bvh_nodes);
		gpu_buffer_destroy(g->bvh_tris);
		g->bvh_nodes = g->bvh_tris = NULL;
		snprintf(err, errlen, "shadow hierarchy: cannot upload %u nodes and %u triangles",
			 l.nnodes, l.ntris);
		goto done;
	}
	g->bvh_nnodes = l.nnodes;
	g->bvh_ntris = l.ntris;
	ok = true;
done:
	if (bvh)
		rtcReleaseBVH(bvh);
	if (dev)
		rtcReleaseDevice(dev);
	free(l.tris);
	free(l.nodes);
	free(prims);
	free(src);
	free(opacity);
	free(slot);
	free(quads);
	free(P);
	return ok;
}

void gpu_shadow_bvh_stats(const struct gpu_shadow_geometry *g, uint32_t *nodes, uint32_t *tris,
			  size_t *bytes)
{
	uint32_t n = g && g->bvh_nodes ? g->bvh_nnodes : 0;
	uint32_t t = g && g->bvh_nodes ? g->bvh_ntris : 0;
	if (nodes)
		*nodes = n;
	if (tris)
		*tris = t;
	if (bytes)
		*bytes = (size_t)n * 32 + (size_t)t * 48;
}

bool gpu_shadow_bvh_bind(struct gpu_shadow_geometry *g, uint32_t unit, const float *casts,
			 uint32_t ncasts, struct gpu_binding out[3])
{
	if (!g || !g->bvh_nodes || !gpu_shadow_set_casts(g, casts, ncasts))
		return false;
	out[0] = (struct gpu_binding){ .unit = unit, .buffer = g->bvh_nodes, .rgba = true };
	out[1] = (struct gpu_binding){ .unit = unit + 1, .buffer = g->bvh_tris, .rgba = true };
	out[2] = (struct gpu_binding){ .unit = unit + 2, .buffer = g->casts };
	return true;
}

/* One invocation a ray: rays in, transmission out. */
static const char trace_main[] =
	"layout(binding = 0) uniform samplerBuffer u_nodes;\n"
	"layout(binding = 1) uniform samplerBuffer u_tris;\n"
	"layout(binding = 2) uniform samplerBuffer u_casts;\n"
	"layout(std430, binding = 3) readonly buffer Rays { float rays[]; };\n"
	"layout(std430, binding = 4) writeonly buffer Out { float result[]; };\n"
	"void main()\n"
	"{\n"
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
	"	if (i >= u_count)\n"
	"		return;\n"
	"	vec3 o = vec3(rays[7u * i], rays[7u * i + 1u], rays[7u * i + 2u]);\n"
	"	vec3 d = vec3(rays[7u * i + 3u], rays[7u * i + 4u], rays[7u * i + 5u]);\n"
	"	result[i] = rl_bvh_transmission(u_nodes, u_tris, u_casts, o, d, rays[7u * i + 6u]);\n"
	"}\n";

bool gpu_shadow_bvh_trace(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g, const float *org,
			  const float *dir, const float *tmax, uint32_t n, const float *casts,
			  uint32_t ncasts, float *out)
{
	if (!ctx || !g || g->ctx != ctx || (n && (!org || !dir || !tmax || !out)))
		return false;
	if (!gpu_shadow_bvh_build(g, NULL, 0))
		return false;
	if (n == 0)
		return true;
	if (!g->bvh_trace) {
		size_t len = strlen(sl_glsl_bvh_source) + sizeof(trace_main) + 256;
		char *src = malloc(len);
		if (!src)
			return false;
		snprintf(src, len, "#version 430 core\nlayout(local_size_x = 64) in;\n"
			 "uniform uint u_count;\n%s%s", sl_glsl_bvh_source, trace_main);
		g->bvh_trace = gpu_program(ctx, src, NULL);
		free(src);
		if (!g->bvh_trace)
			return false;
	}
	float *rays = malloc((size_t)n * 7 * sizeof(float));
	if (!rays)
		return false;
	for (uint32_t i = 0; i < n; i++) {
		memcpy(rays + 7 * (size_t)i, org + 3 * (size_t)i, 3 * sizeof(float));
		memcpy(rays + 7 * (size_t)i + 3, dir + 3 * (size_t)i, 3 * sizeof(float));
		rays[7 * (size_t)i + 6] = tmax[i];
	}
	struct gpu_buffer *in = gpu_buffer_create(ctx, (size_t)n * 7 * sizeof(float), rays);
	struct gpu_buffer *res = gpu_buffer_create(ctx, (size_t)n * sizeof(float), NULL);
	free(rays);
	struct gpu_binding b[5];
	bool ok = in && res && gpu_shadow_bvh_bind(g, 0, casts, ncasts, b);
	if (ok) {
		b[3] = (struct gpu_binding){ .unit = 3, .ssbo = true, .buffer = in };
		b[4] = (struct gpu_binding){ .unit = 4, .ssbo = true, .buffer = res };
		ok = gpu_dispatch(ctx, g->bvh_trace, b, 5, n) &&
		     gpu_buffer_read(res, 0, (size_t)n * sizeof(float), out);
	}
	gpu_buffer_destroy(in);
	gpu_buffer_destroy(res);
	return ok;
}

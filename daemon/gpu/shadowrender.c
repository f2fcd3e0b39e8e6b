/*
 * Shadow maps from shadow geometry on the GPU: see shadowrender.h.
 *
 * Layout in GPU memory (read through texture buffers, which llvmpipe
 * streams ~2.5x faster than SSBOs): the points as they came, 3 R32F texels
 * each; per kept micropolygon one RGBA32F texel of its 4 point indices and
 * one R32F texel of its object's slot. Slots number the distinct object ids
 * in ascending order, so an id of any size costs one small table entry; a
 * render uploads one flag per slot (0: the object does not cast). Indices
 * and slots travel in a float's bits, shifted up by the smallest normal
 * float's bits (IDX_BIAS) so that every stored pattern is a positive,
 * normal, finite float that no denormal flush or NaN canonicalization can
 * change.
 *
 * Rasterizing. One invocation per micropolygon projects its corners
 * (h = [P 1] world_to_ndc, screen = h.xy / h.w in pixels), and tests the
 * pixel centres inside its bounding box against the two triangles
 * (v0, v1, v2) and (v0, v2, v3), the cut the renderer's hider makes, with
 * the hider's edge functions and tie rule: edges are evaluated from their
 * lexicographically smaller endpoint (so the two micropolygons sharing an
 * edge compute exactly opposite values), and a centre on an edge belongs to
 * the side it would fall in if moved an infinitesimal amount right, then
 * down. The arithmetic that feeds those tests is `precise` (no contraction
 * into fused multiply-adds that could differ between two copies of the same
 * expression), so a centre on an edge shared by two micropolygons is
 * counted exactly once and one inside a micropolygon's own diagonal too.
 * A micropolygon counts at most once per pixel (its first triangle that
 * holds the centre), as in the hider.
 *
 * Depth. The triangle's screen-space edge values are its barycentric weights
 * of the centre on the screen; divided by each corner's h.w they become the
 * weights of the triangle's world-space point that projects there
 * (perspective-correct interpolation), which give its camera-space z. For a
 * flat triangle this is the exact ray/plane intersection (up to float
 * rounding) whatever the projection, perspective or orthographic; the
 * hider interpolates z linearly on the screen instead, which differs by the
 * curvature of 1/z across a micropolygon (relative 1e-4 or less for the
 * micropolygons of a diced scene), but which would be off by the whole
 * perspective error across a large flat polygon given as few micropolygons.
 *
 * Depth filters. A depth is kept as its float bits, which order like
 * unsigned integers for positive floats: the nearest hit is an atomicMin.
 * For the midpoint filter a second pass over the geometry, with the same
 * program and so the same bits per micropolygon and pixel, counts the hits
 * exactly at that depth and keeps the nearest hit behind it; "another
 * surface" is another micropolygon covering the centre, as in the hider,
 * which keeps its two nearest hits whatever objects they belong to (the
 * front and back of a closed object are two). Two hits at the same depth
 * (coincident surfaces) are two surfaces, as in the hider. The tie rule is
 * what keeps neighbours of one surface from counting twice; where two
 * micropolygons of one surface overlap on the screen (a surface folded over
 * itself, or grids that overlap at seams), the hider also sees two hits.
 *
 * Limits. A micropolygon with a corner at or behind the eye (h.w <= 0) or
 * that projects to a non-finite point is left out: micropolygons are small,
 * and a camera does not look at what touches its eye plane. Hits at z <= 0
 * or at or beyond 1e30 are ignored. A micropolygon whose bounding box holds
 * more than MAX_PIXELS pixel centres inside the map is left out whole, so
 * one invocation does at most MAX_PIXELS pixel tests.
 */
#include "shadowrender.h"
#include "shadowrender_impl.h"

#include "log.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A micropolygon may test at most this many pixel centres; beyond it, it is left out. */
#define MAX_PIXELS 65536

/* Pixels per map at most (a 32-bit index, and far above any SSBO limit). */
#define MAX_MAP_PIXELS (1u << 30)


/* ---- shaders ---- */

#define PRELUDE_BASE \
	"#version 430 core\n" \
	"layout(local_size_x = 64) in;\n" \
	"uniform uint u_count;\n" \
	"const uint EMPTY = 0x7149f2cau; /* 1e30 */\n" \
	"uint invocation()\n" \
	"{\n" \
	"	return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n" \
	"}\n"

#define SHADER_PRELUDE \
	PRELUDE_BASE \
	"layout(std430, binding = 0) buffer Depth { uint depth_bits[]; };\n" \
	"layout(std430, binding = 1) buffer Scratch { uint scratch[]; };\n"

/* Every pixel empty; for the midpoint filter no second depth and no count. */
static const char clear_src[] =
	SHADER_PRELUDE
	"uniform int u_midpoint;\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	depth_bits[p] = EMPTY;\n"
	"	if (u_midpoint != 0) {\n"
	"		scratch[2u * p] = EMPTY;\n"
	"		scratch[2u * p + 1u] = 0u;\n"
	"	}\n"
	"}\n";

/*
 * What the depth and deep rasterizers share: the micropolygon's projection
 * and edge setup (RASTER_SETUP, in main, returning when it covers nothing),
 * then per centre c the hit test (RASTER_HIT: continues unless it hits, with
 * its depth in z). Centres are those of a grid u_ns times finer than the map
 * on each axis (1 for depth maps), at integer + 0.5 in that grid's units.
 */
#define RASTER_HELPERS \
	"uniform mat4 u_to_ndc;\n" \
	"uniform vec4 u_zrow;\n" \
	"uniform int u_width;\n" \
	"uniform int u_height;\n" \
	"uniform int u_ns;\n" \
	"uniform int u_pass;\n" \
	"layout(binding = 0) uniform samplerBuffer u_points;\n" \
	"layout(binding = 1) uniform samplerBuffer u_quads;\n" \
	"layout(binding = 2) uniform samplerBuffer u_slots;\n" \
	"layout(binding = 3) uniform samplerBuffer u_casts;\n" \
	"const uint IDX_BIAS = 0x00800000u;\n" \
	"const float MAX_PIXELS = 65536.0;\n" \
	"bool finite(float v)\n" \
	"{\n" \
	"	return (floatBitsToUint(v) & 0x7f800000u) != 0x7f800000u;\n" \
	"}\n" \
	"/* An edge from its lexicographically smaller endpoint a, direction d; s = -1\n" \
	"   when that reverses the edge as given. */\n" \
	"struct Edge {\n" \
	"	vec2 a;\n" \
	"	vec2 d;\n" \
	"	float s;\n" \
	"};\n" \
	"Edge edge(vec2 p, vec2 q)\n" \
	"{\n" \
	"	bool fwd = p.x < q.x || (p.x == q.x && p.y <= q.y);\n" \
	"	Edge e;\n" \
	"	e.a = fwd ? p : q;\n" \
	"	precise vec2 d = fwd ? q - p : p - q;\n" \
	"	e.d = d;\n" \
	"	e.s = fwd ? 1.0 : -1.0;\n" \
	"	return e;\n" \
	"}\n" \
	"float edge_eval(Edge e, vec2 c)\n" \
	"{\n" \
	"	precise float v = e.d.x * (c.y - e.a.y) - e.d.y * (c.x - e.a.x);\n" \
	"	return v;\n" \
	"}\n" \
	"/* Does a centre moved right, then down, cross edge direction k * d inward? */\n" \
	"bool owns(Edge e, float k)\n" \
	"{\n" \
	"	float A = k * e.d.x, B = k * e.d.y;\n" \
	"	return B < 0.0 || (B == 0.0 && A > 0.0);\n" \
	"}\n" \
	"bool inside(vec3 v, bvec3 own)\n" \
	"{\n" \
	"	return (v.x > 0.0 || (v.x == 0.0 && own.x)) && (v.y > 0.0 || (v.y == 0.0 && own.y)) &&\n" \
	"	       (v.z > 0.0 || (v.z == 0.0 && own.z));\n" \
	"}\n"

#define RASTER_SETUP \
	"	uint i = invocation();\n" \
	"	if (i >= u_count)\n" \
	"		return;\n" \
	"	int slot = int(floatBitsToUint(texelFetch(u_slots, int(i)).r) - IDX_BIAS);\n" \
	"	if (texelFetch(u_casts, slot).r == 0.0)\n" \
	"		return;\n" \
	"	uvec4 vi = floatBitsToUint(texelFetch(u_quads, int(i))) - uvec4(IDX_BIAS);\n" \
	"	vec2 s[4];\n" \
	"	float q[4], r[4];\n" \
	"	vec2 size = vec2(float(u_width * u_ns), float(u_height * u_ns));\n" \
	"	for (int k = 0; k < 4; k++) {\n" \
	"		int b = int(vi[k] * 3u);\n" \
	"		vec4 P = vec4(texelFetch(u_points, b).r, texelFetch(u_points, b + 1).r,\n" \
	"			      texelFetch(u_points, b + 2).r, 1.0);\n" \
	"		precise vec4 h = u_to_ndc * P;\n" \
	"		if (!(h.w > 0.0))\n" \
	"			return;\n" \
	"		precise vec2 sp = h.xy / h.w * size;\n" \
	"		s[k] = sp;\n" \
	"		r[k] = 1.0 / h.w;\n" \
	"		q[k] = dot(u_zrow, P) * r[k];\n" \
	"		if (!finite(s[k].x) || !finite(s[k].y) || !finite(r[k]) || !finite(q[k]))\n" \
	"			return;\n" \
	"	}\n" \
	"	vec2 lo = min(min(s[0], s[1]), min(s[2], s[3]));\n" \
	"	vec2 hi = max(max(s[0], s[1]), max(s[2], s[3]));\n" \
	"	/* Centres x + 0.5 in [lo, hi], within the map (clamped before any int). */\n" \
	"	vec2 f0 = max(ceil(lo - 0.5), vec2(0.0));\n" \
	"	vec2 f1 = min(floor(hi - 0.5), size - 1.0);\n" \
	"	if (!(f0.x <= f1.x && f0.y <= f1.y))\n" \
	"		return;\n" \
	"	if ((f1.x - f0.x + 1.0) * (f1.y - f0.y + 1.0) > MAX_PIXELS)\n" \
	"		return;\n" \
	"	Edge e0 = edge(s[0], s[1]), e1 = edge(s[1], s[2]), e2 = edge(s[2], s[3]),\n" \
	"	     e3 = edge(s[3], s[0]), e4 = edge(s[0], s[2]);\n" \
	"	/* Triangle (v0, v1, v2): edges opposite its corners v1->v2, v2->v0 (the\n" \
	"	   diagonal reversed), v0->v1; orientation from v0->v1 at v2. */\n" \
	"	float a0 = e0.s * edge_eval(e0, s[2]);\n" \
	"	bool ok0 = a0 != 0.0 && finite(a0);\n" \
	"	float o0 = a0 > 0.0 ? 1.0 : -1.0;\n" \
	"	vec3 k0 = o0 * vec3(e1.s, -e4.s, e0.s);\n" \
	"	bvec3 own0 = bvec3(owns(e1, k0.x), owns(e4, k0.y), owns(e0, k0.z));\n" \
	"	/* Triangle (v0, v2, v3): v2->v3, v3->v0, v0->v2; orientation from v0->v2 at v3. */\n" \
	"	float a1 = e4.s * edge_eval(e4, s[3]);\n" \
	"	bool ok1 = a1 != 0.0 && finite(a1);\n" \
	"	float o1 = a1 > 0.0 ? 1.0 : -1.0;\n" \
	"	vec3 k1 = o1 * vec3(e2.s, e3.s, e4.s);\n" \
	"	bvec3 own1 = bvec3(owns(e2, k1.x), owns(e3, k1.y), owns(e4, k1.z));\n" \
	"	if (!ok0 && !ok1)\n" \
	"		return;\n" \
	"	vec3 q0 = vec3(q[0], q[1], q[2]), r0 = vec3(r[0], r[1], r[2]);\n" \
	"	vec3 q1 = vec3(q[0], q[2], q[3]), r1 = vec3(r[0], r[2], r[3]);\n" \
	"	int x0 = int(f0.x), x1 = int(f1.x), y0 = int(f0.y), y1 = int(f1.y);\n"

#define RASTER_HIT \
	"			float d4 = edge_eval(e4, c);\n" \
	"			float num = 0.0, den = 0.0;\n" \
	"			bool hit = false;\n" \
	"			if (ok0) {\n" \
	"				vec3 w = k0 * vec3(edge_eval(e1, c), d4, edge_eval(e0, c));\n" \
	"				if (inside(w, own0)) {\n" \
	"					num = dot(w, q0);\n" \
	"					den = dot(w, r0);\n" \
	"					hit = true;\n" \
	"				}\n" \
	"			}\n" \
	"			if (!hit && ok1) {\n" \
	"				vec3 w = k1 * vec3(edge_eval(e2, c), edge_eval(e3, c), d4);\n" \
	"				if (inside(w, own1)) {\n" \
	"					num = dot(w, q1);\n" \
	"					den = dot(w, r1);\n" \
	"					hit = true;\n" \
	"				}\n" \
	"			}\n" \
	"			if (!hit || !(den > 0.0))\n" \
	"				continue;\n" \
	"			float z = num / den;\n" \
	"			uint bits = floatBitsToUint(z);\n" \
	"			if (!(z > 0.0) || bits >= EMPTY)\n" \
	"				continue;\n"

/*
 * One invocation per micropolygon. Pass 0 keeps the nearest hit per pixel;
 * pass 1 (midpoint) counts the hits at exactly that depth and keeps the
 * nearest behind it.
 */
static const char raster_src[] =
	SHADER_PRELUDE
	RASTER_HELPERS
	"void main()\n"
	"{\n"
	RASTER_SETUP
	"	for (int y = y0; y <= y1; y++) {\n"
	"		for (int x = x0; x <= x1; x++) {\n"
	"			vec2 c = vec2(float(x) + 0.5, float(y) + 0.5);\n"
	RASTER_HIT
	"			uint p = uint(y) * uint(u_width) + uint(x);\n"
	"			if (u_pass == 0) {\n"
	"				atomicMin(depth_bits[p], bits);\n"
	"			} else {\n"
	"				uint first = depth_bits[p];\n"
	"				if (bits == first)\n"
	"					atomicAdd(scratch[2u * p + 1u], 1u);\n"
	"				else if (bits > first)\n"
	"					atomicMin(scratch[2u * p], bits);\n"
	"			}\n"
	"		}\n"
	"	}\n"
	"}\n";

/*
 * Midpoint: halfway between the nearest hit and the next (the nearest again
 * when two hits share its depth); empty with fewer than two hits.
 */
static const char resolve_src[] =
	SHADER_PRELUDE
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	uint first = depth_bits[p];\n"
	"	if (first >= EMPTY)\n"
	"		return;\n"
	"	uint second = scratch[2u * p + 1u] >= 2u ? first : scratch[2u * p];\n"
	"	if (second >= EMPTY) {\n"
	"		depth_bits[p] = EMPTY;\n"
	"		return;\n"
	"	}\n"
	"	depth_bits[p] = floatBitsToUint(0.5 * (uintBitsToFloat(first) + uintBitsToFloat(second)));\n"
	"}\n";

/*
 * Deep maps. Hits are events (depth bits, opacity bits, sample index) in
 * one list per texel, at [offsets[p], offsets[p + 1]) of the event buffer.
 */
#define DEEP_PRELUDE \
	PRELUDE_BASE \
	"layout(std430, binding = 0) buffer Count { uint count[]; };\n" \
	"layout(std430, binding = 1) buffer Offsets { uint offsets[]; };\n" \
	"layout(std430, binding = 2) buffer Events { uint events[]; };\n"

static const char deep_clear_src[] =
	DEEP_PRELUDE
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p < u_count)\n"
	"		count[p] = 0u;\n"
	"}\n";

/*
 * One invocation per micropolygon, at u_ns x u_ns sample centres per texel
 * (sample k = row * u_ns + column of its texel). Pass 0 counts each texel's
 * hits; pass 1, with the counts cleared and the offsets their prefix sums,
 * writes them. Both run the same arithmetic, so they find the same hits.
 */
static const char deep_raster_src[] =
	DEEP_PRELUDE
	RASTER_HELPERS
	"layout(binding = 4) uniform samplerBuffer u_opacity;\n"
	"void main()\n"
	"{\n"
	RASTER_SETUP
	"	float opacity = min(texelFetch(u_opacity, int(i)).r, 1.0);\n"
	"	if (!(opacity > 0.0))\n"
	"		return;\n"
	"	uint ns = uint(u_ns);\n"
	"	for (int y = y0; y <= y1; y++) {\n"
	"		for (int x = x0; x <= x1; x++) {\n"
	"			vec2 c = vec2(float(x) + 0.5, float(y) + 0.5);\n"
	RASTER_HIT
	"			uint p = (uint(y) / ns) * uint(u_width) + uint(x) / ns;\n"
	"			uint k = (uint(y) % ns) * ns + uint(x) % ns;\n"
	"			uint at = atomicAdd(count[p], 1u);\n"
	"			if (u_pass == 0)\n"
	"				continue;\n"
	"			at += offsets[p];\n"
	"			if (at >= offsets[p + 1u])\n"
	"				continue;\n"
	"			events[3u * at] = bits;\n"
	"			events[3u * at + 1u] = floatBitsToUint(opacity);\n"
	"			events[3u * at + 2u] = k;\n"
	"		}\n"
	"	}\n"
	"}\n";

/*
 * One invocation per texel: its events sorted by depth, then sample
 * (insertion sort in place: lists are bounded, DEEP_MAX_TEXEL_HITS), then
 * reyes_deep_build_pixel's walk (render/deepshadow.c): the mean over the
 * texel's samples of each one's transmittance, a sample ignoring what lies
 * behind the point where it became opaque (the hider's opacity threshold),
 * compressed into runs whose drops add up to at most u_error. At most two
 * nodes per event, at nodes[2 * offsets[p]] (pairs z, T); their count in
 * count[p].
 */
static const char deep_build_src[] =
	DEEP_PRELUDE
	"layout(std430, binding = 3) buffer Nodes { float nodes[]; };\n"
	"uniform int u_samples;\n"
	"uniform float u_error;\n"
	"uniform float u_threshold;\n"
	"const int DEEP_MAX_SAMPLES = 64;\n"
	"uint base, n;\n"
	"void put(float z, double t)\n"
	"{\n"
	"	float tf = float(clamp(t, 0.0lf, 1.0lf));\n"
	"	uint at = 2u * (2u * base + n);\n"
	"	if (n > 0u && nodes[at - 2u] == z && nodes[at - 1u] == tf)\n"
	"		return;\n"
	"	if (n >= 2u && nodes[at - 2u] == z && nodes[at - 4u] == z) {\n"
	"		nodes[at - 1u] = tf;\n"
	"		return;\n"
	"	}\n"
	"	nodes[at] = z;\n"
	"	nodes[at + 1u] = tf;\n"
	"	n++;\n"
	"}\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	base = offsets[p];\n"
	"	uint m = offsets[p + 1u] - base;\n"
	"	n = 0u;\n"
	"	for (uint i = 1u; i < m; i++) {\n"
	"		uvec3 e = uvec3(events[3u * (base + i)], events[3u * (base + i) + 1u],\n"
	"				events[3u * (base + i) + 2u]);\n"
	"		float ze = uintBitsToFloat(e.x);\n"
	"		uint j = i;\n"
	"		for (; j > 0u; j--) {\n"
	"			uint q = base + j - 1u;\n"
	"			float zq = uintBitsToFloat(events[3u * q]);\n"
	"			if (!(zq > ze || (zq == ze && events[3u * q + 2u] > e.z)))\n"
	"				break;\n"
	"			events[3u * (q + 1u)] = events[3u * q];\n"
	"			events[3u * (q + 1u) + 1u] = events[3u * q + 1u];\n"
	"			events[3u * (q + 1u) + 2u] = events[3u * q + 2u];\n"
	"		}\n"
	"		events[3u * (base + j)] = e.x;\n"
	"		events[3u * (base + j) + 1u] = e.y;\n"
	"		events[3u * (base + j) + 2u] = e.z;\n"
	"	}\n"
	"	double ts[DEEP_MAX_SAMPLES];\n"
	"	for (int k = 0; k < u_samples; k++)\n"
	"		ts[k] = 1.0lf;\n"
	"	double err = double(u_error), inv = 1.0lf / double(u_samples);\n"
	"	double opaque = 1.0lf - double(u_threshold);\n"
	"	double v = 1.0lf, va = 1.0lf, drop = 0.0lf;\n"
	"	float za = 0.0, zl = 0.0;\n"
	"	bool open = false;\n"
	"	for (uint i = 0u; i < m; i++) {\n"
	"		uint at = 3u * (base + i);\n"
	"		float z = uintBitsToFloat(events[at]);\n"
	"		double o = double(uintBitsToFloat(events[at + 1u]));\n"
	"		uint k = events[at + 2u];\n"
	"		/* the hider keeps no hit behind a sample's opaque point */\n"
	"		if (ts[k] <= opaque)\n"
	"			continue;\n"
	"		double d = ts[k] * o * inv;\n"
	"		ts[k] *= 1.0lf - o;\n"
	"		if (open && drop + d > err) {\n"
	"			put(za, va);\n"
	"			put(zl, v);\n"
	"			open = false;\n"
	"		}\n"
	"		if (!open) {\n"
	"			open = true;\n"
	"			za = z;\n"
	"			va = v;\n"
	"			drop = 0.0lf;\n"
	"		}\n"
	"		v -= d;\n"
	"		drop += d;\n"
	"		zl = z;\n"
	"	}\n"
	"	if (open) {\n"
	"		put(za, va);\n"
	"		put(zl, v);\n"
	"	}\n"
	"	count[p] = n;\n"
	"}\n";

/*
 * The map buffer as the runtime reads deep maps (shadowmap.c): u_count + 1
 * offsets as floats, written by the caller, then each texel's nodes moved
 * there from where the build left them.
 */
static const char deep_pack_src[] =
	DEEP_PRELUDE
	"layout(std430, binding = 3) buffer Nodes { float nodes[]; };\n"
	"layout(std430, binding = 4) buffer Map { float map[]; };\n"
	"void main()\n"
	"{\n"
	"	uint p = invocation();\n"
	"	if (p >= u_count)\n"
	"		return;\n"
	"	uint from = 4u * offsets[p], to = u_count + 1u + 2u * uint(map[p]);\n"
	"	for (uint k = 0u; k < 2u * count[p]; k++)\n"
	"		map[to + k] = nodes[from + k];\n"
	"}\n";

/* ---- geometry ---- */

static int cmp_u32(const void *a, const void *b)
{
	uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
	return (x > y) - (x < y);
}

static bool corner_ok(const float *P, uint64_t npoints, uint32_t v)
{
	if (v >= npoints)
		return false;
	const float *p = P + 3 * (uint64_t)v;
	return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

struct gpu_buffer *gpu_shadow_upload(struct gpu_shadow_geometry *g, size_t bytes, const void *data)
{
	size_t size = bytes < 16 ? 16 : bytes;
	struct gpu_buffer *b = gpu_buffer_create(g->ctx, size, bytes == size ? data : NULL);
	if (b && bytes != size && bytes && !gpu_buffer_write(b, 0, bytes, data)) {
		gpu_buffer_destroy(b);
		return NULL;
	}
	if (b)
		g->bytes += size;
	return b;
}

struct gpu_shadow_geometry *gpu_shadow_geometry_create(struct gpu_ctx *ctx, const float *P,
						       uint64_t npoints, const uint32_t *quads,
						       const uint32_t *object, const float *opacity,
						       uint64_t nquads, char *err, size_t errlen)
{
	char dummy[1];
	if (!err || !errlen) {
		err = dummy;
		errlen = sizeof(dummy);
	}
	err[0] = '\0';
	if (!ctx || (npoints && !P) || (nquads && (!quads || !object))) {
		snprintf(err, errlen, "shadow geometry: no %s", !ctx ? "context" :
			 (npoints && !P) ? "points" : "micropolygons");
		return NULL;
	}
	if (npoints > (uint64_t)IDX_MAX + 1 || npoints > SIZE_MAX / (3 * sizeof(float))) {
		snprintf(err, errlen, "shadow geometry: %llu points are too many",
			 (unsigned long long)npoints);
		return NULL;
	}

	/* Keep the micropolygons whose corners exist and are finite. */
	uint64_t kept = 0;
	for (uint64_t q = 0; q < nquads; q++) {
		const uint32_t *v = quads + 4 * q;
		kept += corner_ok(P, npoints, v[0]) && corner_ok(P, npoints, v[1]) &&
			corner_ok(P, npoints, v[2]) && corner_ok(P, npoints, v[3]);
	}
	if (kept > (uint64_t)IDX_MAX + 1 || kept > UINT32_MAX ||
	    kept > SIZE_MAX / (4 * sizeof(uint32_t))) {
		snprintf(err, errlen, "shadow geometry: %llu micropolygons are too many",
			 (unsigned long long)kept);
		return NULL;
	}

	struct gpu_shadow_geometry *g = calloc(1, sizeof(*g));
	uint32_t *idx = malloc((size_t)(kept ? kept : 1) * 4 * sizeof(uint32_t));
	uint32_t *slot = malloc((size_t)(kept ? kept : 1) * sizeof(uint32_t));
	uint32_t *runs = malloc((size_t)(kept ? kept : 1) * sizeof(uint32_t));
	float *op = opacity ? malloc((size_t)(kept ? kept : 1) * sizeof(float)) : NULL;
	if (!g || !idx || !slot || !runs || (opacity && !op)) {
		snprintf(err, errlen, "shadow geometry: out of memory");
		goto fail;
	}
	g->ctx = ctx;
	g->npoints = npoints;
	g->nquads = (uint32_t)kept;

	/* Object ids: the first id of each run (grids come one after another),
	 * sorted and made unique, are the slots. */
	uint64_t k = 0, nruns = 0;
	for (uint64_t q = 0; q < nquads; q++) {
		const uint32_t *v = quads + 4 * q;
		if (!(corner_ok(P, npoints, v[0]) && corner_ok(P, npoints, v[1]) &&
		      corner_ok(P, npoints, v[2]) && corner_ok(P, npoints, v[3])))
			continue;
		for (int c = 0; c < 4; c++)
			idx[4 * k + (uint64_t)c] = v[c] + IDX_BIAS;
		slot[k] = object[q];
		if (op)
			op[k] = isfinite(opacity[q]) ? fminf(fmaxf(opacity[q], 0.0f), 1.0f) : 1.0f;
		if (!nruns || runs[nruns - 1] != object[q])
			runs[nruns++] = object[q];
		k++;
	}
	qsort(runs, (size_t)nruns, sizeof(uint32_t), cmp_u32);
	uint32_t nslots = 0;
	for (uint64_t i = 0; i < nruns; i++)
		if (!nslots || runs[nslots - 1] != runs[i])
			runs[nslots++] = runs[i];
	g->nslots = nslots;
	g->slot_id = malloc((size_t)(nslots ? nslots : 1) * sizeof(uint32_t));
	g->flags = malloc((size_t)(nslots ? nslots : 1) * sizeof(float));
	if (!g->slot_id || !g->flags) {
		snprintf(err, errlen, "shadow geometry: out of memory");
		goto fail;
	}
	if (nslots)
		memcpy(g->slot_id, runs, nslots * sizeof(uint32_t));
	for (uint32_t i = 0; i < nslots; i++)
		g->flags[i] = 1.0f;
	uint32_t prev_id = 0, prev_slot = UINT32_MAX;
	for (uint64_t q = 0; q < kept; q++) {
		if (prev_slot == UINT32_MAX || slot[q] != prev_id) {
			const uint32_t *f = bsearch(&slot[q], g->slot_id, nslots, sizeof(uint32_t),
						    cmp_u32);
			prev_id = slot[q];
			prev_slot = (uint32_t)(f - g->slot_id);
		}
		slot[q] = prev_slot + IDX_BIAS;
	}

	g->points = gpu_shadow_upload(g, (size_t)npoints * 3 * sizeof(float), P);
	g->quads = gpu_shadow_upload(g, (size_t)kept * 4 * sizeof(uint32_t), idx);
	g->slots = gpu_shadow_upload(g, (size_t)kept * sizeof(uint32_t), slot);
	g->casts = gpu_shadow_upload(g, (size_t)nslots * sizeof(float), g->flags);
	if (op)
		g->opacity = gpu_shadow_upload(g, (size_t)kept * sizeof(float), op);
	if (!g->points || !g->quads || !g->slots || !g->casts || (op && !g->opacity)) {
		snprintf(err, errlen, "shadow geometry: cannot upload %llu points and %llu "
			 "micropolygons", (unsigned long long)npoints, (unsigned long long)kept);
		goto fail;
	}
	free(op);
	free(runs);
	free(slot);
	free(idx);
	return g;

fail:
	free(op);
	free(runs);
	free(slot);
	free(idx);
	gpu_shadow_geometry_destroy(g);
	return NULL;
}

void gpu_shadow_geometry_destroy(struct gpu_shadow_geometry *g)
{
	if (!g)
		return;
	gpu_buffer_destroy(g->bvh_tris);
	gpu_buffer_destroy(g->bvh_nodes);
	gpu_buffer_destroy(g->scratch);
	gpu_buffer_destroy(g->opacity);
	gpu_buffer_destroy(g->casts);
	gpu_buffer_destroy(g->slots);
	gpu_buffer_destroy(g->quads);
	gpu_buffer_destroy(g->points);
	free(g->flags);
	free(g->slot_id);
	free(g);
}

size_t gpu_shadow_geometry_bytes(const struct gpu_shadow_geometry *g)
{
	return g ? g->bytes : 0;
}

/* ---- rendering ---- */

static bool programs(struct gpu_shadow_geometry *g)
{
	if (!g->clear)
		g->clear = gpu_program(g->ctx, clear_src, NULL);
	if (!g->raster)
		g->raster = gpu_program(g->ctx, raster_src, NULL);
	if (!g->resolve)
		g->resolve = gpu_program(g->ctx, resolve_src, NULL);
	return g->clear && g->raster && g->resolve;
}

/* Upload the per-slot cast flags when they changed. */
bool gpu_shadow_set_casts(struct gpu_shadow_geometry *g, const float *casts, uint32_t ncasts)
{
	bool changed = false;
	for (uint32_t i = 0; i < g->nslots; i++) {
		uint32_t id = g->slot_id[i];
		float f = casts && id < ncasts && casts[id] == 0.0f ? 0.0f : 1.0f;
		changed |= g->flags[i] != f;
		g->flags[i] = f;
	}
	return !changed || gpu_buffer_write(g->casts, 0, (size_t)g->nslots * sizeof(float),
					    g->flags);
}

static bool matrix_finite(const float *m)
{
	for (int i = 0; i < 16; i++)
		if (!isfinite(m[i]))
			return false;
	return true;
}

bool gpu_shadow_geometry_render(struct gpu_ctx *ctx, struct gpu_shadow_geometry *g,
				const float world_to_camera[16], const float world_to_ndc[16],
				uint32_t width, uint32_t height, enum gpu_depth_filter filter,
				const float *casts, uint32_t ncasts, struct gpu_buffer *depth)
{
	if (!ctx || !g || g->ctx != ctx || !world_to_camera || !world_to_ndc || !depth) {
		rl_log(RL_LOG_ERROR, "gpu_shadow_geometry_render: %s",
		       !ctx || !g || !depth ? "no context, geometry or depth buffer" :
		       g->ctx != ctx ? "the geometry belongs to another context" : "no matrices");
		return false;
	}
	if (!width || !height || (uint64_t)width * height > MAX_MAP_PIXELS ||
	    (filter != GPU_DEPTH_MIN && filter != GPU_DEPTH_MIDPOINT)) {
		rl_log(RL_LOG_ERROR, "gpu_shadow_geometry_render: a %ux%u map, filter %d", width,
		       height, (int)filter);
		return false;
	}
	if (!matrix_finite(world_to_camera) || !matrix_finite(world_to_ndc)) {
		rl_log(RL_LOG_ERROR, "gpu_shadow_geometry_render: a matrix is not finite");
		return false;
	}
	uint32_t npix = width * height;
	size_t need = (size_t)npix * sizeof(float);
	/* A write of nothing at the end checks that @depth holds the map. */
	char none = 0;
	if (!gpu_buffer_write(depth, need, 0, &none)) {
		rl_log(RL_LOG_ERROR, "gpu_shadow_geometry_render: the depth buffer is smaller than "
		       "%ux%u floats", width, height);
		return false;
	}
	bool midpoint = filter == GPU_DEPTH_MIDPOINT;
	if (midpoint && g->scratch_bytes < 2 * need) {
		gpu_buffer_destroy(g->scratch);
		g->bytes -= g->scratch_bytes;
		g->scratch_bytes = 0;
		g->scratch = gpu_buffer_create(ctx, 2 * need, NULL);
		if (!g->scratch)
			return false;
		g->scratch_bytes = 2 * need;
		g->bytes += g->scratch_bytes;
	}
	if (!programs(g) || !gpu_shadow_set_casts(g, casts, ncasts))
		return false;

	/* The map's camera z of a world point is column 2 of world_to_camera. */
	float zrow[4] = { world_to_camera[2], world_to_camera[6], world_to_camera[10],
			  world_to_camera[14] };
	/* Row vectors, h = [P 1] M: GLSL's M * P with M uploaded as it is (transposed). */
	struct gpu_buffer *scratch = midpoint ? g->scratch : depth;
	const struct gpu_binding out[2] = {
		{ .unit = 0, .ssbo = true, .buffer = depth },
		{ .unit = 1, .ssbo = true, .buffer = scratch },
	};
	const struct gpu_binding in[6] = {
		{ .unit = 0, .buffer = g->points },
		{ .unit = 1, .buffer = g->quads, .rgba = true },
		{ .unit = 2, .buffer = g->slots },
		{ .unit = 3, .buffer = g->casts },
		{ .unit = 0, .ssbo = true, .buffer = depth },
		{ .unit = 1, .ssbo = true, .buffer = scratch },
	};
	if (!gpu_uniform_int(g->clear, "u_midpoint", midpoint) ||
	    !gpu_dispatch(ctx, g->clear, out, 2, npix))
		return false;
	if (g->nquads) {
		if (!gpu_uniform_mat4(g->raster, "u_to_ndc", world_to_ndc) ||
		    !gpu_uniform_float(g->raster, "u_zrow", zrow, 4) ||
		    !gpu_uniform_int(g->raster, "u_width", (int)width) ||
		    !gpu_uniform_int(g->raster, "u_height", (int)height) ||
		    !gpu_uniform_int(g->raster, "u_ns", 1))
			return false;
		for (int pass = 0; pass < (midpoint ? 2 : 1); pass++)
			if (!gpu_uniform_int(g->raster, "u_pass", pass) ||
			    !gpu_dispatch(ctx, g->raster, in, 6, g->nquads))
				return false;
	}
	return !midpoint || gpu_dispatch(ctx, g->resolve, out, 2, npix);
}

/* ---- deep maps ---- */

bool gpu_shadow_geometry_has_opacity(const struct gpu_shadow_geometry *g)
{
	return g && g->opacity;
}

static bool deep_programs(struct gpu_shadow_geometry *g)
{
	if (!g->deep_clear)
		g->deep_clear = gpu_program(g->ctx, deep_clear_src, NULL);
	if (!g->deep_raster)
		g->deep_raster = gpu_program(g->ctx, deep_raster_src, NULL);
	if (!g->deep_build)
		g->deep_build = gpu_program(g->ctx, deep_build_src, NULL);
	if (!g->deep_pack)
		g->deep_pack = gpu_program(g->ctx, deep_pack_src, NULL);
	return g->deep_clear && g->deep_raster && g->deep_build && g->deep_pack;
}

/* The scratch of one deep render: freed when it ends, whatever happens. */
struct deep_scratch {
	struct gpu_buffer *count, *offsets, *events, *nodes;
	uint32_t *host;              /* npix + 1 counts, then offsets */
	size_t bytes;
};

static struct gpu_buffer *deep_buffer(struct gpu_ctx *ctx, struct deep_scratch *d, size_t bytes)
{
	size_t size = bytes < 16 ? 16 : bytes;
	struct gpu_buffer *b = gpu_buffer_create(ctx, size, NULL);
	if (b)
		d->bytes += size;
	return b;
}

static void deep_scratch_free(struct deep_scratch *d)
{
	gpu_buffer_destroy(d->nodes);
	gpu_buffer_destroy(d->events);
	gpu_buffer_destroy(d->offsets);
	gpu_buffer_destroy(d->count);
	free(d->host);
}

/* Counts to exclusive prefix sums in place (npix + 1 entries); false past @cap in all. */
static bool prefix_sums(uint32_t *c, uint32_t npix, uint64_t cap, uint64_t *total,
			uint32_t *largest)
{
	uint64_t at = 0;
	uint32_t big = 0;
	for (uint32_t p = 0; p < npix; p++) {
		uint32_t n = c[p];
		big = n > big ? n : big;
		c[p] = (uint32_t)(at <= UINT32_MAX ? at : UINT32_MAX);
		at += n;
	}
	c[npix] = (uint32_t)(at <= UINT32_MAX ? at : UINT32_MAX);
	*total = at;
	if (largest)
		*largest = big;
	return at <= cap;
}

struct gpu_buffer *gpu_shadow_geometry_render_deep(struct gpu_ctx *ctx,
						   struct gpu_shadow_geometry *g,
						   const float world_to_camera[16],
						   const float world_to_ndc[16], uint32_t width,
						   uint32_t height, const struct gpu_deep_opts *o,
						   const float *casts, uint32_t ncasts,
						   struct gpu_deep_stats *st, char *err, size_t errlen)
{
	char dummy[1];
	if (!err || !errlen) {
		err = dummy;
		errlen = sizeof(dummy);
	}
	err[0] = '\0';
	struct gpu_deep_stats none;
	if (!st)
		st = &none;
	memset(st, 0, sizeof(*st));
	if (!ctx || !g || g->ctx != ctx || !world_to_camera || !world_to_ndc || !o) {
		snprintf(err, errlen, "deep shadow map: no context, geometry, matrices or options");
		return NULL;
	}
	if (!g->opacity) {
		snprintf(err, errlen, "the shot's shadow geometry has no opacity (it was baked "
			 "before relight recorded it)");
		return NULL;
	}
	uint32_t ns = o->samples;
	if (!width || !height || (uint64_t)width * height * ns * ns > MAX_MAP_PIXELS || !ns ||
	    ns * ns > GPU_DEEP_MAX_SAMPLES || !(o->error >= 0.0f) ||
	    !(o->threshold > 0.0f && o->threshold <= 1.0f)) {
		snprintf(err, errlen, "deep shadow map: a %ux%u map of %u x %u samples per texel, "
			 "error %g, threshold %g", width, height, ns, ns, (double)o->error,
			 (double)o->threshold);
		return NULL;
	}
	if (!matrix_finite(world_to_camera) || !matrix_finite(world_to_ndc)) {
		snprintf(err, errlen, "deep shadow map: a matrix is not finite");
		return NULL;
	}
	if (!programs(g) || !deep_programs(g) || !gpu_shadow_set_casts(g, casts, ncasts)) {
		snprintf(err, errlen, "deep shadow map: its programs do not build or run");
		return NULL;
	}
	uint32_t npix = width * height;
	uint64_t cap = o->max_hits ? o->max_hits : GPU_DEEP_MAX_HITS;
	struct deep_scratch d = { 0 };
	struct gpu_buffer *map = NULL;
	d.host = malloc(((size_t)npix + 1) * sizeof(uint32_t));
	d.count = deep_buffer(ctx, &d, (size_t)npix * sizeof(uint32_t));
	d.offsets = deep_buffer(ctx, &d, ((size_t)npix + 1) * sizeof(uint32_t));
	if (!d.host || !d.count || !d.offsets) {
		snprintf(err, errlen, "deep shadow map: out of memory for a %ux%u map", width, height);
		goto done;
	}
	float zrow[4] = { world_to_camera[2], world_to_camera[6], world_to_camera[10],
			  world_to_camera[14] };
	/* the event buffer is bound for pass 0 too; the count alone sizes it later */
	struct gpu_binding b[8] = {
		{ .unit = 0, .buffer = g->points },
		{ .unit = 1, .buffer = g->quads, .rgba = true },
		{ .unit = 2, .buffer = g->slots },
		{ .unit = 3, .buffer = g->casts },
		{ .unit = 4, .buffer = g->opacity },
		{ .unit = 0, .ssbo = true, .buffer = d.count },
		{ .unit = 1, .ssbo = true, .buffer = d.offsets },
		{ .unit = 2, .ssbo = true, .buffer = d.offsets },
	};
	struct gpu_program *r = g->deep_raster;
	bool ok = gpu_dispatch(ctx, g->deep_clear, b + 5, 1, npix) &&
		  (!g->nquads ||
		   (gpu_uniform_mat4(r, "u_to_ndc", world_to_ndc) &&
		    gpu_uniform_float(r, "u_zrow", zrow, 4) &&
		    gpu_uniform_int(r, "u_width", (int)width) &&
		    gpu_uniform_int(r, "u_height", (int)height) &&
		    gpu_uniform_int(r, "u_ns", (int)ns) && gpu_uniform_int(r, "u_pass", 0) &&
		    gpu_dispatch(ctx, r, b, 8, g->nquads))) &&
		  gpu_buffer_read(d.count, 0, (size_t)npix * sizeof(uint32_t), d.host);
	if (!ok) {
		snprintf(err, errlen, "deep shadow map: counting its hits failed on the GPU");
		goto done;
	}
	if (!prefix_sums(d.host, npix, cap, &st->hits, &st->max_hits)) {
		snprintf(err, errlen, "deep shadow map: %llu hits, over the %llu a map may have on "
			 "the GPU", (unsigned long long)st->hits, (unsigned long long)cap);
		goto done;
	}
	if (st->max_hits > GPU_DEEP_MAX_TEXEL_HITS) {
		snprintf(err, errlen, "deep shadow map: a texel of %u hits, over the %u one may have "
			 "on the GPU", st->max_hits, GPU_DEEP_MAX_TEXEL_HITS);
		goto done;
	}
	d.events = deep_buffer(ctx, &d, (size_t)st->hits * 3 * sizeof(uint32_t));
	/* at most two nodes (four floats) per event */
	d.nodes = deep_buffer(ctx, &d, (size_t)st->hits * 4 * sizeof(float));
	if (!d.events || !d.nodes ||
	    !gpu_buffer_write(d.offsets, 0, ((size_t)npix + 1) * sizeof(uint32_t), d.host)) {
		snprintf(err, errlen, "deep shadow map: out of GPU memory for %llu hits",
			 (unsigned long long)st->hits);
		goto done;
	}
	b[7].buffer = d.events;
	struct gpu_binding bb[4] = {
		{ .unit = 0, .ssbo = true, .buffer = d.count },
		{ .unit = 1, .ssbo = true, .buffer = d.offsets },
		{ .unit = 2, .ssbo = true, .buffer = d.events },
		{ .unit = 3, .ssbo = true, .buffer = d.nodes },
	};
	struct gpu_program *bd = g->deep_build;
	ok = gpu_dispatch(ctx, g->deep_clear, bb, 1, npix) &&
	     (!g->nquads ||
	      (gpu_uniform_int(r, "u_pass", 1) && gpu_dispatch(ctx, r, b, 8, g->nquads))) &&
	     gpu_uniform_int(bd, "u_samples", (int)(ns * ns)) &&
	     gpu_uniform_float(bd, "u_error", &o->error, 1) &&
	     gpu_uniform_float(bd, "u_threshold", &o->threshold, 1) &&
	     gpu_dispatch(ctx, bd, bb, 4, npix) &&
	     gpu_buffer_read(d.count, 0, (size_t)npix * sizeof(uint32_t), d.host);
	if (!ok) {
		snprintf(err, errlen, "deep shadow map: sorting and compressing its hits failed on "
			 "the GPU");
		goto done;
	}
	if (!prefix_sums(d.host, npix, GPU_DEEP_MAX_NODES, &st->nodes, NULL)) {
		snprintf(err, errlen, "deep shadow map: %llu nodes, over the GPU's %u",
			 (unsigned long long)st->nodes, GPU_DEEP_MAX_NODES);
		goto done;
	}
	/* the offsets in the map's own format: floats, exact below 2^24 */
	size_t nmap = (size_t)npix + 1 + 2 * (size_t)st->nodes;
	float *off = malloc(((size_t)npix + 1) * sizeof(float));
	map = off ? gpu_buffer_create(ctx, nmap * sizeof(float), NULL) : NULL;
	for (uint32_t p = 0; off && p <= npix; p++)
		off[p] = (float)d.host[p];
	ok = map && gpu_buffer_write(map, 0, ((size_t)npix + 1) * sizeof(float), off);
	free(off);
	/* the pack pass takes each texel's node count from the build's count buffer */
	struct gpu_binding pb[5] = {
		bb[0], bb[1], bb[2], bb[3], { .unit = 4, .ssbo = true, .buffer = map },
	};
	ok = ok && gpu_dispatch(ctx, g->deep_pack, pb, 5, npix);
	if (!ok) {
		snprintf(err, errlen, "deep shadow map: out of GPU memory for %llu nodes",
			 (unsigned long long)st->nodes);
		gpu_buffer_destroy(map);
		map = NULL;
		goto done;
	}
	st->bytes = nmap * sizeof(float);
done:
	st->scratch_bytes = d.bytes;
	deep_scratch_free(&d);
	return map;
}

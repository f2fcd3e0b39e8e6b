/*
 * The GLSL of ray-traced shadows on the GPU: the traversal of a shot's
 * shadow-geometry hierarchy (glsl.h, "Ray-traced shadows"). gpu/shadowbvh.c
 * writes the layout this code reads.
 *
 * Traversal. A stack of node indices (a node's first child follows it, so
 * only the second is pushed); a ray is tested against a node's box with the
 * slab method on the reciprocal direction, whose zero components are nudged
 * to +-1e-30 so that no 0 * inf appears. Every triangle of a leaf whose
 * object casts is intersected (Moller-Trumbore, in float), and a hit at a
 * distance in (0, tmax) multiplies the transmission by 1 - opacity (its
 * edges widened by 1e-6 in barycentric terms, so that a ray through the edge
 * two triangles share, which float rounding could let pass between them,
 * hits at least one, as Embree's robust mode ensures on the CPU): the
 * product is the same in any order, so the hits are not sorted, and the
 * walk stops as soon as nothing gets through (an opaque hit). A stack that
 * would overflow (deeper than the builder ever makes) gives 0 light: a
 * shadow too many, never a light leak.
 */
#include "glsl.h"

const char sl_glsl_bvh_source[] =
	"const uint RL_BVH_BIAS = 0x00800000u;\n"
	"const float RL_BVH_EDGE = 1e-6;\n"
	"float rl_bvh_transmission(samplerBuffer nodes, samplerBuffer tris, samplerBuffer casts,\n"
	"                          vec3 org, vec3 dir, float tmax)\n"
	"{\n"
	"	if (!(tmax > 0.0) || textureSize(nodes) == 0)\n"
	"		return 1.0;\n"
	"	vec3 d = dir;\n"
	"	for (int k = 0; k < 3; k++)\n"
	"		if (abs(d[k]) < 1e-30)\n"
	"			d[k] = d[k] < 0.0 ? -1e-30 : 1e-30;\n"
	"	vec3 inv = 1.0 / d;\n"
	"	float trans = 1.0;\n"
	"	uint stack[40];\n"
	"	int top = 0;\n"
	"	uint node = 0u;\n"
	"	for (;;) {\n"
	"		vec4 lo = texelFetch(nodes, int(2u * node));\n"
	"		vec4 hi = texelFetch(nodes, int(2u * node + 1u));\n"
	"		vec3 t0 = (lo.xyz - org) * inv, t1 = (hi.xyz - org) * inv;\n"
	"		vec3 tn = min(t0, t1), tf = max(t0, t1);\n"
	"		float enter = max(max(tn.x, tn.y), max(tn.z, 0.0));\n"
	"		float leave = min(min(tf.x, tf.y), min(tf.z, tmax));\n"
	"		uint a = floatBitsToUint(lo.w) - RL_BVH_BIAS;\n"
	"		uint count = floatBitsToUint(hi.w) - RL_BVH_BIAS;\n"
	"		if (enter <= leave * 1.00001) {\n"
	"			if (count == 0u) {\n"
	"				if (top == 40)\n"
	"					return 0.0;\n"
	"				stack[top++] = a;\n"
	"				node = node + 1u;\n"
	"				continue;\n"
	"			}\n"
	"			for (uint i = a; i < a + count; i++) {\n"
	"				vec4 v0 = texelFetch(tris, int(3u * i));\n"
	"				vec4 e1 = texelFetch(tris, int(3u * i + 1u));\n"
	"				vec4 e2 = texelFetch(tris, int(3u * i + 2u));\n"
	"				int slot = int(floatBitsToUint(v0.w) - RL_BVH_BIAS);\n"
	"				if (texelFetch(casts, slot).r == 0.0)\n"
	"					continue;\n"
	"				vec3 p = cross(dir, e2.xyz);\n"
	"				float det = dot(e1.xyz, p);\n"
	"				if (det == 0.0)\n"
	"					continue;\n"
	"				float f = 1.0 / det;\n"
	"				vec3 s = org - v0.xyz;\n"
	"				float u = f * dot(s, p);\n"
	"				if (u < -RL_BVH_EDGE || u > 1.0 + RL_BVH_EDGE)\n"
	"					continue;\n"
	"				vec3 q = cross(s, e1.xyz);\n"
	"				float v = f * dot(dir, q);\n"
	"				if (v < -RL_BVH_EDGE || u + v > 1.0 + RL_BVH_EDGE)\n"
	"					continue;\n"
	"				float t = f * dot(e2.xyz, q);\n"
	"				if (t > 0.0 && t < tmax) {\n"
	"					trans *= 1.0 - e1.w;\n"
	"					if (trans <= 0.0)\n"
	"						return 0.0;\n"
	"				}\n"
	"			}\n"
	"		}\n"
	"		if (top == 0)\n"
	"			break;\n"
	"		node = stack[--top];\n"
	"	}\n"
	"	return trans;\n"
	"}\n";

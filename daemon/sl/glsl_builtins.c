/*
 * GLSL generation, the built-in library: RSL's built-in functions as GLSL
 * with the grid interpreter's numerics (exec_builtins.c, mathlib.c,
 * noise.c): the same special cases, clamps and domain rules, so that no
 * result is NaN or Inf and the two agree to float rounding. Noise uses the
 * same 32-bit integer hash, bit for bit.
 *
 * What the GPU cannot do is an error at the call: derivatives (Du, Dv,
 * Deriv, area, calculatenormal, two-argument filterstep) except on
 * derivative stencils (slice->input_steps), random(), map files except on
 * stencils (shadow maps here; texture and environment maps with
 * glsl_texmap.c's filters), string building (format, concat), host queries
 * (attribute, option, rendererinfo, depth). printf is dropped with a
 * warning.
 *
 * On derivative stencils a derivative is the difference between a value
 * and its copies moved one grid step along u and v (glsl.c), taken with the
 * interpreter's arithmetic: Du(f) = (f_u - f) / du, and the changes over
 * one step themselves (f_u - f) for filter regions, area() and filterstep()
 * widths. shadow() is render/texture.c's reyes_tex_shadow: the corners in
 * float, the transforms as sl_xform_point does them (double, rounded to
 * float), the map's NDC and the sample grid in double, the same jitter hash.
 * "precise" keeps the compiler from fusing multiplies and adds that the
 * CPU rounds apart.
 */
#include "glsl_impl.h"
#include "mathlib.h"

#include <ctype.h>
#include <regex.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* ------------------------------------------------------------------------ */
/* Hand-written GLSL                                                         */

static const char core_glsl[] =
	"const float RL_FLT_MAX = 3.40282347e+38;\n"
	"const float RL_FLT_MIN = 1.17549435e-38;\n"
	"float rl_c(float x) { return clamp(x, -RL_FLT_MAX, RL_FLT_MAX); }\n"
	"vec3 rl_c(vec3 x) { return clamp(x, vec3(-RL_FLT_MAX), vec3(RL_FLT_MAX)); }\n"
	"mat4 rl_c(mat4 m) {\n"
	"\tfor (int i = 0; i < 4; i++) m[i] = clamp(m[i], vec4(-RL_FLT_MAX), vec4(RL_FLT_MAX));\n"
	"\treturn m;\n"
	"}\n"
	"float rl_fin(float x) { return isnan(x) ? 0.0 : rl_c(x); }\n"
	"vec3 rl_fin(vec3 x) { return vec3(rl_fin(x.x), rl_fin(x.y), rl_fin(x.z)); }\n"
	"mat4 rl_fin(mat4 m) {\n"
	"\tfor (int i = 0; i < 4; i++)\n"
	"\t\tfor (int j = 0; j < 4; j++) m[i][j] = rl_fin(m[i][j]);\n"
	"\treturn m;\n"
	"}\n"
	"float rl_div(float p, float q) { return q == 0.0 ? 0.0 : rl_fin(p / q); }\n"
	"vec3 rl_div(vec3 p, vec3 q) {\n"
	"\treturn vec3(rl_div(p.x, q.x), rl_div(p.y, q.y), rl_div(p.z, q.z));\n"
	"}\n"
	"mat4 rl_div(mat4 p, mat4 q) {\n"
	"\tfor (int i = 0; i < 4; i++)\n"
	"\t\tfor (int j = 0; j < 4; j++) p[i][j] = rl_div(p[i][j], q[i][j]);\n"
	"\treturn p;\n"
	"}\n"
	"mat4 rl_fill(float x) { return mat4(vec4(x), vec4(x), vec4(x), vec4(x)); }\n";

/* Float forms; the vec3 forms are generated componentwise (math_fns). */
static const char math_glsl[] =
	"float rl_radians(float x) { return rl_c(x * 0.0174532924); }\n"
	"float rl_degrees(float x) { return rl_c(x * 57.2957764); }\n"
	"float rl_sin(float x) { return sin(x); }\n"
	"float rl_cos(float x) { return cos(x); }\n"
	"float rl_tan(float x) { return rl_fin(tan(x)); }\n"
	/* Arc tangents to float precision (some drivers' atan and asin are far coarser):
	 * reduced to |x| <= tan(pi/8), then an odd polynomial. */
	"float rl_atan(float z) {\n"
	"\tfloat x = abs(z), y = 0.0;\n"
	"\tif (x > 2.41421356) {\n"
	"\t\ty = 1.57079637;\n"
	"\t\tx = -1.0 / x;\n"
	"\t} else if (x > 0.414213562) {\n"
	"\t\ty = 0.785398163;\n"
	"\t\tx = (x - 1.0) / (x + 1.0);\n"
	"\t}\n"
	"\tfloat q = x * x;\n"
	"\ty += (((0.0805374449538 * q - 0.138776856032) * q + 0.199777106478) * q -\n"
	"\t\t0.333329491539) * q * x + x;\n"
	"\treturn z < 0.0 ? -y : y;\n"
	"}\n"
	"float rl_atan2(float y, float x) {\n"
	"\tif (x == 0.0) return y > 0.0 ? 1.57079637 : y < 0.0 ? -1.57079637 : 0.0;\n"
	"\tfloat a = rl_atan(y / x);\n"
	"\tif (x < 0.0) a += y >= 0.0 ? 3.14159274 : -3.14159274;\n"
	"\treturn a;\n"
	"}\n"
	"float rl_asin(float x) {\n"
	"\tx = clamp(x, -1.0, 1.0);\n"
	"\treturn rl_atan2(x, sqrt((1.0 - x) * (1.0 + x)));\n"
	"}\n"
	"float rl_acos(float x) {\n"
	"\tx = clamp(x, -1.0, 1.0);\n"
	"\treturn rl_atan2(sqrt((1.0 - x) * (1.0 + x)), x);\n"
	"}\n"
	"float rl_sinh(float x) { return rl_fin(sinh(x)); }\n"
	"float rl_cosh(float x) { return rl_fin(cosh(x)); }\n"
	"float rl_tanh(float x) { return tanh(clamp(x, -15.0, 15.0)); }\n"
	"float rl_pow(float x, float y) {\n"
	"\tif (y == 0.0) return 1.0;\n"
	"\tif (x == 0.0) return 0.0;\n"
	"\tif (x < 0.0 && floor(y) != y) return 0.0;\n"
	"\tfloat r = exp2(y * log2(abs(x)));\n"
	"\tif (x < 0.0 && mod(y, 2.0) != 0.0) r = -r;\n"
	"\treturn rl_fin(r);\n"
	"}\n"
	"float rl_exp(float x) { return rl_c(exp(x)); }\n"
	"float rl_sqrt(float x) { return x > 0.0 ? sqrt(x) : 0.0; }\n"
	"float rl_isqrt(float x) { return x > 0.0 ? rl_c(inversesqrt(x)) : 0.0; }\n"
	"float rl_log(float x) { return log(x >= RL_FLT_MIN ? x : RL_FLT_MIN); }\n"
	"float rl_logb(float x, float b) {\n"
	"\tif (!(b > 0.0) || b == 1.0) return 0.0;\n"
	"\treturn rl_fin(rl_log(x) / rl_log(b));\n"
	"}\n"
	"float rl_mod(float a, float b) {\n"
	"\tif (b == 0.0) return 0.0;\n"
	"\tfloat r = rl_fin(a - b * floor(a / b));\n"
	"\tif ((b > 0.0 && r >= b) || (b < 0.0 && r <= b)) r = 0.0;\n"
	"\treturn r;\n"
	"}\n"
	"float rl_abs(float x) { return abs(x); }\n"
	"float rl_sign(float x) { return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0; }\n"
	"float rl_min(float a, float b) { return min(a, b); }\n"
	"float rl_max(float a, float b) { return max(a, b); }\n"
	"float rl_clamp(float x, float lo, float hi) { return min(max(x, lo), hi); }\n"
	"float rl_mix(float a, float b, float t) { return rl_fin((1.0 - t) * a + t * b); }\n"
	"float rl_floor(float x) { return floor(x); }\n"
	"float rl_ceil(float x) { return ceil(x); }\n"
	"float rl_round(float x) {\n"
	"\tfloat t = trunc(x);\n"
	"\treturn abs(x - t) >= 0.5 ? t + sign(x) : t;\n"
	"}\n"
	"float rl_step(float e, float x) { return x < e ? 0.0 : 1.0; }\n"
	"float rl_smoothstep(float e0, float e1, float x) {\n"
	"\tif (e0 == e1) return x < e0 ? 0.0 : 1.0;\n"
	"\tfloat t = clamp(rl_fin((x - e0) / (e1 - e0)), 0.0, 1.0);\n"
	"\treturn t * t * (3.0 - 2.0 * t);\n"
	"}\n";

/* The componentwise functions of math_glsl and their arities. */
static const struct { const char *name; int arity; } math_fns[] = {
	{ "rl_radians", 1 }, { "rl_degrees", 1 }, { "rl_sin", 1 }, { "rl_cos", 1 },
	{ "rl_tan", 1 }, { "rl_asin", 1 }, { "rl_acos", 1 }, { "rl_atan", 1 },
	{ "rl_atan2", 2 }, { "rl_sinh", 1 }, { "rl_cosh", 1 }, { "rl_tanh", 1 },
	{ "rl_pow", 2 }, { "rl_exp", 1 }, { "rl_sqrt", 1 }, { "rl_isqrt", 1 },
	{ "rl_log", 1 }, { "rl_logb", 2 }, { "rl_mod", 2 }, { "rl_abs", 1 },
	{ "rl_sign", 1 }, { "rl_min", 2 }, { "rl_max", 2 }, { "rl_clamp", 3 },
	{ "rl_mix", 3 }, { "rl_floor", 1 }, { "rl_ceil", 1 }, { "rl_round", 1 },
	{ "rl_step", 2 }, { "rl_smoothstep", 3 },
};

static const char aidx_glsl[] =
	"int rl_aidx(float f, int len) {\n"
	"\tif (f > -1.0 && f < float(len)) return int(f);\n"
	"\treturn f >= float(len) ? len - 1 : 0;\n"
	"}\n";

static const char cidx_glsl[] =
	"int rl_cidx(float f, int mx) { return f >= 0.0 ? (f <= float(mx) ? int(f) : mx) : 0; }\n";

/* Lengths scaled by the largest component: squares of big components would overflow. */
static const char vec_glsl[] =
	"float rl_length(vec3 v) {\n"
	"\tfloat m = max(max(abs(v.x), abs(v.y)), abs(v.z));\n"
	"\tif (!(m > 0.0)) return 0.0;\n"
	"\treturn rl_c(m * length(v / m));\n"
	"}\n"
	"vec3 rl_normalize(vec3 v) {\n"
	"\tfloat m = max(max(abs(v.x), abs(v.y)), abs(v.z));\n"
	"\tif (!(m > 0.0)) return vec3(0.0);\n"
	"\tvec3 u = v / m;\n"
	"\tfloat l = length(u);\n"
	"\tif (!(m * l >= RL_FLT_MIN)) return vec3(0.0);\n"
	"\treturn u / l;\n"
	"}\n";

/*
 * Gauss-Jordan with partial pivoting. rowscale: rows first scaled to unit
 * maximum and a pivot below 1e-12 is singular (transforms); else a pivot
 * below 1e-10 of the largest element is (matrix division).
 */
static const char inverse_glsl[] =
	"bool rl_inv(mat4 m, bool rowscale, out mat4 r) {\n"
	"\tfloat a[32];\n"
	"\tfloat big = 0.0;\n"
	"\tr = mat4(1.0);\n"
	"\tfor (int i = 0; i < 4; i++) {\n"
	"\t\tfloat rmax = max(max(abs(m[i][0]), abs(m[i][1])), max(abs(m[i][2]), abs(m[i][3])));\n"
	"\t\tif (rowscale && !(rmax > 0.0)) return false;\n"
	"\t\tbig = max(big, rmax);\n"
	"\t\tfor (int j = 0; j < 4; j++) {\n"
	"\t\t\ta[i * 8 + j] = rowscale ? m[i][j] / rmax : m[i][j];\n"
	"\t\t\ta[i * 8 + 4 + j] = i == j ? (rowscale ? 1.0 / rmax : 1.0) : 0.0;\n"
	"\t\t}\n"
	"\t}\n"
	"\tif (!(big > 0.0)) return false;\n"
	"\tfloat tol = rowscale ? 1e-12 : big * 1e-10;\n"
	"\tfor (int c = 0; c < 4; c++) {\n"
	"\t\tint piv = c;\n"
	"\t\tfor (int i = c + 1; i < 4; i++)\n"
	"\t\t\tif (abs(a[i * 8 + c]) > abs(a[piv * 8 + c])) piv = i;\n"
	"\t\tif (!(abs(a[piv * 8 + c]) > tol)) return false;\n"
	"\t\tif (piv != c)\n"
	"\t\t\tfor (int k = 0; k < 8; k++) {\n"
	"\t\t\t\tfloat t = a[c * 8 + k];\n"
	"\t\t\t\ta[c * 8 + k] = a[piv * 8 + k];\n"
	"\t\t\t\ta[piv * 8 + k] = t;\n"
	"\t\t\t}\n"
	"\t\tfloat inv = 1.0 / a[c * 8 + c];\n"
	"\t\tfor (int k = 0; k < 8; k++) a[c * 8 + k] *= inv;\n"
	"\t\tfor (int i = 0; i < 4; i++) {\n"
	"\t\t\tfloat f = a[i * 8 + c];\n"
	"\t\t\tif (i == c || f == 0.0) continue;\n"
	"\t\t\tfor (int k = 0; k < 8; k++) a[i * 8 + k] -= f * a[c * 8 + k];\n"
	"\t\t}\n"
	"\t}\n"
	"\tmat4 t;\n"
	"\tfor (int i = 0; i < 4; i++)\n"
	"\t\tfor (int j = 0; j < 4; j++) {\n"
	"\t\t\tfloat v = a[i * 8 + 4 + j];\n"
	"\t\t\tif (!(abs(v) <= RL_FLT_MAX)) return false;\n"
	"\t\t\tt[i][j] = v;\n"
	"\t\t}\n"
	"\tr = t;\n"
	"\treturn true;\n"
	"}\n"
	"mat4 rl_inverse(mat4 m) {\n"
	"\tmat4 r;\n"
	"\tif (!rl_inv(m, true, r)) r = mat4(1.0);\n"
	"\treturn r;\n"
	"}\n";

/* a / b = a * inverse(b); a singular b gives the zero matrix. */
static const char matdiv_glsl[] =
	"mat4 rl_matdiv(mat4 a, mat4 b) {\n"
	"\tmat4 bi;\n"
	"\tif (!rl_inv(b, false, bi)) bi = mat4(0.0);\n"
	"\treturn rl_c(bi * a);\n"
	"}\n";

static const char xform_glsl[] =
	"vec3 rl_xpoint(mat4 m, vec3 p) {\n"
	"\tvec4 o = m * vec4(p, 1.0);\n"
	"\tif (o.w != 0.0 && o.w != 1.0) o.xyz = o.xyz / o.w;\n"
	"\treturn rl_fin(o.xyz);\n"
	"}\n"
	"vec3 rl_xvector(mat4 m, vec3 v) { return rl_fin(mat3(m) * v); }\n"
	"vec3 rl_xnormal(mat4 m, vec3 n) {\n"
	"\tvec3 a0 = m[0].xyz, a1 = m[1].xyz, a2 = m[2].xyz;\n"
	"\tvec3 c0 = cross(a1, a2), c1 = cross(a2, a0), c2 = cross(a0, a1);\n"
	"\tfloat det = dot(a0, c0);\n"
	"\tfloat s = abs(det) > 1e-30 ? 1.0 / det : 1.0;\n"
	"\treturn rl_fin((n.x * c0 + n.y * c1 + n.z * c2) * s);\n"
	"}\n";

/* noise.c, statement for statement. */
static const char noise_glsl[] =
	"uint rl_hmix(uint h) {\n"
	"\th ^= h >> 16;\n"
	"\th *= 0x7feb352du;\n"
	"\th ^= h >> 15;\n"
	"\th *= 0x846ca68bu;\n"
	"\th ^= h >> 16;\n"
	"\treturn h;\n"
	"}\n"
	"uint rl_hlat(int dim, ivec4 ip, uint seed) {\n"
	"\tuint h = rl_hmix(seed * 0x9e3779b9u + 0x632be5abu);\n"
	"\tfor (int d = 0; d < dim; d++) h = rl_hmix(h ^ uint(ip[d]));\n"
	"\treturn h;\n"
	"}\n"
	"float rl_hunit(uint h) { return float(h >> 8) * (1.0 / 16777216.0); }\n"
	"int rl_lattice(float x, out float frac) {\n"
	"\tif (isnan(x)) x = 0.0;\n"
	"\tx = clamp(x, -1073741824.0, 1073741824.0);\n"
	"\tfloat fl = floor(x);\n"
	"\tfrac = x - fl;\n"
	"\treturn int(fl);\n"
	"}\n"
	"int rl_wrap(int i, int period) {\n"
	"\tif (period <= 0) return i;\n"
	"\tif (i >= 0) return int(uint(i) % uint(period));\n"
	"\treturn period - 1 - int(uint(-(i + 1)) % uint(period));\n"
	"}\n"
	"float rl_fade(float t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }\n"
	"float rl_grad(int dim, uint h, vec4 f) {\n"
	"\tif (dim == 1) return (rl_hunit(h) * 2.0 - 1.0) * f.x;\n"
	"\tif (dim == 2) {\n"
	"\t\tuint k = h >> 29;\n"
	"\t\tif (k < 4u) {\n"
	"\t\t\tfloat g = (k & 1u) != 0u ? f.y : f.x;\n"
	"\t\t\treturn (k & 2u) != 0u ? -g : g;\n"
	"\t\t}\n"
	"\t\tconst float r = 0.70710678;\n"
	"\t\treturn ((k & 1u) != 0u ? -f.x : f.x) * r + ((k & 2u) != 0u ? -f.y : f.y) * r;\n"
	"\t}\n"
	"\tif (dim == 3) {\n"
	"\t\tuint k = h >> 28;\n"
	"\t\tfloat a = k < 8u ? f.x : f.y;\n"
	"\t\tfloat b = k < 4u ? f.y : (k == 12u || k == 14u) ? f.x : f.z;\n"
	"\t\treturn ((k & 1u) != 0u ? -a : a) + ((k & 2u) != 0u ? -b : b);\n"
	"\t}\n"
	"\tuint k = h >> 27;\n"
	"\tuint zero = k >> 3;\n"
	"\tfloat s = 0.0;\n"
	"\tuint bit = 0u;\n"
	"\tfor (uint d = 0u; d < 4u; d++) {\n"
	"\t\tif (d == zero) continue;\n"
	"\t\ts += ((k >> bit) & 1u) != 0u ? -f[d] : f[d];\n"
	"\t\tbit++;\n"
	"\t}\n"
	"\treturn s;\n"
	"}\n"
	"float rl_noise(int dim, vec4 p, ivec4 per, uint seed) {\n"
	"\tconst float scale[5] = float[5](0.0, 2.0, 1.41421356, 0.95, 0.8);\n"
	"\tivec4 i0 = ivec4(0);\n"
	"\tvec4 f = vec4(0.0), w = vec4(0.0);\n"
	"\tfor (int d = 0; d < dim; d++) {\n"
	"\t\tfloat fr;\n"
	"\t\ti0[d] = rl_lattice(p[d], fr);\n"
	"\t\tf[d] = fr;\n"
	"\t\tw[d] = rl_fade(fr);\n"
	"\t}\n"
	"\tfloat v[16];\n"
	"\tint nc = 1 << dim;\n"
	"\tfor (int c = 0; c < nc; c++) {\n"
	"\t\tivec4 ic = ivec4(0);\n"
	"\t\tvec4 off = vec4(0.0);\n"
	"\t\tfor (int d = 0; d < dim; d++) {\n"
	"\t\t\tint bit = (c >> d) & 1;\n"
	"\t\t\tic[d] = rl_wrap(i0[d] + bit, per[d]);\n"
	"\t\t\toff[d] = f[d] - float(bit);\n"
	"\t\t}\n"
	"\t\tv[c] = rl_grad(dim, rl_hlat(dim, ic, seed), off);\n"
	"\t}\n"
	"\tfor (int d = 0; d < dim; d++) {\n"
	"\t\tnc >>= 1;\n"
	"\t\tfor (int k = 0; k < nc; k++) v[k] = v[2 * k] + w[d] * (v[2 * k + 1] - v[2 * k]);\n"
	"\t}\n"
	"\treturn clamp(0.5 + 0.5 * scale[dim] * v[0], 0.0, 1.0);\n"
	"}\n"
	"float rl_cellnoise(int dim, vec4 p, uint seed) {\n"
	"\tivec4 ip = ivec4(0);\n"
	"\tfor (int d = 0; d < dim; d++) {\n"
	"\t\tfloat fr;\n"
	"\t\tip[d] = rl_lattice(p[d], fr);\n"
	"\t}\n"
	"\treturn rl_hunit(rl_hlat(dim, ip, seed + 0x8000u));\n"
	"}\n"
	"int rl_nperiod(float p) {\n"
	"\tif (!(p >= 0.5) || p > 1073741824.0) return 0;\n"
	"\treturn int(floor(p + 0.5));\n"
	"}\n";

static const char geom_glsl[] =
	"float rl_ptlined(vec3 p0, vec3 p1, vec3 q) {\n"
	"\tvec3 d = p1 - p0, w = q - p0;\n"
	"\tfloat dd = dot(d, d);\n"
	"\tfloat t = dd > 0.0 ? dot(w, d) / dd : 0.0;\n"
	"\tt = clamp(t, 0.0, 1.0);\n"
	"\treturn rl_length(w - t * d);\n"
	"}\n"
	"vec3 rl_faceforward(vec3 N, vec3 I, vec3 Nref) { return dot(I, Nref) > 0.0 ? -N : N; }\n"
	"vec3 rl_reflect(vec3 I, vec3 N) { return rl_fin(I - 2.0 * dot(I, N) * N); }\n"
	"vec3 rl_refract(vec3 I, vec3 N, float eta) {\n"
	"\tfloat idn = dot(I, N);\n"
	"\tfloat k = 1.0 - eta * eta * (1.0 - idn * idn);\n"
	"\tif (!(k >= 0.0)) return vec3(0.0);\n"
	"\treturn rl_fin(eta * I - (eta * idn + sqrt(k)) * N);\n"
	"}\n"
	"mat4 rl_rotation(float angle, vec3 axis) {\n"
	"\tmat4 m = mat4(1.0);\n"
	"\tvec3 u = rl_normalize(axis);\n"
	"\tif (dot(u, u) == 0.0) return m;\n"
	"\tfloat c = cos(angle), s = sin(angle), t = 1.0 - c;\n"
	"\tfloat x = u.x, y = u.y, z = u.z;\n"
	"\tm[0] = vec4(t * x * x + c, t * x * y + s * z, t * x * z - s * y, 0.0);\n"
	"\tm[1] = vec4(t * x * y - s * z, t * y * y + c, t * y * z + s * x, 0.0);\n"
	"\tm[2] = vec4(t * x * z + s * y, t * y * z - s * x, t * z * z + c, 0.0);\n"
	"\treturn m;\n"
	"}\n"
	"vec3 rl_rotate(vec3 q, float angle, vec3 p0, vec3 p1) {\n"
	"\tmat4 m = rl_rotation(angle, p1 - p0);\n"
	"\treturn rl_fin(rl_fin(mat3(m) * (q - p0)) + p0);\n"
	"}\n"
	"mat4 rl_translation(vec3 t) {\n"
	"\tmat4 m = mat4(1.0);\n"
	"\tm[3] = vec4(t, 1.0);\n"
	"\treturn m;\n"
	"}\n"
	"mat4 rl_scaling(vec3 s) { return mat4(vec4(s.x, 0.0, 0.0, 0.0), vec4(0.0, s.y, 0.0, 0.0),\n"
	"\tvec4(0.0, 0.0, s.z, 0.0), vec4(0.0, 0.0, 0.0, 1.0)); }\n";

static const char fresnel_glsl[] =
	"void rl_fresnel(vec3 I, vec3 N, float eta, out float Kr, out float Kt, out vec3 R,\n"
	"\t\tout vec3 T) {\n"
	"\tvec3 i = rl_normalize(I), n = rl_normalize(N);\n"
	"\tR = I;\n"
	"\tT = I;\n"
	"\tKr = 0.0;\n"
	"\tKt = 1.0;\n"
	"\tif (dot(i, i) == 0.0 || dot(n, n) == 0.0 || !(eta > 0.0)) return;\n"
	"\tfloat idn = dot(i, n);\n"
	"\tif (idn > 0.0) {\n"
	"\t\tn = -n;\n"
	"\t\tidn = -idn;\n"
	"\t}\n"
	"\tR = rl_reflect(i, n);\n"
	"\tT = rl_refract(i, n, eta);\n"
	"\tfloat c = -idn, e = 1.0 / eta;\n"
	"\tfloat g2 = e * e + c * c - 1.0;\n"
	"\tif (g2 < 0.0) {\n"
	"\t\tKr = 1.0;\n"
	"\t\tKt = 0.0;\n"
	"\t\treturn;\n"
	"\t}\n"
	"\tfloat g = sqrt(g2), gpc = g + c, gmc = g - c;\n"
	"\tfloat kr = 1.0;\n"
	"\tif (gpc > 0.0) {\n"
	"\t\tfloat a = gmc / gpc, den = c * gmc + 1.0;\n"
	"\t\tfloat b = den != 0.0 ? (c * gpc - 1.0) / den : 0.0;\n"
	"\t\tkr = 0.5 * a * a * (1.0 + b * b);\n"
	"\t}\n"
	"\tKr = clamp(kr, 0.0, 1.0);\n"
	"\tKt = 1.0 - Kr;\n"
	"}\n";

/* The exponent's numerator, 8.0 (PRMan's model) or 1.0 (the RiSpec's), is printed in
 * (sl_glsl_emit_helpers). */
static const char specbrdf_glsl[] =
	"float rl_specbrdf(vec3 L, vec3 N, vec3 V, float rough) {\n"
	"\tvec3 h = rl_normalize(L + V);\n"
	"\tfloat d = dot(N, h);\n"
	"\tif (!(d > 0.0)) return 0.0;\n"
	"\tif (!(rough > 1e-6)) rough = 1e-6;\n"
	"\treturn rl_pow(d, %s / rough);\n"
	"}\n";

/* Is @L within @angle of @axis? A zero L or axis is; angle >= pi (the float above) always. */
static const char cone_glsl[] =
	"bool rl_in_cone(vec3 L, vec3 ax, float angle) {\n"
	"\tfloat ll = dot(L, L), aa = dot(ax, ax);\n"
	"\tif (ll == 0.0 || aa == 0.0 || angle >= 3.14159274) return true;\n"
	"\tif (!(angle >= 0.0)) return false;\n"
	"\treturn dot(L, ax) / (sqrt(ll) * sqrt(aa)) >= cos(angle) - 1e-7;\n"
	"}\n";

/* mathlib.c's nonlinear color spaces; the linear ones are matrices (color_matrix()). */
static const char color_glsl[] =
	"float rl_hue(vec3 c, float mx, float d) {\n"
	"\tfloat h;\n"
	"\tif (mx == c.r) h = (c.g - c.b) / d;\n"
	"\telse if (mx == c.g) h = 2.0 + (c.b - c.r) / d;\n"
	"\telse h = 4.0 + (c.r - c.g) / d;\n"
	"\th /= 6.0;\n"
	"\tif (h < 0.0) h += 1.0;\n"
	"\tif (h >= 1.0) h -= 1.0;\n"
	"\treturn rl_fin(h);\n"
	"}\n"
	"vec3 rl_rgb_hsv(vec3 c) {\n"
	"\tfloat mx = max(c.r, max(c.g, c.b)), mn = min(c.r, min(c.g, c.b)), d = mx - mn;\n"
	"\treturn vec3(d > 0.0 ? rl_hue(c, mx, d) : 0.0,\n"
	"\t\t(mx > 0.0 && d > 0.0) ? rl_fin(d / mx) : 0.0, mx);\n"
	"}\n"
	"vec3 rl_hsv_rgb(vec3 c) {\n"
	"\tfloat h = c.x - floor(c.x), s = c.y, v = c.z;\n"
	"\tfloat h6 = h * 6.0;\n"
	"\tif (!(h6 >= 0.0 && h6 < 6.0)) h6 = 0.0;\n"
	"\tint sector = int(h6);\n"
	"\tfloat f = h6 - float(sector);\n"
	"\tfloat p = v * (1.0 - s), q = v * (1.0 - s * f), t = v * (1.0 - s * (1.0 - f));\n"
	"\tif (sector == 0) return vec3(v, t, p);\n"
	"\tif (sector == 1) return vec3(q, v, p);\n"
	"\tif (sector == 2) return vec3(p, v, t);\n"
	"\tif (sector == 3) return vec3(p, q, v);\n"
	"\tif (sector == 4) return vec3(t, p, v);\n"
	"\treturn vec3(v, p, q);\n"
	"}\n"
	"vec3 rl_rgb_hsl(vec3 c) {\n"
	"\tfloat mx = max(c.r, max(c.g, c.b)), mn = min(c.r, min(c.g, c.b));\n"
	"\tfloat d = mx - mn, l = 0.5 * (mx + mn);\n"
	"\tif (!(d > 0.0)) return vec3(0.0, 0.0, l);\n"
	"\tfloat den = l <= 0.5 ? mx + mn : 2.0 - mx - mn;\n"
	"\treturn vec3(rl_hue(c, mx, d), den != 0.0 ? rl_fin(d / den) : 0.0, l);\n"
	"}\n"
	"float rl_hsl_ch(float p, float q, float h) {\n"
	"\th -= floor(h);\n"
	"\tif (h < 1.0 / 6.0) return p + (q - p) * 6.0 * h;\n"
	"\tif (h < 0.5) return q;\n"
	"\tif (h < 2.0 / 3.0) return p + (q - p) * (2.0 / 3.0 - h) * 6.0;\n"
	"\treturn p;\n"
	"}\n"
	"vec3 rl_hsl_rgb(vec3 c) {\n"
	"\tfloat h = c.x, s = c.y, l = c.z;\n"
	"\tif (s == 0.0) return vec3(l);\n"
	"\tfloat q = l < 0.5 ? l * (1.0 + s) : l + s - l * s;\n"
	"\tfloat p = 2.0 * l - q;\n"
	"\treturn vec3(rl_hsl_ch(p, q, h + 1.0 / 3.0), rl_hsl_ch(p, q, h),\n"
	"\t\trl_hsl_ch(p, q, h - 1.0 / 3.0));\n"
	"}\n"
	"vec3 rl_xyz_xyy(vec3 c) {\n"
	"\tfloat sum = c.x + c.y + c.z;\n"
	"\tif (sum == 0.0) return vec3(0.3127, 0.3290, c.y);\n"
	"\treturn vec3(rl_fin(c.x / sum), rl_fin(c.y / sum), c.y);\n"
	"}\n"
	"vec3 rl_xyy_xyz(vec3 c) {\n"
	"\tif (c.y == 0.0) return vec3(0.0);\n"
	"\treturn vec3(rl_fin(c.x * c.z / c.y), c.z, rl_fin((1.0 - c.x - c.y) * c.z / c.y));\n"
	"}\n";

static const char spline_glsl[] =
	"vec4 rl_spline_w(int basis, float u) {\n"
	"\tif (basis == 5) return u < 1.0 ? vec4(0.0, 1.0, 0.0, 0.0) : vec4(0.0, 0.0, 1.0, 0.0);\n"
	"\tconst mat4 m[5] = mat4[5](\n"
	"\t\tmat4(-0.5, 1.0, -0.5, 0.0, 1.5, -2.5, 0.0, 1.0, -1.5, 2.0, 0.5, 0.0, 0.5, -0.5, 0.0,\n"
	"\t\t     0.0),\n"
	"\t\tmat4(-1.0 / 6.0, 3.0 / 6.0, -3.0 / 6.0, 1.0 / 6.0, 3.0 / 6.0, -6.0 / 6.0, 0.0,\n"
	"\t\t     4.0 / 6.0, -3.0 / 6.0, 3.0 / 6.0, 3.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0, 0.0, 0.0, 0.0),\n"
	"\t\tmat4(-1.0, 3.0, -3.0, 1.0, 3.0, -6.0, 3.0, 0.0, -3.0, 3.0, 0.0, 0.0, 1.0, 0.0, 0.0,\n"
	"\t\t     0.0),\n"
	"\t\tmat4(2.0, -3.0, 0.0, 1.0, 1.0, -2.0, 1.0, 0.0, -2.0, 3.0, 0.0, 0.0, 1.0, -1.0, 0.0,\n"
	"\t\t     0.0),\n"
	"\t\tmat4(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0));\n"
	"\tmat4 b = m[basis];\n"
	"\tvec4 pw = vec4(u * u * u, u * u, u, 1.0);\n"
	"\treturn vec4(pw.x * b[0][0] + pw.y * b[0][1] + pw.z * b[0][2] + pw.w * b[0][3],\n"
	"\t\tpw.x * b[1][0] + pw.y * b[1][1] + pw.z * b[1][2] + pw.w * b[1][3],\n"
	"\t\tpw.x * b[2][0] + pw.y * b[2][1] + pw.z * b[2][2] + pw.w * b[2][3],\n"
	"\t\tpw.x * b[3][0] + pw.y * b[3][1] + pw.z * b[3][2] + pw.w * b[3][3]);\n"
	"}\n"
	"int rl_spline_step(int basis) { return basis == 2 ? 3 : basis == 3 ? 2 : 1; }\n"
	"int rl_spline_segs(int basis, int nvals) {\n"
	"\treturn nvals < 4 ? 1 : (nvals - 4) / rl_spline_step(basis) + 1;\n"
	"}\n";

static const char filterstep_glsl[] =
	"float rl_fstep(float edge, float s0, float s1) {\n"
	"\tif (s1 < s0) {\n"
	"\t\tfloat t = s0;\n"
	"\t\ts0 = s1;\n"
	"\t\ts1 = t;\n"
	"\t}\n"
	"\tfloat w = s1 - s0;\n"
	"\tif (!(w > 0.0)) return s0 < edge ? 0.0 : 1.0;\n"
	"\treturn clamp(rl_fin((s1 - edge) / w), 0.0, 1.0);\n"
	"}\n"
	"float rl_filterstep(float edge, float s1, float s2, float width) {\n"
	"\tfloat mid = 0.5 * (s1 + s2), hw = 0.5 * abs(s2 - s1) * width;\n"
	"\treturn rl_fstep(edge, mid - hw, mid + hw);\n"
	"}\n";

static const char deriv_glsl[] =
	"float rl_dtof(double x) {\n"
	"\tif (isnan(x)) return 0.0;\n"
	"\tif (x > double(RL_FLT_MAX)) return RL_FLT_MAX;\n"
	"\tif (x < -double(RL_FLT_MAX)) return -RL_FLT_MAX;\n"
	"\treturn float(x);\n"
	"}\n"
	/* v + su du + sv dv: a corner of a filter region (exec_builtins.c tex_region). */
	"float rl_corner1(float v, float du, float dv, float su, float sv) {\n"
	"\tprecise float a = v + su * du;\n"
	"\tprecise float b = a + sv * dv;\n"
	"\treturn rl_fin(b);\n"
	"}\n"
	"vec3 rl_corner(vec3 v, vec3 du, vec3 dv, float su, float sv) {\n"
	"\tprecise vec3 a = v + su * du;\n"
	"\tprecise vec3 b = a + sv * dv;\n"
	"\treturn rl_fin(b);\n"
	"}\n"
	"vec3 rl_pcross(vec3 a, vec3 b) {\n"
	"\tprecise float x = a.y * b.z - a.z * b.y;\n"
	"\tprecise float y = a.z * b.x - a.x * b.z;\n"
	"\tprecise float z = a.x * b.y - a.y * b.x;\n"
	"\treturn vec3(x, y, z);\n"
	"}\n"
	/* |u x v| with the length in double (mathlib.c sl_v3_length). */
	"float rl_area(vec3 u, vec3 v) {\n"
	"\tvec3 c = rl_pcross(u, v);\n"
	"\tprecise double s = double(c.x) * double(c.x) + double(c.y) * double(c.y) +\n"
	"\t\tdouble(c.z) * double(c.z);\n"
	"\treturn rl_dtof(sqrt(s));\n"
	"}\n"
	/* filterstep(edge, s) over the box of s's changes along u and v. */
	"float rl_fstep_d(float edge, float s, float du, float dv, float width) {\n"
	"\tprecise float w = (abs(du) + abs(dv)) * width;\n"
	"\tprecise float lo = s - 0.5 * w;\n"
	"\tprecise float hi = s + 0.5 * w;\n"
	"\treturn rl_fstep(edge, lo, hi);\n"
	"}\n";

/* render/texture.c: to_map, size_opt, clamp_region, reyes_tex_shadow, statement for statement. */
static const char shadow_glsl[] =
	"vec3 rl_dxpoint(mat4 m, vec3 p) {\n"
	"\tprecise dvec4 o = double(p.x) * dvec4(m[0]) + double(p.y) * dvec4(m[1]) +\n"
	"\t\tdouble(p.z) * dvec4(m[2]) + dvec4(m[3]);\n"
	"\tdouble w = o.w;\n"
	"\tif (w != 0.0LF && w != 1.0LF) o.xyz = o.xyz / w;\n"
	"\treturn vec3(rl_dtof(o.x), rl_dtof(o.y), rl_dtof(o.z));\n"
	"}\n"
	"bool rl_dfinite(double x) { return !isnan(x) && !isinf(x); }\n"
	"bool rl_to_map(mat4 tow, mat4 tocam, mat4 tondc, vec3 pc, out double s, out double t,\n"
	"\t\tout double z) {\n"
	"\tvec3 pw = rl_dxpoint(tow, pc);\n"
	"\tvec3 pl = rl_dxpoint(tocam, pw);\n"
	"\tz = double(pl.z);\n"
	"\tprecise dvec4 h = double(pw.x) * dvec4(tondc[0]) + double(pw.y) * dvec4(tondc[1]) +\n"
	"\t\tdouble(pw.z) * dvec4(tondc[2]) + dvec4(tondc[3]);\n"
	"\ts = 0.0LF;\n"
	"\tt = 0.0LF;\n"
	"\tif (!(h.w > 1e-20LF) || !rl_dfinite(h.x) || !rl_dfinite(h.y)) return false;\n"
	"\ts = h.x / h.w;\n"
	"\tt = h.y / h.w;\n"
	"\treturn rl_dfinite(s) && rl_dfinite(t) && rl_dfinite(z);\n"
	"}\n"
	"double rl_size_opt(float v) {\n"
	"\tif (isnan(v) || isinf(v) || v <= 0.0) return 0.0LF;\n"
	"\treturn double(v) < 1e6LF ? double(v) : 1e6LF;\n"
	"}\n"
	"double rl_clamp_region(double d) { return d < 1e6LF ? d : 1e6LF; }\n"
	"float rl_fo0(float v) { return isnan(v) || isinf(v) ? 0.0 : v; }\n"
	/* render/deepshadow.c reyes_deep_eval: offsets, then (z, T) nodes */
	"double rl_deep_eval(samplerBuffer m, ivec2 size, int x, int y, double z) {\n"
	"\tint p = y * size.x + x, base = size.x * size.y + 1;\n"
	"\tint lo = int(texelFetch(m, p).x), hi = int(texelFetch(m, p + 1).x);\n"
	"\tint a = lo, b = hi;\n"
	"\twhile (a < b) {\n"
	"\t\tint mid = a + (b - a) / 2;\n"
	"\t\tif (double(texelFetch(m, base + 2 * mid).x) > z) b = mid;\n"
	"\t\telse a = mid + 1;\n"
	"\t}\n"
	"\tif (a == lo) return 1.0LF;\n"
	"\tif (a == hi) return double(texelFetch(m, base + 2 * hi - 1).x);\n"
	"\tdouble z0 = double(texelFetch(m, base + 2 * a - 2).x);\n"
	"\tdouble t0 = double(texelFetch(m, base + 2 * a - 1).x);\n"
	"\tdouble z1 = double(texelFetch(m, base + 2 * a).x);\n"
	"\tdouble t1 = double(texelFetch(m, base + 2 * a + 1).x);\n"
	"\tprecise double r = t0 + (t1 - t0) * ((z - z0) / (z1 - z0));\n"
	"\treturn r;\n"
	"}\n"
	"float rl_shadow(samplerBuffer zmap, ivec2 size, bool deep, mat4 tow, mat4 tocam,\n"
	"\t\tmat4 tondc,\n"
	"\t\tfloat mapbias, vec3 p0, vec3 p1, vec3 p2, vec3 p3, bool hasc, vec3 center,\n"
	"\t\tfloat swidth, float twidth, float sblur, float tblur, float samples, float bias,\n"
	"\t\tfloat fill) {\n"
	"\tif (size.x <= 0 || size.y <= 0) return fill;\n"
	"\tfloat b = bias >= 0.0 && !isinf(bias) ? bias : mapbias;\n"
	"\tdouble sw = rl_size_opt(swidth), tw = rl_size_opt(twidth);\n"
	"\tdouble sb = rl_size_opt(sblur), tb = rl_size_opt(tblur);\n"
	"\tdouble nsamp = isnan(samples) || isinf(samples) ? 1.0LF : double(samples);\n"
	"\tnsamp = nsamp < 1.0LF ? 1.0LF : nsamp > 1024.0LF ? 1024.0LF : nsamp;\n"
	"\tprecise double nm = nsamp - 1e-6LF;\n"
	"\tint grid = int(ceil(sqrt(nm)));\n"
	"\tif (grid < 1) grid = 1;\n"
	"\tdouble smin = 0.0LF, smax = 0.0LF, tmin = 0.0LF, tmax = 0.0LF;\n"
	"\tprecise double zsum = 0.0LF;\n"
	"\tint nvalid = 0;\n"
	"\tfor (int k = 0; k < 4; k++) {\n"
	"\t\tvec3 p = k == 0 ? p0 : k == 1 ? p1 : k == 2 ? p2 : p3;\n"
	"\t\tdouble s, t, z;\n"
	"\t\tif (!rl_to_map(tow, tocam, tondc, vec3(rl_fo0(p.x), rl_fo0(p.y), rl_fo0(p.z)), s,\n"
	"\t\t\t\tt, z))\n"
	"\t\t\tcontinue;\n"
	"\t\tif (nvalid == 0) {\n"
	"\t\t\tsmin = smax = s;\n"
	"\t\t\ttmin = tmax = t;\n"
	"\t\t} else {\n"
	"\t\t\tsmin = s < smin ? s : smin;\n"
	"\t\t\tsmax = s > smax ? s : smax;\n"
	"\t\t\ttmin = t < tmin ? t : tmin;\n"
	"\t\t\ttmax = t > tmax ? t : tmax;\n"
	"\t\t}\n"
	"\t\tzsum += z;\n"
	"\t\tnvalid++;\n"
	"\t}\n"
	"\tprecise double z = nvalid > 0 ? zsum / double(nvalid) : 0.0LF;\n"
	"\tif (!(nvalid > 0 && z > 0.0LF)) return 0.0;\n"
	"\tprecise double sc = 0.5LF * (smin + smax), tc = 0.5LF * (tmin + tmax);\n"
	"\tprecise double ds = rl_clamp_region((smax - smin) * sw + sb);\n"
	"\tprecise double dt = rl_clamp_region((tmax - tmin) * tw + tb);\n"
	"\tint nu = ds > 0.0LF || dt > 0.0LF ? grid : 1;\n"
	"\tuint seed;\n"
	"\tif (hasc)\n"
	"\t\tseed = rl_hmix(rl_hmix(floatBitsToUint(center.x)) ^\n"
	"\t\t\trl_hmix(floatBitsToUint(center.y) + 0x9e3779b9u) ^\n"
	"\t\t\trl_hmix(floatBitsToUint(center.z) + 0x7f4a7c15u));\n"
	"\telse\n"
	"\t\tseed = rl_hmix(rl_hmix(floatBitsToUint(float(sc))) ^\n"
	"\t\t\trl_hmix(floatBitsToUint(float(tc)) + 0x9e3779b9u));\n"
	"\tprecise double zb = z - double(b);\n"
	"\tprecise double shadowed = 0.0LF;\n"
	"\tfor (int v = 0; v < nu; v++) {\n"
	"\t\tfor (int u = 0; u < nu; u++) {\n"
	"\t\t\tdouble ju = 0.5LF, jv = 0.5LF;\n"
	"\t\t\tif (nu > 1) {\n"
	"\t\t\t\tseed = rl_hmix(seed + 0x6d2b79f5u);\n"
	"\t\t\t\tju = double(seed >> 8) * (1.0LF / 16777216.0LF);\n"
	"\t\t\t\tseed = rl_hmix(seed + 0x6d2b79f5u);\n"
	"\t\t\t\tjv = double(seed >> 8) * (1.0LF / 16777216.0LF);\n"
	"\t\t\t}\n"
	"\t\t\tprecise double s = sc + ((double(u) + ju) / double(nu) - 0.5LF) * ds;\n"
	"\t\t\tprecise double t = tc + ((double(v) + jv) / double(nu) - 0.5LF) * dt;\n"
	"\t\t\tif (!(s >= 0.0LF && s < 1.0LF && t >= 0.0LF && t < 1.0LF)) continue;\n"
	"\t\t\tprecise double xs = s * double(size.x), ys = t * double(size.y);\n"
	"\t\t\tint x = min(int(xs), size.x - 1), y = min(int(ys), size.y - 1);\n"
	"\t\t\tif (deep) {\n"
	"\t\t\t\tshadowed += 1.0LF - rl_deep_eval(zmap, size, x, y, zb);\n"
	"\t\t\t\tcontinue;\n"
	"\t\t\t}\n"
	"\t\t\tfloat zm = texelFetch(zmap, y * size.x + x).x;\n"
	"\t\t\tif (zm > 0.0 && zb > double(zm)) shadowed += 1.0LF;\n"
	"\t\t}\n"
	"\t}\n"
	"\treturn float(shadowed / double(nu * nu));\n"
	"}\n";

struct helper {
	const char *text;
	uint8_t deps[3];   /* helpers it calls (0: none; GH_CORE is always there) */
};

/*
 * shadow("raytrace", P) in a light (see the renderer's reyes_trace.c): the
 * shadowed fraction of the segment from P to the light's position (the
 * light's Ps - L), in world space, its start moved @bias along it (the
 * default when not a length), through the shadow geometry's hierarchy.
 * A segment shorter than the bias is not shadowed.
 */
static const char rtshadow_glsl[] =
	"float rl_rt_shadow(samplerBuffer nodes, samplerBuffer tris, samplerBuffer casts,\n"
	"\t\tmat4 tow, vec3 p, vec3 light, float bias, float defbias) {\n"
	"\tvec3 a = rl_dxpoint(tow, p), d = rl_dxpoint(tow, light) - a;\n"
	"\tfloat len = length(d);\n"
	"\tif (!(len > 0.0) || isinf(len)) return 0.0;\n"
	"\tfloat b = bias >= 0.0 && !isinf(bias) ? bias : defbias;\n"
	"\tif (!(b < len)) return 0.0;\n"
	"\tvec3 dn = d / len;\n"
	"\treturn 1.0 - rl_bvh_transmission(nodes, tris, casts, a + b * dn, dn, len - b);\n"
	"}\n";

static const struct helper helpers[GH_COUNT] = {
	[GH_CORE] = { core_glsl, { 0 } },
	[GH_MATDIV] = { matdiv_glsl, { GH_INVERSE } },
	[GH_INVERSE] = { inverse_glsl, { 0 } },
	[GH_XFORM] = { xform_glsl, { 0 } },
	[GH_AIDX] = { aidx_glsl, { 0 } },
	[GH_CIDX] = { cidx_glsl, { 0 } },
	[GH_VEC] = { vec_glsl, { 0 } },
	[GH_MATH] = { math_glsl, { 0 } },
	[GH_NOISE] = { noise_glsl, { 0 } },
	[GH_GEOM] = { geom_glsl, { GH_VEC } },
	[GH_FRESNEL] = { fresnel_glsl, { GH_GEOM, GH_VEC } },
	[GH_SPECBRDF] = { specbrdf_glsl, { GH_MATH, GH_VEC } },
	[GH_CONE] = { cone_glsl, { 0 } },
	[GH_COLOR] = { color_glsl, { 0 } },
	[GH_SPLINE] = { spline_glsl, { 0 } },
	[GH_FILTERSTEP] = { filterstep_glsl, { 0 } },
	[GH_DERIV] = { deriv_glsl, { GH_FILTERSTEP } },
	[GH_SHADOW] = { shadow_glsl, { GH_DERIV, GH_NOISE } },
	[GH_TEXMAP] = { sl_glsl_texmap_src, { GH_DERIV } },
	[GH_RTSHADOW] = { rtshadow_glsl, { GH_SHADOW } },
};

/* Output order: every helper after the ones it calls. */
static const uint8_t helper_order[GH_COUNT] = {
	GH_CORE, GH_MATH, GH_VEC, GH_AIDX, GH_CIDX, GH_INVERSE, GH_MATDIV, GH_XFORM, GH_NOISE,
	GH_GEOM, GH_FRESNEL, GH_SPECBRDF, GH_CONE, GH_COLOR, GH_SPLINE, GH_FILTERSTEP, GH_DERIV,
	GH_SHADOW, GH_TEXMAP, GH_RTSHADOW,
};

void sl_glsl_need(struct glsl_gen *g, enum glsl_helper h)
{
	if (g->need[h])
		return;
	g->need[h] = true;
	for (int k = 0; k < 3; k++)
		if (helpers[h].deps[k])
			sl_glsl_need(g, (enum glsl_helper)helpers[h].deps[k]);
}

void sl_glsl_emit_helpers(struct glsl_gen *g)
{
	struct rl_strbuf *b = &g->sec[GS_HELPERS];
	for (int k = 0; k < GH_COUNT; k++) {
		int h = helper_order[k];
		if (!g->need[h])
			continue;
		if (h == GH_SPECBRDF) {
			bool rispec = g->slice->specular_model == SL_SPECULAR_RISPEC;
			rl_strbuf_printf(b, specbrdf_glsl, rispec ? "1.0" : "8.0");
			continue;
		}
		if (h == GH_RTSHADOW)
			rl_strbuf_puts(b, sl_glsl_bvh_source);
		rl_strbuf_puts(b, helpers[h].text);
		if (h != GH_MATH)
			continue;
		/* The componentwise vec3 forms. */
		for (size_t i = 0; i < sizeof(math_fns) / sizeof(math_fns[0]); i++) {
			const char *f = math_fns[i].name;
			int n = math_fns[i].arity;
			static const char *const par[] = { "vec3 a", "vec3 a, vec3 b",
							   "vec3 a, vec3 b, vec3 c" };
			rl_strbuf_printf(b, "vec3 %s(%s) { return vec3(", f, par[n - 1]);
			for (int c = 0; c < 3; c++) {
				static const char comp[] = "xyz";
				rl_strbuf_printf(b, "%s%s(a.%c", c ? ", " : "", f, comp[c]);
				if (n > 1)
					rl_strbuf_printf(b, ", b.%c", comp[c]);
				if (n > 2)
					rl_strbuf_printf(b, ", c.%c", comp[c]);
				rl_strbuf_putc(b, ')');
			}
			rl_strbuf_puts(b, "); }\n");
		}
	}
}

/* ------------------------------------------------------------------------ */
/* Calls                                                                     */

static const char *bi_name(const struct sl_insn *in)
{
	return sl_builtins[in->bi].name;
}

static bool need_args(struct glsl_gen *g, const struct sl_insn *in, int n)
{
	if (in->nargs >= n)
		return true;
	sl_glsl_error(g, in, "invalid program: %s() needs %d arguments", bi_name(in), n);
	return false;
}

static bool is_string(struct glsl_gen *g, int32_t r)
{
	return g->cur->prog->regs[r].type == SL_TYPE_STRING;
}

static int ncomp(struct glsl_gen *g, int32_t r)
{
	return sl_glsl_ncomp(g->cur->prog, r);
}

static const char *op(struct glsl_gen *g, int32_t r, int want)
{
	return sl_glsl_op(g, r, want);
}

/* "dst = expr;" for the destination register of @in, if it has one. */
static void set_dst(struct glsl_gen *g, const struct sl_insn *in, const char *expr)
{
	if (in->dst < 0)
		return;
	const char *d = sl_glsl_lv(g, in->dst);
	if (!d) {
		sl_glsl_error(g, in, "invalid program: write to a constant");
		return;
	}
	sl_glsl_line(g, "%s = %s;", d, expr);
}

/* An argument the call writes. */
static const char *out_arg(struct glsl_gen *g, const struct sl_insn *in, int32_t r)
{
	const char *d = sl_glsl_lv(g, r);
	if (!d)
		sl_glsl_error(g, in, "invalid program: %s() writes a constant", bi_name(in));
	return d;
}

/* The destination expression of a triple result for a dst of @nd components. */
static const char *fit3(struct glsl_gen *g, int nd, const char *v3)
{
	return nd == 1 ? SL_GLSL_FMT(g, "(%s).x", v3) : v3;
}

static void unsupported(struct glsl_gen *g, const struct sl_insn *in, const char *why)
{
	sl_glsl_error(g, in, "%s() is not supported on the GPU%s%s", bi_name(in), why ? ": " : "",
		      why ? why : "");
}

/* ---- derivatives on stencils ---- */

/* Can the derivatives of @r be taken here? Reports why not. */
static bool deriv_operand(struct glsl_gen *g, const struct sl_insn *in, int32_t r)
{
	if (!g->stencil) {
		sl_glsl_error(g, in, "derivatives of GPU-computed values are not supported (%s)",
			      bi_name(in));
		return false;
	}
	if (sl_glsl_class(g, r) & GC_OPAQUE) {
		sl_glsl_error(g, in, "derivatives of GPU-computed values are not supported (%s): the "
			      "value does not come from inputs with derivative steps", bi_name(in));
		return false;
	}
	return true;
}

/* Component @c of the expression @e of register @r. */
static const char *comp_of(struct glsl_gen *g, int32_t r, const char *e, int c)
{
	int nc = ncomp(g, r);
	if (nc == 1)
		return e;
	if (nc == 16)
		return SL_GLSL_FMT(g, "%s[%d][%d]", e, c / 4, c % 4);
	return SL_GLSL_FMT(g, "%s[%d]", e, c);
}

/*
 * The change of component @c of @r over one step along u (@dir 1) or v
 * (2), as the interpreter's stencil difference: f moved - f, clamped.
 */
static const char *step_diff(struct glsl_gen *g, int32_t r, int c, int dir)
{
	if (!sl_glsl_class(g, r))
		return "0.0";
	return SL_GLSL_FMT(g, "rl_fin(%s - %s)", comp_of(g, r, sl_glsl_moved(g, r, 0, dir), c),
			   comp_of(g, r, op(g, r, 0), c));
}

/* The same for the three components of a triple (floats broadcast). */
static const char *step_diff3(struct glsl_gen *g, int32_t r, int dir)
{
	if (!sl_glsl_class(g, r))
		return "vec3(0.0)";
	return SL_GLSL_FMT(g, "rl_fin(%s - %s)", sl_glsl_moved(g, r, 3, dir), op(g, r, 3));
}

/* Du(f) or Dv(f) of component @c: the difference divided by the sample's step. */
static const char *deriv_comp(struct glsl_gen *g, int32_t r, int c, int dir)
{
	if (!sl_glsl_class(g, r))
		return "0.0";
	return SL_GLSL_FMT(g, "rl_div(%s - %s, %s)", comp_of(g, r, sl_glsl_moved(g, r, 0, dir), c),
			   comp_of(g, r, op(g, r, 0), c), dir == 1 ? "rl_du" : "rl_dv");
}

/* Du, Dv, Deriv, area, calculatenormal on derivative stencils. */
static void call_deriv(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	int want = id == SL_BI_DERIV ? 2 : 1;
	if (!need_args(g, in, want))
		return;
	const int32_t *a = in->args;
	for (int k = 0; k < want; k++)
		if (!deriv_operand(g, in, a[k]))
			return;
	if (in->dst < 0)
		return;
	int nd = ncomp(g, in->dst);
	if (id == SL_BI_AREA || id == SL_BI_CALCULATENORMAL) {
		const char *e;
		sl_glsl_need(g, GH_DERIV);
		if (!sl_glsl_class(g, a[0]))
			e = id == SL_BI_AREA ? "0.0" : "vec3(0.0)";
		else if (id == SL_BI_AREA)
			e = SL_GLSL_FMT(g, "rl_area(%s, %s)", step_diff3(g, a[0], 1),
					step_diff3(g, a[0], 2));
		else
			e = SL_GLSL_FMT(g, "rl_fin(rl_pcross(rl_div(%s - %s, vec3(rl_du)), "
					"rl_div(%s - %s, vec3(rl_dv))))", sl_glsl_moved(g, a[0], 3, 1),
					op(g, a[0], 3), sl_glsl_moved(g, a[0], 3, 2), op(g, a[0], 3));
		if (id == SL_BI_AREA)
			set_dst(g, in, nd == 3 ? SL_GLSL_FMT(g, "vec3(%s)", e) : e);
		else
			set_dst(g, in, fit3(g, nd, e));
		return;
	}
	int nc = nd > 3 ? 3 : nd;
	if (nc != 1 && nc != 3) {
		sl_glsl_error(g, in, "invalid program: %s() of a %d-component value", bi_name(in), nd);
		return;
	}
	const char *e[3];
	for (int c = 0; c < nc; c++) {
		int ca = ncomp(g, a[0]) == 1 ? 0 : c;
		if (id == SL_BI_DU || id == SL_BI_DV) {
			e[c] = deriv_comp(g, a[0], ca, id == SL_BI_DU ? 1 : 2);
			continue;
		}
		e[c] = SL_GLSL_FMT(g, "rl_fin(rl_div(%s, %s) + rl_div(%s, %s))",
				   deriv_comp(g, a[0], ca, 1), deriv_comp(g, a[1], 0, 1),
				   deriv_comp(g, a[0], ca, 2), deriv_comp(g, a[1], 0, 2));
	}
	if (nc == 1)
		set_dst(g, in, e[0]);
	else
		set_dst(g, in, SL_GLSL_FMT(g, "vec3(%s, %s, %s)", e[0], e[1], e[2]));
}

/* ---- math ---- */

static const char *math_fn(int id, int nargs)
{
	switch (id) {
	case SL_BI_RADIANS: return "rl_radians";
	case SL_BI_DEGREES: return "rl_degrees";
	case SL_BI_SIN: return "rl_sin";
	case SL_BI_ASIN: return "rl_asin";
	case SL_BI_COS: return "rl_cos";
	case SL_BI_ACOS: return "rl_acos";
	case SL_BI_TAN: return "rl_tan";
	case SL_BI_ATAN: return nargs >= 2 ? "rl_atan2" : "rl_atan";
	case SL_BI_SINH: return "rl_sinh";
	case SL_BI_COSH: return "rl_cosh";
	case SL_BI_TANH: return "rl_tanh";
	case SL_BI_POW: return "rl_pow";
	case SL_BI_EXP: return "rl_exp";
	case SL_BI_SQRT: return "rl_sqrt";
	case SL_BI_INVERSESQRT: return "rl_isqrt";
	case SL_BI_LOG: return nargs >= 2 ? "rl_logb" : "rl_log";
	case SL_BI_MOD: return "rl_mod";
	case SL_BI_ABS: return "rl_abs";
	case SL_BI_SIGN: return "rl_sign";
	case SL_BI_MIN: return "rl_min";
	case SL_BI_MAX: return "rl_max";
	case SL_BI_CLAMP: return "rl_clamp";
	case SL_BI_MIX: return "rl_mix";
	case SL_BI_FLOOR: return "rl_floor";
	case SL_BI_CEIL: return "rl_ceil";
	case SL_BI_ROUND: return "rl_round";
	case SL_BI_STEP: return "rl_step";
	case SL_BI_SMOOTHSTEP: return "rl_smoothstep";
	default: return NULL;
	}
}

static int math_arity(int id, int nargs)
{
	switch (id) {
	case SL_BI_POW: case SL_BI_MOD: case SL_BI_STEP: case SL_BI_MIN: case SL_BI_MAX:
		return 2;
	case SL_BI_CLAMP: case SL_BI_MIX: case SL_BI_SMOOTHSTEP:
		return 3;
	case SL_BI_ATAN: case SL_BI_LOG:
		return nargs >= 2 ? 2 : 1;
	default:
		return 1;
	}
}

static void call_math(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	int n = math_arity(id, in->nargs);
	if (in->dst < 0 || !need_args(g, in, n))
		return;
	int nd = ncomp(g, in->dst);
	if (nd != 1 && nd != 3) {
		sl_glsl_error(g, in, "invalid program: %s() of a %d-component value", bi_name(in), nd);
		return;
	}
	sl_glsl_need(g, GH_MATH);
	const char *fn = math_fn(id, in->nargs);
	const char *e;
	if (id == SL_BI_MIN || id == SL_BI_MAX) {
		e = op(g, in->args[0], nd);
		for (int k = 1; k < in->nargs; k++)
			e = SL_GLSL_FMT(g, "%s(%s, %s)", fn, e, op(g, in->args[k], nd));
	} else if (n == 1) {
		e = SL_GLSL_FMT(g, "%s(%s)", fn, op(g, in->args[0], nd));
	} else if (n == 2) {
		e = SL_GLSL_FMT(g, "%s(%s, %s)", fn, op(g, in->args[0], nd), op(g, in->args[1], nd));
	} else {
		e = SL_GLSL_FMT(g, "%s(%s, %s, %s)", fn, op(g, in->args[0], nd),
				op(g, in->args[1], nd), op(g, in->args[2], nd));
	}
	set_dst(g, in, e);
}

/* filterstep(edge, s1, s2 [, "width", w ...]); the two-value form needs derivatives. */
static void call_filterstep(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const int32_t *a = in->args;
	int nnum = 0;
	while (nnum < in->nargs && !is_string(g, a[nnum]))
		nnum++;
	if (nnum < 3 && !g->stencil) {
		sl_glsl_error(g, in, "derivatives of GPU-computed values are not supported "
			      "(filterstep() without a second value estimates one)");
		return;
	}
	const char *width = "1.0";
	for (int k = nnum; k + 1 < in->nargs; k += 2) {
		const char *opt = sl_glsl_cstr(g, a[k]);
		if (!opt) {
			sl_glsl_error(g, in, "filterstep() options must be constant strings on the "
				      "GPU");
			return;
		}
		if ((!strcmp(opt, "width") || !strcmp(opt, "swidth")) && !is_string(g, a[k + 1]))
			width = SL_GLSL_FMT(g, "max(%s, 0.0)", op(g, a[k + 1], 1));
		else if (strcmp(opt, "filter") != 0 && strcmp(opt, "twidth") != 0)
			sl_glsl_warning(g, in, "filterstep: unknown option '%s'", opt);
	}
	if (nnum < 3) {
		if (!deriv_operand(g, in, a[1]))
			return;
		sl_glsl_need(g, GH_DERIV);
		set_dst(g, in, SL_GLSL_FMT(g, "rl_fstep_d(%s, %s, %s, %s, %s)", op(g, a[0], 1),
					   op(g, a[1], 1), step_diff(g, a[1], 0, 1),
					   step_diff(g, a[1], 0, 2), width));
		return;
	}
	sl_glsl_need(g, GH_FILTERSTEP);
	set_dst(g, in, SL_GLSL_FMT(g, "rl_filterstep(%s, %s, %s, %s)", op(g, a[0], 1),
				   op(g, a[1], 1), op(g, a[2], 1), width));
}

const char *sl_glsl_spline_fn(struct glsl_gen *g, int nvals, int nc)
{
	uint64_t key = (uint64_t)nvals << 8 | (uint64_t)nc;
	size_t i;
	for (i = 0; i < g->splines.len; i++)
		if (g->splines.data[i] == key)
			break;
	if (i == g->splines.len) {
		rl_vec_push(g->splines, key);
		sl_glsl_emit_spline(g, nvals, nc);
	}
	return SL_GLSL_FMT(g, "rl_spline%d_%d", nc, nvals);
}

void sl_glsl_emit_spline(struct glsl_gen *g, int n, int nc)
{
	struct rl_strbuf *b = &g->sec[GS_GENERATED];
	const char *t = nc == 3 ? "vec3" : "float";
	sl_glsl_need(g, GH_SPLINE);
	rl_strbuf_printf(b,
		"%s rl_spline%d_%d(int basis, float t, %s v[%d]) {\n"
		"\tint nseg = rl_spline_segs(basis, %d);\n"
		"\tt = clamp(isnan(t) ? 0.0 : t, 0.0, 1.0);\n"
		"\tfloat x = t * float(nseg);\n"
		"\tint seg = clamp(int(floor(x)), 0, nseg - 1);\n"
		"\tfloat u = x - float(seg);\n"
		"\tint first = seg * rl_spline_step(basis);\n"
		"\tvec4 w = rl_spline_w(basis, u);\n"
		"\t%s s = %s(0.0);\n"
		"\tfor (int j = 0; j < 4; j++) s += w[j] * v[min(first + j, %d)];\n"
		"\treturn rl_c(s);\n"
		"}\n", t, nc, n, t, n, n, t, t, n - 1);
	if (nc != 1)
		return;
	/* The "solve" bases: the parameter where the spline reaches t, by bisection. */
	rl_strbuf_printf(b,
		"float rl_splinesolve_%d(int basis, float t, float v[%d]) {\n"
		"\tbool up = rl_spline1_%d(basis, 1.0, v) >= rl_spline1_%d(basis, 0.0, v);\n"
		"\tfloat lo = 0.0, hi = 1.0;\n"
		"\tfor (int it = 0; it < 32; it++) {\n"
		"\t\tfloat mid = 0.5 * (lo + hi);\n"
		"\t\tif ((rl_spline1_%d(basis, mid, v) < t) == up) lo = mid;\n"
		"\t\telse hi = mid;\n"
		"\t}\n"
		"\treturn 0.5 * (lo + hi);\n"
		"}\n", n, n, n, n, n);
}

/* spline([basis,] t, v1, ..., vn) and spline([basis,] t, values[]) */
static void call_spline(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const int32_t *a = in->args;
	int first = 0, basis = SL_SPLINE_CATMULL_ROM;
	if (is_string(g, a[0])) {
		const char *name = sl_glsl_cstr(g, a[0]);
		if (!name) {
			sl_glsl_error(g, in, "spline bases must be constant strings on the GPU");
			return;
		}
		basis = sl_spline_basis(name);
		if (basis < 0) {
			sl_glsl_warning(g, in, "spline: unknown basis '%s' (catmull-rom used)", name);
			basis = SL_SPLINE_CATMULL_ROM;
		}
		first = 1;
	}
	if (!need_args(g, in, first + 2))
		return;
	int nd = ncomp(g, in->dst);
	if (nd != 1 && nd != 3) {
		sl_glsl_error(g, in, "invalid program: spline() of a %d-component value", nd);
		return;
	}
	int32_t arr = a[first + 1];
	bool array = in->nargs == first + 2 && g->cur->prog->regs[arr].arraylen > 0;
	int n = array ? g->cur->prog->regs[arr].arraylen : in->nargs - first - 1;
	const char *vals;
	if (array && ncomp(g, arr) == nd) {
		vals = op(g, arr, 0);
	} else {
		struct rl_strbuf b = { 0 };
		rl_strbuf_printf(&b, "%s[%d](", nd == 3 ? "vec3" : "float", n);
		const char *base = array ? op(g, arr, 0) : NULL;
		for (int k = 0; k < n; k++) {
			const char *v;
			if (array)
				v = nd == 3 ? SL_GLSL_FMT(g, "vec3(%s[%d])", base, k)
					    : SL_GLSL_FMT(g, "%s[%d]", base, k);
			else
				v = op(g, a[first + 1 + k], nd);
			rl_strbuf_printf(&b, "%s%s", k ? ", " : "", v);
		}
		rl_strbuf_putc(&b, ')');
		vals = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
		rl_strbuf_finish(&b);
	}
	const char *fn = sl_glsl_spline_fn(g, n, nd);
	const char *t = op(g, a[first], 1);
	int solve = basis & SL_SPLINE_SOLVE;
	basis &= ~SL_SPLINE_SOLVE;
	if (solve && nd == 1)
		set_dst(g, in, SL_GLSL_FMT(g, "rl_splinesolve_%d(%d, %s, %s)", n, basis, t, vals));
	else
		set_dst(g, in, SL_GLSL_FMT(g, "%s(%d, %s, %s)", fn, basis, t, vals));
}

/* ---- noise ---- */

static void call_noise(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	if (in->dst < 0 || !need_args(g, in, 1))
		return;
	const char *comp[8];
	int m = 0;
	for (int k = 0; k < in->nargs; k++) {
		int32_t r = in->args[k];
		int nc = ncomp(g, r);
		if (is_string(g, r) || g->cur->prog->regs[r].arraylen || nc > 3 || m + nc > 8) {
			sl_glsl_error(g, in, "%s: unsupported arguments", bi_name(in));
			return;
		}
		for (int c = 0; c < nc; c++)
			comp[m++] = nc == 1 ? op(g, r, 1) : SL_GLSL_FMT(g, "%s[%d]", op(g, r, 0), c);
	}
	int dim = id == SL_BI_PNOISE ? m / 2 : m;
	if (dim < 1 || dim > 4) {
		sl_glsl_error(g, in, "%s: unsupported arguments", bi_name(in));
		return;
	}
	const char *p[4], *per[4];
	for (int d = 0; d < 4; d++) {
		p[d] = d < dim ? comp[d] : "0.0";
		per[d] = id == SL_BI_PNOISE && d < dim ? SL_GLSL_FMT(g, "rl_nperiod(%s)", comp[dim + d])
						       : "0";
	}
	const char *pos = SL_GLSL_FMT(g, "vec4(%s, %s, %s, %s)", p[0], p[1], p[2], p[3]);
	const char *pv = SL_GLSL_FMT(g, "ivec4(%s, %s, %s, %s)", per[0], per[1], per[2], per[3]);
	sl_glsl_need(g, GH_NOISE);
	int nd = ncomp(g, in->dst);
	const char *e[3];
	for (int c = 0; c < 3; c++) {
		unsigned seed = nd == 1 ? 0u : (unsigned)c + 1u;
		if (id == SL_BI_CELLNOISE)
			e[c] = SL_GLSL_FMT(g, "rl_cellnoise(%d, %s, %uu)", dim, pos, seed);
		else
			e[c] = SL_GLSL_FMT(g, "rl_noise(%d, %s, %s, %uu)", dim, pos, pv, seed);
	}
	if (nd == 1)
		set_dst(g, in, e[0]);
	else if (nd == 3)
		set_dst(g, in, SL_GLSL_FMT(g, "vec3(%s, %s, %s)", e[0], e[1], e[2]));
	else
		sl_glsl_error(g, in, "invalid program: %s() of a matrix", bi_name(in));
}

/* ---- geometry ---- */

static void call_geometry(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	static const int nargs_of[SL_BI_COUNT] = {
		[SL_BI_XCOMP] = 1, [SL_BI_YCOMP] = 1, [SL_BI_ZCOMP] = 1, [SL_BI_LENGTH] = 1,
		[SL_BI_NORMALIZE] = 1, [SL_BI_DISTANCE] = 2, [SL_BI_PTLINED] = 3,
		[SL_BI_ROTATE] = 3, [SL_BI_FACEFORWARD] = 2, [SL_BI_REFLECT] = 2,
		[SL_BI_REFRACT] = 3, [SL_BI_SPECULARBRDF] = 4, [SL_BI_DETERMINANT] = 1,
		[SL_BI_TRANSLATE] = 2, [SL_BI_SCALE] = 2,
	};
	if (in->dst < 0 || !need_args(g, in, nargs_of[id]))
		return;
	const int32_t *a = in->args;
	int nd = ncomp(g, in->dst);
	const char *e = NULL;
	sl_glsl_need(g, GH_VEC);
	switch (id) {
	case SL_BI_XCOMP: case SL_BI_YCOMP: case SL_BI_ZCOMP:
		e = SL_GLSL_FMT(g, "%s[%d]", op(g, a[0], 3), id - SL_BI_XCOMP);
		break;
	case SL_BI_LENGTH:
		e = SL_GLSL_FMT(g, "rl_length(%s)", op(g, a[0], 3));
		break;
	case SL_BI_NORMALIZE:
		e = fit3(g, nd, SL_GLSL_FMT(g, "rl_normalize(%s)", op(g, a[0], 3)));
		break;
	case SL_BI_DISTANCE:
		e = SL_GLSL_FMT(g, "rl_length(%s - %s)", op(g, a[0], 3), op(g, a[1], 3));
		break;
	case SL_BI_PTLINED:
		sl_glsl_need(g, GH_GEOM);
		e = SL_GLSL_FMT(g, "rl_ptlined(%s, %s, %s)", op(g, a[0], 3), op(g, a[1], 3),
				op(g, a[2], 3));
		break;
	case SL_BI_ROTATE:
		sl_glsl_need(g, GH_GEOM);
		if (ncomp(g, a[0]) == 16) {
			e = SL_GLSL_FMT(g, "rl_c(%s * rl_rotation(%s, %s))", op(g, a[0], 0),
					op(g, a[1], 1), op(g, a[2], 3));
		} else {
				if (!need_args(g, in, 4))
					return;
				e = fit3(g, nd, SL_GLSL_FMT(g, "rl_rotate(%s, %s, %s, %s)", op(g, a[0], 3),
							    op(g, a[1], 1), op(g, a[2], 3), op(g, a[3], 3)));
		}
		break;
	case SL_BI_FACEFORWARD: {
		sl_glsl_need(g, GH_GEOM);
		int32_t nref = in->nargs >= 3 ? a[2] : g->cur->prog->global_reg[SL_GLOBAL_NG];
		if (nref < 0)
			nref = a[0];
		e = fit3(g, nd, SL_GLSL_FMT(g, "rl_faceforward(%s, %s, %s)", op(g, a[0], 3),
					    op(g, a[1], 3), op(g, nref, 3)));
		break;
	}
	case SL_BI_REFLECT:
		sl_glsl_need(g, GH_GEOM);
		e = fit3(g, nd, SL_GLSL_FMT(g, "rl_reflect(%s, %s)", op(g, a[0], 3), op(g, a[1], 3)));
		break;
	case SL_BI_REFRACT:
		sl_glsl_need(g, GH_GEOM);
		e = fit3(g, nd, SL_GLSL_FMT(g, "rl_refract(%s, %s, %s)", op(g, a[0], 3),
					    op(g, a[1], 3), op(g, a[2], 1)));
		break;
	case SL_BI_SPECULARBRDF:
		sl_glsl_need(g, GH_SPECBRDF);
		e = SL_GLSL_FMT(g, "rl_specbrdf(%s, %s, %s, %s)", op(g, a[0], 3), op(g, a[1], 3),
				op(g, a[2], 3), op(g, a[3], 1));
		if (nd == 3)
			e = SL_GLSL_FMT(g, "vec3(%s)", e);
		break;
	case SL_BI_DETERMINANT:
		e = SL_GLSL_FMT(g, "rl_c(determinant(%s))", op(g, a[0], 16));
		break;
	case SL_BI_TRANSLATE:
		sl_glsl_need(g, GH_GEOM);
		e = SL_GLSL_FMT(g, "rl_c(%s * rl_translation(%s))", op(g, a[0], 16), op(g, a[1], 3));
		break;
	case SL_BI_SCALE:
		sl_glsl_need(g, GH_GEOM);
		e = SL_GLSL_FMT(g, "rl_c(%s * rl_scaling(%s))", op(g, a[0], 16), op(g, a[1], 3));
		break;
	default:
		break;
	}
	if (e)
		set_dst(g, in, e);
}

/* fresnel(I, N, eta, Kr, Kt [, R, T]) */
static void call_fresnel(struct glsl_gen *g, const struct sl_insn *in)
{
	if (!need_args(g, in, 5))
		return;
	const int32_t *a = in->args;
	bool dirs = in->nargs >= 7;
	const char *kr = out_arg(g, in, a[3]), *kt = out_arg(g, in, a[4]);
	const char *R = dirs ? out_arg(g, in, a[5]) : "rl_fR";
	const char *T = dirs ? out_arg(g, in, a[6]) : "rl_fT";
	if (!kr || !kt || !R || !T)
		return;
	if (ncomp(g, a[3]) != 1 || ncomp(g, a[4]) != 1 ||
	    (dirs && (ncomp(g, a[5]) != 3 || ncomp(g, a[6]) != 3))) {
		sl_glsl_error(g, in, "invalid program: fresnel() output types");
		return;
	}
	sl_glsl_need(g, GH_FRESNEL);
	if (!dirs) {
		sl_glsl_line(g, "{");
		g->indent++;
		sl_glsl_line(g, "vec3 rl_fR, rl_fT;");
	}
	sl_glsl_line(g, "rl_fresnel(%s, %s, %s, %s, %s, %s, %s);", op(g, a[0], 3), op(g, a[1], 3),
		     op(g, a[2], 1), kr, kt, R, T);
	if (!dirs) {
		g->indent--;
		sl_glsl_line(g, "}");
	}
}

/* setxcomp / setycomp / setzcomp (p, v) and setcomp (c, i, v) / (m, row, col, v). */
static void call_setcomp(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	if (!need_args(g, in, 2))
		return;
	const int32_t *a = in->args;
	int nc = ncomp(g, a[0]);
	bool mat = nc == 16;
	int want = id == SL_BI_SETCOMP ? (mat ? 4 : 3) : 2;
	if (!need_args(g, in, want))
		return;
	const char *t = out_arg(g, in, a[0]);
	if (!t)
		return;
	const char *lv;
	if (id != SL_BI_SETCOMP) {
		int c = id - SL_BI_SETXCOMP;
		if (c >= nc)
			return;
		lv = nc == 1 ? t : SL_GLSL_FMT(g, "%s[%d]", t, c);
	} else if (mat) {
		sl_glsl_need(g, GH_CIDX);
		lv = SL_GLSL_FMT(g, "%s[rl_cidx(%s, 3)][rl_cidx(%s, 3)]", t, op(g, a[1], 1),
				 op(g, a[2], 1));
	} else {
		sl_glsl_need(g, GH_CIDX);
		lv = nc == 1 ? t : SL_GLSL_FMT(g, "%s[rl_cidx(%s, %d)]", t, op(g, a[1], 1), nc - 1);
	}
	sl_glsl_line(g, "%s = %s;", lv, op(g, a[want - 1], 1));
}

/* comp(c, i) / comp(m, row, col) */
static void call_comp(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const int32_t *a = in->args;
	int nc = ncomp(g, a[0]);
	if (nc == 16 && !need_args(g, in, 3))
		return;
	sl_glsl_need(g, GH_CIDX);
	const char *e;
	if (nc == 16)
		e = SL_GLSL_FMT(g, "%s[rl_cidx(%s, 3)][rl_cidx(%s, 3)]", op(g, a[0], 0),
				op(g, a[1], 1), op(g, a[2], 1));
	else if (nc == 3)
		e = SL_GLSL_FMT(g, "%s[rl_cidx(%s, 2)]", op(g, a[0], 0), op(g, a[1], 1));
	else
		e = op(g, a[0], 1);
	set_dst(g, in, e);
}

/* ---- coordinate systems ---- */

void sl_glsl_space_uniform(char *out, size_t cap, int light, const char *param)
{
	/* "l<k>S": never a parameter's uniform ("l<k>_NAME" or "l<k>U..."), no "__" */
	size_t n = (size_t)snprintf(out, cap, "l%dS", light);
	for (const char *c = param; *c && n + 3 < cap; c++) {
		if (isalnum((unsigned char)*c))
			out[n++] = *c;
		else
			n += (size_t)snprintf(out + n, cap - n, "_%02x", (unsigned char)*c);
	}
	out[n < cap ? n : cap - 1] = 0;
}

const char *sl_glsl_space_param(struct glsl_gen *g, const char *param)
{
	char u[320];
	sl_glsl_space_uniform(u, sizeof(u), g->cur->light, param);
	char decl[340];
	snprintf(decl, sizeof(decl), "uniform mat4 %s;\n", u);
	struct rl_strbuf *b = &g->sec[GS_UNIFORMS];
	if (!b->data || !strstr(b->data, decl))
		rl_strbuf_puts(b, decl);
	return SL_GLSL_FMT(g, "%s", u);
}

/*
 * The matrix of space register @r (that space -> current) as a GLSL
 * expression in *m, NULL for the identity. A light's string parameter names
 * a space the runtime binds as a uniform when the light is bound (an edit of
 * it rebinds); any other name not known here is a warning in a light.
 * False (an error) for a name the GPU cannot take.
 */
static bool space_of(struct glsl_gen *g, const struct sl_insn *in, int32_t r, const char **m)
{
	*m = NULL;
	const char *s = sl_glsl_cstr(g, r);
	if (s) {
		*m = sl_glsl_space(g, in, s);
		return true;
	}
	const char *param = g->cur->light >= 0 ? sl_glsl_string_param(g, r) : NULL;
	if (param) {
		*m = sl_glsl_space_param(g, param);
		return true;
	}
	if (g->cur->light >= 0) {
		sl_glsl_warning(g, in, "a coordinate system named by a variable that is not a "
				"parameter in a light shader: the GPU uses \"current\"");
		return true;
	}
	sl_glsl_error(g, in, "coordinate system names must be constant strings on the GPU");
	return false;
}

/*
 * The matrix of (from -> to) as a GLSL expression, NULL for the identity;
 * @a is from's matrix (from -> current), @b the matrix of "to" (to ->
 * current), @m a matrix expression that takes the place of current -> to
 * (NULL: none).
 */
static const char *space_product(struct glsl_gen *g, const char *a, const char *b,
				 const char *m)
{
	if (!m && b) {
		sl_glsl_need(g, GH_INVERSE);
		m = SL_GLSL_FMT(g, "rl_inverse(%s)", b);
	}
	if (a && m)
		return SL_GLSL_FMT(g, "rl_fin(%s * %s)", m, a);
	return a ? a : m;
}

/* transform / vtransform / ntransform: (to, v), (from, to, v), (m, v), (from, m, v). */
static void call_transform(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const struct sl_program *prog = g->cur->prog;
	const int32_t *a = in->args;
	int na = in->nargs > 3 ? 3 : in->nargs;
	int32_t val = a[na - 1], last = a[na - 2];
	int kind = id == SL_BI_VTRANSFORM ? 1 : id == SL_BI_NTRANSFORM ? 2 : 0;
	if (id == SL_BI_TRANSFORM) {
		if (prog->regs[val].type == SL_TYPE_VECTOR)
			kind = 1;
		else if (prog->regs[val].type == SL_TYPE_NORMAL)
			kind = 2;
	}
	const char *from = NULL, *to = NULL, *m = NULL;
	if (na == 3 && !space_of(g, in, a[0], &from))
		return;
	if (ncomp(g, last) == 16)
		m = op(g, last, 0);
	else if (!space_of(g, in, last, &to))
		return;
	const char *M = space_product(g, from, to, m);
	int nd = ncomp(g, in->dst);
	if (!M) {
		set_dst(g, in, fit3(g, nd, op(g, val, 3)));
		return;
	}
	static const char *const fn[] = { "rl_xpoint", "rl_xvector", "rl_xnormal" };
	sl_glsl_need(g, GH_XFORM);
	set_dst(g, in, fit3(g, nd, SL_GLSL_FMT(g, "%s(%s, %s)", fn[kind], M, op(g, val, 3))));
}

/* __spacematrix(space, m): m * (space -> current). */
static void call_spacematrix(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const char *s;
	if (!space_of(g, in, in->args[0], &s))
		return;
	const char *m = op(g, in->args[1], 16);
	set_dst(g, in, s ? SL_GLSL_FMT(g, "rl_fin(%s * %s)", s, m) : m);
}

/* Index of a color space name among mathlib.c's (case-insensitive), or -1. */
static int color_space(const char *name)
{
	static const char *const names[] = { "rgb", "hsv", "hsl", "xyz", "xyy", "yiq" };
	for (int i = 0; i < 6; i++)
		if (!strcasecmp(name, names[i]))
			return i;
	return -1;
}

/*
 * The linear map of mathlib.c's conversion from RGB to the linear space
 * @space (or back), as a GLSL mat3: its columns are the images of the unit
 * vectors, taken from mathlib itself.
 */
static const char *color_matrix(struct glsl_gen *g, const char *space, bool to_rgb)
{
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, "mat3(");
	for (int j = 0; j < 3; j++) {
		float e[3] = { 0, 0, 0 }, col[3];
		e[j] = 1;
		if (to_rgb)
			sl_color_to_rgb(space, e, col);
		else
			sl_color_from_rgb(space, e, col);
		for (int i = 0; i < 3; i++)
			rl_strbuf_printf(&b, "%s%s", i + j ? ", " : "", sl_glsl_float(g, col[i]));
	}
	rl_strbuf_putc(&b, ')');
	const char *s = rl_arena_strdup(g->arena, rl_strbuf_str(&b));
	rl_strbuf_finish(&b);
	return s;
}

static const char *to_rgb(struct glsl_gen *g, int cs, const char *c)
{
	switch (cs) {
	case 1: return SL_GLSL_FMT(g, "rl_hsv_rgb(%s)", c);
	case 2: return SL_GLSL_FMT(g, "rl_hsl_rgb(%s)", c);
	case 3: return SL_GLSL_FMT(g, "rl_fin(%s * %s)", color_matrix(g, "xyz", true), c);
	case 4: return SL_GLSL_FMT(g, "rl_fin(%s * rl_xyy_xyz(%s))", color_matrix(g, "xyz", true),
				   c);
	case 5: return SL_GLSL_FMT(g, "rl_fin(%s * %s)", color_matrix(g, "yiq", true), c);
	default: return c;
	}
}

static const char *from_rgb(struct glsl_gen *g, int cs, const char *c)
{
	switch (cs) {
	case 1: return SL_GLSL_FMT(g, "rl_rgb_hsv(%s)", c);
	case 2: return SL_GLSL_FMT(g, "rl_rgb_hsl(%s)", c);
	case 3: return SL_GLSL_FMT(g, "rl_fin(%s * %s)", color_matrix(g, "xyz", false), c);
	case 4: return SL_GLSL_FMT(g, "rl_xyz_xyy(rl_fin(%s * %s))", color_matrix(g, "xyz", false),
				   c);
	case 5: return SL_GLSL_FMT(g, "rl_fin(%s * %s)", color_matrix(g, "yiq", false), c);
	default: return c;
	}
}

/* ctransform(to, c) / ctransform(from, to, c) */
static void call_ctransform(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const int32_t *a = in->args;
	bool two = in->nargs >= 3;
	const char *from = two ? sl_glsl_cstr(g, a[0]) : "rgb";
	const char *to = sl_glsl_cstr(g, a[two ? 1 : 0]);
	if (!from || !to) {
		sl_glsl_error(g, in, "color space names must be constant strings on the GPU");
		return;
	}
	int cf = color_space(from), ct = color_space(to);
	if (cf < 0)
		sl_glsl_warning(g, in, "unknown color space '%s'", from);
	if (ct < 0)
		sl_glsl_warning(g, in, "unknown color space '%s'", to);
	sl_glsl_need(g, GH_COLOR);
	const char *c = op(g, a[two ? 2 : 1], 3);
	set_dst(g, in, fit3(g, ncomp(g, in->dst), from_rgb(g, ct, to_rgb(g, cf, c))));
}

/* ---- lighting ---- */

static void call_lighting(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	int want = id == SL_BI_AMBIENT ? 0 : id == SL_BI_DIFFUSE ? 1 : 3;
	if (in->dst < 0 || !need_args(g, in, want))
		return;
	if (g->cur->light >= 0) {
		unsupported(g, in, "light shaders cannot loop over the lights");
		return;
	}
	const int32_t *a = in->args;
	int32_t P = g->cur->prog->global_reg[SL_GLOBAL_P];
	const char *Ps = P >= 0 ? g->cur->name[P] : "vec3(0.0)";
	/* Lights that take derivatives of Ps get it moved along u and v too. */
	if (g->any_moved_ps)
		Ps = P >= 0 ? SL_GLSL_FMT(g, "%s, %s, %s", Ps, sl_glsl_moved(g, P, 3, 1),
					  sl_glsl_moved(g, P, 3, 2))
			    : "vec3(0.0), vec3(0.0), vec3(0.0)";
	const char *e;
	switch (id) {
	case SL_BI_AMBIENT:
		g->lighting[GL_AMBIENT] = true;
		e = SL_GLSL_FMT(g, "rl_ambient(%s)", Ps);
		break;
	case SL_BI_DIFFUSE:
		g->lighting[GL_DIFFUSE] = true;
		e = SL_GLSL_FMT(g, "rl_diffuse(%s, %s)", Ps, op(g, a[0], 3));
		break;
	default:
		g->lighting[id == SL_BI_SPECULAR ? GL_SPECULAR : GL_PHONG] = true;
		e = SL_GLSL_FMT(g, "%s(%s, %s, %s, %s)",
				id == SL_BI_SPECULAR ? "rl_specular" : "rl_phong", Ps, op(g, a[0], 3),
				op(g, a[1], 3), op(g, a[2], 1));
		break;
	}
	sl_glsl_need(g, GH_VEC);
	sl_glsl_need(g, GH_GEOM);
	sl_glsl_need(g, GH_SPECBRDF);
	set_dst(g, in, fit3(g, ncomp(g, in->dst), e));
}

/* Light @k's parameter @name as a float flag register, or NULL (lh_message's type rules). */
static const char *light_flag(struct glsl_gen *g, int k, const char *name)
{
	const struct sl_program *lp = g->lights[k];
	int pk = sl_program_find_param(lp, name);
	if (pk < 0)
		return NULL;
	int32_t r = lp->params[pk].reg;
	const struct sl_reg *rg = &lp->regs[r];
	if ((rg->type != SL_TYPE_FLOAT && rg->type != SL_TYPE_BOOL) || rg->arraylen ||
	    rg->kind == SL_REG_CONST)
		return NULL;
	return g->lp[k].name[r];
}

/* The part of diffuse(), specular() or phong() for light @k, after it ran. */
static void emit_lit(struct glsl_gen *g, enum glsl_lighting w, int k)
{
	const char *flag = light_flag(g, k, w == GL_DIFFUSE ? "__nondiffuse" : "__nonspecular");
	sl_glsl_line(g, "if (!rl_amb && rl_lit%s%s%s) {", flag ? " && !(" : "", flag ? flag : "",
		     flag ? " > 0.5)" : "");
	g->indent++;
	sl_glsl_line(g, "vec3 Ln = rl_normalize(rl_L);");
	sl_glsl_line(g, "float cosl = dot(Ln, Nn);");
	const char *k3 = w == GL_DIFFUSE ? "cosl" :
			 w == GL_SPECULAR ? "rl_specbrdf(Ln, N, V, rough)" :
			 "rl_pow(max(0.0, dot(R, Ln)), size)";
	sl_glsl_line(g, "if (cosl >= 0.0) acc = rl_fin(acc + rl_Cl * %s);", k3);
	g->indent--;
	sl_glsl_line(g, "}");
}

void sl_glsl_emit_lighting(struct glsl_gen *g, enum glsl_lighting w)
{
	static const char *const head[GL_COUNT][2] = {
		{ "vec3 rl_ambient(vec3 Ps", ") {" }, /* the lights' Ns: zero */
		{ "vec3 rl_diffuse(vec3 Ps", ", vec3 N) {" },
		{ "vec3 rl_specular(vec3 Ps", ", vec3 N, vec3 V, float rough) {" },
		{ "vec3 rl_phong(vec3 Ps", ", vec3 N, vec3 V, float size) {" },
	};
	g->out = &g->sec[GS_LIGHTING];
	g->indent = 0;
	sl_glsl_line(g, "%s%s%s", head[w][0], g->any_moved_ps ? ", vec3 Psu, vec3 Psv" : "",
		     head[w][1]);
	g->indent++;
	sl_glsl_line(g, "vec3 acc = vec3(0.0);");
	if (w != GL_AMBIENT)
		sl_glsl_line(g, "vec3 Nn = rl_normalize(N);");
	if (w == GL_PHONG)
		sl_glsl_line(g, "vec3 R = rl_reflect(-rl_normalize(V), Nn);");
	for (uint32_t k = 0; k < g->nlights; k++) {
		if (w != GL_AMBIENT && g->lp[k].static_ambient)
			continue;
		/* per-light passes: the pass's own light alone */
		bool gate = g->slice->per_light;
		if (gate) {
			sl_glsl_line(g, "if (rl_only == %u) {", k);
			g->indent++;
		}
		/* The lights' Ns: the normal given, none for ambient() (the light host's rule). */
		const char *Ns = w == GL_AMBIENT ? "vec3(0.0)" : "N";
		if (g->lp[k].moved_ps)
			sl_glsl_line(g, "light_%u(Ps, %s, Psu, Psv);", k, Ns);
		else
			sl_glsl_line(g, "light_%u(Ps, %s);", k, Ns);
		if (w == GL_AMBIENT)
			sl_glsl_line(g, g->lp[k].static_ambient ? "acc += rl_Cl;"
								: "if (rl_amb) acc += rl_Cl;");
		else
			emit_lit(g, w, (int)k);
		if (gate) {
			g->indent--;
			sl_glsl_line(g, "}");
		}
	}
	sl_glsl_line(g, "return rl_fin(acc);");
	g->indent--;
	sl_glsl_line(g, "}");
}

/* ---- textures ---- */

/* The "fill" option's value among the options from argument @k, or "0.0". */
static const char *fill_value(struct glsl_gen *g, const struct sl_insn *in, int k)
{
	const char *fill = "0.0";
	for (; k + 1 < in->nargs; k++) {
		const char *opt = is_string(g, in->args[k]) ? sl_glsl_cstr(g, in->args[k]) : NULL;
		if (opt && !strcmp(opt, "fill") && !is_string(g, in->args[k + 1]))
			fill = op(g, in->args[k + 1], 1);
	}
	return fill;
}

/* The value of option @r (its first component) as a float expression. */
static const char *opt_value(struct glsl_gen *g, int32_t r)
{
	int nc = ncomp(g, r);
	if (g->cur->prog->regs[r].arraylen)
		return SL_GLSL_FMT(g, "%s[0]%s", op(g, r, 0), nc == 3 ? "[0]" : nc == 16 ? "[0][0]" : "");
	return comp_of(g, r, op(g, r, 0), 0);
}

/*
 * shadow(name, channel, P, options...) or (..., P1, P2, P3, P4, ...) on
 * derivative stencils: a site of the layout, whose map is bound when the
 * kernel runs (the fill when none is), filtered as reyes_tex_shadow filters.
 * The corners around P are exec_builtins.c's tex_region on the stencil.
 */
static void call_shadow(struct glsl_gen *g, const struct sl_insn *in)
{
	const struct sl_program *prog = g->cur->prog;
	const int32_t *a = in->args;
	int ncoord = 0;
	while (2 + ncoord < in->nargs && prog->regs[a[2 + ncoord]].type != SL_TYPE_STRING)
		ncoord++;
	if (ncoord < 1) {
		sl_glsl_error(g, in, "shadow: missing direction");
		return;
	}
	const char *c[4], *center = "vec3(0.0)", *hasc = "false";
	if (ncoord >= 4) {
		for (int k = 0; k < 4; k++)
			c[k] = op(g, a[2 + k], 3);
		ncoord = 4;
	} else {
		if (!deriv_operand(g, in, a[2]))
			return;
		static const char *const su[4] = { "-0.5", "0.5", "0.5", "-0.5" };
		static const char *const sv[4] = { "-0.5", "-0.5", "0.5", "0.5" };
		center = op(g, a[2], 3);
		const char *du = step_diff3(g, a[2], 1), *dv = step_diff3(g, a[2], 2);
		for (int k = 0; k < 4; k++)
			c[k] = SL_GLSL_FMT(g, "rl_corner(%s, %s, %s, %s, %s)", center, du, dv, su[k],
					   sv[k]);
		hasc = "true";
		ncoord = 1;
	}
	/* The options, as exec_builtins.c tex_options reads them. */
	const char *sw = "1.0", *tw = "1.0", *sb = "0.0", *tb = "0.0", *samples = "16.0";
	const char *bias = "(-1.0)", *fill = "0.0";
	for (int k = 2 + ncoord; k < in->nargs; k += 2) {
		const char *opt = prog->regs[a[k]].type == SL_TYPE_STRING ? sl_glsl_cstr(g, a[k]) : NULL;
		if (prog->regs[a[k]].type != SL_TYPE_STRING || k + 1 >= in->nargs) {
			sl_glsl_warning(g, in, "shadow: options must be \"name\", value pairs");
			break;
		}
		if (!opt) {
			sl_glsl_error(g, in, "shadow() options must be constant strings on the GPU");
			return;
		}
		int32_t vr = a[k + 1];
		if (prog->regs[vr].type == SL_TYPE_STRING) {
			if (strcmp(opt, "filter") != 0)
				sl_glsl_warning(g, in, "shadow: unknown option '%s'", opt);
			continue;
		}
		const char *v = opt_value(g, vr);
		if (!strcmp(opt, "blur"))
			sb = tb = v;
		else if (!strcmp(opt, "sblur"))
			sb = v;
		else if (!strcmp(opt, "tblur"))
			tb = v;
		else if (!strcmp(opt, "width"))
			sw = tw = v;
		else if (!strcmp(opt, "swidth"))
			sw = v;
		else if (!strcmp(opt, "twidth"))
			tw = v;
		else if (!strcmp(opt, "samples"))
			samples = v;
		else if (!strcmp(opt, "bias"))
			bias = v;
		else if (!strcmp(opt, "fill"))
			fill = v;
		else
			sl_glsl_warning(g, in, "shadow: unknown option '%s'", opt);
	}
	int site = sl_glsl_shadow_site(g, in);
	if (site < 0 || in->dst < 0)
		return;
	sl_glsl_need(g, GH_SHADOW);
	const char *e = SL_GLSL_FMT(g, "rl_shadow(u_shadow%d, ivec2(u_shadow%d_size[0], "
				    "u_shadow%d_size[1]), u_shadow%d_deep != 0, u_to_world, "
				    "u_shadow%d_to_camera, u_shadow%d_to_ndc, u_shadow%d_bias, %s, %s, %s, "
				    "%s, %s, %s, %s, %s, %s, %s, %s, %s, %s)", site, site, site, site, site,
				    site, site, c[0], c[1], c[2], c[3], hasc, center, sw, tw, sb, tb,
				    samples, bias, fill);
	if (g->sites.data[site].raytrace) {
		/* the map name may be "raytrace": the light's position is its Ps - L */
		int32_t rl = prog->global_reg[SL_GLOBAL_L], rps = prog->global_reg[SL_GLOBAL_PS];
		if (rl < 0 || rps < 0) {
			sl_glsl_error(g, in, "shadow(\"raytrace\") outside an illuminate or solar "
				      "statement: no light position to trace toward");
			return;
		}
		sl_glsl_need(g, GH_RTSHADOW);
		e = SL_GLSL_FMT(g, "(u_shadow%d_rt != 0 ? rl_rt_shadow(u_bvh_nodes, u_bvh_tris, "
				"u_bvh_casts, u_to_world, %s, %s - %s, %s, u_trace_bias) : %s)", site,
				op(g, a[2], 3), op(g, rps, 3), op(g, rl, 3), bias, e);
	}
	set_dst(g, in, ncomp(g, in->dst) == 3 ? SL_GLSL_FMT(g, "vec3(%s)", e) : e);
}

/*
 * The options of texture() and environment() from argument @k on, as
 * exec_builtins.c tex_options reads them: o[0..4] swidth, twidth, sblur,
 * tblur, fill. False (an error) for an option whose name is not constant.
 */
static bool map_options(struct glsl_gen *g, const struct sl_insn *in, int k, const char *o[5])
{
	const struct sl_program *prog = g->cur->prog;
	const int32_t *a = in->args;
	o[0] = o[1] = "1.0";
	o[2] = o[3] = o[4] = "0.0";
	for (; k < in->nargs; k += 2) {
		if (prog->regs[a[k]].type != SL_TYPE_STRING || k + 1 >= in->nargs) {
			sl_glsl_warning(g, in, "%s: options must be \"name\", value pairs", bi_name(in));
			break;
		}
		const char *opt = sl_glsl_cstr(g, a[k]);
		if (!opt) {
			sl_glsl_error(g, in, "%s() options must be constant strings on the GPU",
				      bi_name(in));
			return false;
		}
		int32_t vr = a[k + 1];
		if (prog->regs[vr].type == SL_TYPE_STRING) {
			if (strcmp(opt, "filter") != 0)
				sl_glsl_warning(g, in, "%s: unknown option '%s'", bi_name(in), opt);
			continue;
		}
		const char *v = opt_value(g, vr);
		if (!strcmp(opt, "blur"))
			o[2] = o[3] = v;
		else if (!strcmp(opt, "sblur"))
			o[2] = v;
		else if (!strcmp(opt, "tblur"))
			o[3] = v;
		else if (!strcmp(opt, "width"))
			o[0] = o[1] = v;
		else if (!strcmp(opt, "swidth"))
			o[0] = v;
		else if (!strcmp(opt, "twidth"))
			o[1] = v;
		else if (!strcmp(opt, "fill"))
			o[4] = v;
		else if (strcmp(opt, "samples") && strcmp(opt, "bias"))
			sl_glsl_warning(g, in, "%s: unknown option '%s'", bi_name(in), opt);
	}
	return true;
}

/*
 * texture(name[channel], [s, t | s1, t1, ..., s4, t4], options...) and
 * environment(name[channel], D | D1, D2, D3, D4, options...) of a named
 * map on derivative stencils: a map site, whose map is bound when the kernel
 * runs (the fill when none is), filtered as reyes_tex_texture and
 * reyes_tex_environment filter. The corners around s, t or D are
 * exec_builtins.c's tex_region on the stencil.
 */
static void call_texmap(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	const struct sl_program *prog = g->cur->prog;
	const int32_t *a = in->args;
	static const char *const su[4] = { "-0.5", "0.5", "0.5", "-0.5" };
	static const char *const sv[4] = { "-0.5", "-0.5", "0.5", "0.5" };
	int ncoord = 0;
	while (2 + ncoord < in->nargs && prog->regs[a[2 + ncoord]].type != SL_TYPE_STRING)
		ncoord++;
	const char *c[8];
	if (id == SL_BI_TEXTURE) {
		if (ncoord >= 8) {
			for (int k = 0; k < 8; k++)
				c[k] = op(g, a[2 + k], 1);
			ncoord = 8;
		} else {
			int32_t st[2] = { ncoord >= 2 ? a[2] : prog->global_reg[SL_GLOBAL_S],
					  ncoord >= 2 ? a[3] : prog->global_reg[SL_GLOBAL_T] };
			for (int j = 0; j < 2; j++) {
				if (st[j] < 0) {
					sl_glsl_error(g, in, "texture: no s and t here");
					return;
				}
				if (!deriv_operand(g, in, st[j]))
					return;
				const char *v = op(g, st[j], 1), *du = step_diff(g, st[j], 0, 1);
				const char *dv = step_diff(g, st[j], 0, 2);
				for (int k = 0; k < 4; k++)
					c[2 * k + j] = SL_GLSL_FMT(g, "rl_corner1(%s, %s, %s, %s, %s)", v,
								   du, dv, su[k], sv[k]);
			}
			ncoord = ncoord >= 2 ? 2 : 0;
		}
	} else {
		if (ncoord < 1) {
			sl_glsl_error(g, in, "environment: missing direction");
			return;
		}
		if (ncoord >= 4) {
			for (int k = 0; k < 4; k++)
				c[k] = op(g, a[2 + k], 3);
			ncoord = 4;
		} else {
			if (!deriv_operand(g, in, a[2]))
				return;
			const char *v = op(g, a[2], 3), *du = step_diff3(g, a[2], 1);
			const char *dv = step_diff3(g, a[2], 2);
			for (int k = 0; k < 4; k++)
				c[k] = SL_GLSL_FMT(g, "rl_corner(%s, %s, %s, %s, %s)", v, du, dv, su[k],
						   sv[k]);
			ncoord = 1;
		}
	}
	const char *o[5];
	if (!map_options(g, in, 2 + ncoord, o))
		return;
	int site = sl_glsl_map_site(g, in, id == SL_BI_TEXTURE ? SL_GLSL_MAP_TEXTURE
							       : SL_GLSL_MAP_ENVIRONMENT);
	if (site < 0 || in->dst < 0)
		return;
	sl_glsl_need(g, GH_TEXMAP);
	int nc = ncomp(g, in->dst) == 3 ? 3 : 1;
	const char *e;
	if (id == SL_BI_TEXTURE)
		e = SL_GLSL_FMT(g, "rl_texture(u_map%d, %s, %d, vec4(%s, %s, %s, %s), "
				"vec4(%s, %s, %s, %s), %s, %s, %s, %s, %s)", site, op(g, a[1], 1), nc,
				c[0], c[2], c[4], c[6], c[1], c[3], c[5], c[7], o[0], o[1], o[2], o[3],
				o[4]);
	else
		e = SL_GLSL_FMT(g, "rl_environment(u_map%d, %s, %d, %s, %s, %s, %s, %s, %s, %s, %s, "
				"%s)", site, op(g, a[1], 1), nc, c[0], c[1], c[2], c[3], o[0], o[1], o[2],
				o[3], o[4]);
	set_dst(g, in, nc == 3 ? e : SL_GLSL_FMT(g, "%s.x", e));
}

/*
 * A light's texture() of four s, t corners or environment() of four
 * directions of a map a string parameter or a constant names: its filter
 * region needs no derivative, so it is a map site off derivative stencils
 * too.
 */
static bool corners_given(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	const struct sl_program *prog = g->cur->prog;
	if (g->cur->light < 0 ||
	    !(sl_glsl_cstr(g, in->args[0]) || sl_glsl_string_param(g, in->args[0])))
		return false;
	int ncoord = 0;
	while (2 + ncoord < (int)in->nargs && prog->regs[in->args[2 + ncoord]].type != SL_TYPE_STRING)
		ncoord++;
	return ncoord >= (id == SL_BI_TEXTURE ? 8 : 4);
}

/*
 * texture / environment / shadow / textureinfo: only the empty name, the
 * "no map" default of texture parameters, gives what the interpreter gives
 * for it (the fill value; textureinfo: not found).
 */
static void call_texture(struct glsl_gen *g, const struct sl_insn *in, int id)
{
	if (!need_args(g, in, id == SL_BI_TEXTUREINFO ? 3 : 2))
		return;
	const char *name = sl_glsl_cstr(g, in->args[0]);
	if (id == SL_BI_SHADOW && g->stencil && !(name && !*name)) {
		call_shadow(g, in);
		return;
	}
	if ((id == SL_BI_TEXTURE || id == SL_BI_ENVIRONMENT) && !(name && !*name) &&
	    (g->stencil || corners_given(g, in, id))) {
		call_texmap(g, in, id);
		return;
	}
	if (name && *name) {
		sl_glsl_error(g, in, "%s '%s' cannot be read on the GPU (texture files are not "
			      "supported)", bi_name(in), name);
		return;
	}
	if (!name)
		sl_glsl_warning(g, in, "%s() with a name that is not a constant: the GPU reads no "
				"file and gives what an empty name gives", bi_name(in));
	if (id == SL_BI_TEXTUREINFO) {
		set_dst(g, in, "0.0");
		return;
	}
	if (in->dst < 0)
		return;
	const char *fill = fill_value(g, in, 2);
	set_dst(g, in, ncomp(g, in->dst) == 3 ? SL_GLSL_FMT(g, "vec3(%s)", fill) : fill);
}

/* ---- message passing ---- */

static bool type_fits(int want, int have)
{
	if (want == have)
		return true;
	if (sl_type_is_triple(want) && sl_type_is_triple(have))
		return true;
	return (want == SL_TYPE_FLOAT || want == SL_TYPE_BOOL) &&
	       (have == SL_TYPE_FLOAT || have == SL_TYPE_BOOL);
}

/* lightsource(name, var): the parameter of the light an illuminance body visits. */
static void call_lightsource(struct glsl_gen *g, const struct sl_insn *in)
{
	if (!need_args(g, in, 2))
		return;
	int32_t out = in->args[1];
	const char *name = sl_glsl_cstr(g, in->args[0]);
	if (!name) {
		sl_glsl_error(g, in, "message names must be constant strings on the GPU");
		return;
	}
	int k = g->cur->light < 0 ? g->cur_light : -1;
	bool ok = false;
	if (k >= 0) {
		const struct sl_program *lp = g->lights[k];
		int pk = sl_program_find_param(lp, name);
		if (pk >= 0) {
			int32_t r = lp->params[pk].reg;
			const struct sl_reg *src = &lp->regs[r], *dst = &g->cur->prog->regs[out];
			ok = type_fits(dst->type, src->type) && src->arraylen == dst->arraylen;
			if (ok) {
				const char *lv = out_arg(g, in, out);
				const char *v = src->kind == SL_REG_CONST ? NULL : g->lp[k].name[r];
				if (!lv || !v)
					return;
				sl_glsl_line(g, "%s = %s;", lv, v);
			}
		}
	}
	set_dst(g, in, ok ? "1.0" : "0.0");
}

/* surface(name, var) in a light: the surface's parameter of that name. */
static void call_surface(struct glsl_gen *g, const struct sl_insn *in)
{
	if (!need_args(g, in, 2))
		return;
	int32_t out = in->args[1];
	const char *name = sl_glsl_cstr(g, in->args[0]);
	if (!name) {
		sl_glsl_error(g, in, "message names must be constant strings on the GPU");
		return;
	}
	bool ok = false;
	const struct sl_program *sp = g->surf;
	int pk = g->cur->light >= 0 ? sl_program_find_param(sp, name) : -1;
	if (pk >= 0) {
		int32_t r = sp->params[pk].reg;
		const struct sl_reg *src = &sp->regs[r], *dst = &g->cur->prog->regs[out];
		bool ps = src->type == SL_TYPE_STRING, xs = dst->type == SL_TYPE_STRING;
		ok = ps == xs && sl_glsl_ncomp(sp, r) == ncomp(g, out) &&
		     src->arraylen == dst->arraylen && src->kind != SL_REG_CONST;
		if (ok) {
			const char *lv = out_arg(g, in, out);
			if (!lv)
				return;
			sl_glsl_line(g, "%s = %s;", lv, g->sp.name[r]);
		}
	}
	set_dst(g, in, ok ? "1.0" : "0.0");
}

/* match(pattern, subject) of two compile-time strings. */
static void call_match(struct glsl_gen *g, const struct sl_insn *in)
{
	if (in->dst < 0 || !need_args(g, in, 2))
		return;
	const char *pat = sl_glsl_cstr(g, in->args[0]), *subj = sl_glsl_cstr(g, in->args[1]);
	if (!pat || !subj) {
		unsupported(g, in, "only constant strings can be matched");
		return;
	}
	regex_t re;
	bool m = false;
	if (regcomp(&re, pat, REG_EXTENDED | REG_NOSUB) == 0) {
		m = regexec(&re, subj, 0, NULL, 0) == 0;
		regfree(&re);
	} else {
		sl_glsl_warning(g, in, "match: invalid pattern '%s'", pat);
	}
	set_dst(g, in, m ? "1.0" : "0.0");
}

void sl_glsl_call(struct glsl_gen *g, const struct sl_insn *in)
{
	int id = sl_builtins[in->bi].id;
	switch ((enum sl_bi)id) {
	case SL_BI_RADIANS: case SL_BI_DEGREES: case SL_BI_SIN: case SL_BI_ASIN: case SL_BI_COS:
	case SL_BI_ACOS: case SL_BI_TAN: case SL_BI_ATAN: case SL_BI_SINH: case SL_BI_COSH:
	case SL_BI_TANH: case SL_BI_POW: case SL_BI_EXP: case SL_BI_SQRT: case SL_BI_INVERSESQRT:
	case SL_BI_LOG: case SL_BI_MOD: case SL_BI_ABS: case SL_BI_SIGN: case SL_BI_MIN:
	case SL_BI_MAX: case SL_BI_CLAMP: case SL_BI_MIX: case SL_BI_FLOOR: case SL_BI_CEIL:
	case SL_BI_ROUND: case SL_BI_STEP: case SL_BI_SMOOTHSTEP:
		call_math(g, in, id);
		break;
	case SL_BI_FILTERSTEP:
		call_filterstep(g, in);
		break;
	case SL_BI_SPLINE:
		call_spline(g, in);
		break;
	case SL_BI_NOISE: case SL_BI_PNOISE: case SL_BI_CELLNOISE:
		call_noise(g, in, id);
		break;
	case SL_BI_RANDOM:
		unsupported(g, in, "its per-point sequence cannot be reproduced");
		break;
	case SL_BI_XCOMP: case SL_BI_YCOMP: case SL_BI_ZCOMP: case SL_BI_LENGTH:
	case SL_BI_NORMALIZE: case SL_BI_DISTANCE: case SL_BI_PTLINED: case SL_BI_ROTATE:
	case SL_BI_FACEFORWARD: case SL_BI_REFLECT: case SL_BI_REFRACT:
	case SL_BI_SPECULARBRDF: case SL_BI_DETERMINANT: case SL_BI_TRANSLATE: case SL_BI_SCALE:
		call_geometry(g, in, id);
		break;
	case SL_BI_SETXCOMP: case SL_BI_SETYCOMP: case SL_BI_SETZCOMP: case SL_BI_SETCOMP:
		call_setcomp(g, in, id);
		break;
	case SL_BI_COMP:
		call_comp(g, in);
		break;
	case SL_BI_FRESNEL:
		call_fresnel(g, in);
		break;
	case SL_BI_TRANSFORM: case SL_BI_VTRANSFORM: case SL_BI_NTRANSFORM:
		call_transform(g, in, id);
		break;
	case SL_BI_SPACEMATRIX:
		call_spacematrix(g, in);
		break;
	case SL_BI_DEPTH:
		unsupported(g, in, "it needs the camera's clipping planes");
		break;
	case SL_BI_CTRANSFORM:
		call_ctransform(g, in);
		break;
	case SL_BI_DU: case SL_BI_DV: case SL_BI_DERIV: case SL_BI_AREA:
	case SL_BI_CALCULATENORMAL:
		call_deriv(g, in, id);
		break;
	case SL_BI_AMBIENT: case SL_BI_DIFFUSE: case SL_BI_SPECULAR: case SL_BI_PHONG:
		call_lighting(g, in, id);
		break;
	case SL_BI_TEXTURE: case SL_BI_ENVIRONMENT: case SL_BI_SHADOW: case SL_BI_TEXTUREINFO:
		call_texture(g, in, id);
		break;
	case SL_BI_LIGHTSOURCE:
		call_lightsource(g, in);
		break;
	case SL_BI_SURFACE:
		call_surface(g, in);
		break;
	case SL_BI_DISPLACEMENT: case SL_BI_ATMOSPHERE: case SL_BI_INCIDENT: case SL_BI_OPPOSITE:
		/* No peer shader is reachable from the GPU, as none is from a light host. */
		set_dst(g, in, "0.0");
		break;
	case SL_BI_ATTRIBUTE: case SL_BI_OPTION: case SL_BI_RENDERERINFO:
		unsupported(g, in, "the renderer cannot be asked from the GPU");
		break;
	case SL_BI_PRINTF:
		sl_glsl_warning(g, in, "printf() output is dropped on the GPU");
		break;
	case SL_BI_FORMAT: case SL_BI_CONCAT:
		unsupported(g, in, "strings cannot be built on the GPU");
		break;
	case SL_BI_MATCH:
		call_match(g, in);
		break;
	case SL_BI_TRACE: case SL_BI_TRANSMISSION: case SL_BI_OCCLUSION:
	case SL_BI_INDIRECTDIFFUSE: case SL_BI_RAYLEVEL: case SL_BI_ISSHADOWRAY: case SL_BI_RAYINFO:
		sl_glsl_error(g, in, "%s() casts rays, which only the renderer does: on the GPU it "
			      "is a value the bake keeps (it must not depend on the lights or on "
			      "edited parameters)", bi_name(in));
		break;
	case SL_BI_COUNT:
	default:
		sl_glsl_error(g, in, "invalid program: unknown built-in");
		break;
	}
}

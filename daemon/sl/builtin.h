/*
 * The built-in function library of RSL: every overload's name, signature and
 * implementation id. Semantic analysis resolves calls against this table; the
 * grid interpreter runs them by id (exec_builtins.c).
 */
#ifndef SL_BUILTIN_H
#define SL_BUILTIN_H

#include <stdint.h>

/** One id per built-in function (not per overload). */
enum sl_bi {
	/* math */
	SL_BI_RADIANS, SL_BI_DEGREES, SL_BI_SIN, SL_BI_ASIN, SL_BI_COS, SL_BI_ACOS,
	SL_BI_TAN, SL_BI_ATAN, SL_BI_SINH, SL_BI_COSH, SL_BI_TANH, SL_BI_POW, SL_BI_EXP,
	SL_BI_SQRT, SL_BI_INVERSESQRT, SL_BI_LOG, SL_BI_MOD, SL_BI_ABS, SL_BI_SIGN,
	SL_BI_MIN, SL_BI_MAX, SL_BI_CLAMP, SL_BI_MIX, SL_BI_FLOOR, SL_BI_CEIL,
	SL_BI_ROUND, SL_BI_STEP, SL_BI_SMOOTHSTEP, SL_BI_FILTERSTEP, SL_BI_SPLINE,
	/* noise */
	SL_BI_NOISE, SL_BI_PNOISE, SL_BI_CELLNOISE, SL_BI_RANDOM,
	/* geometry */
	SL_BI_XCOMP, SL_BI_YCOMP, SL_BI_ZCOMP, SL_BI_SETXCOMP, SL_BI_SETYCOMP, SL_BI_SETZCOMP,
	SL_BI_LENGTH, SL_BI_NORMALIZE, SL_BI_DISTANCE, SL_BI_PTLINED, SL_BI_ROTATE,
	SL_BI_AREA, SL_BI_FACEFORWARD, SL_BI_REFLECT, SL_BI_REFRACT, SL_BI_FRESNEL,
	SL_BI_TRANSFORM, SL_BI_VTRANSFORM, SL_BI_NTRANSFORM, SL_BI_DEPTH,
	SL_BI_CALCULATENORMAL, SL_BI_DU, SL_BI_DV, SL_BI_DERIV,
	/* colors */
	SL_BI_COMP, SL_BI_SETCOMP, SL_BI_CTRANSFORM,
	/* matrices */
	SL_BI_DETERMINANT, SL_BI_TRANSLATE, SL_BI_SCALE,
	/* shading and lighting */
	SL_BI_AMBIENT, SL_BI_DIFFUSE, SL_BI_SPECULAR, SL_BI_SPECULARBRDF, SL_BI_PHONG,
	/* textures */
	SL_BI_TEXTURE, SL_BI_ENVIRONMENT, SL_BI_SHADOW, SL_BI_TEXTUREINFO,
	/* message passing and queries */
	SL_BI_ATMOSPHERE, SL_BI_DISPLACEMENT, SL_BI_INCIDENT, SL_BI_OPPOSITE,
	SL_BI_LIGHTSOURCE, SL_BI_SURFACE, SL_BI_ATTRIBUTE, SL_BI_OPTION, SL_BI_RENDERERINFO,
	/* strings */
	SL_BI_PRINTF, SL_BI_FORMAT, SL_BI_CONCAT, SL_BI_MATCH,
	/* internal: m * (space -> current), for `matrix "space" (...)` */
	SL_BI_SPACEMATRIX,
	/* ray tracing (exec_raytrace.c): through struct sl_host's trace and rayinfo */
	SL_BI_TRACE, SL_BI_TRANSMISSION, SL_BI_OCCLUSION, SL_BI_INDIRECTDIFFUSE,
	SL_BI_RAYLEVEL, SL_BI_ISSHADOWRAY, SL_BI_RAYINFO,
	SL_BI_COUNT
};

enum {
	SL_BIF_VARYING = 1 << 0,     /* result is varying whatever the arguments */
	SL_BIF_DERIV = 1 << 1,       /* takes derivatives over the grid */
	SL_BIF_LIGHTS = 1 << 2,      /* loops over the lights (result varying) */
	SL_BIF_TEXNAME = 1 << 3,     /* first argument is a texture name that may carry [channel];
					semantic analysis inserts the channel (float) as argument 2 */
	SL_BIF_SIDE_EFFECT = 1 << 4, /* printing: never removed as dead code */
	SL_BIF_MESSAGE = 1 << 5,     /* message passing: reads another shader or the renderer */
	SL_BIF_GLOBALS = 1 << 6,     /* reads global variables not among its arguments */
	SL_BIF_RAYS = 1 << 7,        /* casts rays: runs in the renderer, never on the GPU */
	SL_BIF_RAYLIT = 1 << 8,      /* brings back light from what its rays hit (lit by the
					lights there): a bake freezes it */
};

/**
 * Signature: "R:ARGS". Letters: f float, c color, p point, v vector,
 * n normal, m matrix, s string, '-' void (results only), '?' any type
 * (message passing), F C P V N: arrays of float, color, point, vector, normal.
 * A '&' before a letter marks an output argument. A final '*' accepts any
 * further arguments (printf/format/concat values, or texture-style
 * "name", value option pairs). point, vector and normal arguments accept any
 * of the three; floats are promoted to triples where no better overload fits.
 */
struct sl_builtin {
	const char *name;
	const char *sig;
	uint16_t id;     /* enum sl_bi */
	uint16_t flags;
};

extern const struct sl_builtin sl_builtins[];
extern const uint32_t sl_nbuiltins;

/** Index of the first overload named @name (the overloads are contiguous), or -1. */
int sl_builtin_find(const char *name);

/** Name of an id (for messages). */
const char *sl_bi_name(enum sl_bi id);

#endif

/*
 * The built-in function table. Overloads of one name are contiguous; the
 * order within a name matters only to break ties (the first listed wins),
 * so float results come first where the result type is polymorphic.
 */
#include "builtin.h"

#include <string.h>

#define V SL_BIF_VARYING
#define D SL_BIF_DERIV
#define LI SL_BIF_LIGHTS
#define TX SL_BIF_TEXNAME
#define SE SL_BIF_SIDE_EFFECT
#define MSG SL_BIF_MESSAGE
#define G SL_BIF_GLOBALS
#define RAY SL_BIF_RAYS
#define LIT SL_BIF_RAYLIT

/* Overloads of a function that maps float to float and triple to triple componentwise. */
#define COMPONENTWISE1(name, id) \
	{ name, "f:f", id, 0 }, { name, "c:c", id, 0 }, { name, "p:p", id, 0 }, \
	{ name, "v:v", id, 0 }, { name, "n:n", id, 0 }
#define COMPONENTWISE2(name, id) \
	{ name, "f:ff", id, 0 }, { name, "c:cc", id, 0 }, { name, "p:pp", id, 0 }, \
	{ name, "v:vv", id, 0 }, { name, "n:nn", id, 0 }
/* Functions whose result type is chosen by context: float, color, point, vector. */
#define POLY(name, args, id, fl) \
	{ name, "f:" args, id, fl }, { name, "c:" args, id, fl }, { name, "p:" args, id, fl }, \
	{ name, "v:" args, id, fl }

const struct sl_builtin sl_builtins[] = {
	/* math */
	{ "radians", "f:f", SL_BI_RADIANS, 0 },
	{ "degrees", "f:f", SL_BI_DEGREES, 0 },
	{ "sin", "f:f", SL_BI_SIN, 0 },
	{ "asin", "f:f", SL_BI_ASIN, 0 },
	{ "cos", "f:f", SL_BI_COS, 0 },
	{ "acos", "f:f", SL_BI_ACOS, 0 },
	{ "tan", "f:f", SL_BI_TAN, 0 },
	{ "atan", "f:f", SL_BI_ATAN, 0 },
	{ "atan", "f:ff", SL_BI_ATAN, 0 },
	{ "sinh", "f:f", SL_BI_SINH, 0 },
	{ "cosh", "f:f", SL_BI_COSH, 0 },
	{ "tanh", "f:f", SL_BI_TANH, 0 },
	COMPONENTWISE2("pow", SL_BI_POW),
	{ "pow", "c:cf", SL_BI_POW, 0 },
	COMPONENTWISE1("exp", SL_BI_EXP),
	COMPONENTWISE1("sqrt", SL_BI_SQRT),
	COMPONENTWISE1("inversesqrt", SL_BI_INVERSESQRT),
	{ "log", "f:f", SL_BI_LOG, 0 },
	{ "log", "f:ff", SL_BI_LOG, 0 },
	COMPONENTWISE2("mod", SL_BI_MOD),
	{ "mod", "c:cf", SL_BI_MOD, 0 },
	{ "mod", "p:pf", SL_BI_MOD, 0 },
	{ "mod", "v:vf", SL_BI_MOD, 0 },
	COMPONENTWISE1("abs", SL_BI_ABS),
	COMPONENTWISE1("sign", SL_BI_SIGN),
	COMPONENTWISE2("min", SL_BI_MIN),
	{ "min", "f:fff*", SL_BI_MIN, 0 },
	{ "min", "c:ccc*", SL_BI_MIN, 0 },
	COMPONENTWISE2("max", SL_BI_MAX),
	{ "max", "f:fff*", SL_BI_MAX, 0 },
	{ "max", "c:ccc*", SL_BI_MAX, 0 },
	{ "clamp", "f:fff", SL_BI_CLAMP, 0 },
	{ "clamp", "c:ccc", SL_BI_CLAMP, 0 },
	{ "clamp", "p:ppp", SL_BI_CLAMP, 0 },
	{ "clamp", "v:vvv", SL_BI_CLAMP, 0 },
	{ "clamp", "n:nnn", SL_BI_CLAMP, 0 },
	{ "mix", "f:fff", SL_BI_MIX, 0 },
	{ "mix", "c:ccf", SL_BI_MIX, 0 },
	{ "mix", "p:ppf", SL_BI_MIX, 0 },
	{ "mix", "v:vvf", SL_BI_MIX, 0 },
	{ "mix", "n:nnf", SL_BI_MIX, 0 },
	{ "mix", "c:ccc", SL_BI_MIX, 0 },
	COMPONENTWISE1("floor", SL_BI_FLOOR),
	COMPONENTWISE1("ceil", SL_BI_CEIL),
	COMPONENTWISE1("round", SL_BI_ROUND),
	{ "step", "f:ff", SL_BI_STEP, 0 },
	{ "smoothstep", "f:fff", SL_BI_SMOOTHSTEP, 0 },
	/* filterstep(edge, s1 [, s2] [, "width", w ...]) */
	{ "filterstep", "f:ff*", SL_BI_FILTERSTEP, D },
	{ "filterstep", "f:fff*", SL_BI_FILTERSTEP, D },
	/* spline([basis,] t, v0, v1, v2, v3, ...) and spline([basis,] t, array) */
	{ "spline", "f:fffff*", SL_BI_SPLINE, 0 },
	{ "spline", "c:fcccc*", SL_BI_SPLINE, 0 },
	{ "spline", "p:fpppp*", SL_BI_SPLINE, 0 },
	{ "spline", "v:fvvvv*", SL_BI_SPLINE, 0 },
	{ "spline", "f:sfffff*", SL_BI_SPLINE, 0 },
	{ "spline", "c:sfcccc*", SL_BI_SPLINE, 0 },
	{ "spline", "p:sfpppp*", SL_BI_SPLINE, 0 },
	{ "spline", "v:sfvvvv*", SL_BI_SPLINE, 0 },
	{ "spline", "f:fF", SL_BI_SPLINE, 0 },
	{ "spline", "c:fC", SL_BI_SPLINE, 0 },
	{ "spline", "p:fP", SL_BI_SPLINE, 0 },
	{ "spline", "v:fV", SL_BI_SPLINE, 0 },
	{ "spline", "f:sfF", SL_BI_SPLINE, 0 },
	{ "spline", "c:sfC", SL_BI_SPLINE, 0 },
	{ "spline", "p:sfP", SL_BI_SPLINE, 0 },
	{ "spline", "v:sfV", SL_BI_SPLINE, 0 },

	/* noise */
	POLY("noise", "f", SL_BI_NOISE, 0),
	POLY("noise", "ff", SL_BI_NOISE, 0),
	POLY("noise", "p", SL_BI_NOISE, 0),
	POLY("noise", "pf", SL_BI_NOISE, 0),
	POLY("pnoise", "ff", SL_BI_PNOISE, 0),
	POLY("pnoise", "ffff", SL_BI_PNOISE, 0),
	POLY("pnoise", "pp", SL_BI_PNOISE, 0),
	POLY("pnoise", "pfpf", SL_BI_PNOISE, 0),
	POLY("cellnoise", "f", SL_BI_CELLNOISE, 0),
	POLY("cellnoise", "ff", SL_BI_CELLNOISE, 0),
	POLY("cellnoise", "p", SL_BI_CELLNOISE, 0),
	POLY("cellnoise", "pf", SL_BI_CELLNOISE, 0),
	POLY("random", "", SL_BI_RANDOM, V),

	/* geometry */
	{ "xcomp", "f:p", SL_BI_XCOMP, 0 },
	{ "ycomp", "f:p", SL_BI_YCOMP, 0 },
	{ "zcomp", "f:p", SL_BI_ZCOMP, 0 },
	{ "setxcomp", "-:&pf", SL_BI_SETXCOMP, 0 },
	{ "setycomp", "-:&pf", SL_BI_SETYCOMP, 0 },
	{ "setzcomp", "-:&pf", SL_BI_SETZCOMP, 0 },
	{ "length", "f:v", SL_BI_LENGTH, 0 },
	{ "normalize", "v:v", SL_BI_NORMALIZE, 0 },
	{ "distance", "f:pp", SL_BI_DISTANCE, 0 },
	{ "ptlined", "f:ppp", SL_BI_PTLINED, 0 },
	{ "rotate", "p:pfpp", SL_BI_ROTATE, 0 },
	{ "rotate", "m:mfv", SL_BI_ROTATE, 0 },
	{ "area", "f:p", SL_BI_AREA, D },
	{ "faceforward", "v:vv", SL_BI_FACEFORWARD, G },
	{ "faceforward", "v:vvv", SL_BI_FACEFORWARD, 0 },
	{ "reflect", "v:vv", SL_BI_REFLECT, 0 },
	{ "refract", "v:vvf", SL_BI_REFRACT, 0 },
	{ "fresnel", "-:vvf&f&f", SL_BI_FRESNEL, 0 },
	{ "fresnel", "-:vvf&f&f&v&v", SL_BI_FRESNEL, 0 },
	{ "transform", "p:sp", SL_BI_TRANSFORM, 0 },
	{ "transform", "p:ssp", SL_BI_TRANSFORM, 0 },
	{ "transform", "p:mp", SL_BI_TRANSFORM, 0 },
	{ "transform", "p:smp", SL_BI_TRANSFORM, 0 },
	{ "vtransform", "v:sv", SL_BI_VTRANSFORM, 0 },
	{ "vtransform", "v:ssv", SL_BI_VTRANSFORM, 0 },
	{ "vtransform", "v:mv", SL_BI_VTRANSFORM, 0 },
	{ "vtransform", "v:smv", SL_BI_VTRANSFORM, 0 },
	{ "ntransform", "n:sn", SL_BI_NTRANSFORM, 0 },
	{ "ntransform", "n:ssn", SL_BI_NTRANSFORM, 0 },
	{ "ntransform", "n:mn", SL_BI_NTRANSFORM, 0 },
	{ "ntransform", "n:smn", SL_BI_NTRANSFORM, 0 },
	{ "depth", "f:p", SL_BI_DEPTH, 0 },
	{ "calculatenormal", "n:p", SL_BI_CALCULATENORMAL, D },
	{ "Du", "f:f", SL_BI_DU, D },
	{ "Du", "c:c", SL_BI_DU, D },
	{ "Du", "v:p", SL_BI_DU, D },
	{ "Dv", "f:f", SL_BI_DV, D },
	{ "Dv", "c:c", SL_BI_DV, D },
	{ "Dv", "v:p", SL_BI_DV, D },
	{ "Deriv", "f:ff", SL_BI_DERIV, D },
	{ "Deriv", "c:cf", SL_BI_DERIV, D },
	{ "Deriv", "v:pf", SL_BI_DERIV, D },

	/* colors and components */
	{ "comp", "f:cf", SL_BI_COMP, 0 },
	{ "comp", "f:pf", SL_BI_COMP, 0 },
	{ "comp", "f:mff", SL_BI_COMP, 0 },
	{ "setcomp", "-:&cff", SL_BI_SETCOMP, 0 },
	{ "setcomp", "-:&pff", SL_BI_SETCOMP, 0 },
	{ "setcomp", "-:&mfff", SL_BI_SETCOMP, 0 },
	{ "ctransform", "c:sc", SL_BI_CTRANSFORM, 0 },
	{ "ctransform", "c:ssc", SL_BI_CTRANSFORM, 0 },

	/* matrices */
	{ "determinant", "f:m", SL_BI_DETERMINANT, 0 },
	{ "translate", "m:mv", SL_BI_TRANSLATE, 0 },
	{ "scale", "m:mp", SL_BI_SCALE, 0 },

	/* shading and lighting: these read P (and N/I where the spec says) and the lights */
	{ "ambient", "c:", SL_BI_AMBIENT, LI | V | G },
	{ "diffuse", "c:n", SL_BI_DIFFUSE, LI | V | G },
	{ "specular", "c:nvf", SL_BI_SPECULAR, LI | V | G },
	{ "specularbrdf", "c:vnvf", SL_BI_SPECULARBRDF, 0 },
	{ "phong", "c:nvf", SL_BI_PHONG, LI | V | G },

	/* textures: name[channel], coordinates, then "option", value pairs */
	{ "texture", "f:s*", SL_BI_TEXTURE, TX | D | G },
	{ "texture", "c:s*", SL_BI_TEXTURE, TX | D | G },
	{ "texture", "f:sff*", SL_BI_TEXTURE, TX | D },
	{ "texture", "c:sff*", SL_BI_TEXTURE, TX | D },
	{ "texture", "f:sffffffff*", SL_BI_TEXTURE, TX },
	{ "texture", "c:sffffffff*", SL_BI_TEXTURE, TX },
	{ "environment", "f:sv*", SL_BI_ENVIRONMENT, TX | D },
	{ "environment", "c:sv*", SL_BI_ENVIRONMENT, TX | D },
	{ "environment", "f:svvvv*", SL_BI_ENVIRONMENT, TX },
	{ "environment", "c:svvvv*", SL_BI_ENVIRONMENT, TX },
	{ "shadow", "f:sp*", SL_BI_SHADOW, TX | D },
	{ "shadow", "f:spppp*", SL_BI_SHADOW, TX },
	{ "textureinfo", "f:ss&?", SL_BI_TEXTUREINFO, MSG },

	/* message passing and queries: (name, output variable) -> 1 if found */
	{ "atmosphere", "f:s&?", SL_BI_ATMOSPHERE, MSG },
	{ "displacement", "f:s&?", SL_BI_DISPLACEMENT, MSG },
	{ "incident", "f:s&?", SL_BI_INCIDENT, MSG },
	{ "opposite", "f:s&?", SL_BI_OPPOSITE, MSG },
	{ "lightsource", "f:s&?", SL_BI_LIGHTSOURCE, MSG },
	{ "surface", "f:s&?", SL_BI_SURFACE, MSG },
	{ "attribute", "f:s&?", SL_BI_ATTRIBUTE, MSG },
	{ "option", "f:s&?", SL_BI_OPTION, MSG },
	{ "rendererinfo", "f:s&?", SL_BI_RENDERERINFO, MSG },

	/* strings */
	{ "printf", "-:s*", SL_BI_PRINTF, SE },
	{ "format", "s:s*", SL_BI_FORMAT, 0 },
	{ "concat", "s:ss*", SL_BI_CONCAT, 0 },
	{ "concat", "s:s", SL_BI_CONCAT, 0 },
	{ "match", "f:ss", SL_BI_MATCH, 0 },

	/* internal, emitted by the compiler for `matrix "space" (...)` */
	{ "__spacematrix", "m:sm", SL_BI_SPACEMATRIX, 0 },

	/* ray tracing: "name", value options after the fixed arguments */
	{ "trace", "c:pv*", SL_BI_TRACE, V | RAY | LIT },
	{ "trace", "f:pv*", SL_BI_TRACE, V | RAY },
	{ "transmission", "c:pp*", SL_BI_TRANSMISSION, V | RAY },
	{ "occlusion", "f:pnf*", SL_BI_OCCLUSION, V | RAY },
	{ "occlusion", "f:pn*", SL_BI_OCCLUSION, V | RAY },
	{ "indirectdiffuse", "c:pnf*", SL_BI_INDIRECTDIFFUSE, V | RAY | LIT },
	{ "indirectdiffuse", "c:pn*", SL_BI_INDIRECTDIFFUSE, V | RAY | LIT },
	{ "raylevel", "f:", SL_BI_RAYLEVEL, V | MSG },
	{ "isshadowray", "f:", SL_BI_ISSHADOWRAY, V | MSG },
	{ "rayinfo", "f:s&?", SL_BI_RAYINFO, MSG },
};

const uint32_t sl_nbuiltins = sizeof(sl_builtins) / sizeof(sl_builtins[0]);

int sl_builtin_find(const char *name)
{
	/* A linear scan is fine: it runs once per call site at compile time. */
	for (uint32_t i = 0; i < sl_nbuiltins; i++)
		if (!strcmp(sl_builtins[i].name, name))
			return (int)i;
	return -1;
}

const char *sl_bi_name(enum sl_bi id)
{
	for (uint32_t i = 0; i < sl_nbuiltins; i++)
		if (sl_builtins[i].id == id)
			return sl_builtins[i].name;
	return "?";
}

/*
 * The scene the REYES renderer draws: options (camera, image, displays),
 * attribute bundles, shader instances, lights and primitives, as the RIB
 * scene builder (ri.c) leaves them after WorldEnd. Matrices are 4x4,
 * row-major, RenderMan's row-vector convention (p' = p M, translation in
 * elements 12..14). Everything lives in the scene's arena.
 */
#ifndef REYES_SCENE_H
#define REYES_SCENE_H

#include "csg.h"
#include "exec.h"
#include "rib.h"

#include <stdbool.h>
#include <stdint.h>

enum reyes_filter {
	REYES_FILTER_BOX,
	REYES_FILTER_TRIANGLE,
	REYES_FILTER_CATMULLROM,
	REYES_FILTER_GAUSSIAN,
	REYES_FILTER_SINC,
	REYES_FILTER_SEP_CATMULLROM,
	REYES_FILTER_SEP_GAUSSIAN,
};

enum reyes_depthfilter { REYES_DEPTH_MIN, REYES_DEPTH_MAX, REYES_DEPTH_AVERAGE,
			 REYES_DEPTH_MIDPOINT };

/** One Display request. */
struct reyes_display {
	const char *name;       /* output file name ("+name" already stripped) */
	const char *type;       /* "file", "openexr", "framebuffer", "zfile", "shadow", ... */
	const char *mode;       /* "rgba", "rgb", "a", "z", "rgbaz", or an output variable (AOV) */
	bool half;              /* write half floats (default for colour); "float" asked for float */
	bool png;               /* write an 8-bit sRGB PNG instead of OpenEXR (set by the caller) */
	const char *file;       /* where it was requested */
	uint32_t line;
	float deep_error;       /* "deepshad": the functions' error bound (deepshadow.h) */
};

struct reyes_options {
	uint32_t xres, yres;            /* Format (default 640 480) */
	/* Where Format, PixelSamples and CropWindow were given (file NULL: not given) */
	struct rib_loc format_loc, samples_loc, crop_loc;
	float pixel_aspect;             /* default 1 */
	float frame_aspect;             /* FrameAspectRatio, 0: xres*pixel_aspect/yres */
	float screen[4];                /* ScreenWindow left right bottom top */
	bool screen_set;                /* else derived from frame_aspect */
	float crop[4];                  /* CropWindow xmin xmax ymin ymax (NDC), default 0 1 0 1 */
	bool perspective;               /* Projection "perspective" (else orthographic) */
	float fov;                      /* degrees, default 90 */
	float clip_near, clip_far;      /* Clipping, default epsilon and infinity (1e30) */
	float shutter[2];               /* Shutter, default 0 0 */
	uint32_t xsamples, ysamples;    /* PixelSamples, default 2 2 */
	enum reyes_filter filter;       /* PixelFilter, default gaussian 2 2 */
	float filter_width[2];
	float gain, gamma;              /* Exposure, default 1 1 */
	/* Imager: run on the final pixels before Exposure (NULL: none) */
	const struct reyes_shader *imager;
	struct rib_loc imager_loc;
	struct reyes_display *displays; /* in order; default one "file" rgba display */
	uint32_t ndisplays;
	bool numbered;                  /* the world is in a FrameBegin: frame_number is its number */
	int32_t frame_number;
	enum reyes_depthfilter depthfilter; /* Hider "hidden" "depthfilter", default min */
	bool jitter;                    /* Hider "hidden" "jitter", default on */
	float opacity_threshold;        /* a sample this opaque hides what is behind (0.996) */
	const char *shader_path;        /* Option "searchpath": colon-separated, after & and @ */
	const char *texture_path;
	const char *archive_path;
	const char *include_path;       /* where shaders' #include look after their own folder */
	/* Option "shading" "specularmodel": specular()'s highlight (default 0, PRMan's) */
	enum sl_specular_model specular_model;
	uint32_t trace_maxdepth;        /* Option "trace" "maxdepth": rays in a path (default 10) */
	float world_to_camera[16];      /* the transform at WorldBegin (at shutter open) */
	float world_to_camera1[16];     /* at shutter close: a moving camera's second sample */
	bool camera_moving;             /* world_to_camera1 differs from world_to_camera */
	float fstop;                    /* DepthOfField; 0: none (a pinhole camera) */
	float focallength, focaldistance;
	float camera_to_screen[16];     /* projection (from fov or orthographic) */
};

/** Parameter values given to a shader instance in RIB (typed by Declare or the shader). */
struct reyes_param_value {
	const char *name;
	int type;                       /* enum sl_basetype */
	uint32_t arraylen;              /* 0: not an array */
	uint32_t nvalues;               /* floats (or strings) given */
	const float *values;
	const char *const *strings;
};

/** A Surface, Displacement or LightSource request. */
struct reyes_shader {
	const char *name;               /* shader name as written */
	struct sl_program *prog;        /* compiled once per scene and shared */
	const struct reyes_param_value *params;
	uint32_t nparams;
	float shader_to_world[16];      /* "shader" space: the current transform at the request */
};

struct reyes_light {
	struct reyes_shader shader;
	const char *handle;             /* "1", "key", ... */
	bool default_on;                /* lights are on where declared (Illuminate changes it) */
	uint32_t index;                 /* position in scene->lights */
};

/** An attribute bundle: shared by all primitives declared while it was current. */
/* How a primitive's hits by a ray type are shaded (Attribute "shade" "...hitmode"). */
enum reyes_hitmode { REYES_HIT_PRIMITIVE, REYES_HIT_SHADER };

/* What shadow rays see of a primitive (Attribute "visibility" "transmission"). */
enum reyes_transmission {
	REYES_TRANS_NONE,     /* 0, "transparent": not seen */
	REYES_TRANS_OPAQUE,   /* "opaque": blocks all light */
	REYES_TRANS_OS,       /* 1, "Os", "shader": lets 1 - Os through */
};

/* Ray tracing (ri.c): which rays see the primitive, and how. */
struct reyes_ray_attrs {
	bool camera;                  /* "visibility" "camera" (default 1): the hider sees it */
	bool specular, diffuse;       /* seen by specular and diffuse rays (default 0) */
	uint8_t transmission;         /* enum reyes_transmission (default REYES_TRANS_OS) */
	uint8_t hitmode[3];           /* enum reyes_hitmode per enum sl_ray_type */
	float bias;                   /* Attribute "trace" "bias" (default 0.01) */
	uint32_t max_specular_depth;  /* "maxspeculardepth" (default 2) */
	uint32_t max_diffuse_depth;   /* "maxdiffusedepth" (default 1) */
};

struct reyes_attrs {
	float Cs[3], Os[3];                   /* Color, Opacity */
	const struct reyes_shader *surface;   /* NULL: the default surface */
	const struct reyes_shader *displacement;
	const uint32_t *lights;               /* indices of the lights that are on */
	uint32_t nlights;
	int sides;                            /* 1 or 2 */
	bool flip_normals;                    /* Orientation / ReverseOrientation vs handedness */
	float shading_rate;                   /* area in pixels per micropolygon, default 1 */
	struct rib_loc shading_rate_loc;      /* its ShadingRate request (file NULL: the default) */
	bool smooth;                          /* ShadingInterpolation "smooth" (default constant) */
	const char *identifier;               /* Attribute "identifier" "name" */
	float displacement_bound;             /* Attribute "displacementbound" "sphere" */
	const char *displacement_bound_space; /* its coordinate system, default "object" */
	bool casts_shadows;                   /* Attribute "visibility" "transmission" (default on) */
	struct reyes_ray_attrs ray;
	bool matte;                           /* Matte: hides what is behind, adds no colour or alpha */
	/* TextureCoordinates: s, t at (u, v) = (0, 0), (1, 0), (0, 1), (1, 1), for
	   quadrics and patches without s, t of their own; NULL: s = u, t = v. */
	const float *texcoords;
	/* DetailRange's cross-fade: when dissolve is set, only a subpixel sample
	   whose dissolve number (uniform in [0, 1), the hider's) is in
	   [lod_lo, lod_hi) sees the primitive. */
	bool dissolve;
	float lod_lo, lod_hi;
	bool moving;                          /* object_to_world differs at shutter close */
	float object_to_world[2][16];         /* at shutter open and close */
};

struct reyes_nurbs;

enum reyes_class { REYES_CONSTANT, REYES_UNIFORM, REYES_VARYING, REYES_VERTEX, REYES_FACEVARYING };

/** A primitive variable: P, N, Cs, Os, s, t, st, or user data for shader parameters. */
struct reyes_primvar {
	const char *name;
	enum reyes_class cls;
	int type;                             /* enum sl_basetype */
	uint32_t arraylen;                    /* 0: not an array */
	uint32_t count;                       /* number of items (per class: 1, faces, corners...) */
	const float *values;                  /* count * ncomp * max(1, arraylen) */
	const float *values1;                 /* at shutter close (deforming motion), or NULL */
};

enum reyes_prim_kind {
	REYES_SPHERE,       /* q: radius zmin zmax thetamax */
	REYES_CYLINDER,     /* q: radius zmin zmax thetamax */
	REYES_CONE,         /* q: height radius thetamax */
	REYES_DISK,         /* q: height radius thetamax */
	REYES_HYPERBOLOID,  /* q: x1 y1 z1 x2 y2 z2 thetamax */
	REYES_PARABOLOID,   /* q: rmax zmin zmax thetamax */
	REYES_TORUS,        /* q: majorradius minorradius phimin phimax thetamax */
	REYES_POLYGONS,     /* Polygon, GeneralPolygon, PointsPolygons, PointsGeneralPolygons */
	REYES_PATCHES,      /* Patch and PatchMesh, bilinear or bicubic */
	REYES_SUBDIV,       /* SubdivisionMesh "catmull-clark" (subdiv: geom_subdiv.c) */
	REYES_NUPATCH,      /* NuPatch (NURBS, any order, rational, trimmed): see nurbs.h */
	REYES_CURVES,       /* Curves: ribbons along linear or cubic curves (struct reyes_curves) */
	REYES_POINTS,       /* Points: a disk per "P" point */
};

/* A Catmull-Clark SubdivisionMesh: its faces and tags (ri_subdiv.c). */
struct reyes_subdiv {
	uint64_t serial;                      /* unique in the process: its OpenSubdiv mesh's key */
	uint32_t nfaces;
	const uint32_t *nverts;               /* per face (>= 3) */
	const uint32_t *verts;                /* vertex indices, face after face */
	uint32_t ncreases;                    /* crease edges (a tag's chain, edge by edge) */
	const uint32_t *crease_verts;         /* 2 per edge */
	const float *crease_sharp;
	uint32_t ncorners;
	const uint32_t *corner_verts;
	const float *corner_sharp;
	uint32_t nholes;
	const uint32_t *holes;                /* face indices */
	int interp_boundary;                  /* "interpolateboundary": 0 none, 1 edges and
						 corners, 2 edges only (prman) */
	int fvar_boundary;                    /* "facevaryinginterpolateboundary" 0..3, default 1 */
};

/*
 * REYES_CURVES: the curves of one Curves request. Curve c has nverts[c]
 * vertices from vertex vfirst[c] and pieces (segments) sfirst[c] to
 * sfirst[c + 1] - 1; its varying items start at sfirst[c] (periodic) or
 * sfirst[c] + c. Cubic curves go through the v basis and its step.
 */
struct reyes_curves {
	bool cubic, periodic;
	uint32_t ncurves;
	const uint32_t *nverts;
	const uint32_t *vfirst;               /* ncurves */
	const uint32_t *sfirst;               /* ncurves + 1: sfirst[ncurves] is the piece count */
	float basis[16];                      /* rows: coefficients of t^3..1 */
	uint32_t vstep;
};

struct reyes_prim {
	enum reyes_prim_kind kind;
	const struct reyes_attrs *attrs;
	uint32_t id;                          /* order of declaration */
	float q[8];                           /* quadric parameters (angles in degrees, as in RIB) */
	float q1[8];                          /* at shutter close (a deforming quadric), if qmoving */
	bool qmoving;                         /* q1 differs from q */

	/* REYES_POLYGONS: faces made of loops (the first is the outline, others holes). */
	uint32_t nfaces;
	const uint32_t *nloops;               /* per face (1 for simple polygons) */
	const uint32_t *nverts;               /* per loop */
	const uint32_t *verts;                /* vertex indices, loop after loop */

	/* REYES_PATCHES: an nu x nv mesh of control points (one patch: 2x2 or 4x4). */
	bool bicubic;
	uint32_t nu, nv;
	bool uperiodic, vperiodic;
	float ubasis[16], vbasis[16];         /* bicubic bases (rows: coefficients of t^3..1) */
	uint32_t ustep, vstep;
	/* A height field ("Pz"): the surface's x and y are its u and v over the
	   whole mesh, z is "P"'s z through the basis (P's x and y are unused). */
	bool heightfield;

	/* REYES_SUBDIV: the mesh (its faces, creases, corners, holes). */
	const struct reyes_subdiv *subdiv;
	/* REYES_NUPATCH: orders, knots, weights, ranges and trim region (nurbs.h). */
	const struct reyes_nurbs *nurbs;
	/* REYES_CURVES and REYES_POINTS (geom_curves.c): ribbons and disks face
	   the camera. eye[t] is the eye in object space at shutter open and close
	   (w = 1), or for an orthographic camera the direction towards it (w = 0),
	   set when the scene is finished (reyes_ri_face_camera), as is mirror:
	   the object-to-camera transform at shutter open turns space inside out. */
	const struct reyes_curves *curves;    /* REYES_CURVES only */
	float eye[2][4];
	bool mirror;

	uint32_t npoints;                     /* vertex positions ("P" count) */
	const struct reyes_primvar *vars;     /* "P" is always present (vertex point) */
	uint32_t nvars;

	/* Solid modeling (csg.h): 1 + the node of the "primitive" solid the
	   primitive bounds in the scene's csg; 0: it is in no solid. */
	uint32_t csg_leaf;
};

/** A finished scene: what one frame renders. */
struct reyes_scene {
	struct rl_arena *arena;
	struct reyes_options opts;
	struct reyes_light *lights;
	uint32_t nlights;
	struct reyes_prim *prims;
	uint32_t nprims;
	/* Named coordinate systems (CoordinateSystem): name -> that space to world. */
	const char *const *space_names;
	const float (*space_to_world)[16];
	uint32_t nspaces;
	uint32_t world;                 /* the world's place in the scene, from 0, rendered or not */
	struct reyes_csg csg;           /* SolidBegin/SolidEnd trees (nnodes 0: none) */
};

/** The variable named @name of @p, or NULL. */
const struct reyes_primvar *reyes_prim_var(const struct reyes_prim *p, const char *name);

#endif

/*
 * Internals of the RIB scene builder, shared by ri.c (diagnostics, request
 * arguments, options, the graphics state, transformations, blocks, shaders,
 * archives, frames and the dispatch of requests) and ri_prims.c (type
 * declarations, the geometric primitives and their primitive variables,
 * Basis, motion blocks, retained objects): the builder's state and the
 * functions each file offers the other.
 */
#ifndef REYES_RI_IMPL_H
#define REYES_RI_IMPL_H

#include "ri.h"

#include "arena.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* ---- a string-keyed hash map ------------------------------------------------ */

struct strmap_slot {
	const char *key;      /* owned by an arena that outlives the entry */
	uintptr_t val;
};

struct strmap {
	struct strmap_slot *slots;
	size_t cap, len;
};

static inline uint64_t hash_str(const char *s)
{
	uint64_t h = 1469598103934665603u;
	for (; *s; s++) {
		h ^= (unsigned char)*s;
		h *= 1099511628211u;
	}
	return h;
}

static inline struct strmap_slot *strmap_slot(const struct strmap *m, const char *key)
{
	size_t mask = m->cap - 1;
	for (size_t i = (size_t)hash_str(key) & mask;; i = (i + 1) & mask) {
		struct strmap_slot *s = &m->slots[i];
		if (!s->key || strcmp(s->key, key) == 0)
			return s;
	}
}

static inline bool strmap_get(const struct strmap *m, const char *key, uintptr_t *val)
{
	if (!m->cap)
		return false;
	const struct strmap_slot *s = strmap_slot(m, key);
	if (!s->key)
		return false;
	*val = s->val;
	return true;
}

static inline void strmap_put(struct strmap *m, const char *key, uintptr_t val)
{
	if ((m->len + 1) * 2 > m->cap) {
		struct strmap old = *m;
		m->cap = old.cap ? old.cap * 2 : 16;
		m->slots = rl_xcalloc(m->cap, sizeof(*m->slots));
		m->len = 0;
		for (size_t i = 0; i < old.cap; i++)
			if (old.slots[i].key) {
				*strmap_slot(m, old.slots[i].key) = old.slots[i];
				m->len++;
			}
		free(old.slots);
	}
	struct strmap_slot *s = strmap_slot(m, key);
	if (!s->key) {
		s->key = key;
		m->len++;
	}
	s->val = val;
}

static inline void strmap_free(struct strmap *m)
{
	free(m->slots);
	*m = (struct strmap){0};
}

/* ---- the builder's state ------------------------------------------------------ */

/* A type from a declaration: "[class] type ['[' n ']'] [name]". */
struct decl {
	enum reyes_class cls;
	int type;              /* enum sl_basetype; integer is float, hpoint is point */
	bool hpoint;           /* four components, divided by w on the way in */
	uint32_t arraylen;     /* 0: not an array */
	const char *name;      /* inline declarations only */
};

/* The current transformation at shutter open and close. */
struct xform {
	float m[2][16];
	bool moving;
};

/*
 * Which attributes a request set inside the object definition being built
 * (struct attrstate's objset): those are recorded with the object's
 * primitives and override the instance's at ObjectInstance.
 */
enum {
	OBJ_CS = 1 << 0,
	OBJ_OS = 1 << 1,
	OBJ_SURFACE = 1 << 2,
	OBJ_DISPLACEMENT = 1 << 3,
	OBJ_SIDES = 1 << 4,
	OBJ_ORIENTATION = 1 << 5,
	OBJ_SHADING_RATE = 1 << 6,
	OBJ_INTERPOLATION = 1 << 7,
	OBJ_IDENTIFIER = 1 << 8,
	OBJ_DBOUND = 1 << 9,
	OBJ_VISIBILITY = 1 << 10,
	OBJ_TEXCOORDS = 1 << 11,
	OBJ_MATTE = 1 << 12,
	OBJ_DETAIL = 1 << 13,
	OBJ_DETAIL_RANGE = 1 << 14,
	OBJ_ATMOSPHERE = 1 << 15,
};

/* The attributes of the graphics state (the transformation aside). */
struct attrstate {
	float Cs[3], Os[3];
	const struct reyes_shader *surface, *displacement;
	/* Atmosphere, Interior, Exterior (NULL: none); the atmosphere runs after
	   the surface, in the bundle's joined surface (reyes_ri_make_bundle) */
	const struct reyes_shader *atmosphere, *interior, *exterior;
	const uint32_t *lights;         /* indices of the lights that are on, ascending */
	uint32_t nlights;
	int sides;
	/* The orientation differs from the coordinate system's handedness. */
	bool inside;
	float shading_rate;
	struct rib_loc shading_rate_loc; /* its ShadingRate request (file NULL: the default) */
	bool smooth;
	const char *identifier;
	float dbound;
	const char *dbound_space;
	bool casts_shadows;
	struct reyes_ray_attrs ray;
	float ubasis[16], vbasis[16];
	uint32_t ustep, vstep;
	float texcoords[8];             /* TextureCoordinates s1 t1 ... s4 t4 */
	bool has_texcoords;             /* not the default 0 0 1 0 0 1 1 1 */
	bool matte;
	float detail;                   /* Detail: the bound's raster area; < 0: none given */
	float detail_range[4];          /* DetailRange minvisible ... maxvisible */
	bool has_detail_range;
	unsigned objset;                /* OBJ_*: set since ObjectBegin */
	/* TrimCurve: the trim region of the NuPatches that follow (NULL: none);
	   trim_bad: the last TrimCurve was malformed (its NuPatches are dropped). */
	const struct reyes_trim *trim;
	bool trim_bad;
	struct rib_loc trim_loc;
};

struct gstate {
	struct attrstate a;
	struct xform x;
	/* The bundle for a and x, made when a primitive first needs it. */
	const struct reyes_attrs *bundle;
	/*
	 * a.lights when nothing else refers to it (no bundle, no saved block),
	 * so that it may change in place; it has room for lights_cap entries.
	 * Otherwise NULL, and a change makes a copy.
	 */
	uint32_t *own_lights;
	uint32_t lights_cap;
};

struct optstate {
	struct reyes_options o;        /* displays: an immutable array in perm */
	bool projection_given;
	bool quantize_float;           /* Quantize "rgba" 0 ...: float images */
	struct rib_loc dof_loc;        /* the DepthOfField request in force */
	float relative_detail;         /* RelativeDetail: scales every Detail (default 1) */
};

enum blk { BLK_FRAME, BLK_WORLD, BLK_ATTRIBUTE, BLK_TRANSFORM, BLK_MOTION, BLK_OBJECT };

struct block {
	enum blk kind;
	struct rib_loc loc;      /* file name interned */
	uint32_t file_depth;     /* which file (archive nesting) opened it */
	size_t pre_lights;       /* lights declared before WorldBegin when it opened */
	struct gstate gs;        /* what to restore */
	struct optstate opt;     /* BLK_FRAME */
};

enum motion_kind { MOTION_NONE, MOTION_XFORM, MOTION_PRIM };

struct motion {
	bool active;
	bool bad;                 /* the block was rejected: its samples are skipped */
	struct rib_loc loc;
	float times[2];
	uint32_t ntimes, nsamples;
	const char *request;      /* the first sample's request */
	enum motion_kind kind;
	bool set;                 /* transform samples replace the transformation */
	float xf[2][16];
	struct reyes_prim *prim[2];
};

struct obj_prim {
	struct reyes_prim *p;     /* attrs NULL: given at each instance */
	/* The attributes at the primitive, when the definition set some
	   (a->objset); NULL: the instance's alone. */
	const struct attrstate *a;
	float rel[2][16];         /* the primitive's transformation relative to ObjectBegin's */
	bool identity;
};

struct object {
	RL_VEC(struct obj_prim) prims;
};

struct space {
	const char *name;
	float m[16];              /* that space to world (before WorldBegin: to camera) */
};

/* An open SolidBegin (ri_csg.c). */
struct ri_solid {
	uint32_t node;            /* its node, or the enclosing one's when it opened none */
	struct rib_loc loc;
};

/* A file being read: the top-level file or an archive. */
struct file {
	const char *path;
	const char *raw_name;     /* the reader's name pointer, valid while it reads */
	const char *name;         /* interned */
	struct stat st;
	bool have_st;
	struct rib_loc last;      /* the last request seen */
};

struct ri {
	const struct reyes_ri_opts *opts;
	FILE *diag;               /* where diagnostics end up */
	int max_errors;
	int nerrors;              /* the builder's own, plus frames the callback refused */
	int reader_errors;
	int frame_errors;         /* in the frame being built: it is not rendered */
	int warnings;             /* printed */
	int repeats;              /* diagnostics not printed again at the same place */
	int dropped;              /* primitives dropped for their errors */
	int prim_errors;          /* errors of those primitives (in nerrors) */
	int reader_prim;          /* the reader's errors that dropped a primitive, this file */
	int reader_prim_total;    /* the same, every file read (not in reader_errors) */
	bool in_prim;             /* a primitive's request is being built */
	bool prim_failed;         /* ... and it had an error */
	struct strmap seen;       /* 'w' or 'e' + "FILE:LINE: message" printed */
	uint32_t worlds;          /* worlds ended so far */
	bool stop;
	bool *edit_seen;          /* per opts->light_edits: a LightSource had its handle */

	/* The reader's diagnostics pass through a memory stream, so that its
	   errors can hold back the frame they occur in. */
	FILE *rdiag;
	char *rbuf;
	size_t rlen;

	struct rl_arena *perm;
	struct strmap decls;              /* name -> struct decl * */
	struct strmap shader_cache;       /* path + include path -> struct sl_program * (NULL: failed) */
	struct strmap joined;             /* surface + atmosphere programs -> their joined program */
	struct sl_program *default_surface; /* defaultsurface.sl, for an atmosphere with no Surface */
	struct strmap shader_names;       /* search path + '\n' + declared name -> file path */
	struct strmap names_indexed;      /* search paths whose .sl files were read for names */
	RL_VEC(struct sl_program *) progs;
	const char *default_shader_path;
	const char *default_texture_path;
	const char *default_include_path;

	struct optstate opt;
	struct gstate gs;
	RL_VEC(struct block) blocks;
	RL_VEC(struct file) files;
	uint32_t archive_reads;

	/*
	 * Lights declared before WorldBegin (shader space relative to camera),
	 * in perm: they are the first lights of every world that follows, until
	 * the FrameEnd of the frame that declared them.
	 */
	RL_VEC(struct reyes_light) pre_lights;
	struct strmap pre_light_index;    /* handle -> index + 1 */

	/* before WorldBegin: named spaces relative to camera */
	RL_VEC(struct space) pre_spaces;
	struct strmap pre_space_index;    /* name -> index + 1 */

	/* objects: those defined outside a world first, then the world's */
	RL_VEC(struct object) objects;
	size_t outer_objects;
	struct strmap outer_object_index; /* handle -> index + 1 */
	struct strmap world_object_index;
	int objdef;                       /* the object being defined, or -1 */
	float objdef_inv[2][16];

	struct motion motion;

	/* the world */
	struct rl_arena *world;
	float w2c_inv[16];
	bool w2c_mirror;                  /* the camera transformation flips handedness */
	RL_VEC(struct reyes_light) lights;
	struct strmap light_index;        /* handle -> index + 1 */
	RL_VEC(struct reyes_prim) prims;
	RL_VEC(struct space) spaces;
	struct strmap space_index;

	/* SolidBegin/SolidEnd (ri_csg.c): the world's CSG nodes, the open solids */
	RL_VEC(struct reyes_csg_node) csg_nodes;
	RL_VEC(struct ri_solid) csg_open;
	/* ri_procedural.c: DelayedReadArchive left unread (out of view) in world unread_world */
	uint32_t unread_archives, unread_world;
};

/* ---- ri.c: diagnostics ------------------------------------------------------------- */

/**
 * Report "FILE:LINE: error: MESSAGE" at @loc (after the reader's pending
 * messages), once per message and place. It counts against the read and
 * holds back the frame being built, or, inside a primitive's request, drops
 * that primitive only; the read stops when the errors of the first kind
 * reach opts->max_errors.
 */
void reyes_ri_err(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/**
 * Report "FILE:LINE: warning: MESSAGE" at @loc, once per message and place:
 * what is ignored, the frame renders. With opts->strict it is an error.
 */
void reyes_ri_warn(struct ri *ri, struct rib_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* Reports an error and leaves the (void) request handler. */
#define FAIL(...) \
	do { \
		reyes_ri_err(__VA_ARGS__); \
		return; \
	} while (0)

/** @loc with its file name interned in ri->perm (the reader's name dies with its read). */
struct rib_loc reyes_ri_keep_loc(struct ri *ri, struct rib_loc loc);

/** "line 9", or "FILE:9" when @at is in another file than @from; made in ri->perm. */
const char *reyes_ri_where(struct ri *ri, struct rib_loc at, struct rib_loc from);

/* ---- ri.c: arguments ----------------------------------------------------------------- */

/** Argument @i of @r as one number; false (reported) when it is not one. */
bool reyes_ri_num_arg(struct ri *ri, const struct rib_request *r, uint32_t i, double *out);

/** Argument @i of @r as one string (owned by @r); false (reported) when it is not one. */
bool reyes_ri_str_arg(struct ri *ri, const struct rib_request *r, uint32_t i, const char **out);

/**
 * Arguments first..first+n-1 of @r as floats into @out; false (reported)
 * when one is missing, not a number or beyond the float range.
 */
bool reyes_ri_float_args(struct ri *ri, const struct rib_request *r, uint32_t first, uint32_t n,
			 float *out);

/** Argument @i of @r, a handle (integer or string), as a string in @a; NULL (reported) if not. */
const char *reyes_ri_handle_arg(struct ri *ri, const struct rib_request *r, uint32_t i,
				struct rl_arena *a);

/**
 * The v->n numbers of @v as floats into @out; false (reported at @loc,
 * naming @what) when one is beyond the float range.
 */
bool reyes_ri_value_floats(struct ri *ri, const struct rib_value *v, struct rib_loc loc,
			   const char *what, float *out);

/** Does @v hold numbers (one or an array)? */
bool reyes_ri_is_numbers(const struct rib_value *v);

/* ---- ri.c: the graphics state, transformations and blocks --------------------------- */

/** Is @m exactly the identity? */
bool reyes_ri_is_identity(const float m[16]);

/** Where what is made now lives: the world's arena inside a world, else ri->perm. */
struct rl_arena *reyes_ri_cur_arena(struct ri *ri);

/** Set the current transformation at shutter open (@m0) and close (@m1). */
void reyes_ri_set_xform(struct ri *ri, const float m0[16], const float m1[16]);

/**
 * A new bundle (in the world's arena) of the current attributes with
 * transformation @x. It shares the current light set.
 */
const struct reyes_attrs *reyes_ri_make_bundle(struct ri *ri, const struct xform *x);

/** The bundle of the current attributes and transformation, made once until they change. */
const struct reyes_attrs *reyes_ri_cur_bundle(struct ri *ri);

/** May one more block open? False (reported) when blocks are nested too deeply. */
bool reyes_ri_depth_ok(struct ri *ri, const struct rib_request *r);

/** Open a block of @kind at @r, saving the graphics state and options it restores. */
void reyes_ri_push_block(struct ri *ri, const struct rib_request *r, enum blk kind);

/**
 * The end of a block of @kind: it must close the innermost open block,
 * opened in the same file. Pops it and returns true, or reports and
 * returns false.
 */
bool reyes_ri_close_block(struct ri *ri, const struct rib_request *r, enum blk kind);

/** The innermost open block of @kind, or NULL. */
const struct block *reyes_ri_find_block(const struct ri *ri, enum blk kind);

/* ---- ri_detail.c: level of detail and the geometric attributes ------------------- */

/** The attributes of ri_detail.c at their defaults (no Detail, no DetailRange). */
void reyes_ri_detail_init(struct attrstate *a);

/* Attribute "shade" and "trace" (@name), Option "trace" (ri_trace.c). */
void reyes_ri_trace_attribute(struct ri *ri, const struct rib_request *r, const char *name);
void reyes_ri_trace_option(struct ri *ri, const struct rib_request *r);

/**
 * The part of the samples that see primitives under @a (DetailRange over
 * the Detail's raster area): a sample whose dissolve number is in
 * [*lo, *hi) sees them. False when they are not visible at all.
 */
bool reyes_ri_detail_visible(const struct attrstate *a, float *lo, float *hi);

/** TextureCoordinates: the s, t of the corners of the (u, v) square. */
void reyes_ri_req_texture_coordinates(struct ri *ri, const struct rib_request *r);

/** Matte: whether the primitives that follow are matte objects. */
void reyes_ri_req_matte(struct ri *ri, const struct rib_request *r);

/** Detail: the bound whose raster area selects representations. */
void reyes_ri_req_detail(struct ri *ri, const struct rib_request *r);

/** RelativeDetail: the option that scales every Detail's raster area. */
void reyes_ri_req_relative_detail(struct ri *ri, const struct rib_request *r);

/** DetailRange: the detail over which the representation that follows is seen. */
void reyes_ri_req_detail_range(struct ri *ri, const struct rib_request *r);

/** GeometricApproximation: "flatness" and "motionfactor", accepted (see docs/renderer.md). */
void reyes_ri_req_geometric_approximation(struct ri *ri, const struct rib_request *r);

/** GeometricRepresentation: "primitive" renders; any other is reported and ignored. */
void reyes_ri_req_geometric_representation(struct ri *ri, const struct rib_request *r);

/* ---- ri_prims.c: declarations ------------------------------------------------------ */

/**
 * A parameter's name (in the current arena) and, if its token has one,
 * its inline declaration into @d (*has_decl then true). False (reported,
 * naming request @req) for an empty name or a malformed declaration.
 */
bool reyes_ri_param_token(struct ri *ri, const struct rib_param *par, const char *req,
			  struct decl *d, bool *has_decl, const char **name);

/* ---- ri_prims.c: requests, in ri.c's dispatch table -------------------------------- */

/** Declare NAME DECLARATION: the type of a parameter or primitive variable. */
void reyes_ri_req_declare(struct ri *ri, const struct rib_request *r);

/** Sphere, Cylinder, Cone, Disk, Hyperboloid, Paraboloid and Torus. */
void reyes_ri_req_quadric(struct ri *ri, const struct rib_request *r);

/** Polygon: one convex polygon. */
void reyes_ri_req_polygon(struct ri *ri, const struct rib_request *r);

/** GeneralPolygon: one polygon with holes. */
void reyes_ri_req_general_polygon(struct ri *ri, const struct rib_request *r);

/** PointsPolygons and PointsGeneralPolygons: polygons sharing vertices. */
void reyes_ri_req_points_polygons(struct ri *ri, const struct rib_request *r);

/** Patch: one bilinear or bicubic patch. */
void reyes_ri_req_patch(struct ri *ri, const struct rib_request *r);

/** PatchMesh: a mesh of bilinear or bicubic patches, each direction periodic or not. */
void reyes_ri_req_patch_mesh(struct ri *ri, const struct rib_request *r);

/* ---- ri_nurbs.c: NuPatch and TrimCurve ---- */
void reyes_ri_req_nu_patch(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_trim_curve(struct ri *ri, const struct rib_request *r);
/** Do two motion samples of a NuPatch agree in all but their points? */
bool reyes_ri_nurbs_same(const struct reyes_prim *a, const struct reyes_prim *b);

/** Basis: the bicubic bases and steps of the patches that follow (an attribute). */
void reyes_ri_req_basis(struct ri *ri, const struct rib_request *r);

/** MotionBegin: opens a motion block of one or two sample times. */
void reyes_ri_req_motion_begin(struct ri *ri, const struct rib_request *r);

/** MotionEnd: closes the motion block (see reyes_ri_motion_end). */
void reyes_ri_req_motion_end(struct ri *ri, const struct rib_request *r);

/** ObjectBegin: starts defining a retained object, outside or inside a world. */
void reyes_ri_req_object_begin(struct ri *ri, const struct rib_request *r);

/** ObjectEnd: closes the object definition. */
void reyes_ri_req_object_end(struct ri *ri, const struct rib_request *r);

/** ObjectInstance: the object's primitives under the current attributes and transformation. */
void reyes_ri_req_object_instance(struct ri *ri, const struct rib_request *r);

/* ---- ri_prims.c: motion blocks and object definitions, for ri.c's own requests ------ */

/**
 * A transformation request @r inside a motion block: its matrix @x is the
 * next sample; @set: it replaces the current transformation (else it is
 * applied before it).
 */
void reyes_ri_motion_xform(struct ri *ri, const struct rib_request *r, const float x[16],
			   bool set);

/**
 * The motion block closes (or unwinds): with @apply, and when its samples
 * are complete and agree, its transformation samples apply to the current
 * transformation, or its deforming primitive is added.
 */
void reyes_ri_motion_end(struct ri *ri, bool apply);

/** The object definition closes (or unwinds). */
void reyes_ri_object_end(struct ri *ri);

/* ---- ri_prims.c: for the primitives of other files --------------------------------- */

/* As in ri_prims.c: where a primitive may go, argument arrays, counts, points, variables. */
bool reyes_ri_geometry_ok(struct ri *ri, const struct rib_request *r);
bool reyes_ri_array_arg(struct ri *ri, const struct rib_request *r, uint32_t i);
uint32_t *reyes_ri_uint_values(struct ri *ri, const struct rib_value *v, const char *req,
			       const char *what, uint64_t limit);
bool reyes_ri_check_counts(struct ri *ri, const struct rib_request *r, const struct rib_value *v,
			   const uint32_t *c, uint32_t min, const char *what, uint64_t *sum);
bool reyes_ri_point_count(struct ri *ri, const struct rib_request *r, uint32_t *np);
/* The primitive variables of @r, sizes[class] items each; @points: "P" is required. */
bool reyes_ri_prim_vars(struct ri *ri, const struct rib_request *r, const uint32_t sizes[5],
			bool points, struct reyes_prim *p);
struct reyes_prim *reyes_ri_new_prim(struct ri *ri, enum reyes_prim_kind kind);
/* Into the world, the object being defined, or the motion block. */
void reyes_ri_emit_prim(struct ri *ri, const struct rib_request *r, struct reyes_prim *p);

/* ---- ri_subdiv.c -------------------------------------------------------------------- */

/** SubdivisionMesh: a Catmull-Clark mesh with its tags. */
void reyes_ri_req_subdivision_mesh(struct ri *ri, const struct rib_request *r);

/** Do two motion samples of subdivision meshes agree in faces and tags? */
bool reyes_ri_subdiv_same(const struct reyes_prim *a, const struct reyes_prim *b);

/* ---- ri_csg.c: solid modeling -------------------------------------------------------- */

/** SolidBegin OPERATION: opens a solid inside the innermost open one (or a new tree). */
void reyes_ri_req_solid_begin(struct ri *ri, const struct rib_request *r);

/** SolidEnd: closes the innermost open solid. */
void reyes_ri_req_solid_end(struct ri *ri, const struct rib_request *r);

/**
 * The csg_leaf of a primitive added now (1 + its leaf node; 0: in no
 * solid). A primitive directly inside an operation gets a leaf of its own
 * (reported).
 */
uint32_t reyes_ri_csg_leaf(struct ri *ri);

/** WorldEnd at @at: solids still open are reported and closed. */
void reyes_ri_csg_world_end(struct ri *ri, struct rib_loc at);

/** The world's CSG nodes, copied into @a, for its scene. */
void reyes_ri_csg_scene(struct ri *ri, struct rl_arena *a, struct reyes_csg *out);

/* ---- ri_curves.c: Curves and Points ------------------------------------------------- */

/** Curves TYPE [NVERTICES] WRAP ...: linear or cubic ribbons. */
void reyes_ri_req_curves(struct ri *ri, const struct rib_request *r);

/** Points ...: a disk per point. */
void reyes_ri_req_points(struct ri *ri, const struct rib_request *r);

/** Do two motion samples of a Curves request have the same curves? */
bool reyes_ri_same_curves(const struct reyes_curves *a, const struct reyes_curves *b);

/**
 * The eye of every Curves and Points primitive of the finished scene @sc in
 * its object space at both shutter times (what their ribbons and disks face).
 */
void reyes_ri_face_camera(struct reyes_scene *sc);

/* ---- ri_detail.c: for the primitives of their own files ------------------------------ */

/**
 * The raster area of the rectangle around bound @b (xmin xmax ymin ymax zmin
 * zmax, in the space @m takes to camera space) clipped to the near plane, as
 * Detail measures it; 0 when it is all behind the near plane.
 */
float reyes_ri_raster_area(const struct reyes_options *o, const float m[16], const float b[6]);

/* ---- ri_blobby.c -------------------------------------------------------------------------- */

/** Blobby: an implicit surface, polygonized to the shading rate where it is declared. */
void reyes_ri_req_blobby(struct ri *ri, const struct rib_request *r);

/* ---- ri.c: archives, for Procedural ------------------------------------------------------ */

/**
 * Read archive @name (found as ReadArchive finds it) in the current state;
 * @what names the request in messages. False (reported at @r) when it
 * cannot be found or read, nests too deeply or would read itself.
 */
bool reyes_ri_read_archive(struct ri *ri, const struct rib_request *r, const char *what,
			   const char *name);
/** Read @len bytes of RIB at @data, named @name in diagnostics, in the current state. */
bool reyes_ri_read_buffer(struct ri *ri, const char *name, const char *data, size_t len);
/** Is bound @b (object space under the current transformation) outside the view? */
bool reyes_ri_bound_unseen(struct ri *ri, const float b[6]);

/* ---- ri_procedural.c ---------------------------------------------------------------------- */

/** Procedural: DelayedReadArchive and RunProgram; DynamicLoad is refused. */
void reyes_ri_req_procedural(struct ri *ri, const struct rib_request *r);
/** A light @l was declared in the world at @r: warned about if it reads a shadow map
    that archives left unread (out of view) before it should have cast into. */
void reyes_ri_procedural_light(struct ri *ri, const struct rib_request *r,
			       const struct reyes_light *l);

/* ---- ri_geometry.c ------------------------------------------------------------------------ */

/** Geometry: "teapot", the Newell teapot; other names are warned about. */
void reyes_ri_req_geometry(struct ri *ri, const struct rib_request *r);

/* ---- ri_options.c: options (the camera, the image, displays, the hider, Option) ------ */

/** The options at the start of a read (RISpec's defaults). */
void reyes_ri_options_init(struct ri *ri, struct optstate *s);

/** May an option be given here (outside the world)? Reported if not. */
bool reyes_ri_option_ok(struct ri *ri, const struct rib_request *r);

void reyes_ri_req_format(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_frame_aspect(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_screen_window(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_crop_window(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_projection(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_clipping(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_shutter(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_depth_of_field(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_pixel_samples(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_pixel_filter(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_exposure(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_quantize(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_display(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_hider(struct ri *ri, const struct rib_request *r);
void reyes_ri_req_option(struct ri *ri, const struct rib_request *r);

#endif

/*
 * Blobby implicit surfaces (RISpec 3.2 §5.6): the field program of a Blobby
 * request (leaves: constants, ellipsoids, segment blobs, repelling planes;
 * operators: add, multiply, maximum, minimum, subtract, divide, negate,
 * identity), its evaluation, and its polygonization into a closed triangle
 * mesh with vertices on the isosurface and normals from the field's
 * gradient. The scene builder (ri_blobby.c) hands the mesh to the polygon
 * pieces of geom.c, so that the renderer, the bake and the shadow geometry
 * draw it as they draw any polygon mesh.
 */
#ifndef REYES_GEOM_BLOBBY_H
#define REYES_GEOM_BLOBBY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* RISpec's opcodes. */
enum reyes_blobby_op {
	BLOBBY_ADD = 0,
	BLOBBY_MUL = 1,
	BLOBBY_MAX = 2,
	BLOBBY_MIN = 3,
	BLOBBY_SUB = 4,
	BLOBBY_DIV = 5,
	BLOBBY_NEG = 6,
	BLOBBY_IDENTITY = 7,
	BLOBBY_CONSTANT = 1000,
	BLOBBY_ELLIPSOID = 1001,
	BLOBBY_SEGMENT = 1002,
	BLOBBY_PLANE = 1003,
};

/** The field's level set that is the surface. */
#define REYES_BLOBBY_THRESHOLD 0.5

/** One instruction; its value is numbered by its place in the program. */
struct reyes_blobby_instr {
	enum reyes_blobby_op op;
	uint32_t leaf;            /* leaves: which leaf, from 0, in code order */
	uint32_t first, count;    /* operators: operands[first .. first + count) */
	double inv[16];           /* ellipsoid, segment: object to blob space (row vectors) */
	double a[3], b[3];        /* segment: its ends, in blob space */
	double rr;                /* segment: 1 / radius^2 */
	double value;             /* constant */
	bool bounded;             /* ellipsoid, segment: zero outside lo..hi */
	double lo[3], hi[3];      /* that box, in object space */
};

struct reyes_blobby {
	struct reyes_blobby_instr *instr;
	uint32_t ninstr, nleaf;
	uint32_t *operands;
	uint32_t noperands;
	uint32_t nplanes;         /* repelling planes (their field is taken as 0) */
	bool bounded;             /* some leaf has a bound: lo..hi is their union */
	double lo[3], hi[3];
};

/**
 * Decode a Blobby's code (@ncode integers) over its @nfloats floats and
 * @nstrings strings into @b (heap; reyes_blobby_finish frees it). Operands
 * name earlier instructions, so the program has no cycles. False, with a
 * message in @err, for malformed code: an unknown opcode, an operand or
 * index out of range, a singular or projective matrix, a segment radius
 * that is not positive, a leaf count that is not @nleaf.
 */
bool reyes_blobby_decode(struct reyes_blobby *b, uint32_t nleaf, const int32_t *code,
			 uint32_t ncode, const float *floats, uint32_t nfloats, uint32_t nstrings,
			 char *err, size_t errlen);

void reyes_blobby_finish(struct reyes_blobby *b);

/**
 * The field at object-space point @p (the last instruction's value; never
 * NaN or infinite: a value that is becomes 0). @vals has room for ninstr
 * values and gets each instruction's, the leaves' among them.
 */
double reyes_blobby_field(const struct reyes_blobby *b, const double p[3], double *vals);

/** A closed triangle mesh around the region where the field exceeds the threshold. */
struct reyes_blobby_mesh {
	uint32_t npoints, ntris;
	float *P;                 /* npoints x 3, on the surface */
	float *N;                 /* npoints x 3, unit, outward (along minus the gradient) */
	uint32_t *tris;           /* ntris x 3; P[1] - P[0] ^ P[2] - P[0] points outward */
	double *leaf;             /* npoints x nleaf: the leaves' field values at each point */
	double cell;              /* the grid's widest cell */
	bool coarsened;           /* wider than asked: the program is too long for that grid */
};

/**
 * Polygonize @b over its bound on a grid of cells at most @cell wide
 * (object space), at most @max_cells cells per axis: Freudenthal's six
 * tetrahedra per cell (crack-free between cells), each crossing of the
 * threshold found on its edge by false position to 1e-7 of the edge,
 * shared between the tetrahedra that meet there. The field is taken as
 * below the threshold outside the bound, so the mesh is closed. Samples
 * times instructions are bounded (1e8): a longer program gets wider cells
 * (m->coarsened). False only
 * when memory runs out or the grid would be too large.
 */
bool reyes_blobby_polygonize(const struct reyes_blobby *b, double cell, uint32_t max_cells,
			     struct reyes_blobby_mesh *m);

void reyes_blobby_mesh_finish(struct reyes_blobby_mesh *m);

#endif

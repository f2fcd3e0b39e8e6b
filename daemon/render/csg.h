/*
 * Solid modeling (RISpec 3.2 §5.8, SolidBegin/SolidEnd): the scene's CSG
 * trees and their evaluation along a sample's ray.
 *
 * A scene's solids are one array of nodes: each top-level solid is a tree
 * whose leaves are "primitive" solids (the closed surfaces given inside
 * one) and whose inner nodes are unions, intersections and differences
 * (the first child less the union of the others). A primitive inside a
 * solid names its leaf (reyes_prim's csg_leaf). The hider follows, per
 * sample and front to back, whether the ray is inside each leaf (a
 * crossing count per leaf: +1 where the ray enters a leaf's surface, -1
 * where it leaves) and keeps a hit of a solid's surface only where the
 * value of its tree changes: the composite solid's boundary.
 */
#ifndef REYES_CSG_H
#define REYES_CSG_H

#include "rib.h"

#include <stdbool.h>
#include <stdint.h>

#define REYES_CSG_NONE 0xffffffffu

enum reyes_csg_op {
	REYES_CSG_PRIMITIVE,    /* a leaf: the primitives that name it */
	REYES_CSG_UNION,
	REYES_CSG_INTERSECTION,
	REYES_CSG_DIFFERENCE,   /* the first child less the union of the others */
};

struct reyes_csg_node {
	enum reyes_csg_op op;
	uint32_t parent;        /* REYES_CSG_NONE for a top-level solid */
	uint32_t root;          /* the top-level solid this node is in (itself for one) */
	uint32_t first, next;   /* first child, next sibling (REYES_CSG_NONE: none) */
	struct rib_loc loc;     /* its SolidBegin (or the primitive taken as a leaf) */
};

struct reyes_csg {
	const struct reyes_csg_node *nodes;
	uint32_t nnodes;
};

/**
 * Is the ray inside node @n, given each leaf's crossing count in @count
 * (indexed by node; inside a leaf when its count is > 0)? An operation
 * with no children is empty.
 */
bool reyes_csg_inside(const struct reyes_csg *csg, uint32_t n, const int32_t *count);

/**
 * Does leaf @leaf lie on the subtracted side of a difference (a child
 * other than the first, at any depth)? Its surface can bound the solid
 * only inside what it is subtracted from.
 */
bool reyes_csg_subtracted(const struct reyes_csg *csg, uint32_t leaf);

/** Is every operation of @leaf's top-level solid a union? Then its surfaces' first hit is exact. */
bool reyes_csg_union_only(const struct reyes_csg *csg, uint32_t leaf);

/** "primitive", "union", "intersection" or "difference". */
const char *reyes_csg_op_name(enum reyes_csg_op op);

#endif

/*
 * The CSG trees of a scene and their evaluation (see csg.h).
 */
#include "csg.h"

bool reyes_csg_inside(const struct reyes_csg *csg, uint32_t n, const int32_t *count)
{
	const struct reyes_csg_node *nd = &csg->nodes[n];
	uint32_t c = nd->first;
	switch (nd->op) {
	case REYES_CSG_PRIMITIVE:
		return count[n] > 0;
	case REYES_CSG_UNION:
		for (; c != REYES_CSG_NONE; c = csg->nodes[c].next)
			if (reyes_csg_inside(csg, c, count))
				return true;
		return false;
	case REYES_CSG_INTERSECTION:
		if (c == REYES_CSG_NONE)
			return false;
		for (; c != REYES_CSG_NONE; c = csg->nodes[c].next)
			if (!reyes_csg_inside(csg, c, count))
				return false;
		return true;
	case REYES_CSG_DIFFERENCE:
		if (c == REYES_CSG_NONE || !reyes_csg_inside(csg, c, count))
			return false;
		for (c = csg->nodes[c].next; c != REYES_CSG_NONE; c = csg->nodes[c].next)
			if (reyes_csg_inside(csg, c, count))
				return false;
		return true;
	}
	return false;
}

bool reyes_csg_subtracted(const struct reyes_csg *csg, uint32_t leaf)
{
	for (uint32_t n = leaf; csg->nodes[n].parent != REYES_CSG_NONE;) {
		uint32_t p = csg->nodes[n].parent;
		if (csg->nodes[p].op == REYES_CSG_DIFFERENCE && csg->nodes[p].first != n)
			return true;
		n = p;
	}
	return false;
}

/* Is every operation under node @n a union? */
static bool unions_below(const struct reyes_csg *csg, uint32_t n)
{
	const struct reyes_csg_node *nd = &csg->nodes[n];
	if (nd->op == REYES_CSG_PRIMITIVE)
		return true;
	if (nd->op != REYES_CSG_UNION)
		return false;
	for (uint32_t c = nd->first; c != REYES_CSG_NONE; c = csg->nodes[c].next)
		if (!unions_below(csg, c))
			return false;
	return true;
}

bool reyes_csg_union_only(const struct reyes_csg *csg, uint32_t leaf)
{
	return unions_below(csg, csg->nodes[leaf].root);
}

const char *reyes_csg_op_name(enum reyes_csg_op op)
{
	switch (op) {
	case REYES_CSG_PRIMITIVE:
		return "primitive";
	case REYES_CSG_UNION:
		return "union";
	case REYES_CSG_INTERSECTION:
		return "intersection";
	case REYES_CSG_DIFFERENCE:
		return "difference";
	}
	return "?";
}

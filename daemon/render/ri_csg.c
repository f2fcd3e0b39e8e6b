/*
 * SolidBegin/SolidEnd (RISpec 3.2 §5.8): the scene builder's CSG trees.
 *
 * Each SolidBegin opens a node under the innermost open solid (or a new
 * top-level solid); a primitive names the innermost open "primitive"
 * solid as its leaf. What RISpec does not allow is reported as a warning
 * and given the nearest meaning, so that the frame still renders:
 *  - a primitive directly inside an operation is taken as a "primitive"
 *    solid of its own (one leaf per primitive);
 *  - an unknown operation, a SolidBegin inside a "primitive" solid, inside
 *    an object definition, outside the world or nested past the depth
 *    limit opens no node: what it holds belongs to the enclosing solid
 *    (or to none), and its SolidEnd closes it;
 *  - a SolidEnd with no open solid is ignored; solids still open at
 *    WorldEnd are closed there.
 * Solids do not save or restore attributes: attributes set inside one
 * apply to its primitives and after it, as in any other place (put an
 * AttributeBegin/End around them to scope them). The nodes live with the
 * world and go with it.
 */
#include "ri_impl.h"

#define MAX_CSG_DEPTH 64

/* The node primitives go into now: the innermost open solid's, or NONE. */
static uint32_t open_node(const struct ri *ri)
{
	return ri->csg_open.len ? ri->csg_open.data[ri->csg_open.len - 1].node : REYES_CSG_NONE;
}

static uint32_t add_node(struct ri *ri, enum reyes_csg_op op, uint32_t parent,
			 struct rib_loc loc)
{
	uint32_t n = (uint32_t)ri->csg_nodes.len;
	struct reyes_csg_node nd = { .op = op, .parent = parent, .root = n,
				     .first = REYES_CSG_NONE, .next = REYES_CSG_NONE,
				     .loc = reyes_ri_keep_loc(ri, loc) };
	if (parent != REYES_CSG_NONE) {
		/* appended after the last child: a difference's first child stays first */
		struct reyes_csg_node *p = &ri->csg_nodes.data[parent];
		nd.root = p->root;
		if (p->first == REYES_CSG_NONE) {
			p->first = n;
		} else {
			uint32_t c = p->first;
			while (ri->csg_nodes.data[c].next != REYES_CSG_NONE)
				c = ri->csg_nodes.data[c].next;
			ri->csg_nodes.data[c].next = n;
		}
	}
	rl_vec_push(ri->csg_nodes, nd);
	return n;
}

static bool op_from_name(const char *s, enum reyes_csg_op *op)
{
	static const enum reyes_csg_op ops[] = { REYES_CSG_PRIMITIVE, REYES_CSG_UNION,
						 REYES_CSG_INTERSECTION, REYES_CSG_DIFFERENCE };
	for (size_t i = 0; i < sizeof(ops) / sizeof(ops[0]); i++)
		if (strcmp(s, reyes_csg_op_name(ops[i])) == 0) {
			*op = ops[i];
			return true;
		}
	return false;
}

/* Why a SolidBegin at @r opens no node, or NULL when it may. */
static const char *no_node_reason(const struct ri *ri, uint32_t parent)
{
	if (!ri->world)
		return "outside WorldBegin/WorldEnd";
	if (ri->objdef >= 0)
		return "inside an object definition (solids of retained objects are not "
		       "supported: instance the object inside a solid instead)";
	if (parent != REYES_CSG_NONE && ri->csg_nodes.data[parent].op == REYES_CSG_PRIMITIVE)
		return "inside a \"primitive\" solid (which holds primitives only): its "
		       "primitives belong to the enclosing one";
	if (ri->csg_open.len >= MAX_CSG_DEPTH)
		return "nested too deeply (limit 64): its primitives belong to the enclosing solid";
	return NULL;
}

void reyes_ri_req_solid_begin(struct ri *ri, const struct rib_request *r)
{
	const char *name;
	if (!reyes_ri_str_arg(ri, r, 0, &name))
		return;
	uint32_t parent = open_node(ri), node = parent;
	enum reyes_csg_op op;
	const char *why = no_node_reason(ri, parent);
	if (!op_from_name(name, &op))
		reyes_ri_warn(ri, r->loc, "SolidBegin: unknown operation '%s' (use \"primitive\", "
			      "\"union\", \"intersection\" or \"difference\"): the block is no "
			      "solid", name);
	else if (why)
		reyes_ri_warn(ri, r->loc, "SolidBegin \"%s\" %s", name, why);
	else
		node = add_node(ri, op, parent, r->loc);
	struct ri_solid s = { .node = node, .loc = reyes_ri_keep_loc(ri, r->loc) };
	rl_vec_push(ri->csg_open, s);
}

void reyes_ri_req_solid_end(struct ri *ri, const struct rib_request *r)
{
	if (!ri->csg_open.len) {
		reyes_ri_warn(ri, r->loc, "SolidEnd without a SolidBegin: ignored");
		return;
	}
	ri->csg_open.len--;
}

uint32_t reyes_ri_csg_leaf(struct ri *ri)
{
	uint32_t n = open_node(ri);
	if (n == REYES_CSG_NONE)
		return 0;
	const struct reyes_csg_node *nd = &ri->csg_nodes.data[n];
	if (nd->op == REYES_CSG_PRIMITIVE)
		return n + 1;
	struct rib_loc at = ri->files.len ? ri->files.data[ri->files.len - 1].last : nd->loc;
	reyes_ri_warn(ri, at, "a primitive directly inside a \"%s\" solid (SolidBegin at %s) "
		      "is taken as a \"primitive\" solid of its own", reyes_csg_op_name(nd->op),
		      reyes_ri_where(ri, nd->loc, at));
	return add_node(ri, REYES_CSG_PRIMITIVE, n, at) + 1;
}

void reyes_ri_csg_world_end(struct ri *ri, struct rib_loc at)
{
	for (size_t i = ri->csg_open.len; i-- > 0;)
		reyes_ri_warn(ri, ri->csg_open.data[i].loc, "SolidBegin is not closed by a SolidEnd "
			      "before %s: closed there", reyes_ri_where(ri, at, ri->csg_open.data[i].loc));
	ri->csg_open.len = 0;
}

void reyes_ri_csg_scene(struct ri *ri, struct rl_arena *a, struct reyes_csg *out)
{
	size_t n = ri->csg_nodes.len;
	struct reyes_csg_node *nodes = rl_arena_alloc(a, sizeof(*nodes) * (n ? n : 1));
	if (n)
		memcpy(nodes, ri->csg_nodes.data, sizeof(*nodes) * n);
	out->nodes = nodes;
	out->nnodes = (uint32_t)n;
}

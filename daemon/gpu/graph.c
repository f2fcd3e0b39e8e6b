/*
 * The computation graph: see graph.h.
 *
 * Nodes are kept in the order they were added. An edge may join any two
 * nodes, but one that would close a cycle is refused when it is made, so
 * pulling is a depth-first walk that always ends. Each node keeps, per input, the version of that input
 * it last ran with; it is stale when one of them differs, or when it was
 * touched, or when it never ran.
 */
#include "graph.h"

#include "arena.h"
#include "log.h"

#include <stdlib.h>
#include <string.h>

struct graph_node {
	struct graph *g;
	char *name;
	enum graph_port_type type;
	graph_run_fn run;
	void *user;
	struct graph_node **in;    /* input ports, each fed by one node */
	uint64_t *seen;            /* per input: its version when this node last ran */
	uint32_t nin;
	uint64_t version;          /* bumped when the outputs change */
	uint64_t runs;
	bool touched;              /* changed by hand, or never ran */
	uint32_t mark;             /* for the walks */
};

struct graph {
	RL_VEC(struct graph_node *) nodes;
	uint32_t walk;
};

struct graph *graph_create(void)
{
	return rl_xcalloc(1, sizeof(struct graph));
}

void graph_destroy(struct graph *g)
{
	if (!g)
		return;
	for (size_t i = 0; i < g->nodes.len; i++) {
		struct graph_node *n = g->nodes.data[i];
		free(n->name);
		free(n->in);
		free(n->seen);
		free(n);
	}
	rl_vec_free(g->nodes);
	free(g);
}

struct graph_node *graph_add(struct graph *g, const char *name, enum graph_port_type out,
			     graph_run_fn run, void *user)
{
	struct graph_node *n = rl_xcalloc(1, sizeof(*n));
	n->g = g;
	n->name = rl_xstrdup(name ? name : "?");
	n->type = out;
	n->run = run;
	n->user = user;
	n->touched = true;
	n->version = 1;
	rl_vec_push(g->nodes, n);
	return n;
}

/* Is @target reachable from @n by following inputs (upstream)? */
static bool upstream(struct graph_node *n, const struct graph_node *target, uint32_t walk)
{
	if (n == target)
		return true;
	if (n->mark == walk)
		return false;
	n->mark = walk;
	for (uint32_t i = 0; i < n->nin; i++)
		if (upstream(n->in[i], target, walk))
			return true;
	return false;
}

bool graph_connect(struct graph *g, struct graph_node *from, struct graph_node *to)
{
	if (!from || !to || from->g != g || to->g != g)
		return false;
	/* to upstream of from: the edge would close a cycle */
	if (upstream(from, to, ++g->walk)) {
		rl_log(RL_LOG_ERROR, "graph: %s -> %s would make a cycle", from->name, to->name);
		return false;
	}
	to->in = rl_xrealloc(to->in, (to->nin + 1) * sizeof(*to->in));
	to->seen = rl_xrealloc(to->seen, (to->nin + 1) * sizeof(*to->seen));
	to->in[to->nin] = from;
	to->seen[to->nin] = 0;
	to->nin++;
	to->touched = true;
	return true;
}

void graph_touch(struct graph_node *n)
{
	if (!n)
		return;
	n->touched = true;
	if (!n->run)
		n->version++;
}

static bool inputs_changed(const struct graph_node *n)
{
	for (uint32_t i = 0; i < n->nin; i++)
		if (n->seen[i] != n->in[i]->version)
			return true;
	return false;
}

bool graph_stale(const struct graph_node *n)
{
	if (!n)
		return false;
	if (!n->run)
		return false;
	if (n->touched || inputs_changed(n))
		return true;
	for (uint32_t i = 0; i < n->nin; i++)
		if (graph_stale(n->in[i]))
			return true;
	return false;
}

static bool pull(struct graph_node *n, uint32_t walk)
{
	if (n->mark == walk)
		return true;
	n->mark = walk;
	for (uint32_t i = 0; i < n->nin; i++)
		if (!pull(n->in[i], walk))
			return false;
	if (!n->run) {
		n->touched = false;
		return true;
	}
	if (!n->touched && !inputs_changed(n))
		return true;
	bool changed = true;
	if (!n->run(n, n->user, &changed)) {
		rl_log(RL_LOG_ERROR, "graph: node %s failed", n->name);
		return false;
	}
	n->runs++;
	for (uint32_t i = 0; i < n->nin; i++)
		n->seen[i] = n->in[i]->version;
	n->touched = false;
	if (changed)
		n->version++;
	return true;
}

bool graph_pull(struct graph *g, struct graph_node *n)
{
	if (!g || !n || n->g != g)
		return false;
	return pull(n, ++g->walk);
}

uint32_t graph_count(const struct graph *g)
{
	return g ? (uint32_t)g->nodes.len : 0;
}

const char *graph_node_name(const struct graph_node *n)
{
	return n ? n->name : "";
}

uint64_t graph_node_runs(const struct graph_node *n)
{
	return n ? n->runs : 0;
}

struct graph_node *graph_node_at(const struct graph *g, uint32_t i)
{
	return g && i < g->nodes.len ? g->nodes.data[i] : NULL;
}

static const char *const type_names[] = {
	[GRAPH_PARAMS] = "params",
	[GRAPH_DEPTH_MAP] = "depth_map",
	[GRAPH_SAMPLE_COLORS] = "sample_colors",
	[GRAPH_IMAGE] = "image",
	[GRAPH_IMAGE8] = "image8",
};

/* @s as a JSON string (names are ours, but a light's name comes from a RIB). */
static void json_string(FILE *out, const char *s)
{
	fputc('"', out);
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;
		if (c == '"' || c == '\\')
			fprintf(out, "\\%c", c);
		else if (c < 0x20)
			fprintf(out, "\\u%04x", c);
		else
			fputc(c, out);
	}
	fputc('"', out);
}

void graph_print_json(const struct graph *g, FILE *out)
{
	fputc('[', out);
	for (uint32_t i = 0; g && i < g->nodes.len; i++) {
		const struct graph_node *n = g->nodes.data[i];
		fprintf(out, "%s{\"name\": ", i ? ", " : "");
		json_string(out, n->name);
		fprintf(out, ", \"type\": \"%s\", \"inputs\": [", type_names[n->type]);
		for (uint32_t k = 0; k < n->nin; k++) {
			if (k)
				fputs(", ", out);
			json_string(out, n->in[k]->name);
		}
		fprintf(out, "], \"runs\": %llu}", (unsigned long long)n->runs);
	}
	fputc(']', out);
}

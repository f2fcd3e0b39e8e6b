/*
 * The computation graph of the GPU runtime (lightspeed-2007 §6.3): nodes
 * with typed ports joined by edges, generated per shot from what it holds,
 * evaluated by pulling. A node runs only when a node upstream of it changed
 * since its last run; a source node (a light's parameters, a surface's
 * editable parameters) changes when it is told to. Each node keeps a
 * version, bumped every time its outputs change; a node remembers the
 * versions of its inputs it last ran with.
 */
#ifndef GPU_GRAPH_H
#define GPU_GRAPH_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/** What flows along an edge. */
enum graph_port_type {
	GRAPH_PARAMS,        /* parameter values (uniforms) */
	GRAPH_DEPTH_MAP,     /* a shadow map */
	GRAPH_SAMPLE_COLORS, /* a colour per shading sample */
	GRAPH_IMAGE,         /* linear RGBA pixels */
	GRAPH_IMAGE8,        /* display-referred 8-bit pixels */
};

struct graph;
struct graph_node;

/**
 * Run a node: compute its outputs from its inputs. @user is the node's.
 * Returns false on failure (the node stays out of date); sets *@changed to
 * false when the outputs came out the same (downstream need not run).
 */
typedef bool (*graph_run_fn)(struct graph_node *n, void *user, bool *changed);

struct graph *graph_create(void);
void graph_destroy(struct graph *g);

/**
 * Add a node called @name (copied) that runs @run (NULL: a source) with
 * @user, producing @out. The name is for messages and graph_print.
 */
struct graph_node *graph_add(struct graph *g, const char *name, enum graph_port_type out,
			     graph_run_fn run, void *user);

/**
 * Connect @from's output to a new input port of @to. False (nothing added)
 * when the edge would make a cycle or the graph is out of memory.
 */
bool graph_connect(struct graph *g, struct graph_node *from, struct graph_node *to);

/** Mark source (or any) node @n changed: everything downstream is out of date. */
void graph_touch(struct graph_node *n);

/** Whether @n would run on the next graph_pull of it or of a node downstream. */
bool graph_stale(const struct graph_node *n);

/**
 * Bring @n up to date: run, in dependency order, every node upstream of it
 * (and itself) that is out of date. False when a node fails (its name in
 * the log); nodes that ran before it keep their results.
 */
bool graph_pull(struct graph *g, struct graph_node *n);

/** Nodes, and how many times each ran (for tests and `--json`). */
uint32_t graph_count(const struct graph *g);
const char *graph_node_name(const struct graph_node *n);
uint64_t graph_node_runs(const struct graph_node *n);
struct graph_node *graph_node_at(const struct graph *g, uint32_t i);

/** Print the nodes and edges as JSON (an array of {name, type, inputs, runs}). */
void graph_print_json(const struct graph *g, FILE *out);

#endif

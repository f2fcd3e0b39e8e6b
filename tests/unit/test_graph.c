/*
 * The computation graph: pulling runs what is out of date upstream, in
 * dependency order, once; touching a source reruns exactly what depends on
 * it; a node reporting no change stops the rerun below it; cycles are
 * refused; a failing node stays out of date.
 */
#include "graph.h"
#include "test.h"

struct rec {
	char log[256];
	int fail;                  /* the node with this id fails */
	int same;                  /* the node with this id reports no change */
};

struct tag {
	struct rec *rec;
	int id;
};

static bool run(struct graph_node *n, void *user, bool *changed)
{
	(void)n;
	struct tag *t = user;
	if (t->rec->fail == t->id)
		return false;
	size_t len = strlen(t->rec->log);
	snprintf(t->rec->log + len, sizeof(t->rec->log) - len, "%d", t->id);
	*changed = t->rec->same != t->id;
	return true;
}

static void test_pull(void)
{
	struct rec rec = { .fail = -1, .same = -1 };
	struct tag tags[6];
	for (int i = 0; i < 6; i++)
		tags[i] = (struct tag){ &rec, i };
	struct graph *g = graph_create();
	/* a, b sources; 2 = f(a); 3 = f(a, b); 4 = f(2, 3); 5 = f(2) */
	struct graph_node *a = graph_add(g, "a", GRAPH_PARAMS, NULL, NULL);
	struct graph_node *b = graph_add(g, "b", GRAPH_PARAMS, NULL, NULL);
	struct graph_node *n2 = graph_add(g, "n2", GRAPH_SAMPLE_COLORS, run, &tags[2]);
	struct graph_node *n3 = graph_add(g, "n3", GRAPH_SAMPLE_COLORS, run, &tags[3]);
	struct graph_node *n4 = graph_add(g, "n4", GRAPH_IMAGE, run, &tags[4]);
	struct graph_node *n5 = graph_add(g, "n5", GRAPH_IMAGE, run, &tags[5]);
	CHECK(graph_connect(g, a, n2));
	CHECK(graph_connect(g, a, n3));
	CHECK(graph_connect(g, b, n3));
	CHECK(graph_connect(g, n2, n4));
	CHECK(graph_connect(g, n3, n4));
	CHECK(graph_connect(g, n2, n5));
	/* no cycles */
	CHECK(!graph_connect(g, n4, n2));
	CHECK(!graph_connect(g, n2, n2));
	CHECK(graph_count(g) == 6);

	CHECK(graph_stale(n4));
	CHECK(graph_pull(g, n4));
	CHECK_STR(rec.log, "234");
	CHECK(!graph_stale(n4));
	CHECK(graph_stale(n5));
	CHECK(graph_pull(g, n5));
	CHECK_STR(rec.log, "2345");
	/* nothing changed: nothing runs */
	rec.log[0] = '\0';
	CHECK(graph_pull(g, n4));
	CHECK_STR(rec.log, "");
	/* b changed: only 3 and 4 */
	graph_touch(b);
	CHECK(graph_stale(n4));
	CHECK(!graph_stale(n2));
	CHECK(graph_pull(g, n4));
	CHECK_STR(rec.log, "34");
	/* a changed, and 2 says its output came out the same: 4 still runs for 3 */
	rec.log[0] = '\0';
	rec.same = 2;
	graph_touch(a);
	CHECK(graph_pull(g, n5));
	/* 2 reported no change: 5 does not run */
	CHECK_STR(rec.log, "2");
	CHECK(graph_node_runs(n5) == 1);
	/* 3 still depends on a */
	rec.log[0] = '\0';
	rec.same = -1;
	CHECK(graph_pull(g, n4));
	CHECK_STR(rec.log, "34");
	/* a failing node stays stale and stops the pull */
	rec.log[0] = '\0';
	rec.fail = 3;
	graph_touch(b);
	CHECK(!graph_pull(g, n4));
	CHECK(graph_stale(n4));
	rec.fail = -1;
	CHECK(graph_pull(g, n4));
	CHECK_STR(rec.log, "34");
	CHECK(graph_node_runs(n4) == 4);

	/* the JSON lists every node with its inputs */
	char *buf = NULL;
	size_t len = 0;
	FILE *mem = open_memstream(&buf, &len);
	graph_print_json(g, mem);
	fclose(mem);
	CHECK(buf && strstr(buf, "{\"name\": \"n4\", \"type\": \"image\", \"inputs\": [\"n2\", "
				 "\"n3\"], \"runs\": 4}"));
	free(buf);
	graph_destroy(g);
}

int main(void)
{
	RUN(test_pull);
	return test_finish();
}

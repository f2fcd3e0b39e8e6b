/*
 * relightd's edit log (daemon/server/editlog.c): 100,000 random edits of a
 * shot leave a log whose size depends on the lights and parameters touched,
 * not on the number of edits, and replaying the log gives the state the
 * edits gave, freeze flags included.
 *
 * The state is a model of what the runtime keeps per light (gpu/runtime.c:
 * parameters, muted, frozen, pinned; the soloed light; lights added and
 * removed, a removed light keeping its index), with the runtime's rules:
 * an edit of a light unfreezes it and freezes the lights earlier edits
 * unfroze (those not pinned by an explicit unfreeze).
 */
#include "srv.h"

#include "test.h"

#include <stdint.h>

#define MAX_LIGHTS 64
#define NPARAMS 6
#define BASE_LIGHTS 16

static const char *const param_names[NPARAMS] = {
	"intensity", "lightcolor", "from", "to", "coneangle", "shadowbias",
};

struct mlight {
	char name[16];
	bool live;
	float v[NPARAMS];
	bool muted, frozen, pinned;
};

struct model {
	struct mlight l[MAX_LIGHTS];
	uint32_t n;
	int solo;
};

static void model_init(struct model *m)
{
	memset(m, 0, sizeof(*m));
	m->solo = -1;
	for (uint32_t i = 0; i < BASE_LIGHTS; i++) {
		snprintf(m->l[i].name, sizeof(m->l[i].name), "L%u", i);
		m->l[i].live = true;
		m->l[i].frozen = true;
	}
	m->n = BASE_LIGHTS;
}

static int find(const struct model *m, const char *name)
{
	for (uint32_t i = 0; i < m->n; i++)
		if (m->l[i].live && !strcmp(m->l[i].name, name))
			return (int)i;
	return -1;
}

static int param_index(const char *name)
{
	for (int k = 0; k < NPARAMS; k++)
		if (!strcmp(param_names[k], name))
			return k;
	return -1;
}

static void editing(struct model *m, int L)
{
	for (uint32_t i = 0; i < m->n; i++)
		if ((int)i != L && !m->l[i].frozen && !m->l[i].pinned)
			m->l[i].frozen = true;
	m->l[L].frozen = false;
}

static bool model_set(struct model *m, int L, const struct srv_job *j)
{
	for (uint32_t k = 0; k < j->nparams; k++) {
		int p = param_index(j->params[k].name);
		if (p < 0)
			return false;
		m->l[L].v[p] = j->params[k].values[0];
	}
	editing(m, L);
	return true;
}

/* Apply @j as the worker does; false where the worker refuses it. */
static bool model_apply(struct model *m, const struct srv_job *j)
{
	int L = j->light ? find(m, j->light) : -1;
	if (j->light && j->op != PROTO_ADD_LIGHT && L < 0)
		return false;
	switch (j->op) {
	case PROTO_SET:
		return model_set(m, L, j);
	case PROTO_MUTE:
		m->l[L].muted = j->on;
		return true;
	case PROTO_SOLO:
		m->solo = L;
		return true;
	case PROTO_FREEZE:
		m->l[L].pinned = !j->on;
		m->l[L].frozen = j->on;
		return true;
	case PROTO_REMOVE_LIGHT:
		m->l[L].live = false;
		if (m->solo == L)
			m->solo = -1;
		return true;
	case PROTO_ADD_LIGHT: {
		if (L >= 0 || m->n == MAX_LIGHTS)
			return false;
		struct mlight *n = &m->l[m->n];
		memset(n, 0, sizeof(*n));
		snprintf(n->name, sizeof(n->name), "%s", j->light);
		n->live = true;
		m->n++;
		editing(m, (int)m->n - 1);
		return !j->nparams || model_set(m, (int)m->n - 1, j);
	}
	default:
		return false;
	}
}

static void check_same(const struct model *a, const struct model *b)
{
	bool same = a->n == b->n && a->solo == b->solo;
	for (uint32_t i = 0; same && i < a->n; i++) {
		const struct mlight *x = &a->l[i], *y = &b->l[i];
		same = x->live == y->live && !strcmp(x->name, y->name);
		if (same && x->live)
			same = !memcmp(x->v, y->v, sizeof(x->v)) && x->muted == y->muted &&
			       x->frozen == y->frozen && x->pinned == y->pinned;
		if (!same)
			fprintf(stderr, "light %u (%s) differs\n", i, x->name);
	}
	CHECK(same);
}

static uint64_t rng = 88172645463325252ull;
static uint32_t next_rand(uint32_t n)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (uint32_t)(rng % n);
}

/* A random edit of @m's lights (by name: some no longer live). */
static struct srv_job *random_edit(const struct model *m, uint32_t *added)
{
	struct srv_job *j = calloc(1, sizeof(*j));
	char name[16];
	uint32_t r = next_rand(1000);
	/* now and then a light that is gone: the worker refuses those */
	uint32_t pick = next_rand(m->n);
	for (int tries = 0; tries < 8 && !m->l[pick].live; tries++)
		pick = next_rand(m->n);
	snprintf(name, sizeof(name), "%s", m->l[pick].name);
	if (r < 800) {
		j->op = PROTO_SET;
		j->nparams = 1 + next_rand(3);
		j->params = calloc(j->nparams, sizeof(*j->params));
		for (uint32_t k = 0; k < j->nparams; k++) {
			j->params[k].name = strdup(param_names[(k * 2 + next_rand(NPARAMS)) % NPARAMS]);
			j->params[k].values[0] = (float)next_rand(100000);
			j->params[k].n = 1;
		}
		/* one name twice in a set is the codec's to refuse */
		for (uint32_t k = 1; k < j->nparams; k++)
			for (uint32_t q = 0; q < k; q++)
				if (!strcmp(j->params[k].name, j->params[q].name)) {
					free((char *)j->params[k].name);
					j->params[k] = j->params[--j->nparams];
					k--;
					break;
				}
	} else if (r < 880) {
		j->op = PROTO_MUTE;
		j->on = next_rand(2);
	} else if (r < 940) {
		j->op = PROTO_FREEZE;
		j->on = next_rand(2);
	} else if (r < 990) {
		j->op = PROTO_SOLO;
		if (next_rand(4) == 0)
			name[0] = '\0';
	} else if (r < 997) {
		if (*added >= MAX_LIGHTS - BASE_LIGHTS) {
			j->op = PROTO_MUTE;
			j->on = false;
			j->light = strdup(name);
			return j;
		}
		j->op = PROTO_ADD_LIGHT;
		snprintf(name, sizeof(name), "N%u", (*added)++);
		j->shader = strdup("pointlight");
		if (next_rand(2)) {
			j->nparams = 1;
			j->params = calloc(1, sizeof(*j->params));
			j->params[0].name = strdup("intensity");
			j->params[0].values[0] = 3;
			j->params[0].n = 1;
		}
	} else {
		uint32_t live = 0;
		for (uint32_t i = 0; i < m->n; i++)
			live += m->l[i].live;
		j->op = live > 8 ? PROTO_REMOVE_LIGHT : PROTO_FREEZE;
	}
	j->light = name[0] ? strdup(name) : NULL;
	return j;
}

static void test_compaction(void)
{
	struct model live, replayed;
	model_init(&live);
	struct srv_editlog log = { 0 };
	uint32_t added = 0, applied = 0;
	size_t most = 0, most_bytes = 0;
	for (int i = 0; i < 100000; i++) {
		struct srv_job *j = random_edit(&live, &added);
		if (!model_apply(&live, j)) {
			srv_job_free(j);
			continue;
		}
		applied++;
		CHECK(srv_editlog_add(&log, j));
		most = log.n > most ? log.n : most;
		most_bytes = log.bytes > most_bytes ? log.bytes : most_bytes;
		/* now and then, and at the end: the replay gives the same state */
		if (i % 9973 == 0 || i == 99999) {
			model_init(&replayed);
			for (size_t k = 0; k < log.n; k++)
				CHECK(model_apply(&replayed, log.v[k]));
			check_same(&live, &replayed);
		}
	}
	size_t bytes = 0;
	for (size_t k = 0; k < log.n; k++)
		bytes += srv_job_bytes(log.v[k]);
	CHECK(bytes == log.bytes);
	/* At most: a set per parameter, a mute and a freeze per light of each
	 * epoch, one solo, and the adds and removes with their epochs' entries. */
	size_t epochs = BASE_LIGHTS + 2 * (size_t)added;
	size_t bound = epochs * (NPARAMS + 2) + 1 + 2 * (size_t)added;
	printf("%u edits applied; log: %zu entries (most %zu), %zu bytes (most %zu); bound %zu\n",
	       applied, log.n, most, log.bytes, most_bytes, bound);
	CHECK(applied > 60000);
	CHECK(added > 0);
	CHECK(most <= bound);
	CHECK(most_bytes <= bound * 512);
	srv_editlog_finish(&log);
	CHECK(log.n == 0 && log.bytes == 0);
}

/* The rules one by one, on a small log. */
static void test_rules(void)
{
	struct srv_editlog log = { 0 };
	struct proto_param p2[2] = { { .name = "intensity", .n = 1 }, { .name = "from", .n = 3 } };
	struct proto_param p1[1] = { { .name = "intensity", .n = 1, .values = { 5 } } };
	struct proto_request set2 = { .op = PROTO_SET, .light = "a", .params = p2, .nparams = 2 };
	struct proto_request set1 = { .op = PROTO_SET, .light = "a", .params = p1, .nparams = 1 };
	struct proto_request mute = { .op = PROTO_MUTE, .light = "a", .on = true };
	struct proto_request rm = { .op = PROTO_REMOVE_LIGHT, .light = "a" };
	struct proto_request add = { .op = PROTO_ADD_LIGHT, .light = "a", .shader = "spot" };
	struct proto_request solo = { .op = PROTO_SOLO, .light = "b" };
	CHECK(srv_editlog_add(&log, srv_job_from(&set2, 1, 0)));
	CHECK(srv_editlog_add(&log, srv_job_from(&set1, 1, 0)));
	/* the first set keeps "from" alone */
	CHECK(log.n == 2 && log.v[0]->nparams == 1 && !strcmp(log.v[0]->params[0].name, "from"));
	CHECK(srv_editlog_add(&log, srv_job_from(&set1, 1, 0)));
	CHECK(log.n == 2);
	CHECK(srv_editlog_add(&log, srv_job_from(&solo, 1, 0)));
	CHECK(srv_editlog_add(&log, srv_job_from(&mute, 1, 0)));
	CHECK(srv_editlog_add(&log, srv_job_from(&mute, 1, 0)));
	CHECK(srv_editlog_add(&log, srv_job_from(&solo, 1, 0)));
	CHECK(log.n == 4);
	/* a removal takes the light's mute; the sets stay; a re-added light starts afresh */
	CHECK(srv_editlog_add(&log, srv_job_from(&rm, 1, 0)));
	CHECK(log.n == 4 && log.v[3]->op == PROTO_REMOVE_LIGHT);
	CHECK(srv_editlog_add(&log, srv_job_from(&add, 1, 0)));
	CHECK(srv_editlog_add(&log, srv_job_from(&set1, 1, 0)));
	CHECK(log.n == 6 && log.v[0]->op == PROTO_SET && log.v[5]->op == PROTO_SET);
	CHECK(log.v[5]->client == 0);
	srv_editlog_finish(&log);
}

int main(void)
{
	RUN(test_rules);
	RUN(test_compaction);
	return test_finish();
}

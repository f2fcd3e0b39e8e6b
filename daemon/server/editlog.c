/*
 * Jobs for the render worker, and each shot's log of the edits applied to
 * it, replayed in order when an evicted shot is loaded again.
 *
 * The log holds the state the edits produce, not their history: an edit
 * that a later one makes void is dropped when the later one is added, so a
 * lighter who drags a slider for an hour leaves one entry per parameter.
 * What an entry may be dropped for, light by light, within its "epoch"
 * (the entries since the light was last added or removed):
 *
 *   set L p=v     a later set of L's parameter p: p leaves the earlier
 *                 entry (the entry goes once it has no parameter left). The
 *                 later set unfreezes L and freezes the lights that earlier
 *                 edits unfroze, as the earlier one did, so the lights'
 *                 freeze state after the later one does not depend on it;
 *   mute L        a later mute of L: it sets the one flag the earlier set;
 *   freeze L      a later freeze of L (both set L's frozen and pinned
 *                 flags, and nothing else);
 *   mute, freeze  remove_light L: a removed light's flags are never read;
 *   solo          any later solo: the shot has one soloed light.
 *
 * add_light and remove_light stay, in order, with the sets between them:
 * a set also changes other lights' freeze state, which a replay must
 * reproduce exactly for the light cache to sum what it summed before.
 */
#include "srv.h"

#include <stdlib.h>
#include <string.h>

/* ---- jobs ---- */

static char *dup_str(const char *s)
{
	return s ? strdup(s) : NULL;
}

struct srv_job *srv_job_from(const struct proto_request *r, uint64_t client, double t0)
{
	struct srv_job *j = calloc(1, sizeof(*j));
	if (!j)
		return NULL;
	j->op = r->op;
	j->client = client;
	j->has_id = r->has_id;
	j->id = r->id;
	j->t0 = t0;
	j->on = r->on;
	j->format = r->format;
	j->x = r->x;
	j->y = r->y;
	j->light = dup_str(r->light);
	j->shader = dup_str(r->shader);
	bool ok = (!r->light || j->light) && (!r->shader || j->shader);
	if (ok && r->nparams) {
		j->params = calloc(r->nparams, sizeof(*j->params));
		ok = j->params != NULL;
		for (uint32_t k = 0; ok && k < r->nparams; k++) {
			j->params[k] = r->params[k];
			j->params[k].name = strdup(r->params[k].name);
			j->params[k].text = r->params[k].text ? strdup(r->params[k].text) : NULL;
			ok = j->params[k].name != NULL && (!r->params[k].text || j->params[k].text);
			j->nparams = k + 1;
		}
	}
	if (!ok) {
		srv_job_free(j);
		return NULL;
	}
	return j;
}

void srv_job_free(struct srv_job *j)
{
	if (!j)
		return;
	free(j->light);
	free(j->shader);
	for (uint32_t k = 0; k < j->nparams; k++) {
		free((char *)j->params[k].name);
		free((char *)j->params[k].text);
	}
	free(j->params);
	free(j);
}

size_t srv_job_bytes(const struct srv_job *j)
{
	size_t n = sizeof(*j) + (size_t)j->nparams * sizeof(*j->params);
	n += j->light ? strlen(j->light) + 1 : 0;
	n += j->shader ? strlen(j->shader) + 1 : 0;
	for (uint32_t k = 0; k < j->nparams; k++)
		n += strlen(j->params[k].name) + 1 +
		     (j->params[k].text ? strlen(j->params[k].text) + 1 : 0);
	return n;
}

/* ---- the edit log ---- */

static bool same_light(const struct srv_job *a, const struct srv_job *b)
{
	return a->light && b->light && !strcmp(a->light, b->light);
}

static bool has_param(const struct srv_job *j, const char *name)
{
	for (uint32_t k = 0; k < j->nparams; k++)
		if (!strcmp(j->params[k].name, name))
			return true;
	return false;
}

/* Take from set @old the parameters set @newer sets again; whether any is left. */
static bool drop_params(struct srv_job *old, const struct srv_job *newer)
{
	uint32_t kept = 0;
	for (uint32_t k = 0; k < old->nparams; k++) {
		if (has_param(newer, old->params[k].name)) {
			free((char *)old->params[k].name);
			free((char *)old->params[k].text);
		}
		else
			old->params[kept++] = old->params[k];
	}
	old->nparams = kept;
	return kept > 0;
}

/* Whether adding @j voids @old, an earlier entry of @j's light's epoch (any entry for a solo). */
static bool superseded(struct srv_job *old, const struct srv_job *j)
{
	switch (j->op) {
	case PROTO_SOLO:
		return old->op == PROTO_SOLO;
	case PROTO_SET:
		return old->op == PROTO_SET && !drop_params(old, j);
	case PROTO_MUTE:
	case PROTO_FREEZE:
		return old->op == j->op;
	case PROTO_REMOVE_LIGHT:
		return old->op == PROTO_MUTE || old->op == PROTO_FREEZE;
	default:
		return false;
	}
}

bool srv_editlog_add(struct srv_editlog *log, struct srv_job *j)
{
	if (log->n == log->cap) {
		size_t cap = log->cap ? log->cap * 2 : 16;
		struct srv_job **v = realloc(log->v, cap * sizeof(*v));
		if (!v) {
			srv_job_free(j);
			return false;
		}
		log->v = v;
		log->cap = cap;
	}
	/* Newest first, back to the light's last add or remove (a solo: all the way). */
	size_t first_gap = log->n;
	for (size_t i = log->n; i-- > 0;) {
		struct srv_job *old = log->v[i];
		if (j->op != PROTO_SOLO) {
			if (!same_light(old, j))
				continue;
			if (old->op == PROTO_ADD_LIGHT || old->op == PROTO_REMOVE_LIGHT)
				break;
		}
		size_t before = srv_job_bytes(old);
		if (superseded(old, j)) {
			log->bytes -= before;
			srv_job_free(old);
			log->v[i] = NULL;
			first_gap = i;
		} else {
			log->bytes -= before - srv_job_bytes(old);
		}
	}
	size_t kept = first_gap;
	for (size_t i = first_gap; i < log->n; i++)
		if (log->v[i])
			log->v[kept++] = log->v[i];
	log->n = kept;
	j->client = 0;
	j->next = NULL;
	log->v[log->n++] = j;
	log->bytes += srv_job_bytes(j);
	return true;
}

void srv_editlog_finish(struct srv_editlog *log)
{
	for (size_t i = 0; i < log->n; i++)
		srv_job_free(log->v[i]);
	free(log->v);
	memset(log, 0, sizeof(*log));
}

/*
 * Texture and environment maps on the GPU: see texmap.h. The levels are
 * uploaded as the texture system holds them (reyes_tex_map): one float per
 * channel, channels interleaved, rows top to bottom, level after level, so
 * a kernel's texel index is the renderer's.
 */
#include "texmap.h"
#include "texture.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

struct gpu_texmap {
	struct gpu_buffer *texels;
	size_t bytes;
	int info[4];                         /* channels, levels, swrap, twrap */
	int lv[4 * GPU_TEXMAP_LEVELS];       /* per level: first float, width, height, face */
	float cube[3];                       /* cube or not, 0.5 / tan(fov / 2) as two floats */
};

struct gpu_texmap *gpu_texmap_load(struct gpu_ctx *ctx, struct reyes_texsys *ts,
				   const char *name, char *err, size_t errlen)
{
	char dummy[1];
	if (!err || !errlen) {
		err = dummy;
		errlen = sizeof(dummy);
	}
	err[0] = '\0';
	if (!ctx || !ts || !name || !name[0]) {
		snprintf(err, errlen, "%s: no context, texture system or map name",
			 name && name[0] ? name : "(no name)");
		return NULL;
	}
	struct reyes_tex_map_info info;
	if (!reyes_tex_map(ts, name, &info)) {
		snprintf(err, errlen, "%s: not found or unreadable", name);
		return NULL;
	}
	if (info.nlevels > GPU_TEXMAP_LEVELS || !info.nchannels) {
		snprintf(err, errlen, "%s: %u levels of %u channels cannot be read on the GPU "
			 "(at most %d levels: maps up to %u texels on a side)", name, info.nlevels,
			 info.nchannels, GPU_TEXMAP_LEVELS, 1u << (GPU_TEXMAP_LEVELS - 1));
		return NULL;
	}
	struct gpu_texmap *m = calloc(1, sizeof(*m));
	if (!m) {
		snprintf(err, errlen, "%s: out of memory", name);
		return NULL;
	}
	size_t total = 0;
	for (uint32_t l = 0; l < info.nlevels; l++) {
		const struct reyes_image *im = &info.levels[l];
		if (im->nchannels != info.nchannels || total > (size_t)INT32_MAX) {
			snprintf(err, errlen, "%s: level %u does not fit", name, l);
			free(m);
			return NULL;
		}
		m->lv[4 * l] = (int)total;
		m->lv[4 * l + 1] = (int)im->width;
		m->lv[4 * l + 2] = (int)im->height;
		m->lv[4 * l + 3] = (int)info.face_size[l];
		total += (size_t)im->width * im->height * im->nchannels;
	}
	/* texel indices are ints in the kernel */
	if (!total || total > (size_t)INT32_MAX) {
		snprintf(err, errlen, "%s: %zu floats cannot be read on the GPU", name, total);
		free(m);
		return NULL;
	}
	m->texels = gpu_buffer_create(ctx, total * sizeof(float), NULL);
	for (uint32_t l = 0; m->texels && l < info.nlevels; l++) {
		const struct reyes_image *im = &info.levels[l];
		size_t n = (size_t)im->width * im->height * im->nchannels;
		if (!gpu_buffer_write(m->texels, (size_t)m->lv[4 * l] * sizeof(float),
				      n * sizeof(float), im->data)) {
			gpu_buffer_destroy(m->texels);
			m->texels = NULL;
		}
	}
	if (!m->texels) {
		snprintf(err, errlen, "%s: cannot upload %zu floats", name, total);
		free(m);
		return NULL;
	}
	m->bytes = total * sizeof(float);
	m->info[0] = (int)info.nchannels;
	m->info[1] = (int)info.nlevels;
	m->info[2] = (int)info.swrap;
	m->info[3] = (int)info.twrap;
	if (info.cube) {
		/* texture.c dir_to_cube's k, in double there: here as a float and its remainder */
		double k = 0.5 / tan(0.5 * info.fov * PI / 180.0);
		m->cube[0] = 1.0f;
		m->cube[1] = (float)k;
		m->cube[2] = (float)(k - (double)m->cube[1]);
	}
	return m;
}

void gpu_texmap_destroy(struct gpu_texmap *m)
{
	if (!m)
		return;
	gpu_buffer_destroy(m->texels);
	free(m);
}

size_t gpu_texmap_bytes(const struct gpu_texmap *m)
{
	return m ? m->bytes : 0;
}

bool gpu_texmap_bind(struct gpu_program *p, uint32_t site, bool environment,
		     const struct gpu_texmap *m, uint32_t unit, struct gpu_binding *b)
{
	if (!p || !b || site > 1000000u || (!m && !b->buffer))
		return false;
	static const int none[4 * GPU_TEXMAP_LEVELS];
	static const float flat[3];
	char name[64];
	snprintf(name, sizeof(name), "u_map%u_info", site);
	int info[4] = { 0, 0, 0, 0 };
	if (m)
		memcpy(info, m->info, sizeof(info));
	if (!gpu_uniform_ints(p, name, info, 4))
		return false;
	snprintf(name, sizeof(name), "u_map%u_lv", site);
	gpu_uniform_ints(p, name, m ? m->lv : none, 4 * GPU_TEXMAP_LEVELS);
	if (environment) {
		snprintf(name, sizeof(name), "u_map%u_cube", site);
		gpu_uniform_float(p, name, m ? m->cube : flat, 3);
	}
	b->unit = unit;
	b->ssbo = false;
	b->rgba = false;
	if (m)
		b->buffer = m->texels;
	return true;
}

/* ------------------------------------------------------------------------ */
/* A shot's maps                                                             */

struct entry {
	char *name;
	struct gpu_texmap *map;    /* NULL: missing (warned once) */
};

struct gpu_texmaps {
	struct gpu_ctx *ctx;
	struct reyes_texsys *ts;
	FILE *diag;
	struct entry *e;
	uint32_t n, cap;
};

struct gpu_texmaps *gpu_texmaps_create(struct gpu_ctx *ctx, struct reyes_texsys *ts, FILE *diag)
{
	struct gpu_texmaps *c = calloc(1, sizeof(*c));
	if (!c)
		return NULL;
	c->ctx = ctx;
	c->ts = ts;
	c->diag = diag ? diag : stderr;
	return c;
}

void gpu_texmaps_destroy(struct gpu_texmaps *c)
{
	if (!c)
		return;
	for (uint32_t i = 0; i < c->n; i++) {
		gpu_texmap_destroy(c->e[i].map);
		free(c->e[i].name);
	}
	free(c->e);
	free(c);
}

const struct gpu_texmap *gpu_texmaps_get(struct gpu_texmaps *c, const char *name, const char *who,
					 size_t room)
{
	if (!c || !name || !name[0])
		return NULL;
	for (uint32_t i = 0; i < c->n; i++)
		if (!strcmp(c->e[i].name, name))
			return c->e[i].map;
	if (c->n == c->cap) {
		uint32_t cap = c->cap ? 2 * c->cap : 8;
		struct entry *e = realloc(c->e, cap * sizeof(*e));
		if (!e)
			return NULL;
		c->e = e;
		c->cap = cap;
	}
	char *copy = strdup(name);
	if (!copy)
		return NULL;
	char err[512];
	struct gpu_texmap *m = gpu_texmap_load(c->ctx, c->ts, name, err, sizeof(err));
	if (m && m->bytes > room) {
		snprintf(err, sizeof(err), "%s: %.1f MiB do not fit in what is left of the shot's GPU "
			 "memory budget (%.1f MiB)", name, (double)m->bytes / 1048576.0,
			 (double)room / 1048576.0);
		gpu_texmap_destroy(m);
		m = NULL;
	}
	if (!m)
		fprintf(c->diag, "relight: warning: %s: %s; its lookups give the fill\n",
			who ? who : "a light", err);
	c->e[c->n++] = (struct entry){ copy, m };
	return m;
}

size_t gpu_texmaps_bytes(const struct gpu_texmaps *c)
{
	size_t b = 0;
	for (uint32_t i = 0; c && i < c->n; i++)
		b += gpu_texmap_bytes(c->e[i].map);
	return b;
}

uint32_t gpu_texmaps_count(const struct gpu_texmaps *c)
{
	uint32_t n = 0;
	for (uint32_t i = 0; c && i < c->n; i++)
		n += c->e[i].map != NULL;
	return n;
}

void gpu_texmaps_keep_only(struct gpu_texmaps *c, const char *const *names, uint32_t n)
{
	if (!c)
		return;
	uint32_t out = 0;
	for (uint32_t i = 0; i < c->n; i++) {
		bool keep = c->e[i].map == NULL;   /* a missing map keeps its one warning */
		for (uint32_t k = 0; k < n && !keep; k++)
			keep = names[k] && !strcmp(names[k], c->e[i].name);
		if (keep) {
			c->e[out++] = c->e[i];
			continue;
		}
		gpu_texmap_destroy(c->e[i].map);
		free(c->e[i].name);
	}
	c->n = out;
}

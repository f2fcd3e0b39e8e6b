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

/* The header before the levels (sl/glsl_texmap.c): floats, ints as their bits. */
#define HEADER (8 + 4 * GPU_TEXMAP_LEVELS)

struct gpu_texmap {
	struct gpu_buffer *texels;
	size_t bytes;
};

static float int_bits(int32_t v)
{
	float f;
	memcpy(&f, &v, sizeof(f));
	return f;
}

/* The header of @info's map, whose levels start at float HEADER. */
static void make_header(const struct reyes_tex_map_info *info, float h[HEADER])
{
	int32_t ints[8] = { (int32_t)info->nchannels, (int32_t)info->nlevels,
			    (int32_t)info->swrap, (int32_t)info->twrap, info->cube ? 1 : 0 };
	for (int k = 0; k < 8; k++)
		h[k] = int_bits(ints[k]);
	if (info->cube) {
		/* texture.c dir_to_cube's k, in double there: here as a float and its remainder */
		double k = 0.5 / tan(0.5 * info->fov * PI / 180.0);
		h[5] = (float)k;
		h[6] = (float)(k - (double)h[5]);
	}
	size_t at = HEADER;
	for (uint32_t l = 0; l < GPU_TEXMAP_LEVELS; l++) {
		const struct reyes_image *im = l < info->nlevels ? &info->levels[l] : NULL;
		int32_t lv[4] = { im ? (int32_t)at : 0, im ? (int32_t)im->width : 0,
				  im ? (int32_t)im->height : 0, im ? (int32_t)info->face_size[l] : 0 };
		for (int k = 0; k < 4; k++)
			h[8 + 4 * l + k] = int_bits(lv[k]);
		if (im)
			at += (size_t)im->width * im->height * im->nchannels;
	}
}

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
	if (info.nlevels > GPU_TEXMAP_LEVELS || !info.nchannels || !info.nlevels) {
		snprintf(err, errlen, "%s: %u levels of %u channels cannot be read on the GPU "
			 "(at most %d levels: maps up to %u texels on a side)", name, info.nlevels,
			 info.nchannels, GPU_TEXMAP_LEVELS, 1u << (GPU_TEXMAP_LEVELS - 1));
		return NULL;
	}
	size_t total = HEADER;
	for (uint32_t l = 0; l < info.nlevels; l++) {
		const struct reyes_image *im = &info.levels[l];
		if (im->nchannels != info.nchannels) {
			snprintf(err, errlen, "%s: level %u has %u channels, level 0 %u", name, l,
				 im->nchannels, info.nchannels);
			return NULL;
		}
		total += (size_t)im->width * im->height * im->nchannels;
	}
	/* texel indices are ints in the kernel */
	if (total > (size_t)INT32_MAX) {
		snprintf(err, errlen, "%s: %zu floats cannot be read on the GPU", name, total);
		return NULL;
	}
	struct gpu_texmap *m = calloc(1, sizeof(*m));
	if (!m) {
		snprintf(err, errlen, "%s: out of memory", name);
		return NULL;
	}
	float header[HEADER];
	make_header(&info, header);
	m->texels = gpu_buffer_create(ctx, total * sizeof(float), NULL);
	bool ok = m->texels && gpu_buffer_write(m->texels, 0, sizeof(header), header);
	size_t at = HEADER;
	for (uint32_t l = 0; ok && l < info.nlevels; l++) {
		const struct reyes_image *im = &info.levels[l];
		size_t n = (size_t)im->width * im->height * im->nchannels;
		ok = gpu_buffer_write(m->texels, at * sizeof(float), n * sizeof(float), im->data);
		at += n;
	}
	if (!ok) {
		snprintf(err, errlen, "%s: cannot upload %zu floats", name, total);
		gpu_buffer_destroy(m->texels);
		free(m);
		return NULL;
	}
	m->bytes = total * sizeof(float);
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

bool gpu_texmap_bind(const struct gpu_texmap *m, uint32_t unit, struct gpu_binding *b)
{
	if (!b || (!m && !b->buffer))
		return false;
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

/*
 * Shadow maps on the GPU: see shadowmap.h. The depth plane is uploaded as
 * it is in the texture system (reyes_tex_shadow_map): one float per texel,
 * row-major, so the kernel's texel index is the renderer's. A deep shadow
 * map (render/deepshadow.h) is one buffer too: width * height + 1 offsets
 * (as floats: node indices, exact below 2^24), then the (z, T) nodes.
 */
#include "shadowmap.h"
#include "glsl.h"
#include "texture.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct gpu_shadow_map {
	struct gpu_buffer *depth;
	uint32_t width, height;
	float world_to_camera[16], world_to_ndc[16];
	float bias;
	bool borrowed;       /* depth belongs to the caller (gpu_shadow_map_with_depth) */
	bool deep;           /* a deep shadow map: offsets and nodes, not depths */
	size_t bytes;
};

/* Most nodes a deep map may have on the GPU: its offsets are floats. */
#define MAX_DEEP_NODES (1u << 24)

/* The buffer of deep map @info: offsets then nodes; NULL with @err when too big. */
static float *deep_plane(const struct reyes_shadow_map_info *info, const char *name, size_t *n,
			 char *err, size_t errlen)
{
	size_t npix = (size_t)info->width * info->height;
	uint32_t total = info->deep_offsets[npix];
	if (total > MAX_DEEP_NODES) {
		snprintf(err, errlen, "%s: a deep shadow map of %u nodes is over the GPU's %u", name,
			 total, MAX_DEEP_NODES);
		return NULL;
	}
	*n = npix + 1 + 2 * (size_t)total;
	float *plane = malloc(*n * sizeof(float));
	if (!plane) {
		snprintf(err, errlen, "%s: out of memory", name);
		return NULL;
	}
	for (size_t i = 0; i <= npix; i++)
		plane[i] = (float)info->deep_offsets[i];
	memcpy(plane + npix + 1, info->deep_nodes, 2 * (size_t)total * sizeof(float));
	return plane;
}

struct gpu_shadow_map *gpu_shadow_map_load(struct gpu_ctx *ctx, struct reyes_texsys *ts,
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
	struct reyes_shadow_map_info info;
	if (!reyes_tex_shadow_map(ts, name, &info)) {
		snprintf(err, errlen, "%s: not found, unreadable, or not a shadow map", name);
		return NULL;
	}
	size_t n = (size_t)info.width * info.height;
	if (!n || n > (size_t)INT32_MAX - 2 * (size_t)MAX_DEEP_NODES - 1) {
		snprintf(err, errlen, "%s: a %ux%u map cannot be used on the GPU", name, info.width,
			 info.height);
		return NULL;
	}
	bool deep = info.depth == NULL;
	float *plane = deep ? deep_plane(&info, name, &n, err, errlen) : malloc(n * sizeof(float));
	if (!plane) {
		if (!deep)
			snprintf(err, errlen, "%s: out of memory", name);
		return NULL;
	}
	struct gpu_shadow_map *m = calloc(1, sizeof(*m));
	if (!m) {
		snprintf(err, errlen, "%s: out of memory", name);
		free(plane);
		return NULL;
	}
	for (size_t i = 0; !deep && i < n; i++)
		plane[i] = info.depth[i * info.stride];
	m->deep = deep;
	m->bytes = n * sizeof(float);
	m->depth = gpu_buffer_create(ctx, n * sizeof(float), plane);
	free(plane);
	if (!m->depth) {
		snprintf(err, errlen, "%s: cannot upload %zu depths", name, n);
		free(m);
		return NULL;
	}
	m->width = info.width;
	m->height = info.height;
	memcpy(m->world_to_camera, info.world_to_camera, sizeof(m->world_to_camera));
	memcpy(m->world_to_ndc, info.world_to_ndc, sizeof(m->world_to_ndc));
	m->bias = info.bias;
	return m;
}

void gpu_shadow_map_destroy(struct gpu_shadow_map *m)
{
	if (!m)
		return;
	if (!m->borrowed)
		gpu_buffer_destroy(m->depth);
	free(m);
}

struct gpu_shadow_map *gpu_shadow_map_with_depth(const struct gpu_shadow_map *like,
						 struct gpu_buffer *depth)
{
	if (!like || !depth)
		return NULL;
	struct gpu_shadow_map *m = malloc(sizeof(*m));
	if (!m)
		return NULL;
	*m = *like;
	m->depth = depth;
	m->deep = false;
	m->bytes = (size_t)m->width * m->height * sizeof(float);
	m->borrowed = true;
	return m;
}

struct gpu_shadow_map *gpu_shadow_map_with_deep(const struct gpu_shadow_map *like,
						struct gpu_buffer *deep, size_t bytes)
{
	if (!like || !deep)
		return NULL;
	struct gpu_shadow_map *m = malloc(sizeof(*m));
	if (!m)
		return NULL;
	*m = *like;
	m->depth = deep;
	m->deep = true;
	m->bytes = bytes;
	m->borrowed = false;
	return m;
}

void gpu_shadow_map_set_camera(struct gpu_shadow_map *m, const float world_to_camera[16],
			       const float world_to_ndc[16])
{
	memcpy(m->world_to_camera, world_to_camera, 16 * sizeof(float));
	memcpy(m->world_to_ndc, world_to_ndc, 16 * sizeof(float));
}

void gpu_shadow_map_camera(const struct gpu_shadow_map *m, float world_to_camera[16],
			   float world_to_ndc[16])
{
	memcpy(world_to_camera, m->world_to_camera, 16 * sizeof(float));
	memcpy(world_to_ndc, m->world_to_ndc, 16 * sizeof(float));
}

size_t gpu_shadow_map_bytes(const struct gpu_shadow_map *m)
{
	return m ? m->bytes : 0;
}

bool gpu_shadow_map_is_deep(const struct gpu_shadow_map *m)
{
	return m && m->deep;
}

void gpu_shadow_map_size(const struct gpu_shadow_map *m, uint32_t *width, uint32_t *height)
{
	if (width)
		*width = m ? m->width : 0;
	if (height)
		*height = m ? m->height : 0;
}

bool gpu_shadow_map_bind(struct gpu_ctx *ctx, struct gpu_program *p, uint32_t site,
			 const struct gpu_shadow_map *m, const float to_world[16],
			 struct gpu_binding *b)
{
	if (!ctx || !p || !b || !to_world || site > 1000000u || (!m && !b->buffer))
		return false;
	char name[64];
	snprintf(name, sizeof(name), "u_shadow%u_size[0]", site);
	if (!gpu_uniform_int(p, name, m ? (int)m->width : 0))
		return false;
	snprintf(name, sizeof(name), "u_shadow%u_size[1]", site);
	gpu_uniform_int(p, name, m ? (int)m->height : 0);
	static const float zero[16];
	snprintf(name, sizeof(name), "u_shadow%u_to_camera", site);
	gpu_uniform_mat4(p, name, m ? m->world_to_camera : zero);
	snprintf(name, sizeof(name), "u_shadow%u_to_ndc", site);
	gpu_uniform_mat4(p, name, m ? m->world_to_ndc : zero);
	snprintf(name, sizeof(name), "u_shadow%u_bias", site);
	float bias = m ? m->bias : 0.0f;
	gpu_uniform_float(p, name, &bias, 1);
	snprintf(name, sizeof(name), "u_shadow%u_deep", site);
	gpu_uniform_int(p, name, m && m->deep);
	gpu_uniform_mat4(p, "u_to_world", to_world);
	b->unit = SL_GLSL_SHADOW_UNIT0 + site;
	b->ssbo = false;
	if (m)
		b->buffer = m->depth;
	return true;
}

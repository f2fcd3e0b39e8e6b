/*
 * Shadow maps on the GPU: see shadowmap.h.
 */
#include "shadowmap.h"

#include <stdio.h>

struct gpu_shadow_map *gpu_shadow_map_load(struct gpu_ctx *ctx, struct reyes_texsys *ts,
					   const char *name, char *err, size_t errlen)
{
	(void)ctx;
	(void)ts;
	snprintf(err, errlen, "%s: shadow maps on the GPU are not available", name);
	return NULL;
}

void gpu_shadow_map_destroy(struct gpu_shadow_map *m)
{
	(void)m;
}

size_t gpu_shadow_map_bytes(const struct gpu_shadow_map *m)
{
	(void)m;
	return 0;
}

bool gpu_shadow_map_bind(struct gpu_ctx *ctx, struct gpu_program *p, uint32_t site,
			 const struct gpu_shadow_map *m, const float to_world[16],
			 struct gpu_binding *b)
{
	(void)ctx;
	(void)p;
	(void)site;
	(void)m;
	(void)to_world;
	(void)b;
	return false;
}

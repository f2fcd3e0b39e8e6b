/*
 * What the REYES pipeline (reyes.c) and ray tracing in it (reyes_trace.c)
 * share: the camera, grid jobs, per-thread shading state, the frame being
 * rendered. Private to daemon/render.
 */
#ifndef REYES_IMPL_H
#define REYES_IMPL_H

#include "reyes.h"
#include "geom.h"
#include "texture.h"
#include "deepshadow.h"
#include "lighthost.h"

#include <pthread.h>
#include <stdatomic.h>

struct reyes_rt;

struct camera {
	float w2c[16];          /* world -> camera (at shutter open) */
	float w2c1[16];         /* at shutter close */
	bool moving;            /* w2c1 differs from w2c */
	float lens[2];          /* depth of field: the aperture's radius in pixels at distance 1 */
	float focus;            /* 1 / the focal distance */
	float lens_screen;      /* the aperture's radius in screen units at distance 1 */
	float c2w[16];
	float c2ndc[16];        /* camera -> NDC (projective) */
	float screen[4];        /* l r b t */
	bool perspective;
	float focal;            /* 1 / tan(fov / 2) */
	float xres, yres;
	float near, far;
};

struct shaded {
	struct reyes_hider_grid hg;
	float *mem;             /* everything the hider grid points into */
};

struct job {
	struct reyes_patch piece;
	uint32_t nu, nv;        /* vertices */
	float bx0, by0, bx1, by1; /* raster bound (motion and displacement included) */
	uint32_t row0, row1;    /* bucket rows touched */
	struct shaded *sh;
};

struct aov {
	const char *name;
	int ncomp;
	uint32_t offset;        /* first plane in the hider's aov channels */
};

struct render;

/* Per-thread state: executors by shader instance, light executors, a hider. */
struct tctx {
	struct render *r;
	struct reyes_hider *hider;
	struct exec_entry {
		const struct reyes_shader *sh;
		struct sl_exec *x;
	} *execs;
	size_t nexecs, capexecs;
	struct sl_exec **light_x;        /* per scene light, created on first use */
	struct sl_lighthost lh;
	struct sl_exec **lights_on;      /* scratch: the executors of a grid's lights */
	float (*light_mats)[16];         /* scratch: their shader spaces */
	uint64_t grids, points, samples;
	float *bucket_rgba, *bucket_z, *bucket_aov;
	struct reyes_deep_scratch deep;  /* deep shadow pixels' scratch */
	bool failed;
	/* ray tracing (reyes_trace.c): the object being shaded, and the ray
	 * whose hit it is when this context shades hits (depth > 0) */
	const struct reyes_attrs *shading;
	uint32_t depth, specular_depth, diffuse_depth;
	enum sl_ray_type ray_type;
	float ray_org[3], ray_dir[3], ray_len;
	struct tctx *sub;                /* the context that shades this one's hits */
	uint64_t rays;                   /* rays cast from this context */
};

struct render {
	const struct reyes_scene *scene;
	const struct reyes_render_opts *o;
	FILE *diag;
	struct camera cam;
	uint32_t px0, px1, py0, py1;     /* pixels rendered (crop) */
	float margin;                    /* filter margin in pixels */
	uint32_t bucket, nbx, nby;
	uint32_t max_points;
	struct job *jobs;
	size_t njobs, capjobs;
	struct aov *aovs;
	size_t capaov;
	uint32_t naov, naov_planes;
	struct reyes_texsys *tex;
	struct reyes_shader default_surface;
	struct sl_program *default_prog;
	float (*light_mats)[16];         /* per scene light: its shader space -> camera */
	/* the image */
	float *rgba, *z, *aov;
	/* a deepshad display's: per pixel its visibility function, built to deep_error */
	struct reyes_deep_pixel *deep;
	float deep_error;
	/* work sharing */
	atomic_size_t next;
	size_t *todo;
	size_t ntodo;
	size_t *active;                  /* the shaded jobs the current row touches */
	size_t nactive;
	uint32_t row;
	struct tctx *ctx;
	uint32_t nthreads;
	uint64_t dropped;                /* pieces given up at the eye plane */
	atomic_bool failed;
	/*
	 * Dicing only (reyes_dice): keep what the camera cannot see (measured
	 * by the size of a pixel at its distance), and dice at @rate instead of
	 * each primitive's ShadingRate when it is positive.
	 */
	bool keep_unseen;
	float rate;
	/* With keep_unseen: dice everything as if the camera faced it (the
	 * geometry rays see, whichever way they come), none by its projection. */
	bool orient_free;
	/*
	 * The memory guard: the limit, the bytes the frame takes whatever is
	 * diced (images, buckets), and, as pieces are queued, the micropolygons
	 * their ShadingRate asks for, spread over the bucket rows they span,
	 * and the jobs they will split into.
	 */
	uint64_t limit;
	double fixed_bytes, job_bytes, total_points;
	double *row_points;              /* nby: points alive while the row is rendered */
	double row_most;                 /* the largest of them, in row row_fullest */
	uint32_t row_fullest;
	bool predicted;                  /* inside a piece already counted */
	/* ray tracing: the scene rays see, built on the first ray (under rt_lock) */
	struct reyes_rt *rt;
	pthread_mutex_t rt_lock;
	bool rt_tried;
};

/* Camera-space data of a grid being shaded. */
struct cgrid {
	uint32_t nu, nv, n;
	float *P0, *P1, *N, *Ng, *dPdu, *dPdv, *I, *s, *t, *Cs, *Os;
	const float *u, *v;
	float du, dv;
};

/* Spaces a shader may name, as matrices to camera ("current") space. */
struct spaces {
	const char *names[64];
	float mats[64][16];
	int n;
};

/* Split @pa until its pieces can be diced, queueing them as jobs of @r. */
void reyes_split_piece(struct render *r, const struct reyes_patch *pa);

/*
 * Dice a job into @g and carry it to camera space, displaced, in @c. On
 * success the caller frees c->P0 (one buffer holds all of @c's planes) and
 * finishes @g; on failure nothing is left to free.
 */
bool reyes_dice_job(struct tctx *t, const struct job *job, struct reyes_grid *g,
		    struct cgrid *c);

/* Run surface shader @surf over the grid @g, @c with the primitive's lights; *@sx ran it. */
bool reyes_shade_surface(struct tctx *t, const struct reyes_attrs *a,
			 const struct reyes_shader *surf, const struct reyes_grid *g,
			 const struct cgrid *c, struct sl_exec **sx);

/* For a trimmed NuPatch grid: a byte per micropolygon, 0 where the trim cuts it away. */
bool reyes_trim_keep(const struct reyes_prim *prim, const struct reyes_grid *g, uint8_t **keep);

/* The object-to-camera matrix of @a at shutter open (@t 0) or close (1). */
void reyes_obj_to_camera(const struct render *r, const struct reyes_attrs *a, int t,
			 float m[16]);


#endif

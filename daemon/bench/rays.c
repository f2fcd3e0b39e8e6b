/* Rays per second, Embree against the GPU's shadow kernel: see rays.h. */
#include "rays.h"
#include "gpu.h"
#include "shadowbvh.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const double PI = 3.14159265358979323846;

static double now_s(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* The spheres: @n x @n of radius 0.4 a unit apart, at heights 6 .. 7 over the floor z = 10. */
struct field {
	float *P;
	uint32_t *quads, *object;
	uint32_t npoints, nquads;
};

static bool make_field(struct field *f, int n)
{
	const uint32_t nu = 65, nv = 33;
	f->npoints = (uint32_t)(n * n) * nu * nv;
	f->nquads = (uint32_t)(n * n) * (nu - 1) * (nv - 1);
	f->P = malloc(sizeof(float) * 3 * f->npoints);
	f->quads = malloc(sizeof(uint32_t) * 4 * f->nquads);
	f->object = malloc(sizeof(uint32_t) * f->nquads);
	if (!f->P || !f->quads || !f->object)
		return false;
	uint32_t p = 0, q = 0;
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double c[3] = { -0.5 * (n - 1) + i, -0.5 * (n - 1) + j, 6 + 0.5 * ((i + j) % 3) };
			uint32_t base = p;
			for (uint32_t b = 0; b < nv; b++)
				for (uint32_t a = 0; a < nu; a++, p++) {
					double phi = 2 * PI * a / (nu - 1), th = PI * b / (nv - 1);
					f->P[3 * p] = (float)(c[0] + 0.4 * sin(th) * cos(phi));
					f->P[3 * p + 1] = (float)(c[1] + 0.4 * sin(th) * sin(phi));
					f->P[3 * p + 2] = (float)(c[2] + 0.4 * cos(th));
				}
			for (uint32_t b = 0; b + 1 < nv; b++)
				for (uint32_t a = 0; a + 1 < nu; a++, q++) {
					uint32_t k = base + b * nu + a;
					uint32_t *v = f->quads + 4 * (size_t)q;
					v[0] = k;
					v[1] = k + 1;
					v[2] = k + 1 + nu;
					v[3] = k + nu;
					f->object[q] = (uint32_t)(j * n + i);
				}
		}
	return true;
}

struct job {
	RTCScene scene;
	const float *org, *dir;
	uint32_t first, last;
	uint8_t *blocked;
};

static void *trace_slice(void *arg)
{
	struct job *j = arg;
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	for (uint32_t i = j->first; i < j->last; i++) {
		struct RTCRay r = {
			.org_x = j->org[3 * (size_t)i], .org_y = j->org[3 * (size_t)i + 1],
			.org_z = j->org[3 * (size_t)i + 2], .tnear = 0.0f,
			.dir_x = j->dir[3 * (size_t)i], .dir_y = j->dir[3 * (size_t)i + 1],
			.dir_z = j->dir[3 * (size_t)i + 2], .time = 0.0f, .tfar = 1.0f,
			.mask = 0xffffffffu, .id = 0, .flags = 0,
		};
		rtcOccluded1(j->scene, &ictx, &r);
		j->blocked[i] = r.tfar < 0.0f;
	}
	return NULL;
}

bool bench_rays(struct gpu_ctx *ctx, bool quick, uint32_t side, uint32_t threads,
		struct bench_rays *out, char *err, size_t errlen)
{
	memset(out, 0, sizeof(*out));
	struct field f = { 0 };
	uint32_t n = side * side;
	float *org = malloc(sizeof(float) * 3 * (size_t)n), *dir = malloc(sizeof(float) * 3 * (size_t)n);
	float *tmax = malloc(sizeof(float) * (size_t)n), *trans = malloc(sizeof(float) * (size_t)n);
	uint8_t *blocked = malloc((size_t)n);
	RTCDevice dev = NULL;
	RTCScene scene = NULL;
	struct gpu_shadow_geometry *g = NULL;
	bool ok = false;
	if (!make_field(&f, quick ? 5 : 10) || !org || !dir || !tmax || !trans || !blocked) {
		snprintf(err, errlen, "out of memory");
		goto done;
	}
	const double light[3] = { 3, 2, -5 }, half = quick ? 3.5 : 6;
	for (uint32_t y = 0; y < side; y++)
		for (uint32_t x = 0; x < side; x++) {
			size_t i = (size_t)y * side + x;
			double p[3] = { -half + 2 * half * (x + 0.5) / side,
					-half + 2 * half * (y + 0.5) / side, 10 };
			for (int k = 0; k < 3; k++) {
				org[3 * i + (size_t)k] = (float)p[k];
				dir[3 * i + (size_t)k] = (float)(light[k] - p[k]);
			}
			tmax[i] = 1;
		}
	out->triangles = 2 * f.nquads;
	out->rays = n;
	out->threads = threads ? threads : 1;

	/* Embree: the triangles the GPU traces, (v0, v1, v2) and (v0, v2, v3) */
	double t0 = now_s();
	dev = rtcNewDevice(NULL);
	scene = dev ? rtcNewScene(dev) : NULL;
	RTCGeometry geo = scene ? rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE) : NULL;
	float *vb = geo ? rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0,
						  RTC_FORMAT_FLOAT3, 3 * sizeof(float),
						  f.npoints) : NULL;
	uint32_t *ib = geo ? rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0,
						     RTC_FORMAT_UINT3, 3 * sizeof(uint32_t),
						     2 * (size_t)f.nquads) : NULL;
	if (!vb || !ib) {
		snprintf(err, errlen, "Embree cannot start (error %d)",
			 dev ? (int)rtcGetDeviceError(dev) : -1);
		if (geo)
			rtcReleaseGeometry(geo);
		goto done;
	}
	memcpy(vb, f.P, sizeof(float) * 3 * f.npoints);
	for (uint32_t q = 0; q < f.nquads; q++) {
		const uint32_t *v = f.quads + 4 * (size_t)q;
		uint32_t *t = ib + 6 * (size_t)q;
		t[0] = v[0], t[1] = v[1], t[2] = v[2];
		t[3] = v[0], t[4] = v[2], t[5] = v[3];
	}
	rtcCommitGeometry(geo);
	rtcAttachGeometry(scene, geo);
	rtcReleaseGeometry(geo);
	rtcCommitScene(scene);
	out->embree_build_s = now_s() - t0;

	struct job jobs[64];
	pthread_t tid[64];
	uint32_t nt = out->threads > 64 ? 64 : out->threads;
	t0 = now_s();
	for (uint32_t k = 0; k < nt; k++) {
		jobs[k] = (struct job){ scene, org, dir, (uint32_t)((uint64_t)n * k / nt),
					(uint32_t)((uint64_t)n * (k + 1) / nt), blocked };
		if (pthread_create(&tid[k], NULL, trace_slice, &jobs[k]) != 0) {
			trace_slice(&jobs[k]);
			tid[k] = 0;
		}
	}
	for (uint32_t k = 0; k < nt; k++)
		if (tid[k])
			pthread_join(tid[k], NULL);
	out->embree_s = now_s() - t0;
	out->embree_rays_per_s = out->embree_s > 0 ? n / out->embree_s : 0;
	for (uint32_t i = 0; i < n; i++)
		out->occluded += blocked[i];

	if (ctx) {
		g = gpu_shadow_geometry_create(ctx, f.P, f.npoints, f.quads, f.object, NULL,
					       f.nquads, err, errlen);
		if (!g)
			goto done;
		t0 = now_s();
		if (!gpu_shadow_bvh_build(g, err, errlen))
			goto done;
		out->gpu_build_s = now_s() - t0;
		gpu_shadow_bvh_stats(g, NULL, NULL, &out->gpu_bytes);
		/* the kernel is compiled on the first call: time the second */
		if (!gpu_shadow_bvh_trace(ctx, g, org, dir, tmax, n < 4096 ? n : 4096, NULL, 0,
					  trans)) {
			snprintf(err, errlen, "the GPU's shadow kernel failed");
			goto done;
		}
		t0 = now_s();
		if (!gpu_shadow_bvh_trace(ctx, g, org, dir, tmax, n, NULL, 0, trans)) {
			snprintf(err, errlen, "the GPU's shadow kernel failed");
			goto done;
		}
		out->gpu_s = now_s() - t0;
		out->gpu_rays_per_s = out->gpu_s > 0 ? n / out->gpu_s : 0;
		for (uint32_t i = 0; i < n; i++)
			out->disagree += (trans[i] < 0.5f) != (blocked[i] != 0);
	}
	ok = true;
done:
	gpu_shadow_geometry_destroy(g);
	if (scene)
		rtcReleaseScene(scene);
	if (dev)
		rtcReleaseDevice(dev);
	free(f.P);
	free(f.quads);
	free(f.object);
	free(org);
	free(dir);
	free(tmax);
	free(trans);
	free(blocked);
	return ok;
}

/*
 * MakeTexture, MakeShadow and the texture system behind texture(),
 * environment(), shadow() and textureinfo().
 *
 * Textures are tiled OpenEXR mip-maps (exr.c writes them); a plain image
 * used as a texture gets its pyramid built when it is loaded. Loaded maps
 * are kept whole, as floats, and never change after loading, so lookups
 * read them without locks; only the cache of names takes a mutex.
 *
 * Conventions:
 *  - (s, t) = (0, 0) is the top left corner of the image, (1, 1) the bottom
 *    right; texel (i, j) covers [i, i+1]/width x [j, j+1]/height.
 *  - Channels are reordered when a map is loaded so that channel 0, 1, 2, 3
 *    are R, G, B, A whatever the file's (alphabetical) order: names sort by
 *    layer ("diffuse." prefix), then R, G, B, A, then the rest by name.
 *  - environment(): latitude-longitude maps as RiMakeLatLongEnvironment
 *    defines them, +z up: direction (x, y, z) has longitude atan2(y, x)
 *    (s = longitude / 2pi, 0 at the left) and latitude asin(z) (t = 0 at
 *    the north pole +z, 1 at the south pole).
 *  - environment() on a cube map (RiMakeCubeFaceEnvironment): the six
 *    faces stacked top to bottom in the order px nx py ny pz nz, as
 *    OpenEXR's "envmap" cube layout has them, each face a picture as a
 *    left-handed camera at the origin renders it looking along the face's
 *    axis with the map's "fov" (see dir_to_cube).
 *  - shadow(): the map's worldToNDC takes world points to RenderMan NDC
 *    ((0,0) top left, (1,1) bottom right, after the homogeneous divide), its
 *    worldToCamera to the light's camera space, where "Z" is the depth z.
 *    Map depths <= 0 (or not finite) are empty: nothing there casts shadow.
 */
#include "deepshadow.h"
#include "exr_internal.h"
#include "lighthost.h"
#include "mathlib.h"
#include "noise.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PI 3.14159265358979323846
/* Most samples per axis in one filtered texture lookup, and the anisotropy. */
#define MAX_AXIS_SAMPLES 16
#define MAX_ANISO 8.0
/* Shadow samples are capped at this many. */
#define MAX_SHADOW_SAMPLES 1024
#define DEFAULT_SHADOW_BIAS 0.01f
/* Texture values beyond this are clamped when loaded, so sums stay finite. */
#define MAX_TEXEL 1e30f
/* Region sizes (in s, t units) are capped here: bigger means "everything". */
#define MAX_REGION 1e6

enum wrap { WRAP_BLACK, WRAP_CLAMP, WRAP_PERIODIC, WRAP_MIRROR };

/* ------------------------------------------------------------------------ */
/* Mip-map pyramids                                                          */

static uint32_t level_count(uint32_t w, uint32_t h)
{
	uint32_t m = w > h ? w : h, n = 1;
	while (m > 1) {
		m >>= 1;
		n++;
	}
	return n;
}

/*
 * Box-filter @src (n pixels, @step floats apart) to @dst (dn pixels): pixel
 * i covers source [i r, (i+1) r) with r = n / dn, partly covered pixels
 * weighted by their coverage. For even sizes this is the plain average of
 * pairs; for odd ones each destination pixel takes a little more than two
 * source pixels, so nothing is dropped and the mean is kept.
 */
static void box_1d(const float *src, uint32_t n, size_t step, float *dst, uint32_t dn,
		   size_t dstep, uint32_t nch)
{
	double r = (double)n / dn;
	for (uint32_t i = 0; i < dn; i++) {
		double a = i * r, b = (i + 1) * r;
		uint32_t k0 = (uint32_t)floor(a), k1 = (uint32_t)ceil(b);
		if (k1 > n)
			k1 = n;
		for (uint32_t c = 0; c < nch; c++) {
			double sum = 0.0;
			for (uint32_t k = k0; k < k1; k++) {
				double lo = k > a ? k : a, hi = k + 1 < b ? k + 1 : b;
				sum += (hi - lo) * src[k * step + c];
			}
			dst[i * dstep + c] = (float)(sum / r);
		}
	}
}

/* @dst = @src halved (sizes rounded down, at least 1), by box filtering. */
static bool downsample(const struct reyes_image *src, struct reyes_image *dst)
{
	uint32_t w = src->width, h = src->height, nch = src->nchannels;
	uint32_t dw = w > 1 ? w / 2 : 1, dh = h > 1 ? h / 2 : 1;
	if (!reyes_image_init(dst, dw, dh, nch, src->channel_names))
		return false;
	float *tmp = malloc((size_t)dw * h * nch * sizeof(float));
	if (!tmp) {
		reyes_image_finish(dst);
		return false;
	}
	for (uint32_t y = 0; y < h; y++)
		box_1d(src->data + (size_t)y * w * nch, w, nch, tmp + (size_t)y * dw * nch, dw, nch,
		       nch);
	for (uint32_t x = 0; x < dw; x++)
		box_1d(tmp + (size_t)x * nch, h, (size_t)dw * nch, dst->data + (size_t)x * nch, dh,
		       (size_t)dw * nch, nch);
	free(tmp);
	return true;
}

/* One level of a pyramid from the one above it; false leaves @dst unset. */
typedef bool (*halve_fn)(const struct reyes_image *src, struct reyes_image *dst);

/*
 * Replace f->levels (one level) by the full pyramid @halve builds from it.
 * Level 0 is moved, not copied.
 */
static bool pyramid(struct reyes_exr_file *f, halve_fn halve)
{
	uint32_t n = level_count(f->levels[0].width, f->levels[0].height);
	struct reyes_image *lv = calloc(n, sizeof(*lv));
	if (!lv)
		return false;
	lv[0] = f->levels[0];
	free(f->levels);
	f->levels = lv;
	f->nlevels = 1;
	for (uint32_t l = 1; l < n; l++) {
		if (!halve(&lv[l - 1], &lv[l]))
			return false;
		f->nlevels = l + 1;
	}
	return true;
}

static bool build_pyramid(struct reyes_exr_file *f)
{
	return pyramid(f, downsample);
}

/* ------------------------------------------------------------------------ */
/* MakeTexture, MakeShadow                                                   */

static bool parse_wrap(const char *s, size_t len, enum wrap *w)
{
	static const struct {
		const char *name;
		enum wrap w;
	} modes[] = {
		{ "black", WRAP_BLACK }, { "clamp", WRAP_CLAMP },
		{ "periodic", WRAP_PERIODIC }, { "mirror", WRAP_MIRROR },
	};
	for (size_t k = 0; k < sizeof(modes) / sizeof(modes[0]); k++) {
		if (strlen(modes[k].name) == len && !strncmp(s, modes[k].name, len)) {
			*w = modes[k].w;
			return true;
		}
	}
	return false;
}

bool reyes_make_texture(const char *in, const char *out, const char *swrap, const char *twrap,
			const char *filter, float swidth, float twidth, FILE *diag)
{
	FILE *d = diag ? diag : stderr;
	const char *oname = out && out[0] ? out : "(no name)";
	if (!swrap || !swrap[0])
		swrap = "black";
	if (!twrap || !twrap[0])
		twrap = "black";
	enum wrap w;
	const char *bad = !parse_wrap(swrap, strlen(swrap), &w) ? swrap :
			  !parse_wrap(twrap, strlen(twrap), &w) ? twrap : NULL;
	if (bad) {
		fprintf(d, "%s: error: unknown wrap mode '%s' (periodic, clamp or black)\n", oname,
			bad);
		return false;
	}
	struct reyes_exr_file f;
	if (!reyes_exr_read(in, false, &f, diag))
		return false;
	bool ok = build_pyramid(&f);
	if (!ok) {
		fprintf(d, "%s: error: out of memory making the texture\n", oname);
	} else {
		char wrapmodes[64], params[160];
		snprintf(wrapmodes, sizeof(wrapmodes), "%s,%s", swrap, twrap);
		snprintf(params, sizeof(params), "filter=%s swidth=%g twidth=%g",
			 filter && filter[0] ? filter : "box", (double)sl_finite(swidth),
			 (double)sl_finite(twidth));
		const char *attrs[] = { "maketexture", params };
		struct reyes_exr_write_opts o = {
			.half = f.half, .mipmap = true, .wrapmodes = wrapmodes,
			.strattrs = attrs, .nstrattrs = 1,
		};
		ok = reyes_exr_write(out, f.levels, f.nlevels, &o, diag);
	}
	reyes_exr_file_finish(&f);
	return ok;
}

/* Face f of a cube map level: face size, 0 when the level is too small for six. */
static uint32_t cube_face_size(const struct reyes_image *lv)
{
	if (lv->height < 6)
		return 0;
	return lv->width < lv->height / 6 ? lv->width : lv->height / 6;
}

/*
 * A level of a cube map's pyramid (the six faces stacked): each face halved
 * on its own, so that no filter reaches across into the next face of the
 * stack. Levels too small to hold six faces are plain halvings (no lookup
 * reads them; they make the file a whole mip-map).
 */
static bool cube_halve(const struct reyes_image *src, struct reyes_image *dst)
{
	uint32_t sf = cube_face_size(src), w = src->width, h = src->height;
	uint32_t dw = w > 1 ? w / 2 : 1, dh = h > 1 ? h / 2 : 1, nch = src->nchannels;
	if (sf < 2 || dh < 6)
		return downsample(src, dst);
	if (!reyes_image_init(dst, dw, dh, nch, src->channel_names))
		return false;
	uint32_t df = cube_face_size(dst);
	for (uint32_t face = 0; face < 6; face++) {
		struct reyes_image a, b;
		bool ok = reyes_image_init(&a, sf, sf, nch, src->channel_names);
		if (ok) {
			for (uint32_t y = 0; y < sf; y++)
				memcpy(a.data + (size_t)y * sf * nch,
				       src->data + ((size_t)(face * sf + y) * w) * nch,
				       (size_t)sf * nch * sizeof(float));
			ok = downsample(&a, &b);
			reyes_image_finish(&a);
		}
		if (!ok) {
			reyes_image_finish(dst);
			return false;
		}
		uint32_t cw = b.width < df ? b.width : df, ch = b.height < df ? b.height : df;
		for (uint32_t y = 0; y < ch; y++)
			memcpy(dst->data + ((size_t)(face * df + y) * dw) * nch,
			       b.data + (size_t)y * b.width * nch, (size_t)cw * nch * sizeof(float));
		reyes_image_finish(&b);
	}
	return true;
}

static bool cube_pyramid(struct reyes_exr_file *f)
{
	return pyramid(f, cube_halve);
}

static void make_params(char *buf, size_t n, const char *filter, float swidth, float twidth)
{
	snprintf(buf, n, "filter=%s swidth=%g twidth=%g", filter && filter[0] ? filter : "box",
		 (double)sl_finite(swidth), (double)sl_finite(twidth));
}

bool reyes_make_latlong_environment(const char *in, const char *out, const char *filter,
				    float swidth, float twidth, FILE *diag)
{
	FILE *d = diag ? diag : stderr;
	const char *oname = out && out[0] ? out : "(no name)";
	struct reyes_exr_file f;
	if (!reyes_exr_read(in, false, &f, diag))
		return false;
	bool ok = build_pyramid(&f);
	if (!ok) {
		fprintf(d, "%s: error: out of memory making the environment map\n", oname);
	} else {
		char params[160];
		make_params(params, sizeof(params), filter, swidth, twidth);
		const char *attrs[] = { "makelatlongenvironment", params };
		struct reyes_exr_write_opts o = {
			.half = f.half, .mipmap = true, .wrapmodes = "periodic,clamp",
			.strattrs = attrs, .nstrattrs = 1, .envmap = REYES_ENVMAP_LATLONG,
		};
		ok = reyes_exr_write(out, f.levels, f.nlevels, &o, diag);
	}
	reyes_exr_file_finish(&f);
	return ok;
}

bool reyes_make_cube_environment(const char *const faces[6], const char *out, float fov,
				 const char *filter, float swidth, float twidth, FILE *diag)
{
	static const char *const face_names[6] = { "px", "nx", "py", "ny", "pz", "nz" };
	FILE *d = diag ? diag : stderr;
	const char *oname = out && out[0] ? out : "(no name)";
	if (!(fov >= 1.0f && fov < 180.0f)) {
		fprintf(d, "%s: error: cube face field of view %g out of range (1 to 180 degrees)\n",
			oname, (double)fov);
		return false;
	}
	struct reyes_exr_file f[6];
	memset(f, 0, sizeof(f));
	struct reyes_exr_file cube = { 0 };
	bool ok = true;
	for (int k = 0; k < 6 && ok; k++)
		ok = reyes_exr_read(faces[k], false, &f[k], diag);
	const struct reyes_image *f0 = ok ? &f[0].levels[0] : NULL;
	for (int k = 0; k < 6 && ok; k++) {
		const struct reyes_image *im = &f[k].levels[0];
		bool same = im->nchannels == f0->nchannels;
		for (uint32_t c = 0; same && c < im->nchannels; c++)
			same = !strcmp(im->channel_names[c], f0->channel_names[c]);
		if (im->width != im->height || im->width != f0->width) {
			fprintf(d, "%s: error: cube face %s (%s) is %ux%u: the faces must be square "
				"and all of one size (%s is %ux%u)\n", oname, face_names[k], faces[k],
				im->width, im->height, faces[0], f0->width, f0->height);
			ok = false;
		} else if (!same) {
			fprintf(d, "%s: error: cube face %s (%s) has other channels than %s\n", oname,
				face_names[k], faces[k], faces[0]);
			ok = false;
		}
	}
	if (ok && (uint64_t)f0->width * 6 > UINT32_MAX / 2) {
		fprintf(d, "%s: error: cube faces too large\n", oname);
		ok = false;
	}
	if (ok) {
		/* The faces stacked top to bottom in the order px nx py ny pz nz. */
		uint32_t w = f0->width, nch = f0->nchannels;
		cube.levels = calloc(1, sizeof(*cube.levels));
		ok = cube.levels && reyes_image_init(&cube.levels[0], w, 6 * w, nch,
						     f0->channel_names);
		if (ok) {
			cube.nlevels = 1;
			size_t face_floats = (size_t)w * w * nch;
			for (int k = 0; k < 6; k++)
				memcpy(cube.levels[0].data + k * face_floats, f[k].levels[0].data,
				       face_floats * sizeof(float));
			ok = cube_pyramid(&cube);
		}
		if (!ok)
			fprintf(d, "%s: error: out of memory making the environment map\n", oname);
	}
	if (ok) {
		char params[160];
		make_params(params, sizeof(params), filter, swidth, twidth);
		const char *attrs[] = { "makecubefaceenvironment", params };
		bool half = true;
		for (int k = 0; k < 6; k++)
			half = half && f[k].half;
		struct reyes_exr_write_opts o = {
			.half = half, .mipmap = true, .strattrs = attrs, .nstrattrs = 1,
			.envmap = REYES_ENVMAP_CUBE, .fov = fov,
		};
		ok = reyes_exr_write(out, cube.levels, cube.nlevels, &o, diag);
	}
	reyes_exr_file_finish(&cube);
	for (int k = 0; k < 6; k++)
		reyes_exr_file_finish(&f[k]);
	return ok;
}

/* The depth channel: "Z", else the only channel; -1 if neither. */
static int depth_channel(const struct reyes_image *im)
{
	for (uint32_t c = 0; c < im->nchannels; c++)
		if (!strcmp(im->channel_names[c], "Z"))
			return (int)c;
	return im->nchannels == 1 ? 0 : -1;
}

/* MakeShadow of a deep shadow map: checked, and written again as it is. */
static bool make_deep_shadow(const char *in, const char *out, struct reyes_exr_file *f,
			     FILE *diag)
{
	struct reyes_deep_map m;
	if (!reyes_deep_from_image(&f->levels[0], f->deepshadow, in, &m, diag))
		return false;
	reyes_deep_map_finish(&m);
	const char *sa[2] = { "deepshadow", f->deepshadow };
	struct reyes_exr_write_opts o = { .strattrs = sa, .nstrattrs = 1 };
	return reyes_exr_write(out, &f->levels[0], 1, &o, diag);
}

bool reyes_make_shadow(const char *in, const char *out, FILE *diag)
{
	FILE *d = diag ? diag : stderr;
	struct reyes_exr_file df;
	if (!reyes_exr_read(in, false, &df, diag))
		return false;
	if (df.deepshadow[0]) {
		bool ok = make_deep_shadow(in, out, &df, diag);
		reyes_exr_file_finish(&df);
		return ok;
	}
	reyes_exr_file_finish(&df);
	struct reyes_image src;
	if (!reyes_image_read_exr(in, &src, diag))
		return false;
	int zc = depth_channel(&src);
	bool ok = false;
	if (zc < 0 || !src.has_matrices) {
		fprintf(d, "%s: error: not a depth map with camera matrices\n", in);
		goto done;
	}
	static const char *const zname[] = { "Z" };
	struct reyes_image z;
	if (!reyes_image_init(&z, src.width, src.height, 1, zname)) {
		fprintf(d, "%s: error: out of memory\n", in);
		goto done;
	}
	size_t n = (size_t)src.width * src.height;
	for (size_t k = 0; k < n; k++) {
		float v = src.data[k * src.nchannels + (size_t)zc];
		/* Infinitely far (or undefined) is as far as can be written. */
		z.data[k] = isfinite(v) ? v : FLT_MAX;
	}
	z.has_matrices = true;
	memcpy(z.world_to_camera, src.world_to_camera, sizeof(z.world_to_camera));
	memcpy(z.world_to_ndc, src.world_to_ndc, sizeof(z.world_to_ndc));
	ok = reyes_image_write_exr(out, &z, false, diag);
	reyes_image_finish(&z);
done:
	reyes_image_finish(&src);
	return ok;
}

/* ------------------------------------------------------------------------ */
/* The cache                                                                 */

struct tex {
	struct tex *next;            /* hash chain */
	char *name;                  /* as looked up */
	bool ok;                     /* loaded; else every lookup fails */
	struct reyes_exr_file f;     /* levels (channels reordered), attributes */
	uint32_t nch;
	enum wrap swrap, twrap;
	int zchan;                   /* depth channel, -1 if none */
	bool has_matrices;
	float world_to_camera[16], world_to_ndc[16];
	bool is_deep;                /* a deep shadow map: shadow() reads deep */
	struct reyes_deep_map deep;
};

#define NBUCKETS 256

struct reyes_texsys {
	pthread_mutex_t lock;
	char *searchpath;            /* NULL: the current directory */
	float camera_to_world[16];
	FILE *diag;
	struct tex *buckets[NBUCKETS];
};

struct reyes_texsys *reyes_texsys_create(const char *searchpath,
					 const float camera_to_world[16], FILE *diag)
{
	struct reyes_texsys *ts = calloc(1, sizeof(*ts));
	if (!ts)
		return NULL;
	if (searchpath && !(ts->searchpath = strdup(searchpath))) {
		free(ts);
		return NULL;
	}
	if (pthread_mutex_init(&ts->lock, NULL) != 0) {
		free(ts->searchpath);
		free(ts);
		return NULL;
	}
	if (camera_to_world)
		memcpy(ts->camera_to_world, camera_to_world, sizeof(ts->camera_to_world));
	else
		sl_m44_identity(ts->camera_to_world);
	ts->diag = diag;
	return ts;
}

void reyes_texsys_destroy(struct reyes_texsys *ts)
{
	if (!ts)
		return;
	for (int b = 0; b < NBUCKETS; b++) {
		struct tex *t = ts->buckets[b];
		while (t) {
			struct tex *next = t->next;
			reyes_exr_file_finish(&t->f);
			reyes_deep_map_finish(&t->deep);
			free(t->name);
			free(t);
			t = next;
		}
	}
	pthread_mutex_destroy(&ts->lock);
	free(ts->searchpath);
	free(ts);
}

static uint32_t hash_name(const char *s)
{
	uint32_t h = 2166136261u;
	for (; *s; s++)
		h = (h ^ (uint8_t)*s) * 16777619u;
	return h;
}

/* Sort key of a channel name: layer, then R, G, B, A, then the rest. */
static int channel_rank(const char *name, const char **layer_end)
{
	const char *dot = strrchr(name, '.');
	const char *base = dot ? dot + 1 : name;
	*layer_end = dot ? dot : name;
	static const char *const rgba[] = { "R", "G", "B", "A" };
	for (int k = 0; k < 4; k++)
		if (!strcmp(base, rgba[k]))
			return k;
	return 4;
}

static int channel_cmp(const char *a, const char *b)
{
	const char *ea, *eb;
	int ra = channel_rank(a, &ea), rb = channel_rank(b, &eb);
	size_t la = (size_t)(ea - a), lb = (size_t)(eb - b);
	int c = strncmp(a, b, la < lb ? la : lb);
	if (c == 0 && la != lb)
		c = la < lb ? -1 : 1;
	if (c != 0)
		return c;
	if (ra != rb)
		return ra < rb ? -1 : 1;
	return strcmp(a, b);
}

/* Put every level's channels in channel_cmp() order; sanitize values. */
static bool reorder_channels(struct reyes_exr_file *f)
{
	uint32_t nch = f->levels[0].nchannels;
	uint32_t *perm = malloc(nch * sizeof(uint32_t));
	float *px = malloc(nch * sizeof(float));
	const char **names = malloc(nch * sizeof(char *));
	if (!perm || !px || !names) {
		free(perm);
		free(px);
		free(names);
		return false;
	}
	const char *const *cn = f->levels[0].channel_names;
	for (uint32_t c = 0; c < nch; c++) {
		uint32_t k = c;
		while (k > 0 && channel_cmp(cn[perm[k - 1]], cn[c]) > 0) {
			perm[k] = perm[k - 1];
			k--;
		}
		perm[k] = c;
	}
	for (uint32_t l = 0; l < f->nlevels; l++) {
		struct reyes_image *im = &f->levels[l];
		size_t n = (size_t)im->width * im->height;
		for (size_t p = 0; p < n; p++) {
			float *v = im->data + p * nch;
			for (uint32_t c = 0; c < nch; c++) {
				float x = v[perm[c]];
				px[c] = !isfinite(x) ? 0.0f : sl_clampf(x, -MAX_TEXEL, MAX_TEXEL);
			}
			memcpy(v, px, nch * sizeof(float));
		}
		for (uint32_t c = 0; c < nch; c++)
			names[c] = im->channel_names[perm[c]];
		memcpy((void *)im->channel_names, names, nch * sizeof(char *));
	}
	free(perm);
	free(px);
	free(names);
	return true;
}

/* Find @name along the search path; the first readable file wins. */
static char *find_file(const struct reyes_texsys *ts, const char *name)
{
	if (name[0] == '/' || !ts->searchpath)
		return access(name, R_OK) == 0 ? strdup(name) : NULL;
	const char *p = ts->searchpath;
	size_t nlen = strlen(name);
	for (;;) {
		const char *end = strchr(p, ':');
		size_t dlen = end ? (size_t)(end - p) : strlen(p);
		bool skip = dlen == 1 && (p[0] == '&' || p[0] == '@');
		if (!skip) {
			char *path = malloc(dlen + nlen + 3);
			if (!path)
				return NULL;
			if (dlen == 0)
				memcpy(path, name, nlen + 1);
			else
				snprintf(path, dlen + nlen + 3, "%.*s/%s", (int)dlen, p, name);
			if (access(path, R_OK) == 0)
				return path;
			free(path);
		}
		if (!end)
			break;
		p = end + 1;
	}
	/* Not on the path: the name as given, relative to the current directory. */
	return access(name, R_OK) == 0 ? strdup(name) : NULL;
}

/* Load a map into @t (t->ok tells whether it worked). */
static void load(const struct reyes_texsys *ts, struct tex *t)
{
	char *path = find_file(ts, t->name);
	if (!path)
		return;
	struct reyes_exr_file *f = &t->f;
	bool ok = reyes_exr_read(path, true, f, ts->diag);
	/* A deep shadow map: its functions, checked; the image stays as read. */
	if (ok && f->deepshadow[0]) {
		ok = reyes_deep_from_image(&f->levels[0], f->deepshadow, path, &t->deep,
					   ts->diag);
		if (!ok)
			reyes_exr_file_finish(f);
	}
	free(path);
	if (!ok)
		return;
	if (!reorder_channels(f)) {
		reyes_deep_map_finish(&t->deep);
		reyes_exr_file_finish(f);
		return;
	}
	const struct reyes_image *im = &f->levels[0];
	t->nch = im->nchannels;
	t->zchan = depth_channel(im);
	t->has_matrices = im->has_matrices;
	memcpy(t->world_to_camera, im->world_to_camera, sizeof(t->world_to_camera));
	memcpy(t->world_to_ndc, im->world_to_ndc, sizeof(t->world_to_ndc));
	if (t->deep.offsets) {
		t->is_deep = true;
		t->ok = true;
		return;
	}
	/* Wrap modes "swrap,twrap" (one word: both); black when absent, as txmake does. */
	t->swrap = t->twrap = WRAP_BLACK;
	const char *wm = f->wrapmodes, *comma = strchr(wm, ',');
	if (wm[0]) {
		size_t len = comma ? (size_t)(comma - wm) : strlen(wm);
		if (parse_wrap(wm, len, &t->swrap))
			t->twrap = t->swrap;
		if (comma)
			parse_wrap(comma + 1, strlen(comma + 1), &t->twrap);
	}
	/* A depth map only needs its one level; anything else gets a pyramid. */
	bool depth_map = t->has_matrices && t->nch == 1 && t->zchan == 0;
	if (f->cube && cube_face_size(&f->levels[0]) == 0) {
		fprintf(ts->diag ? ts->diag : stderr,
			"%s: error: a cube map %ux%u is too small for six faces\n", t->name,
			f->levels[0].width, f->levels[0].height);
		reyes_exr_file_finish(f);
		return;
	}
	if (f->nlevels == 1 && f->cube && !cube_pyramid(f)) {
		reyes_exr_file_finish(f);
		return;
	}
	if (f->nlevels == 1 && !depth_map && !build_pyramid(f)) {
		reyes_exr_file_finish(f);
		return;
	}
	t->ok = true;
}

/* The cached entry for @name, loading it on first use. NULL only when out of memory. */
static atomic_uint_fast64_t unread_maps;

uint64_t reyes_tex_unread_maps(void)
{
	return (uint64_t)atomic_load(&unread_maps);
}

static const struct tex *get(struct reyes_texsys *ts, const char *name)
{
	if (!ts || !name || !name[0])
		return NULL;
	uint32_t b = hash_name(name) % NBUCKETS;
	pthread_mutex_lock(&ts->lock);
	struct tex *t = ts->buckets[b];
	while (t && strcmp(t->name, name) != 0)
		t = t->next;
	if (!t) {
		t = calloc(1, sizeof(*t));
		if (t && !(t->name = strdup(name))) {
			free(t);
			t = NULL;
		}
		if (t) {
			load(ts, t);
			if (!t->ok)
				atomic_fetch_add(&unread_maps, 1);
			t->next = ts->buckets[b];
			ts->buckets[b] = t;
		}
	}
	pthread_mutex_unlock(&ts->lock);
	return t;
}

/* ------------------------------------------------------------------------ */
/* Filtering                                                                 */

/* Bring a coordinate into a range where the wrap mode is cheap and exact. */
static double prewrap(double s, enum wrap w)
{
	switch (w) {
	case WRAP_PERIODIC:
		return s - floor(s);
	case WRAP_MIRROR: {
		double m = s - 2.0 * floor(s * 0.5);
		return m > 1.0 ? 2.0 - m : m;
	}
	default:
		/* Beyond one map away, clamp and black give the same as at -1 or 2. */
		return s < -1.0 ? -1.0 : s > 2.0 ? 2.0 : s;
	}
}

/* Texel index @i on an axis of @n texels, or false for black outside. */
static bool wrap_index(int64_t i, uint32_t n, enum wrap w, uint32_t *out)
{
	if (i >= 0 && i < (int64_t)n) {
		*out = (uint32_t)i;
		return true;
	}
	switch (w) {
	case WRAP_BLACK:
		return false;
	case WRAP_PERIODIC:
		*out = (uint32_t)(((i % (int64_t)n) + (int64_t)n) % (int64_t)n);
		return true;
	default:
		/* Clamp, and mirror (prewrap left at most one texel beyond the edge). */
		*out = i < 0 ? 0 : n - 1;
		return true;
	}
}

/* Accumulate @weight times the bilinear value at (s, t) into acc[0..nc-1]. */
static void bilinear(const struct reyes_image *lv, double s, double t, enum wrap sw,
		     enum wrap tw, uint32_t ch0, uint32_t nc, double weight, double *acc)
{
	double x = prewrap(s, sw) * lv->width - 0.5, y = prewrap(t, tw) * lv->height - 0.5;
	double fx = floor(x), fy = floor(y);
	double ax = x - fx, ay = y - fy;
	int64_t ix = (int64_t)fx, iy = (int64_t)fy;
	uint32_t nch = lv->nchannels;
	for (int dy = 0; dy < 2; dy++) {
		double wy = dy ? ay : 1.0 - ay;
		uint32_t row;
		if (wy == 0.0 || !wrap_index(iy + dy, lv->height, tw, &row))
			continue;
		for (int dx = 0; dx < 2; dx++) {
			double wx = dx ? ax : 1.0 - ax;
			uint32_t col;
			if (wx == 0.0 || !wrap_index(ix + dx, lv->width, sw, &col))
				continue;
			const float *p = lv->data + ((size_t)row * lv->width + col) * nch + ch0;
			double k = weight * wx * wy;
			for (uint32_t c = 0; c < nc; c++)
				acc[c] += k * p[c];
		}
	}
}

/* A filter region in (s, t): centre and full sizes. */
struct region {
	double s, t, ds, dt;
};

/* acc = average of bilinear samples over the region on level @l. */
static void filter_level(const struct reyes_image *lv, const struct region *r, enum wrap sw,
			 enum wrap tw, uint32_t ch0, uint32_t nc, double *acc)
{
	double du = r->ds * lv->width, dv = r->dt * lv->height;
	int nu = du > 1.0 ? (du < MAX_AXIS_SAMPLES ? (int)ceil(du) : MAX_AXIS_SAMPLES) : 1;
	int nv = dv > 1.0 ? (dv < MAX_AXIS_SAMPLES ? (int)ceil(dv) : MAX_AXIS_SAMPLES) : 1;
	double w = 1.0 / (nu * nv);
	for (uint32_t c = 0; c < nc; c++)
		acc[c] = 0.0;
	for (int j = 0; j < nv; j++) {
		double t = r->t + ((j + 0.5) / nv - 0.5) * r->dt;
		for (int i = 0; i < nu; i++) {
			double s = r->s + ((i + 0.5) / nu - 0.5) * r->ds;
			bilinear(lv, s, t, sw, tw, ch0, nc, w, acc);
		}
	}
}

/*
 * Filtered value of channels ch0.. (nc of them, all present) over @r: the
 * mip level from the region's size in level-0 texels (its smaller side, or
 * the larger over MAX_ANISO), trilinear between the two nearest levels.
 */
static void lookup_region(const struct tex *tx, const struct region *r, enum wrap sw,
			  enum wrap tw, uint32_t ch0, uint32_t nc, double res[3])
{
	const struct reyes_image *l0 = &tx->f.levels[0];
	double fs = r->ds * l0->width, ft = r->dt * l0->height;
	double fmin = fs < ft ? fs : ft, fmax = fs < ft ? ft : fs;
	double f = fmin > fmax / MAX_ANISO ? fmin : fmax / MAX_ANISO;
	double lod = f > 1.0 ? log2(f) : 0.0;
	double top = tx->f.nlevels - 1;
	if (lod > top)
		lod = top;
	uint32_t la = (uint32_t)lod;
	double frac = lod - la;
	filter_level(&tx->f.levels[la], r, sw, tw, ch0, nc, res);
	if (frac > 0.0 && la + 1 < tx->f.nlevels) {
		double b[3];
		filter_level(&tx->f.levels[la + 1], r, sw, tw, ch0, nc, b);
		for (uint32_t c = 0; c < nc; c++)
			res[c] += frac * (b[c] - res[c]);
	}
}

static double finite_or0(float v)
{
	return isfinite(v) ? v : 0.0;
}

/* A width or blur option: non-negative, finite and not absurd. */
static double size_opt(float v)
{
	if (!isfinite(v) || v <= 0.0f)
		return 0.0;
	return v < MAX_REGION ? v : MAX_REGION;
}

static double clamp_region(double d)
{
	return d < MAX_REGION ? d : MAX_REGION;
}

/* Write res (avail channels) and the fill for the rest of point @i. */
static void put_result(const struct sl_tex_lookup *q, uint32_t i, const double *res,
		       uint32_t avail)
{
	for (int c = 0; c < q->nchannels; c++) {
		float v = (uint32_t)c < avail ? (float)res[c] : q->fill;
		q->out[(size_t)c * q->stride + i] = sl_finite(v);
	}
}

static bool active(const struct sl_tex_lookup *q, uint32_t i)
{
	return !q->mask || q->mask[i];
}

/* Channels of the lookup present in the map (the rest get the fill). */
static uint32_t available(const struct tex *tx, const struct sl_tex_lookup *q)
{
	if (q->channel < 0 || (uint32_t)q->channel >= tx->nch)
		return 0;
	uint32_t left = tx->nch - (uint32_t)q->channel;
	return left < (uint32_t)q->nchannels ? left : (uint32_t)q->nchannels;
}

static bool lookup_valid(const struct sl_tex_lookup *q)
{
	return q && q->out && (q->nchannels == 1 || q->nchannels == 3);
}

bool reyes_tex_texture(struct reyes_texsys *ts, const struct sl_tex_lookup *q)
{
	if (!lookup_valid(q))
		return false;
	const struct tex *tx = get(ts, q->name);
	if (!tx || !tx->ok)
		return false;
	uint32_t avail = available(tx, q);
	double sw = size_opt(q->swidth), tw = size_opt(q->twidth);
	double sb = size_opt(q->sblur), tb = size_opt(q->tblur);
	double res[3] = { 0.0, 0.0, 0.0 };
	for (uint32_t i = 0; i < q->n; i++) {
		if (!active(q, i))
			continue;
		double smin = DBL_MAX, smax = -DBL_MAX, tmin = DBL_MAX, tmax = -DBL_MAX;
		double ssum = 0.0, tsum = 0.0;
		for (int k = 0; k < 4; k++) {
			double s = finite_or0(q->s[k][i]), t = finite_or0(q->t[k][i]);
			ssum += s;
			tsum += t;
			smin = s < smin ? s : smin;
			smax = s > smax ? s : smax;
			tmin = t < tmin ? t : tmin;
			tmax = t > tmax ? t : tmax;
		}
		struct region r = {
			.s = ssum * 0.25, .t = tsum * 0.25,
			.ds = clamp_region((smax - smin) * sw + sb),
			.dt = clamp_region((tmax - tmin) * tw + tb),
		};
		if (avail)
			lookup_region(tx, &r, tx->swrap, tx->twrap, (uint32_t)q->channel, avail, res);
		put_result(q, i, res, avail);
	}
	return true;
}

/* Direction -> lat-long (s, t); false for a zero vector. */
static bool dir_to_st(const double d[3], double *s, double *t)
{
	double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
	if (!(len > 1e-30) || !isfinite(len))
		return false;
	double z = d[2] / len;
	z = z < -1.0 ? -1.0 : z > 1.0 ? 1.0 : z;
	double lon = atan2(d[1], d[0]);
	*s = lon / (2.0 * PI);
	if (*s < 0.0)
		*s += 1.0;
	*t = acos(z) / PI;
	return true;
}

/*
 * A direction's cube face and its (s, t) on that face's picture, for faces
 * rendered with field of view @fov_deg: px nx py ny pz nz are faces 0..5,
 * each as a left-handed camera at the origin sees it looking along its
 * axis (x right, y up on the picture): up is +y for the four faces around
 * y, -z for py and +z for ny. *grow: how much an angle at the direction
 * stretches on the face, d(s or t)/d(angle). False for a zero vector.
 */
static bool dir_to_cube(const double d[3], double fov_deg, int *face, double *s, double *t,
			double *grow_s, double *grow_t)
{
	double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]);
	double ma, sc, tc;
	if (ax >= ay && ax >= az) {
		*face = d[0] >= 0.0 ? 0 : 1;
		ma = ax, sc = d[0] >= 0.0 ? -d[2] : d[2], tc = -d[1];
	} else if (ay >= az) {
		*face = d[1] >= 0.0 ? 2 : 3;
		ma = ay, sc = d[0], tc = d[1] >= 0.0 ? d[2] : -d[2];
	} else {
		*face = d[2] >= 0.0 ? 4 : 5;
		ma = az, sc = d[2] >= 0.0 ? d[0] : -d[0], tc = -d[1];
	}
	if (!(ma > 1e-30) || !isfinite(ma))
		return false;
	double a = sc / ma, b = tc / ma, k = 0.5 / tan(0.5 * fov_deg * PI / 180.0);
	*s = 0.5 + k * a;
	*t = 0.5 + k * b;
	*grow_s = k * (1.0 + a * a);
	*grow_t = k * (1.0 + b * b);
	return true;
}

/* acc += @weight times the bilinear value at (s, t) of face @face, clamped to the face. */
static void cube_bilinear(const struct reyes_image *lv, uint32_t fw, int face, double s,
			  double t, uint32_t ch0, uint32_t nc, double weight, double *acc)
{
	double x = s * fw - 0.5, y = t * fw - 0.5;
	x = x < 0.0 ? 0.0 : x > fw - 1.0 ? fw - 1.0 : x;
	y = y < 0.0 ? 0.0 : y > fw - 1.0 ? fw - 1.0 : y;
	uint32_t ix = (uint32_t)x, iy = (uint32_t)y;
	double ax = x - ix, ay = y - iy;
	uint32_t nch = lv->nchannels;
	for (uint32_t dy = 0; dy < 2; dy++) {
		double wy = dy ? ay : 1.0 - ay;
		if (wy == 0.0)
			continue;
		uint32_t row = (uint32_t)face * fw + (iy + dy < fw ? iy + dy : fw - 1);
		for (uint32_t dx = 0; dx < 2; dx++) {
			double wx = dx ? ax : 1.0 - ax;
			if (wx == 0.0)
				continue;
			uint32_t col = ix + dx < fw ? ix + dx : fw - 1;
			const float *p = lv->data + ((size_t)row * lv->width + col) * nch + ch0;
			double kk = weight * wx * wy;
			for (uint32_t c = 0; c < nc; c++)
				acc[c] += kk * p[c];
		}
	}
}

/* The average of bilinear samples over region @r of face @face on level @lv. */
static void cube_filter_level(const struct reyes_image *lv, int face, const struct region *r,
			      uint32_t ch0, uint32_t nc, double *acc)
{
	uint32_t fw = cube_face_size(lv);
	double du = r->ds * fw, dv = r->dt * fw;
	int nu = du > 1.0 ? (du < MAX_AXIS_SAMPLES ? (int)ceil(du) : MAX_AXIS_SAMPLES) : 1;
	int nv = dv > 1.0 ? (dv < MAX_AXIS_SAMPLES ? (int)ceil(dv) : MAX_AXIS_SAMPLES) : 1;
	double w = 1.0 / (nu * nv);
	for (uint32_t c = 0; c < nc; c++)
		acc[c] = 0.0;
	for (int j = 0; j < nv; j++) {
		double t = r->t + ((j + 0.5) / nv - 0.5) * r->dt;
		for (int i = 0; i < nu; i++) {
			double s = r->s + ((i + 0.5) / nu - 0.5) * r->ds;
			cube_bilinear(lv, fw, face, s, t, ch0, nc, w, acc);
		}
	}
}

/*
 * The filtered value of a cube map over region @r of face @face, trilinear
 * between the two nearest levels that still hold six faces. The region does
 * not reach into the neighbouring faces: a lookup near an edge filters what
 * its own face has there (with a field of view over 90 degrees, the margin
 * beyond the edge).
 */
static void cube_lookup(const struct tex *tx, int face, const struct region *r, uint32_t ch0,
			uint32_t nc, double res[3])
{
	uint32_t fw0 = cube_face_size(&tx->f.levels[0]), top = 0;
	while (top + 1 < tx->f.nlevels && cube_face_size(&tx->f.levels[top + 1]) > 0)
		top++;
	double fs = r->ds * fw0, ft = r->dt * fw0;
	double fmin = fs < ft ? fs : ft, fmax = fs < ft ? ft : fs;
	double f = fmin > fmax / MAX_ANISO ? fmin : fmax / MAX_ANISO;
	double lod = f > 1.0 ? log2(f) : 0.0;
	if (lod > top)
		lod = top;
	uint32_t la = (uint32_t)lod;
	double frac = lod - la;
	cube_filter_level(&tx->f.levels[la], face, r, ch0, nc, res);
	if (frac > 0.0 && la + 1 <= top) {
		double b[3];
		cube_filter_level(&tx->f.levels[la + 1], face, r, ch0, nc, b);
		for (uint32_t c = 0; c < nc; c++)
			res[c] += frac * (b[c] - res[c]);
	}
}

bool reyes_tex_environment(struct reyes_texsys *ts, const struct sl_tex_lookup *q)
{
	if (!lookup_valid(q))
		return false;
	const struct tex *tx = get(ts, q->name);
	if (!tx || !tx->ok)
		return false;
	uint32_t avail = available(tx, q);
	double sw = size_opt(q->swidth), tw = size_opt(q->twidth);
	double sb = size_opt(q->sblur), tb = size_opt(q->tblur);
	for (uint32_t i = 0; i < q->n; i++) {
		if (!active(q, i))
			continue;
		double res[3] = { 0.0, 0.0, 0.0 };
		/* The centre: the mean of the corners' unit directions. */
		double nk[4][3], c[3] = { 0.0, 0.0, 0.0 };
		int nvalid = 0;
		for (int k = 0; k < 4; k++) {
			double d[3], len2 = 0.0;
			for (int a = 0; a < 3; a++) {
				d[a] = finite_or0(q->dir[k][(size_t)a * q->stride + i]);
				len2 += d[a] * d[a];
			}
			double len = sqrt(len2);
			if (!(len > 1e-30) || !isfinite(len)) {
				nk[k][0] = nk[k][1] = nk[k][2] = 0.0;
				continue;
			}
			for (int a = 0; a < 3; a++) {
				nk[k][a] = d[a] / len;
				c[a] += nk[k][a];
			}
			nvalid++;
		}
		double s, t;
		if (nvalid == 0 || !dir_to_st(c, &s, &t)) {
			put_result(q, i, res, avail);
			continue;
		}
		double clen = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
		double spread = 0.0;
		for (int k = 0; k < 4; k++) {
			double dot = (nk[k][0] * c[0] + nk[k][1] * c[1] + nk[k][2] * c[2]) / clen;
			if (nk[k][0] == 0.0 && nk[k][1] == 0.0 && nk[k][2] == 0.0)
				continue;
			double a = acos(dot < -1.0 ? -1.0 : dot > 1.0 ? 1.0 : dot);
			spread = a > spread ? a : spread;
		}
		if (tx->f.cube) {
			/* The angular diameter 2*spread, stretched as the face stretches it. */
			int face;
			double gs, gt;
			if (dir_to_cube(c, tx->f.fov, &face, &s, &t, &gs, &gt)) {
				struct region r = {
					.s = s, .t = t,
					.ds = clamp_region(2.0 * spread * gs * sw + sb),
					.dt = clamp_region(2.0 * spread * gt * tw + tb),
				};
				if (avail)
					cube_lookup(tx, face, &r, (uint32_t)q->channel, avail, res);
			}
			put_result(q, i, res, avail);
			continue;
		}
		/* The angular diameter 2*spread, in t (pi per map) and in s (2pi at the equator). */
		double sint = sin(t * PI);
		double ds = spread / PI / (sint > 1e-3 ? sint : 1e-3);
		struct region r = {
			.s = s, .t = t,
			.ds = clamp_region((ds < 1.0 ? ds : 1.0) * sw + sb),
			.dt = clamp_region(2.0 * spread / PI * tw + tb),
		};
		if (avail)
			lookup_region(tx, &r, WRAP_PERIODIC, WRAP_CLAMP, (uint32_t)q->channel, avail,
				      res);
		put_result(q, i, res, avail);
	}
	return true;
}

static uint32_t float_bits(double v)
{
	float f = (float)v;
	uint32_t u;
	memcpy(&u, &f, sizeof(u));
	return u;
}

/* One corner of a shadow lookup in the map: (s, t) and light-space depth. */
static bool to_map(const struct reyes_texsys *ts, const struct tex *tx, const float pc[3],
		   double *s, double *t, double *z)
{
	float pw[3], pl[3];
	sl_xform_point(pw, ts->camera_to_world, pc);
	sl_xform_point(pl, tx->world_to_camera, pw);
	*z = pl[2];
	const float *m = tx->world_to_ndc;
	double h[4];
	for (int c = 0; c < 4; c++)
		h[c] = (double)pw[0] * m[c] + (double)pw[1] * m[4 + c] + (double)pw[2] * m[8 + c] +
		       m[12 + c];
	if (!(h[3] > 1e-20) || !isfinite(h[0]) || !isfinite(h[1]))
		return false;
	*s = h[0] / h[3];
	*t = h[1] / h[3];
	return isfinite(*s) && isfinite(*t) && isfinite(*z);
}

bool reyes_tex_shadow(struct reyes_texsys *ts, const struct sl_tex_lookup *q)
{
	if (!lookup_valid(q))
		return false;
	const struct tex *tx = get(ts, q->name);
	if (!tx || !tx->ok)
		return false;
	if (!tx->has_matrices || tx->zchan < 0)
		return false;
	const struct reyes_image *map = &tx->f.levels[0];
	uint32_t W = map->width, H = map->height, nch = map->nchannels, zc = (uint32_t)tx->zchan;
	if (tx->is_deep) {
		W = tx->deep.width;
		H = tx->deep.height;
	}
	float bias = q->bias >= 0.0f && isfinite(q->bias) ? q->bias :
		     tx->f.has_bias ? tx->f.bias : DEFAULT_SHADOW_BIAS;
	double sw = size_opt(q->swidth), tw = size_opt(q->twidth);
	double sb = size_opt(q->sblur), tb = size_opt(q->tblur);
	double nsamp = isfinite(q->samples) ? q->samples : 1.0;
	nsamp = nsamp < 1.0 ? 1.0 : nsamp > MAX_SHADOW_SAMPLES ? MAX_SHADOW_SAMPLES : nsamp;
	int grid = (int)ceil(sqrt(nsamp - 1e-6));
	if (grid < 1)
		grid = 1;
	for (uint32_t i = 0; i < q->n; i++) {
		if (!active(q, i))
			continue;
		double smin = DBL_MAX, smax = -DBL_MAX, tmin = DBL_MAX, tmax = -DBL_MAX, zsum = 0.0;
		int nvalid = 0;
		for (int k = 0; k < 4; k++) {
			float pc[3];
			for (int a = 0; a < 3; a++)
				pc[a] = (float)finite_or0(q->pos[k][(size_t)a * q->stride + i]);
			double s, t, z;
			if (!to_map(ts, tx, pc, &s, &t, &z))
				continue;
			smin = s < smin ? s : smin;
			smax = s > smax ? s : smax;
			tmin = t < tmin ? t : tmin;
			tmax = t > tmax ? t : tmax;
			zsum += z;
			nvalid++;
		}
		double frac = 0.0;
		double z = nvalid ? zsum / nvalid : 0.0;
		/* Behind the light, or not projectable: lit. */
		if (nvalid > 0 && z > 0.0) {
			double sc = 0.5 * (smin + smax), tc = 0.5 * (tmin + tmax);
			double ds = clamp_region((smax - smin) * sw + sb);
			double dt = clamp_region((tmax - tmin) * tw + tb);
			int nu = ds > 0.0 || dt > 0.0 ? grid : 1;
			/* Jitter from where the lookup lands, not from the point's
			 * place in the batch: the same point shadows the same way
			 * in a grid of the renderer and among a shot's samples. */
			uint32_t seed;
			if (q->center)
				seed = sl_hash_mix(
					sl_hash_mix(float_bits(q->center[i])) ^
					sl_hash_mix(float_bits(q->center[q->stride + i]) + 0x9e3779b9u) ^
					sl_hash_mix(float_bits(q->center[2 * (size_t)q->stride + i]) +
						    0x7f4a7c15u));
			else
				seed = sl_hash_mix(sl_hash_mix(float_bits((float)sc)) ^
						   sl_hash_mix(float_bits((float)tc) + 0x9e3779b9u));
			double shadowed = 0.0;
			for (int v = 0; v < nu; v++) {
				for (int u = 0; u < nu; u++) {
					double ju = 0.5, jv = 0.5;
					if (nu > 1) {
						seed = sl_hash_mix(seed + 0x6d2b79f5u);
						ju = (seed >> 8) * (1.0 / 16777216.0);
						seed = sl_hash_mix(seed + 0x6d2b79f5u);
						jv = (seed >> 8) * (1.0 / 16777216.0);
					}
					double s = sc + ((u + ju) / nu - 0.5) * ds;
					double t = tc + ((v + jv) / nu - 0.5) * dt;
					if (!(s >= 0.0 && s < 1.0 && t >= 0.0 && t < 1.0))
						continue;
					uint32_t x = (uint32_t)(s * W), y = (uint32_t)(t * H);
					x = x < W ? x : W - 1;
					y = y < H ? y : H - 1;
					if (tx->is_deep) {
						/* Lokovic & Veach: the light not let through */
						shadowed += 1.0 - reyes_deep_eval(&tx->deep, x, y,
										  z - bias);
						continue;
					}
					float zm = map->data[((size_t)y * W + x) * nch + zc];
					if (zm > 0.0f && z - bias > zm)
						shadowed++;
				}
			}
			frac = shadowed / (nu * nu);
		}
		for (int c = 0; c < q->nchannels; c++)
			q->out[(size_t)c * q->stride + i] = (float)frac;
	}
	return true;
}

bool reyes_tex_shadow_map(struct reyes_texsys *ts, const char *name,
			  struct reyes_shadow_map_info *out)
{
	if (!out)
		return false;
	memset(out, 0, sizeof(*out));
	const struct tex *tx = get(ts, name);
	if (!tx || !tx->ok || !tx->has_matrices || tx->zchan < 0)
		return false;
	const struct reyes_image *map = &tx->f.levels[0];
	out->width = map->width;
	out->height = map->height;
	out->depth = map->data + tx->zchan;
	out->stride = map->nchannels;
	if (tx->is_deep) {
		out->width = tx->deep.width;
		out->height = tx->deep.height;
		out->depth = NULL;
		out->stride = 0;
		out->deep_offsets = tx->deep.offsets;
		out->deep_nodes = tx->deep.zt;
	}
	memcpy(out->world_to_camera, tx->world_to_camera, sizeof(out->world_to_camera));
	memcpy(out->world_to_ndc, tx->world_to_ndc, sizeof(out->world_to_ndc));
	out->bias = tx->f.has_bias ? tx->f.bias : DEFAULT_SHADOW_BIAS;
	memcpy(out->camera_to_world, ts->camera_to_world, sizeof(out->camera_to_world));
	return true;
}

bool reyes_tex_map(struct reyes_texsys *ts, const char *name, struct reyes_tex_map_info *out)
{
	_Static_assert((int)WRAP_BLACK == (int)REYES_WRAP_BLACK &&
		       (int)WRAP_CLAMP == (int)REYES_WRAP_CLAMP &&
		       (int)WRAP_PERIODIC == (int)REYES_WRAP_PERIODIC &&
		       (int)WRAP_MIRROR == (int)REYES_WRAP_MIRROR, "wrap modes in the same order");
	if (!out)
		return false;
	memset(out, 0, sizeof(*out));
	const struct tex *tx = get(ts, name);
	if (!tx || !tx->ok)
		return false;
	out->levels = tx->f.levels;
	out->nlevels = tx->f.nlevels;
	out->nchannels = tx->nch;
	out->swrap = (enum reyes_wrap)tx->swrap;
	out->twrap = (enum reyes_wrap)tx->twrap;
	out->cube = tx->f.cube;
	out->fov = tx->f.fov;
	if (tx->f.cube) {
		/* cube_lookup's top: the last level that holds six faces */
		uint32_t top = 0;
		while (top + 1 < tx->f.nlevels && cube_face_size(&tx->f.levels[top + 1]) > 0)
			top++;
		out->nlevels = top + 1;
	}
	if (out->nlevels > sizeof(out->face_size) / sizeof(out->face_size[0]))
		out->nlevels = sizeof(out->face_size) / sizeof(out->face_size[0]);
	for (uint32_t l = 0; l < out->nlevels; l++)
		out->face_size[l] = tx->f.cube ? cube_face_size(&tx->f.levels[l]) : 0;
	return true;
}

static bool serve_texture(void *user, const struct sl_tex_lookup *q)
{
	return reyes_tex_texture(((struct sl_lighthost *)user)->owner, q);
}

static bool serve_environment(void *user, const struct sl_tex_lookup *q)
{
	return reyes_tex_environment(((struct sl_lighthost *)user)->owner, q);
}

static bool serve_shadow(void *user, const struct sl_tex_lookup *q)
{
	return reyes_tex_shadow(((struct sl_lighthost *)user)->owner, q);
}

void reyes_tex_serve(struct sl_lighthost *lh, struct reyes_texsys *ts)
{
	lh->owner = ts;
	lh->host.texture = serve_texture;
	lh->host.environment = serve_environment;
	lh->host.shadow = serve_shadow;
}

/* ------------------------------------------------------------------------ */
/* textureinfo                                                               */

bool reyes_tex_info(struct reyes_texsys *ts, const char *name, const char *query, int type,
		    int arraylen, float *out, const char **sout)
{
	if (!query)
		return false;
	const struct tex *tx = get(ts, name);
	if (!tx || !tx->ok)
		return false;
	const struct reyes_image *l0 = &tx->f.levels[0];
	if (!strcmp(query, "resolution")) {
		if (type != SL_TYPE_FLOAT || arraylen != 2 || !out)
			return false;
		/* a deep map's image is taller than the map (deepshadow.h) */
		out[0] = (float)l0->width;
		out[1] = (float)(tx->is_deep ? tx->deep.height : l0->height);
		return true;
	}
	if (!strcmp(query, "channels")) {
		if (type != SL_TYPE_FLOAT || arraylen != 0 || !out)
			return false;
		out[0] = tx->is_deep ? 1.0f : (float)tx->nch;
		return true;
	}
	if (!strcmp(query, "type")) {
		if (type != SL_TYPE_STRING || arraylen != 0 || !sout)
			return false;
		bool depth_map = tx->is_deep || (tx->has_matrices && tx->nch == 1 && tx->zchan == 0);
		sout[0] = depth_map ? "shadow" :
			  tx->f.latlong || tx->f.cube ? "environment" : "texture";
		return true;
	}
	bool view = !strcmp(query, "viewingmatrix");
	if (view || !strcmp(query, "projectionmatrix")) {
		if (type != SL_TYPE_MATRIX || arraylen != 0 || !out || !tx->has_matrices)
			return false;
		memcpy(out, view ? tx->world_to_camera : tx->world_to_ndc, 16 * sizeof(float));
		return true;
	}
	return false;
}

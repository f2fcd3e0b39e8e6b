/*
 * Images, textures and shadow maps: OpenEXR round trips (checked with
 * Debian's exrheader and exrmaketiled when installed), atomic writes,
 * corrupt files, MakeTexture's pyramid, texture() filtering and wrap modes,
 * environment(), shadow() percentage-closer filtering, textureinfo().
 */
#include "test.h"

#include "exr_internal.h"
#include "mathlib.h"
#include "texture.h"

#include <openexr.h>

#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <pthread.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[64];

/* A path in the test's scratch directory (one of a few rotating buffers). */
static const char *tmp_path(const char *name)
{
	static char buf[8][512];
	static int k;
	k = (k + 1) % 8;
	snprintf(buf[k], sizeof(buf[k]), "%s/%s", dir, name);
	return buf[k];
}

static void remove_tree(const char *path)
{
	DIR *d = opendir(path);
	if (!d)
		return;
	struct dirent *e;
	char p[1024];
	while ((e = readdir(d))) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(p, sizeof(p), "%s/%s", path, e->d_name);
		struct stat st;
		if (lstat(p, &st) == 0 && S_ISDIR(st.st_mode)) {
			chmod(p, 0755);
			remove_tree(p);
		} else {
			unlink(p);
		}
	}
	closedir(d);
	rmdir(path);
}

/* Files in @path whose names contain ".tmp.". */
static int count_temps(const char *path)
{
	DIR *d = opendir(path);
	if (!d)
		return -1;
	int n = 0;
	struct dirent *e;
	while ((e = readdir(d)))
		if (strstr(e->d_name, ".tmp."))
			n++;
	closedir(d);
	return n;
}

/* Everything written to a diagnostics stream so far. */
static const char *diag_text(FILE *f)
{
	static char buf[8192];
	fflush(f);
	long end = ftell(f);
	rewind(f);
	size_t n = fread(buf, 1, sizeof(buf) - 1, f);
	buf[n] = 0;
	fseek(f, end, SEEK_SET);
	return buf;
}

static bool tool_exists(const char *path)
{
	return access(path, X_OK) == 0;
}

/* Output of a shell command (stdout and stderr), and its exit status. */
static int run_cmd(const char *cmd, char *out, size_t outsize)
{
	FILE *p = popen(cmd, "r");
	if (!p)
		return -1;
	size_t n = fread(out, 1, outsize - 1, p);
	out[n] = 0;
	return pclose(p);
}

static float half_round(float v)
{
	/* The nearest half of v's order: 11 significant bits. */
	int e;
	float m = frexpf(v, &e);
	return ldexpf(roundf(m * 2048.0f) / 2048.0f, e);
}

static const char *const aov_names[] = { "R", "G", "B", "A", "Z", "diffuse.R" };

/* A 37x23 image with RGBA, Z and an AOV; values depend on pixel and channel. */
static bool make_test_image(struct reyes_image *im)
{
	if (!reyes_image_init(im, 37, 23, 6, aov_names))
		return false;
	for (uint32_t y = 0; y < im->height; y++)
		for (uint32_t x = 0; x < im->width; x++)
			for (uint32_t c = 0; c < 6; c++)
				im->data[((size_t)y * im->width + x) * 6 + c] =
					(float)(x * 0.37 + y * 1.1 + c * 10.0 + 0.1);
	im->has_matrices = true;
	for (int k = 0; k < 16; k++) {
		im->world_to_camera[k] = (float)k + 0.5f;
		im->world_to_ndc[k] = -(float)k * 0.25f;
	}
	return true;
}

static int channel_index(const struct reyes_image *im, const char *name)
{
	for (uint32_t c = 0; c < im->nchannels; c++)
		if (!strcmp(im->channel_names[c], name))
			return (int)c;
	return -1;
}

static void check_round_trip(bool half)
{
	struct reyes_image im, back;
	CHECK(make_test_image(&im));
	const char *path = tmp_path(half ? "rt_half.exr" : "rt_float.exr");
	CHECK(reyes_image_write_exr(path, &im, half, NULL));
	CHECK(reyes_image_read_exr(path, &back, NULL));
	CHECK(back.width == 37 && back.height == 23 && back.nchannels == 6);
	/* The file keeps channels sorted by name. */
	static const char *const sorted[] = { "A", "B", "G", "R", "Z", "diffuse.R" };
	for (uint32_t c = 0; c < 6 && c < back.nchannels; c++)
		CHECK_STR(back.channel_names[c], sorted[c]);
	double maxerr = 0.0, zerr = 0.0;
	for (uint32_t c = 0; c < 6; c++) {
		int bc = channel_index(&back, aov_names[c]);
		CHECK(bc >= 0);
		if (bc < 0 || back.width != 37 || back.height != 23)
			continue;
		for (size_t p = 0; p < 37 * 23; p++) {
			float a = im.data[p * 6 + c], b = back.data[p * 6 + (size_t)bc];
			/* Half keeps 11 significant bits: relative error <= 2^-11. */
			float expect = half && c != 4 ? half_round(a) : a;
			double err = fabs((double)b - expect);
			if (c == 4)
				zerr = err > zerr ? err : zerr;
			else
				maxerr = err > maxerr ? err : maxerr;
		}
	}
	CHECK_NEAR(maxerr, 0.0, half ? 1e-6 : 0.0);
	CHECK_NEAR(zerr, 0.0, 0.0); /* Z is always float */
	CHECK(back.has_matrices);
	for (int k = 0; k < 16; k++) {
		CHECK_NEAR(back.world_to_camera[k], im.world_to_camera[k], 0.0);
		CHECK_NEAR(back.world_to_ndc[k], im.world_to_ndc[k], 0.0);
	}

	/* Independently: exrheader reads the header, exrmaketiled all pixels. */
	char out[8192], cmd[1200];
	if (tool_exists("/usr/bin/exrheader")) {
		snprintf(cmd, sizeof(cmd), "/usr/bin/exrheader '%s' 2>&1", path);
		CHECK(run_cmd(cmd, out, sizeof(out)) == 0);
		CHECK(strstr(out, "worldToCamera (type m44f)") != NULL);
		CHECK(strstr(out, "worldToNDC (type m44f)") != NULL);
		CHECK(strstr(out, "software (type string): \"relight\"") != NULL);
		CHECK(strstr(out, "compression (type compression): zip") != NULL);
		CHECK(strstr(out, "Z, 32-bit floating-point") != NULL);
		CHECK(strstr(out, half ? "R, 16-bit floating-point" : "R, 32-bit floating-point"));
		CHECK(strstr(out, "diffuse.R,") != NULL);
		CHECK(strstr(out, "dataWindow (type box2i): (0 0) - (36 22)") != NULL);
	} else {
		printf("exrheader not installed: header check skipped\n");
	}
	if (tool_exists("/usr/bin/exrmaketiled")) {
		snprintf(cmd, sizeof(cmd), "/usr/bin/exrmaketiled '%s' '%s' 2>&1", path,
			 tmp_path("rt_tiled_copy.exr"));
		CHECK(run_cmd(cmd, out, sizeof(out)) == 0);
	}
	reyes_image_finish(&back);
	reyes_image_finish(&im);
}

static void test_round_trip(void)
{
	check_round_trip(false);
	check_round_trip(true);

	/* Without matrices: none in the file, none read back. */
	struct reyes_image im, back;
	CHECK(reyes_image_init(&im, 3, 2, 4, NULL));
	CHECK_STR(im.channel_names[3], "A");
	const char *path = tmp_path("nomat.exr");
	CHECK(reyes_image_write_exr(path, &im, true, NULL));
	CHECK(reyes_image_read_exr(path, &back, NULL));
	CHECK(!back.has_matrices);
	CHECK(back.width == 3 && back.height == 2);
	reyes_image_finish(&back);
	reyes_image_finish(&im);
}

static void test_nonfinite(void)
{
	static const char *const names[] = { "R", "Z" };
	struct reyes_image im, back;
	CHECK(reyes_image_init(&im, 4, 1, 2, names));
	im.data[0] = NAN;
	im.data[2] = INFINITY;
	im.data[3] = -INFINITY;
	im.data[4] = 1e6f;  /* beyond half: clamped to 65504 */
	im.data[6] = 0.5f;
	FILE *diag = tmpfile();
	const char *path = tmp_path("nonfinite.exr");
	CHECK(reyes_image_write_exr(path, &im, true, diag));
	const char *msg = diag_text(diag);
	CHECK(strstr(msg, "warning: 3 NaN or infinite values written as 0") != NULL);
	CHECK(strstr(msg, "1 values beyond the half-float range clamped") != NULL);
	CHECK(reyes_image_read_exr(path, &back, NULL));
	if (back.nchannels == 2 && back.width == 4) {
		/* Sorted: R then Z. */
		CHECK_NEAR(back.data[0], 0.0, 0.0);
		CHECK_NEAR(back.data[2], 0.0, 0.0);
		CHECK_NEAR(back.data[3], 0.0, 0.0);
		CHECK_NEAR(back.data[4], 65504.0, 0.0);
		CHECK_NEAR(back.data[6], 0.5, 0.0);
	}
	reyes_image_finish(&back);
	reyes_image_finish(&im);
	fclose(diag);
}

static bool same_file(const char *a, const struct reyes_image *im)
{
	struct reyes_image b;
	if (!reyes_image_read_exr(a, &b, NULL))
		return false;
	bool same = b.width == im->width && b.height == im->height && b.nchannels == 1 &&
		    b.data[0] == im->data[0];
	reyes_image_finish(&b);
	return same;
}

static void test_atomic(void)
{
	static const char *const names[] = { "Y" };
	struct reyes_image im, other;
	CHECK(reyes_image_init(&im, 5, 5, 1, names));
	CHECK(reyes_image_init(&other, 7, 3, 1, names));
	im.data[0] = 42.0f;
	other.data[0] = 7.0f;

	/* A temporary name too long for the file system: the old file survives. */
	char longname[256];
	memset(longname, 'a', 250);
	strcpy(longname + 250, ".exr");
	const char *lpath = tmp_path(longname);
	CHECK(reyes_image_write_exr(tmp_path("short.exr"), &im, false, NULL));
	CHECK(rename(tmp_path("short.exr"), lpath) == 0);
	FILE *diag = tmpfile();
	CHECK(!reyes_image_write_exr(lpath, &other, false, diag));
	char expect[600];
	snprintf(expect, sizeof(expect), "%s: error: cannot write: ", lpath);
	CHECK(strstr(diag_text(diag), expect) != NULL);
	CHECK(same_file(lpath, &im));
	CHECK(count_temps(dir) == 0);

	/* A missing directory. */
	const char *missing = tmp_path("no/such/dir.exr");
	CHECK(!reyes_image_write_exr(missing, &im, false, diag));
	snprintf(expect, sizeof(expect), "%s: error: cannot write: ", missing);
	CHECK(strstr(diag_text(diag), expect) != NULL);

	/* An invalid image: nothing is written, the old file stays. */
	struct reyes_image bad = other;
	static const char *const dup[] = { "Y", "Y" };
	struct reyes_image two;
	CHECK(reyes_image_init(&two, 2, 2, 2, dup));
	CHECK(!reyes_image_write_exr(lpath, &two, false, diag));
	CHECK(strstr(diag_text(diag), "channel 'Y' appears twice") != NULL);
	CHECK(same_file(lpath, &im));
	reyes_image_finish(&two);
	(void)bad;

	/* A read-only directory (only meaningful when not root). */
	const char *ro = tmp_path("ro");
	CHECK(mkdir(ro, 0755) == 0);
	char ropath[600];
	snprintf(ropath, sizeof(ropath), "%s/keep.exr", ro);
	CHECK(reyes_image_write_exr(ropath, &im, false, NULL));
	if (geteuid() != 0) {
		CHECK(chmod(ro, 0555) == 0);
		CHECK(!reyes_image_write_exr(ropath, &other, false, diag));
		CHECK(strstr(diag_text(diag), "Permission denied") != NULL);
		CHECK(chmod(ro, 0755) == 0);
		CHECK(same_file(ropath, &im));
		CHECK(count_temps(ro) == 0);
	} else {
		printf("running as root: read-only directory check skipped\n");
	}
	/* A successful overwrite replaces the file and leaves no temporary. */
	CHECK(reyes_image_write_exr(ropath, &other, false, NULL));
	CHECK(same_file(ropath, &other));
	CHECK(count_temps(ro) == 0);

	fclose(diag);
	reyes_image_finish(&im);
	reyes_image_finish(&other);
}

static bool write_bytes(const char *path, const void *data, size_t n)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		return false;
	bool ok = fwrite(data, 1, n, f) == n;
	return fclose(f) == 0 && ok;
}

static size_t read_bytes(const char *path, uint8_t *buf, size_t cap)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	size_t n = fread(buf, 1, cap, f);
	fclose(f);
	return n;
}

static void test_corrupt(void)
{
	FILE *diag = tmpfile();
	struct reyes_image im;
	const char *p;

	p = tmp_path("missing.exr");
	CHECK(!reyes_image_read_exr(p, &im, diag));
	CHECK(strstr(diag_text(diag), "missing.exr: error: cannot read: No such file") != NULL);

	p = tmp_path("empty.exr");
	CHECK(write_bytes(p, "", 0));
	CHECK(!reyes_image_read_exr(p, &im, diag));

	/* Random bytes, with and without the magic number. */
	uint8_t rnd[4096];
	uint32_t x = 12345;
	for (size_t k = 0; k < sizeof(rnd); k++) {
		x = x * 1664525u + 1013904223u;
		rnd[k] = (uint8_t)(x >> 24);
	}
	p = tmp_path("random.exr");
	CHECK(write_bytes(p, rnd, sizeof(rnd)));
	CHECK(!reyes_image_read_exr(p, &im, diag));
	static const uint8_t magic[4] = { 0x76, 0x2f, 0x31, 0x01 };
	memcpy(rnd, magic, 4);
	CHECK(write_bytes(p, rnd, sizeof(rnd)));
	CHECK(!reyes_image_read_exr(p, &im, diag));
	CHECK(strstr(diag_text(diag), "random.exr: error: cannot read: ") != NULL);

	/* Truncations of a valid file (scanline, then tiled): always an error. */
	struct reyes_image src;
	CHECK(make_test_image(&src));
	const char *good = tmp_path("good.exr");
	CHECK(reyes_image_write_exr(good, &src, false, NULL));
	const char *goodtex = tmp_path("good.tex");
	CHECK(reyes_make_texture(good, goodtex, "periodic", "periodic", "box", 1, 1, NULL));
	static uint8_t buf[1 << 16];
	const char *files[2] = { good, goodtex };
	for (int f = 0; f < 2; f++) {
		size_t n = read_bytes(files[f], buf, sizeof(buf));
		CHECK(n > 200 && n < sizeof(buf));
		p = tmp_path("trunc.exr");
		size_t cuts[] = { 4, 8, 100, n / 3, n / 2, n - 40, n - 1 };
		for (size_t c = 0; c < sizeof(cuts) / sizeof(cuts[0]); c++) {
			CHECK(write_bytes(p, buf, cuts[c]));
			/* Cutting a texture's last (smallest) levels leaves level 0 whole. */
			bool ok = reyes_image_read_exr(p, &im, diag);
			if (f == 0 || cuts[c] <= 100)
				CHECK(!ok);
			if (ok)
				reyes_image_finish(&im);
			struct reyes_exr_file ef;
			ok = reyes_exr_read(p, true, &ef, diag);
			CHECK(!ok);
			if (ok)
				reyes_exr_file_finish(&ef);
		}
		/* Damaged bytes past the header: an error or some image, never a crash. */
		for (size_t k = n / 2; k < n; k += 97) {
			uint8_t save = buf[k];
			buf[k] ^= 0x5a;
			CHECK(write_bytes(p, buf, n));
			if (reyes_image_read_exr(p, &im, diag))
				reyes_image_finish(&im);
			buf[k] = save;
		}
	}
	reyes_image_finish(&src);
	fclose(diag);
}

/*
 * Write a scanline file with data window @dw and display window @disp through
 * the C API: one channel "Y" = x * 100 + y, as float or as unsigned int.
 */
static bool write_windowed(const char *path, exr_attr_box2i_t dw, exr_attr_box2i_t disp,
			   exr_pixel_type_t type)
{
	exr_context_t ctx;
	exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
	if (exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init) != EXR_ERR_SUCCESS)
		return false;
	int part;
	bool ok = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part) == EXR_ERR_SUCCESS;
	exr_attr_v2f_t swc = { .x = 0.0f, .y = 0.0f };
	ok = ok && exr_initialize_required_attr(ctx, part, &disp, &dw, 1.0f, &swc, 1.0f,
						EXR_LINEORDER_INCREASING_Y,
						EXR_COMPRESSION_NONE) == EXR_ERR_SUCCESS;
	ok = ok && exr_add_channel(ctx, part, "Y", type, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1) ==
			   EXR_ERR_SUCCESS;
	ok = ok && exr_write_header(ctx) == EXR_ERR_SUCCESS;
	int w = dw.max.x - dw.min.x + 1;
	float row[64];
	uint32_t urow[64];
	exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
	bool started = false;
	for (int y = dw.min.y; ok && y <= dw.max.y; y++) {
		for (int x = 0; x < w; x++) {
			row[x] = (float)((dw.min.x + x) * 100 + y);
			urow[x] = (uint32_t)((dw.min.x + x) * 100 + y);
		}
		exr_chunk_info_t ci;
		ok = exr_write_scanline_chunk_info(ctx, part, y, &ci) == EXR_ERR_SUCCESS;
		ok = ok && (started ? exr_encoding_update(ctx, part, &ci, &enc)
				    : exr_encoding_initialize(ctx, part, &ci, &enc)) == EXR_ERR_SUCCESS;
		if (!ok)
			break;
		enc.channels[0].user_bytes_per_element = 4;
		enc.channels[0].user_data_type = (uint16_t)type;
		enc.channels[0].user_pixel_stride = 4;
		enc.channels[0].user_line_stride = w * 4;
		enc.channels[0].encode_from_ptr =
			type == EXR_PIXEL_UINT ? (const uint8_t *)urow : (const uint8_t *)row;
		if (!started)
			ok = exr_encoding_choose_default_routines(ctx, part, &enc) == EXR_ERR_SUCCESS;
		started = true;
		ok = ok && exr_encoding_run(ctx, part, &enc) == EXR_ERR_SUCCESS;
	}
	if (started)
		exr_encoding_destroy(ctx, &enc);
	return exr_finish(&ctx) == EXR_ERR_SUCCESS && ok;
}

static void test_windows(void)
{
	struct reyes_image im;
	/* Data window (2,1)-(5,3) inside display (0,0)-(7,5): an 8x6 image, zero outside. */
	exr_attr_box2i_t dw = { .min = { .x = 2, .y = 1 }, .max = { .x = 5, .y = 3 } };
	exr_attr_box2i_t disp = { .min = { .x = 0, .y = 0 }, .max = { .x = 7, .y = 5 } };
	const char *p = tmp_path("window_in.exr");
	CHECK(write_windowed(p, dw, disp, EXR_PIXEL_FLOAT));
	CHECK(reyes_image_read_exr(p, &im, NULL));
	CHECK(im.width == 8 && im.height == 6 && im.nchannels == 1);
	if (im.width == 8 && im.height == 6) {
		double outside = 0.0;
		for (uint32_t y = 0; y < 6; y++)
			for (uint32_t x = 0; x < 8; x++)
				if (x < 2 || x > 5 || y < 1 || y > 3)
					outside += fabs(im.data[y * 8 + x]);
		CHECK_NEAR(outside, 0.0, 0.0);
		CHECK_NEAR(im.data[1 * 8 + 2], 201.0, 0.0);
		CHECK_NEAR(im.data[3 * 8 + 5], 503.0, 0.0);
	}
	reyes_image_finish(&im);

	/* Data window sticking out of the display window: the image is the data window. */
	exr_attr_box2i_t dw2 = { .min = { .x = -3, .y = 2 }, .max = { .x = 4, .y = 4 } };
	p = tmp_path("window_out.exr");
	CHECK(write_windowed(p, dw2, disp, EXR_PIXEL_FLOAT));
	CHECK(reyes_image_read_exr(p, &im, NULL));
	CHECK(im.width == 8 && im.height == 3);
	if (im.width == 8 && im.height == 3) {
		CHECK_NEAR(im.data[0], -300.0 + 2.0, 0.0);
		CHECK_NEAR(im.data[2 * 8 + 7], 400.0 + 4.0, 0.0);
	}
	reyes_image_finish(&im);

	/* Unsigned int channels read as float. */
	p = tmp_path("uint.exr");
	CHECK(write_windowed(p, dw, dw, EXR_PIXEL_UINT));
	CHECK(reyes_image_read_exr(p, &im, NULL));
	CHECK(im.width == 4 && im.height == 3);
	if (im.width == 4 && im.height == 3) {
		CHECK_NEAR(im.data[0], 201.0, 0.0);
		CHECK_NEAR(im.data[2 * 4 + 3], 503.0, 0.0);
	}
	reyes_image_finish(&im);
}

/* An image of @w x @h with channels R = x + w*y (a gradient), G = checker. */
static void make_gradient(const char *path, uint32_t w, uint32_t h, bool half)
{
	static const char *const names[] = { "R", "G" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, w, h, 2, names));
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++) {
			im.data[(y * w + x) * 2] = (float)(x + w * y);
			im.data[(y * w + x) * 2 + 1] = (float)((x + y) & 1);
		}
	CHECK(reyes_image_write_exr(path, &im, half, NULL));
	reyes_image_finish(&im);
}

static void test_make_texture(void)
{
	const char *src = tmp_path("grad8x4.exr"), *tex = tmp_path("grad8x4.tex");
	make_gradient(src, 8, 4, false);
	CHECK(reyes_make_texture(src, tex, "periodic", "clamp", "gaussian", 2, 2, NULL));
	struct reyes_exr_file f;
	CHECK(reyes_exr_read(tex, true, &f, NULL));
	CHECK(f.nlevels == 4);
	CHECK_STR(f.wrapmodes, "periodic,clamp");
	CHECK(!f.half);
	static const uint32_t sizes[4][2] = { { 8, 4 }, { 4, 2 }, { 2, 1 }, { 1, 1 } };
	for (uint32_t l = 0; l < f.nlevels && l < 4; l++)
		CHECK(f.levels[l].width == sizes[l][0] && f.levels[l].height == sizes[l][1]);
	if (f.nlevels == 4) {
		/* Level 1 pixel (x, y): the mean of level 0's 2x2 block (R channel). */
		const struct reyes_image *l0 = &f.levels[0], *l1 = &f.levels[1];
		int rc = channel_index(l0, "R");
		CHECK(rc >= 0);
		double maxerr = 0.0;
		for (uint32_t y = 0; y < 2 && rc >= 0; y++)
			for (uint32_t x = 0; x < 4; x++) {
				double sum = 0.0;
				for (uint32_t k = 0; k < 4; k++)
					sum += l0->data[((2 * y + k / 2) * 8 + 2 * x + k % 2) * 2 +
							(uint32_t)rc];
				double e = fabs(l1->data[(y * 4 + x) * 2 + (uint32_t)rc] - sum / 4);
				maxerr = e > maxerr ? e : maxerr;
			}
		CHECK_NEAR(maxerr, 0.0, 1e-5);
		/* The top level is the mean: (0..31) -> 15.5; the checker's 0.5. */
		CHECK_NEAR(f.levels[3].data[rc], 15.5, 1e-5);
		CHECK_NEAR(f.levels[3].data[1 - rc], 0.5, 1e-6);
	}
	reyes_exr_file_finish(&f);

	char out[8192], cmd[1200];
	if (tool_exists("/usr/bin/exrheader")) {
		snprintf(cmd, sizeof(cmd), "/usr/bin/exrheader '%s' 2>&1", tex);
		CHECK(run_cmd(cmd, out, sizeof(out)) == 0);
		CHECK(strstr(out, "wrapmodes (type string): \"periodic,clamp\"") != NULL);
		CHECK(strstr(out, "mip-map") != NULL);
		CHECK(strstr(out, "tile size 64 by 64 pixels") != NULL);
		CHECK(strstr(out, "level sizes rounded down") != NULL);
		CHECK(strstr(out, "filter=gaussian swidth=2 twidth=2") != NULL);
	} else {
		printf("exrheader not installed: texture header check skipped\n");
	}

	/* Odd sizes: 5x3 -> 2x1 -> 1x1, the mean kept at every level; half stays half. */
	src = tmp_path("odd.exr");
	tex = tmp_path("odd.tex");
	make_gradient(src, 5, 3, true);
	CHECK(reyes_make_texture(src, tex, "black", "black", "box", 1, 1, NULL));
	CHECK(reyes_exr_read(tex, true, &f, NULL));
	CHECK(f.nlevels == 3);
	CHECK(f.half);
	if (f.nlevels == 3) {
		CHECK(f.levels[1].width == 2 && f.levels[1].height == 1);
		double m1 = (f.levels[1].data[1] + f.levels[1].data[3]) / 2; /* R is channel 1 */
		CHECK_NEAR(m1, 7.0, 7.0 * 1e-3);                       /* mean of 0..14 */
		CHECK_NEAR(f.levels[2].data[1], 7.0, 7.0 * 1e-3);
	}
	reyes_exr_file_finish(&f);

	/*
	 * Several tiles per level and partial edge tiles on every level: 200x100
	 * -> 100x50 -> 50x25 -> 25x12 -> 12x6 -> 6x3 -> 3x1 -> 1x1.
	 */
	src = tmp_path("wide.exr");
	tex = tmp_path("wide.tex");
	make_gradient(src, 200, 100, false);
	CHECK(reyes_make_texture(src, tex, "clamp", "clamp", "box", 1, 1, NULL));
	CHECK(reyes_exr_read(tex, true, &f, NULL));
	CHECK(f.nlevels == 8);
	if (f.nlevels == 8) {
		static const uint32_t wide[8][2] = { { 200, 100 }, { 100, 50 }, { 50, 25 },
						     { 25, 12 }, { 12, 6 }, { 6, 3 }, { 3, 1 },
						     { 1, 1 } };
		bool sizes_ok = true;
		for (uint32_t l = 0; l < 8; l++)
			sizes_ok = sizes_ok && f.levels[l].width == wide[l][0] &&
				   f.levels[l].height == wide[l][1];
		CHECK(sizes_ok);
		/* R is channel 1 (file order G, R). Level 1's last pixel, in an edge tile. */
		const float *l0 = f.levels[0].data, *l1 = f.levels[1].data;
		double block = (l0[(98 * 200 + 198) * 2 + 1] + l0[(98 * 200 + 199) * 2 + 1] +
				l0[(99 * 200 + 198) * 2 + 1] + l0[(99 * 200 + 199) * 2 + 1]) / 4;
		CHECK_NEAR(l1[(49 * 100 + 99) * 2 + 1], block, 1e-3);
		CHECK_NEAR(l1[(49 * 100 + 99) * 2 + 1], 198.5 + 200 * 98.5, 1e-3);
		/* Every level keeps the mean of x + 200 y: 99.5 + 200 * 49.5 = 9999.5. */
		for (uint32_t l = 0; l < 8; l++) {
			const struct reyes_image *lv = &f.levels[l];
			double sum = 0.0;
			for (size_t k = 0; k < (size_t)lv->width * lv->height; k++)
				sum += lv->data[k * 2 + 1];
			CHECK_NEAR(sum / ((double)lv->width * lv->height), 9999.5, 0.01);
		}
	}
	reyes_exr_file_finish(&f);

	/* A tiled mip-map written by the C++ library (edge tiles on levels too) reads. */
	if (tool_exists("/usr/bin/exrmaketiled")) {
		snprintf(cmd, sizeof(cmd), "/usr/bin/exrmaketiled -m -t 64 64 '%s' '%s' 2>&1", src,
			 tmp_path("cxx.tex"));
		CHECK(run_cmd(cmd, out, sizeof(out)) == 0);
		CHECK(reyes_exr_read(tmp_path("cxx.tex"), true, &f, NULL));
		CHECK(f.nlevels == 8);
		if (f.nlevels == 8) {
			CHECK(f.levels[3].width == 25 && f.levels[3].height == 12);
			CHECK_NEAR(f.levels[0].data[(73 * 200 + 155) * 2 + 1], 155 + 200 * 73, 0.0);
			CHECK_NEAR(f.levels[0].data[(99 * 200 + 199) * 2 + 1], 199 + 200 * 99, 0.0);
		}
		reyes_exr_file_finish(&f);
	} else {
		printf("exrmaketiled not installed: C++ mip-map check skipped\n");
	}

	FILE *diag = tmpfile();
	CHECK(!reyes_make_texture(src, tex, "repeat", "clamp", "box", 1, 1, diag));
	CHECK(strstr(diag_text(diag), "unknown wrap mode 'repeat'") != NULL);
	CHECK(!reyes_make_texture(tmp_path("nothere.exr"), tex, "clamp", "clamp", "box", 1, 1, diag));
	CHECK(strstr(diag_text(diag), "nothere.exr: error: cannot read") != NULL);
	fclose(diag);
}

/* ---- lookups ---- */

#define NPTS 8

struct lookup {
	float s[4][NPTS], t[4][NPTS];
	float d[4][3 * NPTS];
	float out[3 * NPTS];
	uint8_t mask[NPTS];
	struct sl_tex_lookup q;
};

static void lookup_init(struct lookup *l, const char *name, int channel, int nch, uint32_t n)
{
	memset(l, 0, sizeof(*l));
	struct sl_tex_lookup *q = &l->q;
	q->name = name;
	q->channel = channel;
	q->nchannels = nch;
	q->n = n;
	q->stride = NPTS;
	q->mask = NULL;
	for (int k = 0; k < 4; k++) {
		q->s[k] = l->s[k];
		q->t[k] = l->t[k];
		q->dir[k] = l->d[k];
		q->pos[k] = l->d[k];
	}
	q->width = q->swidth = q->twidth = 1.0f;
	q->samples = 1.0f;
	q->bias = -1.0f;
	q->filter = "gaussian";
	q->out = l->out;
}

/* Point @i's region: the square of side @size centred on (s, t). */
static void set_square(struct lookup *l, uint32_t i, float s, float t, float size)
{
	static const float cs[4] = { -0.5f, 0.5f, 0.5f, -0.5f }, ct[4] = { -0.5f, -0.5f, 0.5f, 0.5f };
	for (int k = 0; k < 4; k++) {
		l->s[k][i] = s + cs[k] * size;
		l->t[k][i] = t + ct[k] * size;
	}
}

/* Point @i's corners in current space: p +- half along x and y. */
static void set_points(struct lookup *l, uint32_t i, float x, float y, float z, float half)
{
	static const float cx[4] = { -1, 1, 1, -1 }, cy[4] = { -1, -1, 1, 1 };
	for (int k = 0; k < 4; k++) {
		l->d[k][i] = x + cx[k] * half;
		l->d[k][NPTS + i] = y + cy[k] * half;
		l->d[k][2 * NPTS + i] = z;
	}
}

/* The 16x16 gradient R = x + 16 y, bilinear at (s, t) away from the edges. */
static double grad_bilinear(double s, double t)
{
	return (s * 16 - 0.5) + 16 * (t * 16 - 0.5);
}

static void test_texture_lookup(void)
{
	const char *src = tmp_path("g16.exr");
	make_gradient(src, 16, 16, false);
	CHECK(reyes_make_texture(src, tmp_path("g16p.tex"), "periodic", "periodic", "box", 1, 1,
				 NULL));
	CHECK(reyes_make_texture(src, tmp_path("g16c.tex"), "clamp", "clamp", "box", 1, 1, NULL));
	CHECK(reyes_make_texture(src, tmp_path("g16b.tex"), "black", "black", "box", 1, 1, NULL));
	static const char *const yname[] = { "Y" };
	struct reyes_image st;
	CHECK(reyes_image_init(&st, 256, 256, 1, yname));
	for (uint32_t y = 0; y < 256; y++)
		for (uint32_t x = 0; x < 256; x++)
			st.data[y * 256 + x] = x % 16 == 7 || x % 16 == 8 ? 1.0f : 0.0f;
	CHECK(reyes_image_write_exr(tmp_path("stripes.exr"), &st, false, NULL));
	reyes_image_finish(&st);
	CHECK(reyes_make_texture(tmp_path("stripes.exr"), tmp_path("stripes.tex"), "periodic",
				 "periodic", "box", 1, 1, NULL));
	float ident[16];
	sl_m44_identity(ident);
	char path[600];
	snprintf(path, sizeof(path), "/nonexistent:%s", dir);
	struct reyes_texsys *ts = reyes_texsys_create(path, ident, NULL);
	CHECK(ts != NULL);
	if (!ts)
		return;

	struct lookup l;
	/* Tiny regions: the bilinear value, in closed form for the gradient. */
	lookup_init(&l, "g16c.tex", 0, 1, 3);
	set_square(&l, 0, 0.3f, 0.4f, 1e-5f);
	set_square(&l, 1, 0.5f, 0.5f, 0.0f);
	set_square(&l, 2, 0.71f, 0.23f, 1e-4f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], grad_bilinear(0.3, 0.4), 1e-3);
	CHECK_NEAR(l.out[1], grad_bilinear(0.5, 0.5), 1e-3);
	CHECK_NEAR(l.out[2], grad_bilinear(0.71, 0.23), 1e-3);

	/* The whole map: the mean (127.5), within 1%. */
	lookup_init(&l, "g16c.tex", 0, 1, 1);
	set_square(&l, 0, 0.5f, 0.5f, 1.0f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 127.5, 1.275);
	/* ... and of the checkerboard (channel 1): 0.5. */
	l.q.channel = 1;
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.5, 0.005);
	/* A region of 4x4 texels on the checkerboard averages it too. */
	set_square(&l, 0, 0.5f, 0.5f, 0.25f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.5, 0.05);
	/* While one tiny sample sits on a texel centre: 0 or 1. */
	set_square(&l, 0, 4.5f / 16, 6.5f / 16, 0.0f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.0, 1e-6);
	set_square(&l, 0, 5.5f / 16, 6.5f / 16, 0.0f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 1.0, 1e-6);

	/*
	 * The mip level matters: 256x256 stripes, 2 texels on in every 16
	 * (mean 0.125). Sampled on level 0 a region's 16 samples per axis would
	 * all fall on the stripes; the right level gives the mean.
	 */
	for (int k = 0; k < 2; k++) {
		lookup_init(&l, "stripes.tex", 0, 1, 2);
		set_square(&l, 0, 0.5f, 0.5f, 1.0f);
		set_square(&l, 1, 0.375f, 0.6f, 0.25f);
		CHECK(reyes_tex_texture(ts, &l.q));
		CHECK_NEAR(l.out[0], 0.125, 0.00125);
		CHECK_NEAR(l.out[1], 0.125, 0.00125);
	}

	/* "blur" widens the region: a blur of 1 averages the whole map. */
	lookup_init(&l, "g16c.tex", 0, 1, 1);
	set_square(&l, 0, 0.5f, 0.5f, 0.0f);
	l.q.blur = l.q.sblur = l.q.tblur = 1.0f;
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 127.5, 1.275);

	/* Wrap modes at s = 0 on row 8 (texel centre): half texel 0, half texel -1. */
	double v0 = 0 + 16 * 8, v15 = 15 + 16 * 8;
	const char *maps[3] = { "g16p.tex", "g16c.tex", "g16b.tex" };
	double expect[3] = { 0.5 * (v0 + v15), v0, 0.5 * v0 };
	for (int m = 0; m < 3; m++) {
		lookup_init(&l, maps[m], 0, 1, 2);
		set_square(&l, 0, 0.0f, 8.5f / 16, 0.0f);
		/* Far outside: periodic repeats, clamp gives the edge, black gives 0. */
		set_square(&l, 1, -2.0f + 3.5f / 16, 8.5f / 16, 0.0f);
		CHECK(reyes_tex_texture(ts, &l.q));
		CHECK_NEAR(l.out[0], expect[m], 1e-3);
		double far[3] = { 3 + 16 * 8, v0, 0.0 };
		CHECK_NEAR(l.out[1], far[m], 1e-3);
	}

	/* Colour lookups: channel 0..2 of an R, G map; B is missing and gets the fill. */
	lookup_init(&l, "g16c.tex", 0, 3, 2);
	set_square(&l, 0, 2.5f / 16, 3.5f / 16, 0.0f);
	set_square(&l, 1, 0.5f, 0.5f, 0.0f);
	l.mask[0] = 1;
	l.mask[1] = 0;
	l.q.mask = l.mask;
	l.q.fill = 0.25f;
	l.out[1] = -7.0f;
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], 2 + 16 * 3, 1e-4);
	CHECK_NEAR(l.out[NPTS], 1.0, 1e-6);
	CHECK_NEAR(l.out[2 * NPTS], 0.25, 0.0);
	CHECK_NEAR(l.out[1], -7.0, 0.0); /* masked off: untouched */

	/* Garbage coordinates and options: finite results. */
	lookup_init(&l, "g16p.tex", 0, 3, 4);
	set_square(&l, 0, NAN, INFINITY, 1.0f);
	set_square(&l, 1, 1e30f, -1e30f, 1e30f);
	set_square(&l, 2, 0.5f, 0.5f, -3.0f);
	set_square(&l, 3, -1e-30f, 7.0f, 1e-38f);
	l.q.swidth = INFINITY;
	l.q.tblur = NAN;
	l.q.sblur = 1e30f;
	CHECK(reyes_tex_texture(ts, &l.q));
	bool finite = true;
	for (int c = 0; c < 3; c++)
		for (int i = 0; i < 4; i++)
			finite = finite && isfinite(l.out[c * NPTS + i]);
	CHECK(finite);

	/* Missing maps fail (the interpreter then warns and uses the fill). */
	lookup_init(&l, "nosuch.tex", 0, 1, 1);
	CHECK(!reyes_tex_texture(ts, &l.q));
	CHECK(!reyes_tex_texture(ts, &l.q));

	/* textureinfo */
	float res[16] = { 0 };
	const char *sres[1] = { NULL };
	CHECK(reyes_tex_info(ts, "g16c.tex", "resolution", SL_TYPE_FLOAT, 2, res, sres));
	CHECK_NEAR(res[0], 16.0, 0.0);
	CHECK_NEAR(res[1], 16.0, 0.0);
	CHECK(!reyes_tex_info(ts, "g16c.tex", "resolution", SL_TYPE_FLOAT, 0, res, sres));
	CHECK(reyes_tex_info(ts, "g16c.tex", "channels", SL_TYPE_FLOAT, 0, res, sres));
	CHECK_NEAR(res[0], 2.0, 0.0);
	CHECK(reyes_tex_info(ts, "g16c.tex", "type", SL_TYPE_STRING, 0, res, sres));
	CHECK_STR(sres[0], "texture");
	CHECK(!reyes_tex_info(ts, "g16c.tex", "viewingmatrix", SL_TYPE_MATRIX, 0, res, sres));
	CHECK(!reyes_tex_info(ts, "g16c.tex", "nonsense", SL_TYPE_FLOAT, 0, res, sres));
	CHECK(!reyes_tex_info(ts, "nosuch.tex", "resolution", SL_TYPE_FLOAT, 2, res, sres));
	reyes_texsys_destroy(ts);

	/* With no search path, relative names are relative to the current directory. */
	ts = reyes_texsys_create(NULL, NULL, NULL);
	lookup_init(&l, tmp_path("g16c.tex"), 0, 1, 1);
	set_square(&l, 0, 0.3f, 0.4f, 0.0f);
	CHECK(reyes_tex_texture(ts, &l.q));
	CHECK_NEAR(l.out[0], grad_bilinear(0.3, 0.4), 1e-3);
	reyes_texsys_destroy(ts);
}

static void test_environment(void)
{
	/* A 64x32 lat-long map whose R is the row and G the column. */
	static const char *const names[] = { "R", "G" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, 64, 32, 2, names));
	for (uint32_t y = 0; y < 32; y++)
		for (uint32_t x = 0; x < 64; x++) {
			im.data[(y * 64 + x) * 2] = (float)y;
			im.data[(y * 64 + x) * 2 + 1] = (float)x;
		}
	const char *src = tmp_path("env.exr");
	CHECK(reyes_image_write_exr(src, &im, false, NULL));
	reyes_image_finish(&im);
	CHECK(reyes_make_texture(src, tmp_path("env.tex"), "periodic", "clamp", "box", 1, 1, NULL));
	struct reyes_texsys *ts = reyes_texsys_create(dir, NULL, NULL);
	struct lookup l;
	lookup_init(&l, "env.tex", 0, 3, 4);
	/* +z: the north pole (top row); -z the bottom; +x: s = 0; +y: s = 1/4 at the equator. */
	float dirs[4][3] = { { 0, 0, 1 }, { 0, 0, -1 }, { 1, 0, 0 }, { 0, 1, 0 } };
	for (uint32_t i = 0; i < 4; i++)
		for (int k = 0; k < 4; k++)
			for (int a = 0; a < 3; a++)
				l.d[k][a * NPTS + i] = dirs[i][a];
	CHECK(reyes_tex_environment(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.0, 1e-3);            /* t = 0: row 0 (clamped) */
	CHECK_NEAR(l.out[1], 31.0, 1e-3);           /* t = 1: row 31 */
	CHECK_NEAR(l.out[2], 15.5, 1e-3);           /* equator: between rows 15 and 16 */
	CHECK_NEAR(l.out[NPTS + 2], 31.5, 1e-3);    /* s = 0: columns 63 and 0 (periodic) */
	CHECK_NEAR(l.out[NPTS + 3], 15.5, 1e-3);    /* s = 0.25: between columns 15 and 16 */
	CHECK_NEAR(l.out[3], 15.5, 1e-3);
	/* A wide spread of directions gives an average, still finite; a zero direction gives 0. */
	lookup_init(&l, "env.tex", 0, 1, 2);
	float spread[4][3] = { { 1, 0, 0.2f }, { 0, 1, 0.2f }, { -1, 0, 0.2f }, { 0, -1, 0.2f } };
	for (int k = 0; k < 4; k++)
		for (int a = 0; a < 3; a++)
			l.d[k][a * NPTS] = spread[k][a];
	CHECK(reyes_tex_environment(ts, &l.q));
	CHECK(l.out[0] > 0.0f && l.out[0] < 16.0f);
	CHECK_NEAR(l.out[1], 0.0, 0.0);
	reyes_texsys_destroy(ts);
}

/* A @w x @w picture of constant colour @rgb, or (@ramp) with R = s at each texel centre. */
static void write_face(const char *path, uint32_t w, const float rgb[3], bool ramp)
{
	static const char *const names[] = { "R", "G", "B" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, w, w, 3, names));
	for (uint32_t y = 0; y < w; y++)
		for (uint32_t x = 0; x < w; x++)
			for (int c = 0; c < 3; c++)
				im.data[(y * w + x) * 3 + (uint32_t)c] =
					ramp && c == 0 ? (x + 0.5f) / (float)w : rgb[c];
	CHECK(reyes_image_write_exr(path, &im, false, NULL));
	reyes_image_finish(&im);
}

/* One environment() lookup of direction @d (a point lookup: all corners equal) into rgb. */
static bool env_at(struct reyes_texsys *ts, const char *name, const double d[3], float rgb[3])
{
	struct lookup l;
	lookup_init(&l, name, 0, 3, 1);
	for (int k = 0; k < 4; k++)
		for (int a = 0; a < 3; a++)
			l.d[k][a * NPTS] = (float)d[a];
	if (!reyes_tex_environment(ts, &l.q))
		return false;
	for (int c = 0; c < 3; c++)
		rgb[c] = l.out[c * NPTS];
	return true;
}

/*
 * MakeCubeFaceEnvironment from six constant faces (px red, nx green, py
 * blue, ny yellow, pz magenta, nz cyan): every direction gets the colour of
 * the face its largest component points at, exactly (a constant face
 * filters to itself; the lookup never reaches into another face). Then
 * the field of view: px a ramp R = s, the map made with fov 120 degrees;
 * a direction at angle a from +x towards -z (the face's right) lands at
 * s = 1/2 + tan(a) / (2 tan 60), within 1e-3 (a linear ramp filters to its
 * value; 90 degrees would give 1/2 + tan(a) / 2).
 */
static void test_cube_environment(void)
{
	static const float colours[6][3] = { { 1, 0, 0 }, { 0, 1, 0 }, { 0, 0, 1 },
					      { 1, 1, 0 }, { 1, 0, 1 }, { 0, 1, 1 } };
	static const char *const fnames[6] = { "px.exr", "nx.exr", "py.exr", "ny.exr", "pz.exr",
						"nz.exr" };
	char paths[6][256];
	const char *faces[6];
	for (int k = 0; k < 6; k++) {
		snprintf(paths[k], sizeof(paths[k]), "%s", tmp_path(fnames[k]));
		write_face(paths[k], 16, colours[k], false);
		faces[k] = paths[k];
	}
	CHECK(reyes_make_cube_environment(faces, tmp_path("cube.env"), 90, "box", 1, 1, NULL));
	struct reyes_texsys *ts = reyes_texsys_create(dir, NULL, NULL);
	const char *type = NULL;
	CHECK(reyes_tex_info(ts, "cube.env", "type", SL_TYPE_STRING, 0, NULL, &type));
	CHECK(type && !strcmp(type, "environment"));
	/* Directions on a grid of the sphere, away from the cube's edges. */
	int checked = 0, wrong = 0;
	for (int i = 0; i < 24; i++)
		for (int j = 1; j < 12; j++) {
			double th = 2 * 3.14159265358979 * (i + 0.3) / 24, ph = 3.14159265358979 * j / 12;
			double d[3] = { sin(ph) * cos(th), sin(ph) * sin(th), cos(ph) };
			double m[3] = { fabs(d[0]), fabs(d[1]), fabs(d[2]) };
			int ax = m[0] >= m[1] && m[0] >= m[2] ? 0 : m[1] >= m[2] ? 1 : 2;
			double second = ax == 0 ? fmax(m[1], m[2]) : ax == 1 ? fmax(m[0], m[2]) :
				       fmax(m[0], m[1]);
			if (m[ax] - second < 0.05)
				continue;
			int face = 2 * ax + (d[ax] < 0);
			float rgb[3];
			CHECK(env_at(ts, "cube.env", d, rgb));
			checked++;
			for (int c = 0; c < 3; c++)
				wrong += fabsf(rgb[c] - colours[face][c]) > 1e-5f;
		}
	printf("cube map: %d directions checked, %d channels wrong\n", checked, wrong);
	CHECK(checked > 200);
	CHECK(wrong == 0);
	/* A mip-mapped lookup over a wide cone inside one face is still that face's colour. */
	struct lookup l;
	lookup_init(&l, "cube.env", 0, 3, 1);
	float cone[4][3] = { { 0.3f, 0.3f, 1 }, { -0.3f, 0.3f, 1 }, { 0.3f, -0.3f, 1 },
			     { -0.3f, -0.3f, 1 } };
	for (int k = 0; k < 4; k++)
		for (int a = 0; a < 3; a++)
			l.d[k][a * NPTS] = cone[k][a];
	CHECK(reyes_tex_environment(ts, &l.q));
	CHECK_NEAR(l.out[0], 1, 1e-5);
	CHECK_NEAR(l.out[NPTS], 0, 1e-5);
	CHECK_NEAR(l.out[2 * NPTS], 1, 1e-5);
	reyes_texsys_destroy(ts);

	for (int k = 0; k < 6; k++)
		write_face(paths[k], 64, colours[k], k == 0);
	CHECK(reyes_make_cube_environment(faces, tmp_path("wide.env"), 120, "box", 1, 1, NULL));
	ts = reyes_texsys_create(dir, NULL, NULL);
	double worst = 0;
	for (int k = -4; k <= 4; k++) {
		double a = k * 10 * 3.14159265358979 / 180;
		double d[3] = { cos(a), 0, -sin(a) };
		float rgb[3];
		CHECK(env_at(ts, "wide.env", d, rgb));
		double want = 0.5 + tan(a) / (2 * tan(3.14159265358979 / 3));
		worst = fmax(worst, fabs(rgb[0] - want));
	}
	printf("cube map, fov 120: worst s error %.2g (tolerance 1e-3)\n", worst);
	CHECK(worst <= 1e-3);
	reyes_texsys_destroy(ts);

	/* Faces of different sizes, a bad fov and a missing face are errors. */
	write_face(paths[1], 8, colours[1], false);
	CHECK(!reyes_make_cube_environment(faces, tmp_path("bad.env"), 90, "box", 1, 1, NULL));
	write_face(paths[1], 64, colours[1], false);
	CHECK(!reyes_make_cube_environment(faces, tmp_path("bad.env"), 0, "box", 1, 1, NULL));
	faces[5] = tmp_path("missing.exr");
	CHECK(!reyes_make_cube_environment(faces, tmp_path("bad.env"), 90, "box", 1, 1, NULL));
}

/*
 * MakeLatLongEnvironment from a 64x32 picture whose R is t and G is s at
 * each texel centre: direction (x, y, z) looks up s = atan2(y, x) / 2pi and
 * t = acos(z) / pi (texture.c's convention) within 1e-3 away from the poles
 * and the seam, and the map says it is an environment.
 */
static void test_latlong_environment(void)
{
	static const char *const names[] = { "R", "G", "B" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, 64, 32, 3, names));
	for (uint32_t y = 0; y < 32; y++)
		for (uint32_t x = 0; x < 64; x++) {
			im.data[(y * 64 + x) * 3] = (y + 0.5f) / 32;
			im.data[(y * 64 + x) * 3 + 1] = (x + 0.5f) / 64;
		}
	CHECK(reyes_image_write_exr(tmp_path("ll.exr"), &im, false, NULL));
	reyes_image_finish(&im);
	CHECK(reyes_make_latlong_environment(tmp_path("ll.exr"), tmp_path("ll.env"), "box", 1, 1,
					     NULL));
	struct reyes_texsys *ts = reyes_texsys_create(dir, NULL, NULL);
	const char *type = NULL;
	CHECK(reyes_tex_info(ts, "ll.env", "type", SL_TYPE_STRING, 0, NULL, &type));
	CHECK(type && !strcmp(type, "environment"));
	double worst = 0;
	for (int i = 1; i < 16; i++)
		for (int j = 2; j < 11; j++) {
			double th = 2 * 3.14159265358979 * i / 16.5, ph = 3.14159265358979 * j / 12.5;
			double d[3] = { sin(ph) * cos(th), sin(ph) * sin(th), cos(ph) };
			float rgb[3];
			CHECK(env_at(ts, "ll.env", d, rgb));
			worst = fmax(worst, fabs(rgb[0] - ph / 3.14159265358979));
			worst = fmax(worst, fabs(rgb[1] - th / (2 * 3.14159265358979)));
		}
	printf("lat-long map: worst error %.2g (tolerance 1e-3)\n", worst);
	CHECK(worst <= 1e-3);
	reyes_texsys_destroy(ts);
}

/*
 * A shadow map of a light at the world origin looking down +z (orthographic):
 * NDC s = (x + 1) / 2, t = (1 - y) / 2 over x, y in [-1, 1]. The left half
 * (x < 0) sees an occluder at depth 5, the right half one at depth 10.
 */
static void make_depth_map(const char *path, bool matrices)
{
	static const char *const names[] = { "Z" };
	struct reyes_image im;
	CHECK(reyes_image_init(&im, 64, 64, 1, names));
	for (uint32_t y = 0; y < 64; y++)
		for (uint32_t x = 0; x < 64; x++)
			im.data[y * 64 + x] = x < 32 ? 5.0f : 10.0f;
	im.has_matrices = matrices;
	sl_m44_identity(im.world_to_camera);
	float ndc[16] = { 0.5f, 0, 0, 0, 0, -0.5f, 0, 0, 0, 0, 1, 0, 0.5f, 0.5f, 0, 1 };
	memcpy(im.world_to_ndc, ndc, sizeof(ndc));
	CHECK(reyes_image_write_exr(path, &im, true, NULL));
	reyes_image_finish(&im);
}

static void test_shadow(void)
{
	const char *zfile = tmp_path("light.z.exr"), *smap = tmp_path("light.shad");
	make_depth_map(zfile, true);
	CHECK(reyes_make_shadow(zfile, smap, NULL));
	/* "current" space is world moved by -2 in z: camera_to_world translates by +2. */
	float c2w[16];
	float tr[3] = { 0, 0, 2 };
	sl_m44_translation(c2w, tr);
	struct reyes_texsys *ts = reyes_texsys_create(dir, c2w, NULL);

	struct lookup l;
	lookup_init(&l, "light.shad", 0, 1, 8);
	l.q.samples = 16;
	float small = 0.01f;
	set_points(&l, 0, -0.5f, 0.0f, 3.0f - 2, small);    /* in front of depth 5 */
	set_points(&l, 1, -0.5f, 0.3f, 7.0f - 2, small);    /* behind depth 5 */
	set_points(&l, 2, 0.5f, -0.3f, 7.0f - 2, small);    /* in front of depth 10 */
	set_points(&l, 3, 0.5f, 0.0f, 12.0f - 2, small);    /* behind depth 10 */
	set_points(&l, 4, -0.5f, 0.0f, -1.0f - 2, small);   /* behind the light */
	set_points(&l, 5, 3.0f, 0.0f, 20.0f - 2, small);    /* outside the map */
	set_points(&l, 6, -0.5f, 0.0f, 5.005f - 2, small);  /* within the default bias 0.01 */
	set_points(&l, 7, -0.5f, 0.0f, 5.05f - 2, small);   /* beyond it */
	CHECK(reyes_tex_shadow(ts, &l.q));
	double expect[8] = { 0, 1, 0, 1, 0, 0, 0, 1 };
	for (int i = 0; i < 8; i++)
		CHECK_NEAR(l.out[i], expect[i], 0.0);

	/* An explicit bias of 0 shadows the point 0.005 behind the occluder. */
	l.q.bias = 0.0f;
	CHECK(reyes_tex_shadow(ts, &l.q));
	CHECK_NEAR(l.out[6], 1.0, 0.0);

	/* On the edge between depth 5 and 10, at depth 7: half the region is shadowed. */
	lookup_init(&l, "light.shad", 0, 1, 3);
	l.q.samples = 256;
	set_points(&l, 0, 0.0f, 0.0f, 7.0f - 2, 0.2f);
	set_points(&l, 1, 0.0f, 0.37f, 7.0f - 2, 0.2f);
	/* The same with blur instead of a region: 0.2 in s is 0.4 in x. */
	set_points(&l, 2, 0.0f, -0.2f, 7.0f - 2, 0.0f);
	l.q.blur = l.q.sblur = l.q.tblur = 0.2f;
	CHECK(reyes_tex_shadow(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.5, 0.08);
	CHECK_NEAR(l.out[1], 0.5, 0.08);
	/* Point 2's own region is a point widened only by blur. */
	CHECK_NEAR(l.out[2], 0.5, 0.08);

	/* width scales the region: a quarter of it on the near side. */
	lookup_init(&l, "light.shad", 0, 1, 1);
	l.q.samples = 1024;
	set_points(&l, 0, -0.1f, 0.0f, 7.0f - 2, 0.2f);
	CHECK(reyes_tex_shadow(ts, &l.q));
	CHECK_NEAR(l.out[0], 0.75, 0.06);
	l.q.width = l.q.swidth = l.q.twidth = 0.25f;
	CHECK(reyes_tex_shadow(ts, &l.q));
	CHECK_NEAR(l.out[0], 1.0, 0.0);

	/* Colour results get the same fraction in every channel; garbage stays finite. */
	lookup_init(&l, "light.shad", 0, 3, 2);
	set_points(&l, 0, -0.5f, 0.0f, 5.0f, small);
	set_points(&l, 1, NAN, INFINITY, 1e30f, 1e30f);
	l.q.samples = NAN;
	CHECK(reyes_tex_shadow(ts, &l.q));
	CHECK_NEAR(l.out[0], 1.0, 0.0);
	CHECK_NEAR(l.out[NPTS], 1.0, 0.0);
	CHECK_NEAR(l.out[2 * NPTS], 1.0, 0.0);
	CHECK(isfinite(l.out[1]) && isfinite(l.out[NPTS + 1]));

	/* textureinfo on the shadow map. */
	float m[16];
	const char *type = NULL;
	CHECK(reyes_tex_info(ts, "light.shad", "type", SL_TYPE_STRING, 0, m, &type));
	CHECK_STR(type, "shadow");
	CHECK(reyes_tex_info(ts, "light.shad", "projectionmatrix", SL_TYPE_MATRIX, 0, m, &type));
	CHECK_NEAR(m[0], 0.5, 0.0);
	CHECK_NEAR(m[5], -0.5, 0.0);
	CHECK_NEAR(m[12], 0.5, 0.0);
	CHECK(reyes_tex_info(ts, "light.shad", "viewingmatrix", SL_TYPE_MATRIX, 0, m, &type));
	CHECK_NEAR(m[0], 1.0, 0.0);
	CHECK_NEAR(m[14], 0.0, 0.0);
	CHECK(reyes_tex_info(ts, "light.shad", "resolution", SL_TYPE_FLOAT, 2, m, &type));
	CHECK_NEAR(m[0], 64.0, 0.0);

	/* The shadow map is float Z with the matrices. */
	struct reyes_image back;
	CHECK(reyes_image_read_exr(smap, &back, NULL));
	CHECK(back.nchannels == 1 && back.has_matrices);
	if (back.nchannels == 1)
		CHECK_STR(back.channel_names[0], "Z");
	reyes_image_finish(&back);
	char out[8192], cmd[1200];
	if (tool_exists("/usr/bin/exrheader")) {
		snprintf(cmd, sizeof(cmd), "/usr/bin/exrheader '%s' 2>&1", smap);
		CHECK(run_cmd(cmd, out, sizeof(out)) == 0);
		CHECK(strstr(out, "Z, 32-bit floating-point") != NULL);
		CHECK(strstr(out, "worldToNDC (type m44f)") != NULL);
	}

	/* shadow() of a map that is not a depth map fails. */
	lookup_init(&l, "g16c.tex", 0, 1, 1);
	CHECK(!reyes_tex_shadow(ts, &l.q));
	reyes_texsys_destroy(ts);

	/* MakeShadow needs the matrices. */
	FILE *diag = tmpfile();
	make_depth_map(tmp_path("nomat.z.exr"), false);
	CHECK(!reyes_make_shadow(tmp_path("nomat.z.exr"), tmp_path("nomat.shad"), diag));
	CHECK(strstr(diag_text(diag), "not a depth map with camera matrices") != NULL);
	CHECK(access(tmp_path("nomat.shad"), F_OK) != 0);
	fclose(diag);
}

/* ---- threads ---- */

struct worker {
	struct reyes_texsys *ts;
	float out[NPTS];
	bool ok;
};

static void *worker_main(void *arg)
{
	struct worker *w = arg;
	struct lookup l;
	w->ok = true;
	for (int rep = 0; rep < 50; rep++) {
		lookup_init(&l, rep % 2 ? "g16p.tex" : "g16c.tex", 0, 1, NPTS);
		for (uint32_t i = 0; i < NPTS; i++)
			set_square(&l, i, 0.1f * i, 0.37f, 0.05f);
		w->ok = w->ok && reyes_tex_texture(w->ts, &l.q);
		if (rep == 48)
			memcpy(w->out, l.out, sizeof(w->out));
	}
	return NULL;
}

static void test_threads(void)
{
	struct reyes_texsys *ts = reyes_texsys_create(dir, NULL, NULL);
	struct worker w[4];
	pthread_t th[4];
	for (int k = 0; k < 4; k++) {
		w[k].ts = ts;
		CHECK(pthread_create(&th[k], NULL, worker_main, &w[k]) == 0);
	}
	for (int k = 0; k < 4; k++)
		pthread_join(th[k], NULL);
	for (int k = 0; k < 4; k++) {
		CHECK(w[k].ok);
		CHECK(memcmp(w[k].out, w[0].out, sizeof(w[0].out)) == 0);
	}
	reyes_texsys_destroy(ts);
}

int main(void)
{
	snprintf(dir, sizeof(dir), "/tmp/relight-texture-XXXXXX");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_round_trip);
	RUN(test_nonfinite);
	RUN(test_atomic);
	RUN(test_corrupt);
	RUN(test_windows);
	RUN(test_make_texture);
	RUN(test_texture_lookup);
	RUN(test_environment);
	RUN(test_cube_environment);
	RUN(test_latlong_environment);
	RUN(test_shadow);
	RUN(test_threads);
	remove_tree(dir);
	return test_finish();
}

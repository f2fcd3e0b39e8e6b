/*
 * The PNG writer and the sRGB transfer function. Written files are decoded
 * here independently of the writer: chunks parsed by hand, every CRC
 * checked with zlib's crc32(), the IDAT data inflated with uncompress(),
 * filter type 0 undone, and the pixels compared exactly.
 */
#include "png.h"
#include "texture.h"

#include "test.h"

#include <dirent.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

static char dir[] = "/tmp/relight-test-png-XXXXXX";

struct decoded {
	uint32_t width, height, nch;
	uint32_t nidat;         /* how many IDAT chunks */
	uint8_t *pixels;        /* width * height * nch, tightly packed */
};

static uint32_t be32(const uint8_t *p)
{
	return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static uint8_t *slurp(const char *path, size_t *size)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	size_t cap = 1 << 16, n = 0;
	uint8_t *buf = malloc(cap);
	size_t got;
	while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
		n += got;
		if (n == cap) {
			uint8_t *nb = realloc(buf, cap *= 2);
			if (!nb)
				free(buf);
			buf = nb;
		}
	}
	fclose(f);
	*size = n;
	return buf;
}

/* Decode a PNG as the writer makes them; false (with a message) on anything unexpected. */
static bool decode(const char *path, struct decoded *d)
{
	static const uint8_t sig[8] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n' };
	memset(d, 0, sizeof(*d));
	size_t size = 0;
	uint8_t *buf = slurp(path, &size);
	uint8_t *z = NULL;
	size_t zlen = 0;
	bool ok = false, seen_ihdr = false, seen_iend = false;
	if (!buf || size < 8 || memcmp(buf, sig, 8) != 0) {
		fprintf(stderr, "%s: no PNG signature\n", path);
		goto done;
	}
	size_t pos = 8;
	while (!seen_iend) {
		if (size - pos < 12) {
			fprintf(stderr, "%s: truncated chunk at %zu\n", path, pos);
			goto done;
		}
		uint32_t len = be32(buf + pos);
		const uint8_t *type = buf + pos + 4, *data = buf + pos + 8;
		if (len > size - pos - 12) {
			fprintf(stderr, "%s: chunk length %u too long\n", path, len);
			goto done;
		}
		uLong crc = crc32(crc32(0L, Z_NULL, 0), type, 4 + len);
		if ((uint32_t)crc != be32(data + len)) {
			fprintf(stderr, "%s: bad CRC on chunk %.4s\n", path, (const char *)type);
			goto done;
		}
		if (memcmp(type, "IHDR", 4) == 0) {
			static const uint32_t nch_of[7] = { 1, 0, 3, 0, 2, 0, 4 };
			if (seen_ihdr || pos != 8 || len != 13 || data[8] != 8 || data[9] > 6 ||
			    !nch_of[data[9]] || data[10] || data[11] || data[12]) {
				fprintf(stderr, "%s: unexpected IHDR\n", path);
				goto done;
			}
			seen_ihdr = true;
			d->width = be32(data);
			d->height = be32(data + 4);
			d->nch = nch_of[data[9]];
		} else if (memcmp(type, "IDAT", 4) == 0) {
			uint8_t *nz = realloc(z, zlen + len + 1);
			if (!nz)
				goto done;
			z = nz;
			memcpy(z + zlen, data, len);
			zlen += len;
			d->nidat++;
		} else if (memcmp(type, "IEND", 4) == 0) {
			seen_iend = true;
		} else {
			fprintf(stderr, "%s: unexpected chunk %.4s\n", path, (const char *)type);
			goto done;
		}
		pos += 12 + (size_t)len;
	}
	if (!seen_ihdr || pos != size || !d->nidat) {
		fprintf(stderr, "%s: bad chunk sequence or trailing bytes\n", path);
		goto done;
	}
	size_t row = (size_t)d->width * d->nch;
	uLongf rawlen = (uLongf)((row + 1) * d->height);
	/* One spare byte: a stream that inflates to more than expected fails. */
	uint8_t *raw = malloc(rawlen + 1);
	uLongf got = rawlen + 1;
	if (!raw || uncompress(raw, &got, z, (uLong)zlen) != Z_OK || got != rawlen) {
		fprintf(stderr, "%s: the image data does not inflate to %lu bytes\n", path,
			(unsigned long)rawlen);
		free(raw);
		goto done;
	}
	d->pixels = malloc(row * d->height);
	for (uint32_t y = 0; d->pixels && y < d->height; y++) {
		const uint8_t *r = raw + y * (row + 1);
		if (r[0] != 0) {
			fprintf(stderr, "%s: row %u has filter type %u\n", path, y, r[0]);
			free(raw);
			goto done;
		}
		memcpy(d->pixels + y * row, r + 1, row);
	}
	free(raw);
	ok = d->pixels != NULL;
done:
	if (!ok) {
		free(d->pixels);
		d->pixels = NULL;
	}
	free(z);
	free(buf);
	return ok;
}

/* A deterministic pseudo-random byte stream (xorshift). */
static uint8_t noise_byte(uint32_t *s)
{
	*s ^= *s << 13;
	*s ^= *s >> 17;
	*s ^= *s << 5;
	return (uint8_t)(*s >> 24);
}

static void path_in_dir(char *buf, size_t size, const char *name)
{
	snprintf(buf, size, "%s/%s", dir, name);
}

/* Write, decode and compare one image. */
static void roundtrip(const char *name, uint32_t w, uint32_t h, uint32_t nch, bool noisy,
		      uint32_t min_idat)
{
	char path[256];
	path_in_dir(path, sizeof(path), name);
	size_t n = (size_t)w * h * nch;
	uint8_t *px = malloc(n);
	uint32_t seed = 12345u + w + h + nch;
	for (size_t i = 0; i < n; i++)
		px[i] = noisy ? noise_byte(&seed) : (uint8_t)((i * 7 + i / 13) & 0xff);
	CHECK(reyes_png_write(path, px, w, h, nch, stderr));
	struct decoded d;
	bool ok = decode(path, &d);
	CHECK(ok);
	if (ok) {
		CHECK(d.width == w && d.height == h && d.nch == nch);
		CHECK(d.nidat >= min_idat);
		CHECK(memcmp(d.pixels, px, n) == 0);
		free(d.pixels);
	}
	free(px);
}

static void test_roundtrip(void)
{
	roundtrip("grey.png", 7, 5, 1, false, 1);
	roundtrip("grey_alpha.png", 3, 9, 2, false, 1);
	roundtrip("rgb.png", 17, 11, 3, false, 1);
	roundtrip("rgba.png", 1, 1, 4, false, 1);
	roundtrip("wide.png", 1000, 2, 4, false, 1);
	/* 200x200 RGBA of noise, 160 kB that do not compress: several IDAT chunks. */
	roundtrip("noise.png", 200, 200, 4, true, 2);
}

static void test_known_bytes(void)
{
	/* A 2x1 RGB image: check the header bytes themselves, not only our decoder. */
	const uint8_t px[6] = { 255, 0, 0, 0, 128, 255 };
	char path[256];
	path_in_dir(path, sizeof(path), "two.png");
	CHECK(reyes_png_write(path, px, 2, 1, 3, stderr));
	size_t size = 0;
	uint8_t *buf = slurp(path, &size);
	CHECK(buf && size > 33);
	if (buf && size > 33) {
		static const uint8_t head[] = {
			0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n',
			0, 0, 0, 13, 'I', 'H', 'D', 'R',
			0, 0, 0, 2, 0, 0, 0, 1, 8, 2, 0, 0, 0,
		};
		CHECK(memcmp(buf, head, sizeof(head)) == 0);
		/* Ends with IEND and its fixed CRC. */
		static const uint8_t iend[] = { 0, 0, 0, 0, 'I', 'E', 'N', 'D',
						0xae, 0x42, 0x60, 0x82 };
		CHECK(memcmp(buf + size - 12, iend, 12) == 0);
	}
	free(buf);
	struct stat st;
	CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == 0644);
}

static bool no_temp_files(void)
{
	DIR *d = opendir(dir);
	if (!d)
		return false;
	bool clean = true;
	struct dirent *e;
	while ((e = readdir(d)))
		if (strstr(e->d_name, ".tmp."))
			clean = false;
	closedir(d);
	return clean;
}

static void test_errors(void)
{
	char path[256], bad[256];
	path_in_dir(path, sizeof(path), "keep.png");
	const uint8_t px[4] = { 1, 2, 3, 4 };
	CHECK(reyes_png_write(path, px, 2, 2, 1, stderr));

	/* Each of these fails before anything is written; the old file stays. */
	FILE *devnull = fopen("/dev/null", "w");
	CHECK(!reyes_png_write(path, px, 2, 2, 5, devnull));
	CHECK(!reyes_png_write(path, px, 0, 2, 1, devnull));
	CHECK(!reyes_png_write(path, px, 2, 0, 1, devnull));
	CHECK(!reyes_png_write(path, px, 0x80000000u, 1, 1, devnull));
	CHECK(!reyes_png_write(path, NULL, 2, 2, 1, devnull));
	CHECK(!reyes_png_write("", px, 2, 2, 1, devnull));
	CHECK(!reyes_png_write(NULL, px, 2, 2, 1, devnull));
	/* A directory that does not exist: mkstemp fails. */
	path_in_dir(bad, sizeof(bad), "no/such/dir.png");
	CHECK(!reyes_png_write(bad, px, 2, 2, 1, devnull));
	/* The destination is a directory: the rename fails, the temporary file goes. */
	path_in_dir(bad, sizeof(bad), "adir");
	CHECK(mkdir(bad, 0755) == 0);
	CHECK(!reyes_png_write(bad, px, 2, 2, 1, devnull));
	rmdir(bad);
	fclose(devnull);

	struct decoded d;
	CHECK(decode(path, &d));
	if (d.pixels) {
		CHECK(d.width == 2 && d.height == 2 && d.nch == 1);
		CHECK(memcmp(d.pixels, px, 4) == 0);
		free(d.pixels);
	}
	/* Overwriting replaces the old file. */
	const uint8_t px2[3] = { 9, 8, 7 };
	CHECK(reyes_png_write(path, px2, 1, 1, 3, stderr));
	CHECK(decode(path, &d));
	if (d.pixels) {
		CHECK(d.width == 1 && d.height == 1 && d.nch == 3);
		CHECK(memcmp(d.pixels, px2, 3) == 0);
		free(d.pixels);
	}
	CHECK(no_temp_files());

	/* The message names the file. */
	char msgbuf[512] = "";
	FILE *msg = fmemopen(msgbuf, sizeof(msgbuf) - 1, "w");
	if (msg) {
		CHECK(!reyes_png_write(path, px, 2, 2, 0, msg));
		fclose(msg);
		CHECK(strstr(msgbuf, path) && strstr(msgbuf, "error: cannot write"));
	}
}

/* The inverse transfer, written independently, in double. */
static double srgb_decode(double v)
{
	return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void test_srgb(void)
{
	/* The end points and what lies beyond them. */
	CHECK(reyes_srgb_encode(0.0f) == 0.0f);
	CHECK(reyes_srgb_encode(1.0f) == 1.0f);
	CHECK(reyes_srgb8(0.0f) == 0);
	CHECK(reyes_srgb8(1.0f) == 255);
	CHECK(reyes_srgb8(-0.5f) == 0);
	CHECK(reyes_srgb8(7.0f) == 255);
	CHECK(reyes_srgb8(NAN) == 0);
	CHECK(reyes_srgb8(-NAN) == 0);
	CHECK(reyes_srgb8(INFINITY) == 255);
	CHECK(reyes_srgb8(-INFINITY) == 0);
	CHECK(reyes_srgb_encode(NAN) == 0.0f);
	CHECK(reyes_srgb_encode(INFINITY) == 1.0f);

	/* Known values (from the formula in double), to float precision. */
	CHECK_NEAR(reyes_srgb_encode(0.001f), 0.01292, 1e-7);
	CHECK_NEAR(reyes_srgb_encode(0.0031308f), 0.040449936, 2e-7);
	CHECK_NEAR(reyes_srgb_encode(0.0031309f), 0.040451178, 2e-7);
	CHECK_NEAR(reyes_srgb_encode(0.18f), 0.461356130, 2e-7);
	CHECK_NEAR(reyes_srgb_encode(0.25f), 0.537098730, 2e-7);
	CHECK_NEAR(reyes_srgb_encode(0.5f), 0.735356983, 2e-7);
	/* Rounding is to nearest: 0.5 -> 187.516 -> 188, 0.25 -> 136.960 -> 137,
	 * 0.0031308 -> 10.315 -> 10, 0.75 -> 224.610 -> 225. */
	CHECK(reyes_srgb8(0.5f) == 188);
	CHECK(reyes_srgb8(0.25f) == 137);
	CHECK(reyes_srgb8(0.0031308f) == 10);
	CHECK(reyes_srgb8(0.75f) == 225);

	/* Every 8-bit code decoded to linear comes back to itself. */
	int wrong = 0;
	for (int k = 0; k < 256; k++)
		wrong += reyes_srgb8((float)srgb_decode(k / 255.0)) != k;
	CHECK(wrong == 0);

	/* Monotonic, and within 1e-6 of the double formula everywhere. */
	float prev = -1.0f;
	double worst = 0;
	int nonmono = 0;
	for (int i = 0; i <= 100000; i++) {
		float x = i / 100000.0f;
		float v = reyes_srgb_encode(x);
		double ref = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
		if (fabs(v - ref) > worst)
			worst = fabs(v - ref);
		nonmono += v < prev;
		prev = v;
	}
	CHECK(worst < 1e-6);
	CHECK(nonmono == 0);

	CHECK(reyes_unorm8(0.5f) == 128);
	CHECK(reyes_unorm8(NAN) == 0);
	CHECK(reyes_unorm8(2.0f) == 255);
	CHECK(reyes_unorm8(-1.0f) == 0);
}

static void test_rgba(void)
{
	/* Premultiplied (0.25, 0.25, 0.25, 0.5): straight colour 0.5. */
	const float px[12] = {
		0.25f, 0.25f, 0.25f, 0.5f,
		NAN, INFINITY, -1.0f, 1.0f,
		0.3f, 0.2f, 0.1f, 0.0f,
	};
	uint8_t rgb[9], rgba[12];
	reyes_srgb8_rgba(px, 3, false, rgb);
	const uint8_t want_rgb[9] = { 137, 137, 137, 0, 255, 0,
				      reyes_srgb8(0.3f), reyes_srgb8(0.2f), reyes_srgb8(0.1f) };
	CHECK(memcmp(rgb, want_rgb, 9) == 0);
	reyes_srgb8_rgba(px, 3, true, rgba);
	const uint8_t want_rgba[12] = { 188, 188, 188, 128, 0, 255, 0, 255,
					reyes_srgb8(0.3f), reyes_srgb8(0.2f), reyes_srgb8(0.1f), 0 };
	CHECK(memcmp(rgba, want_rgba, 12) == 0);
}

/* A renderer image written as PNG: alpha last is straight, "A" and "Z" alone are linear. */
static void test_image(void)
{
	char path[512];
	struct decoded d;
	/* RGBA, premultiplied: as reyes_srgb8_rgba() with alpha gives it */
	static const char *const rgba_names[4] = { "R", "G", "B", "A" };
	float px[12] = { 0.25f, 0.25f, 0.25f, 0.5f, 0.3f, 0.2f, 0.1f, 1.0f, 0, 0, 0, 0 };
	struct reyes_image im = { .width = 3, .height = 1, .nchannels = 4,
				  .channel_names = (const char **)rgba_names, .data = px };
	path_in_dir(path, sizeof(path), "image_rgba.png");
	CHECK(reyes_png_write_image(path, &im, stderr));
	uint8_t want[12];
	reyes_srgb8_rgba(px, 3, true, want);
	CHECK(decode(path, &d) && d.nch == 4 && d.width == 3 && memcmp(d.pixels, want, 12) == 0);
	free(d.pixels);

	/* one AOV channel: grey through sRGB; alpha alone: linear */
	static const char *const y_name[1] = { "Y" }, *const a_name[1] = { "A" };
	float g[2] = { 0.5f, 0.25f };
	im = (struct reyes_image){ .width = 2, .height = 1, .nchannels = 1,
				   .channel_names = (const char **)y_name, .data = g };
	path_in_dir(path, sizeof(path), "image_y.png");
	CHECK(reyes_png_write_image(path, &im, stderr));
	CHECK(decode(path, &d) && d.nch == 1 && d.pixels[0] == reyes_srgb8(0.5f) &&
	      d.pixels[1] == reyes_srgb8(0.25f));
	free(d.pixels);
	im.channel_names = (const char **)a_name;
	path_in_dir(path, sizeof(path), "image_a.png");
	CHECK(reyes_png_write_image(path, &im, stderr));
	CHECK(decode(path, &d) && d.nch == 1 && d.pixels[0] == reyes_unorm8(0.5f) &&
	      d.pixels[1] == reyes_unorm8(0.25f));
	free(d.pixels);

	/* five channels do not fit */
	static const char *const five[5] = { "R", "G", "B", "A", "Z" };
	float f5[5] = { 0 };
	im = (struct reyes_image){ .width = 1, .height = 1, .nchannels = 5,
				   .channel_names = (const char **)five, .data = f5 };
	path_in_dir(path, sizeof(path), "image_5.png");
	CHECK(!reyes_png_write_image(path, &im, NULL));
}

int main(void)
{
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_roundtrip);
	RUN(test_known_bytes);
	RUN(test_errors);
	RUN(test_srgb);
	RUN(test_rgba);
	RUN(test_image);

	/* Clean up the files written. */
	DIR *d = opendir(dir);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		char p[512];
		if (e->d_name[0] == '.')
			continue;
		snprintf(p, sizeof(p), "%s/%s", dir, e->d_name);
		unlink(p);
	}
	if (d)
		closedir(d);
	rmdir(dir);
	return test_finish();
}

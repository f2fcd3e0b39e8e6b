/*
 * The shot file container: round trips of tables and deep parts in every
 * compression mode, half-float rounding and clamping, atomic writes, the
 * refusal of truncated, corrupted, foreign and newer files, and what
 * OpenEXR itself (exrheader, the Core decoder) makes of a written file.
 */
#include "shotfile.h"
#include "test.h"
#include "texture.h"

#include <openexr.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <signal.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static char dir[512];

static const char *in_dir(const char *name)
{
	static char buf[4][600];
	static int k;
	k = (k + 1) % 4;
	snprintf(buf[k], sizeof(buf[k]), "%s/%s", dir, name);
	return buf[k];
}

static uint64_t rng_state = 0x1234567887654321u;

static uint64_t rnd(void)
{
	uint64_t x = rng_state;
	x ^= x << 13;
	x ^= x >> 7;
	x ^= x << 17;
	return rng_state = x;
}

/* The value of half @h, computed independently of the code under test. */
static float half_value(uint16_t h)
{
	int e = (h >> 10) & 31, m = h & 1023;
	float v = e == 0 ? ldexpf((float)m, -24) : ldexpf((float)(m + 1024), e - 25);
	return (h & 0x8000) ? -v : v;
}

static uint16_t random_half(void)
{
	for (;;) {
		uint16_t h = (uint16_t)rnd();
		if (((h >> 10) & 31) != 31)
			return h;
	}
}

static float random_float(void)
{
	for (;;) {
		uint32_t b = (uint32_t)rnd();
		float f;
		memcpy(&f, &b, 4);
		if (isfinite(f))
			return f;
	}
}

static bool file_bytes(const char *path, uint8_t **data, size_t *size)
{
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return false;
	fseek(fp, 0, SEEK_END);
	long n = ftell(fp);
	fseek(fp, 0, SEEK_SET);
	*data = malloc(n > 0 ? (size_t)n : 1);
	*size = n > 0 ? (size_t)n : 0;
	bool ok = *data && fread(*data, 1, *size, fp) == *size;
	fclose(fp);
	return ok;
}

static bool put_bytes(const char *path, const void *data, size_t n)
{
	FILE *fp = fopen(path, "wb");
	if (!fp)
		return false;
	bool ok = fwrite(data, 1, n, fp) == n;
	return fclose(fp) == 0 && ok;
}

/* Temporary files ("X.tmp.XXXXXX") left in the test directory. */
static int count_temps(void)
{
	DIR *d = opendir(dir);
	int n = 0;
	struct dirent *e;
	while (d && (e = readdir(d)))
		if (strstr(e->d_name, ".tmp."))
			n++;
	if (d)
		closedir(d);
	return n;
}

/* ------------------------------------------------------------------------ */
/* Building and comparing shots                                              */

static void fill_channel(struct shot_channel *c, const char *name, enum shot_type type, uint64_t n)
{
	c->name = strdup(name);
	c->type = type;
	c->data = malloc((size_t)(n ? n : 1) * 4);
	for (uint64_t i = 0; i < n; i++) {
		if (type == SHOT_HALF)
			((float *)c->data)[i] = half_value(random_half());
		else if (type == SHOT_FLOAT)
			((float *)c->data)[i] = random_float();
		else
			((uint32_t *)c->data)[i] = (uint32_t)rnd();
	}
}

/* A table of three channels given out of name order: "z" half, "A.x" float, "m_1" uint. */
static void make_table(struct shot_table *t, const char *name, uint64_t nrows)
{
	t->name = strdup(name);
	t->nrows = nrows;
	t->nchannels = 3;
	t->channels = calloc(3, sizeof(*t->channels));
	fill_channel(&t->channels[0], "z", SHOT_HALF, nrows);
	fill_channel(&t->channels[1], "A.x", SHOT_FLOAT, nrows);
	fill_channel(&t->channels[2], "m_1", SHOT_UINT, nrows);
}

/* A deep part whose pixel (x, y) has (x * 7 + y * 3) % 5 entries, line 1 empty. */
static void make_deep(struct shot_deep *d, const char *name, uint32_t w, uint32_t h, int pattern)
{
	d->name = strdup(name);
	d->width = w;
	d->height = h;
	d->offsets = malloc(((size_t)w * h + 1) * sizeof(uint64_t));
	d->offsets[0] = 0;
	for (uint32_t y = 0; y < h; y++)
		for (uint32_t x = 0; x < w; x++) {
			uint64_t n = 0;
			if (pattern == 1 && y != 1)
				n = (x * 7u + y * 3u) % 5u;
			else if (pattern == 2)
				n = 1000;
			d->offsets[(size_t)y * w + x + 1] = d->offsets[(size_t)y * w + x] + n;
		}
	uint64_t n = d->offsets[(size_t)w * h];
	d->nchannels = 3;
	d->channels = calloc(3, sizeof(*d->channels));
	fill_channel(&d->channels[0], "weight", SHOT_HALF, n);
	fill_channel(&d->channels[1], "sample", SHOT_UINT, n);
	fill_channel(&d->channels[2], "depth", SHOT_FLOAT, n);
}

/* Free a shot built by the test (the library's shot_free() is for files it read). */
static void free_built(struct shot_file *f)
{
	for (uint32_t i = 0; i < f->ntables; i++) {
		for (uint32_t c = 0; c < f->tables[i].nchannels; c++) {
			free(f->tables[i].channels[c].name);
			free(f->tables[i].channels[c].data);
		}
		free(f->tables[i].channels);
		free(f->tables[i].name);
	}
	for (uint32_t i = 0; i < f->ndeeps; i++) {
		for (uint32_t c = 0; c < f->deeps[i].nchannels; c++) {
			free(f->deeps[i].channels[c].name);
			free(f->deeps[i].channels[c].data);
		}
		free(f->deeps[i].channels);
		free(f->deeps[i].name);
		free(f->deeps[i].offsets);
	}
	free(f->tables);
	free(f->deeps);
	free(f->metadata);
	memset(f, 0, sizeof(*f));
}

static const struct shot_channel *find_channel(const struct shot_channel *ch, uint32_t n,
					       const char *name)
{
	for (uint32_t c = 0; c < n; c++)
		if (!strcmp(ch[c].name, name))
			return &ch[c];
	return NULL;
}

/* Channels equal bit for bit (the expected values are exactly representable). */
static bool same_channels(const struct shot_channel *a, uint32_t na, const struct shot_channel *b,
			  uint32_t nb, uint64_t n)
{
	if (na != nb)
		return false;
	for (uint32_t c = 0; c < na; c++) {
		const struct shot_channel *o = find_channel(b, nb, a[c].name);
		if (!o || o->type != a[c].type || (n && (!o->data || memcmp(o->data, a[c].data, n * 4))))
			return false;
	}
	/* File order: sorted by name. */
	for (uint32_t c = 1; c < nb; c++)
		if (strcmp(b[c - 1].name, b[c].name) >= 0)
			return false;
	return true;
}

static bool same_table(const struct shot_table *a, const struct shot_table *b)
{
	return b && !strcmp(a->name, b->name) && a->nrows == b->nrows &&
	       same_channels(a->channels, a->nchannels, b->channels, b->nchannels, a->nrows);
}

static bool same_deep(const struct shot_deep *a, const struct shot_deep *b)
{
	if (!b || strcmp(a->name, b->name) || a->width != b->width || a->height != b->height ||
	    !b->offsets)
		return false;
	size_t np = (size_t)a->width * a->height + 1;
	if (memcmp(a->offsets, b->offsets, np * sizeof(uint64_t)))
		return false;
	return same_channels(a->channels, a->nchannels, b->channels, b->nchannels, a->offsets[np - 1]);
}

/* Everything a reader sees of @b equals @a (which may be a shot built by the test). */
static bool same_shot(const struct shot_file *a, const struct shot_file *b)
{
	if (!b || strcmp(a->metadata, b->metadata) || a->ntables != b->ntables ||
	    a->ndeeps != b->ndeeps)
		return false;
	for (uint32_t i = 0; i < a->ntables; i++)
		if (!same_table(&a->tables[i], shot_find_table(b, a->tables[i].name)) ||
		    strcmp(a->tables[i].name, b->tables[i].name))
			return false;
	for (uint32_t i = 0; i < a->ndeeps; i++)
		if (!same_deep(&a->deeps[i], shot_find_deep(b, a->deeps[i].name)) ||
		    strcmp(a->deeps[i].name, b->deeps[i].name))
			return false;
	return true;
}

/* A small shot of every kind of part, for the damage tests. */
static void make_small(struct shot_file *f)
{
	memset(f, 0, sizeof(*f));
	f->metadata = strdup("{\"lights\": [\"key\", \"rim\"], \"glsl\": \"void main() {}\"}");
	f->ntables = 2;
	f->tables = calloc(2, sizeof(*f->tables));
	make_table(&f->tables[0], "samples.plastic", 1500);
	make_table(&f->tables[1], "shadow", 3);
	f->ndeeps = 1;
	f->deeps = calloc(1, sizeof(*f->deeps));
	make_deep(&f->deeps[0], "indirect", 13, 5, 1);
}

/* ------------------------------------------------------------------------ */
/* Hash                                                                      */

static int popcount64(uint64_t v)
{
	int n = 0;
	for (; v; v &= v - 1)
		n++;
	return n;
}

static void test_hash(void)
{
	uint8_t buf[256];
	for (int i = 0; i < 256; i++)
		buf[i] = (uint8_t)(i * 37 + 11);
	/* Fixed values: the hash is part of the file format and must never change. */
	CHECK(shot_hash("", 0, 0) == UINT64_C(0x02e6dfc85a207e9d));
	CHECK(shot_hash(buf, 256, 0) == UINT64_C(0xdd970dd7306975a8));
	CHECK(shot_hash(buf, 31, 7) == UINT64_C(0xfc9282172ec705b2));
	CHECK(shot_hash(buf, 256, 0) == shot_hash(buf, 256, 0));
	CHECK(shot_hash(buf, 256, 0) != shot_hash(buf, 256, 1));

	/* Lengths 1..256 of zeros and of data: all different. */
	static uint8_t zeros[256];
	uint64_t seen[512];
	int ns = 0, dup = 0;
	for (int n = 1; n <= 256; n++) {
		uint64_t h[2] = { shot_hash(zeros, (size_t)n, 0), shot_hash(buf, (size_t)n, 0) };
		for (int k = 0; k < 2; k++) {
			for (int j = 0; j < ns; j++)
				dup += seen[j] == h[k];
			seen[ns++] = h[k];
		}
	}
	CHECK(dup == 0);

	/* Avalanche: each input bit flip changes about half of the output bits. */
	for (size_t len = 5; len <= 100; len += 19) {
		uint64_t h0 = shot_hash(buf, len, 0);
		long total = 0;
		int lo = 64, hi = 0;
		for (size_t bit = 0; bit < len * 8; bit++) {
			buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
			int d = popcount64(h0 ^ shot_hash(buf, len, 0));
			buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
			total += d;
			lo = d < lo ? d : lo;
			hi = d > hi ? d : hi;
		}
		double mean = (double)total / (double)(len * 8);
		CHECK_NEAR(mean, 32.0, 2.0);
		CHECK(lo >= 12 && hi <= 52);
	}
}

/* ------------------------------------------------------------------------ */
/* Round trips                                                               */

static const char *const mode_names[] = { "NONE", "RLE", "ZIPS", "ZIP" };

static void test_tables(void)
{
	static const uint64_t rows[] = { 0, 1, 1023, 1024, 1025, 100000, 300001 };
	const size_t nt = sizeof(rows) / sizeof(rows[0]);
	struct shot_file f = { 0 };
	f.metadata = strdup("{}");
	f.ntables = (uint32_t)nt;
	f.tables = calloc(nt, sizeof(*f.tables));
	for (size_t i = 0; i < nt; i++) {
		char name[32];
		snprintf(name, sizeof(name), "t%llu", (unsigned long long)rows[i]);
		make_table(&f.tables[i], name, rows[i]);
	}
	uint64_t before = shot_hash(f.tables[5].channels[0].data, 100000 * 4, 0);
	for (int mode = SHOT_COMPRESS_NONE; mode <= SHOT_COMPRESS_ZIP; mode++) {
		char err[512] = "";
		char path[600];
		snprintf(path, sizeof(path), "%s", in_dir("tables.exr"));
		struct shot_write_options o = { .tables = (enum shot_compression)mode };
		bool ok = shot_write(path, &f, &o, err, sizeof(err));
		CHECK(ok);
		if (!ok) {
			fprintf(stderr, "  %s: %s\n", mode_names[mode], err);
			continue;
		}
		struct stat st;
		stat(path, &st);
		struct shot_file *g = shot_read(path, err, sizeof(err));
		CHECK(g != NULL);
		if (!g) {
			fprintf(stderr, "  %s: %s\n", mode_names[mode], err);
			continue;
		}
		CHECK(same_shot(&f, g));
		CHECK(err[0] == '\0');
		uint64_t sum = 0;
		for (size_t i = 0; i < nt; i++) {
			CHECK(g->part_bytes[i] > 0);
			sum += g->part_bytes[i];
		}
		CHECK(sum < (uint64_t)st.st_size);
		/* Uncompressed: every value and the padding, and no more than the headers besides. */
		if (mode == SHOT_COMPRESS_NONE) {
			const struct shot_table *t = shot_find_table(g, "t300001");
			CHECK(t && g->part_bytes[6] >= 293 * (uint64_t)1024 * 10);
			CHECK(t && g->part_bytes[6] <= 293 * (uint64_t)1024 * 10 + 293 * 20);
		}
		struct shot_file *hd = shot_read_header(path, err, sizeof(err));
		CHECK(hd != NULL);
		if (hd) {
			CHECK_STR(hd->metadata, "{}");
			CHECK(hd->ntables == nt && hd->ndeeps == 0);
			for (size_t i = 0; i < nt && i < hd->ntables; i++) {
				CHECK(hd->tables[i].nrows == rows[i]);
				CHECK(hd->tables[i].nchannels == 3);
				CHECK_STR(hd->tables[i].channels[0].name, "A.x");
				CHECK(hd->tables[i].channels[0].type == SHOT_FLOAT);
				CHECK(hd->tables[i].channels[2].type == SHOT_HALF);
				CHECK(hd->tables[i].channels[0].data == NULL);
				CHECK(hd->part_bytes[i] == g->part_bytes[i]);
			}
		}
		shot_free(hd);
		shot_free(g);
	}
	/* The writer leaves the caller's data alone. */
	CHECK(shot_hash(f.tables[5].channels[0].data, 100000 * 4, 0) == before);
	CHECK(count_temps() == 0);
	unlink(in_dir("tables.exr"));
	free_built(&f);
}

static void test_deep(void)
{
	struct shot_file f = { 0 };
	f.metadata = strdup("{\"tiles\": []}");
	f.ntables = 1;
	f.tables = calloc(1, sizeof(*f.tables));
	make_table(&f.tables[0], "samples", 2000);
	f.ndeeps = 3;
	f.deeps = calloc(3, sizeof(*f.deeps));
	make_deep(&f.deeps[0], "indirect", 37, 23, 1);
	make_deep(&f.deeps[1], "empty", 5, 4, 0);
	make_deep(&f.deeps[2], "one", 1, 1, 2);
	for (int mode = SHOT_COMPRESS_NONE; mode <= SHOT_COMPRESS_ZIPS; mode++) {
		char err[512] = "";
		char path[600];
		snprintf(path, sizeof(path), "%s", in_dir("deep.exr"));
		struct shot_write_options o = { .tables = SHOT_COMPRESS_ZIP,
						.deep = (enum shot_compression)mode };
		bool ok = shot_write(path, &f, &o, err, sizeof(err));
		CHECK(ok);
		if (!ok) {
			fprintf(stderr, "  %s: %s\n", mode_names[mode], err);
			continue;
		}
		struct shot_file *g = shot_read(path, err, sizeof(err));
		CHECK(g != NULL);
		if (!g) {
			fprintf(stderr, "  %s: %s\n", mode_names[mode], err);
			continue;
		}
		CHECK(same_shot(&f, g));
		const struct shot_deep *d = shot_find_deep(g, "indirect");
		CHECK(d && d->offsets[37 * 23] == f.deeps[0].offsets[37 * 23]);
		CHECK(d && d->offsets[37 * 2] == d->offsets[37]);  /* line 1 is empty */
		d = shot_find_deep(g, "empty");
		CHECK(d && d->offsets[20] == 0 && d->channels[0].data != NULL);
		CHECK(shot_find_table(g, "indirect") == NULL && shot_find_deep(g, "samples") == NULL);
		CHECK(g->part_bytes[1] > 0 && g->part_bytes[2] > 0 && g->part_bytes[3] > 0);
		shot_free(g);
	}

	/* A file of one deep part alone. */
	struct shot_file one = { .metadata = f.metadata, .deeps = f.deeps, .ndeeps = 1 };
	char err[512] = "";
	CHECK(shot_write(in_dir("deep1.exr"), &one, NULL, err, sizeof(err)));
	struct shot_file *g = shot_read(in_dir("deep1.exr"), err, sizeof(err));
	CHECK(g && g->ndeeps == 1 && g->ntables == 0 && same_deep(&f.deeps[0], &g->deeps[0]));
	shot_free(g);

	/* Deep parts take no ZIP. */
	struct shot_write_options zip = { .deep = SHOT_COMPRESS_ZIP };
	CHECK(!shot_write(in_dir("deep2.exr"), &f, &zip, err, sizeof(err)));
	CHECK(strstr(err, "deep2.exr: cannot write: deep parts take NONE, RLE or ZIPS") == err ||
	      strstr(err, "deep parts take NONE, RLE or ZIPS") != NULL);
	CHECK(access(in_dir("deep2.exr"), F_OK) != 0);
	unlink(in_dir("deep.exr"));
	unlink(in_dir("deep1.exr"));
	free_built(&f);
}

/* Channel names past OpenEXR's 31 characters need its long-name flag. */
static void test_long_names(void)
{
	char name[256];
	memset(name, 'x', 255);
	name[255] = '\0';
	name[0] = 'A';
	struct shot_file f = { 0 };
	f.metadata = strdup("{}");
	f.ntables = 1;
	f.tables = calloc(1, sizeof(*f.tables));
	make_table(&f.tables[0], "long", 100);
	free(f.tables[0].channels[1].name);
	f.tables[0].channels[1].name = strdup(name);
	free(f.tables[0].channels[2].name);
	f.tables[0].channels[2].name = strdup("a_channel_name_of_forty_characters_long");
	char err[512] = "", path[600];
	snprintf(path, sizeof(path), "%s", in_dir("long.exr"));
	CHECK(shot_write(path, &f, NULL, err, sizeof(err)));
	struct shot_file *g = shot_read(path, err, sizeof(err));
	CHECK(same_shot(&f, g));
	CHECK(g && strlen(g->tables[0].channels[0].name) == 255);
	shot_free(g);
	/* 256 characters is too many. */
	char *saved = f.tables[0].channels[2].name;
	char longer[257];
	memset(longer, 'y', 256);
	longer[256] = '\0';
	f.tables[0].channels[2].name = longer;
	CHECK(!shot_write(path, &f, NULL, err, sizeof(err)) && strstr(err, "invalid channel name"));
	f.tables[0].channels[2].name = saved;
	unlink(path);
	free_built(&f);
}

static void test_metadata(void)
{
	/* ~600 KB of JSON with every character that needs care. */
	const char *piece = "{\"glsl\": \"uniform vec3 Cl;\\nvoid main() { /* \\\"q\\\" */ }\", "
			    "\"path\": \"C:\\\\shots\\\\a\", \"utf8\": \"\xc3\xa9\xe2\x82\xac\xf0\x9f\x92\xa1\", "
			    "\"ctl\": \"\t\r\n\x01\x7f\"}\n";
	size_t plen = strlen(piece), reps = 600000 / plen + 1;
	char *meta = malloc(plen * reps + 1);
	for (size_t i = 0; i < reps; i++)
		memcpy(meta + i * plen, piece, plen);
	meta[plen * reps] = '\0';
	struct shot_file f = { 0 };
	f.metadata = meta;
	f.ntables = 1;
	f.tables = calloc(1, sizeof(*f.tables));
	make_table(&f.tables[0], "t", 10);
	char err[512] = "";
	CHECK(shot_write(in_dir("meta.exr"), &f, NULL, err, sizeof(err)));
	struct shot_file *g = shot_read(in_dir("meta.exr"), err, sizeof(err));
	CHECK(g && strlen(g->metadata) == plen * reps && same_shot(&f, g));
	shot_free(g);
	g = shot_read_header(in_dir("meta.exr"), err, sizeof(err));
	CHECK(g && !strcmp(g->metadata, meta));
	shot_free(g);

	/* Empty metadata is metadata too. */
	free(f.metadata);
	f.metadata = strdup("");
	CHECK(shot_write(in_dir("meta.exr"), &f, NULL, err, sizeof(err)));
	g = shot_read(in_dir("meta.exr"), err, sizeof(err));
	CHECK(g && g->metadata[0] == '\0');
	shot_free(g);
	unlink(in_dir("meta.exr"));
	free_built(&f);
}

/* ------------------------------------------------------------------------ */
/* Conversions                                                               */

/* Write @n values of channel type @type and read them back into @out. */
static bool through_file(enum shot_type type, const float *in, size_t n, float *out)
{
	struct shot_channel ch = { .name = "v", .type = type, .data = (void *)in };
	struct shot_table t = { .name = "conv", .nrows = n, .nchannels = 1, .channels = &ch };
	struct shot_file f = { .metadata = "", .tables = &t, .ntables = 1 };
	char err[512];
	if (!shot_write(in_dir("conv.exr"), &f, NULL, err, sizeof(err))) {
		fprintf(stderr, "  %s\n", err);
		return false;
	}
	struct shot_file *g = shot_read(in_dir("conv.exr"), err, sizeof(err));
	if (!g) {
		fprintf(stderr, "  %s\n", err);
		return false;
	}
	memcpy(out, g->tables[0].channels[0].data, n * 4);
	shot_free(g);
	unlink(in_dir("conv.exr"));
	return true;
}

static bool same_bits(float a, float b)
{
	return !memcmp(&a, &b, 4);
}

static void test_half(void)
{
	/* Every finite half exactly; every midpoint to the even neighbour; just off it to the nearer. */
	size_t n = 0, cap = 65536 * 4;
	float *in = malloc(cap * 4), *want = malloc(cap * 4), *out = malloc(cap * 4);
	for (uint32_t h = 0; h < 0x10000; h++) {
		if (((h >> 10) & 31) == 31)
			continue;
		float a = half_value((uint16_t)h);
		in[n] = want[n] = a;
		n++;
		uint32_t nx = h + 1;
		if ((h & 0x7fff) == 0x7bff)
			continue;  /* the largest magnitude: no neighbour above */
		float b = half_value((uint16_t)nx);
		float mid = (float)(((double)a + (double)b) / 2);
		in[n] = mid;
		want[n] = (h & 1) ? b : a;
		n++;
		in[n] = nextafterf(mid, a);
		want[n] = a;
		n++;
		in[n] = nextafterf(mid, b);
		want[n] = b;
		n++;
	}
	/* Clamping and the non-finite values. */
	const float special_in[] = { 65504.0f, 65519.0f, 65520.0f, 70000.0f, 1e30f, INFINITY,
				     -65520.0f, -1e30f, -INFINITY, NAN, -0.0f, 0x1p-25f, 0x1.8p-25f,
				     1e-30f, 0x1.ffcp-15f, 1.0f + 0x1p-11f, 1.0f + 0x3p-11f };
	const float special_want[] = { 65504.0f, 65504.0f, 65504.0f, 65504.0f, 65504.0f, 65504.0f,
				       -65504.0f, -65504.0f, -65504.0f, 0.0f, -0.0f, 0.0f, 0x1p-24f,
				       0.0f, 0x1p-14f, 1.0f, 1.0f + 0x1p-9f };
	size_t ns = sizeof(special_in) / sizeof(special_in[0]);
	for (size_t i = 0; i < ns; i++) {
		in[n] = special_in[i];
		want[n] = special_want[i];
		n++;
	}
	CHECK(through_file(SHOT_HALF, in, n, out));
	size_t bad = 0;
	for (size_t i = 0; i < n; i++) {
		if (!same_bits(out[i], want[i])) {
			if (bad++ < 10)
				fprintf(stderr, "  half(%a) = %a, expected %a\n", (double)in[i],
					(double)out[i], (double)want[i]);
		}
	}
	CHECK(bad == 0);
	/* The caller's NaN and infinity are still there. */
	CHECK(isnan(in[n - ns + 9]) && isinf(in[n - ns + 5]));

	/* Float channels: NaN to 0, infinities to the largest float, everything else exact. */
	const float fin[] = { NAN, INFINITY, -INFINITY, FLT_MAX, -0.0f, 0x1p-149f, 1.5f };
	const float fwant[] = { 0.0f, FLT_MAX, -FLT_MAX, FLT_MAX, -0.0f, 0x1p-149f, 1.5f };
	float fout[7];
	CHECK(through_file(SHOT_FLOAT, fin, 7, fout));
	for (int i = 0; i < 7; i++)
		CHECK(same_bits(fout[i], fwant[i]));
	free(in);
	free(want);
	free(out);
}

/* ------------------------------------------------------------------------ */
/* Invalid input and atomic writes                                           */

static void expect_refused(struct shot_file *f, const struct shot_write_options *o, const char *what)
{
	char err[512] = "";
	char path[600];
	snprintf(path, sizeof(path), "%s", in_dir("bad.exr"));
	CHECK(!shot_write(path, f, o, err, sizeof(err)));
	CHECK(strncmp(err, path, strlen(path)) == 0);
	if (!strstr(err, what)) {
		fprintf(stderr, "  message '%s' lacks '%s'\n", err, what);
		CHECK(strstr(err, what) != NULL);
	}
	CHECK(access(path, F_OK) != 0);
}

static void test_invalid(void)
{
	struct shot_file f;
	make_small(&f);
	char *saved;

	saved = f.tables[1].name;
	f.tables[1].name = "samples.plastic";
	expect_refused(&f, NULL, "part name 'samples.plastic' appears twice");
	f.tables[1].name = "indirect";
	expect_refused(&f, NULL, "part name 'indirect' appears twice");
	f.tables[1].name = "";
	expect_refused(&f, NULL, "invalid name");
	f.tables[1].name = "a\nb";
	expect_refused(&f, NULL, "invalid name");
	f.tables[1].name = saved;

	saved = f.tables[0].channels[1].name;
	f.tables[0].channels[1].name = "z";
	expect_refused(&f, NULL, "channel 'z' appears twice");
	f.tables[0].channels[1].name = "a b";
	expect_refused(&f, NULL, "invalid channel name 'a b'");
	f.tables[0].channels[1].name = "";
	expect_refused(&f, NULL, "invalid channel name");
	f.tables[0].channels[1].name = saved;

	f.tables[0].nchannels = 0;
	expect_refused(&f, NULL, "0 channels");
	f.tables[0].nchannels = 3;
	f.tables[0].channels[2].type = (enum shot_type)9;
	expect_refused(&f, NULL, "no valid type");
	f.tables[0].channels[2].type = SHOT_UINT;

	f.deeps[0].offsets[5] += 100;
	expect_refused(&f, NULL, "offsets decrease");
	f.deeps[0].offsets[5] -= 100;
	f.deeps[0].offsets[0] = 1;
	expect_refused(&f, NULL, "offsets[0] is not 0");
	f.deeps[0].offsets[0] = 0;
	f.deeps[0].width = 0;
	expect_refused(&f, NULL, "size 0x5");
	f.deeps[0].width = 13;

	saved = f.metadata;
	f.metadata = NULL;
	expect_refused(&f, NULL, "no metadata");
	f.metadata = saved;

	struct shot_write_options o = { .tables = (enum shot_compression)7 };
	expect_refused(&f, &o, "unknown table compression");
	struct shot_file none = { .metadata = "" };
	expect_refused(&none, NULL, "0 parts");

	char err[512];
	CHECK(!shot_write(in_dir("no/such/dir/x.exr"), &f, NULL, err, sizeof(err)));
	CHECK(strstr(err, "no/such/dir/x.exr: cannot write") != NULL);
	CHECK(!shot_write("", &f, NULL, err, sizeof(err)));
	CHECK(count_temps() == 0);
	free_built(&f);
}

static void test_atomic(void)
{
	struct shot_file f;
	make_small(&f);
	char err[512] = "";
	char path[600];
	snprintf(path, sizeof(path), "%s", in_dir("keep.exr"));
	CHECK(shot_write(path, &f, NULL, err, sizeof(err)));
	chmod(path, 0640);
	uint8_t *orig = NULL;
	size_t orig_size = 0;
	CHECK(file_bytes(path, &orig, &orig_size));

	/* Invalid input: refused before anything is written. */
	char *saved = f.tables[1].name;
	f.tables[1].name = "indirect";
	CHECK(!shot_write(path, &f, NULL, err, sizeof(err)));
	f.tables[1].name = saved;

	/* A failure in the middle of writing: the file size limit stops the temporary file. */
	struct shot_file big = { 0 };
	big.metadata = strdup("{}");
	big.ntables = 1;
	big.tables = calloc(1, sizeof(*big.tables));
	make_table(&big.tables[0], "big", 200000);
	struct rlimit old;
	getrlimit(RLIMIT_FSIZE, &old);
	struct rlimit lim = { 256 * 1024, old.rlim_max };
	void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
	CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0);
	bool wrote = shot_write(path, &big, NULL, err, sizeof(err));
	setrlimit(RLIMIT_FSIZE, &old);
	signal(SIGXFSZ, prev);
	CHECK(!wrote);
	CHECK(strstr(err, "keep.exr: cannot write: ") != NULL);
	free_built(&big);

	uint8_t *now = NULL;
	size_t now_size = 0;
	CHECK(file_bytes(path, &now, &now_size));
	CHECK(now_size == orig_size && !memcmp(now, orig, orig_size));
	free(now);
	struct shot_file *g = shot_read(path, err, sizeof(err));
	CHECK(same_shot(&f, g));
	shot_free(g);

	/* Replacing it keeps its permissions. */
	CHECK(shot_write(path, &f, NULL, err, sizeof(err)));
	struct stat st;
	CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == 0640);

	/* The target is a directory: the rename fails, the temporary file goes. */
	mkdir(in_dir("adir.exr"), 0755);
	CHECK(!shot_write(in_dir("adir.exr"), &f, NULL, err, sizeof(err)));
	CHECK(strstr(err, "adir.exr: cannot write") != NULL);
	rmdir(in_dir("adir.exr"));

	/* A read-only directory (root writes anyway: then there is nothing to test). */
	mkdir(in_dir("ro"), 0755);
	CHECK(shot_write(in_dir("ro/keep.exr"), &f, NULL, err, sizeof(err)));
	chmod(in_dir("ro"), 0555);
	if (geteuid() != 0) {
		CHECK(!shot_write(in_dir("ro/keep.exr"), &f, NULL, err, sizeof(err)));
		CHECK(strstr(err, "ro/keep.exr: cannot write: cannot create a temporary file") != NULL);
		g = shot_read(in_dir("ro/keep.exr"), err, sizeof(err));
		CHECK(same_shot(&f, g));
		shot_free(g);
	} else {
		printf("note: running as root, the read-only directory case is skipped\n");
	}
	chmod(in_dir("ro"), 0755);
	unlink(in_dir("ro/keep.exr"));
	rmdir(in_dir("ro"));

	CHECK(count_temps() == 0);
	unlink(path);
	free(orig);
	free_built(&f);
}

/* ------------------------------------------------------------------------ */
/* Damaged and foreign files                                                 */

static bool has(const char *err, const char *what)
{
	if (strstr(err, what))
		return true;
	fprintf(stderr, "  message '%s' lacks '%s'\n", err, what);
	return false;
}

static void test_truncated(void)
{
	struct shot_file f;
	make_small(&f);
	for (int mode = 0; mode < 2; mode++) {
		char err[512] = "";
		char path[600];
		snprintf(path, sizeof(path), "%s", in_dir("trunc.exr"));
		struct shot_write_options o = { .tables = mode ? SHOT_COMPRESS_ZIP : SHOT_COMPRESS_NONE,
						.deep = mode ? SHOT_COMPRESS_ZIPS : SHOT_COMPRESS_NONE };
		CHECK(shot_write(path, &f, &o, err, sizeof(err)));
		uint8_t *data;
		size_t size;
		CHECK(file_bytes(path, &data, &size));
		/* Where the header ends: the metadata string is in it. */
		const char *meta = "\"glsl\": \"void main() {}\"}";
		size_t header_end = 0;
		for (size_t i = 0; i + strlen(meta) < size; i++)
			if (!memcmp(data + i, meta, strlen(meta)))
				header_end = i + strlen(meta) + 200;
		CHECK(header_end > 0 && header_end < size);
		size_t cuts[] = { 0, 3, 7, 8, 40, 150, header_end / 2, header_end, header_end + 100,
				  size / 2, size - 100, size - 9, size - 1 };
		for (size_t k = 0; k < sizeof(cuts) / sizeof(cuts[0]); k++) {
			size_t cut = cuts[k];
			const char *tp = in_dir("cut.exr");
			CHECK(put_bytes(tp, data, cut));
			struct shot_file *g = shot_read(tp, err, sizeof(err));
			CHECK(g == NULL);
			shot_free(g);
			CHECK(strncmp(err, tp, strlen(tp)) == 0);
			if (cut < 8)
				CHECK(has(err, "not an OpenEXR file"));
			else
				CHECK(has(err, "truncated"));
			/* shot_read_header() too refuses what it can see is missing. */
			g = shot_read_header(tp, err, sizeof(err));
			if (cut <= header_end + 100)
				CHECK(g == NULL);
			shot_free(g);
		}
		/* Bytes appended do no harm. */
		uint8_t *longer = malloc(size + 100);
		memcpy(longer, data, size);
		memset(longer + size, 0xab, 100);
		struct shot_file *g = shot_read_buffer("longer", longer, size + 100, false, err,
						       sizeof(err));
		CHECK(same_shot(&f, g));
		shot_free(g);
		free(longer);
		free(data);
		unlink(in_dir("cut.exr"));
		unlink(path);
	}
	free_built(&f);
}

/*
 * Flip one bit at many places, in the header and in the data: every file so
 * damaged is refused, or (where the byte is one the reader never uses)
 * read back identical.
 */
static void test_bitflips(void)
{
	struct shot_file f;
	make_small(&f);
	for (int mode = 0; mode < 3; mode++) {
		char err[512] = "";
		char path[600];
		snprintf(path, sizeof(path), "%s", in_dir("flip.exr"));
		static const enum shot_compression tm[] = { SHOT_COMPRESS_NONE, SHOT_COMPRESS_ZIP,
							    SHOT_COMPRESS_RLE };
		static const enum shot_compression dm[] = { SHOT_COMPRESS_NONE, SHOT_COMPRESS_ZIPS,
							    SHOT_COMPRESS_RLE };
		struct shot_write_options o = { .tables = tm[mode], .deep = dm[mode] };
		CHECK(shot_write(path, &f, &o, err, sizeof(err)));
		uint8_t *data;
		size_t size;
		CHECK(file_bytes(path, &data, &size));
		int refused = 0, same = 0, wrong = 0;
		/* Every byte of the first 4 KiB (the header), then every 7th. */
		for (size_t i = 0; i < size; i += i < 4096 ? 1 : 7) {
			uint8_t bit = (uint8_t)(1u << (i % 8));
			data[i] ^= bit;
			struct shot_file *g = shot_read_buffer("flip", data, size, false, err, sizeof(err));
			if (!g) {
				refused++;
				if (strncmp(err, "flip: ", 6) != 0) {
					fprintf(stderr, "  bad message at %zu: '%s'\n", i, err);
					wrong++;
				}
			} else if (same_shot(&f, g)) {
				same++;
			} else {
				fprintf(stderr, "  flipped bit at byte %zu read back different data\n", i);
				wrong++;
			}
			shot_free(g);
			/* The header-only reader must survive it too. */
			g = shot_read_buffer("flip", data, size, true, err, sizeof(err));
			shot_free(g);
			data[i] ^= bit;
		}
		CHECK(wrong == 0);
		CHECK(refused > same);
		printf("bit flips (%s): %d refused, %d inert\n", mode_names[tm[mode]], refused, same);
		free(data);
		unlink(path);
	}
	free_built(&f);
}

/* Replace the int value of attribute @name (every occurrence) in the file's bytes. */
static int patch_int_attr(uint8_t *data, size_t size, const char *name, int32_t value)
{
	size_t nl = strlen(name) + 1;
	int n = 0;
	for (size_t i = 0; i + nl + 4 + 4 + 4 <= size; i++) {
		if (memcmp(data + i, name, nl) || memcmp(data + i + nl, "int", 4))
			continue;
		memcpy(data + i + nl + 4 + 4, &value, 4);
		n++;
	}
	return n;
}

static void test_foreign(void)
{
	char err[512] = "";
	struct shot_file f;
	make_small(&f);
	char path[600];
	snprintf(path, sizeof(path), "%s", in_dir("ver.exr"));
	CHECK(shot_write(path, &f, NULL, err, sizeof(err)));
	uint8_t *data;
	size_t size;
	CHECK(file_bytes(path, &data, &size));
	CHECK(patch_int_attr(data, size, "relight.format", 7) == 3);
	CHECK(put_bytes(path, data, size));
	struct shot_file *g = shot_read(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "ver.exr: format version 7, this relight reads 1"));
	shot_free(g);
	g = shot_read_header(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "format version 7, this relight reads 1"));
	shot_free(g);
	free(data);

	/* Not OpenEXR at all. */
	snprintf(path, sizeof(path), "%s", in_dir("text.exr"));
	const char *text = "{\"this\": \"is JSON, not OpenEXR\"}\n";
	CHECK(put_bytes(path, text, strlen(text)));
	g = shot_read(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "text.exr: not an OpenEXR file"));
	CHECK(put_bytes(path, "", 0));
	g = shot_read(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "not an OpenEXR file"));
	g = shot_read(in_dir("missing.exr"), err, sizeof(err));
	CHECK(g == NULL && has(err, "missing.exr: cannot read: No such file or directory"));
	g = shot_read(dir, err, sizeof(err));
	CHECK(g == NULL && has(err, "not a regular file"));

	/* An OpenEXR image from the renderer. */
	struct reyes_image im;
	CHECK(reyes_image_init(&im, 8, 4, 4, NULL));
	for (size_t i = 0; i < 8 * 4 * 4; i++)
		im.data[i] = (float)i / 128.0f;
	snprintf(path, sizeof(path), "%s", in_dir("image.exr"));
	FILE *devnull = fopen("/dev/null", "w");
	CHECK(reyes_image_write_exr(path, &im, true, devnull));
	fclose(devnull);
	reyes_image_finish(&im);
	g = shot_read(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "image.exr: not a shot file"));
	g = shot_read_header(path, err, sizeof(err));
	CHECK(g == NULL && has(err, "not a shot file"));

	unlink(in_dir("ver.exr"));
	unlink(in_dir("text.exr"));
	unlink(in_dir("image.exr"));
	free_built(&f);
}

/* ------------------------------------------------------------------------ */
/* OpenEXR's view of a written file                                          */

static void test_exrheader(void)
{
	const char *tool = "/usr/bin/exrheader";
	if (access(tool, X_OK) != 0) {
		printf("note: %s not installed (Debian package openexr): check skipped\n", tool);
		return;
	}
	struct shot_file f;
	make_small(&f);
	char err[512];
	char path[600];
	snprintf(path, sizeof(path), "%s", in_dir("hdr.exr"));
	struct shot_write_options o = { .tables = SHOT_COMPRESS_ZIP, .deep = SHOT_COMPRESS_ZIPS };
	CHECK(shot_write(path, &f, &o, err, sizeof(err)));
	char cmd[1200];
	snprintf(cmd, sizeof(cmd), "%s '%s' 2>&1", tool, path);
	FILE *p = popen(cmd, "r");
	CHECK(p != NULL);
	if (!p)
		return;
	size_t cap = 1 << 16, len = 0, k;
	char *out = malloc(cap + 1);
	while ((k = fread(out + len, 1, cap - len, p)) > 0) {
		len += k;
		if (len == cap)
			out = realloc(out, (cap *= 2) + 1);
	}
	out[len] = '\0';
	int status = pclose(p);
	CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
	CHECK(strstr(out, " part 2:") != NULL);
	CHECK(strstr(out, "name (type string): \"samples.plastic\"") != NULL);
	CHECK(strstr(out, "name (type string): \"indirect\"") != NULL);
	CHECK(strstr(out, "type (type string): \"deepscanline\"") != NULL);
	CHECK(strstr(out, "relight.format (type int): 1") != NULL);
	CHECK(strstr(out, "compression (type compression): zip, multi-scanline blocks") != NULL);
	CHECK(strstr(out, "dataWindow (type box2i): (0 0) - (1023 1)") != NULL);
	free(out);
	unlink(path);
	free_built(&f);
}

/* A stored value (half bits, float bits, uint) equals entry @i of channel @sc. */
static bool stored_matches(const uint8_t *v, int bytes, const struct shot_channel *sc, uint64_t i)
{
	if (sc->type == SHOT_HALF) {
		uint16_t h;
		memcpy(&h, v, 2);
		return bytes == 2 && same_bits(half_value(h), ((float *)sc->data)[i]);
	}
	return bytes == 4 && !memcmp(v, (uint32_t *)sc->data + i, 4);
}

/*
 * Decode a table part with the OpenEXR Core library's own decompressors
 * and compare with what was written (values as stored: half bits, float
 * bits, uint).
 */
static bool library_table_matches(exr_context_t ctx, int part, const struct shot_table *t)
{
	exr_attr_box2i_t dw;
	if (exr_get_data_window(ctx, part, &dw) != EXR_ERR_SUCCESS)
		return false;
	int32_t lpc = 1;
	exr_get_scanlines_per_chunk(ctx, part, &lpc);
	exr_decode_pipeline_t pipe = EXR_DECODE_PIPELINE_INITIALIZER;
	bool started = false, ok = true;
	uint8_t *buf = malloc((size_t)SHOT_TABLE_WIDTH * 16 * 4 * t->nchannels);
	for (int y = 0; y <= dw.max.y && ok; y += lpc) {
		exr_chunk_info_t ci;
		ok = exr_read_scanline_chunk_info(ctx, part, y, &ci) == EXR_ERR_SUCCESS;
		if (ok)
			ok = (started ? exr_decoding_update(ctx, part, &ci, &pipe)
				      : exr_decoding_initialize(ctx, part, &ci, &pipe)) == EXR_ERR_SUCCESS;
		if (!ok)
			break;
		size_t off = 0;
		for (int c = 0; c < pipe.channel_count; c++) {
			exr_coding_channel_info_t *ch = &pipe.channels[c];
			ch->user_bytes_per_element = ch->bytes_per_element;
			ch->user_data_type = ch->data_type;
			ch->user_pixel_stride = ch->bytes_per_element;
			ch->user_line_stride = ch->width * ch->bytes_per_element;
			ch->decode_to_ptr = buf + off;
			off += (size_t)ch->width * (size_t)ch->height * (size_t)ch->bytes_per_element;
		}
		if (!started) {
			ok = exr_decoding_choose_default_routines(ctx, part, &pipe) == EXR_ERR_SUCCESS;
			started = true;
		}
		if (ok)
			ok = exr_decoding_run(ctx, part, &pipe) == EXR_ERR_SUCCESS;
		off = 0;
		for (int c = 0; c < pipe.channel_count && ok; c++) {
			const exr_coding_channel_info_t *ch = &pipe.channels[c];
			const struct shot_channel *sc =
				find_channel(t->channels, t->nchannels, ch->channel_name);
			ok = sc != NULL;
			for (int l = 0; l < ci.height && ok; l++) {
				for (int x = 0; x < SHOT_TABLE_WIDTH && ok; x++) {
					uint64_t row = (uint64_t)(y + l) * SHOT_TABLE_WIDTH + (uint64_t)x;
					const uint8_t *v = buf + off +
							   ((size_t)l * SHOT_TABLE_WIDTH + (size_t)x) *
								   (size_t)ch->bytes_per_element;
					if (row >= t->nrows) {
						uint32_t z = 0;
						ok = !memcmp(v, &z, (size_t)ch->bytes_per_element);
					} else {
						ok = stored_matches(v, ch->bytes_per_element, sc, row);
					}
				}
			}
			off += (size_t)ch->width * (size_t)ch->height * (size_t)ch->bytes_per_element;
		}
	}
	if (started)
		exr_decoding_destroy(ctx, &pipe);
	free(buf);
	return ok;
}

/*
 * The same for a deep part, line by line in two passes as OpenEXR 3.1
 * needs: the cumulative sample counts first, then the entries.
 */
static bool library_deep_matches(exr_context_t ctx, int part, const struct shot_deep *d)
{
	exr_decode_pipeline_t pipe = EXR_DECODE_PIPELINE_INITIALIZER;
	bool started = false, ok = true;
	uint8_t *buf = NULL;
	for (uint32_t y = 0; y < d->height && ok; y++) {
		exr_chunk_info_t ci;
		ok = exr_read_scanline_chunk_info(ctx, part, (int)y, &ci) == EXR_ERR_SUCCESS;
		if (ok)
			ok = (started ? exr_decoding_update(ctx, part, &ci, &pipe)
				      : exr_decoding_initialize(ctx, part, &ci, &pipe)) == EXR_ERR_SUCCESS;
		if (!ok)
			break;
		pipe.decode_flags |= EXR_DECODE_SAMPLE_DATA_ONLY;
		for (int c = 0; c < pipe.channel_count; c++)
			pipe.channels[c].decode_to_ptr = NULL;
		if (!started) {
			ok = exr_decoding_choose_default_routines(ctx, part, &pipe) == EXR_ERR_SUCCESS;
			started = true;
		}
		ok = ok && exr_decoding_run(ctx, part, &pipe) == EXR_ERR_SUCCESS;
		const uint64_t *o = d->offsets + (size_t)y * d->width;
		for (uint32_t x = 0; x < d->width && ok; x++)
			ok = (uint64_t)pipe.sample_count_table[x] == o[x + 1] - o[0];
		if (!ok)
			break;
		size_t n = (size_t)(o[d->width] - o[0]);
		pipe.decode_flags &= ~EXR_DECODE_SAMPLE_DATA_ONLY;
		free(buf);
		buf = malloc(n * 4 * (size_t)pipe.channel_count + 4);
		size_t off = 0;
		for (int c = 0; c < pipe.channel_count; c++) {
			exr_coding_channel_info_t *ch = &pipe.channels[c];
			ch->user_bytes_per_element = ch->bytes_per_element;
			ch->user_data_type = ch->data_type;
			ch->user_pixel_stride = ch->bytes_per_element;
			ch->user_line_stride = 0;
			ch->decode_to_ptr = buf + off;
			off += n * (size_t)ch->bytes_per_element;
		}
		ok = exr_decoding_choose_default_routines(ctx, part, &pipe) == EXR_ERR_SUCCESS &&
		     exr_decoding_run(ctx, part, &pipe) == EXR_ERR_SUCCESS;
		off = 0;
		for (int c = 0; c < pipe.channel_count && ok; c++) {
			const exr_coding_channel_info_t *ch = &pipe.channels[c];
			const struct shot_channel *sc =
				find_channel(d->channels, d->nchannels, ch->channel_name);
			ok = sc != NULL;
			for (size_t i = 0; i < n && ok; i++)
				ok = stored_matches(buf + off + i * (size_t)ch->bytes_per_element,
						    ch->bytes_per_element, sc, o[0] + i);
			off += n * (size_t)ch->bytes_per_element;
		}
	}
	if (started)
		exr_decoding_destroy(ctx, &pipe);
	free(buf);
	return ok;
}

static void test_library_decode(void)
{
	struct shot_file f = { 0 };
	f.metadata = strdup("{}");
	f.ntables = 2;
	f.tables = calloc(2, sizeof(*f.tables));
	make_table(&f.tables[0], "a", 5000);
	make_table(&f.tables[1], "b", 40000);
	/* All-half channels: the layout OpenEXR 3.1's unpacker special-cases. */
	for (uint32_t c = 0; c < 3; c++) {
		f.tables[1].channels[c].type = SHOT_HALF;
		for (uint64_t i = 0; i < 40000; i++)
			((float *)f.tables[1].channels[c].data)[i] = half_value(random_half());
	}
	for (int mode = SHOT_COMPRESS_NONE; mode <= SHOT_COMPRESS_ZIP; mode++) {
		char err[512];
		char path[600];
		snprintf(path, sizeof(path), "%s", in_dir("lib.exr"));
		struct shot_write_options o = { .tables = (enum shot_compression)mode };
		CHECK(shot_write(path, &f, &o, err, sizeof(err)));
		exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
		exr_context_t ctx = NULL;
		CHECK(exr_start_read(&ctx, path, &init) == EXR_ERR_SUCCESS);
		if (!ctx)
			continue;
		bool a = library_table_matches(ctx, 0, &f.tables[0]);
		bool b = library_table_matches(ctx, 1, &f.tables[1]);
		if (!a || !b)
			fprintf(stderr, "  OpenEXR decodes %s tables differently\n", mode_names[mode]);
		CHECK(a && b);
		exr_finish(&ctx);
		unlink(path);
	}

	/* Deep parts, in their three modes, beside a table. */
	f.ndeeps = 2;
	f.deeps = calloc(2, sizeof(*f.deeps));
	make_deep(&f.deeps[0], "indirect", 37, 23, 1);
	make_deep(&f.deeps[1], "one", 1, 1, 2);
	for (int mode = SHOT_COMPRESS_NONE; mode <= SHOT_COMPRESS_ZIPS; mode++) {
		char err[512], path[600];
		snprintf(path, sizeof(path), "%s", in_dir("libdeep.exr"));
		struct shot_write_options o = { .deep = (enum shot_compression)mode };
		CHECK(shot_write(path, &f, &o, err, sizeof(err)));
		exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
		exr_context_t ctx = NULL;
		CHECK(exr_start_read(&ctx, path, &init) == EXR_ERR_SUCCESS);
		if (!ctx)
			continue;
		bool a = library_deep_matches(ctx, 2, &f.deeps[0]);
		bool b = library_deep_matches(ctx, 3, &f.deeps[1]);
		if (!a || !b)
			fprintf(stderr, "  OpenEXR decodes %s deep parts differently\n", mode_names[mode]);
		CHECK(a && b);
		exr_finish(&ctx);
		unlink(path);
	}
	free_built(&f);
}

int main(void)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(dir, sizeof(dir), "%s/test_shotfile.XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
	if (!mkdtemp(dir)) {
		perror(dir);
		return 1;
	}
	RUN(test_hash);
	RUN(test_tables);
	RUN(test_deep);
	RUN(test_long_names);
	RUN(test_metadata);
	RUN(test_half);
	RUN(test_invalid);
	RUN(test_atomic);
	RUN(test_truncated);
	RUN(test_bitflips);
	RUN(test_foreign);
	RUN(test_exrheader);
	RUN(test_library_decode);
	CHECK(count_temps() == 0);
	if (rmdir(dir) != 0) {
		fprintf(stderr, "%s: left files behind\n", dir);
		CHECK(false);
	}
	return test_finish();
}

/*
 * The GPU module on whatever EGL finds (llvmpipe without a GPU): compute
 * dispatch in 1D and 2D with exact results, uniforms of each kind, compile
 * errors with numbered source, the program cache, buffer ranges, offline
 * validation, timings (printed, not checked) and the arithmetic
 * micro-benchmark, whose results are checked against the CPU. Skips (77)
 * without EGL.
 */
#include "gpu.h"
#include "clock.h"
#include "microbench.h"
#include "test.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static struct gpu_ctx *ctx;

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(*v), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Everything written to @f so far, NUL-terminated (free it). */
static char *slurp(FILE *f)
{
	long n = ftell(f);
	if (n < 0)
		return NULL;
	char *s = calloc((size_t)n + 1, 1);
	rewind(f);
	if (s && fread(s, 1, (size_t)n, f) != (size_t)n)
		s[0] = '\0';
	return s;
}

/* The index of gpu.h's dispatch convention; u_count of type @count_type. */
#define SQUARE_SHADER(count_type) \
	"#version 430 core\n" \
	"layout(local_size_x = 64) in;\n" \
	"layout(binding = 0) uniform samplerBuffer u_in;\n" \
	"layout(std430, binding = 1) writeonly buffer Out { float v[]; } u_out;\n" \
	"uniform " count_type " u_count;\n" \
	"void main()\n" \
	"{\n" \
	"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n" \
	"	if (i >= uint(u_count))\n" \
	"		return;\n" \
	"	float x = texelFetch(u_in, int(i)).r;\n" \
	"	u_out.v[i] = x * x;\n" \
	"}\n"

static const char square_int_src[] = SQUARE_SHADER("int");
static const char square_uint_src[] = SQUARE_SHADER("uint");

/* Square n floats on the GPU; 64 floats past the end must stay untouched. */
static void square(const char *src, uint32_t n, bool timed)
{
	struct gpu_program *p = gpu_program(ctx, src, NULL);
	CHECK(p != NULL);
	float *in = malloc(n * sizeof(float));
	float *out = malloc((n + 64) * sizeof(float));
	if (!p || !in || !out) {
		free(in);
		free(out);
		CHECK(!"setup");
		return;
	}
	/* Quarter steps up to 1000: the squares are exact in binary32. */
	for (uint32_t i = 0; i < n; i++)
		in[i] = (float)(int)(i % 4001 - 2000) * 0.25f;
	for (uint32_t i = 0; i < n + 64; i++)
		out[i] = -1.0f;
	struct gpu_buffer *bin = gpu_buffer_create(ctx, n * sizeof(float), in);
	struct gpu_buffer *bout = gpu_buffer_create(ctx, (n + 64) * sizeof(float), out);
	CHECK(bin && bout);
	struct gpu_binding b[2] = {
		{ .unit = 0, .ssbo = false, .buffer = bin },
		{ .unit = 1, .ssbo = true, .buffer = bout },
	};
	double t0 = rl_now_ms();
	CHECK(gpu_dispatch(ctx, p, b, 2, n));
	CHECK(gpu_buffer_read(bout, 0, (n + 64) * sizeof(float), out));
	double first = rl_now_ms() - t0;
	uint32_t wrong = 0, first_wrong = 0;
	for (uint32_t i = 0; i < n; i++) {
		if (out[i] != in[i] * in[i] && !wrong++)
			first_wrong = i;
	}
	if (wrong)
		fprintf(stderr, "n=%u: %u wrong, first at %u: %g, expected %g\n", n, wrong,
			first_wrong, out[first_wrong], in[first_wrong] * in[first_wrong]);
	CHECK(wrong == 0);
	uint32_t past = 0;
	for (uint32_t i = n; i < n + 64; i++)
		past += out[i] != -1.0f;
	CHECK(past == 0);

	if (timed) {
		/* Dispatch then a 4-byte read, which waits for the kernel. */
		double t[7];
		float one;
		for (int r = 0; r < 7; r++) {
			double s = rl_now_ms();
			gpu_dispatch(ctx, p, b, 2, n);
			gpu_buffer_read(bout, 0, sizeof(one), &one);
			t[r] = rl_now_ms() - s;
		}
		double m = median(t, 7);
		printf("square of %u floats: first run %.2f ms (with readback of %.1f MB), kernel "
		       "median %.2f ms (%.2f GB/s read+write)\n", n, first,
		       (double)n * 4 / 1e6, m, (double)n * 8 / (m * 1e6));
	}
	gpu_buffer_destroy(bin);
	gpu_buffer_destroy(bout);
	free(in);
	free(out);
}

static void test_square_small(void)
{
	square(square_int_src, 1000, false);
	/* Exactly one group, and a partial one. */
	square(square_int_src, 64, false);
	square(square_int_src, 65, false);
}

static void test_square_large(void)
{
	/* 78125 groups: more than 65535, so two rows of groups. */
	square(square_uint_src, 5000000, true);
}

static void test_uniforms(void)
{
	static const char src[] =
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"layout(std430, binding = 2) buffer Out { float v[]; } u_out;\n"
		"uniform float u_f;\n"
		"uniform vec3 u_v;\n"
		"uniform int u_i;\n"
		"uniform mat4 u_m;\n"
		"uniform float u_arr[4];\n"
		"uniform bool u_b;\n"
		"uniform int u_count;\n"
		"void main()\n"
		"{\n"
		"	uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;\n"
		"	if (i >= uint(u_count))\n"
		"		return;\n"
		"	u_out.v[0] = u_f;\n"
		"	u_out.v[1] = u_v.x; u_out.v[2] = u_v.y; u_out.v[3] = u_v.z;\n"
		"	u_out.v[4] = float(u_i);\n"
		"	for (int k = 0; k < 16; k++)\n"
		"		u_out.v[5 + k] = u_m[k / 4][k % 4];\n"
		"	vec4 q = u_m * vec4(1.0, 2.0, 3.0, 1.0);\n"
		"	u_out.v[21] = q.x; u_out.v[22] = q.y; u_out.v[23] = q.z; u_out.v[24] = q.w;\n"
		"	for (int k = 0; k < 4; k++)\n"
		"		u_out.v[25 + k] = u_arr[k];\n"
		"	u_out.v[29] = u_b ? 1.0 : 0.0;\n"
		"}\n";
	struct gpu_program *p = gpu_program(ctx, src, NULL);
	CHECK(p != NULL);
	if (!p)
		return;
	const float f = 2.5f, v[3] = { -1.0f, 0.5f, 1e6f }, arr[4] = { 1, 2, 3, 4 };
	/* A translation by (10, 20, 30) with a scale of 2: m[4 * col + row]. */
	float m[16] = { 0 };
	m[0] = m[5] = m[10] = 2.0f;
	m[15] = 1.0f;
	m[12] = 10.0f;
	m[13] = 20.0f;
	m[14] = 30.0f;
	CHECK(gpu_uniform_float(p, "u_f", &f, 1));
	CHECK(gpu_uniform_float(p, "u_v", v, 3));
	CHECK(gpu_uniform_int(p, "u_i", -7));
	CHECK(gpu_uniform_mat4(p, "u_m", m));
	CHECK(gpu_uniform_float(p, "u_arr", arr, 4));
	CHECK(gpu_uniform_int(p, "u_b", 1));
	/* One element and the tail of the array by their own names. */
	const float nine = 9.0f, tail[2] = { 7.0f, 8.0f };
	CHECK(gpu_uniform_float(p, "u_arr[1]", &nine, 1));
	CHECK(gpu_uniform_float(p, "u_arr[2]", tail, 2));

	/* Refused: absent names, wrong types, wrong counts. */
	CHECK(!gpu_uniform_float(p, "u_absent", &f, 1));
	CHECK(!gpu_uniform_int(p, "u_absent", 1));
	CHECK(!gpu_uniform_mat4(p, "u_absent", m));
	CHECK(!gpu_uniform_int(p, "u_f", 3));
	CHECK(!gpu_uniform_float(p, "u_i", &f, 1));
	CHECK(!gpu_uniform_float(p, "u_v", v, 2));
	CHECK(!gpu_uniform_float(p, "u_arr", arr, 5));
	CHECK(!gpu_uniform_float(p, "u_arr[3]", tail, 2));
	CHECK(!gpu_uniform_float(p, "u_arr[4]", &f, 1));
	CHECK(!gpu_uniform_mat4(p, "u_v", m));
	CHECK(!gpu_uniform_float(p, "u_f", &f, 0));
	CHECK(!gpu_uniform_float(p, "u_f", NULL, 1));
	CHECK(!gpu_uniform_float(NULL, "u_f", &f, 1));

	float out[30];
	for (int k = 0; k < 30; k++)
		out[k] = -99.0f;
	struct gpu_buffer *b = gpu_buffer_create(ctx, sizeof(out), out);
	CHECK(b != NULL);
	struct gpu_binding bd = { .unit = 2, .ssbo = true, .buffer = b };
	CHECK(gpu_dispatch(ctx, p, &bd, 1, 1));
	CHECK(gpu_buffer_read(b, 0, sizeof(out), out));
	CHECK(out[0] == 2.5f);
	CHECK(out[1] == -1.0f && out[2] == 0.5f && out[3] == 1e6f);
	CHECK(out[4] == -7.0f);
	int same = 0;
	for (int k = 0; k < 16; k++)
		same += out[5 + k] == m[k];
	CHECK(same == 16);
	CHECK(out[21] == 12.0f && out[22] == 24.0f && out[23] == 36.0f && out[24] == 1.0f);
	CHECK(out[25] == 1.0f && out[26] == 9.0f && out[27] == 7.0f && out[28] == 8.0f);
	CHECK(out[29] == 1.0f);

	/* A set value stays set: change one and dispatch again. */
	const float g = -0.125f;
	CHECK(gpu_uniform_float(p, "u_f", &g, 1));
	CHECK(gpu_dispatch(ctx, p, &bd, 1, 1));
	CHECK(gpu_buffer_read(b, 0, 2 * sizeof(float), out));
	CHECK(out[0] == -0.125f && out[1] == -1.0f);
	gpu_buffer_destroy(b);
}

static void test_compile_error(void)
{
	static const char bad[] =
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"layout(std430, binding = 1) buffer Out { float v[]; } u_out;\n"
		"void main()\n"
		"{\n"
		"	u_out.v[0] = undeclared_thing * 2.0;\n"
		"}\n";
	FILE *log = tmpfile();
	CHECK(log != NULL);
	if (!log)
		return;
	CHECK(gpu_program(ctx, bad, log) == NULL);
	char *text = slurp(log);
	CHECK(text != NULL);
	if (text) {
		/* The driver's message, then the numbered source with the bad line. */
		CHECK(strstr(text, "undeclared_thing") != NULL);
		CHECK(strstr(text, "    6| \tu_out.v[0] = undeclared_thing * 2.0;\n") != NULL);
		CHECK(strstr(text, "    1| #version 430 core\n") != NULL);
		CHECK(strstr(text, "    7| }\n") != NULL);
		CHECK(strstr(text, "    8|") == NULL);
	}
	free(text);
	fclose(log);

	/* A failure is not cached: the second try fails the same way. */
	log = tmpfile();
	CHECK(log && gpu_program(ctx, bad, log) == NULL);
	if (log)
		fclose(log);

	/* A link error: no main(). */
	static const char nomain[] =
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"void helper() {}\n";
	log = tmpfile();
	CHECK(log && gpu_program(ctx, nomain, log) == NULL);
	if (log) {
		text = slurp(log);
		CHECK(text && strstr(text, "    3| void helper() {}\n"));
		free(text);
		fclose(log);
	}
}

static void test_cache(void)
{
	struct gpu_program *a = gpu_program(ctx, square_int_src, NULL);
	/* An equal string at another address is the same program. */
	char *copy = malloc(sizeof(square_int_src));
	CHECK(copy != NULL);
	if (!copy)
		return;
	memcpy(copy, square_int_src, sizeof(square_int_src));
	struct gpu_program *b = gpu_program(ctx, copy, NULL);
	CHECK(a != NULL && a == b);
	struct gpu_program *c = gpu_program(ctx, square_uint_src, NULL);
	CHECK(c != NULL && c != a);
	free(copy);

	/* Many programs: the cache grows and keeps every one. */
	struct gpu_program *progs[40];
	char src[512];
	int ok = 0;
	for (int k = 0; k < 40; k++) {
		snprintf(src, sizeof(src),
			 "#version 430 core\nlayout(local_size_x = 64) in;\n"
			 "layout(std430, binding = 1) buffer Out { float v[]; } u_out;\n"
			 "void main() { u_out.v[0] = %d.0; }\n", k);
		progs[k] = gpu_program(ctx, src, NULL);
		ok += progs[k] != NULL;
	}
	CHECK(ok == 40);
	int hits = 0;
	for (int k = 0; k < 40; k++) {
		snprintf(src, sizeof(src),
			 "#version 430 core\nlayout(local_size_x = 64) in;\n"
			 "layout(std430, binding = 1) buffer Out { float v[]; } u_out;\n"
			 "void main() { u_out.v[0] = %d.0; }\n", k);
		hits += gpu_program(ctx, src, NULL) == progs[k];
	}
	CHECK(hits == 40);
	CHECK(gpu_program(ctx, square_int_src, NULL) == a);
}

/* The single *.glprog file in @dir, or false. */
static bool only_entry(const char *dir, char *path, size_t n)
{
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "ls %s/*.glprog 2>/dev/null", dir);
	FILE *p = popen(cmd, "r");
	if (!p)
		return false;
	int count = 0;
	char line[512];
	while (fgets(line, sizeof(line), p)) {
		line[strcspn(line, "\n")] = '\0';
		if (!count++)
			snprintf(path, n, "%s", line);
	}
	pclose(p);
	return count == 1;
}

/* Damage byte @at of @path (from the end when negative) or cut it to @cut bytes. */
static void damage(const char *path, long at, long cut)
{
	FILE *f = fopen(path, "r+b");
	CHECK(f != NULL);
	if (!f)
		return;
	fseek(f, 0, SEEK_END);
	long n = ftell(f);
	if (cut >= 0) {
		fclose(f);
		CHECK(truncate(path, cut) == 0);
		return;
	}
	long pos = at < 0 ? n + at : at;
	fseek(f, pos, SEEK_SET);
	int c = fgetc(f);
	fseek(f, pos, SEEK_SET);
	fputc(c ^ 0x5a, f);
	fclose(f);
}

/*
 * Compiled programs on disk: a new context (as a new process would) loads
 * the binary instead of compiling, and computes the same; a damaged, cut or
 * foreign entry is dropped and the program compiled again.
 */
static void test_disk_cache(void)
{
	char dir[] = "/tmp/relight-glcache-XXXXXX";
	CHECK(mkdtemp(dir) != NULL);
	static const char src[] = SQUARE_SHADER("int") "// disk cache test\n";
	char err[512], path[512];
	/* damage: none, a byte of the binary, a byte of the header, cut short, empty */
	const long at[] = { 0, -7, 20, 0, 0 }, cut[] = { -1, -1, -1, 40, 0 };
	unsigned hits_total = 0, compiled_total = 0;
	for (int round = 0; round < 6; round++) {
		struct gpu_ctx *c = gpu_create(err, sizeof(err));
		CHECK(c != NULL);
		if (!c)
			break;
		gpu_set_program_cache(c, dir);
		double t0 = rl_now_ms();
		struct gpu_program *p = gpu_program(c, src, NULL);
		double ms = rl_now_ms() - t0;
		CHECK(p != NULL);
		unsigned hits, compiled;
		gpu_program_stats(c, &hits, &compiled);
		/* round 0 compiles; round 1 loads; after damage (rounds 2..5) it compiles */
		bool want_hit = round == 1;
		CHECK(hits == (want_hit ? 1u : 0u) && compiled == (want_hit ? 0u : 1u));
		hits_total += hits;
		compiled_total += compiled;
		printf("disk cache round %d: %s in %.2f ms\n", round, hits ? "loaded" : "compiled", ms);
		float in[3] = { 1.5f, -2.0f, 3.0f }, out[3] = { 0 };
		struct gpu_buffer *bi = gpu_buffer_create(c, sizeof(in), in);
		struct gpu_buffer *bo = gpu_buffer_create(c, sizeof(out), out);
		struct gpu_binding b[2] = { { 0, false, bi }, { 1, true, bo } };
		CHECK(p && gpu_dispatch(c, p, b, 2, 3) && gpu_buffer_read(bo, 0, sizeof(out), out));
		CHECK(out[0] == 2.25f && out[1] == 4.0f && out[2] == 9.0f);
		gpu_destroy(c);
		CHECK(only_entry(dir, path, sizeof(path)));
		CHECK(gpu_make_current(ctx));
		if (round >= 1 && round <= 5)
			damage(path, at[round - 1], cut[round - 1]);
	}
	CHECK(hits_total == 1 && compiled_total == 5);
	/* Caching off: nothing written. */
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	CHECK(system(cmd) == 0);
	struct gpu_ctx *c = gpu_create(err, sizeof(err));
	if (c) {
		gpu_set_program_cache(c, NULL);
		CHECK(gpu_program(c, src, NULL) != NULL);
		gpu_destroy(c);
	}
	CHECK(access(dir, F_OK) != 0);
	CHECK(gpu_make_current(ctx));
}

static void test_buffers(void)
{
	unsigned char data[1024], back[1024];
	for (int i = 0; i < 1024; i++)
		data[i] = (unsigned char)(i * 7 + 3);
	struct gpu_buffer *b = gpu_buffer_create(ctx, sizeof(data), data);
	CHECK(b != NULL);
	if (!b)
		return;
	CHECK(gpu_buffer_read(b, 0, sizeof(back), back));
	CHECK(memcmp(back, data, sizeof(data)) == 0);

	unsigned char patch[37];
	for (int i = 0; i < 37; i++)
		patch[i] = (unsigned char)(200 + i);
	CHECK(gpu_buffer_write(b, 101, sizeof(patch), patch));
	memcpy(data + 101, patch, sizeof(patch));
	memset(back, 0, sizeof(back));
	CHECK(gpu_buffer_read(b, 0, sizeof(back), back));
	CHECK(memcmp(back, data, sizeof(data)) == 0);
	/* A read at an offset that straddles the written range. */
	unsigned char part[50];
	CHECK(gpu_buffer_read(b, 90, sizeof(part), part));
	CHECK(memcmp(part, data + 90, sizeof(part)) == 0);
	/* The last byte, and empty ranges at the end. */
	CHECK(gpu_buffer_read(b, 1023, 1, part));
	CHECK(part[0] == data[1023]);
	CHECK(gpu_buffer_read(b, 1024, 0, part));
	CHECK(gpu_buffer_write(b, 1024, 0, patch));

	/* Out of range, overflowing, NULL: refused, the contents unchanged. */
	CHECK(!gpu_buffer_write(b, 1000, 25, patch));
	CHECK(!gpu_buffer_write(b, 1025, 0, patch));
	CHECK(!gpu_buffer_write(b, SIZE_MAX, 2, patch));
	CHECK(!gpu_buffer_write(b, 2, SIZE_MAX, patch));
	CHECK(!gpu_buffer_read(b, 1020, 5, part));
	CHECK(!gpu_buffer_read(b, 0, 1, NULL));
	CHECK(!gpu_buffer_write(NULL, 0, 1, patch));
	CHECK(!gpu_buffer_read(NULL, 0, 1, part));
	CHECK(gpu_buffer_read(b, 0, sizeof(back), back));
	CHECK(memcmp(back, data, sizeof(data)) == 0);

	/* No initial data; an impossible size. */
	struct gpu_buffer *e = gpu_buffer_create(ctx, 64, NULL);
	CHECK(e != NULL);
	CHECK(gpu_buffer_write(e, 0, 64, data));
	CHECK(gpu_buffer_read(e, 0, 64, back));
	CHECK(memcmp(back, data, 64) == 0);
	CHECK(gpu_buffer_create(ctx, SIZE_MAX, NULL) == NULL);
	CHECK(gpu_buffer_create(NULL, 16, NULL) == NULL);
	gpu_buffer_destroy(b);
	gpu_buffer_destroy(NULL);
	/* @e is left for gpu_destroy to free. */
}

static void test_dispatch_errors(void)
{
	struct gpu_program *p = gpu_program(ctx, square_int_src, NULL);
	struct gpu_buffer *buf = gpu_buffer_create(ctx, 256, NULL);
	CHECK(p && buf);
	struct gpu_binding ok[2] = {
		{ .unit = 0, .ssbo = false, .buffer = buf },
		{ .unit = 1, .ssbo = true, .buffer = buf },
	};
	/* Nothing to do is not an error. */
	CHECK(gpu_dispatch(ctx, p, ok, 2, 0));
	struct gpu_binding none = { .unit = 1, .ssbo = true, .buffer = NULL };
	CHECK(!gpu_dispatch(ctx, p, &none, 1, 10));
	struct gpu_binding far = { .unit = 100000, .ssbo = true, .buffer = buf };
	CHECK(!gpu_dispatch(ctx, p, &far, 1, 10));
	far.ssbo = false;
	CHECK(!gpu_dispatch(ctx, p, &far, 1, 10));
	CHECK(!gpu_dispatch(ctx, p, NULL, 2, 10));
	CHECK(!gpu_dispatch(ctx, NULL, ok, 2, 10));
	CHECK(!gpu_dispatch(NULL, p, ok, 2, 10));
	/* u_count is an int here: 2^31 and more does not fit. */
	CHECK(!gpu_dispatch(ctx, p, ok, 2, 0x80000000u));

	/* A local size other than 64 breaks the index convention. */
	static const char wide[] =
		"#version 430 core\n"
		"layout(local_size_x = 32) in;\n"
		"layout(std430, binding = 1) buffer Out { float v[]; } u_out;\n"
		"void main() { u_out.v[gl_GlobalInvocationID.x] = 1.0; }\n";
	struct gpu_program *w = gpu_program(ctx, wide, NULL);
	CHECK(w != NULL);
	CHECK(!gpu_dispatch(ctx, w, &ok[1], 1, 10));

	/* Still working after all that. */
	float in[3] = { 1.5f, -2.0f, 3.0f }, out[3] = { 0 };
	CHECK(gpu_buffer_write(buf, 0, sizeof(in), in));
	struct gpu_buffer *o = gpu_buffer_create(ctx, sizeof(out), NULL);
	ok[1].buffer = o;
	CHECK(gpu_dispatch(ctx, p, ok, 2, 3));
	CHECK(gpu_buffer_read(o, 0, sizeof(out), out));
	CHECK(out[0] == 2.25f && out[1] == 4.0f && out[2] == 9.0f);
	gpu_buffer_destroy(o);
	gpu_buffer_destroy(buf);
}

static void test_overhead(void)
{
	struct gpu_program *p = gpu_program(ctx, square_int_src, NULL);
	float in[64], out[64];
	for (int i = 0; i < 64; i++)
		in[i] = (float)i;
	struct gpu_buffer *bin = gpu_buffer_create(ctx, sizeof(in), in);
	struct gpu_buffer *bout = gpu_buffer_create(ctx, sizeof(out), NULL);
	CHECK(p && bin && bout);
	struct gpu_binding b[2] = {
		{ .unit = 0, .ssbo = false, .buffer = bin },
		{ .unit = 1, .ssbo = true, .buffer = bout },
	};
	enum { RUNS = 201 };
	static double issue[RUNS], round[RUNS];
	for (int r = 0; r < RUNS; r++) {
		double t0 = rl_now_ms();
		gpu_dispatch(ctx, p, b, 2, 64);
		double t1 = rl_now_ms();
		gpu_buffer_read(bout, 0, sizeof(out), out);
		round[r] = rl_now_ms() - t0;
		issue[r] = t1 - t0;
	}
	CHECK(out[63] == 63.0f * 63.0f);
	printf("dispatch of one group: issue %.4f ms, with readback (round trip) %.4f ms "
	       "(medians of %d)\n", median(issue, RUNS), median(round, RUNS), RUNS);
	gpu_buffer_destroy(bin);
	gpu_buffer_destroy(bout);
}

static void test_validate(void)
{
	FILE *log = tmpfile();
	CHECK(log != NULL);
	if (!log)
		return;
	int r = gpu_validate_glsl(square_int_src, log);
	if (r < 0) {
		printf("SKIP gpu_validate_glsl: glslangValidator is missing\n");
		fclose(log);
		return;
	}
	CHECK(r == 1);
	static const char bad[] =
		"#version 430 core\n"
		"layout(local_size_x = 64) in;\n"
		"void main() { float x = nope; }\n";
	CHECK(gpu_validate_glsl(bad, log) == 0);
	char *text = slurp(log);
	CHECK(text && strstr(text, "nope"));
	free(text);
	fclose(log);
	CHECK(gpu_validate_glsl(NULL, NULL) == 0);

	/* No validator on the PATH: -1, not a verdict. */
	const char *path = getenv("PATH");
	char *saved = path ? strdup(path) : NULL;
	setenv("PATH", "/nonexistent-relight-dir", 1);
	CHECK(gpu_validate_glsl(square_int_src, NULL) == -1);
	if (saved)
		setenv("PATH", saved, 1);
	else
		unsetenv("PATH");
	free(saved);
}

/*
 * In a child process, before this process touches EGL: gpu_create must
 * fail cleanly with a reason when glvnd finds no EGL vendor, and when Mesa
 * can give no more than OpenGL 3.3. Returns the child's findings.
 */
static int create_in_child(const char *var, const char *value, bool *failed, char *reason,
			   size_t n)
{
	int fds[2];
	if (pipe(fds) != 0)
		return -1;
	pid_t pid = fork();
	if (pid < 0)
		return -1;
	if (pid == 0) {
		close(fds[0]);
		setenv(var, value, 1);
		char err[512] = "untouched";
		struct gpu_ctx *c = gpu_create(err, sizeof(err));
		char msg[600];
		int len = snprintf(msg, sizeof(msg), "%c%s", c ? 'S' : 'F', err);
		gpu_destroy(c);
		if (write(fds[1], msg, (size_t)len) != len)
			_exit(2);
		_exit(0);
	}
	close(fds[1]);
	char msg[600] = { 0 };
	ssize_t got = 0, r;
	while (got < (ssize_t)sizeof(msg) - 1 &&
	       (r = read(fds[0], msg + got, sizeof(msg) - 1 - (size_t)got)) > 0)
		got += r;
	close(fds[0]);
	int status = 0;
	waitpid(pid, &status, 0);
	if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || got < 1)
		return -1;
	*failed = msg[0] == 'F';
	snprintf(reason, n, "%.*s", (int)(n - 1), msg + 1);
	return 0;
}

static void test_create_failures(void)
{
	bool failed = false;
	char reason[512];
	CHECK(create_in_child("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl_vendor.json",
			      &failed, reason, sizeof(reason)) == 0);
	CHECK(failed);
	CHECK(reason[0] != '\0' && strcmp(reason, "untouched") != 0);
	printf("without an EGL vendor: %s\n", reason);

	/* Mesa only: elsewhere the variable means nothing and creation may succeed. */
	if (create_in_child("MESA_GL_VERSION_OVERRIDE", "3.3", &failed, reason,
			    sizeof(reason)) == 0 && failed) {
		CHECK(strstr(reason, "4.3") != NULL);
		printf("with OpenGL 3.3 only: %s\n", reason);
	}
}

/*
 * The micro-benchmark's result of invocation @i as microbench.h defines it,
 * evaluated on the CPU, with @steps steps of each chain.
 */
static double arith_expected(const struct gpu_arith_rate *r, bool vec4, uint32_t i,
			     uint32_t steps)
{
	float f = r->seed + (float)(i & 1023u) * 0.0009765625f;
	int chains = vec4 ? GPU_ARITH_VEC4_CHAINS : GPU_ARITH_SCALAR_CHAINS;
	int width = vec4 ? 4 : 1;
	float s[4] = { 0, 0, 0, 0 };
	for (int k = 0; k < chains; k++) {
		for (int j = 0; j < width; j++) {
			float x = f + (float)(width * k + j) * 0.0078125f;
			for (uint32_t n = 0; n < steps; n++)
				x = fmaf(x, r->mul[j], r->add[j]);
			s[j] += x;
		}
	}
	return vec4 ? (double)((s[0] + s[1]) + (s[2] + s[3])) : (double)s[0];
}

static void check_arith_kernel(const struct gpu_arith_rate *r, const struct gpu_arith_kernel *k,
			       bool vec4)
{
	CHECK(k->flops > 0 && isfinite(k->flops));
	CHECK(k->ms > 0 && isfinite(k->ms));
	CHECK(k->invocations >= 1024 && k->invocations % 64 == 0);
	CHECK(k->steps >= 32 && k->steps <= (1u << 20));
	/* The rate is the work over the best time. */
	double work = 2.0 * (vec4 ? 4 * GPU_ARITH_VEC4_CHAINS : GPU_ARITH_SCALAR_CHAINS) *
		      (double)k->steps * (double)k->invocations;
	CHECK_NEAR(k->flops * k->ms * 1e-3 / work, 1.0, 1e-9);
	int terms = vec4 ? 4 * GPU_ARITH_VEC4_CHAINS : GPU_ARITH_SCALAR_CHAINS;
	for (int c = 0; c < GPU_ARITH_CHECKS; c++) {
		uint32_t i = r->check_index[c];
		if (i >= k->invocations)
			continue;
		double want = arith_expected(r, vec4, i, k->steps);
		/*
		 * The chains are exact in float; only the final sum rounds. Each
		 * addition of positive terms is off by at most 2^-24 of its
		 * partial sum, itself at most the total, in whatever order.
		 */
		double tol = (terms - 1) * ldexp(fabs(want), -24);
		CHECK_NEAR(k->check[c], want, tol);
		/* Half the steps would have been caught: the check can fail. */
		CHECK(fabs(arith_expected(r, vec4, i, k->steps / 2) - want) > 2 * tol);
	}
	/* Results depend on the invocation. */
	CHECK(k->check[0] != k->check[1]);
}

static void test_arith_rate(void)
{
	struct gpu_arith_rate r;
	double t0 = rl_now_ms();
	bool ok = gpu_arith_rate(ctx, 3, 20.0, &r);
	double wall = rl_now_ms() - t0;
	CHECK(ok);
	if (!ok)
		return;
	CHECK(r.runs == 3);
	check_arith_kernel(&r, &r.vec4, true);
	check_arith_kernel(&r, &r.scalar, false);
	CHECK(r.flops == (r.vec4.flops >= r.scalar.flops ? r.vec4.flops : r.scalar.flops));
	CHECK(r.ms == (r.vec4.flops >= r.scalar.flops ? r.vec4.ms : r.scalar.ms));
	/* About the asked-for time per run (printed; timing is not checked). */
	printf("arithmetic rate: vec4 %.1f GFLOP/s (%.1f ms, %llu invocations x %u steps), "
	       "scalar %.1f GFLOP/s (%.1f ms, %llu x %u); whole call %.0f ms\n",
	       r.vec4.flops * 1e-9, r.vec4.ms, (unsigned long long)r.vec4.invocations,
	       r.vec4.steps, r.scalar.flops * 1e-9, r.scalar.ms,
	       (unsigned long long)r.scalar.invocations, r.scalar.steps, wall);

	struct gpu_arith_rate z;
	CHECK(!gpu_arith_rate(NULL, 1, 5.0, &z));
	CHECK(z.flops == 0 && z.vec4.invocations == 0);
	CHECK(!gpu_arith_rate(ctx, 1, 5.0, NULL));
}

int main(void)
{
	setvbuf(stdout, NULL, _IONBF, 0);
	/* Children first: fork before this process starts the driver's threads. */
	RUN(test_create_failures);

	char err[512];
	ctx = gpu_create(err, sizeof(err));
	if (!ctx) {
		printf("SKIP: no OpenGL 4.3 context: %s\n", err);
		return 77;
	}
	CHECK(err[0] == '\0');
	printf("GL_RENDERER: %s (%s)\n", gpu_renderer(ctx),
	       gpu_is_software(ctx) ? "software" : "hardware");
	CHECK(gpu_renderer(ctx)[0] != '\0');

	RUN(test_square_small);
	RUN(test_square_large);
	RUN(test_uniforms);
	RUN(test_compile_error);
	RUN(test_cache);
	RUN(test_disk_cache);
	RUN(test_buffers);
	RUN(test_dispatch_errors);
	RUN(test_overhead);
	RUN(test_validate);
	RUN(test_arith_rate);

	gpu_destroy(ctx);
	gpu_destroy(NULL);
	return test_finish();
}

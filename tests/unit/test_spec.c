/*
 * The specializer: which instructions are static, dynamic and dead, what is
 * cached, and that the caching program computes those cached values exactly
 * as the original shader does.
 */
#include "spec.h"
#include "builtin.h"
#include "exec.h"
#include "test.h"

#include <stdio.h>
#include <string.h>

static struct sl_program *compile(const char *src)
{
	struct sl_program *p = sl_compile_string("test.sl", src, strlen(src), NULL);
	if (!p)
		fprintf(stderr, "cannot compile:\n%s\n", src);
	return p;
}

/* Is a call of built-in @name kept in the dynamic slice / in the caching program? */
static bool kept_call(const struct sl_spec *s, const char *name)
{
	for (uint32_t i = 0; i < s->prog->ncode; i++) {
		const struct sl_insn *in = &s->prog->code[i];
		if (s->keep[i] && in->op == SL_OP_CALL && !strcmp(sl_builtins[in->bi].name, name))
			return true;
	}
	return false;
}

static bool caching_call(const struct sl_spec *s, const char *name)
{
	for (uint32_t i = 0; i < s->caching->ncode; i++) {
		const struct sl_insn *in = &s->caching->code[i];
		if (in->op == SL_OP_CALL && !strcmp(sl_builtins[in->bi].name, name))
			return true;
	}
	return false;
}

static const char *marble =
	"surface marble(float Kd = 0.8; float veinfreq = 4; color base = color(0.9, 0.9, 0.85);\n"
	"               color vein = color(0.2, 0.2, 0.3))\n"
	"{\n"
	"	point Pshad = transform(\"shader\", P);\n"
	"	float n = noise(Pshad * veinfreq) + 0.5 * noise(Pshad * veinfreq * 2);\n"
	"	color c = mix(base, vein, smoothstep(0.6, 0.8, n));\n"
	"	normal Nf = faceforward(normalize(N), I);\n"
	"	float unused = noise(Pshad * 17);\n"
	"	Oi = Os;\n"
	"	Ci = Os * c * Kd * diffuse(Nf);\n"
	"}\n";

/* Only lights dynamic: the pattern is static, no noise on the GPU. */
static void test_marble_lights_only(void)
{
	struct sl_program *p = compile(marble);
	CHECK(p != NULL);
	if (!p)
		return;
	struct sl_spec *s = sl_specialize(p, NULL, 0, NULL);
	CHECK(s != NULL);
	if (!s)
		goto out;
	CHECK(!kept_call(s, "noise"));
	CHECK(!kept_call(s, "mix"));
	CHECK(kept_call(s, "diffuse"));
	CHECK(caching_call(s, "noise"));
	CHECK(!caching_call(s, "diffuse"));
	CHECK(s->ndead >= 1);   /* `unused` */
	CHECK(s->ndynamic >= 2);
	CHECK(s->ncache_required == 0);
	/* diffuse() reads P without being given it: P is an input of the dynamic part */
	bool p_cached = false;
	for (uint32_t k = 0; k < s->ncached; k++)
		p_cached = p_cached || s->cached[k] == p->global_reg[SL_GLOBAL_P];
	CHECK(p_cached);
	/* the cached values include the pattern colour and the normal, not n itself */
	printf("marble, lights dynamic: %u static, %u dynamic, %u dead, %u cached registers\n",
	       s->nstatic, s->ndynamic, s->ndead, s->ncached);
	CHECK(s->ncached >= 3 && s->ncached <= 8);
	sl_spec_destroy(s);
out:
	sl_program_destroy(p);
}

/* The vein frequency dynamic: the noise moves to the GPU, what feeds it stays cached. */
static void test_marble_veinfreq(void)
{
	struct sl_program *p = compile(marble);
	if (!p)
		return;
	const char *dyn[] = { "veinfreq" };
	struct sl_spec *s = sl_specialize(p, dyn, 1, NULL);
	CHECK(s != NULL);
	if (s) {
		CHECK(kept_call(s, "noise"));
		CHECK(kept_call(s, "mix"));
		CHECK(kept_call(s, "smoothstep"));
		CHECK(!kept_call(s, "transform"));  /* Pshad is upstream of veinfreq: cached */
		CHECK(!kept_call(s, "normalize"));
		CHECK(!kept_call(s, "faceforward"));
		bool pshad_cached = false;
		for (uint32_t k = 0; k < s->ncached; k++) {
			const struct sl_reg *r = &p->regs[s->cached[k]];
			if (r->name && !strcmp(r->name, "Pshad"))
				pshad_cached = true;
		}
		CHECK(pshad_cached);
		printf("marble, veinfreq dynamic: %u static, %u dynamic, %u cached registers\n",
		       s->nstatic, s->ndynamic, s->ncached);
	}
	sl_spec_destroy(s);
	sl_program_destroy(p);
}

/*
 * A dynamic branch: the caching program computes what both sides need (the
 * noise and the cellnoise), the GPU only chooses.
 */
static void test_dynamic_branch(void)
{
	const char *src =
		"surface br(float Kd = 0.8; float pick = 0.2)\n"
		"{\n"
		"	float x;\n"
		"	if (pick > 0.5)\n"
		"		x = noise(P * 3);\n"
		"	else\n"
		"		x = cellnoise(P * 3);\n"
		"	Oi = 1;\n"
		"	Ci = x * Kd;\n"
		"}\n";
	struct sl_program *p = compile(src);
	if (!p)
		return;
	const char *dyn[] = { "pick" };
	struct sl_spec *s = sl_specialize(p, dyn, 1, NULL);
	CHECK(s != NULL);
	if (s) {
		CHECK(!kept_call(s, "noise"));
		CHECK(!kept_call(s, "cellnoise"));
		CHECK(caching_call(s, "noise"));
		CHECK(caching_call(s, "cellnoise"));
		/* no if of the dynamic condition in the caching program */
		bool has_if = false;
		for (uint32_t i = 0; i < s->caching->ncode; i++)
			has_if = has_if || s->caching->code[i].op == SL_OP_IF;
		CHECK(!has_if);
	}
	sl_spec_destroy(s);
	sl_program_destroy(p);
}

/*
 * The caching program's values are the original shader's: run both on the
 * interpreter over a grid and compare every cached register.
 */
static void test_caching_values(void)
{
	struct sl_program *p = compile(marble);
	if (!p)
		return;
	struct sl_spec *s = sl_specialize(p, NULL, 0, NULL);
	if (!s) {
		sl_program_destroy(p);
		return;
	}
	enum { NU = 8, NV = 8 };
	struct sl_exec *full = sl_exec_create(p, NU * NV), *cache = sl_exec_create(s->caching, NU * NV);
	CHECK(full && cache);
	if (!full || !cache)
		goto out;
	struct sl_exec *xs[2] = { full, cache };
	for (int e = 0; e < 2; e++) {
		sl_exec_set_grid(xs[e], NU, NV);
		for (int g = 0; g < SL_GLOBAL_COUNT; g++) {
			bool vary;
			float *d = sl_exec_global(xs[e], (enum sl_global)g, &vary);
			if (!d)
				continue;
			uint32_t st = sl_exec_stride(xs[e]);
			int nc = sl_type_ncomp(sl_global_type((enum sl_global)g).base);
			for (uint32_t i = 0; i < (vary ? NU * NV : 1u); i++)
				for (int c = 0; c < nc; c++)
					d[(size_t)c * (vary ? st : 1) + (vary ? i : 0)] =
						(float)((i * 7 + (uint32_t)c * 3 + (uint32_t)g) % 11) * 0.1f +
						(c == 2 ? 0.5f : 0);
		}
		CHECK(sl_exec_run(xs[e], NULL));
	}
	int compared = 0;
	for (uint32_t k = 0; k < s->ncached; k++) {
		int32_t r = s->cached[k];
		const float *a = sl_exec_reg(full, r), *b = sl_exec_reg(cache, r);
		int nc = sl_reg_ncomp(&p->regs[r]);
		bool vary = p->regs[r].varying;
		for (int c = 0; c < nc; c++)
			for (uint32_t i = 0; i < (vary ? NU * NV : 1u); i++) {
				size_t o = vary ? (size_t)c * sl_exec_stride(full) + i : (size_t)c;
				size_t o2 = vary ? (size_t)c * sl_exec_stride(cache) + i : (size_t)c;
				CHECK_NEAR(a[o], b[o2], 0);
				compared++;
			}
	}
	printf("caching program: %d cached values equal to the original's\n", compared);
	CHECK(compared > 0);
out:
	sl_exec_destroy(full);
	sl_exec_destroy(cache);
	sl_spec_destroy(s);
	sl_program_destroy(p);
}

static void test_errors(void)
{
	struct sl_program *p = compile(marble);
	if (!p)
		return;
	char *text = NULL;
	size_t len = 0;
	FILE *diag = open_memstream(&text, &len);
	const char *dyn[] = { "nosuch" };
	CHECK(sl_specialize(p, dyn, 1, diag) == NULL);
	fclose(diag);
	CHECK(text && strstr(text, "has no parameter 'nosuch'"));
	free(text);
	sl_program_destroy(p);
}

int main(void)
{
	RUN(test_marble_lights_only);
	RUN(test_marble_veinfreq);
	RUN(test_dynamic_branch);
	RUN(test_caching_values);
	RUN(test_errors);
	return test_finish();
}

/*
 * Header hygiene. Built two ways (tests/unit/meson.build):
 *
 * - once per public header with RL_HEADER_UNDER_TEST naming it: the header
 *   comes first and alone, twice, so it must include what it needs and have
 *   an include guard; this is a compile-time check;
 * - once without, as the `headers` test: every header together, plus checks
 *   of the small inline helpers and constants they define.
 */
#ifdef RL_HEADER_UNDER_TEST

#include RL_HEADER_UNDER_TEST
#include RL_HEADER_UNDER_TEST

/* Something for the object file to hold. */
int rl_header_test_symbol(void);
int rl_header_test_symbol(void)
{
	return 0;
}

#else

#include "arena.h"
#include "log.h"
#include "strbuf.h"

#include "ast.h"
#include "builtin.h"
#include "ctx.h"
#include "exec.h"
#include "exec_impl.h"
#include "ir.h"
#include "sl.h"
#include "token.h"

#include "test.h"

/* Enumerations that other code indexes tables with. */
_Static_assert(SL_TYPE_VOID == 0 && SL_TYPE_COUNT == 9, "sl_basetype changed");
_Static_assert(SL_TOK_EOF == 0, "SL_TOK_EOF must be 0 (zeroed tokens are EOF)");
_Static_assert(SL_GLOBAL_P == 0 && SL_GLOBAL_COUNT == 27, "sl_global changed");
_Static_assert(SL_PEER_COUNT == 3, "sl_peer changed");
_Static_assert(SL_DETAIL_DEFAULT == 0, "zeroed types must have the default detail");
_Static_assert(SL_OP_NOP == 0, "a zeroed instruction must be a no-op");

static void test_types(void)
{
	CHECK(sl_type_ncomp(SL_TYPE_FLOAT) == 1);
	CHECK(sl_type_ncomp(SL_TYPE_BOOL) == 1);
	CHECK(sl_type_ncomp(SL_TYPE_COLOR) == 3);
	CHECK(sl_type_ncomp(SL_TYPE_POINT) == 3);
	CHECK(sl_type_ncomp(SL_TYPE_VECTOR) == 3);
	CHECK(sl_type_ncomp(SL_TYPE_NORMAL) == 3);
	CHECK(sl_type_ncomp(SL_TYPE_MATRIX) == 16);
	CHECK(sl_type_ncomp(SL_TYPE_STRING) == 0);
	CHECK(sl_type_ncomp(SL_TYPE_VOID) == 0);

	int triples = 0;
	for (int t = 0; t < SL_TYPE_COUNT; t++)
		triples += sl_type_is_triple(t);
	CHECK(triples == 4);
	CHECK(!sl_type_is_triple(SL_TYPE_FLOAT) && !sl_type_is_triple(SL_TYPE_MATRIX));

	struct sl_reg r = { .type = SL_TYPE_NORMAL };
	CHECK(sl_reg_ncomp(&r) == 3);
	r.type = SL_TYPE_STRING;
	CHECK(sl_reg_ncomp(&r) == 0);
}

static void test_options(void)
{
	/* Zero-initialized options are valid (sl.h): nothing to set. */
	struct sl_options o = { 0 };
	CHECK(o.include_dirs == NULL && o.n_include_dirs == 0 && o.diag == NULL &&
	      o.max_errors == 0);

	/* RL_VEC and rl_strbuf start empty from {0}. */
	RL_VEC(double) v = { 0 };
	CHECK(v.len == 0 && v.cap == 0 && v.data == NULL);
	struct rl_strbuf b = { 0 };
	CHECK(b.data == NULL && b.len == 0);
	CHECK(RL_LOG_SILENT == 0 && RL_LOG_ERROR < RL_LOG_WARN && RL_LOG_INFO < RL_LOG_DEBUG);
}

int main(void)
{
	RUN(test_types);
	RUN(test_options);
	return test_finish();
}

#endif

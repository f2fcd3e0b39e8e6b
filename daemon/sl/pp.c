/*
 * The preprocessor: directives, conditional groups, includes and macro
 * expansion over the lexer's tokens, then keyword classification.
 *
 * Expansion reads from a stream: the tokens of a file (or of an argument, or
 * of an #if line) with a stack of frames on top, one per macro expansion
 * being rescanned. A macro is disabled while its frame is on the stack; a
 * name read while its macro is disabled is marked so that it never expands,
 * which is what stops `#define a a` and `#define f(x) f(x)+1`. Caps on the
 * number of expansions, of tokens produced and of bytes pasted end
 * exponential macro bombs with an error.
 */
#include "token.h"
#include "../common/strbuf.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/*
 * Defined in lex.c: sl_lex() that leaves some errors to the preprocessor,
 * which reports them only for tokens that reach its output. A stray byte
 * becomes a one-byte SL_TOK_HASH token spelled as that byte, an invalid
 * number has the value NaN, and an unterminated string is not reported.
 */
bool sl_lex_pp(struct sl_ctx *ctx, uint32_t file, const char *src, size_t len,
	       struct sl_token_list *out);

/*
 * From sl_lex_pp(): the token starts a line only because a comment before it
 * spans lines. A directive goes on over such a line break (as if the comment
 * were a space), but a '#' there still starts one.
 */
#define TOKF_COMMENT_LINE (1u << 6)

/* A name read while its macro was disabled: it never expands. Cleared on output. */
#define TOKF_NOEXPAND (1u << 7)

#define MAX_INCLUDE_DEPTH 64
#define MAX_INCLUDES 10000
#define MAX_INCLUDED_BYTES ((size_t)8 << 20) /* all included files together */
#define MAX_EXPANSIONS ((size_t)1 << 20)
#define MAX_EXPANDED_TOKENS (((size_t)64 << 20) / sizeof(struct sl_token))
#define MAX_PASTED_BYTES ((size_t)64 << 20)
#define MAX_NESTING 200
#define MAX_PARAMS 256

struct macro {
	const char *name;
	bool defined;
	bool function_like, variadic;
	size_t nparams;
	const char **params;
	struct sl_token *body;
	int *param_of; /* per body token: the parameter it names, or -1 */
	size_t nbody;
	bool disabled; /* its expansion is being rescanned */
};

struct frame {
	struct sl_token *toks; /* heap */
	size_t n, pos;
	struct macro *m;
};

struct stream {
	const struct sl_token *base;
	size_t nbase, pos;
	bool is_file; /* base is a file's tokens: directives and its EOF end arguments */
	RL_VEC(struct frame) frames;
};

struct cond {
	struct sl_loc loc;
	bool active;      /* this group's tokens are kept */
	bool taken;       /* a group of this conditional has been (or can no longer be) chosen */
	bool seen_else;
};

struct pp {
	struct sl_ctx *ctx;
	struct sl_token_list *out;
	bool failed;

	struct macro **slots; /* open addressing, keyed by the interned name */
	size_t cap, count;

	RL_VEC(struct cond) conds;
	int include_depth;
	size_t nincludes, included_bytes;
	bool include_cap_hit;

	size_t nexpansions, ntokens, npasted;
	bool dead; /* an expansion cap was hit: no more expansion */
	struct sl_loc eof_loc; /* where the last file processed ended */
	int nesting;

	const char *name_defined, *name_va_args;
	const char *keywords[SL_TOK_KW_GATHER - SL_TOK_KW_FLOAT + 1];
	struct rl_strbuf sb;
};

static const char *const keyword_names[] = {
	"float", "color", "point", "vector", "normal", "matrix", "string", "void",
	"uniform", "varying", "output", "extern", "surface", "light", "displacement",
	"volume", "imager", "if", "else", "while", "for", "break", "continue", "return",
	"illuminance", "illuminate", "solar", "gather",
};
_Static_assert(sizeof(keyword_names) / sizeof(keyword_names[0]) ==
		       SL_TOK_KW_GATHER - SL_TOK_KW_FLOAT + 1,
	       "one name per keyword token");

static void pp_error(struct pp *pp, struct sl_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static void pp_warning(struct pp *pp, struct sl_loc loc, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void pp_error(struct pp *pp, struct sl_loc loc, const char *fmt, ...)
{
	pp->failed = true;
	if (pp->ctx->too_many)
		return;
	struct rl_strbuf msg = { 0 };
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(&msg, fmt, ap);
	va_end(ap);
	sl_error(pp->ctx, loc, "%s", rl_strbuf_str(&msg));
	rl_strbuf_finish(&msg);
}

static void pp_warning(struct pp *pp, struct sl_loc loc, const char *fmt, ...)
{
	if (pp->ctx->too_many)
		return;
	struct rl_strbuf msg = { 0 };
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(&msg, fmt, ap);
	va_end(ap);
	sl_warning(pp->ctx, loc, "%s", rl_strbuf_str(&msg));
	rl_strbuf_finish(&msg);
}

/* Token helpers */

/* A '#' (not a stray byte that sl_lex_pp() spelled as SL_TOK_HASH). */
static bool is_hash(const struct sl_token *t)
{
	return t->kind == SL_TOK_HASH && t->len == 1 && t->text[0] == '#';
}

/* One of the stray bytes '&', '|', '~' that #if understands. */
static bool is_other(const struct sl_token *t, char c)
{
	return t->kind == SL_TOK_HASH && t->len == 1 && t->text[0] == c;
}

static bool is_ident(const struct sl_token *t, const char *name)
{
	return t->kind == SL_TOK_IDENT && !strcmp(t->str, name);
}

/* The spelling of @t for messages, shortened when long. */
static int quote_len(const struct sl_token *t)
{
	return t->len > 40 ? 40 : (int)t->len;
}

/* Macro table */

static size_t hash_ptr(const char *p)
{
	uint64_t h = (uint64_t)(uintptr_t)p;
	h ^= h >> 29;
	h *= 0xbf58476d1ce4e5b9ull;
	h ^= h >> 32;
	return (size_t)h;
}

static struct macro *lookup(const struct pp *pp, const char *name)
{
	if (!pp->cap)
		return NULL;
	size_t i = hash_ptr(name) & (pp->cap - 1);
	while (pp->slots[i]) {
		if (pp->slots[i]->name == name)
			return pp->slots[i];
		i = (i + 1) & (pp->cap - 1);
	}
	return NULL;
}

/* The defined macro called @name, or NULL. */
static struct macro *find_macro(const struct pp *pp, const char *name)
{
	struct macro *m = lookup(pp, name);
	return m && m->defined ? m : NULL;
}

static struct macro *get_macro(struct pp *pp, const char *name)
{
	struct macro *m = lookup(pp, name);
	if (m)
		return m;
	if ((pp->count + 1) * 2 > pp->cap) {
		size_t ncap = pp->cap ? pp->cap * 2 : 64;
		struct macro **ns = rl_xcalloc(ncap, sizeof(*ns));
		for (size_t i = 0; i < pp->cap; i++) {
			struct macro *o = pp->slots[i];
			if (!o)
				continue;
			size_t j = hash_ptr(o->name) & (ncap - 1);
			while (ns[j])
				j = (j + 1) & (ncap - 1);
			ns[j] = o;
		}
		free(pp->slots);
		pp->slots = ns;
		pp->cap = ncap;
	}
	m = rl_arena_alloc(pp->ctx->arena, sizeof(*m));
	m->name = name;
	size_t j = hash_ptr(name) & (pp->cap - 1);
	while (pp->slots[j])
		j = (j + 1) & (pp->cap - 1);
	pp->slots[j] = m;
	pp->count++;
	return m;
}

/* Streams */

static void pop_frame(struct stream *s)
{
	struct frame *f = &s->frames.data[--s->frames.len];
	if (f->m)
		f->m->disabled = false;
	free(f->toks);
}

static void stream_finish(struct stream *s)
{
	while (s->frames.len)
		pop_frame(s);
	rl_vec_free(s->frames);
}

/* The next token without taking it, or NULL at the end; exhausted frames are popped. */
static const struct sl_token *stream_peek(struct stream *s)
{
	while (s->frames.len) {
		struct frame *f = &s->frames.data[s->frames.len - 1];
		if (f->pos < f->n)
			return &f->toks[f->pos];
		pop_frame(s);
	}
	return s->pos < s->nbase ? &s->base[s->pos] : NULL;
}

/* True when @t (from stream_peek()) ends macro arguments: the end, EOF or a directive. */
static bool stream_at_end(const struct stream *s, const struct sl_token *t)
{
	if (!t || t->kind == SL_TOK_EOF)
		return true;
	return s->is_file && !s->frames.len && (t->flags & SL_TOKF_BOL) && is_hash(t);
}

/* Take the next token (stream_peek() must have returned it). */
static struct sl_token stream_next(struct pp *pp, struct stream *s)
{
	struct sl_token t;
	if (s->frames.len) {
		struct frame *f = &s->frames.data[s->frames.len - 1];
		t = f->toks[f->pos++];
	} else {
		t = s->base[s->pos++];
	}
	if (t.kind == SL_TOK_IDENT && !(t.flags & TOKF_NOEXPAND)) {
		struct macro *m = find_macro(pp, t.str);
		if (m && m->disabled)
			t.flags |= TOKF_NOEXPAND;
	}
	return t;
}

/* Expansion limits */

static bool over_budget(struct pp *pp, struct sl_loc loc)
{
	if (pp->dead)
		return true;
	if (pp->nexpansions > MAX_EXPANSIONS || pp->ntokens > MAX_EXPANDED_TOKENS ||
	    pp->npasted > MAX_PASTED_BYTES) {
		pp_error(pp, loc, "macro expansion too large");
		pp->dead = true;
	}
	return pp->dead;
}

static void add_tok(struct pp *pp, struct sl_token_list *v, const struct sl_token *t)
{
	pp->ntokens++;
	rl_vec_push(*v, *t);
}

static bool try_expand(struct pp *pp, struct stream *s, struct sl_token *name);

/* Fully macro-expand @n tokens into @out, on their own (a macro call in them ends with them). */
static void expand_list(struct pp *pp, const struct sl_token *toks, size_t n,
			struct sl_token_list *out)
{
	struct stream s = { .base = toks, .nbase = n };
	const struct sl_token *p;
	while ((p = stream_peek(&s)) != NULL) {
		struct sl_token t = stream_next(pp, &s);
		if (t.kind == SL_TOK_IDENT && try_expand(pp, &s, &t))
			continue;
		add_tok(pp, out, &t);
	}
	stream_finish(&s);
}

/* Macro calls */

struct arg {
	size_t start, n;  /* raw tokens in the collected list */
	struct sl_token_list expanded;
	bool done;        /* expanded is filled */
};

struct arg_list {
	struct arg *data;
	size_t len, cap;
};

/* args: '(' [ tokens { ',' tokens } ] ')', the '(' already read. */
static bool collect_args(struct pp *pp, struct stream *s, const struct macro *m,
			 const struct sl_token *use, struct sl_token_list *raw, struct arg_list *args)
{
	int depth = 0;
	struct arg cur = { 0 };
	/* Empty argument lists still index into raw->data: make it non-NULL. */
	rl_vec_reserve(*raw, 1);
	for (;;) {
		const struct sl_token *p = stream_peek(s);
		if (stream_at_end(s, p)) {
			pp_error(pp, use->loc, "unterminated argument list invoking macro '%s'",
				 m->name);
			return false;
		}
		struct sl_token t = stream_next(pp, s);
		if (depth == 0 && t.kind == SL_TOK_RPAREN)
			break;
		if (depth == 0 && t.kind == SL_TOK_COMMA &&
		    !(m->variadic && args->len + 1 >= m->nparams)) {
			cur.n = raw->len - cur.start;
			rl_vec_push(*args, cur);
			cur = (struct arg){ .start = raw->len };
			continue;
		}
		if (t.kind == SL_TOK_LPAREN)
			depth++;
		else if (t.kind == SL_TOK_RPAREN)
			depth--;
		/* inside an argument being expanded, this copies tokens once more */
		if (pp->nesting)
			pp->ntokens++;
		rl_vec_push(*raw, t);
	}
	cur.n = raw->len - cur.start;
	rl_vec_push(*args, cur);

	size_t given = args->len;
	if (given == 1 && args->data[0].n == 0 && m->nparams == 0)
		given = 0;
	bool ok = m->variadic ? given + 1 >= m->nparams : given == m->nparams;
	if (!ok) {
		pp_error(pp, use->loc, "macro '%s' expects %zu argument%s, got %zu", m->name,
			 m->nparams, m->nparams == 1 ? "" : "s", given);
		return false;
	}
	/* a missing variadic argument is empty */
	while (args->len < m->nparams)
		rl_vec_push(*args, ((struct arg){ .start = raw->len }));
	return true;
}

/* The parameter that body token @i names, or -1. */
static int body_param(const struct macro *m, size_t i)
{
	return m->param_of ? m->param_of[i] : -1;
}

/* The string literal token that #param makes of @n raw tokens. */
static struct sl_token stringize(struct pp *pp, const struct sl_token *toks, size_t n,
				 struct sl_loc loc)
{
	struct rl_strbuf value = { 0 }, text = { 0 };
	rl_strbuf_putc(&text, '"');
	for (size_t i = 0; i < n; i++) {
		const struct sl_token *t = &toks[i];
		if (i > 0 && (t->flags & (SL_TOKF_SPACE | SL_TOKF_BOL))) {
			rl_strbuf_putc(&value, ' ');
			rl_strbuf_putc(&text, ' ');
		}
		rl_strbuf_add(&value, t->text, t->len);
		if (t->kind != SL_TOK_STRING) {
			rl_strbuf_add(&text, t->text, t->len);
			continue;
		}
		for (uint32_t k = 0; k < t->len; k++) {
			if (t->text[k] == '"' || t->text[k] == '\\')
				rl_strbuf_putc(&text, '\\');
			rl_strbuf_putc(&text, t->text[k]);
		}
	}
	rl_strbuf_putc(&text, '"');
	pp->npasted += text.len;
	struct sl_token r = {
		.kind = SL_TOK_STRING,
		.len = (uint32_t)text.len,
		.text = rl_arena_strndup(pp->ctx->arena, text.data, text.len),
		.str = rl_arena_strndup(pp->ctx->arena, rl_strbuf_str(&value), value.len),
		.loc = loc,
	};
	rl_strbuf_finish(&value);
	rl_strbuf_finish(&text);
	return r;
}

/* Paste @a and @b into one token in @r; false (reported) if they do not form one. */
static bool paste(struct pp *pp, const struct sl_token *a, const struct sl_token *b,
		  struct sl_loc loc, struct sl_token *r)
{
	size_t n = (size_t)a->len + b->len;
	pp->npasted += n;
	char *buf = rl_arena_alloc(pp->ctx->arena, n + 1);
	memcpy(buf, a->text, a->len);
	memcpy(buf + a->len, b->text, b->len);

	/* the lexer's own complaints would point into this buffer: keep them quiet */
	struct sl_ctx *ctx = pp->ctx;
	int nerrors = ctx->nerrors, nwarnings = ctx->nwarnings;
	bool quiet = ctx->quiet, too_many = ctx->too_many;
	ctx->quiet = true;
	struct sl_token_list l = { 0 };
	bool ok = sl_lex_pp(ctx, loc.file, buf, n, &l);
	ctx->quiet = quiet;
	ctx->nerrors = nerrors;
	ctx->nwarnings = nwarnings;
	ctx->too_many = too_many;

	ok = ok && l.len == 2 && !(l.data[0].kind == SL_TOK_HASH && !is_hash(&l.data[0]));
	if (ok) {
		*r = l.data[0];
		r->loc = loc;
		r->flags = a->flags & (SL_TOKF_BOL | SL_TOKF_SPACE);
	} else {
		pp_error(pp, loc, "pasting '%.*s' and '%.*s' does not give a valid token",
			 quote_len(a), a->text, quote_len(b), b->text);
	}
	free(l.data);
	return ok;
}

/*
 * One element of a macro body for substitution: a plain token, a parameter
 * (raw when @raw, else fully expanded), or '#' parameter. Appends its tokens
 * to @res and returns how many body tokens it took.
 */
static size_t subst_element(struct pp *pp, const struct macro *m, size_t i, bool raw,
			    const struct sl_token_list *rawtoks, struct arg_list *args,
			    const struct sl_token *use, struct sl_token_list *res)
{
	const struct sl_token *b = &m->body[i];
	if (m->function_like && is_hash(b) && i + 1 < m->nbody) {
		int k = body_param(m, i + 1);
		if (k >= 0) {
			const struct arg *a = &args->data[k];
			struct sl_token t = stringize(pp, rawtoks->data + a->start, a->n, use->loc);
			t.flags = b->flags;
			add_tok(pp, res, &t);
			return 2;
		}
	}
	int k = body_param(m, i);
	if (k < 0) {
		struct sl_token t = *b;
		t.loc = use->loc;
		add_tok(pp, res, &t);
		return 1;
	}
	struct arg *a = &args->data[k];
	const struct sl_token *src;
	size_t n;
	if (raw) {
		src = rawtoks->data + a->start;
		n = a->n;
	} else {
		if (!a->done) {
			if (pp->nesting >= MAX_NESTING) {
				if (!pp->dead)
					pp_error(pp, use->loc, "macro arguments nested too deeply");
				pp->dead = true;
			}
			pp->nesting++;
			expand_list(pp, rawtoks->data + a->start, a->n, &a->expanded);
			pp->nesting--;
			a->done = true;
		}
		src = a->expanded.data;
		n = a->expanded.len;
	}
	for (size_t j = 0; j < n; j++) {
		struct sl_token t = src[j];
		if (j == 0)
			t.flags = (uint8_t)((t.flags & ~(SL_TOKF_BOL | SL_TOKF_SPACE)) |
					    (b->flags & SL_TOKF_SPACE));
		add_tok(pp, res, &t);
	}
	return 1;
}

/* The tokens of macro @m called at @use with @args, before rescanning. */
static void substitute(struct pp *pp, const struct macro *m, const struct sl_token *use,
		       const struct sl_token_list *rawtoks, struct arg_list *args, struct sl_token_list *res)
{
	size_t i = 0;
	bool prev_empty = false; /* the previous element gave no tokens (a placemarker) */
	while (i < m->nbody && !pp->dead) {
		const struct sl_token *b = &m->body[i];
		if (b->kind == SL_TOK_HASHHASH && i > 0 && i + 1 < m->nbody) {
			struct sl_token_list rhs = { 0 };
			i++;
			i += subst_element(pp, m, i, true, rawtoks, args, use, &rhs);
			if (prev_empty) {
				for (size_t j = 0; j < rhs.len; j++)
					rl_vec_push(*res, rhs.data[j]);
				prev_empty = rhs.len == 0;
			} else if (rhs.len && res->len) {
				struct sl_token *lhs = &res->data[res->len - 1];
				struct sl_token r;
				if (paste(pp, lhs, &rhs.data[0], use->loc, &r))
					*lhs = r;
				else
					rl_vec_push(*res, rhs.data[0]);
				for (size_t j = 1; j < rhs.len; j++)
					rl_vec_push(*res, rhs.data[j]);
			}
			rl_vec_free(rhs);
			continue;
		}
		bool raw = i + 1 < m->nbody && m->body[i + 1].kind == SL_TOK_HASHHASH;
		size_t before = res->len;
		i += subst_element(pp, m, i, raw, rawtoks, args, use, res);
		prev_empty = res->len == before;
		over_budget(pp, use->loc);
	}
	if (res->len) {
		struct sl_token *f = &res->data[0];
		f->flags = (uint8_t)((f->flags & ~(SL_TOKF_BOL | SL_TOKF_SPACE)) |
				     (use->flags & (SL_TOKF_BOL | SL_TOKF_SPACE)));
	}
}

/*
 * If @name (just read from @s) is a macro that may expand, expand it: its
 * arguments are read from @s and its expansion is pushed on @s for
 * rescanning. Returns false, marking @name, when it stays as it is.
 */
static bool try_expand(struct pp *pp, struct stream *s, struct sl_token *name)
{
	if ((name->flags & TOKF_NOEXPAND) || pp->dead)
		return false;
	struct macro *m = find_macro(pp, name->str);
	if (!m)
		return false;
	if (m->disabled) {
		name->flags |= TOKF_NOEXPAND;
		return false;
	}

	struct sl_token_list raw = { 0 };
	struct arg_list args = { 0 };
	if (m->function_like) {
		const struct sl_token *p = stream_peek(s);
		if (stream_at_end(s, p) || p->kind != SL_TOK_LPAREN)
			return false;
		stream_next(pp, s);
		if (!collect_args(pp, s, m, name, &raw, &args))
			goto done;
	}
	pp->nexpansions++;
	if (over_budget(pp, name->loc))
		goto done;

	struct sl_token_list res = { 0 };
	substitute(pp, m, name, &raw, &args, &res);
	if (res.len) {
		m->disabled = true;
		rl_vec_push(s->frames, ((struct frame){ .toks = res.data, .n = res.len, .m = m }));
	} else {
		rl_vec_free(res);
	}
done:
	for (size_t i = 0; i < args.len; i++)
		rl_vec_free(args.data[i].expanded);
	rl_vec_free(args);
	rl_vec_free(raw);
	return true;
}

/* Output */

static bool string_closed(const struct sl_token *t)
{
	for (uint32_t i = 1; i < t->len; i++) {
		if (t->text[i] == '\\')
			i++;
		else if (t->text[i] == '"')
			return i == t->len - 1;
	}
	return false;
}

static void emit(struct pp *pp, struct sl_token t)
{
	t.flags &= SL_TOKF_BOL | SL_TOKF_SPACE;
	if (t.kind == SL_TOK_HASH || t.kind == SL_TOK_HASHHASH) {
		unsigned char c = (unsigned char)t.text[0];
		if (t.kind == SL_TOK_HASHHASH)
			pp_error(pp, t.loc, "stray '##' in program");
		else if (c > ' ' && c < 0x7f)
			pp_error(pp, t.loc, "stray '%c' in program", c);
		else
			pp_error(pp, t.loc, "stray '\\x%02x' in program", (unsigned)c);
		return;
	}
	if (t.kind == SL_TOK_NUMBER && isnan(t.num)) {
		pp_error(pp, t.loc, "invalid number near '%.*s'", quote_len(&t), t.text);
		t.num = 0;
	}
	if (t.kind == SL_TOK_STRING && !string_closed(&t))
		pp_error(pp, t.loc, "unterminated string near '%.*s'", quote_len(&t), t.text);
	if (t.kind == SL_TOK_IDENT) {
		for (size_t i = 0; i < sizeof(pp->keywords) / sizeof(pp->keywords[0]); i++) {
			if (pp->keywords[i] == t.str) {
				t.kind = (enum sl_tok)(SL_TOK_KW_FLOAT + i);
				break;
			}
		}
	}
	uint32_t kind = (uint32_t)t.kind;
	rl_hash128_add(&pp->ctx->program_hash, &kind, sizeof(kind));
	rl_hash128_add(&pp->ctx->program_hash, &t.len, sizeof(t.len));
	rl_hash128_add(&pp->ctx->program_hash, t.text, t.len);
	rl_vec_push(*pp->out, t);
}

/* #if expressions */

struct eval {
	struct pp *pp;
	const struct sl_token *t;
	size_t n, i;
	struct sl_loc loc; /* of the directive */
	bool err;
	int depth;
};

static void eval_error(struct eval *e, const char *what)
{
	if (e->err)
		return;
	e->err = true;
	if (e->i < e->n) {
		const struct sl_token *t = &e->t[e->i];
		pp_error(e->pp, t->loc, "%s in #if near '%.*s'", what, quote_len(t), t->text);
	} else {
		pp_error(e->pp, e->loc, "%s in #if at end of line", what);
	}
}

static const struct sl_token *eval_peek(const struct eval *e, size_t k)
{
	return e->i + k < e->n ? &e->t[e->i + k] : NULL;
}

/* defined-op: 'defined' ident | 'defined' '(' ident ')', 'defined' (at @loc) already read */
static int64_t eval_defined(struct pp *pp, const struct sl_token *t, size_t n, size_t *i,
			    struct sl_loc loc, bool *err)
{
	bool paren = *i < n && t[*i].kind == SL_TOK_LPAREN;
	size_t k = *i + (paren ? 1 : 0);
	bool ok = k < n && t[k].kind == SL_TOK_IDENT;
	if (ok && paren)
		ok = k + 1 < n && t[k + 1].kind == SL_TOK_RPAREN;
	if (!ok) {
		if (!*err)
			pp_error(pp, loc, "operator 'defined' requires an identifier");
		*err = true;
		*i = n;
		return 0;
	}
	*i = k + (paren ? 2 : 1);
	return find_macro(pp, t[k].str) != NULL;
}

static int64_t eval_cond(struct eval *e, bool live);

static int64_t eval_number(struct eval *e, const struct sl_token *t)
{
	uint64_t v = 0;
	for (uint32_t k = 0; k < t->len; k++) {
		char c = t->text[k];
		if (c < '0' || c > '9') {
			bool fp = c == '.' || c == 'e' || c == 'E' || c == 'f' || c == 'F';
			eval_error(e, fp ? "floating constant" : "invalid integer constant");
			return 0;
		}
		v = v * 10 + (uint64_t)(c - '0');
	}
	return (int64_t)v;
}

/* unary: ('+' | '-' | '!' | '~') unary | '(' cond ')' | number | ident | defined-op */
static int64_t eval_unary(struct eval *e, bool live)
{
	if (e->err)
		return 0;
	if (++e->depth > MAX_NESTING) {
		eval_error(e, "expression nested too deeply");
		return 0;
	}
	int64_t v = 0;
	const struct sl_token *t = eval_peek(e, 0);
	if (!t) {
		eval_error(e, "expected a value");
	} else if (t->kind == SL_TOK_PLUS || t->kind == SL_TOK_MINUS || t->kind == SL_TOK_BANG ||
		   is_other(t, '~')) {
		e->i++;
		uint64_t u = (uint64_t)eval_unary(e, live);
		if (t->kind == SL_TOK_PLUS)
			v = (int64_t)u;
		else if (t->kind == SL_TOK_MINUS)
			v = (int64_t)(0 - u);
		else if (t->kind == SL_TOK_BANG)
			v = u == 0;
		else
			v = (int64_t)~u;
	} else if (t->kind == SL_TOK_LPAREN) {
		e->i++;
		v = eval_cond(e, live);
		if (!e->err) {
			t = eval_peek(e, 0);
			if (t && t->kind == SL_TOK_RPAREN)
				e->i++;
			else
				eval_error(e, "missing ')'");
		}
	} else if (t->kind == SL_TOK_NUMBER) {
		v = eval_number(e, t);
		e->i++;
	} else if (is_ident(t, "defined")) {
		e->i++;
		v = eval_defined(e->pp, e->t, e->n, &e->i, t->loc, &e->err);
	} else if (t->kind == SL_TOK_IDENT) {
		e->i++; /* names that are no macros are 0 */
	} else {
		eval_error(e, "expected a value");
	}
	e->depth--;
	return v;
}

enum binop { OP_NONE, OP_OR, OP_AND, OP_BITOR, OP_XOR, OP_BITAND, OP_EQ, OP_NE, OP_LT, OP_LE,
	     OP_GT, OP_GE, OP_SHL, OP_SHR, OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_MOD };

static const int op_prec[] = {
	[OP_OR] = 1, [OP_AND] = 2, [OP_BITOR] = 3, [OP_XOR] = 4, [OP_BITAND] = 5,
	[OP_EQ] = 6, [OP_NE] = 6, [OP_LT] = 7, [OP_LE] = 7, [OP_GT] = 7, [OP_GE] = 7,
	[OP_SHL] = 8, [OP_SHR] = 8, [OP_ADD] = 9, [OP_SUB] = 9,
	[OP_MUL] = 10, [OP_DIV] = 10, [OP_MOD] = 10,
};

/* The operator at the read position and how many tokens it takes. */
static enum binop eval_binop(const struct eval *e, size_t *ntok)
{
	const struct sl_token *t = eval_peek(e, 0), *u = eval_peek(e, 1);
	*ntok = 1;
	if (!t)
		return OP_NONE;
	bool twin = u && u->kind == t->kind && !(u->flags & (SL_TOKF_SPACE | SL_TOKF_BOL));
	switch (t->kind) {
	case SL_TOK_OR: return OP_OR;
	case SL_TOK_AND: return OP_AND;
	case SL_TOK_CARET: return OP_XOR;
	case SL_TOK_EQ: return OP_EQ;
	case SL_TOK_NE: return OP_NE;
	case SL_TOK_LE: return OP_LE;
	case SL_TOK_GE: return OP_GE;
	case SL_TOK_PLUS: return OP_ADD;
	case SL_TOK_MINUS: return OP_SUB;
	case SL_TOK_STAR: return OP_MUL;
	case SL_TOK_SLASH: return OP_DIV;
	case SL_TOK_PERCENT: return OP_MOD;
	case SL_TOK_LT:
	case SL_TOK_GT:
		if (twin) {
			*ntok = 2;
			return t->kind == SL_TOK_LT ? OP_SHL : OP_SHR;
		}
		return t->kind == SL_TOK_LT ? OP_LT : OP_GT;
	default:
		break;
	}
	if (is_other(t, '&'))
		return OP_BITAND;
	if (is_other(t, '|'))
		return OP_BITOR;
	return OP_NONE;
}

static int64_t apply(struct eval *e, enum binop op, int64_t a, int64_t b, bool live,
		     const struct sl_token *optok)
{
	uint64_t ua = (uint64_t)a, ub = (uint64_t)b;
	switch (op) {
	case OP_BITOR: return (int64_t)(ua | ub);
	case OP_XOR: return (int64_t)(ua ^ ub);
	case OP_BITAND: return (int64_t)(ua & ub);
	case OP_EQ: return a == b;
	case OP_NE: return a != b;
	case OP_LT: return a < b;
	case OP_LE: return a <= b;
	case OP_GT: return a > b;
	case OP_GE: return a >= b;
	case OP_SHL: return b < 0 || b > 63 ? 0 : (int64_t)(ua << b);
	case OP_SHR:
		if (b < 0 || b > 63)
			return a < 0 ? -1 : 0;
		return a < 0 ? (int64_t)~(~ua >> b) : (int64_t)(ua >> b);
	case OP_ADD: return (int64_t)(ua + ub);
	case OP_SUB: return (int64_t)(ua - ub);
	case OP_MUL: return (int64_t)(ua * ub);
	case OP_DIV:
	case OP_MOD:
		if (b == 0) {
			if (live && !e->err) {
				e->err = true;
				pp_error(e->pp, optok->loc, "division by zero in #if");
			}
			return 0;
		}
		if (b == -1) /* INT64_MIN / -1 overflows */
			return op == OP_DIV ? (int64_t)(0 - ua) : 0;
		return op == OP_DIV ? a / b : a % b;
	default:
		return 0;
	}
}

/* binary: unary { binop unary }, by precedence climbing from @min */
static int64_t eval_binary(struct eval *e, int min, bool live)
{
	int64_t a = eval_unary(e, live);
	for (;;) {
		size_t ntok;
		enum binop op = eval_binop(e, &ntok);
		if (e->err || op == OP_NONE || op_prec[op] < min)
			return a;
		const struct sl_token *optok = eval_peek(e, 0);
		e->i += ntok;
		if (op == OP_AND || op == OP_OR) {
			bool rhs_live = live && (op == OP_AND ? a != 0 : a == 0);
			int64_t b = eval_binary(e, op_prec[op] + 1, rhs_live);
			a = op == OP_AND ? (a != 0 && b != 0) : (a != 0 || b != 0);
			continue;
		}
		int64_t b = eval_binary(e, op_prec[op] + 1, live);
		a = apply(e, op, a, b, live, optok);
	}
}

/* cond: binary [ '?' cond ':' cond ] */
static int64_t eval_cond(struct eval *e, bool live)
{
	if (++e->depth > MAX_NESTING) {
		eval_error(e, "expression nested too deeply");
		return 0;
	}
	int64_t c = eval_binary(e, 1, live);
	const struct sl_token *t = eval_peek(e, 0);
	if (!e->err && t && t->kind == SL_TOK_QUESTION) {
		e->i++;
		int64_t a = eval_cond(e, live && c);
		t = eval_peek(e, 0);
		if (!e->err && !(t && t->kind == SL_TOK_COLON))
			eval_error(e, "missing ':'");
		e->i++;
		int64_t b = eval_cond(e, live && !c);
		c = c ? a : b;
	}
	e->depth--;
	return c;
}

/* The value of the #if/#elif expression in @n tokens; false after an error. */
static bool eval_if(struct pp *pp, const struct sl_token *toks, size_t n, struct sl_loc loc)
{
	if (n == 0) {
		pp_error(pp, loc, "#if with no expression");
		return false;
	}
	/* defined X is decided before the line is expanded */
	struct sl_token_list pre = { 0 }, line = { 0 };
	bool err = false;
	for (size_t i = 0; i < n;) {
		if (is_ident(&toks[i], "defined")) {
			struct sl_token one = toks[i];
			i++;
			int64_t v = eval_defined(pp, toks, n, &i, one.loc, &err);
			one.kind = SL_TOK_NUMBER;
			one.text = v ? "1" : "0";
			one.len = 1;
			one.num = (double)v;
			rl_vec_push(pre, one);
			continue;
		}
		rl_vec_push(pre, toks[i]);
		i++;
	}
	if (!err)
		expand_list(pp, pre.data, pre.len, &line);
	struct eval e = { .pp = pp, .t = line.data, .n = line.len, .loc = loc, .err = err };
	int64_t v = 0;
	if (!err) {
		v = eval_cond(&e, true);
		if (!e.err && e.i < e.n)
			eval_error(&e, "unexpected token");
	}
	rl_vec_free(pre);
	rl_vec_free(line);
	return !e.err && v != 0;
}

/* Files and directives */

struct file {
	uint32_t index;
	const char *path;
	struct sl_token_list toks;
	struct stream s;
	size_t cond_base; /* conds.len when the file began */
};

static bool skipping(const struct pp *pp)
{
	return pp->conds.len && !pp->conds.data[pp->conds.len - 1].active;
}

static void process(struct pp *pp, struct file *f);

enum read_result { READ_OK, READ_MISSING, READ_TOO_BIG };

/* Read the file at @path into the arena. */
static enum read_result read_source(struct pp *pp, const char *path, char **src, size_t *len)
{
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return READ_MISSING;
	struct rl_strbuf b = { 0 };
	char chunk[16384];
	size_t n;
	enum read_result r = READ_OK;
	while ((n = fread(chunk, 1, sizeof(chunk), fp)) > 0) {
		rl_strbuf_add(&b, chunk, n);
		if (pp->included_bytes + b.len > MAX_INCLUDED_BYTES) {
			r = READ_TOO_BIG;
			break;
		}
	}
	if (r == READ_OK && ferror(fp))
		r = READ_MISSING;
	fclose(fp);
	if (r == READ_OK) {
		*len = b.len;
		*src = rl_arena_strndup(pp->ctx->arena, rl_strbuf_str(&b), b.len);
	}
	rl_strbuf_finish(&b);
	return r;
}

/* Lex and process the file @path (index @index) whose text is @src. */
static void process_source(struct pp *pp, const char *path, uint32_t index, const char *src,
			   size_t len)
{
	struct file f = { .index = index, .path = path, .cond_base = pp->conds.len };
	rl_hash128_add(&pp->ctx->source_hash, src, len);
	rl_hash128_add(&pp->ctx->source_hash, "", 1);
	if (!sl_lex_pp(pp->ctx, index, src, len, &f.toks))
		pp->failed = true;
	f.s = (struct stream){ .base = f.toks.data, .nbase = f.toks.len, .is_file = true };
	process(pp, &f);
	pp->eof_loc = f.toks.data[f.toks.len - 1].loc;
	stream_finish(&f.s);
	rl_vec_free(f.toks);
}

/* The directory part of @path with its trailing '/', or "" when it has none. */
static size_t dir_len(const char *path)
{
	const char *slash = strrchr(path, '/');
	return slash ? (size_t)(slash - path) + 1 : 0;
}

/* Include @dir/@name if it can be read; false if it cannot. */
static bool try_include(struct pp *pp, const char *dir, size_t dlen, const char *name,
			struct sl_loc loc)
{
	struct rl_strbuf p = { 0 };
	rl_strbuf_add(&p, dir, dlen);
	if (dlen && dir[dlen - 1] != '/')
		rl_strbuf_putc(&p, '/');
	rl_strbuf_puts(&p, name);
	size_t len = 0;
	char *src = NULL;
	enum read_result r = read_source(pp, rl_strbuf_str(&p), &src, &len);
	if (r == READ_OK) {
		pp->included_bytes += len;
		uint32_t index = sl_ctx_add_file(pp->ctx, rl_strbuf_str(&p));
		const char *path = pp->ctx->files.data[index];
		pp->include_depth++;
		process_source(pp, path, index, src, len);
		pp->include_depth--;
	} else if (r == READ_TOO_BIG) {
		pp_error(pp, loc, "too much included source in '%s'", rl_strbuf_str(&p));
	}
	rl_strbuf_finish(&p);
	return r != READ_MISSING;
}

/* include-line: '"' name '"' | '<' tokens '>' | tokens that expand to one of these */
static void do_include(struct pp *pp, struct file *f, const struct sl_token *d,
		       const struct sl_token *t, size_t n)
{
	struct sl_token_list expanded = { 0 };
	if (n && t[0].kind != SL_TOK_STRING && t[0].kind != SL_TOK_LT) {
		expand_list(pp, t, n, &expanded);
		t = expanded.data;
		n = expanded.len;
	}
	struct rl_strbuf name = { 0 };
	size_t used = 0;
	if (n && t[0].kind == SL_TOK_STRING && t[0].len >= 2 && t[0].text[t[0].len - 1] == '"') {
		rl_strbuf_add(&name, t[0].text + 1, t[0].len - 2);
		used = 1;
	} else if (n && t[0].kind == SL_TOK_LT) {
		size_t k = 1;
		for (; k < n && t[k].kind != SL_TOK_GT; k++) {
			if (k > 1 && (t[k].flags & SL_TOKF_SPACE))
				rl_strbuf_putc(&name, ' ');
			rl_strbuf_add(&name, t[k].text, t[k].len);
		}
		used = k < n ? k + 1 : 0;
	}
	struct sl_loc loc = n ? t[0].loc : d->loc;
	if (!used || !name.len) {
		pp_error(pp, loc, "#include expects \"FILENAME\" or <FILENAME>");
		goto done;
	}
	if (used < n)
		pp_warning(pp, t[used].loc, "extra tokens at end of #include near '%.*s'",
			   quote_len(&t[used]), t[used].text);
	if (++pp->nincludes > MAX_INCLUDES) {
		if (!pp->include_cap_hit)
			pp_error(pp, loc, "too many #include directives");
		pp->include_cap_hit = true;
		goto done;
	}
	if (pp->include_depth >= MAX_INCLUDE_DEPTH) {
		pp_error(pp, loc, "#include nested too deeply");
		goto done;
	}
	const char *fname = rl_strbuf_str(&name);
	bool found;
	if (fname[0] == '/') {
		found = try_include(pp, "", 0, fname, loc);
	} else {
		found = try_include(pp, f->path, dir_len(f->path), fname, loc);
		const struct sl_options *o = &pp->ctx->opts;
		for (size_t i = 0; !found && i < o->n_include_dirs; i++)
			if (o->include_dirs[i])
				found = try_include(pp, o->include_dirs[i],
						    strlen(o->include_dirs[i]), fname, loc);
	}
	if (!found)
		pp_error(pp, loc, "cannot find include file '%s'", fname);
done:
	rl_strbuf_finish(&name);
	rl_vec_free(expanded);
}

static bool same_definition(const struct macro *m, bool fn, bool variadic, const char **params,
			    size_t np, const struct sl_token *body, size_t nb)
{
	if (m->function_like != fn || m->variadic != variadic || m->nparams != np ||
	    m->nbody != nb)
		return false;
	for (size_t i = 0; i < np; i++)
		if (m->params[i] != params[i])
			return false;
	for (size_t i = 0; i < nb; i++) {
		const struct sl_token *a = &m->body[i], *b = &body[i];
		if (a->kind != b->kind || a->len != b->len || memcmp(a->text, b->text, a->len) ||
		    (i && (a->flags & SL_TOKF_SPACE) != (b->flags & SL_TOKF_SPACE)))
			return false;
	}
	return true;
}

/* define-line: ident [ '(' [ params ] ')' ] tokens  (no space before a parameter list's '(') */
static void do_define(struct pp *pp, struct sl_loc loc, const struct sl_token *t, size_t n)
{
	if (!n || t[0].kind != SL_TOK_IDENT) {
		pp_error(pp, n ? t[0].loc : loc, "macro names must be identifiers");
		return;
	}
	const char *name = t[0].str;
	if (name == pp->name_defined) {
		pp_error(pp, t[0].loc, "'defined' cannot be used as a macro name");
		return;
	}
	size_t i = 1;
	bool fn = false, variadic = false;
	RL_VEC(const char *) params = { 0 };
	if (i < n && t[i].kind == SL_TOK_LPAREN && !(t[i].flags & SL_TOKF_SPACE)) {
		fn = true;
		i++;
		bool ok = false;
		if (i < n && t[i].kind == SL_TOK_RPAREN) {
			i++;
			ok = true;
		}
		while (!ok && i < n) {
			if (i + 2 < n && t[i].kind == SL_TOK_DOT && t[i + 1].kind == SL_TOK_DOT &&
			    t[i + 2].kind == SL_TOK_DOT) {
				variadic = true;
				rl_vec_push(params, pp->name_va_args);
				i += 3;
				ok = i < n && t[i].kind == SL_TOK_RPAREN;
				i++;
				break;
			}
			if (t[i].kind != SL_TOK_IDENT || t[i].str == pp->name_va_args)
				break;
			for (size_t k = 0; k < params.len; k++) {
				if (params.data[k] == t[i].str) {
					pp_error(pp, t[i].loc, "duplicate macro parameter '%s'",
						 t[i].str);
					goto out;
				}
			}
			if (params.len >= MAX_PARAMS) {
				pp_error(pp, t[i].loc, "too many macro parameters");
				goto out;
			}
			rl_vec_push(params, t[i].str);
			i++;
			if (i < n && t[i].kind == SL_TOK_COMMA) {
				i++;
			} else {
				ok = i < n && t[i].kind == SL_TOK_RPAREN;
				i++;
				break;
			}
		}
		if (!ok) {
			size_t k = i - 1 < n ? i - 1 : n - 1;
			pp_error(pp, t[k].loc, "bad macro parameter list near '%.*s'",
				 quote_len(&t[k]), t[k].text);
			goto out;
		}
	}

	const struct sl_token *body = t + i;
	size_t nb = n - i;
	if (nb && (body[0].kind == SL_TOK_HASHHASH || body[nb - 1].kind == SL_TOK_HASHHASH)) {
		const struct sl_token *bad = body[0].kind == SL_TOK_HASHHASH ? &body[0] : &body[nb - 1];
		pp_error(pp, bad->loc, "'##' cannot appear at either end of a macro expansion");
		goto out;
	}
	if (fn) {
		for (size_t k = 0; k < nb; k++) {
			if (!is_hash(&body[k]))
				continue;
			bool param = false;
			if (k + 1 < nb && body[k + 1].kind == SL_TOK_IDENT)
				for (size_t p = 0; p < params.len; p++)
					param = param || params.data[p] == body[k + 1].str;
			if (!param) {
				pp_error(pp, body[k].loc, "'#' is not followed by a macro parameter");
				goto out;
			}
		}
	}

	struct macro *m = get_macro(pp, name);
	if (m->defined) {
		if (same_definition(m, fn, variadic, params.data, params.len, body, nb))
			goto out;
		pp_warning(pp, t[0].loc, "'%s' redefined", name);
	}
	m->defined = true;
	m->function_like = fn;
	m->variadic = variadic;
	m->nparams = params.len;
	m->params = NULL;
	if (params.len) {
		m->params = rl_arena_alloc(pp->ctx->arena, params.len * sizeof(*m->params));
		memcpy(m->params, params.data, params.len * sizeof(*m->params));
	}
	m->nbody = nb;
	m->body = NULL;
	m->param_of = NULL;
	if (nb && params.len) {
		m->param_of = rl_arena_alloc(pp->ctx->arena, nb * sizeof(*m->param_of));
		for (size_t k = 0; k < nb; k++) {
			m->param_of[k] = -1;
			for (size_t p = 0; body[k].kind == SL_TOK_IDENT && p < params.len; p++)
				if (params.data[p] == body[k].str)
					m->param_of[k] = (int)p;
		}
	}
	if (nb) {
		m->body = rl_arena_alloc(pp->ctx->arena, nb * sizeof(*m->body));
		for (size_t k = 0; k < nb; k++) {
			m->body[k] = body[k];
			m->body[k].flags &= SL_TOKF_SPACE;
		}
		m->body[0].flags &= (uint8_t)~SL_TOKF_SPACE;
	}
out:
	rl_vec_free(params);
}

/* The rest of a directive line as text, for #error and #warning. */
static const char *line_text(struct pp *pp, const struct sl_token *t, size_t n)
{
	rl_strbuf_reset(&pp->sb);
	for (size_t i = 0; i < n; i++) {
		if (i && (t[i].flags & SL_TOKF_SPACE))
			rl_strbuf_putc(&pp->sb, ' ');
		rl_strbuf_add(&pp->sb, t[i].text, t[i].len);
	}
	return rl_strbuf_str(&pp->sb);
}

static void extra_tokens(struct pp *pp, const char *dir, const struct sl_token *t, size_t n)
{
	if (n)
		pp_warning(pp, t[0].loc, "extra tokens at end of #%s near '%.*s'", dir,
			   quote_len(&t[0]), t[0].text);
}

/* A name after #ifdef, #ifndef or #undef. */
static const char *directive_name(struct pp *pp, const char *dir, struct sl_loc loc,
				  const struct sl_token *t, size_t n)
{
	if (!n || t[0].kind != SL_TOK_IDENT) {
		pp_error(pp, n ? t[0].loc : loc, "#%s expects a macro name", dir);
		return NULL;
	}
	extra_tokens(pp, dir, t + 1, n - 1);
	return t[0].str;
}

/*
 * directive: '#' [ name tokens ] up to the end of the line, the '#' at
 * f->s.pos. In a skipped group only the conditionals count.
 */
static void directive(struct pp *pp, struct file *f)
{
	const struct sl_token *base = f->toks.data;
	size_t start = f->s.pos, end = start + 1;
	while (base[end].kind != SL_TOK_EOF &&
	       (base[end].flags & (SL_TOKF_BOL | TOKF_COMMENT_LINE)) != SL_TOKF_BOL)
		end++;
	f->s.pos = end;
	const struct sl_token *hash = &base[start];
	if (end == start + 1)
		return; /* the null directive */
	const struct sl_token *d = &base[start + 1];
	const struct sl_token *rest = d + 1;
	size_t n = end - start - 2;
	const char *dir = d->kind == SL_TOK_IDENT ? d->str : "";
	bool skip = skipping(pp);

	if (!strcmp(dir, "if") || !strcmp(dir, "ifdef") || !strcmp(dir, "ifndef")) {
		struct cond c = { .loc = hash->loc };
		if (skip) {
			c.taken = true;
		} else if (dir[2] == '\0') {
			c.active = eval_if(pp, rest, n, d->loc);
		} else {
			const char *name = directive_name(pp, dir, d->loc, rest, n);
			c.active = name && (find_macro(pp, name) != NULL) == (dir[2] == 'd');
		}
		c.taken = c.taken || c.active;
		rl_vec_push(pp->conds, c);
		return;
	}
	if (!strcmp(dir, "elif") || !strcmp(dir, "else") || !strcmp(dir, "endif")) {
		if (pp->conds.len <= f->cond_base) {
			pp_error(pp, d->loc, "#%s without #if", dir);
			return;
		}
		struct cond *c = &pp->conds.data[pp->conds.len - 1];
		if (dir[1] == 'n') { /* endif */
			if (c->active)
				extra_tokens(pp, dir, rest, n);
			pp->conds.len--;
			return;
		}
		if (c->seen_else) {
			pp_error(pp, d->loc, "#%s after #else", dir);
			return;
		}
		if (dir[2] == 's') { /* else */
			c->seen_else = true;
			c->active = !c->taken;
			c->taken = true;
			if (c->active)
				extra_tokens(pp, dir, rest, n);
			return;
		}
		c->active = false;
		if (!c->taken) {
			c->active = eval_if(pp, rest, n, d->loc);
			c->taken = c->active;
		}
		return;
	}
	if (skip)
		return;

	if (!strcmp(dir, "define")) {
		do_define(pp, d->loc, rest, n);
	} else if (!strcmp(dir, "undef")) {
		const char *name = directive_name(pp, dir, d->loc, rest, n);
		struct macro *m = name ? find_macro(pp, name) : NULL;
		if (m)
			m->defined = false;
	} else if (!strcmp(dir, "include")) {
		do_include(pp, f, d, rest, n);
	} else if (!strcmp(dir, "error")) {
		pp_error(pp, hash->loc, "%s", n ? line_text(pp, rest, n) : "#error");
	} else if (!strcmp(dir, "warning")) {
		pp_warning(pp, hash->loc, "%s", n ? line_text(pp, rest, n) : "#warning");
	} else if (!strcmp(dir, "pragma") || !strcmp(dir, "line")) {
		/* accepted and ignored */
	} else {
		pp_error(pp, d->loc, "invalid preprocessing directive near '#%.*s'", quote_len(d),
			 d->text);
	}
}

/* Run the directives of file @f and expand the rest into the output. */
static void process(struct pp *pp, struct file *f)
{
	struct stream *s = &f->s;
	for (;;) {
		const struct sl_token *p = stream_peek(s);
		if (!s->frames.len && (p->flags & SL_TOKF_BOL) && is_hash(p)) {
			directive(pp, f);
			continue;
		}
		if (p->kind == SL_TOK_EOF)
			break;
		if (skipping(pp)) {
			s->pos++;
			continue;
		}
		struct sl_token t = stream_next(pp, s);
		if (t.kind == SL_TOK_IDENT && try_expand(pp, s, &t))
			continue;
		emit(pp, t);
	}
	while (pp->conds.len > f->cond_base) {
		pp_error(pp, pp->conds.data[pp->conds.len - 1].loc,
			 "unterminated conditional directive");
		pp->conds.len--;
	}
}

/* -D NAME or NAME=VALUE, as a #define line of the file "<command line>". */
static void predefine(struct pp *pp, uint32_t index, const char *def)
{
	if (strpbrk(def, "\r\n")) {
		pp_error(pp, (struct sl_loc){ index, 1, 1 }, "invalid definition '%s'", def);
		return;
	}
	struct rl_strbuf b = { 0 };
	rl_strbuf_puts(&b, "#define ");
	const char *eq = strchr(def, '=');
	if (eq) {
		rl_strbuf_add(&b, def, (size_t)(eq - def));
		rl_strbuf_putc(&b, ' ');
		rl_strbuf_puts(&b, eq + 1);
	} else {
		rl_strbuf_puts(&b, def);
		rl_strbuf_puts(&b, " 1");
	}
	char *src = rl_arena_strndup(pp->ctx->arena, rl_strbuf_str(&b), b.len);
	size_t len = b.len;
	rl_strbuf_finish(&b);
	process_source(pp, pp->ctx->files.data[index], index, src, len);
}

bool sl_preprocess(struct sl_ctx *ctx, const char *path, const char *src, size_t len,
		   struct sl_token_list *out)
{
	struct pp pp = { .ctx = ctx, .out = out };
	pp.name_defined = sl_intern_cstr(ctx, "defined");
	pp.name_va_args = sl_intern_cstr(ctx, "__VA_ARGS__");
	for (size_t i = 0; i < sizeof(keyword_names) / sizeof(keyword_names[0]); i++)
		pp.keywords[i] = sl_intern_cstr(ctx, keyword_names[i]);
	if (!path)
		path = "<input>";
	uint32_t index = sl_ctx_add_file(ctx, path);
	path = ctx->files.data[index];

	struct macro *m = get_macro(&pp, sl_intern_cstr(ctx, "__RELIGHT__"));
	m->defined = true;
	m->nbody = 1;
	m->body = rl_arena_alloc(ctx->arena, sizeof(*m->body));
	m->body[0] = (struct sl_token){
		.kind = SL_TOK_NUMBER, .len = 1, .text = "1", .num = 1,
		.loc = { index, 1, 1 },
	};
	if (ctx->opts.n_defines) {
		uint32_t cl = sl_ctx_add_file(ctx, "<command line>");
		for (size_t i = 0; i < ctx->opts.n_defines; i++)
			if (ctx->opts.defines[i]) {
				rl_hash128_str(&ctx->source_hash, ctx->opts.defines[i]);
				predefine(&pp, cl, ctx->opts.defines[i]);
			}
	}

	/* the tokens' spellings point into the source: keep a copy that lives as long */
	char *copy = rl_arena_strndup(ctx->arena, src ? src : "", src ? len : 0);
	process_source(&pp, path, index, copy, src ? len : 0);

	struct sl_token eof = { .kind = SL_TOK_EOF, .flags = SL_TOKF_BOL, .text = "",
				.loc = pp.eof_loc };
	rl_vec_push(*out, eof);

	free(pp.slots);
	rl_vec_free(pp.conds);
	rl_strbuf_finish(&pp.sb);
	return !pp.failed;
}

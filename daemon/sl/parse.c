/*
 * The RSL parser: recursive descent over the preprocessed token list, one
 * function per grammar rule, building the tree described in ast.h.
 *
 * Errors are reported where they are found and the offending rule returns
 * NULL, which every caller passes on untouched; the nearest statement list,
 * parameter list or the unit then skips to a point where parsing can resume
 * (see the sync functions), so one mistake gives one message and several
 * mistakes give several.
 *
 * Operator precedence follows the RenderMan Interface Specification 3.2:
 * unary operators bind tightest, then '.', then '*' and '/', then '^', then
 * '+' and '-', then the relations, '&&', '||', '?:' and assignment.
 *
 * Parenthesized tuples without a type name, `(a, b, c)` and the sixteen-value
 * `(m00, ..., m33)`, become CTOR nodes whose type.base is SL_TYPE_VOID: their
 * type (color, point, vector, normal or matrix) is not known here and comes
 * from the context in which they are used, which semantic analysis resolves.
 *
 * Nesting is limited to MAX_DEPTH levels of statements, parenthesized,
 * prefixed or called expressions and right operands, so no pass that walks
 * the tree recursively can run out of stack. A flat chain of left-associative
 * operators (`a + b + c + ...`, as generated shaders have by the thousand) is
 * not nesting: every pass walks its left spine in a loop, so it is bounded
 * by its size instead, MAX_EXPR_OPS operators in one expression.
 */
#include "ast.h"
#include "builtin.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DEPTH 256
#define MAX_EXPR_OPS 100000
#define MAX_ARRAY_LEN (1 << 20)
#define MAX_SPELLING 40

/* Names of the functions defined so far, for telling `point space (x, y, z)`
 * from `point func (x, y, z)`. Open addressing on the interned pointers. */
struct name_set {
	const char **slots;
	size_t cap, count;
};

struct parser {
	struct sl_ctx *ctx;
	const struct sl_token *toks;
	size_t ntoks;              /* up to and including the first EOF */
	size_t pos;
	struct sl_token eof;       /* stands in for a missing final EOF */
	int depth;
	int expr_nest;             /* parse_expr calls open: 0 outside expressions */
	uint32_t expr_ops;         /* binary operators of the outermost expression so far */
	bool fatal;                /* nesting too deep: give up on the whole unit */
	struct name_set funcs;
};

/* An array of nodes grown in the arena (at most twice the final size). */
struct node_list {
	struct sl_ast **data;
	uint32_t len, cap;
};

typedef struct sl_ast *(*parse_fn)(struct parser *p);

static struct sl_ast *parse_expr(struct parser *p);
static struct sl_ast *parse_conditional(struct parser *p);
static struct sl_ast *parse_unary(struct parser *p);
static struct sl_ast *parse_statement(struct parser *p);
static struct sl_ast *parse_block(struct parser *p);

/* ---- tokens ---- */

static const struct sl_token *cur(const struct parser *p)
{
	return p->pos < p->ntoks ? &p->toks[p->pos] : &p->eof;
}

static const struct sl_token *peek(const struct parser *p, size_t k)
{
	return p->pos + k < p->ntoks ? &p->toks[p->pos + k] : &p->eof;
}

/* The token just consumed (only called right after a successful advance). */
static const struct sl_token *prev(const struct parser *p)
{
	return p->pos > 0 ? &p->toks[p->pos - 1] : cur(p);
}

static enum sl_tok kind(const struct parser *p)
{
	return cur(p)->kind;
}

static void advance(struct parser *p)
{
	if (p->pos < p->ntoks && p->toks[p->pos].kind != SL_TOK_EOF)
		p->pos++;
}

static bool accept(struct parser *p, enum sl_tok k)
{
	if (kind(p) != k)
		return false;
	advance(p);
	return true;
}

static bool stopped(const struct parser *p)
{
	return p->fatal || p->ctx->too_many;
}

/* The interned name of an identifier or keyword token. */
static const char *tok_name(struct parser *p, const struct sl_token *t)
{
	if (t->str)
		return t->str;
	return sl_intern(p->ctx, t->text ? t->text : "", t->text ? t->len : 0);
}

/* ---- diagnostics ---- */

static void error_near(struct parser *p, const struct sl_token *t, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* "MESSAGE near 'tok'" at @t, or "near end of file". */
static void error_near(struct parser *p, const struct sl_token *t, const char *fmt, ...)
{
	if (stopped(p))
		return;
	char msg[256];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);

	if (t->kind == SL_TOK_EOF) {
		sl_error(p->ctx, t->loc, "%s near end of file", msg);
		return;
	}
	const char *text = t->text ? t->text : "";
	size_t len = t->text ? t->len : 0;
	/* Long string literals are cut short, and a token never runs past a newline. */
	size_t shown = 0;
	while (shown < len && shown < MAX_SPELLING && text[shown] != '\n' && text[shown] != '\0')
		shown++;
	sl_error(p->ctx, t->loc, "%s near '%.*s%s'", msg, (int)shown, text,
		 shown < len ? "..." : "");
}

static bool expect(struct parser *p, enum sl_tok k)
{
	if (accept(p, k))
		return true;
	error_near(p, cur(p), "expected %s", sl_tok_name(k));
	return false;
}

/* Count one more level of nesting; false (reported once) past MAX_DEPTH. */
static bool enter(struct parser *p)
{
	if (p->fatal)
		return false;
	if (p->depth >= MAX_DEPTH) {
		error_near(p, cur(p), "nesting too deep");
		p->fatal = true;
		return false;
	}
	p->depth++;
	return true;
}

static void leave(struct parser *p)
{
	p->depth--;
}

/*
 * Resume after a broken statement: skip past the next ';' outside braces, or
 * past the '}' that closes a block opened after the error; stop before a '}'
 * that closes the enclosing block.
 */
static void sync_statement(struct parser *p)
{
	int depth = 0;
	for (;;) {
		switch (kind(p)) {
		case SL_TOK_EOF:
			return;
		case SL_TOK_SEMI:
			advance(p);
			if (depth == 0)
				return;
			break;
		case SL_TOK_LBRACE:
			depth++;
			advance(p);
			break;
		case SL_TOK_RBRACE:
			if (depth == 0)
				return;
			advance(p);
			if (--depth == 0)
				return;
			break;
		default:
			advance(p);
			break;
		}
	}
}

/* Resume after a broken definition: past the next ';' at the outer level or
 * the '}' that ends a body (a stray '}' is skipped too). */
static void sync_definition(struct parser *p)
{
	int depth = 0;
	while (kind(p) != SL_TOK_EOF) {
		enum sl_tok k = kind(p);
		advance(p);
		if (k == SL_TOK_LBRACE)
			depth++;
		else if (k == SL_TOK_RBRACE && --depth <= 0)
			return;
		else if (k == SL_TOK_SEMI && depth == 0)
			return;
	}
}

/* Resume after a broken parameter: stop at the next ';' or ')' outside
 * parentheses, or at the '{' of the body. */
static void sync_formal(struct parser *p)
{
	int depth = 0;
	for (;;) {
		switch (kind(p)) {
		case SL_TOK_EOF:
		case SL_TOK_LBRACE:
			return;
		case SL_TOK_SEMI:
			if (depth == 0)
				return;
			break;
		case SL_TOK_LPAREN:
			depth++;
			break;
		case SL_TOK_RPAREN:
			if (depth == 0)
				return;
			depth--;
			break;
		default:
			break;
		}
		advance(p);
	}
}

/* ---- helpers ---- */

static void list_push(struct parser *p, struct node_list *l, struct sl_ast *n)
{
	if (l->len == l->cap) {
		uint32_t ncap = l->cap ? l->cap * 2 : 4;
		struct sl_ast **data = rl_arena_alloc(p->ctx->arena, ncap * sizeof(*data));
		if (l->len)
			memcpy(data, l->data, l->len * sizeof(*data));
		l->data = data;
		l->cap = ncap;
	}
	l->data[l->len++] = n;
}

static void set_list(struct sl_ast *n, const struct node_list *l)
{
	n->list = l->data;
	n->nlist = l->len;
}

static struct sl_ast *new_node(struct parser *p, enum sl_ast_kind k, const struct sl_token *t)
{
	return sl_ast_new(p->ctx, k, t->loc);
}

static size_t name_hash(const char *name, size_t cap)
{
	uint64_t h = (uint64_t)(uintptr_t)name * 0x9e3779b97f4a7c15ull;
	return (size_t)(h >> 32) & (cap - 1);
}

static void name_set_add(struct name_set *s, const char *name)
{
	if (s->count * 2 >= s->cap) {
		size_t ncap = s->cap ? s->cap * 2 : 64;
		const char **slots = rl_xcalloc(ncap, sizeof(*slots));
		for (size_t i = 0; i < s->cap; i++) {
			if (!s->slots[i])
				continue;
			size_t j = name_hash(s->slots[i], ncap);
			while (slots[j])
				j = (j + 1) & (ncap - 1);
			slots[j] = s->slots[i];
		}
		free(s->slots);
		s->slots = slots;
		s->cap = ncap;
	}
	size_t j = name_hash(name, s->cap);
	while (s->slots[j]) {
		if (s->slots[j] == name)
			return;
		j = (j + 1) & (s->cap - 1);
	}
	s->slots[j] = name;
	s->count++;
}

static bool name_set_has(const struct name_set *s, const char *name)
{
	if (!s->cap)
		return false;
	size_t j = name_hash(name, s->cap);
	while (s->slots[j]) {
		if (s->slots[j] == name)
			return true;
		j = (j + 1) & (s->cap - 1);
	}
	return false;
}

/* The base type a type keyword names, or -1. */
static int keyword_basetype(enum sl_tok k)
{
	switch (k) {
	case SL_TOK_KW_FLOAT: return SL_TYPE_FLOAT;
	case SL_TOK_KW_COLOR: return SL_TYPE_COLOR;
	case SL_TOK_KW_POINT: return SL_TYPE_POINT;
	case SL_TOK_KW_VECTOR: return SL_TYPE_VECTOR;
	case SL_TOK_KW_NORMAL: return SL_TYPE_NORMAL;
	case SL_TOK_KW_MATRIX: return SL_TYPE_MATRIX;
	case SL_TOK_KW_STRING: return SL_TYPE_STRING;
	case SL_TOK_KW_VOID: return SL_TYPE_VOID;
	default: return -1;
	}
}

static bool is_value_type(enum sl_tok k)
{
	return keyword_basetype(k) > SL_TYPE_VOID;
}

static int shader_kind(enum sl_tok k)
{
	switch (k) {
	case SL_TOK_KW_SURFACE: return SL_SHADER_SURFACE;
	case SL_TOK_KW_LIGHT: return SL_SHADER_LIGHT;
	case SL_TOK_KW_DISPLACEMENT: return SL_SHADER_DISPLACEMENT;
	case SL_TOK_KW_VOLUME: return SL_SHADER_VOLUME;
	case SL_TOK_KW_IMAGER: return SL_SHADER_IMAGER;
	default: return -1;
	}
}

static bool is_assign_op(enum sl_tok k)
{
	return k == SL_TOK_ASSIGN || k == SL_TOK_PLUS_ASSIGN || k == SL_TOK_MINUS_ASSIGN ||
	       k == SL_TOK_STAR_ASSIGN || k == SL_TOK_SLASH_ASSIGN;
}

static bool is_lvalue(const struct sl_ast *n)
{
	return n->kind == SL_AST_IDENT || n->kind == SL_AST_INDEX;
}

/*
 * True when the tokens from the current one read
 * `{ uniform | varying } (TYPE | void) IDENT (`: a function definition.
 */
static bool at_function_definition(const struct parser *p)
{
	size_t k = 0;
	while (peek(p, k)->kind == SL_TOK_KW_UNIFORM || peek(p, k)->kind == SL_TOK_KW_VARYING)
		k++;
	if (keyword_basetype(peek(p, k)->kind) < 0)
		return false;
	return peek(p, k + 1)->kind == SL_TOK_IDENT && peek(p, k + 2)->kind == SL_TOK_LPAREN;
}

/* A NUMBER token holding a whole number in [1, max], else -1. */
static long positive_int(const struct sl_token *t, long max)
{
	if (t->kind != SL_TOK_NUMBER || !(t->num >= 1 && t->num <= (double)max) ||
	    t->num != floor(t->num))
		return -1;
	return (long)t->num;
}

/* ---- expressions ---- */

/*
 * args: [ expression { ',' expression } ] ')'
 * (the opening parenthesis is already consumed)
 */
static bool parse_args(struct parser *p, struct node_list *out)
{
	if (accept(p, SL_TOK_RPAREN))
		return true;
	for (;;) {
		struct sl_ast *e = parse_expr(p);
		if (!e)
			return false;
		list_push(p, out, e);
		if (accept(p, SL_TOK_COMMA))
			continue;
		return expect(p, SL_TOK_RPAREN);
	}
}

/* string: STRING { STRING }   (adjacent literals are joined) */
static struct sl_ast *parse_string(struct parser *p)
{
	const struct sl_token *first = cur(p);
	size_t total = 0, n = 0;
	while (peek(p, n)->kind == SL_TOK_STRING) {
		const char *s = peek(p, n)->str;
		total += s ? strlen(s) : 0;
		n++;
	}
	struct sl_ast *node = new_node(p, SL_AST_STR, first);
	char *buf = rl_arena_alloc(p->ctx->arena, total + 1);
	size_t at = 0;
	for (size_t i = 0; i < n; i++) {
		const char *s = cur(p)->str;
		if (s) {
			size_t len = strlen(s);
			memcpy(buf + at, s, len);
			at += len;
		}
		advance(p);
	}
	buf[at] = '\0';
	node->str = buf;
	return node;
}

/* call: name '(' args   (the name and the parenthesis are already consumed) */
static struct sl_ast *finish_call(struct parser *p, const struct sl_token *name)
{
	struct sl_ast *call = new_node(p, SL_AST_CALL, name);
	call->name = tok_name(p, name);
	struct node_list args = {0};
	if (!parse_args(p, &args))
		return NULL;
	set_list(call, &args);
	return call;
}

/*
 * primary: NUMBER | string | IDENT | IDENT '(' args
 *        | shader_kind '(' args
 *        | '(' expression ')'
 *        | '(' expression ',' expression ',' expression ')'
 *        | '(' expression { ',' expression } ')'    (sixteen values)
 */
static struct sl_ast *parse_primary(struct parser *p)
{
	const struct sl_token *t = cur(p);
	switch (t->kind) {
	case SL_TOK_NUMBER: {
		struct sl_ast *n = new_node(p, SL_AST_NUM, t);
		n->num = t->num;
		advance(p);
		return n;
	}
	case SL_TOK_STRING:
		return parse_string(p);
	case SL_TOK_IDENT:
		advance(p);
		if (accept(p, SL_TOK_LPAREN))
			return finish_call(p, t);
		{
			struct sl_ast *n = new_node(p, SL_AST_IDENT, t);
			n->name = tok_name(p, t);
			return n;
		}
	case SL_TOK_KW_SURFACE:
	case SL_TOK_KW_LIGHT:
	case SL_TOK_KW_DISPLACEMENT:
	case SL_TOK_KW_VOLUME:
	case SL_TOK_KW_IMAGER:
		/* message passing: surface("Kd", x), displacement("Ps", y) */
		if (peek(p, 1)->kind != SL_TOK_LPAREN)
			break;
		advance(p);
		advance(p);
		return finish_call(p, t);
	case SL_TOK_LPAREN: {
		advance(p);
		struct node_list vals = {0};
		if (!parse_args(p, &vals))
			return NULL;
		if (vals.len == 1)
			return vals.data[0];
		if (vals.len != 3 && vals.len != 16) {
			error_near(p, prev(p),
				   "a parenthesized list needs 1, 3 or 16 values, not %u",
				   (unsigned)vals.len);
			return NULL;
		}
		/* a tuple typed by its context: see the comment at the top */
		struct sl_ast *n = new_node(p, SL_AST_CTOR, t);
		n->type.base = SL_TYPE_VOID;
		set_list(n, &vals);
		return n;
	}
	default:
		break;
	}
	error_near(p, t, "expected expression");
	return NULL;
}

/* The `{ '[' expression ']' | '++' | '--' }` part of postfix, applied to @e. */
static struct sl_ast *parse_postfix_rest(struct parser *p, struct sl_ast *e)
{
	int saved = p->depth;
	while (e) {
		const struct sl_token *t = cur(p);
		if (t->kind == SL_TOK_LBRACKET) {
			if (!enter(p))
				break;
			advance(p);
			struct sl_ast *idx = parse_expr(p);
			if (!idx || !expect(p, SL_TOK_RBRACKET)) {
				e = NULL;
				break;
			}
			struct sl_ast *n = new_node(p, SL_AST_INDEX, t);
			n->a = e;
			n->b = idx;
			e = n;
		} else if (t->kind == SL_TOK_INC || t->kind == SL_TOK_DEC) {
			if (!is_lvalue(e)) {
				error_near(p, t, "%s needs a variable or an array element",
					   sl_tok_name(t->kind));
				e = NULL;
				break;
			}
			if (!enter(p))
				break;
			advance(p);
			struct sl_ast *n = new_node(p, SL_AST_INCDEC, t);
			n->op = t->kind;
			n->a = e;
			n->num = 0;
			e = n;
		} else {
			break;
		}
	}
	p->depth = saved;
	return p->fatal ? NULL : e;
}

/* postfix: primary { '[' expression ']' | '++' | '--' } */
static struct sl_ast *parse_postfix(struct parser *p)
{
	return parse_postfix_rest(p, parse_primary(p));
}

/*
 * typecast: TYPE [ spacename ] '(' expression { ',' expression } ')'
 *         | TYPE [ spacename ] unary
 * spacename: string | IDENT      (color, point, vector, normal, matrix only)
 *
 * `point name (a, b, c)` is ambiguous: a space held in a string variable, or
 * a cast of a call. It is a call when `name` is a built-in or an already
 * defined function, or when the argument count (3 for triples, 16 for
 * matrices) does not fit a constructor.
 */
static struct sl_ast *parse_typecast(struct parser *p)
{
	const struct sl_token *t = cur(p);
	int base = keyword_basetype(t->kind);
	advance(p);
	if (base == SL_TYPE_VOID) {
		error_near(p, t, "expected expression");
		return NULL;
	}
	struct sl_ast *ctor = new_node(p, SL_AST_CTOR, t);
	ctor->type.base = (uint8_t)base;
	bool spaced = sl_type_is_triple(base) || base == SL_TYPE_MATRIX;
	struct node_list comps = {0};

	if (spaced && kind(p) == SL_TOK_STRING) {
		ctor->a = parse_string(p);
	} else if (spaced && kind(p) == SL_TOK_IDENT && peek(p, 1)->kind == SL_TOK_LPAREN) {
		const struct sl_token *name = cur(p);
		advance(p);
		advance(p);
		struct sl_ast *call = finish_call(p, name);
		if (!call)
			return NULL;
		uint32_t want = base == SL_TYPE_MATRIX ? 16 : 3;
		if (call->nlist == want && !name_set_has(&p->funcs, call->name) &&
		    sl_builtin_find(call->name) < 0) {
			struct sl_ast *space = new_node(p, SL_AST_IDENT, name);
			space->name = call->name;
			ctor->a = space;
			ctor->list = call->list;
			ctor->nlist = call->nlist;
			return ctor;
		}
		struct sl_ast *operand = parse_postfix_rest(p, call);
		if (!operand)
			return NULL;
		list_push(p, &comps, operand);
		set_list(ctor, &comps);
		return ctor;
	}

	if (accept(p, SL_TOK_LPAREN)) {
		const struct sl_token *open = prev(p);
		if (!parse_args(p, &comps))
			return NULL;
		if (comps.len != 1 && comps.len != 3 && comps.len != 16) {
			error_near(p, open, "a %s constructor needs 1, 3 or 16 values, not %u",
				   sl_basetype_name(base), (unsigned)comps.len);
			return NULL;
		}
	} else {
		struct sl_ast *operand = parse_unary(p);
		if (!operand)
			return NULL;
		list_push(p, &comps, operand);
	}
	set_list(ctor, &comps);
	return ctor;
}

/* unary: ('-' | '+' | '!') unary | ('++' | '--') unary | typecast | postfix */
static struct sl_ast *parse_unary(struct parser *p)
{
	const struct sl_token *t = cur(p);
	switch (t->kind) {
	case SL_TOK_MINUS:
	case SL_TOK_PLUS:
	case SL_TOK_BANG:
	case SL_TOK_INC:
	case SL_TOK_DEC: {
		if (!enter(p))
			return NULL;
		advance(p);
		struct sl_ast *operand = parse_unary(p);
		leave(p);
		if (!operand)
			return NULL;
		bool incdec = t->kind == SL_TOK_INC || t->kind == SL_TOK_DEC;
		if (incdec && !is_lvalue(operand)) {
			error_near(p, t, "%s needs a variable or an array element",
				   sl_tok_name(t->kind));
			return NULL;
		}
		struct sl_ast *n = new_node(p, incdec ? SL_AST_INCDEC : SL_AST_UNARY, t);
		n->op = t->kind;
		n->a = operand;
		n->num = incdec ? 1 : 0;
		return n;
	}
	default:
		if (keyword_basetype(t->kind) >= 0) {
			if (!enter(p))
				return NULL;
			struct sl_ast *n = parse_typecast(p);
			leave(p);
			return n;
		}
		return parse_postfix(p);
	}
}

/* One left-associative level: next { op next }. */
static struct sl_ast *parse_binary_level(struct parser *p, const enum sl_tok *ops, size_t nops,
					 parse_fn next)
{
	struct sl_ast *left = next(p);
	while (left) {
		const struct sl_token *t = cur(p);
		bool match = false;
		for (size_t i = 0; i < nops; i++)
			match = match || t->kind == ops[i];
		if (!match)
			break;
		/* The tree leans left and every walk follows that spine in a
		 * loop: an operator adds size, not depth. */
		if (++p->expr_ops > MAX_EXPR_OPS) {
			error_near(p, t, "expression too large (more than %d operators)",
				   MAX_EXPR_OPS);
			p->fatal = true;
			left = NULL;
			break;
		}
		advance(p);
		struct sl_ast *right = next(p);
		if (!right) {
			left = NULL;
			break;
		}
		struct sl_ast *n = new_node(p, SL_AST_BINARY, t);
		n->op = t->kind;
		n->a = left;
		n->b = right;
		left = n;
	}
	return left;
}

/* dot: unary { '.' unary } */
static struct sl_ast *parse_dot(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_DOT};
	return parse_binary_level(p, ops, 1, parse_unary);
}

/* multiplicative: dot { ('*' | '/') dot } */
static struct sl_ast *parse_multiplicative(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_STAR, SL_TOK_SLASH};
	return parse_binary_level(p, ops, 2, parse_dot);
}

/* cross: multiplicative { '^' multiplicative } */
static struct sl_ast *parse_cross(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_CARET};
	return parse_binary_level(p, ops, 1, parse_multiplicative);
}

/* additive: cross { ('+' | '-') cross } */
static struct sl_ast *parse_additive(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_PLUS, SL_TOK_MINUS};
	return parse_binary_level(p, ops, 2, parse_cross);
}

/* relational: additive { ('<' | '<=' | '>' | '>=') additive } */
static struct sl_ast *parse_relational(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_LT, SL_TOK_LE, SL_TOK_GT, SL_TOK_GE};
	return parse_binary_level(p, ops, 4, parse_additive);
}

/* equality: relational { ('==' | '!=') relational } */
static struct sl_ast *parse_equality(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_EQ, SL_TOK_NE};
	return parse_binary_level(p, ops, 2, parse_relational);
}

/* logical_and: equality { '&&' equality } */
static struct sl_ast *parse_logical_and(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_AND};
	return parse_binary_level(p, ops, 1, parse_equality);
}

/* logical_or: logical_and { '||' logical_and } */
static struct sl_ast *parse_logical_or(struct parser *p)
{
	static const enum sl_tok ops[] = {SL_TOK_OR};
	return parse_binary_level(p, ops, 1, parse_logical_and);
}

/* conditional: logical_or [ '?' expression ':' conditional ] */
static struct sl_ast *parse_conditional(struct parser *p)
{
	struct sl_ast *cond = parse_logical_or(p);
	if (!cond || kind(p) != SL_TOK_QUESTION)
		return cond;
	const struct sl_token *t = cur(p);
	if (!enter(p))
		return NULL;
	advance(p);
	struct sl_ast *n = NULL;
	struct sl_ast *yes = parse_expr(p);
	if (yes && expect(p, SL_TOK_COLON)) {
		struct sl_ast *no = parse_conditional(p);
		if (no) {
			n = new_node(p, SL_AST_COND, t);
			n->a = cond;
			n->b = yes;
			n->c = no;
		}
	}
	leave(p);
	return n;
}

/*
 * expression: conditional [ asgnop expression ]
 * asgnop: '=' | '+=' | '-=' | '*=' | '/='
 */
static struct sl_ast *parse_expr(struct parser *p)
{
	if (!enter(p))
		return NULL;
	if (p->expr_nest++ == 0)
		p->expr_ops = 0;
	struct sl_ast *n = parse_conditional(p);
	if (n && is_assign_op(kind(p))) {
		const struct sl_token *t = cur(p);
		if (!is_lvalue(n)) {
			error_near(p, t, "the left side of %s must be a variable or an array element",
				   sl_tok_name(t->kind));
			n = NULL;
		} else {
			advance(p);
			struct sl_ast *value = parse_expr(p);
			if (value) {
				struct sl_ast *a = new_node(p, SL_AST_ASSIGN, t);
				a->op = t->kind;
				a->a = n;
				a->b = value;
				n = a;
			} else {
				n = NULL;
			}
		}
	}
	p->expr_nest--;
	leave(p);
	return n;
}

/* ---- declarations ---- */

/* initializer: expression | '{' [ expression { ',' expression } ] '}' */
static struct sl_ast *parse_initializer(struct parser *p)
{
	const struct sl_token *t = cur(p);
	if (!accept(p, SL_TOK_LBRACE))
		return parse_expr(p);
	struct sl_ast *lit = new_node(p, SL_AST_ARRAYLIT, t);
	struct node_list elems = {0};
	if (!accept(p, SL_TOK_RBRACE)) {
		for (;;) {
			struct sl_ast *e = parse_expr(p);
			if (!e)
				return NULL;
			list_push(p, &elems, e);
			if (accept(p, SL_TOK_COMMA))
				continue;
			if (!expect(p, SL_TOK_RBRACE))
				return NULL;
			break;
		}
	}
	set_list(lit, &elems);
	return lit;
}

enum array_mode {
	ARRAY_SIZED,  /* variables and shader parameters: `[N]` */
	ARRAY_OPEN,   /* function parameters: `[N]` or `[]` */
};

/* declarator: IDENT [ '[' [NUMBER] ']' ] [ '=' initializer ] */
static struct sl_ast *parse_declarator(struct parser *p, struct sl_type type, bool output,
				       bool is_extern, enum array_mode mode)
{
	const struct sl_token *name = cur(p);
	if (name->kind != SL_TOK_IDENT) {
		error_near(p, name, "expected a name");
		return NULL;
	}
	advance(p);
	struct sl_ast *var = new_node(p, SL_AST_VAR, name);
	var->name = tok_name(p, name);
	var->output = output;
	var->is_extern = is_extern;

	if (accept(p, SL_TOK_LBRACKET)) {
		const struct sl_token *size = cur(p);
		if (size->kind == SL_TOK_RBRACKET && mode == ARRAY_OPEN) {
			type.arraylen = 0;
		} else {
			long n = positive_int(size, MAX_ARRAY_LEN);
			if (n < 0) {
				error_near(p, size, "array size must be a whole number from 1 to %d",
					   MAX_ARRAY_LEN);
				return NULL;
			}
			type.arraylen = (int32_t)n;
			advance(p);
		}
		if (!expect(p, SL_TOK_RBRACKET))
			return NULL;
	}
	var->type = type;

	if (accept(p, SL_TOK_ASSIGN)) {
		var->a = parse_initializer(p);
		if (!var->a)
			return NULL;
	}
	return var;
}

/*
 * typespec: { qualifier } (TYPE | void)
 * qualifier: 'uniform' | 'varying' | 'output' (when @output) | 'extern' (when @is_extern)
 */
static bool parse_typespec(struct parser *p, struct sl_type *type, bool *output, bool *is_extern)
{
	*type = (struct sl_type){.base = SL_TYPE_VOID, .detail = SL_DETAIL_DEFAULT, .arraylen = -1};
	for (;;) {
		enum sl_tok k = kind(p);
		if (k == SL_TOK_KW_UNIFORM)
			type->detail = SL_DETAIL_UNIFORM;
		else if (k == SL_TOK_KW_VARYING)
			type->detail = SL_DETAIL_VARYING;
		else if (k == SL_TOK_KW_OUTPUT && output)
			*output = true;
		else if (k == SL_TOK_KW_EXTERN && is_extern)
			*is_extern = true;
		else
			break;
		advance(p);
	}
	int base = keyword_basetype(kind(p));
	if (base < 0) {
		error_near(p, cur(p), "expected a type");
		return false;
	}
	type->base = (uint8_t)base;
	advance(p);
	return true;
}

/* variable_type: typespec, and not void */
static bool parse_variable_type(struct parser *p, struct sl_type *type, bool *output,
				bool *is_extern)
{
	if (!parse_typespec(p, type, output, is_extern))
		return false;
	if (type->base == SL_TYPE_VOID) {
		error_near(p, prev(p), "a variable cannot be void");
		return false;
	}
	return true;
}

/*
 * formal_group: { 'output' | 'uniform' | 'varying' } TYPE declarator
 *               { ',' declarator }
 * (a ',' followed by a type or a qualifier starts the next group instead)
 */
static bool parse_formal_group(struct parser *p, struct node_list *out, enum array_mode mode)
{
	struct sl_type type;
	bool output = false;
	if (!parse_variable_type(p, &type, &output, NULL))
		return false;
	for (;;) {
		struct sl_ast *var = parse_declarator(p, type, output, false, mode);
		if (!var)
			return false;
		list_push(p, out, var);
		if (kind(p) == SL_TOK_COMMA && peek(p, 1)->kind == SL_TOK_IDENT) {
			advance(p);
			continue;
		}
		return true;
	}
}

/*
 * formals: [ formal_group { (';' | ',') formal_group } [';'] ] ')'
 * Shader parameters (ARRAY_SIZED) and function parameters (ARRAY_OPEN)
 * share this rule; real shaders separate both with either ';' or ','.
 * Returns false when an error was reported; the parser then stands on the
 * closing ')' or the body's '{' (or the end).
 */
static bool parse_formals(struct parser *p, struct node_list *out, enum array_mode mode)
{
	bool ok = true;
	while (kind(p) != SL_TOK_RPAREN && !stopped(p)) {
		if (!parse_formal_group(p, out, mode)) {
			ok = false;
			sync_formal(p);
			if (accept(p, SL_TOK_SEMI))
				continue;
			return false;
		}
		if (accept(p, SL_TOK_SEMI) || accept(p, SL_TOK_COMMA))
			continue;
		if (kind(p) != SL_TOK_RPAREN) {
			error_near(p, cur(p), "expected ';' or ')'");
			ok = false;
			sync_formal(p);
			if (accept(p, SL_TOK_SEMI))
				continue;
			return false;
		}
	}
	return ok && !stopped(p);
}

/*
 * formal_list: '(' formals ')'
 * False when the definition cannot go on (the caller then skips it).
 */
static bool parse_formal_list(struct parser *p, struct sl_ast *def, enum array_mode mode)
{
	if (!expect(p, SL_TOK_LPAREN))
		return false;
	struct node_list params = {0};
	bool ok = parse_formals(p, &params, mode);
	set_list(def, &params);
	if (accept(p, SL_TOK_RPAREN))
		return true;
	if (ok) {
		error_near(p, cur(p), "expected ')'");
		return false;
	}
	/* the error is reported; go on with the body when it follows */
	return kind(p) == SL_TOK_LBRACE;
}

/*
 * function_definition: [ { 'uniform' | 'varying' } (TYPE | void) ] IDENT
 *                      '(' formals ')' block
 */
static struct sl_ast *parse_function(struct parser *p)
{
	struct sl_type ret = {.base = SL_TYPE_VOID, .detail = SL_DETAIL_DEFAULT, .arraylen = -1};
	if (kind(p) != SL_TOK_IDENT && !parse_typespec(p, &ret, NULL, NULL))
		return NULL;
	const struct sl_token *name = cur(p);
	if (name->kind != SL_TOK_IDENT) {
		error_near(p, name, "expected a function name");
		return NULL;
	}
	advance(p);
	struct sl_ast *fn = new_node(p, SL_AST_FUNC, name);
	fn->name = tok_name(p, name);
	fn->type = ret;
	name_set_add(&p->funcs, fn->name);
	if (!parse_formal_list(p, fn, ARRAY_OPEN))
		return NULL;
	fn->a = parse_block(p);
	return fn->a ? fn : NULL;
}

/* shader_definition: shader_kind IDENT '(' formals ')' block */
static struct sl_ast *parse_shader(struct parser *p)
{
	const struct sl_token *t = cur(p);
	int sk = shader_kind(t->kind);
	advance(p);
	const struct sl_token *name = cur(p);
	if (name->kind != SL_TOK_IDENT) {
		error_near(p, name, "expected a shader name");
		return NULL;
	}
	advance(p);
	struct sl_ast *sh = new_node(p, SL_AST_SHADER, name);
	sh->op = sk;
	sh->name = tok_name(p, name);
	if (!parse_formal_list(p, sh, ARRAY_SIZED))
		return NULL;
	sh->a = parse_block(p);
	return sh->a ? sh : NULL;
}

/*
 * declaration: { 'extern' | 'uniform' | 'varying' } TYPE declarator
 *              { ',' declarator } ';'
 */
static struct sl_ast *parse_declaration(struct parser *p)
{
	struct sl_ast *decl = new_node(p, SL_AST_DECL, cur(p));
	struct sl_type type;
	bool is_extern = false;
	if (!parse_variable_type(p, &type, NULL, &is_extern))
		return NULL;
	struct node_list vars = {0};
	do {
		struct sl_ast *var = parse_declarator(p, type, false, is_extern, ARRAY_SIZED);
		if (!var)
			return NULL;
		list_push(p, &vars, var);
	} while (accept(p, SL_TOK_COMMA));
	if (!expect(p, SL_TOK_SEMI))
		return NULL;
	set_list(decl, &vars);
	return decl;
}

/* ---- statements ---- */

/* paren_expr: '(' expression ')' */
static struct sl_ast *parse_paren_expr(struct parser *p)
{
	if (!expect(p, SL_TOK_LPAREN))
		return NULL;
	struct sl_ast *e = parse_expr(p);
	if (!e || !expect(p, SL_TOK_RPAREN))
		return NULL;
	return e;
}

/* if_statement: 'if' '(' expression ')' statement [ 'else' statement ] */
static struct sl_ast *parse_if(struct parser *p)
{
	struct sl_ast *n = new_node(p, SL_AST_IF, cur(p));
	advance(p);
	if (!(n->a = parse_paren_expr(p)) || !(n->b = parse_statement(p)))
		return NULL;
	if (accept(p, SL_TOK_KW_ELSE) && !(n->c = parse_statement(p)))
		return NULL;
	return n;
}

/* while_statement: 'while' '(' expression ')' statement */
static struct sl_ast *parse_while(struct parser *p)
{
	struct sl_ast *n = new_node(p, SL_AST_WHILE, cur(p));
	advance(p);
	if (!(n->a = parse_paren_expr(p)) || !(n->b = parse_statement(p)))
		return NULL;
	return n;
}

/*
 * for_statement: 'for' '(' [ expression ] ';' [ expression ] ';' [ expression ] ')'
 *                statement
 *              | 'for' '(' declaration [ expression ] ';' [ expression ] ')' statement
 * The second form becomes BLOCK { DECL, FOR } so the variable is scoped to the loop.
 */
static struct sl_ast *parse_for(struct parser *p)
{
	const struct sl_token *t = cur(p);
	struct sl_ast *n = new_node(p, SL_AST_FOR, t);
	struct sl_ast *decl = NULL;
	advance(p);
	if (!expect(p, SL_TOK_LPAREN))
		return NULL;

	enum sl_tok k = kind(p);
	if (k == SL_TOK_KW_EXTERN || k == SL_TOK_KW_UNIFORM || k == SL_TOK_KW_VARYING ||
	    (is_value_type(k) && peek(p, 1)->kind == SL_TOK_IDENT)) {
		if (!(decl = parse_declaration(p)))
			return NULL;
	} else if (!accept(p, SL_TOK_SEMI)) {
		const struct sl_token *start = cur(p);
		struct sl_ast *init = parse_expr(p);
		if (!init || !expect(p, SL_TOK_SEMI))
			return NULL;
		n->a = new_node(p, SL_AST_EXPR, start);
		n->a->a = init;
	}
	if (kind(p) != SL_TOK_SEMI && !(n->b = parse_expr(p)))
		return NULL;
	if (!expect(p, SL_TOK_SEMI))
		return NULL;
	if (kind(p) != SL_TOK_RPAREN && !(n->c = parse_expr(p)))
		return NULL;
	if (!expect(p, SL_TOK_RPAREN) || !(n->d = parse_statement(p)))
		return NULL;
	if (!decl)
		return n;

	struct sl_ast *block = new_node(p, SL_AST_BLOCK, t);
	struct node_list stmts = {0};
	list_push(p, &stmts, decl);
	list_push(p, &stmts, n);
	set_list(block, &stmts);
	return block;
}

/* loop_mod: ('break' | 'continue') [ NUMBER ] ';' */
static struct sl_ast *parse_loop_mod(struct parser *p)
{
	const struct sl_token *t = cur(p);
	struct sl_ast *n = new_node(p, t->kind == SL_TOK_KW_BREAK ? SL_AST_BREAK : SL_AST_CONTINUE, t);
	advance(p);
	n->num = 1;
	if (kind(p) != SL_TOK_SEMI) {
		long levels = positive_int(cur(p), 1 << 16);
		if (levels < 0) {
			error_near(p, cur(p), "expected a loop count or ';'");
			return NULL;
		}
		n->num = (double)levels;
		advance(p);
	}
	return expect(p, SL_TOK_SEMI) ? n : NULL;
}

/* return_statement: 'return' [ expression ] ';' */
static struct sl_ast *parse_return(struct parser *p)
{
	struct sl_ast *n = new_node(p, SL_AST_RETURN, cur(p));
	advance(p);
	if (kind(p) != SL_TOK_SEMI && !(n->a = parse_expr(p)))
		return NULL;
	return expect(p, SL_TOK_SEMI) ? n : NULL;
}

/*
 * light_loop: 'illuminance' '(' [ expression ',' ] expression [ ',' expression ',' expression ] ')' statement
 *           | 'illuminate' '(' expression [ ',' expression ',' expression ] ')' statement
 *           | 'solar' '(' [ expression ',' expression ] ')' statement
 */
static struct sl_ast *parse_light_loop(struct parser *p)
{
	const struct sl_token *t = cur(p);
	enum sl_ast_kind k = t->kind == SL_TOK_KW_ILLUMINANCE ? SL_AST_ILLUMINANCE
			     : t->kind == SL_TOK_KW_ILLUMINATE ? SL_AST_ILLUMINATE
							       : SL_AST_SOLAR;
	struct sl_ast *n = new_node(p, k, t);
	advance(p);
	if (!expect(p, SL_TOK_LPAREN))
		return NULL;
	const struct sl_token *open = prev(p);
	struct node_list args = {0};
	if (!parse_args(p, &args))
		return NULL;
	bool fits = k == SL_AST_ILLUMINANCE ? args.len >= 1 && args.len <= 4
		    : k == SL_AST_ILLUMINATE ? args.len == 1 || args.len == 3
					     : args.len == 0 || args.len == 2;
	if (!fits) {
		error_near(p, open, "%s does not take %u arguments", sl_tok_name(t->kind),
			   (unsigned)args.len);
		return NULL;
	}
	set_list(n, &args);
	n->a = parse_statement(p);
	return n->a ? n : NULL;
}

/* gather_statement: 'gather' '(' args ')' statement [ 'else' statement ]  (not supported) */
static struct sl_ast *parse_gather(struct parser *p)
{
	const struct sl_token *t = cur(p);
	if (!stopped(p))
		sl_error(p->ctx, t->loc, "gather is not supported");
	advance(p);
	/* parse the rest anyway so that what follows is read in step */
	struct node_list args = {0};
	if (!expect(p, SL_TOK_LPAREN) || !parse_args(p, &args) || !parse_statement(p))
		return NULL;
	if (accept(p, SL_TOK_KW_ELSE) && !parse_statement(p))
		return NULL;
	return new_node(p, SL_AST_EMPTY, t);
}

/*
 * statement: block | declaration | function_definition | if_statement
 *          | while_statement | for_statement | loop_mod | return_statement
 *          | light_loop | gather_statement | ';' | expression ';'
 */
static struct sl_ast *parse_statement_body(struct parser *p)
{
	const struct sl_token *t = cur(p);
	switch (t->kind) {
	case SL_TOK_LBRACE:
		return parse_block(p);
	case SL_TOK_SEMI:
		advance(p);
		return new_node(p, SL_AST_EMPTY, t);
	case SL_TOK_KW_IF:
		return parse_if(p);
	case SL_TOK_KW_WHILE:
		return parse_while(p);
	case SL_TOK_KW_FOR:
		return parse_for(p);
	case SL_TOK_KW_BREAK:
	case SL_TOK_KW_CONTINUE:
		return parse_loop_mod(p);
	case SL_TOK_KW_RETURN:
		return parse_return(p);
	case SL_TOK_KW_ILLUMINANCE:
	case SL_TOK_KW_ILLUMINATE:
	case SL_TOK_KW_SOLAR:
		return parse_light_loop(p);
	case SL_TOK_KW_GATHER:
		return parse_gather(p);
	case SL_TOK_KW_EXTERN:
		return parse_declaration(p);
	default:
		break;
	}
	if (at_function_definition(p))
		return parse_function(p);
	if (t->kind == SL_TOK_KW_UNIFORM || t->kind == SL_TOK_KW_VARYING ||
	    (is_value_type(t->kind) && peek(p, 1)->kind == SL_TOK_IDENT))
		return parse_declaration(p);

	struct sl_ast *e = parse_expr(p);
	if (!e || !expect(p, SL_TOK_SEMI))
		return NULL;
	struct sl_ast *n = new_node(p, SL_AST_EXPR, t);
	n->a = e;
	return n;
}

/* statement, one nesting level deeper (see parse_statement_body for the rule) */
static struct sl_ast *parse_statement(struct parser *p)
{
	if (!enter(p))
		return NULL;
	struct sl_ast *n = parse_statement_body(p);
	leave(p);
	return n;
}

/* block: '{' { statement } '}' */
static struct sl_ast *parse_block(struct parser *p)
{
	const struct sl_token *t = cur(p);
	if (!expect(p, SL_TOK_LBRACE))
		return NULL;
	struct sl_ast *block = new_node(p, SL_AST_BLOCK, t);
	struct node_list stmts = {0};
	while (kind(p) != SL_TOK_RBRACE && kind(p) != SL_TOK_EOF && !stopped(p)) {
		struct sl_ast *s = parse_statement(p);
		if (s)
			list_push(p, &stmts, s);
		else
			sync_statement(p);
	}
	set_list(block, &stmts);
	/* at the end of the input the error is reported, the block kept */
	expect(p, SL_TOK_RBRACE);
	return block;
}

/* ---- the unit ---- */

/*
 * unit: { definition }
 * definition: shader_definition | function_definition | ';'
 */
static struct sl_ast *parse_unit(struct parser *p)
{
	struct sl_ast *unit = new_node(p, SL_AST_UNIT, cur(p));
	struct node_list defs = {0};
	while (kind(p) != SL_TOK_EOF && !stopped(p)) {
		const struct sl_token *t = cur(p);
		struct sl_ast *def = NULL;
		if (t->kind == SL_TOK_SEMI) {
			advance(p);
			continue;
		}
		if (shader_kind(t->kind) >= 0) {
			def = parse_shader(p);
		} else if (at_function_definition(p) ||
			   (t->kind == SL_TOK_IDENT && peek(p, 1)->kind == SL_TOK_LPAREN)) {
			def = parse_function(p);
		} else {
			error_near(p, t, "expected a shader or function definition");
		}
		if (def)
			list_push(p, &defs, def);
		else if (!stopped(p))
			sync_definition(p);
	}
	set_list(unit, &defs);
	return unit;
}

struct sl_ast *sl_parse(struct sl_ctx *ctx, const struct sl_token *toks, size_t ntoks)
{
	struct parser p = {.ctx = ctx, .toks = toks};
	if (!toks)
		ntoks = 0;
	while (p.ntoks < ntoks && toks[p.ntoks].kind != SL_TOK_EOF)
		p.ntoks++;
	if (p.ntoks < ntoks)
		p.ntoks++;
	p.eof.kind = SL_TOK_EOF;
	if (p.ntoks > 0)
		p.eof.loc = toks[p.ntoks - 1].loc;
	else
		p.eof.loc = (struct sl_loc){.file = 0, .line = 1, .col = 1};

	int errors_before = ctx->nerrors;
	struct sl_ast *unit = parse_unit(&p);
	free(p.funcs.slots);
	if (unit->nlist == 0 && ctx->nerrors > errors_before)
		return NULL;
	return unit;
}

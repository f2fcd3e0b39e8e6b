/*
 * Blobby implicit surfaces: decoding the field program, evaluating it, and
 * polygonizing its isosurface (see geom_blobby.h).
 *
 * The field of an ellipsoid or segment leaf at squared distance r^2 in its
 * unit space is RISpec's soft falloff (1 - r^2)^3 (Aqsis renders the same):
 * 1 at the centre, 0 with zero slope and curvature at r = 1, nothing beyond.
 * A lone leaf's surface, where the field is 0.5, is therefore the sphere of
 * radius sqrt(1 - 0.5^(1/3)) = 0.454202 in its unit space.
 */
#include "geom_blobby.h"

#include "arena.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ROOT_ITERS 60          /* false position steps on an edge, at most */
#define ROOT_TOL 1e-7          /* ... until the bracket is this part of the edge */
#define MAX_SAMPLES (1u << 24) /* grid samples of one polygonization */
#define MAX_WORK 1e8           /* grid samples times instructions, at most */

/* ---- decoding ------------------------------------------------------------------- */

/* The inverse of the affine row-vector matrix @m (last column 0 0 0 1). */
static bool affine_inverse(double r[16], const double m[16])
{
	double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], h = m[9],
	       i = m[10];
	double A = e * i - f * h, B = f * g - d * i, C = d * h - e * g;
	double det = a * A + b * B + c * C;
	double scale = fabs(a) + fabs(b) + fabs(c) + fabs(d) + fabs(e) + fabs(f) + fabs(g) +
		       fabs(h) + fabs(i);
	if (!isfinite(det) || !(fabs(det) > 1e-12 * scale * scale * scale))
		return false;
	double inv3[9] = {
		A / det, (c * h - b * i) / det, (b * f - c * e) / det,
		B / det, (a * i - c * g) / det, (c * d - a * f) / det,
		C / det, (b * g - a * h) / det, (a * e - b * d) / det,
	};
	memset(r, 0, sizeof(double) * 16);
	for (int row = 0; row < 3; row++)
		for (int col = 0; col < 3; col++)
			r[row * 4 + col] = inv3[row * 3 + col];
	for (int col = 0; col < 3; col++)
		r[12 + col] = -(m[12] * inv3[col] + m[13] * inv3[3 + col] + m[14] * inv3[6 + col]);
	r[15] = 1;
	return true;
}

static void xform(double r[3], const double m[16], const double p[3])
{
	for (int j = 0; j < 3; j++)
		r[j] = p[0] * m[j] + p[1] * m[4 + j] + p[2] * m[8 + j] + m[12 + j];
}

/* The object-space box of the ball of radius @rad about blob-space point @c. */
static void ball_box(const double m[16], const double c[3], double rad, double lo[3],
		     double hi[3])
{
	double o[3];
	xform(o, m, c);
	for (int j = 0; j < 3; j++) {
		double e = rad * sqrt(m[j] * m[j] + m[4 + j] * m[4 + j] + m[8 + j] * m[8 + j]);
		lo[j] = o[j] - e;
		hi[j] = o[j] + e;
	}
}

struct decoder {
	const int32_t *code;
	uint32_t ncode, pc;
	const float *floats;
	uint32_t nfloats;
	char *err;
	size_t errlen;
};

static bool fail(struct decoder *d, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static bool fail(struct decoder *d, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(d->err, d->errlen, fmt, ap);
	va_end(ap);
	return false;
}

/* The next code word, as an index below @limit into what @what names. */
static bool next_index(struct decoder *d, uint32_t op_at, uint32_t limit, const char *what,
		       uint32_t *out)
{
	if (d->pc >= d->ncode)
		return fail(d, "the code ends inside opcode %d (code[%u])", d->code[op_at], op_at);
	int32_t v = d->code[d->pc++];
	if (v < 0 || (uint32_t)v >= limit)
		return fail(d, "code[%u] = %d: %s index out of range (%u available)", d->pc - 1, v,
			    what, limit);
	*out = (uint32_t)v;
	return true;
}

/* @n floats from index @at, checked to exist and be finite. */
static bool get_floats(struct decoder *d, uint32_t at, uint32_t n, double *out)
{
	if ((uint64_t)at + n > d->nfloats)
		return fail(d, "float index %u needs %u floats, the array has %u", at, n,
			    d->nfloats);
	for (uint32_t k = 0; k < n; k++) {
		out[k] = d->floats[at + k];
		if (!isfinite(out[k]))
			return fail(d, "float %u is not finite", at + k);
	}
	return true;
}

/* A leaf's matrix at float index @at: affine and invertible. */
static bool leaf_matrix(struct decoder *d, uint32_t at, double m[16], double inv[16])
{
	if (!get_floats(d, at, 16, m))
		return false;
	if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] == 0)
		return fail(d, "the matrix at float %u is projective (its last column is not "
			    "0 0 0 w)", at);
	if (m[15] != 1)
		for (int k = 0; k < 16; k++)
			m[k] /= m[15];
	if (!affine_inverse(inv, m))
		return fail(d, "the matrix at float %u is singular", at);
	return true;
}

static bool decode_leaf(struct decoder *d, uint32_t op_at, uint32_t nstrings,
			struct reyes_blobby_instr *in)
{
	uint32_t fi, si;
	double m[16];
	switch (in->op) {
	case BLOBBY_CONSTANT:
		return next_index(d, op_at, d->nfloats, "float", &fi) &&
		       get_floats(d, fi, 1, &in->value);
	case BLOBBY_ELLIPSOID: {
		static const double origin[3] = {0, 0, 0};
		if (!next_index(d, op_at, d->nfloats, "float", &fi) ||
		    !leaf_matrix(d, fi, m, in->inv))
			return false;
		ball_box(m, origin, 1, in->lo, in->hi);
		in->bounded = true;
		return true;
	}
	case BLOBBY_SEGMENT: {
		double ab[7];
		if (!next_index(d, op_at, d->nfloats, "float", &fi) || !get_floats(d, fi, 7, ab) ||
		    !leaf_matrix(d, fi + 7, m, in->inv))
			return false;
		if (!(ab[6] > 0))
			return fail(d, "the segment blob at float %u has radius %g (it must be "
				    "positive)", fi, ab[6]);
		memcpy(in->a, ab, sizeof(in->a));
		memcpy(in->b, ab + 3, sizeof(in->b));
		in->rr = 1 / (ab[6] * ab[6]);
		double lo2[3], hi2[3];
		ball_box(m, in->a, ab[6], in->lo, in->hi);
		ball_box(m, in->b, ab[6], lo2, hi2);
		for (int j = 0; j < 3; j++) {
			in->lo[j] = fmin(in->lo[j], lo2[j]);
			in->hi[j] = fmax(in->hi[j], hi2[j]);
		}
		in->bounded = true;
		return true;
	}
	case BLOBBY_PLANE:
		/* a depth map's name and four floats (A B C D of the repulsion) */
		return next_index(d, op_at, nstrings, "string", &si) &&
		       next_index(d, op_at, d->nfloats, "float", &fi) && get_floats(d, fi, 4, m);
	default:
		return false;
	}
}

bool reyes_blobby_decode(struct reyes_blobby *b, uint32_t nleaf, const int32_t *code,
			 uint32_t ncode, const float *floats, uint32_t nfloats, uint32_t nstrings,
			 char *err, size_t errlen)
{
	*b = (struct reyes_blobby){0};
	struct decoder d = {code, ncode, 0, floats, nfloats, err, errlen};
	RL_VEC(struct reyes_blobby_instr) instr = {0};
	RL_VEC(uint32_t) operands = {0};
	bool ok = true;
	while (ok && d.pc < ncode) {
		uint32_t at = d.pc;
		struct reyes_blobby_instr in = {.op = (enum reyes_blobby_op)code[d.pc++]};
		uint32_t self = (uint32_t)instr.len, n = 1, o;
		switch (code[at]) {
		case BLOBBY_CONSTANT:
		case BLOBBY_ELLIPSOID:
		case BLOBBY_SEGMENT:
		case BLOBBY_PLANE:
			in.leaf = b->nleaf++;
			b->nplanes += code[at] == BLOBBY_PLANE;
			ok = decode_leaf(&d, at, nstrings, &in);
			break;
		case BLOBBY_ADD:
		case BLOBBY_MUL:
		case BLOBBY_MAX:
		case BLOBBY_MIN:
			/* count, then that many operands */
			if (d.pc >= ncode) {
				ok = fail(&d, "the code ends inside opcode %d (code[%u])", code[at],
					  at);
				break;
			}
			if (code[d.pc] < 1 || (uint32_t)code[d.pc] > ncode - d.pc - 1) {
				ok = fail(&d, "code[%u] = %d: opcode %d's operand count must be "
					  "1 to the %u words left", d.pc, code[d.pc], code[at],
					  ncode - d.pc - 1);
				break;
			}
			n = (uint32_t)code[d.pc++];
			/* fallthrough */
		case BLOBBY_SUB:
		case BLOBBY_DIV:
			if (code[at] == BLOBBY_SUB || code[at] == BLOBBY_DIV)
				n = 2;
			/* fallthrough */
		case BLOBBY_NEG:
		case BLOBBY_IDENTITY:
			in.first = (uint32_t)operands.len;
			in.count = n;
			for (uint32_t k = 0; k < n && ok; k++) {
				ok = next_index(&d, at, self, "operand (an earlier instruction)", &o);
				if (ok)
					rl_vec_push(operands, o);
			}
			break;
		default:
			ok = fail(&d, "code[%u] = %d is not a Blobby opcode", at, code[at]);
			break;
		}
		if (ok)
			rl_vec_push(instr, in);
	}
	if (ok && instr.len == 0)
		ok = fail(&d, "the code is empty");
	if (ok && b->nleaf != nleaf)
		ok = fail(&d, "nleaf is %u, the code has %u leaves", nleaf, b->nleaf);
	b->instr = instr.data;
	b->ninstr = (uint32_t)instr.len;
	b->operands = operands.data;
	b->noperands = (uint32_t)operands.len;
	if (!ok) {
		reyes_blobby_finish(b);
		return false;
	}
	for (uint32_t k = 0; k < b->ninstr; k++) {
		const struct reyes_blobby_instr *in = &b->instr[k];
		if (!in->bounded)
			continue;
		for (int j = 0; j < 3; j++) {
			b->lo[j] = b->bounded ? fmin(b->lo[j], in->lo[j]) : in->lo[j];
			b->hi[j] = b->bounded ? fmax(b->hi[j], in->hi[j]) : in->hi[j];
		}
		b->bounded = true;
	}
	return true;
}

void reyes_blobby_finish(struct reyes_blobby *b)
{
	free(b->instr);
	free(b->operands);
	*b = (struct reyes_blobby){0};
}

/* ---- evaluation ----------------------------------------------------------------- */

static double falloff(double r2)
{
	if (!(r2 < 1))
		return 0;
	double s = 1 - r2;
	return s * s * s;
}

static double leaf_value(const struct reyes_blobby_instr *in, const double p[3])
{
	if (in->bounded)
		for (int j = 0; j < 3; j++)
			if (p[j] < in->lo[j] || p[j] > in->hi[j])
				return 0;
	double q[3];
	switch (in->op) {
	case BLOBBY_CONSTANT:
		return in->value;
	case BLOBBY_ELLIPSOID:
		xform(q, in->inv, p);
		return falloff(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
	case BLOBBY_SEGMENT: {
		xform(q, in->inv, p);
		double ab[3], aq[3], l2 = 0, t = 0;
		for (int j = 0; j < 3; j++) {
			ab[j] = in->b[j] - in->a[j];
			aq[j] = q[j] - in->a[j];
			l2 += ab[j] * ab[j];
			t += ab[j] * aq[j];
		}
		t = l2 > 0 ? fmin(fmax(t / l2, 0), 1) : 0;
		double r2 = 0;
		for (int j = 0; j < 3; j++) {
			double e = aq[j] - t * ab[j];
			r2 += e * e;
		}
		return falloff(r2 * in->rr);
	}
	default:
		return 0;       /* a repelling plane (reported by the scene builder) */
	}
}

double reyes_blobby_field(const struct reyes_blobby *b, const double p[3], double *vals)
{
	for (uint32_t k = 0; k < b->ninstr; k++) {
		const struct reyes_blobby_instr *in = &b->instr[k];
		const uint32_t *o = b->operands ? b->operands + in->first : NULL;
		double v;
		switch (in->op) {
		case BLOBBY_ADD:
			v = 0;
			for (uint32_t i = 0; i < in->count; i++)
				v += vals[o[i]];
			break;
		case BLOBBY_MUL:
			v = 1;
			for (uint32_t i = 0; i < in->count; i++)
				v *= vals[o[i]];
			break;
		case BLOBBY_MAX:
			v = vals[o[0]];
			for (uint32_t i = 1; i < in->count; i++)
				v = fmax(v, vals[o[i]]);
			break;
		case BLOBBY_MIN:
			v = vals[o[0]];
			for (uint32_t i = 1; i < in->count; i++)
				v = fmin(v, vals[o[i]]);
			break;
		case BLOBBY_SUB:
			v = vals[o[0]] - vals[o[1]];
			break;
		case BLOBBY_DIV:
			/* a zero divisor gives 0 (as Aqsis), not an infinity */
			v = vals[o[1]] != 0 ? vals[o[0]] / vals[o[1]] : 0;
			break;
		case BLOBBY_NEG:
			v = -vals[o[0]];
			break;
		case BLOBBY_IDENTITY:
			v = vals[o[0]];
			break;
		default:
			v = leaf_value(in, p);
			break;
		}
		vals[k] = isfinite(v) ? v : 0;
	}
	return vals[b->ninstr - 1];
}

/* ---- polygonization ------------------------------------------------------------- */

struct edge_slot {
	uint64_t key;           /* 0: empty; else (a << 32 | b) + 1 over sample indices a < b */
	uint32_t point;
};

struct poly {
	const struct reyes_blobby *b;
	double *vals;
	double org[3], step[3];
	uint32_t nx, ny, nz;    /* cells per axis */
	float *g;               /* field - threshold at each sample; boundary samples -1 */
	struct edge_slot *edges;
	size_t ecap, elen;
	RL_VEC(double) P;       /* 3 per point */
	RL_VEC(uint32_t) tris;
};

static void sample_pos(const struct poly *s, uint32_t idx, double p[3])
{
	uint32_t sx = s->nx + 1, sy = s->ny + 1;
	uint32_t i = idx % sx, j = idx / sx % sy, k = idx / sx / sy;
	p[0] = s->org[0] + i * s->step[0];
	p[1] = s->org[1] + j * s->step[1];
	p[2] = s->org[2] + k * s->step[2];
}

static bool on_boundary(const struct poly *s, uint32_t idx)
{
	uint32_t sx = s->nx + 1, sy = s->ny + 1;
	uint32_t i = idx % sx, j = idx / sx % sy, k = idx / sx / sy;
	return i == 0 || j == 0 || k == 0 || i == s->nx || j == s->ny || k == s->nz;
}

static double g_at(struct poly *s, const double pa[3], const double pb[3], double t)
{
	double p[3];
	for (int c = 0; c < 3; c++)
		p[c] = pa[c] + t * (pb[c] - pa[c]);
	return reyes_blobby_field(s->b, p, s->vals) - REYES_BLOBBY_THRESHOLD;
}

/*
 * The crossing on the edge from sample @a (inside) to @b (outside): false
 * position with the Illinois rule on the field itself, so that the point is
 * on the surface, not on the grid's linear interpolation of it. Edges to the
 * grid's boundary (where the field is taken as outside) are interpolated.
 */
static void edge_point(struct poly *s, uint32_t a, uint32_t b, double out[3])
{
	double pa[3], pb[3];
	sample_pos(s, a, pa);
	sample_pos(s, b, pb);
	double ga = s->g[a], gb = s->g[b];
	double t = ga / (ga - gb);
	if (!on_boundary(s, a) && !on_boundary(s, b)) {
		double t0 = 0, t1 = 1, g0 = ga, g1 = gb;
		int side = 0;
		for (int it = 0; it < ROOT_ITERS && t1 - t0 > ROOT_TOL; it++) {
			t = (t0 * g1 - t1 * g0) / (g1 - g0);
			if (!(t > t0 && t < t1))
				t = 0.5 * (t0 + t1);
			double gt = g_at(s, pa, pb, t);
			if (gt > 0) {
				t0 = t, g0 = gt;
				if (side == 1)
					g1 *= 0.5;
				side = 1;
			} else if (gt < 0) {
				t1 = t, g1 = gt;
				if (side == -1)
					g0 *= 0.5;
				side = -1;
			} else {
				break;
			}
		}
	}
	for (int c = 0; c < 3; c++)
		out[c] = pa[c] + t * (pb[c] - pa[c]);
}

static uint64_t mix(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdu;
	x ^= x >> 33;
	return x;
}

/* The point on the edge between samples @a and @b (one inside), made once. */
static uint32_t edge_vertex(struct poly *s, uint32_t a, uint32_t b)
{
	uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
	uint64_t key = ((uint64_t)lo << 32 | hi) + 1;
	if ((s->elen + 1) * 2 > s->ecap) {
		size_t old = s->ecap;
		struct edge_slot *prev = s->edges;
		s->ecap = old ? old * 2 : 1024;
		s->edges = rl_xcalloc(s->ecap, sizeof(*s->edges));
		for (size_t k = 0; k < old; k++) {
			if (!prev[k].key)
				continue;
			size_t h = mix(prev[k].key) & (s->ecap - 1);
			while (s->edges[h].key)
				h = (h + 1) & (s->ecap - 1);
			s->edges[h] = prev[k];
		}
		free(prev);
	}
	size_t h = mix(key) & (s->ecap - 1);
	while (s->edges[h].key && s->edges[h].key != key)
		h = (h + 1) & (s->ecap - 1);
	if (s->edges[h].key)
		return s->edges[h].point;
	double p[3];
	if (s->g[a] > 0)
		edge_point(s, a, b, p);
	else
		edge_point(s, b, a, p);
	uint32_t idx = (uint32_t)(s->P.len / 3);
	for (int c = 0; c < 3; c++)
		rl_vec_push(s->P, p[c]);
	s->edges[h] = (struct edge_slot){key, idx};
	s->elen++;
	return idx;
}

/* Triangle (p, q, r) facing along @out (from the inside to the outside); none if degenerate. */
static void emit_tri(struct poly *s, uint32_t p, uint32_t q, uint32_t r, const double out[3])
{
	const double *A = &s->P.data[3 * p], *B = &s->P.data[3 * q], *C = &s->P.data[3 * r];
	double u[3], v[3], n[3];
	for (int c = 0; c < 3; c++) {
		u[c] = B[c] - A[c];
		v[c] = C[c] - A[c];
	}
	n[0] = u[1] * v[2] - u[2] * v[1];
	n[1] = u[2] * v[0] - u[0] * v[2];
	n[2] = u[0] * v[1] - u[1] * v[0];
	double d = n[0] * out[0] + n[1] * out[1] + n[2] * out[2];
	if (p == q || q == r || p == r || d == 0 || !isfinite(d))
		return;
	rl_vec_push(s->tris, p);
	rl_vec_push(s->tris, d > 0 ? q : r);
	rl_vec_push(s->tris, d > 0 ? r : q);
}

/* The surface's part in the tetrahedron of samples @t. */
static void tetra(struct poly *s, const uint32_t t[4])
{
	uint32_t in[4], outv[4], ni = 0, no = 0;
	for (int k = 0; k < 4; k++) {
		if (s->g[t[k]] > 0)
			in[ni++] = t[k];
		else
			outv[no++] = t[k];
	}
	if (ni == 0 || no == 0)
		return;
	double dir[3] = {0, 0, 0}, p[3];
	for (uint32_t k = 0; k < no; k++) {
		sample_pos(s, outv[k], p);
		for (int c = 0; c < 3; c++)
			dir[c] += p[c] / no;
	}
	for (uint32_t k = 0; k < ni; k++) {
		sample_pos(s, in[k], p);
		for (int c = 0; c < 3; c++)
			dir[c] -= p[c] / ni;
	}
	if (ni == 1 || no == 1) {
		uint32_t lone = ni == 1 ? in[0] : outv[0];
		const uint32_t *rest = ni == 1 ? outv : in;
		emit_tri(s, edge_vertex(s, lone, rest[0]), edge_vertex(s, lone, rest[1]),
			 edge_vertex(s, lone, rest[2]), dir);
		return;
	}
	/* two in, two out: a quad, its corners in order around it */
	uint32_t q0 = edge_vertex(s, in[0], outv[0]), q1 = edge_vertex(s, in[0], outv[1]);
	uint32_t q2 = edge_vertex(s, in[1], outv[1]), q3 = edge_vertex(s, in[1], outv[0]);
	emit_tri(s, q0, q1, q2, dir);
	emit_tri(s, q0, q2, q3, dir);
}

static void sample_grid(struct poly *s)
{
	uint32_t sx = s->nx + 1, sy = s->ny + 1, sz = s->nz + 1;
	for (uint32_t k = 0; k < sz; k++)
		for (uint32_t j = 0; j < sy; j++)
			for (uint32_t i = 0; i < sx; i++) {
				uint32_t idx = (k * sy + j) * sx + i;
				if (on_boundary(s, idx)) {
					s->g[idx] = -1;
					continue;
				}
				double p[3];
				sample_pos(s, idx, p);
				double v = reyes_blobby_field(s->b, p, s->vals) -
					   REYES_BLOBBY_THRESHOLD;
				/* a sample exactly on the surface counts as outside */
				s->g[idx] = v > 0 ? (float)fmax(v, 1e-30) : (float)fmin(v, 0);
			}
}

static void march(struct poly *s)
{
	/* Freudenthal's split: the six paths from corner 000 to 111 */
	static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
				       {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
	uint32_t sx = s->nx + 1, sy = s->ny + 1;
	uint32_t stride[3] = {1, sx, sx * sy};
	for (uint32_t k = 0; k < s->nz; k++)
		for (uint32_t j = 0; j < s->ny; j++)
			for (uint32_t i = 0; i < s->nx; i++) {
				uint32_t base = (k * sy + j) * sx + i;
				bool any_in = false, any_out = false;
				for (int c = 0; c < 8; c++) {
					uint32_t idx = base + (c & 1) * stride[0] +
						       (c >> 1 & 1) * stride[1] + (c >> 2) * stride[2];
					any_in |= s->g[idx] > 0;
					any_out |= !(s->g[idx] > 0);
				}
				if (!any_in || !any_out)
					continue;
				for (int t = 0; t < 6; t++) {
					uint32_t v[4];
					v[0] = base;
					v[1] = v[0] + stride[perm[t][0]];
					v[2] = v[1] + stride[perm[t][1]];
					v[3] = v[2] + stride[perm[t][2]];
					tetra(s, v);
				}
			}
}

/* Unit normals along minus the field's gradient (central differences). */
static void normals(struct poly *s, struct reyes_blobby_mesh *m)
{
	double h = 1e-4 * fmin(s->step[0], fmin(s->step[1], s->step[2]));
	uint32_t nleaf = s->b->nleaf;
	/* the face normals' sum, where the gradient vanishes (a crease's ridge) */
	double *fn = rl_xcalloc(3 * (size_t)m->npoints, sizeof(double));
	for (uint32_t t = 0; t < m->ntris; t++) {
		const uint32_t *v = &m->tris[3 * t];
		const double *A = &s->P.data[3 * v[0]], *B = &s->P.data[3 * v[1]],
			     *C = &s->P.data[3 * v[2]];
		double u[3], w[3];
		for (int c = 0; c < 3; c++) {
			u[c] = B[c] - A[c];
			w[c] = C[c] - A[c];
		}
		double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
			       u[0] * w[1] - u[1] * w[0]};
		for (int k = 0; k < 3; k++)
			for (int c = 0; c < 3; c++)
				fn[3 * v[k] + c] += n[c];
	}
	for (uint32_t k = 0; k < m->npoints; k++) {
		const double *p = &s->P.data[3 * k];
		double grad[3], len = 0;
		for (int c = 0; c < 3; c++) {
			double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
			a[c] += h;
			b[c] -= h;
			grad[c] = -(reyes_blobby_field(s->b, a, s->vals) -
				    reyes_blobby_field(s->b, b, s->vals)) / (2 * h);
			len += grad[c] * grad[c];
		}
		len = sqrt(len);
		if (!(len > 1e-12) || !isfinite(len)) {
			for (int c = 0; c < 3; c++)
				grad[c] = fn[3 * k + c];
			len = sqrt(grad[0] * grad[0] + grad[1] * grad[1] + grad[2] * grad[2]);
			if (!(len > 0))
				grad[0] = 0, grad[1] = 0, grad[2] = 1, len = 1;
		}
		for (int c = 0; c < 3; c++) {
			m->N[3 * k + c] = (float)(grad[c] / len);
			m->P[3 * k + c] = (float)p[c];
		}
		reyes_blobby_field(s->b, p, s->vals);
		for (uint32_t i = 0; i < s->b->ninstr; i++) {
			const struct reyes_blobby_instr *in = &s->b->instr[i];
			if (in->op >= BLOBBY_CONSTANT)
				m->leaf[(size_t)k * nleaf + in->leaf] = s->vals[i];
		}
	}
	free(fn);
}

bool reyes_blobby_polygonize(const struct reyes_blobby *b, double cell, uint32_t max_cells,
			     struct reyes_blobby_mesh *m)
{
	*m = (struct reyes_blobby_mesh){0};
	m->cell = cell;
	if (!b->bounded || !(cell > 0) || max_cells < 2)
		return false;
	struct poly s = {.b = b};
	uint32_t n[3];
	/* a long program on a fine grid: coarser cells, so that the work stays bounded */
	double ext_v = 1;
	for (int c = 0; c < 3; c++)
		ext_v *= fmin((b->hi[c] - b->lo[c]) / cell + 3, max_cells + 1.0);
	if (ext_v * b->ninstr > MAX_WORK) {
		cell *= cbrt(ext_v * b->ninstr / MAX_WORK);
		m->coarsened = true;
	}
	for (int c = 0; c < 3; c++) {
		double ext = b->hi[c] - b->lo[c];
		double cells = ceil(ext / cell);
		if (!(cells >= 1))
			cells = 1;
		/* one cell of margin each side, where the field is taken as outside */
		n[c] = cells + 2 > max_cells ? max_cells : (uint32_t)cells + 2;
		double inner = n[c] - 2;
		s.step[c] = ext > 0 ? ext / inner : cell;
		if (!(s.step[c] > 0) || !isfinite(s.step[c]))
			return false;
		s.org[c] = b->lo[c] - s.step[c];
	}
	s.nx = n[0], s.ny = n[1], s.nz = n[2];
	m->cell = fmax(s.step[0], fmax(s.step[1], s.step[2]));
	uint64_t samples = (uint64_t)(n[0] + 1) * (n[1] + 1) * (n[2] + 1);
	if (samples > MAX_SAMPLES)
		return false;
	s.g = malloc(sizeof(float) * samples);
	s.vals = malloc(sizeof(double) * b->ninstr);
	if (!s.g || !s.vals) {
		free(s.g);
		free(s.vals);
		return false;
	}
	sample_grid(&s);
	march(&s);
	m->npoints = (uint32_t)(s.P.len / 3);
	m->ntris = (uint32_t)(s.tris.len / 3);
	m->tris = s.tris.data;
	m->P = rl_xmalloc(sizeof(float) * 3 * (m->npoints ? m->npoints : 1));
	m->N = rl_xmalloc(sizeof(float) * 3 * (m->npoints ? m->npoints : 1));
	m->leaf = rl_xcalloc((size_t)m->npoints * b->nleaf + 1, sizeof(double));
	normals(&s, m);
	free(s.g);
	free(s.vals);
	free(s.edges);
	free(s.P.data);
	return true;
}

void reyes_blobby_mesh_finish(struct reyes_blobby_mesh *m)
{
	free(m->P);
	free(m->N);
	free(m->tris);
	free(m->leaf);
	*m = (struct reyes_blobby_mesh){0};
}

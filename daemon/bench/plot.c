/*
 * The benchmark report's pictures: SVG 1.1 line plots and bar charts, and
 * error heat maps as PNG.
 *
 * An SVG is built in memory and written in one atomic step. The picture is
 * laid out in pixels (the SVG's user units):
 *
 *   title, centred over the plot area
 *   the plot area, the rectangle with class "plot-area"; a value v lies at
 *       x = area.x + (u(v) - u(xlo)) / (u(xhi) - u(xlo)) * area.width
 *       y = area.y + area.height - (u(v) - u(ylo)) / (u(yhi) - u(ylo)) * area.height
 *     where u is the identity on a linear axis and log10 on a log axis, and
 *     [xlo, xhi], [ylo, yhi] are the axes' first and last ticks: on a linear
 *     axis the multiples of a 1-2-5 step that just cover every drawn value,
 *     on a log axis the powers of ten that do;
 *   tick labels left of and under the area, the axis labels beyond them;
 *   the legend right of the area (or under it, when it would take more than
 *     a third of the width), never over the data;
 *   a note under everything when some points could not be drawn.
 *
 * Widths of text are estimated (0.6 em a character), which is close enough
 * for the generic sans-serif fonts that viewers substitute.
 */
#include "plot.h"

#include "fileutil.h"
#include "png.h"
#include "strbuf.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEFAULT_WIDTH 720
#define DEFAULT_HEIGHT 440
#define MIN_WIDTH 240
#define MIN_HEIGHT 160
#define MAX_SIZE 16384

#define FONT_TICK 12.0
#define FONT_AXIS 13.0
#define FONT_TITLE 15.0
#define FONT_SMALL 11.0
#define FONT_LEGEND 12.0
#define TICK_LEN 5.0
#define LEGEND_ROW 20.0
#define LEGEND_SWATCH 24.0

#define MAX_TICKS 80
#define MAX_LABEL 120           /* bytes of a legend or group label kept */

/*
 * Okabe and Ito's colour-blind-safe palette, ordered so that the first
 * colours are the most distinct on white (their yellow, weak on white, last).
 */
static const char *const palette[8] = {
	"#0072B2", /* blue */
	"#D55E00", /* vermillion */
	"#009E73", /* bluish green */
	"#CC79A7", /* reddish purple */
	"#E69F00", /* orange */
	"#56B4E9", /* sky blue */
	"#000000", /* black */
	"#F0E442", /* yellow */
};

/* The heat map's colour at 0, 1/5, 2/5, ... 5/5 of the scale. */
static const uint8_t ramp[6][3] = {
	{ 0, 0, 0 },            /* black */
	{ 0, 0, 255 },          /* blue */
	{ 0, 255, 0 },          /* green */
	{ 255, 255, 0 },        /* yellow */
	{ 255, 0, 0 },          /* red */
	{ 255, 255, 255 },      /* white */
};

void plot_ramp(double v, uint8_t rgb[3])
{
	/* The same operations, in the same order, as relight diff has always used. */
	double t = v * 5.0;
	if (!(t > 0.0))
		t = 0.0;
	if (t >= 5.0)
		t = 5.0;
	int i = t >= 5.0 ? 4 : (int)t;
	double f = t - i;
	for (int c = 0; c < 3; c++)
		rgb[c] = (uint8_t)lrint(ramp[i][c] + f * (ramp[i + 1][c] - ramp[i][c]));
}

static const char *colour_of(int index, size_t series)
{
	size_t i = index >= 0 ? (size_t)index : series;
	return palette[i % 8];
}

/* ---- text ---- */

/* The length of the UTF-8 sequence that starts at @s, or 0 if it is not one. */
static size_t utf8_len(const unsigned char *s)
{
	unsigned char c = s[0];
	size_t n;
	unsigned cp;
	if (c < 0x80)
		return 1;
	if (c >= 0xc2 && c <= 0xdf) {
		n = 2;
		cp = c & 0x1fu;
	} else if (c >= 0xe0 && c <= 0xef) {
		n = 3;
		cp = c & 0x0fu;
	} else if (c >= 0xf0 && c <= 0xf4) {
		n = 4;
		cp = c & 0x07u;
	} else {
		return 0;
	}
	for (size_t i = 1; i < n; i++) {
		if ((s[i] & 0xc0) != 0x80)
			return 0;
		cp = cp << 6 | (s[i] & 0x3fu);
	}
	/* Overlong forms, surrogates and code points past U+10FFFF are not text. */
	if ((n == 3 && cp < 0x800) || (n == 4 && (cp < 0x10000 || cp > 0x10ffff)) ||
	    (cp >= 0xd800 && cp <= 0xdfff))
		return 0;
	/* U+FFFE and U+FFFF are not XML characters either. */
	if (cp == 0xfffe || cp == 0xffff)
		return 0;
	return n;
}

/* Characters in @s, each invalid byte counting as one (it is drawn as U+FFFD). */
static size_t text_chars(const char *s)
{
	size_t n = 0;
	const unsigned char *p = (const unsigned char *)s;
	while (*p) {
		size_t l = utf8_len(p);
		p += l ? l : 1;
		n++;
	}
	return n;
}

/* An estimate of the width of @s drawn at @size pixels. */
static double text_width(const char *s, double size)
{
	return (double)text_chars(s) * size * 0.6;
}

/*
 * @s cut to at most @maxbytes bytes and @maxw pixels at @size, at a
 * character boundary, with an ellipsis where something was cut off.
 */
static void text_fit(const char *s, double size, double maxw, size_t maxbytes, char *out,
		     size_t outlen)
{
	static const char ellipsis[] = "\xe2\x80\xa6";
	size_t len = strlen(s);
	if (len <= maxbytes && len < outlen && text_width(s, size) <= maxw) {
		memcpy(out, s, len + 1);
		return;
	}
	const unsigned char *p = (const unsigned char *)s;
	size_t used = 0, chars = 0;
	double room = maxw - size * 0.6; /* the ellipsis */
	while (p[used]) {
		size_t l = utf8_len(p + used);
		if (!l)
			l = 1;
		if (used + l + sizeof(ellipsis) > outlen || used + l > maxbytes ||
		    (double)(chars + 1) * size * 0.6 > room)
			break;
		used += l;
		chars++;
	}
	memcpy(out, s, used);
	memcpy(out + used, ellipsis, sizeof(ellipsis));
}

/* ---- the SVG being built ---- */

struct svg {
	struct rl_strbuf b;
	bool bad;               /* a non-finite number was to be written */
	char num[12][32];       /* a ring of formatted numbers, see N() */
	int next;
};

static void put(struct svg *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void put(struct svg *s, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	rl_strbuf_vprintf(&s->b, fmt, ap);
	va_end(ap);
}

/* Strip the zeros after a decimal point, and the point when nothing is left after it. */
static void strip_zeros(char *buf)
{
	char *dot = strchr(buf, '.');
	if (!dot || strchr(buf, 'e'))
		return;
	char *end = buf + strlen(buf);
	while (end > dot + 1 && end[-1] == '0')
		*--end = '\0';
	if (end == dot + 1)
		*dot = '\0';
}

/*
 * A coordinate as text, to 0.01 pixel, without trailing zeros. The text
 * lives in a ring of twelve buffers, so one put() may use up to twelve of
 * them. A non-finite value, which a correct layout never gives, marks the
 * picture as bad instead of printing "nan" into it.
 */
static const char *N(struct svg *s, double v)
{
	char *buf = s->num[s->next];
	s->next = (s->next + 1) % 12;
	if (!isfinite(v)) {
		s->bad = true;
		v = 0.0;
	}
	snprintf(buf, sizeof(s->num[0]), "%.2f", v);
	strip_zeros(buf);
	if (strcmp(buf, "-0") == 0)
		strcpy(buf, "0");
	return buf;
}

/*
 * Append @t as XML character data (or attribute text): markup characters
 * escaped, control characters (which XML 1.0 forbids) and invalid UTF-8
 * replaced by U+FFFD, so that no label can break the file.
 */
static void put_text(struct svg *s, const char *t)
{
	const unsigned char *p = (const unsigned char *)t;
	while (*p) {
		size_t l = utf8_len(p);
		switch (*p) {
		case '&': rl_strbuf_puts(&s->b, "&amp;"); break;
		case '<': rl_strbuf_puts(&s->b, "&lt;"); break;
		case '>': rl_strbuf_puts(&s->b, "&gt;"); break;
		case '"': rl_strbuf_puts(&s->b, "&quot;"); break;
		case '\'': rl_strbuf_puts(&s->b, "&apos;"); break;
		default:
			if (!l || (*p < 0x20 && *p != '\t'))
				rl_strbuf_puts(&s->b, "\xef\xbf\xbd");
			else
				rl_strbuf_add(&s->b, (const char *)p, l);
		}
		p += l ? l : 1;
	}
}

/* <text> at (@x, @y) with @attrs (extra attributes, may be ""), the text escaped. */
static void put_label(struct svg *s, double x, double y, const char *attrs, const char *t)
{
	put(s, "<text x=\"%s\" y=\"%s\"%s%s>", N(s, x), N(s, y), *attrs ? " " : "", attrs);
	put_text(s, t);
	put(s, "</text>\n");
}

/*
 * A label over data: first the same text in a thick white stroke, so that
 * lines crossing it do not cut through the letters (SVG 1.1 has no
 * paint-order, so the halo is a text element of its own).
 */
static void put_label_halo(struct svg *s, double x, double y, const char *attrs,
			   const char *colour, const char *t)
{
	char a[256];
	snprintf(a, sizeof(a), "%s%sfill=\"#ffffff\" stroke=\"#ffffff\" stroke-width=\"3\" "
		 "stroke-linejoin=\"round\"", attrs, *attrs ? " " : "");
	put_label(s, x, y, a, t);
	snprintf(a, sizeof(a), "%s%sfill=\"%s\"", attrs, *attrs ? " " : "", colour);
	put_label(s, x, y, a, t);
}

static void svg_begin(struct svg *s, int w, int h, const char *title)
{
	memset(s, 0, sizeof(*s));
	put(s, "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"no\"?>\n"
	       "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"%d\" "
	       "height=\"%d\" viewBox=\"0 0 %d %d\" font-family=\"sans-serif\" "
	       "font-size=\"12\">\n", w, h, w, h);
	if (title && *title) {
		put(s, "<title>");
		put_text(s, title);
		put(s, "</title>\n");
	}
	/* An opaque background: on a dark page a transparent plot would be unreadable. */
	put(s, "<rect width=\"%d\" height=\"%d\" fill=\"#ffffff\"/>\n", w, h);
}

/* Finish @s and write it to @path atomically; @s is freed either way. */
static bool svg_write(struct svg *s, const char *path, char *err, size_t errlen)
{
	put(s, "</svg>\n");
	bool ok = false;
	if (s->bad)
		snprintf(err, errlen, "%s: a coordinate of the plot is not finite", path);
	else
		ok = rl_write_file_atomic(path, s->b.data, s->b.len, err, errlen);
	rl_strbuf_finish(&s->b);
	return ok;
}

/* ---- axes ---- */

struct tick {
	double u;               /* position in axis units */
	bool major;             /* a full-length tick and a grid line */
	char label[32];         /* "" for none */
};

struct axis {
	bool log;
	double lo, hi;          /* axis units: the value, or its log10 */
	double p_lo, p_hi;      /* pixel positions of lo and hi */
	size_t nticks;
	struct tick ticks[MAX_TICKS];
};

static double axis_pos(const struct axis *a, double v)
{
	double u = a->log ? log10(v) : v;
	return a->p_lo + (u - a->lo) / (a->hi - a->lo) * (a->p_hi - a->p_lo);
}

static void add_tick(struct axis *a, double u, bool major, const char *label)
{
	if (a->nticks == MAX_TICKS)
		return;
	struct tick *t = &a->ticks[a->nticks++];
	t->u = u;
	t->major = major;
	snprintf(t->label, sizeof(t->label), "%s", label ? label : "");
}

/* The widest tick label, in pixels at the tick font. */
static double axis_label_width(const struct axis *a)
{
	double w = 0.0;
	for (size_t i = 0; i < a->nticks; i++)
		w = fmax(w, text_width(a->ticks[i].label, FONT_TICK));
	return w;
}

static size_t axis_labels(const struct axis *a)
{
	size_t n = 0;
	for (size_t i = 0; i < a->nticks; i++)
		n += a->ticks[i].label[0] != '\0';
	return n;
}

/* @v with @prec significant digits, as %g writes it, never "-0". */
static void fmt_g(double v, int prec, char *buf, size_t len)
{
	snprintf(buf, len, "%.*g", prec, v);
	if (strcmp(buf, "-0") == 0)
		snprintf(buf, len, "0");
}

/*
 * A linear axis over [@lo, @hi] (finite) with about @target intervals: the
 * step is 1, 2 or 5 times a power of ten, the ends are multiples of it.
 */
static bool axis_linear(struct axis *a, double lo, double hi, int target)
{
	a->log = false;
	a->nticks = 0;
	if (lo == hi) {
		double d = lo == 0.0 ? 1.0 : fabs(lo) * 0.1;
		lo -= d;
		hi += d;
	}
	double span = hi - lo;
	if (!isfinite(span) || !(span > 0.0) || target < 1)
		return false;
	double raw = span / target;
	double mag = pow(10.0, floor(log10(raw)));
	double r = raw / mag;
	double step = (r <= 1.0 + 1e-9 ? 1.0 : r <= 2.0 + 1e-9 ? 2.0 : r <= 5.0 + 1e-9 ? 5.0 : 10.0) *
		      mag;
	if (!isfinite(step) || !(step > 0.0))
		return false;
	/* A little slack so that 0.3 / 0.1 = 2.9999999999999996 does not add a tick. */
	double k0 = floor(lo / step + 1e-9), k1 = ceil(hi / step - 1e-9);
	if (k0 * step > lo + step * 1e-6)
		k0 -= 1.0;
	if (k1 * step < hi - step * 1e-6)
		k1 += 1.0;
	if (k1 <= k0)
		k1 = k0 + 1.0;
	if (k1 - k0 + 1.0 > MAX_TICKS)
		return false;
	a->lo = k0 * step;
	a->hi = k1 * step;
	if (!isfinite(a->lo) || !isfinite(a->hi) || !(a->hi > a->lo))
		return false;
	/* Enough digits to tell neighbouring ticks apart; whole numbers in full up to 6 digits. */
	int emax = (int)floor(log10(fmax(fabs(a->lo), fabs(a->hi))));
	int estep = (int)floor(log10(step));
	int prec = emax - estep + 1;
	if (emax >= 0 && emax <= 5 && prec < emax + 1)
		prec = emax + 1;
	prec = prec < 1 ? 1 : prec > 17 ? 17 : prec;
	for (double k = k0; k <= k1; k += 1.0) {
		double v = k * step;
		if (fabs(v) < step * 1e-6)
			v = 0.0;
		char label[32];
		fmt_g(v, prec, label, sizeof(label));
		add_tick(a, v, true, label);
	}
	return true;
}

/* 10^@d as a tick label: "0.001" to "1000" in full, "1e+04", "1e-05" beyond. */
static void fmt_decade(int d, int mant, char *buf, size_t len)
{
	if (d >= -3 && d <= 3)
		fmt_g(mant * pow(10.0, d), 6, buf, len);
	else
		snprintf(buf, len, "%de%+03d", mant, d);
}

/*
 * A base-10 log axis over [@lo, @hi] (0 < lo <= hi, finite): from the
 * power of ten at or below @lo to the one at or above @hi. Decades are
 * labelled (every k-th one when there are more than ten), with minor ticks
 * at 2 and 5 times each decade, labelled too when there is only one decade.
 */
static bool axis_log(struct axis *a, double lo, double hi)
{
	a->log = true;
	a->nticks = 0;
	if (!(lo > 0.0) || !(hi >= lo) || !isfinite(hi))
		return false;
	/* log10 rounds; correct by one decade where it crossed a power of ten. */
	int d0 = (int)floor(log10(lo));
	if (pow(10.0, d0) > lo)
		d0--;
	else if (pow(10.0, d0 + 1) <= lo)
		d0++;
	int d1 = (int)ceil(log10(hi));
	if (pow(10.0, d1) < hi)
		d1++;
	else if (pow(10.0, d1 - 1) >= hi)
		d1--;
	if (d1 <= d0) {
		d0--;
		d1++;
	}
	int ndec = d1 - d0;
	int every = ndec <= 10 ? 1 : (ndec + 9) / 10;
	a->lo = d0;
	a->hi = d1;
	for (int d = d0; d <= d1; d++) {
		char label[32];
		bool labelled = ((d % every) + every) % every == 0;
		if (labelled) {
			fmt_decade(d, 1, label, sizeof(label));
			add_tick(a, d, true, label);
		} else if (ndec <= 60) {
			add_tick(a, d, false, NULL);
		}
		if (d < d1 && ndec <= 12) {
			static const int minor[2] = { 2, 5 };
			for (int m = 0; m < 2; m++) {
				if (ndec == 1)
					fmt_decade(d, minor[m], label, sizeof(label));
				add_tick(a, d + log10(minor[m]), false, ndec == 1 ? label : NULL);
			}
		}
	}
	return true;
}

/* ---- layout ---- */

struct legend_entry {
	char text[MAX_LABEL + 4];
	const char *colour;
	int marker;             /* -1: a bar swatch */
	bool dashed;
	double w;               /* the entry's width, swatch and text */
	double x, y;            /* where it goes: the swatch's left end, the row's middle */
};

struct legend {
	size_t n;
	struct legend_entry *e;
	bool below;
	double width;           /* right: the column's width; below: unused */
	int rows;
};

struct frame {
	int w, h;
	double x0, y0, x1, y1;  /* the plot area */
	double ylab_w;          /* the widest y tick label */
	double below_h;         /* room under the area for tick or group labels */
	bool has_xlabel, has_ylabel, has_title, has_note;
	double legend_y;        /* below: the first row's middle */
	double note_y;
};

/*
 * Place the plot area and the legend in a @o picture. The caller gives the
 * widest y tick label and the room its x labels need under the area.
 */
static bool frame_layout(struct frame *f, const struct plot_opts *o, double ylab_w,
			 double below_h, bool note, struct legend *lg)
{
	f->ylab_w = ylab_w;
	f->below_h = below_h;
	f->has_title = o->title && *o->title;
	f->has_xlabel = o->xlabel && *o->xlabel;
	f->has_ylabel = o->ylabel && *o->ylabel;
	f->has_note = note;
	double left = 10.0 + (f->has_ylabel ? FONT_AXIS + 8.0 : 0.0) + ylab_w + TICK_LEN + 4.0;
	double top = f->has_title ? 36.0 : 14.0;
	/* Room for half of the last x tick label, which is centred on the area's edge. */
	double right = 28.0;
	double bottom = below_h + (f->has_xlabel ? 22.0 : 0.0) + (note ? 18.0 : 0.0) + 10.0;

	double widest = 0.0;
	for (size_t i = 0; i < lg->n; i++) {
		lg->e[i].w = LEGEND_SWATCH + 8.0 + text_width(lg->e[i].text, FONT_LEGEND);
		widest = fmax(widest, lg->e[i].w);
	}
	lg->below = false;
	lg->rows = 0;
	if (lg->n) {
		double column = widest + 28.0;
		double room = f->h - top - bottom;
		if (column <= f->w / 3.0 && (double)lg->n * LEGEND_ROW <= room) {
			lg->width = column;
			right = column;
			lg->rows = (int)lg->n;
		} else {
			lg->below = true;
		}
	}
	f->x0 = left;
	f->x1 = f->w - right;
	if (lg->below) {
		/* Entries flow left to right under the plot, wrapping at the area's width. */
		double avail = f->x1 - f->x0, x = 0.0;
		int row = 0;
		for (size_t i = 0; i < lg->n; i++) {
			if (lg->e[i].w > avail) {
				/* Too long for a row of its own: cut, with an ellipsis. */
				char cut[sizeof(lg->e[i].text)];
				text_fit(lg->e[i].text, FONT_LEGEND, avail - LEGEND_SWATCH - 8.0,
					 MAX_LABEL, cut, sizeof(cut));
				memcpy(lg->e[i].text, cut, sizeof(cut));
				lg->e[i].w = avail;
			}
			if (x > 0.0 && x + lg->e[i].w > avail) {
				row++;
				x = 0.0;
			}
			lg->e[i].x = x;
			lg->e[i].y = row;
			x += lg->e[i].w + 18.0;
		}
		lg->rows = row + 1;
		bottom += lg->rows * LEGEND_ROW + 4.0;
	}
	f->y0 = top;
	f->y1 = f->h - bottom;
	if (f->x1 - f->x0 < 80.0 || f->y1 - f->y0 < 60.0)
		return false;

	double after = f->y1 + below_h + (f->has_xlabel ? 22.0 : 0.0);
	f->legend_y = after + 4.0 + LEGEND_ROW / 2.0;
	f->note_y = after + (lg->below ? lg->rows * LEGEND_ROW + 4.0 : 0.0) + 14.0;
	for (size_t i = 0; i < lg->n; i++) {
		struct legend_entry *e = &lg->e[i];
		if (lg->below) {
			e->x += f->x0;
			e->y = f->legend_y + e->y * LEGEND_ROW;
		} else {
			e->x = f->x1 + 16.0;
			e->y = f->y0 + 8.0 + ((double)i + 0.5) * LEGEND_ROW;
		}
	}
	return true;
}

static bool legend_init(struct legend *lg, size_t max)
{
	memset(lg, 0, sizeof(*lg));
	lg->e = calloc(max ? max : 1, sizeof(*lg->e));
	return lg->e != NULL;
}

/* Add an entry (nothing for a NULL or empty label); -1 @marker for a bar swatch. */
static void legend_add(struct legend *lg, const char *label, const char *colour, int marker,
		       bool dashed, double maxw)
{
	if (!label || !*label)
		return;
	struct legend_entry *e = &lg->e[lg->n++];
	text_fit(label, FONT_LEGEND, maxw, MAX_LABEL, e->text, sizeof(e->text));
	e->colour = colour;
	e->marker = marker;
	e->dashed = dashed;
}

/* A marker of shape @shape (circle, square, triangle, diamond) centred on (@x, @y). */
static void put_marker(struct svg *s, int shape, double x, double y, const char *colour)
{
	const double r = 3.5;
	switch (shape % 4) {
	case 0:
		put(s, "<circle cx=\"%s\" cy=\"%s\" r=\"%s\" fill=\"%s\"/>\n", N(s, x), N(s, y),
		    N(s, r), colour);
		break;
	case 1:
		put(s, "<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" fill=\"%s\"/>\n",
		    N(s, x - r * 0.9), N(s, y - r * 0.9), N(s, 1.8 * r), N(s, 1.8 * r), colour);
		break;
	case 2:
		put(s, "<path d=\"M%s %sL%s %sL%s %sZ\" fill=\"%s\"/>\n", N(s, x), N(s, y - r * 1.2),
		    N(s, x + r * 1.1), N(s, y + r * 0.8), N(s, x - r * 1.1), N(s, y + r * 0.8),
		    colour);
		break;
	default:
		put(s, "<path d=\"M%s %sL%s %sL%s %sL%s %sZ\" fill=\"%s\"/>\n", N(s, x),
		    N(s, y - r * 1.25), N(s, x + r * 1.1), N(s, y), N(s, x), N(s, y + r * 1.25),
		    N(s, x - r * 1.1), N(s, y), colour);
		break;
	}
}

static void put_legend(struct svg *s, const struct legend *lg)
{
	if (!lg->n)
		return;
	put(s, "<g class=\"legend\" font-size=\"%d\">\n", (int)FONT_LEGEND);
	for (size_t i = 0; i < lg->n; i++) {
		const struct legend_entry *e = &lg->e[i];
		if (e->marker < 0) {
			put(s, "<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"10\" fill=\"%s\"/>\n",
			    N(s, e->x + 4.0), N(s, e->y - 5.0), N(s, LEGEND_SWATCH - 8.0), e->colour);
		} else {
			put(s, "<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"%s\" "
			    "stroke-width=\"2\"%s/>\n", N(s, e->x), N(s, e->y),
			    N(s, e->x + LEGEND_SWATCH), N(s, e->y), e->colour,
			    e->dashed ? " stroke-dasharray=\"6 4\"" : "");
			put_marker(s, e->marker, e->x + LEGEND_SWATCH / 2.0, e->y, e->colour);
		}
		put_label(s, e->x + LEGEND_SWATCH + 8.0, e->y + 4.0, "", e->text);
	}
	put(s, "</g>\n");
}

/* The title, the axis labels and the note of @f. */
static void put_frame_text(struct svg *s, const struct frame *f, const struct plot_opts *o,
			   const char *note)
{
	char buf[512];
	if (f->has_title) {
		/* Shrink a long title rather than cut it, down to the small font. */
		double size = FONT_TITLE, avail = f->w - 20.0;
		while (size > FONT_SMALL && text_width(o->title, size) > avail)
			size -= 1.0;
		text_fit(o->title, size, avail, sizeof(buf) - 4, buf, sizeof(buf) - 4);
		double cx = (f->x0 + f->x1) / 2.0, half = text_width(buf, size) / 2.0;
		cx = fmin(fmax(cx, 10.0 + half), f->w - 10.0 - half);
		char attrs[96];
		snprintf(attrs, sizeof(attrs), "text-anchor=\"middle\" font-size=\"%d\" "
			 "font-weight=\"bold\"", (int)size);
		put_label(s, cx, 22.0, attrs, buf);
	}
	if (f->has_xlabel) {
		text_fit(o->xlabel, FONT_AXIS, f->x1 - f->x0, sizeof(buf) - 4, buf, sizeof(buf) - 4);
		put_label(s, (f->x0 + f->x1) / 2.0, f->y1 + f->below_h + 17.0,
			  "text-anchor=\"middle\" font-size=\"13\"", buf);
	}
	if (f->has_ylabel) {
		text_fit(o->ylabel, FONT_AXIS, f->y1 - f->y0, sizeof(buf) - 4, buf, sizeof(buf) - 4);
		double x = 10.0 + FONT_AXIS - 2.0, y = (f->y0 + f->y1) / 2.0;
		char attrs[128];
		snprintf(attrs, sizeof(attrs), "text-anchor=\"middle\" font-size=\"13\" "
			 "transform=\"rotate(-90 %s %s)\"", N(s, x), N(s, y));
		put_label(s, x, y, attrs, buf);
	}
	if (note)
		put_label(s, 10.0, f->note_y, "font-size=\"11\" fill=\"#555555\"", note);
}

/* Grid lines and ticks of @x (NULL: none, as in bar charts) and @y, then the area's frame. */
static void put_axes(struct svg *s, const struct frame *f, const struct axis *x,
		     const struct axis *y)
{
	put(s, "<g class=\"grid\" shape-rendering=\"crispEdges\" stroke-width=\"1\">\n");
	for (int pass = 0; pass < 2; pass++) {
		/* Minor lines first, so that the major ones are drawn over them. */
		const char *colour = pass ? "#d9d9d9" : "#f0f0f0";
		for (size_t i = 0; x && i < x->nticks; i++) {
			const struct tick *t = &x->ticks[i];
			if (t->major != (pass == 1))
				continue;
			double px = x->p_lo + (t->u - x->lo) / (x->hi - x->lo) * (x->p_hi - x->p_lo);
			put(s, "<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"%s\"/>\n",
			    N(s, px), N(s, f->y0), N(s, px), N(s, f->y1), colour);
		}
		for (size_t i = 0; i < y->nticks; i++) {
			const struct tick *t = &y->ticks[i];
			if (t->major != (pass == 1))
				continue;
			double py = y->p_lo + (t->u - y->lo) / (y->hi - y->lo) * (y->p_hi - y->p_lo);
			put(s, "<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\" stroke=\"%s\"/>\n",
			    N(s, f->x0), N(s, py), N(s, f->x1), N(s, py), colour);
		}
	}
	put(s, "</g>\n");

	put(s, "<g class=\"ticks\" shape-rendering=\"crispEdges\" stroke=\"#333333\" "
	       "stroke-width=\"1\">\n");
	for (size_t i = 0; x && i < x->nticks; i++) {
		const struct tick *t = &x->ticks[i];
		double px = x->p_lo + (t->u - x->lo) / (x->hi - x->lo) * (x->p_hi - x->p_lo);
		double len = t->major ? TICK_LEN : TICK_LEN * 0.6;
		put(s, "<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\"/>\n", N(s, px), N(s, f->y1),
		    N(s, px), N(s, f->y1 + len));
	}
	for (size_t i = 0; i < y->nticks; i++) {
		const struct tick *t = &y->ticks[i];
		double py = y->p_lo + (t->u - y->lo) / (y->hi - y->lo) * (y->p_hi - y->p_lo);
		double len = t->major ? TICK_LEN : TICK_LEN * 0.6;
		put(s, "<line x1=\"%s\" y1=\"%s\" x2=\"%s\" y2=\"%s\"/>\n", N(s, f->x0 - len),
		    N(s, py), N(s, f->x0), N(s, py));
	}
	put(s, "</g>\n");

	put(s, "<g class=\"tick-labels\" font-size=\"%d\" fill=\"#333333\">\n", (int)FONT_TICK);
	for (size_t i = 0; x && i < x->nticks; i++) {
		const struct tick *t = &x->ticks[i];
		if (!t->label[0])
			continue;
		double px = x->p_lo + (t->u - x->lo) / (x->hi - x->lo) * (x->p_hi - x->p_lo);
		/* A long label at either end is moved in rather than cut off by the edge. */
		double half = text_width(t->label, FONT_TICK) / 2.0;
		px = fmax(fmin(px, f->w - 2.0 - half), 2.0 + half);
		put_label(s, px, f->y1 + TICK_LEN + 3.0 + FONT_TICK - 1.0, "text-anchor=\"middle\"",
			  t->label);
	}
	for (size_t i = 0; i < y->nticks; i++) {
		const struct tick *t = &y->ticks[i];
		if (!t->label[0])
			continue;
		double py = y->p_lo + (t->u - y->lo) / (y->hi - y->lo) * (y->p_hi - y->p_lo);
		put_label(s, f->x0 - TICK_LEN - 3.0, py + FONT_TICK * 0.35, "text-anchor=\"end\"",
			  t->label);
	}
	put(s, "</g>\n");
	put(s, "<rect class=\"plot-area\" x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" "
	    "fill=\"none\" stroke=\"#333333\" stroke-width=\"1\" shape-rendering=\"crispEdges\"/>\n",
	    N(s, f->x0), N(s, f->y0), N(s, f->x1 - f->x0), N(s, f->y1 - f->y0));
}

static bool check_size(const struct plot_opts *o, int *w, int *h, const char *path, char *err,
		       size_t errlen)
{
	*w = o->width ? o->width : DEFAULT_WIDTH;
	*h = o->height ? o->height : DEFAULT_HEIGHT;
	if (*w < MIN_WIDTH || *h < MIN_HEIGHT || *w > MAX_SIZE || *h > MAX_SIZE) {
		snprintf(err, errlen, "%s: a plot of %d x %d pixels; %d x %d to %d x %d are drawn",
			 path, *w, *h, MIN_WIDTH, MIN_HEIGHT, MAX_SIZE, MAX_SIZE);
		return false;
	}
	return true;
}

static bool check_path(const char *path, char *err, size_t errlen)
{
	if (!path || !*path) {
		snprintf(err, errlen, "plot: no output file named");
		return false;
	}
	return true;
}

static bool drawable(double v, bool log)
{
	return isfinite(v) && (!log || v > 0.0);
}

/* The note under a plot for @n things left out, or NULL when there are none. */
static const char *skip_note(size_t n, const char *what, bool log, char *buf, size_t len)
{
	if (!n)
		return NULL;
	snprintf(buf, len, "%zu %s%s not drawn (%s)", n, what, n == 1 ? "" : "s",
		 log ? "not finite, or not positive on a log axis" : "not finite");
	return buf;
}

/* ---- line plots ---- */

bool plot_lines_svg(const char *path, const struct plot_opts *o, const struct plot_series *s,
		    size_t ns, char *err, size_t errlen)
{
	static const struct plot_opts defaults = { 0 };
	if (!check_path(path, err, errlen))
		return false;
	if (!o)
		o = &defaults;
	int w, h;
	if (!check_size(o, &w, &h, path, err, errlen))
		return false;
	if (!s && ns) {
		snprintf(err, errlen, "%s: no series given", path);
		return false;
	}

	/* The range of the drawable points, and how many are not. */
	double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
	size_t skipped = 0, drawn = 0;
	for (size_t k = 0; k < ns; k++) {
		if (s[k].n && (!s[k].x || !s[k].y)) {
			snprintf(err, errlen, "%s: series %zu has %zu points but no values", path, k,
				 s[k].n);
			return false;
		}
		for (size_t i = 0; i < s[k].n; i++) {
			double x = s[k].x[i], y = s[k].y[i];
			if (!drawable(x, o->xlog) || !drawable(y, o->ylog)) {
				skipped++;
				continue;
			}
			drawn++;
			xmin = fmin(xmin, x);
			xmax = fmax(xmax, x);
			ymin = fmin(ymin, y);
			ymax = fmax(ymax, y);
		}
	}
	if (!drawn) {
		snprintf(err, errlen, "%s: nothing to draw: none of the %zu points is finite%s", path,
			 skipped, o->xlog || o->ylog ? " and positive on the log axes" : "");
		return false;
	}
	char notebuf[160];
	const char *note = skip_note(skipped, "point", o->xlog || o->ylog, notebuf,
				     sizeof(notebuf));

	struct legend lg;
	if (!legend_init(&lg, ns)) {
		snprintf(err, errlen, "%s: out of memory", path);
		return false;
	}
	for (size_t k = 0; k < ns; k++)
		legend_add(&lg, s[k].label, colour_of(s[k].color, k), (int)(k % 4), s[k].dashed,
			   w * 0.8);

	/*
	 * The y tick labels set the left margin, and the area's height sets how
	 * many y ticks there are: settle them together (a wider margin never
	 * changes the height, so this ends at the second round).
	 */
	struct frame f = { .w = w, .h = h };
	struct axis *ax = calloc(2, sizeof(*ax));
	struct axis *xa = ax, *ya = ax ? ax + 1 : NULL;
	bool ok = false;
	double ylab_w = 0.0;
	if (!ax) {
		snprintf(err, errlen, "%s: out of memory", path);
		goto done;
	}
	for (int round = 0; round < 4; round++) {
		if (!frame_layout(&f, o, ylab_w, TICK_LEN + 3.0 + FONT_TICK + 2.0, note != NULL,
				  &lg)) {
			snprintf(err, errlen, "%s: a %d x %d plot has no room for its plot area "
				 "next to its labels and legend", path, w, h);
			goto done;
		}
		int target = (int)((f.y1 - f.y0) / 50.0);
		target = target < 2 ? 2 : target > 8 ? 8 : target;
		if (!(o->ylog ? axis_log(ya, ymin, ymax) : axis_linear(ya, ymin, ymax, target))) {
			snprintf(err, errlen, "%s: no axis fits the y values' range, %g to %g",
				 path, ymin, ymax);
			goto done;
		}
		double need = axis_label_width(ya);
		if (need <= ylab_w)
			break;
		ylab_w = need;
	}
	/* As many x ticks as there is room for their labels side by side. */
	for (int target = 8; target >= 1; target--) {
		if (!(o->xlog ? axis_log(xa, xmin, xmax) : axis_linear(xa, xmin, xmax, target))) {
			snprintf(err, errlen, "%s: no axis fits the x values' range, %g to %g",
				 path, xmin, xmax);
			goto done;
		}
		double room = (f.x1 - f.x0) / (double)(axis_labels(xa) > 1 ? axis_labels(xa) - 1 : 1);
		if (o->xlog || axis_label_width(xa) + 12.0 <= room)
			break;
	}
	xa->p_lo = f.x0;
	xa->p_hi = f.x1;
	ya->p_lo = f.y1;
	ya->p_hi = f.y0;

	struct svg svg;
	svg_begin(&svg, w, h, o->title);
	put_axes(&svg, &f, xa, ya);
	for (size_t k = 0; k < ns; k++) {
		const char *colour = colour_of(s[k].color, k);
		/* The line breaks where a point is left out: nothing is drawn across a gap. */
		bool open = false, any = false;
		for (size_t i = 0; i < s[k].n; i++) {
			double x = s[k].x[i], y = s[k].y[i];
			if (!drawable(x, o->xlog) || !drawable(y, o->ylog)) {
				open = false;
				continue;
			}
			if (!any)
				put(&svg, "<path class=\"series\" fill=\"none\" stroke=\"%s\" "
				    "stroke-width=\"2\" stroke-linejoin=\"round\"%s d=\"", colour,
				    s[k].dashed ? " stroke-dasharray=\"6 4\"" : "");
			put(&svg, "%s%s %s", open ? "L" : "M", N(&svg, axis_pos(xa, x)),
			    N(&svg, axis_pos(ya, y)));
			open = any = true;
		}
		if (any)
			put(&svg, "\"/>\n");
		for (size_t i = 0; i < s[k].n; i++) {
			double x = s[k].x[i], y = s[k].y[i];
			if (drawable(x, o->xlog) && drawable(y, o->ylog))
				put_marker(&svg, (int)(k % 4), axis_pos(xa, x), axis_pos(ya, y),
					   colour);
		}
	}
	/* The point labels over every line, so that no later series hides them. */
	for (size_t k = 0; k < ns; k++) {
		const char *colour = colour_of(s[k].color, k);
		for (size_t i = 0; s[k].point_labels && i < s[k].n; i++) {
			double x = s[k].x[i], y = s[k].y[i];
			const char *t = s[k].point_labels[i];
			if (!t || !*t || !drawable(x, o->xlog) || !drawable(y, o->ylog))
				continue;
			char buf[MAX_LABEL + 4];
			text_fit(t, FONT_SMALL, 200.0, MAX_LABEL, buf, sizeof(buf));
			/* Right of the point, or left of it near the area's right edge. */
			double px = axis_pos(xa, x), py = axis_pos(ya, y);
			bool left = px + 6.0 + text_width(buf, FONT_SMALL) > f.x1;
			put_label_halo(&svg, left ? px - 6.0 : px + 6.0, py - 6.0,
				       left ? "font-size=\"11\" text-anchor=\"end\"" : "font-size=\"11\"",
				       colour, buf);
		}
	}
	put_legend(&svg, &lg);
	put_frame_text(&svg, &f, o, note);
	ok = svg_write(&svg, path, err, errlen);
done:
	free(ax);
	free(lg.e);
	return ok;
}

/* ---- bar charts ---- */

/* @v to 3 significant digits, compactly: "0.0123", "4.5", "1230", "1.2e+06". */
static void fmt_sig3(double v, char *buf, size_t len)
{
	double a = fabs(v);
	if (a >= 1e3 && a < 1e5) {
		double unit = pow(10.0, floor(log10(a)) - 2.0);
		fmt_g(round(v / unit) * unit, 6, buf, len);
	} else {
		fmt_g(v, 3, buf, len);
	}
}

bool plot_bars_svg(const char *path, const struct plot_opts *o, const char *const *groups,
		   size_t ngroups, const char *const *series, size_t nseries, const double *values,
		   char *err, size_t errlen)
{
	static const struct plot_opts defaults = { 0 };
	if (!check_path(path, err, errlen))
		return false;
	if (!o)
		o = &defaults;
	int w, h;
	if (!check_size(o, &w, &h, path, err, errlen))
		return false;
	if (!ngroups || !nseries || !values || ngroups > 4096 || nseries > 4096) {
		snprintf(err, errlen, "%s: a bar chart needs 1 to 4096 groups of 1 to 4096 bars "
			 "(%zu groups, %zu series)", path, ngroups, nseries);
		return false;
	}
	size_t nval = ngroups * nseries;
	double vmin = INFINITY, vmax = -INFINITY;
	size_t skipped = 0;
	for (size_t i = 0; i < nval; i++) {
		double v = values[i];
		if (!drawable(v, o->ylog) || v < 0.0) {
			skipped++;
			continue;
		}
		vmin = fmin(vmin, v);
		vmax = fmax(vmax, v);
	}
	if (skipped == nval) {
		snprintf(err, errlen, "%s: nothing to draw: none of the %zu bars is finite%s", path,
			 nval, o->ylog ? " and positive on the log axis" : " and not negative");
		return false;
	}
	char notebuf[160];
	const char *note = skip_note(skipped, "bar", o->ylog, notebuf, sizeof(notebuf));

	/* The value labels, and the widest of them. */
	char (*labels)[32] = calloc(nval, sizeof(*labels));
	struct legend lg = { 0 };
	struct axis *ya = calloc(1, sizeof(*ya));
	bool ok = false;
	if (!labels || !ya || !legend_init(&lg, nseries)) {
		snprintf(err, errlen, "%s: out of memory", path);
		goto done;
	}
	double lab_w = 0.0;
	for (size_t i = 0; i < nval; i++) {
		if (drawable(values[i], o->ylog) && values[i] >= 0.0) {
			fmt_sig3(values[i], labels[i], sizeof(labels[i]));
			lab_w = fmax(lab_w, text_width(labels[i], FONT_SMALL));
		}
	}
	for (size_t k = 0; k < nseries; k++)
		legend_add(&lg, series ? series[k] : NULL, palette[k % 8], -1, false, w * 0.8);
	double glab_w = 0.0;
	for (size_t g = 0; groups && g < ngroups; g++)
		if (groups[g])
			glab_w = fmax(glab_w, fmin(text_width(groups[g], FONT_TICK),
						   FONT_TICK * 0.6 * 30));

	/*
	 * Settle together: the left margin (y tick labels), the room under the
	 * area (group labels, slanted when they do not fit their group), the
	 * bars' width (value labels upright when they do not fit a bar) and the
	 * headroom above the tallest bar for its label.
	 */
	struct frame f = { .w = w, .h = h };
	double ylab_w = 0.0, gw = 0.0, bw = 0.0;
	bool slant = false, upright = false;
	for (int round = 0; round < 4; round++) {
		double below = slant ? 10.0 + glab_w * 0.574 + FONT_TICK * 0.82
				     : TICK_LEN + 3.0 + FONT_TICK + 2.0;
		if (!frame_layout(&f, o, ylab_w, below, note != NULL, &lg)) {
			snprintf(err, errlen, "%s: a %d x %d chart has no room for its plot area "
				 "next to its labels and legend", path, w, h);
			goto done;
		}
		gw = (f.x1 - f.x0) / (double)ngroups;
		bw = gw * 0.8 / (double)nseries;
		bool slant2 = glab_w > gw - 6.0;
		upright = lab_w > bw + 2.0;
		double ph = f.y1 - f.y0;
		double headroom = upright ? lab_w + 8.0 : FONT_SMALL + 6.0;
		headroom = fmin(headroom, ph * 0.6);
		int target = (int)(ph / 50.0);
		target = target < 2 ? 2 : target > 8 ? 8 : target;
		bool axis_ok;
		if (o->ylog) {
			/* Another decade on top until the tallest bar's label fits under it. */
			double top = vmax;
			axis_ok = axis_log(ya, vmin, top);
			for (int i = 0; axis_ok && i < 3 &&
			     (ya->hi - log10(vmax)) / (ya->hi - ya->lo) * ph < headroom; i++)
				axis_ok = axis_log(ya, vmin, top *= 10.0);
		} else {
			double top = vmax > 0.0 ? vmax * ph / (ph - headroom) : 1.0;
			axis_ok = axis_linear(ya, 0.0, top, target);
		}
		if (!axis_ok) {
			snprintf(err, errlen, "%s: no axis fits the values' range, %g to %g", path,
				 vmin, vmax);
			goto done;
		}
		double need = axis_label_width(ya);
		if (need <= ylab_w && slant2 == slant)
			break;
		ylab_w = fmax(need, ylab_w);
		slant = slant2 || slant;
	}
	ya->p_lo = f.y1;
	ya->p_hi = f.y0;

	struct svg svg;
	svg_begin(&svg, w, h, o->title);
	put_axes(&svg, &f, NULL, ya);
	double base = f.y1;
	put(&svg, "<g class=\"bars\">\n");
	for (size_t g = 0; g < ngroups; g++) {
		for (size_t k = 0; k < nseries; k++) {
			double v = values[g * nseries + k];
			if (!drawable(v, o->ylog) || v < 0.0)
				continue;
			double x = f.x0 + (double)g * gw + gw * 0.1 + (double)k * bw;
			double top = axis_pos(ya, v);
			/* A hairline gap between neighbouring bars, when they are wide enough. */
			double inset = bw > 6.0 ? 0.5 : 0.0;
			put(&svg, "<rect x=\"%s\" y=\"%s\" width=\"%s\" height=\"%s\" fill=\"%s\"/>\n",
			    N(&svg, x + inset), N(&svg, top), N(&svg, bw - 2.0 * inset),
			    N(&svg, base - top), palette[k % 8]);
		}
	}
	put(&svg, "</g>\n<g class=\"values\" font-size=\"11\" fill=\"#222222\">\n");
	for (size_t g = 0; g < ngroups; g++) {
		for (size_t k = 0; k < nseries; k++) {
			size_t i = g * nseries + k;
			if (!labels[i][0])
				continue;
			double cx = f.x0 + (double)g * gw + gw * 0.1 + ((double)k + 0.5) * bw;
			double top = axis_pos(ya, values[i]);
			if (upright) {
				double x = cx + FONT_SMALL * 0.35, y = top - 4.0;
				char attrs[96];
				snprintf(attrs, sizeof(attrs), "transform=\"rotate(-90 %s %s)\"",
					 N(&svg, x), N(&svg, y));
				put_label(&svg, x, y, attrs, labels[i]);
			} else {
				put_label(&svg, cx, top - 4.0, "text-anchor=\"middle\"", labels[i]);
			}
		}
	}
	put(&svg, "</g>\n<g class=\"groups\" font-size=\"%d\" fill=\"#333333\">\n",
	    (int)FONT_TICK);
	for (size_t g = 0; groups && g < ngroups; g++) {
		if (!groups[g] || !*groups[g])
			continue;
		char buf[MAX_LABEL + 4];
		text_fit(groups[g], FONT_TICK, FONT_TICK * 0.6 * 30, MAX_LABEL, buf, sizeof(buf));
		double cx = f.x0 + ((double)g + 0.5) * gw;
		double y = f.y1 + TICK_LEN + 3.0 + FONT_TICK - 1.0;
		if (slant) {
			char attrs[128];
			snprintf(attrs, sizeof(attrs), "text-anchor=\"end\" transform=\"rotate(-35 %s "
				 "%s)\"", N(&svg, cx), N(&svg, y));
			put_label(&svg, cx, y, attrs, buf);
		} else {
			put_label(&svg, cx, y, "text-anchor=\"middle\"", buf);
		}
	}
	put(&svg, "</g>\n");
	put_legend(&svg, &lg);
	put_frame_text(&svg, &f, o, note);
	ok = svg_write(&svg, path, err, errlen);
done:
	free(lg.e);
	free(ya);
	free(labels);
	return ok;
}

/* ---- heat maps ---- */

bool plot_heatmap_png(const char *path, const float *const *maps, size_t nmaps, uint32_t w,
		      uint32_t h, uint32_t shrink, double vmax, char *err, size_t errlen)
{
	static const uint8_t gap_rgb[3] = { 128, 128, 128 };
	static const uint8_t bad_rgb[3] = { 255, 0, 255 };
	if (!check_path(path, err, errlen))
		return false;
	if (!maps || !nmaps || !w || !h || !shrink) {
		snprintf(err, errlen, "%s: a heat map needs at least one map of at least 1 x 1 "
			 "pixels and a shrink factor of at least 1", path);
		return false;
	}
	if (!isfinite(vmax) || !(vmax > 0.0)) {
		snprintf(err, errlen, "%s: the heat map's scale must be above 0 and finite", path);
		return false;
	}
	for (size_t k = 0; k < nmaps; k++) {
		if (!maps[k]) {
			snprintf(err, errlen, "%s: heat map %zu has no values", path, k);
			return false;
		}
	}
	uint64_t ow = ((uint64_t)w + shrink - 1) / shrink, oh = ((uint64_t)h + shrink - 1) / shrink;
	uint64_t W = (uint64_t)nmaps * ow + ((uint64_t)nmaps - 1) * PLOT_HEATMAP_GAP;
	uint64_t H = oh + PLOT_HEATMAP_GAP + PLOT_HEATMAP_BAR;
	if (nmaps > UINT32_MAX || W > 0x7fffffffu || H > 0x7fffffffu || W * H > (1u << 26)) {
		snprintf(err, errlen, "%s: a heat map of %llu x %llu pixels is too large", path,
			 (unsigned long long)W, (unsigned long long)H);
		return false;
	}
	uint8_t *px = malloc((size_t)(W * H * 3));
	if (!px) {
		snprintf(err, errlen, "%s: out of memory for the heat map", path);
		return false;
	}
	for (size_t i = 0; i < W * H; i++)
		memcpy(px + 3 * i, gap_rgb, 3);
	for (size_t k = 0; k < nmaps; k++) {
		const float *m = maps[k];
		size_t x_off = k * (size_t)(ow + PLOT_HEATMAP_GAP);
		for (uint64_t oy = 0; oy < oh; oy++) {
			for (uint64_t ox = 0; ox < ow; ox++) {
				/* The block's largest value; any non-finite one marks the whole block. */
				float top = 0.0f;
				bool bad = false;
				uint64_t y1 = (oy + 1) * shrink < h ? (oy + 1) * shrink : h;
				uint64_t x1 = (ox + 1) * shrink < w ? (ox + 1) * shrink : w;
				for (uint64_t y = oy * shrink; y < y1; y++) {
					for (uint64_t x = ox * shrink; x < x1; x++) {
						float v = m[(size_t)y * w + x];
						if (!isfinite(v))
							bad = true;
						else if (v > top)
							top = v;
					}
				}
				uint8_t *p = px + 3 * (size_t)(oy * W + x_off + ox);
				if (bad)
					memcpy(p, bad_rgb, 3);
				else
					plot_ramp((double)top / vmax, p);
			}
		}
	}
	/* The colour bar: the ramp from 0 at the left edge to @vmax at the right one. */
	for (uint64_t y = oh + PLOT_HEATMAP_GAP; y < H; y++)
		for (uint64_t x = 0; x < W; x++)
			plot_ramp(W > 1 ? (double)x / (double)(W - 1) : 0.0,
				  px + 3 * (size_t)(y * W + x));

	/* The writer reports to a stream; catch its message for @err. */
	char *msg = NULL;
	size_t msglen = 0;
	FILE *diag = open_memstream(&msg, &msglen);
	FILE *devnull = NULL;
	if (!diag)
		devnull = fopen("/dev/null", "w");
	bool ok = reyes_png_write(path, px, (uint32_t)W, (uint32_t)H, 3,
				  diag ? diag : devnull ? devnull : stderr);
	if (diag)
		fclose(diag);
	if (devnull)
		fclose(devnull);
	if (!ok) {
		if (msg && msglen) {
			while (msglen && (msg[msglen - 1] == '\n' || msg[msglen - 1] == '\r'))
				msg[--msglen] = '\0';
			snprintf(err, errlen, "%s", msg);
		} else {
			snprintf(err, errlen, "%s: cannot write the heat map", path);
		}
	}
	free(msg);
	free(px);
	return ok;
}

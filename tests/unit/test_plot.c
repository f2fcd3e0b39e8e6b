/*
 * The report's pictures. SVGs are written to a temporary directory and read
 * back: well-formed XML (a small checker here: balanced tags, quoted
 * attributes, valid entities, one <svg> root), points at the pixels the
 * axis mapping of plot.h puts them, decade labels on log axes, escaped
 * text, left-out points counted and never printed as "nan"/"inf", refusals
 * that leave old files alone; bar charts with their value labels and bar
 * heights; heat maps decoded here (chunks, CRCs, inflate) and checked pixel
 * by pixel.
 */
#include "plot.h"

#include "test.h"

#include <ctype.h>
#include <dirent.h>
#include <stdbool.h>
#include <stdint.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

static char dir[] = "/tmp/relight-test-plot-XXXXXX";

static const char *in_dir(const char *name)
{
	static char buf[4][512];
	static int next;
	char *p = buf[next++ % 4];
	snprintf(p, sizeof(buf[0]), "%s/%s", dir, name);
	return p;
}

/* The whole file, NUL-terminated (NULL if it cannot be read); *size its length. */
static char *slurp(const char *path, size_t *size)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	size_t cap = 1 << 16, n = 0, got;
	char *buf = malloc(cap + 1);
	while (buf && (got = fread(buf + n, 1, cap - n, f)) > 0) {
		n += got;
		if (n == cap) {
			char *nb = realloc(buf, (cap *= 2) + 1);
			if (!nb)
				free(buf);
			buf = nb;
		}
	}
	fclose(f);
	if (buf)
		buf[n] = '\0';
	if (size)
		*size = n;
	return buf;
}

static bool exists(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0;
}

/* ---- a small XML well-formedness checker ---- */

static bool name_start(int c)
{
	return isalpha(c) || c == '_' || c == ':';
}

static bool name_char(int c)
{
	return isalnum(c) || c == '_' || c == ':' || c == '.' || c == '-';
}

/* At '&': one of XML's five entities or a character reference; *p moves past it. */
static bool entity(const char **p)
{
	static const char *const named[] = { "&amp;", "&lt;", "&gt;", "&quot;", "&apos;" };
	for (int i = 0; i < 5; i++) {
		size_t n = strlen(named[i]);
		if (strncmp(*p, named[i], n) == 0) {
			*p += n;
			return true;
		}
	}
	const char *q = *p + 1;
	if (*q++ != '#')
		return false;
	bool hex = *q == 'x';
	q += hex;
	const char *digits = q;
	while (hex ? isxdigit((unsigned char)*q) : isdigit((unsigned char)*q))
		q++;
	if (q == digits || *q != ';')
		return false;
	*p = q + 1;
	return true;
}

/* False with the reason and offset in @why when @s is not well-formed XML with an <svg> root. */
static bool xml_ok(const char *s, char *why, size_t len)
{
	char stack[64][48];
	int depth = 0, roots = 0;
	const char *p = s;
#define XML_FAIL(msg) \
	do { \
		snprintf(why, len, "offset %ld: %s", (long)(p - s), msg); \
		return false; \
	} while (0)
	while (*p) {
		if (*p != '<') {
			if (*p == '&') {
				if (!entity(&p))
					XML_FAIL("bad entity");
				if (!depth)
					XML_FAIL("entity outside the root");
				continue;
			}
			if (*p == '>' && p > s && p[-1] == ']')
				XML_FAIL("']>' in text");
			if (!depth && !isspace((unsigned char)*p))
				XML_FAIL("text outside the root");
			p++;
			continue;
		}
		if (strncmp(p, "<?", 2) == 0) {
			if (p != s)
				XML_FAIL("declaration not at the start");
			const char *q = strstr(p, "?>");
			if (!q)
				XML_FAIL("unterminated declaration");
			p = q + 2;
			continue;
		}
		if (strncmp(p, "<!--", 4) == 0) {
			const char *q = strstr(p + 4, "-->");
			if (!q)
				XML_FAIL("unterminated comment");
			p = q + 3;
			continue;
		}
		bool close = p[1] == '/';
		const char *n = p + 1 + close, *e = n;
		if (!name_start((unsigned char)*e))
			XML_FAIL("bad tag name");
		while (name_char((unsigned char)*e))
			e++;
		if ((size_t)(e - n) >= sizeof(stack[0]))
			XML_FAIL("tag name too long");
		char name[48];
		memcpy(name, n, (size_t)(e - n));
		name[e - n] = '\0';
		p = e;
		if (close) {
			while (isspace((unsigned char)*p))
				p++;
			if (*p != '>')
				XML_FAIL("bad end tag");
			if (!depth || strcmp(stack[depth - 1], name) != 0)
				XML_FAIL("end tag does not match");
			depth--;
			p++;
			continue;
		}
		if (!depth && roots++)
			XML_FAIL("a second root element");
		if (!depth && strcmp(name, "svg") != 0)
			XML_FAIL("the root is not <svg>");
		char seen[32][48];
		int nseen = 0;
		for (;;) {
			bool space = isspace((unsigned char)*p);
			while (isspace((unsigned char)*p))
				p++;
			if (p[0] == '/' && p[1] == '>') {
				p += 2;
				break;
			}
			if (*p == '>') {
				if (depth == 64)
					XML_FAIL("too deep");
				strcpy(stack[depth++], name);
				p++;
				break;
			}
			if (!space || !name_start((unsigned char)*p))
				XML_FAIL("bad attribute");
			const char *a = p;
			while (name_char((unsigned char)*p))
				p++;
			if (p - a >= 48 || nseen == 32)
				XML_FAIL("attribute name too long or too many");
			memcpy(seen[nseen], a, (size_t)(p - a));
			seen[nseen][p - a] = '\0';
			for (int i = 0; i < nseen; i++)
				if (strcmp(seen[i], seen[nseen]) == 0)
					XML_FAIL("duplicate attribute");
			nseen++;
			while (isspace((unsigned char)*p))
				p++;
			if (*p++ != '=')
				XML_FAIL("attribute without '='");
			while (isspace((unsigned char)*p))
				p++;
			char q = *p++;
			if (q != '"' && q != '\'')
				XML_FAIL("unquoted attribute");
			while (*p != q) {
				if (!*p || *p == '<')
					XML_FAIL("bad attribute value");
				if (*p == '&') {
					if (!entity(&p))
						XML_FAIL("bad entity in attribute");
				} else {
					p++;
				}
			}
			p++;
		}
	}
	if (depth)
		XML_FAIL("unclosed element");
	if (roots != 1)
		XML_FAIL("no root element");
#undef XML_FAIL
	return true;
}

/* ---- reading the SVG ---- */

/* The number in attribute @name of the tag that starts at @tag. */
static bool attr(const char *tag, const char *name, double *v)
{
	const char *end = strchr(tag, '>');
	char key[64];
	snprintf(key, sizeof(key), " %s=\"", name);
	const char *a = strstr(tag, key);
	if (!a || !end || a > end)
		return false;
	char *e;
	*v = strtod(a + strlen(key), &e);
	return *e == '"';
}

struct area {
	double x, y, w, h;
};

static bool plot_area(const char *svg, struct area *a)
{
	const char *c = strstr(svg, "class=\"plot-area\"");
	if (!c)
		return false;
	while (c > svg && *c != '<')
		c--;
	return attr(c, "x", &a->x) && attr(c, "y", &a->y) && attr(c, "width", &a->w) &&
	       attr(c, "height", &a->h);
}

/* Whether a <circle> is centred on (@x, @y) within @tol, between @from and @to. */
static bool circle_at(const char *from, const char *to, double x, double y, double tol)
{
	for (const char *c = from; (c = strstr(c, "<circle ")) && (!to || c < to); c++) {
		double cx, cy;
		if (attr(c, "cx", &cx) && attr(c, "cy", &cy) && fabs(cx - x) <= tol &&
		    fabs(cy - y) <= tol)
			return true;
	}
	return false;
}

static size_t count(const char *from, const char *to, const char *what)
{
	size_t n = 0;
	for (const char *c = from; (c = strstr(c, what)) && (!to || c < to); c++)
		n++;
	return n;
}

/* The text of a <text> element, exactly: ">TEXT</text>". */
static bool has_text(const char *svg, const char *text)
{
	char key[256];
	snprintf(key, sizeof(key), ">%s</text>", text);
	return strstr(svg, key) != NULL;
}

static bool has_nonnumber(const char *svg)
{
	for (const char *p = svg; *p; p++)
		if (strncasecmp(p, "nan", 3) == 0 || strncasecmp(p, "inf", 3) == 0)
			return true;
	return false;
}

/* Read @path and check it as every SVG must be; NULL (a failed check) if it is not. */
static char *read_svg(const char *path)
{
	char *svg = slurp(path, NULL);
	CHECK(svg != NULL);
	if (!svg)
		return NULL;
	char why[128] = "";
	bool ok = xml_ok(svg, why, sizeof(why));
	CHECK(ok);
	if (!ok)
		fprintf(stderr, "%s: not well-formed: %s\n", path, why);
	CHECK(!has_nonnumber(svg));
	return svg;
}

/* ---- the checker itself must catch what it is there for ---- */

static void test_checker(void)
{
	char why[128];
	CHECK(xml_ok("<?xml version=\"1.0\"?>\n<svg a=\"1\"><g><text>a &amp; b</text></g>"
		     "<rect x='2'/></svg>\n", why, sizeof(why)));
	CHECK(!xml_ok("<svg><g></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg><text>a & b</text></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg><text>a < b</text></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg x=\"a<b\"></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg x=1></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg x=\"1\" x=\"2\"></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<svg></svg><svg></svg>", why, sizeof(why)));
	CHECK(!xml_ok("<html></html>", why, sizeof(why)));
	CHECK(!xml_ok("<svg>", why, sizeof(why)));
	CHECK(has_nonnumber("<svg x=\"NaN\"/>") && has_nonnumber("-inf"));
}

/* ---- line plots ---- */

static void test_lines_linear(void)
{
	const char *path = in_dir("lines.svg");
	double x[3] = { 0, 5, 10 }, y[3] = { 0, 50, 100 };
	double x2[3] = { 2, 4, 6 }, y2[3] = { 10, 20, 30 };
	static const char *const plabels[3] = { "p0", NULL, "p<2>" };
	struct plot_series s[2] = {
		{ .label = "a<b&c", .x = x, .y = y, .n = 3, .color = -1, .point_labels = plabels },
		{ .label = "second", .x = x2, .y = y2, .n = 3, .dashed = true, .color = -1 },
	};
	struct plot_opts o = { .title = "Speed & \"error\"", .xlabel = "time (ms)",
			       .ylabel = "error (%)" };
	char err[256] = "";
	CHECK(plot_lines_svg(path, &o, s, 2, err, sizeof(err)));
	char *svg = read_svg(path);
	if (!svg)
		return;
	CHECK(strstr(svg, "width=\"720\" height=\"440\"") != NULL);
	struct area a;
	CHECK(plot_area(svg, &a));
	/* x runs 0..10 and y 0..100 (ticks of 2 and 20): the points are at the centre and corners. */
	CHECK(circle_at(svg, NULL, a.x + a.w / 2.0, a.y + a.h / 2.0, 0.011));
	CHECK(circle_at(svg, NULL, a.x, a.y + a.h, 0.011));
	CHECK(circle_at(svg, NULL, a.x + a.w, a.y, 0.011));
	CHECK(has_text(svg, "0") && has_text(svg, "10") && has_text(svg, "100"));
	CHECK(has_text(svg, "20") && has_text(svg, "80"));
	CHECK(strstr(svg, "a&lt;b&amp;c") != NULL && strstr(svg, "a<b") == NULL);
	CHECK(strstr(svg, "Speed &amp; &quot;error&quot;") != NULL);
	CHECK(has_text(svg, "p0") && has_text(svg, "p&lt;2&gt;"));
	CHECK(has_text(svg, "time (ms)") && has_text(svg, "error (%)"));
	CHECK(count(svg, NULL, "stroke-dasharray") == 2); /* the series and its legend swatch */
	/* Two series' colours, the first two of the palette. */
	CHECK(strstr(svg, "stroke=\"#0072B2\"") && strstr(svg, "stroke=\"#D55E00\""));
	/* The legend lies right of the plot area, not over the data. */
	const char *lg = strstr(svg, "<g class=\"legend\"");
	CHECK(lg != NULL);
	if (lg) {
		const char *t = strstr(lg, "<text ");
		double tx;
		CHECK(t && attr(t, "x", &tx) && tx > a.x + a.w);
	}
	/* Nothing noted: every point was drawn. */
	CHECK(strstr(svg, "not drawn") == NULL);
	/* The line of series 0 goes through its three points. */
	const char *d = strstr(svg, "<path class=\"series\"");
	CHECK(d && strstr(d, " d=\"M") != NULL);
	free(svg);

	/* A size of our own; a constant series (one y value) still gets an axis. */
	double cy[2] = { 7, 7 };
	struct plot_series c = { .label = NULL, .x = x, .y = cy, .n = 2, .color = 3 };
	struct plot_opts small = { .width = 400, .height = 300 };
	CHECK(plot_lines_svg(path, &small, &c, 1, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(strstr(svg, "width=\"400\" height=\"300\"") != NULL);
		CHECK(strstr(svg, "#CC79A7") != NULL);        /* colour index 3 */
		CHECK(strstr(svg, "class=\"legend\"") == NULL); /* no label, no legend */
		CHECK(plot_area(svg, &a));
		/*
		 * y spans 6.3..7.7; the area is 254 pixels high, so about 5 ticks:
		 * a step of 0.5 from 6 to 8, with 7 in the middle.
		 */
		CHECK(circle_at(svg, NULL, a.x, a.y + a.h / 2.0, 0.011));
		CHECK_NEAR(a.h, 254.0, 0.0);
		CHECK(has_text(svg, "6") && has_text(svg, "6.5") && has_text(svg, "8"));
		free(svg);
	}
	/* No options at all. */
	CHECK(plot_lines_svg(path, NULL, &c, 1, err, sizeof(err)));
}

static void test_lines_log(void)
{
	const char *path = in_dir("log.svg");
	double x[3] = { 1, 10, 1000 }, y[3] = { 0.01, 1, 100 };
	struct plot_series s = { .label = "log", .x = x, .y = y, .n = 3, .color = -1 };
	struct plot_opts o = { .xlog = true, .ylog = true };
	char err[256] = "";
	CHECK(plot_lines_svg(path, &o, &s, 1, err, sizeof(err)));
	char *svg = read_svg(path);
	if (!svg)
		return;
	struct area a;
	CHECK(plot_area(svg, &a));
	/* x: decades 0..3, 10 a third of the way; y: decades -2..2, 1 in the middle. */
	CHECK(circle_at(svg, NULL, a.x + a.w / 3.0, a.y + a.h / 2.0, 0.011));
	CHECK(circle_at(svg, NULL, a.x + a.w, a.y, 0.011));
	for (int i = 0; i < 5; i++) {
		static const char *const dec[] = { "0.01", "0.1", "1", "10", "100" };
		CHECK(has_text(svg, dec[i]));
	}
	CHECK(has_text(svg, "1000"));
	/* Ticks: x 4 decades + 3 x 2 minor (2, 5), y 5 decades + 4 x 2 minor. */
	const char *t0 = strstr(svg, "<g class=\"ticks\""), *t1 = t0 ? strstr(t0, "</g>") : NULL;
	CHECK(t0 && t1 && count(t0, t1, "<line ") == 4 + 6 + 5 + 8);
	/* Minor ticks are not labelled when an axis spans several decades. */
	CHECK(!has_text(svg, "2") && !has_text(svg, "50"));
	free(svg);

	/* Ten decades: labels switch to exponents outside 0.001..1000. */
	double wx[2] = { 1, 2 }, wy[2] = { 1e-5, 1e5 };
	struct plot_series w = { .label = "wide", .x = wx, .y = wy, .n = 2, .color = -1 };
	struct plot_opts wo = { .ylog = true };
	CHECK(plot_lines_svg(path, &wo, &w, 1, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(has_text(svg, "1e-05") && has_text(svg, "1e-04") && has_text(svg, "0.001"));
		CHECK(has_text(svg, "1000") && has_text(svg, "1e+04") && has_text(svg, "1e+05"));
		CHECK(plot_area(svg, &a));
		CHECK(circle_at(svg, NULL, a.x, a.y + a.h, 0.011));
		free(svg);
	}

	/* One decade: the minor ticks are labelled too. */
	double oy[2] = { 12, 80 };
	struct plot_series one = { .label = "one", .x = wx, .y = oy, .n = 2, .color = -1 };
	CHECK(plot_lines_svg(path, &wo, &one, 1, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(has_text(svg, "10") && has_text(svg, "20") && has_text(svg, "50") &&
		      has_text(svg, "100"));
		free(svg);
	}
}

static void test_lines_skipped(void)
{
	const char *path = in_dir("skip.svg");
	double x[5] = { 1, 2, 3, 4, 5 }, y[5] = { 1, NAN, INFINITY, -1, 4 };
	struct plot_series s = { .label = "ok", .x = x, .y = y, .n = 5, .color = -1 };
	struct plot_opts o = { .ylog = true };
	char err[256] = "";
	CHECK(plot_lines_svg(path, &o, &s, 1, err, sizeof(err)));
	char *svg = read_svg(path);
	if (!svg)
		return;
	CHECK(strstr(svg, ">3 points not drawn (not finite, or not positive on a log axis)<") !=
	      NULL);
	/* Two markers and one in the legend; the line breaks at the gap. */
	CHECK(count(svg, NULL, "<circle ") == 3);
	const char *d = strstr(svg, "<path class=\"series\"");
	const char *dend = d ? strstr(d, "/>") : NULL;
	CHECK(d && dend && count(d, dend, "M") == 2 && count(d, dend, "L") == 0);
	free(svg);

	/* On linear axes -1 is drawn; the others are not. */
	o.ylog = false;
	x[0] = NAN;
	CHECK(plot_lines_svg(path, &o, &s, 1, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(strstr(svg, ">3 points not drawn (not finite)<") != NULL);
		CHECK(count(svg, NULL, "<circle ") == 3);
		free(svg);
	}
}

static void test_lines_refused(void)
{
	const char *path = in_dir("refused.svg");
	double x[2] = { 1, 2 }, y[2] = { 3, 4 }, bad[2] = { NAN, -INFINITY };
	struct plot_series good = { .label = "g", .x = x, .y = y, .n = 2, .color = -1 };
	struct plot_series s = { .label = "nan", .x = x, .y = bad, .n = 2, .color = -1 };
	char err[256] = "";
	/* Nothing drawable: refused, no file. */
	CHECK(!plot_lines_svg(path, NULL, &s, 1, err, sizeof(err)));
	CHECK(strstr(err, "nothing to draw") != NULL && strstr(err, path) != NULL);
	CHECK(!exists(path));
	CHECK(!plot_lines_svg(path, NULL, &s, 0, err, sizeof(err)));
	CHECK(!exists(path));
	/* On a log axis, negative values are not drawable either. */
	double neg[2] = { -1, 0 };
	struct plot_series n = { .label = "neg", .x = x, .y = neg, .n = 2, .color = -1 };
	struct plot_opts lo = { .ylog = true };
	CHECK(!plot_lines_svg(path, &lo, &n, 1, err, sizeof(err)));
	CHECK(strstr(err, "nothing to draw") != NULL);

	/* A refusal leaves the old file as it was. */
	CHECK(plot_lines_svg(path, NULL, &good, 1, err, sizeof(err)));
	size_t before_len = 0, after_len = 0;
	char *before = slurp(path, &before_len);
	CHECK(!plot_lines_svg(path, NULL, &s, 1, err, sizeof(err)));
	char *after = slurp(path, &after_len);
	CHECK(before && after && before_len == after_len && memcmp(before, after, before_len) == 0);
	free(before);
	free(after);

	/* Bad arguments. */
	struct plot_opts tiny = { .width = 100, .height = 100 };
	CHECK(!plot_lines_svg(path, &tiny, &good, 1, err, sizeof(err)));
	CHECK(strstr(err, "100 x 100") != NULL);
	struct plot_opts neg_size = { .width = -5 };
	CHECK(!plot_lines_svg(path, &neg_size, &good, 1, err, sizeof(err)));
	CHECK(!plot_lines_svg(NULL, NULL, &good, 1, err, sizeof(err)));
	CHECK(!plot_lines_svg("", NULL, &good, 1, err, sizeof(err)));
	struct plot_series novalues = { .label = "x", .n = 3 };
	CHECK(!plot_lines_svg(path, NULL, &novalues, 1, err, sizeof(err)));
	const char *nodir = in_dir("no/such/dir.svg");
	CHECK(!plot_lines_svg(nodir, NULL, &good, 1, err, sizeof(err)));
	CHECK(strstr(err, "no/such/dir.svg") != NULL);
	/* A value range too wide to subdivide. */
	double huge[2] = { -1.7e308, 1.7e308 };
	struct plot_series h = { .label = "h", .x = x, .y = huge, .n = 2, .color = -1 };
	CHECK(!plot_lines_svg(path, NULL, &h, 1, err, sizeof(err)));
	CHECK(strstr(err, "range") != NULL);
}

static void test_lines_legend(void)
{
	/* Many series with long names: the legend moves under the plot, colours cycle. */
	enum { NS = 10 };
	const char *path = in_dir("legend.svg");
	double x[2] = { 1, 2 }, y[NS][2];
	char names[NS][80];
	struct plot_series s[NS];
	for (int k = 0; k < NS; k++) {
		y[k][0] = k;
		y[k][1] = k + 1;
		snprintf(names[k], sizeof(names[k]), "series %d with a rather long name \xc3\xa9\x01"
			 "\xff", k);
		s[k] = (struct plot_series){ .label = names[k], .x = x, .y = y[k], .n = 2,
					     .color = -1 };
	}
	char err[256] = "";
	CHECK(plot_lines_svg(path, NULL, s, NS, err, sizeof(err)));
	char *svg = read_svg(path);
	if (!svg)
		return;
	struct area a;
	CHECK(plot_area(svg, &a));
	const char *lg = strstr(svg, "<g class=\"legend\"");
	CHECK(lg != NULL);
	if (lg) {
		const char *t = strstr(lg, "<text ");
		double ty;
		CHECK(t && attr(t, "y", &ty) && ty > a.y + a.h);
		/* Ten long entries do not fit one row: they wrap, each starting inside the picture. */
		const char *end = strstr(lg, "</g>");
		double first_y = -1.0, tx;
		int rows = 0, entries = 0;
		for (t = lg; (t = strstr(t, "<text ")) && t < end; t++, entries++) {
			CHECK(attr(t, "x", &tx) && attr(t, "y", &ty) && tx >= a.x && tx < 720.0 - 100.0);
			if (ty != first_y)
				rows++;
			first_y = ty;
		}
		CHECK(entries == NS && rows >= 3 && rows < NS);
	}
	/* UTF-8 kept; a control character and a stray byte replaced by U+FFFD. */
	CHECK(strstr(svg, "name \xc3\xa9\xef\xbf\xbd\xef\xbf\xbd<") != NULL);
	/* Series 8 takes the first colour again. */
	CHECK(count(svg, NULL, "stroke=\"#0072B2\"") == 4);
	free(svg);
}

static void test_lines_extremes(void)
{
	/*
	 * Awkward ranges, linear and log: each is drawn as valid SVG without a
	 * non-finite number in it, or refused with a message; never a crash.
	 */
	static const double ranges[][2] = {
		{ 1e9, 1e9 + 1e-3 }, { -1e-300, 1e-300 }, { 5e-324, 1e-323 }, { 0, 0 },
		{ -3, -3 }, { 1e-300, 1e300 }, { 1e300, 1.7e308 }, { -1e308, 1e308 },
		{ 0.1, 0.3 }, { 123456789, 987654321 }, { 1, 1 + 1e-15 }, { 0.999999, 1.000001 },
	};
	const char *path = in_dir("extreme.svg");
	char err[256];
	int drawn = 0;
	for (size_t i = 0; i < sizeof(ranges) / sizeof(ranges[0]); i++) {
		for (int log = 0; log < 2; log++) {
			double x[3] = { ranges[i][0], (ranges[i][0] + ranges[i][1]) / 2, ranges[i][1] };
			struct plot_series s = { .label = "x", .x = x, .y = x, .n = 3, .color = -1 };
			struct plot_opts o = { .xlog = log, .ylog = log };
			unlink(path);
			err[0] = '\0';
			if (plot_lines_svg(path, &o, &s, 1, err, sizeof(err))) {
				char *svg = read_svg(path);
				drawn++;
				free(svg);
			} else {
				CHECK(err[0] != '\0' && !exists(path));
			}
		}
	}
	/* Most of them are drawable. */
	CHECK(drawn >= 16);
}

/* ---- bar charts ---- */

/* The <rect>s of the bars group, in order: @n of them at most. */
static size_t bars(const char *svg, struct area *r, size_t n)
{
	const char *g = strstr(svg, "<g class=\"bars\">"), *end = g ? strstr(g, "</g>") : NULL;
	size_t k = 0;
	for (const char *c = g; c && (c = strstr(c, "<rect ")) && c < end && k < n; c++, k++)
		if (!attr(c, "x", &r[k].x) || !attr(c, "y", &r[k].y) ||
		    !attr(c, "width", &r[k].w) || !attr(c, "height", &r[k].h))
			return 0;
	return k;
}

static void test_bars(void)
{
	const char *path = in_dir("bars.svg");
	static const char *const groups[2] = { "scene A", "scene <B>" };
	static const char *const series[2] = { "cpu", "gpu & co" };
	double values[4] = { 12.5, 0.75, 3, NAN };
	struct plot_opts o = { .title = "Frame time", .ylabel = "ms" };
	char err[256] = "";
	CHECK(plot_bars_svg(path, &o, groups, 2, series, 2, values, err, sizeof(err)));
	char *svg = read_svg(path);
	if (!svg)
		return;
	CHECK(has_text(svg, "12.5") && has_text(svg, "0.75") && has_text(svg, "3"));
	CHECK(has_text(svg, "scene A") && has_text(svg, "scene &lt;B&gt;"));
	CHECK(has_text(svg, "gpu &amp; co"));
	CHECK(strstr(svg, ">1 bar not drawn (not finite)<") != NULL);
	struct area a, r[4];
	CHECK(plot_area(svg, &a));
	CHECK(bars(svg, r, 4) == 3);
	/* Heights in proportion to the values, all standing on the area's bottom. */
	CHECK_NEAR(r[0].h / r[2].h, 12.5 / 3.0, 0.01);
	CHECK_NEAR(r[1].h / r[2].h, 0.75 / 3.0, 0.01);
	for (int i = 0; i < 3; i++)
		CHECK_NEAR(r[i].y + r[i].h, a.y + a.h, 0.011);
	/* Group 0's bars left of group 1's, inside the area; the tallest's label fits above it. */
	CHECK(r[0].x >= a.x && r[1].x > r[0].x && r[2].x > r[1].x && r[2].x + r[2].w <= a.x + a.w);
	CHECK(r[0].y > a.y + 11.0);
	CHECK(strstr(svg, "fill=\"#0072B2\"") && strstr(svg, "fill=\"#D55E00\""));
	free(svg);

	/* Labels to 3 significant digits; a zero left out on a log axis. */
	double v2[4] = { 1234.5, 0.012345, 2.5e6, 0 };
	struct plot_opts lo = { .ylog = true };
	CHECK(plot_bars_svg(path, &lo, groups, 1, NULL, 4, v2, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(has_text(svg, "1230") && has_text(svg, "0.0123") && has_text(svg, "2.5e+06"));
		CHECK(strstr(svg, ">1 bar not drawn (not finite, or not positive on a log axis)<"));
		CHECK(has_text(svg, "1e+07") && has_text(svg, "0.01"));
		free(svg);
	}

	/* Many narrow bars: value labels upright, long group labels slanted; still valid. */
	enum { G = 12, S = 3 };
	const char *gl[G];
	double v3[G * S];
	for (int i = 0; i < G; i++)
		gl[i] = "a long scene name";
	for (int i = 0; i < G * S; i++)
		v3[i] = 1000.0 + i * 37.7;
	CHECK(plot_bars_svg(path, NULL, gl, G, NULL, S, v3, err, sizeof(err)));
	svg = read_svg(path);
	if (svg) {
		CHECK(count(svg, NULL, "rotate(-90") == G * S);
		CHECK(count(svg, NULL, "rotate(-35") == G);
		CHECK(strstr(svg, "class=\"legend\"") == NULL);
		free(svg);
	}

	/* Refusals. */
	double nothing[2] = { NAN, -1 };
	CHECK(!plot_bars_svg(path, NULL, groups, 1, series, 2, nothing, err, sizeof(err)));
	CHECK(strstr(err, "nothing to draw") != NULL);
	double zeros[2] = { 0, 0 };
	CHECK(!plot_bars_svg(path, &lo, groups, 1, series, 2, zeros, err, sizeof(err)));
	CHECK(plot_bars_svg(path, NULL, groups, 1, series, 2, zeros, err, sizeof(err)));
	CHECK(!plot_bars_svg(path, NULL, groups, 0, series, 2, values, err, sizeof(err)));
	CHECK(!plot_bars_svg(path, NULL, groups, 1, series, 0, values, err, sizeof(err)));
	CHECK(!plot_bars_svg(path, NULL, groups, 1, series, 2, NULL, err, sizeof(err)));
}

/* ---- heat maps ---- */

static uint32_t be32(const uint8_t *p)
{
	return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* An 8-bit RGB PNG read back: chunks and CRCs checked, IDAT inflated, filter 0 only. */
static uint8_t *read_png(const char *path, uint32_t *w, uint32_t *h)
{
	static const uint8_t sig[8] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n' };
	size_t size;
	uint8_t *buf = (uint8_t *)slurp(path, &size), *z = NULL, *raw = NULL, *px = NULL;
	size_t zlen = 0;
	*w = *h = 0;
	if (!buf || size < 8 || memcmp(buf, sig, 8) != 0)
		goto done;
	for (size_t pos = 8; pos + 12 <= size;) {
		uint32_t len = be32(buf + pos);
		const uint8_t *type = buf + pos + 4, *data = buf + pos + 8;
		if (len > size - pos - 12)
			goto done;
		if ((uint32_t)crc32(crc32(0L, Z_NULL, 0), type, 4 + len) != be32(data + len))
			goto done;
		if (memcmp(type, "IHDR", 4) == 0) {
			*w = be32(data);
			*h = be32(data + 4);
			if (len != 13 || data[8] != 8 || data[9] != 2)
				goto done;
		} else if (memcmp(type, "IDAT", 4) == 0) {
			uint8_t *nz = realloc(z, zlen + len);
			if (!nz)
				goto done;
			z = nz;
			memcpy(z + zlen, data, len);
			zlen += len;
		}
		pos += 12 + (size_t)len;
	}
	if (!*w || !*h || !z)
		goto done;
	uLongf rawlen = (uLongf)*h * (1 + 3 * (uLongf)*w);
	raw = malloc(rawlen);
	px = malloc((size_t)*w * *h * 3);
	if (!raw || !px || uncompress(raw, &rawlen, z, zlen) != Z_OK ||
	    rawlen != (uLongf)*h * (1 + 3 * (uLongf)*w)) {
		free(px);
		px = NULL;
		goto done;
	}
	for (uint32_t y = 0; y < *h; y++) {
		const uint8_t *row = raw + (size_t)y * (1 + 3 * (size_t)*w);
		if (row[0] != 0) {
			free(px);
			px = NULL;
			goto done;
		}
		memcpy(px + (size_t)y * *w * 3, row + 1, (size_t)*w * 3);
	}
done:
	free(buf);
	free(z);
	free(raw);
	return px;
}

static bool rgb_is(const uint8_t *px, uint32_t w, uint32_t x, uint32_t y, int r, int g, int b)
{
	const uint8_t *p = px + 3 * ((size_t)y * w + x);
	if (p[0] == r && p[1] == g && p[2] == b)
		return true;
	fprintf(stderr, "pixel (%u, %u) is (%d, %d, %d), expected (%d, %d, %d)\n", x, y, p[0],
		p[1], p[2], r, g, b);
	return false;
}

static void test_ramp(void)
{
	uint8_t c[3];
	static const struct {
		double v;
		uint8_t rgb[3];
	} cases[] = {
		{ 0.0, { 0, 0, 0 } },
		{ 0.2, { 0, 0, 255 } },
		{ 0.4, { 0, 255, 0 } },
		{ 0.6, { 255, 255, 0 } },
		{ 0.8, { 255, 0, 0 } },
		{ 1.0, { 255, 255, 255 } },
		{ 2.0, { 255, 255, 255 } },
		{ -1.0, { 0, 0, 0 } },
		{ NAN, { 0, 0, 0 } },
		{ INFINITY, { 255, 255, 255 } },
		/* Half-way from green to yellow: 127.5 rounds to even, 128. */
		{ 0.5, { 128, 255, 0 } },
		/* relight diff's test: 19.825825 % on a 100 % scale is blue 253. */
		{ 0.19825825, { 0, 0, 253 } },
		{ 0.9, { 255, 128, 128 } },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		plot_ramp(cases[i].v, c);
		CHECK(memcmp(c, cases[i].rgb, 3) == 0);
		if (memcmp(c, cases[i].rgb, 3) != 0)
			fprintf(stderr, "plot_ramp(%g) = (%d, %d, %d)\n", cases[i].v, c[0], c[1], c[2]);
	}
}

static void test_heatmap(void)
{
	/* Two 8 x 6 maps shrunk by 2: 4 x 3 each, a gap of 4: 12 x (3 + 4 + 12). */
	enum { W = 8, H = 6 };
	float m0[W * H] = { 0 }, m1[W * H];
	for (int i = 0; i < W * H; i++)
		m1[i] = 1.0f;          /* 1 % of a 5 % scale: blue */
	m0[2 * W + 5] = 3.0f;          /* (5, 2): block (2, 1), 3/5 of the scale: yellow */
	m0[5 * W + 7] = 0.5f;          /* (7, 5): block (3, 2), a tenth: half-way to blue */
	m1[5 * W + 0] = NAN;           /* (0, 5): block (0, 2) of map 1: magenta */
	m1[0] = 50.0f;                 /* (0, 0): far above the scale: white */
	const float *maps[2] = { m0, m1 };
	const char *path = in_dir("heat.png");
	char err[256] = "";
	CHECK(plot_heatmap_png(path, maps, 2, W, H, 2, 5.0, err, sizeof(err)));
	uint32_t w, h;
	uint8_t *px = read_png(path, &w, &h);
	CHECK(px != NULL);
	if (!px)
		return;
	CHECK(w == 4 + PLOT_HEATMAP_GAP + 4 && h == 3 + PLOT_HEATMAP_GAP + PLOT_HEATMAP_BAR);
	CHECK(w == 12 && h == 19);
	if (w == 12 && h == 19) {
		CHECK(rgb_is(px, w, 2, 1, 255, 255, 0));
		CHECK(rgb_is(px, w, 3, 2, 0, 0, 128));
		CHECK(rgb_is(px, w, 0, 0, 0, 0, 0));
		CHECK(rgb_is(px, w, 3, 1, 0, 0, 0));
		CHECK(rgb_is(px, w, 2, 2, 0, 0, 0));
		/* The gap. */
		CHECK(rgb_is(px, w, 4, 0, 128, 128, 128) && rgb_is(px, w, 7, 2, 128, 128, 128));
		CHECK(rgb_is(px, w, 0, 3, 128, 128, 128) && rgb_is(px, w, 11, 6, 128, 128, 128));
		/* Map 1 starts at x = 8. */
		CHECK(rgb_is(px, w, 8, 0, 255, 255, 255));
		CHECK(rgb_is(px, w, 8, 2, 255, 0, 255));
		CHECK(rgb_is(px, w, 9, 0, 0, 0, 255) && rgb_is(px, w, 11, 2, 0, 0, 255));
		/* The colour bar: the ramp from black at the left to white at the right. */
		for (uint32_t y = 7; y < 19; y++)
			CHECK(rgb_is(px, w, 0, y, 0, 0, 0) && rgb_is(px, w, 11, y, 255, 255, 255));
		uint8_t mid[3];
		plot_ramp(6.0 / 11.0, mid);
		CHECK(rgb_is(px, w, 6, 10, mid[0], mid[1], mid[2]));
	}
	free(px);

	/* No shrink, one map of one row: a single bad pixel at its own place. */
	float row[5] = { 0, 0, 0, 5, 0 };
	const float *one[1] = { row };
	CHECK(plot_heatmap_png(path, one, 1, 5, 1, 1, 5.0, err, sizeof(err)));
	px = read_png(path, &w, &h);
	CHECK(px && w == 5 && h == 1 + PLOT_HEATMAP_GAP + PLOT_HEATMAP_BAR);
	if (px && w == 5 && h == 17)
		CHECK(rgb_is(px, w, 3, 0, 255, 255, 255) && rgb_is(px, w, 2, 0, 0, 0, 0));
	free(px);

	/* A shrink that does not divide the size: partial blocks at the edges. */
	float odd[7 * 5] = { 0 };
	odd[4 * 7 + 6] = 2.0f; /* the last pixel: in the partial block (2, 1) */
	const float *oddm[1] = { odd };
	CHECK(plot_heatmap_png(path, oddm, 1, 7, 5, 3, 5.0, err, sizeof(err)));
	px = read_png(path, &w, &h);
	CHECK(px && w == 3 && h == 2 + PLOT_HEATMAP_GAP + PLOT_HEATMAP_BAR);
	if (px && w == 3 && h == 18)
		CHECK(rgb_is(px, w, 2, 1, 0, 255, 0) && rgb_is(px, w, 2, 0, 0, 0, 0));
	free(px);

	/* Refusals, and an old file left alone by them. */
	size_t before_len = 0, after_len = 0;
	char *before = slurp(path, &before_len);
	CHECK(!plot_heatmap_png(path, maps, 2, W, H, 2, 0.0, err, sizeof(err)));
	CHECK(strstr(err, "scale") != NULL);
	CHECK(!plot_heatmap_png(path, maps, 2, W, H, 2, NAN, err, sizeof(err)));
	CHECK(!plot_heatmap_png(path, maps, 2, W, H, 2, INFINITY, err, sizeof(err)));
	CHECK(!plot_heatmap_png(path, maps, 2, W, H, 0, 5.0, err, sizeof(err)));
	CHECK(!plot_heatmap_png(path, maps, 0, W, H, 2, 5.0, err, sizeof(err)));
	CHECK(!plot_heatmap_png(path, maps, 2, 0, H, 2, 5.0, err, sizeof(err)));
	CHECK(!plot_heatmap_png(path, NULL, 2, W, H, 2, 5.0, err, sizeof(err)));
	const float *holes[2] = { m0, NULL };
	CHECK(!plot_heatmap_png(path, holes, 2, W, H, 2, 5.0, err, sizeof(err)));
	CHECK(strstr(err, "heat map 1") != NULL);
	CHECK(!plot_heatmap_png(path, maps, 2, 100000, 100000, 1, 5.0, err, sizeof(err)));
	CHECK(strstr(err, "too large") != NULL);
	char *after = slurp(path, &after_len);
	CHECK(before && after && before_len == after_len && memcmp(before, after, before_len) == 0);
	free(before);
	free(after);
	const char *nodir = in_dir("no/such/heat.png");
	CHECK(!plot_heatmap_png(nodir, maps, 2, W, H, 2, 5.0, err, sizeof(err)));
	CHECK(strstr(err, "no/such/heat.png") != NULL && strchr(err, '\n') == NULL);
}

int main(void)
{
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	RUN(test_checker);
	RUN(test_lines_linear);
	RUN(test_lines_log);
	RUN(test_lines_skipped);
	RUN(test_lines_refused);
	RUN(test_lines_legend);
	RUN(test_lines_extremes);
	RUN(test_bars);
	RUN(test_ramp);
	RUN(test_heatmap);

	/* Clean up: every file written, then the directory. */
	DIR *d = opendir(dir);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		if (e->d_name[0] == '.')
			continue;
		unlink(in_dir(e->d_name));
	}
	if (d)
		closedir(d);
	rmdir(dir);
	return test_finish();
}

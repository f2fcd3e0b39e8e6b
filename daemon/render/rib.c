/*
 * The RIB reader. Three layers, bottom up:
 *
 *  - a byte source: a memory buffer, a FILE, or either one through zlib's
 *    inflate when the data starts with the gzip magic bytes (1f 8b);
 *  - a tokenizer: numbers, "strings", [ and ], bare words, # comments;
 *  - a request parser driven by one table (reqdefs[]) that lists every
 *    request with its positional arguments and whether a parameter list
 *    follows.
 *
 * A request's values are gathered in growable arrays owned by the reader and
 * reused from one request to the next; they are addressed by index while the
 * request is read (the arrays may move) and turned into pointers just before
 * the handler is called. After an error the reader skips tokens up to the
 * next request name and goes on.
 */
#include "rib.h"

#include "arena.h"

#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#define ZLIB_CONST
#include <zlib.h>

enum {
	CHUNK = 1 << 16,            /* raw and inflated buffer size */
	WORD_MAX = 255,             /* longest bare word or number */
	STRING_MAX = 1 << 20,       /* longest string, in bytes */
	REQ_STRING_BYTES = 1 << 26, /* string bytes in one request */
	NAME_SUGGEST_MAX = 64,      /* longer unknown names get no suggestion */
	SHRINK_ELEMS = 1 << 20,     /* free request storage above this after use */
	FEED_MAX = 1 << 30,         /* compressed bytes handed to inflate at once */
};

#define DEFAULT_MAX_ERRORS 20
#define DEFAULT_MAX_ARRAY ((size_t)64 << 20)

/* ---- the request table ---------------------------------------------------- */

enum {
	TAKES_PARAMS = 1 << 0,  /* a parameter list follows the positional arguments */
	BRACKET_OK = 1 << 1,    /* the numbers may also be written as one [ array ] */
	NONE_OK = 1 << 2,       /* the numbers may also be left out altogether */
	PRIMITIVE = 1 << 3,     /* a geometric primitive: an error in it drops it alone */
	MORE_ARRAYS = 1 << 4,   /* more [ arrays ] may follow the positional arguments
				   (SubdivisionMesh's tags): the handler checks them */
};

/*
 * A request: its canonical name, its positional arguments as a
 * space-separated list of "name:kind", and flags. Kinds:
 *   n number         i integer          s string
 *   h handle: an integer or a string
 *   a [numbers]      I [integers]       m [16 numbers]
 *   S [strings] (possibly empty)
 *   b basis: a string (a named basis) or [16 numbers]
 */
struct reqdef {
	const char *name;
	const char *args;
	unsigned flags;
};

static const struct reqdef reqdefs[] = {
	{"version", "version:n", 0},
	{"FrameBegin", "frame:i", 0},
	{"FrameEnd", "", 0},
	{"WorldBegin", "", 0},
	{"WorldEnd", "", 0},
	{"AttributeBegin", "", 0},
	{"AttributeEnd", "", 0},
	{"TransformBegin", "", 0},
	{"TransformEnd", "", 0},
	/* camera and display options */
	{"Format", "xresolution:i yresolution:i pixelaspectratio:n", 0},
	{"FrameAspectRatio", "frameaspectratio:n", 0},
	{"ScreenWindow", "left:n right:n bottom:n top:n", 0},
	{"CropWindow", "xmin:n xmax:n ymin:n ymax:n", 0},
	{"Projection", "name:s", TAKES_PARAMS},
	{"Clipping", "near:n far:n", 0},
	{"Shutter", "opentime:n closetime:n", 0},
	{"DepthOfField", "fstop:n focallength:n focaldistance:n", NONE_OK},
	{"PixelSamples", "xsamples:n ysamples:n", 0},
	{"PixelVariance", "variation:n", 0},
	{"PixelFilter", "filter:s xwidth:n ywidth:n", 0},
	{"Exposure", "gain:n gamma:n", 0},
	{"Quantize", "type:s one:i min:i max:i ditheramplitude:n", 0},
	{"Display", "name:s type:s mode:s", TAKES_PARAMS},
	{"Hider", "type:s", TAKES_PARAMS},
	{"Option", "name:s", TAKES_PARAMS},
	/* attributes */
	{"Attribute", "name:s", TAKES_PARAMS},
	{"Color", "r:n g:n b:n", BRACKET_OK},
	{"Opacity", "r:n g:n b:n", BRACKET_OK},
	{"Surface", "name:s", TAKES_PARAMS},
	{"Imager", "name:s", TAKES_PARAMS},
	{"Displacement", "name:s", TAKES_PARAMS},
	{"Atmosphere", "name:s", TAKES_PARAMS},
	{"Interior", "name:s", TAKES_PARAMS},
	{"Exterior", "name:s", TAKES_PARAMS},
	{"LightSource", "name:s light:h", TAKES_PARAMS},
	{"Illuminate", "light:h onoff:i", 0},
	{"Sides", "nsides:i", 0},
	{"Orientation", "orientation:s", 0},
	{"ReverseOrientation", "", 0},
	{"ShadingRate", "size:n", 0},
	{"ShadingInterpolation", "type:s", 0},
	{"Basis", "ubasis:b ustep:i vbasis:b vstep:i", 0},
	{"Declare", "name:s declaration:s", 0},
	{"TextureCoordinates", "s1:n t1:n s2:n t2:n s3:n t3:n s4:n t4:n", BRACKET_OK},
	{"Matte", "onoff:i", 0},
	{"Detail", "minx:n maxx:n miny:n maxy:n minz:n maxz:n", BRACKET_OK},
	{"RelativeDetail", "relativedetail:n", 0},
	{"DetailRange", "minvisible:n lowertransition:n uppertransition:n maxvisible:n",
	 BRACKET_OK},
	{"GeometricApproximation", "type:s value:n", 0},
	{"GeometricRepresentation", "type:s", 0},
	/* transformations */
	{"Identity", "", 0},
	{"Transform", "matrix:m", 0},
	{"ConcatTransform", "matrix:m", 0},
	{"Translate", "dx:n dy:n dz:n", 0},
	{"Rotate", "angle:n dx:n dy:n dz:n", 0},
	{"Scale", "sx:n sy:n sz:n", 0},
	{"Skew", "angle:n dx1:n dy1:n dz1:n dx2:n dy2:n dz2:n", BRACKET_OK},
	{"CoordinateSystem", "space:s", 0},
	{"CoordSysTransform", "space:s", 0},
	/* motion, retained geometry, archives, texture making */
	{"MotionBegin", "times:a", 0},
	{"MotionEnd", "", 0},
	{"ObjectBegin", "handle:h", 0},
	{"ObjectEnd", "", 0},
	{"SolidBegin", "operation:s", 0},
	{"SolidEnd", "", 0},
	{"ObjectInstance", "handle:h", 0},
	{"ReadArchive", "filename:s", TAKES_PARAMS},
	{"MakeTexture", "picturename:s texturename:s swrap:s twrap:s filter:s swidth:n twidth:n",
	 TAKES_PARAMS},
	{"MakeShadow", "picturename:s texturename:s", TAKES_PARAMS},
	{"MakeLatLongEnvironment", "picturename:s texturename:s filter:s swidth:n twidth:n",
	 TAKES_PARAMS},
	{"MakeCubeFaceEnvironment", "px:s nx:s py:s ny:s pz:s nz:s texturename:s fov:n filter:s "
	 "swidth:n twidth:n", TAKES_PARAMS},
	/* geometry */
	{"Sphere", "radius:n zmin:n zmax:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Cylinder", "radius:n zmin:n zmax:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Cone", "height:n radius:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Disk", "height:n radius:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Hyperboloid", "x1:n y1:n z1:n x2:n y2:n z2:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Paraboloid", "rmax:n zmin:n zmax:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Torus", "majorradius:n minorradius:n phimin:n phimax:n thetamax:n", TAKES_PARAMS | PRIMITIVE},
	{"Polygon", "", TAKES_PARAMS | PRIMITIVE},
	{"GeneralPolygon", "nvertices:I", TAKES_PARAMS | PRIMITIVE},
	{"PointsPolygons", "nvertices:I vertices:I", TAKES_PARAMS | PRIMITIVE},
	{"PointsGeneralPolygons", "nloops:I nvertices:I vertices:I", TAKES_PARAMS | PRIMITIVE},
	{"Patch", "type:s", TAKES_PARAMS | PRIMITIVE},
	{"PatchMesh", "type:s nu:i uwrap:s nv:i vwrap:s", TAKES_PARAMS | PRIMITIVE},
	{"SubdivisionMesh", "scheme:s nvertices:I vertices:I",
	 TAKES_PARAMS | PRIMITIVE | MORE_ARRAYS},
	{"NuPatch", "nu:i uorder:i uknot:a umin:n umax:n nv:i vorder:i vknot:a vmin:n vmax:n",
	 TAKES_PARAMS | PRIMITIVE},
	{"TrimCurve", "ncurves:I order:I knot:a min:a max:a n:I u:a v:a w:a", 0},
	{"Curves", "type:s nvertices:I wrap:s", TAKES_PARAMS | PRIMITIVE},
	{"Points", "", TAKES_PARAMS | PRIMITIVE},
	{"Blobby", "nleaf:i code:I floats:a strings:S", TAKES_PARAMS | PRIMITIVE},
	{"Geometry", "type:s", TAKES_PARAMS | PRIMITIVE},
	{"Procedural", "procname:s args:S bound:a", PRIMITIVE},
};

/*
 * Requests of the RenderMan Interface that this renderer does not implement:
 * the handler gets them as RIB_UNSUPPORTED (ignored with a warning), not as
 * misspelt names.
 */
static const char *const unsupported[] = {
	"AreaLightSource", "ArchiveBegin", "ArchiveEnd", "ArchiveRecord",
	"Bound", "Camera", "ClippingPlane", "ColorSamples", "Deformation",
	"DisplayChannel", "Else", "ElseIf", "ErrorHandler", "IfBegin",
	"IfEnd", "MakeBrickMap", "MakeBump", "Perspective",
	"Resource", "ResourceBegin", "ResourceEnd", "ScopedCoordinateSystem",
	"Shader", "System",
};

/* ---- diagnostics ------------------------------------------------------------ */

static void vreport(FILE *diag, struct rib_loc loc, const char *kind, const char *fmt,
		    va_list ap)
{
	if (!diag)
		diag = stderr;
	if (!fmt)
		fmt = "(no message)";
	const char *file = loc.file ? loc.file : "<rib>";
	/* one line at a time, whatever other threads print */
	flockfile(diag);
	if (loc.line)
		fprintf(diag, "%s:%u: %s: ", file, (unsigned)loc.line, kind);
	else
		fprintf(diag, "%s: %s: ", file, kind);
	vfprintf(diag, fmt, ap);
	fputc('\n', diag);
	funlockfile(diag);
}

void rib_error(FILE *diag, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vreport(diag, loc, "error", fmt, ap);
	va_end(ap);
}

void rib_warning(FILE *diag, struct rib_loc loc, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vreport(diag, loc, "warning", fmt, ap);
	va_end(ap);
}

/* ---- the reader's state ------------------------------------------------------ */

enum tok {
	T_EOF,
	T_NUM,
	T_STR,     /* text in r->str */
	T_NAME,    /* text in r->word */
	T_LBRACK,
	T_RBRACK,
	T_ERR,     /* a lexical error, already reported */
};

/* A value while its request is being read: indices instead of pointers. */
struct pvalue {
	enum rib_vtype type;
	uint32_t n;
	size_t start;   /* into nums (numbers) or strofs (strings) */
	uint32_t line;
};

struct pparam {
	size_t token;   /* into strofs */
	struct pvalue value;
	uint32_t line;
};

struct rib_reader {
	const char *file;        /* owned copy of the name, for every loc */
	FILE *diag;
	int max_errors;
	size_t max_array;
	size_t max_req_elems;
	rib_handler_fn fn;
	void *user;

	int nerrors;
	int prim_errors;         /* of nerrors, those inside primitives (not limited) */
	bool in_primitive;       /* reading a PRIMITIVE request's arguments */
	bool stop;               /* too many errors, or the handler said stop */
	bool handler_stopped;
	bool skipping;           /* after an error: lexical errors are not reported */

	/* source */
	const unsigned char *buf; /* current window of decoded bytes */
	size_t pos, len;
	FILE *fp;
	const unsigned char *mem; /* raw input of a gzip buffer */
	size_t memlen, mempos;
	bool gz, gz_member_done, raw_eof, src_failed;
	const char *zerr;        /* inflate's error, reported after the bytes before it */
	z_stream zs;
	bool zinit;
	unsigned char *inbuf, *outbuf;

	/* tokenizer */
	uint32_t line;
	bool have_tok;
	enum tok tok;
	double tok_num;
	uint32_t tok_line;
	char word[WORD_MAX + 1];
	RL_VEC(char) str;

	/* the request being read */
	uint32_t req_line;
	RL_VEC(double) nums;
	RL_VEC(char) chars;
	RL_VEC(size_t) strofs;   /* into chars */
	RL_VEC(struct pvalue) pargs;
	RL_VEC(struct pparam) pparams;
	size_t req_elems;
	/* what the handler sees */
	RL_VEC(const char *) strptrs;
	RL_VEC(struct rib_value) args;
	RL_VEC(struct rib_param) params;
};

static struct rib_loc loc_at(const struct rib_reader *r, uint32_t line)
{
	return (struct rib_loc){.file = r->file, .line = line};
}

/*
 * Reports an error unless the read already stopped or its input failed;
 * stops after max_errors (errors inside a primitive, which drop only it, are
 * not counted).
 */
static void report(struct rib_reader *r, uint32_t line, const char *fmt, va_list ap)
{
	if (r->stop || r->src_failed)
		return;
	vreport(r->diag, loc_at(r, line), "error", fmt, ap);
	r->nerrors++;
	r->prim_errors += r->in_primitive;
	if (r->nerrors - r->prim_errors >= r->max_errors) {
		r->stop = true;
		fprintf(r->diag ? r->diag : stderr, "%s: note: too many errors, stopping\n",
			r->file);
	}
}

static void error_at(struct rib_reader *r, uint32_t line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void error_at(struct rib_reader *r, uint32_t line, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	report(r, line, fmt, ap);
	va_end(ap);
}

/* ---- byte source ---------------------------------------------------------------- */

/*
 * The input cannot be read further (I/O error, corrupt or truncated gzip
 * data): one error at the line reached. What follows would only be errors
 * caused by the cut, so the reader goes quiet.
 */
static void source_failed(struct rib_reader *r, const char *fmt, const char *detail)
{
	if (r->src_failed)
		return;
	error_at(r, r->line, fmt, detail);
	r->src_failed = true;
}

/* Reads more raw bytes of a file into inbuf; returns the count (0 at the end or on error). */
static size_t read_raw(struct rib_reader *r)
{
	if (!r->fp || r->raw_eof)
		return 0;
	size_t n = fread(r->inbuf, 1, CHUNK, r->fp);
	if (n < CHUNK) {
		r->raw_eof = true;
		if (ferror(r->fp))
			source_failed(r, "read error: %s", strerror(errno));
	}
	return n;
}

/* Hands inflate its next slice of compressed bytes. */
static void feed_inflate(struct rib_reader *r)
{
	if (r->mem) {
		size_t left = r->memlen - r->mempos;
		size_t n = left < FEED_MAX ? left : FEED_MAX;
		r->zs.next_in = r->mem + r->mempos;
		r->zs.avail_in = (uInt)n;
		r->mempos += n;
		if (r->mempos == r->memlen)
			r->raw_eof = true;
		return;
	}
	size_t n = read_raw(r);
	r->zs.next_in = r->inbuf;
	r->zs.avail_in = (uInt)n;
}

/* Inflate the next window of bytes; false at the end of the data or on an error. */
static bool inflate_more(struct rib_reader *r)
{
	if (r->zerr) {
		/* Reported only now: the bytes inflated before the damage came first. */
		source_failed(r, "corrupt gzip data (%s)", r->zerr);
		return false;
	}
	for (;;) {
		if (r->zs.avail_in == 0 && !r->raw_eof)
			feed_inflate(r);
		if (r->gz_member_done) {
			if (r->zs.avail_in == 0 && r->raw_eof)
				return false;
			/* Another gzip member follows (as `cat a.gz b.gz` makes). */
			inflateReset(&r->zs);
			r->gz_member_done = false;
		}
		r->zs.next_out = r->outbuf;
		r->zs.avail_out = CHUNK;
		int ret = inflate(&r->zs, Z_NO_FLUSH);
		size_t produced = CHUNK - r->zs.avail_out;
		if (ret == Z_STREAM_END) {
			r->gz_member_done = true;
		} else if (ret == Z_DATA_ERROR || ret == Z_NEED_DICT || ret == Z_STREAM_ERROR) {
			r->zerr = r->zs.msg ? r->zs.msg : "invalid stream";
			if (!produced)
				return inflate_more(r);
		} else if (ret == Z_MEM_ERROR) {
			source_failed(r, "%s", "out of memory while inflating gzip data");
			return false;
		} else if (produced == 0 && r->zs.avail_in == 0 && r->raw_eof) {
			/* Z_OK or Z_BUF_ERROR with nothing left to give it. */
			source_failed(r, "%s", "truncated gzip data");
			return false;
		}
		if (produced) {
			r->buf = r->outbuf;
			r->pos = 0;
			r->len = produced;
			return true;
		}
	}
}

/* The next window of bytes: false at the end of the input. */
static bool refill(struct rib_reader *r)
{
	if (r->src_failed)
		return false;
	if (r->gz)
		return inflate_more(r);
	if (r->fp) {
		size_t n = read_raw(r);
		if (!n)
			return false;
		r->buf = r->inbuf;
		r->pos = 0;
		r->len = n;
		return true;
	}
	return false;
}

static inline int peekc(struct rib_reader *r)
{
	if (r->pos == r->len && !refill(r))
		return EOF;
	return r->buf[r->pos];
}

static inline int getc_(struct rib_reader *r)
{
	if (r->pos == r->len && !refill(r))
		return EOF;
	int c = r->buf[r->pos++];
	if (c == '\n' && r->line < UINT32_MAX)
		r->line++;
	return c;
}

static bool is_gzip_magic(const unsigned char *p, size_t n)
{
	return n >= 2 && p[0] == 0x1f && p[1] == 0x8b;
}

static bool start_inflate(struct rib_reader *r, const unsigned char *in, size_t n)
{
	r->gz = true;
	r->outbuf = rl_xmalloc(CHUNK);
	/* 16 + MAX_WBITS: gzip wrapper only. */
	if (inflateInit2(&r->zs, 16 + MAX_WBITS) != Z_OK) {
		source_failed(r, "%s", "cannot initialise zlib");
		return false;
	}
	r->zinit = true;
	r->zs.next_in = in;
	r->zs.avail_in = (uInt)n;
	return true;
}

/* ---- tokenizer ------------------------------------------------------------------ */

static bool is_space(int c)
{
	return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

/* Printable characters that may be part of a bare word or number. */
static bool is_word_char(int c)
{
	return c > 0x20 && c < 0x7f && c != '"' && c != '[' && c != ']' && c != '#';
}

static enum tok lex_fail(struct rib_reader *r, uint32_t line, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static enum tok lex_fail(struct rib_reader *r, uint32_t line, const char *fmt, ...)
{
	/* Tokens skipped after an error are part of that error. */
	if (!r->skipping) {
		va_list ap;
		va_start(ap, fmt);
		report(r, line, fmt, ap);
		va_end(ap);
	}
	return T_ERR;
}

/* The end of the input inside a token: quiet when the source already said why. */
static enum tok lex_truncated(struct rib_reader *r, uint32_t line, const char *where)
{
	if (r->src_failed)
		return T_ERR;
	return lex_fail(r, line, "truncated file (inside %s)", where);
}

static void str_putc(struct rib_reader *r, char c, bool *too_long)
{
	if (r->str.len >= STRING_MAX) {
		*too_long = true;
		return;
	}
	rl_vec_push(r->str, c);
}

/*
 * string := '"' { char | '\' escape } '"'
 * escape := n t r b f v \ " ' | newline (continues the line) | 1-3 octal digits
 */
static enum tok lex_string(struct rib_reader *r)
{
	uint32_t start = r->line;
	bool too_long = false, bad = false;
	r->str.len = 0;
	for (;;) {
		int c = getc_(r);
		if (c == EOF && r->line > start && !r->src_failed)
			/* most likely a forgotten closing quote: say where it opened */
			return lex_fail(r, start,
					"unterminated string: it runs from here over %u lines to the "
					"end of the file",
					(unsigned)(r->line - start));
		if (c == EOF)
			return lex_truncated(r, start, "a string");
		if (c == '"')
			break;
		/* A string may hold newlines, as prman reads them (a long path or
		   Display name broken over lines); the reader counts them as lines. */
		if (c != '\\') {
			str_putc(r, (char)c, &too_long);
			continue;
		}
		c = getc_(r);
		switch (c) {
		case EOF:
			return lex_truncated(r, start, "a string");
		case 'n': str_putc(r, '\n', &too_long); break;
		case 't': str_putc(r, '\t', &too_long); break;
		case 'r': str_putc(r, '\r', &too_long); break;
		case 'b': str_putc(r, '\b', &too_long); break;
		case 'f': str_putc(r, '\f', &too_long); break;
		case 'v': str_putc(r, '\v', &too_long); break;
		case '\\': case '"': case '\'':
			str_putc(r, (char)c, &too_long);
			break;
		case '\n':
			break;
		default:
			if (c >= '0' && c <= '7') {
				int v = c - '0';
				for (int k = 1; k < 3; k++) {
					int d = peekc(r);
					if (d < '0' || d > '7')
						break;
					v = v * 8 + (getc_(r) - '0');
				}
				str_putc(r, (char)(v & 0xff), &too_long);
			} else if (!bad) {
				bad = true;
				if (isprint(c))
					lex_fail(r, r->line, "unknown escape '\\%c' in string", c);
				else
					lex_fail(r, r->line, "unknown escape (byte 0x%02x) in string", c);
			}
			break;
		}
	}
	if (bad)
		return T_ERR;
	if (too_long)
		return lex_fail(r, start, "string longer than %d bytes", STRING_MAX);
	rl_vec_push(r->str, '\0');
	r->str.len--;
	return T_STR;
}

static bool is_nonfinite_word(const char *w)
{
	if (*w == '+' || *w == '-')
		w++;
	static const char *const names[] = {"nan", "inf", "infinity"};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		const char *a = w, *b = names[i];
		while (*a && *b && tolower((unsigned char)*a) == *b) {
			a++;
			b++;
		}
		if (!*a && !*b)
			return true;
	}
	return false;
}

/* number := [+-] ( digits [ '.' [digits] ] | '.' digits ) [ (e|E) [+-] digits ] */
static bool is_number_syntax(const char *w)
{
	const char *p = w;
	if (*p == '+' || *p == '-')
		p++;
	size_t nd = 0;
	while (isdigit((unsigned char)*p)) {
		p++;
		nd++;
	}
	if (*p == '.') {
		p++;
		while (isdigit((unsigned char)*p)) {
			p++;
			nd++;
		}
	}
	if (!nd)
		return false;
	if (*p == 'e' || *p == 'E') {
		p++;
		if (*p == '+' || *p == '-')
			p++;
		if (!isdigit((unsigned char)*p))
			return false;
		while (isdigit((unsigned char)*p))
			p++;
	}
	return *p == '\0';
}

static bool is_name_syntax(const char *w)
{
	if (!isalpha((unsigned char)*w) && *w != '_')
		return false;
	for (w++; *w; w++)
		if (!isalnum((unsigned char)*w) && *w != '_')
			return false;
	return true;
}

/* A bare word: a request name, a number, or an error. */
static enum tok lex_word(struct rib_reader *r, int first)
{
	uint32_t line = r->line;
	size_t n = 0;
	bool too_long = false;
	r->word[n++] = (char)first;
	while (is_word_char(peekc(r))) {
		int c = getc_(r);
		if (n < WORD_MAX)
			r->word[n++] = (char)c;
		else
			too_long = true;
	}
	r->word[n] = '\0';
	if (too_long)
		return lex_fail(r, line, "token too long: '%.32s...'", r->word);
	if (is_name_syntax(r->word) && !is_nonfinite_word(r->word))
		return T_NAME;
	if (is_nonfinite_word(r->word))
		return lex_fail(r, line, "'%s' is not a finite number", r->word);
	if (!is_number_syntax(r->word)) {
		if (strchr("+-.0123456789", r->word[0]))
			return lex_fail(r, line, "malformed number '%s'", r->word);
		return lex_fail(r, line, "unexpected '%s'", r->word);
	}
	double v = strtod(r->word, NULL);
	/* Renderers keep RtFloat (single precision): larger numbers would be infinite. */
	if (!isfinite(v) || fabs(v) > FLT_MAX)
		return lex_fail(r, line, "number out of range: %s", r->word);
	r->tok_num = v;
	return T_NUM;
}

static enum tok lex(struct rib_reader *r)
{
	for (;;) {
		int c = getc_(r);
		r->tok_line = r->line;
		if (c == EOF)
			return T_EOF;
		if (is_space(c))
			continue;
		if (c == '#') {
			/* Comments and ## structure comments alike run to the end of the line. */
			while ((c = peekc(r)) != EOF && c != '\n')
				getc_(r);
			continue;
		}
		if (c == '[')
			return T_LBRACK;
		if (c == ']')
			return T_RBRACK;
		if (c == '"')
			return lex_string(r);
		if (is_word_char(c))
			return lex_word(r, c);
		if (c >= 0x80)
			return lex_fail(r, r->line,
					"unexpected byte 0x%02x (binary RIB is not supported)", c);
		return lex_fail(r, r->line, "unexpected control character 0x%02x", c);
	}
}

static enum tok peek(struct rib_reader *r)
{
	if (!r->have_tok) {
		r->tok = lex(r);
		r->have_tok = true;
	}
	return r->tok;
}

static void advance(struct rib_reader *r)
{
	peek(r);
	r->have_tok = false;
}

/* The current token for messages: "number 3", "string \"x\"", "'['". */
static const char *tok_desc(struct rib_reader *r, char *buf, size_t size)
{
	switch (peek(r)) {
	case T_NUM:
		snprintf(buf, size, "number %g", r->tok_num);
		break;
	case T_STR:
		snprintf(buf, size, "string \"%.40s%s\"", r->str.data,
			 r->str.len > 40 ? "..." : "");
		break;
	case T_NAME:
		snprintf(buf, size, "'%.60s'", r->word);
		break;
	case T_LBRACK:
		snprintf(buf, size, "'['");
		break;
	case T_RBRACK:
		snprintf(buf, size, "']'");
		break;
	case T_EOF:
		snprintf(buf, size, "the end of the file");
		break;
	case T_ERR:
		snprintf(buf, size, "an invalid token");
		break;
	}
	return buf;
}

/* ---- request storage -------------------------------------------------------------- */

static void request_reset(struct rib_reader *r)
{
	if (r->nums.cap > SHRINK_ELEMS)
		rl_vec_free(r->nums);
	if (r->strofs.cap > SHRINK_ELEMS)
		rl_vec_free(r->strofs);
	if (r->strptrs.cap > SHRINK_ELEMS)
		rl_vec_free(r->strptrs);
	if (r->chars.cap > (size_t)16 * SHRINK_ELEMS)
		rl_vec_free(r->chars);
	if (r->pparams.cap > SHRINK_ELEMS) {
		rl_vec_free(r->pparams);
		rl_vec_free(r->params);
	}
	r->nums.len = r->chars.len = r->strofs.len = 0;
	r->pargs.len = r->pparams.len = 0;
	r->req_elems = 0;
}

/* Counts one more value against the request's budget; false (reported) when over. */
static bool budget(struct rib_reader *r, uint32_t line)
{
	if (++r->req_elems > r->max_req_elems) {
		error_at(r, line, "request holds more than %zu values", r->max_req_elems);
		return false;
	}
	return true;
}

/* Copies the current string token into the request; returns its strofs index. */
static bool keep_string(struct rib_reader *r, size_t *index)
{
	if (r->chars.len + r->str.len + 1 > REQ_STRING_BYTES) {
		error_at(r, r->tok_line, "request holds more than %d bytes of strings",
			 REQ_STRING_BYTES);
		return false;
	}
	if (!budget(r, r->tok_line))
		return false;
	size_t at = r->chars.len;
	rl_vec_reserve(r->chars, at + r->str.len + 1);
	memcpy(r->chars.data + at, r->str.data ? r->str.data : "", r->str.len);
	r->chars.data[at + r->str.len] = '\0';
	r->chars.len = at + r->str.len + 1;
	*index = r->strofs.len;
	rl_vec_push(r->strofs, at);
	return true;
}

static bool keep_number(struct rib_reader *r, double v, size_t *index)
{
	if (!budget(r, r->tok_line))
		return false;
	*index = r->nums.len;
	rl_vec_push(r->nums, v);
	return true;
}

/*
 * array := '[' { number } ']' | '[' { string } ']'
 * The current token is '['. An empty array is an array of numbers.
 */
static bool parse_array(struct rib_reader *r, struct pvalue *v)
{
	v->line = r->tok_line;
	v->type = RIB_NUMBERS;
	v->n = 0;
	v->start = r->nums.len;
	advance(r);
	char desc[80];
	for (;;) {
		enum tok t = peek(r);
		if (t == T_RBRACK) {
			advance(r);
			return true;
		}
		if (t == T_ERR)
			return false;
		if (t == T_EOF) {
			if (!r->src_failed)
				error_at(r, v->line, "truncated file (inside an array)");
			return false;
		}
		if (t == T_NAME) {
			error_at(r, r->tok_line, "unexpected '%s' inside an array (missing ']'?)",
				 r->word);
			return false;
		}
		if (t == T_LBRACK) {
			error_at(r, r->tok_line, "arrays cannot be nested");
			return false;
		}
		if (v->n == 0 && t == T_STR) {
			v->type = RIB_STRINGS;
			v->start = r->strofs.len;
		}
		if ((t == T_STR) != (v->type == RIB_STRINGS)) {
			error_at(r, r->tok_line, "array mixes numbers and strings (%s)",
				 tok_desc(r, desc, sizeof(desc)));
			return false;
		}
		if ((size_t)v->n >= r->max_array || v->n == UINT32_MAX) {
			error_at(r, v->line, "array too long (more than %zu elements)",
				 r->max_array);
			return false;
		}
		size_t index;
		if (t == T_STR ? !keep_string(r, &index) : !keep_number(r, r->tok_num, &index))
			return false;
		v->n++;
		advance(r);
	}
}

static bool is_integer(double v)
{
	return v == floor(v) && fabs(v) <= 2147483647.0;
}

/* ---- requests -------------------------------------------------------------------------- */

/* One "name:kind" of a request's argument list. */
struct argspec {
	char name[32];
	char kind;
};

static size_t parse_argspec(const char *s, struct argspec *out, size_t max)
{
	size_t n = 0;
	while (*s && n < max) {
		while (*s == ' ')
			s++;
		if (!*s)
			break;
		size_t len = strcspn(s, ":");
		if (len >= sizeof(out[n].name))
			len = sizeof(out[n].name) - 1;
		memcpy(out[n].name, s, len);
		out[n].name[len] = '\0';
		s = strchr(s, ':');
		if (!s)
			break;
		out[n].kind = s[1];
		n++;
		s += 2;
	}
	return n;
}

static const char *kind_desc(char kind)
{
	switch (kind) {
	case 'n': return "a number";
	case 'i': return "an integer";
	case 's': return "a string";
	case 'h': return "an integer or a string";
	case 'a': return "an array of numbers";
	case 'I': return "an array of integers";
	case 'S': return "an array of strings";
	case 'm': return "an array of 16 numbers";
	case 'b': return "a basis name or an array of 16 numbers";
	}
	return "a value";
}

static bool push_arg(struct rib_reader *r, enum rib_vtype type, uint32_t n, size_t start,
		     uint32_t line)
{
	rl_vec_push(r->pargs, (struct pvalue){.type = type, .n = n, .start = start, .line = line});
	return true;
}

/* A wrong or missing argument: false, with the error reported unless a bad token already was. */
static bool arg_mismatch(struct rib_reader *r, const struct reqdef *def,
			 const struct argspec *a)
{
	enum tok t = peek(r);
	if (t == T_ERR)
		return false;
	if (t == T_NAME || t == T_EOF) {
		error_at(r, r->req_line, "%s is missing its '%s' argument (%s)", def->name,
			 a->name, kind_desc(a->kind));
	} else {
		char desc[80];
		error_at(r, r->tok_line, "%s expects %s for '%s', got %s", def->name,
			 kind_desc(a->kind), a->name, tok_desc(r, desc, sizeof(desc)));
	}
	return false;
}

static bool check_integer(struct rib_reader *r, const struct reqdef *def, const char *name,
			  double v, uint32_t line)
{
	if (is_integer(v))
		return true;
	error_at(r, line, "%s expects an integer for '%s', got %g", def->name, name, v);
	return false;
}

/*
 * numbers := number { number }          (exactly as many as the request takes)
 *          | '[' number { number } ']'  (requests marked BRACKET_OK)
 *          | (nothing)                  (requests marked NONE_OK)
 * For requests whose positional arguments are all numbers: the count is
 * checked as a whole, which gives the clearest message.
 */
static bool parse_number_args(struct rib_reader *r, const struct reqdef *def,
			      const struct argspec *spec, size_t nspec)
{
	size_t got = 0;
	char desc[80];
	const char *tail = def->flags & TAKES_PARAMS ? " before its parameter list" : "";
	const char *plural = nspec == 1 ? "" : "s";
	if ((def->flags & BRACKET_OK) && peek(r) == T_LBRACK) {
		struct pvalue v;
		if (!parse_array(r, &v))
			return false;
		if (v.type != RIB_NUMBERS || v.n != nspec) {
			error_at(r, v.line, "%s expects %zu number%s, got an array of %u %s",
				 def->name, nspec, plural, v.n,
				 v.type == RIB_NUMBERS ? "numbers" : "strings");
			return false;
		}
		for (size_t i = 0; i < nspec; i++)
			push_arg(r, RIB_NUMBER, 1, v.start + i, v.line);
		return true;
	}
	while (peek(r) == T_NUM) {
		if (got < nspec) {
			size_t index;
			if (!keep_number(r, r->tok_num, &index))
				return false;
			push_arg(r, RIB_NUMBER, 1, index, r->tok_line);
		}
		got++;
		advance(r);
	}
	if (got == 0 && (def->flags & NONE_OK) && (peek(r) == T_NAME || peek(r) == T_EOF))
		return true;
	if (got != nspec) {
		if (peek(r) == T_ERR)
			return false;
		if (got == 0 && peek(r) == T_LBRACK)
			snprintf(desc, sizeof(desc), "an array");
		else
			snprintf(desc, sizeof(desc), "%zu", got);
		error_at(r, r->req_line, "%s expects %zu number%s%s, got %s", def->name, nspec, plural, tail, desc);
		return false;
	}
	for (size_t i = 0; i < nspec; i++) {
		const struct pvalue *v = &r->pargs.data[i];
		if (spec[i].kind == 'i' &&
		    !check_integer(r, def, spec[i].name, r->nums.data[v->start], v->line))
			return false;
	}
	return true;
}

/* One positional argument of kind a->kind. */
static bool parse_arg(struct rib_reader *r, const struct reqdef *def, const struct argspec *a)
{
	enum tok t = peek(r);
	uint32_t line = r->tok_line;
	size_t index;
	/* Handles and bases may be strings as well. */
	if (t == T_STR && (a->kind == 's' || a->kind == 'h' || a->kind == 'b' || a->kind == 'S')) {
		if (!keep_string(r, &index))
			return false;
		advance(r);
		return push_arg(r, RIB_STRING, 1, index, line);
	}
	switch (a->kind) {
	case 'n':
	case 'i':
		if (t != T_NUM)
			return arg_mismatch(r, def, a);
		if (a->kind == 'i' && !check_integer(r, def, a->name, r->tok_num, line))
			return false;
		if (!keep_number(r, r->tok_num, &index))
			return false;
		advance(r);
		return push_arg(r, RIB_NUMBER, 1, index, line);
	case 'h':
		if (t != T_NUM)
			return arg_mismatch(r, def, a);
		if (!is_integer(r->tok_num)) {
			error_at(r, line, "%s expects an integer or a string for '%s', got %g",
				 def->name, a->name, r->tok_num);
			return false;
		}
		if (!keep_number(r, r->tok_num, &index))
			return false;
		advance(r);
		return push_arg(r, RIB_NUMBER, 1, index, line);
	case 'S': {
		if (t != T_LBRACK)
			return arg_mismatch(r, def, a);
		struct pvalue v;
		if (!parse_array(r, &v))
			return false;
		if (v.type != RIB_STRINGS && v.n) {
			error_at(r, v.line, "%s expects %s for '%s', got an array of numbers",
				 def->name, kind_desc(a->kind), a->name);
			return false;
		}
		if (v.type != RIB_STRINGS) {
			/* an empty array: of strings */
			v.type = RIB_STRINGS;
			v.start = r->strofs.len;
		}
		rl_vec_push(r->pargs, v);
		return true;
	}
	case 'a':
	case 'b':
	case 'I':
	case 'm': {
		if (t != T_LBRACK)
			return arg_mismatch(r, def, a);
		struct pvalue v;
		if (!parse_array(r, &v))
			return false;
		if (v.type != RIB_NUMBERS) {
			error_at(r, v.line, "%s expects %s for '%s', got an array of strings",
				 def->name, kind_desc(a->kind), a->name);
			return false;
		}
		if ((a->kind == 'm' || a->kind == 'b') && v.n != 16) {
			error_at(r, v.line, "%s expects 16 numbers for '%s', got %u", def->name,
				 a->name, v.n);
			return false;
		}
		if (a->kind == 'I') {
			for (uint32_t i = 0; i < v.n; i++) {
				double x = r->nums.data[v.start + i];
				if (!is_integer(x)) {
					error_at(r, v.line,
						 "%s expects integers in '%s', got %g (element %u)",
						 def->name, a->name, x, i);
					return false;
				}
			}
		}
		rl_vec_push(r->pargs, v);
		return true;
	}
	}
	return arg_mismatch(r, def, a);
}

/*
 * paramlist := { string value }
 * value     := array | number | string   (a single value becomes a 1-element array)
 * The list ends at the next request name or the end of the file.
 */
static bool parse_params(struct rib_reader *r, const struct reqdef *def)
{
	char desc[80];
	for (;;) {
		enum tok t = peek(r);
		if (t == T_NAME || t == T_EOF)
			return true;
		if (t == T_ERR)
			return false;
		if (t != T_STR) {
			error_at(r, r->tok_line,
				 "expected a parameter name (a string) in %s's parameter list, got %s",
				 def->name, tok_desc(r, desc, sizeof(desc)));
			return false;
		}
		struct pparam p = {.line = r->tok_line};
		if (!keep_string(r, &p.token))
			return false;
		size_t tok_chars = r->strofs.data[p.token];
		advance(r);
		t = peek(r);
		p.value.line = r->tok_line;
		size_t index;
		switch (t) {
		case T_LBRACK:
			if (!parse_array(r, &p.value))
				return false;
			break;
		case T_NUM:
			if (!keep_number(r, r->tok_num, &index))
				return false;
			p.value = (struct pvalue){RIB_NUMBERS, 1, index, r->tok_line};
			advance(r);
			break;
		case T_STR:
			if (!keep_string(r, &index))
				return false;
			p.value = (struct pvalue){RIB_STRINGS, 1, index, r->tok_line};
			advance(r);
			break;
		case T_ERR:
			return false;
		default:
			error_at(r, p.line, "parameter '%s' has no value",
				 r->chars.data + tok_chars);
			return false;
		}
		rl_vec_push(r->pparams, p);
	}
}

static void fill_value(struct rib_reader *r, const struct pvalue *p, struct rib_value *v)
{
	*v = (struct rib_value){.type = p->type, .n = p->n, .loc = loc_at(r, p->line)};
	if (p->type == RIB_NUMBER || p->type == RIB_NUMBERS)
		v->nums = r->nums.data ? r->nums.data + p->start : NULL;
	else
		v->strs = r->strptrs.data ? r->strptrs.data + p->start : NULL;
}

/* Turns indices into pointers and calls the handler. */
static void dispatch(struct rib_reader *r, const struct reqdef *def, uint32_t line)
{
	/* A request read up to a failed input may be cut short (a number's digits). */
	if (!r->fn || r->src_failed)
		return;
	r->strptrs.len = 0;
	rl_vec_reserve(r->strptrs, r->strofs.len);
	for (size_t i = 0; i < r->strofs.len; i++)
		r->strptrs.data[i] = r->chars.data + r->strofs.data[i];
	r->strptrs.len = r->strofs.len;

	r->args.len = 0;
	rl_vec_reserve(r->args, r->pargs.len);
	for (size_t i = 0; i < r->pargs.len; i++)
		fill_value(r, &r->pargs.data[i], &r->args.data[i]);
	r->args.len = r->pargs.len;

	r->params.len = 0;
	rl_vec_reserve(r->params, r->pparams.len);
	for (size_t i = 0; i < r->pparams.len; i++) {
		const struct pparam *p = &r->pparams.data[i];
		struct rib_param *q = &r->params.data[i];
		q->token = r->strptrs.data[p->token];
		q->loc = loc_at(r, p->line);
		fill_value(r, &p->value, &q->value);
	}
	r->params.len = r->pparams.len;

	struct rib_request req = {
		.name = def->name,
		.loc = loc_at(r, line),
		.args = r->args.len ? r->args.data : NULL,
		.nargs = (uint32_t)r->args.len,
		.params = r->params.len ? r->params.data : NULL,
		.nparams = (uint32_t)r->params.len,
	};
	if (!r->fn(r->user, &req)) {
		r->handler_stopped = true;
		r->stop = true;
	}
}

/* request := name positional-arguments [ paramlist ]   (the current token is the name) */
static bool parse_request(struct rib_reader *r, const struct reqdef *def)
{
	uint32_t line = r->tok_line;
	r->req_line = line;
	request_reset(r);
	advance(r);

	struct argspec spec[12]; /* as many as any request of the table has */
	size_t nspec = parse_argspec(def->args, spec, sizeof(spec) / sizeof(spec[0]));
	bool all_numbers = nspec > 0;
	for (size_t i = 0; i < nspec; i++)
		all_numbers &= spec[i].kind == 'n' || spec[i].kind == 'i';

	if (all_numbers) {
		if (!parse_number_args(r, def, spec, nspec))
			return false;
	} else {
		for (size_t i = 0; i < nspec; i++)
			if (!parse_arg(r, def, &spec[i]))
				return false;
	}
	while ((def->flags & MORE_ARRAYS) && peek(r) == T_LBRACK) {
		struct pvalue v;
		if (!parse_array(r, &v))
			return false;
		rl_vec_push(r->pargs, v);
	}
	if (def->flags & TAKES_PARAMS) {
		if (!parse_params(r, def))
			return false;
		dispatch(r, def, line);
		return true;
	}
	/*
	 * Without a parameter list the request is complete here: whatever follows
	 * is wrong, but the request itself stands.
	 */
	enum tok t = peek(r);
	bool clean = t == T_NAME || t == T_EOF;
	if (!clean && t != T_ERR) {
		char desc[80];
		error_at(r, r->tok_line, "unexpected %s after the arguments of %s",
			 tok_desc(r, desc, sizeof(desc)), def->name);
	}
	if (!r->stop)
		dispatch(r, def, line);
	return clean;
}

/* Edit distance ignoring case; both strings are at most NAME_SUGGEST_MAX long. */
static size_t edit_distance(const char *a, const char *b)
{
	size_t la = strlen(a), lb = strlen(b);
	size_t row[NAME_SUGGEST_MAX + 1];
	for (size_t j = 0; j <= lb; j++)
		row[j] = j;
	for (size_t i = 1; i <= la; i++) {
		size_t diag = row[0];
		row[0] = i;
		for (size_t j = 1; j <= lb; j++) {
			size_t up = row[j];
			size_t cost = tolower((unsigned char)a[i - 1]) !=
				      tolower((unsigned char)b[j - 1]);
			size_t best = diag + cost;
			if (up + 1 < best)
				best = up + 1;
			if (row[j - 1] + 1 < best)
				best = row[j - 1] + 1;
			row[j] = best;
			diag = up;
		}
	}
	return row[lb];
}

/* The known request closest to @name, or NULL when none is close. */
static const char *suggest(const char *name)
{
	size_t len = strlen(name);
	if (len > NAME_SUGGEST_MAX)
		return NULL;
	size_t limit = len / 3 > 1 ? len / 3 : 1;
	const char *best = NULL;
	size_t best_d = limit + 1;
	for (size_t i = 0; i < sizeof(reqdefs) / sizeof(reqdefs[0]); i++) {
		/* The distance is at least the difference in length. */
		size_t cl = strlen(reqdefs[i].name);
		if (cl > NAME_SUGGEST_MAX || (cl > len ? cl - len : len - cl) > limit)
			continue;
		size_t d = edit_distance(name, reqdefs[i].name);
		if (d < best_d) {
			best_d = d;
			best = reqdefs[i].name;
		}
	}
	return best;
}

static const struct reqdef *find_request(const char *name)
{
	for (size_t i = 0; i < sizeof(reqdefs) / sizeof(reqdefs[0]); i++)
		if (reqdefs[i].name[0] == name[0] && strcmp(reqdefs[i].name, name) == 0)
			return &reqdefs[i];
	return NULL;
}

static bool is_unsupported(const char *name)
{
	for (size_t i = 0; i < sizeof(unsupported) / sizeof(unsupported[0]); i++)
		if (strcmp(unsupported[i], name) == 0)
			return true;
	return false;
}

/* After an error: drop tokens up to the next request name (not consumed). */
static void skip_to_request(struct rib_reader *r)
{
	r->skipping = true;
	while (!r->stop) {
		enum tok t = peek(r);
		if (t == T_NAME || t == T_EOF)
			break;
		advance(r);
	}
	r->skipping = false;
}

/*
 * A request the table lacks (the current token is its name): its arguments
 * are read as tokens up to the next request name, and it goes to the
 * handler by name, to be warned about there; after a lexical error in them
 * (the first one reported) it is dropped, as a known request would be.
 */
static void pass_unhandled(struct rib_reader *r)
{
	char name[sizeof(r->word)];
	memcpy(name, r->word, sizeof(name));
	uint32_t line = r->tok_line;
	advance(r);
	bool bad = false;
	while (!r->stop) {
		enum tok t = peek(r);
		if (t == T_NAME || t == T_EOF)
			break;
		if (t == T_ERR)
			bad = r->skipping = true;
		advance(r);
	}
	r->skipping = false;
	if (!r->fn || r->src_failed || r->stop || bad)
		return;
	bool unsupported = is_unsupported(name);
	struct rib_request req = {
		.name = name,
		.loc = loc_at(r, line),
		.known = unsupported ? RIB_UNSUPPORTED : RIB_UNKNOWN,
		.near = unsupported ? NULL : suggest(name),
	};
	if (!r->fn(r->user, &req)) {
		r->handler_stopped = true;
		r->stop = true;
	}
}

/*
 * A primitive whose arguments had an error (reported, and skipped): it goes
 * to the handler by name, so that the handler drops what it would have made
 * (a sample of a motion block takes the whole primitive with it).
 */
static void pass_malformed(struct rib_reader *r, const struct reqdef *def)
{
	if (!r->fn || r->src_failed || r->stop)
		return;
	struct rib_request req = {
		.name = def->name,
		.loc = loc_at(r, r->req_line),
		.known = RIB_MALFORMED,
	};
	if (!r->fn(r->user, &req)) {
		r->handler_stopped = true;
		r->stop = true;
	}
}

/* file := { request } */
static void read_all(struct rib_reader *r)
{
	char desc[80];
	while (!r->stop) {
		enum tok t = peek(r);
		if (t == T_EOF)
			break;
		if (t != T_NAME) {
			if (t != T_ERR)
				error_at(r, r->tok_line, "expected a request name, got %s",
					 tok_desc(r, desc, sizeof(desc)));
			advance(r);
			skip_to_request(r);
			continue;
		}
		const struct reqdef *def = find_request(r->word);
		if (!def) {
			pass_unhandled(r);
			continue;
		}
		r->in_primitive = def->flags & PRIMITIVE;
		if (!parse_request(r, def)) {
			skip_to_request(r);
			if (r->in_primitive)
				pass_malformed(r, def);
		}
		r->in_primitive = false;
	}
}

static void reader_init(struct rib_reader *r, const char *name,
			const struct rib_reader_opts *opts, rib_handler_fn fn, void *user)
{
	memset(r, 0, sizeof(*r));
	r->file = rl_xstrdup(name ? name : "<rib>");
	r->diag = opts ? opts->diag : NULL;
	r->max_errors = opts && opts->max_errors > 0 ? opts->max_errors : DEFAULT_MAX_ERRORS;
	r->max_array = opts && opts->max_array ? opts->max_array : DEFAULT_MAX_ARRAY;
	if (r->max_array > UINT32_MAX)
		r->max_array = UINT32_MAX;
	/* A request may hold several arrays (indices, positions, normals...). */
	r->max_req_elems = r->max_array <= SIZE_MAX / 4 ? r->max_array * 4 : SIZE_MAX;
	r->fn = fn;
	r->user = user;
	r->line = 1;
}

static bool reader_finish(struct rib_reader *r, int *nerrors)
{
	bool ok = r->nerrors == 0 && !r->handler_stopped;
	if (nerrors)
		*nerrors = r->nerrors;
	if (r->zinit)
		inflateEnd(&r->zs);
	free(r->inbuf);
	free(r->outbuf);
	rl_vec_free(r->str);
	rl_vec_free(r->nums);
	rl_vec_free(r->chars);
	rl_vec_free(r->strofs);
	rl_vec_free(r->pargs);
	rl_vec_free(r->pparams);
	rl_vec_free(r->strptrs);
	rl_vec_free(r->args);
	rl_vec_free(r->params);
	free((char *)r->file);
	return ok;
}

bool rib_read_buffer(const char *name, const char *data, size_t len,
		     const struct rib_reader_opts *opts, rib_handler_fn fn, void *user,
		     int *nerrors)
{
	struct rib_reader r;
	reader_init(&r, name, opts, fn, user);
	const unsigned char *p = (const unsigned char *)data;
	if (!p && len) {
		error_at(&r, 0, "no data");
		return reader_finish(&r, nerrors);
	}
	if (is_gzip_magic(p, len)) {
		r.mem = p;
		r.memlen = len;
		if (start_inflate(&r, NULL, 0))
			read_all(&r);
	} else {
		r.buf = p;
		r.len = len;
		read_all(&r);
	}
	return reader_finish(&r, nerrors);
}

bool rib_read_file(const char *path, const struct rib_reader_opts *opts, rib_handler_fn fn,
		   void *user, int *nerrors)
{
	struct rib_reader r;
	reader_init(&r, path, opts, fn, user);
	r.fp = path ? fopen(path, "rb") : NULL;
	if (!r.fp) {
		error_at(&r, 0, "cannot open: %s", path ? strerror(errno) : "no file name");
		return reader_finish(&r, nerrors);
	}
	r.inbuf = rl_xmalloc(CHUNK);
	size_t n = read_raw(&r);
	if (is_gzip_magic(r.inbuf, n)) {
		if (start_inflate(&r, r.inbuf, n))
			read_all(&r);
	} else {
		r.buf = r.inbuf;
		r.len = n;
		read_all(&r);
	}
	fclose(r.fp);
	r.fp = NULL;
	return reader_finish(&r, nerrors);
}

/*
 * The GPU module: a headless OpenGL core context through EGL, compute
 * programs cached by the hash of their source, buffers, dispatch, readback,
 * and offline GLSL validation.
 *
 * GL entry points are called directly (GL_GLEXT_PROTOTYPES with
 * <GL/glcorearb.h>, linked against glvnd's libOpenGL). libOpenGL exports
 * every core function through 4.6 and forwards each call to the vendor of
 * the context current on the thread, so no loader table is needed and every
 * call is type-checked against its prototype. The price is that a function
 * the driver lacks becomes a silent no-op, which is why gpu_create checks
 * the version (and direct state access) before handing out a context. Only
 * EGL extension functions go through eglGetProcAddress.
 *
 * Every object is created and used with direct state access: the indexed
 * binds that dispatch needs (glBindBufferBase) also move the generic binding
 * points, so a non-DSA call afterwards would touch the wrong object.
 */
#include "gpu.h"
#include "config.h"
#include "fileutil.h"
#include "log.h"

#define GL_GLEXT_PROTOTYPES 1
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

/* The work-group size every dispatched program declares, and the largest
 * group count used in x (the minimum every implementation supports). */
enum { LOCAL_SIZE = 64, MAX_GROUPS_X = 65535 };

/* A uniform as seen through one name: where it is, its GL type, and how
 * many array elements there are from that location on. */
struct uniform_slot {
	char *name;            /* NULL: empty slot */
	uint64_t hash;
	GLint location;        /* -1: not an active uniform of the program */
	GLenum type;
	GLint count;
};

struct gpu_program {
	struct gpu_ctx *ctx;
	struct gpu_program *next;  /* the cache's hash chain */
	uint64_t hash;
	char *source;
	GLuint name;
	GLint local_size[3];
	struct uniform_slot *slots;  /* open addressing, power-of-two size */
	uint32_t nslots, nused;
};

struct gpu_buffer {
	struct gpu_ctx *ctx;
	struct gpu_buffer *prev, *next;  /* every live buffer of the context */
	GLuint name;
	GLuint texture;  /* its R32F buffer texture, made on first use as a samplerBuffer */
	GLuint texture4; /* the same as RGBA32F texels */
	size_t bytes;
};

struct gpu_ctx {
	EGLDisplay display;
	EGLContext context;
	char renderer[256];
	bool software;
	GLint gl_major, gl_minor;
	/* Limits checked at dispatch. */
	GLint max_ssbo_bindings, max_texture_units, max_texels, max_groups_y;
	GLint64 max_ssbo_bytes;
	struct gpu_program **buckets;  /* program cache, power-of-two buckets */
	uint32_t nbuckets, nprograms;
	struct gpu_buffer *buffers;
	/* Compiled programs kept on disk (NULL: off) and what they saved. */
	char *cache_dir;
	GLint nbinary_formats;
	unsigned disk_hits, compiled;
};

/* ---- small helpers ---- */

/* FNV-1a, 64 bits: program sources and uniform names. */
static uint64_t hash_bytes(const char *s, size_t n)
{
	uint64_t h = 0xcbf29ce484222325u;
	for (size_t i = 0; i < n; i++) {
		h ^= (unsigned char)s[i];
		h *= 0x100000001b3u;
	}
	return h;
}

static char *dup_string(const char *s)
{
	size_t n = strlen(s) + 1;
	char *d = malloc(n);
	if (d)
		memcpy(d, s, n);
	return d;
}

/* Is @name one of the space-separated words of @list? */
static bool has_word(const char *list, const char *name)
{
	size_t n = strlen(name);
	if (!list || !n)
		return false;
	for (const char *p = list; (p = strstr(p, name)) != NULL; p += n) {
		bool starts = p == list || p[-1] == ' ';
		bool ends = p[n] == '\0' || p[n] == ' ';
		if (starts && ends)
			return true;
	}
	return false;
}

/* Append "; MESSAGE" (or MESSAGE when @err is empty) to @err, truncating. */
__attribute__((format(printf, 3, 4)))
static void add_reason(char *err, size_t errlen, const char *fmt, ...)
{
	size_t used = strlen(err);
	if (used + 1 >= errlen)
		return;
	if (used) {
		snprintf(err + used, errlen - used, "; ");
		used = strlen(err);
	}
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(err + used, errlen - used, fmt, ap);
	va_end(ap);
}

static const char *egl_error_name(EGLint e)
{
	switch (e) {
	case EGL_SUCCESS: return "EGL_SUCCESS";
	case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
	case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
	case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
	case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
	case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
	case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
	case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
	case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
	case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
	case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
	case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
	case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
	case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
	case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
	default: return "unknown EGL error";
	}
}

static const char *gl_error_name(GLenum e)
{
	switch (e) {
	case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
	case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
	case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
	case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
	case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
	case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
	case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
	case GL_CONTEXT_LOST: return "GL_CONTEXT_LOST";
	default: return "unknown GL error";
	}
}

/* Log every pending GL error under @what; false if there was one. Bounded:
 * a lost context may report errors forever. */
static bool gl_check(const char *what)
{
	bool ok = true;
	for (int i = 0; i < 8; i++) {
		GLenum e = glGetError();
		if (e == GL_NO_ERROR)
			break;
		rl_log(RL_LOG_ERROR, "%s: OpenGL error %s (0x%04x)", what, gl_error_name(e), (unsigned)e);
		ok = false;
	}
	return ok;
}

/* Clear errors left by earlier calls so they are not blamed on the next. */
static void gl_drain(void)
{
	for (int i = 0; i < 8 && glGetError() != GL_NO_ERROR; i++)
		;
}

/* GL calls go to the context current on the calling thread. */
static bool is_current(const struct gpu_ctx *ctx, const char *fn)
{
	if (eglGetCurrentContext() == ctx->context)
		return true;
	rl_log(RL_LOG_ERROR, "%s: the GPU context is not current on this thread", fn);
	return false;
}

bool gpu_make_current(struct gpu_ctx *ctx)
{
	if (!ctx)
		return false;
	if (eglGetCurrentContext() == ctx->context)
		return true;
	if (eglMakeCurrent(ctx->display, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx->context))
		return true;
	rl_log(RL_LOG_ERROR, "gpu_make_current: eglMakeCurrent failed (0x%x)", (unsigned)eglGetError());
	return false;
}

/* ---- EGL displays ---- */

/*
 * Displays are never terminated once they serve a context. An EGLDisplay is
 * one per platform and device for the whole process, shared with every other
 * EGL user in it, and eglTerminate is not reference-counted (glvnd offers no
 * EGL_KHR_display_reference): terminating ours would pull the display from
 * under them. Keeping it also spares the next gpu_create a reload of the
 * driver; it goes when the process exits. A display that this module
 * initialized and then could not use is terminated at once.
 */

static bool is_software_renderer(const char *r)
{
	static const char *const names[] = {
		"llvmpipe", "softpipe", "swrast", "SWR", "Software Rasterizer",
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (strstr(r, names[i]))
			return true;
	return false;
}

static bool gl_has_extension(const char *name)
{
	GLint n = 0;
	glGetIntegerv(GL_NUM_EXTENSIONS, &n);
	for (GLint i = 0; i < n; i++) {
		const GLubyte *e = glGetStringi(GL_EXTENSIONS, (GLuint)i);
		if (e && !strcmp((const char *)e, name))
			return true;
	}
	return false;
}

/* With the context current: is it good enough, and what are its limits? */
static bool check_gl(struct gpu_ctx *ctx, const char *label, char *err, size_t errlen)
{
	const char *renderer = (const char *)glGetString(GL_RENDERER);
	if (!renderer) {
		add_reason(err, errlen, "%s: the context answers no GL_RENDERER", label);
		return false;
	}
	snprintf(ctx->renderer, sizeof(ctx->renderer), "%s", renderer);
	glGetIntegerv(GL_MAJOR_VERSION, &ctx->gl_major);
	glGetIntegerv(GL_MINOR_VERSION, &ctx->gl_minor);
	if (ctx->gl_major < 4 || (ctx->gl_major == 4 && ctx->gl_minor < 3)) {
		add_reason(err, errlen, "%s: OpenGL %d.%d on %s, 4.3 needed", label, ctx->gl_major,
			   ctx->gl_minor, ctx->renderer);
		return false;
	}
	if (ctx->gl_major == 4 && ctx->gl_minor < 5 && !gl_has_extension("GL_ARB_direct_state_access")) {
		add_reason(err, errlen, "%s: OpenGL %d.%d on %s without GL_ARB_direct_state_access",
			   label, ctx->gl_major, ctx->gl_minor, ctx->renderer);
		return false;
	}
	glGetIntegerv(GL_MAX_SHADER_STORAGE_BUFFER_BINDINGS, &ctx->max_ssbo_bindings);
	glGetIntegerv(GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS, &ctx->max_texture_units);
	glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &ctx->max_texels);
	glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &ctx->max_ssbo_bytes);
	glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 1, &ctx->max_groups_y);
	return gl_check("gpu_create");
}

/*
 * Initialize @d and make a core context current on it, 4.5 if it can be had
 * (direct state access is core there), else 4.3. On failure nothing is left
 * behind and the reason is appended to @err.
 */
static bool try_display(struct gpu_ctx *ctx, EGLDisplay d, const char *label, char *err,
			size_t errlen)
{
	if (d == EGL_NO_DISPLAY) {
		add_reason(err, errlen, "%s: no display (%s)", label, egl_error_name(eglGetError()));
		return false;
	}
	/* Only an initialized display answers EGL_VENDOR. */
	bool was_initialized = eglQueryString(d, EGL_VENDOR) != NULL;
	EGLint major = 0, minor = 0;
	if (!eglInitialize(d, &major, &minor)) {
		add_reason(err, errlen, "%s: eglInitialize failed (%s)", label,
			   egl_error_name(eglGetError()));
		return false;
	}
	const char *ext = eglQueryString(d, EGL_EXTENSIONS);
	bool egl15 = major > 1 || (major == 1 && minor >= 5);
	EGLContext c = EGL_NO_CONTEXT;
	if (!egl15 && !has_word(ext, "EGL_KHR_create_context")) {
		add_reason(err, errlen, "%s: EGL %d.%d without EGL_KHR_create_context", label, major, minor);
		goto fail;
	}
	if (!has_word(ext, "EGL_KHR_surfaceless_context")) {
		add_reason(err, errlen, "%s: no EGL_KHR_surfaceless_context", label);
		goto fail;
	}
	EGLConfig config = EGL_NO_CONFIG_KHR;
	if (!has_word(ext, "EGL_KHR_no_config_context") && !has_word(ext, "EGL_MESA_configless_context")) {
		/* Any OpenGL-capable config will do: nothing is ever drawn to a surface. */
		static const EGLint want[] = {
			EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_DONT_CARE, EGL_NONE,
		};
		EGLint n = 0;
		if (!eglChooseConfig(d, want, &config, 1, &n) || n < 1) {
			add_reason(err, errlen, "%s: no EGL_KHR_no_config_context and no OpenGL config",
				   label);
			goto fail;
		}
	}
	if (!eglBindAPI(EGL_OPENGL_API)) {
		add_reason(err, errlen, "%s: eglBindAPI(EGL_OPENGL_API) failed (%s)", label,
			   egl_error_name(eglGetError()));
		goto fail;
	}
	static const EGLint versions[][2] = { { 4, 5 }, { 4, 3 } };
	EGLint cerr = EGL_SUCCESS;
	for (size_t i = 0; i < 2 && c == EGL_NO_CONTEXT; i++) {
		const EGLint attribs[] = {
			EGL_CONTEXT_MAJOR_VERSION, versions[i][0],
			EGL_CONTEXT_MINOR_VERSION, versions[i][1],
			EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
			EGL_NONE,
		};
		c = eglCreateContext(d, config, EGL_NO_CONTEXT, attribs);
		if (c == EGL_NO_CONTEXT)
			cerr = eglGetError();
	}
	if (c == EGL_NO_CONTEXT) {
		add_reason(err, errlen, "%s: no OpenGL 4.5 or 4.3 core context (%s)", label,
			   egl_error_name(cerr));
		goto fail;
	}
	if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
		add_reason(err, errlen, "%s: eglMakeCurrent without a surface failed (%s)", label,
			   egl_error_name(eglGetError()));
		goto fail;
	}
	ctx->display = d;
	ctx->context = c;
	if (!check_gl(ctx, label, err, errlen)) {
		eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
		ctx->display = EGL_NO_DISPLAY;
		ctx->context = EGL_NO_CONTEXT;
		goto fail;
	}
	return true;

fail:
	if (c != EGL_NO_CONTEXT)
		eglDestroyContext(d, c);
	if (!was_initialized)
		eglTerminate(d);
	return false;
}

/*
 * The device platform enumerates GPUs (and Mesa's software device). Try the
 * hardware devices first so that a machine with both uses its GPU whatever
 * order the vendors come in.
 */
static bool try_devices(struct gpu_ctx *ctx, const char *client, char *err, size_t errlen)
{
	PFNEGLQUERYDEVICESEXTPROC query_devices =
		(PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
	PFNEGLQUERYDEVICESTRINGEXTPROC query_string = NULL;
	if (has_word(client, "EGL_EXT_device_query") || has_word(client, "EGL_EXT_device_base"))
		query_string = (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
	if (!query_devices) {
		add_reason(err, errlen, "device platform: no eglQueryDevicesEXT");
		return false;
	}
	enum { MAX_DEVICES = 32 };
	EGLDeviceEXT devices[MAX_DEVICES];
	EGLint n = 0;
	if (!query_devices(MAX_DEVICES, devices, &n) || n <= 0) {
		add_reason(err, errlen, "device platform: no devices (%s)", egl_error_name(eglGetError()));
		return false;
	}
	for (int pass = 0; pass < 2; pass++) {
		for (EGLint i = 0; i < n; i++) {
			const char *dext = query_string ? query_string(devices[i], EGL_EXTENSIONS) : NULL;
			bool software = has_word(dext, "EGL_MESA_device_software");
			if (software != (pass == 1))
				continue;
			char label[64];
			snprintf(label, sizeof(label), "EGL device %d%s", (int)i, software ? " (software)" : "");
			EGLDisplay d = eglGetPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL);
			if (try_display(ctx, d, label, err, errlen)) {
				ctx->software = software;
				return true;
			}
		}
	}
	return false;
}

struct gpu_ctx *gpu_create(char *err, size_t errlen)
{
	char scratch[512];
	if (!err || !errlen) {
		err = scratch;
		errlen = sizeof(scratch);
	}
	err[0] = '\0';
	struct gpu_ctx *ctx = calloc(1, sizeof(*ctx));
	if (!ctx) {
		snprintf(err, errlen, "out of memory");
		return NULL;
	}
	ctx->display = EGL_NO_DISPLAY;
	ctx->context = EGL_NO_CONTEXT;
	ctx->nbuckets = 16;
	ctx->buckets = calloc(ctx->nbuckets, sizeof(*ctx->buckets));
	if (!ctx->buckets) {
		free(ctx);
		snprintf(err, errlen, "out of memory");
		return NULL;
	}

	/* Client extensions (EGL 1.5 or EGL_EXT_client_extensions) list the platforms. */
	const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
	bool ok = false;
	if (!client) {
		add_reason(err, errlen, "EGL lists no client extensions (%s): no headless platform",
			   egl_error_name(eglGetError()));
	} else {
		if (has_word(client, "EGL_EXT_platform_device"))
			ok = try_devices(ctx, client, err, errlen);
		else
			add_reason(err, errlen, "no EGL_EXT_platform_device");
		if (!ok && has_word(client, "EGL_MESA_platform_surfaceless"))
			ok = try_display(ctx, eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA,
								    EGL_DEFAULT_DISPLAY, NULL),
					 "surfaceless platform", err, errlen);
		else if (!ok)
			add_reason(err, errlen, "no EGL_MESA_platform_surfaceless");
	}
	if (!ok) {
		free(ctx->buckets);
		free(ctx);
		return NULL;
	}
	if (err[0])
		rl_log(RL_LOG_INFO, "GPU: skipped before a context was made: %s", err);
	err[0] = '\0';

	ctx->software = ctx->software || is_software_renderer(ctx->renderer);
	glGetIntegerv(GL_NUM_PROGRAM_BINARY_FORMATS, &ctx->nbinary_formats);
	gl_check("GL_NUM_PROGRAM_BINARY_FORMATS");
	ctx->cache_dir = rl_cache_dir("gl");
	if (ctx->software)
		rl_log(RL_LOG_WARN, "GPU: OpenGL %d.%d renders in SOFTWARE on '%s': no GPU was found, "
		       "GPU work runs on the CPU and is many times slower", ctx->gl_major,
		       ctx->gl_minor, ctx->renderer);
	else
		rl_log(RL_LOG_INFO, "GPU: OpenGL %d.%d core on '%s'", ctx->gl_major, ctx->gl_minor,
		       ctx->renderer);
	return ctx;
}

static void program_free(struct gpu_program *p, bool current)
{
	if (current)
		glDeleteProgram(p->name);
	for (uint32_t i = 0; i < p->nslots; i++)
		free(p->slots[i].name);
	free(p->slots);
	free(p->source);
	free(p);
}

static void buffer_free(struct gpu_buffer *b, bool current)
{
	if (current) {
		if (b->texture)
			glDeleteTextures(1, &b->texture);
		if (b->texture4)
			glDeleteTextures(1, &b->texture4);
		glDeleteBuffers(1, &b->name);
	}
	free(b);
}

void gpu_destroy(struct gpu_ctx *ctx)
{
	if (!ctx)
		return;
	/* GL objects can only be deleted with their context current: make it
	 * current for the deletes, then give the thread back what it had. */
	EGLDisplay prev_display = eglGetCurrentDisplay();
	EGLContext prev_context = eglGetCurrentContext();
	EGLSurface prev_draw = eglGetCurrentSurface(EGL_DRAW);
	EGLSurface prev_read = eglGetCurrentSurface(EGL_READ);
	bool current = prev_context == ctx->context ||
		eglMakeCurrent(ctx->display, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx->context);
	if (!current)
		rl_log(RL_LOG_WARN, "gpu_destroy: the context is current on another thread; its GL "
		       "objects go with the context");

	for (uint32_t i = 0; i < ctx->nbuckets; i++) {
		struct gpu_program *p = ctx->buckets[i];
		while (p) {
			struct gpu_program *next = p->next;
			program_free(p, current);
			p = next;
		}
	}
	free(ctx->buckets);
	while (ctx->buffers) {
		struct gpu_buffer *b = ctx->buffers;
		ctx->buffers = b->next;
		buffer_free(b, current);
	}

	if (current) {
		if (prev_context != EGL_NO_CONTEXT && prev_context != ctx->context)
			eglMakeCurrent(prev_display, prev_draw, prev_read, prev_context);
		else
			eglMakeCurrent(ctx->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
	}
	/* The display stays initialized (see "Displays are never terminated"). */
	eglDestroyContext(ctx->display, ctx->context);
	free(ctx->cache_dir);
	free(ctx);
}

const char *gpu_renderer(const struct gpu_ctx *ctx)
{
	return ctx ? ctx->renderer : "";
}

bool gpu_is_software(const struct gpu_ctx *ctx)
{
	return ctx && ctx->software;
}

/* ---- programs ---- */

/* The source with 1-based line numbers, as compile errors refer to them. */
static void print_numbered(FILE *log, const char *source)
{
	unsigned line = 1;
	for (const char *p = source; *p; line++) {
		const char *eol = strchr(p, '\n');
		size_t len = eol ? (size_t)(eol - p) : strlen(p);
		size_t shown = len && p[len - 1] == '\r' ? len - 1 : len;
		fprintf(log, "%5u| %.*s\n", line, (int)(shown < INT_MAX ? shown : INT_MAX), p);
		p += len + (eol != NULL);
	}
}

static void report_failure(FILE *log, const char *what, const char *info, const char *source)
{
	fprintf(log, "gpu: the compute shader failed to %s:\n", what);
	if (info && info[0]) {
		size_t n = strlen(info);
		fprintf(log, "%s%s", info, info[n - 1] == '\n' ? "" : "\n");
	} else {
		fprintf(log, "(the driver gave no message)\n");
	}
	fprintf(log, "gpu: source:\n");
	print_numbered(log, source);
	fflush(log);
}

static char *shader_info_log(GLuint shader)
{
	GLint n = 0;
	glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &n);
	char *s = malloc(n > 0 ? (size_t)n + 1 : 1);
	if (!s)
		return NULL;
	s[0] = '\0';
	if (n > 0) {
		glGetShaderInfoLog(shader, n, NULL, s);
		s[n] = '\0';
	}
	return s;
}

static char *program_info_log(GLuint program)
{
	GLint n = 0;
	glGetProgramiv(program, GL_INFO_LOG_LENGTH, &n);
	char *s = malloc(n > 0 ? (size_t)n + 1 : 1);
	if (!s)
		return NULL;
	s[0] = '\0';
	if (n > 0) {
		glGetProgramInfoLog(program, n, NULL, s);
		s[n] = '\0';
	}
	return s;
}

static GLuint compile_and_link(const char *source, size_t len, FILE *log, bool retrievable)
{
	GLuint shader = glCreateShader(GL_COMPUTE_SHADER);
	if (!shader) {
		gl_check("glCreateShader(GL_COMPUTE_SHADER)");
		fprintf(log, "gpu: cannot create a compute shader\n");
		return 0;
	}
	const GLchar *text = source;
	GLint text_len = (GLint)len;
	glShaderSource(shader, 1, &text, &text_len);
	glCompileShader(shader);
	GLint ok = GL_FALSE;
	glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
	if (!ok) {
		char *info = shader_info_log(shader);
		report_failure(log, "compile", info, source);
		free(info);
		glDeleteShader(shader);
		return 0;
	}
	GLuint program = glCreateProgram();
	if (!program) {
		gl_check("glCreateProgram");
		glDeleteShader(shader);
		return 0;
	}
	glAttachShader(program, shader);
	if (retrievable)
		glProgramParameteri(program, GL_PROGRAM_BINARY_RETRIEVABLE_HINT, GL_TRUE);
	glLinkProgram(program);
	glDetachShader(program, shader);
	glDeleteShader(shader);
	glGetProgramiv(program, GL_LINK_STATUS, &ok);
	if (!ok) {
		char *info = program_info_log(program);
		report_failure(log, "link", info, source);
		free(info);
		glDeleteProgram(program);
		return 0;
	}
	return program;
}

static bool cache_grow(struct gpu_ctx *ctx)
{
	uint32_t n = ctx->nbuckets * 2;
	struct gpu_program **b = calloc(n, sizeof(*b));
	if (!b)
		return false;
	for (uint32_t i = 0; i < ctx->nbuckets; i++) {
		struct gpu_program *p = ctx->buckets[i];
		while (p) {
			struct gpu_program *next = p->next;
			uint32_t k = (uint32_t)(p->hash & (n - 1));
			p->next = b[k];
			b[k] = p;
			p = next;
		}
	}
	free(ctx->buckets);
	ctx->buckets = b;
	ctx->nbuckets = n;
	return true;
}

/* ---- programs kept on disk ---- */

/*
 * A compiled program is kept as DIR/KEY.glprog, KEY a hash of everything its
 * binary depends on: the source (which names the shader sources, dynamic set
 * and generator version it came from), the driver (vendor, renderer, GL
 * version) and relight's version. The file holds a magic, the binary's
 * format and length, a hash of the binary, then the binary; an entry that
 * fails any check, or that the driver refuses, is deleted and recompiled.
 */
#define BIN_MAGIC "RLGLPRG1"
#define BIN_HEADER 56  /* magic 8, format 4, length 4, binary hash 32, reserved 8 */
#define BIN_MAX (256u << 20)

static char *binary_path(const struct gpu_ctx *ctx, const char *source, size_t len)
{
	struct rl_hash128 h;
	rl_hash128_init(&h);
	rl_hash128_str(&h, BIN_MAGIC);
	rl_hash128_str(&h, RELIGHT_VERSION);
	rl_hash128_str(&h, (const char *)glGetString(GL_VENDOR));
	rl_hash128_str(&h, (const char *)glGetString(GL_RENDERER));
	rl_hash128_str(&h, (const char *)glGetString(GL_VERSION));
	rl_hash128_add(&h, source, len);
	char key[33];
	rl_hash128_hex(&h, key);
	size_t n = strlen(ctx->cache_dir) + sizeof(key) + 16;
	char *path = malloc(n);
	if (path)
		snprintf(path, n, "%s/%s.glprog", ctx->cache_dir, key);
	return path;
}

static void binary_hash(const void *data, size_t len, char out[33])
{
	struct rl_hash128 h;
	rl_hash128_init(&h);
	rl_hash128_add(&h, data, len);
	rl_hash128_hex(&h, out);
}

static uint32_t get_u32(const unsigned char *p)
{
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_u32(unsigned char *p, uint32_t v)
{
	for (int i = 0; i < 4; i++)
		p[i] = (unsigned char)(v >> (8 * i));
}

/* The program kept at @path, or 0 (a bad entry is removed). */
static GLuint load_binary(const char *path)
{
	size_t n = 0;
	char err[256] = "";
	unsigned char *d = (unsigned char *)rl_read_file(path, BIN_MAX, &n, err, sizeof(err));
	if (!d)
		return 0;
	GLuint program = 0;
	uint32_t len = n >= BIN_HEADER ? get_u32(d + 12) : 0;
	char want[33], have[33];
	bool valid = n >= BIN_HEADER && !memcmp(d, BIN_MAGIC, 8) && len == n - BIN_HEADER && len;
	if (valid) {
		memcpy(want, d + 16, 32);
		want[32] = '\0';
		binary_hash(d + BIN_HEADER, len, have);
		valid = !strcmp(want, have);
	}
	if (valid) {
		program = glCreateProgram();
		glProgramBinary(program, (GLenum)get_u32(d + 8), d + BIN_HEADER, (GLsizei)len);
		GLint ok = GL_FALSE;
		glGetProgramiv(program, GL_LINK_STATUS, &ok);
		gl_drain();
		if (!ok) {
			glDeleteProgram(program);
			program = 0;
		}
	}
	free(d);
	if (!program) {
		rl_log(RL_LOG_INFO, "gpu: dropping the unusable program cache entry %s", path);
		unlink(path);
	}
	return program;
}

/* Keep @program's binary at @path; failures only cost a later compile. */
static void store_binary(const char *path, GLuint program)
{
	GLint len = 0;
	glGetProgramiv(program, GL_PROGRAM_BINARY_LENGTH, &len);
	if (len <= 0 || (uint32_t)len > BIN_MAX - BIN_HEADER) {
		gl_drain();
		return;
	}
	unsigned char *d = malloc((size_t)len + BIN_HEADER);
	if (!d)
		return;
	GLenum format = 0;
	GLsizei got = 0;
	glGetProgramBinary(program, len, &got, &format, d + BIN_HEADER);
	if (got > 0 && got <= len) {
		memset(d, 0, BIN_HEADER);
		memcpy(d, BIN_MAGIC, 8);
		put_u32(d + 8, (uint32_t)format);
		put_u32(d + 12, (uint32_t)got);
		char hash[33];
		binary_hash(d + BIN_HEADER, (size_t)got, hash);
		memcpy(d + 16, hash, 32);
		char err[512];
		if (!rl_write_file_atomic(path, d, (size_t)got + BIN_HEADER, err, sizeof(err)))
			rl_log(RL_LOG_INFO, "gpu: cannot keep a compiled program: %s", err);
	}
	gl_drain();
	free(d);
}

void gpu_set_program_cache(struct gpu_ctx *ctx, const char *dir)
{
	free(ctx->cache_dir);
	ctx->cache_dir = NULL;
	if (dir && *dir && rl_mkdir_p(dir)) {
		size_t n = strlen(dir) + 1;
		ctx->cache_dir = malloc(n);
		if (ctx->cache_dir)
			memcpy(ctx->cache_dir, dir, n);
	}
}

void gpu_program_stats(const struct gpu_ctx *ctx, unsigned *disk_hits, unsigned *compiled)
{
	if (disk_hits)
		*disk_hits = ctx->disk_hits;
	if (compiled)
		*compiled = ctx->compiled;
}

struct gpu_program *gpu_program(struct gpu_ctx *ctx, const char *source, FILE *log)
{
	if (!log)
		log = stderr;
	if (!ctx || !source) {
		rl_log(RL_LOG_ERROR, "gpu_program: %s is NULL", ctx ? "source" : "ctx");
		return NULL;
	}
	size_t len = strlen(source);
	uint64_t h = hash_bytes(source, len);
	for (struct gpu_program *p = ctx->buckets[h & (ctx->nbuckets - 1)]; p; p = p->next)
		if (p->hash == h && !strcmp(p->source, source))
			return p;

	if (!is_current(ctx, __func__))
		return NULL;
	if (len > INT_MAX) {
		fprintf(log, "gpu: a shader source of %zu bytes is too long\n", len);
		return NULL;
	}
	if (ctx->nprograms >= ctx->nbuckets / 4 * 3 && !cache_grow(ctx)) {
		rl_log(RL_LOG_ERROR, "gpu_program: out of memory");
		return NULL;
	}
	struct gpu_program *p = calloc(1, sizeof(*p));
	char *copy = dup_string(source);
	if (!p || !copy) {
		rl_log(RL_LOG_ERROR, "gpu_program: out of memory");
		free(p);
		free(copy);
		return NULL;
	}
	gl_drain();
	bool keep = ctx->cache_dir && ctx->nbinary_formats > 0;
	char *path = keep ? binary_path(ctx, source, len) : NULL;
	GLuint name = path ? load_binary(path) : 0;
	if (name) {
		ctx->disk_hits++;
	} else {
		name = compile_and_link(source, len, log, path != NULL);
		if (name) {
			ctx->compiled++;
			if (path)
				store_binary(path, name);
		}
	}
	free(path);
	if (!name) {
		free(p);
		free(copy);
		return NULL;
	}
	glGetProgramiv(name, GL_COMPUTE_WORK_GROUP_SIZE, p->local_size);
	gl_check("gpu_program");
	p->ctx = ctx;
	p->hash = h;
	p->source = copy;
	p->name = name;
	uint32_t k = (uint32_t)(h & (ctx->nbuckets - 1));
	p->next = ctx->buckets[k];
	ctx->buckets[k] = p;
	ctx->nprograms++;
	return p;
}

/* ---- uniforms ---- */

/*
 * The type and remaining array length of the uniform @name. An element of an
 * array ("a[3]") is described by its array's resource: strip the subscript,
 * query the array, and count from the element on.
 */
static bool uniform_type(GLuint program, const char *name, GLenum *type, GLint *count)
{
	size_t n = strlen(name);
	const char *lb = strrchr(name, '[');
	GLint sub = 0;
	char *base = NULL;
	if (lb && n > 2 && name[n - 1] == ']' && lb + 1 < name + n - 1) {
		long k = 0;
		const char *q = lb + 1;
		for (; *q >= '0' && *q <= '9' && k <= INT_MAX; q++)
			k = k * 10 + (*q - '0');
		if (q == name + n - 1 && k <= INT_MAX) {
			sub = (GLint)k;
			base = malloc((size_t)(lb - name) + 1);
			if (!base)
				return false;
			memcpy(base, name, (size_t)(lb - name));
			base[lb - name] = '\0';
		}
	}
	GLuint index = glGetProgramResourceIndex(program, GL_UNIFORM, base ? base : name);
	free(base);
	if (index == GL_INVALID_INDEX)
		return false;
	const GLenum props[2] = { GL_TYPE, GL_ARRAY_SIZE };
	GLint values[2] = { 0, 0 };
	glGetProgramResourceiv(program, GL_UNIFORM, index, 2, props, 2, NULL, values);
	*type = (GLenum)values[0];
	*count = values[1] - sub;
	return *count > 0;
}

static bool slots_grow(struct gpu_program *p)
{
	uint32_t n = p->nslots ? p->nslots * 2 : 16;
	struct uniform_slot *s = calloc(n, sizeof(*s));
	if (!s)
		return false;
	for (uint32_t i = 0; i < p->nslots; i++) {
		if (!p->slots[i].name)
			continue;
		uint32_t k = (uint32_t)(p->slots[i].hash & (n - 1));
		while (s[k].name)
			k = (k + 1) & (n - 1);
		s[k] = p->slots[i];
	}
	free(p->slots);
	p->slots = s;
	p->nslots = n;
	return true;
}

/* The cached lookup of @name (absent names are cached too); NULL on no memory. */
static const struct uniform_slot *uniform_find(struct gpu_program *p, const char *name)
{
	uint64_t h = hash_bytes(name, strlen(name));
	if (p->nslots) {
		for (uint32_t k = (uint32_t)(h & (p->nslots - 1)); p->slots[k].name;
		     k = (k + 1) & (p->nslots - 1))
			if (p->slots[k].hash == h && !strcmp(p->slots[k].name, name))
				return &p->slots[k];
	}
	if ((p->nused + 1) * 4 > p->nslots * 3 && !slots_grow(p))
		return NULL;
	struct uniform_slot u = { .hash = h, .location = -1 };
	if (!(u.name = dup_string(name)))
		return NULL;
	u.location = glGetUniformLocation(p->name, name);
	if (u.location >= 0 && !uniform_type(p->name, name, &u.type, &u.count))
		u.location = -1;
	uint32_t k = (uint32_t)(h & (p->nslots - 1));
	while (p->slots[k].name)
		k = (k + 1) & (p->nslots - 1);
	p->slots[k] = u;
	p->nused++;
	return &p->slots[k];
}

static const struct uniform_slot *uniform_lookup(struct gpu_program *p, const char *name,
						 const char *fn)
{
	if (!p || !name) {
		rl_log(RL_LOG_ERROR, "%s: %s is NULL", fn, p ? "name" : "program");
		return NULL;
	}
	if (!is_current(p->ctx, fn))
		return NULL;
	const struct uniform_slot *u = uniform_find(p, name);
	if (!u)
		rl_log(RL_LOG_ERROR, "%s: out of memory", fn);
	return u && u->location >= 0 ? u : NULL;
}

bool gpu_uniform_float(struct gpu_program *p, const char *name, const float *v, int n)
{
	if (!v || n < 1) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_float: no values for '%s'", name ? name : "");
		return false;
	}
	const struct uniform_slot *u = uniform_lookup(p, name, __func__);
	if (!u)
		return false;
	int comps;
	switch (u->type) {
	case GL_FLOAT: comps = 1; break;
	case GL_FLOAT_VEC2: comps = 2; break;
	case GL_FLOAT_VEC3: comps = 3; break;
	case GL_FLOAT_VEC4: comps = 4; break;
	default:
		rl_log(RL_LOG_ERROR, "gpu_uniform_float: '%s' is not a float or vec2/3/4 (GL type 0x%04x)",
		       name, (unsigned)u->type);
		return false;
	}
	if (n % comps || n / comps > u->count) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_float: %d floats do not fit '%s' (%d x %d)", n, name,
		       u->count, comps);
		return false;
	}
	GLsizei count = n / comps;
	switch (comps) {
	case 1: glProgramUniform1fv(p->name, u->location, count, v); break;
	case 2: glProgramUniform2fv(p->name, u->location, count, v); break;
	case 3: glProgramUniform3fv(p->name, u->location, count, v); break;
	default: glProgramUniform4fv(p->name, u->location, count, v); break;
	}
	return true;
}

static bool is_float_type(GLenum t)
{
	switch (t) {
	case GL_FLOAT: case GL_FLOAT_VEC2: case GL_FLOAT_VEC3: case GL_FLOAT_VEC4:
	case GL_DOUBLE: case GL_DOUBLE_VEC2: case GL_DOUBLE_VEC3: case GL_DOUBLE_VEC4:
	case GL_FLOAT_MAT2: case GL_FLOAT_MAT3: case GL_FLOAT_MAT4:
	case GL_FLOAT_MAT2x3: case GL_FLOAT_MAT2x4: case GL_FLOAT_MAT3x2:
	case GL_FLOAT_MAT3x4: case GL_FLOAT_MAT4x2: case GL_FLOAT_MAT4x3:
	case GL_DOUBLE_MAT2: case GL_DOUBLE_MAT3: case GL_DOUBLE_MAT4:
	case GL_DOUBLE_MAT2x3: case GL_DOUBLE_MAT2x4: case GL_DOUBLE_MAT3x2:
	case GL_DOUBLE_MAT3x4: case GL_DOUBLE_MAT4x2: case GL_DOUBLE_MAT4x3:
	case GL_INT_VEC2: case GL_INT_VEC3: case GL_INT_VEC4:
	case GL_UNSIGNED_INT_VEC2: case GL_UNSIGNED_INT_VEC3: case GL_UNSIGNED_INT_VEC4:
	case GL_BOOL_VEC2: case GL_BOOL_VEC3: case GL_BOOL_VEC4:
		return true;
	default:
		return false;
	}
}

bool gpu_uniform_int(struct gpu_program *p, const char *name, int v)
{
	const struct uniform_slot *u = uniform_lookup(p, name, __func__);
	if (!u)
		return false;
	if (u->type == GL_UNSIGNED_INT) {
		if (v < 0) {
			rl_log(RL_LOG_ERROR, "gpu_uniform_int: %d for the uint '%s'", v, name);
			return false;
		}
		glProgramUniform1ui(p->name, u->location, (GLuint)v);
		return true;
	}
	if (is_float_type(u->type)) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_int: '%s' is not an int, uint, bool or sampler "
		       "(GL type 0x%04x)", name, (unsigned)u->type);
		return false;
	}
	/* int, bool, and the opaque types (samplers, images) whose value is a unit. */
	gl_drain();
	glProgramUniform1i(p->name, u->location, v);
	return gl_check("gpu_uniform_int");
}

bool gpu_uniform_ints(struct gpu_program *p, const char *name, const int *v, int n)
{
	if (!v || n < 1) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_ints: no values for '%s'", name ? name : "");
		return false;
	}
	const struct uniform_slot *u = uniform_lookup(p, name, __func__);
	if (!u)
		return false;
	if ((u->type != GL_INT && u->type != GL_INT_VEC4) ||
	    (u->type == GL_INT_VEC4 && n % 4)) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_ints: %d ints do not fit '%s' (GL type 0x%04x)", n,
		       name, (unsigned)u->type);
		return false;
	}
	/* the compiler may keep only the elements the program reads: set those */
	if (u->type == GL_INT_VEC4)
		glProgramUniform4iv(p->name, u->location, n / 4 < u->count ? n / 4 : u->count, v);
	else
		glProgramUniform1iv(p->name, u->location, n < u->count ? n : u->count, v);
	return true;
}

bool gpu_uniform_mat4(struct gpu_program *p, const char *name, const float m[16])
{
	if (!m) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_mat4: no matrix for '%s'", name ? name : "");
		return false;
	}
	const struct uniform_slot *u = uniform_lookup(p, name, __func__);
	if (!u)
		return false;
	if (u->type != GL_FLOAT_MAT4) {
		rl_log(RL_LOG_ERROR, "gpu_uniform_mat4: '%s' is not a mat4 (GL type 0x%04x)", name,
		       (unsigned)u->type);
		return false;
	}
	/* As given, untransposed: m[4 * c + r] is GLSL's column c, row r. */
	glProgramUniformMatrix4fv(p->name, u->location, 1, GL_FALSE, m);
	return true;
}

/* ---- buffers ---- */

struct gpu_buffer *gpu_buffer_create(struct gpu_ctx *ctx, size_t bytes, const void *data)
{
	if (!ctx) {
		rl_log(RL_LOG_ERROR, "gpu_buffer_create: ctx is NULL");
		return NULL;
	}
	if (bytes > (size_t)PTRDIFF_MAX) {
		rl_log(RL_LOG_ERROR, "gpu_buffer_create: %zu bytes is too large", bytes);
		return NULL;
	}
	if (!is_current(ctx, __func__))
		return NULL;
	struct gpu_buffer *b = calloc(1, sizeof(*b));
	if (!b) {
		rl_log(RL_LOG_ERROR, "gpu_buffer_create: out of memory");
		return NULL;
	}
	gl_drain();
	glCreateBuffers(1, &b->name);
	glNamedBufferData(b->name, (GLsizeiptr)bytes, data, GL_DYNAMIC_DRAW);
	if (!b->name || !gl_check("gpu_buffer_create")) {
		rl_log(RL_LOG_ERROR, "gpu_buffer_create: no buffer of %zu bytes", bytes);
		if (b->name)
			glDeleteBuffers(1, &b->name);
		free(b);
		return NULL;
	}
	b->ctx = ctx;
	b->bytes = bytes;
	b->next = ctx->buffers;
	if (ctx->buffers)
		ctx->buffers->prev = b;
	ctx->buffers = b;
	return b;
}

void gpu_buffer_destroy(struct gpu_buffer *b)
{
	if (!b)
		return;
	struct gpu_ctx *ctx = b->ctx;
	if (b->prev)
		b->prev->next = b->next;
	else
		ctx->buffers = b->next;
	if (b->next)
		b->next->prev = b->prev;
	buffer_free(b, is_current(ctx, __func__));
}

static bool range_ok(const struct gpu_buffer *b, size_t offset, size_t bytes, const void *data,
		     const char *fn)
{
	if (!b || !data) {
		rl_log(RL_LOG_ERROR, "%s: %s is NULL", fn, b ? "data" : "buffer");
		return false;
	}
	if (offset > b->bytes || bytes > b->bytes - offset) {
		rl_log(RL_LOG_ERROR, "%s: bytes [%zu, +%zu) outside a buffer of %zu", fn, offset, bytes,
		       b->bytes);
		return false;
	}
	return is_current(b->ctx, fn);
}

bool gpu_buffer_write(struct gpu_buffer *b, size_t offset, size_t bytes, const void *data)
{
	if (!range_ok(b, offset, bytes, data, __func__))
		return false;
	if (!bytes)
		return true;
	gl_drain();
	glNamedBufferSubData(b->name, (GLintptr)offset, (GLsizeiptr)bytes, data);
	return gl_check("gpu_buffer_write");
}

bool gpu_buffer_read(struct gpu_buffer *b, size_t offset, size_t bytes, void *out)
{
	if (!range_ok(b, offset, bytes, out, __func__))
		return false;
	if (!bytes)
		return true;
	gl_drain();
	glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
	glGetNamedBufferSubData(b->name, (GLintptr)offset, (GLsizeiptr)bytes, out);
	return gl_check("gpu_buffer_read");
}

/* ---- dispatch ---- */

static bool bind(struct gpu_ctx *ctx, const struct gpu_binding *bd, uint32_t i)
{
	struct gpu_buffer *b = bd->buffer;
	if (!b || b->ctx != ctx) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: binding %u has %s", i,
		       b ? "a buffer of another context" : "no buffer");
		return false;
	}
	if (bd->ssbo) {
		if (bd->unit >= (uint32_t)ctx->max_ssbo_bindings) {
			rl_log(RL_LOG_ERROR, "gpu_dispatch: SSBO binding %u (the limit is %d)", bd->unit,
			       ctx->max_ssbo_bindings);
			return false;
		}
		if ((uint64_t)b->bytes > (uint64_t)ctx->max_ssbo_bytes) {
			rl_log(RL_LOG_ERROR, "gpu_dispatch: a %zu-byte SSBO at binding %u exceeds the "
			       "limit of %lld bytes", b->bytes, bd->unit, (long long)ctx->max_ssbo_bytes);
			return false;
		}
		glBindBufferBase(GL_SHADER_STORAGE_BUFFER, bd->unit, b->name);
		return true;
	}
	if (bd->unit >= (uint32_t)ctx->max_texture_units) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: texture unit %u (the limit is %d)", bd->unit,
		       ctx->max_texture_units);
		return false;
	}
	size_t texel = bd->rgba ? 16 : 4;
	if (b->bytes / texel > (size_t)ctx->max_texels) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: %zu texels at texture unit %u exceed the buffer "
		       "texture limit of %d", b->bytes / texel, bd->unit, ctx->max_texels);
		return false;
	}
	GLuint *tex = bd->rgba ? &b->texture4 : &b->texture;
	if (!*tex) {
		glCreateTextures(GL_TEXTURE_BUFFER, 1, tex);
		glTextureBuffer(*tex, bd->rgba ? GL_RGBA32F : GL_R32F, b->name);
		if (!*tex || !gl_check("gpu_dispatch: buffer texture"))
			return false;
	}
	glBindTextureUnit(bd->unit, *tex);
	return true;
}

bool gpu_dispatch(struct gpu_ctx *ctx, struct gpu_program *p, const struct gpu_binding *b,
		  uint32_t nb, uint32_t n)
{
	if (!ctx || !p || (nb && !b)) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: %s is NULL", !ctx ? "ctx" : !p ? "program" : "bindings");
		return false;
	}
	if (p->ctx != ctx) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: the program belongs to another context");
		return false;
	}
	if (p->local_size[0] != LOCAL_SIZE || p->local_size[1] != 1 || p->local_size[2] != 1) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: the program's local size is %dx%dx%d, not %dx1x1",
		       p->local_size[0], p->local_size[1], p->local_size[2], LOCAL_SIZE);
		return false;
	}
	/*
	 * At most 65535 groups in x, the rest in y, with x spread evenly over the
	 * rows so that no more than a row's worth of groups is wasted. The
	 * shader's index x + y * 64 * groups_x must stay within 32 bits.
	 */
	uint64_t groups = ((uint64_t)n + LOCAL_SIZE - 1) / LOCAL_SIZE;
	uint64_t gy = (groups + MAX_GROUPS_X - 1) / MAX_GROUPS_X;
	if (gy < 1)
		gy = 1;
	uint64_t gx = (groups + gy - 1) / gy;
	if (gx * gy * LOCAL_SIZE > (uint64_t)UINT32_MAX + 1 || gy > (uint64_t)ctx->max_groups_y) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: %u invocations do not fit a 32-bit index", n);
		return false;
	}
	if (!is_current(ctx, __func__))
		return false;
	gl_drain();
	for (uint32_t i = 0; i < nb; i++)
		if (!bind(ctx, &b[i], i))
			return false;

	const struct uniform_slot *count = uniform_find(p, "u_count");
	if (!count) {
		rl_log(RL_LOG_ERROR, "gpu_dispatch: out of memory");
		return false;
	}
	if (count->location >= 0) {
		if (count->type == GL_UNSIGNED_INT) {
			glProgramUniform1ui(p->name, count->location, n);
		} else if (count->type == GL_INT && n <= (uint32_t)INT32_MAX) {
			glProgramUniform1i(p->name, count->location, (GLint)n);
		} else {
			rl_log(RL_LOG_ERROR, "gpu_dispatch: u_count (GL type 0x%04x) cannot hold %u",
			       (unsigned)count->type, n);
			return false;
		}
	}
	if (n) {
		glUseProgram(p->name);
		glDispatchCompute((GLuint)gx, (GLuint)gy, 1);
		glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
	}
	return gl_check("gpu_dispatch");
}

bool gpu_finish(struct gpu_ctx *ctx)
{
	if (!ctx || !is_current(ctx, __func__))
		return false;
	glFinish();
	return gl_check("gpu_finish");
}

/* ---- offline validation ---- */

static bool write_file(const char *path, const char *text)
{
	int fd = open(path, O_WRONLY | O_CREAT | O_EXCL, 0600);
	if (fd < 0)
		return false;
	size_t len = strlen(text), done = 0;
	while (done < len) {
		ssize_t w = write(fd, text + done, len - done);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0) {
			close(fd);
			return false;
		}
		done += (size_t)w;
	}
	return close(fd) == 0;
}

static void copy_file(FILE *log, const char *path)
{
	FILE *f = fopen(path, "r");
	if (!f)
		return;
	char buf[4096];
	size_t n;
	while ((n = fread(buf, 1, sizeof(buf), f)) > 0)
		fwrite(buf, 1, n, log);
	fclose(f);
	fflush(log);
}

/* Wait for @pid at most @seconds, then kill it; false when it was killed. */
static bool wait_child(pid_t pid, int *status, int seconds)
{
	struct timespec start, now;
	clock_gettime(CLOCK_MONOTONIC, &start);
	for (;;) {
		pid_t r = waitpid(pid, status, WNOHANG);
		if (r == pid)
			return true;
		if (r < 0 && errno != EINTR)
			return false;
		clock_gettime(CLOCK_MONOTONIC, &now);
		if (now.tv_sec - start.tv_sec >= seconds) {
			kill(pid, SIGKILL);
			while (waitpid(pid, status, 0) < 0 && errno == EINTR)
				;
			return false;
		}
		const struct timespec nap = { 0, 1000000 };
		nanosleep(&nap, NULL);
	}
}

int gpu_validate_glsl(const char *source, FILE *log)
{
	if (!log)
		log = stderr;
	if (!source) {
		fprintf(log, "gpu: no GLSL source to validate\n");
		return 0;
	}
	/* A private directory: the validator picks the stage from the .comp suffix. */
	const char *tmp = getenv("TMPDIR");
	if (!tmp || !tmp[0])
		tmp = "/tmp";
	char dir[PATH_MAX], shader[PATH_MAX + 32], output[PATH_MAX + 32];
	int k = snprintf(dir, sizeof(dir), "%s/relight-glsl-XXXXXX", tmp);
	if (k < 0 || (size_t)k + 16 >= sizeof(dir) || !mkdtemp(dir)) {
		fprintf(log, "gpu: no temporary directory under %s for glslangValidator\n", tmp);
		return -1;
	}
	snprintf(shader, sizeof(shader), "%s/shader.comp", dir);
	snprintf(output, sizeof(output), "%s/messages.txt", dir);

	int result = -1;
	posix_spawn_file_actions_t fa;
	bool have_fa = false;
	if (!write_file(shader, source)) {
		fprintf(log, "gpu: cannot write %s\n", shader);
		goto done;
	}
	if (posix_spawn_file_actions_init(&fa) != 0)
		goto done;
	have_fa = true;
	if (posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0) ||
	    posix_spawn_file_actions_addopen(&fa, 1, output, O_WRONLY | O_CREAT | O_TRUNC, 0600) ||
	    posix_spawn_file_actions_adddup2(&fa, 1, 2))
		goto done;
	char *argv[] = { "glslangValidator", shader, NULL };
	pid_t pid;
	int rc = posix_spawnp(&pid, "glslangValidator", &fa, NULL, argv, environ);
	if (rc != 0) {
		if (rc != ENOENT)
			fprintf(log, "gpu: cannot run glslangValidator: %s\n", strerror(rc));
		goto done;
	}
	int status = 0;
	if (!wait_child(pid, &status, 60)) {
		fprintf(log, "gpu: glslangValidator did not finish\n");
		goto done;
	}
	if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
		result = 1;
	} else if (WIFEXITED(status) && WEXITSTATUS(status) == 127) {
		/* The shell convention for "not found", from an exec that failed late. */
		result = -1;
	} else {
		copy_file(log, output);
		result = 0;
	}

done:
	if (have_fa)
		posix_spawn_file_actions_destroy(&fa);
	unlink(output);
	unlink(shader);
	rmdir(dir);
	return result;
}

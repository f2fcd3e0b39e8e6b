/* What the end-to-end rendering tests share: see render_scene.h. */
#include "render_scene.h"
#include "reyes.h"
#include "ri.h"
#include "config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

char tmpdir[256];
char diag_text[8192];
bool failure_expected;

bool scene_dir_create(const char *prefix)
{
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/%s-XXXXXX", prefix);
	if (!mkdtemp(tmpdir)) {
		perror("mkdtemp");
		return false;
	}
	return true;
}

void scene_dir_remove(void)
{
	if (getenv("RELIGHT_KEEP_TMP"))
		return;
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", tmpdir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", tmpdir);
}

const char *tmp_path(const char *name)
{
	static char buf[4][512];
	static int k;
	char *b = buf[k++ & 3];
	snprintf(b, 512, "%s/%s", tmpdir, name);
	return b;
}

bool scene_write_file(const char *name, const char *text)
{
	FILE *f = fopen(tmp_path(name), "w");
	if (!f)
		return false;
	fputs(text, f);
	return fclose(f) == 0;
}

static bool on_frame(void *user, const struct reyes_scene *scene)
{
	struct reyes_render_opts ro = { .threads = 2, .diag = user };
	return reyes_render(scene, &ro, NULL);
}

bool render(const char *rib, const char *out, struct reyes_image *im)
{
	const char *path = tmp_path("scene.rib");
	if (!scene_write_file("scene.rib", rib))
		return false;
	char *dbuf = NULL;
	size_t dlen = 0;
	FILE *diag = open_memstream(&dbuf, &dlen);
	if (!diag)
		return false;
	struct reyes_ri_opts o = {
		.default_shader_path = RELIGHT_SOURCE_SHADER_DIR,
		.frame = on_frame,
		.user = diag,
		.diag = diag,
	};
	int nerr = 0;
	bool ok = chdir(tmpdir) == 0 && reyes_ri_read(path, &o, &nerr) && nerr == 0;
	fclose(diag);
	snprintf(diag_text, sizeof(diag_text), "%s", dbuf ? dbuf : "");
	free(dbuf);
	if (!ok) {
		if (!failure_expected)
			fprintf(stderr, "render failed (%d errors):\n%s", nerr, diag_text);
		return false;
	}
	return reyes_image_read_exr(tmp_path(out), im, NULL);
}

int channel(const struct reyes_image *im, const char *name)
{
	for (uint32_t c = 0; c < im->nchannels; c++)
		if (!strcmp(im->channel_names[c], name))
			return (int)c;
	return -1;
}

float px(const struct reyes_image *im, int c, uint32_t x, uint32_t y)
{
	return im->data[((size_t)y * im->width + x) * im->nchannels + (size_t)c];
}

double disk_pixel(double cx, double cy, double rad, uint32_t x, uint32_t y)
{
	int n = 256, in = 0;
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double sx = x + (i + 0.5) / n - cx, sy = y + (j + 0.5) / n - cy;
			in += sx * sx + sy * sy <= rad * rad;
		}
	return (double)in / (n * n);
}

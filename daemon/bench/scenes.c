/* The benchmarks' generated scenes. */
#include "scenes.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

void bench_street_light_params(int k, int ring, float spot_intensity, struct bench_light *out)
{
	memset(out, 0, sizeof(*out));
	out->color[0] = out->color[1] = out->color[2] = 1.0f;
	if (k <= 1) {
		*out = (struct bench_light){ .shader = "spotlight", .intensity = spot_intensity,
					     .from = { 1, 6, 2 }, .to = { 0, 0, 5 },
					     .color = { 1, 1, 1 } };
	} else if (k == 2) {
		out->shader = "ambientlight";
		out->intensity = 0.03f;
	} else if (k == 3) {
		*out = (struct bench_light){ .shader = "distantlight", .intensity = 0.3f,
					     .from = { 0, 1, 0 }, .to = { 0.3f, 0, 0.4f },
					     .color = { 1, 1, 1 } };
	} else {
		/* rounded as the RIB prints them, so a shot and its RIB agree */
		double a = 2.0 * 3.14159265 * k / (ring > 0 ? ring : 1);
		out->shader = "pointlight";
		out->intensity = 0.6f;
		out->from[0] = (float)(round(6 * cos(a) * 1e3) / 1e3);
		out->from[1] = (float)(1.5 + k % 3);
		out->from[2] = (float)(round((5 + 6 * sin(a)) * 1e3) / 1e3);
		out->color[0] = 0.6f + 0.4f * (float)(k % 2);
		out->color[1] = 0.7f;
		out->color[2] = 0.6f + 0.4f * (float)(k % 3 == 0);
	}
}

void bench_street_light(int k, int ring, float spot_intensity, char *buf, size_t size)
{
	struct bench_light l;
	bench_street_light_params(k, ring, spot_intensity, &l);
	if (k <= 1)
		snprintf(buf, size, "LightSource \"spotlight\" 1 \"intensity\" %g \"from\" [1 6 2]"
			 " \"to\" [0 0 5] \"coneangle\" 0.6 \"conedeltaangle\" 0.1",
			 (double)spot_intensity);
	else if (k == 2)
		snprintf(buf, size, "LightSource \"ambientlight\" 2 \"intensity\" 0.03");
	else if (k == 3)
		snprintf(buf, size, "LightSource \"distantlight\" 3 \"intensity\" 0.3 \"from\""
			 " [0 1 0] \"to\" [0.3 0 0.4]");
	else
		snprintf(buf, size, "LightSource \"pointlight\" %d \"intensity\" 0.6 \"from\" [%.3f"
			 " %.3f %.3f] \"lightcolor\" [%.2f %.2f %.2f]", k, (double)l.from[0],
			 (double)l.from[1], (double)l.from[2], (double)l.color[0],
			 (double)l.color[1], (double)l.color[2]);
}

bool bench_street_rib(const char *path, int width, int height, int nlights, int ring,
		      float spot_intensity, char *err, size_t errlen)
{
	FILE *f = fopen(path, "w");
	if (!f) {
		snprintf(err, errlen, "%s: %s", path, strerror(errno));
		return false;
	}
	fprintf(f, "Format %d %d 1\nPixelSamples 2 2\nShadingRate 1\n"
		"Projection \"perspective\" \"fov\" 40\n"
		"Display \"street.exr\" \"file\" \"rgba\"\n"
		"Translate 0 -1.2 9\nRotate -12 1 0 0\nWorldBegin\n", width, height);
	char req[512];
	for (int k = 1; k <= nlights; k++) {
		bench_street_light(k, ring, spot_intensity, req, sizeof(req));
		fprintf(f, "  %s\n", req);
	}
	fprintf(f, "  AttributeBegin\n    Surface \"matte\"\n    Color [0.6 0.6 0.55]\n"
		"    Polygon \"P\" [-12 0 -4  -12 0 20  12 0 20  12 0 -4]\n  AttributeEnd\n");
	static const char *const surf[3] = { "plastic\" \"roughness\" 0.12",
					     "metal\" \"roughness\" 0.2", "matte\"" };
	for (int z = 0; z < 4; z++)
		for (int x = 0; x < 8; x++)
			fprintf(f, "  AttributeBegin\n    Surface \"%s\n    Color [%.2f %.2f %.2f]\n"
				"    Translate %.2f 0.5 %.2f\n    Sphere 0.5 -0.5 0.5 360\n"
				"  AttributeEnd\n", surf[(x + z) % 3], 0.3 + 0.1 * (x % 5),
				0.3 + 0.15 * (z % 3), 0.4 + 0.07 * ((x + z) % 4), -4.2 + 1.2 * x,
				1.5 + 2.2 * z);
	fprintf(f, "WorldEnd\n");
	bool bad = ferror(f) != 0;
	if (fclose(f) != 0 || bad) {
		snprintf(err, errlen, "%s: cannot write", path);
		return false;
	}
	return true;
}

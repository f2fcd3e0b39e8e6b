/*
 * relight's OpenEXR reader and writer (C API, daemon/render/exr.c) checked
 * against OpenEXR's own C++ implementation: files relight writes, in half and
 * float, must read back through Imf::InputFile with every channel's values in
 * place; files the C++ library writes must read back through relight's reader.
 * A round trip through one implementation cannot catch a channel mix-up that
 * the writer and the reader make symmetrically; this can.
 */
extern "C" {
#include "texture.h"
}

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <half.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

static int failures, checks;

#define CHECK(c) \
	do { \
		checks++; \
		if (!(c)) { \
			failures++; \
			fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #c); \
		} \
	} while (0)

/* A distinct value for each (pixel, channel), exact in half. */
static float value(unsigned x, unsigned y, unsigned c)
{
	return (float)(c + 1) * 0.25f + (float)x * 0.0625f + (float)y * 0.5f;
}

/*
 * @N channels from "R", "G", "B", "A", "Z", "diffuse.R": 4 (an all-half RGBA
 * image, the layout OpenEXR 3.1 has special-cased packers for), 3 (RGB) and
 * 6 (mixed half and float).
 */
static void relight_writes(const char *dir, bool half, unsigned N)
{
	const char *names[6] = { "R", "G", "B", "A", "Z", "diffuse.R" };
	const unsigned W = 7, H = 5;
	struct reyes_image im;
	CHECK(reyes_image_init(&im, W, H, N, names));
	for (unsigned y = 0; y < H; y++)
		for (unsigned x = 0; x < W; x++)
			for (unsigned c = 0; c < N; c++)
				im.data[(y * W + x) * N + c] = value(x, y, c);
	std::string path = std::string(dir) + (half ? "/half" : "/float") + std::to_string(N) + ".exr";
	CHECK(reyes_image_write_exr(path.c_str(), &im, half, NULL));
	reyes_image_finish(&im);

	Imf::InputFile in(path.c_str());
	Imath::Box2i dw = in.header().dataWindow();
	CHECK(dw.max.x - dw.min.x + 1 == (int)W && dw.max.y - dw.min.y + 1 == (int)H);
	std::vector<float> planes(N * W * H);
	Imf::FrameBuffer fb;
	for (unsigned c = 0; c < N; c++) {
		CHECK(in.header().channels().findChannel(names[c]) != nullptr);
		fb.insert(names[c], Imf::Slice(Imf::FLOAT, (char *)&planes[c * W * H], sizeof(float),
					      sizeof(float) * W));
	}
	in.setFrameBuffer(fb);
	in.readPixels(dw.min.y, dw.max.y);
	for (unsigned c = 0; c < N; c++)
		for (unsigned y = 0; y < H; y++)
			for (unsigned x = 0; x < W; x++) {
				float got = planes[c * W * H + y * W + x], want = value(x, y, c);
				if (got != want) {
					fprintf(stderr, "%s: channel %s at (%u,%u) = %g, expected %g\n",
						path.c_str(), names[c], x, y, got, want);
					failures++;
					return;
				}
			}
	checks++;
}

static void cpp_writes(const char *dir, Imf::PixelType type, unsigned N)
{
	const char *names[5] = { "R", "G", "B", "A", "Z" };
	const unsigned W = 6, H = 4;
	std::string path = std::string(dir) + (type == Imf::HALF ? "/cpp_half" : "/cpp_float") +
			   std::to_string(N) + ".exr";
	{
		Imf::Header hd((int)W, (int)H);
		for (unsigned c = 0; c < N; c++)
			hd.channels().insert(names[c], Imf::Channel(c == 4 ? Imf::FLOAT : type));
		std::vector<float> planes(N * W * H);
		std::vector<half> hplanes(N * W * H);
		Imf::FrameBuffer fb;
		for (unsigned c = 0; c < N; c++)
			for (unsigned k = 0; k < W * H; k++) {
				planes[c * W * H + k] = value(k % W, k / W, c);
				hplanes[c * W * H + k] = half(planes[c * W * H + k]);
			}
		for (unsigned c = 0; c < N; c++) {
			if (c != 4 && type == Imf::HALF)
				fb.insert(names[c], Imf::Slice(Imf::HALF, (char *)&hplanes[c * W * H],
							      sizeof(half), sizeof(half) * W));
			else
				fb.insert(names[c], Imf::Slice(Imf::FLOAT, (char *)&planes[c * W * H],
							      sizeof(float), sizeof(float) * W));
		}
		Imf::OutputFile out(path.c_str(), hd);
		out.setFrameBuffer(fb);
		out.writePixels((int)H);
	}
	struct reyes_image im = {};
	CHECK(reyes_image_read_exr(path.c_str(), &im, NULL));
	CHECK(im.width == W && im.height == H && im.nchannels == N);
	for (unsigned c = 0; c < im.nchannels; c++) {
		int want_c = -1;
		for (unsigned k = 0; k < N; k++)
			if (!strcmp(im.channel_names[c], names[k]))
				want_c = (int)k;
		CHECK(want_c >= 0);
		for (unsigned y = 0; want_c >= 0 && y < H; y++)
			for (unsigned x = 0; x < W; x++) {
				float got = im.data[(y * W + x) * im.nchannels + c];
				float want = value(x, y, (unsigned)want_c);
				if (got != want) {
					fprintf(stderr, "%s: channel %s at (%u,%u) read as %g, written %g\n",
						path.c_str(), im.channel_names[c], x, y, got, want);
					failures++;
					y = H;
					break;
				}
			}
	}
	reyes_image_finish(&im);
}

int main()
{
	char dir[] = "/tmp/relight-exr-oracle-XXXXXX";
	if (!mkdtemp(dir))
		return 1;
	for (unsigned n : { 3u, 4u, 6u }) {
		relight_writes(dir, true, n);
		relight_writes(dir, false, n);
	}
	for (unsigned n : { 3u, 4u, 5u }) {
		cpp_writes(dir, Imf::HALF, n);
		cpp_writes(dir, Imf::FLOAT, n);
	}
	std::string cmd = std::string("rm -rf '") + dir + "'";
	if (system(cmd.c_str()) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
	printf("%d checks, %d failed\n", checks, failures);
	return failures ? 1 : 0;
}

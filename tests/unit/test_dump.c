/* test_dump.c - table dumps: EXR round trip and orientation, PNG previews,
 * the JSON writer, and the error paths. */
#include <dirent.h>
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <openexr.h>
#include <png.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "dump.h"
#include "skymap.h"
#include "skyproto.h"
#include "test.h"

static char dir[4096];

static const char *in_dir(const char *name)
{
	static char path[4200];
	snprintf(path, sizeof(path), "%s/%s", dir, name);
	return path;
}

static bool same_bits(float a, float b)
{
	return memcmp(&a, &b, sizeof(a)) == 0;
}

static float bits_float(uint32_t u)
{
	float f;
	memcpy(&f, &u, sizeof(f));
	return f;
}

/* A 3-D f32 table whose R says where it is (i + 10 j + 100 k) and whose G,
 * B, A carry awkward values that must survive bit for bit. */
enum { W3 = 5, H3 = 7, D3 = 3 };	/* 21 scanlines: ZIP chunks of 16 cross slices */

static void fill_3d(float *t)
{
	static const uint32_t odd[] = {
		0x80000000u,	/* -0 */
		0x00000001u,	/* smallest subnormal */
		0x7f7fffffu,	/* largest finite */
		0xff800000u,	/* -inf */
		0x7fc01234u,	/* a NaN with a payload */
		0x3dcccccdu,	/* 0.1f */
	};
	for (int k = 0; k < D3; k++)
		for (int j = 0; j < H3; j++)
			for (int i = 0; i < W3; i++) {
				size_t n = ((size_t)(k * H3 + j) * W3 + i);
				float *p = t + n * 4;
				p[0] = (float)(i + 10 * j + 100 * k);
				p[1] = bits_float(odd[n % 6]);
				p[2] = -1.0f / (float)(n + 3);
				p[3] = (float)n * 0.25f;
			}
}

/* R of image scanline y straight from the file through the C core, to check
 * the orientation without trusting dump_read_exr's inverse mapping. Returns
 * 0 or -1. */
static int raw_scanline_r(const char *path, int y, float *ret_r, int width)
{
	exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
	exr_context_t ctx = NULL;
	exr_chunk_info_t cinfo;
	float buf[16 * 64];
	int ok = -1;

	if (width > 64 || exr_start_read(&ctx, path, NULL) != EXR_ERR_SUCCESS)
		return -1;
	if (exr_read_scanline_chunk_info(ctx, 0, y, &cinfo) == EXR_ERR_SUCCESS && cinfo.height <= 16 &&
	    exr_decoding_initialize(ctx, 0, &cinfo, &dec) == EXR_ERR_SUCCESS) {
		for (int c = 0; c < dec.channel_count; c++) {
			exr_coding_channel_info_t *ch = &dec.channels[c];
			bool r = strcmp(ch->channel_name, "R") == 0;
			ch->decode_to_ptr = r ? (uint8_t *)buf : NULL;
			ch->user_data_type = EXR_PIXEL_FLOAT;
			ch->user_bytes_per_element = 4;
			ch->user_pixel_stride = 4;
			ch->user_line_stride = 4 * width;
		}
		if (exr_decoding_choose_default_routines(ctx, 0, &dec) == EXR_ERR_SUCCESS &&
		    exr_decoding_run(ctx, 0, &dec) == EXR_ERR_SUCCESS) {
			memcpy(ret_r, buf + (y - cinfo.start_y) * width, sizeof(float) * width);
			ok = 0;
		}
		exr_decoding_destroy(ctx, &dec);
	}
	exr_finish(&ctx);
	return ok;
}

static void test_exr_3d_f32(void)
{
	static float t[W3 * H3 * D3 * 4];
	struct dump_table table = { "aerial", W3, H3, D3, SKY_FORMAT_RGBA32F, t, 0 };
	struct dump_exr_info info;
	const char *path = in_dir("aerial.exr");
	char err[256] = "";
	float *back = NULL, r[W3];
	size_t bad = 0;

	fill_3d(t);
	CHECK_EQ(dump_exr(path, &table, err, sizeof(err)), 0);
	if (err[0])
		FAIL("dump_exr: %s", err);
	if (dump_read_exr(path, &info, &back, err, sizeof(err)) != 0) {
		FAIL("dump_read_exr: %s", err);
		return;
	}
	CHECK(info.width == W3 && info.height == H3 && info.depth == D3);
	CHECK(strcmp(info.name, "aerial") == 0);
	CHECK_EQ(info.uv_mapping_version, SKYMAP_VERSION);
	for (size_t n = 0; n < sizeof(t) / sizeof(t[0]); n++)
		bad += !same_bits(back[n], t[n]);
	if (bad)
		FAIL("%zu of %zu floats differ after the round trip", bad, sizeof(t) / sizeof(t[0]));
	free(back);

	/* Scanline y holds row H-1-(y mod H) of slice y / H. */
	for (int y = 0; y < H3 * D3; y++) {
		int k = y / H3, j = H3 - 1 - y % H3;
		if (raw_scanline_r(path, y, r, W3) < 0) {
			FAIL("scanline %d unreadable", y);
			continue;
		}
		for (int i = 0; i < W3; i++)
			if (r[i] != (float)(i + 10 * j + 100 * k))
				FAIL("scanline %d x %d: R %g, want %d", y, i, r[i], i + 10 * j + 100 * k);
	}
}

/* Chunks on the edge of compressing: random bits with a few more zeros
 * from chunk to chunk (one more every 32 chunks of 16 scanlines), so that
 * ZIP's output crosses the chunk's raw size of 8 KiB, and some chunks
 * compress to exactly that size, which OpenEXRCore 3.1 kept compressed
 * and every reader then took for raw (dump_exr.c, exr_compress_or_keep;
 * with Debian 12's zlib, several of these). Every bit comes back. */
enum { WE = 32, CHUNK_LINES = 16, EDGE_CHUNKS = 1024 };

static void test_exr_edge_of_compression(void)
{
	size_t per_chunk = (size_t)WE * CHUNK_LINES * 4, n = per_chunk * EDGE_CHUNKS, bad = 0;
	float *t = malloc(n * sizeof(float)), *back = NULL;
	struct dump_table table = { "edge", WE, CHUNK_LINES * EDGE_CHUNKS, 1, SKY_FORMAT_RGBA32F, t, 0 };
	struct dump_exr_info info;
	const char *path = in_dir("edge.exr");
	uint64_t x = 88172645463325252ull;
	char err[256] = "";

	if (!t) {
		FAIL("out of memory");
		return;
	}
	for (size_t c = 0; c < EDGE_CHUNKS; c++)
		for (size_t i = 0; i < per_chunk; i++) {
			x ^= x << 13;
			x ^= x >> 7;
			x ^= x << 17;
			t[c * per_chunk + i] = i < 10 + c / 32 ? 0.0f : bits_float((uint32_t)x);
		}
	CHECK_EQ(dump_exr(path, &table, err, sizeof(err)), 0);
	if (dump_read_exr(path, &info, &back, err, sizeof(err)) != 0) {
		FAIL("dump_read_exr: %s", err);
		free(t);
		return;
	}
	for (size_t i = 0; i < n; i++)
		bad += !same_bits(back[i], t[i]);
	if (bad)
		FAIL("%zu of %zu floats differ after the round trip", bad, n);
	free(back);
	free(t);
}

/* binary16 in, float32 out, every value exact. */
static void test_exr_2d_f16(void)
{
	static const struct { uint16_t h; uint32_t f; } v[] = {
		{ 0x3c00, 0x3f800000 },	/* 1 */
		{ 0xc100, 0xc0200000 },	/* -2.5 */
		{ 0x0001, 0x33800000 },	/* 2^-24, smallest subnormal */
		{ 0x03ff, 0x387fc000 },	/* largest subnormal */
		{ 0x0400, 0x38800000 },	/* 2^-14 */
		{ 0x7bff, 0x477fe000 },	/* 65504 */
		{ 0x7c00, 0x7f800000 },	/* inf */
		{ 0x8000, 0x80000000 },	/* -0 */
		{ 0x3555, 0x3eaaa000 },	/* 0.333251953125 */
	};
	enum { W = 6, H = 4, N = W * H * 4, NV = sizeof(v) / sizeof(v[0]) };
	uint16_t t[N];
	struct dump_table table = { "transmittance", W, H, 1, SKY_FORMAT_RGBA16F, t, 0 };
	struct dump_exr_info info;
	const char *path = in_dir("transmittance.exr");
	char err[256] = "";
	float *back = NULL;
	int bad = 0;

	for (int n = 0; n < N; n++)
		t[n] = v[n % NV].h;
	CHECK_EQ(dump_exr(path, &table, err, sizeof(err)), 0);
	if (dump_read_exr(path, &info, &back, err, sizeof(err)) != 0) {
		FAIL("dump_read_exr: %s", err);
		return;
	}
	CHECK(info.width == W && info.height == H && info.depth == 1);
	CHECK(strcmp(info.name, "transmittance") == 0);

	/* The previews widen halves themselves: a 1x1 table's exposure is
	 * 1 / its luminance, the same from either format. */
	for (int n = 0; n < NV; n++) {
		uint16_t hs[4] = { v[n].h, v[n].h, v[n].h, v[n].h };
		float fv = bits_float(v[n].f), fs[4] = { fv, fv, fv, fv };
		struct dump_table th = { "h", 1, 1, 1, SKY_FORMAT_RGBA16F, hs, 0 };
		struct dump_table tf = { "f", 1, 1, 1, SKY_FORMAT_RGBA32F, fs, 0 };
		double eh = 0, ef = -1;
		CHECK(dump_auto_exposure(&th, &eh) == 0 && dump_auto_exposure(&tf, &ef) == 0);
		if (eh != ef)
			FAIL("half 0x%04x: exposure %.17g, float gives %.17g", v[n].h, eh, ef);
	}
	for (int n = 0; n < N; n++)
		bad += !same_bits(back[n], bits_float(v[n % NV].f));
	if (bad)
		FAIL("%d of %d half values did not widen exactly", bad, N);
	free(back);
}

/* Decode a PNG into 8-bit RGB; NULL on failure. */
static uint8_t *read_png(const char *path, uint32_t *ret_w, uint32_t *ret_h)
{
	png_image img;
	uint8_t *px;

	memset(&img, 0, sizeof(img));
	img.version = PNG_IMAGE_VERSION;
	if (!png_image_begin_read_from_file(&img, path))
		return NULL;
	img.format = PNG_FORMAT_RGB;
	px = malloc(PNG_IMAGE_SIZE(img));
	if (!px || !png_image_finish_read(&img, NULL, px, 0, NULL)) {
		png_image_free(&img);
		free(px);
		return NULL;
	}
	*ret_w = img.width;
	*ret_h = img.height;
	return px;
}

static int pixel_sum(const uint8_t *px, uint32_t w, uint32_t x, uint32_t y)
{
	const uint8_t *p = px + ((size_t)y * w + x) * 3;
	return p[0] + p[1] + p[2];
}

/* A grey ramp brightening with i, j and k: the preview must keep that order
 * in the documented orientation. */
static void test_png_orientation(void)
{
	static float t[W3 * H3 * D3 * 4];
	struct dump_table table = { "ramp", W3, H3, D3, SKY_FORMAT_RGBA32F, t, 0 };
	const char *path = in_dir("ramp.png");
	char err[256] = "";
	uint32_t w = 0, h = 0;
	uint8_t *px;
	double exposure = 0;

	for (size_t n = 0; n < W3 * H3 * D3; n++)
		for (int c = 0; c < 3; c++)
			t[n * 4 + c] = 0.01f * (float)(n + 1);
	/* The 99th percentile of 105 texels is texel 103, luminance 1.04. */
	CHECK_EQ(dump_auto_exposure(&table, &exposure), 0);
	CHECK(fabs(exposure * 1.04 - 1.0) < 1e-6);
	CHECK(dump_png(path, &table, NULL, err, sizeof(err)) == 0);
	px = read_png(path, &w, &h);
	if (!px) {
		FAIL("'%s' does not decode (%s)", path, err);
		return;
	}
	CHECK(w == W3 && h == H3 * D3);
	if (w != W3 || h != H3 * D3) {
		free(px);
		return;
	}
	/* 8 bits may merge neighbours; the ends of each run must differ. */
	for (uint32_t y = 0; y < h; y++) {
		for (uint32_t x = 1; x < w; x++)
			if (pixel_sum(px, w, x, y) < pixel_sum(px, w, x - 1, y))
				FAIL("row %u: pixel %u darker than its left neighbour", y, x);
		if (pixel_sum(px, w, w - 1, y) <= pixel_sum(px, w, 0, y))
			FAIL("row %u: right end not brighter than left", y);
		/* Down the image: darker inside a band (v up), brighter at a new band. */
		if (y + 1 < h) {
			bool band_end = (y + 1) % H3 == 0;
			int a = pixel_sum(px, w, w - 1, y), b = pixel_sum(px, w, w - 1, y + 1);
			if (band_end ? b <= a : b > a)
				FAIL("rows %u and %u in the wrong order (%d, %d)", y, y + 1, a, b);
		}
	}
	for (uint32_t k = 0; k < D3; k++)
		if (pixel_sum(px, w, 0, k * H3) <= pixel_sum(px, w, 0, k * H3 + H3 - 1))
			FAIL("band %u: top row (v = 1) not brighter than bottom row (v = 0)", k);
	/* v downward (the sky-view table's zenith up): each band upside down,
	 * the bands in the same order. */
	const struct dump_tonemap down = { .exposure = 0.0, .curve = DUMP_CURVE_ACES,
					   .rows = DUMP_ROWS_V_DOWN };
	uint32_t w2 = 0, h2 = 0;
	uint8_t *px2 = NULL;
	CHECK_EQ(dump_png(in_dir("ramp-down.png"), &table, &down, err, sizeof(err)), 0);
	px2 = read_png(in_dir("ramp-down.png"), &w2, &h2);
	CHECK(px2 && w2 == w && h2 == h);
	for (uint32_t y = 0; px2 && w2 == w && h2 == h && y < h; y++) {
		uint32_t mirror = y / H3 * H3 + (H3 - 1 - y % H3);
		if (memcmp(px2 + (size_t)y * w * 3, px + (size_t)mirror * w * 3, (size_t)w * 3) != 0)
			FAIL("v downward: row %u is not v upward's row %u", y, mirror);
	}
	free(px2);
	free(px);

	/* Half input, Reinhard, a fixed exposure and values no curve likes. */
	uint16_t ht[4 * 3 * 4];
	static const uint16_t odd[] = { 0x7c00, 0xfc00, 0x7e00, 0xbc00, 0x0000, 0x3c00 };
	for (size_t n = 0; n < sizeof(ht) / sizeof(ht[0]); n++)
		ht[n] = odd[n % 6];
	struct dump_table half = { "odd", 4, 3, 1, SKY_FORMAT_RGBA16F, ht, 0 };
	struct dump_tonemap tm = { .exposure = 2.0, .curve = DUMP_CURVE_REINHARD };
	path = in_dir("odd.png");
	CHECK_EQ(dump_png(path, &half, &tm, err, sizeof(err)), 0);
	px = read_png(path, &w, &h);
	CHECK(px && w == 4 && h == 3);
	free(px);
}

static const char *json_text(struct dump_json *j)
{
	const char *s = dump_json_buffer(j, NULL);
	return s ? s : "";
}

static void test_json(void)
{
	static const char want[] =
		"{\n"
		"  \"name\": \"say \\\"hi\\\" \\\\ \\n\\t\\r\\b\\f\\u0001\\u001f caf\xc3\xa9\",\n"
		"  \"k\\\"ey\": 0.10000000000000001,\n"
		"  \"list\": [\n"
		"    1,\n"
		"    -0,\n"
		"    1.0000000000000001e+300,\n"
		"    null,\n"
		"    18446744073709551615,\n"
		"    true,\n"
		"    false,\n"
		"    {},\n"
		"    []\n"
		"  ],\n"
		"  \"empty\": {}\n"
		"}\n";
	struct dump_json *j = dump_json_new_buffer();
	size_t len = 0;

	if (!j) {
		FAIL("dump_json_new_buffer");
		return;
	}
	dump_json_begin_object(j);
	dump_json_key(j, "name");
	dump_json_string(j, "say \"hi\" \\ \n\t\r\b\f\x01\x1f caf\xc3\xa9");
	dump_json_key(j, "k\"ey");
	dump_json_number(j, 0.1);
	dump_json_key(j, "list");
	dump_json_begin_array(j);
	dump_json_number(j, 1.0);
	dump_json_number(j, -0.0);
	dump_json_number(j, 1e300);
	dump_json_number(j, NAN);
	dump_json_uint(j, UINT64_MAX);
	dump_json_bool(j, true);
	dump_json_bool(j, false);
	dump_json_begin_object(j);
	dump_json_end_object(j);
	dump_json_begin_array(j);
	dump_json_end_array(j);
	dump_json_end_array(j);
	dump_json_key(j, "empty");
	dump_json_begin_object(j);
	dump_json_end_object(j);
	CHECK_EQ(dump_json_end_object(j), 0);
	CHECK_EQ(dump_json_finish(j), 0);
	CHECK(strcmp(json_text(j), want) == 0);
	CHECK(dump_json_buffer(j, &len) && len == strlen(want));
	if (strcmp(json_text(j), want) != 0)
		FAIL("got:\n%s", json_text(j));
	dump_json_free(j);

	/* The same through a FILE, whatever the process's numeric locale. */
	const char *path = in_dir("manifest.json");
	FILE *f = fopen(path, "we");
	char back[64] = "";
	bool comma = setlocale(LC_NUMERIC, "de_DE.UTF-8") != NULL;
	j = f ? dump_json_new_file(f) : NULL;
	CHECK(j && dump_json_buffer(j, NULL) == NULL);
	dump_json_begin_array(j);
	dump_json_number(j, 2.5);
	dump_json_end_array(j);
	CHECK_EQ(dump_json_finish(j), 0);
	dump_json_free(j);
	setlocale(LC_NUMERIC, "C");
	if (f)
		fclose(f);
	f = fopen(path, "re");
	CHECK(f && fread(back, 1, sizeof(back) - 1, f) > 0);
	CHECK(strcmp(back, "[\n  2.5\n]\n") == 0);
	if (f)
		fclose(f);
	if (!comma)
		printf("test_dump: no de_DE.UTF-8 locale here; the comma locale case ran in C\n");
}

/* Each misuse fails the writer, and the failure sticks. */
static void test_json_misuse(void)
{
	struct dump_json *j;

#define MISUSE(setup, bad)                                     \
	do {                                                   \
		j = dump_json_new_buffer();                    \
		setup;                                         \
		CHECK((bad) == -EINVAL);                       \
		CHECK(dump_json_finish(j) == -EINVAL);         \
		dump_json_free(j);                             \
	} while (0)

	MISUSE(dump_json_begin_array(j), dump_json_key(j, "k"));
	MISUSE(dump_json_begin_object(j), dump_json_uint(j, 1));
	MISUSE((dump_json_begin_object(j), dump_json_key(j, "k")), dump_json_key(j, "k2"));
	MISUSE((dump_json_begin_object(j), dump_json_key(j, "k")), dump_json_end_object(j));
	MISUSE(dump_json_begin_object(j), dump_json_end_array(j));
	MISUSE((void)0, dump_json_end_object(j));
	MISUSE(dump_json_uint(j, 1), dump_json_uint(j, 2));
	MISUSE(dump_json_begin_object(j), dump_json_finish(j));
	MISUSE((void)0, dump_json_finish(j));
	MISUSE(dump_json_begin_array(j), dump_json_string(j, NULL));
	MISUSE(for (int d = 0; d < 32; d++) dump_json_begin_array(j), dump_json_begin_array(j));
#undef MISUSE
	/* 32 levels are fine. */
	j = dump_json_new_buffer();
	for (int d = 0; d < 32; d++)
		dump_json_begin_array(j);
	for (int d = 0; d < 32; d++)
		dump_json_end_array(j);
	CHECK_EQ(dump_json_finish(j), 0);
	dump_json_free(j);
	CHECK(dump_json_new_file(NULL) == NULL);
	dump_json_free(NULL);
}

static void test_errors(void)
{
	float t[4] = { 1, 2, 3, 4 };
	struct dump_table table = { "one", 1, 1, 1, SKY_FORMAT_RGBA32F, t, 0 };
	struct dump_table bad = table;
	struct dump_exr_info info = { .width = 12345 };
	static float sentinel;
	float *back = &sentinel;
	const char *path = in_dir("missing/one.exr");
	char err[512];
	FILE *f;

	err[0] = '\0';
	CHECK_EQ(dump_exr(path, &table, err, sizeof(err)), -ENOENT);
	CHECK(strstr(err, path) != NULL);
	err[0] = '\0';
	CHECK(dump_png(in_dir("missing/one.png"), &table, NULL, err, sizeof(err)) == -ENOENT);
	CHECK(strstr(err, "missing/one.png") != NULL);
	err[0] = '\0';
	CHECK_EQ(dump_read_exr(path, &info, &back, err, sizeof(err)), -ENOENT);
	CHECK(strstr(err, path) != NULL);
	CHECK(info.width == 12345 && back == &sentinel);

	/* Not an EXR: refused with a message, outputs untouched, nothing printed. */
	path = in_dir("junk.exr");
	f = fopen(path, "we");
	CHECK(f && fputs("this is not an image\n", f) >= 0);
	if (f)
		fclose(f);
	err[0] = '\0';
	CHECK(dump_read_exr(path, &info, &back, err, sizeof(err)) < 0);
	CHECK(strstr(err, path) != NULL);
	CHECK(info.width == 12345 && back == &sentinel);

	bad.width = 0;
	CHECK_EQ(dump_exr(in_dir("bad.exr"), &bad, err, sizeof(err)), -EINVAL);
	CHECK(access(in_dir("bad.exr"), F_OK) != 0);
	bad = table;
	bad.format = 7;
	CHECK(dump_png(in_dir("bad.png"), &bad, NULL, err, sizeof(err)) == -EINVAL);
	bad = table;
	bad.texels = NULL;
	CHECK(dump_exr(in_dir("bad.exr"), &bad, NULL, 0) == -EINVAL);
	CHECK(dump_exr(NULL, &table, NULL, 0) == -EINVAL);
	struct dump_tonemap tm = { .exposure = NAN, .curve = DUMP_CURVE_ACES };
	CHECK_EQ(dump_png(in_dir("bad.png"), &table, &tm, err, sizeof(err)), -EINVAL);
	tm = (struct dump_tonemap){ .curve = DUMP_CURVE_ACES, .rows = (enum dump_rows)7 };
	CHECK_EQ(dump_png(in_dir("bad.png"), &table, &tm, err, sizeof(err)), -EINVAL);
}

static bool file_is(const char *path, const char *text)
{
	char buf[64] = "";
	FILE *f = fopen(path, "re");
	size_t n = f ? fread(buf, 1, sizeof(buf) - 1, f) : 0;

	if (f)
		fclose(f);
	return n == strlen(text) && memcmp(buf, text, n) == 0;
}

static int count_temporaries(void)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	int n = 0;

	while (d && (e = readdir(d)))
		n += strstr(e->d_name, ".tmp-") != NULL;
	if (d)
		closedir(d);
	return n;
}

/* A write that fails half way (here at the file size limit) keeps the old
 * file and leaves no temporary; a later good write replaces it. */
static void test_failed_write_keeps_old_file(void)
{
	enum { W = 64, H = 64 };
	static float t[W * H * 4];
	struct dump_table table = { "noise", W, H, 1, SKY_FORMAT_RGBA32F, t, 0 };
	struct rlimit old, small;
	char exr[4200], png[4200], err[512] = "";
	uint32_t x = 12345;
	float *back = NULL;
	struct dump_exr_info info;

	for (size_t n = 0; n < sizeof(t) / sizeof(t[0]); n++) {
		x = x * 1664525u + 1013904223u;	/* fixed seed: incompressible, reproducible */
		t[n] = (float)(x >> 8) / (float)(1 << 24);
	}
	snprintf(exr, sizeof(exr), "%s", in_dir("keep.exr"));
	snprintf(png, sizeof(png), "%s", in_dir("keep.png"));
	for (int i = 0; i < 2; i++) {
		FILE *f = fopen(i ? png : exr, "we");
		CHECK(f && fputs("previous", f) >= 0);
		if (f)
			fclose(f);
	}
	if (getrlimit(RLIMIT_FSIZE, &old) < 0) {
		FAIL("getrlimit: %s", strerror(errno));
		return;
	}
	small = old;
	small.rlim_cur = 1000;
	signal(SIGXFSZ, SIG_IGN);
	CHECK_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
	CHECK_EQ(dump_exr(exr, &table, err, sizeof(err)), -EFBIG);
	CHECK(strstr(err, exr) != NULL);
	CHECK(dump_png(png, &table, NULL, err, sizeof(err)) == -EFBIG);
	CHECK(strstr(err, png) != NULL);
	CHECK_EQ(setrlimit(RLIMIT_FSIZE, &old), 0);
	signal(SIGXFSZ, SIG_DFL);
	CHECK(file_is(exr, "previous") && file_is(png, "previous"));
	CHECK_EQ(count_temporaries(), 0);

	CHECK_EQ(dump_exr(exr, &table, err, sizeof(err)), 0);
	CHECK_EQ(dump_read_exr(exr, &info, &back, err, sizeof(err)), 0);
	CHECK(back && memcmp(back, t, sizeof(t)) == 0);
	free(back);
	CHECK_EQ(count_temporaries(), 0);
}

static void remove_dir(void)
{
	DIR *d = opendir(dir);
	struct dirent *e;

	if (!d)
		return;
	while ((e = readdir(d)))
		if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
			unlinkat(dirfd(d), e->d_name, 0);
	closedir(d);
	if (rmdir(dir) < 0)
		FAIL("rmdir '%s': %s", dir, strerror(errno));
}

int main(void)
{
	const char *tmp = getenv("TMPDIR");

	snprintf(dir, sizeof(dir), "%s/test_dump.XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	test_exr_3d_f32();
	test_exr_2d_f16();
	test_exr_edge_of_compression();
	test_png_orientation();
	test_json();
	test_json_misuse();
	test_errors();
	test_failed_write_keeps_old_file();
	remove_dir();
	return test_report("test_dump");
}

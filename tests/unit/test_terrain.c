/* test_terrain.c - the terrain height field: files the test writes itself
 * (16-bit, 8-bit, low-depth, grey with alpha and interlaced PNGs by
 * libpng, SKYTERRAIN16 raw files) read texel for texel with one hash; the
 * bound of 4096 texels a side and 40 MiB checked before decoding; every
 * refusal with its exact text naming the file; the cache that a changed
 * file defeats; the keys (a refused set keeps the last good field, what
 * each invalidates, the hash check a follower makes, a replication
 * message with a field); and proto/skyterrain.h's height, gradient and ray
 * against values worked by hand. */
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "skyterrain.h"
#define SKYTERRAIN_DOUBLE 1
#include "skyterrain.h"

#include "state.h"
#include "sync.h"
#include "terrain.h"
#include "terrain_png.h"
#include "test.h"

static char dir[256];

static const char *at(const char *name)
{
	static char buf[4][320];
	static int k;
	k = (k + 1) % 4;
	snprintf(buf[k], sizeof(buf[k]), "%s/%s", dir, name);
	return buf[k];
}

/* A pattern that uses all 16 bits and differs in every texel. */
static uint16_t *pattern(uint32_t w, uint32_t h, uint32_t salt)
{
	uint16_t *t = malloc(sizeof(uint16_t) * w * h);
	for (uint32_t j = 0; j < h; j++)
		for (uint32_t i = 0; i < w; i++)
			t[j * w + i] = (uint16_t)((i * 4099u + j * 257u + salt * 31u) * 2654435761u >> 16);
	return t;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- reading ---- */

static void check_same(const struct terrain *t, const uint16_t *want, uint32_t w, uint32_t h,
		       const char *what)
{
	CHECK_EQ(terrain_width(t), w);
	CHECK_EQ(terrain_height(t), h);
	if (memcmp(terrain_texels(t), want, sizeof(uint16_t) * w * h) != 0)
		FAIL("%s: the texels differ", what);
	CHECK_EQ(terrain_hash(t), terrain_hash_texels(want, w, h));
}

static void test_formats(void)
{
	enum { W = 37 };
	uint16_t *p = pattern(W, W, 1), *p8 = malloc(sizeof(uint16_t) * W * W);
	uint16_t *p1 = malloc(sizeof(uint16_t) * W * W);
	struct terrain *t = NULL;
	char err[256];

	for (int i = 0; i < W * W; i++) {
		p8[i] = (uint16_t)((p[i] >> 8) * 257u);		/* what 8 bits keep, widened */
		p1[i] = (p[i] >> 15) ? 65535 : 0;
	}
	CHECK(terrain_png_write(at("g16.png"), W, W, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	CHECK(terrain_load(at("g16.png"), &t, err, sizeof(err)) == 0);
	if (t)
		check_same(t, p, W, W, "16-bit grey");
	uint64_t hash16 = t ? terrain_hash(t) : 0;
	terrain_unref(t);

	struct { const char *name; int depth, type, interlace; const uint16_t *want; } cases[] = {
		{ "g16i.png", 16, PNG_COLOR_TYPE_GRAY, 1, p },
		{ "ga16.png", 16, PNG_COLOR_TYPE_GRAY_ALPHA, 0, p },
		{ "g8.png", 8, PNG_COLOR_TYPE_GRAY, 0, p8 },
		{ "ga8i.png", 8, PNG_COLOR_TYPE_GRAY_ALPHA, 1, p8 },
		{ "g1.png", 1, PNG_COLOR_TYPE_GRAY, 0, p1 },
	};
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		t = NULL;
		CHECK(terrain_png_write(at(cases[c].name), W, W, cases[c].depth, cases[c].type, p,
					cases[c].interlace, 0) == 0);
		if (terrain_load(at(cases[c].name), &t, err, sizeof(err)) < 0)
			FAIL("%s: %s", cases[c].name, err);
		else
			check_same(t, cases[c].want, W, W, cases[c].name);
		terrain_unref(t);
	}
	/* The raw file of the same heights: the same hash. */
	t = NULL;
	CHECK(terrain_raw_write(at("g16.raw"), W, W, p, 0) == 0);
	if (terrain_load(at("g16.raw"), &t, err, sizeof(err)) < 0)
		FAIL("raw: %s", err);
	else
		CHECK_EQ(terrain_hash(t), hash16);
	if (t)
		check_same(t, p, W, W, "raw");
	terrain_unref(t);
	free(p);
	free(p8);
	free(p1);
}

/* One refusal: the code and the exact text. */
static void refused(const char *path, int code, const char *want)
{
	struct terrain *t = NULL;
	char err[256] = "";
	int r = terrain_load(path, &t, err, sizeof(err));
	CHECK_EQ(r, code);
	if (strcmp(err, want) != 0)
		FAIL("'%s': got \"%s\", want \"%s\"", path, err, want);
	CHECK(t == NULL);
}

static void test_refusals(void)
{
	uint16_t *p = pattern(64, 64, 2);
	char want[512];

	snprintf(want, sizeof(want), "cannot read '%s': No such file or directory", at("none.png"));
	refused(at("none.png"), -EINVAL, want);
	snprintf(want, sizeof(want), "'%s' is not a regular file", dir);
	refused(dir, -EINVAL, want);
	/* A FIFO is refused without waiting for a writer. */
	CHECK(mkfifo(at("fifo"), 0600) == 0);
	snprintf(want, sizeof(want), "'%s' is not a regular file", at("fifo"));
	refused(at("fifo"), -EINVAL, want);
	FILE *f = fopen(at("notes.txt"), "w");
	fputs("not a height field\n", f);
	fclose(f);
	snprintf(want, sizeof(want), "'%s' is neither a PNG nor a SKYTERRAIN16 file", at("notes.txt"));
	refused(at("notes.txt"), -EINVAL, want);
	CHECK(terrain_png_write(at("rgb.png"), 8, 8, 8, PNG_COLOR_TYPE_RGB, p, 0, 0) == 0);
	snprintf(want, sizeof(want), "'%s' is a colour PNG; a height field is greyscale", at("rgb.png"));
	refused(at("rgb.png"), -EINVAL, want);
	CHECK(terrain_png_write(at("wide.png"), 64, 32, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	snprintf(want, sizeof(want), "'%s' is 64 x 32 texels; a height field is square", at("wide.png"));
	refused(at("wide.png"), -EINVAL, want);
	/* Too large, from the header alone: nothing of the image is there. */
	CHECK(terrain_png_write(at("big.png"), 4097, 4097, 16, PNG_COLOR_TYPE_GRAY, p, 0, 1) == 0);
	snprintf(want, sizeof(want), "'%s' is 4097 x 4097 texels, more than 4096 x 4096", at("big.png"));
	refused(at("big.png"), -EFBIG, want);
	CHECK(terrain_raw_write(at("big.raw"), 5000, 16, p, -(5000 * 16 * 2)) == 0);
	snprintf(want, sizeof(want), "'%s' is 5000 x 16 texels, more than 4096 x 4096", at("big.raw"));
	refused(at("big.raw"), -EFBIG, want);
	int fd = open(at("huge.raw"), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
	CHECK(fd >= 0 && ftruncate(fd, 41l << 20) == 0);
	close(fd);
	snprintf(want, sizeof(want), "'%s' is 42991616 bytes, more than 40 MiB", at("huge.raw"));
	refused(at("huge.raw"), -EFBIG, want);
	/* Cut short: libpng's own words follow the file's name. */
	CHECK(terrain_png_write(at("cut.png"), 64, 64, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	CHECK(terrain_file_cut(at("cut.png"), 200) == 0);
	struct terrain *t = NULL;
	char err[256];
	CHECK_EQ(terrain_load(at("cut.png"), &t, err, sizeof(err)), -EINVAL);
	snprintf(want, sizeof(want), "'%s': truncated or corrupt PNG (", at("cut.png"));
	if (strncmp(err, want, strlen(want)) != 0)
		FAIL("cut: got \"%s\"", err);
	printf("a PNG cut short: %s\n", err);
	CHECK(terrain_raw_write(at("short.raw"), 16, 16, p, -2) == 0);
	snprintf(want, sizeof(want), "'%s' holds 510 bytes of texels where 16 x 16 need 512", at("short.raw"));
	refused(at("short.raw"), -EINVAL, want);
	f = fopen(at("head.raw"), "w");
	fputs("SKYTERRAIN16 016 16\n", f);
	fclose(f);
	snprintf(want, sizeof(want), "'%s': the first line is not 'SKYTERRAIN16 <width> <height>'", at("head.raw"));
	refused(at("head.raw"), -EINVAL, want);
	refused("dem.png", -EINVAL, "'dem.png' is not an absolute path (skyd's directory is not the client's)");
	refused("/tmp/d\x01m.png", -EINVAL, "byte 6 of the path is 0x01, not printable ASCII");
	char longp[200];
	memset(longp, 'a', sizeof(longp) - 1);
	longp[0] = '/';
	longp[sizeof(longp) - 1] = 0;
	refused(longp, -EINVAL, "a path of 199 bytes, more than 127");
	free(p);
}

/* The largest field is read, and how long it takes is printed (the time
 * a `set terrain=` holds skyd's loop: docs/terrain.md). */
static void test_largest(void)
{
	enum { W = SKYTERRAIN_MAX_TEXELS };
	uint16_t *p = malloc(sizeof(uint16_t) * W * W);
	for (uint32_t j = 0; j < W; j++)
		for (uint32_t i = 0; i < W; i++)
			p[j * W + i] = (uint16_t)(32768 + 30000 * sin(i * 0.003) * cos(j * 0.002));
	struct terrain *t = NULL;
	char err[256];
	CHECK(terrain_png_write(at("max.png"), W, W, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	double t0 = now_s();
	CHECK(terrain_load(at("max.png"), &t, err, sizeof(err)) == 0);
	double t1 = now_s();
	if (t)
		check_same(t, p, W, W, "4096^2");
	struct stat st;
	stat(at("max.png"), &st);
	printf("4096 x 4096 16-bit PNG of %lld bytes read in %.0f ms\n", (long long)st.st_size,
	       1e3 * (t1 - t0));
	/* Again, from the cache: a stat. */
	struct terrain *u = NULL;
	t0 = now_s();
	CHECK(terrain_load(at("max.png"), &u, err, sizeof(err)) == 0);
	printf("the same again, from the cache: %.3f ms\n", 1e3 * (now_s() - t0));
	CHECK(u == t);
	terrain_unref(u);
	terrain_unref(t);
	unlink(at("max.png"));
	free(p);
}

/* The cache serves the same file again and notices a changed one. */
static void test_cache(void)
{
	uint16_t *a = pattern(16, 16, 3), *b = pattern(16, 16, 4);
	struct terrain *t1 = NULL, *t2 = NULL, *t3 = NULL;
	char err[256];

	CHECK(terrain_png_write(at("c.png"), 16, 16, 16, PNG_COLOR_TYPE_GRAY, a, 0, 0) == 0);
	CHECK(terrain_load(at("c.png"), &t1, err, sizeof(err)) == 0);
	CHECK(terrain_load(at("c.png"), &t2, err, sizeof(err)) == 0);
	CHECK(t1 && t1 == t2);
	CHECK(terrain_png_write(at("c.png"), 16, 16, 16, PNG_COLOR_TYPE_GRAY, b, 0, 0) == 0);
	/* A modification time of its own, whatever the file system's grain. */
	struct timespec ts[2] = { { 1000, 0 }, { 1000, 0 } };
	CHECK(utimensat(AT_FDCWD, at("c.png"), ts, 0) == 0);
	CHECK(terrain_load(at("c.png"), &t3, err, sizeof(err)) == 0);
	CHECK(t3 && t3 != t1);
	if (t3)
		CHECK_EQ(terrain_hash(t3), terrain_hash_texels(b, 16, 16));
	terrain_unref(t1);
	terrain_unref(t2);
	terrain_unref(t3);
	free(a);
	free(b);
}

/* ---- the keys ---- */

static int set(struct sky_state *s, const char *pair, uint32_t *dirty, char *err, size_t n)
{
	return state_set_pair(s, pair, dirty, err, n);
}

static void test_keys(void)
{
	struct sky_state s, before;
	char err[512], pair[400], buf[160], want[512];
	uint32_t dirty;
	uint16_t *p = pattern(32, 32, 5);
	const uint32_t terrain_bits = STATE_BIT(STATE_CLOUD_SHADOW) | STATE_BIT(STATE_SKYVIEW) |
				      STATE_BIT(STATE_AERIAL);

	state_default(&s);
	CHECK(state_get(&s, "terrain", buf, sizeof(buf)) == 0 && strcmp(buf, "none") == 0);
	CHECK(state_get(&s, "terrain_hash", buf, sizeof(buf)) == 0 && strcmp(buf, "none") == 0);
	/* Without a field the other keys change no table. */
	dirty = 0;
	CHECK(set(&s, "terrain_extent_km=20", &dirty, err, sizeof(err)) == 0 && dirty == 0);
	CHECK(set(&s, "terrain_height_m=3000", &dirty, err, sizeof(err)) == 0 && dirty == 0);
	CHECK(terrain_png_write(at("k.png"), 32, 32, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	snprintf(pair, sizeof(pair), "terrain=%s", at("k.png"));
	CHECK(set(&s, pair, &dirty, err, sizeof(err)) == 0);
	CHECK_EQ(dirty, terrain_bits);
	CHECK(state_get(&s, "terrain", buf, sizeof(buf)) == 0 && strcmp(buf, at("k.png")) == 0);
	char hash[32];
	snprintf(hash, sizeof(hash), "%016" PRIx64, terrain_hash_texels(p, 32, 32));
	CHECK(state_get(&s, "terrain_hash", buf, sizeof(buf)) == 0 && strcmp(buf, hash) == 0);
	CHECK(s.terrain.width == 32 && s.terrain.height == 32);
	dirty = 0;
	CHECK(set(&s, "terrain_extent_km=30", &dirty, err, sizeof(err)) == 0 && dirty == terrain_bits);

	/* A refused file: the state keeps the field it had. */
	before = s;
	snprintf(pair, sizeof(pair), "terrain=%s", at("none.png"));
	CHECK_EQ(set(&s, pair, NULL, err, sizeof(err)), -EINVAL);
	snprintf(want, sizeof(want), "terrain: cannot read '%s': No such file or directory", at("none.png"));
	if (strcmp(err, want) != 0)
		FAIL("got \"%s\"", err);
	CHECK(memcmp(&s, &before, sizeof(s)) == 0);
	snprintf(pair, sizeof(pair), "terrain=%s", at("big.png"));
	CHECK_EQ(set(&s, pair, NULL, err, sizeof(err)), -ERANGE);
	CHECK(memcmp(&s, &before, sizeof(s)) == 0);

	/* The hash: its own passes, another is refused naming the file. */
	snprintf(pair, sizeof(pair), "terrain_hash=%s", hash);
	CHECK(set(&s, pair, NULL, err, sizeof(err)) == 0);
	CHECK_EQ(set(&s, "terrain_hash=0123456789abcdef", NULL, err, sizeof(err)), -EINVAL);
	snprintf(want, sizeof(want), "terrain_hash: '%s' here holds %s, not 0123456789abcdef: every host needs the same file",
		 at("k.png"), hash);
	if (strcmp(err, want) != 0)
		FAIL("got \"%s\"", err);
	CHECK_EQ(set(&s, "terrain_hash=xyz", NULL, err, sizeof(err)), -EINVAL);
	CHECK(strcmp(err, "terrain_hash: 'xyz' is not none or 16 hexadecimal digits") == 0);

	/* White above the atmosphere's top is refused by validation. */
	struct sky_state low = s;
	CHECK(set(&low, "top_radius_km=6365", NULL, err, sizeof(err)) == 0);
	CHECK(set(&low, "terrain_height_m=6000", NULL, err, sizeof(err)) == 0);
	CHECK_EQ(state_validate(&low, 0, err, sizeof(err)), -ERANGE);
	printf("%s\n", err);

	/* Back from the state to the heights, and none again. */
	struct terrain *t = NULL;
	struct skyterrain v;
	CHECK(state_terrain_get(&s, &t, &v, err, sizeof(err)) == 0);
	CHECK(t && v.width == 32 && v.extent_km == 30.0 && v.height_km == 3.0);
	terrain_unref(t);
	dirty = 0;
	CHECK(set(&s, "terrain=none", &dirty, err, sizeof(err)) == 0 && dirty == terrain_bits);
	CHECK(state_get(&s, "terrain_hash", buf, sizeof(buf)) == 0 && strcmp(buf, "none") == 0);
	CHECK_EQ(state_terrain_get(&s, &t, &v, err, sizeof(err)), -ENOENT);
	dirty = 0;
	CHECK(set(&s, "terrain=", &dirty, err, sizeof(err)) == 0 && dirty == 0);
	free(p);
}

/* A state with a field travels as its keys; a follower whose file holds
 * other heights refuses it and says why. */
static void test_sync(void)
{
	static char msg[SYNC_MSG_MAX + 1];
	struct sky_state s, got;
	struct sync_msg_header h = { .generation = 3, .apply_time_ns = 1 }, hr;
	char err[256], why[320], pair[400];
	size_t len;
	uint16_t *p = pattern(24, 24, 6), *q = pattern(24, 24, 7);
	struct timespec ts;

	clock_gettime(CLOCK_REALTIME, &ts);
	h.apply_time_ns = (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
	snprintf(h.controller, sizeof(h.controller), "skyhost/4242/0123456789abcdef");
	state_default(&s);
	CHECK(terrain_png_write(at("s.png"), 24, 24, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	snprintf(pair, sizeof(pair), "terrain=%s", at("s.png"));
	CHECK(state_set_pair(&s, pair, NULL, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "terrain_extent_km=12.5", NULL, err, sizeof(err)) == 0);
	CHECK(sync_msg_encode(&s, &h, msg, sizeof(msg), &len) == 0);
	CHECK(strstr(msg, "\nterrain_hash=") != NULL);
	CHECK_EQ(sync_msg_decode(msg, len, &hr, &got, why, sizeof(why)), SYNC_DROP_NONE);
	CHECK(strcmp(got.terrain.path, s.terrain.path) == 0 && got.terrain.hash == s.terrain.hash &&
	      got.terrain.extent_km == 12.5);
	/* The file changes under the same path: this host now differs. */
	CHECK(terrain_png_write(at("s.png"), 24, 24, 16, PNG_COLOR_TYPE_GRAY, q, 0, 0) == 0);
	struct timespec mt[2] = { { 2000, 0 }, { 2000, 0 } };
	CHECK(utimensat(AT_FDCWD, at("s.png"), mt, 0) == 0);
	CHECK_EQ(sync_msg_decode(msg, len, &hr, &got, why, sizeof(why)), SYNC_DROP_RANGE);
	printf("a follower with another file: %s\n", why);
	CHECK(strstr(why, "terrain_hash: '") && strstr(why, "every host needs the same file"));
	unlink(at("s.png"));
	CHECK_EQ(sync_msg_decode(msg, len, &hr, &got, why, sizeof(why)), SYNC_DROP_RANGE);
	printf("a follower without the file: %s\n", why);
	CHECK(strstr(why, "terrain: cannot read '") != NULL);
	free(p);
	free(q);
}

/* ---- proto/skyterrain.h against hand values ---- */

static const uint16_t grid3[9] = { 0, 1000, 2000, 3000, 4000, 5000, 6000, 7000, 8000 };

static void test_height(void)
{
	/* 3 x 3 texels over 3 km: centres at -1, 0, 1 km east and 1, 0, -1
	 * km north (row 0); 65.535 km white, so a texel's value is metres. */
	struct skyterrain t = { .texels = grid3, .width = 3, .height = 3, .max_texel = 8000,
				.extent_km = 3.0, .height_km = 65.535 };
	struct { double x, y, want_m; } pts[] = {
		{ 0, 0, 4000 }, { -1, 1, 0 }, { 1, -1, 8000 }, { 0.5, 0.5, 3000 },
		{ -0.25, -0.75, 6000 }, { 1.4, 0, 5000 }, { -1.5, 1.5, 0 }, { 1.5, -1.5, 8000 },
		{ 0, 1.3, 1000 }, { 1.6, 0, 0 }, { 0, -1.51, 0 }, { -0.5, 0, 3500 },
	};
	for (size_t i = 0; i < sizeof(pts) / sizeof(pts[0]); i++) {
		double hd = skyterraind_height_km(&t, pts[i].x, pts[i].y) * 1e3;
		double hf = skyterrain_height_km(&t, (float)pts[i].x, (float)pts[i].y) * 1e3;
		if (fabs(hd - pts[i].want_m) > 1e-9 || fabs(hf - pts[i].want_m) > 2e-3)
			FAIL("height at (%g, %g): %.12g m (float %.7g), want %g", pts[i].x, pts[i].y, hd,
			     hf, pts[i].want_m);
	}
	/* The gradient inside a cell: 1 km per km east (1000 m over 1 km),
	 * -3 north (rows grow 3000 m southward); flat past the edge centres. */
	double g[2];
	skyterraind_height_grad_km(&t, 0.5, 0.5, g);
	CHECK_NEAR(g[0], 1.0, 1e-12);
	CHECK_NEAR(g[1], -3.0, 1e-12);
	double e = 1e-6, fd = (skyterraind_height_km(&t, 0.3 + e, -0.2) - skyterraind_height_km(&t, 0.3 - e, -0.2)) / (2 * e);
	skyterraind_height_grad_km(&t, 0.3, -0.2, g);
	CHECK_NEAR(g[0], fd, 1e-6);
	skyterraind_height_grad_km(&t, 1.2, 0.5, g);
	CHECK_NEAR(g[0], 0.0, 0.0);
	/* No field, or none set: height 0. */
	CHECK_EQ(skyterraind_height_km(NULL, 0, 0), 0.0);
}

/* Rays against a plateau and a ramp on a flat planet (radius 1e6 km),
 * where the answers are lines and planes. */
static void test_rays(void)
{
	static uint16_t flat[16], ramp[2 * 2];
	for (int i = 0; i < 16; i++)
		flat[i] = 65535;
	/* A ramp east: 0 on the western centres, 1 km on the eastern ones. */
	ramp[0] = ramp[2] = 0;
	ramp[1] = ramp[3] = 65535;
	struct skyterrain plateau = { .texels = flat, .width = 4, .height = 4, .max_texel = 65535,
				      .extent_km = 10.0, .height_km = 1.0 };
	struct skyterrain r = { .texels = ramp, .width = 2, .height = 2, .max_texel = 65535,
				.extent_km = 4.0, .height_km = 1.0 };
	const double rb = 1e6;
	double t = 0;

	const double o1[3] = { 0, 0, 2 }, down[3] = { 0, 0, -1 };
	CHECK(skyterraind_ray_hit(&plateau, rb, o1, down, 10.0, &t) == 1);
	CHECK_NEAR(t, 1.0, 1e-6);
	/* Horizontally from the west at 0.5 km: the plateau's edge, 15 km on. */
	const double o2[3] = { -20, 0, 0.5 }, east[3] = { 1, 0, 0 };
	CHECK(skyterraind_ray_hit(&plateau, rb, o2, east, 100.0, &t) == 1);
	CHECK_NEAR(t, 15.0, 1e-5);
	const double o3[3] = { -20, 0, 1.5 };
	CHECK(skyterraind_ray_hit(&plateau, rb, o3, east, 100.0, &t) == 0);
	/* Inside the plateau: met at once. */
	const double o4[3] = { 1, 1, 0.5 };
	CHECK(skyterraind_ray_hit(&plateau, rb, o4, east, 100.0, &t) == 1 && t == 0.0);
	/* The ramp: h = (x + 1) / 2 km between the centres x = -1 and 1. A
	 * ray at 0.8 km going east meets it where (x + 1) / 2 = 0.8 + the
	 * planet's drop x^2 / 2R (under 1e-6 km here): x = 0.6. */
	const double o5[3] = { -3, 0.3, 0.8 };
	CHECK(skyterraind_ray_hit(&r, rb, o5, east, 10.0, &t) == 1);
	CHECK_NEAR(-3 + t, 0.6, 1e-5);
	/* Going down at 45 degrees from above the western edge. */
	const double s = sqrt(0.5), d6[3] = { s, 0, -s }, o6[3] = { -1, 0, 1 };
	CHECK(skyterraind_ray_hit(&r, rb, o6, d6, 10.0, &t) == 1);
	/* z = 1 - u, h = (u) / 2 with x = -1 + u: u = 2/3. */
	CHECK_NEAR(t * s, 2.0 / 3.0, 1e-5);
	float tf = 0;
	const float o6f[3] = { -1, 0, 1 }, d6f[3] = { (float)s, 0, (float)-s };
	CHECK(skyterrain_ray_hit(&r, (float)rb, o6f, d6f, 10.0f, &tf) == 1);
	CHECK_NEAR(tf * s, 2.0 / 3.0, 2e-3);
	/* Straight up from inside the square, above the ramp: never. */
	const double up[3] = { 0, 0, 1 }, o7[3] = { 0, 0, 0.6 };
	CHECK(skyterraind_ray_hit(&r, rb, o7, up, 10.0, &t) == 0);
}

static int remove_one(const char *path, const struct stat *st, int flag, struct FTW *f)
{
	(void)st;
	(void)flag;
	(void)f;
	return remove(path);
}

int main(void)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(dir, sizeof(dir), "%s/test_terrain.XXXXXX", tmp && *tmp ? tmp : "/tmp");
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	test_formats();
	test_refusals();
	test_cache();
	test_keys();
	test_sync();
	test_height();
	test_rays();
	test_largest();
	if (nftw(dir, remove_one, 8, FTW_DEPTH | FTW_PHYS) != 0)
		FAIL("cannot remove %s", dir);
	return test_report("test_terrain");
}

/* test_daemon_terrain_maps.c - the terrain's shadow maps reach the clients
 * without a cloud layer: through the real skyd and libsky, a north-south
 * ridge 1.6 km high, 3 km east of the observer, with the sun 5 degrees up
 * in the east and no layer drawn:
 *  - the region holds the cloud tables, the slot's shadow map is valid and
 *    the coverage table is not (the terrain alone has none), the sun's map
 *    alone is marked (the moon lights nothing), no layer is published;
 *  - every texel is clear of cloud (RGB 0), and its fourth channel, the
 *    terrain's opaque depth, puts the first point below the ground on the
 *    ridge wherever that point is above the plain: each texel's hit,
 *    taken back through the published frame, lies within 2.5 km of the
 *    ridge's line and no higher than its crest, and some hits are on its
 *    upper half;
 *  - without the terrain (before it is set) the region has no cloud table. */
#include <math.h>
#include <stdlib.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sky_set.h"
#include "skycloudmarch.h"
#include "test.h"

#define RIDGE_TEXELS 64
#define RIDGE_EXTENT_KM 20.0
#define RIDGE_X_KM 3.0
#define RIDGE_TOP_KM 1.6	/* 0.8 of terrain_height_m=2000 */
#define MAP_WIDTH 64

static char ridge_path[600];

/* A SKYTERRAIN16 file: a Gaussian ridge along x = RIDGE_X_KM, 1 km wide,
 * its crest 0.8 of white. */
static int write_ridge(const char *dir)
{
	snprintf(ridge_path, sizeof(ridge_path), "%s/ridge.raw", dir);
	FILE *f = fopen(ridge_path, "wb");
	if (!f)
		return -1;
	fprintf(f, "SKYTERRAIN16 %d %d\n", RIDGE_TEXELS, RIDGE_TEXELS);
	for (int j = 0; j < RIDGE_TEXELS; j++)
		for (int i = 0; i < RIDGE_TEXELS; i++) {
			double x = ((i + 0.5) / RIDGE_TEXELS - 0.5) * RIDGE_EXTENT_KM - RIDGE_X_KM;
			uint16_t v = (uint16_t)lrint(0.8 * 65535.0 * exp(-x * x));
			unsigned char b[2] = { (unsigned char)(v & 255), (unsigned char)(v >> 8) };
			fwrite(b, 1, 2, f);
		}
	return fclose(f);
}

/* Waits until the mapping holds a generation >= gen with all of tables
 * valid, and returns that view begun (the caller ends it). */
static int wait_tables(sky_client *c, uint32_t gen, uint32_t tables, struct sky_view *ret)
{
	for (int i = 0; i < 1000; i++) {
		int r = sky_view_begin(c, ret);
		if (r < 0)
			return r;
		if (ret->slot->generation >= gen && (ret->valid_tables & tables) == tables)
			return 0;
		uint32_t g = ret->generation;
		if (!sky_view_end(c, ret))
			continue;
		if ((r = sky_wait(c, g, 30000, NULL)) < 0)
			return r;
	}
	return -ETIMEDOUT;
}


/* The sun's map of the view against the ridge, hit by hit. */
static void ridge_in_map(const struct sky_view *v)
{
	const struct sky_shm_header *h = v->header;
	const struct sky_shm_table *t = &h->tables[SKY_TABLE_SHADOW];
	struct skycloud_shadow_frame f;
	unsigned hits = 0, upper = 0, off_ridge = 0, cloudy = 0;
	double highest = 0.0, rb = v->slot->state.bottom_radius_km;

	CHECK_EQ(t->width, MAP_WIDTH);
	CHECK_EQ(t->depth, 2u);
	CHECK_EQ(t->format, (uint32_t)SKY_FORMAT_RGBA32F);
	if (t->width != MAP_WIDTH || t->format != SKY_FORMAT_RGBA32F)
		return;
	const float *map = (const float *)((const uint8_t *)v->slot_base + t->offset);
	skycloud_shadow_frame_from_slot(&v->slot->clouds, 0, &f);
	for (unsigned y = 0; y < MAP_WIDTH; y++)
		for (unsigned x = 0; x < MAP_WIDTH; x++) {
			const float *texel = map + 4 * (y * MAP_WIDTH + x);
			cloudy += texel[0] != 0.0f || texel[1] != 0.0f || texel[2] != 0.0f;
			if (!(texel[3] < 1e29f))
				continue;
			double o[3], p[3];
			skycloud_shadow_frame_origin(&f, (x + 0.5) / MAP_WIDTH, (y + 0.5) / MAP_WIDTH, o);
			for (int k = 0; k < 3; k++)
				p[k] = o[k] + texel[3] * f.row_depth[k];
			/* Above the curved ground under the observer. */
			double z = p[2] + (p[0] * p[0] + p[1] * p[1]) / (2.0 * rb);
			hits++;
			highest = fmax(highest, z);
			upper += z > 0.5 * RIDGE_TOP_KM;
			if (z > 0.2 && fabs(p[0] - RIDGE_X_KM) > 2.5)
				off_ridge++;
		}
	printf("sun's map %ux%u: %u hits, highest %.3f km, %u on the ridge's upper half, %u off it, "
	       "%u cloudy texels\n", MAP_WIDTH, MAP_WIDTH, hits, highest, upper, off_ridge, cloudy);
	CHECK(hits > 0 && hits < MAP_WIDTH * MAP_WIDTH);
	CHECK(upper > 0);
	CHECK(highest < RIDGE_TOP_KM + 0.05);
	CHECK_EQ(off_ridge, 0u);
	CHECK_EQ(cloudy, 0u);
}

static void test_terrain_maps(sky_client *c)
{
	char line[800];
	struct sky_view v;

	CHECK(sky_header(c)->n_tables < SKY_TABLE_SHADOW + 1);	/* nothing casts yet */
	snprintf(line, sizeof(line),
		 "set terrain=%s terrain_extent_km=%g terrain_height_m=2000 sun_elevation_deg=5 "
		 "sun_azimuth_deg=90",
		 ridge_path, RIDGE_EXTENT_KM);
	uint32_t g = set_and_generation(c, line);
	int r = wait_tables(c, g, SKY_TABLE_BIT(SKY_TABLE_SHADOW), &v);
	if (r < 0) {
		FAIL("no shadow map with the terrain alone: %s", sky_strerror(r));
		return;
	}
	CHECK(v.header->n_tables > SKY_TABLE_SHADOW);
	CHECK_EQ(v.valid_tables & SKY_TABLE_BIT(SKY_TABLE_CLOUD), 0u);
	CHECK_EQ(v.slot->clouds.shadow_lights, 1u);
	CHECK_EQ(v.slot->clouds.n_layers, 0u);
	ridge_in_map(&v);
	CHECK(sky_view_end(c, &v));
}

int main(void)
{
	static const char *const args[] = { HARNESS_SMALL, "shadow_width=64", NULL };
	struct daemon d = { 0 };

	harness_need_device();
	if (daemon_start(&d, args) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_terrain_maps");
	}
	CHECK(write_ridge(d.dir) == 0);
	sky_client *c = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	if (c) {
		sky_set_timeout(c, 30000);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL | SKY_TABLES_CLOUDS, SKY_SUBSCRIBE_EVENTS) == 0);
		test_terrain_maps(c);
		sky_disconnect(c);
	}
	daemon_cleanup(&d);
	return test_report("test_daemon_terrain_maps");
}

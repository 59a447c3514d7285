/* test_daemon_f16.c - storage=f16 through the real skyd on Mars: the slot's
 * state carries each table's scale, every published half is finite, libsky
 * and the daemon's `sample` verbs read the same values, and those are the
 * float32 region's values within the half's rounding (test_f16.c's bound)
 * once the daemon switches to storage=f32. */
#include <math.h>
#include <stdlib.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sky_set.h"
#include "test.h"

static const char *const args[] = { HARNESS_SMALL, "preset=mars", "storage=f16",
				    "sun_elevation_deg=20", NULL };

#define N_DIRS 6
static const double dirs[N_DIRS][2] = { { 20, 180 }, { 21, 182 }, { 60, 90 }, { 1, 0 }, { 89, 10 },
					{ -10, 200 } };

/* What one region gave: sky radiance toward dirs, the sun and an aerial
 * perspective sample, and the sky-view table's scale. */
struct reading {
	double sky[N_DIRS][3], sun[3], aerial[3], tr;
	int32_t k_sky;
};

/* Waits (futex, following a new region) until the mapping holds a
 * generation >= gen with every table valid and storage format fmt;
 * 0 or -errno. */
static int wait_tables(sky_client *c, uint32_t gen, uint32_t fmt, struct sky_view *ret)
{
	for (int i = 0; i < 1000; i++) {
		int r = sky_view_begin(c, ret);
		if (r < 0)
			return r;
		bool ok = ret->slot->generation >= gen && ret->valid_tables == SKY_TABLES_ALL &&
			  ret->header->tables[0].format == fmt;
		if (sky_view_end(c, ret) && ok)
			return 0;
		struct sky_event ev;
		while (sky_dispatch(c, &ev) == 1)
			;
		r = sky_wait(c, ret->generation, 30000, NULL);
		if (r < 0)
			return r;
	}
	return -ETIMEDOUT;
}


/* No stored half of a valid table is infinite or NaN. */
static void check_finite(const struct sky_view *v)
{
	for (uint32_t n = 0; n < v->header->n_tables; n++) {
		const struct sky_shm_table *t = &v->header->tables[n];
		const uint16_t *h = (const uint16_t *)((const char *)v->slot_base + t->offset);
		size_t bad = 0;
		for (uint64_t i = 0; i < t->bytes / 2; i++)
			bad += (h[i] & 0x7c00) == 0x7c00;
		if (bad)
			FAIL("table %u: %zu halves not finite", t->id, bad);
		double f = 0;
		CHECK(sky_table_scale(v, t->id, &f) == 0 &&
		      f == ldexp(1.0, v->slot->state.rgb_scale_log2[t->id]));
	}
	CHECK(v->slot->state.rgb_scale_log2[SKY_TABLE_TRANSMITTANCE] == -15);
}

static void read_region(sky_client *c, const struct sky_view *v, bool ask_daemon, struct reading *ret)
{
	for (int i = 0; i < N_DIRS; i++) {
		CHECK(sky_sample_sky(v, dirs[i][0], dirs[i][1], 0, ret->sky[i]) == 0);
		if (!ask_daemon)
			continue;
		char line[96];
		sky_reply *rep = NULL;
		double x[3] = { NAN, NAN, NAN };
		snprintf(line, sizeof(line), "sample sky el_deg=%g az_deg=%g", dirs[i][0], dirs[i][1]);
		CHECK(sky_request(c, line, &rep) == 0);
		const char *val = rep ? sky_reply_get(rep, "radiance_rgb_cd_m2") : NULL;
		if (val)
			sscanf(val, "%lf,%lf,%lf", &x[0], &x[1], &x[2]);
		for (int k = 0; k < 3; k++)
			if (!(fabs(x[k] - ret->sky[i][k]) <= 1e-8 * fabs(ret->sky[i][k])))
				FAIL("%s: skyd %.9g, libsky %.9g", line, x[k], ret->sky[i][k]);
		sky_reply_free(rep);
	}
	CHECK(sky_sample_sun(v, ret->sun) == 0);
	CHECK(sky_sample_aerial(v, 0.4, 0.6, 20.0, ret->aerial, &ret->tr) == 0);
	ret->k_sky = v->slot->state.rgb_scale_log2[SKY_TABLE_SKYVIEW];
}

/* |a - b| within the rounding of b's halves of scale k. */
static bool within(double a, double b, int32_t k)
{
	return fabs(a - b) <= 0x1p-11 * fabs(a) * (1 + 1e-12) + ldexp(1.0, k - 25);
}

int main(void)
{
	struct daemon d = { 0 };
	harness_need_device();
	if (daemon_start(&d, args) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_f16");
	}
	sky_client *c = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	if (c) {
		struct sky_view v;
		struct reading half, full;
		sky_set_timeout(c, 30000);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS) == 0);
		uint32_t g = set_and_generation(c, "set sun_azimuth_deg=180");
		CHECK(wait_tables(c, g, SKY_FORMAT_RGBA16F, &v) == 0);
		check_finite(&v);
		read_region(c, &v, true, &half);
		CHECK(sky_view_end(c, &v));
		printf("f16: sky-view scale 2^%d, toward the sun %.6g cd/m2\n", half.k_sky, half.sky[0][0]);
		g = set_and_generation(c, "set storage=f32");
		CHECK(wait_tables(c, g, SKY_FORMAT_RGBA32F, &v) == 0);
		CHECK(v.slot->state.rgb_scale_log2[SKY_TABLE_SKYVIEW] == 0);
		read_region(c, &v, false, &full);
		CHECK(sky_view_end(c, &v));
		for (int k = 0; k < 3; k++) {
			for (int i = 0; i < N_DIRS; i++)
				if (!within(full.sky[i][k], half.sky[i][k], half.k_sky))
					FAIL("sky toward %g, %g: f32 %.9g, f16 %.9g", dirs[i][0], dirs[i][1],
					     full.sky[i][k], half.sky[i][k]);
			CHECK(within(full.sun[k], half.sun[k], -15));
			CHECK(fabs(full.aerial[k] - half.aerial[k]) <= 0x1p-10 * full.aerial[k]);
		}
		sky_disconnect(c);
	}
	daemon_cleanup(&d);
	return test_report("test_daemon_f16");
}

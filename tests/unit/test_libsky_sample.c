/* test_libsky_sample.c - libsky's sampling of the stand-in's tables
 * (testkit/fake_skyd.h) against their known values at texel centres, and
 * the ambient light and sun disk of skysample.h against their integrals,
 * and sky_sample_clouds() against skycloudmarch.h on the same tables. */
#include <errno.h>
#include <math.h>
#include <stdio.h>

#include "fake_skyd.h"
#include "sky.h"
#include "skycloudmarch.h"
#include "skysample.h"
#include "test.h"

#define PI SKYMAP_PI
#define DEG (PI / 180.0)

static struct fake_skyd fake;

static void test_sampling_at_texel_centres(sky_client *c)
{
	struct sky_view v;
	CHECK_EQ(sky_view_begin(c, &v), 0);
	CHECK(v.valid_tables == SKY_TABLES_ALL && v.generation == 1 && v.slot_index == 1);
	const float *t = fake_skyd_table(&fake, 1, SKY_TABLE_TRANSMITTANCE);
	double worst = 0.0;
	for (int j = 0; j < FAKE_TH; j++)
		for (int i = 0; i < FAKE_TW; i++) {
			double alt, mu, rgb[3];
			skymap_transmittance_inverse(6360.0, 6460.0, (i + 0.5) / FAKE_TW, (j + 0.5) / FAKE_TH,
						     FAKE_TW, FAKE_TH, &alt, &mu);
			CHECK_EQ(sky_sample_transmittance(&v, alt, mu, rgb), 0);
			for (int k = 0; k < 3; k++)
				worst = fmax(worst, fabs(rgb[k] - t[(j * FAKE_TW + i) * 4 + k]));
		}
	printf("transmittance at texel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);

	/* sky-view (f16): texel centres, and halfway between two texels */
	worst = 0.0;
	for (int j = 0; j < FAKE_SH; j++)
		for (int i = 0; i < FAKE_SW; i++) {
			double zen, az, rgb[3];
			double hc = skymap_horizon_cos(6360.0, 0.2);
			skymap_skyview_inverse(hc, (i + 0.5) / FAKE_SW, (j + 0.5) / FAKE_SH, FAKE_SH, &zen, &az);
			CHECK_EQ(sky_sample_sky(&v, 90.0 - zen / DEG, az / DEG, 0, rgb), 0);
			worst = fmax(worst, fabs(rgb[0] - (i + 1)));
			worst = fmax(worst, fabs(rgb[1] - (j + 1)));
			worst = fmax(worst, fabs(rgb[2] - (i + FAKE_SW * j)));
		}
	printf("sky-view (f16) at texel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);
	{
		/* azimuth 0 lies between the last and the first column: the average */
		double zen, az, rgb[3];
		skymap_skyview_inverse(skymap_horizon_cos(6360.0, 0.2), 0.5 / FAKE_SW, 2.5 / FAKE_SH, FAKE_SH,
				       &zen, &az);
		CHECK_EQ(sky_sample_sky(&v, 90.0 - zen / DEG, 0.0, 0, rgb), 0);
		CHECK(fabs(rgb[0] - 0.5 * (1 + FAKE_SW)) < 1e-6);
		CHECK(fabs(rgb[1] - 3.0) < 1e-6);
	}

	/* aerial: froxel centres at the far edge of each slice; depth 0 is (0, 1) */
	worst = 0.0;
	for (int k = 0; k < FAKE_AD; k++)
		for (int j = 0; j < FAKE_AH; j++)
			for (int i = 0; i < FAKE_AW; i++) {
				double rgb[3], tr;
				double d = skymap_aerial_depth_km(k, FAKE_AD, 32.0, 1);
				CHECK_EQ(sky_sample_aerial(&v, (i + 0.5) / FAKE_AW, (j + 0.5) / FAKE_AH, d, rgb, &tr), 0);
				worst = fmax(worst, fabs(rgb[0] - (k + 1)));
				worst = fmax(worst, fabs(rgb[1] - (i + 1)));
				worst = fmax(worst, fabs(rgb[2] - (j + 1)));
				worst = fmax(worst, fabs(tr - (1.0 - 0.1 * (k + 1))));
			}
	printf("aerial at froxel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);
	double rgb[3], tr;
	CHECK_EQ(sky_sample_aerial(&v, 0.5, 0.5, 0.0, rgb, &tr), 0);
	CHECK(rgb[0] == 0.0 && tr == 1.0);
	/* halfway (in the slice coordinate) between the camera and slice 0 */
	double half = 32.0 * pow(0.5 / FAKE_AD, 2.0);
	CHECK_EQ(sky_sample_aerial(&v, (0.5) / FAKE_AW, 0.5 / FAKE_AH, half, rgb, &tr), 0);
	CHECK(fabs(rgb[0] - 0.5) < 1e-9 && fabs(tr - 0.95) < 1e-6);
	CHECK_EQ(sky_sample_aerial(&v, 0.5, 0.5, -1.0, rgb, &tr), -EINVAL);

	/* sun: top-of-atmosphere illuminance times the table at (altitude, mu_sun) */
	double lx[3], tr3[3];
	CHECK_EQ(sky_sample_sun(&v, lx), 0);
	skysample_transmittance(&(struct skysample_table){ t, SKY_FORMAT_RGBA32F, FAKE_TW, FAKE_TH, 1, 0 },
				&v.slot->state, 0.2, sin(30.0 * DEG), tr3);
	for (int k = 0; k < 3; k++)
		CHECK(fabs(lx[k] - 1.0e5 * (k + 1) * tr3[k]) < 1e-6 * lx[k]);
	CHECK(sky_view_end(c, &v));
	sky_view_end(c, &v);
}

/* A uniform sky integrates to pi L over the hemisphere; the sun's disk
 * integrates to its illuminance times the transmittance. */
static void test_ambient_and_disk(void)
{
	static float sky[FAKE_SW * FAKE_SH * 4], trans[FAKE_TW * FAKE_TH * 4];
	for (int i = 0; i < FAKE_SW * FAKE_SH * 4; i++)
		sky[i] = 2.0f;
	for (int i = 0; i < FAKE_TW * FAKE_TH * 4; i++)
		trans[i] = 0.25f;
	struct skysample_table ts = { sky, SKY_FORMAT_RGBA32F, FAKE_SW, FAKE_SH, 1, 0 };
	struct skysample_table tt = { trans, SKY_FORMAT_RGBA32F, FAKE_TW, FAKE_TH, 1, 0 };
	struct sky_shm_state st = { .bottom_radius_km = 6360, .top_radius_km = 6460, .altitude_km = 0.2,
				    .sun_illuminance_lx = { 1000, 2000, 3000 },
				    .sun_angular_radius_rad = 2.0 * DEG };
	double lx[3];
	skysample_ambient(&ts, &st, lx);
	CHECK(fabs(lx[0] - 2.0 * PI) < 1e-12 && fabs(lx[2] - 2.0 * PI) < 1e-12);
	skysample_direction(40.0 * DEG, 200.0 * DEG, st.sun_direction);
	for (int limb = 0; limb < 2; limb++) {
		/* integrate the disk radiance over solid angle around the sun */
		double sum = 0.0, n = 400;
		double e0[3] = { cos(200 * DEG), -sin(200 * DEG), 0 }, e1[3];
		const double *s = st.sun_direction;
		e1[0] = s[1] * e0[2] - s[2] * e0[1];
		e1[1] = s[2] * e0[0] - s[0] * e0[2];
		e1[2] = s[0] * e0[1] - s[1] * e0[0];
		double h = 2.2 * DEG * 2.0 / n;
		for (int a = 0; a < n; a++)
			for (int b = 0; b < n; b++) {
				double x = -2.2 * DEG + (a + 0.5) * h, y = -2.2 * DEG + (b + 0.5) * h;
				double d[3], rgb[3] = { 0, 0, 0 }, len = 0;
				for (int k = 0; k < 3; k++) {
					d[k] = s[k] + x * e0[k] + y * e1[k];
					len += d[k] * d[k];
				}
				len = sqrt(len);
				for (int k = 0; k < 3; k++)
					d[k] /= len;
				skysample_add_disk(&tt, &st, s, st.sun_illuminance_lx, 2.0 * DEG, d,
						   limb ? 0.6 : 0.0, rgb);
				sum += rgb[0] * h * h / (len * len * len);
			}
		printf("disk integral (limb %d): %.6g, expected %.6g\n", limb, sum, 1000 * 0.25);
		CHECK(fabs(sum - 250.0) < 250.0 * 5e-3);
	}
	/* below the horizon the sun is blocked */
	skysample_direction(-1.0 * DEG, 0.0, st.sun_direction);
	skysample_sun(&tt, &st, lx);
	CHECK(lx[0] == 0.0 && lx[1] == 0.0);
}

/* sky_sample_clouds() is skycloud_march() on the view's tables, lights
 * and cloud layers (the stand-in publishes one stratocumulus layer and no
 * cloud tables: the field's own coverage, a march toward the sun), bit
 * for bit, and its composite is skycloud_composite() of the view's sky
 * and aerial perspective; bad arguments are refused. */
static void test_sample_clouds(sky_client *c)
{
	struct sky_view v;
	struct skycloud_layer L;
	struct skycloud_scene sc;
	struct skysample_table tr, ms;
	CHECK_EQ(sky_view_begin(c, &v), 0);
	skycloud_layer_init(&L, SKYCLOUD_STRATOCUMULUS, FAKE_CLOUD_COVER, FAKE_CLOUD_BASE_KM, FAKE_CLOUD_TOP_KM,
			    FAKE_CLOUD_SEED, 0u);
	skycloud_scene_init(&sc, &L, 1, fake_cloud_offset_km);
	sc.diffusion = 1;	/* a slot's scene (skycloud_scene_from_slot) */
	struct sky_cloud_params p = { .steps = 32, .light_steps = 4, .jitter = 0.5 };
	CHECK_EQ(skysample_table_from_slot(v.header, v.slot_base, SKY_TABLE_TRANSMITTANCE, &tr), 0);
	CHECK_EQ(skysample_table_from_slot(v.header, v.slot_base, SKY_TABLE_MULTISCATTER, &ms), 0);
	const struct sky_shm_state *st = &v.slot->state;
	const struct skycloud_sky sky = { &tr, &ms, st->bottom_radius_km, st->top_radius_km };
	struct skycloud_light sun = { .shadow = NULL };
	for (int k = 0; k < 3; k++) {
		sun.dir[k] = st->sun_direction[k];
		sun.illuminance_lx[k] = st->sun_illuminance_lx[k];
	}
	int cloudy = 0;
	for (int i = 0; i < 24; i++) {
		double el = 5.0 + 3.5 * i, az = 15.0 * i, d[3], rgb[3], t, depth, sky_rgb[3], air[3], air_t, want[3];
		struct skycloud_sample m;
		skysample_direction(el * DEG, az * DEG, d);
		const double o[3] = { 0.0, 0.0, st->altitude_km };
		skycloud_march(&sc, &sun, &sky, o, d, 1e30, 32, 4, 0.5, &m);
		if (st->moon_illuminance_lx[0] > 0.0)
			continue;	/* the stand-in's moon is dark: the sun alone */
		CHECK_EQ(sky_sample_clouds(&v, &p, el, az, INFINITY, 0, rgb, &t, &depth), 0);
		CHECK_EQ(rgb[1], m.radiance[1]);
		CHECK_EQ(t, m.transmittance);
		CHECK_EQ(depth, m.depth_km);
		cloudy += t < 1.0;
		CHECK_EQ(sky_sample_clouds(&v, &p, el, az, INFINITY, SKY_SAMPLE_CLOUD_COMPOSITE, rgb, NULL, NULL), 0);
		CHECK_EQ(sky_sample_sky(&v, el, az, 0, sky_rgb), 0);
		CHECK_EQ(sky_sample_view_aerial_dir(&v, NULL, d, m.depth_km, air, &air_t), 0);
		skycloud_composite(sky_rgb, &m, air, air_t, want);
		CHECK_NEAR(rgb[2], want[2], 1e-12 * fabs(want[2]));
		/* Defaults: 64 steps, 8 toward the sun, the midpoint. */
		skycloud_march(&sc, &sun, &sky, o, d, 1e30, SKYCLOUD_MARCH_STEPS_MEDIUM, 8, 0.5, &m);
		CHECK_EQ(sky_sample_clouds(&v, NULL, el, az, INFINITY, 0, rgb, &t, NULL), 0);
		CHECK_EQ(t, m.transmittance);
	}
	CHECK(cloudy > 4);
	double rgb[3];
	CHECK_EQ(sky_sample_clouds(NULL, &p, 10.0, 0.0, INFINITY, 0, rgb, NULL, NULL), -EINVAL);
	CHECK_EQ(sky_sample_clouds(&v, &p, NAN, 0.0, INFINITY, 0, rgb, NULL, NULL), -EINVAL);
	CHECK_EQ(sky_sample_clouds(&v, &p, 10.0, 0.0, -1.0, 0, rgb, NULL, NULL), -EINVAL);
	CHECK_EQ(sky_sample_clouds(&v, &p, 10.0, 0.0, INFINITY, 64, rgb, NULL, NULL), -EINVAL);
	p.jitter = 1.0;
	CHECK_EQ(sky_sample_clouds(&v, &p, 10.0, 0.0, INFINITY, 0, rgb, NULL, NULL), -EINVAL);
	CHECK(sky_view_end(c, &v));
}

int main(void)
{
	fake_skyd_start(&fake);
	sky_client *c = fake_skyd_client(&fake);
	if (c) {
		test_sampling_at_texel_centres(c);
		test_ambient_and_disk();
		test_sample_clouds(c);
		sky_disconnect(c);
	}
	fake_skyd_stop(&fake);
	return test_report("test_libsky_sample");
}

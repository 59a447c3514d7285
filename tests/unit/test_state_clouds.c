/* test_state_clouds.c - the cloud layers in the sky's state: their keys
 * and refusals, what each invalidates (nothing while no layer is drawn),
 * the rule that a drawn layer replaces the weather's light factor (and
 * cloud_oktas alone keeps it), the tops, the region, the cross-key rules,
 * what a METAR's cloud and wind groups make of them, the field's
 * placement in whole simulated seconds and its offset. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "drive.h"
#include "metar.h"
#include "skycloud.h"
#include "state.h"
#include "test.h"

#define LIGHTS (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL))
#define CLOUDS (STATE_CLOUD_TABLES | LIGHTS)

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s: %s", pair, err);
}

static int set_r(struct sky_state *s, const char *pair, uint32_t *dirty)
{
	char err[256];
	return state_set_pair(s, pair, dirty, err, sizeof(err));
}

static void get(const struct sky_state *s, const char *key, char *buf, size_t n)
{
	if (state_get(s, key, buf, n) < 0)
		FAIL("get %s", key);
}

static void test_keys(void)
{
	struct sky_state s;
	char buf[64];

	state_default(&s);
	/* The state's names are the field's types, in order. */
	for (int t = 0; t < SKYCLOUD_N_TYPES; t++) {
		snprintf(buf, sizeof(buf), "cloud2_type=%s", skycloud_types[t].name);
		set(&s, buf);
		CHECK_EQ(s.clouds.layer[1].type, t);
	}
	CHECK_EQ(set_r(&s, "cloud1_oktas=9", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud1_oktas=-0.5", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud1_type=nimbus", NULL), -EINVAL);
	CHECK_EQ(set_r(&s, "cloud5_oktas=1", NULL), -ENOENT);
	CHECK_EQ(set_r(&s, "cloud1_base_m=20001", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud1_base_m=nan", NULL), -EINVAL);
	CHECK_EQ(set_r(&s, "wind_dir_deg=361", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "wind_speed_mps=-1", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "wind_speed_mps=151", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud_seed=-1", NULL), -EINVAL);
	CHECK_EQ(set_r(&s, "cloud_seed=4294967296", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud_extent_km=513", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud_width=8", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud_cell_texels=-1", NULL), -ERANGE);
	CHECK_EQ(set_r(&s, "cloud_cell_texels=65", NULL), -ERANGE);
	/* The ends of every range are taken. */
	set(&s, "cloud_seed=4294967295");
	set(&s, "wind_dir_deg=360");
	set(&s, "wind_speed_mps=150");
	set(&s, "cloud_extent_km=512");
	set(&s, "cloud1_base_m=0");
	set(&s, "cloud1_top_m=20000");
	set(&s, "cloud_cell_texels=0");
	set(&s, "cloud_cell_texels=64");
	CHECK_EQ(s.clouds.seed, 4294967295u);
	/* The fraction is the oktas in eighths. */
	set(&s, "cloud3_fraction=0.75");
	CHECK_EQ(s.clouds.layer[2].oktas, 6.0);
	get(&s, "cloud3_fraction", buf, sizeof(buf));
	CHECK(strcmp(buf, "0.75") == 0);
	set(&s, "cloud3_fraction=auto");
	CHECK(isnan(s.clouds.layer[2].oktas));
}

/* What each key invalidates: nothing while no layer is drawn, the cloud
 * tables and sky-view and aerial once one is; cloud_oktas nothing then. */
static void test_dirty(void)
{
	struct sky_state s;
	uint32_t d;

	state_default(&s);
	d = 0;
	CHECK(set_r(&s, "cloud1_oktas=6", &d) == 0 && d == 0);
	d = 0;
	CHECK(set_r(&s, "wind_speed_mps=5", &d) == 0 && d == 0);
	d = 0;
	CHECK(set_r(&s, "quality=low", &d) == 0 && d == STATE_ALL_TABLES);
	set(&s, "quality=medium");
	d = 0;
	CHECK(set_r(&s, "cloud1_base_m=900", &d) == 0 && d == CLOUDS);	/* drawn now */
	CHECK_EQ(state_clouds_drawn(&s), 1);
	d = 0;
	CHECK(set_r(&s, "cloud_seed=7", &d) == 0 && d == CLOUDS);
	d = 0;
	CHECK(set_r(&s, "shadow_width=512", &d) == 0 &&
	      d == (STATE_BIT(STATE_CLOUD_SHADOW) | LIGHTS));
	d = 0;
	CHECK(set_r(&s, "cloud_oktas=6", &d) == 0 && d == 0);	/* the layers dim the sun */
	d = 0;
	CHECK(set_r(&s, "quality=low", &d) == 0 && d == (STATE_ALL_TABLES | STATE_CLOUD_TABLES));
	d = 0;
	CHECK(set_r(&s, "cloud1_oktas=0", &d) == 0 && d == CLOUDS);	/* no longer drawn */
	CHECK_EQ(state_clouds_drawn(&s), 0);
	d = 0;
	CHECK(set_r(&s, "cloud_oktas=3", &d) == 0 && d == LIGHTS);
	char names[96];
	state_format_all_tables(CLOUDS, names, sizeof(names));
	CHECK(strcmp(names, "skyview,aerial,cloud,shadow") == 0);
	state_format_tables(CLOUDS, names, sizeof(names));
	CHECK(strcmp(names, "skyview,aerial") == 0);
}

/* cloud_oktas alone dims the lights as before; a drawn layer replaces it. */
static void test_light_factor(void)
{
	struct sky_state s, sky;
	char err[256];

	state_default(&s);
	set(&s, "cloud_oktas=6");
	CHECK(state_resolve(&s, &sky, NULL, err, sizeof(err)) == 0);
	CHECK_EQ(sky.sun.illuminance_lx, s.sun.illuminance_lx * weather_cloud_light_factor(6.0));
	set(&s, "cloud1_oktas=6");		/* no base: not drawn */
	CHECK(state_resolve(&s, &sky, NULL, err, sizeof(err)) == 0);
	CHECK_EQ(sky.sun.illuminance_lx, s.sun.illuminance_lx * weather_cloud_light_factor(6.0));
	set(&s, "cloud1_base_m=914.4");
	CHECK(state_resolve(&s, &sky, NULL, err, sizeof(err)) == 0);
	CHECK_EQ(sky.sun.illuminance_lx, s.sun.illuminance_lx);
	CHECK_EQ(state_cloud_factor_applied(&s), 1.0);
	/* A state without weather and layers resolves to itself, bytes and all. */
	state_default(&s);
	CHECK(state_resolve(&s, &sky, NULL, err, sizeof(err)) == 0);
	CHECK(memcmp(&s, &sky, sizeof(s)) == 0);
}

static void test_tops_and_region(void)
{
	struct sky_state s;
	char err[256];

	state_default(&s);
	CHECK(isnan(state_cloud_top_m(&s, 0)));
	CHECK_EQ(state_cloud_extent_km(&s), 50.0);
	set(&s, "cloud1_oktas=6");
	set(&s, "cloud1_base_m=914.4");
	CHECK_NEAR(state_cloud_top_m(&s, 0), 1314.4, 1e-9);	/* stratocumulus: 400 m */
	CHECK_NEAR(state_cloud_extent_km(&s), sqrt(2.0 * 6360.0 * 1.3144), 1e-6);
	set(&s, "cloud2_oktas=2");
	set(&s, "cloud2_base_m=15000");
	set(&s, "cloud2_type=cumulonimbus");		/* 15 + 8 km: held at 20 km */
	CHECK_EQ(state_cloud_top_m(&s, 1), 20000.0);
	CHECK_EQ(state_cloud_extent_km(&s), 400.0);
	set(&s, "cloud_extent_km=75");
	CHECK_EQ(state_cloud_extent_km(&s), 75.0);
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	/* A top under its base, above the atmosphere, or no room at all. */
	set(&s, "cloud1_top_m=900");
	CHECK(state_validate(&s, 0, err, sizeof(err)) == -ERANGE && strstr(err, "cloud1_top_m") == err);
	set(&s, "cloud1_top_m=auto");
	set(&s, "cloud2_base_m=20000");
	CHECK(state_validate(&s, 0, err, sizeof(err)) == -ERANGE && strstr(err, "cloud2_base_m") == err);
	set(&s, "cloud2_base_m=15000");
	set(&s, "top_radius_km=6370");		/* a shell of 10 km */
	CHECK(state_validate(&s, 0, err, sizeof(err)) == -ERANGE && strstr(err, "cloud2_base_m") == err);
	set(&s, "cloud2_base_m=5000");
	CHECK_EQ(state_cloud_top_m(&s, 1), 10000.0);
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	set(&s, "cloud2_top_m=12000");
	CHECK(state_validate(&s, 0, err, sizeof(err)) == -ERANGE && strstr(err, "cloud2_top_m") == err);
	/* The drawn layers as the field takes them keep their own index. */
	set(&s, "top_radius_km=6420");
	set(&s, "cloud2_base_m=15000");
	set(&s, "cloud2_top_m=auto");
	set(&s, "cloud1_oktas=0");
	struct skycloud_layer L[4];
	CHECK_EQ(state_cloud_layers(&s, L), 1);
	CHECK_EQ(L[0].index, 1u);
	CHECK_EQ(L[0].type, SKYCLOUD_CUMULONIMBUS);
	CHECK_NEAR(L[0].cover, 0.25, 1e-7);
	CHECK_NEAR(L[0].base_km, 15.0, 1e-6);
}

static void metar(struct sky_state *s, const char *report)
{
	char err[256];
	if (state_set_metar(s, report, NULL, NULL, err, sizeof(err)) < 0)
		FAIL("%s: %s", report, err);
}

static void test_metar(void)
{
	struct sky_state s;
	char buf[64];

	state_default(&s);
	metar(&s, "EGLL 241250Z 27015KT 9999 BKN030 12/06 Q1018");
	CHECK_EQ(state_clouds_drawn(&s), 1);
	CHECK_EQ(s.clouds.layer[0].oktas, 6.0);
	CHECK_EQ(s.clouds.layer[0].base_m, 914.4);
	CHECK_EQ(s.clouds.layer[0].type, SKYCLOUD_STRATOCUMULUS);
	CHECK_EQ(s.clouds.wind_dir_deg, 270.0);
	CHECK_EQ(s.clouds.wind_speed_mps, 7.72);	/* 15 kt, to the centimetre */
	/* Their text reads back as the same doubles. */
	get(&s, "cloud1_base_m", buf, sizeof(buf));
	CHECK(strcmp(buf, "914.4") == 0);
	get(&s, "wind_speed_mps", buf, sizeof(buf));
	CHECK(strcmp(buf, "7.72") == 0);

	/* Four layers, typed by their height and amount, a fifth left out. */
	metar(&s, "KXYZ 241250Z 09010MPS 9999 FEW020 SCT035TCU BKN080 OVC250 OVC300 12/06 Q1018");
	CHECK_EQ(state_clouds_drawn(&s), 4);
	CHECK_EQ(s.clouds.layer[0].type, SKYCLOUD_CUMULUS);
	CHECK_EQ(s.clouds.layer[0].oktas, 1.5);
	CHECK_EQ(s.clouds.layer[1].type, SKYCLOUD_CUMULUS);
	CHECK_EQ(s.clouds.layer[1].oktas, 3.5);
	CHECK_EQ(s.clouds.layer[2].type, SKYCLOUD_ALTOSTRATUS);
	CHECK_EQ(s.clouds.layer[3].type, SKYCLOUD_CIRRUS);
	CHECK_EQ(s.clouds.layer[3].base_m, 7620.0);
	CHECK_EQ(s.clouds.wind_dir_deg, 90.0);
	CHECK_EQ(s.clouds.wind_speed_mps, 10.0);

	metar(&s, "EGLL 241250Z VRB03KT 9999 SCT025CB OVC005 12/06 Q1018");
	CHECK_EQ(s.clouds.layer[0].type, SKYCLOUD_CUMULONIMBUS);
	CHECK_EQ(s.clouds.layer[1].type, SKYCLOUD_STRATUS);	/* overcast under 1000 ft */
	CHECK(isnan(s.clouds.layer[2].oktas));
	CHECK_EQ(s.clouds.wind_dir_deg, 90.0);			/* variable: kept */
	CHECK_EQ(s.clouds.wind_speed_mps, 1.54);

	metar(&s, "EGLL 241250Z 00000KT 0100 FG VV003 12/12 Q1018");
	CHECK_EQ(state_clouds_drawn(&s), 1);
	CHECK_EQ(s.clouds.layer[0].type, SKYCLOUD_STRATUS);
	CHECK_EQ(s.clouds.layer[0].oktas, 8.0);
	CHECK_EQ(s.clouds.layer[0].base_m, 91.4);
	CHECK_EQ(s.clouds.wind_speed_mps, 0.0);

	/* A clear sky clears them, whatever says it; a height of /// is no layer. */
	static const char *const clear[] = {
		"EGLL 241250Z 27015KT CAVOK 12/06 Q1018", "EGLL 241250Z 27015KT 9999 NSC 12/06 Q1018",
		"EGLL 241250Z 27015KT 9999 NCD 12/06 Q1018", "KJFK 241251Z 27015KT 10SM SKC 12/06 A3000",
		"EGLL 241250Z 27015KT 9999 BKN/// 12/06 Q1018",
	};
	for (size_t i = 0; i < sizeof(clear) / sizeof(clear[0]); i++) {
		metar(&s, "EGLL 241250Z 27015KT 9999 BKN030 12/06 Q1018");
		metar(&s, clear[i]);
		CHECK_EQ(state_clouds_drawn(&s), 0);
	}
	/* A report without a wind group keeps the wind. */
	set(&s, "wind_speed_mps=3");
	metar(&s, "EGLL 241250Z 9999 BKN030 12/06 Q1018");
	CHECK_EQ(s.clouds.wind_speed_mps, 3.0);

	/* A wind group beyond the key's range (999 kt) leaves a state that is
	 * refused as the key would be: skyd refuses the report whole. */
	char err[256] = "";
	int r = state_set_metar(&s, "EGLL 241250Z 270999KT 9999 FEW010 12/06 Q1018", NULL, NULL, err,
				sizeof(err));
	if (r == 0)
		r = state_validate(&s, 0, err, sizeof(err));
	CHECK_EQ(r, -ERANGE);
	CHECK(strstr(err, "wind_speed_mps: 513.93 is outside [0, 150]") != NULL);
}

/* The field is placed in whole simulated seconds while it moves, and the
 * resolve carries the wind's offset then. */
static void test_placement(void)
{
	struct sky_state s, sky;
	uint32_t d = 0;
	char err[256];

	state_default(&s);
	set(&s, "utc=2024-06-21T12:00:00.75Z");
	set(&s, "time_rate=0");
	set(&s, "sun_mode=manual");
	drive_field(&s, 0.0, &d);
	CHECK(isnan(s.clouds.utc_s) && d == 0);		/* nothing drawn */
	set(&s, "cloud1_oktas=8");
	set(&s, "cloud1_base_m=1000");
	drive_field(&s, 0.0, &d);
	CHECK(isnan(s.clouds.utc_s) && d == 0);		/* no wind */
	set(&s, "wind_dir_deg=270");
	set(&s, "wind_speed_mps=10");
	drive_field(&s, 0.0, &d);
	CHECK_EQ(s.clouds.utc_s, 1718971200.0);		/* the second it is in */
	CHECK_EQ(d, CLOUDS);
	d = 0;
	drive_field(&s, 123.0, &d);			/* the clock is frozen */
	CHECK_EQ(d, 0u);
	CHECK(state_resolve(&s, &sky, NULL, err, sizeof(err)) == 0);
	double want[2];
	skycloud_wind_offset_km(270.0, 10.0, 1718971200.0, want);
	CHECK_EQ(sky.clouds.offset_km[0], want[0]);
	CHECK_EQ(sky.clouds.offset_km[1], 0.0);
	CHECK_NEAR(fmod(1718971200.0 * 10.0 * 1e-3, 1024.0), want[0], 1e-6);
	/* A quarter texel of the shadow map: 2 x extent / 256 / 4. */
	CHECK_NEAR(drive_field_threshold_km(&s), 0.5 * state_cloud_extent_km(&s) / 256.0, 1e-12);
	CHECK_EQ(drive_field_speed_km_s(&s), 0.0);	/* frozen */
	set(&s, "time_rate=-60");
	CHECK_NEAR(drive_field_speed_km_s(&s), 0.6, 1e-12);
}

/* The tables' place of the field: the offset on the lattice of
 * cloud_cell_texels shadow texels, the shift what is left; a cell of 0
 * places them where the field is. */
static void test_table_place(void)
{
	struct sky_state s;
	double at[2], shift[2];

	state_default(&s);
	set(&s, "cloud1_oktas=4");
	set(&s, "cloud1_base_m=1000");
	set(&s, "cloud_extent_km=64");
	set(&s, "shadow_width=256");
	double cell = 2.0 * 2.0 * 64.0 / 256.0;		/* 2 texels of 0.5 km */
	s.clouds.offset_km[0] = 10.3;
	s.clouds.offset_km[1] = 1023.9;
	state_cloud_table_offset_km(&s, at, shift);
	CHECK_EQ(at[0], 10.0);
	CHECK_EQ(at[1], 1023.0);
	CHECK_NEAR(shift[0], 0.3, 1e-12);
	CHECK_NEAR(shift[1], 0.9, 1e-12);
	CHECK(shift[0] >= 0.0 && shift[0] < cell && shift[1] >= 0.0 && shift[1] < cell);
	set(&s, "cloud_cell_texels=0");
	state_cloud_table_offset_km(&s, at, shift);
	CHECK_EQ(at[0], 10.3);
	CHECK_EQ(shift[0], 0.0);
	CHECK_EQ(shift[1], 0.0);
}

int main(void)
{
	test_keys();
	test_dirty();
	test_light_factor();
	test_tops_and_region();
	test_metar();
	test_placement();
	test_table_place();
	return test_report("test_state_clouds");
}

/* test_state.c - the key vocabulary: parsing, refusal, invalidation. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "state.h"
#include "test.h"

static void test_defaults_are_valid(void)
{
	struct sky_state s;
	char err[256];
	state_default(&s);
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	CHECK(s.atmo.c[ATMO_RAYLEIGH].scattering_per_km[2] == 33.1e-3);
	CHECK(s.quality.t[STATE_TRANSMITTANCE].width == 256);
}

static void test_refusals_name_the_key(void)
{
	static const char *bad[] = {
		"nonsense_key=1", "sun_elevation_deg=nan", "sun_elevation_deg=inf",
		"sun_elevation_deg=91", "sun_elevation_deg=12abc", "ground_albedo=1.5",
		"mie_g=1", "mie_g=-1.0", "rayleigh_scattering_per_km=-1e-3",
		"skyview_width=0", "multiscatter_dirs=7", "storage=f64", "preset=venus",
		"transmittance_width=-3", "transmittance_width=1e3",
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		struct sky_state s;
		char err[256] = "", key[64];
		state_default(&s);
		CHECK(state_set_pair(&s, bad[i], NULL, err, sizeof(err)) < 0);
		snprintf(key, sizeof(key), "%.*s", (int)strcspn(bad[i], "="), bad[i]);
		if (!strstr(err, key))
			FAIL("'%s': message '%s' does not name the key", bad[i], err);
	}
}

static void test_cross_key_rules(void)
{
	struct sky_state s;
	char err[256];
	state_default(&s);
	CHECK(state_set_pair(&s, "top_radius_km=6000", NULL, err, sizeof(err)) == 0);
	CHECK(state_validate(&s, 0, err, sizeof(err)) < 0);
	CHECK(strstr(err, "top_radius_km") != NULL);
	state_default(&s);
	CHECK(state_validate(&s, 1024, err, sizeof(err)) < 0);
}

static void test_invalidation(void)
{
	struct sky_state s;
	char err[256];
	uint32_t dirty = 0;
	state_default(&s);
	CHECK(state_set_pair(&s, "sun_elevation_deg=10", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL)));
	dirty = 0;
	CHECK(state_set_pair(&s, "sun_elevation_deg=10", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == 0);
	CHECK(state_set_pair(&s, "camera_yaw_deg=10", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == STATE_BIT(STATE_AERIAL));
	dirty = 0;
	CHECK(state_set_pair(&s, "mie_g=0.7", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == STATE_ALL_TABLES);
	dirty = 0;
	CHECK(state_set_pair(&s, "ground_albedo=0.1", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == (STATE_ALL_TABLES & ~STATE_BIT(STATE_TRANSMITTANCE)));
	/* The sun's disk setting at the horizon is in the multiple scattering. */
	dirty = 0;
	CHECK(state_set_pair(&s, "sun_angular_radius_deg=0.3", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == (STATE_ALL_TABLES & ~STATE_BIT(STATE_TRANSMITTANCE)));
}

/* state_diff sees every bit: a value the clock computed that get's nine
 * digits show alike, the raw keys that win over the weather, a cloud
 * factor a light sensor set; and state_get_exact reads back exactly. */
static void test_diff_exact(void)
{
	const uint32_t lights = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);
	struct sky_state a, b;
	char ta[64], tb[64], err[256];

	state_default(&a);
	b = a;
	CHECK_EQ(state_diff(&a, &b), 0);
	b.sun.illuminance_lx = 123716.78708808632;
	a.sun.illuminance_lx = 123716.78738820556;
	CHECK(state_get(&a, "sun_illuminance_lx", ta, sizeof(ta)) == 0 &&
	      state_get(&b, "sun_illuminance_lx", tb, sizeof(tb)) == 0 && strcmp(ta, tb) == 0);
	CHECK_EQ(state_diff(&a, &b), lights);
	CHECK(state_get_exact(&b, "sun_illuminance_lx", tb, sizeof(tb)) == 0);
	CHECK(state_set(&a, "sun_illuminance_lx", tb, NULL, err, sizeof(err)) == 0);
	CHECK(memcmp(&a.sun.illuminance_lx, &b.sun.illuminance_lx, sizeof(double)) == 0);
	CHECK_EQ(state_diff(&a, &b), 0);
	/* The same keys, in the order weather then raw key: mie_g wins. */
	CHECK(state_set_pair(&a, "visibility_km=20", NULL, err, sizeof(err)) == 0);
	b = a;
	CHECK(state_set_pair(&b, "mie_g=0.8", NULL, err, sizeof(err)) == 0);
	CHECK(b.weather.overridden == STATE_OVERRIDE_MIE_G);
	CHECK_EQ(state_diff(&a, &b), STATE_ALL_TABLES);
	b = a;
	CHECK(state_set_cloud_factor(&b, 0.5, NULL) == 0);
	a.weather.in.cloud_oktas = b.weather.in.cloud_oktas;
	CHECK_EQ(state_diff(&a, &b), lights);
}

static void test_roundtrip(void)
{
	struct sky_state s;
	char err[256], buf[128];
	state_default(&s);
	CHECK(state_set_pair(&s, "rayleigh_scattering_per_km=1e-3,2e-3,3e-3", NULL, err, sizeof(err)) == 0);
	CHECK(state_get(&s, "rayleigh_scattering_per_km", buf, sizeof(buf)) == 0);
	CHECK(strcmp(buf, "0.001,0.002,0.003") == 0);
	CHECK(state_set_pair(&s, "mie_scale_height_km=2.5", NULL, err, sizeof(err)) == 0);
	CHECK(state_get(&s, "mie_scale_height_km", buf, sizeof(buf)) == 0);
	CHECK(strcmp(buf, "2.5") == 0);
	CHECK(state_get(&s, "no_such_key", buf, sizeof(buf)) < 0);
	uint32_t m;
	CHECK(state_parse_tables("skyview,aerial", &m) == 0 && m == 0xc);
	CHECK(state_closure(m) == STATE_ALL_TABLES);
	CHECK(state_parse_tables("skyview,bogus", &m) < 0);
}

/* The clock's keys: modes follow what was set, a rate alone invalidates
 * nothing, a rate change on a running clock keeps the time continuous. */
static void test_clock_keys(void)
{
	struct sky_state s, cur;
	char err[256], buf[64];
	uint32_t dirty = 0;

	state_default(&s);
	CHECK(s.sun.illuminance_lx == 133800.0);
	CHECK(s.clock.sun_mode == STATE_MANUAL && s.clock.moon_mode == STATE_MANUAL);
	CHECK(state_get(&s, "utc", buf, sizeof(buf)) == 0 && strcmp(buf, "none") == 0);
	CHECK(state_set_pair(&s, "utc=2026-06-21T18:30:00Z", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL)));
	CHECK(s.clock.sun_mode == STATE_CLOCK && s.clock.moon_mode == STATE_CLOCK);
	CHECK(fabs(state_clock_utc_s(&s, s.clock.anchor_mono_s) - 1782066600.0) < 1e-6);
	CHECK(state_set_pair(&s, "moon_elevation_deg=10", NULL, err, sizeof(err)) == 0);
	CHECK(s.clock.sun_mode == STATE_CLOCK && s.clock.moon_mode == STATE_MANUAL);
	CHECK(state_set_pair(&s, "moon_mode=clock", NULL, err, sizeof(err)) == 0);
	CHECK(s.clock.moon_mode == STATE_CLOCK);
	dirty = 0;
	cur = s;
	CHECK(state_set_pair(&s, "time_rate=60", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == 0);
	state_clock_rebase(&s, &cur, cur.clock.anchor_mono_s + 10.0);
	CHECK(fabs(state_clock_utc_s(&s, cur.clock.anchor_mono_s + 10.0) - (1782066600.0 + 10.0)) < 1e-6);
	CHECK(fabs(state_clock_utc_s(&s, cur.clock.anchor_mono_s + 11.0) - (1782066600.0 + 70.0)) < 1e-6);
	static const char *const bad[] = { "lat_deg=91", "lon_deg=-180.1", "utc=2026-13-01T00:00:00Z",
					   "utc=2026-06-21 18:30:00Z", "utc=2026-06-21T18:30:00",
					   "time_rate=2e6", "delta_t_s=x", "sun_mode=on", NULL };
	for (int i = 0; bad[i]; i++) {
		struct sky_state before = s;
		char key[32];
		snprintf(key, sizeof(key), "%.*s:", (int)strcspn(bad[i], "="), bad[i]);
		err[0] = 0;
		CHECK(state_set_pair(&s, bad[i], NULL, err, sizeof(err)) < 0);
		if (strncmp(err, key, strlen(key)) != 0)
			FAIL("%s: message '%s' does not start with %s", bad[i], err, key);
		s = before;
	}
	CHECK(state_set_pair(&s, "delta_t_s=auto", NULL, err, sizeof(err)) == 0 && isnan(s.clock.delta_t_s));
	CHECK(state_set_pair(&s, "night_illuminance_lx=1e-4", NULL, err, sizeof(err)) == 0);
	CHECK(state_validate(&s, 0, err, sizeof(err)) < 0 && strstr(err, "night_illuminance_lx") == err);
}

static void test_quality_presets(void)
{
	struct sky_state s, d;
	char err[256], buf[32];
	uint32_t dirty = 0;
	state_default(&s);
	d = s;
	CHECK(state_get(&s, "quality", buf, sizeof(buf)) == 0 && strcmp(buf, "medium") == 0);
	CHECK(state_set_pair(&s, "quality=low", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == STATE_ALL_TABLES);
	CHECK(s.quality.storage == STATE_F16 && s.quality.multiscatter_dirs == 2);
	CHECK(state_get(&s, "quality", buf, sizeof(buf)) == 0 && strcmp(buf, "low") == 0);
	CHECK(state_set_pair(&s, "skyview_steps=17", NULL, err, sizeof(err)) == 0);
	CHECK(state_get(&s, "quality", buf, sizeof(buf)) == 0 && strcmp(buf, "custom") == 0);
	CHECK(state_set_pair(&s, "quality=ultra", NULL, err, sizeof(err)) == 0);
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "quality=medium", NULL, err, sizeof(err)) == 0);
	CHECK(memcmp(&s.quality, &d.quality, sizeof(s.quality)) == 0);
	CHECK(state_set_pair(&s, "quality=best", NULL, err, sizeof(err)) < 0 && strstr(err, "quality"));
}

/* multiscatter_iterations: auto iterates only optically thick atmospheres
 * (Earth's vertical optical depth is 0.3, Mars's 0.4, ten times Earth's
 * scattering 2.7); an explicit count wins; multi-scattering off needs none. */
static void test_multiscatter_iterations(void)
{
	struct sky_state s;
	char err[256], buf[32];
	uint32_t dirty = 0;
	state_default(&s);
	CHECK(state_get(&s, "multiscatter_iterations", buf, sizeof(buf)) == 0 && strcmp(buf, "auto") == 0);
	CHECK(state_multiscatter_iterations(&s) == 0);
	CHECK(state_set_pair(&s, "preset=mars", NULL, err, sizeof(err)) == 0);
	CHECK(state_multiscatter_iterations(&s) == 0);
	state_default(&s);
	CHECK(state_set_pair(&s, "rayleigh_scattering_per_km=0.05802,0.13558,0.331", NULL, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "mie_scattering_per_km=0.03996", NULL, err, sizeof(err)) == 0);
	CHECK(state_multiscatter_iterations(&s) == 2);
	CHECK(state_set_pair(&s, "multiscatter_dirs=2", NULL, err, sizeof(err)) == 0);
	CHECK(state_multiscatter_iterations(&s) == 0);
	CHECK(state_set_pair(&s, "multiscatter_dirs=64", NULL, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "multiscatter_iterations=0", &dirty, err, sizeof(err)) == 0);
	CHECK(dirty == (STATE_ALL_TABLES & ~STATE_BIT(STATE_TRANSMITTANCE)));
	CHECK(state_multiscatter_iterations(&s) == 0);
	CHECK(state_set_pair(&s, "multiscatter_iterations=3", NULL, err, sizeof(err)) == 0);
	CHECK(state_multiscatter_iterations(&s) == 3);
	CHECK(state_get(&s, "quality", buf, sizeof(buf)) == 0 && strcmp(buf, "custom") == 0);
	CHECK(state_set_pair(&s, "multiscatter_dirs=0", NULL, err, sizeof(err)) == 0);
	CHECK(state_multiscatter_iterations(&s) == 0);
	CHECK(state_set_pair(&s, "multiscatter_iterations=5", NULL, err, sizeof(err)) == -EINVAL);
	CHECK(strstr(err, "multiscatter_iterations") != NULL);
}

int main(void)
{
	test_defaults_are_valid();
	test_refusals_name_the_key();
	test_cross_key_rules();
	test_invalidation();
	test_diff_exact();
	test_roundtrip();
	test_clock_keys();
	test_quality_presets();
	test_multiscatter_iterations();
	return test_report("test_state");
}

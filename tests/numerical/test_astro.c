/* test_astro.c - sun and moon against published cases and NREL's reference data. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "astro.h"
#include "simclock.h"
#include "test.h"

static double utc(const char *text)
{
	double s = NAN;
	if (simclock_parse_utc(text, &s) != 0)
		FAIL("cannot parse '%s'", text);
	return s;
}

/* Hours after local midnight of (year, month, day) at utc_offset_min. */
static double local_hours(double utc_s, int year, int month, int day, int utc_offset_min)
{
	double midnight_s = (double)simclock_days_from_civil(year, month, day) * 86400.0 -
			    utc_offset_min * 60.0;
	return (utc_s - midnight_s) / 3600.0;
}

/* The SPA report's example (Reda and Andreas, table A5.1 and its output). */
static const struct astro_site golden = { 39.742476, -105.1786, 1830.14 };

static struct astro_options golden_options(void)
{
	struct astro_options o;
	astro_options_default(&o);
	o.delta_t_auto = false;
	o.delta_t_s = 67.0;
	o.delta_ut1_s = 0.0;
	o.pressure_mbar = 820.0;
	o.temperature_c = 11.0;
	o.horizon_refraction_deg = 0.5667;
	return o;
}

static void test_spa_published_case(void)
{
	struct astro_options o = golden_options();
	struct astro_sun s;
	char err[256] = "";

	CHECK_EQ(astro_sun(&golden, utc("2003-10-17T12:30:30-07:00"), &o, &s, err, sizeof(err)), 0);
	CHECK_NEAR(s.apparent.zenith_deg, 50.11162, 1e-5);
	CHECK_NEAR(s.apparent.azimuth_deg, 194.34024, 1e-5);
	CHECK_NEAR(s.apparent.elevation_deg, 90.0 - 50.11162, 1e-5);
	/* The report's intermediate values: R, alpha, delta, topocentric e0. */
	CHECK_NEAR(s.distance_au, 0.9965422974, 1e-9);
	CHECK_NEAR(s.right_ascension_deg, 202.22741, 1e-5);
	CHECK_NEAR(s.declination_deg, -9.31434, 1e-5);
	CHECK_NEAR(s.geometric.elevation_deg, 39.872046, 1e-5);
	CHECK_NEAR(s.equation_of_time_min, 14.641503, 1e-4);
	CHECK_EQ(s.geometric.azimuth_deg, s.apparent.azimuth_deg);
	CHECK_EQ(s.delta_t_s, 67.0);
	CHECK_NEAR(s.angular_radius_deg, 0.2667, 0.001);
	CHECK(s.illuminance_lx > 130000.0 && s.illuminance_lx < 140000.0);
}

/* The report's published rise, transit and set for the same case: sunrise
 * 06:12:43.4, transit 11:46:04.97, sunset 17:20:19.2 local (UTC-7). The
 * report counts the day from 0 h UT, so its "sunset" is the one at 00:20 UT
 * of October 17, which is 17:20 local on October 16: astro_sun_times with
 * a zero offset reproduces the report's numbers (to 0.05 s: it repeats the
 * report's single correction step), and the local-day form gives the same
 * events under their own local dates. */
static void test_spa_published_times(void)
{
	static const double transit_h = 11.0 + 46.0 / 60.0 + 4.97 / 3600.0;
	static const double sunrise_h = 6.212067;	/* 06:12:43.44 */
	static const double sunset_h = 17.338667;	/* 17:20:19.20 */
	static const double second_h = 1.0 / 3600.0;
	struct astro_options o = golden_options();
	struct astro_times t;
	char err[256];

	struct astro_date ut_day = { 2003, 10, 17, 0 };
	CHECK_EQ(astro_sun_times(&golden, &ut_day, &o, &t, err, sizeof(err)), 0);
	CHECK_EQ(t.sunrise_sunset.kind, ASTRO_RISES_AND_SETS);
	double tr = local_hours(t.transit_utc_s, 2003, 10, 17, -420);
	double ri = local_hours(t.sunrise_sunset.rise_utc_s, 2003, 10, 17, -420);
	double se = local_hours(t.sunrise_sunset.set_utc_s, 2003, 10, 16, -420);
	printf("SPA case, report's UT day: transit %.6f h (%+.3f s), sunrise %.6f h (%+.3f s), "
	       "sunset %.6f h (%+.3f s)\n", tr, (tr - transit_h) * 3600.0, ri,
	       (ri - sunrise_h) * 3600.0, se, (se - sunset_h) * 3600.0);
	CHECK_NEAR(tr, transit_h, 0.05 * second_h);
	CHECK_NEAR(ri, sunrise_h, 0.05 * second_h);
	CHECK_NEAR(se, sunset_h, 0.05 * second_h);

	struct astro_date oct17 = { 2003, 10, 17, -420 }, oct16 = { 2003, 10, 16, -420 };
	CHECK_EQ(astro_sun_times(&golden, &oct17, &o, &t, err, sizeof(err)), 0);
	CHECK_NEAR(local_hours(t.transit_utc_s, 2003, 10, 17, -420), transit_h, second_h);
	CHECK_NEAR(local_hours(t.sunrise_sunset.rise_utc_s, 2003, 10, 17, -420), sunrise_h, second_h);
	double set17 = local_hours(t.sunrise_sunset.set_utc_s, 2003, 10, 17, -420);
	CHECK(t.transit_elevation_deg > 39.0 && t.transit_elevation_deg < 41.0);
	/* Twilights nest around the day, in order. */
	CHECK(t.astronomical.rise_utc_s < t.nautical.rise_utc_s);
	CHECK(t.nautical.rise_utc_s < t.civil.rise_utc_s);
	CHECK(t.civil.rise_utc_s < t.sunrise_sunset.rise_utc_s);
	CHECK(t.sunrise_sunset.set_utc_s < t.civil.set_utc_s);
	CHECK(t.civil.set_utc_s < t.nautical.set_utc_s);
	CHECK(t.nautical.set_utc_s < t.astronomical.set_utc_s);

	CHECK_EQ(astro_sun_times(&golden, &oct16, &o, &t, err, sizeof(err)), 0);
	double set16 = local_hours(t.sunrise_sunset.set_utc_s, 2003, 10, 16, -420);
	printf("SPA case, local days: sunset Oct 16 %.6f h (%+.3f s vs the report), Oct 17 %.6f h\n",
	       set16, (set16 - sunset_h) * 3600.0, set17);
	CHECK_NEAR(set16, sunset_h, second_h);
	CHECK(set17 < set16 - 60.0 * second_h); /* October evenings shorten ~1.5 min a day */
}

/* Each event puts the sun where its threshold says (geometric, centre);
 * the events are computed geocentric, so parallax (< 0.0025 deg) remains. */
static void test_events_hit_their_thresholds(void)
{
	struct astro_options o = golden_options();
	struct astro_date day = { 2026, 3, 20, -360 };
	struct astro_times t;
	struct astro_sun s;
	char err[256];

	CHECK_EQ(astro_sun_times(&golden, &day, &o, &t, err, sizeof(err)), 0);
	const struct astro_rise_set *rs[] = { &t.sunrise_sunset, &t.civil, &t.nautical,
					      &t.astronomical };
	for (size_t i = 0; i < 4; i++) {
		CHECK_EQ(rs[i]->kind, ASTRO_RISES_AND_SETS);
		CHECK_EQ(astro_sun(&golden, rs[i]->rise_utc_s, &o, &s, err, sizeof(err)), 0);
		CHECK_NEAR(s.geometric.elevation_deg, rs[i]->threshold_deg, 0.003);
		CHECK(s.geometric.azimuth_deg < 180.0);
		CHECK_EQ(astro_sun(&golden, rs[i]->set_utc_s, &o, &s, err, sizeof(err)), 0);
		CHECK_NEAR(s.geometric.elevation_deg, rs[i]->threshold_deg, 0.003);
		CHECK(s.geometric.azimuth_deg > 180.0);
	}
	CHECK_NEAR(t.sunrise_sunset.threshold_deg, -0.83337, 1e-9);
	CHECK_EQ(astro_sun(&golden, t.transit_utc_s, &o, &s, err, sizeof(err)), 0);
	CHECK_NEAR(s.hour_angle_deg, 0.0, 0.01);
}

/* Every row of NREL's reference data, within SPA's own +-0.0003 degrees. */
static void test_spa_reference_csv(void)
{
	const char *path = SKYD_TEST_DATA "/spa_reference.csv";
	char line[512];
	FILE *f;

	f = fopen(path, "re");
	if (!f) {
		FAIL("cannot open %s", path);
		return;
	}
	struct astro_options o;
	astro_options_default(&o);
	o.delta_t_auto = false;
	o.delta_t_s = 0.0;
	o.pressure_mbar = 1000.0;
	o.temperature_c = 10.0;
	o.horizon_refraction_deg = 0.5667;

	int rows = 0, bad = 0;
	double worst_zen = 0.0, worst_az = 0.0;
	char worst_zen_line[512] = "", worst_az_line[512] = "";
	while (fgets(line, sizeof(line), f)) {
		char when[64];
		double lat, lon, az, zen;
		struct astro_sun s;
		char err[256];

		if (line[0] == '#' || line[0] == '\n')
			continue;
		line[strcspn(line, "\n")] = '\0';
		if (sscanf(line, "%63[^,],%lf,%lf,%lf,%lf", when, &lat, &lon, &az, &zen) != 5) {
			FAIL("malformed row '%s'", line);
			continue;
		}
		rows++;
		struct astro_site site = { lat, lon, 0.0 };
		if (astro_sun(&site, utc(when), &o, &s, err, sizeof(err)) != 0) {
			FAIL("'%s': %s", line, err);
			continue;
		}
		double dz = fabs(s.apparent.zenith_deg - zen);
		double da = fabs(fmod(s.apparent.azimuth_deg - az + 540.0, 360.0) - 180.0);
		/* Azimuth error as an angle on the sky: it shrinks near the zenith. */
		double da_sky = da * sin(zen * M_PI / 180.0);
		if (dz > worst_zen)
			worst_zen = dz, snprintf(worst_zen_line, sizeof(worst_zen_line), "%s", line);
		if (da_sky > worst_az)
			worst_az = da_sky, snprintf(worst_az_line, sizeof(worst_az_line), "%s", line);
		if (dz > 0.0003 || da_sky > 0.0003) {
			bad++;
			FAIL("'%s': zenith %.6f azimuth %.6f", line, s.apparent.zenith_deg,
			     s.apparent.azimuth_deg);
		}
	}
	fclose(f);
	test_checks++;
	printf("spa_reference.csv: %d rows, %d outside 0.0003 deg; worst zenith error %.2e deg (%s), "
	       "worst azimuth error x sin(zenith) %.2e deg (%s)\n",
	       rows, bad, worst_zen, worst_zen_line, worst_az, worst_az_line);
	CHECK_EQ(rows, 512);
}

/* Meeus example 47.a (1992-04-12 0h TD) and 48.a (same instant). */
static void test_meeus_moon(void)
{
	struct astro_site site = { 0.0, 0.0, 0.0 };
	struct astro_options o;
	struct astro_moon m;
	char err[256];

	astro_options_default(&o);
	o.delta_t_auto = false;
	o.delta_t_s = 0.0;	/* 0h TD: give the time as TT */
	CHECK_EQ(astro_moon(&site, utc("1992-04-12T00:00:00Z"), &o, &m, err, sizeof(err)), 0);
	CHECK_NEAR(m.longitude_deg, 133.162655, 0.5e-6);
	CHECK_NEAR(m.latitude_deg, -3.229126, 0.5e-6);
	CHECK_NEAR(m.distance_km, 368409.7, 0.05);
	/* 47.a goes on: apparent lambda 133.167265, alpha 134.688470, delta
	 * 13.768368, with Meeus's nutation (ch. 22) where this uses SPA's
	 * 63 terms: agreement to about a microdegree. */
	CHECK_NEAR(m.apparent_longitude_deg, 133.167265, 2e-6);
	CHECK_NEAR(m.right_ascension_deg, 134.688470, 2e-6);
	CHECK_NEAR(m.declination_deg, 13.768368, 2e-6);
	CHECK_NEAR(m.illuminated_fraction, 0.6786, 0.5e-4);
	CHECK_NEAR(m.phase_angle_deg, 69.0756, 0.001);
	CHECK(m.waxing);
	CHECK(m.angular_radius_deg > 0.26 && m.angular_radius_deg < 0.28);
	CHECK(m.topocentric_distance_km < m.distance_km);
}

static void test_moon_light(void)
{
	struct astro_site site = { 46.5, 7.98, 3571.0 };	/* a high-altitude site */
	struct astro_moon m;
	char err[256];

	/* Mean-distance full moon: 0.314 lx outside the atmosphere. */
	double full = astro_moon_illuminance_lx(0.0, 384400.0, 1.0);
	CHECK_NEAR(full, 0.314, 0.002);
	/* docs/physics.md: a quarter moon is about 9 % of the full one. */
	CHECK_NEAR(astro_moon_illuminance_lx(90.0, 384400.0, 1.0) / full, 0.09, 0.01);
	CHECK_EQ(astro_moon_illuminance_lx(180.0, 384400.0, 1.0), 0.0);
	CHECK_EQ(astro_moon_illuminance_lx(NAN, 384400.0, 1.0), 0.0);

	/* Full moon 2024-01-25 17:54 UTC, new moon 2024-01-11 11:57 UTC. */
	CHECK(astro_moon(&site, utc("2024-01-25T17:54:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(m.illuminated_fraction > 0.998);
	/* That full moon was far (401000 km) and 4.8 deg off opposition. */
	CHECK(m.illuminance_lx > 0.25 && m.illuminance_lx < full);
	CHECK(astro_moon(&site, utc("2024-01-11T11:57:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(m.illuminated_fraction < 0.002);
	CHECK(m.illuminance_lx < 1e-3);
	CHECK(astro_moon(&site, utc("2024-01-18T00:00:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(m.waxing);
	CHECK(astro_moon(&site, utc("2024-02-01T00:00:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(!m.waxing);
	/* Moonlight is reddened sunlight of luminance 1. */
	double y = 0.2126 * m.color[0] + 0.7152 * m.color[1] + 0.0722 * m.color[2];
	CHECK_NEAR(y, 1.0, 1e-12);
	CHECK(m.color[0] > m.color[1] && m.color[1] > m.color[2]);
	/* Parallax: the topocentric moon sits lower than the geocentric one,
	 * by up to about a degree. */
	CHECK(m.geometric.elevation_deg >= -90.0 && m.geometric.elevation_deg <= 90.0);
}

/* Tromso (69.65 N) and the poles: polar day and night say so, with no times. */
static void test_polar(void)
{
	struct astro_site tromso = { 69.65, 18.96, 0.0 }, south_pole = { -90.0, 0.0, 2835.0 },
			  north_pole = { 90.0, 0.0, 0.0 };
	struct astro_times t;
	char err[256];

	struct astro_date midsummer = { 2026, 6, 21, 120 }, midwinter = { 2026, 12, 21, 60 };
	CHECK(astro_sun_times(&tromso, &midsummer, NULL, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.sunrise_sunset.kind, ASTRO_ALWAYS_ABOVE);
	CHECK(isnan(t.sunrise_sunset.rise_utc_s) && isnan(t.sunrise_sunset.set_utc_s));
	CHECK_EQ(t.astronomical.kind, ASTRO_ALWAYS_ABOVE);
	CHECK(isfinite(t.transit_utc_s));

	CHECK(astro_sun_times(&tromso, &midwinter, NULL, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.sunrise_sunset.kind, ASTRO_ALWAYS_BELOW);
	CHECK(isnan(t.sunrise_sunset.rise_utc_s) && isnan(t.sunrise_sunset.set_utc_s));
	/* The noon sun reaches about -3 degrees: civil twilight still happens. */
	CHECK_EQ(t.civil.kind, ASTRO_RISES_AND_SETS);
	CHECK(t.civil.rise_utc_s < t.transit_utc_s && t.transit_utc_s < t.civil.set_utc_s);
	CHECK(t.transit_elevation_deg > -4.0 && t.transit_elevation_deg < -2.0);

	CHECK(astro_sun_times(&south_pole, &midwinter, NULL, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.sunrise_sunset.kind, ASTRO_ALWAYS_ABOVE);
	CHECK_EQ(t.civil.kind, ASTRO_ALWAYS_ABOVE);
	CHECK(astro_sun_times(&north_pole, &midwinter, NULL, &t, err, sizeof(err)) == 0);
	CHECK_EQ(t.sunrise_sunset.kind, ASTRO_ALWAYS_BELOW);
	CHECK_EQ(t.astronomical.kind, ASTRO_ALWAYS_BELOW);

	/* At the pole the sun's elevation is its declination, give or take. */
	struct astro_sun s;
	CHECK(astro_sun(&north_pole, utc("2026-06-21T12:00:00Z"), NULL, &s, err, sizeof(err)) == 0);
	CHECK_NEAR(s.geometric.elevation_deg, s.declination_deg, 0.01);
	CHECK(isfinite(s.geometric.azimuth_deg));
}

/* 1900 and 2100: delta T's branches, the secular terms, and the transit
 * against the equation of time (two independent paths through the code). */
static void test_1900_and_2100(void)
{
	struct astro_site greenwich = { 51.4769, 0.0, 46.0 };
	struct astro_sun s;
	struct astro_times t;
	char err[256];

	CHECK_NEAR(astro_delta_t_s(1900.0), -2.79, 1e-9);
	CHECK_NEAR(astro_delta_t_s(2000.0), 63.86, 1e-9);
	CHECK_NEAR(astro_delta_t_s(2100.0), -20.0 + 32.0 * 2.8 * 2.8 - 0.5628 * 50.0, 1e-9);
	CHECK_NEAR(astro_delta_t_s(3000.0), -20.0 + 32.0 * 11.8 * 11.8, 1e-9);
	/* The branches meet within a second or so where they join. */
	static const double joins[] = { 1600, 1700, 1800, 1860, 1900, 1920, 1941, 1961,
					1986, 2005, 2050, 2150 };
	for (size_t i = 0; i < sizeof(joins) / sizeof(joins[0]); i++)
		CHECK_NEAR(astro_delta_t_s(joins[i] - 1e-9), astro_delta_t_s(joins[i]), 1.5);
	CHECK_NEAR(astro_decimal_year(utc("2026-07-02T12:00:00Z")), 2026.5, 1e-9);
	CHECK_NEAR(astro_decimal_year(utc("1900-01-01T00:00:00Z")), 1900.0, 1e-12);

	/* June solstice declination = obliquity: 23.4523 in 1900, 23.4263 in
	 * 2100 (Laskar), to within nutation (+-0.0026). */
	static const struct {
		const char *when;
		double obliquity_deg;
	} solstices[] = { { "1900-06-21T20:00:00Z", 23.4523 }, { "2100-06-21T06:00:00Z", 23.4263 } };
	for (size_t i = 0; i < 2; i++) {
		double best = -90.0, t0 = utc(solstices[i].when);
		for (int h = -48; h <= 48; h++) {
			CHECK(astro_sun(&greenwich, t0 + h * 3600.0, NULL, &s, err, sizeof(err)) == 0);
			best = fmax(best, s.declination_deg);
		}
		CHECK_NEAR(best, solstices[i].obliquity_deg, 0.004);
	}

	static const struct astro_date days[] = { { 1900, 1, 1, 0 }, { 1900, 11, 3, 0 },
						   { 2100, 1, 1, 0 }, { 2100, 7, 26, 0 } };
	for (size_t i = 0; i < 4; i++) {
		CHECK(astro_sun_times(&greenwich, &days[i], NULL, &t, err, sizeof(err)) == 0);
		CHECK(astro_sun(&greenwich, t.transit_utc_s, NULL, &s, err, sizeof(err)) == 0);
		double noon_h = local_hours(t.transit_utc_s, days[i].year, days[i].month, days[i].day, 0);
		CHECK_NEAR(noon_h, 12.0 - s.equation_of_time_min / 60.0, 1.0 / 3600.0);
		CHECK_EQ(t.sunrise_sunset.kind, ASTRO_RISES_AND_SETS);
	}

	struct astro_moon m;
	CHECK(astro_moon(&greenwich, utc("1900-01-01T00:00:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(m.distance_km > 356000.0 && m.distance_km < 407000.0);
	CHECK(astro_moon(&greenwich, utc("2100-12-31T00:00:00Z"), NULL, &m, err, sizeof(err)) == 0);
	CHECK(m.distance_km > 356000.0 && m.distance_km < 407000.0);
}

static void test_refraction(void)
{
	struct astro_site site = { 0.0, 0.0, 0.0 };
	struct astro_options o;
	struct astro_times t;
	struct astro_sun s;
	char err[256];
	struct astro_date day = { 2026, 3, 20, 0 };

	astro_options_default(&o);
	CHECK_EQ(astro_sun_times(&site, &day, &o, &t, err, sizeof(err)), 0);
	/* Two minutes after sunrise (centre 0.33 deg below the horizon) the
	 * apparent centre is lifted about half a degree (SPA eq. 42: 0.53). */
	double after_s = t.sunrise_sunset.rise_utc_s + 120.0;
	CHECK_EQ(astro_sun(&site, after_s, &o, &s, err, sizeof(err)), 0);
	double lift = s.apparent.elevation_deg - s.geometric.elevation_deg;
	CHECK(lift > 0.45 && lift < 0.6);
	/* No air, no refraction; deep below the horizon, none either. */
	o.pressure_mbar = 0.0;
	CHECK_EQ(astro_sun(&site, after_s, &o, &s, err, sizeof(err)), 0);
	CHECK_EQ(s.apparent.elevation_deg, s.geometric.elevation_deg);
	astro_options_default(&o);
	CHECK_EQ(astro_sun(&site, t.transit_utc_s + 43200.0, &o, &s, err, sizeof(err)), 0);
	CHECK(s.geometric.elevation_deg < -80.0);
	CHECK_EQ(s.apparent.elevation_deg, s.geometric.elevation_deg);
	CHECK_NEAR(s.geometric.zenith_deg + s.geometric.elevation_deg, 90.0, 1e-12);
}

static void test_refusals(void)
{
	static const struct {
		struct astro_site site;
		const char *key;
	} sites[] = {
		{ { 90.5, 0, 0 }, "lat_deg" }, { { -91, 0, 0 }, "lat_deg" },
		{ { NAN, 0, 0 }, "lat_deg" }, { { 0, 180.5, 0 }, "lon_deg" },
		{ { 0, -181, 0 }, "lon_deg" }, { { 0, INFINITY, 0 }, "lon_deg" },
		{ { 0, 0, -5000 }, "elevation_m" }, { { 0, 0, NAN }, "elevation_m" },
	};
	struct astro_site ok = { 10, 20, 0 };
	struct astro_sun s, untouched;
	struct astro_moon m;
	struct astro_times t;
	struct astro_date day = { 2026, 6, 21, 0 };
	double now = utc("2026-06-21T18:30:00Z");
	char err[256];

	memset(&untouched, 0xa5, sizeof(untouched));
	for (size_t i = 0; i < sizeof(sites) / sizeof(sites[0]); i++) {
		err[0] = '\0';
		s = untouched;
		CHECK(astro_sun(&sites[i].site, now, NULL, &s, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, sites[i].key) != NULL);
		CHECK(memcmp(&s, &untouched, sizeof(s)) == 0);
		err[0] = '\0';
		CHECK(astro_moon(&sites[i].site, now, NULL, &m, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, sites[i].key) != NULL);
		err[0] = '\0';
		CHECK(astro_sun_times(&sites[i].site, &day, NULL, &t, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, sites[i].key) != NULL);
	}
	/* Edges are in. */
	struct astro_site edge = { -90, 180, 0 };
	CHECK(astro_sun(&edge, now, NULL, &s, err, sizeof(err)) == 0);
	edge = (struct astro_site){ 90, -180, 0 };
	CHECK(astro_moon(&edge, now, NULL, &m, err, sizeof(err)) == 0);

	/* Times: not ISO, month 13, outside SPA's years, not a number. */
	double x = 0.0;
	CHECK_EQ(simclock_parse_utc("2026-13-01T00:00:00Z", &x), -EINVAL);
	CHECK_EQ(simclock_parse_utc("21/06/2026 18:30", &x), -EINVAL);
	CHECK_EQ(simclock_parse_utc("2026-06-21T18:30:00", &x), -EINVAL);
	static const double bad_times[] = { NAN, INFINITY, -1e12, 1e12 };
	for (size_t i = 0; i < 4; i++) {
		err[0] = '\0';
		CHECK(astro_sun(&ok, bad_times[i], NULL, &s, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, "utc") != NULL);
		err[0] = '\0';
		CHECK(astro_moon(&ok, bad_times[i], NULL, &m, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, "utc") != NULL);
	}

	static const struct {
		struct astro_date date;
		const char *key;
	} dates[] = {
		{ { 2026, 13, 1, 0 }, "month" }, { { 2026, 0, 1, 0 }, "month" },
		{ { 2026, 1, 32, 0 }, "day" }, { { 2026, 2, 29, 0 }, "day" },
		{ { 2026, 6, 0, 0 }, "day" }, { { 7000, 1, 1, 0 }, "year" },
		{ { 2026, 6, 21, 2000 }, "utc_offset_min" },
	};
	for (size_t i = 0; i < sizeof(dates) / sizeof(dates[0]); i++) {
		err[0] = '\0';
		CHECK(astro_sun_times(&ok, &dates[i].date, NULL, &t, err, sizeof(err)) == -EINVAL);
		CHECK(strstr(err, dates[i].key) != NULL);
	}

	struct astro_options o;
	static const char *opt_keys[] = { "pressure_mbar", "temperature_c", "delta_t_s",
					  "delta_ut1_s", "horizon_refraction_deg" };
	for (int i = 0; i < 5; i++) {
		astro_options_default(&o);
		switch (i) {
		case 0: o.pressure_mbar = -1; break;
		case 1: o.temperature_c = -300; break;
		case 2: o.delta_t_auto = false, o.delta_t_s = NAN; break;
		case 3: o.delta_ut1_s = 1.5; break;
		case 4: o.horizon_refraction_deg = NAN; break;
		}
		err[0] = '\0';
		CHECK_EQ(astro_sun(&ok, now, &o, &s, err, sizeof(err)), -EINVAL);
		CHECK(strstr(err, opt_keys[i]) != NULL);
	}
	/* A NULL or zero-sized err buffer is fine. */
	CHECK(astro_sun(&sites[0].site, now, NULL, &s, NULL, 0) == -EINVAL);
}

int main(void)
{
	test_spa_published_case();
	test_spa_published_times();
	test_events_hit_their_thresholds();
	test_spa_reference_csv();
	test_meeus_moon();
	test_moon_light();
	test_polar();
	test_1900_and_2100();
	test_refraction();
	test_refusals();
	return test_report("test_astro");
}

/* test_daemon_clock.c - the daemon's clock against the real skyd: time and
 * place drive the sun and moon, the rate moves them, polar days and nights
 * are said, bad input is refused with the state untouched. */
#include <math.h>
#include <sys/mman.h>

#include "astro.h"
#include "daemon_harness.h"
#include "simclock.h"
#include "skyproto.h"
#include "test.h"

static char reply[1 << 17];

static double get_num(struct conn *c, const char *req, const char *key)
{
	char buf[128];
	if (conn_request(c, req, reply, sizeof(reply)) != 0 || !reply_value(reply, key, buf, sizeof(buf)))
		return NAN;
	return strtod(buf, NULL);
}

static const char *get_str(struct conn *c, const char *req, const char *key, char *buf, size_t size)
{
	if (conn_request(c, req, reply, sizeof(reply)) != 0 || !reply_value(reply, key, buf, size))
		return "";
	return buf;
}

static const struct astro_site golden = { 39.742476, -105.1786, 1830.0 };
#define GOLDEN_SET "lat_deg=39.742476 lon_deg=-105.1786 site_elevation_m=1830"

/* Time and place in; the sun the daemon reports and lights the tables with
 * is astro's for that time; the slot it publishes carries time and place. */
static void test_sun_matches_astro(struct conn *c, struct conn *ev)
{
	char buf[128];
	double utc_s;
	struct astro_sun a;

	CHECK(strcmp(get_str(c, "get utc", "utc", buf, sizeof(buf)), "none") == 0);
	CHECK(strcmp(get_str(c, "get sun_mode", "sun_mode", buf, sizeof(buf)), "manual") == 0);
	CHECK(conn_request(c, "get sun", reply, sizeof(reply)) == SKY_ACK_STATE);
	CHECK(strstr(reply, "utc:") != NULL);

	CHECK(conn_request(c, "set utc=2026-06-21T18:30:00Z time_rate=0 " GOLDEN_SET, reply,
			   sizeof(reply)) == 0);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(strcmp(get_str(c, "get utc", "utc", buf, sizeof(buf)), "2026-06-21T18:30:00Z") == 0);
	CHECK(strcmp(get_str(c, "get sun_mode", "sun_mode", buf, sizeof(buf)), "clock") == 0);
	CHECK(simclock_parse_utc("2026-06-21T18:30:00Z", &utc_s) == 0);
	CHECK(astro_sun(&golden, utc_s, NULL, &a, NULL, 0) == 0);
	CHECK(conn_request(c, "get sun", reply, sizeof(reply)) == 0);
	CHECK_NEAR(get_num(c, "get sun", "elevation_deg"), a.geometric.elevation_deg, 2e-6);
	CHECK_NEAR(get_num(c, "get sun", "azimuth_deg"), a.geometric.azimuth_deg, 2e-6);
	CHECK_NEAR(get_num(c, "get sun", "apparent_zenith_deg"), a.apparent.zenith_deg, 2e-6);
	CHECK_NEAR(get_num(c, "get sun", "equation_of_time_min"), a.equation_of_time_min, 2e-6);
	CHECK_NEAR(get_num(c, "get sun", "illuminance_lx"), a.illuminance_lx, 2e-3);
	/* The tables get the geometric direction and astro's illuminance. */
	CHECK_NEAR(get_num(c, "get sun_elevation_deg", "sun_elevation_deg"), a.geometric.elevation_deg, 1e-6);
	CHECK_NEAR(get_num(c, "get sun_azimuth_deg", "sun_azimuth_deg"), a.geometric.azimuth_deg, 1e-6);
	CHECK_NEAR(get_num(c, "get sun_illuminance_lx", "sun_illuminance_lx"), a.illuminance_lx, 1e-3);
	printf("sun 2026-06-21T18:30Z golden: elevation %.6f azimuth %.6f (astro %.6f %.6f)\n",
	       get_num(c, "get sun", "elevation_deg"), get_num(c, "get sun", "azimuth_deg"),
	       a.geometric.elevation_deg, a.geometric.azimuth_deg);

	/* The published slot carries the time and place that lit it. */
	struct conn sub;
	CHECK(conn_wait_generation(ev, g) == 0);
	if (conn_open(&sub, getenv("SKYD_TEST_SOCK")) == 0 &&
	    conn_request(&sub, "subscribe tables=all", reply, sizeof(reply)) == 0 && sub.n_fds == 1) {
		size_t bytes = reply_u64(reply, "shm_bytes");
		const uint8_t *m = mmap(NULL, bytes, PROT_READ, MAP_SHARED, sub.fds[0], 0);
		CHECK(m != MAP_FAILED);
		if (m != MAP_FAILED) {
			const struct sky_shm_header *h = (const void *)m;
			const struct sky_shm_slot *s = (const void *)(m + h->header_bytes +
				__atomic_load_n(&h->current_slot, __ATOMIC_ACQUIRE) * h->slot_bytes);
			CHECK(s->generation >= g);
			CHECK_NEAR(s->state.utc_unix_s, utc_s, 1e-6);
			CHECK_NEAR(s->state.latitude_rad, golden.lat_deg * M_PI / 180.0, 1e-12);
			CHECK_NEAR(s->state.longitude_rad, golden.lon_deg * M_PI / 180.0, 1e-12);
			CHECK_NEAR(asin(s->state.sun_direction[2]) * 180.0 / M_PI, a.geometric.elevation_deg, 1e-6);
			munmap((void *)m, bytes);
		}
	} else {
		FAIL("subscribe tables=all for the slot state");
	}
	conn_close(&sub);
}

/* The sun's disk follows its distance in steps of DRIVE_SUN_RADIUS_STEP_DEG,
 * so that a move of the clock recomputes multi-scattering only when the
 * step changes: not for a minute later, but for half a year later. */
static void test_radius_steps(struct conn *c)
{
	char buf[256];

	CHECK(conn_request(c, "set utc=2026-03-10T12:00:00Z time_rate=0 sun_mode=clock", reply,
			   sizeof(reply)) == 0);
	double r0 = get_num(c, "get sun_angular_radius_deg", "sun_angular_radius_deg");
	CHECK_NEAR(r0 / 1e-5, round(r0 / 1e-5), 1e-6);
	CHECK(conn_request(c, "set utc=2026-03-10T12:01:00Z", reply, sizeof(reply)) == 0);
	CHECK(reply_value(reply, "tables", buf, sizeof(buf)) && strcmp(buf, "skyview,aerial") == 0);
	printf("a minute later: tables %s\n", buf);
	CHECK(conn_request(c, "set utc=2026-09-10T12:01:00Z", reply, sizeof(reply)) == 0);
	CHECK(reply_value(reply, "tables", buf, sizeof(buf)) && strstr(buf, "multiscatter") != NULL);
	CHECK(get_num(c, "get sun_angular_radius_deg", "sun_angular_radius_deg") != r0);
	printf("half a year later: tables %s\n", buf);
}

/* Rate 0 freezes; a high rate moves the sun and the daemon recomputes on
 * its own (a changed: event nobody asked for); a negative rate runs back. */
static void test_rate(struct conn *c, struct conn *ev)
{
	char t1[64], t2[64];

	CHECK(conn_request(c, "set utc=2026-06-21T12:00:00Z time_rate=0", reply, sizeof(reply)) == 0);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(conn_wait_generation(ev, g) == 0);
	get_str(c, "get utc", "utc", t1, sizeof(t1));
	CHECK(strcmp(t1, "2026-06-21T12:00:00Z") == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "clock_next_tick_s: none\n") != NULL);
	get_str(c, "get utc", "utc", t2, sizeof(t2));
	CHECK(strcmp(t1, t2) == 0);

	double el0 = get_num(c, "get sun_elevation_deg", "sun_elevation_deg");
	double u0;
	CHECK(simclock_parse_utc(t1, &u0) == 0);
	/* An hour a second: 15 deg/s; recompute past 0.5 deg. */
	CHECK(conn_request(c, "set time_rate=3600 clock_threshold_deg=0.5", reply, sizeof(reply)) == 0);
	g = reply_u64(reply, "generation");
	CHECK(conn_wait_generation(ev, g + 1) == 0);
	CHECK(conn_request(c, "set time_rate=0", reply, sizeof(reply)) == 0);
	double el1 = get_num(c, "get sun_elevation_deg", "sun_elevation_deg"), u1;
	get_str(c, "get utc", "utc", t1, sizeof(t1));
	CHECK(simclock_parse_utc(t1, &u1) == 0);
	printf("rate 3600: simulated %.1f s later, sun elevation %.4f -> %.4f deg\n", u1 - u0, el0, el1);
	CHECK(u1 - u0 > 60.0);
	CHECK(fabs(el1 - el0) > 0.2);
	struct astro_sun a;
	CHECK(astro_sun(&golden, u1, NULL, &a, NULL, 0) == 0);
	CHECK_NEAR(el1, a.geometric.elevation_deg, 1e-6);

	CHECK(conn_request(c, "set time_rate=-3600", reply, sizeof(reply)) == 0);
	g = reply_u64(reply, "generation");
	CHECK(conn_wait_generation(ev, g + 1) == 0);
	CHECK(conn_request(c, "set time_rate=0", reply, sizeof(reply)) == 0);
	double u2;
	get_str(c, "get utc", "utc", t2, sizeof(t2));
	CHECK(simclock_parse_utc(t2, &u2) == 0);
	CHECK(u2 < u1 - 60.0);
}

/* Manual angles take a light from the clock; sun_mode=clock gives it back. */
static void test_modes(struct conn *c)
{
	char buf[64];

	CHECK(conn_request(c, "set sun_elevation_deg=60", reply, sizeof(reply)) == 0);
	CHECK(strcmp(get_str(c, "get sun_mode", "sun_mode", buf, sizeof(buf)), "manual") == 0);
	CHECK(strcmp(get_str(c, "get moon_mode", "moon_mode", buf, sizeof(buf)), "clock") == 0);
	CHECK_NEAR(get_num(c, "get sun_elevation_deg", "sun_elevation_deg"), 60.0, 0);
	double el = get_num(c, "get sun", "elevation_deg");
	CHECK(fabs(el - 60.0) > 1.0);
	CHECK(conn_request(c, "set sun_mode=clock", reply, sizeof(reply)) == 0);
	CHECK_NEAR(get_num(c, "get sun_elevation_deg", "sun_elevation_deg"), el, 1e-6);
}

static void check_times(struct conn *c, const struct astro_site *site, int y, int mo, int d,
			const char *sunrise)
{
	char req[128], buf[128];
	struct astro_times t;
	struct astro_date date = { y, mo, d, 0 };

	snprintf(req, sizeof(req), "get times date=%04d-%02d-%02d utc_offset_min=0", y, mo, d);
	get_str(c, req, "sunrise_utc", buf, sizeof(buf));
	CHECK(astro_sun_times(site, &date, NULL, &t, NULL, 0) == 0);
	if (sunrise) {
		if (strcmp(buf, sunrise) != 0)
			FAIL("%s: sunrise_utc '%s', want '%s'", req, buf, sunrise);
		return;
	}
	double got;
	CHECK(simclock_parse_utc(buf, &got) == 0);
	CHECK_NEAR(got, t.sunrise_sunset.rise_utc_s, 1e-3);
	get_str(c, req, "civil_dusk_utc", buf, sizeof(buf));
	CHECK(simclock_parse_utc(buf, &got) == 0);
	CHECK_NEAR(got, t.civil.set_utc_s, 1e-3);
}

static void test_times(struct conn *c)
{
	char buf[128];
	static const struct astro_site svalbard = { 78.0, 15.0, 0.0 };

	check_times(c, &golden, 2026, 6, 21, NULL);
	CHECK(conn_request(c, "set lat_deg=78 lon_deg=15 site_elevation_m=0", reply, sizeof(reply)) == 0);
	check_times(c, &svalbard, 2026, 6, 21, "none (polar day)");
	check_times(c, &svalbard, 2026, 12, 21, "none (polar night)");
	CHECK(strcmp(get_str(c, "get times date=2026-12-21", "civil_dusk_utc", buf, sizeof(buf)),
		     "none (sun never above -6 deg)") == 0);
	/* The default date is the simulated one, in the longitude's zone. */
	CHECK(conn_request(c, "get times", reply, sizeof(reply)) == 0);
	CHECK(strcmp(reply_value(reply, "utc_offset_min", buf, sizeof(buf)) ? buf : "", "60") == 0);
	CHECK(conn_request(c, "get times date=2026-02-30", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(strstr(reply, "{get} date:") != NULL);
	CHECK(conn_request(c, "get times date=tomorrow", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "get times when=1", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "set " GOLDEN_SET, reply, sizeof(reply)) == 0);
}

/* Each bad value is refused naming its key, and nothing changes. */
static void test_invalid(struct conn *c)
{
	static const struct {
		const char *req, *key;
	} bad[] = {
		{ "set lat_deg=91", "lat_deg" },
		{ "set lat_deg=-90.5", "lat_deg" },
		{ "set lon_deg=181", "lon_deg" },
		{ "set lat_deg=nan", "lat_deg" },
		{ "set utc=2026-13-01T00:00:00Z", "utc" },
		{ "set utc=2026-02-29T00:00:00Z", "utc" },
		{ "set utc=2026-06-21T18:30:00", "utc" },
		{ "set utc=yesterday", "utc" },
		{ "set utc=7000-01-01T00:00:00Z", "utc" },
		{ "set time_rate=1e7", "time_rate" },
		{ "set delta_t_s=soon", "delta_t_s" },
		{ "set sun_mode=auto", "sun_mode" },
		{ "set pressure_mbar=-1", "pressure_mbar" },
		{ "set night_illuminance_lx=0.0001", "night_illuminance_lx" },
		{ "set lat_deg=10 utc=2026-13-01T00:00:00Z", "utc" },
	};
	char before[1 << 15], after[1 << 15], want[64];

	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		int r = conn_request(c, bad[i].req, reply, sizeof(reply));
		snprintf(want, sizeof(want), "{set} %s:", bad[i].key);
		if (r <= 0 || !strstr(reply, want))
			FAIL("%s: got '%s', want an ACK naming %s", bad[i].req, reply, bad[i].key);
	}
	/* A batch answers once, at end: refused whole. */
	CHECK(conn_request(c, "batch\nset lat_deg=10\nset utc=2026-13-01T00:00:00Z\nend", reply,
			   sizeof(reply)) > 0);
	CHECK(strstr(reply, "utc:") != NULL);
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	if (strcmp(before, after) != 0)
		FAIL("a refused request changed the state");
}

/* The moon lights the tables where it is up, not where it is down. */
static void test_moon(struct conn *c)
{
	struct astro_site site = { 40.0, 0.0, 0.0 };
	double t_up = NAN, t_down = NAN, start;
	char req[160], text[64];

	CHECK(simclock_parse_utc("2026-01-01T00:00:00Z", &start) == 0);
	for (int h = 0; h < 24 * 40 && (isnan(t_up) || isnan(t_down)); h++) {
		struct astro_moon m;
		double t = start + 3600.0 * h;
		if (astro_moon(&site, t, NULL, &m, NULL, 0) < 0)
			continue;
		if (isnan(t_up) && m.geometric.elevation_deg > 30 && m.illuminated_fraction > 0.8)
			t_up = t;
		if (isnan(t_down) && m.geometric.elevation_deg < -30)
			t_down = t;
	}
	CHECK(!isnan(t_up) && !isnan(t_down));
	simclock_format_utc(t_up, text, sizeof(text));
	snprintf(req, sizeof(req), "set utc=%s time_rate=0 lat_deg=40 lon_deg=0 site_elevation_m=0", text);
	CHECK(conn_request(c, req, reply, sizeof(reply)) == 0);
	struct astro_moon m;
	CHECK(astro_moon(&site, t_up, NULL, &m, NULL, 0) == 0);
	CHECK(get_num(c, "get moon", "lit") == 1.0);
	CHECK_NEAR(get_num(c, "get moon_illuminance_lx", "moon_illuminance_lx"), m.illuminance_lx, 1e-7);
	CHECK_NEAR(get_num(c, "get moon_elevation_deg", "moon_elevation_deg"), m.geometric.elevation_deg, 1e-6);
	CHECK_NEAR(get_num(c, "get moon", "illuminated_fraction"), m.illuminated_fraction, 2e-6);
	CHECK_NEAR(get_num(c, "get moon_angular_radius_deg", "moon_angular_radius_deg"), m.angular_radius_deg, 1e-6);
	printf("moon up at %s: elevation %.3f deg, %.4f lx, fraction %.3f\n", text,
	       m.geometric.elevation_deg, m.illuminance_lx, m.illuminated_fraction);

	simclock_format_utc(t_down, text, sizeof(text));
	snprintf(req, sizeof(req), "set utc=%s", text);
	CHECK(conn_request(c, req, reply, sizeof(reply)) == 0);
	CHECK(get_num(c, "get moon", "lit") == 0.0);
	CHECK(get_num(c, "get moon_illuminance_lx", "moon_illuminance_lx") == 0.0);
	CHECK(get_num(c, "get moon", "elevation_deg") < -30.0);
}

/* The night-sky floor: the zenith and the horizontal illuminance that
 * docs/physics.md promises, read back from the published tables; 0 turns it off. */
static void test_night(struct conn *c, struct conn *ev)
{
	CHECK(conn_request(c, "set sun_elevation_deg=-40 moon_illuminance_lx=0", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation")) == 0);
	double zenith = get_num(c, "sample sky el_deg=90 az_deg=0", "luminance_cd_m2");
	double ambient = get_num(c, "sample ambient", "illuminance_lx");
	printf("night floor: zenith %.4g cd/m2, horizontal %.5g lx\n", zenith, ambient);
	CHECK_NEAR(zenith, 2.0e-4, 2e-6);
	CHECK_NEAR(ambient, 0.002, 4e-5);
	CHECK(conn_request(c, "set night_zenith_luminance_cd_m2=0", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation")) == 0);
	CHECK(get_num(c, "sample sky el_deg=90 az_deg=0", "luminance_cd_m2") < 1e-9);
	CHECK(conn_request(c, "set night_zenith_luminance_cd_m2=0.0002", reply, sizeof(reply)) == 0);
}

int main(void)
{
	struct daemon d = { 0 };
	struct conn c, ev;

	harness_need_device();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_clock");
	}
	setenv("SKYD_TEST_SOCK", d.sock, 1);
	CHECK(conn_open(&c, d.sock) == 0);
	CHECK(conn_open(&ev, d.sock) == 0);
	CHECK(conn_request(&ev, "subscribe events=1", reply, sizeof(reply)) == 0);

	test_sun_matches_astro(&c, &ev);
	test_rate(&c, &ev);
	test_radius_steps(&c);
	test_modes(&c);
	test_times(&c);
	test_invalid(&c);
	test_moon(&c);
	test_night(&c, &ev);

	conn_close(&c);
	conn_close(&ev);
	daemon_cleanup(&d);
	return test_report("test_daemon_clock");
}

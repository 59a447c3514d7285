/* test_daemon_clouds.c - cloud layers through the real skyd: a METAR's
 * BKN030 is a broken layer at 914 m in `get clouds` with its wind, 270
 * degrees at 15 kt (7.7 m/s); CAVOK clears it; cloud_oktas alone dims the
 * sun as before while a layer with a base switches that factor off; bad
 * cloud keys are refused with the usual ACK codes and change nothing; and
 * the field drifts with the simulated clock, backwards too, and stops
 * when it is frozen; changed: events name the cloud tables computed; and
 * while the clock runs, the cloud tables its next moves need are made
 * ahead and taken, for the wind's field and for the sun, and so are those
 * of a client that steps the sun by its keys, but not after a jump. */
#include <math.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "test.h"
#include "weather.h"

static char reply[1 << 16];

static double num(const char *key)
{
	char buf[128];
	return reply_value(reply, key, buf, sizeof(buf)) ? strtod(buf, NULL) : NAN;
}

static int has(const char *text)
{
	return strstr(reply, text) != NULL;
}

/* Sends req, which must succeed, and waits for the generation it names. */
static void change(struct conn *c, struct conn *ev, const char *req)
{
	if (conn_request(c, req, reply, sizeof(reply)) != 0) {
		FAIL("%s: %s", req, reply);
		return;
	}
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation")) == 0);
}

static double sun_lx(struct conn *c)
{
	CHECK(conn_request(c, "sample sun", reply, sizeof(reply)) == 0);
	return num("illuminance_lx");
}

static void test_metar(struct conn *c, struct conn *ev)
{
	change(c, ev, "set metar=\"EGLL 241250Z 27015KT 9999 BKN030 12/06 Q1018\"");
	printf("%s", reply);
	/* The layer's first generation computes the coverage and the sun's
	 * map, and its changed: line names them with the sky's tables. */
	printf("changed: tables=%s\n", ev->event_tables);
	CHECK(strstr(ev->event_tables, "cloud") && strstr(ev->event_tables, "shadow"));
	CHECK(has("cloud1_oktas=6 cloud1_base_m=914.4 cloud1_type=stratocumulus wind_dir_deg=270 "
		  "wind_speed_mps=7.72\n"));
	CHECK(conn_request(c, "get clouds", reply, sizeof(reply)) == 0);
	printf("%s", reply);
	CHECK(num("clouds_drawn") == 1.0 && num("cloud1_drawn") == 1.0);
	CHECK(num("cloud1_oktas") == 6.0);			/* broken: 5 to 7 oktas */
	CHECK(fabs(num("cloud1_base_m") - 914.0) < 1.0);	/* 3000 ft */
	CHECK(num("cloud1_top_m") > num("cloud1_base_m"));
	CHECK(has("cloud1_type: stratocumulus\n") && num("cloud2_drawn") == 0.0);
	CHECK(num("wind_dir_deg") == 270.0);
	CHECK(fabs(num("wind_speed_mps") - 15.0 * 1852.0 / 3600.0) < 0.005);	/* 7.7 m/s */
	CHECK(num("cloud_extent_km") >= 50.0 && num("cloud_extent_km") <= 400.0);
	CHECK(has("cloud_extent_source: auto\n") && has("cloud_factor_applied: 1\n"));
	/* The layer dims the sun itself, once its passes do: the factor of
	 * the report's cloud_oktas=6 no longer applies, and does again when
	 * the layer is gone. */
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("cloud_oktas: 6\n") && has("cloud_factor_applied: 1\n"));
	double drawn_lx = sun_lx(c);
	change(c, ev, "set cloud1_oktas=auto");
	double f = sun_lx(c) / drawn_lx;
	printf("the report's layer taken away: sun x %.6f\n", f);
	CHECK(fabs(f - weather_cloud_light_factor(6.0)) < 1e-6);

	change(c, ev, "set metar=\"EGLL 241250Z 27015KT CAVOK 12/06 Q1018\"");
	CHECK(conn_request(c, "get clouds", reply, sizeof(reply)) == 0);
	CHECK(num("clouds_drawn") == 0.0 && has("cloud1_oktas: auto\n"));
	CHECK(conn_request(c, "get cloud_oktas", reply, sizeof(reply)) == 0 && num("cloud_oktas") == 0.0);
}

/* cloud_oktas alone keeps its meaning: Kasten and Czeplak's factor; a
 * layer with a base takes it over, one without a base does not. */
static void test_light_factor(struct conn *c, struct conn *ev)
{
	change(c, ev, "set visibility_km=auto relative_humidity=auto aerosol=auto cloud_oktas=auto");
	double clear_lx = sun_lx(c);
	change(c, ev, "set cloud_oktas=6");
	CHECK(has("tables: skyview,aerial\n"));
	double f = sun_lx(c) / clear_lx;
	printf("cloud_oktas=6 alone: sun x %.6f\n", f);
	CHECK(fabs(f - weather_cloud_light_factor(6.0)) < 1e-6);
	change(c, ev, "set cloud1_oktas=6");		/* no base: not drawn, no table */
	CHECK(has("tables: none\n"));
	CHECK(fabs(sun_lx(c) / clear_lx - weather_cloud_light_factor(6.0)) < 1e-6);
	change(c, ev, "set cloud1_base_m=900");
	CHECK(has("tables: skyview,aerial\n"));
	CHECK(sun_lx(c) == clear_lx);
	change(c, ev, "set cloud1_oktas=auto cloud1_base_m=auto");
	CHECK(fabs(sun_lx(c) / clear_lx - weather_cloud_light_factor(6.0)) < 1e-6);
	change(c, ev, "set cloud_oktas=auto");
	CHECK(sun_lx(c) == clear_lx);
}

/* Every refusal is the key's usual one, and changes nothing. */
static void test_refusals(struct conn *c)
{
	static const struct {
		const char *req;
		int code;
		const char *says;
	} bad[] = {
		{ "set cloud1_oktas=9", SKY_ACK_RANGE, "cloud1_oktas: 9 is outside [0, 8]" },
		{ "set cloud2_fraction=1.5", SKY_ACK_RANGE, "cloud2_fraction" },
		{ "set cloud1_type=nimbus", SKY_ACK_ARG, "cloud1_type: 'nimbus'" },
		{ "set cloud3_base_m=twelve", SKY_ACK_ARG, "cloud3_base_m" },
		{ "set cloud5_oktas=1", SKY_ACK_NO_EXIST, "cloud5_oktas: unknown key" },
		{ "set cloud1_base_m=1000 cloud1_top_m=900", SKY_ACK_RANGE, "cloud1_top_m: 900 is not above" },
		{ "set cloud4_top_m=25000", SKY_ACK_RANGE, "cloud4_top_m" },
		{ "set wind_dir_deg=400", SKY_ACK_RANGE, "wind_dir_deg" },
		{ "set wind_speed_mps=-3", SKY_ACK_RANGE, "wind_speed_mps" },
		{ "set cloud_seed=-1", SKY_ACK_ARG, "cloud_seed" },
		{ "set cloud_extent_km=0", SKY_ACK_RANGE, "cloud_extent_km" },
		{ "set shadow_width=4", SKY_ACK_RANGE, "shadow_width" },
		{ "get clouds now", SKY_ACK_SYNTAX, "get clouds takes no other arguments" },
	};
	char before[8192];

	CHECK(conn_request(c, "get clouds", before, sizeof(before)) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	uint64_t g = reply_u64(reply, "generation");
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		int code = conn_request(c, bad[i].req, reply, sizeof(reply));
		if (code != bad[i].code || !has(bad[i].says))
			FAIL("%s: ACK %d '%s', expected ACK %d saying '%s'", bad[i].req, code, reply,
			     bad[i].code, bad[i].says);
		test_checks++;
	}
	CHECK(conn_request(c, "get clouds", reply, sizeof(reply)) == 0);
	CHECK(strcmp(reply, before) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == g);
}

/* The field's time and offset after the next move of the clock. */
static void next_move(struct conn *c, struct conn *ev, double *ret_utc_s, double *ret_east_km)
{
	char buf[128];

	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation") + 1) == 0);
	CHECK(conn_request(c, "get clouds", reply, sizeof(reply)) == 0);
	*ret_east_km = num("cloud_offset_km");		/* strtod stops at the comma */
	*ret_utc_s = NAN;
	if (reply_value(reply, "cloud_placed_utc", buf, sizeof(buf))) {
		int y, mo, d, h, mi, s;
		if (sscanf(buf, "%d-%d-%dT%d:%d:%dZ", &y, &mo, &d, &h, &mi, &s) == 6)
			*ret_utc_s = ((d * 24.0 + h) * 60.0 + mi) * 60.0 + s;	/* within the month */
	}
}

/* From the west at 10 m/s: the field moves east as the clock runs,
 * west when it runs backwards, and stops when it is frozen. */
static void test_drift(struct conn *c, struct conn *ev)
{
	double t0, t1, e0, e1;

	change(c, ev, "set sun_mode=manual moon_mode=manual cloud1_oktas=4 cloud1_base_m=1500 "
		      "wind_dir_deg=270 wind_speed_mps=10 utc=2024-06-21T12:00:00Z time_rate=300");
	next_move(c, ev, &t0, &e0);
	next_move(c, ev, &t1, &e1);
	printf("forward: %.0f s -> %.0f s, east %.4f -> %.4f km\n", t0, t1, e0, e1);
	CHECK(t1 > t0);
	CHECK(fabs((e1 - e0) - 0.01 * (t1 - t0)) < 1e-5);	/* %.9g of ~800 km */
	change(c, ev, "set time_rate=-300");
	next_move(c, ev, &t0, &e0);
	next_move(c, ev, &t1, &e1);
	printf("backward: %.0f s -> %.0f s, east %.4f -> %.4f km\n", t0, t1, e0, e1);
	CHECK(t1 < t0);
	CHECK(fabs((e1 - e0) - 0.01 * (t1 - t0)) < 1e-5);	/* %.9g of ~800 km */
	change(c, ev, "set time_rate=0");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(has("clock_next_tick_s: none\n"));
}

/* Waits for the clock's moves until status counts more than taken
 * computations that took cloud tables made ahead (at most 400 moves). */
static int wait_taken_ahead(struct conn *c, struct conn *ev, uint64_t taken)
{
	for (int k = 0; k < 400; k++) {
		CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
		if (reply_u64(reply, "clouds_taken_ahead") > taken)
			return 1;
		if (conn_wait_generation(ev, reply_u64(reply, "generation") + 1) != 0)
			return 0;
	}
	return 0;
}

/* The cloud tables made ahead of the clock (docs/clouds.md, "Maps made
 * ahead"), with a reader of sky-view, which reads the maps. */
static void test_ahead(struct conn *c, struct conn *ev, struct conn *tab)
{
	uint64_t made, taken;

	CHECK(conn_request(tab, "subscribe tables=skyview", reply, sizeof(reply)) == 0);
	/* The wind carries the field across the tables' lattice: one move in
	 * eight crosses a cell. */
	change(c, ev, "set sun_mode=manual sun_elevation_deg=30 moon_mode=manual cloud1_oktas=4 "
		      "cloud1_base_m=1500 wind_dir_deg=270 wind_speed_mps=10 "
		      "utc=2024-06-21T12:00:00Z time_rate=300");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	taken = reply_u64(reply, "clouds_taken_ahead");
	CHECK(wait_taken_ahead(c, ev, taken));
	/* The sun on the clock, no wind: its light crosses a cell of the
	 * maps' grid every ten moves or so. */
	change(c, ev, "set wind_speed_mps=0 sun_mode=clock lat_deg=39.74 lon_deg=-105.18 "
		      "utc=2024-06-21T14:30:00Z time_rate=120");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	taken = reply_u64(reply, "clouds_taken_ahead");
	CHECK(wait_taken_ahead(c, ev, taken));
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	made = reply_u64(reply, "clouds_made_ahead");
	taken = reply_u64(reply, "clouds_taken_ahead");
	printf("clock running: cloud tables made ahead %llu times, taken %llu\n", (unsigned long long)made,
	       (unsigned long long)taken);
	CHECK(made >= taken && taken >= 2);
	/* The clock frozen, a client steps the sun by its keys: its last
	 * step is repeated. */
	change(c, ev, "set time_rate=0 sun_mode=manual sun_azimuth_deg=120 sun_elevation_deg=20");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	taken = reply_u64(reply, "clouds_taken_ahead");
	char req[64];
	for (int k = 1; k <= 60 && reply_u64(reply, "clouds_taken_ahead") == taken; k++) {
		snprintf(req, sizeof(req), "set sun_elevation_deg=%.1f", 20.0 + 0.1 * k);
		change(c, ev, req);
		CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	}
	CHECK(reply_u64(reply, "clouds_taken_ahead") > taken);
	/* A jump across cells nobody foresaw remakes the maps, and the next
	 * change is not foreseen from it: nothing is made ahead after it. */
	change(c, ev, "set sun_elevation_deg=35");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	made = reply_u64(reply, "clouds_made_ahead");
	CHECK(strstr(reply, "last_computed: skyview,shadow\n") != NULL);	/* the reader's demand */
	change(c, ev, "set sun_elevation_deg=50");
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK_EQ(reply_u64(reply, "clouds_made_ahead"), made);
	CHECK(conn_request(tab, "unsubscribe", reply, sizeof(reply)) == 0);
}

int main(void)
{
	struct daemon d = { 0 };
	struct conn c, ev, tab;

	harness_need_device();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, "skyview_width=64",
						    "skyview_height=32", NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_clouds");
	}
	CHECK(conn_open(&c, d.sock) == 0);
	CHECK(conn_open(&ev, d.sock) == 0);
	CHECK(conn_request(&ev, "subscribe events=1", reply, sizeof(reply)) == 0);
	/* A reader of the tables while the METAR's layer comes, so that the
	 * cloud passes run; gone before the clock's drift, whose moves must
	 * publish as fast as they come. */
	CHECK(conn_open(&tab, d.sock) == 0);
	CHECK(conn_request(&tab, "subscribe tables=skyview,cloud,shadow", reply, sizeof(reply)) == 0);
	test_metar(&c, &ev);
	CHECK(conn_request(&tab, "unsubscribe", reply, sizeof(reply)) == 0);
	test_light_factor(&c, &ev);
	test_refusals(&c);
	test_drift(&c, &ev);
	test_ahead(&c, &ev, &tab);
	conn_close(&tab);

	conn_close(&c);
	conn_close(&ev);
	daemon_cleanup(&d);
	return test_report("test_daemon_clouds");
}

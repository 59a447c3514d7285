/* test_daemon_weather.c - weather through the real skyd: set in words, the
 * sky changes as a person expects (hazier, a whiter horizon, a dimmer sun;
 * clouds dim the lights only), get weather tells the keys, the coefficients
 * they made and the raw keys that override them, METAR reports apply with
 * what was used and ignored, a malformed one changes nothing, and auto
 * brings the preset's sky back. */
#include <math.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "test.h"
#include "weather.h"

static char reply[1 << 16];

/* What a person looks at: the zenith, the horizon across from the sun (3
 * degrees up, azimuth 90 with the sun in the south) and the sun. */
struct look {
	double zenith[3], horizon[3];
	double zenith_cd_m2, horizon_cd_m2;
	double sun_lx;
};

static double num(const char *key)
{
	char buf[128];
	return reply_value(reply, key, buf, sizeof(buf)) ? strtod(buf, NULL) : NAN;
}

static void rgb(const char *key, double ret[3])
{
	char buf[128];
	ret[0] = ret[1] = ret[2] = NAN;
	if (reply_value(reply, key, buf, sizeof(buf)))
		sscanf(buf, "%lf,%lf,%lf", &ret[0], &ret[1], &ret[2]);
}

/* A line that gets no reply of its own (batch and what is inside it). */
static void send_line(struct conn *c, const char *line)
{
	char buf[512];
	int n = snprintf(buf, sizeof(buf), "%s\n", line);
	CHECK(send(c->fd, buf, (size_t)n, MSG_NOSIGNAL) == n);
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

static void look(struct conn *c, struct look *ret)
{
	CHECK(conn_request(c, "sample sky el_deg=90 az_deg=0", reply, sizeof(reply)) == 0);
	rgb("radiance_rgb_cd_m2", ret->zenith);
	ret->zenith_cd_m2 = num("luminance_cd_m2");
	CHECK(conn_request(c, "sample sky el_deg=3 az_deg=90", reply, sizeof(reply)) == 0);
	rgb("radiance_rgb_cd_m2", ret->horizon);
	ret->horizon_cd_m2 = num("luminance_cd_m2");
	CHECK(conn_request(c, "sample sun", reply, sizeof(reply)) == 0);
	ret->sun_lx = num("illuminance_lx");
}

static double contrast(const struct look *l)
{
	return (l->horizon_cd_m2 - l->zenith_cd_m2) / (l->horizon_cd_m2 + l->zenith_cd_m2);
}

/* How far the horizon's colour is from grey: blue over red, less one. */
static double horizon_tint(const struct look *l)
{
	return l->horizon[2] / l->horizon[0] - 1.0;
}

static void print_look(const char *name, const struct look *l)
{
	printf("%-6s zenith %8.1f cd/m2, horizon %8.1f cd/m2 (contrast %.3f), horizon blue/red %.3f, sun %9.1f lx\n",
	       name, l->zenith_cd_m2, l->horizon_cd_m2, contrast(l), l->horizon[2] / l->horizon[0],
	       l->sun_lx);
}

static int has(const char *line)
{
	return strstr(reply, line) != NULL;
}

/* 5 km of humid urban haze against the default clear sky. */
static void test_haze(struct conn *c, struct conn *ev, struct look *clear)
{
	struct look hazy;

	look(c, clear);
	change(c, ev, "set visibility_km=5 relative_humidity=0.9 aerosol=urban");
	CHECK(has("tables: transmittance,multiscatter,skyview,aerial\n"));
	look(c, &hazy);
	print_look("clear", clear);
	print_look("hazy", &hazy);
	CHECK(fabs(contrast(&hazy)) < 0.5 * contrast(clear));	/* hazier */
	CHECK(fabs(horizon_tint(&hazy)) < 0.5 * fabs(horizon_tint(clear)));	/* whiter */
	CHECK(hazy.horizon[2] / hazy.horizon[0] < clear->horizon[2] / clear->horizon[0]);
	CHECK(hazy.sun_lx < 0.5 * clear->sun_lx);			/* dimmer sun */

	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("visibility_km: 5\n") && has("relative_humidity: 0.9\n") && has("aerosol: urban\n"));
	CHECK(has("angstrom_beta: auto\n") && has("mie_source: weather\n"));
	CHECK(has("\nmie_scattering_per_km: ") && has("\nmie_absorption_per_km: ") && has("\nmie_g: "));
	CHECK(fabs(num("visibility_effective_km") - 5.0) < 1e-6);
	CHECK(has("overridden: none\n") && has("cloud_factor: 1\n"));
	/* The user's own atmosphere stays what its keys say. */
	CHECK(conn_request(c, "get mie_g visibility_km", reply, sizeof(reply)) == 0);
	CHECK(num("mie_g") == 0.8 && num("visibility_km") == 5.0);

	/* A raw key after the weather wins for its coefficient ... */
	CHECK(conn_request(c, "set mie_g=0.75", reply, sizeof(reply)) == 0);
	CHECK(has("tables: transmittance,multiscatter,skyview,aerial\n"));
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("overridden: mie_g\n"));
	/* ... until a weather key is set again. */
	change(c, ev, "set relative_humidity=0.9");
	CHECK(has("tables: transmittance,multiscatter,skyview,aerial\n"));
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("overridden: none\n"));
}

/* Full cover dims the sun by Kasten and Czeplak's 0.25, lights only. */
static void test_clouds(struct conn *c, struct conn *ev)
{
	struct look before, after;

	look(c, &before);
	change(c, ev, "set cloud_oktas=8");
	CHECK(has("tables: skyview,aerial\n"));
	look(c, &after);
	printf("cloud_oktas=8: sun %.1f -> %.1f lx (x %.6f), zenith x %.6f\n", before.sun_lx,
	       after.sun_lx, after.sun_lx / before.sun_lx, after.zenith_cd_m2 / before.zenith_cd_m2);
	CHECK(fabs(after.sun_lx / before.sun_lx - 0.25) < 1e-6);
	CHECK(fabs(after.zenith_cd_m2 / before.zenith_cd_m2 - 0.25) < 1e-3);
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("cloud_oktas: 8\n") && has("cloud_factor: 0.25\n"));
	change(c, ev, "set cloud_fraction=auto");
	look(c, &after);
	CHECK(after.sun_lx == before.sun_lx);
}

static void test_metar(struct conn *c, struct conn *ev)
{
	change(c, ev, "set metar=\"EGLL 241250Z 27008KT 9999 FEW030 12/06 Q1018\"");
	CHECK(has("metar_used: 27008KT 9999 FEW030 12/06 Q1018\n"));
	CHECK(has("metar_ignored: EGLL 241250Z\n"));
	CHECK(has("metar_applied: visibility_km=auto relative_humidity=0.66"));
	CHECK(has("cloud_oktas=1.5 pressure_mbar=1018 temperature_c=12 cloud1_oktas=1.5 "
		  "cloud1_base_m=914.4 cloud1_type=cumulus wind_dir_deg=270 wind_speed_mps=4.12\n"));
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("visibility_km: auto\n") && has("aerosol: auto\n") && has("cloud_oktas: 1.5\n"));
	CHECK(fabs(num("relative_humidity") - weather_relative_humidity(12, 6)) < 1e-8);
	CHECK(conn_request(c, "get pressure_mbar temperature_c", reply, sizeof(reply)) == 0);
	CHECK(num("pressure_mbar") == 1018.0 && num("temperature_c") == 12.0);

	/* A report clears what it does not fill, and says so: the top set on
	 * the layer it fills, the second layer whole. */
	change(c, ev, "set cloud1_top_m=2500 cloud2_oktas=3 cloud2_base_m=6000 cloud2_type=altostratus");
	change(c, ev, "set metar=\"EGLL 241250Z 27008KT 9999 BKN030 12/06 Q1018\"");
	CHECK(has("cloud1_oktas=6 cloud1_base_m=914.4 cloud1_top_m=auto cloud1_type=stratocumulus "
		  "cloud2_oktas=auto cloud2_base_m=auto cloud2_type=stratocumulus wind_dir_deg=270"));
	CHECK(conn_request(c, "get cloud1_top_m cloud2_oktas", reply, sizeof(reply)) == 0);
	CHECK(has("cloud1_top_m: auto\n") && has("cloud2_oktas: auto\n"));

	/* In a batch, a foggy report; end answers for it. */
	send_line(c, "batch");
	send_line(c, "set metar=\"EGLL 241250Z 0200 FG VV001 08/08 Q1020\"");
	change(c, ev, "end");
	CHECK(has("metar_used: 0200 FG VV001 08/08 Q1020\n"));
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("visibility_km: 0.2\n") && has("aerosol: maritime\n") && has("cloud_oktas: 8\n"));
	CHECK(has("relative_humidity: 1\n"));
}

/* A malformed report is refused naming its group; nothing changes. */
static void test_malformed(struct conn *c)
{
	char weather[8192];
	uint64_t g;

	CHECK(conn_request(c, "get weather", weather, sizeof(weather)) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	g = reply_u64(reply, "generation");
	CHECK(conn_request(c, "set sun_elevation_deg=20 metar=\"EGLL 241250Z 27008KT 9999X FEW030\"",
			   reply, sizeof(reply)) == SKY_ACK_ARG);
	printf("%s", reply);
	CHECK(has("{set} metar: group 4 '9999X'"));
	CHECK(conn_request(c, "set metar=\"EGLL 241250Z", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == g);
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(strcmp(reply, weather) == 0);
	CHECK(conn_request(c, "get sun_elevation_deg", reply, sizeof(reply)) == 0);
	CHECK(num("sun_elevation_deg") == 30.0);
}

/* Every weather key back to auto: the user's own atmosphere again, which
 * keeps the raw mie_g set above until it is set back. */
static void test_auto(struct conn *c, struct conn *ev, const struct look *clear)
{
	struct look again;

	change(c, ev, "set visibility_km=auto relative_humidity=auto aerosol=auto cloud_oktas=auto "
		      "cloud1_oktas=auto cloud1_base_m=auto");
	CHECK(conn_request(c, "get mie_g", reply, sizeof(reply)) == 0 && num("mie_g") == 0.75);
	change(c, ev, "set mie_g=0.8");
	CHECK(conn_request(c, "get weather", reply, sizeof(reply)) == 0);
	CHECK(has("mie_source: atmosphere\n") && has("ozone_source: atmosphere\n"));
	look(c, &again);
	CHECK(again.zenith_cd_m2 == clear->zenith_cd_m2 && again.sun_lx == clear->sun_lx);
	CHECK(again.horizon_cd_m2 == clear->horizon_cd_m2);
}

int main(void)
{
	struct daemon d = { 0 };
	struct conn c, ev;
	struct look clear;

	harness_need_device();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, "skyview_width=64",
						    "skyview_height=32", NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_weather");
	}
	CHECK(conn_open(&c, d.sock) == 0);
	CHECK(conn_open(&ev, d.sock) == 0);
	CHECK(conn_request(&ev, "subscribe events=1", reply, sizeof(reply)) == 0);

	test_haze(&c, &ev, &clear);
	test_clouds(&c, &ev);
	test_metar(&c, &ev);
	test_malformed(&c);
	test_auto(&c, &ev, &clear);

	conn_close(&c);
	conn_close(&ev);
	daemon_cleanup(&d);
	return test_report("test_daemon_weather");
}

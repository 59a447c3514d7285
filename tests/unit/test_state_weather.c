/* test_state_weather.c - the weather in the sky's state: its keys and what
 * each invalidates, state_resolve (nothing without weather, the preset back
 * with auto), the override rule of raw keys, the cloud factor, METAR
 * reports, the config file, and the protocol's quoted values. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "config.h"
#include "metar.h"
#include "proto.h"
#include "state.h"
#include "test.h"

#define ALL STATE_ALL_TABLES
#define LIGHTS (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL))

static uint32_t set(struct sky_state *s, const char *pair)
{
	char err[256];
	uint32_t dirty = 0;
	if (state_set_pair(s, pair, &dirty, err, sizeof(err)) < 0)
		FAIL("%s: %s", pair, err);
	return dirty;
}

static void resolve(const struct sky_state *s, struct sky_state *ret)
{
	char err[256];
	if (state_resolve(s, ret, NULL, err, sizeof(err)) < 0)
		FAIL("state_resolve: %s", err);
}

static const struct atmo_constituent *mie(const struct sky_state *s)
{
	return &s->atmo.c[ATMO_MIE];
}

/* No weather: the state the tables get is the state itself, bytes and all;
 * a weather key and its auto bring the preset's atmosphere back. */
static void test_resolve(void)
{
	struct sky_state s, sky;

	state_default(&s);
	resolve(&s, &sky);
	CHECK(memcmp(&s, &sky, sizeof(s)) == 0);
	set(&s, "sun_elevation_deg=10");
	set(&s, "mie_g=0.7");
	resolve(&s, &sky);
	CHECK(memcmp(&s, &sky, sizeof(s)) == 0);

	CHECK(set(&s, "visibility_km=5") == ALL);
	resolve(&s, &sky);
	CHECK(fabs(weather_visibility_km(&sky.atmo) - 5.0) < 1e-9);
	CHECK(memcmp(&s.atmo, &sky.atmo, sizeof(s.atmo)) != 0);
	CHECK(mie(&s)->g == 0.7);	/* the user's own atmosphere stays */
	/* Resolving what was resolved changes nothing. */
	struct sky_state again;
	resolve(&sky, &again);
	CHECK(memcmp(&sky, &again, sizeof(sky)) == 0);

	CHECK(set(&s, "visibility_km=auto") == ALL);
	resolve(&s, &sky);
	CHECK(memcmp(&s.atmo, &sky.atmo, sizeof(s.atmo)) == 0);
	CHECK(set(&s, "visibility_km=auto") == 0);	/* no change, nothing stale */

	char buf[64];
	CHECK(state_get(&s, "visibility_km", buf, sizeof(buf)) == 0 && strcmp(buf, "auto") == 0);
	set(&s, "cloud_fraction=0.5");
	CHECK(state_get(&s, "cloud_oktas", buf, sizeof(buf)) == 0 && strcmp(buf, "4") == 0);
	CHECK(state_get(&s, "cloud_fraction", buf, sizeof(buf)) == 0 && strcmp(buf, "0.5") == 0);
}

/* A raw key set after a weather key wins for its coefficient; a weather
 * key set after it wins back; preset= forgets the raw keys. */
static void test_overrides(void)
{
	struct sky_state s, sky, plain;

	state_default(&s);
	set(&s, "mie_g=0.5");		/* before any weather: the weather wins */
	set(&s, "visibility_km=5");
	CHECK(s.weather.overridden == 0);
	resolve(&s, &plain);
	CHECK(mie(&plain)->g != 0.5);

	CHECK(set(&s, "mie_g=0.6") == ALL);
	CHECK(s.weather.overridden == STATE_OVERRIDE_MIE_G);
	resolve(&s, &sky);
	CHECK(mie(&sky)->g == 0.6);
	CHECK(memcmp(mie(&sky)->scattering_per_km, mie(&plain)->scattering_per_km,
		     sizeof(mie(&sky)->scattering_per_km)) == 0);
	set(&s, "mie_layer1_exp_scale_per_km=-0.5");
	set(&s, "ozone_absorption_per_km=0");	/* the weather maps no ozone: no override */
	CHECK(s.weather.overridden == (STATE_OVERRIDE_MIE_G | STATE_OVERRIDE_MIE_PROFILE));
	resolve(&s, &sky);
	CHECK(mie(&sky)->density.layers[1].exp_scale_per_km == -0.5);
	CHECK(sky.atmo.c[ATMO_OZONE].absorption_per_km[1] == 0.0);

	set(&s, "relative_humidity=0.5");	/* a weather key again: it wins */
	CHECK(s.weather.overridden == 0);
	resolve(&s, &sky);
	CHECK(mie(&sky)->g != 0.6);

	set(&s, "ozone_du=600");
	set(&s, "ozone_absorption_per_km=1e-3");
	set(&s, "mie_g=0.6");
	CHECK(s.weather.overridden == (STATE_OVERRIDE_OZONE_ABSORPTION | STATE_OVERRIDE_MIE_G));
	set(&s, "ozone_du=300");		/* wins back the ozone only */
	CHECK(s.weather.overridden == STATE_OVERRIDE_MIE_G);
	set(&s, "preset=earth");
	CHECK(s.weather.overridden == 0);

}

struct collect {
	char text[8192];
	size_t n;
};

static void collect(void *ctx, const char *key, const char *value)
{
	struct collect *c = ctx;
	if (c->n < sizeof(c->text))
		c->n += (size_t)snprintf(c->text + c->n, sizeof(c->text) - c->n, "%s: %s\n", key, value);
}

static void test_describe(void)
{
	struct sky_state s;
	struct collect c = { .n = 0 };
	char err[256];

	state_default(&s);
	set(&s, "visibility_km=5");
	set(&s, "aerosol=urban");
	set(&s, "mie_scattering_per_km=0.1");
	set(&s, "mie_scale_height_km=2");
	CHECK(state_describe_weather(&s, collect, &c, err, sizeof(err)) == 0);
	CHECK(strstr(c.text, "visibility_km: 5\n") != NULL);
	CHECK(strstr(c.text, "aerosol: urban\n") != NULL);
	CHECK(strstr(c.text, "mie_scattering_per_km: ") != NULL);
	CHECK(strstr(c.text, "overridden: mie_scattering_per_km,mie_profile\n") != NULL);
	CHECK(strstr(c.text, "cloud_factor: 1\n") != NULL);

	/* get lists the weather keys given, and no others. */
	c.n = 0;
	c.text[0] = 0;
	state_foreach(&s, collect, &c);
	CHECK(strstr(c.text, "visibility_km: 5\n") != NULL);
	CHECK(strstr(c.text, "relative_humidity:") == NULL);
}

/* Cloud cover dims the lights only; a sensor's factor takes the same path. */
static void test_clouds(void)
{
	struct sky_state s, sky;

	state_default(&s);
	set(&s, "moon_illuminance_lx=0.3");
	CHECK(set(&s, "cloud_oktas=8") == LIGHTS);
	CHECK(s.weather.cloud_factor == 0.25);
	resolve(&s, &sky);
	CHECK(sky.sun.illuminance_lx == 133800.0 * 0.25);
	CHECK(sky.moon.illuminance_lx == 0.3 * 0.25);
	CHECK(memcmp(&sky.atmo, &s.atmo, sizeof(s.atmo)) == 0);

	uint32_t dirty = 0;
	CHECK(state_set_cloud_factor(&s, 0.7, &dirty) == 0 && dirty == LIGHTS);
	CHECK(fabs(weather_cloud_light_factor(s.weather.in.cloud_oktas) - 0.7) < 1e-12);
	CHECK(s.weather.cloud_factor == 0.7);
	CHECK(state_set_cloud_factor(&s, 0.1, NULL) == 0 && s.weather.in.cloud_oktas == 8.0);
	CHECK(state_set_cloud_factor(&s, 1.5, NULL) == -ERANGE);
	CHECK(set(&s, "cloud_oktas=auto") == LIGHTS && s.weather.cloud_factor == 1.0);
}

static void test_metar(void)
{
	struct sky_state s, before;
	struct metar m;
	uint32_t dirty = 0;
	char err[256];

	state_default(&s);
	set(&s, "mie_g=0.6");
	set(&s, "visibility_km=20");
	set(&s, "mie_g=0.6");
	CHECK(state_set_metar(&s, "EGLL 241250Z 27008KT 4000 -RA BR BKN008 12/11 Q1018", &m, &dirty,
			      err, sizeof(err)) == 0);
	/* BKN008 is a drawn layer: the cloud tables too. */
	CHECK(dirty == (ALL | STATE_CLOUD_TABLES));
	CHECK(s.weather.in.visibility_km == 4.0);
	CHECK(s.weather.in.aerosol == WEATHER_MARITIME);
	CHECK(s.weather.in.cloud_oktas == 6.0);
	CHECK(fabs(s.weather.in.relative_humidity - weather_relative_humidity(12, 11)) < 1e-12);
	CHECK(s.clock.pressure_mbar == 1018.0 && s.clock.temperature_c == 12.0);
	CHECK(s.weather.overridden == 0);	/* the report is the last writer */
	CHECK(strstr(m.used, "4000") && strstr(m.used, "27008KT") && !strstr(m.ignored, "27008KT"));

	/* QNH is reduced to the site: 1013.25 at sea level is ~898.8 at 1000 m. */
	set(&s, "site_elevation_m=1000");
	set(&s, "metar=EGLL 241250Z 9999 SCT030 12/06 Q1013");
	CHECK(fabs(s.clock.pressure_mbar - 1013.0 * pow(1.0 - 2.25577e-2, 5.25588)) < 1e-9);
	CHECK(isnan(s.weather.in.visibility_km));

	/* A malformed report names its group and changes nothing that matters
	 * (callers work on a copy). */
	before = s;
	int r = state_set_metar(&s, "EGLL 241250Z 27008KT 9999X FEW030", NULL, NULL, err, sizeof(err));
	CHECK(r == -EINVAL && strstr(err, "metar: group 4 '9999X'") == err);
	CHECK(memcmp(&before, &s, sizeof(s)) == 0);
	CHECK(state_set_pair(&s, "metar=EGLL 241250Z Q9999", NULL, err, sizeof(err)) == -EINVAL &&
	      strstr(err, "group 3 'Q9999'"));
}

/* ozone_du needs an ozone constituent; the refusal names the key. */
static void test_validate(void)
{
	struct sky_state s;
	char err[256];

	state_default(&s);
	set(&s, "ozone_du=300");
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	set(&s, "preset=mars");
	CHECK(state_validate(&s, 0, err, sizeof(err)) < 0 && strstr(err, "ozone_du") == err);
	set(&s, "ozone_du=auto");
	set(&s, "visibility_km=0.05");
	CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
	CHECK(state_set_pair(&s, "visibility_km=0.01", NULL, err, sizeof(err)) == -ERANGE);
	CHECK(state_set_pair(&s, "aerosol=smog", NULL, err, sizeof(err)) == -EINVAL);
}

static void test_quoting(void)
{
	struct proto_request req;
	char err[128], line[256];

	snprintf(line, sizeof(line), "set metar=\"EGLL 241250Z 9999\" sun_elevation_deg=5");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == 0 && req.n_args == 2);
	CHECK(req.n_args == 2 && strcmp(req.args[0].value, "EGLL 241250Z 9999") == 0 &&
	      strcmp(req.args[1].key, "sun_elevation_deg") == 0);
	snprintf(line, sizeof(line), "set a=\"\"\tb=1");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == 0 && req.n_args == 2 &&
	      strcmp(req.args[0].value, "") == 0);
	snprintf(line, sizeof(line), "set a=\"x y");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == -EINVAL);
	snprintf(line, sizeof(line), "set a=\"x\"y b=1");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == -EINVAL);
	/* A quote that does not open the value stays what it was. */
	snprintf(line, sizeof(line), "set a=x\"y b=\"");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == -EINVAL);
	snprintf(line, sizeof(line), "set a=x\"y");
	CHECK(proto_parse_request(line, &req, err, sizeof(err)) == 0 &&
	      strcmp(req.args[0].value, "x\"y") == 0);
	struct proto_arg args[4];
	snprintf(line, sizeof(line), "generation=3 message=\"a b\"");
	CHECK(proto_split_args(line, args, 4) == 2 && strcmp(args[1].value, "a b") == 0);
}

static void test_config(void)
{
	char path[] = "/tmp/skyd-weather-XXXXXX", err[512];
	int fd = mkstemp(path);
	struct sky_state s;
	CHECK(fd >= 0);
	if (fd < 0)
		return;
	FILE *f = fdopen(fd, "w");
	fprintf(f, "# weather\nmetar = \"EGLL 241250Z 27008KT 3000 HZ FEW030 22/06 Q1018\"\n"
		   "aerosol = urban\nozone_du = 350\n");
	fclose(f);
	state_default(&s);
	CHECK(config_load(path, &s, err, sizeof(err)) == 0);
	CHECK(s.weather.in.visibility_km == 3.0 && s.weather.in.aerosol == WEATHER_URBAN);
	CHECK(s.weather.in.ozone_du == 350.0 && s.clock.temperature_c == 22.0);
	f = fopen(path, "w");
	fprintf(f, "metar = EGLL 241250Z 27008KT 9999X\n");
	fclose(f);
	CHECK(config_load(path, &s, err, sizeof(err)) < 0 && strstr(err, ":1: metar: group 4"));
	unlink(path);
}

int main(void)
{
	test_resolve();
	test_overrides();
	test_describe();
	test_clouds();
	test_metar();
	test_validate();
	test_quoting();
	test_config();
	return test_report("test_state_weather");
}

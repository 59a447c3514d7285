/* test_sync_msg.c - the replication messages and settings (daemon/sync):
 * a state survives encoding and decoding bit for bit (its cloud layers and
 * wind among it, set as keys or by a METAR), the simulated clock
 * means the same instant on both sides, every kind of bad message is
 * refused with its reason, the broker URL and the checks of the settings. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "simclock.h"
#include "state.h"
#include "sync.h"
#include "state_compare.h"
#include "test.h"

#define ID "skyhost/4242/0123456789abcdef"

static char msg[SYNC_MSG_MAX + 1];

static int64_t real_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s: %s", pair, err);
}

/* The message of s under generation gen, its sequence SEQ_OF(gen): the
 * two travel apart. */
#define SEQ_OF(gen) ((gen) + 40)
static size_t encode(const struct sky_state *s, uint64_t gen, int64_t apply_ns)
{
	struct sync_msg_header h = { .sequence = SEQ_OF(gen), .generation = gen,
				     .apply_time_ns = apply_ns };
	size_t len = 0;
	snprintf(h.controller, sizeof(h.controller), "%s", ID);
	int r = sync_msg_encode(s, &h, msg, sizeof(msg), &len);
	if (r < 0)
		FAIL("encode: %s", strerror(-r));
	return len;
}

/* ---- round trips ---- */

static void scene_clock(struct sky_state *s)
{
	set(s, "utc=2026-06-21T12:00:00.25Z");
	set(s, "lat_deg=47.3769");
	set(s, "lon_deg=8.5417");
	set(s, "time_rate=60");
	set(s, "moon_elevation_deg=12.5");	/* the moon manual, the sun on the clock */
}

static void scene_mars(struct sky_state *s)
{
	set(s, "preset=mars");
	set(s, "sun_elevation_deg=-3.25");
	set(s, "sun_azimuth_deg=271.125");
	set(s, "camera_yaw_deg=33.3");
	set(s, "storage=f16");
	set(s, "aerial_spacing=linear");
}

static void scene_custom(struct sky_state *s)
{
	set(s, "mie_scale_height_km=2.5");
	set(s, "ozone_layer0_width_km=27.5");	/* the ozone profile stays two layers */
	set(s, "rayleigh_scattering_per_km=5.802e-3,13.558e-3,33.1e-3");
	set(s, "ground_albedo=0.1,0.2,0.3");
	set(s, "night_zenith_luminance_cd_m2=0.0003");
	set(s, "multiscatter_iterations=3");
	set(s, "multiscatter_moment=on");
	set(s, "quality=high");
	set(s, "altitude_km=1.234");
	set(s, "delta_t_s=69.2");
	set(s, "sun_color=1.1,1,0.9");
}

/* Weather in words and the sensor's settings travel too. */
static void scene_weather(struct sky_state *s)
{
	set(s, "visibility_km=8.5");
	set(s, "relative_humidity=0.73");
	set(s, "aerosol=urban");
	set(s, "ozone_du=287");
	set(s, "cloud_oktas=3");
	set(s, "sensor_mode=cloud");
	set(s, "sensor_time_constant_s=45");
}

/* What nine digits and the keys alone do not carry: values the clock, a
 * METAR or a light sensor computed to every bit, raw keys that win over
 * the weather because they were set after it, a cloud factor a light
 * sensor set (cloud_oktas gives it back only to within its last bits). */
static void scene_exact(struct sky_state *s)
{
	set(s, "visibility_km=20");
	set(s, "mie_g=0.7");				/* after the weather: pinned */
	set(s, "ozone_du=300");
	set(s, "ozone_absorption_per_km=7e-4,1.9e-3,9e-5");	/* pinned */
	s->sun.illuminance_lx = 123716.78708808632;	/* as the clock left it */
	s->sun.elevation_deg = 12.345678912345678;
	s->weather.in.relative_humidity = 0.93141530512345;	/* as a METAR gave it */
	CHECK(state_set_cloud_factor(s, 0.12345678912345678, NULL) == 0);
	CHECK(s->weather.overridden == (STATE_OVERRIDE_MIE_G | STATE_OVERRIDE_OZONE_ABSORPTION));
}

/* The cloud layers and the wind travel as keys, every bit of them: the
 * field is a function of these keys and the time (docs/clouds.md). */
static void scene_clouds(struct sky_state *s)
{
	set(s, "cloud1_oktas=6.5");
	set(s, "cloud1_base_m=914.4");
	set(s, "cloud1_type=stratocumulus");
	set(s, "cloud2_fraction=0.3");
	set(s, "cloud2_base_m=7620");
	set(s, "cloud2_top_m=9123.45");
	set(s, "cloud2_type=cirrus");
	set(s, "cloud4_oktas=1");		/* no base: kept, not drawn */
	set(s, "cloud_seed=4294967295");
	set(s, "wind_dir_deg=247.5");
	set(s, "wind_speed_mps=12.34");
	set(s, "cloud_extent_km=123.456");
	set(s, "shadow_width=384");
}

/* What a METAR makes of the layers and the wind (computed: feet to
 * metres, knots to m/s) reads back the same on the other side. Without a
 * temperature group: the humidity Magnus's formula makes of it has more
 * digits than the text carries, which is the weather's, not the clouds'. */
static void scene_metar_clouds(struct sky_state *s)
{
	set(s, "metar=EGLL 241250Z 27015KT 9999 FEW012 SCT035TCU BKN080 OVC250 Q1018");
}

static void test_round_trip(const char *name, void (*scene)(struct sky_state *))
{
	struct sky_state a, b, c;
	struct sync_msg_header h;
	char why[256];

	state_default(&a);
	if (scene)
		scene(&a);
	int64_t apply = real_ns() + 300000000ll;
	size_t len = encode(&a, 7, apply);
	CHECK(len > 1000 && len < 16384);
	enum sync_drop d = sync_msg_decode(msg, len, &h, &b, why, sizeof(why));
	if (d) {
		FAIL("%s: refused (%s): %s", name, sync_drop_name(d), why);
		return;
	}
	CHECK(h.version == SYNC_FORMAT_VERSION && h.generation == 7 && h.apply_time_ns == apply);
	CHECK_EQ(h.sequence, SEQ_OF(7));
	CHECK(strcmp(h.controller, ID) == 0);
	const char *f = state_compare(&a, &b);
	if (f)
		FAIL("%s: %s differs after the round trip", name, f);
	/* And so does the sky the tables are computed with: the weather
	 * applied, the raw keys that win kept. */
	struct sky_state ra, rb;
	CHECK(state_resolve(&a, &ra, NULL, why, sizeof(why)) == 0 &&
	      state_resolve(&b, &rb, NULL, why, sizeof(why)) == 0);
	if ((f = state_compare(&ra, &rb)))
		FAIL("%s: %s differs in the resolved state", name, f);
	CHECK(b.n_views == 0);
	/* The same instant on the simulated clock on both sides. */
	double real_s, mono_s;
	simclock_read_clocks(&real_s, &mono_s);
	double ua = state_clock_utc_s(&a, mono_s), ub = state_clock_utc_s(&b, mono_s);
	if (isnan(ua) != isnan(ub) || (!isnan(ua) && fabs(ua - ub) > 1e-3))
		FAIL("%s: simulated time %.6f here, %.6f there", name, ua, ub);
	/* Encoding what was decoded gives the same message: a fixpoint. */
	char first[SYNC_MSG_MAX + 1];
	memcpy(first, msg, len + 1);
	size_t len2 = encode(&b, 7, apply);
	d = sync_msg_decode(msg, len2, &h, &c, why, sizeof(why));
	CHECK(d == SYNC_DROP_NONE && state_compare(&b, &c) == NULL);
	if (isnan(ua))
		CHECK(len2 == len && memcmp(first, msg, len) == 0);
}

/* The time in the message is the one the clock shows at the apply time. */
/* The message names the cloud keys of a state with clouds, and none of a
 * state without. */
static void test_cloud_lines(void)
{
	struct sky_state a;
	int64_t apply = real_ns() + 300000000ll;

	state_default(&a);
	encode(&a, 9, apply);
	CHECK(!strstr(msg, "\ncloud1_oktas=") && !strstr(msg, "\nwind_speed_mps="));
	scene_clouds(&a);
	encode(&a, 9, apply);
	CHECK(strstr(msg, "\ncloud1_oktas=6.5\n") && strstr(msg, "\nwind_speed_mps=12.34\n") &&
	      strstr(msg, "\ncloud2_top_m=9123.45\n") && strstr(msg, "\ncloud_seed=4294967295\n"));
}

static void test_utc_at_apply_time(void)
{
	struct sky_state a;
	state_default(&a);
	scene_clock(&a);
	int64_t apply = real_ns() + 2000000000ll;
	size_t len = encode(&a, 1, apply);
	const char *line = strstr(msg, "\nutc=");
	CHECK(line != NULL && (size_t)(line - msg) < len);
	if (!line)
		return;
	char text[64];
	double utc_s, real_s, mono_s;
	snprintf(text, sizeof(text), "%.*s", (int)strcspn(line + 5, "\n"), line + 5);
	CHECK(simclock_parse_utc(text, &utc_s) == 0);
	simclock_read_clocks(&real_s, &mono_s);
	double expect = state_clock_utc_s(&a, mono_s + ((double)apply / 1e9 - real_s));
	CHECK(fabs(utc_s - expect) < 60 * 1e-3);
	/* And a clock never set stays unset: no utc line at all. */
	state_default(&a);
	len = encode(&a, 1, apply);
	CHECK(strstr(msg, "\nutc=") == NULL);
}

/* ---- refusals ---- */

/* Replaces the line of key with text (NULL removes it) and fixes the
 * header's line count by delta_lines. */
static size_t edit(size_t len, const char *key, const char *text, int delta_lines)
{
	char out[SYNC_MSG_MAX + 1], pat[80];
	snprintf(pat, sizeof(pat), "\n%s=", key);
	char *at = strstr(msg, pat);
	if (!at) {
		FAIL("no line %s", key);
		return len;
	}
	at++;
	char *end = strchr(at, '\n') + 1;
	int n = snprintf(out, sizeof(out), "%.*s%s%s%s", (int)(at - msg), msg, text ? text : "",
			 text ? "\n" : "", end);
	memcpy(msg, out, (size_t)n + 1);
	if (delta_lines) {
		char *l = strstr(msg, "\nlines=");
		unsigned v = (unsigned)atoi(l + 7);
		char rest[SYNC_MSG_MAX + 1];
		snprintf(rest, sizeof(rest), "%s", strchr(l + 1, '\n'));
		snprintf(l, sizeof(msg) - (size_t)(l - msg), "\nlines=%u%s", v + delta_lines, rest);
	}
	return strlen(msg);
}

static void expect_drop(const char *what, size_t len, enum sync_drop want, const char *word)
{
	struct sync_msg_header h;
	struct sky_state s;
	char why[256] = "";
	enum sync_drop d = sync_msg_decode(msg, len, &h, &s, why, sizeof(why));
	if (d != want)
		FAIL("%s: %s (%s), expected %s", what, sync_drop_name(d), why, sync_drop_name(want));
	else if (word && !strstr(why, word))
		FAIL("%s: reason '%s' does not say '%s'", what, why, word);
}

static void test_refusals(void)
{
	struct sky_state a;
	int64_t now = real_ns();
	size_t len;

	state_default(&a);
	scene_clock(&a);
#define FRESH() (len = encode(&a, 3, now))
	FRESH();
	expect_drop("good", len, SYNC_DROP_NONE, NULL);
	expect_drop("empty", 0, SYNC_DROP_MALFORMED, "empty");
	memcpy(msg, "\x00\x01\xff garbage\n", 12);
	expect_drop("binary", 12, SYNC_DROP_MALFORMED, "not text");
	strcpy(msg, "hello world\n");
	expect_drop("text", strlen(msg), SYNC_DROP_MALFORMED, "not a skysync");
	FRESH();
	expect_drop("no final newline", len - 1, SYNC_DROP_MALFORMED, "newline");
	FRESH();
	msg[8] = '3';
	expect_drop("version 3", len, SYNC_DROP_VERSION, "version 3 (this skyd reads 2)");
	/* A version 1 message, as a controller before sequences wrote it:
	 * refused whole, the reason naming both versions. */
	FRESH();
	msg[8] = '1';
	expect_drop("version 1", edit(len, "sequence", NULL, 0), SYNC_DROP_VERSION,
		    "version 1 (this skyd reads 2)");
	FRESH();
	expect_drop("unknown key", edit(len, "sun_azimuth_deg", "sun_bogus_deg=1", 0), SYNC_DROP_KEY,
		    "sun_bogus_deg");
	FRESH();
	expect_drop("out of range", edit(len, "sun_elevation_deg", "sun_elevation_deg=95", 0),
		    SYNC_DROP_RANGE, "sun_elevation_deg");
	FRESH();
	expect_drop("not a number", edit(len, "camera_vfov_deg", "camera_vfov_deg=wide", 0),
		    SYNC_DROP_RANGE, "camera_vfov_deg");
	FRESH();
	expect_drop("cross-key", edit(len, "top_radius_km", "top_radius_km=6000", 0),
		    SYNC_DROP_RANGE, "top_radius_km");
	FRESH();
	expect_drop("bad utc", edit(len, "utc", "utc=yesterday", 0), SYNC_DROP_RANGE, "utc");
	FRESH();
	expect_drop("truncated", edit(len, "night_illuminance_lx", NULL, 0), SYNC_DROP_MALFORMED,
		    "lines");
	FRESH();
	expect_drop("missing key", edit(len, "camera_roll_deg", NULL, -1), SYNC_DROP_MALFORMED,
		    "camera_roll_deg");
	FRESH();
	expect_drop("extra key", edit(len, "storage", "storage=f32\nquality=low", 1),
		    SYNC_DROP_MALFORMED, "keys");
	FRESH();
	expect_drop("twice", edit(len, "storage", "storage=f32\nstorage=f16", 1),
		    SYNC_DROP_MALFORMED, "twice");
	FRESH();
	expect_drop("no '='", edit(len, "storage", "storage", 0), SYNC_DROP_MALFORMED, NULL);
	FRESH();
	expect_drop("controller id", edit(len, "controller", "controller=a b", 0),
		    SYNC_DROP_MALFORMED, "controller");
	FRESH();
	expect_drop("generation 0", edit(len, "generation", "generation=0", 0), SYNC_DROP_MALFORMED,
		    "generation");
	FRESH();
	expect_drop("generation -1", edit(len, "generation", "generation=-1", 0),
		    SYNC_DROP_MALFORMED, "generation");
	FRESH();
	expect_drop("no apply time", edit(len, "apply_time_ns", NULL, 0), SYNC_DROP_MALFORMED,
		    "apply_time_ns");
	len = encode(&a, 3, now + SYNC_APPLY_AHEAD_MAX_NS + 10000000000ll);
	expect_drop("apply time far ahead", len, SYNC_DROP_RANGE, "ahead");
	FRESH();
	char longline[700];
	memset(longline, 'x', sizeof(longline));
	memcpy(longline, "storage=", 8);
	longline[sizeof(longline) - 1] = 0;
	expect_drop("long line", edit(len, "storage", longline, 0), SYNC_DROP_MALFORMED, "long");
	/* A field a later revision of version 2 adds is skipped. */
	FRESH();
	expect_drop("no line count", edit(len, "lines", NULL, 0), SYNC_DROP_MALFORMED, "lines");
	FRESH();
	char *l = strstr(msg, "\nlines=");
	char rest[SYNC_MSG_MAX + 1];
	snprintf(rest, sizeof(rest), "%s", l);
	snprintf(l, sizeof(msg) - (size_t)(l - msg), "\nfuture_field=yes%s", rest);
	expect_drop("unknown header field", strlen(msg), SYNC_DROP_NONE, NULL);
#undef FRESH
}

/* The header fields of version 2: the sequence, the weather's overrides
 * and the cloud factor. */
static void test_header_fields(void)
{
	struct sky_state a;
	int64_t now = real_ns();
	size_t len;

	state_default(&a);
	scene_clock(&a);
#define FRESH() (len = encode(&a, 3, now))
	FRESH();
	expect_drop("no sequence", edit(len, "sequence", NULL, 0), SYNC_DROP_MALFORMED, "sequence");
	FRESH();
	expect_drop("sequence 0", edit(len, "sequence", "sequence=0", 0), SYNC_DROP_MALFORMED,
		    "sequence");
	FRESH();
	expect_drop("no overridden", edit(len, "overridden", NULL, 0), SYNC_DROP_MALFORMED,
		    "overridden");
	FRESH();
	expect_drop("overridden unknown", edit(len, "overridden", "overridden=mie_q", 0),
		    SYNC_DROP_MALFORMED, "overridden");
	FRESH();
	expect_drop("overridden twice", edit(len, "overridden", "overridden=mie_g,mie_g", 0),
		    SYNC_DROP_MALFORMED, "overridden");
	FRESH();
	expect_drop("overridden list", edit(len, "overridden", "overridden=mie_g,ozone_absorption_per_km", 0),
		    SYNC_DROP_NONE, NULL);
	FRESH();
	expect_drop("no cloud factor", edit(len, "cloud_factor", NULL, 0), SYNC_DROP_MALFORMED,
		    "cloud_factor");
	FRESH();
	expect_drop("cloud factor 2", edit(len, "cloud_factor", "cloud_factor=2", 0), SYNC_DROP_RANGE,
		    "cloud_factor");
	FRESH();
	expect_drop("cloud factor nan", edit(len, "cloud_factor", "cloud_factor=nan", 0),
		    SYNC_DROP_RANGE, "cloud_factor");
#undef FRESH
}

/* The field's placement travels in the header, exact: a follower's own
 * clocks could floor the apply instant to another second. A message
 * without it (a controller before it) still reads, the placement left to
 * the follower. */
static void test_cloud_placed(void)
{
	static const double placed[] = { 1782036005.0, NAN, -62167219200.0, 253402300799.0 };
	struct sync_msg_header h;
	struct sky_state a, b;
	char why[256];
	size_t len;

	for (size_t i = 0; i < sizeof(placed) / sizeof(placed[0]); i++) {
		state_default(&a);
		scene_clouds(&a);
		a.clouds.utc_s = placed[i];
		len = encode(&a, 5, real_ns());
		CHECK(sync_msg_decode(msg, len, &h, &b, why, sizeof(why)) == SYNC_DROP_NONE);
		CHECK_EQ(h.cloud_placed_sent, 1);
		CHECK(memcmp(&h.cloud_placed_utc_s, &placed[i], sizeof(double)) == 0);
	}
	len = edit(len, "cloud_placed_utc_s", NULL, 0);
	CHECK(sync_msg_decode(msg, len, &h, &b, why, sizeof(why)) == SYNC_DROP_NONE);
	CHECK_EQ(h.cloud_placed_sent, 0);
	CHECK(isnan(h.cloud_placed_utc_s));
	static const char *const bad[] = { "cloud_placed_utc_s=1782036005.5", "cloud_placed_utc_s=nan",
					   "cloud_placed_utc_s=", "cloud_placed_utc_s=1e300",
					   "cloud_placed_utc_s=253402300800" };
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		len = encode(&a, 5, real_ns());
		expect_drop(bad[i], edit(len, "cloud_placed_utc_s", bad[i], 0), SYNC_DROP_RANGE,
			    "cloud_placed_utc_s");
	}
	len = encode(&a, 5, real_ns());
	len = edit(len, "cloud_placed_utc_s", "cloud_placed_utc_s=1\ncloud_placed_utc_s=2", 0);
	expect_drop("cloud_placed_utc_s twice", len, SYNC_DROP_MALFORMED, "twice");
}

static void test_presence(void)
{
	struct sync_presence p = { .online = 1 }, q;
	char buf[256], why[256];
	size_t len;

	snprintf(p.controller, sizeof(p.controller), "%s", ID);
	CHECK(sync_presence_encode(&p, buf, sizeof(buf), &len) == 0);
	CHECK(sync_presence_decode(buf, len, &q, why, sizeof(why)) == SYNC_DROP_NONE);
	CHECK(strcmp(q.controller, ID) == 0 && q.online == 1);
	CHECK(sync_presence_decode("", 0, &q, why, sizeof(why)) == SYNC_DROP_NONE);
	CHECK(q.controller[0] == 0 && q.online == 0);
	CHECK(sync_presence_decode("junk", 4, &q, why, sizeof(why)) == SYNC_DROP_MALFORMED);
	CHECK(strncmp(buf, "skysync=2\n", 10) == 0);
	const char *v1 = "skysync=1\ncontroller=" ID "\nonline=1\n";
	CHECK(sync_presence_decode(v1, strlen(v1), &q, why, sizeof(why)) == SYNC_DROP_VERSION);
	const char *v3 = "skysync=3\ncontroller=" ID "\nonline=1\n";
	CHECK(sync_presence_decode(v3, strlen(v3), &q, why, sizeof(why)) == SYNC_DROP_VERSION);
	const char *bad = "skysync=2\ncontroller=" ID "\nonline=2\n";
	CHECK(sync_presence_decode(bad, strlen(bad), &q, why, sizeof(why)) == SYNC_DROP_MALFORMED);
	const char *noid = "skysync=2\nonline=1\n";
	CHECK(sync_presence_decode(noid, strlen(noid), &q, why, sizeof(why)) ==
	      SYNC_DROP_MALFORMED);
	CHECK(sync_id_valid(ID) && !sync_id_valid("a/b") && !sync_id_valid("a//b") &&
	      !sync_id_valid("a/b/c d") && !sync_id_valid("/a/b") && !sync_id_valid(""));
	snprintf(p.controller, sizeof(p.controller), "not an id");
	CHECK(sync_presence_encode(&p, buf, sizeof(buf), &len) == -EINVAL);
}

/* ---- settings ---- */

static void test_url(void)
{
	struct sync_config c;
	char err[256];

	sync_config_defaults(&c);
	CHECK(sync_config_parse_url(&c, "mqtt://127.0.0.1:18830/sky/hall", err, sizeof(err)) == 0);
	CHECK(!strcmp(c.host, "127.0.0.1") && c.port == 18830 && !strcmp(c.prefix, "sky/hall") &&
	      !c.tls);
	CHECK(sync_config_parse_url(&c, "mqtts://broker.example.org/dome", err, sizeof(err)) == 0);
	CHECK(!strcmp(c.host, "broker.example.org") && c.port == 8883 && c.tls);
	CHECK(sync_config_parse_url(&c, "mqtt://[::1]:1884/p", err, sizeof(err)) == 0);
	CHECK(!strcmp(c.host, "::1") && c.port == 1884 && !c.tls);
	CHECK(sync_config_parse_url(&c, "mqtt://broker/sky", err, sizeof(err)) == 0 && c.port == 1883);
	static const char *const bad[] = {
		"http://h/p", "mqtt://h", "mqtt://h/", "mqtt://h:0/p", "mqtt://h:65536/p",
		"mqtt://h:12a/p", "mqtt://h/p/+", "mqtt://h/#", "mqtt://h/a//b", "mqtt://h/a/",
		"mqtt://:1883/p", "mqtt://[::1/p", "mqtt://ho st/p", "mqtt://h:/p",
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		struct sync_config before = c;
		if (sync_config_parse_url(&c, bad[i], err, sizeof(err)) != -EINVAL)
			FAIL("%s accepted", bad[i]);
		CHECK(memcmp(&before, &c, sizeof(c)) == 0);
	}
	/* Credentials in a URL: refused, and never repeated in the message. */
	CHECK(sync_config_parse_url(&c, "mqtt://alice:hunter2@h/p", err, sizeof(err)) == -EINVAL);
	CHECK(strstr(err, "hunter2") == NULL && strstr(err, "alice") == NULL);
}

static void test_check(void)
{
	struct sync_config c;
	char err[256], path[] = "/tmp/test_sync_pwXXXXXX";

	sync_config_defaults(&c);
	CHECK(sync_config_check(&c, err, sizeof(err)) == -EINVAL);	/* no broker */
	CHECK(sync_config_parse_url(&c, "mqtt://127.0.0.1/sky", err, sizeof(err)) == 0);
	CHECK(sync_config_check(&c, err, sizeof(err)) == 0);
	struct sync_config d = c;
	snprintf(d.password, sizeof(d.password), "pw");
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL && strstr(err, "username"));
	d = c;
	snprintf(d.cafile, sizeof(d.cafile), "/etc/ca.pem");
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL && strstr(err, "mqtts"));
	d.tls = 1;
	CHECK(sync_config_check(&d, err, sizeof(err)) == 0);
	snprintf(d.certfile, sizeof(d.certfile), "/etc/client.pem");
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL);
	d = c;
	d.keepalive_s = 1;
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL);
	d = c;
	d.lead_ms = 20000;
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL);
	d = c;
	d.backoff_min_ms = 5000;
	d.backoff_max_ms = 1000;
	CHECK(sync_config_check(&d, err, sizeof(err)) == -EINVAL);
	enum sync_role r;
	CHECK(sync_parse_role("controller", &r) == 0 && r == SYNC_CONTROLLER);
	CHECK(sync_parse_role("follower", &r) == 0 && r == SYNC_FOLLOWER);
	CHECK(sync_parse_role("leader", &r) == -EINVAL);
	/* The password file: its first line; the error names the file only. */
	int fd = mkstemp(path);
	CHECK(fd >= 0 && write(fd, "s3cret pass\nnext\n", 17) == 17);
	close(fd);
	CHECK(sync_config_read_password(&c, path, err, sizeof(err)) == 0);
	CHECK(strcmp(c.password, "s3cret pass") == 0);
	fd = open(path, O_WRONLY | O_TRUNC);
	CHECK(fd >= 0 && write(fd, "\n", 1) == 1);
	close(fd);
	CHECK(sync_config_read_password(&c, path, err, sizeof(err)) == -EINVAL);
	unlink(path);
	CHECK(sync_config_read_password(&c, path, err, sizeof(err)) == -ENOENT);
}

int main(void)
{
	test_round_trip("default", NULL);
	test_round_trip("clock", scene_clock);
	test_round_trip("mars", scene_mars);
	test_round_trip("custom", scene_custom);
	test_round_trip("weather", scene_weather);
	test_round_trip("exact", scene_exact);
	test_round_trip("clouds", scene_clouds);
	test_round_trip("metar clouds", scene_metar_clouds);
	test_cloud_lines();
	test_utc_at_apply_time();
	test_refusals();
	test_header_fields();
	test_cloud_placed();
	test_presence();
	test_url();
	test_check();
	return test_report("test_sync_msg");
}

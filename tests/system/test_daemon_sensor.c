/* test_daemon_sensor.c - the real skyd with a mocked USB light sensor:
 * umockdev's device descriptions and usbmon captures from tests/sensor
 * (gen.py, gen_daemon.py), the readings of which are known.
 *
 * One scenario per run, named by the first argument:
 *   cloud      the light factor is each reading over the clear sky that the
 *              tables predict, and the published tables then give the
 *              reading back as their horizontal illuminance;
 *   elevation  the readings place the sun (refined until the tables give
 *              the reading); one outside the curve is reported, not applied;
 *   exposure   EV100 of each reading in events and status; no generation;
 *              the next slot carries the last one;
 *   garbage    refused readings are counted by reason, the sky stays;
 *   vanish     the device stops answering: the value goes stale and stays,
 *              get sensor says why (started with sensor_mode=cloud);
 *   list       skyd --list-sensors lists both families and the keyboard;
 *   follower   a follower of replication (through a mosquitto of the
 *              test's) reads its sensor but changes nothing: its sky is
 *              the controller's.
 * Started outside umockdev, it runs itself under umockdev-run with the
 * scenario's files; 77 without umockdev-run or a Vulkan device. Every wait
 * is on a line from skyd: a sensor: event, a changed: generation. */
#include <math.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sync_harness.h"
#include "test.h"
#include "umockdev_exec.h"

#define REL(a, b, tol) (fabs((a) - (b)) <= (tol) * fabs(b))

static char reply[1 << 16];

/* ---- sensor: events ---- */

struct ev {
	char mode[16], state[16], not_applied[160];
	double lux, ev100, cloud_factor, elevation_deg;	/* NAN for none */
	int stale;
	uint64_t generation, changes, accepted, rejected;
};

static struct ev evs[512];
static int n_evs;

static double field_num(const char *v)
{
	return strcmp(v, "none") == 0 ? NAN : strtod(v, NULL);
}

static void parse_event(const char *line)
{
	char copy[1024], *save = NULL;
	struct ev e = { .lux = NAN, .ev100 = NAN, .cloud_factor = NAN, .elevation_deg = NAN };

	snprintf(copy, sizeof(copy), "%s", line + 8);
	for (char *tok = strtok_r(copy, " ", &save); tok; tok = strtok_r(NULL, " ", &save)) {
		char *v = strchr(tok, '=');
		if (!v)
			continue;
		*v++ = 0;
		if (!strcmp(tok, "mode")) snprintf(e.mode, sizeof(e.mode), "%s", v);
		else if (!strcmp(tok, "state")) snprintf(e.state, sizeof(e.state), "%s", v);
		else if (!strcmp(tok, "not_applied")) snprintf(e.not_applied, sizeof(e.not_applied), "%s", v);
		else if (!strcmp(tok, "lux")) e.lux = field_num(v);
		else if (!strcmp(tok, "ev100")) e.ev100 = field_num(v);
		else if (!strcmp(tok, "cloud_factor")) e.cloud_factor = field_num(v);
		else if (!strcmp(tok, "elevation_deg")) e.elevation_deg = field_num(v);
		else if (!strcmp(tok, "stale")) e.stale = atoi(v);
		else if (!strcmp(tok, "generation")) e.generation = strtoull(v, NULL, 10);
		else if (!strcmp(tok, "changes")) e.changes = strtoull(v, NULL, 10);
		else if (!strcmp(tok, "accepted")) e.accepted = strtoull(v, NULL, 10);
		else if (!strcmp(tok, "rejected")) e.rejected = strtoull(v, NULL, 10);
	}
	if (n_evs < (int)(sizeof(evs) / sizeof(evs[0])))
		evs[n_evs++] = e;
}

/* An event line of either kind: noted. 1 if it was one. */
static int note(struct conn *c, const char *line)
{
	if (!strncmp(line, "sensor: ", 8)) {
		parse_event(line);
		return 1;
	}
	if (is_event_line(line)) {
		conn_note_event(c, line);
		return 1;
	}
	return 0;
}

/* conn_request, with sensor: lines taken as the events they are. */
static int request(struct conn *c, const char *req)
{
	char line[8192];
	size_t o = 0, n = strlen(req);

	reply[0] = 0;
	if (send(c->fd, req, n, MSG_NOSIGNAL) != (ssize_t)n || send(c->fd, "\n", 1, MSG_NOSIGNAL) != 1)
		return -1;
	for (;;) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		if (note(c, line))
			continue;
		if (o < sizeof(reply))
			o += (size_t)snprintf(reply + o, sizeof(reply) - o, "%s\n", line);
		if (strcmp(line, "OK") == 0)
			return 0;
		if (strncmp(line, "ACK [", 5) == 0)
			return atoi(line + 5);
	}
}

/* Reads lines until one more sensor: event came; its index, -1 on timeout. */
static int next_event(struct conn *c)
{
	char line[8192];
	int have = n_evs;

	while (n_evs == have) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		note(c, line);
	}
	return n_evs - 1;
}

/* Reads events until pred holds for one; its index, -1 on timeout. */
static int wait_event(struct conn *c, int from, int (*pred)(const struct ev *))
{
	for (int i = from; ; i++) {
		while (i >= n_evs)
			if (next_event(c) < 0)
				return -1;
		if (pred(&evs[i]))
			return i;
	}
}

static int wait_generation(struct conn *c, uint64_t g)
{
	char line[8192];

	while (c->event_generation < g) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		note(c, line);
	}
	return 0;
}

static double num(struct conn *c, const char *req, const char *key)
{
	char buf[256];

	if (request(c, req) != 0 || !reply_value(reply, key, buf, sizeof(buf))) {
		FAIL("%s: no %s in '%s'", req, key, reply);
		return NAN;
	}
	return field_num(buf);
}

static const char *text(struct conn *c, const char *req, const char *key, char *buf, size_t size)
{
	if (request(c, req) != 0 || !reply_value(reply, key, buf, size)) {
		FAIL("%s: no %s in '%s'", req, key, reply);
		snprintf(buf, size, "?");
	}
	return buf;
}

/* The published tables' horizontal illuminance, as any client can read
 * it: the sun's illuminance at the observer times the sine of its
 * elevation, plus the sky's (sample ambient); the moon lights nothing. */
static double horizontal_lx(struct conn *c)
{
	double sun = num(c, "sample sun", "illuminance_lx");
	double sky = num(c, "sample ambient", "illuminance_lx");
	double el = num(c, "get sun_elevation_deg", "sun_elevation_deg");

	return sun * sin(el * M_PI / 180.0) + sky;
}

/* ---- the daemon ---- */

/* Fast settings for a test: every reading is an output, the device stops
 * soon after its capture ends. report_interval_s is gen.py's 50 ms, which
 * the HID sensor's set-up writes into its feature report. */
#define FAST "sensor_time_constant_s=0", "sensor_hysteresis=0", "sensor_min_interval_s=0", \
	"sensor_report_interval_s=0.05", "sensor_io_timeout_s=0.2", "sensor_rescan_s=0.2",   \
	"sensor_stale_after_s=0.5"

static struct daemon d;

static int start(struct conn *c, const char *const *args)
{
	if (daemon_start(&d, args) < 0 || conn_open(c, d.sock) < 0) {
		FAIL("skyd did not start");
		return -1;
	}
	CHECK(request(c, "subscribe events=1") == 0);
	CHECK(request(c, "sensor events=1") == 0);
	CHECK(strstr(reply, "events: 1") != NULL);
	return 0;
}

static int is_reading(const struct ev *e)
{
	return !isnan(e->lux) && !e->stale;
}

/* The device stopped: no longer reading (it is looked for again). */
static int is_stopped(const struct ev *e)
{
	return strcmp(e->state, "searching") == 0 || strcmp(e->state, "starting") == 0;
}

static int is_stale(const struct ev *e)
{
	return e->stale;
}

/* A device is open: reading, or stale while nothing comes. */
static int is_open(const struct ev *e)
{
	return strcmp(e->state, "reading") == 0 || strcmp(e->state, "stale") == 0;
}

/* ---- scenarios ---- */

static double bh1750_lux(unsigned count)
{
	return count / 1.2 * 69.0 / 31.0;
}

static void run_cloud(void)
{
	static const unsigned counts[] = { 5391, 13478, 21565, 29652 };	/* gen_daemon.py */
	static const char *const args[] = { HARNESS_SMALL, FAST, "sun_elevation_deg=60", NULL };
	struct conn c;
	char buf[256];

	if (start(&c, args) < 0)
		return;
	double clear = horizontal_lx(&c);
	printf("cloud: clear sky %.1f lx at 60 deg\n", clear);
	CHECK(request(&c, "set sensor_mode=cloud") == 0);
	int from = 0;
	for (int k = 0; k < 4; k++) {
		int i = wait_event(&c, from, is_reading);
		if (i < 0) {
			FAIL("no reading %d", k);
			return;
		}
		const struct ev *e = &evs[i];
		printf("cloud: %.3f lx -> cloud_factor %.6f in generation %llu\n", e->lux,
		       e->cloud_factor, (unsigned long long)e->generation);
		CHECK(REL(e->lux, bh1750_lux(counts[k]), 1e-8));	/* printed to 9 digits */
		CHECK(e->accepted == (uint64_t)k + 1);
		/* The clear sky from the same tables, less the night floor's 0.002 lx. */
		CHECK(REL(e->cloud_factor, e->lux / clear, 1e-6));
		CHECK(e->changes == (uint64_t)k + 1 && !strcmp(e->not_applied, "none"));
		from = i + 1;
	}
	const struct ev *last = &evs[from - 1];
	CHECK(wait_generation(&c, last->generation) == 0);
	/* The lights move as the readings say: the tables give the reading back. */
	double seen = horizontal_lx(&c);
	printf("cloud: the tables of generation %llu give %.3f lx for a reading of %.3f lx\n",
	       (unsigned long long)last->generation, seen, last->lux);
	CHECK(REL(seen, last->lux, 1e-4));
	/* The state keeps the sun as set; the factor is the sensor's. */
	CHECK(num(&c, "get sun_illuminance_lx", "sun_illuminance_lx") == 133800.0);
	CHECK(REL(num(&c, "get sensor", "cloud_factor"), last->cloud_factor, 1e-9));
	CHECK(!strcmp(text(&c, "get sensor", "family", buf, sizeof(buf)), "mcp2221-bh1750"));
	CHECK(!strcmp(text(&c, "get sensor", "device", buf, sizeof(buf)), "1-3"));
	CHECK(request(&c, "sensor list") == 0);
	CHECK(strstr(reply, "device: bus=1-3 family=mcp2221-bh1750 id=04d8:00dd serial=MCP-0001") != NULL);
	CHECK(num(&c, "status", "sensor_cloud_factor") == last->cloud_factor);
	/* skyctl sensor is get sensor. */
	char cmd[512], out[8192];
	snprintf(cmd, sizeof(cmd), "%s --socket '%s' sensor", SKYCTL_BINARY, d.sock);
	FILE *p = popen(cmd, "r");
	size_t n = p ? fread(out, 1, sizeof(out) - 1, p) : 0;
	out[n] = 0;
	CHECK(p && pclose(p) == 0);
	CHECK(strstr(out, "mode: cloud\n") && strstr(out, "family: mcp2221-bh1750\n"));
	/* The sensor wrote the weather's cloud cover: get weather says so. */
	CHECK(REL(num(&c, "get weather", "cloud_factor"), last->cloud_factor, 1e-9));
	/* Off keeps the cover last measured; auto gives the lights back. */
	CHECK(request(&c, "set sensor_mode=off cloud_oktas=auto") == 0);
	CHECK(wait_generation(&c, reply_u64(reply, "generation")) == 0);
	CHECK(REL(horizontal_lx(&c), clear, 1e-6));
	conn_close(&c);
}

static double usno_elevation(double lux)
{
	static const double el[] = { -12.0, -6.0, -0.8, 0.0, 10.0, 30.0, 60.0, 90.0 };
	static const double lx[] = { 0.008, 3.4, 464.0, 759.0, 11100.0, 46000.0, 103000.0, 128800.0 };
	int i = 1;

	while (i < 7 && lux > lx[i])
		i++;
	return el[i - 1] + (log(lux) - log(lx[i - 1])) / (log(lx[i]) - log(lx[i - 1])) * (el[i] - el[i - 1]);
}

/* Until the sensor's generation is published and a look after it finds
 * it unchanged: the refinement that follows each publication is over. */
static uint64_t settle(struct conn *c)
{
	uint64_t g = 0, next;

	for (int round = 0; round < 20; round++) {
		next = (uint64_t)num(c, "get sensor", "generation");
		if (next == g)
			return g;
		g = next;
		if (wait_generation(c, g) < 0)
			break;
	}
	FAIL("the elevation did not settle");
	return g;
}

static void run_elevation(void)
{
	static const char *const args[] = { HARNESS_SMALL, FAST, NULL };
	static const double readings[] = { 3.0, 0.0, 25000.0 };	/* gen_daemon.py */
	struct conn c;
	char buf[256];

	if (start(&c, args) < 0)
		return;
	/* The tables first, as a sensor in use finds them: the capture's
	 * three readings are all there is, and the curve is refined from the
	 * tables only while a reading is fresh. */
	CHECK(horizontal_lx(&c) > 0.0);
	CHECK(request(&c, "set sensor_mode=elevation") == 0);
	int from = 0;
	for (int k = 0; k < 3; k++) {
		int i = wait_event(&c, from, is_reading);
		if (i < 0) {
			FAIL("no reading %d", k);
			return;
		}
		const struct ev *e = &evs[i];
		printf("elevation: %g lx -> %.4f deg (USNO alone %.4f) in generation %llu, %s\n",
		       e->lux, e->elevation_deg, readings[k] > 0 ? usno_elevation(readings[k]) : NAN,
		       (unsigned long long)e->generation, e->not_applied);
		/* 0 lx comes back from the pipeline's logarithm as a few 1e-18. */
		CHECK(fabs(e->lux - readings[k]) <= 1e-8 * readings[k] + 1e-12);
		if (k == 1) {
			/* No light at all: outside the curve, the sun stays. */
			CHECK(strstr(e->not_applied, "outside_the_curve") != NULL);
			CHECK(e->elevation_deg == evs[from - 1].elevation_deg);
			CHECK(e->changes == evs[from - 1].changes);
		} else {
			CHECK(!strcmp(e->not_applied, "none"));
			/* The tables are brighter than USNO's sky at low sun: the
			 * refined curve puts the sun lower, by a few degrees. */
			double u = usno_elevation(readings[k]);
			CHECK(e->elevation_deg <= u + 0.5 && e->elevation_deg >= u - 6.0);
		}
		from = i + 1;
	}
	if (wait_event(&c, from, is_stopped) < 0)
		FAIL("the device did not stop");
	uint64_t g = settle(&c);
	double el = num(&c, "get sensor", "elevation_deg");
	double sun = num(&c, "get sun_elevation_deg", "sun_elevation_deg");
	double seen = horizontal_lx(&c);
	printf("elevation: settled in generation %llu at %.4f deg (sun %.4f); the tables give %.1f lx for 25000; curve %s with %.0f points\n",
	       (unsigned long long)g, el, sun, seen, text(&c, "get sensor", "curve", buf, sizeof(buf)),
	       num(&c, "get sensor", "curve_points"));
	CHECK(fabs(el - sun) <= 0.011);
	CHECK(!strcmp(text(&c, "get sun_mode", "sun_mode", buf, sizeof(buf)), "manual"));
	CHECK(!strcmp(text(&c, "get sensor", "curve", buf, sizeof(buf)), "tables+usno"));
	CHECK(num(&c, "get sensor", "curve_points") >= 2);
	CHECK(REL(seen, 25000.0, 0.03));
	conn_close(&c);
}

/* The next slot carries the last EV100 (sky_shm_state.exposure_ev100): a
 * set publishes one, read through libsky. */
static void check_slot_exposure(struct conn *c, double ev100)
{
	sky_client *sc = NULL;
	struct sky_view v;

	CHECK(request(c, "set sun_azimuth_deg=170") == 0);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(wait_generation(c, g) == 0);
	CHECK(sky_connect(d.sock, &sc) == 0);
	if (!sc)
		return;
	sky_set_timeout(sc, 30000);
	CHECK(sky_subscribe(sc, SKY_TABLES_ALL, 0) == 0);
	CHECK(sky_view_begin(sc, &v) == 0);
	uint64_t slot_g = v.slot->generation;
	double slot_ev = v.slot->state.exposure_ev100;
	CHECK(sky_view_end(sc, &v));
	printf("exposure: slot of generation %llu carries EV100 %.4f\n", (unsigned long long)slot_g,
	       slot_ev);
	CHECK(slot_g >= g);
	CHECK(REL(slot_ev, ev100, 1e-8));
	sky_disconnect(sc);
}

static void run_exposure(void)
{
	static const char *const args[] = { HARNESS_SMALL, FAST, NULL };
	static const double readings[] = { 1234.56, 1300.0, 25000.0, 0.5, 101325.0 };	/* gen.py */
	struct conn c;

	if (start(&c, args) < 0)
		return;
	CHECK(request(&c, "set sensor_mode=exposure") == 0);
	uint64_t g = reply_u64(reply, "generation");
	int from = 0;
	for (int k = 0; k < 5; k++) {
		int i = wait_event(&c, from, is_reading);
		if (i < 0) {
			FAIL("no reading %d", k);
			return;
		}
		const struct ev *e = &evs[i];
		double want = log2(readings[k] * 100.0 / 250.0);
		printf("exposure: %g lx -> EV100 %.4f, generation %llu\n", e->lux, e->ev100,
		       (unsigned long long)e->generation);
		CHECK(REL(e->lux, readings[k], 1e-8));
		CHECK(REL(e->ev100, want, 1e-8));
		CHECK(e->generation == g && e->changes == 0);
		from = i + 1;
	}
	CHECK(REL(num(&c, "status", "sensor_ev100"), log2(101325.0 * 100.0 / 250.0), 1e-8));
	CHECK(num(&c, "status", "generation") == (double)g);
	CHECK(num(&c, "get sensor", "changes") == 0.0);
	CHECK(num(&c, "get sensor", "cloud_factor") == 1.0);
	check_slot_exposure(&c, evs[from - 1].ev100);
	conn_close(&c);
}

static void run_garbage(void)
{
	static const char *const args[] = { HARNESS_SMALL, FAST, "sun_elevation_deg=60", NULL };
	struct conn c;
	char buf[256], cmd[512];

	if (start(&c, args) < 0)
		return;
	double clear = horizontal_lx(&c);
	CHECK(request(&c, "set sensor_mode=cloud") == 0);
	int i = wait_event(&c, 0, is_reading);
	if (i < 0) {
		FAIL("no reading");
		return;
	}
	struct ev good = evs[i];
	CHECK(good.lux == 20000.0 && REL(good.cloud_factor, 20000.0 / clear, 1e-6));
	CHECK(wait_generation(&c, good.generation) == 0);
	double seen = horizontal_lx(&c);
	if (wait_event(&c, i + 1, is_stopped) < 0)
		FAIL("the device did not stop");
	CHECK(num(&c, "get sensor", "accepted") == 1.0);
	CHECK(num(&c, "get sensor", "rejected") == 6.0);
	printf("garbage: rejected_by %s, last_error %s\n",
	       text(&c, "get sensor", "rejected_by", buf, sizeof(buf)),
	       text(&c, "get sensor", "last_error", cmd, sizeof(cmd)));
	CHECK(!strcmp(text(&c, "get sensor", "rejected_by", buf, sizeof(buf)),
		      "high=1,malformed=4,not-ready=1"));
	/* The sky stayed: no change after the good reading's. */
	CHECK(num(&c, "get sensor", "changes") == 1.0);
	CHECK(num(&c, "get sensor", "generation") == (double)good.generation);
	CHECK(num(&c, "status", "generation") == (double)good.generation);
	CHECK(num(&c, "get sensor", "cloud_factor") == good.cloud_factor);
	CHECK(horizontal_lx(&c) == seen);
	/* Refusals say why in the log (five lines in ten seconds at most). */
	snprintf(cmd, sizeof(cmd), "grep -q 'reading refused: malformed' '%s'", d.log);
	CHECK(system(cmd) == 0);
	conn_close(&c);
}

/* Started with the sensor on: the five readings come before the test
 * listens; then the capture ends with a transfer pending. */
static void run_vanish(void)
{
	static const char *const args[] = { HARNESS_SMALL, FAST, "sun_elevation_deg=85",
					    "sensor_mode=cloud", NULL };
	struct conn c;
	char buf[256];

	if (start(&c, args) < 0)
		return;
	/* Asked after sensor events=1: if it is not stale yet, its event comes. */
	if (num(&c, "get sensor", "stale") != 1.0 && wait_event(&c, 0, is_stale) < 0)
		FAIL("the value did not go stale");
	/* Then it fails: a stop after it was open (the state it started in,
	 * starting, is no stop), which last_error must name. Waiting for the
	 * stale value only raced the first timeout of its transfers, which
	 * comes at the same time and sets last_error. */
	int open = wait_event(&c, 0, is_open);
	if (open < 0 || wait_event(&c, open + 1, is_stopped) < 0)
		FAIL("the device did not stop");
	double clear = num(&c, "get sensor", "clear_sky_lx");
	double f = num(&c, "get sensor", "cloud_factor");
	printf("vanish: state %s, stale, lux %s, cloud_factor %.6f, last_error %s\n",
	       text(&c, "get sensor", "state", buf, sizeof(buf)),
	       text(&c, "get sensor", "lux", buf + 64, 64), f,
	       text(&c, "get sensor", "last_error", buf + 128, 128));
	CHECK(num(&c, "get sensor", "stale") == 1.0);
	CHECK(num(&c, "get sensor", "lux") == 101325.0);
	CHECK(clear > 101325.0 && REL(f, 101325.0 / clear, 1e-6));
	CHECK(strstr(text(&c, "get sensor", "not_applied", buf, sizeof(buf)), "stale") != NULL);
	CHECK(strcmp(text(&c, "get sensor", "last_error", buf, sizeof(buf)), "none") != 0);
	CHECK(num(&c, "get sensor", "failures") >= 1.0);
	CHECK(num(&c, "status", "sensor_stale") == 1.0);
	/* The last good value still lights the sky. */
	uint64_t g = (uint64_t)num(&c, "get sensor", "generation");
	CHECK(wait_generation(&c, g) == 0);
	CHECK(REL(horizontal_lx(&c), 101325.0, 1e-4));
	conn_close(&c);
}

static void run_list(void)
{
	char cmd[512], out[4096];

	snprintf(cmd, sizeof(cmd), "%s --list-sensors sensor_io_timeout_s=0.2 2>/dev/null", SKYD_BINARY);
	FILE *p = popen(cmd, "r");
	size_t n = p ? fread(out, 1, sizeof(out) - 1, p) : 0;
	out[n] = 0;
	CHECK(p && pclose(p) == 0);
	printf("%s", out);
	CHECK(strstr(out, "1-2 hid-sensor 1209:0001 serial=ALS-0001 state=idle selected") != NULL);
	CHECK(strstr(out, "1-3 mcp2221-bh1750 04d8:00dd serial=MCP-0001 state=idle selected") != NULL);
	CHECK(strstr(out, "(BH1750 at 0x5c") != NULL);
	CHECK(strstr(out, "(illuminance 32 bit in report 1") != NULL);
	CHECK(strstr(out, "1-4 hid-sensor 1209:0003 serial=KBD-1 state=unsupported") != NULL);
}

/* A follower's readings change nothing, each output saying why; the
 * follower has no controller here, so none of them is the controller's. */
static void run_follower(void)
{
	static struct sync_rig rig;
	struct conn c;

	if (!sync_have_mosquitto()) {
		printf("skipped: no %s\n", SYNC_MOSQUITTO_BIN);
		exit(77);
	}
	if (sync_broker_setup(&rig) < 0) {
		FAIL("mosquitto did not start");
		return;
	}
	const char *const args[] = { "--sync", rig.url, "--sync-role", "follower", HARNESS_SMALL,
				     FAST, "sun_elevation_deg=60", "sensor_mode=cloud", NULL };
	if (start(&c, args) == 0) {
		for (int k = 0, from = 0; k < 2; k++) {
			int i = wait_event(&c, from, is_reading);
			if (i < 0) {
				FAIL("no reading %d", k);
				break;
			}
			printf("follower: %.3f lx: %s\n", evs[i].lux, evs[i].not_applied);
			CHECK(strstr(evs[i].not_applied, "follows_controller") != NULL);	/* spaces as _ */
			CHECK(evs[i].changes == 0 && evs[i].cloud_factor == 1.0);
			from = i + 1;
		}
		CHECK(num(&c, "status", "sensor_cloud_factor") == 1.0);
		conn_close(&c);
	}
	sync_rig_finish(&rig);
}

/* ---- running ---- */

struct scenario {
	const char *name;
	const char *devices[4];		/* *.umockdev in tests/sensor */
	const char *captures[4];	/* "port=file.pcap" */
	void (*run)(void);
};

static const struct scenario scenarios[] = {
	{ "cloud", { "mcp" }, { "3=mcp-cloud" }, run_cloud },
	{ "elevation", { "als" }, { "2=als-elevation" }, run_elevation },
	{ "exposure", { "als" }, { "2=als" }, run_exposure },
	{ "garbage", { "als" }, { "2=als-junk" }, run_garbage },
	{ "vanish", { "als" }, { "2=als" }, run_vanish },
	{ "list", { "als", "mcp", "keyboard" }, { "2=als", "3=mcp" }, run_list },
	{ "follower", { "mcp" }, { "3=mcp-cloud" }, run_follower },
};

int main(int argc, char **argv)
{
	const struct scenario *sc = NULL;

	for (size_t i = 0; argc > 1 && i < sizeof(scenarios) / sizeof(scenarios[0]); i++)
		if (!strcmp(argv[1], scenarios[i].name))
			sc = &scenarios[i];
	if (!sc) {
		fprintf(stderr, "usage: test_daemon_sensor cloud|elevation|exposure|garbage|vanish|list|"
				"follower\n");
		return 2;
	}
	if (!getenv("UMOCKDEV_DIR"))
		return umockdev_exec(SKYD_SENSOR_DATA, sc->devices, sc->captures, argv[0], sc->name,
				     "test_daemon_sensor");
	if (strcmp(sc->name, "list") != 0)
		harness_need_device();
	sc->run();
	if (d.pid > 0) {
		if (test_failures) {
			char cmd[256];
			snprintf(cmd, sizeof(cmd), "cat '%s' >&2", d.log);
			(void)!system(cmd);
		}
		daemon_cleanup(&d);
	}
	char name[64];
	snprintf(name, sizeof(name), "test_daemon_sensor %s", sc->name);
	return test_report(name);
}

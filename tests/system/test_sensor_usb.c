/* test_sensor_usb.c - the sensor manager on the daemon's real event loop
 * against mocked USB devices: umockdev's device descriptions and usbmon
 * captures from tests/sensor (written by tests/sensor/gen.py, which says
 * what each report means).
 *
 * One scenario per run, named by the first argument: each family found and
 * read with the right lux (hid, mcp), garbage reports (garbage), a flood of
 * reports (flood), a unit that is not lux (kelvin), a device that vanishes
 * mid-transfer (hid: the capture ends), the choice between devices and a
 * keyboard left alone (select), the list of --list-sensors (list). Started
 * outside umockdev, it runs itself under umockdev-run with the scenario's
 * files; exit 77 when umockdev-run is missing. Every wait is on a loop
 * event (a reading or a status change), bounded by a guard timer. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "loop.h"
#include "sensor.h"
#include "test.h"
#include "umockdev_exec.h"

#define REL(a, b, tol) (fabs((a) - (b)) <= (tol) * fabs(b))
#define GUARD_S 30

struct scenario;

struct run {
	const struct scenario *sc;
	struct loop *loop;
	struct sensor *s;
	struct sensor_config cfg;
	int phase;
	double lux[64];
	int n_lux;
	int stale_seen;
	double stale_lux;
	uint64_t t0_ns;
	int done;
};

struct scenario {
	const char *name;
	const char *devices[4];		/* *.umockdev in tests/sensor */
	const char *captures[4];	/* "port=file.pcap" */
	void (*configure)(struct sensor_config *cfg);
	/* Called on every reading and status change: 1 when finished. */
	int (*step)(struct run *r, const struct sensor_status *st);
};

/* The readings tests/sensor/gen.py puts in the captures. */
static const double als_readings[] = { 1234.56, 1300.0, 25000.0, 0.5, 101325.0 };

static double bh1750_lux(unsigned count)
{
	return count / 1.2 * 69.0 / 31.0;
}

static uint64_t rejected(const struct sensor_status *st)
{
	uint64_t n = 0;
	for (int i = 0; i < SENSOR_REJECT_N; i++)
		n += st->pipe.rejected[i];
	return n;
}

/* ---- scenarios ---- */

/* Read the five readings; then the capture ends with an input report
 * pending: three deadlines pass, the device is stopped, the value went
 * stale meanwhile, and the manager keeps trying. */
static int step_hid(struct run *r, const struct sensor_status *st)
{
	if (r->phase == 0 && r->n_lux == 5) {
		for (int i = 0; i < 5; i++)
			CHECK(REL(r->lux[i], als_readings[i], 1e-9));
		CHECK(st->state == SENSOR_STATE_READING);
		CHECK(!strcmp(st->device.bus_path, "1-2"));
		CHECK(!strcmp(st->device.family, "hid-sensor"));
		CHECK(!strcmp(st->device.serial, "ALS-0001"));
		CHECK(!strcmp(st->device.name, "skyd tests Test ambient light sensor"));
		CHECK(strstr(st->device.detail, "illuminance 32 bit in report 1") != NULL);
		CHECK(st->pipe.accepted == 5 && rejected(st) == 0);
		r->phase = 1;
	}
	if (r->phase == 1 && st->counters.failures >= 1) {
		printf("vanished: %s\n", st->why);
		CHECK(strstr(st->why, "stopped answering: 3 transfers in a row timed out") != NULL);
		CHECK(st->counters.timeouts >= 3);
		CHECK(r->stale_seen && r->stale_lux == r->lux[4]);
		CHECK(st->reading.stale && REL(st->reading.lux, 101325.0, 1e-9));
		r->phase = 2;
	}
	/* It lives on: it reopens the device, whose capture is over. */
	if (r->phase == 2 && st->counters.failures >= 2) {
		CHECK(st->counters.opens >= 2);
		CHECK(st->state == SENSOR_STATE_SEARCHING || st->state == SENSOR_STATE_STARTING);
		printf("and then: %s\n", st->why);
		return 1;
	}
	return 0;
}

static int step_garbage(struct run *r, const struct sensor_status *st)
{
	if (st->pipe.accepted < 2 || rejected(st) < 6)
		return 0;
	CHECK(st->pipe.accepted == 2);
	CHECK(st->pipe.rejected[SENSOR_REJECT_MALFORMED] == 5);
	CHECK(st->pipe.rejected[SENSOR_REJECT_NOT_READY] == 1);
	CHECK(rejected(st) == 6);
	CHECK(r->n_lux == 2 && REL(r->lux[0], 500.0, 1e-9) && REL(r->lux[1], 800.0, 1e-9));
	CHECK(st->state == SENSOR_STATE_READING);
	CHECK(st->why[0] != 0);
	printf("garbage: latest problem: %s\n", st->why);
	return 1;
}

static void configure_flood(struct sensor_config *cfg)
{
	cfg->pipe.time_constant_s = 2.0;
	cfg->pipe.hysteresis = 0.05;
	cfg->pipe.min_interval_s = 1.0;
	cfg->pipe.stale_after_s = 30.0;
}

static int step_flood(struct run *r, const struct sensor_status *st)
{
	if (st->counters.readings < 1000)
		return 0;
	double s = (double)(loop_now_ns() - r->t0_ns) * 1e-9;
	printf("flood: 1000 reports read in %.3f s (set-up included), %d outputs\n", s, r->n_lux);
	CHECK(st->counters.readings == 1000 && st->pipe.accepted == 1000);
	/* The rate limit: the first output, then at most one a second. */
	CHECK(r->n_lux >= 1 && r->n_lux <= 1 + (int)s);
	CHECK(st->pipe.emitted == (uint64_t)r->n_lux);
	CHECK(r->lux[r->n_lux - 1] >= 320.0 && r->lux[r->n_lux - 1] <= 480.0);
	CHECK(st->state == SENSOR_STATE_READING);
	return 1;
}

static int step_kelvin(struct run *r, const struct sensor_status *st)
{
	if (st->pipe.rejected[SENSOR_REJECT_UNIT] < 3)
		return 0;
	CHECK(st->pipe.accepted == 0 && r->n_lux == 0);
	CHECK(st->counters.io_errors == 1);	/* the stalled feature report */
	CHECK(strstr(st->device.detail, "unit not lux") != NULL);
	CHECK(strstr(st->why, "refused: unit") != NULL);
	CHECK(st->state == SENSOR_STATE_READING || st->state == SENSOR_STATE_STALE);
	return 1;
}

static int step_mcp(struct run *r, const struct sensor_status *st)
{
	if (st->pipe.accepted < 3 || rejected(st) < 3)
		return 0;
	CHECK(r->n_lux == 3);
	CHECK(REL(r->lux[0], bh1750_lux(1000), 1e-9));
	CHECK(REL(r->lux[1], bh1750_lux(20000), 1e-9));
	CHECK(REL(r->lux[2], bh1750_lux(54000), 1e-9));
	CHECK(st->pipe.rejected[SENSOR_REJECT_SATURATED] == 1);
	CHECK(st->pipe.rejected[SENSOR_REJECT_MALFORMED] == 2);	/* a wrong echo, a failed read */
	CHECK(!strcmp(st->device.family, "mcp2221-bh1750"));
	CHECK(!strcmp(st->device.bus_path, "1-3"));
	CHECK(strstr(st->device.detail, "BH1750 at 0x5c") != NULL);
	return 1;
}

static void configure_select(struct sensor_config *cfg)
{
	snprintf(cfg->select, sizeof(cfg->select), "serial:MCP-0001");
}

static int find_info(const struct sensor_info *infos, size_t n, const char *bus)
{
	for (size_t i = 0; i < n; i++)
		if (!strcmp(infos[i].bus_path, bus))
			return (int)i;
	return -1;
}

/* Three devices, the one with serial MCP-0001 chosen; the keyboard is
 * never opened (one open in all). Then the choice moves to bus 1-2; then,
 * from the reading callback, to none: the manager lets everything go. */
static int step_select(struct run *r, const struct sensor_status *st)
{
	struct sensor_info infos[8];

	if (r->phase == 0 && r->n_lux >= 1) {
		size_t n = sensor_devices(r->s, infos, 8);
		CHECK(n == 3);
		int kb = find_info(infos, n, "1-4"), als = find_info(infos, n, "1-2");
		CHECK(kb >= 0 && infos[kb].state == SENSOR_DEV_UNSUPPORTED);
		CHECK(kb >= 0 && strstr(infos[kb].detail, "no ambient light sensor") != NULL);
		CHECK(als >= 0 && infos[als].state == SENSOR_DEV_IDLE && !infos[als].selected);
		CHECK(!strcmp(st->device.serial, "MCP-0001"));
		CHECK(st->counters.opens == 1);
		CHECK(REL(r->lux[0], bh1750_lux(1000), 1e-9));
		struct sensor_config c = r->cfg;
		snprintf(c.select, sizeof(c.select), "bus:1-2");
		CHECK(sensor_set_config(r->s, &c) == 0);
		r->n_lux = 0;
		r->phase = 1;
		return 0;
	}
	if (r->phase == 1 && r->n_lux >= 1 && !strcmp(st->device.bus_path, "1-2")) {
		CHECK(REL(r->lux[0], als_readings[0], 1e-9));
		CHECK(st->counters.opens == 2);
		size_t n = sensor_devices(r->s, infos, 8);
		int mcp = find_info(infos, n, "1-3");
		CHECK(mcp >= 0 && infos[mcp].state == SENSOR_DEV_IDLE && !infos[mcp].selected);
		CHECK(mcp >= 0 && !strcmp(infos[mcp].detail, "not selected"));
		struct sensor_config c = r->cfg;
		snprintf(c.select, sizeof(c.select), "none");
		CHECK(sensor_set_config(r->s, &c) == 0);	/* applied once the callback is over */
		r->phase = 2;
		return 0;
	}
	if (r->phase == 2 && st->state == SENSOR_STATE_OFF) {
		CHECK(sensor_devices(r->s, infos, 8) == 0);
		CHECK(st->device.bus_path[0] == 0 && st->why[0] == 0);
		return 1;
	}
	return 0;
}

static const struct scenario scenarios[] = {
	{ "hid", { "als" }, { "2=als" }, NULL, step_hid },
	{ "garbage", { "als" }, { "2=als-garbage" }, NULL, step_garbage },
	{ "flood", { "als" }, { "2=als-flood" }, configure_flood, step_flood },
	{ "kelvin", { "kelvin" }, { "5=kelvin" }, NULL, step_kelvin },
	{ "mcp", { "mcp" }, { "3=mcp" }, NULL, step_mcp },
	{ "select", { "als", "mcp", "keyboard" }, { "2=als", "3=mcp" }, configure_select,
	  step_select },
	{ "list", { "als", "mcp", "keyboard", "kelvin" }, { "2=als", "3=mcp", "5=kelvin" }, NULL,
	  NULL },
};

/* ---- the loop ---- */

static void check_step(struct run *r)
{
	struct sensor_status st;

	if (r->done)
		return;
	sensor_get_status(r->s, &st);
	if (r->sc->step(r, &st)) {
		r->done = 1;
		loop_quit(r->loop);
	}
}

static void on_reading(void *ctx, const struct sensor_reading *rd)
{
	struct run *r = ctx;

	if (rd->stale) {
		r->stale_seen = 1;
		r->stale_lux = rd->lux;
	} else if (r->n_lux < 64) {
		r->lux[r->n_lux++] = rd->lux;
	}
	check_step(r);
}

static void on_status(void *ctx)
{
	check_step(ctx);
}

static void on_guard(void *ctx)
{
	struct run *r = ctx;
	struct sensor_status st;

	sensor_get_status(r->s, &st);
	FAIL("scenario %s: no end after %d s, in phase %d, state %s, why '%s', %d readings",
	     r->sc->name, GUARD_S, r->phase, sensor_state_name(st.state), st.why, r->n_lux);
	loop_quit(r->loop);
}

static void test_config(struct sensor_config *cfg)
{
	sensor_config_defaults(cfg);
	cfg->report_interval_s = 0.05;	/* gen.py's TEST_INTERVAL_MS */
	cfg->io_timeout_s = 0.2;
	cfg->rescan_s = 0.2;
	cfg->pipe.time_constant_s = 0.0;
	cfg->pipe.hysteresis = 0.0;
	cfg->pipe.min_interval_s = 0.0;
	cfg->pipe.stale_after_s = 0.5;
}

static void run_list(void)
{
	struct sensor_config cfg;
	struct sensor_info *infos;
	size_t n;
	char err[128], line[512];

	test_config(&cfg);
	CHECK(sensor_list(&cfg, 10.0, &infos, &n, err, sizeof(err)) == 0);
	for (size_t i = 0; i < n; i++) {
		sensor_info_format(&infos[i], line, sizeof(line));
		printf("list: %s\n", line);
	}
	CHECK(n == 4);
	int als = find_info(infos, n, "1-2"), mcp = find_info(infos, n, "1-3");
	int kb = find_info(infos, n, "1-4"), kel = find_info(infos, n, "1-5");
	CHECK(als >= 0 && infos[als].state == SENSOR_DEV_IDLE &&
	      strstr(infos[als].detail, "illuminance 32 bit") != NULL);
	CHECK(mcp >= 0 && infos[mcp].state == SENSOR_DEV_IDLE &&
	      strstr(infos[mcp].detail, "BH1750 at 0x5c") != NULL);
	CHECK(kb >= 0 && infos[kb].state == SENSOR_DEV_UNSUPPORTED);
	CHECK(kel >= 0 && strstr(infos[kel].detail, "unit not lux") != NULL);
	CHECK(als >= 0 && !strcmp(infos[als].family, "hid-sensor") && infos[als].selected);
	CHECK(als >= 0 && infos[als].vendor_id == 0x1209 && infos[als].product_id == 0x0001);
	free(infos);
}

static void run_scenario(const struct scenario *sc)
{
	struct run r;
	struct loop_timer *guard;

	memset(&r, 0, sizeof(r));
	r.sc = sc;
	test_config(&r.cfg);
	if (sc->configure)
		sc->configure(&r.cfg);
	CHECK(loop_new(&r.loop) == 0);
	CHECK(loop_timer_add(r.loop, on_guard, &r, &guard) == 0);
	CHECK(loop_timer_arm(guard, (uint64_t)GUARD_S * 1000000000ull) == 0);
	r.t0_ns = loop_now_ns();
	CHECK(sensor_new(r.loop, &r.cfg, on_reading, &r, &r.s) == 0);
	sensor_on_status(r.s, on_status, &r);
	check_step(&r);
	if (!r.done)
		loop_run(r.loop);
	CHECK(r.done);
	sensor_free(r.s);
	loop_timer_del(guard);
	loop_free(r.loop);
}

int main(int argc, char **argv)
{
	const struct scenario *sc = NULL;

	for (size_t i = 0; argc > 1 && i < sizeof(scenarios) / sizeof(scenarios[0]); i++)
		if (!strcmp(argv[1], scenarios[i].name))
			sc = &scenarios[i];
	if (!sc) {
		fprintf(stderr, "usage: test_sensor_usb hid|garbage|flood|kelvin|mcp|select|list\n");
		return 2;
	}
	if (!getenv("UMOCKDEV_DIR"))
		return umockdev_exec(SKYD_SENSOR_DATA, sc->devices, sc->captures, argv[0], sc->name,
				     "test_sensor_usb");
	if (sc->step)
		run_scenario(sc);
	else
		run_list();
	char name[64];
	snprintf(name, sizeof(name), "test_sensor_usb %s", sc->name);
	return test_report(name);
}

/* test_sensor_hotplug.c - a light sensor unplugged while a transfer is in
 * flight and plugged back in, under an umockdev testbed this program drives
 * itself (libumockdev): the manager reads it, lets it go when it leaves
 * (saying why), and reads it again at its new address when it comes back.
 * The devices and captures are tests/sensor's (gen.py). Started without
 * umockdev's preload library, it runs itself under umockdev-wrapper; exit 77
 * when that is missing. Every wait is on a loop event, bounded by a guard. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <umockdev.h>

#include "loop.h"
#include "sensor.h"
#include "test.h"
#include "umockdev_exec.h"

#define SYSFS_ALS UMOCKDEV_SYSFS "2"
#define REL(a, b, tol) (fabs((a) - (b)) <= (tol) * fabs(b))
#define GUARD_S 30

struct run {
	UMockdevTestbed *tb;
	struct loop *loop;
	struct sensor *s;
	int phase;
	double lux[16];
	int n_lux;
	int done;
};

static int plug(struct run *r, const char *device, const char *capture)
{
	char path[512];
	GError *err = NULL;

	snprintf(path, sizeof(path), "%s/%s", SKYD_SENSOR_DATA, device);
	if (!umockdev_testbed_add_from_file(r->tb, path, &err)) {
		FAIL("adding %s: %s", device, err ? err->message : "?");
		return -1;
	}
	snprintf(path, sizeof(path), "%s/%s", SKYD_SENSOR_DATA, capture);
	if (!umockdev_testbed_load_pcap(r->tb, SYSFS_ALS, path, &err)) {
		FAIL("loading %s: %s", capture, err ? err->message : "?");
		return -1;
	}
	return 0;
}

static void step(struct run *r)
{
	struct sensor_status st;
	struct sensor_info infos[4];

	sensor_get_status(r->s, &st);
	if (r->phase == 0 && r->n_lux == 5) {
		CHECK(REL(r->lux[0], 1234.56, 1e-9) && REL(r->lux[4], 101325.0, 1e-9));
		CHECK(st.state == SENSOR_STATE_READING && !strcmp(st.device.bus_path, "1-2"));
		/* Out, with the next input report pending. */
		umockdev_testbed_uevent(r->tb, SYSFS_ALS, "remove");
		umockdev_testbed_remove_device(r->tb, SYSFS_ALS);
		r->phase = 1;
		return;
	}
	if (r->phase == 1 && st.counters.departures == 1 && sensor_devices(r->s, infos, 4) == 0) {
		printf("unplugged: %s\n", st.why);
		CHECK(st.state == SENSOR_STATE_SEARCHING);
		CHECK(strstr(st.why, "1-2 left the bus") != NULL);
		CHECK(st.device.bus_path[0] == 0);
		CHECK(st.counters.failures == 0);	/* leaving is not failing */
		CHECK(plug(r, "als-replug.umockdev", "als-replug.pcap") == 0);
		r->n_lux = 0;
		r->phase = 2;
		return;
	}
	if (r->phase == 2 && r->n_lux == 2) {
		CHECK(REL(r->lux[0], 4321.0, 1e-9) && REL(r->lux[1], 4400.0, 1e-9));
		CHECK(st.counters.arrivals == 2 && st.counters.opens == 2);
		CHECK(st.state == SENSOR_STATE_READING && !strcmp(st.device.bus_path, "1-2"));
		r->done = 1;
		loop_quit(r->loop);
	}
}

static void on_reading(void *ctx, const struct sensor_reading *rd)
{
	struct run *r = ctx;

	if (!rd->stale && r->n_lux < 16)
		r->lux[r->n_lux++] = rd->lux;
	step(r);
}

static void on_status(void *ctx)
{
	step(ctx);
}

static void on_guard(void *ctx)
{
	struct run *r = ctx;
	struct sensor_status st;

	sensor_get_status(r->s, &st);
	FAIL("no end after %d s, in phase %d, state %s, why '%s'", GUARD_S, r->phase,
	     sensor_state_name(st.state), st.why);
	loop_quit(r->loop);
}

int main(int argc, char **argv)
{
	const char *preload = getenv("LD_PRELOAD");
	struct sensor_config cfg;
	struct loop_timer *guard;
	struct run r;

	if (!preload || !strstr(preload, "umockdev-preload")) {
		umockdev_allow_preload();
		execlp("umockdev-wrapper", "umockdev-wrapper", argv[0], (char *)NULL);
		printf("test_sensor_hotplug: umockdev-wrapper: %s: skipped\n", strerror(errno));
		return 77;
	}
	memset(&r, 0, sizeof(r));
	r.tb = umockdev_testbed_new();
	if (plug(&r, "als.umockdev", "als.pcap") < 0)
		return test_report("test_sensor_hotplug");

	sensor_config_defaults(&cfg);
	cfg.report_interval_s = 0.05;	/* gen.py's TEST_INTERVAL_MS */
	cfg.io_timeout_s = 0.2;
	cfg.rescan_s = 0.2;
	cfg.pipe.time_constant_s = 0.0;
	cfg.pipe.hysteresis = 0.0;
	cfg.pipe.min_interval_s = 0.0;
	cfg.pipe.stale_after_s = 5.0;	/* longer than the test: leaving is what stops it */
	CHECK(loop_new(&r.loop) == 0);
	CHECK(loop_timer_add(r.loop, on_guard, &r, &guard) == 0);
	CHECK(loop_timer_arm(guard, (uint64_t)GUARD_S * 1000000000ull) == 0);
	CHECK(sensor_new(r.loop, &cfg, on_reading, &r, &r.s) == 0);
	sensor_on_status(r.s, on_status, &r);
	step(&r);
	if (!r.done)
		loop_run(r.loop);
	CHECK(r.done);
	sensor_free(r.s);
	loop_timer_del(guard);
	loop_free(r.loop);
	g_object_unref(r.tb);
	return test_report("test_sensor_hotplug");
}

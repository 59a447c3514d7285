/* test_libsky_daemon.c - libsky against the real skyd on a private socket:
 * requests, the mapping, the futex wait, events, the CPU sampler agreeing
 * with the daemon's `sample` verbs, a layout change, and reconnecting after
 * skyd is killed with SIGKILL and started again. */
#include <math.h>
#include <poll.h>
#include <sys/mman.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sky_set.h"
#include "test.h"

static const char *const small[] = { HARNESS_SMALL, NULL };

/* Waits (futex) until the mapping holds a generation >= gen with all of
 * tables valid; 0 or -errno. */
static int wait_tables(sky_client *c, uint32_t gen, uint32_t tables, struct sky_view *ret)
{
	for (int i = 0; i < 1000; i++) {
		int r = sky_view_begin(c, ret);
		if (r < 0)
			return r;
		bool ok = ret->slot->generation >= gen && (ret->valid_tables & tables) == tables;
		if (sky_view_end(c, ret) && ok)
			return 0;
		r = sky_wait(c, ret->generation, 30000, NULL);
		if (r < 0)
			return r;
	}
	return -ETIMEDOUT;
}

static double reply_rgb(const sky_reply *rep, const char *key, int ch)
{
	const char *v = sky_reply_get(rep, key);
	double x[3] = { NAN, NAN, NAN };
	if (v)
		sscanf(v, "%lf,%lf,%lf", &x[0], &x[1], &x[2]);
	return x[ch];
}

static bool close_rel(double a, double b, double rel)
{
	return fabs(a - b) <= rel * fmax(fabs(a), fabs(b)) + 1e-300;
}


static void test_sampling_agrees(sky_client *c)
{
	uint32_t g = set_and_generation(c, "set sun_elevation_deg=12 sun_azimuth_deg=135");
	struct sky_view v;
	CHECK(wait_tables(c, g, SKY_TABLES_ALL, &v) == 0);
	/* a snapshot carries a checksum the daemon wrote */
	size_t n = sky_snapshot_size(c);
	void *buf = aligned_alloc(64, (n + 63) & ~(size_t)63);
	CHECK(sky_snapshot(c, buf, n, &v) == 0);
	CHECK(sky_view_verify(&v));
	CHECK(fabs(asin(v.slot->state.sun_direction[2]) * 180.0 / M_PI - 12.0) < 1e-9);
	static const double dirs[][2] = { { 10, 180 }, { 45, 135 }, { 0.5, 300 }, { 89, 0 }, { -10, 20 } };
	for (size_t i = 0; i < sizeof(dirs) / sizeof(dirs[0]); i++) {
		char line[128];
		sky_reply *rep = NULL;
		double mine[3];
		snprintf(line, sizeof(line), "sample sky el_deg=%g az_deg=%g", dirs[i][0], dirs[i][1]);
		CHECK(sky_request(c, line, &rep) == 0);
		CHECK(sky_sample_sky(&v, dirs[i][0], dirs[i][1], 0, mine) == 0);
		for (int k = 0; k < 3; k++)
			if (!close_rel(mine[k], reply_rgb(rep, "radiance_rgb_cd_m2", k), 1e-8))
				FAIL("sample sky %s: libsky %.9g, skyd %.9g", line, mine[k],
				     reply_rgb(rep, "radiance_rgb_cd_m2", k));
		sky_reply_free(rep);
	}
	sky_reply *rep = NULL;
	double mine[3];
	CHECK(sky_request(c, "sample sun", &rep) == 0);
	CHECK(sky_sample_sun(&v, mine) == 0);
	for (int k = 0; k < 3; k++)
		CHECK(close_rel(mine[k], reply_rgb(rep, "illuminance_rgb_lx", k), 1e-8));
	printf("sample sun: libsky %.6g %.6g %.6g lx\n", mine[0], mine[1], mine[2]);
	sky_reply_free(rep);
	rep = NULL;
	CHECK(sky_request(c, "sample ambient", &rep) == 0);
	CHECK(sky_sample_ambient(&v, mine) == 0);
	for (int k = 0; k < 3; k++)
		CHECK(close_rel(mine[k], reply_rgb(rep, "illuminance_rgb_lx", k), 1e-8));
	printf("sample ambient: libsky %.6g %.6g %.6g lx\n", mine[0], mine[1], mine[2]);
	sky_reply_free(rep);
	/* transmittance and aerial perspective are physical on the real tables */
	double t[3], tr;
	CHECK(sky_sample_transmittance(&v, 0.0, 1.0, t) == 0);
	CHECK(t[0] > 0.5 && t[0] <= 1.0 && t[2] < t[0]);
	CHECK(sky_sample_aerial(&v, 0.5, 0.5, 10.0, mine, &tr) == 0);
	CHECK(tr > 0.0 && tr < 1.0 && mine[2] > 0.0);
	/* the sun's disk makes the direction of the sun far brighter */
	double sky_only[3], with_disk[3];
	CHECK(sky_sample_sky(&v, 12.0, 135.0, 0, sky_only) == 0);
	CHECK(sky_sample_sky(&v, 12.0, 135.0, SKY_SAMPLE_SUN_DISK, with_disk) == 0);
	CHECK(with_disk[1] > 100.0 * sky_only[1]);
	free(buf);
}

/* Loop integration: sky_send and sky_dispatch, with "changed" events. */
static void test_event_loop(sky_client *c)
{
	CHECK(sky_send(c, "set sun_elevation_deg=25", 42) == 0);
	uint32_t reply_gen = 0, seen_gen = 0;
	for (int spins = 0; spins < 1000 && !(reply_gen && seen_gen >= reply_gen); spins++) {
		struct sky_event ev;
		int r = sky_dispatch(c, &ev);
		CHECK(r >= 0);
		if (r < 0)
			break;
		if (r == 0) {
			struct pollfd p = { sky_get_fd(c), POLLIN | (sky_want_write(c) ? POLLOUT : 0), 0 };
			CHECK(poll(&p, 1, 30000) == 1);
			continue;
		}
		if (ev.type == SKY_EVENT_REPLY) {
			CHECK(ev.userdata == 42 && ev.ack == 0);
			reply_gen = (uint32_t)strtoul(sky_reply_get(ev.reply, "generation"), NULL, 10);
		} else if (ev.type == SKY_EVENT_CHANGED) {
			seen_gen = ev.generation;
		}
	}
	CHECK(reply_gen > 0 && seen_gen >= reply_gen);
}

/* New table sizes: the daemon supersedes the region; sky_wait follows it. */
static void test_layout_change(sky_client *c)
{
	const struct sky_shm_header *old = sky_header(c);
	uint32_t g0 = __atomic_load_n(&old->generation, __ATOMIC_ACQUIRE);
	uint32_t g = set_and_generation(c, "set skyview_width=48");
	uint32_t now = g0;
	int r = 0;
	for (int i = 0; i < 100 && r == 0; i++) {
		r = sky_wait(c, now, 30000, &now);
		const struct sky_shm_header *h = sky_header(c);
		if (h != old && h->tables[SKY_TABLE_SKYVIEW].width == 48 && now >= g)
			break;
	}
	CHECK(r == 0);
	const struct sky_shm_header *h = sky_header(c);
	CHECK(h != old && h->tables[SKY_TABLE_SKYVIEW].width == 48);
	struct sky_view v;
	CHECK(wait_tables(c, g, SKY_TABLES_ALL, &v) == 0);
	double rgb[3];
	CHECK(sky_sample_sky(&v, 30.0, 0.0, 0, rgb) == 0 && rgb[2] > 0.0);
	/* the SKY_EVENT_LAYOUT event was queued for the loop */
	struct sky_event ev;
	int layouts = 0;
	while (sky_dispatch(c, &ev) == 1)
		layouts += ev.type == SKY_EVENT_LAYOUT;
	CHECK(layouts == 1);
}

static void test_reconnect(struct daemon *d, sky_client *c)
{
	struct sky_view v;
	uint32_t g = set_and_generation(c, "set sun_elevation_deg=33");
	CHECK(wait_tables(c, g, SKY_TABLES_ALL, &v) == 0);
	daemon_stop(d, SIGKILL);
	/* the hang-up shows on the socket; the mapping stays readable */
	struct sky_event ev = { 0 };
	for (int i = 0; i < 100; i++) {
		int r = sky_dispatch(c, &ev);
		if (r == 1 && ev.type == SKY_EVENT_HANGUP)
			break;
		if (r < 0)
			break;
		struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
		if (r == 0 && poll(&p, 1, 30000) != 1)
			break;
	}
	CHECK(ev.type == SKY_EVENT_HANGUP);
	CHECK(sky_view_begin(c, &v) == 0 && sky_view_end(c, &v));
	CHECK(sky_request(c, "ping", NULL) < 0);	/* nobody there */
	CHECK(daemon_start_in(d, d->dir, small) == 0);
	/* the next request reconnects and subscribes again by itself */
	int r = sky_request(c, "ping", NULL);
	if (r != 0)
		FAIL("ping after restart: %d %s", r, sky_strerror(r));
	g = set_and_generation(c, "set sun_elevation_deg=8");
	CHECK(wait_tables(c, g, SKY_TABLES_ALL, &v) == 0);
	CHECK(fabs(asin(v.slot->state.sun_direction[2]) * 180.0 / M_PI - 8.0) < 1e-9);
	CHECK(sky_view_end(c, &v));
}

int main(void)
{
	struct daemon d = { 0 };
	harness_need_device();
	if (daemon_start(&d, small) < 0) {
		FAIL("skyd did not start");
		return test_report("test_libsky_daemon");
	}
	sky_client *c = NULL;
	CHECK(sky_connect(d.sock, &c) == 0);
	if (c) {
		sky_set_timeout(c, 30000);
		CHECK(strcmp(sky_protocol_version(c), SKY_PROTO_VERSION) == 0);
		CHECK(sky_request(c, "ping", NULL) == 0);
		CHECK(sky_request(c, "set sun_elevation_deg=91", NULL) == SKY_ACK_RANGE);
		CHECK(sky_request(c, "set no_such_key=1", NULL) == SKY_ACK_NO_EXIST);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS) == 0);
		CHECK(sky_header(c) != NULL);
		/* the mapping is read-only for good */
		CHECK(mprotect((void *)sky_header(c), 4096, PROT_READ | PROT_WRITE) < 0);
		test_sampling_agrees(c);
		test_event_loop(c);
		test_layout_change(c);
		test_reconnect(&d, c);
		sky_disconnect(c);
	}
	daemon_cleanup(&d);
	return test_report("test_libsky_daemon");
}

/* test_restart_reconnect.c - without systemd (no fd store) a libsky client
 * survives a restart of skyd: reconnecting by itself (sky_set_reconnect)
 * it comes back, maps the new region and says so exactly once
 * (SKY_EVENT_RECONNECTED, userdata 1; no SKY_EVENT_HANGUP); a client that
 * only sleeps in sky_wait() comes back too; a client that did not ask
 * still gets its hang-up. */
#include <math.h>
#include <time.h>

#include "daemon_harness.h"
#include "sky.h"
#include "test.h"

static const char *const small[] = { HARNESS_SMALL, NULL };

struct events {
	int reconnected, hangups, layouts, changed;
	uint64_t userdata;
};

/* Dispatches for up to ms (polling the socket, or every 10 ms while there
 * is none), counting events; stops early at a reconnection when until is
 * set. */
static void pump(sky_client *c, struct events *ev, int ms, bool until)
{
	int64_t end = harness_now_ms() + ms;
	int before = ev->reconnected;

	while (harness_now_ms() < end && !(until && ev->reconnected > before)) {
		struct sky_event e;
		int fd = sky_get_fd(c);
		struct pollfd p = { fd, POLLIN, 0 };
		poll(fd >= 0 ? &p : NULL, fd >= 0 ? 1 : 0, 10);
		while (sky_dispatch(c, &e) == 1) {
			ev->reconnected += e.type == SKY_EVENT_RECONNECTED;
			ev->hangups += e.type == SKY_EVENT_HANGUP;
			ev->layouts += e.type == SKY_EVENT_LAYOUT;
			ev->changed += e.type == SKY_EVENT_CHANGED;
			if (e.type == SKY_EVENT_RECONNECTED)
				ev->userdata = e.userdata;
		}
	}
}

/* The newest slot has every table, read through a verified copy. */
static bool all_tables(sky_client *c)
{
	size_t n = sky_snapshot_size(c);
	void *buf = n ? aligned_alloc(64, (n + 63) / 64 * 64) : NULL;
	struct sky_view v;
	double rgb[3] = { 0 };
	bool ok = buf && sky_snapshot(c, buf, n, &v) == 0 && sky_view_verify(&v) &&
		  v.valid_tables == SKY_TABLES_ALL &&
		  sky_sample_sky(&v, 20.0, 90.0, 0, rgb) == 0 && rgb[0] > 0 && isfinite(rgb[2]);
	free(buf);
	return ok;
}

/* Waits in sky_wait() (and in nothing else) until every table is there. */
static bool wait_all_tables(sky_client *c)
{
	int64_t end = harness_now_ms() + HARNESS_TIMEOUT_MS;
	uint32_t seen = 0;

	while (harness_now_ms() < end) {
		if (sky_header(c) && all_tables(c))
			return true;
		int r = sky_wait(c, seen, 200, &seen);
		if (r < 0 && r != -ETIMEDOUT)
			return false;
	}
	return false;
}

int main(void)
{
	struct daemon d;
	struct events ev = { 0 }, plain_ev = { 0 };
	sky_client *c = NULL, *w = NULL, *plain = NULL;

	harness_need_device();
	/* No fd store: skyd hands nothing over, as outside systemd. */
	unsetenv("FDSTORE");
	if (daemon_start(&d, small) < 0) {
		FAIL("skyd did not start");
		return test_report("test_restart_reconnect");
	}
	CHECK(sky_connect(d.sock, &c) == 0 && sky_connect(d.sock, &w) == 0 &&
	      sky_connect(d.sock, &plain) == 0);
	if (!c || !w || !plain)
		return test_report("test_restart_reconnect");
	CHECK(sky_set_reconnect(c, 10) == 0 && sky_set_reconnect(w, 10) == 0);
	CHECK(sky_set_reconnect(c, -1) == -EINVAL);
	CHECK(sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS) == 0);
	CHECK(sky_subscribe(w, SKY_TABLES_ALL, 0) == 0);
	CHECK(sky_subscribe(plain, SKY_TABLES_ALL, 0) == 0);
	CHECK(wait_all_tables(c) && wait_all_tables(w));
	const struct sky_shm_header *old_c = sky_header(c), *old_w = sky_header(w);
	pump(c, &ev, 50, false);

	/* Restarted by hand: a new region; the old one stays readable. */
	daemon_stop(&d, SIGTERM);
	CHECK(all_tables(c));
	pump(c, &ev, 100, false);
	CHECK(ev.reconnected == 0 && ev.hangups == 0);
	CHECK(sky_get_fd(c) == -ENOTCONN);
	CHECK(daemon_start_in(&d, d.dir, small) == 0);

	int64_t end;
	pump(c, &ev, HARNESS_TIMEOUT_MS, true);
	CHECK(ev.reconnected == 1 && ev.userdata == 1);
	CHECK(ev.hangups == 0 && ev.layouts == 0);
	CHECK(sky_get_fd(c) >= 0);
	CHECK(sky_header(c) != NULL && sky_header(c) != old_c);
	/* The client that only waits comes back inside sky_wait(): a new
	 * region, which no futex wake announces. */
	uint32_t seen = __atomic_load_n(&old_w->generation, __ATOMIC_ACQUIRE);
	end = harness_now_ms() + HARNESS_TIMEOUT_MS;
	while (sky_header(w) == old_w && harness_now_ms() < end)
		(void)sky_wait(w, seen, 200, &seen);
	CHECK(sky_header(w) != old_w);
	CHECK(wait_all_tables(w));
	CHECK(wait_all_tables(c));
	/* Exactly once: a change later, events flow again, nothing more. */
	sky_reply *rep = NULL;
	CHECK(sky_request(c, "set sun_elevation_deg=33", &rep) == 0);
	sky_reply_free(rep);
	int changed = ev.changed;
	end = harness_now_ms() + HARNESS_TIMEOUT_MS;
	while (ev.changed == changed && harness_now_ms() < end)
		pump(c, &ev, 50, false);
	CHECK(ev.changed > changed);
	CHECK(ev.reconnected == 1 && ev.hangups == 0 && ev.layouts == 0);

	/* A client that did not ask hears the hang-up and stays down. */
	pump(plain, &plain_ev, 100, false);
	CHECK(plain_ev.hangups == 1 && plain_ev.reconnected == 0);
	struct sky_event e;
	CHECK(sky_dispatch(plain, &e) == -ENOTCONN);

	sky_disconnect(c);
	sky_disconnect(w);
	sky_disconnect(plain);
	daemon_cleanup(&d);
	return test_report("test_restart_reconnect");
}

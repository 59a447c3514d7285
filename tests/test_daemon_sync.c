/* test_daemon_sync.c - three real skyd, one controller and two followers,
 * through a real mosquitto on a free loopback port (docs/sync.md): they
 * show the same sky, switch together at the apply time as their libsky
 * clients see it, survive the broker's restart, a restarted follower
 * catches up from the retained message, and garbage on the topic changes
 * nothing. Exits 77 without mosquitto or a Vulkan device.
 *
 * Usage: test_daemon_sync switch|restart|garbage */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sync_harness.h"

#define N_SKYD SYNC_N_SKYD
/* The apply-time switch lands within this across the clients. */
#define SPREAD_MAX_NS 2000000ll

static int failures;
#define CHECK(cond)                                                                       \
	do {                                                                              \
		if (!(cond)) {                                                            \
			fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
			failures++;                                                       \
		}                                                                         \
	} while (0)

static struct sync_rig rig;
#define client rig.client

static int64_t realtime_ns(void)
{
	return sync_realtime_ns();
}

static void setup_broker(void)
{
	if (!sync_have_mosquitto()) {
		printf("skipped: no %s or %s\n", SYNC_MOSQUITTO_BIN, SYNC_MOSQUITTO_PUB);
		exit(77);
	}
	harness_need_device();
	if (sync_broker_setup(&rig) < 0) {
		fprintf(stderr, "mosquitto did not start\n");
		exit(1);
	}
}

static int start_skyd(int i)
{
	return sync_skyd_start(&rig, i);
}

static void stop_skyd(int i)
{
	sync_skyd_stop(&rig, i);
}

/* One request to skyd i; its reply in buf; the ACK code or -1. */
static int request(int i, const char *line, char *buf, size_t size)
{
	return sync_request(&rig, i, line, buf, size);
}

static uint64_t status_u64(int i, const char *key)
{
	char buf[8192];

	if (request(i, "status", buf, sizeof(buf)) != 0)
		return UINT64_MAX;
	return reply_u64(buf, key);
}

static int status_is(int i, const char *key, const char *want)
{
	return sync_status_is(&rig, i, key, want);
}

/* The z of the sun direction in client i's slot as libsky hands it out;
 * NAN none. */
static double sun_z(int i)
{
	return sync_sun_z(&rig, i, NULL);
}

/* Waits on client i's futex (a publication) until pred holds or about
 * 20 s of publications or timeouts passed; each wait is an event wait
 * with a bound. */
static int wait_until(int i, int (*pred)(int), int arg_index)
{
	for (int k = 0; k < 400; k++) {
		if (pred(arg_index))
			return 0;
		const struct sky_shm_header *h = sky_header(client[i]);
		uint32_t seen = h ? atomic_load((_Atomic uint32_t *)&h->generation) : 0;
		uint32_t gen;
		sky_wait(client[i], seen, 50, &gen);
	}
	return -1;
}

/* ---- the switch: every client sees the new slot at the same instant ---- */

struct watcher {
	int index;
	double target_z;
	int64_t seen_ns;
	pthread_t thread;
};

static void *watch(void *arg)
{
	struct watcher *w = arg;

	for (int k = 0; k < 2000; k++) {
		if (fabs(sun_z(w->index) - w->target_z) < 1e-9) {
			w->seen_ns = realtime_ns();
			return NULL;
		}
		const struct sky_shm_header *h = sky_header(client[w->index]);
		uint32_t seen = atomic_load((_Atomic uint32_t *)&h->generation), gen;
		if (fabs(sun_z(w->index) - w->target_z) < 1e-9)
			continue;
		sky_wait(client[w->index], seen, 100, &gen);
	}
	return NULL;
}

/* Sets the sun's elevation on the controller with watchers on every
 * client; returns the spread of the instants they saw it, in ns. */
static int64_t switch_to(double elevation_deg, int64_t *ret_late_ns)
{
	struct watcher w[N_SKYD];
	char line[96], buf[1024];
	int64_t t_set, lo = INT64_MAX, hi = INT64_MIN;

	for (int i = 0; i < N_SKYD; i++) {
		w[i] = (struct watcher){ .index = i, .target_z = sin(elevation_deg * M_PI / 180.0) };
		pthread_create(&w[i].thread, NULL, watch, &w[i]);
	}
	snprintf(line, sizeof(line), "set sun_elevation_deg=%g", elevation_deg);
	t_set = realtime_ns();
	CHECK(request(0, line, buf, sizeof(buf)) == 0);
	for (int i = 0; i < N_SKYD; i++) {
		pthread_join(w[i].thread, NULL);
		CHECK(w[i].seen_ns > 0);
		if (w[i].seen_ns < lo)
			lo = w[i].seen_ns;
		if (w[i].seen_ns > hi)
			hi = w[i].seen_ns;
	}
	*ret_late_ns = lo - t_set;
	return hi - lo;
}

/* Every client's current slot has the same checksum (state and tables). */
static void check_same_sky(void)
{
	uint64_t sum[N_SKYD];

	for (int i = 0; i < N_SKYD; i++) {
		struct sky_view v;
		sum[i] = 0;
		for (int k = 0; k < 100 && !sum[i]; k++)
			if (sky_view_begin(client[i], &v) == 0) {
				uint64_t s = v.slot->checksum;
				if (sky_view_end(client[i], &v))
					sum[i] = s;
			}
	}
	for (int i = 1; i < N_SKYD; i++) {
		if (sum[i] != sum[0])
			fprintf(stderr, "skyd %d's slot checksum %016llx, the controller's %016llx\n",
				i, (unsigned long long)sum[i], (unsigned long long)sum[0]);
		CHECK(sum[i] == sum[0]);
	}
}

static void check_same_generation(void)
{
	uint64_t g0 = status_u64(0, "sync_generation");

	for (int i = 1; i < N_SKYD; i++)
		CHECK(status_u64(i, "sync_generation") == g0);
}

static int has_z(int i)
{
	return fabs(sun_z(i) - sin(20.0 * M_PI / 180.0)) < 1e-9;
}

static void scenario_switch(void)
{
	int64_t late, spread[5], worst = 0;
	char buf[1024];

	for (int n = 0; n < 5; n++) {
		spread[n] = switch_to(n % 2 ? 25.0 : 35.0, &late);
		printf("switch %d: spread %.3f ms across %d clients, %.1f ms after the set\n", n,
		       (double)spread[n] / 1e6, N_SKYD, (double)late / 1e6);
		if (spread[n] > worst)
			worst = spread[n];
	}
	/* The median: a machine shared with other work can delay one wake-up
	 * (three daemons and three watchers on two cores); the worst is
	 * reported. */
	for (int a = 0; a < 5; a++)
		for (int b = a + 1; b < 5; b++)
			if (spread[b] < spread[a]) {
				int64_t t = spread[a];
				spread[a] = spread[b];
				spread[b] = t;
			}
	printf("median spread %.3f ms, worst %.3f ms\n", (double)spread[2] / 1e6,
	       (double)worst / 1e6);
	CHECK(spread[2] <= SPREAD_MAX_NS);
	check_same_sky();
	check_same_generation();
	/* A follower refuses a change, naming the controller. */
	CHECK(request(1, "set sun_elevation_deg=20", buf, sizeof(buf)) == SKY_ACK_PERMISSION);
	CHECK(strstr(buf, "controller") != NULL);
	CHECK(status_is(1, "sync_role", "follower"));
}

/* ---- the broker's restart, a follower's restart ---- */

static int connected(int i)
{
	return status_is(i, "sync", "connected");
}

static int lost(int i)
{
	return !status_is(i, "sync", "connected");
}

static void scenario_restart(void)
{
	char buf[1024];
	int64_t late;

	sync_broker_kill(&rig);
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, lost, i) == 0);
	CHECK(sync_broker_start(&rig) == 0);
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, connected, i) == 0);
	printf("spread after the restart %.3f ms\n", (double)switch_to(30.0, &late) / 1e6);
	check_same_sky();
	/* A follower killed while the sky changes catches up when it comes
	 * back, from the retained message alone. */
	stop_skyd(2);
	CHECK(request(0, "set sun_elevation_deg=20", buf, sizeof(buf)) == 0);
	CHECK(wait_until(1, has_z, 1) == 0);
	CHECK(start_skyd(2) == 0);
	CHECK(wait_until(2, has_z, 2) == 0);
	check_same_sky();
	check_same_generation();
}

/* ---- hostile input ---- */

static void scenario_garbage(void)
{
	char topic[64];
	uint64_t g1 = status_u64(1, "sync_generation");
	double z1 = sun_z(1);

	snprintf(topic, sizeof(topic), "sky/state");
	char portstr[16];
	snprintf(portstr, sizeof(portstr), "%d", rig.port);
	pid_t p = fork();
	if (p == 0) {
		execl(SYNC_MOSQUITTO_PUB, "mosquitto_pub", "-h", "127.0.0.1", "-p", portstr, "-t", topic,
		      "-q", "1", "-m", "skysync=1\ncontroller=x/1/2\ngarbage\n", (char *)NULL);
		_exit(127);
	}
	int st;
	waitpid(p, &st, 0);
	CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0);
	/* The drop is counted: wait for the counter, then nothing moved. */
	for (int k = 0; k < 400 && status_u64(1, "sync_generation") == g1; k++) {
		char buf[8192], v[256];
		if (request(1, "status", buf, sizeof(buf)) == 0 &&
		    reply_value(buf, "sync_counters", v, sizeof(v)) && !strstr(v, "dropped=0"))
			break;
		uint32_t gen;
		sky_wait(client[1], atomic_load((_Atomic uint32_t *)&sky_header(client[1])->generation),
			 50, &gen);
	}
	char buf[8192], v[256];
	CHECK(request(1, "status", buf, sizeof(buf)) == 0);
	CHECK(reply_value(buf, "sync_counters", v, sizeof(v)) && !strstr(v, "dropped=0"));
	CHECK(status_u64(1, "sync_generation") == g1);
	CHECK(sun_z(1) == z1);
	/* And they still follow. */
	int64_t late;
	printf("spread after the garbage %.3f ms\n", (double)switch_to(15.0, &late) / 1e6);
	check_same_sky();
}

int main(int argc, char **argv)
{
	const char *scenario = argc > 1 ? argv[1] : "switch";

	setup_broker();
	for (int i = 0; i < N_SKYD; i++)
		if (start_skyd(i) < 0) {
			sync_rig_finish(&rig);
			return 1;
		}
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, connected, i) == 0);
	if (strcmp(scenario, "switch") == 0)
		scenario_switch();
	else if (strcmp(scenario, "restart") == 0)
		scenario_restart();
	else if (strcmp(scenario, "garbage") == 0)
		scenario_garbage();
	else
		fprintf(stderr, "unknown scenario %s\n", scenario), failures++;
	sync_rig_finish(&rig);
	printf("%s: %s\n", scenario, failures ? "FAILED" : "ok");
	return failures ? 1 : 0;
}

/* test_daemon_sync.c - three real skyd, one controller and two followers,
 * through a real mosquitto on a free loopback port (docs/sync.md): they
 * show the same sky, switch together at the apply time as their libsky
 * clients see it, survive the broker's restart, a restarted follower
 * catches up from the retained message, garbage on the topic changes
 * nothing, a follower whose terrain file differs from the controller's
 * keeps its sky and says why, and after a METAR and a wind step the three
 * hold the same cloud and shadow tables bit for bit (keys travel, never
 * textures). Exits 77 without mosquitto or a Vulkan device.
 *
 * Usage: test_daemon_sync switch|restart|garbage|terrain|clouds */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "daemon_harness.h"
#include "sky.h"
#include "skysample.h"
#include "sync_harness.h"

#define N_SKYD SYNC_N_SKYD
/* The apply-time switch lands within this across the clients. Under the
 * sanitizers, the three instrumented daemons' timers (their own switch,
 * no copy: the slot was written ahead) and the clients' wake-ups fall on
 * the same instant on two cores, and the order the scheduler picks is the
 * spread: medians of 0.5 to 2.1 ms were seen, so the bound there is the
 * order of magnitude, and the 2 ms is the plain build's. */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SPREAD_MAX_NS 8000000ll
#else
#define SPREAD_MAX_NS 2000000ll
#endif

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

/* The new sky reaches the followers ahead of its apply time and goes into
 * their spare slot at once; libsky hands it out from the apply time on,
 * whether or not skyd's own timer has made it the current slot yet. */
struct watcher {
	int index;
	double target_z;
	int64_t seen_ns;		/* CLOCK_REALTIME when the client first saw it */
	int64_t apply_ns;		/* the slot's apply time */
	int on_spare;			/* seen in the spare slot: libsky's switch */
	pthread_t thread;
};

/* Client i's sun z in the slot libsky hands out, with that slot's index
 * and apply time; 0 or -1 when no consistent view came. */
static int look(int i, double *ret_z, uint32_t *ret_slot, int64_t *ret_apply_ns,
		uint32_t *ret_generation)
{
	struct sky_view v;

	for (int k = 0; k < 100; k++) {
		if (sky_view_begin(client[i], &v) < 0)
			continue;
		double z = v.slot->state.sun_direction[2];
		int64_t at = v.slot->apply_time_ns;
		if (!sky_view_end(client[i], &v))
			continue;
		*ret_z = z;
		*ret_slot = v.slot_index;
		*ret_apply_ns = at;
		*ret_generation = v.generation;
		return 0;
	}
	return -1;
}

static void *watch(void *arg)
{
	struct watcher *w = arg;

	for (int k = 0; k < 2000; k++) {
		double z;
		uint32_t slot, gen, next;
		int64_t at;
		if (look(w->index, &z, &slot, &at, &gen) < 0)
			continue;
		if (fabs(z - w->target_z) < 1e-9) {
			w->seen_ns = realtime_ns();
			w->apply_ns = at;
			w->on_spare = slot == sky_header(client[w->index])->n_slots - 1;
			return NULL;
		}
		/* Bounded by the apply time of a slot published ahead. */
		sky_wait(client[w->index], gen, 100, &next);
	}
	return NULL;
}

/* A reader of the controller's region (early, its own client) between the
 * set and the apply time: once the new sky sits in the spare slot, libsky
 * still hands out the old one. Returns 1 when it looked before the apply
 * time, 0 when the machine was too slow to, -1 when the slot never came. */
static int check_before_apply(sky_client *early, double old_z, double target_z)
{
	const struct sky_shm_header *h = sky_header(early);
	const struct sky_shm_slot *spare =
		(const void *)((const uint8_t *)h + h->header_bytes +
			       (uint64_t)(h->n_slots - 1) * h->slot_bytes);

	for (int k = 0; k < 400; k++) {
		uint32_t seq = atomic_load((_Atomic uint32_t *)&spare->seq), gen;
		double z = spare->state.sun_direction[2];
		int64_t at = spare->apply_time_ns;
		atomic_thread_fence(memory_order_acquire);
		if (!(seq & 1u) && atomic_load((_Atomic uint32_t *)&spare->seq) == seq &&
		    fabs(z - target_z) < 1e-9) {
			struct sky_view v;
			double seen = NAN;
			if (sky_view_begin(early, &v) == 0) {
				seen = v.slot->state.sun_direction[2];
				if (!sky_view_end(early, &v))
					seen = NAN;
			}
			if (realtime_ns() >= at)
				return 0;
			CHECK(fabs(seen - old_z) < 1e-9);
			return 1;
		}
		sky_wait(early, atomic_load((_Atomic uint32_t *)&h->generation), 5, &gen);
	}
	return -1;
}

struct switch_result {
	int64_t spread_ns;		/* last client's instant - first's */
	int64_t late_ns;		/* first client's instant - the set */
	int64_t after_apply_ns;		/* the latest client's instant - the apply time */
	int on_spare;			/* clients that switched on the spare slot */
	int before_apply;		/* check_before_apply's */
};

/* Sets the sun's elevation on the controller with watchers on every
 * client (and early, when not NULL, reading before the apply time). */
static void switch_to(double elevation_deg, sky_client *early, struct switch_result *ret)
{
	struct watcher w[N_SKYD];
	char line[96], buf[1024];
	int64_t t_set, lo = INT64_MAX, hi = INT64_MIN;
	double old_z = sun_z(0), target_z = sin(elevation_deg * M_PI / 180.0);

	*ret = (struct switch_result){ 0 };
	for (int i = 0; i < N_SKYD; i++) {
		w[i] = (struct watcher){ .index = i, .target_z = target_z };
		pthread_create(&w[i].thread, NULL, watch, &w[i]);
	}
	snprintf(line, sizeof(line), "set sun_elevation_deg=%g", elevation_deg);
	t_set = realtime_ns();
	CHECK(request(0, line, buf, sizeof(buf)) == 0);
	if (early)
		ret->before_apply = check_before_apply(early, old_z, target_z);
	for (int i = 0; i < N_SKYD; i++) {
		pthread_join(w[i].thread, NULL);
		CHECK(w[i].seen_ns > 0);
		/* Never before the apply time. */
		/* A change is never seen before its apply time. */
		CHECK(fabs(old_z - target_z) < 1e-9 ||
		      (w[i].apply_ns > 0 && w[i].seen_ns >= w[i].apply_ns));
		if (w[i].seen_ns < lo)
			lo = w[i].seen_ns;
		if (w[i].seen_ns > hi)
			hi = w[i].seen_ns;
		ret->on_spare += w[i].on_spare;
		if (w[i].seen_ns - w[i].apply_ns > ret->after_apply_ns)
			ret->after_apply_ns = w[i].seen_ns - w[i].apply_ns;
	}
	ret->late_ns = lo - t_set;
	ret->spread_ns = hi - lo;
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

/* Every table in the client's current slot. */
static int has_tables(int i)
{
	struct sky_view v;

	for (int k = 0; k < 100; k++) {
		if (sky_view_begin(client[i], &v) < 0)
			continue;
		uint32_t valid = v.valid_tables;
		if (sky_view_end(client[i], &v))
			return valid == 0xf;
	}
	return 0;
}

/* The sun of has_z with every table: a restarted skyd publishes the
 * retained state first with the tables nobody had asked for yet, then
 * again once its client's subscription brings them into demand. */
static int has_sky(int i)
{
	return has_tables(i) && has_z(i);
}

static void scenario_switch(void)
{
	int64_t spread[5], worst = 0;
	int looked = 0;
	char buf[1024];
	sky_client *early;

	CHECK(sky_connect(rig.skyd[0]->sock, &early) == 0 && sky_subscribe(early, 0xf, 0) == 0);
	/* From a settled sky: the first tables make their pipelines first,
	 * seconds under a sanitizer, which check_before_apply does not wait. */
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, has_tables, i) == 0);
	for (int n = 0; n < 5; n++) {
		struct switch_result r;
		switch_to(n % 2 ? 25.0 : 35.0, early, &r);
		spread[n] = r.spread_ns;
		printf("switch %d: spread %.3f ms across %d clients, %.1f ms after the set, "
		       "last %.3f ms after the apply time, %d on the spare slot\n",
		       n, (double)r.spread_ns / 1e6, N_SKYD, (double)r.late_ns / 1e6,
		       (double)r.after_apply_ns / 1e6, r.on_spare);
		CHECK(r.before_apply >= 0);
		looked += r.before_apply == 1;
		if (spread[n] > worst)
			worst = spread[n];
	}
	sky_disconnect(early);
	/* The new sky was in the spare slot before the apply time, and a
	 * reader then still got the old one, at least once. */
	CHECK(looked > 0);
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
	struct switch_result sw;

	sync_broker_kill(&rig);
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, lost, i) == 0);
	CHECK(sync_broker_start(&rig) == 0);
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, connected, i) == 0);
	switch_to(30.0, NULL, &sw);
	printf("spread after the restart %.3f ms\n", (double)sw.spread_ns / 1e6);
	/* A follower still making its first tables (its pipelines: seconds on
	 * a loaded host) publishes the new state first, without tables. */
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, has_tables, i) == 0);
	check_same_sky();
	/* A follower killed while the sky changes catches up when it comes
	 * back, from the retained message alone. */
	stop_skyd(2);
	CHECK(request(0, "set sun_elevation_deg=20", buf, sizeof(buf)) == 0);
	CHECK(wait_until(1, has_z, 1) == 0);
	CHECK(start_skyd(2) == 0);
	CHECK(wait_until(2, has_sky, 2) == 0);
	check_same_sky();
	check_same_generation();
}

/* 1 when skyd i's log holds text. */
static int log_has(int i, const char *text)
{
	static char buf[1 << 20];
	FILE *f = fopen(rig.skyd[i]->log, "r");
	size_t n = f ? fread(buf, 1, sizeof(buf) - 1, f) : 0;

	if (f)
		fclose(f);
	buf[n] = 0;
	return strstr(buf, text) != NULL;
}

/* A follower reloading a file with sky keys keeps the controller's sky:
 * the file's sync and daemon settings apply, its sky does not. */
static void reload_follower(void)
{
	static const char *const done = "the sky's keys are not applied: this skyd follows controller";
	char conf[256];
	double z = sun_z(1);
	uint64_t g = status_u64(1, "generation");

	snprintf(conf, sizeof(conf), "%s/skyd.conf", rig.skyd[1]->dir);
	FILE *f = fopen(conf, "a");
	CHECK(f && fputs("sun_elevation_deg = 44\nmax_connections = 99\n", f) >= 0 && fclose(f) == 0);
	kill(rig.skyd[1]->pid, SIGHUP);
	/* The reload logs its outcome; each turn waits on a publication or
	 * 50 ms, as wait_until does. */
	for (int k = 0; k < 400 && !log_has(1, done); k++) {
		uint32_t gen;
		sky_wait(client[1], atomic_load((_Atomic uint32_t *)&sky_header(client[1])->generation),
			 50, &gen);
	}
	CHECK(log_has(1, done));
	CHECK(status_u64(1, "max_connections") == 99);
	CHECK(status_u64(1, "generation") == g);
	CHECK(sun_z(1) == z);
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
	struct switch_result sw;
	switch_to(15.0, NULL, &sw);
	printf("spread after the garbage %.3f ms\n", (double)sw.spread_ns / 1e6);
	check_same_sky();
	reload_follower();
}

/* ---- terrain: every host needs the same file ---- */

/* A SKYTERRAIN16 file of 16 x 16 texels of one value. */
static int write_terrain(const char *path, uint16_t value)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		return -1;
	fprintf(f, "SKYTERRAIN16 16 16\n");
	for (int i = 0; i < 16 * 16; i++) {
		fputc(value & 0xff, f);
		fputc(value >> 8, f);
	}
	return fclose(f);
}

static int dropped(int i)
{
	char buf[8192], v[512];
	return request(i, "status", buf, sizeof(buf)) == 0 &&
	       reply_value(buf, "sync_last_drop", v, sizeof(v)) && strcmp(v, "none") != 0;
}

/* The followers take the controller's field; once the file under the
 * same path holds other heights (as a host with another file would),
 * they refuse the controller's next state, keep their sky, and say why
 * in their status. */
static void scenario_terrain(void)
{
	char path[192], req[256], buf[8192], v[512], hash[520] = "";

	snprintf(path, sizeof(path), "%s/terrain.raw", rig.dir);
	CHECK(write_terrain(path, 30000) == 0);
	snprintf(req, sizeof(req), "set terrain=%s sun_elevation_deg=20", path);
	CHECK(request(0, req, buf, sizeof(buf)) == 0);
	for (int i = 1; i < N_SKYD; i++)
		CHECK(wait_until(i, has_z, i) == 0);
	check_same_generation();
	for (int i = 0; i < N_SKYD; i++) {
		CHECK(request(i, "get terrain_hash", buf, sizeof(buf)) == 0 &&
		      reply_value(buf, "terrain_hash", v, sizeof(v)));
		if (i == 0)
			snprintf(hash, sizeof(hash), "%s", v);
		CHECK(strcmp(v, hash) == 0);
		CHECK(status_is(i, "sync_last_drop", "none"));
	}
	CHECK(write_terrain(path, 50000) == 0);
	struct timespec mt[2] = { { 3000, 0 }, { 3000, 0 } };
	CHECK(utimensat(AT_FDCWD, path, mt, 0) == 0);
	double z1 = sun_z(1);
	uint64_t g1 = status_u64(1, "sync_generation");
	CHECK(request(0, "set sun_elevation_deg=35", buf, sizeof(buf)) == 0);
	CHECK(wait_until(1, dropped, 1) == 0);
	CHECK(request(1, "status", buf, sizeof(buf)) == 0);
	printf("follower: sync_last_drop: %s\n",
	       reply_value(buf, "sync_last_drop", v, sizeof(v)) ? v : "(none)");
	CHECK(strstr(v, "terrain_hash: '") && strstr(v, "every host needs the same file"));
	CHECK(strstr(v, hash) != NULL);
	CHECK(status_u64(1, "sync_generation") == g1);
	CHECK(sun_z(1) == z1);
}

/* ---- the cloud field: the same tables on every host ---- */

#define CLOUD_BITS (SKY_TABLE_BIT(SKY_TABLE_CLOUD) | SKY_TABLE_BIT(SKY_TABLE_SHADOW))

/* Client i's slot with the cloud tables: its checksum and the cloud
 * block's offset east; 0 and NAN while they are not there. */
static uint64_t cloud_slot(int i, double *ret_offset_km)
{
	struct sky_view v;

	*ret_offset_km = NAN;
	for (int k = 0; k < 100; k++) {
		if (sky_view_begin(client[i], &v) < 0)
			continue;
		uint64_t sum = v.slot->checksum;
		uint32_t valid = v.valid_tables;
		double off = v.slot->clouds.offset_km[0];
		if (sky_view_end(client[i], &v)) {
			if ((valid & CLOUD_BITS) != CLOUD_BITS)
				return 0;
			*ret_offset_km = off;
			return sum;
		}
	}
	return 0;
}

static uint64_t want_sum;
static double want_offset;

/* Client i shows the cloud tables, placed away from want_offset (the
 * controller, the step taken), or with the controller's checksum. */
static int moved(int i)
{
	double off;
	return cloud_slot(i, &off) && off != want_offset;
}

static int caught_up(int i)
{
	double off;
	return cloud_slot(i, &off) == want_sum;
}

/* The cloud and shadow tables of the followers against the controller's,
 * byte for byte. */
static void same_cloud_tables(void)
{
	struct sky_view v[N_SKYD];
	int ok[N_SKYD];

	for (int i = 0; i < N_SKYD; i++)
		ok[i] = sky_view_begin(client[i], &v[i]) == 0;
	for (int i = 1; i < N_SKYD; i++)
		for (uint32_t id = SKY_TABLE_CLOUD; id <= SKY_TABLE_SHADOW && ok[0] && ok[i]; id++) {
			struct skysample_table a = { 0 }, b = { 0 };
			int found = skysample_table_from_slot(v[0].header, v[0].slot_base, id, &a) == 0 &&
				    skysample_table_from_slot(v[i].header, v[i].slot_base, id, &b) == 0;
			CHECK(found);
			size_t bytes = (size_t)a.width * a.height * a.depth * 16;
			CHECK(found && a.width == b.width && a.depth == b.depth &&
			      memcmp(a.texels, b.texels, bytes) == 0);
		}
	for (int i = 0; i < N_SKYD; i++)
		if (ok[i])
			CHECK(sky_view_end(client[i], &v[i]));
}

/* skyrender's frame of skyd i's sky, clouds and their shadows on the
 * terrain, into dir/frame<i>.png; 0 when skyrender exited 0. */
static int render_frame(int i, char *path, size_t size)
{
	snprintf(path, size, "%s/frame%d.png", rig.dir, i);
	pid_t pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_WRONLY);
		dup2(null, STDOUT_FILENO);
		execl(SKYRENDER_BINARY, SKYRENDER_BINARY, "--socket", rig.skyd[i]->sock, "--size", "48x32",
		      "--yaw", "200", "--pitch", "5", "--cloud-steps", "16", "--out", path, (char *)NULL);
		_exit(127);
	}
	int status;
	return pid > 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0
		       ? 0
		       : -1;
}

static int read_file(const char *path, char *buf, size_t size, size_t *ret_len)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return -1;
	*ret_len = fread(buf, 1, size, f);
	fclose(f);
	return 0;
}

/* The same slot draws the same frame: skyrender on the controller's and
 * on a follower's machine writes the same PNG, byte for byte. */
static void same_frames(void)
{
	static char a[1 << 16], b[1 << 16];
	char pa[256], pb[256];
	size_t na = 0, nb = 0;

	CHECK(render_frame(0, pa, sizeof(pa)) == 0 && render_frame(1, pb, sizeof(pb)) == 0);
	CHECK(read_file(pa, a, sizeof(a), &na) == 0 && read_file(pb, b, sizeof(b), &nb) == 0);
	printf("skyrender on the controller and a follower: %zu and %zu bytes, %s\n", na, nb,
	       na == nb && memcmp(a, b, na) == 0 ? "the same" : "different");
	CHECK(na > 0 && na == nb && memcmp(a, b, na) == 0);
}

/* A METAR with a broken layer, then a wind step, on the controller; then
 * a time 0.4 us before a whole second (the lights set by hand), which the
 * controller places in the second before and the message, to the
 * microsecond, in the next: the followers take the controller's
 * placement. Their clocks differ by those 0.4 us, and so do the slots'
 * checksums, which cover the state, and the sky tables' last bits: the
 * field's place and the cloud tables do not. */
static void scenario_clouds(void)
{
	const char *steps[3] = { "set utc=2026-06-21T10:00:00Z time_rate=0 "
				 "metar=\"EGLL 241250Z 27015KT 9999 BKN030 12/06 Q1018\"",
				 "set wind_speed_mps=20",
				 "set utc=2026-06-21T10:00:05.9999996Z sun_elevation_deg=35 "
				 "sun_azimuth_deg=160 moon_elevation_deg=-20" };
	char buf[2048];

	want_offset = NAN;
	for (int n = 0; n < 3; n++) {
		double before = want_offset, placed, off;
		CHECK(request(0, steps[n], buf, sizeof(buf)) == 0);
		CHECK(wait_until(0, moved, 0) == 0);
		want_sum = cloud_slot(0, &placed);
		want_offset = n < 2 ? placed : before;
		for (int i = 1; i < N_SKYD; i++) {
			CHECK(wait_until(i, n < 2 ? caught_up : moved, i) == 0);
			CHECK(cloud_slot(i, &off) && off == placed);
		}
		want_offset = placed;
		same_cloud_tables();
		printf("%s: %s %016llx, the field at %.6f km east\n", steps[n],
		       n < 2 ? "the three hold checksum" : "the controller's checksum",
		       (unsigned long long)want_sum, want_offset);
		if (n == 1)
			same_frames();
	}
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
	else if (strcmp(scenario, "terrain") == 0)
		scenario_terrain();
	else if (strcmp(scenario, "clouds") == 0)
		scenario_clouds();
	else
		fprintf(stderr, "unknown scenario %s\n", scenario), failures++;
	sync_rig_finish(&rig);
	printf("%s: %s\n", scenario, failures ? "FAILED" : "ok");
	return failures ? 1 : 0;
}

/* test_daemon_sync.c - three real skyd, one controller and two followers,
 * through a real mosquitto on a free loopback port (docs/sync.md): they
 * show the same sky, switch together at the apply time as their libsky
 * clients see it, survive the broker's restart, a restarted follower
 * catches up from the retained message, and garbage on the topic changes
 * nothing. Exits 77 without mosquitto or a Vulkan device.
 *
 * Usage: test_daemon_sync switch|restart|garbage */
#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <pwd.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "daemon_harness.h"
#include "sky.h"

#define MOSQUITTO_BIN "/usr/sbin/mosquitto"
#define MOSQUITTO_PUB "/usr/bin/mosquitto_pub"
#define N_SKYD 3
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

static char dir[128], broker_conf[192], url[96];
static int port;
static pid_t broker_pid = -1;
static struct daemon *skyd[N_SKYD];
static sky_client *client[N_SKYD];

static int64_t realtime_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static int free_port(void)
{
	struct sockaddr_in a = { .sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
	socklen_t len = sizeof(a);
	int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0), p = -1;

	if (fd >= 0 && bind(fd, (struct sockaddr *)&a, sizeof(a)) == 0 &&
	    getsockname(fd, (struct sockaddr *)&a, &len) == 0)
		p = ntohs(a.sin_port);
	if (fd >= 0)
		close(fd);
	return p;
}

static int tcp_accepts(void)
{
	struct sockaddr_in a = { .sin_family = AF_INET, .sin_port = htons((uint16_t)port),
				 .sin_addr.s_addr = htonl(INADDR_LOOPBACK) };
	int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
	int ok = fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof(a)) == 0;

	if (fd >= 0)
		close(fd);
	return ok;
}

/* Starts mosquitto (no persistence) and waits on its output pipe until
 * it accepts a connection or dies. */
static int broker_start(void)
{
	int p[2];

	if (pipe2(p, O_CLOEXEC) < 0)
		return -1;
	broker_pid = fork();
	if (broker_pid == 0) {
		dup2(p[1], 1);
		dup2(p[1], 2);
		execl(MOSQUITTO_BIN, "mosquitto", "-c", broker_conf, (char *)NULL);
		_exit(127);
	}
	close(p[1]);
	for (int i = 0; i < 1000; i++) {
		struct pollfd pfd = { .fd = p[0], .events = POLLIN };
		char buf[256];
		if (tcp_accepts()) {
			close(p[0]);
			return 0;
		}
		if (poll(&pfd, 1, 10) > 0 && read(p[0], buf, sizeof(buf)) == 0)
			break;
	}
	close(p[0]);
	return -1;
}

static void broker_kill(void)
{
	if (broker_pid > 0) {
		kill(broker_pid, SIGKILL);
		waitpid(broker_pid, NULL, 0);
	}
	broker_pid = -1;
}

static void setup_broker(void)
{
	struct passwd *pw = getpwuid(getuid());

	if (access(MOSQUITTO_BIN, X_OK) != 0 || access(MOSQUITTO_PUB, X_OK) != 0) {
		printf("skipped: no %s or %s\n", MOSQUITTO_BIN, MOSQUITTO_PUB);
		exit(77);
	}
	harness_need_device();
	if (harness_mkdtemp(dir, sizeof(dir)) < 0)
		exit(1);
	port = free_port();
	snprintf(broker_conf, sizeof(broker_conf), "%s/mosquitto.conf", dir);
	FILE *f = fopen(broker_conf, "w");
	if (!f)
		exit(1);
	fprintf(f, "listener %d 127.0.0.1\npersistence false\nallow_anonymous true\n", port);
	if (pw)
		fprintf(f, "user %s\n", pw->pw_name);
	fclose(f);
	snprintf(url, sizeof(url), "mqtt://127.0.0.1:%d/sky", port);
	if (broker_start() < 0) {
		fprintf(stderr, "mosquitto did not start\n");
		exit(1);
	}
}

static const char *const role_of[N_SKYD] = { "controller", "follower", "follower" };

static int start_skyd(int i)
{
	const char *args[] = { "--sync", url, "--sync-role", role_of[i], "sync_lead_ms=300",
			       HARNESS_SMALL, NULL };
	/* sync_lead_ms is a config key, not a state key: it goes in a file. */
	char conf[256], cdir[sizeof(skyd[0]->dir)];
	int r;

	/* A restart keeps its directory. */
	if (!skyd[i]->dir[0] && harness_mkdtemp(skyd[i]->dir, sizeof(skyd[0]->dir)) < 0)
		return -1;
	snprintf(conf, sizeof(conf), "%s/skyd.conf", skyd[i]->dir);
	FILE *f = fopen(conf, "w");
	if (!f)
		return -1;
	fprintf(f, "sync_lead_ms = 300\n");
	fclose(f);
	const char *argv[32];
	int n = 0;
	argv[n++] = "--config";
	argv[n++] = conf;
	for (int k = 0; args[k]; k++)
		if (strncmp(args[k], "sync_lead_ms", 12) != 0)
			argv[n++] = args[k];
	argv[n] = NULL;
	memcpy(cdir, skyd[i]->dir, sizeof(cdir));
	r = daemon_start_in(skyd[i], cdir, argv);
	if (r < 0)
		return r;
	if (sky_connect(skyd[i]->sock, &client[i]) < 0 ||
	    sky_subscribe(client[i], 0xf, 0) < 0)
		return -1;
	return 0;
}

static void stop_skyd(int i)
{
	sky_disconnect(client[i]);
	client[i] = NULL;
	daemon_stop(skyd[i], SIGKILL);
}

/* One request to skyd i; its reply in buf; the ACK code or 0. */
static int request(int i, const char *line, char *buf, size_t size)
{
	struct conn c;
	int r;

	if (conn_open(&c, skyd[i]->sock) < 0)
		return -1;
	r = conn_request(&c, line, buf, size);
	conn_close(&c);
	return r;
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
	char buf[8192], v[128];

	return request(i, "status", buf, sizeof(buf)) == 0 && reply_value(buf, key, v, sizeof(v)) &&
	       strcmp(v, want) == 0;
}

/* The z of the sun direction in client i's current slot; NAN none. */
static double sun_z(int i)
{
	struct sky_view v;

	for (int k = 0; k < 100; k++) {
		if (sky_view_begin(client[i], &v) < 0)
			continue;
		double z = v.slot->state.sun_direction[2];
		if (sky_view_end(client[i], &v))
			return z;
	}
	return NAN;
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

	broker_kill();
	for (int i = 0; i < N_SKYD; i++)
		CHECK(wait_until(i, lost, i) == 0);
	CHECK(broker_start() == 0);
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
	snprintf(portstr, sizeof(portstr), "%d", port);
	pid_t p = fork();
	if (p == 0) {
		execl(MOSQUITTO_PUB, "mosquitto_pub", "-h", "127.0.0.1", "-p", portstr, "-t", topic,
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
	char cmd[192];

	setup_broker();
	for (int i = 0; i < N_SKYD; i++)
		skyd[i] = calloc(1, sizeof(*skyd[i]));
	for (int i = 0; i < N_SKYD; i++)
		if (start_skyd(i) < 0) {
			broker_kill();
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
	for (int i = 0; i < N_SKYD; i++) {
		sky_disconnect(client[i]);
		daemon_cleanup(skyd[i]);
	}
	broker_kill();
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	(void)!system(cmd);
	printf("%s: %s\n", scenario, failures ? "FAILED" : "ok");
	return failures ? 1 : 0;
}

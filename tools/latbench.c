/* latbench.c - the service's figures: latency from a set to the new
 * generation visible in a client, a client's snapshot copy time, the
 * writer's compute time with 0 and 64 clients reading at 60 Hz, skyd's
 * resident memory at rest, and the latency from a light sensor's reading
 * to the generation it makes, visible in a client. Starts its own skyd
 * (default layout) on a private socket; the sensor figure runs latbench
 * again under umockdev-run with a replayed MCP2221A and BH1750
 * (tests/sensor/mcp-ramp.pcap), skipped without umockdev-run.
 * `latbench --sync [N]` instead measures replication: mosquitto and three
 * skyd (testkit/sync_harness.h), N sets on the controller, the latency to
 * the new sky on every follower and the spread of their switches; skipped
 * without mosquitto. A benchmark, not a test: it prints, it does not judge. */
#include <linux/futex.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>

#include "daemon_harness.h"
#include "sky.h"
#include "skyproto.h"
#include "sync_harness.h"

static char reply[1 << 16];

static double now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double pct(double *v, int n, double p)
{
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	int i = (int)ceil(p * n) - 1;
	return v[i < 0 ? 0 : i];
}

struct region {
	const uint8_t *map;
	const struct sky_shm_header *h;
	uint64_t bytes;
};

static int subscribe(struct conn *c, const char *sock, struct region *r)
{
	struct stat st;
	if (conn_open(c, sock) < 0 || conn_request(c, "subscribe tables=all", reply, sizeof(reply)) ||
	    c->n_fds < 1 || fstat(c->fds[c->n_fds - 1], &st) < 0)
		return -1;
	r->bytes = (uint64_t)st.st_size;
	r->map = mmap(NULL, r->bytes, PROT_READ, MAP_SHARED, c->fds[c->n_fds - 1], 0);
	r->h = (const void *)r->map;
	return r->map == MAP_FAILED ? -1 : 0;
}

static int copy_slot(const struct region *r, uint8_t *out)
{
	for (;;) {
		uint32_t cur = atomic_load_explicit((_Atomic uint32_t *)&r->h->current_slot, memory_order_acquire);
		const uint8_t *slot = r->map + r->h->header_bytes + (uint64_t)cur * r->h->slot_bytes;
		_Atomic uint32_t *seq = (_Atomic uint32_t *)slot;
		uint32_t s1 = atomic_load_explicit(seq, memory_order_acquire);
		if (s1 & 1)
			continue;
		memcpy(out, slot, r->h->slot_bytes);
		atomic_thread_fence(memory_order_acquire);
		if (atomic_load_explicit(seq, memory_order_relaxed) == s1)
			return 0;
	}
}

/* Waits on the futex word until the generation reaches gen. */
static void wait_generation(const struct region *r, uint32_t gen)
{
	_Atomic uint32_t *g = (_Atomic uint32_t *)&r->h->generation;
	for (;;) {
		uint32_t v = atomic_load_explicit(g, memory_order_acquire);
		if ((int32_t)(v - gen) >= 0)
			return;
		syscall(SYS_futex, g, FUTEX_WAIT, v, NULL, NULL, 0);
	}
}

static long rss_kb(pid_t pid)
{
	char path[64], line[256];
	long kb = -1;
	snprintf(path, sizeof(path), "/proc/%d/status", (int)pid);
	FILE *f = fopen(path, "r");
	while (f && fgets(line, sizeof(line), f))
		if (!strncmp(line, "VmRSS:", 6))
			kb = atol(line + 6);
	if (f)
		fclose(f);
	return kb;
}

/* The ways a render client reads the tables, all through libsky. */
enum reader_kind {
	READ_VIEW,		/* zero-copy view, a few texels sampled, validity check */
	READ_COPY,		/* sky_snapshot(): the whole slot copied out every frame */
	READ_COPY_NEW,		/* sky_snapshot() only when the generation moved */
	READ_KINDS
};
static const char *const reader_names[READ_KINDS] = { "view+sample", "copy every frame",
						       "copy when new" };

struct reader_result {
	uint64_t reads, copies, torn;
	double cpu_ms;
	long nvcsw, nivcsw;
};

static volatile sig_atomic_t reader_stop;
static void on_term(int sig)
{
	(void)sig;
	reader_stop = 1;
}

/* A client reading 60 times a second until SIGTERM; then its counts go to
 * result_fd. Frames that fall behind (SIGSTOP) are dropped, not caught up. */
static void reader_60hz(const char *sock, enum reader_kind kind, int ready_fd, int result_fd)
{
	struct reader_result res = { 0 };
	struct sigaction sa = { .sa_handler = on_term };
	sky_client *c;
	struct sky_view v;
	struct rusage ru;
	double rgb[3], sink = 0;
	uint32_t have = 0;

	sigaction(SIGTERM, &sa, NULL);
	if (sky_connect(sock, &c) < 0 || sky_subscribe(c, SKY_TABLES_ALL, 0) != 0) {
		(void)!write(ready_fd, "x", 1);	/* refused: the parent must not wait */
		_exit(1);
	}
	size_t size = sky_snapshot_size(c);
	void *buf = aligned_alloc(64, (size + 63) & ~(size_t)63);
	(void)!write(ready_fd, "r", 1);
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	while (!reader_stop) {
		res.reads++;
		if (kind == READ_VIEW) {
			for (;;) {
				if (sky_view_begin(c, &v) < 0)
					continue;
				for (int i = 0; i < 4; i++) {
					sky_sample_sky(&v, 5.0 + 20.0 * i, 90.0 * i, 0, rgb);
					sink += rgb[0];
				}
				if (sky_view_end(c, &v))
					break;
				res.torn++;
			}
		} else {
			uint32_t g = __atomic_load_n(&sky_header(c)->generation, __ATOMIC_ACQUIRE);
			if (kind == READ_COPY || g != have) {
				while (sky_snapshot(c, buf, size, &v) < 0)
					res.torn++;
				have = v.generation;
				res.copies++;
			}
		}
		t.tv_nsec += 16666667;
		if (t.tv_nsec >= 1000000000) {
			t.tv_nsec -= 1000000000;
			t.tv_sec++;
		}
		struct timespec now;
		clock_gettime(CLOCK_MONOTONIC, &now);
		if (now.tv_sec > t.tv_sec || (now.tv_sec == t.tv_sec && now.tv_nsec > t.tv_nsec))
			t = now;
		clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL);
	}
	getrusage(RUSAGE_SELF, &ru);
	res.cpu_ms = (ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) * 1e3 +
		     (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e3;
	res.nvcsw = ru.ru_nvcsw;
	res.nivcsw = ru.ru_nivcsw + (sink < 0);
	(void)!write(result_fd, &res, sizeof(res));
	sky_disconnect(c);
	_exit(0);
}

/* Writer compute time with 64 readers of one kind: alternating phases with
 * the readers stopped (SIGSTOP: 0 readers) and running, so that a drift in
 * the machine's load hits both alike. */
static void bench_readers(struct conn *c, const struct region *r, const char *sock,
			  enum reader_kind kind, int rounds, int per_phase)
{
	enum { N = 64 };
	pid_t kids[N];
	int ready[2], results[2];
	double *idle = calloc((size_t)(rounds * per_phase), sizeof(double));
	double *busy = calloc((size_t)(rounds * per_phase), sizeof(double));
	int ni = 0, nb = 0;
	char buf[64];
	static int salt;

	if (pipe2(ready, O_CLOEXEC) < 0 || pipe2(results, O_CLOEXEC) < 0)
		return;
	for (int i = 0; i < N; i++) {
		kids[i] = fork();
		if (kids[i] == 0)
			reader_60hz(sock, kind, ready[1], results[1]);
	}
	int refused = 0;
	for (int i = 0; i < N; i++)
		if (read(ready[0], buf, 1) != 1 || buf[0] != 'r')
			refused++;
	if (refused)
		fprintf(stderr, "latbench: %d of %d readers could not subscribe\n", refused, N);
	double t_busy = 0;
	for (int round = 0; round < rounds; round++) {
		for (int phase = 0; phase < 2; phase++) {
			for (int i = 0; i < N; i++)
				kill(kids[i], phase ? SIGCONT : SIGSTOP);
			double t0 = now_ms();
			for (int k = 0; k < per_phase; k++) {
				char req[128];
				snprintf(req, sizeof(req), "set sun_elevation_deg=%.4f",
					 5.0 + 0.0001 * ++salt);
				conn_request(c, req, reply, sizeof(reply));
				wait_generation(r, (uint32_t)reply_u64(reply, "generation"));
				conn_request(c, "status", reply, sizeof(reply));
				double ms = atof(reply_value(reply, "compute_ms", buf, sizeof(buf)));
				if (phase)
					busy[nb++] = ms;
				else
					idle[ni++] = ms;
			}
			if (phase)
				t_busy += now_ms() - t0;
		}
	}
	struct reader_result total = { 0 }, one;
	for (int i = 0; i < N; i++)
		kill(kids[i], SIGTERM);
	for (int i = 0; i < N; i++)
		if (read(results[0], &one, sizeof(one)) == sizeof(one)) {
			total.reads += one.reads;
			total.copies += one.copies;
			total.torn += one.torn;
			total.cpu_ms += one.cpu_ms;
			total.nvcsw += one.nvcsw;
			total.nivcsw += one.nivcsw;
		}
	for (int i = 0; i < N; i++)
		waitpid(kids[i], NULL, 0);
	close(ready[0]);
	close(ready[1]);
	close(results[0]);
	close(results[1]);
	double mi = 0, mb = 0;
	for (int i = 0; i < ni; i++)
		mi += idle[i] / ni;
	for (int i = 0; i < nb; i++)
		mb += busy[i] / nb;
	qsort(idle, (size_t)ni, sizeof(double), cmp_double);
	qsort(busy, (size_t)nb, sizeof(double), cmp_double);
	printf("64 readers, %s: writer compute_ms mean %.2f -> %.2f (%+.1f %%), median %.2f -> %.2f "
	       "(%+.1f %%), %d changes each\n",
	       reader_names[kind], mi, mb, 100.0 * (mb - mi) / mi, idle[ni / 2], busy[nb / 2],
	       100.0 * (busy[nb / 2] - idle[ni / 2]) / idle[ni / 2], ni);
	printf("    readers: %llu reads (%.0f/s), %llu copies, %llu torn, %.1f us CPU per read "
	       "(incl. wake-up), %.1f %% of one core in all, %.1f context switches per read, "
	       "%.0f MB/s copied\n",
	       (unsigned long long)total.reads, total.reads / (t_busy / 1e3),
	       (unsigned long long)total.copies, (unsigned long long)total.torn,
	       total.reads ? total.cpu_ms * 1e3 / total.reads : 0.0,
	       100.0 * total.cpu_ms / t_busy,
	       total.reads ? (double)(total.nvcsw + total.nivcsw) / total.reads : 0.0,
	       (double)total.copies * (double)r->h->slot_bytes / (t_busy * 1e3));
	free(idle);
	free(busy);
}

/* ---- a light sensor's reading -> the generation it makes ---- */

#define MAX_GENERATIONS 4096

/* When each generation was first seen, by a thread waiting on the futex
 * word, so that the time does not wait for the socket's lines. */
struct seen {
	const struct region *r;
	double at_ms[MAX_GENERATIONS];
	atomic_int stop;
};

static void *watch_generations(void *arg)
{
	struct seen *s = arg;
	_Atomic uint32_t *g = (_Atomic uint32_t *)&s->r->h->generation;
	uint32_t have = atomic_load_explicit(g, memory_order_acquire);

	while (!atomic_load(&s->stop)) {
		struct timespec ts = { 0, 100000000 };
		syscall(SYS_futex, g, FUTEX_WAIT, have, &ts, NULL, 0);
		uint32_t v = atomic_load_explicit(g, memory_order_acquire);
		double t = now_ms();
		for (uint32_t k = have + 1; (int32_t)(v - k) >= 0 && k < MAX_GENERATIONS; k++)
			s->at_ms[k] = t;
		have = v;
	}
	return NULL;
}

static uint64_t event_u64(const char *line, const char *key)
{
	const char *p = strstr(line, key);
	return p ? strtoull(p + strlen(key), NULL, 10) : 0;
}

/* Sends req and reads to its OK; sensor: lines that come on the way are
 * handed to fn. */
static int sensor_request(struct conn *c, const char *req, void (*fn)(void *, const char *),
			  void *ctx)
{
	char line[8192];

	if (send(c->fd, req, strlen(req), MSG_NOSIGNAL) < 0 || send(c->fd, "\n", 1, MSG_NOSIGNAL) < 0)
		return -1;
	for (;;) {
		if (conn_line(c, line, sizeof(line)) < 0)
			return -1;
		if (!strncmp(line, "sensor: ", 8))
			fn(ctx, line);
		else if (!strcmp(line, "OK") || !strncmp(line, "ACK", 3))
			return line[0] == 'O' ? 0 : -1;
	}
}

struct changes {
	uint64_t generation[MAX_GENERATIONS], mono_ns[MAX_GENERATIONS];
	int n;
	uint64_t last_changes;
	int stopped;			/* the device stopped: its capture is over */
};

/* A sensor: line whose reading made a change: its generation and the
 * monotonic time skyd took the reading at. */
static void note_change(void *ctx, const char *line)
{
	struct changes *ch = ctx;
	uint64_t k = event_u64(line, " changes=");

	if (ch->n && (strstr(line, " state=searching") || strstr(line, " state=starting")))
		ch->stopped = 1;
	if (k > ch->last_changes && !strstr(line, " stale=1") && ch->n < MAX_GENERATIONS) {
		ch->generation[ch->n] = event_u64(line, " generation=");
		ch->mono_ns[ch->n] = event_u64(line, " mono_ns=");
		ch->n++;
	}
	if (k > ch->last_changes)
		ch->last_changes = k;
}

/* Under umockdev-run: skyd reads the replayed MCP2221A, polled every
 * 100 ms; in cloud mode every reading of the ramp is a change. */
static int bench_sensor(void)
{
	static const char *const args[] = { "sun_elevation_deg=60", "sensor_time_constant_s=0",
		"sensor_hysteresis=0", "sensor_min_interval_s=0", "sensor_report_interval_s=0.1",
		"sensor_io_timeout_s=0.3", NULL };
	static struct seen seen;
	static struct changes ch;
	struct daemon d;
	struct conn c;
	struct region r;
	pthread_t th;
	char line[8192];

	harness_need_device();
	if (daemon_start(&d, args) < 0 || subscribe(&c, d.sock, &r) < 0)
		return 1;
	seen.r = &r;
	if (pthread_create(&th, NULL, watch_generations, &seen) != 0)
		return 1;
	if (sensor_request(&c, "sensor events=1", note_change, &ch) < 0 ||
	    sensor_request(&c, "set sensor_mode=cloud", note_change, &ch) < 0)
		return 1;
	while (!ch.stopped && conn_line(&c, line, sizeof(line)) >= 0)
		if (!strncmp(line, "sensor: ", 8))
			note_change(&ch, line);
	atomic_store(&seen.stop, 1);
	pthread_join(th, NULL);
	double *lat = malloc(sizeof(double) * (size_t)(ch.n ? ch.n : 1));
	int n = 0;
	for (int i = 0; i < ch.n; i++)
		if (ch.generation[i] < MAX_GENERATIONS && seen.at_ms[ch.generation[i]] > 0.0)
			lat[n++] = seen.at_ms[ch.generation[i]] - (double)ch.mono_ns[i] / 1e6;
	if (n)
		printf("sensor reading -> generation visible (cloud mode, %d readings of a replayed "
		       "MCP2221A + BH1750, default layout): median %.2f ms, p99 %.2f ms\n", n,
		       pct(lat, n, 0.5), pct(lat, n, 0.99));
	else
		printf("sensor reading -> generation visible: no reading made a change\n");
	free(lat);
	conn_close(&c);
	daemon_cleanup(&d);
	return 0;
}

/* Runs latbench --sensor under umockdev-run with the MCP2221A's device
 * description and the ramp's capture. */
static void run_sensor_bench(void)
{
	char self[512], dev[512], cap[640];
	ssize_t k = readlink("/proc/self/exe", self, sizeof(self) - 1);

	if (k <= 0)
		return;
	self[k] = 0;
	snprintf(dev, sizeof(dev), "%s/mcp.umockdev", SKYD_SENSOR_DATA);
	snprintf(cap, sizeof(cap), "/sys/devices/pci0000:00/0000:00:14.0/usb1/1-3=%s/mcp-ramp.pcap",
		 SKYD_SENSOR_DATA);
	fflush(stdout);
	pid_t pid = fork();
	if (pid == 0) {
		execlp("umockdev-run", "umockdev-run", "-d", dev, "-p", cap, "--", self, "--sensor",
		       (char *)NULL);
		printf("sensor reading -> generation visible: skipped (umockdev-run: %s)\n",
		       strerror(errno));
		_exit(0);
	}
	if (pid > 0)
		waitpid(pid, NULL, 0);
}

/* ---- --sync: a controller and two followers through mosquitto ---- */

struct sync_watch {
	const struct sync_rig *rig;
	int index;
	double target_z;
	int64_t ahead_ns;		/* the new sky first found in the spare slot */
	int64_t seen_ns;		/* libsky first handed it out */
	int64_t apply_ns;
	pthread_t thread;
};

/* The sun z in the spare slot of client i's region, NAN while written. */
static double spare_z(const struct sync_rig *rig, int i)
{
	const struct sky_shm_header *h = sky_header(rig->client[i]);
	const struct sky_shm_slot *s = (const void *)((const uint8_t *)h + h->header_bytes +
						      (uint64_t)(h->n_slots - 1) * h->slot_bytes);
	uint32_t seq = atomic_load_explicit((_Atomic uint32_t *)&s->seq, memory_order_acquire);
	double z = s->state.sun_direction[2];

	atomic_thread_fence(memory_order_acquire);
	if ((seq & 1u) || atomic_load_explicit((_Atomic uint32_t *)&s->seq, memory_order_relaxed) != seq)
		return NAN;
	return z;
}

/* Follows one follower's client through one change: when the new sky
 * arrives in the spare slot and when libsky hands it out. */
static void *sync_watch(void *arg)
{
	struct sync_watch *w = arg;
	sky_client *c = w->rig->client[w->index];

	for (int k = 0; k < 4000; k++) {
		struct sky_view v;
		uint32_t next;
		if (!w->ahead_ns && fabs(spare_z(w->rig, w->index) - w->target_z) < 1e-9)
			w->ahead_ns = sync_realtime_ns();
		if (sky_view_begin(c, &v) < 0)
			continue;
		double z = v.slot->state.sun_direction[2];
		int64_t at = v.slot->apply_time_ns;
		if (!sky_view_end(c, &v))
			continue;
		if (fabs(z - w->target_z) < 1e-9) {
			w->seen_ns = sync_realtime_ns();
			w->apply_ns = at;
			return NULL;
		}
		if (w->ahead_ns) {
			sky_wait(c, v.generation, 100, &next);
			continue;
		}
		/* sky_wait sleeps through the arrival ahead of the apply time
		 * (it hands out nothing new then): the header's futex wakes. */
		const uint32_t *word = &sky_header(c)->generation;
		struct timespec ts = { 0, 100000000L };
		syscall(SYS_futex, word, FUTEX_WAIT, v.generation, &ts, NULL, 0);
	}
	return NULL;
}

/* One set on the controller, watched on every follower: fills the
 * latency to the last follower's switch, to the last follower's spare
 * slot, and the spread of the switches, in ms. -1 when one never came. */
static int sync_one(struct sync_rig *rig, int run, double *ret_visible, double *ret_ahead,
		    double *ret_spread)
{
	struct sync_watch w[SYNC_N_SKYD - 1];
	double el = 10.0 + 0.01 * run;
	char req[96], buf[1024];
	int64_t lo = INT64_MAX, hi = INT64_MIN, ahead = INT64_MIN, t0;

	for (int i = 0; i < SYNC_N_SKYD - 1; i++) {
		w[i] = (struct sync_watch){ .rig = rig, .index = i + 1,
					    .target_z = sin(el * M_PI / 180.0) };
		pthread_create(&w[i].thread, NULL, sync_watch, &w[i]);
	}
	snprintf(req, sizeof(req), "set sun_elevation_deg=%.4f", el);
	t0 = sync_realtime_ns();
	int e = sync_request(rig, 0, req, buf, sizeof(buf));
	for (int i = 0; i < SYNC_N_SKYD - 1; i++) {
		pthread_join(w[i].thread, NULL);
		if (!w[i].seen_ns)
			e = -1;
		lo = w[i].seen_ns < lo ? w[i].seen_ns : lo;
		hi = w[i].seen_ns > hi ? w[i].seen_ns : hi;
		/* A follower that only saw it when it became current: no time ahead. */
		int64_t a = w[i].ahead_ns ? w[i].ahead_ns : w[i].seen_ns;
		ahead = a > ahead ? a : ahead;
	}
	*ret_visible = (double)(hi - t0) / 1e6;
	*ret_ahead = (double)(ahead - t0) / 1e6;
	*ret_spread = (double)(hi - lo) / 1e6;
	return e ? -1 : 0;
}

/* latbench --sync [N]: mosquitto on a free loopback port, a controller and
 * two followers (testkit/sync_harness.h: small tables, sync_lead_ms 300),
 * N sets on the controller. */
static int bench_sync(int n)
{
	struct sync_rig rig = { 0 };
	int ok = 1;

	if (!sync_have_mosquitto()) {
		printf("sync: skipped (no %s or %s)\n", SYNC_MOSQUITTO_BIN, SYNC_MOSQUITTO_PUB);
		return 0;
	}
	harness_need_device();
	if (sync_broker_setup(&rig) < 0) {
		fprintf(stderr, "sync: mosquitto did not start\n");
		sync_rig_finish(&rig);
		return 1;
	}
	for (int i = 0; i < SYNC_N_SKYD && ok; i++)
		ok = sync_skyd_start(&rig, i) == 0;
	for (int i = 0; i < SYNC_N_SKYD && ok; i++)
		for (int k = 0; k < 2000 && !sync_status_is(&rig, i, "sync", "connected"); k++)
			sky_wait(rig.client[i], sky_header(rig.client[i])->generation, 10, NULL);
	double *vis = calloc((size_t)n, sizeof(double)), *ahead = calloc((size_t)n, sizeof(double));
	double *spread = calloc((size_t)n, sizeof(double));
	int m = 0;
	for (int i = 0; ok && vis && ahead && spread && i < n; i++)
		if (sync_one(&rig, i, &vis[m], &ahead[m], &spread[m]) == 0)
			m++;
	if (m > 0) {
		printf("sync: %d sets on the controller, 2 followers, sync_lead_ms %d, %d lost\n", m,
		       SYNC_LEAD_MS, n - m);
		printf("set -> new sky in every follower's spare slot: median %.2f ms, p99 %.2f ms\n",
		       pct(ahead, m, 0.5), pct(ahead, m, 0.99));
		printf("set -> visible in a client on every follower: median %.2f ms, p99 %.2f ms\n",
		       pct(vis, m, 0.5), pct(vis, m, 0.99));
		printf("spread of the followers' switches: median %.3f ms, p99 %.3f ms\n",
		       pct(spread, m, 0.5), pct(spread, m, 0.99));
	}
	free(vis);
	free(ahead);
	free(spread);
	sync_rig_finish(&rig);
	return ok && m == n ? 0 : 1;
}

int main(int argc, char **argv)
{
	if (argc > 1 && !strcmp(argv[1], "--sync"))
		return bench_sync(argc > 2 ? atoi(argv[2]) : 50);
	if (argc > 1 && !strcmp(argv[1], "--sensor")) {
		if (getenv("UMOCKDEV_DIR"))
			return bench_sensor();
		run_sensor_bench();
		return 0;
	}
	int n = argc > 1 ? atoi(argv[1]) : 200;
	struct daemon d;
	struct conn c;
	struct region r;
	char req[128];

	/* 64 readers and this client subscribe under one uid: above skyd's
	 * default bound per uid. */
	static const char *const args[] = { "--max-subscriptions-per-uid", "128", NULL };
	harness_need_device();
	if (daemon_start(&d, args) < 0)
		return 1;
	if (subscribe(&c, d.sock, &r) < 0)
		return 1;
	wait_generation(&r, 1);
	printf("device: ");
	conn_request(&c, "status", reply, sizeof(reply));
	char buf[256];
	printf("%s\n", reply_value(reply, "device", buf, sizeof(buf)));
	printf("default layout: %llu bytes a slot, %llu bytes in all\n",
	       (unsigned long long)r.h->slot_bytes, (unsigned long long)r.h->total_bytes);

	/* 1. set -> visible, through the futex. */
	double *lat = malloc(sizeof(double) * (size_t)n);
	for (int i = 0; i < n; i++) {
		snprintf(req, sizeof(req), "set sun_elevation_deg=%.4f", 10.0 + 0.01 * i);
		double t0 = now_ms();
		conn_request(&c, req, reply, sizeof(reply));
		wait_generation(&r, (uint32_t)reply_u64(reply, "generation"));
		lat[i] = now_ms() - t0;
	}
	printf("set -> generation visible (sun change, %d runs): median %.2f ms, p99 %.2f ms\n", n,
	       pct(lat, n, 0.5), pct(lat, n, 0.99));

	/* 2. A client's snapshot copy. */
	uint8_t *copy = malloc(r.h->slot_bytes);
	int copies = 2000;
	double t0 = now_ms();
	for (int i = 0; i < copies; i++)
		copy_slot(&r, copy);
	printf("snapshot copy (%llu bytes): %.1f us each (mean of %d)\n",
	       (unsigned long long)r.h->slot_bytes, (now_ms() - t0) * 1e3 / copies, copies);

	/* 3. Writer compute time, 0 vs 64 readers at 60 Hz, per kind of reader. */
	/* Short phases, many rounds: the load of a shared machine drifts. */
	int per_phase = 3, rounds = n / 12 < 4 ? 4 : n / 12;
	for (int k = 0; k < READ_KINDS; k++)
		bench_readers(&c, &r, d.sock, (enum reader_kind)k, rounds, per_phase);

	/* 4. Resident memory at rest. */
	conn_close(&c);
	printf("skyd resident memory at rest: %ld kB\n", rss_kb(d.pid));
	daemon_cleanup(&d);

	/* 5. A light sensor's reading -> the generation it makes. */
	run_sensor_bench();
	return 0;
}

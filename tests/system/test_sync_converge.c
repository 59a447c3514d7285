/* test_sync_converge.c - replication keeps every change: one controller and
 * two followers through a real mosquitto (testkit/sync_harness.h), a
 * libsky client on each; changes come to the controller faster than its
 * computations (each held until its apply time, 300 ms ahead) and than
 * the broker, and at the end every follower and every client has the
 * controller's last state: the same get output, the same replicated
 * sequence, the published slot's state and tables bit for bit.
 *
 * Usage: test_sync_converge three|hundred|random [SEED]
 *   three    three sets of sun_elevation_deg 5 ms apart;
 *   hundred  a hundred sets 1 ms apart;
 *     both: every follower ends on the last value, and each client's sun
 *     only ever rises (the switches come in the order of the sets);
 *   random   three rounds of seeded random set, batch, metar, views and
 *            clock changes at random intervals of 0 to 50 ms; the seed is
 *            SEED, else $SKYD_TEST_SEED, else a fixed one, printed, and
 *            printed again on failure with the line that reruns it.
 * Exits 77 without mosquitto or a Vulkan device. Every wait is on a
 * publication (sky_wait) bounded by a deadline; the pauses between the
 * changes pace the load and wait for nothing. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "daemon_harness.h"
#include "sky.h"
#include "sync_harness.h"
#include "test.h"
#include "change_gen.h"

#define N_SKYD SYNC_N_SKYD
#define MS 1000000ll
/* How long the followers may take to converge after the last change:
 * the lead (300 ms) and the computations of three skyd on a shared
 * machine, with ample room. */
#define CONVERGE_NS (20000 * MS)
#define ROUNDS 3
#define OPS_PER_ROUND 60
#define DEFAULT_SEED 20261124

static struct sync_rig rig;
static struct conn ctl;			/* the controller's control connection */
static uint64_t last_generation;	/* the one the controller's last change named */
static char reply[1 << 16];

static int64_t mono_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

/* Waits until t0 + at_ns: the pace of the changes, not a wait for an
 * event. */
static void pace(int64_t t0, int64_t at_ns)
{
	int64_t t = t0 + at_ns;
	struct timespec ts = { .tv_sec = t / 1000000000ll, .tv_nsec = t % 1000000000ll };

	while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
		;
}

/* One change (a request line, or a batch of lines) on the controller. */
static void change(const char *req)
{
	int e = conn_request(&ctl, req, reply, sizeof(reply));

	if (e != 0) {
		FAIL("controller: '%s': %d: %s", req, e, reply);
		return;
	}
	uint64_t g = reply_u64(reply, "generation");
	if (g != UINT64_MAX && g > last_generation)
		last_generation = g;
}

/* ---- what each machine shows ---- */

/* The get output through client i, as "key: value" lines; 0 or -1. */
static int get_text(int i, char *buf, size_t size)
{
	sky_reply *r = NULL;
	size_t o = 0;

	buf[0] = 0;
	if (sky_request(rig.client[i], "get", &r) != 0) {
		sky_reply_free(r);
		return -1;
	}
	for (size_t k = 0; k < sky_reply_count(r) && o < size; k++)
		o += (size_t)snprintf(buf + o, size - o, "%s: %s\n", sky_reply_key(r, k),
				      sky_reply_value(r, k));
	sky_reply_free(r);
	return 0;
}

/* The first line where a and b differ, into why; 1 when they do. */
static int text_differs(const char *a, const char *b, char *why, size_t size)
{
	while (*a && *b) {
		size_t na = strcspn(a, "\n"), nb = strcspn(b, "\n");
		if (na != nb || memcmp(a, b, na)) {
			snprintf(why, size, "'%.*s', the controller '%.*s'", (int)nb, b, (int)na, a);
			return 1;
		}
		a += na + (a[na] != 0);
		b += nb + (b[nb] != 0);
	}
	if (*a || *b)
		snprintf(why, size, "%s lines", *a ? "fewer" : "more");
	return *a || *b;
}

static uint64_t status_u64(int i, const char *key)
{
	char buf[8192];

	if (sync_request(&rig, i, "status", buf, sizeof(buf)) != 0)
		return UINT64_MAX;
	return reply_u64(buf, key);
}

/* A copy of the slot client i hands out now. */
struct snap {
	void *buf;
	struct sky_view v;
};

static int take(int i, struct snap *s)
{
	size_t size = sky_snapshot_size(rig.client[i]);

	free(s->buf);
	s->buf = aligned_alloc(64, (size + 63) & ~(size_t)63);
	return s->buf ? sky_snapshot(rig.client[i], s->buf, size, &s->v) : -ENOMEM;
}

/* NULL when b's slot holds a's state and tables bit for bit (views are
 * each machine's own: left out), else what differs. */
static const char *slot_differs(const struct snap *a, const struct snap *b)
{
	static char why[128];
	const struct sky_shm_header *ha = a->v.header, *hb = b->v.header;

	if (a->v.valid_tables != b->v.valid_tables) {
		snprintf(why, sizeof(why), "valid tables 0x%x, the controller's 0x%x",
			 b->v.valid_tables, a->v.valid_tables);
		return why;
	}
	if (memcmp(&a->v.slot->state, &b->v.slot->state, sizeof(a->v.slot->state)))
		return "the slot's state";
	for (uint32_t t = 0; t < ha->n_tables; t++) {
		if (!(a->v.valid_tables & (1u << t)))
			continue;
		if (ha->tables[t].bytes != hb->tables[t].bytes ||
		    memcmp((const uint8_t *)a->v.slot_base + ha->tables[t].offset,
			   (const uint8_t *)b->v.slot_base + hb->tables[t].offset, ha->tables[t].bytes)) {
			snprintf(why, sizeof(why), "table %u's bytes", t);
			return why;
		}
	}
	return NULL;
}

/* ---- convergence ---- */

/* Waits until the controller has published its last change with nothing
 * in flight and its client hands it out; 0 or -1 at the deadline. */
static int settle_controller(int64_t deadline)
{
	while (mono_ns() < deadline) {
		char buf[8192];
		struct sky_view v;
		if (sync_request(&rig, 0, "status", buf, sizeof(buf)) == 0 &&
		    reply_u64(buf, "generation") >= last_generation &&
		    reply_u64(buf, "computing") == 0 && reply_u64(buf, "pending") == 0 &&
		    sky_view_begin(rig.client[0], &v) == 0 && sky_view_end(rig.client[0], &v) &&
		    v.generation >= (uint32_t)last_generation)
			return 0;
		uint32_t seen = atomic_load((_Atomic uint32_t *)&sky_header(rig.client[0])->generation);
		sky_wait(rig.client[0], seen, 100, NULL);
	}
	return -1;
}

/* What the followers must reach: the controller's get output, sequence
 * and slot. */
struct target {
	char get[16384];
	uint64_t sequence;
	struct snap slot;
};

/* Whether follower i shows the target now; why says what differs. */
static int follower_has(int i, const struct target *t, struct snap *s, char *why, size_t size)
{
	static char get[16384];
	const char *d = NULL;
	uint64_t seq;

	if (take(i, s) < 0)
		d = "no snapshot";
	else if (!(d = slot_differs(&t->slot, s)) && get_text(i, get, sizeof(get)) < 0)
		d = "no get";
	if (d) {
		snprintf(why, size, "%s", d);
		return 0;
	}
	if (text_differs(t->get, get, why, size))
		return 0;
	if ((seq = status_u64(i, "sync_sequence")) != t->sequence) {
		snprintf(why, size, "sync_sequence %llu, the controller's %llu",
			 (unsigned long long)seq, (unsigned long long)t->sequence);
		return 0;
	}
	return 1;
}

/* Every follower and its client on the controller's last state: each
 * waits on its client's publications until it shows it, or the deadline.
 * Says how long each took. */
static void check_converged(const char *what)
{
	int64_t t_last = mono_ns(), deadline = t_last + CONVERGE_NS;
	struct target *t = calloc(1, sizeof(*t));
	char why[512] = "";

	if (!t || settle_controller(deadline) < 0) {
		FAIL("%s: the controller did not settle on generation %llu", what,
		     (unsigned long long)last_generation);
		free(t);
		return;
	}
	CHECK(take(0, &t->slot) == 0 && get_text(0, t->get, sizeof(t->get)) == 0);
	t->sequence = status_u64(0, "sync_sequence");
	if (t->sequence == UINT64_MAX)
		FAIL("%s: the controller's status has no sync_sequence", what);
	for (int i = 1; i < N_SKYD; i++) {
		struct snap s = { NULL };
		int ok = 0;
		while (!(ok = follower_has(i, t, &s, why, sizeof(why))) && mono_ns() < deadline)
			sky_wait(rig.client[i], s.buf ? s.v.generation : 0, 100, NULL);
		if (!ok) {
			char buf[8192], v[256] = "";
			if (sync_request(&rig, i, "status", buf, sizeof(buf)) == 0)
				reply_value(buf, "sync_counters", v, sizeof(v));
			FAIL("%s: follower %d is not on the controller's last state after %.0f s: "
			     "%s (sync_counters: %s)", what, i, (double)CONVERGE_NS / 1e9, why, v);
		} else {
			printf("%s: follower %d on the controller's state (sequence %llu) %.1f ms "
			       "after the last change\n", what, i,
			       (unsigned long long)t->sequence, (double)(mono_ns() - t_last) / 1e6);
		}
		free(s.buf);
	}
	free(t->slot.buf);
	free(t);
}

/* ---- the switches come in order ---- */

/* A client of its own on skyd index that notes the sun's z of each slot
 * it is handed, until stop. */
struct watcher {
	int index;
	sky_client *c;
	pthread_t thread;
	atomic_int stop;
	double z[4096];
	int n;
};

static void *watch(void *arg)
{
	struct watcher *w = arg;
	uint32_t gen = 0;

	while (!atomic_load(&w->stop)) {
		struct sky_view v;
		if (sky_view_begin(w->c, &v) == 0) {
			double z = v.slot->state.sun_direction[2];
			uint32_t g = v.generation;
			if (sky_view_end(w->c, &v) && (w->n == 0 || z != w->z[w->n - 1]) &&
			    w->n < (int)(sizeof(w->z) / sizeof(w->z[0])))
				w->z[w->n++] = z;
			gen = g;
		}
		sky_wait(w->c, gen, 20, NULL);
	}
	return NULL;
}

/* n sets of sun_elevation_deg, period_ns apart, each higher than the
 * last; every follower ends on the last, and no client's sun ever went
 * down on the way. */
static void scenario_rising(int n, int64_t period_ns)
{
	struct watcher w[N_SKYD];
	char line[96], what[64];
	double last_deg = 0.0;

	snprintf(what, sizeof(what), "%d sets %.0f ms apart", n, (double)period_ns / 1e6);
	for (int i = 0; i < N_SKYD; i++) {
		w[i] = (struct watcher){ .index = i };
		atomic_init(&w[i].stop, 0);
		if (sky_connect(rig.skyd[i]->sock, &w[i].c) < 0 || sky_subscribe(w[i].c, 0xf, 0) < 0) {
			FAIL("watcher %d", i);
			return;
		}
		pthread_create(&w[i].thread, NULL, watch, &w[i]);
	}
	int64_t t0 = mono_ns();
	for (int k = 0; k < n; k++) {
		pace(t0, k * period_ns);
		snprintf(line, sizeof(line), "set sun_elevation_deg=%.4f", 31.0 + 50.0 * (k + 1) / n);
		last_deg = strtod(strchr(line, '=') + 1, NULL);
		change(line);
	}
	check_converged(what);
	for (int i = 0; i < N_SKYD; i++) {
		char get[256], v[64] = "";
		CHECK(sync_request(&rig, i, "get sun_elevation_deg", get, sizeof(get)) == 0 &&
		      reply_value(get, "sun_elevation_deg", v, sizeof(v)));
		CHECK_NEAR(strtod(v, NULL), last_deg, 1e-9);
		CHECK_NEAR(sync_sun_z(&rig, i, NULL), sin(last_deg * M_PI / 180.0), 1e-9);
	}
	for (int i = 0; i < N_SKYD; i++) {
		atomic_store(&w[i].stop, 1);
		pthread_join(w[i].thread, NULL);
		for (int k = 1; k < w[i].n; k++)
			if (w[i].z[k] < w[i].z[k - 1])
				FAIL("%s: skyd %d's client saw the sun go down: z %.9f after %.9f", what,
				     i, w[i].z[k], w[i].z[k - 1]);
		printf("%s: skyd %d's client saw %d skies on the way\n", what, i, w[i].n);
		sky_disconnect(w[i].c);
	}
}

/* ---- random changes ---- */

/* A connection per skyd for views: each machine's own. */
static struct conn vconn[N_SKYD];
static int vopen[N_SKYD];
static unsigned vnames[N_SKYD];		/* views added on vconn[i], by name v0 ... */

/* A view added, moved or deleted on a random skyd, or its connection
 * closed (its views go) and opened again. */
static void view_op(struct change_gen *g)
{
	int i = (int)change_gen_below(g, N_SKYD);
	unsigned what = change_gen_below(g, 6);
	char line[160];

	if (!vopen[i] || what == 0) {
		if (vopen[i])
			conn_close(&vconn[i]);
		vopen[i] = conn_open(&vconn[i], rig.skyd[i]->sock) == 0;
		vnames[i] = 0;
		CHECK(vopen[i]);
		return;
	}
	if (what == 1 && vnames[i]) {
		snprintf(line, sizeof(line), "view del name=v%u", --vnames[i]);
	} else if (vnames[i] < 3) {
		snprintf(line, sizeof(line), "view add name=v%u yaw_deg=%.3f pitch_deg=%.3f%s",
			 vnames[i]++, change_gen_uniform(g, 0, 360), change_gen_uniform(g, -20, 20),
			 change_gen_below(g, 2) ? " form=panorama" : "");
	} else {
		return;
	}
	if (conn_request(&vconn[i], line, reply, sizeof(reply)) != 0)
		FAIL("skyd %d: '%s': %s", i, line, reply);
}

/* Closes the view connections: their views go, a change on each skyd. */
static void views_close(void)
{
	for (int i = 0; i < N_SKYD; i++)
		if (vopen[i]) {
			conn_close(&vconn[i]);
			vopen[i] = 0;
		}
}

/* OPS_PER_ROUND random changes at 0 to 50 ms, then the views closed and
 * the clock stopped at a named time: a skyd's views share the marches of
 * the state's camera (its aerial table is its own while it has some), a
 * running clock moves each machine's lights on its own ticks, and a clock
 * stopped anywhere travels rounded to the microsecond (docs/sync.md). */
static void round_random(uint64_t seed)
{
	struct change_gen g = { .rng = seed, .clock = 1 };
	char line[2048], what[64];
	int64_t t0 = mono_ns(), at = 0;

	snprintf(what, sizeof(what), "seed %llu", (unsigned long long)seed);
	for (int k = 0; k < OPS_PER_ROUND; k++) {
		at += (int64_t)change_gen_uniform(&g, 0, 50.0 * MS);
		pace(t0, at);
		unsigned kind = change_gen_below(&g, 20);
		if (kind < 8)
			change_gen_set(&g, line, sizeof(line));
		else if (kind < 11)
			change_gen_batch(&g, line, sizeof(line));
		else if (kind < 13)
			change_gen_metar(&g, line, sizeof(line));
		else if (kind < 16)
			change_gen_clock(&g, line, sizeof(line));
		else
			line[0] = 0;
		if (line[0])
			change(line);
		else
			view_op(&g);
	}
	views_close();
	snprintf(line, sizeof(line), "set time_rate=0 utc=2026-06-21T%02u:%02u:00Z%s",
		 4 + change_gen_below(&g, 16), change_gen_below(&g, 60),
		 change_gen_below(&g, 2) ? " sun_elevation_deg=12.5" : "");
	change(line);
	check_converged(what);
}

static void scenario_random(uint64_t seed)
{
	printf("seed %llu (SKYD_TEST_SEED=%llu test_sync_converge random reruns it)\n",
	       (unsigned long long)seed, (unsigned long long)seed);
	change("set utc=2026-06-21T06:00:00Z lat_deg=48.2 lon_deg=16.4 time_rate=0");
	for (int r = 0; r < ROUNDS; r++)
		round_random(seed + (uint64_t)r);
	if (test_failures)
		fprintf(stderr, "failed with seed %llu: SKYD_TEST_SEED=%llu test_sync_converge random\n",
			(unsigned long long)seed, (unsigned long long)seed);
}

static int connected(int i)
{
	return sync_status_is(&rig, i, "sync", "connected");
}

int main(int argc, char **argv)
{
	const char *scenario = argc > 1 ? argv[1] : "random";

	if (!sync_have_mosquitto()) {
		printf("skipped: no %s or %s\n", SYNC_MOSQUITTO_BIN, SYNC_MOSQUITTO_PUB);
		return 77;
	}
	harness_need_device();
	if (sync_broker_setup(&rig) < 0) {
		fprintf(stderr, "mosquitto did not start\n");
		return 1;
	}
	for (int i = 0; i < N_SKYD; i++)
		if (sync_skyd_start(&rig, i) < 0) {
			sync_rig_finish(&rig);
			return 1;
		}
	/* Connected: each turn waits on a publication or 100 ms. */
	for (int i = 0; i < N_SKYD; i++)
		for (int k = 0; k < 200 && !connected(i); k++)
			sky_wait(rig.client[i],
				 atomic_load((_Atomic uint32_t *)&sky_header(rig.client[i])->generation),
				 100, NULL);
	if (conn_open(&ctl, rig.skyd[0]->sock) < 0)
		FAIL("no connection to the controller");
	else if (strcmp(scenario, "three") == 0)
		scenario_rising(3, 5 * MS);
	else if (strcmp(scenario, "hundred") == 0)
		scenario_rising(100, 1 * MS);
	else if (strcmp(scenario, "random") == 0)
		scenario_random(change_gen_seed(argc, argv, 2, DEFAULT_SEED));
	else
		FAIL("unknown scenario %s", scenario);
	conn_close(&ctl);
	sync_rig_finish(&rig);
	return test_report(scenario);
}

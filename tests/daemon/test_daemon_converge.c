/* test_daemon_converge.c - one skyd ends on its last change: seeded random
 * interleavings of changes (set, batch, metar, clock rates) from a main
 * connection and from others, subscriptions to random tables and to
 * events, views, closes (polite, abrupt, and right after a request whose
 * reply is never read) and new connections, at random intervals of 0 to
 * 20 ms. Then the last accepted change: get must show the test's mirror of
 * every accepted change, and the last published generation, once nothing
 * is in flight, must hold it: its slot's state and every valid table bit
 * for bit those of a full recompute of the mirror in this process.
 *
 * First each key the rounds change, alone, on a sky that needs every
 * table: what its row invalidates is all that differs from a full
 * recompute.
 *
 * Usage: test_daemon_converge [SEED] (else $SKYD_TEST_SEED, else a fixed
 * one; printed, and printed again on failure with the line that reruns
 * it). Several rounds, each its seed plus its index. The pauses between
 * the requests pace the load and wait for nothing; every wait is on a
 * changed: line. */
#include <math.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>

#include "daemon_harness.h"
#include "eng.h"
#include "pub.h"
#include "skyproto.h"
#include "state.h"
#include "state_geom.h"
#include "test.h"
#include "change_gen.h"

#define ROUNDS 4
#define OPS_PER_ROUND 80
#define N_AUX 4
#define DEFAULT_SEED 20261124

static const char *const small[] = { HARNESS_SMALL, NULL };
static const char *const table_lists[] = {
	"transmittance", "skyview", "aerial", "multiscatter,aerial", "transmittance,skyview",
	"all",
};

static char reply[1 << 16];
static struct daemon d;
static struct conn ctl;			/* changes, and the changed: lines */
static struct conn aux[N_AUX];		/* subscriptions, views, changes, closes */
static int aux_open[N_AUX];
static struct sky_state mirror;		/* every accepted change, as the test made it */
static struct eng *ref_eng;
static uint64_t last_generation;

static int64_t mono_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

/* Waits until t0 + at_ns: the pace of the requests, not a wait for an
 * event. */
static void pace(int64_t t0, int64_t at_ns)
{
	int64_t t = t0 + at_ns;
	struct timespec ts = { .tv_sec = t / 1000000000ll, .tv_nsec = t % 1000000000ll };

	while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
		;
}

/* The pairs of one "set" line onto the mirror; a metar="..." value keeps
 * its spaces, without the quotes. */
static void mirror_set_line(const char *line)
{
	char buf[1024], err[256];
	const char *p = line + 4;

	while (*p) {
		size_t n = strcspn(p, " ");
		if (!strncmp(p, "metar=\"", 7))
			n = (size_t)(strchr(p + 7, '"') - p) + 1;
		snprintf(buf, sizeof(buf), "%.*s", (int)n, p);
		char *q = strchr(buf, '"');
		if (q) {
			memmove(q, q + 1, strlen(q));
			buf[strlen(buf) - 1] = 0;
		}
		if (state_set_pair(&mirror, buf, NULL, err, sizeof(err)) < 0)
			FAIL("mirror: %s: %s", buf, err);
		p += n;
		p += *p == ' ';
	}
}

/* A change (a set line or a batch) on c, mirrored when accepted. */
static void change_on(struct conn *c, const char *req)
{
	int e = conn_request(c, req, reply, sizeof(reply));

	if (e != 0) {
		FAIL("'%s': %d: %s", req, e, reply);
		return;
	}
	for (const char *l = req; l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL)
		if (!strncmp(l, "set ", 4)) {
			char line[1024];
			snprintf(line, sizeof(line), "%.*s", (int)strcspn(l, "\n"), l);
			mirror_set_line(line);
		}
	uint64_t g = reply_u64(reply, "generation");
	if (g != UINT64_MAX && g > last_generation)
		last_generation = g;
}

static void random_change(struct change_gen *g, struct conn *c)
{
	char line[2048];
	unsigned kind = change_gen_below(g, 10);

	if (kind < 5)
		change_gen_set(g, line, sizeof(line));
	else if (kind < 7)
		change_gen_batch(g, line, sizeof(line));
	else if (kind < 8)
		change_gen_metar(g, line, sizeof(line));
	else
		change_gen_clock(g, line, sizeof(line));
	change_on(c, line);
}

/* ---- the other connections ---- */

static void aux_close(int i, unsigned how)
{
	if (how == 0)
		CHECK(conn_request(&aux[i], "close", reply, sizeof(reply)) == 0);
	if (how == 1) {
		/* A request whose reply is never read. */
		const char *req = "view add name=gone yaw_deg=10\n";
		CHECK(send(aux[i].fd, req, strlen(req), MSG_NOSIGNAL) == (ssize_t)strlen(req));
	}
	conn_close(&aux[i]);
	aux_open[i] = 0;
}

/* One thing on a random other connection: open it, subscribe it, a view,
 * a change, or a close. */
static void aux_op(struct change_gen *g)
{
	int i = (int)change_gen_below(g, N_AUX);
	unsigned what = change_gen_below(g, 8);
	char line[160];
	int e = 0;

	if (!aux_open[i]) {
		aux_open[i] = conn_open(&aux[i], d.sock) == 0;
		CHECK(aux_open[i]);
		return;
	}
	if (what < 2) {
		const unsigned n = sizeof(table_lists) / sizeof(table_lists[0]);
		snprintf(line, sizeof(line), "subscribe tables=%s events=%u",
			 table_lists[change_gen_below(g, n)], change_gen_below(g, 2));
		e = conn_request(&aux[i], line, reply, sizeof(reply));
	} else if (what < 4) {
		snprintf(line, sizeof(line), "view add name=a%dv%u yaw_deg=%.3f pitch_deg=%.3f%s", i,
			 change_gen_below(g, 3), change_gen_uniform(g, 0, 360),
			 change_gen_uniform(g, -20, 20), change_gen_below(g, 2) ? " form=panorama" : "");
		e = conn_request(&aux[i], line, reply, sizeof(reply));
		e = e == SKY_ACK_LIMIT ? 0 : e;		/* eight views already */
	} else if (what < 5) {
		snprintf(line, sizeof(line), "view del name=a%dv%u", i, change_gen_below(g, 3));
		e = conn_request(&aux[i], line, reply, sizeof(reply));
		e = e == SKY_ACK_NO_EXIST ? 0 : e;	/* a view it never added */
	} else if (what < 6) {
		random_change(g, &aux[i]);
	} else {
		aux_close(i, change_gen_below(g, 3));
		return;
	}
	if (e != 0)
		FAIL("aux %d: '%s': %d: %s", i, line, e, reply);
}

/* ---- the end ---- */

/* Waits until status shows generation >= g with nothing in flight. */
static void settle(uint64_t g)
{
	CHECK(conn_wait_generation(&ctl, g) == 0);
	for (;;) {
		if (conn_request(&ctl, "status", reply, sizeof(reply)) != 0)
			return;
		if (reply_u64(reply, "computing") == 0 && reply_u64(reply, "pending") == 0)
			return;
		/* A computation is in flight: its changed: line ends it. */
		CHECK(conn_wait_generation(&ctl, ctl.event_generation + 1) == 0);
	}
}

static void emit_get(void *ctx, const char *key, const char *value)
{
	size_t o = strlen(ctx);
	snprintf((char *)ctx + o, 16384 - o, "%s: %s\n", key, value);
}

/* get shows the mirror, line for line. */
static void check_get(const char *what)
{
	static char want[16384];

	want[0] = 0;
	state_foreach(&mirror, emit_get, want);
	if (conn_request(&ctl, "get", reply, sizeof(reply)) != 0) {
		FAIL("%s: get", what);
		return;
	}
	size_t n = strlen(reply) - 3;			/* the OK */
	if (strlen(want) != n || memcmp(want, reply, n)) {
		size_t k = 0;
		while (k < n && want[k] == reply[k])
			k++;
		while (k > 0 && want[k - 1] != '\n')
			k--;
		FAIL("%s: get shows '%.*s', the mirror '%.*s'", what, (int)strcspn(reply + k, "\n"),
		     reply + k, (int)strcspn(want + k, "\n"), want + k);
	}
}

/* The current slot of the region c received last: the mirror's state and,
 * for every valid table, the bytes of a full recompute. */
static void check_slot(struct conn *c, const char *what)
{
	struct sky_state sky;
	struct state_lights lights;
	struct sky_shm_state want;
	struct eng_timing t;
	struct stat st;
	char err[256];

	if (c->n_fds < 1 || fstat(c->fds[c->n_fds - 1], &st) < 0) {
		FAIL("%s: no region", what);
		return;
	}
	const uint8_t *map = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED,
				  c->fds[c->n_fds - 1], 0);
	if (map == MAP_FAILED) {
		FAIL("%s: mmap", what);
		return;
	}
	const struct sky_shm_header *h = (const void *)map;
	uint32_t cur = __atomic_load_n(&h->current_slot, __ATOMIC_ACQUIRE);
	const uint8_t *base = map + h->header_bytes + (uint64_t)cur * h->slot_bytes;
	const struct sky_shm_slot *slot = (const void *)base;
	if (state_resolve(&mirror, &sky, NULL, err, sizeof(err)) < 0 ||
	    eng_compute(ref_eng, &sky, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("%s: reference: %s", what, err);
		munmap((void *)map, (size_t)st.st_size);
		return;
	}
	state_lights_of(&mirror, &lights);
	pub_shm_state(&sky, &lights, &want);
	/* With a drawn layer the slot holds the cloud tables too. */
	CHECK_EQ(slot->valid_tables,
		 STATE_ALL_TABLES | (state_clouds_drawn(&sky) ? (uint32_t)STATE_CLOUD_TABLES : 0u));
	CHECK(slot->generation >= last_generation);
	if (memcmp(&slot->state, &want, sizeof(want)))
		FAIL("%s: the slot's state is not the last change's", what);
	for (int i = 0; i < STATE_N_TABLES; i++) {
		size_t bytes;
		const void *ref = eng_table(ref_eng, (enum state_table)i, &bytes);
		if ((slot->valid_tables & STATE_BIT(i)) &&
		    (bytes < h->tables[i].bytes || memcmp(ref, base + h->tables[i].offset, h->tables[i].bytes)))
			FAIL("%s: %s is not a full recompute of the last change", what,
			     state_table_names[i]);
	}
	for (int i = STATE_CLOUD_COVERAGE; i <= STATE_CLOUD_SHADOW; i++) {
		size_t bytes = 0;
		const void *ref = eng_cloud_table(ref_eng, i, &bytes);
		if ((slot->valid_tables & STATE_BIT(i)) &&
		    (!ref || bytes < h->tables[i].bytes || memcmp(ref, base + h->tables[i].offset, h->tables[i].bytes)))
			FAIL("%s: cloud table %d is not a full recompute of the last change", what, i);
	}
	munmap((void *)map, (size_t)st.st_size);
}

/* Each key the rounds change, alone, on a sky that needs every table:
 * what it invalidates is all that differs from a full recompute. */
static void keys_alone(void)
{
	const size_t n = sizeof(change_keys) / sizeof(change_keys[0]);
	struct conn all;
	char line[160], what[96];

	if (conn_open(&all, d.sock) < 0 ||
	    conn_request(&all, "subscribe tables=all", reply, sizeof(reply)) != 0) {
		FAIL("keys alone: subscribe tables=all");
		return;
	}
	for (size_t k = 0; k < n; k++) {
		const struct change_key *key = &change_keys[k];
		if (key->clock)
			continue;
		snprintf(line, sizeof(line), "set %s=%.6g", key->name, 0.3 * key->lo + 0.7 * key->hi);
		snprintf(what, sizeof(what), "%s alone", key->name);
		change_on(&ctl, line);
		settle(last_generation);
		CHECK(conn_request(&all, "ping", reply, sizeof(reply)) == 0);
		check_get(what);
		check_slot(&all, what);
	}
	conn_close(&all);
}

/* A round: OPS_PER_ROUND random things, the other connections closed
 * (their views go: a skyd's views share the marches of its aerial table),
 * one last change, then what it must show. */
static void round_random(uint64_t seed)
{
	struct change_gen g = { .rng = seed, .clock = 0 };
	struct conn all;
	char what[64];
	int64_t t0 = mono_ns(), at = 0;

	snprintf(what, sizeof(what), "seed %llu", (unsigned long long)seed);
	for (int k = 0; k < OPS_PER_ROUND; k++) {
		at += (int64_t)change_gen_uniform(&g, 0, 20e6);
		pace(t0, at);
		if (change_gen_below(&g, 2))
			random_change(&g, &ctl);
		else
			aux_op(&g);
	}
	for (int i = 0; i < N_AUX; i++)
		if (aux_open[i])
			aux_close(i, 2);
	random_change(&g, &ctl);
	/* The whole region, with the changes made: every table is needed. */
	if (conn_open(&all, d.sock) < 0 ||
	    conn_request(&all, "subscribe tables=all", reply, sizeof(reply)) != 0) {
		FAIL("%s: subscribe tables=all", what);
		return;
	}
	settle(reply_u64(reply, "generation"));
	/* A new region (the views gone) came to all with a layout: line. */
	CHECK(conn_request(&all, "ping", reply, sizeof(reply)) == 0);
	check_get(what);
	check_slot(&all, what);
	conn_close(&all);
}

int main(int argc, char **argv)
{
	uint64_t seed = change_gen_seed(argc, argv, 1, DEFAULT_SEED);
	char err[256];

	harness_need_device();
	if (eng_new(NULL, err, sizeof(err), &ref_eng) < 0) {
		printf("skipped: %s\n", err);
		return 77;
	}
	printf("seed %llu (SKYD_TEST_SEED=%llu test_daemon_converge reruns it)\n",
	       (unsigned long long)seed, (unsigned long long)seed);
	state_default(&mirror);
	for (int i = 0; small[i]; i++)
		if (state_set_pair(&mirror, small[i], NULL, err, sizeof(err)) < 0)
			FAIL("mirror %s: %s", small[i], err);
	if (daemon_start(&d, small) < 0 || conn_open(&ctl, d.sock) < 0 ||
	    conn_request(&ctl, "subscribe events=1", reply, sizeof(reply)) != 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_converge");
	}
	keys_alone();
	for (int r = 0; r < ROUNDS; r++)
		round_random(seed + (uint64_t)r);
	conn_close(&ctl);
	daemon_cleanup(&d);
	eng_free(ref_eng);
	if (test_failures)
		fprintf(stderr, "failed with seed %llu: SKYD_TEST_SEED=%llu test_daemon_converge\n",
			(unsigned long long)seed, (unsigned long long)seed);
	return test_report("test_daemon_converge");
}

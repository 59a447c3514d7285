/* test_sync_broker.c - replication through a real MQTT broker: a mosquitto
 * started by the test on a free loopback port, a controller and followers
 * (sync_new) on one event loop of this process.
 *
 * One scenario per run, named by the first argument:
 *   replicate  followers reach the controller's state, bit for bit, with
 *              its sequence, generation and apply time, through a burst of
 *              changes; two states under one generation both arrive;
 *   latejoin   a follower started later, and one restarted, get the
 *              retained state at once, with no new publication;
 *   restart    the broker killed: everyone goes lost, attempts back off,
 *              the broker back: connected again, and the next change
 *              arrives;
 *   hostile    garbage, an unknown version, out-of-range values, an
 *              unknown key, a second controller and a stale sequence are
 *              ignored and counted, the followers' state untouched;
 *   secrets    username and password reach the broker (a wrong one is
 *              refused), and no password appears in the log (captured);
 *   tls        mqtts:// with a CA made by openssl, by name and by address;
 *              a client with the wrong CA never connects;
 *   standby    a second controller stands by and follows, takes over when
 *              the first one leaves, and the followers follow it.
 * Exit 77 when /usr/sbin/mosquitto (or, for tls, openssl; for secrets,
 * mosquitto_passwd) is missing. Every wait is on a loop event, bounded by
 * a guard timer; the broker is ready when it accepts a connection. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <pwd.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <mosquitto.h>

#include "log.h"
#include "loopback.h"
#include "loop.h"
#include "state.h"
#include "sync.h"
#include "state_compare.h"
#include "test.h"

#define MOSQUITTO_BIN "/usr/sbin/mosquitto"
#define PASSWD_BIN "/usr/bin/mosquitto_passwd"
#define PREFIX "skytest/sky"
#define GUARD_S 20
#define S_NS 1000000000ull

/* ---- the broker ---- */

struct broker {
	pid_t pid;
	int port;
	int out_fd;		/* its stdout and stderr: EOF when it dies */
	char dir[64];
	char conf[128];
};

static struct broker broker = { .pid = -1, .out_fd = -1 };

/* Writes the broker's configuration: a loopback listener, no
 * persistence (a restarted broker has lost every retained message), its
 * log in a file, plus extra. */
static int broker_configure(const char *extra)
{
	struct passwd *pw = getpwuid(getuid());
	char path[160];

	snprintf(broker.conf, sizeof(broker.conf), "%s/mosquitto.conf", broker.dir);
	snprintf(path, sizeof(path), "%s/broker.log", broker.dir);
	FILE *f = fopen(broker.conf, "w");
	if (!f)
		return -errno;
	fprintf(f, "listener %d 127.0.0.1\npersistence false\nlog_dest file %s\n", broker.port,
		path);
	if (pw)
		fprintf(f, "user %s\n", pw->pw_name);	/* as root it would become "mosquitto" */
	fprintf(f, "%s", extra ? extra : "allow_anonymous true\n");
	return fclose(f) == 0 ? 0 : -EIO;
}

/* Starts the broker and waits until it accepts a TCP connection: one
 * attempt, then up to 10 ms on its output pipe, which also tells of its
 * death. */
static int broker_start(void)
{
	int p[2];

	if (pipe2(p, O_CLOEXEC) < 0)
		return -errno;
	pid_t pid = fork();
	if (pid == 0) {
		dup2(p[1], 1);
		dup2(p[1], 2);
		execl(MOSQUITTO_BIN, "mosquitto", "-c", broker.conf, (char *)NULL);
		_exit(127);
	}
	close(p[1]);
	if (pid < 0) {
		close(p[0]);
		return -errno;
	}
	broker.pid = pid;
	broker.out_fd = p[0];
	uint64_t deadline = loop_now_ns() + 10 * S_NS;
	while (loop_now_ns() < deadline) {
		if (loopback_accepts(broker.port))
			return 0;
		struct pollfd pfd = { .fd = broker.out_fd, .events = POLLIN };
		char buf[512];
		if (poll(&pfd, 1, 10) > 0 && read(broker.out_fd, buf, sizeof(buf)) == 0) {
			FAIL("the broker exited (see %s/broker.log)", broker.dir);
			return -ECHILD;
		}
	}
	return -ETIMEDOUT;
}

static void broker_kill(void)
{
	if (broker.pid > 0) {
		kill(broker.pid, SIGKILL);
		waitpid(broker.pid, NULL, 0);
		broker.pid = -1;
	}
	if (broker.out_fd >= 0)
		close(broker.out_fd);
	broker.out_fd = -1;
}

/* Runs a program to its end, its output thrown away; its exit status. */
static int run(const char *const argv[])
{
	pid_t pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_WRONLY);
		dup2(null, 1);
		dup2(null, 2);
		execv(argv[0], (char *const *)argv);
		_exit(127);
	}
	int status = 0;
	if (pid < 0 || waitpid(pid, &status, 0) < 0)
		return -1;
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* ---- nodes: sync instances on the loop ---- */

struct node {
	const char *name;
	struct sync *s;
	struct sky_state state;		/* the last one on_state handed over */
	uint64_t seq, gen;
	int64_t apply_ns;
	char from[SYNC_ID_MAX];		/* the controller of seq */
	unsigned n_states;
	enum sync_state seen;
	char trail[64];			/* the states seen, one letter each: c C L */
	uint64_t attempts;
	uint64_t attempt_ns[16];	/* when each attempt began */
	unsigned n_attempts;
};

static struct loop *loop;
static struct loop_timer *guard;
static struct sync_config base;
static int (*until)(void);
static int timed_out;

static void poke(void)
{
	if (until && until())
		loop_quit(loop);
}

static void guard_fired(void *ctx)
{
	timed_out = 1;
	loop_quit(loop);
}

/* Runs the loop until pred holds (1) or the guard fires (0, a failure). */
static int wait_for(int (*pred)(void), const char *what)
{
	if (pred())
		return 1;
	until = pred;
	timed_out = 0;
	loop_timer_arm(guard, GUARD_S * S_NS);
	loop_run(loop);
	loop_timer_arm(guard, 0);
	until = NULL;
	if (timed_out) {
		FAIL("timed out waiting for %s", what);
		return 0;
	}
	return 1;
}

static void node_state(void *ctx, const struct sky_state *c, const struct sync_msg_header *h)
{
	struct node *n = ctx;

	if (h->sequence <= n->seq && strcmp(h->controller, n->from) == 0)
		FAIL("%s: state %llu after %llu", n->name, (unsigned long long)h->sequence,
		     (unsigned long long)n->seq);
	snprintf(n->from, sizeof(n->from), "%s", h->controller);
	n->state = *c;
	n->seq = h->sequence;
	n->gen = h->generation;
	n->apply_ns = h->apply_time_ns;
	n->n_states++;
	poke();
}

static void node_status(void *ctx)
{
	struct node *n = ctx;
	struct sync_status st;

	sync_get_status(n->s, &st);
	if (st.state != n->seen) {
		size_t k = strlen(n->trail);
		if (k + 1 < sizeof(n->trail))
			n->trail[k] = "OcCL"[st.state];
		n->seen = st.state;
	}
	if (st.attempts != n->attempts) {
		n->attempts = st.attempts;
		if (n->n_attempts < 16)
			n->attempt_ns[n->n_attempts++] = loop_now_ns();
	}
	poke();
}

static void node_start_cfg(struct node *n, const char *name, const struct sync_config *cfg)
{
	struct sync_callbacks cb = { node_state, node_status, n };

	memset(n, 0, sizeof(*n));
	n->name = name;
	if (sync_new(loop, cfg, &cb, &n->s) < 0)
		FAIL("%s: sync_new", name);
}

static void node_start(struct node *n, const char *name, enum sync_role role)
{
	struct sync_config c = base;
	c.role = role;
	node_start_cfg(n, name, &c);
}

static void node_stop(struct node *n)
{
	sync_free(n->s);
	n->s = NULL;
}

static struct sync_status status(const struct node *n)
{
	struct sync_status st;
	sync_get_status(n->s, &st);
	return st;
}

/* Connected; a controller holds the claim; a follower knows its online
 * controller. */
static int ready(const struct node *n)
{
	struct sync_status st = status(n);
	if (st.state != SYNC_CONNECTED)
		return 0;
	return st.role == SYNC_CONTROLLER ? st.active : st.controller[0] && st.controller_online;
}

/* ---- states ---- */

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s: %s", pair, err);
}

static struct sky_state scene(double sun_elevation_deg)
{
	struct sky_state s;
	char pair[64];

	state_default(&s);
	set(&s, "lat_deg=46.5197");
	set(&s, "lon_deg=6.6323");
	set(&s, "utc=2026-03-20T06:00:00Z");
	snprintf(pair, sizeof(pair), "moon_elevation_deg=%.3f", sun_elevation_deg);
	set(&s, pair);
	set(&s, "mie_g=0.76");
	set(&s, "camera_yaw_deg=210.5");
	return s;
}

/* ---- the nodes a scenario uses, and what it waits for ---- */

static struct node ctl, f1, f2, f3;
static uint64_t want_gen;

static int ready_ctl_f1(void)
{
	return ready(&ctl) && ready(&f1);
}

static int ready_all3(void)
{
	return ready(&ctl) && ready(&f1) && ready(&f2);
}

static int f12_have_gen(void)
{
	return f1.gen == want_gen && f2.gen == want_gen;
}

static uint64_t want_seq;

static int f12_have_seq(void)
{
	return f1.seq == want_seq && f2.seq == want_seq;
}

static int ctl_published_gen(void)
{
	return status(&ctl).generation == want_gen;
}

static void publish(struct node *n, const struct sky_state *s, uint64_t gen)
{
	int64_t apply = sync_apply_time_ns(n->s);
	if (sync_publish(n->s, s, gen, apply) != 0)
		FAIL("%s: sync_publish %llu", n->name, (unsigned long long)gen);
}

static void check_same(const struct node *n, const struct sky_state *s)
{
	const char *f = state_compare(&n->state, s);
	if (f)
		FAIL("%s: %s differs from the controller's", n->name, f);
}

/* ---- scenarios ---- */

static void scenario_replicate(void)
{
	node_start(&ctl, "controller", SYNC_CONTROLLER);
	node_start(&f1, "follower 1", SYNC_FOLLOWER);
	node_start(&f2, "follower 2", SYNC_FOLLOWER);
	if (!wait_for(ready_all3, "the controller and two followers"))
		return;
	struct sync_status sc = status(&ctl), s1 = status(&f1);
	CHECK(strcmp(s1.controller, sc.self) == 0 && strcmp(status(&f2).controller, sc.self) == 0);

	struct sky_state a = scene(12.5);
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	int64_t now = (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
	int64_t apply = sync_apply_time_ns(ctl.s);
	CHECK(apply - now >= 300000000ll && apply - now < 400000000ll);	/* the default lead */
	CHECK(sync_publish(ctl.s, &a, 1, apply) == 0);
	want_gen = 1;
	if (!wait_for(f12_have_gen, "generation 1 on both followers"))
		return;
	check_same(&f1, &a);
	check_same(&f2, &a);
	CHECK(f1.apply_ns == apply && f2.apply_ns == apply);

	/* A burst: the latest arrives; at most one is in flight, so some in
	 * between may never be sent. */
	struct sky_state b;
	for (unsigned g = 2; g <= 20; g++) {
		b = scene(10.0 + g);
		publish(&ctl, &b, g);
	}
	want_gen = 20;
	if (!wait_for(f12_have_gen, "generation 20 on both followers") ||
	    !wait_for(ctl_published_gen, "the controller's acknowledgement of 20"))
		return;
	check_same(&f1, &b);
	check_same(&f2, &b);
	CHECK(f1.n_states >= 2 && f1.n_states <= 20);

	s1 = status(&f1);
	sc = status(&ctl);
	CHECK(s1.generation == 20 && s1.applied == f1.n_states && s1.age_ns < 10 * S_NS);
	for (int d = 1; d < SYNC_DROP_N; d++)
		CHECK(s1.dropped[d] == 0 && sc.dropped[d] == 0);
	CHECK(sc.published >= 2 && sc.published <= 20 && sc.active && s1.active == 0);
	CHECK_EQ(s1.sequence, sc.sequence);
	char who[SYNC_ID_MAX] = "";
	CHECK(sync_may_change(ctl.s, who, sizeof(who)) == 1);
	CHECK(sync_may_change(f1.s, who, sizeof(who)) == 0 && strcmp(who, sc.self) == 0);
	CHECK(sync_publish(f1.s, &a, 21, apply) == -EPERM);

	/* Two states under one generation, each sent (changes that come
	 * while a computation is in flight share the next one): each is a
	 * new state, none a duplicate; a generation never goes back. */
	for (int k = 1; k <= 2; k++) {
		b = scene(40.0 + k);
		CHECK(sync_publish(ctl.s, &b, 20, sync_apply_time_ns(ctl.s)) == 0);
		want_seq = sc.sequence + (uint64_t)k;
		if (!wait_for(f12_have_seq, "a new state under generation 20"))
			return;
		check_same(&f1, &b);
		check_same(&f2, &b);
	}
	CHECK(status(&f1).duplicates == s1.duplicates && f1.gen == 20 && f2.gen == 20);
	CHECK(sync_publish(ctl.s, &b, 19, sync_apply_time_ns(ctl.s)) == -EINVAL);
}

static int f3_has_gen(void)
{
	return f3.gen == want_gen;
}

static int f1_has_gen(void)
{
	return f1.gen == want_gen;
}

static void scenario_latejoin(void)
{
	node_start(&ctl, "controller", SYNC_CONTROLLER);
	node_start(&f1, "follower 1", SYNC_FOLLOWER);
	if (!wait_for(ready_ctl_f1, "the controller and a follower"))
		return;
	struct sky_state a = scene(-4.0);
	publish(&ctl, &a, 5);
	want_gen = 5;
	if (!wait_for(f1_has_gen, "generation 5") ||
	    !wait_for(ctl_published_gen, "the controller's acknowledgement"))
		return;
	uint64_t published = status(&ctl).published;

	uint64_t t0 = loop_now_ns();
	node_start(&f3, "late follower", SYNC_FOLLOWER);
	if (!wait_for(f3_has_gen, "the retained state on the late follower"))
		return;
	CHECK(loop_now_ns() - t0 < 2 * S_NS);
	CHECK(status(&ctl).published == published);	/* it came from the broker */
	check_same(&f3, &a);
	CHECK(f3.n_states == 1);

	/* A follower restarted: a new instance, the state again at once. */
	node_stop(&f1);
	t0 = loop_now_ns();
	node_start(&f1, "restarted follower", SYNC_FOLLOWER);
	if (!wait_for(f1_has_gen, "the retained state on the restarted follower"))
		return;
	CHECK(loop_now_ns() - t0 < 2 * S_NS);
	check_same(&f1, &a);
	node_stop(&f3);
}

static int all3_lost(void)
{
	return status(&ctl).state == SYNC_LOST && status(&f1).state == SYNC_LOST &&
	       status(&f2).state == SYNC_LOST;
}

static int f1_four_attempts_since_loss(void)
{
	return f1.n_attempts >= 5;
}

static void scenario_restart(void)
{
	node_start(&ctl, "controller", SYNC_CONTROLLER);
	node_start(&f1, "follower 1", SYNC_FOLLOWER);
	node_start(&f2, "follower 2", SYNC_FOLLOWER);
	if (!wait_for(ready_all3, "the controller and two followers"))
		return;
	struct sky_state a = scene(3.0);
	publish(&ctl, &a, 1);
	want_gen = 1;
	if (!wait_for(f12_have_gen, "generation 1"))
		return;

	broker_kill();
	if (!wait_for(all3_lost, "everyone to lose the broker"))
		return;
	/* Attempts while the broker is away, each after a longer delay (50 ms
	 * doubled, +-25 %: every gap longer than the one before). */
	f1.n_attempts = 0;
	if (!wait_for(f1_four_attempts_since_loss, "five attempts"))
		return;
	for (unsigned i = 2; i < f1.n_attempts; i++) {
		uint64_t g0 = f1.attempt_ns[i - 1] - f1.attempt_ns[i - 2];
		uint64_t g1 = f1.attempt_ns[i] - f1.attempt_ns[i - 1];
		if (g1 <= g0)
			FAIL("attempt %u after %.0f ms, the one before after %.0f ms", i, g1 / 1e6,
			     g0 / 1e6);
	}
	struct sync_status s1 = status(&f1);
	CHECK(s1.state == SYNC_LOST || s1.state == SYNC_CONNECTING);
	CHECK(s1.why[0] != 0);
	CHECK(f1.n_states == 1 && f1.gen == 1);		/* the last sky stays */

	if (broker_start() < 0) {
		FAIL("the broker did not come back");
		return;
	}
	if (!wait_for(ready_all3, "everyone back"))
		return;
	struct sky_state b = scene(4.0);
	publish(&ctl, &b, 2);
	want_gen = 2;
	if (!wait_for(f12_have_gen, "generation 2 after the broker came back"))
		return;
	check_same(&f1, &b);
	check_same(&f2, &b);
	CHECK(status(&f1).connects == 2 && status(&ctl).connects == 2);
	/* connected, lost, then attempts, then connected again */
	const char *t = strstr(f1.trail, "CL");
	if (!t || !strchr(t, 'c') || f1.trail[strlen(f1.trail) - 1] != 'C')
		FAIL("follower 1 went through %s", f1.trail);
}


/* A plain client of the test's own, blocking: publishes each message with
 * QoS 1 and returns once the broker has acknowledged them all. */
struct raw {
	struct mosquitto *m;
	int acked;
};

static void raw_acked(struct mosquitto *m, void *ctx, int mid)
{
	((struct raw *)ctx)->acked++;
}

static void raw_publish(const char *const *topics, const char *const *payloads,
			const size_t *lens, int n, int retain)
{
	struct raw r = { .acked = 0 };

	r.m = mosquitto_new(NULL, true, &r);
	mosquitto_publish_callback_set(r.m, raw_acked);
	if (!r.m || mosquitto_connect(r.m, "127.0.0.1", broker.port, 10) != MOSQ_ERR_SUCCESS) {
		FAIL("the test's own client cannot connect");
		mosquitto_destroy(r.m);
		return;
	}
	for (int i = 0; i < n; i++)
		mosquitto_publish(r.m, NULL, topics[i], (int)lens[i], payloads[i], 1, retain);
	for (int i = 0; i < 400 && r.acked < n; i++)
		mosquitto_loop(r.m, 50, 1);
	CHECK(r.acked == n);
	mosquitto_disconnect(r.m);
	mosquitto_destroy(r.m);
}

/* A valid message of s under id and sequence seq (its generation the
 * same), with the line of key replaced by repl (NULL: as it is). */
static size_t forge(char *buf, const struct sky_state *s, const char *id, uint64_t seq,
		    const char *key, const char *repl)
{
	struct sync_msg_header h = { .sequence = seq, .generation = seq,
				     .apply_time_ns = sync_apply_time_ns(ctl.s) };
	char tmp[SYNC_MSG_MAX + 1], pat[80];
	size_t len = 0;

	snprintf(h.controller, sizeof(h.controller), "%s", id);
	CHECK(sync_msg_encode(s, &h, tmp, sizeof(tmp), &len) == 0);
	snprintf(pat, sizeof(pat), "\n%s=", key ? key : "");
	char *at = key ? strstr(tmp, pat) : NULL;
	if (!at) {
		memcpy(buf, tmp, len + 1);
		return len;
	}
	at++;
	return (size_t)sprintf(buf, "%.*s%s\n%s", (int)(at - tmp), tmp, repl, strchr(at, '\n') + 1);
}

/* What each follower must have counted, by reason. */
static const uint64_t hostile_want[SYNC_DROP_N] = {
	[SYNC_DROP_MALFORMED] = 2, [SYNC_DROP_VERSION] = 1, [SYNC_DROP_KEY] = 1,
	[SYNC_DROP_RANGE] = 1, [SYNC_DROP_CONTROLLER] = 1, [SYNC_DROP_STALE] = 1,
};

static int drops_are(const struct node *n, const uint64_t *want)
{
	struct sync_status st = status(n);
	for (int d = 1; d < SYNC_DROP_N; d++)
		if (st.dropped[d] != want[d])
			return 0;
	return 1;
}

/* The controller's: its own id's stale message is its own, left alone. */
static const uint64_t hostile_want_ctl[SYNC_DROP_N] = {
	[SYNC_DROP_MALFORMED] = 2, [SYNC_DROP_VERSION] = 1, [SYNC_DROP_KEY] = 1,
	[SYNC_DROP_RANGE] = 1, [SYNC_DROP_CONTROLLER] = 1,
};

static int all_counted(void)
{
	return drops_are(&f1, hostile_want) && drops_are(&f2, hostile_want) &&
	       drops_are(&ctl, hostile_want_ctl);
}

static int f3_refused_intruder(void)
{
	return status(&f3).dropped[SYNC_DROP_CONTROLLER] == 1;
}

static void scenario_hostile(void)
{
	static char m[6][SYNC_MSG_MAX + 1];
	node_start(&ctl, "controller", SYNC_CONTROLLER);
	node_start(&f1, "follower 1", SYNC_FOLLOWER);
	node_start(&f2, "follower 2", SYNC_FOLLOWER);
	if (!wait_for(ready_all3, "the controller and two followers"))
		return;
	/* Two states: the second's sequence is 2, so that 1 is stale. */
	struct sky_state a = scene(20.0);
	publish(&ctl, &a, 1);
	want_gen = 1;
	if (!wait_for(f12_have_gen, "generation 1"))
		return;
	publish(&ctl, &a, 2);
	want_gen = 2;
	if (!wait_for(f12_have_gen, "generation 2") ||
	    !wait_for(ctl_published_gen, "the controller's acknowledgement"))
		return;
	CHECK(f1.seq == 2 && f2.seq == 2);
	const char *id = status(&ctl).self, *intruder = "intruder/1/00000000000000ff";
	char state_topic[] = PREFIX "/state", presence_topic[] = PREFIX "/controller";
	const char *topics[] = { state_topic, state_topic, state_topic, state_topic,
				 state_topic, state_topic, presence_topic };
	size_t lens[7];
	const char *payloads[7] = { "\x00\xff garbage\n", m[0], m[1], m[2], m[3], m[4],
				    "who knows\n" };
	lens[0] = 11;
	lens[1] = forge(m[0], &a, id, 3, NULL, NULL);
	m[0][8] = '3';						/* version 3 */
	lens[2] = forge(m[1], &a, id, 3, "sun_elevation_deg", "sun_elevation_deg=95");
	lens[3] = forge(m[2], &a, id, 3, "mie_g", "mie_gee=0.7");	/* unknown key */
	lens[4] = forge(m[3], &a, intruder, 99, NULL, NULL);	/* a second controller */
	lens[5] = forge(m[4], &a, id, 1, NULL, NULL);		/* older than applied */
	lens[6] = 10;
	raw_publish(topics, payloads, lens, 7, 0);
	if (!wait_for(all_counted, "everyone to count every bad message"))
		return;
	CHECK(f1.n_states == 2 && f1.gen == 2 && f2.n_states == 2 && f2.gen == 2);
	check_same(&f1, &a);
	check_same(&f2, &a);
	struct sync_status s1 = status(&f1), sc = status(&ctl);
	CHECK(s1.last_drop == SYNC_DROP_MALFORMED && strstr(s1.last_drop_why, "presence"));
	CHECK(strcmp(s1.controller, sc.self) == 0);
	CHECK(sc.active && sc.generation == 2);

	/* The followers still follow. */
	struct sky_state b = scene(21.0);
	publish(&ctl, &b, 3);
	want_gen = 3;
	if (!wait_for(f12_have_gen, "generation 3 after the bad messages"))
		return;
	check_same(&f1, &b);

	/* The intruder retained: a late joiner refuses it and waits for the
	 * controller. */
	const char *one[] = { state_topic }, *body[] = { m[3] };
	raw_publish(one, body, &lens[4], 1, 1);
	node_start(&f3, "late follower", SYNC_FOLLOWER);
	if (!wait_for(f3_refused_intruder, "the late follower to refuse the intruder"))
		return;
	CHECK(f3.n_states == 0);
	struct sky_state c = scene(22.0);
	publish(&ctl, &c, 4);
	want_gen = 4;
	if (wait_for(f3_has_gen, "generation 4 on the late follower"))
		check_same(&f3, &c);
	node_stop(&f3);
}

#define GOOD_PASSWORD "Tr0ub4dor&3-sync-secret"
#define BAD_PASSWORD "wr0ng-Secret-zz9-plural"

static int bad_refused(void)
{
	struct sync_status st = status(&f2);
	return st.attempts >= 2 && st.state == SYNC_LOST && strstr(st.why, "refused");
}

/* Whether the bytes of a status hold text. */
static int status_holds(const struct sync_status *st, const char *text)
{
	return memmem(st, sizeof(*st), text, strlen(text)) != NULL;
}

static void scenario_secrets_run(void)
{
	struct sync_config c = base;
	snprintf(c.username, sizeof(c.username), "skyd");
	snprintf(c.password, sizeof(c.password), GOOD_PASSWORD);
	c.role = SYNC_CONTROLLER;
	node_start_cfg(&ctl, "controller", &c);
	c.role = SYNC_FOLLOWER;
	node_start_cfg(&f1, "follower", &c);
	snprintf(c.password, sizeof(c.password), BAD_PASSWORD);
	node_start_cfg(&f2, "follower with the wrong password", &c);
	if (!wait_for(ready_ctl_f1, "the controller and the follower to log in") ||
	    !wait_for(bad_refused, "the wrong password to be refused twice"))
		return;
	struct sky_state a = scene(7.0);
	publish(&ctl, &a, 1);
	want_gen = 1;
	if (!wait_for(f1_has_gen, "generation 1"))
		return;
	check_same(&f1, &a);
	CHECK(f2.n_states == 0);
	struct sync_status st[3] = { status(&ctl), status(&f1), status(&f2) };
	for (int i = 0; i < 3; i++) {
		CHECK(st[i].auth == 1);
		CHECK(!status_holds(&st[i], GOOD_PASSWORD) && !status_holds(&st[i], BAD_PASSWORD));
	}
	CHECK(strstr(st[2].why, "not authorised") != NULL);
}

/* Runs the scenario with the log, at debug level, in a file; then looks
 * for the passwords in it. */
static void scenario_secrets(void)
{
	char passwd[160], log_path[160], extra[256];
	snprintf(passwd, sizeof(passwd), "%s/passwd", broker.dir);
	const char *argv[] = { PASSWD_BIN, "-b", "-c", passwd, "skyd", GOOD_PASSWORD, NULL };
	if (run(argv) != 0) {
		FAIL("mosquitto_passwd failed");
		return;
	}
	snprintf(extra, sizeof(extra), "allow_anonymous false\npassword_file %s\n", passwd);
	broker_kill();
	if (broker_configure(extra) < 0 || broker_start() < 0) {
		FAIL("no broker with a password file");
		return;
	}
	snprintf(log_path, sizeof(log_path), "%s/skyd.log", broker.dir);
	int saved = dup(2), fd = open(log_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
	if (saved < 0 || fd < 0) {
		FAIL("cannot capture the log");
		return;
	}
	log_init(LOG_LEVEL_DEBUG, 0);
	dup2(fd, 2);
	close(fd);
	scenario_secrets_run();
	node_stop(&ctl);
	node_stop(&f1);
	node_stop(&f2);
	fflush(stderr);
	dup2(saved, 2);
	close(saved);

	static char text[1 << 20];
	FILE *f = fopen(log_path, "r");
	size_t n = f ? fread(text, 1, sizeof(text) - 1, f) : 0;
	if (f)
		fclose(f);
	text[n] = 0;
	fprintf(stderr, "---- the log ----\n%s---- end of the log ----\n", text);
	CHECK(strstr(text, "sync: connected") != NULL && strstr(text, "mosquitto:") != NULL);
	CHECK(strstr(text, GOOD_PASSWORD) == NULL && strstr(text, BAD_PASSWORD) == NULL);
	CHECK(strstr(text, "Tr0ub4dor") == NULL && strstr(text, "wr0ng-Secret") == NULL);
}

/* Makes a CA (ca.crt) and a certificate for localhost and 127.0.0.1
 * signed by it (server.crt, server.key), and a second CA (other.crt). */
static int make_certs(void)
{
	char cmd[2048];
	snprintf(cmd, sizeof(cmd),
		 "set -e; cd '%s'; k='-newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes';"
		 "openssl req -x509 $k -keyout ca.key -out ca.crt -days 2 -subj /CN=skysync-test-ca;"
		 "openssl req -x509 $k -keyout other.key -out other.crt -days 2 -subj /CN=other-ca;"
		 "openssl req $k -keyout server.key -out server.csr -subj /CN=localhost;"
		 "printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\\n' > ext;"
		 "openssl x509 -req -in server.csr -CA ca.crt -CAkey ca.key -CAcreateserial"
		 " -out server.crt -days 2 -extfile ext;"
		 "chmod 644 server.key ca.key other.key",
		 broker.dir);
	strcat(cmd, " >/dev/null 2>&1");
	return system(cmd) == 0 ? 0 : -1;
}

/* "localhost" when it names 127.0.0.1 first (the broker listens there
 * only), so that the look-up runs; else the address. */
static const char *tls_host(void)
{
	struct addrinfo hints = { .ai_socktype = SOCK_STREAM }, *res = NULL;
	int local = getaddrinfo("localhost", NULL, &hints, &res) == 0 && res &&
		    res->ai_family == AF_INET &&
		    ((struct sockaddr_in *)res->ai_addr)->sin_addr.s_addr == htonl(INADDR_LOOPBACK);
	if (res)
		freeaddrinfo(res);
	return local ? "localhost" : "127.0.0.1";
}

static int tls_bad_lost(void)
{
	struct sync_status st = status(&f2);
	return st.attempts >= 2 && st.state == SYNC_LOST;
}

static void tls_node(struct node *n, const char *name, enum sync_role role, const char *host,
		     const char *ca)
{
	struct sync_config c;
	char url[160], err[256];
	sync_config_defaults(&c);
	snprintf(url, sizeof(url), "mqtts://%s:%d/%s", host, broker.port, PREFIX);
	CHECK(sync_config_parse_url(&c, url, err, sizeof(err)) == 0);
	snprintf(c.cafile, sizeof(c.cafile), "%s/%s", broker.dir, ca);
	c.role = role;
	c.backoff_min_ms = 50;
	c.backoff_max_ms = 400;
	node_start_cfg(n, name, &c);
}

static void scenario_tls(void)
{
	char extra[512];
	if (make_certs() < 0) {
		FAIL("openssl could not make the certificates");
		return;
	}
	snprintf(extra, sizeof(extra),
		 "allow_anonymous true\ncafile %s/ca.crt\ncertfile %s/server.crt\n"
		 "keyfile %s/server.key\n", broker.dir, broker.dir, broker.dir);
	broker_kill();
	if (broker_configure(extra) < 0 || broker_start() < 0) {
		FAIL("no broker with TLS");
		return;
	}
	tls_node(&ctl, "controller", SYNC_CONTROLLER, tls_host(), "ca.crt");
	tls_node(&f1, "follower", SYNC_FOLLOWER, "127.0.0.1", "ca.crt");
	tls_node(&f2, "follower with the wrong CA", SYNC_FOLLOWER, "127.0.0.1", "other.crt");
	if (!wait_for(ready_ctl_f1, "the TLS connections") ||
	    !wait_for(tls_bad_lost, "the wrong CA to fail twice"))
		return;
	struct sky_state a = scene(15.0);
	publish(&ctl, &a, 1);
	want_gen = 1;
	if (!wait_for(f1_has_gen, "generation 1 over TLS"))
		return;
	check_same(&f1, &a);
	CHECK(status(&ctl).tls && status(&f1).tls && f2.n_states == 0);
	CHECK(status(&f2).connects == 0);
	CHECK(strstr(status(&f2).why, "certificate verify failed") != NULL);
}

static struct node *standby_node;

static int standby_follows(void)
{
	struct sync_status st = status(standby_node);
	return st.state == SYNC_CONNECTED && st.standby && !st.active && st.controller[0] &&
	       st.controller_online && standby_node->gen == want_gen;
}

static int f2_took_over(void)
{
	return status(&f2).active && f1.n_states == 2;
}

static void scenario_standby(void)
{
	node_start(&ctl, "controller 1", SYNC_CONTROLLER);
	node_start(&f1, "follower", SYNC_FOLLOWER);
	if (!wait_for(ready_ctl_f1, "the first controller and the follower"))
		return;
	struct sky_state a = scene(30.0);
	publish(&ctl, &a, 1);
	want_gen = 1;
	if (!wait_for(f1_has_gen, "generation 1"))
		return;
	char first[SYNC_ID_MAX], who[SYNC_ID_MAX] = "";
	snprintf(first, sizeof(first), "%s", status(&ctl).self);

	/* A second controller stands by and follows the first. */
	node_start(&f2, "controller 2", SYNC_CONTROLLER);
	standby_node = &f2;
	if (!wait_for(standby_follows, "the second controller to stand by"))
		return;
	check_same(&f2, &a);
	CHECK(strcmp(status(&f2).controller, first) == 0);
	CHECK(sync_may_change(f2.s, who, sizeof(who)) == 0 && strcmp(who, first) == 0);
	CHECK(sync_may_change(ctl.s, who, sizeof(who)) == 1);
	/* What it commits it hands on, as the first controller's state. */
	CHECK(sync_publish(f2.s, &f2.state, 1, f2.apply_ns) == 0);

	/* The first one leaves: the second claims, publishes, and the
	 * follower takes its state. */
	node_stop(&ctl);
	if (!wait_for(f2_took_over, "the second controller to take over"))
		return;
	struct sync_status s2 = status(&f2), s1 = status(&f1);
	CHECK(strcmp(s1.controller, s2.self) == 0 && s1.controller_online);
	check_same(&f1, &a);
	CHECK(sync_may_change(f2.s, who, sizeof(who)) == 1);

	/* The first one back (a new instance) stands by. */
	node_start(&ctl, "controller 1 again", SYNC_CONTROLLER);
	standby_node = &ctl;
	if (!wait_for(standby_follows, "the returning controller to stand by"))
		return;
	CHECK(strcmp(status(&ctl).controller, s2.self) == 0 && status(&f2).active);
}

static const struct {
	const char *name;
	void (*run)(void);
	const char *needs;
} scenarios[] = {
	{ "replicate", scenario_replicate, NULL },
	{ "latejoin", scenario_latejoin, NULL },
	{ "restart", scenario_restart, NULL },
	{ "hostile", scenario_hostile, NULL },
	{ "secrets", scenario_secrets, PASSWD_BIN },
	{ "tls", scenario_tls, "/usr/bin/openssl" },
	{ "standby", scenario_standby, NULL },
};

static void stop_all(void)
{
	struct node *all[] = { &ctl, &f1, &f2, &f3 };
	for (int i = 0; i < 4; i++)
		if (all[i]->s)
			node_stop(all[i]);
}

int main(int argc, char **argv)
{
	int which = -1;
	char err[256], url[160];

	for (size_t i = 0; argc == 2 && i < sizeof(scenarios) / sizeof(scenarios[0]); i++)
		if (strcmp(argv[1], scenarios[i].name) == 0)
			which = (int)i;
	if (which < 0) {
		fprintf(stderr, "usage: test_sync_broker replicate|latejoin|restart|hostile|"
				"secrets|tls|standby\n");
		return 2;
	}
	if (access(MOSQUITTO_BIN, X_OK) != 0 ||
	    (scenarios[which].needs && access(scenarios[which].needs, X_OK) != 0)) {
		printf("%s is missing\n", access(MOSQUITTO_BIN, X_OK) ? MOSQUITTO_BIN
								     : scenarios[which].needs);
		return 77;
	}
	signal(SIGPIPE, SIG_IGN);
	log_init(LOG_LEVEL_INFO, 0);	/* $SKYD_LOG=debug shows more */
	snprintf(broker.dir, sizeof(broker.dir), "/tmp/test_sync_XXXXXX");
	if (!mkdtemp(broker.dir) || (broker.port = loopback_free_port()) < 0 || broker_configure(NULL) < 0 ||
	    broker_start() < 0) {
		fprintf(stderr, "cannot start mosquitto\n");
		return 1;
	}
	if (loop_new(&loop) < 0 || loop_timer_add(loop, guard_fired, NULL, &guard) < 0)
		return 1;
	sync_config_defaults(&base);
	snprintf(url, sizeof(url), "mqtt://127.0.0.1:%d/%s", broker.port, PREFIX);
	CHECK(sync_config_parse_url(&base, url, err, sizeof(err)) == 0);
	base.backoff_min_ms = 50;
	base.backoff_max_ms = 5000;
	base.keepalive_s = 5;

	scenarios[which].run();

	stop_all();
	loop_timer_del(guard);
	loop_free(loop);
	broker_kill();
	char cmd[128];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", broker.dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", broker.dir);
	return test_report(argv[1]);
}

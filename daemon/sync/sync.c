/* sync.c - the replication client: libmosquitto driven by the daemon's
 * loop, the connection and its back-off, the controller's claim and
 * publications, the follower's checks before a state is handed on.
 *
 * The loop owns the socket: EPOLLIN runs mosquitto_loop_read, EPOLLOUT
 * (asked for only while mosquitto_want_write) mosquitto_loop_write, a
 * one-second timer mosquitto_loop_misc (keep-alive, and the deadline of a
 * connection that never completes). Every entry point ends in settle(),
 * which follows the socket libmosquitto has now, its wish to write and a
 * connection that died underneath. */
#include "sync.h"

#include <arpa/inet.h>
#include <errno.h>
#include <inttypes.h>
#include <netdb.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

#include <mosquitto.h>

#include "log.h"
#include "loop.h"
#include "state.h"

#define MS 1000000ull
#define MISC_PERIOD_NS (1000 * MS)
#define RESOLVE_POLL_NS (10 * MS)
#define TOPIC_MAX (SYNC_PREFIX_MAX + SYNC_ID_MAX + 16)

/* A name lookup in flight (getaddrinfo_a); it owns what the resolver's
 * thread reads and writes, so that it can outlive the client. */
struct lookup {
	struct gaicb cb;
	struct addrinfo hints;
	char host[SYNC_HOST_MAX];
};

struct sync {
	struct loop *loop;
	struct sync_config cfg;
	struct sync_callbacks cb;
	struct mosquitto *m;
	char id[SYNC_ID_MAX];
	char topic_state[TOPIC_MAX], topic_presence[TOPIC_MAX], topic_probe[TOPIC_MAX];

	struct loop_io *io;
	int io_fd;
	uint32_t io_events;
	struct loop_timer *misc_timer, *retry_timer, *resolve_timer;
	struct lookup *lookup;

	enum sync_state state;
	uint32_t backoff_ms;		/* the next delay */
	uint64_t rng;
	char refusal[256];		/* why this attempt failed, when libmosquitto said it:
					 * the broker's CONNACK, a TLS error */
	int last_sub_mid;
	int probe_done;			/* controller: retained presence seen (or none) */
	int active;
	struct sync_presence presence;
	int presence_known;

	/* controller: the latest state to send, named by its sequence (the
	 * last one given); sent_seq: the last one handed to the broker on
	 * this connection, 0 none; inflight_*: the one it has not
	 * acknowledged yet */
	struct sky_state *pending;
	uint64_t seq, pending_gen, sent_seq;
	int64_t pending_apply;
	uint64_t inflight_gen;
	int64_t inflight_apply;
	int inflight_mid;		/* 0: nothing in flight */
	char *buf;			/* SYNC_MSG_MAX + 1 */

	/* follower: what was handed on last */
	char applied_from[SYNC_ID_MAX];
	uint64_t applied_seq;
	struct sky_state *candidate;

	struct sync_status st;
	uint64_t last_mono_ns;		/* when st.generation was applied or published */
	uint64_t drop_logged_ns[SYNC_DROP_N];
	uint64_t drop_quiet[SYNC_DROP_N];
	int status_dirty;
	int depth;			/* loop callbacks under way (settle runs at the end) */
	int closing;
};

static void settle(struct sync *s);
static void start_attempt(struct sync *s);

/* ---- small helpers ---- */

static void mark(struct sync *s)
{
	s->status_dirty = 1;
}

static void set_state(struct sync *s, enum sync_state st)
{
	if (s->state != st) {
		s->state = st;
		mark(s);
	}
}

static const char *mosq_error(int rc)
{
	return rc == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(rc);
}

/* xorshift64*: the back-off's jitter, so that followers that lost the
 * same broker do not all come back in the same millisecond. */
static double random01(struct sync *s)
{
	s->rng ^= s->rng >> 12;
	s->rng ^= s->rng << 25;
	s->rng ^= s->rng >> 27;
	return (double)((s->rng * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

/* HOST/PID/NONCE: the host tells a person which machine it is, the pid
 * and 64 random bits tell a restarted daemon from the one before. */
static void make_id(struct sync *s)
{
	char host[64] = "";
	uint64_t nonce = 0;

	if (gethostname(host, sizeof(host) - 1) < 0 || !host[0])
		snprintf(host, sizeof(host), "host");
	host[48] = 0;
	for (char *p = host; *p; p++)
		if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		      (*p >= '0' && *p <= '9') || *p == '.' || *p == '_' || *p == '-'))
			*p = '-';
	if (getrandom(&nonce, sizeof(nonce), GRND_NONBLOCK) != (ssize_t)sizeof(nonce)) {
		struct timespec ts;
		clock_gettime(CLOCK_REALTIME, &ts);
		nonce = (uint64_t)ts.tv_nsec * 6364136223846793005ull ^ (uint64_t)ts.tv_sec ^
			(uint64_t)getpid() << 32;
	}
	snprintf(s->id, sizeof(s->id), "%s/%d/%016" PRIx64, host, (int)getpid(), nonce);
	s->rng = nonce | 1;
}

/* One warning per reason and second at most: a flood of garbage must not
 * flood the journal. The counters count every one. */
static void count_drop(struct sync *s, enum sync_drop d, const char *what, const char *why)
{
	uint64_t now = loop_now_ns();

	s->st.dropped[d]++;
	s->st.last_drop = d;
	snprintf(s->st.last_drop_why, sizeof(s->st.last_drop_why), "%s: %s", what, why);
	mark(s);
	if (s->drop_logged_ns[d] && now - s->drop_logged_ns[d] < 1000 * MS) {
		s->drop_quiet[d]++;
		return;
	}
	if (s->drop_quiet[d])
		log_warning("sync: ignored %s on %s (%s): %s (and %" PRIu64 " more since)", what,
			    s->cfg.prefix, sync_drop_name(d), why, s->drop_quiet[d]);
	else
		log_warning("sync: ignored %s on %s (%s): %s", what, s->cfg.prefix,
			    sync_drop_name(d), why);
	s->drop_logged_ns[d] = now;
	s->drop_quiet[d] = 0;
}

/* ---- the connection ---- */

/* The connection is gone, or the attempt failed: stop watching the
 * socket, forget the claim and what was in flight, and try again after
 * the back-off, which doubles for the next time. Only the loss of an
 * established connection is a warning. */
static void connection_lost(struct sync *s, const char *why)
{
	int was_connected = s->state == SYNC_CONNECTED;

	if (s->state == SYNC_LOST)
		return;		/* told twice (a hang-up, then libmosquitto) */
	if (s->io) {
		loop_io_del(s->io);
		s->io = NULL;
	}
	loop_timer_arm(s->misc_timer, 0);
	s->active = 0;
	s->probe_done = 0;
	s->inflight_mid = 0;
	snprintf(s->st.why, sizeof(s->st.why), "%s", s->refusal[0] ? s->refusal : why);
	set_state(s, SYNC_LOST);
	mark(s);
	if (s->closing)
		return;
	uint32_t delay = (uint32_t)(s->backoff_ms * (0.75 + 0.5 * random01(s)));
	if (delay < s->cfg.backoff_min_ms)
		delay = s->cfg.backoff_min_ms;
	s->st.backoff_ms = delay;
	if (was_connected)
		log_warning("sync: lost the broker %s:%u: %s; next attempt in %u ms", s->cfg.host,
			    s->cfg.port, s->st.why, delay);
	else
		log_info("sync: no connection to %s:%u: %s; next attempt in %u ms", s->cfg.host,
			 s->cfg.port, s->st.why, delay);
	loop_timer_arm(s->retry_timer, (uint64_t)delay * MS);
	s->backoff_ms = s->backoff_ms > s->cfg.backoff_max_ms / 2 ? s->cfg.backoff_max_ms
								    : s->backoff_ms * 2;
}

static void fd_ready(void *ctx, uint32_t events)
{
	struct sync *s = ctx;

	s->depth++;
	if (events & (EPOLLIN | EPOLLERR | EPOLLHUP))
		mosquitto_loop_read(s->m, 1);
	if ((events & EPOLLOUT) && mosquitto_socket(s->m) >= 0) {
		mosquitto_loop_write(s->m, 1);
		/* A TLS handshake moves on in loop_read only, whichever way
		 * the socket was waiting; elsewhere a read finds nothing. */
		if (mosquitto_socket(s->m) >= 0)
			mosquitto_loop_read(s->m, 1);
	}
	/* An error or hang-up that libmosquitto did not act on (a TLS
	 * handshake keeps asking for more) ends the connection here, or the
	 * level-triggered event would come back at once, for ever. */
	if ((events & (EPOLLERR | EPOLLHUP)) && mosquitto_socket(s->m) >= 0 &&
	    s->state != SYNC_LOST)
		connection_lost(s, "the connection failed");
	s->depth--;
	settle(s);
}

static void misc_fired(void *ctx)
{
	struct sync *s = ctx;

	s->depth++;
	if (mosquitto_socket(s->m) >= 0)
		mosquitto_loop_misc(s->m);
	if (mosquitto_socket(s->m) >= 0 && s->state != SYNC_LOST)
		loop_timer_arm(s->misc_timer, MISC_PERIOD_NS);
	s->depth--;
	settle(s);
}

/* Connects (the name already looked up when it is one). */
static void connect_now(struct sync *s)
{
	int rc = mosquitto_connect_async(s->m, s->cfg.host, s->cfg.port, (int)s->cfg.keepalive_s);

	if (rc != MOSQ_ERR_SUCCESS)
		connection_lost(s, mosq_error(rc));
}

static void lookup_fired(void *ctx)
{
	struct sync *s = ctx;
	struct lookup *q = s->lookup;
	int r = gai_error(&q->cb);

	if (r == EAI_INPROGRESS) {
		loop_timer_arm(s->resolve_timer, RESOLVE_POLL_NS);
		return;
	}
	if (q->cb.ar_result)
		freeaddrinfo(q->cb.ar_result);
	free(q);
	s->lookup = NULL;
	if (r == 0)
		connect_now(s);
	else
		connection_lost(s, gai_strerror(r));
	settle(s);
}

static int host_numeric(const char *h)
{
	unsigned char a[16];
	return inet_pton(AF_INET, h, a) == 1 || inet_pton(AF_INET6, h, a) == 1;
}

/* libmosquitto looks names up with getaddrinfo, which waits for the
 * resolver. The name is looked up first without waiting (getaddrinfo_a,
 * polled): a resolver that does not answer costs a failed attempt, never
 * the loop; libmosquitto's own lookup then finds a fresh answer. */
static void start_lookup(struct sync *s)
{
	struct lookup *q = calloc(1, sizeof(*q));
	struct gaicb *list[1];

	if (!q) {
		connection_lost(s, strerror(ENOMEM));
		return;
	}
	snprintf(q->host, sizeof(q->host), "%s", s->cfg.host);
	q->hints.ai_family = AF_UNSPEC;
	q->hints.ai_socktype = SOCK_STREAM;
	q->cb.ar_name = q->host;
	q->cb.ar_request = &q->hints;
	list[0] = &q->cb;
	int r = getaddrinfo_a(GAI_NOWAIT, list, 1, NULL);
	if (r != 0) {
		free(q);
		connection_lost(s, gai_strerror(r));
		return;
	}
	s->lookup = q;
	loop_timer_arm(s->resolve_timer, RESOLVE_POLL_NS);
}

static void start_attempt(struct sync *s)
{
	s->st.attempts++;
	s->refusal[0] = 0;
	set_state(s, SYNC_CONNECTING);
	log_debug("sync: connecting to %s:%u (attempt %" PRIu64 ")", s->cfg.host, s->cfg.port,
		  s->st.attempts);
	if (host_numeric(s->cfg.host))
		connect_now(s);
	else
		start_lookup(s);
}

static void retry_fired(void *ctx)
{
	struct sync *s = ctx;

	start_attempt(s);
	settle(s);
}

/* Follows libmosquitto's socket: a new one joins the loop, a closed one
 * leaves it; EPOLLOUT only while it has something to write. */
static void watch(struct sync *s)
{
	int fd = mosquitto_socket(s->m);

	if (s->io && s->io_fd != fd) {
		loop_io_del(s->io);
		s->io = NULL;
	}
	if (fd < 0)
		return;
	uint32_t ev = EPOLLIN | (mosquitto_want_write(s->m) ? EPOLLOUT : 0);
	if (!s->io) {
		if (loop_io_add(s->loop, fd, ev, fd_ready, s, &s->io) < 0) {
			s->io = NULL;
			connection_lost(s, "cannot watch the socket");
			return;
		}
		s->io_fd = fd;
		s->io_events = ev;
		loop_timer_arm(s->misc_timer, MISC_PERIOD_NS);
	} else if (ev != s->io_events && loop_io_mod(s->io, ev) == 0) {
		s->io_events = ev;
	}
}

static void settle(struct sync *s)
{
	if (mosquitto_socket(s->m) < 0 && !s->lookup &&
	    (s->state == SYNC_CONNECTING || s->state == SYNC_CONNECTED))
		connection_lost(s, "the connection closed");
	if (s->state != SYNC_LOST)
		watch(s);
	if (s->status_dirty && !s->closing) {
		s->status_dirty = 0;
		if (s->cb.on_status)
			s->cb.on_status(s->cb.ctx);
	}
}

/* ---- the controller ---- */

/* Sends the latest state if this instance may and nothing is in flight. */
static void send_pending(struct sync *s)
{
	struct sync_msg_header h = { .sequence = s->seq, .generation = s->pending_gen,
				     .apply_time_ns = s->pending_apply };
	size_t len;
	int mid = 0;

	if (s->cfg.role != SYNC_CONTROLLER || !s->active || s->state != SYNC_CONNECTED ||
	    !s->pending || s->inflight_mid || s->seq == s->sent_seq)
		return;
	snprintf(h.controller, sizeof(h.controller), "%s", s->id);
	int r = sync_msg_encode(s->pending, &h, s->buf, SYNC_MSG_MAX + 1, &len);
	if (r < 0) {
		log_error("sync: cannot write state %" PRIu64 " (generation %" PRIu64 "): %s",
			  s->seq, s->pending_gen, strerror(-r));
		s->sent_seq = s->seq;
		return;
	}
	int rc = mosquitto_publish(s->m, &mid, s->topic_state, (int)len, s->buf, 1, true);
	if (rc != MOSQ_ERR_SUCCESS) {
		log_warning("sync: publishing state %" PRIu64 " (generation %" PRIu64 "): %s",
			    s->seq, s->pending_gen, mosq_error(rc));
		return;
	}
	s->inflight_mid = mid ? mid : -1;
	s->inflight_gen = s->pending_gen;
	s->inflight_apply = s->pending_apply;
	s->sent_seq = s->seq;
}

static void publish_presence(struct sync *s, int online)
{
	struct sync_presence p = { .online = online };
	char buf[256];
	size_t len;

	snprintf(p.controller, sizeof(p.controller), "%s", s->id);
	if (sync_presence_encode(&p, buf, sizeof(buf), &len) == 0)
		mosquitto_publish(s->m, NULL, s->topic_presence, (int)len, buf, 1, true);
}

static void claim(struct sync *s)
{
	publish_presence(s, 1);
	s->active = 1;
	mark(s);
	log_info("sync: controller of %s (%s)", s->cfg.prefix, s->id);
	send_pending(s);
}

/* The latest presence decides: this instance is active while it names
 * this instance; another online controller makes it stand by (of two that
 * claimed at once, the one the broker took last wins, and both see that);
 * an offline one or none lets it claim. */
static void reconsider(struct sync *s)
{
	int self = strcmp(s->presence.controller, s->id) == 0;

	if (self && s->presence.online) {
		if (!s->active) {
			s->active = 1;
			mark(s);
			send_pending(s);
		}
	} else if (!self && s->presence.online && s->presence.controller[0]) {
		if (s->active)
			log_warning("sync: controller %s took %s; standing by",
				    s->presence.controller, s->cfg.prefix);
		else
			log_info("sync: controller %s holds %s; standing by",
				 s->presence.controller, s->cfg.prefix);
		s->active = 0;
		mark(s);
	} else if (!s->active) {
		claim(s);
	}
}

/* ---- what arrives ---- */

static void on_presence(struct sync *s, const struct mosquitto_message *msg)
{
	struct sync_presence p;
	char why[160];
	enum sync_drop d = sync_presence_decode(msg->payload, (size_t)msg->payloadlen, &p, why,
						sizeof(why));

	if (d) {
		count_drop(s, d, "a presence", why);
		return;
	}
	if ((strcmp(p.controller, s->presence.controller) || p.online != s->presence.online) &&
	    strcmp(p.controller, s->id) != 0)
		log_info("sync: %s: controller %s %s", s->cfg.prefix,
			 p.controller[0] ? p.controller : "(none)", p.online ? "online" : "offline");
	s->presence = p;
	s->presence_known = 1;
	mark(s);
	if (s->cfg.role == SYNC_CONTROLLER && s->probe_done)
		reconsider(s);
}

/* Whether a decoded state from h->controller is the one to hand on. */
static enum sync_drop accept_state(struct sync *s, const struct sync_msg_header *h, char *why,
				   size_t why_size)
{
	if (s->cfg.role == SYNC_CONTROLLER && s->active) {
		snprintf(why, why_size, "%s publishes while %s holds the claim", h->controller,
			 s->id);
		return SYNC_DROP_CONTROLLER;
	}
	if (!s->presence_known || strcmp(h->controller, s->presence.controller) != 0) {
		snprintf(why, why_size, "from %s, but the controller is %s", h->controller,
			 s->presence.controller[0] ? s->presence.controller : "none");
		return SYNC_DROP_CONTROLLER;
	}
	if (strcmp(h->controller, s->applied_from) == 0 && h->sequence < s->applied_seq) {
		snprintf(why, why_size, "state %" PRIu64 " after %" PRIu64, h->sequence,
			 s->applied_seq);
		return SYNC_DROP_STALE;
	}
	return SYNC_DROP_NONE;
}

static void on_state_msg(struct sync *s, const struct mosquitto_message *msg)
{
	struct sync_msg_header h;
	char why[256];
	enum sync_drop d = sync_msg_decode(msg->payload, (size_t)msg->payloadlen, &h, s->candidate,
					   why, sizeof(why));

	if (!d && strcmp(h.controller, s->id) == 0)
		return;		/* our own, back from the broker */
	s->st.received++;
	mark(s);
	if (!d)
		d = accept_state(s, &h, why, sizeof(why));
	if (d) {
		count_drop(s, d, "a state", why);
		return;
	}
	/* Only the sequence tells states apart: the same one again is a
	 * repeat (QoS 1, the retained message after a reconnection). */
	if (strcmp(h.controller, s->applied_from) == 0 && h.sequence == s->applied_seq) {
		s->st.duplicates++;
		return;
	}
	snprintf(s->applied_from, sizeof(s->applied_from), "%s", h.controller);
	s->applied_seq = h.sequence;
	s->st.sequence = h.sequence;
	s->st.generation = h.generation;
	s->st.apply_time_ns = h.apply_time_ns;
	s->st.applied++;
	s->last_mono_ns = loop_now_ns();
	log_debug("sync: state %" PRIu64 " (generation %" PRIu64 ") from %s", h.sequence,
		  h.generation, h.controller);
	if (s->cb.on_state)
		s->cb.on_state(s->cb.ctx, s->candidate, &h);
}

static void on_message(struct mosquitto *m, void *ctx, const struct mosquitto_message *msg)
{
	struct sync *s = ctx;

	if (strcmp(msg->topic, s->topic_state) == 0) {
		on_state_msg(s, msg);
	} else if (strcmp(msg->topic, s->topic_presence) == 0) {
		on_presence(s, msg);
	} else if (strcmp(msg->topic, s->topic_probe) == 0 && !s->probe_done) {
		/* Our probe came back after every retained message that the
		 * subscriptions brought: the presence, if any, is known. */
		s->probe_done = 1;
		mark(s);
		reconsider(s);
	}
}

/* ---- libmosquitto's callbacks ---- */

static void subscribe_all(struct sync *s)
{
	const char *topics[] = { s->topic_presence, s->topic_state, s->topic_probe };
	int n = s->cfg.role == SYNC_CONTROLLER ? 3 : 2;

	/* The presence first: the broker sends retained messages in the
	 * order of the subscriptions, so a joining follower knows the
	 * controller before its state arrives. */
	for (int i = 0; i < n; i++) {
		int rc = mosquitto_subscribe(s->m, &s->last_sub_mid, topics[i], 1);
		if (rc != MOSQ_ERR_SUCCESS)
			log_warning("sync: subscribing to %s: %s", topics[i], mosq_error(rc));
	}
}

static void on_connect(struct mosquitto *m, void *ctx, int rc)
{
	struct sync *s = ctx;

	if (rc != 0) {
		/* libmosquitto closes the connection after this. */
		snprintf(s->refusal, sizeof(s->refusal), "the broker refused us: %s",
			 mosquitto_connack_string(rc));
		return;
	}
	s->st.connects++;
	s->st.why[0] = 0;
	s->st.backoff_ms = 0;
	s->backoff_ms = s->cfg.backoff_min_ms;
	s->sent_seq = 0;
	s->inflight_mid = 0;
	/* Only what this connection brings counts: a restarted broker may
	 * have lost the retained presence that the last one showed. */
	memset(&s->presence, 0, sizeof(s->presence));
	s->presence_known = 0;
	set_state(s, SYNC_CONNECTED);
	log_info("sync: connected to %s:%u as %s of %s", s->cfg.host, s->cfg.port,
		 sync_role_name(s->cfg.role), s->cfg.prefix);
	subscribe_all(s);
}

static void on_subscribe(struct mosquitto *m, void *ctx, int mid, int n, const int *granted)
{
	struct sync *s = ctx;

	for (int i = 0; i < n; i++)
		if (granted[i] > 2) {
			log_error("sync: the broker refused a subscription under %s (access "
				  "rules?)", s->cfg.prefix);
			snprintf(s->st.why, sizeof(s->st.why), "the broker refused a subscription");
			mark(s);
		}
	if (mid == s->last_sub_mid && s->cfg.role == SYNC_CONTROLLER)
		mosquitto_publish(s->m, NULL, s->topic_probe, 1, "?", 1, false);
}

static void on_publish(struct mosquitto *m, void *ctx, int mid)
{
	struct sync *s = ctx;

	if (mid != s->inflight_mid)
		return;
	s->inflight_mid = 0;
	s->st.published++;
	s->st.generation = s->inflight_gen;
	s->st.apply_time_ns = s->inflight_apply;
	s->last_mono_ns = loop_now_ns();
	mark(s);
	send_pending(s);
}

static void on_disconnect(struct mosquitto *m, void *ctx, int rc)
{
	struct sync *s = ctx;

	connection_lost(s, rc == 0 ? "disconnected" : mosq_error(rc));
}

/* libmosquitto's own messages go to the debug level; none of them
 * carries the password. Its first error of an attempt (a TLS
 * verification failure, which closes the socket without a callback) is
 * kept to say why the attempt failed. */
static void on_log(struct mosquitto *m, void *ctx, int level, const char *text)
{
	struct sync *s = ctx;
	char buf[256];

	log_escape(text, strlen(text), buf, sizeof(buf));
	log_debug("sync: mosquitto: %s", buf);
	if (level == MOSQ_LOG_ERR && !s->refusal[0])
		snprintf(s->refusal, sizeof(s->refusal), "%s", buf);
}

/* ---- the public side ---- */

static int setup_mosquitto(struct sync *s)
{
	const struct sync_config *c = &s->cfg;
	int rc;

	s->m = mosquitto_new(NULL, true, s);
	if (!s->m)
		return -ENOMEM;
	mosquitto_int_option(s->m, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
	mosquitto_connect_callback_set(s->m, on_connect);
	mosquitto_disconnect_callback_set(s->m, on_disconnect);
	mosquitto_message_callback_set(s->m, on_message);
	mosquitto_subscribe_callback_set(s->m, on_subscribe);
	mosquitto_publish_callback_set(s->m, on_publish);
	mosquitto_log_callback_set(s->m, on_log);
	if (c->username[0] &&
	    mosquitto_username_pw_set(s->m, c->username, c->password[0] ? c->password : NULL))
		return -ENOMEM;
	if (c->tls) {
		const char *capath = c->cafile[0] || c->capath[0] ? c->capath : "/etc/ssl/certs";
		rc = mosquitto_tls_set(s->m, c->cafile[0] ? c->cafile : NULL,
				       capath[0] ? capath : NULL, c->certfile[0] ? c->certfile : NULL,
				       c->keyfile[0] ? c->keyfile : NULL, NULL);
		if (rc != MOSQ_ERR_SUCCESS) {
			log_error("sync: the TLS files cannot be used: %s", mosq_error(rc));
			return -EIO;
		}
	}
	if (c->role == SYNC_CONTROLLER) {
		struct sync_presence p = { .online = 0 };
		char buf[256];
		size_t len;
		snprintf(p.controller, sizeof(p.controller), "%s", s->id);
		if (sync_presence_encode(&p, buf, sizeof(buf), &len) < 0 ||
		    mosquitto_will_set(s->m, s->topic_presence, (int)len, buf, 1, true))
			return -ENOMEM;
	}
	return 0;
}

static int sync_init(struct sync *s, struct loop *l)
{
	int r;

	s->loop = l;
	s->io_fd = -1;
	s->backoff_ms = s->cfg.backoff_min_ms;
	make_id(s);
	snprintf(s->topic_state, sizeof(s->topic_state), "%s/state", s->cfg.prefix);
	snprintf(s->topic_presence, sizeof(s->topic_presence), "%s/controller", s->cfg.prefix);
	snprintf(s->topic_probe, sizeof(s->topic_probe), "%s/probe/%s", s->cfg.prefix, s->id);
	s->candidate = malloc(sizeof(*s->candidate));
	s->buf = malloc(SYNC_MSG_MAX + 1);
	if (!s->candidate || !s->buf)
		return -ENOMEM;
	if ((r = loop_timer_add(l, misc_fired, s, &s->misc_timer)) < 0 ||
	    (r = loop_timer_add(l, retry_fired, s, &s->retry_timer)) < 0 ||
	    (r = loop_timer_add(l, lookup_fired, s, &s->resolve_timer)) < 0)
		return r;
	return setup_mosquitto(s);
}

int sync_new(struct loop *l, const struct sync_config *cfg, const struct sync_callbacks *cb,
	     struct sync **ret)
{
	char err[256];
	struct sync *s;
	int r;

	if (sync_config_check(cfg, err, sizeof(err)) < 0) {
		log_error("%s", err);
		return -EINVAL;
	}
	s = calloc(1, sizeof(*s));
	if (!s)
		return -ENOMEM;
	s->cfg = *cfg;
	if (cb)
		s->cb = *cb;
	mosquitto_lib_init();
	if ((r = sync_init(s, l)) < 0) {
		sync_free(s);
		return r;
	}
	log_info("sync: %s of %s on %s:%u%s%s", sync_role_name(cfg->role), cfg->prefix, cfg->host,
		 cfg->port, cfg->tls ? " with TLS" : "", cfg->username[0] ? ", with a login" : "");
	start_attempt(s);
	s->status_dirty = 0;
	settle(s);
	*ret = s;
	return 0;
}

void sync_free(struct sync *s)
{
	if (!s)
		return;
	s->closing = 1;
	if (s->io)
		loop_io_del(s->io);
	if (s->m) {
		/* A controller says it is offline and leaves without DISCONNECT,
		 * so that the broker also sends its will should that
		 * publication not get out. */
		if (s->cfg.role == SYNC_CONTROLLER && s->active && s->state == SYNC_CONNECTED)
			publish_presence(s, 0);
		else if (s->state == SYNC_CONNECTED)
			mosquitto_disconnect(s->m);
		mosquitto_destroy(s->m);
	}
	mosquitto_lib_cleanup();
	loop_timer_del(s->misc_timer);
	loop_timer_del(s->retry_timer);
	loop_timer_del(s->resolve_timer);
	/* A lookup the resolver cannot cancel is left to it: it owns its
	 * memory, and the few bytes stay allocated. */
	if (s->lookup && gai_cancel(&s->lookup->cb) != EAI_NOTCANCELED) {
		if (s->lookup->cb.ar_result)
			freeaddrinfo(s->lookup->cb.ar_result);
		free(s->lookup);
	}
	free(s->pending);
	free(s->candidate);
	free(s->buf);
	explicit_bzero(s->cfg.password, sizeof(s->cfg.password));
	free(s);
}

int sync_publish(struct sync *s, const struct sky_state *st, uint64_t generation,
		 int64_t apply_time_ns)
{
	if (s->cfg.role != SYNC_CONTROLLER)
		return -EPERM;
	if (generation == 0 || generation < s->pending_gen || apply_time_ns <= 0)
		return -EINVAL;
	if (!s->pending && !(s->pending = malloc(sizeof(*s->pending))))
		return -ENOMEM;
	*s->pending = *st;
	s->seq++;
	s->pending_gen = generation;
	s->pending_apply = apply_time_ns;
	mark(s);
	send_pending(s);
	if (!s->depth)
		settle(s);	/* else the loop callback under way settles */
	return 0;
}

int64_t sync_apply_time_ns(const struct sync *s)
{
	struct timespec ts;

	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec + (int64_t)s->cfg.lead_ms * 1000000ll;
}

int sync_may_change(const struct sync *s, char *ret_controller, size_t size)
{
	const char *who = s->presence.controller[0] ? s->presence.controller : "unknown";

	if (s->cfg.role == SYNC_CONTROLLER &&
	    (s->active || !s->presence.online || strcmp(s->presence.controller, s->id) == 0 ||
	     !s->presence.controller[0]))
		return 1;
	snprintf(ret_controller, size, "%s", who);
	return 0;
}

void sync_get_status(const struct sync *s, struct sync_status *ret)
{
	*ret = s->st;
	ret->state = s->state;
	ret->role = s->cfg.role;
	ret->active = s->active;
	ret->standby = s->cfg.role == SYNC_CONTROLLER && s->probe_done && !s->active;
	ret->tls = s->cfg.tls;
	ret->auth = s->cfg.username[0] != 0;
	snprintf(ret->self, sizeof(ret->self), "%s", s->id);
	snprintf(ret->controller, sizeof(ret->controller), "%s", s->presence.controller);
	ret->controller_online = s->presence.online;
	if (s->cfg.role == SYNC_CONTROLLER && s->active)
		ret->sequence = s->seq;
	ret->age_ns = s->last_mono_ns ? loop_now_ns() - s->last_mono_ns : UINT64_MAX;
	if (s->state != SYNC_LOST)
		ret->backoff_ms = 0;
}

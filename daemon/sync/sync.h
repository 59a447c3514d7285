/* sync.h - one sky across several machines: skyd instances replicate their
 * control state through an MQTT broker, one controller and any number of
 * followers. docs/sync.md has the design, the message format and the
 * topics.
 *
 * Two parts:
 *   the messages (sync_msg_*, sync_presence_*): the versioned text format,
 *     no I/O; decoding parses a whole message into a candidate state and
 *     refuses all of it when one line fails;
 *   the client (sync_new ...): libmosquitto on a struct loop. The loop owns
 *     libmosquitto's socket (mosquitto_loop_read/write/misc from loop
 *     handles), nothing blocks it, the connection comes back by itself with
 *     a back-off. The process must ignore SIGPIPE (skyd does): libmosquitto
 *     writes with plain write().
 *
 * What skyd does with it (phase B): the controller calls sync_apply_time_ns
 * for every change it accepts, commits the change for that time and hands
 * the committed state to sync_publish; a follower commits what on_state
 * hands it, for the time it names, and answers a local change with the
 * controller that sync_may_change names.
 */
#ifndef SKYD_SYNC_H
#define SKYD_SYNC_H

#include <stddef.h>
#include <stdint.h>

struct loop;
struct sky_state;
struct sync;

/* The message format this code writes and the only one it reads. Version
 * 2 names each state by its sequence (docs/sync.md): a version 1 reader,
 * which told states apart by their generation alone, refuses it. */
#define SYNC_FORMAT_VERSION 2
/* Largest message read or written; a whole state is about 5 KiB. */
#define SYNC_MSG_MAX (64 * 1024)
/* A controller id: "HOST/PID/NONCE". */
#define SYNC_ID_MAX 96
#define SYNC_HOST_MAX 256
#define SYNC_PREFIX_MAX 128
#define SYNC_NAME_MAX 128
#define SYNC_SECRET_MAX 256
#define SYNC_PATH_MAX 256
/* An apply time further ahead of the receiver's clock than this is refused
 * (SYNC_DROP_RANGE): no lead is that long, and a sky held back that long
 * is a fault. */
#define SYNC_APPLY_AHEAD_MAX_NS (60ll * 1000000000ll)

/* ---- why a message was ignored ---- */

enum sync_drop {
	SYNC_DROP_NONE = 0,
	SYNC_DROP_MALFORMED,	/* not a skysync message, a bad header, bytes that are not
				 * text, a line count that does not match, a key missing */
	SYNC_DROP_VERSION,	/* a format version this code does not read */
	SYNC_DROP_KEY,		/* a key the state vocabulary does not know */
	SYNC_DROP_RANGE,	/* a value the vocabulary refuses (malformed, out of range,
				 * cross-key rules), or an apply time too far ahead */
	SYNC_DROP_CONTROLLER,	/* from a controller other than the one the topic names */
	SYNC_DROP_STALE,	/* an older sequence than the one applied */
	SYNC_DROP_N
};
/* A short lower-case name ("malformed", "controller", ...). */
const char *sync_drop_name(enum sync_drop d);

/* ---- the messages (no I/O) ---- */

/* The header of a state message. The sequence names the state: every
 * state a controller hands to sync_publish gets the next one, so two
 * different states never share it. The generation is the controller's
 * generation that shows the state: skyd coalesces changes that come while
 * a computation is in flight, so several states may name one generation. */
struct sync_msg_header {
	uint32_t version;		/* SYNC_FORMAT_VERSION */
	char controller[SYNC_ID_MAX];	/* who sent it */
	uint64_t sequence;		/* this controller's number of the state, >= 1, increasing */
	uint64_t generation;		/* the controller's generation that shows it, >= 1 */
	int64_t apply_time_ns;		/* CLOCK_REALTIME at which every machine switches */
	/* The cloud field's placement (sky_state.clouds.utc_s: whole seconds,
	 * NAN where it stands), which each follower takes as it is: its own
	 * clocks could floor the apply instant to another second. Absent from
	 * a controller before it (cloud_placed_sent 0): placed here. */
	int cloud_placed_sent;
	double cloud_placed_utc_s;
};

/* Writes the state message of st under header h (its version is ignored:
 * SYNC_FORMAT_VERSION is written) into buf, terminated; *ret_len gets its
 * length without the terminator. The simulated time travels as the time
 * the clock shows at h->apply_time_ns, so that any receiver with a
 * synchronised real-time clock shows the same time at the same instant.
 * Views are not part of it: they belong to the connections that made them.
 * 0, -EINVAL for a bad id, sequence or generation 0, -ENOSPC. */
int sync_msg_encode(const struct sky_state *st, const struct sync_msg_header *h, char *buf,
		    size_t size, size_t *ret_len);

/* Parses a whole state message of len bytes (not terminated) into
 * *ret_header and a candidate *ret_state built from state_default() and
 * every key of the message, validated as a whole (state_validate with no
 * device limit). Returns SYNC_DROP_NONE, or the reason the message is
 * refused with why naming the line; then *ret_state is unspecified and the
 * caller's state must stay as it was. Reads the real-time and monotonic
 * clocks to anchor the simulated clock and to check the apply time. */
enum sync_drop sync_msg_decode(const void *payload, size_t len, struct sync_msg_header *ret_header,
			       struct sky_state *ret_state, char *why, size_t why_size);

/* The controller's presence (retained on PREFIX/controller): who controls
 * this sky and whether it is connected now. */
struct sync_presence {
	char controller[SYNC_ID_MAX];	/* "" when the topic is empty */
	int online;
};
int sync_presence_encode(const struct sync_presence *p, char *buf, size_t size, size_t *ret_len);
/* An empty payload decodes as no controller. */
enum sync_drop sync_presence_decode(const void *payload, size_t len, struct sync_presence *ret,
				    char *why, size_t why_size);

/* Whether text is a well-formed controller id (HOST/PID/NONCE, at most
 * SYNC_ID_MAX - 1 bytes of [A-Za-z0-9._-] and two '/'). */
int sync_id_valid(const char *text);

/* ---- configuration ---- */

enum sync_role { SYNC_FOLLOWER = 0, SYNC_CONTROLLER = 1 };
const char *sync_role_name(enum sync_role r);
/* "controller" or "follower"; -EINVAL otherwise. */
int sync_parse_role(const char *name, enum sync_role *ret);

struct sync_config {
	char host[SYNC_HOST_MAX];	/* the broker: a name or an address */
	uint16_t port;
	char prefix[SYNC_PREFIX_MAX];	/* topics PREFIX/state, PREFIX/controller */
	int tls;			/* mqtts:// */
	enum sync_role role;
	uint32_t lead_ms;		/* how far ahead the controller sets the apply time */
	uint32_t keepalive_s;		/* MQTT keep-alive: a dead broker is noticed in 1.5x */
	uint32_t backoff_min_ms;	/* first reconnection delay, doubled per failure */
	uint32_t backoff_max_ms;	/* up to this */
	char username[SYNC_NAME_MAX];	/* "" none */
	char password[SYNC_SECRET_MAX];	/* never logged, never in the status */
	char cafile[SYNC_PATH_MAX];	/* TLS: "" with capath "" uses /etc/ssl/certs */
	char capath[SYNC_PATH_MAX];
	char certfile[SYNC_PATH_MAX];	/* a client certificate, with keyfile; "" none */
	char keyfile[SYNC_PATH_MAX];
};

/* Defaults: no broker, follower, lead 300 ms, keep-alive 10 s, back-off
 * 500 ms to 30 s. */
void sync_config_defaults(struct sync_config *ret);
/* Reads mqtt://HOST[:PORT]/PREFIX (port 1883) or mqtts://... (port 8883,
 * tls set) into host, port, prefix and tls; IPv6 addresses in brackets.
 * Credentials in the URL are refused (a command line is visible to every
 * user): they go in username and password. 0 or -EINVAL with err saying
 * what is wrong, never quoting the URL. */
int sync_config_parse_url(struct sync_config *cfg, const char *url, char *err, size_t err_size);
/* Reads the password from the first line of a file (what follows a
 * newline is ignored). 0 or -errno with err (which names the file, not
 * its content). */
int sync_config_read_password(struct sync_config *cfg, const char *path, char *err,
			      size_t err_size);
/* 0, or -EINVAL with err naming the field. */
int sync_config_check(const struct sync_config *cfg, char *err, size_t err_size);

/* ---- the client ---- */

enum sync_state {
	SYNC_OFF = 0,		/* no replication (skyd without --sync) */
	SYNC_CONNECTING,	/* a connection attempt is under way */
	SYNC_CONNECTED,		/* the broker accepted us; subscribed */
	SYNC_LOST,		/* no connection; the next attempt waits for the back-off */
};
const char *sync_state_name(enum sync_state s);

struct sync_status {
	enum sync_state state;
	enum sync_role role;
	int active;			/* controller: it holds the claim and publishes */
	int standby;			/* controller: another one holds the claim; this one
					 * follows it and waits for it to go */
	int tls, auth;			/* TLS on; a username is set (never the password) */
	char self[SYNC_ID_MAX];		/* this instance's controller id */
	char controller[SYNC_ID_MAX];	/* the controller the topic names, "" none known */
	int controller_online;
	uint64_t sequence;		/* of the state this instance shows: an active
					 * controller's newest (sent, or waiting for the
					 * broker), a follower's or a standby's last applied */
	uint64_t generation;		/* last applied (follower) or published (controller) */
	int64_t apply_time_ns;		/* its apply time */
	uint64_t age_ns;		/* since it was applied or published; UINT64_MAX none */
	uint64_t received;		/* state messages that arrived */
	uint64_t applied;		/* handed to on_state */
	uint64_t published;		/* sent (controller) */
	uint64_t duplicates;		/* the sequence already applied again (after a
					 * reconnection, a QoS 1 repeat): ignored quietly */
	uint64_t dropped[SYNC_DROP_N];	/* ignored, by reason ([SYNC_DROP_NONE] stays 0) */
	enum sync_drop last_drop;
	char last_drop_why[320];
	uint64_t connects;		/* connections the broker accepted */
	uint64_t attempts;		/* connection attempts */
	uint32_t backoff_ms;		/* the delay before the next attempt while lost */
	char why[256];			/* the latest connection problem, "" none */
};

/* A follower's (or a standby controller's) new sky: candidate is complete
 * and validated, h its message's header; commit it exactly as a local set
 * would be, switching at h->apply_time_ns (CLOCK_REALTIME; in the past: at
 * once). Each call brings a state of a higher sequence than the last (a
 * new controller starts its own). Views are not in it: keep the local
 * ones. From the loop; it may call sync_get_status, not sync_free. */
typedef void (*sync_state_fn)(void *ctx, const struct sky_state *candidate,
			      const struct sync_msg_header *h);
/* Something in sync_get_status changed (state, claim, counters). */
typedef void (*sync_status_fn)(void *ctx);

struct sync_callbacks {
	sync_state_fn on_state;		/* may be NULL */
	sync_status_fn on_status;	/* may be NULL */
	void *ctx;
};

/* Starts replication on l with cfg (copied): connects at once, without
 * waiting. A follower subscribes and hands every accepted state to
 * on_state; a controller claims the sky unless another controller holds
 * it (then it stands by and follows that one until it goes away) and
 * publishes what sync_publish gives it. 0, -EINVAL for a config that
 * sync_config_check refuses (the reason is logged), -ENOMEM, -EIO when
 * libmosquitto refuses a setting (a TLS file that cannot be read). */
int sync_new(struct loop *l, const struct sync_config *cfg, const struct sync_callbacks *cb,
	     struct sync **ret);
/* A controller hands its claim back (the presence says offline) and
 * disconnects; the password is wiped. */
void sync_free(struct sync *s);

/* The controller's state: once after sync_new (the state it starts
 * with), then after every accepted change, with the generation that shows
 * it (never decreasing: changes coalesced into one computation share it)
 * and its apply time. Each call gives the state the next sequence, so a
 * follower tells it from the one before even under the same generation. A
 * standby controller keeps handing over the state it follows. The latest
 * is kept and sent when this instance holds the claim and is connected, at
 * once or after a reconnection; at most one is in flight, a newer one
 * replaces one still waiting. 0, -EPERM on a follower, -EINVAL for
 * generation 0, a generation below the last one or an apply time <= 0. */
int sync_publish(struct sync *s, const struct sky_state *st, uint64_t generation,
		 int64_t apply_time_ns);

/* CLOCK_REALTIME now plus the configured lead, in ns: the apply time of a
 * change the controller accepts now. */
int64_t sync_apply_time_ns(const struct sync *s);

/* 1 when this instance may change the sky itself (a controller that does
 * not know of another one holding the claim); 0 for a follower or a
 * standby controller, with the controller in charge (its id, or "unknown")
 * in ret_controller for the refusal. */
int sync_may_change(const struct sync *s, char *ret_controller, size_t size);

void sync_get_status(const struct sync *s, struct sync_status *ret);

#endif

/* sky_internal.h - what the files of libsky share: the client's state and
 * the entry points between them (sky.c common parts and replies, sky_conn.c
 * the socket, sky_input.c what skyd sends, sky_shm.c the mapping). Not
 * installed; nothing here is exported (the library builds with hidden
 * visibility, only SKY_EXPORT names leave it). */
#ifndef SKY_INTERNAL_H
#define SKY_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/un.h>

#include "sky.h"

#define SKY_MAX_PENDING 64		/* requests waiting for their reply */
#define SKY_MAX_REPLY_LINES 65536	/* a reply longer than this is garbage */
#define SKY_IN_MAX (1u << 20)		/* bytes of one incoming line, bounded */
#define SKY_OUT_MAX (SKY_MAX_PENDING * SKY_PROTO_LINE_MAX)
#define SKY_MAX_FDS 8
#define SKY_VIEW_TRIES 64
#define SKY_SNAPSHOT_TRIES 16
#define SKY_DEFAULT_TIMEOUT_MS 5000

struct sky_reply {
	int ack;
	int fd;				/* descriptor that came with it, -1 if none */
	char *message;
	size_t n, cap;
	char **keys, **values;
};

struct sky_pending {
	uint64_t userdata;
	bool sync;			/* sky_request() is waiting for it */
	bool subscribe;			/* its reply carries the memfd */
	bool internal;			/* libsky's own re-subscription: no reply event */
};

struct sky_queued {
	struct sky_event ev;
	sky_reply *owned;
};

struct sky_client {
	char path[sizeof(((struct sockaddr_un *)0)->sun_path)];
	int fd;
	bool hung_up;
	bool greeted;
	char proto_version[32];
	int timeout_ms;
	uint64_t bytes_sent;		/* since connect, to know what reached the peer */

	char *in;
	size_t in_len, in_cap;
	char *out;
	size_t out_len, out_off;

	struct sky_pending pend[SKY_MAX_PENDING];
	unsigned pend_head, pend_count;
	sky_reply *cur;			/* reply being read */
	int fds[SKY_MAX_FDS];
	unsigned n_fds;

	struct sky_queued *evq;
	size_t ev_head, ev_count, ev_cap;
	sky_reply *handed_out;		/* reply of the last dispatched event */
	sky_reply *sync_reply;		/* completed reply of sky_request() */
	bool sync_done;

	bool in_batch;			/* lines after "batch" get no reply until "end" */
	bool unanswered;		/* the last queued line expects no reply */

	uint32_t sub_tables;
	unsigned sub_flags;
	bool subscribed;
	int map_error;			/* result of mapping the last subscribe's memfd */
	const struct sky_shm_header *map;
	size_t map_bytes;
	const struct sky_shm_header *old_map;	/* sky_wait: the superseded region */
	uint64_t map_dev, map_ino;	/* the mapped memfd, to know it again */
	unsigned map_serial;		/* +1 for every new mapping */

	/* sky_set_reconnect: after a hang-up, reconnect from sky_dispatch()
	 * and sky_wait() without blocking, at most once per reconnect_ms. */
	int reconnect_ms;		/* 0: off */
	int64_t next_try_ms;		/* CLOCK_MONOTONIC of the next attempt */
	bool lost;			/* hung up; SKY_EVENT_RECONNECTED due when back */
	bool resyncing;			/* connected again; greeting or subscription due */
	bool resub_sent;		/* the re-subscription is on its way */
	unsigned resync_serial;		/* map_serial when the connection was lost */

	/* sky_gpu_tables(): what each table held when last seen, in the
	 * mapping gpu_map (another mapping starts afresh). */
	const struct sky_shm_header *gpu_map;
	struct sky_gpu_seen {
		bool known;
		uint32_t generation;	/* the view generation it was hashed in */
		uint32_t changed;	/* changed_generation */
		uint64_t hash;		/* format, sizes, scale and texels */
	} gpu_seen[SKY_SHM_MAX_TABLES];
	/* sky_gpu_view_table(): the same per view volume, by name. */
	struct sky_gpu_seen_view {
		char name[SKY_SHM_VIEW_NAME_MAX];
		struct sky_gpu_seen seen;
	} gpu_views[SKY_SHM_MAX_VIEWS];
};

/* ---- sky.c: clocks and replies ---------------------------------------- */

/* CLOCK_MONOTONIC in milliseconds. */
int64_t sky_now_ms(void);

/* Milliseconds left before deadline (-1: none, which gives -1) for poll(). */
int sky_left_ms(int64_t deadline);

/* An empty reply (OK, no lines, no descriptor), or NULL without memory. */
sky_reply *sky_reply_alloc(void);

/* Appends the line "key: value" to r. Returns 0, -EPROTO past
 * SKY_MAX_REPLY_LINES or -ENOMEM. */
int sky_reply_add_pair(sky_reply *r, const char *key, const char *value);

/* Makes r the refusal "ACK [code] {verb} message": sky_reply_ack() gives
 * code, sky_reply_message() "{verb} message" as the line said it. Returns 0
 * or -ENOMEM. */
int sky_reply_set_ack(sky_reply *r, int code, const char *verb, const char *message);

/* ---- sky_input.c: lines from skyd --------------------------------------- */

/* Parses the whole lines in c->in (the greeting, reply lines, event lines)
 * and keeps the incomplete tail. Returns 0, or -EPROTO (garbled, or a line
 * over SKY_IN_MAX), -EPROTONOSUPPORT (another major protocol version) or
 * -ENOMEM, after which the stream cannot be trusted. */
int sky_input_lines(sky_client *c);

/* Records that a reply is due for a request just queued. -EAGAIN when
 * SKY_MAX_PENDING replies are already due. */
int sky_pending_push(sky_client *c, uint64_t userdata, bool sync, bool subscribe);

/* Queues an event for sky_dispatch(); owned (may be NULL) is freed when the
 * event has been handed out. Returns 0 or -ENOMEM (owned is not taken). */
int sky_event_push(sky_client *c, const struct sky_event *ev, sky_reply *owned);

/* Drops every queued event and the last one handed out. */
void sky_events_clear(sky_client *c);

/* ---- sky_conn.c: the socket ------------------------------------------- */

/* A client with no connection, no mapping and the default timeout, or NULL
 * without memory. Free with sky_disconnect(). */
sky_client *sky_client_alloc(void);

/* Blocks (up to timeout_ms, < 0 forever) until cond holds, writing what is
 * queued and reading what comes. A request that times out drops the
 * connection (drop_on_timeout), since a late reply would be taken for the
 * next request's. Returns 0, -ETIMEDOUT, -ECONNRESET or -errno. */
int sky_pump_until(sky_client *c, bool (*cond)(const sky_client *), int timeout_ms,
		   bool drop_on_timeout);

/* Reconnecting by itself (sky_set_reconnect): one non-blocking step that
 * reads what the socket holds (to hear of a hang-up) and, disconnected,
 * makes at most one connection attempt per interval. Returns 0 or -errno
 * of a garbled stream (the connection is then dropped and tried again). */
int sky_reconnect_step(sky_client *c);

/* The re-subscription's reply r (taken) arrived: 0 and a
 * SKY_EVENT_RECONNECTED queued, or -ECONNRESET when it failed (the
 * connection is dropped and tried again later). */
int sky_resynced(sky_client *c, sky_reply *r);

/* ---- sky_shm.c: the mapping ------------------------------------------- */

/* Maps memfd read-only in place of the current mapping after checking its
 * seals and header; the memfd already mapped (same inode and size: a
 * restarted skyd that adopted the region) keeps its mapping. Takes
 * ownership of fd. Returns 0, -EPROTO or -errno; on failure the old
 * mapping stays. */
int sky_map_memfd(sky_client *c, int fd);

/* Unmaps the region, if any. */
void sky_unmap(sky_client *c);

#endif

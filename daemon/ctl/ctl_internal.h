/* ctl_internal.h - what the files of the control server share: a client
 * connection, the server, a reply under construction and the command
 * table's entry, with the functions one file offers the others.
 *
 * conn.c owns the connections (queues, framing, dispatch); ctl.c the
 * listening socket and the events sent to every client; cmd.c the table of
 * verbs; each cmd_*.c one group of verbs. A new group of verbs is a new
 * cmd_*.c, its handlers declared below and entered in cmd.c's table.
 */
#ifndef SKYD_CTL_INTERNAL_H
#define SKYD_CTL_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include <sys/socket.h>
#include <sys/un.h>

#include "ctl.h"
#include "metar.h"
#include "proto.h"
#include "role.h"
#include "state.h"

struct chunk;
struct loop_io;
struct loop_timer;

/* The last METAR report a request applied, for its reply (cmd_weather.c). */
struct ctl_metar {
	int given;			/* a metar= key was applied */
	struct metar report;
	char applied[768];		/* the keys it set, key=value ... */
};

/* A batch: set lines applied to a copy of the state, committed by end. */
struct batch {
	struct sky_state state;
	uint32_t dirty;
	struct ctl_metar metar;
	int lines;
	int error_code;			/* first failure; 0 if none */
	char error[300];
};

/* Connections refused past max_connections, logged once a minute per uid
 * (a full backlog of retries must not flood the journal). An entry is
 * reused once its minute is over; while every entry is younger, the
 * refusals of further uids are counted in unlisted and told with the
 * next line logged. */
#define CTL_REFUSAL_UIDS 64
#define CTL_REFUSAL_LOG_NS (60ull * 1000000000ull)
struct ctl_refusal {
	uid_t uid;
	uint64_t logged_ns;		/* 0: unused */
	uint64_t unlogged;		/* refused since */
};
struct ctl_refusals {
	struct ctl_refusal uids[CTL_REFUSAL_UIDS];
	uint64_t unlisted;
};

struct client {
	struct ctl *ctl;
	struct client *prev, *next;
	uint64_t id;
	int fd;
	struct loop_io *io;
	uint32_t io_events;
	struct ucred cred;		/* peer, at accept */
	enum role role;			/* from cred and the settings (role.h) */

	char in[SKY_PROTO_LINE_MAX];
	size_t in_len;
	int discarding;			/* inside a line that was too long */
	int eof;			/* the peer will send nothing more */
	int closing;			/* drop once the output is out */
	int dead;			/* dropped: unlinked, its fd closed, freed by the loop */

	struct chunk *out_head, *out_tail;
	size_t out_bytes;

	uint32_t sub_tables;		/* has the region, gets layout: lines */
	int sub_events;			/* gets changed: and failed: lines */
	uint32_t sample_tables;		/* demanded by its sample requests, until unsubscribe */
	int sub_sensor;			/* gets sensor: lines (sensor events=1) */
	const char *line;		/* the request being handled, unparsed */
	char *deferred;			/* a sample waiting for its table; input waits too */
	struct batch *batch;
};

struct ctl {
	struct loop *loop;
	struct srv *srv;
	int listen_fd;
	struct loop_io *listen_io;
	struct loop_timer *accept_timer;
	int accept_paused;
	int accept_warned;		/* said so in the log; quiet until accepting again */
	char path[sizeof(((struct sockaddr_un *)0)->sun_path)];
	int created_socket;
	struct client *clients;
	int n_clients;
	uint64_t next_id;
	struct ctl_sync sync;		/* replication; may_change NULL: none */
	struct role_settings roles;	/* who controls, the bounds */
	struct ctl_refusals refusals;	/* connections refused, for the log */
	int finishing;
};

/* A reply under construction: pairs, then OK or one ACK line. */
struct reply {
	char *buf;
	size_t len, cap;
	int fd;				/* sent with the reply, owned */
	int failed;
};

/* A verb's handler returns 0 (the dispatcher adds OK), an ACK code with
 * the message in msg (what it wrote to the reply is then discarded), or -1
 * when it answers later (a batch, a sample waiting for its table). */
typedef int ctl_handler_fn(struct client *c, const struct proto_request *req, struct reply *r,
			   char *msg, size_t msg_size);

/* One verb: its usage and help for `help`, and the argument counts the
 * dispatcher checks before calling fn. */
struct ctl_cmd {
	const char *name;
	const char *usage;
	const char *help;
	int min_args, max_args;
	ctl_handler_fn *fn;
	enum role need;			/* ROLE_READER unless it changes the sky */
};

/* In a handler: writes the message and yields the ACK code. */
#define CTL_ACK(code, ...) (snprintf(msg, msg_size, __VA_ARGS__), (code))

/* SKY_ACK_PERMISSION with msg naming the role c lacks, or 0 when c has
 * need. For handlers whose sub-commands differ (view list reads, view add
 * changes); the table's need covers whole verbs. */
int ctl_need_role(struct client *c, enum role need, char *msg, size_t msg_size);
/* The subscriptions (connections with tables or events) and the views
 * held by connections of uid. */
unsigned ctl_uid_subscriptions(struct ctl *ctl, uid_t uid);
unsigned ctl_uid_views(struct ctl *ctl, uid_t uid);

/* conn.c: connections. */
int ctl_client_add(struct ctl *ctl, int fd);
/* Closes c and takes it out of the list of clients. The memory stays
 * valid, marked dead, until the loop is back at its top: a verb whose
 * client vanished while it ran (a flush that failed, a bound, a role) may
 * go on using c, and every call below on a dead client does nothing and
 * returns -1. Walks of ctl->clients skip dead entries. */
void ctl_client_drop(struct client *c, const char *why);
/* Queues len bytes and a dup of fd (if >= 0); 0, or -1 if the client was
 * dropped (its queue over its bound, or no fd to pass). */
int ctl_client_queue(struct client *c, const char *data, size_t len, int fd);
/* Writes what the socket takes. 0, or -1 if the client is gone. */
int ctl_client_flush(struct client *c);
/* Answers the samples that waited for a table (failed: with an ACK), then
 * the input that queued behind them. */
void ctl_resume_deferred(struct ctl *ctl, int failed);
/* Appends printf-formatted text; on lack of memory marks r failed. */
void ctl_reply_add(struct reply *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ctl.c: the server. */
/* Tells srv the tables in use: what clients subscribed to and sampled. */
void ctl_update_demand(struct ctl *ctl);

/* cmd.c: the command table and the verbs about the protocol itself. */
const struct ctl_cmd *ctl_find_cmd(const char *name);
/* A strict finite number in the C locale: 0 or -EINVAL. */
int ctl_cmd_commands(struct client *c, const struct proto_request *req, struct reply *r,
		     char *msg, size_t msg_size);
int ctl_cmd_help(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size);
int ctl_cmd_ping(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size);
int ctl_cmd_close(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size);

/* cmd_state.c: set, get, batch, end. */
int ctl_cmd_set(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size);
int ctl_cmd_get(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size);
int ctl_cmd_batch(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size);
int ctl_cmd_end(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size);
/* Applies a set line inside a batch to the batch's copy of the state; the
 * first failure is kept for end to report. */
void ctl_batch_line(struct client *c, const char *line);
/* Makes next the served state through srv_apply and replies with its
 * generation and tables; 0 or an ACK code with msg. */
int ctl_commit(struct client *c, const struct sky_state *next, uint32_t dirty, struct reply *r,
	       char *msg, size_t msg_size);

/* SKY_ACK_PERMISSION with msg when replication makes this instance a
 * follower (the controller named), 0 when it may change the state. */
int ctl_sync_refuse(struct ctl *ctl, char *msg, size_t msg_size);

/* cmd_astro.c: get sun, get moon, get times (reached through get). */
int ctl_get_sun(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size);
int ctl_get_moon(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size);
int ctl_get_times(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size);

/* cmd_weather.c: get weather (reached through get), and the metar key of
 * set and batch. */
int ctl_get_weather(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size);
/* get clouds: the cloud layers, the wind and the field's region. */
int ctl_get_clouds(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size);
/* Applies metar=report to s (state_set_metar), ORs the tables it
 * invalidates into *dirty and notes the report for the reply; 0 or
 * state_set's -errno with err. */
int ctl_apply_metar(struct sky_state *s, const char *report, uint32_t *dirty,
		    struct ctl_metar *note, char *err, size_t err_size);
/* The metar_used:, metar_ignored: and metar_applied: lines; nothing when
 * the request had no report. */
void ctl_reply_metar(struct reply *r, const struct ctl_metar *note);

/* cmd_tables.c: status, subscribe, unsubscribe, sample. */
int ctl_cmd_status(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size);
int ctl_cmd_subscribe(struct client *c, const struct proto_request *req, struct reply *r,
		      char *msg, size_t msg_size);
int ctl_cmd_unsubscribe(struct client *c, const struct proto_request *req, struct reply *r,
			char *msg, size_t msg_size);
int ctl_cmd_sample(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size);

/* cmd_sensor.c: get sensor (reached through get), the sensor verb (list,
 * events), the sensor lines of status. */
int ctl_get_sensor(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size);
int ctl_cmd_sensor(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size);
void ctl_status_sensor(struct ctl *ctl, struct reply *r);

/* cmd_view.c: view add, del, list. */
int ctl_cmd_view(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size);
/* Drops the views of a connection that closed. */
void ctl_views_drop_owner(struct ctl *ctl, uint64_t owner);

#endif

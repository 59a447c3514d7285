/* ctl.c - the control socket: connections, line framing, output queues and
 * the command table of the text protocol. */
#include "ctl.h"

#include <errno.h>
#include <fcntl.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "astro.h"
#include "drive.h"
#include "log.h"
#include "loop.h"
#include "proto.h"
#include "pub.h"
#include "simclock.h"
#include "skysample.h"
#include "srv.h"

/* One queued piece of output; fd (if >= 0) travels with its first byte. */
struct chunk {
	struct chunk *next;
	int fd;
	size_t len, off;
	char data[];
};

struct batch {
	struct sky_state state;
	uint32_t dirty;
	int lines;
	int error_code;			/* first failure; 0 if none */
	char error[300];
};

struct client {
	struct ctl *ctl;
	struct client *prev, *next;
	uint64_t id;
	int fd;
	struct loop_io *io;
	uint32_t io_events;
	struct ucred cred;		/* peer, recorded for roles */

	char in[SKY_PROTO_LINE_MAX];
	size_t in_len;
	int discarding;			/* inside a line that was too long */
	int eof;			/* the peer will send nothing more */
	int closing;			/* drop once the output is out */

	struct chunk *out_head, *out_tail;
	size_t out_bytes;

	uint32_t sub_tables;		/* has the region, gets layout: lines */
	int sub_events;			/* gets changed: and failed: lines */
	uint32_t sample_tables;		/* demanded by its sample requests, until unsubscribe */
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
	struct drive *drive;		/* the clock; NULL: none */
	int finishing;
};

/* A reply under construction: pairs, then OK or one ACK line. */
struct reply {
	char *buf;
	size_t len, cap;
	int fd;				/* sent with the reply, owned */
	int failed;
};

/* Handlers return 0 (the dispatcher adds OK) or an ACK code with the
 * message in msg; what they wrote to the reply is then discarded. */
struct cmd_entry {
	const char *name;
	const char *usage;
	const char *help;
	int min_args, max_args;
	int (*fn)(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size);
};

static const struct cmd_entry cmds[];
static const size_t n_cmds;

/* Output ---------------------------------------------------------------- */

static void reply_add(struct reply *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void reply_add(struct reply *r, const char *fmt, ...)
{
	va_list ap;
	int n;

	if (r->failed)
		return;
	for (;;) {
		va_start(ap, fmt);
		n = vsnprintf(r->buf + r->len, r->cap - r->len, fmt, ap);
		va_end(ap);
		if (n < 0) {
			r->failed = 1;
			return;
		}
		if ((size_t)n < r->cap - r->len)
			break;
		size_t cap = (r->cap + (size_t)n + 1) * 2;
		char *b = realloc(r->buf, cap);
		if (!b) {
			r->failed = 1;
			return;
		}
		r->buf = b;
		r->cap = cap;
	}
	r->len += (size_t)n;
}

static void client_update_events(struct client *c);
static void client_drop(struct client *c, const char *why);
static void update_demand(struct ctl *ctl);
static void views_drop_owner(struct ctl *ctl, uint64_t owner);
static int handle_line(struct client *c, char *line);
static int process_input(struct client *c);

/* Queues len bytes and owned_fd (if >= 0), which it takes in all cases.
 * Returns 0, or -1 when the client was dropped for exceeding its bound or
 * for lack of memory. */
static int client_queue_owned(struct client *c, const char *data, size_t len, int owned_fd)
{
	struct chunk *k;

	if (c->out_bytes + len > CTL_OUT_MAX) {
		if (owned_fd >= 0)
			close(owned_fd);
		client_drop(c, "output queue over its bound (the client does not read)");
		return -1;
	}
	k = malloc(sizeof(*k) + len);
	if (!k) {
		if (owned_fd >= 0)
			close(owned_fd);
		client_drop(c, "out of memory");
		return -1;
	}
	k->next = NULL;
	k->len = len;
	k->off = 0;
	k->fd = owned_fd;
	memcpy(k->data, data, len);
	if (c->out_tail)
		c->out_tail->next = k;
	else
		c->out_head = k;
	c->out_tail = k;
	c->out_bytes += len;
	return 0;
}

/* Queues len bytes and a dup of fd (if >= 0). A line that must carry an fd
 * means nothing without it: when no fd is free the client is dropped (it
 * reconnects) rather than sent the line alone. Returns 0 or -1 (dropped). */
static int client_queue(struct client *c, const char *data, size_t len, int fd)
{
	int dup = -1;

	if (fd >= 0) {
		dup = fcntl(fd, F_DUPFD_CLOEXEC, 3);
		if (dup < 0) {
			char why[128];
			snprintf(why, sizeof(why), "no fd to pass the shared memory: %s", strerror(errno));
			client_drop(c, why);
			return -1;
		}
	}
	return client_queue_owned(c, data, len, dup);
}

static void chunk_free(struct chunk *k)
{
	if (k->fd >= 0)
		close(k->fd);
	free(k);
}

/* Writes what the socket takes. Returns 0, or -1 if the client is gone. */
static int client_flush(struct client *c)
{
	while (c->out_head) {
		struct chunk *k = c->out_head;
		ssize_t n;
		if (k->fd >= 0 && k->off == 0) {
			union {
				char buf[CMSG_SPACE(sizeof(int))];
				struct cmsghdr align;
			} u;
			struct iovec iov = { k->data, k->len };
			struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1,
					     .msg_control = u.buf, .msg_controllen = sizeof(u.buf) };
			struct cmsghdr *cm = CMSG_FIRSTHDR(&mh);
			cm->cmsg_level = SOL_SOCKET;
			cm->cmsg_type = SCM_RIGHTS;
			cm->cmsg_len = CMSG_LEN(sizeof(int));
			memcpy(CMSG_DATA(cm), &k->fd, sizeof(int));
			n = sendmsg(c->fd, &mh, MSG_NOSIGNAL | MSG_DONTWAIT);
			if (n > 0) {
				close(k->fd);
				k->fd = -1;
			}
		} else {
			n = send(c->fd, k->data + k->off, k->len - k->off, MSG_NOSIGNAL | MSG_DONTWAIT);
		}
		if (n < 0) {
			if (errno == EAGAIN || errno == EINTR)
				break;
			client_drop(c, strerror(errno));
			return -1;
		}
		k->off += (size_t)n;
		c->out_bytes -= (size_t)n;
		if (k->off < k->len)
			break;
		c->out_head = k->next;
		if (!c->out_head)
			c->out_tail = NULL;
		chunk_free(k);
	}
	if (!c->out_head && c->closing) {
		client_drop(c, NULL);
		return -1;
	}
	client_update_events(c);
	return 0;
}

static void client_update_events(struct client *c)
{
	uint32_t ev = 0;

	/* Requests wait while the client does not read its replies. */
	if (!c->eof && !c->closing && c->out_bytes < CTL_OUT_HIGH)
		ev |= EPOLLIN;
	if (c->out_head)
		ev |= EPOLLOUT;
	if (ev != c->io_events) {
		loop_io_mod(c->io, ev);
		c->io_events = ev;
	}
}

static void client_drop(struct client *c, const char *why)
{
	struct ctl *ctl = c->ctl;

	if (why)
		log_info("client %llu (pid %d uid %d) dropped: %s", (unsigned long long)c->id,
			 (int)c->cred.pid, (int)c->cred.uid, why);
	else
		log_debug("client %llu closed", (unsigned long long)c->id);
	loop_io_del(c->io);
	close(c->fd);
	while (c->out_head) {
		struct chunk *k = c->out_head;
		c->out_head = k->next;
		chunk_free(k);
	}
	if (c->prev)
		c->prev->next = c->next;
	else
		ctl->clients = c->next;
	if (c->next)
		c->next->prev = c->prev;
	ctl->n_clients--;
	uint64_t id = c->id;
	free(c->batch);
	free(c->deferred);
	free(c);
	if (!ctl->finishing) {
		update_demand(ctl);
		views_drop_owner(ctl, id);
	}
	/* A freed fd may be what accept was waiting for. */
	if (ctl->accept_paused) {
		ctl->accept_paused = 0;
		loop_timer_arm(ctl->accept_timer, 0);
		loop_io_mod(ctl->listen_io, EPOLLIN);
	}
}

/* Demand ---------------------------------------------------------------- */

/* The tables in use: what connections subscribed to and what they sampled.
 * srv computes this and its dependencies, nothing else. */
static void update_demand(struct ctl *ctl)
{
	uint32_t demand = 0;

	for (struct client *k = ctl->clients; k; k = k->next)
		demand |= k->sub_tables | k->sample_tables;
	srv_set_demand(ctl->srv, demand);
}

static int send_ack(struct client *c, int code, const char *verb, const char *message);

/* Answers the samples that waited for a table, after a publication (the
 * table may be there now; if not, the request waits again) or a failure
 * (ACK, the tables stay as they were). Then the input that queued. */
static void resume_deferred(struct ctl *ctl, int failed)
{
	struct client *c, *next;

	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (!c->deferred)
			continue;
		char *line = c->deferred;
		c->deferred = NULL;
		int r = failed ? send_ack(c, SKY_ACK_ENGINE, "sample",
					  "the computation of the table failed; see status")
			       : handle_line(c, line);
		free(line);
		if (r == 0 && !c->deferred)
			process_input(c);
	}
}

/* Events ---------------------------------------------------------------- */

void ctl_published(void *ctx, uint64_t generation, uint32_t tables, int new_region)
{
	struct ctl *ctl = ctx;
	struct pub *p = srv_pub(ctl->srv);
	struct client *c, *next;
	char names[64], line[160];

	state_format_tables(tables, names, sizeof(names));
	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (new_region && c->sub_tables) {
			int n = snprintf(line, sizeof(line), "layout: generation=%llu bytes=%llu\n",
					 (unsigned long long)generation,
					 (unsigned long long)pub_bytes(p));
			if (client_queue(c, line, (size_t)n, pub_fd(p)) < 0)
				continue;
		}
		if (c->sub_events) {
			int n = snprintf(line, sizeof(line), "changed: generation=%llu tables=%s\n",
					 (unsigned long long)generation, names);
			if (client_queue(c, line, (size_t)n, -1) < 0)
				continue;
		}
		if (c->out_head)
			client_flush(c);
	}
	resume_deferred(ctl, 0);
}

void ctl_failed(void *ctx, uint64_t generation, const char *message)
{
	struct ctl *ctl = ctx;
	struct client *c, *next;
	char line[400];
	int n = snprintf(line, sizeof(line), "failed: generation=%llu message=", (unsigned long long)generation);

	/* The message is free text: keep it on one line, spaces as '_'. */
	for (const char *m = message; *m && n < (int)sizeof(line) - 2; m++)
		line[n++] = (*m > ' ' && *m < 0x7f) ? *m : '_';
	line[n++] = '\n';
	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (c->sub_events && client_queue(c, line, (size_t)n, -1) == 0)
			client_flush(c);
	}
	resume_deferred(ctl, 1);
}

/* Verbs ----------------------------------------------------------------- */

#define ACK(code, ...) (snprintf(msg, msg_size, __VA_ARGS__), (code))

/* Maps a state_set failure onto an ACK code from its cause. */
static int set_error_code(const struct sky_state *s, const char *key, int r, const char *err)
{
	char buf[8];

	if (state_get(s, key, buf, sizeof(buf)) == -ENOENT)
		return SKY_ACK_NO_EXIST;
	if (r == -ERANGE || strstr(err, "outside") || strstr(err, "must"))
		return SKY_ACK_RANGE;
	return SKY_ACK_ARG;
}

/* Applies the args of a set to s. Returns 0 or an ACK code with msg. */
static int apply_pairs(struct sky_state *s, const struct proto_request *req, uint32_t *dirty,
		       char *msg, size_t msg_size)
{
	char err[256];

	for (int i = 0; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		err[0] = 0;
		int r = state_set(s, a->key, a->value, dirty, err, sizeof(err));
		if (r < 0) {
			int code = set_error_code(s, a->key, r, err);
			return ACK(code, "%s", err[0] ? err : strerror(-r));
		}
	}
	return 0;
}

static int commit(struct client *c, const struct sky_state *next_in, uint32_t dirty,
		  struct reply *r, char *msg, size_t msg_size)
{
	char err[256] = "", names[64];
	uint64_t generation;
	struct sky_state lit = *next_in;
	const struct sky_state *next = &lit;

	/* A new time, place or light mode moves the lights at once, so that
	 * the reply's generation shows them; astro may refuse the time. */
	if (memcmp(&lit.clock, &srv_state(c->ctl->srv)->clock, sizeof(lit.clock)) != 0) {
		double mono_s;
		simclock_read_clocks(NULL, &mono_s);
		state_clock_rebase(&lit, srv_state(c->ctl->srv), mono_s);
		if (drive_lights(&lit, mono_s, &dirty, err, sizeof(err)) < 0)
			return ACK(SKY_ACK_RANGE, "%s", err);
	}
	if (srv_check(c->ctl->srv, next, err, sizeof(err)) < 0)
		return ACK(SKY_ACK_RANGE, "%s", err);
	if (srv_change(c->ctl->srv, next, dirty, &generation, err, sizeof(err)) < 0)
		return ACK(SKY_ACK_ENGINE, "state unchanged, computation failed: %s", err);
	drive_changed(c->ctl->drive);
	state_format_tables(dirty, names, sizeof(names));
	reply_add(r, "generation: %llu\ntables: %s\n", (unsigned long long)generation, names);
	return 0;
}

static int cmd_set(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	struct sky_state next = *srv_state(c->ctl->srv);
	uint32_t dirty = 0;
	int code = apply_pairs(&next, req, &dirty, msg, msg_size);

	return code ? code : commit(c, &next, dirty, r, msg, msg_size);
}

static void emit_pair(void *ctx, const char *key, const char *value)
{
	reply_add(ctx, "%s: %s\n", key, value);
}

/* Sun, moon and times --------------------------------------------------- */

static int parse_number(const char *v, double *ret);

/* The clock's time now, or an ACK when no time was ever set. */
static int clock_now(const struct sky_state *s, double *ret_utc_s, char *msg, size_t msg_size)
{
	double mono_s;

	simclock_read_clocks(NULL, &mono_s);
	*ret_utc_s = state_clock_utc_s(s, mono_s);
	if (isnan(*ret_utc_s))
		return ACK(SKY_ACK_STATE, "utc: no time set (set utc=now or utc=YYYY-MM-DDTHH:MM:SSZ)");
	return 0;
}

/* What `get sun` and `get moon` share: no arguments, the clock's time now
 * and the observer's site. */
static int light_request(const struct client *c, const struct proto_request *req,
			 const char *verb, double *ret_utc_s, struct astro_site *ret_site,
			 struct astro_options *ret_opt, char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	int code = clock_now(s, ret_utc_s, msg, msg_size);

	if (code)
		return code;
	if (req->n_args > 1)
		return ACK(SKY_ACK_SYNTAX, "get %s takes no arguments", verb);
	drive_site(s, ret_site, ret_opt);
	return 0;
}

static void reply_utc(struct reply *r, const char *key, double utc_s)
{
	char buf[SIMCLOCK_UTC_TEXT_MAX];

	if (simclock_format_utc(utc_s, buf, sizeof(buf)) < 0)
		reply_add(r, "%s: %.3f\n", key, utc_s);
	else
		reply_add(r, "%s: %s\n", key, buf);
}

static void reply_direction(struct reply *r, const struct astro_direction *geo,
			    const struct astro_direction *app)
{
	reply_add(r, "zenith_deg: %.6f\nelevation_deg: %.6f\nazimuth_deg: %.6f\n",
		  geo->zenith_deg, geo->elevation_deg, geo->azimuth_deg);
	reply_add(r, "apparent_zenith_deg: %.6f\napparent_elevation_deg: %.6f\napparent_azimuth_deg: %.6f\n",
		  app->zenith_deg, app->elevation_deg, app->azimuth_deg);
}

static int get_sun(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_sun a;
	char err[256];
	double utc_s;
	int code = light_request(c, req, "sun", &utc_s, &site, &opt, msg, msg_size);

	if (code)
		return code;
	if (astro_sun(&site, utc_s, &opt, &a, err, sizeof(err)) < 0)
		return ACK(SKY_ACK_RANGE, "%s", err);
	reply_utc(r, "utc", utc_s);
	reply_add(r, "sun_mode: %s\n", s->clock.sun_mode == STATE_CLOCK ? "clock" : "manual");
	reply_direction(r, &a.geometric, &a.apparent);
	reply_add(r, "right_ascension_deg: %.6f\ndeclination_deg: %.6f\nhour_angle_deg: %.6f\n",
		  a.right_ascension_deg, a.declination_deg, a.hour_angle_deg);
	reply_add(r, "equation_of_time_min: %.6f\ndistance_au: %.9f\nangular_radius_deg: %.6f\n",
		  a.equation_of_time_min, a.distance_au, a.angular_radius_deg);
	reply_add(r, "illuminance_lx: %.3f\ndelta_t_s: %.3f\n", a.illuminance_lx, a.delta_t_s);
	return 0;
}

static int get_moon(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_moon m;
	char err[256];
	double utc_s;
	int code = light_request(c, req, "moon", &utc_s, &site, &opt, msg, msg_size);

	if (code)
		return code;
	if (astro_moon(&site, utc_s, &opt, &m, err, sizeof(err)) < 0)
		return ACK(SKY_ACK_RANGE, "%s", err);
	reply_utc(r, "utc", utc_s);
	reply_add(r, "moon_mode: %s\n", s->clock.moon_mode == STATE_CLOCK ? "clock" : "manual");
	reply_direction(r, &m.geometric, &m.apparent);
	reply_add(r, "longitude_deg: %.6f\nlatitude_deg: %.6f\n", m.longitude_deg, m.latitude_deg);
	reply_add(r, "right_ascension_deg: %.6f\ndeclination_deg: %.6f\n", m.right_ascension_deg,
		  m.declination_deg);
	reply_add(r, "distance_km: %.3f\ntopocentric_distance_km: %.3f\nangular_radius_deg: %.6f\n",
		  m.distance_km, m.topocentric_distance_km, m.angular_radius_deg);
	reply_add(r, "phase_angle_deg: %.6f\nilluminated_fraction: %.6f\nelongation_deg: %.6f\nwaxing: %d\n",
		  m.phase_angle_deg, m.illuminated_fraction, m.elongation_deg, m.waxing ? 1 : 0);
	reply_add(r, "illuminance_lx: %.6g\n", m.illuminance_lx);
	/* What the tables are lit with: the served state's moon. */
	reply_add(r, "lit: %d\nlit_illuminance_lx: %.6g\n", s->moon.illuminance_lx > 0.0,
		  s->moon.illuminance_lx);
	return 0;
}

static void reply_event(struct reply *r, const char *key, double utc_s, enum astro_day_kind kind,
			const char *above, const char *below)
{
	if (kind == ASTRO_RISES_AND_SETS)
		reply_utc(r, key, utc_s);
	else
		reply_add(r, "%s: none (%s)\n", key, kind == ASTRO_ALWAYS_ABOVE ? above : below);
}

static void reply_rise_set(struct reply *r, const char *rise, const char *set,
			   const struct astro_rise_set *rs, const char *above, const char *below)
{
	reply_event(r, rise, rs->rise_utc_s, rs->kind, above, below);
	reply_event(r, set, rs->set_utc_s, rs->kind, above, below);
}

/* get times [date=YYYY-MM-DD] [utc_offset_min=N]: the local day starts at
 * local midnight, local = UTC + utc_offset_min; by default the offset of
 * the longitude's nominal zone (15 degrees an hour) and the simulated date. */
static int get_times(struct client *c, const struct proto_request *req, struct reply *r,
		     char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_times t;
	struct astro_date d = { 0 };
	const char *date = NULL;
	char err[256], buf[SIMCLOCK_UTC_TEXT_MAX];
	double off;

	d.utc_offset_min = (int)lround(s->clock.lon_deg / 15.0) * 60;
	for (int i = 1; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return ACK(SKY_ACK_SYNTAX, "usage: get times [date=YYYY-MM-DD] [utc_offset_min=N]");
		if (strcmp(a->key, "date") == 0) {
			date = a->value;
		} else if (strcmp(a->key, "utc_offset_min") == 0) {
			if (parse_number(a->value, &off) < 0 || off != floor(off))
				return ACK(SKY_ACK_ARG, "utc_offset_min: '%s' is not a whole number", a->value);
			if (fabs(off) > 1080)
				return ACK(SKY_ACK_RANGE, "utc_offset_min: %g is outside [-1080, 1080]", off);
			d.utc_offset_min = (int)off;
		} else {
			return ACK(SKY_ACK_NO_EXIST, "%s: unknown key (date, utc_offset_min)", a->key);
		}
	}
	if (date) {
		char tail;
		if (sscanf(date, "%5d-%2d-%2d%c", &d.year, &d.month, &d.day, &tail) != 3 ||
		    strlen(date) != 10 || date[0] < '0' || date[0] > '9' || date[4] != '-' || date[7] != '-' ||
		    !simclock_valid_date(d.year, d.month, d.day))
			return ACK(SKY_ACK_ARG, "date: '%s' is not a date YYYY-MM-DD", date);
	} else {
		double utc_s;
		int code = clock_now(s, &utc_s, msg, msg_size);
		if (code)
			return code;
		if (simclock_format_utc(utc_s + 60.0 * d.utc_offset_min, buf, sizeof(buf)) < 0 ||
		    sscanf(buf, "%d-%d-%d", &d.year, &d.month, &d.day) != 3)
			return ACK(SKY_ACK_RANGE, "utc: outside years 0..9999");
	}
	drive_site(s, &site, &opt);
	if (astro_sun_times(&site, &d, &opt, &t, err, sizeof(err)) < 0)
		return ACK(SKY_ACK_RANGE, "%s", err);
	reply_add(r, "date: %04d-%02d-%02d\nutc_offset_min: %d\n", d.year, d.month, d.day,
		  d.utc_offset_min);
	reply_utc(r, "transit_utc", t.transit_utc_s);
	reply_add(r, "transit_elevation_deg: %.6f\n", t.transit_elevation_deg);
	reply_rise_set(r, "sunrise_utc", "sunset_utc", &t.sunrise_sunset, "polar day", "polar night");
	reply_rise_set(r, "civil_dawn_utc", "civil_dusk_utc", &t.civil,
		       "sun never below -6 deg", "sun never above -6 deg");
	reply_rise_set(r, "nautical_dawn_utc", "nautical_dusk_utc", &t.nautical,
		       "sun never below -12 deg", "sun never above -12 deg");
	reply_rise_set(r, "astronomical_dawn_utc", "astronomical_dusk_utc", &t.astronomical,
		       "sun never below -18 deg", "sun never above -18 deg");
	return 0;
}

static int cmd_get(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	char buf[256];

	if (req->n_args && !req->args[0].value) {
		if (strcmp(req->args[0].key, "sun") == 0)
			return get_sun(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "moon") == 0)
			return get_moon(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "times") == 0)
			return get_times(c, req, r, msg, msg_size);
	}
	if (!req->n_args) {
		state_foreach(s, emit_pair, r);
		return 0;
	}
	for (int i = 0; i < req->n_args; i++) {
		const char *key = req->args[i].key;
		if (req->args[i].value)
			return ACK(SKY_ACK_SYNTAX, "'%s=': key names expected, without values", key);
		if (state_get(s, key, buf, sizeof(buf)) < 0)
			return ACK(SKY_ACK_NO_EXIST, "%s: unknown key", key);
		reply_add(r, "%s: %s\n", key, buf);
	}
	return 0;
}

/* batch and the set lines inside it answer nothing; end answers for all. */
static int cmd_batch(struct client *c, const struct proto_request *req, struct reply *r,
		     char *msg, size_t msg_size)
{
	c->batch = calloc(1, sizeof(*c->batch));
	if (!c->batch)
		return ACK(SKY_ACK_LIMIT, "out of memory");
	c->batch->state = *srv_state(c->ctl->srv);
	return -1;
}

static void batch_line(struct client *c, const char *line)
{
	struct batch *b = c->batch;
	struct proto_request req;
	char copy[SKY_PROTO_LINE_MAX], msg[256];
	int code = 0;

	b->lines++;
	if (b->error_code)
		return;
	snprintf(copy, sizeof(copy), "%s", line);
	int r = proto_parse_request(copy, &req, msg, sizeof(msg));
	if (r == -ENODATA)
		return;
	if (r < 0)
		code = r == -E2BIG ? SKY_ACK_LIMIT : SKY_ACK_SYNTAX;
	else if (strcmp(req.verb, "set") != 0)
		code = SKY_ACK_STATE, snprintf(msg, sizeof(msg), "%s: only set and end inside a batch", req.verb);
	else if (b->lines > CTL_BATCH_MAX)
		code = SKY_ACK_LIMIT, snprintf(msg, sizeof(msg), "more than %d lines", CTL_BATCH_MAX);
	else if (!req.n_args)
		code = SKY_ACK_SYNTAX, snprintf(msg, sizeof(msg), "set: key=value expected");
	else
		code = apply_pairs(&b->state, &req, &b->dirty, msg, sizeof(msg));
	if (code) {
		b->error_code = code;
		snprintf(b->error, sizeof(b->error), "line %d: %s", b->lines, msg);
	}
}

static int cmd_end(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	struct batch *b = c->batch;
	int code;

	if (!b)
		return ACK(SKY_ACK_STATE, "no batch to end");
	c->batch = NULL;
	if (b->error_code)
		code = ACK(b->error_code, "%s; nothing applied", b->error);
	else
		code = commit(c, &b->state, b->dirty, r, msg, msg_size);
	free(b);
	return code;
}

static int cmd_status(struct client *c, const struct proto_request *req, struct reply *r,
		      char *msg, size_t msg_size)
{
	struct srv *s = c->ctl->srv;
	const struct eng_device *d = srv_device(s);
	struct srv_status st;
	char names[64];
	int subscribers = 0;

	srv_status(s, &st);
	for (struct client *k = c->ctl->clients; k; k = k->next)
		subscribers += k->sub_tables || k->sub_events;
	reply_add(r, "generation: %llu\n", (unsigned long long)st.generation);
	reply_add(r, "computing: %d\npending: %d\n", st.computing, st.pending);
	state_format_tables(st.last_computed, names, sizeof(names));
	reply_add(r, "tables_computed: %s\n", names);
	state_format_tables(st.published_valid, names, sizeof(names));
	reply_add(r, "tables_valid: %s\n", names);
	state_format_tables(st.published_computed, names, sizeof(names));
	reply_add(r, "last_computed: %s\n", names);
	state_format_tables(st.demand, names, sizeof(names));
	reply_add(r, "demand: %s\n", names);
	state_format_tables(st.needed, names, sizeof(names));
	reply_add(r, "tables_needed: %s\n", names);
	const struct sky_shm_slot *cur = pub_current(srv_pub(s), NULL);
	reply_add(r, "views: %u\n", srv_state(s)->n_views);
	for (uint32_t i = 0; i < cur->n_views && i < SKY_SHM_MAX_VIEWS; i++)
		reply_add(r, "view: name=%.*s index=%u valid=%d\n", (int)SKY_SHM_VIEW_NAME_MAX,
			  cur->views[i].name, i, !!(cur->valid_views & (1u << i)));
	reply_add(r, "compute_ms: %.3f\n", st.last_total_ms);
	for (int t = 0; t < STATE_N_TABLES; t++)
		reply_add(r, "%s_ms: %.3f\n", state_table_names[t], st.table_ms[t]);
	reply_add(r, "computations: %llu\nfailures: %llu\n", (unsigned long long)st.computations,
		  (unsigned long long)st.failures);
	reply_add(r, "column_passes: %llu\n", (unsigned long long)st.column_passes);
	reply_add(r, "last_error: %s\n", st.last_error[0] ? st.last_error : "none");
	reply_add(r, "storage_warning: %s\n", st.storage_warning[0] ? st.storage_warning : "none");
	reply_add(r, "device: %s\ndevice_type: %s\n", d->name, d->type_name);
	reply_add(r, "clients: %d\nsubscribers: %d\n", c->ctl->n_clients, subscribers);
	reply_add(r, "shm_bytes: %llu\n", (unsigned long long)pub_bytes(srv_pub(s)));
	reply_add(r, "protocol: %s\n", SKY_PROTO_VERSION);
	if (c->ctl->drive) {
		struct drive_stats ds;
		drive_stats(c->ctl->drive, &ds);
		reply_add(r, "clock_ticks: %llu\nclock_changes: %llu\n", (unsigned long long)ds.ticks,
			  (unsigned long long)ds.changes);
		if (ds.next_tick_s < 0)
			reply_add(r, "clock_next_tick_s: none\n");
		else
			reply_add(r, "clock_next_tick_s: %.3f\n", ds.next_tick_s);
	}
	return 0;
}

static const char *format_name(uint32_t f)
{
	return f == SKY_FORMAT_RGBA16F ? "rgba16f" : "rgba32f";
}

static int cmd_subscribe(struct client *c, const struct proto_request *req, struct reply *r,
			 char *msg, size_t msg_size)
{
	uint32_t tables = 0;
	int events = -1, fd = -1;

	for (int i = 0; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		if (strcmp(a->key, "tables") == 0) {
			if (state_parse_tables(a->value, &tables) < 0)
				return ACK(SKY_ACK_NO_EXIST, "tables: '%s' is not a list of transmittance, multiscatter, skyview, aerial or all", a->value);
		} else if (strcmp(a->key, "events") == 0) {
			if (strcmp(a->value, "0") && strcmp(a->value, "1"))
				return ACK(SKY_ACK_ARG, "events: '%s' is not 0 or 1", a->value);
			events = a->value[0] == '1';
		} else {
			return ACK(SKY_ACK_NO_EXIST, "%s: unknown key (tables, events)", a->key);
		}
	}
	if (tables) {
		/* Taken before anything changes, so that a refusal changes nothing. */
		fd = fcntl(pub_fd(srv_pub(c->ctl->srv)), F_DUPFD_CLOEXEC, 3);
		if (fd < 0)
			return ACK(SKY_ACK_LIMIT, "no file descriptor free to pass the shared memory (%s); try again",
				   strerror(errno));
	}
	if (events >= 0)
		c->sub_events = events;
	if (!tables) {
		reply_add(r, "events: %d\n", c->sub_events);
		return 0;
	}
	c->sub_tables = tables;
	update_demand(c->ctl);
	struct pub *p = srv_pub(c->ctl->srv);
	const struct sky_shm_header *h = pub_header(p);
	reply_add(r, "generation: %llu\n", (unsigned long long)h->generation);
	reply_add(r, "events: %d\n", c->sub_events);
	reply_add(r, "shm_bytes: %llu\nheader_bytes: %u\nslots: %u\nslot_bytes: %llu\n",
		  (unsigned long long)h->total_bytes, h->header_bytes, h->n_slots,
		  (unsigned long long)h->slot_bytes);
	reply_add(r, "layout_version: %u\nuv_mapping_version: %u\n", h->layout_version,
		  h->uv_mapping_version);
	for (uint32_t t = 0; t < h->n_tables; t++) {
		const struct sky_shm_table *d = &h->tables[t];
		reply_add(r, "table: name=%s format=%s width=%u height=%u depth=%u texel_bytes=%u offset=%llu bytes=%llu\n",
			  state_table_names[t], format_name(d->format), d->width, d->height, d->depth,
			  d->texel_bytes, (unsigned long long)d->offset,
			  (unsigned long long)d->bytes);
	}
	r->fd = fd;
	return 0;
}

static int cmd_unsubscribe(struct client *c, const struct proto_request *req, struct reply *r,
			   char *msg, size_t msg_size)
{
	c->sub_tables = 0;
	c->sub_events = 0;
	c->sample_tables = 0;
	update_demand(c->ctl);
	return 0;
}

/* A strict finite number in the C locale, whatever the process locale. */
static int parse_number(const char *v, double *ret)
{
	static locale_t c_locale;
	char *end;

	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!c_locale || !v || !*v)
		return -EINVAL;
	errno = 0;
	double d = strtod_l(v, &end, c_locale);
	if (*end || !isfinite(d) || errno == ERANGE)
		return -EINVAL;
	*ret = d;
	return 0;
}

static void reply_rgb(struct reply *r, const char *key_rgb, const char *key_y, const double rgb[3])
{
	/* Rec. 709 / sRGB primaries: the luminance of linear RGB. */
	double y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];

	reply_add(r, "%s: %.9g,%.9g,%.9g\n%s: %.9g\n", key_rgb, rgb[0], rgb[1], rgb[2], key_y, y);
}

/* The table a sample reads is not in the current slot: the connection now
 * demands it and the request (and the connection's input after it) waits
 * for the generation that brings it (PROTOCOL.md, "Demand"). */
static int sample_wait(struct client *c, uint32_t id, char *msg, size_t msg_size)
{
	update_demand(c->ctl);
	if (!(srv_tables_coming(c->ctl->srv) & (1u << id)))
		return ACK(SKY_ACK_STATE, "no %s table published yet", state_table_names[id]);
	c->deferred = strdup(c->line);
	if (!c->deferred)
		return ACK(SKY_ACK_LIMIT, "out of memory");
	return -1;
}

/* Samples the current slot exactly as a client would (skysample.h). The
 * daemon is its only writer and runs on this thread, so no seqlock retry. */
static int cmd_sample(struct client *c, const struct proto_request *req, struct reply *r,
		      char *msg, size_t msg_size)
{
	const struct pub *p = srv_pub(c->ctl->srv);
	const struct sky_shm_header *h = pub_header(p);
	const uint8_t *base;
	const struct sky_shm_slot *slot = pub_current(p, &base);
	const char *what = req->args[0].key;
	struct skysample_table t;
	double rgb[3];
	uint32_t id;

	if (req->args[0].value)
		return ACK(SKY_ACK_SYNTAX, "usage: sample sky el_deg=E az_deg=A | sample sun | sample ambient");
	if (strcmp(what, "sky") == 0 || strcmp(what, "ambient") == 0)
		id = SKY_TABLE_SKYVIEW;
	else if (strcmp(what, "sun") == 0)
		id = SKY_TABLE_TRANSMITTANCE;
	else
		return ACK(SKY_ACK_NO_EXIST, "%s: not sky, sun or ambient", what);
	if (strcmp(what, "sky") == 0) {
		double el, az;
		const char *ev = proto_arg_value(req->args, req->n_args, "el_deg");
		const char *av = proto_arg_value(req->args, req->n_args, "az_deg");
		for (int i = 1; i < req->n_args; i++)
			if (strcmp(req->args[i].key, "el_deg") && strcmp(req->args[i].key, "az_deg"))
				return ACK(SKY_ACK_NO_EXIST, "%s: unknown key (el_deg, az_deg)", req->args[i].key);
		if (!ev || !av)
			return ACK(SKY_ACK_SYNTAX, "usage: sample sky el_deg=E az_deg=A");
		if (parse_number(ev, &el) < 0)
			return ACK(SKY_ACK_ARG, "el_deg: '%s' is not a finite number", ev);
		if (parse_number(av, &az) < 0)
			return ACK(SKY_ACK_ARG, "az_deg: '%s' is not a finite number", av);
		if (el < -90 || el > 90)
			return ACK(SKY_ACK_RANGE, "el_deg: %g is outside [-90, 90]", el);
		if (az < -360 || az > 720)
			return ACK(SKY_ACK_RANGE, "az_deg: %g is outside [-360, 720]", az);
		c->sample_tables |= 1u << id;
		if (!(slot->valid_tables & (1u << id)))
			return sample_wait(c, id, msg, msg_size);
		if (skysample_table_from_slot(h, base, id, &t) < 0)
			return ACK(SKY_ACK_STATE, "no sky-view table published yet");
		skysample_sky(&t, &slot->state, el * SKYMAP_PI / 180.0, az * SKYMAP_PI / 180.0, rgb);
		reply_add(r, "generation: %llu\n", (unsigned long long)slot->generation);
		reply_rgb(r, "radiance_rgb_cd_m2", "luminance_cd_m2", rgb);
		return 0;
	}
	if (req->n_args > 1)
		return ACK(SKY_ACK_SYNTAX, "sample %s takes no arguments", what);
	c->sample_tables |= 1u << id;
	if (!(slot->valid_tables & (1u << id)))
		return sample_wait(c, id, msg, msg_size);
	if (skysample_table_from_slot(h, base, id, &t) < 0)
		return ACK(SKY_ACK_STATE, "no %s table published yet", state_table_names[id]);
	if (id == SKY_TABLE_TRANSMITTANCE)
		skysample_sun(&t, &slot->state, rgb);
	else
		skysample_ambient(&t, &slot->state, rgb);
	reply_add(r, "generation: %llu\n", (unsigned long long)slot->generation);
	reply_rgb(r, "illuminance_rgb_lx", "illuminance_lx", rgb);
	return 0;
}

/* Views ----------------------------------------------------------------- */

static int view_find(const struct sky_state *s, const char *name)
{
	for (uint32_t i = 0; i < s->n_views; i++)
		if (strcmp(s->views[i].name, name) == 0)
			return (int)i;
	return -1;
}

static void view_remove(struct sky_state *s, uint32_t i)
{
	memmove(&s->views[i], &s->views[i + 1], (s->n_views - i - 1) * sizeof(s->views[0]));
	s->n_views--;
	memset(&s->views[s->n_views], 0, sizeof(s->views[0]));
}

/* Views belong to the connection that added them and go with it: a view
 * nobody uses any more is dropped. */
static void views_drop_owner(struct ctl *ctl, uint64_t owner)
{
	struct sky_state next = *srv_state(ctl->srv);
	char err[256];
	uint64_t generation;
	int changed = 0;

	for (uint32_t i = next.n_views; i-- > 0;)
		if (next.views[i].owner == owner) {
			view_remove(&next, i);
			changed = 1;
		}
	if (changed && srv_change(ctl->srv, &next, STATE_BIT(STATE_AERIAL), &generation, err,
				  sizeof(err)) < 0)
		log_error("dropping the views of client %llu: %s", (unsigned long long)owner, err);
}

static const struct {
	const char *key;
	size_t offset;			/* in struct state_view */
	double min, max;
} view_keys[] = {
	{ "altitude_km", offsetof(struct state_view, altitude_km), -1e300, 1e7 },
	{ "yaw_deg", offsetof(struct state_view, camera.yaw_deg), -360, 720 },
	{ "pitch_deg", offsetof(struct state_view, camera.pitch_deg), -90, 90 },
	{ "roll_deg", offsetof(struct state_view, camera.roll_deg), -180, 180 },
	{ "vfov_deg", offsetof(struct state_view, camera.vfov_deg), 0.1, 179 },
	{ "aspect", offsetof(struct state_view, camera.aspect), 0.01, 100 },
};

static int parse_number(const char *v, double *ret);

static int view_add(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	struct sky_state next = *srv_state(c->ctl->srv);
	struct state_view v = { .altitude_km = NAN, .owner = c->id };
	const char *name = proto_arg_value(req->args, req->n_args, "name");

	state_default_camera(&v.camera);
	if (!name)
		return ACK(SKY_ACK_SYNTAX, "usage: view add name=NAME [altitude_km=H] [yaw_deg=] [pitch_deg=] [roll_deg=] [vfov_deg=] [aspect=]");
	size_t n = strlen(name);
	if (n == 0 || n >= STATE_VIEW_NAME_MAX || strspn(name, "abcdefghijklmnopqrstuvwxyz"
		"ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.") != n)
		return ACK(SKY_ACK_ARG, "name: '%s' is not 1 to %d letters, digits, '_', '-' or '.'",
			   name, STATE_VIEW_NAME_MAX - 1);
	snprintf(v.name, sizeof(v.name), "%s", name);
	for (int i = 1; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		size_t k;
		double d;
		if (!a->value)
			return ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		if (strcmp(a->key, "name") == 0)
			continue;
		for (k = 0; k < sizeof(view_keys) / sizeof(view_keys[0]); k++)
			if (strcmp(view_keys[k].key, a->key) == 0)
				break;
		if (k == sizeof(view_keys) / sizeof(view_keys[0]))
			return ACK(SKY_ACK_NO_EXIST, "%s: unknown key (name, altitude_km, yaw_deg, pitch_deg, roll_deg, vfov_deg, aspect)", a->key);
		if (parse_number(a->value, &d) < 0)
			return ACK(SKY_ACK_ARG, "%s: '%s' is not a finite number", a->key, a->value);
		if (d < view_keys[k].min || d > view_keys[k].max)
			return ACK(SKY_ACK_RANGE, "%s: %g is outside [%g, %g]", a->key, d,
				   view_keys[k].min, view_keys[k].max);
		*(double *)((char *)&v + view_keys[k].offset) = d;
	}
	int i = view_find(&next, v.name);
	if (i >= 0 && next.views[i].owner != c->id)
		return ACK(SKY_ACK_ARG, "name: view '%s' belongs to another connection", v.name);
	if (i < 0 && next.n_views == STATE_MAX_VIEWS)
		return ACK(SKY_ACK_LIMIT, "%d views already (SKY_SHM_MAX_VIEWS)", STATE_MAX_VIEWS);
	if (i < 0)
		i = (int)next.n_views++;
	int same = memcmp(&next.views[i], &v, sizeof(v)) == 0;
	next.views[i] = v;
	return commit(c, &next, same ? 0 : STATE_BIT(STATE_AERIAL), r, msg, msg_size);
}

static int cmd_view(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	const char *what = req->args[0].key;
	const struct sky_state *s = srv_state(c->ctl->srv);

	if (req->args[0].value)
		return ACK(SKY_ACK_SYNTAX, "usage: view add|del|list ...");
	if (strcmp(what, "add") == 0)
		return view_add(c, req, r, msg, msg_size);
	if (strcmp(what, "del") == 0) {
		const char *name = proto_arg_value(req->args, req->n_args, "name");
		if (!name || req->n_args != 2)
			return ACK(SKY_ACK_SYNTAX, "usage: view del name=NAME");
		int i = view_find(s, name);
		if (i < 0)
			return ACK(SKY_ACK_NO_EXIST, "name: no view '%s'", name);
		struct sky_state next = *s;
		view_remove(&next, (uint32_t)i);
		return commit(c, &next, STATE_BIT(STATE_AERIAL), r, msg, msg_size);
	}
	if (strcmp(what, "list") == 0) {
		if (req->n_args != 1)
			return ACK(SKY_ACK_SYNTAX, "usage: view list");
		for (uint32_t i = 0; i < s->n_views; i++) {
			const struct state_view *v = &s->views[i];
			char alt[32];
			if (isnan(v->altitude_km))
				snprintf(alt, sizeof(alt), "observer");
			else
				snprintf(alt, sizeof(alt), "%.9g", v->altitude_km);
			reply_add(r, "view: name=%s index=%u altitude_km=%s yaw_deg=%.9g pitch_deg=%.9g roll_deg=%.9g vfov_deg=%.9g aspect=%.9g mine=%d\n",
				  v->name, i, alt, v->camera.yaw_deg, v->camera.pitch_deg,
				  v->camera.roll_deg, v->camera.vfov_deg, v->camera.aspect,
				  v->owner == c->id);
		}
		return 0;
	}
	return ACK(SKY_ACK_NO_EXIST, "%s: not add, del or list", what);
}

static int cmd_commands(struct client *c, const struct proto_request *req, struct reply *r,
			char *msg, size_t msg_size)
{
	for (size_t i = 0; i < n_cmds; i++)
		reply_add(r, "command: %s\n", cmds[i].name);
	return 0;
}

static const struct cmd_entry *find_cmd(const char *name)
{
	for (size_t i = 0; i < n_cmds; i++)
		if (strcmp(cmds[i].name, name) == 0)
			return &cmds[i];
	return NULL;
}

static int cmd_help(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	const char *name = req->n_args ? req->args[0].key : "help";
	const struct cmd_entry *e = find_cmd(name);

	if (!e || (req->n_args && req->args[0].value))
		return ACK(SKY_ACK_NO_EXIST, "%s: unknown verb", name);
	reply_add(r, "usage: %s\nhelp: %s\n", e->usage, e->help);
	return 0;
}

static int cmd_ping(struct client *c, const struct proto_request *req, struct reply *r,
		    char *msg, size_t msg_size)
{
	return 0;
}

static int cmd_close(struct client *c, const struct proto_request *req, struct reply *r,
		     char *msg, size_t msg_size)
{
	c->closing = 1;
	return 0;
}

static const struct cmd_entry cmds[] = {
	{ "set", "set key=value ...", "change the sky; all or nothing; names the generation that shows it",
	  1, PROTO_MAX_ARGS, cmd_set },
	{ "get", "get [key ...] | get sun | get moon | get times [date=YYYY-MM-DD] [utc_offset_min=N]",
	  "the current state, every key or the named ones; the clock's sun, moon, or the day's rise, set and twilights",
	  0, PROTO_MAX_ARGS, cmd_get },
	{ "batch", "batch", "start a batch: set lines until end apply as one change (no reply until end)",
	  0, 0, cmd_batch },
	{ "end", "end", "apply the batch as one change", 0, 0, cmd_end },
	{ "status", "status", "generation, computation times, device, clients, last error", 0, 0, cmd_status },
	{ "subscribe", "subscribe [tables=LIST] [events=0|1]",
	  "tables: receive the shared memory (SCM_RIGHTS) and its layout; events: changed: lines",
	  1, 2, cmd_subscribe },
	{ "unsubscribe", "unsubscribe", "stop events and layout lines", 0, 0, cmd_unsubscribe },
	{ "sample", "sample sky el_deg=E az_deg=A | sample sun | sample ambient",
	  "sky radiance in a direction (no sun disk), the sun's illuminance at the observer, or the horizontal sky irradiance, from the published tables",
	  1, 3, cmd_sample },
	{ "view", "view add name=NAME [altitude_km=H] [yaw_deg=] [pitch_deg=] [roll_deg=] [vfov_deg=] [aspect=] | view del name=NAME | view list",
	  "cameras with their own aerial-perspective volume; a view lasts while the connection that added it is open",
	  1, 8, cmd_view },
	{ "commands", "commands", "list the verbs", 0, 0, cmd_commands },
	{ "help", "help [VERB]", "usage of a verb", 0, 1, cmd_help },
	{ "ping", "ping", "answer OK", 0, 0, cmd_ping },
	{ "close", "close", "answer OK and close the connection", 0, 0, cmd_close },
};
static const size_t n_cmds = sizeof(cmds) / sizeof(cmds[0]);

/* Requests -------------------------------------------------------------- */

static int send_ack(struct client *c, int code, const char *verb, const char *message)
{
	char line[512];
	int n = proto_format_ack(line, sizeof(line), code, verb, message);

	if (n >= (int)sizeof(line)) {
		n = (int)sizeof(line) - 1;
		line[n - 1] = '\n';
	}
	return client_queue(c, line, (size_t)n, -1);
}

/* Handles one line. Returns 0, or -1 if the client is gone. */
static int handle_line(struct client *c, char *line)
{
	struct proto_request req;
	char msg[512] = "", verb[PROTO_VERB_MAX] = "";
	struct reply r = { .fd = -1 };
	int code, ret;

	if (c->batch) {
		char copy[SKY_PROTO_LINE_MAX];
		snprintf(copy, sizeof(copy), "%s", line);
		if (proto_parse_request(copy, &req, msg, sizeof(msg)) != 0 || strcmp(req.verb, "end") != 0) {
			batch_line(c, line);
			return 0;
		}
	}
	char raw[SKY_PROTO_LINE_MAX];
	snprintf(raw, sizeof(raw), "%s", line);
	c->line = raw;
	int pr = proto_parse_request(line, &req, msg, sizeof(msg));
	if (pr == -ENODATA)
		return 0;
	if (pr < 0)
		return send_ack(c, pr == -E2BIG ? SKY_ACK_LIMIT : SKY_ACK_SYNTAX, req.verb ? req.verb : "", msg);
	snprintf(verb, sizeof(verb), "%s", req.verb);
	const struct cmd_entry *e = find_cmd(verb);
	if (!e)
		return send_ack(c, SKY_ACK_UNKNOWN, verb, "unknown verb; 'commands' lists them");
	if (req.n_args < e->min_args || req.n_args > e->max_args) {
		snprintf(msg, sizeof(msg), "usage: %s", e->usage);
		return send_ack(c, SKY_ACK_SYNTAX, verb, msg);
	}
	code = e->fn(c, &req, &r, msg, sizeof(msg));
	if (code != 0 && r.fd >= 0) {
		close(r.fd);
		r.fd = -1;
	}
	c->line = NULL;
	if (code < 0) {
		ret = 0;	/* answers later (batch, a sample waiting for its table) */
	} else if (code > 0) {
		ret = send_ack(c, code, verb, msg);
	} else {
		reply_add(&r, "OK\n");
		if (r.failed) {
			if (r.fd >= 0)
				close(r.fd);
			ret = send_ack(c, SKY_ACK_LIMIT, verb, "out of memory");
		} else {
			ret = client_queue_owned(c, r.buf, r.len, r.fd);
		}
	}
	free(r.buf);
	return ret;
}

/* Handles the complete lines in the buffer while the client reads its
 * replies. Returns 0, or -1 if the client is gone. */
static int process_input(struct client *c)
{
	size_t start = 0;

	while (!c->closing && !c->deferred && c->out_bytes < CTL_OUT_HIGH) {
		char *nl = memchr(c->in + start, '\n', c->in_len - start);
		char *line = c->in + start;
		if (nl) {
			*nl = 0;
			start = (size_t)(nl - c->in) + 1;
		} else if (c->eof && start < c->in_len && c->in_len < sizeof(c->in)) {
			/* A last line without its newline. */
			c->in[c->in_len] = 0;
			start = c->in_len;
		} else {
			break;
		}
		if (handle_line(c, line) < 0)
			return -1;
	}
	memmove(c->in, c->in + start, c->in_len - start);
	c->in_len -= start;
	if (c->in_len == sizeof(c->in)) {
		/* Full without a newline: the line is too long. Drop what came
		 * and what follows up to the next newline. */
		c->in_len = 0;
		if (!c->discarding) {
			c->discarding = 1;
			if (c->batch) {
				c->batch->lines++;
				if (!c->batch->error_code) {
					c->batch->error_code = SKY_ACK_TOO_LONG;
					snprintf(c->batch->error, sizeof(c->batch->error),
						 "line %d: over %d bytes", c->batch->lines, SKY_PROTO_LINE_MAX);
				}
			} else if (send_ack(c, SKY_ACK_TOO_LONG, "", "request line over SKY_PROTO_LINE_MAX bytes") < 0) {
				return -1;
			}
		}
	}
	if (c->eof && c->in_len == 0 && !c->deferred)
		c->closing = 1;
	return client_flush(c);
}

static void client_ready(void *ctx, uint32_t events)
{
	struct client *c = ctx;

	if (events & EPOLLOUT) {
		if (client_flush(c) < 0)
			return;
		/* Room again: the requests that waited. */
		if (c->out_bytes < CTL_OUT_HIGH && c->in_len && process_input(c) < 0)
			return;
	}
	if (events & (EPOLLIN | EPOLLHUP | EPOLLERR)) {
		if (!(c->io_events & EPOLLIN) && !(events & (EPOLLHUP | EPOLLERR)))
			return;
		ssize_t n = read(c->fd, c->in + c->in_len, sizeof(c->in) - c->in_len);
		if (n < 0 && (errno == EAGAIN || errno == EINTR))
			return;
		if (n < 0) {
			client_drop(c, strerror(errno));
			return;
		}
		if (n == 0) {
			c->eof = 1;
			if (events & EPOLLERR) {
				client_drop(c, NULL);
				return;
			}
		}
		if (c->discarding && n > 0) {
			/* Skip to the newline that ends the long line. */
			char *nl = memchr(c->in + c->in_len, '\n', (size_t)n);
			if (!nl)
				return;
			size_t rest = (size_t)n - (size_t)(nl + 1 - (c->in + c->in_len));
			memmove(c->in, nl + 1, rest);
			c->in_len = rest;
			c->discarding = 0;
		} else {
			c->in_len += (size_t)n;
		}
		process_input(c);
	}
}

/* Accepting ------------------------------------------------------------- */

static void accept_resume(void *ctx)
{
	struct ctl *ctl = ctx;

	if (ctl->accept_paused) {
		ctl->accept_paused = 0;
		loop_io_mod(ctl->listen_io, EPOLLIN);
	}
}

static void accept_ready(void *ctx, uint32_t events)
{
	struct ctl *ctl = ctx;

	for (int i = 0; i < 64; i++) {
		int fd = accept4(ctl->listen_fd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
		if (fd < 0) {
			if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
				/* Out of fds: stop accepting until a client leaves or
				 * 100 ms pass, instead of spinning on the ready socket.
				 * Said once, not on every retry. */
				if (!ctl->accept_warned)
					log_warning("accept: %s; pausing until a client leaves (retrying every 100 ms)",
						    strerror(errno));
				ctl->accept_warned = 1;
				ctl->accept_paused = 1;
				loop_io_mod(ctl->listen_io, 0);
				loop_timer_arm(ctl->accept_timer, 100000000u);
			}
			return;
		}
		if (ctl->accept_warned) {
			log_info("accepting connections again");
			ctl->accept_warned = 0;
		}
		if (ctl->n_clients >= CTL_MAX_CLIENTS) {
			static const char line[] = "ACK [52] {} too many clients\n";
			(void)!send(fd, line, sizeof(line) - 1, MSG_NOSIGNAL | MSG_DONTWAIT);
			close(fd);
			continue;
		}
		struct client *c = calloc(1, sizeof(*c));
		socklen_t len = sizeof(struct ucred);
		if (!c) {
			close(fd);
			continue;
		}
		c->ctl = ctl;
		c->fd = fd;
		c->id = ++ctl->next_id;
		if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &c->cred, &len) < 0)
			c->cred = (struct ucred){ .pid = 0, .uid = (uid_t)-1, .gid = (gid_t)-1 };
		c->io_events = EPOLLIN;
		if (loop_io_add(ctl->loop, fd, EPOLLIN, client_ready, c, &c->io) < 0) {
			close(fd);
			free(c);
			continue;
		}
		c->next = ctl->clients;
		if (c->next)
			c->next->prev = c;
		ctl->clients = c;
		ctl->n_clients++;
		log_debug("client %llu: pid %d uid %d gid %d", (unsigned long long)c->id,
			  (int)c->cred.pid, (int)c->cred.uid, (int)c->cred.gid);
		char greeting[64];
		int n = snprintf(greeting, sizeof(greeting), "OK skyd %s\n", SKY_PROTO_VERSION);
		if (client_queue(c, greeting, (size_t)n, -1) == 0)
			client_flush(c);
	}
}

/* Socket ---------------------------------------------------------------- */

int ctl_default_path(char *buf, size_t size)
{
	const char *xdg = getenv("XDG_RUNTIME_DIR");
	int n = xdg && *xdg ? snprintf(buf, size, "%s/skyd/control", xdg)
			    : snprintf(buf, size, "/run/skyd/control");

	return n < 0 || (size_t)n >= size ? -ENAMETOOLONG : 0;
}

#define SET_ERR(...) (snprintf(err, err_size, __VA_ARGS__))

/* The directory of the socket: made 0700 if missing; if present, a real
 * directory (no symlink), ours, and writable by nobody else, so that no
 * one can swap the socket under us. */
static int check_dir(const char *path, char *err, size_t err_size)
{
	char dir[sizeof(((struct sockaddr_un *)0)->sun_path)];
	struct stat st;
	char *slash;

	snprintf(dir, sizeof(dir), "%s", path);
	slash = strrchr(dir, '/');
	if (!slash)
		snprintf(dir, sizeof(dir), ".");
	else if (slash == dir)
		slash[1] = 0;
	else
		*slash = 0;
	if (mkdir(dir, 0700) < 0 && errno != EEXIST) {
		int e = errno;
		SET_ERR("cannot create '%s': %s (create its parent or pass --socket)", dir, strerror(e));
		return -e;
	}
	if (lstat(dir, &st) < 0) {
		int e = errno;
		SET_ERR("'%s': %s", dir, strerror(e));
		return -e;
	}
	if (!S_ISDIR(st.st_mode)) {
		SET_ERR("'%s' is not a directory", dir);
		return -ENOTDIR;
	}
	if (st.st_uid != geteuid()) {
		SET_ERR("'%s' belongs to uid %d, not to us (uid %d); remove it or pass --socket",
			dir, (int)st.st_uid, (int)geteuid());
		return -EPERM;
	}
	if (st.st_mode & 022) {
		SET_ERR("'%s' is writable by group or others (mode %04o); chmod go-w it",
			dir, (unsigned)(st.st_mode & 07777));
		return -EPERM;
	}
	return 0;
}

static int make_socket(struct ctl *ctl, char *err, size_t err_size)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd, r;

	if (strlen(ctl->path) >= sizeof(sa.sun_path)) {
		SET_ERR("socket path '%s' is too long", ctl->path);
		return -ENAMETOOLONG;
	}
	r = check_dir(ctl->path, err, err_size);
	if (r < 0)
		return r;
	memcpy(sa.sun_path, ctl->path, strlen(ctl->path) + 1);
	fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
	if (fd < 0)
		return -errno;
	/* A socket that answers belongs to a live skyd; one that refuses is stale. */
	int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	if (probe >= 0) {
		if (connect(probe, (struct sockaddr *)&sa, sizeof(sa)) == 0) {
			close(probe);
			close(fd);
			SET_ERR("'%s': another skyd is listening there", ctl->path);
			return -EADDRINUSE;
		}
		close(probe);
	}
	unlink(ctl->path);
	mode_t old = umask(077);
	r = bind(fd, (struct sockaddr *)&sa, sizeof(sa));
	umask(old);
	if (r < 0 || listen(fd, 128) < 0) {
		r = -errno;
		close(fd);
		SET_ERR("'%s': %s", ctl->path, strerror(-r));
		return r;
	}
	ctl->created_socket = 1;
	ctl->listen_fd = fd;
	return 0;
}

int ctl_new(struct loop *l, struct srv *s, const char *path, int listen_fd, char *err,
	    size_t err_size, struct ctl **ret)
{
	struct ctl *ctl = calloc(1, sizeof(*ctl));
	int r;

	if (!ctl)
		return -ENOMEM;
	ctl->loop = l;
	ctl->srv = s;
	ctl->listen_fd = -1;
	snprintf(ctl->path, sizeof(ctl->path), "%s", path);
	if (listen_fd >= 0) {
		ctl->listen_fd = listen_fd;
		fcntl(listen_fd, F_SETFL, fcntl(listen_fd, F_GETFL) | O_NONBLOCK);
	} else {
		r = make_socket(ctl, err, err_size);
		if (r < 0)
			goto fail;
	}
	r = loop_timer_add(l, accept_resume, ctl, &ctl->accept_timer);
	if (r < 0)
		goto fail;
	r = loop_io_add(l, ctl->listen_fd, EPOLLIN, accept_ready, ctl, &ctl->listen_io);
	if (r < 0)
		goto fail;
	*ret = ctl;
	return 0;
fail:
	if (!err[0])
		SET_ERR("control socket: %s", strerror(-r));
	ctl_free(ctl);
	return r;
}

void ctl_set_drive(struct ctl *ctl, struct drive *d)
{
	ctl->drive = d;
}

void ctl_free(struct ctl *ctl)
{
	if (!ctl)
		return;
	ctl->finishing = 1;	/* no demand or view changes on the way out */
	while (ctl->clients)
		client_drop(ctl->clients, NULL);
	loop_io_del(ctl->listen_io);
	loop_timer_del(ctl->accept_timer);
	if (ctl->listen_fd >= 0)
		close(ctl->listen_fd);
	if (ctl->created_socket)
		unlink(ctl->path);
	free(ctl);
}

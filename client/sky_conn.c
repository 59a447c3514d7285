/* sky_conn.c - libsky's connection to skyd: connecting and the greeting,
 * reconnecting, the non-blocking send queue, reading the socket (with the
 * descriptors that come with replies), requests, sky_dispatch() and
 * subscribing. What is read is parsed by sky_input.c. */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "proto.h"
#include "sky_internal.h"

/* Closes descriptors that came with the stream and were never used. */
static void close_fds(sky_client *c)
{
	for (unsigned i = 0; i < c->n_fds; i++)
		close(c->fds[i]);
	c->n_fds = 0;
}

/* Forgets the connection: socket, buffers, pending requests. Keeps the
 * mapping (still readable) and the queued events. */
static void drop_connection(sky_client *c)
{
	if (c->fd >= 0)
		close(c->fd);
	c->fd = -1;
	c->in_len = 0;
	c->out_len = c->out_off = 0;
	c->pend_count = c->pend_head = 0;
	c->in_batch = false;
	sky_reply_free(c->cur);
	c->cur = NULL;
	close_fds(c);
	c->greeted = false;
}

/* The peer is gone: drops the connection and queues one SKY_EVENT_HANGUP
 * (not a second for a connection already dropped). Reconnecting by itself
 * (sky_set_reconnect), the client says nothing until it is back: the
 * first attempt comes at once, later ones an interval apart. */
static void hang_up(sky_client *c)
{
	if (c->fd < 0 && c->hung_up)
		return;
	drop_connection(c);
	c->hung_up = true;
	c->resyncing = c->resub_sent = false;
	if (c->reconnect_ms > 0) {
		if (!c->lost) {
			c->lost = true;
			c->resync_serial = c->map_serial;
			c->next_try_ms = sky_now_ms();
		}
		return;
	}
	struct sky_event ev = { .type = SKY_EVENT_HANGUP };
	(void)sky_event_push(c, &ev, NULL);
}

/* Reads what the socket holds without blocking, keeping the descriptors
 * that come with it in c->fds. 1 if bytes came, 0 if none, -ECONNRESET on
 * end of stream, other -errno. */
static int read_some(sky_client *c)
{
	if (c->in_cap - c->in_len < 4096) {
		size_t cap = c->in_cap ? c->in_cap * 2 : 8192;
		if (cap > SKY_IN_MAX + 8192)
			cap = SKY_IN_MAX + 8192;
		if (cap <= c->in_len)
			return -EPROTO;
		char *p = realloc(c->in, cap);
		if (!p)
			return -ENOMEM;
		c->in = p;
		c->in_cap = cap;
	}
	union {
		struct cmsghdr h;
		char buf[CMSG_SPACE(sizeof(int) * SKY_MAX_FDS)];
	} cm;
	/* Leave a byte for the terminator handle_input writes. */
	struct iovec iov = { c->in + c->in_len, c->in_cap - c->in_len - 1 };
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1, .msg_control = cm.buf,
			     .msg_controllen = sizeof(cm.buf) };
	ssize_t n = recvmsg(c->fd, &mh, MSG_DONTWAIT | MSG_CMSG_CLOEXEC);
	if (n < 0)
		return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -errno;
	for (struct cmsghdr *h = CMSG_FIRSTHDR(&mh); h; h = CMSG_NXTHDR(&mh, h)) {
		if (h->cmsg_level != SOL_SOCKET || h->cmsg_type != SCM_RIGHTS)
			continue;
		size_t k = (h->cmsg_len - CMSG_LEN(0)) / sizeof(int);
		int fds[SKY_MAX_FDS];
		memcpy(fds, CMSG_DATA(h), k * sizeof(int));
		for (size_t i = 0; i < k; i++) {
			if (c->n_fds < SKY_MAX_FDS)
				c->fds[c->n_fds++] = fds[i];
			else
				close(fds[i]);
		}
	}
	if (n == 0)
		return -ECONNRESET;
	c->in_len += (size_t)n;
	return 1;
}

/* Writes queued bytes without blocking. 0 (maybe some left), -errno. */
static int flush_out(sky_client *c)
{
	while (c->out_off < c->out_len) {
		ssize_t n = send(c->fd, c->out + c->out_off, c->out_len - c->out_off,
				 MSG_DONTWAIT | MSG_NOSIGNAL);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			if (errno == EAGAIN || errno == EWOULDBLOCK)
				return 0;
			return -errno;
		}
		c->out_off += (size_t)n;
		c->bytes_sent += (uint64_t)n;
	}
	c->out_off = c->out_len = 0;
	return 0;
}

/* Reads and parses whatever is there; on end of stream or a garbled stream
 * hangs up. Returns 0 or -errno (-ECONNRESET after a hang-up). */
static int pump_input(sky_client *c)
{
	for (;;) {
		int r = read_some(c);
		if (r == 0)
			return 0;
		if (r > 0)
			r = sky_input_lines(c);
		if (r < 0) {
			hang_up(c);
			return r == -ECONNRESET || r == -EPIPE ? -ECONNRESET : r;
		}
	}
}

/* A close-on-exec socket connected to path, non-blocking if asked (a
 * Unix socket connects at once or not at all). 0 or -errno. */
static int open_socket(const char *path, bool nonblock, int *ret_fd)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	if (strlen(path) >= sizeof(sa.sun_path))
		return -ENAMETOOLONG;
	strcpy(sa.sun_path, path);
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | (nonblock ? SOCK_NONBLOCK : 0), 0);
	if (fd < 0)
		return -errno;
	if (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
		int e = -errno;
		close(fd);
		return e;
	}
	*ret_fd = fd;
	return 0;
}

/* The loop that serves the greeting, sky_request() and sky_wait()'s layout
 * change. */
int sky_pump_until(sky_client *c, bool (*cond)(const sky_client *), int timeout_ms,
		      bool drop_on_timeout)
{
	int64_t deadline = timeout_ms < 0 ? -1 : sky_now_ms() + timeout_ms;
	while (!cond(c)) {
		if (c->fd < 0)
			return -ECONNRESET;
		struct pollfd pfd = { c->fd, POLLIN | (c->out_len > c->out_off ? POLLOUT : 0), 0 };
		int n = poll(&pfd, 1, sky_left_ms(deadline));
		if (n < 0 && errno != EINTR)
			return -errno;
		if (n == 0) {
			/* A late reply would be taken for the next request's: drop the line. */
			if (drop_on_timeout) {
				drop_connection(c);
				c->hung_up = true;
			}
			return -ETIMEDOUT;
		}
		if (n < 0)
			continue;
		if (pfd.revents & POLLOUT) {
			int r = flush_out(c);
			if (r < 0) {
				hang_up(c);
				return -ECONNRESET;
			}
		}
		if (pfd.revents & (POLLIN | POLLHUP | POLLERR)) {
			int r = pump_input(c);
			/* "close": the reply came, then the end of the stream */
			if (r < 0 && !cond(c))
				return r;
		}
	}
	return 0;
}

static bool greeted(const sky_client *c)
{
	return c->greeted;
}

static bool sync_done(const sky_client *c)
{
	return c->sync_done;
}

/* Connects to c->path and waits (c->timeout_ms) for the greeting. 0 or
 * -errno; on failure the client is left hung up, without a socket. */
static int do_connect(sky_client *c)
{
	int fd = -1;
	int r = open_socket(c->path, false, &fd);
	if (r < 0)
		return r;
	c->fd = fd;
	c->hung_up = false;
	c->greeted = false;
	c->bytes_sent = 0;
	r = sky_pump_until(c, greeted, c->timeout_ms, true);
	if (r < 0) {
		drop_connection(c);
		c->hung_up = true;
		/* A daemon that closes before greeting is not a protocol error of ours. */
		return r;
	}
	return 0;
}

sky_client *sky_client_alloc(void)
{
	sky_client *c = calloc(1, sizeof(*c));
	if (c) {
		c->fd = -1;
		c->timeout_ms = SKY_DEFAULT_TIMEOUT_MS;
	}
	return c;
}

int sky_connect(const char *path, sky_client **ret_client)
{
	if (!ret_client)
		return -EINVAL;
	sky_client *c = sky_client_alloc();
	if (!c)
		return -ENOMEM;
	int r;
	if (path) {
		if (strlen(path) >= sizeof(c->path)) {
			r = -ENAMETOOLONG;
			goto fail;
		}
		strcpy(c->path, path);
	} else if ((r = sky_default_path(c->path, sizeof(c->path))) < 0) {
		goto fail;
	}
	r = do_connect(c);
	if (r < 0)
		goto fail;
	sky_events_clear(c);
	*ret_client = c;
	return 0;
fail:
	sky_disconnect(c);
	return r;
}

void sky_disconnect(sky_client *c)
{
	if (!c)
		return;
	drop_connection(c);
	sky_events_clear(c);
	free(c->evq);
	sky_reply_free(c->sync_reply);
	sky_unmap(c);
	free(c->in);
	free(c->out);
	free(c);
}

const char *sky_protocol_version(const sky_client *c)
{
	return c ? c->proto_version : NULL;
}

void sky_set_timeout(sky_client *c, int timeout_ms)
{
	if (c)
		c->timeout_ms = timeout_ms;
}

/* The length of a request line fit to send: printable, not empty, shorter
 * than SKY_PROTO_LINE_MAX. -EINVAL otherwise. */
static int check_line(const char *line)
{
	size_t n = 0;
	for (const unsigned char *p = (const unsigned char *)line; *p; p++, n++)
		if (*p < 0x20 || *p == 0x7f)
			return -EINVAL;
	return n == 0 || n >= SKY_PROTO_LINE_MAX ? -EINVAL : (int)n;
}

/* True if line's first word is verb. */
static bool is_verb(const char *line, const char *verb)
{
	size_t n = strlen(verb);
	return strncmp(line, verb, n) == 0 && (line[n] == 0 || line[n] == ' ');
}

/* Appends line + newline to the output queue and records what waits for
 * its reply. */
static int queue_line(sky_client *c, const char *line, size_t n, uint64_t userdata, bool sync)
{
	if (c->pend_count >= SKY_MAX_PENDING)
		return -EAGAIN;
	if (c->out_off && c->out_off == c->out_len)
		c->out_off = c->out_len = 0;
	if (c->out_len + n + 1 > SKY_OUT_MAX)
		return -EAGAIN;
	if (!c->out) {
		c->out = malloc(SKY_OUT_MAX);
		if (!c->out)
			return -ENOMEM;
	}
	memcpy(c->out + c->out_len, line, n);
	c->out[c->out_len + n] = '\n';
	c->out_len += n + 1;
	/* "batch" and the lines inside it are answered only by "end". */
	c->unanswered = c->in_batch ? !is_verb(line, "end") : is_verb(line, "batch");
	if (c->in_batch && !c->unanswered)
		c->in_batch = false;
	else if (!c->in_batch && c->unanswered)
		c->in_batch = true;
	if (c->unanswered)
		return 0;
	return sky_pending_push(c, userdata, sync, is_verb(line, "subscribe"));
}

static void reconnected(sky_client *c);

/* Queues and starts writing a line; if the peer turns out to be gone before
 * any byte of it was delivered, reconnects once and queues it again. */
static int send_line(sky_client *c, const char *line, uint64_t userdata, bool sync)
{
	int n = check_line(line);
	if (n < 0)
		return n;
	for (int attempt = 0;; attempt++) {
		if (c->fd < 0) {
			bool was_lost = c->lost;
			unsigned serial = c->resync_serial;
			int r = sky_reconnect(c);
			if (r < 0) {
				/* Reconnecting by itself goes on later. */
				if (was_lost) {
					c->lost = true;
					c->resync_serial = serial;
				}
				return r;
			}
			/* Back while reconnecting by itself: still said once. */
			if (was_lost) {
				c->resync_serial = serial;
				reconnected(c);
			}
		}
		uint64_t before = c->bytes_sent + (c->out_len - c->out_off);
		int r = queue_line(c, line, (size_t)n, userdata, sync);
		if (r < 0)
			return r;
		r = flush_out(c);
		if (r == 0)
			return 0;
		bool delivered = c->bytes_sent > before;
		hang_up(c);
		if (delivered || attempt > 0)
			return -ECONNRESET;
	}
}

int sky_request(sky_client *c, const char *line, sky_reply **ret_reply)
{
	if (!c || !line)
		return -EINVAL;
	sky_reply_free(c->sync_reply);
	c->sync_reply = NULL;
	c->sync_done = false;
	int r = send_line(c, line, 0, true);
	if (r < 0)
		return r;
	if (c->unanswered) {
		if (ret_reply && !(*ret_reply = sky_reply_alloc()))
			return -ENOMEM;
		return 0;
	}
	r = sky_pump_until(c, sync_done, c->timeout_ms, true);
	if (r < 0)
		return r;
	sky_reply *rep = c->sync_reply;
	c->sync_reply = NULL;
	c->sync_done = false;
	int ack = rep->ack;
	if (ret_reply)
		*ret_reply = rep;
	else
		sky_reply_free(rep);
	return ack;
}

int sky_send(sky_client *c, const char *line, uint64_t userdata)
{
	if (!c || !line)
		return -EINVAL;
	return send_line(c, line, userdata, false);
}

int sky_get_fd(const sky_client *c)
{
	if (!c)
		return -EINVAL;
	return c->fd >= 0 ? c->fd : -ENOTCONN;
}

bool sky_want_write(const sky_client *c)
{
	return c && c->fd >= 0 && c->out_len > c->out_off;
}

int sky_dispatch(sky_client *c, struct sky_event *ret_event)
{
	if (!c || !ret_event)
		return -EINVAL;
	sky_reply_free(c->handed_out);
	c->handed_out = NULL;
	if (c->fd >= 0) {
		if (flush_out(c) < 0)
			hang_up(c);
	}
	if (c->fd >= 0) {
		int r = pump_input(c);
		if (r < 0 && r != -ECONNRESET && !c->ev_count)
			return r;
	}
	if (c->lost) {
		int r = sky_reconnect_step(c);
		if (r < 0 && !c->ev_count)
			return r;
	}
	if (!c->ev_count)
		return c->fd < 0 && c->hung_up && !c->lost ? -ENOTCONN : 0;
	struct sky_queued q = c->evq[c->ev_head];
	c->ev_head = (c->ev_head + 1) % c->ev_cap;
	c->ev_count--;
	c->handed_out = q.owned;
	*ret_event = q.ev;
	return 1;
}

/* Writes "subscribe tables=a,b[ events=1]" into buf; its length. */
static int subscribe_line(uint32_t tables, unsigned flags, char *buf, size_t size)
{
	int n = snprintf(buf, size, "subscribe tables=");
	bool first = true;
	for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++) {
		if (!(tables & SKY_TABLE_BIT(i)))
			continue;
		n += snprintf(buf + n, size - (size_t)n, "%s%s", first ? "" : ",", proto_table_name(i));
		first = false;
	}
	if (flags & SKY_SUBSCRIBE_EVENTS)
		n += snprintf(buf + n, size - (size_t)n, " events=1");
	return n;
}

/* Subscribes and maps the memfd of the reply. 0, the ACK code, or -errno
 * (the mapping's failure included). */
static int subscribe_now(sky_client *c, uint32_t tables, unsigned flags)
{
	char line[256];
	subscribe_line(tables, flags, line, sizeof(line));
	c->map_error = 0;
	int r = sky_request(c, line, NULL);
	if (r != 0)
		return r;
	return c->map_error;
}

int sky_subscribe(sky_client *c, uint32_t tables, unsigned flags)
{
	if (!c || !tables || (tables & ~(SKY_TABLES_ALL | SKY_TABLES_CLOUDS)) ||
	    (flags & ~(unsigned)SKY_SUBSCRIBE_EVENTS))
		return -EINVAL;
	int r = subscribe_now(c, tables, flags);
	if (r == 0) {
		c->subscribed = true;
		c->sub_tables = tables;
		c->sub_flags = flags;
	}
	return r;
}

int sky_reconnect(sky_client *c)
{
	if (!c)
		return -EINVAL;
	drop_connection(c);
	sky_events_clear(c);
	c->hung_up = true;
	c->lost = c->resyncing = c->resub_sent = false;
	int r = do_connect(c);
	if (r < 0)
		return r;
	if (c->subscribed) {
		r = subscribe_now(c, c->sub_tables, c->sub_flags);
		if (r != 0) {
			drop_connection(c);
			c->hung_up = true;
			return r > 0 ? -EPROTO : r;
		}
	}
	return 0;
}

int sky_set_reconnect(sky_client *c, int interval_ms)
{
	if (!c || interval_ms < 0)
		return -EINVAL;
	c->reconnect_ms = interval_ms;
	if (!interval_ms) {
		c->lost = c->resyncing = c->resub_sent = false;
		if (c->fd < 0)
			c->hung_up = true;
		return 0;
	}
	/* Already disconnected (its hang-up seen): from the next call on. */
	if (c->fd < 0 && !c->lost) {
		c->lost = true;
		c->resync_serial = c->map_serial;
		c->next_try_ms = sky_now_ms();
	}
	return 0;
}

/* Queues the subscription the client had, marked as libsky's own. */
static int resubscribe(sky_client *c)
{
	char line[256];
	int n = subscribe_line(c->sub_tables, c->sub_flags, line, sizeof(line));
	int r = queue_line(c, line, (size_t)n, 0, false);
	if (r < 0)
		return r;
	c->pend[(c->pend_head + c->pend_count - 1) % SKY_MAX_PENDING].internal = true;
	c->map_error = 0;
	c->resub_sent = true;
	return flush_out(c);
}

/* Tells the application, once, that the connection is back. */
static void reconnected(sky_client *c)
{
	struct sky_event ev = {
		.type = SKY_EVENT_RECONNECTED,
		.userdata = c->map_serial != c->resync_serial,
		.tables = c->subscribed ? c->sub_tables : 0,
		.generation = c->map ? __atomic_load_n(&c->map->generation, __ATOMIC_ACQUIRE) : 0,
	};
	c->lost = c->resyncing = c->resub_sent = false;
	(void)sky_event_push(c, &ev, NULL);
}

int sky_reconnect_step(sky_client *c)
{
	if (c->reconnect_ms <= 0)
		return 0;
	/* A client that only waits on the futex hears of a hang-up here. */
	if (!c->lost && c->fd >= 0) {
		int r = pump_input(c);
		if (r < 0 && r != -ECONNRESET)
			return r;
	}
	if (!c->lost)
		return 0;
	if (c->fd < 0) {
		int64_t now = sky_now_ms();
		int fd;
		if (now < c->next_try_ms)
			return 0;
		c->next_try_ms = now + c->reconnect_ms;
		if (open_socket(c->path, true, &fd) < 0)
			return 0;
		c->fd = fd;
		c->hung_up = false;
		c->greeted = false;
		c->bytes_sent = 0;
		c->resyncing = true;
		c->resub_sent = false;
	}
	int r = pump_input(c);
	if (r < 0)
		return r == -ECONNRESET ? 0 : r;
	if (!c->greeted || c->resub_sent)
		return 0;
	if (!c->subscribed) {
		reconnected(c);
		return 0;
	}
	if (resubscribe(c) < 0)
		hang_up(c);
	return 0;
}

int sky_resynced(sky_client *c, sky_reply *r)
{
	int ack = r->ack;

	sky_reply_free(r);
	c->resub_sent = false;
	/* Refused, or the memory failed its checks: try again later. */
	if (ack != 0 || c->map_error < 0)
		return -ECONNRESET;
	reconnected(c);
	return 0;
}

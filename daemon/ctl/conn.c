/* conn.c - one client connection: its bounded output queue, the framing of
 * its input into request lines, and the dispatch of each line through the
 * command table to a reply or an ACK. */
#include "ctl_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"

/* One queued piece of output; fd (if >= 0) travels with its first byte. */
struct chunk {
	struct chunk *next;
	int fd;
	size_t len, off;
	char data[];
};

static int handle_line(struct client *c, char *line);
static int process_input(struct client *c);

/* Output ---------------------------------------------------------------- */

void ctl_reply_add(struct reply *r, const char *fmt, ...)
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

/* Queues len bytes and owned_fd (if >= 0), which it takes in all cases.
 * Returns 0, or -1 when the client was dropped for exceeding its bound or
 * for lack of memory. */
static int client_queue_owned(struct client *c, const char *data, size_t len, int owned_fd)
{
	struct chunk *k;

	if (c->dead) {
		if (owned_fd >= 0)
			close(owned_fd);
		return -1;
	}
	if (c->out_bytes + len > CTL_OUT_MAX) {
		if (owned_fd >= 0)
			close(owned_fd);
		ctl_client_drop(c, "output queue over its bound (the client does not read)");
		return -1;
	}
	k = malloc(sizeof(*k) + len);
	if (!k) {
		if (owned_fd >= 0)
			close(owned_fd);
		ctl_client_drop(c, "out of memory");
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

/* A line that must carry an fd means nothing without it: when no fd is
 * free the client is dropped (it reconnects) rather than sent the line
 * alone. */
int ctl_client_queue(struct client *c, const char *data, size_t len, int fd)
{
	int dup = -1;

	if (c->dead)
		return -1;
	if (fd >= 0) {
		dup = fcntl(fd, F_DUPFD_CLOEXEC, 3);
		if (dup < 0) {
			char why[128];
			snprintf(why, sizeof(why), "no fd to pass the shared memory: %s", strerror(errno));
			ctl_client_drop(c, why);
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

/* Sends the chunk's first bytes with its fd as SCM_RIGHTS. */
static ssize_t send_with_fd(struct client *c, struct chunk *k)
{
	union {
		char buf[CMSG_SPACE(sizeof(int))];
		struct cmsghdr align;
	} u;
	struct iovec iov = { k->data, k->len };
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1,
			     .msg_control = u.buf, .msg_controllen = sizeof(u.buf) };
	struct cmsghdr *cm = CMSG_FIRSTHDR(&mh);
	ssize_t n;

	cm->cmsg_level = SOL_SOCKET;
	cm->cmsg_type = SCM_RIGHTS;
	cm->cmsg_len = CMSG_LEN(sizeof(int));
	memcpy(CMSG_DATA(cm), &k->fd, sizeof(int));
	n = sendmsg(c->fd, &mh, MSG_NOSIGNAL | MSG_DONTWAIT);
	if (n > 0) {
		close(k->fd);
		k->fd = -1;
	}
	return n;
}

int ctl_client_flush(struct client *c)
{
	if (c->dead)
		return -1;
	while (c->out_head) {
		struct chunk *k = c->out_head;
		ssize_t n;
		if (k->fd >= 0 && k->off == 0)
			n = send_with_fd(c, k);
		else
			n = send(c->fd, k->data + k->off, k->len - k->off, MSG_NOSIGNAL | MSG_DONTWAIT);
		if (n < 0) {
			if (errno == EAGAIN || errno == EINTR)
				break;
			ctl_client_drop(c, strerror(errno));
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
		ctl_client_drop(c, NULL);
		return -1;
	}
	client_update_events(c);
	return 0;
}

static void free_output(struct client *c)
{
	while (c->out_head) {
		struct chunk *k = c->out_head;
		c->out_head = k->next;
		chunk_free(k);
	}
	c->out_tail = NULL;
	c->out_bytes = 0;
}

/* The loop's release of a dropped client, once no handler is on the stack. */
static void client_release(void *ctx)
{
	struct client *c = ctx;

	free_output(c);
	free(c->batch);
	free(c->deferred);
	free(c);
}

void ctl_client_drop(struct client *c, const char *why)
{
	struct ctl *ctl = c->ctl;

	if (c->dead)
		return;
	if (why)
		log_info("client %llu (pid %d uid %d) dropped: %s", (unsigned long long)c->id,
			 (int)c->cred.pid, (int)c->cred.uid, why);
	else
		log_debug("client %llu closed", (unsigned long long)c->id);
	c->dead = 1;
	close(c->fd);
	c->fd = -1;
	free_output(c);
	/* c->next stays as it was: a walk of the list that stands on c goes on
	 * from there, past entries that are dead too. */
	if (c->prev)
		c->prev->next = c->next;
	else
		ctl->clients = c->next;
	if (c->next)
		c->next->prev = c->prev;
	ctl->n_clients--;
	loop_io_retire(c->io, client_release);
	if (!ctl->finishing) {
		ctl_update_demand(ctl);
		ctl_views_drop_owner(ctl, c->id);
	}
	/* A freed fd may be what accept was waiting for. */
	if (ctl->accept_paused) {
		ctl->accept_paused = 0;
		loop_timer_arm(ctl->accept_timer, 0);
		loop_io_mod(ctl->listen_io, EPOLLIN);
	}
}

/* Requests -------------------------------------------------------------- */

static int send_ack(struct client *c, int code, const char *verb, const char *message)
{
	char line[512];
	int n = proto_format_ack(line, sizeof(line), code, verb, message);

	if (n >= (int)sizeof(line)) {
		n = (int)sizeof(line) - 1;
		line[n - 1] = '\n';
	}
	return ctl_client_queue(c, line, (size_t)n, -1);
}

void ctl_resume_deferred(struct ctl *ctl, int failed)
{
	struct client *c, *next;

	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (c->dead || !c->deferred)
			continue;
		char *line = c->deferred;
		c->deferred = NULL;
		int r = failed ? send_ack(c, SKY_ACK_ENGINE, "sample",
					  "the computation of the table failed; see status")
			       : handle_line(c, line);
		free(line);
		if (r == 0 && !c->dead && !c->deferred)
			process_input(c);
	}
}

/* Queues what the handler answered: its reply with OK, or its ACK. */
static int answer(struct client *c, const char *verb, int code, struct reply *r,
		  const char *msg)
{
	if (code != 0 && r->fd >= 0) {
		close(r->fd);
		r->fd = -1;
	}
	if (code < 0)
		return 0;	/* answers later (batch, a sample waiting for its table) */
	if (code > 0)
		return send_ack(c, code, verb, msg);
	ctl_reply_add(r, "OK\n");
	if (r->failed) {
		if (r->fd >= 0)
			close(r->fd);
		return send_ack(c, SKY_ACK_LIMIT, verb, "out of memory");
	}
	return client_queue_owned(c, r->buf, r->len, r->fd);
}

/* Handles one line: inside a batch every line but end goes to the batch;
 * otherwise the verb's handler answers. Returns 0, or -1 if the client is
 * gone. */
static int handle_line(struct client *c, char *line)
{
	struct proto_request req;
	char msg[512] = "", verb[PROTO_VERB_MAX] = "";
	struct reply r = { .fd = -1 };
	int ret;

	if (c->dead)
		return -1;
	if (c->batch) {
		char copy[SKY_PROTO_LINE_MAX];
		snprintf(copy, sizeof(copy), "%s", line);
		if (proto_parse_request(copy, &req, msg, sizeof(msg)) != 0 || strcmp(req.verb, "end") != 0) {
			ctl_batch_line(c, line);
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
	const struct ctl_cmd *e = ctl_find_cmd(verb);
	if (!e)
		return send_ack(c, SKY_ACK_UNKNOWN, verb, "unknown verb; 'commands' lists them");
	if (req.n_args < e->min_args || req.n_args > e->max_args) {
		snprintf(msg, sizeof(msg), "usage: %s", e->usage);
		return send_ack(c, SKY_ACK_SYNTAX, verb, msg);
	}
	int code = ctl_need_role(c, e->need, msg, sizeof(msg));
	if (code)
		return send_ack(c, code, verb, msg);
	code = e->fn(c, &req, &r, msg, sizeof(msg));
	c->line = NULL;
	ret = answer(c, verb, code, &r, msg);
	free(r.buf);
	return ret;
}

/* A line too long for the buffer: refused once, in the batch if one is
 * open. Returns 0, or -1 if the client is gone. */
static int refuse_long_line(struct client *c)
{
	struct batch *b = c->batch;

	if (!b)
		return send_ack(c, SKY_ACK_TOO_LONG, "", "request line over SKY_PROTO_LINE_MAX bytes") < 0
		       ? -1 : 0;
	b->lines++;
	if (!b->error_code) {
		b->error_code = SKY_ACK_TOO_LONG;
		snprintf(b->error, sizeof(b->error), "line %d: over %d bytes", b->lines,
			 SKY_PROTO_LINE_MAX);
	}
	return 0;
}

/* Handles the complete lines in the buffer while the client reads its
 * replies. Returns 0, or -1 if the client is gone. */
static int process_input(struct client *c)
{
	size_t start = 0;

	if (c->dead)
		return -1;
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
		if (handle_line(c, line) < 0 || c->dead)
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
			if (refuse_long_line(c) < 0)
				return -1;
		}
	}
	if (c->eof && c->in_len == 0 && !c->deferred)
		c->closing = 1;
	return ctl_client_flush(c);
}

/* Reads what came; a long line's rest is skipped up to its newline. */
static void client_read(struct client *c, uint32_t events)
{
	if (!(c->io_events & EPOLLIN) && !(events & (EPOLLHUP | EPOLLERR)))
		return;
	ssize_t n = read(c->fd, c->in + c->in_len, sizeof(c->in) - c->in_len);
	if (n < 0 && (errno == EAGAIN || errno == EINTR))
		return;
	if (n < 0) {
		ctl_client_drop(c, strerror(errno));
		return;
	}
	if (n == 0) {
		c->eof = 1;
		if (events & EPOLLERR) {
			ctl_client_drop(c, NULL);
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

static void client_ready(void *ctx, uint32_t events)
{
	struct client *c = ctx;

	if (events & EPOLLOUT) {
		if (ctl_client_flush(c) < 0)
			return;
		/* Room again: the requests that waited. */
		if (c->out_bytes < CTL_OUT_HIGH && c->in_len && process_input(c) < 0)
			return;
	}
	if (!c->dead && (events & (EPOLLIN | EPOLLHUP | EPOLLERR)))
		client_read(c, events);
}

/* Takes fd (closed on failure), records the peer and greets it. */
int ctl_client_add(struct ctl *ctl, int fd)
{
	struct client *c = calloc(1, sizeof(*c));
	socklen_t len = sizeof(struct ucred);
	int r;

	if (!c) {
		close(fd);
		return -ENOMEM;
	}
	c->ctl = ctl;
	c->fd = fd;
	c->id = ++ctl->next_id;
	if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &c->cred, &len) < 0)
		c->cred = (struct ucred){ .pid = 0, .uid = (uid_t)-1, .gid = (gid_t)-1 };
	c->role = role_of_peer(&ctl->roles, fd, &c->cred);
	c->io_events = EPOLLIN;
	r = loop_io_add(ctl->loop, fd, EPOLLIN, client_ready, c, &c->io);
	if (r < 0) {
		close(fd);
		free(c);
		return r;
	}
	c->next = ctl->clients;
	if (c->next)
		c->next->prev = c;
	ctl->clients = c;
	ctl->n_clients++;
	log_debug("client %llu: pid %d uid %d gid %d, %s", (unsigned long long)c->id,
		  (int)c->cred.pid, (int)c->cred.uid, (int)c->cred.gid, role_name(c->role));
	char greeting[64];
	int n = snprintf(greeting, sizeof(greeting), "OK skyd %s\n", SKY_PROTO_VERSION);
	if (ctl_client_queue(c, greeting, (size_t)n, -1) == 0)
		ctl_client_flush(c);
	return 0;
}

/* sky_input.c - what libsky reads from skyd: the greeting, replies and their
 * completion in request order, event lines, and the queue of events that
 * sky_dispatch() hands out. Works on the bytes sky_conn.c has read; does no
 * I/O of its own. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "sky_internal.h"

int sky_pending_push(sky_client *c, uint64_t userdata, bool sync, bool subscribe)
{
	if (c->pend_count >= SKY_MAX_PENDING)
		return -EAGAIN;
	struct sky_pending *p = &c->pend[(c->pend_head + c->pend_count) % SKY_MAX_PENDING];
	p->userdata = userdata;
	p->sync = sync;
	p->subscribe = subscribe;
	p->internal = false;
	c->pend_count++;
	return 0;
}

int sky_event_push(sky_client *c, const struct sky_event *ev, sky_reply *owned)
{
	if (c->ev_count == c->ev_cap) {
		size_t cap = c->ev_cap ? c->ev_cap * 2 : 16;
		struct sky_queued *q = malloc(cap * sizeof(*q));
		if (!q)
			return -ENOMEM;
		for (size_t i = 0; i < c->ev_count; i++)
			q[i] = c->evq[(c->ev_head + i) % c->ev_cap];
		free(c->evq);
		c->evq = q;
		c->ev_head = 0;
		c->ev_cap = cap;
	}
	struct sky_queued *slot = &c->evq[(c->ev_head + c->ev_count) % c->ev_cap];
	slot->ev = *ev;
	slot->owned = owned;
	c->ev_count++;
	return 0;
}

void sky_events_clear(sky_client *c)
{
	for (size_t i = 0; i < c->ev_count; i++)
		sky_reply_free(c->evq[(c->ev_head + i) % c->ev_cap].owned);
	c->ev_head = c->ev_count = 0;
	sky_reply_free(c->handed_out);
	c->handed_out = NULL;
}

/* Takes the oldest descriptor that came with the stream, -1 if none. Each
 * arrives with the first byte of the line that needs it, so the oldest is
 * the one of the line being handled. */
static int take_fd(sky_client *c)
{
	if (!c->n_fds)
		return -1;
	int fd = c->fds[0];
	memmove(c->fds, c->fds + 1, --c->n_fds * sizeof(int));
	return fd;
}

/* An event line (key and value from proto_parse_reply) -> a queued event;
 * a layout line maps the region that came with it first. */
static int handle_event(sky_client *c, const char *key, char *value)
{
	struct proto_event pe;
	if (proto_parse_event(key, value, &pe) < 0)
		return -EPROTO;
	struct sky_event ev = { .type = SKY_EVENT_CHANGED, .generation = (uint32_t)pe.generation };
	if (pe.kind == PROTO_EVENT_FAILED)
		ev.type = SKY_EVENT_FAILED;
	if (pe.tables)
		ev.tables = proto_table_mask(pe.tables);
	if (pe.kind == PROTO_EVENT_LAYOUT) {
		/* The new region came with the line; without it the line is garbage. */
		int fd = take_fd(c);
		if (fd < 0)
			return -EPROTO;
		int r = sky_map_memfd(c, fd);
		if (r < 0)
			return r;
		ev.type = SKY_EVENT_LAYOUT;
	}
	sky_reply *owned = NULL;
	if (pe.message) {
		/* The message lives as long as the event: in a reply freed with it. */
		if (!(owned = sky_reply_alloc()) || !(owned->message = strdup(pe.message))) {
			sky_reply_free(owned);
			return -ENOMEM;
		}
		ev.message = owned->message;
	}
	int r = sky_event_push(c, &ev, owned);
	if (r < 0)
		sky_reply_free(owned);
	return r;
}

/* OK or ACK closed c->cur: hands it to the oldest request that waits for a
 * reply (sky_request() or an event for sky_dispatch()), mapping the memfd a
 * successful subscribe brings. -EPROTO when no request waits. */
static int complete_reply(sky_client *c)
{
	sky_reply *r = c->cur;
	c->cur = NULL;
	if (!c->pend_count) {
		sky_reply_free(r);
		return -EPROTO;
	}
	struct sky_pending p = c->pend[c->pend_head];
	c->pend_head = (c->pend_head + 1) % SKY_MAX_PENDING;
	c->pend_count--;
	if (p.subscribe && r->ack == 0) {
		int fd = take_fd(c);
		c->map_error = fd < 0 ? -EPROTO : sky_map_memfd(c, fd);
	}
	if (p.internal)
		return sky_resynced(c, r);
	if (p.sync) {
		c->sync_reply = r;
		c->sync_done = true;
		return 0;
	}
	struct sky_event ev = { .type = SKY_EVENT_REPLY, .userdata = p.userdata, .ack = r->ack,
				.reply = r };
	int e = sky_event_push(c, &ev, r);
	if (e < 0)
		sky_reply_free(r);
	return e;
}

/* The greeting "OK skyd <version>": libsky speaks to a daemon of its own
 * major version (what precedes the first '.'). A skyd at its connection
 * bound greets with one ACK [52] line and closes: -EAGAIN, try later. */
static int handle_greeting(sky_client *c, char *line)
{
	struct proto_reply rep;
	if (proto_parse_reply(line, &rep) < 0)
		return -EPROTO;
	if (rep.kind == PROTO_ACK && rep.ack_code == SKY_ACK_LIMIT)
		return -EAGAIN;
	if (rep.kind != PROTO_OK || strncmp(rep.value, "skyd ", 5) != 0)
		return -EPROTO;
	const char *v = rep.value + 5;
	size_t len = strlen(v);
	if (len >= sizeof(c->proto_version))
		return -EPROTO;
	memcpy(c->proto_version, v, len + 1);
	size_t a = strcspn(v, "."), b = strcspn(SKY_PROTO_VERSION, ".");
	if (a != b || memcmp(v, SKY_PROTO_VERSION, a) != 0)
		return -EPROTONOSUPPORT;
	c->greeted = true;
	return 0;
}

/* One line from skyd, parsed by proto's reply grammar. Event lines may come
 * between replies only, and no reply uses their keys, so they are events
 * wherever they arrive. */
static int handle_line(sky_client *c, char *line)
{
	struct proto_reply rep;
	if (!c->greeted)
		return handle_greeting(c, line);
	if (proto_parse_reply(line, &rep) < 0)
		return -EPROTO;
	if (rep.kind == PROTO_EVENT)
		return handle_event(c, rep.key, line + (rep.value - line));
	if (!c->cur && !(c->cur = sky_reply_alloc()))
		return -ENOMEM;
	switch (rep.kind) {
	case PROTO_OK:
		return complete_reply(c);
	case PROTO_ACK:
		/* An ACK without a code would read as success. */
		if (rep.ack_code <= 0)
			return -EPROTO;
		if (sky_reply_set_ack(c->cur, rep.ack_code, rep.ack_verb, rep.ack_message) < 0)
			return -ENOMEM;
		return complete_reply(c);
	default:
		return sky_reply_add_pair(c->cur, rep.key, rep.value);
	}
}

int sky_input_lines(sky_client *c)
{
	size_t start = 0;
	int r = 0;
	for (;;) {
		char *nl = memchr(c->in + start, '\n', c->in_len - start);
		if (!nl)
			break;
		*nl = 0;
		r = handle_line(c, c->in + start);
		start = (size_t)(nl - c->in) + 1;
		if (r < 0)
			break;
	}
	memmove(c->in, c->in + start, c->in_len - start);
	c->in_len -= start;
	if (r == 0 && c->in_len >= SKY_IN_MAX)
		r = -EPROTO;
	return r;
}

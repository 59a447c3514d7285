/* sky_input.c - what libsky reads from skyd: the greeting, replies and their
 * completion in request order, event lines, and the queue of events that
 * sky_dispatch() hands out. Works on the bytes sky_conn.c has read; does no
 * I/O of its own. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sky_internal.h"

sky_client *sky_client_alloc(void)
{
	sky_client *c = calloc(1, sizeof(*c));
	if (c) {
		c->fd = -1;
		c->timeout_ms = SKY_DEFAULT_TIMEOUT_MS;
	}
	return c;
}

int sky_pending_push(sky_client *c, uint64_t userdata, bool sync, bool subscribe)
{
	if (c->pend_count >= SKY_MAX_PENDING)
		return -EAGAIN;
	struct sky_pending *p = &c->pend[(c->pend_head + c->pend_count) % SKY_MAX_PENDING];
	p->userdata = userdata;
	p->sync = sync;
	p->subscribe = subscribe;
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

static bool is_event_line(const char *line, size_t len)
{
	static const char *const pfx[] = { "changed: ", "failed: ", "layout: " };
	for (size_t i = 0; i < sizeof(pfx) / sizeof(pfx[0]); i++) {
		size_t n = strlen(pfx[i]);
		if (len >= n && memcmp(line, pfx[i], n) == 0)
			return true;
	}
	return false;
}

static uint32_t parse_tables(char *list)
{
	uint32_t mask = 0;
	char *save = NULL;
	for (char *t = strtok_r(list, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
		for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++)
			if (strcmp(t, sky_table_names[i]) == 0)
				mask |= SKY_TABLE_BIT(i);
		if (strcmp(t, "all") == 0)
			mask = SKY_TABLES_ALL;
	}
	return mask;
}

/* "changed: generation=N tables=a,b", "failed: generation=N message=text",
 * "layout: generation=N bytes=B" (with the new memfd) -> events. Unknown
 * words are ignored: a later protocol may add some. */
static int handle_event_line(sky_client *c, const char *line, size_t len)
{
	struct sky_event ev = { .type = SKY_EVENT_CHANGED };
	sky_reply *owned = NULL;
	char buf[512];
	size_t n = len < sizeof(buf) - 1 ? len : sizeof(buf) - 1;
	memcpy(buf, line, n);
	buf[n] = 0;
	char *colon = strchr(buf, ':');
	*colon = 0;
	if (strcmp(buf, "failed") == 0)
		ev.type = SKY_EVENT_FAILED;
	else if (strcmp(buf, "layout") == 0)
		ev.type = SKY_EVENT_LAYOUT;
	char *save = NULL;
	for (char *w = strtok_r(colon + 1, " ", &save); w; w = strtok_r(NULL, " ", &save)) {
		if (strncmp(w, "generation=", 11) == 0) {
			ev.generation = (uint32_t)strtoull(w + 11, NULL, 10);
		} else if (strncmp(w, "tables=", 7) == 0) {
			ev.tables = parse_tables(w + 7);
		} else if (strncmp(w, "message=", 8) == 0 && !owned) {
			if (!(owned = sky_reply_alloc()) || !(owned->message = strdup(w + 8))) {
				sky_reply_free(owned);
				return -ENOMEM;
			}
			ev.message = owned->message;
		}
	}
	if (ev.type == SKY_EVENT_LAYOUT) {
		/* The new region came with the line; without it the line is garbage. */
		if (!c->n_fds)
			return -EPROTO;
		int fd = c->fds[0];
		memmove(c->fds, c->fds + 1, --c->n_fds * sizeof(int));
		int r = sky_map_memfd(c, fd);
		if (r < 0)
			return r;
	}
	int r = sky_event_push(c, &ev, owned);
	if (r < 0)
		sky_reply_free(owned);
	return r;
}

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
		if (c->n_fds) {
			int fd = c->fds[0];
			memmove(c->fds, c->fds + 1, --c->n_fds * sizeof(int));
			c->map_error = sky_map_memfd(c, fd);
		} else {
			c->map_error = -EPROTO;
		}
	}
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

static int handle_line(sky_client *c, char *line, size_t len)
{
	if (len && line[len - 1] == '\r')
		line[--len] = 0;
	if (!c->greeted) {
		/* "OK skyd <version>" */
		if (len < 8 || memcmp(line, "OK skyd ", 8) != 0 || len - 8 >= sizeof(c->proto_version))
			return -EPROTO;
		memcpy(c->proto_version, line + 8, len - 8);
		c->proto_version[len - 8] = 0;
		size_t a = strcspn(c->proto_version, "."), b = strcspn(SKY_PROTO_VERSION, ".");
		if (a != b || memcmp(c->proto_version, SKY_PROTO_VERSION, a) != 0)
			return -EPROTONOSUPPORT;
		c->greeted = true;
		return 0;
	}
	if ((!c->cur || c->cur->n == 0) && is_event_line(line, len))
		return handle_event_line(c, line, len);
	if (!c->cur && !(c->cur = sky_reply_alloc()))
		return -ENOMEM;
	if (len == 2 && memcmp(line, "OK", 2) == 0)
		return complete_reply(c);
	if (len >= 5 && memcmp(line, "ACK [", 5) == 0) {
		char *end;
		long code = strtol(line + 5, &end, 10);
		if (end == line + 5 || *end != ']' || code <= 0 || code > 9999)
			return -EPROTO;
		end++;
		while (*end == ' ')
			end++;
		c->cur->ack = (int)code;
		if (!(c->cur->message = strdup(end)))
			return -ENOMEM;
		return complete_reply(c);
	}
	return sky_reply_add_line(c->cur, line, len);
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
		r = handle_line(c, c->in + start, (size_t)(nl - (c->in + start)));
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

/* Reads what the socket holds without blocking. 1 if bytes came, 0 if none,
 * -ECONNRESET on end of stream, other -errno. */

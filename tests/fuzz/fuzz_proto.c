/* fuzz_proto.c - libFuzzer target for both ends of the control protocol.
 * skyd's end: every line of the input is parsed as a request, and a set is
 * applied to a copy of the state and validated as skyd does. The clients'
 * end: the whole input is a stream from skyd into libsky's own input code
 * (sky_input.c: greeting, replies, ACKs, event lines, the event queue), once
 * from a fresh connection and once after the greeting. Built without
 * libFuzzer, a main() replays the files named on the command line
 * (fuzz_replay.h). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "sky_internal.h"
#include "state.h"

static void one_line(char *line, const struct sky_state *base)
{
	char copy[SKY_PROTO_LINE_MAX + 1], err[256];
	struct proto_request req;
	struct proto_reply rep;
	struct proto_arg args[16];

	snprintf(copy, sizeof(copy), "%s", line);
	if (proto_parse_request(copy, &req, err, sizeof(err)) == 0) {
		if (!strcmp(req.verb, "set")) {
			struct sky_state s = *base;
			uint32_t dirty = 0;
			for (int i = 0; i < req.n_args; i++)
				if (!req.args[i].value ||
				    state_set(&s, req.args[i].key, req.args[i].value, &dirty, err, sizeof(err)) < 0)
					return;
			state_validate(&s, 0, err, sizeof(err));
		} else if (!strcmp(req.verb, "get")) {
			char buf[256];
			for (int i = 0; i < req.n_args; i++)
				state_get(base, req.args[i].key, buf, sizeof(buf));
		} else if (!strcmp(req.verb, "subscribe") && req.n_args) {
			uint32_t mask;
			const char *t = proto_arg_value(req.args, req.n_args, "tables");
			if (t)
				state_parse_tables(t, &mask);
		}
	}
	snprintf(copy, sizeof(copy), "%s", line);
	if (proto_parse_reply(copy, &rep) == 0 && rep.kind == PROTO_EVENT) {
		char v[SKY_PROTO_LINE_MAX + 1];
		snprintf(v, sizeof(v), "%s", rep.value);
		proto_split_args(v, args, 16);
	}
	char ack[SKY_PROTO_LINE_MAX + 64];
	proto_format_ack(ack, sizeof(ack), SKY_ACK_SYNTAX, "x", line);
}

/* Reads what an application reads: the events sky_dispatch() hands out and
 * every accessor of a reply (into sink, so that no read is optimised out). */
static volatile size_t sink;

static void drain_events(sky_client *c)
{
	struct sky_event ev;

	while (sky_dispatch(c, &ev) == 1) {
		if (ev.message)
			sink += strlen(ev.message);
		if (ev.type != SKY_EVENT_REPLY)
			continue;
		if (ev.ack != sky_reply_ack(ev.reply) || (ev.ack && !sky_reply_message(ev.reply)[0]))
			abort();	/* an ACK's message holds at least "{verb}" */
		for (size_t i = 0; i < sky_reply_count(ev.reply); i++) {
			const char *key = sky_reply_key(ev.reply, i), *value = sky_reply_value(ev.reply, i);
			if (!key[0] || !value)
				abort();	/* proto's grammar: a key, then ": " */
			sink += strlen(value);
		}
		sink += (size_t)sky_reply_get(ev.reply, "generation");
	}
	if (c->sync_done) {
		/* as sky_request() takes its reply */
		sky_reply_free(c->sync_reply);
		c->sync_reply = NULL;
		c->sync_done = false;
	}
}

/* The input as skyd's side of a connection: handed to libsky's line code a
 * line at a time, as reads may deliver it, with two replies always due (one
 * in four a subscribe, whose memfd never comes; one in eight waited for as
 * sky_request() waits). Stops where libsky would hang up. */
static void client_stream(const uint8_t *data, size_t size, bool greeted)
{
	sky_client *c = sky_client_alloc();
	unsigned k = 0;

	if (!c || !(c->in = malloc(size + 1))) {
		sky_disconnect(c);
		return;
	}
	c->in_cap = size + 1;
	c->greeted = greeted;
	for (size_t i = 0; i < size;) {
		const uint8_t *nl = memchr(data + i, '\n', size - i);
		size_t n = nl ? (size_t)(nl - (data + i)) + 1 : size - i;
		for (; c->pend_count < 2; k++)
			sky_pending_push(c, k, k % 8 == 5, k % 4 == 3);
		memcpy(c->in + c->in_len, data + i, n);
		c->in_len += n;
		i += n;
		if (sky_input_lines(c) < 0)
			break;
		drain_events(c);
	}
	drain_events(c);
	sky_disconnect(c);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct sky_state base;
	static int ready;
	char line[SKY_PROTO_LINE_MAX + 1];
	size_t n = 0;

	if (!ready) {
		state_default(&base);
		ready = 1;
	}
	/* Lines as skyd frames them: at most SKY_PROTO_LINE_MAX bytes, NULs
	 * end the C string early just as they would in skyd. */
	for (size_t i = 0; i <= size; i++) {
		if (i == size || data[i] == '\n' || n == SKY_PROTO_LINE_MAX) {
			line[n] = 0;
			one_line(line, &base);
			n = 0;
			continue;
		}
		line[n++] = (char)data[i];
	}
	client_stream(data, size, false);
	client_stream(data, size, true);
	return 0;
}

#include "fuzz_replay.h"

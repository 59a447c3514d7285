/* cmd_state.c - the verbs that read and change the sky's state: set, get
 * (its key=value part; get weather and get clouds are cmd_weather.c's),
 * batch and end. */
#include "ctl_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "srv.h"

/* The ACK code of a state_set refusal, from its -errno. */
static int set_error_code(int r)
{
	switch (r) {
	case -ENOENT:
		return SKY_ACK_NO_EXIST;
	case -ERANGE:
		return SKY_ACK_RANGE;
	default:
		return SKY_ACK_ARG;
	}
}

/* Applies the args of a set to s; a metar= is noted for the reply. Returns
 * 0 or an ACK code with msg. */
static int apply_pairs(struct sky_state *s, const struct proto_request *req, uint32_t *dirty,
		       struct ctl_metar *metar, char *msg, size_t msg_size)
{
	char err[256];

	for (int i = 0; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return CTL_ACK(SKY_ACK_SYNTAX, "'%s': key=value expected", a->key);
		err[0] = 0;
		int r = strcmp(a->key, state_key_name(STATE_KEY_ID_METAR)) == 0
			? ctl_apply_metar(s, a->value, dirty, metar, err, sizeof(err))
			: state_set(s, a->key, a->value, dirty, err, sizeof(err));
		if (r < 0)
			return CTL_ACK(set_error_code(r), "%s", err[0] ? err : strerror(-r));
	}
	return 0;
}

int ctl_commit(struct client *c, const struct sky_state *next, uint32_t dirty, struct reply *r,
	       char *msg, size_t msg_size)
{
	char err[256] = "", names[64];
	uint64_t generation;
	int e = srv_apply(c->ctl->srv, next, dirty, &generation, &dirty, err, sizeof(err));

	if (e == -ERANGE)
		return CTL_ACK(SKY_ACK_RANGE, "%s", err);
	if (e < 0)
		return CTL_ACK(SKY_ACK_ENGINE, "state unchanged, computation failed: %s", err);
	state_format_tables(dirty, names, sizeof(names));
	ctl_reply_add(r, "generation: %llu\ntables: %s\n", (unsigned long long)generation, names);
	return 0;
}

int ctl_sky_follows(struct ctl *ctl, char *who, size_t who_size)
{
	return ctl->sync.may_change && !ctl->sync.may_change(ctl->sync.ctx, who, who_size);
}

int ctl_sync_refuse(struct ctl *ctl, char *msg, size_t msg_size)
{
	char who[128];

	if (!ctl_sky_follows(ctl, who, sizeof(who)))
		return 0;
	return CTL_ACK(SKY_ACK_PERMISSION, "this skyd follows controller %s: change the sky there",
		       who);
}

int ctl_cmd_set(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size)
{
	struct sky_state next = *srv_state(c->ctl->srv);
	struct ctl_metar metar = { 0 };
	uint32_t dirty = 0;
	int code = ctl_sync_refuse(c->ctl, msg, msg_size);

	if (!code)
		code = apply_pairs(&next, req, &dirty, &metar, msg, msg_size);

	if (!code)
		code = ctl_commit(c, &next, dirty, r, msg, msg_size);
	if (!code)
		ctl_reply_metar(r, &metar);
	return code;
}

static void emit_pair(void *ctx, const char *key, const char *value)
{
	ctl_reply_add(ctx, "%s: %s\n", key, value);
}

int ctl_cmd_get(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	char buf[256];

	if (req->n_args && !req->args[0].value) {
		if (strcmp(req->args[0].key, "sun") == 0)
			return ctl_get_sun(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "moon") == 0)
			return ctl_get_moon(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "times") == 0)
			return ctl_get_times(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "weather") == 0)
			return ctl_get_weather(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "clouds") == 0)
			return ctl_get_clouds(c, req, r, msg, msg_size);
		if (strcmp(req->args[0].key, "sensor") == 0)
			return ctl_get_sensor(c, req, r, msg, msg_size);
	}
	if (!req->n_args) {
		state_foreach(s, emit_pair, r);
		return 0;
	}
	for (int i = 0; i < req->n_args; i++) {
		const char *key = req->args[i].key;
		if (req->args[i].value)
			return CTL_ACK(SKY_ACK_SYNTAX, "'%s=': key names expected, without values", key);
		if (state_get(s, key, buf, sizeof(buf)) < 0)
			return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown key", key);
		ctl_reply_add(r, "%s: %s\n", key, buf);
	}
	return 0;
}

/* batch and the set lines inside it answer nothing; end answers for all. */
int ctl_cmd_batch(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size)
{
	c->batch = calloc(1, sizeof(*c->batch));
	if (!c->batch)
		return CTL_ACK(SKY_ACK_LIMIT, "out of memory");
	c->batch->state = *srv_state(c->ctl->srv);
	return -1;
}

void ctl_batch_line(struct client *c, const char *line)
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
		code = apply_pairs(&b->state, &req, &b->dirty, &b->metar, msg, sizeof(msg));
	if (code) {
		b->error_code = code;
		snprintf(b->error, sizeof(b->error), "line %d: %s", b->lines, msg);
	}
}

int ctl_cmd_end(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size)
{
	struct batch *b = c->batch;
	int code;

	if (!b)
		return CTL_ACK(SKY_ACK_STATE, "no batch to end");
	c->batch = NULL;
	if (b->error_code)
		code = CTL_ACK(b->error_code, "%s; nothing applied", b->error);
	else if (!(code = ctl_sync_refuse(c->ctl, msg, msg_size)))
		code = ctl_commit(c, &b->state, b->dirty, r, msg, msg_size);
	if (!code)
		ctl_reply_metar(r, &b->metar);
	free(b);
	return code;
}


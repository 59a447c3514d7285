/* proto.h - the line grammar of the control protocol, one parser shared by
 * skyd, libsky, skyctl and the fuzz target.
 *
 * A request is one line "verb arg arg ...", where an arg is key=value or a
 * bare word, separated by spaces or tabs; a value in double quotes
 * (key="a b") keeps its spaces and loses the quotes. A reply is "key: value" lines
 * closed by "OK" or "ACK [code] {verb} message"; event lines ("changed:",
 * "layout:", "failed:") may arrive between replies, never inside one.
 * Everything is parsed in place: the returned pointers point into the line
 * and stay valid as long as the caller's buffer does.
 */
#ifndef SKYD_PROTO_H
#define SKYD_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "skyproto.h"

#define PROTO_MAX_ARGS 128		/* args per request; a 4 KiB line cannot hold many more */
#define PROTO_VERB_MAX 32

struct proto_arg {
	const char *key;		/* the bare word when value is NULL */
	const char *value;		/* after '=', may be empty; NULL for a bare word */
};

struct proto_request {
	const char *verb;
	int n_args;
	struct proto_arg args[PROTO_MAX_ARGS];
};

/* Splits line (NUL-terminated, without its newline; a trailing '\r' is
 * ignored) in place into ret. Returns 0; -ENODATA for a blank line; -EINVAL
 * for a malformed line (control or non-ASCII bytes, a verb or key that is not
 * [a-z0-9_], "=value" without a key, a quoted value without its closing
 * quote or with text right after it) or -E2BIG for too many args, with a
 * message in err. ret is unspecified on failure. */
int proto_parse_request(char *line, struct proto_request *ret, char *err, size_t err_size);

/* Splits "k=v k=v ..." (the value of an event or table line) in place.
 * Returns the number of args stored (at most max) or -EINVAL. */
int proto_split_args(char *s, struct proto_arg *ret, int max);

/* The value of key among args, or NULL. A bare word counts as key with "". */
const char *proto_arg_value(const struct proto_arg *args, int n, const char *key);

enum proto_reply_kind {
	PROTO_PAIR,			/* key: value, part of a reply */
	PROTO_EVENT,			/* changed: / layout: / failed:, outside replies */
	PROTO_OK,			/* "OK" or the greeting "OK skyd <version>" */
	PROTO_ACK,
};

struct proto_reply {
	enum proto_reply_kind kind;
	const char *key, *value;	/* PAIR and EVENT; for OK, value is what follows "OK " or "" */
	int ack_code;			/* ACK */
	const char *ack_verb, *ack_message;
};

/* Parses one reply line in place. Returns 0 or -EINVAL if it is none of the
 * four kinds. */
int proto_parse_reply(char *line, struct proto_reply *ret);

/* 1 if key names an event line. */
int proto_is_event(const char *key);

enum proto_event_kind {
	PROTO_EVENT_CHANGED,		/* changed: generation=N tables=LIST */
	PROTO_EVENT_LAYOUT,		/* layout: generation=N bytes=B (a new region's fd with it) */
	PROTO_EVENT_FAILED,		/* failed: generation=N message=TEXT (spaces as '_') */
};

struct proto_event {
	enum proto_event_kind kind;
	uint64_t generation;
	const char *tables;		/* changed: the comma list; NULL when absent */
	uint64_t bytes;			/* layout: the new region's size; 0 when absent */
	const char *message;		/* failed: why; NULL when absent */
};

/* Parses the value of an event line (key and value as proto_parse_reply
 * gave them, value writable) in place. Keys it does not know are skipped,
 * so that a later protocol may add some. Returns 0, or -EINVAL when key is
 * no event, value is not a k=v list or generation= is missing or not a
 * decimal number. */
int proto_parse_event(const char *key, char *value, struct proto_event *ret);

/* The protocol's name of table id (enum sky_shm_table_id), NULL past the
 * last. */
const char *proto_table_name(unsigned id);

/* The bits (1 << id) of the tables a comma list names, "all" for the sky's
 * four (the cloud tables, "cloud" and "shadow", by name only).
 * Names it does not know add nothing: in an event they may be a later
 * protocol's tables. */
uint32_t proto_table_mask(const char *list);

/* Writes "ACK [code] {verb} message\n" into buf, replacing any byte of the
 * message that could break the line (control, non-ASCII) with '?'. Returns
 * the length as snprintf does. */
/* A number as the protocol writes it: the whole string, finite, parsed in
 * the C locale whatever the process locale (a value that underflows reads
 * as its denormal or 0). Returns 0 or -EINVAL; *ret untouched on failure. */
int proto_parse_number(const char *v, double *ret);

int proto_format_ack(char *buf, size_t size, int code, const char *verb, const char *message);

/* The symbolic name of an ACK code ("syntax", "range", ...) or "unknown". */
const char *proto_ack_name(int code);

#endif

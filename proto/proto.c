/* proto.c - the control protocol's line tokenizer and reply parser. */
#include "proto.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ERR(...) (snprintf(err, err_size, __VA_ARGS__), -EINVAL)

static int is_name_char(unsigned char c)
{
	return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
}

static int is_space(char c)
{
	return c == ' ' || c == '\t';
}

/* Cuts the next space-separated token out of *pp into *ret: 1, or 0 at the
 * end. A value may be quoted: in key="a b" the quotes go and the spaces
 * between them stay (no escapes; a value cannot hold '"'). Only a quote
 * right after the first '=' opens one, so every line that parsed before
 * quoting existed parses the same, but for values that began with '"'.
 * -EINVAL for an unclosed quote or text right after the closing one. */
static int next_token(char **pp, char **ret)
{
	char *p = *pp, *eq = NULL;

	while (is_space(*p))
		p++;
	if (!*p)
		return 0;
	*ret = p;
	while (*p && !is_space(*p)) {
		if (*p == '=' && !eq) {
			eq = p;
			if (p[1] != '"') {
				p++;
				continue;
			}
			char *close = strchr(p + 2, '"');
			if (!close || (close[1] && !is_space(close[1])))
				return -EINVAL;
			/* Shift the quoted text over the opening quote. */
			memmove(p + 1, p + 2, (size_t)(close - (p + 2)));
			close[-1] = 0;
			*pp = close[1] ? close + 2 : close + 1;
			return 1;
		}
		p++;
	}
	if (*p)
		*p++ = 0;
	*pp = p;
	return 1;
}

static int split_arg(char *tok, struct proto_arg *ret, char *err, size_t err_size)
{
	char *eq = strchr(tok, '=');

	if (eq)
		*eq = 0;
	if (!*tok)
		return ERR("'=%.32s': key=value expected", eq ? eq + 1 : "");
	for (char *c = tok; *c; c++)
		if (!is_name_char((unsigned char)*c))
			return ERR("'%.32s': a key is lower-case letters, digits and _", tok);
	ret->key = tok;
	ret->value = eq ? eq + 1 : NULL;
	return 0;
}

static int check_bytes(char *line, char *err, size_t err_size)
{
	size_t len = strlen(line);

	if (len && line[len - 1] == '\r')
		line[--len] = 0;
	for (size_t i = 0; i < len; i++) {
		unsigned char c = (unsigned char)line[i];
		if ((c < 0x20 && c != '\t') || c >= 0x7f)
			return ERR("byte 0x%02x at column %zu is not printable ASCII", c, i + 1);
	}
	return 0;
}

int proto_parse_request(char *line, struct proto_request *ret, char *err, size_t err_size)
{
	char *p = line, *tok;
	int r;

	ret->verb = NULL;
	ret->n_args = 0;
	r = check_bytes(line, err, err_size);
	if (r < 0)
		return r;
	r = next_token(&p, &tok);
	if (r == 0)
		return -ENODATA;
	if (r < 0)
		return ERR("'%.32s': a quoted value needs its closing '\"' and a space after it", tok);
	for (char *c = tok; *c; c++)
		if (!is_name_char((unsigned char)*c))
			return ERR("verb '%.32s' is not lower-case letters, digits and _", tok);
	if (strlen(tok) >= PROTO_VERB_MAX)
		return ERR("verb '%.32s...' is too long", tok);
	ret->verb = tok;
	while ((r = next_token(&p, &tok)) != 0) {
		if (r < 0)
			return ERR("'%.32s': a quoted value needs its closing '\"' and a space after it", tok);
		if (ret->n_args == PROTO_MAX_ARGS)
			return snprintf(err, err_size, "more than %d arguments", PROTO_MAX_ARGS), -E2BIG;
		r = split_arg(tok, &ret->args[ret->n_args], err, err_size);
		if (r < 0)
			return r;
		ret->n_args++;
	}
	return 0;
}

int proto_split_args(char *s, struct proto_arg *ret, int max)
{
	char err[8], *tok, *p = s;
	int n = 0, r;

	if (check_bytes(s, err, sizeof(err)) < 0)
		return -EINVAL;
	while ((r = next_token(&p, &tok)) != 0) {
		struct proto_arg a;
		if (r < 0)
			return -EINVAL;
		if (split_arg(tok, &a, err, sizeof(err)) < 0)
			return -EINVAL;
		if (n < max)
			ret[n++] = a;
	}
	return n;
}

const char *proto_arg_value(const struct proto_arg *args, int n, const char *key)
{
	for (int i = 0; i < n; i++)
		if (strcmp(args[i].key, key) == 0)
			return args[i].value ? args[i].value : "";
	return NULL;
}

int proto_is_event(const char *key)
{
	return strcmp(key, "changed") == 0 || strcmp(key, "layout") == 0 ||
	       strcmp(key, "failed") == 0;
}

/* A decimal number without sign, as skyd prints generations and sizes. */
static int parse_u64(const char *s, uint64_t *ret)
{
	char *end;

	if (!s || *s < '0' || *s > '9')
		return -EINVAL;
	errno = 0;
	unsigned long long v = strtoull(s, &end, 10);
	if (*end || errno)
		return -EINVAL;
	*ret = v;
	return 0;
}

int proto_parse_event(const char *key, char *value, struct proto_event *ret)
{
	struct proto_arg args[16];
	int n;

	memset(ret, 0, sizeof(*ret));
	if (strcmp(key, "changed") == 0)
		ret->kind = PROTO_EVENT_CHANGED;
	else if (strcmp(key, "layout") == 0)
		ret->kind = PROTO_EVENT_LAYOUT;
	else if (strcmp(key, "failed") == 0)
		ret->kind = PROTO_EVENT_FAILED;
	else
		return -EINVAL;
	n = proto_split_args(value, args, (int)(sizeof(args) / sizeof(args[0])));
	if (n < 0 || parse_u64(proto_arg_value(args, n, "generation"), &ret->generation) < 0)
		return -EINVAL;
	ret->tables = proto_arg_value(args, n, "tables");
	ret->message = proto_arg_value(args, n, "message");
	if (proto_arg_value(args, n, "bytes") &&
	    parse_u64(proto_arg_value(args, n, "bytes"), &ret->bytes) < 0)
		return -EINVAL;
	return 0;
}

static const char *const table_names[SKY_SHM_MAX_TABLES] = {
	"transmittance", "multiscatter", "skyview", "aerial", "cloud", "shadow",
};

const char *proto_table_name(unsigned id)
{
	return id < SKY_SHM_MAX_TABLES ? table_names[id] : NULL;
}

uint32_t proto_table_mask(const char *list)
{
	uint32_t mask = 0;

	while (*list) {
		size_t n = strcspn(list, ",");
		if (n == 3 && strncmp(list, "all", 3) == 0)
			mask |= (1u << (SKY_TABLE_AERIAL + 1)) - 1;	/* the sky's four, as skyd's "all" */
		for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++)
			if (strlen(table_names[i]) == n && strncmp(list, table_names[i], n) == 0)
				mask |= 1u << i;
		list += n;
		if (*list == ',')
			list++;
	}
	return mask;
}

int proto_parse_reply(char *line, struct proto_reply *ret)
{
	size_t len = strlen(line);

	if (len && line[len - 1] == '\r')
		line[--len] = 0;
	memset(ret, 0, sizeof(*ret));
	if (strcmp(line, "OK") == 0 || strncmp(line, "OK ", 3) == 0) {
		ret->kind = PROTO_OK;
		ret->value = line[2] ? line + 3 : "";
		return 0;
	}
	if (strncmp(line, "ACK [", 5) == 0) {
		char *end;
		long code = strtol(line + 5, &end, 10);
		if (end == line + 5 || strncmp(end, "] {", 3) != 0 || code < 0 || code > 999)
			return -EINVAL;
		char *verb = end + 3, *close = strchr(verb, '}');
		if (!close)
			return -EINVAL;
		*close = 0;
		ret->kind = PROTO_ACK;
		ret->ack_code = (int)code;
		ret->ack_verb = verb;
		ret->ack_message = close[1] == ' ' ? close + 2 : close + 1;
		return 0;
	}
	char *colon = strstr(line, ": ");
	if (!colon || colon == line)
		return -EINVAL;
	for (char *c = line; c < colon; c++)
		if (!is_name_char((unsigned char)*c))
			return -EINVAL;
	*colon = 0;
	ret->key = line;
	ret->value = colon + 2;
	ret->kind = proto_is_event(line) ? PROTO_EVENT : PROTO_PAIR;
	return 0;
}

int proto_format_ack(char *buf, size_t size, int code, const char *verb, const char *message)
{
	int n = snprintf(buf, size, "ACK [%d] {%s} %s\n", code, verb ? verb : "", message);
	/* Sanitize everything after the code: verb and message come from peers. */
	if (size)
		for (size_t i = 5; i + 1 < size && buf[i] && buf[i + 1]; i++) {
			unsigned char c = (unsigned char)buf[i];
			if (c < 0x20 || c >= 0x7f)
				buf[i] = '?';
		}
	return n;
}

const char *proto_ack_name(int code)
{
	switch (code) {
	case SKY_ACK_SYNTAX: return "syntax";
	case SKY_ACK_ARG: return "arg";
	case SKY_ACK_PERMISSION: return "permission";
	case SKY_ACK_UNKNOWN: return "unknown";
	case SKY_ACK_NO_EXIST: return "no_exist";
	case SKY_ACK_RANGE: return "range";
	case SKY_ACK_LIMIT: return "limit";
	case SKY_ACK_TOO_LONG: return "too_long";
	case SKY_ACK_STATE: return "state";
	case SKY_ACK_ENGINE: return "engine";
	}
	return "unknown";
}

int proto_parse_number(const char *v, double *ret)
{
	static locale_t c_locale;
	char *end;

	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!c_locale || !v || !*v)
		return -EINVAL;
	errno = 0;
	double d = strtod_l(v, &end, c_locale);
	if (*end || end == v || !isfinite(d) || (errno == ERANGE && d != 0.0))
		return -EINVAL;
	*ret = d;
	return 0;
}

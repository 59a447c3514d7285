/* sky.c - libsky's common parts: its version, error strings, the default
 * socket path, clocks and the reply object. The manual is sky.h; the other
 * files of the library are named in sky_internal.h. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include "sky_internal.h"

unsigned sky_version(void)
{
	return SKY_VERSION;
}

const char *sky_strerror(int err)
{
	if (err > 0) {
		switch (err) {
		case SKY_ACK_SYNTAX: return "daemon refused: syntax";
		case SKY_ACK_ARG: return "daemon refused: bad argument";
		case SKY_ACK_PERMISSION: return "daemon refused: permission";
		case SKY_ACK_UNKNOWN: return "daemon refused: unknown verb";
		case SKY_ACK_NO_EXIST: return "daemon refused: no such key or table";
		case SKY_ACK_RANGE: return "daemon refused: out of range";
		case SKY_ACK_LIMIT: return "daemon refused: limit reached";
		case SKY_ACK_TOO_LONG: return "daemon refused: line too long";
		case SKY_ACK_STATE: return "daemon refused: not allowed now";
		case SKY_ACK_ENGINE: return "daemon failed: engine error";
		default: return "daemon refused";
		}
	}
	switch (-err) {
	case 0: return "success";
	case EINVAL: return "invalid argument";
	case ENOENT: return "no such socket (is skyd running?)";
	case ECONNREFUSED: return "connection refused (is skyd running?)";
	case ECONNRESET: return "skyd closed the connection";
	case EPIPE: return "skyd closed the connection";
	case ENOTCONN: return "not connected or not subscribed";
	case ETIMEDOUT: return "timed out";
	case EPROTO: return "protocol error (garbled reply or shared memory)";
	case EPROTONOSUPPORT: return "protocol or layout version not supported";
	case EAGAIN: return "try again (writer busy or queue full)";
	case ENODATA: return "table not valid in this slot";
	case ENOBUFS: return "buffer too small";
	case ENOMEM: return "out of memory";
	case EACCES: return "permission denied";
	case ENAMETOOLONG: return "path too long";
	case EINTR: return "interrupted";
	default: return "system error";
	}
}

int sky_default_path(char *buf, size_t size)
{
	if (!buf || !size)
		return -EINVAL;
	const char *xdg = getenv("XDG_RUNTIME_DIR");
	char tmp[PATH_MAX];
	const char *p = "/run/skyd/control";
	if (xdg && xdg[0] == '/') {
		int n = snprintf(tmp, sizeof(tmp), "%s/skyd/control", xdg);
		if (n > 0 && (size_t)n < sizeof(tmp) && access(tmp, F_OK) == 0)
			p = tmp;
	}
	size_t n = strlen(p);
	if (n >= size || n >= sizeof(((struct sockaddr_un *)0)->sun_path))
		return -ENAMETOOLONG;
	memcpy(buf, p, n + 1);
	return (int)n;
}

int64_t sky_now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

int sky_left_ms(int64_t deadline)
{
	if (deadline < 0)
		return -1;
	int64_t d = deadline - sky_now_ms();
	return d < 0 ? 0 : d > INT_MAX ? INT_MAX : (int)d;
}

sky_reply *sky_reply_alloc(void)
{
	sky_reply *r = calloc(1, sizeof(*r));
	if (r)
		r->fd = -1;
	return r;
}

void sky_reply_free(sky_reply *r)
{
	if (!r)
		return;
	for (size_t i = 0; i < r->n; i++) {
		free(r->keys[i]);
		free(r->values[i]);
	}
	free(r->keys);
	free(r->values);
	free(r->message);
	if (r->fd >= 0)
		close(r->fd);
	free(r);
}

/* Grows the key and value arrays to hold one more line. */
static int reply_reserve(sky_reply *r)
{
	if (r->n >= SKY_MAX_REPLY_LINES)
		return -EPROTO;
	if (r->n < r->cap)
		return 0;
	size_t cap = r->cap ? r->cap * 2 : 16;
	char **k = realloc(r->keys, cap * sizeof(*k));
	if (!k)
		return -ENOMEM;
	r->keys = k;
	char **v = realloc(r->values, cap * sizeof(*v));
	if (!v)
		return -ENOMEM;
	r->values = v;
	r->cap = cap;
	return 0;
}

int sky_reply_add_pair(sky_reply *r, const char *key, const char *value)
{
	int e = reply_reserve(r);
	if (e < 0)
		return e;
	char *k = strdup(key), *v = strdup(value);
	if (!k || !v) {
		free(k);
		free(v);
		return -ENOMEM;
	}
	r->keys[r->n] = k;
	r->values[r->n] = v;
	r->n++;
	return 0;
}

int sky_reply_set_ack(sky_reply *r, int code, const char *verb, const char *message)
{
	size_t n = strlen(verb) + strlen(message) + 4;
	char *m = malloc(n);
	if (!m)
		return -ENOMEM;
	snprintf(m, n, *message ? "{%s} %s" : "{%s}%s", verb, message);
	free(r->message);
	r->message = m;
	r->ack = code;
	return 0;
}

int sky_reply_ack(const sky_reply *r)
{
	return r ? r->ack : -EINVAL;
}

const char *sky_reply_message(const sky_reply *r)
{
	return r && r->message ? r->message : "";
}

size_t sky_reply_count(const sky_reply *r)
{
	return r ? r->n : 0;
}

const char *sky_reply_key(const sky_reply *r, size_t i)
{
	return r && i < r->n ? r->keys[i] : NULL;
}

const char *sky_reply_value(const sky_reply *r, size_t i)
{
	return r && i < r->n ? r->values[i] : NULL;
}

const char *sky_reply_get(const sky_reply *r, const char *key)
{
	if (!r || !key)
		return NULL;
	for (size_t i = 0; i < r->n; i++)
		if (strcmp(r->keys[i], key) == 0)
			return r->values[i];
	return NULL;
}


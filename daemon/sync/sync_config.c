/* sync_config.c - the replication settings: the broker's URL, the role,
 * credentials and TLS files, and the checks they pass before a client
 * starts. */
#include "sync.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

const char *sync_role_name(enum sync_role r)
{
	return r == SYNC_CONTROLLER ? "controller" : r == SYNC_FOLLOWER ? "follower" : "?";
}

int sync_parse_role(const char *name, enum sync_role *ret)
{
	if (strcmp(name, "controller") == 0)
		*ret = SYNC_CONTROLLER;
	else if (strcmp(name, "follower") == 0)
		*ret = SYNC_FOLLOWER;
	else
		return -EINVAL;
	return 0;
}

const char *sync_state_name(enum sync_state s)
{
	static const char *const names[] = { "off", "connecting", "connected", "lost" };
	return (unsigned)s < sizeof(names) / sizeof(names[0]) ? names[s] : "?";
}

void sync_config_defaults(struct sync_config *ret)
{
	memset(ret, 0, sizeof(*ret));
	ret->port = 1883;
	ret->role = SYNC_FOLLOWER;
	ret->lead_ms = 300;
	ret->keepalive_s = 10;
	ret->backoff_min_ms = 500;
	ret->backoff_max_ms = 30000;
}

static int in_set(char c, const char *extra)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
	       (c && strchr(extra, c));
}

/* A topic prefix: levels of [A-Za-z0-9._-] joined by single '/', short
 * enough that every topic built on it fits. Wildcards ('+', '#') and
 * empty levels are refused. */
static int prefix_valid(const char *p)
{
	size_t n = strnlen(p, SYNC_PREFIX_MAX);

	if (n == 0 || n >= SYNC_PREFIX_MAX || p[0] == '/' || p[n - 1] == '/' || strstr(p, "//"))
		return 0;
	for (size_t i = 0; i < n; i++)
		if (!in_set(p[i], "._-/"))
			return 0;
	return 1;
}

static int host_valid(const char *h)
{
	size_t n = strnlen(h, SYNC_HOST_MAX);

	if (n == 0 || n >= SYNC_HOST_MAX)
		return 0;
	for (size_t i = 0; i < n; i++)
		if (!in_set(h[i], ".-:"))
			return 0;
	return 1;
}

#define ERR(...) (snprintf(err, err_size, __VA_ARGS__), -EINVAL)

/* HOST, [V6] or either with :PORT, from [a, b). */
static int parse_authority(struct sync_config *c, const char *a, const char *b, char *err,
			   size_t err_size)
{
	const char *host_end = b, *port = NULL;

	if (memchr(a, '@', (size_t)(b - a)))
		return ERR("sync: credentials in the URL are refused (every user can read a "
			   "command line): give sync_username and sync_password_file");
	if (*a == '[') {
		host_end = memchr(a, ']', (size_t)(b - a));
		if (!host_end)
			return ERR("sync: an IPv6 address needs its closing ']'");
		port = host_end + 1 < b && host_end[1] == ':' ? host_end + 2 : NULL;
		if (!port && host_end + 1 != b)
			return ERR("sync: only :PORT may follow an IPv6 address");
		a++;
	} else {
		const char *colon = memchr(a, ':', (size_t)(b - a));
		if (colon) {
			host_end = colon;
			port = colon + 1;
		}
	}
	size_t n = (size_t)(host_end - a);
	if (n == 0 || n >= sizeof(c->host))
		return ERR("sync: the URL names no broker host, or one too long");
	memcpy(c->host, a, n);
	c->host[n] = 0;
	if (!host_valid(c->host))
		return ERR("sync: the broker host has characters a host name cannot have");
	if (port) {
		unsigned long v = 0;
		if (port == b || b - port > 5)
			return ERR("sync: the port must be a number from 1 to 65535");
		for (const char *p = port; p < b; p++) {
			if (*p < '0' || *p > '9')
				return ERR("sync: the port must be a number from 1 to 65535");
			v = v * 10 + (unsigned long)(*p - '0');
		}
		if (v < 1 || v > 65535)
			return ERR("sync: the port must be a number from 1 to 65535");
		c->port = (uint16_t)v;
	}
	return 0;
}

int sync_config_parse_url(struct sync_config *cfg, const char *url, char *err, size_t err_size)
{
	struct sync_config c = *cfg;
	const char *a;

	if (strncmp(url, "mqtt://", 7) == 0) {
		a = url + 7;
		c.tls = 0;
		c.port = 1883;
	} else if (strncmp(url, "mqtts://", 8) == 0) {
		a = url + 8;
		c.tls = 1;
		c.port = 8883;
	} else {
		return ERR("sync: the URL must start with mqtt:// or mqtts://");
	}
	const char *slash = strchr(a, '/');
	if (!slash)
		return ERR("sync: the URL needs a topic prefix: mqtt://HOST:PORT/PREFIX");
	int r = parse_authority(&c, a, slash, err, err_size);
	if (r < 0)
		return r;
	if (strlen(slash + 1) >= sizeof(c.prefix) || !prefix_valid(slash + 1))
		return ERR("sync: the topic prefix must be levels of letters, digits, '.', '_', "
			   "'-' joined by '/', shorter than %d", SYNC_PREFIX_MAX);
	snprintf(c.prefix, sizeof(c.prefix), "%s", slash + 1);
	*cfg = c;
	return 0;
}

int sync_config_read_password(struct sync_config *cfg, const char *path, char *err,
			      size_t err_size)
{
	char buf[SYNC_SECRET_MAX + 1];
	int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOCTTY);

	if (fd < 0) {
		int e = errno;
		snprintf(err, err_size, "sync: %s: %s", path, strerror(e));
		return -e;
	}
	ssize_t n = read(fd, buf, sizeof(buf) - 1);
	int e = errno;
	close(fd);
	if (n < 0) {
		snprintf(err, err_size, "sync: %s: %s", path, strerror(e));
		return -e;
	}
	buf[n] = 0;
	buf[strcspn(buf, "\r\n")] = 0;
	size_t len = strlen(buf);
	int r = 0;
	if (len == 0)
		r = ERR("sync: %s: no password on its first line", path);
	else if (len >= sizeof(cfg->password))
		r = ERR("sync: %s: the password is longer than %d bytes", path, SYNC_SECRET_MAX - 1);
	else
		memcpy(cfg->password, buf, len + 1);
	explicit_bzero(buf, sizeof(buf));
	return r;
}

static int terminated(const char *s, size_t size)
{
	return memchr(s, 0, size) != NULL;
}

int sync_config_check(const struct sync_config *cfg, char *err, size_t err_size)
{
	if (!terminated(cfg->host, sizeof(cfg->host)) || !host_valid(cfg->host) || !cfg->port)
		return ERR("sync: no broker: give mqtt://HOST:PORT/PREFIX");
	if (!terminated(cfg->prefix, sizeof(cfg->prefix)) || !prefix_valid(cfg->prefix))
		return ERR("sync: the topic prefix is empty or not valid");
	if (cfg->role != SYNC_FOLLOWER && cfg->role != SYNC_CONTROLLER)
		return ERR("sync_role: must be controller or follower");
	if (cfg->lead_ms > 10000)
		return ERR("sync_lead_ms: %u is outside [0, 10000]", cfg->lead_ms);
	if (cfg->keepalive_s < 5 || cfg->keepalive_s > 3600)
		return ERR("sync_keepalive_s: %u is outside [5, 3600]", cfg->keepalive_s);
	if (cfg->backoff_min_ms < 10 || cfg->backoff_max_ms < cfg->backoff_min_ms ||
	    cfg->backoff_max_ms > 3600000)
		return ERR("sync back-off: need 10 <= min <= max <= 3600000 ms");
	if (!terminated(cfg->username, sizeof(cfg->username)) ||
	    !terminated(cfg->password, sizeof(cfg->password)))
		return ERR("sync: the username or password is too long");
	if (cfg->password[0] && !cfg->username[0])
		return ERR("sync: a password needs a username");
	const char *files[] = { cfg->cafile, cfg->capath, cfg->certfile, cfg->keyfile };
	for (int i = 0; i < 4; i++) {
		if (!terminated(files[i], SYNC_PATH_MAX))
			return ERR("sync: a TLS file name is too long");
		if (files[i][0] && !cfg->tls)
			return ERR("sync: TLS files need an mqtts:// URL");
	}
	if (!cfg->certfile[0] != !cfg->keyfile[0])
		return ERR("sync: a client certificate needs its key, and a key its certificate");
	return 0;
}

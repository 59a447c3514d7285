/* config.c - parses a configuration file whole, then applies it. */
#include "config.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "skyproto.h"

static char *trim(char *s)
{
	char *e = s + strlen(s);

	while (*s == ' ' || *s == '\t')
		s++;
	while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\n' || e[-1] == '\r'))
		*--e = 0;
	return s;
}

int config_load(const char *path, struct sky_state *s, char *err, size_t err_size)
{
	return config_load_with(path, s, NULL, NULL, err, err_size);
}

int config_load_with(const char *path, struct sky_state *s, config_key_fn *daemon_key, void *ctx,
		     char *err, size_t err_size)
{
	struct sky_state next = *s;
	char line[SKY_PROTO_LINE_MAX], msg[256];
	int lineno = 0, r = 0;
	FILE *f = fopen(path, "re");

	if (!f) {
		r = -errno;
		snprintf(err, err_size, "%s: %s", path, strerror(-r));
		return r;
	}
	while (fgets(line, sizeof(line), f)) {
		lineno++;
		size_t len = strlen(line);
		if (len == sizeof(line) - 1 && line[len - 1] != '\n') {
			snprintf(err, err_size, "%s:%d: line over %d bytes", path, lineno,
				 SKY_PROTO_LINE_MAX - 1);
			r = -EINVAL;
			break;
		}
		char *hash = strchr(line, '#');
		if (hash)
			*hash = 0;
		char *p = trim(line);
		if (!*p)
			continue;
		char *eq = strchr(p, '=');
		if (!eq) {
			snprintf(err, err_size, "%s:%d: '%.64s': key = value expected", path, lineno, p);
			r = -EINVAL;
			break;
		}
		*eq = 0;
		char *key = trim(p), *value = trim(eq + 1);
		/* A value may be quoted as on the socket (metar = "EGLL ..."). */
		size_t n = strlen(value);
		if (n >= 2 && value[0] == '"' && value[n - 1] == '"') {
			value[n - 1] = 0;
			value++;
		}
		msg[0] = 0;
		r = daemon_key ? daemon_key(ctx, key, value, msg, sizeof(msg)) : 0;
		if (r == 0)
			r = state_set(&next, key, value, NULL, msg, sizeof(msg));
		else if (r > 0)
			r = 0;
		if (r < 0) {
			snprintf(err, err_size, "%s:%d: %s", path, lineno, msg[0] ? msg : strerror(-r));
			break;
		}
	}
	if (!r && ferror(f)) {
		r = -EIO;
		snprintf(err, err_size, "%s: read error", path);
	}
	fclose(f);
	if (r < 0)
		return r;
	r = state_validate(&next, 0, msg, sizeof(msg));
	if (r < 0) {
		snprintf(err, err_size, "%s: %s", path, msg);
		return r;
	}
	*s = next;
	return 0;
}

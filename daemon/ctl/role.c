/* role.c - the controllers= list resolved to uids and gids, the bounds of
 * the control socket as settings, and a peer's role from its credentials. */
#include "role.h"

#include <errno.h>
#include <grp.h>
#include <limits.h>
#include <pwd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ctl.h"

/* getpwnam_r and getgrnam_r answer ERANGE past this; a group of some
 * thousand members needs more than sysconf's usual hint. */
#define ROLE_NSS_BUF (64u << 10)

/* A whole decimal number up to max, without sign or spaces: 0 or -EINVAL. */
static int parse_count(const char *text, unsigned long max, unsigned long *ret)
{
	char *end;

	if (!text[0] || text[0] < '0' || text[0] > '9')
		return -EINVAL;
	errno = 0;
	unsigned long v = strtoul(text, &end, 10);
	if (errno || *end || v > max)
		return -EINVAL;
	*ret = v;
	return 0;
}

/* One entry of the list: a user name, @group, a uid or @gid. 1 when it
 * resolved (added to s), 0 when the name is unknown, -EINVAL when it is
 * malformed or the list is full (err says which). */
static int add_entry(struct role_settings *s, const char *entry, char *buf, char *err,
		     size_t err_size)
{
	int group = entry[0] == '@';
	const char *name = entry + group;
	unsigned long id;

	if (!name[0]) {
		snprintf(err, err_size, "controllers: an empty entry");
		return -EINVAL;
	}
	if ((group ? s->n_gids : s->n_uids) == ROLE_MAX_IDS) {
		snprintf(err, err_size, "controllers: more than %d %s", ROLE_MAX_IDS,
			 group ? "groups" : "users");
		return -EINVAL;
	}
	if (parse_count(name, (unsigned long)UINT_MAX - 1, &id) < 0) {
		if (name[0] >= '0' && name[0] <= '9') {
			snprintf(err, err_size, "controllers: '%s' is not a valid %s", entry,
				 group ? "gid" : "uid");
			return -EINVAL;
		}
		if (group) {
			struct group gr, *gp = NULL;
			if (getgrnam_r(name, &gr, buf, ROLE_NSS_BUF, &gp) != 0 || !gp)
				return 0;
			id = gp->gr_gid;
		} else {
			struct passwd pw, *pp = NULL;
			if (getpwnam_r(name, &pw, buf, ROLE_NSS_BUF, &pp) != 0 || !pp)
				return 0;
			id = pp->pw_uid;
		}
	}
	if (group)
		s->gids[s->n_gids++] = (gid_t)id;
	else
		s->uids[s->n_uids++] = (uid_t)id;
	return 1;
}

/* Resolves list into s's uids and gids. strict: an unknown name is an
 * error; otherwise it is left out (the default's @skyd on a machine
 * without that group). 0 or -errno with err; s untouched on failure. */
static int parse_controllers(struct role_settings *s, const char *list, int strict, char *err,
			     size_t err_size)
{
	struct role_settings next = *s;
	char copy[ROLE_LIST_MAX], text[ROLE_LIST_MAX] = "", *save = NULL;
	size_t text_len = 0;
	int r = 0;

	if (strlen(list) >= sizeof(copy)) {
		snprintf(err, err_size, "controllers: longer than %d bytes", ROLE_LIST_MAX - 1);
		return -EINVAL;
	}
	char *buf = malloc(ROLE_NSS_BUF);
	if (!buf) {
		snprintf(err, err_size, "controllers: out of memory");
		return -ENOMEM;
	}
	snprintf(copy, sizeof(copy), "%s", list);
	next.n_uids = next.n_gids = 0;
	for (char *e = strtok_r(copy, ",", &save); e; e = strtok_r(NULL, ",", &save)) {
		e += strspn(e, " \t");
		size_t n = strlen(e);
		while (n && (e[n - 1] == ' ' || e[n - 1] == '\t'))
			e[--n] = 0;
		r = add_entry(&next, e, buf, err, err_size);
		if (r == 0 && strict) {
			snprintf(err, err_size, "controllers: no %s '%s' on this machine (a list of user names, @groups, uids and @gids)",
				 e[0] == '@' ? "group" : "user", e + (e[0] == '@'));
			r = -EINVAL;
		}
		if (r < 0)
			break;
		/* The text says what was resolved: messages name no group that
		 * is not there. Fits: it is no longer than list. */
		if (r > 0)
			text_len += (size_t)snprintf(text + text_len, sizeof(text) - text_len, "%s%s",
						     text_len ? "," : "", e);
	}
	free(buf);
	if (r < 0)
		return r;
	snprintf(next.controllers, sizeof(next.controllers), "%s", text);
	*s = next;
	return 0;
}

void role_settings_default(struct role_settings *ret)
{
	char err[160];

	memset(ret, 0, sizeof(*ret));
	ret->max_connections = ROLE_DEFAULT_MAX_CONNECTIONS;
	ret->max_subscriptions_per_uid = ROLE_DEFAULT_MAX_SUBSCRIPTIONS_PER_UID;
	ret->max_views_per_uid = ROLE_DEFAULT_MAX_VIEWS_PER_UID;
	if (parse_controllers(ret, ROLE_DEFAULT_CONTROLLERS, 0, err, sizeof(err)) < 0) {
		/* Out of memory for the lookup: root alone, which needs none. */
		snprintf(ret->controllers, sizeof(ret->controllers), "root");
		ret->uids[0] = 0;
		ret->n_uids = 1;
	}
}

int role_settings_parse_key(struct role_settings *s, const char *key, const char *value,
			    char *err, size_t err_size)
{
	static const struct {
		const char *key;
		size_t offset;
		unsigned long min, max;
	} bounds[] = {
		{ "max_connections", offsetof(struct role_settings, max_connections), 1,
		  CTL_MAX_CLIENTS },
		{ "max_subscriptions_per_uid",
		  offsetof(struct role_settings, max_subscriptions_per_uid), 0, CTL_MAX_CLIENTS },
		{ "max_views_per_uid", offsetof(struct role_settings, max_views_per_uid), 0,
		  CTL_MAX_CLIENTS },
	};
	unsigned long v;

	if (strcmp(key, "controllers") == 0)
		return parse_controllers(s, value, 1, err, err_size) < 0 ? -EINVAL : 1;
	for (size_t i = 0; i < sizeof(bounds) / sizeof(bounds[0]); i++) {
		if (strcmp(key, bounds[i].key) != 0)
			continue;
		if (parse_count(value, bounds[i].max, &v) < 0 || v < bounds[i].min) {
			snprintf(err, err_size, "%s: a whole number from %lu to %lu", key,
				 bounds[i].min, bounds[i].max);
			return -EINVAL;
		}
		*(unsigned *)((char *)s + bounds[i].offset) = (unsigned)v;
		return 1;
	}
	return 0;
}

/* The peer's supplementary groups as the kernel recorded them at connect:
 * no NSS lookup, and the groups the process really had. 1 when one of
 * them is in s->gids. Kernels before 4.13 lack SO_PEERGROUPS: then only
 * the primary gid counts. */
static int peer_groups_match(const struct role_settings *s, int fd)
{
	gid_t small[64], *groups = small;
	socklen_t len = sizeof(small);
	int found = 0;

	if (getsockopt(fd, SOL_SOCKET, SO_PEERGROUPS, groups, &len) < 0) {
		if (errno != ERANGE || !(groups = malloc(len)))
			return 0;
		if (getsockopt(fd, SOL_SOCKET, SO_PEERGROUPS, groups, &len) < 0)
			len = 0;
	}
	for (size_t i = 0; i < len / sizeof(gid_t) && !found; i++)
		for (unsigned k = 0; k < s->n_gids && !found; k++)
			found = groups[i] == s->gids[k];
	if (groups != small)
		free(groups);
	return found;
}

enum role role_of_peer(const struct role_settings *s, int fd, const struct ucred *cred)
{
	if (cred->uid == (uid_t)-1)
		return ROLE_READER;
	/* skyd's own uid always controls: whoever runs ./dev run steers it. */
	if (cred->uid == geteuid())
		return ROLE_CONTROLLER;
	for (unsigned i = 0; i < s->n_uids; i++)
		if (cred->uid == s->uids[i])
			return ROLE_CONTROLLER;
	for (unsigned i = 0; i < s->n_gids; i++)
		if (cred->gid == s->gids[i])
			return ROLE_CONTROLLER;
	return s->n_gids && peer_groups_match(s, fd) ? ROLE_CONTROLLER : ROLE_READER;
}

const char *role_name(enum role r)
{
	return r == ROLE_CONTROLLER ? "controller" : "reader";
}

/* role.h - who may change the sky: the controllers= list of the config,
 * resolved to uids and gids when the settings are read, a peer's role from
 * its socket credentials, and the per-uid bounds of the control socket
 * (proto/PROTOCOL.md, "Roles and bounds").
 *
 * Settings are parsed whole into a struct role_settings and handed to the
 * control server at once (ctl_set_roles), so a reload applies all of them
 * or none. Name lookups (getpwnam_r, getgrnam_r: NSS, which may block on a
 * directory server) happen only while parsing, never on the event loop:
 * a peer's role is a comparison of numbers from SO_PEERCRED and
 * SO_PEERGROUPS against the resolved lists.
 */
#ifndef SKYD_ROLE_H
#define SKYD_ROLE_H

#include <stddef.h>
#include <sys/socket.h>
#include <sys/types.h>

#define ROLE_DEFAULT_CONTROLLERS "root,@skyd"
#define ROLE_DEFAULT_MAX_CONNECTIONS 1024u
#define ROLE_DEFAULT_MAX_SUBSCRIPTIONS_PER_UID 64u
#define ROLE_DEFAULT_MAX_VIEWS_PER_UID 64u
/* Entries of controllers= (users and groups together). */
#define ROLE_MAX_IDS 32
#define ROLE_LIST_MAX 256		/* bytes of the controllers= text */

/* Ordered: a verb needing READER is open to a CONTROLLER too. */
enum role { ROLE_READER = 0, ROLE_CONTROLLER = 1 };

struct role_settings {
	char controllers[ROLE_LIST_MAX];	/* as written, for messages */
	uid_t uids[ROLE_MAX_IDS];		/* resolved users */
	unsigned n_uids;
	gid_t gids[ROLE_MAX_IDS];		/* resolved @groups */
	unsigned n_gids;
	unsigned max_connections;		/* 1 .. CTL_MAX_CLIENTS */
	unsigned max_subscriptions_per_uid;	/* 0 .. CTL_MAX_CLIENTS */
	unsigned max_views_per_uid;		/* 0 .. STATE_MAX_VIEWS */
};

/* The defaults: controllers root and @skyd (a group skyd that does not
 * exist on this machine is left out), and the default bounds. Looks the
 * group up (NSS): call it while reading the settings, not on the loop. */
void role_settings_default(struct role_settings *ret);

/* One setting, as config_key_fn takes it (config.h): controllers,
 * max_connections, max_subscriptions_per_uid or max_views_per_uid.
 * Returns 1 when key is one of them and value was taken, 0 when key is not
 * one, -EINVAL with err ("key: what is expected") when value is refused;
 * s is untouched unless 1. controllers= names that do not resolve (no such
 * user or group) are refused. Looks names up (NSS): see above. */
int role_settings_parse_key(struct role_settings *s, const char *key, const char *value,
			    char *err, size_t err_size);

/* The role of the peer on the connected socket fd with credentials cred
 * (SO_PEERCRED): CONTROLLER when its uid is skyd's own effective uid or in
 * the list, or its gid or one of its supplementary groups (SO_PEERGROUPS,
 * taken by the kernel at connect) is; READER otherwise, and for a peer
 * whose credentials are unknown (uid -1). Does not block. */
enum role role_of_peer(const struct role_settings *s, int fd, const struct ucred *cred);

/* "reader" or "controller"; static. */
const char *role_name(enum role r);

#endif

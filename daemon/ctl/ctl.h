/* ctl.h - the control server: the Unix socket, one bounded connection per
 * client, and the protocol's verbs (proto/PROTOCOL.md), one handler each.
 *
 * Every client has a line buffer of SKY_PROTO_LINE_MAX bytes and an output
 * queue: past CTL_OUT_HIGH queued bytes its requests wait until it reads;
 * past CTL_OUT_MAX (only events can get there) it is dropped. Accepting
 * pauses while the process is out of fds. Each connection has a role from
 * its peer's credentials, and connections, subscriptions and views per uid
 * are bounded (role.h, ctl_set_roles).
 */
#ifndef SKYD_CTL_H
#define SKYD_CTL_H

#include <stddef.h>
#include <stdint.h>

#define CTL_OUT_HIGH (64u << 10)
/* Only events pass CTL_OUT_HIGH: 256 KiB is about 5400 changed: lines, a
 * client that far behind is better reconnected; and 4096 such clients
 * hold at most 1 GiB. */
#define CTL_OUT_MAX (256u << 10)
#define CTL_MAX_CLIENTS 4096
#define CTL_BATCH_MAX 256		/* set lines in one batch */

struct ctl;
struct role_settings;
struct loop;
struct srv;
struct srv_sensor_status;

/* Where the socket goes when --socket is not given:
 * $XDG_RUNTIME_DIR/skyd/control, else /run/skyd/control. */
int ctl_default_path(char *buf, size_t size);

/* Listens on path: its directory is created 0700 if missing and must be
 * ours and writable by nobody else; a stale socket is replaced, a live one
 * (another skyd answers) is an error. listen_fd >= 0 uses an inherited,
 * listening socket instead (systemd socket activation) and path only for
 * messages. err says what to do on failure. ctl is one of s's listeners
 * (changed: and failed: lines) until ctl_free. Changes go to srv_apply;
 * the clock's and the light sensor's status come from srv. */
int ctl_new(struct loop *l, struct srv *s, const char *path, int listen_fd, char *err,
	    size_t err_size, struct ctl **ret);
/* Closes every connection and removes the socket it created. */
void ctl_free(struct ctl *c);
/* The listening socket, which outlives this skyd (in systemd's fd store):
 * ctl_free leaves its path in place. The fd stays ctl's. */
int ctl_keep_socket(struct ctl *c);

/* Who controls and the bounds (role.h), all at once: a copy is kept.
 * Connections open now get their role again from the new list (the
 * credentials they connected with, no lookup); bounds apply to what comes
 * next: nobody is dropped when they shrink. Until called: the defaults. */
void ctl_set_roles(struct ctl *ctl, const struct role_settings *s);

/* The light sensor's event hook, to be wired by main:
 * a sensor: line to every connection that asked (sensor events=1). */
void ctl_sensor_event(void *ctx, const struct srv_sensor_status *st);

/* Replication (docs/sync.md). may_change says whether this instance may
 * change the replicated state; when not, it names the controller in
 * charge in who, and set and batch are refused with SKY_ACK_PERMISSION.
 * status appends the "sync..." lines of status to buf (terminated). */
struct ctl_sync {
	int (*may_change)(void *ctx, char *who, size_t who_size);
	void (*status)(void *ctx, char *buf, size_t size);
	void *ctx;
};
/* NULL: no replication ("sync: off" in status). */
void ctl_set_sync(struct ctl *ctl, const struct ctl_sync *sync);
/* 1 when the sky follows a controller elsewhere (who names it), so that
 * no local source may change it; 0 otherwise. */
int ctl_sky_follows(struct ctl *ctl, char *who, size_t who_size);

/* The connections open now (systemd's STATUS line). */
int ctl_clients(const struct ctl *ctl);

#endif

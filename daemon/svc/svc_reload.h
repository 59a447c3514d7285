/* svc_reload.h - re-reading the configuration file on SIGHUP (systemctl
 * reload), all or nothing: the whole file is parsed into new settings
 * first, every group of settings checked, and only then applied; a file
 * that fails anywhere is refused, logged, and changes nothing.
 *
 * The sky's keys are one group, built in: the file's keys and then the
 * command line's key=value arguments, over the running state (a key the
 * file does not name keeps its running value, whoever set it), applied
 * as one change (srv_apply). Settings of the daemon itself that the same
 * file carries (sync_*, and any later group) join as steps
 * (svc_reload_add_step): each parses its own keys into a candidate, checks
 * it once the whole file is read, and makes it current only when every
 * step and the sky accepted theirs. */
#ifndef SKYD_SVC_RELOAD_H
#define SKYD_SVC_RELOAD_H

#include <stddef.h>

#include "config.h"

struct ctl;
struct srv;
struct svc_notify;
struct svc_reload;

struct svc_reload_step {
	const char *name;		/* for the log: "sync", "roles" */
	/* Starts a candidate from the settings as they are at start (the
	 * defaults: a key the file no longer names goes back to them). */
	void (*begin)(void *ctx);
	/* config_key_fn: 1 when key is this step's (taken into the
	 * candidate), 0 when not, -errno with err when refused. */
	config_key_fn *key;
	/* The whole candidate, after the last line: 0, or -errno with err.
	 * NULL: nothing to check. */
	int (*check)(void *ctx, char *err, size_t err_size);
	/* Makes the candidate current; cannot fail (it was checked). */
	void (*apply)(void *ctx);
	void *ctx;
};

#define SVC_RELOAD_MAX_STEPS 8

/* path: the config file (NULL: none, a reload only says so); args: the
 * command line's key=value arguments (n_args of them, kept by pointer). */
int svc_reload_new(const char *path, char *const *args, int n_args, struct svc_reload **ret);
void svc_reload_free(struct svc_reload *r);
/* The running service a reload changes: srv, notify and ctl (NULL: none)
 * must outlive r. Before it, svc_reload_run refuses. A follower of
 * replication (ctl_sky_follows) takes the file's daemon settings but not
 * its sky: that comes from the controller. */
void svc_reload_attach(struct svc_reload *r, struct srv *srv, struct svc_notify *notify,
		       struct ctl *ctl);

/* Adds a settings group; step is copied. 0, or -ENOSPC past
 * SVC_RELOAD_MAX_STEPS. */
int svc_reload_add_step(struct svc_reload *r, const struct svc_reload_step *step);

/* The first read, at start: the file (if any) and the arguments over s,
 * every step checked, then every step applied. On error nothing is
 * applied and s is untouched: 0 or -errno with err. */
int svc_reload_load(struct svc_reload *r, struct sky_state *s, char *err, size_t err_size);

/* Re-reads the file and applies it, or refuses it whole. Logs the
 * outcome. 0 applied, -errno refused (err says why; nothing changed). */
int svc_reload_run(struct svc_reload *r, char *err, size_t err_size);

#endif

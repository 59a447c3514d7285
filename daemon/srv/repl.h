/* repl.h - the daemon's side of replication (docs/sync.md): it joins the
 * sync client (daemon/sync/sync.h) to the sky service and the control
 * server.
 *
 * A controller times every accepted change (the control socket's, the
 * clock's, the light sensor's) at sync_apply_time_ns and hands the
 * committed state to sync_publish, which names each by its own sequence;
 * standing by, it hands over the states it follows. A follower commits
 * every state the broker brings through srv_apply, for its apply time,
 * keeping its own views, and its control socket refuses set and batch
 * (SKY_ACK_PERMISSION) naming the controller.
 */
#ifndef SKYD_REPL_H
#define SKYD_REPL_H

struct ctl;
struct loop;
struct repl;
struct srv;
struct sync_config;

/* Starts replication with cfg; srv and ctl (NULL: none) must outlive it.
 * It hears of every change srv accepts (a listener). A controller
 * publishes the state it starts with. 0 or sync_new's -errno. */
int repl_new(struct loop *l, const struct sync_config *cfg, struct srv *srv, struct ctl *ctl,
	     struct repl **ret);
/* Unhooks srv and ctl, then stops the client (a controller hands its
 * claim back). */
void repl_free(struct repl *r);

#endif

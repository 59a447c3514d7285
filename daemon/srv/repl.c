/* repl.c - replication wired into skyd: the srv's timing hook and its
 * listener for committed changes, the follower's commits and the control
 * server's refusals and status. */
#include "repl.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ctl.h"
#include "log.h"
#include "srv.h"
#include "state.h"
#include "sync.h"

struct repl {
	struct sync *sync;
	struct srv *srv;
	struct ctl *ctl;
	enum sync_role role;
};

/* srv's hook: a change the controller accepts switches everywhere at now
 * plus the lead; anything else (a follower's own clock) at once. */
static int64_t apply_time(void *ctx)
{
	struct repl *r = ctx;
	char who[SYNC_ID_MAX];

	if (r->role != SYNC_CONTROLLER || !sync_may_change(r->sync, who, sizeof(who)))
		return 0;
	return sync_apply_time_ns(r->sync);
}

/* srv's listener: a controller hands every committed state to the sync
 * client, which names it by the next sequence and sends it while this
 * instance holds the claim. A standby controller hands over the states it
 * follows too, so that it claims with the sky it shows, not the one it
 * started with. */
static void committed(void *ctx, const struct sky_state *st, uint64_t generation,
		      int64_t apply_time_ns)
{
	struct repl *r = ctx;

	if (r->role != SYNC_CONTROLLER || generation == 0)
		return;
	int e = sync_publish(r->sync, st, generation, apply_time_ns);
	if (e < 0)
		log_warning("sync: publishing generation %" PRIu64 ": %s", generation,
			    strerror(-e));
}

/* The sync client's hook: the controller's state, committed as a local
 * set would be, with this machine's views, visible at its apply time. */
static void on_state(void *ctx, const struct sky_state *candidate, const struct sync_msg_header *h)
{
	struct repl *r = ctx;
	const struct sky_state *cur = srv_state(r->srv);
	struct sky_state *next = malloc(sizeof(*next));
	uint64_t shown;
	uint32_t dirty;
	char err[256] = "";

	if (!next) {
		log_error("sync: state %" PRIu64 ": out of memory", h->sequence);
		return;
	}
	*next = *candidate;
	next->n_views = cur->n_views;
	memcpy(next->views, cur->views, sizeof(next->views));
	dirty = state_diff(cur, next);
	srv_set_next_apply_time(r->srv, h->apply_time_ns);
	srv_set_next_field(r->srv, h->cloud_placed_sent, h->cloud_placed_utc_s);
	int e = srv_apply(r->srv, next, dirty, &shown, &dirty, err, sizeof(err));
	srv_set_next_field(r->srv, 0, NAN);
	srv_set_next_apply_time(r->srv, 0);
	free(next);
	if (e < 0) {
		log_warning("sync: controller's state %" PRIu64 " (generation %" PRIu64
			    ") refused here: %s", h->sequence, h->generation,
			    err[0] ? err : strerror(-e));
		return;
	}
	log_debug("sync: controller's state %" PRIu64 " (generation %" PRIu64
		  ") is generation %" PRIu64 " here", h->sequence, h->generation, shown);
}

static int may_change(void *ctx, char *who, size_t who_size)
{
	struct repl *r = ctx;

	return sync_may_change(r->sync, who, who_size);
}

/* The status lines (PROTOCOL.md, "status"). */
static void status(void *ctx, char *buf, size_t size)
{
	struct repl *r = ctx;
	struct sync_status st;
	uint64_t dropped = 0;
	size_t n;

	sync_get_status(r->sync, &st);
	for (int i = 0; i < SYNC_DROP_N; i++)
		dropped += st.dropped[i];
	n = (size_t)snprintf(buf, size,
			     "sync: %s\nsync_role: %s\nsync_active: %d\nsync_standby: %d\n"
			     "sync_controller: %s\nsync_controller_online: %d\n"
			     "sync_sequence: %" PRIu64 "\nsync_generation: %" PRIu64
			     "\nsync_apply_time_ns: %" PRId64 "\n",
			     sync_state_name(st.state), sync_role_name(st.role), st.active,
			     st.standby, st.controller[0] ? st.controller : "none",
			     st.controller_online, st.sequence, st.generation, st.apply_time_ns);
	if (n >= size)
		return;
	if (st.age_ns == UINT64_MAX)
		n += (size_t)snprintf(buf + n, size - n, "sync_age_ms: none\n");
	else
		n += (size_t)snprintf(buf + n, size - n, "sync_age_ms: %.1f\n",
				      (double)st.age_ns / 1e6);
	if (n >= size)
		return;
	n += (size_t)snprintf(buf + n, size - n,
			      "sync_counters: received=%" PRIu64 " applied=%" PRIu64
			      " published=%" PRIu64 " duplicates=%" PRIu64 " dropped=%" PRIu64
			      " connects=%" PRIu64 " attempts=%" PRIu64 "\n",
			      st.received, st.applied, st.published, st.duplicates, dropped,
			      st.connects, st.attempts);
	if (n >= size)
		return;
	n += (size_t)snprintf(buf + n, size - n, "sync_dropped:");
	for (int i = 1; i < SYNC_DROP_N && n < size; i++)
		n += (size_t)snprintf(buf + n, size - n, " %s=%" PRIu64,
				      sync_drop_name((enum sync_drop)i), st.dropped[i]);
	/* Why the last message was ignored: a follower whose terrain file
	 * differs from the controller's says so here. */
	if (n < size)
		n += (size_t)snprintf(buf + n, size - n, "\nsync_last_drop: %s",
				      st.last_drop ? st.last_drop_why : "none");
	if (n < size)
		snprintf(buf + n, size - n, "\nsync_error: %s\n", st.why[0] ? st.why : "none");
}

int repl_new(struct loop *l, const struct sync_config *cfg, struct srv *srv, struct ctl *ctl,
	     struct repl **ret)
{
	struct repl *r = calloc(1, sizeof(*r));
	int e;

	if (!r)
		return -ENOMEM;
	r->srv = srv;
	r->ctl = ctl;
	r->role = cfg->role;
	e = sync_new(l, cfg, &(struct sync_callbacks){ .on_state = on_state, .ctx = r }, &r->sync);
	if (e < 0) {
		free(r);
		return e;
	}
	e = srv_add_listener(srv, &(struct srv_listener){ .changed = committed, .ctx = r });
	if (e < 0) {
		sync_free(r->sync);
		free(r);
		return e;
	}
	srv_set_sync(srv, &(struct srv_sync){ apply_time, may_change, r });
	if (ctl)
		ctl_set_sync(ctl, &(struct ctl_sync){ may_change, status, r });
	if (r->role == SYNC_CONTROLLER) {
		/* The state it starts with is shown already: applied now. */
		struct timespec now;
		uint64_t generation = srv_state_generation(srv);
		clock_gettime(CLOCK_REALTIME, &now);
		committed(r, srv_state(srv), generation ? generation : 1,
			  (int64_t)now.tv_sec * 1000000000ll + now.tv_nsec);
	}
	*ret = r;
	return 0;
}

void repl_free(struct repl *r)
{
	if (!r)
		return;
	srv_set_sync(r->srv, &(struct srv_sync){ 0 });
	srv_remove_listener(r->srv, r);
	if (r->ctl)
		ctl_set_sync(r->ctl, NULL);
	sync_free(r->sync);
	free(r);
}

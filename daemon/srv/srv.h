/* srv.h - the sky the daemon serves: the current state, the coalescing of
 * changes into at most one computation in flight, and the publication of
 * each finished computation as a new generation.
 *
 * A change replaces the state at once (get sees it); its tables become
 * visible in a later generation, which srv_change names. While the engine
 * works, later changes overwrite the pending state and only the newest is
 * computed. Only the tables a change invalidated and some client needs are
 * computed. A failed computation keeps the last good tables published.
 */
#ifndef SKYD_SRV_H
#define SKYD_SRV_H

#include <stddef.h>
#include <stdint.h>

#include "eng.h"
#include "state.h"

struct drive;
struct loop;
struct pub;
struct srv;

struct srv_listener {
	/* A new generation is current. tables: those computed for it.
	 * new_region: it lives in a new memfd (srv_pub) with a new layout. */
	void (*published)(void *ctx, uint64_t generation, uint32_t tables, int new_region);
	/* The computation meant for generation failed; message says why. */
	void (*failed)(void *ctx, uint64_t generation, const char *message);
};

struct srv_status {
	uint64_t generation;		/* published */
	int computing;			/* a computation is in flight */
	int pending;			/* a newer change waits for it */
	uint32_t last_computed;		/* STATE_BIT mask of the last successful computation */
	double last_total_ms;
	double table_ms[STATE_N_TABLES];/* the last time each table was computed; -1 never */
	uint32_t published_valid;	/* tables valid in the current slot */
	uint32_t published_computed;	/* tables computed for the current slot (others carried) */
	uint32_t demand;		/* srv_set_demand's tables */
	uint32_t needed;		/* demand with its dependencies */
	uint64_t computations, failures;
	uint64_t column_passes;		/* computations that ran transmittance's column pass */
	char last_error[256];		/* "" when the last computation succeeded */
	char storage_warning[192];	/* float16 broke in the last computation; "" when not */
};

/* Takes neither loop nor engine; both must outlive the srv. The first
 * computation (every needed table of initial) starts at once. */
int srv_new(struct loop *l, struct eng *e, const struct sky_state *initial, struct srv **ret);
/* srv_new publishing into region (taken, also on failure; pub_same_layout
 * as initial) whose newest generation is generation: the next publication
 * is generation + 1. Region NULL: srv_new. */
int srv_new_from(struct loop *l, struct eng *e, const struct sky_state *initial,
		 struct pub *region, uint64_t generation, struct srv **ret);
/* Who hears of publications and failures (the control server). */
void srv_set_listener(struct srv *s, const struct srv_listener *listener, void *ctx);
void srv_free(struct srv *s);

/* The state as last changed (not necessarily computed yet). */
const struct sky_state *srv_state(const struct srv *s);
/* The state (as set: before state_resolve) whose tables the current slot
 * holds; the initial state before the first publication. */
const struct sky_state *srv_published(const struct srv *s);
/* The current region; valid until the next publication with a new layout. */
struct pub *srv_pub(const struct srv *s);
const struct eng_device *srv_device(const struct srv *s);
void srv_status(const struct srv *s, struct srv_status *ret);

/* Cross-key and device rules for a candidate state: 0 or -EINVAL / -ERANGE
 * with the reason in err. */
int srv_check(const struct srv *s, const struct sky_state *next, char *err, size_t err_size);

/* Makes next (checked) the state; dirty: the tables it invalidates
 * (state_set's mask). ret_generation: the generation in which it becomes
 * visible. -EIO when the computation could not start (err says why): the
 * state is kept and computed with the next change. */
int srv_change(struct srv *s, const struct sky_state *next, uint32_t dirty,
	       uint64_t *ret_generation, char *err, size_t err_size);

/* The generation that shows the served state as it is now: the published
 * one, the one in flight, or the one after it when a newer change waits. */
uint64_t srv_state_generation(const struct srv *s);

/* Applies a candidate state that a request built from the served one, as
 * one change: a new time_rate re-anchors the running clock
 * (state_clock_rebase); a new clock (time, place, light mode) places the
 * clock-driven lights at once (drive_lights), so that the generation named
 * shows them; then srv_check and srv_change; clock (NULL: none) then takes
 * the new lights as its reference. dirty: the tables the request
 * invalidated (state_set's mask). ret_dirty gets them with the lights'.
 * Returns 0; -ERANGE when refused (astro cannot place the lights, or a
 * cross-key or device rule), or -EIO / -ENOMEM when the computation could
 * not start: err says why and nothing changed. */
int srv_apply(struct srv *s, struct drive *clock, const struct sky_state *next, uint32_t dirty,
	      uint64_t *ret_generation, uint32_t *ret_dirty, char *err, size_t err_size);

/* Replication (docs/sync.md): how changes are timed and where they go.
 * apply_time_ns gives the CLOCK_REALTIME instant at which a change
 * accepted now becomes visible (0: as soon as it is computed); committed
 * hears of every accepted change with the generation that shows it and
 * that instant. Either may be NULL. */
struct srv_sync {
	int64_t (*apply_time_ns)(void *ctx);
	void (*committed)(void *ctx, const struct sky_state *st, uint64_t generation,
			  int64_t apply_time_ns);
	void *ctx;
};
void srv_set_sync(struct srv *s, const struct srv_sync *sync);

/* The next change (srv_change, srv_apply) becomes visible at apply_time_ns
 * (CLOCK_REALTIME) rather than the hook's: its tables are computed at once
 * and written into the region's spare slot with that instant
 * (pub_publish_ahead: libsky switches to it then), and their generation is
 * made the current slot at that instant, or at once when it has passed.
 * Changes that coalesce with it keep the newest instant. */
void srv_set_next_apply_time(struct srv *s, int64_t apply_time_ns);

/* The tables some client needs: the demand and its dependencies under the
 * newest state. Only these are ever computed; a change to any other table
 * only marks it stale (it leaves the published slots until asked for). */
uint32_t srv_tables_needed(const struct srv *s);

/* Sets the demand (STATE_BIT mask, the union of what clients use); 0 at
 * start. Needed tables that are not current are computed at once, with
 * the state as it is: a later generation carries them. */
void srv_set_demand(struct srv *s, uint32_t tables);

/* Sets the tables the daemon reads from the published slots itself (the
 * light sensor's cloud and elevation modes): joined with the clients'
 * demand in srv_tables_needed, not shown as theirs in status. 0 at start. */
void srv_set_own_demand(struct srv *s, uint32_t tables);

/* Needed tables that are in flight or will be computed next: a table not
 * valid in the current slot that is here will come in a later generation. */
uint32_t srv_tables_coming(const struct srv *s);

#endif

/* srv.h - the sky the daemon serves: the current state, the coalescing of
 * changes into at most one computation in flight, and the publication of
 * each finished computation as a new generation.
 *
 * A change replaces the state at once (get sees it); its tables become
 * visible in a later generation, which srv_apply names. While the engine
 * works, later changes overwrite the pending state and only the newest is
 * computed. Only the tables a change invalidated and some client needs are
 * computed. A failed computation keeps the last good tables published.
 *
 * Every change goes one way: srv_apply, from a request (ctl), a reload,
 * replication or the light sensor; the clock drive, which srv owns, moves
 * the lights the same way. srv resolves each change once (the weather
 * applied, the lights' directions computed) and keeps that for the engine
 * and the publisher. Whoever reacts to a change (the light sensor,
 * replication) or to a publication (the control server, systemd) is a
 * listener (srv_add_listener): srv knows none of them by name.
 */
#ifndef SKYD_SRV_H
#define SKYD_SRV_H

#include <stddef.h>
#include <stdint.h>

#include "eng.h"
#include "sensor.h"
#include "state.h"

struct loop;
struct pub;
struct srv;

/* Who hears of what srv does; any member may be NULL. Listeners are told
 * in the order they were added. */
struct srv_listener {
	/* A change was accepted: st is the served state as set, generation
	 * the one that shows it, apply_time_ns the CLOCK_REALTIME instant it
	 * becomes visible (now, when it waits for nothing). Called once srv is
	 * done with it; the listener may make a change of its own (srv_apply),
	 * which every listener hears of once all have heard of this one. st
	 * is valid for the call. */
	void (*changed)(void *ctx, const struct sky_state *st, uint64_t generation,
			int64_t apply_time_ns);
	/* A new generation is current. tables: those computed for it.
	 * new_region: it lives in a new memfd (srv_pub) with a new layout. */
	void (*published)(void *ctx, uint64_t generation, uint32_t tables, int new_region);
	/* The computation meant for generation failed; message says why. */
	void (*failed)(void *ctx, uint64_t generation, const char *message);
	void *ctx;
};

#define SRV_MAX_LISTENERS 8

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
	uint64_t clouds_made_ahead;	/* cloud tables made ahead of the clock (look_ahead) */
	uint64_t clouds_taken_ahead;	/* computations that took them instead of the cloud passes */
	char last_error[256];		/* "" when the last computation succeeded */
	char storage_warning[192];	/* float16 broke in the last computation; "" when not */
	int publish_direct;		/* the device writes the current region's slots itself
					 * (eng_host_import); 0: skyd copies the tables in */
	uint64_t clock_ticks;		/* the clock drive's timer expirations */
	uint64_t clock_changes;		/* the moves it made changes */
	double clock_next_tick_s;	/* real seconds to its next tick; -1 none armed */
};

/* The light sensor as the protocol shows it (daemon/srv/sense.c fills it;
 * the control server reads it through srv_sensor_status). */
enum srv_sensor_curve {
	SRV_SENSOR_CURVE_USNO = 0,	/* sensor_curve_usno alone */
	SRV_SENSOR_CURVE_TABLES = 1,	/* refined by points measured from the tables */
};

struct srv_sensor_status {
	enum state_sensor_mode mode;	/* the served state's sensor_mode */
	struct sensor_status sensor;	/* the manager's; state off while none runs */
	int have_reading;		/* an output came since the manager started */
	double age_s;			/* since the last accepted reading; NAN none */
	uint64_t reading_mono_ns;	/* CLOCK_MONOTONIC of that reading; 0 none */
	double ev100;			/* of the last output; NAN none */
	double cloud_factor;		/* the served state's (weather.cloud_factor) */
	double clear_sky_lx;		/* the lights' clear-sky illuminance last predicted; NAN none */
	double elevation_deg;		/* the last inversion; NAN none */
	double deg_per_ln;		/* its sensitivity, d elevation / d ln E */
	enum srv_sensor_curve curve;
	size_t curve_points;		/* points from the tables in the curve */
	double curve_min_deg, curve_max_deg;	/* their range; NAN when none */
	char not_applied[160];		/* why the last output changed nothing; "" when it did */
	uint64_t changes;		/* changes the readings made */
	uint64_t generation;		/* that shows the last output's outcome (the
					 * current one before the first output) */
};

/* What the light sensor offers the readers of srv: its status and the
 * devices its manager knows (at most max into ret; 0 while none runs). */
struct srv_sensor {
	void (*status)(void *ctx, struct srv_sensor_status *ret);
	size_t (*devices)(void *ctx, struct sensor_info *ret, size_t max);
	void *ctx;
};

/* Takes neither loop nor engine; both must outlive the srv. The first
 * computation (every needed table of initial, resolved) starts at once,
 * and the clock drive watches initial's clock. */
int srv_new(struct loop *l, struct eng *e, const struct sky_state *initial, struct srv **ret);
/* srv_new publishing into region (taken, also on failure; pub_same_layout
 * as initial) whose newest generation is generation: the next publication
 * is generation + 1. Region NULL: srv_new. */
int srv_new_from(struct loop *l, struct eng *e, const struct sky_state *initial,
		 struct pub *region, uint64_t generation, struct srv **ret);
/* Adds a listener (copied): 0, or -ENOSPC past SRV_MAX_LISTENERS. */
int srv_add_listener(struct srv *s, const struct srv_listener *listener);
/* Removes the listeners whose ctx is ctx. */
void srv_remove_listener(struct srv *s, void *ctx);
void srv_free(struct srv *s);

/* The state as last changed (not necessarily computed yet). */
const struct sky_state *srv_state(const struct srv *s);
/* The state (as set: before state_resolve) whose tables the current slot
 * holds; the initial state before the first publication. */
const struct sky_state *srv_published(const struct srv *s);
/* The current region; valid until the next publication with a new layout. */
struct pub *srv_pub(const struct srv *s);
const struct eng_device *srv_device(const struct srv *s);
/* The grain the engine dispatches its passes at. */
enum eng_grain srv_grain(const struct srv *s);
void srv_status(const struct srv *s, struct srv_status *ret);

/* The generation that shows the served state as it is now: the published
 * one, the one in flight, or the one after it when a newer change waits. */
uint64_t srv_state_generation(const struct srv *s);

/* Applies a candidate state that a request built from the served one, as
 * one change: a new time_rate re-anchors the running clock
 * (state_clock_rebase); a new clock (time, place, light mode) places the
 * clock-driven lights at once (drive_lights), so that the generation named
 * shows them; then the cross-key and device rules on the state resolved
 * (state_resolve, once: kept for the computation); the clock drive then
 * takes the new lights as its reference, and the listeners hear of it.
 * dirty: the tables the request invalidated (state_set's mask). ret_dirty
 * gets them with the lights'. Returns 0; -ERANGE when refused (astro
 * cannot place the lights, or a cross-key or device rule), or -EIO /
 * -ENOMEM when the computation could not start: err says why and nothing
 * changed. */
int srv_apply(struct srv *s, const struct sky_state *next, uint32_t dirty,
	      uint64_t *ret_generation, uint32_t *ret_dirty, char *err, size_t err_size);

/* The light sensor registers here (NULL: none); ctl reads it below. */
void srv_set_sensor(struct srv *s, const struct srv_sensor *sensor);
/* The sensor's status: 0, or -ENODEV when none is registered. */
int srv_sensor_status(const struct srv *s, struct srv_sensor_status *ret);
/* The devices its manager knows, at most max; 0 when none. */
size_t srv_sensor_devices(const struct srv *s, struct sensor_info *ret, size_t max);

/* Replication (docs/sync.md): when a change accepted now becomes
 * visible, as a CLOCK_REALTIME instant (0: as soon as it is computed).
 * NULL apply_time_ns: as soon as computed. may_change: whether this skyd
 * may change the sky of its own accord (a follower may not: its sky is
 * the controller's), else 0 with the controller in charge in who; NULL:
 * always. Where changes go is a listener's business
 * (srv_listener.changed). */
struct srv_sync {
	int64_t (*apply_time_ns)(void *ctx);
	int (*may_change)(void *ctx, char *who, size_t who_size);
	void *ctx;
};
void srv_set_sync(struct srv *s, const struct srv_sync *sync);
/* 1 when this skyd may change the sky of its own accord (srv_sync's
 * may_change; always without replication), else 0 with who set. The
 * light sensor asks before it applies a reading. */
int srv_may_change(const struct srv *s, char *who, size_t who_size);

/* The next change (srv_apply, or the clock's) becomes visible at
 * apply_time_ns (CLOCK_REALTIME) rather than the hook's: its tables are computed at once
 * and written into the region's spare slot with that instant
 * (pub_publish_ahead: libsky switches to it then), and their generation is
 * made the current slot at that instant, or at once when it has passed.
 * Changes that coalesce with it keep the newest instant. */
void srv_set_next_apply_time(struct srv *s, int64_t apply_time_ns);

/* The next change (srv_apply) takes the cloud field's placement utc_s
 * (sky_state.clouds.utc_s: whole seconds, NAN where the field stands)
 * rather than placing it at its apply instant: a follower takes its
 * controller's. given 0: it places the field itself again. */
void srv_set_next_field(struct srv *s, int given, double utc_s);

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

/* srv.c - one way for a change: resolved once, coalesced into
 * computations, computations into published generations, and told to the
 * listeners; the clock drive's moves go the same way. */
#include "srv.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drive.h"
#include "log.h"
#include "loop.h"
#include "pub.h"
#include "simclock.h"

/* Four slots of the region must fit in memory beside everything else. */
#define SRV_MAX_REGION_BYTES (2ull << 30)
/* How many of the clock's next moves look_ahead looks at: a cell of the
 * lights' grid is some ten moves wide at the default threshold, a cell of
 * the field's lattice eight (docs/clouds.md, "Maps made ahead"). */
#define SRV_AHEAD_MOVES 32

/* A state as srv serves it: the keys as set (what get shows, what
 * listeners hear of), and once resolved what the tables and the slot get
 * (state_resolve: the weather applied, the lights times the cloud factor)
 * with its lights' directions, computed once here and handed to the
 * engine and the publisher. */
struct served {
	struct sky_state keys;
	struct sky_state sky;
	struct state_lights lights;
};

struct srv {
	struct loop *loop;
	struct eng *eng;
	struct loop_io *eng_io;
	struct pub *pub;
	/* A region of a new layout, made when a computation for it starts
	 * and current from its first publication. */
	struct pub *next_pub;
	/* Whether the engine imported pub's and next_pub's memory: it then
	 * writes the tables into the claimed slot itself (in_flight_direct)
	 * and skyd copies nothing. */
	int pub_direct, next_direct;
	int in_flight_direct;
	int told_copy;			/* the log said why the copy */
	struct drive *drive;		/* the clock, moving cur's lights */
	struct srv_listener listeners[SRV_MAX_LISTENERS];
	int n_listeners;
	struct srv_sensor sensor;	/* status NULL: none */

	struct served cur;		/* newest */
	uint32_t dirty;			/* invalidated since the last submission */
	int pending;			/* cur differs from what was submitted last */

	/* Telling the listeners: a change one of them makes meanwhile waits
	 * for the round to end (queued: the newest only), so that every
	 * listener hears of every change in order. told: the state of the
	 * round, which a change inside it leaves alone. */
	int telling, queued;
	uint64_t queued_generation;
	int64_t queued_apply_ns;
	struct sky_state told;

	/* computing: the computation's; published_keys: the state as set of
	 * the current slot. */
	struct served computing;
	struct sky_state published_keys;
	int in_flight;
	/* The computation in flight makes cloud tables ahead (look_ahead):
	 * it publishes nothing. ahead_worth: the last computation kept its
	 * cloud tables or took them made ahead, so the light or the field
	 * stays more than a move in a cell and the next one can be foreseen. */
	int ahead_in_flight, ahead_worth;
	/* The lights of the last computation, and their move from the one
	 * before (lights_moved: not zero), which look_ahead repeats when no
	 * clock moves them: a client that steps the time by its keys. */
	struct state_lights last_lights, lights_step;
	int have_last_lights, lights_moved;
	uint32_t in_flight_mask;
	uint64_t in_flight_generation;

	uint32_t eng_valid;		/* engine tables that match computing.sky */
	uint32_t demand;		/* tables clients asked for (srv_set_demand) */
	uint32_t own_demand;		/* tables the daemon reads itself (srv_set_own_demand) */
	uint64_t generation;		/* published */
	struct srv_status st;

	/* Switching at an apply time (srv_set_next_apply_time): the instant of
	 * the pending state and of the computation in flight; a finished
	 * computation whose instant is ahead goes into the spare slot at once
	 * (libsky switches to it at that instant) and stays in flight (held)
	 * until hold_timer makes it the current slot. */
	struct srv_sync sync;
	int64_t next_apply_ns;		/* for the next change; 0 none */
	int next_field_given;		/* the next change's placement: srv_set_next_field */
	double next_field_utc_s;
	int64_t pending_apply_ns;
	int64_t in_flight_apply_ns;
	int held;
	uint32_t held_computed;
	struct loop_timer *hold_timer;
};

const struct sky_state *srv_state(const struct srv *s)
{
	return &s->cur.keys;
}

const struct sky_state *srv_published(const struct srv *s)
{
	return &s->published_keys;
}

struct pub *srv_pub(const struct srv *s)
{
	return s->pub;
}

const struct eng_device *srv_device(const struct srv *s)
{
	return eng_device(s->eng);
}

enum eng_grain srv_grain(const struct srv *s)
{
	return eng_grain(s->eng);
}

void srv_status(const struct srv *s, struct srv_status *ret)
{
	struct drive_stats ds;

	*ret = s->st;
	drive_stats(s->drive, &ds);
	ret->clock_ticks = ds.ticks;
	ret->clock_changes = ds.changes;
	ret->clock_next_tick_s = ds.next_tick_s;
	ret->generation = s->generation;
	ret->computing = s->in_flight && !s->ahead_in_flight;
	ret->pending = s->pending;
	ret->published_valid = pub_current(s->pub, NULL)->valid_tables;
	ret->publish_direct = s->pub_direct;
	ret->demand = s->demand;
	ret->needed = srv_tables_needed(s);
}

/* The demand and what it depends on. With multi-scattering switched off
 * (multiscatter_dirs=0) sky-view and aerial perspective do not read the
 * multi-scattering table, so only an explicit demand computes it. */
static uint32_t demand_closure(const struct sky_state *st, uint32_t demand)
{
	uint32_t c = state_closure(demand);

	if (st->quality.multiscatter_dirs == 0 && !(demand & STATE_BIT(STATE_MULTISCATTER)))
		c &= ~STATE_BIT(STATE_MULTISCATTER);
	/* Drawn layers shadow sky-view and aerial perspective: their maps,
	 * made from the coverage table, come along; the terrain alone casts
	 * into the maps only. */
	if (eng_shadow_casters(st) && (c & (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL))))
		c |= state_clouds_drawn(st) ? STATE_CLOUD_TABLES : STATE_BIT(STATE_CLOUD_SHADOW);
	return c;
}

uint32_t srv_tables_needed(const struct srv *s)
{
	return demand_closure(&s->cur.keys, s->demand | s->own_demand);
}

uint32_t srv_tables_coming(const struct srv *s)
{
	uint32_t c = s->in_flight ? s->in_flight_mask : 0;

	return c | (s->dirty & srv_tables_needed(s));
}

/* Resolves c->keys into c->sky (once per change: the computation takes
 * it as it is) with its lights (given: the clock's, computed for the same
 * directions; NULL: computed here), then the cross-key and device rules:
 * those of state_validate, the user's atmosphere and the resolved one
 * alike, and a region's size. 0, or -EINVAL / -ERANGE with err. */
static int prepare(const struct srv *s, struct served *c, const struct state_lights *given,
		   char *err, size_t err_size)
{
	uint64_t total = 0;
	int r = atmo_validate(&c->keys.atmo, err, err_size);

	if (r < 0 || (r = state_resolve(&c->keys, &c->sky, NULL, err, err_size)) < 0 ||
	    (r = state_validate(&c->sky, eng_max_table_bytes(s->eng), err, err_size)) < 0)
		return r;
	for (int t = 0; t < STATE_N_TABLES; t++)
		total += state_table_bytes(&c->keys, (enum state_table)t);
	if (total * PUB_SLOTS > SRV_MAX_REGION_BYTES) {
		snprintf(err, err_size, "tables of %llu bytes in all exceed the %llu bytes of a region's slot",
			 (unsigned long long)total,
			 (unsigned long long)(SRV_MAX_REGION_BYTES / PUB_SLOTS));
		return -ERANGE;
	}
	if (given)
		c->lights = *given;
	else
		state_lights_of(&c->keys, &c->lights);
	return 0;
}

static void fail(struct srv *s, uint64_t generation, const char *message)
{
	snprintf(s->st.last_error, sizeof(s->st.last_error), "%s", message);
	s->st.failures++;
	log_error("computation for generation %llu failed: %s", (unsigned long long)generation,
		  message);
	for (int i = 0; i < s->n_listeners; i++)
		if (s->listeners[i].failed)
			s->listeners[i].failed(s->listeners[i].ctx, generation, message);
}

/* Lets the engine write r's slots itself where it can, unless
 * $SKYD_PUBLISH is "copy" (a diagnostic and test switch); 1 if it does.
 * Says why not once, in the log. */
static int import_region(struct srv *s, struct pub *r)
{
	const char *force = getenv("SKYD_PUBLISH");
	char err[128] = "";
	int rc;

	if (force && !strcmp(force, "copy"))
		return 0;
	rc = eng_host_import(s->eng, pub_map(r), (size_t)pub_bytes(r), err, sizeof(err));
	if (rc == -EOPNOTSUPP && !s->told_copy)
		log_info("publish: copy (%s)", err);
	else if (rc < 0)
		log_warning("the device cannot write the shared memory itself: %s; skyd copies the tables",
			    err);
	s->told_copy |= rc < 0;
	return rc == 0;
}

static void drop_region(struct srv *s, struct pub *r)
{
	if (!r)
		return;
	eng_host_release(s->eng, pub_map(r));
	pub_free(r);
}

/* The region the computation of computing.sky goes into: the current one,
 * or for a new layout a new region (made once, kept until published).
 * NULL, with err, when a new region cannot be made. */
static struct pub *target_region(struct srv *s, int *ret_direct, char *err, size_t err_size)
{
	if (pub_same_layout(s->pub, &s->computing.sky)) {
		*ret_direct = s->pub_direct;
		return s->pub;
	}
	if (s->next_pub && !pub_same_layout(s->next_pub, &s->computing.sky)) {
		drop_region(s, s->next_pub);
		s->next_pub = NULL;
	}
	if (!s->next_pub) {
		int r = pub_new_like(s->pub, &s->computing.sky, s->generation, &s->next_pub);
		if (r < 0) {
			snprintf(err, err_size, "new shared memory region: %s", strerror(-r));
			s->next_pub = NULL;
			return NULL;
		}
		s->next_direct = import_region(s, s->next_pub);
	}
	*ret_direct = s->next_direct;
	return s->next_pub;
}

/* Makes the region made for the computation's new layout current. */
static void switch_region(struct srv *s)
{
	pub_supersede(s->pub);
	drop_region(s, s->pub);
	s->pub = s->next_pub;
	s->pub_direct = s->next_direct;
	s->next_pub = NULL;
}

/* The engine's valid tables and their scales, as the publisher takes them. */
static void engine_tables(const struct srv *s, const void *ret_tables[STATE_N_TABLES],
			  int32_t ret_scales[STATE_N_TABLES])
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		ret_tables[t] = (s->eng_valid & STATE_BIT(t))
					? eng_table(s->eng, (enum state_table)t, NULL)
					: NULL;
		ret_scales[t] = eng_table_scale_log2(s->eng, (enum state_table)t);
	}
}

/* Publishes the computation's state with the engine's tables (no GPU work when
 * mask is 0: only the state changed for tables nobody needs), as current
 * from apply_ns (0: now). */
static void publish(struct srv *s, uint32_t computed, int64_t apply_ns)
{
	const void *tables[STATE_N_TABLES];
	int32_t scales[STATE_N_TABLES];
	int new_region = 0;
	uint64_t generation = s->in_flight_generation;

	if (s->next_pub && pub_same_layout(s->next_pub, &s->computing.sky)) {
		switch_region(s);
		new_region = 1;
	} else if (!pub_same_layout(s->pub, &s->computing.sky)) {
		struct pub *p;
		int r = pub_new_like(s->pub, &s->computing.sky, s->generation, &p);
		if (r < 0) {
			char msg[128];
			snprintf(msg, sizeof(msg), "new shared memory region: %s", strerror(-r));
			fail(s, generation, msg);
			s->dirty |= computed;
			s->eng_valid &= ~computed;
			return;
		}
		pub_supersede(s->pub);
		drop_region(s, s->pub);
		s->pub = p;
		s->pub_direct = import_region(s, p);
		new_region = 1;
	}
	/* A held computation's slot was written with it (publish_ahead):
	 * its apply time costs no copy. */
	if (new_region || apply_ns <= 0 || pub_publish_staged(s->pub, generation) < 0) {
		engine_tables(s, tables, scales);
		pub_set_cloud_tables(s->pub, eng_cloud_table(s->eng, STATE_CLOUD_COVERAGE, NULL),
				     eng_cloud_table(s->eng, STATE_CLOUD_SHADOW, NULL));
		if (s->in_flight_direct)
			pub_publish_claimed(s->pub, &s->computing.sky, &s->computing.lights,
					    s->eng_valid, scales, generation, apply_ns);
		else
			pub_publish_at(s->pub, &s->computing.sky, &s->computing.lights, s->eng_valid,
				       tables, eng_panoramas(s->eng, NULL), scales, generation,
				       apply_ns);
	}
	s->in_flight_direct = 0;
	s->published_keys = s->computing.keys;
	s->generation = generation;
	s->st.published_computed = computed;
	s->st.last_error[0] = 0;
	log_debug("generation %llu published", (unsigned long long)generation);
	for (int i = 0; i < s->n_listeners; i++)
		if (s->listeners[i].published)
			s->listeners[i].published(s->listeners[i].ctx, generation, computed,
						  new_region);
}

/* Writes the held computation into the spare slot for its apply time, so
 * that libsky switches at that instant by itself; a new layout waits for
 * the hold's end (its region comes with it). */
static void publish_ahead(struct srv *s)
{
	const void *tables[STATE_N_TABLES];
	int32_t scales[STATE_N_TABLES];

	if (!pub_same_layout(s->pub, &s->computing.sky))
		return;
	engine_tables(s, tables, scales);
	pub_set_cloud_tables(s->pub, eng_cloud_table(s->eng, STATE_CLOUD_COVERAGE, NULL),
			     eng_cloud_table(s->eng, STATE_CLOUD_SHADOW, NULL));
	pub_publish_ahead(s->pub, &s->computing.sky, &s->computing.lights, s->eng_valid, tables,
			  eng_panoramas(s->eng, NULL), scales, s->in_flight_generation,
			  s->in_flight_apply_ns);
}

static int64_t realtime_ns(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

/* Publishes the finished computation now, or, when its apply time is
 * ahead, into the spare slot at once and holds it (in flight, so that
 * nothing overwrites the engine's tables) until that time makes it the
 * current slot for readers that ignore apply times. Returns 1 when held. */
static int finish(struct srv *s, uint32_t computed)
{
	int64_t ahead_ns = s->in_flight_apply_ns - realtime_ns();

	if (s->in_flight_apply_ns > 0 && ahead_ns > 0 &&
	    loop_timer_arm(s->hold_timer, (uint64_t)ahead_ns) == 0) {
		s->in_flight = 1;
		s->held = 1;
		s->held_computed = computed;
		publish_ahead(s);
		return 1;
	}
	/* A slot made current never names an instant still ahead. */
	publish(s, computed, s->in_flight_apply_ns > 0 && ahead_ns <= 0 ? s->in_flight_apply_ns : 0);
	return 0;
}

static void kick(struct srv *s);

static void hold_expired(void *ctx)
{
	struct srv *s = ctx;

	if (!s->held)
		return;
	s->held = 0;
	s->in_flight = 0;
	publish(s, s->held_computed, s->in_flight_apply_ns);
	kick(s);
}

/* Float16 storage can overflow (a bright sky, Mars) or lose its precision
 * in subnormals (deep twilight): said in status and the log, not refused,
 * since where it breaks depends on the sky, not on a key. */
static void check_storage(struct srv *s, uint32_t computed)
{
	struct eng_f16_range r;

	eng_f16_range(s->eng, &s->computing.sky, computed, &r);
	if (!eng_f16_broken(&r)) {
		s->st.storage_warning[0] = 0;
		return;
	}
	snprintf(s->st.storage_warning, sizeof(s->st.storage_warning),
		 "storage=f16 breaks: %llu values not finite, %llu of %llu sky radiance values "
		 "above the night floor subnormal; use storage=f32",
		 (unsigned long long)r.overflow, (unsigned long long)r.subnormal,
		 (unsigned long long)r.radiance_values);
	log_warning("%s", s->st.storage_warning);
}

/* Where the computation's tables go: into the next slot of its region,
 * which the device writes itself where the engine imported the region
 * (*ret_direct), or into the engine's host copies, from which publish
 * copies them. A computation with an apply time takes the copies: it may
 * be published ahead into the spare slot; so does one whose new region
 * cannot be made now (publish tries again, and says why it fails). */
static void plan_target(struct srv *s, struct eng_target *target, int *ret_direct)
{
	char err[128];
	int direct = 0;
	struct pub *r;

	*ret_direct = 0;
	if (!target->tables || s->in_flight_apply_ns)
		return;
	r = target_region(s, &direct, err, sizeof(err));
	if (r && direct && pub_claim(r, &s->computing.sky, &s->computing.lights, target->tables, target) == 0)
		*ret_direct = 1;
}

/* Starts computing the newest state, as prepare resolved it, if nothing
 * is in flight; with nothing to compute, publishes at once unless the
 * tables kept must reach the slot through the device. */
static void kick(struct srv *s)
{
	char err[256] = "";
	uint32_t mask;
	int r;

	if (s->in_flight || !s->pending)
		return;
	s->computing = s->cur;
	s->pending = 0;
	s->eng_valid &= ~s->dirty;
	mask = s->dirty & srv_tables_needed(s);
	s->dirty &= ~mask;
	s->in_flight_generation = s->generation + 1;
	s->in_flight_mask = mask;
	s->in_flight_apply_ns = s->pending_apply_ns;
	s->pending_apply_ns = 0;
	/* The slot holds the tables kept and those computed now. */
	struct eng_target target = { .base = NULL, .tables = s->eng_valid | mask };
	int direct = 0;
	plan_target(s, &target, &direct);
	if (!mask && !direct && eng_host_fresh(s->eng, target.tables)) {
		finish(s, 0);
		return;
	}
	r = eng_submit_to(s->eng, &s->computing.sky, &s->computing.lights, mask, &target, err,
			  sizeof(err));
	if (r < 0) {
		s->dirty |= mask;
		fail(s, s->in_flight_generation, err[0] ? err : strerror(-r));
		return;
	}
	s->in_flight = 1;
	s->in_flight_direct = direct;
}

/* Whether the engine holds the cloud tables of sky lit by lights in its
 * bound set (1: look further); if not, makes them ahead unless its spare
 * set has them (0). */
static int ahead_of(struct srv *s, const struct sky_state *sky, const struct state_lights *lights)
{
	char err[256] = "";
	enum eng_clouds_made made = eng_clouds_made(s->eng, sky, lights);

	if (made == ENG_CLOUDS_BOUND)
		return 1;
	if (made == ENG_CLOUDS_NONE && eng_submit_ahead(s->eng, sky, lights, err, sizeof(err)) == 0) {
		s->in_flight = s->ahead_in_flight = 1;
	} else if (err[0]) {
		log_warning("cloud tables ahead: %s", err);
		s->ahead_worth = 0;
	}
	return 0;
}

/* The light moved by k steps of step from at, into ret (a unit vector). */
static void light_ahead(const double at[3], const double step[3], int k, double ret[3])
{
	double n = 0.0;

	for (int i = 0; i < 3; i++) {
		ret[i] = at[i] + k * step[i];
		n += ret[i] * ret[i];
	}
	n = n > 0.0 ? 1.0 / sqrt(n) : 0.0;
	for (int i = 0; i < 3; i++)
		ret[i] *= n;
}

/* The cloud tables the next changes will need, made while the device
 * would idle (docs/clouds.md, "Maps made ahead"): the served state as its
 * clock moves it, one move after another, or, with no clock running, with
 * the lights' last move repeated (a client that steps the time by its
 * keys), up to the first whose tables the engine's bound set does not
 * hold; made ahead unless the spare set holds them already. Only while
 * sky-view or aerial perspective is wanted (they read the maps), nothing
 * waits, and the moves stay in cells (ahead_worth): where each move
 * crosses cells (a light a few degrees high), the next one may skip the
 * cell foreseen. */
static void look_ahead(struct srv *s)
{
	const uint32_t readers = STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL);
	double step_s = drive_move_interval_s(&s->cur.keys), mono_s;
	char err[256] = "";

	if (s->in_flight || s->pending || !s->ahead_worth || !(step_s > 0.0 || s->lights_moved) ||
	    !eng_shadow_casters(&s->cur.sky) || !(srv_tables_needed(s) & readers))
		return;
	if (!(step_s > 0.0)) {
		struct state_lights l;
		for (int k = 1; k <= SRV_AHEAD_MOVES; k++) {
			light_ahead(s->cur.lights.sun, s->lights_step.sun, k, l.sun);
			light_ahead(s->cur.lights.moon, s->lights_step.moon, k, l.moon);
			if (!ahead_of(s, &s->cur.sky, &l))
				break;
		}
		return;
	}
	struct served *f = malloc(sizeof(*f));
	if (!f)
		return;
	simclock_read_clocks(NULL, &mono_s);
	for (int k = 1; k <= SRV_AHEAD_MOVES; k++) {
		f->keys = s->cur.keys;
		if (drive_lights(&f->keys, mono_s + k * step_s, NULL, err, sizeof(err)) < 0 ||
		    prepare(s, f, NULL, err, sizeof(err)) < 0 || !ahead_of(s, &f->sky, &f->lights))
			break;
	}
	free(f);
}

/* Keeps the lights of the computation just made and their move. */
static void note_lights(struct srv *s)
{
	const struct state_lights *l = &s->computing.lights;

	s->lights_moved = 0;
	for (int i = 0; i < 3 && s->have_last_lights; i++) {
		s->lights_step.sun[i] = l->sun[i] - s->last_lights.sun[i];
		s->lights_step.moon[i] = l->moon[i] - s->last_lights.moon[i];
		s->lights_moved |= s->lights_step.sun[i] != 0.0 || s->lights_step.moon[i] != 0.0;
	}
	s->last_lights = *l;
	s->have_last_lights = 1;
}

static void eng_ready(void *ctx, uint32_t events)
{
	struct srv *s = ctx;
	struct eng_timing timing;
	char err[256] = "";
	int r;

	if (!s->in_flight || s->held)
		return;
	r = eng_complete(s->eng, &timing, err, sizeof(err));
	if (r == -EAGAIN)
		return;
	s->in_flight = 0;
	if (s->ahead_in_flight) {
		s->ahead_in_flight = 0;
		if (r < 0) {
			log_warning("cloud tables ahead: %s", err[0] ? err : strerror(-r));
			s->ahead_worth = 0;
		} else {
			s->st.clouds_made_ahead++;
		}
		kick(s);
		return;
	}
	s->st.computations++;
	if (r < 0) {
		s->in_flight_direct = 0;
		s->dirty |= s->in_flight_mask;
		s->eng_valid &= ~s->in_flight_mask;
		/* Nothing is made ahead of tables that were not published. */
		s->ahead_worth = 0;
		fail(s, s->in_flight_generation, err[0] ? err : strerror(-r));
	} else {
		/* The engine adds the cloud tables its reads need. */
		s->eng_valid |= s->in_flight_mask | timing.computed;
		s->st.last_computed = timing.computed ? timing.computed : s->in_flight_mask;
		s->st.last_total_ms = timing.total_ms;
		s->st.column_passes += (uint64_t)timing.columns;
		s->st.clouds_taken_ahead += (uint64_t)timing.clouds_ahead;
		s->ahead_worth = timing.clouds_ahead || !(timing.computed & STATE_BIT(STATE_CLOUD_SHADOW));
		note_lights(s);
		for (int t = 0; t < STATE_N_TABLES; t++)
			if (s->st.last_computed & STATE_BIT(t))
				s->st.table_ms[t] = timing.table_ms[t];
		check_storage(s, s->st.last_computed);
		if (finish(s, s->in_flight_mask | (timing.computed & STATE_CLOUD_TABLES)))
			return;
	}
	kick(s);
	look_ahead(s);
}

void srv_set_sync(struct srv *s, const struct srv_sync *sync)
{
	s->sync = *sync;
}

int srv_may_change(const struct srv *s, char *who, size_t who_size)
{
	return !s->sync.may_change || s->sync.may_change(s->sync.ctx, who, who_size);
}

void srv_set_next_apply_time(struct srv *s, int64_t apply_time_ns)
{
	s->next_apply_ns = apply_time_ns;
}

/* Tells the listeners of an accepted change, in the order they were
 * added; a change one of them makes meanwhile is told after this round. */
static void tell_changed(struct srv *s, uint64_t generation, int64_t apply_ns)
{
	if (s->telling) {
		s->queued = 1;
		s->queued_generation = generation;
		s->queued_apply_ns = apply_ns;
		return;
	}
	s->telling = 1;
	do {
		s->queued = 0;
		s->told = s->cur.keys;
		for (int i = 0; i < s->n_listeners; i++)
			if (s->listeners[i].changed)
				s->listeners[i].changed(s->listeners[i].ctx, &s->told, generation,
							apply_ns);
		generation = s->queued_generation;
		apply_ns = s->queued_apply_ns;
	} while (s->queued);
	s->telling = 0;
}

/* Makes c (prepared) the served state; dirty: the tables it invalidates.
 * ret_generation: the generation in which it becomes visible;
 * ret_apply_ns: the instant (CLOCK_REALTIME) it does. -EIO when the
 * computation could not start (err says why), -ENOMEM: nothing changed. */
static int change(struct srv *s, const struct served *c, uint32_t dirty,
		  uint64_t *ret_generation, int64_t *ret_apply_ns, char *err, size_t err_size)
{
	uint64_t failures = s->st.failures;
	uint32_t prev_dirty = s->dirty;
	int prev_pending = s->pending;
	int64_t apply_ns = s->next_apply_ns;
	struct served *prev = malloc(sizeof(*prev));

	s->next_apply_ns = 0;
	if (!prev)
		return -ENOMEM;
	if (!apply_ns && s->sync.apply_time_ns)
		apply_ns = s->sync.apply_time_ns(s->sync.ctx);
	*ret_apply_ns = apply_ns ? apply_ns : realtime_ns();
	*prev = s->cur;
	s->cur = *c;
	s->dirty |= dirty;
	if (!dirty && !s->pending) {
		/* Nothing new: visible with what is in flight, or already. */
		*ret_generation = s->in_flight ? s->in_flight_generation : s->generation;
		free(prev);
		return 0;
	}
	s->pending = 1;
	if (apply_ns)
		s->pending_apply_ns = apply_ns;
	kick(s);
	if (s->st.failures != failures) {
		/* The computation could not start (a table the device cannot
		 * allocate): the request is refused whole, the state goes back.
		 * The engine may have released tables on the way, so everything
		 * it holds is recomputed before it is published again; the last
		 * good tables stay published meanwhile. */
		s->cur = *prev;
		s->dirty = prev_dirty | STATE_ALL_TABLES | STATE_CLOUD_TABLES;
		s->eng_valid = 0;
		s->pending = prev_pending;
		free(prev);
		snprintf(err, err_size, "%s", s->st.last_error);
		return -EIO;
	}
	free(prev);
	*ret_generation = srv_state_generation(s);
	return 0;
}

uint64_t srv_state_generation(const struct srv *s)
{
	if (s->pending)		/* behind the computation in flight */
		return s->in_flight_generation + 1;
	return s->in_flight ? s->in_flight_generation : s->generation;
}

/* Places the cloud field of keys at the instant a change made now applies
 * (drive_field): a controller and its followers, which switch together
 * then, place it alike. Returns that instant for change (0: now). */
static int64_t place_field(struct srv *s, struct sky_state *keys, double real_s, double mono_s,
			   uint32_t *dirty)
{
	int64_t at_ns = s->next_apply_ns;

	if (!at_ns && s->sync.apply_time_ns)
		at_ns = s->sync.apply_time_ns(s->sync.ctx);
	if (s->next_field_given)
		drive_field_at(keys, s->next_field_utc_s, dirty);
	else
		drive_field(keys, mono_s + (at_ns ? (double)at_ns / 1e9 - real_s : 0.0), dirty);
	return at_ns;
}

void srv_set_next_field(struct srv *s, int given, double utc_s)
{
	s->next_field_given = given;
	s->next_field_utc_s = utc_s;
}

int srv_apply(struct srv *s, const struct sky_state *next, uint32_t dirty,
	      uint64_t *ret_generation, uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct served *c = malloc(sizeof(*c));
	uint64_t generation;
	double real_s, mono_s;
	int64_t apply_ns;
	int r = -ERANGE;

	if (!c)
		return -ENOMEM;
	c->keys = *next;
	simclock_read_clocks(&real_s, &mono_s);
	if (memcmp(&c->keys.clock, &s->cur.keys.clock, sizeof(c->keys.clock)) != 0) {
		state_clock_rebase(&c->keys, &s->cur.keys, mono_s);
		if (drive_lights(&c->keys, mono_s, &dirty, err, err_size) < 0)
			goto out;
	}
	int64_t at_ns = place_field(s, &c->keys, real_s, mono_s, &dirty);
	if (prepare(s, c, NULL, err, err_size) < 0)
		goto out;
	s->next_apply_ns = at_ns;
	r = change(s, c, dirty, &generation, &apply_ns, err, err_size);
	if (r < 0)
		goto out;
	drive_changed(s->drive);
	*ret_generation = generation;
	*ret_dirty = dirty;
	tell_changed(s, generation, apply_ns);
out:
	free(c);
	return r;
}

/* The clock's move (drive_move_fn): a change like srv_apply's, but for the
 * drive's reference, which the drive takes itself. */
static void clock_moved(void *ctx, const struct sky_state *next, const struct state_lights *lights,
			uint32_t dirty)
{
	struct srv *s = ctx;
	struct served *c = malloc(sizeof(*c));
	char err[256] = "";
	uint64_t generation;
	int64_t apply_ns;

	if (!c) {
		log_warning("clock: out of memory; the lights stay where they are");
		return;
	}
	c->keys = *next;
	double real_s, mono_s;
	simclock_read_clocks(&real_s, &mono_s);
	int64_t at_ns = place_field(s, &c->keys, real_s, mono_s, &dirty);
	int r = prepare(s, c, lights, err, sizeof(err));
	if (r == 0) {
		s->next_apply_ns = at_ns;
		r = change(s, c, dirty, &generation, &apply_ns, err, sizeof(err));
	}
	if (r < 0)
		log_warning("clock: computation did not start: %s", err);
	else
		tell_changed(s, generation, apply_ns);
	free(c);
}

/* A table asked for that is not current: compute it (and only the
 * missing part of its closure), with the state as it is. */
static void demand_changed(struct srv *s)
{
	if (s->dirty & srv_tables_needed(s)) {
		s->pending = 1;
		kick(s);
	}
}

void srv_set_demand(struct srv *s, uint32_t tables)
{
	s->demand = tables & (STATE_ALL_TABLES | STATE_CLOUD_TABLES);
	demand_changed(s);
}

void srv_set_own_demand(struct srv *s, uint32_t tables)
{
	s->own_demand = tables & (STATE_ALL_TABLES | STATE_CLOUD_TABLES);
	demand_changed(s);
}

int srv_add_listener(struct srv *s, const struct srv_listener *listener)
{
	if (s->n_listeners == SRV_MAX_LISTENERS)
		return -ENOSPC;
	s->listeners[s->n_listeners++] = *listener;
	return 0;
}

void srv_remove_listener(struct srv *s, void *ctx)
{
	int n = 0;

	for (int i = 0; i < s->n_listeners; i++)
		if (s->listeners[i].ctx != ctx)
			s->listeners[n++] = s->listeners[i];
	s->n_listeners = n;
}

void srv_set_sensor(struct srv *s, const struct srv_sensor *sensor)
{
	if (sensor)
		s->sensor = *sensor;
	else
		memset(&s->sensor, 0, sizeof(s->sensor));
}

int srv_sensor_status(const struct srv *s, struct srv_sensor_status *ret)
{
	if (!s->sensor.status)
		return -ENODEV;
	s->sensor.status(s->sensor.ctx, ret);
	return 0;
}

size_t srv_sensor_devices(const struct srv *s, struct sensor_info *ret, size_t max)
{
	return s->sensor.devices ? s->sensor.devices(s->sensor.ctx, ret, max) : 0;
}

int srv_new(struct loop *l, struct eng *e, const struct sky_state *initial, struct srv **ret)
{
	return srv_new_from(l, e, initial, NULL, 0, ret);
}

int srv_new_from(struct loop *l, struct eng *e, const struct sky_state *initial,
		 struct pub *region, uint64_t generation, struct srv **ret)
{
	struct srv *s = calloc(1, sizeof(*s));
	int r;

	if (!s) {
		pub_free(region);
		return -ENOMEM;
	}
	s->loop = l;
	s->eng = e;
	s->cur.keys = *initial;
	s->published_keys = *initial;
	for (int t = 0; t < STATE_N_TABLES; t++)
		s->st.table_ms[t] = -1;
	/* An adopted region goes on counting where its last skyd stopped. */
	s->generation = generation;
	s->pub = region;
	r = region ? 0 : pub_new(initial, 0, &s->pub);
	if (r < 0)
		goto fail;
	s->pub_direct = import_region(s, s->pub);
	/* The initial state was validated by the caller, with the device. */
	char err[256] = "";
	r = state_resolve(initial, &s->cur.sky, NULL, err, sizeof(err));
	if (r < 0) {
		log_error("initial state: %s", err);
		goto fail;
	}
	state_lights_of(initial, &s->cur.lights);
	r = drive_new(l, &s->cur.keys, &s->cur.lights, clock_moved, s, &s->drive);
	if (r < 0)
		goto fail;
	/* Edge-triggered: right whether or not eng_complete drains the eventfd. */
	r = loop_io_add(l, eng_event_fd(e), EPOLLIN | EPOLLET, eng_ready, s, &s->eng_io);
	if (r < 0)
		goto fail;
	r = loop_timer_add(l, hold_expired, s, &s->hold_timer);
	if (r < 0)
		goto fail;
	s->dirty = STATE_ALL_TABLES | STATE_CLOUD_TABLES;
	s->pending = 1;
	kick(s);
	*ret = s;
	return 0;
fail:
	srv_free(s);
	return r;
}

void srv_free(struct srv *s)
{
	if (!s)
		return;
	drive_free(s->drive);
	loop_io_del(s->eng_io);
	loop_timer_del(s->hold_timer);
	drop_region(s, s->next_pub);
	drop_region(s, s->pub);
	free(s);
}

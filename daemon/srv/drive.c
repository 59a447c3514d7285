/* drive.c - the clock's sun, moon and cloud field, and the timer that
 * moves them. */
#include "drive.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "log.h"
#include "loop.h"
#include "simclock.h"
#include "state_keys.h"

#define LIGHTS (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL))
/* What a move of the cloud field invalidates: its tables and the sky
 * tables its shadows reach (the cloud keys' mask). */
#define FIELD (STATE_CLOUD_TABLES | LIGHTS)

/* Ticks never come closer than this: beyond it the engine, not the clock,
 * bounds how often the sky changes, and srv coalesces anyway. */
#define DRIVE_MIN_TICK_S 0.01
/* A clock that moves very slowly is still looked at this often. */
#define DRIVE_MAX_TICK_S 60.0

struct drive {
	struct loop *loop;
	const struct sky_state *served;
	const struct state_lights *served_lights;
	drive_move_fn *move;
	void *ctx;
	struct loop_timer *timer;
	struct state_lights ref;	/* directions as last submitted */
	int ref_moon_lit;
	double ref_field_utc_s;		/* the cloud field's time as last submitted */
	double ref_mono_s;		/* when they were submitted */
	double armed_mono_s;		/* when the timer fires; -1 disarmed */
	int warned;			/* astro refused the clock: logged once */
	uint64_t ticks, changes;
};

void drive_field(struct sky_state *s, double mono_s, uint32_t *ret_dirty)
{
	drive_field_at(s, floor(state_clock_utc_s(s, mono_s)), ret_dirty);
}

void drive_field_at(struct sky_state *s, double utc_s, uint32_t *ret_dirty)
{
	double want = state_clouds_drawn(s) && s->clouds.wind_speed_mps > 0.0 ? utc_s : NAN;

	if (memcmp(&want, &s->clouds.utc_s, sizeof(want)) == 0)
		return;
	s->clouds.utc_s = want;
	if (ret_dirty)
		*ret_dirty |= FIELD;
}

double drive_field_speed_km_s(const struct sky_state *s)
{
	if (!state_clouds_drawn(s) || isnan(s->clock.anchor_utc_s))
		return 0.0;
	return s->clouds.wind_speed_mps * 1e-3 * fabs(s->clock.rate);
}

double drive_field_threshold_km(const struct sky_state *s)
{
	return DRIVE_FIELD_TEXEL_SHARE * 2.0 * state_cloud_extent_km(s) / s->quality.shadow_width;
}

int drive_lights(struct sky_state *s, double mono_s, uint32_t *ret_dirty, char *err,
		 size_t err_size)
{
	struct sky_state next = *s;
	struct astro_site site;
	struct astro_options opt;
	double utc_s = state_clock_utc_s(s, mono_s);
	int sun = s->clock.sun_mode == STATE_CLOCK, moon = s->clock.moon_mode == STATE_CLOCK;
	int r;

	next.lights_utc_s = NAN;
	if ((sun || moon) && !isnan(utc_s)) {
		state_astro_site(s, &site, &opt);
		next.lights_utc_s = utc_s;
	}
	if (sun && !isnan(utc_s)) {
		struct astro_sun a;
		r = astro_sun(&site, utc_s, &opt, &a, err, err_size);
		if (r < 0)
			return r;
		next.sun.elevation_deg = a.geometric.elevation_deg;
		next.sun.azimuth_deg = a.geometric.azimuth_deg;
		next.sun.illuminance_lx = a.illuminance_lx;
		/* Rounded, so that the disk the multiple-scattering table sees
		 * moves a few times a day rather than at every step. */
		next.sun.angular_radius_deg =
			round(a.angular_radius_deg / DRIVE_SUN_RADIUS_STEP_DEG) * DRIVE_SUN_RADIUS_STEP_DEG;
	}
	if (moon && !isnan(utc_s)) {
		struct astro_moon m;
		r = astro_moon(&site, utc_s, &opt, &m, err, err_size);
		if (r < 0)
			return r;
		next.moon.elevation_deg = m.geometric.elevation_deg;
		next.moon.azimuth_deg = m.geometric.azimuth_deg;
		next.moon.angular_radius_deg = m.angular_radius_deg;
		memcpy(next.moon.color, m.color, sizeof(m.color));
		next.moon.illuminance_lx = m.geometric.elevation_deg > DRIVE_MOON_MIN_ELEVATION_DEG
					   ? m.illuminance_lx : 0.0;
	}
	if (ret_dirty && (memcmp(&next.sun, &s->sun, sizeof(next.sun)) ||
			  memcmp(&next.moon, &s->moon, sizeof(next.moon)) ||
			  memcmp(&next.lights_utc_s, &s->lights_utc_s, sizeof(double))))
		*ret_dirty |= LIGHTS;
	/* The sun's distance moves its disk, which the multiple-scattering
	 * table sees too: the key's row says what that invalidates. */
	if (ret_dirty && next.sun.angular_radius_deg != s->sun.angular_radius_deg)
		*ret_dirty |= state_key_find("sun_angular_radius_deg")->dirty;
	drive_field(&next, mono_s, ret_dirty);
	*s = next;
	return 0;
}

static double angle_deg(const double a[3], const double b[3])
{
	double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
	return acos(fmax(-1.0, fmin(1.0, d))) * 180.0 / M_PI;
}

static void take_reference(struct drive *d, const struct sky_state *s,
			   const struct state_lights *lights, double mono_s)
{
	d->ref = *lights;
	d->ref_moon_lit = s->moon.illuminance_lx > 0.0;
	d->ref_field_utc_s = s->clouds.utc_s;
	d->ref_mono_s = mono_s;
}

double drive_move_interval_s(const struct sky_state *s)
{
	const struct state_clock *c = &s->clock;
	double field_km_s = drive_field_speed_km_s(s), interval_s = INFINITY;

	if (isnan(c->anchor_utc_s) || c->rate == 0.0)
		return 0.0;
	if (c->sun_mode == STATE_CLOCK || c->moon_mode == STATE_CLOCK)
		interval_s = c->threshold_deg / (DRIVE_MAX_SPEED_DEG_PER_H / 3600.0 * fabs(c->rate));
	if (field_km_s > 0.0)
		interval_s = fmin(interval_s, drive_field_threshold_km(s) / field_km_s);
	return isfinite(interval_s) ? interval_s : 0.0;
}

/* Half the real time in which the fastest light could cover the threshold,
 * or the wind the cloud field's, so that no move overshoots it by more
 * than half; within the cadence. */
static void arm(struct drive *d, const struct sky_state *s, double mono_s)
{
	const struct state_clock *c = &s->clock;
	double interval_s = drive_move_interval_s(s);

	d->armed_mono_s = -1.0;
	if (!(interval_s > 0.0)) {
		loop_timer_arm(d->timer, 0);
		return;
	}
	double delay_s = 0.5 * interval_s;
	if (c->cadence_s > 0.0)
		delay_s = fmin(delay_s, fmax(c->cadence_s - (mono_s - d->ref_mono_s), 0.0));
	delay_s = fmin(fmax(delay_s, DRIVE_MIN_TICK_S), DRIVE_MAX_TICK_S);
	d->armed_mono_s = mono_s + delay_s;
	loop_timer_arm(d->timer, (uint64_t)(delay_s * 1e9));
}

static void tick(void *ctx)
{
	struct drive *d = ctx;
	struct sky_state next = *d->served;
	struct state_lights lights;
	char err[256] = "";
	uint32_t dirty = 0;
	double mono_s;

	d->ticks++;
	simclock_read_clocks(NULL, &mono_s);
	if (drive_lights(&next, mono_s, &dirty, err, sizeof(err)) < 0) {
		/* The clock ran out of astro's years: the lights stay put. */
		if (!d->warned)
			log_warning("clock: %s; the lights stay where they are", err);
		d->warned = 1;
		d->armed_mono_s = -1.0;
		return;
	}
	d->warned = 0;
	state_lights_of(&next, &lights);
	double moved = fmax(angle_deg(lights.sun, d->ref.sun),
			    next.moon.illuminance_lx > 0.0 ? angle_deg(lights.moon, d->ref.moon) : 0.0);
	int lit_changed = (next.moon.illuminance_lx > 0.0) != d->ref_moon_lit;
	int due = next.clock.cadence_s > 0.0 && mono_s - d->ref_mono_s >= next.clock.cadence_s;
	/* The field's move since the reference, or a placement that began or
	 * ended (the time became known, the wind rose or fell). */
	double field_km = fabs(next.clouds.utc_s - d->ref_field_utc_s) * next.clouds.wind_speed_mps * 1e-3;
	int field_moved = isnan(next.clouds.utc_s) != isnan(d->ref_field_utc_s) ||
			  field_km >= drive_field_threshold_km(&next);
	if (dirty && (moved >= next.clock.threshold_deg || lit_changed || due || field_moved)) {
		d->move(d->ctx, &next, &lights, dirty);
		d->changes++;
		take_reference(d, &next, &lights, mono_s);
	}
	arm(d, &next, mono_s);
}

void drive_changed(struct drive *d)
{
	double mono_s;

	simclock_read_clocks(NULL, &mono_s);
	take_reference(d, d->served, d->served_lights, mono_s);
	d->warned = 0;
	arm(d, d->served, mono_s);
}

void drive_stats(const struct drive *d, struct drive_stats *ret)
{
	double mono_s;

	simclock_read_clocks(NULL, &mono_s);
	ret->ticks = d->ticks;
	ret->changes = d->changes;
	ret->next_tick_s = d->armed_mono_s < 0.0 ? -1.0 : fmax(d->armed_mono_s - mono_s, 0.0);
}

int drive_new(struct loop *l, const struct sky_state *served, const struct state_lights *lights,
	      drive_move_fn *move, void *ctx, struct drive **ret)
{
	struct drive *d = calloc(1, sizeof(*d));
	int r;

	if (!d)
		return -ENOMEM;
	d->loop = l;
	d->served = served;
	d->served_lights = lights;
	d->move = move;
	d->ctx = ctx;
	d->armed_mono_s = -1.0;
	r = loop_timer_add(l, tick, d, &d->timer);
	if (r < 0) {
		free(d);
		return r;
	}
	drive_changed(d);
	*ret = d;
	return 0;
}

void drive_free(struct drive *d)
{
	if (!d)
		return;
	loop_timer_del(d->timer);
	free(d);
}

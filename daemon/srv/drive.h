/* drive.h - the simulation clock driving the sun, the moon and the cloud
 * field: it turns the state's time and place into light directions and the
 * wind's offset of the clouds, and a timer on the loop hands on a move
 * whenever a light moved past the threshold, the wind carried the clouds
 * past theirs, or the cadence elapsed.
 *
 * The tables are lit by the geometric (unrefracted) directions; astro's
 * refracted ones are only reported (ctl's get sun / get moon). srv owns
 * the drive: it watches the served state, and srv makes each move a change
 * like any request's, so that it coalesces with the rest: at most one
 * computation in flight, only the newest state computed. The drive calls
 * nothing of srv.
 */
#ifndef SKYD_DRIVE_H
#define SKYD_DRIVE_H

#include <stddef.h>
#include <stdint.h>

#include "astro.h"
#include "state.h"

struct drive;
struct loop;

/* The moon lights the tables while its geometric elevation is above this:
 * lower down, its twilight (the sun's twilight scaled by the moon/sun
 * illuminance ratio, about 2e-6) adds under 1 % of the night-sky floor. */
#define DRIVE_MOON_MIN_ELEVATION_DEG (-5.0)

/* The clock's sun disk radius is kept to this step (0.036 arcsec, far
 * below the ephemeris' error): the radius follows the earth's distance by
 * at most 4e-5 deg a day, so the multiple-scattering table, which sees
 * the disk, is recomputed a few times a day instead of at every move. */
#define DRIVE_SUN_RADIUS_STEP_DEG 1e-5

/* Upper bound of how fast either light moves across the sky, in degrees
 * of simulated time per hour: the earth turns 15.04 deg/h; the moon's
 * own motion is slower and in the other direction. */
#define DRIVE_MAX_SPEED_DEG_PER_H 15.1

/* Puts into s the lights whose mode is STATE_CLOCK as they are at monotonic
 * time mono_s: sun direction, illuminance (133.8 klx / R^2, clear sky: the
 * tables get it times the state's cloud factor, state_resolve) and angular
 * radius; moon direction, angular radius, colour and illuminance (0 while
 * it is below DRIVE_MOON_MIN_ELEVATION_DEG); lights_utc_s; and the cloud
 * field (drive_field). Nothing when no light is clock-driven or no time
 * is set (lights_utc_s becomes NAN).
 * ret_dirty, if not NULL, gets the tables this invalidated ORed in.
 * -EINVAL with err naming the key (utc, lat_deg, ...) when astro refuses
 * the time or place; s is untouched then. Pure apart from its arguments. */
int drive_lights(struct sky_state *s, double mono_s, uint32_t *ret_dirty, char *err,
		 size_t err_size);

/* The cloud field is recomputed when the wind has carried it this share
 * of a shadow map's texel (2 cloud_extent_km / shadow_width) since it was
 * last placed: a quarter keeps a shadow's edge within a quarter texel of
 * where the wind has it, and costs a move every 40 simulated seconds for
 * a 7.7 m/s wind over the 160 km region of a layer at 2 km. */
#define DRIVE_FIELD_TEXEL_SHARE 0.25

/* Places the cloud field of s at the simulated time of monotonic time
 * mono_s, in whole seconds (clouds.utc_s), while it moves: a layer drawn,
 * a wind and a time; NAN else. ret_dirty, if not NULL, gets the field's
 * tables ORed in when the placement changed. Two clocks that agree to a
 * fraction of a second can still floor to different seconds: a follower
 * takes the controller's placement as it is (drive_field_at). */
void drive_field(struct sky_state *s, double mono_s, uint32_t *ret_dirty);

/* The same with the placement given: utc_s (whole seconds) while the field
 * moves, NAN else. */
void drive_field_at(struct sky_state *s, double utc_s, uint32_t *ret_dirty);

/* How far the wind moves the field of s in km per real second while the
 * clock runs (0 while it stands still), and the distance that calls for a
 * recomputation (DRIVE_FIELD_TEXEL_SHARE of a shadow map's texel). */
double drive_field_speed_km_s(const struct sky_state *s);
double drive_field_threshold_km(const struct sky_state *s);

/* The fewest real seconds between two of the clock's moves of s: its
 * lights' threshold at the fastest a light moves, or the field's at its
 * wind, whichever is sooner; 0 while the clock moves neither. */
double drive_move_interval_s(const struct sky_state *s);

/* A move of the clock's lights: next is the served state with the lights
 * where the clock has them now, lights their directions (state_lights_of),
 * dirty the tables that invalidates (state_set's mask). */
typedef void drive_move_fn(void *ctx, const struct sky_state *next,
			   const struct state_lights *lights, uint32_t dirty);

/* served: the state the clock moves, and lights its directions, both
 * read at every tick and at drive_changed; move hears of each move. The
 * loop and what served and lights point to must outlive the drive. The
 * served lights are the reference at once. */
int drive_new(struct loop *l, const struct sky_state *served, const struct state_lights *lights,
	      drive_move_fn *move, void *ctx, struct drive **ret);
void drive_free(struct drive *d);

/* The served state was changed by a request: the lights it holds are the
 * new reference and the timer is re-armed for its clock. */
void drive_changed(struct drive *d);

struct drive_stats {
	uint64_t ticks;			/* timer expirations */
	uint64_t changes;		/* changes submitted to srv */
	double next_tick_s;		/* real seconds to the next tick; -1 none armed */
};
void drive_stats(const struct drive *d, struct drive_stats *ret);

#endif

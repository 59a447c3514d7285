/* state_compare.h - the first field in which two sky states differ, bit
 * for bit: what replication must carry exactly (test_sync_msg's round
 * trips, test_sync_broker's followers). Needs skycore (state.h). */
#ifndef SKYD_STATE_COMPARE_H
#define SKYD_STATE_COMPARE_H

#include <string.h>

#include "state.h"

#define STATE_COMPARE_SAME(f)                                      \
	do {                                                       \
		if (memcmp(&a->f, &b->f, sizeof(a->f)) != 0)        \
			return #f;                                 \
	} while (0)

/* The constituents and the planet, field by field. */
static inline const char *state_compare_atmo(const struct atmo *a, const struct atmo *b)
{
	STATE_COMPARE_SAME(bottom_radius_km);
	STATE_COMPARE_SAME(top_radius_km);
	STATE_COMPARE_SAME(ground_albedo);
	STATE_COMPARE_SAME(n_constituents);
	for (int i = 0; i < a->n_constituents; i++) {
		STATE_COMPARE_SAME(c[i].name);
		STATE_COMPARE_SAME(c[i].scattering_per_km);
		STATE_COMPARE_SAME(c[i].absorption_per_km);
		STATE_COMPARE_SAME(c[i].phase);
		STATE_COMPARE_SAME(c[i].g);
		STATE_COMPARE_SAME(c[i].density);
	}
	return NULL;
}

/* The first field in which a and b differ, NULL when none does. Left out:
 * the clock's anchors, the lights' and the cloud field's times and the
 * field's offset (instants on each machine's own clocks, and what follows
 * from them), the views (they stay local) and the sensor's EV100 (not
 * replicated). */
static inline const char *state_compare(const struct sky_state *a, const struct sky_state *b)
{
	const char *d = state_compare_atmo(&a->atmo, &b->atmo);
	if (d)
		return d;
	if (strcmp(a->preset, b->preset))
		return "preset";
	STATE_COMPARE_SAME(altitude_km);
	STATE_COMPARE_SAME(sun);
	STATE_COMPARE_SAME(moon);
	STATE_COMPARE_SAME(camera);
	STATE_COMPARE_SAME(quality);
	STATE_COMPARE_SAME(clock.rate);
	STATE_COMPARE_SAME(clock.lat_deg);
	STATE_COMPARE_SAME(clock.lon_deg);
	STATE_COMPARE_SAME(clock.site_elevation_m);
	STATE_COMPARE_SAME(clock.pressure_mbar);
	STATE_COMPARE_SAME(clock.temperature_c);
	STATE_COMPARE_SAME(clock.delta_t_s);
	STATE_COMPARE_SAME(clock.horizon_refraction_deg);
	STATE_COMPARE_SAME(clock.threshold_deg);
	STATE_COMPARE_SAME(clock.cadence_s);
	STATE_COMPARE_SAME(clock.sun_mode);
	STATE_COMPARE_SAME(clock.moon_mode);
	STATE_COMPARE_SAME(night);
	STATE_COMPARE_SAME(weather);
	STATE_COMPARE_SAME(clouds.layer);
	STATE_COMPARE_SAME(clouds.seed);
	STATE_COMPARE_SAME(clouds.wind_dir_deg);
	STATE_COMPARE_SAME(clouds.wind_speed_mps);
	STATE_COMPARE_SAME(clouds.extent_km);
	STATE_COMPARE_SAME(sensor);
	return NULL;
}

#undef STATE_COMPARE_SAME

#endif

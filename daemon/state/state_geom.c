/* state_geom.c - the geometry of a state: light directions, camera frames
 * and the observer's site. */
#include "state_geom.h"

#include <math.h>

#include "astro.h"
#include "state.h"

void state_direction(double elevation_deg, double azimuth_deg, double ret[3])
{
	double el = elevation_deg * M_PI / 180.0, az = azimuth_deg * M_PI / 180.0;
	ret[0] = cos(el) * sin(az);
	ret[1] = cos(el) * cos(az);
	ret[2] = sin(el);
}

void state_lights_of(const struct sky_state *s, struct state_lights *ret)
{
	state_direction(s->sun.elevation_deg, s->sun.azimuth_deg, ret->sun);
	state_direction(s->moon.elevation_deg, s->moon.azimuth_deg, ret->moon);
}

void state_camera_basis(const struct state_camera *c, double fwd[3], double right[3], double up[3])
{
	double yaw = c->yaw_deg * M_PI / 180.0, roll = c->roll_deg * M_PI / 180.0;
	double f[3], r0[3] = { cos(yaw), -sin(yaw), 0.0 };	/* level, to the right */

	state_direction(c->pitch_deg, c->yaw_deg, f);
	double u0[3] = { r0[1] * f[2] - r0[2] * f[1], r0[2] * f[0] - r0[0] * f[2],
			 r0[0] * f[1] - r0[1] * f[0] };		/* r0 x f: up */
	for (int i = 0; i < 3; i++) {
		fwd[i] = f[i];
		right[i] = cos(roll) * r0[i] + sin(roll) * u0[i];
		up[i] = -sin(roll) * r0[i] + cos(roll) * u0[i];
	}
}

void state_astro_site(const struct sky_state *s, struct astro_site *ret_site,
		      struct astro_options *ret_opt)
{
	const struct state_clock *c = &s->clock;

	*ret_site = (struct astro_site){ .lat_deg = c->lat_deg, .lon_deg = c->lon_deg,
		.elevation_m = c->site_elevation_m };
	astro_options_default(ret_opt);
	ret_opt->delta_t_auto = isnan(c->delta_t_s);
	ret_opt->delta_t_s = isnan(c->delta_t_s) ? 0.0 : c->delta_t_s;
	ret_opt->pressure_mbar = c->pressure_mbar;
	ret_opt->temperature_c = c->temperature_c;
	ret_opt->horizon_refraction_deg = c->horizon_refraction_deg;
}

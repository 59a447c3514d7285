/* state_geom.h - where things are in a state: the lights' directions, a
 * camera's frame and the observer's site as astro takes it, in the
 * observer's east-north-up frame (x east, y north, z up). */
#ifndef SKYD_STATE_GEOM_H
#define SKYD_STATE_GEOM_H

struct astro_options;
struct astro_site;
struct sky_state;
struct state_camera;

/* The sun's and the moon's unit vectors in east-north-up, from their
 * elevations and azimuths. A resolved state's lights are computed once
 * (state_lights_of) and handed on: to the engine's uniform block, the
 * aerial plan's cameras and the published slot, which must all see the
 * same vectors. */
struct state_lights {
	double sun[3];
	double moon[3];
};

void state_lights_of(const struct sky_state *s, struct state_lights *ret);

/* Unit vector in east-north-up from elevation and azimuth (from north, eastward). */
void state_direction(double elevation_deg, double azimuth_deg, double ret[3]);

/* The camera's unit basis in the observer's east-north-up frame from yaw
 * (azimuth), pitch (elevation) and roll. */
void state_camera_basis(const struct state_camera *c, double fwd[3], double right[3],
			double up[3]);

/* The astro inputs of s: its site (latitude, longitude, elevation) and
 * options (delta T, the refraction of the reported directions). */
void state_astro_site(const struct sky_state *s, struct astro_site *ret_site,
		      struct astro_options *ret_opt);

#endif

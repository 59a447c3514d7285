/* sky_cloud.c - libsky's CPU drawing of the clouds from a view: the march
 * of proto/skycloudmarch.h lit by the view's tables and lights, and its
 * compositing with the sky and the aerial perspective. Touches no client
 * state: thread-safe on a stable view. */
#include <errno.h>
#include <math.h>
#include <stddef.h>

#include "sky.h"
#include "skycloudmarch.h"

#define DEG (SKYMAP_PI / 180.0)
#define LIGHT_STEPS 8

static int cloud_table(const struct sky_view *v, uint32_t id, struct skysample_table *ret)
{
	if (!(v->valid_tables & SKY_TABLE_BIT(id)))
		return -ENODATA;
	return skysample_table_from_slot(v->header, v->slot_base, id, ret) < 0 ? -ENODATA : 0;
}

static int check_args(const struct sky_view *v, const struct sky_cloud_params *p, double elevation_deg,
		      double azimuth_deg, double distance_km, unsigned flags)
{
	const unsigned known = SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK | SKY_SAMPLE_LIMB_DARKENING |
			       SKY_SAMPLE_CLOUD_COMPOSITE;
	if (!v || !v->header || !v->slot_base || !p || !p->scene || (flags & ~known))
		return -EINVAL;
	if (!isfinite(elevation_deg) || !isfinite(azimuth_deg) || !(distance_km > 0.0))
		return -EINVAL;
	const struct skycloud_scene *sc = p->scene;
	if (sc->n_layers < 0 || sc->n_layers > SKYCLOUD_MAX_LAYERS || (sc->n_layers && !sc->layers) ||
	    sc->octaves < 1 || sc->octaves > SKYCLOUD_MARCH_MAX_OCTAVES || (sc->coverage && !(sc->extent_km > 0.0)))
		return -EINVAL;
	if (p->steps < 0 || p->light_steps < 0 || !(p->jitter >= 0.0 && p->jitter < 1.0) ||
	    (p->sun_shadow && !p->sun_frame))
		return -EINVAL;
	return 0;
}

/* Marches the clouds along d for the sun, and the moon where it lights. */
static void march_lights(const struct sky_view *v, const struct sky_cloud_params *p,
			 const struct skycloud_sky *sky, const double d[3], double distance_km,
			 struct skycloud_sample *ret)
{
	const struct sky_shm_state *st = &v->slot->state;
	const double o[3] = { 0.0, 0.0, st->altitude_km };
	const double far_km = isfinite(distance_km) ? distance_km : 1e30;
	int steps = p->steps ? p->steps : SKYCLOUD_MARCH_STEPS_MEDIUM;
	int light_steps = p->light_steps ? p->light_steps : LIGHT_STEPS;
	struct skycloud_light li = { .shadow = p->sun_shadow };
	if (p->sun_shadow)
		li.frame = *p->sun_frame;
	for (int k = 0; k < 3; k++) {
		li.dir[k] = st->sun_direction[k];
		li.illuminance_lx[k] = st->sun_illuminance_lx[k];
	}
	skycloud_march(p->scene, &li, sky, o, d, far_km, steps, p->sun_shadow ? 0 : light_steps, p->jitter, ret);
	if (!(st->moon_illuminance_lx[0] + st->moon_illuminance_lx[1] + st->moon_illuminance_lx[2] > 0.0))
		return;
	struct skycloud_light moon = { .shadow = NULL };
	struct skycloud_sample m;
	for (int k = 0; k < 3; k++) {
		moon.dir[k] = st->moon_direction[k];
		moon.illuminance_lx[k] = st->moon_illuminance_lx[k];
	}
	skycloud_march(p->scene, &moon, sky, o, d, far_km, steps, light_steps, p->jitter, &m);
	for (int k = 0; k < 3; k++)
		ret->radiance[k] += m.radiance[k];
}

int sky_sample_clouds(const struct sky_view *v, const struct sky_cloud_params *p, double elevation_deg,
		      double azimuth_deg, double distance_km, unsigned flags, double ret_rgb[3],
		      double *ret_transmittance, double *ret_depth_km)
{
	struct skysample_table trans, ms;
	struct skycloud_sample c;
	double d[3];
	int r = check_args(v, p, elevation_deg, azimuth_deg, distance_km, flags);
	if (r < 0 || !ret_rgb)
		return r < 0 ? r : -EINVAL;
	if ((r = cloud_table(v, SKY_TABLE_TRANSMITTANCE, &trans)) < 0 ||
	    (r = cloud_table(v, SKY_TABLE_MULTISCATTER, &ms)) < 0)
		return r;
	const struct skycloud_sky sky = { &trans, &ms, v->slot->state.bottom_radius_km,
					  v->slot->state.top_radius_km };
	skysample_direction(elevation_deg * DEG, azimuth_deg * DEG, d);
	march_lights(v, p, &sky, d, distance_km, &c);
	double rgb[3] = { c.radiance[0], c.radiance[1], c.radiance[2] };
	if (flags & SKY_SAMPLE_CLOUD_COMPOSITE) {
		double behind[3] = { 0.0, 0.0, 0.0 }, air[3], air_t;
		if (!isfinite(distance_km) &&
		    (r = sky_sample_sky(v, elevation_deg, azimuth_deg, flags & ~(unsigned)SKY_SAMPLE_CLOUD_COMPOSITE,
					behind)) < 0)
			return r;
		if ((r = sky_sample_view_aerial_dir(v, NULL, d, isfinite(c.depth_km) ? c.depth_km : 1e9, air,
						    &air_t)) < 0)
			return r;
		skycloud_composite(behind, &c, air, air_t, rgb);
	}
	for (int k = 0; k < 3; k++)
		ret_rgb[k] = rgb[k];
	if (ret_transmittance)
		*ret_transmittance = c.transmittance;
	if (ret_depth_km)
		*ret_depth_km = c.depth_km;
	return 0;
}

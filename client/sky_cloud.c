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
	if (!v || !v->header || !v->slot_base || !v->slot || (flags & ~known))
		return -EINVAL;
	if (!isfinite(elevation_deg) || !isfinite(azimuth_deg) || !(distance_km > 0.0))
		return -EINVAL;
	if (p->steps < 0 || p->light_steps < 0 || !(p->jitter >= 0.0 && p->jitter < 1.0))
		return -EINVAL;
	return 0;
}

/* Light k's (0 the sun, 1 the moon) published shadow map as a 2-D table,
 * its slice of the shadow table; -ENODATA where the slot has none. */
static int light_map(const struct sky_view *v, int k, struct skysample_table *ret)
{
	if (!(v->slot->clouds.shadow_lights & (1u << k)) || cloud_table(v, SKY_TABLE_SHADOW, ret) < 0 ||
	    ret->depth < 2 || ret->format != SKY_FORMAT_RGBA32F)
		return -ENODATA;
	ret->texels = (const float *)ret->texels + (size_t)k * ret->width * ret->height * 4;
	ret->depth = 1;
	return 0;
}

/* Light k of the state, with its map where it has one and light_steps is
 * 0; returns the light steps to march it with. */
static int light_of(const struct sky_view *v, const struct sky_cloud_params *p, int k,
		    struct skysample_table *map, struct skycloud_light *ret)
{
	const struct sky_shm_state *st = &v->slot->state;
	*ret = (struct skycloud_light){ .shadow = NULL };
	for (int c = 0; c < 3; c++) {
		ret->dir[c] = k ? st->moon_direction[c] : st->sun_direction[c];
		ret->illuminance_lx[c] = k ? st->moon_illuminance_lx[c] : st->sun_illuminance_lx[c];
	}
	if (p->light_steps > 0)
		return p->light_steps;
	if (light_map(v, k, map) < 0)
		return LIGHT_STEPS;
	ret->shadow = map;
	skycloud_shadow_frame_from_slot(&v->slot->clouds, k, &ret->frame);
	return 0;
}

/* Marches the clouds along d for the sun, and the moon where it lights. */
static void march_lights(const struct sky_view *v, const struct sky_cloud_params *p,
			 const struct skycloud_scene *sc, const struct skycloud_sky *sky, const double d[3],
			 double distance_km, struct skycloud_sample *ret)
{
	const struct sky_shm_state *st = &v->slot->state;
	const double o[3] = { 0.0, 0.0, st->altitude_km };
	const double far_km = isfinite(distance_km) ? distance_km : 1e30;
	int steps = p->steps ? p->steps : SKYCLOUD_MARCH_STEPS_MEDIUM;
	struct skysample_table map;
	struct skycloud_light li;
	int light_steps = light_of(v, p, 0, &map, &li);
	skycloud_march(sc, &li, sky, o, d, far_km, steps, light_steps, p->jitter, ret);
	if (!(st->moon_illuminance_lx[0] + st->moon_illuminance_lx[1] + st->moon_illuminance_lx[2] > 0.0))
		return;
	struct skycloud_sample m;
	light_steps = light_of(v, p, 1, &map, &li);
	skycloud_march(sc, &li, sky, o, d, far_km, steps, light_steps, p->jitter, &m);
	for (int k = 0; k < 3; k++)
		ret->radiance[k] += m.radiance[k];
}

int sky_sample_clouds(const struct sky_view *v, const struct sky_cloud_params *p, double elevation_deg,
		      double azimuth_deg, double distance_km, unsigned flags, double ret_rgb[3],
		      double *ret_transmittance, double *ret_depth_km)
{
	static const struct sky_cloud_params defaults = { .jitter = 0.5 };
	struct skysample_table trans, ms, cov;
	struct skycloud_layer layers[SKYCLOUD_MAX_LAYERS];
	struct skycloud_scene sc;
	struct skycloud_sample c;
	double d[3];
	if (!p)
		p = &defaults;
	int r = check_args(v, p, elevation_deg, azimuth_deg, distance_km, flags);
	if (r < 0 || !ret_rgb)
		return r < 0 ? r : -EINVAL;
	if ((r = cloud_table(v, SKY_TABLE_TRANSMITTANCE, &trans)) < 0 ||
	    (r = cloud_table(v, SKY_TABLE_MULTISCATTER, &ms)) < 0)
		return r;
	const struct skycloud_sky sky = { &trans, &ms, v->slot->state.bottom_radius_km,
					  v->slot->state.top_radius_km };
	skycloud_scene_from_slot(&v->slot->clouds, layers, &sc);
	if (sc.n_layers > 0 && sc.extent_km > 0.0 && cloud_table(v, SKY_TABLE_CLOUD, &cov) == 0)
		sc.coverage = &cov;
	skysample_direction(elevation_deg * DEG, azimuth_deg * DEG, d);
	for (int k = 0; k < 3; k++)
		sc.ambient_lx[k] = p->ambient_lx[k];
	march_lights(v, p, &sc, &sky, d, distance_km, &c);
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

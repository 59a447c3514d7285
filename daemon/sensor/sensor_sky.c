/* sensor_sky.c - light levels for the sensor modes: horizontal illuminance
 * from the published tables, the inversion of a clear-sky illuminance curve,
 * the exposure value of an illuminance. Pure. */
#include "sensor.h"

#include <errno.h>
#include <math.h>

double sensor_sky_luminance(const double rgb[3])
{
	return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* A light's illuminance on a horizontal surface: top-of-atmosphere
 * illuminance times the transmittance toward it (0 below the horizon)
 * times the cosine of its zenith angle. */
static double direct_lx(const struct skysample_table *trans, const struct sky_shm_state *st,
			const double dir[3], const double illuminance_lx[3])
{
	double tr[3], rgb[3];

	if (!(dir[2] > 0.0))
		return 0.0;
	skysample_light_transmittance(trans, st, dir, tr);
	for (int c = 0; c < 3; c++)
		rgb[c] = illuminance_lx[c] * tr[c] * dir[2];
	return sensor_sky_luminance(rgb);
}

void sensor_sky_horizontal(const struct skysample_table *transmittance,
			   const struct skysample_table *skyview, const struct sky_shm_state *st,
			   struct sensor_sky_lux *ret)
{
	double sky[3];

	ret->sun_lx = direct_lx(transmittance, st, st->sun_direction, st->sun_illuminance_lx);
	ret->moon_lx = direct_lx(transmittance, st, st->moon_direction, st->moon_illuminance_lx);
	skysample_ambient(skyview, st, sky);
	ret->sky_lx = sensor_sky_luminance(sky);
	ret->total_lx = ret->sun_lx + ret->moon_lx + ret->sky_lx;
}

static const double usno_elevation_deg[] = { -12.0, -6.0, -0.8, 0.0, 10.0, 30.0, 60.0, 90.0 };
static const double usno_lux[] = { 0.008, 3.4, 464.0, 759.0, 11100.0, 46000.0, 103000.0, 128800.0 };

const struct sensor_curve sensor_curve_usno = {
	usno_elevation_deg,
	usno_lux,
	sizeof(usno_lux) / sizeof(usno_lux[0]),
};

int sensor_curve_invert(const struct sensor_curve *c, double lux, double *ret_elevation_deg,
			double *ret_deg_per_ln)
{
	if (isnan(lux))
		return -EINVAL;
	if (c->n < 2)
		return -EDOM;
	for (size_t i = 0; i < c->n; i++) {
		if (!(c->lux[i] > 0.0) || !isfinite(c->lux[i]) || !isfinite(c->elevation_deg[i]))
			return -EDOM;
		if (i && !(c->lux[i] > c->lux[i - 1] && c->elevation_deg[i] > c->elevation_deg[i - 1]))
			return -EDOM;
	}
	if (!(lux >= c->lux[0] && lux <= c->lux[c->n - 1]))
		return -ERANGE;
	size_t i = 1;
	while (i < c->n - 1 && lux > c->lux[i])
		i++;
	/* Linear in ln(E) between samples: through twilight the light falls
	 * by about a decade per two degrees, so ln(E) is close to linear in
	 * elevation where E itself is not. */
	double l0 = log(c->lux[i - 1]), l1 = log(c->lux[i]);
	double e0 = c->elevation_deg[i - 1], e1 = c->elevation_deg[i];
	double slope = (e1 - e0) / (l1 - l0);
	*ret_elevation_deg = e0 + (log(lux) - l0) * slope;
	if (ret_deg_per_ln)
		*ret_deg_per_ln = slope;
	return 0;
}

double sensor_ev100(double lux)
{
	return log2(lux * 100.0 / SENSOR_EV_INCIDENT_C);
}

/* model_sky.c - the reference model's view marches: the sky-view and
 * aerial-perspective tables. */
#include "model_internal.h"

/* A light's height over the local horizon (mu_l - mu_horizon) at distance t
 * along a view ray from the observer. */
static double light_over_horizon(const struct ctx *c, v3 dir, double t, v3 light)
{
	double rr, h = altitude_along(c, c->h0, dir.z, t, &rr);
	v3 up = v(dir.x * t / rr, dir.y * t / rr, (c->rb + c->h0 + dir.z * t) / rr);
	return dot(up, light) - skymap_horizon_cos(c->rb, h);
}

static bool ray_in_shell(const struct ctx *c, double h0, v3 dir, double *t0, double *t1)
{
	double r = c->rb + h0, mu = dir.z, tg;
	*t0 = 0;
	*t1 = 0;
	if (h0 > c->shell) {
		double cc = (h0 - c->shell) * (2.0 * c->rb + h0 + c->shell);
		double disc = r * r * mu * mu - cc;
		if (mu >= 0.0 || disc <= 0.0)
			return false;
		*t0 = -r * mu - sqrt(disc);
		*t1 = -r * mu + sqrt(disc);
		double ra, he = altitude_along(c, h0, mu, *t0, &ra);
		double mue = (r * mu + *t0) / ra;
		if (hits_ground(c, he, mue, &tg))
			*t1 = *t0 + tg;
	} else {
		double hh = h0 > 0 ? h0 : 0;
		*t1 = distance_to_top(c, hh, mu);
		if (hits_ground(c, hh, mu, &tg))
			*t1 = tg;
	}
	return *t1 > *t0;
}

/* In-scattered radiance and optical depth along [a, b] of a view ray.
 * segment_lit averages the visible part of each light's disk over each step
 * (the sky-view pass); otherwise it is taken at the step's midpoint. */
static void march(const struct ctx *c, v3 dir, double a, double b, uint32_t n, bool quadratic,
		  bool segment_lit, v3 *radiance, v3 *tau, v3 *tau_scaled)
{
	double r0 = c->rb + c->h0, len = b - a, prev = 0;
	double sun_x = segment_lit ? light_over_horizon(c, dir, a, c->sun) : 0;
	double moon_x = segment_lit && c->moon_lit ? light_over_horizon(c, dir, a, c->moon) : 0;
	for (uint32_t i = 0; i < n; i++) {
		double x = (double)(i + 1) / n, next = quadratic ? len * x * x : len * x;
		double dt = next - prev, t = a + 0.5 * (prev + next), rr;
		prev = next;
		double hs = altitude_along(c, c->h0, dir.z, t, &rr);
		v3 up = v(dir.x * t / rr, dir.y * t / rr, (r0 + dir.z * t) / rr);
		struct medium m = model_medium(c, hs);
		double vis_sun = -1, vis_moon = -1;
		if (segment_lit) {
			double xb = light_over_horizon(c, dir, a + next, c->sun);
			vis_sun = model_disk_visible_mean(sun_x, xb, model_disk_halfwidth(c, hs, c->s->sun.angular_radius_deg *
										   SKYMAP_PI / 180.0));
			sun_x = xb;
			if (c->moon_lit) {
				xb = light_over_horizon(c, dir, a + next, c->moon);
				vis_moon = model_disk_visible_mean(moon_x, xb,
							     model_disk_halfwidth(c, hs, c->s->moon.angular_radius_deg *
										   SKYMAP_PI / 180.0));
				moon_x = xb;
			}
		}
		if (c->delta >= 0) {
			model_delta_step(c, hs, up, dir, dt, vis_sun, vis_moon, m, radiance, tau, tau_scaled);
			continue;
		}
		v3 ground = model_ground_scattering(c, hs, dot(up, dir));
		v3 s = model_light_source(c, hs, up, dir, c->sun, c->s->sun.angular_radius_deg, vis_sun, c->sun_illum,
				    m.scattering, ground);
		if (c->moon_lit)
			s = add(s, model_light_source(c, hs, up, dir, c->moon, c->s->moon.angular_radius_deg, vis_moon,
						c->moon_illum, m.scattering, ground));
		*radiance = add(*radiance, mul(mul(vexp_neg(*tau), s), segment_weight(m.extinction, dt)));
		*tau = add(*tau, scale(m.extinction, dt));
	}
}

/* The night-sky floor of a sky-view direction (docs/physics.md): the measured
 * floor over the sky, L_z (1 + c (1 - mu)); toward the ground only the
 * airlight of the ray, the horizon's floor times (1 - T). */
static v3 night_sky(const struct ctx *c, double mu, bool sky, v3 tr)
{
	double l = c->night_cd_m2 * (1 + c->night_gain * (1 - fmax(mu, 0)));
	return sky ? v(l, l, l) : scale(v(1 - tr.x, 1 - tr.y, 1 - tr.z), l);
}

/* The direction of a sky-view texel as skyview.comp computes it: the
 * mapping of skymap_skyview_inverse, evaluated from the horizon's angle
 * from the nadir and, for rays that point down, the ray's own; ret_sky
 * says whether the row is above the horizon. */
static v3 skyview_direction(const struct ctx *c, double u, double vv, uint32_t h, bool *ret_sky)
{
	double beta = atan2(c->rb, sqrt(rho2(c, c->h0))), th = SKYMAP_PI - beta;
	double x = skymap_clamp(skymap_tex_to_unit(vv, h), 0.0, 1.0), sin_z, cos_z;
	*ret_sky = x < 0.5;
	if (*ret_sky) {
		double a = 1.0 - 2.0 * x, zenith = th * (1.0 - a * a);
		if (zenith <= 0.5 * SKYMAP_PI) {
			sin_z = sin(zenith);
			cos_z = cos(zenith);
		} else {
			double nadir = beta + th * a * a;
			sin_z = sin(nadir);
			cos_z = -cos(nadir);
		}
	} else {
		double a = 2.0 * x - 1.0, nadir = beta * (1.0 - a * a);
		sin_z = sin(nadir);
		cos_z = -cos(nadir);
	}
	double az = 2.0 * SKYMAP_PI * u;
	return v(sin_z * sin(az), sin_z * cos(az), cos_z);
}

void model_compute_skyview(const struct ctx *c, const struct state_table_quality *q, double *out)
{
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double t0, t1;
			bool sky;
			v3 dir = skyview_direction(c, (i + 0.5) / q->width, (j + 0.5) / q->height, q->height, &sky);
			v3 rad = { 0 }, tau = { 0 }, tau_s = { 0 };
			if (ray_in_shell(c, c->h0, dir, &t0, &t1)) {
				double len = t1 - t0, lo = c->s->quality.skyview_min_steps;
				double nf = ceil(lo + (q->steps - lo) * skymap_clamp(len / 100.0, 0, 1));
				march(c, dir, t0, t1, nf < 1 ? 1 : (uint32_t)nf, true, true, &rad, &tau, &tau_s);
			}
			rad = add(rad, night_sky(c, dir.z, sky, vexp_neg(tau)));
			put(out + 4 * (j * q->width + i), rad, mean3(vexp_neg(tau)));
		}
}

void model_compute_aerial(const struct ctx *c, const struct state_table_quality *q, double *out)
{
	double fwd[3], right[3], up[3];
	double tan_half = tan(c->s->camera.vfov_deg * SKYMAP_PI / 360.0), aspect = c->s->camera.aspect;
	bool squared = c->s->quality.aerial_spacing == STATE_SQUARED;

	state_camera_basis(&c->s->camera, fwd, right, up);
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double nx = (i + 0.5) / q->width * 2 - 1, ny = (j + 0.5) / q->height * 2 - 1;
			v3 d = v(fwd[0] + nx * tan_half * aspect * right[0] + ny * tan_half * up[0],
				 fwd[1] + nx * tan_half * aspect * right[1] + ny * tan_half * up[1],
				 fwd[2] + nx * tan_half * aspect * right[2] + ny * tan_half * up[2]);
			v3 dir = scale(d, 1.0 / sqrt(dot(d, d)));
			double t0, t1, prev = 0;
			bool inside = ray_in_shell(c, c->h0, dir, &t0, &t1);
			v3 rad = { 0 }, tau = { 0 }, tau_s = { 0 };
			for (uint32_t k = 0; k < q->depth; k++) {
				double depth = skymap_aerial_depth_km(k, q->depth, c->s->quality.aerial_range_km, squared);
				double a = fmax(prev, t0), b = inside ? fmin(depth, t1) : a;
				prev = depth;
				if (b > a)
					march(c, dir, a, b, q->steps, false, false, &rad, &tau, &tau_s);
				v3 tr = vexp_neg(tau);
				v3 night = scale(v(1 - tr.x, 1 - tr.y, 1 - tr.z), c->night_cd_m2 * (1 + c->night_gain / 3));
				put(out + 4 * ((k * q->height + j) * q->width + i), add(rad, night), mean3(tr));
			}
		}
}


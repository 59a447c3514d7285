/* model_delta.c - the reference model's delta-M for the higher orders
 * (delta_source in common.glsl). */
#include "model_internal.h"

#include <errno.h>
#include <stdlib.h>

/* The peak's optical depth toward mu from altitude h, f sigma_D L_D (T_l' /
 * T_l is exp of it), L_D read bilinearly from the column table at the
 * transmittance lookup's taps. */
static v3 delta_depth(const struct ctx *c, double h, double mu)
{
	const struct atmo_constituent *k = &c->s->atmo.c[c->delta];	/* the real sigma_D */
	struct taps t = model_transmittance_taps(c, h, mu);
	return scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
		     c->delta_f * taps_channel(c->delta_col, &t, 0));
}

/* The scaled medium's light_transmittance: the visible part of the disk
 * times exp(-tau'), tau' read bilinearly from the scaled optical depths at
 * the transmittance texels (columns_at in common.glsl). */
v3 model_delta_light_transmittance(const struct ctx *c, double h, double mu, double radius_rad)
{
	double vis = model_light_visible(c, h, mu, radius_rad);
	if (vis <= 0)
		return v(0, 0, 0);
	struct taps t = model_transmittance_taps(c, h, mu);
	return scale(vexp_neg(v(taps_channel(c->delta_col, &t, 1), taps_channel(c->delta_col, &t, 2),
				taps_channel(c->delta_col, &t, 3))), vis);
}

/* The delta constituent's scattering at h and f times it. */
static v3 delta_sigma(const struct ctx *c, double h)
{
	const struct atmo_constituent *k = &c->a->c[c->delta];
	return scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
		     atmo_density(&k->density, h));
}

/* delta_source: the part weighed by the real view transmittance in
 * ret_real, by the scaled one in ret_scaled. */
static void delta_light_source(const struct ctx *c, double h, v3 up, v3 dir, v3 light, double radius_deg,
			       double visible, v3 illum, v3 sigma_s, v3 ground, double tau_view, v3 *ret_real,
			       v3 *ret_scaled)
{
	double mu_l = dot(up, light), mu = dot(dir, light);
	const struct atmo_constituent *k = &c->a->c[c->delta];
	v3 t = model_step_light(c, h, mu_l, radius_deg, visible);
	v3 ph = model_phased_scattering(c, h, mu);
	v3 depth = delta_depth(c, h, mu_l);
	double tau = tau_view + (depth.x + depth.y + depth.z) / 3.0;
	v3 ph_s = add(ph, scale(delta_sigma(c, h), phase_delta_peak_phase(k->phase, k->g, c->delta_h, c->delta_spread,
									     tau, mu_l, mu) -
						     phase_value(k->phase, k->g, mu)));
	*ret_real = mul(mul(add(ph, scale(ph_s, -1.0)), t), illum);
	v3 gain = v(exp(fmin(depth.x, 80.0)), exp(fmin(depth.y, 80.0)), exp(fmin(depth.z, 80.0)));	/* T_l' / T_l */
	v3 s = mul(mul(ph_s, t), gain);
	/* The shape through the truncated phase (lobe_g: g', g'^2) of the
	 * scaled constituent. */
	s = add(s, model_higher_orders(c, h, up, dir, light, sigma_s, ground, scale(delta_sigma(c, h), 1.0 - c->delta_f)));
	*ret_scaled = mul(s, illum);
}

/* One step of model_sky.c's march() with delta-M: the scaled medium's
 * scattering, ground term and view optical depth (tau_scaled) beside the
 * real ones. */
void model_delta_step(const struct ctx *c, double hs, v3 up, v3 dir, double dt, double vis_sun,
		      double vis_moon, struct medium m, v3 *radiance, v3 *tau, v3 *tau_scaled)
{
	v3 removed = scale(delta_sigma(c, hs), c->delta_f), r, rs, r2, rs2;
	v3 ext_s = add(m.extinction, scale(removed, -1.0)), sig_s = add(m.scattering, scale(removed, -1.0));
	/* ground_scattering with the scaled constituent: ground_fit holds the
	 * truncated phase's for it (delta_init). */
	double ex = phase_ground_fit_at(c->ground_fit[c->delta], dot(up, dir));
	v3 ground = add(model_ground_scattering(c, hs, dot(up, dir)), scale(removed, -ex));
	/* The peak's optical depth from the eye to the middle of the step. */
	v3 peak = add(add(*tau, scale(*tau_scaled, -1.0)), scale(removed, 0.5 * dt));
	double tau_view = (peak.x + peak.y + peak.z) / 3.0;
	delta_light_source(c, hs, up, dir, c->sun, c->s->sun.angular_radius_deg, vis_sun, c->sun_illum, sig_s,
			   ground, tau_view, &r, &rs);
	if (c->moon_lit) {
		delta_light_source(c, hs, up, dir, c->moon, c->s->moon.angular_radius_deg, vis_moon, c->moon_illum,
				   sig_s, ground, tau_view, &r2, &rs2);
		r = add(r, r2);
		rs = add(rs, rs2);
	}
	*radiance = add(*radiance, add(mul(mul(vexp_neg(*tau), r), segment_weight(m.extinction, dt)),
				       mul(mul(vexp_neg(*tau_scaled), rs), segment_weight(ext_s, dt))));
	*tau = add(*tau, scale(m.extinction, dt));
	*tau_scaled = add(*tau_scaled, scale(ext_s, dt));
}

/* Sets up c's delta-M (phase_delta_constituent): f, g', the scaled
 * atmosphere, the truncated phase's ground fit and the column table at the
 * transmittance texels of s. Returns 0 or -ENOMEM. */
int model_delta_init(struct ctx *c, const struct sky_state *s, const struct model_tables *m)
{
	c->delta = s->quality.multiscatter_dirs && m->t[1] ? phase_delta_constituent(s, NULL) : -1;
	if (c->delta < 0)
		return 0;
	struct atmo_constituent *k = &c->scaled.c[c->delta];
	double excess[PHASE_GROUND_N];
	const struct state_table_quality *q = &s->quality.t[0];
	phase_delta_truncation(s->atmo.c[c->delta].phase, s->atmo.c[c->delta].g, &c->delta_f, &c->delta_g);
	phase_delta_peak(s->atmo.c[c->delta].phase, s->atmo.c[c->delta].g, &c->delta_h, &c->delta_spread);
	c->scaled = s->atmo;
	for (int ch = 0; ch < 3; ch++)
		k->scattering_per_km[ch] *= 1.0 - c->delta_f;
	k->phase = ATMO_PHASE_HENYEY_GREENSTEIN;
	k->g = c->delta_g;
	phase_ground_excess(ATMO_PHASE_HENYEY_GREENSTEIN, c->delta_g, excess);
	phase_ground_fit(excess, c->ground_fit[c->delta]);
	c->delta_col = calloc(4 * (size_t)q->width * q->height, sizeof(double));
	if (!c->delta_col)
		return -ENOMEM;
	struct ctx scaled = *c;	/* column R: L_D; GBA: the scaled optical depth */
	scaled.a = &c->scaled;
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double h, mu;
			skymap_transmittance_inverse(c->rb, c->rt, (i + 0.5) / q->width, (j + 0.5) / q->height,
						     q->width, q->height, &h, &mu);
			c->delta_col[4 * (j * q->width + i)] =
				model_column(c, &c->a->c[c->delta].density, h, mu, q->steps);
			v3 tau = model_depth_to_top(&scaled, h, mu, q->steps);
			c->delta_col[4 * (j * q->width + i) + 1] = tau.x;
			c->delta_col[4 * (j * q->width + i) + 2] = tau.y;
			c->delta_col[4 * (j * q->width + i) + 3] = tau.z;
		}
	return 0;
}


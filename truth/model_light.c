/* model_light.c - the reference model's light at a point of a march: the
 * tables' lookups, the light's disk over the horizon, the sources. */
#include "model_internal.h"

v3 model_phased_scattering(const struct ctx *c, double h, double mu)
{
	v3 s = { 0 };
	for (int i = 0; i < c->a->n_constituents; i++) {
		const struct atmo_constituent *k = &c->a->c[i];
		if (k->phase == ATMO_PHASE_NONE)
			continue;
		double w = atmo_density(&k->density, h) * phase_value(k->phase, k->g, mu);
		s = add(s, scale(v(k->scattering_per_km[0], k->scattering_per_km[1],
				   k->scattering_per_km[2]), w));
	}
	return s;
}

v3 model_transmittance_to_top(const struct ctx *c, double h, double mu)
{
	double t, u, vv;
	if (hits_ground(c, h, mu, &t))
		return v(0, 0, 0);
	const struct model_tables *m = c->tab;
	skymap_transmittance_uv(c->rb, c->rt, h, mu, m->w[0], m->h[0], &u, &vv);
	return bilinear(m->t[0], m->w[0], m->h[0], u, vv);
}

/* Visible part of a light's disk of half-width e (cosine units at the
 * horizon) whose centre stands x over the local horizon: see
 * light_transmittance in common.glsl. */
static double disk_visible(double x, double e)
{
	if (!(e > 0))
		return x < 0 ? 0 : 1;
	double k = (x + e) / (2.0 * e);
	k = k < 0 ? 0 : k > 1 ? 1 : k;
	return k * k * (3.0 - 2.0 * k);
}

/* Mean of disk_visible over a march step along which x goes linearly from
 * xa to xb: see disk_visible_mean in common.glsl, the same algorithm. */
double model_disk_visible_mean(double xa, double xb, double e)
{
	double lo = fmin(xa, xb), hi = fmax(xa, xb);
	if (lo >= e)
		return 1.0;
	if (hi <= -e)
		return 0.0;
	double inside = 1.0, above = 0.0;
	if (hi > lo) {
		inside = fmax(fmin(hi, e) - fmax(lo, -e), 0.0) / (hi - lo);
		above = fmax(hi - fmax(lo, e), 0.0) / (hi - lo);
	}
	if (!(e > 0))
		return above;
	double kl = 0.5 + 0.5 * skymap_clamp(lo / e, -1, 1), kh = 0.5 + 0.5 * skymap_clamp(hi / e, -1, 1);
	double g = kh * kh + kh * kl + kl * kl - 0.5 * (kh + kl) * (kh * kh + kl * kl);
	return inside * g + above;
}

/* Half-width of a light's disk in cosine units at the horizon of altitude h. */
double model_disk_halfwidth(const struct ctx *c, double h, double radius_rad)
{
	double hc = h < 0 ? 0 : h > c->shell ? c->shell : h;
	return c->rb / (c->rb + hc) * radius_rad;
}

/* Transmittance to the top times the visible part of the light's disk. */
static v3 visible_transmittance(const struct ctx *c, double h, double mu, double visible)
{
	if (visible <= 0)
		return v(0, 0, 0);
	double hc = h < 0 ? 0 : h > c->shell ? c->shell : h, u, vv;
	const struct model_tables *m = c->tab;
	skymap_transmittance_uv(c->rb, c->rt, hc, mu < -1 ? -1 : mu > 1 ? 1 : mu, m->w[0], m->h[0], &u, &vv);
	return scale(bilinear(m->t[0], m->w[0], m->h[0], u, vv), visible);
}

/* See light_visible in common.glsl: the light is a disk of angular radius
 * radius_rad that the horizon covers gradually. */
double model_light_visible(const struct ctx *c, double h, double mu, double radius_rad)
{
	double hc = h < 0 ? 0 : h > c->shell ? c->shell : h;
	double mu_h = h < 0 ? -2.0 : skymap_horizon_cos(c->rb, hc);
	return disk_visible(mu - mu_h, model_disk_halfwidth(c, h, radius_rad));
}

v3 model_light_transmittance(const struct ctx *c, double h, double mu, double radius_rad)
{
	return visible_transmittance(c, h, mu, model_light_visible(c, h, mu, radius_rad));
}

/* The light reaching a march step: visible is the part of the disk seen,
 * averaged over the step (disk_visible_mean), or negative to take it at the
 * point. */
v3 model_step_light(const struct ctx *c, double h, double mu_l, double radius_deg, double visible)
{
	return visible < 0 ? model_light_transmittance(c, h, mu_l, radius_deg * SKYMAP_PI / 180.0)
			   : visible_transmittance(c, h, mu_l, visible);
}

/* The bilinear taps of the transmittance texels toward mu from altitude h
 * (the column table shares them: columns_at in common.glsl). */
struct taps model_transmittance_taps(const struct ctx *c, double h, double mu)
{
	const struct model_tables *m = c->tab;
	double hc = h < 0 ? 0 : h > c->shell ? c->shell : h, u, vv;
	skymap_transmittance_uv(c->rb, c->rt, hc, mu < -1 ? -1 : mu > 1 ? 1 : mu, m->w[0], m->h[0], &u, &vv);
	return taps_at(m->w[0], m->h[0], u, vv);
}

/* The 4 numbers of the multiply scattered light's shape of row tab at u,
 * linear between texel centres. */
static void shape_row(const double *tab, uint32_t w, double u, double ret[4])
{
	double p = u * w - 0.5, f = p - floor(p);
	int i = (int)floor(p);
	int i0 = i < 0 ? 0 : i > (int)w - 1 ? (int)w - 1 : i;
	int i1 = i + 1 < 0 ? 0 : i + 1 > (int)w - 1 ? (int)w - 1 : i + 1;
	for (int k = 0; k < 4; k++)
		ret[k] = tab[4 * i0 + k] + (tab[4 * i1 + k] - tab[4 * i0 + k]) * f;
}

/* Each of the two rows at its own altitude's u, blended in altitude (see
 * multiscatter_at in common.glsl); the A channel (the ground's share) in
 * ret_share. */
v3 model_multiscatter(const struct ctx *c, double h, double mu_s, double *ret_share, double ret_shape[4])
{
	double u, vv;
	const struct model_tables *m = c->tab;
	uint32_t w = m->w[1], n = m->h[1];
	skymap_multiscatter_uv(c->rb, c->rt, h, mu_s, w, n, &u, &vv);
	double py = vv * n - 0.5, fy = py - floor(py);
	int iy = (int)floor(py);
	int y0 = iy < 0 ? 0 : iy > (int)n - 1 ? (int)n - 1 : iy;
	int y1 = iy + 1 < 0 ? 0 : iy + 1 > (int)n - 1 ? (int)n - 1 : iy + 1;
	v3 row[2];
	double mrow[2][4] = { { 0 }, { 0 } };
	double share[2];
	for (int k = 0; k < 2; k++) {
		int y = k ? y1 : y0;
		/* skymap_multiscatter_uv at the row's altitude, except that sqrt|s|
		 * turns linear for |s| < 1e-10 (a shift below 1e-5 texel): row 0's
		 * horizon is mu = 0 exactly, where sqrt would blow the last-bit
		 * difference of two mirrored views' mu up to 1e-8 and break the
		 * 1e-9 mirror check of the model (truth/stab.c). */
		double mh = skymap_horizon_cos(c->rb, (double)y / (n - 1) * c->shell);
		double d = skymap_clamp(mu_s, -1.0, 1.0) - mh;
		double sn = skymap_clamp(d < 0.0 ? d / (1.0 + mh) : d / (1.0 - mh), -1.0, 1.0);
		double a = fabs(sn) < 1e-10 ? sn * 1e5 : copysign(sqrt(fabs(sn)), sn);
		row[k] = bilinear(m->t[1] + 4 * (size_t)y * w, w, 1, skymap_unit_to_tex(0.5 + 0.5 * a, w), 0.5);
		share[k] = bilinear_a(m->t[1] + 4 * (size_t)y * w, w, 1, skymap_unit_to_tex(0.5 + 0.5 * a, w), 0.5);
		if (c->lobe >= 0)
			shape_row(c->moment + 4 * (size_t)y * w, w, skymap_unit_to_tex(0.5 + 0.5 * a, w), mrow[k]);
	}
	*ret_share = share[0] + (share[1] - share[0]) * fy;
	for (int i = 0; i < 4; i++)
		ret_shape[i] = mrow[0][i] + (mrow[1][i] - mrow[0][i]) * fy;
	return add(row[0], scale(add(row[1], scale(row[0], -1.0)), fy));
}

/* The ground's first bounce through the phases at altitude h for a view of
 * cos-zenith mu_view there: sum of sigma_i (k_i - 1), as ground_excess and
 * ground_scattering in common.glsl (the same fit, evaluated alike). */
v3 model_ground_scattering(const struct ctx *c, double h, double mu_view)
{
	v3 s = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *k = &c->a->c[n];
		double ex = phase_ground_fit_at(c->ground_fit[n], mu_view);
		s = add(s, scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
				 atmo_density(&k->density, h) * ex));
	}
	return s;
}

/* The higher orders at a march step for one light (ms_source in
 * common.glsl): psi_ms scattered by sigma_s, its ground share by sigma_s +
 * ground, and with a lobe constituent (scattering fwd, its phase's moments
 * c->lobe_g) the shape's bands 1 and 2 toward o = -dir, in the frame of the
 * light's vertical plane, and the sun's aureole. Zero when the higher
 * orders are switched off (0 directions). */
v3 model_higher_orders(const struct ctx *c, double h, v3 up, v3 dir, v3 light, v3 sigma_s, v3 ground, v3 fwd)
{
	if (!c->s->quality.multiscatter_dirs)
		return v(0, 0, 0);
	double mu_l = dot(up, light), share, sh[4];
	v3 psi = model_multiscatter(c, h, mu_l, &share, sh);
	v3 sig = add(sigma_s, scale(ground, share));
	if (c->lobe >= 0) {
		double view_up = dot(up, dir), s2 = 1.0 - mu_l * mu_l, o_z = -view_up;
		double o_x = skymap_clamp((view_up * mu_l - dot(dir, light)) / sqrt(fmax(s2, 1e-12)), -1.0, 1.0);
		double b1 = sh[0] * o_z;
		/* sh[2]: the (T_xx - T_yy) term under delta-M, T_xz's without;
		 * o_x^2 - o_y^2 = 2 o_x^2 + o_z^2 - 1. */
		double b2 = sh[1] * (1.5 * o_z * o_z - 0.5) +
			    sh[2] * (c->delta >= 0 ? 2.0 * o_x * o_x + o_z * o_z - 1.0 : o_x * o_z);
		/* The aureole: a (4 pi HG_{g1 g1}(view . light) - 1). */
		double gl = c->lobe_g[0] * c->lobe_g[0];
		double den = (1.0 - gl) * (1.0 - gl) + 2.0 * gl * (1.0 - dot(dir, light));
		double lobe = sh[3] * ((1.0 - gl * gl) / (den * sqrt(den)) - 1.0);
		sig = add(sig, scale(fwd, c->lobe_g[0] * b1 + c->lobe_g[1] * b2 + lobe));
		sig = v(fmax(sig.x, 0.0), fmax(sig.y, 0.0), fmax(sig.z, 0.0));
	}
	return mul(sig, psi);
}

/* visible: see model_step_light(). ground: model_ground_scattering() of the step. */
v3 model_light_source(const struct ctx *c, double h, v3 up, v3 dir, v3 light, double radius_deg,
		      double visible, v3 illum, v3 sigma_s, v3 ground)
{
	v3 s = mul(model_phased_scattering(c, h, dot(dir, light)), model_step_light(c, h, dot(up, light), radius_deg, visible));
	v3 fwd = v(0, 0, 0);
	/* A Rayleigh lobe (g1 = 0): every constituent's band 2, sum sigma_i
	 * g2_i over the lobe's g2 (forward_scattering in common.glsl). */
	for (int n = 0; n < c->a->n_constituents && c->lobe >= 0; n++) {
		const struct atmo_constituent *k = &c->a->c[n];
		if (c->lobe_weight[n] != 0.0)
			fwd = add(fwd, scale(v(k->scattering_per_km[0], k->scattering_per_km[1],
					       k->scattering_per_km[2]),
					     c->lobe_weight[n] * atmo_density(&k->density, h)));
	}
	s = add(s, model_higher_orders(c, h, up, dir, light, sigma_s, ground, fwd));
	return mul(s, illum);
}


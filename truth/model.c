/* model.c - double-precision mirror of the compute shaders, used as the oracle:
 * its context, the tables, transmittance and the column densities. */
#include "model_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* ---- the medium and its column densities ---- */

struct medium model_medium(const struct ctx *c, double h)
{
	struct medium m = { 0 };
	for (int i = 0; i < c->a->n_constituents; i++) {
		const struct atmo_constituent *k = &c->a->c[i];
		double d = atmo_density(&k->density, h);
		m.scattering = add(m.scattering, scale(v(k->scattering_per_km[0], k->scattering_per_km[1],
							   k->scattering_per_km[2]), d));
		m.absorption = add(m.absorption, scale(v(k->absorption_per_km[0], k->absorption_per_km[1],
							   k->absorption_per_km[2]), d));
	}
	m.extinction = add(m.scattering, m.absorption);
	return m;
}

/* Mean of exp(k h) over [ha, hb], exact for a linear change of altitude.
 * Written as a difference of two exponentials of real altitudes, never as
 * exp(k hm) sinh(x) / x: with a 0.1 km scale height over a 100 km step that
 * product is 0 * inf = NaN. The series keeps the small-step limit exact. */
static double mean_exp(double k, double ha, double hb)
{
	double x = 0.5 * k * (hb - ha);
	if (fabs(x) < 1e-4)
		return exp(0.5 * k * (ha + hb)) * (1.0 + x * x / 6.0);
	return (exp(k * hb) - exp(k * ha)) / (2.0 * x);
}

/* Mean density over a step from ha to hb of a profile with an exponential
 * term, exact where the altitude changes linearly over the step. */
static double mean_density(const struct atmo_profile *p, double ha, double hb)
{
	double hm = 0.5 * (ha + hb);
	const struct atmo_layer *l = hm < p->layers[0].width_km ? &p->layers[0] : &p->layers[1];
	double e = l->exp_term != 0.0 ? l->exp_term * mean_exp(l->exp_scale_per_km, ha, hb) : 0.0;
	double d = e + l->linear_per_km * hm + l->constant;
	return d < 0 ? 0 : d > 1 ? 1 : d;
}

/* A straight ray seen from the planet's centre: impact parameter p (the
 * radius of the tangent point) and the tangent point's altitude, kept apart
 * because p - rb would cancel. Along the ray u = t + r mu, and the altitude
 * is h(u) = h_tan + u^2 / (s + p), s = sqrt(u^2 + p^2). common.glsl has the
 * same functions in float32 (shaders/columns.comp). */
struct chord {
	double rb, p, h_tan;
};

static struct chord chord_of(double rb, double h, double mu)
{
	double u0 = (rb + h) * mu;
	double q = h * (2.0 * rb + h) - u0 * u0;	/* p^2 - rb^2 */
	struct chord c = { .rb = rb, .p = sqrt(fmax(rb * rb + q, 0.0)) };
	c.h_tan = q / (c.p + rb);
	return c;
}

static double chord_altitude(const struct chord *c, double u)
{
	double sp = sqrt(u * u + c->p * c->p) + c->p;
	return sp > 0 ? c->h_tan + u * u / sp : c->h_tan;
}

/* |u| where the chord crosses altitude h (>= h_tan). */
static double chord_crossing(const struct chord *c, double h)
{
	return sqrt(fmax((h - c->h_tan) * (h + c->h_tan + 2.0 * c->rb), 0.0));
}

/* x - asinh(x) for x >= 0 without cancellation: the series below 0.1 (its
 * first left-out term is 7e-16 of the sum there). shaders/columns.comp splits at
 * 0.5 (float32). */
static double x_minus_asinh(double x)
{
	if (x >= 0.1)
		return x - asinh(x);
	double x2 = x * x;
	return x * x2 * (1.0 / 6 - x2 * (3.0 / 40 - x2 * (5.0 / 112 - x2 * (35.0 / 1152 -
	       x2 * (63.0 / 2816 - x2 * (231.0 / 13312 - x2 * (143.0 / 10240 -
	       x2 * (6435.0 / 557056))))))));
}

/* The integral of h(u) over [ua, ub] (0 <= ua <= ub) minus its trapezoid
 * (ub - ua) (h(ua) + h(ub)) / 2. With u = p sinh(theta) it is
 * -p^2 (sinh(dtheta) - dtheta) / 2, and sinh(dtheta) is the X below, which
 * has no p in a denominator (p = 0 on a vertical ray). <= 0: h is convex. */
static double chord_curvature(const struct chord *c, double ua, double ub)
{
	double sa = sqrt(ua * ua + c->p * c->p), sb = sqrt(ub * ub + c->p * c->p);
	double den = ub * sa + ua * sb;
	if (!(c->p > 0) || !(den > 0))
		return 0.0;
	return -0.5 * c->p * c->p * x_minus_asinh((ub - ua) * (ub + ua) / den);
}

#define N_KINKS 5

/* The profile's kinks: the layer boundary and where either layer's linear
 * term meets the clamps at 0 and 1. A kink that a layer never reaches only
 * cuts a piece in two; a flat layer repeats the boundary. */
static void profile_kinks(const struct atmo_profile *p, double ret[N_KINKS])
{
	double w = p->layers[0].width_km;
	ret[0] = w;
	for (int i = 0; i < 2; i++) {
		const struct atmo_layer *l = &p->layers[i];
		ret[1 + 2 * i] = l->linear_per_km != 0.0 ? -l->constant / l->linear_per_km : w;
		ret[2 + 2 * i] = l->linear_per_km != 0.0 ? (1.0 - l->constant) / l->linear_per_km : w;
	}
}

/* The integral over [ua, ub] of a profile that is linear in altitude
 * between the altitudes ha and hb (no kink between): the trapezoid of the
 * densities at the ends, which cannot cancel, plus the slope times the
 * chord's curvature. */
static double column_piece(const struct atmo_profile *p, const struct chord *c, double ua,
			   double ha, double ub, double hb)
{
	double hm = 0.5 * (ha + hb);
	const struct atmo_layer *l = hm < p->layers[0].width_km ? &p->layers[0] : &p->layers[1];
	double dm = l->linear_per_km * hm + l->constant;
	if (dm <= 0.0)
		return 0.0;
	if (dm >= 1.0)
		return ub - ua;
	double da = l->linear_per_km * ha + l->constant, db = l->linear_per_km * hb + l->constant;
	da = da < 0 ? 0 : da > 1 ? 1 : da;
	db = db < 0 ? 0 : db > 1 ? 1 : db;
	double x = (ub - ua) * 0.5 * (da + db) + l->linear_per_km * chord_curvature(c, ua, ub);
	return x > 0 ? x : 0;
}

/* The same over |u| in [lo, hi], 0 <= lo, where the altitude rises with
 * |u|: cut at every kink crossed, the next one the lowest kink above the
 * last (as columns.comp, which cannot sort). */
static double column_rising(const struct atmo_profile *p, const struct chord *c,
			    const double kinks[N_KINKS], double lo, double hi)
{
	double ua = lo, ha = chord_altitude(c, lo), h_hi = chord_altitude(c, hi), sum = 0.0;
	for (int i = 0; i < N_KINKS; i++) {
		double next = h_hi;
		for (int j = 0; j < N_KINKS; j++)
			if (kinks[j] > ha && kinks[j] < next)
				next = kinks[j];
		if (!(next < h_hi))
			break;
		double ub = chord_crossing(c, next);
		ub = ub < ua ? ua : ub > hi ? hi : ub;
		sum += column_piece(p, c, ua, ha, ub, next);
		ua = ub;
		ha = next;
	}
	return sum + column_piece(p, c, ua, ha, hi, h_hi);
}

/* The column density of a profile of clamped linear layers (ozone's tent)
 * from altitude h along mu for a length d, in closed form: steps that take
 * the altitude as linear in t miss its curvature near a grazing ray's
 * tangent point, enough to make the table's rows rise. The ray descends
 * to its tangent point (u < 0), then rises: each half is monotone in
 * altitude. */
static double column_linear(const struct atmo_profile *p, double rb, double h, double mu, double d)
{
	double kinks[N_KINKS];
	profile_kinks(p, kinks);
	struct chord c = chord_of(rb, h, mu);
	double u0 = (rb + h) * mu, u1 = u0 + d, sum = 0.0;
	if (u0 < 0)
		sum += column_rising(p, &c, kinks, u1 < 0 ? -u1 : 0.0, -u0);
	if (u1 > 0)
		sum += column_rising(p, &c, kinks, u0 > 0 ? u0 : 0.0, u1);
	return sum;
}

/* The column density of p from altitude h along mu to the top: profiles of
 * linear layers in closed form (column_linear), profiles with an
 * exponential term in steps of equal length, each exact for a linear
 * change of altitude over the step. */
double model_column(const struct ctx *c, const struct atmo_profile *p, double h, double mu, uint32_t steps)
{
	double d = distance_to_top(c, h, mu), dt = d / steps, rr, column = 0.0, ha = h;
	if (p->layers[0].exp_term == 0.0 && p->layers[1].exp_term == 0.0)
		return column_linear(p, c->rb, h, mu, d);
	for (uint32_t k = 0; k < steps; k++) {
		double hb = altitude_along(c, h, mu, (k + 1) * dt, &rr);
		column += mean_density(p, ha, hb);
		ha = hb;
	}
	return column * dt;
}

/* Optical depth from altitude h along mu to the top, as the engine's two
 * transmittance passes compute it: per constituent the column density of
 * its profile (geometry only), then the sum of the columns weighted by the
 * extinctions. */
v3 model_depth_to_top(const struct ctx *c, double h, double mu, uint32_t steps)
{
	v3 tau = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *a = &c->a->c[n];
		double column = model_column(c, &a->density, h, mu, steps);
		tau = add(tau, scale(v(a->scattering_per_km[0] + a->absorption_per_km[0],
				       a->scattering_per_km[1] + a->absorption_per_km[1],
				       a->scattering_per_km[2] + a->absorption_per_km[2]), column));
	}
	return tau;
}

static void compute_transmittance(const struct ctx *c, const struct state_table_quality *q, double *out)
{
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double h, mu;
			skymap_transmittance_inverse(c->rb, c->rt, (i + 0.5) / q->width, (j + 0.5) / q->height,
						     q->width, q->height, &h, &mu);
			put(out + 4 * (j * q->width + i), vexp_neg(model_depth_to_top(c, h, mu, q->steps)), 1.0);
		}
}

void model_optical_depth(const struct atmo *a, double altitude_km, double mu, uint32_t steps,
			 double ret_tau[3])
{
	struct ctx c = { .a = a, .rb = a->bottom_radius_km, .rt = a->top_radius_km };
	c.shell = c.rt - c.rb;
	v3 tau = model_depth_to_top(&c, skymap_clamp(altitude_km, 0, c.shell), skymap_clamp(mu, -1, 1),
				    steps ? steps : 1);
	ret_tau[0] = tau.x;
	ret_tau[1] = tau.y;
	ret_tau[2] = tau.z;
}

void model_tables_finish(struct model_tables *m)
{
	for (int t = 0; t < STATE_N_TABLES; t++)
		free(m->t[t]);
	memset(m, 0, sizeof(*m));
}

int model_tables_new(const struct sky_state *s, uint32_t mask, struct model_tables *ret)
{
	struct model_tables m = { 0 };

	mask = state_closure(mask);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		const struct state_table_quality *q = &s->quality.t[t];
		m.w[t] = q->width;
		m.h[t] = q->height;
		m.d[t] = t == STATE_AERIAL ? q->depth : 1;
		if (!(mask & STATE_BIT(t)))
			continue;
		m.t[t] = calloc((size_t)m.w[t] * m.h[t] * m.d[t] * 4, sizeof(double));
		if (!m.t[t]) {
			model_tables_finish(&m);
			return -ENOMEM;
		}
	}
	*ret = m;
	return 0;
}

/* The model's context for state s reading the tables in tab. */
void model_ctx_init(struct ctx *c, const struct sky_state *s, const struct model_tables *tab)
{
	double sun[3], moon[3];

	*c = (struct ctx){ .s = s, .a = &s->atmo, .tab = tab, .lobe = -1, .delta = -1 };
	c->rb = s->atmo.bottom_radius_km;
	c->rt = s->atmo.top_radius_km;
	c->shell = c->rt - c->rb;
	c->h0 = s->altitude_km > 0 ? s->altitude_km : 0;
	state_direction(s->sun.elevation_deg, s->sun.azimuth_deg, sun);
	state_direction(s->moon.elevation_deg, s->moon.azimuth_deg, moon);
	c->sun = v(sun[0], sun[1], sun[2]);
	c->moon = v(moon[0], moon[1], moon[2]);
	c->sun_illum = scale(v(s->sun.color[0], s->sun.color[1], s->sun.color[2]), s->sun.illuminance_lx);
	c->moon_illum = scale(v(s->moon.color[0], s->moon.color[1], s->moon.color[2]), s->moon.illuminance_lx);
	c->moon_lit = s->moon.illuminance_lx > 0;
	state_night_floor(s, &c->night_cd_m2, &c->night_gain);
	for (int n = 0; n < s->atmo.n_constituents; n++) {
		const struct atmo_constituent *k = &s->atmo.c[n];
		bool scatters = k->scattering_per_km[0] > 0 || k->scattering_per_km[1] > 0 ||
				k->scattering_per_km[2] > 0;
		double excess[PHASE_GROUND_N];
		phase_ground_excess(scatters ? k->phase : ATMO_PHASE_NONE, k->g, excess);
		phase_ground_fit(excess, c->ground_fit[n]);
	}
}

int model_compute(const struct sky_state *s, uint32_t mask, struct model_tables *ret)
{
	struct model_tables m = { 0 };
	struct ctx c;

	model_ctx_init(&c, s, &m);
	int rc = model_tables_new(s, mask, &m);
	if (rc < 0)
		return rc;
	rc = model_delta_init(&c, s, &m);
	if (rc < 0) {
		model_tables_finish(&m);
		return rc;
	}
	c.lobe = s->quality.multiscatter_dirs && m.t[1] ? phase_lobe_constituent(s, NULL) : -1;
	if (c.lobe >= 0) {
		c.lobe_g[0] = phase_legendre(s->atmo.c[c.lobe].phase, s->atmo.c[c.lobe].g, 1);
		c.lobe_g[1] = phase_legendre(s->atmo.c[c.lobe].phase, s->atmo.c[c.lobe].g, 2);
		if (c.delta >= 0) {	/* the truncated phase (ms_source in common.glsl) */
			c.lobe_g[0] = c.delta_g;
			c.lobe_g[1] = c.delta_g * c.delta_g;
		}
		for (int n = 0; n < s->atmo.n_constituents; n++) {
			const struct atmo_constituent *k = &s->atmo.c[n];
			c.lobe_weight[n] = c.lobe_g[0] != 0.0 ? n == c.lobe
					   : k->phase == ATMO_PHASE_NONE ? 0.0
					   : phase_legendre(k->phase, k->g, 2) / c.lobe_g[1];
		}
		c.moment = calloc(4 * (size_t)m.w[1] * m.h[1], sizeof(double));
		if (!c.moment) {
			free(c.delta_col);
			model_tables_finish(&m);
			return -ENOMEM;
		}
	}
	if (m.t[0])
		compute_transmittance(&c, &s->quality.t[0], m.t[0]);
	if (m.t[1])
		rc = model_compute_multiscatter(&c, &s->quality.t[1],
					  s->quality.multiscatter_dirs ? s->quality.multiscatter_dirs : 2, m.t[1]);
	if (rc < 0) {
		free(c.delta_col);
		model_tables_finish(&m);
		return rc;
	}
	if (m.t[2])
		model_compute_skyview(&c, &s->quality.t[2], m.t[2]);
	if (m.t[3])
		model_compute_aerial(&c, &s->quality.t[3], m.t[3]);
	free(c.moment);
	free(c.delta_col);
	*ret = m;
	return 0;
}

void model_refine(const struct sky_state *s, uint32_t factor, struct sky_state *ret)
{
	*ret = *s;
	for (int t = 0; t < STATE_N_TABLES; t++)
		ret->quality.t[t].steps *= factor;
	ret->quality.skyview_min_steps = ret->quality.t[STATE_SKYVIEW].steps;
}

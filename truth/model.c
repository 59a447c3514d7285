/* model.c - double-precision mirror of the compute shaders, used as the oracle. */
#include "model.h"

#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "phase.h"
#include "skymap.h"

typedef struct {
	double x, y, z;
} v3;

static v3 v(double x, double y, double z) { return (v3){ x, y, z }; }
static v3 add(v3 a, v3 b) { return v(a.x + b.x, a.y + b.y, a.z + b.z); }
static v3 mul(v3 a, v3 b) { return v(a.x * b.x, a.y * b.y, a.z * b.z); }
static v3 scale(v3 a, double s) { return v(a.x * s, a.y * s, a.z * s); }
static v3 vexp_neg(v3 a) { return v(exp(-a.x), exp(-a.y), exp(-a.z)); }
static double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static double mean3(v3 a) { return (a.x + a.y + a.z) / 3.0; }

/* The model's view of a state: what the shaders get as uniforms. */
struct ctx {
	const struct sky_state *s;
	const struct atmo *a;
	double rb, rt, shell, h0;
	v3 sun, moon, sun_illum, moon_illum;
	bool moon_lit;
	double night_cd_m2, night_gain;	/* state_night_floor */
	const struct model_tables *tab;
	/* phase_ground_fit of each constituent's phase_ground_excess (0 for one
	 * that scatters nothing) */
	double ground_fit[ATMO_MAX_CONSTITUENTS][PHASE_GROUND_FIT];
	/* The shape of the multiply scattered light for the constituent
	 * phase_moment_constituent names (-1 none): per multi-scattering
	 * texel the 4 numbers of multiscatter.comp's texel; that
	 * constituent's g1 and g2. */
	int lobe;
	double *moment;
	double lobe_g[2];
	/* Delta-M (phase_delta_constituent, delta_source in common.glsl):
	 * the constituent (-1 none), its f and g', the scaled atmosphere
	 * (its scattering (1 - f) sigma_D through Henyey-Greenstein g'),
	 * its column density per transmittance texel (RGBA, in R), and
	 * whether the sunlight comes through the scaled transmittance (the
	 * multi-scattering table's context only). */
	int delta;
	double delta_f, delta_g, delta_h, delta_spread;
	struct atmo scaled;
	double *delta_col;
	bool delta_light;
};

static double rho2(const struct ctx *c, double h) { return h * (2.0 * c->rb + h); }

static double horizon_cos(const struct ctx *c, double h)
{
	return skymap_horizon_cos(c->rb, h);
}

struct medium {
	v3 scattering, absorption, extinction;
};

static struct medium medium(const struct ctx *c, double h)
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
 * from altitude h along mu for a length d, in closed form. Steps that take
 * the altitude as linear in t miss its curvature near a grazing ray's
 * tangent point, where rows of the table rose by 0.11 %. The ray descends
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

static v3 phased_scattering(const struct ctx *c, double h, double mu)
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

/* (1 - exp(-sigma dt)) / sigma without cancellation; dt at sigma = 0. */
static double seg1(double sigma, double dt)
{
	double x = sigma * dt;
	if (x < 1e-4)
		return dt * (1.0 - x * (0.5 - x / 6.0));
	return -expm1(-x) / sigma;
}

static v3 segment_weight(v3 sigma, double dt)
{
	return v(seg1(sigma.x, dt), seg1(sigma.y, dt), seg1(sigma.z, dt));
}

static double altitude_along(const struct ctx *c, double h, double mu, double t, double *ret_r)
{
	double r = c->rb + h;
	double excess = rho2(c, h) + t * (t + 2.0 * r * mu);
	*ret_r = sqrt(c->rb * c->rb + (excess > 0 ? excess : 0));
	return excess / (*ret_r + c->rb);
}

static double distance_to_top(const struct ctx *c, double h, double mu)
{
	return skymap_distance_to_top(c->rb, c->rt, h, mu);
}

static bool hits_ground(const struct ctx *c, double h, double mu, double *ret_t)
{
	double mu_h = horizon_cos(c, h);
	*ret_t = 0.0;
	if (h < 0.0 || mu >= mu_h)
		return false;
	double r = c->rb + h;
	double disc = r * r * (mu - mu_h) * (mu + mu_h);
	double t = -r * mu - skymap_safe_sqrt(disc);
	*ret_t = t > 0 ? t : 0;
	return true;
}

/* The four texels around (u, vv) of a w x h RGBA table (the edges clamped)
 * and the weights, as the shaders' bilinear reads. */
struct taps {
	size_t i00, i01, i10, i11;
	double fx, fy;
};

static struct taps taps_at(uint32_t w, uint32_t h, double u, double vv)
{
	double px = skymap_clamp(u, 0, 1) * w - 0.5, py = skymap_clamp(vv, 0, 1) * h - 0.5;
	int ix = (int)floor(px), iy = (int)floor(py);
	int x0 = ix < 0 ? 0 : ix > (int)w - 1 ? (int)w - 1 : ix;
	int x1 = ix + 1 < 0 ? 0 : ix + 1 > (int)w - 1 ? (int)w - 1 : ix + 1;
	int y0 = iy < 0 ? 0 : iy > (int)h - 1 ? (int)h - 1 : iy;
	int y1 = iy + 1 < 0 ? 0 : iy + 1 > (int)h - 1 ? (int)h - 1 : iy + 1;
	return (struct taps){ 4 * ((size_t)y0 * w + x0), 4 * ((size_t)y0 * w + x1),
			      4 * ((size_t)y1 * w + x0), 4 * ((size_t)y1 * w + x1),
			      px - floor(px), py - floor(py) };
}

static double taps_channel(const double *tab, const struct taps *t, int ch)
{
	double top = tab[t->i00 + ch] + (tab[t->i01 + ch] - tab[t->i00 + ch]) * t->fx;
	double bot = tab[t->i10 + ch] + (tab[t->i11 + ch] - tab[t->i10 + ch]) * t->fx;
	return top + (bot - top) * t->fy;
}

static v3 bilinear(const double *tab, uint32_t w, uint32_t h, double u, double vv)
{
	struct taps t = taps_at(w, h, u, vv);
	return v(taps_channel(tab, &t, 0), taps_channel(tab, &t, 1), taps_channel(tab, &t, 2));
}

/* bilinear() of the A channel. */
static double bilinear_a(const double *tab, uint32_t w, uint32_t h, double u, double vv)
{
	struct taps t = taps_at(w, h, u, vv);
	return taps_channel(tab, &t, 3);
}

static v3 transmittance_to_top(const struct ctx *c, double h, double mu)
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
static double disk_visible_mean(double xa, double xb, double e)
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
static double disk_halfwidth(const struct ctx *c, double h, double radius_rad)
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
static double light_visible(const struct ctx *c, double h, double mu, double radius_rad)
{
	double hc = h < 0 ? 0 : h > c->shell ? c->shell : h;
	double mu_h = h < 0 ? -2.0 : skymap_horizon_cos(c->rb, hc);
	return disk_visible(mu - mu_h, disk_halfwidth(c, h, radius_rad));
}

static v3 light_transmittance(const struct ctx *c, double h, double mu, double radius_rad)
{
	return visible_transmittance(c, h, mu, light_visible(c, h, mu, radius_rad));
}

/* The light reaching a march step: visible is the part of the disk seen,
 * averaged over the step (disk_visible_mean), or negative to take it at the
 * point. */
static v3 step_light(const struct ctx *c, double h, double mu_l, double radius_deg, double visible)
{
	return visible < 0 ? light_transmittance(c, h, mu_l, radius_deg * SKYMAP_PI / 180.0)
			   : visible_transmittance(c, h, mu_l, visible);
}

/* The bilinear taps of the transmittance texels toward mu from altitude h
 * (the column table shares them: columns_at in common.glsl). */
static struct taps transmittance_taps(const struct ctx *c, double h, double mu)
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
static v3 multiscatter(const struct ctx *c, double h, double mu_s, double *ret_share, double ret_shape[4])
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
		 * 1e-9 mirror check of the model (tools/stab.c). */
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
static v3 ground_scattering(const struct ctx *c, double h, double mu_view)
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
static v3 higher_orders(const struct ctx *c, double h, v3 up, v3 dir, v3 light, v3 sigma_s, v3 ground, v3 fwd)
{
	if (!c->s->quality.multiscatter_dirs)
		return v(0, 0, 0);
	double mu_l = dot(up, light), share, sh[4];
	v3 psi = multiscatter(c, h, mu_l, &share, sh);
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

/* visible: see step_light(). ground: ground_scattering() of the step. */
static v3 light_source(const struct ctx *c, double h, v3 up, v3 dir, v3 light, double radius_deg,
			double visible, v3 illum, v3 sigma_s, v3 ground)
{
	v3 s = mul(phased_scattering(c, h, dot(dir, light)), step_light(c, h, dot(up, light), radius_deg, visible));
	v3 fwd = v(0, 0, 0);
	if (c->lobe >= 0) {
		const struct atmo_constituent *k = &c->a->c[c->lobe];
		fwd = scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
			    atmo_density(&k->density, h));
	}
	s = add(s, higher_orders(c, h, up, dir, light, sigma_s, ground, fwd));
	return mul(s, illum);
}

/* ---- delta-M for the higher orders (delta_source in common.glsl) ---- */

static v3 optical_depth(const struct ctx *c, double h, double mu, uint32_t steps);

/* The delta constituent's column density from altitude h along mu to the
 * top, as optical_depth computes each constituent's. */
static double delta_column(const struct ctx *c, double h, double mu, uint32_t steps)
{
	const struct atmo_profile *p = &c->a->c[c->delta].density;
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

/* The peak's optical depth toward mu from altitude h, f sigma_D L_D (T_l' /
 * T_l is exp of it), L_D read bilinearly from the column table at the
 * transmittance lookup's taps. */
static v3 delta_depth(const struct ctx *c, double h, double mu)
{
	const struct atmo_constituent *k = &c->s->atmo.c[c->delta];	/* the real sigma_D */
	struct taps t = transmittance_taps(c, h, mu);
	return scale(v(k->scattering_per_km[0], k->scattering_per_km[1], k->scattering_per_km[2]),
		     c->delta_f * taps_channel(c->delta_col, &t, 0));
}

/* The scaled medium's light_transmittance: the visible part of the disk
 * times exp(-tau'), tau' read bilinearly from the scaled optical depths at
 * the transmittance texels (columns_at in common.glsl). */
static v3 delta_light_transmittance(const struct ctx *c, double h, double mu, double radius_rad)
{
	double vis = light_visible(c, h, mu, radius_rad);
	if (vis <= 0)
		return v(0, 0, 0);
	struct taps t = transmittance_taps(c, h, mu);
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
	v3 t = step_light(c, h, mu_l, radius_deg, visible);
	v3 ph = phased_scattering(c, h, mu);
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
	s = add(s, higher_orders(c, h, up, dir, light, sigma_s, ground, scale(delta_sigma(c, h), 1.0 - c->delta_f)));
	*ret_scaled = mul(s, illum);
}

/* One step of march() with delta-M: the scaled medium's scattering, ground
 * term and view optical depth (tau_scaled) beside the real ones. */
static void delta_step(const struct ctx *c, double hs, v3 up, v3 dir, double dt, double vis_sun,
		       double vis_moon, struct medium m, v3 *radiance, v3 *tau, v3 *tau_scaled)
{
	v3 removed = scale(delta_sigma(c, hs), c->delta_f), r, rs, r2, rs2;
	v3 ext_s = add(m.extinction, scale(removed, -1.0)), sig_s = add(m.scattering, scale(removed, -1.0));
	/* ground_scattering with the scaled constituent: ground_fit holds the
	 * truncated phase's for it (delta_init). */
	double ex = phase_ground_fit_at(c->ground_fit[c->delta], dot(up, dir));
	v3 ground = add(ground_scattering(c, hs, dot(up, dir)), scale(removed, -ex));
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
static int delta_init(struct ctx *c, const struct sky_state *s, const struct model_tables *m)
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
			c->delta_col[4 * (j * q->width + i)] = delta_column(c, h, mu, q->steps);
			v3 tau = optical_depth(&scaled, h, mu, q->steps);
			c->delta_col[4 * (j * q->width + i) + 1] = tau.x;
			c->delta_col[4 * (j * q->width + i) + 2] = tau.y;
			c->delta_col[4 * (j * q->width + i) + 3] = tau.z;
		}
	return 0;
}

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

static void put(double *dst, v3 rgb, double a)
{
	dst[0] = rgb.x;
	dst[1] = rgb.y;
	dst[2] = rgb.z;
	dst[3] = a;
}

/* Optical depth from altitude h along mu to the top, as the engine's two
 * transmittance passes compute it: per constituent the column density of
 * its profile (geometry only), then the sum of the columns weighted by the
 * extinctions. Profiles of linear layers in closed form (column_linear);
 * profiles with an exponential term in steps of equal length, each exact
 * for a linear change of altitude over the step. */
static v3 optical_depth(const struct ctx *c, double h, double mu, uint32_t steps)
{
	double d = distance_to_top(c, h, mu), dt = d / steps, rr;
	v3 tau = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *a = &c->a->c[n];
		const struct atmo_profile *p = &a->density;
		double column = 0.0, ha = h;
		if (p->layers[0].exp_term == 0.0 && p->layers[1].exp_term == 0.0) {
			column = column_linear(p, c->rb, h, mu, d);
		} else {
			for (uint32_t k = 0; k < steps; k++) {
				double hb = altitude_along(c, h, mu, (k + 1) * dt, &rr);
				column += mean_density(p, ha, hb);
				ha = hb;
			}
			column *= dt;
		}
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
			put(out + 4 * (j * q->width + i), vexp_neg(optical_depth(c, h, mu, q->steps)), 1.0);
		}
}

void model_optical_depth(const struct atmo *a, double altitude_km, double mu, uint32_t steps,
			 double ret_tau[3])
{
	struct ctx c = { .a = a, .rb = a->bottom_radius_km, .rt = a->top_radius_km };
	c.shell = c.rt - c.rb;
	v3 tau = optical_depth(&c, skymap_clamp(altitude_km, 0, c.shell), skymap_clamp(mu, -1, 1),
			       steps ? steps : 1);
	ret_tau[0] = tau.x;
	ret_tau[1] = tau.y;
	ret_tau[2] = tau.z;
}

/* Sub-samples per axis of a direction's cell for its mean phase. */
#define MS_PHASE_SUB 2
/* The 64-direction grid: rings of cos-zenith, denser near the horizon, by
 * azimuth columns (why 16 x 4 and these rings: multiscatter.comp). */
#define MS_RINGS 16
#define MS_COLS 4
#define MS_RING_POW 1.2
/* The weights of A, the ground's share of psi (see msgrid.glsl). */
#define SHARE_LUM v(0.2126, 0.7152, 0.0722)

/* The cosine of ring edge e (0: zenith, MS_RINGS: nadir); for two
 * directions, the hemispheres' edges (1, 0, -1). */
static double ms_ring_edge(uint32_t e, uint32_t n)
{
	if (n == 2)
		return 1.0 - e;
	double s = 1.0 - 2.0 * e / MS_RINGS;
	return (s < 0 ? -1.0 : 1.0) * pow(fabs(s), MS_RING_POW);
}

/* Direction k's ring's top and bottom cosines. */
static void ms_ring(uint32_t k, uint32_t n, double *ret_top, double *ret_bot)
{
	uint32_t ring = n == 2 ? k : k / MS_COLS;
	*ret_top = ms_ring_edge(ring, n);
	*ret_bot = ms_ring_edge(ring + 1, n);
}

/* Direction k's cell's solid angle over the mean cell's. */
static double ms_cell_weight(uint32_t k, uint32_t n)
{
	double top, bot;
	ms_ring(k, n, &top, &bot);
	return n == 2 ? 1.0 : (top - bot) * MS_RINGS * 0.5;
}

/* The mean over direction k's cell of constituent kc's phase toward the sun,
 * from MS_PHASE_SUB^2 equal-area sub-samples (see multiscatter.comp). The
 * cells: MS_RINGS rings (ms_ring_edge()) by MS_COLS azimuth columns, or for
 * two directions the upper and lower hemispheres. With ret_xy2, also the
 * sub-samples' mean x^2 - y^2 weighted by the phase (cell_xy2 in
 * multiscatter.comp). */
static double ms_cell_phase(const struct atmo_constituent *kc, uint32_t k, uint32_t n, v3 sun, double *ret_xy2)
{
	uint32_t col = n == 2 ? 0 : k % MS_COLS;
	double dphi = n == 2 ? 2.0 * SKYMAP_PI : 2.0 * SKYMAP_PI / MS_COLS, sum = 0, xy2 = 0, top, bot;
	ms_ring(k, n, &top, &bot);
	for (int a = 0; a < MS_PHASE_SUB; a++) {
		double ct = top + (bot - top) * (a + 0.5) / MS_PHASE_SUB;
		double st = skymap_safe_sqrt(1.0 - ct * ct);
		for (int b = 0; b < MS_PHASE_SUB; b++) {
			double ph = dphi * (col + (b + 0.5) / MS_PHASE_SUB);
			double p = phase_value(kc->phase, kc->g, st * cos(ph) * sun.x + ct * sun.z);
			sum += p;
			xy2 += p * st * st * cos(2.0 * ph);
		}
	}
	if (ret_xy2)
		*ret_xy2 = xy2 / fmax(sum, 1e-30);
	return sum / (MS_PHASE_SUB * MS_PHASE_SUB);
}

static v3 ms_direction(uint32_t k, uint32_t n)
{
	if (n == 2)
		return v(0, 0, k == 0 ? 1.0 : -1.0);
	double top, bot;
	ms_ring(k, n, &top, &bot);
	double ct = 0.5 * (top + bot);
	double ph = 2.0 * SKYMAP_PI * ((k % MS_COLS) + 0.5) / MS_COLS;
	double st = skymap_safe_sqrt(1.0 - ct * ct);
	return v(st * cos(ph), st * sin(ph), ct);
}

/* One texel of the multi-scattering table at altitude h and sun cosine
 * mu_s: psi, the ground's share of it (A) and the escape 1 - f_ms. */
static void ms_texel(const struct ctx *c, uint32_t steps, uint32_t dirs, double h, double mu_s,
		     v3 *ret_psi, double *ret_share, v3 *ret_escape, double ret_shape[4])
{
	const double albedo[3] = { c->a->ground_albedo[0], c->a->ground_albedo[1], c->a->ground_albedo[2] };
	v3 sun = v(skymap_safe_sqrt(1.0 - mu_s * mu_s), 0, mu_s);
	/* s2: L2's second moments zz, xz and, from the sub-samples, xx - yy. */
	v3 sl = { 0 }, sg = { 0 }, sr = { 0 }, se = { 0 }, sm = { 0 }, s2 = { 0 };
	double r0 = c->rb + h;
	/* The first scattering of L2 with each constituent's own phase,
	 * the cells' means normalised to sum to exactly 1 over the
	 * sphere (see multiscatter.comp). */
	double norm_phase[ATMO_MAX_CONSTITUENTS] = { 0 };
	for (int n = 0; n < c->a->n_constituents; n++) {
		const struct atmo_constituent *kc = &c->a->c[n];
		if (kc->phase == ATMO_PHASE_NONE)
			continue;
		double sum = 0;
		for (uint32_t k = 0; k < dirs; k++)
			sum += ms_cell_weight(k, dirs) * ms_cell_phase(kc, k, dirs, sun, NULL);
		norm_phase[n] = 1.0 / (4.0 * SKYMAP_PI * sum / dirs);
	}
	for (uint32_t k = 0; k < dirs; k++) {
		v3 dir = ms_direction(k, dirs);
		double cell_phase[ATMO_MAX_CONSTITUENTS] = { 0 }, cell_xy2 = 0;
		for (int n = 0; n < c->a->n_constituents; n++)
			if (c->a->c[n].phase != ATMO_PHASE_NONE)
				cell_phase[n] = ms_cell_phase(&c->a->c[n], k, dirs, sun,
							      n == c->lobe && c->delta >= 0 ? &cell_xy2 : NULL) *
					norm_phase[n];
		double tg, t_end = distance_to_top(c, h, dir.z);
		bool ground = hits_ground(c, h, dir.z, &tg);
		if (ground)
			t_end = tg;
		double dt = t_end / steps;
		v3 tau = { 0 }, l2 = { 0 }, absorbed = { 0 };
		for (uint32_t s = 0; s < steps; s++) {
			double t = (s + 0.5) * dt, rr;
			double hs = altitude_along(c, h, dir.z, t, &rr);
			struct medium m = medium(c, hs);
			v3 w = mul(vexp_neg(tau), segment_weight(m.extinction, dt));
			v3 p = v(dir.x * t / rr, dir.y * t / rr, (r0 + dir.z * t) / rr);
			v3 t_sun = light_transmittance(c, hs, dot(p, sun),
						       c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
			if (c->delta_light)
				t_sun = delta_light_transmittance(c, hs, dot(p, sun),
								  c->s->sun.angular_radius_deg * SKYMAP_PI / 180.0);
			v3 phased = { 0 };
			for (int n = 0; n < c->a->n_constituents; n++) {
				const struct atmo_constituent *kc = &c->a->c[n];
				phased = add(phased, scale(v(kc->scattering_per_km[0], kc->scattering_per_km[1],
							     kc->scattering_per_km[2]),
							   atmo_density(&kc->density, hs) * cell_phase[n]));
			}
			l2 = add(l2, mul(mul(w, phased), t_sun));
			absorbed = add(absorbed, mul(w, m.absorption));
			tau = add(tau, scale(m.extinction, dt));
		}
		/* The cell's solid angle over the mean cell's: every
		 * term below is linear in these four. */
		double wk = ms_cell_weight(k, dirs);
		l2 = scale(l2, wk);
		absorbed = scale(absorbed, wk);
		v3 t_ray = scale(vexp_neg(tau), wk), returned = { 0 };
		if (ground) {
			v3 n = v(dir.x * t_end / c->rb, dir.y * t_end / c->rb, (r0 + dir.z * t_end) / c->rb);
			double mu_g = dot(n, sun);
			double tg_unused;
			v3 g = mul(t_ray, !c->delta_light ? transmittance_to_top(c, 0.0, mu_g)
					  : hits_ground(c, 0.0, mu_g, &tg_unused) ? v(0, 0, 0)
					  : delta_light_transmittance(c, 0.0, mu_g, 0.0));
			sg = add(sg, scale(mul(g, v(albedo[0], albedo[1], albedo[2])),
					   (mu_g > 0 ? mu_g : 0) / SKYMAP_PI));
			/* Every order bounces off the ground (see multiscatter.comp). */
			returned = mul(t_ray, v(albedo[0], albedo[1], albedo[2]));
		}
		sl = add(sl, l2);
		/* L2's first and second moments, with the cell's weight as l2
		 * has it by now: its light travels along -dir. */
		double l2_lum = dot(l2, SHARE_LUM);
		sm = add(sm, scale(dir, -l2_lum));
		s2 = add(s2, scale(v(dir.z * dir.z, dir.x * dir.z, cell_xy2), l2_lum));
		sr = add(sr, returned);
		se = add(se, add(add(t_ray, scale(returned, -1.0)), absorbed));
	}
	double lum_l2 = dot(sl, SHARE_LUM);
	sl = scale(sl, 1.0 / dirs);
	sg = scale(sg, 1.0 / dirs);
	sr = scale(sr, 1.0 / dirs);
	se = scale(se, 1.0 / dirs);
	/* The ground's first bounce G: its higher orders without the
	 * ground-to-ground return, its share of psi in A (see
	 * multiscatter.comp). */
	sl = add(sl, mul(sg, v(1.0 - sr.x, 1.0 - sr.y, 1.0 - sr.z)));
	v3 psi = v(sl.x / fmax(se.x, 1e-6), sl.y / fmax(se.y, 1e-6), sl.z / fmax(se.z, 1e-6));
	double share = dot(sg, SHARE_LUM) / fmax(dot(psi, SHARE_LUM), 1e-30);
	*ret_psi = psi;
	*ret_share = skymap_clamp(share, 0.0, 1.0);
	*ret_escape = se;
	if (ret_shape && c->lobe >= 0) {
		/* The shape of multiscatter.comp (sl is L2 + the ground's part
		 * by now: L2 alone is sm's and s2's weight). */
		double l = fmax(lum_l2, 1e-30);
		double k = l / dirs / fmax(dot(se, SHARE_LUM), 1e-6) / fmax(dot(psi, SHARE_LUM), 1e-30);
		double a = skymap_clamp(-(sm.x / l) / fmax(c->lobe_g[0] * sun.x, 1e-3), 0.0, 1.0);
		ret_shape[0] = k * 3.0 * sm.z / l;
		ret_shape[1] = k * (7.5 * s2.x / l - 2.5);
		/* Under delta-M the (T_xx - T_yy) term less the aureole's, whose
		 * own is the lobe term's, in T_xz's place (multiscatter.comp). */
		double g = c->lobe_g[0];
		ret_shape[2] = k * (c->delta >= 0 ? 3.75 * (s2.z / l - a * g * g * sun.x * sun.x) : 15.0 * s2.y / l);
		ret_shape[3] = k * a;
	}
}

/* Row y of the multi-scattering table at mu_s, read at the row's own u as
 * multiscatter() does. */
static v3 ms_row_at(const struct ctx *c, int y, double mu_s)
{
	const struct model_tables *m = c->tab;
	uint32_t w = m->w[1], n = m->h[1];
	y = y < 0 ? 0 : y > (int)n - 1 ? (int)n - 1 : y;
	double mh = skymap_horizon_cos(c->rb, (double)y / (n - 1) * c->shell);
	double d = skymap_clamp(mu_s, -1.0, 1.0) - mh;
	double sn = skymap_clamp(d < 0.0 ? d / (1.0 + mh) : d / (1.0 - mh), -1.0, 1.0);
	double a = copysign(sqrt(fabs(sn)), sn);
	return bilinear(m->t[1] + 4 * (size_t)y * w, w, 1, skymap_unit_to_tex(0.5 + 0.5 * a, w), 0.5);
}

/* psi at altitude h and mu_s for the iteration's neighbours: the parabola
 * through the three nearest rows, each read at its own u (see
 * ms_read_quadratic in msiterate.comp). */
static v3 multiscatter_quadratic(const struct ctx *c, double h, double mu_s)
{
	int n = (int)c->tab->h[1];
	if (n < 3) {
		double share, shape[4];
		return multiscatter(c, h, mu_s, &share, shape);
	}
	double p = skymap_clamp(h / c->shell, 0.0, 1.0) * (n - 1);
	int i = (int)floor(p + 0.5);
	i = i < 1 ? 1 : i > n - 2 ? n - 2 : i;
	double f = p - i;
	v3 a = ms_row_at(c, i - 1, mu_s), b = ms_row_at(c, i, mu_s), e = ms_row_at(c, i + 1, mu_s);
	v3 r = add(add(b, scale(add(e, scale(a, -1.0)), 0.5 * f)),
		   scale(add(add(e, scale(b, -2.0)), a), 0.5 * f * f));
	return v(fmax(r.x, 0.0), fmax(r.y, 0.0), fmax(r.z, 0.0));
}

/* The sky's light that reaches the ground per unit albedo, from psi at the
 * ground and the sunlight's irradiance over pi (ground_sky in
 * msiterate.comp). */
static v3 ground_sky(v3 albedo, v3 psi_g, v3 sunlit)
{
	v3 s = add(scale(psi_g, 2.0), scale(mul(albedo, sunlit), -1.0));
	return v(fmax(s.x, 0.0) / (1.0 + albedo.x), fmax(s.y, 0.0) / (1.0 + albedo.y),
		 fmax(s.z, 0.0) / (1.0 + albedo.z));
}

/* The steps of the neighbourhood iteration of psi_ms (msiterate.comp):
 * psi'(x) = L2(x) + the light that the air around x, lit by psi at its own
 * altitude and sun angle (the table), and the ground scatter toward x,
 * with the quadrature of the table. l2 holds each texel's L2 (with the
 * ground's first bounce, as the table has it); the ground's share in A
 * keeps the first bounce's luminance as psi grows. */
static int iterate_multiscatter(const struct ctx *c, const struct state_table_quality *q,
				uint32_t dirs, uint32_t steps, const v3 *l2, double *out)
{
	const v3 albedo = v(c->a->ground_albedo[0], c->a->ground_albedo[1], c->a->ground_albedo[2]);
	size_t n = (size_t)q->width * q->height;
	double *next = malloc(4 * n * sizeof(double));
	if (!next)
		return -ENOMEM;
	for (uint32_t it = 0; it < steps; it++) {
		for (uint32_t j = 0; j < q->height; j++)
			for (uint32_t i = 0; i < q->width; i++) {
				double h, mu_s, share, shape[4];
				skymap_multiscatter_inverse(c->rb, c->rt, (i + 0.5) / q->width,
							    (j + 0.5) / q->height, q->width, q->height, &h, &mu_s);
				v3 sun = v(skymap_safe_sqrt(1.0 - mu_s * mu_s), 0, mu_s), g = { 0 }, first = { 0 };
				v3 returned = { 0 };
				double r0 = c->rb + h;
				for (uint32_t k = 0; k < dirs; k++) {
					v3 dir = ms_direction(k, dirs), gk = { 0 };
					double tg, t_end = distance_to_top(c, h, dir.z);
					bool ground = hits_ground(c, h, dir.z, &tg);
					if (ground)
						t_end = tg;
					double dt = t_end / q->steps;
					v3 tau = { 0 };
					for (uint32_t s = 0; s < q->steps; s++) {
						double t = (s + 0.5) * dt, rr;
						double hs = altitude_along(c, h, dir.z, t, &rr);
						struct medium m = medium(c, hs);
						v3 w = mul(vexp_neg(tau), segment_weight(m.extinction, dt));
						v3 p = v(dir.x * t / rr, dir.y * t / rr, (r0 + dir.z * t) / rr);
						gk = add(gk, mul(mul(w, m.scattering), multiscatter_quadratic(c, hs, dot(p, sun))));
						tau = add(tau, scale(m.extinction, dt));
					}
					double wk = ms_cell_weight(k, dirs);
					if (ground) {
						v3 nr = v(dir.x * t_end / c->rb, dir.y * t_end / c->rb,
							  (r0 + dir.z * t_end) / c->rb);
						double mu_g = dot(nr, sun);
						v3 back = mul(vexp_neg(tau), albedo);
						v3 sunlit = scale(transmittance_to_top(c, 0.0, mu_g), fmax(mu_g, 0.0) / SKYMAP_PI);
						v3 psi_g = multiscatter(c, 0.0, mu_g, &share, shape);
						first = add(first, scale(mul(back, sunlit), wk));
						returned = add(returned, scale(back, wk));
						gk = add(gk, mul(back, ground_sky(albedo, psi_g, sunlit)));
					}
					g = add(g, scale(gk, wk));
				}
				size_t at = (size_t)j * q->width + i;
				const double *own = out + 4 * at;
				/* l2 holds L2 + G (1 - f_ground) as the table had it; here G
				 * counts whole (see msiterate.comp). */
				v3 l2_whole = add(l2[at], scale(mul(first, returned), 1.0 / ((double)dirs * dirs)));
				v3 psi = add(l2_whole, scale(g, 1.0 / dirs));
				double kept = dot(v(own[0], own[1], own[2]), SHARE_LUM) / fmax(dot(psi, SHARE_LUM), 1e-30);
				put(next + 4 * at, psi, skymap_clamp(own[3] * kept, 0.0, 1.0));
				/* The shape, relative to psi, keeps its absolute size as A does. */
				if (c->lobe >= 0)
					for (int k = 0; k < 4; k++)
						c->moment[4 * at + k] *= kept;
			}
		memcpy(out, next, 4 * n * sizeof(double));
	}
	free(next);
	return 0;
}

static int compute_multiscatter(const struct ctx *c, const struct state_table_quality *q,
				uint32_t dirs, double *out)
{
	uint32_t steps = state_multiscatter_iterations(c->s);
	/* Delta-M: the table is the scaled medium's (delta_source). */
	struct ctx scaled = *c;
	if (c->delta >= 0) {
		scaled.a = &c->scaled;
		scaled.delta_light = true;
	}
	v3 *l2_of = steps ? calloc((size_t)q->width * q->height, sizeof(v3)) : NULL;
	if (steps && !l2_of)
		return -ENOMEM;
	for (uint32_t j = 0; j < q->height; j++)
		for (uint32_t i = 0; i < q->width; i++) {
			double h, mu_s, share;
			v3 psi, escape;
			skymap_multiscatter_inverse(c->rb, c->rt, (i + 0.5) / q->width, (j + 0.5) / q->height,
						    q->width, q->height, &h, &mu_s);
			ms_texel(&scaled, q->steps, dirs, h, mu_s, &psi, &share, &escape,
				 c->lobe >= 0 ? c->moment + 4 * ((size_t)j * q->width + i) : NULL);
			put(out + 4 * (j * q->width + i), psi, share);
			/* L2 as the iteration recovers it from the table. */
			if (l2_of)
				l2_of[j * q->width + i] = mul(psi, v(fmax(escape.x, 1e-6), fmax(escape.y, 1e-6),
								   fmax(escape.z, 1e-6)));
		}
	int rc = steps ? iterate_multiscatter(c, q, dirs, steps, l2_of, out) : 0;
	free(l2_of);
	return rc;
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
		struct medium m = medium(c, hs);
		double vis_sun = -1, vis_moon = -1;
		if (segment_lit) {
			double xb = light_over_horizon(c, dir, a + next, c->sun);
			vis_sun = disk_visible_mean(sun_x, xb, disk_halfwidth(c, hs, c->s->sun.angular_radius_deg *
										   SKYMAP_PI / 180.0));
			sun_x = xb;
			if (c->moon_lit) {
				xb = light_over_horizon(c, dir, a + next, c->moon);
				vis_moon = disk_visible_mean(moon_x, xb,
							     disk_halfwidth(c, hs, c->s->moon.angular_radius_deg *
										   SKYMAP_PI / 180.0));
				moon_x = xb;
			}
		}
		if (c->delta >= 0) {
			delta_step(c, hs, up, dir, dt, vis_sun, vis_moon, m, radiance, tau, tau_scaled);
			continue;
		}
		v3 ground = ground_scattering(c, hs, dot(up, dir));
		v3 s = light_source(c, hs, up, dir, c->sun, c->s->sun.angular_radius_deg, vis_sun, c->sun_illum,
				    m.scattering, ground);
		if (c->moon_lit)
			s = add(s, light_source(c, hs, up, dir, c->moon, c->s->moon.angular_radius_deg, vis_moon,
						c->moon_illum, m.scattering, ground));
		*radiance = add(*radiance, mul(mul(vexp_neg(*tau), s), segment_weight(m.extinction, dt)));
		*tau = add(*tau, scale(m.extinction, dt));
	}
}

/* The night-sky floor of a sky-view direction (PROTOCOL.md): the measured
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

static void compute_skyview(const struct ctx *c, const struct state_table_quality *q, double *out)
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

static void compute_aerial(const struct ctx *c, const struct state_table_quality *q, double *out)
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
static void ctx_init(struct ctx *c, const struct sky_state *s, const struct model_tables *tab)
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

	ctx_init(&c, s, &m);
	int rc = model_tables_new(s, mask, &m);
	if (rc < 0)
		return rc;
	rc = delta_init(&c, s, &m);
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
		rc = compute_multiscatter(&c, &s->quality.t[1],
					  s->quality.multiscatter_dirs ? s->quality.multiscatter_dirs : 2, m.t[1]);
	if (rc < 0) {
		free(c.delta_col);
		model_tables_finish(&m);
		return rc;
	}
	if (m.t[2])
		compute_skyview(&c, &s->quality.t[2], m.t[2]);
	if (m.t[3])
		compute_aerial(&c, &s->quality.t[3], m.t[3]);
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

int model_multiscatter_escape(const struct sky_state *s, double altitude_km, double ret_escape[3])
{
	struct model_tables m;
	struct ctx c;
	int rc = model_compute(s, 1u << STATE_TRANSMITTANCE, &m);
	if (rc < 0)
		return rc;
	ctx_init(&c, s, &m);
	uint32_t dirs = s->quality.multiscatter_dirs ? s->quality.multiscatter_dirs : 2;
	double share;
	v3 psi, escape;
	ms_texel(&c, s->quality.t[STATE_MULTISCATTER].steps, dirs, altitude_km, 1.0, &psi, &share, &escape, NULL);
	ret_escape[0] = escape.x;
	ret_escape[1] = escape.y;
	ret_escape[2] = escape.z;
	model_tables_finish(&m);
	return 0;
}

/* pt.c - the estimator of pt.h's Monte Carlo path tracer (one sample of one
 * channel along a view ray) and its single-scattering reference; the
 * driver that runs it is pt_render.c.
 *
 * Estimator, per channel and per sample:
 *  - The first scattering point along the view ray is importance-sampled
 *    from a per-direction table of optical depth (a piecewise-exponential
 *    proposal, mixed with 30 % that follows the sunlit air for low suns and
 *    10 % uniform, so that every point where light can scatter has a
 *    positive density), weighted by T * sigma_s / pdf. The
 *    transmittance T of the view ray is the same for every sample, so it is
 *    integrated once per direction by Gauss-Legendre on cells cut at the
 *    profiles' kinks: exact to rounding for the smooth pieces.
 *  - Every vertex sends a shadow ray towards a point drawn uniformly on the
 *    sun's disk (next-event estimation); its transmittance is estimated by
 *    ratio tracking against a majorant, unbiased.
 *  - Paths go on after sampling the phase function of a constituent chosen
 *    in proportion to its scattering coefficient (no uniform directions), or
 *    a cosine lobe at the ground; free paths beyond the first are sampled by
 *    delta tracking against the same majorant. Escaping paths add nothing:
 *    the sun is reached by next-event estimation only, so the sun's disk is
 *    never counted twice.
 *  - Russian roulette on the throughput ends paths; there is no order cap.
 * The majorant per channel is sum(extinction * max density), the maximum of
 * every clamped exponential-plus-linear layer found analytically.
 */
#include "pt_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define MAX_BREAKS 64
#define DEFENSIVE 0.1		/* share of the uniform proposal on the view ray */
#define SUNLIT 0.3		/* share of the proposal that follows the sunlit air */

/* 8-point Gauss-Legendre on [-1, 1], positive half. */
static const double gl_x[4] = { 0.1834346424956498, 0.5255324099163290,
				0.7966664774136267, 0.9602898564975363 };
static const double gl_w[4] = { 0.3626837833783620, 0.3137066458778873,
				0.2223810344533745, 0.1012285362903763 };

/* ---- vectors ---- */

static double dot(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void axpy(const double o[3], double t, const double d[3], double ret[3])
{
	for (int i = 0; i < 3; i++)
		ret[i] = o[i] + t * d[i];
}

/* Orthonormal u, v completing n (Duff et al. 2017). */
static void basis(const double n[3], double u[3], double v[3])
{
	double s = copysign(1.0, n[2]);
	double a = -1.0 / (s + n[2]), b = n[0] * n[1] * a;
	u[0] = 1.0 + s * n[0] * n[0] * a;
	u[1] = s * b;
	u[2] = -s * n[0];
	v[0] = b;
	v[1] = s + n[1] * n[1] * a;
	v[2] = -n[1];
}

static void from_local(const double n[3], double cos_t, double phi, double ret[3])
{
	double u[3], v[3], s = sqrt(fmax(0.0, (1.0 - cos_t) * (1.0 + cos_t)));
	basis(n, u, v);
	double cu = s * cos(phi), cv = s * sin(phi);
	for (int i = 0; i < 3; i++)
		ret[i] = cos_t * n[i] + cu * u[i] + cv * v[i];
}

static void direction(double elevation_deg, double azimuth_deg, double ret[3])
{
	double el = elevation_deg * PI / 180.0, az = azimuth_deg * PI / 180.0;
	ret[0] = cos(el) * sin(az);
	ret[1] = cos(el) * cos(az);
	ret[2] = sin(el);
}

/* ---- counter-based random numbers ---- */

static uint64_t mix64(uint64_t z)
{
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

void pt_rng_init(struct rng *r, uint64_t seed, uint64_t dir, uint64_t sample, int channel)
{
	const uint64_t k = 0x9e3779b97f4a7c15ull;
	r->key = mix64(mix64(mix64(seed + k) + dir * k) + sample * 4 + (uint64_t)channel);
	r->ctr = 0;
}

/* Uniform in [0, 1). */
static double rnd(struct rng *r)
{
	uint64_t x = mix64(r->key + ++r->ctr * 0x9e3779b97f4a7c15ull);
	return (double)(x >> 11) * 0x1.0p-53;
}

/* ---- the medium ---- */

static double altitude(const struct medium *m, const double x[3])
{
	return sqrt(dot(x, x)) - m->rb;
}

static void densities(const struct medium *m, const double x[3], double ret[])
{
	double h = altitude(m, x);
	for (int i = 0; i < m->n; i++)
		ret[i] = atmo_density(&m->c[i].density, h);
}

static double extinction(const struct medium *m, const double x[3], int ch)
{
	double h = altitude(m, x), s = 0.0;
	for (int i = 0; i < m->n; i++)
		if (m->ext[i][ch] > 0.0)
			s += m->ext[i][ch] * atmo_density(&m->c[i].density, h);
	return s;
}

static double layer_value(const struct atmo_layer *l, double h)
{
	double d = l->exp_term * exp(l->exp_scale_per_km * h) + l->linear_per_km * h + l->constant;
	return d < 0.0 ? 0.0 : d > 1.0 ? 1.0 : d;
}

/* Largest density of one layer over [lo, hi]: a e^{sh} + l h + c is convex
 * or concave, so the maximum is at an end or at the stationary point. */
static double layer_max(const struct atmo_layer *l, double lo, double hi)
{
	double m = fmax(layer_value(l, lo), layer_value(l, hi));
	double a = l->exp_term, s = l->exp_scale_per_km, k = l->linear_per_km;
	if (a != 0.0 && s != 0.0 && k != 0.0 && -k / (a * s) > 0.0) {
		double h = log(-k / (a * s)) / s;
		if (h > lo && h < hi)
			m = fmax(m, layer_value(l, h));
	}
	return m;
}

static double profile_max(const struct atmo_profile *p, double shell_km)
{
	double w = p->layers[0].width_km, m = 0.0;
	if (w > 0.0)
		m = layer_max(&p->layers[0], 0.0, fmin(w, shell_km));
	if (w < shell_km)
		m = fmax(m, layer_max(&p->layers[1], fmax(w, 0.0), shell_km));
	return m;
}

static void add_kink(struct medium *m, double h, double shell_km)
{
	size_t cap = sizeof(m->kink_km) / sizeof(m->kink_km[0]);
	if (isfinite(h) && h > 0.0 && h < shell_km && (size_t)m->n_kinks < cap)
		m->kink_km[m->n_kinks++] = h;
}

/* Altitudes where a layer's clamp starts or stops acting, where the
 * quadrature must cut its cells. Mixed exponential-plus-linear layers have
 * no closed form and are left to the cell size. */
static void layer_kinks(struct medium *m, const struct atmo_layer *l, double shell_km)
{
	for (int v = 0; v <= 1; v++) {
		if (l->exp_term == 0.0 && l->linear_per_km != 0.0)
			add_kink(m, (v - l->constant) / l->linear_per_km, shell_km);
		else if (l->linear_per_km == 0.0 && l->exp_term != 0.0 &&
			 l->exp_scale_per_km != 0.0 && (v - l->constant) / l->exp_term > 0.0)
			add_kink(m, log((v - l->constant) / l->exp_term) / l->exp_scale_per_km,
				 shell_km);
	}
}

void pt_medium_init(struct medium *m, const struct atmo *a, const struct pt_sun *sun)
{
	double shell = a->top_radius_km - a->bottom_radius_km;

	memset(m, 0, sizeof(*m));
	m->rb = a->bottom_radius_km;
	m->rt = a->top_radius_km;
	m->n = a->n_constituents;
	m->c = a->c;
	m->dh_max_km = 1e300;
	for (int i = 0; i < m->n; i++) {
		const struct atmo_constituent *c = &a->c[i];
		double dmax = profile_max(&c->density, shell);
		for (int ch = 0; ch < 3; ch++) {
			m->ext[i][ch] = c->scattering_per_km[ch] + c->absorption_per_km[ch];
			m->majorant[ch] += m->ext[i][ch] * dmax;
		}
		for (int k = 0; k < 2; k++) {
			const struct atmo_layer *l = &c->density.layers[k];
			if (l->exp_term != 0.0 && l->exp_scale_per_km != 0.0)
				m->dh_max_km = fmin(m->dh_max_km, 2.0 / fabs(l->exp_scale_per_km));
			layer_kinks(m, l, shell);
		}
		add_kink(m, c->density.layers[0].width_km, shell);
	}
	for (int ch = 0; ch < 3; ch++) {
		/* Rounding in atmo_density must never exceed the majorant. */
		m->majorant[ch] *= 1.0 + 1e-9;
		m->albedo[ch] = a->ground_albedo[ch];
		m->illuminance[ch] = sun->illuminance[ch];
	}
	direction(sun->elevation_deg, sun->azimuth_deg, m->sun);
	basis(m->sun, m->sun_u, m->sun_v);
	double half = sun->angular_radius_deg * PI / 360.0;
	m->sun_one_minus_cos = 2.0 * sin(half) * sin(half);
}

/* ---- geometry ---- */

/* |x|^2 - r^2 without cancellation near the sphere. */
static double sphere_c(const double x[3], double r)
{
	double len = sqrt(dot(x, x));
	return (len - r) * (len + r);
}

/* Distance from x (inside the shell) along d to where the ray leaves it;
 * *ret_ground says whether that is the ground. A ray only meets the ground
 * while it goes down, which keeps rays that start on the ground off it. */
static double exit_distance(const struct medium *m, const double x[3], const double d[3],
			    int *ret_ground)
{
	double b = dot(x, d);
	if (b < 0.0) {
		double c = sphere_c(x, m->rb);
		if (c <= 0.0) {
			*ret_ground = 1;
			return 0.0;
		}
		double disc = b * b - c;
		if (disc >= 0.0) {
			*ret_ground = 1;
			return c / (-b + sqrt(disc));
		}
	}
	*ret_ground = 0;
	double c = sphere_c(x, m->rt);
	double s = sqrt(fmax(0.0, b * b - c));
	double t = b > 0.0 ? -c / (b + s) : -b + s;
	return t > 0.0 ? t : 0.0;
}

/* The view ray's stretch inside the shell, [*t0, *t1]; 0 if it misses. */
static int view_segment(const struct medium *m, const double o[3], const double d[3],
			double *t0, double *t1, int *ret_ground)
{
	*ret_ground = 0;
	if (sqrt(dot(o, o)) <= m->rt) {
		*t0 = 0.0;
		*t1 = exit_distance(m, o, d, ret_ground);
		return *t1 > 0.0 || *ret_ground;
	}
	double b = dot(o, d), c = sphere_c(o, m->rt), disc = b * b - c;
	if (disc <= 0.0 || b >= 0.0)
		return 0;
	double enter = c / (-b + sqrt(disc)), x[3];
	int g;
	axpy(o, enter, d, x);
	double len = exit_distance(m, x, d, &g);
	*t0 = enter;
	*t1 = enter + len;
	*ret_ground = g;
	return 1;
}

/* ---- quadrature cells along a ray ---- */

/* Walks [ta, tb] along o + t d in cells whose ends include the point closest
 * to the centre and the crossings of every kink altitude, each cell short
 * enough in altitude (dh_max, 1 km + 10 % of the altitude) and length
 * (20 km) for 8-point Gauss-Legendre to integrate the profiles to rounding. */
struct walk {
	const struct medium *m;
	const double *o, *d;
	double bp[MAX_BREAKS];
	int nbp, j;
	double t;
};

static void walk_init(struct walk *w, const struct medium *m, const double o[3],
		      const double d[3], double ta, double tb)
{
	w->m = m;
	w->o = o;
	w->d = d;
	w->nbp = 0;
	w->bp[w->nbp++] = ta;
	double tc = -dot(o, d);
	if (tc > ta && tc < tb)
		w->bp[w->nbp++] = tc;
	for (int k = 0; k < m->n_kinks && w->nbp < MAX_BREAKS - 3; k++) {
		double r = m->rb + m->kink_km[k], b = dot(o, d), c = sphere_c(o, r);
		double disc = b * b - c;
		if (disc <= 0.0)
			continue;
		double s = sqrt(disc);
		double roots[2] = { -b - s, -b + s };
		for (int i = 0; i < 2; i++)
			if (roots[i] > ta && roots[i] < tb)
				w->bp[w->nbp++] = roots[i];
	}
	w->bp[w->nbp++] = tb;
	for (int i = 1; i < w->nbp; i++)	/* insertion sort: a few entries */
		for (int k = i; k > 0 && w->bp[k] < w->bp[k - 1]; k--) {
			double tmp = w->bp[k];
			w->bp[k] = w->bp[k - 1];
			w->bp[k - 1] = tmp;
		}
	w->j = 0;
	w->t = ta;
}

static int walk_next(struct walk *w, double *ret_a, double *ret_b)
{
	while (w->j + 1 < w->nbp && w->t >= w->bp[w->j + 1])
		w->j++;
	if (w->j + 1 >= w->nbp)
		return 0;
	double x[3];
	axpy(w->o, w->t, w->d, x);
	double r = sqrt(dot(x, x)), h = r - w->m->rb;
	double mu = fabs(dot(x, w->d)) / r;
	double dh = fmin(1.0 + 0.1 * fmax(h, 0.0), w->m->dh_max_km);
	double step = mu > 0.0 ? fmin(20.0, dh / mu) : 20.0;
	double end = w->bp[w->j + 1];
	/* Avoid a sliver cell at the end of a piece. */
	double b = w->t + step > end - 0.25 * step ? end : w->t + step;
	*ret_a = w->t;
	*ret_b = b;
	w->t = b;
	return 1;
}

/* Optical depth per channel of the cell [a, b] along o + t d. */
static void cell_tau(const struct medium *m, const double o[3], const double d[3],
		     double a, double b, double ret[3])
{
	double mid = 0.5 * (a + b), half = 0.5 * (b - a), x[3];
	double rho[ATMO_MAX_CONSTITUENTS];
	ret[0] = ret[1] = ret[2] = 0.0;
	for (int k = 0; k < 8; k++) {
		double t = mid + (k < 4 ? -gl_x[k] : gl_x[k - 4]) * half;
		double w = gl_w[k & 3] * half;
		axpy(o, t, d, x);
		densities(m, x, rho);
		for (int i = 0; i < m->n; i++)
			for (int ch = 0; ch < 3; ch++)
				ret[ch] += w * m->ext[i][ch] * rho[i];
	}
}

/* Optical depth along the whole ray [ta, tb]. */
static void ray_tau(const struct medium *m, const double o[3], const double d[3],
		    double ta, double tb, double ret[3])
{
	struct walk w;
	double a, b, c[3];
	ret[0] = ret[1] = ret[2] = 0.0;
	walk_init(&w, m, o, d, ta, tb);
	while (walk_next(&w, &a, &b)) {
		cell_tau(m, o, d, a, b, c);
		for (int ch = 0; ch < 3; ch++)
			ret[ch] += c[ch];
	}
}

/* ---- phase functions (per steradian, normalised over the sphere) ---- */

static double phase(const struct atmo_constituent *c, double mu)
{
	double g = c->g, den;
	switch (c->phase) {
	case ATMO_PHASE_RAYLEIGH:
		return 3.0 / (16.0 * PI) * (1.0 + mu * mu);
	case ATMO_PHASE_HENYEY_GREENSTEIN:
		/* (1-g)^2 + 2g(1-mu): no cancellation at g -> 1. */
		den = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
		return (1.0 - g * g) / (4.0 * PI * den * sqrt(den));
	case ATMO_PHASE_CORNETTE_SHANKS:
		den = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
		return 3.0 / (8.0 * PI) * (1.0 - g * g) * (1.0 + mu * mu) /
		       ((2.0 + g * g) * den * sqrt(den));
	default:
		return 0.0;
	}
}

static double sample_hg(double g, double u)
{
	if (fabs(g) < 1e-6)
		return 2.0 * u - 1.0;
	double s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
	double mu = (1.0 + g * g - s * s) / (2.0 * g);
	return fmax(-1.0, fmin(1.0, mu));
}

/* Cosine of the scattering angle, drawn exactly from the phase function. */
static double sample_phase(const struct atmo_constituent *c, struct rng *r)
{
	switch (c->phase) {
	case ATMO_PHASE_RAYLEIGH: {
		/* Inverse of the CDF (mu^3 + 3 mu + 4) / 8 by Cardano. */
		double q = 4.0 * (2.0 * rnd(r) - 1.0), s = sqrt(0.25 * q * q + 1.0);
		return fmax(-1.0, fmin(1.0, cbrt(0.5 * q + s) + cbrt(0.5 * q - s)));
	}
	case ATMO_PHASE_CORNETTE_SHANKS:
		/* CS / HG is proportional to (1 + mu^2) / 2 <= 1: rejection. */
		for (;;) {
			double mu = sample_hg(c->g, rnd(r));
			if (rnd(r) * 2.0 < 1.0 + mu * mu)
				return mu;
		}
	case ATMO_PHASE_HENYEY_GREENSTEIN:
		return sample_hg(c->g, rnd(r));
	default:
		return 2.0 * rnd(r) - 1.0;	/* unreachable: no scattering */
	}
}

/* ---- transport ---- */

/* Ratio tracking: an unbiased estimate of the transmittance from x along d
 * to the edge of the shell, 0 if the ray meets the ground. */
static double transmittance(const struct medium *m, const double x[3], const double d[3],
			    int ch, struct rng *r)
{
	int ground;
	double te = exit_distance(m, x, d, &ground);
	if (ground)
		return 0.0;
	double maj = m->majorant[ch], T = 1.0, t = 0.0, p[3];
	if (maj <= 0.0)
		return 1.0;
	for (;;) {
		t -= log1p(-rnd(r)) / maj;
		if (t >= te)
			return T;
		axpy(x, t, d, p);
		T *= 1.0 - extinction(m, p, ch) / maj;
		if (T < 1e-3) {
			/* Roulette: a dim shadow ray is not worth finishing. */
			if (rnd(r) >= 0.25)
				return 0.0;
			T *= 4.0;
		}
	}
}

/* A direction uniform in solid angle over the sun's disk. */
static void sample_sun(const struct medium *m, struct rng *r, double ret[3])
{
	double v = rnd(r) * m->sun_one_minus_cos, cos_t = 1.0 - v;
	double sin_t = sqrt(fmax(0.0, v * (2.0 - v))), phi = 2.0 * PI * rnd(r);
	for (int i = 0; i < 3; i++)
		ret[i] = cos_t * m->sun[i] +
			 sin_t * (cos(phi) * m->sun_u[i] + sin(phi) * m->sun_v[i]);
}

/* Next-event estimate at a scattering point x reached along d: the sun's
 * radiance times its solid angle (the illuminance) times the phase function
 * mixture (sum sigma_s,i p_i / sigma_s) times the shadow ray. */
static double nee_medium(const struct medium *m, const double x[3], const double d[3],
			 const double rho[], double sigma_s, int ch, struct rng *r)
{
	double ws[3], p = 0.0;
	sample_sun(m, r, ws);
	double mu = dot(ws, d);
	for (int i = 0; i < m->n; i++)
		if (m->c[i].scattering_per_km[ch] > 0.0)
			p += m->c[i].scattering_per_km[ch] * rho[i] * phase(&m->c[i], mu);
	p /= sigma_s;
	if (p <= 0.0)
		return 0.0;
	return m->illuminance[ch] * p * transmittance(m, x, ws, ch, r);
}

/* Next-event estimate at a ground point x (on the sphere) with normal n. */
static double nee_ground(const struct medium *m, const double x[3], const double n[3],
			 int ch, struct rng *r)
{
	double ws[3];
	sample_sun(m, r, ws);
	double cos_s = dot(ws, n);
	if (cos_s <= 0.0 || m->albedo[ch] <= 0.0)
		return 0.0;
	return m->illuminance[ch] * m->albedo[ch] / PI * cos_s * transmittance(m, x, ws, ch, r);
}

static double scattering(const struct medium *m, const double rho[], int ch)
{
	double s = 0.0;
	for (int i = 0; i < m->n; i++)
		s += m->c[i].scattering_per_km[ch] * rho[i];
	return s;
}

/* New direction at a scattering point: pick a constituent in proportion to
 * its scattering, then draw from its phase function around d. */
static void scatter_dir(const struct medium *m, const double rho[], double sigma_s,
			const double d[3], int ch, struct rng *r, double ret[3])
{
	double u = rnd(r) * sigma_s, acc = 0.0;
	int pick = -1;
	for (int i = 0; i < m->n; i++) {
		double s = m->c[i].scattering_per_km[ch] * rho[i];
		if (s <= 0.0)
			continue;
		pick = i;
		acc += s;
		if (u < acc)
			break;
	}
	double mu = sample_phase(&m->c[pick], r);
	from_local(d, mu, 2.0 * PI * rnd(r), ret);
}

/* Radiance carried back to a vertex by every later order, per unit
 * throughput. At entry (x, d) is the vertex and the direction the path
 * arrived along; ground says whether x is on the ground (normal n). */
static double trace_on(const struct medium *m, const double x0[3], const double d0[3],
		       const double rho0[], double sigma_s0, int ground, int ch, struct rng *r)
{
	double x[3], d[3], nd[3], rho[ATMO_MAX_CONSTITUENTS], sigma_s = sigma_s0;
	double L = 0.0, w = 1.0;
	memcpy(x, x0, sizeof(x));
	memcpy(d, d0, sizeof(d));
	memcpy(rho, rho0, sizeof(double) * (size_t)m->n);

	for (int depth = 0;; depth++) {
		/* Leave the vertex. */
		if (ground) {
			double n[3], len = sqrt(dot(x, x));
			for (int i = 0; i < 3; i++)
				n[i] = x[i] / len;
			double u1 = rnd(r);
			from_local(n, sqrt(1.0 - u1), 2.0 * PI * rnd(r), nd);
			w *= m->albedo[ch];
		} else if (m->isotropic) {
			from_local(d, 2.0 * rnd(r) - 1.0, 2.0 * PI * rnd(r), nd);
		} else {
			scatter_dir(m, rho, sigma_s, d, ch, r, nd);
		}
		memcpy(d, nd, sizeof(d));

		/* Roulette on the throughput; no cap on the number of orders. */
		double q = fmin(1.0, w);
		if (depth > 64)
			q = fmin(q, 0.9);
		if (q < 1.0) {
			if (rnd(r) >= q)
				break;
			w /= q;
		}

		/* Delta tracking to the next real collision. */
		int hits_ground;
		double te = exit_distance(m, x, d, &hits_ground), t = 0.0, p[3];
		double maj = m->majorant[ch];
		int collided = 0;
		while (maj > 0.0) {
			t -= log1p(-rnd(r)) / maj;
			if (t >= te)
				break;
			axpy(x, t, d, p);
			densities(m, p, rho);
			double st = 0.0;
			for (int i = 0; i < m->n; i++)
				st += m->ext[i][ch] * rho[i];
			if (rnd(r) * maj < st) {
				sigma_s = scattering(m, rho, ch);
				w *= sigma_s / st;
				collided = 1;
				break;
			}
		}
		if (collided) {
			memcpy(x, p, sizeof(x));
			ground = 0;
			if (sigma_s <= 0.0)
				break;
			L += w * nee_medium(m, x, d, rho, sigma_s, ch, r);
		} else if (hits_ground) {
			axpy(x, te, d, p);
			double s = m->rb / sqrt(dot(p, p)), n[3];
			for (int i = 0; i < 3; i++) {
				x[i] = p[i] * s;
				n[i] = x[i] / m->rb;
			}
			ground = 1;
			if (m->albedo[ch] <= 0.0)
				break;
			L += w * nee_ground(m, x, n, ch, r);
		} else {
			break;	/* escaped: the sun is counted by NEE only */
		}
	}
	return L;
}

/* ---- per-direction view-ray tables ---- */

void pt_view_free(struct view *v)
{
	free(v->t);
	for (int ch = 0; ch < 3; ch++)
		free(v->tau[ch]);
	memset(v, 0, sizeof(*v));
}

/* Builds the sunlit proposal from the optical-depth table and one shadow ray
 * to the sun's centre per group: a guide only, its pdf is evaluated exactly
 * as sampled, so its accuracy changes the noise, never the mean. */
static void view_sunlit(struct view *v, const struct medium *m)
{
	int per = (v->n + GROUPS - 1) / GROUPS;
	double rho[ATMO_MAX_CONSTITUENTS];
	v->ng = 0;
	v->gt[0] = v->t[0];
	for (int ch = 0; ch < 3; ch++)
		v->gcdf[ch][0] = 0.0;
	for (int k0 = 0; k0 < v->n; k0 += per) {
		int k1 = k0 + per < v->n ? k0 + per : v->n, g = v->ng++;
		double a = v->t[k0], b = v->t[k1], mid = 0.5 * (a + b), x[3], tau_s[3];
		int kc = k0;
		while (kc + 1 < k1 && v->t[kc + 1] <= mid)
			kc++;
		axpy(v->o, mid, v->d, x);
		densities(m, x, rho);
		int ground;
		double te = exit_distance(m, x, m->sun, &ground);
		if (!ground)
			ray_tau(m, x, m->sun, 0.0, te, tau_s);
		v->gt[g + 1] = b;
		for (int ch = 0; ch < 3; ch++) {
			double s = (v->tau[ch][kc + 1] - v->tau[ch][kc]) / (v->t[kc + 1] - v->t[kc]);
			double tau_v = v->tau[ch][kc] + s * (mid - v->t[kc]);
			double w = ground ? 0.0 : (b - a) * scattering(m, rho, ch) *
						  exp(-tau_v - tau_s[ch]);
			v->gcdf[ch][g + 1] = v->gcdf[ch][g] + w;
		}
	}
}

int pt_view_build(struct view *v, const struct medium *m, double altitude_km,
		  const struct pt_dir *dir)
{
	memset(v, 0, sizeof(*v));
	v->o[2] = m->rb + (altitude_km > 0.0 ? altitude_km : 0.0);
	direction(dir->elevation_deg, dir->azimuth_deg, v->d);
	if (!view_segment(m, v->o, v->d, &v->t0, &v->t1, &v->ground) || !(v->t1 > v->t0)) {
		v->t0 = v->t1 = 0.0;
		return 0;	/* nothing to scatter: radiance 0 */
	}
	int cap = 64;
	struct walk w;
	double a, b, c[3];
	v->t = malloc(sizeof(double) * (size_t)(cap + 1));
	for (int ch = 0; ch < 3; ch++)
		v->tau[ch] = malloc(sizeof(double) * (size_t)(cap + 1));
	if (!v->t || !v->tau[0] || !v->tau[1] || !v->tau[2])
		goto oom;
	v->t[0] = v->t0;
	v->tau[0][0] = v->tau[1][0] = v->tau[2][0] = 0.0;
	walk_init(&w, m, v->o, v->d, v->t0, v->t1);
	while (walk_next(&w, &a, &b)) {
		if (v->n == cap) {
			cap *= 2;
			double *nt = realloc(v->t, sizeof(double) * (size_t)(cap + 1));
			if (!nt)
				goto oom;
			v->t = nt;
			for (int ch = 0; ch < 3; ch++) {
				double *p = realloc(v->tau[ch], sizeof(double) * (size_t)(cap + 1));
				if (!p)
					goto oom;
				v->tau[ch] = p;
			}
		}
		cell_tau(m, v->o, v->d, a, b, c);
		v->n++;
		v->t[v->n] = b;
		for (int ch = 0; ch < 3; ch++)
			v->tau[ch][v->n] = v->tau[ch][v->n - 1] + c[ch];
	}
	view_sunlit(v, m);
	return 0;
oom:
	pt_view_free(v);
	return -ENOMEM;
}

/* Cell holding t: the last k with t[k] <= t. */
static int view_cell(const struct view *v, double t)
{
	int lo = 0, hi = v->n - 1;
	while (lo < hi) {
		int mid = (lo + hi + 1) / 2;
		if (v->t[mid] <= t)
			lo = mid;
		else
			hi = mid - 1;
	}
	return lo;
}

static double sample_air(const struct medium *m, const struct view *v, enum pt_mode mode,
			 int ch, struct rng *r);

/* Radiance estimate of one sample of one channel along a view ray: the air,
 * and in PT_GROUND the ground the ray ends on, seen through the air. */
double pt_sample_view(const struct medium *m, const struct view *v, enum pt_mode mode,
		      int ch, struct rng *r)
{
	double L = 0.0, rho[ATMO_MAX_CONSTITUENTS] = { 0 };
	if (v->n > 0)
		L += sample_air(m, v, mode, ch, r);
	if (mode == PT_GROUND && v->ground && m->albedo[ch] > 0.0) {
		double g[3], n[3];
		axpy(v->o, v->t1, v->d, g);
		double s = m->rb / sqrt(dot(g, g));
		for (int i = 0; i < 3; i++) {
			g[i] *= s;
			n[i] = g[i] / m->rb;
		}
		double Tg = v->n > 0 ? exp(-v->tau[ch][v->n]) : 1.0;
		L += Tg * nee_ground(m, g, n, ch, r);
		L += Tg * trace_on(m, g, v->d, rho, 0.0, 1, ch, r);
	}
	return L;
}

/* The light scattered by the air along the view ray. */
static double sample_air(const struct medium *m, const struct view *v, enum pt_mode mode,
			 int ch, struct rng *r)
{
	double L = 0.0, rho[ATMO_MAX_CONSTITUENTS], x[3];

	/* The first scattering point: proposal = DEFENSIVE uniform + SUNLIT
	 * groups weighted by the lit air + the piecewise-exponential fit of
	 * sigma_t T on the table; the pdf is the mixture's, whichever drew t. */
	double len = v->t1 - v->t0, tau_tot = v->tau[ch][v->n];
	double p_col = -expm1(-tau_tot), t;
	double share = p_col > 0.0 ? DEFENSIVE : 1.0;
	double w_lit = v->gcdf[ch][v->ng];
	double lit = w_lit > 0.0 && p_col > 0.0 ? SUNLIT : 0.0;
	double u = rnd(r);
	int k;
	if (u < share) {
		t = v->t0 + rnd(r) * len;
		k = view_cell(v, t);
	} else if (u < share + lit) {
		double target = rnd(r) * w_lit;
		int g = 0;
		while (g < v->ng - 1 && v->gcdf[ch][g + 1] <= target)
			g++;
		t = v->gt[g] + rnd(r) * (v->gt[g + 1] - v->gt[g]);
		k = view_cell(v, t);
	} else {
		double target = -log1p(-rnd(r) * p_col);
		int lo = 0, hi = v->n - 1;	/* last k with tau[k] <= target < tau[k+1] */
		while (lo < hi) {
			int mid = (lo + hi + 1) / 2;
			if (v->tau[ch][mid] <= target)
				lo = mid;
			else
				hi = mid - 1;
		}
		k = lo;
		while (k < v->n - 1 && !(v->tau[ch][k + 1] > v->tau[ch][k]))
			k++;
		double s = (v->tau[ch][k + 1] - v->tau[ch][k]) / (v->t[k + 1] - v->t[k]);
		t = s > 0.0 ? v->t[k] + (target - v->tau[ch][k]) / s : v->t[k];
		t = fmin(fmax(t, v->t[k]), v->t[k + 1]);
	}
	double pdf = share / len;
	if (p_col > 0.0) {
		double s = (v->tau[ch][k + 1] - v->tau[ch][k]) / (v->t[k + 1] - v->t[k]);
		double tau_fit = v->tau[ch][k] + s * (t - v->t[k]);
		pdf += (1.0 - share - lit) * s * exp(-tau_fit) / p_col;
	}
	if (lit > 0.0) {
		int g = 0;	/* the group holding t, as sampled: gt[g] <= t < gt[g+1] */
		while (g < v->ng - 1 && v->gt[g + 1] <= t)
			g++;
		double wg = v->gcdf[ch][g + 1] - v->gcdf[ch][g];
		pdf += lit * wg / (w_lit * (v->gt[g + 1] - v->gt[g]));
	}

	/* The view ray's transmittance to t: table plus the partial cell. */
	double part[3];
	cell_tau(m, v->o, v->d, v->t[k], t, part);
	double T = exp(-(v->tau[ch][k] + part[ch]));

	axpy(v->o, t, v->d, x);
	densities(m, x, rho);
	double sigma_s = scattering(m, rho, ch);
	if (sigma_s > 0.0 && pdf > 0.0) {
		double W = T * sigma_s / pdf;
		if (!m->multi_only)
			L += W * nee_medium(m, x, v->d, rho, sigma_s, ch, r);
		if (mode != PT_SINGLE)
			L += W * trace_on(m, x, v->d, rho, sigma_s, 0, ch, r);
	}
	return L;
}

/* ---- arguments ---- */

int pt_check_args(const struct atmo *a, const struct pt_sun *sun)
{
	char err[256];
	if (!a || !sun || atmo_validate(a, err, sizeof(err)) < 0)
		return -EINVAL;
	if (!(sun->angular_radius_deg > 0.0 && sun->angular_radius_deg < 90.0) ||
	    !isfinite(sun->elevation_deg) || !isfinite(sun->azimuth_deg))
		return -EINVAL;
	for (int ch = 0; ch < 3; ch++)
		if (!isfinite(sun->illuminance[ch]) || sun->illuminance[ch] < 0.0)
			return -EINVAL;
	return 0;
}

/* ---- the deterministic single-scattering reference ---- */

/* 4-point Gauss-Legendre on [0, 1] for the disk's 1 - cos. */
static const double gl4_x[4] = { 0.0694318442029737, 0.3300094782075719,
				 0.6699905217924281, 0.9305681557970263 };
static const double gl4_w[4] = { 0.1739274225687269, 0.3260725774312731,
				 0.3260725774312731, 0.1739274225687269 };
#define DISK_PHI 8

/* E * sum_i sigma_s,i rho_i <p_i(w.d) T(x, w)>_disk at one point. */
static void ss_source(const struct medium *m, const double x[3], const double d[3],
		      const double rho[], double ret[3])
{
	ret[0] = ret[1] = ret[2] = 0.0;
	for (int a = 0; a < 4; a++) {
		double v = gl4_x[a] * m->sun_one_minus_cos, cos_t = 1.0 - v;
		double sin_t = sqrt(fmax(0.0, v * (2.0 - v)));
		for (int b = 0; b < DISK_PHI; b++) {
			double phi = 2.0 * PI * (b + 0.5) / DISK_PHI, w[3];
			for (int i = 0; i < 3; i++)
				w[i] = cos_t * m->sun[i] +
				       sin_t * (cos(phi) * m->sun_u[i] + sin(phi) * m->sun_v[i]);
			int ground;
			double te = exit_distance(m, x, w, &ground), tau[3];
			if (ground)
				continue;
			ray_tau(m, x, w, 0.0, te, tau);
			double mu = dot(w, d);
			for (int ch = 0; ch < 3; ch++) {
				double s = 0.0;
				for (int i = 0; i < m->n; i++)
					s += m->c[i].scattering_per_km[ch] * rho[i] * phase(&m->c[i], mu);
				ret[ch] += gl4_w[a] / DISK_PHI * s * exp(-tau[ch]);
			}
		}
	}
	for (int ch = 0; ch < 3; ch++)
		ret[ch] *= m->illuminance[ch];
}

int pt_single_scatter_reference(const struct atmo *a, double altitude_km,
				const struct pt_sun *sun, const struct pt_dir *dir,
				double ret_radiance[3])
{
	struct medium m;
	double o[3] = { 0 }, d[3], t0, t1, L[3] = { 0 };
	int ground, r = pt_check_args(a, sun);

	if (r < 0 || !dir || !ret_radiance || !isfinite(altitude_km))
		return -EINVAL;
	pt_medium_init(&m, a, sun);
	o[2] = m.rb + (altitude_km > 0.0 ? altitude_km : 0.0);
	direction(dir->elevation_deg, dir->azimuth_deg, d);
	if (view_segment(&m, o, d, &t0, &t1, &ground) && t1 > t0) {
		struct walk w;
		double ca, cb, tau_a[3] = { 0 };
		walk_init(&w, &m, o, d, t0, t1);
		while (walk_next(&w, &ca, &cb)) {
			double mid = 0.5 * (ca + cb), half = 0.5 * (cb - ca);
			for (int k = 0; k < 8; k++) {
				double t = mid + (k < 4 ? -gl_x[k] : gl_x[k - 4]) * half;
				double part[3], x[3], rho[ATMO_MAX_CONSTITUENTS], s[3];
				cell_tau(&m, o, d, ca, t, part);
				axpy(o, t, d, x);
				densities(&m, x, rho);
				ss_source(&m, x, d, rho, s);
				for (int ch = 0; ch < 3; ch++)
					L[ch] += gl_w[k & 3] * half * exp(-(tau_a[ch] + part[ch])) * s[ch];
			}
			double c[3];
			cell_tau(&m, o, d, ca, cb, c);
			for (int ch = 0; ch < 3; ch++)
				tau_a[ch] += c[ch];
		}
	}
	memcpy(ret_radiance, L, sizeof(L));
	return 0;
}


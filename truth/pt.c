/* pt.c - the estimator of pt.h's Monte Carlo path tracer (one sample of one
 * channel along a view ray); its medium and transport primitives are
 * pt_media.c, its deterministic references pt_ref.c, the driver that runs
 * it pt_render.c.
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
 * every clamped exponential-plus-linear layer found analytically, plus
 * inside each cloud layer's shell its extinction per km (the density of
 * proto/skycloud.h never exceeds it).
 *
 * Clouds scatter with their type's albedo and Henyey-Greenstein phase,
 * chosen beside the air's constituents in proportion to their scattering;
 * the terrain is a Lambertian surface of the ground's albedo, met by
 * marching its height field (proto/skyterrain.h) before the free path is
 * sampled. The tables' view ray (PT_VIEW_AIR) draws its first vertex in
 * the air alone, as above; PT_VIEW_ALL draws it by delta tracking.
 */
#include "pt_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DEFENSIVE 0.1		/* share of the uniform proposal on the view ray */
#define SUNLIT 0.3		/* share of the proposal that follows the sunlit air */

/* ---- phase functions (per steradian, normalised over the sphere) ---- */

double pt_phase(const struct atmo_constituent *c, double mu)
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

/* Henyey-Greenstein, per steradian: (1-g)^2 + 2g(1-mu), no cancellation
 * at g -> 1. */
static double hg(double g, double mu)
{
	double den = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
	return (1.0 - g * g) / (4.0 * PI * den * sqrt(den));
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

double pt_phase_mix(const struct medium *m, const double rho[], double sigma_s, double mu, int ch)
{
	double p = 0.0;
	for (int i = 0; i < m->n; i++)
		if (m->c[i].scattering_per_km[ch] > 0.0)
			p += m->c[i].scattering_per_km[ch] * rho[i] * pt_phase(&m->c[i], mu);
	for (int i = 0; i < m->n_layers; i++)
		if (rho[CLOUD_SLOT(i)] > 0.0)
			p += m->layer_albedo[i] * rho[CLOUD_SLOT(i)] * hg(m->layer_g[i], mu);
	return p / sigma_s;
}

/* Next-event estimate at a scattering point x reached along d: the sun's
 * radiance times its solid angle (the illuminance) times the phase function
 * mixture (sum sigma_s,i p_i / sigma_s) times the shadow ray. */
static double nee_medium(const struct medium *m, const double x[3], const double d[3],
			 const double rho[], double sigma_s, int ch, struct rng *r)
{
	double ws[3];
	sample_sun(m, r, ws);
	double p = pt_phase_mix(m, rho, sigma_s, dot(ws, d), ch);
	if (p <= 0.0)
		return 0.0;
	return m->illuminance[ch] * p * pt_transmittance(m, x, ws, ch, r);
}

/* Next-event estimate at a ground point x (the sphere's or the terrain's)
 * with normal n. */
static double nee_ground(const struct medium *m, const double x[3], const double n[3],
			 int ch, struct rng *r)
{
	double ws[3];
	sample_sun(m, r, ws);
	double cos_s = dot(ws, n);
	if (cos_s <= 0.0 || m->albedo[ch] <= 0.0)
		return 0.0;
	return m->illuminance[ch] * m->albedo[ch] / PI * cos_s * pt_transmittance(m, x, ws, ch, r);
}

/* New direction at a scattering point: pick an air constituent or a cloud
 * layer in proportion to its scattering, then draw from its phase function
 * around d. */
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
	for (int i = 0; i < m->n_layers && !(u < acc && pick >= 0); i++) {
		double s = m->layer_albedo[i] * rho[CLOUD_SLOT(i)];
		if (s <= 0.0)
			continue;
		pick = CLOUD_SLOT(i);
		acc += s;
	}
	double mu = pick >= CLOUD_SLOT(0) ? sample_hg(m->layer_g[pick - CLOUD_SLOT(0)], rnd(r))
					  : sample_phase(&m->c[pick], r);
	pt_from_local(d, mu, 2.0 * PI * rnd(r), ret);
}

/* Paths through clouds (albedo 1) end by leaving them, after some hundred
 * orders under an overcast; the clear sky's air is held to this many
 * orders before its roulette tightens. */
#define ORDERS_FREE 64
#define ORDERS_FREE_CLOUDS 4096

/* Radiance carried back to a vertex by every later order, per unit
 * throughput. At entry (x, d) is the vertex and the direction the path
 * arrived along; ground says whether x is on a surface, of normal n0. */
static double trace_on(const struct medium *m, const double x0[3], const double d0[3],
		       const double rho0[], double sigma_s0, int ground, const double n0[3], int ch,
		       struct rng *r)
{
	double x[3], d[3], n[3], nd[3], rho[PT_MEDIA], sigma_s = sigma_s0;
	double L = 0.0, w = 1.0;
	struct pt_hit h;
	int free_orders = m->n_layers ? ORDERS_FREE_CLOUDS : ORDERS_FREE;
	memcpy(x, x0, sizeof(x));
	memcpy(d, d0, sizeof(d));
	memcpy(rho, rho0, sizeof(rho));
	if (ground)
		memcpy(n, n0, sizeof(n));

	for (int depth = 0;; depth++) {
		/* Leave the vertex. */
		if (ground) {
			double u1 = rnd(r);
			pt_from_local(n, sqrt(1.0 - u1), 2.0 * PI * rnd(r), nd);
			w *= m->albedo[ch];
		} else if (m->isotropic) {
			pt_from_local(d, 2.0 * rnd(r) - 1.0, 2.0 * PI * rnd(r), nd);
		} else {
			scatter_dir(m, rho, sigma_s, d, ch, r, nd);
		}
		memcpy(d, nd, sizeof(d));

		/* Roulette on the throughput; no cap on the number of orders. */
		double q = fmin(1.0, w);
		if (depth > free_orders)
			q = fmin(q, 0.9);
		if (q < 1.0) {
			if (rnd(r) >= q)
				break;
			w /= q;
		}

		enum pt_event e = pt_fly(m, x, d, ch, r, &h);
		if (e == PT_COLLIDE) {
			memcpy(x, h.p, sizeof(x));
			memcpy(rho, h.rho, sizeof(rho));
			sigma_s = pt_sigma_s(m, rho, ch);
			w *= sigma_s / h.sigma_t;
			ground = 0;
			if (sigma_s <= 0.0)
				break;
			L += w * nee_medium(m, x, d, rho, sigma_s, ch, r);
		} else if (e == PT_SURFACE) {
			memcpy(x, h.p, sizeof(x));
			memcpy(n, h.normal, sizeof(n));
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

/* PT_VIEW_ALL: the eye's ray, its first vertex by delta tracking through
 * everything, ending on a surface (whose own light PT_GROUND adds). */
static double sample_eye(const struct medium *m, const struct view *v, enum pt_mode mode, int ch,
			 struct rng *r)
{
	struct pt_hit h;
	enum pt_event e = pt_fly(m, v->o, v->d, ch, r, &h);

	if (e == PT_COLLIDE) {
		double sigma_s = pt_sigma_s(m, h.rho, ch);
		if (!(sigma_s > 0.0))
			return 0.0;
		double w = sigma_s / h.sigma_t, L = 0.0;
		if (!m->multi_only)
			L += w * nee_medium(m, h.p, v->d, h.rho, sigma_s, ch, r);
		if (mode != PT_SINGLE)
			L += w * trace_on(m, h.p, v->d, h.rho, sigma_s, 0, NULL, ch, r);
		return L;
	}
	if (e == PT_SURFACE && mode == PT_GROUND && m->albedo[ch] > 0.0) {
		double none[PT_MEDIA] = { 0 };
		return nee_ground(m, h.p, h.normal, ch, r) +
		       trace_on(m, h.p, v->d, none, 0.0, 1, h.normal, ch, r);
	}
	return 0.0;
}

/* ---- per-direction view-ray tables ---- */

void pt_view_free(struct view *v)
{
	free(v->t);
	for (int ch = 0; ch < 3; ch++)
		free(v->tau[ch]);
	memset(v, 0, sizeof(*v));
}

/* What the air alone holds at x: the tables' view ray sees no cloud. */
static void air_only(const struct medium *m, const double x[3], double rho[])
{
	pt_densities(m, x, rho);
	for (int i = 0; i < m->n_layers; i++)
		rho[CLOUD_SLOT(i)] = 0.0;
}

/* Builds the sunlit proposal from the optical-depth table and one shadow ray
 * to the sun's centre per group: a guide only, its pdf is evaluated exactly
 * as sampled, so its accuracy changes the noise, never the mean. */
static void view_sunlit(struct view *v, const struct medium *m)
{
	int per = (v->n + GROUPS - 1) / GROUPS;
	double rho[PT_MEDIA];
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
		air_only(m, x, rho);
		int ground;
		double te = pt_exit_distance(m, x, m->sun, &ground), th, shade = 1.0;
		if (!ground)
			pt_ray_tau(m, x, m->sun, 0.0, te, tau_s);
		/* The scene's shadow at the group's middle, the guide's only. */
		if (!ground && pt_terrain_hit(m, x, m->sun, te, &th))
			shade = 0.0;
		else if (!ground && m->n_layers)
			shade = exp(-pt_cloud_tau(m, x, m->sun, te, 64));
		v->gt[g + 1] = b;
		for (int ch = 0; ch < 3; ch++) {
			double s = (v->tau[ch][kc + 1] - v->tau[ch][kc]) / (v->t[kc + 1] - v->t[kc]);
			double tau_v = v->tau[ch][kc] + s * (mid - v->t[kc]);
			double w = ground ? 0.0 : (b - a) * pt_sigma_s(m, rho, ch) * shade *
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
	pt_direction(dir->elevation_deg, dir->azimuth_deg, v->d);
	if (!pt_view_segment(m, v->o, v->d, &v->t0, &v->t1, &v->ground) || !(v->t1 > v->t0)) {
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
	pt_walk_init(&w, m, v->o, v->d, v->t0, v->t1);
	while (pt_walk_next(&w, &a, &b)) {
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
		pt_cell_tau(m, v->o, v->d, a, b, c);
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
 * and in PT_GROUND the ground the ray ends on, seen through the air; or,
 * PT_VIEW_ALL, what the eye sees. */
double pt_sample_view(const struct medium *m, const struct view *v, enum pt_mode mode,
		      int ch, struct rng *r)
{
	double L = 0.0, rho[PT_MEDIA] = { 0 };
	if (m->view == PT_VIEW_ALL)
		return v->t1 > v->t0 ? sample_eye(m, v, mode, ch, r) : 0.0;
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
		L += Tg * trace_on(m, g, v->d, rho, 0.0, 1, n, ch, r);
	}
	return L;
}

/* The light scattered by the air along the view ray. */
static double sample_air(const struct medium *m, const struct view *v, enum pt_mode mode,
			 int ch, struct rng *r)
{
	double L = 0.0, rho[PT_MEDIA], x[3];

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
	pt_cell_tau(m, v->o, v->d, v->t[k], t, part);
	double T = exp(-(v->tau[ch][k] + part[ch]));

	axpy(v->o, t, v->d, x);
	air_only(m, x, rho);
	double sigma_s = pt_sigma_s(m, rho, ch);
	if (sigma_s > 0.0 && pdf > 0.0) {
		double W = T * sigma_s / pdf;
		if (!m->multi_only)
			L += W * nee_medium(m, x, v->d, rho, sigma_s, ch, r);
		if (mode != PT_SINGLE)
			L += W * trace_on(m, x, v->d, rho, sigma_s, 0, NULL, ch, r);
	}
	return L;
}


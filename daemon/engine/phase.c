/* phase.c - what the engine derives from the constituents' phase functions
 * at run time: Legendre moments, the ground's first bounce, the constituent
 * that carries the lobe, delta-M's truncation and peak. */
#include "phase.h"

#include <math.h>
#include <stdbool.h>

#include "skymap.h"

double phase_value(enum atmo_phase kind, double g, double mu)
{
	if (kind == ATMO_PHASE_RAYLEIGH)
		return 3.0 / (16.0 * SKYMAP_PI) * (1.0 + mu * mu);
	double den = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
	double hg = (1.0 - g * g) / (4.0 * SKYMAP_PI * den * sqrt(den));
	if (kind == ATMO_PHASE_HENYEY_GREENSTEIN)
		return hg;
	return hg * 1.5 * (1.0 + mu * mu) / (2.0 + g * g);
}

/* Nodes of phase_legendre's quadrature. */
#define LEGENDRE_NODES 8192

double phase_legendre(enum atmo_phase kind, double g, int l)
{
	if (kind == ATMO_PHASE_NONE || l < 0)
		return 0.0;
	if (l == 0)
		return 1.0;	/* the phases are normalised to 1 over the sphere */
	if (kind == ATMO_PHASE_RAYLEIGH)
		return l == 2 ? 0.1 : 0.0;	/* 3/4 (1 + c^2) = P0 + P2 / 2 */
	if (kind == ATMO_PHASE_HENYEY_GREENSTEIN)
		return pow(g, l);
	/* 2 pi times the integral of p(c) P_l(c) over [-1, 1], with the
	 * nodes crowded at the peak: c = +-(1 - 2 u^4), dc = 8 u^3 du, which
	 * puts dozens of them inside a g = 0.99 peak ((1 - c) ~ 1e-4); P_l by
	 * its recurrence. */
	double sum = 0.0, peak = g < 0.0 ? -1.0 : 1.0;
	for (int n = 0; n < LEGENDRE_NODES; n++) {
		double u = (n + 0.5) / LEGENDRE_NODES, u2 = u * u, c = peak * (1.0 - 2.0 * u2 * u2);
		double p0 = 1.0, p1 = c;
		for (int k = 2; k <= l; k++) {
			double p2 = ((2 * k - 1) * c * p1 - (k - 1) * p0) / k;
			p0 = p1;
			p1 = p2;
		}
		sum += phase_value(kind, g, c) * p1 * 8.0 * u2 * u;
	}
	return 2.0 * SKYMAP_PI * sum / LEGENDRE_NODES;
}

/* phase_moment_constituent's threshold on |g1| tau: Earth's Mie
 * (0.0048 x 0.8) is far below it, Mars' dust (0.17 x 0.88) far above. */
#define MOMENT_AUTO_MIN 0.02

int phase_moment_constituent(const struct sky_state *s, const double *g1_of)
{
	const struct atmo *a = &s->atmo;
	double shell = a->top_radius_km - a->bottom_radius_km, best_steered = 0.0;
	int best = -1;
	/* Two directions (up and down) see no shape, only T_zz = 1, and band
	 * 2 would take all the light for vertical: horizontal views dark. */
	if (s->quality.multiscatter_moment == STATE_MOMENT_OFF || s->quality.multiscatter_dirs < 64)
		return -1;
	for (int n = 0; n < a->n_constituents; n++) {
		const struct atmo_constituent *k = &a->c[n];
		double g1 = fabs(g1_of ? g1_of[n] : phase_legendre(k->phase, k->g, 1)), tau = 0.0;
		if (g1 == 0.0 || k->scattering_per_km[1] <= 0.0)
			continue;
		for (int i = 0; i < 256; i++)
			tau += atmo_density(&k->density, (i + 0.5) / 256 * shell) * shell / 256;
		double steered = g1 * tau * k->scattering_per_km[1];
		if (best < 0 || steered > best_steered) {
			best = n;
			best_steered = steered;
		}
	}
	if (s->quality.multiscatter_moment == STATE_MOMENT_AUTO && best_steered < MOMENT_AUTO_MIN)
		return -1;
	return best;
}

int phase_delta_constituent(const struct sky_state *s, const double *g1_of)
{
	struct sky_state t;
	/* Not where the neighbourhood iteration runs (msiterate.comp): it
	 * transports psi through the real medium, and the two together
	 * disagree with the model (test_engine); forced on, the pair reads
	 * thick atmospheres better, so it is worth making consistent one day
	 * (docs/findings/shaders.md). */
	if (s->quality.multiscatter_delta == STATE_MOMENT_OFF || state_multiscatter_iterations(s) > 0)
		return -1;
	t = *s;
	t.quality.multiscatter_moment = s->quality.multiscatter_delta;
	int n = phase_moment_constituent(&t, g1_of);
	/* A backward peak is no forward one: the truncation would give
	 * |g'| > 1 (a negative phase, negative light). */
	if (n >= 0 && !((g1_of ? g1_of[n] : phase_legendre(s->atmo.c[n].phase, s->atmo.c[n].g, 1)) > 0.0))
		return -1;
	return n;
}

/* The Rayleigh constituent that scatters most (green, at the ground), or
 * -1: where no forward lobe steers the light, the field's band 2 (its
 * brightness toward the horizon) still matters to every phase's g2, and a
 * lobe of g1 = 0 carries it (ms_source, forward_scattering). */
static int rayleigh_constituent(const struct atmo *a)
{
	int best = -1;
	for (int n = 0; n < a->n_constituents; n++)
		if (a->c[n].phase == ATMO_PHASE_RAYLEIGH && a->c[n].scattering_per_km[1] > 0.0 &&
		    (best < 0 || a->c[n].scattering_per_km[1] > a->c[best].scattering_per_km[1]))
			best = n;
	return best;
}

int phase_lobe_constituent(const struct sky_state *s, const double *g1_of)
{
	int delta = phase_delta_constituent(s, g1_of);
	if (delta >= 0 && s->quality.multiscatter_moment == STATE_MOMENT_OFF)
		return -1;
	int lobe = phase_moment_constituent(s, g1_of);
	if (lobe < 0 && s->quality.multiscatter_moment == STATE_MOMENT_AUTO &&
	    s->quality.multiscatter_dirs >= 64)
		lobe = rayleigh_constituent(&s->atmo);
	return delta >= 0 && lobe != delta ? -1 : lobe;
}

void phase_delta_truncation(enum atmo_phase kind, double g, double *ret_f, double *ret_g)
{
	double f = phase_legendre(kind, g, PHASE_DELTA_ORDER), g1 = phase_legendre(kind, g, 1);
	/* 0 <= f <= g1 keeps g' in [0, g1]; a forward-peaked phase has it. */
	f = f < 0.0 || !(g1 > 0.0) ? 0.0 : f > g1 ? g1 : f;
	*ret_f = f;
	*ret_g = f < 1.0 ? (g1 - f) / (1.0 - f) : 0.0;
}

void phase_delta_peak(enum atmo_phase kind, double g, double *ret_h, double *ret_spread_rad)
{
	double f, gp;
	phase_delta_truncation(kind, g, &f, &gp);
	*ret_h = 1.0;
	*ret_spread_rad = 0.0;
	if (!(f > 0.0))
		return;
	double p2 = (phase_legendre(kind, g, 2) - (1.0 - f) * gp * gp) / f;
	double pn = (f - (1.0 - f) * pow(gp, PHASE_DELTA_ORDER)) / f;
	*ret_h = pn > 0.0 ? pow(fmin(pn, 1.0), 1.0 / PHASE_DELTA_ORDER) : 0.0;
	*ret_spread_rad = sqrt(fmax(2.0 / 3.0 * (1.0 - p2), 0.0));
}

double phase_delta_peak_phase(enum atmo_phase kind, double g, double h, double spread_rad, double tau,
			      double mu_l, double mu)
{
	double n = tau < 1e-4 ? 1.0 + 0.5 * tau : tau / (1.0 - exp(-tau));
	double above = 1.0 / (1.0 + exp(-1.702 * asin(fmax(-1.0, fmin(1.0, mu_l))) / fmax(spread_rad * sqrt(n), 1e-6)));
	return above * phase_value(kind, g * pow(h, n), mu);
}

/* Quadrature of phase_ground_excess: midpoints in u with c = 1 - 2 u^2, which
 * crowds the nodes at the forward peak (g = 0.99: 1 - c ~ 1e-4 holds several
 * of them), mirrored for a backward peak (g < 0). */
#define GROUND_NODES 1024

/* k(mu) of phase_ground_excess for mu >= 0 as a single integral over the
 * scattering cosine c between upwelling light d and w = -view: of the
 * directions at cosine c from w, those with d_z > 0 span the azimuths where
 * s_c s_v cos(phi) > c mu (s the sines), 2 acos(c mu / (s_c s_v)) of 2 pi. */
static double ground_k(enum atmo_phase kind, double g, double mu)
{
	double sv = skymap_safe_sqrt(1.0 - mu * mu), sum = 0.0, peak = g < 0.0 ? -1.0 : 1.0;
	for (int n = 0; n < GROUND_NODES; n++) {
		double u = (n + 0.5) / GROUND_NODES, c = peak * (1.0 - 2.0 * u * u);
		double sc = 2.0 * u * sqrt(1.0 - u * u);	/* sqrt(1 - c^2) */
		double den = sc * sv, span;
		if (c * mu >= den)
			span = 0.0;
		else if (c * mu <= -den)
			span = 2.0 * SKYMAP_PI;
		else
			span = 2.0 * acos(c * mu / den);
		sum += phase_value(kind, g, c) * span * 4.0 * u;	/* dc = 4 u du */
	}
	return 2.0 * sum / GROUND_NODES;
}

void phase_ground_excess(enum atmo_phase kind, double g, double ret_excess[PHASE_GROUND_N])
{
	for (int i = 0; i < PHASE_GROUND_N; i++) {
		/* The isotropic phase is exactly isotropic over any hemisphere and
		 * Rayleigh's (1 + c^2) too (the mean of c^2 over a hemisphere is 1/3
		 * about any axis): 0 without quadrature noise. */
		double k = kind == ATMO_PHASE_NONE || kind == ATMO_PHASE_RAYLEIGH
				   ? 1.0 : ground_k(kind, g, (double)i / (PHASE_GROUND_N - 1));
		/* k(0) = 1 by symmetry; the clamp keeps k(mu) + k(-mu) = 2 in [0, 2]. */
		ret_excess[i] = i == 0 ? 0.0 : skymap_clamp(k - 1.0, -1.0, 1.0);
	}
}

void phase_ground_fit(const double excess[PHASE_GROUND_N], double ret_coef[PHASE_GROUND_FIT])
{
	/* Least squares by modified Gram-Schmidt on the columns s^j at the
	 * table's points (normal equations of monomials lose digits). */
	enum { N = PHASE_GROUND_N, M = PHASE_GROUND_FIT };
	double q[M][N], r[M][M] = { { 0 } }, qb[M];
	for (int j = 0; j < M; j++)
		for (int i = 0; i < N; i++)
			q[j][i] = pow(sqrt((double)i / (N - 1)), j + 2);
	for (int j = 0; j < M; j++) {
		for (int k = 0; k < j; k++) {
			double d = 0;
			for (int i = 0; i < N; i++)
				d += q[k][i] * q[j][i];
			r[k][j] = d;
			for (int i = 0; i < N; i++)
				q[j][i] -= d * q[k][i];
		}
		double norm = 0;
		for (int i = 0; i < N; i++)
			norm += q[j][i] * q[j][i];
		r[j][j] = sqrt(norm);
		for (int i = 0; i < N; i++)
			q[j][i] /= r[j][j];
		qb[j] = 0;
		for (int i = 0; i < N; i++)
			qb[j] += q[j][i] * excess[i];
	}
	for (int j = M - 1; j >= 0; j--) {
		double x = qb[j];
		for (int k = j + 1; k < M; k++)
			x -= r[j][k] * ret_coef[k];
		ret_coef[j] = x / r[j][j];
	}
}

double phase_ground_fit_at(const double coef[PHASE_GROUND_FIT], double mu_view)
{
	double s = sqrt(fmin(fabs(mu_view), 1.0)), e = coef[PHASE_GROUND_FIT - 1];
	for (int j = PHASE_GROUND_FIT - 2; j >= 0; j--)
		e = e * s + coef[j];
	e *= s * s;
	return mu_view < 0 ? -e : e;
}


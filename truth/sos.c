/* sos.c - successive orders of scattering in a plane-parallel Rayleigh
 * layer (sos.h): the path tracer's independent check. */
#include "sos.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define AZIMUTHS 8	/* exact for the quartic azimuthal terms of P M P */
#define MAX_ORDERS 2000

typedef double mat3[9];

/* Gauss-Legendre nodes and weights on (0, 1). */
static void gauss01(uint32_t n, double *x, double *w)
{
	for (uint32_t i = 0; i < n; i++) {
		double z = cos(PI * (i + 0.75) / (n + 0.5)), dp = 1.0;
		for (int it = 0; it < 100; it++) {
			double p0 = 1.0, p1 = z;
			for (uint32_t k = 2; k <= n; k++) {
				double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
				p0 = p1;
				p1 = p2;
			}
			dp = n * (z * p1 - p0) / (z * z - 1.0);
			double dz = p1 / dp;
			z -= dz;
			if (fabs(dz) < 1e-15)
				break;
		}
		x[i] = 0.5 * (1.0 - z);
		w[i] = 1.0 / ((1.0 - z * z) * dp * dp);
	}
}

static void projector(const double n[3], mat3 ret)
{
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++)
			ret[3 * a + b] = (a == b) - n[a] * n[b];
}

/* The weights of the two ends of a layer x = dtau / mu thick for a source
 * linear in tau, seen from the w1 end: w0 far, w1 near. */
static void layer_weights(double x, double *ret_w0, double *ret_w1, double *ret_t)
{
	double t = exp(-x), f;	/* f = (1 - e^-x) / x */
	f = x < 1e-4 ? 1.0 - x / 2.0 + x * x / 6.0 - x * x * x / 24.0 : -expm1(-x) / x;
	*ret_w0 = f - t;
	*ret_w1 = 1.0 - f;
	*ret_t = t;
}

/* The first order's part of G: integral of exp(-tau' / mu0) along a ray of
 * cosine mu going down (to depth tau from the top) or up (from the bottom
 * T to tau), over mu. */
static double direct_g(double tau, double total, double mu0, double mu, int up)
{
	if (up)
		return exp(-tau / mu0) * mu0 / (mu0 + mu) * -expm1(-(total - tau) * (1.0 / mu0 + 1.0 / mu));
	double d = tau * (1.0 / mu - 1.0 / mu0);
	double r = fabs(d) < 1e-8 ? 1.0 - d / 2.0 : -expm1(-d) / d;
	return exp(-tau / mu0) * tau / mu * r;
}

/* The linear map X -> sum over the azimuths of k P_n X P_n dphi (or its
 * unpolarized form, trace(P_n X P_n) P_n k / 2) for the directions of
 * cosine-z nz: a 9 x 9 matrix on the 9 entries of X. */
static void azimuth_map(double nz, int polarized, double ret[81])
{
	memset(ret, 0, 81 * sizeof(double));
	double st = sqrt(fmax(1.0 - nz * nz, 0.0)), k = 3.0 / (8.0 * PI);
	for (int q = 0; q < AZIMUTHS; q++) {
		double phi = 2.0 * PI * q / AZIMUTHS, n[3] = { st * cos(phi), st * sin(phi), nz };
		mat3 p;
		projector(n, p);
		double wq = k * 2.0 * PI / AZIMUTHS;
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				for (int c = 0; c < 3; c++)
					for (int d = 0; d < 3; d++) {
						/* out_ab += in_cd * coefficient */
						double coef = polarized ? p[3 * a + c] * p[3 * d + b]
							      : 0.5 * p[3 * a + b] * p[3 * d + c];
						ret[9 * (3 * a + b) + 3 * c + d] += wq * coef;
					}
	}
}

/* State of one solution: the grid, the beam and the diffuse M(tau). */
struct sos {
	const struct sos_layer *l;
	uint32_t nl, ns;
	double dtau, mu0;
	mat3 beam;		/* (E / 2) P_s: the beam's integrated tensor at tau 0 */
	double *mu, *w;		/* Gauss cosines and weights, ns */
	double *maps;		/* 2 ns azimuth maps (down, up) */
	mat3 *m, *next, *g;	/* M_diffuse, its next iterate, G along a sweep: nl + 1 */
};

/* G(tau_i) for rays of cosine mu (down: at depth tau_i from above; up:
 * from below), beam and diffuse parts, into s->g. */
static void sweep(struct sos *s, double mu, int up)
{
	double w0, w1, t;
	layer_weights(s->dtau / mu, &w0, &w1, &t);
	mat3 acc = { 0 };
	for (uint32_t step = 0; step <= s->nl; step++) {
		uint32_t i = up ? s->nl - step : step;
		if (step > 0) {
			uint32_t far = up ? i + 1 : i - 1;
			for (int e = 0; e < 9; e++)
				acc[e] = acc[e] * t + w0 * s->m[far][e] + w1 * s->m[i][e];
		}
		double gd = direct_g(i * s->dtau, s->l->tau, s->mu0, mu, up);
		for (int e = 0; e < 9; e++)
			s->g[i][e] = acc[e] + gd * s->beam[e];
	}
}

/* One order more everywhere: next = integral over directions of the
 * light scattered from (beam + m). Returns the largest change relative to
 * the largest entry. */
static double iterate(struct sos *s)
{
	memset(s->next, 0, (s->nl + 1) * sizeof(mat3));
	for (uint32_t j = 0; j < s->ns; j++)
		for (int up = 0; up < 2; up++) {
			const double *map = s->maps + 81 * (2 * j + up);
			sweep(s, s->mu[j], up);
			for (uint32_t i = 0; i <= s->nl; i++)
				for (int a = 0; a < 9; a++) {
					double sum = 0.0;
					for (int b = 0; b < 9; b++)
						sum += map[9 * a + b] * s->g[i][b];
					s->next[i][a] += s->w[j] * sum;
				}
		}
	double change = 0.0, scale = 1e-300;
	for (uint32_t i = 0; i <= s->nl; i++)
		for (int e = 0; e < 9; e++) {
			change = fmax(change, fabs(s->next[i][e] - s->m[i][e]));
			scale = fmax(scale, fabs(s->next[i][e]));
		}
	mat3 *t = s->m;
	s->m = s->next;
	s->next = t;
	return change / scale;
}

/* The radiance toward view v once m has converged. */
static double view_radiance(struct sos *s, const struct sos_view *v)
{
	double el = v->elevation_deg * PI / 180.0, az = v->azimuth_deg * PI / 180.0;
	double n[3] = { -cos(el) * cos(az), -cos(el) * sin(az), -sin(el) };
	int up = n[2] > 0.0;
	sweep(s, fabs(n[2]), up);
	const double *g = s->g[up ? 0 : s->nl];
	mat3 p;
	projector(n, p);
	/* trace(k P G P) = k trace(P G), the same for both problems. */
	double tr = 0.0;
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++)
			tr += p[3 * a + b] * g[3 * b + a];
	return 3.0 / (8.0 * PI) * tr;
}

int sos_rayleigh(const struct sos_layer *l, const struct sos_view *views, size_t n,
		 double *ret_radiance, int *ret_orders)
{
	if (!l || !views || !ret_radiance || !(l->tau > 0.0) ||
	    !(l->sun_elevation_deg > 0.0 && l->sun_elevation_deg <= 90.0))
		return -EINVAL;
	for (size_t i = 0; i < n; i++)
		if (!(fabs(sin(views[i].elevation_deg * PI / 180.0)) > 1e-6) ||
		    fabs(views[i].elevation_deg) > 90.0)
			return -EINVAL;
	struct sos s = { .l = l, .nl = l->layers ? l->layers : 400, .ns = l->streams ? l->streams : 48 };
	s.dtau = l->tau / s.nl;
	double el_s = l->sun_elevation_deg * PI / 180.0, sun[3] = { cos(el_s), 0.0, sin(el_s) };
	s.mu0 = sun[2];
	projector(sun, s.beam);
	for (int e = 0; e < 9; e++)
		s.beam[e] *= 0.5 * l->irradiance;
	s.mu = calloc(s.ns, sizeof(double));
	s.w = calloc(s.ns, sizeof(double));
	s.maps = calloc(162 * (size_t)s.ns, sizeof(double));
	s.m = calloc(s.nl + 1, sizeof(mat3));
	s.next = calloc(s.nl + 1, sizeof(mat3));
	s.g = calloc(s.nl + 1, sizeof(mat3));
	int r = -ENOMEM, orders = 1;
	if (!s.mu || !s.w || !s.maps || !s.m || !s.next || !s.g)
		goto out;
	gauss01(s.ns, s.mu, s.w);
	for (uint32_t j = 0; j < s.ns; j++) {
		azimuth_map(-s.mu[j], l->polarized, s.maps + 81 * (2 * j));
		azimuth_map(s.mu[j], l->polarized, s.maps + 81 * (2 * j + 1));
	}
	/* m starts at 0 (the first order alone); each iterate adds one. */
	while (orders < MAX_ORDERS && iterate(&s) > 1e-13)
		orders++;
	for (size_t i = 0; i < n; i++)
		ret_radiance[i] = view_radiance(&s, &views[i]);
	if (ret_orders)
		*ret_orders = orders;
	r = 0;
out:
	free(s.mu);
	free(s.w);
	free(s.maps);
	free(s.m);
	free(s.next);
	free(s.g);
	return r;
}

/* atmo.c - atmosphere presets, density profiles and validation. */
#include "atmo.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static void set3(double v[3], double r, double g, double b)
{
	v[0] = r;
	v[1] = g;
	v[2] = b;
}

static struct atmo_profile exp_profile(double scale_height_km)
{
	struct atmo_profile p = { 0 };
	p.layers[1].exp_term = 1.0;
	p.layers[1].exp_scale_per_km = -1.0 / scale_height_km;
	return p;
}

void atmo_earth(struct atmo *ret)
{
	struct atmo a = { 0 };

	a.bottom_radius_km = 6360.0;
	a.top_radius_km = 6460.0;
	set3(a.ground_albedo, 0.3, 0.3, 0.3);
	a.n_constituents = 3;

	struct atmo_constituent *r = &a.c[ATMO_RAYLEIGH];
	snprintf(r->name, sizeof(r->name), "rayleigh");
	set3(r->scattering_per_km, 5.802e-3, 13.558e-3, 33.1e-3);
	r->phase = ATMO_PHASE_RAYLEIGH;
	r->density = exp_profile(8.0);

	struct atmo_constituent *m = &a.c[ATMO_MIE];
	snprintf(m->name, sizeof(m->name), "mie");
	set3(m->scattering_per_km, 3.996e-3, 3.996e-3, 3.996e-3);
	set3(m->absorption_per_km, 0.444e-3, 0.444e-3, 0.444e-3);
	m->phase = ATMO_PHASE_CORNETTE_SHANKS;
	m->g = 0.8;
	m->density = exp_profile(1.2);

	/* Ozone: a tent, 0 at 10 km, 1 at 25 km, 0 at 40 km. */
	struct atmo_constituent *o = &a.c[ATMO_OZONE];
	snprintf(o->name, sizeof(o->name), "ozone");
	set3(o->absorption_per_km, 0.650e-3, 1.881e-3, 0.085e-3);
	o->phase = ATMO_PHASE_NONE;
	o->density.layers[0] = (struct atmo_layer){ .width_km = 25.0,
		.linear_per_km = 1.0 / 15.0, .constant = -2.0 / 3.0 };
	o->density.layers[1] = (struct atmo_layer){
		.linear_per_km = -1.0 / 15.0, .constant = 8.0 / 3.0 };

	*ret = a;
}

void atmo_mars(struct atmo *ret)
{
	struct atmo a = { 0 };

	a.bottom_radius_km = 3386.19;
	a.top_radius_km = 3463.17;
	set3(a.ground_albedo, 0.1, 0.1, 0.1);
	a.n_constituents = 2;

	struct atmo_constituent *r = &a.c[0];
	snprintf(r->name, sizeof(r->name), "rayleigh");
	set3(r->scattering_per_km, 19.918e-3, 13.57e-3, 5.75e-3);
	r->phase = ATMO_PHASE_RAYLEIGH;
	r->density = exp_profile(10.44);

	/* Dust: extinction = scattering / 0.98979. */
	struct atmo_constituent *d = &a.c[1];
	snprintf(d->name, sizeof(d->name), "mie");
	double s = 53.62e-3, k = s / 0.98979 - s;
	set3(d->scattering_per_km, s, s, s);
	set3(d->absorption_per_km, k, k, k);
	d->phase = ATMO_PHASE_CORNETTE_SHANKS;
	d->g = 0.85;
	d->density = exp_profile(3.095);

	*ret = a;
}

int atmo_preset(const char *name, struct atmo *ret)
{
	if (strcmp(name, "earth") == 0)
		atmo_earth(ret);
	else if (strcmp(name, "mars") == 0)
		atmo_mars(ret);
	else
		return -EINVAL;
	return 0;
}

static double layer_density(const struct atmo_layer *l, double h)
{
	double d = l->exp_term * exp(l->exp_scale_per_km * h) +
		   l->linear_per_km * h + l->constant;
	return d < 0.0 ? 0.0 : d > 1.0 ? 1.0 : d;
}

double atmo_density(const struct atmo_profile *p, double altitude_km)
{
	const struct atmo_layer *l =
		altitude_km < p->layers[0].width_km ? &p->layers[0] : &p->layers[1];
	return layer_density(l, altitude_km);
}

static int finite_nonneg(const double *v, int n)
{
	for (int i = 0; i < n; i++)
		if (!isfinite(v[i]) || v[i] < 0.0)
			return 0;
	return 1;
}

static int layer_finite(const struct atmo_layer *l)
{
	return isfinite(l->width_km) && isfinite(l->exp_term) &&
	       isfinite(l->exp_scale_per_km) && isfinite(l->linear_per_km) &&
	       isfinite(l->constant);
}

int atmo_validate(const struct atmo *a, char *err, size_t err_size)
{
#define FAIL(...)                                      \
	do {                                           \
		snprintf(err, err_size, __VA_ARGS__); \
		return -EINVAL;                        \
	} while (0)

	if (!isfinite(a->bottom_radius_km) || a->bottom_radius_km <= 0.0)
		FAIL("bottom_radius_km: must be a finite number > 0");
	if (!isfinite(a->top_radius_km) || !(a->top_radius_km > a->bottom_radius_km))
		FAIL("top_radius_km: must be finite and above bottom_radius_km");
	for (int i = 0; i < 3; i++)
		if (!isfinite(a->ground_albedo[i]) || a->ground_albedo[i] < 0.0 ||
		    a->ground_albedo[i] > 1.0)
			FAIL("ground_albedo: must be in [0, 1]");
	if (a->n_constituents < 0 || a->n_constituents > ATMO_MAX_CONSTITUENTS)
		FAIL("constituents: at most %d", ATMO_MAX_CONSTITUENTS);
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *c = &a->c[i];
		if (!finite_nonneg(c->scattering_per_km, 3))
			FAIL("%s_scattering_per_km: must be finite and >= 0", c->name);
		if (!finite_nonneg(c->absorption_per_km, 3))
			FAIL("%s_absorption_per_km: must be finite and >= 0", c->name);
		if (c->phase < ATMO_PHASE_NONE || c->phase > ATMO_PHASE_HENYEY_GREENSTEIN)
			FAIL("%s_phase: unknown phase function", c->name);
		if (c->phase == ATMO_PHASE_NONE &&
		    (c->scattering_per_km[0] > 0 || c->scattering_per_km[1] > 0 ||
		     c->scattering_per_km[2] > 0))
			FAIL("%s_phase: a scattering constituent needs a phase function",
			     c->name);
		if (!isfinite(c->g) || !(fabs(c->g) < 1.0))
			FAIL("%s_g: must be finite with |g| < 1", c->name);
		for (int k = 0; k < 2; k++)
			if (!layer_finite(&c->density.layers[k]))
				FAIL("%s density layer %d: must be finite", c->name, k);
		if (c->density.layers[0].width_km < 0.0)
			FAIL("%s density layer 0 width_km: must be >= 0", c->name);
	}
	return 0;
#undef FAIL
}

void atmo_vertical_optical_depth(const struct atmo *a, int n, double ret_tau[3])
{
	double shell = a->top_radius_km - a->bottom_radius_km, tau[3] = { 0 };

	if (n % 2)
		n++;	/* Simpson needs an even count */
	double dh = shell / n;
	for (int j = 0; j <= n; j++) {
		double h = j * dh, w = (j == 0 || j == n) ? 1.0 : (j % 2 ? 4.0 : 2.0);
		for (int i = 0; i < a->n_constituents; i++) {
			const struct atmo_constituent *c = &a->c[i];
			double d = atmo_density(&c->density, h);
			for (int ch = 0; ch < 3; ch++)
				tau[ch] += w * d *
					   (c->scattering_per_km[ch] + c->absorption_per_km[ch]);
		}
	}
	for (int ch = 0; ch < 3; ch++)
		ret_tau[ch] = tau[ch] * dh / 3.0;
}

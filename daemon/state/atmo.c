/* atmo.c - the planet presets, density profiles and validation. */
#include "atmo.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

/* One exponential of scale height h_km: the upper layer from the ground up. */
#define EXP_PROFILE(h_km) \
	{ .layers = { [1] = { .exp_term = 1.0, .exp_scale_per_km = -1.0 / (h_km) } } }

enum atmo_planet { ATMO_EARTH, ATMO_MARS, ATMO_N_PLANETS };

const char *const atmo_preset_names[ATMO_N_PLANETS + 1] = {
	[ATMO_EARTH] = "earth", [ATMO_MARS] = "mars", [ATMO_N_PLANETS] = NULL,
};

/* Mars's dust: extinction = scattering / 0.98979. */
#define MARS_DUST_SCATTERING 53.62e-3
#define MARS_DUST_ABSORPTION (MARS_DUST_SCATTERING / 0.98979 - MARS_DUST_SCATTERING)

static const struct atmo planets[ATMO_N_PLANETS] = {
	/* Hillaire's EGSR 2020 Earth with the constants of docs/physics.md. */
	[ATMO_EARTH] = {
		.bottom_radius_km = 6360.0, .top_radius_km = 6460.0,
		.ground_albedo = { 0.3, 0.3, 0.3 },
		.n_constituents = 3,
		.c = {
			[ATMO_RAYLEIGH] = {
				.name = "rayleigh",
				.scattering_per_km = { 5.802e-3, 13.558e-3, 33.1e-3 },
				.phase = ATMO_PHASE_RAYLEIGH,
				.density = EXP_PROFILE(8.0),
			},
			[ATMO_MIE] = {
				.name = "mie",
				.scattering_per_km = { 3.996e-3, 3.996e-3, 3.996e-3 },
				.absorption_per_km = { 0.444e-3, 0.444e-3, 0.444e-3 },
				.phase = ATMO_PHASE_CORNETTE_SHANKS, .g = 0.8,
				.density = EXP_PROFILE(1.2),
			},
			/* Ozone: a tent, 0 at 10 km, 1 at 25 km, 0 at 40 km. */
			[ATMO_OZONE] = {
				.name = "ozone",
				.absorption_per_km = { 0.650e-3, 1.881e-3, 0.085e-3 },
				.phase = ATMO_PHASE_NONE,
				.density = { .layers = {
					{ .width_km = 25.0, .linear_per_km = 1.0 / 15.0,
					  .constant = -2.0 / 3.0 },
					{ .linear_per_km = -1.0 / 15.0, .constant = 8.0 / 3.0 },
				} },
			},
		},
	},
	/* Mars after Collienne 2013 (OpenSpace). */
	[ATMO_MARS] = {
		.bottom_radius_km = 3386.19, .top_radius_km = 3463.17,
		.ground_albedo = { 0.1, 0.1, 0.1 },
		.n_constituents = 2,
		.c = {
			[ATMO_RAYLEIGH] = {
				.name = "rayleigh",
				.scattering_per_km = { 19.918e-3, 13.57e-3, 5.75e-3 },
				.phase = ATMO_PHASE_RAYLEIGH,
				.density = EXP_PROFILE(10.44),
			},
			[ATMO_MIE] = {
				.name = "mie",
				.scattering_per_km = { MARS_DUST_SCATTERING, MARS_DUST_SCATTERING,
						       MARS_DUST_SCATTERING },
				.absorption_per_km = { MARS_DUST_ABSORPTION, MARS_DUST_ABSORPTION,
						       MARS_DUST_ABSORPTION },
				.phase = ATMO_PHASE_CORNETTE_SHANKS, .g = 0.85,
				.density = EXP_PROFILE(3.095),
			},
		},
	},
};

void atmo_earth(struct atmo *ret)
{
	*ret = planets[ATMO_EARTH];
}

void atmo_mars(struct atmo *ret)
{
	*ret = planets[ATMO_MARS];
}

int atmo_preset(const char *name, struct atmo *ret)
{
	for (int i = 0; i < ATMO_N_PLANETS; i++)
		if (strcmp(name, atmo_preset_names[i]) == 0) {
			*ret = planets[i];
			return 0;
		}
	return -EINVAL;
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

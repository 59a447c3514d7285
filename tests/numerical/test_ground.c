/* test_ground.c - the ground's first bounce seen through each constituent's
 * phase: the hemisphere factor k against a brute-force integral, and the
 * model's sky over a sunlit ground in a thin atmosphere against single
 * scattering of the ground's light, which an isotropic treatment gets many
 * times too bright at the zenith for a forward-peaked phase. */
#include <math.h>
#include <stdio.h>

#include "model.h"
#include "skymap.h"
#include "test.h"

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s", err);
}

/* The phase functions of common.glsl, for the brute-force reference. */
static double phase(enum atmo_phase kind, double g, double mu)
{
	if (kind == ATMO_PHASE_RAYLEIGH)
		return 3.0 / (16.0 * SKYMAP_PI) * (1.0 + mu * mu);
	double den = 1.0 + g * g - 2.0 * g * mu, hg = (1.0 - g * g) / (4.0 * SKYMAP_PI * pow(den, 1.5));
	return kind == ATMO_PHASE_HENYEY_GREENSTEIN ? hg : hg * 1.5 * (1.0 + mu * mu) / (2.0 + g * g);
}

/* k(mu_view) = 2 * the integral of p(-d . view) over upward d, on a plain
 * midpoint grid in (cos-zenith, azimuth) of d: a different quadrature from
 * phase_ground_excess's single integral over the scattering angle. */
static double brute_k(enum atmo_phase kind, double g, double mu_view)
{
	const int n = 1500, m = 1500;
	double sv = sqrt(fmax(1.0 - mu_view * mu_view, 0.0)), sum = 0.0;
	for (int a = 0; a < n; a++) {
		double dz = (a + 0.5) / n, ds = sqrt(1.0 - dz * dz);
		for (int b = 0; b < m; b++) {
			double phi = SKYMAP_PI * (b + 0.5) / m;	/* symmetric in phi: half */
			sum += phase(kind, g, -(dz * mu_view + ds * sv * cos(phi)));
		}
	}
	return 2.0 * sum * (1.0 / n) * (2.0 * SKYMAP_PI / m);
}

static void check_excess(void)
{
	static const struct {
		enum atmo_phase kind;
		double g;
	} cases[] = {
		{ ATMO_PHASE_CORNETTE_SHANKS, 0.8 },
		{ ATMO_PHASE_HENYEY_GREENSTEIN, 0.5 },
		{ ATMO_PHASE_HENYEY_GREENSTEIN, -0.6 },
		{ ATMO_PHASE_CORNETTE_SHANKS, 0.0 },
	};
	double e[PHASE_GROUND_N];
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		phase_ground_excess(cases[c].kind, cases[c].g, e);
		CHECK(e[0] == 0.0);
		for (int i = 1; i < PHASE_GROUND_N; i += 6) {
			double mu = (double)i / (PHASE_GROUND_N - 1), ref = brute_k(cases[c].kind, cases[c].g, mu);
			printf("kind %d g %+.1f mu %.3f: k %.5f, brute force %.5f\n", cases[c].kind, cases[c].g,
			       mu, 1.0 + e[i], ref);
			if (!(fabs(1.0 + e[i] - ref) < 2e-3))
				FAIL("kind %d g %.2f mu %.3f: k %.5f against %.5f", cases[c].kind, cases[c].g, mu,
				     1.0 + e[i], ref);
			/* A forward lobe sends upwelling light up, not back down. */
			if (cases[c].g > 0.0 && !(e[i] <= e[i - 1] + 1e-9))
				FAIL("g %.2f: k rises with mu at %.3f", cases[c].g, mu);
		}
	}
	/* Rayleigh's phase is exactly isotropic over any hemisphere. */
	phase_ground_excess(ATMO_PHASE_RAYLEIGH, 0.0, e);
	for (int i = 0; i < PHASE_GROUND_N; i++)
		CHECK(e[i] == 0.0);
}

/* The polynomial the marches evaluate: at the table's points against the
 * table, between them (where it replaces the table's interpolation)
 * against the brute-force k, and odd in mu. */
static void check_fit(void)
{
	static const struct {
		enum atmo_phase kind;
		double g, limit;
	} cases[] = {
		{ ATMO_PHASE_CORNETTE_SHANKS, 0.8, 2e-3 },	/* Earth's Mie */
		{ ATMO_PHASE_CORNETTE_SHANKS, 0.85, 2e-3 },	/* Mars' dust */
		{ ATMO_PHASE_HENYEY_GREENSTEIN, 0.95, 8e-3 },
		{ ATMO_PHASE_HENYEY_GREENSTEIN, -0.6, 1e-3 },
		{ ATMO_PHASE_RAYLEIGH, 0.0, 1e-6 },	/* the brute force's own error */
	};
	static const double between[] = { 0.25, 0.5, 1.5, 5.5, 15.5, 30.5 };	/* in table steps */
	double e[PHASE_GROUND_N], coef[PHASE_GROUND_FIT];
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		phase_ground_excess(cases[c].kind, cases[c].g, e);
		phase_ground_fit(e, coef);
		double at_points = 0, off_points = 0;
		for (int i = 0; i < PHASE_GROUND_N; i++) {
			double mu = (double)i / (PHASE_GROUND_N - 1);
			at_points = fmax(at_points, fabs(phase_ground_fit_at(coef, mu) - e[i]));
			CHECK(phase_ground_fit_at(coef, -mu) == -phase_ground_fit_at(coef, mu));
		}
		for (size_t i = 0; i < sizeof(between) / sizeof(between[0]); i++) {
			double mu = between[i] / (PHASE_GROUND_N - 1);
			double ref = brute_k(cases[c].kind, cases[c].g, mu) - 1.0;
			off_points = fmax(off_points, fabs(phase_ground_fit_at(coef, mu) - ref));
		}
		printf("kind %d g %+.2f: fit within %.1e of the table at its points, %.1e of k between them "
		       "(limit %.0e)\n", cases[c].kind, cases[c].g, at_points, off_points, cases[c].limit);
		if (!(at_points <= cases[c].limit && off_points <= cases[c].limit))
			FAIL("kind %d g %.2f: fit %.1e / %.1e off", cases[c].kind, cases[c].g, at_points, off_points);
	}
}

/* Green radiance of the sky-view table at a view elevation (azimuth 0),
 * bilinear in v at the texel column of azimuth 0's texel. */
static double skyview_green(const struct model_tables *m, const struct sky_state *s, double elevation_deg)
{
	double u, vv, mh = skymap_horizon_cos(s->atmo.bottom_radius_km, s->altitude_km);
	uint32_t w = m->w[STATE_SKYVIEW], h = m->h[STATE_SKYVIEW];
	skymap_skyview_uv(mh, (90.0 - elevation_deg) * SKYMAP_PI / 180.0, 0.0, h, &u, &vv);
	double py = vv * h - 0.5, fy = py - floor(py);
	int y0 = (int)floor(py), y1 = y0 + 1;
	y0 = y0 < 0 ? 0 : y0;
	y1 = y1 > (int)h - 1 ? (int)h - 1 : y1;
	const double *t = m->t[STATE_SKYVIEW];
	return t[4 * ((size_t)y0 * w) + 1] * (1.0 - fy) + t[4 * ((size_t)y1 * w) + 1] * fy;
}

/* A thin atmosphere of one scattering constituent over a ground of albedo
 * 0.3, sun at the zenith: the sky's radiance with the ground minus without
 * it is, to first order in the optical depth tau, the ground's light
 * L_g = albedo / pi * E scattered along the view: tau / mu * (L_g / 2) * k(mu)
 * (L_g / 2 is its mean over the sphere). The higher orders of the ground's
 * light add about f_ms ~ 0.01 of L_g / 2. */
static void check_thin(const char *name, const char *zero, const char *scatter, enum atmo_phase kind)
{
	struct sky_state s;
	struct model_tables with, without;
	double e[PHASE_GROUND_N], tau[3];

	state_default(&s);
	set(&s, "rayleigh_scattering_per_km=0");
	set(&s, "ozone_absorption_per_km=0");
	set(&s, "mie_absorption_per_km=0");
	set(&s, zero);
	set(&s, scatter);
	set(&s, "altitude_km=0");
	set(&s, "sun_elevation_deg=90");
	set(&s, "night_zenith_luminance_cd_m2=0");
	set(&s, "ground_albedo=0.3");
	CHECK(model_compute(&s, STATE_BIT(STATE_SKYVIEW), &with) == 0);
	set(&s, "ground_albedo=0");
	CHECK(model_compute(&s, STATE_BIT(STATE_SKYVIEW), &without) == 0);

	const struct atmo_constituent *c = NULL;
	for (int i = 0; i < s.atmo.n_constituents; i++)
		if (s.atmo.c[i].phase == kind && s.atmo.c[i].scattering_per_km[1] > 0)
			c = &s.atmo.c[i];
	if (!c) {
		FAIL("%s: no scattering constituent of kind %d", name, kind);
		return;
	}
	phase_ground_excess(kind, c->g, e);
	/* The vertical optical depth is the extinction's: scattering only. */
	model_optical_depth(&s.atmo, 0.0, 1.0, 200, tau);
	double l_g = 0.3 / SKYMAP_PI * s.sun.illuminance_lx * s.sun.color[1] * exp(-tau[1]);
	static const double elevations[] = { 90, 30 };
	for (int i = 0; i < 2; i++) {
		double mu = sin(elevations[i] * SKYMAP_PI / 180.0);
		double x = mu * (PHASE_GROUND_N - 1), fl = floor(x);
		int j = (int)fl, j1 = j + 1 < PHASE_GROUND_N ? j + 1 : j;
		double k = 1.0 + e[j] + (e[j1] - e[j]) * (x - fl);
		double delta = skyview_green(&with, &s, elevations[i]) - skyview_green(&without, &s, elevations[i]);
		double r = delta / (tau[1] / mu * 0.5 * l_g);
		printf("%s, view elevation %2.0f: ground's part %.4g cd/m2 = %.4f x tau / mu L_g / 2, k %.4f\n",
		       name, elevations[i], delta, r, k);
		if (!(fabs(r - k) <= 0.02 + 0.1 * k))
			FAIL("%s, elevation %.0f: the ground's light reads %.4f of tau / mu L_g / 2, k is %.4f", name,
			     elevations[i], r, k);
	}
	model_tables_finish(&with);
	model_tables_finish(&without);
}

int main(void)
{
	check_excess();
	check_fit();
	check_thin("Mie g 0.8", "rayleigh_scattering_per_km=0", "mie_scattering_per_km=0.001",
		   ATMO_PHASE_CORNETTE_SHANKS);
	check_thin("Rayleigh", "mie_scattering_per_km=0", "rayleigh_scattering_per_km=0.001",
		   ATMO_PHASE_RAYLEIGH);
	return test_report("test_ground");
}

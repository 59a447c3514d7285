/* test_msgrid.c - the multi-scattering table's direction quadrature against
 * the exact path lengths: in a shell of uniform, purely scattering medium, f_ms
 * (1 - model_multiscatter_escape) is the sphere's mean of 1 - exp(-beta L(mu)), L the path
 * to the top or the ground, which the march integrates exactly per
 * direction; what is left is the error of the rings and their weights. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "skymap.h"
#include "test.h"

#define RB_KM 6360.0
#define RT_KM 6460.0

/* The path from altitude h along cos-zenith mu to the top, or to the ground
 * below the horizon. */
static double path_km(double h, double mu)
{
	double r = RB_KM + h, mh = skymap_horizon_cos(RB_KM, h);
	if (mu < mh || (h <= 0.0 && mu < 0.0))
		return fmax(-r * mu - sqrt(fmax(r * r * mu * mu - h * (2 * RB_KM + h), 0.0)), 0.0);
	return sqrt(r * r * mu * mu + (RT_KM - r) * (RT_KM + r)) - r * mu;
}

/* The reference: the sphere's mean of 1 - exp(-beta L) by 20000 midpoints on
 * each side of the horizon, where L jumps. */
static double f_reference(double h, double beta_per_km)
{
	const int n = 20000;
	double mh = skymap_horizon_cos(RB_KM, h), sum = 0;
	double a[2] = { -1.0, mh }, b[2] = { mh, 1.0 };
	for (int side = 0; side < 2; side++) {
		double d = (b[side] - a[side]) / n;
		for (int i = 0; i < n; i++)
			sum += -expm1(-beta_per_km * path_km(h, a[side] + (i + 0.5) * d)) * d;
	}
	return 0.5 * sum;
}

/* One constituent of constant density, scattering beta on every channel,
 * no absorption, black ground; only the multi-scattering table matters. */
static void uniform_shell(double beta_per_km, struct sky_state *ret)
{
	char err[256];
	state_default(ret);
	struct atmo *a = &ret->atmo;
	memset(a, 0, sizeof(*a));
	a->bottom_radius_km = RB_KM;
	a->top_radius_km = RT_KM;
	a->n_constituents = 1;
	snprintf(a->c[0].name, sizeof(a->c[0].name), "uniform");
	for (int ch = 0; ch < 3; ch++)
		a->c[0].scattering_per_km[ch] = beta_per_km;
	a->c[0].phase = ATMO_PHASE_RAYLEIGH;
	a->c[0].density.layers[0].constant = 1.0;
	a->c[0].density.layers[1].constant = 1.0;
	if (state_validate(ret, 0, err, sizeof(err)) < 0)
		FAIL("uniform shell: %s", err);
}

/* f at every row's altitude of the table against the reference: within tol
 * at every altitude and within tol_ground at the ground, where the horizon
 * is a ring edge. (test_engine compares the engine's table with the
 * model's.) */
static void check_f(double beta_per_km, double tol, double tol_ground)
{
	struct sky_state s;
	uniform_shell(beta_per_km, &s);
	uint32_t w = s.quality.t[STATE_MULTISCATTER].width, hgt = s.quality.t[STATE_MULTISCATTER].height;
	double worst = 0, worst_h = 0, worst_ground = 0;
	for (uint32_t j = 0; j < hgt; j++) {
		double h, mu_s, escape[3];
		skymap_multiscatter_inverse(RB_KM, RT_KM, 0.5 / w, (j + 0.5) / hgt, w, hgt, &h, &mu_s);
		if (model_multiscatter_escape(&s, h, escape) < 0) {
			FAIL("model_multiscatter_escape: out of memory");
			return;
		}
		double rel = (1 - escape[1]) / f_reference(h, beta_per_km) - 1;
		if (fabs(rel) > fabs(worst)) {
			worst = rel;
			worst_h = h;
		}
		if (j == 0)
			worst_ground = rel;
	}
	printf("beta %-6g f: model worst %+.2f %% at %.2f km (limit %.1f %%)\n", beta_per_km, 100 * worst,
	       worst_h, 100 * tol);
	if (!(fabs(worst_ground) <= tol_ground))
		FAIL("beta %g: f at the ground %+.2f %% off the reference (limit %.2f %%)", beta_per_km,
		     100 * worst_ground, 100 * tol_ground);
	if (!(fabs(worst) <= tol))
		FAIL("beta %g: f %+.2f %% off the reference at %.2f km", beta_per_km, 100 * worst, worst_h);
}

/* psi of the table at altitude h and sun cosine mu_s, channel ch: row y read
 * at its own u (as the lookups), linear within the row. */
static double psi_row(const struct model_tables *m, uint32_t y, double mu_s, int ch)
{
	uint32_t w = m->w[STATE_MULTISCATTER], n = m->h[STATE_MULTISCATTER];
	double hy = (double)y / (n - 1) * (RT_KM - RB_KM), u, vv;
	skymap_multiscatter_uv(RB_KM, RT_KM, hy, mu_s, w, n, &u, &vv);
	double px = u * w - 0.5, f = px - floor(px);
	int i = (int)floor(px);
	int x0 = i < 0 ? 0 : i > (int)w - 1 ? (int)w - 1 : i;
	int x1 = i + 1 < 0 ? 0 : i + 1 > (int)w - 1 ? (int)w - 1 : i + 1;
	const double *row = m->t[STATE_MULTISCATTER] + 4 * (size_t)y * w;
	return row[4 * x0 + ch] + (row[4 * x1 + ch] - row[4 * x0 + ch]) * f;
}

/* Earth with ten times the scattering (the iteration of psi_ms runs): the
 * 32-row table's texels against a 96-row table's at the same altitudes
 * (every third row), the lowest 20 km, green and blue, sun 30 and 60
 * degrees. The iteration reads each neighbour's psi between rows, and psi
 * is concave in altitude where the sunlight dies within a few rows: a
 * linear blend reads it low, the parabola through three rows
 * (msiterate.comp) keeps it within about 1 %. The ground row gets a wider
 * limit: the parabola over the lowest 6.5 km does not follow blue's psi
 * into the last kilometre. */
static void check_thick_rows(double tol, double tol_ground)
{
	struct model_tables m[2];
	struct sky_state s[2];
	char err[256];
	static const char *const keys[] = { "rayleigh_scattering_per_km=0.05802,0.13558,0.331",
					    "mie_scattering_per_km=0.03996", "ground_albedo=0.3" };
	for (int k = 0; k < 2; k++) {
		state_default(&s[k]);
		for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
			CHECK(state_set_pair(&s[k], keys[i], NULL, err, sizeof(err)) == 0);
		CHECK(state_set_pair(&s[k], k ? "multiscatter_height=94" : "multiscatter_height=32", NULL, err,
				     sizeof(err)) == 0);
		CHECK(state_multiscatter_iterations(&s[k]) == 2);
		if (model_compute(&s[k], STATE_BIT(STATE_MULTISCATTER), &m[k]) < 0) {
			FAIL("model_compute: out of memory");
			if (k)
				model_tables_finish(&m[0]);
			return;
		}
	}
	/* 94 rows: row 3 j of it lies at row j's altitude of 32 (93 = 3 x 31). */
	double worst = 0, worst_h = 0, worst_ground = 0;
	for (int sun = 0; sun < 2; sun++)
		for (uint32_t j = 0; j <= 6; j++)
			for (int ch = 1; ch <= 2; ch++) {
				double mu_s = sun ? 0.866 : 0.5;
				double rel = psi_row(&m[0], j, mu_s, ch) / psi_row(&m[1], 3 * j, mu_s, ch) - 1;
				if (j == 0) {
					worst_ground = fabs(rel) > fabs(worst_ground) ? rel : worst_ground;
					continue;
				}
				if (fabs(rel) > fabs(worst)) {
					worst = rel;
					worst_h = j * (RT_KM - RB_KM) / 31;
				}
			}
	printf("earth x10: psi at 32 rows against 94, worst %+.2f %% at %.2f km (limit %.1f %%), "
	       "at the ground %+.2f %% (limit %.1f %%)\n", 100 * worst, worst_h, 100 * tol,
	       100 * worst_ground, 100 * tol_ground);
	if (!(fabs(worst_ground) <= tol_ground))
		FAIL("earth x10: psi at 32 rows %+.2f %% off 94 rows at the ground", 100 * worst_ground);
	if (!(fabs(worst) <= tol))
		FAIL("earth x10: psi at 32 rows %+.2f %% off 94 rows at %.2f km", 100 * worst, worst_h);
	model_tables_finish(&m[0]);
	model_tables_finish(&m[1]);
}

int main(void)
{
	check_f(1e-3, 0.10, 0.01);
	check_f(1e-2, 0.012, 0.01);
	check_thick_rows(0.015, 0.06);
	return test_report("test_msgrid");
}

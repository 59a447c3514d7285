/* test_engine.c - every GPU table against the double-precision model, plus
 * the analytic checks: zenith transmittance, empty atmosphere, sign and
 * finiteness of every texel. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "eng.h"
#include "model.h"
#include "skysample.h"
#include "test.h"
#include "vk_or_skip.h"

static struct eng *eng;

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s", err);
}

static int compute(const struct sky_state *s, struct eng_timing *t)
{
	char err[512];
	int rc = eng_compute(eng, s, STATE_ALL_TABLES, t, err, sizeof(err));
	if (rc < 0)
		FAIL("eng_compute: %s", err);
	return rc;
}

static float texel(enum state_table t, size_t i)
{
	return ((const float *)eng_table(eng, t, NULL))[i];
}

/* Every texel finite and >= 0; transmittance within [0, 1]. */
static void check_texels(const char *name, const struct sky_state *s)
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t n = state_table_bytes(s, (enum state_table)t) / 4, bad = 0;
		for (size_t i = 0; i < n; i++) {
			float x = texel((enum state_table)t, i);
			if (!isfinite(x) || x < 0.0f || (t == STATE_TRANSMITTANCE && x > 1.0f))
				bad++;
		}
		if (bad)
			FAIL("%s: %s has %zu texels not finite, negative or above 1", name,
			     state_table_names[t], bad);
	}
}

/* PSNR (peak = the model's largest RGB value) and the largest relative error
 * among texels above 1e-3 of that peak; the model at refine times the steps. */
static void compare(const char *name, const struct sky_state *s, uint32_t refine, double min_psnr_db)
{
	struct sky_state fine;
	struct model_tables m;
	model_refine(s, refine, &fine);
	CHECK(model_compute(&fine, STATE_ALL_TABLES, &m) == 0);
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t n = state_table_bytes(s, (enum state_table)t) / 4;
		double peak = 0, se = 0, max_rel = 0;
		for (size_t i = 0; i < n; i++)
			if (i % 4 != 3)
				peak = fmax(peak, fabs(m.t[t][i]));
		for (size_t i = 0; i < n; i++) {
			if (i % 4 == 3)
				continue;
			double ref = m.t[t][i], d = texel((enum state_table)t, i) - ref;
			se += d * d;
			if (fabs(ref) > 1e-3 * peak)
				max_rel = fmax(max_rel, fabs(d) / fabs(ref));
		}
		double mse = se / (n / 4 * 3);
		double psnr = mse > 0 ? 10 * log10(peak * peak / mse) : INFINITY;
		printf("%-28s %-14s PSNR %6.1f dB  max rel %.2e\n", name, state_table_names[t], psnr, max_rel);
		/* The multi-scattering table's A: the ground's share of psi_ms. */
		if (t == STATE_MULTISCATTER) {
			double max_a = 0;
			for (size_t i = 3; i < n; i += 4)
				max_a = fmax(max_a, fabs(texel((enum state_table)t, i) - m.t[t][i]));
			if (!(max_a <= 0.01))
				FAIL("%s: multiscatter A (the ground's share) off by %.3g", name, max_a);
		}
		if (peak > 0 && !(psnr >= min_psnr_db))
			FAIL("%s: %s PSNR %.1f dB under %.0f dB", name, state_table_names[t], psnr, min_psnr_db);
	}
	model_tables_finish(&m);
}

static void test_against_model(void)
{
	static const char *const cases[][4] = {
		{ "earth sun 30", NULL },
		{ "earth sun 2 observer 10 km", "sun_elevation_deg=2", "altitude_km=10" },
		{ "earth sun -4 moon", "sun_elevation_deg=-4", "moon_elevation_deg=40", "moon_illuminance_lx=0.3" },
		{ "mars sun 20", "preset=mars", "sun_elevation_deg=20" },
		{ "mars sun 5, 1 iteration", "preset=mars", "sun_elevation_deg=5", "multiscatter_iterations=1" },
		/* The multiply scattered light's shape on Earth's Mie, moon lit too. */
		{ "earth shape, moon", "multiscatter_moment=on", "moon_elevation_deg=40", "moon_illuminance_lx=0.3" },
	};
	/* Exponential lower layers: Rayleigh's in both layers, Mie's in the
	 * lower only (the column pass carries exp(k h) per exponential layer). */
	static const char *const layered[] = { "rayleigh_layer0_width_km=6", "rayleigh_layer0_exp_term=0.9",
		"rayleigh_layer0_exp_scale_per_km=-0.1", "mie_layer0_width_km=3", "mie_layer0_exp_term=1.2",
		"mie_layer0_exp_scale_per_km=-0.5", "mie_layer1_exp_term=0", "mie_layer1_linear_per_km=-0.01",
		"mie_layer1_constant=0.2", NULL };
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
		struct sky_state s;
		struct eng_timing t;
		state_default(&s);
		for (int k = 1; k < 4 && cases[c][k]; k++)
			set(&s, cases[c][k]);
		if (compute(&s, &t) < 0)
			continue;
		check_texels(cases[c][0], &s);
		compare(cases[c][0], &s, 8, 50.0);
	}
	struct sky_state s;
	struct eng_timing t;
	state_default(&s);
	for (int k = 0; layered[k]; k++)
		set(&s, layered[k]);
	if (compute(&s, &t) == 0) {
		check_texels("earth layered profiles", &s);
		compare("earth layered profiles", &s, 8, 50.0);
	}
}

/* Ten times Earth's scattering (auto: 2 steps of the iteration of psi_ms
 * and the multiply scattered light's shape on Mie)
 * against the model at the same steps: the method, mirrored. At medium's
 * steps the thick medium is not converged, so the convergence is not what
 * this checks. */
static void test_thick_against_model(void)
{
	struct sky_state s;
	struct eng_timing t;
	state_default(&s);
	set(&s, "rayleigh_scattering_per_km=0.05802,0.13558,0.331");
	set(&s, "mie_scattering_per_km=0.03996");
	set(&s, "ground_albedo=0.3");
	CHECK(state_multiscatter_iterations(&s) == 2);
	/* and the shape (auto: Mie's g1 tau 0.04), rescaled by the iteration */
	CHECK(phase_moment_constituent(&s, NULL) == 1);
	if (compute(&s, &t) < 0)
		return;
	check_texels("earth x10 sun 30", &s);
	compare("earth x10 sun 30", &s, 1, 60.0);
}

/* Zenith from the ground is texel (0, 0) of the transmittance table exactly:
 * x_mu = 0 (d = d_min) and x_r = 0. */
static void test_zenith_transmittance(void)
{
	static const double tau[3] = {
		0.0464 + 0.00533 + 0.00975, 0.1085 + 0.00533 + 0.0282, 0.2648 + 0.00533 + 0.00128,
	};
	struct sky_state s;
	struct eng_timing t;
	double model_tau[3];
	state_default(&s);
	if (compute(&s, &t) < 0)
		return;
	atmo_vertical_optical_depth(&s.atmo, 20000, model_tau);
	for (int ch = 0; ch < 3; ch++) {
		double want = exp(-tau[ch]), got = texel(STATE_TRANSMITTANCE, ch);
		printf("zenith transmittance ch%d: %.6f, exp(-tau) of docs/physics.md %.6f, rel %.2e\n", ch, got,
		       want, fabs(got / want - 1));
		if (fabs(got / want - 1) > 1e-3)
			FAIL("zenith transmittance channel %d: %.6f vs %.6f", ch, got, want);
		CHECK(fabs(model_tau[ch] / tau[ch] - 1) < 1e-2);
	}
}

static void test_no_atmosphere(void)
{
	struct sky_state s;
	struct eng_timing t;
	state_default(&s);
	set(&s, "rayleigh_scattering_per_km=0");
	set(&s, "mie_scattering_per_km=0");
	set(&s, "mie_absorption_per_km=0");
	set(&s, "ozone_absorption_per_km=0");
	set(&s, "moon_illuminance_lx=1");
	/* The night-sky floor is light from beyond the scattering: off here. */
	set(&s, "night_zenith_luminance_cd_m2=0");
	if (compute(&s, &t) < 0)
		return;
	check_texels("vacuum", &s);
	size_t bad = 0;
	for (size_t i = 0; i < state_table_bytes(&s, STATE_TRANSMITTANCE) / 4; i++)
		bad += texel(STATE_TRANSMITTANCE, i) != 1.0f;
	for (int tb = STATE_SKYVIEW; tb <= STATE_AERIAL; tb++)
		for (size_t i = 0; i < state_table_bytes(&s, (enum state_table)tb) / 4; i++)
			bad += texel((enum state_table)tb, i) != (i % 4 == 3 ? 1.0f : 0.0f);
	if (bad)
		FAIL("vacuum: %zu texels differ from T = 1, L = 0 exactly", bad);
}

/* Changing only the sun recomputes sky-view and aerial perspective, and the
 * result is bit-identical to a full recompute. */
static void test_partial_equals_full(void)
{
	struct sky_state s;
	struct eng_timing t;
	char err[512];
	state_default(&s);
	if (compute(&s, &t) < 0)
		return;
	set(&s, "sun_elevation_deg=12");
	CHECK(eng_compute(eng, &s, STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL), &t, err,
			  sizeof(err)) == 0);
	CHECK(t.computed == (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL)));
	size_t n = state_table_bytes(&s, STATE_SKYVIEW);
	float *partial = malloc(n);
	memcpy(partial, eng_table(eng, STATE_SKYVIEW, NULL), n);
	CHECK(eng_compute(eng, &s, STATE_ALL_TABLES, &t, err, sizeof(err)) == 0);
	CHECK(memcmp(partial, eng_table(eng, STATE_SKYVIEW, NULL), n) == 0);
	free(partial);
}

static void test_f16_storage(void)
{
	struct sky_state s;
	struct eng_timing t;
	state_default(&s);
	set(&s, "storage=f16");
	if (compute(&s, &t) < 0)
		return;
	size_t n;
	const uint16_t *h = eng_table(eng, STATE_TRANSMITTANCE, &n);
	CHECK(n == 256 * 64 * 8);
	/* 0x3c00 is 1.0 in binary16: the alpha of every transmittance texel,
	 * never scaled; RGB is, by 2^15 (the largest transmittance is 1). */
	CHECK(h[3] == 0x3c00);
	CHECK(eng_table_scale_log2(eng, STATE_TRANSMITTANCE) == -15);
	double zenith = ldexp(skysample_half(h[0]), eng_table_scale_log2(eng, STATE_TRANSMITTANCE));
	CHECK(zenith > 0.9 && zenith < 1.0);	/* zenith transmittance ~0.94 */

	/* Half floats hold every sky: not only the default Earth but Mars'
	 * sky-view, above 65504 at 133.8 klx, and the night at -18 degrees,
	 * whose radiance lies below the half's normal range: each table's
	 * scale moves its values into that range. */
	struct eng_f16_range r;
	eng_f16_range(eng, &s, STATE_ALL_TABLES, &r);
	CHECK(r.overflow == 0 && !eng_f16_broken(&r));
	CHECK(r.radiance_values == 3 * (192 * 108 + 32 * 32 * 32));
	set(&s, "preset=mars");
	if (compute(&s, &t) < 0)
		return;
	eng_f16_range(eng, &s, STATE_ALL_TABLES, &r);
	CHECK(r.overflow == 0 && !eng_f16_broken(&r));
	state_default(&s);
	set(&s, "storage=f16");
	set(&s, "sun_elevation_deg=-18");
	if (compute(&s, &t) < 0)
		return;
	eng_f16_range(eng, &s, STATE_ALL_TABLES, &r);
	CHECK(r.overflow == 0 && !eng_f16_broken(&r));
	printf("f16 at -18 degrees: %llu of %llu radiance values subnormal\n",
	       (unsigned long long)r.subnormal, (unsigned long long)r.radiance_values);
}

int main(void)
{
	eng = vk_or_skip();
	printf("device: %s\n", eng_device(eng)->name);
	test_zenith_transmittance();
	test_no_atmosphere();
	test_partial_equals_full();
	test_f16_storage();
	test_against_model();
	test_thick_against_model();
	eng_free(eng);
	return test_report("test_engine");
}

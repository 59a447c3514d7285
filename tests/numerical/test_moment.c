/* test_moment.c - the shape of the multiply scattered light for a
 * forward-peaked phase (ms_source in shaders/common.glsl): the phases'
 * Legendre moments against closed forms, the rule that switches it on, and
 * what it does to Mars' sky in the model, and the engine's sky doing the
 * same (test_engine's PSNR bound alone does not catch a shape with band
 * 1's sign flipped). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "sky_probe.h"
#include "vk_or_skip.h"


static void test_legendre(void)
{
	/* Henyey-Greenstein: g^l exactly. */
	CHECK(phase_legendre(ATMO_PHASE_HENYEY_GREENSTEIN, 0.85, 1) == 0.85);
	CHECK(fabs(phase_legendre(ATMO_PHASE_HENYEY_GREENSTEIN, 0.85, 2) - 0.7225) < 1e-12);
	/* Cornette-Shanks by quadrature against its closed-form mean cosine
	 * 3 g (4 + g^2) / (5 (2 + g^2)), forward and backward, and its
	 * g2 against an adaptive quadrature in 30 digits (mpmath's quad). */
	static const double gs[][2] = {
		{ 0.8, 0.709662337662338 }, { 0.85, 0.778655253837072 },
		{ 0.99, 0.98461440105078 }, { -0.5, 0.357142857142857 },
	};
	for (size_t i = 0; i < sizeof(gs) / sizeof(gs[0]); i++) {
		double g = gs[i][0], want = 3.0 * g * (4.0 + g * g) / (5.0 * (2.0 + g * g));
		double got = phase_legendre(ATMO_PHASE_CORNETTE_SHANKS, g, 1);
		if (!(fabs(got - want) < 1e-7))
			FAIL("Cornette-Shanks g %.2f: g1 %.9f, closed form %.9f", g, got, want);
		got = phase_legendre(ATMO_PHASE_CORNETTE_SHANKS, g, 2);
		if (!(fabs(got - gs[i][1]) < 1e-7))
			FAIL("Cornette-Shanks g %.2f: g2 %.9f, want %.9f", g, got, gs[i][1]);
	}
	/* Rayleigh: 3/4 (1 + mu^2) = 1 + P2 / 2, so g1 = 0 and g2 = 1/10. */
	CHECK(phase_legendre(ATMO_PHASE_RAYLEIGH, 0, 1) == 0.0);
	double r2 = phase_legendre(ATMO_PHASE_RAYLEIGH, 0, 2);
	if (!(fabs(r2 - 0.1) < 1e-6))
		FAIL("Rayleigh g2 %.8f, want 0.1", r2);
	CHECK(phase_legendre(ATMO_PHASE_NONE, 0.8, 1) == 0.0);
}

/* Which constituent the rule picks: Mars' dust, not Earth's thin Mie layer,
 * unless asked for. */
static void test_rule(void)
{
	probe_check_rule(phase_moment_constituent, "multiscatter_moment");
}

static const struct probe_dir mars_dirs[] = {
	{ 1, 150 },	/* horizon beside the sun */
	{ 1, 90 },	/* horizon across */
	{ 90, 0 },	/* zenith */
};
static const double mars_lo[] = { 1.3, 1.05, 0.6 }, mars_hi[] = { 1.7, 1.3, 0.9 };
#define N_MARS_DIRS (sizeof(mars_dirs) / sizeof(mars_dirs[0]))

/* The shape is the higher orders' term only where delta-M is off. */
static void mars_state(struct sky_state *s)
{
	probe_mars_sun5(s, "multiscatter_delta=off");
}

/* Sky luminance with the shape on over off in mars_dirs, from sky(). */
static void mars_ratios(probe_sky_fn *sky, void *arg, double ret[N_MARS_DIRS])
{
	struct sky_state s;
	mars_state(&s);
	probe_on_off(sky, arg, &s, "multiscatter_moment=auto", "multiscatter_moment=off", mars_dirs,
		     N_MARS_DIRS, ret);
}

/* Mars, sun 5 deg at azimuth 180, 0.2 km: against the path tracer the
 * isotropic phase read the horizon 30 deg beside the sun 60 % low, the
 * horizon elsewhere 20-30 % low and the zenith 18 % high; the shape must
 * move each the right way. */
static double model_ratio[N_MARS_DIRS];

static void test_mars_sky(void)
{
	mars_ratios(probe_model_sky, NULL, model_ratio);
	for (size_t i = 0; i < N_MARS_DIRS; i++) {
		double r = model_ratio[i];
		printf("mars sun 5, model: elevation %g azimuth %g: on / off %.3f\n", mars_dirs[i].el_deg,
		       mars_dirs[i].az_deg, r);
		if (!(r >= mars_lo[i] && r <= mars_hi[i]))
			FAIL("elevation %g azimuth %g: on / off %.3f outside [%g, %g]", mars_dirs[i].el_deg,
			     mars_dirs[i].az_deg, r, mars_lo[i], mars_hi[i]);
	}
}

/* The engine's ratios within 2 % of the model's. */
static void test_engine_mars_sky(struct eng *e)
{
	double r[N_MARS_DIRS] = { 0 };
	mars_ratios(probe_engine_sky, e, r);
	for (size_t i = 0; i < N_MARS_DIRS; i++) {
		printf("mars sun 5, engine: elevation %g azimuth %g: on / off %.3f\n", mars_dirs[i].el_deg,
		       mars_dirs[i].az_deg, r[i]);
		if (!(fabs(r[i] / model_ratio[i] - 1.0) < 0.02))
			FAIL("engine elevation %g azimuth %g: on / off %.3f, model %.3f", mars_dirs[i].el_deg,
			     mars_dirs[i].az_deg, r[i], model_ratio[i]);
	}
}

int main(void)
{
	test_legendre();
	test_rule();
	test_mars_sky();
	/* The engine last: without Vulkan the test is reported skipped, so
	 * the CPU checks' failures must not hide behind it. */
	if (test_failures)
		return test_report("test_moment");
	struct eng *e = vk_or_skip();
	test_engine_mars_sky(e);
	eng_free(e);
	return test_report("test_moment");
}

/* test_weather_visibility.c - the engine's own horizontal transmittance at
 * the ground reproduces the visibility set with visibility_km.
 *
 * Koschmieder: a black object is seen until its contrast falls to 2 %, at
 * V = 3.912 / sigma with sigma the extinction at 550 nm at the ground; so
 * along a horizontal view T(V) = exp(-3.912) in the green channel. The
 * weather model gives the aerosol what the air (Rayleigh; the ozone tent is
 * 0 at the ground) leaves of 3.912 / V, so the total, which the engine
 * integrates, must come back.
 *
 * Method: the aerial-perspective volume of a camera on the ground looking
 * level. Its middle row (odd height) looks exactly along the pitch, and
 * with linear slices over twice V the far edge of slice depth / 2 - 1 lies
 * at V. The volume's A channel is the mean of the three channels'
 * transmittance; to read the green one from it, the test copies every
 * constituent's green coefficients into red and blue of the resolved state
 * (what the engine computes with), which leaves the green extinction, the
 * one Koschmieder speaks of, as the weather made it. On Earth's radius a
 * level ray climbs d^2 / 2R (200 m at 50 km) out of the aerosol's densest
 * air, which Koschmieder's flat ground does not; the test therefore runs
 * on a planet of 1e6 km (the flat stiff case), where the ray stays within
 * 1.3 m of the ground, and on Earth's radius up to 20 km, where it climbs
 * 31 m (50 km is only reported there). Exits 77 without a Vulkan device. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

#include "eng.h"
#include "test.h"
#include "vk_or_skip.h"

#define KOSCHMIEDER 3.912
#define TOLERANCE 0.02		/* relative, on the visibility the engine gives back */
#define AERIAL_H 17
#define AERIAL_D 32

static struct eng *eng;

static void set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s: %s", pair, err);
}

/* The visibility the engine gives back for visibility_km = v on a planet
 * of radius_km; NAN on failure. ret_t: the green transmittance at v. */
static double engine_visibility(double v, double radius_km, const char *aerosol, double *ret_t)
{
	struct sky_state s, sky;
	struct eng_timing t;
	char err[512], pair[64];

	state_default(&s);
	snprintf(pair, sizeof(pair), "bottom_radius_km=%.17g", radius_km);
	set(&s, pair);
	snprintf(pair, sizeof(pair), "top_radius_km=%.17g", radius_km + 100.0);
	set(&s, pair);
	set(&s, "altitude_km=0");
	set(&s, "camera_pitch_deg=0");
	set(&s, "transmittance_width=64");
	set(&s, "transmittance_height=16");
	set(&s, "multiscatter_dirs=2");
	set(&s, "skyview_width=32");
	set(&s, "skyview_height=16");
	set(&s, "aerial_width=9");
	set(&s, "aerial_height=17");
	set(&s, "aerial_depth=32");
	set(&s, "aerial_steps=8");
	set(&s, "aerial_spacing=linear");
	snprintf(pair, sizeof(pair), "aerial_range_km=%.17g", 2.0 * v);
	set(&s, pair);
	snprintf(pair, sizeof(pair), "visibility_km=%.17g", v);
	set(&s, pair);
	snprintf(pair, sizeof(pair), "aerosol=%s", aerosol);
	set(&s, pair);
	if (state_validate(&s, 0, err, sizeof(err)) < 0 ||
	    state_resolve(&s, &sky, NULL, err, sizeof(err)) < 0) {
		FAIL("%.3g km: %s", v, err);
		return NAN;
	}
	for (int i = 0; i < sky.atmo.n_constituents; i++) {
		struct atmo_constituent *c = &sky.atmo.c[i];
		c->scattering_per_km[0] = c->scattering_per_km[2] = c->scattering_per_km[1];
		c->absorption_per_km[0] = c->absorption_per_km[2] = c->absorption_per_km[1];
	}
	if (eng_compute(eng, &sky, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("%.3g km: %s", v, err);
		return NAN;
	}
	const float *a = eng_table(eng, STATE_AERIAL, NULL);
	const struct state_table_quality *q = &sky.quality.t[STATE_AERIAL];
	size_t k = AERIAL_D / 2 - 1, j = (AERIAL_H - 1) / 2, i = q->width / 2;
	double tr = a[((k * q->height + j) * q->width + i) * 4 + 3];
	*ret_t = tr;
	return v * KOSCHMIEDER / -log(tr);
}

/* asserted: false only reports (the curvature figure on Earth's radius). */
static void check(double v, double radius_km, const char *aerosol, bool asserted)
{
	double tr = NAN, got = engine_visibility(v, radius_km, aerosol, &tr);
	double rel = got / v - 1.0;
	printf("radius %-9g %-11s V %5.2f km: T(V) %.6f (Koschmieder %.6f), visibility back %.4f km, %+.2f %%\n",
	       radius_km, aerosol, v, tr, exp(-KOSCHMIEDER), got, 100.0 * rel);
	if (!asserted)
		return;
	test_checks++;
	if (!(fabs(rel) <= TOLERANCE))
		FAIL("radius %g km, %s, V %g km: the engine gives back %.4f km (%+.2f %%)", radius_km,
		     aerosol, v, got, 100.0 * rel);
}

int main(void)
{
	static const double flat[] = { 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0 };
	static const double earth[] = { 0.5, 2.0, 10.0, 20.0 };

	eng = vk_or_skip();
	for (size_t i = 0; i < sizeof(flat) / sizeof(flat[0]); i++)
		check(flat[i], 1e6, "continental", true);
	check(5.0, 1e6, "urban", true);
	check(1.0, 1e6, "maritime", true);
	check(0.2, 1e6, "desert", true);
	for (size_t i = 0; i < sizeof(earth) / sizeof(earth[0]); i++)
		check(earth[i], 6360.0, "continental", true);
	check(50.0, 6360.0, "continental", false);
	eng_free(eng);
	return test_report("test_weather_visibility");
}

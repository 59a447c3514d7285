/* test_pt_orbit.c - the path tracer's observers at and above the top of the
 * atmosphere, which the accuracy matrix traces from 100 and 400 km: a view
 * ray from outside starts where it enters the air, and one that misses the
 * air sees nothing. */
#include <math.h>
#include <stdio.h>

#include "atmo.h"
#include "pt.h"
#include "test.h"

static struct pt_options options(void)
{
	struct pt_options o;
	pt_options_default(&o);
	o.rel_error = 0.01;
	o.max_samples = 1u << 20;
	o.threads = 2;
	o.seed = 11;
	return o;
}

/* Straight down, the local frame is the same all along the vertical, so
 * from 400 km the ray sees exactly what it sees from the top (100 km) and
 * from just above the top: the same air, the same sun. */
static void test_nadir_from_outside(void)
{
	struct atmo a;
	atmo_earth(&a);
	for (int c = 0; c < 3; c++)
		a.ground_albedo[c] = 0.0;
	struct pt_sun sun = { .elevation_deg = 40, .azimuth_deg = 180, .angular_radius_deg = 0.2678,
			      .illuminance = { 1e5, 1e5, 1e5 } };
	struct pt_dir down = { -90.0, 0.0 };
	struct pt_options o = options();
	const double alts[] = { 100.0, 100.001, 400.0 };
	struct pt_result r[3];
	for (int k = 0; k < 3; k++)
		CHECK(pt_render(&a, alts[k], &sun, &down, 1, &o, &r[k]) == 0);
	for (int k = 1; k < 3; k++)
		for (int c = 0; c < 3; c++) {
			double d = r[k].radiance[c] - r[0].radiance[c];
			double se = hypot(r[k].std_error[c], r[0].std_error[c]);
			printf("nadir from %g km ch %d: %.6g +- %.2g against %.6g from 100 km (%+.2f se)\n",
			       alts[k], c, r[k].radiance[c], r[k].std_error[c], r[0].radiance[c], d / se);
			CHECK(r[0].radiance[c] > 0 && fabs(d) <= 4.0 * se);
		}
}

/* From 400 km the air's top (100 km) is 17.1 deg below the horizontal:
 * a view above it misses the atmosphere and reads 0; one just below it
 * grazes thin air, faint but lit. */
static void test_miss_and_graze(void)
{
	struct atmo a;
	atmo_earth(&a);
	struct pt_sun sun = { .elevation_deg = 10, .azimuth_deg = 180, .angular_radius_deg = 0.2678,
			      .illuminance = { 1e5, 1e5, 1e5 } };
	double top_deg = -acos(a.top_radius_km / (a.bottom_radius_km + 400.0)) * 180.0 / M_PI;
	struct pt_dir dirs[3] = { { 10.0, 0.0 }, { top_deg + 0.05, 90.0 }, { top_deg - 0.3, 90.0 } };
	struct pt_options o = options();
	o.max_samples = 1u << 16;
	struct pt_result r[3];
	CHECK(pt_render(&a, 400.0, &sun, dirs, 3, &o, r) == 0);
	for (int c = 0; c < 3; c++) {
		CHECK(r[0].radiance[c] == 0.0 && r[1].radiance[c] == 0.0);
		CHECK(r[2].radiance[c] > 0.0);
	}
	printf("from 400 km: top of the air at %.3f deg; 0.3 deg below it %.4g %.4g %.4g\n", top_deg,
	       r[2].radiance[0], r[2].radiance[1], r[2].radiance[2]);
}

int main(void)
{
	test_nadir_from_outside();
	test_miss_and_graze();
	return test_report("test_pt_orbit");
}

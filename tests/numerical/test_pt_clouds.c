/* test_pt_clouds.c - the path tracer's clouds and terrain against closed
 * forms: the shadow of a homogeneous cloud slab on the air below is
 * Beer-Lambert's exp(-tau / mu0); the light a slab scatters once toward
 * an eye below it and above it is the slab's closed form with its type's
 * Henyey-Greenstein phase; a conservative slab over white ground and a
 * white plateau sends out all the light it gets (energy); a cliff's shadow
 * on a vertical view ray starts where the geometry says; a broken layer of
 * the real field shades the air as the quadrature reference says; and the
 * same seed gives the same bits on any number of threads. All in the
 * plane-parallel limit (a planet of radius 1e6 km) but the broken layer's. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "atmo.h"
#include "pt.h"
#include "test.h"

#define PI 3.14159265358979323846
#define RB 1e6

static struct pt_sun sun_at(double elevation_deg, double azimuth_deg, double e)
{
	return (struct pt_sun){ .elevation_deg = elevation_deg, .azimuth_deg = azimuth_deg,
		.angular_radius_deg = 0.01, .illuminance = { e, e, e } };
}

static struct pt_options options(enum pt_mode mode, double rel_error)
{
	struct pt_options o;
	pt_options_default(&o);
	o.mode = mode;
	o.rel_error = rel_error;
	o.min_samples = 2048;
	o.batch = 2048;
	o.max_samples = 1u << 21;
	o.seed = 11;
	return o;
}

static int near(const char *what, int i, int ch, double mc, double se, double ref, double k,
		double slack)
{
	int ok = fabs(mc - ref) <= k * se + slack;
	printf("%s dir %d ch %d: mc %.6g +- %.2g ref %.6g (%+.2f se, %+.3f %%)%s\n", what, i, ch,
	       mc, se, ref, se > 0 ? (mc - ref) / se : 0.0, ref != 0 ? 100.0 * (mc / ref - 1) : 0.0,
	       ok ? "" : "  <-- FAIL");
	return ok;
}

/* Air of one constituent, homogeneous over a shell of shell_km on the flat
 * planet. */
static void air(struct atmo *a, double shell_km, double scattering_per_km, enum atmo_phase phase,
		double g, double albedo)
{
	memset(a, 0, sizeof(*a));
	a->bottom_radius_km = RB;
	a->top_radius_km = RB + shell_km;
	a->n_constituents = 1;
	snprintf(a->c[0].name, sizeof(a->c[0].name), "air");
	for (int ch = 0; ch < 3; ch++) {
		a->c[0].scattering_per_km[ch] = scattering_per_km;
		a->ground_albedo[ch] = albedo;
	}
	a->c[0].phase = phase;
	a->c[0].g = g;
	a->c[0].density.layers[1].constant = 1.0;
}

/* A homogeneous cloud slab: a stratus layer at full cover with its fades
 * and erosion taken away, so that its density is extinction_per_km
 * throughout (base, top): its g (0.85) and albedo (1) are the type's. */
static void slab_layer(struct pt_scene *sc, double base_km, double top_km, double ext_per_km)
{
	struct skycloudd_layer *L = &sc->layers[sc->n_layers++];
	skycloudd_layer_init(L, SKYCLOUD_STRATUS, 1.0, base_km, top_km, 0, 0);
	L->inv_bottom_fade = L->inv_top_fade = 1e12;
	L->erosion = 0.0;
	L->inv_keep = 1.0;
	L->extinction_per_km = ext_per_km;
}

static double hg(double g, double mu)
{
	double den = 1.0 + g * g - 2.0 * g * mu;
	return (1.0 - g * g) / (4.0 * PI * den * sqrt(den));
}

/* The air under a slab of optical depth 2 lit at 60 degrees: its single
 * scattering is the clear sky's times exp(-2 / sin 60), in the tracer
 * (ratio tracking through the layer's majorant) and in the reference. */
static void test_beer_lambert(void)
{
	struct atmo a;
	struct pt_scene sc = { 0 };
	air(&a, 5.0, 0.01, ATMO_PHASE_RAYLEIGH, 0.0, 0.0);
	slab_layer(&sc, 2.0, 2.5, 4.0);
	struct pt_sun sun = sun_at(60.0, 180.0, 1000.0);
	const struct pt_dir dirs[] = { { -10, 0 }, { -30, 180 }, { -60, 90 } };
	enum { N = sizeof(dirs) / sizeof(dirs[0]) };
	struct pt_result res[N];
	double t = exp(-2.0 / sin(60.0 * PI / 180.0));
	struct pt_options o = options(PT_SINGLE, 0.003);

	CHECK(pt_render_scene(&a, 1.0, &sun, &sc, dirs, N, &o, res) == 0);
	for (int i = 0; i < N; i++) {
		double clear[3], shaded[3], f;
		CHECK(pt_single_scatter_reference(&a, 1.0, &sun, &dirs[i], clear) == 0);
		CHECK(pt_single_scatter_scene(&a, 1.0, &sun, &sc, &dirs[i], shaded) == 0);
		CHECK(pt_shadow_fraction(&a, 1.0, &sun, &sc, &dirs[i], &f) == 0);
		CHECK_NEAR(f, 1.0 - t, 1e-5);
		for (int ch = 0; ch < 3; ch++) {
			CHECK_NEAR(shaded[ch] / (clear[ch] * t), 1.0, 1e-5);
			CHECK(near("beer-lambert", i, ch, res[i].radiance[ch], res[i].std_error[ch],
				   clear[ch] * t, 3.0, 0.0));
		}
	}
}

/* Single scattering of a slab of optical depth tau seen by an eye below
 * (transmitted) and above (reflected), sun mu0, view mu:
 *   below: E p mu0 / (mu - mu0) (exp(-tau / mu) - exp(-tau / mu0))
 *   above: E p mu0 / (mu0 + mu) (1 - exp(-tau (1 / mu0 + 1 / mu)))
 * with the type's Henyey-Greenstein p; the air is 1e-9 per km. */
static void test_slab_single(void)
{
	struct atmo a;
	struct pt_scene sc = { .view = PT_VIEW_ALL };
	air(&a, 5.0, 1e-9, ATMO_PHASE_RAYLEIGH, 0.0, 0.0);
	slab_layer(&sc, 1.0, 2.0, 2.0);
	const double tau = 2.0, e = 1000.0, g = 0.85;
	struct pt_sun sun = sun_at(30.0, 90.0, e);
	const double mu0 = 0.5;
	struct { double alt, el, az; } v[] = { { 0.001, 60, 0 }, { 0.001, 40, 120 }, { 3.0, -60, 0 },
					       { 3.0, -20, 300 } };
	enum { N = sizeof(v) / sizeof(v[0]) };
	struct pt_options o = options(PT_SINGLE, 0.003);
	for (int i = 0; i < N; i++) {
		struct pt_dir d = { v[i].el, v[i].az };
		struct pt_result res;
		double el = v[i].el * PI / 180.0, mu = fabs(sin(el));
		/* cos of the scattering angle: the sun's direction with the ray's. */
		double az_s = 90.0 * PI / 180.0, az_v = v[i].az * PI / 180.0, es = asin(mu0);
		double cs = cos(es) * cos(el) * cos(az_s - az_v) + sin(es) * sin(el);
		double p = hg(g, cs), ref;
		if (v[i].el > 0)
			ref = e * p * mu0 / (mu - mu0) * (exp(-tau / mu) - exp(-tau / mu0));
		else
			ref = e * p * mu0 / (mu0 + mu) * (1.0 - exp(-tau * (1.0 / mu0 + 1.0 / mu)));
		CHECK(pt_render_scene(&a, v[i].alt, &sun, &sc, &d, 1, &o, &res) == 0);
		for (int ch = 0; ch < 3; ch++)
			CHECK(near("slab single", i, ch, res.radiance[ch], res.std_error[ch], ref, 3.0, 0.0));
	}
}

/* A plateau 0.5 km high over 400 km, white, under conservative air and a
 * conservative slab: every watt that comes in goes out. The radiance going
 * up at the top, integrated over the hemisphere (stratified cosine-weighted
 * directions), is the incident flux. */
static void test_energy(void)
{
	static uint16_t white[4] = { 65535, 65535, 65535, 65535 };
	const struct skyterrain plateau = { .texels = white, .width = 2, .height = 2,
					    .max_texel = 65535, .extent_km = 400.0, .height_km = 0.5 };
	struct atmo a;
	struct pt_scene sc = { .view = PT_VIEW_ALL, .terrain = &plateau };
	air(&a, 10.0, 0.05, ATMO_PHASE_RAYLEIGH, 0.0, 1.0);
	slab_layer(&sc, 2.0, 3.0, 3.0);
	double elevation = 40.0, e = 1000.0;
	struct pt_sun sun = sun_at(elevation, 180.0, e);
	enum { NU = 12, NP = 12, N = NU * NP };
	static struct pt_dir dirs[N];
	static struct pt_result res[N];
	uint64_t state = 4242;
	for (int i = 0; i < NU; i++)
		for (int k = 0; k < NP; k++) {
			state = state * 6364136223846793005ull + 1442695040888963407ull;
			double j1 = (double)(state >> 11) * 0x1.0p-53;
			state = state * 6364136223846793005ull + 1442695040888963407ull;
			double j2 = (double)(state >> 11) * 0x1.0p-53;
			double mu = sqrt((i + j1) / NU);
			dirs[i * NP + k] = (struct pt_dir){ -asin(mu) * 180.0 / PI, 360.0 * (k + j2) / NP };
		}
	struct pt_options o = options(PT_GROUND, 0.0);
	o.min_samples = o.max_samples = o.batch = 512;
	CHECK(pt_render_scene(&a, 10.0, &sun, &sc, dirs, N, &o, res) == 0);
	double f_in = e * sin(elevation * PI / 180.0);
	for (int ch = 0; ch < 3; ch++) {
		double sum = 0.0, var = 0.0;
		for (int i = 0; i < N; i++)
			sum += res[i].radiance[ch];
		for (int i = 0; i < N; i += 2) {
			double dlt = res[i].radiance[ch] - res[i + 1].radiance[ch];
			var += dlt * dlt;
		}
		double f = PI * sum / N, se = PI * sqrt(var) / N;
		printf("energy with a cloud and a plateau, ch %d: out %.6g +- %.2g in %.6g ratio %.5f\n",
		       ch, f, se, f_in, f / f_in);
		CHECK(fabs(f - f_in) <= 3.0 * se + 2e-3 * f_in);
	}
}

/* A cliff east of the observer: 0 west of x = 1.75 km, 1 km east of 2.25
 * km (20 km square, 0.5 km texels). The sun low in the east (10 degrees):
 * the air over the observer is in shadow below z_s = 1 - 2.25 tan 10, and
 * the zenith's single scattering is the integral from z_s up in a
 * homogeneous Rayleigh slab of 2 km. */
static uint16_t cliff_texels[40 * 40];

static void test_cliff(void)
{
	for (int j = 0; j < 40; j++)
		for (int i = 0; i < 40; i++)
			cliff_texels[j * 40 + i] = i >= 24 ? 65535 : 0;
	const struct skyterrain cliff = { .texels = cliff_texels, .width = 40, .height = 40,
					  .max_texel = 65535, .extent_km = 20.0, .height_km = 1.0 };
	struct atmo a;
	struct pt_scene sc = { .terrain = &cliff };
	const double sigma = 0.2, zt = 2.0, e = 1000.0, el = 10.0 * PI / 180.0;
	air(&a, zt, sigma, ATMO_PHASE_RAYLEIGH, 0.0, 0.0);
	struct pt_sun sun = sun_at(10.0, 90.0, e);
	const struct pt_dir up = { 90.0, 0.0 };
	double mu0 = sin(el), zs = 1.0 - 2.25 * tan(el), k = 1.0 / mu0 - 1.0;
	double p = 3.0 / (16.0 * PI) * (1.0 + mu0 * mu0);
	/* E sigma p int_zs^zt exp(-sigma z) exp(-sigma (zt - z) / mu0) dz */
	double ref = e * sigma * p * exp(-sigma * zt / mu0) *
		     (exp(sigma * k * zt) - exp(sigma * k * zs)) / (sigma * k);
	double det[3], f;
	CHECK(pt_single_scatter_scene(&a, 0.001, &sun, &sc, &up, det) == 0);
	CHECK(pt_shadow_fraction(&a, 0.001, &sun, &sc, &up, &f) == 0);
	printf("cliff: shadow below %.4f km, reference %.6g, quadrature %.6g, shadowed %.1f %%\n", zs,
	       ref, det[1], 100 * f);
	/* The quadrature's cells are cut to 50 m below the cliff's top: the
	 * shadow's edge costs 0.1 %. f: 1 - that over the clear integral. */
	CHECK_NEAR(det[1] / ref, 1.0, 1e-3);
	double clear = e * sigma * p * exp(-sigma * zt / mu0) * (exp(sigma * k * zt) - 1.0) / (sigma * k);
	CHECK_NEAR(f, 1.0 - ref / clear, 2e-3);
	struct pt_result res;
	struct pt_options o = options(PT_SINGLE, 0.003);
	CHECK(pt_render_scene(&a, 0.001, &sun, &sc, &up, 1, &o, &res) == 0);
	for (int ch = 0; ch < 3; ch++)
		CHECK(near("cliff", 0, ch, res.radiance[ch], res.std_error[ch], ref, 3.0, 0.0));
}

/* The real field: a broken stratocumulus shades the air below it as the
 * quadrature reference says (its cloud optical depth by 256 midpoints). */
static void test_broken_layer(void)
{
	struct atmo a;
	struct pt_scene sc = { 0 };
	atmo_earth(&a);
	skycloudd_layer_init(&sc.layers[0], SKYCLOUD_STRATOCUMULUS, 0.75, 1.0, 1.4, 7u, 0);
	sc.n_layers = 1;
	sc.offset_km[0] = 3.25;
	struct pt_sun sun = sun_at(25.0, 180.0, 100000.0);
	const struct pt_dir dirs[] = { { 90, 0 }, { 30, 180 }, { 10, 0 }, { 5, 90 } };
	enum { N = sizeof(dirs) / sizeof(dirs[0]) };
	struct pt_result res[N];
	struct pt_options o = options(PT_SINGLE, 0.005);
	CHECK(pt_render_scene(&a, 0.2, &sun, &sc, dirs, N, &o, res) == 0);
	for (int i = 0; i < N; i++) {
		double ref[3], f;
		CHECK(pt_single_scatter_scene(&a, 0.2, &sun, &sc, &dirs[i], ref) == 0);
		CHECK(pt_shadow_fraction(&a, 0.2, &sun, &sc, &dirs[i], &f) == 0);
		printf("broken layer dir %d: %.1f %% of its single scattering shadowed\n", i, 100 * f);
		for (int ch = 0; ch < 3; ch++)
			CHECK(near("broken layer", i, ch, res[i].radiance[ch], res[i].std_error[ch],
				   ref[ch], 3.0, 2e-3 * ref[ch]));
	}
}

/* Same seed, any number of threads: the same bits, clouds and terrain
 * included; and a scene the tracer cannot take is refused. */
static void test_determinism(void)
{
	struct atmo a;
	struct pt_scene sc = { 0 };
	atmo_earth(&a);
	const struct skyterrain cliff = { .texels = cliff_texels, .width = 40, .height = 40,
					  .max_texel = 65535, .extent_km = 20.0, .height_km = 1.0 };
	skycloudd_layer_init(&sc.layers[0], SKYCLOUD_CUMULUS, 0.4, 1.0, 2.5, 3u, 0);
	sc.n_layers = 1;
	sc.terrain = &cliff;
	struct pt_sun sun = sun_at(8.0, 90.0, 1000.0);
	const struct pt_dir dirs[] = { { 45, 0 }, { 3, 90 }, { -10, 270 } };
	struct pt_result r1[3], r2[3];
	struct pt_options o = options(PT_GROUND, 0.0);
	o.min_samples = o.max_samples = o.batch = 256;
	o.threads = 1;
	CHECK(pt_render_scene(&a, 0.3, &sun, &sc, dirs, 3, &o, r1) == 0);
	o.threads = 3;
	CHECK(pt_render_scene(&a, 0.3, &sun, &sc, dirs, 3, &o, r2) == 0);
	CHECK(memcmp(r1, r2, sizeof(r1)) == 0);
	for (int i = 0; i < 3; i++)
		for (int ch = 0; ch < 3; ch++)
			CHECK(isfinite(r1[i].radiance[ch]) && r1[i].radiance[ch] >= 0.0);
	sc.n_layers = 5;
	CHECK(pt_render_scene(&a, 0.3, &sun, &sc, dirs, 3, &o, r1) < 0);
}

int main(void)
{
	test_beer_lambert();
	test_slab_single();
	test_cliff();
	test_determinism();
	test_broken_layer();
	test_energy();
	return test_report("test_pt_clouds");
}

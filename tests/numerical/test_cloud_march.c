/* test_cloud_march.c - proto/skycloudmarch.h against closed forms: a
 * uniform slab (a layer of cover 1 whose profile is flat) in the real
 * planet's spherical shell, lit by a sun of known elevation through an
 * atmosphere of known transmittance and multi-scattering.
 *
 * - The shadow on a ground point and inside the slab, from a Beer shadow
 *   map made by skycloud_shadow_texel, against the optical depth of the
 *   shell along the light (exact sphere intersections in double);
 *   terrain and the map's outside.
 * - The view march's transmittance against Beer-Lambert along vertical
 *   and slanted rays (the span is exact, the slab uniform: rounding only).
 * - Its radiance against single scattering with one octave, against the
 *   multi-octave sum, and against the ambient term, each a closed-form
 *   integral over the slab (flat: the light's path in the shell differs
 *   from the flat one by under 5e-5 here); the march takes the source at
 *   each step's midpoint, so its error falls as the square of the step,
 *   about (k dt)^2 / 24 with k the rate of the source's exponent: 1e-3 at
 *   128 steps bounds it with a margin, and with the light marched (exact
 *   on the slab) the errors at 32, 64 and 128 steps differ in the ratio 4
 *   and extrapolate to the flat slab's 5e-5.
 * - The coverage-table path: at a table's own sample points the density
 *   from the coverage is skycloud_density's, bit for bit (no anvil).
 * - The compositing's ends: no cloud gives what is behind, an opaque cloud
 *   at the eye its own light. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "skycloudmarch.h"
#include "test.h"

#define RB 6360.0
#define RT 6460.0
#define SIGMA 10.0	/* per km */
#define BASE 1.0
#define TOP 1.25	/* vertical optical depth 2.5; a float */
#define MS 0.02		/* the multi-scattering table's psi_ms, constant */
#define TR 0.8		/* the air's transmittance, constant */

static float ones[4 * 16], ms_texels[4 * 16];
static struct skysample_table trans_t = { ones, SKY_FORMAT_RGBA32F, 4, 4, 1, 0 };
static struct skysample_table ms_t = { ms_texels, SKY_FORMAT_RGBA32F, 4, 4, 1, 0 };

/* A layer of cover 1, uniform between BASE and TOP (its fades made
 * vanishingly thin: the erosion cannot take from an envelope of 1). */
static void slab(struct skycloud_layer *L)
{
	skycloud_layer_init(L, SKYCLOUD_STRATUS, 1.0, BASE, TOP, 7u, 0u);
	L->inv_bottom_fade = L->inv_top_fade = 1e9f;
	L->extinction_per_km = (float)SIGMA;
	L->profile_integral = 1.0f;
}

/* Distance from inside a sphere of radius rs, at radius r and cos-zenith
 * mu, to the sphere along the ray. */
static double to_sphere(double r, double mu, double rs)
{
	return -r * mu + sqrt(r * r * mu * mu + (rs - r) * (rs + r));
}

/* Path of the upward ray o + t d (d unit, o below TOP) through the shell
 * [BASE, TOP] of the planet: exact, in double. */
static double shell_path(const double o[3], const double d[3])
{
	double c[3] = { o[0], o[1], o[2] + RB };
	double r = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
	double mu = (c[0] * d[0] + c[1] * d[1] + c[2] * d[2]) / r;
	double top = to_sphere(r, mu, RB + TOP);
	return r < RB + BASE ? top - to_sphere(r, mu, RB + BASE) : top;
}

static void sun_dir(double el_deg, double az_deg, double ret[3])
{
	double e = el_deg * SKYMAP_PI / 180.0, a = az_deg * SKYMAP_PI / 180.0;
	ret[0] = cos(e) * sin(a);
	ret[1] = cos(e) * cos(a);
	ret[2] = sin(e);
}

#define MAP_N 64
static float map_texels[4 * MAP_N * MAP_N];
static struct skysample_table map_t = { map_texels, SKY_FORMAT_RGBA32F, MAP_N, MAP_N, 1, 0 };

static void make_map(const struct skycloud_scene *sc, const double light[3], double extent, double terrain_km,
		     struct skycloud_shadow_frame *f)
{
	skycloud_shadow_frame_init(light, extent, -extent * extent / RB, TOP, f);
	for (int j = 0; j < MAP_N; j++)
		for (int i = 0; i < MAP_N; i++)
			skycloud_shadow_texel(sc, RB, f, light, (i + 0.5) / MAP_N, (j + 0.5) / MAP_N, 16, terrain_km,
					      &map_texels[4 * (j * MAP_N + i)]);
}

static void test_shadow(void)
{
	struct skycloud_layer L;
	struct skycloud_scene sc;
	struct skycloud_shadow_frame f;
	const float off[2] = { 0.0f, 0.0f };
	double light[3];
	slab(&L);
	skycloud_scene_init(&sc, &L, 1, off);
	sun_dir(35.0, 120.0, light);
	make_map(&sc, light, 20.0, 1e30, &f);
	/* Ground points and points inside the slab, across the region. */
	double worst = 0.0;
	for (int k = 0; k < 200; k++) {
		double x = -15.0 + 30.0 * ((k * 37) % 200) / 200.0, y = -15.0 + 30.0 * ((k * 91) % 200) / 200.0;
		double z = k % 2 ? -(x * x + y * y) / (2.0 * RB) : BASE + (TOP - BASE) * ((k * 13) % 10) / 10.0;
		double p[3] = { x, y, z };
		double want = SIGMA * shell_path(p, light);
		double got = skycloud_shadow_depth(&map_t, &f, p);
		double err = fabs(got - want) / (want + 1e-3);
		worst = err > worst ? err : worst;
		CHECK_NEAR(got, want, 1e-3 * want + 1e-4);
		CHECK_NEAR(skycloud_shadow(&map_t, &f, p), exp(-want), 1e-3 * exp(-want) * want + 1e-7);
	}
	printf("shadow map 64^2, 16 steps a texel: optical depth within %.2g of the shell's (relative)\n", worst);
	/* Outside the map nothing is known: no shadow. */
	double far[3] = { 200.0, 0.0, 0.0 };
	CHECK_EQ(skycloud_shadow(&map_t, &f, far), 1.0);
	/* Terrain: past its opaque depth (plus the bias), black. */
	make_map(&sc, light, 20.0, 0.0, &f);
	double ground[3] = { 1.0, 2.0, 0.0 };
	CHECK_EQ(skycloud_shadow(&map_t, &f, ground), 0.0);
	f.terrain_bias_km = 1e3;
	CHECK(skycloud_shadow(&map_t, &f, ground) > 0.0);
}

/* The march's scene: the slab, the sun at el_deg, one octave or three. */
struct setup {
	struct skycloud_layer L;
	struct skycloud_scene sc;
	struct skycloud_light li;
	struct skycloud_sky sky;
};

static void setup(struct setup *s, double el_deg, int octaves, double ms, double tr)
{
	const float off[2] = { 0.0f, 0.0f };
	slab(&s->L);
	skycloud_scene_init(&s->sc, &s->L, 1, off);
	s->sc.octaves = octaves;
	for (int i = 0; i < 16; i++) {
		for (int c = 0; c < 3; c++) {
			ones[4 * i + c] = (float)tr;
			ms_texels[4 * i + c] = (float)ms;
		}
		ones[4 * i + 3] = ms_texels[4 * i + 3] = 1.0f;
	}
	memset(&s->li, 0, sizeof(s->li));
	sun_dir(el_deg, 200.0, s->li.dir);
	for (int c = 0; c < 3; c++)
		s->li.illuminance_lx[c] = 1000.0;
	s->sky = (struct skycloud_sky){ &trans_t, &ms_t, RB, RT };
}

static void test_beer(void)
{
	struct setup s;
	struct skycloud_sample r;
	setup(&s, 30.0, 1, 0.0, 1.0);
	const double o[3] = { 0.0, 0.0, 0.0 };
	for (int k = 0; k < 4; k++) {
		double el = (90.0 - 25.0 * k) * SKYMAP_PI / 180.0;
		double d[3] = { cos(el) * 0.6, cos(el) * 0.8, sin(el) };
		skycloud_march(&s.sc, &s.li, &s.sky, o, d, 1e30, 64, 8, 0.5, &r);
		double want = exp(-SIGMA * shell_path(o, d));
		/* Where it falls under SKYCLOUD_MARCH_MIN_TRANSMITTANCE the
		 * march stops within a step of it. */
		if (want < SKYCLOUD_MARCH_MIN_TRANSMITTANCE)
			CHECK(r.transmittance < SKYCLOUD_MARCH_MIN_TRANSMITTANCE && r.transmittance > want);
		else
			CHECK_NEAR(r.transmittance, want, 1e-9 * want);
	}
	/* Beyond the scene's depth nothing counts: a ray stopped halfway. */
	const double up[3] = { 0.0, 0.0, 1.0 };
	skycloud_march(&s.sc, &s.li, &s.sky, o, up, BASE + 0.5 * (TOP - BASE), 64, 8, 0.5, &r);
	CHECK_NEAR(r.transmittance, exp(-SIGMA * 0.5 * (TOP - BASE)), 1e-9);
	skycloud_march(&s.sc, &s.li, &s.sky, o, up, 0.5 * BASE, 64, 8, 0.5, &r);
	CHECK_EQ(r.transmittance, 1.0);
	CHECK_EQ(r.depth_km, 0.5 * BASE);
}

/* The radiance up through the flat slab from its base at the sun's
 * elevation el_deg: octaves k of b^k HG(c^k g) through extinction a^k
 * toward the sun, the air's transmittance tr, and the ambient psi_ms E
 * under the open sky exp(-sigma (H - u)). */
static double closed_form(const struct setup *s, double tr, double ms)
{
	double H = TOP - BASE, lz = s->li.dir[2], mu = s->li.dir[2], E = s->li.illuminance_lx[0];
	double sum = 0.0, bk = 1.0, ak = 1.0, ck = 1.0;
	for (int k = 0; k < s->sc.octaves; k++) {
		/* int_0^H sigma e^{-sigma u} e^{-a sigma (H - u) / lz} du */
		double kk = SIGMA * (1.0 - ak / lz);
		double I = SIGMA * exp(-ak * SIGMA * H / lz) * (fabs(kk) > 1e-12 ? (1.0 - exp(-kk * H)) / kk : H);
		sum += bk * skycloud_hg(ck * s->sc.phase_g[0], mu) * I;
		bk *= s->sc.octave_b;
		ak *= s->sc.octave_a;
		ck *= s->sc.octave_c;
	}
	return E * tr * sum + E * ms * SIGMA * H * exp(-SIGMA * H);
}

/* The march straight up from the ground, light_steps 0 (a shadow map) or
 * 32; its relative error against the closed form. */
static double scatter_error(int octaves, double ms, double tr, int steps, int light_steps)
{
	struct setup s;
	struct skycloud_sample r;
	struct skycloud_shadow_frame f;
	setup(&s, 40.0, octaves, ms, tr);
	make_map(&s.sc, s.li.dir, 10.0, 1e30, &f);
	s.li.shadow = light_steps ? NULL : &map_t;
	s.li.frame = f;
	const double o[3] = { 0.0, 0.0, 0.0 }, up[3] = { 0.0, 0.0, 1.0 };
	skycloud_march(&s.sc, &s.li, &s.sky, o, up, 1e30, steps, light_steps, 0.5, &r);
	double want = closed_form(&s, tr, ms);
	CHECK_NEAR(r.radiance[0], r.radiance[2], 1e-12 * want);
	return (r.radiance[0] - want) / want;
}

static void test_scatter(void)
{
	static const struct {
		const char *what;
		int octaves;
		double ms, tr;
	} cases[] = {
		{ "single scattering", 1, 0.0, 1.0 },
		{ "three octaves", 3, 0.0, TR },
		{ "ambient alone", 1, MS, 0.0 },
		{ "three octaves and ambient", 3, MS, TR },
	};
	/* k: the source's exponent changes at sigma / sin(40 deg) = 15.6 per
	 * km; at 128 steps over 0.3 km, (k dt)^2 / 24 = 5.3e-4. */
	const double bound = 1e-3;
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		for (int light = 0; light <= 32; light += 32) {
			double e128 = scatter_error(cases[i].octaves, cases[i].ms, cases[i].tr, 128, light);
			double e64 = scatter_error(cases[i].octaves, cases[i].ms, cases[i].tr, 64, light);
			double e32 = scatter_error(cases[i].octaves, cases[i].ms, cases[i].tr, 32, light);
			double q = (e32 - e64) / (e64 - e128);
			printf("%-26s %s: error %+.2e at 128 steps, %+.2e at 64, %+.2e at 32 (%.1f)\n", cases[i].what,
			       light ? "light march" : "shadow map ", e128, e64, e32, q);
			CHECK(fabs(e128) < bound);
			CHECK(fabs(e32) < 16.0 * bound);
			/* The light march is exact on a uniform slab: the
			 * error is the view's step, C dt^2 (successive
			 * differences in the ratio 4), plus the closed form's
			 * flat slab, which the shell is to 5e-5 here. The
			 * shadow map adds its own interpolation of the curved
			 * shell, under 2e-4. */
			if (light) {
				CHECK(q > 3.5 && q < 4.5);
				CHECK(fabs(e128 - (e64 - e128) / 3.0) < 5e-5);
			}
		}
	}
}

static void test_table(void)
{
	struct skycloud_layer L;
	const float off[2] = { 123.25f, 1000.5f };
	skycloud_layer_init(&L, SKYCLOUD_STRATOCUMULUS, 0.6, 1.0, 1.4, 99u, 2u);
	long differ = 0, cloudy = 0;
	for (int j = 0; j < 64; j++)
		for (int i = 0; i < 64; i++) {
			float x = -20.0f + (i + 0.5f) * 40.0f / 64.0f, y = -20.0f + (j + 0.5f) * 40.0f / 64.0f;
			float h = 1.0f + 0.4f * ((i * 7 + j * 3) % 16 + 0.5f) / 16.0f;
			float c = skycloud_coverage(&L, x, y, off);
			float a = skycloud_density_cov(&L, c, x, y, h, off), b = skycloud_density(&L, x, y, h, off);
			differ += memcmp(&a, &b, sizeof(a)) != 0;
			cloudy += b > 0.0f;
		}
	printf("coverage from a table at its texels: %ld of 4096 differ, %ld cloudy\n", differ, cloudy);
	CHECK_EQ(differ, 0);
	CHECK(cloudy > 400 && cloudy < 4000);
}

static void test_composite(void)
{
	const double behind[3] = { 1.0, 2.0, 3.0 }, air[3] = { 0.5, 0.5, 0.5 };
	struct skycloud_sample clear = { { 0.0, 0.0, 0.0 }, 1.0, 10.0 };
	struct skycloud_sample opaque = { { 7.0, 8.0, 9.0 }, 0.0, 0.0 };
	double rgb[3];
	skycloud_composite(behind, &clear, air, 0.9, rgb);
	CHECK_EQ(rgb[2], 3.0);
	skycloud_composite(behind, &opaque, (const double[3]){ 0.0, 0.0, 0.0 }, 1.0, rgb);
	CHECK_EQ(rgb[0], 7.0);
	/* Behind an opaque cloud at a distance: the air in front and the
	 * cloud's light through it. */
	skycloud_composite(behind, &opaque, air, 0.9, rgb);
	CHECK_NEAR(rgb[1], 0.5 + 0.9 * 8.0, 1e-12);
}

/* The ground's light under a layer (skycloud_ground_light): the two-stream
 * slab's limits (all through at tau 0, 4/3 over 4/3 + (1 - g) tau under a
 * thick one, never less than the beam alone), and a layer's cover mixing
 * the clear share with the slab's. */
static void test_ground_light(void)
{
	const double g = 0.85, mu = 0.5;
	CHECK_NEAR(skycloud_slab_transmittance(0.0, g, mu), 1.0, 1e-15);
	CHECK_NEAR(skycloud_slab_diffuse(0.0, g), 1.0, 1e-15);
	CHECK_NEAR(skycloud_slab_diffuse(400.0, g) * (4.0 / 3.0 + (1.0 - g) * 400.0), 4.0 / 3.0, 1e-9);
	for (double tau = 0.1; tau < 100.0; tau *= 2.0)
		CHECK(skycloud_slab_transmittance(tau, g, mu) > exp(-tau / mu) &&
		      skycloud_slab_transmittance(tau, g, mu) < 1.0);
	struct skycloud_layer L;
	struct skycloud_scene sc;
	const float zero[2] = { 0.0f, 0.0f };
	double e[2];
	slab(&L);
	L.cover = 0.6f;
	skycloud_scene_init(&sc, &L, 1, zero);
	skycloud_ground_light(&sc, 0.0, mu, e);
	double tau = (double)L.extinction_per_km * (L.top_km - L.base_km) * L.profile_integral;
	double c = L.cover;
	printf("ground light under the slab (tau %.2f, cover %.2f): sky %.4f, sun scattered down %.4f\n", tau, c,
	       e[0], e[1]);
	CHECK_NEAR(e[0], 1.0 - c + c * skycloud_slab_diffuse(tau, sc.phase_g[0]), 1e-12);
	CHECK_NEAR(e[1], c * (skycloud_slab_transmittance(tau, sc.phase_g[0], mu) - exp(-tau / mu)), 1e-12);
	skycloud_ground_light(&sc, 0.0, -0.1, e);
	CHECK(e[1] == 0.0);
	sc.n_layers = 0;
	skycloud_ground_light(&sc, 0.0, mu, e);
	CHECK(e[0] == 1.0 && e[1] == 0.0);
}

int main(void)
{
	test_shadow();
	test_beer();
	test_scatter();
	test_table();
	test_composite();
	test_ground_light();
	return test_report("test_cloud_march");
}

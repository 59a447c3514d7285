/* test_skycloud.c - the cloud field of proto/skycloud.h: its bits are the
 * committed ones (a checksum over a grid: what another host or compiler
 * must give too), it repeats across the period bit for bit, the covered
 * fraction of a period is the cover for 1 to 8 oktas at several seeds, the
 * density is finite and >= 0 at the ends of every key's range, the sky
 * occlusion is in [0, 1] and grows with the cover, the float and double
 * builds agree within the bounds below, the optical depth of an overcast
 * is its column's, and the wind's offset is where the wind blows. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "skycloud.h"
#define SKYCLOUD_DOUBLE 1
#include "skycloud.h"

#include "test.h"

#define P SKYCLOUD_PERIOD_KM

static uint64_t fnv_bits(uint64_t h, float v)
{
	uint32_t u;
	memcpy(&u, &v, sizeof(u));
	for (int i = 0; i < 4; i++) {
		h ^= (u >> (8 * i)) & 0xffu;
		h *= 0x100000001b3ull;
	}
	return h;
}

static void layer(struct skycloud_layer *f, struct skycloudd_layer *d, int type, double cover,
		  double base_km, double top_km, uint32_t seed, uint32_t index)
{
	skycloud_layer_init(f, type, cover, base_km, top_km, seed, index);
	if (d)
		skycloudd_layer_init(d, type, cover, base_km, top_km, seed, index);
}

/* The committed bits: coverage and density of every type over a grid
 * that crosses the wrap, hashed. A change of the function changes it (and
 * SKYCLOUD_VERSION with it); so does a compiler that fuses or reorders
 * float operations. */
#define GOLDEN_CHECKSUM 0x8fcb237af671dd73ull

static void test_golden(void)
{
	uint64_t h = 0xcbf29ce484222325ull;
	const float off[2] = { 1000.25f, 3.5f };

	for (int t = 0; t < SKYCLOUD_N_TYPES; t++) {
		struct skycloud_layer L;
		layer(&L, NULL, t, 0.1 + 0.15 * t, 0.5 + t, 1.7 + 1.5 * t, 12345u + (uint32_t)t, (uint32_t)t % 4);
		for (int j = 0; j < 40; j++)
			for (int i = 0; i < 40; i++) {
				float x = -37.125f + 1.875f * i, y = -20.0f + 1.0625f * j;
				float z = L.base_km + (L.top_km - L.base_km) * (0.5f + j) / 40.0f;
				h = fnv_bits(h, skycloud_coverage(&L, x, y, off));
				h = fnv_bits(h, skycloud_density(&L, x, y, z, off));
			}
	}
	printf("golden checksum 0x%016llx\n", (unsigned long long)h);
	if (GOLDEN_CHECKSUM)
		CHECK_EQ(h, GOLDEN_CHECKSUM);
	/* The same call twice: the same bits. */
	struct skycloud_layer L;
	layer(&L, NULL, SKYCLOUD_CUMULUS, 0.5, 1.0, 2.5, 7u, 1u);
	float a = skycloud_density(&L, 3.3f, -4.4f, 1.9f, off);
	float b = skycloud_density(&L, 3.3f, -4.4f, 1.9f, off);
	CHECK(memcmp(&a, &b, sizeof(a)) == 0);
}

/* x and x + P (both exact floats) give the same bits, east, north and
 * through the offset. */
static void test_period(void)
{
	const float zero[2] = { 0.0f, 0.0f }, shifted[2] = { (float)P, -(float)P };
	int bad = 0;

	for (int t = 0; t < SKYCLOUD_N_TYPES; t++) {
		struct skycloud_layer L;
		layer(&L, NULL, t, 0.6, 1.0, 2.0, 99u, 2u);
		for (int i = 0; i < 2000; i++) {
			float x = -512.0f + 0.515625f * i, y = 300.0f - 0.3125f * i, z = 1.5f;
			float c0 = skycloud_coverage(&L, x, y, zero);
			float c1 = skycloud_coverage(&L, x + (float)P, y, zero);
			float c2 = skycloud_coverage(&L, x, y - (float)P, zero);
			float c3 = skycloud_coverage(&L, x, y, shifted);
			float d0 = skycloud_density(&L, x, y, z, zero);
			float d1 = skycloud_density(&L, x + (float)P, y + (float)P, z, zero);
			bad += memcmp(&c0, &c1, 4) != 0 || memcmp(&c0, &c2, 4) != 0 ||
			       memcmp(&c0, &c3, 4) != 0 || memcmp(&d0, &d1, 4) != 0;
		}
	}
	CHECK_EQ(bad, 0);
}

/* The covered fraction (coverage above one half: the fBm above the
 * threshold) of a whole period on a prime grid, for 1..8 oktas, every
 * type, three seeds; and of a region of half-width 100 km, whose few
 * cells make it wander further. */
#define GRID 509
#define TOL_PERIOD 0.02
#define TOL_REGION 0.12

static void test_cover(void)
{
	const float zero[2] = { 0.0f, 0.0f };
	const uint32_t seeds[] = { 1u, 2024u, 0xdeadbeefu };
	float *v = malloc(sizeof(float) * GRID * GRID);
	double worst_period = 0.0, worst_region = 0.0;

	if (!v)
		return;
	for (int t = 0; t < SKYCLOUD_N_TYPES; t++)
		for (size_t s = 0; s < sizeof(seeds) / sizeof(seeds[0]); s++) {
			struct skycloud_layer L;
			layer(&L, NULL, t, 0.5, 1.0, 2.0, seeds[s], (uint32_t)s);
			for (int j = 0; j < GRID; j++)
				for (int i = 0; i < GRID; i++)
					v[j * GRID + i] = skycloud_coverage_fbm(
						&L, (float)(i * (double)P / GRID), (float)(j * (double)P / GRID));
			for (int oktas = 1; oktas <= 8; oktas++) {
				double cover = oktas / 8.0;
				float th = (float)skycloud_threshold(1.0 - cover);
				long n = 0, nr = 0, in = 0;
				for (int j = 0; j < GRID; j++)
					for (int i = 0; i < GRID; i++) {
						int cloud = v[j * GRID + i] > th;
						n += cloud;
						/* The region: 100 km either way of the origin. */
						double x = i * (double)P / GRID, y = j * (double)P / GRID;
						if ((x < 100.0 || x > P - 100.0) && (y < 100.0 || y > P - 100.0)) {
							in++;
							nr += cloud;
						}
					}
				double f = (double)n / (GRID * GRID), fr = (double)nr / in;
				worst_period = fmax(worst_period, fabs(f - cover));
				worst_region = fmax(worst_region, fabs(fr - cover));
				CHECK_NEAR(f, cover, TOL_PERIOD);
				CHECK_NEAR(fr, cover, TOL_REGION);
				/* The coverage function says the same as the threshold. */
				skycloud_layer_init(&L, t, cover, 1.0, 2.0, seeds[s], (uint32_t)s);
				float x = (float)(17 * (double)P / GRID), y = (float)(33 * (double)P / GRID);
				CHECK_EQ(skycloud_coverage(&L, x, y, zero) > 0.5f, v[33 * GRID + 17] > th);
				skycloud_layer_init(&L, t, 0.5, 1.0, 2.0, seeds[s], (uint32_t)s);
			}
		}
	printf("covered fraction: worst |fraction - cover| %.4f over a period, %.4f over a region of +-100 km\n",
	       worst_period, worst_region);
	free(v);
}

/* Every key at the ends of its range: cover 0..8 oktas, base and top in
 * [0, 20] km (1 m and 20 km thick), seeds 0 and 2^32 - 1, offsets 0 and
 * just under the period, positions far outside the region. */
static void test_finite(void)
{
	const double covers[] = { 0.0, 1e-9, 0.5, 1.0 - 1e-9, 1.0 };
	const double layers[][2] = { { 0.0, 0.001 }, { 0.0, 20.0 }, { 19.999, 20.0 }, { 1.0, 1.4 } };
	const uint32_t seeds[] = { 0u, 0xffffffffu };
	const float offs[][2] = { { 0.0f, 0.0f }, { 1023.9999f, 1023.9999f } };
	const float xs[] = { 0.0f, -1e4f, 1e4f, 511.99f, -0.0f, 1e-30f };
	int bad = 0, visited = 0;

	for (int t = 0; t < SKYCLOUD_N_TYPES; t++)
		for (size_t c = 0; c < 5; c++)
			for (size_t l = 0; l < 4; l++)
				for (size_t s = 0; s < 2; s++) {
					struct skycloud_layer L;
					struct skycloudd_layer D;
					layer(&L, &D, t, covers[c], layers[l][0], layers[l][1], seeds[s], 3u);
					for (size_t o = 0; o < 2; o++)
						for (size_t i = 0; i < 6; i++)
							for (int k = 0; k <= 8; k++) {
								float z = L.base_km + (L.top_km - L.base_km) * k / 8.0f;
								double od[2] = { offs[o][0], offs[o][1] };
								float v = skycloud_density(&L, xs[i], xs[5 - i], z, offs[o]);
								double w = skycloudd_density(&D, xs[i], xs[5 - i], z, od);
								float cv = skycloud_coverage(&L, xs[i], xs[5 - i], offs[o]);
								bad += !(isfinite(v) && v >= 0.0f && isfinite(w) && w >= 0.0 &&
									 cv >= 0.0f && cv <= 1.0f);
								visited++;
							}
				}
	CHECK_EQ(bad, 0);
	CHECK(visited > 10000);
}

static void test_occlusion(void)
{
	for (int t = 0; t < SKYCLOUD_N_TYPES; t++)
		for (int h = 0; h < 3; h++) {
			float last = -1.0f;
			for (int oktas = 0; oktas <= 8; oktas++) {
				struct skycloud_layer L[2];
				layer(&L[0], NULL, t, oktas / 8.0, 1.0, 2.0, 5u, 0u);
				layer(&L[1], NULL, SKYCLOUD_CIRRUS, 0.25, 8.0, 9.5, 5u, 1u);
				float o = skycloud_sky_occlusion(L, 2, (float)(h * 1.5));
				CHECK(o >= 0.0f && o <= 1.0f);
				CHECK(o >= last);
				last = o;
			}
		}
	/* Above every layer nothing occludes; under a clear sky neither. */
	struct skycloud_layer L;
	layer(&L, NULL, SKYCLOUD_STRATUS, 1.0, 1.0, 1.4, 5u, 0u);
	CHECK_EQ(skycloud_sky_occlusion(&L, 1, 2.0f), 0.0f);
	CHECK(skycloud_sky_occlusion(&L, 1, 0.0f) > 0.999f);
	layer(&L, NULL, SKYCLOUD_STRATUS, 0.0, 1.0, 1.4, 5u, 0u);
	CHECK_EQ(skycloud_sky_occlusion(&L, 1, 0.0f), 0.0f);
}

/* Float against double on the same float inputs. Where x - offset is
 * exact in a float (both on a 1/64 km grid) only the arithmetic differs:
 * coverage within TOL_ARITH_COVERAGE, density within TOL_ARITH_DENSITY of
 * the extinction. Elsewhere the float rounds x - offset to its ulp (up to
 * 6 cm at the period's far end), which moves a sharp edge (cumulus: 0.02
 * of the fBm, whose slope reaches about 3 per km) by up to
 * TOL_POSITION. */
#define TOL_ARITH_COVERAGE 2e-5
#define TOL_ARITH_DENSITY 2e-5
#define TOL_POSITION 0.02

static void precision(int exact, double *ret_c, double *ret_d)
{
	uint64_t rng = 0x5eedull;

	*ret_c = *ret_d = 0.0;
	for (int t = 0; t < SKYCLOUD_N_TYPES; t++) {
		struct skycloud_layer L;
		struct skycloudd_layer D;
		layer(&L, &D, t, 0.3 + 0.1 * t, 0.8, 0.8 + skycloud_types[t].thickness_m * 1e-3, 77u, 1u);
		for (int i = 0; i < 20000; i++) {
			double q[4];
			for (int k = 0; k < 4; k++) {
				q[k] = test_uniform(&rng) * P;
				if (exact)
					q[k] = floor(q[k] * 64.0) / 64.0;
			}
			float x = (float)(q[0] - 0.5 * P), y = (float)(q[1] - 0.5 * P);
			float z = L.base_km + (L.top_km - L.base_km) * (float)test_uniform(&rng);
			float of[2] = { (float)q[2], (float)q[3] };
			double od[2] = { of[0], of[1] };
			double c = fabs(skycloud_coverage(&L, x, y, of) - skycloudd_coverage(&D, x, y, od));
			double d = fabs(skycloud_density(&L, x, y, z, of) - skycloudd_density(&D, x, y, z, od)) /
				   skycloud_types[t].extinction_per_km;
			*ret_c = fmax(*ret_c, c);
			*ret_d = fmax(*ret_d, d);
		}
	}
}

static void test_precision(void)
{
	double c, d;

	precision(1, &c, &d);
	printf("float against double, exact positions: coverage %.3g, density %.3g of the extinction\n", c, d);
	CHECK(c <= TOL_ARITH_COVERAGE);
	CHECK(d <= TOL_ARITH_DENSITY);
	precision(0, &c, &d);
	printf("float against double, any position: coverage %.3g, density %.3g of the extinction\n", c, d);
	CHECK(c <= TOL_POSITION);
	CHECK(d <= TOL_POSITION);
}

/* An 8/8 stratus 1.0-1.4 km: its optical depth straight up is the column
 * (extinction x thickness x profile integral) less what erosion takes,
 * and slant paths hold more; no layer, nothing. */
static void test_optical_depth(void)
{
	const float off[2] = { 10.0f, 20.0f }, o[3] = { 0.0f, 0.0f, 0.2f };
	const float up[3] = { 0.0f, 0.0f, 1.0f }, slant[3] = { 0.0f, 0.8f, 0.6f };
	const float rb = 6360.0f;
	struct skycloud_layer L;

	layer(&L, NULL, SKYCLOUD_STRATUS, 1.0, 1.0, 1.4, 3u, 0u);
	double column = 90.0 * 0.4 * skycloud_profile_integral(&skycloud_types[SKYCLOUD_STRATUS]);
	float tau = skycloud_optical_depth(&L, 1, off, rb, o, up, 100.0f, 256);
	printf("overcast stratus: optical depth up %.2f of a column of %.2f\n", tau, column);
	CHECK(tau > 0.6 * column && tau <= column * 1.001);
	float ts = skycloud_optical_depth(&L, 1, off, rb, o, slant, 100.0f, 256);
	CHECK(ts > tau);
	/* Above the layer looking up: nothing; looking down through it: it. */
	const float high[3] = { 0.0f, 0.0f, 3.0f }, down[3] = { 0.0f, 0.0f, -1.0f };
	CHECK_EQ(skycloud_optical_depth(&L, 1, off, rb, high, up, 100.0f, 64), 0.0f);
	CHECK(skycloud_optical_depth(&L, 1, off, rb, high, down, 100.0f, 256) > 0.6 * column);
	layer(&L, NULL, SKYCLOUD_STRATUS, 0.0, 1.0, 1.4, 3u, 0u);
	CHECK_EQ(skycloud_optical_depth(&L, 1, off, rb, o, up, 100.0f, 64), 0.0f);
}

static void test_wind(void)
{
	double off[2], s, c;

	/* From the west at 7.72 m/s for 1000 s: 7.72 km east. */
	skycloud_wind_offset_km(270.0, 7.72, 1000.0, off);
	CHECK_NEAR(off[0], 7.72, 1e-12);
	CHECK_NEAR(off[1], 0.0, 1e-12);
	/* From the north: southward, modulo the period; backwards in time the
	 * other way. */
	skycloud_wind_offset_km(0.0, 10.0, 1000.0, off);
	CHECK_NEAR(off[1], P - 10.0, 1e-9);
	skycloud_wind_offset_km(0.0, 10.0, -1000.0, off);
	CHECK_NEAR(off[1], 10.0, 1e-9);
	/* A date in the year 6000 at 150 m/s stays in the period. */
	skycloud_wind_offset_km(123.0, 150.0, 1.3e11, off);
	CHECK(off[0] >= 0.0 && off[0] < P && off[1] >= 0.0 && off[1] < P);
	/* The deterministic sine: exact at the quadrants, libm's elsewhere. */
	double worst = 0.0;
	for (int i = -720; i <= 720; i++) {
		double d = i * 0.5 + 0.123 * (i % 3);
		skycloud_sincos_deg(d, &s, &c);
		worst = fmax(worst, fmax(fabs(s - sin(d * M_PI / 180.0)), fabs(c - cos(d * M_PI / 180.0))));
	}
	CHECK(worst < 4e-15);
	skycloud_sincos_deg(90.0, &s, &c);
	CHECK(s == 1.0 && c == 0.0);
	skycloud_sincos_deg(270.0, &s, &c);
	CHECK(s == -1.0 && c == 0.0);
}

int main(void)
{
	test_golden();
	test_period();
	test_cover();
	test_finite();
	test_occlusion();
	test_precision();
	test_optical_depth();
	test_wind();
	return test_report("test_skycloud");
}

/* test_grain.c - the engine's two grains (eng.h, enum eng_grain) give the
 * same tables within float rounding: every table of a set of scenes
 * computed at the CPU grain and at the wide grain, texel by texel; and so
 * do the two ways sky-view and aerial perspective read their lookups,
 * texel buffers filtered by hand and sampled images (eng_lookup_images).
 *
 * The bound. Both grains evaluate the same expression for each direction
 * and step; what may differ is how the sums over them associate. The CPU
 * grain adds a texel's terms one after the other; the wide grain adds each
 * lane's own terms, then the lanes' sums in lane order (ms_reduce in
 * shaders/msgrid.glsl). The terms are non-negative (L2, the ground's
 * bounce, the escape, psi read back), and a sum of n non-negative terms
 * computed in any order lies within (n - 1) u of the exact sum, relative,
 * u = 2^-24: two orders differ by at most 2 (n - 1) u. A texel sums 32
 * directions (2 for multiscatter_dirs=2) of 20 steps (the default) and a
 * ground bounce each, n = 672, so
 * multi-scattering agrees within 2 x 671 u = 8.0e-5; each step of the
 * iteration of psi_ms sums as many and reads the last, adding as much
 * again; sky-view and aerial perspective weigh psi by non-negative
 * factors and carry its relative error, no more. With the float16 storage,
 * a value that lies on a half's rounding edge may round either way: one
 * half ulp, 2^-10 of it, more. Values below 1e-6 of their table's largest
 * are held to the bound times that floor (the relative error of nothing
 * says nothing). On lavapipe the sums that do not iterate come out bit for
 * bit (the lanes' sums are added in the CPU grain's order, and no multiply
 * is fused into them); the iteration's measured worst is 17 u.
 *
 * The lookups. A sampled image read at texel coordinates p + 0.5 finds the
 * same texels and the same fraction as bilinear() (p + 0.5 is exact below
 * 2^22); what differs is how the four texels are weighed: the hand's two
 * nested lerps against the sampler's own arithmetic, a few roundings each,
 * 8 u at most for one lookup apart from the hand's 4. A source term
 * multiplies two lookups (transmittance and multi-scattering) and the
 * march adds such terms with non-negative weights, which keeps their
 * relative error: 2 x (8 + 4) u, held to 32 u. That is lavapipe's
 * sampler, which filters float32 in float; a GPU's texture units weigh
 * with 8-bit fractions, an error of up to 2^-9 of the step between two
 * texels, not float rounding, so the images are compared on CPU devices
 * only (the measured worst on lavapipe: 5.8 u). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eng.h"
#include "skysample.h"
#include "test.h"
#include "vk_or_skip.h"

static struct eng *eng;

/* Every table of s at grain g, as float32 values (halves widened, times
 * their scale), in ret (malloc'd); ret_n: values per table. */
static int tables_at(const struct sky_state *s, enum eng_grain g, int images,
		     double *ret[STATE_N_TABLES], size_t ret_n[STATE_N_TABLES])
{
	struct eng_timing t;
	char err[512];

	eng_set_grain(eng, g);
	eng_set_lookup_images(eng, images);
	eng_forget_columns(eng);
	if (eng_compute(eng, s, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("%s grain: %s", eng_grain_name(g), err);
		return -1;
	}
	for (int k = 0; k < STATE_N_TABLES; k++) {
		size_t bytes;
		const void *p = eng_table(eng, (enum state_table)k, &bytes);
		bool half = s->quality.storage == STATE_F16;
		double scale = ldexp(1.0, eng_table_scale_log2(eng, (enum state_table)k));
		ret_n[k] = bytes / (half ? 2 : 4);
		ret[k] = malloc(ret_n[k] * sizeof(double));
		if (!ret[k] || !p)
			return -1;
		for (size_t i = 0; i < ret_n[k]; i++)
			ret[k][i] = half ? skysample_half(((const uint16_t *)p)[i]) * (i % 4 == 3 ? 1.0 : scale)
					 : ((const float *)p)[i];
	}
	return 0;
}

/* The bound of the header for s: the sums' worst case, and a half ulp
 * with float16 storage. */
static double bound(const struct sky_state *s)
{
	double cells = s->quality.multiscatter_dirs == 64 ? 32.0 : 2.0;	/* half the grid is marched */
	double n = cells * (s->quality.t[STATE_MULTISCATTER].steps + 1);
	double sums = (1 + state_multiscatter_iterations(s)) * 2 * (n - 1) * ldexp(1.0, -24);
	return sums + (s->quality.storage == STATE_F16 ? ldexp(1.0, -10) : 0.0);
}

/* Every table of s at the CPU grain with buffers against the other way
 * (the wide grain, or the CPU grain with images), within eps. */
static void compare(const char *scene, const struct sky_state *s, enum eng_grain g, int images,
		    double eps)
{
	double *cpu[STATE_N_TABLES] = { 0 }, *wide[STATE_N_TABLES] = { 0 };
	size_t n[STATE_N_TABLES], m[STATE_N_TABLES];
	char what[400];

	snprintf(what, sizeof(what), "%s (%s)", scene, images ? "images" : eng_grain_name(g));
	scene = what;
	if (tables_at(s, ENG_GRAIN_CPU, 0, cpu, n) == 0 && tables_at(s, g, images, wide, m) == 0) {
		for (int k = 0; k < STATE_N_TABLES; k++) {
			double peak = 0, worst = 0;
			size_t differ = 0;
			CHECK_EQ(n[k], m[k]);
			for (size_t i = 0; i < n[k]; i++)
				peak = fmax(peak, fabs(cpu[k][i]));
			for (size_t i = 0; i < n[k] && n[k] == m[k]; i++) {
				double d = fabs(cpu[k][i] - wide[k][i]);
				double ref = fmax(fabs(cpu[k][i]), 1e-6 * peak);
				differ += d > 0;
				worst = fmax(worst, d / ref);
				if (!(d <= eps * ref))
					FAIL("%s: %s value %zu: cpu %.9g, other %.9g", scene, state_table_names[k], i,
					     cpu[k][i], wide[k][i]);
			}
			printf("%-44s %-14s %7zu of %7zu differ, worst %.2e (%.1f u), bound %.2e\n", scene,
			       state_table_names[k], differ, n[k], worst, worst / ldexp(1.0, -24), eps);
		}
	}
	for (int k = 0; k < STATE_N_TABLES; k++) {
		free(cpu[k]);
		free(wide[k]);
	}
}

static void scene(const char *pairs)
{
	struct sky_state s;
	char err[256], copy[256];

	state_default(&s);
	snprintf(copy, sizeof(copy), "%s", pairs);
	for (char *save, *p = strtok_r(copy, " ", &save); p; p = strtok_r(NULL, " ", &save))
		if (state_set_pair(&s, p, NULL, err, sizeof(err)) < 0) {
			FAIL("%s: %s", pairs, err);
			return;
		}
	if (state_validate(&s, 0, err, sizeof(err)) < 0) {
		FAIL("%s: %s", pairs, err);
		return;
	}
	compare(pairs, &s, ENG_GRAIN_WIDE, 0, bound(&s));
	/* The texture units of a GPU filter with fewer bits (the header). */
	if (!strcmp(eng_device(eng)->type_name, "cpu") && s.quality.storage == STATE_F32)
		compare(pairs, &s, ENG_GRAIN_CPU, 1, 32 * ldexp(1.0, -24));
}

int main(void)
{
	eng = vk_or_skip();
	/* The grains' paths: the CPU grain's four sun angles and twelve
	 * azimuths an invocation, the wide grain's lanes; the 2-direction
	 * grid (quality=low), the shape and delta-M (Mars), the moon, the
	 * iteration of psi_ms and float16 storage. */
	scene("sun_elevation_deg=30");
	scene("sun_elevation_deg=-2 sun_azimuth_deg=270");
	scene("sun_elevation_deg=10 moon_elevation_deg=40 moon_illuminance_lx=0.25");
	scene("preset=mars sun_elevation_deg=20");
	scene("quality=low sun_elevation_deg=5");
	scene("multiscatter_iterations=3 sun_elevation_deg=10");
	scene("storage=f16 sun_elevation_deg=3");
	scene("cloud_oktas=6 sun_elevation_deg=20");
	eng_free(eng);
	return test_report("test_grain");
}

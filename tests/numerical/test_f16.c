/* test_f16.c - storage=f16 against storage=f32: the same engine computes
 * each scene both ways, and every binary16 value, times its table's
 * power-of-two scale, must be the float32 value rounded once, on Earth by
 * day, in twilight, under the moon at night and on Mars, whose sky-view
 * passes the half's 65504 cd/m2; so must a client's bilinear samples.
 *
 * The bound: a half has 11 significant bits, so rounding to nearest (what
 * packHalf2x16 does on lavapipe and the GPUs we know) moves a value in the
 * normal range, |x| 2^-k >= 2^-14, by at most 2^-11 |x|, and one below it
 * (a subnormal half) by at most half its step, 2^(k - 25). A bilinear
 * sample weighs its taps with weights >= 0 that sum to 1, so its error is
 * at most 2^-11 S + 2^(k - 25) for a sample S of non-negative taps. Every
 * sky radiance at or above the night floor (the night sky's zenith
 * luminance, the dimmest sky there is) must be a normal half: there the
 * bound is the relative 2^-11. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eng.h"
#include "skysample.h"
#include "test.h"
#include "vk_or_skip.h"

#define REL 0x1p-11

static struct eng *eng;

struct scene {
	const char *name;
	const char *keys[4];
};

static const struct scene scenes[] = {
	{ "earth sun 20", { "sun_elevation_deg=20" } },
	{ "earth sun 60", { "sun_elevation_deg=60" } },
	{ "earth twilight -6", { "sun_elevation_deg=-6" } },
	{ "earth night, moon 30", { "sun_elevation_deg=-18", "moon_elevation_deg=30",
				    "moon_illuminance_lx=0.25" } },
	{ "mars sun 20", { "preset=mars", "sun_elevation_deg=20" } },
	{ "mars sun 20, quality=low", { "preset=mars", "sun_elevation_deg=20", "quality=low" } },
	{ "earth sun 5, 3 iterations", { "sun_elevation_deg=5", "multiscatter_iterations=3" } },
};

/* One scene's tables in float32, kept while the float16 ones are computed. */
struct copy {
	float *t[STATE_N_TABLES];
};

static int make_state(const struct scene *sc, const char *storage, struct sky_state *ret)
{
	char err[256];
	state_default(ret);
	for (int i = 0; i < 4 && sc->keys[i]; i++)
		if (state_set_pair(ret, sc->keys[i], NULL, err, sizeof(err)) < 0) {
			FAIL("%s: %s", sc->name, err);
			return -1;
		}
	if (state_set_pair(ret, storage, NULL, err, sizeof(err)) < 0) {
		FAIL("%s: %s", sc->name, err);
		return -1;
	}
	return 0;
}

static int compute(const struct sky_state *s, const char *name)
{
	char err[512];
	struct eng_timing t;
	if (eng_compute(eng, s, STATE_ALL_TABLES, &t, err, sizeof(err)) < 0) {
		FAIL("%s: eng_compute: %s", name, err);
		return -1;
	}
	return 0;
}

/* The worst errors of one table: relative among normal halves, absolute
 * (in units of 2^(k - 25)) among subnormal ones. */
struct worst {
	double rel, sub;
	size_t bad, normal, subnormal;
};

/* Checks one value: x the float32 one, h its half, k the scale. */
static void check_value(float x, uint16_t h, int32_t k, struct worst *w)
{
	double v = ldexp(skysample_half(h), k), err = fabs(v - x);
	if (!isfinite(v)) {
		w->bad++;
		return;
	}
	if (fabs(ldexp(x, -k)) >= 0x1p-14) {
		w->normal++;
		w->rel = fmax(w->rel, err / fabs(x));
		w->bad += err > REL * fabs(x);
	} else {
		w->subnormal++;
		w->sub = fmax(w->sub, err / ldexp(1.0, k - 25));
		w->bad += err > ldexp(1.0, k - 25);
	}
}

/* The scale pack.comp must choose for the largest |RGB| m: the smallest k
 * with m 2^-k <= 65504; transmittance's is 2^15 whatever its values. */
static int32_t expected_scale(const float *f32, size_t n, int t)
{
	double m = 0;
	if (t == STATE_TRANSMITTANCE)
		return -15;
	for (size_t i = 0; i < n; i++)
		if (i % 4 != 3)
			m = fmax(m, fabs(f32[i]));
	int32_t k = -126;
	while (m > 0 && ldexp(m, -k) > 65504.0)
		k++;
	return m > 0 ? k : 0;
}

/* Every RGBA value of table t; for sky radiance, also that every value at
 * or above the night floor is a normal half. */
static void check_table(const char *name, const struct sky_state *s, const float *f32, int t)
{
	size_t bytes;
	const uint16_t *h = eng_table(eng, (enum state_table)t, &bytes);
	int32_t k = eng_table_scale_log2(eng, (enum state_table)t);
	double floor_cd_m2, gain;
	struct worst w = { 0 };
	size_t dim = 0;

	state_night_floor(s, &floor_cd_m2, &gain);
	for (size_t i = 0; i < bytes / 2; i++) {
		bool rgb = i % 4 != 3;
		check_value(f32[i], h[i], rgb ? k : 0, &w);
		if (rgb && t >= STATE_SKYVIEW && f32[i] >= floor_cd_m2 && fabs(ldexp(f32[i], -k)) < 0x1p-14)
			dim++;
	}
	printf("%-26s %-13s k %4d  max rel %.3e (2^%.2f) of %zu normal, %zu subnormal (max %.2f of 2^(k-25))\n",
	       name, state_table_names[t], k, w.rel, w.rel > 0 ? log2(w.rel) : -INFINITY, w.normal,
	       w.subnormal, w.sub);
	if (w.bad)
		FAIL("%s: %s: %zu values beyond the half's rounding", name, state_table_names[t], w.bad);
	if (dim)
		FAIL("%s: %s: %zu radiance values above the night floor %g are subnormal halves", name,
		     state_table_names[t], dim, floor_cd_m2);
	if (k != expected_scale(f32, bytes / 2, t))
		FAIL("%s: %s: scale 2^%d, the largest value asks for 2^%d", name, state_table_names[t], k,
		     expected_scale(f32, bytes / 2, t));
}

/* The table as a client reads it: f32 from the copy, f16 from the engine. */
static struct skysample_table table_of(const struct sky_state *s, int t, const void *f32)
{
	const struct state_table_quality *q = &s->quality.t[t];
	struct skysample_table r = { .width = q->width, .height = q->height,
				     .depth = t == STATE_AERIAL ? q->depth : 1 };
	if (f32) {
		r.texels = f32;
		r.format = SKY_FORMAT_RGBA32F;
	} else {
		r.texels = eng_table(eng, (enum state_table)t, NULL);
		r.format = SKY_FORMAT_RGBA16F;
		r.rgb_scale_log2 = eng_table_scale_log2(eng, (enum state_table)t);
	}
	return r;
}

/* One sample: a the float32 table's, b the float16 one's. */
static void check_sample(const double a[3], const double b[3], int32_t k, double floor_cd_m2,
			 double *worst, size_t *bad)
{
	for (int c = 0; c < 3; c++) {
		double err = fabs(b[c] - a[c]);
		if (a[c] >= floor_cd_m2)
			*worst = fmax(*worst, err / a[c]);
		*bad += !(err <= REL * a[c] * (1 + 1e-12) + ldexp(1.0, k - 25));
	}
}

/* Bilinear samples of sky-view and aerial perspective between the texels. */
static void check_samples(const char *name, const struct sky_state *s, const struct copy *c)
{
	struct skysample_table sv32 = table_of(s, STATE_SKYVIEW, c->t[STATE_SKYVIEW]),
			       sv16 = table_of(s, STATE_SKYVIEW, NULL),
			       ap32 = table_of(s, STATE_AERIAL, c->t[STATE_AERIAL]),
			       ap16 = table_of(s, STATE_AERIAL, NULL);
	struct sky_shm_state st = { .altitude_km = s->altitude_km,
		.bottom_radius_km = s->atmo.bottom_radius_km, .top_radius_km = s->atmo.top_radius_km,
		.aerial_range_km = s->quality.aerial_range_km,
		.aerial_squared = s->quality.aerial_spacing == STATE_SQUARED };
	double floor_cd_m2, gain, worst_sky = 0, worst_aerial = 0;
	size_t bad = 0;

	state_night_floor(s, &floor_cd_m2, &gain);
	for (int i = 0; i < 97; i++)
		for (int j = 0; j < 61; j++) {
			double el = (-89.0 + 178.0 * i / 96.0) * SKYMAP_PI / 180.0, az = 2 * SKYMAP_PI * j / 61.0;
			double a[3], b[3];
			skysample_sky(&sv32, &st, el, az, a);
			skysample_sky(&sv16, &st, el, az, b);
			check_sample(a, b, sv16.rgb_scale_log2, floor_cd_m2, &worst_sky, &bad);
			double u = (i + 0.3) / 97.0, v = (j + 0.6) / 61.0, d = st.aerial_range_km * (i * 61 + j) / 5917.0;
			double ta, tb;
			skysample_aerial(&ap32, &st, u, v, d, a, &ta);
			skysample_aerial(&ap16, &st, u, v, d, b, &tb);
			check_sample(a, b, ap16.rgb_scale_log2, floor_cd_m2, &worst_aerial, &bad);
			bad += !(fabs(tb - ta) <= REL * ta * (1 + 1e-12) + 0x1p-25);
		}
	printf("%-26s samples: sky-view max rel %.3e, aerial %.3e (above the night floor %g cd/m2)\n",
	       name, worst_sky, worst_aerial, floor_cd_m2);
	if (bad)
		FAIL("%s: %zu bilinear samples beyond 2^-11 S + 2^(k-25)", name, bad);
}

static void test_scene(const struct scene *sc)
{
	struct sky_state s32, s16;
	struct copy c = { { NULL } };
	if (make_state(sc, "storage=f32", &s32) < 0 || make_state(sc, "storage=f16", &s16) < 0 ||
	    compute(&s32, sc->name) < 0)
		return;
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes;
		const void *p = eng_table(eng, (enum state_table)t, &bytes);
		c.t[t] = malloc(bytes);
		memcpy(c.t[t], p, bytes);
	}
	if (compute(&s16, sc->name) == 0) {
		for (int t = 0; t < STATE_N_TABLES; t++)
			check_table(sc->name, &s16, c.t[t], t);
		check_samples(sc->name, &s16, &c);
		struct eng_f16_range r;
		eng_f16_range(eng, &s16, STATE_ALL_TABLES, &r);
		CHECK(r.overflow == 0 && r.subnormal == 0 && !eng_f16_broken(&r));
	}
	for (int t = 0; t < STATE_N_TABLES; t++)
		free(c.t[t]);
}

/* A computation of some tables keeps the others' scales; float32 has 0. */
static void test_kept_scales(void)
{
	struct sky_state s;
	char err[512];
	struct eng_timing t;
	if (make_state(&scenes[4], "storage=f16", &s) < 0 || compute(&s, "mars") < 0)
		return;
	int32_t k_sky = eng_table_scale_log2(eng, STATE_SKYVIEW);
	CHECK(k_sky > 0);	/* above 65504 cd/m2 */
	CHECK(state_set_pair(&s, "sun_elevation_deg=-6", NULL, err, sizeof(err)) == 0);
	CHECK(eng_compute(eng, &s, STATE_BIT(STATE_AERIAL), &t, err, sizeof(err)) == 0);
	CHECK(eng_table_scale_log2(eng, STATE_SKYVIEW) == k_sky);
	CHECK(eng_table_scale_log2(eng, STATE_AERIAL) < 0);	/* twilight */
	CHECK(state_set_pair(&s, "storage=f32", NULL, err, sizeof(err)) == 0 && compute(&s, "f32") == 0);
	for (int i = 0; i < STATE_N_TABLES; i++)
		CHECK(eng_table_scale_log2(eng, (enum state_table)i) == 0);
}

int main(void)
{
	eng = vk_or_skip();
	printf("device: %s\n", eng_device(eng)->name);
	for (size_t i = 0; i < sizeof(scenes) / sizeof(scenes[0]); i++)
		test_scene(&scenes[i]);
	test_kept_scales();
	eng_free(eng);
	return test_report("test_f16");
}

/* test_weather.c - the weather mapping's invariants and reference points:
 * Koschmieder, the humidity growth, the ozone column, the cloud factor,
 * the keys, and finite non-negative outputs over the whole validity range. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "state.h"
#include "test.h"
#include "weather.h"

#define RAYLEIGH_550 13.558e-3	/* Earth's Rayleigh scattering at 550 nm, 1/km */

static bool near(double a, double b, double rel)
{
	return fabs(a - b) <= rel * fmax(fabs(a), fabs(b));
}

static int map_earth(const struct weather *w, struct weather_map *m, struct atmo *ret)
{
	char err[256] = "";
	struct atmo a;
	atmo_earth(&a);
	int rc = weather_map(w, &a, m, err, sizeof(err));
	if (rc < 0)
		FAIL("weather_map: %s", err);
	else
		weather_apply(m, &a);
	if (ret)
		*ret = a;
	return rc;
}

static struct weather make(double vis_km, double rh, enum weather_aerosol type)
{
	struct weather w;
	weather_init(&w);
	w.visibility_km = vis_km;
	w.relative_humidity = rh;
	w.aerosol = type;
	return w;
}

static void test_default_atmosphere(void)
{
	struct atmo a;
	atmo_earth(&a);
	/* The default ozone is Bruneton's 300 DU over a 15 km tent. */
	double du = weather_ozone_du(&a);
	CHECK(fabs(du - 300.0) < 0.1);
	/* Hillaire's Mie is a very clean day: 3.912 / (13.558e-3 + 4.44e-3). */
	double v = weather_visibility_km(&a);
	CHECK(near(v, 3.912 / (RAYLEIGH_550 + 4.44e-3), 1e-12));
	printf("default atmosphere: %.3f DU, visibility %.1f km\n", du, v);

	struct weather w;
	struct weather_map m;
	struct atmo b;
	weather_init(&w);
	CHECK(weather_is_empty(&w));
	CHECK(map_earth(&w, &m, &b) == 0);
	CHECK(!m.sets_mie && !m.sets_ozone && m.light_factor == 1.0);
	CHECK(memcmp(&a, &b, sizeof(a)) == 0);	/* no input, no change */
	CHECK(near(m.visibility_km, v, 1e-12) && fabs(m.ozone_du - du) < 1e-9);
}

static void test_koschmieder(void)
{
	struct weather_map m;
	struct atmo a;
	/* 5 km: the aerosol takes what the air leaves of 3.912 / V. */
	struct weather w = make(5.0, NAN, WEATHER_CONTINENTAL);
	CHECK(map_earth(&w, &m, &a) == 0);
	double want = 3.912 / 5.0 - RAYLEIGH_550;
	CHECK(near(m.extinction_550_per_km, want, 1e-12));
	const struct atmo_constituent *c = &a.c[ATMO_MIE];
	CHECK(near(c->scattering_per_km[1] + c->absorption_per_km[1], want, 1e-12));
	CHECK(near(weather_visibility_km(&a), 5.0, 1e-12));
	CHECK(near(m.visibility_km, 5.0, 1e-12));

	/* Round trip: the default's own visibility gives back its extinction. */
	struct atmo e;
	atmo_earth(&e);
	w = make(weather_visibility_km(&e), NAN, WEATHER_CONTINENTAL);
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(near(m.extinction_550_per_km, 4.44e-3, 1e-9));

	/* 23.5 km, the "standard clear" day, is 34 times the default's aerosol. */
	w = make(23.5, NAN, WEATHER_CONTINENTAL);
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(near(m.extinction_550_per_km, 3.912 / 23.5 - RAYLEIGH_550, 1e-12));
	CHECK(fabs(m.mie.g - 0.703) < 1e-12 && fabs(m.ssa - 0.925) < 1e-12);
	CHECK(fabs(m.aod_550 - 0.2706) < 1e-3);
	CHECK(m.extinction_550_per_km / 4.44e-3 > 30.0);
	printf("V 23.5 km continental: extinction %.4f /km (%.1f x default), AOD %.3f, g %.3f\n",
	       m.extinction_550_per_km, m.extinction_550_per_km / 4.44e-3, m.aod_550, m.mie.g);

	/* Clearer than the air alone allows: no aerosol, nothing negative. */
	w = make(300.0, NAN, WEATHER_CLEAN);
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(m.extinction_550_per_km == 0.0 && m.mie.scattering_per_km[2] == 0.0);
}

static void test_angstrom(void)
{
	struct weather_map m;
	struct weather w = make(10.0, NAN, WEATHER_URBAN);
	CHECK(map_earth(&w, &m, NULL) == 0);
	double e[3];
	for (int ch = 0; ch < 3; ch++)
		e[ch] = m.mie.scattering_per_km[ch] + m.mie.absorption_per_km[ch];
	CHECK(near(log(e[2] / e[1]) / log(550.0 / 440.0), m.angstrom_440_550, 1e-9));
	CHECK(near(log(e[1] / e[0]) / log(680.0 / 550.0), m.angstrom_550_680, 1e-9));
	CHECK(e[2] > e[1] && e[1] > e[0]);	/* fine particles: bluer */

	/* Turbidity alone: AOD(550) = beta (0.55)^-alpha. */
	weather_init(&w);
	w.angstrom_beta = 0.1;
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(near(m.aod_550, 0.1 * pow(0.55, -m.angstrom_550_680), 1e-12));
	/* Turbidity with visibility: the column fixes the scale height. */
	w.visibility_km = 20.0;
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(near(m.mie.scale_height_km * m.extinction_550_per_km,
		   0.1 * pow(0.55, -m.angstrom_550_680), 1e-12));
}

static void test_humidity(void)
{
	for (int t = WEATHER_CLEAN; t < WEATHER_N_AEROSOLS; t++) {
		struct weather_map prev = { 0 }, prev_v = { 0 };
		for (int i = 0; i <= 20; i++) {
			double rh = i / 20.0;
			struct weather_map m, mv;
			struct weather w = make(NAN, rh, (enum weather_aerosol)t);
			struct weather wv = make(8.0, rh, (enum weather_aerosol)t);
			CHECK(map_earth(&w, &m, NULL) == 0);
			CHECK(map_earth(&wv, &mv, NULL) == 0);
			if (i == 0) {
				prev = m;
				prev_v = mv;
				continue;
			}
			/* Climatological loading: scattering grows with the water taken up. */
			for (int ch = 0; ch < 3; ch++)
				if (!(m.mie.scattering_per_km[ch] >= prev.mie.scattering_per_km[ch]))
					FAIL("type %d RH %.2f ch %d: scattering fell", t, rh, ch);
			/* At a fixed visibility the extinction stays and the albedo rises. */
			if (!(mv.mie.scattering_per_km[1] >= prev_v.mie.scattering_per_km[1]) ||
			    !near(mv.extinction_550_per_km, prev_v.extinction_550_per_km, 1e-12))
				FAIL("type %d RH %.2f: fixed-visibility scattering", t, rh);
			if (!(m.mie.g >= prev.mie.g && m.angstrom_550_680 <= prev.angstrom_550_680))
				FAIL("type %d RH %.2f: g must rise, alpha fall", t, rh);
			prev = m;
			prev_v = mv;
		}
		/* RH 80 % is OPAC's reference: no growth. */
		struct weather_map m;
		struct weather w = make(NAN, 0.8, (enum weather_aerosol)t);
		CHECK(map_earth(&w, &m, NULL) == 0);
		CHECK(fabs(m.growth - 1.0) < 1e-12);
	}
	/* Maritime at saturation: clamped to 99 %, finite, droplet-like g. */
	struct weather_map m;
	struct weather w = make(NAN, 1.0, WEATHER_MARITIME);
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(m.relative_humidity == 0.99 && isfinite(m.growth));
	CHECK(m.mie.g > 0.8 && m.mie.g < 0.9 && m.ssa > 0.999);
}

static void test_ozone(void)
{
	struct atmo base;
	atmo_earth(&base);
	for (double du = 0.0; du <= 600.0; du += 75.0) {
		struct weather w;
		struct weather_map m;
		struct atmo a;
		weather_init(&w);
		w.ozone_du = du;
		CHECK(map_earth(&w, &m, &a) == 0);
		CHECK(m.sets_ozone && fabs(weather_ozone_du(&a) - du) < 1e-9);
		for (int ch = 0; ch < 3; ch++)
			if (!near(a.c[ATMO_OZONE].absorption_per_km[ch],
				  base.c[ATMO_OZONE].absorption_per_km[ch] * du / weather_ozone_du(&base),
				  1e-12) && du > 0)
				FAIL("ozone %g DU channel %d not linear", du, ch);
		/* Idempotent: the same map again changes nothing (to rounding). */
		struct weather_map m2;
		char err[256];
		CHECK(weather_map(&w, &a, &m2, err, sizeof(err)) == 0);
		struct atmo b = a;
		weather_apply(&m2, &b);
		for (int ch = 0; ch < 3; ch++)
			CHECK(near(a.c[ATMO_OZONE].absorption_per_km[ch],
				   b.c[ATMO_OZONE].absorption_per_km[ch], 1e-14));
	}
	/* From no ozone at all, the cross-sections give Hillaire's values at 300 DU
	 * (to their three digits). */
	struct atmo a = base;
	for (int ch = 0; ch < 3; ch++)
		a.c[ATMO_OZONE].absorption_per_km[ch] = 0.0;
	struct weather w;
	struct weather_map m;
	char err[256];
	weather_init(&w);
	w.ozone_du = 300.0;
	CHECK(weather_map(&w, &a, &m, err, sizeof(err)) == 0);
	CHECK(isnan(m.ozone_scale));
	for (int ch = 0; ch < 3; ch++)
		CHECK(near(m.ozone_absorption_per_km[ch], base.c[ATMO_OZONE].absorption_per_km[ch],
			   1e-3));
	/* Mars has no ozone to scale. */
	atmo_mars(&a);
	CHECK(weather_map(&w, &a, &m, err, sizeof(err)) == -EINVAL);
	CHECK(strstr(err, "ozone_du") != NULL);
}

static void test_clouds(void)
{
	CHECK(weather_cloud_light_factor(0.0) == 1.0);
	CHECK(fabs(weather_cloud_light_factor(8.0) - 0.25) < 1e-15);
	CHECK(fabs(weather_cloud_light_factor(4.0) - 0.92895) < 1e-5);
	CHECK(weather_cloud_light_factor(NAN) == 1.0);
	for (double n = 0.5; n <= 8.0; n += 0.5)
		CHECK(weather_cloud_light_factor(n) < weather_cloud_light_factor(n - 0.5));
	struct weather w;
	struct weather_map m;
	weather_init(&w);
	w.cloud_oktas = 8.0;
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(!m.sets_mie && fabs(m.light_factor - 0.25) < 1e-15);
}

static void test_magnus(void)
{
	CHECK(fabs(weather_relative_humidity(20.0, 20.0) - 1.0) < 1e-15);
	CHECK(fabs(weather_relative_humidity(20.0, 10.0) - 0.52541) < 1e-5);
	CHECK(isnan(weather_relative_humidity(NAN, 3.0)));
}

/* The weather's keys are rows of the state's key registry: each sets its
 * input, reads back, and refuses a bad value naming the key with the
 * inputs as they were; keys that are no weather input leave them. */
static void test_keys(void)
{
	struct sky_state s, before;
	char err[256], buf[64];
	uint32_t dirty = 0;
	state_default(&s);
	CHECK(state_set(&s, "visibility_km", "12.5", NULL, err, sizeof(err)) == 0 &&
	      s.weather.in.visibility_km == 12.5);
	CHECK(state_set(&s, "aerosol", "desert", NULL, err, sizeof(err)) == 0 &&
	      s.weather.in.aerosol == WEATHER_DESERT);
	CHECK(state_set(&s, "cloud_fraction", "0.5", NULL, err, sizeof(err)) == 0 &&
	      s.weather.in.cloud_oktas == 4.0);
	CHECK(state_get(&s, "cloud_fraction", buf, sizeof(buf)) == 0 && strcmp(buf, "0.5") == 0);
	CHECK(state_get(&s, "aerosol", buf, sizeof(buf)) == 0 && strcmp(buf, "desert") == 0);
	CHECK(state_set(&s, "visibility_km", "auto", NULL, err, sizeof(err)) == 0 &&
	      isnan(s.weather.in.visibility_km));
	CHECK(state_get(&s, "visibility_km", buf, sizeof(buf)) == 0 && strcmp(buf, "auto") == 0);
	static const char *const bad[][2] = {
		{ "visibility_km", "0.01" }, { "visibility_km", "301" }, { "relative_humidity", "1.2" },
		{ "ozone_du", "-1" }, { "ozone_du", "601" }, { "cloud_oktas", "9" },
		{ "angstrom_beta", "nan" }, { "aerosol", "volcanic" }, { "cloud_fraction", "2" },
		{ "relative_humidity", "0,5" },
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		before = s;
		int rc = state_set(&s, bad[i][0], bad[i][1], NULL, err, sizeof(err));
		if (!(rc == -EINVAL || rc == -ERANGE) || !strstr(err, bad[i][0]))
			FAIL("%s=%s: rc %d, '%s'", bad[i][0], bad[i][1], rc, err);
		CHECK(weather_equal(&s.weather.in, &before.weather.in));
	}
	before = s;
	CHECK(state_set(&s, "pressure_mbar", "1000", NULL, err, sizeof(err)) == 0 &&
	      weather_equal(&s.weather.in, &before.weather.in));
	CHECK(state_set(&s, "ozone_du", "300", &dirty, err, sizeof(err)) == 0 &&
	      dirty == STATE_ALL_TABLES);
	dirty = 0;
	CHECK(state_set(&s, "cloud_oktas", "2", &dirty, err, sizeof(err)) == 0 &&
	      dirty == (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL)));
	before = s;
	CHECK(state_set(&s, "sun_elevation_deg", "10", NULL, err, sizeof(err)) == 0 &&
	      weather_equal(&s.weather.in, &before.weather.in));
	/* A struct set by hand out of range is refused by the map. */
	struct weather w = s.weather.in;
	struct weather_map m;
	struct atmo a;
	atmo_earth(&a);
	w.relative_humidity = 1.5;
	CHECK(weather_map(&w, &a, &m, err, sizeof(err)) == -ERANGE);
	CHECK(strstr(err, "relative_humidity") != NULL);
}

static bool all_finite_nonneg(const double *v, int n)
{
	for (int i = 0; i < n; i++)
		if (!isfinite(v[i]) || v[i] < 0.0)
			return false;
	return true;
}

/* Maps w onto Earth and checks what the engine relies on. */
static void check_sane(const struct weather *w, const char *label)
{
	struct weather_map m;
	struct atmo a;
	char err[256];
	if (map_earth(w, &m, &a) < 0)
		return;
	const struct atmo_constituent *c = &a.c[ATMO_MIE];
	double figures[] = { m.light_factor, m.ozone_du, m.visibility_km };
	if (!all_finite_nonneg(c->scattering_per_km, 3) || !all_finite_nonneg(c->absorption_per_km, 3) ||
	    !all_finite_nonneg(a.c[ATMO_OZONE].absorption_per_km, 3) ||
	    !all_finite_nonneg(figures, 3) || !(fabs(c->g) < 1.0))
		FAIL("%s: an output is not finite and >= 0", label);
	if (m.sets_mie && (!isfinite(m.aod_550) || !(m.mie.scale_height_km > 0.0) ||
			   !isfinite(m.growth) || !(m.ssa > 0.0 && m.ssa <= 1.0)))
		FAIL("%s: derived figures", label);
	if (atmo_validate(&a, err, sizeof(err)) < 0)
		FAIL("%s: %s", label, err);
}

static double uniform(uint64_t *s, double lo, double hi)
{
	*s = *s * 6364136223846793005ull + 1442695040888963407ull;
	return lo + (hi - lo) * (double)(*s >> 11) / 9007199254740992.0;
}

static void test_sweep(void)
{
	uint64_t seed = 20240611;
	char label[64];
	for (int i = 0; i < 5000; i++) {
		struct weather w;
		weather_init(&w);
		/* Each input given or not; visibility log-uniform over its range. */
		if (uniform(&seed, 0, 1) < 0.8)
			w.visibility_km = exp(uniform(&seed, log(0.05), log(300.0)));
		if (uniform(&seed, 0, 1) < 0.8)
			w.relative_humidity = uniform(&seed, 0, 1);
		w.aerosol = (enum weather_aerosol)(int)uniform(&seed, 0, WEATHER_N_AEROSOLS - 1e-9);
		if (uniform(&seed, 0, 1) < 0.3)
			w.angstrom_beta = uniform(&seed, 0, WEATHER_ANGSTROM_BETA_MAX);
		if (uniform(&seed, 0, 1) < 0.5)
			w.ozone_du = uniform(&seed, 0, WEATHER_OZONE_DU_MAX);
		if (uniform(&seed, 0, 1) < 0.5)
			w.cloud_oktas = uniform(&seed, 0, 8);
		snprintf(label, sizeof(label), "sweep %d", i);
		check_sane(&w, label);
	}
	static const struct {
		const char *label;
		double vis, rh, beta, du, oktas;
		enum weather_aerosol type;
	} extremes[] = {
		{ "50 m fog", 0.05, 1.0, NAN, NAN, 8, WEATHER_MARITIME },
		{ "50 m fog, dry", 0.05, 0.0, NAN, NAN, NAN, WEATHER_URBAN },
		{ "50 m fog with a column", 0.05, 1.0, 10.0, NAN, NAN, WEATHER_MARITIME },
		{ "300 km", 300.0, NAN, NAN, NAN, NAN, WEATHER_CLEAN },
		{ "300 km with a column", 300.0, 0.0, 10.0, NAN, 0, WEATHER_DESERT },
		{ "RH 1.0", NAN, 1.0, NAN, NAN, NAN, WEATHER_MARITIME },
		{ "RH 1.0 turbid", NAN, 1.0, 10.0, NAN, NAN, WEATHER_URBAN },
		{ "0 DU", NAN, NAN, NAN, 0.0, NAN, WEATHER_AEROSOL_AUTO },
		{ "600 DU", NAN, NAN, NAN, 600.0, NAN, WEATHER_AEROSOL_AUTO },
		{ "dust storm", 0.2, 0.1, NAN, NAN, 8, WEATHER_DESERT },
		{ "dust storm, turbid", 0.2, 0.0, 10.0, 600, 8, WEATHER_DESERT },
	};
	for (size_t i = 0; i < sizeof(extremes) / sizeof(extremes[0]); i++) {
		struct weather w;
		weather_init(&w);
		w.visibility_km = extremes[i].vis;
		w.relative_humidity = extremes[i].rh;
		w.angstrom_beta = extremes[i].beta;
		w.ozone_du = extremes[i].du;
		w.cloud_oktas = extremes[i].oktas;
		w.aerosol = extremes[i].type;
		check_sane(&w, extremes[i].label);
	}
	/* The dust storm's figures. */
	struct weather w = make(0.2, NAN, WEATHER_DESERT);
	struct weather_map m;
	CHECK(map_earth(&w, &m, NULL) == 0);
	CHECK(near(m.extinction_550_per_km, 3.912 / 0.2 - RAYLEIGH_550, 1e-12));
	printf("dust storm V 0.2 km: extinction %.2f /km, AOD %.1f; 50 m fog: extinction %.2f /km\n",
	       m.extinction_550_per_km, m.aod_550, 3.912 / 0.05 - RAYLEIGH_550);
}

static void test_describe_cb(void *ctx, const char *key, const char *value)
{
	int *n = ctx;
	(*n)++;
	if (!*key || !*value || strchr(key, ' ') || strchr(value, '\n'))
		FAIL("describe: bad pair '%s' '%s'", key, value);
}

static void test_describe(void)
{
	struct weather w = make(7.0, 0.6, WEATHER_URBAN);
	struct weather_map m;
	int n = 0;
	struct sky_state s;
	char err[256];
	w.ozone_du = 320.0;
	w.cloud_oktas = 3.0;
	CHECK(map_earth(&w, &m, NULL) == 0);
	state_default(&s);
	s.weather.in = w;
	CHECK(state_describe_weather(&s, test_describe_cb, &n, err, sizeof(err)) == 0);
	CHECK(n > 20);
}

int main(void)
{
	test_default_atmosphere();
	test_koschmieder();
	test_angstrom();
	test_humidity();
	test_ozone();
	test_clouds();
	test_magnus();
	test_keys();
	test_sweep();
	test_describe();
	return test_report("test_weather");
}

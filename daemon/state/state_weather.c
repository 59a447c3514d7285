/* state_weather.c - the weather in the sky's state: its keys, METAR reports,
 * the raw keys that override it, and the state the tables are computed
 * with (state_resolve). The model is daemon/weather's (docs/weather.md). */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "metar.h"

/* The weather maps the Mie constituent when an aerosol input is given, the
 * ozone when a column is (weather_map's own rule). */
static bool maps_mie(const struct weather *w)
{
	return !isnan(w->visibility_km) || !isnan(w->relative_humidity) ||
	       w->aerosol != WEATHER_AEROSOL_AUTO || !isnan(w->angstrom_beta);
}

static bool maps_ozone(const struct weather *w)
{
	return !isnan(w->ozone_du);
}

/* The raw keys that pin a coefficient the weather maps; a key ending in
 * '*' is a prefix. */
static const struct {
	const char *key;
	uint32_t bit;
	const char *report;		/* its name in get weather's overridden: */
} raw_overrides[] = {
	{ "mie_scattering_per_km", STATE_OVERRIDE_MIE_SCATTERING, "mie_scattering_per_km" },
	{ "mie_absorption_per_km", STATE_OVERRIDE_MIE_ABSORPTION, "mie_absorption_per_km" },
	{ "mie_g", STATE_OVERRIDE_MIE_G, "mie_g" },
	{ "mie_scale_height_km", STATE_OVERRIDE_MIE_PROFILE, "mie_profile" },
	{ "mie_layer*", STATE_OVERRIDE_MIE_PROFILE, "mie_profile" },
	{ "ozone_absorption_per_km", STATE_OVERRIDE_OZONE_ABSORPTION, "ozone_absorption_per_km" },
};
#define N_RAW (sizeof(raw_overrides) / sizeof(raw_overrides[0]))

static bool key_matches(const char *pattern, const char *key)
{
	size_t n = strlen(pattern);

	if (n && pattern[n - 1] == '*')
		return strncmp(pattern, key, n - 1) == 0;
	return strcmp(pattern, key) == 0;
}

void state_weather_note_raw(struct sky_state *s, const char *key)
{
	for (size_t i = 0; i < N_RAW; i++) {
		uint32_t bit = raw_overrides[i].bit;
		bool mapped = (bit & STATE_OVERRIDE_MIE) ? maps_mie(&s->weather.in)
							 : maps_ozone(&s->weather.in);
		if (mapped && key_matches(raw_overrides[i].key, key))
			s->weather.overridden |= bit;
	}
}

int state_set_weather_key(struct sky_state *s, const char *key, const char *value,
			  uint32_t *ret_dirty, char *err, size_t err_size)
{
	if (strcmp(key, "metar") == 0)
		return state_set_metar(s, value, NULL, ret_dirty, err, err_size);
	unsigned affects = weather_key_affects(key);
	if (!affects)
		return 1;
	int r = weather_set(&s->weather.in, key, value, err, err_size);
	if (r < 0)
		return r;
	if (affects & WEATHER_AFFECTS_ATMOSPHERE) {
		/* A weather key set after a raw key wins over it again. */
		s->weather.overridden &= strcmp(key, "ozone_du") == 0
					 ? ~(uint32_t)STATE_OVERRIDE_OZONE_ABSORPTION
					 : ~(uint32_t)STATE_OVERRIDE_MIE;
		*ret_dirty = FROM_T;
	} else {
		s->weather.cloud_factor = weather_cloud_light_factor(s->weather.in.cloud_oktas);
		*ret_dirty = LIGHTS;
	}
	return 0;
}

void state_foreach_weather(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char buf[64];

	for (int i = 0; weather_keys[i]; i++) {
		if (strcmp(weather_keys[i], "cloud_fraction") == 0)
			continue;
		weather_get(&s->weather.in, weather_keys[i], buf, sizeof(buf));
		if (strcmp(buf, "auto") != 0)
			fn(ctx, weather_keys[i], buf);
	}
}

/* QNH is the pressure reduced to sea level in the ICAO standard atmosphere;
 * refraction wants the station's: the same law back up to the site. */
static double station_pressure_hpa(double qnh_hpa, double elevation_m)
{
	double base = fmax(1.0 - 2.25577e-5 * elevation_m, 0.0);
	return qnh_hpa * pow(base, 5.25588);
}

int state_set_metar(struct sky_state *s, const char *report, struct metar *ret_metar,
		    uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct metar m;
	struct state_weather before = s->weather;
	char why[256];

	if (metar_decode(report, &m, why, sizeof(why)) < 0)
		return ERR("metar: %s", why);
	/* Within pressure_mbar's and temperature_c's ranges: the decoder takes
	 * QNH 850..1100 hPa and two-digit temperatures, and site_elevation_m
	 * is at least -1000 m. */
	if (isfinite(m.qnh_hpa))
		s->clock.pressure_mbar = station_pressure_hpa(m.qnh_hpa, s->clock.site_elevation_m);
	if (isfinite(m.temperature_c))
		s->clock.temperature_c = m.temperature_c;
	metar_weather(&m, &s->weather.in);
	/* The report writes every aerosol input: it wins over raw Mie keys. */
	s->weather.overridden &= ~(uint32_t)STATE_OVERRIDE_MIE;
	s->weather.cloud_factor = weather_cloud_light_factor(s->weather.in.cloud_oktas);
	uint32_t dirty = 0;
	struct weather a = before.in, b = s->weather.in;
	a.cloud_oktas = b.cloud_oktas = 0.0;
	if (!weather_equal(&a, &b) || before.overridden != s->weather.overridden)
		dirty |= FROM_T;
	if (before.cloud_factor != s->weather.cloud_factor)
		dirty |= LIGHTS;
	if (ret_dirty)
		*ret_dirty = dirty;
	if (ret_metar)
		*ret_metar = m;
	return 0;
}

int state_set_cloud_factor(struct sky_state *s, double factor, uint32_t *ret_dirty)
{
	if (!(factor >= 0.0 && factor <= 1.0))
		return -ERANGE;
	struct state_weather before = s->weather;
	/* Kasten and Czeplak inverted: 1 - 0.75 (N / 8)^3.4 = factor. */
	double n = 8.0 * pow(fmin((1.0 - factor) / 0.75, 1.0), 1.0 / 3.4);
	s->weather.in.cloud_oktas = n;
	s->weather.cloud_factor = factor;
	if (ret_dirty && memcmp(&before, &s->weather, sizeof(before)) != 0)
		*ret_dirty |= LIGHTS;
	return 0;
}

/* Copies the coefficients of the overridden raw keys from src into dst. */
static void keep_overrides(uint32_t bits, const struct atmo *src, struct atmo *dst)
{
	for (int i = 0; i < src->n_constituents && i < dst->n_constituents; i++) {
		const struct atmo_constituent *a = &src->c[i];
		struct atmo_constituent *b = &dst->c[i];
		if (strcmp(a->name, "mie") == 0) {
			if (bits & STATE_OVERRIDE_MIE_SCATTERING)
				memcpy(b->scattering_per_km, a->scattering_per_km, sizeof(a->scattering_per_km));
			if (bits & STATE_OVERRIDE_MIE_ABSORPTION)
				memcpy(b->absorption_per_km, a->absorption_per_km, sizeof(a->absorption_per_km));
			if (bits & STATE_OVERRIDE_MIE_G)
				b->g = a->g;
			if (bits & STATE_OVERRIDE_MIE_PROFILE)
				b->density = a->density;
		} else if (strcmp(a->name, "ozone") == 0 && (bits & STATE_OVERRIDE_OZONE_ABSORPTION)) {
			memcpy(b->absorption_per_km, a->absorption_per_km, sizeof(a->absorption_per_km));
		}
	}
}

int state_resolve(const struct sky_state *s, struct sky_state *ret, struct weather_map *ret_map,
		  char *err, size_t err_size)
{
	struct state_weather w = s->weather;
	struct weather_map map;
	struct atmo a = s->atmo;

	if (weather_is_empty(&w.in) && w.cloud_factor == 1.0 && !ret_map) {
		/* Nothing to apply: the state as it is, bytes and all. */
		if (ret != s)
			*ret = *s;
		return 0;
	}
	int r = weather_map(&w.in, &s->atmo, &map, err, err_size);
	if (r < 0)
		return r;
	weather_apply(&map, &a);
	keep_overrides(w.overridden, &s->atmo, &a);
	if (ret != s)
		*ret = *s;
	ret->atmo = a;
	ret->sun.illuminance_lx *= w.cloud_factor;
	ret->moon.illuminance_lx *= w.cloud_factor;
	weather_init(&ret->weather.in);
	ret->weather.overridden = 0;
	ret->weather.cloud_factor = 1.0;
	if (ret_map)
		*ret_map = map;
	return 0;
}

int state_describe_weather(const struct sky_state *s, state_emit_fn fn, void *ctx, char *err,
			   size_t err_size)
{
	struct weather_map map;
	char list[160] = "";
	size_t o = 0;

	int r = weather_map(&s->weather.in, &s->atmo, &map, err, err_size);
	if (r < 0)
		return r;
	weather_describe(&s->weather.in, &map, fn, ctx);
	for (size_t i = 0; i < N_RAW; i++) {
		if (!(s->weather.overridden & raw_overrides[i].bit) ||
		    (i && raw_overrides[i - 1].bit == raw_overrides[i].bit))
			continue;
		o += (size_t)snprintf(list + o, o < sizeof(list) ? sizeof(list) - o : 0, "%s%s",
				      o ? "," : "", raw_overrides[i].report);
	}
	fn(ctx, "overridden", o ? list : "none");
	snprintf(list, sizeof(list), "%.9g", s->weather.cloud_factor);
	fn(ctx, "cloud_factor", list);
	return 0;
}

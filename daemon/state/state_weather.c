/* state_weather.c - the weather in the sky's state: the hooks of its keys,
 * METAR reports, the raw keys that override it, `get weather`, and the
 * state the tables are computed with (state_resolve). The model is
 * daemon/weather's (docs/weather.md). */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
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

void state_weather_pin(struct sky_state *s, uint32_t bits)
{
	if (maps_mie(&s->weather.in))
		s->weather.overridden |= bits & STATE_OVERRIDE_MIE;
	if (maps_ozone(&s->weather.in))
		s->weather.overridden |= bits & STATE_OVERRIDE_OZONE_ABSORPTION;
}

/* An aerosol input or the ozone column: set after a raw key, it wins over
 * it again. */
int state_set_weather(struct sky_state *s, const struct state_key *k, const char *v,
		      uint32_t *ret_dirty, char *err, size_t err_size)
{
	int r = state_key_parse(k, v, (char *)s + k->offset, err, err_size);

	if (r == 0)
		s->weather.overridden &= ~k->override;
	return r;
}

/* While a layer is drawn the factor dims nothing: no table. */
static void narrow_cloud(const struct sky_state *s, uint32_t *ret_dirty)
{
	if (state_clouds_drawn(s))
		*ret_dirty = 0;
}

int state_set_cloud(struct sky_state *s, const struct state_key *k, const char *v,
		    uint32_t *ret_dirty, char *err, size_t err_size)
{
	int r = state_key_parse(k, v, &s->weather.in.cloud_oktas, err, err_size);

	if (r < 0)
		return r;
	s->weather.cloud_factor = weather_cloud_light_factor(s->weather.in.cloud_oktas);
	narrow_cloud(s, ret_dirty);
	return 0;
}

int state_set_cloud_fraction(struct sky_state *s, const struct state_key *k, const char *v,
			     uint32_t *ret_dirty, char *err, size_t err_size)
{
	double fraction;
	int r = state_key_parse(k, v, &fraction, err, err_size);

	if (r < 0)
		return r;
	s->weather.in.cloud_oktas = isnan(fraction) ? NAN : fraction * WEATHER_OKTAS_MAX;
	s->weather.cloud_factor = weather_cloud_light_factor(s->weather.in.cloud_oktas);
	narrow_cloud(s, ret_dirty);
	return 0;
}

int state_get_cloud_fraction(const struct sky_state *s, const struct state_key *k, char *buf,
			     size_t n)
{
	double fraction = s->weather.in.cloud_oktas / WEATHER_OKTAS_MAX;

	state_key_format(k, &fraction, buf, n);
	return 0;
}

int state_set_metar_key(struct sky_state *s, const struct state_key *k, const char *v,
			uint32_t *ret_dirty, char *err, size_t err_size)
{
	return state_set_metar(s, v, NULL, ret_dirty, err, err_size);
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
	struct state_clouds clouds_before = s->clouds;
	double factor_before = state_cloud_factor_applied(s);
	int drawn_before = state_clouds_drawn(s);
	char why[256];

	if (metar_decode(report, &m, why, sizeof(why)) < 0)
		return ERR("%s: %s", state_key_name(STATE_KEY_ID_METAR), why);
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
	state_clouds_from_metar(s, &m);
	/* The tables of what changed: the aerosol inputs', the light factor
	 * applied, the drawn layers'. */
	uint32_t dirty = 0;
	struct weather a = before.in, b = s->weather.in;
	a.cloud_oktas = b.cloud_oktas = 0.0;
	if (!weather_equal(&a, &b) || before.overridden != s->weather.overridden)
		dirty |= state_key_of(STATE_KEY_ID_VISIBILITY_KM)->dirty;
	if (factor_before != state_cloud_factor_applied(s))
		dirty |= state_key_of(STATE_KEY_ID_CLOUD_OKTAS)->dirty;
	if ((drawn_before || state_clouds_drawn(s)) &&
	    memcmp(&clouds_before, &s->clouds, sizeof(clouds_before)) != 0)
		dirty |= STATE_CLOUD_TABLES | LIGHTS;
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
	if (ret_dirty && memcmp(&before, &s->weather, sizeof(before)) != 0 && !state_clouds_drawn(s))
		*ret_dirty |= state_key_of(STATE_KEY_ID_CLOUD_OKTAS)->dirty;
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
	/* A drawn layer dims the lights itself (the cloud passes): the
	 * weather's factor would count the clouds twice. */
	int drawn = state_clouds_drawn(s);
	double factor = drawn ? 1.0 : w.cloud_factor;
	double offset_km[2];

	if (weather_is_empty(&w.in) && factor == 1.0 && !ret_map && !drawn) {
		/* Nothing to apply: the state as it is, bytes and all. */
		if (ret != s)
			*ret = *s;
		return 0;
	}
	state_cloud_offset_km(s, offset_km);
	int r = weather_map(&w.in, &s->atmo, &map, err, err_size);
	if (r < 0)
		return r;
	weather_apply(&map, &a);
	keep_overrides(w.overridden, &s->atmo, &a);
	if (ret != s)
		*ret = *s;
	ret->atmo = a;
	ret->sun.illuminance_lx *= factor;
	ret->moon.illuminance_lx *= factor;
	ret->clouds.offset_km[0] = offset_km[0];
	ret->clouds.offset_km[1] = offset_km[1];
	weather_init(&ret->weather.in);
	ret->weather.overridden = 0;
	ret->weather.cloud_factor = 1.0;
	if (ret_map)
		*ret_map = map;
	return 0;
}

static void emit(state_emit_fn fn, void *ctx, const char *key, const char *fmt, ...)
	__attribute__((format(printf, 4, 5)));
static void emit(state_emit_fn fn, void *ctx, const char *key, const char *fmt, ...)
{
	char buf[128];
	va_list ap;

	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	fn(ctx, key, buf);
}

/* A coefficient the map writes, under the name of the raw key that
 * would pin it. */
static void emit_mapped(state_emit_fn fn, void *ctx, uint32_t bit, const double *v, int n)
{
	const char *key = state_key_pinning(bit)->name;

	if (n == 3)
		emit(fn, ctx, key, "%.9g,%.9g,%.9g", v[0], v[1], v[2]);
	else
		emit(fn, ctx, key, "%.9g", v[0]);
}

/* The Mie part of the map: what the aerosol inputs made. */
static void describe_mie(const struct weather_map *m, state_emit_fn fn, void *ctx)
{
	const struct weather_mie *p = &m->mie;

	emit(fn, ctx, "aerosol_used", "%s", weather_aerosol_name(m->aerosol));
	emit(fn, ctx, "relative_humidity_used", "%.9g", m->relative_humidity);
	emit(fn, ctx, "humidity_growth", "%.9g", m->growth);
	emit(fn, ctx, "aerosol_extinction_550_per_km", "%.9g", m->extinction_550_per_km);
	emit(fn, ctx, "aerosol_optical_depth_550", "%.9g", m->aod_550);
	emit(fn, ctx, "single_scattering_albedo", "%.9g", m->ssa);
	emit(fn, ctx, "angstrom_440_550", "%.9g", m->angstrom_440_550);
	emit(fn, ctx, "angstrom_550_680", "%.9g", m->angstrom_550_680);
	emit_mapped(fn, ctx, STATE_OVERRIDE_MIE_SCATTERING, p->scattering_per_km, 3);
	emit_mapped(fn, ctx, STATE_OVERRIDE_MIE_ABSORPTION, p->absorption_per_km, 3);
	emit_mapped(fn, ctx, STATE_OVERRIDE_MIE_G, &p->g, 1);
	emit_mapped(fn, ctx, STATE_OVERRIDE_MIE_PROFILE, &p->scale_height_km, 1);
}

const char *state_override_name(uint32_t bit)
{
	return bit == STATE_OVERRIDE_MIE_PROFILE ? "mie_profile" : state_key_pinning(bit)->name;
}

/* The raw keys that win over the weather, a comma list or none. */
static void describe_overridden(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char list[160] = "";
	size_t o = 0;

	for (uint32_t bit = 1; bit <= STATE_OVERRIDE_OZONE_ABSORPTION; bit <<= 1)
		if (s->weather.overridden & bit)
			o += (size_t)snprintf(list + o, o < sizeof(list) ? sizeof(list) - o : 0,
					      "%s%s", o ? "," : "", state_override_name(bit));
	fn(ctx, "overridden", o ? list : "none");
}

int state_describe_weather(const struct sky_state *s, state_emit_fn fn, void *ctx, char *err,
			   size_t err_size)
{
	struct weather_map m;

	int r = weather_map(&s->weather.in, &s->atmo, &m, err, err_size);
	if (r < 0)
		return r;
	state_foreach_given(s, fn, ctx);
	emit(fn, ctx, "mie_source", "%s", m.sets_mie ? "weather" : "atmosphere");
	if (m.sets_mie)
		describe_mie(&m, fn, ctx);
	emit(fn, ctx, "visibility_effective_km", "%.9g", m.visibility_km);
	emit(fn, ctx, "ozone_source", "%s", m.sets_ozone ? "weather" : "atmosphere");
	emit(fn, ctx, "ozone_du_effective", "%.9g", m.ozone_du);
	if (m.sets_ozone)
		emit_mapped(fn, ctx, STATE_OVERRIDE_OZONE_ABSORPTION, m.ozone_absorption_per_km, 3);
	emit(fn, ctx, "cloud_light_factor", "%.9g", m.light_factor);
	describe_overridden(s, fn, ctx);
	emit(fn, ctx, "cloud_factor", "%.9g", s->weather.cloud_factor);
	emit(fn, ctx, "cloud_factor_applied", "%.9g", state_cloud_factor_applied(s));
	return 0;
}

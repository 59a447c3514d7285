/* state_clouds.c - the cloud layers in the sky's state: the hooks of their
 * keys, which layers are drawn, their tops and region, what a METAR's
 * cloud and wind groups make of them, the cross-key rules and `get
 * clouds`. The field itself is proto/skycloud.h's (docs/clouds.md). */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "metar.h"
#include "simclock.h"
#include "skycloud.h"
#define SKYCLOUD_DOUBLE 1
#include "skycloud.h"

/* In enum skycloud_type's order (test_state_clouds checks the names
 * against skycloud_types). */
const char *const state_cloud_type_names[SKYCLOUD_N_TYPES + 1] = {
	"stratus", "stratocumulus", "cumulus", "cumulonimbus", "altostratus", "cirrus", NULL,
};

/* The key range of a layer's base and top, in m. */
#define CLOUD_MAX_M 20000.0
/* The auto region's bounds (docs/clouds.md, "The region"). */
#define EXTENT_MIN_KM 50.0
#define EXTENT_MAX_KM 400.0

static int layer_drawn(const struct state_cloud_layer *l)
{
	return l->oktas > 0.0 && !isnan(l->base_m);
}

int state_clouds_drawn(const struct sky_state *s)
{
	int n = 0;

	for (int i = 0; i < STATE_CLOUD_LAYERS; i++)
		n += layer_drawn(&s->clouds.layer[i]);
	return n;
}

double state_cloud_factor_applied(const struct sky_state *s)
{
	return state_clouds_drawn(s) ? 1.0 : s->weather.cloud_factor;
}

/* The atmosphere's shell in m: no layer reaches past it. */
static double shell_m(const struct sky_state *s)
{
	return (s->atmo.top_radius_km - s->atmo.bottom_radius_km) * 1000.0;
}

double state_cloud_top_m(const struct sky_state *s, int i)
{
	const struct state_cloud_layer *l = &s->clouds.layer[i];

	if (isnan(l->base_m))
		return NAN;
	if (!isnan(l->top_m))
		return l->top_m;
	int t = l->type >= 0 && l->type < SKYCLOUD_N_TYPES ? l->type : SKYCLOUD_STRATOCUMULUS;
	return fmin(l->base_m + skycloud_types[t].thickness_m, fmin(CLOUD_MAX_M, shell_m(s)));
}

double state_cloud_extent_km(const struct sky_state *s)
{
	double top_km = 0.0;

	if (!isnan(s->clouds.extent_km))
		return s->clouds.extent_km;
	for (int i = 0; i < STATE_CLOUD_LAYERS; i++)
		if (layer_drawn(&s->clouds.layer[i]))
			top_km = fmax(top_km, state_cloud_top_m(s, i) * 1e-3);
	double d = sqrt(2.0 * s->atmo.bottom_radius_km * top_km);
	return fmin(fmax(d, EXTENT_MIN_KM), EXTENT_MAX_KM);
}

int state_cloud_layers(const struct sky_state *s, struct skycloud_layer *ret)
{
	int n = 0;

	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		const struct state_cloud_layer *l = &s->clouds.layer[i];
		if (!layer_drawn(l))
			continue;
		skycloud_layer_init(&ret[n++], l->type, l->oktas / WEATHER_OKTAS_MAX, l->base_m * 1e-3,
				    state_cloud_top_m(s, i) * 1e-3, s->clouds.seed, (uint32_t)i);
	}
	return n;
}

int state_cloud_layers_double(const struct sky_state *s, struct skycloudd_layer *ret)
{
	int n = 0;

	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		const struct state_cloud_layer *l = &s->clouds.layer[i];
		if (!layer_drawn(l))
			continue;
		skycloudd_layer_init(&ret[n++], l->type, l->oktas / WEATHER_OKTAS_MAX, l->base_m * 1e-3,
				     state_cloud_top_m(s, i) * 1e-3, s->clouds.seed, (uint32_t)i);
	}
	return n;
}

void state_cloud_offset_km(const struct sky_state *s, double ret_km[2])
{
	ret_km[0] = ret_km[1] = 0.0;
	if (!isnan(s->clouds.utc_s))
		skycloud_wind_offset_km(s->clouds.wind_dir_deg, s->clouds.wind_speed_mps,
					s->clouds.utc_s, ret_km);
}

void state_cloud_table_offset_km(const struct sky_state *s, double ret_km[2], double ret_shift_km[2])
{
	double cell_km = s->quality.cloud_cell_texels * 2.0 * state_cloud_extent_km(s) / s->quality.shadow_width;
	bool lattice = cell_km > 0.0 && !state_terrain_set(s);

	for (int k = 0; k < 2; k++) {
		double o = s->clouds.offset_km[k];
		ret_km[k] = lattice ? floor(o / cell_km) * cell_km : o;
		ret_shift_km[k] = o - ret_km[k];
	}
}

/* ---- the keys' hooks ---- */

/* A cloud key changes no table while no layer is drawn, before or after. */
static void narrow(const struct sky_state *s, int was_drawn, uint32_t *ret_dirty)
{
	if (!was_drawn && !state_clouds_drawn(s))
		*ret_dirty = 0;
}

int state_set_cloud_key(struct sky_state *s, const struct state_key *k, const char *v,
			uint32_t *ret_dirty, char *err, size_t err_size)
{
	int was = state_clouds_drawn(s);
	int r = state_key_parse(k, v, (char *)s + k->offset, err, err_size);

	if (r == 0)
		narrow(s, was, ret_dirty);
	return r;
}

/* cloudN_fraction: the same field as cloudN_oktas, in eighths. */
int state_set_cloud_layer_fraction(struct sky_state *s, const struct state_key *k, const char *v,
				   uint32_t *ret_dirty, char *err, size_t err_size)
{
	int was = state_clouds_drawn(s);
	double fraction;
	int r = state_key_parse(k, v, &fraction, err, err_size);

	if (r < 0)
		return r;
	*(double *)((char *)s + k->offset) = isnan(fraction) ? NAN : fraction * WEATHER_OKTAS_MAX;
	narrow(s, was, ret_dirty);
	return 0;
}

int state_get_cloud_layer_fraction(const struct sky_state *s, const struct state_key *k, char *buf,
				   size_t n)
{
	double fraction = *(const double *)((const char *)s + k->offset) / WEATHER_OKTAS_MAX;

	state_key_format(k, &fraction, buf, n);
	return 0;
}

/* ---- METAR ---- */

void state_clouds_from_metar(struct sky_state *s, const struct metar *m)
{
	struct metar_layer layers[STATE_CLOUD_LAYERS];
	int n = metar_layers(m, layers, STATE_CLOUD_LAYERS);

	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		struct state_cloud_layer *l = &s->clouds.layer[i];
		*l = (struct state_cloud_layer){ .oktas = NAN, .base_m = NAN, .top_m = NAN,
						 .type = SKYCLOUD_STRATOCUMULUS };
		if (i < n) {
			l->oktas = layers[i].oktas;
			l->base_m = layers[i].base_m;
			l->type = layers[i].type;
		}
	}
	double dir_deg, speed_mps;
	if (metar_wind(m, &dir_deg, &speed_mps) == 0) {
		if (!isnan(dir_deg))
			s->clouds.wind_dir_deg = dir_deg;
		s->clouds.wind_speed_mps = speed_mps;
	}
}

/* ---- cross-key rules ---- */

int state_clouds_validate(const struct sky_state *s, char *err, size_t err_size)
{
	double shell = shell_m(s);

	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		const struct state_cloud_layer *l = &s->clouds.layer[i];
		int n = i + 1;
		if (!isnan(l->base_m) && !isnan(l->top_m) && !(l->top_m > l->base_m))
			return ERR_RANGE("cloud%d_top_m: %g is not above cloud%d_base_m = %g", n, l->top_m,
					 n, l->base_m);
		double top = state_cloud_top_m(s, i);
		if (!isnan(top) && top > shell)
			return ERR_RANGE("cloud%d_top_m: %g is above the top of the atmosphere (%g m)", n,
					 top, shell);
		if (!isnan(top) && !(top > l->base_m))
			return ERR_RANGE("cloud%d_base_m: %g leaves no room for a layer below %g m; give cloud%d_top_m",
					 n, l->base_m, fmin(CLOUD_MAX_M, shell), n);
	}
	/* A METAR's wind group sets the speed without the key's check
	 * (state_clouds_from_metar): the key's range, from its row. */
	const struct state_key *k = state_key_find("wind_speed_mps");
	double v = s->clouds.wind_speed_mps;
	if (k && !(v >= k->min && v <= k->max))
		return ERR_RANGE("wind_speed_mps: %g is outside [%g, %g]", v, k->min, k->max);
	return 0;
}

/* ---- get clouds ---- */

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

static void emit_number(state_emit_fn fn, void *ctx, const char *key, double v)
{
	if (isnan(v))
		fn(ctx, key, "auto");
	else
		emit(fn, ctx, key, "%.9g", v);
}

void state_describe_clouds(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char key[32];
	double off[2];

	emit(fn, ctx, "clouds_drawn", "%d", state_clouds_drawn(s));
	for (int i = 0; i < STATE_CLOUD_LAYERS; i++) {
		const struct state_cloud_layer *l = &s->clouds.layer[i];
		snprintf(key, sizeof(key), "cloud%d_oktas", i + 1);
		emit_number(fn, ctx, key, l->oktas);
		snprintf(key, sizeof(key), "cloud%d_base_m", i + 1);
		emit_number(fn, ctx, key, l->base_m);
		snprintf(key, sizeof(key), "cloud%d_top_m", i + 1);
		emit_number(fn, ctx, key, state_cloud_top_m(s, i));
		snprintf(key, sizeof(key), "cloud%d_type", i + 1);
		fn(ctx, key, state_cloud_type_names[l->type]);
		snprintf(key, sizeof(key), "cloud%d_drawn", i + 1);
		emit(fn, ctx, key, "%d", layer_drawn(l));
	}
	emit(fn, ctx, "wind_dir_deg", "%.9g", s->clouds.wind_dir_deg);
	emit(fn, ctx, "wind_speed_mps", "%.9g", s->clouds.wind_speed_mps);
	emit(fn, ctx, "cloud_seed", "%u", s->clouds.seed);
	emit(fn, ctx, "cloud_extent_km", "%.9g", state_cloud_extent_km(s));
	fn(ctx, "cloud_extent_source", isnan(s->clouds.extent_km) ? "auto" : "key");
	emit(fn, ctx, "cloud_period_km", "%d", SKYCLOUD_PERIOD_KM);
	state_cloud_offset_km(s, off);
	emit(fn, ctx, "cloud_offset_km", "%.9g,%.9g", off[0], off[1]);
	char t[64];
	if (isnan(s->clouds.utc_s) || simclock_format_utc(s->clouds.utc_s, t, sizeof(t)) < 0)
		snprintf(t, sizeof(t), "none");
	fn(ctx, "cloud_placed_utc", t);
	emit(fn, ctx, "cloud_factor_applied", "%.9g", state_cloud_factor_applied(s));
}

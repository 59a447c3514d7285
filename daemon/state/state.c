/* state.c - the sky state: its defaults, set and get over every key, the
 * clock keys, validation and the tables' bookkeeping. */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "simclock.h"

const char *const state_table_names[STATE_N_TABLES] = {
	"transmittance", "multiscatter", "skyview", "aerial",
};

/* Keys that hand a light to the clock, or take it back (manual). */
static const char *const clock_keys[] = {
	"utc", "lat_deg", "lon_deg", "site_elevation_m", NULL,
};
static const char *const sun_manual_keys[] = {
	"sun_elevation_deg", "sun_azimuth_deg", "sun_illuminance_lx", "sun_angular_radius_deg", NULL,
};
static const char *const moon_manual_keys[] = {
	"moon_elevation_deg", "moon_azimuth_deg", "moon_illuminance_lx", "moon_color",
	"moon_angular_radius_deg", NULL,
};
static const char *const mode_names[] = { "manual", "clock", NULL };

void state_default_camera(struct state_camera *ret)
{
	*ret = (struct state_camera){ .yaw_deg = 180.0, .pitch_deg = 0.0, .roll_deg = 0.0,
				      .vfov_deg = 60.0, .aspect = 16.0 / 9.0 };
}

/* The quality presets behind the key quality=low|medium|high|ultra. medium
 * is the reference of docs/physics.md and the default; it takes at most 20
 * sky-view steps a ray (docs/physics.md: about 4 to 30), where more steps
 * no longer move the error (docs/findings.md). low halves it,
 * high raises steps by half, ultra doubles sizes and steps (about 8 times
 * the work of medium: more would take seconds on lavapipe). `skybench
 * accuracy` measures their cost and error. */
struct quality_preset {
	const char *name;
	struct state_quality q;
};

/* The last three fields: multiscatter_iterations=auto (0), multiscatter_moment=auto,
 * multiscatter_delta=auto. */
static const struct quality_preset quality_presets[] = {
	{ "low", { { { 128, 32, 1, 20 }, { 16, 16, 1, 10 }, { 96, 54, 1, 16 }, { 16, 16, 16, 1 } },
		   2, 4, 128.0, STATE_SQUARED, STATE_F16, 0, STATE_MOMENT_AUTO, STATE_MOMENT_AUTO } },
	{ "medium", { { { 256, 64, 1, 40 }, { 32, 32, 1, 20 }, { 192, 108, 1, 20 }, { 32, 32, 32, 1 } },
		      64, 4, 128.0, STATE_SQUARED, STATE_F32, 0, STATE_MOMENT_AUTO, STATE_MOMENT_AUTO } },
	{ "high", { { { 256, 64, 1, 60 }, { 32, 32, 1, 30 }, { 256, 144, 1, 45 }, { 48, 48, 32, 2 } },
		    64, 6, 128.0, STATE_SQUARED, STATE_F32, 0, STATE_MOMENT_AUTO, STATE_MOMENT_AUTO } },
	{ "ultra", { { { 512, 128, 1, 80 }, { 64, 64, 1, 40 }, { 384, 216, 1, 60 }, { 64, 64, 64, 2 } },
		     64, 8, 128.0, STATE_SQUARED, STATE_F32, 0, STATE_MOMENT_AUTO, STATE_MOMENT_AUTO } },
};
#define N_QUALITY_PRESETS (sizeof(quality_presets) / sizeof(quality_presets[0]))

static int set_quality(struct sky_state *s, const char *v)
{
	for (size_t i = 0; i < N_QUALITY_PRESETS; i++)
		if (strcmp(quality_presets[i].name, v) == 0) {
			s->quality = quality_presets[i].q;
			return 0;
		}
	return -EINVAL;
}

/* The preset the quality settings equal, or "custom". */
static const char *quality_name(const struct sky_state *s)
{
	for (size_t i = 0; i < N_QUALITY_PRESETS; i++)
		if (memcmp(&quality_presets[i].q, &s->quality, sizeof(s->quality)) == 0)
			return quality_presets[i].name;
	return "custom";
}

void state_default(struct sky_state *ret)
{
	struct sky_state s = { 0 };

	snprintf(s.preset, sizeof(s.preset), "earth");
	atmo_earth(&s.atmo);
	s.altitude_km = 0.2;
	s.sun = (struct state_light){ .elevation_deg = 30.0, .azimuth_deg = 180.0,
		.illuminance_lx = 133800.0, .color = { 1, 1, 1 },
		.angular_radius_deg = 0.004675 * 180.0 / M_PI };
	s.moon = (struct state_light){ .elevation_deg = -30.0, .azimuth_deg = 0.0,
		.illuminance_lx = 0.0, .color = { 1, 1, 1 },
		.angular_radius_deg = 0.259 };
	state_default_camera(&s.camera);
	set_quality(&s, "medium");
	s.clock = (struct state_clock){ .anchor_utc_s = NAN, .anchor_mono_s = 0.0, .rate = 1.0,
		.lat_deg = 0.0, .lon_deg = 0.0, .site_elevation_m = 0.0,
		.pressure_mbar = 1013.25, .temperature_c = 15.0, .delta_t_s = NAN,
		.horizon_refraction_deg = 0.5667, .threshold_deg = 0.1, .cadence_s = 60.0,
		.sun_mode = STATE_MANUAL, .moon_mode = STATE_MANUAL };
	s.lights_utc_s = NAN;
	s.exposure_ev100 = NAN;
	s.night = (struct state_night){ .zenith_luminance_cd_m2 = 2.0e-4, .illuminance_lx = 0.002 };
	weather_init(&s.weather.in);
	s.weather.cloud_factor = 1.0;
	state_sensor_defaults(&s.sensor);
	*ret = s;
}

static int in_list(const char *const *list, const char *key)
{
	for (int i = 0; list[i]; i++)
		if (strcmp(list[i], key) == 0)
			return 1;
	return 0;
}

double state_clock_utc_s(const struct sky_state *s, double mono_s)
{
	const struct state_clock *c = &s->clock;

	if (isnan(c->anchor_utc_s))
		return NAN;
	return c->anchor_utc_s + c->rate * (mono_s - c->anchor_mono_s);
}

void state_clock_rebase(struct sky_state *next, const struct sky_state *cur, double mono_s)
{
	struct state_clock *n = &next->clock;
	const struct state_clock *c = &cur->clock;

	if (n->rate == c->rate || isnan(c->anchor_utc_s) ||
	    memcmp(&n->anchor_utc_s, &c->anchor_utc_s, sizeof(double)) ||
	    n->anchor_mono_s != c->anchor_mono_s)
		return;
	n->anchor_utc_s = state_clock_utc_s(cur, mono_s);
	n->anchor_mono_s = mono_s;
}

/* A clock that was never set starts at the real time, so that naming only
 * a place shows that place's sky now. */
static void clock_anchor_now(struct state_clock *c)
{
	double real_s, mono_s;

	simclock_read_clocks(&real_s, &mono_s);
	c->anchor_utc_s = real_s;
	c->anchor_mono_s = mono_s;
}

/* utc, time_rate, delta_t_s, sun_mode, moon_mode. Returns 1 if key is not
 * one of them, else 0 or -EINVAL with err. */
static int set_clock_key(struct sky_state *s, const char *key, const char *v, uint32_t *ret_dirty,
			 char *err, size_t err_size)
{
	struct state_clock *c = &s->clock;
	double d, mono_s;

	if (strcmp(key, "utc") == 0) {
		if (strcmp(v, "now") == 0) {
			clock_anchor_now(c);
		} else if (simclock_parse_utc(v, &d) == 0) {
			simclock_read_clocks(NULL, &mono_s);
			c->anchor_utc_s = d;
			c->anchor_mono_s = mono_s;
		} else {
			return ERR("utc: '%s' is not now or an ISO 8601 UTC time such as 2026-06-21T18:30:00Z (a real date, a zone)", v);
		}
	} else if (strcmp(key, "time_rate") == 0) {
		if (proto_parse_number(v, &d) < 0)
			return ERR("time_rate: '%s' is not a finite number", v);
		if (fabs(d) > SIMCLOCK_RATE_MAX)
			return ERR_RANGE("time_rate: %g is outside [%g, %g]", d, -SIMCLOCK_RATE_MAX, SIMCLOCK_RATE_MAX);
		/* The rate runs from the anchor; a running clock is re-anchored
		 * by state_clock_rebase when the change is committed, so that
		 * utc= and time_rate= in one request mean the same in any order. */
		c->rate = d;
	} else if (strcmp(key, "delta_t_s") == 0) {
		if (strcmp(v, "auto") == 0)
			d = NAN;
		else if (proto_parse_number(v, &d) < 0)
			return ERR("delta_t_s: '%s' is not auto or a finite number", v);
		else if (fabs(d) > 1e6)
			return ERR_RANGE("delta_t_s: %g is outside [-1e6, 1e6]", d);
		c->delta_t_s = d;
	} else if (strcmp(key, "sun_mode") == 0 || strcmp(key, "moon_mode") == 0) {
		int m = state_enum_index(mode_names, v);
		if (m < 0)
			return ERR("%s: '%s' is not clock or manual", key, v);
		*(key[0] == 's' ? &c->sun_mode : &c->moon_mode) = (enum state_light_mode)m;
		if (m == STATE_CLOCK && isnan(c->anchor_utc_s))
			clock_anchor_now(c);
	} else {
		return 1;
	}
	/* A rate alone moves nothing until the clock runs on it. */
	if (ret_dirty && strcmp(key, "time_rate") != 0)
		*ret_dirty |= LIGHTS;
	return 0;
}

int state_set(struct sky_state *s, const char *key, const char *value,
	      uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct sky_state before = *s;
	uint32_t dirty = 0;
	int r;

	r = set_clock_key(s, key, value, &dirty, err, err_size);
	if (r > 0)
		r = state_set_weather_key(s, key, value, &dirty, err, err_size);
	if (r > 0)
		r = state_set_sensor_key(s, key, value, err, err_size);
	if (r <= 0) {
		if (r < 0)
			return r;
	} else if (strcmp(key, "quality") == 0) {
		if (set_quality(s, value) < 0)
			return ERR("quality: '%s' is not low, medium, high or ultra", value);
		dirty = STATE_ALL_TABLES;
	} else if (strcmp(key, "preset") == 0) {
		struct atmo a;
		if (atmo_preset(value, &a) < 0)
			return ERR("preset: '%s' is not earth or mars", value);
		s->atmo = a;
		snprintf(s->preset, sizeof(s->preset), "%s", value);
		/* The raw keys the overrides kept are gone with the old atmosphere. */
		s->weather.overridden = 0;
		dirty = FROM_T;
	} else {
		const struct state_key *k = state_find_key(key);
		if (k) {
			r = state_set_table_key(s, k, value, err, err_size);
			dirty = state_key_dirty(k);
		} else {
			r = state_set_constituent_key(s, key, value, err, err_size);
			dirty = FROM_T;
			if (r == 0)
				state_weather_note_raw(s, key);
		}
		if (r < 0)
			return r;
	}
	/* Naming a time or a place hands both lights to the clock; setting what
	 * the clock computes for a light takes that light back. */
	if (in_list(clock_keys, key)) {
		s->clock.sun_mode = s->clock.moon_mode = STATE_CLOCK;
		if (isnan(s->clock.anchor_utc_s))
			clock_anchor_now(&s->clock);
	} else if (in_list(sun_manual_keys, key)) {
		s->clock.sun_mode = STATE_MANUAL;
	} else if (in_list(moon_manual_keys, key)) {
		s->clock.moon_mode = STATE_MANUAL;
	}
	if (ret_dirty && memcmp(&before, s, sizeof(before)) != 0)
		*ret_dirty |= dirty;
	return 0;
}

int state_set_pair(struct sky_state *s, const char *pair, uint32_t *ret_dirty,
		   char *err, size_t err_size)
{
	const char *eq = strchr(pair, '=');
	char key[64];

	if (!eq || eq == pair)
		return ERR("'%s': expected key=value", pair);
	if ((size_t)(eq - pair) >= sizeof(key))
		return ERR("'%.32s...': key too long", pair);
	memcpy(key, pair, eq - pair);
	key[eq - pair] = 0;
	return state_set(s, key, eq + 1, ret_dirty, err, err_size);
}

size_t state_texel_bytes(enum state_storage st)
{
	return st == STATE_F16 ? 8 : 16;
}

size_t state_table_bytes(const struct sky_state *s, enum state_table t)
{
	const struct state_table_quality *q = &s->quality.t[t];
	return (size_t)q->width * q->height * (t == STATE_AERIAL ? q->depth : 1) *
	       state_texel_bytes(s->quality.storage);
}

uint32_t state_multiscatter_iterations(const struct sky_state *s)
{
	if (s->quality.multiscatter_dirs == 0)
		return 0;
	if (s->quality.multiscatter_iterations > 0)
		return (uint32_t)s->quality.multiscatter_iterations - 1;
	/* Not on the 2-direction fast path: its f_ms is too coarse for the
	 * transfer, and iterating spreads its errors instead of correcting
	 * them (docs/findings.md). */
	if (s->quality.multiscatter_dirs != 64)
		return 0;
	/* The threshold needs a few percent: 1000 intervals are plenty. */
	double tau[3];
	atmo_vertical_optical_depth(&s->atmo, 1000, tau);
	double most = fmax(tau[0], fmax(tau[1], tau[2]));
	return most >= STATE_THICK_OPTICAL_DEPTH ? 2 : 0;
}

int state_validate(const struct sky_state *s, uint64_t max_buffer_bytes,
		   char *err, size_t err_size)
{
	int r = atmo_validate(&s->atmo, err, err_size);
	if (r < 0)
		return r;
	if (!weather_is_empty(&s->weather.in)) {
		/* The weather must fit the atmosphere, and what it makes of it
		 * must be one the engine takes. */
		struct sky_state sky;
		r = state_resolve(s, &sky, NULL, err, err_size);
		if (r < 0 || (r = atmo_validate(&sky.atmo, err, err_size)) < 0)
			return r;
	}
	if (s->night.zenith_luminance_cd_m2 > 0.0 &&
	    s->night.illuminance_lx < M_PI * s->night.zenith_luminance_cd_m2)
		return ERR_RANGE("night_illuminance_lx: %g is below pi * night_zenith_luminance_cd_m2 = %g (a night sky darker at the horizon than at the zenith)",
			   s->night.illuminance_lx, M_PI * s->night.zenith_luminance_cd_m2);
	if (s->quality.skyview_min_steps > s->quality.t[STATE_SKYVIEW].steps)
		return ERR_RANGE("skyview_min_steps: must not exceed skyview_steps");
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t bytes = state_table_bytes(s, (enum state_table)t);
		if (max_buffer_bytes && bytes > max_buffer_bytes)
			return ERR_RANGE("%s_width: table of %zu bytes exceeds the device limit of %llu",
				   state_table_names[t], bytes,
				   (unsigned long long)max_buffer_bytes);
	}
	return 0;
}

static const char *const clock_special[] = {
	"utc", "time_rate", "delta_t_s", "sun_mode", "moon_mode", NULL,
};

/* Formats one of clock_special; the time is the simulated time now. */
static void format_clock_key(const struct sky_state *s, const char *key, char *buf, size_t n)
{
	if (strcmp(key, "utc") == 0) {
		double mono_s;
		simclock_read_clocks(NULL, &mono_s);
		double utc_s = state_clock_utc_s(s, mono_s);
		if (isnan(utc_s))
			snprintf(buf, n, "none");
		else if (simclock_format_utc(utc_s, buf, n) < 0)
			snprintf(buf, n, "%.3f", utc_s);	/* outside years 0..9999 */
	} else if (strcmp(key, "time_rate") == 0) {
		snprintf(buf, n, "%.9g", s->clock.rate);
	} else if (strcmp(key, "delta_t_s") == 0) {
		if (isnan(s->clock.delta_t_s))
			snprintf(buf, n, "auto");
		else
			snprintf(buf, n, "%.9g", s->clock.delta_t_s);
	} else {
		snprintf(buf, n, "%s", mode_names[key[0] == 's' ? s->clock.sun_mode : s->clock.moon_mode]);
	}
}

void state_night_floor(const struct sky_state *s, double *ret_zenith_cd_m2, double *ret_gain)
{
	double lz = s->night.zenith_luminance_cd_m2;

	*ret_zenith_cd_m2 = lz > 0.0 ? lz : 0.0;
	*ret_gain = lz > 0.0 ? fmax(3.0 * (s->night.illuminance_lx / (M_PI * lz) - 1.0), 0.0) : 0.0;
}

void state_foreach(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char buf[128];

	fn(ctx, "preset", s->preset);
	for (int i = 0; clock_special[i]; i++) {
		format_clock_key(s, clock_special[i], buf, sizeof(buf));
		fn(ctx, clock_special[i], buf);
	}
	state_foreach_key(s, fn, ctx);
	state_foreach_weather(s, fn, ctx);
	state_foreach_sensor(s, fn, ctx);
}

/* state_diff's walk: each key of one state whose text the other state
 * does not show, set on a scratch copy of the other to learn its mask. */
struct diff {
	const struct sky_state *other;
	struct sky_state scratch;
	uint32_t dirty;
};

static void diff_key(void *ctx, const char *key, const char *value)
{
	struct diff *d = ctx;
	char other[512], err[256];

	if (state_get(d->other, key, other, sizeof(other)) == 0 && strcmp(other, value) == 0)
		return;
	if (state_set(&d->scratch, key, value, &d->dirty, err, sizeof(err)) < 0)
		d->dirty = STATE_ALL_TABLES;
}

uint32_t state_diff(const struct sky_state *a, const struct sky_state *b)
{
	struct diff *d = malloc(sizeof(*d));
	uint32_t dirty;

	if (!d)
		return STATE_ALL_TABLES;
	/* Both ways: `get` lists some keys only away from their defaults. */
	*d = (struct diff){ .other = a, .scratch = *a };
	state_foreach(b, diff_key, d);
	dirty = d->dirty;
	*d = (struct diff){ .other = b, .scratch = *b };
	state_foreach(a, diff_key, d);
	dirty |= d->dirty;
	free(d);
	return dirty;
}

int state_get(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	if (strcmp(key, "preset") == 0) {
		snprintf(buf, size, "%s", s->preset);
		return 0;
	}
	if (in_list(clock_special, key)) {
		format_clock_key(s, key, buf, size);
		return 0;
	}
	if (strcmp(key, "quality") == 0) {
		snprintf(buf, size, "%s", quality_name(s));
		return 0;
	}
	if (weather_get(&s->weather.in, key, buf, size) == 0)
		return 0;
	if (state_get_sensor_key(s, key, buf, size) == 0)
		return 0;
	return state_get_key(s, key, buf, size);
}

int state_parse_tables(const char *list, uint32_t *ret_mask)
{
	uint32_t mask = 0;
	const char *p = list;

	while (*p) {
		size_t n = strcspn(p, ",");
		int found = 0;
		if (n == 3 && strncmp(p, "all", 3) == 0) {
			mask |= STATE_ALL_TABLES;
			found = 1;
		}
		for (int t = 0; t < STATE_N_TABLES && !found; t++)
			if (strlen(state_table_names[t]) == n &&
			    strncmp(p, state_table_names[t], n) == 0) {
				mask |= STATE_BIT(t);
				found = 1;
			}
		if (!found)
			return -EINVAL;
		p += n;
		if (*p == ',')
			p++;
	}
	if (!mask)
		return -EINVAL;
	*ret_mask = mask;
	return 0;
}

void state_format_tables(uint32_t mask, char *buf, size_t size)
{
	size_t o = 0;

	buf[0] = 0;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t))
			o += (size_t)snprintf(buf + o, o < size ? size - o : 0, "%s%s", o ? "," : "",
					      state_table_names[t]);
	if (!o)
		snprintf(buf, size, "none");
}

uint32_t state_closure(uint32_t mask)
{
	if (mask & (S_BIT | A_BIT))
		mask |= M_BIT;
	if (mask & M_BIT)
		mask |= T_BIT;
	return mask;
}

/* state.c - the sky state, its keys, their parsing and their invalidation. */
#include "state.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "simclock.h"

const char *const state_table_names[STATE_N_TABLES] = {
	"transmittance", "multiscatter", "skyview", "aerial",
};

#define T_BIT STATE_BIT(STATE_TRANSMITTANCE)
#define M_BIT STATE_BIT(STATE_MULTISCATTER)
#define S_BIT STATE_BIT(STATE_SKYVIEW)
#define A_BIT STATE_BIT(STATE_AERIAL)
/* What a change to one table forces downstream. */
#define FROM_T (T_BIT | M_BIT | S_BIT | A_BIT)
#define FROM_M (M_BIT | S_BIT | A_BIT)
#define LIGHTS (S_BIT | A_BIT)

enum kind { K_DOUBLE, K_TRIPLE, K_UINT, K_ENUM };

struct key {
	const char *name;
	enum kind kind;
	size_t offset;
	uint32_t dirty;		/* tables a change of this key invalidates */
	double min, max;	/* inclusive; for K_ENUM unused */
	const char *const *names; /* K_ENUM value names, NULL-terminated */
};

static const char *const storage_names[] = { "f32", "f16", NULL };
static const char *const spacing_names[] = { "linear", "squared", NULL };
static const char *const iteration_names[] = { "auto", "0", "1", "2", "3", "4", NULL };
static const char *const moment_names[] = { "auto", "off", "on", NULL };

#define OFF(field) offsetof(struct sky_state, field)
#define QT(i, f) OFF(quality.t[i].f)
#define BIG 1e300

static const struct key keys[] = {
	{ "bottom_radius_km", K_DOUBLE, OFF(atmo.bottom_radius_km), FROM_T, 1e-3, 1e7, 0 },
	{ "top_radius_km", K_DOUBLE, OFF(atmo.top_radius_km), FROM_T, 1e-3, 1e7, 0 },
	{ "ground_albedo", K_TRIPLE, OFF(atmo.ground_albedo), FROM_M, 0, 1, 0 },
	{ "altitude_km", K_DOUBLE, OFF(altitude_km), LIGHTS, -BIG, 1e7, 0 },

	{ "sun_elevation_deg", K_DOUBLE, OFF(sun.elevation_deg), LIGHTS, -90, 90, 0 },
	{ "sun_azimuth_deg", K_DOUBLE, OFF(sun.azimuth_deg), LIGHTS, -360, 720, 0 },
	{ "sun_illuminance_lx", K_DOUBLE, OFF(sun.illuminance_lx), LIGHTS, 0, 1e9, 0 },
	{ "sun_color", K_TRIPLE, OFF(sun.color), LIGHTS, 0, 1e3, 0 },
	{ "sun_angular_radius_deg", K_DOUBLE, OFF(sun.angular_radius_deg), LIGHTS, 1e-4, 20, 0 },
	{ "moon_elevation_deg", K_DOUBLE, OFF(moon.elevation_deg), LIGHTS, -90, 90, 0 },
	{ "moon_azimuth_deg", K_DOUBLE, OFF(moon.azimuth_deg), LIGHTS, -360, 720, 0 },
	{ "moon_illuminance_lx", K_DOUBLE, OFF(moon.illuminance_lx), LIGHTS, 0, 1e9, 0 },
	{ "moon_color", K_TRIPLE, OFF(moon.color), LIGHTS, 0, 1e3, 0 },
	{ "moon_angular_radius_deg", K_DOUBLE, OFF(moon.angular_radius_deg), LIGHTS, 1e-4, 20, 0 },

	{ "camera_yaw_deg", K_DOUBLE, OFF(camera.yaw_deg), A_BIT, -360, 720, 0 },
	{ "camera_pitch_deg", K_DOUBLE, OFF(camera.pitch_deg), A_BIT, -90, 90, 0 },
	{ "camera_roll_deg", K_DOUBLE, OFF(camera.roll_deg), A_BIT, -180, 180, 0 },
	{ "camera_vfov_deg", K_DOUBLE, OFF(camera.vfov_deg), A_BIT, 0.1, 179, 0 },
	{ "camera_aspect", K_DOUBLE, OFF(camera.aspect), A_BIT, 0.01, 100, 0 },

	{ "transmittance_width", K_UINT, QT(0, width), FROM_T, 2, 4096, 0 },
	{ "transmittance_height", K_UINT, QT(0, height), FROM_T, 2, 4096, 0 },
	{ "transmittance_steps", K_UINT, QT(0, steps), FROM_T, 1, 4096, 0 },
	{ "multiscatter_width", K_UINT, QT(1, width), FROM_M, 2, 1024, 0 },
	{ "multiscatter_height", K_UINT, QT(1, height), FROM_M, 2, 1024, 0 },
	{ "multiscatter_steps", K_UINT, QT(1, steps), FROM_M, 1, 4096, 0 },
	{ "multiscatter_dirs", K_UINT, OFF(quality.multiscatter_dirs), FROM_M, 0, 64, 0 },
	{ "multiscatter_iterations", K_ENUM, OFF(quality.multiscatter_iterations), FROM_M, 0, 0,
	  iteration_names },
	{ "multiscatter_moment", K_ENUM, OFF(quality.multiscatter_moment), FROM_M, 0, 0, moment_names },
	{ "multiscatter_delta", K_ENUM, OFF(quality.multiscatter_delta), FROM_M, 0, 0, moment_names },
	{ "skyview_width", K_UINT, QT(2, width), S_BIT, 2, 4096, 0 },
	{ "skyview_height", K_UINT, QT(2, height), S_BIT, 2, 4096, 0 },
	{ "skyview_steps", K_UINT, QT(2, steps), S_BIT, 1, 4096, 0 },
	{ "skyview_min_steps", K_UINT, OFF(quality.skyview_min_steps), S_BIT, 1, 4096, 0 },
	{ "aerial_width", K_UINT, QT(3, width), A_BIT, 1, 1024, 0 },
	{ "aerial_height", K_UINT, QT(3, height), A_BIT, 1, 1024, 0 },
	{ "aerial_depth", K_UINT, QT(3, depth), A_BIT, 1, 1024, 0 },
	{ "aerial_steps", K_UINT, QT(3, steps), A_BIT, 1, 256, 0 },
	{ "aerial_range_km", K_DOUBLE, OFF(quality.aerial_range_km), A_BIT, 1e-3, 1e5, 0 },
	{ "aerial_spacing", K_ENUM, OFF(quality.aerial_spacing), A_BIT, 0, 0, spacing_names },
	{ "storage", K_ENUM, OFF(quality.storage), STATE_ALL_TABLES, 0, 0, storage_names },

	/* The site and the clock's settings; utc, time_rate, delta_t_s and the
	 * light modes have their own parsers (set_clock_key). Refraction only
	 * changes the reported direction, never the tables. */
	{ "lat_deg", K_DOUBLE, OFF(clock.lat_deg), LIGHTS, -90, 90, 0 },
	{ "lon_deg", K_DOUBLE, OFF(clock.lon_deg), LIGHTS, -180, 180, 0 },
	{ "site_elevation_m", K_DOUBLE, OFF(clock.site_elevation_m), LIGHTS, -1000, 1e5, 0 },
	{ "pressure_mbar", K_DOUBLE, OFF(clock.pressure_mbar), 0, 0, 5000, 0 },
	{ "temperature_c", K_DOUBLE, OFF(clock.temperature_c), 0, -100, 100, 0 },
	{ "horizon_refraction_deg", K_DOUBLE, OFF(clock.horizon_refraction_deg), 0, 0, 3, 0 },
	{ "clock_threshold_deg", K_DOUBLE, OFF(clock.threshold_deg), 0, 1e-4, 180, 0 },
	{ "clock_cadence_s", K_DOUBLE, OFF(clock.cadence_s), 0, 0, 86400, 0 },
	{ "night_zenith_luminance_cd_m2", K_DOUBLE, OFF(night.zenith_luminance_cd_m2), LIGHTS, 0, 1e3, 0 },
	{ "night_illuminance_lx", K_DOUBLE, OFF(night.illuminance_lx), LIGHTS, 0, 1e4, 0 },
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

/* Per-constituent keys: "<name>_<suffix>", e.g. mie_g, ozone_absorption_per_km. */
enum ckey {
	C_SCATTERING, C_ABSORPTION, C_SCALE_HEIGHT, C_G, C_PHASE, C_WIDTH,
	C_EXP_TERM, C_EXP_SCALE, C_LINEAR, C_CONSTANT,
};
static const char *const phase_names[] = {
	"none", "rayleigh", "cornette_shanks", "henyey_greenstein", NULL,
};
static const struct {
	const char *suffix;
	enum ckey which;
	int layer;
} ckeys[] = {
	{ "scattering_per_km", C_SCATTERING, 0 },
	{ "absorption_per_km", C_ABSORPTION, 0 },
	{ "scale_height_km", C_SCALE_HEIGHT, 0 },
	{ "g", C_G, 0 },
	{ "phase", C_PHASE, 0 },
	{ "layer0_width_km", C_WIDTH, 0 },
	{ "layer0_exp_term", C_EXP_TERM, 0 },
	{ "layer0_exp_scale_per_km", C_EXP_SCALE, 0 },
	{ "layer0_linear_per_km", C_LINEAR, 0 },
	{ "layer0_constant", C_CONSTANT, 0 },
	{ "layer1_exp_term", C_EXP_TERM, 1 },
	{ "layer1_exp_scale_per_km", C_EXP_SCALE, 1 },
	{ "layer1_linear_per_km", C_LINEAR, 1 },
	{ "layer1_constant", C_CONSTANT, 1 },
};

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

static void sensor_defaults(struct state_sensor *ret);	/* the light sensor's block below */

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
	s.night = (struct state_night){ .zenith_luminance_cd_m2 = 2.0e-4, .illuminance_lx = 0.002 };
	sensor_defaults(&s.sensor);
	*ret = s;
}

/* Strict C-locale double: the whole string, finite. strtod reads the
 * locale's decimal point, so it runs under a "C" locale_t. */
static int parse_double(const char *v, double *ret)
{
	static locale_t c_locale;
	char *end;

	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!c_locale || !*v)
		return -EINVAL;
	locale_t old = uselocale(c_locale);
	errno = 0;
	double d = strtod(v, &end);
	int e = errno;
	uselocale(old);
	if (*end || end == v || !isfinite(d) || (e == ERANGE && d != 0.0))
		return -EINVAL;
	*ret = d;
	return 0;
}

static int parse_triple(const char *v, double ret[3])
{
	char buf[128], *parts[3];
	int n = 0;

	if (strlen(v) >= sizeof(buf))
		return -EINVAL;
	snprintf(buf, sizeof(buf), "%s", v);
	char *p = buf;
	for (;;) {
		if (n == 3)
			return -EINVAL;
		parts[n++] = p;
		char *comma = strchr(p, ',');
		if (!comma)
			break;
		*comma = 0;
		p = comma + 1;
	}
	if (n != 1 && n != 3)
		return -EINVAL;
	double out[3];
	for (int i = 0; i < n; i++)
		if (parse_double(parts[i], &out[i]) < 0)
			return -EINVAL;
	for (int i = 0; i < 3; i++)
		ret[i] = out[n == 1 ? 0 : i];
	return 0;
}

static int enum_index(const char *const *names, const char *v)
{
	for (int i = 0; names[i]; i++)
		if (strcmp(names[i], v) == 0)
			return i;
	return -1;
}

/* The three refusals of a key: malformed, out of its range, unknown. */
#define ERR(...) (snprintf(err, err_size, __VA_ARGS__), -EINVAL)
#define ERR_RANGE(...) (snprintf(err, err_size, __VA_ARGS__), -ERANGE)
#define ERR_UNKNOWN(...) (snprintf(err, err_size, __VA_ARGS__), -ENOENT)

static int set_key(struct sky_state *s, const struct key *k, const char *v,
		   char *err, size_t err_size)
{
	char *base = (char *)s + k->offset;
	double d, t[3];

	switch (k->kind) {
	case K_DOUBLE:
		if (parse_double(v, &d) < 0)
			return ERR("%s: '%s' is not a finite number", k->name, v);
		if (d < k->min || d > k->max)
			return ERR_RANGE("%s: %g is outside [%g, %g]", k->name, d, k->min, k->max);
		*(double *)base = d;
		return 0;
	case K_TRIPLE:
		if (parse_triple(v, t) < 0)
			return ERR("%s: '%s' is not one or three finite numbers", k->name, v);
		for (int i = 0; i < 3; i++)
			if (t[i] < k->min || t[i] > k->max)
				return ERR_RANGE("%s: %g is outside [%g, %g]", k->name, t[i], k->min, k->max);
		memcpy(base, t, sizeof(t));
		return 0;
	case K_UINT: {
		char *end;
		if (!*v || *v == '-' || *v == '+')
			return ERR("%s: '%s' is not a whole number", k->name, v);
		errno = 0;
		unsigned long long u = strtoull(v, &end, 10);
		if (*end || errno)
			return ERR("%s: '%s' is not a whole number", k->name, v);
		if (u < k->min || u > k->max)
			return ERR_RANGE("%s: %llu is outside [%g, %g]", k->name, u, k->min, k->max);
		if (strcmp(k->name, "multiscatter_dirs") == 0 && u != 0 && u != 2 && u != 64)
			return ERR_RANGE("multiscatter_dirs: must be 0 (off), 2 or 64");
		*(uint32_t *)base = (uint32_t)u;
		return 0;
	}
	case K_ENUM: {
		int i = enum_index(k->names, v);
		if (i < 0)
			return ERR("%s: '%s' is not one of the allowed values", k->name, v);
		*(int *)base = i;
		return 0;
	}
	}
	return ERR("%s: internal error", k->name);
}

static struct atmo_constituent *find_constituent(struct sky_state *s, const char *key,
						 const char **ret_suffix)
{
	for (int i = 0; i < s->atmo.n_constituents; i++) {
		size_t n = strlen(s->atmo.c[i].name);
		if (n && strncmp(key, s->atmo.c[i].name, n) == 0 && key[n] == '_') {
			*ret_suffix = key + n + 1;
			return &s->atmo.c[i];
		}
	}
	return NULL;
}

static int set_constituent(struct atmo_constituent *c, const char *key, const char *suffix,
			   const char *v, char *err, size_t err_size)
{
	for (size_t i = 0; i < sizeof(ckeys) / sizeof(ckeys[0]); i++) {
		if (strcmp(ckeys[i].suffix, suffix) != 0)
			continue;
		struct atmo_layer *l = &c->density.layers[ckeys[i].layer];
		double d, t[3];
		if (ckeys[i].which == C_PHASE) {
			int p = enum_index(phase_names, v);
			if (p < 0)
				return ERR("%s: '%s' is not none, rayleigh, cornette_shanks or henyey_greenstein", key, v);
			c->phase = (enum atmo_phase)p;
			return 0;
		}
		if (ckeys[i].which == C_SCATTERING || ckeys[i].which == C_ABSORPTION) {
			if (parse_triple(v, t) < 0)
				return ERR("%s: '%s' is not one or three finite numbers", key, v);
			for (int ch = 0; ch < 3; ch++)
				if (t[ch] < 0.0)
					return ERR_RANGE("%s: coefficients must be >= 0", key);
			memcpy(ckeys[i].which == C_SCATTERING ? c->scattering_per_km
							      : c->absorption_per_km, t, sizeof(t));
			return 0;
		}
		if (parse_double(v, &d) < 0)
			return ERR("%s: '%s' is not a finite number", key, v);
		switch (ckeys[i].which) {
		case C_SCALE_HEIGHT:
			if (!(d > 0.0))
				return ERR_RANGE("%s: must be > 0", key);
			c->density = (struct atmo_profile){ 0 };
			c->density.layers[1].exp_term = 1.0;
			c->density.layers[1].exp_scale_per_km = -1.0 / d;
			return 0;
		case C_G:
			if (!(fabs(d) < 1.0))
				return ERR_RANGE("%s: must satisfy |g| < 1", key);
			c->g = d;
			return 0;
		case C_WIDTH:
			if (d < 0.0)
				return ERR_RANGE("%s: must be >= 0", key);
			l->width_km = d;
			return 0;
		case C_EXP_TERM: l->exp_term = d; return 0;
		case C_EXP_SCALE: l->exp_scale_per_km = d; return 0;
		case C_LINEAR: l->linear_per_km = d; return 0;
		case C_CONSTANT: l->constant = d; return 0;
		default: break;
		}
	}
	return ERR_UNKNOWN("%s: unknown key", key);
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
		if (parse_double(v, &d) < 0)
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
		else if (parse_double(v, &d) < 0)
			return ERR("delta_t_s: '%s' is not auto or a finite number", v);
		else if (fabs(d) > 1e6)
			return ERR_RANGE("delta_t_s: %g is outside [-1e6, 1e6]", d);
		c->delta_t_s = d;
	} else if (strcmp(key, "sun_mode") == 0 || strcmp(key, "moon_mode") == 0) {
		int m = enum_index(mode_names, v);
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

static const struct key *find_key(const char *name)
{
	for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
		if (strcmp(keys[i].name, name) == 0)
			return &keys[i];
	return NULL;
}

/* ---- the light sensor's keys (docs/sensor.md) ----
 * A block of its own: its own table, listed by `get` only while it differs
 * from its defaults (state_foreach), and a mode that, leaving cloud, gives
 * the lights back their full illuminance. The ranges are sensor_config's
 * (daemon/sensor/sensor.h), which the service checks again. */

static const char *const sensor_mode_names[] = { "off", "cloud", "elevation", "exposure", NULL };

#define SOFF(field) OFF(sensor.field)
static const struct key sensor_key_table[] = {
	{ "sensor_mode", K_ENUM, SOFF(mode), 0, 0, 0, sensor_mode_names },
	{ "sensor_time_constant_s", K_DOUBLE, SOFF(time_constant_s), 0, 0, 86400, 0 },
	{ "sensor_hysteresis", K_DOUBLE, SOFF(hysteresis), 0, 0, 10, 0 },
	{ "sensor_min_interval_s", K_DOUBLE, SOFF(min_interval_s), 0, 0, 86400, 0 },
	{ "sensor_stale_after_s", K_DOUBLE, SOFF(stale_after_s), 0, 0.001, 86400, 0 },
	{ "sensor_max_lux", K_DOUBLE, SOFF(max_lux), 0, 1, 1e7, 0 },
	{ "sensor_floor_lux", K_DOUBLE, SOFF(floor_lux), 0, 1e-9, 1e3, 0 },
	{ "sensor_report_interval_s", K_DOUBLE, SOFF(report_interval_s), 0, 0.01, 3600, 0 },
	{ "sensor_io_timeout_s", K_DOUBLE, SOFF(io_timeout_s), 0, 0.01, 60, 0 },
	{ "sensor_rescan_s", K_DOUBLE, SOFF(rescan_s), 0, 0.01, 3600, 0 },
};
#define N_SENSOR_KEYS (sizeof(sensor_key_table) / sizeof(sensor_key_table[0]))

const char *const state_sensor_keys[] = {
	"sensor_mode", "sensor_select", "sensor_time_constant_s", "sensor_hysteresis",
	"sensor_min_interval_s", "sensor_stale_after_s", "sensor_max_lux", "sensor_floor_lux",
	"sensor_report_interval_s", "sensor_io_timeout_s", "sensor_rescan_s", NULL,
};

/* sensor_config_defaults' values. */
static void sensor_defaults(struct state_sensor *ret)
{
	*ret = (struct state_sensor){ .mode = STATE_SENSOR_OFF, .time_constant_s = 5.0,
		.hysteresis = 0.05, .min_interval_s = 1.0, .stale_after_s = 30.0,
		.max_lux = 200000.0, .floor_lux = 0.01, .report_interval_s = 0.5,
		.io_timeout_s = 1.0, .rescan_s = 5.0, .light_factor = 1.0 };
	snprintf(ret->select, sizeof(ret->select), "auto");
}

const char *state_sensor_mode_name(enum state_sensor_mode m)
{
	return (unsigned)m < 4 ? sensor_mode_names[m] : "?";
}

void state_set_light_factor(struct sky_state *s, double factor, uint32_t *ret_dirty)
{
	double f = fmin(fmax(factor, STATE_LIGHT_FACTOR_MIN), 1.0);

	if (ret_dirty && f != s->sensor.light_factor)
		*ret_dirty |= LIGHTS;
	s->sensor.light_factor = f;
}

static const struct key *find_sensor_key(const char *name)
{
	for (size_t i = 0; i < N_SENSOR_KEYS; i++)
		if (strcmp(sensor_key_table[i].name, name) == 0)
			return &sensor_key_table[i];
	return NULL;
}

/* The forms of sensor_config's select; no spaces, as every value. */
static int valid_select(const char *v)
{
	return !strcmp(v, "auto") || !strcmp(v, "none") || (!strncmp(v, "bus:", 4) && v[4]) ||
	       (!strncmp(v, "serial:", 7) && v[7]) || (!strncmp(v, "name:", 5) && v[5]);
}

/* A sensor key into s. Returns 1 if key is not one, else 0 or -errno with
 * err; a mode other than cloud sets the light factor back to 1. */
static int set_sensor_key(struct sky_state *s, const char *key, const char *v,
			  uint32_t *ret_dirty, char *err, size_t err_size)
{
	if (strcmp(key, "sensor_select") == 0) {
		if (strlen(v) >= sizeof(s->sensor.select))
			return ERR_RANGE("sensor_select: longer than %zu bytes",
					 sizeof(s->sensor.select) - 1);
		if (!valid_select(v))
			return ERR("sensor_select: '%s' is not auto, none, bus:PORTS, serial:TEXT or name:TEXT", v);
		snprintf(s->sensor.select, sizeof(s->sensor.select), "%s", v);
		return 0;
	}
	const struct key *k = find_sensor_key(key);
	if (!k)
		return 1;
	int r = set_key(s, k, v, err, err_size);
	if (r < 0)
		return r;
	if (k->kind == K_ENUM && s->sensor.mode != STATE_SENSOR_CLOUD)
		state_set_light_factor(s, 1.0, ret_dirty);
	return 0;
}

static void format_value(const struct sky_state *s, const struct key *k, char *buf, size_t n);

/* One sensor key's value; -ENOENT if key is not one. */
static int get_sensor_key(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	if (strcmp(key, "sensor_select") == 0) {
		snprintf(buf, size, "%s", s->sensor.select);
		return 0;
	}
	const struct key *k = find_sensor_key(key);
	if (!k)
		return -ENOENT;
	format_value(s, k, buf, size);
	return 0;
}

static void foreach_sensor(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	struct sky_state d;
	char buf[STATE_SENSOR_SELECT_MAX], def[STATE_SENSOR_SELECT_MAX];
	int same = 1;

	sensor_defaults(&d.sensor);
	for (int i = 0; state_sensor_keys[i] && same; i++) {
		get_sensor_key(s, state_sensor_keys[i], buf, sizeof(buf));
		get_sensor_key(&d, state_sensor_keys[i], def, sizeof(def));
		same = strcmp(buf, def) == 0;
	}
	if (same)
		return;
	for (int i = 0; state_sensor_keys[i]; i++) {
		get_sensor_key(s, state_sensor_keys[i], buf, sizeof(buf));
		fn(ctx, state_sensor_keys[i], buf);
	}
}


int state_set(struct sky_state *s, const char *key, const char *value,
	      uint32_t *ret_dirty, char *err, size_t err_size)
{
	struct sky_state before = *s;
	uint32_t dirty = 0;
	int r;

	r = set_clock_key(s, key, value, &dirty, err, err_size);
	if (r > 0)
		r = set_sensor_key(s, key, value, &dirty, err, err_size);
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
		dirty = FROM_T;
	} else {
		const struct key *k = find_key(key);
		if (k) {
			r = set_key(s, k, value, err, err_size);
			dirty = k->dirty;
		} else {
			const char *suffix;
			struct atmo_constituent *c = find_constituent(s, key, &suffix);
			if (!c)
				return ERR_UNKNOWN("%s: unknown key", key);
			r = set_constituent(c, key, suffix, value, err, err_size);
			dirty = FROM_T;
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

static void format_value(const struct sky_state *s, const struct key *k, char *buf, size_t n)
{
	const char *base = (const char *)s + k->offset;
	switch (k->kind) {
	case K_DOUBLE: snprintf(buf, n, "%.9g", *(const double *)base); break;
	case K_TRIPLE: {
		const double *t = (const double *)base;
		snprintf(buf, n, "%.9g,%.9g,%.9g", t[0], t[1], t[2]);
		break;
	}
	case K_UINT: snprintf(buf, n, "%u", *(const uint32_t *)base); break;
	case K_ENUM: snprintf(buf, n, "%s", k->names[*(const int *)base]); break;
	}
}

static void format_constituent(const struct atmo_constituent *c, size_t which, char *buf, size_t n)
{
	const struct atmo_layer *l = &c->density.layers[ckeys[which].layer];
	switch (ckeys[which].which) {
	case C_SCATTERING:
	case C_ABSORPTION: {
		const double *t = ckeys[which].which == C_SCATTERING ? c->scattering_per_km
								    : c->absorption_per_km;
		snprintf(buf, n, "%.9g,%.9g,%.9g", t[0], t[1], t[2]);
		break;
	}
	case C_SCALE_HEIGHT:
		/* Defined only for a pure exponential profile. */
		if (c->density.layers[1].exp_scale_per_km < 0 && c->density.layers[0].width_km == 0)
			snprintf(buf, n, "%.9g", -1.0 / c->density.layers[1].exp_scale_per_km);
		else
			snprintf(buf, n, "none");
		break;
	case C_G: snprintf(buf, n, "%.9g", c->g); break;
	case C_PHASE: snprintf(buf, n, "%s", phase_names[c->phase]); break;
	case C_WIDTH: snprintf(buf, n, "%.9g", l->width_km); break;
	case C_EXP_TERM: snprintf(buf, n, "%.9g", l->exp_term); break;
	case C_EXP_SCALE: snprintf(buf, n, "%.9g", l->exp_scale_per_km); break;
	case C_LINEAR: snprintf(buf, n, "%.9g", l->linear_per_km); break;
	case C_CONSTANT: snprintf(buf, n, "%.9g", l->constant); break;
	}
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
	char buf[128], name[64];

	fn(ctx, "preset", s->preset);
	for (int i = 0; clock_special[i]; i++) {
		format_clock_key(s, clock_special[i], buf, sizeof(buf));
		fn(ctx, clock_special[i], buf);
	}
	for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++) {
		format_value(s, &keys[i], buf, sizeof(buf));
		fn(ctx, keys[i].name, buf);
	}
	for (int c = 0; c < s->atmo.n_constituents; c++)
		for (size_t i = 0; i < sizeof(ckeys) / sizeof(ckeys[0]); i++) {
			snprintf(name, sizeof(name), "%s_%s", s->atmo.c[c].name, ckeys[i].suffix);
			format_constituent(&s->atmo.c[c], i, buf, sizeof(buf));
			fn(ctx, name, buf);
		}
	foreach_sensor(s, fn, ctx);
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
	const struct key *k = find_key(key);
	if (k) {
		format_value(s, k, buf, size);
		return 0;
	}
	if (get_sensor_key(s, key, buf, size) == 0)
		return 0;
	for (int c = 0; c < s->atmo.n_constituents; c++) {
		size_t n = strlen(s->atmo.c[c].name);
		if (strncmp(key, s->atmo.c[c].name, n) || key[n] != '_')
			continue;
		for (size_t i = 0; i < sizeof(ckeys) / sizeof(ckeys[0]); i++)
			if (strcmp(key + n + 1, ckeys[i].suffix) == 0) {
				format_constituent(&s->atmo.c[c], i, buf, size);
				return 0;
			}
	}
	return -ENOENT;
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

void state_direction(double elevation_deg, double azimuth_deg, double ret[3])
{
	double el = elevation_deg * M_PI / 180.0, az = azimuth_deg * M_PI / 180.0;
	ret[0] = cos(el) * sin(az);
	ret[1] = cos(el) * cos(az);
	ret[2] = sin(el);
}

void state_camera_basis(const struct state_camera *c, double fwd[3], double right[3], double up[3])
{
	double yaw = c->yaw_deg * M_PI / 180.0, roll = c->roll_deg * M_PI / 180.0;
	double f[3], r0[3] = { cos(yaw), -sin(yaw), 0.0 };	/* level, to the right */

	state_direction(c->pitch_deg, c->yaw_deg, f);
	double u0[3] = { r0[1] * f[2] - r0[2] * f[1], r0[2] * f[0] - r0[0] * f[2],
			 r0[0] * f[1] - r0[1] * f[0] };		/* r0 x f: up */
	for (int i = 0; i < 3; i++) {
		fwd[i] = f[i];
		right[i] = cos(roll) * r0[i] + sin(roll) * u0[i];
		up[i] = -sin(roll) * r0[i] + cos(roll) * u0[i];
	}
}

/* state_keys.c - the table of the state's keys (what each sets, its range,
 * what it invalidates, what it is), their parsing and formatting, and the
 * key list that proto/PROTOCOL.md carries. */
#include "state_internal.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "simclock.h"

enum kind { K_DOUBLE, K_TRIPLE, K_UINT, K_ENUM };

struct state_key {
	const char *name;
	enum kind kind;
	size_t offset;
	uint32_t dirty;		/* tables a change of this key invalidates */
	double min, max;	/* inclusive; for K_ENUM unused */
	const char *const *names; /* K_ENUM value names, NULL-terminated */
	const char *unit;	/* for the key list: "-" for none */
	const char *doc;	/* one sentence for the key list */
};

static const char *const storage_names[] = { "f32", "f16", NULL };
static const char *const spacing_names[] = { "linear", "squared", NULL };
static const char *const iteration_names[] = { "auto", "0", "1", "2", "3", "4", NULL };
static const char *const moment_names[] = { "auto", "off", "on", NULL };

#define OFF(field) offsetof(struct sky_state, field)
#define QT(i, f) OFF(quality.t[i].f)
#define BIG 1e300
#define D(field, dirty, lo, hi) K_DOUBLE, OFF(field), dirty, lo, hi, 0
#define U(i, f, dirty, lo, hi) K_UINT, QT(i, f), dirty, lo, hi, 0

static const struct state_key keys[] = {
	{ "bottom_radius_km", D(atmo.bottom_radius_km, FROM_T, 1e-3, 1e7), "km",
	  "radius of the planet's ground" },
	{ "top_radius_km", D(atmo.top_radius_km, FROM_T, 1e-3, 1e7), "km",
	  "radius of the top of the atmosphere" },
	{ "ground_albedo", K_TRIPLE, OFF(atmo.ground_albedo), FROM_M, 0, 1, 0, "-",
	  "the ground's diffuse reflectance, r,g,b or one number" },
	{ "altitude_km", D(altitude_km, LIGHTS, -BIG, 1e7), "km",
	  "the observer above the ground (below it: on the ground)" },

	{ "sun_elevation_deg", D(sun.elevation_deg, LIGHTS, -90, 90), "deg",
	  "the sun's geometric elevation; setting it makes the sun manual" },
	{ "sun_azimuth_deg", D(sun.azimuth_deg, LIGHTS, -360, 720), "deg",
	  "the sun's azimuth, eastward from north" },
	{ "sun_illuminance_lx", D(sun.illuminance_lx, LIGHTS, 0, 1e9), "lx",
	  "the sun's illuminance at the top of the atmosphere (the tables get it times the cloud factor)" },
	{ "sun_color", K_TRIPLE, OFF(sun.color), LIGHTS, 0, 1e3, 0, "-",
	  "the sun's linear RGB tint, luminance 1; never the clock's" },
	{ "sun_angular_radius_deg", D(sun.angular_radius_deg, LIGHTS, 1e-4, 20), "deg",
	  "the sun disk's angular radius" },
	{ "moon_elevation_deg", D(moon.elevation_deg, LIGHTS, -90, 90), "deg",
	  "the moon's geometric elevation; setting it makes the moon manual" },
	{ "moon_azimuth_deg", D(moon.azimuth_deg, LIGHTS, -360, 720), "deg",
	  "the moon's azimuth, eastward from north" },
	{ "moon_illuminance_lx", D(moon.illuminance_lx, LIGHTS, 0, 1e9), "lx",
	  "the moon's illuminance at the top of the atmosphere; 0 lights nothing" },
	{ "moon_color", K_TRIPLE, OFF(moon.color), LIGHTS, 0, 1e3, 0, "-",
	  "the moon's linear RGB tint, luminance 1" },
	{ "moon_angular_radius_deg", D(moon.angular_radius_deg, LIGHTS, 1e-4, 20), "deg",
	  "the moon disk's angular radius" },

	{ "camera_yaw_deg", D(camera.yaw_deg, A_BIT, -360, 720), "deg",
	  "azimuth of the aerial-perspective camera's axis" },
	{ "camera_pitch_deg", D(camera.pitch_deg, A_BIT, -90, 90), "deg",
	  "elevation of the camera's axis" },
	{ "camera_roll_deg", D(camera.roll_deg, A_BIT, -180, 180), "deg", "the camera's roll" },
	{ "camera_vfov_deg", D(camera.vfov_deg, A_BIT, 0.1, 179), "deg",
	  "the camera's vertical field of view" },
	{ "camera_aspect", D(camera.aspect, A_BIT, 0.01, 100), "-", "the camera's width over height" },

	{ "transmittance_width", U(0, width, FROM_T, 2, 4096), "texels", "transmittance table width" },
	{ "transmittance_height", U(0, height, FROM_T, 2, 4096), "texels",
	  "transmittance table height" },
	{ "transmittance_steps", U(0, steps, FROM_T, 1, 4096), "steps",
	  "quadrature steps of a transmittance ray" },
	{ "multiscatter_width", U(1, width, FROM_M, 2, 1024), "texels",
	  "multi-scattering table width" },
	{ "multiscatter_height", U(1, height, FROM_M, 2, 1024), "texels",
	  "multi-scattering table height" },
	{ "multiscatter_steps", U(1, steps, FROM_M, 1, 4096), "steps",
	  "quadrature steps of a multi-scattering ray" },
	{ "multiscatter_dirs", K_UINT, OFF(quality.multiscatter_dirs), FROM_M, 0, 64, 0,
	  "directions", "0 (multi-scattering off), 2 (up and down) or 64" },
	{ "multiscatter_iterations", K_ENUM, OFF(quality.multiscatter_iterations), FROM_M, 0, 0,
	  iteration_names, "-",
	  "steps of the neighbourhood iteration of psi_ms; auto: 2 where the vertical optical depth reaches 1" },
	{ "multiscatter_moment", K_ENUM, OFF(quality.multiscatter_moment), FROM_M, 0, 0, moment_names,
	  "-", "the multiply scattered light's shape through the most forward phase" },
	{ "multiscatter_delta", K_ENUM, OFF(quality.multiscatter_delta), FROM_M, 0, 0, moment_names,
	  "-", "delta-M scaling of the forward peak for the orders >= 2" },
	{ "skyview_width", U(2, width, S_BIT, 2, 4096), "texels", "sky-view table width" },
	{ "skyview_height", U(2, height, S_BIT, 2, 4096), "texels", "sky-view table height" },
	{ "skyview_steps", U(2, steps, S_BIT, 1, 4096), "steps", "most quadrature steps of a sky-view ray" },
	{ "skyview_min_steps", K_UINT, OFF(quality.skyview_min_steps), S_BIT, 1, 4096, 0, "steps",
	  "fewest quadrature steps of a sky-view ray; at most skyview_steps" },
	{ "aerial_width", U(3, width, A_BIT, 1, 1024), "texels", "aerial-perspective volume width" },
	{ "aerial_height", U(3, height, A_BIT, 1, 1024), "texels", "aerial-perspective volume height" },
	{ "aerial_depth", U(3, depth, A_BIT, 1, 1024), "slices", "aerial-perspective volume slices" },
	{ "aerial_steps", U(3, steps, A_BIT, 1, 256), "steps", "quadrature steps per slice" },
	{ "aerial_range_km", D(quality.aerial_range_km, A_BIT, 1e-3, 1e5), "km",
	  "depth of the last slice's far edge" },
	{ "aerial_spacing", K_ENUM, OFF(quality.aerial_spacing), A_BIT, 0, 0, spacing_names, "-",
	  "slice depths linear or squared in the slice index" },
	{ "storage", K_ENUM, OFF(quality.storage), STATE_ALL_TABLES, 0, 0, storage_names, "-",
	  "texels as float32 or float16" },

	/* The site and the clock's settings; utc, time_rate, delta_t_s and the
	 * light modes have their own parsers (set_clock_key). Refraction only
	 * changes the reported direction, never the tables. */
	{ "lat_deg", D(clock.lat_deg, LIGHTS, -90, 90), "deg",
	  "the site's geodetic latitude, north positive; hands both lights to the clock" },
	{ "lon_deg", D(clock.lon_deg, LIGHTS, -180, 180), "deg",
	  "the site's longitude, east positive; hands both lights to the clock" },
	{ "site_elevation_m", D(clock.site_elevation_m, LIGHTS, -1000, 1e5), "m",
	  "the site above sea level (parallax); hands both lights to the clock" },
	{ "pressure_mbar", D(clock.pressure_mbar, 0, 0, 5000), "mbar",
	  "air pressure at the site, for refraction (reported directions only)" },
	{ "temperature_c", D(clock.temperature_c, 0, -100, 100), "C",
	  "air temperature at the site, for refraction (reported directions only)" },
	{ "horizon_refraction_deg", D(clock.horizon_refraction_deg, 0, 0, 3), "deg",
	  "refraction at the horizon (SPA's atmos_refract)" },
	{ "clock_threshold_deg", D(clock.threshold_deg, 0, 1e-4, 180), "deg",
	  "recompute when the sun or a lit moon moved this far" },
	{ "clock_cadence_s", D(clock.cadence_s, 0, 0, 86400), "s",
	  "and at least this often while the clock runs; 0 never" },
	{ "night_zenith_luminance_cd_m2", D(night.zenith_luminance_cd_m2, LIGHTS, 0, 1e3), "cd/m2",
	  "night-sky floor at the zenith; 0 switches it off" },
	{ "night_illuminance_lx", D(night.illuminance_lx, LIGHTS, 0, 1e4), "lx",
	  "horizontal illuminance of the whole night-sky floor; at least pi times its zenith luminance" },
};
#define N_KEYS (sizeof(keys) / sizeof(keys[0]))

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
	const char *unit, *range, *doc;
} ckeys[] = {
	{ "scattering_per_km", C_SCATTERING, 0, "1/km", ">= 0",
	  "scattering at density 1, r,g,b or one number" },
	{ "absorption_per_km", C_ABSORPTION, 0, "1/km", ">= 0",
	  "absorption at density 1, r,g,b or one number" },
	{ "scale_height_km", C_SCALE_HEIGHT, 0, "km", "> 0",
	  "makes the profile one exponential of this scale height (none: it is not one)" },
	{ "g", C_G, 0, "-", "(-1, 1)", "asymmetry of the cornette_shanks or henyey_greenstein phase" },
	{ "phase", C_PHASE, 0, "-", "none, rayleigh, cornette_shanks, henyey_greenstein",
	  "phase function (none: absorbs only)" },
	{ "layer0_width_km", C_WIDTH, 0, "km", ">= 0",
	  "height where the profile's lower layer ends and the upper begins" },
	{ "layer0_exp_term", C_EXP_TERM, 0, "-", "finite",
	  "lower layer: density = clamp(exp_term exp(exp_scale_per_km h) + linear_per_km h + constant, 0, 1)" },
	{ "layer0_exp_scale_per_km", C_EXP_SCALE, 0, "1/km", "finite", "lower layer's exponent" },
	{ "layer0_linear_per_km", C_LINEAR, 0, "1/km", "finite", "lower layer's linear term" },
	{ "layer0_constant", C_CONSTANT, 0, "-", "finite", "lower layer's constant" },
	{ "layer1_exp_term", C_EXP_TERM, 1, "-", "finite", "upper layer's exp_term" },
	{ "layer1_exp_scale_per_km", C_EXP_SCALE, 1, "1/km", "finite", "upper layer's exponent" },
	{ "layer1_linear_per_km", C_LINEAR, 1, "1/km", "finite", "upper layer's linear term" },
	{ "layer1_constant", C_CONSTANT, 1, "-", "finite", "upper layer's constant" },
};
#define N_CKEYS (sizeof(ckeys) / sizeof(ckeys[0]))

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
		if (proto_parse_number(parts[i], &out[i]) < 0)
			return -EINVAL;
	for (int i = 0; i < 3; i++)
		ret[i] = out[n == 1 ? 0 : i];
	return 0;
}

int state_enum_index(const char *const *names, const char *v)
{
	for (int i = 0; names[i]; i++)
		if (strcmp(names[i], v) == 0)
			return i;
	return -1;
}


int state_set_table_key(struct sky_state *s, const struct state_key *k, const char *v,
			char *err, size_t err_size)
{
	char *base = (char *)s + k->offset;
	double d, t[3];

	switch (k->kind) {
	case K_DOUBLE:
		if (proto_parse_number(v, &d) < 0)
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
		int i = state_enum_index(k->names, v);
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
	for (size_t i = 0; i < N_CKEYS; i++) {
		if (strcmp(ckeys[i].suffix, suffix) != 0)
			continue;
		struct atmo_layer *l = &c->density.layers[ckeys[i].layer];
		double d, t[3];
		if (ckeys[i].which == C_PHASE) {
			int p = state_enum_index(phase_names, v);
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
		if (proto_parse_number(v, &d) < 0)
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

const struct state_key *state_find_key(const char *name)
{
	for (size_t i = 0; i < N_KEYS; i++)
		if (strcmp(keys[i].name, name) == 0)
			return &keys[i];
	return NULL;
}

uint32_t state_key_dirty(const struct state_key *k)
{
	return k->dirty;
}

static void format_value(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
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

int state_set_constituent_key(struct sky_state *s, const char *key, const char *value,
			      char *err, size_t err_size)
{
	const char *suffix;
	struct atmo_constituent *c = find_constituent(s, key, &suffix);

	if (!c)
		return ERR_UNKNOWN("%s: unknown key", key);
	return set_constituent(c, key, suffix, value, err, err_size);
}

int state_get_key(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	const struct state_key *k = state_find_key(key);
	if (k) {
		format_value(s, k, buf, size);
		return 0;
	}
	for (int c = 0; c < s->atmo.n_constituents; c++) {
		size_t n = strlen(s->atmo.c[c].name);
		if (strncmp(key, s->atmo.c[c].name, n) || key[n] != '_')
			continue;
		for (size_t i = 0; i < N_CKEYS; i++)
			if (strcmp(key + n + 1, ckeys[i].suffix) == 0) {
				format_constituent(&s->atmo.c[c], i, buf, size);
				return 0;
			}
	}
	return -ENOENT;
}

void state_foreach_key(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char buf[128], name[64];

	for (size_t i = 0; i < N_KEYS; i++) {
		format_value(s, &keys[i], buf, sizeof(buf));
		fn(ctx, keys[i].name, buf);
	}
	for (int c = 0; c < s->atmo.n_constituents; c++)
		for (size_t i = 0; i < N_CKEYS; i++) {
			snprintf(name, sizeof(name), "%s_%s", s->atmo.c[c].name, ckeys[i].suffix);
			format_constituent(&s->atmo.c[c], i, buf, sizeof(buf));
			fn(ctx, name, buf);
		}
}

/* ---- the key list (skyd --list-keys) ---- */

/* Keys outside the table: their own parsers in state.c and state_weather.c. */
static const struct {
	const char *name, *unit, *range;
	uint32_t dirty;
	const char *doc;
} special_keys[] = {
	{ "preset", "-", "earth, mars", FROM_T,
	  "the atmosphere: planet, shell and constituents; resets every raw atmosphere key" },
	{ "quality", "-", "low, medium, high, ultra", STATE_ALL_TABLES,
	  "every size, step count, multiscatter_dirs and storage at once" },
	{ "utc", "-", "now or ISO 8601 with a zone", LIGHTS,
	  "the simulated time; hands both lights to the clock" },
	{ "time_rate", "-", NULL, 0,
	  "simulated seconds per real second; the time goes on without a jump" },
	{ "delta_t_s", "s", "auto or [-1e+06, 1e+06]", LIGHTS,
	  "TT - UT1; auto: Espenak and Meeus at the date" },
	{ "sun_mode", "-", "manual, clock", LIGHTS, "clock: the clock drives the sun" },
	{ "moon_mode", "-", "manual, clock", LIGHTS, "clock: the clock drives the moon" },
};

/* The weather keys (daemon/weather/weather.h), in weather_keys' order. */
static const struct {
	const char *name, *unit, *range, *doc;
} weather_docs[] = {
	{ "visibility_km", "km", "auto or [0.05, 300]",
	  "meteorological optical range: the aerosol extinction at 550 nm (Koschmieder)" },
	{ "relative_humidity", "-", "auto or [0, 1]",
	  "hygroscopic growth of the aerosol: albedo, g, colour" },
	{ "aerosol", "-", "auto, clean, continental, urban, maritime, desert",
	  "the aerosol type, an OPAC mixture" },
	{ "angstrom_beta", "-", "auto or [0, 10]",
	  "turbidity: the aerosol optical depth at 1000 nm" },
	{ "ozone_du", "DU", "auto or [0, 600]", "total ozone column; scales the ozone absorption" },
	{ "cloud_oktas", "oktas", "auto or [0, 8]",
	  "cloud cover: the sun's and moon's illuminance factor (Kasten and Czeplak)" },
	{ "cloud_fraction", "-", "auto or [0, 1]", "cloud cover as a fraction: cloud_oktas / 8" },
	{ "metar", "-", "a METAR or SPECI report, quoted",
	  "sets visibility_km, relative_humidity, aerosol, cloud_oktas, pressure_mbar, temperature_c; write-only" },
};

/* A key list row; markdown escapes nothing, so no field may hold a '|'. */
void state_print_row(FILE *f, bool markdown, const char *name, const char *unit,
		     const char *range, const char *def, uint32_t dirty, const char *doc)
{
	char tables[96];

	if (dirty == STATE_ALL_TABLES)
		snprintf(tables, sizeof(tables), "all");
	else
		state_format_tables(dirty, tables, sizeof(tables));
	if (markdown)
		fprintf(f, "| `%s` | %s | %s | `%s` | %s | %s |\n", name, unit, range, def, tables, doc);
	else
		fprintf(f, "%s\t%s\t%s\t%s\t%s\t%s\n", name, unit, range, def, tables, doc);
}

static void key_range(const struct state_key *k, char *buf, size_t n)
{
	size_t o = 0;

	if (k->kind == K_ENUM) {
		buf[0] = 0;
		for (int i = 0; k->names[i]; i++)
			o += (size_t)snprintf(buf + o, o < n ? n - o : 0, "%s%s", i ? ", " : "",
					      k->names[i]);
	} else if (strcmp(k->name, "multiscatter_dirs") == 0) {
		snprintf(buf, n, "0, 2, 64");
	} else if (k->min == -BIG) {
		snprintf(buf, n, "<= %g", k->max);
	} else {
		snprintf(buf, n, "[%g, %g]", k->min, k->max);
	}
}

void state_print_keys(FILE *f, bool markdown)
{
	struct sky_state s;
	char def[128], range[96], name[64];

	state_default(&s);
	if (markdown)
		fprintf(f, "| key | unit | range | default | invalidates | what it is |\n"
			   "| --- | --- | --- | --- | --- | --- |\n");
	for (size_t i = 0; i < sizeof(special_keys) / sizeof(special_keys[0]); i++) {
		if (state_get(&s, special_keys[i].name, def, sizeof(def)) < 0)
			snprintf(def, sizeof(def), "-");
		/* NULL: time_rate's range, simclock's. */
		snprintf(range, sizeof(range), "[%g, %g]", -SIMCLOCK_RATE_MAX, SIMCLOCK_RATE_MAX);
		state_print_row(f, markdown, special_keys[i].name, special_keys[i].unit,
				special_keys[i].range ? special_keys[i].range : range, def,
				special_keys[i].dirty, special_keys[i].doc);
	}
	for (size_t i = 0; i < N_KEYS; i++) {
		format_value(&s, &keys[i], def, sizeof(def));
		key_range(&keys[i], range, sizeof(range));
		state_print_row(f, markdown, keys[i].name, keys[i].unit, range, def, keys[i].dirty,
				keys[i].doc);
	}
	for (size_t i = 0; i < sizeof(weather_docs) / sizeof(weather_docs[0]); i++) {
		unsigned affects = weather_key_affects(weather_docs[i].name);
		if (state_get(&s, weather_docs[i].name, def, sizeof(def)) < 0)
			snprintf(def, sizeof(def), "-");
		state_print_row(f, markdown, weather_docs[i].name, weather_docs[i].unit,
				weather_docs[i].range, def,
				affects & WEATHER_AFFECTS_LIGHTS ? LIGHTS : FROM_T, weather_docs[i].doc);
	}
	for (int c = 0; c < s.atmo.n_constituents; c++)
		for (size_t i = 0; i < N_CKEYS; i++) {
			snprintf(name, sizeof(name), "%s_%s", s.atmo.c[c].name, ckeys[i].suffix);
			format_constituent(&s.atmo.c[c], i, def, sizeof(def));
			state_print_row(f, markdown, name, ckeys[i].unit, ckeys[i].range, def,
					FROM_T, ckeys[i].doc);
		}
	state_print_sensor_keys(f, markdown);
}

/* state_keys.c - the key registry: every key of the sky's state, one row
 * each, and what reads the rows: set (a lookup and the row's setter), get,
 * the defaults and the key list of skyd --list-keys.
 *
 * Adding a key is adding a row (struct state_key, state_keys.h), where its
 * neighbours are: the order of the rows is the order of `get` and of the
 * key list.
 *   - A plain key names its kind and its field in struct sky_state, its
 *     range, default, unit, the tables a change invalidates and one line
 *     of doc: the kind's parser and format (state_key_parse/_format) do
 *     the rest, its name appears nowhere else.
 *   - A key that needs code gets a hook: .set and .get, declared in
 *     state_internal.h by the room that implements it (state_clock.c,
 *     state_atmo.c, state_weather.c, state_sensor.c). A hook parses with
 *     state_key_parse where the kind fits and adds what the key does.
 *   - A family of keys (the constituents' rayleigh_g, mie_g, ...) is a
 *     macro holding what its members share, and one row per member with
 *     the member's literal name: CONSTITUENT below. Layered families such
 *     as cloudN_base_m take the index as an argument and address their
 *     field with it (.offset = OFF(clouds.layer[N - 1].base_m): CL_BASE).
 *   - Code elsewhere that must name a key uses its row: state_key_find,
 *     or an id (enum state_key_id) in the row and state_key_of.
 * Then regenerate the key list of proto/PROTOCOL.md (tools/gen_keys_doc.sh);
 * skyd.conf(5) follows at build time. */
#include "state_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"
#include "simclock.h"
#include "skycloud.h"

static const char *const storage_names[] = { "f32", "f16", NULL };
static const char *const spacing_names[] = { "linear", "squared", NULL };
static const char *const iteration_names[] = { "auto", "0", "1", "2", "3", "4", NULL };
static const char *const moment_names[] = { "auto", "off", "on", NULL };
static const char *const light_mode_names[] = { "manual", "clock", NULL };

static state_key_set_fn set_multiscatter_dirs;

#define OFF(field) offsetof(struct sky_state, field)
#define BIG 1e300
#define NUMBER(field, lo, hi) .kind = STATE_KIND_NUMBER, .offset = OFF(field), .min = (lo), .max = (hi)
#define NUMBER_AUTO(field, lo, hi) \
	.kind = STATE_KIND_NUMBER_AUTO, .offset = OFF(field), .min = (lo), .max = (hi), .def = NAN
#define INTEGER(field, lo, hi) .kind = STATE_KIND_INTEGER, .offset = OFF(field), .min = (lo), .max = (hi)
#define TRIPLE(field, lo, hi) .kind = STATE_KIND_TRIPLE, .offset = OFF(field), .min = (lo), .max = (hi)
#define WORD(field, list) .kind = STATE_KIND_WORD, .offset = OFF(field), .words = (list)
/* A size or step count of a table: the quality preset gives its default. */
#define TABLE(table, f, lo, hi) \
	INTEGER(quality.t[table].f, lo, hi), .flags = STATE_KEY_PRESET_DEFAULT
/* No default of its own: the preset's (planet) or the quality's. */
#define FROM_PRESET .flags = STATE_KEY_PRESET_DEFAULT

/* The constituent family: "<constituent>_<field>" for each constituent
 * that a preset names (rayleigh, mie, ozone), one row per key, the layer
 * keys with their layer (0 lower, 1 upper). What a field's keys share
 * (kind, unit, range, doc) is written once, in its C_<field> macro; pins
 * is what the key holds against the weather. The hooks find the
 * constituent by the name's prefix: a state whose preset lacks it has no
 * such key. The kind parses any finite number; the hooks check each
 * field's range. */
#define CONSTITUENT(key, field, pins) CONSTITUENT_ROW(key, STATE_##field, pins, field)
#define CONSTITUENT_LAYER(key, layer, field, pins) \
	CONSTITUENT_ROW(key, STATE_##field + (layer) * STATE_C_UPPER, pins, field##_##layer)
#define CONSTITUENT_ROW(key, arg_, pins, ...)                                             \
	{ .name = key, .arg = (arg_), .dirty = FROM_T, .override = (pins),                \
	  .set = state_set_constituent, .get = state_get_constituent, __VA_ARGS__ }
#define C_FIELD(kind_, unit_, range_, flags_, doc_)                                          \
	.kind = STATE_KIND_##kind_, .min = -INFINITY, .max = INFINITY, .unit = unit_,        \
	.range = range_, .flags = STATE_KEY_PRESET_DEFAULT | (flags_), .doc = doc_
#define C_SCATTERING C_FIELD(TRIPLE, "1/km", ">= 0", 0, "scattering at density 1, r,g,b or one number")
#define C_ABSORPTION C_FIELD(TRIPLE, "1/km", ">= 0", 0, "absorption at density 1, r,g,b or one number")
#define C_SCALE_HEIGHT C_FIELD(NUMBER, "km", "> 0", STATE_KEY_NONE_UNSET, \
	"makes the profile one exponential of this scale height (none: it is not one)")
#define C_G C_FIELD(NUMBER, "-", "(-1, 1)", 0, "asymmetry of the cornette_shanks or henyey_greenstein phase")
#define C_PHASE C_FIELD(WORD, "-", NULL, 0, "phase function (none: absorbs only)"), \
	.words = state_phase_names
#define C_WIDTH C_FIELD(NUMBER, "km", ">= 0", 0, \
	"height where the profile's lower layer ends and the upper begins")
#define C_EXP_TERM_0 C_FIELD(NUMBER, "-", "finite", 0, \
	"lower layer: density = clamp(exp_term exp(exp_scale_per_km h) + linear_per_km h + constant, 0, 1)")
#define C_EXP_SCALE_0 C_FIELD(NUMBER, "1/km", "finite", 0, "lower layer's exponent")
#define C_LINEAR_0 C_FIELD(NUMBER, "1/km", "finite", 0, "lower layer's linear term")
#define C_CONSTANT_0 C_FIELD(NUMBER, "-", "finite", 0, "lower layer's constant")
#define C_EXP_TERM_1 C_FIELD(NUMBER, "-", "finite", 0, "upper layer's exp_term")
#define C_EXP_SCALE_1 C_FIELD(NUMBER, "1/km", "finite", 0, "upper layer's exponent")
#define C_LINEAR_1 C_FIELD(NUMBER, "1/km", "finite", 0, "upper layer's linear term")
#define C_CONSTANT_1 C_FIELD(NUMBER, "-", "finite", 0, "upper layer's constant")
#define MIE_PROFILE STATE_OVERRIDE_MIE_PROFILE

/* A weather input: auto (not given) by default, listed by get when given. */
#define WEATHER(field, lo, hi) NUMBER_AUTO(weather.in.field, lo, hi), .listed = STATE_LISTED_GIVEN

/* The cloud layer family (docs/clouds.md; state_clouds.c): cloudN_<field>
 * for the layers N = 1..4, one row per key with its literal name, its
 * field by the layer's index; what a field's keys share is written once,
 * in its CL_<field> macro. The cloud keys are one block: get lists them
 * while one is away from its default, so a state without clouds reads as
 * before. A cloud key invalidates the cloud tables and what their shadows
 * reach, but nothing while no layer is drawn (state_set_cloud_key). */
#define CLOUD_BLOCK .listed = STATE_LISTED_BLOCK, .dirty = CLOUDS, .set = state_set_cloud_key
#define CL_OKTAS(n) NUMBER_AUTO(clouds.layer[(n) - 1].oktas, 0.0, WEATHER_OKTAS_MAX), CLOUD_BLOCK, \
	.unit = "oktas", .doc = "the layer's cover; with a base the layer is drawn"
#define CL_BASE(n) NUMBER_AUTO(clouds.layer[(n) - 1].base_m, 0.0, 20000.0), CLOUD_BLOCK, \
	.unit = "m", .doc = "the layer's base above the ground under the observer"
#define CL_TOP(n) NUMBER_AUTO(clouds.layer[(n) - 1].top_m, 0.0, 20000.0), CLOUD_BLOCK, \
	.unit = "m", .doc = "the layer's top, above its base; auto: the base plus the type's thickness"
#define CL_TYPE(n) WORD(clouds.layer[(n) - 1].type, state_cloud_type_names), CLOUD_BLOCK, \
	.def = SKYCLOUD_STRATOCUMULUS, .unit = "-", \
	.doc = "the layer's type: its profile, extinction, phase and noise (docs/clouds.md)"
#define CL_FRACTION(n) NUMBER_AUTO(clouds.layer[(n) - 1].oktas, 0.0, 1.0), .dirty = CLOUDS, \
	.unit = "-", .listed = STATE_LISTED_NEVER, .set = state_set_cloud_layer_fraction, \
	.get = state_get_cloud_layer_fraction, .doc = "the layer's cover as a fraction: its oktas / 8"

/* The terrain: the shadow maps (its opaque depth) and what they reach. */
#define TERRAIN (STATE_BIT(STATE_CLOUD_SHADOW) | S_BIT | A_BIT)

/* A light sensor key: what its readings do and how they are taken; they
 * invalidate no table (the readings change the state, each a change of
 * its own). The ranges are sensor_config's (daemon/sensor/sensor.h). */
#define SENSOR(field, lo, hi, def_) \
	NUMBER(sensor.field, lo, hi), .def = (def_), .listed = STATE_LISTED_BLOCK

static const struct state_key keys[] = {
	/* ---- the atmosphere, the quality, the clock ---- */
	{ .name = "preset", .kind = STATE_KIND_WORD, .words = atmo_preset_names, .def_text = "earth",
	  .dirty = FROM_T, .unit = "-", .set = state_set_preset, .get = state_get_preset,
	  .doc = "the atmosphere: planet, shell and constituents; resets every raw atmosphere key" },
	{ .name = "quality", .kind = STATE_KIND_WORD, .words = state_quality_names,
	  .def_text = "medium", .dirty = STATE_ALL_TABLES | STATE_CLOUD_TABLES, .unit = "-",
	  .listed = STATE_LISTED_NEVER, .set = state_set_quality, .get = state_get_quality,
	  .doc = "every size, step count, multiscatter_dirs and storage at once" },
	{ .name = "utc", .kind = STATE_KIND_TIME, .offset = OFF(clock.anchor_utc_s), .def = NAN,
	  .dirty = LIGHTS, .unit = "-", .range = "now or ISO 8601 with a zone",
	  .hands = STATE_HANDS_TO_CLOCK, .id = STATE_KEY_ID_UTC,
	  .flags = STATE_KEY_NOW | STATE_KEY_NONE_UNSET, .set = state_set_utc, .get = state_get_utc,
	  .doc = "the simulated time; hands both lights to the clock" },
	/* A rate alone moves nothing until the clock runs on it; a running
	 * clock is re-anchored when the change is committed
	 * (state_clock_rebase), so that utc= and time_rate= in one request
	 * mean the same in any order. */
	{ .name = "time_rate", NUMBER(clock.rate, -SIMCLOCK_RATE_MAX, SIMCLOCK_RATE_MAX), .def = 1.0,
	  .dirty = 0, .unit = "-",
	  .doc = "simulated seconds per real second; the time goes on without a jump" },
	{ .name = "delta_t_s", NUMBER_AUTO(clock.delta_t_s, -1e6, 1e6), .dirty = LIGHTS, .unit = "s",
	  .doc = "TT - UT1; auto: Espenak and Meeus at the date" },
	{ .name = "sun_mode", WORD(clock.sun_mode, light_mode_names), .dirty = LIGHTS, .unit = "-",
	  .flags = STATE_KEY_LAST, .set = state_set_light_mode,
	  .doc = "clock: the clock drives the sun" },
	{ .name = "moon_mode", WORD(clock.moon_mode, light_mode_names), .dirty = LIGHTS, .unit = "-",
	  .flags = STATE_KEY_LAST, .set = state_set_light_mode,
	  .doc = "clock: the clock drives the moon" },

	/* ---- the planet and the observer ---- */
	{ .name = "bottom_radius_km", NUMBER(atmo.bottom_radius_km, 1e-3, 1e7), .dirty = FROM_T,
	  .unit = "km", FROM_PRESET, .doc = "radius of the planet's ground" },
	{ .name = "top_radius_km", NUMBER(atmo.top_radius_km, 1e-3, 1e7), .dirty = FROM_T,
	  .unit = "km", FROM_PRESET, .doc = "radius of the top of the atmosphere" },
	{ .name = "ground_albedo", TRIPLE(atmo.ground_albedo, 0, 1), .dirty = FROM_M, .unit = "-",
	  FROM_PRESET, .doc = "the ground's diffuse reflectance, r,g,b or one number" },
	{ .name = "altitude_km", NUMBER(altitude_km, -BIG, 1e7), .def = 0.2, .dirty = LIGHTS,
	  .unit = "km", .id = STATE_KEY_ID_ALTITUDE_KM,
	  .doc = "the observer above the ground (below it: on the ground)" },

	/* ---- the lights ---- */
	{ .name = "sun_elevation_deg", NUMBER(sun.elevation_deg, -90, 90), .def = 30.0,
	  .dirty = LIGHTS, .unit = "deg", .hands = STATE_HANDS_SUN_TO_USER,
	  .doc = "the sun's geometric elevation; setting it makes the sun manual" },
	{ .name = "sun_azimuth_deg", NUMBER(sun.azimuth_deg, -360, 720), .def = 180.0,
	  .dirty = LIGHTS, .unit = "deg", .hands = STATE_HANDS_SUN_TO_USER,
	  .doc = "the sun's azimuth, eastward from north" },
	{ .name = "sun_illuminance_lx", NUMBER(sun.illuminance_lx, 0, 1e9), .def = 133800.0,
	  .dirty = LIGHTS, .unit = "lx", .hands = STATE_HANDS_SUN_TO_USER,
	  .doc = "the sun's illuminance at the top of the atmosphere (the tables get it times the cloud factor)" },
	{ .name = "sun_color", TRIPLE(sun.color, 0, 1e3), .def = 1.0, .dirty = LIGHTS, .unit = "-",
	  .doc = "the sun's linear RGB tint, luminance 1; never the clock's" },
	/* The multiple-scattering table sees the disk set at the horizon
	 * (multiscatter.comp's sunlight, light_visible): not the lights alone. */
	{ .name = "sun_angular_radius_deg", NUMBER(sun.angular_radius_deg, 1e-4, 20),
	  .def = 0.004675 * 180.0 / M_PI, .dirty = FROM_M, .unit = "deg",
	  .hands = STATE_HANDS_SUN_TO_USER, .doc = "the sun disk's angular radius" },
	{ .name = "moon_elevation_deg", NUMBER(moon.elevation_deg, -90, 90), .def = -30.0,
	  .dirty = LIGHTS, .unit = "deg", .hands = STATE_HANDS_MOON_TO_USER,
	  .doc = "the moon's geometric elevation; setting it makes the moon manual" },
	{ .name = "moon_azimuth_deg", NUMBER(moon.azimuth_deg, -360, 720), .def = 0.0,
	  .dirty = LIGHTS, .unit = "deg", .hands = STATE_HANDS_MOON_TO_USER,
	  .doc = "the moon's azimuth, eastward from north" },
	{ .name = "moon_illuminance_lx", NUMBER(moon.illuminance_lx, 0, 1e9), .def = 0.0,
	  .dirty = LIGHTS, .unit = "lx", .hands = STATE_HANDS_MOON_TO_USER,
	  .doc = "the moon's illuminance at the top of the atmosphere; 0 lights nothing" },
	{ .name = "moon_color", TRIPLE(moon.color, 0, 1e3), .def = 1.0, .dirty = LIGHTS, .unit = "-",
	  .hands = STATE_HANDS_MOON_TO_USER, .doc = "the moon's linear RGB tint, luminance 1" },
	{ .name = "moon_angular_radius_deg", NUMBER(moon.angular_radius_deg, 1e-4, 20), .def = 0.259,
	  .dirty = LIGHTS, .unit = "deg", .hands = STATE_HANDS_MOON_TO_USER,
	  .doc = "the moon disk's angular radius" },

	/* ---- the aerial-perspective camera ---- */
	{ .name = "camera_yaw_deg", NUMBER(camera.yaw_deg, -360, 720), .def = 180.0, .dirty = A_BIT,
	  .unit = "deg", .doc = "azimuth of the aerial-perspective camera's axis" },
	{ .name = "camera_pitch_deg", NUMBER(camera.pitch_deg, -90, 90), .def = 0.0, .dirty = A_BIT,
	  .unit = "deg", .doc = "elevation of the camera's axis" },
	{ .name = "camera_roll_deg", NUMBER(camera.roll_deg, -180, 180), .def = 0.0, .dirty = A_BIT,
	  .unit = "deg", .doc = "the camera's roll" },
	{ .name = "camera_vfov_deg", NUMBER(camera.vfov_deg, 0.1, 179), .def = 60.0, .dirty = A_BIT,
	  .unit = "deg", .doc = "the camera's vertical field of view" },
	{ .name = "camera_aspect", NUMBER(camera.aspect, 0.01, 100), .def = 16.0 / 9.0,
	  .dirty = A_BIT, .unit = "-", .doc = "the camera's width over height" },

	/* ---- the tables' sizes and quadrature (quality) ---- */
	{ .name = "transmittance_width", TABLE(STATE_TRANSMITTANCE, width, 2, 4096), .dirty = FROM_T,
	  .unit = "texels", .doc = "transmittance table width" },
	{ .name = "transmittance_height", TABLE(STATE_TRANSMITTANCE, height, 2, 4096),
	  .dirty = FROM_T, .unit = "texels", .doc = "transmittance table height" },
	{ .name = "transmittance_steps", TABLE(STATE_TRANSMITTANCE, steps, 1, 4096), .dirty = FROM_T,
	  .unit = "steps", .doc = "quadrature steps of a transmittance ray" },
	{ .name = "multiscatter_width", TABLE(STATE_MULTISCATTER, width, 2, 1024), .dirty = FROM_M,
	  .unit = "texels", .doc = "multi-scattering table width" },
	{ .name = "multiscatter_height", TABLE(STATE_MULTISCATTER, height, 2, 1024), .dirty = FROM_M,
	  .unit = "texels", .doc = "multi-scattering table height" },
	{ .name = "multiscatter_steps", TABLE(STATE_MULTISCATTER, steps, 1, 4096), .dirty = FROM_M,
	  .unit = "steps", .doc = "quadrature steps of a multi-scattering ray" },
	{ .name = "multiscatter_dirs", INTEGER(quality.multiscatter_dirs, 0, 64), FROM_PRESET,
	  .dirty = FROM_M, .unit = "directions", .range = "0, 2, 64", .set = set_multiscatter_dirs,
	  .doc = "0 (multi-scattering off), 2 (up and down) or 64" },
	{ .name = "multiscatter_iterations", WORD(quality.multiscatter_iterations, iteration_names),
	  FROM_PRESET, .dirty = FROM_M, .unit = "-",
	  .doc = "steps of the neighbourhood iteration of psi_ms; auto: 2 where the vertical optical depth reaches 1" },
	{ .name = "multiscatter_moment", WORD(quality.multiscatter_moment, moment_names), FROM_PRESET,
	  .dirty = FROM_M, .unit = "-",
	  .doc = "the multiply scattered light's shape through the most forward phase" },
	{ .name = "multiscatter_delta", WORD(quality.multiscatter_delta, moment_names), FROM_PRESET,
	  .dirty = FROM_M, .unit = "-", .doc = "delta-M scaling of the forward peak for the orders >= 2" },
	{ .name = "skyview_width", TABLE(STATE_SKYVIEW, width, 2, 4096), .dirty = S_BIT,
	  .unit = "texels", .doc = "sky-view table width" },
	{ .name = "skyview_height", TABLE(STATE_SKYVIEW, height, 2, 4096), .dirty = S_BIT,
	  .unit = "texels", .doc = "sky-view table height" },
	{ .name = "skyview_steps", TABLE(STATE_SKYVIEW, steps, 1, 4096), .dirty = S_BIT,
	  .unit = "steps", .doc = "most quadrature steps of a sky-view ray" },
	{ .name = "skyview_min_steps", INTEGER(quality.skyview_min_steps, 1, 4096), FROM_PRESET,
	  .dirty = S_BIT, .unit = "steps",
	  .doc = "fewest quadrature steps of a sky-view ray; at most skyview_steps" },
	{ .name = "aerial_width", TABLE(STATE_AERIAL, width, 1, 1024), .dirty = A_BIT,
	  .unit = "texels", .doc = "aerial-perspective volume width" },
	{ .name = "aerial_height", TABLE(STATE_AERIAL, height, 1, 1024), .dirty = A_BIT,
	  .unit = "texels", .doc = "aerial-perspective volume height" },
	{ .name = "aerial_depth", TABLE(STATE_AERIAL, depth, 1, 1024), .dirty = A_BIT,
	  .unit = "slices", .doc = "aerial-perspective volume slices" },
	{ .name = "aerial_steps", TABLE(STATE_AERIAL, steps, 1, 256), .dirty = A_BIT,
	  .unit = "steps", .doc = "quadrature steps per slice" },
	{ .name = "aerial_range_km", NUMBER(quality.aerial_range_km, 1e-3, 1e5), FROM_PRESET,
	  .dirty = A_BIT, .unit = "km", .doc = "depth of the last slice's far edge" },
	{ .name = "aerial_spacing", WORD(quality.aerial_spacing, spacing_names), FROM_PRESET,
	  .dirty = A_BIT, .unit = "-", .doc = "slice depths linear or squared in the slice index" },
	{ .name = "storage", WORD(quality.storage, storage_names), FROM_PRESET, .dirty = STATE_ALL_TABLES,
	  .unit = "-", .doc = "texels as float32 or float16" },
	/* The cloud tables' sizes (docs/clouds.md): nothing while no layer is drawn. */
	{ .name = "cloud_width", INTEGER(quality.cloud_width, 16, 2048), FROM_PRESET, .dirty = CLOUDS,
	  .set = state_set_cloud_key, .unit = "texels",
	  .doc = "size of the cloud coverage table over the field's region (square)" },
	{ .name = "shadow_width", INTEGER(quality.shadow_width, 16, 2048), FROM_PRESET,
	  .dirty = STATE_BIT(STATE_CLOUD_SHADOW) | LIGHTS, .set = state_set_cloud_key,
	  .unit = "texels", .doc = "size of a cloud shadow map over the field's region (square)" },
	{ .name = "cloud_cell_texels", NUMBER(quality.cloud_cell_texels, 0, 64), FROM_PRESET, .dirty = CLOUDS,
	  .set = state_set_cloud_key, .unit = "texels",
	  .doc = "shadow texels the wind carries the field before its tables are remade (0: every move)" },

	/* ---- the site and the clock's settings: refraction only changes
	 * the reported direction, never the tables ---- */
	{ .name = "lat_deg", NUMBER(clock.lat_deg, -90, 90), .def = 0.0, .dirty = LIGHTS,
	  .unit = "deg", .hands = STATE_HANDS_TO_CLOCK,
	  .doc = "the site's geodetic latitude, north positive; hands both lights to the clock" },
	{ .name = "lon_deg", NUMBER(clock.lon_deg, -180, 180), .def = 0.0, .dirty = LIGHTS,
	  .unit = "deg", .hands = STATE_HANDS_TO_CLOCK,
	  .doc = "the site's longitude, east positive; hands both lights to the clock" },
	{ .name = "site_elevation_m", NUMBER(clock.site_elevation_m, -1000, 1e5), .def = 0.0,
	  .dirty = LIGHTS, .unit = "m", .hands = STATE_HANDS_TO_CLOCK,
	  .doc = "the site above sea level (parallax); hands both lights to the clock" },
	/* The site's terrain (docs/terrain.md; state_terrain.c): a block, so
	 * a state without one reads as before. terrain reads the file. */
	{ .name = "terrain", .kind = STATE_KIND_TEXT, .def_text = "none", .dirty = TERRAIN,
	  .unit = "-", .range = "none or an absolute path", .listed = STATE_LISTED_BLOCK,
	  .set = state_set_terrain, .get = state_get_terrain,
	  .doc = "a height field (16-bit greyscale PNG or SKYTERRAIN16 raw) centred on the site; every host needs the same file" },
	{ .name = "terrain_extent_km", NUMBER(terrain.extent_km, 0.01, 1024), .def = 50.0,
	  .dirty = TERRAIN, .unit = "km", .listed = STATE_LISTED_BLOCK, .set = state_set_terrain_key,
	  .doc = "the side of the square the height field covers, centred on the site" },
	{ .name = "terrain_height_m", NUMBER(terrain.height_m, 0, 20000), .def = 1000.0,
	  .dirty = TERRAIN, .unit = "m", .listed = STATE_LISTED_BLOCK, .set = state_set_terrain_key,
	  .doc = "the height above the ground that white (65535) stands for" },
	{ .name = "terrain_hash", .kind = STATE_KIND_TEXT, .dirty = 0, .unit = "-",
	  .range = "none or 16 hex digits", .listed = STATE_LISTED_BLOCK,
	  .set = state_set_terrain_hash, .get = state_get_terrain_hash,
	  .doc = "the field's content hash; set, a check that the file here holds it (a follower's)" },
	{ .name = "pressure_mbar", NUMBER(clock.pressure_mbar, 0, 5000), .def = 1013.25, .dirty = 0,
	  .unit = "mbar", .id = STATE_KEY_ID_PRESSURE_MBAR,
	  .doc = "air pressure at the site, for refraction (reported directions only)" },
	{ .name = "temperature_c", NUMBER(clock.temperature_c, -100, 100), .def = 15.0, .dirty = 0,
	  .unit = "C", .id = STATE_KEY_ID_TEMPERATURE_C,
	  .doc = "air temperature at the site, for refraction (reported directions only)" },
	{ .name = "horizon_refraction_deg", NUMBER(clock.horizon_refraction_deg, 0, 3), .def = 0.5667,
	  .dirty = 0, .unit = "deg", .doc = "refraction at the horizon (SPA's atmos_refract)" },
	{ .name = "clock_threshold_deg", NUMBER(clock.threshold_deg, 1e-4, 180), .def = 0.1,
	  .dirty = 0, .unit = "deg", .doc = "recompute when the sun or a lit moon moved this far" },
	{ .name = "clock_cadence_s", NUMBER(clock.cadence_s, 0, 86400), .def = 60.0, .dirty = 0,
	  .unit = "s", .doc = "and at least this often while the clock runs; 0 never" },

	/* ---- the night-sky floor ---- */
	{ .name = "night_zenith_luminance_cd_m2", NUMBER(night.zenith_luminance_cd_m2, 0, 1e3),
	  .def = 2.0e-4, .dirty = LIGHTS, .unit = "cd/m2",
	  .doc = "night-sky floor at the zenith; 0 switches it off" },
	{ .name = "night_illuminance_lx", NUMBER(night.illuminance_lx, 0, 1e4), .def = 0.002,
	  .dirty = LIGHTS, .unit = "lx",
	  .doc = "horizontal illuminance of the whole night-sky floor; at least pi times its zenith luminance" },

	/* ---- the constituents (state_atmo.c) ---- */
	CONSTITUENT("rayleigh_scattering_per_km", C_SCATTERING, 0),
	CONSTITUENT("rayleigh_absorption_per_km", C_ABSORPTION, 0),
	CONSTITUENT("rayleigh_scale_height_km", C_SCALE_HEIGHT, 0),
	CONSTITUENT("rayleigh_g", C_G, 0),
	CONSTITUENT("rayleigh_phase", C_PHASE, 0),
	CONSTITUENT("rayleigh_layer0_width_km", C_WIDTH, 0),
	CONSTITUENT_LAYER("rayleigh_layer0_exp_term", 0, C_EXP_TERM, 0),
	CONSTITUENT_LAYER("rayleigh_layer0_exp_scale_per_km", 0, C_EXP_SCALE, 0),
	CONSTITUENT_LAYER("rayleigh_layer0_linear_per_km", 0, C_LINEAR, 0),
	CONSTITUENT_LAYER("rayleigh_layer0_constant", 0, C_CONSTANT, 0),
	CONSTITUENT_LAYER("rayleigh_layer1_exp_term", 1, C_EXP_TERM, 0),
	CONSTITUENT_LAYER("rayleigh_layer1_exp_scale_per_km", 1, C_EXP_SCALE, 0),
	CONSTITUENT_LAYER("rayleigh_layer1_linear_per_km", 1, C_LINEAR, 0),
	CONSTITUENT_LAYER("rayleigh_layer1_constant", 1, C_CONSTANT, 0),
	CONSTITUENT("mie_scattering_per_km", C_SCATTERING, STATE_OVERRIDE_MIE_SCATTERING),
	CONSTITUENT("mie_absorption_per_km", C_ABSORPTION, STATE_OVERRIDE_MIE_ABSORPTION),
	CONSTITUENT("mie_scale_height_km", C_SCALE_HEIGHT, MIE_PROFILE),
	CONSTITUENT("mie_g", C_G, STATE_OVERRIDE_MIE_G),
	CONSTITUENT("mie_phase", C_PHASE, 0),
	CONSTITUENT("mie_layer0_width_km", C_WIDTH, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer0_exp_term", 0, C_EXP_TERM, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer0_exp_scale_per_km", 0, C_EXP_SCALE, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer0_linear_per_km", 0, C_LINEAR, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer0_constant", 0, C_CONSTANT, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer1_exp_term", 1, C_EXP_TERM, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer1_exp_scale_per_km", 1, C_EXP_SCALE, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer1_linear_per_km", 1, C_LINEAR, MIE_PROFILE),
	CONSTITUENT_LAYER("mie_layer1_constant", 1, C_CONSTANT, MIE_PROFILE),
	CONSTITUENT("ozone_scattering_per_km", C_SCATTERING, 0),
	CONSTITUENT("ozone_absorption_per_km", C_ABSORPTION, STATE_OVERRIDE_OZONE_ABSORPTION),
	CONSTITUENT("ozone_scale_height_km", C_SCALE_HEIGHT, 0),
	CONSTITUENT("ozone_g", C_G, 0),
	CONSTITUENT("ozone_phase", C_PHASE, 0),
	CONSTITUENT("ozone_layer0_width_km", C_WIDTH, 0),
	CONSTITUENT_LAYER("ozone_layer0_exp_term", 0, C_EXP_TERM, 0),
	CONSTITUENT_LAYER("ozone_layer0_exp_scale_per_km", 0, C_EXP_SCALE, 0),
	CONSTITUENT_LAYER("ozone_layer0_linear_per_km", 0, C_LINEAR, 0),
	CONSTITUENT_LAYER("ozone_layer0_constant", 0, C_CONSTANT, 0),
	CONSTITUENT_LAYER("ozone_layer1_exp_term", 1, C_EXP_TERM, 0),
	CONSTITUENT_LAYER("ozone_layer1_exp_scale_per_km", 1, C_EXP_SCALE, 0),
	CONSTITUENT_LAYER("ozone_layer1_linear_per_km", 1, C_LINEAR, 0),
	CONSTITUENT_LAYER("ozone_layer1_constant", 1, C_CONSTANT, 0),

	/* ---- the weather (docs/weather.md; state_weather.c): an aerosol input
	 * wins the Mie coefficients back from raw keys, ozone_du the ozone's ---- */
	{ .name = "visibility_km", WEATHER(visibility_km, WEATHER_VISIBILITY_MIN_KM,
					   WEATHER_VISIBILITY_MAX_KM),
	  .dirty = FROM_T, .unit = "km", .override = STATE_OVERRIDE_MIE,
	  .id = STATE_KEY_ID_VISIBILITY_KM, .set = state_set_weather,
	  .doc = "meteorological optical range: the aerosol extinction at 550 nm (Koschmieder)" },
	{ .name = "relative_humidity", WEATHER(relative_humidity, 0.0, 1.0), .dirty = FROM_T,
	  .unit = "-", .override = STATE_OVERRIDE_MIE, .id = STATE_KEY_ID_RELATIVE_HUMIDITY,
	  .set = state_set_weather, .doc = "hygroscopic growth of the aerosol: albedo, g, colour" },
	{ .name = "aerosol", WORD(weather.in.aerosol, weather_aerosol_names), .def = WEATHER_AEROSOL_AUTO,
	  .listed = STATE_LISTED_GIVEN, .dirty = FROM_T, .unit = "-", .override = STATE_OVERRIDE_MIE,
	  .id = STATE_KEY_ID_AEROSOL, .set = state_set_weather,
	  .doc = "the aerosol type, an OPAC mixture" },
	{ .name = "angstrom_beta", WEATHER(angstrom_beta, 0.0, WEATHER_ANGSTROM_BETA_MAX),
	  .dirty = FROM_T, .unit = "-", .override = STATE_OVERRIDE_MIE, .set = state_set_weather,
	  .doc = "turbidity: the aerosol optical depth at 1000 nm" },
	{ .name = "ozone_du", WEATHER(ozone_du, 0.0, WEATHER_OZONE_DU_MAX), .dirty = FROM_T,
	  .unit = "DU", .override = STATE_OVERRIDE_OZONE_ABSORPTION, .set = state_set_weather,
	  .doc = "total ozone column; scales the ozone absorption" },
	{ .name = "cloud_oktas", WEATHER(cloud_oktas, 0.0, WEATHER_OKTAS_MAX), .dirty = LIGHTS,
	  .unit = "oktas", .id = STATE_KEY_ID_CLOUD_OKTAS, .set = state_set_cloud,
	  .doc = "cloud cover: the sun's and moon's illuminance factor (Kasten and Czeplak)" },
	{ .name = "cloud_fraction", NUMBER_AUTO(weather.in.cloud_oktas, 0.0, 1.0), .dirty = LIGHTS,
	  .unit = "-", .listed = STATE_LISTED_NEVER, .set = state_set_cloud_fraction,
	  .get = state_get_cloud_fraction, .doc = "cloud cover as a fraction: cloud_oktas / 8" },
	{ .name = "metar", .kind = STATE_KIND_TEXT, .dirty = FROM_T, .unit = "-",
	  .range = "a METAR or SPECI report, quoted", .listed = STATE_LISTED_NEVER,
	  .id = STATE_KEY_ID_METAR, .flags = STATE_KEY_WRITE_ONLY, .set = state_set_metar_key,
	  .doc = "sets visibility_km, relative_humidity, aerosol, cloud_oktas, pressure_mbar, temperature_c, the cloud layers and the wind; write-only" },

	/* ---- the cloud layers and the wind (docs/clouds.md; state_clouds.c) ---- */
	{ .name = "cloud1_oktas", CL_OKTAS(1) },
	{ .name = "cloud1_base_m", CL_BASE(1) },
	{ .name = "cloud1_top_m", CL_TOP(1) },
	{ .name = "cloud1_type", CL_TYPE(1) },
	{ .name = "cloud2_oktas", CL_OKTAS(2) },
	{ .name = "cloud2_base_m", CL_BASE(2) },
	{ .name = "cloud2_top_m", CL_TOP(2) },
	{ .name = "cloud2_type", CL_TYPE(2) },
	{ .name = "cloud3_oktas", CL_OKTAS(3) },
	{ .name = "cloud3_base_m", CL_BASE(3) },
	{ .name = "cloud3_top_m", CL_TOP(3) },
	{ .name = "cloud3_type", CL_TYPE(3) },
	{ .name = "cloud4_oktas", CL_OKTAS(4) },
	{ .name = "cloud4_base_m", CL_BASE(4) },
	{ .name = "cloud4_top_m", CL_TOP(4) },
	{ .name = "cloud4_type", CL_TYPE(4) },
	{ .name = "cloud_seed", INTEGER(clouds.seed, 0, 4294967295.0), CLOUD_BLOCK, .unit = "-",
	  .range = "0 to 4294967295",
	  .doc = "the field's noise: the same seed and keys give the same clouds on every host" },
	{ .name = "wind_dir_deg", NUMBER(clouds.wind_dir_deg, 0, 360), CLOUD_BLOCK, .unit = "deg",
	  .doc = "where the wind that carries the clouds blows from, clockwise from north" },
	{ .name = "wind_speed_mps", NUMBER(clouds.wind_speed_mps, 0, 150), CLOUD_BLOCK, .unit = "m/s",
	  .doc = "the wind's speed: the field moves with the simulated time" },
	{ .name = "cloud_extent_km", NUMBER_AUTO(clouds.extent_km, 1, 512), CLOUD_BLOCK, .unit = "km",
	  .doc = "half-width of the field's square region; auto: sqrt(2 R top), 50 to 400 km" },
	/* Aliases, listed never: they end the block before the sensor's. */
	{ .name = "cloud1_fraction", CL_FRACTION(1) },
	{ .name = "cloud2_fraction", CL_FRACTION(2) },
	{ .name = "cloud3_fraction", CL_FRACTION(3) },
	{ .name = "cloud4_fraction", CL_FRACTION(4) },

	/* ---- the light sensor (docs/sensor.md; state_sensor.c) ---- */
	{ .name = "sensor_mode", WORD(sensor.mode, state_sensor_mode_names), .def = STATE_SENSOR_OFF,
	  .listed = STATE_LISTED_BLOCK, .unit = "-",
	  .doc = "what a USB light sensor's readings do: the cloud factor, the sun's elevation, a suggested EV100 (docs/sensor.md)" },
	{ .name = "sensor_select", .kind = STATE_KIND_TEXT, .offset = OFF(sensor.select),
	  .def_text = "auto", .listed = STATE_LISTED_BLOCK, .unit = "-",
	  .range = "auto, none, bus:PORTS, serial:TEXT, name:TEXT", .set = state_set_sensor_select,
	  .doc = "which sensor: the first that works, none, or by port path, serial number or name" },
	{ .name = "sensor_time_constant_s", SENSOR(time_constant_s, 0, 86400, 5.0), .unit = "s",
	  .doc = "smoothing of the readings (exponential, in ln lux); 0 passes them through" },
	{ .name = "sensor_hysteresis", SENSOR(hysteresis, 0, 10, 0.05), .unit = "-",
	  .doc = "relative change of the smoothed reading that makes a new output (0.05: 5 %)" },
	{ .name = "sensor_min_interval_s", SENSOR(min_interval_s, 0, 86400, 1.0), .unit = "s",
	  .doc = "rate limit: outputs at least this far apart" },
	{ .name = "sensor_stale_after_s", SENSOR(stale_after_s, 0.001, 86400, 30.0), .unit = "s",
	  .doc = "no accepted reading for this long: the last value is kept and marked stale" },
	{ .name = "sensor_max_lux", SENSOR(max_lux, 1, 1e7, 200000.0), .unit = "lx",
	  .doc = "readings above are refused (no daylight is that bright)" },
	{ .name = "sensor_floor_lux", SENSOR(floor_lux, 1e-9, 1e3, 0.01), .unit = "lx",
	  .doc = "added before the logarithm of smoothing and hysteresis: differences far below count less" },
	{ .name = "sensor_report_interval_s", SENSOR(report_interval_s, 0.01, 3600, 0.5), .unit = "s",
	  .doc = "asked of the device: its HID report interval, the BH1750's poll period" },
	{ .name = "sensor_io_timeout_s", SENSOR(io_timeout_s, 0.01, 60, 1.0), .unit = "s",
	  .doc = "a transfer taking longer is cancelled; three in a row stop the device" },
	{ .name = "sensor_rescan_s", SENSOR(rescan_s, 0.01, 3600, 5.0), .unit = "s",
	  .doc = "looking for a device while none reads; a failed one is retried after up to 16 times this" },
};
#define N_KEYS (sizeof(keys) / sizeof(keys[0]))

/* ---- lookup ---- */

const struct state_key *state_key_find(const char *name)
{
	for (size_t i = 0; i < N_KEYS; i++)
		if (strcmp(keys[i].name, name) == 0)
			return &keys[i];
	return NULL;
}

const struct state_key *state_key_of(enum state_key_id id)
{
	for (size_t i = 0; i < N_KEYS; i++)
		if (keys[i].id == id)
			return &keys[i];
	abort();	/* an id no row carries: a broken table */
}

const char *state_key_name(enum state_key_id id)
{
	return state_key_of(id)->name;
}

int state_enum_index(const char *const *names, const char *v)
{
	for (int i = 0; names[i]; i++)
		if (strcmp(names[i], v) == 0)
			return i;
	return -1;
}

/* ---- the kinds ---- */

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

/* The words of a list joined by sep, the last two by last: "a, b or c". */
static void join_words(const char *const *words, const char *sep, const char *last, char *buf,
		       size_t n)
{
	size_t o = 0;

	buf[0] = 0;
	for (int i = 0; words[i]; i++)
		o += (size_t)snprintf(buf + o, o < n ? n - o : 0, "%s%s",
				      i == 0 ? "" : words[i + 1] ? sep : last, words[i]);
}

static int parse_whole(const struct state_key *k, const char *v, uint32_t *ret, char *err,
		       size_t err_size)
{
	char *end;

	if (!*v || *v == '-' || *v == '+')
		return ERR("%s: '%s' is not a whole number", k->name, v);
	errno = 0;
	unsigned long long u = strtoull(v, &end, 10);
	if (*end || errno)
		return ERR("%s: '%s' is not a whole number", k->name, v);
	if (u < k->min || u > k->max)
		return ERR_RANGE("%s: %llu is outside [%g, %g]", k->name, u, k->min, k->max);
	*ret = (uint32_t)u;
	return 0;
}

/* A number of k's range; with auto_ok, "auto" gives NAN. */
static int parse_number(const struct state_key *k, const char *v, bool auto_ok, double *ret,
			char *err, size_t err_size)
{
	double d;

	if (auto_ok && strcmp(v, "auto") == 0) {
		*ret = NAN;
		return 0;
	}
	if (proto_parse_number(v, &d) < 0)
		return ERR("%s: '%s' is not %sa finite number", k->name, v, auto_ok ? "auto or " : "");
	if (d < k->min || d > k->max)
		return ERR_RANGE("%s: %g is outside [%g, %g]", k->name, d, k->min, k->max);
	*ret = d;
	return 0;
}

int state_key_parse(const struct state_key *k, const char *v, void *field, char *err,
		    size_t err_size)
{
	double t[3];
	char list[256];
	int i;

	switch (k->kind) {
	case STATE_KIND_NUMBER:
	case STATE_KIND_NUMBER_AUTO:
		return parse_number(k, v, k->kind == STATE_KIND_NUMBER_AUTO, field, err, err_size);
	case STATE_KIND_TRIPLE:
		if (parse_triple(v, t) < 0)
			return ERR("%s: '%s' is not one or three finite numbers", k->name, v);
		for (i = 0; i < 3; i++)
			if (t[i] < k->min || t[i] > k->max)
				return ERR_RANGE("%s: %g is outside [%g, %g]", k->name, t[i], k->min, k->max);
		memcpy(field, t, sizeof(t));
		return 0;
	case STATE_KIND_INTEGER:
		return parse_whole(k, v, field, err, err_size);
	case STATE_KIND_WORD:
		if ((i = state_enum_index(k->words, v)) < 0) {
			join_words(k->words, ", ", " or ", list, sizeof(list));
			return ERR("%s: '%s' is not %s", k->name, v, list);
		}
		*(int *)field = i;
		return 0;
	case STATE_KIND_TEXT:
	case STATE_KIND_TIME:
		break;
	}
	return ERR("%s: internal error: no parser", k->name);
}

/* Set while state_foreach_exact or state_get_exact runs: numbers are then
 * written so that they read back to the same double. */
static _Thread_local int format_exact;

static int reads_back(const char *text, double v)
{
	double r = strtod(text, NULL);
	return memcmp(&r, &v, sizeof(v)) == 0;
}

void state_format_number(double v, char *buf, size_t n)
{
	snprintf(buf, n, "%.9g", v);
	for (int digits = 10; format_exact && digits <= 17 && !reads_back(buf, v); digits++)
		snprintf(buf, n, "%.*g", digits, v);
}

void state_key_format(const struct state_key *k, const void *field, char *buf, size_t n)
{
	const double *d = field;
	char c[3][32];
	int i = 0, w = 0;

	switch (k->kind) {
	case STATE_KIND_NUMBER_AUTO:
		if (isnan(*d))
			snprintf(buf, n, "auto");
		else
			state_format_number(*d, buf, n);
		break;
	case STATE_KIND_NUMBER:
	case STATE_KIND_TIME:
		state_format_number(*d, buf, n);
		break;
	case STATE_KIND_TRIPLE:
		for (int j = 0; j < 3; j++)
			state_format_number(d[j], c[j], sizeof(c[j]));
		snprintf(buf, n, "%s,%s,%s", c[0], c[1], c[2]);
		break;
	case STATE_KIND_INTEGER:
		snprintf(buf, n, "%u", *(const uint32_t *)field);
		break;
	case STATE_KIND_WORD:
		i = *(const int *)field;
		while (k->words[w])
			w++;
		snprintf(buf, n, "%s", i >= 0 && i < w ? k->words[i] : "?");
		break;
	case STATE_KIND_TEXT:
		snprintf(buf, n, "%s", (const char *)field);
		break;
	}
}

static int set_multiscatter_dirs(struct sky_state *s, const struct state_key *k, const char *v,
				 uint32_t *ret_dirty, char *err, size_t err_size)
{
	uint32_t u;
	int r = state_key_parse(k, v, &u, err, err_size);

	if (r < 0)
		return r;
	if (u != 0 && u != 2 && u != 64)
		return ERR_RANGE("%s: must be 0 (off), 2 or 64", k->name);
	s->quality.multiscatter_dirs = u;
	return 0;
}

/* ---- set and get ---- */

static int key_set(struct sky_state *s, const struct state_key *k, const char *v,
		   uint32_t *ret_dirty, char *err, size_t err_size)
{
	if (k->set)
		return k->set(s, k, v, ret_dirty, err, err_size);
	return state_key_parse(k, v, (char *)s + k->offset, err, err_size);
}

static int key_get(const struct sky_state *s, const struct state_key *k, char *buf, size_t n)
{
	if (k->flags & STATE_KEY_WRITE_ONLY)
		return -ENOENT;
	if (k->get)
		return k->get(s, k, buf, n);
	state_key_format(k, (const char *)s + k->offset, buf, n);
	return 0;
}

int state_set(struct sky_state *s, const char *key, const char *value, uint32_t *ret_dirty,
	      char *err, size_t err_size)
{
	const struct state_key *k = state_key_find(key);

	if (!k)
		return ERR_UNKNOWN("%s: unknown key", key);
	struct sky_state before = *s;
	uint32_t dirty = k->dirty;
	int r = key_set(s, k, value, &dirty, err, err_size);
	if (r < 0)
		return r;
	state_clock_hand_lights(s, k->hands);
	if (ret_dirty && memcmp(&before, s, sizeof(before)) != 0)
		*ret_dirty |= dirty;
	return 0;
}

int state_get(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	const struct state_key *k = state_key_find(key);

	return k ? key_get(s, k, buf, size) : -ENOENT;
}

void state_keys_default(struct sky_state *s)
{
	char err[256];

	for (size_t i = 0; i < N_KEYS; i++) {
		const struct state_key *k = &keys[i];
		char *field = (char *)s + k->offset;
		uint32_t dirty = 0;
		if (k->flags & (STATE_KEY_PRESET_DEFAULT | STATE_KEY_WRITE_ONLY))
			continue;
		if (k->def_text) {
			if (key_set(s, k, k->def_text, &dirty, err, sizeof(err)) < 0)
				abort();	/* a default its own key refuses */
			continue;
		}
		switch (k->kind) {
		case STATE_KIND_NUMBER:
		case STATE_KIND_NUMBER_AUTO:
		case STATE_KIND_TIME:
			*(double *)field = k->def;
			break;
		case STATE_KIND_TRIPLE:
			for (int c = 0; c < 3; c++)
				((double *)field)[c] = k->def;
			break;
		case STATE_KIND_INTEGER:
			*(uint32_t *)field = (uint32_t)k->def;
			break;
		case STATE_KIND_WORD:
			*(int *)field = (int)k->def;
			break;
		case STATE_KIND_TEXT:
			break;
		}
	}
}

/* Whether the run of STATE_LISTED_BLOCK rows from keys[i] has a key away
 * from its default; *ret_end gets the index past the run. */
static bool block_differs(const struct sky_state *s, size_t i, size_t *ret_end)
{
	struct sky_state d;
	char a[STATE_VALUE_MAX], b[STATE_VALUE_MAX];
	bool differs = false;

	state_default(&d);
	for (; i < N_KEYS && keys[i].listed == STATE_LISTED_BLOCK; i++)
		if (key_get(s, &keys[i], a, sizeof(a)) == 0 &&
		    key_get(&d, &keys[i], b, sizeof(b)) == 0 && strcmp(a, b) != 0)
			differs = true;
	*ret_end = i;
	return differs;
}

void state_foreach(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char buf[STATE_VALUE_MAX];
	size_t block_end = 0;
	bool block = false;

	for (size_t i = 0; i < N_KEYS; i++) {
		const struct state_key *k = &keys[i];
		if (k->listed == STATE_LISTED_NEVER || key_get(s, k, buf, sizeof(buf)) < 0)
			continue;
		if (k->listed == STATE_LISTED_GIVEN && strcmp(buf, "auto") == 0)
			continue;
		if (k->listed == STATE_LISTED_BLOCK && i >= block_end)
			block = block_differs(s, i, &block_end);
		if (k->listed == STATE_LISTED_BLOCK && !block)
			continue;
		fn(ctx, k->name, buf);
	}
}

void state_foreach_exact(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	int was = format_exact;

	format_exact = 1;
	state_foreach(s, fn, ctx);
	format_exact = was;
}

int state_get_exact(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	int was = format_exact;

	format_exact = 1;
	int r = state_get(s, key, buf, size);
	format_exact = was;
	return r;
}

void state_foreach_given(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	char buf[STATE_VALUE_MAX];

	for (size_t i = 0; i < N_KEYS; i++)
		if (keys[i].listed == STATE_LISTED_GIVEN && key_get(s, &keys[i], buf, sizeof(buf)) == 0)
			fn(ctx, keys[i].name, buf);
}

const struct state_key *state_key_pinning(uint32_t bit)
{
	for (size_t i = 0; i < N_KEYS; i++)
		if ((keys[i].override & bit) && keys[i].set == state_set_constituent)
			return &keys[i];
	return NULL;
}

/* ---- the key list (skyd --list-keys) ---- */

static void key_range(const struct state_key *k, char *buf, size_t n)
{
	if (k->range)
		snprintf(buf, n, "%s", k->range);
	else if (k->kind == STATE_KIND_WORD)
		join_words(k->words, ", ", ", ", buf, n);
	else if (k->kind == STATE_KIND_NUMBER_AUTO)
		snprintf(buf, n, "auto or [%g, %g]", k->min, k->max);
	else if (k->min == -BIG)
		snprintf(buf, n, "<= %g", k->max);
	else
		snprintf(buf, n, "[%g, %g]", k->min, k->max);
}

/* Markdown escapes nothing: no field of a row may hold a '|'. */
void state_print_keys(FILE *f, bool markdown)
{
	struct sky_state s;
	char def[STATE_VALUE_MAX], range[160], tables[96];

	state_default(&s);
	if (markdown)
		fprintf(f, "| key | unit | range | default | invalidates | what it is |\n"
			   "| --- | --- | --- | --- | --- | --- |\n");
	for (size_t i = 0; i < N_KEYS; i++) {
		const struct state_key *k = &keys[i];
		if (key_get(&s, k, def, sizeof(def)) < 0)
			snprintf(def, sizeof(def), "-");
		key_range(k, range, sizeof(range));
		if ((k->dirty & STATE_ALL_TABLES) == STATE_ALL_TABLES)
			snprintf(tables, sizeof(tables), "all");
		else
			state_format_all_tables(k->dirty, tables, sizeof(tables));
		if (markdown)
			fprintf(f, "| `%s` | %s | %s | `%s` | %s | %s |\n", k->name, k->unit, range, def,
				tables, k->doc);
		else
			fprintf(f, "%s\t%s\t%s\t%s\t%s\t%s\n", k->name, k->unit, range, def, tables,
				k->doc);
	}
}

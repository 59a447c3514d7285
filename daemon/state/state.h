/* state.h - the state of one sky and its key=value vocabulary.
 *
 * The same keys serve the command line (skyd --once key=value), the config
 * file and the control protocol. A change is parsed whole into a copy, then
 * validated, then applied: it applies entirely or not at all.
 */
#ifndef SKYD_STATE_H
#define SKYD_STATE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "atmo.h"
#include "state_geom.h"
#include "state_keys.h"
#include "weather.h"

/* The four tables, in dependency order. */
enum state_table {
	STATE_TRANSMITTANCE = 0,
	STATE_MULTISCATTER = 1,
	STATE_SKYVIEW = 2,
	STATE_AERIAL = 3,
	STATE_N_TABLES = 4,
};
#define STATE_BIT(t) (1u << (t))
#define STATE_ALL_TABLES 0xfu

/* The cloud field's tables (docs/clouds.md): the coverage table and the
 * shadow maps. Their dirty bits follow the four's in a mask, but they are
 * not tables of enum state_table: STATE_N_TABLES, the published layout,
 * demand and the protocol's table names know the four only, so that a
 * mask with these bits changes none of them. A key's row declares them
 * (the key list names them); srv keeps them in its dirty mask and
 * computes nothing for them until the cloud passes exist. */
enum state_cloud_table {
	STATE_CLOUD_COVERAGE = STATE_N_TABLES,
	STATE_CLOUD_SHADOW = STATE_N_TABLES + 1,
	STATE_N_ALL_TABLES = STATE_N_TABLES + 2,
};
#define STATE_CLOUD_TABLES (STATE_BIT(STATE_CLOUD_COVERAGE) | STATE_BIT(STATE_CLOUD_SHADOW))

enum state_storage { STATE_F32 = 0, STATE_F16 = 1 };
enum state_spacing { STATE_LINEAR = 0, STATE_SQUARED = 1 };
/* The multiply scattered light's first moment (model_moment_wanted). */
enum state_moment { STATE_MOMENT_AUTO = 0, STATE_MOMENT_OFF = 1, STATE_MOMENT_ON = 2 };

struct state_light {
	double elevation_deg;		/* geometric, above the astronomical horizon */
	double azimuth_deg;		/* eastward from north */
	double illuminance_lx;		/* at the top of the atmosphere, normal incidence */
	double color[3];		/* linear RGB, scaled so luminance is 1 */
	double angular_radius_deg;
};

struct state_camera {
	double yaw_deg;			/* azimuth of the view axis, eastward from north */
	double pitch_deg;		/* elevation of the view axis */
	double roll_deg;
	double vfov_deg;
	double aspect;			/* width / height */
};

/* Views: cameras that each get their own aerial-perspective volume (proto
 * SKY_SHM_MAX_VIEWS of them at most), added and removed with the view verb. */
#define STATE_MAX_VIEWS 8
#define STATE_VIEW_NAME_MAX 32

struct state_view {
	char name[STATE_VIEW_NAME_MAX];
	double altitude_km;		/* NAN: the observer's altitude_km */
	/* The eye's horizontal position from the observer's site, along the
	 * ground: east_km and north_km of the azimuthal equidistant projection
	 * about the site (hypot is the great-circle distance, atan2(east,
	 * north) its bearing). The camera's angles are in the local frame
	 * there: its vertical, and true north for a site at clock.lat_deg. */
	double east_km, north_km;
	/* How its aerial perspective is published (enum sky_view_form): its
	 * own volume, or the panorama of its eye point, which every view of
	 * that form there shares. */
	uint32_t form;
	struct state_camera camera;
	uint64_t owner;			/* the connection that added it */
};

/* Size and quadrature of one table. depth is 1 except for aerial perspective. */
struct state_table_quality {
	uint32_t width, height, depth;
	uint32_t steps;
};

struct state_quality {
	struct state_table_quality t[STATE_N_TABLES];
	uint32_t multiscatter_dirs;	/* 2 (up and down) or 64; 0 switches multi-scattering off */
	uint32_t skyview_min_steps;
	double aerial_range_km;
	enum state_spacing aerial_spacing;
	enum state_storage storage;
	/* Steps of the neighbourhood iteration of psi_ms (shaders/msiterate.comp):
	 * 0 auto (state_multiscatter_iterations decides from the optical
	 * depth), else one more than the number of steps (1: none). */
	int multiscatter_iterations;
	enum state_moment multiscatter_moment;
	/* Delta-M scaling of the forward peak for the higher orders
	 * (phase_delta_constituent); auto, off, on as multiscatter_moment. */
	enum state_moment multiscatter_delta;
	uint32_t cloud_width;		/* texels of the cloud coverage table, square */
	uint32_t shadow_width;		/* texels of a cloud shadow map, square */
	/* How far the wind carries the field, in shadow texels, before its
	 * tables are remade (state_cloud_table_offset_km); 0: at every move. */
	double cloud_cell_texels;
};

/* Who drives a light: the key=value of its angles (manual) or the clock. */
enum state_light_mode { STATE_MANUAL = 0, STATE_CLOCK = 1 };

/* The simulation clock and the observer's site: where the sun and moon
 * come from when their mode is STATE_CLOCK (daemon/srv/drive.c computes them).
 * The simulated time at monotonic time m is
 * anchor_utc_s + rate * (m - anchor_mono_s). */
struct state_clock {
	double anchor_utc_s;		/* POSIX seconds; NAN: no time set yet */
	double anchor_mono_s;		/* CLOCK_MONOTONIC seconds of the anchor */
	double rate;			/* time_rate: simulated seconds per real second */
	double lat_deg, lon_deg;	/* geodetic, north and east positive */
	double site_elevation_m;	/* above sea level, for SPA's parallax */
	double pressure_mbar, temperature_c;	/* refraction of the reported direction */
	double delta_t_s;		/* TT - UT1; NAN: astro_delta_t_s() at the date */
	double horizon_refraction_deg;	/* SPA's atmos_refract */
	double threshold_deg;		/* recompute when a light moved this much */
	double cadence_s;		/* or this much real time passed; 0: never */
	enum state_light_mode sun_mode, moon_mode;
};

/* Night-sky floor (airglow, starlight, zodiacal light) added to the
 * sky-view and aerial tables; see docs/physics.md "The night-sky floor". */
struct state_night {
	double zenith_luminance_cd_m2;	/* 0 switches the floor off */
	double illuminance_lx;		/* horizontal, from the whole floor */
};

/* Weather (docs/weather.md): inputs in the words people use, kept apart
 * from the atmosphere. `atmo` stays what the preset and the raw keys made
 * it; state_resolve applies the weather to a copy, the state the tables
 * are computed with. */

/* What the weather maps that a raw key set after a weather key keeps: the
 * raw key wins for its coefficient until a weather key that maps it is set
 * again (last writer wins). preset= clears every bit. */
enum state_override {
	STATE_OVERRIDE_MIE_SCATTERING = 1u << 0,	/* mie_scattering_per_km */
	STATE_OVERRIDE_MIE_ABSORPTION = 1u << 1,	/* mie_absorption_per_km */
	STATE_OVERRIDE_MIE_G = 1u << 2,			/* mie_g */
	STATE_OVERRIDE_MIE_PROFILE = 1u << 3,		/* mie_scale_height_km, mie_layer* */
	STATE_OVERRIDE_OZONE_ABSORPTION = 1u << 4,	/* ozone_absorption_per_km */
};
#define STATE_OVERRIDE_MIE 0xfu
/* The name an override bit goes by in `get weather`'s overridden: line and
 * the sync message: its key's, or mie_profile for the Mie profile's keys. */
const char *state_override_name(uint32_t bit);

struct state_weather {
	struct weather in;		/* the weather keys; all auto by default */
	uint32_t overridden;		/* enum state_override bits */
	/* The sun's and the moon's illuminance factor, 1 under a clear sky:
	 * from cloud_oktas (Kasten and Czeplak), or from a light sensor's
	 * cloud mode through state_set_cloud_factor, the one path for both. */
	double cloud_factor;
};

/* ---- the light sensor (docs/sensor.md) ----
 * A USB light sensor's keys: what its readings do to the sky
 * (daemon/srv/sense.c) and how they are taken (daemon/sensor's
 * sensor_config, the same fields and ranges). Setting them computes no
 * table; the readings change the state, each as a change of its own (the
 * cloud mode through state_set_cloud_factor). */
enum state_sensor_mode {
	STATE_SENSOR_OFF = 0,		/* no sensor opened; the default */
	STATE_SENSOR_CLOUD = 1,		/* reading over clear-sky illuminance: the cloud factor */
	STATE_SENSOR_ELEVATION = 2,	/* the reading places the sun (its elevation) */
	STATE_SENSOR_EXPOSURE = 3,	/* a suggested EV100; the tables stay */
};
#define STATE_SENSOR_SELECT_MAX 128

struct state_sensor {
	enum state_sensor_mode mode;			/* sensor_mode */
	char select[STATE_SENSOR_SELECT_MAX];		/* sensor_select: auto, none, bus:, serial:, name: */
	double time_constant_s, hysteresis, min_interval_s;	/* the reading pipeline */
	double stale_after_s, max_lux, floor_lux;
	double report_interval_s, io_timeout_s, rescan_s;	/* the device */
};

/* ---- cloud layers (docs/clouds.md; state_clouds.c) ----
 * Up to four layers over a region around the observer, the field of
 * proto/skycloud.h, moved by the wind with the simulated time. A layer
 * with a cover above 0 and a base is drawn; while one is, the weather's
 * cloud factor (cloud_oktas, the light sensor) no longer dims the lights:
 * the layers do (state_resolve). */
#define STATE_CLOUD_LAYERS 4

struct state_cloud_layer {
	double oktas;			/* cloudN_oktas 0..8 (cloudN_fraction x 8); NAN: not given */
	double base_m;			/* above the ground under the observer; NAN: not given */
	double top_m;			/* NAN: the base plus the type's typical thickness */
	int type;			/* enum skycloud_type */
};

struct state_clouds {
	struct state_cloud_layer layer[STATE_CLOUD_LAYERS];
	uint32_t seed;			/* cloud_seed */
	double wind_dir_deg;		/* where the wind blows from, clockwise from north */
	double wind_speed_mps;
	double extent_km;		/* half-width of the field's region; NAN: auto */
	/* Not keys. utc_s: the simulated time the field is placed for, whole
	 * seconds (daemon/srv/drive.c); NAN while it stands still (no layer
	 * drawn, no wind or no time). offset_km: where the wind has carried
	 * it then, east and north in [0, SKYCLOUD_PERIOD_KM); state_resolve
	 * writes it, 0 in the state as set. */
	double utc_s;
	double offset_km[2];
};

/* ---- terrain (docs/terrain.md; state_terrain.c) ----
 * An optional height field over a square centred on the observer's site,
 * read from the file `terrain` names (daemon/terrain/terrain.h): a second
 * caster of shadows beside the cloud layers. The state holds the path and
 * what the file held when it was read (its texels stay in the terrain
 * module's cache, found again by path and hash). */
#define STATE_TERRAIN_PATH_MAX 128

struct state_terrain {
	char path[STATE_TERRAIN_PATH_MAX];	/* absolute; "" none */
	double extent_km;		/* terrain_extent_km: the square's side */
	double height_m;		/* terrain_height_m: what white (65535) stands for */
	/* Not keys' fields: what the file held when the path was set. hash
	 * is terrain_hash (terrain.h); 0 and 0 x 0 without a field. */
	uint64_t hash;
	uint32_t width, height;		/* texels */
};

struct sky_state {
	char preset[ATMO_NAME_MAX];
	struct atmo atmo;		/* the user's: preset and raw keys, no weather */
	double altitude_km;		/* observer above the ground, kept apart from radius */
	struct state_light sun;
	struct state_light moon;	/* lit when moon_illuminance_lx > 0 */
	struct state_camera camera;
	struct state_quality quality;
	struct state_clock clock;
	double lights_utc_s;		/* the simulated time the clock-driven lights
					 * were computed for; NAN when none is */
	struct state_night night;
	uint32_t n_views;		/* views[0 .. n_views) in use, in the order added */
	struct state_view views[STATE_MAX_VIEWS];
	struct state_weather weather;
	struct state_clouds clouds;
	struct state_terrain terrain;
	struct state_sensor sensor;
	double exposure_ev100;		/* the sensor's suggested EV100 (exposure
					 * mode); NAN when none. Not a key: set by
					 * the sensor, published, not replicated */
};

/* The default camera (and a new view's): south, level, 60 degrees, 16:9. */
void state_default_camera(struct state_camera *ret);

/* Default: Earth, sun at 30 degrees, observer at 0.2 km, reference sizes. */
void state_default(struct sky_state *ret);

/* Parses one key=value into s: the key's row in the registry
 * (state_keys.h) and its setter. On failure returns -ENOENT (unknown key),
 * -EINVAL (a malformed value: not a number, not one of the names) or
 * -ERANGE (a value outside the key's range or rule) and writes a message
 * naming the key and the rule to err; the control protocol answers each
 * with its own ACK code. s may be partly changed, so callers work on a
 * copy. Numbers are parsed in the C locale. ret_dirty, if not NULL, gets
 * the tables this key invalidates ORed in. */
int state_set(struct sky_state *s, const char *key, const char *value,
	      uint32_t *ret_dirty, char *err, size_t err_size);

/* Splits "key=value" and calls state_set; -EINVAL without a '='. */
int state_set_pair(struct sky_state *s, const char *pair, uint32_t *ret_dirty,
		   char *err, size_t err_size);

/* Cross-key rules (top above bottom, sizes within limits): 0, or -ERANGE
 * (-EINVAL from atmo_validate) with err naming the key. max_buffer_bytes
 * is the device's largest buffer: 0 means no device limit known. */
int state_validate(const struct sky_state *s, uint64_t max_buffer_bytes,
		   char *err, size_t err_size);

/* Calls fn for every key with its current value formatted, in the
 * registry's order and as its rows say (enum state_key_listed). */
typedef void (*state_emit_fn)(void *ctx, const char *key, const char *value);
void state_foreach(const struct sky_state *s, state_emit_fn fn, void *ctx);

/* Formats one key's value; -ENOENT if unknown (or write-only). */
int state_get(const struct sky_state *s, const char *key, char *buf, size_t size);

/* As state_foreach and state_get, with every number written so that it
 * reads back to the same double: as get writes it (nine significant
 * digits) where that does, with up to seventeen where it does not (a
 * light's direction the clock computed, a humidity a METAR gave). What a
 * replica must read back bit for bit (the sync message) and what tells
 * two states apart (state_diff) use these. */
void state_foreach_exact(const struct sky_state *s, state_emit_fn fn, void *ctx);
int state_get_exact(const struct sky_state *s, const char *key, char *buf, size_t size);

/* The simulated time at monotonic time mono_s (seconds); NAN if no time was
 * ever set. */
double state_clock_utc_s(const struct sky_state *s, double mono_s);

/* A new time_rate in next against the running clock of cur, with the same
 * anchor: re-anchors next at mono_s so the simulated time goes on without
 * a jump. A new utc in next wins: the rate then runs from its anchor. */
void state_clock_rebase(struct sky_state *next, const struct sky_state *cur, double mono_s);

/* The night floor as the shaders take it: zenith luminance (cd/m2, white)
 * and the horizon gain c of L(mu) = L_zenith (1 + c (1 - mu)), chosen so
 * that the horizontal illuminance pi L_zenith (1 + c / 3) is the state's. */
void state_night_floor(const struct sky_state *s, double *ret_zenith_cd_m2, double *ret_gain);


/* The name of a sensor mode ("off", "cloud", "elevation", "exposure"). */
const char *state_sensor_mode_name(enum state_sensor_mode m);

/* The tables to recompute going from a to b: the masks state_set gives
 * for each key whose exact text differs (state_get_exact: a difference in
 * the last bit counts), every table for one it cannot set, and those of
 * the weather's overrides and cloud factor where they differ. */
uint32_t state_diff(const struct sky_state *a, const struct sky_state *b);

/* Bytes of one texel in the given storage (4 channels). */
size_t state_texel_bytes(enum state_storage st);
size_t state_table_bytes(const struct sky_state *s, enum state_table t);

/* The steps of the neighbourhood iteration of psi_ms that the tables of s
 * get: the key multiscatter_iterations, or with "auto" 2 where the
 * atmosphere's vertical optical depth from the ground (largest channel)
 * is at least STATE_THICK_OPTICAL_DEPTH and 0 below or with 2 directions;
 * always 0 with multi-scattering off. Hillaire's psi = L2 / (1 - f_ms) is within a few
 * percent below that depth and 14-29 % low at ten times Earth's (see
 * shaders/msiterate.comp). */
#define STATE_THICK_OPTICAL_DEPTH 1.0
uint32_t state_multiscatter_iterations(const struct sky_state *s);

extern const char *const state_table_names[STATE_N_TABLES];
/* Table mask from a comma list ("skyview,aerial", "all": the four;
 * "cloud" and "shadow" name the cloud tables); -EINVAL if unknown. */
int state_parse_tables(const char *list, uint32_t *ret_mask);
/* The inverse: "transmittance,skyview", or "none" for 0; the tables of
 * enum state_table only. */
void state_format_tables(uint32_t mask, char *buf, size_t size);
/* The same with the cloud tables' bits named too ("cloud", "shadow"): the
 * key list's invalidates column. */
void state_format_all_tables(uint32_t mask, char *buf, size_t size);
/* The tables t depends on, t included. */
uint32_t state_closure(uint32_t mask);

/* ---- weather (state_weather.c) ---- */

/* The state the tables are computed with: s with its weather mapped onto a
 * copy of its atmosphere (weather_map, weather_apply; coefficients of raw
 * keys set after the weather kept, enum state_override), the sun's and
 * moon's illuminance times the cloud factor applied (cloud_factor, or 1
 * while a cloud layer is drawn: no double counting) and the cloud field's
 * offset at clouds.utc_s (clouds.offset_km). ret's weather is cleared, so
 * that resolving it again changes nothing; ret may be s. Without weather
 * and drawn layers ret is s byte for byte. ret_map (NULL: not wanted) gets the map. Returns 0, or
 * -EINVAL / -ERANGE with err naming the key when the weather does not fit
 * the atmosphere (ozone_du without an ozone constituent). */
int state_resolve(const struct sky_state *s, struct sky_state *ret, struct weather_map *ret_map,
		  char *err, size_t err_size);

/* `get weather`: the weather keys and what they map to (weather_map),
 * then `overridden:` (the raw keys that win, or none), `cloud_factor:`
 * and `cloud_factor_applied:` (1 while a cloud layer is drawn).
 * 0, or the error of weather_map with err. */
int state_describe_weather(const struct sky_state *s, state_emit_fn fn, void *ctx, char *err,
			   size_t err_size);

struct metar;
/* Applies one METAR or SPECI report: metar_weather's visibility_km,
 * relative_humidity, aerosol and cloud_oktas, the QNH reduced to
 * site_elevation_m as pressure_mbar and the temperature as temperature_c
 * (the refraction keys), the cloud layers (every one replaced: metar_layers)
 * and the wind (kept where the report has none). ret_metar (NULL: not wanted) gets the decoded
 * report. -EINVAL with err naming the group and its position for a
 * malformed report; s is unchanged then. */
int state_set_metar(struct sky_state *s, const char *report, struct metar *ret_metar,
		    uint32_t *ret_dirty, char *err, size_t err_size);

/* Sets cloud_factor (0..1, -ERANGE outside) as a light sensor measures it
 * (illuminance over the clear-sky one), and cloud_oktas to the cover that
 * Kasten and Czeplak's law gives that factor (8 below 0.25), so that get
 * weather tells the same. ret_dirty as state_set's (no table while a
 * cloud layer is drawn: the factor then applies to nothing). */
int state_set_cloud_factor(struct sky_state *s, double factor, uint32_t *ret_dirty);

/* ---- cloud layers (state_clouds.c) ---- */

/* The number of drawn layers: cover above 0 and a base. */
int state_clouds_drawn(const struct sky_state *s);
/* The factor the sun's and moon's illuminance get in the tables: the
 * weather's cloud_factor while no layer is drawn, else 1. */
double state_cloud_factor_applied(const struct sky_state *s);
/* The top of layer i (0..3) in m: cloudN_top_m, or auto's base plus the
 * type's thickness, held under the key's range and the atmosphere's top;
 * NAN without a base. */
double state_cloud_top_m(const struct sky_state *s, int i);
/* The half-width of the field's region: cloud_extent_km, or auto's
 * sqrt(2 R top) for the highest drawn top, in [50, 400] km (50 without
 * a layer): how far a layer's top stays above a ground observer's
 * horizon. */
double state_cloud_extent_km(const struct sky_state *s);
/* The drawn layers as proto/skycloud.h takes them, in order, each with
 * its own index (a layer keeps its pattern when another changes); returns
 * how many (0..4). */
struct skycloud_layer;
int state_cloud_layers(const struct sky_state *s, struct skycloud_layer *ret);
/* The same layers in double (the path tracer's skycloudd_*). */
struct skycloudd_layer;
int state_cloud_layers_double(const struct sky_state *s, struct skycloudd_layer *ret);
/* The wind's offset of the field placed at clouds.utc_s (0, 0 when it is
 * NAN), east and north km. */
void state_cloud_offset_km(const struct sky_state *s, double ret_km[2]);
/* Where the field's tables (the coverage table, the shadow maps) place
 * it: the effective state's clouds.offset_km on a lattice of
 * quality.cloud_cell_texels shadow texels, so that the tables stay while
 * the wind carries the field within a cell and their readers shift by the
 * rest (ret_shift_km = offset - table offset; docs/clouds.md, "The wind
 * between the tables"). With a height field the maps hold the terrain,
 * which stays: the lattice is off, the shift 0; likewise with a cell of 0. */
void state_cloud_table_offset_km(const struct sky_state *s, double ret_km[2], double ret_shift_km[2]);
/* `get clouds`: each layer (cover, base, top, type, drawn), the wind,
 * the seed, the region and the field's offset. */
void state_describe_clouds(const struct sky_state *s, state_emit_fn fn, void *ctx);

/* ---- terrain (state_terrain.c) ---- */

/* Whether s has a height field (a path set). */
bool state_terrain_set(const struct sky_state *s);
struct terrain;
struct skyterrain;
/* The height field of s from the terrain module (terrain_load: the cache
 * unless the file changed) with the view proto/skyterrain.h takes of it:
 * 0 with *ret_terrain (a reference, terrain_unref when done) and *ret_view
 * (valid while it is held); -ENOENT without a field; -EINVAL (-EFBIG)
 * with err when the file cannot be read again or no longer holds what
 * the state was set from (its hash differs). */
int state_terrain_get(const struct sky_state *s, struct terrain **ret_terrain,
		      struct skyterrain *ret_view, char *err, size_t err_size);

/* ---- the key list (state_keys.c) ---- */

/* Prints every settable key: name, unit, range, default, the tables it
 * invalidates and what it is, as a markdown table or as tab-separated
 * lines. proto/PROTOCOL.md's key list is this output (tools/gen_keys_doc.sh). */
void state_print_keys(FILE *f, bool markdown);

#endif

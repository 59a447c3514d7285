/* state_internal.h - what the files of the state module share: state.c (the
 * state, its defaults and checks, the quality presets), state_keys.c (the
 * key registry, set, get and the key list) and the rooms whose keys need
 * code, each with the hooks its rows name: state_clock.c (the clock),
 * state_atmo.c (the planet preset and the constituents), state_weather.c
 * (the weather keys, METAR, state_resolve), state_clouds.c (the cloud
 * layers), state_terrain.c (the terrain) and state_sensor.c (the light
 * sensor). */
#ifndef SKYD_STATE_INTERNAL_H
#define SKYD_STATE_INTERNAL_H

#include <stdio.h>

#include "state.h"

#define T_BIT STATE_BIT(STATE_TRANSMITTANCE)
#define M_BIT STATE_BIT(STATE_MULTISCATTER)
#define S_BIT STATE_BIT(STATE_SKYVIEW)
#define A_BIT STATE_BIT(STATE_AERIAL)
/* What a change to one table forces downstream. */
#define FROM_T (T_BIT | M_BIT | S_BIT | A_BIT)
#define FROM_M (M_BIT | S_BIT | A_BIT)
#define LIGHTS (S_BIT | A_BIT)
/* The cloud field: its tables and the sky tables its shadows will reach. */
#define CLOUDS (STATE_CLOUD_TABLES | S_BIT | A_BIT)

/* The three refusals of a key: malformed, out of its range, unknown; each
 * writes the message to err (err_size in scope). */
#define ERR(...) (snprintf(err, err_size, __VA_ARGS__), -EINVAL)
#define ERR_RANGE(...) (snprintf(err, err_size, __VA_ARGS__), -ERANGE)
#define ERR_UNKNOWN(...) (snprintf(err, err_size, __VA_ARGS__), -ENOENT)

/* Longest value text state_get writes (sensor_select's 127 bytes). */
#define STATE_VALUE_MAX 160

/* A number as get writes it (nine significant digits); while
 * state_foreach_exact or state_get_exact runs, with as many more (up to
 * seventeen) as it takes to read back to the same double. */
void state_format_number(double v, char *buf, size_t n);

/* Index of v in a NULL-terminated list, or -1. */
int state_enum_index(const char *const *names, const char *v);

/* Sets every key to its row's default (state_default): the preset and the
 * quality first, then each key that has a default of its own. */
void state_keys_default(struct sky_state *s);
/* Calls fn for every weather input (STATE_LISTED_GIVEN), auto or not. */
void state_foreach_given(const struct sky_state *s, state_emit_fn fn, void *ctx);
/* The first constituent key that pins bit (enum state_override): the name
 * of the coefficient the weather maps. */
const struct state_key *state_key_pinning(uint32_t bit);

/* ---- state.c: the quality presets (quality=) ---- */
extern const char *const state_quality_names[];
state_key_set_fn state_set_quality;
state_key_get_fn state_get_quality;		/* the preset the settings equal, or custom */

/* ---- state_clock.c ---- */
state_key_set_fn state_set_utc;			/* now or ISO 8601: the clock's anchor */
state_key_get_fn state_get_utc;			/* the simulated time now, or none */
state_key_set_fn state_set_light_mode;		/* a clock mode starts a clock never set */
/* What setting a key does to the lights' modes (enum state_key_hands). */
void state_clock_hand_lights(struct sky_state *s, enum state_key_hands hands);

/* ---- state_atmo.c: the planet preset and the constituent family ---- */
/* The field of struct atmo_constituent a constituent key names (its arg). */
enum state_constituent_field {
	STATE_C_SCATTERING, STATE_C_ABSORPTION, STATE_C_SCALE_HEIGHT, STATE_C_G, STATE_C_PHASE,
	STATE_C_WIDTH, STATE_C_EXP_TERM, STATE_C_EXP_SCALE, STATE_C_LINEAR, STATE_C_CONSTANT,
};
/* Added to a layer's field: the upper layer's (layers[1]). */
#define STATE_C_UPPER 16
extern const char *const state_phase_names[];
state_key_set_fn state_set_preset;
state_key_get_fn state_get_preset;
/* "<constituent>_<field>": the constituent the name starts with; -ENOENT
 * when the state's preset has none of that name. */
state_key_set_fn state_set_constituent;
state_key_get_fn state_get_constituent;

/* ---- state_weather.c ---- */
state_key_set_fn state_set_weather;		/* an aerosol or ozone input */
state_key_set_fn state_set_cloud;		/* cloud_oktas: the cloud factor follows */
state_key_set_fn state_set_cloud_fraction;	/* stored as oktas */
state_key_get_fn state_get_cloud_fraction;
state_key_set_fn state_set_metar_key;
/* A raw constituent key was set: while the weather maps the coefficients
 * in bits (enum state_override), the raw key now wins for them. */
void state_weather_pin(struct sky_state *s, uint32_t bits);

/* ---- state_clouds.c ---- */
extern const char *const state_cloud_type_names[];
/* A cloud key into its field; no table while no layer is drawn. */
state_key_set_fn state_set_cloud_key;
state_key_set_fn state_set_cloud_layer_fraction;	/* stored as oktas */
state_key_get_fn state_get_cloud_layer_fraction;
/* The layers and the wind of a METAR (every layer replaced: none where
 * the report has none; the wind kept where it has none). */
struct metar;
void state_clouds_from_metar(struct sky_state *s, const struct metar *m);
/* The layers' cross-key rules (a top above its base and below the
 * atmosphere's top): 0 or -ERANGE with err naming the key. */
int state_clouds_validate(const struct sky_state *s, char *err, size_t err_size);

/* ---- state_terrain.c ---- */
state_key_set_fn state_set_terrain;		/* reads the file; refused whole when it cannot */
state_key_get_fn state_get_terrain;		/* the path, or none */
state_key_set_fn state_set_terrain_key;		/* extent and height: nothing while no field */
state_key_set_fn state_set_terrain_hash;	/* a check against the field read */
state_key_get_fn state_get_terrain_hash;
/* The terrain's cross-key rule (its white below the atmosphere's top):
 * 0 or -ERANGE with err naming the key. */
int state_terrain_validate(const struct sky_state *s, char *err, size_t err_size);

/* ---- state_sensor.c ---- */
extern const char *const state_sensor_mode_names[];
state_key_set_fn state_set_sensor_select;

#endif

/* state_internal.h - what the files of the state module share: state.c (the
 * state, set and get), state_keys.c (the key table, its parsers and its
 * list), state_weather.c (the weather keys, METAR, state_resolve) and
 * state_sensor.c (the light sensor's keys). */
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

/* The three refusals of a key: malformed, out of its range, unknown; each
 * writes the message to err (err_size in scope). */
#define ERR(...) (snprintf(err, err_size, __VA_ARGS__), -EINVAL)
#define ERR_RANGE(...) (snprintf(err, err_size, __VA_ARGS__), -ERANGE)
#define ERR_UNKNOWN(...) (snprintf(err, err_size, __VA_ARGS__), -ENOENT)

/* Index of v in a NULL-terminated list, or -1. */
int state_enum_index(const char *const *names, const char *v);

/* The keys of the table in state_keys.c (sizes, angles, lights, site) and
 * the per-constituent keys "<constituent>_<suffix>". */
struct state_key;
const struct state_key *state_find_key(const char *name);
/* The tables a change of k invalidates. */
uint32_t state_key_dirty(const struct state_key *k);
/* Parses value into s's field of k: 0, -EINVAL or -ERANGE with err. */
int state_set_table_key(struct sky_state *s, const struct state_key *k, const char *value,
			char *err, size_t err_size);
/* A constituent key of s->atmo: 0, -EINVAL, -ERANGE, or -ENOENT when key
 * names no constituent key (err says so). */
int state_set_constituent_key(struct sky_state *s, const char *key, const char *value,
			      char *err, size_t err_size);
/* Formats a table or constituent key of s; -ENOENT if key is neither. */
int state_get_key(const struct sky_state *s, const char *key, char *buf, size_t size);
/* Calls fn for the table keys, then every constituent key, in order. */
void state_foreach_key(const struct sky_state *s, state_emit_fn fn, void *ctx);

/* The weather keys (weather_keys) and metar: 1 when key is none of them,
 * else as state_set, with the tables it invalidates in *ret_dirty. */
int state_set_weather_key(struct sky_state *s, const char *key, const char *value,
			  uint32_t *ret_dirty, char *err, size_t err_size);
/* A raw constituent key was set: while the weather maps its coefficient,
 * the raw key now wins for it (enum state_override). */
void state_weather_note_raw(struct sky_state *s, const char *key);
/* Calls fn for the weather keys that are given (not auto). */
void state_foreach_weather(const struct sky_state *s, state_emit_fn fn, void *ctx);

/* One row of the key list (skyd --list-keys): markdown or tab-separated. */
void state_print_row(FILE *f, bool markdown, const char *name, const char *unit,
		     const char *range, const char *def, uint32_t dirty, const char *doc);

/* The light sensor's keys (state_sensor_keys): their defaults; a key into s,
 * 1 when key is none of them, else 0, -EINVAL or -ERANGE with err (they
 * invalidate no table); its value, -ENOENT when none of them; all of them
 * to fn while one differs from its default; their rows of the key list. */
void state_sensor_defaults(struct state_sensor *ret);
int state_set_sensor_key(struct sky_state *s, const char *key, const char *value, char *err,
			 size_t err_size);
int state_get_sensor_key(const struct sky_state *s, const char *key, char *buf, size_t size);
void state_foreach_sensor(const struct sky_state *s, state_emit_fn fn, void *ctx);
void state_print_sensor_keys(FILE *f, bool markdown);

#endif

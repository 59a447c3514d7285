/* state_keys.h - the key registry: one row per key of the sky's state, the
 * one place that knows a key's name, kind, unit, range, default, the tables
 * it invalidates and what it is. set and get, the config file, the sync
 * message and skyd --list-keys (and from it PROTOCOL.md's key list and
 * skyd.conf(5)) all read it. The rows are in state_keys.c, whose opening
 * comment says how to add one. */
#ifndef SKYD_STATE_KEYS_H
#define SKYD_STATE_KEYS_H

#include <stddef.h>
#include <stdint.h>

struct sky_state;

/* How a value is written, and what its field in struct sky_state holds. */
enum state_key_kind {
	STATE_KIND_NUMBER,	/* a finite number in [min, max]; a double */
	STATE_KIND_NUMBER_AUTO,	/* the same, or auto: NAN, not given */
	STATE_KIND_INTEGER,	/* a whole number in [min, max]; a uint32_t */
	STATE_KIND_TRIPLE,	/* r,g,b or one number for all three, each in [min, max]; double[3] */
	STATE_KIND_WORD,	/* one of words; its index, an int (an enum) */
	STATE_KIND_TEXT,	/* free text; hooks parse it */
	STATE_KIND_TIME,	/* an instant: now or ISO 8601 with a zone; hooks parse it */
};

/* When `get` without keys (state_foreach, and so a sync message) lists a key. */
enum state_key_listed {
	STATE_LISTED_ALWAYS = 0,
	STATE_LISTED_GIVEN,	/* a weather input: only when not auto (get weather: always) */
	STATE_LISTED_BLOCK,	/* with the run of rows around it, while one of them is away
				 * from its default: a state without a sensor reads as before */
	STATE_LISTED_NEVER,	/* get names it or nothing does (quality, an alias) */
};

/* What setting a key does to the lights' modes, whatever its value. */
enum state_key_hands {
	STATE_HANDS_NONE = 0,
	STATE_HANDS_TO_CLOCK,		/* a time or a place: both lights to the clock */
	STATE_HANDS_SUN_TO_USER,	/* what the clock computes for the sun: sun manual */
	STATE_HANDS_MOON_TO_USER,	/* the same for the moon */
};

enum state_key_flag {
	/* Its value is the simulated time now: a replica is sent the time
	 * at the change's apply instant instead (utc). */
	STATE_KEY_NOW = 1u << 0,
	/* Set after every other key when a whole state is replayed: those
	 * hand its light over as a side effect (a light's mode). */
	STATE_KEY_LAST = 1u << 1,
	/* get may show none, which set does not take: a clock never set, the
	 * scale height of a profile that is not one exponential. */
	STATE_KEY_NONE_UNSET = 1u << 2,
	/* No default of its own: the preset's or the quality's. */
	STATE_KEY_PRESET_DEFAULT = 1u << 3,
	/* An action, not a value: get does not know it (metar). */
	STATE_KEY_WRITE_ONLY = 1u << 4,
};

/* The keys that code outside the registry names, each by its row's id;
 * add one only for a key another module must name. */
enum state_key_id {
	STATE_KEY_ID_NONE = 0,
	STATE_KEY_ID_UTC,		/* get sun and get moon answer with the time used */
	STATE_KEY_ID_ALTITUDE_KM,	/* a view's altitude is this key, per view */
	STATE_KEY_ID_METAR,		/* set answers what the report gave */
	/* What a METAR report sets, in metar_applied's order. */
	STATE_KEY_ID_VISIBILITY_KM,
	STATE_KEY_ID_RELATIVE_HUMIDITY,
	STATE_KEY_ID_AEROSOL,
	STATE_KEY_ID_CLOUD_OKTAS,
	STATE_KEY_ID_PRESSURE_MBAR,
	STATE_KEY_ID_TEMPERATURE_C,
};

struct state_key;

/* A hook's set: parses value into s; 0, or -EINVAL (malformed), -ERANGE
 * (out of range) or -ENOENT (not a key of this state) with err naming the
 * key. *ret_dirty comes in as the row's dirty; a hook may narrow it. */
typedef int state_key_set_fn(struct sky_state *s, const struct state_key *k, const char *value,
			     uint32_t *ret_dirty, char *err, size_t err_size);
/* A hook's get: formats the value; 0, or -ENOENT when this state has no
 * such key (a constituent its preset lacks). */
typedef int state_key_get_fn(const struct sky_state *s, const struct state_key *k, char *buf,
			     size_t size);

struct state_key {
	const char *name;
	enum state_key_kind kind;
	size_t offset;			/* its field in struct sky_state, for the kinds that store one */
	double min, max;		/* inclusive: a number, an integer, each of a triple */
	const char *const *words;	/* a word's values, NULL-terminated */
	double def;			/* the default: a number (NAN: auto), an integer,
					 * each of a triple, a word's index */
	const char *def_text;		/* or the value set takes for its default (preset=earth) */
	uint32_t dirty;			/* the tables a change invalidates (STATE_BIT) */
	const char *unit;		/* "-": none */
	const char *range;		/* the key list's range where min, max and words do not say it */
	const char *doc;		/* what it is, one line of the key list */
	enum state_key_listed listed;
	enum state_key_hands hands;
	/* The raw coefficients (enum state_override) it concerns: a constituent
	 * key pins them while the weather maps them, a weather key wins them back. */
	uint32_t override;
	int arg;			/* its hooks' own: a constituent's field */
	enum state_key_id id;
	unsigned flags;			/* enum state_key_flag */
	state_key_set_fn *set;		/* NULL: the kind's parser into the field */
	state_key_get_fn *get;		/* NULL: the kind's format of the field */
};

/* The row of a name, NULL if none; the row of an id (never NULL). Rows
 * live as long as the program. */
const struct state_key *state_key_find(const char *name);
const struct state_key *state_key_of(enum state_key_id id);
const char *state_key_name(enum state_key_id id);

/* The kind's parser: value into field (the kind's type), 0, -EINVAL or
 * -ERANGE with err naming the key; field is untouched on failure. */
int state_key_parse(const struct state_key *k, const char *value, void *field, char *err,
		    size_t err_size);
/* The kind's format of field: "%.9g", auto, the word. */
void state_key_format(const struct state_key *k, const void *field, char *buf, size_t size);

#endif

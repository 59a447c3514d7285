/* weather.h - weather in the words people use (visibility, humidity, aerosol
 * type, turbidity, ozone column, cloud cover) mapped onto an atmosphere.
 *
 * A struct weather holds the inputs, each optional (NAN or
 * WEATHER_AEROSOL_AUTO: not given). weather_map() turns them, against the
 * atmosphere they will be applied to, into a struct weather_map: the Mie
 * constituent (scattering and absorption per channel, g, scale height), a
 * scale for the ozone absorption and a light factor for the sun and moon.
 * weather_apply() writes the map into an atmosphere. Formulas, sources and
 * ranges: docs/weather.md. The keys that set the inputs are the sky
 * state's (daemon/state/state_keys.c).
 *
 * The inputs are a plain value struct, not an opaque one, so that the sky's
 * state can embed and copy it like struct atmo; compare two with
 * weather_equal() (NAN never equals itself).
 */
#ifndef SKYD_WEATHER_H
#define SKYD_WEATHER_H

#include <stdbool.h>
#include <stddef.h>

#include "atmo.h"

/* Aerosol types, each an OPAC mixture (Hess, Koepke and Schult 1998). */
enum weather_aerosol {
	WEATHER_AEROSOL_AUTO = 0,	/* not given: continental where needed */
	WEATHER_CLEAN = 1,		/* OPAC continental clean */
	WEATHER_CONTINENTAL = 2,	/* OPAC continental average */
	WEATHER_URBAN = 3,		/* OPAC urban */
	WEATHER_MARITIME = 4,		/* OPAC maritime clean */
	WEATHER_DESERT = 5,		/* OPAC desert */
	WEATHER_N_AEROSOLS = 6,
};

/* Validity ranges of the inputs (inclusive). */
#define WEATHER_VISIBILITY_MIN_KM 0.05
#define WEATHER_VISIBILITY_MAX_KM 300.0
#define WEATHER_ANGSTROM_BETA_MAX 10.0
#define WEATHER_OZONE_DU_MAX 600.0
#define WEATHER_OKTAS_MAX 8.0

/* The inputs. Every field is optional: NAN (or WEATHER_AEROSOL_AUTO) means
 * not given. */
struct weather {
	double visibility_km;		/* meteorological optical range at the ground */
	double relative_humidity;	/* 0..1 at the ground */
	enum weather_aerosol aerosol;
	double angstrom_beta;		/* turbidity: aerosol optical depth at 1000 nm */
	double ozone_du;		/* total ozone column, Dobson units */
	double cloud_oktas;		/* cloud cover 0..8 */
};

/* The Mie constituent a weather maps to. */
struct weather_mie {
	double scattering_per_km[3];	/* at the ground, 680 / 550 / 440 nm */
	double absorption_per_km[3];
	double g;			/* asymmetry, the same for every channel */
	double scale_height_km;		/* density exp(-h / scale_height_km) */
};

/* The outcome of weather_map: what weather_apply writes, and the figures
 * `get weather` reports (state_describe_weather). */
struct weather_map {
	bool sets_mie;			/* false: no aerosol input, Mie left as it is */
	struct weather_mie mie;
	enum weather_aerosol aerosol;	/* the type used (never AUTO when sets_mie) */
	double relative_humidity;	/* used for the growth, clamped to 0.99 */
	double growth;			/* f(RH): scattering relative to RH 80 % */
	double extinction_550_per_km;	/* aerosol, at the ground */
	double ssa;			/* single-scattering albedo */
	double angstrom_440_550;	/* exponent between 440 and 550 nm */
	double angstrom_550_680;	/* and between 550 and 680 nm */
	double aod_550;			/* vertical aerosol optical depth */
	double visibility_km;		/* Koschmieder range of air + aerosol at the ground */

	bool sets_ozone;		/* false: ozone left as it is */
	double ozone_absorption_per_km[3];	/* what weather_apply writes */
	double ozone_scale;		/* new over old absorption; NAN when the old
					 * was 0 and the new comes from the cross-sections */
	double ozone_du;		/* the column after the map */

	double light_factor;		/* sun and moon illuminance factor, 1 without clouds */
};

/* All inputs not given. */
void weather_init(struct weather *ret);
/* True when no input is given (the map then changes nothing). */
bool weather_is_empty(const struct weather *w);
/* True when a and b give the same inputs (NAN equals NAN here). */
bool weather_equal(const struct weather *a, const struct weather *b);

typedef void (*weather_emit_fn)(void *ctx, const char *key, const char *value);

/* Checks every input against its range. Returns 0 or -ERANGE with a
 * message naming the field (the key that sets it). */
int weather_validate(const struct weather *w, char *err, size_t err_size);

/* Maps w against atmosphere a (found by constituent name: "rayleigh" and
 * any other air constituent give the air's own extinction at the ground,
 * "mie" is replaced, "ozone" is scaled). Returns 0, or -ERANGE (an input
 * out of range) / -EINVAL (a needed constituent missing, e.g. ozone_du on
 * an atmosphere without ozone) with a message in err. Every output is
 * finite and >= 0 over the whole validity range. */
int weather_map(const struct weather *w, const struct atmo *a, struct weather_map *ret,
		char *err, size_t err_size);
/* Writes m into a: the Mie constituent's coefficients, g and exponential
 * profile when m->sets_mie, the ozone absorption when m->sets_ozone; the
 * phase functions, the ozone profile and the rest stay. The light factor is
 * the caller's to apply to the illuminances. */
void weather_apply(const struct weather_map *m, struct atmo *a);

/* Kasten and Czeplak (1980): global irradiance under N oktas of cloud over
 * the clear-sky value, 1 - 0.75 (N / 8)^3.4; oktas clamped to [0, 8]. */
double weather_cloud_light_factor(double oktas);
/* Relative humidity (0..1) from temperature and dew point in Celsius by the
 * Magnus formula over water (Alduchov and Eskridge 1996); NAN if either is
 * not finite. Not clamped: a dew point above the temperature gives > 1. */
double weather_relative_humidity(double temperature_c, double dewpoint_c);
/* Total ozone column of a in Dobson units, from its ozone constituent's
 * 550 nm absorption and the ozone cross-section; 0 without ozone. */
double weather_ozone_du(const struct atmo *a);
/* Koschmieder visibility 3.912 / extinction(550 nm) at the ground of a, in
 * km; INFINITY for an atmosphere with no extinction. */
double weather_visibility_km(const struct atmo *a);

/* The aerosol types' names, NULL-terminated, in enum order ("auto",
 * "clean", "continental", ...), and the name of one. */
extern const char *const weather_aerosol_names[];
const char *weather_aerosol_name(enum weather_aerosol t);

#endif

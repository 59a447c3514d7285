/* metar.h - a decoder of METAR and SPECI reports (WMO FM 15 / FM 16 with
 * the US variants) and their mapping onto weather inputs.
 *
 * metar_decode() reads one report into a struct metar, a plain value the
 * caller owns; metar_weather() turns it into the inputs of weather.h;
 * metar_describe() lists what was decoded as key: value pairs. What each
 * group maps to: docs/weather.md.
 */
#ifndef SKYD_METAR_H
#define SKYD_METAR_H

#include <stdbool.h>
#include <stddef.h>

#include "weather.h"

#define METAR_MAX_LEN 1024		/* longest report accepted, bytes */
#define METAR_GROUP_MAX 32		/* longest group kept, with its NUL */
#define METAR_MAX_WEATHER 8		/* present weather groups kept */
#define METAR_MAX_CLOUDS 8		/* cloud layers kept */

/* How a visibility reads: exactly, "or more" (9999, P6SM, 10SM, CAVOK) or
 * "less than" (0000, M1/4SM). */
enum metar_qualifier { METAR_EXACT = 0, METAR_OR_MORE = 1, METAR_LESS_THAN = 2 };

/* Sky condition besides layers. */
enum metar_sky {
	METAR_SKY_NONE = 0,		/* no sky group (or only layers) */
	METAR_SKY_CLEAR = 1,		/* SKC, CLR, NSC, NCD or CAVOK */
	METAR_SKY_OBSCURED = 2,		/* VV: vertical visibility */
};

/* Cloud amounts; METAR_COVER_MISSING for "///". */
enum metar_cover {
	METAR_COVER_MISSING = 0, METAR_FEW = 1, METAR_SCT = 2, METAR_BKN = 3, METAR_OVC = 4,
};

struct metar_cloud {
	enum metar_cover cover;
	double height_ft;		/* above the ground; NAN for "///" */
	char type[4];			/* "CB", "TCU" or "" */
};

/* Phenomena of a present weather group, one bit each. */
enum metar_phenomenon {
	METAR_DZ = 1u << 0, METAR_RA = 1u << 1, METAR_SN = 1u << 2, METAR_SG = 1u << 3,
	METAR_IC = 1u << 4, METAR_PL = 1u << 5, METAR_GR = 1u << 6, METAR_GS = 1u << 7,
	METAR_UP = 1u << 8, METAR_BR = 1u << 9, METAR_FG = 1u << 10, METAR_FU = 1u << 11,
	METAR_VA = 1u << 12, METAR_DU = 1u << 13, METAR_SA = 1u << 14, METAR_HZ = 1u << 15,
	METAR_PY = 1u << 16, METAR_PO = 1u << 17, METAR_SQ = 1u << 18, METAR_FC = 1u << 19,
	METAR_SS = 1u << 20, METAR_DS = 1u << 21,
};
#define METAR_PRECIPITATION (METAR_DZ | METAR_RA | METAR_SN | METAR_SG | METAR_IC | \
			     METAR_PL | METAR_GR | METAR_GS | METAR_UP)

struct metar_weather_group {
	char code[METAR_GROUP_MAX];	/* as reported, e.g. "-SHRA" */
	int intensity;			/* -1 light, 0 moderate, 1 heavy */
	bool vicinity;			/* VC: near, not at, the station */
	char descriptor[3];		/* MI BC PR DR BL SH TS FZ or "" */
	unsigned phenomena;		/* enum metar_phenomenon bits */
};

/* A decoded report. Numbers not reported are NAN. */
struct metar {
	char type[6];			/* "METAR" or "SPECI" ("METAR" when absent) */
	char station[5];		/* ICAO location indicator */
	int day, hour, minute;		/* of the observation, UTC */
	bool nil, automatic, corrected;

	double wind_dir_deg;		/* NAN when variable (VRB) or missing */
	bool wind_variable;		/* VRB */
	double wind_speed, wind_gust;	/* in wind_unit */
	char wind_unit[4];		/* "KT", "MPS", "KMH" or "" */
	int wind_from_deg, wind_to_deg;	/* variable sector dddVddd; -1 without */

	bool cavok;
	double visibility_m;		/* prevailing */
	enum metar_qualifier visibility_qualifier;
	double min_visibility_m;	/* directional minimum */
	char min_visibility_dir[3];	/* N, NE, ... */
	int n_rvr;			/* runway visual range groups read */

	int n_weather;
	struct metar_weather_group weather[METAR_MAX_WEATHER];
	bool no_significant_weather;	/* NSW */
	int n_recent;			/* RE groups read */

	enum metar_sky sky;
	int n_clouds;
	struct metar_cloud clouds[METAR_MAX_CLOUDS];
	double vertical_visibility_ft;

	double temperature_c, dewpoint_c;
	double qnh_hpa;			/* from Qxxxx, or Axxxx converted */
	bool wind_shear;
	char trend[6];			/* "NOSIG", "BECMG", "TEMPO" or "" */
	bool remarks;

	/* The groups, space-separated: used feed the decoded weather (visibility,
	 * present weather, clouds, temperature, pressure); ignored are read but
	 * not used (identification, wind, RVR, recent weather, wind shear, the
	 * trend and the remarks with what follows them). */
	char used[METAR_MAX_LEN];
	char ignored[METAR_MAX_LEN];

	/* On a refusal: the offending group and its 1-based position among the
	 * report's space-separated groups; 0 and "" otherwise. */
	int error_position;
	char error_group[METAR_GROUP_MAX];
};

/* Decodes one report (a trailing '=' allowed). Decoding stops at a trend
 * (NOSIG, BECMG, TEMPO) or RMK; the rest is listed as ignored. "NIL" after
 * the time gives a report with nil set and nothing else. Returns 0, or
 * -EINVAL for a malformed report with err naming the group and its
 * position ("group 5 '9999X': ...") and ret->error_* set. */
int metar_decode(const char *text, struct metar *ret, char *err, size_t err_size);

/* The weather inputs a report gives: visibility_km (unless reported as the
 * maximum, 9999 / CAVOK / 10SM / P6SM: then auto), relative_humidity from
 * temperature and dew point, aerosol from present weather, cloud_oktas
 * from the layers. Each of these four is overwritten, with auto where the
 * report says nothing; angstrom_beta and ozone_du are left as they are. */
void metar_weather(const struct metar *m, struct weather *w);

/* Calls fn with key: value pairs of what was decoded. */
void metar_describe(const struct metar *m, weather_emit_fn fn, void *ctx);

/* A cloud layer of a report as the sky's state takes it (its top is the
 * type's typical thickness above the base): cover in oktas, base in m
 * above the ground, an enum skycloud_type. */
struct metar_layer {
	double oktas;
	double base_m;
	int type;
};

/* The report's cloud layers, in its order, at most max: every FEW, SCT,
 * BKN and OVC group with a height (its CB or TCU naming the type, else
 * the height and the amount: docs/clouds.md, "METAR"), and VV with a
 * height as an overcast stratus there. None for a clear sky (SKC, CLR,
 * NSC, NCD, CAVOK), nor for a group whose amount or height is "///".
 * Bases in m rounded to 0.1 m, so that their text travels exactly. */
int metar_layers(const struct metar *m, struct metar_layer *ret, int max);

/* The wind group: where it blows from (NAN when variable) and its speed
 * in m/s rounded to 0.01; -ENODATA when the report has no wind or its
 * speed is missing. */
int metar_wind(const struct metar *m, double *ret_dir_deg, double *ret_speed_mps);

/* Oktas of a layer amount (FEW 1.5, SCT 3.5, BKN 6, OVC 8: the middle of
 * each range) and of a whole report (the largest layer; 8 with vertical
 * visibility; 0 when clear; NAN when the report says nothing). */
double metar_cover_oktas(enum metar_cover c);
double metar_oktas(const struct metar *m);

#endif

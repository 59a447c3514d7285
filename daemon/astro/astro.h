/* astro.h - where the sun and the moon are, how bright, and when they rise,
 * from a time and a place, so that users set those and not angles.
 *
 * Sun: the NREL Solar Position Algorithm (I. Reda and A. Andreas, "Solar
 * Position Algorithm for Solar Radiation Applications", NREL/TP-560-34302,
 * 2003, revised 2008; Solar Energy 76 (2004) 577-589), implemented from the
 * report; its periodic-term tables are taken as numbers. Stated accuracy
 * +-0.0003 deg for years -2000..6000 given the right delta T.
 * Moon: J. Meeus, "Astronomical Algorithms", 2nd ed. 1998: ch. 47 (position,
 * tables 47.A/47.B), ch. 40 (parallax, done as SPA does for the sun), ch. 48
 * (phase angle, illuminated fraction). About 10" in longitude, 4" in latitude.
 *
 * Times are POSIX seconds (UTC, no leap seconds); the user's UT1 - UTC and
 * TT - UT1 (delta T) come with the options. Angles are degrees. Azimuths run
 * eastward from north, [0, 360). Every direction comes twice: geometric (the
 * straight line, what the sky tables want; docs/physics.md: feed the unrefracted
 * direction to the tables) and apparent (raised by refraction, what a person
 * sees). All functions are pure and thread-safe.
 *
 * Errors: -EINVAL for an argument outside its domain, with a message naming
 * the key (lat_deg, lon_deg, elevation_m, utc, month, ...) written into err
 * (which may be NULL); *ret is untouched on failure.
 */
#ifndef SKYD_ASTRO_H
#define SKYD_ASTRO_H

#include <stdbool.h>
#include <stddef.h>

/* The observer. */
struct astro_site {
	double lat_deg;			/* geodetic latitude, north positive, [-90, 90] */
	double lon_deg;			/* longitude, east positive, [-180, 180] */
	double elevation_m;		/* above sea level (WGS84-ish ellipsoid), [-1000, 1e5] */
};

struct astro_options {
	bool delta_t_auto;		/* true: delta_t_s from astro_delta_t_s() at the date */
	double delta_t_s;		/* TT - UT1 when !delta_t_auto, |x| <= 1e6 */
	double delta_ut1_s;		/* UT1 - UTC from IERS Bulletin A, (-1, 1) */
	double pressure_mbar;		/* at the site, for refraction, [0, 5000] */
	double temperature_c;		/* at the site, for refraction, [-100, 100] */
	double horizon_refraction_deg;	/* refraction at the horizon for rise and set
					 * and for where refraction stops being applied:
					 * SPA's atmos_refract, 0.5667 by default, [0, 3] */
};

/* delta T automatic, UT1 = UTC, 1013.25 mbar, 15 C, 0.5667 deg. */
void astro_options_default(struct astro_options *ret);

/* A direction from the observer (topocentric). */
struct astro_direction {
	double zenith_deg;		/* [0, 180] */
	double elevation_deg;		/* 90 - zenith_deg */
	double azimuth_deg;		/* eastward from north, [0, 360) */
};

struct astro_sun {
	struct astro_direction geometric;	/* no refraction: for the sky tables */
	struct astro_direction apparent;	/* refracted (SPA eq. 42, Bennett/Saemundsson
						 * scaled by pressure and temperature) */
	double right_ascension_deg;	/* geocentric apparent, [0, 360) */
	double declination_deg;		/* geocentric apparent */
	double hour_angle_deg;		/* topocentric local hour angle, [-180, 180) */
	double distance_au;		/* earth-sun */
	double equation_of_time_min;	/* apparent minus mean solar time, [-20, 20] */
	double angular_radius_deg;	/* 959.63 arcsec / distance_au */
	double illuminance_lx;		/* top of the atmosphere, normal incidence:
					 * ASTRO_SUN_ILLUMINANCE_1AU_LX / distance_au^2 */
	double delta_t_s;		/* the TT - UT1 that was used */
};

/* The extraterrestrial luminous solar constant at 1 AU: 133.8 klx (Darula,
 * Kittler and Gueymard, "Reference luminous solar constant and solar
 * luminance for illuminance calculations", Solar Energy 79 (2005) 559). */
#define ASTRO_SUN_ILLUMINANCE_1AU_LX 133800.0

/* A V = 0 star's illuminance outside the atmosphere (Allen's Astrophysical
 * Quantities). The full moon at mean distances, V = -12.73 (Krisciunas and
 * Schaefer 1991), then gives 0.314 lx outside the atmosphere; docs/physics.md
 * quotes 0.27-0.31 lx at the ground at high altitude. */
#define ASTRO_MOON_ILLUMINANCE_MAG0_LX 2.54e-6

struct astro_moon {
	struct astro_direction geometric;	/* topocentric (with parallax), no refraction */
	struct astro_direction apparent;	/* topocentric, refracted */
	double longitude_deg;		/* geocentric ecliptic, mean equinox of date, no
					 * nutation (Meeus 47.a's lambda), [0, 360) */
	double apparent_longitude_deg;	/* longitude_deg plus nutation in longitude */
	double latitude_deg;		/* geocentric ecliptic */
	double distance_km;		/* centre of the earth to centre of the moon */
	double topocentric_distance_km;	/* observer to centre of the moon */
	double right_ascension_deg;	/* geocentric apparent, [0, 360) */
	double declination_deg;		/* geocentric apparent */
	double phase_angle_deg;		/* sun-moon-earth angle: 0 full, 180 new */
	double illuminated_fraction;	/* (1 + cos phase_angle) / 2, Meeus 48.1 */
	double elongation_deg;		/* geocentric angle sun-earth-moon, [0, 180] */
	bool waxing;			/* apparent longitude ahead of the sun's by < 180 */
	double angular_radius_deg;	/* asin(1737.4 km / topocentric_distance_km) */
	double illuminance_lx;		/* top of the atmosphere, normal incidence; see
					 * astro_moon_illuminance_lx() */
	double color[3];		/* linear RGB (680, 550, 440 nm, the tables'
					 * channels) of the moonlight relative to the
					 * sunlight, luminance 1; see astro_moon.c */
	double delta_t_s;		/* the TT - UT1 that was used */
};

/* Rise and set of one kind (sunrise, civil twilight, ...). */
enum astro_day_kind {
	ASTRO_RISES_AND_SETS = 0,	/* rise_utc_s and set_utc_s are times */
	ASTRO_ALWAYS_ABOVE = 1,		/* polar day for this threshold: no event */
	ASTRO_ALWAYS_BELOW = 2,		/* polar night for this threshold: no event */
};

struct astro_rise_set {
	enum astro_day_kind kind;
	double rise_utc_s;		/* morning crossing upward; NAN unless RISES_AND_SETS */
	double set_utc_s;		/* evening crossing downward; NAN unless RISES_AND_SETS */
	double threshold_deg;		/* elevation of the sun's centre that defines it */
};

/* One local calendar day: the 24 hours that start at local midnight, where
 * local time is UTC + utc_offset_min. */
struct astro_date {
	int year;			/* -2000..6000 (SPA's range) */
	int month;			/* 1..12 */
	int day;			/* 1..28/29/30/31 */
	int utc_offset_min;		/* local minus UTC, [-1080, 1080] (e.g. -420 for MST) */
};

struct astro_times {
	double transit_utc_s;		/* the sun on the local meridian (solar noon) */
	double transit_elevation_deg;	/* its geometric topocentric elevation then */
	struct astro_rise_set sunrise_sunset;	/* upper limb on the horizon with
						 * refraction: threshold -(0.26667 +
						 * horizon_refraction_deg) */
	struct astro_rise_set civil;		/* centre at -6 deg */
	struct astro_rise_set nautical;		/* centre at -12 deg */
	struct astro_rise_set astronomical;	/* centre at -18 deg */
};

/* Night-sky floor, for the engine to add where the sun and moon leave the
 * sky dark. Horizontal illuminance from starlight, airglow and zodiacal
 * light on a clear moonless night: about 0.002 lx (USNO Circular 171 via
 * docs/physics.md: "below -18: about 0.002 lx"). Zenith luminance of a dark
 * site: V = 21.6..22.0 mag/arcsec^2 (Leinert et al. 1998, "The 1997 reference of diffuse night
 * sky brightness", A&AS 127, 1), i.e. with L = 10.8e4 * 10^(-0.4 V) cd/m^2
 * about 0.2 mcd/m^2. */
#define ASTRO_NIGHT_FLOOR_ILLUMINANCE_LX 0.002
#define ASTRO_NIGHT_ZENITH_LUMINANCE_CD_M2 2.0e-4

/* The sun at utc_s (POSIX seconds) for site. opt NULL means defaults. */
int astro_sun(const struct astro_site *site, double utc_s, const struct astro_options *opt,
	      struct astro_sun *ret, char *err, size_t err_size);

/* The moon at utc_s for site. opt NULL means defaults. */
int astro_moon(const struct astro_site *site, double utc_s, const struct astro_options *opt,
	       struct astro_moon *ret, char *err, size_t err_size);

/* Transit, sunrise/sunset and the three twilights of one local calendar day,
 * by the SPA report's appendix A.2 (sidereal time and three daily positions
 * interpolated, then one correction step), but counted from local midnight
 * rather than 0 h UT so that every event belongs to the asked day. Where the
 * sun does not cross a threshold that day the kind says so and the times are
 * NAN; no time is made up. Accuracy: seconds (the report's example agrees
 * to 0.03 s), worse in the days a polar day begins or ends. */
int astro_sun_times(const struct astro_site *site, const struct astro_date *date,
		    const struct astro_options *opt, struct astro_times *ret,
		    char *err, size_t err_size);

/* Delta T = TT - UT1 in seconds at a decimal year (2026.5 = mid 2026), from
 * the polynomials of Espenak and Meeus, "Five Millennium Canon of Solar
 * Eclipses" (NASA/TP-2006-214141), valid -1999..3000, and their long-term
 * parabola -20 + 32 u^2, u = (y - 1820) / 100, outside. Uncertain by about a
 * second today (the 2005-2050 branch runs a few seconds high of the observed
 * 69 s in 2024) and by minutes to hours in antiquity: callers that know
 * better set astro_options.delta_t_s. */
double astro_delta_t_s(double decimal_year);

/* The decimal year of a POSIX time (for astro_delta_t_s). */
double astro_decimal_year(double utc_s);

/* Moonlight outside the atmosphere, normal incidence, in lux:
 * E = 2.54e-6 lx * 10^(-0.4 m), m = -12.73 + 0.026 |a| + 4e-9 a^4 (the
 * moon's V magnitude at phase angle a in degrees, Krisciunas and Schaefer
 * 1991, PASP 103, 1033, eq. 9, after Allen), scaled by the inverse squares
 * of the earth-moon and sun distances over their means (384400 km, 1 AU).
 * Leaves out the opposition surge within a few degrees of full (up to +35 %
 * per K&S) and is 0 for |a| >= 180. */
double astro_moon_illuminance_lx(double phase_angle_deg, double moon_distance_km,
				 double sun_distance_au);

#endif

/* astro_internal.h - what the files of astro/ share (astro.c): constants,
 * degree trigonometry, the sun's geocentric place and the way to the
 * observer's horizon. Not part of astro.h's API. */
#ifndef SKYD_ASTRO_INTERNAL_H
#define SKYD_ASTRO_INTERNAL_H

#include <math.h>

#include "astro.h"

#define DEG (M_PI / 180.0)
#define JD_UNIX_EPOCH 2440587.5
#define JD_J2000 2451545.0
#define AU_KM 149597870.7
#define EARTH_EQUATORIAL_RADIUS_KM 6378.14	/* the value SPA and Meeus ch. 40 use */
#define SUN_RADIUS_1AU_DEG (959.63 / 3600.0)
#define SUN_RADIUS_SPA_DEG 0.26667		/* SPA's fixed sun radius for rise/set */

#define N(a) (sizeof(a) / sizeof((a)[0]))

static inline double wrap360(double x)
{
	x = fmod(x, 360.0);
	return x < 0.0 ? x + 360.0 : x;
}

static inline double wrap180(double x)
{
	x = wrap360(x + 180.0);
	return x - 180.0;
}

static inline double wrap01(double x)
{
	return x - floor(x);
}

static inline double sind(double x) { return sin(x * DEG); }
static inline double cosd(double x) { return cos(x * DEG); }
static inline double tand(double x) { return tan(x * DEG); }
static inline double asind(double x) { return asin(fmin(1.0, fmax(-1.0, x))) / DEG; }
static inline double atan2d(double y, double x) { return atan2(y, x) / DEG; }

/* Everything geocentric about the sun at one instant. */
struct astro_geo {
	double jd, jc, jce, jme;
	double r_au;
	double dpsi_deg, eps_deg;
	double lambda_deg;	/* apparent ecliptic longitude */
	double alpha_deg;	/* apparent right ascension, [0, 360) */
	double delta_deg;	/* apparent declination */
	double nu_deg;		/* apparent sidereal time at Greenwich, [0, 360) */
};

/* Time arguments and the earth-dependent parts of g (nutation, obliquity,
 * sidereal time); jd is UT1. */
void astro_geo_time(double jd, double delta_t_s, struct astro_geo *g);
/* SPA 3.1-3.9 for the sun: all of g (astro_sun.c). */
void astro_sun_geocentric(double jd, double delta_t_s, struct astro_geo *g);
/* Apparent equatorial coordinates from apparent ecliptic ones, SPA 3.8-3.9. */
void astro_ecliptic_to_equatorial(double lambda_deg, double beta_deg, double eps_deg,
				  double *ret_alpha_deg, double *ret_delta_deg);
/* The observer's distance from the earth's axis (x) and from the equator's
 * plane (y), in equatorial radii, on SPA's ellipsoid. */
void astro_observer_xy(const struct astro_site *site, double *ret_x, double *ret_y);
/* From geocentric apparent (alpha, delta) to the topocentric horizon, with
 * refraction where the body of radius_deg is not far below it; see astro.c. */
void astro_topocentric(const struct astro_site *site, const struct astro_options *o,
		       double alpha_deg, double delta_deg, double nu_deg, double sin_parallax,
		       double radius_deg, struct astro_direction *ret_geometric,
		       struct astro_direction *ret_apparent, double *ret_h_deg);

/* Writes the message to err (if err and err_size) and returns -EINVAL. */
int astro_refuse(char *err, size_t err_size, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
/* The site checked, and the options checked into *ret_opt (defaults for
 * opt NULL); -EINVAL naming the key otherwise. */
int astro_check_common(const struct astro_site *site, const struct astro_options *opt,
		       struct astro_options *ret_opt, char *err, size_t err_size);
/* utc_s within SPA's years -2000..6000, or -EINVAL. */
int astro_check_utc(double utc_s, char *err, size_t err_size);
/* The TT - UT1 the options ask for at utc_s. */
double astro_pick_delta_t_s(const struct astro_options *o, double utc_s);
/* The Julian day (UT1) of utc_s. */
double astro_jd_of(double utc_s, const struct astro_options *o);

#endif

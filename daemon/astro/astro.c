/* astro.c - what the sun, the moon and their rise and set share: the
 * options and their checks, delta T and the time scales, nutation and the
 * obliquity (SPA 3.4-3.5), and the way from geocentric coordinates to the
 * observer's horizon with refraction (SPA 3.8-3.15). */
#include "astro_internal.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>

#include "simclock.h"

/* SPA table A4.3: nutation in longitude and obliquity. Multiples of the
 * arguments D, M, M', F, Omega, then a, b (psi) and c, d (epsilon) in
 * 0.0001 arcsec: (a + b JCE) sin(arg), (c + d JCE) cos(arg). */
struct nut_term {
	signed char y[5];
	double a, b, c, d;
};

static const struct nut_term nutation_terms[] = {
	{ { 0, 0, 0, 0, 1 }, -171996, -174.2, 92025, 8.9 },
	{ { -2, 0, 0, 2, 2 }, -13187, -1.6, 5736, -3.1 },
	{ { 0, 0, 0, 2, 2 }, -2274, -0.2, 977, -0.5 },
	{ { 0, 0, 0, 0, 2 }, 2062, 0.2, -895, 0.5 },
	{ { 0, 1, 0, 0, 0 }, 1426, -3.4, 54, -0.1 },
	{ { 0, 0, 1, 0, 0 }, 712, 0.1, -7, 0 },
	{ { -2, 1, 0, 2, 2 }, -517, 1.2, 224, -0.6 },
	{ { 0, 0, 0, 2, 1 }, -386, -0.4, 200, 0 },
	{ { 0, 0, 1, 2, 2 }, -301, 0, 129, -0.1 },
	{ { -2, -1, 0, 2, 2 }, 217, -0.5, -95, 0.3 },
	{ { -2, 0, 1, 0, 0 }, -158, 0, 0, 0 },
	{ { -2, 0, 0, 2, 1 }, 129, 0.1, -70, 0 },
	{ { 0, 0, -1, 2, 2 }, 123, 0, -53, 0 },
	{ { 2, 0, 0, 0, 0 }, 63, 0, 0, 0 },
	{ { 0, 0, 1, 0, 1 }, 63, 0.1, -33, 0 },
	{ { 2, 0, -1, 2, 2 }, -59, 0, 26, 0 },
	{ { 0, 0, -1, 0, 1 }, -58, -0.1, 32, 0 },
	{ { 0, 0, 1, 2, 1 }, -51, 0, 27, 0 },
	{ { -2, 0, 2, 0, 0 }, 48, 0, 0, 0 },
	{ { 0, 0, -2, 2, 1 }, 46, 0, -24, 0 },
	{ { 2, 0, 0, 2, 2 }, -38, 0, 16, 0 },
	{ { 0, 0, 2, 2, 2 }, -31, 0, 13, 0 },
	{ { 0, 0, 2, 0, 0 }, 29, 0, 0, 0 },
	{ { -2, 0, 1, 2, 2 }, 29, 0, -12, 0 },
	{ { 0, 0, 0, 2, 0 }, 26, 0, 0, 0 },
	{ { -2, 0, 0, 2, 0 }, -22, 0, 0, 0 },
	{ { 0, 0, -1, 2, 1 }, 21, 0, -10, 0 },
	{ { 0, 2, 0, 0, 0 }, 17, -0.1, 0, 0 },
	{ { 2, 0, -1, 0, 1 }, 16, 0, -8, 0 },
	{ { -2, 2, 0, 2, 2 }, -16, 0.1, 7, 0 },
	{ { 0, 1, 0, 0, 1 }, -15, 0, 9, 0 },
	{ { -2, 0, 1, 0, 1 }, -13, 0, 7, 0 },
	{ { 0, -1, 0, 0, 1 }, -12, 0, 6, 0 },
	{ { 0, 0, 2, -2, 0 }, 11, 0, 0, 0 },
	{ { 2, 0, -1, 2, 1 }, -10, 0, 5, 0 },
	{ { 2, 0, 1, 2, 2 }, -8, 0, 3, 0 },
	{ { 0, 1, 0, 2, 2 }, 7, 0, -3, 0 },
	{ { -2, 1, 1, 0, 0 }, -7, 0, 0, 0 },
	{ { 0, -1, 0, 2, 2 }, -7, 0, 3, 0 },
	{ { 2, 0, 0, 2, 1 }, -7, 0, 3, 0 },
	{ { 2, 0, 1, 0, 0 }, 6, 0, 0, 0 },
	{ { -2, 0, 2, 2, 2 }, 6, 0, -3, 0 },
	{ { -2, 0, 1, 2, 1 }, 6, 0, -3, 0 },
	{ { 2, 0, -2, 0, 1 }, -6, 0, 3, 0 },
	{ { 2, 0, 0, 0, 1 }, -6, 0, 3, 0 },
	{ { 0, -1, 1, 0, 0 }, 5, 0, 0, 0 },
	{ { -2, -1, 0, 2, 1 }, -5, 0, 3, 0 },
	{ { -2, 0, 0, 0, 1 }, -5, 0, 3, 0 },
	{ { 0, 0, 2, 2, 1 }, -5, 0, 3, 0 },
	{ { -2, 0, 2, 0, 1 }, 4, 0, 0, 0 },
	{ { -2, 1, 0, 2, 1 }, 4, 0, 0, 0 },
	{ { 0, 0, 1, -2, 0 }, 4, 0, 0, 0 },
	{ { -1, 0, 1, 0, 0 }, -4, 0, 0, 0 },
	{ { -2, 1, 0, 0, 0 }, -4, 0, 0, 0 },
	{ { 1, 0, 0, 0, 0 }, -4, 0, 0, 0 },
	{ { 0, 0, 1, 2, 0 }, 3, 0, 0, 0 },
	{ { 0, 0, -2, 2, 2 }, -3, 0, 0, 0 },
	{ { -1, -1, 1, 0, 0 }, -3, 0, 0, 0 },
	{ { 0, 1, 1, 0, 0 }, -3, 0, 0, 0 },
	{ { 0, -1, 1, 2, 2 }, -3, 0, 0, 0 },
	{ { 2, -1, -1, 2, 2 }, -3, 0, 0, 0 },
	{ { 0, 0, 3, 2, 2 }, -3, 0, 0, 0 },
	{ { 2, -1, 0, 2, 2 }, -3, 0, 0, 0 },
};

/* Nutation in longitude and obliquity (degrees) at JCE, SPA 3.4. */
static void nutation(double jce, double *ret_dpsi_deg, double *ret_deps_deg)
{
	double x[5], dpsi = 0.0, deps = 0.0;
	double t2 = jce * jce, t3 = t2 * jce;

	x[0] = 297.85036 + 445267.111480 * jce - 0.0019142 * t2 + t3 / 189474.0;
	x[1] = 357.52772 + 35999.050340 * jce - 0.0001603 * t2 - t3 / 300000.0;
	x[2] = 134.96298 + 477198.867398 * jce + 0.0086972 * t2 + t3 / 56250.0;
	x[3] = 93.27191 + 483202.017538 * jce - 0.0036825 * t2 + t3 / 327270.0;
	x[4] = 125.04452 - 1934.136261 * jce + 0.0020708 * t2 + t3 / 450000.0;
	for (size_t i = 0; i < N(nutation_terms); i++) {
		const struct nut_term *n = &nutation_terms[i];
		double arg = 0.0;
		for (int j = 0; j < 5; j++)
			arg += x[j] * n->y[j];
		arg *= DEG;
		dpsi += (n->a + n->b * jce) * sin(arg);
		deps += (n->c + n->d * jce) * cos(arg);
	}
	*ret_dpsi_deg = dpsi / 36000000.0;
	*ret_deps_deg = deps / 36000000.0;
}

/* True obliquity of the ecliptic (degrees), SPA 3.5. */
static double obliquity_deg(double jme, double deps_deg)
{
	double u = jme / 10.0;
	static const double c[] = { 84381.448, -4680.93, -1.55, 1999.25, -51.38, -249.67,
				    -39.05, 7.12, 27.87, 5.79, 2.45 };
	double e0 = 0.0, up = 1.0;

	for (size_t i = 0; i < N(c); i++, up *= u)
		e0 += c[i] * up;
	return e0 / 3600.0 + deps_deg;
}

/* Time arguments and the earth-dependent parts; jd is UT1. */
void astro_geo_time(double jd, double delta_t_s, struct astro_geo *g)
{
	g->jd = jd;
	g->jc = (jd - JD_J2000) / 36525.0;
	g->jce = (jd + delta_t_s / 86400.0 - JD_J2000) / 36525.0;
	g->jme = g->jce / 10.0;
	nutation(g->jce, &g->dpsi_deg, &g->eps_deg);
	g->eps_deg = obliquity_deg(g->jme, g->eps_deg);
	double nu0 = 280.46061837 + 360.98564736629 * (jd - JD_J2000) +
		     0.000387933 * g->jc * g->jc - g->jc * g->jc * g->jc / 38710000.0;
	g->nu_deg = wrap360(wrap360(nu0) + g->dpsi_deg * cosd(g->eps_deg));
}

/* Apparent equatorial coordinates from apparent ecliptic ones, SPA 3.8-3.9. */
void astro_ecliptic_to_equatorial(double lambda_deg, double beta_deg, double eps_deg,
				  double *ret_alpha_deg, double *ret_delta_deg)
{
	double sl = sind(lambda_deg), ce = cosd(eps_deg), se = sind(eps_deg);

	*ret_alpha_deg = wrap360(atan2d(sl * ce - tand(beta_deg) * se, cosd(lambda_deg)));
	*ret_delta_deg = asind(sind(beta_deg) * ce + cosd(beta_deg) * se * sl);
}

/* Refraction (degrees) at the true elevation e0_deg, SPA eq. 42:
 * Saemundsson's formula scaled by pressure and temperature. Applied only
 * while the body is not below the horizon by more than its radius plus the
 * horizon refraction, where the formula stops meaning anything. */
static double refraction_deg(double e0_deg, double radius_deg, const struct astro_options *o)
{
	if (e0_deg < -(radius_deg + o->horizon_refraction_deg))
		return 0.0;
	return o->pressure_mbar / 1010.0 * 283.0 / (273.0 + o->temperature_c) * 1.02 /
	       (60.0 * tand(e0_deg + 10.3 / (e0_deg + 5.11)));
}

static void set_direction(struct astro_direction *d, double elevation_deg, double azimuth_deg)
{
	d->elevation_deg = elevation_deg;
	d->zenith_deg = 90.0 - elevation_deg;
	d->azimuth_deg = azimuth_deg;
}

/* The observer's distance from the earth's axis (x) and from the equator's
 * plane (y), in equatorial radii, on SPA's ellipsoid (SPA 3.12.2-3.12.5). */
void astro_observer_xy(const struct astro_site *site, double *ret_x, double *ret_y)
{
	double phi = site->lat_deg;
	double u = atan(0.99664719 * tand(phi));
	double e_rel = site->elevation_m / (EARTH_EQUATORIAL_RADIUS_KM * 1000.0);

	*ret_x = cos(u) + e_rel * cosd(phi);
	*ret_y = 0.99664719 * sin(u) + e_rel * sind(phi);
}

/* From geocentric apparent (alpha, delta) to the topocentric horizon, SPA
 * 3.10-3.15 (Meeus ch. 40 in SPA's notation). sin_parallax is the sine of
 * the equatorial horizontal parallax. ret_h_deg gets the topocentric hour
 * angle. */
void astro_topocentric(const struct astro_site *site, const struct astro_options *o,
		       double alpha_deg, double delta_deg, double nu_deg, double sin_parallax,
		       double radius_deg, struct astro_direction *ret_geometric,
		       struct astro_direction *ret_apparent, double *ret_h_deg)
{
	double phi = site->lat_deg, x, y;
	double h_deg = wrap360(nu_deg + site->lon_deg - alpha_deg);
	astro_observer_xy(site, &x, &y);
	double cd = cosd(delta_deg), ch = cosd(h_deg);
	double den = cd - x * sin_parallax * ch;
	double dalpha_deg = atan2d(-x * sin_parallax * sind(h_deg), den);
	double delta_p_deg = atan2d((sind(delta_deg) - y * sin_parallax) * cosd(dalpha_deg), den);
	double hp_deg = h_deg - dalpha_deg;

	double e0_deg = asind(sind(phi) * sind(delta_p_deg) + cosd(phi) * cosd(delta_p_deg) * cosd(hp_deg));
	double gamma_deg = atan2d(sind(hp_deg), cosd(hp_deg) * sind(phi) - tand(delta_p_deg) * cosd(phi));
	double azimuth_deg = wrap360(gamma_deg + 180.0);

	set_direction(ret_geometric, e0_deg, azimuth_deg);
	set_direction(ret_apparent, e0_deg + refraction_deg(e0_deg, radius_deg, o), azimuth_deg);
	if (ret_h_deg)
		*ret_h_deg = wrap180(hp_deg);
}

void astro_options_default(struct astro_options *ret)
{
	*ret = (struct astro_options){
		.delta_t_auto = true,
		.delta_t_s = 0.0,
		.delta_ut1_s = 0.0,
		.pressure_mbar = 1013.25,
		.temperature_c = 15.0,
		.horizon_refraction_deg = 0.5667,
	};
}

int astro_refuse(char *err, size_t err_size, const char *fmt, ...)
{
	va_list ap;

	if (err && err_size) {
		va_start(ap, fmt);
		vsnprintf(err, err_size, fmt, ap);
		va_end(ap);
	}
	return -EINVAL;
}

/* A finite number in [lo, hi]. NaN fails every comparison, hence the form. */
static bool in_range(double v, double lo, double hi)
{
	return v >= lo && v <= hi;
}

static int check_site(const struct astro_site *s, char *err, size_t err_size)
{
	if (!s)
		return astro_refuse(err, err_size, "site: missing");
	if (!in_range(s->lat_deg, -90.0, 90.0))
		return astro_refuse(err, err_size, "lat_deg: %g is not in [-90, 90]", s->lat_deg);
	if (!in_range(s->lon_deg, -180.0, 180.0))
		return astro_refuse(err, err_size, "lon_deg: %g is not in [-180, 180]", s->lon_deg);
	if (!in_range(s->elevation_m, -1000.0, 1e5))
		return astro_refuse(err, err_size, "elevation_m: %g is not in [-1000, 100000]",
				    s->elevation_m);
	return 0;
}

static int check_options(const struct astro_options *o, char *err, size_t err_size)
{
	if (!o->delta_t_auto && !in_range(o->delta_t_s, -1e6, 1e6))
		return astro_refuse(err, err_size, "delta_t_s: %g is not in [-1e6, 1e6]", o->delta_t_s);
	if (!(fabs(o->delta_ut1_s) < 1.0))
		return astro_refuse(err, err_size, "delta_ut1_s: %g is not in (-1, 1)", o->delta_ut1_s);
	if (!in_range(o->pressure_mbar, 0.0, 5000.0))
		return astro_refuse(err, err_size, "pressure_mbar: %g is not in [0, 5000]", o->pressure_mbar);
	/* The refraction formula divides by 273 + T and by e0 + 5.11: these
	 * ranges keep both well away from zero. */
	if (!in_range(o->temperature_c, -100.0, 100.0))
		return astro_refuse(err, err_size, "temperature_c: %g is not in [-100, 100]",
				    o->temperature_c);
	if (!in_range(o->horizon_refraction_deg, 0.0, 3.0))
		return astro_refuse(err, err_size, "horizon_refraction_deg: %g is not in [0, 3]",
				    o->horizon_refraction_deg);
	return 0;
}

/* SPA's stated range in POSIX seconds: years -2000..6000 inclusive. */
#define UTC_FIRST_S (-125281123200.0)	/* -2000-01-01T00:00:00Z */
#define UTC_END_S (127206115200.0)	/* 6001-01-01T00:00:00Z */

int astro_check_common(const struct astro_site *site, const struct astro_options *opt,
		       struct astro_options *ret_opt, char *err, size_t err_size)
{
	int r = check_site(site, err, err_size);

	if (r < 0)
		return r;
	if (opt) {
		if ((r = check_options(opt, err, err_size)) < 0)
			return r;
		*ret_opt = *opt;
	} else {
		astro_options_default(ret_opt);
	}
	return 0;
}

int astro_check_utc(double utc_s, char *err, size_t err_size)
{
	if (!(utc_s >= UTC_FIRST_S && utc_s < UTC_END_S))
		return astro_refuse(err, err_size, "utc: %g s is outside years -2000..6000", utc_s);
	return 0;
}

double astro_decimal_year(double utc_s)
{
	double days = floor(utc_s / 86400.0);
	/* Find the year by the mean Gregorian year, then correct by the calendar. */
	long year = (long)floor(1970.0 + days / 365.2425);
	long start;

	while ((start = simclock_days_from_civil(year, 1, 1)) > (long)days)
		year--;
	while (simclock_days_from_civil(year + 1, 1, 1) <= (long)days)
		year++;
	start = simclock_days_from_civil(year, 1, 1);
	double len = (double)(simclock_days_from_civil(year + 1, 1, 1) - start);
	return (double)year + (utc_s / 86400.0 - (double)start) / len;
}

double astro_delta_t_s(double y)
{
	double t, u;

	if (y < -500.0 || y >= 2150.0) {
		u = (y - 1820.0) / 100.0;
		return -20.0 + 32.0 * u * u;
	}
	if (y < 500.0) {
		u = y / 100.0;
		return 10583.6 + u * (-1014.41 + u * (33.78311 + u * (-5.952053 +
		       u * (-0.1798452 + u * (0.022174192 + u * 0.0090316521)))));
	}
	if (y < 1600.0) {
		u = (y - 1000.0) / 100.0;
		return 1574.2 + u * (-556.01 + u * (71.23472 + u * (0.319781 +
		       u * (-0.8503463 + u * (-0.005050998 + u * 0.0083572073)))));
	}
	if (y < 1700.0) {
		t = y - 1600.0;
		return 120.0 + t * (-0.9808 + t * (-0.01532 + t / 7129.0));
	}
	if (y < 1800.0) {
		t = y - 1700.0;
		return 8.83 + t * (0.1603 + t * (-0.0059285 + t * (0.00013336 - t / 1174000.0)));
	}
	if (y < 1860.0) {
		t = y - 1800.0;
		return 13.72 + t * (-0.332447 + t * (0.0068612 + t * (0.0041116 + t * (-0.00037436 +
		       t * (0.0000121272 + t * (-0.0000001699 + t * 0.000000000875))))));
	}
	if (y < 1900.0) {
		t = y - 1860.0;
		return 7.62 + t * (0.5737 + t * (-0.251754 + t * (0.01680668 +
		       t * (-0.0004473624 + t / 233174.0))));
	}
	if (y < 1920.0) {
		t = y - 1900.0;
		return -2.79 + t * (1.494119 + t * (-0.0598939 + t * (0.0061966 - t * 0.000197)));
	}
	if (y < 1941.0) {
		t = y - 1920.0;
		return 21.20 + t * (0.84493 + t * (-0.076100 + t * 0.0020936));
	}
	if (y < 1961.0) {
		t = y - 1950.0;
		return 29.07 + t * (0.407 + t * (-1.0 / 233.0 + t / 2547.0));
	}
	if (y < 1986.0) {
		t = y - 1975.0;
		return 45.45 + t * (1.067 + t * (-1.0 / 260.0 - t / 718.0));
	}
	if (y < 2005.0) {
		t = y - 2000.0;
		return 63.86 + t * (0.3345 + t * (-0.060374 + t * (0.0017275 +
		       t * (0.000651814 + t * 0.00002373599))));
	}
	if (y < 2050.0) {
		t = y - 2000.0;
		return 62.92 + t * (0.32217 + t * 0.005589);
	}
	u = (y - 1820.0) / 100.0;
	return -20.0 + 32.0 * u * u - 0.5628 * (2150.0 - y);
}

double astro_pick_delta_t_s(const struct astro_options *o, double utc_s)
{
	return o->delta_t_auto ? astro_delta_t_s(astro_decimal_year(utc_s)) : o->delta_t_s;
}

double astro_jd_of(double utc_s, const struct astro_options *o)
{
	return JD_UNIX_EPOCH + (utc_s + o->delta_ut1_s) / 86400.0;
}

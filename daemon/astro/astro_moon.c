/* astro_moon.c - the moon for a time and a place: Meeus ch. 47 (position),
 * 40 (parallax) and 48 (phase), and its light and colour. */
#include "astro_internal.h"

#include <math.h>
#include <stdlib.h>

#define MOON_RADIUS_KM 1737.4
#define MOON_MEAN_DISTANCE_KM 384400.0

/* Meeus table 47.A: multiples of D, M, M', F; then the longitude term
 * (1e-6 deg, sine) and the distance term (1e-3 km, cosine). */
struct moon_lr_term {
	signed char d, m, mp, f;
	double l, r;
};

static const struct moon_lr_term moon_lr[] = {
	{ 0, 0, 1, 0, 6288774, -20905355 }, { 2, 0, -1, 0, 1274027, -3699111 },
	{ 2, 0, 0, 0, 658314, -2955968 }, { 0, 0, 2, 0, 213618, -569925 },
	{ 0, 1, 0, 0, -185116, 48888 }, { 0, 0, 0, 2, -114332, -3149 },
	{ 2, 0, -2, 0, 58793, 246158 }, { 2, -1, -1, 0, 57066, -152138 },
	{ 2, 0, 1, 0, 53322, -170733 }, { 2, -1, 0, 0, 45758, -204586 },
	{ 0, 1, -1, 0, -40923, -129620 }, { 1, 0, 0, 0, -34720, 108743 },
	{ 0, 1, 1, 0, -30383, 104755 }, { 2, 0, 0, -2, 15327, 10321 },
	{ 0, 0, 1, 2, -12528, 0 }, { 0, 0, 1, -2, 10980, 79661 },
	{ 4, 0, -1, 0, 10675, -34782 }, { 0, 0, 3, 0, 10034, -23210 },
	{ 4, 0, -2, 0, 8548, -21636 }, { 2, 1, -1, 0, -7888, 24208 },
	{ 2, 1, 0, 0, -6766, 30824 }, { 1, 0, -1, 0, -5163, -8379 },
	{ 1, 1, 0, 0, 4987, -16675 }, { 2, -1, 1, 0, 4036, -12831 },
	{ 2, 0, 2, 0, 3994, -10445 }, { 4, 0, 0, 0, 3861, -11650 },
	{ 2, 0, -3, 0, 3665, 14403 }, { 0, 1, -2, 0, -2689, -7003 },
	{ 2, 0, -1, 2, -2602, 0 }, { 2, -1, -2, 0, 2390, 10056 },
	{ 1, 0, 1, 0, -2348, 6322 }, { 2, -2, 0, 0, 2236, -9884 },
	{ 0, 1, 2, 0, -2120, 5751 }, { 0, 2, 0, 0, -2069, 0 },
	{ 2, -2, -1, 0, 2048, -4950 }, { 2, 0, 1, -2, -1773, 4130 },
	{ 2, 0, 0, 2, -1595, 0 }, { 4, -1, -1, 0, 1215, -3958 },
	{ 0, 0, 2, 2, -1110, 0 }, { 3, 0, -1, 0, -892, 3258 },
	{ 2, 1, 1, 0, -810, 2616 }, { 4, -1, -2, 0, 759, -1897 },
	{ 0, 2, -1, 0, -713, -2117 }, { 2, 2, -1, 0, -700, 2354 },
	{ 2, 1, -2, 0, 691, 0 }, { 2, -1, 0, -2, 596, 0 },
	{ 4, 0, 1, 0, 549, -1423 }, { 0, 0, 4, 0, 537, -1117 },
	{ 4, -1, 0, 0, 520, -1571 }, { 1, 0, -2, 0, -487, -1739 },
	{ 2, 1, 0, -2, -399, 0 }, { 0, 0, 2, -2, -381, -4421 },
	{ 1, 1, 1, 0, 351, 0 }, { 3, 0, -2, 0, -340, 0 },
	{ 4, 0, -3, 0, 330, 0 }, { 2, -1, 2, 0, 327, 0 },
	{ 0, 2, 1, 0, -323, 1165 }, { 1, 1, -1, 0, 299, 0 },
	{ 2, 0, 3, 0, 294, 0 }, { 2, 0, -1, -2, 0, 8752 },
};

/* Meeus table 47.B: multiples of D, M, M', F; latitude term (1e-6 deg, sine). */
struct moon_b_term {
	signed char d, m, mp, f;
	double b;
};

static const struct moon_b_term moon_b[] = {
	{ 0, 0, 0, 1, 5128122 }, { 0, 0, 1, 1, 280602 }, { 0, 0, 1, -1, 277693 },
	{ 2, 0, 0, -1, 173237 }, { 2, 0, -1, 1, 55413 }, { 2, 0, -1, -1, 46271 },
	{ 2, 0, 0, 1, 32573 }, { 0, 0, 2, 1, 17198 }, { 2, 0, 1, -1, 9266 },
	{ 0, 0, 2, -1, 8822 }, { 2, -1, 0, -1, 8216 }, { 2, 0, -2, -1, 4324 },
	{ 2, 0, 1, 1, 4200 }, { 2, 1, 0, -1, -3359 }, { 2, -1, -1, 1, 2463 },
	{ 2, -1, 0, 1, 2211 }, { 2, -1, -1, -1, 2065 }, { 0, 1, -1, -1, -1870 },
	{ 4, 0, -1, -1, 1828 }, { 0, 1, 0, 1, -1794 }, { 0, 0, 0, 3, -1749 },
	{ 0, 1, -1, 1, -1565 }, { 1, 0, 0, 1, -1491 }, { 0, 1, 1, 1, -1475 },
	{ 0, 1, 1, -1, -1410 }, { 0, 1, 0, -1, -1344 }, { 1, 0, 0, -1, -1335 },
	{ 0, 0, 3, 1, 1107 }, { 4, 0, 0, -1, 1021 }, { 4, 0, -1, 1, 833 },
	{ 0, 0, 1, -3, 777 }, { 4, 0, -2, 1, 671 }, { 2, 0, 0, -3, 607 },
	{ 2, 0, 2, -1, 596 }, { 2, -1, 1, -1, 491 }, { 2, 0, -2, 1, -451 },
	{ 0, 0, 3, -1, 439 }, { 2, 0, 2, 1, 422 }, { 2, 0, -3, -1, 421 },
	{ 2, 1, -1, 1, -366 }, { 2, 1, 0, 1, -351 }, { 4, 0, 0, 1, 331 },
	{ 2, -1, 1, 1, 315 }, { 2, -2, 0, -1, 302 }, { 0, 0, 1, 3, -283 },
	{ 2, 1, 1, -1, -229 }, { 1, 1, 0, -1, 223 }, { 1, 1, 0, 1, 223 },
	{ 0, 1, -2, -1, -220 }, { 2, 1, -1, -1, -220 }, { 1, 0, 1, 1, -185 },
	{ 2, -1, -2, -1, 181 }, { 0, 1, 2, 1, -177 }, { 4, 0, -2, -1, 176 },
	{ 4, -1, -1, -1, 166 }, { 1, 0, 1, -1, -164 }, { 4, 0, 1, -1, 132 },
	{ 1, 0, -1, -1, -119 }, { 4, -1, 0, -1, 115 }, { 2, -2, 0, 1, 107 },
};

double astro_moon_illuminance_lx(double phase_angle_deg, double moon_distance_km,
				 double sun_distance_au)
{
	double a = fabs(phase_angle_deg);

	if (!(a < 180.0) || !(moon_distance_km > 0.0) || !(sun_distance_au > 0.0))
		return 0.0;
	double mag = -12.73 + 0.026 * a + 4e-9 * a * a * a * a;
	double dm = MOON_MEAN_DISTANCE_KM / moon_distance_km;
	return ASTRO_MOON_ILLUMINANCE_MAG0_LX * pow(10.0, -0.4 * mag) * dm * dm /
	       (sun_distance_au * sun_distance_au);
}

/* The moon reflects sunlight but reddens it: its colour index B-V is 0.92
 * against the sun's 0.65 (Allen), so its reflectance at 440 nm is
 * 10^(-0.4 * 0.27) = 0.78 of that at 550 nm. Taking the reflectance as
 * linear in wavelength over the visible (as lunar spectra roughly are)
 * gives 1.26 at 680 nm; normalized to Rec. 709 luminance that is about
 * (1.212, 0.962, 0.750) of the sunlight's colour. */
static void moon_color(double ret[3])
{
	double blue = pow(10.0, -0.4 * (0.92 - 0.65));
	double slope_per_nm = (1.0 - blue) / (550.0 - 440.0);
	double red = 1.0 + slope_per_nm * (680.0 - 550.0);
	double y = 0.2126 * red + 0.7152 * 1.0 + 0.0722 * blue;

	ret[0] = red / y;
	ret[1] = 1.0 / y;
	ret[2] = blue / y;
}

/* Geocentric ecliptic longitude and latitude (degrees, mean equinox of date)
 * and distance (km) at JCE, Meeus ch. 47. */
static void moon_geocentric(double t, double *ret_lambda_deg, double *ret_beta_deg,
			    double *ret_distance_km)
{
	double t2 = t * t, t3 = t2 * t, t4 = t3 * t;
	double lp = 218.3164477 + 481267.88123421 * t - 0.0015786 * t2 + t3 / 538841.0 -
		    t4 / 65194000.0;
	double d = 297.8501921 + 445267.1114034 * t - 0.0018819 * t2 + t3 / 545868.0 -
		   t4 / 113065000.0;
	double m = 357.5291092 + 35999.0502909 * t - 0.0001536 * t2 + t3 / 24490000.0;
	double mp = 134.9633964 + 477198.8675055 * t + 0.0087414 * t2 + t3 / 69699.0 -
		    t4 / 14712000.0;
	double f = 93.2720950 + 483202.0175233 * t - 0.0036539 * t2 - t3 / 3526000.0 +
		   t4 / 863310000.0;
	double a1 = 119.75 + 131.849 * t;
	double a2 = 53.09 + 479264.290 * t;
	double a3 = 313.45 + 481266.484 * t;
	/* The eccentricity of the earth's orbit shrinks the terms in M. */
	double e = 1.0 - 0.002516 * t - 0.0000074 * t2;
	double e_pow[3] = { 1.0, e, e * e };
	double sl = 0.0, sr = 0.0, sb = 0.0;

	d = wrap360(d) * DEG, m = wrap360(m) * DEG, mp = wrap360(mp) * DEG, f = wrap360(f) * DEG;
	for (size_t i = 0; i < N(moon_lr); i++) {
		const struct moon_lr_term *k = &moon_lr[i];
		double arg = k->d * d + k->m * m + k->mp * mp + k->f * f;
		double ef = e_pow[abs(k->m)];
		sl += k->l * ef * sin(arg);
		sr += k->r * ef * cos(arg);
	}
	for (size_t i = 0; i < N(moon_b); i++) {
		const struct moon_b_term *k = &moon_b[i];
		double arg = k->d * d + k->m * m + k->mp * mp + k->f * f;
		sb += k->b * e_pow[abs(k->m)] * sin(arg);
	}
	lp = wrap360(lp);
	sl += 3958.0 * sind(a1) + 1962.0 * sin(lp * DEG - f) + 318.0 * sind(a2);
	sb += -2235.0 * sind(lp) + 382.0 * sind(a3) + 175.0 * sin(a1 * DEG - f) +
	      175.0 * sin(a1 * DEG + f) + 127.0 * sin(lp * DEG - mp) - 115.0 * sin(lp * DEG + mp);

	*ret_lambda_deg = wrap360(lp + sl / 1e6);
	*ret_beta_deg = sb / 1e6;
	*ret_distance_km = 385000.56 + sr / 1000.0;
}

/* Observer to body: the geocentric vector less the observer's, in the
 * equatorial frame turned so that the observer's meridian is x. */
static double topocentric_distance_km(const struct astro_site *site, double distance_km,
				      double alpha_deg, double delta_deg, double nu_deg)
{
	double x, y;

	astro_observer_xy(site, &x, &y);
	double h_deg = nu_deg + site->lon_deg - alpha_deg;
	double bx = distance_km * cosd(delta_deg) * cosd(h_deg) - x * EARTH_EQUATORIAL_RADIUS_KM;
	double by = distance_km * cosd(delta_deg) * sind(h_deg);
	double bz = distance_km * sind(delta_deg) - y * EARTH_EQUATORIAL_RADIUS_KM;
	return sqrt(bx * bx + by * by + bz * bz);
}

int astro_moon(const struct astro_site *site, double utc_s, const struct astro_options *opt,
	       struct astro_moon *ret, char *err, size_t err_size)
{
	struct astro_options o;
	struct astro_moon m;
	struct astro_geo sun;
	double alpha_deg, delta_deg;
	int r;

	if ((r = astro_check_common(site, opt, &o, err, err_size)) < 0 ||
	    (r = astro_check_utc(utc_s, err, err_size)) < 0)
		return r;
	m.delta_t_s = astro_pick_delta_t_s(&o, utc_s);
	/* The sun's geocentric position comes along: it shares the time
	 * arguments, nutation and sidereal time, and gives the phase. */
	astro_sun_geocentric(astro_jd_of(utc_s, &o), m.delta_t_s, &sun);

	moon_geocentric(sun.jce, &m.longitude_deg, &m.latitude_deg, &m.distance_km);
	m.apparent_longitude_deg = wrap360(m.longitude_deg + sun.dpsi_deg);
	astro_ecliptic_to_equatorial(m.apparent_longitude_deg, m.latitude_deg, sun.eps_deg,
				     &alpha_deg, &delta_deg);
	m.right_ascension_deg = alpha_deg;
	m.declination_deg = delta_deg;

	double sin_parallax = EARTH_EQUATORIAL_RADIUS_KM / m.distance_km;
	/* The moon's radius is 0.2725 of the earth's: its angular radius is
	 * 0.2725 of its parallax; refraction stops below that, as for the sun. */
	astro_topocentric(site, &o, alpha_deg, delta_deg, sun.nu_deg, sin_parallax,
			  0.2725 * asind(sin_parallax), &m.geometric, &m.apparent, NULL);

	m.topocentric_distance_km = topocentric_distance_km(site, m.distance_km, alpha_deg,
							    delta_deg, sun.nu_deg);

	/* Meeus 48.2-48.3 with the sun's apparent place and distance. */
	double r_km = sun.r_au * AU_KM;
	double cos_psi = sind(sun.delta_deg) * sind(delta_deg) +
			 cosd(sun.delta_deg) * cosd(delta_deg) * cosd(sun.alpha_deg - alpha_deg);
	double psi_deg = acos(fmin(1.0, fmax(-1.0, cos_psi))) / DEG;
	m.elongation_deg = psi_deg;
	m.phase_angle_deg = atan2d(r_km * sind(psi_deg), m.distance_km - r_km * cos_psi);
	m.illuminated_fraction = (1.0 + cosd(m.phase_angle_deg)) / 2.0;
	m.waxing = wrap360(m.apparent_longitude_deg - sun.lambda_deg) < 180.0;
	m.angular_radius_deg = asind(MOON_RADIUS_KM / m.topocentric_distance_km);
	m.illuminance_lx = astro_moon_illuminance_lx(m.phase_angle_deg, m.topocentric_distance_km,
						     sun.r_au);
	moon_color(m.color);
	*ret = m;
	return 0;
}

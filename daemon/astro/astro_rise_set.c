/* astro_rise_set.c - sun rise, transit and set and the three twilights of a
 * local calendar day, SPA appendix A.2 counted from local midnight. */
#include "astro_internal.h"

#include <math.h>

#include "simclock.h"

/* The three daily positions (at 0 TT of the day before, the day, the day
 * after local midnight) and the sidereal time at local midnight. */
struct rts_day {
	double nu_deg;
	double alpha_deg[3], delta_deg[3];
	double delta_t_s;
	double lat_deg, lon_deg;
};

/* Newton steps for an event, and the step (days, 1 ms) that ends them. */
#define RTS_MAX_STEPS 5
#define RTS_STEP_DONE 1e-8

/* Interpolated right ascension or declination at n days from the middle
 * point, A.2.8. Differences of right ascension are taken the short way
 * round, where the report folds them into [0, 1) and loses a degree at
 * the wrap. */
static double interpolate(const double v[3], double n, bool angle)
{
	double a = v[1] - v[0], b = v[2] - v[1];

	if (angle)
		a = wrap180(a), b = wrap180(b);
	return v[1] + n * (a + b + (b - a) * n) / 2.0;
}

/* Elevation of the sun's centre (geocentric) at day fraction m, with its
 * local hour angle and declination there, A.2.6-A.2.10. */
static double rts_elevation(const struct rts_day *d, double m, double *ret_h_deg,
			    double *ret_delta_deg)
{
	double nu = d->nu_deg + 360.985647 * m;
	double n = m + d->delta_t_s / 86400.0;
	double alpha = interpolate(d->alpha_deg, n, true);
	double delta = interpolate(d->delta_deg, n, false);
	double h = wrap180(nu + d->lon_deg - alpha);

	*ret_h_deg = h;
	*ret_delta_deg = delta;
	return asind(sind(d->lat_deg) * sind(delta) + cosd(d->lat_deg) * cosd(delta) * cosd(h));
}

static void rise_set(const struct rts_day *d, double m0, double threshold_deg, double midnight_s,
		     double dut1_s, struct astro_rise_set *ret)
{
	double phi = d->lat_deg, delta0 = d->delta_deg[1];
	double arg = (sind(threshold_deg) - sind(phi) * sind(delta0)) / (cosd(phi) * cosd(delta0));

	ret->threshold_deg = threshold_deg;
	ret->rise_utc_s = ret->set_utc_s = NAN;
	/* Written so that a NaN (a pole, where cos(phi) is 0 and sin(phi) is
	 * +-1) cannot fall through as "rises and sets". */
	if (!(arg >= -1.0)) {
		ret->kind = ASTRO_ALWAYS_ABOVE;
		return;
	}
	if (!(arg <= 1.0)) {
		ret->kind = ASTRO_ALWAYS_BELOW;
		return;
	}
	ret->kind = ASTRO_RISES_AND_SETS;
	double h0_deg = acos(arg) / DEG;
	double m[2] = { wrap01(m0 - h0_deg / 360.0), wrap01(m0 + h0_deg / 360.0) };
	double *out[2] = { &ret->rise_utc_s, &ret->set_utc_s };
	for (int i = 0; i < 2; i++) {
		/* A.2.12-A.2.13 is one Newton step on the elevation; the report
		 * stops there, which leaves up to ~0.01 deg (seconds) at the
		 * twilights where the first guess is far. Repeating the step
		 * until it stalls changes the report's own example by < 0.1 s. */
		double frac = m[i];
		for (int k = 0; k < RTS_MAX_STEPS; k++) {
			double h_deg, delta_deg;
			double e = rts_elevation(d, frac, &h_deg, &delta_deg);
			double step = (e - threshold_deg) /
				      (360.0 * cosd(delta_deg) * cosd(phi) * sind(h_deg));
			if (!isfinite(step))
				break;
			frac += step;
			if (fabs(step) < RTS_STEP_DONE)
				break;
		}
		*out[i] = midnight_s + frac * 86400.0 - dut1_s;
	}
}

static int check_date(const struct astro_date *dt, char *err, size_t err_size)
{
	if (!dt)
		return astro_refuse(err, err_size, "date: missing");
	if (dt->year < -2000 || dt->year > 6000)
		return astro_refuse(err, err_size, "year: %d is not in [-2000, 6000]", dt->year);
	if (dt->month < 1 || dt->month > 12)
		return astro_refuse(err, err_size, "month: %d is not in [1, 12]", dt->month);
	if (!simclock_valid_date(dt->year, dt->month, dt->day))
		return astro_refuse(err, err_size, "day: %d is not a day of %04d-%02d", dt->day, dt->year,
				    dt->month);
	if (dt->utc_offset_min < -1080 || dt->utc_offset_min > 1080)
		return astro_refuse(err, err_size, "utc_offset_min: %d is not in [-1080, 1080]",
				    dt->utc_offset_min);
	return 0;
}

int astro_sun_times(const struct astro_site *site, const struct astro_date *date,
		    const struct astro_options *opt, struct astro_times *ret,
		    char *err, size_t err_size)
{
	struct astro_options o;
	struct astro_times t;
	struct rts_day d;
	struct astro_geo g;
	int r;

	if ((r = astro_check_common(site, opt, &o, err, err_size)) < 0 ||
	    (r = check_date(date, err, err_size)) < 0)
		return r;
	double midnight_s = (double)simclock_days_from_civil(date->year, date->month, date->day) *
			    86400.0 - date->utc_offset_min * 60.0;
	/* The day's local midnight in UT1: the report's 0 h UT, moved. */
	double jd0 = JD_UNIX_EPOCH + midnight_s / 86400.0;

	d.delta_t_s = astro_pick_delta_t_s(&o, midnight_s + 43200.0);
	d.lat_deg = site->lat_deg;
	d.lon_deg = site->lon_deg;
	/* A.2.1-A.2.2: sidereal time at midnight, positions at 0 TT. */
	for (int i = 0; i < 3; i++) {
		astro_sun_geocentric(jd0 + i - 1, 0.0, &g);
		d.alpha_deg[i] = g.alpha_deg;
		d.delta_deg[i] = g.delta_deg;
		if (i == 1)
			d.nu_deg = g.nu_deg;
	}
	double m0 = wrap01((d.alpha_deg[1] - d.lon_deg - d.nu_deg) / 360.0);
	/* A.2.11, repeated like the rise and set steps. */
	double transit = m0;
	for (int k = 0; k < RTS_MAX_STEPS; k++) {
		double h_deg, delta_deg;
		rts_elevation(&d, transit, &h_deg, &delta_deg);
		transit -= h_deg / 360.0;
		if (fabs(h_deg / 360.0) < RTS_STEP_DONE)
			break;
	}
	t.transit_utc_s = midnight_s + transit * 86400.0 - o.delta_ut1_s;

	rise_set(&d, m0, -(SUN_RADIUS_SPA_DEG + o.horizon_refraction_deg), midnight_s,
		 o.delta_ut1_s, &t.sunrise_sunset);
	rise_set(&d, m0, -6.0, midnight_s, o.delta_ut1_s, &t.civil);
	rise_set(&d, m0, -12.0, midnight_s, o.delta_ut1_s, &t.nautical);
	rise_set(&d, m0, -18.0, midnight_s, o.delta_ut1_s, &t.astronomical);

	struct astro_sun at_noon;
	if ((r = astro_sun(site, t.transit_utc_s, &o, &at_noon, err, err_size)) < 0)
		return r;
	t.transit_elevation_deg = at_noon.geometric.elevation_deg;
	*ret = t;
	return 0;
}

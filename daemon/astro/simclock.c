/* simclock.c - simulated UTC against the monotonic clock, and its ISO 8601 text. */
#include "simclock.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

/* The clock is a line through one anchor point: re-anchoring at every change
 * keeps the simulated time continuous when the rate changes. */
struct simclock {
	double anchor_utc_s;
	double anchor_mono_s;
	double rate;
};

int simclock_new(double mono_s, struct simclock **ret)
{
	struct simclock *c;

	if (!ret || !isfinite(mono_s))
		return -EINVAL;
	c = calloc(1, sizeof(*c));
	if (!c)
		return -ENOMEM;
	c->anchor_mono_s = mono_s;
	c->rate = 1.0;
	*ret = c;
	return 0;
}

void simclock_free(struct simclock *c)
{
	free(c);
}

double simclock_utc_s(const struct simclock *c, double mono_s)
{
	return c->anchor_utc_s + c->rate * (mono_s - c->anchor_mono_s);
}

double simclock_rate(const struct simclock *c)
{
	return c->rate;
}

int simclock_set_utc(struct simclock *c, double utc_s, double mono_s)
{
	if (!isfinite(utc_s) || !isfinite(mono_s))
		return -EINVAL;
	c->anchor_utc_s = utc_s;
	c->anchor_mono_s = mono_s;
	return 0;
}

int simclock_set_rate(struct simclock *c, double rate, double mono_s)
{
	if (!isfinite(rate) || fabs(rate) > SIMCLOCK_RATE_MAX || !isfinite(mono_s))
		return -EINVAL;
	c->anchor_utc_s = simclock_utc_s(c, mono_s);
	c->anchor_mono_s = mono_s;
	c->rate = rate;
	return 0;
}

int simclock_set_now(struct simclock *c, double real_utc_s, double mono_s)
{
	int r = simclock_set_utc(c, real_utc_s, mono_s);

	if (r < 0)
		return r;
	c->rate = 1.0;
	return 0;
}

int simclock_mono_for_utc(const struct simclock *c, double utc_s, double *ret_mono_s)
{
	if (!isfinite(utc_s))
		return -EINVAL;
	if (c->rate == 0.0)
		return -ERANGE;
	*ret_mono_s = c->anchor_mono_s + (utc_s - c->anchor_utc_s) / c->rate;
	return 0;
}

void simclock_read_clocks(double *ret_real_utc_s, double *ret_mono_s)
{
	struct timespec ts;

	if (ret_real_utc_s) {
		clock_gettime(CLOCK_REALTIME, &ts);
		*ret_real_utc_s = (double)ts.tv_sec + ts.tv_nsec * 1e-9;
	}
	if (ret_mono_s) {
		clock_gettime(CLOCK_MONOTONIC, &ts);
		*ret_mono_s = (double)ts.tv_sec + ts.tv_nsec * 1e-9;
	}
}

/* Days from 1970-01-01, by 400-year eras starting in March so that the leap
 * day falls at the end of each year (the well-known civil-from-days scheme). */
long simclock_days_from_civil(long year, int month, int day)
{
	long y = year - (month <= 2);
	long era = (y >= 0 ? y : y - 399) / 400;
	long yoe = y - era * 400;
	long doy = (153L * (month > 2 ? month - 3 : month + 9) + 2) / 5 + day - 1;
	long doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
	return era * 146097 + doe - 719468;
}

/* The inverse of simclock_days_from_civil. */
static void civil_from_days(long z, long *ret_year, int *ret_month, int *ret_day)
{
	z += 719468;
	long era = (z >= 0 ? z : z - 146096) / 146097;
	long doe = z - era * 146097;
	long yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
	long doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
	long mp = (5 * doy + 2) / 153;
	int d = (int)(doy - (153 * mp + 2) / 5 + 1);
	int m = (int)(mp < 10 ? mp + 3 : mp - 9);
	*ret_year = yoe + era * 400 + (m <= 2);
	*ret_month = m;
	*ret_day = d;
}

int simclock_valid_date(long year, int month, int day)
{
	static const int days_in[12] = { 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31 };

	if (month < 1 || month > 12 || day < 1)
		return 0;
	int leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
	int n = days_in[month - 1] + (month == 2 && leap);
	return day <= n;
}

/* Reads exactly n decimal digits; -1 if any is not a digit. Digits are
 * checked by value, not isdigit(), which depends on the locale. */
static long digits(const char **p, int n)
{
	long v = 0;

	for (int i = 0; i < n; i++) {
		char ch = (*p)[i];
		if (ch < '0' || ch > '9')
			return -1;
		v = v * 10 + (ch - '0');
	}
	*p += n;
	return v;
}

static int expect(const char **p, char ch)
{
	if (**p != ch)
		return 0;
	(*p)++;
	return 1;
}

int simclock_parse_utc(const char *text, double *ret_utc_s)
{
	const char *p = text;
	long year, month, day, hour, minute, second = 0, off_h = 0, off_m = 0;
	double frac = 0.0;
	int sign = 0;

	if (!text || !ret_utc_s)
		return -EINVAL;
	if ((year = digits(&p, 4)) < 0 || !expect(&p, '-') ||
	    (month = digits(&p, 2)) < 0 || !expect(&p, '-') ||
	    (day = digits(&p, 2)) < 0)
		return -EINVAL;
	if (!expect(&p, 'T') && !expect(&p, 't'))
		return -EINVAL;
	if ((hour = digits(&p, 2)) < 0 || !expect(&p, ':') || (minute = digits(&p, 2)) < 0)
		return -EINVAL;
	if (expect(&p, ':')) {
		if ((second = digits(&p, 2)) < 0)
			return -EINVAL;
		if (expect(&p, '.')) {
			double scale = 0.1;
			int n = 0;
			for (; *p >= '0' && *p <= '9'; p++, n++) {
				if (n == 9)
					return -EINVAL;
				frac += (*p - '0') * scale;
				scale *= 0.1;
			}
			if (n == 0)
				return -EINVAL;
		}
	}
	if (expect(&p, 'Z') || expect(&p, 'z')) {
		sign = 0;
	} else if (*p == '+' || *p == '-') {
		sign = *p++ == '+' ? 1 : -1;
		if ((off_h = digits(&p, 2)) < 0)
			return -EINVAL;
		expect(&p, ':');
		if ((off_m = digits(&p, 2)) < 0)
			return -EINVAL;
	} else {
		return -EINVAL;
	}
	if (*p != '\0')
		return -EINVAL;
	if (!simclock_valid_date(year, (int)month, (int)day) || hour > 23 || minute > 59 ||
	    second > 59 || off_h > 23 || off_m > 59)
		return -EINVAL;

	long days = simclock_days_from_civil(year, (int)month, (int)day);
	double s = (double)days * 86400.0 + (double)(hour * 3600 + minute * 60 + second);
	s -= sign * (double)(off_h * 3600 + off_m * 60);
	*ret_utc_s = s + frac;
	return 0;
}

int simclock_format_utc(double utc_s, char *buf, size_t size)
{
	/* Years 0..9999 in POSIX seconds. */
	static const double first_s = -62167219200.0, end_s = 253402300800.0;
	long year;
	int month, day, n;

	if (!buf || !isfinite(utc_s) || utc_s < first_s || utc_s >= end_s)
		return -EINVAL;
	/* Round to whole microseconds first so that 59.9999996 carries into the
	 * next minute instead of printing "60". */
	double us = round(utc_s * 1e6);
	double whole_s = floor(us / 1e6);
	long frac_us = (long)(us - whole_s * 1e6);
	long days = (long)floor(whole_s / 86400.0);
	long sod = (long)(whole_s - (double)days * 86400.0);

	civil_from_days(days, &year, &month, &day);
	if (year > 9999)
		return -EINVAL;
	n = snprintf(buf, size, "%04ld-%02d-%02dT%02ld:%02ld:%02ld", year, month, day,
		     sod / 3600, sod / 60 % 60, sod % 60);
	if (n < 0 || (size_t)n >= size)
		return -ENOSPC;
	if (frac_us) {
		char f[8];
		int len = 6;
		snprintf(f, sizeof(f), "%06ld", frac_us);
		while (f[len - 1] == '0')
			len--;
		int m = snprintf(buf + n, size - (size_t)n, ".%.*s", len, f);
		if (m < 0 || (size_t)(n + m) >= size)
			return -ENOSPC;
		n += m;
	}
	if ((size_t)n + 2 > size)
		return -ENOSPC;
	buf[n++] = 'Z';
	buf[n] = '\0';
	return n;
}

/* test_simclock.c - the simulation clock's arithmetic and its ISO 8601 text. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "simclock.h"
#include "test.h"

#define NEAR(a, b, tol) (fabs((a) - (b)) <= (tol))

/* 2026-06-21T18:30:00Z */
static const double solstice_s = 1782066600.0;

static void test_rates(void)
{
	struct simclock *c;
	double mono_s = 1000.0;

	CHECK_EQ(simclock_new(mono_s, &c), 0);
	CHECK_EQ(simclock_rate(c), 1.0);
	CHECK_EQ(simclock_set_utc(c, solstice_s, mono_s), 0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 10.0), solstice_s + 10.0);

	/* Rate 60: an hour a minute. */
	CHECK_EQ(simclock_set_rate(c, 60.0, mono_s), 0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 60.0), solstice_s + 3600.0);

	/* The change of rate keeps the time continuous: 1 min at 60x, then freeze. */
	CHECK_EQ(simclock_set_rate(c, 0.0, mono_s + 60.0), 0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 60.0), solstice_s + 3600.0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 1e6), solstice_s + 3600.0);

	/* Backward at 2x from there. */
	CHECK_EQ(simclock_set_rate(c, -2.0, mono_s + 100.0), 0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 110.0), solstice_s + 3600.0 - 20.0);

	/* Setting the time keeps the rate. */
	CHECK_EQ(simclock_set_utc(c, solstice_s, mono_s + 200.0), 0);
	CHECK_EQ(simclock_rate(c), -2.0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 201.0), solstice_s - 2.0);

	/* Refusals leave the clock as it was. */
	CHECK_EQ(simclock_set_rate(c, NAN, mono_s), -EINVAL);
	CHECK_EQ(simclock_set_rate(c, INFINITY, mono_s), -EINVAL);
	CHECK_EQ(simclock_set_rate(c, 2 * SIMCLOCK_RATE_MAX, mono_s), -EINVAL);
	CHECK_EQ(simclock_set_utc(c, NAN, mono_s), -EINVAL);
	CHECK_EQ(simclock_rate(c), -2.0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 201.0), solstice_s - 2.0);

	simclock_free(c);
	simclock_free(NULL);
}

static void test_now_and_timers(void)
{
	struct simclock *c;
	double real_s, mono_s, at_s;

	simclock_read_clocks(&real_s, &mono_s);
	CHECK(real_s > 1.6e9 && mono_s > 0.0);
	CHECK_EQ(simclock_new(mono_s, &c), 0);
	CHECK_EQ(simclock_set_rate(c, 3600.0, mono_s), 0);
	CHECK_EQ(simclock_set_now(c, real_s, mono_s + 5.0), 0);
	CHECK_EQ(simclock_rate(c), 1.0);
	CHECK_EQ(simclock_utc_s(c, mono_s + 5.0), real_s);
	CHECK_NEAR(simclock_utc_s(c, mono_s + 65.0), real_s + 60.0, 1e-6);

	/* When does the clock reach a target? */
	CHECK_EQ(simclock_set_utc(c, solstice_s, 100.0), 0);
	CHECK_EQ(simclock_set_rate(c, 60.0, 100.0), 0);
	CHECK_EQ(simclock_mono_for_utc(c, solstice_s + 3600.0, &at_s), 0);
	CHECK_EQ(at_s, 160.0);
	CHECK_EQ(simclock_set_rate(c, -60.0, 100.0), 0);
	CHECK_EQ(simclock_mono_for_utc(c, solstice_s - 3600.0, &at_s), 0);
	CHECK_EQ(at_s, 160.0);
	CHECK_EQ(simclock_set_rate(c, 0.0, 100.0), 0);
	CHECK_EQ(simclock_mono_for_utc(c, solstice_s + 1.0, &at_s), -ERANGE);
	simclock_free(c);
}

static void test_parse(void)
{
	static const struct {
		const char *text;
		double utc_s;
	} good[] = {
		{ "2026-06-21T18:30:00Z", 1782066600.0 },
		{ "2026-06-21t18:30:00z", 1782066600.0 },
		{ "2026-06-21T18:30Z", 1782066600.0 },
		{ "2026-06-21T20:30:00+02:00", 1782066600.0 },
		{ "2026-06-21T20:30:00+0200", 1782066600.0 },
		{ "2026-06-21T13:00:00-05:30", 1782066600.0 },
		{ "2026-06-21T18:30:00.25Z", 1782066600.25 },
		{ "2026-06-21T18:30:00.123456789Z", 1782066600.123456789 },
		{ "1970-01-01T00:00:00Z", 0.0 },
		{ "1969-12-31T23:59:59Z", -1.0 },
		{ "1900-01-01T00:00:00Z", -2208988800.0 },
		{ "2000-02-29T12:00:00Z", 951825600.0 },
		{ "2100-01-01T00:00:00Z", 4102444800.0 },
		{ "2003-10-17T12:30:30-07:00", 1066419030.0 },
	};
	for (size_t i = 0; i < sizeof(good) / sizeof(good[0]); i++) {
		double s = -1e300;
		int r = simclock_parse_utc(good[i].text, &s);
		if (r != 0 || !NEAR(s, good[i].utc_s, 1e-6))
			FAIL("'%s': r %d, %.6f, want %.6f", good[i].text, r, s, good[i].utc_s);
		else
			test_checks++;
	}

	static const char *bad[] = {
		"", "now", "2026-13-01T00:00:00Z", "2026-00-10T00:00:00Z", "2026-01-32T00:00:00Z",
		"2026-02-29T00:00:00Z", "1900-02-29T00:00:00Z", "2026-04-31T00:00:00Z",
		"2026-06-21T25:00:00Z", "2026-06-21T24:00:00Z", "2026-06-21T12:60:00Z",
		"2026-06-21T12:00:60Z", "2026-06-21T12:00:00", "2026-06-21T12:00:00Zjunk",
		"2026-06-21T12:00:00Z ", " 2026-06-21T12:00:00Z", "2026-06-21 12:00:00Z",
		"2026-06-21", "2026-6-21T12:00:00Z", "26-06-21T12:00:00Z", "+2026-06-21T12:00:00Z",
		"2026-06-21T12:00:00.Z", "2026-06-21T12:00:00.1234567890Z",
		"2026-06-21T12:00:00+24:00", "2026-06-21T12:00:00+02:60", "2026-06-21T12:00:00+2",
		"2026-06-21T12:00:00+02:0", "2026-06-21T12:00:00,5Z", "2026-06-21T12:00:0Z",
		"2026-06-21T12:00:00\nZ", "2026-06-21T12:00:00ZZ", "２026-06-21T12:00:00Z",
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		double s = 42.0;
		int r = simclock_parse_utc(bad[i], &s);
		if (r != -EINVAL || s != 42.0)
			FAIL("'%s' accepted (r %d, %.3f)", bad[i], r, s);
		else
			test_checks++;
	}
	CHECK(simclock_parse_utc(NULL, &(double){ 0 }) == -EINVAL);
}

static void test_format(void)
{
	char buf[SIMCLOCK_UTC_TEXT_MAX];
	double back;

	CHECK_EQ(simclock_format_utc(solstice_s, buf, sizeof(buf)), 20);
	CHECK(strcmp(buf, "2026-06-21T18:30:00Z") == 0);
	CHECK(simclock_format_utc(-1.0, buf, sizeof(buf)) > 0);
	CHECK(strcmp(buf, "1969-12-31T23:59:59Z") == 0);
	CHECK(simclock_format_utc(solstice_s + 0.25, buf, sizeof(buf)) > 0);
	CHECK(strcmp(buf, "2026-06-21T18:30:00.25Z") == 0);
	/* Rounding carries into the next minute rather than printing :60. */
	CHECK(simclock_format_utc(solstice_s - 1e-7, buf, sizeof(buf)) > 0);
	CHECK(strcmp(buf, "2026-06-21T18:30:00Z") == 0);
	CHECK_EQ(simclock_format_utc(solstice_s + 0.123456, buf, sizeof(buf)), SIMCLOCK_UTC_TEXT_MAX - 1);
	CHECK(strcmp(buf, "2026-06-21T18:30:00.123456Z") == 0);
	CHECK(simclock_format_utc(253402300799.5, buf, sizeof(buf)) > 0);
	CHECK(strcmp(buf, "9999-12-31T23:59:59.5Z") == 0);
	CHECK_EQ(simclock_format_utc(253402300800.0, buf, sizeof(buf)), -EINVAL);

	CHECK_EQ(simclock_format_utc(solstice_s, buf, 20), -ENOSPC);
	CHECK_EQ(simclock_format_utc(NAN, buf, sizeof(buf)), -EINVAL);
	CHECK_EQ(simclock_format_utc(1e15, buf, sizeof(buf)), -EINVAL);

	/* Round trip over four millennia with a fixed-seed generator: whole
	 * seconds come back exactly, fractions to the microsecond. */
	unsigned long long x = 0x9e3779b97f4a7c15ull;
	for (int i = 0; i < 20000; i++) {
		x ^= x << 13, x ^= x >> 7, x ^= x << 17;
		double s = -5e10 + (double)(x % 300000000000ull);
		if (i & 1)
			s += (double)(x % 1000000) * 1e-6;
		if (simclock_format_utc(s, buf, sizeof(buf)) <= 0 ||
		    simclock_parse_utc(buf, &back) != 0 || fabs(back - s) > 5e-7 + fabs(s) * 1e-15) {
			FAIL("round trip %.6f -> '%s' -> %.6f", s, buf, back);
			break;
		}
	}
	test_checks++;
}

static void test_calendar(void)
{
	CHECK_EQ(simclock_days_from_civil(1970, 1, 1), 0);
	CHECK_EQ(simclock_days_from_civil(2000, 3, 1), 11017);
	CHECK_EQ(simclock_days_from_civil(1600, 1, 1), -135140);
	CHECK(simclock_valid_date(2000, 2, 29));
	CHECK(!simclock_valid_date(2100, 2, 29));
	CHECK(simclock_valid_date(2024, 2, 29));
	CHECK(!simclock_valid_date(2026, 13, 1));
	CHECK(!simclock_valid_date(2026, 6, 31));
}

int main(void)
{
	test_rates();
	test_now_and_timers();
	test_parse();
	test_format();
	test_calendar();
	return test_report("test_simclock");
}

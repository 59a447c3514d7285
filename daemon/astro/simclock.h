/* simclock.h - the simulation clock: a UTC time that runs at a settable rate
 * against the monotonic clock, and the ISO 8601 UTC text form of a time.
 *
 * The clock is pure arithmetic: every call that needs "the time now" takes
 * the monotonic reading (seconds, CLOCK_MONOTONIC) from the caller, so the
 * clock is testable without sleeping and never reads a clock behind the
 * caller's back. simclock_read_clocks() is the one helper that reads the real
 * clocks, for the daemon's loop.
 *
 * Times are POSIX seconds since 1970-01-01T00:00:00Z (no leap seconds, the
 * proleptic Gregorian calendar), as a double: about 0.25 us resolution today.
 * Not thread-safe; one owner (the event loop) calls it.
 */
#ifndef SKYD_SIMCLOCK_H
#define SKYD_SIMCLOCK_H

#include <stddef.h>

/* Largest |rate| simclock_set_rate() accepts: a million simulated seconds
 * (11.6 days) per real second is beyond any use and keeps arithmetic sane. */
#define SIMCLOCK_RATE_MAX 1e6

/* Longest text simclock_format_utc() writes, terminator included:
 * "9999-12-31T23:59:59.999999Z". */
#define SIMCLOCK_UTC_TEXT_MAX 28

struct simclock;

/* A clock frozen nowhere in particular: utc 0, rate 1, anchored at mono_s.
 * Returns 0 or -ENOMEM; *ret gets the clock. */
int simclock_new(double mono_s, struct simclock **ret);
void simclock_free(struct simclock *c);

/* The simulated UTC time (POSIX seconds) at the monotonic time mono_s:
 * anchor_utc + rate * (mono_s - anchor_mono). */
double simclock_utc_s(const struct simclock *c, double mono_s);

/* Seconds of simulated time per second of monotonic time. */
double simclock_rate(const struct simclock *c);

/* Sets the simulated time to utc_s at monotonic time mono_s; the rate stays.
 * -EINVAL if either is not finite. */
int simclock_set_utc(struct simclock *c, double utc_s, double mono_s);

/* Sets the rate from mono_s on: 60 = an hour a minute, 1 = real time,
 * 0 = frozen, negative = backward. The simulated time is continuous across
 * the change. -EINVAL if not finite or |rate| > SIMCLOCK_RATE_MAX. */
int simclock_set_rate(struct simclock *c, double rate, double mono_s);

/* Real time at rate 1: the simulated time becomes real_utc_s (the caller's
 * CLOCK_REALTIME reading) at mono_s, and the rate becomes 1. */
int simclock_set_now(struct simclock *c, double real_utc_s, double mono_s);

/* The monotonic time at which the simulated time is utc_s, for arming a
 * timer. -ERANGE if the clock is frozen. A time the clock has passed (or,
 * running backward, has not reached) gives a ret_mono_s in the past: the
 * caller compares it with its own monotonic reading. */
int simclock_mono_for_utc(const struct simclock *c, double utc_s, double *ret_mono_s);

/* Reads CLOCK_REALTIME and CLOCK_MONOTONIC as seconds. Either may be NULL. */
void simclock_read_clocks(double *ret_real_utc_s, double *ret_mono_s);

/* Parses an ISO 8601 / RFC 3339 date-time with an explicit zone:
 * YYYY-MM-DDTHH:MM[:SS[.fraction]] then Z or +HH:MM / -HH:MM (or +HHMM).
 * 'T' and 'Z' may be lower case. Year 0000..9999, fraction up to 9 digits,
 * seconds 00..59 (leap second 60 is refused: POSIX time has none).
 * Returns 0 and sets *ret_utc_s, or -EINVAL on anything else: out-of-range
 * fields (month 13, day 32, Feb 29 in a common year, hour 24), a missing
 * zone (local time is ambiguous in a daemon), blanks, trailing junk. */
int simclock_parse_utc(const char *text, double *ret_utc_s);

/* Formats utc_s as "YYYY-MM-DDTHH:MM:SS[.ffffff]Z": microseconds, trailing
 * zeros dropped, no fraction at all for a whole second, so that
 * simclock_parse_utc() reads back the same time to within 0.5 us.
 * Returns the length written (without the terminator), -ENOSPC if size is
 * too small, -EINVAL if utc_s is not finite or outside years 0..9999. */
int simclock_format_utc(double utc_s, char *buf, size_t size);

/* Days from 1970-01-01 to the given proleptic Gregorian date (negative
 * before); no range check. Shared with astro for calendar dates. */
long simclock_days_from_civil(long year, int month, int day);

/* 1 if (year, month, day) is a real date of the proleptic Gregorian
 * calendar, else 0. */
int simclock_valid_date(long year, int month, int day);

#endif

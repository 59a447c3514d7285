/* test_sensor_math.c - the sensor's pure parts: the reading pipeline
 * (refusals, smoothing, hysteresis, rate limit, staleness), horizontal
 * illuminance from tables, the inversion of a clear-sky curve, EV100. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sensor.h"
#include "test.h"

#define REL(a, b, tol) (fabs((a) - (b)) <= (tol) * fabs(b))
#define MS 1000000ull
#define SEC 1000000000ull

static void test_ev100(void)
{
	CHECK_NEAR(sensor_ev100(2.5), 0.0, 1e-12);	/* E = C / S */
	CHECK_NEAR(sensor_ev100(5.0), 1.0, 1e-12);
	/* Bright sun, 100 klx: EV100 15.29 (the "sunny 16" rule's 15). */
	CHECK_NEAR(sensor_ev100(100000.0), log2(40000.0), 1e-12);
	CHECK_NEAR(sensor_ev100(100000.0), 15.2877, 1e-4);
	CHECK(isinf(sensor_ev100(0.0)) && sensor_ev100(0.0) < 0.0);
	CHECK(isnan(sensor_ev100(-1.0)));
}

static void test_curve(void)
{
	const struct sensor_curve *c = &sensor_curve_usno;
	double el, k;

	/* The samples themselves come back. */
	for (size_t i = 0; i < c->n; i++) {
		CHECK(sensor_curve_invert(c, c->lux[i], &el, NULL) == 0);
		CHECK_NEAR(el, c->elevation_deg[i], 1e-9);
	}
	/* Linear in ln(E): the geometric mean of two samples is half way. */
	CHECK_EQ(sensor_curve_invert(c, sqrt(3.4 * 464.0), &el, &k), 0);
	CHECK_NEAR(el, -3.4, 1e-9);
	/* Civil twilight is well conditioned: about a degree per unit of ln E
	 * (a 10 % error moves the answer by 0.1 deg)... */
	CHECK(k > 0.9 && k < 1.2);
	/* ...high sun is not: over 100 deg per unit of ln E. */
	CHECK_EQ(sensor_curve_invert(c, 120000.0, &el, &k), 0);
	CHECK(el > 60.0 && el < 90.0 && k > 100.0);
	/* Outside the curve, and nonsense. */
	el = 12345.0;
	CHECK(sensor_curve_invert(c, 0.002, &el, NULL) == -ERANGE);
	CHECK(sensor_curve_invert(c, 200000.0, &el, NULL) == -ERANGE);
	CHECK(sensor_curve_invert(c, -1.0, &el, NULL) == -ERANGE);
	CHECK_EQ(el, 12345.0);
	CHECK(sensor_curve_invert(c, NAN, &el, NULL) == -EINVAL);

	static const double e_bad[] = { 0.0, 10.0, 20.0 };
	static const double l_bad[] = { 1.0, 100.0, 50.0 };	/* not monotone */
	struct sensor_curve bad = { e_bad, l_bad, 3 };
	CHECK(sensor_curve_invert(&bad, 10.0, &el, NULL) == -EDOM);
	static const double l_zero[] = { 0.0, 100.0, 500.0 };
	bad.lux = l_zero;
	CHECK(sensor_curve_invert(&bad, 10.0, &el, NULL) == -EDOM);
	bad.n = 1;
	CHECK(sensor_curve_invert(&bad, 10.0, &el, NULL) == -EDOM);
}

/* A uniform table of w x h texels in the given format. */
static void *uniform_table(uint32_t format, uint32_t w, uint32_t h, const float rgba[4])
{
	size_t n = (size_t)w * h;
	if (format == SKY_FORMAT_RGBA32F) {
		float *t = malloc(n * 16);
		for (size_t i = 0; i < n; i++)
			memcpy(t + 4 * i, rgba, 16);
		return t;
	}
	uint16_t *t = malloc(n * 8);
	for (size_t i = 0; i < n; i++)
		for (int c = 0; c < 4; c++) {
			/* exact half floats for the values used below */
			float v = rgba[c];
			int e;
			double m = frexp(v, &e);	/* v = m 2^e, m in [0.5, 1) */
			t[4 * i + c] = v == 0.0f ? 0 : (uint16_t)(((e - 1 + 15) << 10) |
							    (uint16_t)((m * 2.0 - 1.0) * 1024.0));
		}
	return t;
}

static void test_horizontal(uint32_t format)
{
	const float trans[4] = { 0.5f, 0.5f, 0.5f, 0.0f };
	const float sky[4] = { 1000.0f, 2000.0f, 3000.0f, 0.0f };
	struct skysample_table tt = { uniform_table(format, 16, 8, trans), format, 16, 8, 1, 0 };
	struct skysample_table st = { uniform_table(format, 24, 16, sky), format, 24, 16, 1, 0 };
	struct sky_shm_state s;
	struct sensor_sky_lux lx;

	memset(&s, 0, sizeof(s));
	s.bottom_radius_km = 6360.0;
	s.top_radius_km = 6460.0;
	s.altitude_km = 0.0;
	skysample_direction(30.0 * SKYMAP_PI / 180.0, 1.0, s.sun_direction);
	for (int c = 0; c < 3; c++)
		s.sun_illuminance_lx[c] = 120000.0;
	skysample_direction(-10.0 * SKYMAP_PI / 180.0, 3.0, s.moon_direction);
	for (int c = 0; c < 3; c++)
		s.moon_illuminance_lx[c] = 0.3;

	sensor_sky_horizontal(&tt, &st, &s, &lx);
	double y_sky = 0.2126 * 1000.0 + 0.7152 * 2000.0 + 0.0722 * 3000.0;
	/* Direct: E0 T cos(zenith); sky: the quadrature integrates a uniform
	 * radiance to pi L exactly. */
	CHECK(REL(lx.sun_lx, 120000.0 * 0.5 * 0.5, 1e-9));
	CHECK_EQ(lx.moon_lx, 0.0);		/* below the horizon */
	CHECK(REL(lx.sky_lx, SKYMAP_PI * y_sky, 1e-9));
	CHECK(REL(lx.total_lx, lx.sun_lx + lx.sky_lx, 1e-12));

	/* The moon up, the sun down. */
	double sun_down[3], moon_up[3];
	skysample_direction(-5.0 * SKYMAP_PI / 180.0, 1.0, sun_down);
	skysample_direction(90.0 * SKYMAP_PI / 180.0, 0.0, moon_up);
	memcpy(s.sun_direction, sun_down, sizeof(sun_down));
	memcpy(s.moon_direction, moon_up, sizeof(moon_up));
	sensor_sky_horizontal(&tt, &st, &s, &lx);
	CHECK_EQ(lx.sun_lx, 0.0);
	CHECK(REL(lx.moon_lx, 0.3 * 0.5, 1e-9));
	CHECK(REL(sensor_sky_luminance((const double[3]){ 1.0, 1.0, 1.0 }), 1.0, 1e-12));
	free((void *)tt.texels);
	free((void *)st.texels);
}

static struct sensor_pipe *pipe_with(double tau, double h, double interval, double stale)
{
	struct sensor_pipe_config c;
	struct sensor_pipe *p = NULL;

	sensor_pipe_defaults(&c);
	c.time_constant_s = tau;
	c.hysteresis = h;
	c.min_interval_s = interval;
	c.stale_after_s = stale;
	CHECK_EQ(sensor_pipe_new(&c, &p), 0);
	return p;
}

static void test_pipe_refusals(void)
{
	struct sensor_pipe *p = pipe_with(0.0, 0.05, 0.0, 10.0);
	struct sensor_pipe_stats st;
	struct sensor_reading r;
	uint64_t next;

	CHECK_EQ(sensor_pipe_push(p, NAN, SENSOR_REJECT_NONE, 1), SENSOR_REJECT_NAN);
	CHECK_EQ(sensor_pipe_push(p, -0.5, SENSOR_REJECT_NONE, 2), SENSOR_REJECT_NEGATIVE);
	CHECK_EQ(sensor_pipe_push(p, 250000.0, SENSOR_REJECT_NONE, 3), SENSOR_REJECT_HIGH);
	CHECK_EQ(sensor_pipe_push(p, INFINITY, SENSOR_REJECT_NONE, 4), SENSOR_REJECT_HIGH);
	CHECK_EQ(sensor_pipe_push(p, 500.0, SENSOR_REJECT_UNIT, 5), SENSOR_REJECT_UNIT);
	CHECK_EQ(sensor_pipe_push(p, 500.0, SENSOR_REJECT_SATURATED, 6), SENSOR_REJECT_SATURATED);
	CHECK_EQ(sensor_pipe_push(p, 500.0, (enum sensor_reject)99, 7), SENSOR_REJECT_MALFORMED);
	/* Nothing accepted: nothing to say. */
	CHECK(sensor_pipe_poll(p, 10, &r, &next) == 0 && next == 0);
	CHECK_EQ(sensor_pipe_push(p, 0.0, SENSOR_REJECT_NONE, 8), SENSOR_REJECT_NONE);
	CHECK_EQ(sensor_pipe_push(p, 200000.0, SENSOR_REJECT_NONE, 9), SENSOR_REJECT_NONE);
	sensor_pipe_stats(p, &st);
	CHECK_EQ(st.accepted, 2);
	CHECK(st.rejected[SENSOR_REJECT_NAN] == 1 && st.rejected[SENSOR_REJECT_NEGATIVE] == 1);
	CHECK(st.rejected[SENSOR_REJECT_HIGH] == 2 && st.rejected[SENSOR_REJECT_UNIT] == 1);
	CHECK(st.rejected[SENSOR_REJECT_SATURATED] == 1 && st.rejected[SENSOR_REJECT_MALFORMED] == 1);
	CHECK_EQ(st.rejected[SENSOR_REJECT_NONE], 0);
	CHECK_EQ(st.last_reject, SENSOR_REJECT_MALFORMED);
	CHECK(!strcmp(sensor_reject_name(SENSOR_REJECT_UNIT), "unit"));
	sensor_pipe_free(p);

	struct sensor_pipe_config c;
	char err[80];
	sensor_pipe_defaults(&c);
	CHECK_EQ(sensor_pipe_check(&c, err, sizeof(err)), 0);
	c.hysteresis = NAN;
	CHECK(sensor_pipe_check(&c, err, sizeof(err)) == -EINVAL && strstr(err, "hysteresis"));
	CHECK_EQ(sensor_pipe_new(&c, &p), -EINVAL);
}

static void test_pipe_hysteresis_rate(void)
{
	struct sensor_pipe *p = pipe_with(0.0, 0.05, 1.0, 100.0);
	struct sensor_reading r;
	uint64_t next, t = 10 * SEC;

	/* The first value goes out at once. */
	sensor_pipe_push(p, 1000.0, SENSOR_REJECT_NONE, t);
	CHECK_EQ(sensor_pipe_poll(p, t, &r, &next), 1);
	CHECK(REL(r.lux, 1000.0, 1e-9) && r.raw_lux == 1000.0 && !r.stale && r.time_ns == t);
	CHECK_EQ(next, t + 100 * SEC);		/* only staleness is pending */
	/* 3 % is within the hysteresis. */
	t += 2 * SEC;
	sensor_pipe_push(p, 1030.0, SENSOR_REJECT_NONE, t);
	CHECK_EQ(sensor_pipe_poll(p, t, &r, &next), 0);
	/* 6 % is news, but the rate limit holds it for a second. */
	t += 2 * SEC;
	sensor_pipe_push(p, 1060.0, SENSOR_REJECT_NONE, t);
	CHECK(sensor_pipe_poll(p, t, &r, &next) == 1 && REL(r.lux, 1060.0, 1e-9));
	sensor_pipe_push(p, 2000.0, SENSOR_REJECT_NONE, t + 100 * MS);
	CHECK_EQ(sensor_pipe_poll(p, t + 100 * MS, &r, &next), 0);
	CHECK_EQ(next, t + SEC);
	CHECK(sensor_pipe_poll(p, t + SEC, &r, &next) == 1 && REL(r.lux, 2000.0, 1e-9));
	/* Back within the hysteresis of the last output: nothing. */
	sensor_pipe_push(p, 2050.0, SENSOR_REJECT_NONE, t + 3 * SEC);
	CHECK_EQ(sensor_pipe_poll(p, t + 3 * SEC, &r, &next), 0);
	sensor_pipe_free(p);
}

static void test_pipe_smoothing(void)
{
	struct sensor_pipe *p = pipe_with(10.0, 0.0, 0.0, 1000.0);
	struct sensor_reading r;
	uint64_t next, t = SEC;

	sensor_pipe_push(p, 100.0, SENSOR_REJECT_NONE, t);
	CHECK(sensor_pipe_poll(p, t, &r, &next) == 1 && REL(r.lux, 100.0, 1e-9));
	/* A step to 1000 lx, sampled every 10 ms for one time constant: the
	 * log of the output covers 1 - 1/e of the step (about 431 lx). */
	for (int i = 1; i <= 1000; i++)
		sensor_pipe_push(p, 1000.0, SENSOR_REJECT_NONE, t + (uint64_t)i * 10 * MS);
	CHECK_EQ(sensor_pipe_poll(p, t + 10 * SEC, &r, &next), 1);
	double want = exp(log(100.01) + (1.0 - exp(-1.0)) * (log(1000.01) - log(100.01))) - 0.01;
	CHECK(REL(r.lux, want, 1e-6));
	CHECK_EQ(r.raw_lux, 1000.0);
	sensor_pipe_free(p);

	/* The same step as one sample after ten seconds weighs the same. */
	p = pipe_with(10.0, 0.0, 0.0, 1000.0);
	sensor_pipe_push(p, 100.0, SENSOR_REJECT_NONE, t);
	sensor_pipe_push(p, 1000.0, SENSOR_REJECT_NONE, t + 10 * SEC);
	CHECK(sensor_pipe_poll(p, t + 10 * SEC, &r, &next) == 1 && REL(r.lux, want, 1e-6));
	sensor_pipe_free(p);
}

/* A hand over the sensor or a flood of reports at 1 kHz: few outputs. */
static void test_pipe_flood(void)
{
	struct sensor_pipe *p = pipe_with(2.0, 0.05, 1.0, 30.0);
	struct sensor_reading r;
	struct sensor_pipe_stats st;
	uint64_t next, t = SEC;
	int outputs = 0;

	for (int i = 0; i < 3000; i++, t += MS) {
		double lux = (i % 2) ? 450.0 : 550.0;	/* noise around 500 */
		if (i >= 1000 && i < 1300)
			lux = 5.0;			/* a hand, 0.3 s */
		sensor_pipe_push(p, lux, SENSOR_REJECT_NONE, t);
		outputs += sensor_pipe_poll(p, t, &r, &next);
	}
	sensor_pipe_stats(p, &st);
	CHECK_EQ(st.accepted, 3000);
	CHECK(outputs <= 4);			/* 3 s of reports, one output a second at most */
	CHECK_EQ(st.emitted, (uint64_t)outputs);
	/* The last output is near 500 lx: the hand came and went. */
	sensor_pipe_last(p, &r);
	CHECK(r.lux > 250.0 && r.lux < 600.0);
	sensor_pipe_free(p);
}

static void test_pipe_stale(void)
{
	struct sensor_pipe *p = pipe_with(0.0, 0.05, 0.5, 10.0);
	struct sensor_reading r;
	uint64_t next, t = SEC;

	sensor_pipe_push(p, 321.0, SENSOR_REJECT_NONE, t);
	CHECK(sensor_pipe_poll(p, t, &r, &next) == 1 && !r.stale);
	CHECK_EQ(next, t + 10 * SEC);
	/* Refused readings do not keep it fresh. */
	sensor_pipe_push(p, NAN, SENSOR_REJECT_NONE, t + 5 * SEC);
	CHECK_EQ(sensor_pipe_poll(p, t + 9 * SEC, &r, &next), 0);
	CHECK_EQ(sensor_pipe_poll(p, t + 10 * SEC, &r, &next), 1);
	CHECK(r.stale && REL(r.lux, 321.0, 1e-9) && next == 0);
	CHECK_EQ(sensor_pipe_poll(p, t + 20 * SEC, &r, &next), 0);
	/* A reading brings it back, even the same value. */
	sensor_pipe_push(p, 321.0, SENSOR_REJECT_NONE, t + 30 * SEC);
	CHECK(sensor_pipe_poll(p, t + 30 * SEC, &r, &next) == 1 && !r.stale);
	/* A reset forgets the value; a new device starts over at once. */
	sensor_pipe_reset(p);
	CHECK_EQ(sensor_pipe_poll(p, t + 31 * SEC, &r, &next), 0);
	sensor_pipe_push(p, 50.0, SENSOR_REJECT_NONE, t + 32 * SEC);
	CHECK(sensor_pipe_poll(p, t + 32 * SEC, &r, &next) == 1 && REL(r.lux, 50.0, 1e-9));
	sensor_pipe_free(p);
}

int main(void)
{
	test_ev100();
	test_curve();
	test_horizontal(SKY_FORMAT_RGBA32F);
	test_horizontal(SKY_FORMAT_RGBA16F);
	test_pipe_refusals();
	test_pipe_hysteresis_rate();
	test_pipe_smoothing();
	test_pipe_flood();
	test_pipe_stale();
	return test_report("test_sensor_math");
}

/* sensor_pipe.c - the reading pipeline: refusals, smoothing, hysteresis,
 * rate limit and staleness, pure and clocked by its caller. */
#include "sensor.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct sensor_pipe {
	struct sensor_pipe_config cfg;
	int have_value;
	double y;			/* smoothed ln(lux + floor) */
	double raw_lux;
	uint64_t last_ns;		/* last accepted reading */
	int have_output;
	double out_y;			/* y of the last output */
	int out_stale;
	uint64_t out_ns;		/* when the last output was handed out */
	struct sensor_reading out;
	struct sensor_pipe_stats stats;
};

static const char *const reject_names[SENSOR_REJECT_N] = {
	[SENSOR_REJECT_NONE] = "none",
	[SENSOR_REJECT_NAN] = "nan",
	[SENSOR_REJECT_NEGATIVE] = "negative",
	[SENSOR_REJECT_HIGH] = "high",
	[SENSOR_REJECT_UNIT] = "unit",
	[SENSOR_REJECT_SATURATED] = "saturated",
	[SENSOR_REJECT_MALFORMED] = "malformed",
	[SENSOR_REJECT_NOT_READY] = "not-ready",
};

const char *sensor_reject_name(enum sensor_reject r)
{
	return (unsigned)r < SENSOR_REJECT_N ? reject_names[r] : "?";
}

void sensor_pipe_defaults(struct sensor_pipe_config *ret)
{
	ret->time_constant_s = 5.0;
	ret->hysteresis = 0.05;
	ret->min_interval_s = 1.0;
	ret->stale_after_s = 30.0;
	ret->max_lux = 200000.0;
	ret->floor_lux = 0.01;
}

static int in_range(double v, double lo, double hi)
{
	return isfinite(v) && v >= lo && v <= hi;
}

int sensor_pipe_check(const struct sensor_pipe_config *cfg, char *err, size_t err_size)
{
	const char *bad = NULL;

	if (!in_range(cfg->time_constant_s, 0.0, 86400.0))
		bad = "time_constant_s";
	else if (!in_range(cfg->hysteresis, 0.0, 10.0))
		bad = "hysteresis";
	else if (!in_range(cfg->min_interval_s, 0.0, 86400.0))
		bad = "min_interval_s";
	else if (!in_range(cfg->stale_after_s, 0.001, 86400.0))
		bad = "stale_after_s";
	else if (!in_range(cfg->max_lux, 1.0, 1e7))
		bad = "max_lux";
	else if (!in_range(cfg->floor_lux, 1e-9, 1e3))
		bad = "floor_lux";
	if (!bad)
		return 0;
	if (err && err_size)
		snprintf(err, err_size, "%s out of range", bad);
	return -EINVAL;
}

int sensor_pipe_new(const struct sensor_pipe_config *cfg, struct sensor_pipe **ret)
{
	if (sensor_pipe_check(cfg, NULL, 0) < 0)
		return -EINVAL;
	struct sensor_pipe *p = calloc(1, sizeof(*p));
	if (!p)
		return -ENOMEM;
	p->cfg = *cfg;
	*ret = p;
	return 0;
}

void sensor_pipe_free(struct sensor_pipe *p)
{
	free(p);
}

void sensor_pipe_configure(struct sensor_pipe *p, const struct sensor_pipe_config *cfg)
{
	p->cfg = *cfg;
}

void sensor_pipe_reset(struct sensor_pipe *p)
{
	p->have_value = 0;
}

static double ns_to_s(uint64_t ns)
{
	return (double)ns * 1e-9;
}

enum sensor_reject sensor_pipe_push(struct sensor_pipe *p, double lux, enum sensor_reject why,
				    uint64_t now_ns)
{
	if (why == SENSOR_REJECT_NONE) {
		if (isnan(lux))
			why = SENSOR_REJECT_NAN;
		else if (lux < 0.0)
			why = SENSOR_REJECT_NEGATIVE;
		else if (lux > p->cfg.max_lux)	/* +inf included */
			why = SENSOR_REJECT_HIGH;
	}
	if ((unsigned)why >= SENSOR_REJECT_N)
		why = SENSOR_REJECT_MALFORMED;
	if (why != SENSOR_REJECT_NONE) {
		p->stats.rejected[why]++;
		p->stats.last_reject = why;
		return why;
	}
	p->stats.accepted++;

	/* Smoothing in ln(lux): a reading spans eight decades, and a passing
	 * cloud that halves the light should settle at the same pace at
	 * 100 lx as at 100 klx. The weight of a sample grows with the time
	 * since the previous one, so a flood of reports weighs no more than
	 * the same span of time at a slow rate. */
	double y = log(lux + p->cfg.floor_lux);
	if (!p->have_value || p->cfg.time_constant_s <= 0.0) {
		p->y = y;
	} else {
		double dt = now_ns > p->last_ns ? ns_to_s(now_ns - p->last_ns) : 0.0;
		double a = -expm1(-dt / p->cfg.time_constant_s);
		p->y += a * (y - p->y);
	}
	p->have_value = 1;
	p->raw_lux = lux;
	p->last_ns = now_ns;
	return SENSOR_REJECT_NONE;
}

static uint64_t s_to_ns(double s)
{
	return (uint64_t)(s * 1e9 + 0.5);
}

int sensor_pipe_poll(struct sensor_pipe *p, uint64_t now_ns, struct sensor_reading *ret,
		     uint64_t *ret_next_ns)
{
	uint64_t next = 0;

	*ret_next_ns = 0;
	if (!p->have_value)
		return 0;
	uint64_t stale_at = p->last_ns + s_to_ns(p->cfg.stale_after_s);
	int stale = now_ns >= stale_at;
	if (!stale)
		next = stale_at;

	int due = !p->have_output || stale != p->out_stale ||
		  fabs(p->y - p->out_y) >= log1p(p->cfg.hysteresis);
	/* A zero hysteresis would report every push; an unchanged value is
	 * never news. */
	if (p->have_output && stale == p->out_stale && p->y == p->out_y)
		due = 0;
	if (!due) {
		*ret_next_ns = next;
		return 0;
	}
	uint64_t allowed = p->have_output ? p->out_ns + s_to_ns(p->cfg.min_interval_s) : 0;
	if (now_ns < allowed) {
		*ret_next_ns = next && next < allowed ? next : allowed;
		return 0;
	}
	double lux = exp(p->y) - p->cfg.floor_lux;
	p->out.lux = lux > 0.0 ? lux : 0.0;
	p->out.raw_lux = p->raw_lux;
	p->out.time_ns = p->last_ns;
	p->out.stale = stale;
	p->have_output = 1;
	p->out_y = p->y;
	p->out_stale = stale;
	p->out_ns = now_ns;
	p->stats.emitted++;
	*ret = p->out;
	*ret_next_ns = next;
	return 1;
}

void sensor_pipe_last(const struct sensor_pipe *p, struct sensor_reading *ret)
{
	*ret = p->out;
}

void sensor_pipe_stats(const struct sensor_pipe *p, struct sensor_pipe_stats *ret)
{
	*ret = p->stats;
}

/* sense.c - the light sensor's readings as changes of the served sky: the
 * manager run from the sensor keys, the three modes, and the curve the
 * elevation mode inverts. */
#include "sense.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "log.h"
#include "loop.h"
#include "pub.h"
#include "skysample.h"
#include "srv.h"

#define LIGHTS (STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL))
/* What the cloud and elevation modes read from the published slot. */
#define READS (STATE_BIT(STATE_TRANSMITTANCE) | STATE_BIT(STATE_SKYVIEW))

/* The curve's points from the tables: one per degree of sun elevation over
 * the USNO curve's range, the latest measured in each. */
#define CURVE_MIN_DEG (-12.0)
#define CURVE_BINS 103
#define CURVE_MAX_POINTS (CURVE_BINS + 8)
/* One reading refines the elevation at most this many times: the
 * refinement converges in a few steps (more with small, coarse tables);
 * this bounds a curve that will not. */
#define MAX_REFINEMENTS 8
/* A new sun under the same reading changes the cloud factor only past the
 * hysteresis and at least this much: the tables carry the factor in float
 * (or half) precision, so the factor read back from them differs from the
 * one applied in the last digits, and a smaller step would chase that. */
#define REEVALUATE_MIN 0.01

/* What the clear-sky curve was measured for: another atmosphere, observer,
 * table size or night floor starts it over. */
struct curve_ref {
	struct atmo atmo;
	double altitude_km;
	struct state_quality quality;
	struct state_night night;
	double sun_color[3];
};

struct curve {
	struct curve_ref ref;
	int have_ref;
	double bin_el[CURVE_BINS], bin_lux[CURVE_BINS];
	unsigned char used[CURVE_BINS];
	int dirty;			/* points changed since the last build */
	double el[CURVE_MAX_POINTS], lux[CURVE_MAX_POINTS];
	struct sensor_curve c;		/* over el, lux; or sensor_curve_usno */
};

enum cause { CAUSE_READING, CAUSE_MODE, CAUSE_PUBLISHED };

struct sense {
	struct loop *loop;
	struct srv *srv;
	struct sensor *sensor;		/* NULL until a mode first needs one */
	struct sensor_config cfg;	/* as last given to the manager */
	enum state_sensor_mode mode;	/* as last applied */
	struct loop_timer *published;	/* a publication to read, after srv is done */
	sense_event_fn fn;
	void *ctx;

	struct sensor_reading last;	/* the pipeline's last output */
	int waiting;			/* it waits for tables to be published */
	uint32_t own_demand;		/* as last given to srv */
	int refinements;		/* elevation changes since the last reading */
	enum sensor_state told_state;	/* what the last event said */
	char told_bus[32];
	enum sensor_dev_state told_dev;
	struct curve curve;
	struct srv_sensor_status st;
};

/* ---- the clear-sky curve ---- */

/* The USNO curve at el, linear in ln(E), held at its ends. */
static double usno_at(double el)
{
	const struct sensor_curve *u = &sensor_curve_usno;
	size_t i = 1;

	if (el <= u->elevation_deg[0])
		return u->lux[0];
	if (el >= u->elevation_deg[u->n - 1])
		return u->lux[u->n - 1];
	while (i < u->n - 1 && el > u->elevation_deg[i])
		i++;
	double f = (el - u->elevation_deg[i - 1]) / (u->elevation_deg[i] - u->elevation_deg[i - 1]);
	return exp(log(u->lux[i - 1]) + f * (log(u->lux[i]) - log(u->lux[i - 1])));
}

/* ln(tables / USNO) at el: linear between the measured points, held
 * beyond them. */
static double ratio_at(const struct curve *cv, double el)
{
	int lo = -1, hi = -1;

	for (int b = 0; b < CURVE_BINS; b++) {
		if (!cv->used[b])
			continue;
		if (cv->bin_el[b] <= el)
			lo = b;
		if (cv->bin_el[b] >= el && hi < 0)
			hi = b;
	}
	int a = lo >= 0 ? lo : hi, z = hi >= 0 ? hi : lo;
	double ra = log(cv->bin_lux[a] / usno_at(cv->bin_el[a]));
	double rz = log(cv->bin_lux[z] / usno_at(cv->bin_el[z]));
	if (a == z || cv->bin_el[z] == cv->bin_el[a])
		return ra;
	return ra + (el - cv->bin_el[a]) / (cv->bin_el[z] - cv->bin_el[a]) * (rz - ra);
}

static void add_point(struct curve *cv, size_t *n, double el, double lux)
{
	if (*n < CURVE_MAX_POINTS) {
		cv->el[*n] = el;
		cv->lux[*n] = lux;
		(*n)++;
	}
}

/* The curve the elevation mode inverts: the measured points, and the USNO
 * samples away from them scaled by the measured ratio, so that between
 * points the curve keeps USNO's shape at the tables' level. Falls back to
 * USNO alone when that is not strictly increasing. */
static void build_curve(struct sense *s)
{
	struct curve *cv = &s->curve;
	const struct sensor_curve *u = &sensor_curve_usno;
	size_t n = 0, points = 0, k = 0;
	double dummy;

	cv->dirty = 0;
	s->st.curve_min_deg = s->st.curve_max_deg = NAN;
	for (int b = 0; b < CURVE_BINS; b++) {
		if (!cv->used[b])
			continue;
		/* USNO samples below this point and not within half a degree of one. */
		for (; k < u->n && u->elevation_deg[k] < cv->bin_el[b]; k++)
			if (cv->bin_el[b] - u->elevation_deg[k] > 0.5 &&
			    (n == 0 || u->elevation_deg[k] - cv->el[n - 1] > 0.5))
				add_point(cv, &n, u->elevation_deg[k],
					  u->lux[k] * exp(ratio_at(cv, u->elevation_deg[k])));
		add_point(cv, &n, cv->bin_el[b], cv->bin_lux[b]);
		if (!points++)
			s->st.curve_min_deg = cv->bin_el[b];
		s->st.curve_max_deg = cv->bin_el[b];
	}
	for (; k < u->n; k++)
		if (n == 0 || u->elevation_deg[k] - cv->el[n - 1] > 0.5)
			add_point(cv, &n, u->elevation_deg[k],
				  u->lux[k] * (points ? exp(ratio_at(cv, u->elevation_deg[k])) : 1.0));
	cv->c = (struct sensor_curve){ cv->el, cv->lux, n };
	s->st.curve_points = points;
	s->st.curve = points ? SRV_SENSOR_CURVE_TABLES : SRV_SENSOR_CURVE_USNO;
	if (!points || sensor_curve_invert(&cv->c, cv->lux[0], &dummy, NULL) == -EDOM) {
		if (points)
			log_warning("sensor: the tables' clear-sky points do not rise with the sun; "
				    "the elevation mode inverts the USNO curve alone");
		cv->c = sensor_curve_usno;
		s->st.curve = SRV_SENSOR_CURVE_USNO;
	}
}

static void curve_ref(const struct sky_state *k, struct curve_ref *ret)
{
	memset(ret, 0, sizeof(*ret));
	ret->atmo = k->atmo;
	ret->altitude_km = k->altitude_km;
	ret->quality = k->quality;
	ret->night = k->night;
	memcpy(ret->sun_color, k->sun.color, sizeof(ret->sun_color));
}

/* A point for the curve: the lights' clear-sky illuminance of a published
 * slot whose sun is in the curve's range and whose moon lights nothing,
 * scaled to the sun's mean illuminance. */
static void record_point(struct sense *s, const struct sky_state *k, double lights_lx,
			 int moon_lit)
{
	struct curve *cv = &s->curve;
	struct curve_ref ref;
	double el = k->sun.elevation_deg;

	curve_ref(k, &ref);
	if (!cv->have_ref || memcmp(&ref, &cv->ref, sizeof(ref)) != 0) {
		memset(cv->used, 0, sizeof(cv->used));
		cv->ref = ref;
		cv->have_ref = 1;
		cv->dirty = 1;
	}
	if (moon_lit || !(el >= CURVE_MIN_DEG && el <= 90.0) || !(k->sun.illuminance_lx > 0.0) ||
	    !(lights_lx > 0.0))
		return;
	int b = (int)floor(el - CURVE_MIN_DEG);
	b = b < 0 ? 0 : b >= CURVE_BINS ? CURVE_BINS - 1 : b;
	double lux = lights_lx * SENSE_SUN_MEAN_LX / k->sun.illuminance_lx;
	if (cv->used[b] && cv->bin_el[b] == el && cv->bin_lux[b] == lux)
		return;
	cv->bin_el[b] = el;
	cv->bin_lux[b] = lux;
	cv->used[b] = 1;
	cv->dirty = 1;
}

/* ---- the published tables ---- */

/* The clear-sky illuminance of the lights in the current slot: its
 * horizontal illuminance less the night floor's, over the cloud factor
 * it was computed with (radiance is linear in the lights' illuminance).
 * -EAGAIN while the slot lacks the tables. With record, the slot also
 * gives the curve a point. */
static int clear_sky(struct sense *s, int record, double *ret_lights_lx, double *ret_night_lx)
{
	const struct pub *p = srv_pub(s->srv);
	const uint8_t *base;
	const struct sky_shm_slot *slot = pub_current(p, &base);
	const struct sky_state *k = srv_published(s->srv);
	struct skysample_table trans, sky;
	struct sensor_sky_lux lux;

	if ((slot->valid_tables & READS) != READS ||
	    skysample_table_from_slot(pub_header(p), base, SKY_TABLE_TRANSMITTANCE, &trans) < 0 ||
	    skysample_table_from_slot(pub_header(p), base, SKY_TABLE_SKYVIEW, &sky) < 0)
		return -EAGAIN;
	sensor_sky_horizontal(&trans, &sky, &slot->state, &lux);
	*ret_night_lx = k->night.zenith_luminance_cd_m2 > 0.0 ? k->night.illuminance_lx : 0.0;
	*ret_lights_lx = fmax(lux.total_lx - *ret_night_lx, 0.0) /
			 fmax(state_cloud_factor_applied(k), SENSE_FACTOR_MIN);
	if (record)
		record_point(s, k, *ret_lights_lx, k->moon.illuminance_lx > 0.0);
	return 0;
}

/* ---- the modes ---- */

static void emit(struct sense *s)
{
	struct srv_sensor_status st;

	if (!s->fn)
		return;
	sense_status(s, &st);
	s->told_state = st.sensor.state;
	s->told_dev = st.sensor.device.state;
	snprintf(s->told_bus, sizeof(s->told_bus), "%s", st.sensor.device.bus_path);
	s->fn(s->ctx, &st);
}

/* A follower's sky is its controller's: a reading of its own would part
 * it from the others until the next replicated change. 1, with the
 * reason noted, where this skyd follows. */
static int note_follower(struct sense *s)
{
	char who[256] = "";

	if (srv_may_change(s->srv, who, sizeof(who)))
		return 0;
	snprintf(s->st.not_applied, sizeof(s->st.not_applied),
		 "this skyd follows controller %s: only its readings change the sky", who);
	return 1;
}

/* next, built from the served state, as the readings' change. Returns 1
 * when it was made. */
static int apply(struct sense *s, const struct sky_state *next, uint32_t dirty)
{
	char err[256] = "";
	uint64_t generation;
	uint32_t all;

	if (note_follower(s))
		return 0;
	int r = srv_apply(s->srv, next, dirty, &generation, &all, err, sizeof(err));

	if (r < 0) {
		snprintf(s->st.not_applied, sizeof(s->st.not_applied), "refused: %s", err);
		log_warning("sensor: change refused: %s", err);
		return 0;
	}
	s->st.changes++;
	s->st.generation = generation;
	return 1;
}

/* The exposure mode's EV100 into the served state, for the next slot to
 * carry (sky_shm_state.exposure_ev100): no table depends on it, so it
 * names no generation of its own and counts as no change. */
static void set_exposure(struct sense *s, double ev100)
{
	const struct sky_state *cur = srv_state(s->srv);
	char err[256] = "";
	uint64_t generation;
	uint32_t all;

	if (cur->exposure_ev100 == ev100 || (isnan(cur->exposure_ev100) && isnan(ev100)))
		return;
	struct sky_state next = *cur;
	next.exposure_ev100 = ev100;
	if (srv_apply(s->srv, &next, 0, &generation, &all, err, sizeof(err)) < 0)
		log_warning("sensor: EV100 not kept in the state: %s", err);
}

#define NOTE(...) snprintf(s->st.not_applied, sizeof(s->st.not_applied), __VA_ARGS__)

/* Each eval_* returns 1 when it changed the served state. */
static int eval_cloud(struct sense *s, enum cause cause)
{
	const struct sky_state *cur = srv_state(s->srv);
	double lights_lx, night_lx;

	/* Drawn cloud layers dim the lights themselves: a factor on top
	 * would count the clouds twice (docs/sensor.md, "cloud"). */
	if (state_clouds_drawn(cur)) {
		NOTE("cloud layers are drawn: they, not the reading, dim the sun and the moon");
		return 0;
	}
	if (clear_sky(s, cause == CAUSE_PUBLISHED, &lights_lx, &night_lx) < 0) {
		s->waiting = 1;
		/* With the tables a follower's reading would change nothing
		 * either: that is the reason to give. */
		if (!note_follower(s))
			NOTE("waiting for the tables: the clear sky is read from them");
		return 0;
	}
	s->waiting = 0;
	s->st.clear_sky_lx = lights_lx;
	if (lights_lx < SENSE_CLOUD_MIN_LX) {
		NOTE("the clear sky gives %.3g lx, under %g: too dark to measure clouds", lights_lx,
		     SENSE_CLOUD_MIN_LX);
		return 0;
	}
	double f = (s->last.lux - night_lx) / lights_lx;
	f = fmin(fmax(f, SENSE_FACTOR_MIN), 1.0);
	double was = cur->weather.cloud_factor;
	/* A new sun under the same reading: only a change past the hysteresis. */
	if (cause == CAUSE_PUBLISHED &&
	    fabs(f - was) < fmax(cur->sensor.hysteresis, REEVALUATE_MIN) * was)
		return 0;
	s->st.not_applied[0] = 0;
	if (f == was)
		return 0;
	struct sky_state next = *cur;
	uint32_t dirty = 0;
	state_set_cloud_factor(&next, f, &dirty);
	return apply(s, &next, dirty);
}

static int eval_elevation(struct sense *s, enum cause cause)
{
	const struct sky_state *cur = srv_state(s->srv);
	double lights_lx, night_lx, el, slope;

	if (clear_sky(s, cause == CAUSE_PUBLISHED, &lights_lx, &night_lx) == 0)
		s->st.clear_sky_lx = lights_lx;
	/* After a publication only a new point of the curve moves the sun. */
	if (cause == CAUSE_PUBLISHED && !s->curve.dirty)
		return 0;
	if (s->curve.dirty || !s->curve.c.n)
		build_curve(s);
	const struct sensor_curve *c = &s->curve.c;
	double lux = s->last.lux;
	if (cur->sun.illuminance_lx > 0.0)
		lux *= SENSE_SUN_MEAN_LX / cur->sun.illuminance_lx;
	if (sensor_curve_invert(c, lux, &el, &slope) < 0) {
		if (cause != CAUSE_PUBLISHED)
			NOTE("%.6g lx is outside the curve's %.3g to %.6g lx (sun -12 to 90 deg): reported, not applied",
			     s->last.lux, c->lux[0], c->lux[c->n - 1]);
		return 0;
	}
	s->st.elevation_deg = el;
	s->st.deg_per_ln = slope;
	if (cause == CAUSE_PUBLISHED &&
	    (fabs(el - cur->sun.elevation_deg) < SENSE_ELEVATION_SETTLE_DEG ||
	     ++s->refinements > MAX_REFINEMENTS))
		return 0;
	if (cause != CAUSE_PUBLISHED)
		s->st.not_applied[0] = 0;
	if (el == cur->sun.elevation_deg && cur->clock.sun_mode == STATE_MANUAL)
		return 0;
	struct sky_state next = *cur;
	next.sun.elevation_deg = el;
	next.clock.sun_mode = STATE_MANUAL;
	return apply(s, &next, LIGHTS);
}

/* The last output under the served state's mode; 1 when it changed the
 * served state. */
static int evaluate(struct sense *s, enum cause cause)
{
	const struct sky_state *cur = srv_state(s->srv);

	if (!s->st.have_reading)
		return 0;
	s->st.ev100 = sensor_ev100(s->last.lux);
	if (cause != CAUSE_PUBLISHED)
		s->st.generation = srv_state_generation(s->srv);
	if (s->last.stale) {
		if (cause != CAUSE_PUBLISHED)
			NOTE("stale: nothing read for sensor_stale_after_s; the last good value stays");
		return 0;
	}
	switch (cur->sensor.mode) {
	case STATE_SENSOR_CLOUD:
		return eval_cloud(s, cause);
	case STATE_SENSOR_ELEVATION:
		return eval_elevation(s, cause);
	case STATE_SENSOR_EXPOSURE:
		s->st.not_applied[0] = 0;
		set_exposure(s, s->st.ev100);
		return 0;
	default:
		NOTE("sensor_mode is off");
		return 0;
	}
}

/* ---- the manager ---- */

static void on_reading(void *ctx, const struct sensor_reading *r)
{
	struct sense *s = ctx;

	s->last = *r;
	s->st.have_reading = 1;
	s->refinements = 0;
	evaluate(s, CAUSE_READING);
	emit(s);
}

/* Told only when the state or the device changed: counters move with
 * every reading, and each output is told already. */
static void on_status(void *ctx)
{
	struct sense *s = ctx;
	struct sensor_status st;

	sensor_get_status(s->sensor, &st);
	if (st.state != s->told_state || st.device.state != s->told_dev ||
	    strcmp(st.device.bus_path, s->told_bus) != 0)
		emit(s);
}

static void published_fired(void *ctx)
{
	struct sense *s = ctx;
	enum state_sensor_mode m = srv_state(s->srv)->sensor.mode;

	if (m != STATE_SENSOR_CLOUD && m != STATE_SENSOR_ELEVATION)
		return;
	int was_waiting = s->waiting;
	int changed = evaluate(s, s->waiting ? CAUSE_MODE : CAUSE_PUBLISHED);
	if (changed || (was_waiting && !s->waiting))
		emit(s);
}

/* srv's listener: a generation was published. The cloud and elevation
 * modes read its tables from a zero-delay timer, not from inside srv. */
static void on_published(void *ctx, uint64_t generation, uint32_t tables, int new_region)
{
	struct sense *s = ctx;

	(void)generation;
	(void)tables;
	(void)new_region;
	if (s->sensor)
		loop_timer_arm(s->published, 1);
}

static void keys_config(const struct state_sensor *k, struct sensor_config *ret)
{
	sensor_config_defaults(ret);
	snprintf(ret->select, sizeof(ret->select), "%s", k->mode == STATE_SENSOR_OFF ? "none" : k->select);
	ret->pipe = (struct sensor_pipe_config){ .time_constant_s = k->time_constant_s,
		.hysteresis = k->hysteresis, .min_interval_s = k->min_interval_s,
		.stale_after_s = k->stale_after_s, .max_lux = k->max_lux, .floor_lux = k->floor_lux };
	ret->report_interval_s = k->report_interval_s;
	ret->io_timeout_s = k->io_timeout_s;
	ret->rescan_s = k->rescan_s;
}

/* Starts, stops or reconfigures the manager for the served keys. */
static int apply_keys(struct sense *s)
{
	const struct state_sensor *k = &srv_state(s->srv)->sensor;
	struct sensor_config cfg;
	char err[160] = "";
	int r = 0;

	keys_config(k, &cfg);
	if (sensor_config_check(&cfg, err, sizeof(err)) < 0) {
		log_warning("sensor: %s; the sensor keeps its settings", err);
		return -EINVAL;
	}
	if (!s->sensor && k->mode != STATE_SENSOR_OFF) {
		r = sensor_new(s->loop, &cfg, on_reading, s, &s->sensor);
		if (r < 0) {
			log_error("sensor: %s", strerror(-r));
			return r;
		}
		sensor_on_status(s->sensor, on_status, s);
	} else if (s->sensor && memcmp(&cfg, &s->cfg, sizeof(cfg)) != 0) {
		sensor_set_config(s->sensor, &cfg);
	}
	s->cfg = cfg;
	int reads = k->mode == STATE_SENSOR_CLOUD || k->mode == STATE_SENSOR_ELEVATION;
	if (s->own_demand != (reads ? READS : 0u)) {
		s->own_demand = reads ? READS : 0u;
		srv_set_own_demand(s->srv, s->own_demand);
	}
	if (k->mode != s->mode) {
		s->mode = k->mode;
		s->waiting = 0;
		s->refinements = 0;
		s->st.not_applied[0] = 0;
		if (k->mode != STATE_SENSOR_EXPOSURE)
			set_exposure(s, NAN);
		evaluate(s, CAUSE_MODE);
		if (s->sensor)
			emit(s);
	}
	return 0;
}

/* srv's listener: the served state changed. Its sensor keys start, stop
 * or reconfigure the manager; a new mode applies the last reading. The
 * readings' own changes and the clock's come here too: they leave the
 * sensor keys as they were, so apply_keys does nothing then. */
static void on_changed(void *ctx, const struct sky_state *st, uint64_t generation,
		       int64_t apply_time_ns)
{
	(void)st;
	(void)generation;
	(void)apply_time_ns;
	apply_keys(ctx);
}

/* ---- the rest ---- */

void sense_status(const struct sense *s, struct srv_sensor_status *ret)
{
	*ret = s->st;
	ret->mode = srv_state(s->srv)->sensor.mode;
	ret->cloud_factor = srv_state(s->srv)->weather.cloud_factor;
	memset(&ret->sensor, 0, sizeof(ret->sensor));
	ret->sensor.state = SENSOR_STATE_OFF;
	if (s->sensor)
		sensor_get_status(s->sensor, &ret->sensor);
	if (!s->st.have_reading)
		ret->generation = srv_state_generation(s->srv);
	ret->reading_mono_ns = s->st.have_reading ? s->last.time_ns : 0;
	ret->age_s = s->st.have_reading ? (double)(loop_now_ns() - s->last.time_ns) * 1e-9 : NAN;
}

size_t sense_devices(const struct sense *s, struct sensor_info *ret, size_t max)
{
	return s->sensor ? sensor_devices(s->sensor, ret, max) : 0;
}

void sense_set_listener(struct sense *s, sense_event_fn fn, void *ctx)
{
	s->fn = fn;
	s->ctx = ctx;
}

static void status_hook(void *ctx, struct srv_sensor_status *ret)
{
	sense_status(ctx, ret);
}

static size_t devices_hook(void *ctx, struct sensor_info *ret, size_t max)
{
	return sense_devices(ctx, ret, max);
}

int sense_new(struct loop *l, struct srv *srv, struct sense **ret)
{
	struct sense *s = calloc(1, sizeof(*s));
	int r;

	if (!s)
		return -ENOMEM;
	s->loop = l;
	s->srv = srv;
	s->st.ev100 = s->st.clear_sky_lx = s->st.elevation_deg = s->st.deg_per_ln = NAN;
	s->st.curve_min_deg = s->st.curve_max_deg = NAN;
	r = loop_timer_add(l, published_fired, s, &s->published);
	if (r < 0) {
		free(s);
		return r;
	}
	r = srv_add_listener(srv, &(struct srv_listener){ .changed = on_changed,
			     .published = on_published, .ctx = s });
	if (r < 0) {
		sense_free(s);
		return r;
	}
	srv_set_sensor(srv, &(struct srv_sensor){ status_hook, devices_hook, s });
	r = apply_keys(s);
	if (r < 0 && r != -EINVAL) {
		sense_free(s);
		return r;
	}
	*ret = s;
	return 0;
}

void sense_free(struct sense *s)
{
	if (!s)
		return;
	srv_remove_listener(s->srv, s);
	srv_set_sensor(s->srv, NULL);
	sensor_free(s->sensor);
	loop_timer_del(s->published);
	free(s);
}

/* cmd_astro.c - get sun, get moon and get times: where the clock's sun and
 * moon are now, and the day's rise, set and twilights, from astro. */
#include "ctl_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "astro.h"
#include "simclock.h"
#include "srv.h"

/* The clock's time now, or an ACK when no time was ever set. */
static int clock_now(const struct sky_state *s, double *ret_utc_s, char *msg, size_t msg_size)
{
	double mono_s;

	simclock_read_clocks(NULL, &mono_s);
	*ret_utc_s = state_clock_utc_s(s, mono_s);
	if (isnan(*ret_utc_s))
		return CTL_ACK(SKY_ACK_STATE, "utc: no time set (set utc=now or utc=YYYY-MM-DDTHH:MM:SSZ)");
	return 0;
}

/* What `get sun` and `get moon` share: no arguments, the clock's time now
 * and the observer's site. */
static int light_request(const struct client *c, const struct proto_request *req,
			 const char *verb, double *ret_utc_s, struct astro_site *ret_site,
			 struct astro_options *ret_opt, char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	int code = clock_now(s, ret_utc_s, msg, msg_size);

	if (code)
		return code;
	if (req->n_args > 1)
		return CTL_ACK(SKY_ACK_SYNTAX, "get %s takes no arguments", verb);
	state_astro_site(s, ret_site, ret_opt);
	return 0;
}

static void reply_utc(struct reply *r, const char *key, double utc_s)
{
	char buf[SIMCLOCK_UTC_TEXT_MAX];

	if (simclock_format_utc(utc_s, buf, sizeof(buf)) < 0)
		ctl_reply_add(r, "%s: %.3f\n", key, utc_s);
	else
		ctl_reply_add(r, "%s: %s\n", key, buf);
}

static void reply_direction(struct reply *r, const struct astro_direction *geo,
			    const struct astro_direction *app)
{
	ctl_reply_add(r, "zenith_deg: %.6f\nelevation_deg: %.6f\nazimuth_deg: %.6f\n",
		  geo->zenith_deg, geo->elevation_deg, geo->azimuth_deg);
	ctl_reply_add(r, "apparent_zenith_deg: %.6f\napparent_elevation_deg: %.6f\napparent_azimuth_deg: %.6f\n",
		  app->zenith_deg, app->elevation_deg, app->azimuth_deg);
}

int ctl_get_sun(struct client *c, const struct proto_request *req, struct reply *r,
		char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_sun a;
	char err[256];
	double utc_s;
	int code = light_request(c, req, "sun", &utc_s, &site, &opt, msg, msg_size);

	if (code)
		return code;
	if (astro_sun(&site, utc_s, &opt, &a, err, sizeof(err)) < 0)
		return CTL_ACK(SKY_ACK_RANGE, "%s", err);
	reply_utc(r, state_key_name(STATE_KEY_ID_UTC), utc_s);
	ctl_reply_add(r, "sun_mode: %s\n", s->clock.sun_mode == STATE_CLOCK ? "clock" : "manual");
	reply_direction(r, &a.geometric, &a.apparent);
	ctl_reply_add(r, "right_ascension_deg: %.6f\ndeclination_deg: %.6f\nhour_angle_deg: %.6f\n",
		  a.right_ascension_deg, a.declination_deg, a.hour_angle_deg);
	ctl_reply_add(r, "equation_of_time_min: %.6f\ndistance_au: %.9f\nangular_radius_deg: %.6f\n",
		  a.equation_of_time_min, a.distance_au, a.angular_radius_deg);
	ctl_reply_add(r, "illuminance_lx: %.3f\ndelta_t_s: %.3f\n", a.illuminance_lx, a.delta_t_s);
	return 0;
}

int ctl_get_moon(struct client *c, const struct proto_request *req, struct reply *r,
		 char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_moon m;
	char err[256];
	double utc_s;
	int code = light_request(c, req, "moon", &utc_s, &site, &opt, msg, msg_size);

	if (code)
		return code;
	if (astro_moon(&site, utc_s, &opt, &m, err, sizeof(err)) < 0)
		return CTL_ACK(SKY_ACK_RANGE, "%s", err);
	reply_utc(r, state_key_name(STATE_KEY_ID_UTC), utc_s);
	ctl_reply_add(r, "moon_mode: %s\n", s->clock.moon_mode == STATE_CLOCK ? "clock" : "manual");
	reply_direction(r, &m.geometric, &m.apparent);
	ctl_reply_add(r, "longitude_deg: %.6f\nlatitude_deg: %.6f\n", m.longitude_deg, m.latitude_deg);
	ctl_reply_add(r, "right_ascension_deg: %.6f\ndeclination_deg: %.6f\n", m.right_ascension_deg,
		  m.declination_deg);
	ctl_reply_add(r, "distance_km: %.3f\ntopocentric_distance_km: %.3f\nangular_radius_deg: %.6f\n",
		  m.distance_km, m.topocentric_distance_km, m.angular_radius_deg);
	ctl_reply_add(r, "phase_angle_deg: %.6f\nilluminated_fraction: %.6f\nelongation_deg: %.6f\nwaxing: %d\n",
		  m.phase_angle_deg, m.illuminated_fraction, m.elongation_deg, m.waxing ? 1 : 0);
	ctl_reply_add(r, "illuminance_lx: %.6g\n", m.illuminance_lx);
	/* What the tables are lit with: the served state's moon. */
	ctl_reply_add(r, "lit: %d\nlit_illuminance_lx: %.6g\n", s->moon.illuminance_lx > 0.0,
		  s->moon.illuminance_lx);
	return 0;
}

static void reply_event(struct reply *r, const char *key, double utc_s, enum astro_day_kind kind,
			const char *above, const char *below)
{
	if (kind == ASTRO_RISES_AND_SETS)
		reply_utc(r, key, utc_s);
	else
		ctl_reply_add(r, "%s: none (%s)\n", key, kind == ASTRO_ALWAYS_ABOVE ? above : below);
}

static void reply_rise_set(struct reply *r, const char *rise, const char *set,
			   const struct astro_rise_set *rs, const char *above, const char *below)
{
	reply_event(r, rise, rs->rise_utc_s, rs->kind, above, below);
	reply_event(r, set, rs->set_utc_s, rs->kind, above, below);
}

/* get times [date=YYYY-MM-DD] [utc_offset_min=N]: the local day starts at
 * local midnight, local = UTC + utc_offset_min; by default the offset of
 * the longitude's nominal zone (15 degrees an hour) and the simulated date. */
int ctl_get_times(struct client *c, const struct proto_request *req, struct reply *r,
		  char *msg, size_t msg_size)
{
	const struct sky_state *s = srv_state(c->ctl->srv);
	struct astro_site site;
	struct astro_options opt;
	struct astro_times t;
	struct astro_date d = { 0 };
	const char *date = NULL;
	char err[256], buf[SIMCLOCK_UTC_TEXT_MAX];
	double off;

	d.utc_offset_min = (int)lround(s->clock.lon_deg / 15.0) * 60;
	for (int i = 1; i < req->n_args; i++) {
		const struct proto_arg *a = &req->args[i];
		if (!a->value)
			return CTL_ACK(SKY_ACK_SYNTAX, "usage: get times [date=YYYY-MM-DD] [utc_offset_min=N]");
		if (strcmp(a->key, "date") == 0) {
			date = a->value;
		} else if (strcmp(a->key, "utc_offset_min") == 0) {
			if (proto_parse_number(a->value, &off) < 0 || off != floor(off))
				return CTL_ACK(SKY_ACK_ARG, "utc_offset_min: '%s' is not a whole number", a->value);
			if (fabs(off) > 1080)
				return CTL_ACK(SKY_ACK_RANGE, "utc_offset_min: %g is outside [-1080, 1080]", off);
			d.utc_offset_min = (int)off;
		} else {
			return CTL_ACK(SKY_ACK_NO_EXIST, "%s: unknown key (date, utc_offset_min)", a->key);
		}
	}
	if (date) {
		char tail;
		if (sscanf(date, "%5d-%2d-%2d%c", &d.year, &d.month, &d.day, &tail) != 3 ||
		    strlen(date) != 10 || date[0] < '0' || date[0] > '9' || date[4] != '-' || date[7] != '-' ||
		    !simclock_valid_date(d.year, d.month, d.day))
			return CTL_ACK(SKY_ACK_ARG, "date: '%s' is not a date YYYY-MM-DD", date);
	} else {
		double utc_s;
		int code = clock_now(s, &utc_s, msg, msg_size);
		if (code)
			return code;
		if (simclock_format_utc(utc_s + 60.0 * d.utc_offset_min, buf, sizeof(buf)) < 0 ||
		    sscanf(buf, "%d-%d-%d", &d.year, &d.month, &d.day) != 3)
			return CTL_ACK(SKY_ACK_RANGE, "utc: outside years 0..9999");
	}
	state_astro_site(s, &site, &opt);
	if (astro_sun_times(&site, &d, &opt, &t, err, sizeof(err)) < 0)
		return CTL_ACK(SKY_ACK_RANGE, "%s", err);
	ctl_reply_add(r, "date: %04d-%02d-%02d\nutc_offset_min: %d\n", d.year, d.month, d.day,
		  d.utc_offset_min);
	reply_utc(r, "transit_utc", t.transit_utc_s);
	ctl_reply_add(r, "transit_elevation_deg: %.6f\n", t.transit_elevation_deg);
	reply_rise_set(r, "sunrise_utc", "sunset_utc", &t.sunrise_sunset, "polar day", "polar night");
	reply_rise_set(r, "civil_dawn_utc", "civil_dusk_utc", &t.civil,
		       "sun never below -6 deg", "sun never above -6 deg");
	reply_rise_set(r, "nautical_dawn_utc", "nautical_dusk_utc", &t.nautical,
		       "sun never below -12 deg", "sun never above -12 deg");
	reply_rise_set(r, "astronomical_dawn_utc", "astronomical_dusk_utc", &t.astronomical,
		       "sun never below -18 deg", "sun never above -18 deg");
	return 0;
}


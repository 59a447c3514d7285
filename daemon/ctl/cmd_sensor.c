/* cmd_sensor.c - the light sensor in the protocol: get sensor (what it
 * reads and what that did to the sky), the sensor verb (the devices it
 * knows, sensor: event lines) and its lines in status. */
#include "ctl_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "srv.h"

/* Values never hold spaces: device names and reasons get '_' for them. */
static void one_word(const char *text, char *buf, size_t size)
{
	size_t n = 0;

	for (const char *t = text; *t && n + 1 < size; t++)
		buf[n++] = (*t > ' ' && *t < 0x7f) ? *t : '_';
	buf[n] = 0;
	if (!n)
		snprintf(buf, size, "none");
}

/* "none" for NAN, else the number. */
static void number(double v, char *buf, size_t size)
{
	if (isnan(v))
		snprintf(buf, size, "none");
	else
		snprintf(buf, size, "%.9g", v);
}

static uint64_t rejected_total(const struct sensor_pipe_stats *p)
{
	uint64_t n = 0;

	for (int i = 0; i < SENSOR_REJECT_N; i++)
		n += p->rejected[i];
	return n;
}

static void reply_device(struct reply *r, const struct sensor_info *d)
{
	char name[SENSOR_TEXT_MAX], detail[SENSOR_TEXT_MAX], serial[64];

	one_word(d->bus_path, name, sizeof(name));
	ctl_reply_add(r, "device: %s\n", name);
	one_word(d->family, name, sizeof(name));
	ctl_reply_add(r, "family: %s\n", name);
	one_word(d->name, name, sizeof(name));
	one_word(d->serial, serial, sizeof(serial));
	one_word(d->detail, detail, sizeof(detail));
	ctl_reply_add(r, "name: %s\nserial: %s\ndevice_state: %s\ndetail: %s\n", name, serial,
		      d->bus_path[0] ? sensor_dev_state_name(d->state) : "none", detail);
}

/* The reading, what it did, the counters. */
static void reply_reading(struct reply *r, const struct srv_sensor_status *st)
{
	const struct sensor_reading *rd = &st->sensor.reading;
	char a[64], b[64];

	number(st->have_reading ? rd->lux : NAN, a, sizeof(a));
	number(st->have_reading ? rd->raw_lux : NAN, b, sizeof(b));
	ctl_reply_add(r, "lux: %s\nraw_lux: %s\n", a, b);
	number(st->age_s, a, sizeof(a));
	ctl_reply_add(r, "age_s: %s\nstale: %d\n", a, st->have_reading && rd->stale);
	number(st->ev100, a, sizeof(a));
	ctl_reply_add(r, "ev100: %s\ncloud_factor: %.9g\n", a, st->cloud_factor);
	number(st->clear_sky_lx, a, sizeof(a));
	ctl_reply_add(r, "clear_sky_lx: %s\n", a);
	number(st->elevation_deg, a, sizeof(a));
	number(st->deg_per_ln, b, sizeof(b));
	ctl_reply_add(r, "elevation_deg: %s\ndeg_per_ln: %s\n", a, b);
	ctl_reply_add(r, "curve: %s\ncurve_points: %zu\n",
		      st->curve == SRV_SENSOR_CURVE_TABLES ? "tables+usno" : "usno", st->curve_points);
	if (st->curve_points)
		ctl_reply_add(r, "curve_range_deg: %.3f,%.3f\n", st->curve_min_deg, st->curve_max_deg);
	else
		ctl_reply_add(r, "curve_range_deg: none\n");
	char why[sizeof(st->not_applied)];
	one_word(st->not_applied, why, sizeof(why));
	ctl_reply_add(r, "not_applied: %s\nchanges: %llu\ngeneration: %llu\n", why,
		      (unsigned long long)st->changes, (unsigned long long)st->generation);
}

static void reply_counters(struct reply *r, const struct srv_sensor_status *st)
{
	const struct sensor_status *s = &st->sensor;
	const struct sensor_counters *k = &s->counters;
	char by[256] = "", why[sizeof(s->why)];
	size_t o = 0;

	ctl_reply_add(r, "readings: %llu\naccepted: %llu\nrejected: %llu\noutputs: %llu\n",
		      (unsigned long long)k->readings, (unsigned long long)s->pipe.accepted,
		      (unsigned long long)rejected_total(&s->pipe), (unsigned long long)s->pipe.emitted);
	for (int i = 1; i < SENSOR_REJECT_N; i++)
		if (s->pipe.rejected[i] && o < sizeof(by))
			o += (size_t)snprintf(by + o, sizeof(by) - o, "%s%s=%llu", o ? "," : "",
					      sensor_reject_name((enum sensor_reject)i),
					      (unsigned long long)s->pipe.rejected[i]);
	ctl_reply_add(r, "rejected_by: %s\nlast_reject: %s\n", o ? by : "none",
		      s->pipe.last_reject ? sensor_reject_name(s->pipe.last_reject) : "none");
	ctl_reply_add(r, "transfers: %llu\ntimeouts: %llu\nio_errors: %llu\n",
		      (unsigned long long)k->transfers, (unsigned long long)k->timeouts,
		      (unsigned long long)k->io_errors);
	ctl_reply_add(r, "arrivals: %llu\ndepartures: %llu\nopens: %llu\nfailures: %llu\n",
		      (unsigned long long)k->arrivals, (unsigned long long)k->departures,
		      (unsigned long long)k->opens, (unsigned long long)k->failures);
	one_word(s->why, why, sizeof(why));
	ctl_reply_add(r, "last_error: %s\n", why);
}

int ctl_get_sensor(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	struct srv_sensor_status st;

	if (req->n_args > 1)
		return CTL_ACK(SKY_ACK_SYNTAX, "get sensor takes no arguments");
	if (srv_sensor_status(c->ctl->srv, &st) < 0)
		return CTL_ACK(SKY_ACK_STATE, "no light sensor in this skyd");
	ctl_reply_add(r, "mode: %s\nstate: %s\n", state_sensor_mode_name(st.mode),
		      sensor_state_name(st.sensor.state));
	reply_device(r, &st.sensor.device);
	reply_reading(r, &st);
	reply_counters(r, &st);
	return 0;
}

/* sensor list: one device: line each, its fields as key=value. */
static void reply_list(struct client *c, struct reply *r)
{
	struct sensor_info infos[32];
	char name[SENSOR_TEXT_MAX], detail[SENSOR_TEXT_MAX], serial[64];
	size_t n = srv_sensor_devices(c->ctl->srv, infos, 32);

	ctl_reply_add(r, "devices: %zu\n", n);
	for (size_t i = 0; i < n && i < 32; i++) {
		one_word(infos[i].name, name, sizeof(name));
		one_word(infos[i].serial, serial, sizeof(serial));
		one_word(infos[i].detail, detail, sizeof(detail));
		ctl_reply_add(r, "device: bus=%s family=%s id=%04x:%04x serial=%s state=%s selected=%d name=%s detail=%s\n",
			      infos[i].bus_path, infos[i].family, infos[i].vendor_id,
			      infos[i].product_id, serial, sensor_dev_state_name(infos[i].state),
			      infos[i].selected, name, detail);
	}
}

int ctl_cmd_sensor(struct client *c, const struct proto_request *req, struct reply *r,
		   char *msg, size_t msg_size)
{
	const struct proto_arg *a = &req->args[0];

	if (strcmp(a->key, "list") == 0 && !a->value) {
		reply_list(c, r);
		return 0;
	}
	if (strcmp(a->key, "events") == 0 && a->value) {
		if (strcmp(a->value, "0") && strcmp(a->value, "1"))
			return CTL_ACK(SKY_ACK_ARG, "events: '%s' is not 0 or 1", a->value);
		c->sub_sensor = a->value[0] == '1';
		ctl_reply_add(r, "events: %d\n", c->sub_sensor);
		return 0;
	}
	return CTL_ACK(SKY_ACK_SYNTAX, "usage: sensor list | sensor events=0|1");
}

void ctl_status_sensor(struct ctl *ctl, struct reply *r)
{
	struct srv_sensor_status st;
	char a[64];

	if (srv_sensor_status(ctl->srv, &st) < 0)
		return;
	if (st.mode == STATE_SENSOR_OFF)
		return;
	ctl_reply_add(r, "sensor_mode: %s\nsensor_state: %s\n", state_sensor_mode_name(st.mode),
		      sensor_state_name(st.sensor.state));
	number(st.have_reading ? st.sensor.reading.lux : NAN, a, sizeof(a));
	ctl_reply_add(r, "sensor_lux: %s\nsensor_stale: %d\n", a,
		      st.have_reading && st.sensor.reading.stale);
	number(st.ev100, a, sizeof(a));
	ctl_reply_add(r, "sensor_ev100: %s\nsensor_cloud_factor: %.9g\n", a, st.cloud_factor);
}

void ctl_sensor_event(void *ctx, const struct srv_sensor_status *st)
{
	struct ctl *ctl = ctx;
	const struct sensor_reading *rd = &st->sensor.reading;
	char line[512], lux[32], ev[32], el[32], why[sizeof(st->not_applied)];
	struct client *c, *next;

	number(st->have_reading ? rd->lux : NAN, lux, sizeof(lux));
	number(st->ev100, ev, sizeof(ev));
	number(st->elevation_deg, el, sizeof(el));
	one_word(st->not_applied, why, sizeof(why));
	int n = snprintf(line, sizeof(line),
			 "sensor: mode=%s state=%s lux=%s stale=%d ev100=%s cloud_factor=%.9g "
			 "elevation_deg=%s generation=%llu changes=%llu accepted=%llu rejected=%llu "
			 "mono_ns=%llu not_applied=%s\n",
			 state_sensor_mode_name(st->mode), sensor_state_name(st->sensor.state), lux,
			 st->have_reading && rd->stale, ev, st->cloud_factor, el,
			 (unsigned long long)st->generation, (unsigned long long)st->changes,
			 (unsigned long long)st->sensor.pipe.accepted,
			 (unsigned long long)rejected_total(&st->sensor.pipe),
			 (unsigned long long)st->reading_mono_ns, why);
	if (n < 0 || (size_t)n >= sizeof(line)) {
		n = (int)sizeof(line) - 1;
		line[n - 1] = '\n';
	}
	for (c = ctl->clients; c; c = next) {
		next = c->next;
		if (c->sub_sensor && ctl_client_queue(c, line, (size_t)n, -1) == 0)
			ctl_client_flush(c);
	}
}

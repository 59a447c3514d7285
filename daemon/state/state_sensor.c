/* state_sensor.c - the light sensor's keys in the sky's state: what its
 * readings do (sensor_mode), which device (sensor_select), how the
 * readings are filtered and the device is read. A block of its own: its
 * own table and parser, listed by `get` only while it differs from its
 * defaults. The ranges are sensor_config's (daemon/sensor/sensor.h), which
 * the service checks again when it applies them. docs/sensor.md. */
#include "state_internal.h"

#include <errno.h>
#include <stddef.h>
#include <string.h>

#include "proto.h"

static const char *const mode_names[] = { "off", "cloud", "elevation", "exposure", NULL };

/* The numeric keys: a double each in struct state_sensor. */
static const struct {
	const char *name;
	size_t offset;
	double min, max;
	const char *unit, *doc;
} nkeys[] = {
	{ "sensor_time_constant_s", offsetof(struct state_sensor, time_constant_s), 0, 86400, "s",
	  "smoothing of the readings (exponential, in ln lux); 0 passes them through" },
	{ "sensor_hysteresis", offsetof(struct state_sensor, hysteresis), 0, 10, "-",
	  "relative change of the smoothed reading that makes a new output (0.05: 5 %)" },
	{ "sensor_min_interval_s", offsetof(struct state_sensor, min_interval_s), 0, 86400, "s",
	  "rate limit: outputs at least this far apart" },
	{ "sensor_stale_after_s", offsetof(struct state_sensor, stale_after_s), 0.001, 86400, "s",
	  "no accepted reading for this long: the last value is kept and marked stale" },
	{ "sensor_max_lux", offsetof(struct state_sensor, max_lux), 1, 1e7, "lx",
	  "readings above are refused (no daylight is that bright)" },
	{ "sensor_floor_lux", offsetof(struct state_sensor, floor_lux), 1e-9, 1e3, "lx",
	  "added before the logarithm of smoothing and hysteresis: differences far below count less" },
	{ "sensor_report_interval_s", offsetof(struct state_sensor, report_interval_s), 0.01, 3600,
	  "s", "asked of the device: its HID report interval, the BH1750's poll period" },
	{ "sensor_io_timeout_s", offsetof(struct state_sensor, io_timeout_s), 0.01, 60, "s",
	  "a transfer taking longer is cancelled; three in a row stop the device" },
	{ "sensor_rescan_s", offsetof(struct state_sensor, rescan_s), 0.01, 3600, "s",
	  "looking for a device while none reads; a failed one is retried after up to 16 times this" },
};
#define N_NKEYS (sizeof(nkeys) / sizeof(nkeys[0]))

const char *const state_sensor_keys[] = {
	"sensor_mode", "sensor_select", "sensor_time_constant_s", "sensor_hysteresis",
	"sensor_min_interval_s", "sensor_stale_after_s", "sensor_max_lux", "sensor_floor_lux",
	"sensor_report_interval_s", "sensor_io_timeout_s", "sensor_rescan_s", NULL,
};

/* sensor_config_defaults' values, and the mode off. */
void state_sensor_defaults(struct state_sensor *ret)
{
	*ret = (struct state_sensor){ .mode = STATE_SENSOR_OFF, .time_constant_s = 5.0,
		.hysteresis = 0.05, .min_interval_s = 1.0, .stale_after_s = 30.0,
		.max_lux = 200000.0, .floor_lux = 0.01, .report_interval_s = 0.5,
		.io_timeout_s = 1.0, .rescan_s = 5.0 };
	snprintf(ret->select, sizeof(ret->select), "auto");
}

const char *state_sensor_mode_name(enum state_sensor_mode m)
{
	return (unsigned)m < sizeof(mode_names) / sizeof(mode_names[0]) - 1 ? mode_names[m] : "?";
}

static int find_nkey(const char *name)
{
	for (size_t i = 0; i < N_NKEYS; i++)
		if (strcmp(nkeys[i].name, name) == 0)
			return (int)i;
	return -1;
}

/* The forms of sensor_config's select; no spaces, as every value. */
static int valid_select(const char *v)
{
	return !strcmp(v, "auto") || !strcmp(v, "none") || (!strncmp(v, "bus:", 4) && v[4]) ||
	       (!strncmp(v, "serial:", 7) && v[7]) || (!strncmp(v, "name:", 5) && v[5]);
}

int state_set_sensor_key(struct sky_state *s, const char *key, const char *v, char *err,
			 size_t err_size)
{
	struct state_sensor *k = &s->sensor;
	double d;

	if (strcmp(key, "sensor_mode") == 0) {
		int m = state_enum_index(mode_names, v);
		if (m < 0)
			return ERR("sensor_mode: '%s' is not off, cloud, elevation or exposure", v);
		k->mode = (enum state_sensor_mode)m;
		return 0;
	}
	if (strcmp(key, "sensor_select") == 0) {
		if (strlen(v) >= sizeof(k->select))
			return ERR_RANGE("sensor_select: longer than %zu bytes", sizeof(k->select) - 1);
		if (!valid_select(v))
			return ERR("sensor_select: '%s' is not auto, none, bus:PORTS, serial:TEXT or name:TEXT", v);
		snprintf(k->select, sizeof(k->select), "%s", v);
		return 0;
	}
	int i = find_nkey(key);
	if (i < 0)
		return 1;
	if (proto_parse_number(v, &d) < 0)
		return ERR("%s: '%s' is not a finite number", key, v);
	if (d < nkeys[i].min || d > nkeys[i].max)
		return ERR_RANGE("%s: %g is outside [%g, %g]", key, d, nkeys[i].min, nkeys[i].max);
	*(double *)((char *)k + nkeys[i].offset) = d;
	return 0;
}

int state_get_sensor_key(const struct sky_state *s, const char *key, char *buf, size_t size)
{
	const struct state_sensor *k = &s->sensor;
	int i;

	if (strcmp(key, "sensor_mode") == 0)
		snprintf(buf, size, "%s", state_sensor_mode_name(k->mode));
	else if (strcmp(key, "sensor_select") == 0)
		snprintf(buf, size, "%s", k->select);
	else if ((i = find_nkey(key)) >= 0)
		snprintf(buf, size, "%.9g", *(const double *)((const char *)k + nkeys[i].offset));
	else
		return -ENOENT;
	return 0;
}

void state_foreach_sensor(const struct sky_state *s, state_emit_fn fn, void *ctx)
{
	struct sky_state d;
	char buf[STATE_SENSOR_SELECT_MAX], def[STATE_SENSOR_SELECT_MAX];
	int same = 1;

	state_sensor_defaults(&d.sensor);
	for (int i = 0; state_sensor_keys[i] && same; i++) {
		state_get_sensor_key(s, state_sensor_keys[i], buf, sizeof(buf));
		state_get_sensor_key(&d, state_sensor_keys[i], def, sizeof(def));
		same = strcmp(buf, def) == 0;
	}
	if (same)
		return;
	for (int i = 0; state_sensor_keys[i]; i++) {
		state_get_sensor_key(s, state_sensor_keys[i], buf, sizeof(buf));
		fn(ctx, state_sensor_keys[i], buf);
	}
}

void state_print_sensor_keys(FILE *f, bool markdown)
{
	struct sky_state s;
	char def[64], range[64];

	state_sensor_defaults(&s.sensor);
	state_print_row(f, markdown, "sensor_mode", "-", "off, cloud, elevation, exposure", "off", 0,
			"what a USB light sensor's readings do: the cloud factor, the sun's elevation, a suggested EV100 (docs/sensor.md)");
	state_print_row(f, markdown, "sensor_select", "-", "auto, none, bus:PORTS, serial:TEXT, name:TEXT",
			"auto", 0, "which sensor: the first that works, none, or by port path, serial number or name");
	for (size_t i = 0; i < N_NKEYS; i++) {
		state_get_sensor_key(&s, nkeys[i].name, def, sizeof(def));
		snprintf(range, sizeof(range), "[%g, %g]", nkeys[i].min, nkeys[i].max);
		state_print_row(f, markdown, nkeys[i].name, nkeys[i].unit, range, def, 0, nkeys[i].doc);
	}
}

/* state_sensor.c - the light sensor's keys in the sky's state (rows in
 * state_keys.c): the names of its modes and the form of sensor_select. The
 * ranges are sensor_config's (daemon/sensor/sensor.h), which the service
 * checks again when it applies them. docs/sensor.md. */
#include "state_internal.h"

#include <errno.h>
#include <string.h>

const char *const state_sensor_mode_names[] = {
	[STATE_SENSOR_OFF] = "off", [STATE_SENSOR_CLOUD] = "cloud",
	[STATE_SENSOR_ELEVATION] = "elevation", [STATE_SENSOR_EXPOSURE] = "exposure", NULL,
};

const char *state_sensor_mode_name(enum state_sensor_mode m)
{
	const size_t n = sizeof(state_sensor_mode_names) / sizeof(state_sensor_mode_names[0]) - 1;

	return (unsigned)m < n ? state_sensor_mode_names[m] : "?";
}

/* The forms of sensor_config's select; no spaces, as every value. */
static int valid_select(const char *v)
{
	return !strcmp(v, "auto") || !strcmp(v, "none") || (!strncmp(v, "bus:", 4) && v[4]) ||
	       (!strncmp(v, "serial:", 7) && v[7]) || (!strncmp(v, "name:", 5) && v[5]);
}

int state_set_sensor_select(struct sky_state *s, const struct state_key *k, const char *v,
			    uint32_t *ret_dirty, char *err, size_t err_size)
{
	char *select = s->sensor.select;

	if (strlen(v) >= sizeof(s->sensor.select))
		return ERR_RANGE("%s: longer than %zu bytes", k->name, sizeof(s->sensor.select) - 1);
	if (!valid_select(v))
		return ERR("%s: '%s' is not auto, none, bus:PORTS, serial:TEXT or name:TEXT", k->name, v);
	snprintf(select, sizeof(s->sensor.select), "%s", v);
	return 0;
}

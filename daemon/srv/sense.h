/* sense.h - the light sensor driving the sky: runs daemon/sensor's manager
 * as the state's sensor keys say, and turns each reading it hands on into
 * a change of the served state, by the mode (docs/sensor.md):
 *
 *   cloud: the reading over the clear-sky horizontal illuminance that the
 *     published tables give for the sun and place (sensor_sky_horizontal,
 *     with the cloud factor they were computed with taken out) is the new
 *     cloud factor (state_set_cloud_factor, the weather's, which also sets
 *     cloud_oktas to match);
 *   elevation: the sun's elevation is where a clear-sky illuminance curve
 *     gives the reading (the USNO curve, refined by points measured from
 *     the published tables); the sun becomes manual;
 *   exposure: a suggested EV100 for clients; the state and the tables stay.
 *
 * A change goes through srv_apply like a set: it coalesces with the rest
 * and names the generation that shows it. A follower of replication
 * (srv_may_change) applies none: its sky is the controller's, and the
 * output's not_applied says so. The sense is one of srv's
 * listeners: every accepted change (its sensor keys start, stop or
 * reconfigure the manager) and every publication (the cloud and elevation
 * modes read the new slot); and srv shows its status (srv_set_sensor). The pipeline's time constant,
 * hysteresis and rate limit (sensor_pipe) keep a passing cloud or a hand
 * from flooding the engine; a stale reading changes nothing more.
 */
#ifndef SKYD_SENSE_H
#define SKYD_SENSE_H

#include <stddef.h>
#include <stdint.h>

#include "sensor.h"
#include "srv.h"
#include "state.h"

struct loop;
struct srv;
struct sense;

/* Below this clear-sky illuminance of the lights (the sun about 6.5
 * degrees below the horizon) the cloud mode does not measure: the night
 * floor and the sensor's own floor make the ratio meaningless. */
#define SENSE_CLOUD_MIN_LX 1.0

/* The cloud factor's floor: 1 is a clear sky; below 1/1000 (ten times
 * darker than a thunderstorm's 1/100) a reading says more about the sensor
 * than about the clouds. */
#define SENSE_FACTOR_MIN 0.001

/* The sun's mean top-of-atmosphere illuminance: the elevation mode's curve
 * is for it, a reading is scaled by it over the sun's illuminance. */
#define SENSE_SUN_MEAN_LX 133800.0

/* The elevation mode refines its inversion after each publication (the
 * tables add a point to the curve) until the sun moves less than this. */
#define SENSE_ELEVATION_SETTLE_DEG 0.01

/* Called after each output of the pipeline and each change of the
 * manager's state or device, from the loop. */
typedef void (*sense_event_fn)(void *ctx, const struct srv_sensor_status *st);

/* Takes neither loop nor srv; they must outlive the sense. Adds itself to
 * srv's listeners and sensor (sense_free takes itself off). Starts the
 * manager at once when the served state's sensor_mode is not off. */
int sense_new(struct loop *l, struct srv *srv, struct sense **ret);
void sense_free(struct sense *s);
void sense_set_listener(struct sense *s, sense_event_fn fn, void *ctx);

void sense_status(const struct sense *s, struct srv_sensor_status *ret);
/* The devices the manager knows, as sensor_devices; 0 while none runs. */
size_t sense_devices(const struct sense *s, struct sensor_info *ret, size_t max);

#endif

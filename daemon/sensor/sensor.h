/* sensor.h - a USB light sensor that drives the sky: finds ambient light
 * sensors on USB, reads them through libusb on the daemon's event loop,
 * filters the readings and hands the result to a callback; with the pure
 * light-level maths the sensor modes need. docs/sensor.md says what is
 * supported and how to add a device family.
 *
 * Three parts, usable separately:
 *   the pipeline (sensor_pipe_*): pure, no USB; rejects nonsense, smooths,
 *     applies hysteresis and a rate limit, marks the value stale;
 *   the light levels (sensor_sky_*, sensor_curve_*, sensor_ev100): pure
 *     functions of the published tables (proto/skysample.h) and of lux;
 *   the manager (sensor_new ...): libusb on a struct loop, hot-plug, the
 *     device families (HID Sensor ambient light sensors; an MCP2221A USB to
 *     I2C bridge with a BH1750), the choice of one device, the list.
 *
 * Nothing here blocks the loop: libusb's file descriptors and timeouts are
 * loop handles, every transfer is asynchronous and has a deadline.
 */
#ifndef SKYD_SENSOR_H
#define SKYD_SENSOR_H

#include <stddef.h>
#include <stdint.h>

#include "skysample.h"

struct loop;
struct sensor;
struct sensor_pipe;

/* ---- readings and why one is refused ---- */

enum sensor_reject {
	SENSOR_REJECT_NONE = 0,
	SENSOR_REJECT_NAN,		/* not a number */
	SENSOR_REJECT_NEGATIVE,		/* below 0 lx */
	SENSOR_REJECT_HIGH,		/* above max_lux: no daylight is that bright */
	SENSOR_REJECT_UNIT,		/* the device's unit is not one its driver converts to lux */
	SENSOR_REJECT_SATURATED,	/* the sensor's counter is at the top of its range */
	SENSOR_REJECT_MALFORMED,	/* short or unknown report, value outside its declared
					 * range, failed bus exchange */
	SENSOR_REJECT_NOT_READY,	/* the device says its sensor has no valid data */
	SENSOR_REJECT_N
};

/* A short lower-case name ("nan", "unit", ...) for status lines. */
const char *sensor_reject_name(enum sensor_reject r);

/* What the pipeline hands on. */
struct sensor_reading {
	double lux;			/* smoothed; while stale, the last good value */
	double raw_lux;			/* the last accepted reading as the device gave it */
	uint64_t time_ns;		/* CLOCK_MONOTONIC of the last accepted reading */
	int stale;			/* 1: nothing accepted for stale_after_s */
};

/* ---- the pipeline (pure) ---- */

struct sensor_pipe_config {
	double time_constant_s;		/* exponential smoothing; 0 passes readings through */
	double hysteresis;		/* relative change that makes a new output (0.05: 5 %) */
	double min_interval_s;		/* rate limit: outputs at least this far apart */
	double stale_after_s;		/* no accepted reading for this long: output goes stale */
	double max_lux;			/* readings above are refused (SENSOR_REJECT_HIGH) */
	double floor_lux;		/* smoothing and hysteresis work on ln(lux + floor_lux),
					 * so that differences far below the floor do not count */
};

struct sensor_pipe_stats {
	uint64_t accepted;
	uint64_t rejected[SENSOR_REJECT_N];	/* [SENSOR_REJECT_NONE] stays 0 */
	uint64_t emitted;		/* outputs sensor_pipe_poll handed out */
	enum sensor_reject last_reject;	/* the most recent refusal, NONE if none yet */
};

/* Defaults: 5 s, 5 %, 1 s, 30 s, 200 klx, 0.01 lx. */
void sensor_pipe_defaults(struct sensor_pipe_config *ret);
/* 0, or -EINVAL with err naming the field that is out of range. */
int sensor_pipe_check(const struct sensor_pipe_config *cfg, char *err, size_t err_size);

int sensor_pipe_new(const struct sensor_pipe_config *cfg, struct sensor_pipe **ret);
void sensor_pipe_free(struct sensor_pipe *p);
/* A new configuration; the smoothed value and the counters stay. */
void sensor_pipe_configure(struct sensor_pipe *p, const struct sensor_pipe_config *cfg);
/* Forgets the value (a new device): the next accepted reading starts over. */
void sensor_pipe_reset(struct sensor_pipe *p);

/* Feeds one reading taken at now_ns (monotonic, not decreasing). why is the
 * driver's own verdict, SENSOR_REJECT_NONE when it found nothing wrong; the
 * pipeline adds its checks (NaN, negative, above max_lux). Returns the
 * reason the reading was refused, SENSOR_REJECT_NONE when it was taken.
 * A refused reading changes nothing but the counters. */
enum sensor_reject sensor_pipe_push(struct sensor_pipe *p, double lux, enum sensor_reject why,
				    uint64_t now_ns);

/* Whether an output is due at now_ns: 1 with *ret filled (and counted as
 * emitted), else 0. An output is due for the first value, when the
 * smoothed value moved by the hysteresis since the last output, and when
 * the value goes stale or fresh again; never sooner than min_interval_s
 * after the previous output. *ret_next_ns gets the monotonic time at which
 * the answer may change without a push (a held-back output, the value
 * going stale), 0 when only a push can change it. */
int sensor_pipe_poll(struct sensor_pipe *p, uint64_t now_ns, struct sensor_reading *ret,
		     uint64_t *ret_next_ns);

/* The last output (all zero before the first). */
void sensor_pipe_last(const struct sensor_pipe *p, struct sensor_reading *ret);
void sensor_pipe_stats(const struct sensor_pipe *p, struct sensor_pipe_stats *ret);

/* ---- light levels (pure) ---- */

/* Rec. 709 luminance of linear RGB, the weights PROTOCOL.md uses. */
double sensor_sky_luminance(const double rgb[3]);

/* Illuminance on a horizontal surface at the observer, from the tables of
 * one slot: the sun's and the moon's direct light (top-of-atmosphere
 * illuminance times the transmittance table toward them times the cosine
 * of their zenith angle, 0 below the horizon) plus the sky-view radiance
 * integrated over the upper hemisphere with cosine weight
 * (skysample_ambient). The radiance is in cd/m2 when the illuminances are
 * in lx, so all terms are lx; each is the Rec. 709 luminance of its RGB. */
struct sensor_sky_lux {
	double sun_lx, moon_lx, sky_lx;
	double total_lx;
};
void sensor_sky_horizontal(const struct skysample_table *transmittance,
			   const struct skysample_table *skyview, const struct sky_shm_state *st,
			   struct sensor_sky_lux *ret);

/* A clear-sky illuminance curve E(elevation), sampled at increasing
 * elevations. The inversion reads it in ln(E), linear between samples. */
struct sensor_curve {
	const double *elevation_deg;
	const double *lux;
	size_t n;
};

/* USNO Circular 171 (Janiczek and DeYoung 1987), horizontal illuminance
 * under a clear sky, sun only: -12 deg 0.008 lx, -6 deg 3.4 lx,
 * -0.8 deg 464 lx, 0 deg 759 lx, 10 deg 11.1 klx, 30 deg 46 klx,
 * 60 deg 103 klx, 90 deg 128.8 klx. Strictly increasing over [-12, 90];
 * below -12 deg starlight and airglow (about 0.002 lx) take over and the
 * curve cannot be inverted. */
extern const struct sensor_curve sensor_curve_usno;

/* The sun elevation at which the curve gives lux. 0 with
 * *ret_elevation_deg and, if not NULL, *ret_deg_per_ln: how many degrees a
 * relative error of lux moves the answer (d elevation / d ln E; 1 deg in
 * twilight, over 100 deg near the zenith, where the inversion says little).
 * -ERANGE when lux is outside the curve's range (not NaN, nothing set);
 * -EDOM when the curve is not strictly increasing in both columns or has
 * fewer than two samples or a sample <= 0 lx; -EINVAL for NaN. */
int sensor_curve_invert(const struct sensor_curve *c, double lux, double *ret_elevation_deg,
			double *ret_deg_per_ln);

/* The incident-light calibration constant of a flat (cosine) receptor in
 * lx s (ISO 2720:1974 allows 240 to 400; meters use 250). */
#define SENSOR_EV_INCIDENT_C 250.0

/* The suggested exposure value at ISO 100 for illuminance lux, from the
 * incident-light exposure equation N^2 / t = E S / C: EV100 =
 * log2(E * 100 / C). -inf at 0 lx, NaN below. */
double sensor_ev100(double lux);

/* ---- the manager (libusb on the loop) ---- */

#define SENSOR_SELECT_MAX 128
#define SENSOR_TEXT_MAX 96

struct sensor_config {
	/* Which device: "" or "auto" the first that works; "none" none;
	 * "bus:1-4.2" the device at that port path (as /sys/bus/usb/devices
	 * names it); "serial:TEXT" the device with that serial number;
	 * "name:TEXT" the first whose manufacturer and product contain TEXT
	 * (case-insensitive). */
	char select[SENSOR_SELECT_MAX];
	struct sensor_pipe_config pipe;
	double report_interval_s;	/* asked of the device (HID report interval, BH1750 poll) */
	double io_timeout_s;		/* a control transfer or I2C exchange taking longer is cancelled */
	double rescan_s;		/* rescan and retry period while no device reads; failed
					 * devices back off up to 16 times this */
};

/* Defaults: "auto", sensor_pipe_defaults, 0.5 s, 1 s, 5 s. */
void sensor_config_defaults(struct sensor_config *ret);
/* 0, or -EINVAL with err naming the field (select syntax included). */
int sensor_config_check(const struct sensor_config *cfg, char *err, size_t err_size);

/* What a device is doing. */
enum sensor_dev_state {
	SENSOR_DEV_IDLE = 0,		/* known, not opened (not chosen, or list mode finished) */
	SENSOR_DEV_STARTING,		/* opened, its driver is finding out what it is */
	SENSOR_DEV_READING,		/* the driver found a sensor and reads it */
	SENSOR_DEV_CLOSING,		/* transfers being cancelled before it is closed */
	SENSOR_DEV_FAILED,		/* stopped on an error; retried after a back-off */
	SENSOR_DEV_UNSUPPORTED,		/* not a light sensor (never opened again) */
};
const char *sensor_dev_state_name(enum sensor_dev_state s);

/* One device the manager knows. */
struct sensor_info {
	char bus_path[32];		/* "1-4.2"; what "bus:" selects */
	char family[24];		/* "hid-sensor", "mcp2221-bh1750" */
	char name[SENSOR_TEXT_MAX];	/* manufacturer and product, or "vvvv:pppp" */
	char serial[64];		/* "" when the device has none */
	uint16_t vendor_id, product_id;
	enum sensor_dev_state state;
	int selected;			/* matches the config's select */
	char detail[SENSOR_TEXT_MAX];	/* what the driver found, or why it stopped */
};

/* One line for --list-sensors and get sensor:
 * "1-4.2 hid-sensor 1209:1234 serial=ABC state=reading 'name' (detail)". */
int sensor_info_format(const struct sensor_info *i, char *buf, size_t size);

enum sensor_state {
	SENSOR_STATE_OFF = 0,		/* select is "none" */
	SENSOR_STATE_UNAVAILABLE,	/* libusb could not start; see why */
	SENSOR_STATE_SEARCHING,		/* no device reads */
	SENSOR_STATE_STARTING,		/* a device is being opened and identified */
	SENSOR_STATE_READING,		/* readings arrive */
	SENSOR_STATE_STALE,		/* a device is open but nothing was accepted for stale_after_s */
};
const char *sensor_state_name(enum sensor_state s);

struct sensor_counters {
	uint64_t readings;		/* every reading a driver handed in */
	uint64_t transfers;		/* completed transfers */
	uint64_t timeouts;		/* transfers cancelled at their deadline */
	uint64_t io_errors;		/* stalls, overflows, other transfer errors */
	uint64_t arrivals, departures;	/* hot-plug events of candidate devices */
	uint64_t opens;			/* devices opened */
	uint64_t failures;		/* devices stopped on an error */
};

struct sensor_status {
	enum sensor_state state;
	struct sensor_info device;	/* the device in use; bus_path "" when none */
	char why[160];			/* the latest problem in words, "" when none */
	struct sensor_reading reading;	/* the pipeline's last output */
	struct sensor_pipe_stats pipe;
	struct sensor_counters counters;
};

/* Called for each output of the pipeline, from the loop. It may call
 * sensor_get_status or sensor_set_config, not sensor_free. */
typedef void (*sensor_fn)(void *ctx, const struct sensor_reading *r);

/* Called after any event that changed the status (sensor_get_status: the
 * state, the device in use and its state, why, the counters) or the list
 * of devices; events that come together are told once. From the loop;
 * it may call what sensor_fn may. NULL stops it. */
typedef void (*sensor_status_fn)(void *ctx);
void sensor_on_status(struct sensor *s, sensor_status_fn fn, void *ctx);

/* Starts the manager on l: libusb's fds join the loop, hot-plug (or a
 * rescan timer) watches for devices, the chosen device is opened and read.
 * fn (may be NULL) gets the pipeline's outputs. -EINVAL for a config that
 * sensor_config_check refuses, -ENOMEM. When libusb itself cannot start
 * (no usbfs), the manager still exists in SENSOR_STATE_UNAVAILABLE. */
int sensor_new(struct loop *l, const struct sensor_config *cfg, sensor_fn fn, void *ctx,
	       struct sensor **ret);
/* Cancels the transfers, gives interfaces back to their kernel drivers,
 * closes libusb. Waits at most about 100 ms for cancellations. */
void sensor_free(struct sensor *s);

/* Applies a new configuration; a new select closes the device in use when
 * it no longer matches and looks for one that does. 0 or -EINVAL. */
int sensor_set_config(struct sensor *s, const struct sensor_config *cfg);

void sensor_get_status(const struct sensor *s, struct sensor_status *ret);
/* Up to max known devices into ret; returns how many are known. */
size_t sensor_devices(const struct sensor *s, struct sensor_info *ret, size_t max);

/* For skyd --list-sensors: runs a manager on a loop of its own, opens
 * every candidate device to find out what it is, and returns them all
 * (malloc'ed array in *ret, free() it) once each is identified or
 * timeout_s passed. Devices are closed and given back to their kernel
 * drivers before it returns. 0 or -errno (-ENODEV: libusb could not start,
 * with err saying why). */
int sensor_list(const struct sensor_config *cfg, double timeout_s, struct sensor_info **ret,
		size_t *ret_n, char *err, size_t err_size);

#endif

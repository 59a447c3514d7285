/* sensor_internal.h - what the files of the sensor module share: the HID
 * report descriptor parser (sensor_hidrd.c, pure) and the driver interface
 * between the manager (sensor.c) and the device families (sensor_hid.c,
 * sensor_mcp2221.c). A new family is one more file with one more
 * struct sensor_driver, listed in sensor_drivers[] (sensor.c). */
#ifndef SKYD_SENSOR_INTERNAL_H
#define SKYD_SENSOR_INTERNAL_H

#include <libusb.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "sensor.h"

/* ---- HID report descriptors (HID 1.11 section 6.2.2; usages from the HID
 * Usage Tables' Sensors page, HUTRR39) ---- */

#define SENSOR_HID_PAGE_SENSOR 0x20u
#define SENSOR_HID_USAGE(page, id) (((uint32_t)(page) << 16) | (id))
#define SENSOR_HID_ALS SENSOR_HID_USAGE(0x20, 0x0041)		/* Light: Ambient Light */
#define SENSOR_HID_ILLUMINANCE SENSOR_HID_USAGE(0x20, 0x04D1)	/* Data Field: Illuminance */
#define SENSOR_HID_SENSOR_STATE SENSOR_HID_USAGE(0x20, 0x0201)	/* Property: Sensor State */
#define SENSOR_HID_REPORT_INTERVAL SENSOR_HID_USAGE(0x20, 0x030E)
#define SENSOR_HID_SENSITIVITY_ABS SENSOR_HID_USAGE(0x20, 0x030F)
#define SENSOR_HID_REPORTING_STATE SENSOR_HID_USAGE(0x20, 0x0316)
#define SENSOR_HID_POWER_STATE SENSOR_HID_USAGE(0x20, 0x0319)
/* Data-field modifiers live in the usage's top four bits: illuminance's
 * own change sensitivity, absolute (lux) or relative (percent). */
#define SENSOR_HID_MOD_SENSITIVITY_ABS 0x1000u
#define SENSOR_HID_MOD_SENSITIVITY_REL_PCT 0xE000u
/* The selectors those properties are set to or compared with. */
#define SENSOR_HID_STATE_READY SENSOR_HID_USAGE(0x20, 0x0801)
#define SENSOR_HID_REPORTING_ALL_EVENTS SENSOR_HID_USAGE(0x20, 0x0841)
#define SENSOR_HID_POWER_D0 SENSOR_HID_USAGE(0x20, 0x0851)
#define SENSOR_HID_SENSITIVITY_REL_PCT SENSOR_HID_USAGE(0x20, 0x0311)

/* HID units: nibble 0 the system (1 SI linear), then the exponents of
 * length, mass, time, temperature, current, luminous intensity. Lux is
 * cd sr / m^2: length -2, luminous intensity 1. */
#define SENSOR_HID_UNIT_LUX 0x010000E1u

enum sensor_hid_kind { SENSOR_HID_INPUT = 0, SENSOR_HID_OUTPUT = 1, SENSOR_HID_FEATURE = 2 };

/* One field of one report. */
struct sensor_hid_field {
	int present;
	enum sensor_hid_kind kind;
	uint8_t report_id;		/* 0 when the descriptor uses no report ids */
	uint32_t bit_offset;		/* from the start of the report's data, after the id byte */
	uint32_t bit_size;		/* 1..32 */
	uint32_t usage;			/* page << 16 | id; for an array, its collection's usage */
	int is_array;
	int64_t logical_min, logical_max;	/* logical_max read unsigned when min >= 0 */
	uint32_t unit;
	int unit_exponent;		/* -8..7 */
	/* For the selector properties (reporting state, power state, sensor
	 * state): the value that means All Events, D0 Full Power, Ready. An
	 * array's value is logical_min plus the selector's place in its usage
	 * list; a plain variable takes logical_min + 1, the spec's order. */
	int64_t wanted;
};

#define SENSOR_HID_MAX_REPORTS 64

/* What the ambient light sensor in a report descriptor looks like. */
struct sensor_hid_layout {
	int uses_report_ids;
	struct sensor_hid_field illuminance;	/* input */
	struct sensor_hid_field sensor_state;	/* input, optional */
	struct sensor_hid_field reporting_state, power_state, report_interval;	/* features */
	struct sensor_hid_field sensitivity_abs, sensitivity_rel;		/* features */
	/* Byte length of each report (id byte included when ids are used). */
	struct {
		enum sensor_hid_kind kind;
		uint8_t id;
		uint32_t bytes;
	} reports[SENSOR_HID_MAX_REPORTS];
	size_t n_reports;
};

/* Parses a report descriptor and finds the ambient light sensor in it: an
 * input field of usage Illuminance inside a collection of usage Ambient
 * Light, and its properties in the same collection. 0; -ENOENT when the
 * descriptor parses but holds no such sensor; -EINVAL when it is malformed
 * (unbalanced collections, a field of more than 32 bits, a report over
 * 4096 bytes, an item running past the end, push/pop misuse). */
int sensor_hid_parse(const uint8_t *desc, size_t len, struct sensor_hid_layout *ret);

/* The byte length of report (kind, id), 0 if the descriptor has none. */
uint32_t sensor_hid_report_bytes(const struct sensor_hid_layout *l, enum sensor_hid_kind kind,
				 uint8_t id);

/* Reads field f from a report as the device sent it (id byte first when
 * the descriptor uses ids). 0 with the value, sign-extended when the
 * logical minimum is negative; -EMSGSIZE when the report is too short or
 * carries another id. */
int sensor_hid_get(const struct sensor_hid_layout *l, const struct sensor_hid_field *f,
		   const uint8_t *report, size_t len, int64_t *ret_value);
/* Writes value into field f of a report buffer of len bytes laid out as
 * sensor_hid_get reads it (the id byte included). -EMSGSIZE when it does
 * not fit. */
int sensor_hid_put(const struct sensor_hid_layout *l, const struct sensor_hid_field *f,
		   uint8_t *report, size_t len, int64_t value);

/* The scale from logical value to lux of an illuminance field: 0 with
 * 10^unit_exponent when its unit is lux, or unspecified (0) or the bare
 * SI system (1), which HUTRR39 and Linux read as the field's default unit,
 * lux; -ENOTSUP for any other unit. */
int sensor_hid_lux_scale(const struct sensor_hid_field *f, double *ret_scale);

/* What one input report says of the illuminance. */
enum sensor_hid_input {
	SENSOR_HID_IN_OTHER = 0,	/* another report of the device (a hub's other sensor) */
	SENSOR_HID_IN_MALFORMED,	/* too short, or an id that no input report has */
	SENSOR_HID_IN_RANGE,		/* outside the field's logical range */
	SENSOR_HID_IN_NOT_READY,	/* a value, but the sensor state says not ready */
	SENSOR_HID_IN_READING,		/* a value */
};
/* Reads the illuminance (and, in the same report, the sensor state) from
 * an input report as the device sent it. *ret_value gets the logical value
 * for IN_RANGE, IN_NOT_READY and IN_READING, and is untouched otherwise. */
enum sensor_hid_input sensor_hid_input(const struct sensor_hid_layout *l, const uint8_t *report,
				       size_t len, int64_t *ret_value);

/* ---- the driver interface ---- */

struct sensor_dev;

/* Completion of a driver's transfer. status: 0, -ETIMEDOUT (cancelled at
 * its deadline), -EPIPE (stall), -EOVERFLOW, -EIO. Not called when the
 * device is going away (the manager handles that). data: for an IN
 * transfer the bytes received, for a control transfer the data stage. */
typedef void (*sensor_xfer_fn)(struct sensor_dev *d, int status, const uint8_t *data,
			       size_t len);
typedef void (*sensor_dev_timer_fn)(struct sensor_dev *d);

struct sensor_driver {
	const char *family;		/* short name, also what sensor_info.family says */
	/* Judging by the descriptors alone (no I/O), the interface this
	 * family would claim, or -1 when the device is not one of it. */
	int (*match)(const struct libusb_device_descriptor *dd,
		     const struct libusb_config_descriptor *cfg);
	/* Before the device is opened: may it be opened at all? Reads only
	 * what the kernel already holds (sysfs). 0 to go on, -ENODEV when it
	 * is certainly not a light sensor (detail says why; the device is
	 * never opened, so a keyboard keeps its kernel driver). May be NULL. */
	int (*precheck)(struct sensor_dev *d);
	size_t priv_size;		/* zeroed before start */
	/* The interface is claimed: start the asynchronous work. Call
	 * sensor_dev_ready once the device is known to be a light sensor,
	 * sensor_dev_reading for each reading, sensor_dev_fail to give up.
	 * 0 or -errno (the device is then closed as failed). */
	int (*start)(struct sensor_dev *d);
	/* The device is going (its transfers are cancelled by the manager and
	 * its timer disarmed): free what start allocated. May be NULL. */
	void (*stop)(struct sensor_dev *d);
};

extern const struct sensor_driver sensor_hid_driver;
extern const struct sensor_driver sensor_mcp2221_driver;

void *sensor_dev_priv(struct sensor_dev *d);
const struct sensor_config *sensor_dev_config(const struct sensor_dev *d);
int sensor_dev_interface(const struct sensor_dev *d);
libusb_device *sensor_dev_usb(const struct sensor_dev *d);
/* The port path ("1-4.2"), for sysfs look-ups. */
const char *sensor_dev_bus_path(const struct sensor_dev *d);

/* Asynchronous transfers with a deadline of timeout_ms (0: the config's
 * io_timeout_s). length is the data stage or the buffer; out, when not
 * NULL, the bytes to send (OUT direction). 0 or -errno; fn is called once
 * for each transfer that was submitted. */
int sensor_dev_control(struct sensor_dev *d, uint8_t request_type, uint8_t request,
		       uint16_t value, uint16_t index, const uint8_t *out, uint16_t length,
		       unsigned timeout_ms, sensor_xfer_fn fn);
int sensor_dev_interrupt(struct sensor_dev *d, uint8_t endpoint, const uint8_t *out,
			 uint16_t length, unsigned timeout_ms, sensor_xfer_fn fn);
/* The driver's one timer: fn after delay_ns (re-arming replaces). */
int sensor_dev_timer(struct sensor_dev *d, uint64_t delay_ns, sensor_dev_timer_fn fn);

/* The device is a light sensor; detail says what was found. */
void sensor_dev_ready(struct sensor_dev *d, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* One reading and the driver's verdict on it (SENSOR_REJECT_NONE if fine). */
void sensor_dev_reading(struct sensor_dev *d, double lux, enum sensor_reject why);
/* A problem that does not stop the device (garbage report, a retry). */
void sensor_dev_note(struct sensor_dev *d, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
/* The driver gives up: unsupported != 0 when the device is not a light
 * sensor at all (never retried), else it failed and is retried later. The
 * device is closed once its transfers are cancelled. */
void sensor_dev_fail(struct sensor_dev *d, int unsupported, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

/* Reads a small sysfs attribute of the device or of one of its interfaces
 * (relative path below /sys/bus/usb/devices/<bus path>), trailing newline
 * removed. Bytes read or -errno. */
ssize_t sensor_dev_sysfs(const struct sensor_dev *d, const char *rel, void *buf, size_t size);
/* The first entry of directory rel (as above) whose name starts with
 * prefix, into ret. 0 or -errno (-ENOENT: none). */
int sensor_dev_sysfs_find(const struct sensor_dev *d, const char *rel, const char *prefix,
			  char *ret, size_t size);

/* ---- the manager's state, shared by sensor.c (devices, selection, the
 * loop) and sensor_dev.c (one device: open, transfers, close) ---- */

struct loop;
struct loop_timer;
struct loop_io;

/* Transfers that time out or fail this many times in a row stop the device. */
#define SENSOR_MAX_BAD_IN_ROW 3
/* How often libusb is serviced while a transfer is in flight on a file
 * descriptor that epoll refuses (a regular file: what device nodes are
 * under umockdev; usbfs nodes are always watched). */
#define SENSOR_POLL_NS 2000000ull
/* Cancelled transfers that have not come back by then are abandoned and
 * the device closed anyway. */
#define SENSOR_CLOSE_GRACE_NS 1000000000ull
#define SENSOR_SYSFS_USB "/sys/bus/usb/devices"

struct sensor_xfer {
	struct sensor_dev *d;
	struct libusb_transfer *t;
	sensor_xfer_fn fn;
	int control;
	struct sensor_xfer *next;
};

struct sensor_dev {
	struct sensor *s;
	struct sensor_dev *next;
	libusb_device *usb;
	libusb_device_handle *h;
	const struct sensor_driver *drv;
	void *priv;
	int iface;
	int claimed, detached;
	enum sensor_dev_state state;
	enum sensor_dev_state after_close;
	int gone;			/* left the bus: freed once closed */
	int probed;			/* list mode: identified or given up */
	struct sensor_xfer *xfers;	/* in flight */
	struct loop_timer *timer;	/* the driver's */
	sensor_dev_timer_fn timer_fn;
	int bad_in_row;			/* transfers timed out or failed in a row */
	int failures;			/* consecutive failed starts, for the back-off */
	uint64_t retry_ns;		/* FAILED: not before */
	uint64_t close_ns;		/* CLOSING since */
	uint64_t fresh_ns;		/* ready, or last accepted reading */
	char pending_note[SENSOR_TEXT_MAX];	/* the driver's note on the reading to come */
	char last_logged[SENSOR_TEXT_MAX];
	uint64_t logged_ns;		/* start of the current log window */
	int logged_lines;		/* lines logged in it */
	struct sensor_info info;
};

struct sensor_fd {
	int fd;
	struct loop_io *io;		/* NULL: epoll refused it, polled instead */
	struct sensor_fd *next;
};

struct sensor_event {
	libusb_device *usb;		/* referenced */
	int arrived;
};

struct sensor {
	struct loop *loop;
	struct sensor_config cfg;
	sensor_fn fn;
	void *ctx;
	libusb_context *usb;
	int hotplug;
	libusb_hotplug_callback_handle hotplug_handle;
	struct sensor_fd *fds;
	struct loop_timer *service_timer;
	struct loop_timer *rescan_timer;
	struct loop_timer *pipe_timer;
	struct sensor_dev *devs;
	struct sensor_dev *active;
	struct sensor_pipe *pipe;
	struct sensor_event *events;
	size_t n_events, events_cap;
	int list_mode;
	sensor_status_fn status_fn;
	void *status_ctx;
	uint64_t status_key;		/* digest of what the last status call saw */
	int settling;
	int in_events;			/* inside libusb_handle_events */
	int config_pending;		/* set_config came while dispatching: apply in settle */
	struct sensor_config pending_cfg;
	char why[160];
	struct sensor_counters counters;
};

/* sensor.c */
/* Brings everything up to date after any event: queued hot-plug events,
 * devices whose transfers have all come back are closed, departed ones
 * freed, the device to read chosen, timers armed. Does nothing while
 * libusb is dispatching (it runs right after). */
void sensor_settle(struct sensor *s);
uint64_t sensor_s_to_ns(double s);

/* sensor_dev.c */
const char *sensor_usb_error(int r);
/* The latest problem, for the status. */
void sensor_note_why(struct sensor *s, const char *text);
/* A text attribute (newline stripped, unprintable bytes replaced); ""
 * when it cannot be read. */
void sensor_dev_sysfs_text(const struct sensor_dev *d, const char *rel, char *buf, size_t size);
/* Opens d, takes its interface from the kernel driver and starts its
 * driver; on failure d ends FAILED with the reason. */
void sensor_dev_open(struct sensor *s, struct sensor_dev *d);
/* Starts closing d (state after once closed): the driver stops, its
 * transfers are cancelled; sensor_settle closes the handle once they have
 * all come back. why (may be NULL) becomes its detail. */
void sensor_dev_close(struct sensor_dev *d, enum sensor_dev_state after, const char *why);
/* Releases the interface, gives it back to its kernel driver, closes the
 * handle and frees what is still in flight. */
void sensor_dev_finish_close(struct sensor_dev *d);
void sensor_dev_free(struct sensor_dev *d);
/* Hands the pipeline's due outputs to the callback and arms its timer. */
void sensor_pump(struct sensor *s);

#endif

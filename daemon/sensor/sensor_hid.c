/* sensor_hid.c - the HID Sensor family: ambient light sensors found by the
 * usages in their report descriptor (Sensors page 0x20, Ambient Light 0x41,
 * Illuminance 0x04D1), whatever their vendor. Properties are set through
 * feature reports (GET_REPORT, change, SET_REPORT); readings arrive as
 * input reports on the interrupt IN endpoint. */
#include "sensor_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HID_DESC_CLASS 0x21		/* the HID descriptor, in the interface's extra bytes */
#define HID_DESC_REPORT 0x22
#define HID_GET_REPORT 0x01
#define HID_SET_REPORT 0x09
#define HID_REPORT_TYPE_INPUT 0x01
#define HID_REPORT_TYPE_FEATURE 0x03
#define HID_MAX_DESC 4096
#define HID_UNIT_SECOND 0x1001u	/* SI linear, time^1; the report interval's default is ms */
#define MAX_FEATURE_REPORTS 8

struct hid_priv {
	struct sensor_hid_layout layout;
	uint8_t ep_in;
	uint16_t in_size;
	uint16_t desc_len;		/* from the HID descriptor, 0 when absent */
	double scale;			/* lux per logical unit */
	int unit_ok;
	uint8_t features[MAX_FEATURE_REPORTS];
	int n_features, feature;	/* feature reports to set, the one in progress */
	uint8_t report[HID_MAX_DESC];	/* the report descriptor, then feature scratch */
};

/* The first HID interface with an interrupt IN endpoint: a candidate; what
 * it is, only its report descriptor says. */
static int hid_match(const struct libusb_device_descriptor *dd,
		     const struct libusb_config_descriptor *cfg)
{
	for (int i = 0; i < cfg->bNumInterfaces; i++) {
		if (cfg->interface[i].num_altsetting < 1)
			continue;
		const struct libusb_interface_descriptor *alt = &cfg->interface[i].altsetting[0];
		if (alt->bInterfaceClass != LIBUSB_CLASS_HID)
			continue;
		for (int e = 0; e < alt->bNumEndpoints; e++) {
			const struct libusb_endpoint_descriptor *ep = &alt->endpoint[e];
			if ((ep->bEndpointAddress & LIBUSB_ENDPOINT_IN) &&
			    (ep->bmAttributes & 3) == LIBUSB_TRANSFER_TYPE_INTERRUPT)
				return alt->bInterfaceNumber;
		}
	}
	return -1;
}

/* The interface's directory below the device's in sysfs ("1-2:1.0"). */
static int interface_dir(struct sensor_dev *d, char *buf, size_t size)
{
	struct libusb_config_descriptor *cfg;

	if (libusb_get_active_config_descriptor(sensor_dev_usb(d), &cfg) < 0)
		return -EIO;
	snprintf(buf, size, "%s:%u.%d", sensor_dev_bus_path(d), cfg->bConfigurationValue,
		 sensor_dev_interface(d));
	libusb_free_config_descriptor(cfg);
	return 0;
}

/* The report descriptor the kernel's HID driver already read, when one is
 * bound: bytes, or -errno. */
static ssize_t sysfs_descriptor(struct sensor_dev *d, uint8_t *buf, size_t size)
{
	char ifdir[64], child[64], rel[192];

	if (interface_dir(d, ifdir, sizeof(ifdir)) < 0 ||
	    sensor_dev_sysfs_find(d, ifdir, "0003:", child, sizeof(child)) < 0)
		return -ENOENT;
	snprintf(rel, sizeof(rel), "%s/%s/report_descriptor", ifdir, child);
	return sensor_dev_sysfs(d, rel, buf, size);
}

/* Before opening: a HID interface bound to a kernel driver is only taken
 * from it when its report descriptor shows an ambient light sensor, so
 * that keyboards and mice are never touched. */
static int hid_precheck(struct sensor_dev *d)
{
	struct sensor_hid_layout l;
	char ifdir[64], rel[96];
	uint8_t *desc = malloc(HID_MAX_DESC);
	ssize_t n = desc ? sysfs_descriptor(d, desc, HID_MAX_DESC) : -ENOMEM;
	int r = n >= 0 ? sensor_hid_parse(desc, (size_t)n, &l) : 0;

	free(desc);
	if (n >= 0) {
		if (r == -ENOENT)
			sensor_dev_fail(d, 1, "no ambient light sensor in its report descriptor");
		else if (r < 0)
			sensor_dev_fail(d, 1, "malformed report descriptor");
		return r < 0 ? -ENODEV : 0;
	}
	if (interface_dir(d, ifdir, sizeof(ifdir)) == 0) {
		snprintf(rel, sizeof(rel), "%s/driver/uevent", ifdir);
		uint8_t b;
		if (sensor_dev_sysfs(d, rel, &b, 1) >= 0) {
			sensor_dev_fail(d, 1, "its kernel driver shows no report descriptor");
			return -ENODEV;
		}
	}
	return 0;
}

static void submit_in(struct sensor_dev *d);

/* One input report, from the interrupt endpoint or asked for. */
static void handle_input(struct sensor_dev *d, const uint8_t *data, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);
	const struct sensor_hid_field *f = &p->layout.illuminance;
	int64_t v = 0;

	switch (sensor_hid_input(&p->layout, data, len, &v)) {
	case SENSOR_HID_IN_OTHER:
		return;
	case SENSOR_HID_IN_MALFORMED:
		sensor_dev_note(d, "input report of %zu bytes with id %d: not the illuminance's", len,
				len ? data[0] : -1);
		sensor_dev_reading(d, NAN, SENSOR_REJECT_MALFORMED);
		return;
	case SENSOR_HID_IN_RANGE:
		sensor_dev_note(d, "illuminance %lld outside its range %lld..%lld", (long long)v,
				(long long)f->logical_min, (long long)f->logical_max);
		sensor_dev_reading(d, NAN, SENSOR_REJECT_MALFORMED);
		return;
	case SENSOR_HID_IN_NOT_READY:
		sensor_dev_reading(d, (double)v * p->scale, SENSOR_REJECT_NOT_READY);
		return;
	case SENSOR_HID_IN_READING:
		sensor_dev_reading(d, (double)v * p->scale,
				   p->unit_ok ? SENSOR_REJECT_NONE : SENSOR_REJECT_UNIT);
		return;
	}
}

static void polled(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	if (status < 0)
		sensor_dev_note(d, "asking for an input report: %s", strerror(-status));
	else
		handle_input(d, data, len);
	submit_in(d);
}

static void in_done(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);
	const struct sensor_config *c = sensor_dev_config(d);

	if (status == -ETIMEDOUT) {
		/* A sensor that reports on change only may have nothing to say:
		 * ask for the current value (GET_REPORT, input). */
		uint8_t id = p->layout.illuminance.report_id;
		sensor_dev_note(d, "no input report for %.1f s",
				fmax(c->pipe.stale_after_s, 4.0 * c->report_interval_s));
		int r = sensor_dev_control(
			d, LIBUSB_ENDPOINT_IN | LIBUSB_REQUEST_TYPE_CLASS | LIBUSB_RECIPIENT_INTERFACE,
			HID_GET_REPORT, (uint16_t)(HID_REPORT_TYPE_INPUT << 8 | id),
			(uint16_t)sensor_dev_interface(d), NULL,
			(uint16_t)sensor_hid_report_bytes(&p->layout, SENSOR_HID_INPUT, id), 0, polled);
		if (r < 0 && r != -ESHUTDOWN)
			sensor_dev_fail(d, 0, "GET_REPORT: %s", strerror(-r));
		return;
	}
	if (status < 0)
		sensor_dev_note(d, "input report: %s", strerror(-status));
	else
		handle_input(d, data, len);
	submit_in(d);
}

static void submit_in(struct sensor_dev *d)
{
	struct hid_priv *p = sensor_dev_priv(d);
	const struct sensor_config *c = sensor_dev_config(d);
	/* A sensor that reports on change only may stay quiet for a while:
	 * the deadline is the staleness, not the I/O timeout. */
	double wait_s = fmax(c->pipe.stale_after_s, 4.0 * c->report_interval_s);
	int r = sensor_dev_interrupt(d, p->ep_in, NULL, p->in_size, (unsigned)(wait_s * 1000.0),
				     in_done);

	if (r < 0 && r != -ESHUTDOWN)
		sensor_dev_fail(d, 0, "cannot read input reports: %s", strerror(-r));
}

static void begin_reading(struct sensor_dev *d)
{
	struct hid_priv *p = sensor_dev_priv(d);
	const struct sensor_hid_field *f = &p->layout.illuminance;

	sensor_dev_ready(d, "illuminance %u bit in report %u, %g lx a count%s", f->bit_size,
			 f->report_id, p->scale, p->unit_ok ? "" : ", unit not lux");
	submit_in(d);
}

static int64_t clamp(const struct sensor_hid_field *f, double v)
{
	if (!(v >= (double)f->logical_min))
		return f->logical_min;
	if (v > (double)f->logical_max)
		return f->logical_max;
	return (int64_t)llround(v);
}

/* The properties skyd wants, written into a feature report buffer: all
 * events reported, full power, the configured interval, and no change
 * threshold (the pipeline holds the hysteresis; a device threshold would
 * hide the slow changes of twilight). */
static void set_properties(struct sensor_dev *d, uint8_t id, uint8_t *buf, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);
	const struct sensor_hid_layout *l = &p->layout;
	const struct sensor_hid_field *fields[] = { &l->reporting_state, &l->power_state,
						    &l->report_interval, &l->sensitivity_abs,
						    &l->sensitivity_rel };

	for (size_t i = 0; i < sizeof(fields) / sizeof(fields[0]); i++) {
		const struct sensor_hid_field *f = fields[i];
		int64_t v = 0;
		if (!f->present || f->report_id != id)
			continue;
		if (f == &l->reporting_state || f == &l->power_state) {
			v = f->wanted;
		} else if (f == &l->report_interval) {
			double s = sensor_dev_config(d)->report_interval_s;
			double unit = f->unit == HID_UNIT_SECOND ? s : s * 1000.0;
			v = clamp(f, unit / pow(10.0, f->unit_exponent));
		} else {
			v = clamp(f, 0.0);
		}
		sensor_hid_put(l, f, buf, len, v);
	}
}

static void next_feature(struct sensor_dev *d);

static void feature_set(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);

	if (status < 0)
		sensor_dev_note(d, "setting feature report %u: %s", p->features[p->feature],
				strerror(-status));
	p->feature++;
	next_feature(d);
}

/* A feature report as the device holds it: other fields keep their
 * values, ours are changed, and it goes back. A device that refuses is
 * noted and read all the same. */
static void feature_got(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);
	uint8_t id = p->features[p->feature];
	uint32_t bytes = sensor_hid_report_bytes(&p->layout, SENSOR_HID_FEATURE, id);
	int r;

	if (status < 0 || len < bytes || bytes > sizeof(p->report)) {
		sensor_dev_note(d, "reading feature report %u: %s", id,
				status < 0 ? strerror(-status) : "short");
		p->feature++;
		next_feature(d);
		return;
	}
	memcpy(p->report, data, bytes);
	set_properties(d, id, p->report, bytes);
	r = sensor_dev_control(d, LIBUSB_ENDPOINT_OUT | LIBUSB_REQUEST_TYPE_CLASS |
				       LIBUSB_RECIPIENT_INTERFACE,
			       HID_SET_REPORT, (uint16_t)(HID_REPORT_TYPE_FEATURE << 8 | id),
			       (uint16_t)sensor_dev_interface(d), p->report, (uint16_t)bytes, 0,
			       feature_set);
	if (r < 0 && r != -ESHUTDOWN)
		sensor_dev_fail(d, 0, "SET_REPORT: %s", strerror(-r));
}

static void next_feature(struct sensor_dev *d)
{
	struct hid_priv *p = sensor_dev_priv(d);

	if (p->feature >= p->n_features) {
		begin_reading(d);
		return;
	}
	uint8_t id = p->features[p->feature];
	uint32_t bytes = sensor_hid_report_bytes(&p->layout, SENSOR_HID_FEATURE, id);
	int r = sensor_dev_control(d, LIBUSB_ENDPOINT_IN | LIBUSB_REQUEST_TYPE_CLASS |
					      LIBUSB_RECIPIENT_INTERFACE,
				   HID_GET_REPORT, (uint16_t)(HID_REPORT_TYPE_FEATURE << 8 | id),
				   (uint16_t)sensor_dev_interface(d), NULL, (uint16_t)bytes, 0,
				   feature_got);
	if (r < 0 && r != -ESHUTDOWN)
		sensor_dev_fail(d, 0, "GET_REPORT: %s", strerror(-r));
}

static void add_feature(struct hid_priv *p, const struct sensor_hid_field *f)
{
	if (!f->present)
		return;
	for (int i = 0; i < p->n_features; i++)
		if (p->features[i] == f->report_id)
			return;
	if (p->n_features < MAX_FEATURE_REPORTS)
		p->features[p->n_features++] = f->report_id;
}

/* The report descriptor, from sysfs or the device: no ambient light
 * sensor in it is final (unsupported); then the feature reports to set. */
static void got_descriptor(struct sensor_dev *d, const uint8_t *desc, size_t len)
{
	struct hid_priv *p = sensor_dev_priv(d);
	struct sensor_hid_layout *l = &p->layout;
	int r = sensor_hid_parse(desc, len, l);

	if (r == -ENOENT) {
		sensor_dev_fail(d, 1, "no ambient light sensor in its report descriptor");
		return;
	}
	if (r < 0) {
		sensor_dev_fail(d, 1, "malformed report descriptor");
		return;
	}
	p->unit_ok = sensor_hid_lux_scale(&l->illuminance, &p->scale) == 0;
	if (!p->unit_ok) {
		p->scale = pow(10.0, l->illuminance.unit_exponent);
		sensor_dev_note(d, "illuminance unit 0x%08x is not lux: readings refused",
				l->illuminance.unit);
	}
	add_feature(p, &l->reporting_state);
	add_feature(p, &l->power_state);
	add_feature(p, &l->report_interval);
	add_feature(p, &l->sensitivity_abs);
	add_feature(p, &l->sensitivity_rel);
	next_feature(d);
}

static void descriptor_done(struct sensor_dev *d, int status, const uint8_t *data, size_t len)
{
	if (status < 0) {
		sensor_dev_fail(d, 0, "reading the report descriptor: %s", strerror(-status));
		return;
	}
	got_descriptor(d, data, len);
}

/* The interrupt IN endpoint and the report descriptor's length. */
static int find_endpoint(struct sensor_dev *d, struct hid_priv *p)
{
	struct libusb_config_descriptor *cfg;
	int found = 0;

	if (libusb_get_active_config_descriptor(sensor_dev_usb(d), &cfg) < 0)
		return -EIO;
	for (int i = 0; i < cfg->bNumInterfaces && !found; i++) {
		const struct libusb_interface_descriptor *alt = &cfg->interface[i].altsetting[0];
		if (cfg->interface[i].num_altsetting < 1 ||
		    alt->bInterfaceNumber != sensor_dev_interface(d))
			continue;
		for (int e = 0; e < alt->bNumEndpoints && !found; e++) {
			const struct libusb_endpoint_descriptor *ep = &alt->endpoint[e];
			if ((ep->bEndpointAddress & LIBUSB_ENDPOINT_IN) &&
			    (ep->bmAttributes & 3) == LIBUSB_TRANSFER_TYPE_INTERRUPT) {
				p->ep_in = ep->bEndpointAddress;
				p->in_size = ep->wMaxPacketSize ? ep->wMaxPacketSize : 64;
				found = 1;
			}
		}
		const uint8_t *x = alt->extra;
		for (int o = 0; o + 9 <= alt->extra_length && x[o] >= 2; o += x[o])
			if (x[o + 1] == HID_DESC_CLASS && x[o + 6] == HID_DESC_REPORT)
				p->desc_len = (uint16_t)(x[o + 7] | x[o + 8] << 8);
	}
	libusb_free_config_descriptor(cfg);
	return found ? 0 : -ENOENT;
}

/* The report descriptor: the kernel's copy when sysfs has one, else asked
 * of the device (GET_DESCRIPTOR, report, on the interface). */
static int hid_start(struct sensor_dev *d)
{
	struct hid_priv *p = sensor_dev_priv(d);
	ssize_t n;

	if (find_endpoint(d, p) < 0)
		return -ENOENT;
	n = sysfs_descriptor(d, p->report, sizeof(p->report));
	if (n > 0) {
		got_descriptor(d, p->report, (size_t)n);
		return 0;
	}
	uint16_t len = p->desc_len && p->desc_len <= HID_MAX_DESC ? p->desc_len : HID_MAX_DESC;
	return sensor_dev_control(d, LIBUSB_ENDPOINT_IN | LIBUSB_REQUEST_TYPE_STANDARD |
					     LIBUSB_RECIPIENT_INTERFACE,
				  LIBUSB_REQUEST_GET_DESCRIPTOR, HID_DESC_REPORT << 8,
				  (uint16_t)sensor_dev_interface(d), NULL, len, 0, descriptor_done);
}

const struct sensor_driver sensor_hid_driver = {
	.family = "hid-sensor",
	.match = hid_match,
	.precheck = hid_precheck,
	.priv_size = sizeof(struct hid_priv),
	.start = hid_start,
	.stop = NULL,
};

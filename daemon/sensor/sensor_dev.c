/* sensor_dev.c - one device of the sensor manager: sysfs, open and claim,
 * asynchronous transfers with deadlines, what its driver reports, and the
 * close that waits for cancelled transfers before it lets go. */
#include "sensor_internal.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"

/* ---- sysfs ---- */

ssize_t sensor_dev_sysfs(const struct sensor_dev *d, const char *rel, void *buf, size_t size)
{
	char path[512];
	ssize_t n = 0, got = 0;

	if (snprintf(path, sizeof(path), SENSOR_SYSFS_USB "/%s/%s", d->info.bus_path, rel) >=
	    (int)sizeof(path))
		return -ENAMETOOLONG;
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return -errno;
	while ((size_t)got < size && (n = read(fd, (char *)buf + got, size - (size_t)got)) > 0)
		got += n;
	int e = n < 0 ? errno : 0;
	close(fd);
	return e ? -e : got;
}

void sensor_dev_sysfs_text(const struct sensor_dev *d, const char *rel, char *buf, size_t size)
{
	ssize_t n = sensor_dev_sysfs(d, rel, buf, size - 1);

	if (n < 0)
		n = 0;
	buf[n] = 0;
	while (n > 0 && (buf[n - 1] == '\n' || buf[n - 1] == ' '))
		buf[--n] = 0;
	for (ssize_t i = 0; i < n; i++)	/* device strings are untrusted */
		if (!isprint((unsigned char)buf[i]) || buf[i] == '\'')
			buf[i] = '?';
}

int sensor_dev_sysfs_find(const struct sensor_dev *d, const char *rel, const char *prefix,
			  char *ret, size_t size)
{
	char path[512];
	struct dirent *e;
	int r = -ENOENT;

	if (snprintf(path, sizeof(path), SENSOR_SYSFS_USB "/%s/%s", d->info.bus_path, rel) >=
	    (int)sizeof(path))
		return -ENAMETOOLONG;
	DIR *dir = opendir(path);
	if (!dir)
		return -errno;
	while ((e = readdir(dir)))
		if (!strncmp(e->d_name, prefix, strlen(prefix))) {
			snprintf(ret, size, "%s", e->d_name);
			r = 0;
			break;
		}
	closedir(dir);
	return r;
}

/* ---- devices ---- */

void *sensor_dev_priv(struct sensor_dev *d)
{
	return d->priv;
}

const struct sensor_config *sensor_dev_config(const struct sensor_dev *d)
{
	return &d->s->cfg;
}

int sensor_dev_interface(const struct sensor_dev *d)
{
	return d->iface;
}

libusb_device *sensor_dev_usb(const struct sensor_dev *d)
{
	return d->usb;
}

const char *sensor_dev_bus_path(const struct sensor_dev *d)
{
	return d->info.bus_path;
}

static void set_text(char *dst, size_t size, const char *fmt, va_list ap)
{
	vsnprintf(dst, size, fmt, ap);
}

void sensor_note_why(struct sensor *s, const char *text)
{
	size_t n = strnlen(text, sizeof(s->why) - 1);

	memcpy(s->why, text, n);
	s->why[n] = 0;
}

/* A device's problems go to the log at most five lines in ten seconds and
 * never the same text twice in a row: a device sending garbage at 1 kHz
 * must not flood the journal (the counters say how much there was). */
static void dev_log(struct sensor_dev *d, const char *text)
{
	uint64_t now = loop_now_ns();

	if (!strcmp(text, d->last_logged))
		return;
	if (now - d->logged_ns >= 10000000000ull) {
		d->logged_ns = now;
		d->logged_lines = 0;
	}
	if (d->logged_lines >= 5)
		return;
	d->logged_lines++;
	log_warning("sensor %s: %s", d->info.bus_path, text);
	snprintf(d->last_logged, sizeof(d->last_logged), "%s", text);
}

void sensor_dev_note(struct sensor_dev *d, const char *fmt, ...)
{
	char text[SENSOR_TEXT_MAX];
	va_list ap;

	va_start(ap, fmt);
	set_text(text, sizeof(text), fmt, ap);
	va_end(ap);
	if (d->s->active == d)
		sensor_note_why(d->s, text);
	snprintf(d->pending_note, sizeof(d->pending_note), "%s", text);
	dev_log(d, text);
}

static void free_xfer(struct sensor_xfer *x)
{
	libusb_free_transfer(x->t);	/* frees the buffer too (LIBUSB_TRANSFER_FREE_BUFFER) */
	free(x);
}

static void unlink_xfer(struct sensor_dev *d, struct sensor_xfer *x)
{
	for (struct sensor_xfer **pp = &d->xfers; *pp; pp = &(*pp)->next)
		if (*pp == x) {
			*pp = x->next;
			return;
		}
}

/* Starts closing d: the driver stops, its transfers are cancelled; the
 * handle is closed by sensor_settle() once they have all come back. */
void sensor_dev_close(struct sensor_dev *d, enum sensor_dev_state after, const char *why)
{
	struct sensor *s = d->s;

	if (why) {
		snprintf(d->info.detail, sizeof(d->info.detail), "%s", why);
		if (s->active == d)
			sensor_note_why(s, why);
	}
	if (!d->h) {
		d->state = after;
		return;
	}
	if (d->state == SENSOR_DEV_CLOSING) {
		if (after == SENSOR_DEV_FAILED || after == SENSOR_DEV_UNSUPPORTED)
			d->after_close = after;
		return;
	}
	if (after == SENSOR_DEV_FAILED) {
		s->counters.failures++;
		log_warning("sensor %s: stopped: %s", d->info.bus_path, why ? why : "");
	}
	d->state = SENSOR_DEV_CLOSING;
	d->after_close = after;
	d->close_ns = loop_now_ns();
	if (d->drv->stop)
		d->drv->stop(d);
	if (d->timer)
		loop_timer_arm(d->timer, 0);
	for (struct sensor_xfer *x = d->xfers; x; x = x->next)
		libusb_cancel_transfer(x->t);
}

void sensor_dev_finish_close(struct sensor_dev *d)
{
	struct sensor *s = d->s;

	if (d->claimed)
		libusb_release_interface(d->h, d->iface);
	if (d->detached && libusb_attach_kernel_driver(d->h, d->iface) < 0)
		log_warning("sensor %s: could not give the interface back to its kernel driver",
			    d->info.bus_path);
	libusb_close(d->h);
	/* libusb forgets transfers still in flight on a closed handle; they
	 * are ours to free. */
	while (d->xfers) {
		struct sensor_xfer *x = d->xfers;
		d->xfers = x->next;
		free_xfer(x);
	}
	d->h = NULL;
	d->claimed = d->detached = 0;
	free(d->priv);
	d->priv = NULL;
	d->state = d->after_close;
	if (d->state == SENSOR_DEV_FAILED) {
		d->failures++;
		double back = s->cfg.rescan_s * (double)(1u << (d->failures < 5 ? d->failures - 1 : 4));
		d->retry_ns = loop_now_ns() + sensor_s_to_ns(back);
	}
	if (s->active == d)
		s->active = NULL;
}

void sensor_dev_free(struct sensor_dev *d)
{
	if (d->timer)
		loop_timer_del(d->timer);
	libusb_unref_device(d->usb);
	free(d);
}

/* ---- transfers ---- */

/* libusb's transfer status as -errno, 0 for completed. */
static int map_status(enum libusb_transfer_status st)
{
	switch (st) {
	case LIBUSB_TRANSFER_COMPLETED: return 0;
	case LIBUSB_TRANSFER_TIMED_OUT: return -ETIMEDOUT;
	case LIBUSB_TRANSFER_CANCELLED: return -ECANCELED;
	case LIBUSB_TRANSFER_STALL: return -EPIPE;
	case LIBUSB_TRANSFER_NO_DEVICE: return -ENODEV;
	case LIBUSB_TRANSFER_OVERFLOW: return -EOVERFLOW;
	default: return -EIO;
	}
}

/* Every transfer ends here: bookkeeping, the device stopped after too
 * many bad ones in a row, then the driver's callback. Inside libusb's
 * dispatch. */
static void LIBUSB_CALL xfer_done(struct libusb_transfer *t)
{
	struct sensor_xfer *x = t->user_data;
	struct sensor_dev *d = x->d;
	struct sensor *s = d->s;
	int status = map_status(t->status);

	unlink_xfer(d, x);
	s->counters.transfers++;
	if (d->state == SENSOR_DEV_CLOSING || status == -ECANCELED) {
		free_xfer(x);
		return;
	}
	if (status == -ENODEV) {
		free_xfer(x);
		sensor_dev_close(d, SENSOR_DEV_FAILED, "the device is gone");
		return;
	}
	if (status == 0) {
		d->bad_in_row = 0;
	} else if (status == -EPIPE) {
		/* A stall is an answer (the device refuses a request it need
		 * not support): the driver decides. */
		s->counters.io_errors++;
	} else {
		if (status == -ETIMEDOUT)
			s->counters.timeouts++;
		else
			s->counters.io_errors++;
		if (++d->bad_in_row >= SENSOR_MAX_BAD_IN_ROW) {
			char why[SENSOR_TEXT_MAX];
			snprintf(why, sizeof(why), "stopped answering: %d transfers in a row %s",
				 d->bad_in_row, status == -ETIMEDOUT ? "timed out" : "failed");
			free_xfer(x);
			sensor_dev_close(d, SENSOR_DEV_FAILED, why);
			return;
		}
	}
	const uint8_t *data = x->control ? libusb_control_transfer_get_data(t) : t->buffer;
	x->fn(d, status, data, t->actual_length > 0 ? (size_t)t->actual_length : 0);
	free_xfer(x);
}

static unsigned timeout_ms(const struct sensor_dev *d, unsigned ms)
{
	return ms ? ms : (unsigned)(d->s->cfg.io_timeout_s * 1000.0 + 0.5);
}

/* Submits t (which it owns from here) and tracks it on d. */
static int submit(struct sensor_dev *d, struct libusb_transfer *t, sensor_xfer_fn fn, int control)
{
	struct sensor_xfer *x = calloc(1, sizeof(*x));

	if (!x) {
		libusb_free_transfer(t);
		return -ENOMEM;
	}
	x->d = d;
	x->t = t;
	x->fn = fn;
	x->control = control;
	t->user_data = x;
	t->flags |= LIBUSB_TRANSFER_FREE_BUFFER;
	int r = libusb_submit_transfer(t);
	if (r < 0) {
		free_xfer(x);
		return r == LIBUSB_ERROR_NO_DEVICE ? -ENODEV : -EIO;
	}
	x->next = d->xfers;
	d->xfers = x;
	return 0;
}

int sensor_dev_control(struct sensor_dev *d, uint8_t request_type, uint8_t request,
		       uint16_t value, uint16_t index, const uint8_t *out, uint16_t length,
		       unsigned timeout, sensor_xfer_fn fn)
{
	if (!d->h || d->state == SENSOR_DEV_CLOSING)
		return -ESHUTDOWN;
	struct libusb_transfer *t = libusb_alloc_transfer(0);
	uint8_t *buf = calloc(1, LIBUSB_CONTROL_SETUP_SIZE + (size_t)length);
	if (!t || !buf) {
		libusb_free_transfer(t);
		free(buf);
		return -ENOMEM;
	}
	libusb_fill_control_setup(buf, request_type, request, value, index, length);
	if (out && length)
		memcpy(buf + LIBUSB_CONTROL_SETUP_SIZE, out, length);
	libusb_fill_control_transfer(t, d->h, buf, xfer_done, NULL, timeout_ms(d, timeout));
	return submit(d, t, fn, 1);
}

int sensor_dev_interrupt(struct sensor_dev *d, uint8_t endpoint, const uint8_t *out,
			 uint16_t length, unsigned timeout, sensor_xfer_fn fn)
{
	if (!d->h || d->state == SENSOR_DEV_CLOSING)
		return -ESHUTDOWN;
	struct libusb_transfer *t = libusb_alloc_transfer(0);
	uint8_t *buf = calloc(1, length ? length : 1);
	if (!t || !buf) {
		libusb_free_transfer(t);
		free(buf);
		return -ENOMEM;
	}
	if (out && length)
		memcpy(buf, out, length);
	libusb_fill_interrupt_transfer(t, d->h, endpoint, buf, length, xfer_done, NULL,
				       timeout_ms(d, timeout));
	return submit(d, t, fn, 0);
}

static void dev_timer_fired(void *ctx)
{
	struct sensor_dev *d = ctx;

	if (d->timer_fn && d->state != SENSOR_DEV_CLOSING && d->h)
		d->timer_fn(d);
	sensor_settle(d->s);
}

int sensor_dev_timer(struct sensor_dev *d, uint64_t delay_ns, sensor_dev_timer_fn fn)
{
	int r;

	if (!d->h || d->state == SENSOR_DEV_CLOSING)
		return -ESHUTDOWN;
	if (!d->timer && (r = loop_timer_add(d->s->loop, dev_timer_fired, d, &d->timer)) < 0)
		return r;
	d->timer_fn = fn;
	return loop_timer_arm(d->timer, delay_ns ? delay_ns : 1);
}

/* ---- what drivers report ---- */

void sensor_dev_ready(struct sensor_dev *d, const char *fmt, ...)
{
	struct sensor *s = d->s;
	va_list ap;

	va_start(ap, fmt);
	set_text(d->info.detail, sizeof(d->info.detail), fmt, ap);
	va_end(ap);
	if (d->state != SENSOR_DEV_STARTING)
		return;
	d->failures = 0;
	d->fresh_ns = loop_now_ns();
	d->pending_note[0] = 0;		/* set-up notes are not about readings */
	if (s->list_mode) {
		d->probed = 1;
		sensor_dev_close(d, SENSOR_DEV_IDLE, NULL);
		return;
	}
	d->state = SENSOR_DEV_READING;
	s->why[0] = 0;
	log_info("sensor %s: reading %s '%s': %s", d->info.bus_path, d->info.family, d->info.name,
		 d->info.detail);
}

void sensor_dev_fail(struct sensor_dev *d, int unsupported, const char *fmt, ...)
{
	char why[SENSOR_TEXT_MAX];
	va_list ap;

	va_start(ap, fmt);
	set_text(why, sizeof(why), fmt, ap);
	va_end(ap);
	d->probed = 1;
	sensor_dev_close(d, unsupported ? SENSOR_DEV_UNSUPPORTED : SENSOR_DEV_FAILED, why);
}

void sensor_pump(struct sensor *s)
{
	struct sensor_reading r;
	uint64_t next = 0;

	while (sensor_pipe_poll(s->pipe, loop_now_ns(), &r, &next) == 1)
		if (s->fn)
			s->fn(s->ctx, &r);
	loop_timer_arm(s->pipe_timer, next ? (next > loop_now_ns() ? next - loop_now_ns() : 1) : 0);
}

void sensor_dev_reading(struct sensor_dev *d, double lux, enum sensor_reject why)
{
	struct sensor *s = d->s;
	char text[2 * SENSOR_TEXT_MAX];

	s->counters.readings++;
	if (s->active == d && d->state == SENSOR_DEV_READING) {
		uint64_t now = loop_now_ns();
		enum sensor_reject r = sensor_pipe_push(s->pipe, lux, why, now);
		if (r != SENSOR_REJECT_NONE) {
			/* What the driver noted about this reading says more. */
			snprintf(text, sizeof(text), "reading refused: %s%s%s", sensor_reject_name(r),
				 d->pending_note[0] ? ": " : "", d->pending_note);
			sensor_note_why(s, text);
			dev_log(d, text);
		} else {
			d->fresh_ns = now;
		}
		sensor_pump(s);
	}
	d->pending_note[0] = 0;
}

const char *sensor_usb_error(int r)
{
	return libusb_strerror((enum libusb_error)r);
}

void sensor_dev_open(struct sensor *s, struct sensor_dev *d)
{
	char why[SENSOR_TEXT_MAX];
	int r = libusb_open(d->usb, &d->h);

	if (r < 0) {
		d->h = NULL;
		snprintf(why, sizeof(why), "cannot open: %s%s", sensor_usb_error(r),
			 r == LIBUSB_ERROR_ACCESS ? " (docs/sensor.md: the udev rule)" : "");
		d->probed = 1;
		sensor_dev_close(d, SENSOR_DEV_FAILED, why);	/* not open: only the state */
		sensor_note_why(s, why);
		s->counters.failures++;
		d->failures++;
		d->retry_ns = loop_now_ns() + sensor_s_to_ns(s->cfg.rescan_s);
		return;
	}
	s->counters.opens++;
	d->state = SENSOR_DEV_STARTING;
	d->bad_in_row = 0;
	if (!s->list_mode)
		s->active = d;
	/* 1: a kernel driver has the interface; an error (umockdev answers
	 * none) leaves the claim to find out. */
	if (libusb_kernel_driver_active(d->h, d->iface) == 1) {
		r = libusb_detach_kernel_driver(d->h, d->iface);
		if (r < 0) {
			snprintf(why, sizeof(why), "cannot detach the kernel driver: %s", sensor_usb_error(r));
			sensor_dev_close(d, SENSOR_DEV_FAILED, why);
			return;
		}
		d->detached = 1;
	}
	r = libusb_claim_interface(d->h, d->iface);
	if (r < 0) {
		snprintf(why, sizeof(why), "cannot claim interface %d: %s", d->iface, sensor_usb_error(r));
		sensor_dev_close(d, SENSOR_DEV_FAILED, why);
		return;
	}
	d->claimed = 1;
	d->priv = d->drv->priv_size ? calloc(1, d->drv->priv_size) : NULL;
	if (d->drv->priv_size && !d->priv) {
		sensor_dev_close(d, SENSOR_DEV_FAILED, "out of memory");
		return;
	}
	r = d->drv->start(d);
	if (r < 0 && d->state == SENSOR_DEV_STARTING) {
		snprintf(why, sizeof(why), "driver start: %s", strerror(-r));
		sensor_dev_close(d, SENSOR_DEV_FAILED, why);
	}
}

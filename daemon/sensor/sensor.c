/* sensor.c - the sensor manager: libusb on the daemon's loop, hot-plug,
 * the devices it knows and the one it reads, its configuration, status
 * and the list; sensor_dev.c handles each device. */
#include "sensor_internal.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "log.h"
#include "loop.h"

/* The families, tried in this order; a new one is one more line. */
static const struct sensor_driver *const sensor_drivers[] = {
	&sensor_mcp2221_driver,
	&sensor_hid_driver,
};
#define N_DRIVERS (sizeof(sensor_drivers) / sizeof(sensor_drivers[0]))

/* ---- names ---- */

const char *sensor_dev_state_name(enum sensor_dev_state st)
{
	static const char *const names[] = { "idle", "starting", "reading", "closing", "failed",
					     "unsupported" };
	return (unsigned)st < sizeof(names) / sizeof(names[0]) ? names[st] : "?";
}

const char *sensor_state_name(enum sensor_state st)
{
	static const char *const names[] = { "off", "unavailable", "searching", "starting",
					     "reading", "stale" };
	return (unsigned)st < sizeof(names) / sizeof(names[0]) ? names[st] : "?";
}

int sensor_info_format(const struct sensor_info *i, char *buf, size_t size)
{
	int n = snprintf(buf, size, "%s %s %04x:%04x serial=%s state=%s%s '%s'", i->bus_path,
			 i->family, i->vendor_id, i->product_id, i->serial[0] ? i->serial : "-",
			 sensor_dev_state_name(i->state), i->selected ? " selected" : "", i->name);
	if (n >= 0 && (size_t)n < size && i->detail[0])
		n += snprintf(buf + n, size - (size_t)n, " (%s)", i->detail);
	return n;
}

/* ---- configuration ---- */

void sensor_config_defaults(struct sensor_config *ret)
{
	memset(ret, 0, sizeof(*ret));
	snprintf(ret->select, sizeof(ret->select), "auto");
	sensor_pipe_defaults(&ret->pipe);
	ret->report_interval_s = 0.5;
	ret->io_timeout_s = 1.0;
	ret->rescan_s = 5.0;
}

static int select_is_none(const struct sensor_config *cfg)
{
	return strcmp(cfg->select, "none") == 0;
}

int sensor_config_check(const struct sensor_config *cfg, char *err, size_t err_size)
{
	const char *v = cfg->select, *bad = NULL;

	if (!memchr(v, 0, sizeof(cfg->select)))
		bad = "select is too long";
	else if (!(v[0] == 0 || !strcmp(v, "auto") || !strcmp(v, "none") ||
		   (!strncmp(v, "bus:", 4) && v[4]) || (!strncmp(v, "serial:", 7) && v[7]) ||
		   (!strncmp(v, "name:", 5) && v[5])))
		bad = "select must be auto, none, bus:PATH, serial:TEXT or name:TEXT";
	else if (!(cfg->report_interval_s >= 0.01 && cfg->report_interval_s <= 3600.0))
		bad = "report_interval_s out of range";
	else if (!(cfg->io_timeout_s >= 0.01 && cfg->io_timeout_s <= 60.0))
		bad = "io_timeout_s out of range";
	else if (!(cfg->rescan_s >= 0.01 && cfg->rescan_s <= 3600.0))
		bad = "rescan_s out of range";
	if (bad) {
		if (err && err_size)
			snprintf(err, err_size, "%s", bad);
		return -EINVAL;
	}
	return sensor_pipe_check(&cfg->pipe, err, err_size);
}

static int select_matches(const struct sensor_config *cfg, const struct sensor_info *i)
{
	const char *v = cfg->select;

	if (!strncmp(v, "bus:", 4))
		return !strcmp(i->bus_path, v + 4);
	if (!strncmp(v, "serial:", 7))
		return !strcmp(i->serial, v + 7);
	if (!strncmp(v, "name:", 5))
		return strcasestr(i->name, v + 5) != NULL;
	return !select_is_none(cfg);
}

uint64_t sensor_s_to_ns(double s)
{
	return (uint64_t)(s * 1e9 + 0.5);
}

/* ---- finding devices ---- */

/* The port path ("1-4.2", the name sysfs gives the device) into buf;
 * -ENODEV for a root hub, which has none. */
static int bus_path(libusb_device *usb, char *buf, size_t size)
{
	uint8_t ports[8];
	int n = libusb_get_port_numbers(usb, ports, (int)sizeof(ports));

	if (n <= 0)
		return -ENODEV;		/* a root hub */
	int o = snprintf(buf, size, "%u-", libusb_get_bus_number(usb));
	for (int i = 0; i < n && o > 0 && (size_t)o < size; i++)
		o += snprintf(buf + o, size - (size_t)o, i ? ".%u" : "%u", ports[i]);
	return 0;
}

/* Name and serial from the strings the kernel read at enumeration (sysfs):
 * no USB traffic, nothing that could block. */
static void fill_names(struct sensor_dev *d)
{
	char manufacturer[48], product[48];

	sensor_dev_sysfs_text(d, "manufacturer", manufacturer, sizeof(manufacturer));
	sensor_dev_sysfs_text(d, "product", product, sizeof(product));
	sensor_dev_sysfs_text(d, "serial", d->info.serial, sizeof(d->info.serial));
	if (manufacturer[0] || product[0])
		snprintf(d->info.name, sizeof(d->info.name), "%s%s%s", manufacturer,
			 manufacturer[0] && product[0] ? " " : "", product);
	else
		snprintf(d->info.name, sizeof(d->info.name), "%04x:%04x", d->info.vendor_id,
			 d->info.product_id);
}

static struct sensor_dev *find_dev(struct sensor *s, libusb_device *usb)
{
	for (struct sensor_dev *d = s->devs; d; d = d->next)
		if (d->usb == usb)
			return d;
	return NULL;
}

/* A device on the bus: a candidate when one family's match takes it. */
static void add_device(struct sensor *s, libusb_device *usb)
{
	struct libusb_device_descriptor dd;
	struct libusb_config_descriptor *cfg;
	char path[32];
	int iface = -1;
	const struct sensor_driver *drv = NULL;

	if (find_dev(s, usb) || bus_path(usb, path, sizeof(path)) < 0 ||
	    libusb_get_device_descriptor(usb, &dd) < 0 || dd.bDeviceClass == LIBUSB_CLASS_HUB)
		return;
	if (libusb_get_active_config_descriptor(usb, &cfg) < 0)
		return;
	for (size_t i = 0; i < N_DRIVERS && iface < 0; i++) {
		iface = sensor_drivers[i]->match(&dd, cfg);
		drv = sensor_drivers[i];
	}
	libusb_free_config_descriptor(cfg);
	if (iface < 0)
		return;
	struct sensor_dev *d = calloc(1, sizeof(*d));
	if (!d)
		return;
	d->s = s;
	d->usb = libusb_ref_device(usb);
	d->drv = drv;
	d->iface = iface;
	d->state = SENSOR_DEV_IDLE;
	snprintf(d->info.bus_path, sizeof(d->info.bus_path), "%s", path);
	snprintf(d->info.family, sizeof(d->info.family), "%s", drv->family);
	d->info.vendor_id = dd.idVendor;
	d->info.product_id = dd.idProduct;
	fill_names(d);
	d->info.selected = select_matches(&s->cfg, &d->info);
	if (drv->precheck && drv->precheck(d) == -ENODEV) {
		d->state = SENSOR_DEV_UNSUPPORTED;
		d->probed = 1;
	}
	struct sensor_dev **pp = &s->devs;
	while (*pp)
		pp = &(*pp)->next;
	*pp = d;
	s->counters.arrivals++;
	log_info("sensor %s: %s '%s' (%s)", path, drv->family, d->info.name,
		 d->state == SENSOR_DEV_UNSUPPORTED ? d->info.detail : "candidate");
}

static void device_left(struct sensor *s, struct sensor_dev *d)
{
	char why[SENSOR_TEXT_MAX];

	s->counters.departures++;
	d->gone = 1;
	snprintf(why, sizeof(why), "%s left the bus", d->info.bus_path);
	log_info("sensor %s: left", d->info.bus_path);
	if (s->active == d)
		sensor_note_why(s, why);
	/* Leaving is not failing: it is freed once closed. */
	if (d->h)
		sensor_dev_close(d, SENSOR_DEV_IDLE, why);
}

/* Called from libusb_handle_events (or, for the devices present, from the
 * registration) in the loop's thread. */
static int LIBUSB_CALL hotplug_cb(libusb_context *ctx, libusb_device *usb,
				  libusb_hotplug_event event, void *user)
{
	struct sensor *s = user;

	/* Inside libusb's dispatch: only queue, sensor_settle() acts. */
	if (s->n_events == s->events_cap) {
		size_t cap = s->events_cap ? 2 * s->events_cap : 16;
		struct sensor_event *e = realloc(s->events, cap * sizeof(*e));
		if (!e)
			return 0;
		s->events = e;
		s->events_cap = cap;
	}
	s->events[s->n_events].usb = libusb_ref_device(usb);
	s->events[s->n_events].arrived = event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED;
	s->n_events++;
	return 0;
}

static void process_events(struct sensor *s)
{
	for (size_t i = 0; i < s->n_events; i++) {
		struct sensor_event *e = &s->events[i];
		struct sensor_dev *d = find_dev(s, e->usb);
		if (e->arrived)
			add_device(s, e->usb);
		else if (d && !d->gone)
			device_left(s, d);
		libusb_unref_device(e->usb);
	}
	s->n_events = 0;
}

/* Without hot-plug: what is on the bus now against what is known. */
static void scan(struct sensor *s)
{
	libusb_device **list;
	ssize_t n = libusb_get_device_list(s->usb, &list);

	if (n < 0)
		return;
	for (struct sensor_dev *d = s->devs; d; d = d->next) {
		int present = 0;
		for (ssize_t i = 0; i < n && !present; i++)
			present = list[i] == d->usb;
		if (!present && !d->gone)
			device_left(s, d);
	}
	for (ssize_t i = 0; i < n; i++)
		add_device(s, list[i]);
	libusb_free_device_list(list, 1);
}

/* Not open, still here, and idle or failed long enough ago. */
static int openable(const struct sensor_dev *d, uint64_t now)
{
	if (d->gone || d->h)
		return 0;
	return d->state == SENSOR_DEV_IDLE || (d->state == SENSOR_DEV_FAILED && now >= d->retry_ns);
}

/* Opens what should be open: in list mode every candidate once, else the
 * first selected one when none is in use. */
static void choose(struct sensor *s)
{
	uint64_t now = loop_now_ns();

	for (struct sensor_dev *d = s->devs; d; d = d->next) {
		if (s->list_mode) {
			if (!d->probed && openable(d, now))
				sensor_dev_open(s, d);
			continue;
		}
		if (s->active)
			return;
		if (d->info.selected && openable(d, now)) {
			sensor_pipe_reset(s->pipe);
			sensor_dev_open(s, d);
		}
	}
}

static void apply_config(struct sensor *s, const struct sensor_config *cfg);

/* ---- libusb on the loop ---- */

static void service(struct sensor *s)
{
	struct timeval zero = { 0, 0 };

	if (!s->usb) {
		sensor_settle(s);
		return;
	}
	s->in_events = 1;
	libusb_handle_events_timeout_completed(s->usb, &zero, NULL);
	s->in_events = 0;
	sensor_settle(s);
}

static void fd_ready(void *ctx, uint32_t events)
{
	service(ctx);
}

static void LIBUSB_CALL fd_added(int fd, short events, void *user)
{
	struct sensor *s = user;
	struct sensor_fd *f = calloc(1, sizeof(*f));
	uint32_t ev = ((events & POLLIN) ? EPOLLIN : 0) | ((events & POLLOUT) ? EPOLLOUT : 0);

	if (!f)
		return;
	f->fd = fd;
	if (loop_io_add(s->loop, fd, ev, fd_ready, s, &f->io) < 0)
		f->io = NULL;
	f->next = s->fds;
	s->fds = f;
}

static void LIBUSB_CALL fd_removed(int fd, void *user)
{
	struct sensor *s = user;

	for (struct sensor_fd **pp = &s->fds; *pp; pp = &(*pp)->next) {
		struct sensor_fd *f = *pp;
		if (f->fd != fd)
			continue;
		*pp = f->next;
		loop_io_del(f->io);
		free(f);
		return;
	}
}

static void service_fired(void *ctx)
{
	service(ctx);
}

static void rescan_fired(void *ctx)
{
	struct sensor *s = ctx;

	if (s->usb && !s->hotplug)
		scan(s);
	sensor_settle(s);
}

static void pipe_fired(void *ctx)
{
	struct sensor *s = ctx;

	sensor_pump(s);
	sensor_settle(s);
}

static uint64_t earliest(uint64_t a, uint64_t b)
{
	return !a ? b : !b ? a : a < b ? a : b;
}

static void arm_at(struct loop_timer *t, uint64_t at_ns, uint64_t now)
{
	loop_timer_arm(t, !at_ns ? 0 : at_ns > now ? at_ns - now : 1);
}

/* Arms the service timer (libusb's own deadlines when it has no timerfd,
 * polling of fds epoll refused, the grace of closing devices) and the
 * rescan timer (while no device is in use). */
static void schedule(struct sensor *s)
{
	uint64_t now = loop_now_ns(), service_at = 0, rescan_at = 0;
	struct timeval tv;
	int unwatched = 0, in_flight = 0;

	if (libusb_get_next_timeout(s->usb, &tv) == 1)
		service_at = now + (uint64_t)tv.tv_sec * 1000000000ull + (uint64_t)tv.tv_usec * 1000ull;
	for (struct sensor_fd *f = s->fds; f; f = f->next)
		unwatched |= !f->io;
	for (struct sensor_dev *d = s->devs; d; d = d->next) {
		in_flight |= d->xfers != NULL;
		if (d->state == SENSOR_DEV_CLOSING)
			service_at = earliest(service_at, d->close_ns + SENSOR_CLOSE_GRACE_NS);
		if (d->state == SENSOR_DEV_FAILED && d->info.selected && !d->gone && !s->list_mode)
			rescan_at = earliest(rescan_at, d->retry_ns);
	}
	if (unwatched && in_flight)
		service_at = earliest(service_at, now + SENSOR_POLL_NS);
	arm_at(s->service_timer, service_at, now);
	if (s->active || s->list_mode)
		rescan_at = 0;
	else if (!s->hotplug)
		rescan_at = earliest(rescan_at, now + sensor_s_to_ns(s->cfg.rescan_s));
	arm_at(s->rescan_timer, rescan_at, now);
}

/* FNV-1a over what a status call reports, so that only changes are told. */
static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
	const unsigned char *b = p;
	for (size_t i = 0; i < n; i++)
		h = (h ^ b[i]) * 0x100000001b3ull;
	return h;
}

static void notify(struct sensor *s)
{
	struct sensor_status st;
	uint64_t h = 0xcbf29ce484222325ull;

	if (!s->status_fn)
		return;
	sensor_get_status(s, &st);
	h = fnv(h, &st.state, sizeof(st.state));
	h = fnv(h, st.device.bus_path, strlen(st.device.bus_path));
	h = fnv(h, &st.device.state, sizeof(st.device.state));
	h = fnv(h, st.why, strlen(st.why));
	h = fnv(h, &st.counters, sizeof(st.counters));
	h = fnv(h, &st.pipe, sizeof(st.pipe));
	for (const struct sensor_dev *d = s->devs; d; d = d->next)
		h = fnv(h, &d->state, sizeof(d->state));
	if (h == s->status_key)
		return;
	s->status_key = h;
	s->status_fn(s->status_ctx);
}

void sensor_on_status(struct sensor *s, sensor_status_fn fn, void *ctx)
{
	s->status_fn = fn;
	s->status_ctx = ctx;
	s->status_key = 0;
}

/* List mode: every device identified, given up on, or closed again. */
static int list_done(const struct sensor *s)
{
	uint64_t now = loop_now_ns();

	if (s->n_events)
		return 0;
	for (const struct sensor_dev *d = s->devs; d; d = d->next)
		if (d->h || (!d->probed && openable(d, now)))
			return 0;
	return 1;
}

void sensor_settle(struct sensor *s)
{
	if (s->settling || s->in_events)
		return;
	if (s->config_pending) {
		s->config_pending = 0;
		apply_config(s, &s->pending_cfg);
	}
	if (!s->usb) {
		notify(s);
		return;
	}
	s->settling = 1;
	for (int round = 0; round < 4; round++) {
		process_events(s);
		uint64_t now = loop_now_ns();
		int changed = 0;
		for (struct sensor_dev **pp = &s->devs; *pp;) {
			struct sensor_dev *d = *pp;
			if (d->h && d->state == SENSOR_DEV_CLOSING &&
			    (!d->xfers || now - d->close_ns >= SENSOR_CLOSE_GRACE_NS)) {
				sensor_dev_finish_close(d);
				changed = 1;
			}
			if (d->gone && !d->h) {
				*pp = d->next;
				sensor_dev_free(d);
				continue;
			}
			pp = &d->next;
		}
		choose(s);
		if (!changed)
			break;
	}
	schedule(s);
	if (s->list_mode && list_done(s))
		loop_quit(s->loop);
	notify(s);
	s->settling = 0;
}

/* ---- life cycle ---- */

/* libusb's context on the loop and the devices found; -ENODEV with why
 * when libusb cannot start. */
static int start_usb(struct sensor *s)
{
	const struct libusb_pollfd **fds;
	int r = libusb_init(&s->usb);

	if (r < 0) {
		s->usb = NULL;
		snprintf(s->why, sizeof(s->why),
			 "libusb could not start: %s (it needs /dev/bus/usb, and a netlink socket "
			 "for hot-plug)", sensor_usb_error(r));
		log_warning("sensor: %s", s->why);
		return -ENODEV;
	}
	libusb_set_pollfd_notifiers(s->usb, fd_added, fd_removed, s);
	fds = libusb_get_pollfds(s->usb);
	for (size_t i = 0; fds && fds[i]; i++)
		fd_added(fds[i]->fd, fds[i]->events, s);
	libusb_free_pollfds(fds);
	s->hotplug = libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) &&
		     libusb_hotplug_register_callback(
			     s->usb, LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT,
			     LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
			     LIBUSB_HOTPLUG_MATCH_ANY, hotplug_cb, s, &s->hotplug_handle) == 0;
	if (!s->hotplug)
		scan(s);
	sensor_settle(s);
	return 0;
}

static int any_cancelling(const struct sensor *s)
{
	for (const struct sensor_dev *d = s->devs; d; d = d->next)
		if (d->h && d->xfers)
			return 1;
	return 0;
}

/* Closes every device (waiting a little for cancellations: this runs at
 * shutdown or when the sensor is switched off) and libusb. */
static void stop_usb(struct sensor *s)
{
	if (!s->usb)
		return;
	for (struct sensor_dev *d = s->devs; d; d = d->next)
		if (d->h)
			sensor_dev_close(d, SENSOR_DEV_IDLE, NULL);
	uint64_t deadline = loop_now_ns() + 100000000ull;
	while (any_cancelling(s) && loop_now_ns() < deadline) {
		struct timeval tv = { 0, 10000 };
		libusb_handle_events_timeout_completed(s->usb, &tv, NULL);
	}
	while (s->devs) {
		struct sensor_dev *d = s->devs;
		s->devs = d->next;
		if (d->h)
			sensor_dev_finish_close(d);
		sensor_dev_free(d);
	}
	s->active = NULL;
	for (size_t i = 0; i < s->n_events; i++)
		libusb_unref_device(s->events[i].usb);
	s->n_events = 0;
	if (s->hotplug)
		libusb_hotplug_deregister_callback(s->usb, s->hotplug_handle);
	s->hotplug = 0;
	libusb_set_pollfd_notifiers(s->usb, NULL, NULL, NULL);
	while (s->fds) {
		struct sensor_fd *f = s->fds;
		s->fds = f->next;
		loop_io_del(f->io);
		free(f);
	}
	libusb_exit(s->usb);
	s->usb = NULL;
	loop_timer_arm(s->service_timer, 0);
	loop_timer_arm(s->rescan_timer, 0);
}

static int create(struct loop *l, const struct sensor_config *cfg, sensor_fn fn, void *ctx,
		  int list_mode, struct sensor **ret)
{
	struct sensor *s;
	int r;

	if (sensor_config_check(cfg, NULL, 0) < 0)
		return -EINVAL;
	s = calloc(1, sizeof(*s));
	if (!s)
		return -ENOMEM;
	s->loop = l;
	s->cfg = *cfg;
	s->fn = fn;
	s->ctx = ctx;
	s->list_mode = list_mode;
	if ((r = sensor_pipe_new(&cfg->pipe, &s->pipe)) < 0 ||
	    (r = loop_timer_add(l, service_fired, s, &s->service_timer)) < 0 ||
	    (r = loop_timer_add(l, rescan_fired, s, &s->rescan_timer)) < 0 ||
	    (r = loop_timer_add(l, pipe_fired, s, &s->pipe_timer)) < 0) {
		sensor_free(s);
		return r;
	}
	if (list_mode || !select_is_none(cfg))
		start_usb(s);
	*ret = s;
	return 0;
}

int sensor_new(struct loop *l, const struct sensor_config *cfg, sensor_fn fn, void *ctx,
	       struct sensor **ret)
{
	return create(l, cfg, fn, ctx, 0, ret);
}

void sensor_free(struct sensor *s)
{
	if (!s)
		return;
	stop_usb(s);
	loop_timer_del(s->service_timer);
	loop_timer_del(s->rescan_timer);
	loop_timer_del(s->pipe_timer);
	sensor_pipe_free(s->pipe);
	free(s->events);
	free(s);
}

static void apply_config(struct sensor *s, const struct sensor_config *cfg)
{
	s->cfg = *cfg;
	sensor_pipe_configure(s->pipe, &cfg->pipe);
	if (select_is_none(cfg)) {
		stop_usb(s);
		s->why[0] = 0;
		return;
	}
	if (!s->usb) {
		start_usb(s);
		return;
	}
	for (struct sensor_dev *d = s->devs; d; d = d->next) {
		d->info.selected = select_matches(cfg, &d->info);
		d->retry_ns = 0;
	}
	if (s->active && !s->active->info.selected)
		sensor_dev_close(s->active, SENSOR_DEV_IDLE, "not selected");
}

int sensor_set_config(struct sensor *s, const struct sensor_config *cfg)
{
	if (sensor_config_check(cfg, NULL, 0) < 0)
		return -EINVAL;
	/* From a callback while libusb dispatches or the manager settles:
	 * closing libusb there would pull the ground from under them. */
	if (s->in_events || s->settling) {
		s->pending_cfg = *cfg;
		s->config_pending = 1;
		loop_timer_arm(s->service_timer, 1);
		return 0;
	}
	apply_config(s, cfg);
	sensor_settle(s);
	return 0;
}

/* ---- what it is doing ---- */

void sensor_get_status(const struct sensor *s, struct sensor_status *ret)
{
	memset(ret, 0, sizeof(*ret));
	if (select_is_none(&s->cfg))
		ret->state = SENSOR_STATE_OFF;
	else if (!s->usb)
		ret->state = SENSOR_STATE_UNAVAILABLE;
	else if (!s->active)
		ret->state = SENSOR_STATE_SEARCHING;
	else if (s->active->state != SENSOR_DEV_READING)
		ret->state = SENSOR_STATE_STARTING;
	else if (loop_now_ns() - s->active->fresh_ns >= sensor_s_to_ns(s->cfg.pipe.stale_after_s))
		ret->state = SENSOR_STATE_STALE;
	else
		ret->state = SENSOR_STATE_READING;
	if (s->active)
		ret->device = s->active->info, ret->device.state = s->active->state;
	snprintf(ret->why, sizeof(ret->why), "%s", s->why);
	sensor_pipe_last(s->pipe, &ret->reading);
	sensor_pipe_stats(s->pipe, &ret->pipe);
	ret->counters = s->counters;
}

size_t sensor_devices(const struct sensor *s, struct sensor_info *ret, size_t max)
{
	size_t n = 0;

	for (const struct sensor_dev *d = s->devs; d; d = d->next, n++)
		if (n < max) {
			ret[n] = d->info;
			ret[n].state = d->state;
		}
	return n;
}

static void list_timeout(void *ctx)
{
	loop_quit(ctx);
}

int sensor_list(const struct sensor_config *cfg, double timeout_s, struct sensor_info **ret,
		size_t *ret_n, char *err, size_t err_size)
{
	struct sensor_config c = *cfg;
	struct loop *l;
	struct loop_timer *t;
	struct sensor *s;
	int r;

	*ret = NULL;
	*ret_n = 0;
	if (select_is_none(&c))
		snprintf(c.select, sizeof(c.select), "auto");
	if ((r = loop_new(&l)) < 0)
		return r;
	if ((r = create(l, &c, NULL, NULL, 1, &s)) < 0) {
		loop_free(l);
		return r;
	}
	if (!s->usb) {
		if (err && err_size)
			snprintf(err, err_size, "%s", s->why);
		sensor_free(s);
		loop_free(l);
		return -ENODEV;
	}
	if (loop_timer_add(l, list_timeout, l, &t) == 0) {
		loop_timer_arm(t, sensor_s_to_ns(timeout_s > 0.0 ? timeout_s : 0.001));
		if (!list_done(s))
			loop_run(l);
		loop_timer_del(t);
	}
	size_t n = sensor_devices(s, NULL, 0);
	struct sensor_info *out = calloc(n ? n : 1, sizeof(*out));
	if (!out) {
		r = -ENOMEM;
	} else {
		*ret_n = sensor_devices(s, out, n);
		*ret = out;
		r = 0;
	}
	sensor_free(s);
	loop_free(l);
	return r;
}

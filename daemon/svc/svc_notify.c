/* svc_notify.c - skyd's side of the systemd notification protocol: READY,
 * STATUS, RELOADING, STOPPING and the watchdog's keep-alives. */
#include "svc_notify.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <systemd/sd-daemon.h>

#include "ctl.h"
#include "log.h"
#include "loop.h"
#include "srv.h"

struct svc_notify {
	const struct srv *srv;
	const struct ctl *ctl;
	struct loop_timer *watchdog;
	uint64_t watchdog_ns;		/* keep-alive period: half the watchdog's; 0 none */
	struct loop_timer *status;
	uint64_t status_sent_ns;	/* when STATUS= last went out */
	int status_armed;		/* a deferred STATUS= waits on the timer */
};

void svc_notify_format_status(const struct svc_notify *n, char *buf, size_t size)
{
	struct srv_status st;

	srv_status(n->srv, &st);
	snprintf(buf, size, "generation %llu, clients %d, last compute %.1f ms",
		 (unsigned long long)st.generation, n->ctl ? ctl_clients(n->ctl) : 0,
		 st.last_total_ms);
}

static void send_status(struct svc_notify *n, const char *prefix)
{
	char status[160], msg[256];

	svc_notify_format_status(n, status, sizeof(status));
	snprintf(msg, sizeof(msg), "%sSTATUS=%s", prefix, status);
	sd_notify(0, msg);
	n->status_sent_ns = loop_now_ns();
	n->status_armed = 0;
}

static void on_status_timer(void *ctx)
{
	send_status(ctx, "");
}

/* The keep-alive comes from the loop itself: if a callback hangs, the
 * timer stops firing and systemd's watchdog ends skyd. */
static void on_watchdog(void *ctx)
{
	struct svc_notify *n = ctx;

	sd_notify(0, "WATCHDOG=1");
	loop_timer_arm(n->watchdog, n->watchdog_ns);
}

int svc_notify_new(struct loop *l, const struct srv *srv, struct svc_notify **ret)
{
	struct svc_notify *n = calloc(1, sizeof(*n));
	uint64_t usec = 0;
	int r;

	if (!n)
		return -ENOMEM;
	n->srv = srv;
	r = loop_timer_add(l, on_status_timer, n, &n->status);
	if (r < 0)
		goto fail;
	/* > 0 only when WATCHDOG_USEC is set and WATCHDOG_PID, if set, is us. */
	if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
		n->watchdog_ns = usec * 1000ull / 2;
		r = loop_timer_add(l, on_watchdog, n, &n->watchdog);
		if (r < 0)
			goto fail;
		/* The first one at once: a slow start has used part of the period. */
		sd_notify(0, "WATCHDOG=1");
		r = loop_timer_arm(n->watchdog, n->watchdog_ns);
		if (r < 0)
			goto fail;
		log_debug("watchdog: keep-alive every %llu ms",
			  (unsigned long long)(n->watchdog_ns / 1000000ull));
	}
	*ret = n;
	return 0;
fail:
	svc_notify_free(n);
	return r;
}

void svc_notify_set_ctl(struct svc_notify *n, const struct ctl *ctl)
{
	n->ctl = ctl;
}

void svc_notify_free(struct svc_notify *n)
{
	if (!n)
		return;
	if (n->watchdog)
		loop_timer_del(n->watchdog);
	if (n->status)
		loop_timer_del(n->status);
	free(n);
}

void svc_notify_ready(struct svc_notify *n)
{
	send_status(n, "READY=1\n");
}

void svc_notify_published(struct svc_notify *n)
{
	uint64_t now = loop_now_ns(), next = n->status_sent_ns + SVC_NOTIFY_STATUS_MIN_NS;

	if (n->status_armed)
		return;
	if (now >= next) {
		send_status(n, "");
		return;
	}
	if (loop_timer_arm(n->status, next - now) == 0)
		n->status_armed = 1;
}

void svc_notify_reloading(struct svc_notify *n)
{
	char msg[64];

	snprintf(msg, sizeof(msg), "RELOADING=1\nMONOTONIC_USEC=%llu",
		 (unsigned long long)(loop_now_ns() / 1000ull));
	sd_notify(0, msg);
}

void svc_notify_reloaded(struct svc_notify *n)
{
	send_status(n, "READY=1\n");
}

void svc_notify_stopping(struct svc_notify *n)
{
	sd_notify(0, "STOPPING=1\nSTATUS=stopping");
}

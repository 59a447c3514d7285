/* svc_notify.h - what skyd tells systemd (sd_notify): READY once it
 * serves, a STATUS line after publications (generation, clients, last
 * compute time), RELOADING and READY around a reload, STOPPING at the end,
 * and the watchdog's keep-alives from a timer of the event loop, so that a
 * loop that stops turning stops them and systemd restarts skyd.
 *
 * Without NOTIFY_SOCKET every call does nothing; without WATCHDOG_USEC (or
 * with WATCHDOG_PID naming another process) no keep-alive is sent. */
#ifndef SKYD_SVC_NOTIFY_H
#define SKYD_SVC_NOTIFY_H

#include <stddef.h>
#include <stdint.h>

struct ctl;
struct loop;
struct srv;
struct svc_notify;

/* STATUS= is sent at most this often: publications can come hundreds of
 * times a second (a client steering the sun) and systemd needs none of
 * them but the last. */
#define SVC_NOTIFY_STATUS_MIN_NS 250000000ull

/* Arms the watchdog's keep-alive at half of sd_watchdog_enabled's period.
 * srv and ctl (read for STATUS) must outlive the svc_notify; ctl may be
 * set later (svc_notify_set_ctl). 0 or -errno. */
int svc_notify_new(struct loop *l, const struct srv *srv, struct svc_notify **ret);
void svc_notify_set_ctl(struct svc_notify *n, const struct ctl *ctl);
void svc_notify_free(struct svc_notify *n);

/* READY=1 with the first STATUS. */
void svc_notify_ready(struct svc_notify *n);
/* A new generation is current: STATUS soon (rate-limited). */
void svc_notify_published(struct svc_notify *n);
/* RELOADING=1 (with MONOTONIC_USEC) before a reload, READY=1 after it,
 * whatever its outcome: the old settings still serve when it failed. */
void svc_notify_reloading(struct svc_notify *n);
void svc_notify_reloaded(struct svc_notify *n);
/* STOPPING=1: the loop is over, skyd is tearing down. */
void svc_notify_stopping(struct svc_notify *n);

/* The STATUS text now, as sent: "generation G, clients C, last compute
 * T ms". */
void svc_notify_format_status(const struct svc_notify *n, char *buf, size_t size);

#endif

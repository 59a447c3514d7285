/* sync_harness.h - a replicated skyd set for tests and benchmarks: a real
 * mosquitto on a free loopback port and three skyd (one controller, two
 * followers, sync_lead_ms = 300) with a subscribed libsky client each
 * (docs/sync.md). Needs daemon_harness.h's daemon and libsky. */
#ifndef SKYD_SYNC_HARNESS_H
#define SKYD_SYNC_HARNESS_H

#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <pwd.h>
#include <time.h>

#include "daemon_harness.h"
#include "loopback.h"
#include "sky.h"

#define SYNC_MOSQUITTO_BIN "/usr/sbin/mosquitto"
#define SYNC_MOSQUITTO_PUB "/usr/bin/mosquitto_pub"
#define SYNC_N_SKYD 3
/* The apply time's lead over the controller's set, in ms. */
#define SYNC_LEAD_MS 300

struct sync_rig {
	char dir[128], broker_conf[192], url[96];
	int port;
	pid_t broker_pid;
	struct daemon *skyd[SYNC_N_SKYD];
	sky_client *client[SYNC_N_SKYD];
};

static const char *const sync_role_of[SYNC_N_SKYD] = { "controller", "follower", "follower" };

static inline int64_t sync_realtime_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

/* 1 when mosquitto and mosquitto_pub are installed. */
static inline int sync_have_mosquitto(void)
{
	return access(SYNC_MOSQUITTO_BIN, X_OK) == 0 && access(SYNC_MOSQUITTO_PUB, X_OK) == 0;
}

/* Starts mosquitto (no persistence) with the rig's configuration and waits
 * on its output pipe until it accepts a connection or dies. 0 or -1. */
static inline int sync_broker_start(struct sync_rig *r)
{
	int p[2];

	if (pipe2(p, O_CLOEXEC) < 0)
		return -1;
	r->broker_pid = fork();
	if (r->broker_pid == 0) {
		dup2(p[1], 1);
		dup2(p[1], 2);
		execl(SYNC_MOSQUITTO_BIN, "mosquitto", "-c", r->broker_conf, (char *)NULL);
		_exit(127);
	}
	close(p[1]);
	for (int i = 0; i < 1000; i++) {
		struct pollfd pfd = { .fd = p[0], .events = POLLIN };
		char buf[256];
		if (loopback_accepts(r->port)) {
			close(p[0]);
			return 0;
		}
		if (poll(&pfd, 1, 10) > 0 && read(p[0], buf, sizeof(buf)) == 0)
			break;
	}
	close(p[0]);
	return -1;
}

static inline void sync_broker_kill(struct sync_rig *r)
{
	if (r->broker_pid > 0) {
		kill(r->broker_pid, SIGKILL);
		waitpid(r->broker_pid, NULL, 0);
	}
	r->broker_pid = -1;
}

/* Makes the rig's directory, picks a port, writes the broker's
 * configuration and starts it. 0 or -1. */
static inline int sync_broker_setup(struct sync_rig *r)
{
	struct passwd *pw = getpwuid(getuid());

	r->broker_pid = -1;
	if (harness_mkdtemp(r->dir, sizeof(r->dir)) < 0)
		return -1;
	r->port = loopback_free_port();
	snprintf(r->broker_conf, sizeof(r->broker_conf), "%s/mosquitto.conf", r->dir);
	FILE *f = fopen(r->broker_conf, "w");
	if (!f)
		return -1;
	fprintf(f, "listener %d 127.0.0.1\npersistence false\nallow_anonymous true\n", r->port);
	if (pw)
		fprintf(f, "user %s\n", pw->pw_name);
	fclose(f);
	snprintf(r->url, sizeof(r->url), "mqtt://127.0.0.1:%d/sky", r->port);
	return sync_broker_start(r);
}

/* Starts skyd i in its role (a restart keeps its directory) with small
 * tables and sync_lead_ms in a configuration file (a config key, not a
 * state key), and subscribes its client to every table. 0 or -1. */
static inline int sync_skyd_start(struct sync_rig *r, int i)
{
	char conf[256], cdir[sizeof(r->skyd[0]->dir)];
	const char *argv[] = { "--config", conf, "--sync", r->url, "--sync-role", sync_role_of[i],
			       HARNESS_SMALL, NULL };

	if (!r->skyd[i]) {
		r->skyd[i] = calloc(1, sizeof(*r->skyd[i]));
		if (!r->skyd[i])
			return -1;
	}
	if (!r->skyd[i]->dir[0] && harness_mkdtemp(r->skyd[i]->dir, sizeof(r->skyd[0]->dir)) < 0)
		return -1;
	snprintf(conf, sizeof(conf), "%s/skyd.conf", r->skyd[i]->dir);
	FILE *f = fopen(conf, "w");
	if (!f)
		return -1;
	fprintf(f, "sync_lead_ms = %d\n", SYNC_LEAD_MS);
	fclose(f);
	memcpy(cdir, r->skyd[i]->dir, sizeof(cdir));
	if (daemon_start_in(r->skyd[i], cdir, argv) < 0)
		return -1;
	if (sky_connect(r->skyd[i]->sock, &r->client[i]) < 0 ||
	    sky_subscribe(r->client[i], 0xf, 0) < 0)
		return -1;
	return 0;
}

static inline void sync_skyd_stop(struct sync_rig *r, int i)
{
	sky_disconnect(r->client[i]);
	r->client[i] = NULL;
	daemon_stop(r->skyd[i], SIGKILL);
}

/* Stops everything and removes the directories. */
static inline void sync_rig_finish(struct sync_rig *r)
{
	char cmd[192];

	for (int i = 0; i < SYNC_N_SKYD; i++) {
		sky_disconnect(r->client[i]);
		r->client[i] = NULL;
		if (r->skyd[i])
			daemon_cleanup(r->skyd[i]);
		free(r->skyd[i]);
		r->skyd[i] = NULL;
	}
	sync_broker_kill(r);
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", r->dir);
	(void)!system(cmd);
}

/* One request to skyd i; its reply in buf; the ACK code or -1. */
static inline int sync_request(const struct sync_rig *r, int i, const char *line, char *buf,
			       size_t size)
{
	struct conn c;
	int e;

	if (conn_open(&c, r->skyd[i]->sock) < 0)
		return -1;
	e = conn_request(&c, line, buf, size);
	conn_close(&c);
	return e;
}

/* 1 when skyd i's status says key: want. */
static inline int sync_status_is(const struct sync_rig *r, int i, const char *key,
				 const char *want)
{
	char buf[8192], v[128];

	return sync_request(r, i, "status", buf, sizeof(buf)) == 0 &&
	       reply_value(buf, key, v, sizeof(v)) && strcmp(v, want) == 0;
}

/* The z of the sun direction in client i's slot as libsky hands it out,
 * and in *ret_view_slot (may be NULL) that slot's index; NAN none. */
static inline double sync_sun_z(const struct sync_rig *r, int i, uint32_t *ret_slot)
{
	struct sky_view v;

	for (int k = 0; k < 100; k++) {
		if (sky_view_begin(r->client[i], &v) < 0)
			continue;
		double z = v.slot->state.sun_direction[2];
		uint32_t slot = v.slot_index;
		if (sky_view_end(r->client[i], &v)) {
			if (ret_slot)
				*ret_slot = slot;
			return z;
		}
	}
	return NAN;
}

#endif

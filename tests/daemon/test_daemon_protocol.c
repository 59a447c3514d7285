/* test_daemon_protocol.c - conformance of the control protocol: every verb
 * and every ACK path, against the real skyd on a private socket. */
#include <math.h>
#include <stdatomic.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include "daemon_harness.h"
#include "proto.h"
#include "skyproto.h"
#include "skysample.h"
#include "test.h"

static char reply[1 << 17];

/* get of one key, as a string. */
static const char *get1(struct conn *c, const char *key, char *buf, size_t size)
{
	char req[128];
	snprintf(req, sizeof(req), "get %s", key);
	if (conn_request(c, req, reply, sizeof(reply)) != 0)
		return "";
	return reply_value(reply, key, buf, size) ? buf : "";
}

static void test_basics(struct conn *c)
{
	CHECK(conn_request(c, "ping", reply, sizeof(reply)) == 0);
	CHECK(strcmp(reply, "OK\n") == 0);
	CHECK(conn_request(c, "commands", reply, sizeof(reply)) == 0);
	static const char *const verbs[] = { "set", "get", "batch", "end", "status", "subscribe",
					     "unsubscribe", "sample", "commands", "help", "ping", "close" };
	for (size_t i = 0; i < sizeof(verbs) / sizeof(verbs[0]); i++) {
		char want[64];
		snprintf(want, sizeof(want), "command: %s\n", verbs[i]);
		if (!strstr(reply, want))
			FAIL("commands lacks %s", verbs[i]);
	}
	CHECK(conn_request(c, "help set", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "usage: set key=value") != NULL);
	CHECK(conn_request(c, "help", reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "help nosuchverb", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(strstr(reply, "ACK [50] {help} nosuchverb") == reply);
	CHECK(conn_request(c, "help set extra", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	/* Unknown verb, bad bytes, too many args, blank lines. */
	CHECK(conn_request(c, "frobnicate x=1", reply, sizeof(reply)) == SKY_ACK_UNKNOWN);
	CHECK(strstr(reply, "{frobnicate}") != NULL);
	CHECK(conn_request(c, "Ping", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "get \x01", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "get caf\xc3\xa9", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	char many[2048] = "get";
	for (int i = 0; i < PROTO_MAX_ARGS + 1; i++)
		strcat(many, " a");
	CHECK(conn_request(c, many, reply, sizeof(reply)) == SKY_ACK_LIMIT);
	CHECK(conn_request(c, "\n\nping", reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "ping\r", reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "ping extra", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
}

static void test_get(struct conn *c)
{
	char buf[128];

	CHECK(conn_request(c, "get", reply, sizeof(reply)) == 0);
	static const char *const keys[] = { "preset", "sun_elevation_deg", "sun_azimuth_deg",
					    "altitude_km", "ground_albedo", "mie_g",
					    "rayleigh_scattering_per_km", "skyview_width", "storage" };
	for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
		if (!reply_value(reply, keys[i], buf, sizeof(buf)))
			FAIL("get lacks %s", keys[i]);
	CHECK(conn_request(c, "get sun_elevation_deg skyview_width", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "skyview_width: 32\n") != NULL);
	CHECK(conn_request(c, "get nosuchkey", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "get sun_elevation_deg=3", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
}

static void test_set(struct conn *c, struct conn *ev)
{
	char before[4096], after[4096], buf[64];

	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	/* Every refusal leaves the state as it was. */
	CHECK(conn_request(c, "set", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "set nosuchkey=1", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "set sun_elevation_deg=91", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(conn_request(c, "set sun_elevation_deg=nan", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "set sun_elevation_deg=inf", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "set sun_elevation_deg=1e999", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "set sun_elevation_deg=1,5", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "set sun_elevation_deg", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "set =4", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "set preset=venus", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "set skyview_width=1", reply, sizeof(reply)) == SKY_ACK_RANGE);
	/* All or nothing: the good key before the bad one is not applied. */
	CHECK(conn_request(c, "set sun_elevation_deg=12 nosuchkey=1", reply, sizeof(reply)) ==
	      SKY_ACK_NO_EXIST);
	/* Cross-key rule (state_validate): the top below the ground. */
	CHECK(conn_request(c, "set top_radius_km=6000", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	CHECK(strcmp(before, after) == 0);

	/* A change names its generation; the event says the same. */
	CHECK(conn_request(c, "set sun_elevation_deg=12.5 sun_azimuth_deg=100", reply, sizeof(reply)) == 0);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(g != UINT64_MAX && g > 0);
	CHECK(strstr(reply, "tables: skyview,aerial\n") != NULL);
	CHECK(strcmp(get1(c, "sun_elevation_deg", buf, sizeof(buf)), "12.5") == 0);
	CHECK(conn_wait_generation(ev, g) == 0);
	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") >= g);
	/* A set that changes nothing is visible at once. */
	CHECK(conn_request(c, "set sun_elevation_deg=12.5", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") <= g);
}

static void test_batch(struct conn *c, struct conn *ev)
{
	char buf[64], before[4096], after[4096];

	CHECK(conn_request(c, "end", reply, sizeof(reply)) == SKY_ACK_STATE);
	uint64_t g0 = ev->event_generation;
	/* batch and the sets inside answer nothing; end answers once. */
	const char *ok = "batch\nset sun_elevation_deg=20\nset sun_azimuth_deg=200 camera_yaw_deg=10";
	CHECK(send(c->fd, ok, strlen(ok), 0) > 0);
	CHECK(send(c->fd, "\n", 1, 0) == 1);
	CHECK(conn_request(c, "end", reply, sizeof(reply)) == 0);
	uint64_t g = reply_u64(reply, "generation");
	CHECK(g != UINT64_MAX);
	CHECK(strcmp(get1(c, "sun_azimuth_deg", buf, sizeof(buf)), "200") == 0);
	CHECK(strcmp(get1(c, "sun_elevation_deg", buf, sizeof(buf)), "20") == 0);
	/* One change, one generation: the next event is exactly g. */
	CHECK(g == g0 + 1);
	CHECK(conn_wait_generation(ev, g) == 0);
	CHECK(ev->event_generation == g);

	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	const char *bad = "batch\nset sun_elevation_deg=30\nset sun_elevation_deg=300\nset sun_azimuth_deg=1\n";
	CHECK(send(c->fd, bad, strlen(bad), 0) > 0);
	CHECK(conn_request(c, "end", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(strstr(reply, "{end} line 2:") != NULL);
	const char *other = "batch\nstatus\n";
	CHECK(send(c->fd, other, strlen(other), 0) > 0);
	CHECK(conn_request(c, "end", reply, sizeof(reply)) == SKY_ACK_STATE);
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	CHECK(strcmp(before, after) == 0);
	/* Empty batch: nothing to do, still OK. */
	CHECK(send(c->fd, "batch\n", 6, 0) == 6);
	CHECK(conn_request(c, "end", reply, sizeof(reply)) == 0);
}

static void test_status(struct conn *c)
{
	char buf[256];
	static const char *const keys[] = { "generation", "computing", "pending", "tables_computed",
					    "tables_valid", "compute_ms", "transmittance_ms",
					    "multiscatter_ms", "skyview_ms", "aerial_ms", "failures",
					    "last_error", "device", "clients", "subscribers", "shm_bytes",
					    "grain", "publish" };
	char device[256];

	CHECK(conn_request(c, "status", reply, sizeof(reply)) == 0);
	for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
		if (!reply_value(reply, keys[i], buf, sizeof(buf)))
			FAIL("status lacks %s", keys[i]);
	CHECK(strcmp(reply_value(reply, "last_error", buf, sizeof(buf)), "none") == 0);
	/* A CPU device keeps the CPU grain; lavapipe imports the region, so
	 * the device writes the slots itself. */
	CHECK(reply_value(reply, "device_type", device, sizeof(device)));
	if (!strcmp(device, "cpu"))
		CHECK(strcmp(reply_value(reply, "grain", buf, sizeof(buf)), "cpu") == 0);
	CHECK(reply_value(reply, "device", device, sizeof(device)));
	reply_value(reply, "publish", buf, sizeof(buf));
	if (strstr(device, "llvmpipe"))
		CHECK(!strcmp(buf, "direct"));
	CHECK(!strcmp(buf, "direct") || !strcmp(buf, "copy"));
	CHECK(conn_request(c, "status now", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
}

struct region {
	int fd;
	const uint8_t *map;
	uint64_t bytes;
};

static int map_region(int fd, struct region *r)
{
	struct stat st;
	if (fstat(fd, &st) < 0)
		return -1;
	r->fd = fd;
	r->bytes = (uint64_t)st.st_size;
	r->map = mmap(NULL, r->bytes, PROT_READ, MAP_SHARED, fd, 0);
	return r->map == MAP_FAILED ? -1 : 0;
}

/* Samples the current slot of r as a client does and formats like skyd. */
static void client_sample(const struct region *r, const char *what, double el_deg, double az_deg,
			  char *out, size_t size)
{
	const struct sky_shm_header *h = (const void *)r->map;
	uint32_t cur = atomic_load((_Atomic uint32_t *)&h->current_slot);
	const uint8_t *base = r->map + h->header_bytes + (uint64_t)cur * h->slot_bytes;
	const struct sky_shm_slot *slot = (const void *)base;
	struct skysample_table t;
	double rgb[3];

	if (!strcmp(what, "sky")) {
		skysample_table_from_slot(h, base, SKY_TABLE_SKYVIEW, &t);
		skysample_sky(&t, &slot->state, el_deg * SKYMAP_PI / 180, az_deg * SKYMAP_PI / 180, rgb);
	} else if (!strcmp(what, "sun")) {
		skysample_table_from_slot(h, base, SKY_TABLE_TRANSMITTANCE, &t);
		skysample_sun(&t, &slot->state, rgb);
	} else {
		skysample_table_from_slot(h, base, SKY_TABLE_SKYVIEW, &t);
		skysample_ambient(&t, &slot->state, rgb);
	}
	snprintf(out, size, "%.9g,%.9g,%.9g", rgb[0], rgb[1], rgb[2]);
}

static void test_subscribe_sample(struct conn *c, struct daemon *d)
{
	char buf[256], mine[256];
	struct region r;

	CHECK(conn_request(c, "subscribe", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "subscribe tables=clouds", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "subscribe events=2", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "subscribe colour=1", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "subscribe tables", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(c->n_fds == 0);
	CHECK(conn_request(c, "subscribe tables=all events=1", reply, sizeof(reply)) == 0);
	CHECK(c->n_fds == 1);
	if (c->n_fds != 1 || map_region(c->fds[0], &r) < 0) {
		FAIL("no region");
		return;
	}
	const struct sky_shm_header *h = (const void *)r.map;
	CHECK(h->magic == SKY_SHM_MAGIC && h->layout_version == SKY_SHM_LAYOUT_VERSION);
	CHECK(h->n_slots >= SKY_SHM_MIN_SLOTS);
	CHECK(reply_u64(reply, "shm_bytes") == r.bytes);
	CHECK(reply_u64(reply, "slot_bytes") == h->slot_bytes);
	CHECK(strstr(reply, "table: name=skyview format=rgba32f width=32 height=16 depth=1") != NULL);
	CHECK(skysample_check_layout(h, r.bytes) == 0);

	/* Sampling: errors first, then the numbers a client computes itself. */
	CHECK(conn_request(c, "sample", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "sample moon", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "sample sky el_deg=10", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	CHECK(conn_request(c, "sample sky el_deg=x az_deg=0", reply, sizeof(reply)) == SKY_ACK_ARG);
	CHECK(conn_request(c, "sample sky el_deg=95 az_deg=0", reply, sizeof(reply)) == SKY_ACK_RANGE);
	CHECK(conn_request(c, "sample sky el_deg=9 fov=3", reply, sizeof(reply)) == SKY_ACK_NO_EXIST);
	CHECK(conn_request(c, "sample sun now", reply, sizeof(reply)) == SKY_ACK_SYNTAX);
	/* Settle: no change in flight, so the slot sampled below is current. */
	CHECK(conn_request(c, "set sun_elevation_deg=25 sun_azimuth_deg=180", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(c, reply_u64(reply, "generation")) == 0);
	CHECK(conn_request(c, "sample sky el_deg=10 az_deg=170", reply, sizeof(reply)) == 0);
	client_sample(&r, "sky", 10, 170, mine, sizeof(mine));
	CHECK(reply_value(reply, "radiance_rgb_cd_m2", buf, sizeof(buf)) && !strcmp(buf, mine));
	CHECK(reply_value(reply, "luminance_cd_m2", buf, sizeof(buf)) && atof(buf) > 0);
	CHECK(conn_request(c, "sample sun", reply, sizeof(reply)) == 0);
	client_sample(&r, "sun", 0, 0, mine, sizeof(mine));
	CHECK(reply_value(reply, "illuminance_rgb_lx", buf, sizeof(buf)) && !strcmp(buf, mine));
	CHECK(conn_request(c, "sample ambient", reply, sizeof(reply)) == 0);
	client_sample(&r, "ambient", 0, 0, mine, sizeof(mine));
	CHECK(reply_value(reply, "illuminance_rgb_lx", buf, sizeof(buf)) && !strcmp(buf, mine));

	/* A layout change: a layout: line with the new region; the old one
	 * says it is superseded. */
	int layouts = c->layouts;
	CHECK(conn_request(c, "set skyview_width=48", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(c, reply_u64(reply, "generation")) == 0);
	CHECK(c->layouts == layouts + 1);
	CHECK(c->n_fds == 2);
	CHECK(atomic_load((_Atomic uint32_t *)&h->superseded) == 1);
	struct region r2;
	if (c->n_fds == 2 && map_region(c->fds[1], &r2) == 0) {
		const struct sky_shm_header *h2 = (const void *)r2.map;
		CHECK(h2->tables[SKY_TABLE_SKYVIEW].width == 48);
		CHECK(h2->superseded == 0);
		munmap((void *)r2.map, r2.bytes);
	}
	munmap((void *)r.map, r.bytes);
	CHECK(conn_request(c, "unsubscribe", reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "subscribe events=0", reply, sizeof(reply)) == 0);
	(void)d;
}

static void test_long_line(struct conn *c)
{
	static char line[SKY_PROTO_LINE_MAX + 100];

	memset(line, 'a', sizeof(line) - 1);
	line[sizeof(line) - 1] = 0;
	memcpy(line, "get ", 4);
	CHECK(conn_request(c, line, reply, sizeof(reply)) == SKY_ACK_TOO_LONG);
	CHECK(conn_request(c, "ping", reply, sizeof(reply)) == 0);
	/* The longest line allowed (newline included) is served. */
	memset(line, ' ', SKY_PROTO_LINE_MAX - 1);
	memcpy(line, "ping", 4);
	line[SKY_PROTO_LINE_MAX - 1] = 0;
	CHECK(conn_request(c, line, reply, sizeof(reply)) == 0);
}

static void test_close(struct daemon *d)
{
	struct conn c;
	char line[64];

	CHECK(conn_open(&c, d->sock) == 0);
	CHECK(conn_request(&c, "close", reply, sizeof(reply)) == 0);
	CHECK(conn_line(&c, line, sizeof(line)) == -1);	/* EOF */
	conn_close(&c);
	/* nc-style: requests then EOF still get their replies. */
	int fd = conn_raw(d->sock);
	CHECK(fd >= 0);
	CHECK(send(fd, "ping\nget skyview_height", 23, 0) == 23);
	shutdown(fd, SHUT_WR);
	char all[512] = "";
	size_t o = 0;
	ssize_t n;
	while ((n = read(fd, all + o, sizeof(all) - 1 - o)) > 0)
		o += (size_t)n;
	all[o] = 0;
	CHECK(strstr(all, "OK skyd " SKY_PROTO_VERSION "\nOK\nskyview_height: 16\nOK\n") == all);
	close(fd);
}

static void test_config_check(void)
{
	char dir[128], path[256], cmd[768];
	FILE *f;

	CHECK(harness_mkdtemp(dir, sizeof(dir)) == 0);
	snprintf(path, sizeof(path), "%s/good.conf", dir);
	f = fopen(path, "w");
	fprintf(f, "# a sky\nsun_elevation_deg = 12\n\nmie_g = 0.7  # hazy\n");
	fclose(f);
	snprintf(cmd, sizeof(cmd), "%s -n --config '%s' >/dev/null 2>&1", SKYD_BINARY, path);
	CHECK(WEXITSTATUS(system(cmd)) == 0);
	snprintf(path, sizeof(path), "%s/bad.conf", dir);
	f = fopen(path, "w");
	fprintf(f, "sun_elevation_deg = 12\nsun_elevation_deg = 120\n");
	fclose(f);
	snprintf(cmd, sizeof(cmd), "%s -n --config '%s' 2>&1 | grep -q 'bad.conf:2: sun_elevation_deg'",
		 SKYD_BINARY, path);
	CHECK(WEXITSTATUS(system(cmd)) == 0);
	snprintf(cmd, sizeof(cmd), "%s -n --config '%s' >/dev/null 2>&1", SKYD_BINARY, path);
	CHECK(WEXITSTATUS(system(cmd)) == 1);
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	(void)!system(cmd);
}

static void test_socket_dir(void)
{
	char dir[128], sub[192];
	struct daemon d;
	struct stat st;

	/* A directory others may write is refused; a missing one is made 0700. */
	CHECK(harness_mkdtemp(dir, sizeof(dir)) == 0);
	chmod(dir, 0777);
	memset(&d, 0, sizeof(d));
	CHECK(daemon_start_in(&d, dir, (const char *const[]){ HARNESS_SMALL, NULL }) == -1);
	waitpid(d.pid, NULL, 0);
	close(d.pidfd);
	chmod(dir, 0700);
	snprintf(sub, sizeof(sub), "%s/sub", dir);
	CHECK(mkdir(sub, 0700) == 0);
	memset(&d, 0, sizeof(d));
	CHECK(daemon_start_in(&d, sub, (const char *const[]){ HARNESS_SMALL, NULL }) == 0);
	CHECK(stat(d.sock, &st) == 0 && (st.st_mode & 077) == 0);
	/* SIGTERM: clean exit, socket gone. */
	int status = daemon_stop(&d, SIGTERM);
	CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
	CHECK(access(d.sock, F_OK) == -1);
	char cmd[256];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	(void)!system(cmd);
}

int main(void)
{
	struct daemon d;
	struct conn c, ev;

	harness_need_device();
	test_config_check();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_protocol");
	}
	CHECK(conn_open(&c, d.sock) == 0);
	CHECK(conn_open(&ev, d.sock) == 0);
	CHECK(conn_request(&ev, "subscribe events=1", reply, sizeof(reply)) == 0);
	test_basics(&c);
	test_get(&c);
	test_set(&c, &ev);
	test_batch(&c, &ev);
	test_status(&c);
	test_subscribe_sample(&c, &d);
	test_long_line(&c);
	test_close(&d);
	conn_close(&c);
	conn_close(&ev);
	daemon_cleanup(&d);
	test_socket_dir();
	return test_report("test_daemon_protocol");
}

/* test_daemon_faults.c - the daemon under faults it cannot prevent: a
 * recompute the device refuses (a table allocation over the process's
 * memory limit), a subscriber that never reads its events, and running out
 * of file descriptors; each time everyone else goes on being served. */
#include <stdatomic.h>
#include <sys/inotify.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <dirent.h>
#include <time.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "skysample.h"
#include "test.h"

static char reply[1 << 17];

static long proc_status_kb(pid_t pid, const char *key)
{
	char path[64], line[256];
	size_t k = strlen(key);
	long kb = -1;

	snprintf(path, sizeof(path), "/proc/%d/status", (int)pid);
	FILE *f = fopen(path, "re");
	while (f && fgets(line, sizeof(line), f))
		if (!strncmp(line, key, k) && line[k] == ':')
			kb = atol(line + k + 1);
	if (f)
		fclose(f);
	return kb;
}

/* user + system CPU time of pid, in ms. */
static double proc_cpu_ms(pid_t pid)
{
	char path[64], buf[1024];
	unsigned long long ut = 0, st = 0;

	snprintf(path, sizeof(path), "/proc/%d/stat", (int)pid);
	FILE *f = fopen(path, "re");
	if (!f)
		return -1;
	size_t n = fread(buf, 1, sizeof(buf) - 1, f);
	fclose(f);
	buf[n] = 0;
	const char *p = strrchr(buf, ')');	/* comm may hold spaces */
	if (!p || sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &ut, &st) != 2)
		return -1;
	return (double)(ut + st) * 1000.0 / (double)sysconf(_SC_CLK_TCK);
}

static double now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

/* Count of lines of the daemon's log that hold needle. */
static int log_count(const struct daemon *d, const char *needle)
{
	char line[1024];
	int n = 0;
	FILE *f = fopen(d->log, "re");

	while (f && fgets(line, sizeof(line), f))
		n += strstr(line, needle) != NULL;
	if (f)
		fclose(f);
	return n;
}

/* Waits (inotify on the log, no polling loop) until the log holds at least
 * count lines with needle. 0, or -1 after HARNESS_TIMEOUT_MS. */
static int log_wait(const struct daemon *d, const char *needle, int count)
{
	int in = inotify_init1(IN_CLOEXEC);
	int r = -1;

	if (in < 0 || inotify_add_watch(in, d->log, IN_MODIFY) < 0)
		goto out;
	double deadline = now_ms() + HARNESS_TIMEOUT_MS;
	while (log_count(d, needle) < count) {
		struct pollfd p = { in, POLLIN, 0 };
		int left = (int)(deadline - now_ms());
		if (left <= 0 || poll(&p, 1, left) <= 0)
			goto out;
		char ev[4096];
		(void)!read(in, ev, sizeof(ev));
	}
	r = 0;
out:
	if (in >= 0)
		close(in);
	return r;
}

static int set_soft_limit(pid_t pid, int resource, rlim_t soft)
{
	struct rlimit old, lim;

	if (prlimit(pid, resource, NULL, &old) < 0)
		return -errno;
	lim.rlim_cur = soft;
	lim.rlim_max = old.rlim_max;
	return prlimit(pid, resource, &lim, NULL) < 0 ? -errno : 0;
}

/* A mapping of the region a subscribe passed, or NULL. */
static const struct sky_shm_header *map_region(struct conn *c)
{
	struct stat st;
	if (c->n_fds < 1 || fstat(c->fds[c->n_fds - 1], &st) < 0)
		return NULL;
	void *m = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, c->fds[c->n_fds - 1], 0);
	return m == MAP_FAILED ? NULL : m;
}

static const struct sky_shm_slot *current_slot(const struct sky_shm_header *h)
{
	uint32_t cur = atomic_load_explicit((_Atomic uint32_t *)&h->current_slot, memory_order_acquire);
	return (const void *)((const uint8_t *)h + h->header_bytes + (uint64_t)cur * h->slot_bytes);
}

/* (a) A recompute the device refuses. A table of 128 MiB (the largest
 * lavapipe's storage-buffer limit allows) needs 256 MiB of device memory
 * (table and read-back buffer); with the daemon's address space limited to
 * 64 MiB over what it uses, vkAllocateMemory fails: an honest failure, no
 * fault injection. */
static void test_failed_recompute(struct daemon *d)
{
	struct conn sub, ctl;
	char buf[512];

	CHECK(conn_open(&sub, d->sock) == 0);
	CHECK(conn_open(&ctl, d->sock) == 0);
	CHECK(conn_request(&sub, "subscribe tables=all events=1", reply, sizeof(reply)) == 0);
	const struct sky_shm_header *h = map_region(&sub);
	if (!h) {
		FAIL("no region");
		return;
	}
	/* A good generation to keep. */
	CHECK(conn_request(&ctl, "set sun_elevation_deg=21", reply, sizeof(reply)) == 0);
	uint64_t good = reply_u64(reply, "generation");
	CHECK(conn_wait_generation(&sub, good) == 0);
	const struct sky_shm_slot *s = current_slot(h);
	CHECK(s->generation == good);
	uint32_t valid = s->valid_tables;
	uint64_t checksum = s->checksum;

	char depth_before[128];
	CHECK(conn_request(&ctl, "get aerial_depth", depth_before, sizeof(depth_before)) == 0);
	long vm_kb = proc_status_kb(d->pid, "VmSize");
	CHECK(vm_kb > 0);
	CHECK(set_soft_limit(d->pid, RLIMIT_AS, (rlim_t)(vm_kb + 65536) * 1024) == 0);
	int code = conn_request(&ctl, "set aerial_width=256 aerial_height=256 aerial_depth=128",
				reply, sizeof(reply));
	/* The code the daemon sends for a change whose computation could not
	 * start: 60 (engine), PROTOCOL.md. */
	CHECK(code == SKY_ACK_ENGINE);
	CHECK(strstr(reply, "{set} state unchanged, computation failed:") != NULL);
	printf("refused recompute: %s", reply);
	/* Subscribers hear it as a failed: line naming the generation it was
	 * meant for. */
	char line[1024];
	int got_failed = 0;
	while (!got_failed && conn_line(&sub, line, sizeof(line)) >= 0)
		if (!strncmp(line, "failed: ", 8)) {
			got_failed = 1;
			CHECK(strtoull(line + strlen("failed: generation="), NULL, 10) == good + 1);
			CHECK(strstr(line, " message=") != NULL);
			CHECK(strstr(line, "VK_ERROR_OUT_OF") != NULL);
		}
	CHECK(got_failed);
	/* The last good tables stay published, untouched. */
	CHECK(atomic_load_explicit((_Atomic uint32_t *)&h->superseded, memory_order_acquire) == 0);
	s = current_slot(h);
	CHECK(s->generation == good);
	CHECK(s->valid_tables == valid);
	CHECK(s->checksum == checksum);
	CHECK(skysample_slot_checksum(h, s) == s->checksum);
	/* status says why; the request was refused whole (PROTOCOL.md, code 60). */
	CHECK(conn_request(&ctl, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == good);
	CHECK(reply_u64(reply, "failures") >= 1);
	CHECK(reply_value(reply, "last_error", buf, sizeof(buf)) && strstr(buf, "vkAllocateMemory"));
	CHECK(reply_value(reply, "tables_valid", buf, sizeof(buf)) &&
	      !strcmp(buf, "transmittance,multiscatter,skyview,aerial"));
	CHECK(conn_request(&ctl, "get aerial_depth", reply, sizeof(reply)) == 0);
	CHECK(!strcmp(reply, depth_before));
	/* Samples still come from the last good tables. */
	CHECK(conn_request(&ctl, "sample sun", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "generation") == good);

	/* Memory back: a change that fits computes and publishes (the state it
	 * starts from is the one before the refused request), status clears
	 * the error. */
	CHECK(set_soft_limit(d->pid, RLIMIT_AS, RLIM_INFINITY) == 0);
	CHECK(conn_request(&ctl, "set sun_elevation_deg=12", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(&sub, reply_u64(reply, "generation")) == 0);
	good = reply_u64(reply, "generation");
	CHECK(conn_request(&ctl, "set aerial_width=8 aerial_height=8 aerial_depth=4", reply, sizeof(reply)) == 0);
	uint64_t next = reply_u64(reply, "generation");
	/* Visible at once or with a new generation; either way it applied. */
	CHECK(next >= good);
	CHECK(conn_request(&ctl, "get aerial_depth", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "aerial_depth: 4\n") != NULL);
	CHECK(conn_wait_generation(&sub, next) == 0);
	CHECK(conn_request(&ctl, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_value(reply, "last_error", buf, sizeof(buf)) && !strcmp(buf, "none"));
	CHECK(reply_u64(reply, "generation") >= next);
	conn_close(&sub);
	conn_close(&ctl);
}

/* (b) A subscriber that never reads while changes are published: its
 * queue grows to CTL_OUT_MAX (256 KiB of event lines, about 48 bytes each,
 * behind what the kernel's socket buffer took) and skyd drops it; the
 * others see every generation meanwhile. */
static void test_lazy_subscriber(struct daemon *d)
{
	struct conn lazy, obs, ctl;
	char req[128];
	int changes = 0, dropped = 0;

	CHECK(conn_open(&lazy, d->sock) == 0);
	CHECK(conn_open(&obs, d->sock) == 0);
	CHECK(conn_open(&ctl, d->sock) == 0);
	CHECK(conn_request(&lazy, "subscribe events=1", reply, sizeof(reply)) == 0);
	CHECK(conn_request(&obs, "subscribe events=1", reply, sizeof(reply)) == 0);
	int drops_before = log_count(d, "output queue over its bound");
	double t0 = now_ms();
	uint64_t last = 0;
	/* 256 KiB / 48 bytes is about 5400 events; stop well past that. */
	while (changes < 20000) {
		snprintf(req, sizeof(req), "set sun_azimuth_deg=%.3f", 0.01 * changes);
		if (conn_request(&ctl, req, reply, sizeof(reply)) != 0) {
			FAIL("set %d: %s", changes, reply);
			break;
		}
		changes++;
		last = reply_u64(reply, "generation");
		/* The observer gets every generation, in order. */
		if (conn_wait_generation(&obs, last) < 0) {
			FAIL("observer never saw generation %llu", (unsigned long long)last);
			break;
		}
		struct pollfd p = { lazy.fd, POLLIN, 0 };
		if (poll(&p, 1, 0) == 1 && (p.revents & POLLHUP)) {
			dropped = 1;
			break;
		}
	}
	double ms = now_ms() - t0;
	CHECK(dropped);
	CHECK(log_count(d, "output queue over its bound") > drops_before);
	/* What the kernel had taken is still readable, then the end. */
	size_t bytes = 0;
	int events = 0, eof = 0;
	char line[256];
	for (;;) {
		int n = conn_line(&lazy, line, sizeof(line));
		if (n < 0) {
			eof = 1;
			break;
		}
		bytes += (size_t)n + 1;
		events += !strncmp(line, "changed: ", 9);
	}
	CHECK(eof);
	/* The socket held a few KiB: the drop came from skyd's bound, not from
	 * the kernel refusing more. */
	CHECK(events > 0 && bytes < (64u << 10));
	CHECK((size_t)changes * 48 > (256u << 10) - bytes);
	printf("lazy subscriber dropped after %d changes (%.0f ms, %.2f ms each); it had %zu bytes "
	       "(%d events) in its socket, the rest up to the 256 KiB bound in skyd's queue\n",
	       changes, ms, ms / changes, bytes, events);
	/* The others go on. */
	CHECK(conn_request(&ctl, "set sun_azimuth_deg=123.456", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(&obs, reply_u64(reply, "generation")) == 0);
	CHECK(conn_request(&ctl, "status", reply, sizeof(reply)) == 0);
	CHECK(reply_u64(reply, "clients") == 2);
	conn_close(&lazy);
	conn_close(&obs);
	conn_close(&ctl);
}

/* Open fds of pid and the highest fd number. */
static int count_fds(pid_t pid, int *ret_max)
{
	char path[64];
	int n = 0, max = -1;

	snprintf(path, sizeof(path), "/proc/%d/fd", (int)pid);
	DIR *dir = opendir(path);
	if (!dir)
		return -1;
	for (struct dirent *e; (e = readdir(dir));) {
		if (e->d_name[0] == '.')
			continue;
		int fd = atoi(e->d_name);
		n++;
		if (fd > max)
			max = fd;
	}
	closedir(dir);
	*ret_max = max;
	return n;
}

/* (c) Out of fds: skyd stops accepting instead of spinning on the ready
 * listening socket, serves the clients it has, and accepts again when an
 * fd frees up. */
static void test_emfile(struct daemon *d)
{
	enum { SPARE = 6, EXTRA = 3 };
	struct conn first, extra[EXTRA];
	int maxfd = -1;

	CHECK(conn_open(&first, d->sock) == 0);
	CHECK(conn_request(&first, "subscribe events=1", reply, sizeof(reply)) == 0);
	int open_fds = count_fds(d->pid, &maxfd);
	CHECK(open_fds > 0);
	/* The limit is on fd numbers: every number below it is either open
	 * now or free (holes left by what skyd inherited count too). */
	rlim_t limit = (rlim_t)maxfd + 1 + SPARE;
	int n_acc = (int)limit - open_fds;
	struct conn *accepted = calloc((size_t)n_acc, sizeof(*accepted));
	if (n_acc < SPARE || n_acc > 1000 || !accepted) {
		FAIL("%d free fds", n_acc);
		free(accepted);
		conn_close(&first);
		return;
	}
	CHECK(set_soft_limit(d->pid, RLIMIT_NOFILE, limit) == 0);
	int pauses = log_count(d, "accept: ");
	for (int i = 0; i < n_acc; i++)
		CHECK(conn_open(&accepted[i], d->sock) == 0);
	/* These wait in the listen backlog: skyd has no fd to take them. */
	for (int i = 0; i < EXTRA; i++) {
		memset(&extra[i], 0, sizeof(extra[i]));
		extra[i].fd = conn_raw(d->sock);
		CHECK(extra[i].fd >= 0);
	}
	CHECK(log_wait(d, "accept: ", pauses + 1) == 0);
	/* Paused, not spinning: over a measured half second of wall time in
	 * which it serves a client, skyd uses little CPU. */
	double cpu0 = proc_cpu_ms(d->pid), t0 = now_ms();
	int pings = 0;
	while (now_ms() - t0 < 500) {
		CHECK(conn_request(&accepted[0], "ping", reply, sizeof(reply)) == 0);
		pings++;
		struct pollfd p = { -1, 0, 0 };
		poll(&p, 0, 10);	/* a measurement window, not synchronisation */
	}
	double cpu = proc_cpu_ms(d->pid) - cpu0, wall = now_ms() - t0;
	printf("out of fds: skyd used %.0f ms of CPU in %.0f ms answering %d pings; %d accept "
	       "warnings in its log\n", cpu, wall, pings, log_count(d, "accept: ") - pauses);
	CHECK(cpu < 0.2 * wall);
	/* One line when it pauses, not one per retry. */
	CHECK(log_count(d, "accept: ") - pauses <= 2);
	for (int i = 0; i < EXTRA; i++) {
		struct pollfd p = { extra[i].fd, POLLIN, 0 };
		CHECK(poll(&p, 1, 0) == 0);	/* no greeting */
	}
	/* Existing clients are served: a change computes and is published. */
	CHECK(conn_request(&accepted[1], "set sun_elevation_deg=33", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(&first, reply_u64(reply, "generation")) == 0);
	/* A subscribe needs an fd to pass the region: refused with a clear
	 * ACK, never an OK without the descriptor. */
	int code = conn_request(&accepted[2], "subscribe tables=all", reply, sizeof(reply));
	CHECK(code == SKY_ACK_LIMIT || (code == 0 && accepted[2].n_fds == 1));
	printf("subscribe while out of fds: %s", reply);
	/* A client leaves: one waiting connection gets its fd and greeting. */
	conn_close(&accepted[--n_acc]);
	char line[256];
	int greeted = -1;
	struct pollfd ps[EXTRA];
	for (int i = 0; i < EXTRA; i++)
		ps[i] = (struct pollfd){ extra[i].fd, POLLIN, 0 };
	CHECK(poll(ps, EXTRA, HARNESS_TIMEOUT_MS) == 1);
	for (int i = 0; i < EXTRA; i++)
		if (ps[i].revents & POLLIN)
			greeted = i;
	CHECK(greeted >= 0 && conn_line(&extra[greeted], line, sizeof(line)) > 0 &&
	      !strncmp(line, "OK skyd ", 8));
	/* fds back: the rest are accepted (on the retry timer). */
	CHECK(set_soft_limit(d->pid, RLIMIT_NOFILE, 1024) == 0);
	for (int i = 0; i < EXTRA; i++) {
		if (i == greeted)
			continue;
		CHECK(conn_line(&extra[i], line, sizeof(line)) > 0 && !strncmp(line, "OK skyd ", 8));
		CHECK(conn_request(&extra[i], "ping", reply, sizeof(reply)) == 0);
	}
	code = conn_request(&accepted[2], "subscribe tables=all", reply, sizeof(reply));
	CHECK(code == 0 && accepted[2].n_fds == 1);
	for (int i = 0; i < EXTRA; i++)
		conn_close(&extra[i]);
	for (int i = 0; i < n_acc; i++)
		conn_close(&accepted[i]);
	free(accepted);
	conn_close(&first);
}

int main(void)
{
	struct daemon d;

	harness_need_device();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_faults");
	}
	test_failed_recompute(&d);
	test_emfile(&d);
	test_lazy_subscriber(&d);
	if (test_failures) {
		/* Stopped (it holds our stdout: ctest would wait for it), log kept. */
		daemon_stop(&d, SIGTERM);
		printf("skyd log kept: %s\n", d.log);
	}
	else
		daemon_cleanup(&d);
	return test_report("test_daemon_faults");
}

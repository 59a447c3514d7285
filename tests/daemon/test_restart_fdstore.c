/* test_restart_fdstore.c - a restart of skyd under systemd's fd store
 * keeps the clients' mapping: the test plays systemd (fdstore_harness.h),
 * keeps what skyd stores (FDNAME=shm, FDNAME=control) and starts the next
 * skyd with those fds (LISTEN_FDS, LISTEN_FDNAMES, LISTEN_PID). A libsky
 * client that reconnects by itself stays mapped at the same address on the
 * same memfd, gets no SKY_EVENT_LAYOUT, and reads the next generations,
 * numbered on from the old ones, in that mapping; so does a plain reader
 * of the memory. Another layout after a restart: a new region, the old one
 * superseded, the count still going on. */
#include <inttypes.h>
#include <math.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/un.h>

#include "daemon_harness.h"
#include "fdstore_harness.h"
#include "sky.h"
#include "test.h"

#define SMALL_TABLES HARNESS_SMALL

struct events {
	int reconnected, hangups, layouts;
	uint64_t userdata;		/* of the last SKY_EVENT_RECONNECTED */
};

struct skyd {
	pid_t pid;
	int pidfd;
};

static char dir[128], sock[192], logpath[192];

/* Starts skyd with the store's fds and extra (NULL-terminated) arguments;
 * 0 once it said READY=1. */
static int start_as(struct fdsim *s, struct skyd *d, bool with_socket, const char *const *extra)
{
	const char *argv[40] = { SKYD_BINARY, "--socket", sock, SMALL_TABLES };
	const char *activated[40] = { SKYD_BINARY, SMALL_TABLES };
	int n = 0;

	if (!with_socket)
		memcpy(argv, activated, sizeof(argv));
	while (argv[n])
		n++;
	for (int i = 0; extra && extra[i]; i++)
		argv[n++] = extra[i];
	argv[n] = NULL;
	d->pid = fdsim_spawn(s, argv, logpath, &d->pidfd);
	if (d->pid < 0 || fdsim_wait_ready(s, d->pidfd, HARNESS_TIMEOUT_MS) < 0) {
		char cmd[256];
		snprintf(cmd, sizeof(cmd), "cat '%s' >&2", logpath);
		(void)!system(cmd);
		return -1;
	}
	return 0;
}

static int start(struct fdsim *s, struct skyd *d, const char *const *extra)
{
	return start_as(s, d, true, extra);
}

/* A listening socket at path, as systemd's socket unit makes it. */
static int listen_at(const char *path)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);

	if (strlen(path) >= sizeof(sa.sun_path)) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	memcpy(sa.sun_path, path, strlen(path) + 1);
	if (fd < 0 || bind(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0 || listen(fd, 16) < 0) {
		if (fd >= 0)
			close(fd);
		return -1;
	}
	return fd;
}

static void stop(struct skyd *d, int sig)
{
	kill(d->pid, sig);
	waitpid(d->pid, NULL, 0);
	close(d->pidfd);
	d->pid = 0;
}

/* The inode of the file mapped at addr (/proc/self/maps), 0 if none. */
static unsigned long mapped_inode(const void *addr)
{
	FILE *f = fopen("/proc/self/maps", "r");
	char line[512];
	unsigned long ino = 0;

	while (f && fgets(line, sizeof(line), f)) {
		unsigned long start, inode;
		if (sscanf(line, "%lx-%*x %*s %*s %*s %lu", &start, &inode) == 2 &&
		    start == (unsigned long)(uintptr_t)addr) {
			ino = inode;
			break;
		}
	}
	if (f)
		fclose(f);
	return ino;
}

static unsigned long fd_inode(int fd)
{
	struct stat st;
	return fd >= 0 && fstat(fd, &st) == 0 ? (unsigned long)st.st_ino : 0;
}

/* Dispatches (polling the socket while there is one, else every 10 ms, as
 * sky_set_reconnect asks) until an event of type, counting events. */
static int await_event(sky_client *c, struct events *ev, enum sky_event_type type)
{
	long long end = (notify_now_ns() / 1000000LL) + HARNESS_TIMEOUT_MS;
	int *count = type == SKY_EVENT_LAYOUT ? &ev->layouts : &ev->reconnected;
	int before = *count;

	while (*count == before && (notify_now_ns() / 1000000LL) < end) {
		struct sky_event e;
		int fd = sky_get_fd(c), r;
		if (fd >= 0) {
			struct pollfd p = { fd, POLLIN, 0 };
			poll(&p, 1, 10);
		} else {
			poll(NULL, 0, 10);	/* the reconnect interval: a poll timeout */
		}
		while ((r = sky_dispatch(c, &e)) == 1) {
			ev->reconnected += e.type == SKY_EVENT_RECONNECTED;
			ev->hangups += e.type == SKY_EVENT_HANGUP;
			ev->layouts += e.type == SKY_EVENT_LAYOUT;
			if (e.type == SKY_EVENT_RECONNECTED)
				ev->userdata = e.userdata;
		}
		if (r < 0)
			return r;
	}
	return *count > before ? 0 : -ETIMEDOUT;
}

static int await_reconnect(sky_client *c, struct events *ev)
{
	return await_event(c, ev, SKY_EVENT_RECONNECTED);
}

/* Waits until the newest slot holds a generation > after with every table,
 * within the harness's timeout. */
static int wait_newer(sky_client *c, uint64_t after, struct sky_view *ret)
{
	long long end = notify_now_ns() / 1000000LL + HARNESS_TIMEOUT_MS;

	while (notify_now_ns() / 1000000LL < end) {
		int r = sky_view_begin(c, ret);
		if (r < 0 && r != -EAGAIN)
			return r;
		bool ok = r == 0 && ret->slot->generation > after &&
			  (ret->valid_tables & SKY_TABLES_ALL) == SKY_TABLES_ALL;
		if (r == 0 && sky_view_end(c, ret) && ok)
			return 0;
		r = sky_wait(c, r == 0 ? ret->generation : 0, 200, NULL);
		if (r < 0 && r != -ETIMEDOUT)
			return r;
	}
	return -ETIMEDOUT;
}

static int log_says(const char *what)
{
	char cmd[512];
	snprintf(cmd, sizeof(cmd), "grep -q '%s' '%s'", what, logpath);
	return system(cmd) == 0;
}

/* The sky in a direction, read from a copy of the newest slot. */
static bool sky_readable(sky_client *c)
{
	size_t n = sky_snapshot_size(c);
	void *buf = aligned_alloc(64, (n + 63) / 64 * 64);
	struct sky_view v;
	double rgb[3] = { 0 };
	bool ok = buf && sky_snapshot(c, buf, n, &v) == 0 && sky_view_verify(&v) &&
		  sky_sample_sky(&v, 20.0, 90.0, 0, rgb) == 0 && rgb[0] > 0 && isfinite(rgb[2]);
	free(buf);
	return ok;
}

/* One restart that keeps the region: stop with sig, start the next skyd
 * with the stored fds (and extra arguments); the client and a plain reader
 * (raw, a mapping of the stored memfd of the test's own) stay on the
 * memory. */
static void restart_keeps_mapping(struct fdsim *s, struct skyd *d, int sig, sky_client *c,
				  struct events *ev, const struct sky_shm_header *raw,
				  const char *const *extra)
{
	struct sky_view v;
	const struct sky_shm_header *addr = sky_header(c);
	unsigned long ino = mapped_inode(addr);
	CHECK(sky_view_begin(c, &v) == 0);
	uint64_t old_gen = v.slot->generation;
	uint32_t old_word = __atomic_load_n(&addr->generation, __ATOMIC_ACQUIRE);
	sky_view_end(c, &v);

	long long t0 = notify_now_ns();
	stop(d, sig);
	/* The pause: the old tables stay readable, the socket's path stays. */
	struct stat st;
	CHECK(stat(sock, &st) == 0);
	CHECK(sky_view_begin(c, &v) == 0 && v.slot->generation == old_gen);
	CHECK(sky_view_end(c, &v));
	CHECK(fdsim_get(s, "shm") >= 0 && fdsim_get(s, "control") >= 0);

	truncate(logpath, 0);
	CHECK(start(s, d, extra) == 0);
	CHECK(log_says("adopted the stored region"));
	int before = ev->reconnected, layouts = ev->layouts;
	CHECK(await_reconnect(c, ev) == 0);
	CHECK(ev->reconnected == before + 1);
	CHECK(ev->userdata == 0);
	CHECK(ev->hangups == 0 && ev->layouts == layouts);
	/* The same mapping, the same memfd, and new tables in it. */
	CHECK(sky_header(c) == addr);
	CHECK(mapped_inode(sky_header(c)) == ino && ino == fd_inode(fdsim_get(s, "shm")));
	CHECK(wait_newer(c, old_gen, &v) == 0);
	CHECK(sky_header(c) == addr);
	CHECK(__atomic_load_n(&addr->generation, __ATOMIC_ACQUIRE) > old_word);
	CHECK(sky_readable(c));
	/* A reader that maps the memory itself sees the same generations. */
	CHECK(__atomic_load_n(&raw->generation, __ATOMIC_ACQUIRE) ==
	      __atomic_load_n(&addr->generation, __ATOMIC_ACQUIRE));
	CHECK(!raw->superseded);
	/* The pause: from the signal to the first new generation in place. */
	printf("restart by signal %d: generation %" PRIu64 " -> %" PRIu64
	       " in the mapping at %p, paused %.0f ms\n",
	       sig, old_gen, v.slot->generation, (const void *)addr, (notify_now_ns() - t0) / 1e6);
}

int main(void)
{
	struct fdsim s;
	struct skyd d = { 0 };
	struct events ev = { 0 };
	sky_client *c = NULL;
	struct sky_view v;

	harness_need_device();
	if (harness_mkdtemp(dir, sizeof(dir)) < 0 || fdsim_open(&s, dir, 4) < 0) {
		FAIL("temporary directory or notify socket");
		return test_report("test_restart_fdstore");
	}
	snprintf(sock, sizeof(sock), "%s/control", dir);
	snprintf(logpath, sizeof(logpath), "%s/skyd.log", dir);

	/* First start: skyd stores its region and socket before READY=1. */
	CHECK(start(&s, &d, NULL) == 0);
	int shm = fdsim_get(&s, "shm");
	CHECK(shm >= 0 && fdsim_get(&s, "control") >= 0);
	int seals = fcntl(shm, F_GET_SEALS);
	CHECK(seals == (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL));
	CHECK(sky_connect(sock, &c) == 0);
	if (c) {
		CHECK(sky_set_reconnect(c, 10) == 0);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL, 0) == 0);
		CHECK(wait_newer(c, 0, &v) == 0);
	}
	if (!c || !sky_header(c)) {
		/* What follows reads the mapped region. skyd is stopped: it
		 * holds our stdout, and ctest would wait for it. */
		stop(&d, SIGTERM);
		return test_report("test_restart_fdstore");
	}
	/* What the client maps is the stored memory, and it is read-only. */
	CHECK(mapped_inode(sky_header(c)) == fd_inode(shm));
	CHECK(mprotect((void *)sky_header(c), 4096, PROT_READ | PROT_WRITE) < 0);
	size_t raw_bytes = (size_t)sky_header(c)->total_bytes;
	const struct sky_shm_header *raw = mmap(NULL, raw_bytes, PROT_READ, MAP_SHARED, shm, 0);
	CHECK(raw != MAP_FAILED);

	/* systemctl restart (SIGTERM), then a crash (SIGKILL). */
	restart_keeps_mapping(&s, &d, SIGTERM, c, &ev, raw, NULL);
	restart_keeps_mapping(&s, &d, SIGKILL, c, &ev, raw, NULL);

	/* A new layout while skyd runs: the store gets the new region in
	 * place of the old one (FDSTOREREMOVE=1, FDSTORE=1); the client
	 * remaps as always; a restart with that layout adopts it. */
	static const char *const wider[] = { "skyview_width=48", NULL };
	unsigned long first_ino = fd_inode(shm);
	int removes = s.removes;
	CHECK(sky_request(c, "set skyview_width=48", NULL) == 0);
	CHECK(await_event(c, &ev, SKY_EVENT_LAYOUT) == 0);
	CHECK(fdsim_wait_store(&s, "shm", HARNESS_TIMEOUT_MS) == 0);
	CHECK(raw->superseded == 1);
	CHECK(s.removes > removes);
	shm = fdsim_get(&s, "shm");
	CHECK(fd_inode(shm) != first_ino && fd_inode(shm) == mapped_inode(sky_header(c)));
	size_t raw2_bytes = (size_t)sky_header(c)->total_bytes;
	const struct sky_shm_header *raw2 = mmap(NULL, raw2_bytes, PROT_READ, MAP_SHARED, shm, 0);
	CHECK(raw2 != MAP_FAILED);
	restart_keeps_mapping(&s, &d, SIGTERM, c, &ev, raw2, wider);

	/* Another layout at the restart (the set above was not kept): the
	 * stored region does not fit; it is superseded, a new one is stored
	 * in its place, and the client remaps, told once. */
	const struct sky_shm_header *addr = sky_header(c);
	CHECK(sky_view_begin(c, &v) == 0);
	uint64_t old_gen = v.slot->generation;
	sky_view_end(c, &v);
	unsigned long old_ino = fd_inode(fdsim_get(&s, "shm"));
	int layouts = ev.layouts;
	removes = s.removes;
	stop(&d, SIGTERM);
	CHECK(start(&s, &d, NULL) == 0);
	CHECK(log_says("another layout"));
	CHECK(raw2->superseded == 1);
	CHECK(s.removes > removes);
	CHECK(fd_inode(fdsim_get(&s, "shm")) != old_ino && fdsim_get(&s, "shm") >= 0);
	CHECK(await_reconnect(c, &ev) == 0);
	CHECK(ev.reconnected == 4 && ev.userdata == 1 && ev.hangups == 0 && ev.layouts == layouts);
	CHECK(sky_header(c) != addr && sky_header(c)->tables[SKY_TABLE_SKYVIEW].width == 32);
	CHECK(mapped_inode(sky_header(c)) == fd_inode(fdsim_get(&s, "shm")));
	CHECK(wait_newer(c, old_gen, &v) == 0);
	CHECK(sky_readable(c));

	/* Socket activation, as the unit runs skyd (skyd.socket): systemd
	 * keeps the socket itself, skyd stores only its region and adopts it
	 * again; the client above, on the old path, keeps its mapping and sees
	 * the new generations in it. */
	char act[192];
	snprintf(act, sizeof(act), "%s/activated", dir);
	for (int i = 0; i < s.n; i++)
		if (strcmp(s.e[i].name, "control") == 0) {
			close(s.e[i].fd);
			s.e[i] = s.e[--s.n];
		}
	int lfd = listen_at(act);
	CHECK(lfd >= 0 && s.n < FDSIM_MAX);
	snprintf(s.e[s.n].name, sizeof(s.e[s.n].name), "skyd.socket");
	s.e[s.n++].fd = lfd;
	addr = sky_header(c);
	unsigned long ino = fd_inode(fdsim_get(&s, "shm"));
	uint32_t word = __atomic_load_n(&addr->generation, __ATOMIC_ACQUIRE);
	CHECK(sky_view_begin(c, &v) == 0);
	old_gen = v.slot->generation;
	sky_view_end(c, &v);
	stop(&d, SIGTERM);
	truncate(logpath, 0);
	CHECK(start_as(&s, &d, false, NULL) == 0);
	CHECK(log_says("adopted the stored region") && log_says("socket activation"));
	CHECK(fdsim_get(&s, "control") < 0 && fd_inode(fdsim_get(&s, "shm")) == ino);
	sky_client *a = NULL;
	CHECK(sky_connect(act, &a) == 0);
	if (a) {
		CHECK(sky_subscribe(a, SKY_TABLES_ALL, 0) == 0);
		CHECK(mapped_inode(sky_header(a)) == ino);
		CHECK(wait_newer(a, old_gen, &v) == 0);
		sky_disconnect(a);
	}
	CHECK(sky_header(c) == addr && __atomic_load_n(&addr->generation, __ATOMIC_ACQUIRE) > word);

	sky_disconnect(c);
	munmap((void *)raw, raw_bytes);
	munmap((void *)raw2, raw2_bytes);
	stop(&d, SIGTERM);
	fdsim_close(&s);
	char cmd[256];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	(void)!system(cmd);
	return test_report("test_restart_fdstore");
}

/* test_daemon_shm.c - the shared memory under load and abuse: 16 reader
 * processes check every snapshot while 500 changes are published; clients
 * cannot write or shrink the region; a reader killed mid-read, a client that
 * never reads, 500 connections, a 1 MiB line and a SIGKILLed skyd. */
#include <time.h>
#include <stdatomic.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "test.h"

#define READERS 16
static int CHANGES = 500;

static char reply[1 << 16];

struct reader_result {
	uint64_t snapshots, torn, bad, generations, last_generation;
};

static uint64_t slot_checksum(const struct sky_shm_header *h, const struct sky_shm_slot *slot)
{
	const uint8_t *base = (const uint8_t *)slot;
	uint64_t c = sky_shm_checksum_words(SKY_SHM_CHECKSUM_SEED, &slot->state,
					    sizeof(slot->state) / 8);
	c = sky_shm_checksum_words(c, &slot->clouds, sizeof(slot->clouds) / 8);
	for (uint32_t t = 0; t < h->n_tables; t++)
		if (slot->valid_tables & (1u << t))
			c = sky_shm_checksum_words(c, base + h->tables[t].offset, h->tables[t].bytes / 8);
	return c;
}

/* Copies the newest slot out, seqlock-checked; 1 copied, 0 torn. */
static int snapshot(const uint8_t *map, uint8_t *copy)
{
	const struct sky_shm_header *h = (const void *)map;
	uint32_t cur = atomic_load_explicit((_Atomic uint32_t *)&h->current_slot, memory_order_acquire);
	const uint8_t *slot = map + h->header_bytes + (uint64_t)cur * h->slot_bytes;
	_Atomic uint32_t *seq = (_Atomic uint32_t *)slot;
	uint32_t s1 = atomic_load_explicit(seq, memory_order_acquire);

	if (s1 & 1)
		return 0;
	memcpy(copy, slot, h->slot_bytes);
	atomic_thread_fence(memory_order_acquire);
	return atomic_load_explicit(seq, memory_order_relaxed) == s1;
}

/* A reader process: reads continuously until it has copied a slot of
 * generation *final_gen or later (UINT64_MAX until the writer has made its
 * last change), then writes its counts to result_fd. Ending on the event,
 * not on a signal from the writer, makes every reader prove it saw the last
 * publication however the scheduler treated it. ready_fd gets one byte once
 * it has mapped. */
static int reader(const char *sock, const _Atomic uint64_t *final_gen, int result_fd, int ready_fd)
{
	struct reader_result res = { 0 };
	struct conn c;
	struct stat st;

	if (conn_open(&c, sock) < 0 || conn_request(&c, "subscribe tables=all", reply, sizeof(reply)) ||
	    c.n_fds != 1 || fstat(c.fds[0], &st) < 0)
		return 1;
	const uint8_t *map = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, c.fds[0], 0);
	if (map == MAP_FAILED)
		return 1;
	const struct sky_shm_header *h = (const void *)map;
	uint8_t *copy = malloc(h->slot_bytes);
	/* Readers yield the CPU to skyd and lavapipe on this small machine. */
	(void)!nice(19);
	if (ready_fd >= 0)
		(void)!write(ready_fd, "r", 1);
	for (;;) {
		if (!snapshot(map, copy)) {
			res.torn++;
			continue;
		}
		const struct sky_shm_slot *s = (const void *)copy;
		res.snapshots++;
		if (s->checksum != slot_checksum(h, s))
			res.bad++;
		if (s->generation != res.last_generation) {
			res.generations++;
			res.last_generation = s->generation;
		}
		if (s->generation >= atomic_load_explicit(final_gen, memory_order_acquire))
			break;
	}
	(void)!write(result_fd, &res, sizeof(res));
	return 0;
}

static void test_readers(struct daemon *d)
{
	int results[2], ready[2];
	pid_t pids[READERS];
	struct conn c;
	char req[128];

	_Atomic uint64_t *final_gen = mmap(NULL, sizeof(*final_gen), PROT_READ | PROT_WRITE,
					   MAP_SHARED | MAP_ANONYMOUS, -1, 0);
	if (final_gen == MAP_FAILED) {
		FAIL("mmap: %s", strerror(errno));
		return;
	}
	atomic_store(final_gen, UINT64_MAX);
	CHECK(pipe2(results, O_CLOEXEC) == 0 && pipe2(ready, O_CLOEXEC) == 0);
	for (int i = 0; i < READERS; i++) {
		pids[i] = fork();
		if (pids[i] == 0)
			_exit(reader(d->sock, final_gen, results[1], ready[1]));
	}
	close(results[1]);
	close(ready[1]);
	for (int i = 0; i < READERS; i++) {
		char b;
		CHECK(read(ready[0], &b, 1) == 1);
	}
	CHECK(conn_open(&c, d->sock) == 0);
	CHECK(conn_request(&c, "subscribe events=1", reply, sizeof(reply)) == 0);
	uint64_t first = 0, last = 0, t0 = 0;
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	t0 = (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
	for (int i = 0; i < CHANGES; i++) {
		/* Each change waits for its own generation: 500 publications. */
		snprintf(req, sizeof(req), "set sun_elevation_deg=%.3f sun_azimuth_deg=%d",
			 -10.0 + 80.0 * i / CHANGES, i % 360);
		if (conn_request(&c, req, reply, sizeof(reply)) != 0) {
			FAIL("set %d: %s", i, reply);
			break;
		}
		last = reply_u64(reply, "generation");
		if (!first)
			first = last;
		if (conn_wait_generation(&c, last) < 0) {
			FAIL("generation %llu never came", (unsigned long long)last);
			break;
		}
	}
	clock_gettime(CLOCK_MONOTONIC, &ts);
	double ms = ((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec - t0) / 1e6;
	CHECK(last - first + 1 == (uint64_t)CHANGES);
	atomic_store_explicit(final_gen, last, memory_order_release);
	struct reader_result total = { 0 }, r;
	int got = 0;
	while (read(results[0], &r, sizeof(r)) == sizeof(r)) {
		got++;
		total.snapshots += r.snapshots;
		total.torn += r.torn;
		total.bad += r.bad;
		total.generations += r.generations;
		CHECK(r.snapshots > 0 && r.last_generation >= last);
	}
	for (int i = 0; i < READERS; i++) {
		int status;
		waitpid(pids[i], &status, 0);
		CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
	}
	CHECK(got == READERS);
	CHECK(total.bad == 0);
	printf("readers: %d changes in %.0f ms (%.2f ms each) under %d readers: %llu snapshots, "
	       "%llu torn and retried, %llu inconsistent, %llu generations seen\n",
	       CHANGES, ms, ms / CHANGES, READERS, (unsigned long long)total.snapshots,
	       (unsigned long long)total.torn, (unsigned long long)total.bad,
	       (unsigned long long)total.generations);
	close(results[0]);
	close(ready[0]);
	munmap(final_gen, sizeof(*final_gen));
	conn_close(&c);
}

static void test_protection(struct daemon *d)
{
	struct conn c;
	struct stat st;
	char path[64];

	CHECK(conn_open(&c, d->sock) == 0);
	CHECK(conn_request(&c, "subscribe tables=all", reply, sizeof(reply)) == 0);
	if (c.n_fds != 1) {
		FAIL("no fd");
		return;
	}
	int fd = c.fds[0];
	CHECK(fstat(fd, &st) == 0);
	size_t n = (size_t)st.st_size;
	CHECK(mmap(NULL, n, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0) == MAP_FAILED);
	void *ro = mmap(NULL, n, PROT_READ, MAP_SHARED, fd, 0);
	CHECK(ro != MAP_FAILED);
	CHECK(mprotect(ro, n, PROT_READ | PROT_WRITE) == -1);
	CHECK(write(fd, "x", 1) == -1);
	CHECK(pwrite(fd, "x", 1, 0) == -1);
	CHECK(ftruncate(fd, 0) == -1);
	CHECK(ftruncate(fd, (off_t)n * 2) == -1);
	CHECK(fcntl(fd, F_ADD_SEALS, F_SEAL_WRITE) == -1);
	int seals = fcntl(fd, F_GET_SEALS);
	CHECK(seals >= 0 && (seals & (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE | F_SEAL_SEAL)) ==
			    (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE | F_SEAL_SEAL));
	/* Reopening read-write: refused by the 0444 mode; root passes that
	 * check, and then the seals refuse every way to write or shrink. */
	snprintf(path, sizeof(path), "/proc/self/fd/%d", fd);
	int rw = open(path, O_RDWR | O_CLOEXEC);
	if (rw >= 0) {
		CHECK(geteuid() == 0);
		CHECK(write(rw, "x", 1) == -1 && errno == EPERM);
		CHECK(mmap(NULL, n, PROT_READ | PROT_WRITE, MAP_SHARED, rw, 0) == MAP_FAILED);
		CHECK(ftruncate(rw, 0) == -1 && errno == EPERM);
		CHECK(ftruncate(rw, (off_t)n * 2) == -1 && errno == EPERM);
		CHECK(fallocate(rw, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, 0, 4096) == -1);
		close(rw);
	}
	CHECK(fstat(fd, &st) == 0 && (size_t)st.st_size == n);
	munmap(ro, n);
	conn_close(&c);
}

/* The daemon still answers and publishes for a fresh client. */
static int serves(struct daemon *d)
{
	static int calls;
	struct conn c;
	char req[64];

	/* A new value each time: a set that changes nothing publishes nothing. */
	snprintf(req, sizeof(req), "set sun_azimuth_deg=%d", 33 + ++calls);
	int ok = conn_open(&c, d->sock) == 0 &&
		 conn_request(&c, "subscribe events=1", reply, sizeof(reply)) == 0 &&
		 conn_request(&c, req, reply, sizeof(reply)) == 0 &&
		 conn_wait_generation(&c, reply_u64(reply, "generation")) == 0 &&
		 conn_request(&c, "ping", reply, sizeof(reply)) == 0;
	conn_close(&c);
	return ok;
}

static void test_abuse(struct daemon *d)
{
	/* A reader killed mid-read holds nothing. */
	static const _Atomic uint64_t never = UINT64_MAX;
	int results[2], ready[2];
	CHECK(pipe2(results, O_CLOEXEC) == 0 && pipe2(ready, O_CLOEXEC) == 0);
	pid_t pid = fork();
	if (pid == 0)
		_exit(reader(d->sock, &never, results[1], ready[1]));
	char b;
	CHECK(read(ready[0], &b, 1) == 1);
	kill(pid, SIGKILL);
	waitpid(pid, NULL, 0);
	for (int i = 0; i < 2; i++)
		close(results[i]), close(ready[i]);
	CHECK(serves(d));

	/* A client that never reads: pipelined requests and events pile up. */
	struct conn lazy;
	CHECK(conn_open(&lazy, d->sock) == 0);
	CHECK(conn_request(&lazy, "subscribe events=1", reply, sizeof(reply)) == 0);
	fcntl(lazy.fd, F_SETFL, O_NONBLOCK);
	static char gets[64 << 10];
	for (size_t o = 0; o + 4 <= sizeof(gets); o += 4)
		memcpy(gets + o, "get\n", 4);
	for (int i = 0; i < 16; i++)
		if (send(lazy.fd, gets, sizeof(gets), MSG_NOSIGNAL) < 0)
			break;
	CHECK(serves(d));
	CHECK(serves(d));

	/* 500 connections opened and dropped, some mid-line. */
	int fds[500];
	for (int i = 0; i < 500; i++) {
		fds[i] = conn_raw(d->sock);
		if (fds[i] < 0) {
			FAIL("connection %d: %s", i, strerror(errno));
			continue;
		}
		if (i % 3 == 0)
			(void)!send(fds[i], "set sun_elev", 12, MSG_NOSIGNAL);
	}
	CHECK(serves(d));
	for (int i = 0; i < 500; i++)
		if (fds[i] >= 0)
			close(fds[i]);
	CHECK(serves(d));
	/* Every one of them is reaped (status counts only us and the lazy one). */
	struct conn c;
	CHECK(conn_open(&c, d->sock) == 0);
	uint64_t clients = 0;
	for (int i = 0; i < 10000; i++) {
		CHECK(conn_request(&c, "status", reply, sizeof(reply)) == 0);
		clients = reply_u64(reply, "clients");
		if (clients <= 2)
			break;
	}
	CHECK(clients <= 2);

	/* A 1 MiB request line: ACK, and the connection goes on. */
	size_t big = 1 << 20;
	char *line = malloc(big + 16);
	memset(line, 'x', big);
	memcpy(line, "set ", 4);
	memcpy(line + big, "\nping\n", 6);
	size_t off = 0;
	int acked = 0, ponged = 0;
	fcntl(c.fd, F_SETFL, O_NONBLOCK);
	while (!(acked && ponged)) {
		struct pollfd p = { c.fd, POLLIN | (off < big + 6 ? POLLOUT : 0), 0 };
		if (poll(&p, 1, HARNESS_TIMEOUT_MS) <= 0)
			break;
		if ((p.revents & POLLOUT) && off < big + 6) {
			ssize_t w = send(c.fd, line + off, big + 6 - off, MSG_NOSIGNAL);
			if (w > 0)
				off += (size_t)w;
		}
		/* Every whole line received: the ACK and the OK may come in one
		 * read, and the second would wait in the buffer while poll sleeps. */
		if (p.revents & POLLIN) {
			char l[512];
			int n;
			do {
				if ((n = conn_line(&c, l, sizeof(l))) < 0)
					break;
				if (!strncmp(l, "ACK [53]", 8))
					acked = 1;
				else if (!strcmp(l, "OK") && acked)
					ponged = 1;
			} while (memchr(c.buf, '\n', c.len));
			if (n < 0)
				break;
		}
	}
	CHECK(acked && ponged);
	free(line);
	conn_close(&c);
	CHECK(serves(d));
	conn_close(&lazy);
	CHECK(serves(d));
}

static void test_sigkill(struct daemon *d)
{
	struct conn a, b;
	char line[256];

	CHECK(conn_open(&a, d->sock) == 0);
	CHECK(conn_open(&b, d->sock) == 0);
	CHECK(conn_request(&b, "subscribe tables=all events=1", reply, sizeof(reply)) == 0);
	struct stat st;
	CHECK(b.n_fds == 1 && fstat(b.fds[0], &st) == 0);
	const struct sky_shm_header *h = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, b.fds[0], 0);
	CHECK(h != MAP_FAILED);
	daemon_stop(d, SIGKILL);
	CHECK(conn_line(&a, line, sizeof(line)) == -1);
	/* b may have the changed: line of the tables its subscription made
	 * skyd compute (demand); nothing else. */
	while (conn_line(&b, line, sizeof(line)) >= 0)
		CHECK(is_event_line(line));
	/* The mapping outlives the daemon: the last tables stay readable. */
	if (h != MAP_FAILED)
		CHECK(h->magic == SKY_SHM_MAGIC);
	conn_close(&a);
	conn_close(&b);
	/* A new skyd replaces the stale socket. */
	CHECK(daemon_start_in(d, d->dir, (const char *const[]){ HARNESS_SMALL, NULL }) == 0);
	CHECK(serves(d));
}

int main(void)
{
	struct daemon d;

	harness_need_device();
	if (getenv("TEST_CHANGES"))
		CHANGES = atoi(getenv("TEST_CHANGES"));
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_shm");
	}
	test_protection(&d);
	test_readers(&d);
	test_abuse(&d);
	test_sigkill(&d);
	if (test_failures) {
		/* Stopped (it holds our stdout: ctest would wait for it), log kept. */
		daemon_stop(&d, SIGTERM);
		printf("skyd log kept: %s\n", d.log);
	} else {
		daemon_cleanup(&d);
	}
	return test_report("test_daemon_shm");
}

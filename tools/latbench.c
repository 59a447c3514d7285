/* latbench.c - the service's figures: latency from a set to the new
 * generation visible in a client, a client's snapshot copy time, the
 * writer's compute time with 0 and 64 clients reading at 60 Hz, and skyd's
 * resident memory at rest. Starts its own skyd (default layout) on a private
 * socket. A benchmark, not a test: it prints, it does not judge. */
#include <linux/futex.h>
#include <math.h>
#include <stdatomic.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>

#include "daemon_harness.h"
#include "skyproto.h"

static char reply[1 << 16];

static double now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double pct(double *v, int n, double p)
{
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	int i = (int)ceil(p * n) - 1;
	return v[i < 0 ? 0 : i];
}

struct region {
	const uint8_t *map;
	const struct sky_shm_header *h;
	uint64_t bytes;
};

static int subscribe(struct conn *c, const char *sock, struct region *r)
{
	struct stat st;
	if (conn_open(c, sock) < 0 || conn_request(c, "subscribe tables=all", reply, sizeof(reply)) ||
	    c->n_fds < 1 || fstat(c->fds[c->n_fds - 1], &st) < 0)
		return -1;
	r->bytes = (uint64_t)st.st_size;
	r->map = mmap(NULL, r->bytes, PROT_READ, MAP_SHARED, c->fds[c->n_fds - 1], 0);
	r->h = (const void *)r->map;
	return r->map == MAP_FAILED ? -1 : 0;
}

static int copy_slot(const struct region *r, uint8_t *out)
{
	for (;;) {
		uint32_t cur = atomic_load_explicit((_Atomic uint32_t *)&r->h->current_slot, memory_order_acquire);
		const uint8_t *slot = r->map + r->h->header_bytes + (uint64_t)cur * r->h->slot_bytes;
		_Atomic uint32_t *seq = (_Atomic uint32_t *)slot;
		uint32_t s1 = atomic_load_explicit(seq, memory_order_acquire);
		if (s1 & 1)
			continue;
		memcpy(out, slot, r->h->slot_bytes);
		atomic_thread_fence(memory_order_acquire);
		if (atomic_load_explicit(seq, memory_order_relaxed) == s1)
			return 0;
	}
}

/* Waits on the futex word until the generation reaches gen. */
static void wait_generation(const struct region *r, uint32_t gen)
{
	_Atomic uint32_t *g = (_Atomic uint32_t *)&r->h->generation;
	for (;;) {
		uint32_t v = atomic_load_explicit(g, memory_order_acquire);
		if ((int32_t)(v - gen) >= 0)
			return;
		syscall(SYS_futex, g, FUTEX_WAIT, v, NULL, NULL, 0);
	}
}

static long rss_kb(pid_t pid)
{
	char path[64], line[256];
	long kb = -1;
	snprintf(path, sizeof(path), "/proc/%d/status", (int)pid);
	FILE *f = fopen(path, "r");
	while (f && fgets(line, sizeof(line), f))
		if (!strncmp(line, "VmRSS:", 6))
			kb = atol(line + 6);
	if (f)
		fclose(f);
	return kb;
}

/* Mean compute_ms over n sun changes, each waited for. */
static double mean_compute(struct conn *c, const struct region *r, int n, int salt)
{
	char req[128], buf[64];
	double sum = 0;
	for (int i = 0; i < n; i++) {
		snprintf(req, sizeof(req), "set sun_elevation_deg=%.4f", 5.0 + 0.01 * i + 0.003 * salt);
		conn_request(c, req, reply, sizeof(reply));
		wait_generation(r, (uint32_t)reply_u64(reply, "generation"));
		conn_request(c, "status", reply, sizeof(reply));
		sum += atof(reply_value(reply, "compute_ms", buf, sizeof(buf)));
	}
	return sum / n;
}

/* A client reading a snapshot 60 times a second until killed. */
static void reader_60hz(const char *sock)
{
	struct conn c;
	struct region r;
	if (subscribe(&c, sock, &r) < 0)
		_exit(1);
	uint8_t *buf = malloc(r.h->slot_bytes);
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	for (;;) {
		copy_slot(&r, buf);
		t.tv_nsec += 16666667;
		if (t.tv_nsec >= 1000000000) {
			t.tv_nsec -= 1000000000;
			t.tv_sec++;
		}
		clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL);
	}
}

int main(int argc, char **argv)
{
	int n = argc > 1 ? atoi(argv[1]) : 200;
	struct daemon d;
	struct conn c;
	struct region r;
	char req[128];

	harness_need_device();
	if (daemon_start(&d, NULL) < 0)
		return 1;
	if (subscribe(&c, d.sock, &r) < 0)
		return 1;
	wait_generation(&r, 1);
	printf("device: ");
	conn_request(&c, "status", reply, sizeof(reply));
	char buf[256];
	printf("%s\n", reply_value(reply, "device", buf, sizeof(buf)));
	printf("default layout: %llu bytes a slot, %llu bytes in all\n",
	       (unsigned long long)r.h->slot_bytes, (unsigned long long)r.h->total_bytes);

	/* 1. set -> visible, through the futex. */
	double *lat = malloc(sizeof(double) * (size_t)n);
	for (int i = 0; i < n; i++) {
		snprintf(req, sizeof(req), "set sun_elevation_deg=%.4f", 10.0 + 0.01 * i);
		double t0 = now_ms();
		conn_request(&c, req, reply, sizeof(reply));
		wait_generation(&r, (uint32_t)reply_u64(reply, "generation"));
		lat[i] = now_ms() - t0;
	}
	printf("set -> generation visible (sun change, %d runs): median %.2f ms, p99 %.2f ms\n", n,
	       pct(lat, n, 0.5), pct(lat, n, 0.99));

	/* 2. A client's snapshot copy. */
	uint8_t *copy = malloc(r.h->slot_bytes);
	int copies = 2000;
	double t0 = now_ms();
	for (int i = 0; i < copies; i++)
		copy_slot(&r, copy);
	printf("snapshot copy (%llu bytes): %.1f us each (mean of %d)\n",
	       (unsigned long long)r.h->slot_bytes, (now_ms() - t0) * 1e3 / copies, copies);

	/* 3. Writer compute time, 0 vs 64 readers at 60 Hz. */
	int runs = n < 50 ? n : 50;
	double idle = mean_compute(&c, &r, runs, 0);
	pid_t kids[64];
	for (int i = 0; i < 64; i++) {
		kids[i] = fork();
		if (kids[i] == 0)
			reader_60hz(d.sock);
	}
	conn_request(&c, "status", reply, sizeof(reply));	/* settle: all connected */
	double busy = mean_compute(&c, &r, runs, 1);
	for (int i = 0; i < 64; i++) {
		kill(kids[i], SIGKILL);
		waitpid(kids[i], NULL, 0);
	}
	printf("writer compute_ms (sun change, mean of %d): %.2f with 0 readers, %.2f with 64 readers at 60 Hz (%+.1f %%)\n",
	       runs, idle, busy, 100.0 * (busy - idle) / idle);

	/* 4. Resident memory at rest. */
	conn_close(&c);
	printf("skyd resident memory at rest: %ld kB\n", rss_kb(d.pid));
	daemon_cleanup(&d);
	return 0;
}

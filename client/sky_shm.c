/* sky_shm.c - libsky's side of the shared memory: mapping the sealed memfd
 * read-only, seqlock views and snapshots of the newest slot whose apply time
 * has passed, and waiting for a new generation on the futex word (following
 * a layout change) or for a slot's apply time. */
#include <errno.h>
#include <fcntl.h>
#include <linux/futex.h>
#include <stdatomic.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "sky_internal.h"
#include "skysample.h"

void sky_unmap(sky_client *c)
{
	if (c->map)
		munmap((void *)c->map, c->map_bytes);
	c->map = NULL;
	c->map_bytes = 0;
}

/* The seal against shrinking matters: a shrink would turn our reads into
 * SIGBUS. */
int sky_map_memfd(sky_client *c, int fd)
{
	struct stat st;
	int r;
	if (fstat(fd, &st) < 0) {
		r = -errno;
		goto out;
	}
	int seals = fcntl(fd, F_GET_SEALS);
	if (seals < 0 || !(seals & F_SEAL_SHRINK) || st.st_size < (off_t)sizeof(struct sky_shm_header)) {
		r = -EPROTO;
		goto out;
	}
	/* The same memory: views into it stay valid, nothing to tell. */
	if (c->map && (uint64_t)st.st_dev == c->map_dev && (uint64_t)st.st_ino == c->map_ino &&
	    (size_t)st.st_size == c->map_bytes) {
		r = 0;
		goto out;
	}
	void *m = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
	if (m == MAP_FAILED) {
		r = -errno;
		goto out;
	}
	r = skysample_check_layout(m, (uint64_t)st.st_size);
	if (r < 0) {
		munmap(m, (size_t)st.st_size);
		goto out;
	}
	sky_unmap(c);
	c->map = m;
	c->map_bytes = (size_t)st.st_size;
	c->map_dev = (uint64_t)st.st_dev;
	c->map_ino = (uint64_t)st.st_ino;
	c->map_serial++;
	r = 0;
out:
	close(fd);
	return r;
}

const struct sky_shm_header *sky_header(const sky_client *c)
{
	return c ? c->map : NULL;
}

size_t sky_snapshot_size(const sky_client *c)
{
	return c && c->map ? (size_t)c->map->slot_bytes : 0;
}

static const struct sky_shm_slot *slot_at(const sky_client *c, uint32_t i)
{
	return (const struct sky_shm_slot *)((const unsigned char *)c->map + c->map->header_bytes +
					     (uint64_t)i * c->map->slot_bytes);
}

static int64_t realtime_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

/* The spare slot (the last: the daemon writes a generation computed ahead
 * of its apply time there before it makes it current) when it is stable,
 * has an apply time and is newer than the current slot: 1 with its
 * sequence, generation and apply time, else 0. */
static int spare_ahead(const sky_client *c, uint32_t current, uint32_t *ret_seq,
		       uint64_t *ret_gen, int64_t *ret_apply_ns)
{
	uint32_t j = c->map->n_slots - 1;
	if (j == current)
		return 0;
	const struct sky_shm_slot *s = slot_at(c, j);
	uint32_t seq = __atomic_load_n(&s->seq, __ATOMIC_ACQUIRE);
	if (seq & 1u)
		return 0;
	uint64_t g = __atomic_load_n(&s->generation, __ATOMIC_RELAXED);
	int64_t at = __atomic_load_n(&s->apply_time_ns, __ATOMIC_RELAXED);
	uint64_t cur = __atomic_load_n(&slot_at(c, current)->generation, __ATOMIC_RELAXED);
	atomic_thread_fence(memory_order_acquire);
	if (__atomic_load_n(&s->seq, __ATOMIC_RELAXED) != seq || at <= 0 || g <= cur)
		return 0;
	*ret_seq = seq;
	*ret_gen = g;
	*ret_apply_ns = at;
	return 1;
}

/* Picks the newest slot whose apply time has passed and its even sequence:
 * the current slot, or the spare slot ahead of it once its apply time
 * (CLOCK_REALTIME) is reached; -EAGAIN while the current slot is odd.
 * ret_wake_ns (may be NULL) gets the apply time of a spare slot still
 * ahead, 0 when there is none. The generation is the header's word, but
 * in a superseded region the slot's own: skyd bumped that word once more
 * to wake waiters, to the number the next region publishes, and a view
 * holding that number would take the next region's first publication
 * for one it has seen (sky_wait would sleep through it). */
static int pick_slot(const sky_client *c, uint32_t *ret_index, uint32_t *ret_seq,
		     uint32_t *ret_gen, int64_t *ret_wake_ns)
{
	uint32_t gen = __atomic_load_n(&c->map->generation, __ATOMIC_ACQUIRE);
	uint32_t i = __atomic_load_n(&c->map->current_slot, __ATOMIC_ACQUIRE);
	uint32_t seq;
	uint64_t ahead_gen;
	int64_t apply_ns;

	if (ret_wake_ns)
		*ret_wake_ns = 0;
	if (i >= c->map->n_slots)
		return -EPROTO;
	if (spare_ahead(c, i, &seq, &ahead_gen, &apply_ns)) {
		if (apply_ns <= realtime_ns()) {
			*ret_index = c->map->n_slots - 1;
			*ret_seq = seq;
			*ret_gen = (uint32_t)ahead_gen;
			return 0;
		}
		if (ret_wake_ns)
			*ret_wake_ns = apply_ns;
	}
	uint32_t s = __atomic_load_n(&slot_at(c, i)->seq, __ATOMIC_ACQUIRE);
	if (s & 1u)
		return -EAGAIN;
	/* Read after the word: a bumped word comes with the flag. No writer
	 * touches a superseded region's slots. */
	if (__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE))
		gen = (uint32_t)__atomic_load_n(&slot_at(c, i)->generation, __ATOMIC_RELAXED);
	*ret_index = i;
	*ret_seq = s;
	*ret_gen = gen;
	return 0;
}

int sky_view_begin(sky_client *c, struct sky_view *ret_view)
{
	if (!c || !ret_view)
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	for (int t = 0; t < SKY_VIEW_TRIES; t++) {
		uint32_t i, seq, gen;
		int r = pick_slot(c, &i, &seq, &gen, NULL);
		if (r == -EAGAIN)
			continue;
		if (r < 0)
			return r;
		const struct sky_shm_slot *s = slot_at(c, i);
		ret_view->header = c->map;
		ret_view->slot = s;
		ret_view->slot_base = s;
		ret_view->generation = gen;
		ret_view->valid_tables = __atomic_load_n(&s->valid_tables, __ATOMIC_RELAXED);
		ret_view->slot_index = i;
		ret_view->seq = seq;
		return 0;
	}
	return -EAGAIN;
}

bool sky_view_end(const sky_client *c, const struct sky_view *v)
{
	if (!c || !v || !c->map || v->header != c->map || v->slot_index >= c->map->n_slots)
		return false;
	atomic_thread_fence(memory_order_acquire);
	return __atomic_load_n(&slot_at(c, v->slot_index)->seq, __ATOMIC_RELAXED) == v->seq;
}

int sky_snapshot(sky_client *c, void *buf, size_t size, struct sky_view *ret_view)
{
	if (!c || !buf || !ret_view || ((uintptr_t)buf & 7u))
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	if (size < c->map->slot_bytes)
		return -ENOBUFS;
	for (int t = 0; t < SKY_SNAPSHOT_TRIES; t++) {
		uint32_t i, seq, gen;
		int r = pick_slot(c, &i, &seq, &gen, NULL);
		if (r == -EAGAIN)
			continue;
		if (r < 0)
			return r;
		const struct sky_shm_slot *s = slot_at(c, i);
		memcpy(buf, s, c->map->slot_bytes);
		atomic_thread_fence(memory_order_acquire);
		if (__atomic_load_n(&s->seq, __ATOMIC_RELAXED) != seq)
			continue;
		const struct sky_shm_slot *copy = buf;
		ret_view->header = c->map;
		ret_view->slot = copy;
		ret_view->slot_base = buf;
		ret_view->generation = gen;
		ret_view->valid_tables = copy->valid_tables;
		ret_view->slot_index = i;
		ret_view->seq = seq;
		return 0;
	}
	return -EAGAIN;
}

bool sky_view_verify(const struct sky_view *v)
{
	if (!v || !v->header || !v->slot_base)
		return false;
	return skysample_slot_checksum(v->header, v->slot_base) == v->slot->checksum;
}

static bool map_replaced(const sky_client *c)
{
	return c->map != c->old_map;
}

/* The region was superseded: the new one is on its way on the socket with a
 * "layout:" line. Reads the socket (queueing what else comes) until it is
 * mapped or the deadline passes. */
static int follow_layout(sky_client *c, int64_t deadline)
{
	if (c->fd < 0)
		return -ENOTCONN;
	c->old_map = c->map;
	return sky_pump_until(c, map_replaced, deadline < 0 ? -1 : sky_left_ms(deadline), false);
}

/* The generation a reader sees now (pick_slot's) and, in *ret_wake_ns,
 * the apply time at which that changes by itself (0: none). Returns the
 * header's word when no slot is stable (a publication is under way). */
static uint32_t visible_generation(const sky_client *c, uint32_t word, int64_t *ret_wake_ns)
{
	uint32_t i, seq, gen;

	if (pick_slot(c, &i, &seq, &gen, ret_wake_ns) < 0) {
		*ret_wake_ns = 0;
		return word;
	}
	return gen;
}

/* Sleeps on the futex word while it holds word, at most left_ms (-1: no
 * bound) and not past wake_ns (CLOCK_REALTIME, 0: none). 0 or -errno. */
static int futex_sleep(const uint32_t *addr, uint32_t word, int left_ms, int64_t wake_ns)
{
	int64_t ns = left_ms < 0 ? -1 : (int64_t)left_ms * 1000000ll;
	if (wake_ns > 0) {
		int64_t until = wake_ns - realtime_ns();
		if (until < 0)
			until = 0;
		if (ns < 0 || until < ns)
			ns = until;
	}
	struct timespec ts = { (time_t)(ns / 1000000000ll), (long)(ns % 1000000000ll) };
	/* Shared (not private) futex: the word lives in a shared mapping. */
	long r = syscall(SYS_futex, addr, FUTEX_WAIT, word, ns < 0 ? NULL : &ts, NULL, 0);
	if (r < 0 && errno == EINTR)
		return -EINTR;
	if (r < 0 && errno != EAGAIN && errno != ETIMEDOUT)
		return -errno;
	return 0;
}

int sky_wait(sky_client *c, uint32_t seen, int timeout_ms, uint32_t *ret_generation)
{
	if (!c)
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	int64_t deadline = timeout_ms < 0 ? -1 : sky_now_ms() + timeout_ms;
	bool replaced = false;
	for (;;) {
		/* Reconnecting, the new region comes with the subscription. */
		if (__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE) && !c->lost) {
			int r = follow_layout(c, deadline);
			if (r < 0)
				return r;
			replaced = true;
		}
		const uint32_t *word = &c->map->generation;
		uint32_t g = __atomic_load_n(word, __ATOMIC_ACQUIRE);
		int64_t wake_ns;
		uint32_t v = visible_generation(c, g, &wake_ns);
		/* A new region is news whatever its number: the superseded
		 * one's last increment took the number it publishes, and a
		 * caller may have read that from its header (views hold their
		 * slot's: pick_slot). */
		if ((v != seen || replaced) && !__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE)) {
			if (ret_generation)
				*ret_generation = v;
			return 0;
		}
		int left = sky_left_ms(deadline);
		if (left == 0)
			return -ETIMEDOUT;
		/* Reconnecting by itself: a hang-up and a new region come on
		 * the socket, which no futex wake announces. */
		if (c->reconnect_ms > 0) {
			const struct sky_shm_header *before = c->map;
			int e = sky_reconnect_step(c);
			if (e < 0)
				return e;
			if (c->map != before || __atomic_load_n(&c->map->generation, __ATOMIC_ACQUIRE) != g)
				continue;
			if (left < 0 || left > c->reconnect_ms)
				left = c->reconnect_ms;
		}
		/* A slot ahead of its apply time wakes nobody when the time
		 * comes: the wait is bounded by that time. */
		int r = futex_sleep(word, g, left, wake_ns);
		if (r < 0)
			return r;
	}
}

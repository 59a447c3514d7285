/* sky_shm.c - libsky's side of the shared memory: mapping the sealed memfd
 * read-only, seqlock views and snapshots of the newest slot, and waiting for
 * a new generation on the futex word (following a layout change). */
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

/* Picks the newest slot and its even sequence; -EAGAIN while it is odd. */
static int pick_slot(const sky_client *c, uint32_t *ret_index, uint32_t *ret_seq,
		     uint32_t *ret_gen)
{
	uint32_t gen = __atomic_load_n(&c->map->generation, __ATOMIC_ACQUIRE);
	uint32_t i = __atomic_load_n(&c->map->current_slot, __ATOMIC_ACQUIRE);
	if (i >= c->map->n_slots)
		return -EPROTO;
	uint32_t s = __atomic_load_n(&slot_at(c, i)->seq, __ATOMIC_ACQUIRE);
	if (s & 1u)
		return -EAGAIN;
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
		int r = pick_slot(c, &i, &seq, &gen);
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
		int r = pick_slot(c, &i, &seq, &gen);
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

int sky_wait(sky_client *c, uint32_t seen, int timeout_ms, uint32_t *ret_generation)
{
	if (!c)
		return -EINVAL;
	if (!c->map)
		return -ENOTCONN;
	int64_t deadline = timeout_ms < 0 ? -1 : sky_now_ms() + timeout_ms;
	for (;;) {
		if (__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE)) {
			int r = follow_layout(c, deadline);
			if (r < 0)
				return r;
		}
		uint32_t *word = (uint32_t *)&c->map->generation;
		uint32_t g = __atomic_load_n(word, __ATOMIC_ACQUIRE);
		if (g != seen && !__atomic_load_n(&c->map->superseded, __ATOMIC_ACQUIRE)) {
			if (ret_generation)
				*ret_generation = g;
			return 0;
		}
		int left = sky_left_ms(deadline);
		if (left == 0)
			return -ETIMEDOUT;
		struct timespec ts = { left / 1000, (long)(left % 1000) * 1000000L };
		/* Shared (not private) futex: the word lives in a shared mapping. */
		long r = syscall(SYS_futex, word, FUTEX_WAIT, seen, left < 0 ? NULL : &ts, NULL, 0);
		if (r < 0 && errno == EINTR)
			return -EINTR;
		if (r < 0 && errno != EAGAIN && errno != ETIMEDOUT)
			return -errno;
	}
}

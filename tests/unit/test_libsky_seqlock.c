/* test_libsky_seqlock.c - libsky's seqlock reads of the stand-in's region
 * (testkit/fake_skyd.h): a rewrite between begin and end is detected, a
 * slot held by the writer gives -EAGAIN without blocking, and under a
 * writer that rewrites flat out every view accepted and every snapshot is
 * whole. */
#include <errno.h>
#include <linux/futex.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/syscall.h>
#include <time.h>

#include "fake_skyd.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"

static struct fake_skyd fake;

/* The writer side of the seqlock, as the daemon does it, but often
 * rewriting the current slot in place so that readers are torn. */
static atomic_bool writer_stop;
static atomic_long writer_rounds;

static void *writer(void *arg)
{
	(void)arg;
	for (long n = 2; !atomic_load(&writer_stop); n++) {
		/* three rounds in four as the daemon does (the next slot, then
		 * publish it); the fourth rewrites the current slot in place */
		uint32_t cur = __atomic_load_n(&fake.shm->current_slot, __ATOMIC_RELAXED);
		if (n % 4)
			cur = (cur + 1) % FAKE_NSLOT;
		struct sky_shm_slot *s = fake_skyd_slot(&fake, cur);
		__atomic_store_n(&s->seq, s->seq + 1, __ATOMIC_RELAXED);
		atomic_thread_fence(memory_order_release);
		fake_skyd_fill_slot(&fake, cur, (double)(n % 16 + 1));
		__atomic_store_n(&s->seq, s->seq + 1, __ATOMIC_RELEASE);
		__atomic_store_n(&fake.shm->current_slot, cur, __ATOMIC_RELEASE);
		__atomic_add_fetch(&fake.shm->generation, 1, __ATOMIC_RELEASE);
		syscall(SYS_futex, &fake.shm->generation, FUTEX_WAKE, INT32_MAX, NULL, NULL, 0);
		atomic_fetch_add(&writer_rounds, 1);
	}
	return NULL;
}

static bool slot_consistent(const struct sky_view *v)
{
	/* every table of a slot was written with the scale in utc_unix_s; check
	 * the first and the last texel of each against it */
	double k = v->slot->state.utc_unix_s;
	static const int chan[4] = { 2, 0, 0, 2 };
	struct skysample_table t = { 0 };
	double first[4], last[4];
	for (uint32_t id = 0; id < 4; id++) {
		skysample_table_from_slot(v->header, v->slot_base, id, &t);
		skysample_texel(&t, 0, 0, 0, first);
		skysample_texel(&t, t.width - 1, t.height - 1, t.depth - 1, last);
		double w0 = id == SKY_TABLE_TRANSMITTANCE ? 0.5 * k : k;
		double w1 = id == SKY_TABLE_TRANSMITTANCE ? 0.5 * k :
			    id == SKY_TABLE_MULTISCATTER ? k :
			    id == SKY_TABLE_SKYVIEW ? k * FAKE_SW : k * FAKE_AH;
		if (first[chan[id]] != w0 || last[chan[id]] != w1)
			return false;
	}
	return true;
}

static void test_consistency(sky_client *c)
{
	/* deterministic: a rewrite between begin and end is detected */
	struct sky_view v;
	CHECK(sky_view_begin(c, &v) == 0);
	struct sky_shm_slot *s = fake_skyd_slot(&fake, v.slot_index);
	s->seq++;
	fake_skyd_fill_slot(&fake, v.slot_index, 3.0);
	s->seq++;
	CHECK(!sky_view_end(c, &v));
	CHECK(sky_view_begin(c, &v) == 0 && sky_view_end(c, &v));
	/* a slot held by the writer: bounded retries, then -EAGAIN, no blocking */
	s->seq++;
	CHECK(sky_view_begin(c, &v) == -EAGAIN);
	size_t n = sky_snapshot_size(c);
	void *buf = aligned_alloc(64, (n + 63) & ~(size_t)63);
	CHECK(sky_snapshot(c, buf, n, &v) == -EAGAIN);
	CHECK(sky_snapshot(c, buf, n - 1, &v) == -ENOBUFS);
	s->seq++;
	CHECK(sky_snapshot(c, buf, n, &v) == 0 && slot_consistent(&v) && sky_view_verify(&v));
	((float *)((char *)buf + fake.shm->tables[1].offset))[5] += 1.0f;
	CHECK(!sky_view_verify(&v));

	/* concurrent: a writer rewrites the current slot flat out; every view
	 * that sky_view_end() accepts and every snapshot must be whole */
	uint32_t g0 = __atomic_load_n(&fake.shm->generation, __ATOMIC_ACQUIRE), g1 = 0;
	pthread_t w;
	atomic_store(&writer_stop, false);
	CHECK(pthread_create(&w, NULL, writer, NULL) == 0);
	CHECK(sky_wait(c, g0, 5000, &g1) == 0 && g1 != g0);
	long accepted = 0, torn = 0, snaps = 0, busy = 0, bad = 0;
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	for (long i = 0;; i++) {
		if (i % 1000 == 0) {
			/* until the writer has published enough, within 10 s */
			clock_gettime(CLOCK_MONOTONIC, &t1);
			if ((i >= 20000 && atomic_load(&writer_rounds) >= 5000) || t1.tv_sec - t0.tv_sec > 10)
				break;
		}
		if (sky_view_begin(c, &v) == 0) {
			bool ok = slot_consistent(&v);
			if (sky_view_end(c, &v)) {
				accepted++;
				bad += !ok;
			} else {
				torn++;
			}
		}
		if (i % 10 == 0) {
			int r = sky_snapshot(c, buf, n, &v);
			if (r == 0) {
				snaps++;
				bad += !slot_consistent(&v) || !sky_view_verify(&v);
			} else {
				busy += r == -EAGAIN;
			}
		}
	}
	atomic_store(&writer_stop, true);
	pthread_join(w, NULL);
	printf("consistency: %ld writer rounds, %ld views accepted, %ld torn views detected, "
	       "%ld snapshots, %ld snapshot gave up, %ld inconsistent\n",
	       atomic_load(&writer_rounds), accepted, torn, snaps, busy, bad);
	CHECK(bad == 0);
	CHECK(accepted > 0 && snaps > 0);
	CHECK(atomic_load(&writer_rounds) >= 5000);
	/* restore the reference contents */
	for (uint32_t k = 0; k < FAKE_NSLOT; k++)
		fake_skyd_fill_slot(&fake, k, 1.0);
	free(buf);
	CHECK(sky_wait(c, __atomic_load_n(&fake.shm->generation, __ATOMIC_ACQUIRE), 0, NULL) ==
	      -ETIMEDOUT);
}

int main(void)
{
	fake_skyd_start(&fake);
	sky_client *c = fake_skyd_client(&fake);
	if (c) {
		test_consistency(c);
		sky_disconnect(c);
	}
	fake_skyd_stop(&fake);
	return test_report("test_libsky_seqlock");
}

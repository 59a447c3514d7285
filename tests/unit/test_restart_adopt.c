/* test_restart_adopt.c - the publisher's side of a restart (pub_adopt):
 * a region made for the fd store is adopted by a second publisher, which
 * writes into the same memory and numbers on; a slot left torn by a writer
 * that died and a slot published ahead are emptied, the current slot stays
 * readable; a region sealed against writes is refused, one of another
 * layout is superseded and its count handed on. No GPU: tables are bytes. */
#include <errno.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "pub.h"
#include "pub_kit.h"
#include "skysample.h"
#include "test.h"

int main(void)
{
	struct sky_state s, other;
	struct pub *a = NULL, *b = NULL, *strict = NULL;
	const void *t1[STATE_N_TABLES], *t2[STATE_N_TABLES];
	uint64_t gen = 0;

	pub_kit_small_state(&s, "skyview_width=8");
	pub_kit_small_state(&other, "skyview_width=16");
	pub_kit_tables(&s, 0x11, t1);
	pub_kit_tables(&s, 0x22, t2);

	/* The first skyd: generations 1..5, the last ahead of its time. */
	CHECK_EQ(pub_new_adoptable(&s, 0, &a), 0);
	if (!a)
		return test_report("test_restart_adopt");
	for (uint64_t g = 1; g <= 4; g++)
		pub_publish(a, &s, STATE_ALL_TABLES, t1, NULL, NULL, g);
	pub_publish_ahead(a, &s, NULL, STATE_ALL_TABLES, t1, NULL, NULL, 5, 1);
	int fd = fcntl(pub_store_fd(a), F_DUPFD_CLOEXEC, 3);
	CHECK(fd >= 0 && fcntl(fd, F_GET_SEALS) == (F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL));
	/* A reader's own mapping, and a client's view of it. */
	size_t bytes = (size_t)pub_bytes(a);
	const struct sky_shm_header *r = mmap(NULL, bytes, PROT_READ, MAP_SHARED, pub_fd(a), 0);
	CHECK(r != MAP_FAILED);
	uint32_t cur = r->current_slot;
	/* It dies while writing the slot after the current one. */
	struct sky_shm_header *w = (struct sky_shm_header *)pub_header(a);
	uint32_t torn = (cur + 1) % (PUB_SLOTS - 1);
	((struct sky_shm_slot *)pub_kit_slot(w, torn))->seq |= 1u;
	pub_free(a);

	/* The next skyd adopts it: torn and spare slots emptied, the current
	 * slot untouched, the count going on above 5. */
	CHECK_EQ(pub_adopt(fd, &s, &b, &gen), 0);
	CHECK_EQ(gen, 5);
	if (!b)
		return test_report("test_restart_adopt");
	CHECK(pub_header(b) != NULL && pub_bytes(b) == bytes);
	CHECK(r->current_slot == cur && pub_kit_slot(r, cur)->generation == 4 &&
	      (pub_kit_slot(r, cur)->seq & 1u) == 0 && pub_kit_slot(r, cur)->valid_tables == STATE_ALL_TABLES);
	CHECK_EQ(skysample_slot_checksum(r, pub_kit_slot(r, cur)), pub_kit_slot(r, cur)->checksum);
	CHECK((pub_kit_slot(r, torn)->seq & 1u) == 0 && pub_kit_slot(r, torn)->valid_tables == 0);
	CHECK_EQ(skysample_slot_checksum(r, pub_kit_slot(r, torn)), pub_kit_slot(r, torn)->checksum);
	CHECK(pub_kit_slot(r, PUB_SLOTS - 1)->apply_time_ns == 0 &&
	      pub_kit_slot(r, PUB_SLOTS - 1)->generation == 0);
	/* It writes into the memory the reader has mapped. */
	pub_publish(b, &s, STATE_ALL_TABLES, t2, NULL, NULL, gen + 1);
	CHECK(r->generation == 6 && r->current_slot != cur);
	const struct sky_shm_slot *n = pub_kit_slot(r, r->current_slot);
	CHECK(n->generation == 6 && (n->seq & 1u) == 0);
	CHECK_EQ(((const uint8_t *)n)[r->tables[STATE_SKYVIEW].offset], 0x22);
	CHECK_EQ(skysample_slot_checksum(r, n), n->checksum);
	CHECK(!r->superseded);

	/* Another layout: refused, superseded, the count handed on. */
	int fd2 = fcntl(pub_store_fd(b), F_DUPFD_CLOEXEC, 3);
	struct pub *c = NULL;
	uint64_t gen2 = 0;
	CHECK(pub_adopt(fd2, &other, &c, &gen2) == -ESTALE && c == NULL);
	CHECK(gen2 == 6 && r->superseded == 1 && r->generation == 7);
	close(fd2);

	/* A region sealed against writes, or no memfd: never adopted. */
	CHECK_EQ(pub_new(&s, 0, &strict), 0);
	int fd3 = fcntl(pub_fd(strict), F_DUPFD_CLOEXEC, 3);
	CHECK_EQ(pub_store_fd(strict), -EPERM);
	CHECK(pub_adopt(fd3, &s, &c, &gen2) == -EPERM && c == NULL);
	close(fd3);
	int p[2];
	CHECK(pipe(p) == 0 && pub_adopt(p[0], &s, &c, &gen2) < 0 && c == NULL);
	close(p[0]);
	close(p[1]);

	munmap((void *)r, bytes);
	pub_free(b);
	pub_free(strict);
	pub_kit_tables_free(t1);
	pub_kit_tables_free(t2);
	return test_report("test_restart_adopt");
}

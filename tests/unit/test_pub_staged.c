/* test_pub_staged.c - a generation published ahead of its apply time goes
 * into the spare slot and, not current, into the next slot of the ring;
 * at the apply time pub_publish_staged makes that slot current without a
 * copy. A slot written or claimed since is no longer the staged one. No
 * GPU: tables are bytes. */
#include <errno.h>

#include "pub.h"
#include "pub_kit.h"
#include "skysample.h"
#include "test.h"

/* The current slot holds generation g, whole, with skyview bytes fill. */
static void check_current(const struct sky_shm_header *h, uint32_t g, int fill)
{
	const struct sky_shm_slot *c = pub_kit_slot(h, h->current_slot);
	CHECK_EQ(h->generation, g);
	CHECK_EQ(c->generation, g);
	CHECK_EQ(c->seq & 1u, 0);
	CHECK_EQ(((const uint8_t *)c)[h->tables[STATE_SKYVIEW].offset], fill);
	CHECK_EQ(skysample_slot_checksum(h, c), c->checksum);
}

int main(void)
{
	struct sky_state s;
	struct pub *p = NULL;
	struct eng_target target;
	const void *t1[STATE_N_TABLES], *t2[STATE_N_TABLES];

	pub_kit_small_state(&s, "skyview_width=8");
	pub_kit_tables(&s, 0x11, t1);
	pub_kit_tables(&s, 0x22, t2);
	CHECK_EQ(pub_new(&s, 0, &p), 0);
	if (!p)
		return test_report("test_pub_staged");
	const struct sky_shm_header *h = pub_header(p);

	pub_publish(p, &s, STATE_ALL_TABLES, t1, NULL, NULL, 1);
	pub_publish(p, &s, STATE_ALL_TABLES, t1, NULL, NULL, 2);
	uint32_t cur = h->current_slot;

	/* Ahead: the spare slot and the next one hold 3, the current stays 2. */
	pub_publish_ahead(p, &s, NULL, STATE_ALL_TABLES, t2, NULL, NULL, 3, 1000);
	check_current(h, 2, 0x11);
	CHECK_EQ(h->current_slot, cur);
	CHECK_EQ(pub_kit_slot(h, h->n_slots - 1)->generation, 3);
	CHECK_EQ(pub_kit_slot(h, h->n_slots - 1)->apply_time_ns, 1000);
	CHECK_EQ(pub_publish_staged(p, 4), -ESTALE);
	CHECK_EQ(pub_publish_staged(p, 3), 0);
	check_current(h, 3, 0x22);
	CHECK(h->current_slot != cur && h->current_slot != h->n_slots - 1);
	CHECK_EQ(pub_kit_slot(h, h->current_slot)->apply_time_ns, 1000);
	CHECK_EQ(pub_publish_staged(p, 3), -ESTALE);

	/* Overwritten before its time: the next publication is current, the
	 * staged generation is gone. */
	pub_publish_ahead(p, &s, NULL, STATE_ALL_TABLES, t1, NULL, NULL, 4, 2000);
	pub_publish(p, &s, STATE_ALL_TABLES, t2, NULL, NULL, 5);
	CHECK_EQ(pub_publish_staged(p, 4), -ESTALE);
	check_current(h, 5, 0x22);

	/* Claimed for the device since: not staged either. */
	pub_publish_ahead(p, &s, NULL, STATE_ALL_TABLES, t1, NULL, NULL, 6, 3000);
	CHECK_EQ(pub_claim(p, &s, NULL, STATE_ALL_TABLES, &target), 0);
	CHECK_EQ(pub_publish_staged(p, 6), -ESTALE);
	check_current(h, 5, 0x22);

	pub_free(p);
	pub_kit_tables_free(t1);
	pub_kit_tables_free(t2);
	return test_report("test_pub_staged");
}

/* pub_kit.h - what the publisher's unit tests share: a state with small
 * tables, tables of its layout filled with one byte, and a slot of a
 * region by its index. No GPU: tables are bytes. */
#ifndef SKYD_PUB_KIT_H
#define SKYD_PUB_KIT_H

#include <stdlib.h>
#include <string.h>

#include "skyproto.h"
#include "state.h"
#include "test.h"

static inline void pub_kit_set(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0)
		FAIL("%s", err);
}

/* The default state with every table a few texels, sky-view skyview_width
 * ("skyview_width=N") wide. */
static inline void pub_kit_small_state(struct sky_state *s, const char *skyview_width)
{
	static const char *const small[] = { "transmittance_width=8", "transmittance_height=4",
		"multiscatter_width=8", "multiscatter_height=4", "skyview_height=4",
		"aerial_width=8", "aerial_height=4", "aerial_depth=2" };
	state_default(s);
	for (size_t i = 0; i < sizeof(small) / sizeof(small[0]); i++)
		pub_kit_set(s, small[i]);
	pub_kit_set(s, skyview_width);
}

/* Tables of the layout of s, every byte fill (the aerial table with room
 * for a view's volume after it). */
static inline void pub_kit_tables(const struct sky_state *s, int fill, const void *ret[STATE_N_TABLES])
{
	for (int t = 0; t < STATE_N_TABLES; t++) {
		size_t n = state_table_bytes(s, (enum state_table)t) * (t == STATE_AERIAL ? 2 : 1);
		void *b = malloc(n);
		memset(b, fill, n);
		ret[t] = b;
	}
}

static inline void pub_kit_tables_free(const void *t[STATE_N_TABLES])
{
	for (int i = 0; i < STATE_N_TABLES; i++)
		free((void *)t[i]);
}

static inline const struct sky_shm_slot *pub_kit_slot(const struct sky_shm_header *h, uint32_t i)
{
	return (const struct sky_shm_slot *)((const uint8_t *)h + h->header_bytes +
					     (uint64_t)i * h->slot_bytes);
}

#endif

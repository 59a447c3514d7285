/* pub.h - the publisher: the tables and the state that produced them, in a
 * sealed memfd that any number of clients map read-only (proto/skyproto.h).
 *
 * One pub is one layout (table sizes and storage). It is created, mapped
 * writable by the daemon, then sealed SHRINK | GROW | FUTURE_WRITE | SEAL,
 * so no client can map it writable, write it or resize it. Publication is a
 * seqlock per slot: a reader never blocks the writer and the writer never
 * waits for a reader. The slots rotate over n_slots - 1; the last slot is
 * kept for changes computed ahead of their apply time (pub_publish_ahead).
 *
 * Adoption (restart without losing clients): a sealed region cannot be
 * mapped writable again, so pub_adopt() reads an existing region (from the
 * fd store), checks it and returns its newest generation; the daemon then
 * publishes the next generation in a new region and supersedes the old one
 * only if it still holds a writable mapping.
 */
#ifndef SKYD_PUB_H
#define SKYD_PUB_H

#include <stdint.h>

#include "skyproto.h"
#include "state.h"

#define PUB_SLOTS 4u

struct pub;

/* Creates a region for the layout of s (sizes, storage), no slot valid,
 * header generation set to generation (so that it continues a count). */
int pub_new(const struct sky_state *s, uint64_t generation, struct pub **ret);
void pub_free(struct pub *p);

/* The sealed memfd as clients get it, opened read-only; owned by pub, dup
 * it to keep it. */
int pub_fd(const struct pub *p);
uint64_t pub_bytes(const struct pub *p);
/* 1 if s has the layout of p (same table shapes and storage). */
int pub_same_layout(const struct pub *p, const struct sky_state *s);

/* Writes s and the tables in valid (pointers per enum state_table, each of
 * the layout's size) into the next slot and makes it current as generation,
 * with each valid table's RGB scale, log2 (eng_table_scale_log2: 0 for
 * float32; NULL: all 0) in the slot's state. Wakes futex waiters. Never
 * blocks; costs one copy of the valid tables. */
void pub_publish(struct pub *p, const struct sky_state *s, uint32_t valid,
		 const void *const tables[STATE_N_TABLES],
		 const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation);

/* pub_publish for a generation that became current at apply_time_ns
 * (CLOCK_REALTIME, passed or now; 0: now): the slot keeps the instant. */
void pub_publish_at(struct pub *p, const struct sky_state *s, uint32_t valid,
		    const void *const tables[STATE_N_TABLES],
		    const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		    int64_t apply_time_ns);

/* Writes a generation computed ahead of its apply time (CLOCK_REALTIME,
 * > 0) into the spare slot (PUB_SLOTS - 1) without making it current:
 * libsky hands it to clients from apply_time_ns on, while readers that
 * ignore apply times keep the current slot until the daemon publishes the
 * same generation with pub_publish_at at that instant. Wakes futex waiters
 * (the word unchanged) so that they sleep until the apply time instead.
 * Overwrites an earlier slot ahead. */
void pub_publish_ahead(struct pub *p, const struct sky_state *s, uint32_t valid,
		       const void *const tables[STATE_N_TABLES],
		       const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		       int64_t apply_time_ns);

/* Marks the region superseded (a new layout replaces it) and wakes waiters. */
void pub_supersede(struct pub *p);

/* The daemon's own view of the header and the current slot; valid until the
 * next pub_publish or pub_free. ret_base (may be NULL) gets the slot's first
 * byte, the base of the table offsets. */
const struct sky_shm_header *pub_header(const struct pub *p);
const struct sky_shm_slot *pub_current(const struct pub *p, const uint8_t **ret_base);

/* The slot checksum of proto/PROTOCOL.md for a slot whose tables start at base. */
uint64_t pub_checksum(const struct sky_shm_header *h, const struct sky_shm_slot *slot,
		      const uint8_t *base);

/* Converts the daemon's state into the published form. */
void pub_shm_state(const struct sky_state *s, struct sky_shm_state *ret);

/* Checks an existing sealed region (magic, versions, sizes, seals) and
 * returns its newest generation. Does not take fd. */
int pub_adopt_check(int fd, uint64_t *ret_generation);

#endif

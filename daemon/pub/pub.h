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
 * Adoption (restart without losing clients, docs/restart.md): a region made
 * by pub_new_adoptable() is sealed SHRINK | GROW | SEAL only, so that the
 * read-write fd kept in systemd's fd store (pub_store_fd) lets the next
 * skyd map it writable again (pub_adopt) and go on publishing in the very
 * memory the clients have mapped. Clients still get the read-only file of
 * mode 0444: they can neither map it writable nor write or resize it, nor
 * reopen it read-write unless they run as skyd's user or as root.
 */
#ifndef SKYD_PUB_H
#define SKYD_PUB_H

#include <stdint.h>

#include "eng.h"
#include "skyproto.h"
#include "state.h"

#define PUB_SLOTS 4u

struct pub;

/* Creates a region for the layout of s (sizes, storage), no slot valid,
 * header generation set to generation (so that it continues a count). */
int pub_new(const struct sky_state *s, uint64_t generation, struct pub **ret);
/* pub_new for a region that outlives this skyd in systemd's fd store
 * (pub_store_fd): not sealed against future writes (see above). */
int pub_new_adoptable(const struct sky_state *s, uint64_t generation, struct pub **ret);
/* pub_new sealed as like is (a new layout replacing like). */
int pub_new_like(const struct pub *like, const struct sky_state *s, uint64_t generation,
		 struct pub **ret);
void pub_free(struct pub *p);

/* The sealed memfd as clients get it, opened read-only; owned by pub, dup
 * it to keep it. */
int pub_fd(const struct pub *p);
uint64_t pub_bytes(const struct pub *p);
/* The daemon's writable mapping, pub_bytes long, page-aligned: what the
 * engine imports to write the tables itself (eng_host_import). Valid until
 * pub_free. */
void *pub_map(const struct pub *p);
/* 1 if s has the layout of p (same table shapes and storage). */
int pub_same_layout(const struct pub *p, const struct sky_state *s);

/* Claims the next slot for the device to write the tables of s into
 * itself: marks it being written (its sequence odd, so that a reader still
 * in it from an earlier generation retries) and fills ret with where each
 * table, view volume and panorama of s goes, from pub_map (eng_target;
 * tables: those the slot will hold). The slot is not current and stays
 * claimed until a publication writes it: pub_publish_claimed once the
 * device has written it, or any other pub_publish_at, which writes the
 * tables itself. -EINVAL when s has another layout. */
int pub_claim(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
	      uint32_t tables, struct eng_target *ret);
/* pub_publish_at for the claimed slot whose tables the device wrote where
 * pub_claim said: the state, the views' directory and the checksum are
 * written, nothing is copied. */
void pub_publish_claimed(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
			 uint32_t valid, const int32_t rgb_scale_log2[STATE_N_TABLES],
			 uint64_t generation, int64_t apply_time_ns);

/* Writes s and the tables in valid (pointers per enum state_table, each of
 * the layout's size; the aerial table followed by the views' volumes, and
 * panoramas the published panoramas, as eng_table and eng_panoramas give
 * them, NULL without) into the next slot and makes it current as generation,
 * with each valid table's RGB scale, log2 (eng_table_scale_log2: 0 for
 * float32; NULL: all 0) in the slot's state. Wakes futex waiters. Never
 * blocks; costs one copy of the valid tables. */
void pub_publish(struct pub *p, const struct sky_state *s, uint32_t valid,
		 const void *const tables[STATE_N_TABLES], const void *panoramas,
		 const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation);

/* pub_publish for a generation that became current at apply_time_ns
 * (CLOCK_REALTIME, passed or now; 0: now): the slot keeps the instant.
 * lights: s's as its tables were lit (state_lights_of), for the slot's
 * directions and its views' plan; NULL computes them. */
void pub_publish_at(struct pub *p, const struct sky_state *s, const struct state_lights *lights,
		    uint32_t valid,
		    const void *const tables[STATE_N_TABLES], const void *panoramas,
		    const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		    int64_t apply_time_ns);

/* Writes a generation computed ahead of its apply time (CLOCK_REALTIME,
 * > 0) into the spare slot (PUB_SLOTS - 1) without making it current:
 * libsky hands it to clients from apply_time_ns on, while readers that
 * ignore apply times keep the current slot until the daemon makes the
 * same generation current at that instant (pub_publish_staged). Writes
 * it into the next slot as well, not current, so that the instant costs
 * no copy. Wakes futex waiters (the word unchanged) so that they sleep
 * until the apply time instead. Overwrites an earlier slot ahead. lights
 * as pub_publish_at's. */
void pub_publish_ahead(struct pub *p, const struct sky_state *s,
		       const struct state_lights *lights, uint32_t valid,
		       const void *const tables[STATE_N_TABLES], const void *panoramas,
		       const int32_t rgb_scale_log2[STATE_N_TABLES], uint64_t generation,
		       int64_t apply_time_ns);

/* Makes the next slot, which pub_publish_ahead wrote with generation,
 * current, and wakes waiters: no copy. -ESTALE when the next slot no
 * longer holds it (written or claimed since); then pub_publish_at. */
int pub_publish_staged(struct pub *p, uint64_t generation);

/* The cloud tables (eng_cloud_table: the coverage table and the shadow
 * maps, each the layout's size) that the next publications copy into
 * their slots where the state draws a layer and valid names them; NULL:
 * none. The pointers must stay valid until the next call. */
void pub_set_cloud_tables(struct pub *p, const void *coverage, const void *shadow);

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

/* Converts the daemon's state, lit by lights, into the published form. */
void pub_shm_state(const struct sky_state *s, const struct state_lights *lights,
		   struct sky_shm_state *ret);

/* The read-write fd of an adoptable region, for systemd's fd store (owned
 * by pub: dup it to keep it); -EPERM for a region sealed against writes. */
int pub_store_fd(const struct pub *p);

/* Takes over a region a previous skyd published (fd from the fd store, a
 * pub_store_fd), when its seals, size and header (magic, layout and uv
 * mapping versions, n_slots, every table's shape and offset, the slots'
 * size and room for the views of s) are those a region made for s now
 * would have: the new pub publishes into the same memory, so a reader keeps
 * its mapping and sees at most a pause. Slots left torn by a writer that
 * died, and the spare slot, are emptied; the current slot stays readable.
 * Returns 0 (fd taken) with *ret_generation the newest generation the
 * region showed: publish above it. Errors (fd not taken): -EPERM (sealed
 * against writes, or not sealed enough), -EPROTO (not a region of this
 * version), -ESTALE (another layout, or superseded: the region was marked
 * superseded so that its readers look for a new one, and *ret_generation
 * is still set, to continue the count), -errno. */
int pub_adopt(int fd, const struct sky_state *s, struct pub **ret, uint64_t *ret_generation);

#endif

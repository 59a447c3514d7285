/* fdstore.h - restart without losing clients: skyd keeps its shared memory
 * (FDNAME=shm) and the listening socket it made (FDNAME=control) in
 * systemd's file-descriptor store, and a restarted skyd takes them back
 * (LISTEN_FDS, LISTEN_FDNAMES): the same memory goes on with the next
 * generation, so a client's mapping stays (docs/restart.md).
 *
 * The store is used when NOTIFY_SOCKET is set and $FDSTORE (set by
 * systemd 254 and later from FileDescriptorStoreMax=; the unit sets it on
 * older systemd) is a positive number. Without it skyd makes its regions
 * as always (sealed against every write) and hands nothing over.
 */
#ifndef SKYD_FDSTORE_H
#define SKYD_FDSTORE_H

#include <stdbool.h>
#include <stdint.h>

#include "state.h"

struct fdstore;
struct pub;

/* Takes the fds systemd passed (sd_listen_fds_with_names: those named
 * shm and control, and the rest, socket activation's) and unsets the
 * LISTEN_* variables. 0 or -ENOMEM. */
int fdstore_new(struct fdstore **ret);
/* Closes the fds nobody took. NULL is a no-op. */
void fdstore_free(struct fdstore *f);

/* True when skyd hands its fds to the store. */
bool fdstore_enabled(const struct fdstore *f);

/* The region to publish into, for the initial state s: the stored shm
 * adopted (pub_adopt) when it fits s, else, with the store enabled, a new
 * adoptable region (continuing the count of a stale stored one, whose
 * readers remap), else NULL (srv_new makes its own). *ret_generation: the
 * generation to continue from (0: none). Says in the log which it was.
 * 0 or -errno (a new region could not be made). */
int fdstore_region(struct fdstore *f, const struct sky_state *s, struct pub **ret_pub,
		   uint64_t *ret_generation);

/* The stored control socket when it is a listening stream socket bound to
 * path (taken by the caller), else -1 (closed: it is stale). */
int fdstore_control(struct fdstore *f, const char *path);
/* The first fd of socket activation (neither shm nor control), taken by
 * the caller; -1 when there is none. */
int fdstore_activated(struct fdstore *f);

/* Hands the region's fd (pub_store_fd) and listen_fd (-1: none, as under
 * socket activation, whose socket systemd keeps anyway) to the store, in
 * place of what an earlier skyd stored under those names. Call it once
 * both exist, before READY=1. 0 or -errno (logged; skyd runs on, a restart
 * then loses the clients' mappings). */
int fdstore_hand_over(struct fdstore *f, const struct pub *p, int listen_fd);
/* A new layout replaced the region: the store gets p's fd instead. */
void fdstore_replaced(struct fdstore *f, const struct pub *p);

#endif

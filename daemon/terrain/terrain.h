/* terrain.h - a terrain height field read from a file: a 16-bit (or 8-bit)
 * greyscale PNG or a SKYTERRAIN16 raw file (docs/terrain.md), bounded,
 * checked, hashed, and kept immutable for the shadow pass and the path
 * tracer, which read its heights through proto/skyterrain.h.
 *
 * Reading is synchronous: skyd does it on its event loop when a `set
 * terrain=` arrives. What bounds it is the file: a regular local file
 * (a FIFO or a device is refused without reading it) of at most
 * TERRAIN_FILE_MAX_BYTES, SKYTERRAIN_MAX_TEXELS texels a side, checked
 * before anything is decoded. Network file systems that stall are the
 * administrator's to avoid.
 *
 * A loaded field is shared and counted: terrain_ref / terrain_unref; it
 * never changes once loaded, so any thread may read it. The functions are
 * thread-safe.
 */
#ifndef SKYD_TERRAIN_H
#define SKYD_TERRAIN_H

#include <stddef.h>
#include <stdint.h>

#include "skyterrain.h"

/* The largest file read: a 4096 x 4096 16-bit field is 32 MiB of texels;
 * a PNG of it, incompressible, holds a filter byte per row and zlib's and
 * the chunks' few bytes more, well under this. */
#define TERRAIN_FILE_MAX_BYTES (40u << 20)
/* The raw format's first line: "SKYTERRAIN16 <width> <height>\n", then
 * width x height little-endian unsigned 16-bit texels, north row first,
 * each row west to east, and nothing after them. */
#define TERRAIN_RAW_MAGIC "SKYTERRAIN16"
/* A path's longest text, the terminating NUL included. */
#define TERRAIN_PATH_MAX 128

struct terrain;

/* Reads the height field at path (absolute, printable ASCII, shorter than
 * TERRAIN_PATH_MAX). Returns 0 with *ret (one reference), or with err
 * saying why, naming the file:
 *   -EINVAL  not an absolute path, unreadable (the system's reason), not
 *            a regular file, neither a PNG nor a SKYTERRAIN16 file, a
 *            colour PNG, not square, truncated or corrupt;
 *   -EFBIG   larger than TERRAIN_FILE_MAX_BYTES or SKYTERRAIN_MAX_TEXELS a
 *            side;
 *   -ENOMEM.
 * The last field read is kept (one entry): the same path whose file has
 * the same device, inode, size and modification time is not read again,
 * so that states that name it again (a replicated message, a config
 * reload) cost a stat. */
int terrain_load(const char *path, struct terrain **ret, char *err, size_t err_size);

/* Another reference to t; t. */
struct terrain *terrain_ref(struct terrain *t);
/* Drops one reference; frees t with the last. NULL is fine. */
void terrain_unref(struct terrain *t);

/* What was read: size in texels, the largest texel, and the content
 * hash: FNV-1a 64 over the width, the height and the texels as 16-bit
 * words (little-endian bytes), so that the same heights give the same
 * hash from a PNG or a raw file on any host. */
uint32_t terrain_width(const struct terrain *t);
uint32_t terrain_height(const struct terrain *t);
uint64_t terrain_hash(const struct terrain *t);
/* The texels, row-major, north row first; valid while a reference is held. */
const uint16_t *terrain_texels(const struct terrain *t);

/* The view proto/skyterrain.h takes of t over a square of side extent_km
 * whose white stands for height_km; valid while a reference is held. */
void terrain_view(const struct terrain *t, double extent_km, double height_km,
		  struct skyterrain *ret);

/* The hash of width x height texels, as terrain_hash computes it. */
uint64_t terrain_hash_texels(const uint16_t *texels, uint32_t width, uint32_t height);

#endif

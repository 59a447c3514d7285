/* fuzz_shm.c - libFuzzer target for the shared memory as a client reads
 * it (client/sky_shm.c, proto/skysample.h): the input is the region skyd
 * would pass, header first, mapped through a sealed memfd as libsky maps
 * what it receives; a header that says the region is longer than the
 * input gets zeros up to its total_bytes (at most 4 MiB), so that a small
 * input can stand for a whole region. A region that maps is then read as
 * an application reads it: a view and a snapshot, the checksum, and every
 * sampling function on the state's camera and on each view the slot
 * names. Built without libFuzzer, a main() replays the files named on the
 * command line (fuzz_replay.h). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <fcntl.h>
#include <unistd.h>

#include "sky_internal.h"

#define FUZZ_SHM_MAX_BYTES (4u << 20)

static volatile double sink;

static void add(const double *v, int n)
{
	for (int i = 0; i < n; i++)
		sink += v[i];
}

/* Every reading an application makes of a view; names come from the slot
 * (cut to their bound here: the names a client asks for are its own). */
static void read_view(const struct sky_view *v)
{
	static const double dirs[][2] = { { 90, 0 }, { 30, 180 }, { 0, 90 }, { -10, 270 } };
	static const struct sky_render_params rp[] = {
		{ SKY_PROJECTION_EQUIRECT, 4, 2, 0, 0, 0, 60, SKY_SAMPLE_SUN_DISK },
		{ SKY_PROJECTION_PERSPECTIVE, 3, 2, 180, 10, 5, 60, SKY_SAMPLE_MOON_DISK },
		{ SKY_PROJECTION_FISHEYE, 3, 3, 90, 0, 0, 60, SKY_SAMPLE_LIMB_DARKENING | 1 },
	};
	double rgb[3], t = 0, scale;
	float img[4 * 3 * 3];
	const void *texels;
	size_t bytes;
	char name[SKY_SHM_VIEW_NAME_MAX];

	sink += sky_view_verify(v);
	sky_sample_transmittance(v, 1.0, 0.5, rgb);
	add(rgb, 3);
	for (size_t i = 0; i < sizeof(dirs) / sizeof(dirs[0]); i++)
		if (sky_sample_sky(v, dirs[i][0], dirs[i][1], 7, rgb) == 0)
			add(rgb, 3);
	if (sky_sample_aerial(v, 0.5, 0.5, 10.0, rgb, &t) == 0)
		add(rgb, 3);
	if (sky_sample_sun(v, rgb) == 0)
		add(rgb, 3);
	if (sky_sample_ambient(v, rgb) == 0)
		add(rgb, 3);
	for (uint32_t id = 0; id <= SKY_SHM_MAX_TABLES; id++)
		if (sky_table_scale(v, id, &scale) == 0)
			sink += scale;
	for (size_t i = 0; i < sizeof(rp) / sizeof(rp[0]); i++)
		if (sky_render(v, &rp[i], img) == 0)
			sink += img[0];
	uint32_t n = v->slot->n_views < SKY_SHM_MAX_VIEWS ? v->slot->n_views : SKY_SHM_MAX_VIEWS;
	for (uint32_t i = 0; i <= n; i++) {
		/* One past the slot's own: a name that is not there. */
		if (i < n)
			memcpy(name, v->slot->views[i].name, sizeof(name));
		else
			memcpy(name, "absent", 7);
		name[sizeof(name) - 1] = 0;
		const double dir[3] = { 0.3, 0.9, 0.1 };
		if (sky_sample_view_aerial(v, name, 0.25, 0.75, 5.0, rgb, &t) == 0)
			add(rgb, 3);
		if (sky_sample_view_aerial_dir(v, name, dir, 5.0, rgb, &t) == 0)
			add(rgb, 3);
		if (sky_view_aerial_table(v, name, &texels, &bytes) == 0 && bytes)
			sink += ((const unsigned char *)texels)[bytes - 1];
	}
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct sky_shm_header h;
	size_t bytes = size;
	int fd = memfd_create("fuzz_shm", MFD_CLOEXEC | MFD_ALLOW_SEALING);

	if (fd < 0 || write(fd, data, size) != (ssize_t)size)
		abort();
	if (size >= sizeof(h)) {
		memcpy(&h, data, sizeof(h));
		if (h.total_bytes > size && h.total_bytes <= FUZZ_SHM_MAX_BYTES)
			bytes = (size_t)h.total_bytes;
	}
	/* As skyd seals the regions it sends. */
	if (ftruncate(fd, (off_t)bytes) < 0 ||
	    fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_WRITE | F_SEAL_SEAL) < 0)
		abort();
	sky_client *c = sky_client_alloc();
	if (!c)
		abort();
	if (sky_map_memfd(c, fd) == 0) {
		struct sky_view v;
		if (sky_view_begin(c, &v) == 0) {
			read_view(&v);
			sink += sky_view_end(c, &v);
		}
		size_t n = sky_snapshot_size(c);
		void *buf = n <= FUZZ_SHM_MAX_BYTES ? aligned_alloc(8, (n + 7) & ~(size_t)7) : NULL;
		if (buf && sky_snapshot(c, buf, n, &v) == 0)
			read_view(&v);
		free(buf);
	}
	sky_disconnect(c);
	return 0;
}

#include "fuzz_replay.h"

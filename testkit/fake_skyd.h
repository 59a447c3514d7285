/* fake_skyd.h - a stand-in for skyd in the test's own process, for the tests
 * of libsky that need no Vulkan device: a hand-built shared-memory region
 * that follows proto/skyproto.h, its tables filled with values a test can
 * predict, served on a private socket by a thread that answers the few
 * requests libsky's tests make. Header-only.
 *
 * The tables of a slot filled with scale k (fake_skyd_fill_slot):
 *   transmittance  (k e^(-0.1 / (mu + 1.1)), k e^(-alt / 100), k / 2, 1)
 *                  at each texel's (altitude, mu), float32
 *   multiscatter   k everywhere, float32
 *   sky-view       (k (i + 1), k (j + 1), k (i + SW j), 1) at column i,
 *                  row j, binary16 (integers, exact at k = 1)
 *   aerial         (k (s + 1), k (i + 1), k (j + 1), 1 - 0.1 (s + 1)) at
 *                  column i, row j, slice s, float32
 * and the slot state's utc_unix_s holds k. Every slot starts at k = 1,
 * generation 1, slot 1 current; the sun at 30 deg elevation, azimuth 120.
 *
 * Requests the stand-in answers, one connection at a time: subscribe (the
 * region's fd), ping, get (two keys), emit (a changed event after its
 * reply), supersede (see fake_skyd_supersede), drop (hangs up), shutdown
 * (hangs up and stops serving); anything else gets ACK [5]. */
#ifndef SKYD_FAKE_SKYD_H
#define SKYD_FAKE_SKYD_H

#include <errno.h>
#include <fcntl.h>
#include <linux/futex.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/un.h>
#include <unistd.h>

#include "sky.h"
#include "skycloud.h"
#include "skysample.h"
#include "test.h"

/* The tables' sizes: transmittance, multiscatter, sky-view, aerial (depth
 * FAKE_AD), and the number of slots. */
enum {
	FAKE_TW = 16, FAKE_TH = 8,
	FAKE_MW = 4, FAKE_MH = 4,
	FAKE_SW = 24, FAKE_SH = 16,
	FAKE_AW = 8, FAKE_AH = 6, FAKE_AD = 5,
	FAKE_NSLOT = 3,
};

#define FAKE_DEG (SKYMAP_PI / 180.0)

struct fake_skyd {
	struct sky_shm_header *shm;	/* the region, mapped writable */
	size_t shm_bytes;
	int shm_fd;			/* sealed against resizing and new writable maps */
	char sock_dir[64], sock_path[128];
	int listen_fd;
	atomic_int connections;		/* accepted so far */
	/* The supersede request's second half waits for a byte here. */
	int layout_go[2];
	uint32_t superseded_generation;
	pthread_t thread;
};

static inline struct sky_shm_slot *fake_skyd_slot(struct fake_skyd *f, uint32_t i)
{
	return (struct sky_shm_slot *)((char *)f->shm + f->shm->header_bytes + i * f->shm->slot_bytes);
}

static inline void *fake_skyd_table(struct fake_skyd *f, uint32_t slot, uint32_t id)
{
	return (char *)fake_skyd_slot(f, slot) + f->shm->tables[id].offset;
}

/* binary16 of a value that is exactly representable as a normal half. */
static inline uint16_t fake_skyd_half(double x)
{
	if (x == 0.0)
		return 0;
	int e;
	double m = frexp(fabs(x), &e);	/* x = m 2^e, m in [0.5, 1) */
	uint16_t bits = (uint16_t)(((e - 1 + 15) << 10) | ((uint16_t)(m * 2048.0) & 0x3ff));
	return x < 0 ? bits | 0x8000 : bits;
}

static inline uint64_t fake_skyd_align64(uint64_t x)
{
	return (x + 63) & ~(uint64_t)63;
}

/* The stand-in's cloud field: one stratocumulus layer, as skyd would
 * publish it without its tables (FAKE_CLOUD_* for a test to rebuild it). */
#define FAKE_CLOUD_COVER 0.8
#define FAKE_CLOUD_BASE_KM 1.0
#define FAKE_CLOUD_TOP_KM 1.4
#define FAKE_CLOUD_SEED 5u
static const float fake_cloud_offset_km[2] = { 10.0f, 20.0f };
static inline void fake_skyd_clouds(struct sky_shm_clouds *c)
{
	struct skycloud_layer L;
	memset(c, 0, sizeof(*c));
	skycloud_layer_init(&L, SKYCLOUD_STRATOCUMULUS, FAKE_CLOUD_COVER, FAKE_CLOUD_BASE_KM, FAKE_CLOUD_TOP_KM,
			    FAKE_CLOUD_SEED, 0u);
	c->n_layers = 1;
	memcpy(&c->layers[0], &L, sizeof(L));
	c->layers[0].phase_g = (float)skycloud_types[SKYCLOUD_STRATOCUMULUS].phase_g;
	c->layers[0].albedo = (float)skycloud_types[SKYCLOUD_STRATOCUMULUS].albedo;
	c->extent_km = 50.0;
	c->offset_km[0] = fake_cloud_offset_km[0];
	c->offset_km[1] = fake_cloud_offset_km[1];
	c->period_km = SKYCLOUD_PERIOD_KM;
	c->placed_utc_s = NAN;
	c->sun_transmittance = c->moon_transmittance = 1.0;
}

/* Writes slot s's state and tables with scale k, as the header says, and
 * its checksum; the seqlock is the caller's. */
static inline void fake_skyd_fill_slot(struct fake_skyd *f, uint32_t s, double scale)
{
	struct sky_shm_slot *sl = fake_skyd_slot(f, s);
	struct sky_shm_state *st = &sl->state;
	memset(st, 0, sizeof(*st));
	st->bottom_radius_km = 6360.0;
	st->top_radius_km = 6460.0;
	st->altitude_km = 0.2;
	skysample_direction(30.0 * FAKE_DEG, 120.0 * FAKE_DEG, st->sun_direction);
	for (int c = 0; c < 3; c++)
		st->sun_illuminance_lx[c] = 1.0e5 * (c + 1);
	st->sun_angular_radius_rad = 3.0 * FAKE_DEG;
	skysample_direction(-20.0 * FAKE_DEG, 300.0 * FAKE_DEG, st->moon_direction);
	st->moon_angular_radius_rad = 0.26 * FAKE_DEG;
	st->aerial_range_km = 32.0;
	st->aerial_squared = 1;
	st->utc_unix_s = scale;
	fake_skyd_clouds(&sl->clouds);
	/* transmittance: a smooth function of the (altitude, mu) of each texel */
	float *t = fake_skyd_table(f, s, SKY_TABLE_TRANSMITTANCE);
	for (int j = 0; j < FAKE_TH; j++)
		for (int i = 0; i < FAKE_TW; i++) {
			double alt, mu;
			skymap_transmittance_inverse(6360.0, 6460.0, (i + 0.5) / FAKE_TW, (j + 0.5) / FAKE_TH,
						     FAKE_TW, FAKE_TH, &alt, &mu);
			float *p = t + (j * FAKE_TW + i) * 4;
			p[0] = (float)(scale * exp(-0.1 / (mu + 1.1)));
			p[1] = (float)(scale * exp(-alt / 100.0));
			p[2] = (float)(scale * 0.5);
			p[3] = 1.0f;
		}
	float *m = fake_skyd_table(f, s, SKY_TABLE_MULTISCATTER);
	for (int i = 0; i < FAKE_MW * FAKE_MH * 4; i++)
		m[i] = (float)scale;
	/* sky-view in f16: integers, exact in binary16 */
	uint16_t *v = fake_skyd_table(f, s, SKY_TABLE_SKYVIEW);
	for (int j = 0; j < FAKE_SH; j++)
		for (int i = 0; i < FAKE_SW; i++) {
			uint16_t *p = v + (j * FAKE_SW + i) * 4;
			p[0] = fake_skyd_half(scale * (i + 1));
			p[1] = fake_skyd_half(scale * (j + 1));
			p[2] = fake_skyd_half(scale * (i + FAKE_SW * j));
			p[3] = fake_skyd_half(1.0);
		}
	float *a = fake_skyd_table(f, s, SKY_TABLE_AERIAL);
	for (int k = 0; k < FAKE_AD; k++)
		for (int j = 0; j < FAKE_AH; j++)
			for (int i = 0; i < FAKE_AW; i++) {
				float *p = a + ((k * FAKE_AH + j) * FAKE_AW + i) * 4;
				p[0] = (float)(scale * (k + 1));
				p[1] = (float)(scale * (i + 1));
				p[2] = (float)(scale * (j + 1));
				p[3] = (float)(1.0 - 0.1 * (k + 1));
			}
	sl->valid_tables = SKY_TABLES_ALL;
	sl->checksum = skysample_slot_checksum(f->shm, sl);
}

/* A fresh region in f->shm and f->shm_fd (the previous one is left as it
 * was: a client may still map it). */
static inline void fake_skyd_build_region(struct fake_skyd *f)
{
	struct sky_shm_table tabs[4] = {
		{ SKY_TABLE_TRANSMITTANCE, SKY_FORMAT_RGBA32F, FAKE_TW, FAKE_TH, 1, 16, 0, 0 },
		{ SKY_TABLE_MULTISCATTER, SKY_FORMAT_RGBA32F, FAKE_MW, FAKE_MH, 1, 16, 0, 0 },
		{ SKY_TABLE_SKYVIEW, SKY_FORMAT_RGBA16F, FAKE_SW, FAKE_SH, 1, 8, 0, 0 },
		{ SKY_TABLE_AERIAL, SKY_FORMAT_RGBA32F, FAKE_AW, FAKE_AH, FAKE_AD, 16, 0, 0 },
	};
	uint64_t off = fake_skyd_align64(sizeof(struct sky_shm_slot));
	for (int n = 0; n < 4; n++) {
		tabs[n].offset = off;
		tabs[n].bytes = (uint64_t)tabs[n].width * tabs[n].height * tabs[n].depth * tabs[n].texel_bytes;
		off = fake_skyd_align64(off + tabs[n].bytes);
	}
	uint64_t header_bytes = fake_skyd_align64(sizeof(struct sky_shm_header));
	f->shm_bytes = header_bytes + FAKE_NSLOT * off;
	f->shm_fd = memfd_create("fake_skyd", MFD_CLOEXEC | MFD_ALLOW_SEALING);
	CHECK(f->shm_fd >= 0);
	CHECK(ftruncate(f->shm_fd, (off_t)f->shm_bytes) == 0);
	f->shm = mmap(NULL, f->shm_bytes, PROT_READ | PROT_WRITE, MAP_SHARED, f->shm_fd, 0);
	CHECK(f->shm != MAP_FAILED);
	*f->shm = (struct sky_shm_header){
		.magic = SKY_SHM_MAGIC, .layout_version = SKY_SHM_LAYOUT_VERSION,
		.uv_mapping_version = SKYMAP_VERSION, .header_bytes = (uint32_t)header_bytes,
		.n_slots = FAKE_NSLOT, .n_tables = 4, .slot_bytes = off, .total_bytes = f->shm_bytes,
		.generation = 1, .current_slot = 1,
	};
	memcpy(f->shm->tables, tabs, sizeof(tabs));
	for (uint32_t s = 0; s < FAKE_NSLOT; s++) {
		fake_skyd_fill_slot(f, s, 1.0);
		fake_skyd_slot(f, s)->seq = 2;
		fake_skyd_slot(f, s)->generation = 1;
	}
	CHECK(fcntl(f->shm_fd, F_ADD_SEALS,
		    F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE | F_SEAL_SEAL) == 0);
}

static inline void fake_skyd_send(int fd, const char *s, int pass_fd)
{
	struct iovec iov = { (void *)s, strlen(s) };
	union {
		struct cmsghdr h;
		char buf[CMSG_SPACE(sizeof(int))];
	} cm;
	struct msghdr mh = { .msg_iov = &iov, .msg_iovlen = 1 };
	if (pass_fd >= 0) {
		mh.msg_control = cm.buf;
		mh.msg_controllen = sizeof(cm.buf);
		struct cmsghdr *h = CMSG_FIRSTHDR(&mh);
		h->cmsg_level = SOL_SOCKET;
		h->cmsg_type = SCM_RIGHTS;
		h->cmsg_len = CMSG_LEN(sizeof(int));
		memcpy(CMSG_DATA(h), &pass_fd, sizeof(int));
	}
	(void)sendmsg(fd, &mh, MSG_NOSIGNAL);
}

/* The stand-in's layout change ("supersede"): the region is superseded
 * at once, its word bumped as skyd bumps it, and the next region goes out
 * on the socket only once the test writes a byte to f->layout_go[1] (a
 * pipe the test makes). The number the new region publishes is left in
 * f->superseded_generation. */
static inline void fake_skyd_supersede(struct fake_skyd *f, int fd)
{
	uint32_t next = atomic_fetch_add((_Atomic uint32_t *)&f->shm->generation, 1) + 1;
	atomic_store((_Atomic uint32_t *)&f->shm->superseded, 1);
	syscall(SYS_futex, &f->shm->generation, FUTEX_WAKE, 64, NULL, NULL, 0);
	f->superseded_generation = next;
	fake_skyd_send(fd, "OK\n", -1);
	char go;
	if (read(f->layout_go[0], &go, 1) != 1)
		return;
	/* The next region publishes the generation the old word now holds. */
	fake_skyd_build_region(f);
	f->shm->generation = next;
	for (uint32_t s = 0; s < FAKE_NSLOT; s++)
		fake_skyd_slot(f, s)->generation = next;
	char line[96];
	snprintf(line, sizeof(line), "layout: generation=%u bytes=%zu\n", next, f->shm_bytes);
	fake_skyd_send(fd, line, f->shm_fd);
}

/* Serves one connection at a time until "shutdown". */
static inline void *fake_skyd_serve(void *arg)
{
	struct fake_skyd *f = arg;
	for (;;) {
		int fd = accept4(f->listen_fd, NULL, NULL, SOCK_CLOEXEC);
		if (fd < 0)
			return NULL;
		atomic_fetch_add(&f->connections, 1);
		fake_skyd_send(fd, "OK skyd " SKY_PROTO_VERSION "\n", -1);
		char buf[8192];
		size_t len = 0;
		bool open = true, stop = false;
		while (open) {
			ssize_t n = read(fd, buf + len, sizeof(buf) - 1 - len);
			if (n <= 0)
				break;
			len += (size_t)n;
			char *nl;
			while (open && (nl = memchr(buf, '\n', len))) {
				*nl = 0;
				if (strncmp(buf, "subscribe", 9) == 0)
					fake_skyd_send(fd, "layout_version: 1\nslots: 3\nOK\n", f->shm_fd);
				else if (strcmp(buf, "ping") == 0)
					fake_skyd_send(fd, "OK\n", -1);
				else if (strcmp(buf, "get") == 0)
					fake_skyd_send(fd, "sun_elevation_deg: 30\naltitude_km: 0.2\nOK\n", -1);
				else if (strcmp(buf, "emit") == 0)
					fake_skyd_send(fd, "OK\nchanged: generation=7 tables=skyview,aerial\n", -1);
				else if (strcmp(buf, "supersede") == 0)
					fake_skyd_supersede(f, fd);
				else if (strcmp(buf, "drop") == 0)
					open = false;
				else if (strcmp(buf, "shutdown") == 0)
					open = false, stop = true;
				else
					fake_skyd_send(fd, "ACK [5] {bogus} unknown verb\n", -1);
				size_t used = (size_t)(nl - buf) + 1;
				memmove(buf, buf + used, len - used);
				len -= used;
			}
		}
		close(fd);
		if (stop)
			return NULL;
	}
}

/* Builds the region and starts serving it on f->sock_path, in a fresh
 * directory under $TMPDIR (or /tmp). */
static inline void fake_skyd_start(struct fake_skyd *f)
{
	*f = (struct fake_skyd){ .shm_fd = -1, .listen_fd = -1, .layout_go = { -1, -1 } };
	fake_skyd_build_region(f);
	const char *tmp = getenv("TMPDIR");
	snprintf(f->sock_dir, sizeof(f->sock_dir), "%s/libsky-XXXXXX",
		 tmp && strlen(tmp) < 30 ? tmp : "/tmp");
	CHECK(mkdtemp(f->sock_dir) != NULL);
	snprintf(f->sock_path, sizeof(f->sock_path), "%s/control", f->sock_dir);
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	strcpy(sa.sun_path, f->sock_path);
	f->listen_fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	CHECK(bind(f->listen_fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
	CHECK(listen(f->listen_fd, 8) == 0);
	CHECK(pthread_create(&f->thread, NULL, fake_skyd_serve, f) == 0);
}

/* A client of the stand-in, subscribed to every table with events; NULL
 * (and a failed check) if that fails. */
static inline sky_client *fake_skyd_client(struct fake_skyd *f)
{
	sky_client *c = NULL;
	CHECK(sky_connect(f->sock_path, &c) == 0);
	if (c && sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS) != 0) {
		FAIL("subscribe to the stand-in");
		sky_disconnect(c);
		c = NULL;
	}
	return c;
}

/* Stops the server (through libsky, as a client would) and removes its
 * socket and directory; the region stays mapped. */
static inline void fake_skyd_stop(struct fake_skyd *f)
{
	sky_client *c;
	if (sky_connect(f->sock_path, &c) == 0) {
		sky_send(c, "shutdown", 0);
		struct sky_event ev;
		while (sky_dispatch(c, &ev) >= 0 && ev.type != SKY_EVENT_HANGUP) {
			struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
			if (sky_get_fd(c) < 0 || poll(&p, 1, 5000) <= 0)
				break;
		}
		sky_disconnect(c);
	}
	/* wakes accept() if the server was never told to stop */
	shutdown(f->listen_fd, SHUT_RDWR);
	pthread_join(f->thread, NULL);
	close(f->listen_fd);
	unlink(f->sock_path);
	rmdir(f->sock_dir);
}

#endif

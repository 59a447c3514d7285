/* test_libsky.c - libsky on a hand-built shared-memory region that follows
 * proto/skyproto.h, served by a small in-process stand-in for skyd: the
 * protocol client, seqlock consistency, f16 decoding, sampling against a
 * direct computation at texel centres, and the three projections. */
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
#include <time.h>
#include <unistd.h>

#include "sky.h"
#include "skysample.h"
#include "test.h"

#define PI SKYMAP_PI
#define DEG (PI / 180.0)

/* ---- the hand-built region ----------------------------------------------- */

enum { TW = 16, TH = 8, MW = 4, MH = 4, SW = 24, SH = 16, AW = 8, AH = 6, AD = 5, NSLOT = 3 };

static struct sky_shm_header *shm;
static size_t shm_bytes;
static int shm_fd = -1;

static struct sky_shm_slot *slot_of(uint32_t i)
{
	return (struct sky_shm_slot *)((char *)shm + shm->header_bytes + i * shm->slot_bytes);
}

static void *table_of(uint32_t slot, uint32_t id)
{
	return (char *)slot_of(slot) + shm->tables[id].offset;
}

/* binary16 of a value that is exactly representable as a normal half. */
static uint16_t to_half(double x)
{
	if (x == 0.0)
		return 0;
	int e;
	double m = frexp(fabs(x), &e);	/* x = m 2^e, m in [0.5, 1) */
	uint16_t bits = (uint16_t)(((e - 1 + 15) << 10) | ((uint16_t)(m * 2048.0) & 0x3ff));
	return x < 0 ? bits | 0x8000 : bits;
}

static uint64_t align64(uint64_t x)
{
	return (x + 63) & ~(uint64_t)63;
}

static void fill_slot(uint32_t s, double scale)
{
	struct sky_shm_slot *sl = slot_of(s);
	struct sky_shm_state *st = &sl->state;
	memset(st, 0, sizeof(*st));
	st->bottom_radius_km = 6360.0;
	st->top_radius_km = 6460.0;
	st->altitude_km = 0.2;
	skysample_direction(30.0 * DEG, 120.0 * DEG, st->sun_direction);
	for (int c = 0; c < 3; c++)
		st->sun_illuminance_lx[c] = 1.0e5 * (c + 1);
	st->sun_angular_radius_rad = 3.0 * DEG;
	skysample_direction(-20.0 * DEG, 300.0 * DEG, st->moon_direction);
	st->moon_angular_radius_rad = 0.26 * DEG;
	st->aerial_range_km = 32.0;
	st->aerial_squared = 1;
	st->utc_unix_s = scale;
	/* transmittance: a smooth function of the (altitude, mu) of each texel */
	float *t = table_of(s, SKY_TABLE_TRANSMITTANCE);
	for (int j = 0; j < TH; j++)
		for (int i = 0; i < TW; i++) {
			double alt, mu;
			skymap_transmittance_inverse(6360.0, 6460.0, (i + 0.5) / TW, (j + 0.5) / TH, TW,
						     TH, &alt, &mu);
			float *p = t + (j * TW + i) * 4;
			p[0] = (float)(scale * exp(-0.1 / (mu + 1.1)));
			p[1] = (float)(scale * exp(-alt / 100.0));
			p[2] = (float)(scale * 0.5);
			p[3] = 1.0f;
		}
	float *m = table_of(s, SKY_TABLE_MULTISCATTER);
	for (int i = 0; i < MW * MH * 4; i++)
		m[i] = (float)scale;
	/* sky-view in f16: integers, exact in binary16 */
	uint16_t *v = table_of(s, SKY_TABLE_SKYVIEW);
	for (int j = 0; j < SH; j++)
		for (int i = 0; i < SW; i++) {
			uint16_t *p = v + (j * SW + i) * 4;
			p[0] = to_half(scale * (i + 1));
			p[1] = to_half(scale * (j + 1));
			p[2] = to_half(scale * (i + SW * j));
			p[3] = to_half(1.0);
		}
	float *a = table_of(s, SKY_TABLE_AERIAL);
	for (int k = 0; k < AD; k++)
		for (int j = 0; j < AH; j++)
			for (int i = 0; i < AW; i++) {
				float *p = a + ((k * AH + j) * AW + i) * 4;
				p[0] = (float)(scale * (k + 1));
				p[1] = (float)(scale * (i + 1));
				p[2] = (float)(scale * (j + 1));
				p[3] = (float)(1.0 - 0.1 * (k + 1));
			}
	sl->valid_tables = SKY_TABLES_ALL;
	sl->checksum = skysample_slot_checksum(shm, sl);
}

static void build_region(void)
{
	struct sky_shm_table tabs[4] = {
		{ SKY_TABLE_TRANSMITTANCE, SKY_FORMAT_RGBA32F, TW, TH, 1, 16, 0, 0 },
		{ SKY_TABLE_MULTISCATTER, SKY_FORMAT_RGBA32F, MW, MH, 1, 16, 0, 0 },
		{ SKY_TABLE_SKYVIEW, SKY_FORMAT_RGBA16F, SW, SH, 1, 8, 0, 0 },
		{ SKY_TABLE_AERIAL, SKY_FORMAT_RGBA32F, AW, AH, AD, 16, 0, 0 },
	};
	uint64_t off = align64(sizeof(struct sky_shm_slot));
	for (int n = 0; n < 4; n++) {
		tabs[n].offset = off;
		tabs[n].bytes = (uint64_t)tabs[n].width * tabs[n].height * tabs[n].depth * tabs[n].texel_bytes;
		off = align64(off + tabs[n].bytes);
	}
	uint64_t header_bytes = align64(sizeof(struct sky_shm_header));
	shm_bytes = header_bytes + NSLOT * off;
	shm_fd = memfd_create("test_libsky", MFD_CLOEXEC | MFD_ALLOW_SEALING);
	CHECK(shm_fd >= 0);
	CHECK(ftruncate(shm_fd, (off_t)shm_bytes) == 0);
	shm = mmap(NULL, shm_bytes, PROT_READ | PROT_WRITE, MAP_SHARED, shm_fd, 0);
	CHECK(shm != MAP_FAILED);
	*shm = (struct sky_shm_header){
		.magic = SKY_SHM_MAGIC, .layout_version = SKY_SHM_LAYOUT_VERSION,
		.uv_mapping_version = SKYMAP_VERSION, .header_bytes = (uint32_t)header_bytes,
		.n_slots = NSLOT, .n_tables = 4, .slot_bytes = off, .total_bytes = shm_bytes,
		.generation = 1, .current_slot = 1,
	};
	memcpy(shm->tables, tabs, sizeof(tabs));
	for (uint32_t s = 0; s < NSLOT; s++) {
		fill_slot(s, 1.0);
		slot_of(s)->seq = 2;
		slot_of(s)->generation = 1;
	}
	CHECK(fcntl(shm_fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE | F_SEAL_SEAL) == 0);
}

/* ---- a stand-in for skyd ---------------------------------------------------- */

static char sock_dir[64], sock_path[128];
static int listen_fd = -1;
static atomic_int connections;

static void send_text(int fd, const char *s, int pass_fd)
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
 * on the socket only once the test writes to layout_go. */
static int layout_go[2] = { -1, -1 };
static uint32_t superseded_generation;

static void supersede_then_layout(int fd)
{
	uint32_t next = atomic_fetch_add((_Atomic uint32_t *)&shm->generation, 1) + 1;
	atomic_store((_Atomic uint32_t *)&shm->superseded, 1);
	syscall(SYS_futex, &shm->generation, FUTEX_WAKE, 64, NULL, NULL, 0);
	superseded_generation = next;
	send_text(fd, "OK\n", -1);
	char go;
	if (read(layout_go[0], &go, 1) != 1)
		return;
	/* The next region publishes the generation the old word now holds. */
	build_region();
	shm->generation = next;
	for (uint32_t s = 0; s < NSLOT; s++)
		slot_of(s)->generation = next;
	char line[96];
	snprintf(line, sizeof(line), "layout: generation=%u bytes=%zu\n", next, shm_bytes);
	send_text(fd, line, shm_fd);
}

/* Serves one connection at a time until "shutdown". */
static void *server(void *arg)
{
	(void)arg;
	for (;;) {
		int fd = accept4(listen_fd, NULL, NULL, SOCK_CLOEXEC);
		if (fd < 0)
			return NULL;
		atomic_fetch_add(&connections, 1);
		send_text(fd, "OK skyd " SKY_PROTO_VERSION "\n", -1);
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
					send_text(fd, "layout_version: 1\nslots: 3\nOK\n", shm_fd);
				else if (strcmp(buf, "ping") == 0)
					send_text(fd, "OK\n", -1);
				else if (strcmp(buf, "get") == 0)
					send_text(fd, "sun_elevation_deg: 30\naltitude_km: 0.2\nOK\n", -1);
				else if (strcmp(buf, "emit") == 0)
					send_text(fd, "OK\nchanged: generation=7 tables=skyview,aerial\n", -1);
				else if (strcmp(buf, "supersede") == 0)
					supersede_then_layout(fd);
				else if (strcmp(buf, "drop") == 0)
					open = false;
				else if (strcmp(buf, "shutdown") == 0)
					open = false, stop = true;
				else
					send_text(fd, "ACK [5] {bogus} unknown verb\n", -1);
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

static pthread_t server_thread;

static void start_server(void)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(sock_dir, sizeof(sock_dir), "%s/libsky-XXXXXX", tmp && strlen(tmp) < 30 ? tmp : "/tmp");
	CHECK(mkdtemp(sock_dir) != NULL);
	snprintf(sock_path, sizeof(sock_path), "%s/control", sock_dir);
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	strcpy(sa.sun_path, sock_path);
	listen_fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	CHECK(bind(listen_fd, (struct sockaddr *)&sa, sizeof(sa)) == 0);
	CHECK(listen(listen_fd, 8) == 0);
	CHECK(pthread_create(&server_thread, NULL, server, NULL) == 0);
}

static void stop_server(void)
{
	sky_client *c;
	if (sky_connect(sock_path, &c) == 0) {
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
	shutdown(listen_fd, SHUT_RDWR);
	pthread_join(server_thread, NULL);
	close(listen_fd);
	unlink(sock_path);
	rmdir(sock_dir);
}

/* ---- tests -------------------------------------------------------------- */

/* A view taken of a superseded region, before its successor arrives: the
 * old word was bumped to the number the new region publishes, and
 * sky_wait() from that view must still end once the new region is mapped
 * (the new region is news, whatever its number). */
static void test_layout_wait(sky_client *c)
{
	const struct sky_shm_header *old = sky_header(c);
	size_t size = (sky_snapshot_size(c) + 63) / 64 * 64;
	void *buf = aligned_alloc(64, size);
	struct sky_view v;
	uint32_t g = 0;

	CHECK(pipe2(layout_go, O_CLOEXEC) == 0);
	CHECK(sky_request(c, "supersede", NULL) == 0);
	CHECK(buf && sky_snapshot(c, buf, size, &v) == 0 && v.header == old && old->superseded);
	CHECK(write(layout_go[1], "g", 1) == 1);
	CHECK(sky_wait(c, v.generation, 10000, &g) == 0);
	CHECK(sky_header(c) != old && g == superseded_generation && sky_header(c)->generation == g);
	struct sky_event ev;
	CHECK(sky_dispatch(c, &ev) == 1 && ev.type == SKY_EVENT_LAYOUT);
	free(buf);
	close(layout_go[0]);
	close(layout_go[1]);
}

static void test_half(void)
{
	CHECK(skysample_half(0x3c00) == 1.0);
	CHECK(skysample_half(0xc000) == -2.0);
	CHECK(skysample_half(0x3800) == 0.5);
	CHECK(skysample_half(0x7bff) == 65504.0);
	CHECK(skysample_half(0x0001) == ldexp(1.0, -24));
	CHECK(skysample_half(0x03ff) == ldexp(1023.0, -24));
	CHECK(skysample_half(0x0400) == ldexp(1.0, -14));
	CHECK(skysample_half(0x3555) == 1365.0 / 4096.0);
	CHECK(skysample_half(0x8000) == 0.0 && signbit(skysample_half(0x8000)));
	CHECK(isinf(skysample_half(0x7c00)) && skysample_half(0x7c00) > 0);
	CHECK(isinf(skysample_half(0xfc00)) && skysample_half(0xfc00) < 0);
	CHECK(isnan(skysample_half(0x7e00)));
	for (int i = 1; i < 2048; i++)
		CHECK(skysample_half(to_half(i)) == i);
}

static void test_requests(sky_client *c)
{
	sky_reply *rep = NULL;
	CHECK(strcmp(sky_protocol_version(c), SKY_PROTO_VERSION) == 0);
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK(sky_request(c, "get", &rep) == 0);
	CHECK(sky_reply_count(rep) == 2);
	CHECK(rep && strcmp(sky_reply_key(rep, 0), "sun_elevation_deg") == 0);
	CHECK(rep && strcmp(sky_reply_get(rep, "altitude_km"), "0.2") == 0);
	CHECK(sky_reply_get(rep, "nope") == NULL);
	sky_reply_free(rep);
	rep = NULL;
	CHECK(sky_request(c, "bogus x=1", &rep) == SKY_ACK_UNKNOWN);
	CHECK(rep && strcmp(sky_reply_message(rep), "{bogus} unknown verb") == 0);
	sky_reply_free(rep);
	CHECK(sky_request(c, "two\nlines", NULL) == -EINVAL);
	CHECK(sky_request(c, "", NULL) == -EINVAL);
	/* the connection stays usable */
	CHECK(sky_request(c, "ping", NULL) == 0);

	/* asynchronous: replies in order with their userdata, an event between */
	CHECK(sky_send(c, "ping", 11) == 0);
	CHECK(sky_send(c, "emit", 12) == 0);
	CHECK(sky_send(c, "bogus", 13) == 0);
	int replies = 0, changed = 0;
	uint64_t order[3] = { 0 };
	while (replies < 3) {
		struct sky_event ev;
		int r = sky_dispatch(c, &ev);
		CHECK(r >= 0);
		if (r < 0)
			break;
		if (r == 0) {
			struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
			CHECK(poll(&p, 1, 5000) == 1);
			continue;
		}
		if (ev.type == SKY_EVENT_REPLY) {
			order[replies++] = ev.userdata;
			if (ev.userdata == 13)
				CHECK(ev.ack == SKY_ACK_UNKNOWN && sky_reply_ack(ev.reply) == SKY_ACK_UNKNOWN);
			else
				CHECK(ev.ack == 0);
		} else if (ev.type == SKY_EVENT_CHANGED) {
			changed++;
			CHECK(ev.generation == 7);
			CHECK(ev.tables == (SKY_TABLE_BIT(SKY_TABLE_SKYVIEW) | SKY_TABLE_BIT(SKY_TABLE_AERIAL)));
		}
	}
	CHECK(order[0] == 11 && order[1] == 12 && order[2] == 13);
	/* The event line may arrive after the third reply: it is read by now. */
	struct sky_event ev;
	while (!changed && sky_dispatch(c, &ev) == 1)
		changed += ev.type == SKY_EVENT_CHANGED;
	CHECK(changed == 1);

	/* a sync request queues events that arrive before its reply */
	CHECK(sky_request(c, "emit", NULL) == 0);
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK(sky_dispatch(c, &ev) == 1 && ev.type == SKY_EVENT_CHANGED);
}

static void test_hangup_and_reconnect(sky_client *c)
{
	int before = atomic_load(&connections);
	CHECK(sky_send(c, "drop", 0) == 0);
	struct sky_event ev = { 0 };
	for (int i = 0; i < 100; i++) {
		int r = sky_dispatch(c, &ev);
		if (r == 1 && ev.type == SKY_EVENT_HANGUP)
			break;
		struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
		if (p.fd < 0 || poll(&p, 1, 5000) <= 0)
			break;
	}
	CHECK(ev.type == SKY_EVENT_HANGUP);
	CHECK(sky_dispatch(c, &ev) == -ENOTCONN);
	CHECK(sky_get_fd(c) == -ENOTCONN);
	/* The mapping survives the hang-up. */
	struct sky_view v;
	CHECK(sky_view_begin(c, &v) == 0 && sky_view_end(c, &v));
	/* the next request reconnects by itself and subscribes again */
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK(atomic_load(&connections) == before + 1);
	CHECK(sky_header(c) != NULL);
	CHECK(sky_reconnect(c) == 0);
	CHECK(atomic_load(&connections) == before + 2);
	CHECK(sky_request(c, "ping", NULL) == 0);
}

static void test_sampling_at_texel_centres(sky_client *c)
{
	struct sky_view v;
	CHECK(sky_view_begin(c, &v) == 0);
	CHECK(v.valid_tables == SKY_TABLES_ALL && v.generation == 1 && v.slot_index == 1);
	const float *t = table_of(1, SKY_TABLE_TRANSMITTANCE);
	double worst = 0.0;
	for (int j = 0; j < TH; j++)
		for (int i = 0; i < TW; i++) {
			double alt, mu, rgb[3];
			skymap_transmittance_inverse(6360.0, 6460.0, (i + 0.5) / TW, (j + 0.5) / TH, TW, TH,
						     &alt, &mu);
			CHECK(sky_sample_transmittance(&v, alt, mu, rgb) == 0);
			for (int k = 0; k < 3; k++)
				worst = fmax(worst, fabs(rgb[k] - t[(j * TW + i) * 4 + k]));
		}
	printf("transmittance at texel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);

	/* sky-view (f16): texel centres, and halfway between two texels */
	worst = 0.0;
	for (int j = 0; j < SH; j++)
		for (int i = 0; i < SW; i++) {
			double zen, az, rgb[3];
			double hc = skymap_horizon_cos(6360.0, 0.2);
			skymap_skyview_inverse(hc, (i + 0.5) / SW, (j + 0.5) / SH, SH, &zen, &az);
			CHECK(sky_sample_sky(&v, 90.0 - zen / DEG, az / DEG, 0, rgb) == 0);
			worst = fmax(worst, fabs(rgb[0] - (i + 1)));
			worst = fmax(worst, fabs(rgb[1] - (j + 1)));
			worst = fmax(worst, fabs(rgb[2] - (i + SW * j)));
		}
	printf("sky-view (f16) at texel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);
	{
		/* azimuth 0 lies between the last and the first column: the average */
		double zen, az, rgb[3];
		skymap_skyview_inverse(skymap_horizon_cos(6360.0, 0.2), 0.5 / SW, 2.5 / SH, SH, &zen, &az);
		CHECK(sky_sample_sky(&v, 90.0 - zen / DEG, 0.0, 0, rgb) == 0);
		CHECK(fabs(rgb[0] - 0.5 * (1 + SW)) < 1e-6);
		CHECK(fabs(rgb[1] - 3.0) < 1e-6);
	}

	/* aerial: froxel centres at the far edge of each slice; depth 0 is (0, 1) */
	worst = 0.0;
	for (int k = 0; k < AD; k++)
		for (int j = 0; j < AH; j++)
			for (int i = 0; i < AW; i++) {
				double rgb[3], tr;
				double d = skymap_aerial_depth_km(k, AD, 32.0, 1);
				CHECK(sky_sample_aerial(&v, (i + 0.5) / AW, (j + 0.5) / AH, d, rgb, &tr) == 0);
				worst = fmax(worst, fabs(rgb[0] - (k + 1)));
				worst = fmax(worst, fabs(rgb[1] - (i + 1)));
				worst = fmax(worst, fabs(rgb[2] - (j + 1)));
				worst = fmax(worst, fabs(tr - (1.0 - 0.1 * (k + 1))));
			}
	printf("aerial at froxel centres: worst |error| %.3g\n", worst);
	CHECK(worst < 1e-6);
	double rgb[3], tr;
	CHECK(sky_sample_aerial(&v, 0.5, 0.5, 0.0, rgb, &tr) == 0);
	CHECK(rgb[0] == 0.0 && tr == 1.0);
	/* halfway (in the slice coordinate) between the camera and slice 0 */
	double half = 32.0 * pow(0.5 / AD, 2.0);
	CHECK(sky_sample_aerial(&v, (0.5) / AW, 0.5 / AH, half, rgb, &tr) == 0);
	CHECK(fabs(rgb[0] - 0.5) < 1e-9 && fabs(tr - 0.95) < 1e-6);
	CHECK(sky_sample_aerial(&v, 0.5, 0.5, -1.0, rgb, &tr) == -EINVAL);

	/* sun: top-of-atmosphere illuminance times the table at (altitude, mu_sun) */
	double lx[3], tr3[3];
	CHECK(sky_sample_sun(&v, lx) == 0);
	skysample_transmittance(&(struct skysample_table){ t, SKY_FORMAT_RGBA32F, TW, TH, 1, 0 },
				&v.slot->state, 0.2, sin(30.0 * DEG), tr3);
	for (int k = 0; k < 3; k++)
		CHECK(fabs(lx[k] - 1.0e5 * (k + 1) * tr3[k]) < 1e-6 * lx[k]);
	CHECK(sky_view_end(c, &v));
	sky_view_end(c, &v);
}

/* A uniform sky integrates to pi L over the hemisphere; the sun's disk
 * integrates to its illuminance times the transmittance. */
static void test_ambient_and_disk(void)
{
	static float sky[SW * SH * 4], trans[TW * TH * 4];
	for (int i = 0; i < SW * SH * 4; i++)
		sky[i] = 2.0f;
	for (int i = 0; i < TW * TH * 4; i++)
		trans[i] = 0.25f;
	struct skysample_table ts = { sky, SKY_FORMAT_RGBA32F, SW, SH, 1, 0 };
	struct skysample_table tt = { trans, SKY_FORMAT_RGBA32F, TW, TH, 1, 0 };
	struct sky_shm_state st = { .bottom_radius_km = 6360, .top_radius_km = 6460, .altitude_km = 0.2,
				    .sun_illuminance_lx = { 1000, 2000, 3000 },
				    .sun_angular_radius_rad = 2.0 * DEG };
	double lx[3];
	skysample_ambient(&ts, &st, lx);
	CHECK(fabs(lx[0] - 2.0 * PI) < 1e-12 && fabs(lx[2] - 2.0 * PI) < 1e-12);
	skysample_direction(40.0 * DEG, 200.0 * DEG, st.sun_direction);
	for (int limb = 0; limb < 2; limb++) {
		/* integrate the disk radiance over solid angle around the sun */
		double sum = 0.0, n = 400;
		double e0[3] = { cos(200 * DEG), -sin(200 * DEG), 0 }, e1[3];
		const double *s = st.sun_direction;
		e1[0] = s[1] * e0[2] - s[2] * e0[1];
		e1[1] = s[2] * e0[0] - s[0] * e0[2];
		e1[2] = s[0] * e0[1] - s[1] * e0[0];
		double h = 2.2 * DEG * 2.0 / n;
		for (int a = 0; a < n; a++)
			for (int b = 0; b < n; b++) {
				double x = -2.2 * DEG + (a + 0.5) * h, y = -2.2 * DEG + (b + 0.5) * h;
				double d[3], rgb[3] = { 0, 0, 0 }, len = 0;
				for (int k = 0; k < 3; k++) {
					d[k] = s[k] + x * e0[k] + y * e1[k];
					len += d[k] * d[k];
				}
				len = sqrt(len);
				for (int k = 0; k < 3; k++)
					d[k] /= len;
				skysample_add_disk(&tt, &st, s, st.sun_illuminance_lx, 2.0 * DEG, d,
						   limb ? 0.6 : 0.0, rgb);
				sum += rgb[0] * h * h / (len * len * len);
			}
		printf("disk integral (limb %d): %.6g, expected %.6g\n", limb, sum, 1000 * 0.25);
		CHECK(fabs(sum - 250.0) < 250.0 * 5e-3);
	}
	/* below the horizon the sun is blocked */
	skysample_direction(-1.0 * DEG, 0.0, st.sun_direction);
	skysample_sun(&tt, &st, lx);
	CHECK(lx[0] == 0.0 && lx[1] == 0.0);
}

static void test_projections(sky_client *c)
{
	struct sky_view v;
	CHECK(sky_view_begin(c, &v) == 0);
	double sun_el = 30.0, sun_az = 120.0, dir[3], x, y;
	struct sky_render_params ps[3] = {
		{ .projection = SKY_PROJECTION_EQUIRECT, .width = 360, .height = 180 },
		{ .projection = SKY_PROJECTION_PERSPECTIVE, .width = 160, .height = 90, .yaw_deg = 100,
		  .pitch_deg = 20, .vfov_deg = 60 },
		{ .projection = SKY_PROJECTION_FISHEYE, .width = 201, .height = 151, .yaw_deg = 0 },
	};
	/* known directions to known pixels */
	skysample_direction(0.0, 90.0 * DEG, dir);
	CHECK(sky_render_position(&ps[0], dir, &x, &y) == 1 && fabs(x - 90) < 1e-9 && fabs(y - 90) < 1e-9);
	skysample_direction(90.0 * DEG, 0.0, dir);
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 100.5) < 1e-9 && fabs(y - 75.5) < 1e-9);
	skysample_direction(0.0, 0.0, dir);	/* north horizon: the bottom of the circle */
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 100.5) < 1e-9 &&
	      fabs(y - 151.0) < 1e-9);
	skysample_direction(0.0, 90.0 * DEG, dir);	/* east: the right */
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 1 && fabs(x - 176.0) < 1e-9 &&
	      fabs(y - 75.5) < 1e-9);
	skysample_direction(-5.0 * DEG, 0.0, dir);
	CHECK(sky_render_position(&ps[2], dir, &x, &y) == 0);
	skysample_direction(20.0 * DEG, 100.0 * DEG, dir);	/* perspective axis: the centre */
	CHECK(sky_render_position(&ps[1], dir, &x, &y) == 1 && fabs(x - 80) < 1e-9 && fabs(y - 45) < 1e-9);
	CHECK(sky_render_direction(&ps[2], 0.5, 0.5, dir) == 0);	/* corner outside */

	for (int n = 0; n < 3; n++) {
		struct sky_render_params p = ps[n];
		/* round trip at every 7th pixel */
		for (uint32_t py = 0; py < p.height; py += 7)
			for (uint32_t px = 0; px < p.width; px += 7) {
				double d[3], bx, by;
				if (sky_render_direction(&p, px + 0.5, py + 0.5, d) != 1)
					continue;
				if (sky_render_position(&p, d, &bx, &by) != 1 ||
				    fabs(bx - (px + 0.5)) > 1e-6 || fabs(by - (py + 0.5)) > 1e-6) {
					FAIL("projection %d: pixel (%u, %u) round trip (%g, %g)", n, px, py, bx, by);
					goto next;
				}
			}
	next:;
		/* the brightest pixel of a render is where the sun's disk is */
		p.flags = SKY_SAMPLE_SUN_DISK;
		float *img = malloc(sizeof(float) * 3 * p.width * p.height);
		CHECK(sky_render(&v, &p, img) == 0);
		double best = -1, bx = 0, by = 0, sx, sy;
		double sum_x = 0, sum_y = 0, cnt = 0;
		for (uint32_t py = 0; py < p.height; py++)
			for (uint32_t px = 0; px < p.width; px++) {
				double val = img[(py * p.width + px) * 3];
				if (val > best) {
					best = val;
					bx = px + 0.5;
					by = py + 0.5;
				}
				if (val > 1000.0) {
					sum_x += px + 0.5;
					sum_y += py + 0.5;
					cnt++;
				}
			}
		skysample_direction(sun_el * DEG, sun_az * DEG, dir);
		CHECK(sky_render_position(&p, dir, &sx, &sy) == 1);
		printf("projection %d: sun disk centroid (%.2f, %.2f) over %.0f px, expected (%.2f, %.2f)\n",
		       n, sum_x / cnt, sum_y / cnt, cnt, sx, sy);
		CHECK(cnt > 3 && fabs(sum_x / cnt - sx) < 1.0 && fabs(sum_y / cnt - sy) < 1.0);
		(void)bx, (void)by;
		/* a pixel off the disk holds the sky-view value in that direction */
		double d[3], rgb[3];
		double qx = p.width / 4 + 0.5, qy = p.height / 2 + 0.5;
		CHECK(sky_render_direction(&p, qx, qy, d) == 1);
		double el = asin(d[2]) / DEG, az = atan2(d[0], d[1]) / DEG;
		CHECK(sky_sample_sky(&v, el, az, 0, rgb) == 0);
		CHECK(fabsf(img[((p.height / 2) * p.width + p.width / 4) * 3 + 2] - (float)rgb[2]) <= 1e-6f * (float)rgb[2] + 1e-6f);
		free(img);
	}
	CHECK(sky_view_end(c, &v));
}

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
		uint32_t cur = __atomic_load_n(&shm->current_slot, __ATOMIC_RELAXED);
		if (n % 4)
			cur = (cur + 1) % NSLOT;
		struct sky_shm_slot *s = slot_of(cur);
		__atomic_store_n(&s->seq, s->seq + 1, __ATOMIC_RELAXED);
		atomic_thread_fence(memory_order_release);
		fill_slot(cur, (double)(n % 16 + 1));
		__atomic_store_n(&s->seq, s->seq + 1, __ATOMIC_RELEASE);
		__atomic_store_n(&shm->current_slot, cur, __ATOMIC_RELEASE);
		__atomic_add_fetch(&shm->generation, 1, __ATOMIC_RELEASE);
		syscall(SYS_futex, &shm->generation, FUTEX_WAKE, INT32_MAX, NULL, NULL, 0);
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
			    id == SKY_TABLE_SKYVIEW ? k * SW : k * AH;
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
	struct sky_shm_slot *s = slot_of(v.slot_index);
	s->seq++;
	fill_slot(v.slot_index, 3.0);
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
	((float *)((char *)buf + shm->tables[1].offset))[5] += 1.0f;
	CHECK(!sky_view_verify(&v));

	/* concurrent: a writer rewrites the current slot flat out; every view
	 * that sky_view_end() accepts and every snapshot must be whole */
	uint32_t g0 = __atomic_load_n(&shm->generation, __ATOMIC_ACQUIRE), g1 = 0;
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
	for (uint32_t k = 0; k < NSLOT; k++)
		fill_slot(k, 1.0);
	free(buf);
	CHECK(sky_wait(c, __atomic_load_n(&shm->generation, __ATOMIC_ACQUIRE), 0, NULL) == -ETIMEDOUT);
}

static void test_errors(void)
{
	sky_client *c = NULL;
	CHECK(sky_connect("/nonexistent-dir/control", &c) == -ENOENT && c == NULL);
	CHECK(sky_connect(NULL, NULL) == -EINVAL);
	CHECK(strlen(sky_strerror(-ENOENT)) > 0 && strlen(sky_strerror(SKY_ACK_RANGE)) > 0);
	CHECK(sky_strerror(-123456) != NULL);
	char p[8];
	CHECK(sky_default_path(p, sizeof(p)) == -ENAMETOOLONG);
	sky_disconnect(NULL);
	sky_reply_free(NULL);
	CHECK(sky_version() == SKY_VERSION);
	/* a corrupt header is refused before anything indexes with it */
	struct sky_shm_header h = *shm;
	h.tables[2].bytes += 8;
	CHECK(skysample_check_layout(&h, shm_bytes) == -EPROTO);
	h = *shm;
	h.n_slots = 2;
	CHECK(skysample_check_layout(&h, shm_bytes) == -EPROTO);
	h = *shm;
	h.tables[3].offset = h.slot_bytes;
	CHECK(skysample_check_layout(&h, shm_bytes) == -EPROTO);
	h = *shm;
	h.uv_mapping_version = 99;
	CHECK(skysample_check_layout(&h, shm_bytes) == -EPROTONOSUPPORT);
	CHECK(skysample_check_layout(shm, shm_bytes) == 0);
	CHECK(skysample_check_layout(shm, shm_bytes - 1) == -EPROTO);
}

int main(void)
{
	build_region();
	start_server();
	test_half();
	test_errors();
	sky_client *c = NULL;
	CHECK(sky_connect(sock_path, &c) == 0);
	if (c) {
		struct sky_view v;
		CHECK(sky_view_begin(c, &v) == -ENOTCONN);
		test_requests(c);
		CHECK(sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS) == 0);
		CHECK(sky_header(c) != NULL && sky_snapshot_size(c) == shm->slot_bytes);
		/* read-only: the mapping refuses writes */
		CHECK(mprotect((void *)sky_header(c), 4096, PROT_READ | PROT_WRITE) < 0);
		test_sampling_at_texel_centres(c);
		test_ambient_and_disk();
		test_projections(c);
		test_consistency(c);
		test_layout_wait(c);
		test_hangup_and_reconnect(c);
		sky_disconnect(c);
	}
	stop_server();
	return test_report("test_libsky");
}

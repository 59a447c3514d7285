/* test_libsky_client.c - libsky's protocol client against the stand-in for
 * skyd (testkit/fake_skyd.h): requests and replies, events between them,
 * errors, the read-only mapping, a layout change and a hang-up with the
 * reconnection that follows. */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "fake_skyd.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"

static struct fake_skyd fake;

static void test_errors(void)
{
	sky_client *c = NULL;
	CHECK(sky_connect("/nonexistent-dir/control", &c) == -ENOENT && c == NULL);
	CHECK(sky_connect(NULL, NULL) == -EINVAL);
	CHECK(strlen(sky_strerror(-ENOENT)) > 0 && strlen(sky_strerror(SKY_ACK_RANGE)) > 0);
	CHECK(sky_strerror(-123456) != NULL);
	char p[8];
	CHECK_EQ(sky_default_path(p, sizeof(p)), -ENAMETOOLONG);
	sky_disconnect(NULL);
	sky_reply_free(NULL);
	CHECK_EQ(sky_version(), SKY_VERSION);
	/* a corrupt header is refused before anything indexes with it */
	struct sky_shm_header h = *fake.shm;
	h.tables[2].bytes += 8;
	CHECK_EQ(skysample_check_layout(&h, fake.shm_bytes), -EPROTO);
	h = *fake.shm;
	h.n_slots = 2;
	CHECK_EQ(skysample_check_layout(&h, fake.shm_bytes), -EPROTO);
	h = *fake.shm;
	h.tables[3].offset = h.slot_bytes;
	CHECK_EQ(skysample_check_layout(&h, fake.shm_bytes), -EPROTO);
	h = *fake.shm;
	h.uv_mapping_version = 99;
	CHECK_EQ(skysample_check_layout(&h, fake.shm_bytes), -EPROTONOSUPPORT);
	CHECK_EQ(skysample_check_layout(fake.shm, fake.shm_bytes), 0);
	CHECK_EQ(skysample_check_layout(fake.shm, fake.shm_bytes - 1), -EPROTO);
}

static void test_requests(sky_client *c)
{
	sky_reply *rep = NULL;
	CHECK(strcmp(sky_protocol_version(c), SKY_PROTO_VERSION) == 0);
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK_EQ(sky_request(c, "get", &rep), 0);
	CHECK_EQ(sky_reply_count(rep), 2);
	CHECK(rep && strcmp(sky_reply_key(rep, 0), "sun_elevation_deg") == 0);
	CHECK(rep && strcmp(sky_reply_get(rep, "altitude_km"), "0.2") == 0);
	CHECK(sky_reply_get(rep, "nope") == NULL);
	sky_reply_free(rep);
	rep = NULL;
	CHECK_EQ(sky_request(c, "bogus x=1", &rep), SKY_ACK_UNKNOWN);
	CHECK(rep && strcmp(sky_reply_message(rep), "{bogus} unknown verb") == 0);
	sky_reply_free(rep);
	CHECK(sky_request(c, "two\nlines", NULL) == -EINVAL);
	CHECK(sky_request(c, "", NULL) == -EINVAL);
	/* the connection stays usable */
	CHECK(sky_request(c, "ping", NULL) == 0);

	/* asynchronous: replies in order with their userdata, an event between */
	CHECK_EQ(sky_send(c, "ping", 11), 0);
	CHECK_EQ(sky_send(c, "emit", 12), 0);
	CHECK_EQ(sky_send(c, "bogus", 13), 0);
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
			CHECK_EQ(poll(&p, 1, 5000), 1);
			continue;
		}
		if (ev.type == SKY_EVENT_REPLY) {
			order[replies++] = ev.userdata;
			if (ev.userdata == 13)
				CHECK(ev.ack == SKY_ACK_UNKNOWN && sky_reply_ack(ev.reply) == SKY_ACK_UNKNOWN);
			else
				CHECK_EQ(ev.ack, 0);
		} else if (ev.type == SKY_EVENT_CHANGED) {
			changed++;
			CHECK_EQ(ev.generation, 7);
			CHECK_EQ(ev.tables, (SKY_TABLE_BIT(SKY_TABLE_SKYVIEW) | SKY_TABLE_BIT(SKY_TABLE_AERIAL)));
		}
	}
	CHECK(order[0] == 11 && order[1] == 12 && order[2] == 13);
	/* The event line may arrive after the third reply: it is read by now. */
	struct sky_event ev;
	while (!changed && sky_dispatch(c, &ev) == 1)
		changed += ev.type == SKY_EVENT_CHANGED;
	CHECK_EQ(changed, 1);

	/* a sync request queues events that arrive before its reply */
	CHECK(sky_request(c, "emit", NULL) == 0);
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK(sky_dispatch(c, &ev) == 1 && ev.type == SKY_EVENT_CHANGED);
}

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

	CHECK_EQ(pipe2(fake.layout_go, O_CLOEXEC), 0);
	CHECK(sky_request(c, "supersede", NULL) == 0);
	CHECK(buf && sky_snapshot(c, buf, size, &v) == 0 && v.header == old && old->superseded);
	CHECK_EQ(write(fake.layout_go[1], "g", 1), 1);
	CHECK_EQ(sky_wait(c, v.generation, 10000, &g), 0);
	CHECK(sky_header(c) != old && g == fake.superseded_generation && sky_header(c)->generation == g);
	struct sky_event ev;
	CHECK(sky_dispatch(c, &ev) == 1 && ev.type == SKY_EVENT_LAYOUT);
	free(buf);
	close(fake.layout_go[0]);
	close(fake.layout_go[1]);
}

/* The same layout change with the new region mapped by sky_dispatch()
 * before the wait, as a loop does that drains its events and then waits
 * from the view it took: the view of the superseded region names the
 * generation its slot holds, not the bumped word (the number the new
 * region publishes), so sky_wait() from it ends at once. Once, a view
 * held the bumped number and the wait slept on the new region's word
 * until its timeout. */
static void test_layout_dispatched(sky_client *c)
{
	const struct sky_shm_header *old = sky_header(c);
	size_t size = (sky_snapshot_size(c) + 63) / 64 * 64;
	void *buf = aligned_alloc(64, size);
	struct sky_view v;
	struct sky_event ev = { 0 };
	uint32_t g = 0;

	CHECK_EQ(pipe2(fake.layout_go, O_CLOEXEC), 0);
	CHECK(sky_request(c, "supersede", NULL) == 0);
	CHECK(buf && sky_snapshot(c, buf, size, &v) == 0 && v.header == old && old->superseded);
	CHECK_EQ(v.generation, (uint32_t)v.slot->generation);
	CHECK(v.generation != fake.superseded_generation);
	CHECK_EQ(write(fake.layout_go[1], "g", 1), 1);
	for (int i = 0; i < 100 && ev.type != SKY_EVENT_LAYOUT; i++) {
		int r = sky_dispatch(c, &ev);
		if (r == 1)
			continue;
		struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
		if (r < 0 || p.fd < 0 || poll(&p, 1, 5000) <= 0)
			break;
	}
	CHECK(ev.type == SKY_EVENT_LAYOUT && sky_header(c) != old);
	/* Just look: the new region's generation differs from the view's. */
	CHECK_EQ(sky_wait(c, v.generation, 0, &g), 0);
	CHECK_EQ(g, fake.superseded_generation);
	free(buf);
	close(fake.layout_go[0]);
	close(fake.layout_go[1]);
}

static void test_hangup_and_reconnect(sky_client *c)
{
	int before = atomic_load(&fake.connections);
	CHECK_EQ(sky_send(c, "drop", 0), 0);
	struct sky_event ev = { 0 };
	for (int i = 0; i < 100; i++) {
		int r = sky_dispatch(c, &ev);
		if (r == 1 && ev.type == SKY_EVENT_HANGUP)
			break;
		struct pollfd p = { sky_get_fd(c), POLLIN, 0 };
		if (p.fd < 0 || poll(&p, 1, 5000) <= 0)
			break;
	}
	CHECK_EQ(ev.type, SKY_EVENT_HANGUP);
	CHECK_EQ(sky_dispatch(c, &ev), -ENOTCONN);
	CHECK_EQ(sky_get_fd(c), -ENOTCONN);
	/* The mapping survives the hang-up. */
	struct sky_view v;
	CHECK(sky_view_begin(c, &v) == 0 && sky_view_end(c, &v));
	/* the next request reconnects by itself and subscribes again */
	CHECK(sky_request(c, "ping", NULL) == 0);
	CHECK_EQ(atomic_load(&fake.connections), before + 1);
	CHECK(sky_header(c) != NULL);
	CHECK_EQ(sky_reconnect(c), 0);
	CHECK_EQ(atomic_load(&fake.connections), before + 2);
	CHECK(sky_request(c, "ping", NULL) == 0);
}

int main(void)
{
	fake_skyd_start(&fake);
	test_errors();
	sky_client *c = NULL;
	CHECK_EQ(sky_connect(fake.sock_path, &c), 0);
	if (c) {
		struct sky_view v;
		CHECK_EQ(sky_view_begin(c, &v), -ENOTCONN);
		test_requests(c);
		CHECK_EQ(sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS), 0);
		CHECK(sky_header(c) != NULL && sky_snapshot_size(c) == fake.shm->slot_bytes);
		/* read-only: the mapping refuses writes */
		CHECK(mprotect((void *)sky_header(c), 4096, PROT_READ | PROT_WRITE) < 0);
		test_layout_wait(c);
		test_layout_dispatched(c);
		test_hangup_and_reconnect(c);
		sky_disconnect(c);
	}
	fake_skyd_stop(&fake);
	return test_report("test_libsky_client");
}

/* test_daemon_terrain.c - the terrain through the real skyd: a height field
 * the test writes with libpng is set with its extent and height, shown by
 * get with its hash; every kind of bad file (missing, not an image, colour,
 * too large, a directory) is refused with the exact ACK line naming the
 * file and why, a refused request or batch changes nothing (the last good
 * field stays), the hash check refuses another file's hash, and none takes
 * the field away. */
#include <fcntl.h>
#include <stdint.h>

#include "daemon_harness.h"
#include "skyproto.h"
#include "terrain_png.h"
#include "test.h"

static char reply[1 << 16];
static char dir[192];

static const char *at(const char *name)
{
	static char buf[4][256];
	static int k;
	k = (k + 1) % 4;
	snprintf(buf[k], sizeof(buf[k]), "%s/%s", dir, name);
	return buf[k];
}

static void files(void)
{
	enum { W = 64 };
	static uint16_t p[W * W];
	for (int j = 0; j < W; j++)
		for (int i = 0; i < W; i++)
			p[j * W + i] = (uint16_t)(i < W / 2 ? 0 : 40000 + 100 * j);	/* a cliff */
	CHECK(terrain_png_write(at("ridge.png"), W, W, 16, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	CHECK(terrain_png_write(at("other.png"), W, W, 8, PNG_COLOR_TYPE_GRAY, p, 0, 0) == 0);
	CHECK(terrain_png_write(at("photo.png"), W, W, 8, PNG_COLOR_TYPE_RGB, p, 0, 0) == 0);
	CHECK(terrain_png_write(at("huge.png"), 8192, 8192, 16, PNG_COLOR_TYPE_GRAY, p, 0, 1) == 0);
	FILE *f = fopen(at("notes.txt"), "w");
	if (f) {
		fputs("a list of mountains\n", f);
		fclose(f);
	}
}

/* The exact ACK line a request gets, and that it changed nothing. */
static void refused(struct conn *c, const char *req, const char *want)
{
	char before[8192], after[8192];

	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	CHECK(conn_request(c, req, reply, sizeof(reply)) > 0);
	printf("> %s\n< %s", req, reply);
	if (strcmp(reply, want) != 0)
		FAIL("%s: got \"%s\", want \"%s\"", req, reply, want);
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	CHECK(strcmp(before, after) == 0);
}

static void test_terrain(struct conn *c, struct conn *ev)
{
	char req[512], want[1024], buf[256];

	snprintf(req, sizeof(req), "set terrain=%s terrain_extent_km=20 terrain_height_m=2500",
		 at("ridge.png"));
	CHECK(conn_request(c, req, reply, sizeof(reply)) == 0);
	printf("> %s\n%s", req, reply);
	CHECK(strstr(reply, "tables: skyview,aerial\n") != NULL);
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation")) == 0);
	CHECK(conn_request(c, "get terrain terrain_extent_km terrain_height_m terrain_hash", reply,
			   sizeof(reply)) == 0);
	printf("%s", reply);
	CHECK(strcmp(reply_value(reply, "terrain", buf, sizeof(buf)), at("ridge.png")) == 0);
	CHECK(strstr(reply, "terrain_extent_km: 20\n") && strstr(reply, "terrain_height_m: 2500\n"));
	char hash[64];
	snprintf(hash, sizeof(hash), "%s", reply_value(reply, "terrain_hash", buf, sizeof(buf)));
	CHECK(strlen(hash) == 16);
	/* get lists the block now that a field is set. */
	CHECK(conn_request(c, "get", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "\nterrain_hash: ") != NULL);

	snprintf(req, sizeof(req), "set terrain=%s", at("missing.png"));
	snprintf(want, sizeof(want), "ACK [2] {set} terrain: cannot read '%s': No such file or directory\n",
		 at("missing.png"));
	refused(c, req, want);
	snprintf(req, sizeof(req), "set sun_elevation_deg=10 terrain=%s", at("notes.txt"));
	snprintf(want, sizeof(want), "ACK [2] {set} terrain: '%s' is neither a PNG nor a SKYTERRAIN16 file\n",
		 at("notes.txt"));
	refused(c, req, want);
	snprintf(req, sizeof(req), "set terrain=%s", at("photo.png"));
	snprintf(want, sizeof(want), "ACK [2] {set} terrain: '%s' is a colour PNG; a height field is greyscale\n",
		 at("photo.png"));
	refused(c, req, want);
	snprintf(req, sizeof(req), "set terrain=%s", at("huge.png"));
	snprintf(want, sizeof(want), "ACK [51] {set} terrain: '%s' is 8192 x 8192 texels, more than 4096 x 4096\n",
		 at("huge.png"));
	refused(c, req, want);
	snprintf(req, sizeof(req), "set terrain=%s", dir);
	snprintf(want, sizeof(want), "ACK [2] {set} terrain: '%s' is not a regular file\n", dir);
	refused(c, req, want);
	refused(c, "set terrain=ridge.png",
		"ACK [2] {set} terrain: 'ridge.png' is not an absolute path (skyd's directory is not the client's)\n");
	snprintf(req, sizeof(req), "set terrain_hash=0123456789abcdef");
	snprintf(want, sizeof(want), "ACK [2] {set} terrain_hash: '%s' here holds %s, not 0123456789abcdef: every host needs the same file\n",
		 at("ridge.png"), hash);
	refused(c, req, want);
	snprintf(req, sizeof(req), "set terrain_hash=%s", hash);
	CHECK(conn_request(c, req, reply, sizeof(reply)) == 0);

	/* A batch with a bad file applies nothing of itself. */
	char before[8192], after[8192];
	CHECK(conn_request(c, "get", before, sizeof(before)) == 0);
	snprintf(req, sizeof(req), "batch\nset sun_elevation_deg=12\nset terrain=%s\n", at("missing.png"));
	CHECK(send(c->fd, req, strlen(req), 0) == (ssize_t)strlen(req));
	CHECK(conn_request(c, "end", reply, sizeof(reply)) == SKY_ACK_ARG);
	printf("%s", reply);
	CHECK(strstr(reply, "{end} line 2: terrain: cannot read '") != NULL);
	CHECK(conn_request(c, "get", after, sizeof(after)) == 0);
	CHECK(strcmp(before, after) == 0);

	/* Another file, then none. */
	snprintf(req, sizeof(req), "set terrain=%s", at("other.png"));
	CHECK(conn_request(c, req, reply, sizeof(reply)) == 0);
	CHECK(conn_request(c, "get terrain_hash", reply, sizeof(reply)) == 0);
	CHECK(strcmp(reply_value(reply, "terrain_hash", buf, sizeof(buf)), hash) != 0);
	CHECK(conn_request(c, "set terrain=none", reply, sizeof(reply)) == 0);
	CHECK(conn_wait_generation(ev, reply_u64(reply, "generation")) == 0);
	CHECK(conn_request(c, "get terrain terrain_hash", reply, sizeof(reply)) == 0);
	CHECK(strstr(reply, "terrain: none\n") && strstr(reply, "terrain_hash: none\n"));
}

int main(void)
{
	struct daemon d = { 0 };
	struct conn c, ev;

	harness_need_device();
	if (daemon_start(&d, (const char *const[]){ HARNESS_SMALL, NULL }) < 0) {
		FAIL("skyd did not start");
		return test_report("test_daemon_terrain");
	}
	snprintf(dir, sizeof(dir), "%s", d.dir);
	files();
	CHECK(conn_open(&c, d.sock) == 0);
	CHECK(conn_open(&ev, d.sock) == 0);
	CHECK(conn_request(&ev, "subscribe events=1", reply, sizeof(reply)) == 0);
	test_terrain(&c, &ev);
	conn_close(&c);
	conn_close(&ev);
	daemon_cleanup(&d);
	return test_report("test_daemon_terrain");
}

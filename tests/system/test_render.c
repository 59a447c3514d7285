/* test_render.c - skyrender, the example render client, against the real
 * skyd on a private socket, as three cases (argv[1]):
 *   sky      its frame's sky pixels match `skyctl render` for the same view
 *            and generation (perspective, a tile of a wall, the dome master);
 *   wall     three skyrender processes as the three tiles of one wall meet
 *            at their shared edges (and make the one-process wall);
 *   restart  while it draws without end, skyd restarts on the same socket
 *            and changes its layout: frames go on, and follow the new sky;
 *   panorama the tiles of a wall drawing at once read one panorama (views
 *            of form panorama at the same texels of the slot), the dome
 *            master one panorama of the full circle, and --aerial volume
 *            still draws from volumes, close to the panorama's frame; with
 *            skyd's eight views taken, skyrender refused a view draws with
 *            the state's camera;
 *   window   --window on an Xvfb shows the bytes the PNG holds (skipped
 *            without Xvfb or libxcb);
 *   clouds   with a METAR's broken layer, skyrender's sky pixels match
 *            libsky's CPU march of the same slot (sky_sample_clouds), three
 *            tiles of a wall meet at their edges, and it keeps drawing
 *            while the layers change.
 * Frames are compared as the 8-bit sRGB PNGs both programs write with
 * dump_png's encoding at the same fixed exposure. */
#include <math.h>
#include <png.h>
#include <poll.h>
#include <sys/stat.h>
#include <time.h>

#include "daemon_harness.h"
#include "dump.h"
#include "frame_kit.h"
#include "sky.h"
#include "skysample.h"
#include "test.h"
#include "vk_or_skip.h"

/* Tables of a fair size: large enough that the sky is smooth at these
 * frame sizes, small enough for lavapipe on two cores. */
static const char *const tables[] = {
	"transmittance_width=128", "transmittance_height=32", "multiscatter_width=16",
	"multiscatter_height=16", "multiscatter_dirs=2", "skyview_width=96", "skyview_height=54",
	"aerial_width=16", "aerial_height=16", "aerial_depth=16", "sun_elevation_deg=12",
	"sun_azimuth_deg=160", NULL
};
static const char *const exposure = "0.0002";	/* about 1 / the sky's radiance, cd/m2 */
/* A frame of the wall drawn through the panorama against one through the
 * wall camera's own volume: the panorama is resampled aerial perspective
 * (skyd's accuracy goal for it, tests/numerical/test_views.c), a few percent of the
 * terrain's in-scattering at most, so a few levels on the terrain and
 * nothing on the sky. */
#define PANORAMA_VS_VOLUME_MEAN 1.0
#define PANORAMA_VS_VOLUME_MAX 8
static struct daemon d;

/* skyrender with our socket, an exposure and args; the frame to path, its
 * output and log into out (NULL: the log to our stderr). */
static long skyrender_log(const char *path, const char *const *args, char *out, size_t size)
{
	const char *argv[40] = { SKYRENDER_BINARY, "--socket", d.sock, "--exposure", exposure,
				 "--out", path };
	int n = 7;
	char buf[4096];
	for (int i = 0; args[i] && n < 39; i++)
		argv[n++] = args[i];
	int code = run(argv, out != NULL, out ? out : buf, out ? size : sizeof(buf));
	if (out)
		printf("%s", out);
	if (code != 0) {
		FAIL("skyrender exited %d", code);
		return -1;
	}
	return generation_of(out ? out : buf);
}

static long skyrender(const char *path, const char *const *args)
{
	return skyrender_log(path, args, NULL, 0);
}

static long skyctl_render(const char *path, const char *const *args)
{
	const char *argv[40] = { SKYCTL_BINARY, "--socket", d.sock, "render", "--exposure",
				 exposure };
	int n = 6;
	char out[4096];
	for (int i = 0; args[i] && n < 38; i++)
		argv[n++] = args[i];
	argv[n++] = path;
	int code = run(argv, false, out, sizeof(out));
	if (code != 0) {
		FAIL("skyctl render exited %d", code);
		return -1;
	}
	return generation_of(out);
}

/* Compares b with the sub-rectangle of a at (x0, y0). The tolerance: both
 * are 8-bit sRGB of the same radiance through the same exposure and curve;
 * the GPU reads the tables through the texture units (8 bits of sub-texel
 * weight: at most 1/512 of a neighbouring texel's difference) and computes
 * directions in float where libsky uses double, which moves a value by
 * well under one level, so 1 level may come from rounding at the 8-bit
 * step and 2 is the bound; only pixels whose centre lies on the rim of the
 * sun's or the moon's disk (inside in one, outside in the other, by a
 * float's rounding of the direction) may differ more: at most 0.1 % of the
 * pixels, a handful along a rim 0.27 degrees across. */
static void compare(const char *what, const struct image *a, uint32_t x0, uint32_t y0,
		    const struct image *b)
{
	size_t over = 0, n = (size_t)b->w * b->h;
	int worst = 0;
	double sum = 0.0;
	for (uint32_t y = 0; y < b->h; y++)
		for (uint32_t x = 0; x < b->w; x++) {
			int m = 0;
			for (int c = 0; c < 3; c++) {
				int e = abs(px(a, x0 + x, y0 + y, c) - px(b, x, y, c));
				m = e > m ? e : m;
				sum += e;
			}
			over += m > 2;
			worst = m > worst ? m : worst;
		}
	printf("%s: %zu pixels, mean |diff| %.4f levels, max %d, %zu over 2 levels\n", what, n,
	       sum / (3.0 * n), worst, over);
	CHECK(over * 1000 <= n);
	CHECK(sum / (3.0 * n) < 0.05);
}

static int case_sky(const char *dir)
{
	char a[256], b[256];
	struct image ia = { 0 }, ib = { 0 };

	/* A perspective view facing the sun, disks included, terrain off. */
	snprintf(a, sizeof(a), "%s/skyctl.png", dir);
	snprintf(b, sizeof(b), "%s/skyrender.png", dir);
	long ga = skyctl_render(a, (const char *const[]){ "--view", "perspective", "--size",
		"256x144", "--yaw", "165", "--pitch", "8", "--vfov", "50", NULL });
	long gb = skyrender(b, (const char *const[]){ "--no-terrain", "--size", "256x144",
		"--yaw", "165", "--pitch", "8", "--fov", "50", NULL });
	printf("perspective: skyctl generation %ld, skyrender generation %ld\n", ga, gb);
	CHECK(ga > 0 && ga == gb);
	/* --frames 0 is refused (it once meant --forever), with what to use. */
	char said[512];
	const char *zero[] = { SKYRENDER_BINARY, "--socket", d.sock, "--frames", "0", "--out", b, NULL };
	CHECK(run(zero, true, said, sizeof(said)) == 2 && strstr(said, "--forever"));
	if (image_read(a, &ia) == 0 && image_read(b, &ib) == 0) {
		CHECK(ia.w == 256 && ib.w == 256 && ia.h == 144 && ib.h == 144);
		compare("perspective", &ia, 0, 0, &ib);
	} else {
		FAIL("frames not readable");
	}
	free(ib.rgb);
	ib.rgb = NULL;

	/* The right tile of a 2 x 1 wall is the right half of the whole view. */
	gb = skyrender(b, (const char *const[]){ "--no-terrain", "--size", "128x144", "--yaw",
		"165", "--pitch", "8", "--fov", "50", "--grid", "2x1", "--tile", "1,0", NULL });
	CHECK(gb == ga);
	if (ia.rgb && image_read(b, &ib) == 0)
		compare("tile 1,0 of 2x1", &ia, 128, 0, &ib);
	else
		FAIL("tile not readable");
	free(ia.rgb);
	free(ib.rgb);
	ia.rgb = ib.rgb = NULL;

	/* The dome master, front at azimuth 160 (the sun's). */
	ga = skyctl_render(a, (const char *const[]){ "--view", "fisheye", "--size", "192x192",
		"--yaw", "160", NULL });
	gb = skyrender(b, (const char *const[]){ "--no-terrain", "--fisheye", "--size", "192x192",
		"--yaw", "160", NULL });
	CHECK(ga > 0 && ga == gb);
	if (image_read(a, &ia) == 0 && image_read(b, &ib) == 0)
		compare("fisheye", &ia, 0, 0, &ib);
	else
		FAIL("fisheye frames not readable");
	free(ia.rgb);
	free(ib.rgb);
	return 0;
}

/* Across each seam between tiles (the last column of tile k, the first of
 * tile k + 1: adjacent directions of the wall) the step must be the step
 * the one-process wall has between the same two columns, to 2 levels (the
 * rounding of each of the four values at the 8-bit step, see compare()),
 * and on the whole as good as exact (a mean under 0.03 level: a tile off by
 * one pixel's direction departs by about the sky's step between pixels,
 * 1 level in a third of the rows, 0.07 on the mean). Returns the largest
 * departure and the mean. */
static int seam_departure(const struct image *const t[3], const struct image *wall, uint32_t w,
			  uint32_t h, double *ret_mean)
{
	int worst = 0;
	double sum = 0.0;
	for (uint32_t k = 0; k + 1 < 3; k++)
		for (uint32_t y = 0; y < h; y++)
			for (int c = 0; c < 3; c++) {
				int step = px(t[k + 1], 0, y, c) - px(t[k], w - 1, y, c);
				int want = px(wall, (k + 1) * w, y, c) - px(wall, (k + 1) * w - 1, y, c);
				int e = abs(step - want);
				worst = e > worst ? e : worst;
				sum += e;
			}
	*ret_mean = sum / (2.0 * h * 3);
	return worst;
}

static int case_wall(const char *dir)
{
	const uint32_t w = 96, h = 128;
	char path[4][256], tile[8];
	struct image im[4] = { 0 };
	long gen[4];

	/* Terrain on: the tiles' height field and aerial perspective must
	 * continue too. Each process registers the wall's camera as its view. */
	for (int k = 0; k < 4; k++) {
		snprintf(path[k], sizeof(path[k]), "%s/tile%d.png", dir, k);
		snprintf(tile, sizeof(tile), "%d,0", k);
		gen[k] = k < 3 ?
			skyrender(path[k], (const char *const[]){ "--size", "96x128", "--yaw", "170",
				"--pitch", "4", "--fov", "40", "--grid", "3x1", "--tile", tile, NULL }) :
			skyrender(path[k], (const char *const[]){ "--size", "288x128", "--yaw", "170",
				"--pitch", "4", "--fov", "40", NULL });
		if (image_read(path[k], &im[k]) < 0) {
			FAIL("%s not readable", path[k]);
			return 0;
		}
	}
	/* Each process adds its camera view (a new generation), all the same. */
	printf("generations: %ld %ld %ld, whole wall %ld\n", gen[0], gen[1], gen[2], gen[3]);
	CHECK(gen[0] > 0 && gen[1] > 0 && gen[2] > 0 && gen[3] > 0);
	const struct image *t[3] = { &im[0], &im[1], &im[2] };
	double mean;
	int seam = seam_departure(t, &im[3], w, h, &mean);
	printf("step across the seams against the whole wall's: departure max %d, mean %.4f levels\n",
	       seam, mean);
	/* Every tile reads its eye point's panorama at the same directions as
	 * the whole wall does: the steps across the seams are the wall's
	 * exactly (lavapipe rasterises the tiles' terrain to the same values). */
	CHECK(seam == 0);
	CHECK(mean == 0.0);
	/* And each tile is its part of the wall drawn by one process: the
	 * same directions, the same terrain, the same aerial perspective. */
	for (int k = 0; k < 3; k++) {
		char what[32];
		snprintf(what, sizeof(what), "tile %d,0 vs whole wall", k);
		compare(what, &im[3], k * w, 0, &im[k]);
	}
	for (int k = 0; k < 4; k++)
		free(im[k].rgb);
	return 0;
}

static int stream_start(struct frame_stream *st, const char *out)
{
	const char *argv[] = { SKYRENDER_BINARY, "--socket", d.sock, "--exposure", exposure,
			       "--size", "64x36", "--forever", "--interval", "20", "--out", out,
			       NULL };
	return frame_stream_start(st, argv, true);
}

/* Sends one request to skyd; the generation its reply names, or -1. */
/* Sends line and returns the generation it names once that generation
 * (or a newer one) is published, so that a client started next draws it. */
static long request(const char *line)
{
	struct conn c;
	char reply[4096];
	long g = -1;
	if (conn_open(&c, d.sock) == 0 && conn_request(&c, "subscribe events=1", reply, sizeof(reply)) == 0 &&
	    conn_request(&c, "status", reply, sizeof(reply)) == 0) {
		uint64_t published = reply_u64(reply, "generation");
		if (conn_request(&c, line, reply, sizeof(reply)) == 0) {
			g = (long)reply_u64(reply, "generation");
			if ((uint64_t)g > published && conn_wait_generation(&c, (uint64_t)g) < 0)
				g = -1;
		}
	}
	conn_close(&c);
	return g;
}

static int case_restart(const char *dir)
{
	char out[256];
	struct frame_stream st;
	snprintf(out, sizeof(out), "%s/live.png", dir);
	if (stream_start(&st, out) < 0) {
		FAIL("cannot start skyrender");
		return 0;
	}
	long g0 = frame_stream_next(&st, HARNESS_TIMEOUT_MS);
	CHECK(g0 > 0);

	/* A new layout (another sky-view size): a new region, new images. */
	long g1 = request("set skyview_width=48");
	CHECK(g1 > g0);
	long g = frame_stream_until(&st, g1, HARNESS_TIMEOUT_MS);
	printf("layout change: generation %ld, skyrender drew %ld\n", g1, g);
	CHECK(g >= g1);

	/* skyd stops: frames go on with the last tables. */
	daemon_stop(&d, SIGTERM);
	long down[3];
	for (int i = 0; i < 3; i++)
		down[i] = frame_stream_next(&st, HARNESS_TIMEOUT_MS);
	printf("skyd down: frames of generation %ld %ld %ld\n", down[0], down[1], down[2]);
	CHECK(down[0] >= g1 && down[1] == down[0] && down[2] == down[0]);

	/* A new skyd on the same socket, with another sun; its generations may
	 * start again from 1, so change it until its generation passes the
	 * last one drawn, and wait for a frame of that. */
	CHECK(daemon_start_in(&d, d.dir, tables) == 0);
	long g2 = -1;
	for (int i = 0; i < 1000 && g2 <= down[0]; i++) {
		char line[64];
		snprintf(line, sizeof(line), "set sun_elevation_deg=%d", 30 + i % 40);
		g2 = request(line);
		if (g2 < 0)
			break;
	}
	CHECK(g2 > down[0]);
	g = frame_stream_until(&st, g2, HARNESS_TIMEOUT_MS);
	printf("skyd restarted: generation %ld, skyrender drew %ld\n", g2, g);
	CHECK(g >= g2);

	CHECK(frame_stream_stop(&st) == 0);
	return 0;
}

/* How many views `view list` shows of skyrender process pid, and how many
 * of them are of form (volume or panorama). */
static int views_of(pid_t pid, const char *form, int *ret_of_form)
{
	struct conn c;
	char reply[8192], name[64], want[64];
	int n = 0, f = 0;
	snprintf(name, sizeof(name), " name=skyrender-%d-", (int)pid);
	snprintf(want, sizeof(want), " form=%s ", form);
	if (conn_open(&c, d.sock) == 0 && conn_request(&c, "view list", reply, sizeof(reply)) == 0) {
		for (char *line = strtok(reply, "\n"); line; line = strtok(NULL, "\n"))
			if (strstr(line, name)) {
				n++;
				f += strstr(line, want) != NULL;
			}
	}
	conn_close(&c);
	*ret_of_form = f;
	return n;
}

/* The entries of skyrender's views (named skyrender-*) in the newest slot,
 * read through libsky, into ret (at most max); ret_valid: bit i for ret[i]
 * valid in that slot. Their count, or -1. */
static int slot_views(struct sky_shm_view *ret, uint32_t *ret_valid, uint32_t max)
{
	sky_client *c = NULL;
	struct sky_view v;
	uint32_t seen = 0;
	int n = -1;
	if (sky_connect(d.sock, &c) == 0 &&
	    sky_subscribe(c, SKY_TABLE_BIT(SKY_TABLE_AERIAL), 0) == 0 &&
	    sky_wait(c, 0, HARNESS_TIMEOUT_MS, &seen) >= 0 && sky_view_begin(c, &v) == 0) {
		n = 0;
		*ret_valid = 0;
		for (uint32_t i = 0; i < v.slot->n_views && i < SKY_SHM_MAX_VIEWS; i++) {
			if (strncmp(v.slot->views[i].name, "skyrender-", 10) || (uint32_t)n >= max)
				continue;
			if (v.slot->valid_views & (1u << i))
				*ret_valid |= 1u << n;
			ret[n++] = v.slot->views[i];
		}
		if (!sky_view_end(c, &v))
			n = -1;
	}
	sky_disconnect(c);
	return n;
}

/* The mean and the largest difference (levels) between two frames of the
 * same size. */
static double frame_difference(const struct image *a, const struct image *b, int *ret_max)
{
	double sum = 0.0;
	int worst = 0;
	for (size_t i = 0; i < (size_t)a->w * a->h * 3; i++) {
		int e = abs(a->rgb[i] - b->rgb[i]);
		sum += e;
		worst = e > worst ? e : worst;
	}
	*ret_max = worst;
	return sum / ((double)a->w * a->h * 3);
}

/* Three tiles of a wall drawing at once: each process's one view is of
 * form panorama, and skyd serves them one panorama (the same texels of
 * the slot), which each process says it reads. */
static void panorama_wall(const char *dir)
{
	struct frame_stream st[3];
	char out[3][256], tile[3][8];
	for (int k = 0; k < 3; k++) {
		snprintf(out[k], sizeof(out[k]), "%s/live-tile%d.png", dir, k);
		snprintf(tile[k], sizeof(tile[k]), "%d,0", k);
		const char *argv[] = { SKYRENDER_BINARY, "--socket", d.sock, "--exposure", exposure,
				       "--size", "96x128", "--yaw", "170", "--pitch", "4", "--fov",
				       "40", "--grid", "3x1", "--tile", tile[k], "--forever",
				       "--interval", "20", "--out", out[k], NULL };
		CHECK(frame_stream_start(&st[k], argv, true) == 0);
	}
	for (int k = 0; k < 3; k++)
		CHECK(frame_stream_next(&st[k], HARNESS_TIMEOUT_MS) > 0);
	for (int k = 0; k < 3; k++) {
		int pano, n = views_of(st[k].pid, "panorama", &pano);
		printf("tile %d: %d views, %d of form panorama\n", k, n, pano);
		CHECK(n == 1 && pano == 1);
	}
	struct sky_shm_view v[SKY_SHM_MAX_VIEWS];
	uint32_t valid = 0;
	int n = slot_views(v, &valid, SKY_SHM_MAX_VIEWS);
	printf("slot: %d skyrender views, valid 0x%x\n", n, valid);
	CHECK(n == 3 && valid == 7);
	for (int i = 0; i < n && i < 3; i++) {
		printf("  %s: form %u, panorama at %llu, %ux%ux%u, full circle %u\n", v[i].name,
		       v[i].form, (unsigned long long)v[i].panorama.offset, v[i].panorama.width,
		       v[i].panorama.height, v[i].panorama.depth, v[i].panorama.full_circle);
		CHECK(v[i].form == SKY_VIEW_PANORAMA && v[i].panorama.width > 0);
		CHECK(v[i].panorama.offset == v[0].panorama.offset);
	}
	/* Our views see a wall's arc, not the zenith: an arc of azimuths. */
	for (int k = 0; k < 3; k++) {
		frame_stream_next(&st[k], HARNESS_TIMEOUT_MS);
		CHECK(strstr(st[k].log, "a panorama of an arc") != NULL);
		CHECK(frame_stream_stop(&st[k]) == 0);
	}
}

/* The dome master: one view of form panorama, of the full circle. */
static void panorama_dome(const char *dir)
{
	struct frame_stream st;
	char out[256];
	snprintf(out, sizeof(out), "%s/live-dome.png", dir);
	const char *argv[] = { SKYRENDER_BINARY, "--socket", d.sock, "--exposure", exposure,
			       "--size", "96x96", "--fisheye", "--forever", "--interval", "20",
			       "--out", out, NULL };
	CHECK(frame_stream_start(&st, argv, true) == 0);
	CHECK(frame_stream_next(&st, HARNESS_TIMEOUT_MS) > 0);
	int pano, n = views_of(st.pid, "panorama", &pano);
	printf("dome: %d views, %d of form panorama\n", n, pano);
	CHECK(n == 1 && pano == 1);
	struct sky_shm_view v[SKY_SHM_MAX_VIEWS];
	uint32_t valid = 0;
	CHECK(slot_views(v, &valid, SKY_SHM_MAX_VIEWS) == 1 && valid == 1);
	CHECK(v[0].form == SKY_VIEW_PANORAMA && v[0].panorama.full_circle == 1);
	frame_stream_next(&st, HARNESS_TIMEOUT_MS);
	CHECK(strstr(st.log, "a panorama of the full circle") != NULL);
	CHECK(frame_stream_stop(&st) == 0);
}

/* --aerial volume: the views are volumes (a dome: four), and the frame
 * differs from the panorama's only by the panorama's resampling. */
static void volume_option(const char *dir)
{
	char a[256], b[256], log[8192];
	struct image ia = { 0 }, ib = { 0 };
	snprintf(a, sizeof(a), "%s/wall-panorama.png", dir);
	snprintf(b, sizeof(b), "%s/wall-volume.png", dir);
	long ga = skyrender_log(a, (const char *const[]){ "--size", "288x128", "--yaw", "170",
		"--pitch", "4", "--fov", "40", NULL }, log, sizeof(log));
	CHECK(ga > 0 && strstr(log, "a panorama of an arc") != NULL);
	long gb = skyrender_log(b, (const char *const[]){ "--size", "288x128", "--yaw", "170",
		"--pitch", "4", "--fov", "40", "--aerial", "volume", NULL }, log, sizeof(log));
	CHECK(gb > 0 && strstr(log, "a volume of") != NULL && !strstr(log, "panorama"));
	if (image_read(a, &ia) == 0 && image_read(b, &ib) == 0 && ia.w == ib.w && ia.h == ib.h) {
		int worst;
		double mean = frame_difference(&ia, &ib, &worst);
		printf("wall, panorama vs volume: mean |diff| %.4f levels, max %d\n", mean, worst);
		CHECK(mean < PANORAMA_VS_VOLUME_MEAN && worst <= PANORAMA_VS_VOLUME_MAX);
	} else {
		FAIL("panorama and volume frames not readable");
	}
	free(ia.rgb);
	free(ib.rgb);
	gb = skyrender_log(b, (const char *const[]){ "--size", "96x96", "--fisheye", "--aerial",
		"volume", NULL }, log, sizeof(log));
	CHECK(gb > 0 && strstr(log, "aerial perspective 3: view") != NULL &&
	      !strstr(log, "panorama"));
}

/* With skyd's eight views taken (by one client's connection: eight
 * skyrenders drawing at once cost minutes under the sanitizers and test
 * nothing more), a skyrender is refused its view and draws with the
 * state's camera's volume. */
static void view_refused(const char *dir)
{
	struct conn c;
	char line[64], reply[512], path[256], log[8192];
	CHECK(conn_open(&c, d.sock) == 0);
	for (uint32_t k = 0; k < SKY_SHM_MAX_VIEWS; k++) {
		snprintf(line, sizeof(line), "view add name=taken-%u yaw_deg=%u", k, 45 * k);
		CHECK(conn_request(&c, line, reply, sizeof(reply)) == 0);
	}
	snprintf(path, sizeof(path), "%s/ninth.png", dir);
	long g = skyrender_log(path, (const char *const[]){ "--size", "64x36", NULL }, log,
			       sizeof(log));
	CHECK(g > 0 && strstr(log, "view add: ") != NULL && strstr(log, "limit reached") != NULL &&
	      strstr(log, "aerial perspective 0: the state's camera's volume") != NULL);
	conn_close(&c);
}

static int case_panorama(const char *dir)
{
	panorama_wall(dir);
	panorama_dome(dir);
	volume_option(dir);
	view_refused(dir);
	return 0;
}

#ifdef TEST_RENDER_XCB
#include <xcb/xcb.h>

/* Starts Xvfb on a display it picks (-displayfd: it writes the number
 * once it accepts clients); the number, or -1 (77 when there is no Xvfb). */
static int xvfb_start(pid_t *ret_pid)
{
	int p[2];
	if (access(XVFB_BINARY, X_OK) < 0) {
		printf("skipped: no %s (Debian's xvfb)\n", XVFB_BINARY);
		exit(77);
	}
	if (pipe(p) < 0)
		return -1;
	pid_t pid = fork();
	if (pid == 0) {
		char fd[16];
		snprintf(fd, sizeof(fd), "%d", p[1]);
		close(p[0]);
		int null = open("/dev/null", O_WRONLY);
		dup2(null, 2);
		execl(XVFB_BINARY, XVFB_BINARY, "-displayfd", fd, "-nolisten", "tcp", "-screen", "0",
		      "320x240x24", (char *)NULL);
		_exit(127);
	}
	close(p[1]);
	/* Read up to the newline: Xvfb dies if the pipe closes before it has
	 * written all of it. */
	char buf[16] = "";
	size_t n = 0;
	struct pollfd pf = { p[0], POLLIN, 0 };
	while (n + 1 < sizeof(buf) && !memchr(buf, '\n', n) && poll(&pf, 1, HARNESS_TIMEOUT_MS) > 0) {
		ssize_t k = read(p[0], buf + n, sizeof(buf) - 1 - n);
		if (k <= 0)
			break;
		n += (size_t)k;
	}
	close(p[0]);
	*ret_pid = pid;
	return memchr(buf, '\n', n) ? atoi(buf) : -1;
}

/* The top-left w x h of the root window as 8-bit RGB (a 24-bit screen,
 * little-endian BGRX), or NULL. */
static uint8_t *grab(const char *display, uint32_t w, uint32_t h)
{
	xcb_connection_t *c = xcb_connect(display, NULL);
	uint8_t *rgb = NULL;
	if (!xcb_connection_has_error(c)) {
		xcb_screen_t *s = xcb_setup_roots_iterator(xcb_get_setup(c)).data;
		xcb_get_image_reply_t *r = xcb_get_image_reply(c, xcb_get_image(c,
			XCB_IMAGE_FORMAT_Z_PIXMAP, s->root, 0, 0, (uint16_t)w, (uint16_t)h, ~0u), NULL);
		if (r && xcb_get_image_data_length(r) >= (int)(w * h * 4) && (rgb = malloc(w * h * 3))) {
			const uint8_t *px4 = xcb_get_image_data(r);
			for (size_t i = 0; i < (size_t)w * h; i++) {
				rgb[3 * i] = px4[4 * i + 2];
				rgb[3 * i + 1] = px4[4 * i + 1];
				rgb[3 * i + 2] = px4[4 * i];
			}
		}
		free(r);
	}
	xcb_disconnect(c);
	return rgb;
}

/* skyrender --window on an Xvfb: the window shows what the PNG holds. */
static int case_window(const char *dir)
{
	pid_t xvfb;
	int n = xvfb_start(&xvfb);
	char display[16], out[256];
	struct frame_stream st;
	struct image im = { 0 };
	if (n < 0) {
		FAIL("Xvfb did not start");
		return 0;
	}
	snprintf(display, sizeof(display), ":%d", n);
	snprintf(out, sizeof(out), "%s/window.png", dir);
	setenv("DISPLAY", display, 1);
	const char *argv[] = { SKYRENDER_BINARY, "--socket", d.sock, "--exposure", exposure,
			       "--size", "64x36", "--window", "--interval", "20", "--out", out, NULL };
	CHECK(frame_stream_start(&st, argv, true) == 0);
	long g = frame_stream_next(&st, HARNESS_TIMEOUT_MS), g1 = frame_stream_next(&st, HARNESS_TIMEOUT_MS);
	CHECK(g > 0 && g1 == g);
	uint8_t *shown = grab(display, 64, 36);
	CHECK(shown != NULL);
	if (shown && image_read(out, &im) == 0) {
		size_t differ = 0;
		for (size_t i = 0; i < 64 * 36 * 3; i++)
			differ += shown[i] != im.rgb[i];
		printf("window: %zu of %d values differ from the PNG\n", differ, 64 * 36 * 3);
		CHECK(differ == 0);
	} else {
		FAIL("nothing to compare");
	}
	free(shown);
	free(im.rgb);
	CHECK(frame_stream_stop(&st) == 0);
	kill(xvfb, SIGTERM);
	waitpid(xvfb, NULL, 0);
	return 0;
}
#else
static int case_window(const char *dir)
{
	(void)dir;
	printf("skipped: built without libxcb\n");
	exit(77);
}
#endif

/* The unit ENU direction of pixel (x, y) of a w x h perspective frame
 * (yaw, pitch, vertical field of view in degrees): frame.glsl's
 * view_direction of a 1 x 1 wall. */
static void pixel_direction(uint32_t x, uint32_t y, uint32_t w, uint32_t h, double yaw_deg, double pitch_deg,
			    double vfov_deg, double ret[3])
{
	double yaw = yaw_deg * SKYMAP_PI / 180.0, f[3], r[3] = { cos(yaw), -sin(yaw), 0.0 }, u[3];
	skysample_direction(pitch_deg * SKYMAP_PI / 180.0, yaw, f);
	u[0] = r[1] * f[2] - r[2] * f[1];
	u[1] = r[2] * f[0] - r[0] * f[2];
	u[2] = r[0] * f[1] - r[1] * f[0];
	double t = tan(0.5 * vfov_deg * SKYMAP_PI / 180.0), n = 0.0;
	double sx = (2.0 * (x + 0.5) / w - 1.0) * t * ((double)w / h), sy = (1.0 - 2.0 * (y + 0.5) / h) * t;
	for (int k = 0; k < 3; k++) {
		ret[k] = f[k] + sx * r[k] + sy * u[k];
		n += ret[k] * ret[k];
	}
	for (int k = 0; k < 3; k++)
		ret[k] /= sqrt(n);
}

/* The frame of skyrender at path (drawn in generation g, 32 cloud steps)
 * against sky_sample_clouds of that generation's slot, encoded as the PNG
 * is; the share of its pixels with cloud (transmittance < 0.9). */
static double compare_clouds(sky_client *c, const char *path, long g, uint32_t w, uint32_t h)
{
	struct image im;
	struct sky_view v;
	struct sky_cloud_params p = { .steps = 32, .light_steps = 0, .jitter = 0.5 };
	long cloudy = 0, over = 0, n = 0, refused = 0;
	double sum = 0.0, worst = 0.0;
	uint32_t seen = 0;
	int rc = image_read(path, &im);
	/* The slot skyrender drew, with every table (our subscription's). */
	while (rc == 0 && (rc = sky_wait(c, seen, HARNESS_TIMEOUT_MS, &seen)) >= 0 &&
	       (rc = sky_view_begin(c, &v)) == 0) {
		if ((long)v.generation >= g && (v.valid_tables & SKY_TABLES_ALL) == SKY_TABLES_ALL)
			break;
		sky_view_end(c, &v);
	}
	if (rc < 0) {
		FAIL("cannot read %s or the slot: %d", path, rc);
		return 0.0;
	}
	CHECK_EQ((long)v.generation, g);
	CHECK(im.w == w && im.h == h);
	sky_sample_ambient(&v, p.ambient_lx);	/* skyrender's skylight */
	for (uint32_t y = 0; y < h && im.w == w; y++)
		for (uint32_t x = 0; x < w; x++) {
			double d3[3], rgb[3], t;
			pixel_direction(x, y, w, h, 160.0, 25.0, 60.0, d3);
			double el = asin(d3[2]) * 180.0 / SKYMAP_PI, az = atan2(d3[0], d3[1]) * 180.0 / SKYMAP_PI;
			if (el < 0.5)
				continue;	/* the sky only (--no-terrain draws the ground's sky too) */
			if (sky_sample_clouds(&v, &p, el, az, INFINITY, SKY_SAMPLE_CLOUD_COMPOSITE, rgb, &t, NULL) < 0) {
				refused++;
				continue;
			}
			cloudy += t < 0.9;
			for (int k = 0; k < 3; k++) {
				double e = fabs((double)dump_tonemap_srgb8((float)rgb[k], strtod(exposure, NULL),
									     DUMP_CURVE_ACES) - px(&im, x, y, k));
				sum += e;
				worst = e > worst ? e : worst;
				over += e > 3.0;
			}
			n++;
		}
	CHECK(sky_view_end(c, &v));
	CHECK_EQ(refused, 0);
	free(im.rgb);
	printf("clouds: %ld sky pixels, %ld cloudy; 8-bit error mean %.3f, max %.0f, %ld channels over 3\n", n,
	       cloudy, n ? sum / (3.0 * n) : 0.0, worst, over);
	/* Tolerance: the device's float march against the C's double is
	 * within 3e-3 of the radiance (test_glsl_cloud_march), a third of a
	 * level of 8 bits at this exposure, so a channel rounds to a
	 * neighbouring level at most; the texture unit's filter of the
	 * tables and the shadow map (8-bit weights on lavapipe) may move a
	 * pixel at a cloud's sharp edge by more, rarely. Measured on
	 * lavapipe: mean 0.000, largest 1. */
	CHECK(n > 0 && sum / (3.0 * n) < 0.1);
	CHECK(over * 100 <= n);
	return n ? (double)cloudy / n : 0.0;
}

/* Three tiles of a wall with the clouds (and their shadows on the
 * terrain) meet at their edges as the one-process wall does. */
static void clouds_wall(const char *dir)
{
	char path[4][PATH_MAX], tile[8];
	struct image im[4] = { 0 };
	for (int k = 0; k < 4; k++) {
		snprintf(path[k], sizeof(path[k]), "%s/cwall%d.png", dir, k);
		snprintf(tile, sizeof(tile), "%d,0", k);
		long g = k < 3 ? skyrender(path[k], (const char *const[]){ "--size", "40x48", "--yaw", "170",
				"--pitch", "8", "--fov", "40", "--grid", "3x1", "--tile", tile, NULL }) :
			       skyrender(path[k], (const char *const[]){ "--size", "120x48", "--yaw", "170",
				"--pitch", "8", "--fov", "40", NULL });
		if (g < 0 || image_read(path[k], &im[k]) < 0) {
			FAIL("%s not readable", path[k]);
			return;
		}
	}
	const struct image *t[3] = { &im[0], &im[1], &im[2] };
	double mean;
	int seam = seam_departure(t, &im[3], 40, 48, &mean);
	printf("clouds: step across the seams against the whole wall's: departure max %d, mean %.4f levels\n",
	       seam, mean);
	/* The march takes the same directions in a tile as in the wall. */
	CHECK(seam <= 2 && mean < 0.03);
	for (int k = 0; k < 3; k++)
		compare("clouds: tile vs whole wall", &im[3], (uint32_t)k * 40, 0, &im[k]);
	for (int k = 0; k < 4; k++)
		free(im[k].rgb);
}

static int case_clouds(const char *dir)
{
	char path[PATH_MAX];
	snprintf(path, sizeof(path), "%s/clouds.png", dir);
	const char *const args[] = { "--no-terrain", "--no-disks", "--size", "64x36", "--yaw", "160", "--pitch",
				     "25", "--cloud-steps", "32", NULL };
	sky_client *c = NULL;
	if (sky_connect(d.sock, &c) < 0 || sky_subscribe(c, SKY_TABLES_ALL | SKY_TABLES_CLOUDS, 0) < 0) {
		FAIL("cannot subscribe");
		return 1;
	}
	/* The clock stopped: the wind moves the field with simulated time, and
	 * the comparison needs the slot skyrender drew. */
	long g0 = request("set time_rate=0 metar=\"EGLL 241250Z 27015KT 9999 BKN030 12/06 Q1018\"");
	CHECK(g0 > 0);
	long g = skyrender(path, args);
	CHECK(g >= g0);
	double share = compare_clouds(c, path, g, 64, 36);
	sky_disconnect(c);
	CHECK(share > 0.05 && share < 0.95);
	clouds_wall(dir);
	/* Layers changing under a client that draws without end: its frames
	 * follow every change, and the last one has the new layers. */
	struct frame_stream st;
	char out[PATH_MAX];
	snprintf(out, sizeof(out), "%s/live.png", dir);
	if (stream_start(&st, out) < 0) {
		FAIL("cannot start skyrender");
		return 1;
	}
	long g1 = request("set metar=\"EGLL 241250Z 27015KT 9999 OVC010 12/06 Q1018\"");
	CHECK(g1 > g0 && frame_stream_until(&st, g1, HARNESS_TIMEOUT_MS) >= g1);
	long g2 = request("set metar=\"EGLL 241250Z 27015KT 9999 FEW040 12/06 Q1018\"");
	CHECK(g2 > g1 && frame_stream_until(&st, g2, HARNESS_TIMEOUT_MS) >= g2);
	CHECK(frame_stream_stop(&st) == 0);
	return 0;
}

int main(int argc, char **argv)
{
	const char *which = argc > 1 ? argv[1] : "";
	int (*fn)(const char *) = !strcmp(which, "sky") ? case_sky :
				   !strcmp(which, "wall") ? case_wall :
				   !strcmp(which, "restart") ? case_restart :
				   !strcmp(which, "panorama") ? case_panorama :
				   !strcmp(which, "window") ? case_window :
				   !strcmp(which, "clouds") ? case_clouds : NULL;
	if (!fn) {
		fprintf(stderr, "usage: test_render sky|wall|restart|panorama|window|clouds\n");
		return 2;
	}
	eng_free(vk_or_skip());
	if (daemon_start(&d, tables) < 0)
		return 1;
	fn(d.dir);
	daemon_cleanup(&d);
	return test_report(which);
}

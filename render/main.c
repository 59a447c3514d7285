/* main.c - skyrender, the example render client of skyd: it subscribes to
 * the tables, uploads them to Vulkan images when a generation changes,
 * and draws frames of the sky, the sun and moon disks and a height field
 * under aerial perspective with the GLSL library; headless, as PNG files.
 * Options make it one tile of a wall or a dome master. Its aerial
 * perspective comes from its eye point's panorama (a view of form
 * panorama, which every tile of a wall shares) or a volume of its own. */
#include <errno.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dump.h"
#include "proto.h"
#include "rvk.h"
#include "sky.h"
#include "skycloudmarch.h"
#include "window.h"

enum { EXIT_OK = 0, EXIT_FAILED = 1, EXIT_USAGE = 2 };

#define FIRST_TABLES_TIMEOUT_MS 60000	/* the first generation with the tables */
#define NEEDED_TABLES (SKY_TABLE_BIT(SKY_TABLE_TRANSMITTANCE) | SKY_TABLE_BIT(SKY_TABLE_SKYVIEW))

/* How skyrender asks skyd for its aerial perspective (`view add form=`). */
enum aerial_form {
	AERIAL_PANORAMA = 0,		/* its eye point's panorama: one march for a wall */
	AERIAL_VOLUME = 1,		/* a volume per camera, a dome's four quarters */
};

struct opts {
	const char *socket;
	const char *out;
	struct rvk_options rvk;
	double exposure;		/* <= 0: automatic, as skyctl render */
	long frames;			/* 0 (--forever): until SIGINT or SIGTERM (or the window closes) */
	enum aerial_form aerial;
	bool window;			/* show the frames in an X11 window */
	bool out_given;			/* --out: with --window, write PNGs too */
	bool frames_given;
	int interval_ms;		/* between frames */
};

/* What the loop knows of skyd. */
struct link {
	sky_client *c;
	bool connected;
	uint32_t n_views;		/* our views: 1, or RVK_MAX_AERIAL for a dome of volumes */
	bool view_added[RVK_MAX_AERIAL];	/* registered on this connection */
	int aerial_said[RVK_MAX_AERIAL];	/* enum aerial_source last logged, -1: none */
	uint32_t shown;			/* the generation last uploaded */
	char view_name[RVK_MAX_AERIAL][SKY_SHM_VIEW_NAME_MAX];
};

static volatile sig_atomic_t quit;

static void on_signal(int sig)
{
	(void)sig;
	quit = 1;
}

static void usage(FILE *f)
{
	fprintf(f,
		"usage: skyrender [OPTIONS]\n"
		"  --socket PATH        skyd's control socket (default: libsky's default path)\n"
		"  --size WxH           the frame (this tile), pixels (default 640x360)\n"
		"  --yaw DEG            view azimuth from north, eastward (default 180);\n"
		"                       fisheye: the front, at the bottom of the dome master\n"
		"  --pitch DEG          view elevation (default 10)\n"
		"  --fov DEG            vertical field of view of the whole wall (default 60)\n"
		"  --grid COLSxROWS     the wall's tiles (default 1x1)\n"
		"  --tile C,R           the tile drawn here, from 0,0 at the top left (default 0,0)\n"
		"  --fisheye            dome master: 180 degrees, zenith at the centre\n"
		"  --no-terrain         the sky only\n"
		"  --no-disks           no sun or moon disk\n"
		"  --albedo A           the ground's reflectance (default 0.15)\n"
		"  --cloud-steps N      steps of the cloud march, the quality knob (default 32;\n"
		"                       0: no clouds)\n"
		"  --aerial FORM        panorama: aerial perspective from skyd's panorama of the\n"
		"                       eye point, which all tiles of a wall share (default);\n"
		"                       volume: a volume of this camera (a dome: four)\n"
		"  --exposure E         linear scale before the tone curve (default: automatic)\n"
		"  --frames N           frames to draw, at least 1 (default 1)\n"
		"  --forever            draw until SIGINT or SIGTERM\n"
		"  --interval MS        between frames (default 100 with --forever, else 0)\n"
		"  --out PATH           a PNG per frame: a pattern with %%d (frame number), a\n"
		"                       directory (DIR/frame-%%04d.png), or one file overwritten\n"
		"                       (default frame-%%04d.png)\n"
		"  --window             show the frames in a window on $DISPLAY (X11; Escape or q\n"
		"                       closes it); PNGs then only with --out; --forever by default\n"
		"  --device SEL         Vulkan device, an index or a name substring\n"
		"Prints one line per frame: frame N generation G PATH.\n");
}

static int parse_pair(const char *v, char sep, unsigned long *a, unsigned long *b)
{
	char *end;
	if (!v || v[0] == '-')
		return -1;
	*a = strtoul(v, &end, 10);
	if (*end != sep || end[1] == '-')
		return -1;
	*b = strtoul(end + 1, &end, 10);
	return *end ? -1 : 0;
}

static int parse_number(const char *v, double lo, double hi, double *ret)
{
	double x;
	if (!v || proto_parse_number(v, &x) < 0 || !(x >= lo && x <= hi))
		return -1;
	*ret = x;
	return 0;
}

/* Parses argv into o; 0, or EXIT_USAGE after saying what was wrong. */
static int parse_args(int argc, char **argv, struct opts *o)
{
	struct rvk_camera *cam = &o->rvk.camera;
	unsigned long a, b;
	double x;
	int interval = -1;
	for (int i = 1; i < argc; i++) {
		const char *k = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		bool bad = false, takes = true;
		if (!strcmp(k, "--help")) {
			usage(stdout);
			exit(EXIT_OK);
		} else if (!strcmp(k, "--socket") && v) {
			o->socket = v;
		} else if (!strcmp(k, "--out") && v) {
			o->out = v;
			o->out_given = true;
		} else if (!strcmp(k, "--device") && v) {
			o->rvk.device = v;
		} else if (!strcmp(k, "--size")) {
			bad = parse_pair(v, 'x', &a, &b) < 0 || !a || !b || a > 16384 || b > 16384;
			cam->width = (uint32_t)a;
			cam->height = (uint32_t)b;
		} else if (!strcmp(k, "--grid")) {
			bad = parse_pair(v, 'x', &a, &b) < 0 || !a || !b || a > 64 || b > 64;
			cam->cols = (uint32_t)a;
			cam->rows = (uint32_t)b;
		} else if (!strcmp(k, "--tile")) {
			bad = parse_pair(v, ',', &a, &b) < 0 || a > 64 || b > 64;
			cam->col = (uint32_t)a;
			cam->row = (uint32_t)b;
		} else if (!strcmp(k, "--yaw")) {
			bad = parse_number(v, -360.0, 720.0, &cam->yaw_deg) < 0;
		} else if (!strcmp(k, "--pitch")) {
			bad = parse_number(v, -90.0, 90.0, &cam->pitch_deg) < 0;
		} else if (!strcmp(k, "--fov")) {
			bad = parse_number(v, 0.01, 179.0, &cam->vfov_deg) < 0;
		} else if (!strcmp(k, "--aerial")) {
			bad = !v || (strcmp(v, "panorama") && strcmp(v, "volume"));
			o->aerial = v && !strcmp(v, "volume") ? AERIAL_VOLUME : AERIAL_PANORAMA;
		} else if (!strcmp(k, "--cloud-steps")) {
			double steps = 0.0;
			bad = parse_number(v, 0.0, 1024.0, &steps) < 0;
			o->rvk.cloud_steps = (int)steps;
		} else if (!strcmp(k, "--albedo")) {
			bad = parse_number(v, 0.0, 1.0, &o->rvk.terrain_albedo) < 0;
		} else if (!strcmp(k, "--exposure")) {
			bad = parse_number(v, 0.0, 1e12, &o->exposure) < 0;
		} else if (!strcmp(k, "--frames")) {
			/* 0 once meant forever: a script that asked for one picture
			 * with it waited for ever. */
			if (v && !strcmp(v, "0")) {
				fprintf(stderr, "skyrender: --frames 0 draws nothing; --forever draws until "
						"SIGINT or SIGTERM\n");
				return EXIT_USAGE;
			}
			bad = parse_number(v, 1.0, 1e9, &x) < 0 || x != floor(x);
			o->frames = (long)x;
			o->frames_given = true;
		} else if (!strcmp(k, "--interval")) {
			bad = parse_number(v, 0.0, 3.6e6, &x) < 0;
			interval = (int)x;
		} else {
			takes = false;
			if (!strcmp(k, "--fisheye")) {
				cam->projection = RVK_FISHEYE;
			} else if (!strcmp(k, "--window")) {
				o->window = true;
			} else if (!strcmp(k, "--forever")) {
				o->frames = 0;
				o->frames_given = true;
			} else if (!strcmp(k, "--no-terrain")) {
				o->rvk.terrain = false;
			} else if (!strcmp(k, "--no-disks")) {
				o->rvk.disk_flags = 0;
			} else {
				bad = true;
			}
		}
		if (bad || (takes && !v)) {
			fprintf(stderr, "skyrender: bad argument '%s%s%s' (see --help)\n", k,
				takes && v ? " " : "", takes && v ? v : "");
			return EXIT_USAGE;
		}
		i += takes;
	}
	if (cam->col >= cam->cols || cam->row >= cam->rows) {
		fprintf(stderr, "skyrender: --tile %u,%u is outside --grid %ux%u\n", cam->col,
			cam->row, cam->cols, cam->rows);
		return EXIT_USAGE;
	}
	if (o->window && !o->frames_given)
		o->frames = 0;
	o->interval_ms = interval >= 0 ? interval : o->frames == 0 ? 100 : 0;
	return 0;
}

/* The file of frame n. */
static void frame_path(const char *out, long n, char *buf, size_t size)
{
	struct stat st;
	if (strchr(out, '%'))
		snprintf(buf, size, out, n);
	else if ((stat(out, &st) == 0 && S_ISDIR(st.st_mode)) || out[strlen(out) - 1] == '/')
		snprintf(buf, size, "%s/frame-%04ld.png", out, n);
	else
		snprintf(buf, size, "%s", out);
}

/* Writes the frame (rows top to bottom) with skyctl render's encoding:
 * dump_png's exposure, ACES curve and sRGB, which puts row 0 at the bottom. */
static int write_png(const char *path, const float *rgba, uint32_t w, uint32_t h, double exposure,
		     float *scratch)
{
	for (uint32_t y = 0; y < h; y++)
		memcpy(scratch + (size_t)y * w * 4, rgba + (size_t)(h - 1 - y) * w * 4,
		       (size_t)w * 4 * sizeof(float));
	struct dump_table t = { .name = "frame", .width = w, .height = h, .depth = 1,
				.format = SKY_FORMAT_RGBA32F, .texels = scratch };
	struct dump_tonemap tm = { .exposure = exposure, .curve = DUMP_CURVE_ACES };
	char err[256];
	int r = dump_png(path, &t, &tm, err, sizeof(err));
	if (r < 0)
		fprintf(stderr, "skyrender: %s\n", err);
	return r;
}

/* The dome master's one panorama view: the zenith inside its frustum, so
 * that skyd's panorama covers the full circle of azimuths (skyd widens a
 * panorama to the full circle when a pole is inside a view), and the
 * frustum's border (89.5 degrees off its axis) 9.5 degrees under the
 * horizon, so that the hills at the dome's rim and the filtering across
 * the horizon have rows of their own. */
#define DOME_PITCH_DEG 80.0
#define DOME_VFOV_DEG 179.0

/* The `view add` line of our view k: the wall's camera (its whole field:
 * every tile of the wall asks for the same, so that skyd's panorama of
 * the eye point serves them all), or for a dome master the panorama's
 * wide camera, or with --aerial volume four quarters of the horizon (the
 * first facing the front; 110 degrees wide so that neighbours overlap
 * where the shader blends them, 60 high). */
static void view_line(const struct link *l, const struct opts *o, uint32_t k, char *line,
		      size_t size)
{
	const struct rvk_camera *c = &o->rvk.camera;
	bool pano = o->aerial == AERIAL_PANORAMA;
	double yaw = c->yaw_deg, pitch = c->pitch_deg, vfov = c->vfov_deg;
	double aspect = (double)c->cols * c->width / ((double)c->rows * c->height);
	if (c->projection == RVK_FISHEYE && pano) {
		pitch = DOME_PITCH_DEG;
		vfov = DOME_VFOV_DEG;
		aspect = 1.0;
	} else if (c->projection == RVK_FISHEYE) {
		yaw = fmod(c->yaw_deg + 90.0 * k, 360.0);
		pitch = 0.0;
		vfov = 60.0;
		aspect = tan(55.0 * M_PI / 180.0) / tan(30.0 * M_PI / 180.0);
	}
	snprintf(line, size, "view add name=%s form=%s yaw_deg=%.9g pitch_deg=%.9g vfov_deg=%.9g aspect=%.9g",
		 l->view_name[k], pano ? "panorama" : "volume", yaw, pitch, vfov, aspect);
}

/* Registers our views (view_line()). Without one (refused: a reader, or
 * 8 views taken) the state's camera's volume serves. */
static void add_views(struct link *l, const struct opts *o)
{
	for (uint32_t k = 0; k < l->n_views; k++) {
		char line[256];
		view_line(l, o, k, line, sizeof(line));
		sky_reply *rep = NULL;
		int r = sky_request(l->c, line, &rep);
		l->view_added[k] = r == 0;
		if (r != 0)
			fprintf(stderr, "skyrender: view add: %s%s%s; aerial perspective of the state's camera\n",
				sky_strerror(r), rep ? ": " : "", rep ? sky_reply_message(rep) : "");
		sky_reply_free(rep);
	}
}

/* What aerial texture a frame reads for one of our views. */
enum aerial_source {
	SOURCE_STATE = 0,		/* the state's camera's volume (the aerial table) */
	SOURCE_VOLUME = 1,		/* the view's own volume */
	SOURCE_ARC = 2,			/* the eye point's panorama, an arc of azimuths */
	SOURCE_CIRCLE = 3,		/* the eye point's panorama, the full circle */
};

/* Says on stderr where view k's aerial perspective comes from, when that
 * changed: the one line a user (and tests/system/test_render.c) reads to know
 * that a wall's tiles read a panorama. */
static void say_source(struct link *l, uint32_t k, enum aerial_source src,
		       const struct sky_gpu_table *t)
{
	static const char *const what[] = { "the state's camera's volume", "a volume",
					    "a panorama of an arc", "a panorama of the full circle" };
	if (l->aerial_said[k] == (int)src)
		return;
	l->aerial_said[k] = (int)src;
	if (src == SOURCE_STATE)
		fprintf(stderr, "skyrender: aerial perspective %u: %s\n", k, what[src]);
	else
		fprintf(stderr, "skyrender: aerial perspective %u: view %s, %s of %ux%ux%u\n", k,
			l->view_name[k], what[src], t->width, t->height, t->depth);
}

/* Handles what arrived on the socket; notes a hang-up. */
static void drain_events(struct link *l, struct rvk *r)
{
	struct sky_event ev;
	int n;
	while (l->connected && (n = sky_dispatch(l->c, &ev)) != 0) {
		if (n < 0 || ev.type == SKY_EVENT_HANGUP) {
			l->connected = false;
			memset(l->view_added, 0, sizeof(l->view_added));
			fprintf(stderr, "skyrender: skyd went away; drawing the last tables\n");
		} else if (ev.type == SKY_EVENT_LAYOUT) {
			rvk_forget_tables(r);
		}
	}
}

/* After a hang-up: one attempt to reach skyd again (the same socket), with
 * the subscription and our view renewed. */
static void try_reconnect(struct link *l, struct rvk *r, const struct opts *o)
{
	if (sky_reconnect(l->c) < 0)
		return;
	l->connected = true;
	l->shown = 0;
	for (uint32_t k = 0; k < RVK_MAX_AERIAL; k++)
		l->aerial_said[k] = -1;
	rvk_forget_tables(r);
	fprintf(stderr, "skyrender: reconnected to skyd\n");
	if (o->rvk.terrain)
		add_views(l, o);
}

/* Uploads the newest generation if it is not the one shown: the tables
 * that changed, the uniforms, the aerial volumes or panorama of our views. 0 (nothing to
 * do, or started), -EAGAIN (torn or busy: next frame), -errno. */
static int refresh(struct link *l, struct rvk *r, const struct opts *o)
{
	struct sky_view v;
	struct sky_gpu_table t[SKY_SHM_MAX_TABLES], volume[RVK_MAX_AERIAL];
	struct sky_gpu_state st[RVK_MAX_AERIAL];
	enum aerial_source src[RVK_MAX_AERIAL];
	struct rvk_upload u = { .tables = t, .n_aerial = l->n_views };
	char err[512];
	int rc = sky_view_begin(l->c, &v);
	if (rc < 0)
		return rc;
	if (v.generation == l->shown || (v.valid_tables & NEEDED_TABLES) != NEEDED_TABLES)
		return 0;
	if ((rc = sky_gpu_tables(l->c, &v, t)) < 0)
		return rc;
	for (uint32_t k = 0; k < l->n_views; k++) {
		u.state[k] = &st[k];
		if (l->view_added[k] && sky_gpu_view_table(l->c, &v, l->view_name[k], &volume[k]) >= 0 &&
		    sky_gpu_state(&v, l->view_name[k], &st[k]) == 0) {
			/* A volume or a panorama: sky_gpu_state() says which
			 * (panorama_grid[3]) and the shaders read either. */
			u.aerial[k] = &volume[k];
			u.aerial_is_view[k] = true;
			long form = lrintf(st[k].panorama_grid[3]);
			src[k] = form >= 2 ? SOURCE_CIRCLE : form == 1 ? SOURCE_ARC : SOURCE_VOLUME;
		} else {
			/* This view's volume is not in the slot (yet): the state's camera's. */
			sky_gpu_state(&v, NULL, &st[k]);
			u.aerial[k] = &t[SKY_TABLE_AERIAL];
			src[k] = SOURCE_STATE;
		}
	}
	u.generation = v.generation;
	sky_sample_ambient(&v, u.ambient_lx);
	u.clouds = &v.slot->clouds;
	if ((rc = rvk_upload(r, &u, err, sizeof(err))) < 0) {
		fprintf(stderr, "skyrender: upload: %s\n", err);
		return rc;
	}
	if (!sky_view_end(l->c, &v)) {
		rvk_cancel_upload(r);
		return -EAGAIN;
	}
	l->shown = v.generation;
	for (uint32_t k = 0; o->rvk.terrain && k < l->n_views; k++)
		say_source(l, k, src[k], u.aerial[k]);
	return 0;
}

/* Connects, subscribes and waits for the first generation with the tables. */
static int link_open(struct link *l, const struct opts *o)
{
	/* The clouds need the aerial perspective even without terrain: the
	 * air in front of them (skycloud_composite). */
	uint32_t tables = NEEDED_TABLES |
			  (o->rvk.terrain || o->rvk.cloud_steps > 0 ? SKY_TABLE_BIT(SKY_TABLE_AERIAL) : 0) |
			  (o->rvk.cloud_steps > 0 ? SKY_TABLE_BIT(SKY_TABLE_MULTISCATTER) : 0);
	int r = sky_connect(o->socket, &l->c);
	if (r == 0)
		r = sky_subscribe(l->c, tables, SKY_SUBSCRIBE_EVENTS);
	if (r != 0) {
		fprintf(stderr, "skyrender: skyd: %s\n", sky_strerror(r));
		return -1;
	}
	l->connected = true;
	l->n_views = o->rvk.camera.projection == RVK_FISHEYE && o->aerial == AERIAL_VOLUME ?
		     RVK_MAX_AERIAL : 1;
	for (uint32_t k = 0; k < RVK_MAX_AERIAL; k++)
		l->aerial_said[k] = -1;
	for (uint32_t k = 0; k < l->n_views; k++)
		snprintf(l->view_name[k], sizeof(l->view_name[k]), "skyrender-%d-%u", (int)getpid(), k % 10);
	if (o->rvk.terrain)
		add_views(l, o);
	/* The first frame shows the sky as it is: wait for the tables, and for
	 * our views' aerial volumes or panoramas once skyd took the views. */
	for (uint32_t seen = 0;;) {
		struct sky_view v;
		const void *texels;
		bool all = sky_view_begin(l->c, &v) == 0 &&
			   (v.valid_tables & NEEDED_TABLES) == NEEDED_TABLES;
		for (uint32_t k = 0; all && k < l->n_views; k++)
			all = !l->view_added[k] ||
			      sky_view_aerial_table(&v, l->view_name[k], &texels, NULL) == 0;
		if (all)
			return 0;
		if ((r = sky_wait(l->c, seen, FIRST_TABLES_TIMEOUT_MS, &seen)) < 0 && r != -EINTR) {
			fprintf(stderr, "skyrender: no tables from skyd: %s\n", sky_strerror(r));
			return -1;
		}
		if (quit)
			return -1;
	}
}

/* Shows the frame in the window with the PNGs' encoding and exposure
 * (automatic: dump_auto_exposure, as dump_png does). */
static int show(struct win *w, const float *rgba, uint32_t width, uint32_t height, double exposure)
{
	if (!(exposure > 0.0)) {
		struct dump_table t = { .name = "frame", .width = width, .height = height, .depth = 1,
					.format = SKY_FORMAT_RGBA32F, .texels = rgba };
		dump_auto_exposure(&t, &exposure);
	}
	return win_show(w, rgba, exposure);
}

/* Until the next frame is due, or skyd or the window says something. */
static void wait_frame(const struct link *l, struct win *w, int interval_ms)
{
	struct pollfd p[2] = { { l->connected ? sky_get_fd(l->c) : -1, POLLIN, 0 },
			       { w ? win_fd(w) : -1, POLLIN, 0 } };
	if (interval_ms > 0)
		poll(p, 2, interval_ms);
}

/* Draws frames until done: each frame takes what skyd published (when it
 * is reachable), draws from the images uploaded last, writes a PNG and
 * shows it in the window. */
static int run(struct link *l, struct rvk *r, struct win *w, const struct opts *o)
{
	const struct rvk_camera *c = &o->rvk.camera;
	float *scratch = malloc((size_t)c->width * c->height * 4 * sizeof(float));
	char path[PATH_MAX] = "-", err[512];
	int status = EXIT_OK;
	if (!scratch)
		return EXIT_FAILED;
	for (long n = 0; !quit && (o->frames == 0 || n < o->frames); n++) {
		if (l->connected)
			drain_events(l, r);
		if (!l->connected)
			try_reconnect(l, r, o);
		if (l->connected) {
			int rc = refresh(l, r, o);
			if (rc < 0 && rc != -EAGAIN && rc != -ENOTCONN)
				fprintf(stderr, "skyrender: %s\n", sky_strerror(rc));
		}
		const float *rgba;
		uint64_t gen;
		int rc = rvk_draw(r, &rgba, &gen, err, sizeof(err));
		if (rc < 0) {
			fprintf(stderr, "skyrender: draw: %s\n", err);
			status = EXIT_FAILED;
			break;
		}
		if (!w || o->out_given) {
			frame_path(o->out, n, path, sizeof(path));
			if (write_png(path, rgba, c->width, c->height, o->exposure, scratch) < 0) {
				status = EXIT_FAILED;
				break;
			}
		}
		if (w && (show(w, rgba, c->width, c->height, o->exposure) < 0 || win_closed(w)))
			quit = 1;
		printf("frame %ld generation %llu %s\n", n, (unsigned long long)gen, path);
		fflush(stdout);
		wait_frame(l, w, o->interval_ms);
	}
	free(scratch);
	return status;
}

int main(int argc, char **argv)
{
	struct opts o = {
		.out = "frame-%04d.png", .frames = 1,
		.rvk = { .terrain = true, .terrain_albedo = 0.15, .cloud_steps = SKYCLOUD_MARCH_STEPS_LOW,
			 .disk_flags = SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK | SKY_SAMPLE_LIMB_DARKENING,
			 .camera = { .width = 640, .height = 360, .cols = 1, .rows = 1,
				     .yaw_deg = 180.0, .pitch_deg = 10.0, .vfov_deg = 60.0 } },
	};
	struct link l = { 0 };
	struct rvk *r = NULL;
	char err[512];

	setlocale(LC_ALL, "C");
	int e = parse_args(argc, argv, &o);
	if (e)
		return e;
	struct sigaction sa = { .sa_handler = on_signal };
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	signal(SIGPIPE, SIG_IGN);
	int rc = rvk_new(&o.rvk, err, sizeof(err), &r);
	if (rc < 0) {
		fprintf(stderr, "skyrender: %s\n", err);
		return EXIT_FAILED;
	}
	struct win *w = NULL;
	if (o.window && (rc = win_new(o.rvk.camera.width, o.rvk.camera.height, "skyrender", &w)) < 0) {
		fprintf(stderr, "skyrender: window: %s\n", rc == -ENOTSUP ?
			"not built in (libxcb missing at build time) or not a 24-bit screen" :
			rc == -ENXIO ? "no display ($DISPLAY)" : strerror(-rc));
		rvk_free(r);
		return EXIT_FAILED;
	}
	e = link_open(&l, &o) < 0 ? EXIT_FAILED : run(&l, r, w, &o);
	win_free(w);
	rvk_free(r);
	sky_disconnect(l.c);
	return e;
}

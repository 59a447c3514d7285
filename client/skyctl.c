/* skyctl.c - the command-line front end of skyd: every protocol verb as a
 * subcommand, plus watch, dump and render, all through libsky. */
#include <errno.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "dump.h"
#include "proto.h"
#include "sky.h"
#include "skycloudmarch.h"

/* Exit codes, documented in usage() and skyctl(1) (man/skyctl.1.scd). */
enum { EXIT_OK = 0, EXIT_REFUSED = 1, EXIT_USAGE = 2 };

struct opts {
	const char *socket;
	int timeout_ms;
};

struct cmd {
	const char *name;
	const char *usage;
	int (*run)(const struct opts *o, int argc, char **argv);
};

static int connect_or_complain(const struct opts *o, sky_client **ret)
{
	char path[128] = "";
	if (!o->socket)
		sky_default_path(path, sizeof(path));
	int r = sky_connect(o->socket, ret);
	if (r < 0) {
		fprintf(stderr, "skyctl: cannot connect to '%s': %s\n", o->socket ? o->socket : path,
			sky_strerror(r));
		return EXIT_USAGE;
	}
	sky_set_timeout(*ret, o->timeout_ms);
	return EXIT_OK;
}

static void print_reply(const sky_reply *rep)
{
	for (size_t i = 0; i < sky_reply_count(rep); i++)
		printf("%s: %s\n", sky_reply_key(rep, i), sky_reply_value(rep, i));
}

/* Sends one line, prints the reply (key: value lines on stdout, an ACK on
 * stderr) and maps the outcome to an exit code. */
static int request_print(sky_client *c, const char *line)
{
	sky_reply *rep = NULL;
	int r = sky_request(c, line, &rep);
	if (r < 0) {
		fprintf(stderr, "skyctl: %s: %s\n", line, sky_strerror(r));
		return EXIT_REFUSED;
	}
	print_reply(rep);
	if (r > 0)
		fprintf(stderr, "ACK [%d] %s\n", r, sky_reply_message(rep));
	sky_reply_free(rep);
	return r ? EXIT_REFUSED : EXIT_OK;
}

/* Joins verb and arguments with single spaces; arguments are passed as they
 * are (the daemon parses them), but a newline in one is refused here, and
 * a value with spaces (one shell word, metar=EGLL 241250Z ...) is quoted
 * so that it stays one value. */
static int join_line(const char *verb, int argc, char **argv, char *buf, size_t size)
{
	size_t n = (size_t)snprintf(buf, size, "%s", verb);
	for (int i = 0; i < argc; i++) {
		if (strpbrk(argv[i], "\r\n")) {
			fprintf(stderr, "skyctl: a line break inside '%s'\n", argv[i]);
			return -EINVAL;
		}
		const char *eq = strchr(argv[i], '=');
		char *end = buf + (n < size ? n : size);
		size_t left = n < size ? size - n : 0;
		if (eq && eq[1] != '"' && strpbrk(eq, " \t") && !strchr(eq, '"'))
			n += (size_t)snprintf(end, left, " %.*s\"%s\"", (int)(eq - argv[i] + 1), argv[i],
					      eq + 1);
		else
			n += (size_t)snprintf(end, left, " %s", argv[i]);
	}
	if (n >= size) {
		fprintf(stderr, "skyctl: request longer than %zu bytes\n", size - 1);
		return -EINVAL;
	}
	return 0;
}

/* Every verb without a special front end: the arguments go to the daemon
 * as they are. */
static int run_verb(const struct opts *o, const char *verb, int argc, char **argv)
{
	char line[SKY_PROTO_LINE_MAX];
	sky_client *c;
	if (join_line(verb, argc, argv, line, sizeof(line)) < 0)
		return EXIT_USAGE;
	int e = connect_or_complain(o, &c);
	if (e)
		return e;
	e = request_print(c, line);
	sky_disconnect(c);
	return e;
}

static int cmd_set(const struct opts *o, int argc, char **argv)
{
	if (argc < 1) {
		fprintf(stderr, "usage: skyctl set key=value...\n");
		return EXIT_USAGE;
	}
	for (int i = 0; i < argc; i++) {
		if (!strchr(argv[i], '=')) {
			fprintf(stderr, "skyctl: set: '%s' is not key=value\n", argv[i]);
			return EXIT_USAGE;
		}
	}
	return run_verb(o, "set", argc, argv);
}

/* sun, moon, times [DATE]: the clock's get sun / get moon / get times. */
static int cmd_sun(const struct opts *o, int argc, char **argv)
{
	if (argc) {
		fprintf(stderr, "usage: skyctl sun\n");
		return EXIT_USAGE;
	}
	return run_verb(o, "get", 1, (char *[]){ "sun" });
}

static int cmd_moon(const struct opts *o, int argc, char **argv)
{
	if (argc) {
		fprintf(stderr, "usage: skyctl moon\n");
		return EXIT_USAGE;
	}
	return run_verb(o, "get", 1, (char *[]){ "moon" });
}

static int cmd_times(const struct opts *o, int argc, char **argv)
{
	char date[64];

	if (argc > 1 || (argc == 1 && strchr(argv[0], '='))) {
		fprintf(stderr, "usage: skyctl times [YYYY-MM-DD]\n");
		return EXIT_USAGE;
	}
	if (!argc)
		return run_verb(o, "get", 1, (char *[]){ "times" });
	snprintf(date, sizeof(date), "date=%s", argv[0]);
	return run_verb(o, "get", 2, (char *[]){ "times", date });
}

/* sensor watch: skyd's sensor: lines as they come, on a connection of its
 * own (libsky keeps to the lines of its protocol, which these are not).
 * The first line ("watching: sensor") says it is ready. */
static int sensor_watch(const struct opts *o, long count)
{
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	char path[sizeof(sa.sun_path)], line[SKY_PROTO_LINE_MAX + 2];
	const char *p = o->socket;
	static const char req[] = "sensor events=1\n";

	if (!p && sky_default_path(path, sizeof(path)) == 0)
		p = path;
	int fd = p && strlen(p) < sizeof(sa.sun_path) ? socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0)
						      : -1;
	if (fd >= 0)
		memcpy(sa.sun_path, p, strlen(p) + 1);
	if (fd < 0 || connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0 ||
	    write(fd, req, sizeof(req) - 1) != (ssize_t)sizeof(req) - 1) {
		fprintf(stderr, "skyctl: cannot connect to '%s': %s\n", p ? p : "?", strerror(errno));
		if (fd >= 0)
			close(fd);
		return EXIT_USAGE;
	}
	FILE *f = fdopen(fd, "r");
	int refused = 0, greeted = 0, watching = 0;
	while (f && count != 0 && fgets(line, sizeof(line), f)) {
		if (!greeted) {
			greeted = 1;
			continue;
		}
		if (!strncmp(line, "ACK ", 4)) {
			fprintf(stderr, "%s", line);
			refused = 1;
			break;
		}
		if (!watching) {
			watching = !strcmp(line, "OK\n");
			if (watching) {
				printf("watching: sensor\n");
				fflush(stdout);
			}
			continue;
		}
		if (strncmp(line, "sensor: ", 8) != 0)
			continue;
		fputs(line, stdout);
		fflush(stdout);
		if (count > 0)
			count--;
	}
	if (count != 0 && !refused)
		fprintf(stderr, "skyctl: sensor watch: skyd closed the connection\n");
	if (f)
		fclose(f);
	else
		close(fd);
	return count == 0 ? EXIT_OK : EXIT_REFUSED;
}

/* sensor [list | watch [--count N]]: get sensor, the devices skyd knows,
 * or its sensor: lines as they come. */
static int cmd_sensor(const struct opts *o, int argc, char **argv)
{
	long count = -1;

	if (!argc)
		return run_verb(o, "get", 1, (char *[]){ "sensor" });
	if (argc == 1 && !strcmp(argv[0], "list"))
		return run_verb(o, "sensor", 1, (char *[]){ "list" });
	if (!strcmp(argv[0], "watch")) {
		char *end = NULL;
		if (argc == 3 && !strcmp(argv[1], "--count"))
			count = strtol(argv[2], &end, 10);
		if (argc == 1 || (end && !*end && count >= 1))
			return sensor_watch(o, count);
	}
	fprintf(stderr, "usage: skyctl sensor [list | watch [--count N]]\n");
	return EXIT_USAGE;
}

/* help VERB: the daemon's usage of the verb. help alone: the daemon's verbs
 * (its commands reply) on one line and where to read on, rather than the
 * usage of help itself. */
static int cmd_help(const struct opts *o, int argc, char **argv)
{
	if (argc)
		return run_verb(o, "help", argc, argv);
	sky_client *c;
	sky_reply *rep = NULL;
	int e = connect_or_complain(o, &c);
	if (e)
		return e;
	int r = sky_request(c, "commands", &rep);
	if (r == 0) {
		printf("skyd's verbs:");
		for (size_t i = 0; i < sky_reply_count(rep); i++)
			printf(" %s", sky_reply_value(rep, i));
		printf("\n\n"
		       "skyctl help VERB   the usage of one, e.g. skyctl help set\n"
		       "skyctl --help      skyctl's own commands and options\n"
		       "Every verb and key is in skyctl(1) and proto/PROTOCOL.md.\n");
	} else if (r < 0) {
		fprintf(stderr, "skyctl: commands: %s\n", sky_strerror(r));
	} else {
		fprintf(stderr, "ACK [%d] %s\n", r, sky_reply_message(rep));
	}
	sky_reply_free(rep);
	sky_disconnect(c);
	return r ? EXIT_REFUSED : EXIT_OK;
}

/* batch: lines of key=value (or "set key=value ...") from stdin, sent
 * between "batch" and "end" as one change; the daemon answers only "end"
 * (a refused line refuses the whole batch). Blank lines and # comments are
 * skipped. */
static int cmd_batch(const struct opts *o, int argc, char **argv)
{
	if (argc) {
		fprintf(stderr, "usage: skyctl batch < lines\n");
		return EXIT_USAGE;
	}
	sky_client *c;
	int e = connect_or_complain(o, &c);
	if (e)
		return e;
	char buf[SKY_PROTO_LINE_MAX + 2];
	sky_reply *rep = NULL;
	int r = sky_request(c, "batch", &rep);
	unsigned lineno = 0;
	while (r == 0 && fgets(buf, sizeof(buf), stdin)) {
		lineno++;
		size_t n = strcspn(buf, "\r\n");
		if (buf[n] == 0 && !feof(stdin)) {
			fprintf(stderr, "skyctl: stdin:%u: line too long\n", lineno);
			r = -EINVAL;
			break;
		}
		buf[n] = 0;
		char *p = buf + strspn(buf, " \t");
		if (!*p || *p == '#')
			continue;
		/* a bare key=value line is a set */
		char line[SKY_PROTO_LINE_MAX + 8];
		size_t verb = strcspn(p, " =");
		snprintf(line, sizeof(line), "%s%s", p[verb] == '=' ? "set " : "", p);
		sky_reply_free(rep);
		rep = NULL;
		r = sky_request(c, line, &rep);
		if (r > 0)
			fprintf(stderr, "skyctl: stdin:%u: ", lineno);
	}
	if (r == 0) {
		sky_reply_free(rep);
		rep = NULL;
		r = sky_request(c, "end", &rep);
	}
	e = EXIT_OK;
	if (r < 0) {
		if (r != -EINVAL)
			fprintf(stderr, "skyctl: batch: %s\n", sky_strerror(r));
		e = EXIT_REFUSED;
	} else {
		print_reply(rep);
		if (r > 0) {
			fprintf(stderr, "ACK [%d] %s\n", r, sky_reply_message(rep));
			e = EXIT_REFUSED;
		}
	}
	sky_reply_free(rep);
	sky_disconnect(c);
	return e;
}

static void print_tables(uint32_t mask)
{
	bool first = true;
	for (unsigned i = 0; i < SKY_SHM_MAX_TABLES; i++) {
		if (mask & SKY_TABLE_BIT(i)) {
			printf("%s%s", first ? "" : ",", proto_table_name(i));
			first = false;
		}
	}
	if (first)
		printf("none");
}

/* watch [--count N]: subscribes with events and prints one line per new
 * generation; the first line ("watching: generation=G") says it is ready. */
static int cmd_watch(const struct opts *o, int argc, char **argv)
{
	long count = -1;
	for (int i = 0; i < argc; i++) {
		char *end;
		if (strcmp(argv[i], "--count") == 0 && i + 1 < argc) {
			count = strtol(argv[++i], &end, 10);
			if (*end || count < 1) {
				fprintf(stderr, "skyctl: watch: bad count '%s'\n", argv[i]);
				return EXIT_USAGE;
			}
		} else {
			fprintf(stderr, "usage: skyctl watch [--count N]\n");
			return EXIT_USAGE;
		}
	}
	sky_client *c;
	int e = connect_or_complain(o, &c);
	if (e)
		return e;
	int r = sky_subscribe(c, SKY_TABLES_ALL, SKY_SUBSCRIBE_EVENTS);
	if (r != 0) {
		fprintf(stderr, "skyctl: subscribe: %s\n", sky_strerror(r));
		sky_disconnect(c);
		return EXIT_REFUSED;
	}
	printf("watching: generation=%u\n",
	       __atomic_load_n(&sky_header(c)->generation, __ATOMIC_ACQUIRE));
	fflush(stdout);
	e = EXIT_OK;
	while (count != 0) {
		struct sky_event ev;
		r = sky_dispatch(c, &ev);
		if (r < 0) {
			fprintf(stderr, "skyctl: watch: %s\n", sky_strerror(r));
			e = EXIT_REFUSED;
			break;
		}
		if (r == 0) {
			struct pollfd p = { sky_get_fd(c), POLLIN | (sky_want_write(c) ? POLLOUT : 0), 0 };
			if (poll(&p, 1, -1) < 0 && errno != EINTR) {
				e = EXIT_REFUSED;
				break;
			}
			continue;
		}
		if (ev.type == SKY_EVENT_HANGUP) {
			fprintf(stderr, "skyctl: watch: skyd closed the connection\n");
			e = EXIT_REFUSED;
			break;
		}
		if (ev.type != SKY_EVENT_CHANGED)
			continue;
		printf("generation=%u tables=", ev.generation);
		print_tables(ev.tables);
		putchar('\n');
		fflush(stdout);
		if (count > 0)
			count--;
	}
	sky_disconnect(c);
	return e;
}

/* Connects, subscribes to tables and copies the newest slot that holds
 * them all (waiting, up to the timeout, for the daemon to compute them:
 * it computes only what someone subscribed to). The buffer is the caller's
 * to free. */
static int take_snapshot(const struct opts *o, uint32_t tables, sky_client **ret_c,
			 void **ret_buf, struct sky_view *ret_view)
{
	int e = connect_or_complain(o, ret_c);
	if (e)
		return e;
	/* The cloud tables exist only while a layer is drawn: asked for,
	 * they are waited for only in a slot that draws one. */
	uint32_t sky = tables & ~(uint32_t)SKY_TABLES_CLOUDS;
	int r = sky_subscribe(*ret_c, tables, 0);
	*ret_buf = NULL;
	while (r == 0) {
		size_t n = sky_snapshot_size(*ret_c);
		free(*ret_buf);
		*ret_buf = aligned_alloc(64, (n + 63) / 64 * 64);
		r = *ret_buf ? sky_snapshot(*ret_c, *ret_buf, n, ret_view) : -ENOMEM;
		uint32_t need = r == 0 && ret_view->slot->clouds.n_layers > 0 ? tables : sky;
		if (r < 0 || (ret_view->valid_tables & need) == need)
			break;
		r = sky_wait(*ret_c, ret_view->generation, o->timeout_ms, NULL);
	}
	if (r != 0) {
		fprintf(stderr, "skyctl: %s\n", sky_strerror(r));
		free(*ret_buf);
		sky_disconnect(*ret_c);
		return EXIT_REFUSED;
	}
	return EXIT_OK;
}

/* dump DIR: one EXR per valid table (DIR/<table>.exr), written by the same
 * code as skyd --dump. */
static int cmd_dump(const struct opts *o, int argc, char **argv)
{
	if (argc != 1) {
		fprintf(stderr, "usage: skyctl dump DIR\n");
		return EXIT_USAGE;
	}
	if (mkdir(argv[0], 0755) < 0 && errno != EEXIST) {
		fprintf(stderr, "skyctl: dump: cannot create '%s': %s\n", argv[0], strerror(errno));
		return EXIT_REFUSED;
	}
	sky_client *c;
	void *buf = NULL;
	struct sky_view v;
	int e = take_snapshot(o, SKY_TABLES_ALL, &c, &buf, &v);
	if (e)
		return e;
	for (uint32_t n = 0; n < v.header->n_tables && !e; n++) {
		const struct sky_shm_table *t = &v.header->tables[n];
		if (!(v.valid_tables & SKY_TABLE_BIT(t->id)))
			continue;
		struct dump_table dt = {
			.name = proto_table_name(t->id), .width = t->width, .height = t->height,
			.depth = t->depth, .format = t->format,
			.texels = (const unsigned char *)v.slot_base + t->offset,
			.rgb_scale_log2 = v.slot->state.rgb_scale_log2[t->id],
		};
		char path[PATH_MAX], err[256];
		snprintf(path, sizeof(path), "%s/%s.exr", argv[0], dt.name);
		if (dump_exr(path, &dt, err, sizeof(err)) < 0) {
			fprintf(stderr, "skyctl: dump: %s\n", err);
			e = EXIT_REFUSED;
		} else {
			printf("%s\n", path);
		}
	}
	printf("generation: %u\n", v.generation);
	free(buf);
	sky_disconnect(c);
	return e;
}

/* render --view fisheye|equirect|perspective [--size WxH] [--yaw D]
 * [--pitch D] [--vfov D] [--exposure E] [--no-disks] [--cloud-steps N]
 * OUT.png */
/* render's arguments into p, *ret_out, *ret_exposure and *ret_cloud_steps:
 * 0, or EXIT_USAGE (said on stderr). */
static int render_args(int argc, char **argv, struct sky_render_params *p, const char **ret_out,
		       double *ret_exposure, int *ret_cloud_steps)
{
	const char *out = NULL;
	bool sized = false;
	for (int i = 0; i < argc; i++) {
		const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
		int bad = 0;
		if (strcmp(a, "--view") == 0 && val) {
			i++;
			if (strcmp(val, "fisheye") == 0)
				p->projection = SKY_PROJECTION_FISHEYE;
			else if (strcmp(val, "equirect") == 0)
				p->projection = SKY_PROJECTION_EQUIRECT;
			else if (strcmp(val, "perspective") == 0)
				p->projection = SKY_PROJECTION_PERSPECTIVE;
			else
				bad = 1;
		} else if (strcmp(a, "--size") == 0 && val) {
			i++;
			char *end;
			unsigned long w = strtoul(val, &end, 10), h = 0;
			if (*end == 'x')
				h = strtoul(end + 1, &end, 10);
			bad = *end || w < 1 || h < 1 || w > 16384 || h > 16384 || val[0] == '-';
			p->width = (uint32_t)w;
			p->height = (uint32_t)h;
			sized = true;
		} else if (strcmp(a, "--yaw") == 0 && val) {
			bad = proto_parse_number(argv[++i], &p->yaw_deg) < 0;
		} else if (strcmp(a, "--pitch") == 0 && val) {
			bad = proto_parse_number(argv[++i], &p->pitch_deg) < 0 || fabs(p->pitch_deg) > 90.0;
		} else if (strcmp(a, "--vfov") == 0 && val) {
			bad = proto_parse_number(argv[++i], &p->vfov_deg) < 0 || p->vfov_deg <= 0.0 ||
			      p->vfov_deg >= 180.0;
		} else if (strcmp(a, "--exposure") == 0 && val) {
			bad = proto_parse_number(argv[++i], ret_exposure) < 0 || *ret_exposure < 0.0;
		} else if (strcmp(a, "--no-disks") == 0) {
			p->flags = 0;
		} else if (strcmp(a, "--cloud-steps") == 0 && val) {
			double steps;
			bad = proto_parse_number(argv[++i], &steps) < 0 || steps < 0.0 || steps > 1024.0 ||
			      steps != floor(steps);
			*ret_cloud_steps = bad ? 0 : (int)steps;
		} else if (a[0] != '-' && !out) {
			out = a;
		} else {
			bad = 1;
		}
		if (bad) {
			fprintf(stderr, "skyctl: render: bad argument '%s'\n", a);
			return EXIT_USAGE;
		}
	}
	if (!out) {
		fprintf(stderr, "usage: skyctl render --view fisheye|equirect|perspective "
				"[--size WxH] OUT.png\n");
		return EXIT_USAGE;
	}
	if (!sized) {
		p->width = p->projection == SKY_PROJECTION_FISHEYE ? 1024 : 1024;
		p->height = p->projection == SKY_PROJECTION_EQUIRECT ? 512 :
			    p->projection == SKY_PROJECTION_FISHEYE ? 1024 : 576;
	}
	*ret_out = out;
	return 0;
}

/* A rendered frame (rgb, top row first) as a tone-mapped PNG at path: 0,
 * or EXIT_REFUSED (said on stderr). */
static int render_png(const char *path, const struct sky_render_params *p, const float *rgb,
		      double exposure)
{
	size_t npx = (size_t)p->width * p->height;
	float *rgba = malloc(npx * 4 * sizeof(float));
	char err[256];
	int e = 0;

	if (!rgba) {
		fprintf(stderr, "skyctl: render: %s\n", sky_strerror(-ENOMEM));
		return EXIT_REFUSED;
	}
	/* dump_png shows row 0 at the bottom; ours is the top row. */
	for (uint32_t y = 0; y < p->height; y++) {
		const float *src = rgb + (size_t)(p->height - 1 - y) * p->width * 3;
		float *dst = rgba + (size_t)y * p->width * 4;
		for (uint32_t x = 0; x < p->width; x++) {
			dst[4 * x + 0] = src[3 * x + 0];
			dst[4 * x + 1] = src[3 * x + 1];
			dst[4 * x + 2] = src[3 * x + 2];
			dst[4 * x + 3] = 1.0f;
		}
	}
	struct dump_table dt = { .name = "render", .width = p->width, .height = p->height,
				 .depth = 1, .format = SKY_FORMAT_RGBA32F, .texels = rgba };
	struct dump_tonemap tm = { .exposure = exposure, .curve = DUMP_CURVE_ACES };
	if (dump_png(path, &dt, &tm, err, sizeof(err)) < 0) {
		fprintf(stderr, "skyctl: render: %s\n", err);
		e = EXIT_REFUSED;
	}
	free(rgba);
	return e;
}

/* The sky of the view with its clouds in front, as skyrender draws them
 * (the same march, jitter 1/2, the sun's shadow map, the view's ambient
 * as skylight; sky_sample_clouds marches the moon too where it lights):
 * sky_render()'s pixels through sky_sample_clouds(). 0 or -errno. */
static int render_clouds(const struct sky_view *v, const struct sky_render_params *p, int steps,
			 float *ret_rgb)
{
	struct sky_cloud_params cp = { .steps = steps, .light_steps = 0, .jitter = 0.5 };
	int r = sky_sample_ambient(v, cp.ambient_lx);
	for (uint32_t y = 0; r == 0 && y < p->height; y++)
		for (uint32_t x = 0; r == 0 && x < p->width; x++) {
			double dir[3], rgb[3] = { 0.0, 0.0, 0.0 };
			float *o = ret_rgb + ((size_t)y * p->width + x) * 3;
			if ((r = sky_render_direction(p, x + 0.5, y + 0.5, dir)) == 1) {
				double el = asin(skymap_clamp(dir[2], -1.0, 1.0)) * 180.0 / SKYMAP_PI;
				double az = atan2(dir[0], dir[1]) * 180.0 / SKYMAP_PI;
				r = sky_sample_clouds(v, &cp, el, az, INFINITY, p->flags | SKY_SAMPLE_CLOUD_COMPOSITE,
						      rgb, NULL, NULL);
			}
			r = r < 0 ? r : 0;
			for (int c = 0; c < 3; c++)
				o[c] = (float)rgb[c];
		}
	return r;
}

static int cmd_render(const struct opts *o, int argc, char **argv)
{
	struct sky_render_params p = { .projection = SKY_PROJECTION_FISHEYE, .vfov_deg = 60.0,
				       .flags = SKY_SAMPLE_SUN_DISK | SKY_SAMPLE_MOON_DISK |
						SKY_SAMPLE_LIMB_DARKENING };
	const char *out = NULL;
	double exposure = 0.0;
	int steps = SKYCLOUD_MARCH_STEPS_LOW;
	int e = render_args(argc, argv, &p, &out, &exposure, &steps);
	if (e)
		return e;
	sky_client *c;
	void *buf = NULL;
	struct sky_view v;
	uint32_t need = SKY_TABLE_BIT(SKY_TABLE_SKYVIEW) | SKY_TABLE_BIT(SKY_TABLE_TRANSMITTANCE);
	if (steps > 0)
		need |= SKY_TABLE_BIT(SKY_TABLE_MULTISCATTER) | SKY_TABLE_BIT(SKY_TABLE_AERIAL) |
			SKY_TABLES_CLOUDS;
	e = take_snapshot(o, need, &c, &buf, &v);
	if (e)
		return e;
	float *rgb = malloc((size_t)p.width * p.height * 3 * sizeof(float));
	bool clouds = steps > 0 && v.slot->clouds.n_layers > 0;
	int r = !rgb ? -ENOMEM : clouds ? render_clouds(&v, &p, steps, rgb) : sky_render(&v, &p, rgb);
	if (r != 0) {
		fprintf(stderr, "skyctl: render: %s\n", sky_strerror(r));
		e = EXIT_REFUSED;
	} else {
		e = render_png(out, &p, rgb, exposure);
		if (!e)
			printf("%s: %ux%u generation %u\n", out, p.width, p.height, v.generation);
	}
	free(rgb);
	free(buf);
	sky_disconnect(c);
	return e;
}

static const struct cmd cmds[] = {
	{ "set", "set key=value...         change the sky (one change, one recompute)", cmd_set },
	{ "get", "get [key...]             print the state, every key or the ones named", NULL },
	{ "status", "status                   generation, compute times, device, clients, last error", NULL },
	{ "batch", "batch < lines            apply stdin's key=value lines as one change", cmd_batch },
	{ "subscribe", "subscribe tables=...     subscribe and print the layout", NULL },
	{ "sample", "sample sky el_deg=E az_deg=A | sample sun | sample ambient", NULL },
	{ "sun", "sun                      where the clock's sun is (get sun)", cmd_sun },
	{ "moon", "moon                     where the clock's moon is, its phase (get moon)", cmd_moon },
	{ "times", "times [YYYY-MM-DD]       sunrise, sunset, twilights of a day (get times)", cmd_times },
	{ "sensor", "sensor [list | watch [--count N]]\n"
		    "                         the light sensor (get sensor), the devices skyd knows,\n"
		    "                         or its sensor: lines as readings come", cmd_sensor },
	{ "view", "view list                the camera views (view add|del work too, but a view\n"
		  "                         lasts only while the connection that added it is open)", NULL },
	{ "ping", "ping                     check that skyd answers", NULL },
	{ "commands", "commands                 list the daemon's verbs", NULL },
	{ "help", "help [VERB]              the daemon's verbs, or the usage of one", cmd_help },
	{ "watch", "watch [--count N]        print each new generation", cmd_watch },
	{ "dump", "dump DIR                 write the current tables as EXR files", cmd_dump },
	{ "render", "render --view fisheye|equirect|perspective [--size WxH] [--yaw D]\n"
		    "                         [--pitch D] [--vfov D] [--exposure E] [--no-disks]\n"
		    "                         [--cloud-steps N] OUT.png (clouds: N steps, default 32)",
	  cmd_render },
};

static void usage(FILE *f)
{
	fprintf(f, "usage: skyctl [--socket PATH] [--timeout MS] COMMAND [ARGS...]\n\n"
		   "Commands (any other verb of the protocol is sent as it is):\n");
	for (size_t i = 0; i < sizeof(cmds) / sizeof(cmds[0]); i++)
		fprintf(f, "  %s\n", cmds[i].usage);
	fprintf(f, "\nThe socket is --socket, else $XDG_RUNTIME_DIR/skyd/control, else "
		   "/run/skyd/control.\n"
		   "The timeout is --timeout, else $SKYCTL_TIMEOUT_MS, else 10000 ms.\n"
		   "Replies print as 'key: value' lines on stdout; a refusal prints its ACK line on "
		   "stderr.\n\n"
		   "Exit status:\n"
		   "  0  success (the daemon answered OK)\n"
		   "  1  the daemon refused (ACK) or the operation failed\n"
		   "  2  usage error, or skyd cannot be reached\n");
}

/* A wait in milliseconds, -1 (forever) to INT_MAX; -EINVAL otherwise. */
static int parse_timeout_ms(const char *s, int *ret_ms)
{
	char *end;
	errno = 0;
	long t = strtol(s, &end, 10);
	if (!*s || *end || errno || t < -1 || t > INT_MAX)
		return -EINVAL;
	*ret_ms = (int)t;
	return 0;
}

int main(int argc, char **argv)
{
	struct opts o = { .socket = NULL, .timeout_ms = 10000 };
	const char *env_timeout = getenv("SKYCTL_TIMEOUT_MS");
	int i = 1;
	setlocale(LC_ALL, "C");
	if (env_timeout && parse_timeout_ms(env_timeout, &o.timeout_ms) < 0) {
		fprintf(stderr, "skyctl: bad SKYCTL_TIMEOUT_MS '%s'\n", env_timeout);
		return EXIT_USAGE;
	}
	for (; i < argc && argv[i][0] == '-'; i++) {
		if ((strcmp(argv[i], "--socket") == 0 || strcmp(argv[i], "-s") == 0) && i + 1 < argc) {
			o.socket = argv[++i];
		} else if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc) {
			if (parse_timeout_ms(argv[++i], &o.timeout_ms) < 0) {
				fprintf(stderr, "skyctl: bad timeout '%s'\n", argv[i]);
				return EXIT_USAGE;
			}
		} else if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
			usage(stdout);
			return EXIT_OK;
		} else if (strcmp(argv[i], "--version") == 0) {
			unsigned v = sky_version();
			printf("skyctl (libsky %u.%u.%u, protocol %s)\n", v >> 16, (v >> 8) & 0xff,
			       v & 0xff, SKY_PROTO_VERSION);
			return EXIT_OK;
		} else {
			fprintf(stderr, "skyctl: unknown option '%s'\n", argv[i]);
			usage(stderr);
			return EXIT_USAGE;
		}
	}
	if (i >= argc) {
		usage(stderr);
		return EXIT_USAGE;
	}
	const char *verb = argv[i];
	for (size_t k = 0; k < sizeof(cmds) / sizeof(cmds[0]); k++) {
		if (strcmp(cmds[k].name, verb) == 0 && cmds[k].run)
			return cmds[k].run(&o, argc - i - 1, argv + i + 1);
	}
	if (!verb[0] || strpbrk(verb, " =\t")) {
		fprintf(stderr, "skyctl: '%s' is not a command\n", verb);
		return EXIT_USAGE;
	}
	return run_verb(&o, verb, argc - i - 1, argv + i + 1);
}

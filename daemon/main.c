/* main.c - skyd: the one-shot modes go to once_main, --list-sensors lists
 * the USB light sensors; otherwise the daemon, set up in order and torn
 * down in reverse. */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include "config.h"
#include "ctl.h"
#include "drive.h"
#include "eng.h"
#include "fdstore.h"
#include "log.h"
#include "loop.h"
#include "once.h"
#include "proto.h"
#include "repl.h"
#include "role.h"
#include "sense.h"
#include "sensor.h"
#include "simclock.h"
#include "srv.h"
#include "state.h"
#include "svc_notify.h"
#include "svc_reload.h"
#include "sync.h"

/* Replication's settings: the config file's sync_* keys, then --sync and
 * --sync-role. */
struct sync_settings {
	struct sync_config cfg;
	char url[512];			/* "" none: no replication */
	char password_file[SYNC_PATH_MAX];
};

/* The config keys of role.h, in the order of their options (OPT_ROLE +). */
static const char *const role_keys[4] = { "controllers", "max_connections",
					  "max_subscriptions_per_uid", "max_views_per_uid" };

struct options {
	const char *socket_path;
	const char *config_path;
	const char *device;
	int check_only;
	int list_sensors;
	enum log_level level;
	int first_pair;			/* argv index of the first key=value */
	const char *sync_url;		/* --sync */
	const char *sync_role;		/* --sync-role */
	struct sync_settings sync;
	const char *role_opts[4];	/* --controllers ..., as role_keys */
	struct role_settings roles;
};

static void usage(FILE *f)
{
	fprintf(f,
		"usage: skyd [options] [key=value ...]\n"
		"       skyd --once --dump DIR [key=value ...]\n"
		"       skyd --list-devices\n"
		"       skyd --list-keys [--markdown]\n"
		"       skyd --list-sensors [key=value ...]\n"
		"\n"
		"Computes sky lookup tables on the GPU and serves them over shared memory;\n"
		"steered through a control socket (proto/PROTOCOL.md).\n"
		"\n"
		"  --socket PATH     control socket (default $XDG_RUNTIME_DIR/skyd/control,\n"
		"                    else /run/skyd/control; systemd socket activation wins)\n"
		"  --config FILE     key = value lines applied at start\n"
		"  -n                check the configuration (and key=value args) and exit\n"
		"  --device SEL      Vulkan device index or name substring ($SKYD_DEVICE)\n"
		"  --log-level L     error, warning, info (default) or debug ($SKYD_LOG)\n"
		"  --sync URL        one sky on several machines through an MQTT broker,\n"
		"                    mqtt://HOST[:PORT]/PREFIX or mqtts://... (docs/sync.md)\n"
		"  --sync-role R     controller or follower (default)\n"
		"  --controllers LIST  who may change the sky: users, @groups, uids, @gids\n"
		"                    (default root,@skyd; skyd's own uid always may)\n"
		"  --max-connections N           (default 1024)\n"
		"  --max-subscriptions-per-uid N (default 64)\n"
		"  --max-views-per-uid N         (default 64)\n"
		"  --list-sensors    the USB light sensors found, each opened to see what it is\n"
		"                    (sensor_select and the other sensor_* keys apply)\n"
		"  -h, --help        this text\n"
		"  --version         protocol and program versions\n"
		"  --list-keys       every key of set: name, unit, range, default, the tables\n"
		"                    it invalidates, what it is (tab-separated; --markdown:\n"
		"                    the table of proto/PROTOCOL.md)\n");
}

static int parse_options(int argc, char **argv, struct options *o)
{
	enum { OPT_SOCKET = 256, OPT_CONFIG, OPT_DEVICE, OPT_LOG, OPT_VERSION, OPT_LIST_KEYS,
	       OPT_MARKDOWN, OPT_SENSORS, OPT_SYNC, OPT_SYNC_ROLE, OPT_ROLE,
	       OPT_ROLE_END = OPT_ROLE + 4 };
	static const struct option longs[] = {
		{ "socket", required_argument, NULL, OPT_SOCKET },
		{ "config", required_argument, NULL, OPT_CONFIG },
		{ "device", required_argument, NULL, OPT_DEVICE },
		{ "log-level", required_argument, NULL, OPT_LOG },
		{ "help", no_argument, NULL, 'h' },
		{ "version", no_argument, NULL, OPT_VERSION },
		{ "list-keys", no_argument, NULL, OPT_LIST_KEYS },
		{ "markdown", no_argument, NULL, OPT_MARKDOWN },
		{ "list-sensors", no_argument, NULL, OPT_SENSORS },
		{ "sync", required_argument, NULL, OPT_SYNC },
		{ "sync-role", required_argument, NULL, OPT_SYNC_ROLE },
		{ "controllers", required_argument, NULL, OPT_ROLE },
		{ "max-connections", required_argument, NULL, OPT_ROLE + 1 },
		{ "max-subscriptions-per-uid", required_argument, NULL, OPT_ROLE + 2 },
		{ "max-views-per-uid", required_argument, NULL, OPT_ROLE + 3 },
		{ 0 },
	};
	int c, list_keys = 0, markdown = 0;

	o->level = LOG_LEVEL_INFO;
	while ((c = getopt_long(argc, argv, "+nh", longs, NULL)) != -1) {
		switch (c) {
		case OPT_SOCKET: o->socket_path = optarg; break;
		case OPT_CONFIG: o->config_path = optarg; break;
		case OPT_DEVICE: o->device = optarg; break;
		case OPT_LOG:
			if (log_parse_level(optarg, &o->level) < 0) {
				fprintf(stderr, "skyd: --log-level: '%s' is not error, warning, info or debug\n", optarg);
				return 2;
			}
			break;
		case 'n': o->check_only = 1; break;
		case OPT_SENSORS: o->list_sensors = 1; break;
		case OPT_SYNC: o->sync_url = optarg; break;
		case OPT_SYNC_ROLE: o->sync_role = optarg; break;
		case 'h': usage(stdout); return 0;
		case OPT_VERSION:
			printf("skyd %s, protocol %s, shared memory layout %u\n", PROJECT_VERSION,
			       SKY_PROTO_VERSION, SKY_SHM_LAYOUT_VERSION);
			return 0;
		case OPT_LIST_KEYS: list_keys = 1; break;
		case OPT_MARKDOWN: markdown = 1; break;
		default:
			if (c >= OPT_ROLE && c < OPT_ROLE_END) {
				o->role_opts[c - OPT_ROLE] = optarg;
				break;
			}
			usage(stderr);
			return 2;
		}
	}
	if (list_keys) {
		state_print_keys(stdout, markdown);
		return 0;
	}
	if (markdown) {
		fprintf(stderr, "skyd: --markdown goes with --list-keys\n");
		return 2;
	}
	o->first_pair = optind;
	return -1;
}

static int copy_setting(char *dst, size_t size, const char *value, char *err, size_t err_size)
{
	if (strlen(value) >= size) {
		snprintf(err, err_size, "longer than %zu bytes", size - 1);
		return -EINVAL;
	}
	snprintf(dst, size, "%s", value);
	return 1;
}

/* config_key_fn: the sync_* keys (docs/sync.md). */
static int sync_key(void *ctx, const char *key, const char *value, char *err, size_t err_size)
{
	struct sync_settings *ss = ctx;
	struct sync_config *c = &ss->cfg;
	char *end;

	if (strcmp(key, "sync") == 0)
		return copy_setting(ss->url, sizeof(ss->url), value, err, err_size);
	if (strcmp(key, "sync_role") == 0) {
		if (sync_parse_role(value, &c->role) == 0)
			return 1;
		snprintf(err, err_size, "sync_role: controller or follower");
		return -EINVAL;
	}
	if (strcmp(key, "sync_lead_ms") == 0) {
		errno = 0;
		unsigned long v = strtoul(value, &end, 10);
		if (errno || end == value || *end || v > 10000) {
			snprintf(err, err_size, "sync_lead_ms: a whole number from 0 to 10000");
			return -EINVAL;
		}
		c->lead_ms = (uint32_t)v;
		return 1;
	}
	static const struct { const char *key; size_t off, size; } paths[] = {
		{ "sync_username", offsetof(struct sync_config, username), SYNC_NAME_MAX },
		{ "sync_cafile", offsetof(struct sync_config, cafile), SYNC_PATH_MAX },
		{ "sync_capath", offsetof(struct sync_config, capath), SYNC_PATH_MAX },
		{ "sync_certfile", offsetof(struct sync_config, certfile), SYNC_PATH_MAX },
		{ "sync_keyfile", offsetof(struct sync_config, keyfile), SYNC_PATH_MAX },
	};
	for (size_t i = 0; i < sizeof(paths) / sizeof(paths[0]); i++)
		if (strcmp(key, paths[i].key) == 0)
			return copy_setting((char *)c + paths[i].off, paths[i].size, value, err,
					    err_size);
	if (strcmp(key, "sync_password_file") == 0)
		return copy_setting(ss->password_file, sizeof(ss->password_file), value, err,
				    err_size);
	return 0;
}

/* The command line over the config file, then the whole checked. 0 or
 * -EINVAL (logged). */
static int sync_settings_finish(const struct options *o, struct sync_settings *ss)
{
	char err[512] = "";

	if (o->sync_url && copy_setting(ss->url, sizeof(ss->url), o->sync_url, err,
					sizeof(err)) < 0) {
		log_error("--sync: %s", err);
		return -EINVAL;
	}
	if (o->sync_role && sync_parse_role(o->sync_role, &ss->cfg.role) < 0) {
		log_error("--sync-role: controller or follower");
		return -EINVAL;
	}
	if (!ss->url[0])
		return 0;
	if (sync_config_parse_url(&ss->cfg, ss->url, err, sizeof(err)) < 0) {
		log_error("%s: %s", o->sync_url ? "--sync" : "sync", err);
		return -EINVAL;
	}
	if (ss->password_file[0] &&
	    sync_config_read_password(&ss->cfg, ss->password_file, err, sizeof(err)) < 0) {
		log_error("sync_password_file: %s", err);
		return -EINVAL;
	}
	if (sync_config_check(&ss->cfg, err, sizeof(err)) < 0) {
		log_error("sync: %s", err);
		return -EINVAL;
	}
	return 0;
}

/* The sync_* keys as a settings group of the config file (svc_reload.h):
 * read at start into o->sync; a reload checks them, but replication keeps
 * the settings it started with until skyd restarts. */
struct sync_step {
	struct sync_settings next;
	struct sync_settings *cur;
	int started;
};

static void sync_step_begin(void *ctx)
{
	struct sync_step *st = ctx;

	memset(&st->next, 0, sizeof(st->next));
	sync_config_defaults(&st->next.cfg);
}

static int sync_step_key(void *ctx, const char *key, const char *value, char *err,
			 size_t err_size)
{
	return sync_key(&((struct sync_step *)ctx)->next, key, value, err, err_size);
}

static void sync_step_apply(void *ctx)
{
	struct sync_step *st = ctx;

	if (!st->started) {
		*st->cur = st->next;
		st->started = 1;
	} else if (strcmp(st->next.url, st->cur->url) != 0 ||
		   st->next.cfg.role != st->cur->cfg.role) {
		log_warning("reload: the sync settings changed; they apply when skyd restarts");
	}
}

/* The role.h keys as a settings group: the file's, then --controllers and
 * the bounds over them (options win, at start and on every reload); a
 * reload hands them to the control server at once. */
struct role_step {
	struct role_settings next;
	struct role_settings *cur;
	const char *const *opts;	/* as role_keys; NULL entries: not given */
	struct ctl *ctl;		/* NULL until the server runs */
};

static void role_step_begin(void *ctx)
{
	role_settings_default(&((struct role_step *)ctx)->next);
}

static int role_step_key(void *ctx, const char *key, const char *value, char *err,
			 size_t err_size)
{
	return role_settings_parse_key(&((struct role_step *)ctx)->next, key, value, err, err_size);
}

static int role_step_check(void *ctx, char *err, size_t err_size)
{
	struct role_step *st = ctx;
	char e[400];

	for (int i = 0; i < 4; i++) {
		if (!st->opts[i] ||
		    role_settings_parse_key(&st->next, role_keys[i], st->opts[i], e, sizeof(e)) > 0)
			continue;
		/* e starts with the key; the option says it with '-'. */
		size_t k = strlen(role_keys[i]);
		const char *m = strncmp(e, role_keys[i], k) == 0 && e[k] == ':' ? e + k + 2 : e;
		char name[32];
		for (size_t j = 0; j <= k && j < sizeof(name); j++)
			name[j] = role_keys[i][j] == '_' ? '-' : role_keys[i][j];
		snprintf(err, err_size, "--%s: %s", name, m);
		return -EINVAL;
	}
	return 0;
}

static void role_step_apply(void *ctx)
{
	struct role_step *st = ctx;

	*st->cur = st->next;
	if (st->ctl)
		ctl_set_roles(st->ctl, st->cur);
}

/* The initial state: defaults, the config file, then key=value args; the
 * config file's sync_* keys go to o->sync, its role.h keys to o->roles. */
static int initial_state(struct options *o, struct svc_reload *reload, struct sky_state *ret)
{
	char err[512];
	struct sky_state s;

	state_default(&s);
	if (svc_reload_load(reload, &s, err, sizeof(err)) < 0) {
		log_error("%s", err);
		return -EINVAL;
	}
	if (sync_settings_finish(o, &o->sync) < 0)
		return -EINVAL;
	*ret = s;
	return 0;
}

/* skyd --list-sensors: every candidate device, opened, identified and
 * given back, one line each (sensor_info_format). */
static int list_sensors(const struct sky_state *s)
{
	const struct state_sensor *k = &s->sensor;
	struct sensor_config cfg;
	struct sensor_info *infos;
	size_t n;
	char err[256] = "", line[512];

	sensor_config_defaults(&cfg);
	snprintf(cfg.select, sizeof(cfg.select), "%s", k->select);
	cfg.report_interval_s = k->report_interval_s;
	cfg.io_timeout_s = k->io_timeout_s;
	cfg.rescan_s = k->rescan_s;
	/* Identifying takes a few exchanges, each bounded by io_timeout_s. */
	int r = sensor_list(&cfg, 4.0 * k->io_timeout_s + 1.0, &infos, &n, err, sizeof(err));
	if (r < 0) {
		fprintf(stderr, "skyd: --list-sensors: %s\n", err[0] ? err : strerror(-r));
		return 1;
	}
	for (size_t i = 0; i < n; i++) {
		sensor_info_format(&infos[i], line, sizeof(line));
		printf("%s\n", line);
	}
	if (!n)
		printf("no USB light sensor candidates found\n");
	free(infos);
	return 0;
}

/* The running daemon, built by the start-up steps below in order and
 * torn down by daemon_finish in reverse. */
struct daemon {
	const struct options *o;
	struct svc_reload *reload;
	struct role_step *roles;
	struct fdstore *fds;
	struct loop *loop;
	struct eng *eng;
	struct srv *srv;
	struct svc_notify *notify;
	struct ctl *ctl;
	struct sense *sense;
	struct repl *repl;
	int activated;			/* systemd passed the listening socket */
	char path[108];			/* the control socket, for the log */
};

/* The service's own srv listener, after the control server and the light
 * sensor: systemd's STATUS, and the fd store keeps the newest region. */
static void on_published(void *ctx, uint64_t generation, uint32_t tables, int new_region)
{
	struct daemon *d = ctx;

	(void)generation;
	(void)tables;
	svc_notify_published(d->notify);
	if (new_region)
		fdstore_replaced(d->fds, srv_pub(d->srv));
}

static void on_signal(void *ctx, int signo)
{
	struct daemon *d = ctx;
	char err[512];

	if (signo == SIGHUP) {
		svc_reload_run(d->reload, err, sizeof(err));	/* logs its outcome */
		return;
	}
	log_info("%s: shutting down", strsignal(signo));
	loop_quit(d->loop);
}

/* Many clients each hold a socket: take the whole hard limit of fds. */
static void raise_fd_limit(void)
{
	struct rlimit rl;

	if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < rl.rlim_max) {
		rl.rlim_cur = rl.rlim_max;
		setrlimit(RLIMIT_NOFILE, &rl);
	}
}

/* Each start-up step logs what failed and returns its -errno. */

/* The process, systemd's fd store and the event loop with its signals. */
static int start_loop(struct daemon *d, const struct sky_state *initial)
{
	static const int signals[] = { SIGINT, SIGTERM, SIGHUP };
	int r;

	(void)initial;
	signal(SIGPIPE, SIG_IGN);
	raise_fd_limit();
	r = fdstore_new(&d->fds);
	if (r < 0) {
		log_error("fd store: %s", strerror(-r));
		return r;
	}
	r = loop_new(&d->loop);
	if (r < 0) {
		log_error("event loop: %s", strerror(-r));
		return r;
	}
	r = loop_signals(d->loop, signals, 3, on_signal, d);
	if (r < 0)
		log_error("signalfd: %s", strerror(-r));
	return r;
}

/* skyd's cache directory, made if missing: $CACHE_DIRECTORY (systemd's
 * CacheDirectory=, the first of a list), else $XDG_CACHE_HOME/skyd, else
 * ~/.cache/skyd. 0, or -errno with nothing to use. */
static int cache_dir(char *buf, size_t size)
{
	const char *sd = getenv("CACHE_DIRECTORY"), *xdg = getenv("XDG_CACHE_HOME");
	const char *home = getenv("HOME");
	int n;

	if (sd && *sd) {
		n = snprintf(buf, size, "%.*s", (int)strcspn(sd, ":"), sd);
	} else if (xdg && *xdg == '/') {
		n = snprintf(buf, size, "%s/skyd", xdg);
	} else if (home && *home == '/') {
		n = snprintf(buf, size, "%s/.cache", home);
		if (n > 0 && (size_t)n < size && mkdir(buf, 0700) < 0 && errno != EEXIST)
			return -errno;
		n = snprintf(buf, size, "%s/.cache/skyd", home);
	} else {
		return -ENOENT;
	}
	if (n <= 0 || (size_t)n >= size)
		return -ENAMETOOLONG;
	if (mkdir(buf, 0700) < 0 && errno != EEXIST)
		return -errno;
	return 0;
}

/* The Vulkan device with its pipelines' cache, and the initial state
 * checked against it. */
static int start_engine(struct daemon *d, const struct sky_state *initial)
{
	char err[512] = "", dir[4096];
	int r = eng_new(d->o->device, err, sizeof(err), &d->eng);

	if (r < 0) {
		log_error("no Vulkan device: %s (skyd --list-devices lists them; lavapipe comes with mesa-vulkan-drivers)", err);
		return r;
	}
	log_info("device: %s (%s), grain %s", eng_device(d->eng)->name, eng_device(d->eng)->type_name,
		 eng_grain_name(eng_grain(d->eng)));
	r = cache_dir(dir, sizeof(dir));
	if (r == 0)
		r = eng_use_cache_dir(d->eng, dir, err, sizeof(err));
	if (r < 0)
		log_info("no pipeline cache (%s): every start compiles the shaders",
			 err[0] ? err : strerror(-r));
	err[0] = 0;
	r = state_validate(initial, eng_max_table_bytes(d->eng), err, sizeof(err));
	if (r < 0)
		log_error("initial state: %s", err);
	return r;
}

/* The sky service with its first computation, publishing into the region
 * a restart under systemd handed back (or a new one), and what it tells
 * systemd. */
static int start_sky(struct daemon *d, const struct sky_state *initial)
{
	struct sky_state lit = *initial;
	struct pub *region = NULL;
	uint64_t generation = 0;
	char err[512] = "";
	double mono_s;
	int r;

	/* A time or place among the initial keys lights the first tables. */
	simclock_read_clocks(NULL, &mono_s);
	r = drive_lights(&lit, mono_s, NULL, err, sizeof(err));
	if (r < 0) {
		log_error("initial state: %s", err);
		return r;
	}
	r = fdstore_region(d->fds, &lit, &region, &generation);
	if (r == 0)
		r = srv_new_from(d->loop, d->eng, &lit, region, generation, &d->srv);
	if (r < 0) {
		log_error("publisher: %s", strerror(-r));
		return r;
	}
	r = svc_notify_new(d->loop, d->srv, &d->notify);
	if (r < 0)
		log_error("sd_notify: %s", strerror(-r));
	return r;
}

/* The control socket: --socket, else systemd's, else the default path;
 * then the region and the socket go to systemd's fd store. */
static int start_control(struct daemon *d, const struct sky_state *initial)
{
	char err[512] = "";
	int listen_fd = -1, r;

	(void)initial;
	if (d->o->socket_path) {
		snprintf(d->path, sizeof(d->path), "%s", d->o->socket_path);
	} else if ((listen_fd = fdstore_activated(d->fds)) >= 0) {
		d->activated = 1;
		snprintf(d->path, sizeof(d->path), "(socket activation)");
	} else if (ctl_default_path(d->path, sizeof(d->path)) < 0) {
		log_error("$XDG_RUNTIME_DIR is too long for a socket path; pass --socket");
		return -ENAMETOOLONG;
	}
	if (!d->activated)
		listen_fd = fdstore_control(d->fds, d->path);
	r = ctl_new(d->loop, d->srv, d->path, listen_fd, err, sizeof(err), &d->ctl);
	if (r < 0) {
		log_error("%s", err);
		return r;
	}
	ctl_set_roles(d->ctl, &d->o->roles);
	d->roles->ctl = d->ctl;
	svc_notify_set_ctl(d->notify, d->ctl);
	if (fdstore_enabled(d->fds))
		fdstore_hand_over(d->fds, srv_pub(d->srv), d->activated ? -1 : ctl_keep_socket(d->ctl));
	return 0;
}

/* The light sensor, its events to the control server; then the service's
 * own listener, which hears of publications after both. */
static int start_sensor(struct daemon *d, const struct sky_state *initial)
{
	int r;

	(void)initial;
	r = sense_new(d->loop, d->srv, &d->sense);
	if (r < 0) {
		log_error("light sensor: %s", strerror(-r));
		return r;
	}
	sense_set_listener(d->sense, ctl_sensor_event, d->ctl);
	r = srv_add_listener(d->srv, &(struct srv_listener){ .published = on_published, .ctx = d });
	if (r < 0)
		log_error("publisher: %s", strerror(-r));
	return r;
}

/* Replication, after everything it drives is up: the retained state may
 * arrive in the first dispatch. */
static int start_sync(struct daemon *d, const struct sky_state *initial)
{
	const struct sync_settings *ss = &d->o->sync;
	int r;

	(void)initial;
	if (!ss->url[0])
		return 0;
	r = repl_new(d->loop, &ss->cfg, d->srv, d->ctl, &d->repl);
	if (r < 0) {
		log_error("sync: %s", strerror(-r));
		return r;
	}
	log_info("sync: %s, %s", ss->url, sync_role_name(ss->cfg.role));
	return 0;
}

static int (*const start_steps[])(struct daemon *d, const struct sky_state *initial) = {
	start_loop, start_engine, start_sky, start_control, start_sensor, start_sync,
};

/* Undoes the steps that ran, in reverse; accepts a half-built daemon. */
static void daemon_finish(struct daemon *d)
{
	svc_reload_attach(d->reload, NULL, NULL, NULL);
	d->roles->ctl = NULL;
	repl_free(d->repl);
	sense_free(d->sense);
	if (d->srv)
		srv_remove_listener(d->srv, d);
	ctl_free(d->ctl);
	svc_notify_free(d->notify);
	srv_free(d->srv);
	eng_free(d->eng);
	loop_free(d->loop);
	fdstore_free(d->fds);
}

static int run_daemon(const struct options *o, struct svc_reload *reload,
		      struct role_step *roles, const struct sky_state *initial)
{
	struct daemon d = { .o = o, .reload = reload, .roles = roles };
	int r = 0;

	for (size_t i = 0; i < sizeof(start_steps) / sizeof(start_steps[0]) && r == 0; i++)
		r = start_steps[i](&d, initial);
	if (r == 0) {
		svc_reload_attach(reload, d.srv, d.notify, d.ctl);
		log_info("listening on %s, protocol %s", d.path, SKY_PROTO_VERSION);
		/* Ready once the initial demand's pipelines are made (seconds on
		 * lavapipe): the first clients, and a sensor's first transfers,
		 * then meet a skyd that is not compiling. */
		eng_wait_orders(d.eng);
		svc_notify_ready(d.notify);
		r = loop_run(d.loop);
		if (r < 0)
			log_error("event loop: %s", strerror(-r));
		svc_notify_stopping(d.notify);
	}
	daemon_finish(&d);
	return r < 0 ? 1 : 0;
}

int main(int argc, char **argv)
{
	static struct options o;
	struct sky_state initial;
	struct svc_reload *reload;
	struct sync_step sync_step = { .cur = &o.sync };
	struct role_step role_step = { .cur = &o.roles, .opts = o.role_opts };
	int r;

	for (int i = 1; i < argc; i++)
		if (strcmp(argv[i], "--once") == 0 || strcmp(argv[i], "--list-devices") == 0)
			return once_main(argc, argv);
	r = parse_options(argc, argv, &o);
	if (r >= 0)
		return r;
	/* journald reads "<N>" priorities from the stream it gets. */
	log_init(o.level, getenv("JOURNAL_STREAM") != NULL);
	if (svc_reload_new(o.config_path, argv + o.first_pair, argc - o.first_pair, &reload) < 0)
		return 1;
	/* Every settings group of the config file, read at start and on
	 * SIGHUP alike. */
	svc_reload_add_step(reload, &(struct svc_reload_step){ "sync", sync_step_begin,
			    sync_step_key, NULL, sync_step_apply, &sync_step });
	svc_reload_add_step(reload, &(struct svc_reload_step){ "roles", role_step_begin,
			    role_step_key, role_step_check, role_step_apply, &role_step });
	if (initial_state(&o, reload, &initial) < 0)
		r = 1;
	else if (o.check_only)
		r = printf("%s: ok\n", o.config_path ? o.config_path : "configuration") < 0;
	else if (o.list_sensors)
		r = list_sensors(&initial);
	else
		r = run_daemon(&o, reload, &role_step, &initial);
	svc_reload_free(reload);
	return r;
}

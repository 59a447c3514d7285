/* once.c - skyd's offline modes: --list-devices, and --once [--dump DIR],
 * which computes the tables for a state given on the command line. */
#include "once.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "drive.h"
#include "dump.h"
#include "eng.h"
#include "skymap.h"
#include "simclock.h"
#include "skyproto.h"
#include "state.h"

static int list_devices(void)
{
	struct eng_device devs[16];
	char err[512];
	int n = eng_list_devices(devs, 16, err, sizeof(err));

	if (n < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		return 1;
	}
	if (n == 0) {
		fprintf(stderr, "skyd: no Vulkan device: install mesa-vulkan-drivers (lavapipe) or a GPU driver\n");
		return 1;
	}
	for (int i = 0; i < n && i < 16; i++)
		printf("%u: %s [%s] vendor 0x%04x device 0x%04x, %s\n", devs[i].index, devs[i].name,
		       devs[i].type_name, devs[i].vendor_id, devs[i].device_id, devs[i].driver);
	return 0;
}

/* How each table's PNG preview is drawn and what its axes are, for the
 * manifest: a person expects the zenith up, so the sky-view table, whose
 * v = 0 is the zenith, is drawn v downward; the EXR keeps v upward
 * (dump.h). Rows follow proto/skymap.h's mappings. */
static const struct preview {
	enum dump_rows rows;
	const char *x, *y;
} previews[STATE_N_TABLES] = {
	[STATE_TRANSMITTANCE] = { DUMP_ROWS_V_UP,
		"view direction: straight up (mu = 1) at the left, the horizon at the right",
		"altitude: the ground at the bottom, the top of the atmosphere at the top" },
	[STATE_MULTISCATTER] = { DUMP_ROWS_V_UP,
		"the sun's height: at the nadir at the left, at the zenith at the right, "
		"texels packed around the horizon of each altitude",
		"altitude: the ground at the bottom, the top of the atmosphere at the top" },
	[STATE_SKYVIEW] = { DUMP_ROWS_V_DOWN,
		"azimuth east of north: 0 deg at the left, 360 at the right",
		"the zenith at the top, the horizon at the middle (texels packed around it), "
		"the nadir at the bottom" },
	[STATE_AERIAL] = { DUMP_ROWS_V_UP,
		"the state's camera's screen, left to right",
		"one band per slice, the nearest at the top; in each, the camera's screen "
		"with its up at the top" },
};

static void emit_state(void *ctx, const char *key, const char *value)
{
	struct dump_json *j = ctx;
	dump_json_key(j, key);
	dump_json_string(j, value);
}

static int write_manifest(const char *dir, const struct sky_state *s, const struct eng *e,
			  const struct eng_timing *t, char *err, size_t err_size)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/manifest.json", dir);
	FILE *f = fopen(path, "we");
	if (!f) {
		int rc = -errno;
		snprintf(err, err_size, "'%.256s': %s", path, strerror(errno));
		return rc;
	}
	struct dump_json *j = dump_json_new_file(f);
	dump_json_begin_object(j);
	dump_json_key(j, "generator");
	dump_json_string(j, "skyd --once");
	dump_json_key(j, "uv_mapping_version");
	dump_json_uint(j, SKYMAP_VERSION);
	dump_json_key(j, "device");
	dump_json_string(j, eng_device(e)->name);
	dump_json_key(j, "total_ms");
	dump_json_number(j, t->total_ms);
	dump_json_key(j, "tables");
	dump_json_begin_array(j);
	for (int i = 0; i < STATE_N_TABLES; i++) {
		const struct state_table_quality *q = &s->quality.t[i];
		char file[64];
		dump_json_begin_object(j);
		dump_json_key(j, "name");
		dump_json_string(j, state_table_names[i]);
		dump_json_key(j, "width");
		dump_json_uint(j, q->width);
		dump_json_key(j, "height");
		dump_json_uint(j, q->height);
		dump_json_key(j, "depth");
		dump_json_uint(j, i == STATE_AERIAL ? q->depth : 1);
		dump_json_key(j, "format");
		dump_json_string(j, s->quality.storage == STATE_F16 ? "rgba16f" : "rgba32f");
		dump_json_key(j, "steps");
		dump_json_uint(j, q->steps);
		snprintf(file, sizeof(file), "%s.exr", state_table_names[i]);
		dump_json_key(j, "exr");
		dump_json_string(j, file);
		snprintf(file, sizeof(file), "%s.png", state_table_names[i]);
		dump_json_key(j, "png");
		dump_json_string(j, file);
		/* The EXR as dump.h orders it; the preview for people. */
		dump_json_key(j, "exr_rows");
		dump_json_string(j, "v upward: table row 0 at the bottom of its slice's band, slice 0 on top");
		dump_json_key(j, "png_x");
		dump_json_string(j, previews[i].x);
		dump_json_key(j, "png_y");
		dump_json_string(j, previews[i].y);
		dump_json_key(j, "compute_ms");
		dump_json_number(j, t->table_ms[i]);
		dump_json_end_object(j);
	}
	dump_json_end_array(j);
	dump_json_key(j, "state");
	dump_json_begin_object(j);
	state_foreach(s, emit_state, j);
	dump_json_end_object(j);
	dump_json_end_object(j);
	int rc = dump_json_finish(j);
	dump_json_free(j);
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	if (rc < 0)
		snprintf(err, err_size, "'%.256s': cannot write: %s", path, strerror(-rc));
	return rc;
}

/* The cloud tables where a layer is drawn (EXR only: their channels are
 * a layer's coverage margin or a shadow map's depths, not colours). */
static int dump_clouds(const char *dir, const struct sky_state *s, const struct eng *e, char *err,
		       size_t err_size)
{
	static const char *const names[2] = { "cloud", "shadow" };

	for (int k = 0; k < 2; k++) {
		const void *texels = eng_cloud_table(e, STATE_CLOUD_COVERAGE + k, NULL);
		uint32_t w = k == 0 ? s->quality.cloud_width : s->quality.shadow_width;
		if (!texels)
			continue;
		struct dump_table tab = { .name = names[k], .width = w, .height = w, .depth = k == 0 ? 1 : 2,
			.format = SKY_FORMAT_RGBA32F, .texels = texels };
		char path[4096];
		snprintf(path, sizeof(path), "%s/%s.exr", dir, names[k]);
		int rc = dump_exr(path, &tab, err, err_size);
		if (rc < 0)
			return rc;
	}
	return 0;
}

static int dump_tables(const char *dir, const struct sky_state *s, const struct eng *e,
		       const struct eng_timing *t, char *err, size_t err_size)
{
	if (mkdir(dir, 0755) < 0 && errno != EEXIST) {
		int rc = -errno;
		snprintf(err, err_size, "'%s': %s", dir, strerror(errno));
		return rc;
	}
	for (int i = 0; i < STATE_N_TABLES; i++) {
		const struct state_table_quality *q = &s->quality.t[i];
		struct dump_table tab = { .name = state_table_names[i], .width = q->width,
			.height = q->height, .depth = i == STATE_AERIAL ? q->depth : 1,
			.format = s->quality.storage == STATE_F16 ? SKY_FORMAT_RGBA16F : SKY_FORMAT_RGBA32F,
			.texels = eng_table(e, (enum state_table)i, NULL),
			.rgb_scale_log2 = eng_table_scale_log2(e, (enum state_table)i) };
		char path[4096];
		snprintf(path, sizeof(path), "%s/%s.exr", dir, state_table_names[i]);
		int rc = dump_exr(path, &tab, err, err_size);
		if (rc == 0) {
			snprintf(path, sizeof(path), "%s/%s.png", dir, state_table_names[i]);
			struct dump_tonemap tm = { .exposure = 0.0, .curve = DUMP_CURVE_ACES,
						   .rows = previews[i].rows };
			rc = dump_png(path, &tab, &tm, err, err_size);
		}
		if (rc < 0)
			return rc;
	}
	int rc = dump_clouds(dir, s, e, err, err_size);
	return rc < 0 ? rc : write_manifest(dir, s, e, t, err, err_size);
}

static void usage(FILE *f)
{
	fprintf(f, "usage: skyd --once [--dump DIR] [--device SEL] [key=value ...]\n"
		   "       skyd --list-devices\n"
		   "Keys are those of the control protocol (proto/PROTOCOL.md), e.g.\n"
		   "sun_elevation_deg=10 sun_azimuth_deg=135 altitude_km=0.2 ground_albedo=0.3\n"
		   "preset=mars skyview_width=256 multiscatter_dirs=2 storage=f16.\n"
		   "Exit status: 0 done, 1 device or file failure, 2 bad input.\n");
}

/* The state of the key=value arguments, parsed whole and validated before
 * any GPU work; with the daemon's clock lights and weather: ret_keys as
 * given (the manifest's), ret_sky resolved (the tables'). 0, or 2 (said on
 * stderr). */
static int read_state(int argc, char **argv, int first, struct sky_state *ret_keys,
		      struct sky_state *ret_sky)
{
	struct sky_state s;
	char err[512];
	double mono_s;

	state_default(&s);
	for (int i = first; i < argc; i++)
		if (state_set_pair(&s, argv[i], NULL, err, sizeof(err)) < 0) {
			fprintf(stderr, "skyd: %s\n", err);
			return 2;
		}
	if (state_validate(&s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		return 2;
	}
	/* utc= and a place light the tables as the daemon's clock would. */
	simclock_read_clocks(NULL, &mono_s);
	if (drive_lights(&s, mono_s, NULL, err, sizeof(err)) < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		return 2;
	}
	/* The tables see the weather as the daemon's would; the manifest keeps
	 * the keys as given. */
	if (state_resolve(&s, ret_sky, NULL, err, sizeof(err)) < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		return 2;
	}
	*ret_keys = s;
	return 0;
}

/* Computes the tables of sky (keys: as given) on device, and writes them
 * to dump_dir (NULL: nowhere). The exit status. */
static int compute(const char *device, const char *dump_dir, const struct sky_state *keys,
		   const struct sky_state *sky)
{
	struct eng_timing t;
	struct eng *e;
	char err[512];

	if (eng_new(device, err, sizeof(err), &e) < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		return 1;
	}
	int rc = state_validate(keys, eng_max_table_bytes(e), err, sizeof(err));
	if (rc < 0) {
		fprintf(stderr, "skyd: %s\n", err);
		eng_free(e);
		return 2;
	}
	rc = eng_compute(e, sky, STATE_ALL_TABLES, &t, err, sizeof(err));
	if (rc == -EINVAL) {
		fprintf(stderr, "skyd: %s\n", err);
		eng_free(e);
		return 2;
	}
	if (rc < 0) {
		fprintf(stderr, "skyd: compute failed on '%s': %s\n", eng_device(e)->name, err);
		eng_free(e);
		return 1;
	}
	printf("skyd: %s: tables in %.2f ms (transmittance %.2f, multiscatter %.2f, skyview %.2f, aerial %.2f)\n",
	       eng_device(e)->name, t.total_ms, t.table_ms[0], t.table_ms[1], t.table_ms[2], t.table_ms[3]);
	struct eng_f16_range range;
	eng_f16_range(e, sky, STATE_ALL_TABLES, &range);
	if (eng_f16_broken(&range))
		fprintf(stderr, "skyd: warning: storage=f16 breaks here: %llu values not finite, "
				"%llu of %llu sky radiance values above the night floor stored as "
				"subnormal halves (low precision); use storage=f32\n",
			(unsigned long long)range.overflow, (unsigned long long)range.subnormal,
			(unsigned long long)range.radiance_values);
	if (dump_dir) {
		rc = dump_tables(dump_dir, keys, e, &t, err, sizeof(err));
		if (rc < 0) {
			fprintf(stderr, "skyd: %s\n", err);
			eng_free(e);
			return 1;
		}
		printf("skyd: wrote %s/{transmittance,multiscatter,skyview,aerial}.{exr,png} and manifest.json\n",
		       dump_dir);
	}
	eng_free(e);
	return 0;
}

int once_main(int argc, char **argv)
{
	static const struct option opts[] = {
		{ "once", no_argument, NULL, 'o' },
		{ "list-devices", no_argument, NULL, 'l' },
		{ "dump", required_argument, NULL, 'd' },
		{ "device", required_argument, NULL, 'D' },
		{ "help", no_argument, NULL, 'h' },
		{ 0 },
	};
	const char *dump_dir = NULL, *device = NULL;
	bool once = false;
	int c;

	optind = 1;
	while ((c = getopt_long(argc, argv, "+h", opts, NULL)) != -1) {
		switch (c) {
		case 'o': once = true; break;
		case 'l': return list_devices();
		case 'd': dump_dir = optarg; break;
		case 'D': device = optarg; break;
		case 'h': usage(stdout); return 0;
		default: usage(stderr); return 2;
		}
	}
	if (!once) {
		usage(stderr);
		return 2;
	}
	struct sky_state s, sky;
	int rc = read_state(argc, argv, optind, &s, &sky);
	return rc ? rc : compute(device, dump_dir, &s, &sky);
}

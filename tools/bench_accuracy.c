/* bench_accuracy.c - `skybench accuracy` (see bench_accuracy.h): its configurations,
 * its options, and the run: ground truth, tables, images, report. */
#include "bench_accuracy.h"
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

const char *const acc_cat_names[N_CAT] = { "day", "horizon", "twilight", "down",
					   "lit", "shadow", "shafts" };

const struct config acc_configs[] = {
	{ "low", { "quality=low" }, true },
	{ "medium", { "quality=medium" }, true },
	{ "high", { "quality=high" }, true },
	{ "ultra", { "quality=ultra" }, true },
	{ "T64x16", { "transmittance_width=64", "transmittance_height=16" }, false },
	{ "T128x32", { "transmittance_width=128", "transmittance_height=32" }, false },
	{ "T512x128", { "transmittance_width=512", "transmittance_height=128" }, false },
	{ "Tsteps10", { "transmittance_steps=10" }, false },
	{ "Tsteps80", { "transmittance_steps=80" }, false },
	{ "M16x16", { "multiscatter_width=16", "multiscatter_height=16" }, false },
	{ "M64x64", { "multiscatter_width=64", "multiscatter_height=64" }, false },
	{ "M64x32", { "multiscatter_width=64" }, false },
	{ "M32x64", { "multiscatter_height=64" }, false },
	{ "Msteps10", { "multiscatter_steps=10" }, false },
	{ "Msteps40", { "multiscatter_steps=40" }, false },
	{ "Mdirs2", { "multiscatter_dirs=2" }, false },
	{ "Iter0", { "multiscatter_iterations=0" }, false },
	{ "Iter4", { "multiscatter_iterations=4" }, false },
	{ "MomentOn", { "multiscatter_moment=on" }, false },
	{ "MomentOff", { "multiscatter_moment=off" }, false },
	{ "DeltaOn", { "multiscatter_delta=on" }, false },
	{ "DeltaOff", { "multiscatter_delta=off" }, false },
	{ "DeltaOffMomentOff", { "multiscatter_delta=off", "multiscatter_moment=off" }, false },
	{ "DeltaOnMomentOff", { "multiscatter_delta=on", "multiscatter_moment=off" }, false },
	{ "S96x54", { "skyview_width=96", "skyview_height=54" }, false },
	{ "S384x216", { "skyview_width=384", "skyview_height=216" }, false },
	{ "Ssteps15", { "skyview_steps=15" }, false },
	{ "Ssteps60", { "skyview_steps=60", "skyview_min_steps=8" }, false },
	{ "f16", { "storage=f16" }, false },
	{ "Single", { "multiscatter_dirs=0" }, false },
	{ "Sh128", { "shadow_width=128" }, false },
	{ "Sh512", { "shadow_width=512" }, false },
};
_Static_assert(sizeof(acc_configs) / sizeof(acc_configs[0]) == N_CONFIGS, "N_CONFIGS");

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* A progress bar on stderr, only when it is a terminal. */
static void progress(const char *phase, size_t done, size_t total, const char *what, double t0)
{
	if (!isatty(STDERR_FILENO))
		return;
	int width = 30, fill = total ? (int)(width * done / total) : width;
	char bar[64];
	for (int i = 0; i < width; i++)
		bar[i] = i < fill ? '#' : '.';
	bar[width] = 0;
	fprintf(stderr, "\r%-10s [%s] %zu/%zu %-28.28s %6.0f s", phase, bar, done, total, what,
		now_s() - t0);
	if (done == total)
		fputc('\n', stderr);
	fflush(stderr);
}

static void usage(FILE *f)
{
	fprintf(f,
		"usage: skybench accuracy [--out DIR] [--cache DIR] [--cache-ro DIR] [--device SEL]\n"
		"         [--runs N] [--threads N] [--day-error REL] [--twilight-error REL]\n"
		"         [--max-samples N] [--fisheye-n N] [--fisheye-error REL] [--no-images]\n"
		"         [--shadow-error REL]\n"
		"         [--presets-only] [--reduced] [--scenes TEXT] [--configs A,B]\n"
		"         [--limits FILE]\n"
		"  --out DIR        where the CSVs (directions.csv: every direction), Markdown,\n"
		"                   plot and images go (accuracy-out)\n"
		"  --cache DIR      ground-truth cache, read and written (OUT/gt-cache)\n"
		"  --cache-ro DIR   a cache read first and never written (e.g. committed truth)\n"
		"  --list-truth     print each scene's ground-truth cache file name and exit\n"
		"  --reduced        the CI matrix: ten scenes, default preset only\n"
		"  --shadow-error REL  the truth's error for the scenes with clouds or terrain\n"
		"  --scenes TEXT    only the scenes whose name contains TEXT\n"
		"  --configs A,B    only these configurations besides medium (low, high, ultra,\n"
		"                   T128x32, Mdirs2, S384x216, f16, ...: see accuracy.md)\n"
		"  --limits FILE    exit 1 when the default preset's largest per-scene value\n"
		"                   of a metric (luminance, per channel, u'v', gradient: see\n"
		"                   tests/accuracy_goals.txt) in a category exceeds the limit\n"
		"exit status: 0, 1 on a failure or an exceeded limit, 2 on a usage error,\n"
		"77 when no Vulkan device can be opened\n");
}

static int parse_num(const char *s, double *ret)
{
	char *end;
	locale_t c = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	if (!c)
		return -ENOMEM;
	double d = strtod_l(s, &end, c);
	freelocale(c);
	if (!*s || *end || !isfinite(d))
		return -EINVAL;
	*ret = d;
	return 0;
}

/* Whether configuration c runs on scene sc: the default preset always; with
 * --configs, the named ones on every scene; otherwise the presets on every
 * scene and the sweeps on the scenes marked for them. */
static bool runs_on(const struct opts *o, size_t c, const struct scene *sc)
{
	if (c == DEFAULT_CONFIG)
		return true;
	if (o->only) {
		size_t n = strlen(acc_configs[c].name);
		for (const char *p = o->only; *p; p += strcspn(p, ","), p += *p == ',')
			if (strcspn(p, ",") == n && !strncmp(p, acc_configs[c].name, n))
				return true;
		return false;
	}
	return !o->reduced && (acc_configs[c].preset || (!o->presets_only && sc->sweep));
}

/* One run: its options, scenes, ground truth and results. */
struct run {
	struct opts o;
	char cmdline[1024], device[800];
	const struct scene *sc;
	size_t n_sc;
	const struct gt *gts;
	struct result *res;	/* N_CONFIGS x n_sc, configuration-major */
	double t0, gt_s;
};

static void cmdline_add(char *cmdline, size_t size, const char *arg)
{
	size_t len = strlen(cmdline);
	snprintf(cmdline + len, size - len, " %s", arg);
}

/* The option of o that a (taking a string) sets, or NULL. */
static const char **string_option(struct opts *o, const char *a)
{
	return !strcmp(a, "--out") ? &o->out : !strcmp(a, "--cache") ? &o->cache :
	       !strcmp(a, "--cache-ro") ? &o->cache_ro : !strcmp(a, "--device") ? &o->device :
	       !strcmp(a, "--limits") ? &o->limits : !strcmp(a, "--configs") ? &o->only :
	       !strcmp(a, "--scenes") ? &o->scene_filter : NULL;
}

/* Sets the numeric option a to d (>= 0). Returns 0, or -EINVAL for an
 * unknown option or a value out of its range. */
static int set_number(struct opts *o, const char *a, double d)
{
	if (!strcmp(a, "--runs") && d >= 1 && d <= 64)
		o->runs = (int)d;
	else if (!strcmp(a, "--threads") && d <= 256)
		o->threads = (int)d;
	else if (!strcmp(a, "--day-error") && d > 0)
		o->day_error = d;
	else if (!strcmp(a, "--twilight-error") && d > 0)
		o->twilight_error = d;
	else if (!strcmp(a, "--fisheye-error") && d > 0)
		o->fisheye_error = d;
	else if (!strcmp(a, "--shadow-error") && d > 0)
		o->shadow_error = d;
	else if (!strcmp(a, "--max-samples") && d >= 4096)
		o->max_samples = (uint64_t)d;
	else if (!strcmp(a, "--fisheye-n") && d >= 4 && d <= 48)
		o->fisheye_n = (int)d;
	else
		return -EINVAL;
	return 0;
}

/* Parses the options into o and echoes them after cmdline. Returns -1 to
 * go on, or the exit status: 0 after --help, 2 on a usage error. */
static int parse_args(int argc, char **argv, struct opts *o, char *cmdline, size_t size)
{
	for (int i = 0; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		const char **dst = string_option(o, a);
		double d = 0;
		cmdline_add(cmdline, size, a);
		if (!strcmp(a, "--help")) {
			usage(stdout);
			return 0;
		} else if (!strcmp(a, "--reduced")) {
			o->reduced = true;
		} else if (!strcmp(a, "--presets-only")) {
			o->presets_only = true;
		} else if (!strcmp(a, "--list-truth")) {
			o->list_truth = true;
		} else if (!strcmp(a, "--no-images")) {
			o->no_images = true;
		} else if (v && dst) {
			*dst = v;
			cmdline_add(cmdline, size, v);
			i++;
		} else if (v && parse_num(v, &d) == 0 && d >= 0) {
			if (set_number(o, a, d) < 0) {
				fprintf(stderr, "skybench: %s %s: bad option or value\n", a, v);
				return 2;
			}
			cmdline_add(cmdline, size, v);
			i++;
		} else {
			fprintf(stderr, "skybench: %s: unknown option or missing value\n", a);
			usage(stderr);
			return 2;
		}
	}
	return -1;
}

/* Makes the output and cache directories (the cache in cache's buffer when
 * --cache was not given). Returns 0 or -errno (said on stderr). */
static int make_dirs(struct opts *o, char *cache, size_t size)
{
	if (!o->cache) {
		snprintf(cache, size, "%s/gt-cache", o->out);
		o->cache = cache;
	}
	if ((mkdir(o->out, 0777) < 0 && errno != EEXIST) || (mkdir(o->cache, 0777) < 0 && errno != EEXIST)) {
		int rc = -errno;
		fprintf(stderr, "skybench: cannot create '%s' or '%s': %s\n", o->out, o->cache, strerror(-rc));
		return rc;
	}
	return 0;
}

/* The scenes of the matrix (at most max) that --scenes keeps; how many. */
static size_t select_scenes(const struct opts *o, struct scene *sc, size_t max)
{
	size_t n_sc = acc_build_scenes(sc, max, o->reduced);
	if (o->scene_filter) {
		size_t m = 0;
		for (size_t i = 0; i < n_sc; i++)
			if (strstr(sc[i].name, o->scene_filter))
				sc[m++] = sc[i];
		n_sc = m;
	}
	return n_sc;
}

/* 1. The ground truth of every scene, cached. Returns 0 or -errno. */
static int run_truth(const struct opts *o, const struct scene *sc, size_t n_sc, struct gt *gts, double t0)
{
	int rc = 0;
	for (size_t i = 0; i < n_sc && rc == 0; i++) {
		progress("truth", i, n_sc, sc[i].name, t0);
		acc_direction_set(&sc[i], &gts[i]);
		double err = acc_shadowed(&sc[i]) ? o->shadow_error
			     : sc[i].sun_elevation_deg >= 2 ? o->day_error : o->twilight_error;
		rc = acc_ground_truth(o, &sc[i], err, &gts[i], "directions");
	}
	return rc;
}

/* 2. The engine under every configuration that runs, measured against the
 * truth into r->res, every direction into directions.csv. Returns 0 or
 * -errno. */
static int run_tables(const struct run *r, struct eng *e)
{
	const struct opts *o = &r->o;
	size_t todo = 0, done = 0;
	int rc = 0;
	for (size_t c = 0; c < N_CONFIGS; c++)
		for (size_t i = 0; i < r->n_sc; i++)
			todo += runs_on(o, c, &r->sc[i]);
	char dirs_path[4096];
	FILE *dirs = NULL;
	if (FITS(dirs_path, "%s/directions.csv", o->out))
		dirs = fopen(dirs_path, "w");
	if (!dirs)
		fprintf(stderr, "skybench: cannot write '%s/directions.csv'\n", o->out);
	else
		fprintf(dirs, "config,scene,category,elevation_deg,azimuth_deg,weight,tables_cd_m2,"
			      "truth_cd_m2,truth_se_cd_m2,rel,tables_r,tables_g,tables_b,truth_r,"
			      "truth_g,truth_b,duv,shadow\n");
	double t1 = now_s();
	for (size_t c = 0; c < N_CONFIGS && rc == 0; c++)
		for (size_t i = 0; i < r->n_sc && rc == 0; i++) {
			const struct scene *sc = &r->sc[i];
			if (!runs_on(o, c, sc))
				continue;
			char what[96];
			if (!FITS(what, "%s %s", acc_configs[c].name, sc->name))
				what[sizeof(what) - 1] = 0;
			progress("tables", done++, todo, what, t1);
			struct sky_state s;
			struct result *x = &r->res[c * r->n_sc + i];
			rc = acc_scene_state(sc, &acc_configs[c], &s);
			if (rc == 0)
				rc = acc_time_tables(e, &s, o->runs, &x->time_ms);
			if (rc == 0) {
				acc_measure(e, &s, sc, acc_configs[c].name, &r->gts[i], x, dirs);
				x->done = true;
			}
			if (rc == 0 && acc_shadowed(sc))
				rc = acc_tables_unshadowed(e, sc, &acc_configs[c], &r->gts[i], &x->unshadowed);
		}
	if (dirs && fclose(dirs) != 0)
		fprintf(stderr, "skybench: cannot write '%s'\n", dirs_path);
	if (rc == 0)
		progress("tables", todo, todo, "", t1);
	return rc;
}

/* 3. Images of the default preset against the truth. Returns 0 or -errno. */
static int run_images(const struct run *r, struct eng *e)
{
	size_t n_fish = 0, k = 0;
	int rc = 0;
	for (size_t i = 0; i < r->n_sc; i++)
		n_fish += r->sc[i].fisheye;
	double t2 = now_s();
	for (size_t i = 0; i < r->n_sc && rc == 0; i++)
		if (r->sc[i].fisheye) {
			progress("fisheye", k++, n_fish, r->sc[i].name, t2);
			rc = acc_fisheye(&r->o, e, &r->sc[i]);
			if (k == n_fish)
				progress("fisheye", k, n_fish, "", t2);
		}
	return rc;
}

/* 4. The report files, the summary on stdout and the --limits check.
 * Returns the exit status, 0 or 1. */
static int report(const struct run *r, const char *device_name, double total_s)
{
	const struct opts *o = &r->o;
	int status = 0;
	if (acc_write_csv(o, r->sc, r->n_sc, r->res, r->device) < 0 ||
	    acc_write_md(o, r->sc, r->n_sc, r->res, r->device, r->cmdline, r->gt_s, total_s) < 0) {
		fprintf(stderr, "skybench: cannot write the report in '%s'\n", o->out);
		status = 1;
	}
	if (!o->no_images && acc_write_plot(o, r->sc, r->n_sc, r->res, device_name) < 0)
		status = 1;
	struct summary s;
	acc_summarize(r->sc, r->res, r->n_sc, DEFAULT_CONFIG, false, &s);
	printf("device: %s\n", r->device);
	/* A category no scene has views in (the shadowed scenes alone have
	 * none by day) reads "none", not 0 %. */
	printf("default preset over %d scenes:", s.n_scenes);
	for (int k = 0; k < 3; k++) {
		if (s.n_cat[k])
			printf(" %s %.2f %% (max %.2f)%s", acc_cat_names[k], 100 * s.mean[k], 100 * s.max_mean[k],
			       k < 2 ? "," : ";");
		else
			printf(" %s none%s", acc_cat_names[k], k < 2 ? "," : ";");
	}
	printf(" tables %.1f ms; truth %.0f s, total %.0f s\n", s.time_ms, r->gt_s, total_s);
	if (s.n_cat[CAT_LIT] + s.n_cat[CAT_SHADOW] + s.n_cat[CAT_SHAFTS]) {
		int n_sh = 0, n_un = 0;
		for (size_t i = 0; i < r->n_sc; i++) {
			const struct result *x = &r->res[DEFAULT_CONFIG * r->n_sc + i];
			n_sh += x->done && acc_shadowed(&r->sc[i]);
			n_un += x->done && acc_shadowed(&r->sc[i]) && x->unshadowed;
		}
		printf("shadowed scenes: lit %.2f %% (max %.2f), shadow %.2f %% (max %.2f), shafts %.2f %% "
		       "(max %.2f)\n", 100 * s.mean[CAT_LIT], 100 * s.max_mean[CAT_LIT],
		       100 * s.mean[CAT_SHADOW], 100 * s.max_mean[CAT_SHADOW], 100 * s.mean[CAT_SHAFTS],
		       100 * s.max_mean[CAT_SHAFTS]);
		if (n_un)
			printf("shadowed scenes: in %d of %d the tables are the same without the clouds "
			       "and terrain: they have lost the shadows, and the figures above are what "
			       "leaving them out costs\n", n_un, n_sh);
	}
	printf("report: %s/accuracy.md, %s/accuracy.csv, %s/directions.csv\n", o->out, o->out, o->out);
	if (o->limits) {
		int bad = acc_check_limits(o->limits, r->sc, r->n_sc, r->res);
		if (bad < 0) {
			fprintf(stderr, "skybench: '%s': %s\n", o->limits, strerror(-bad));
			status = 1;
		} else if (bad > 0) {
			status = 1;
		}
	}
	return status;
}

/* 2. to 4. on a Vulkan device: the tables, the images and the report.
 * Returns the exit status (77 without a device). */
static int run_engine(struct run *r)
{
	struct eng *e;
	char err[512];
	if (eng_new(r->o.device, err, sizeof(err), &e) < 0) {
		/* 77: what ctest reports as skipped, for a machine without Vulkan. */
		fprintf(stderr, "skybench: %s\n", err);
		return 77;
	}
	const struct eng_device *dv = eng_device(e);
	if (!FITS(r->device, "%s (%s)", dv->name, dv->driver))
		r->device[sizeof(r->device) - 1] = 0;
	r->res = calloc(N_CONFIGS * r->n_sc, sizeof(*r->res));
	if (!r->res) {
		eng_free(e);
		return 1;
	}
	int rc = run_tables(r, e);
	if (rc == 0 && !r->o.no_images)
		rc = run_images(r, e);
	double total_s = now_s() - r->t0;
	int status = rc < 0 ? 1 : 0;
	if (rc == 0)
		status = report(r, dv->name, total_s);
	free(r->res);
	eng_free(e);
	return status;
}

int bench_accuracy_main(int argc, char **argv)
{
	static struct scene sc[64];
	static struct gt gts[64];
	struct run r = { .o = { .out = "accuracy-out", .runs = 3, .day_error = 0.01, .twilight_error = 0.03,
				.shadow_error = 0.03,
				.max_samples = 1u << 20, .fisheye_n = 32, .image_px = 256,
				.fisheye_error = 0.05 },
			 .cmdline = "skybench accuracy", .sc = sc, .gts = gts };
	char cache[4096];

	int status = parse_args(argc, argv, &r.o, r.cmdline, sizeof(r.cmdline));
	if (status >= 0)
		return status;
	/* --list-truth only names files: it leaves the disk as it was. */
	if (!r.o.list_truth && make_dirs(&r.o, cache, sizeof(cache)) < 0)
		return 1;
	r.n_sc = select_scenes(&r.o, sc, 64);
	r.t0 = now_s();
	if (run_truth(&r.o, sc, r.n_sc, gts, r.t0) < 0)
		return 1;
	if (r.o.list_truth)
		return 0;
	progress("truth", r.n_sc, r.n_sc, "", r.t0);
	r.gt_s = now_s() - r.t0;
	return run_engine(&r);
}

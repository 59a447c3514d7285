/* bench_accuracy.c - the error-against-run-time report of the sky tables (see bench_accuracy.h). */
#include "bench_accuracy.h"

#include <errno.h>
#include <locale.h>
#include <math.h>
#include <png.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "eng.h"
#include "pt.h"
#include "skysample.h"
#include "state.h"

/* Bumped whenever the path tracer's estimator or this file's use of it
 * changes, so that cached ground truth from before is never reused. */
#define GT_VERSION "gt2"
#define MAX_DIRS 2048
#define MAX_KEYS 8

enum category { CAT_DAY = 0, CAT_HORIZON = 1, CAT_TWILIGHT = 2, N_CAT = 3 };
static const char *const cat_names[N_CAT] = { "day", "horizon", "twilight" };

struct scene {
	char name[48];
	const char *preset;
	double altitude_km, sun_elevation_deg, albedo; /* albedo < 0: the preset's */
	double scattering_scale;
	bool sweep;		/* also measured under the knob sweeps */
	bool fisheye;		/* gets a side-by-side image */
};

struct config {
	const char *name;
	const char *keys[MAX_KEYS];	/* applied after quality=medium */
	bool preset;			/* a quality preset (else a sweep of one knob) */
};

static const struct config configs[] = {
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
};
#define N_CONFIGS (sizeof(configs) / sizeof(configs[0]))
#define DEFAULT_CONFIG 1

/* The direction set: every azimuth is covered by 0 to 180 degrees in steps
 * of 30 with the sun at 180, because the sky (the tables' and the
 * truth's) is symmetric about the sun's vertical plane; the directions
 * strictly between count twice. Elevations are denser near the horizon. */
static const double dir_elevations[] = { 0.5, 1, 1.5, 2, 2.5, 3, 4, 6, 9, 13, 20, 30, 45, 65 };
#define N_EL (sizeof(dir_elevations) / sizeof(dir_elevations[0]))
#define N_AZ 7
#define SUN_AZIMUTH_DEG 180.0

struct opts {
	const char *out, *cache, *cache_ro, *device, *limits, *only, *scene_filter;
	int runs, threads, fisheye_n, image_px;
	double day_error, twilight_error, fisheye_error;
	uint64_t max_samples;
	bool reduced, presets_only, no_images, list_truth;
};

struct gt {
	size_t n;
	struct pt_dir dir[MAX_DIRS];
	double weight[MAX_DIRS];
	double lum[MAX_DIRS], lum_se[MAX_DIRS];
	double rgb[MAX_DIRS][3];
};

struct stats {
	double weight, mean_rel, p95_rel, bias_rel, rmse_lum, worst_rel, worst_el, worst_az;
	double gt_rel_se;
};

struct result {
	bool done;
	double time_ms;
	struct stats cat[N_CAT];
};

/* snprintf into a path-sized buffer; false when the result did not fit. */
#define FITS(buf, ...) (snprintf(buf, sizeof(buf), __VA_ARGS__) < (int)sizeof(buf))

static double luminance(const double rgb[3])
{
	return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

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

static size_t build_scenes(struct scene *sc, size_t max, bool reduced)
{
	static const double suns[] = { 90, 45, 20, 10, 5, 2, 0, -2, -4, -6 };
	static const double alts[] = { 0.2, 10 };
	static const double albedos[] = { 0, 0.3 };
	size_t n = 0;

#define ADD(...) do { if (n < max) sc[n++] = (struct scene){ __VA_ARGS__ }; } while (0)
	if (reduced) {
		/* CI: a day sky with its horizon band and one twilight sky. */
		ADD("earth-s20-h0.2-a0.3", "earth", 0.2, 20, 0.3, 1, true, false);
		ADD("earth-s2-h0.2-a0.3", "earth", 0.2, 2, 0.3, 1, true, false);
		ADD("earth-s-4-h0.2-a0.3", "earth", 0.2, -4, 0.3, 1, true, false);
		/* and the atmospheres whose own terms only they switch on: the
		 * iteration (Earth x10), the shape and delta-M (Mars). */
		ADD("earth10x-s30-h0.2-a0.3", "earth", 0.2, 30, 0.3, 10, true, false);
		ADD("mars-s30-h0.2", "mars", 0.2, 30, -1, 1, true, false);
		ADD("mars-s5-h0.2", "mars", 0.2, 5, -1, 1, true, false);
		return n;
	}
	for (size_t a = 0; a < 2; a++)
		for (size_t b = 0; b < 2; b++)
			for (size_t s = 0; s < sizeof(suns) / sizeof(suns[0]); s++) {
				char name[48];
				snprintf(name, sizeof(name), "earth-s%g-h%g-a%g", suns[s], alts[a], albedos[b]);
				bool main_row = a == 0 && b == 1;
				ADD("", "earth", alts[a], suns[s], albedos[b], 1, main_row,
				    main_row && (suns[s] == 20 || suns[s] == 2 || suns[s] == -2));
				snprintf(sc[n - 1].name, sizeof(sc[n - 1].name), "%s", name);
			}
	ADD("mars-s30-h0.2", "mars", 0.2, 30, -1, 1, true, false);
	ADD("mars-s5-h0.2", "mars", 0.2, 5, -1, 1, true, false);
	/* Not in the reduced matrix: a Mars sky that no constant was chosen
	 * by, to check one (PHASE_DELTA_ORDER). */
	ADD("mars-s15-h0.2", "mars", 0.2, 15, -1, 1, true, false);
	ADD("earth10x-s30-h0.2-a0.3", "earth", 0.2, 30, 0.3, 10, true, false);
#undef ADD
	return n;
}

static int apply(struct sky_state *s, const char *pair)
{
	char err[256];
	if (state_set_pair(s, pair, NULL, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return -EINVAL;
	}
	return 0;
}

/* The state of a scene under a configuration (NULL: the default preset). */
static int scene_state(const struct scene *sc, const struct config *cf, struct sky_state *ret)
{
	char kv[96];
	struct sky_state s;

	state_default(&s);
	snprintf(kv, sizeof(kv), "preset=%s", sc->preset);
	if (apply(&s, kv) < 0)
		return -EINVAL;
	s.altitude_km = sc->altitude_km;
	s.sun.elevation_deg = sc->sun_elevation_deg;
	s.sun.azimuth_deg = SUN_AZIMUTH_DEG;
	if (sc->albedo >= 0)
		for (int c = 0; c < 3; c++)
			s.atmo.ground_albedo[c] = sc->albedo;
	for (int i = 0; i < s.atmo.n_constituents; i++)
		for (int c = 0; c < 3; c++)
			s.atmo.c[i].scattering_per_km[c] *= sc->scattering_scale;
	for (int k = 0; cf && k < MAX_KEYS && cf->keys[k]; k++)
		if (apply(&s, cf->keys[k]) < 0)
			return -EINVAL;
	char err[256];
	if (state_validate(&s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s: %s\n", sc->name, err);
		return -EINVAL;
	}
	*ret = s;
	return 0;
}

static void direction_set(struct gt *g)
{
	g->n = 0;
	for (size_t e = 0; e < N_EL; e++)
		for (int a = 0; a < N_AZ; a++) {
			g->dir[g->n] = (struct pt_dir){ dir_elevations[e], 30.0 * a };
			g->weight[g->n++] = a == 0 || a == N_AZ - 1 ? 1.0 : 2.0;
		}
	g->dir[g->n] = (struct pt_dir){ 90.0, 0.0 };
	g->weight[g->n++] = 1.0;
}

/* FNV-1a, 64 bits. */
static uint64_t fnv(uint64_t h, const char *s)
{
	for (; *s; s++)
		h = (h ^ (unsigned char)*s) * 0x100000001b3ull;
	return h;
}

static uint64_t fnv_double(uint64_t h, double d)
{
	char buf[40];
	snprintf(buf, sizeof(buf), "%.17g;", d);
	return fnv(h, buf);
}

/* Only what the truth depends on - the atmosphere, the observer's altitude
 * and the sun - so that keys added to the state later leave the cache (and
 * the committed truth of the CI test) valid. */
static uint64_t hash_scene(uint64_t h, const struct sky_state *s)
{
	const struct atmo *a = &s->atmo;
	h = fnv_double(h, a->bottom_radius_km);
	h = fnv_double(h, a->top_radius_km);
	for (int c = 0; c < 3; c++)
		h = fnv_double(h, a->ground_albedo[c]);
	h = fnv_double(h, a->n_constituents);
	for (int i = 0; i < a->n_constituents; i++) {
		const struct atmo_constituent *k = &a->c[i];
		for (int c = 0; c < 3; c++) {
			h = fnv_double(h, k->scattering_per_km[c]);
			h = fnv_double(h, k->absorption_per_km[c]);
		}
		h = fnv_double(h, k->phase);
		h = fnv_double(h, k->g);
		for (int l = 0; l < 2; l++) {
			const struct atmo_layer *y = &k->density.layers[l];
			h = fnv_double(h, y->width_km);
			h = fnv_double(h, y->exp_term);
			h = fnv_double(h, y->exp_scale_per_km);
			h = fnv_double(h, y->linear_per_km);
			h = fnv_double(h, y->constant);
		}
	}
	h = fnv_double(h, s->altitude_km);
	h = fnv_double(h, s->sun.elevation_deg);
	h = fnv_double(h, s->sun.azimuth_deg);
	h = fnv_double(h, s->sun.angular_radius_deg);
	for (int c = 0; c < 3; c++)
		h = fnv_double(h, s->sun.illuminance_lx * s->sun.color[c]);
	return h;
}

static uint64_t gt_hash(const struct sky_state *s, const struct pt_options *po, const struct gt *g)
{
	struct { uint64_t h; } c = { 0xcbf29ce484222325ull };
	char buf[128];
	c.h = fnv(c.h, GT_VERSION);
	c.h = hash_scene(c.h, s);
	snprintf(buf, sizeof(buf), "err=%.9g;min=%llu;max=%llu;batch=%u;seed=%llu;n=%zu;", po->rel_error,
		 (unsigned long long)po->min_samples, (unsigned long long)po->max_samples, po->batch,
		 (unsigned long long)po->seed, g->n);
	c.h = fnv(c.h, buf);
	for (size_t i = 0; i < g->n; i++) {
		snprintf(buf, sizeof(buf), "%.9g:%.9g,", g->dir[i].elevation_deg, g->dir[i].azimuth_deg);
		c.h = fnv(c.h, buf);
	}
	return c.h;
}

static void fill_gt(struct gt *g, const struct pt_result *r)
{
	static const double w[3] = { 0.2126, 0.7152, 0.0722 };
	for (size_t i = 0; i < g->n; i++) {
		double v = 0;
		for (int c = 0; c < 3; c++) {
			g->rgb[i][c] = r[i].radiance[c];
			v += w[c] * w[c] * r[i].std_error[c] * r[i].std_error[c];
		}
		g->lum[i] = luminance(g->rgb[i]);
		g->lum_se[i] = sqrt(v);	/* channels are traced with independent streams */
	}
}

static int gt_read(const char *path, struct gt *g)
{
	FILE *f = fopen(path, "re");
	if (!f)
		return -errno;
	static locale_t c_locale;
	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = uselocale(c_locale);
	char line[512];
	size_t i = 0;
	struct pt_result r[1];
	int rc = 0;
	static struct pt_result all[MAX_DIRS];
	while (fgets(line, sizeof(line), f)) {
		if (line[0] == '#')
			continue;
		double el, az;
		unsigned long long n;
		if (i >= g->n || sscanf(line, "%lf %lf %lf %lf %lf %lf %lf %lf %llu", &el, &az,
					 &r->radiance[0], &r->radiance[1], &r->radiance[2],
					 &r->std_error[0], &r->std_error[1], &r->std_error[2], &n) != 9 ||
		    fabs(el - g->dir[i].elevation_deg) > 1e-6 || fabs(az - g->dir[i].azimuth_deg) > 1e-6) {
			rc = -EPROTO;
			break;
		}
		all[i++] = r[0];
	}
	uselocale(old);
	fclose(f);
	if (rc == 0 && i != g->n)
		rc = -EPROTO;
	if (rc == 0)
		fill_gt(g, all);
	return rc;
}

static int gt_write(const char *path, const char *what, const struct gt *g, const struct pt_result *r)
{
	char tmp[4096];
	if (!FITS(tmp, "%s.tmp", path))
		return -ENAMETOOLONG;
	FILE *f = fopen(tmp, "we");
	if (!f)
		return -errno;
	static locale_t c_locale;
	if (!c_locale)
		c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = uselocale(c_locale);
	fprintf(f, "# skybench accuracy ground truth (%s), %s\n"
		   "# elevation_deg azimuth_deg L_r L_g L_b se_r se_g se_b samples\n", GT_VERSION, what);
	for (size_t i = 0; i < g->n; i++)
		fprintf(f, "%.9g %.9g %.17g %.17g %.17g %.9g %.9g %.9g %llu\n", g->dir[i].elevation_deg,
			g->dir[i].azimuth_deg, r[i].radiance[0], r[i].radiance[1], r[i].radiance[2],
			r[i].std_error[0], r[i].std_error[1], r[i].std_error[2],
			(unsigned long long)r[i].samples);
	uselocale(old);
	int rc = ferror(f) ? -EIO : 0;
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	if (rc == 0 && rename(tmp, path) < 0)
		rc = -errno;
	if (rc < 0)
		unlink(tmp);
	return rc;
}

/* The ground truth for g's directions: from the read-only cache, the cache,
 * or the path tracer (then written to the cache). */
static int ground_truth(const struct opts *o, const struct scene *sc, double rel_error, struct gt *g,
			const char *kind)
{
	struct sky_state s;
	struct pt_options po;
	char path[4096], what[256];

	if (scene_state(sc, NULL, &s) < 0)
		return -EINVAL;
	pt_options_default(&po);
	po.rel_error = rel_error;
	po.max_samples = o->max_samples;
	po.threads = o->threads;
	uint64_t h = gt_hash(&s, &po, g);
	if (o->list_truth) {
		printf("%s %s gt-%016llx.txt\n", sc->name, kind, (unsigned long long)h);
		return 0;
	}
	if (o->cache_ro) {
		if (FITS(path, "%s/gt-%016llx.txt", o->cache_ro, (unsigned long long)h) &&
		    gt_read(path, g) == 0)
			return 0;
	}
	if (!FITS(path, "%s/gt-%016llx.txt", o->cache, (unsigned long long)h))
		return -ENAMETOOLONG;
	if (gt_read(path, g) == 0)
		return 0;
	struct pt_result *r = calloc(g->n, sizeof(*r));
	if (!r)
		return -ENOMEM;
	struct pt_sun sun = { .elevation_deg = s.sun.elevation_deg, .azimuth_deg = s.sun.azimuth_deg,
			      .angular_radius_deg = s.sun.angular_radius_deg };
	for (int c = 0; c < 3; c++)
		sun.illuminance[c] = s.sun.illuminance_lx * s.sun.color[c];
	int rc = pt_render(&s.atmo, s.altitude_km, &sun, g->dir, g->n, &po, r);
	if (rc == 0) {
		fill_gt(g, r);
		if (!FITS(what, "%s %s, rel_error %g, max_samples %llu", sc->name, kind, rel_error,
			  (unsigned long long)o->max_samples))
			what[sizeof(what) - 1] = 0;
		int wr = gt_write(path, what, g, r);
		if (wr < 0)
			fprintf(stderr, "skybench: cannot write '%s': %s\n", path, strerror(-wr));
	} else {
		fprintf(stderr, "skybench: path tracer on %s: %s\n", sc->name, strerror(-rc));
	}
	free(r);
	return rc;
}

/* The sky radiance a client reads: proto/skysample.h on the sky-view table. */
static void table_radiance(const struct eng *e, const struct sky_state *s, double el_deg,
			   double az_deg, double ret_rgb[3])
{
	size_t bytes;
	struct skysample_table t = {
		.texels = eng_table(e, STATE_SKYVIEW, &bytes),
		.format = s->quality.storage == STATE_F16 ? SKY_FORMAT_RGBA16F : SKY_FORMAT_RGBA32F,
		.width = s->quality.t[STATE_SKYVIEW].width,
		.height = s->quality.t[STATE_SKYVIEW].height,
		.depth = 1,
	};
	struct sky_shm_state st = { .altitude_km = s->altitude_km,
				    .bottom_radius_km = s->atmo.bottom_radius_km,
				    .top_radius_km = s->atmo.top_radius_km };
	skysample_sky(&t, &st, el_deg * M_PI / 180.0, az_deg * M_PI / 180.0, ret_rgb);
}

struct err_sample {
	double rel, weight;
};

static int cmp_err(const void *a, const void *b)
{
	double x = ((const struct err_sample *)a)->rel, y = ((const struct err_sample *)b)->rel;
	return x < y ? -1 : x > y;
}

static enum category category(const struct scene *sc, double el_deg)
{
	if (sc->sun_elevation_deg < 2.0)
		return CAT_TWILIGHT;
	return el_deg < 3.0 ? CAT_HORIZON : CAT_DAY;
}

/* Each direction's row goes to dirs (directions.csv) when it is open. */
static void measure(const struct eng *e, const struct sky_state *s, const struct scene *sc,
		    const char *config, const struct gt *g, struct result *res, FILE *dirs)
{
	static struct err_sample es[N_CAT][MAX_DIRS];
	size_t n[N_CAT] = { 0 };
	double sum_sq[N_CAT] = { 0 }, sum_se[N_CAT] = { 0 };

	for (int c = 0; c < N_CAT; c++)
		res->cat[c] = (struct stats){ .worst_rel = 0, .worst_el = NAN, .worst_az = NAN };
	for (size_t i = 0; i < g->n; i++) {
		double rgb[3];
		table_radiance(e, s, g->dir[i].elevation_deg, g->dir[i].azimuth_deg, rgb);
		double y = luminance(rgb), w = g->weight[i];
		/* A table value that is not finite (f16 overflows above 65504) is
		 * an infinite error, never a NaN that would vanish from the means. */
		double rel = !isfinite(y) ? INFINITY
			     : g->lum[i] > 0 ? (y - g->lum[i]) / g->lum[i] : (y > 0 ? INFINITY : 0);
		enum category c = category(sc, g->dir[i].elevation_deg);
		struct stats *st = &res->cat[c];
		if (dirs)
			fprintf(dirs, "%s,%s,%s,%g,%g,%g,%.6g,%.6g,%.6g,%.6g\n", config, sc->name,
				cat_names[c], g->dir[i].elevation_deg, g->dir[i].azimuth_deg, w, y,
				g->lum[i], g->lum_se[i], rel);
		es[c][n[c]++] = (struct err_sample){ fabs(rel), w };
		st->weight += w;
		st->mean_rel += w * fabs(rel);
		st->bias_rel += w * rel;
		sum_sq[c] += w * (y - g->lum[i]) * (y - g->lum[i]);
		sum_se[c] += w * (g->lum[i] > 0 ? g->lum_se[i] / g->lum[i] : 0);
		if (!(fabs(rel) <= fabs(st->worst_rel))) {
			st->worst_rel = rel;
			st->worst_el = g->dir[i].elevation_deg;
			st->worst_az = g->dir[i].azimuth_deg;
		}
	}
	for (int c = 0; c < N_CAT; c++) {
		struct stats *st = &res->cat[c];
		if (!n[c])
			continue;
		st->mean_rel /= st->weight;
		st->bias_rel /= st->weight;
		st->rmse_lum = sqrt(sum_sq[c] / st->weight);
		st->gt_rel_se = sum_se[c] / st->weight;
		qsort(es[c], n[c], sizeof(es[c][0]), cmp_err);
		double acc = 0;
		st->p95_rel = es[c][n[c] - 1].rel;
		for (size_t i = 0; i < n[c]; i++) {
			acc += es[c][i].weight;
			if (acc >= 0.95 * st->weight) {
				st->p95_rel = es[c][i].rel;
				break;
			}
		}
	}
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* Computes the tables the sky needs (transmittance, multi-scattering,
 * sky-view) once to warm up, then runs times; the median wall time. The
 * tables of the last run stay readable through eng_table. */
static int time_tables(struct eng *e, const struct sky_state *s, int runs, double *ret_ms)
{
	const uint32_t mask = STATE_BIT(STATE_TRANSMITTANCE) | STATE_BIT(STATE_MULTISCATTER) |
			      STATE_BIT(STATE_SKYVIEW);
	double ms[64];
	char err[512];
	struct eng_timing t;

	if (runs > 64)
		runs = 64;
	for (int i = -1; i < runs; i++) {
		if (eng_compute(e, s, mask, &t, err, sizeof(err)) < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			return -EIO;
		}
		if (i >= 0)
			ms[i] = t.total_ms;
	}
	if (runs < 1) {
		*ret_ms = t.total_ms;
		return 0;
	}
	qsort(ms, runs, sizeof(ms[0]), cmp_double);
	*ret_ms = runs % 2 ? ms[runs / 2] : 0.5 * (ms[runs / 2 - 1] + ms[runs / 2]);
	return 0;
}

/* ---- images ---- */

static int write_png(const char *path, const uint8_t *rgb, int w, int h)
{
	FILE *f = fopen(path, "wbe");
	if (!f)
		return -errno;
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png ? png_create_info_struct(png) : NULL;
	int rc = -ENOMEM;
	if (png && info) {
		rc = -EIO;
		if (!setjmp(png_jmpbuf(png))) {
			png_init_io(png, f);
			png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
				     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
			png_write_info(png, info);
			for (int y = 0; y < h; y++)
				png_write_row(png, (png_const_bytep)(rgb + (size_t)y * w * 3));
			png_write_end(png, NULL);
			rc = 0;
		}
	}
	png_destroy_write_struct(&png, &info);
	if (fclose(f) != 0 && rc == 0)
		rc = -errno;
	return rc;
}

static uint8_t srgb8(double x)
{
	x = x < 0 ? 0 : x > 1 ? 1 : x;
	double v = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
	return (uint8_t)lrint(255.0 * v);
}

/* Fisheye pixel -> direction: zenith in the middle, the horizon on the
 * rim, north up and east to the right (the dome seen from above). */
static bool fisheye_dir(double x, double y, double *el, double *az)
{
	double r = sqrt(x * x + y * y);
	if (r > 1.0)
		return false;
	*el = 90.0 * (1.0 - r);
	*az = atan2(x, y) * 180.0 / M_PI;
	if (*az < 0)
		*az += 360.0;
	return true;
}

/* Signed relative error to a colour: blue (tables low) through white to
 * red (tables high), saturating at +-scale. */
static void error_colour(double rel, double scale, uint8_t *p)
{
	double t = rel / scale;
	t = t < -1 ? -1 : t > 1 ? 1 : t;
	double r = t > 0 ? 1 : 1 + t, gch = 1 - fabs(t), b = t < 0 ? 1 : 1 - t;
	p[0] = (uint8_t)lrint(255 * r);
	p[1] = (uint8_t)lrint(255 * (0.15 + 0.85 * gch));
	p[2] = (uint8_t)lrint(255 * b);
}

static int fisheye(const struct opts *o, struct eng *e, const struct scene *sc)
{
	int n = o->fisheye_n, px = o->image_px, gap = 8;
	static struct gt g;
	struct sky_state s;

	g.n = 0;
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double el, az;
			if (fisheye_dir(2.0 * (i + 0.5) / n - 1, 1 - 2.0 * (j + 0.5) / n, &el, &az) &&
			    el >= 0.25 && g.n < MAX_DIRS) {
				g.dir[g.n] = (struct pt_dir){ el, az };
				g.weight[g.n++] = 1;
			}
		}
	int rc = ground_truth(o, sc, o->fisheye_error, &g, "fisheye");
	if (rc < 0)
		return rc;
	double t_ms;
	if (scene_state(sc, &configs[DEFAULT_CONFIG], &s) < 0 || time_tables(e, &s, 0, &t_ms) < 0)
		return -EIO;
	/* One exposure for both radiance panels, from the truth. */
	double lums[MAX_DIRS];
	for (size_t i = 0; i < g.n; i++)
		lums[i] = g.lum[i];
	qsort(lums, g.n, sizeof(lums[0]), cmp_double);
	double exposure = g.n && lums[g.n / 2] > 0 ? 0.4 / lums[g.n / 2] : 1.0;

	int w = 3 * px + 2 * gap;
	uint8_t *img = calloc((size_t)w * px * 3, 1);
	if (!img)
		return -ENOMEM;
	memset(img, 40, (size_t)w * px * 3);
	size_t k = 0;
	int *cell = calloc((size_t)n * n, sizeof(int));
	if (!cell) {
		free(img);
		return -ENOMEM;
	}
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++) {
			double el, az;
			bool in = fisheye_dir(2.0 * (i + 0.5) / n - 1, 1 - 2.0 * (j + 0.5) / n, &el, &az) &&
				  el >= 0.25;
			cell[j * n + i] = in ? (int)k++ : -1;
		}
	for (int y = 0; y < px; y++)
		for (int x = 0; x < px; x++) {
			double el, az, rgb[3];
			if (!fisheye_dir(2.0 * (x + 0.5) / px - 1, 1 - 2.0 * (y + 0.5) / px, &el, &az))
				continue;
			table_radiance(e, &s, el, az, rgb);
			uint8_t *p = img + ((size_t)y * w + x) * 3;
			for (int c = 0; c < 3; c++)
				p[c] = srgb8(1 - exp(-exposure * rgb[c]));
			int ci = cell[(y * n / px) * n + x * n / px];
			if (ci < 0)
				continue;
			p = img + ((size_t)y * w + px + gap + x) * 3;
			for (int c = 0; c < 3; c++)
				p[c] = srgb8(1 - exp(-exposure * g.rgb[ci][c]));
			table_radiance(e, &s, g.dir[ci].elevation_deg, g.dir[ci].azimuth_deg, rgb);
			double yt = luminance(rgb);
			p = img + ((size_t)y * w + 2 * (px + gap) + x) * 3;
			error_colour(g.lum[ci] > 0 ? (yt - g.lum[ci]) / g.lum[ci] : 0, 0.2, p);
		}
	char path[4096];
	rc = FITS(path, "%s/fisheye-%s.png", o->out, sc->name) ? write_png(path, img, w, px)
							       : -ENAMETOOLONG;
	if (rc < 0)
		fprintf(stderr, "skybench: '%s': %s\n", path, strerror(-rc));
	free(cell);
	free(img);
	return rc;
}

/* ---- reports ---- */

/* Error of a configuration over the scenes it ran on, per category: the
 * mean of the per-scene means (and the largest per-scene mean), the time as
 * the mean of the per-scene medians. */
struct summary {
	double time_ms, mean[N_CAT], max_mean[N_CAT], p95[N_CAT], all;
	int n_scenes;
};

static void summarize(const struct scene *sc, const struct result *r, size_t n_sc, size_t cfg,
		      bool sweep_scenes_only, struct summary *ret)
{
	struct summary s = { 0 };
	int cnt[N_CAT] = { 0 };
	double wall = 0, sum_all = 0;
	for (size_t i = 0; i < n_sc; i++) {
		const struct result *x = &r[cfg * n_sc + i];
		if (!x->done || (sweep_scenes_only && !sc[i].sweep))
			continue;
		s.n_scenes++;
		s.time_ms += x->time_ms;
		for (int c = 0; c < N_CAT; c++) {
			if (!(x->cat[c].weight > 0))
				continue;
			cnt[c]++;
			s.mean[c] += x->cat[c].mean_rel;
			s.p95[c] += x->cat[c].p95_rel;
			if (x->cat[c].mean_rel > s.max_mean[c])
				s.max_mean[c] = x->cat[c].mean_rel;
			sum_all += x->cat[c].mean_rel * x->cat[c].weight;
			wall += x->cat[c].weight;
		}
	}
	if (s.n_scenes)
		s.time_ms /= s.n_scenes;
	for (int c = 0; c < N_CAT; c++)
		if (cnt[c]) {
			s.mean[c] /= cnt[c];
			s.p95[c] /= cnt[c];
		}
	s.all = wall > 0 ? sum_all / wall : NAN;
	*ret = s;
}

static int write_csv(const struct opts *o, const struct scene *sc, size_t n_sc,
		     const struct result *r, const char *device)
{
	char path[4096];
	if (!FITS(path, "%s/accuracy.csv", o->out))
		return -ENAMETOOLONG;
	FILE *f = fopen(path, "we");
	if (!f)
		return -errno;
	fprintf(f, "# device: %s\n", device);
	fprintf(f, "config,scene,category,time_ms,mean_rel,p95_rel,bias_rel,rmse_lum_cd_m2,"
		   "worst_rel,worst_elevation_deg,worst_azimuth_deg,gt_rel_se\n");
	fprintf(f, "# the sun at azimuth 180 deg; rel = (tables - truth) / truth of luminance\n");
	for (size_t c = 0; c < N_CONFIGS; c++)
		for (size_t i = 0; i < n_sc; i++) {
			const struct result *x = &r[c * n_sc + i];
			if (!x->done)
				continue;
			for (int k = 0; k < N_CAT; k++) {
				const struct stats *st = &x->cat[k];
				if (!(st->weight > 0))
					continue;
				fprintf(f, "%s,%s,%s,%.4f,%.6f,%.6f,%.6f,%.6g,%.6f,%g,%g,%.6f\n",
					configs[c].name, sc[i].name, cat_names[k], x->time_ms, st->mean_rel,
					st->p95_rel, st->bias_rel, st->rmse_lum, st->worst_rel,
					st->worst_el, st->worst_az, st->gt_rel_se);
			}
		}
	return fclose(f) ? -errno : 0;
}

static void pct(FILE *f, double x)
{
	if (x == x)
		fprintf(f, " %.1f |", 100 * x);
	else
		fprintf(f, " - |");
}

static int write_md(const struct opts *o, const struct scene *sc, size_t n_sc,
		    const struct result *r, const char *device, const char *cmdline, double gt_s,
		    double total_s)
{
	char path[4096];
	if (!FITS(path, "%s/accuracy.md", o->out))
		return -ENAMETOOLONG;
	FILE *f = fopen(path, "we");
	if (!f)
		return -errno;
	fprintf(f, "Made by `%s` on %s; ground truth %.0f s, whole run %.0f s.\n"
		   "Ground truth: path tracer, all orders, per-direction standard error at most "
		   "%.3g (sun >= 2 deg) or %.3g (lower sun) of the radiance, at most %llu paths a "
		   "direction.\n\n",
		   cmdline, device, gt_s, total_s, o->day_error, o->twilight_error,
		   (unsigned long long)o->max_samples);
	fprintf(f, "Relative error of luminance, in %%: mean of the per-scene means (largest "
		   "per-scene mean) and mean of the per-scene 95th percentiles. day: sun >= 2 deg, "
		   "views >= 3 deg; horizon: sun >= 2 deg, views < 3 deg; twilight: sun < 2 deg, "
		   "all views. Time: engine wall time of transmittance + multi-scattering + "
		   "sky-view, mean over scenes of the median of %d runs.\n\n", o->runs);
	for (int pass = 0; pass < 2; pass++) {
		fprintf(f, pass ? "\nThe presets over every scene of the matrix:\n\n"
				: "Every configuration over the same scenes (those the sweeps run on):\n\n");
		fprintf(f, "| config | scenes | time ms | day mean (max) | day p95 | horizon mean (max) | "
			   "horizon p95 | twilight mean (max) | twilight p95 |\n"
			   "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
		for (size_t c = 0; c < N_CONFIGS; c++) {
			struct summary s;
			if (pass && !configs[c].preset)
				continue;
			summarize(sc, r, n_sc, c, !pass, &s);
			if (!s.n_scenes)
				continue;
			fprintf(f, "| %s | %d | %.1f |", configs[c].name, s.n_scenes, s.time_ms);
			for (int k = 0; k < N_CAT; k++) {
				fprintf(f, " %.1f (%.1f) |", 100 * s.mean[k], 100 * s.max_mean[k]);
				pct(f, s.p95[k]);
			}
			fputc('\n', f);
		}
	}
	fprintf(f, "\nDefault preset (medium), per scene: mean / p95 / bias (mean signed) "
		   "relative error in %%, luminance RMSE in cd/m2, the worst direction "
		   "(elevation/azimuth in degrees, the sun at azimuth 180; signed error), and the truth's own mean "
		   "relative standard error.\n\n"
		   "| scene | time ms | category | mean | p95 | bias | RMSE cd/m2 | worst | GT se |\n"
		   "| --- | ---: | --- | ---: | ---: | ---: | ---: | --- | ---: |\n");
	for (size_t i = 0; i < n_sc; i++) {
		const struct result *x = &r[DEFAULT_CONFIG * n_sc + i];
		if (!x->done)
			continue;
		for (int k = 0; k < N_CAT; k++) {
			const struct stats *st = &x->cat[k];
			if (!(st->weight > 0))
				continue;
			fprintf(f, "| %s | %.1f | %s | %.1f | %.1f | %+.1f | %.4g | %+.1f at %g/%g | %.2f |\n",
				sc[i].name, x->time_ms, cat_names[k], 100 * st->mean_rel,
				100 * st->p95_rel, 100 * st->bias_rel, st->rmse_lum,
				100 * st->worst_rel, st->worst_el, st->worst_az,
				100 * st->gt_rel_se);
		}
	}
	return fclose(f) ? -errno : 0;
}

static int write_plot(const struct opts *o, const struct scene *sc, size_t n_sc,
		      const struct result *r, const char *device)
{
	char path[4096];
	struct summary s[N_CONFIGS];
	for (size_t c = 0; c < N_CONFIGS; c++)
		summarize(sc, r, n_sc, c, !o->reduced && !o->only, &s[c]);
	if (!FITS(path, "%s/errtime.dat", o->out))
		return -ENAMETOOLONG;
	FILE *f = fopen(path, "we");
	if (!f)
		return -errno;
	fprintf(f, "# config time_ms all_mean day_mean horizon_mean twilight_mean pareto\n");
	for (size_t c = 0; c < N_CONFIGS; c++) {
		if (!s[c].n_scenes)
			continue;
		/* Pareto-optimal: no other config is both faster and more accurate. */
		bool front = isfinite(s[c].all);
		for (size_t d = 0; d < N_CONFIGS; d++)
			if (d != c && s[d].n_scenes && isfinite(s[d].all) && s[d].time_ms <= s[c].time_ms &&
			    s[d].all <= s[c].all && (s[d].time_ms < s[c].time_ms || s[d].all < s[c].all))
				front = false;
		fprintf(f, "%s %.4f %.6f %.6f %.6f %.6f %d\n", configs[c].name, s[c].time_ms, s[c].all,
			s[c].mean[0], s[c].mean[1], s[c].mean[2], front);
	}
	if (fclose(f))
		return -errno;
	if (!FITS(path, "%s/errtime.gp", o->out))
		return -ENAMETOOLONG;
	f = fopen(path, "we");
	if (!f)
		return -errno;
	fprintf(f, "set terminal pngcairo size 1000,700 noenhanced\n"
		   "set output 'errtime.png'\n"
		   "set logscale xy\n"
		   "set xlabel 'engine time, transmittance + multi-scattering + sky-view (ms, %s)'\n"
		   "set ylabel 'mean relative error of luminance'\n"
		   "set grid\nset key top right\n"
		   "set title 'skybench accuracy: error against run time over the sweep scenes (Pareto front: line)'\n"
		   "plot \"< awk '$7==1' errtime.dat | sort -g -k2\" using 2:3 with lines lw 2 lc rgb 'black' title 'Pareto front (all views)', \\\n"
		   "     'errtime.dat' using 2:3 with points pt 7 ps 1.2 lc rgb 'black' title 'all views', \\\n"
		   "     '' using 2:3:1 with labels offset 1,0.6 font ',8' notitle, \\\n"
		   "     '' using 2:4 with points pt 5 lc rgb 'blue' title 'day', \\\n"
		   "     '' using 2:5 with points pt 9 lc rgb 'red' title 'horizon band', \\\n"
		   "     '' using 2:6 with points pt 11 lc rgb 'purple' title 'twilight'\n", device);
	if (fclose(f))
		return -errno;
	char cmd[8300];
	snprintf(cmd, sizeof(cmd), "cd '%s' && gnuplot errtime.gp", o->out);
	if (strchr(o->out, '\'') || system(cmd) != 0) {
		fprintf(stderr, "skybench: gnuplot failed; errtime.gp and errtime.dat are in '%s'\n", o->out);
		return -EIO;
	}
	return 0;
}

/* --limits FILE: lines "category max_mean_rel [scene]" for the default
 * preset's largest per-scene mean over the scenes whose name contains scene
 * (every scene without it); returns the number of limits exceeded, or
 * -errno. */
static int check_limits(const char *file, const struct scene *sc, size_t n_sc,
			const struct result *r)
{
	FILE *f = fopen(file, "re");
	if (!f)
		return -errno;
	char line[256], cat[64], only[64];
	double lim;
	int bad = 0;
	locale_t c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = c_locale ? uselocale(c_locale) : (locale_t)0;
	while (fgets(line, sizeof(line), f)) {
		only[0] = 0;
		if (line[0] == '#' || sscanf(line, "%63s %lf %63s", cat, &lim, only) < 2)
			continue;
		if (only[0] == '#')
			only[0] = 0;	/* a comment, not a scene */
		for (int k = 0; k < N_CAT; k++) {
			if (strcmp(cat, cat_names[k]))
				continue;
			double worst = 0.0;
			int n = 0;
			for (size_t i = 0; i < n_sc; i++) {
				const struct result *x = &r[DEFAULT_CONFIG * n_sc + i];
				if (!x->done || !(x->cat[k].weight > 0) || !strstr(sc[i].name, only))
					continue;
				n++;
				if (!(x->cat[k].mean_rel <= worst))	/* NaN counts as worst */
					worst = x->cat[k].mean_rel;
			}
			bool ok = n > 0 && worst <= lim;
			printf("limit %-9s %-12s largest scene mean %.2f %% <= %.2f %% (%d scenes): %s\n",
			       cat, only[0] ? only : "(all)", 100 * worst, 100 * lim, n,
			       ok ? "ok" : n ? "EXCEEDED" : "NO SCENE");
			bad += !ok;
		}
	}
	if (c_locale) {
		uselocale(old);
		freelocale(c_locale);
	}
	fclose(f);
	return bad;
}

static void usage(FILE *f)
{
	fprintf(f,
		"usage: skybench accuracy [--out DIR] [--cache DIR] [--cache-ro DIR] [--device SEL]\n"
		"         [--runs N] [--threads N] [--day-error REL] [--twilight-error REL]\n"
		"         [--max-samples N] [--fisheye-n N] [--fisheye-error REL] [--no-images]\n"
		"         [--presets-only] [--reduced] [--scenes TEXT] [--configs A,B]\n"
		"         [--limits FILE]\n"
		"  --out DIR        where the CSVs (directions.csv: every direction), Markdown,\n"
		"                   plot and images go (accuracy-out)\n"
		"  --cache DIR      ground-truth cache, read and written (OUT/gt-cache)\n"
		"  --cache-ro DIR   a cache read first and never written (e.g. committed truth)\n"
		"  --list-truth     print each scene's ground-truth cache file name and exit\n"
		"  --reduced        the CI matrix: six scenes, default preset only\n"
		"  --scenes TEXT    only the scenes whose name contains TEXT\n"
		"  --configs A,B    only these configurations besides medium (low, high, ultra,\n"
		"                   T128x32, Mdirs2, S384x216, f16, ...: see accuracy.md)\n"
		"  --limits FILE    exit 1 when the default preset's largest per-scene mean\n"
		"                   relative error in a category exceeds the file's limit\n"
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
		size_t n = strlen(configs[c].name);
		for (const char *p = o->only; *p; p += strcspn(p, ","), p += *p == ',')
			if (strcspn(p, ",") == n && !strncmp(p, configs[c].name, n))
				return true;
		return false;
	}
	return !o->reduced && (configs[c].preset || (!o->presets_only && sc->sweep));
}

int bench_accuracy_main(int argc, char **argv)
{
	struct opts o = { .out = "accuracy-out", .runs = 3, .day_error = 0.01,
			  .twilight_error = 0.03, .max_samples = 1u << 20, .fisheye_n = 32,
			  .image_px = 256, .fisheye_error = 0.05 };
	char cmdline[1024] = "skybench accuracy", cache[4096];

	for (int i = 0; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		double d = 0;
		size_t len = strlen(cmdline);
		snprintf(cmdline + len, sizeof(cmdline) - len, " %s", a);
		if (!strcmp(a, "--help")) {
			usage(stdout);
			return 0;
		} else if (!strcmp(a, "--reduced")) {
			o.reduced = true;
		} else if (!strcmp(a, "--presets-only")) {
			o.presets_only = true;
		} else if (!strcmp(a, "--list-truth")) {
			o.list_truth = true;
		} else if (!strcmp(a, "--no-images")) {
			o.no_images = true;
		} else if (v && (!strcmp(a, "--out") || !strcmp(a, "--cache") || !strcmp(a, "--cache-ro") ||
				 !strcmp(a, "--device") || !strcmp(a, "--limits") || !strcmp(a, "--configs") ||
				 !strcmp(a, "--scenes"))) {
			const char **dst = !strcmp(a, "--out") ? &o.out : !strcmp(a, "--cache") ? &o.cache :
					   !strcmp(a, "--cache-ro") ? &o.cache_ro :
					   !strcmp(a, "--device") ? &o.device :
					   !strcmp(a, "--configs") ? &o.only :
					   !strcmp(a, "--scenes") ? &o.scene_filter : &o.limits;
			*dst = v;
			len = strlen(cmdline);
			snprintf(cmdline + len, sizeof(cmdline) - len, " %s", v);
			i++;
		} else if (v && parse_num(v, &d) == 0 && d >= 0) {
			if (!strcmp(a, "--runs") && d >= 1 && d <= 64)
				o.runs = (int)d;
			else if (!strcmp(a, "--threads") && d <= 256)
				o.threads = (int)d;
			else if (!strcmp(a, "--day-error") && d > 0)
				o.day_error = d;
			else if (!strcmp(a, "--twilight-error") && d > 0)
				o.twilight_error = d;
			else if (!strcmp(a, "--fisheye-error") && d > 0)
				o.fisheye_error = d;
			else if (!strcmp(a, "--max-samples") && d >= 4096)
				o.max_samples = (uint64_t)d;
			else if (!strcmp(a, "--fisheye-n") && d >= 4 && d <= 48)
				o.fisheye_n = (int)d;
			else {
				fprintf(stderr, "skybench: %s %s: bad option or value\n", a, v);
				return 2;
			}
			len = strlen(cmdline);
			snprintf(cmdline + len, sizeof(cmdline) - len, " %s", v);
			i++;
		} else {
			fprintf(stderr, "skybench: %s: unknown option or missing value\n", a);
			usage(stderr);
			return 2;
		}
	}
	if (!o.cache) {
		snprintf(cache, sizeof(cache), "%s/gt-cache", o.out);
		o.cache = cache;
	}
	if ((mkdir(o.out, 0777) < 0 && errno != EEXIST) || (mkdir(o.cache, 0777) < 0 && errno != EEXIST)) {
		fprintf(stderr, "skybench: cannot create '%s' or '%s': %s\n", o.out, o.cache, strerror(errno));
		return 1;
	}

	static struct scene sc[64];
	size_t n_sc = build_scenes(sc, 64, o.reduced);
	if (o.scene_filter) {
		size_t m = 0;
		for (size_t i = 0; i < n_sc; i++)
			if (strstr(sc[i].name, o.scene_filter))
				sc[m++] = sc[i];
		n_sc = m;
	}
	static struct gt gts[64];
	double t0 = now_s();
	int rc = 0;

	/* 1. Ground truth, cached. */
	for (size_t i = 0; i < n_sc && rc == 0; i++) {
		progress("truth", i, n_sc, sc[i].name, t0);
		direction_set(&gts[i]);
		rc = ground_truth(&o, &sc[i], sc[i].sun_elevation_deg >= 2 ? o.day_error : o.twilight_error,
				  &gts[i], "directions");
	}
	if (rc < 0)
		return 1;
	if (o.list_truth)
		return 0;
	progress("truth", n_sc, n_sc, "", t0);
	double gt_s = now_s() - t0;

	/* 2. The engine under every configuration. */
	struct eng *e;
	char err[512], device[800];
	if (eng_new(o.device, err, sizeof(err), &e) < 0) {
		/* 77: what ctest reports as skipped, for a machine without Vulkan. */
		fprintf(stderr, "skybench: %s\n", err);
		return 77;
	}
	const struct eng_device *dv = eng_device(e);
	if (!FITS(device, "%s (%s)", dv->name, dv->driver))
		device[sizeof(device) - 1] = 0;
	struct result *res = calloc(N_CONFIGS * n_sc, sizeof(*res));
	if (!res) {
		eng_free(e);
		return 1;
	}
	size_t todo = 0, done = 0;
	for (size_t c = 0; c < N_CONFIGS; c++)
		for (size_t i = 0; i < n_sc; i++)
			todo += runs_on(&o, c, &sc[i]);
	char dirs_path[4096];
	FILE *dirs = NULL;
	if (FITS(dirs_path, "%s/directions.csv", o.out))
		dirs = fopen(dirs_path, "w");
	if (!dirs)
		fprintf(stderr, "skybench: cannot write '%s/directions.csv'\n", o.out);
	else
		fprintf(dirs, "config,scene,category,elevation_deg,azimuth_deg,weight,tables_cd_m2,"
			      "truth_cd_m2,truth_se_cd_m2,rel\n");
	double t1 = now_s();
	for (size_t c = 0; c < N_CONFIGS && rc == 0; c++)
		for (size_t i = 0; i < n_sc && rc == 0; i++) {
			if (!runs_on(&o, c, &sc[i]))
				continue;
			char what[96];
			if (!FITS(what, "%s %s", configs[c].name, sc[i].name))
				what[sizeof(what) - 1] = 0;
			progress("tables", done++, todo, what, t1);
			struct sky_state s;
			struct result *x = &res[c * n_sc + i];
			rc = scene_state(&sc[i], &configs[c], &s);
			if (rc == 0)
				rc = time_tables(e, &s, o.runs, &x->time_ms);
			if (rc == 0) {
				measure(e, &s, &sc[i], configs[c].name, &gts[i], x, dirs);
				x->done = true;
			}
		}
	if (dirs && fclose(dirs) != 0)
		fprintf(stderr, "skybench: cannot write '%s'\n", dirs_path);
	if (rc == 0)
		progress("tables", todo, todo, "", t1);
	/* 3. Images of the default preset against the truth. */
	size_t n_fish = 0, k = 0;
	for (size_t i = 0; i < n_sc; i++)
		n_fish += sc[i].fisheye;
	double t2 = now_s();
	for (size_t i = 0; i < n_sc && rc == 0 && !o.no_images; i++)
		if (sc[i].fisheye) {
			progress("fisheye", k++, n_fish, sc[i].name, t2);
			rc = fisheye(&o, e, &sc[i]);
			if (k == n_fish)
				progress("fisheye", k, n_fish, "", t2);
		}
	double total_s = now_s() - t0;
	int status = rc < 0 ? 1 : 0;
	if (rc == 0) {
		if (write_csv(&o, sc, n_sc, res, device) < 0 ||
		    write_md(&o, sc, n_sc, res, device, cmdline, gt_s, total_s) < 0) {
			fprintf(stderr, "skybench: cannot write the report in '%s'\n", o.out);
			status = 1;
		}
		if (!o.no_images && write_plot(&o, sc, n_sc, res, dv->name) < 0)
			status = 1;
		struct summary s;
		summarize(sc, res, n_sc, DEFAULT_CONFIG, false, &s);
		printf("device: %s\n", device);
		printf("default preset over %d scenes: day %.2f %% (max %.2f), horizon %.2f %% (max %.2f), "
		       "twilight %.2f %% (max %.2f); tables %.1f ms; truth %.0f s, total %.0f s\n",
		       s.n_scenes, 100 * s.mean[0], 100 * s.max_mean[0], 100 * s.mean[1],
		       100 * s.max_mean[1], 100 * s.mean[2], 100 * s.max_mean[2], s.time_ms, gt_s,
		       total_s);
		printf("report: %s/accuracy.md, %s/accuracy.csv, %s/directions.csv\n", o.out, o.out, o.out);
		if (o.limits) {
			int bad = check_limits(o.limits, sc, n_sc, res);
			if (bad < 0) {
				fprintf(stderr, "skybench: '%s': %s\n", o.limits, strerror(-bad));
				status = 1;
			} else if (bad > 0) {
				status = 1;
			}
		}
	}
	free(res);
	eng_free(e);
	return status;
}

/* bench_accuracy_internal.h - what the files of `skybench accuracy` share:
 * the scenes, configurations, options, ground truth and results, and the
 * functions of each job (truth, measuring, images, reports). */
#ifndef SKYD_BENCH_ACCURACY_INTERNAL_H
#define SKYD_BENCH_ACCURACY_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "eng.h"
#include "pt.h"
#include "state.h"

#define MAX_DIRS 2048
#define MAX_KEYS 8
#define MAX_SCENE_KEYS 8

/* day: sun >= 2 deg, views >= 3 deg; horizon: sun >= 2 deg, views 0 to 3 deg;
 * twilight: sun < 2 deg, all views; down: sun >= 2 deg, views below the
 * observer's horizontal plane (the limb and the planet under it). The
 * scenes with clouds or terrain (shadowed) sort every view by the share of
 * its single scattering that they shadow (pt_shadow_fraction): lit under
 * SHADOW_LIT, in shadow from SHADOW_DARK (most of it), shafts between (the
 * view ray crosses lit and shadowed air). The tables' view ray goes on
 * through the clouds, so the air above a layer keeps most views up out of
 * the shadow. */
enum category {
	CAT_DAY = 0, CAT_HORIZON = 1, CAT_TWILIGHT = 2, CAT_DOWN = 3,
	CAT_LIT = 4, CAT_SHADOW = 5, CAT_SHAFTS = 6, N_CAT = 7
};
#define SHADOW_LIT 0.1
#define SHADOW_DARK 0.5
extern const char *const acc_cat_names[N_CAT];

struct scene {
	char name[48];
	const char *preset;
	double altitude_km, sun_elevation_deg, albedo; /* albedo < 0: the preset's */
	double scattering_scale;
	bool sweep;		/* also measured under the knob sweeps */
	bool fisheye;		/* gets a side-by-side image */
	bool down;		/* also views below the horizontal (acc_direction_set) */
	/* Clouds and terrain: keys applied after the rest ("terrain=@ridge":
	 * media_terrain_path's field); a scene with any is shadowed, its views
	 * cover the whole circle, and few keeps them to the CI's nine. */
	const char *keys[MAX_SCENE_KEYS];
	bool few;
};

struct config {
	const char *name;
	const char *keys[MAX_KEYS];	/* applied after quality=medium */
	bool preset;			/* a quality preset (else a sweep of one knob) */
};

/* The presets and the one-knob sweeps; the definition's length must match. */
#define N_CONFIGS 32
#define DEFAULT_CONFIG 1
extern const struct config acc_configs[];

struct opts {
	const char *out, *cache, *cache_ro, *device, *limits, *only, *scene_filter;
	int runs, threads, fisheye_n, image_px;
	double day_error, twilight_error, fisheye_error, shadow_error;
	uint64_t max_samples;
	bool reduced, presets_only, no_images, list_truth;
};

struct gt {
	size_t n;
	struct pt_dir dir[MAX_DIRS];
	double weight[MAX_DIRS];
	double lum[MAX_DIRS], lum_se[MAX_DIRS];
	double rgb[MAX_DIRS][3], rgb_se[MAX_DIRS][3];
	double shadow[MAX_DIRS];	/* shadowed scenes: pt_shadow_fraction; else 0 */
};

/* The error of one category of one scene. Luminance: mean_rel to gt_rel_se.
 * Per channel (R, G, B): the mean absolute and mean signed relative error,
 * the worst direction's signed error, where it is and the truth's relative
 * standard error there. Chromaticity: the CIE 1976 u'v' distance between the
 * tables' and the truth's colour (acc_uv), its mean, worst and where, and
 * the truth's own mean u'v' standard error. Gradient (day only): per
 * channel, grad_zl = how much the ratio of the low sky (views 3 to 10 deg)
 * to the zenith cap (views >= 65 deg) is off, (low/cap)_tables /
 * (low/cap)_truth - 1; grad_pair = the largest |(L_i/L_j)_tables /
 * (L_i/L_j)_truth - 1| over every pair of directions i, j and every
 * channel, at grad_el/grad_az (i, then j), and grad_pair_se the truth's
 * standard error of that ratio. */
struct stats {
	double weight, mean_rel, p95_rel, bias_rel, rmse_lum, worst_rel, worst_el, worst_az;
	double gt_rel_se;
	double ch_mean[3], ch_bias[3], ch_worst[3], ch_worst_el[3], ch_worst_az[3], ch_worst_se[3];
	double duv_mean, duv_worst, duv_worst_el, duv_worst_az, duv_se;
	double grad_zl[3], grad_pair, grad_pair_se, grad_el[2], grad_az[2];
	int grad_ch;
};

/* unshadowed: a shadowed scene whose tables read the same with its clouds
 * and terrain as without (acc_tables_unshadowed): the tables carry no
 * shadow yet, so its categories measure what leaving the shadows out
 * costs and --limits skips them. */
struct result {
	bool done, unshadowed;
	double time_ms;
	struct stats cat[N_CAT];
};

/* Error of a configuration over the scenes it ran on, per category: the
 * mean of the per-scene means (and the largest per-scene mean), the time as
 * the mean of the per-scene medians; per channel and of u'v' the same, and
 * the largest per-scene worst channel direction and u'v' mean. */
struct summary {
	double time_ms, mean[N_CAT], max_mean[N_CAT], p95[N_CAT], all;
	double ch_mean[N_CAT][3], ch_max_worst[N_CAT], duv_mean[N_CAT], duv_max_mean[N_CAT];
	int n_scenes, n_cat[N_CAT];
};

/* snprintf into a path-sized buffer; false when the result did not fit. */
#define FITS(buf, ...) (snprintf(buf, sizeof(buf), __VA_ARGS__) < (int)sizeof(buf))

static inline double luminance(const double rgb[3])
{
	return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* The CIE 1976 u'v' chromaticity of linear RGB, read as Rec. 709 / sRGB
 * primaries with a D65 white (whose Y row is luminance()'s weights). */
static inline void acc_uv(const double rgb[3], double ret_uv[2])
{
	double x = 0.4124 * rgb[0] + 0.3576 * rgb[1] + 0.1805 * rgb[2];
	double y = luminance(rgb);
	double z = 0.0193 * rgb[0] + 0.1192 * rgb[1] + 0.9505 * rgb[2];
	double d = x + 15.0 * y + 3.0 * z;
	ret_uv[0] = d > 0 ? 4.0 * x / d : 0.0;
	ret_uv[1] = d > 0 ? 9.0 * y / d : 0.0;
}

/* The u'v' distance between two linear RGB colours. */
static inline double acc_duv(const double a[3], const double b[3])
{
	double ua[2], ub[2];
	acc_uv(a, ua);
	acc_uv(b, ub);
	return hypot(ua[0] - ub[0], ua[1] - ub[1]);
}

/* qsort's comparison of doubles, ascending. */
static inline int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* ---- scenes and the ground truth (bench_accuracy_truth.c) ---- */

/* Whether sc has clouds or terrain. */
static inline bool acc_shadowed(const struct scene *sc)
{
	return sc->keys[0] != NULL;
}

/* Fills sc (at most max) with the matrix, or the CI's eight scenes when
 * reduced; returns how many. */
size_t acc_build_scenes(struct scene *sc, size_t max, bool reduced);
/* The state of a scene under a configuration (NULL: the default preset).
 * Returns 0 or -EINVAL (said on stderr). */
int acc_scene_state(const struct scene *sc, const struct config *cf, struct sky_state *ret);
/* g's directions for scene sc: the measured set, weighted for the sun's
 * mirror plane; views up while the observer is inside the atmosphere, and
 * for a scene marked down the limb (by tangent altitude) and the planet. */
void acc_direction_set(const struct scene *sc, struct gt *g);
/* The ground truth for g's directions: from the read-only cache, the cache,
 * or the path tracer (then written to the cache). kind names the set in the
 * cache file and in --list-truth. Returns 0 or -errno. */
int acc_ground_truth(const struct opts *o, const struct scene *sc, double rel_error, struct gt *g,
		     const char *kind);

/* ---- measuring the tables (bench_accuracy_measure.c) ---- */

/* The sky radiance a client reads from e's sky-view table of state s. */
void acc_table_radiance(const struct eng *e, const struct sky_state *s, double el_deg, double az_deg,
			double ret_rgb[3]);
/* The error statistics of e's tables of state s against g, per category,
 * in res; each direction's row goes to dirs (directions.csv) when open. */
void acc_measure(const struct eng *e, const struct sky_state *s, const struct scene *sc,
		 const char *config, const struct gt *g, struct result *res, FILE *dirs);
/* The tables a client's sky reads through acc_table_radiance, and those
 * they are computed from: the engine's cloud and shadow tables join them
 * when its cloud passes exist. */
#define ACC_SKY_TABLES (STATE_BIT(STATE_TRANSMITTANCE) | STATE_BIT(STATE_MULTISCATTER) | \
			STATE_BIT(STATE_SKYVIEW))
/* Computes the tables the sky needs once to warm up, then runs times; the
 * median wall time in ret_ms. Returns 0 or -EIO (said on stderr). */
int acc_time_tables(struct eng *e, const struct sky_state *s, int runs, double *ret_ms);
/* For a shadowed scene: whether e's tables read the same, bit for bit in
 * every direction of g, with the scene's clouds and terrain as without
 * (then the tables carry no shadow). Leaves e's tables those without.
 * Returns 0 or -EINVAL / -EIO (said on stderr). */
int acc_tables_unshadowed(struct eng *e, const struct scene *sc, const struct config *cf,
			  const struct gt *g, bool *ret);

/* ---- images (bench_accuracy_image.c) ---- */

/* fisheye-<scene>.png in o->out: the tables, the truth and the signed
 * error side by side. Returns 0 or -errno. */
int acc_fisheye(const struct opts *o, struct eng *e, const struct scene *sc);

/* ---- reports (bench_accuracy_report.c) ---- */

void acc_summarize(const struct scene *sc, const struct result *r, size_t n_sc, size_t cfg,
		   bool sweep_scenes_only, struct summary *ret);
/* accuracy.csv, accuracy.md and the plot (errtime.dat, .gp, .png by
 * gnuplot) in o->out. Each returns 0 or -errno. */
int acc_write_csv(const struct opts *o, const struct scene *sc, size_t n_sc, const struct result *r,
		  const char *device);
int acc_write_md(const struct opts *o, const struct scene *sc, size_t n_sc, const struct result *r,
		 const char *device, const char *cmdline, double gt_s, double total_s);
int acc_write_plot(const struct opts *o, const struct scene *sc, size_t n_sc, const struct result *r,
		   const char *device);
/* The colour part of accuracy.md (bench_accuracy_colour.c): the goals per
 * channel, of chromaticity and of the gradient, where each scene stands
 * against them, and every configuration's colour error. */
void acc_write_md_colour(FILE *f, const struct scene *sc, size_t n_sc, const struct result *r);
/* A metric of --limits by name, of one category of one scene; false when
 * there is no metric of that name. */
bool acc_metric(const char *name, const struct stats *st, double *ret);
/* --limits FILE: lines "category [metric] limit [scene]" for the default
 * preset's largest per-scene value of metric (lum_mean when left out; see
 * the file tests/accuracy_goals.txt for the others) over the scenes whose
 * name contains scene, or matches it as a pattern with '*' (every scene
 * without it); returns the number of
 * limits exceeded, or -errno. */
int acc_check_limits(const char *file, const struct scene *sc, size_t n_sc, const struct result *r);

#endif

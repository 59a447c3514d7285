/* bench_accuracy_measure.c - the tables of `skybench accuracy` read as a client
 * reads them, timed, and their error against the ground truth. */
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skysample.h"

/* The sky radiance a client reads: proto/skysample.h on the sky-view table. */
void acc_table_radiance(const struct eng *e, const struct sky_state *s, double el_deg,
			double az_deg, double ret_rgb[3])
{
	size_t bytes;
	struct skysample_table t = {
		.texels = eng_table(e, STATE_SKYVIEW, &bytes),
		.format = s->quality.storage == STATE_F16 ? SKY_FORMAT_RGBA16F : SKY_FORMAT_RGBA32F,
		.width = s->quality.t[STATE_SKYVIEW].width,
		.height = s->quality.t[STATE_SKYVIEW].height,
		.depth = 1,
		.rgb_scale_log2 = eng_table_scale_log2(e, STATE_SKYVIEW),
	};
	struct sky_shm_state st = { .altitude_km = s->altitude_km,
				    .bottom_radius_km = s->atmo.bottom_radius_km,
				    .top_radius_km = s->atmo.top_radius_km };
	skysample_sky(&t, &st, el_deg * M_PI / 180.0, az_deg * M_PI / 180.0, ret_rgb);
}

struct err_sample {
	double rel, weight;
};

static enum category category(const struct scene *sc, const struct gt *g, size_t i)
{
	double el_deg = g->dir[i].elevation_deg;
	if (acc_shadowed(sc))
		return g->shadow[i] < SHADOW_LIT ? CAT_LIT : g->shadow[i] >= SHADOW_DARK ? CAT_SHADOW : CAT_SHAFTS;
	if (sc->sun_elevation_deg < 2.0)
		return CAT_TWILIGHT;
	return el_deg < 0.0 ? CAT_DOWN : el_deg < 3.0 ? CAT_HORIZON : CAT_DAY;
}

/* The truth's standard error of u'v' at rgb, each channel's error carried
 * through by a finite difference (the channels are traced independently). */
static double duv_se(const double rgb[3], const double se[3])
{
	double v = 0;
	for (int c = 0; c < 3; c++) {
		double p[3] = { rgb[0], rgb[1], rgb[2] };
		p[c] += se[c];
		double d = acc_duv(p, rgb);
		v += d * d;
	}
	return sqrt(v);
}

/* One direction of a category, kept for the percentile and the gradient. */
struct dir_err {
	double rel[3], se[3], w, el, az;
};

/* The relative error of value against truth; an infinite one for a value
 * that is not finite, never a NaN that would vanish from the means. */
static double rel_error(double value, double truth)
{
	if (!isfinite(value))
		return INFINITY;
	return truth > 0 ? (value - truth) / truth : (value > 0 ? INFINITY : 0);
}

/* The gradient statistics of one category's n directions d into st. */
static void gradient(const struct dir_err *d, size_t n, struct stats *st)
{
	double low[2][3] = { { 0 } }, cap[2][3] = { { 0 } };
	st->grad_pair = 0;
	for (int c = 0; c < 3; c++) {
		size_t hi = 0, lo = 0;
		for (size_t i = 0; i < n; i++) {
			if (d[i].rel[c] > d[hi].rel[c])
				hi = i;
			if (d[i].rel[c] < d[lo].rel[c])
				lo = i;
			/* (1 + rel) is tables / truth: sums of both in the truth's unit. */
			double (*sum)[3] = d[i].el >= 65.0 ? cap : d[i].el <= 10.0 ? low : NULL;
			if (sum) {
				sum[0][c] += d[i].w * (1.0 + d[i].rel[c]);
				sum[1][c] += d[i].w;
			}
		}
		double pair = n ? (1.0 + d[hi].rel[c]) / (1.0 + d[lo].rel[c]) - 1.0 : 0.0;
		if (!(pair <= st->grad_pair)) {
			st->grad_pair = pair;
			st->grad_pair_se = hypot(d[hi].se[c], d[lo].se[c]);
			st->grad_el[0] = d[hi].el, st->grad_az[0] = d[hi].az;
			st->grad_el[1] = d[lo].el, st->grad_az[1] = d[lo].az;
			st->grad_ch = c;
		}
		st->grad_zl[c] = low[1][c] > 0 && cap[1][c] > 0 ?
			(low[0][c] / low[1][c]) / (cap[0][c] / cap[1][c]) - 1.0 : NAN;
	}
}

/* Sums of one category over its directions, turned into statistics. */
struct cat_acc {
	size_t n;
	double sum_sq, sum_se;
	struct dir_err *d;
};

/* Adds one direction i of g, read from the tables as rgb, to st and a. */
static void add_direction(const struct gt *g, size_t i, const double rgb[3], double rel_lum,
			  struct stats *st, struct cat_acc *a)
{
	double w = g->weight[i], el = g->dir[i].elevation_deg, az = g->dir[i].azimuth_deg;
	double y = luminance(rgb);
	struct dir_err *e = &a->d[a->n++];
	*e = (struct dir_err){ .w = w, .el = el, .az = az };
	st->weight += w;
	st->mean_rel += w * fabs(rel_lum);
	st->bias_rel += w * rel_lum;
	a->sum_sq += w * (y - g->lum[i]) * (y - g->lum[i]);
	a->sum_se += w * (g->lum[i] > 0 ? g->lum_se[i] / g->lum[i] : 0);
	if (!(fabs(rel_lum) <= fabs(st->worst_rel))) {
		st->worst_rel = rel_lum;
		st->worst_el = el;
		st->worst_az = az;
	}
	for (int c = 0; c < 3; c++) {
		double t = g->rgb[i][c];
		e->rel[c] = rel_error(rgb[c], t);
		e->se[c] = t > 0 ? g->rgb_se[i][c] / t : 0;
		st->ch_mean[c] += w * fabs(e->rel[c]);
		st->ch_bias[c] += w * e->rel[c];
		if (!(fabs(e->rel[c]) <= fabs(st->ch_worst[c]))) {
			st->ch_worst[c] = e->rel[c];
			st->ch_worst_el[c] = el;
			st->ch_worst_az[c] = az;
			st->ch_worst_se[c] = e->se[c];
		}
	}
	double duv = isfinite(y) ? acc_duv(rgb, g->rgb[i]) : INFINITY;
	st->duv_mean += w * duv;
	st->duv_se += w * duv_se(g->rgb[i], g->rgb_se[i]);
	if (!(duv <= st->duv_worst)) {
		st->duv_worst = duv;
		st->duv_worst_el = el;
		st->duv_worst_az = az;
	}
}

static int cmp_err(const void *a, const void *b)
{
	double x = ((const struct err_sample *)a)->rel, y = ((const struct err_sample *)b)->rel;
	return x < y ? -1 : x > y;
}

/* The weighted 95th percentile of |rel| of luminance over a's directions. */
static double p95(const struct cat_acc *a, const double *rel_lum_of, double weight)
{
	static struct err_sample es[MAX_DIRS];
	for (size_t i = 0; i < a->n; i++)
		es[i] = (struct err_sample){ fabs(rel_lum_of[i]), a->d[i].w };
	qsort(es, a->n, sizeof(es[0]), cmp_err);
	double acc = 0;
	for (size_t i = 0; i < a->n; i++) {
		acc += es[i].weight;
		if (acc >= 0.95 * weight)
			return es[i].rel;
	}
	return es[a->n - 1].rel;
}

/* Each direction's row goes to dirs (directions.csv) when it is open. */
void acc_measure(const struct eng *e, const struct sky_state *s, const struct scene *sc,
		 const char *config, const struct gt *g, struct result *res, FILE *dirs)
{
	static struct dir_err d[N_CAT][MAX_DIRS];
	static double rel_lum[N_CAT][MAX_DIRS];
	struct cat_acc a[N_CAT];

	for (int c = 0; c < N_CAT; c++) {
		a[c] = (struct cat_acc){ .d = d[c] };
		res->cat[c] = (struct stats){ .worst_el = NAN, .worst_az = NAN, .duv_worst_el = NAN,
					      .duv_worst_az = NAN };
		for (int k = 0; k < 3; k++)
			res->cat[c].ch_worst_el[k] = res->cat[c].ch_worst_az[k] = NAN;
	}
	for (size_t i = 0; i < g->n; i++) {
		double rgb[3];
		acc_table_radiance(e, s, g->dir[i].elevation_deg, g->dir[i].azimuth_deg, rgb);
		double y = luminance(rgb), rel = rel_error(y, g->lum[i]);
		enum category c = category(sc, g, i);
		if (dirs)
			fprintf(dirs, "%s,%s,%s,%g,%g,%g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.4f\n",
				config, sc->name, acc_cat_names[c], g->dir[i].elevation_deg,
				g->dir[i].azimuth_deg, g->weight[i], y, g->lum[i], g->lum_se[i], rel,
				rgb[0], rgb[1], rgb[2], g->rgb[i][0], g->rgb[i][1], g->rgb[i][2],
				isfinite(y) ? acc_duv(rgb, g->rgb[i]) : INFINITY, g->shadow[i]);
		rel_lum[c][a[c].n] = rel;
		add_direction(g, i, rgb, rel, &res->cat[c], &a[c]);
	}
	for (int c = 0; c < N_CAT; c++) {
		struct stats *st = &res->cat[c];
		if (!a[c].n)
			continue;
		double w = st->weight;
		st->mean_rel /= w;
		st->bias_rel /= w;
		st->rmse_lum = sqrt(a[c].sum_sq / w);
		st->gt_rel_se = a[c].sum_se / w;
		for (int k = 0; k < 3; k++) {
			st->ch_mean[k] /= w;
			st->ch_bias[k] /= w;
		}
		st->duv_mean /= w;
		st->duv_se /= w;
		st->p95_rel = p95(&a[c], rel_lum[c], w);
		gradient(a[c].d, a[c].n, st);
	}
}

/* Computes the tables the sky needs (transmittance, multi-scattering,
 * sky-view) once to warm up, then runs times; the median wall time. The
 * tables of the last run stay readable through eng_table. */
int acc_time_tables(struct eng *e, const struct sky_state *s, int runs, double *ret_ms)
{
	const uint32_t mask = ACC_SKY_TABLES;
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

/* The radiance of every direction of g in the tables of sc's state under cf. */
static int radiances(struct eng *e, const struct scene *sc, const struct config *cf,
		     const struct gt *g, double (*ret)[3])
{
	struct sky_state s;
	struct eng_timing t;
	char err[512];

	if (acc_scene_state(sc, cf, &s) < 0)
		return -EINVAL;
	if (eng_compute(e, &s, ACC_SKY_TABLES, &t, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return -EIO;
	}
	for (size_t i = 0; i < g->n; i++)
		acc_table_radiance(e, &s, g->dir[i].elevation_deg, g->dir[i].azimuth_deg, ret[i]);
	return 0;
}

int acc_tables_unshadowed(struct eng *e, const struct scene *sc, const struct config *cf,
			  const struct gt *g, bool *ret)
{
	static double with[MAX_DIRS][3], without[MAX_DIRS][3];
	struct scene clear = *sc;

	memset(clear.keys, 0, sizeof(clear.keys));
	int rc = radiances(e, sc, cf, g, with);
	if (rc == 0)
		rc = radiances(e, &clear, cf, g, without);
	if (rc == 0)
		*ret = memcmp(with, without, g->n * sizeof(with[0])) == 0;
	return rc;
}

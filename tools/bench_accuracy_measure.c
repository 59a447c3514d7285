/* bench_accuracy_measure.c - the tables of `skybench accuracy` read as a client
 * reads them, timed, and their error against the ground truth. */
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>

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
void acc_measure(const struct eng *e, const struct sky_state *s, const struct scene *sc,
		 const char *config, const struct gt *g, struct result *res, FILE *dirs)
{
	static struct err_sample es[N_CAT][MAX_DIRS];
	size_t n[N_CAT] = { 0 };
	double sum_sq[N_CAT] = { 0 }, sum_se[N_CAT] = { 0 };

	for (int c = 0; c < N_CAT; c++)
		res->cat[c] = (struct stats){ .worst_rel = 0, .worst_el = NAN, .worst_az = NAN };
	for (size_t i = 0; i < g->n; i++) {
		double rgb[3];
		acc_table_radiance(e, s, g->dir[i].elevation_deg, g->dir[i].azimuth_deg, rgb);
		double y = luminance(rgb), w = g->weight[i];
		/* A table value that is not finite is an infinite error, never a
		 * NaN that would vanish from the means. */
		double rel = !isfinite(y) ? INFINITY
			     : g->lum[i] > 0 ? (y - g->lum[i]) / g->lum[i] : (y > 0 ? INFINITY : 0);
		enum category c = category(sc, g->dir[i].elevation_deg);
		struct stats *st = &res->cat[c];
		if (dirs)
			fprintf(dirs, "%s,%s,%s,%g,%g,%g,%.6g,%.6g,%.6g,%.6g\n", config, sc->name,
				acc_cat_names[c], g->dir[i].elevation_deg, g->dir[i].azimuth_deg, w, y,
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

/* Computes the tables the sky needs (transmittance, multi-scattering,
 * sky-view) once to warm up, then runs times; the median wall time. The
 * tables of the last run stay readable through eng_table. */
int acc_time_tables(struct eng *e, const struct sky_state *s, int runs, double *ret_ms)
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

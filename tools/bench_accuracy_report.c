/* bench_accuracy_report.c - the reports of `skybench accuracy`: CSV, Markdown,
 * the error-against-time plot and the --limits check. */
#include "bench_accuracy_internal.h"

#include <errno.h>
#include <fnmatch.h>
#include <locale.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void acc_summarize(const struct scene *sc, const struct result *r, size_t n_sc, size_t cfg,
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
			const struct stats *st = &x->cat[c];
			if (!(st->weight > 0))
				continue;
			cnt[c]++;
			s.mean[c] += st->mean_rel;
			s.p95[c] += st->p95_rel;
			if (st->mean_rel > s.max_mean[c])
				s.max_mean[c] = st->mean_rel;
			for (int k = 0; k < 3; k++) {
				s.ch_mean[c][k] += st->ch_mean[k];
				if (!(fabs(st->ch_worst[k]) <= s.ch_max_worst[c]))
					s.ch_max_worst[c] = fabs(st->ch_worst[k]);
			}
			s.duv_mean[c] += st->duv_mean;
			if (!(st->duv_mean <= s.duv_max_mean[c]))
				s.duv_max_mean[c] = st->duv_mean;
			sum_all += x->cat[c].mean_rel * x->cat[c].weight;
			wall += x->cat[c].weight;
		}
	}
	if (s.n_scenes)
		s.time_ms /= s.n_scenes;
	for (int c = 0; c < N_CAT; c++) {
		s.n_cat[c] = cnt[c];
		if (cnt[c]) {
			s.mean[c] /= cnt[c];
			s.p95[c] /= cnt[c];
			s.duv_mean[c] /= cnt[c];
			for (int k = 0; k < 3; k++)
				s.ch_mean[c][k] /= cnt[c];
		}
	}
	s.all = wall > 0 ? sum_all / wall : NAN;
	*ret = s;
}

int acc_write_csv(const struct opts *o, const struct scene *sc, size_t n_sc,
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
		   "worst_rel,worst_elevation_deg,worst_azimuth_deg,gt_rel_se,"
		   "mean_rel_r,mean_rel_g,mean_rel_b,bias_rel_r,bias_rel_g,bias_rel_b,"
		   "worst_rel_r,worst_rel_g,worst_rel_b,duv_mean,duv_worst,duv_worst_elevation_deg,"
		   "duv_worst_azimuth_deg,duv_gt_se,grad_zl_r,grad_zl_g,grad_zl_b,grad_pair,grad_pair_se\n");
	fprintf(f, "# the sun at azimuth 180 deg; rel = (tables - truth) / truth of luminance, "
		   "then per channel (_r _g _b); duv: CIE 1976 u'v' distance (Rec. 709 primaries, "
		   "D65); grad_zl: (low sky / zenith cap) of the tables over the truth's, minus 1; "
		   "grad_pair: the worst such ratio over pairs of directions and channels\n");
	for (size_t c = 0; c < N_CONFIGS; c++)
		for (size_t i = 0; i < n_sc; i++) {
			const struct result *x = &r[c * n_sc + i];
			if (!x->done)
				continue;
			for (int k = 0; k < N_CAT; k++) {
				const struct stats *st = &x->cat[k];
				if (!(st->weight > 0))
					continue;
				fprintf(f, "%s,%s,%s,%.4f,%.6f,%.6f,%.6f,%.6g,%.6f,%g,%g,%.6f",
					acc_configs[c].name, sc[i].name, acc_cat_names[k], x->time_ms, st->mean_rel,
					st->p95_rel, st->bias_rel, st->rmse_lum, st->worst_rel,
					st->worst_el, st->worst_az, st->gt_rel_se);
				for (int ch = 0; ch < 3; ch++)
					fprintf(f, ",%.6f", st->ch_mean[ch]);
				for (int ch = 0; ch < 3; ch++)
					fprintf(f, ",%.6f", st->ch_bias[ch]);
				for (int ch = 0; ch < 3; ch++)
					fprintf(f, ",%.6f", st->ch_worst[ch]);
				fprintf(f, ",%.6f,%.6f,%g,%g,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n", st->duv_mean,
					st->duv_worst, st->duv_worst_el, st->duv_worst_az, st->duv_se,
					st->grad_zl[0], st->grad_zl[1], st->grad_zl[2], st->grad_pair,
					st->grad_pair_se);
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

static bool any_shadowed(const struct scene *sc, size_t n_sc)
{
	for (size_t i = 0; i < n_sc; i++)
		if (acc_shadowed(&sc[i]))
			return true;
	return false;
}

/* How many shadowed scenes of the default preset have tables without shadow. */
static int n_unshadowed(const struct result *r, size_t n_sc, const struct scene *sc)
{
	int n = 0;
	for (size_t i = 0; i < n_sc; i++)
		n += r[DEFAULT_CONFIG * n_sc + i].done && acc_shadowed(&sc[i]) &&
		     r[DEFAULT_CONFIG * n_sc + i].unshadowed;
	return n;
}

int acc_write_md(const struct opts *o, const struct scene *sc, size_t n_sc,
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
		   "views >= 3 deg; horizon: sun >= 2 deg, views 0 to 3 deg; twilight: sun < 2 deg, "
		   "all views; down: sun >= 2 deg, views below the observer's horizontal (the "
		   "limb and the planet beneath, for the observers above 1 km). Time: engine wall time of transmittance + multi-scattering + "
		   "sky-view, mean over scenes of the median of %d runs.\n\n", o->runs);
	if (any_shadowed(sc, n_sc))
		fprintf(f, "Shadowed scenes (shadow-*): clouds or terrain, which shade the air "
			   "(docs/truth.md, \"Clouds and terrain\"). Their views go round the whole "
			   "circle (8 azimuths, elevations 2 to 70 deg and the zenith; the CI's: 4 "
			   "azimuths, 5 and 30 deg and the zenith; from 12 km also 2 limb rings, 2 "
			   "rings below the horizon and the nadir), the truth to %.3g of the radiance, "
			   "and each view is sorted by the share of the single scattering along its "
			   "ray (the tables' view ray, through the clouds) that the clouds and terrain "
			   "shadow: lit under %g, shadow from %g, shafts between.\n\n",
			o->shadow_error, SHADOW_LIT, SHADOW_DARK);
	int n_un = n_unshadowed(r, n_sc, sc);
	if (n_un)
		fprintf(f, "In %d of these scenes (marked * below) the tables read the same, bit for "
			   "bit, with the clouds and terrain as without: the tables have lost the "
			   "scene's shadows, those rows measure what leaving them out costs, and "
			   "--limits fails them.\n\n", n_un);
	for (int pass = 0; pass < 2; pass++) {
		struct summary sum[N_CONFIGS];
		bool cat_in[N_CAT] = { false };
		for (size_t c = 0; c < N_CONFIGS; c++) {
			acc_summarize(sc, r, n_sc, c, !pass, &sum[c]);
			for (int k = 0; k < N_CAT; k++)
				cat_in[k] |= sum[c].n_cat[k] > 0 && (!pass || acc_configs[c].preset);
		}
		fprintf(f, pass ? "\nThe presets over every scene of the matrix:\n\n"
				: "Every configuration over the same scenes (those the sweeps run on):\n\n");
		fprintf(f, "| config | scenes | time ms |");
		for (int k = 0; k < N_CAT; k++)
			if (cat_in[k])
				fprintf(f, " %s mean (max) | %s p95 |", acc_cat_names[k], acc_cat_names[k]);
		fprintf(f, "\n| --- | ---: | ---: |");
		for (int k = 0; k < N_CAT; k++)
			if (cat_in[k])
				fprintf(f, " ---: | ---: |");
		fputc('\n', f);
		for (size_t c = 0; c < N_CONFIGS; c++) {
			const struct summary *s = &sum[c];
			if ((pass && !acc_configs[c].preset) || !s->n_scenes)
				continue;
			fprintf(f, "| %s | %d | %.1f |", acc_configs[c].name, s->n_scenes, s->time_ms);
			for (int k = 0; k < N_CAT; k++) {
				if (!cat_in[k])
					continue;
				if (s->n_cat[k])
					fprintf(f, " %.1f (%.1f) |", 100 * s->mean[k], 100 * s->max_mean[k]);
				else
					fprintf(f, " - |");
				pct(f, s->n_cat[k] ? s->p95[k] : NAN);
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
			fprintf(f, "| %s%s | %.1f | %s | %.1f | %.1f | %+.1f | %.4g | %+.1f at %g/%g | %.2f |\n",
				sc[i].name, x->unshadowed ? " *" : "", x->time_ms, acc_cat_names[k], 100 * st->mean_rel,
				100 * st->p95_rel, 100 * st->bias_rel, st->rmse_lum,
				100 * st->worst_rel, st->worst_el, st->worst_az,
				100 * st->gt_rel_se);
		}
	}
	acc_write_md_colour(f, sc, n_sc, r);
	return fclose(f) ? -errno : 0;
}

int acc_write_plot(const struct opts *o, const struct scene *sc, size_t n_sc,
		   const struct result *r, const char *device)
{
	char path[4096];
	struct summary s[N_CONFIGS];
	for (size_t c = 0; c < N_CONFIGS; c++)
		acc_summarize(sc, r, n_sc, c, !o->reduced && !o->only, &s[c]);
	if (!FITS(path, "%s/errtime.dat", o->out))
		return -ENAMETOOLONG;
	FILE *f = fopen(path, "we");
	if (!f)
		return -errno;
	fprintf(f, "# config time_ms all_mean day_mean horizon_mean twilight_mean pareto day_r day_g day_b "
		   "day_duv horizon_r horizon_g horizon_b\n");
	for (size_t c = 0; c < N_CONFIGS; c++) {
		if (!s[c].n_scenes)
			continue;
		/* Pareto-optimal: no other config is both faster and more accurate. */
		bool front = isfinite(s[c].all);
		for (size_t d = 0; d < N_CONFIGS; d++)
			if (d != c && s[d].n_scenes && isfinite(s[d].all) && s[d].time_ms <= s[c].time_ms &&
			    s[d].all <= s[c].all && (s[d].time_ms < s[c].time_ms || s[d].all < s[c].all))
				front = false;
		fprintf(f, "%s %.4f %.6f %.6f %.6f %.6f %d %.6f %.6f %.6f %.6f %.6f %.6f %.6f\n",
			acc_configs[c].name, s[c].time_ms, s[c].all, s[c].mean[0], s[c].mean[1], s[c].mean[2],
			front, s[c].ch_mean[CAT_DAY][0], s[c].ch_mean[CAT_DAY][1], s[c].ch_mean[CAT_DAY][2],
			s[c].duv_mean[CAT_DAY], s[c].ch_mean[CAT_HORIZON][0], s[c].ch_mean[CAT_HORIZON][1],
			s[c].ch_mean[CAT_HORIZON][2]);
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
		   "     '' using 2:6 with points pt 11 lc rgb 'purple' title 'twilight'\n"
		   "set output 'errtime-rgb.png'\n"
		   "set terminal pngcairo size 1400,600 noenhanced\n"
		   "set multiplot layout 1,2 title 'skybench accuracy: colour error against run time over the sweep scenes (day views)'\n"
		   "set title 'mean relative error per channel and of luminance'\n"
		   "set ylabel 'mean relative error'\nset xlabel 'engine time (ms)'\n"
		   "plot 'errtime.dat' using 2:4 with points pt 6 ps 1.4 lc rgb 'black' title 'luminance', \\\n"
		   "     '' using 2:8 with points pt 7 lc rgb 'red' title 'R (680 nm)', \\\n"
		   "     '' using 2:9 with points pt 7 lc rgb 'dark-green' title 'G (550 nm)', \\\n"
		   "     '' using 2:10 with points pt 7 lc rgb 'blue' title 'B (440 nm)', \\\n"
		   "     '' using 2:10:1 with labels offset 1,0.6 font ',7' notitle, \\\n"
		   "     0.03 with lines dt 2 lc rgb 'gray' title 'goal 3 %%'\n"
		   "set title \"mean CIE 1976 u'v' difference\"\n"
		   "set ylabel \"mean u'v' difference\"\n"
		   "plot 'errtime.dat' using 2:11 with points pt 7 lc rgb 'black' title \"u'v'\", \\\n"
		   "     '' using 2:11:1 with labels offset 1,0.6 font ',7' notitle, \\\n"
		   "     0.003 with lines dt 2 lc rgb 'gray' title 'goal 0.003'\n"
		   "unset multiplot\n", device);
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

/* --limits FILE: lines "category [metric] limit [scene]" for the default
 * preset's largest per-scene value of metric (lum_mean when left out) over
 * the scenes whose name contains scene, or matches it when it holds a '*'
 * (fnmatch; every scene without it); returns
 * the number of limits exceeded, or -errno. */
int acc_check_limits(const char *file, const struct scene *sc, size_t n_sc,
		     const struct result *r)
{
	FILE *f = fopen(file, "re");
	if (!f)
		return -errno;
	char line[256], cat[64], metric[64], only[64], num[64];
	double lim;
	int bad = 0;
	locale_t c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
	locale_t old = c_locale ? uselocale(c_locale) : (locale_t)0;
	while (fgets(line, sizeof(line), f)) {
		only[0] = 0;
		if (line[0] == '#' || sscanf(line, "%63s %63s", cat, num) < 2)
			continue;
		/* The old form "category limit [scene]" checks luminance. */
		if (sscanf(line, "%63s %lf %63s", cat, &lim, only) >= 2) {
			snprintf(metric, sizeof(metric), "lum_mean");
		} else if (sscanf(line, "%63s %63s %lf %63s", cat, metric, &lim, only) < 3) {
			fprintf(stderr, "skybench: %s: cannot read '%s'\n", file, line);
			bad++;
			continue;
		}
		if (only[0] == '#')
			only[0] = 0;	/* a comment, not a scene */
		int k = 0;
		while (k < N_CAT && strcmp(cat, acc_cat_names[k]))
			k++;
		double worst = 0.0, v;
		int n = 0, lost = 0;
		for (size_t i = 0; k < N_CAT && i < n_sc; i++) {
			const struct result *x = &r[DEFAULT_CONFIG * n_sc + i];
			bool in = strchr(only, '*') ? fnmatch(only, sc[i].name, 0) == 0 : !!strstr(sc[i].name, only);
			if (!x->done || !(x->cat[k].weight > 0) || !in)
				continue;
			if (x->unshadowed) {
				lost++;
				continue;
			}
			if (!acc_metric(metric, &x->cat[k], &v)) {
				n = -1;
				break;
			}
			if (n++ == 0 || !(v <= worst))	/* NaN counts as worst */
				worst = v;
		}
		/* The engine casts the scenes' shadows: a shadowed scene whose
		 * tables read the same without its clouds and terrain has lost
		 * them, whatever its error. */
		if (lost > 0) {
			printf("limit %-9s %-13s %-12s NO SHADOW in %d scenes: their tables read the same "
			       "without the clouds and terrain\n", cat, metric, only[0] ? only : "(all)", lost);
			bad++;
			continue;
		}
		bool ok = n > 0 && worst <= lim;
		printf("limit %-9s %-13s %-12s largest scene %.4g <= %.4g (%d scenes): %s\n", cat, metric,
		       only[0] ? only : "(all)", worst, lim, n,
		       ok ? "ok" : n > 0 ? "EXCEEDED" : n < 0 ? "NO SUCH METRIC" : "NO SCENE");
		bad += !ok;
	}
	if (c_locale) {
		uselocale(old);
		freelocale(c_locale);
	}
	fclose(f);
	return bad;
}

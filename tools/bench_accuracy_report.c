/* bench_accuracy_report.c - the reports of `skybench accuracy`: CSV, Markdown,
 * the error-against-time plot and the --limits check. */
#include "bench_accuracy_internal.h"

#include <errno.h>
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
					acc_configs[c].name, sc[i].name, acc_cat_names[k], x->time_ms, st->mean_rel,
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
			if (pass && !acc_configs[c].preset)
				continue;
			acc_summarize(sc, r, n_sc, c, !pass, &s);
			if (!s.n_scenes)
				continue;
			fprintf(f, "| %s | %d | %.1f |", acc_configs[c].name, s.n_scenes, s.time_ms);
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
				sc[i].name, x->time_ms, acc_cat_names[k], 100 * st->mean_rel,
				100 * st->p95_rel, 100 * st->bias_rel, st->rmse_lum,
				100 * st->worst_rel, st->worst_el, st->worst_az,
				100 * st->gt_rel_se);
		}
	}
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
		fprintf(f, "%s %.4f %.6f %.6f %.6f %.6f %d\n", acc_configs[c].name, s[c].time_ms, s[c].all,
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
int acc_check_limits(const char *file, const struct scene *sc, size_t n_sc,
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
			if (strcmp(cat, acc_cat_names[k]))
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

/* bench_accuracy_colour.c - the colour part of `skybench accuracy`'s report:
 * the error of each channel, of chromaticity and of the sky's gradient, the
 * goals they are held to, and the metrics that --limits names. */
#include "bench_accuracy_internal.h"

#include <math.h>
#include <string.h>

static const char ch_names[3] = { 'R', 'G', 'B' };

static double max3_abs(const double v[3])
{
	double m = 0;
	for (int k = 0; k < 3; k++)
		if (!(fabs(v[k]) <= m))
			m = fabs(v[k]);
	return m;
}

/* The largest |worst| - 2 standard errors of the truth there, over the
 * channels: a worst direction that noise alone cannot explain. */
static double worst_beyond_noise(const struct stats *st)
{
	double m = -INFINITY;
	for (int k = 0; k < 3; k++) {
		double v = fabs(st->ch_worst[k]) - 2.0 * st->ch_worst_se[k];
		if (!(v <= m))
			m = v;
	}
	return m;
}

bool acc_metric(const char *name, const struct stats *st, double *ret)
{
	static const char *const ch_mean[3] = { "r_mean", "g_mean", "b_mean" };
	for (int k = 0; k < 3; k++)
		if (!strcmp(name, ch_mean[k])) {
			*ret = st->ch_mean[k];
			return true;
		}
	double v = !strcmp(name, "lum_mean") ? st->mean_rel
		 : !strcmp(name, "ch_mean") ? max3_abs(st->ch_mean)
		 : !strcmp(name, "ch_worst") ? max3_abs(st->ch_worst)
		 : !strcmp(name, "ch_worst_2se") ? worst_beyond_noise(st)
		 : !strcmp(name, "duv_mean") ? st->duv_mean
		 : !strcmp(name, "duv_worst") ? st->duv_worst
		 : !strcmp(name, "grad_zl") ? max3_abs(st->grad_zl)
		 : !strcmp(name, "grad_pair") ? st->grad_pair
		 : !strcmp(name, "grad_pair_2se") ? st->grad_pair - 2.0 * st->grad_pair_se
		 : -HUGE_VAL;
	if (v == -HUGE_VAL)
		return false;
	*ret = v;
	return true;
}

/* The goals for the default preset, every scene and observer. */
struct goal {
	enum category cat;
	const char *metric, *what;
	double limit;
	bool percent;
};

static const struct goal goals[] = {
	{ CAT_DAY, "ch_mean", "day: each channel's mean", 0.03, true },
	{ CAT_DAY, "ch_worst", "day: each channel's worst direction", 0.04, true },
	{ CAT_DAY, "ch_worst_2se", "day: the same, less 2 standard errors of the truth there", 0.04, true },
	{ CAT_DAY, "duv_mean", "day: u'v' mean", 0.003, false },
	{ CAT_DAY, "grad_zl", "day: low sky / zenith cap, each channel", 0.05, true },
	{ CAT_DAY, "grad_pair", "day: any two directions, each channel", 0.05, true },
	{ CAT_DAY, "grad_pair_2se", "day: the same, less 2 standard errors of the ratio", 0.05, true },
	{ CAT_HORIZON, "ch_mean", "horizon: each channel's mean", 0.10, true },
	{ CAT_TWILIGHT, "ch_mean", "twilight: each channel's mean", 0.10, true },
	{ CAT_DOWN, "ch_mean", "down (limb and planet): each channel's mean", 0.10, true },
};

static void value(FILE *f, double v, bool percent)
{
	if (percent)
		fprintf(f, "%.1f %%", 100 * v);
	else
		fprintf(f, "%.4f", v);
}

/* The goals table: per goal, how many scenes meet it and the largest. */
static void write_goals(FILE *f, const struct scene *sc, size_t n_sc, const struct result *r)
{
	fprintf(f, "| goal | limit | scenes that meet it | largest (scene) |\n"
		   "| --- | ---: | ---: | --- |\n");
	for (size_t g = 0; g < sizeof(goals) / sizeof(goals[0]); g++) {
		const struct goal *q = &goals[g];
		int n = 0, met = 0;
		double worst = -INFINITY;
		size_t at = 0;
		for (size_t i = 0; i < n_sc; i++) {
			const struct result *x = &r[DEFAULT_CONFIG * n_sc + i];
			double v;
			if (!x->done || !(x->cat[q->cat].weight > 0) || !acc_metric(q->metric, &x->cat[q->cat], &v))
				continue;
			n++;
			met += v <= q->limit;
			if (!(v <= worst)) {
				worst = v;
				at = i;
			}
		}
		if (!n)
			continue;
		fprintf(f, "| %s | ", q->what);
		value(f, q->limit, q->percent);
		fprintf(f, " | %d of %d | ", met, n);
		value(f, worst, q->percent);
		fprintf(f, " (%s) |\n", sc[at].name);
	}
}

/* "R/G/B" of three relative errors in %. */
static void triple(FILE *f, const double v[3])
{
	fprintf(f, " %.1f / %.1f / %.1f |", 100 * v[0], 100 * v[1], 100 * v[2]);
}

/* Every configuration's colour error over the scenes of pass (0: those of
 * the sweeps, 1: every scene, presets only). */
static void write_configs(FILE *f, const struct scene *sc, size_t n_sc, const struct result *r, int pass)
{
	fprintf(f, "| config | scenes | day R / G / B mean | day worst | day u'v' mean (max) | "
		   "horizon R / G / B mean | twilight R / G / B mean |\n"
		   "| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n");
	for (size_t c = 0; c < N_CONFIGS; c++) {
		struct summary s;
		if (pass && !acc_configs[c].preset)
			continue;
		acc_summarize(sc, r, n_sc, c, !pass, &s);
		if (!s.n_scenes)
			continue;
		fprintf(f, "| %s | %d |", acc_configs[c].name, s.n_scenes);
		triple(f, s.ch_mean[CAT_DAY]);
		fprintf(f, " %.1f | %.4f (%.4f) |", 100 * s.ch_max_worst[CAT_DAY], s.duv_mean[CAT_DAY],
			s.duv_max_mean[CAT_DAY]);
		for (int k = CAT_HORIZON; k <= CAT_TWILIGHT; k++) {
			if (s.n_cat[k])
				triple(f, s.ch_mean[k]);
			else
				fprintf(f, " - |");
		}
		fputc('\n', f);
	}
}

/* One scene's row of the default preset's colour table. */
static void write_scene_row(FILE *f, const struct scene *sc, int k, const struct stats *st)
{
	int w = 0;
	for (int c = 1; c < 3; c++)
		if (!(fabs(st->ch_worst[c]) <= fabs(st->ch_worst[w])))
			w = c;
	fprintf(f, "| %s | %s |", sc->name, acc_cat_names[k]);
	for (int c = 0; c < 3; c++)
		fprintf(f, " %.1f (%+.1f) |", 100 * st->ch_mean[c], 100 * st->ch_bias[c]);
	fprintf(f, " %c %+.1f at %g/%g (%.1f) | %.4f / %.4f at %g/%g (%.4f) |", ch_names[w],
		100 * st->ch_worst[w], st->ch_worst_el[w], st->ch_worst_az[w], 100 * st->ch_worst_se[w],
		st->duv_mean, st->duv_worst, st->duv_worst_el, st->duv_worst_az, st->duv_se);
	if (k == CAT_DAY)
		fprintf(f, " %+.1f / %+.1f / %+.1f | %c %+.1f: %g/%g over %g/%g (%.1f) |\n",
			100 * st->grad_zl[0], 100 * st->grad_zl[1], 100 * st->grad_zl[2],
			ch_names[st->grad_ch], 100 * st->grad_pair, st->grad_el[0], st->grad_az[0],
			st->grad_el[1], st->grad_az[1], 100 * st->grad_pair_se);
	else
		fprintf(f, " - | - |\n");
}

void acc_write_md_colour(FILE *f, const struct scene *sc, size_t n_sc, const struct result *r)
{
	fprintf(f,
		"\n## Colour: each channel, chromaticity and the gradient\n\n"
		"Luminance weighs blue, the colour of the sky, 7 %%; these figures weigh each "
		"channel alike. Per channel: the relative error of R, G and B (the tables' "
		"linear RGB at 680, 550 and 440 nm, proto/PROTOCOL.md), mean of |error| and the "
		"worst direction's signed error. Chromaticity: the CIE 1976 u'v' distance "
		"between the tables' colour and the truth's, reading the channels as the "
		"Rec. 709 / sRGB primaries with a D65 white (the usual renderer's assumption; "
		"its Y row is the luminance weights 0.2126, 0.7152, 0.0722): X = 0.4124 R + "
		"0.3576 G + 0.1805 B, Z = 0.0193 R + 0.1192 G + 0.9505 B, u' = 4X / (X + 15Y + "
		"3Z), v' = 9Y / (X + 15Y + 3Z). 0.003 in u'v' is about one just-noticeable "
		"difference between two patches side by side (MacAdam's ellipses are 0.001 "
		"to 0.004 across): the blue channel of a day sky 1 %% short against red and "
		"green moves its u'v' by 0.001, 3 %% by 0.003, 5 %% by 0.004 to 0.005. Gradient (day views, per channel): how much the tables "
		"flatten or steepen the sky from the zenith to the horizon, as the ratio of "
		"the low sky (views 3 to 10 deg, mean over azimuth) to the zenith cap (views "
		"65 deg and up) in the tables over the same ratio in the truth, minus 1 "
		"(negative: the horizon too dark against the zenith); and over every pair of "
		"day directions i, j and every channel, the largest |(L_i / L_j)_tables / "
		"(L_i / L_j)_truth - 1|, which is (1 + the channel's largest error) / (1 + its "
		"smallest) - 1.\n\n"
		"The goals, for the default preset on every scene and observer: each channel "
		"at most 3 %% mean and 4 %% in the worst direction by day, 10 %% mean on the "
		"horizon band, in twilight and looking down at the limb (the rays graze the "
		"air as the horizon band's do); u'v' at most 0.003 mean by day; the gradient "
		"within 5 %%. The worst direction and the pair are read against the truth's "
		"own noise: a row \"less 2 standard errors\" counts a scene when |error| - 2 "
		"se <= the limit, the error that noise alone cannot explain. Observers "
		"(Earth): 1 m, 0.2, 2, 10 and 30 km look up (day, horizon); 2, 30, 100 and 400 "
		"km also look down (down: rays that graze the air at tangent altitudes of 80 "
		"km to 0.5 km, then 1, 5 and 20 deg below the geometric horizon, and the "
		"nadir); from 100 km (the top of Earth's atmosphere) and 400 km (the ISS) "
		"there is no air above, so they look down only. The same goals hold for every "
		"observer; what bounds the limb from 100 and 400 km is in docs/findings/tools.md, "
		"\"Colour and observers from the ground to orbit\".\n\n");
	write_goals(f, sc, n_sc, r);
	fprintf(f, "\nEvery configuration over the scenes of the sweeps, per channel "
		   "(R / G / B, mean relative error in %%, mean of the per-scene means), the "
		   "largest per-scene worst channel direction in %% and u'v':\n\n");
	write_configs(f, sc, n_sc, r, 0);
	fprintf(f, "\nThe presets over every scene:\n\n");
	write_configs(f, sc, n_sc, r, 1);
	fprintf(f, "\nDefault preset (medium), per scene: each channel's mean relative error "
		   "(bias) in %%; the worst channel direction (elevation/azimuth, the sun at "
		   "180; the truth's relative standard error there in brackets); u'v' mean / "
		   "worst at (the truth's mean u'v' standard error); the gradient low sky / "
		   "zenith cap R / G / B in %%, and the worst pair (i over j; the ratio's "
		   "standard error in brackets).\n\n"
		   "| scene | category | R | G | B | worst | u'v' | gradient R / G / B | worst pair |\n"
		   "| --- | --- | ---: | ---: | ---: | --- | --- | ---: | --- |\n");
	for (size_t i = 0; i < n_sc; i++) {
		const struct result *x = &r[DEFAULT_CONFIG * n_sc + i];
		if (!x->done)
			continue;
		for (int k = 0; k < N_CAT; k++)
			if (x->cat[k].weight > 0)
				write_scene_row(f, &sc[i], k, &x->cat[k]);
	}
}

/* skybench.c - benchmarks of the engine (not tests): `skybench perf` runs
 * each table N times on the chosen device and prints median and spread. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_stability.h"
#include "bench_demand.h"
#include "bench_accuracy.h"
#include "eng.h"
#include "state.h"

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* Median, 10th and 90th percentile of n samples (sorted in place). */
static void summarize(double *v, int n, double *med, double *p10, double *p90)
{
	qsort(v, n, sizeof(*v), cmp_double);
	*med = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
	*p10 = v[n / 10];
	*p90 = v[n - 1 - n / 10];
}

/* CPU time of the whole process, lavapipe's worker threads included: on a
 * shared machine it says what the work costs when wall time cannot. */
static double cpu_ms(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* cold: every run from scratch (the kept column densities dropped first),
 * as after a change of the atmosphere's geometry or profiles. */
static int run(struct eng *e, const struct sky_state *s, uint32_t mask, int runs, const char *label,
	       bool gpu_time_of_one, bool cold)
{
	double *ms = calloc(runs, sizeof(double)), *cpu = calloc(runs, sizeof(double));
	char err[512];
	struct eng_timing t;

	if (!ms || !cpu) {
		free(ms);
		free(cpu);
		return -ENOMEM;
	}
	for (int i = 0; i < runs; i++) {
		if (cold)
			eng_forget_columns(e);
		double c0 = cpu_ms();
		int rc = eng_compute(e, s, mask, &t, err, sizeof(err));
		cpu[i] = cpu_ms() - c0;
		if (rc < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			free(ms);
			free(cpu);
			return rc;
		}
		ms[i] = t.total_ms;
		if (gpu_time_of_one)
			for (int k = 0; k < STATE_N_TABLES; k++)
				if (mask == STATE_BIT(k) && t.table_ms[k] > 0)
					ms[i] = t.table_ms[k];
	}
	double med, lo, hi, cpu_med, cpu_lo, cpu_hi;
	summarize(ms, runs, &med, &lo, &hi);
	summarize(cpu, runs, &cpu_med, &cpu_lo, &cpu_hi);
	printf("%-32s median %8.3f ms   p10 %8.3f   p90 %8.3f   cpu %8.3f ms   (%d runs)\n", label,
	       med, lo, hi, cpu_med, runs);
	free(ms);
	free(cpu);
	return 0;
}

/* The cloud passes where layers are drawn: a new field at each run
 * (cloud_seed alternating), so that the coverage table and the shadow maps
 * are both remade; their own GPU times (timestamps), which sky-view's row
 * counts as well. */
static int cloud_rows(struct eng *e, const struct sky_state *base, int runs)
{
	double *ms[2] = { calloc(runs, sizeof(double)), calloc(runs, sizeof(double)) };
	static const char *const labels[2] = { "cloud (GPU time)", "shadow (GPU time)" };
	struct sky_state s = *base;
	struct eng_timing t;
	char err[512];
	int rc = ms[0] && ms[1] ? 0 : -ENOMEM;

	for (int i = 0; i < runs && rc == 0; i++) {
		s.clouds.seed = base->clouds.seed + 1 + (uint32_t)(i % 2);
		rc = eng_compute(e, &s, STATE_BIT(STATE_SKYVIEW), &t, err, sizeof(err));
		if (rc < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			break;
		}
		ms[0][i] = t.cloud_ms;
		ms[1][i] = t.shadow_ms;
	}
	for (int k = 0; k < 2 && rc == 0; k++) {
		double med, lo, hi;
		summarize(ms[k], runs, &med, &lo, &hi);
		printf("%-32s median %8.3f ms   p10 %8.3f   p90 %8.3f   (%d runs)\n", labels[k], med, lo, hi,
		       runs);
	}
	free(ms[0]);
	free(ms[1]);
	return rc;
}

static int perf(int argc, char **argv)
{
	struct sky_state s;
	const char *device = NULL;
	char err[512];
	int runs = 30;

	state_default(&s);
	for (int i = 0; i < argc; i++) {
		if (!strcmp(argv[i], "--runs") && i + 1 < argc)
			runs = atoi(argv[++i]);
		else if (!strcmp(argv[i], "--device") && i + 1 < argc)
			device = argv[++i];
		else if (state_set_pair(&s, argv[i], NULL, err, sizeof(err)) < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			return 2;
		}
	}
	if (runs < 1 || state_validate(&s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", runs < 1 ? "--runs: must be >= 1" : err);
		return 2;
	}
	struct eng *e;
	if (eng_new(device, err, sizeof(err), &e) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return 1;
	}
	const struct eng_device *d = eng_device(e);
	printf("device: %s [%s], %s\n", d->name, d->type_name, d->driver);
	printf("sizes: transmittance %ux%u/%u steps, multiscatter %ux%u/%u steps x %u dirs, "
	       "skyview %ux%u/%u steps, aerial %ux%ux%u/%u steps, %s\n",
	       s.quality.t[0].width, s.quality.t[0].height, s.quality.t[0].steps, s.quality.t[1].width,
	       s.quality.t[1].height, s.quality.t[1].steps, s.quality.multiscatter_dirs,
	       s.quality.t[2].width, s.quality.t[2].height, s.quality.t[2].steps, s.quality.t[3].width,
	       s.quality.t[3].height, s.quality.t[3].depth, s.quality.t[3].steps,
	       s.quality.storage == STATE_F16 ? "f16" : "f32");
	/* Warm up: pipelines compiled, buffers allocated. */
	int rc = run(e, &s, STATE_ALL_TABLES, 2, "warm-up (whole set)", false, true);
	for (int t = 0; t < STATE_N_TABLES && rc == 0; t++) {
		char label[64];
		snprintf(label, sizeof(label), "%s (GPU time)", state_table_names[t]);
		rc = run(e, &s, STATE_BIT(t), runs, label, true, true);
	}
	/* A coefficient change (weather) keeps the column densities. */
	if (rc == 0)
		rc = run(e, &s, STATE_BIT(STATE_TRANSMITTANCE), runs, "transmittance, columns kept", true,
			 false);
	if (rc == 0)
		rc = run(e, &s, STATE_BIT(STATE_SKYVIEW) | STATE_BIT(STATE_AERIAL), runs,
			 "skyview + aerial (wall)", false, false);
	if (rc == 0)
		rc = run(e, &s, STATE_ALL_TABLES, runs, "whole set (wall)", false, true);
	if (rc == 0 && state_clouds_drawn(&s))
		rc = cloud_rows(e, &s, runs);
	eng_free(e);
	return rc < 0 ? 1 : 0;
}

static void usage(FILE *f)
{
	fprintf(f, "usage: skybench perf [--runs N] [--device SEL] [key=value ...]\n"
		   "  perf   times each table, sky-view + aerial perspective, and the whole set, each\n"
		   "         from scratch (transmittance with its column densities; also with them kept),\n"
		   "         and with cloud layers the coverage and shadow passes\n"
		   "       skybench stability --markdown FILE\n"
		   "  stability  the stiff cases of docs/physics.md: invariants and precision as markdown\n"
		   "       skybench demand [--runs N] [--markdown] [key=value ...]\n"
		   "  demand [--runs N] [--markdown] [key=value ...]: each kind of scene with only the\n"
		   "         tables it needs against a full recompute (docs/performance.md)\n"
		   "       skybench accuracy [options]   (skybench accuracy --help)\n"
		   "  accuracy  error of the sky tables against the path tracer, against run time\n");
}

int main(int argc, char **argv)
{
	if (argc >= 2 && !strcmp(argv[1], "perf"))
		return perf(argc - 2, argv + 2);
	if (argc >= 2 && !strcmp(argv[1], "stability"))
		return bench_stability(argc - 2, argv + 2);
	if (argc >= 2 && !strcmp(argv[1], "demand"))
		return bench_demand_main(argc - 2, argv + 2);
	if (argc >= 2 && !strcmp(argv[1], "accuracy"))
		return bench_accuracy_main(argc - 2, argv + 2);
	usage(argc >= 2 && !strcmp(argv[1], "--help") ? stdout : stderr);
	return argc >= 2 && !strcmp(argv[1], "--help") ? 0 : 2;
}

/* bench_demand.c - `skybench demand`: the cost of each kind of scene with the
 * tables it needs and the ones a change invalidates, against a full
 * recompute, on the real engine. */
#include "bench_demand.h"

#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/utsname.h>

#include "eng.h"
#include "state.h"

#define ALL STATE_ALL_TABLES
#define T STATE_BIT(STATE_TRANSMITTANCE)
#define S STATE_BIT(STATE_SKYVIEW)
#define A STATE_BIT(STATE_AERIAL)

struct bench {
	struct eng *e;
	struct sky_state s;
	int runs;
	bool markdown;
	double full_ms;			/* the reference: every table */
	double one_view_ms;
};

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* What the daemon computes for a change of pairs (alternating between two
 * values so that every run is a real change) under demand: the tables the
 * keys invalidate (state_set's declaration) within demand's closure. */
static uint32_t change_mask(struct bench *b, const char *const pairs[2], int run, uint32_t demand)
{
	uint32_t dirty = 0;
	char err[256];

	if (pairs && state_set_pair(&b->s, pairs[run % 2], &dirty, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		exit(2);
	}
	return pairs ? dirty & state_closure(demand) : state_closure(demand);
}

/* Median and 90th percentile of the wall time (submit to completion,
 * read-back included) of runs computations; -errno on an engine error. */
static int measure(struct bench *b, const char *const pairs[2], uint32_t demand,
		   uint32_t *ret_mask, double *ret_med, double *ret_p90)
{
	double *ms = calloc((size_t)b->runs, sizeof(double));
	char err[512];
	struct eng_timing t;
	uint32_t mask = 0;

	if (!ms)
		return -ENOMEM;
	for (int i = 0; i < b->runs; i++) {
		mask = change_mask(b, pairs, i, demand);
		ms[i] = 0.0;
		if (!mask)
			continue;	/* nothing to compute: the state alone changes */
		int rc = eng_compute(b->e, &b->s, mask, &t, err, sizeof(err));
		if (rc < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			free(ms);
			return rc;
		}
		ms[i] = t.total_ms;
	}
	qsort(ms, (size_t)b->runs, sizeof(*ms), cmp_double);
	*ret_med = b->runs % 2 ? ms[b->runs / 2] : 0.5 * (ms[b->runs / 2 - 1] + ms[b->runs / 2]);
	*ret_p90 = ms[b->runs - 1 - b->runs / 10];
	*ret_mask = mask;
	free(ms);
	return 0;
}

static void mask_names(uint32_t mask, char *buf, size_t size)
{
	size_t o = 0;

	buf[0] = 0;
	for (int t = 0; t < STATE_N_TABLES; t++)
		if (mask & STATE_BIT(t))
			o += (size_t)snprintf(buf + o, o < size ? size - o : 0, "%s%s", o ? "," : "",
					      state_table_names[t]);
	if (!o)
		snprintf(buf, size, "none");
}

static void row(const struct bench *b, const char *scene, uint32_t mask, double med, double p90,
		double ref_ms, const char *ref_name, const char *goal)
{
	char names[80], ratio[32];

	mask_names(mask, names, sizeof(names));
	snprintf(ratio, sizeof(ratio), "%.1f %% of %s", 100.0 * med / ref_ms, ref_name);
	if (b->markdown)
		printf("| %s | %s | %.3f | %.3f | %s | %s |\n", scene, names, med, p90, ratio, goal);
	else
		printf("%-44s %-40s median %8.3f ms  p90 %8.3f  %-22s %s\n", scene, names, med, p90,
		       ratio, goal);
}

static void machine(const struct bench *b)
{
	struct utsname u;
	char cpu[256] = "unknown CPU", line[512], load[128] = "?";
	int ncpu = 0;
	FILE *f = fopen("/proc/cpuinfo", "re");

	while (f && fgets(line, sizeof(line), f)) {
		if (!strncmp(line, "model name", 10) && strchr(line, ':')) {
			snprintf(cpu, sizeof(cpu), "%s", strchr(line, ':') + 2);
			cpu[strcspn(cpu, "\n")] = 0;
		}
		if (!strncmp(line, "processor", 9))
			ncpu++;
	}
	if (f)
		fclose(f);
	f = fopen("/proc/loadavg", "re");
	if (f && fgets(load, sizeof(load), f))
		load[strcspn(load, "\n")] = 0;
	if (f)
		fclose(f);
	uname(&u);
	const struct eng_device *d = eng_device(b->e);
	const struct state_quality *q = &b->s.quality;
	printf("%sMachine: %s, %s %s, %d CPUs (%s); load average at start: %s\n\n",
	       b->markdown ? "" : "# ", u.nodename, u.sysname, u.release, ncpu, cpu, load);
	printf("%sDevice: %s [%s], %s\n\n", b->markdown ? "" : "# ", d->name, d->type_name, d->driver);
	printf("%sTables: transmittance %ux%u (%u steps), multi-scattering %ux%u (%u steps x %u "
	       "directions), sky-view %ux%u (%u steps), aerial %ux%ux%u (%u steps), %s; "
	       "%d runs per scene, wall time from submission to completion with read-back.\n\n",
	       b->markdown ? "" : "# ", q->t[0].width, q->t[0].height, q->t[0].steps, q->t[1].width,
	       q->t[1].height, q->t[1].steps, q->multiscatter_dirs, q->t[2].width, q->t[2].height,
	       q->t[2].steps, q->t[3].width, q->t[3].height, q->t[3].depth, q->t[3].steps,
	       q->storage == STATE_F16 ? "f16" : "f32", b->runs);
	if (b->markdown)
		printf("| scene | tables computed | median ms | p90 ms | against | goal |\n"
		       "| --- | --- | ---: | ---: | --- | --- |\n");
}

static void add_views(struct sky_state *s, uint32_t n)
{
	s->n_views = n;
	for (uint32_t i = 0; i < n; i++) {
		struct state_view *v = &s->views[i];
		memset(v, 0, sizeof(*v));
		snprintf(v->name, sizeof(v->name), "wall%u", i);
		v->altitude_km = __builtin_nan("");
		state_default_camera(&v->camera);
		v->camera.yaw_deg = 45.0 * i;
		v->camera.vfov_deg = 45.0;
	}
}

int bench_demand_main(int argc, char **argv)
{
	static const char *const time_of_day[2] = { "sun_elevation_deg=20", "sun_elevation_deg=20.25" };
	static const char *const weather[2] = { "mie_scattering_per_km=0.004", "mie_scattering_per_km=0.0041" };
	static const char *const camera[2] = { "camera_yaw_deg=170", "camera_yaw_deg=171" };
	struct bench b = { .runs = 30 };
	const char *device = NULL;
	char err[512];
	uint32_t mask;
	double med, p90;
	int rc;

	state_default(&b.s);
	for (int i = 0; i < argc; i++) {
		if (!strcmp(argv[i], "--runs") && i + 1 < argc)
			b.runs = atoi(argv[++i]);
		else if (!strcmp(argv[i], "--device") && i + 1 < argc)
			device = argv[++i];
		else if (!strcmp(argv[i], "--markdown"))
			b.markdown = true;
		else if (state_set_pair(&b.s, argv[i], NULL, err, sizeof(err)) < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			return 2;
		}
	}
	if (b.runs < 2 || state_validate(&b.s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", b.runs < 2 ? "--runs: must be >= 2" : err);
		return 2;
	}
	if (eng_new(device, err, sizeof(err), &b.e) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return 1;
	}
	machine(&b);
	/* Warm-up: every pipeline of the variants below built, buffers sized. */
	rc = measure(&b, NULL, ALL, &mask, &med, &p90);
	if (rc == 0)
		rc = measure(&b, NULL, ALL, &mask, &b.full_ms, &p90);
	if (rc == 0)
		row(&b, "full recompute (weather, every table in use)", mask, b.full_ms, p90, b.full_ms,
		    "full", "reference");
	if (rc == 0 && (rc = measure(&b, time_of_day, ALL, &mask, &med, &p90)) == 0)
		row(&b, "time-of-day change, full scene", mask, med, p90, b.full_ms, "full", "<= 35 %");
	if (rc == 0 && (rc = measure(&b, camera, ALL, &mask, &med, &p90)) == 0)
		row(&b, "camera change, full scene", mask, med, p90, b.full_ms, "full", "");
	if (rc == 0 && (rc = measure(&b, weather, T, &mask, &med, &p90)) == 0)
		row(&b, "transmittance-only scene, weather change", mask, med, p90, b.full_ms, "full",
		    "<= 5 %");
	if (rc == 0 && (rc = measure(&b, time_of_day, T, &mask, &med, &p90)) == 0)
		row(&b, "transmittance-only scene, time of day", mask, med, p90, b.full_ms, "full", "");
	if (rc == 0 && (rc = measure(&b, weather, S, &mask, &med, &p90)) == 0)
		row(&b, "sky-view-only dome, weather change", mask, med, p90, b.full_ms, "full", "");
	if (rc == 0 && (rc = measure(&b, time_of_day, S, &mask, &med, &p90)) == 0)
		row(&b, "sky-view-only dome, time of day", mask, med, p90, b.full_ms, "full", "");
	/* Views: the state's camera is one view; a display wall adds 8 views
	 * on the same eye point, all in the aerial pass's one dispatch. */
	if (rc == 0 && (rc = measure(&b, camera, A, &mask, &b.one_view_ms, &p90)) == 0)
		row(&b, "one view (aerial perspective)", mask, b.one_view_ms, p90, b.one_view_ms,
		    "one view", "reference");
	if (rc == 0) {
		add_views(&b.s, 8);
		rc = measure(&b, NULL, A, &mask, &med, &p90);	/* warm-up: new buffers */
	}
	if (rc == 0 && (rc = measure(&b, camera, A, &mask, &med, &p90)) == 0)
		row(&b, "display wall: 8 views + the state's camera", mask, med, p90, b.one_view_ms,
		    "one view", "< 300 %");
	if (rc == 0) {
		add_views(&b.s, 0);
		rc = measure(&b, NULL, A, &mask, &med, &p90);
	}
	/* A clock animation: one time-of-day step per 60 Hz frame. */
	if (rc == 0 && (rc = measure(&b, time_of_day, ALL, &mask, &med, &p90)) == 0)
		row(&b, "clock animation step, full scene", mask, med, p90, 1000.0 / 60.0,
		    "a 60 Hz frame", "");
	if (rc == 0 && (rc = measure(&b, time_of_day, S, &mask, &med, &p90)) == 0)
		row(&b, "clock animation step, sky-view dome", mask, med, p90, 1000.0 / 60.0,
		    "a 60 Hz frame", "");
	eng_free(b.e);
	return rc < 0 ? 1 : 0;
}

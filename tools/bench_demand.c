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
#include <time.h>

#include "eng.h"
#include "skyproto.h"
#include "state.h"

#define ALL STATE_ALL_TABLES
#define T STATE_BIT(STATE_TRANSMITTANCE)
#define S STATE_BIT(STATE_SKYVIEW)
#define A STATE_BIT(STATE_AERIAL)

/* The clock animation rows' sweep (sweep_row). */
#define SWEEP_FROM_DEG 20.0
#define SWEEP_STEPS_PER_RUN 8

/* What a scene is measured against, run by run: on a shared machine the
 * load drifts, so each run of a scene is paired with a run of its
 * reference right before it, and the ratio is the median of the pairs. */
enum ref { REF_FULL, REF_ONE_VIEW, REF_FRAME };

struct bench {
	struct eng *e;
	struct eng *ref_e;		/* the references, so that e keeps its buffers */
	struct sky_state s;
	int runs;
	bool markdown;
	bool wall_only;			/* --wall: the views' rows only */
	bool march_views;		/* --march-views: no panorama (the reference) */
	const double *field_utc_s;	/* non-NULL: a wind step's pair of field times */
	/* The clock's moves, one a run (sweep_row): the sun's elevation up
	 * by the clock's threshold, or the field on by the wind's, from
	 * wind_utc_s[0] by wind_utc_s[1] a move. */
	enum { SWEEP_NONE, SWEEP_SUN, SWEEP_WIND } sweep;
	double wind_utc_s[2];
	/* Before each run, its cloud tables made ahead as the daemon makes
	 * them while the device idles (eng_submit_ahead), not timed. */
	bool ahead;
};

struct result {
	uint32_t mask;			/* what most runs computed, the cloud tables
					 * the engine added included */
	double med_ms, p90_ms, ratio;	/* ratio: median of scene / reference */
	double cpu_ratio;		/* the same for the process's CPU time; 0 without a
					 * computed reference */
	double gpu_ms;			/* median GPU time of the tables computed */
	double mean_ms;			/* over the runs: a sweep's cost per step */
	int shadow_runs;		/* runs that remade the shadow maps */
	int took_runs;			/* runs that took cloud tables made ahead */
	double took_ms;			/* their mean */
	int made;			/* cloud tables made ahead (b->ahead) */
	double made_ms;			/* their mean wall time */
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

	if (b->field_utc_s || b->sweep == SWEEP_WIND) {
		/* As the clock places the field (srv/drive.c): its tables and
		 * the sky tables its shadows reach. */
		b->s.clouds.utc_s = b->field_utc_s ? b->field_utc_s[run % 2]
						   : b->wind_utc_s[0] + (run + 1) * b->wind_utc_s[1];
		state_cloud_offset_km(&b->s, b->s.clouds.offset_km);
		return (STATE_CLOUD_TABLES | S | A) & state_closure(demand);
	}
	if (b->sweep == SWEEP_SUN) {
		char pair[64];
		snprintf(pair, sizeof(pair), "sun_elevation_deg=%.6f",
			 SWEEP_FROM_DEG + (run + 1) * b->s.clock.threshold_deg);
		if (state_set_pair(&b->s, pair, &dirty, err, sizeof(err)) < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			exit(2);
		}
		return dirty & state_closure(demand);
	}
	if (pairs && state_set_pair(&b->s, pairs[run % 2], &dirty, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		exit(2);
	}
	return pairs ? dirty & state_closure(demand) : state_closure(demand);
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(*v), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static double cpu_now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
	return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* One computation's wall time (submit to completion, read-back included),
 * the process's CPU time over it (on a CPU device, lavapipe's threads: the
 * work itself, which a busy machine stretches less than the wall time),
 * and, if ret_gpu_ms, the GPU time of its tables (timestamps): the wall
 * time less the GPU time is what a computation pays whatever its size. */
static int timed(struct eng *e, const struct sky_state *s, uint32_t mask, double *ret_ms,
		 double *ret_cpu_ms, double *ret_gpu_ms, int *ret_computed, int *ret_took)
{
	char err[512];
	struct eng_timing t;

	*ret_ms = *ret_cpu_ms = 0.0;
	if (ret_gpu_ms)
		*ret_gpu_ms = 0.0;
	if (!mask)
		return 0;	/* nothing to compute: the state alone changes */
	double cpu0 = cpu_now_ms();
	if (eng_compute(e, s, mask, &t, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return -EIO;
	}
	*ret_cpu_ms = cpu_now_ms() - cpu0;
	*ret_ms = t.total_ms;
	if (ret_took)
		*ret_took = t.clouds_ahead;
	for (int i = 0; i < STATE_N_ALL_TABLES && ret_computed; i++)
		ret_computed[i] += (t.computed & STATE_BIT(i)) != 0;
	for (int i = 0; i < STATE_N_TABLES && ret_gpu_ms; i++)
		if (t.computed & STATE_BIT(i))
			*ret_gpu_ms += t.table_ms[i];
	return 0;
}

/* The cloud tables of b's state made ahead, if the engine holds them in
 * neither set: *ret_ms gets the computation's wall time, or 0. */
static int made_ahead(struct bench *b, double *ret_ms)
{
	char err[512];
	struct eng_timing t;
	int rc = eng_submit_ahead(b->e, &b->s, NULL, err, sizeof(err));

	*ret_ms = 0.0;
	if (rc == 0)
		rc = eng_wait(b->e, &t, err, sizeof(err));
	if (rc < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		return -EIO;
	}
	if (rc == 0)
		*ret_ms = t.total_ms;
	return 0;
}

/* runs computations of a scene, each after one of its reference. */
static int measure(struct bench *b, const char *const pairs[2], uint32_t demand, enum ref ref,
		   struct result *ret)
{
	double *ms = calloc((size_t)b->runs, sizeof(double));
	double *ratio = calloc((size_t)b->runs, sizeof(double));
	double *gpu = calloc((size_t)b->runs, sizeof(double));
	double *cpu_ratio = calloc((size_t)b->runs, sizeof(double));
	double *made = calloc((size_t)b->runs, sizeof(double));
	int *took = calloc((size_t)b->runs, sizeof(int));
	struct sky_state one = b->s;
	int rc = ms && ratio && gpu && cpu_ratio && made && took ? 0 : -ENOMEM;

	int computed[STATE_N_ALL_TABLES] = { 0 };	/* runs that computed each table */

	one.n_views = 0;
	for (int i = 0; i < b->runs && rc == 0; i++) {
		double ref_ms = 1000.0 / 60.0, ref_cpu_ms = 0.0, cpu_ms;
		if (ref == REF_FULL) {
			/* From scratch: the column densities too, as an
			 * atmosphere change needs. */
			eng_forget_columns(b->ref_e);
			rc = timed(b->ref_e, &b->s, ALL, &ref_ms, &ref_cpu_ms, NULL, NULL, NULL);
		}
		else if (ref == REF_ONE_VIEW)
			rc = timed(b->ref_e, &one, A, &ref_ms, &ref_cpu_ms, NULL, NULL, NULL);
		uint32_t mask = change_mask(b, pairs, i, demand);
		if (rc == 0 && b->ahead)
			rc = made_ahead(b, &made[i]);
		if (rc == 0)
			rc = timed(b->e, &b->s, mask, &ms[i], &cpu_ms, &gpu[i], computed, &took[i]);
		ratio[i] = ref_ms > 0.0 ? ms[i] / ref_ms : 0.0;
		cpu_ratio[i] = ref_cpu_ms > 0.0 ? cpu_ms / ref_cpu_ms : 0.0;
	}
	if (rc == 0) {
		ret->mask = 0;
		for (int t = 0; t < STATE_N_ALL_TABLES; t++)
			if (2 * computed[t] > b->runs)
				ret->mask |= STATE_BIT(t);
		ret->ratio = median(ratio, b->runs);
		ret->cpu_ratio = median(cpu_ratio, b->runs);
		ret->med_ms = median(ms, b->runs);
		ret->p90_ms = ms[b->runs - 1 - b->runs / 10];
		ret->gpu_ms = median(gpu, b->runs);
		ret->shadow_runs = computed[STATE_CLOUD_SHADOW];
		ret->mean_ms = ret->took_ms = ret->made_ms = 0.0;
		ret->took_runs = ret->made = 0;
		for (int i = 0; i < b->runs; i++) {
			ret->mean_ms += ms[i] / b->runs;
			ret->took_runs += took[i];
			ret->took_ms += took[i] ? ms[i] : 0.0;
			ret->made += made[i] > 0.0;
			ret->made_ms += made[i];
		}
		ret->took_ms /= ret->took_runs ? ret->took_runs : 1;
		ret->made_ms /= ret->made ? ret->made : 1;
	}
	free(took);
	free(made);
	free(cpu_ratio);
	free(gpu);
	free(ms);
	free(ratio);
	return rc;
}

static const char *const ref_names[] = { "full recompute", "one view", "a 60 Hz frame" };

/* Measures a scene and prints its row; returns measure's result. A NULL
 * goal prints the runs' mean there instead (sweep_row). */
static int row(struct bench *b, const char *scene, const char *const pairs[2], uint32_t demand,
	       enum ref ref, const char *goal)
{
	struct result r;
	char names[80], ratio[48], cpu[24] = "-", mean[192];
	int rc = measure(b, pairs, demand, ref, &r);

	if (rc < 0)
		return rc;
	if (!goal) {
		int n = snprintf(mean, sizeof(mean), "mean %.3f ms over %d steps", r.mean_ms, b->runs);
		if (eng_shadow_casters(&b->s))
			n += snprintf(mean + n, sizeof(mean) - (size_t)n, ", %d remade the maps", r.shadow_runs);
		if (b->ahead)
			snprintf(mean + n, sizeof(mean) - (size_t)n,
				 ", %d took them made ahead (mean %.3f ms); made ahead %d times, mean %.3f ms, not counted",
				 r.took_runs, r.took_ms, r.made, r.made_ms);
		goal = mean;
	}
	state_format_all_tables(r.mask, names, sizeof(names));
	snprintf(ratio, sizeof(ratio), "%.1f %% of %s", 100.0 * r.ratio, ref_names[ref]);
	if (r.cpu_ratio > 0.0)
		snprintf(cpu, sizeof(cpu), "%.1f %%", 100.0 * r.cpu_ratio);
	if (b->markdown)
		printf("| %s | %s | %.3f | %.3f | %.3f | %s | %s | %s |\n", scene, names, r.med_ms,
		       r.p90_ms, r.gpu_ms, ratio, cpu, goal);
	else
		printf("%-44s %-40s median %8.3f ms  p90 %8.3f  gpu %8.3f  %-28s cpu %-8s %s\n", scene,
		       names, r.med_ms, r.p90_ms, r.gpu_ms, ratio, cpu, goal);
	fflush(stdout);
	return 0;
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
	       "%d runs per scene, wall time from submission to completion with read-back; "
	       "GPU ms: the median of the tables' GPU time (timestamps); CPU time: the "
	       "process's, the same pairs' median ratio.\n\n",
	       b->markdown ? "" : "# ", q->t[0].width, q->t[0].height, q->t[0].steps, q->t[1].width,
	       q->t[1].height, q->t[1].steps, q->multiscatter_dirs, q->t[2].width, q->t[2].height,
	       q->t[2].steps, q->t[3].width, q->t[3].height, q->t[3].depth, q->t[3].steps,
	       q->storage == STATE_F16 ? "f16" : "f32", b->runs);
	if (b->markdown)
		printf("| scene | tables computed | median ms | p90 ms | GPU ms | against | CPU time against | goal |\n"
		       "| --- | --- | ---: | ---: | ---: | --- | ---: | --- |\n");
}

static void add_views(struct sky_state *s, uint32_t n, uint32_t form)
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
		v->form = form;
	}
}

static const char *const time_of_day[2] = { "sun_elevation_deg=20", "sun_elevation_deg=20.25" };
/* With clouds or terrain, the shadow maps follow the light on a grid of
 * slopes (eng_clouds.c). With the two layers of docs/performance.md's
 * cloud rows a cell is 0.19 in slope, and a 0.25 degree step at 20 degrees
 * moves the slope by 0.04: one such step in five crosses a cell, and the
 * pair above does; the pair below stays in one. The tables computed say
 * which. */
static const char *const time_of_day_cell[2] = { "sun_elevation_deg=20", "sun_elevation_deg=20.05" };
static const char *const weather[2] = { "mie_scattering_per_km=0.004", "mie_scattering_per_km=0.0041" };
static const char *const atmosphere[2] = { "mie_scale_height_km=1.2", "mie_scale_height_km=1.2001" };
static const char *const camera[2] = { "camera_yaw_deg=170", "camera_yaw_deg=171" };
/* A new field in place: the coverage table, the shadow maps, sky-view
 * and aerial perspective. */
static const char *const field[2] = { "cloud_seed=1", "cloud_seed=2" };

/* The clock's wind (srv/drive.c): a westerly of WIND_KM_S, which each of
 * its moves carries a quarter of a shadow texel (DRIVE_FIELD_TEXEL_SHARE),
 * set in b's state; ret_cell_km gets a cell of the tables' lattice
 * (state_cloud_table_offset_km, cloud_cell_texels), ret_step_km a move. */
#define WIND_KM_S 10.0e-3

static void westerly(struct bench *b, double *ret_cell_km, double *ret_step_km)
{
	double texel_km = 2.0 * state_cloud_extent_km(&b->s) / b->s.quality.shadow_width;

	*ret_cell_km = b->s.quality.cloud_cell_texels * texel_km;
	*ret_step_km = 0.25 * texel_km;
	b->s.clouds.wind_dir_deg = 270.0;
	b->s.clouds.wind_speed_mps = 1e3 * WIND_KM_S;
}

/* A wind step as the clock makes one, the lights staying. in_cell: both places in one cell of the tables'
 * lattice (state_cloud_table_offset_km, cloud_cell_texels), so that
 * the tables stay and only their readers move; otherwise the pair
 * straddles a cell's edge and the tables are redone, once in eight steps.
 * dome: sky-view alone is read (a planetarium), not aerial perspective. */
static int wind_row(struct bench *b, bool in_cell, bool dome)
{
	static const char *const scenes[2][2] = {
		{ "wind step across a cell (cloud, shadow, sky-view, aerial)",
		  "wind step within the tables' cell (sky-view, aerial)" },
		{ "wind step across a cell, sky-view dome (cloud, shadow, sky-view)",
		  "wind step within the tables' cell, sky-view dome (sky-view)" },
	};
	struct sky_state keep = b->s;
	double cell_km, step_km;

	westerly(b, &cell_km, &step_km);
	/* East of the origin by whole cells and a part: the pair's first
	 * place, a quarter into a cell, or half a step before its edge. */
	double east_km = 3.0 * cell_km + (in_cell ? 0.25 * cell_km : cell_km - 0.5 * step_km);
	double utc_s[2] = { east_km / WIND_KM_S, (east_km + step_km) / WIND_KM_S };

	b->field_utc_s = utc_s;
	int rc = row(b, scenes[dome][in_cell], NULL, (dome ? S : ALL) | STATE_CLOUD_TABLES, REF_FRAME,
		     "<= 20 % of a frame");
	b->field_utc_s = NULL;
	b->s = keep;
	return rc;
}

/* A clock animation (srv/drive.c), one move a run: SWEEP_SUN, the sun
 * climbs by clock_threshold_deg at each move, from SWEEP_FROM_DEG on;
 * SWEEP_WIND, the lights stay and a 10 m/s westerly carries the field a
 * quarter of a shadow texel a move (DRIVE_FIELD_TEXEL_SHARE), from half a
 * move past a cell's edge of the tables' lattice. SWEEP_STEPS_PER_RUN moves
 * a run of --runs. With clouds or terrain most moves keep the cloud tables
 * and some cross a cell (5 of the sun's 80 moves of --runs 10 with the
 * two layers of docs/performance.md, one of the wind's 8), so the row's
 * mean is what the clock's changes cost; ahead: with the cloud tables of
 * each move made ahead as the daemon makes them (not timed). Without
 * casters every move costs the same. Run r is move r + 1, from tables
 * made at move 0. */
static int sweep_row(struct bench *b, const char *scene, uint32_t demand, int sweep, bool ahead)
{
	struct sky_state keep = b->s;
	int runs = b->runs;
	double ms, cpu_ms;

	if (sweep == SWEEP_WIND) {
		double cell_km, step_km;
		westerly(b, &cell_km, &step_km);
		b->wind_utc_s[0] = (3.0 * cell_km + 0.5 * step_km) / WIND_KM_S;
		b->wind_utc_s[1] = step_km / WIND_KM_S;
	}
	/* From the sweep's first place (run -1), every table made, not timed. */
	b->sweep = sweep;
	change_mask(b, NULL, -1, demand);
	int rc = timed(b->e, &b->s, state_closure(demand) | STATE_CLOUD_TABLES, &ms, &cpu_ms, NULL, NULL,
		       NULL);
	b->runs = runs * SWEEP_STEPS_PER_RUN;
	b->ahead = ahead;
	if (rc == 0)
		rc = row(b, scene, NULL, demand, REF_FRAME, NULL);
	b->sweep = SWEEP_NONE;
	b->ahead = false;
	b->runs = runs;
	b->s = keep;
	return rc;
}

/* The scenes without views, against a full recompute. */
static int other_rows(struct bench *b)
{
	int rc = row(b, "full recompute (atmosphere, every table in use)", atmosphere, ALL, REF_FULL,
		     "reference");
	if (rc == 0)
		rc = row(b, "weather change, full scene", weather, ALL, REF_FULL, "");
	if (rc == 0)
		rc = row(b, "time-of-day change, full scene", time_of_day, ALL, REF_FULL, "<= 35 %");
	if (rc == 0 && eng_shadow_casters(&b->s))
		rc = row(b, "time-of-day change, the light in its map's cell", time_of_day_cell, ALL,
			 REF_FULL, "");
	if (rc == 0)
		rc = row(b, "camera change, full scene", camera, ALL, REF_FULL, "");
	if (rc == 0)
		rc = row(b, "transmittance-only scene, weather change", weather, T, REF_FULL, "<= 5 %");
	if (rc == 0)
		rc = row(b, "transmittance-only scene, time of day", time_of_day, T, REF_FULL, "");
	if (rc == 0)
		rc = row(b, "sky-view-only dome, weather change", weather, S, REF_FULL, "");
	if (rc == 0)
		rc = row(b, "sky-view-only dome, time of day", time_of_day, S, REF_FULL, "");
	if (rc == 0 && state_clouds_drawn(&b->s))
		rc = row(b, "new field (cloud_seed): cloud, shadow, sky-view, aerial", field,
			 ALL | STATE_CLOUD_TABLES, REF_FRAME, "");
	for (int dome = 0; dome < 2; dome++) {
		if (rc == 0 && state_clouds_drawn(&b->s))
			rc = wind_row(b, true, dome);
		if (rc == 0 && state_clouds_drawn(&b->s))
			rc = wind_row(b, false, dome);
	}
	return rc;
}

int bench_demand_main(int argc, char **argv)
{
	struct bench b = { .runs = 30 };
	const char *device = NULL;
	char err[512];
	int rc;

	state_default(&b.s);
	for (int i = 0; i < argc; i++) {
		if (!strcmp(argv[i], "--runs") && i + 1 < argc)
			b.runs = atoi(argv[++i]);
		else if (!strcmp(argv[i], "--device") && i + 1 < argc)
			device = argv[++i];
		else if (!strcmp(argv[i], "--markdown"))
			b.markdown = true;
		else if (!strcmp(argv[i], "--wall"))
			b.wall_only = true;
		else if (!strcmp(argv[i], "--march-views"))
			b.march_views = true;
		else if (state_set_pair(&b.s, argv[i], NULL, err, sizeof(err)) < 0) {
			fprintf(stderr, "skybench: %s\n", err);
			return 2;
		}
	}
	if (b.runs < 2 || state_validate(&b.s, 0, err, sizeof(err)) < 0) {
		fprintf(stderr, "skybench: %s\n", b.runs < 2 ? "--runs: must be >= 2" : err);
		return 2;
	}
	if (eng_new(device, err, sizeof(err), &b.e) < 0 ||
	    eng_new(device, err, sizeof(err), &b.ref_e) < 0) {
		fprintf(stderr, "skybench: %s\n", err);
		eng_free(b.e);
		return 1;
	}
	eng_set_view_sharing(b.e, !b.march_views);
	machine(&b);
	/* Warm-up: pipelines built, buffers sized (not printed). */
	struct result warm;
	int runs = b.runs;
	b.runs = 2;
	rc = measure(&b, NULL, ALL, REF_ONE_VIEW, &warm);
	b.runs = runs;
	if (rc == 0 && !b.wall_only)
		rc = other_rows(&b);

	/* Views: the state's camera is one view; a display wall adds 8 views
	 * on the same eye point, all in the aerial pass's one dispatch. */
	if (rc == 0)
		rc = row(&b, "one view (aerial perspective), camera change", camera, A, REF_ONE_VIEW,
			 "reference");
	/* The wall's views read the eye point's panorama (form=panorama);
	 * then the same wall with a volume per view. */
	static const uint32_t forms[2] = { SKY_VIEW_PANORAMA, SKY_VIEW_VOLUME };
	for (int i = 0; rc == 0 && i < 2; i++) {
		uint32_t form = forms[i];
		add_views(&b.s, 8, form);
		b.runs = 2;
		rc = measure(&b, NULL, A, REF_ONE_VIEW, &warm);	/* new buffers */
		b.runs = runs;
		if (rc == 0)
			rc = row(&b, form == SKY_VIEW_PANORAMA
				     ? "display wall: 8 panorama views + the state's camera"
				     : "display wall: 8 volume views + the state's camera",
				 camera, A, REF_ONE_VIEW, form == SKY_VIEW_PANORAMA ? "<= 200 %" : "");
	}
	if (rc == 0)
		add_views(&b.s, 0, SKY_VIEW_VOLUME);
	/* A clock animation: one time-of-day step per 60 Hz frame. */
	if (rc == 0 && !b.wall_only)
		rc = sweep_row(&b, "clock animation step, full scene", ALL, SWEEP_SUN, false);
	if (rc == 0 && !b.wall_only)
		rc = sweep_row(&b, "clock animation step, sky-view dome", S, SWEEP_SUN, false);
	/* The same moves with the cloud tables made ahead (docs/clouds.md,
	 * "Maps made ahead"), and the wind's. */
	bool casters = eng_shadow_casters(&b.s), drawn = state_clouds_drawn(&b.s) > 0;
	if (rc == 0 && !b.wall_only && casters)
		rc = sweep_row(&b, "clock animation step, full scene, maps made ahead", ALL, SWEEP_SUN, true);
	if (rc == 0 && !b.wall_only && drawn)
		rc = sweep_row(&b, "wind steps of the clock, full scene", ALL, SWEEP_WIND, false);
	if (rc == 0 && !b.wall_only && drawn)
		rc = sweep_row(&b, "wind steps of the clock, maps made ahead", ALL, SWEEP_WIND, true);
	if (rc == 0 && !b.wall_only && drawn)
		rc = sweep_row(&b, "wind steps of the clock, sky-view dome, maps made ahead", S, SWEEP_WIND,
			       true);
	eng_free(b.ref_e);
	eng_free(b.e);
	return rc < 0 ? 1 : 0;
}

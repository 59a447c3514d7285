/* test_stability_gpu.c - the stiff and extreme atmospheres on the Vulkan
 * engine: the named stiff cases
 * (invariants, float32 against the float64 model at the same step counts,
 * an observer at 1 m as accurate as at 1 km, sky continuous through sunset),
 * the clouds' and terrain's cases, and 300 seeded random atmospheres. Exits
 * 77 without a Vulkan device. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "eng.h"
#include "stab.h"
#include "stab_report.h"
#include "test.h"
#include "vk_or_skip.h"

#define SWEEP_CASES 300
#define SWEEP_SEED 0x6a5eed06u
#define MIN_PSNR_DB 60.0

static struct eng *eng;

static int find_case(const char *name)
{
	for (size_t c = 0; c < stab_n_cases; c++)
		if (!strcmp(stab_cases[c].name, name))
			return (int)c;
	return -1;
}

/* Skyview and aerial PSNR of every case, kept for the 1 m / 1 km check. */
static double psnr_of[64][STATE_N_TABLES];

static void test_named(void)
{
	char err[512];
	for (size_t c = 0; c < stab_n_cases; c++) {
		struct sky_state s;
		struct model_tables gpu, ref;
		struct stab_result r = { 0 };
		double psnr[STATE_N_TABLES], rel[STATE_N_TABLES];
		const char *name = stab_cases[c].name;
		state_default(&s);
		stab_cases[c].fill(&s);
		stab_medium(&s);
		if (stab_engine(eng, &s, STATE_ALL_TABLES, &gpu, err, sizeof(err)) < 0 ||
		    stab_model(NULL, &s, STATE_ALL_TABLES, &ref, err, sizeof(err)) < 0) {
			FAIL("%s: %s", name, err);
			continue;
		}
		stab_check(name, &s, &gpu, &stab_tol_f32, &r);
		stab_compare(&s, &ref, &gpu, psnr, rel);
		printf("%-32s", name);
		for (int t = 0; t < STATE_N_TABLES; t++) {
			psnr_of[c][t] = psnr[t];
			printf(" %s %5.1f dB %.1e", state_table_names[t], psnr[t], rel[t]);
			if (!(psnr[t] >= MIN_PSNR_DB))
				FAIL("%s: %s PSNR %.1f dB under %.0f dB", name, state_table_names[t], psnr[t],
				     MIN_PSNR_DB);
		}
		printf("\n");
		model_tables_finish(&gpu);
		model_tables_finish(&ref);
		stab_report(name, &r);
	}
}

/* Altitude is kept apart from radius: 1 m is no worse than 1 km. */
static void test_low_observer(void)
{
	static const char *const pairs[][2] = {
		{ "observer 1 m", "observer 1 km" },
		{ "70000 km planet, 1 m", "70000 km planet, 1 km" },
	};
	for (size_t i = 0; i < 2; i++) {
		int a = find_case(pairs[i][0]), b = find_case(pairs[i][1]);
		CHECK(a >= 0 && b >= 0);
		for (int t = STATE_SKYVIEW; t <= STATE_AERIAL; t++) {
			printf("%s vs %s: %s %.1f vs %.1f dB\n", pairs[i][0], pairs[i][1], state_table_names[t],
			       psnr_of[a][t], psnr_of[b][t]);
			if (!(psnr_of[a][t] >= psnr_of[b][t] - 3.0))
				FAIL("%s: %s PSNR %.1f dB, 3 dB under %s (%.1f dB)", pairs[i][0],
				     state_table_names[t], psnr_of[a][t], pairs[i][1], psnr_of[b][t]);
		}
	}
}

static void test_horizon(void)
{
	static const char *const names[] = { "earth", "mars", "titan-like", "scattering x100", "observer 1 m",
					      "thin x0.01", "planet 10 km, shell 100 km" };
	char err[512];
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		struct sky_state s;
		struct stab_result r = { 0 };
		state_default(&s);
		stab_cases[find_case(names[i])].fill(&s);
		stab_medium(&s);
		if (stab_horizon(names[i], stab_engine, eng, &s, &r, err, sizeof(err)) < 0)
			FAIL("%s: %s", names[i], err);
		printf("horizon %-24s largest step / neighbour %.2f\n", names[i], r.max_jump_ratio);
		stab_report(names[i], &r);
	}
}

static void test_sweep(void)
{
	uint64_t seed = SWEEP_SEED;
	struct stab_result total = { 0 };
	struct stab_tol tol = stab_tol_f32;
	char err[512], name[64];
	double t0 = stab_now_s();

	tol.ray_t = 0;	/* the model's quadrature: test_stability_model */
	for (int i = 0; i < SWEEP_CASES; i++) {
		struct sky_state s;
		struct model_tables m;
		stab_random(&seed, true, &s);
		snprintf(name, sizeof(name), "gpu random %d", i);
		if (state_validate(&s, 0, err, sizeof(err)) < 0 ||
		    stab_engine(eng, &s, STATE_ALL_TABLES, &m, err, sizeof(err)) < 0) {
			FAIL("%s: %s", name, err);
			continue;
		}
		stab_check(name, &s, &m, &tol, &total);
		model_tables_finish(&m);
	}
	printf("sweep: %d random atmospheres on the engine (seed %#x), %.1f s\n", SWEEP_CASES, SWEEP_SEED,
	       stab_now_s() - t0);
	for (int k = 0; k < STAB_N_INVARIANTS; k++)
		printf("  %-24s %llu of %llu failed\n", stab_invariant_names[k],
		       (unsigned long long)total.fails[k], (unsigned long long)total.samples[k]);
	stab_report("gpu sweep", &total);
}

/* The clouds' and terrain's cases (truth/stab_clouds.c) on the engine:
 * every table invariant, and never brighter than the same state clear
 * over a white ground (stab_cloud_bound): here the shadows and the light
 * the layers scatter into the air are held to it. */
static void test_clouds(void)
{
	char err[512];
	for (size_t c = 0; c < stab_n_cloud_cases; c++) {
		const char *name = stab_cloud_cases[c].name;
		struct sky_state s, bound;
		struct model_tables with, without;
		struct stab_result r = { 0 };
		if (stab_cloud_state(&stab_cloud_cases[c], &s, err, sizeof(err)) < 0) {
			FAIL("%s: %s", name, err);
			continue;
		}
		stab_cloud_bound(&s, &bound);
		if (stab_engine(eng, &s, STATE_ALL_TABLES, &with, err, sizeof(err)) < 0 ||
		    stab_engine(eng, &bound, STATE_ALL_TABLES, &without, err, sizeof(err)) < 0) {
			FAIL("%s: %s", name, err);
			continue;
		}
		stab_check(name, &s, &with, &stab_tol_f32, &r);
		stab_check_shadowed(name, &with, &without, &stab_tol_f32, &r);
		printf("clouds %-38s shadowed <= unshadowed: %llu of %llu texels fail\n", name,
		       (unsigned long long)r.fails[STAB_SHADOWED], (unsigned long long)r.samples[STAB_SHADOWED]);
		model_tables_finish(&with);
		model_tables_finish(&without);
		stab_report(name, &r);
	}
}

int main(void)
{
	eng = vk_or_skip();
	printf("device: %s\n", eng_device(eng)->name);
	test_named();
	test_clouds();
	test_low_observer();
	test_horizon();
	test_sweep();
	eng_free(eng);
	return test_report("test_stability_gpu");
}

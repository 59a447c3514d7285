/* test_stability_model.c - the stiff and extreme atmospheres on the
 * double-precision model: every named stiff case of docs/physics.md and
 * 10,000 seeded random atmospheres keep
 * the table invariants (finite, >= 0, T in [0, 1] and monotone along rays,
 * exact vacuum, mirror symmetry, sky continuous through sunset). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "stab.h"
#include "stab_report.h"
#include "test.h"

#define SWEEP_CASES 10000
#define SWEEP_SEED 0x5eed0006u

static void test_named(void)
{
	char err[256];
	for (size_t c = 0; c < stab_n_cases; c++) {
		struct sky_state s;
		struct model_tables m;
		struct stab_result r = { 0 };
		state_default(&s);
		stab_cases[c].fill(&s);
		stab_medium(&s);
		CHECK(state_validate(&s, 0, err, sizeof(err)) == 0);
		if (stab_model(NULL, &s, STATE_ALL_TABLES, &m, err, sizeof(err)) < 0) {
			FAIL("%s: %s", stab_cases[c].name, err);
			continue;
		}
		stab_check(stab_cases[c].name, &s, &m, &stab_tol_model, &r);
		model_tables_finish(&m);
		struct sky_state hz = s;
		stab_small(&hz);
		hz.quality.t[STATE_SKYVIEW] = s.quality.t[STATE_SKYVIEW];
		if (stab_horizon(stab_cases[c].name, stab_model, NULL, &hz, &r, err, sizeof(err)) < 0)
			FAIL("%s: %s", stab_cases[c].name, err);
		printf("%-32s psi max %-10.3g L max %-10.3g T ray drop %-9.2e asym %-9.2e jump ratio %.2f\n",
		       stab_cases[c].name, r.max_psi, r.max_radiance, r.max_t_ray_drop, r.max_asym,
		       r.max_jump_ratio);
		stab_report(stab_cases[c].name, &r);
	}
}

static void test_sweep(void)
{
	uint64_t seed = SWEEP_SEED;
	struct stab_result total = { 0 };
	char err[256], name[64];
	double t0 = stab_now_s();
	int refused = 0;

	for (int i = 0; i < SWEEP_CASES; i++) {
		struct sky_state s;
		struct model_tables m;
		struct stab_result r = { 0 };
		stab_random(&seed, false, &s);
		if (state_validate(&s, 0, err, sizeof(err)) < 0) {
			refused++;
			continue;
		}
		snprintf(name, sizeof(name), "random %d", i);
		if (stab_model(NULL, &s, STATE_ALL_TABLES, &m, err, sizeof(err)) < 0) {
			FAIL("%s: %s", name, err);
			continue;
		}
		stab_check(name, &s, &m, &stab_tol_sweep, &r);
		model_tables_finish(&m);
		if (stab_total_fails(&r) && !stab_total_fails(&total))
			snprintf(total.first, sizeof(total.first), "%s", r.first);
		for (int k = 0; k < STAB_N_INVARIANTS; k++) {
			total.samples[k] += r.samples[k];
			total.fails[k] += r.fails[k];
		}
		total.max_psi = fmax(total.max_psi, r.max_psi);
	}
	printf("sweep: %d random atmospheres (seed %#x), %d refused by validation, %.1f s, psi max %.3g\n",
	       SWEEP_CASES, SWEEP_SEED, refused, stab_now_s() - t0, total.max_psi);
	for (int k = 0; k < STAB_N_INVARIANTS; k++)
		printf("  %-24s %llu of %llu failed\n", stab_invariant_names[k],
		       (unsigned long long)total.fails[k], (unsigned long long)total.samples[k]);
	CHECK(refused == 0);
	stab_report("sweep", &total);
}

int main(void)
{
	test_named();
	test_sweep();
	return test_report("test_stability_model");
}

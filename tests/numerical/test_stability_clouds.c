/* test_stability_clouds.c - the stiff and extreme cases of the clouds and
 * the terrain (truth/stab_clouds.c) on the model side: the field over a
 * grid finite and within [0, extinction], the light it lets through and
 * the sky it hides in [0, 1], the terrain within its height, the air's
 * single scattering never brighter for the shadows, the path tracer
 * finite, >= 0 and the same on any number of threads, the field the same
 * in another thread and on every host (its committed checksum); and the
 * tables of each case (the double-precision model, which has no cloud
 * passes yet) keep every table invariant and are never brighter than the
 * same state clear over a white ground (stab_cloud_bound). test_stability_gpu runs the same cases on the engine. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "stab.h"
#include "stab_report.h"
#include "test.h"

/* The field's checksum of each case (stab_cloud_check_model's grid), in
 * stab_cloud_cases' order: what any host and compiler must give (ISO C,
 * no contraction: docs/clouds.md, "Determinism"); FNV-1a's offset basis
 * where there is no layer. */
#define NO_LAYER 0xcbf29ce484222325ull
static const uint64_t golden[] = {
	0x36c5b7d0a21116f0ull, 0x117ad5cc43ea6706ull, 0xad0436f0c34360b3ull, 0x2edfa15b122f3e4bull,
	NO_LAYER, 0x0668679189e8a325ull, 0x703f97149b01a5e1ull, NO_LAYER, NO_LAYER,
};

int main(void)
{
	char err[512];

	CHECK_EQ(sizeof(golden) / sizeof(golden[0]), stab_n_cloud_cases);
	for (size_t c = 0; c < stab_n_cloud_cases; c++) {
		const struct stab_cloud_case *k = &stab_cloud_cases[c];
		struct sky_state s, bound;
		struct model_tables with, without;
		struct stab_result r = { 0 };
		uint64_t sum = 0;
		double t0 = stab_now_s();
		if (stab_cloud_state(k, &s, err, sizeof(err)) < 0) {
			FAIL("%s: %s", k->name, err);
			continue;
		}
		if (stab_cloud_check_model(k->name, &s, &r, &sum, err, sizeof(err)) < 0)
			FAIL("%s: %s", k->name, err);
		stab_cloud_bound(&s, &bound);
		if (stab_model(NULL, &s, STATE_ALL_TABLES, &with, err, sizeof(err)) < 0 ||
		    stab_model(NULL, &bound, STATE_ALL_TABLES, &without, err, sizeof(err)) < 0) {
			FAIL("%s: %s", k->name, err);
			continue;
		}
		stab_check(k->name, &s, &with, &stab_tol_model, &r);
		stab_check_shadowed(k->name, &with, &without, &stab_tol_model, &r);
		model_tables_finish(&with);
		model_tables_finish(&without);
		printf("%-38s field %016" PRIx64 " %.1f s:", k->name, sum, stab_now_s() - t0);
		for (int i = 0; i < STAB_N_INVARIANTS; i++)
			if (r.samples[i])
				printf(" %s %llu/%llu", stab_invariant_names[i], (unsigned long long)r.fails[i],
				       (unsigned long long)r.samples[i]);
		printf("\n");
		if (sum != golden[c])
			FAIL("%s: the field's checksum %016" PRIx64 ", committed %016" PRIx64, k->name, sum,
			     golden[c]);
		stab_report(k->name, &r);
	}
	return test_report("test_stability_clouds");
}

/* stab_report.h - how the stability tests judge a case: a violation of an
 * invariant fails the test unless tools/stab.c lists it as known (with its
 * cause), in which case it is printed with the first violation it saw. */
#ifndef SKYD_STAB_REPORT_H
#define SKYD_STAB_REPORT_H

#include <stdbool.h>
#include <stdio.h>
#include <time.h>

#include "stab.h"
#include "test.h"

static inline double stab_now_s(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return t.tv_sec + t.tv_nsec * 1e-9;
}

/* f32: the tables are the engine's (known violations are per "model"/"f32"). */
static inline void stab_report(const char *name, const struct stab_result *r, bool f32)
{
	test_checks++;
	for (int i = 0; i < STAB_N_INVARIANTS; i++) {
		if (!r->fails[i])
			continue;
		const struct stab_known *k = stab_find_known(name, i, f32);
		if (k) {
			printf("known: %s: %s: %llu of %llu (%s); first: %s\n", name, stab_invariant_names[i],
			       (unsigned long long)r->fails[i], (unsigned long long)r->samples[i], k->why,
			       r->first);
			continue;
		}
		FAIL("%s: %s: %llu of %llu violated; first violation of the case: %s", name,
		     stab_invariant_names[i], (unsigned long long)r->fails[i],
		     (unsigned long long)r->samples[i], r->first);
	}
}

#endif

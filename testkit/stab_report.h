/* stab_report.h - how the stability tests judge a case: any violation of an
 * invariant fails the test, with the first violation the case saw. */
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

static inline void stab_report(const char *name, const struct stab_result *r)
{
	test_checks++;
	for (int i = 0; i < STAB_N_INVARIANTS; i++) {
		if (!r->fails[i])
			continue;
		FAIL("%s: %s: %llu of %llu violated; first violation of the case: %s", name,
		     stab_invariant_names[i], (unsigned long long)r->fails[i],
		     (unsigned long long)r->samples[i], r->first);
	}
}

#endif

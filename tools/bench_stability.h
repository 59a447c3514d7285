/* bench_stability.h - `skybench stability`: the stiff cases as a report. */
#ifndef SKYD_BENCH_STABILITY_H
#define SKYD_BENCH_STABILITY_H

/* argv after "stability": --markdown FILE. Returns an exit status. */
int bench_stability(int argc, char **argv);

#endif

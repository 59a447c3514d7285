/* bench_demand.h - `skybench demand`: what leaving out unneeded tables saves,
 * measured on the real engine. */
#ifndef SKYD_BENCH_DEMAND_H
#define SKYD_BENCH_DEMAND_H

/* Runs the demand benchmark with skybench's arguments after "demand":
 * [--runs N] [--device SEL] [--markdown] [key=value ...]. Prints a table
 * (Markdown with --markdown) on stdout. Returns the process exit code. */
int bench_demand_main(int argc, char **argv);

#endif

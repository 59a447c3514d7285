/* bench_accuracy.h - `skybench accuracy`: the error of the sky-view tables
 * against the path-traced ground truth, put against the engine's run time,
 * for every quality preset and a sweep of each knob.
 *
 * Outputs (in --out DIR): accuracy.csv, accuracy.md, errtime.png (log-log,
 * Pareto front marked, drawn by gnuplot), fisheye-*.png (tables, ground truth,
 * signed relative error). Ground truth is cached by a hash of the scene and
 * of the path tracer settings (gt-<hash>.txt), so a re-run only times and
 * samples the tables.
 */
#ifndef SKYD_BENCH_ACCURACY_H
#define SKYD_BENCH_ACCURACY_H

/* argv[0] is the first argument after "accuracy". Returns the exit status:
 * 0, 1 on a failure or an exceeded --limits entry, 2 on a usage error, 77
 * when no Vulkan device opens (ctest's skip). */
int bench_accuracy_main(int argc, char **argv);

#endif

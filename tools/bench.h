/* bench.h — the subcommands of overcast-bench (one file each) and their shared helpers. */
#ifndef OC_TOOLS_BENCH_H
#define OC_TOOLS_BENCH_H

#include <stdio.h>

#include "oc_scene.h"

void oct_bench_usage(FILE *f);
/*! oct_parse_list() : "a,b,c" of integers in [lo, hi]; 0, or -1 after printing the error. */
int oct_parse_list(const char *prog, const char *opt, const char *text, long lo, long hi, long *out, int cap, int *n);
/*! oct_now() : monotonic seconds. */
double oct_now(void);
/*! oct_parse_at() : "LAT,LON" in degrees; 0, or -1 after printing the error. */
int oct_parse_at(const char *prog, const char *text, double at[2]);
/*! oct_load_scene() : the scene at path, or the built-in planet when path is NULL; 0, or -1 after
 *  printing the error. */
int oct_load_scene(const char *prog, const char *path, oc_scene_t *sc);
int oct_bench_render(const char *prog, int argc, char **argv);
int oct_bench_field(const char *prog, int argc, char **argv);
int oct_bench_tau(const char *prog, int argc, char **argv);
int oct_bench_plan(const char *prog, int argc, char **argv);
int oct_bench_world(const char *prog, int argc, char **argv);
/* bench_sweep.c: error against run time; bench_truth.c: Monte Carlo ground truth. Each prints its
 * own options section of --help. */
int oct_bench_sweep(const char *prog, int argc, char **argv);
void oct_bench_sweep_usage(FILE *f);
int oct_bench_truth(const char *prog, int argc, char **argv);
void oct_bench_truth_usage(FILE *f);
int oct_bench_stability(const char *prog, int argc, char **argv);
void oct_bench_stability_usage(FILE *f);
/* bench_features.c: each feature a scene uses, turned off alone: memory and time saved. */
int oct_bench_features(const char *prog, int argc, char **argv);
void oct_bench_features_usage(FILE *f);

#endif /* OC_TOOLS_BENCH_H */

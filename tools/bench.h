/* bench.h — the subcommands of overcast-bench (one file each) and their shared helpers. */
#ifndef OC_TOOLS_BENCH_H
#define OC_TOOLS_BENCH_H

#include <stdio.h>

#include "oc_brick.h"
#include "oc_scene.h"
#include "ocs_field.h"

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
/*! oct_fcache_t : a single-threaded brick cache in front of a field at time t (what the server's
 *  shared cache gives the τ callbacks): oct_fcache_sigma() and oct_fcache_bound() are
 *  ocs_tau_desc_t callbacks with ctx an oct_fcache_t; zero-initialise with f and t set, release
 *  with oct_fcache_free() (bench_tau.c). */
typedef struct {
  oc_key_t key;
  int has_bound, brick; /* brick: index + 1 into the pool, 0: not sampled */
  float lo, hi;
} oct_fcache_ent_t;
typedef struct {
  const ocs_field_t *f;
  double t;
  oct_fcache_ent_t *tab;
  size_t cap, n;
  float *pool;
  size_t nb, pool_cap;
  long sigma_calls, bound_calls, sigma_fetches, bound_fetches; /* callback calls; field work */
  int err;
} oct_fcache_t;
int oct_fcache_sigma(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]);
void oct_fcache_bound(void *ctx, oc_key_t key, float *lo, float *hi);
void oct_fcache_free(oct_fcache_t *c);
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
int oct_bench_model(const char *prog, int argc, char **argv);
void oct_bench_model_usage(FILE *f);
int oct_bench_stability(const char *prog, int argc, char **argv);
void oct_bench_stability_usage(FILE *f);
/* bench_features.c: each feature a scene uses, turned off alone: memory and time saved. */
int oct_bench_features(const char *prog, int argc, char **argv);
void oct_bench_features_usage(FILE *f);

#endif /* OC_TOOLS_BENCH_H */

/* bench_world.c — `overcast-bench world`: the server core stepped for a number of epochs.
 *
 * Viewers orbit slowly around the scene camera (or stand still); every epoch is planned, produced
 * and acknowledged. Reports per epoch the plan and production times, the process CPU (getrusage:
 * issue 17's measure, with epoch 0, the median and the largest epoch), the bricks produced and the
 * cache hit rate; over the run the wasted work, issue 17's anchor beside the world's non-empty
 * bricks per CPU-second, and the leaves refreshed against refreshing every leaf every epoch, with
 * the error that saving costs: how much a brick's σt can change within one of its level's time
 * steps (the most stale content can be off by), relative L1. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "bench.h"
#include "bench_util.h"
#include "ocs.h"

/* L1 change of a node's σt over one of its level's time steps starting at t (sum over samples),
 * and the L1 of its σt (den), so a level's figure is a ratio of sums. */
static double step_change(const ocs_field_t *f, oc_key_t key, double t, double *den_out) {
  int level = oc_key_level(key);
  uint64_t s0 = ocs_field_time_step(f, level, t);
  double dt = 0.01, t1 = t;
  for (int i = 0; i < 60; i++, dt *= 1.5) { /* find the next step */
    t1 = t + dt;
    if (ocs_field_time_step(f, level, t1) != s0) break;
  }
  float a[512], b[512];
  memset(a, 0, sizeof a);
  memset(b, 0, sizeof b);
  if (ocs_field_sample(f, key, t, a) < 0 || ocs_field_sample(f, key, t1, b) < 0) return NAN;
  double num = 0.0, den = 0.0;
  for (int i = 0; i < 512; i++) num += fabs((double)a[i] - b[i]), den += a[i];
  *den_out = den;
  return num;
}

/*-*** Options ***/

typedef struct {
  const char *scene, *camera;
  int viewers, epochs, budget, threads;
  double orbit, split, clocked;
} world_opts_t;

static const oc_cli_opt_t world_opts[] = {
    OCT_OPT_SCENE(world_opts_t),
    OCT_INT(world_opts_t, viewers, "viewers", "N", 1, 64, "1", "viewers, spread around the camera's heading when "
        "orbiting"),
    OCT_OPT_EPOCHS(world_opts_t, "20", "epochs to step"),
    OCT_OPT_BUDGET(world_opts_t, "64", "each viewer's"),
    OCT_OPT_THREADS(world_opts_t),
    OCT_OPT_CAMERA(world_opts_t),
    OCT_DBL(world_opts_t, orbit, "orbit", "DEG", -180, 180, "0", "heading change per epoch; 0: a still camera"),
    OCT_DBL_NOTE(world_opts_t, split, "split-fraction", "X", 0.001, 1, "the planner's, 0.1", "planner split cap per "
        "epoch as a fraction of capacity"),
    OCT_DBL_NOTE(world_opts_t, clocked, "clocked", "S", 0, 3600, "off", "clocked epochs: each tick shows only "
        "content that exists, then production runs S seconds; plan-ms includes the target plans (target-ms)"),
    OCT_OPTS_END};

OCT_SPEC(world,
         "The server core stepped for some epochs: plans, production, cache, refresh savings.",
         world_opts);

/*-*** The bench ***/

typedef struct {
  const world_opts_t *o;
  ocs_world_t *w;
  ocs_viewer_t *v[64];
  oc_camera_pose_t pose;
  uint64_t refresh_all, refreshed, last_produced;
  double *cpu; /* process CPU seconds of each epoch (getrusage) */
} world_run_t;

/* The process's CPU seconds so far, user and system, all threads. */
static double process_cpu(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec + 1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/* Viewer 0's output; zeroes when it has none (clocked: no state until the root exists). */
static ocs_epoch_out_t first_output(const world_run_t *R) {
  ocs_epoch_out_t o;
  memset(&o, 0, sizeof o);
  if (ocs_viewer_output(R->v[0], &o) < 0) memset(&o, 0, sizeof o);
  return o;
}

/* Epoch e: the views, the step, the acks, and its line. @return 0 or a negative error. */
static int world_epoch(world_run_t *R, long e) {
  const world_opts_t *opt = R->o;
  for (long i = 0; i < opt->viewers; i++) {
    oc_camera_pose_t p = R->pose;
    p.heading += opt->orbit * (double)e + 360.0 * (double)i / (double)opt->viewers * (opt->orbit != 0.0);
    oc_camera_t cam = oc_camera_from_pose(p);
    ocs_view_t view = {cam.pos, cam.forward, cam.up, p.fov, 1280, 720};
    ocs_viewer_set_view(R->v[i], &view);
  }
  uint32_t leaves_before = 0;
  {
    ocs_epoch_out_t o;
    if (ocs_viewer_output(R->v[0], &o) == 0) leaves_before = o.state->node_count;
  }
  int rc;
  double cpu0 = process_cpu();
  if ((rc = ocs_world_step(R->w)) < 0) return rc;
  ocs_world_stats_t ws;
  ocs_world_stats(R->w, &ws);
  double plan_s = ws.plan_seconds, target_s = ws.target_seconds;
  size_t queue = ocs_world_queue_length(R->w);
  if (opt->clocked >= 0 && (rc = ocs_world_produce(R->w, opt->clocked, 0)) < 0) return rc;
  ocs_world_stats(R->w, &ws);
  ocs_epoch_out_t o = first_output(R);
  for (long i = 0; i < opt->viewers; i++) {
    ocs_epoch_out_t oi;
    if (ocs_viewer_output(R->v[i], &oi) == 0) ocs_viewer_ack(R->v[i], oi.state->epoch);
  }
  if (e > 0) {
    R->refresh_all += leaves_before;
    R->refreshed += o.plan.refreshed;
  }
  R->cpu[e] = process_cpu() - cpu0;
  printf("%5ld %7u %7u %6u %9u %8u %9llu %9.3f %8.1f %9.1f %10.1f %6zu %7.2f\n", e, o.plan.leaves, o.plan.splits,
         o.plan.merges, o.plan.refreshed, o.plan.deferred, (unsigned long long)(ws.bricks_produced - R->last_produced),
         ws.cache_hit_rate, 1e3 * plan_s, 1e3 * target_s, 1e3 * ws.produce_seconds, queue, R->cpu[e]);
  fflush(stdout);
  R->last_produced = ws.bricks_produced;
  return 0;
}

/* Where the wasted work is: per level, the bricks made (ahead's not counted), those that ended up
 * empty and the seconds on each (an empty brick proven so by its bound costs a few µs, one sampled
 * tens). */
static void world_waste_by_level(const ocs_world_stats_t *ws) {
  const double empty = ws->brick_cpu_empty;
  printf("level   made  empty   CPU s  on empty s  µs per empty  share of the waste\n");
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    const double e = ws->level[l].cpu_empty;
    if (!ws->level[l].made) continue;
    printf("%5d %6llu %6llu %7.2f %11.2f %13.1f %18.1f%%\n", l, (unsigned long long)ws->level[l].made,
           (unsigned long long)ws->level[l].empty, ws->level[l].cpu, e,
           ws->level[l].empty ? 1e6 * e / (double)ws->level[l].empty : 0.0, empty > 0.0 ? 100.0 * e / empty : 0.0);
  }
}

/* The run's totals: production, wasted work, bounds and CPU. */
static void world_totals(const world_run_t *R) {
  ocs_world_stats_t ws;
  ocs_world_stats(R->w, &ws);
  printf("total: %llu bricks produced for %llu requested (hit rate %.3f), %llu σt samplings (%llu kept from the node's step before: "
         "proven the same), %llu τ volumes (%llu kept from the light stamp before: inputs unchanged), "
         "%llu clear-sky proofs of τ (%llu proven clear toward the sun: no march; %llu ground nodes by group volumes' "
         "columns)\n",
         (unsigned long long)ws.bricks_produced, (unsigned long long)ws.brick_requests, ws.cache_hit_rate,
         (unsigned long long)ws.sigma_produced, (unsigned long long)ws.sigma_kept, (unsigned long long)ws.tau_volumes,
         (unsigned long long)ws.tau_kept,
         (unsigned long long)ws.tau_direct,
         (unsigned long long)ws.tau_clear, (unsigned long long)ws.tau_columns);
  printf("ahead: %llu σt samplings of slow levels' next time steps (%llu all zero), %llu τ volumes of their next light "
         "stamps, %.2f s (%.2f s on the all-zero σt); the stock it leaves, due after the last epoch: %llu σt, %llu τ "
         "volumes, %.2f s\n",
         (unsigned long long)ws.ahead_sigma, (unsigned long long)ws.ahead_empty, (unsigned long long)ws.ahead_tau, ws.ahead_cpu,
         ws.ahead_cpu_empty, (unsigned long long)ws.ahead_stock_sigma, (unsigned long long)ws.ahead_stock_tau,
         ws.ahead_cpu_stock);
  double spent = ws.brick_cpu + ws.ahead_cpu, empty = ws.brick_cpu_empty + ws.ahead_cpu_empty;
  double run = spent - ws.ahead_cpu_stock; /* the stock ahead leaves is not this run's production */
  printf("wasted work: %llu of %llu bricks made ended up empty (σt and τ all zero), %.2f of %.2f s on made bricks "
         "and ahead (%.1f %%; %.1f %% of the %.2f s without ahead's stock; per-brick timers on the producer threads)\n",
         (unsigned long long)ws.bricks_empty, (unsigned long long)ws.bricks_produced, empty, spent,
         spent > 0.0 ? 100.0 * empty / spent : 0.0, run > 0.0 ? 100.0 * empty / run : 0.0, run);
  world_waste_by_level(&ws);
  ocs_field_stats_t fs;
  ocs_field_stats(ocs_world_field(R->w), &fs);
  double cpu = process_cpu();
  int epochs = R->o->epochs;
  printf("bounds: %llu field bounds, cache %llu hits / %llu misses (hit rate %.3f); process CPU %.1f s (%.2f s per epoch)\n",
         (unsigned long long)fs.bound_calls, (unsigned long long)fs.bound_hits, (unsigned long long)fs.bound_misses,
         fs.bound_hits + fs.bound_misses ? (double)fs.bound_hits / (double)(fs.bound_hits + fs.bound_misses) : 0.0, cpu,
         epochs > 0 ? cpu / (double)epochs : 0.0);
}

/* Issue 17's anchor beside the world's own rate, in the same run: the non-empty bricks made per
 * second of production CPU (the per-brick timers: made bricks and ahead; also without the stock
 * ahead leaves for after the run, which made none of them) and per second of process CPU (planning,
 * acks and the rest included), against a scalar 6-octave fBm once per voxel over (up to 4 096 of)
 * the brick nodes of viewer 0's last state, the fastest of three passes (one pass moved by ±11 %
 * between runs on the shared 2-core machine; the fastest is the stricter anchor). */
static void world_anchor(const world_run_t *R, double cpu) {
  ocs_world_stats_t ws;
  ocs_world_stats(R->w, &ws);
  ocs_epoch_out_t o = first_output(R);
  enum { MAXN = 4096 };
  static oc_key_t keys[MAXN];
  long n = 0;
  for (uint32_t i = 0; o.state && i < o.state->node_count && n < MAXN; i++)
    if (o.state->nodes[i].kind == OC_NODE_BRICK) keys[n++] = o.state->nodes[i].key;
  if (!n) return;
  double sink = 0.0, ta = INFINITY;
  for (int pass = 0; pass < 3; pass++) ta = fmin(ta, oct_anchor_seconds(keys, n, &sink));
  double anchor = (double)n / ta;
  double made = (double)(ws.bricks_produced - ws.bricks_empty), spent = ws.brick_cpu + ws.ahead_cpu;
  double run = spent - ws.ahead_cpu_stock; /* without the stock ahead leaves for after the run */
  printf("anchor: a scalar 6-octave fBm once per voxel over %ld of the state's bricks, %.0f bricks/s per core (the "
         "fastest of 3 passes); the world: %.0f non-empty bricks made, %.0f per second of production CPU (%.3f× the "
         "anchor; %.3f× without the %.2f s ahead spent on content due after the last epoch), %.0f per second of process "
         "CPU (%.3f×)\n",
         n, anchor, made, spent > 0.0 ? made / spent : 0.0, spent > 0.0 ? made / spent / anchor : 0.0,
         run > 0.0 ? made / run / anchor : 0.0, ws.ahead_cpu_stock, cpu > 0.0 ? made / cpu : 0.0,
         cpu > 0.0 ? made / cpu / anchor : 0.0);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Issue 17's CPU figures: epoch 0, the median of the later epochs, and the largest against it. */
static void world_cpu(const world_run_t *R) {
  int n = R->o->epochs - 1;
  printf("CPU per epoch (getrusage, the process): epoch 0 %.2f s", R->cpu[0]);
  if (n < 1) {
    printf("\n");
    return;
  }
  double *v = malloc((size_t)n * sizeof *v), mx = 0.0;
  long at = 1;
  if (!v) {
    printf("\n");
    return;
  }
  for (int i = 0; i < n; i++) {
    v[i] = R->cpu[i + 1];
    if (v[i] > mx) mx = v[i], at = i + 1;
  }
  qsort(v, (size_t)n, sizeof *v, cmp_double);
  double med = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  printf("; epochs 1..%d median %.2f s, largest %.2f s (epoch %ld, %.1f× the median)\n", n, med, mx, at,
         med > 0.0 ? mx / med : 0.0);
  free(v);
}

/* Animated fields: the refresh savings, and the error of not refreshing within a step: how far
 * content moves in one step, per level. */
static void world_refresh(const world_run_t *R) {
  printf("refresh (viewer 0, epochs 1..%d): %llu leaves refreshed; refreshing every leaf every epoch: %llu "
         "(%.1f%% of it, %.1fx fewer)\n",
         R->o->epochs - 1, (unsigned long long)R->refreshed, (unsigned long long)R->refresh_all,
         R->refresh_all ? 100.0 * R->refreshed / R->refresh_all : 0.0,
         R->refreshed ? (double)R->refresh_all / R->refreshed : INFINITY);
  ocs_epoch_out_t o = first_output(R);
  double num[22] = {0}, den[22] = {0};
  int n[22] = {0};
  for (uint32_t i = 0; i < o.state->node_count; i++) {
    const oc_node_t *nd = &o.state->nodes[i];
    int l = oc_key_level(nd->key);
    if (nd->kind != OC_NODE_BRICK || !(nd->range[OC_CH_SIGMA].hi > 0.0f) || n[l] >= 32) continue;
    double dn = 0.0, d = step_change(ocs_world_field(R->w), nd->key, o.state->time, &dn);
    if (!isfinite(d)) continue;
    num[l] += d;
    den[l] += dn;
    n[l]++;
  }
  printf("level  nodes  σt change within one of the level's time steps (L1, relative to the level's L1)\n");
  for (int l = 0; l < 22; l++)
    if (n[l] && den[l] > 0.0) printf("%5d %6d %10.4f\n", l, n[l], num[l] / den[l]);
}

/* The world and its viewers. */
static int world_setup(world_run_t *R, const char *prog, const oc_scene_t *sc) {
  char why[1024];
  const world_opts_t *o = R->o;
  ocs_world_desc_t wd = {.threads = o->threads, .cache_bytes = 1ull << 30, .clocked = o->clocked >= 0};
  if (ocs_world_create(&R->w, sc, &wd, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s", why);
  for (long i = 0; i < o->viewers; i++) {
    ocs_plan_desc_t d = {.budget = (uint64_t)o->budget << 20, .slot_bytes = OC_SLOT_BYTES,
                         .record_bytes = OC_RECORD_BYTES, .max_depth = 21, .split_fraction = o->split};
    if (ocs_world_add_viewer(R->w, &d, &R->v[i], NULL, why, sizeof why) < 0) return oc_cli_fail(prog, -1, "%s", why);
  }
  printf("scene %s, %d viewer(s), budget %d MiB each, %d producer threads, %s field\n", sc->name, o->viewers,
         o->budget, (int)wd.threads, ocs_field_animated(ocs_world_field(R->w)) ? "animated" : "static");
  if (wd.clocked)
    printf("clocked: each tick builds its states from content that exists, then production runs %.3g s\n", o->clocked);
  return 0;
}

int oct_bench_world(const char *prog, int argc, char **argv) {
  world_opts_t o = {.clocked = -1.0};
  static oc_scene_t sc;
  world_run_t R = {.o = &o};
  int rc = oct_begin(&oct_bench_world_spec, argc, argv, &o, &o.scene, &o.camera, &sc, &R.pose);
  if (rc != OCT_GO) return rc;
  if (world_setup(&R, prog, &sc) < 0) {
    rc = OC_EXIT_RUNTIME;
    goto out;
  }
  printf("epoch  leaves  splits merges refreshed deferred  produced  hit-rate  plan-ms target-ms produce-ms  queue  cpu-s\n");
  R.cpu = calloc((size_t)o.epochs, sizeof *R.cpu);
  if (!R.cpu) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
    goto out;
  }
  int r = 0;
  for (long e = 0; e < o.epochs && r == 0; e++) r = world_epoch(&R, e);
  if (r < 0) {
    rc = oc_cli_fail(prog, OC_EXIT_RUNTIME, "epoch failed: %s", oc_strerror(r));
    goto out;
  }
  world_totals(&R);
  world_anchor(&R, process_cpu());
  world_cpu(&R);
  if (ocs_field_animated(ocs_world_field(R.w)) && o.epochs > 1) world_refresh(&R);
  rc = OC_EXIT_OK;
out:
  free(R.cpu);
  ocs_world_free(R.w);
  oc_scene_free(&sc);
  return rc;
}

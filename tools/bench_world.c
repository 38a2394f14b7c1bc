/* bench_world.c — `overcast-bench world`: the server core stepped for a number of epochs.
 *
 * Viewers orbit slowly around the scene camera (or stand still); every epoch is planned, produced
 * and acknowledged. Reports per epoch the plan and production times, the bricks produced and the
 * cache hit rate, and over the run the leaves refreshed against refreshing every leaf every epoch, with the error that saving costs: how much a brick's σt can change
 * within one of its level's time steps (the most stale content can be off by), relative L1. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "bench.h"
#include "bench_util.h"
#include "oc_camera.h"
#include "oc_cli.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "ocs_field.h"
#include "world.h"

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

int oct_bench_world(const char *prog, int argc, char **argv) {
  enum { O_SCENE = 256, O_VIEWERS, O_EPOCHS, O_BUDGET, O_THREADS, O_CAMERA, O_ORBIT, O_SPLIT, O_CLOCKED, O_HELP };
  static const struct option opts[] = {{"scene", required_argument, 0, O_SCENE},     {"viewers", required_argument, 0, O_VIEWERS},
                                       {"epochs", required_argument, 0, O_EPOCHS},   {"budget", required_argument, 0, O_BUDGET},
                                       {"threads", required_argument, 0, O_THREADS}, {"camera", required_argument, 0, O_CAMERA},
                                       {"orbit", required_argument, 0, O_ORBIT},     {"split-fraction", required_argument, 0, O_SPLIT},
                                       {"clocked", required_argument, 0, O_CLOCKED}, {"help", no_argument, 0, O_HELP},
                                       {0, 0, 0, 0}};
  const char *scene_path = NULL, *camera_text = NULL;
  long viewers = 1, epochs = 20, budget_mib = 64, threads = 0;
  double orbit = 0.0, split = 0.0, clocked = -1.0;
  int c;
  opterr = 0;
  optind = 1;
  while ((c = getopt_long(argc, argv, "", opts, NULL)) != -1) {
    switch (c) {
      case O_SCENE: scene_path = optarg; break;
      case O_VIEWERS: if (oc_cli_int(prog, "--viewers", optarg, 1, 64, &viewers)) return OC_EXIT_USAGE; break;
      case O_EPOCHS: if (oc_cli_int(prog, "--epochs", optarg, 1, 100000, &epochs)) return OC_EXIT_USAGE; break;
      case O_BUDGET: if (oc_cli_int(prog, "--budget", optarg, 1, 1 << 20, &budget_mib)) return OC_EXIT_USAGE; break;
      case O_THREADS: if (oc_cli_int(prog, "--threads", optarg, 0, 64, &threads)) return OC_EXIT_USAGE; break;
      case O_CAMERA: camera_text = optarg; break;
      case O_ORBIT: if (oc_cli_double(prog, "--orbit", optarg, -180, 180, &orbit)) return OC_EXIT_USAGE; break;
      case O_SPLIT: if (oc_cli_double(prog, "--split-fraction", optarg, 0.001, 1, &split)) return OC_EXIT_USAGE; break;
      case O_CLOCKED: if (oc_cli_double(prog, "--clocked", optarg, 0, 3600, &clocked)) return OC_EXIT_USAGE; break;
      case O_HELP: oct_bench_usage(stdout); return OC_EXIT_OK;
      default: return oc_cli_fail(prog, OC_EXIT_USAGE, "world: unknown or incomplete option \"%s\"", argv[optind - 1]);
    }
  }
  if (optind < argc) return oc_cli_fail(prog, OC_EXIT_USAGE, "world: unexpected argument \"%s\"", argv[optind]);

  char why[1024];
  static oc_scene_t sc;
  if (oct_load_scene(prog, scene_path, &sc)) return OC_EXIT_RUNTIME;
  oc_camera_pose_t pose = {sc.camera.pos, sc.camera.heading, sc.camera.pitch, sc.camera.fov};
  if (camera_text && oc_camera_parse(camera_text, &pose, why, sizeof why) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--camera: %s", why);
  }
  ocs_world_desc_t wd = {.threads = (int)threads, .cache_bytes = 1ull << 30, .clocked = clocked >= 0};
  ocs_world_t *w = NULL;
  if (ocs_world_create(&w, &sc, &wd, why, sizeof why) < 0) {
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  }
  ocs_viewer_t *v[64];
  for (long i = 0; i < viewers; i++) {
    ocs_plan_desc_t d = {.budget = (uint64_t)budget_mib << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .max_depth = 21,
                         .split_fraction = split};
    if (ocs_world_add_viewer(w, &d, &v[i], NULL, why, sizeof why) < 0) {
      ocs_world_free(w);
      oc_scene_free(&sc);
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
    }
  }
  printf("scene %s, %ld viewer(s), budget %ld MiB each, %d producer threads, %s field\n", sc.name, viewers, budget_mib,
         (int)wd.threads, ocs_field_animated(ocs_world_field(w)) ? "animated" : "static");
  if (wd.clocked)
    printf("clocked: each tick builds its states from content that exists, then production runs %.3g s\n", clocked);
  printf("epoch  leaves  splits merges refreshed deferred  produced  hit-rate  plan-ms target-ms produce-ms  queue\n");
  uint64_t refresh_all = 0, refreshed = 0, last_produced = 0, produced_after_first = 0;
  int rc = 0;
  for (long e = 0; e < epochs && rc == 0; e++) {
    for (long i = 0; i < viewers; i++) {
      oc_camera_pose_t p = pose;
      p.heading += orbit * (double)e + 360.0 * (double)i / (double)viewers * (orbit != 0.0);
      oc_camera_t cam = oc_camera_from_pose(p);
      ocs_view_t view = {cam.pos, cam.forward, cam.up, p.fov, 1280, 720};
      ocs_viewer_set_view(v[i], &view);
    }
    uint32_t leaves_before = 0;
    {
      ocs_epoch_out_t o;
      if (ocs_viewer_output(v[0], &o) == 0) leaves_before = o.state->node_count;
    }
    if ((rc = ocs_world_step(w)) < 0) break;
    ocs_world_stats_t ws;
    ocs_world_stats(w, &ws);
    double plan_s = ws.plan_seconds, target_s = ws.target_seconds;
    size_t queue = ocs_world_queue_length(w);
    if (wd.clocked && (rc = ocs_world_produce(w, clocked, 0)) < 0) break;
    rc = 0;
    ocs_world_stats(w, &ws);
    ocs_epoch_out_t o;
    memset(&o, 0, sizeof o);
    if (ocs_viewer_output(v[0], &o) < 0) memset(&o, 0, sizeof o); /* clocked: no state until the root exists */
    for (long i = 0; i < viewers; i++) {
      ocs_epoch_out_t oi;
      if (ocs_viewer_output(v[i], &oi) == 0) ocs_viewer_ack(v[i], oi.state->epoch);
    }
    if (e > 0) {
      refresh_all += leaves_before;
      refreshed += o.plan.refreshed;
      produced_after_first += ws.bricks_produced - last_produced;
    }
    printf("%5ld %7u %7u %6u %9u %8u %9llu %9.3f %8.1f %9.1f %10.1f %6zu\n", e, o.plan.leaves, o.plan.splits, o.plan.merges,
           o.plan.refreshed, o.plan.deferred, (unsigned long long)(ws.bricks_produced - last_produced), ws.cache_hit_rate,
           1e3 * plan_s, 1e3 * target_s, 1e3 * ws.produce_seconds, queue);
    fflush(stdout);
    last_produced = ws.bricks_produced;
  }
  if (rc < 0) {
    ocs_world_free(w);
    oc_scene_free(&sc);
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "epoch failed: %s", oc_strerror(rc));
  }
  ocs_world_stats_t ws;
  ocs_world_stats(w, &ws);
  printf("total: %llu bricks produced for %llu requested (hit rate %.3f), %llu σt samplings, %llu τ volumes, "
         "%llu single-node τ (%llu proven clear toward the sun: no march)\n",
         (unsigned long long)ws.bricks_produced, (unsigned long long)ws.brick_requests, ws.cache_hit_rate,
         (unsigned long long)ws.sigma_produced, (unsigned long long)ws.tau_volumes, (unsigned long long)ws.tau_direct,
         (unsigned long long)ws.tau_clear);
  printf("wasted work: %llu of %llu bricks made ended up empty (σt and τ all zero), %.2f of %.2f s on made bricks "
         "(%.1f %%; per-brick timers on the producer threads)\n",
         (unsigned long long)ws.bricks_empty, (unsigned long long)ws.bricks_produced, ws.brick_cpu_empty, ws.brick_cpu,
         ws.brick_cpu > 0.0 ? 100.0 * ws.brick_cpu_empty / ws.brick_cpu : 0.0);
  {
    ocs_field_stats_t fs;
    struct rusage ru;
    ocs_field_stats(ocs_world_field(w), &fs);
    getrusage(RUSAGE_SELF, &ru);
    double cpu = (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec + 1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    printf("bounds: %llu field bounds, cache %llu hits / %llu misses (hit rate %.3f); process CPU %.1f s (%.2f s per epoch)\n",
           (unsigned long long)fs.bound_calls, (unsigned long long)fs.bound_hits, (unsigned long long)fs.bound_misses,
           fs.bound_hits + fs.bound_misses ? (double)fs.bound_hits / (double)(fs.bound_hits + fs.bound_misses) : 0.0, cpu,
           epochs > 0 ? cpu / (double)epochs : 0.0);
  }
  if (ocs_field_animated(ocs_world_field(w)) && epochs > 1) {
    printf("refresh (viewer 0, epochs 1..%ld): %llu leaves refreshed; refreshing every leaf every epoch: %llu "
           "(%.1f%% of it, %.1fx fewer)\n",
           epochs - 1, (unsigned long long)refreshed, (unsigned long long)refresh_all,
           refresh_all ? 100.0 * refreshed / refresh_all : 0.0, refreshed ? (double)refresh_all / refreshed : INFINITY);
    /* the error of not refreshing within a step: how far content moves in one step, per level */
    ocs_epoch_out_t o;
    memset(&o, 0, sizeof o);
    if (ocs_viewer_output(v[0], &o) < 0) memset(&o, 0, sizeof o); /* clocked: no state until the root exists */
    double num[22] = {0}, den[22] = {0};
    int n[22] = {0};
    for (uint32_t i = 0; i < o.state->node_count; i++) {
      const oc_node_t *nd = &o.state->nodes[i];
      int l = oc_key_level(nd->key);
      if (nd->kind != OC_NODE_BRICK || !(nd->range[OC_CH_SIGMA].hi > 0.0f) || n[l] >= 32) continue;
      double dn = 0.0, d = step_change(ocs_world_field(w), nd->key, o.state->time, &dn);
      if (!isfinite(d)) continue;
      num[l] += d;
      den[l] += dn;
      n[l]++;
    }
    printf("level  nodes  σt change within one of the level's time steps (L1, relative to the level's L1)\n");
    for (int l = 0; l < 22; l++)
      if (n[l] && den[l] > 0.0) printf("%5d %6d %10.4f\n", l, n[l], num[l] / den[l]);
  }
  ocs_world_free(w);
  oc_scene_free(&sc);
  return OC_EXIT_OK;
}

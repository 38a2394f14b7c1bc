/* test_world.c — the server core end to end, stepped by command: plans become valid states under
 * the budget, production is shared between viewers and never repeated for a static field, slow
 * viewers are coalesced and get smaller plans, results do not depend on the thread count, and
 * τ in the produced bricks matches the analytic optical depth of a slab. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h> /* close */

#include <cmocka.h>

#include "test_main.h"
#include "analytic.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "report.h"
#include "world.h"

static const char *SPHERE =
    "{\"version\":1,\"features\":{\"animation\":false},\"sun\":{\"lat\":20,\"lon\":10},"
    "\"sources\":[{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":2000,\"sigma_t\":0.05},"
    "{\"type\":\"box\",\"lat\":0.05,\"lon\":0.02,\"alt\":1500,\"size\":[3000,2000,1500],\"sigma_t\":0.01}]}";

static const char *SLAB =
    "{\"version\":1,\"features\":{\"animation\":false},\"sun\":{\"lat\":0,\"lon\":0},"
    "\"sources\":[{\"type\":\"slab\",\"base\":2000,\"top\":3000,\"sigma_t\":0.01}]}";

static void scene_from(oc_scene_t *sc, const char *json) {
  char why[512];
  if (oc_scene_parse(sc, json, strlen(json), "test.json", why, sizeof why) < 0) fail_msg("scene: %s", why);
}

static ocs_world_t *world_from(const char *json, int threads) {
  oc_scene_t sc;
  scene_from(&sc, json);
  ocs_world_desc_t d = {.threads = threads, .cache_bytes = 64u << 20, .validate = 1};
  ocs_world_t *w = NULL;
  char why[512];
  if (ocs_world_create(&w, &sc, &d, why, sizeof why) < 0) fail_msg("world: %s", why);
  oc_scene_free(&sc);
  return w;
}

static ocs_view_t view_at(double lat, double lon, double alt, double heading, double pitch) {
  oc_camera_pose_t pose = {{lat, lon, alt}, heading, pitch, 60.0};
  oc_camera_t c = oc_camera_from_pose(pose);
  return (ocs_view_t){c.pos, c.forward, c.up, 60.0, 160, 90};
}

static ocs_viewer_t *add_viewer(ocs_world_t *w, uint64_t budget) {
  /* half the capacity per epoch (the default is a tenth): CI steps at most 8 epochs per test */
  ocs_plan_desc_t d = {.budget = budget, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 18, .split_fraction = 0.5, .reserve = 0.1};
  ocs_viewer_t *v = NULL;
  char why[256];
  if (ocs_world_add_viewer(w, &d, &v, NULL, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  return v;
}

/* Steps once, acknowledges, checks the budget invariant over the kept states. */
static void step_ack(ocs_world_t *w, ocs_viewer_t *const *v, int n) {
  assert_int_equal(ocs_world_step(w), 0);
  for (int i = 0; i < n; i++) {
    ocs_epoch_out_t o;
    assert_int_equal(ocs_viewer_output(v[i], &o), 0);
    ocs_viewer_stats_t vs;
    ocs_viewer_stats(v[i], &vs);
    assert_true(vs.resident_bytes <= vs.budget);
    ocs_viewer_ack(v[i], o.state->epoch);
  }
}

static void test_world__states_valid_under_budget_and_static_converges(void **st) {
  (void)st;
  ocs_world_t *w = world_from(SPHERE, 2);
  ocs_viewer_t *v = add_viewer(w, 4u << 20);
  ocs_view_t view = view_at(-0.02, -0.02, 2500, 45, 5);
  assert_int_equal(ocs_viewer_set_view(v, &view), 0);
  uint64_t produced[8];
  uint32_t lacking[8], leaves = 0;
  for (int e = 0; e < 8; e++) {
    step_ack(w, &v, 1);
    ocs_world_stats_t ws;
    ocs_world_stats(w, &ws);
    produced[e] = ws.bricks_produced;
    ocs_epoch_out_t o;
    ocs_viewer_output(v, &o);
    lacking[e] = o.nlacking;
    if (getenv("OC_TEST_VERBOSE"))
      printf("epoch %d: leaves %u splits %u merges %u new %u lacking %u stop %s pred %llu steady %llu\n", e, o.plan.leaves,
             o.plan.splits, o.plan.merges, o.plan.new_bricks, o.nlacking, o.plan.stop,
             (unsigned long long)o.plan.predicted_bytes, (unsigned long long)o.plan.steady_bytes);
    leaves = o.state->node_count;
    /* every brick the viewer lacks is in the state; everything else it already holds */
    for (uint32_t i = 0; i < o.nlacking; i++) assert_non_null(oc_state_find_brick(o.state, o.lacking[i]));
  }
  printf("world: %u leaves after 8 epochs\n", leaves);
  /* the field is static: once the tree has converged nothing is produced or sent again */
  assert_int_equal(lacking[7], 0);
  assert_int_equal(produced[7], produced[6]);
  assert_true(leaves > 64);
  /* the wasted work per level (overcast-bench world's table): every brick made is counted at its
   * level once (against the cache's own count), and some of the sphere's surroundings came back empty */
  ocs_world_stats_t ws;
  ocs_world_stats(w, &ws);
  uint64_t made = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    assert_true(ws.level[l].empty <= ws.level[l].made && ws.level[l].cpu_empty <= ws.level[l].cpu);
    made += ws.level[l].made;
  }
  assert_int_equal(made, ws.bricks_produced);
  assert_true(ws.bricks_empty > 0 && ws.bricks_empty < made);
  assert_true(ws.brick_cpu_empty > 0.0 && ws.brick_cpu_empty < ws.brick_cpu);
  ocs_world_free(w);
}

static void test_world__two_viewers_cost_one_generation(void **st) {
  (void)st;
  ocs_view_t view = view_at(-0.02, -0.02, 2500, 45, 5);
  ocs_world_stats_t one, two;
  {
    ocs_world_t *w = world_from(SPHERE, 2);
    ocs_viewer_t *v = add_viewer(w, 2u << 20);
    ocs_viewer_set_view(v, &view);
    for (int e = 0; e < 3; e++) step_ack(w, &v, 1);
    ocs_world_stats(w, &one);
    ocs_world_free(w);
  }
  {
    ocs_world_t *w = world_from(SPHERE, 2);
    ocs_viewer_t *v[2] = {add_viewer(w, 2u << 20), add_viewer(w, 2u << 20)};
    ocs_viewer_set_view(v[0], &view);
    ocs_viewer_set_view(v[1], &view);
    for (int e = 0; e < 3; e++) step_ack(w, v, 2);
    ocs_world_stats(w, &two);
    /* same camera, same budget: identical states */
    ocs_epoch_out_t a, b;
    ocs_viewer_output(v[0], &a);
    ocs_viewer_output(v[1], &b);
    assert_true(oc_state_checksum(a.state) == oc_state_checksum(b.state));
    ocs_world_free(w);
  }
  assert_true(one.bricks_produced > 0);
  assert_int_equal(two.bricks_produced, one.bricks_produced);
  assert_int_equal(two.sigma_produced, one.sigma_produced);
  assert_int_equal(two.brick_requests, 2 * one.brick_requests);
  printf("world: bricks produced for one viewer %llu, for two %llu (requests %llu), cache hit rate %.3f\n",
         (unsigned long long)one.bricks_produced, (unsigned long long)two.bricks_produced,
         (unsigned long long)two.brick_requests, two.cache_hit_rate);
}

static void test_world__thread_count_does_not_change_states(void **st) {
  (void)st;
  uint64_t sum[2];
  int threads[2] = {1, 3};
  ocs_view_t view = view_at(0.01, 0.0, 1000, 0, 20);
  for (int k = 0; k < 2; k++) {
    ocs_world_t *w = world_from(SLAB, threads[k]);
    ocs_viewer_t *v = add_viewer(w, 1u << 20);
    ocs_viewer_set_view(v, &view);
    for (int e = 0; e < 3; e++) step_ack(w, &v, 1);
    ocs_epoch_out_t o;
    ocs_viewer_output(v, &o);
    sum[k] = oc_state_checksum(o.state);
    ocs_world_free(w);
  }
  assert_true(sum[0] == sum[1]);
}

static void test_world__unacknowledged_viewer_is_coalesced_and_throttled(void **st) {
  (void)st;
  ocs_world_t *w = world_from(SPHERE, 2);
  ocs_viewer_t *v = add_viewer(w, 4u << 20);
  ocs_view_t view = view_at(-0.02, -0.02, 2500, 45, 5);
  ocs_viewer_set_view(v, &view);
  step_ack(w, &v, 1);
  assert_int_equal(ocs_world_step(w), 0); /* epoch 2 sent, never acknowledged in time */
  ocs_epoch_out_t o;
  ocs_viewer_output(v, &o);
  uint64_t in_flight = o.state->epoch;
  uint32_t sent_new = o.nlacking;
  for (int e = 0; e < 3; e++) assert_int_equal(ocs_world_step(w), 0);
  ocs_viewer_stats_t vs;
  ocs_viewer_stats(v, &vs);
  assert_int_equal(vs.coalesced, 3);
  ocs_viewer_output(v, &o);
  assert_true(o.state->epoch == in_flight); /* nothing new while one is in flight */
  assert_int_equal(ocs_viewer_ack(v, in_flight + 1), OC_EINVAL);
  assert_int_equal(ocs_viewer_ack(v, in_flight), 0);
  assert_int_equal(ocs_world_step(w), 0);
  ocs_viewer_output(v, &o);
  /* it took 4 epochs for the last state: the next one brings at most a quarter as many bricks */
  uint32_t limit = sent_new / 4 > 8 ? sent_new / 4 : 8;
  assert_true(o.nlacking <= limit);
  assert_true(o.plan.new_bricks <= limit);
  printf("world: slow viewer: %u new bricks in the unacknowledged state, %u after (limit %u)\n", sent_new, o.nlacking, limit);
  ocs_world_free(w);
}

/* τ in produced bricks against the slab's analytic optical depth (sun straight overhead at 0,0).
 * The march integrates the trilinear σt exactly (test_sun_depth) and the slab's box filter is exact
 * (source_analytic.c), so along the face normal the whole chain is exact up to the codes and float
 * sums: every sample away from the faces within 1 %. */
static void test_world__tau_matches_slab(void **st) {
  (void)st;
  ocs_world_t *w = world_from(SLAB, 2);
  ocs_viewer_t *v = add_viewer(w, 8u << 20);
  ocs_view_t view = view_at(0.0, 0.0, 2500, 0, 0);
  ocs_viewer_set_view(v, &view);
  for (int e = 0; e < 4; e++) step_ack(w, &v, 1);
  ocs_medium_t m;
  char why[256];
  assert_int_equal(ocs_scene_medium(ocs_world_scene(w), &m, why, sizeof why), 0);
  ocs_epoch_out_t o;
  ocs_viewer_output(v, &o);
  double worst = 0.0;
  int checked = 0, nodes = 0;
  for (uint32_t i = 0; i < o.state->node_count; i++) {
    const oc_node_t *n = &o.state->nodes[i];
    if (n->kind != OC_NODE_BRICK) continue;
    const oc_brick_t *b = oc_state_find_brick(o.state, n->brick_id);
    float sg[512], tau[512];
    oc_brick_decode(&b->codes, n->range, sg, tau);
    oc_dvec3 org;
    double size;
    oc_key_bounds(n->key, &org, &size);
    double vm = oc_key_size(oc_key_level(n->key) - 1) / 7.0;
    int count = 0;
    for (int s = 0; s < 512; s++) {
      oc_dvec3 p = oc_dv3(org.x + (s & 7) * size / 7, org.y + ((s >> 3) & 7) * size / 7, org.z + (s >> 6) * size / 7);
      double alt = oc_dlen(p) - OC_PLANET_RADIUS;
      /* away from the faces by the filter footprint: a march-level voxel and the node's own */
      double margin = vm + size / 7.0;
      if (fabs(alt - 2000.0) < margin || fabs(alt - 3000.0) < margin || sg[s] <= 0.0f) continue;
      double ref = ocs_medium_tau_sun(&m, p, ocs_world_scene(w)->sun_dir);
      double err = fabs(tau[s] - ref) / ref;
      if (err > worst) {
        worst = err;
        if (getenv("OC_TEST_VERBOSE"))
          printf("tau: level %d alt %.1f tau %g ref %g relative error %.3g\n", oc_key_level(n->key), alt, tau[s], ref, err);
      }
      count++;
      checked++;
    }
    nodes += count > 0;
  }
  oc_report("world", "τ of produced bricks vs slab (sun at the zenith), worst relative error", worst, 0.01, "");
  printf("world: τ vs slab over %d samples in %d nodes: worst relative error %.3g\n", checked, nodes, worst);
  assert_true(checked > 1000 && nodes > 10);
  assert_true(worst < 0.01);
  ocs_world_free(w);
}

/* A weather change while the world runs (what the control channel will call): a static procedural
 * field is never regenerated until the preset changes; then every viewer's next states refresh. */
static void test_world__weather_change_refreshes_every_viewer(void **st) {
  (void)st;
  const char *json = "{\"version\":1,\"features\":{\"animation\":false,\"shadows\":false},"
                     "\"sources\":[{\"type\":\"procedural\",\"preset\":\"fair\"}]}";
  ocs_world_t *w = world_from(json, 2);
  ocs_viewer_t *v[2] = {add_viewer(w, 512u << 10), add_viewer(w, 512u << 10)};
  ocs_view_t view = view_at(45.0, 0.0, 3000, 260, -10);
  ocs_viewer_set_view(v[0], &view);
  ocs_viewer_set_view(v[1], &view);
  ocs_epoch_out_t o0, o1;
  for (int e = 0; e < 3; e++) {
    step_ack(w, v, 2);
    ocs_viewer_output(v[0], &o0);
    assert_int_equal(o0.plan.refreshed, 0); /* static: no content is ever regenerated */
  }
  ocs_world_stats_t a, b;
  ocs_world_stats(w, &a);
  assert_int_equal(ocs_world_set_weather(w, ocs_world_utc(w), OC_PRESET_OVERCAST, 10.0), 0);
  step_ack(w, v, 2);
  ocs_world_stats(w, &b);
  ocs_viewer_output(v[0], &o0);
  ocs_viewer_output(v[1], &o1);
  printf("world: weather change: %llu bricks produced for both viewers, %u leaves refreshed each\n",
         (unsigned long long)(b.bricks_produced - a.bricks_produced), o0.plan.refreshed);
  assert_true(b.bricks_produced > a.bricks_produced);
  assert_true(o0.plan.refreshed > 0 && o0.plan.refreshed == o1.plan.refreshed);
  assert_true(oc_state_checksum(o0.state) == oc_state_checksum(o1.state)); /* both see the same weather */
  ocs_world_free(w);
}

static void test_world__admission_and_bad_input(void **st) {
  (void)st;
  oc_scene_t sc;
  scene_from(&sc, SPHERE);
  ocs_world_desc_t d = {.threads = 1, .viewer_bytes = 10u << 20, .max_budget = 10u << 20};
  ocs_world_t *w = NULL;
  char why[256];
  assert_int_equal(ocs_world_create(&w, &sc, &d, why, sizeof why), 0);
  oc_scene_free(&sc);
  ocs_plan_desc_t req = {.budget = 8u << 20, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 30}, got;
  ocs_viewer_t *a, *b;
  assert_int_equal(ocs_world_add_viewer(w, &req, &a, &got, why, sizeof why), 0);
  assert_int_equal(got.max_depth, 21);
  assert_int_equal(got.kept_states, 2); /* static scene */
  req.budget = 1;                       /* raised to the minimum */
  assert_int_equal(ocs_world_add_viewer(w, &req, &b, &got, why, sizeof why), 0);
  assert_true(got.budget == ocs_plan_min_budget(&got));
  req.slot_bytes = 1u << 20;
  ocs_viewer_t *c;
  assert_int_equal(ocs_world_add_viewer(w, &req, &c, &got, why, sizeof why), OC_ERANGE);
  assert_non_null(strstr(why, "server full"));
  ocs_view_t bad = view_at(0, 0, 1000, 0, 0);
  bad.forward.x = NAN;
  assert_int_equal(ocs_viewer_set_view(a, &bad), OC_EINVAL);
  /* a viewer without a camera is simply not planned */
  assert_int_equal(ocs_world_step(w), 0);
  ocs_epoch_out_t o;
  assert_int_equal(ocs_viewer_output(a, &o), OC_ENOENT);
  ocs_world_remove_viewer(w, b);
  ocs_world_free(w);
}

/* The default per-viewer maximum is a fair share: a quarter of the total, at most 1 GiB; a huge
 * request is clamped to it, and what admission is told matches what add_viewer grants. */
static void test_world__fair_share(void **st) {
  (void)st;
  assert_true(ocs_world_fair_share(4ull << 30) == 1ull << 30);
  assert_true(ocs_world_fair_share(16ull << 30) == OCS_FAIR_SHARE_MAX);
  assert_true(ocs_world_fair_share(100ull << 20) == 25ull << 20);
  oc_scene_t sc;
  scene_from(&sc, SPHERE);
  ocs_world_desc_t d = {.threads = 1, .viewer_bytes = 100u << 20};
  ocs_world_t *w = NULL;
  char why[256];
  assert_int_equal(ocs_world_create(&w, &sc, &d, why, sizeof why), 0);
  oc_scene_free(&sc);
  ocs_plan_desc_t req = {.budget = UINT64_MAX, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 21}, got;
  ocs_admission_t a;
  ocs_world_admission(w, &req, &a);
  assert_true(a.wanted == 25u << 20 && a.max_budget == 25u << 20 && a.left == 100u << 20);
  assert_true(a.minimum == 2 * (2048 + 32));
  ocs_viewer_t *v[4];
  for (int i = 0; i < 4; i++) {
    assert_int_equal(ocs_world_add_viewer(w, &req, &v[i], &got, why, sizeof why), 0);
    assert_true(got.budget == 25u << 20);
  }
  ocs_world_admission(w, &req, &a);
  assert_true(a.left == 0 && a.wanted == 25u << 20);
  ocs_viewer_t *x;
  assert_int_equal(ocs_world_add_viewer(w, &req, &x, &got, why, sizeof why), OC_ERANGE);
  ocs_world_remove_viewer(w, v[0]);
  ocs_world_free(w);
}

/* An OCS_BRICK_TRACE file's sums (world.c, trace_interval): every interval's seconds, the wasted
 * ones', and those of ahead's stock (due after the world time of the last line, "now T"). */
typedef struct {
  long lines, wasted;
  double all, waste, stock;
} trace_sums_t;

static trace_sums_t trace_sums(const char *path) {
  trace_sums_t t = {0};
  FILE *f = fopen(path, "r");
  assert_non_null(f);
  char line[256], due[64];
  double now = INFINITY, stock_due[4096], stock_s[4096];
  long nstock = 0;
  while (fgets(line, sizeof line, f)) {
    int tid, wasted;
    double t0, t1;
    if (sscanf(line, "now %lf", &now) == 1) continue;
    assert_int_equal(sscanf(line, "%d %lf %lf %d %63s", &tid, &t0, &t1, &wasted, due), 5);
    assert_true(tid > 0 && t1 >= t0 && (wasted == 0 || wasted == 1));
    t.all += t1 - t0, t.lines++;
    if (wasted) t.waste += t1 - t0, t.wasted++;
    if (strcmp(due, "-") == 0) continue;
    assert_true(nstock < 4096); /* ahead's intervals, more than this test's runs make */
    stock_due[nstock] = atof(due), stock_s[nstock++] = t1 - t0;
  }
  fclose(f);
  assert_true(isfinite(now)); /* the world's last line */
  for (long i = 0; i < nstock; i++)
    if (stock_due[i] > now) t.stock += stock_s[i];
  return t;
}

/* The planet's first epochs take minutes under AddressSanitizer; the gcc stage runs these. */
#if defined(__SANITIZE_ADDRESS__)
#define SKIP_PLANET_RUN_UNDER_ASAN()                                                                         \
  do {                                                                                                       \
    printf("built with AddressSanitizer: skipped (the planet's first epochs take minutes; the gcc stage runs it)\n"); \
    skip();                                                                                                  \
  } while (0)
#else
#define SKIP_PLANET_RUN_UNDER_ASAN() ((void)0)
#endif

/* Ahead (world.c): a slow level's next σt and τ volumes are made over the epochs before they are
 * due. The states are the same bytes with and without it, and the changes find what it made: at
 * least half of its σt samplings and of its τ volumes replace one the epoch of the change would have
 * made. What it made for changes after the last epoch is the stock the stats report apart (measured:
 * 112 of 130 τ volumes used, 17 in the stock). The planet's own camera and sun, a 2 MiB viewer, 40
 * epochs: levels 11–13 change every 2–12 epochs. */
static void planet_run_world(const char *off, uint64_t sums[], int epochs, ocs_world_stats_t *out) {
  if (off) setenv(off, "0", 1); /* OCS_AHEAD or OCS_TAU_KEEP: that saving off */
  ocs_world_t *w = world_from("{\"version\":1,\"sun\":{\"lat\":20,\"lon\":10},"
                              "\"sources\":[{\"type\":\"procedural\",\"preset\":\"fair\"}]}", 2);
  if (off) unsetenv(off);
  ocs_plan_desc_t pd = {.budget = 2u << 20, .slot_bytes = 2048, .record_bytes = 32, .max_depth = 14, .split_fraction = 0.5, .reserve = 0.1};
  ocs_viewer_t *v = NULL;
  char why[256];
  if (ocs_world_add_viewer(w, &pd, &v, NULL, why, sizeof why) < 0) fail_msg("viewer: %s", why);
  ocs_view_t view = view_at(45.0, 0.0, 2000, 260, -5); /* scenes/planet.json's camera and sun */
  assert_int_equal(ocs_viewer_set_view(v, &view), 0);
  for (int e = 0; e < epochs; e++) {
    step_ack(w, &v, 1);
    ocs_epoch_out_t o;
    assert_int_equal(ocs_viewer_output(v, &o), 0);
    sums[e] = oc_state_checksum(o.state);
  }
  ocs_world_stats(w, out);
  ocs_world_free(w);
}

static void test_world__ahead_same_states_and_used(void **st) {
  (void)st;
  SKIP_PLANET_RUN_UNDER_ASAN();
  enum { EPOCHS = 40 };
  uint64_t on[EPOCHS], off[EPOCHS];
  ocs_world_stats_t a, b;
  char path[] = "/tmp/oc_ahead_trace_XXXXXX";
  int fd = mkstemp(path);
  assert_true(fd >= 0);
  close(fd);
  assert_int_equal(setenv("OCS_BRICK_TRACE", path, 1), 0);
  planet_run_world(NULL, on, EPOCHS, &a);
  unsetenv("OCS_BRICK_TRACE");
  trace_sums_t t = trace_sums(path);
  remove(path);
  planet_run_world("OCS_AHEAD", off, EPOCHS, &b);
  for (int e = 0; e < EPOCHS; e++)
    if (on[e] != off[e]) fail_msg("epoch %d: the state differs with ahead", e);
  double used = (double)b.sigma_produced - (double)(a.sigma_produced - a.ahead_sigma);
  double used_tau = (double)b.tau_volumes - (double)(a.tau_volumes - a.ahead_tau);
  print_message("σt samplings: %llu without; %llu with, %llu of them ahead (%.0f used at the changes)\n",
                (unsigned long long)b.sigma_produced, (unsigned long long)a.sigma_produced,
                (unsigned long long)a.ahead_sigma, used);
  print_message("τ volumes: %llu without; %llu with, %llu of them ahead (%.0f used at the changes)\n",
                (unsigned long long)b.tau_volumes, (unsigned long long)a.tau_volumes, (unsigned long long)a.ahead_tau,
                used_tau);
  print_message("the stock left, due after the last epoch: %llu σt, %llu τ volumes, %.3f of %.3f s\n",
                (unsigned long long)a.ahead_stock_sigma, (unsigned long long)a.ahead_stock_tau, a.ahead_cpu_stock,
                a.ahead_cpu);
  assert_true(b.ahead_sigma == 0 && b.ahead_tau == 0 && a.ahead_sigma >= 20 && a.ahead_tau >= 10);
  assert_true(used >= 0.5 * (double)a.ahead_sigma && used_tau >= 0.5 * (double)a.ahead_tau);
  /* The stock is what ahead made for changes after the last epoch: a τ volume made ahead is either
   * used at its change or still in the stock (a few may serve leaves merged before it) */
  assert_true(b.ahead_stock_sigma == 0 && b.ahead_stock_tau == 0 && b.ahead_cpu_stock == 0.0);
  assert_true(a.ahead_stock_sigma >= 1 && a.ahead_stock_tau >= 1);
  assert_true(a.ahead_stock_sigma < a.ahead_sigma && used_tau + (double)a.ahead_stock_tau <= (double)a.ahead_tau);
  assert_true(used_tau + (double)a.ahead_stock_tau >= 0.95 * (double)a.ahead_tau - 2.0);
  assert_true(a.ahead_cpu_stock > 0.0 && a.ahead_cpu_stock < a.ahead_cpu);
  /* the trace tells the same stock: its ahead intervals due after its last line's world time */
  print_message("the trace's stock: %.6f s\n", t.stock);
  assert_true(fabs(t.stock - a.ahead_cpu_stock) <= 2e-9 * (double)t.lines + 1e-9);
}

/* Content of a new stamp kept from the one before (world.c): a τ volume whose inputs give the
 * answers they gave at the light stamp before (tau_volume_keep), and a node's σt that its source
 * proves the same as at its step before (sigma_keep). The states are the same bytes with and
 * without each, and the planet's run keeps some of both (36 % of the τ volumes and 4 % of σt over
 * 24 epochs at 64 MiB in docs/performance.md, levers 28 and 29). */
static void test_world__kept_content_same_states(void **st) {
  (void)st;
  SKIP_PLANET_RUN_UNDER_ASAN();
  enum { EPOCHS = 40 };
  uint64_t on[EPOCHS], tau_off[EPOCHS], sigma_off[EPOCHS];
  ocs_world_stats_t a, b, c;
  planet_run_world(NULL, on, EPOCHS, &a);
  planet_run_world("OCS_TAU_KEEP", tau_off, EPOCHS, &b);
  planet_run_world("OCS_SIGMA_KEEP", sigma_off, EPOCHS, &c);
  for (int e = 0; e < EPOCHS; e++) {
    if (on[e] != tau_off[e]) fail_msg("epoch %d: the state differs with kept τ volumes", e);
    if (on[e] != sigma_off[e]) fail_msg("epoch %d: the state differs with kept σt", e);
  }
  print_message("τ volumes: %llu made, %llu of them kept; %llu built without keeping\n", (unsigned long long)a.tau_volumes,
                (unsigned long long)a.tau_kept, (unsigned long long)b.tau_volumes);
  print_message("σt: %llu made, %llu of them kept; %llu sampled without keeping\n", (unsigned long long)a.sigma_produced,
                (unsigned long long)a.sigma_kept, (unsigned long long)c.sigma_produced);
  assert_true(b.tau_kept == 0 && a.tau_kept * 10 >= a.tau_volumes);
  assert_true(c.sigma_kept == 0 && a.sigma_kept * 100 >= a.sigma_produced);
}

/* Four epochs of one viewer over the sphere with OCS_BRICK_TRACE = trace (NULL: none); the world's
 * stats at the end, after it is freed (which closes the trace). */
static ocs_world_stats_t traced_run(const char *trace, int threads) {
  if (trace) assert_int_equal(setenv("OCS_BRICK_TRACE", trace, 1), 0);
  ocs_world_t *w = world_from(SPHERE, threads);
  unsetenv("OCS_BRICK_TRACE");
  assert_non_null(w);
  ocs_viewer_t *v = add_viewer(w, 8u << 20);
  ocs_view_t view = view_at(0.0, 0.0, 6000, 0, -30);
  ocs_viewer_set_view(v, &view);
  for (int e = 0; e < 4; e++) step_ack(w, &v, 1);
  ocs_world_stats_t ws;
  ocs_world_stats(w, &ws);
  ocs_world_free(w);
  return ws;
}

/* OCS_BRICK_TRACE (scripts/waste_perf.sh gives its intervals to perf's samples): the intervals it
 * writes are the ones the wasted-work timers count, wasted or not, to the rounding of the file. */
static void test_world__brick_trace_matches_timers(void **st) {
  (void)st;
  char path[] = "/tmp/oc_brick_trace_XXXXXX";
  int fd = mkstemp(path);
  assert_true(fd >= 0);
  close(fd);
  ocs_world_stats_t ws = traced_run(path, 2);
  trace_sums_t t = trace_sums(path);
  remove(path);
  long lines = t.lines, nwasted = t.wasted;
  double all = t.all, waste = t.waste;
  double timers = ws.brick_cpu + ws.ahead_cpu, timers_waste = ws.brick_cpu_empty + ws.ahead_cpu_empty;
  printf("trace: %ld intervals (%ld wasted), %.6f s (%.6f s wasted); timers %.6f s (%.6f s)\n", lines, nwasted, all,
         waste, timers, timers_waste);
  assert_true(lines > 10 && nwasted > 0 && nwasted < lines);
  assert_true(fabs(all - timers) <= 2e-9 * (double)lines + 1e-9);
  assert_true(fabs(waste - timers_waste) <= 2e-9 * (double)lines + 1e-9);
}

/* A trace that cannot be written is a warning: the world runs, and makes the same bricks. */
static void test_world__brick_trace_unwritable(void **st) {
  (void)st;
  ocs_world_stats_t bad = traced_run("/nonexistent-overcast-dir/trace.txt", 1), none = traced_run(NULL, 1);
  assert_true(bad.bricks_produced > 0 && bad.bricks_produced == none.bricks_produced);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_world__brick_trace_matches_timers),
             cmocka_unit_test(test_world__brick_trace_unwritable),
             cmocka_unit_test(test_world__fair_share),
             cmocka_unit_test(test_world__states_valid_under_budget_and_static_converges),
             cmocka_unit_test(test_world__two_viewers_cost_one_generation),
             cmocka_unit_test(test_world__thread_count_does_not_change_states),
             cmocka_unit_test(test_world__ahead_same_states_and_used),
             cmocka_unit_test(test_world__kept_content_same_states),
             cmocka_unit_test(test_world__unacknowledged_viewer_is_coalesced_and_throttled),
             cmocka_unit_test(test_world__tau_matches_slab),
             cmocka_unit_test(test_world__weather_change_refreshes_every_viewer),
             cmocka_unit_test(test_world__admission_and_bad_input))

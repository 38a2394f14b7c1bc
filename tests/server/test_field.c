/* test_field.c — the field interface on analytic sources: box filtering (a parent's mean against
 * its 8 and 64 descendants'), conservative bounds, static time steps, sums of sources, errors. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "oc_planet.h"
#include "voxelize.h"
#include "ocs_field.h"
#include "report.h"
#include "test_util.h"
#include "server/filter_check.h"

static ocs_field_t *field_from(const char *json) {
  oc_scene_t sc;
  char why[512];
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "test.json", why, sizeof why), 0);
  ocs_field_t *f = NULL;
  int r = ocs_field_create(&f, &sc, why, sizeof why);
  if (r < 0) fail_msg("field: %s", why);
  oc_scene_free(&sc);
  return f;
}

/* The field at t = 0 as a filter_check.h source. */
static void field_sample0(const void *f, oc_key_t key, float out[512]) {
  assert_int_equal(ocs_field_sample(f, key, 0.0, out), 0);
}
static double field_point0(const void *f, oc_dvec3 p) { return ocs_field_point(f, p, 0.0); }

static const char *sphere_json =
    "{\"sources\": [{\"type\": \"sphere\", \"lat\": 10, \"lon\": 20, \"alt\": 3000, \"radius\": 2000, \"sigma_t\": 0.05}],"
    " \"features\": {\"animation\": false}}";

/* Nodes that straddle the sphere's surface at four levels: the box filter's exactness (truth by
 * 96³ quadrature) and the Conventions' test (filter_check.h). */
static void test_field__box_filter_preserves_the_mean(void **st) {
  (void)st;
  ocs_field_t *f = field_from(sphere_json);
  oc_geo_t edge = {10.0, 20.0 + 2000.0 / (OC_PLANET_RADIUS * cos(10.0 * OC_DEG) * OC_DEG), 3000.0};
  oc_dvec3 p = oc_geo_to_xyz(edge);
  filter_src_t src = {f, field_sample0, field_point0};
  filter_worst_t worst = {0};
  for (int level = 12; level <= 15; level++) {
    filter_check_t r = filter_check(&src, oc_key_from_point(level, p), 96);
    printf("level %d: samples' mean %.6e, true mean %.6e (%.1e of peak); node mean %.6e, 8 children %.6e (%.1e), "
           "64 grandchildren %.6e (%.1e)\n", level, r.plain, r.truth, r.exact, r.m0, r.m1, fabs(r.m1 - r.m0) / r.peak, r.m2,
           fabs(r.m2 - r.m0) / r.peak);
    assert_true(r.m0 > 0.0 && r.peak <= 0.05f);
    filter_worst_add(&worst, &r);
  }
  filter_worst_check(&worst, "analytic sphere", "levels 12-15", 2e-3);
  ocs_field_free(f);
}

/* The bound contains every sample, is exactly [σ, σ] deep inside and [0, 0] far away. */
static void test_field__bound_is_conservative(void **st) {
  (void)st;
  ocs_field_t *f = field_from(sphere_json);
  oc_dvec3 c = oc_geo_to_xyz((oc_geo_t){10.0, 20.0, 3000.0});
  unsigned seed = 7;
  int tight = 0;
  for (int n = 0; n < 300; n++) {
    int level = 10 + n % 7;
    seed = seed * 1103515245u + 12345u;
    double dx = ((seed >> 8) % 6000) - 3000.0;
    seed = seed * 1103515245u + 12345u;
    double dy = ((seed >> 8) % 6000) - 3000.0;
    seed = seed * 1103515245u + 12345u;
    double dz = ((seed >> 8) % 6000) - 3000.0;
    oc_key_t k = oc_key_from_point(level, oc_dadd(c, oc_dv3(dx, dy, dz)));
    float lo, hi, s[512];
    ocs_field_bound(f, k, 0.0, &lo, &hi);
    assert_int_equal(ocs_field_sample(f, k, 0.0, s), 0);
    for (int i = 0; i < 512; i++) {
      assert_true(s[i] >= lo * (1.0f - 1e-6f) - 1e-12f);
      assert_true(s[i] <= hi * (1.0f + 1e-6f) + 1e-12f);
    }
    if (lo == hi) tight++;
  }
  printf("bound classified %d of 300 nodes (empty or uniform) without sampling\n", tight);
  assert_true(tight > 30);
  float lo, hi;
  ocs_field_bound(f, oc_key_from_point(16, c), 0.0, &lo, &hi);
  assert_true(lo == 0.05f && hi == 0.05f);
  ocs_field_bound(f, oc_key_from_point(12, oc_geo_to_xyz((oc_geo_t){-40.0, 100.0, 3000.0})), 0.0, &lo, &hi);
  assert_true(lo == 0.0f && hi == 0.0f);
  ocs_field_free(f);
}

/* Sources add; static scenes have one time step; a slab's interior is uniform. */
static void test_field__sources_add_and_static_steps(void **st) {
  (void)st;
  ocs_field_t *f = field_from(
      "{\"sources\": [{\"type\": \"slab\", \"base\": 1000, \"top\": 5000, \"sigma_t\": 0.001},"
      " {\"type\": \"box\", \"lat\": 0, \"lon\": 0, \"alt\": 2000, \"size\": [1000, 1000, 1000], \"heading\": 30,"
      "  \"sigma_t\": 0.01}], \"features\": {\"animation\": false}}");
  assert_false(ocs_field_animated(f));
  assert_true(ocs_field_time_step(f, 5, 0.0) == ocs_field_time_step(f, 5, 1e6));
  oc_dvec3 inside = oc_geo_to_xyz((oc_geo_t){0.0, 0.0, 2500.0});
  assert_true(fabs(ocs_field_point(f, inside, 0.0) - 0.011) < 1e-12);
  float lo, hi, s[512];
  oc_key_t k = oc_key_from_point(18, inside); /* 49 m node inside both */
  ocs_field_bound(f, k, 0.0, &lo, &hi);
  assert_true(fabsf(lo - 0.011f) < 1e-7f && fabsf(hi - 0.011f) < 1e-7f);
  assert_int_equal(ocs_field_sample(f, k, 0.0, s), 0);
  for (int i = 0; i < 512; i++) assert_true(fabsf(s[i] - 0.011f) < 1e-7f);
  ocs_field_stats_t fs;
  ocs_field_stats(f, &fs);
  assert_true(fs.sampled_bricks == 1 && fs.bound_calls == 1);
  assert_int_equal(ocs_field_set_weather(f, OC_PRESET_STORM, 0.0, 10.0), OC_EINVAL); /* no procedural source */
  assert_int_equal(ocs_field_sample(f, 0, 0.0, s), OC_EINVAL);
  ocs_field_free(f);
}

/* The scene decides animation: a procedural planet with animation off never changes with time. */
static void test_field__static_procedural_is_frozen(void **st) {
  (void)st;
  ocs_field_t *f = field_from("{\"sources\": [{\"type\": \"procedural\", \"preset\": \"overcast\"}],"
                              " \"features\": {\"animation\": false}}");
  assert_false(ocs_field_animated(f));
  assert_true(ocs_field_time_step(f, 14, 0.0) == ocs_field_time_step(f, 14, 3600.0));
  oc_key_t k = oc_key_from_point(12, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 800.0}));
  float a[512], b[512];
  assert_int_equal(ocs_field_sample(f, k, 0.0, a), 0);
  assert_int_equal(ocs_field_sample(f, k, 3600.0, b), 0);
  assert_memory_equal(a, b, sizeof a);
  ocs_field_free(f);
  f = field_from("{\"sources\": [{\"type\": \"procedural\", \"preset\": \"overcast\"}], \"features\": {\"animation\": true}}");
  assert_true(ocs_field_animated(f));
  assert_true(ocs_field_time_step(f, 14, 0.0) != ocs_field_time_step(f, 14, 3600.0));
  ocs_field_free(f);
}

/* ocs_field_step_before() and ocs_field_same_samples() over several sources (lever 29): a static
 * field offers no step before and its samples are the same at any two instants; the planet with a
 * static sphere added is proven the same where the planet's proof holds (the sphere's step does
 * not move), and the samples are then the same bits; a weather change between the two instants
 * is never proven. Tall level-10 nodes at 3 km (where the world keeps most) over 30 s. */
static void test_field__same_samples_over_sources(void **st) {
  (void)st;
  ocs_field_t *f = field_from(sphere_json);
  oc_key_t k = oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){10.0, 20.0, 3000.0}));
  double t0 = -1.0;
  float a[512], b[512];
  assert_int_equal(ocs_field_step_before(f, k, 100.0, &t0), 0);
  assert_int_equal(ocs_field_same_samples(f, k, 0.0, 1e6), 1);
  /* what is not a node, or no field, is never proven and offers no step */
  assert_int_equal(ocs_field_same_samples(f, OC_KEY_INVALID, 0.0, 1e6), 0);
  assert_int_equal(ocs_field_same_samples(NULL, k, 0.0, 1e6), 0);
  assert_int_equal(ocs_field_step_before(f, OC_KEY_INVALID, 100.0, &t0), 0);
  assert_int_equal(ocs_field_step_before(f, k, 100.0, NULL), 0);
  ocs_field_free(f);
  f = field_from("{\"sources\": [{\"type\": \"procedural\", \"preset\": \"fair\"},"
                 " {\"type\": \"sphere\", \"lat\": 10, \"lon\": 20, \"alt\": 3000, \"radius\": 2000, \"sigma_t\": 0.05}]}");
  int proven = 0, tried = 0;
  oc_key_t kept = 0;
  double kt0 = 0.0, kt1 = 0.0;
  for (int i = 0; i < 400 && proven < 3; i++) {
    oc_key_t n = oc_key_from_point(10, oc_geo_to_xyz((oc_geo_t){-60.0 + 0.3 * i, 20.0 + 0.7 * i, 3000.0}));
    double t1 = 0.5 + 0.37 * (i % 80);
    if (!ocs_field_step_before(f, n, t1, &t0)) continue;
    assert_true(t0 < t1 && ocs_field_node_step(f, n, t0) != ocs_field_node_step(f, n, t1));
    tried++;
    if (!ocs_field_same_samples(f, n, t0, t1)) continue;
    assert_int_equal(ocs_field_sample(f, n, t0, a), 0);
    assert_int_equal(ocs_field_sample(f, n, t1, b), 0);
    assert_memory_equal(a, b, sizeof a);
    proven++, kept = n, kt0 = t0, kt1 = t1;
  }
  printf("  %d node-step changes tried, %d proven the same\n", tried, proven);
  assert_true(proven >= 1 && tried > proven);
  assert_int_equal(ocs_field_set_weather(f, OC_PRESET_STORM, 0.5 * (kt0 + kt1), 1.0), 0);
  assert_int_equal(ocs_field_same_samples(f, kept, kt0, kt1 + 2.0), 0);
  ocs_field_free(f);
}

/* The bound cache (ocs_field.h) returns the bits the source computes: two fields of one procedural
 * planet, one with the cache bypassed, asked about random nodes (levels 0–21, 0–16 km shell) at
 * random times and at the two sides of a time-step boundary of the node's level (found by
 * bisection), each twice (a miss, then a hit), before and across weather changes (a transition to
 * storm, then a switch back to fair while cached entries from the storm are still in the table). */
static uint64_t cache_rng = 0x2545f4914f6cdd1dull;
static double cache_u(void) {
  cache_rng ^= cache_rng << 13;
  cache_rng ^= cache_rng >> 7;
  cache_rng ^= cache_rng << 17;
  return (double)(cache_rng >> 11) * 0x1.0p-53;
}

static void same_bound(ocs_field_t *c, ocs_field_t *u, oc_key_t k, double t) {
  float a0, b0, a1, b1, a2, b2;
  ocs_field_bound(u, k, t, &a0, &b0);
  ocs_field_bound(c, k, t, &a1, &b1);
  ocs_field_bound(c, k, t, &a2, &b2);
  if (memcmp(&a0, &a1, sizeof a0) || memcmp(&b0, &b1, sizeof b0) || memcmp(&a0, &a2, sizeof a0) ||
      memcmp(&b0, &b2, sizeof b0))
    fail_msg("key %llx level %d t %.17g: uncached [%a, %a], cached [%a, %a] then [%a, %a]", (unsigned long long)k,
             oc_key_level(k), t, a0, b0, a1, b1, a2, b2);
}

/* The bricks too: the procedural sampler takes its node's ranges from the source's node-bound
 * cache (OCS_PROC_NODE_CACHE=0 at creation: none), filled by the bound just asked, or by a sample. */
static void same_brick(ocs_field_t *c, ocs_field_t *u, oc_key_t k, double t) {
  float a[OC_BRICK_VOXELS], b[OC_BRICK_VOXELS];
  assert_int_equal(ocs_field_sample(u, k, t, a), 0);
  assert_int_equal(ocs_field_sample(c, k, t, b), 0);
  if (memcmp(a, b, sizeof a))
    fail_msg("key %llx level %d t %.17g: the brick differs with the node-bound cache", (unsigned long long)k,
             oc_key_level(k), t);
}

static void test_field__bound_cache_is_exact(void **st) {
  (void)st;
  const char *json = "{\"sources\": [{\"type\": \"procedural\", \"preset\": \"fair\"}], \"features\": {\"animation\": true}}";
  ocs_field_t *c = field_from(json);
  setenv("OCS_PROC_NODE_CACHE", "0", 1);
  ocs_field_t *u = field_from(json);
  unsetenv("OCS_PROC_NODE_CACHE");
  ocs_field_set_bound_cache(u, 0);
  enum { NODES = 160 };
  oc_key_t keys[NODES];
  double times[NODES][4];
  int nonzero = 0;
  for (int i = 0; i < NODES; i++) {
    int level = i % (OC_KEY_MAX_LEVEL + 1);
    oc_geo_t g = {-70.0 + 140.0 * cache_u(), -180.0 + 360.0 * cache_u(), 16000.0 * cache_u()};
    keys[i] = oc_key_from_point(level, oc_geo_to_xyz(g));
    double ta = 4000.0 * cache_u(), tb = ta;
    uint64_t sa = ocs_field_time_step(c, level, ta);
    double span = 1.0;
    while (ocs_field_time_step(c, level, tb) == sa && span < 1e7) tb = ta + (span *= 2.0);
    for (int it = 0; it < 80 && tb - ta > 1e-9 * (1.0 + ta); it++) { /* the boundary within [ta, tb] */
      double m = 0.5 * (ta + tb);
      if (ocs_field_time_step(c, level, m) == sa) ta = m; else tb = m;
    }
    times[i][0] = ta;
    times[i][1] = tb;
    times[i][2] = 4000.0 * cache_u();
    times[i][3] = times[i][2] + 1e-3;
  }
  for (int phase = 0; phase < 3; phase++) {
    if (phase == 1) { /* to storm over [1000, 1600] s: entries at t ≥ 1000 from phase 0 are stale */
      assert_int_equal(ocs_field_set_weather(c, OC_PRESET_STORM, 1000.0, 600.0), 0);
      assert_int_equal(ocs_field_set_weather(u, OC_PRESET_STORM, 1000.0, 600.0), 0);
    } else if (phase == 2) { /* and back to fair at 1200 s, a switch */
      assert_int_equal(ocs_field_set_weather(c, OC_PRESET_FAIR, 1200.0, 0.0), 0);
      assert_int_equal(ocs_field_set_weather(u, OC_PRESET_FAIR, 1200.0, 0.0), 0);
    }
    for (int i = 0; i < NODES; i++)
      for (int j = 0; j < 4; j++) {
        if (j == 2 && i % 4 == 0) same_brick(c, u, keys[i], times[i][j]); /* before its bound: the sample fills */
        same_bound(c, u, keys[i], times[i][j]);
        if (i % 4 == 1 && oc_key_level(keys[i]) >= 4) same_brick(c, u, keys[i], times[i][j]); /* after: it hits */
        float lo, hi;
        ocs_field_bound(u, keys[i], times[i][j], &lo, &hi);
        nonzero += hi > 0.0f;
      }
    for (double t = 990.0; t < 1700.0; t += 37.5) /* through the transition's steps */
      for (int i = 0; i < NODES; i += 7) {
        same_bound(c, u, keys[i], t);
        if (i % 3 == 0) same_brick(c, u, keys[i], t);
      }
  }
  ocs_field_stats_t sc, su;
  ocs_field_stats(c, &sc);
  ocs_field_stats(u, &su);
  assert_true(nonzero > NODES / 4); /* the nodes are not all trivially empty */
  assert_true(sc.bound_hits >= sc.bound_misses); /* every bound asked twice in a row */
  assert_true(su.bound_hits == 0 && su.bound_misses == 0);
  ocs_field_free(c);
  ocs_field_free(u);
}

static void test_field__bad_source_names_it(void **st) {
  (void)st;
  oc_scene_t sc;
  char why[512];
  const char *json = "{\"sources\": [{\"type\": \"vdb\", \"file\": \"/nonexistent/cloud.vdb\", \"lat\": 0, \"lon\": 0, \"alt\": 0}]}";
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "t.json", why, sizeof why), 0);
  ocs_field_t *f = (ocs_field_t *)1;
  assert_true(ocs_field_create(&f, &sc, why, sizeof why) < 0);
  assert_null(f);
  printf("error: %s\n", why);
  assert_non_null(strstr(why, "sources[0]"));
  assert_non_null(strstr(why, "/nonexistent/cloud.vdb"));
  oc_scene_free(&sc);
}

/* Slabs are box-filtered exactly: against the covered fraction along the face normal (a node at
 * 0°N 0°E, where the normal is +X) and against dense sampling on an oblique node. */
static double slab_exact_point(void *ctx, oc_dvec3 p) {
  const double *r = ctx;
  double d = oc_dlen(p);
  return d >= r[0] && d <= r[1] ? 1.0 : 0.0;
}

static void test_field__slab_filter_is_exact(void **st) {
  (void)st;
  ocs_field_t *f = field_from("{\"version\":1,\"sources\":[{\"type\":\"slab\",\"base\":2000,\"top\":3000,\"sigma_t\":1}]}");
  const double rr[2] = {OC_PLANET_RADIUS + 2000.0, OC_PLANET_RADIUS + 3000.0};
  double worst_axis = 0.0, worst_oblique = 0.0;
  for (int lvl = 13; lvl <= 17; lvl += 2) {
    /* on the axis: the fraction of the voxel below each face, in one dimension */
    oc_key_t k = oc_key_from_point(lvl, oc_geo_to_xyz((oc_geo_t){0.0, 0.0, 2000.0}));
    float s[512];
    assert_int_equal(ocs_field_sample(f, k, 0.0, s), 0);
    double v = oc_key_size(lvl) / 7.0;
    for (int i = 0; i < 512; i++) {
      oc_dvec3 p = ocs_brick_sample_pos(k, i & 7, (i >> 3) & 7, i >> 6);
      double r = oc_dlen(p), lo = fmin(1.0, fmax(0.0, (rr[1] - r) / v + 0.5)), hi = fmin(1.0, fmax(0.0, (rr[0] - r) / v + 0.5));
      worst_axis = fmax(worst_axis, fabs(s[i] - (lo - hi)));
    }
    /* oblique: dense stratified sampling (16³ points, the most ocs_brick_sample takes) near the base */
    k = oc_key_from_point(lvl, oc_geo_to_xyz((oc_geo_t){37.0, 23.0, 2000.0}));
    assert_int_equal(ocs_field_sample(f, k, 0.0, s), 0);
    float dense[512];
    ocs_brick_sample(k, slab_exact_point, (void *)rr, 16, dense);
    for (int i = 0; i < 512; i++) worst_oblique = fmax(worst_oblique, fabs(s[i] - dense[i]));
  }
  oc_report("field", "exact slab filter vs 1-D covered fraction on the axis", worst_axis, 1e-3, "σt");
  oc_report("field", "exact slab filter vs 16³-point box average, oblique", worst_oblique, 5e-3, "σt");
  assert_true(worst_axis < 1e-3);
  assert_true(worst_oblique < 5e-3);
  ocs_field_free(f);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_field__box_filter_preserves_the_mean),
             cmocka_unit_test(test_field__bound_is_conservative),
             cmocka_unit_test(test_field__sources_add_and_static_steps),
             cmocka_unit_test(test_field__static_procedural_is_frozen),
             cmocka_unit_test(test_field__same_samples_over_sources),
             cmocka_unit_test(test_field__bound_cache_is_exact),
             cmocka_unit_test(test_field__bad_source_names_it),
             cmocka_unit_test(test_field__slab_filter_is_exact))

/* test_sun_depth.c — the τ channel (server/sun_depth.h): the direct march and the group volume
 * against the analytic optical depth of a homogeneous slab (below it at three sun angles, inside
 * it, sun at the zenith along a grid axis, sun below the horizon, at the root cube's edge, huge
 * σt), the volume against the direct march on the procedural planet, τ = 0 above the clouds,
 * thread-count independence, the clear-sky shortcut against the full march, and argument errors. */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "test_main.h"
#include "analytic.h"
#include "brick_cache.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "voxelize.h"
#include "ocs_field.h"
#include "report.h"
#include "sun_depth.h"
#include "test_util.h" /* SIZE */

/* FULL and SIZE (test_util.h): optimised builds run the full workload; unoptimised or sanitised
 * ones (the CI's ASan+UBSan stage is a Debug build) the same code paths on fewer nodes. */

/*-*** A field behind the callbacks, memoised in the server's shared brick cache ***/

typedef struct {
  ocs_field_t *f;
  double t;
  ocs_cache_t *memo;                         /* σt bricks and bounds of the field at t, keyed {kind, node} */
  _Atomic long sigma_fetches, bound_fetches; /* bricks and bounds produced (each at most once) */
  int fail_sigma;                            /* make sigma() fail with OC_EIO */
} tcache_t;

enum { TC_SIGMA = 1, TC_BOUND = 2 };

/* Copies the memo of (kind, key), `bytes` of it, to out; on a miss produces it from the field
 * first (single flight: threads asking at once wait for the one producing). */
static int tc_memo(tcache_t *c, int kind, oc_key_t key, void *out, size_t bytes) {
  ocs_cache_key_t k = {{(uint64_t)kind, key, 0, 0}};
  ocs_cache_entry_t *e;
  int r = ocs_cache_acquire(c->memo, &k, &e);
  if (r < 0) return r;
  if (r == OCS_CACHE_HIT) {
    memcpy(out, ocs_cache_data(e), bytes);
    ocs_cache_release(c->memo, e);
    return 0;
  }
  if (kind == TC_SIGMA) {
    r = ocs_field_sample(c->f, key, c->t, out);
    if (r >= 0) oc_sanitize(out, 512, NULL);
  } else {
    float *lohi = out;
    ocs_field_bound(c->f, key, c->t, &lohi[0], &lohi[1]);
  }
  void *copy = r < 0 ? NULL : malloc(bytes);
  if (!copy) {
    ocs_cache_abandon(c->memo, e);
    return r < 0 ? r : OC_ENOMEM;
  }
  memcpy(copy, out, bytes);
  ocs_cache_publish(c->memo, e, copy, bytes);
  ocs_cache_release(c->memo, e);
  if (kind == TC_SIGMA) c->sigma_fetches++;
  else c->bound_fetches++;
  return 0;
}

static int tc_sigma(void *ctx, oc_key_t key, float out[512]) {
  tcache_t *c = ctx;
  return c->fail_sigma ? OC_EIO : tc_memo(c, TC_SIGMA, key, out, sizeof(float) * 512);
}

static void tc_bound(void *ctx, oc_key_t key, float *lo, float *hi) {
  float lohi[2];
  assert_int_equal(tc_memo(ctx, TC_BOUND, key, lohi, sizeof lohi), 0);
  *lo = lohi[0], *hi = lohi[1];
}

static void tc_init(tcache_t *c, const char *json, double t) {
  memset(c, 0, sizeof *c);
  oc_scene_t sc;
  char why[512];
  if (json) {
    assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "test.json", why, sizeof why), 0);
  } else {
    oc_scene_default(&sc);
  }
  if (ocs_field_create(&c->f, &sc, why, sizeof why) < 0) fail_msg("field: %s", why);
  oc_scene_free(&sc);
  c->t = t;
  assert_int_equal(ocs_cache_create(&c->memo, UINT64_MAX), 0); /* no cap: nothing is produced twice */
}

static void tc_free(tcache_t *c) {
  ocs_cache_free(c->memo);
  ocs_field_free(c->f);
}

static ocs_tau_desc_t desc_for(tcache_t *c, oc_dvec3 sun) {
  ocs_tau_desc_t d = {0};
  d.sigma = tc_sigma;
  d.bound = tc_bound;
  d.ctx = c;
  d.sun_dir = sun;
  return d;
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

/*-*** Analytic truth ***/

static void medium_from(const char *json, ocs_medium_t *m) {
  oc_scene_t sc;
  char why[512];
  assert_int_equal(oc_scene_parse(&sc, json, strlen(json), "test.json", why, sizeof why), 0);
  assert_int_equal(ocs_scene_medium(&sc, m, why, sizeof why), 0);
  oc_scene_free(&sc);
}


/* The sun at zenith angle z (degrees) toward the east of point p. */
static oc_dvec3 sun_at(oc_dvec3 p, double zenith_deg) {
  oc_enu_t f = oc_enu_at(p);
  return oc_dnorm(oc_dadd(oc_dscale(f.up, cos(zenith_deg * OC_DEG)), oc_dscale(f.east, sin(zenith_deg * OC_DEG))));
}

/* Distance along the ray p + t·d (d unit) to where it enters the sphere |x| = r, or INFINITY. */
static double enter_sphere(oc_dvec3 p, oc_dvec3 d, double r) {
  double b = oc_ddot(p, d);
  double q = oc_dlen(oc_dmad(p, d, -b));
  if (!(q < r) || oc_dlen(p) < r) return INFINITY;
  double t = -b - sqrt((r - q) * (r + q));
  return t >= 0.0 ? t : INFINITY;
}

/* The analytic τ with the march's cut: up to where the ray enters R − 10 km. */
static double tau_truth(const ocs_medium_t *m, oc_dvec3 p, oc_dvec3 sun) {
  double t = enter_sphere(p, sun, OCS_TAU_PLANET_STOP);
  return isfinite(t) ? ocs_medium_optical_depth(m, p, sun, t) : ocs_medium_tau_sun(m, p, sun);
}

static double altitude(oc_dvec3 p) { return oc_dlen(p) - OC_PLANET_RADIUS; }

/* A slab, the node marched, and how to judge it (docs/numerics.md, "Sun optical depth τ").
 *
 * Tolerance: τ integrates σt box-filtered at the march level and reconstructed trilinearly. For a
 * homogeneous slab that keeps the line integral only on average over positions: a ray crossing a
 * face at an angle to the grid picks up an error of up to about κ·σt·v/μ, v the voxel of the level
 * sampled there (the march level's, or coarser where the cone has grown the step), μ the cosine
 * between the ray and the face's normal; its sign depends on where the ray meets the lattice. We
 * measured κ ≤ 0.111 over levels 13–18 and sun angles 0–80°, 0.150 grazing (the quadrature is
 * exact, so this is the reconstruction itself), and assert κ ≤ 0.125 (0.17 grazing) at every
 * sample farther than the
 * filter footprint from both faces (closer, the filtered slab itself differs from the true one).
 * Averaged over a node's samples the sign varies, so the MEAN relative error must stay within 1 %:
 * that is the check of the weights, steps, cone and cuts; the per-sample bound checks the filter. */
typedef struct {
  double kappa;    /* worst |Δτ| / (σt Σ v/μ) */
  double rel_max;  /* worst |Δτ| / τ */
  double rel_mean; /* |mean of Δτ / τ| */
  int n;
} slab_err_t;

static double sigma_of(const char *json) { /* the slab's σt, parsed back from the JSON */
  ocs_medium_t m;
  medium_from(json, &m);
  return m.prims[0].sigma_t;
}

/* The voxel of the level a march samples at distance t (cone distance t + extra), an upper bound. */
static double voxel_at(int node_level, double t) {
  double vm = oc_key_size(node_level - 1) / 7.0, v = vm, want = OCS_TAU_DEFAULT_CONE * t;
  int l = node_level - 1;
  while (v < want && l > OCS_TAU_DEFAULT_MIN_LEVEL) v *= 2.0, l--;
  return v;
}

static void slab_judge(const ocs_medium_t *m, const float *tau, oc_key_t key, oc_dvec3 sun, slab_err_t *e) {
  const ocs_prim_t *pr = &m->prims[0];
  int level = oc_key_level(key);
  double fp = 1.5 * sqrt(3.0) * oc_key_size(level - 1) / 7.0; /* box (½ voxel) + trilinear (1 voxel), diagonal */
  double extra = 0.5 * sqrt(3.0) * oc_key_size(level - OCS_TAU_DEFAULT_GROUP_LEVELS); /* the volume's cone offset */
  double base = pr->slab.r_in - OC_PLANET_RADIUS, top = pr->slab.r_out - OC_PLANET_RADIUS, sum = 0.0;
  for (int v = 0; v < 512; v++) {
    oc_dvec3 p = ocs_brick_sample_pos(key, v & 7, (v >> 3) & 7, v >> 6);
    double h = altitude(p);
    if (fabs(h - base) < fp || fabs(h - top) < fp) continue;
    double truth = tau_truth(m, p, sun), cut = enter_sphere(p, sun, OCS_TAU_PLANET_STOP);
    /* faces the ray crosses before the cut: each sphere's entries and exits at t > 0 */
    double scale = 0.0;
    const double radii[2] = {pr->slab.r_in, pr->slab.r_out};
    for (int f = 0; f < 2; f++) {
      double b = oc_ddot(p, sun), q = oc_dlen(oc_dmad(p, sun, -b)), r = radii[f];
      if (!(q < r)) continue;
      double hh = sqrt((r - q) * (r + q));
      for (int sg = -1; sg <= 1; sg += 2) {
        double t = -b + sg * hh;
        if (!(t > 0.0 && t < cut)) continue;
        oc_dvec3 x = oc_dmad(p, sun, t);
        double mu = fabs(oc_ddot(x, sun)) / oc_dlen(x);
        scale += pr->sigma_t * voxel_at(level, t + extra) / fmax(mu, 1e-3);
      }
    }
    assert_true(isfinite(tau[v]));
    double err = tau[v] - truth;
    if (scale > 0.0) e->kappa = fmax(e->kappa, fabs(err) / scale);
    else assert_true(fabs(err) <= 1e-6 + 1e-6 * truth); /* no face crossed: σt·chord exactly */
    if (truth > 0.0) {
      e->rel_max = fmax(e->rel_max, fabs(err) / truth);
      sum += err / truth;
    }
    e->n++;
  }
  if (e->n) e->rel_mean = fmax(e->rel_mean, fabs(sum / e->n));
}

static const char *slab_json =
    "{\"version\": 1, \"features\": {\"shadows\": true, \"animation\": false},"
    " \"sources\": [{\"type\": \"slab\", \"base\": 2000, \"top\": 3000, \"sigma_t\": 0.01}]}";

/* Higher: 80–93 km, under the root cube's +X face. */
static const char *slab_high_json = "{\"version\": 1, \"features\": {\"animation\": false},"
                                    " \"sources\": [{\"type\": \"slab\", \"base\": 80000, \"top\": 93000, \"sigma_t\": 0.001}]}";

/* Dense: σt = 1000 m⁻¹ at 2–3 km. */
static const char *slab_dense_json = "{\"version\": 1, \"features\": {\"animation\": false},"
                                     " \"sources\": [{\"type\": \"slab\", \"base\": 2000, \"top\": 3000, \"sigma_t\": 1000}]}";

/* One slab test: the field cache at t = 0 and the analytic medium of its scene, and the worst
 * errors of the direct and the volume τ over its cases. */
typedef struct {
  tcache_t c;
  ocs_medium_t m;
  slab_err_t ed, ev;
} slab_t;

/* cmocka setup: the slab_t of the scene given as the test's initial state (slab_json when none). */
static int slab_setup(void **state) {
  const char *json = *state ? *state : slab_json;
  slab_t *s = calloc(1, sizeof *s);
  if (!s) return -1;
  tc_init(&s->c, json, 0.0);
  medium_from(json, &s->m);
  *state = s;
  return 0;
}

static int slab_teardown(void **state) {
  slab_t *s = *state;
  tc_free(&s->c);
  free(s);
  return 0;
}

#define SLAB_TEST(f, json) cmocka_unit_test_prestate_setup_teardown(f, slab_setup, slab_teardown, (void *)(json))

/* Direct and volume τ of one node against the slab's analytic τ. The volume covers every
 * descendant (cover_all), so nodes without σt are judged too. check_mean: also the node's mean
 * relative error (not for grazing rays from inside the slab, where a single face crossing at
 * μ ≈ 0.05 is the whole error and the same for every sample). */
static void slab_case_cb(slab_t *s, oc_key_t key, oc_dvec3 sun, const char *what, int check_mean,
                         int (*sigma)(void *, oc_key_t, float *), double kmax) {
  ocs_tau_desc_t d = desc_for(&s->c, sun), dv;
  if (sigma) d.sigma = sigma;
  dv = d;
  dv.cover_all = 1;
  float td[512], tv[512];
  assert_int_equal(ocs_tau_direct(&d, key, td), 0);
  assert_int_equal(ocs_tau_node(&dv, key, tv), 0);
  slab_err_t a = {0}, b = {0};
  slab_judge(&s->m, td, key, sun, &a);
  slab_judge(&s->m, tv, key, sun, &b);
  printf("%s: %d samples judged; direct κ %.3f, worst %.2e, mean %.1e relative; volume κ %.3f, worst %.2e, mean %.1e\n",
         what, a.n, a.kappa, a.rel_max, a.rel_mean, b.kappa, b.rel_max, b.rel_mean);
  assert_true(a.kappa <= kmax && b.kappa <= kmax);
  if (!check_mean) a.rel_mean = b.rel_mean = 0.0;
  assert_true(a.rel_mean <= 0.01 && b.rel_mean <= 0.01);
  slab_err_t *ed = &s->ed, *ev = &s->ev;
  ed->kappa = fmax(ed->kappa, a.kappa), ed->rel_max = fmax(ed->rel_max, a.rel_max);
  ed->rel_mean = fmax(ed->rel_mean, a.rel_mean), ed->n += a.n;
  ev->kappa = fmax(ev->kappa, b.kappa), ev->rel_max = fmax(ev->rel_max, b.rel_max);
  ev->rel_mean = fmax(ev->rel_mean, b.rel_mean), ev->n += b.n;
}

/* κ bounds: the worst measured is 0.111 for non-grazing rays and 0.150 at 89° (docs/numerics.md). */
#define KAPPA_MAX 0.125
#define KAPPA_GRAZING 0.17

static void slab_case(slab_t *s, oc_key_t key, oc_dvec3 sun, const char *what) {
  slab_case_cb(s, key, sun, what, 1, NULL, KAPPA_MAX);
}

/* Reports the worst errors over the test's cases under `name`. */
static void slab_report(const slab_t *s, const char *name) {
  const slab_err_t *ed = &s->ed, *ev = &s->ev;
  char row[256];
  snprintf(row, sizeof row, "%s: direct, worst κ (error per σt·v/μ per face)", name);
  oc_report("tau", row, ed->kappa, KAPPA_GRAZING, "");
  snprintf(row, sizeof row, "%s: volume, worst κ", name);
  oc_report("tau", row, ev->kappa, KAPPA_GRAZING, "");
  snprintf(row, sizeof row, "%s: direct, mean relative error of a node", name);
  oc_report("tau", row, ed->rel_mean, 0.01, "rel");
  snprintf(row, sizeof row, "%s: volume, mean relative error of a node", name);
  oc_report("tau", row, ev->rel_mean, 0.01, "rel");
  printf("%s: worst relative error of a sample: direct %.2e, volume %.2e\n", name, ed->rel_max, ev->rel_max);
}

/*-*** Tests ***/

/* Below the slab: a level-14 node (790 m) at about 0.3–1.3 km, the slab at 2–3 km lying in other
 * nodes, with the sun 0°, 60° and 80° from the zenith at the node. */
static void test_sun_depth__slab_below_three_sun_angles(void **st) {
  slab_t *s = *st;
  oc_key_t below = oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 700.0}));
  float lo, hi;
  tc_bound(&s->c, below, &lo, &hi);
  assert_true(hi == 0.0f); /* the slab is not in the node */
  const double zen[3] = {0.0, 60.0, 80.0};
  for (int z = 0; z < 3; z++) {
    char what[64];
    snprintf(what, sizeof what, "below the slab, sun %.0f° from the zenith", zen[z]);
    int n0 = s->ed.n;
    slab_case(s, below, sun_at(oc_key_center(below), zen[z]), what);
    assert_true(s->ed.n - n0 >= 500);
  }
  slab_report(s, "slab 2-3 km, node below at level 14, sun 0/60/80°");
}

/* Inside the slab: a level-15 node (395 m) at 2.3–2.7 km; only the top face is crossed. */
static void test_sun_depth__slab_inside(void **st) {
  slab_t *s = *st;
  oc_key_t inside = oc_key_from_point(15, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2500.0}));
  slab_case(s, inside, sun_at(oc_key_center(inside), 60.0), "inside the slab, sun 60°");
  slab_case(s, inside, sun_at(oc_key_center(inside), 0.0), "inside the slab, sun 0°");
  assert_true(s->ed.n >= 300);
  slab_report(s, "slab 2-3 km, node inside at level 15, sun 0/60°");
}

/* The slab's exact box filter for nodes near the north pole: over each sample's cube, 16 × 16
 * (x, y) columns, each with its exact z-extent inside the shell. The field's own box filter
 * estimates the average from sub-samples, whose layers all agree when a face is parallel to them
 * (here the faces are ⊥ z): up to 1/16 of σt·v per face, the same sign at every sample, which
 * would hide what is tested here. Sampling is exact in z, so nearly exact for these faces. */
static double shell_len(double x, double y, double z0, double z1, double ri, double ro) {
  double q = x * x + y * y, a2 = ri * ri - q, b2 = ro * ro - q, len = 0.0;
  if (b2 <= 0.0) return 0.0;
  double b = sqrt(b2), a = a2 > 0.0 ? sqrt(a2) : 0.0;
  const double iv[2][2] = {{a, b}, {-b, -a}}; /* inside: a ≤ |z| ≤ b */
  for (int k = 0; k < 2; k++) {
    double lo = fmax(z0, iv[k][0]), hi = fmin(z1, iv[k][1]);
    if (hi > lo) len += hi - lo;
  }
  return len;
}

static int exact_slab_sigma(void *ctx, oc_key_t key, float out[512]) {
  (void)ctx;
  const double ri = OC_PLANET_RADIUS + 2000.0, ro = OC_PLANET_RADIUS + 3000.0, sg = 0.01;
  double h = oc_key_size(oc_key_level(key)) / 7.0;
  enum { N = 16 };
  for (int v = 0; v < 512; v++) {
    oc_dvec3 p = ocs_brick_sample_pos(key, v & 7, (v >> 3) & 7, v >> 6);
    double sum = 0.0;
    for (int a = 0; a < N; a++)
      for (int b = 0; b < N; b++)
        sum += shell_len(p.x + ((a + 0.5) / N - 0.5) * h, p.y + ((b + 0.5) / N - 0.5) * h, p.z - h / 2, p.z + h / 2, ri, ro);
    out[v] = (float)(sg * sum / ((double)N * N * h));
  }
  return 0;
}

/* The sun exactly at the zenith of the north pole: the ray runs along +Z, parallel to two axes of
 * every node (no division by a zero component, columns parallel to the lattice). The bound still
 * comes from the field (exact for slabs); the samples from the exact box filter above. */
static void test_sun_depth__zenith_along_an_axis(void **st) {
  slab_t *s = *st;
  oc_key_t pole = oc_key_from_point(14, oc_dv3(100.0, 100.0, OC_PLANET_RADIUS + 700.0));
  slab_case_cb(s, pole, oc_dv3(0.0, 0.0, 1.0), "north pole, sun along +Z", 1, exact_slab_sigma, 1e-6);
  assert_true(s->ed.rel_max <= 1e-6 && s->ev.rel_max <= 1e-6); /* along a lattice axis: exact to rounding */
  assert_true(s->ed.n >= 500);
  slab_report(s, "slab, node at the north pole, sun exactly along +Z");
}

/* The sun 5° and 30° below the horizon at a node inside the slab: the ray leaves the slab
 * downward and is cut where it enters R − 10 km. Finite, matches the cut analytic τ, and fast. */
static void test_sun_depth__sun_below_horizon(void **st) {
  slab_t *s = *st;
  oc_key_t inside = oc_key_from_point(15, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2500.0}));
  double t0 = now();
  slab_case(s, inside, sun_at(oc_key_center(inside), 95.0), "inside the slab, sun 5° below the horizon");
  slab_case(s, inside, sun_at(oc_key_center(inside), 120.0), "inside the slab, sun 30° below the horizon");
  double t1 = now() - t0;
  printf("both: %.3f s\n", t1);
  /* a node below the slab sees nothing when the sun is below the horizon: the ray never reaches it */
  oc_key_t below = oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 700.0}));
  ocs_tau_desc_t d = desc_for(&s->c, sun_at(oc_key_center(below), 100.0));
  float t[512];
  assert_int_equal(ocs_tau_direct(&d, below, t), 0);
  for (int v = 0; v < 512; v++) assert_true(t[v] == 0.0f);
  assert_int_equal(ocs_tau_node(&d, below, t), 0);
  for (int v = 0; v < 512; v++) assert_true(t[v] == 0.0f);
  slab_report(s, "slab, node inside, sun 5° and 30° below the horizon (cut at R - 10 km)");
}

/* A node at the root cube's +X face (96.8–100 km: its samples reach the atmosphere's edge and its
 * corners lie outside the atmosphere sphere) above a slab at 80–93 km: the sun outward (nothing
 * ahead: τ = 0 exactly), inward (through the slab, then cut at R − 10 km) and sideways-down. */
static void test_sun_depth__root_cube_edge(void **st) {
  slab_t *s = *st;
  int L = 12;
  uint32_t n = 1u << L;
  oc_key_t edge = oc_key_make(L, n - 1, n / 2, n / 2);
  oc_dvec3 o;
  double size;
  oc_key_bounds(edge, &o, &size);
  assert_true(o.x + size == OC_ROOT_HALF);
  slab_case(s, edge, oc_dv3(1.0, 0.0, 0.0), "root cube edge, sun outward (+X)");
  slab_case(s, edge, oc_dv3(-1.0, 0.0, 0.0), "root cube edge, sun inward (-X)");
  slab_case(s, edge, oc_dnorm(oc_dv3(-0.3, 1.0, 0.2)), "root cube edge, sun sideways and down");
  assert_true(s->ed.n >= 3 * 500);
  /* samples outside the atmosphere sphere with the sun outward: nothing ahead, exactly 0 */
  ocs_tau_desc_t d = desc_for(&s->c, oc_dv3(1.0, 0.0, 0.0));
  float td[512], tv[512];
  assert_int_equal(ocs_tau_direct(&d, edge, td), 0);
  assert_int_equal(ocs_tau_node(&d, edge, tv), 0);
  int outside = 0;
  for (int v = 0; v < 512; v++)
    if (oc_dlen(ocs_brick_sample_pos(edge, v & 7, (v >> 3) & 7, v >> 6)) > OC_ROOT_HALF) {
      assert_true(td[v] == 0.0f && tv[v] == 0.0f);
      outside++;
    }
  assert_true(outside > 0);
  slab_report(s, "slab 80-93 km, level-12 node on the root cube's +X face");
}

/* σt = 1000 m⁻¹: τ of about 10⁶ below the slab, finite and as accurate (relative) as anywhere. */
static void test_sun_depth__huge_sigma(void **st) {
  slab_t *s = *st;
  assert_true(sigma_of(slab_dense_json) == 1000.0);
  oc_key_t below = oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 700.0}));
  oc_key_t inside = oc_key_from_point(15, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2500.0}));
  slab_case(s, below, sun_at(oc_key_center(below), 30.0), "σt 1000, below the slab, sun 30°");
  slab_case(s, inside, sun_at(oc_key_center(inside), 60.0), "σt 1000, inside the slab, sun 60°");
  slab_case_cb(s, inside, sun_at(oc_key_center(inside), 89.0), "σt 1000, inside the slab, sun 89°", 0, NULL, KAPPA_GRAZING);
  ocs_tau_desc_t d = desc_for(&s->c, sun_at(oc_key_center(below), 30.0));
  float t[512];
  assert_int_equal(ocs_tau_direct(&d, below, t), 0);
  for (int v = 0; v < 512; v++) assert_true(isfinite(t[v]) && t[v] > 1e6f && t[v] < 2e6f);
  slab_report(s, "slab with σt 1000 m^-1 (τ ~ 1e6)");
}

/* Above every cloud (30 km) τ is exactly 0, and clear sky costs no brick at all: the bound skips it. */
static void test_sun_depth__above_clouds_is_zero(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, NULL, 600.0);
  oc_key_t k = oc_key_from_point(13, oc_geo_to_xyz((oc_geo_t){45.5, -4.0, 30000.0}));
  ocs_tau_desc_t d = desc_for(&c, sun_at(oc_key_center(k), 30.0));
  float td[512], tv[512];
  assert_int_equal(ocs_tau_direct(&d, k, td), 0);
  long fetched = c.sigma_fetches;
  assert_int_equal(ocs_tau_node(&d, k, tv), 0);
  for (int v = 0; v < 512; v++) assert_true(td[v] == 0.0f && tv[v] == 0.0f);
  printf("above the clouds: %ld bricks, %ld bounds fetched\n", c.sigma_fetches, c.bound_fetches);
  assert_int_equal(fetched, 0);
  assert_int_equal(c.sigma_fetches, 0);
  tc_free(&c);
}

/*-*** The procedural planet: the volume against the direct march ***/

/* A group of level-14 nodes in a cumulus field at about 2.3 km (45.5°N 4°W, t = 600 s): the one of
 * the 8 groups around that point with the most nodes holding σt (59 of 64; searched once, kept as
 * an offset because sampling 512 bricks costs 25 s under ASan). */
static oc_key_t cloudy_group(const ocs_tau_desc_t *d, int level) {
  oc_key_t k0 = oc_key_from_point(level, oc_geo_to_xyz((oc_geo_t){45.5, -4.0, 2000.0}));
  return ocs_tau_group_of(d, oc_key_neighbor(k0, -2, 2, 2));
}

typedef struct {
  double tau_max, tau_s2, t_max, t_s2;
  long n;
} stat_t;

static void stat_add(stat_t *s, double a, double b) {
  double e = a - b, t = fabs(exp(-a) - exp(-b));
  s->tau_max = fmax(s->tau_max, fabs(e) / (1.0 + fabs(b)));
  s->tau_s2 += e * e / ((1.0 + fabs(b)) * (1.0 + fabs(b)));
  s->t_max = fmax(s->t_max, t);
  s->t_s2 += t * t;
  s->n++;
}

/* One volume for the 64 nodes of a cloudy group (sun 60° from the zenith), against ocs_tau_direct at
 * every sample holding σt (τ matters only there). Bounds, from the measurements in
 * docs/numerics.md with a 20–40 % margin: RMS |Δe^-τ| ≤ 0.009, worst |Δe^-τ| ≤ 0.5 (a few
 * samples at the sharp shadow edges of optically thick cumulus: a sample's τ is interpolated
 * between columns one voxel apart whose τ differ by tens; the fast box filter's level-13 bricks,
 * two columns a voxel side, have sharper edges than the exact filter's: worst 0.41 against 0.28);
 * |Δτ|/(1 + τ): RMS ≤ 0.05, worst ≤ 0.9 (0.73 against 0.49).
 * The direct march is exact: steps and cone 8× finer (the same levels) change nothing but rounding. */
static void test_sun_depth__volume_matches_direct_on_the_planet(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, NULL, 600.0);
  int level = 14;
  oc_dvec3 at = oc_geo_to_xyz((oc_geo_t){45.5, -4.0, 2000.0});
  ocs_tau_desc_t d = desc_for(&c, sun_at(at, 60.0));
  oc_key_t grp = cloudy_group(&d, level);
  void *vol = NULL;
  size_t bytes = 0;
  double t0 = now();
  assert_int_equal(ocs_tau_volume_build(&d, grp, level, &vol, &bytes), 0);
  double t_build = now() - t0, t_direct = 0.0;
  stat_t s = {0};
  int with_sigma = 0, fallback = 0;
  oc_key_t ref_keys[64];
  int nref = 0;
  for (int q = 0; q < 64; q++) {
    oc_key_t k = oc_key_child(oc_key_child(grp, q & 7), q >> 3);
    float sg[512], td[512], tv[512];
    assert_int_equal(tc_sigma(&c, k, sg), 0);
    float smax = 0.0f;
    for (int v = 0; v < 512; v++) smax = fmaxf(smax, sg[v]);
    int r = ocs_tau_volume_lookup(vol, k, tv);
    if (r == OC_ENOENT) { /* the march level sees no σt around it: at most a faint wisp */
      assert_true(smax < 1e-3f);
      fallback += smax > 0.0f;
      continue;
    }
    assert_int_equal(r, 0);
    if (!(smax > 0.0f)) continue;
    with_sigma++;
    double t1 = now();
    assert_int_equal(ocs_tau_direct(&d, k, td), 0);
    t_direct += now() - t1;
    for (int v = 0; v < 512; v++)
      if (sg[v] > 0.0f) stat_add(&s, tv[v], td[v]);
    ref_keys[nref++] = k;
  }
  free(vol);
  double rms_t = sqrt(s.t_s2 / s.n), rms_tau = sqrt(s.tau_s2 / s.n);
  printf("group of 64 level-%d nodes, %d with σt (+%d faint ones left to the direct march): one volume of %zu bytes "
         "in %.1f ms (cold brick cache), direct %.1f ms for them (warm)\n", level, with_sigma, fallback, bytes,
         1e3 * t_build, 1e3 * t_direct);
  printf("volume vs direct over %ld samples with σt: |Δe^-τ| worst %.3f RMS %.4f; |Δτ|/(1+τ) worst %.3f RMS %.4f\n", s.n,
         s.t_max, rms_t, s.tau_max, rms_tau);
  assert_true(with_sigma >= 48);
  oc_report("tau", "planet, level-14 group, sun 60°: volume vs direct, RMS error of e^-τ (samples with σt)", rms_t, 0.009, "");
  oc_report("tau", "planet, level-14 group, sun 60°: volume vs direct, worst error of e^-τ", s.t_max, 0.5, "");
  oc_report("tau", "planet, level-14 group, sun 60°: volume vs direct, RMS of Δτ/(1+τ)", rms_tau, 0.05, "");
  oc_report("tau", "planet, level-14 group, sun 60°: volume vs direct, worst Δτ/(1+τ)", s.tau_max, 0.9, "");
  assert_true(rms_t <= 0.009 && s.t_max <= 0.5 && rms_tau <= 0.05 && s.tau_max <= 0.9);

  /* The direct march integrates the reconstruction exactly: steps and cone 8× finer (the same
   * levels at the same distances) change nothing but rounding. */
  ocs_tau_desc_t dr = d;
  dr.step_factor = 0.125;
  dr.cone = OCS_TAU_DEFAULT_CONE / 8.0;
  stat_t sd = {0};
  int nuse = SIZE(8, 2);
  for (int i = 0; i < nref && i < nuse; i++) {
    oc_key_t k = ref_keys[i * (nref / nuse)];
    float sg[512], td[512], tr[512];
    assert_int_equal(tc_sigma(&c, k, sg), 0);
    assert_int_equal(ocs_tau_direct(&d, k, td), 0);
    assert_int_equal(ocs_tau_direct(&dr, k, tr), 0);
    for (int v = 0; v < 512; v++)
      if (sg[v] > 0.0f) stat_add(&sd, td[v], tr[v]);
  }
  printf("against a march with 8x finer steps and cone over %ld samples: worst |Δτ|/(1+τ) %.2e\n", sd.n, sd.tau_max);
  oc_report("tau", "planet: direct against 8x finer steps and cone, worst Δτ/(1+τ) (exact quadrature)", sd.tau_max, 1e-5, "");
  assert_true(sd.n > 0 && sd.tau_max <= 1e-5);
  tc_free(&c);
}

/*-*** Exactness of the quadrature ***/

/* A field that is not a box filter of anything: every sample of level RF_LEVEL at lattice point G
 * (global index 7·node + i) inside a box of RF_HALF points around RF_C is a hash of G in [0, 1),
 * everything else 0 (face samples agree, as the lattice requires). Its reconstruction varies by
 * O(1) within every cell, so the old midpoint rule was off by per cents; the exact quadrature must
 * match a brute-force integral of the same trilinear reconstruction. */
#define RF_LEVEL 13
#define RF_HALF 24
static int64_t rf_c[3];

static double rf_value(int64_t gx, int64_t gy, int64_t gz) {
  if (llabs(gx - rf_c[0]) > RF_HALF || llabs(gy - rf_c[1]) > RF_HALF || llabs(gz - rf_c[2]) > RF_HALF) return 0.0;
  uint64_t h = (uint64_t)gx * 0x9E3779B97F4A7C15ull ^ (uint64_t)gy * 0xC2B2AE3D27D4EB4Full ^ (uint64_t)gz * 0x165667B19E3779F9ull;
  h ^= h >> 29, h *= 0xBF58476D1CE4E5B9ull, h ^= h >> 32;
  return (double)(h >> 11) * 0x1.0p-53 * 0.01; /* up to 0.01 m⁻¹ */
}

static int rf_sigma(void *ctx, oc_key_t key, float out[512]) {
  (void)ctx;
  uint32_t x, y, z;
  oc_key_coords(key, &x, &y, &z);
  for (int v = 0; v < 512; v++)
    out[v] = oc_key_level(key) != RF_LEVEL ? 0.0f
                                           : (float)rf_value(7 * (int64_t)x + (v & 7), 7 * (int64_t)y + ((v >> 3) & 7),
                                                             7 * (int64_t)z + (v >> 6));
  return 0;
}

static void rf_bound(void *ctx, oc_key_t key, float *lo, float *hi) { /* [0, 0] away from the box */
  (void)ctx;
  int l = oc_key_level(key);
  uint32_t c3[3];
  oc_key_coords(key, &c3[0], &c3[1], &c3[2]);
  *lo = 0.0f, *hi = 0.0f;
  for (int a = 0; a < 3; a++) { /* the node's lattice range at RF_LEVEL (l ≤ RF_LEVEL) */
    int64_t g0 = 7 * ((int64_t)c3[a] << (RF_LEVEL - l)) - 1, g1 = 7 * ((int64_t)(c3[a] + 1) << (RF_LEVEL - l)) + 1;
    if (g1 < rf_c[a] - RF_HALF || g0 > rf_c[a] + RF_HALF) return;
  }
  *hi = 0.01f;
}

/* The reconstruction at x, as shaders/brick.h defines it (trilinear in the level's node). */
static double rf_recon(oc_dvec3 x) {
  double v = oc_key_size(RF_LEVEL) / 7.0, p[3] = {x.x + OC_ROOT_HALF, x.y + OC_ROOT_HALF, x.z + OC_ROOT_HALF}, f[3];
  int64_t g[3];
  for (int a = 0; a < 3; a++) {
    double u = p[a] / oc_key_size(RF_LEVEL);
    int64_t n = (int64_t)floor(u), i = (int64_t)floor((u - (double)n) * 7.0);
    i = i > 6 ? 6 : i;
    g[a] = 7 * n + i;
    f[a] = p[a] / v - (double)g[a];
  }
  double r = 0.0;
  for (int c = 0; c < 8; c++)
    r += rf_value(g[0] + (c & 1), g[1] + (c >> 1 & 1), g[2] + (c >> 2)) * (c & 1 ? f[0] : 1 - f[0]) *
         (c >> 1 & 1 ? f[1] : 1 - f[1]) * (c >> 2 ? f[2] : 1 - f[2]);
  return r;
}

static void test_sun_depth__quadrature_is_exact(void **st) {
  (void)st;
  oc_key_t key = oc_key_from_point(RF_LEVEL + 1, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2000.0}));
  uint32_t x, y, z;
  oc_key_coords(oc_key_parent(key), &x, &y, &z);
  rf_c[0] = 7 * (int64_t)x + 3, rf_c[1] = 7 * (int64_t)y + 3, rf_c[2] = 7 * (int64_t)z + 3;
  ocs_tau_desc_t d = {0};
  d.sigma = rf_sigma, d.bound = rf_bound;
  d.sun_dir = oc_dv3(0.31, -0.52, 0.79); /* oblique to every axis */
  float t[512];
  assert_int_equal(ocs_tau_direct(&d, key, t), 0);
  oc_dvec3 sun = oc_dnorm(d.sun_dir);
  double len = (2 * RF_HALF + 4) * sqrt(3.0) * oc_key_size(RF_LEVEL) / 7.0, worst = 0.0; /* past the box */
  int nsamp = SIZE(16, 4), n = SIZE(400000, 100000);
  for (int k = 0; k < nsamp; k++) {
    int vi = (k * 97 + 13) % 512;
    oc_dvec3 p = ocs_brick_sample_pos(key, vi & 7, (vi >> 3) & 7, vi >> 6);
    double h = len / n, ref = 0.0; /* midpoint rule, 0.02 m steps */
    for (int i = 0; i < n; i++) ref += rf_recon(oc_dmad(p, sun, (i + 0.5) * h));
    ref *= h;
    worst = fmax(worst, fabs(t[vi] - ref) / ref);
  }
  printf("random trilinear field: exact quadrature against a brute-force integral, worst relative error %.2e\n", worst);
  oc_report("tau", "random field: direct against a brute-force integral of the reconstruction, worst relative", worst, 1e-5,
            "rel");
  assert_true(worst <= 1e-5);
}

/*-*** Threads ***/

typedef struct {
  const ocs_tau_desc_t *d;
  const oc_key_t *keys;
  int n, first, stride;
  float (*out)[2][512];
  int err;
} job_t;

static void *worker(void *arg) {
  job_t *j = arg;
  for (int i = j->first; i < j->n; i += j->stride) {
    if (ocs_tau_direct(j->d, j->keys[i], j->out[i][0]) < 0) j->err = 1;
    if (ocs_tau_node(j->d, j->keys[i], j->out[i][1]) < 0) j->err = 1;
  }
  return NULL;
}

/* The same nodes on 1 and on 4 threads sharing one brick cache: identical bits. */
static void test_sun_depth__thread_count_independent(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, NULL, 600.0);
  oc_dvec3 at = oc_geo_to_xyz((oc_geo_t){45.5, -4.0, 2000.0});
  ocs_tau_desc_t d = desc_for(&c, sun_at(at, 45.0));
  enum { N = 8 };
  oc_key_t keys[N];
  oc_key_t k0 = oc_key_from_point(14, at);
  for (int i = 0; i < N; i++) keys[i] = oc_key_neighbor(k0, (i & 1) * 5, ((i >> 1) & 1) * 3, (i >> 2) - 1);
  int n = SIZE(N, 4);
  static float one[N][2][512], four[N][2][512];
  job_t j1 = {&d, keys, n, 0, 1, one, 0};
  worker(&j1);
  assert_int_equal(j1.err, 0);
  tcache_t c4; /* a fresh cache, filled in a different order by racing threads */
  tc_init(&c4, NULL, 600.0);
  ocs_tau_desc_t d4 = d;
  d4.ctx = &c4;
  pthread_t th[4];
  job_t j4[4];
  for (int t = 0; t < 4; t++) {
    j4[t] = (job_t){&d4, keys, n, 3 - t, 4, four, 0}; /* reverse order across threads */
    assert_int_equal(pthread_create(&th[t], NULL, worker, &j4[t]), 0);
  }
  for (int t = 0; t < 4; t++) {
    pthread_join(th[t], NULL);
    assert_int_equal(j4[t].err, 0);
  }
  int nonzero = 0;
  for (int i = 0; i < n; i++) {
    assert_memory_equal(one[i], four[i], sizeof one[i]);
    for (int v = 0; v < 512; v++) nonzero += one[i][0][v] > 0.0f;
  }
  printf("%d nodes, %d non-zero direct samples: identical on 1 and 4 threads\n", n, nonzero);
  assert_true(nonzero > 0);
  tc_free(&c4);
  tc_free(&c);
}

/*-*** Clear sky: the proof that skips the march gives the march's bits ***/

/* One cumulus-sized sphere at 30°N 10°E, 2.5 km up, static. */
static const char cumulus_sphere_json[] =
    "{\"version\": 1, \"features\": {\"shadows\": true, \"animation\": false},"
    " \"sources\": [{\"type\": \"sphere\", \"lat\": 30, \"lon\": 10, \"alt\": 2500, \"radius\": 800, \"sigma_t\": 0.01}]}";

/* Ground nodes of `level` on an n × n grid around (lat, lon), spaced `deg` apart, each with its
 * τ from ocs_tau_direct() twice: with the clear-sky shortcut (sun_depth.h, note 1 of
 * ocs_tau_direct) and with march_clear (the full march every time). The two must be the same
 * bits at every sample, proven or not; the shortcut's desc never marches a provably clear column
 * (clear_marched 0), the marching one counts every proven node as marched. */
static void clear_case(tcache_t *c, double lat, double lon, double deg, int n, int level, double zenith, ocs_tau_stats_t *on,
                       ocs_tau_stats_t *off) {
  for (int a = 0; a < n; a++)
    for (int b = 0; b < n; b++) {
      oc_dvec3 p = oc_geo_to_xyz((oc_geo_t){lat + a * deg, lon + b * deg, 0.0});
      oc_key_t k = oc_key_from_point(level, p);
      ocs_tau_desc_t d = desc_for(c, sun_at(p, zenith)), dm = d;
      d.stats = on;
      dm.stats = off, dm.march_clear = 1;
      float t1[512], t2[512];
      long before = atomic_load(&on->clear_proven);
      assert_int_equal(ocs_tau_direct(&d, k, t1), 0);
      assert_int_equal(ocs_tau_direct(&dm, k, t2), 0);
      assert_memory_equal(t1, t2, sizeof t1);
      if (atomic_load(&on->clear_proven) > before)
        for (int v = 0; v < 512; v++) assert_true(t2[v] == 0.0f); /* what "proven clear" means */
    }
}

static void test_sun_depth__clear_column_is_the_march(void **st) {
  (void)st;
  /* One cumulus-sized sphere: right under it the column is not clear (τ > 0 there), beside it it is. */
  tcache_t c;
  tc_init(&c, cumulus_sphere_json, 0.0);
  ocs_tau_stats_t on = {0}, off = {0};
  oc_dvec3 under = oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 0.0});
  oc_key_t k = oc_key_from_point(14, under);
  ocs_tau_desc_t d = desc_for(&c, sun_at(under, 0.0));
  d.stats = &on;
  float t[512];
  assert_int_equal(ocs_tau_direct(&d, k, t), 0);
  assert_int_equal(atomic_load(&on.direct), 1);
  assert_int_equal(atomic_load(&on.clear_proven), 0);
  float tmax = 0.0f;
  for (int v = 0; v < 512; v++) tmax = fmaxf(tmax, t[v]);
  assert_true(tmax > 1.0f); /* 1.6 km of σt 0.01 straight above */
  clear_case(&c, 29.9, 9.9, 0.05, SIZE(5, 3), 13, 0.0, &on, &off);
  clear_case(&c, 29.9, 9.9, 0.05, SIZE(5, 3), 15, 40.0, &on, &off);
  clear_case(&c, 29.9, 9.9, 0.05, SIZE(5, 3), 12, 80.0, &on, &off);
  long proven_sphere = atomic_load(&on.clear_proven);
  printf("sphere: %ld of %ld direct marches proven clear\n", proven_sphere, atomic_load(&on.direct));
  assert_true(proven_sphere > 0);
  assert_true(proven_sphere < atomic_load(&on.direct)); /* some columns meet the sphere */
  tc_free(&c);

  /* The procedural planet's ground, several sun angles and levels: the same bits whether proven
   * or not (under this cumulus field the bounds rarely prove a column clear). */
  tc_init(&c, NULL, 600.0);
  for (int z = 0; z < 3; z++) {
    double zen[3] = {10.0, 50.0, 75.0};
    int lev[3] = {11, 13, 16};
    clear_case(&c, 45.3, -4.2, 0.1, SIZE(4, 2), lev[z], zen[z], &on, &off);
  }
  printf("planet + sphere: %ld of %ld direct marches proven clear\n", atomic_load(&on.clear_proven), atomic_load(&on.direct));
  assert_int_equal(atomic_load(&on.clear_marched), 0);
  assert_int_equal(atomic_load(&off.clear_marched), atomic_load(&off.clear_proven));
  assert_int_equal(atomic_load(&off.clear_proven), atomic_load(&on.clear_proven)); /* the same proofs either way */
  tc_free(&c);

  /* Clear air over the planet's ground near the default camera (t = 0): the bounds alone prove
   * nothing there (the level-13 node above the ground is bounded by [0, 0.14]); its samples,
   * all 0, prove the columns clear, and still give the march's bits. */
  tc_init(&c, NULL, 0.0);
  long proven = atomic_load(&on.clear_proven);
  clear_case(&c, 44.98, -0.02, 0.01, SIZE(4, 2), 14, 30.0, &on, &off);
  printf("planet, clear air: %ld proven clear\n", atomic_load(&on.clear_proven) - proven);
  assert_true(atomic_load(&on.clear_proven) > proven);
  assert_int_equal(atomic_load(&on.clear_marched), 0);
  assert_int_equal(atomic_load(&off.clear_marched), atomic_load(&off.clear_proven));
  tc_free(&c);
}

/*-*** The ground by its own columns ***/

/* Ground nodes hold no σt, so a group volume covers them only when asked (ocs_tau_desc_t.ground,
 * the next test); ocs_tau_columns() marches each node's own sun columns. Under the cumulus field (45.5°N 4°W, t = 600 s), level 14, the scene's sun (28°)
 * and 60°, against the direct march at every sample, air and ground: the interpolation error across
 * the sharp shadow edges of the cumulus that cover the ground here (measured: |Δe^-τ| RMS 0.038, worst
 * 0.53; |Δτ|/(1 + τ) RMS 0.084, worst 1.36; a cloud's samples in its group volume: 0.006 and 0.28),
 * the bounds about 20 % above it; a node proven clear gives the direct march's zeros bit for bit,
 * without columns. */
static void test_sun_depth__ground_columns_match_direct(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, NULL, 600.0);
  stat_t s = {0};
  ocs_tau_stats_t cs = {0};
  long shaded = 0, nodes = 0;
  int n = 6; /* the bounds are the whole set's: a smaller one (2 × 2) has RMS 0.056 */
  for (int z = 0; z < 2; z++) {
    double zen = z ? 60.0 : 28.0;
    for (int a = 0; a < n; a++)
      for (int b = 0; b < n; b++) {
        oc_dvec3 p = oc_geo_to_xyz((oc_geo_t){45.45 + 0.02 * a, -4.05 + 0.02 * b, 0.0});
        oc_key_t k = oc_key_from_point(14, p);
        assert_true(oc_key_meets_ground(k));
        ocs_tau_desc_t d = desc_for(&c, sun_at(p, zen));
        d.stats = &cs;
        float tc[512], td[512];
        long proven = atomic_load(&cs.clear_proven);
        assert_int_equal(ocs_tau_columns(&d, k, tc), 0);
        assert_int_equal(ocs_tau_direct(&d, k, td), 0);
        if (atomic_load(&cs.clear_proven) > proven + 1) assert_memory_equal(tc, td, sizeof tc); /* both proven */
        float tmax = 0.0f;
        for (int v = 0; v < 512; v++) {
          stat_add(&s, tc[v], td[v]);
          tmax = fmaxf(tmax, td[v]);
        }
        shaded += tmax > 0.1f;
        nodes++;
      }
  }
  double rms_t = sqrt(s.t_s2 / s.n), rms_tau = sqrt(s.tau_s2 / s.n);
  printf("ground by columns: %ld level-14 nodes (%ld in cloud shadow, %ld by columns), %ld samples: |Δe^-τ| worst %.3f "
         "RMS %.4f; |Δτ|/(1+τ) worst %.3f RMS %.4f\n", nodes, shaded, atomic_load(&cs.columns), s.n, s.t_max, rms_t,
         s.tau_max, rms_tau);
  assert_true(shaded >= nodes / 4); /* the cumulus shades the ground: the case tests something */
  assert_true(atomic_load(&cs.columns) >= shaded);
  oc_report("tau", "planet ground, level 14: own columns vs direct, RMS error of e^-τ", rms_t, 0.045, "");
  oc_report("tau", "planet ground, level 14: own columns vs direct, worst error of e^-τ", s.t_max, 0.65, "");
  assert_true(rms_t <= 0.045 && s.t_max <= 0.65 && rms_tau <= 0.1 && s.tau_max <= 1.6);
  tc_free(&c);
}

/* The server's group volumes cover the ground too (ocs_tau_desc_t.ground): every ground node of a
 * group that the clear-sky proof does not settle, sharing the group's columns. The four groups of
 * level-14 nodes around 45.5°N 4°W at t = 600 s, suns at 28° and 60°, every ground sample against
 * the direct march: the same interpolation as a node's own columns, with its error (the test above).
 * A ground node the volume does not cover must be proven clear (the direct march's zeros), and
 * without the callback no ground node is covered. */
static int ground_cb(void *ctx, oc_key_t key) {
  (void)ctx;
  return oc_key_level(key) >= 11 && oc_key_meets_ground(key);
}

static void test_sun_depth__ground_in_group_volume(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, NULL, 600.0);
  stat_t s = {0}, so = {0}; /* the group volume's error, and the nodes' own columns' */
  ocs_tau_stats_t cs = {0};
  long shaded = 0, nodes = 0, clear = 0, by_ground = 0;
  for (int z = 0; z < 2; z++)
    for (int g = 0; g < 4; g++) {
      oc_dvec3 p = oc_geo_to_xyz((oc_geo_t){45.47 + 0.03 * (g & 1), -4.03 + 0.03 * (g >> 1), 0.0});
      ocs_tau_desc_t d = desc_for(&c, sun_at(p, z ? 60.0 : 28.0));
      d.stats = &cs;
      oc_key_t grp = ocs_tau_group_of(&d, oc_key_from_point(14, p));
      void *vol = NULL, *bare = NULL;
      size_t bytes;
      assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &bare, &bytes), 0);
      d.ground = ground_cb;
      assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &vol, &bytes), 0);
      for (uint32_t q = 0; q < 64; q++) {
        oc_key_t k = oc_key_child(oc_key_child(grp, q & 7), q >> 3);
        if (!oc_key_meets_ground(k)) continue;
        float tg[512], td[512];
        assert_int_equal(ocs_tau_direct(&d, k, td), 0);
        int rb = ocs_tau_volume_lookup(bare, k, tg), r = ocs_tau_volume_lookup(vol, k, tg);
        if (r == OC_ENOENT) { /* proven clear: nothing to march */
          for (int v = 0; v < 512; v++) assert_true(td[v] == 0.0f);
          clear++;
          continue;
        }
        assert_int_equal(r, 0);
        by_ground += rb == OC_ENOENT; /* covered for the callback's sake, not for σt near it */
        float to[512], tmax = 0.0f;
        assert_int_equal(ocs_tau_columns(&d, k, to), 0);
        for (int v = 0; v < 512; v++) {
          stat_add(&s, tg[v], td[v]);
          stat_add(&so, to[v], td[v]);
          tmax = fmaxf(tmax, td[v]);
        }
        shaded += tmax > 0.1f;
        nodes++;
      }
      free(vol);
      free(bare);
    }
  double rms_t = sqrt(s.t_s2 / s.n), rms_tau = sqrt(s.tau_s2 / s.n);
  printf("ground in group volumes: %ld level-14 ground nodes covered (%ld only as ground, %ld in cloud shadow), %ld "
         "proven clear, %ld samples: |Δe^-τ| worst %.3f RMS %.4f; |Δτ|/(1+τ) worst %.3f RMS %.4f; their own columns: "
         "%.3f %.4f; %.3f %.4f\n", nodes, by_ground, shaded, clear, s.n, s.t_max, rms_t, s.tau_max, rms_tau, so.t_max,
         sqrt(so.t_s2 / so.n), so.tau_max, sqrt(so.tau_s2 / so.n));
  assert_true(by_ground >= 32 && shaded >= nodes / 4); /* the cumulus shades the ground: the case tests something */
  /* the callback's nodes, counted by the volume as columns; the nodes' own volumes add theirs */
  assert_int_equal(atomic_load(&cs.columns), by_ground + nodes);
  oc_report("tau", "planet ground, level 14: group volume vs direct, RMS error of e^-τ", rms_t, 0.05, "");
  oc_report("tau", "planet ground, level 14: group volume vs direct, worst error of e^-τ", s.t_max, 0.8, "");
  assert_true(rms_t <= 0.05 && s.t_max <= 0.8 && rms_tau <= 0.115 && s.tau_max <= 1.6);
  assert_true(rms_t <= 1.15 * sqrt(so.t_s2 / so.n)); /* no worse than the nodes' own columns */
  tc_free(&c);
}

/* The other side of the ground's cover: a ground node the clear-sky proof settles is not covered
 * (OC_ENOENT, the server's τ = 0), and its direct march is 0 at every sample. One cumulus-sized
 * sphere, the sun at the zenith: of the ground nodes of the group under it, those under the sphere
 * are covered and shaded, the others proven clear. */
static void test_sun_depth__ground_clear_not_covered(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, cumulus_sphere_json, 0.0);
  oc_dvec3 under = oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 0.0});
  ocs_tau_stats_t cs = {0};
  ocs_tau_desc_t d = desc_for(&c, sun_at(under, 0.0));
  d.stats = &cs;
  d.ground = ground_cb;
  oc_key_t grp = ocs_tau_group_of(&d, oc_key_from_point(14, under));
  void *vol = NULL;
  size_t bytes;
  assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &vol, &bytes), 0);
  long covered = 0, clear = 0;
  for (uint32_t q = 0; q < 64; q++) {
    oc_key_t k = oc_key_child(oc_key_child(grp, q & 7), q >> 3);
    if (!oc_key_meets_ground(k)) continue;
    float tg[512], td[512], tmax = 0.0f;
    int r = ocs_tau_volume_lookup(vol, k, tg);
    assert_int_equal(ocs_tau_direct(&d, k, td), 0);
    for (int v = 0; v < 512; v++) tmax = fmaxf(tmax, td[v]);
    if (r == OC_ENOENT) {
      assert_true(tmax == 0.0f);
      clear++;
    } else {
      assert_int_equal(r, 0);
      covered++;
    }
  }
  printf("ground under a sphere: %ld covered, %ld proven clear and not covered\n", covered, clear);
  assert_true(covered > 0 && clear > 0);
  free(vol);
  tc_free(&c);
}

/*-*** A volume kept while its inputs give the same answers ***/

/* Callbacks over a tcache that change one answer: the bound's maximum, or one σt sample, of `key`
 * (by +1 m⁻¹); and that note the first key each was asked for. */
typedef struct {
  tcache_t *c;
  oc_key_t key;
  int what; /* 0: none, 1: the bound, 2: σt */
  oc_key_t first_bound, first_brick;
} tweak_t;

static int tw_sigma(void *ctx, oc_key_t key, float out[512]) {
  tweak_t *t = ctx;
  int r = tc_sigma(t->c, key, out);
  if (!t->first_brick) t->first_brick = key;
  if (r == 0 && t->what == 2 && key == t->key) out[137] += 1.0f;
  return r;
}

static void tw_bound(void *ctx, oc_key_t key, float *lo, float *hi) {
  tweak_t *t = ctx;
  tc_bound(t->c, key, lo, hi);
  if (!t->first_bound) t->first_bound = key;
  if (t->what == 1 && key == t->key) *hi += 1.0f;
}

/* ocs_tau_volume_unchanged(): 1 while every answer the build got is the same (and a second build
 * is then the same bytes), 0 when one bound or one σt sample changes, or the sun or a parameter
 * does, the sigma callback's error when it fails, OC_EINVAL for what is not a volume. The sphere
 * under a zenith sun: its group at level 14 fetches bricks and asks bounds. */
static void test_sun_depth__volume_unchanged_while_answers_are(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, cumulus_sphere_json, 0.0);
  oc_dvec3 under = oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 0.0});
  tweak_t tw = {.c = &c};
  ocs_tau_desc_t d = desc_for(&c, sun_at(under, 0.0));
  d.sigma = tw_sigma, d.bound = tw_bound, d.ctx = &tw;
  oc_key_t grp = ocs_tau_group_of(&d, oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2500.0})));
  void *vol = NULL, *again = NULL;
  size_t bytes, bytes2;
  assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &vol, &bytes), 0);
  assert_true(tw.first_bound && tw.first_brick); /* the case tests both kinds of input */
  assert_int_equal(ocs_tau_volume_unchanged(&d, vol), 1);
  assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &again, &bytes2), 0);
  assert_true(bytes2 == bytes && memcmp(again, vol, bytes) == 0);
  free(again);
  tw.what = 1, tw.key = tw.first_bound;
  assert_int_equal(ocs_tau_volume_unchanged(&d, vol), 0);
  tw.what = 2, tw.key = tw.first_brick;
  assert_int_equal(ocs_tau_volume_unchanged(&d, vol), 0);
  tw.what = 0;
  ocs_tau_desc_t o = d;
  o.sun_dir = sun_at(under, 1e-6);
  assert_int_equal(ocs_tau_volume_unchanged(&o, vol), 0);
  o = d, o.cone = 0.03;
  assert_int_equal(ocs_tau_volume_unchanged(&o, vol), 0);
  o = d, o.cover_all = 1;
  assert_int_equal(ocs_tau_volume_unchanged(&o, vol), 0);
  o = d, o.ground = ground_cb;
  assert_int_equal(ocs_tau_volume_unchanged(&o, vol), 0);
  c.fail_sigma = 1;
  assert_int_equal(ocs_tau_volume_unchanged(&d, vol), OC_EIO);
  c.fail_sigma = 0;
  float junk[64] = {0};
  assert_int_equal(ocs_tau_volume_unchanged(&d, junk), OC_EINVAL);
  assert_int_equal(ocs_tau_volume_unchanged(&d, NULL), OC_EINVAL);
  assert_int_equal(ocs_tau_volume_unchanged(&d, vol), 1);
  free(vol);
  tc_free(&c);
}

/*-*** Arguments and errors ***/

static void test_sun_depth__bad_arguments(void **st) {
  (void)st;
  tcache_t c;
  tc_init(&c, slab_json, 0.0);
  oc_key_t k = oc_key_from_point(14, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 700.0}));
  ocs_tau_desc_t d = desc_for(&c, oc_dv3(0.0, 0.0, 1.0));
  float t[512];
  void *vol = NULL;
  size_t bytes = 0;
  assert_int_equal(ocs_tau_direct(&d, OC_KEY_INVALID, t), OC_EINVAL);
  assert_int_equal(ocs_tau_direct(NULL, k, t), OC_EINVAL);
  assert_int_equal(ocs_tau_direct(&d, k, NULL), OC_EINVAL);
  assert_int_equal(ocs_tau_columns(&d, OC_KEY_INVALID, t), OC_EINVAL);
  assert_int_equal(ocs_tau_columns(NULL, k, t), OC_EINVAL);
  assert_int_equal(ocs_tau_columns(&d, k, NULL), OC_EINVAL);
  ocs_tau_desc_t bad = d;
  bad.sun_dir = oc_dv3(0.0, 0.0, 0.0);
  assert_int_equal(ocs_tau_direct(&bad, k, t), OC_EINVAL);
  assert_int_equal(ocs_tau_columns(&bad, k, t), OC_EINVAL);
  bad = d, bad.sun_dir.x = NAN;
  assert_int_equal(ocs_tau_node(&bad, k, t), OC_EINVAL);
  bad = d, bad.sigma = NULL;
  assert_int_equal(ocs_tau_direct(&bad, k, t), OC_EINVAL);
  bad = d, bad.step_factor = -1.0;
  assert_int_equal(ocs_tau_direct(&bad, k, t), OC_EINVAL);
  bad = d, bad.group_levels = OCS_TAU_MAX_GROUP_LEVELS + 1;
  assert_int_equal(ocs_tau_node(&bad, k, t), OC_EINVAL);
  assert_true(ocs_tau_group_of(&bad, k) == OC_KEY_INVALID);
  assert_int_equal(ocs_tau_march_level(&bad, 7), -1);
  assert_int_equal(ocs_tau_march_level(NULL, 7), -1);
  /* the march level (what a τ cache must be keyed by): the node's own up to min_level, the one
   * above it below; -1 off the key's levels */
  ocs_tau_desc_t dl = d;
  dl.filter_levels = dl.min_level = 0;
  assert_int_equal(ocs_tau_march_level(&dl, 0), 0);
  assert_int_equal(ocs_tau_march_level(&dl, 6), 6);
  assert_int_equal(ocs_tau_march_level(&dl, 7), 6);
  assert_int_equal(ocs_tau_march_level(&dl, 14), 13);
  assert_int_equal(ocs_tau_march_level(&dl, -1), -1);
  assert_int_equal(ocs_tau_march_level(&dl, OC_KEY_MAX_LEVEL + 1), -1);
  /* groups: the ancestor 2 up, clamped at the root */
  assert_true(ocs_tau_group_of(&d, k) == oc_key_ancestor(k, 12));
  assert_true(ocs_tau_group_of(&d, oc_key_child(OC_KEY_ROOT, 3)) == OC_KEY_ROOT);
  /* a volume: only descendants at its level */
  oc_key_t grp = ocs_tau_group_of(&d, k);
  assert_int_equal(ocs_tau_volume_build(&d, grp, 11, &vol, &bytes), OC_EINVAL);
  assert_int_equal(ocs_tau_volume_build(&d, grp, 12 + OCS_TAU_MAX_GROUP_LEVELS + 1, &vol, &bytes), OC_EINVAL);
  assert_null(vol);
  assert_int_equal(ocs_tau_volume_build(&d, grp, 14, &vol, &bytes), 0);
  assert_true(bytes > 0);
  assert_int_equal(ocs_tau_volume_lookup(vol, oc_key_parent(k), t), OC_EINVAL);
  assert_int_equal(ocs_tau_volume_lookup(vol, oc_key_neighbor(k, 8, 0, 0), t), OC_EINVAL);
  assert_int_equal(ocs_tau_volume_lookup(NULL, k, t), OC_EINVAL);
  int junk[64] = {0};
  assert_int_equal(ocs_tau_volume_lookup(junk, k, t), OC_EINVAL);
  /* the node below the slab holds no σt: the volume does not cover it, the direct march does */
  assert_int_equal(ocs_tau_volume_lookup(vol, k, t), OC_ENOENT);
  free(vol);
  /* a node with no σt still gets its τ from ocs_tau_node (through the direct march) */
  float td[512];
  assert_int_equal(ocs_tau_node(&d, k, t), 0);
  assert_int_equal(ocs_tau_direct(&d, k, td), 0);
  assert_memory_equal(t, td, sizeof t);
  /* the sigma callback's error aborts the call */
  oc_key_t inside = oc_key_from_point(15, oc_geo_to_xyz((oc_geo_t){30.0, 10.0, 2500.0}));
  tcache_t c2;
  tc_init(&c2, "{\"version\": 1, \"features\": {\"animation\": false},"
               " \"sources\": [{\"type\": \"sphere\", \"lat\": 30, \"lon\": 10, \"alt\": 2500, \"radius\": 800, \"sigma_t\": 0.01}]}",
          0.0);
  c2.fail_sigma = 1;
  ocs_tau_desc_t d2 = desc_for(&c2, oc_dv3(0.0, 0.0, 1.0));
  assert_int_equal(ocs_tau_direct(&d2, inside, t), OC_EIO);
  assert_int_equal(ocs_tau_node(&d2, inside, t), OC_EIO);
  assert_int_equal(ocs_tau_columns(&d2, inside, t), OC_EIO);
  assert_int_equal(ocs_tau_volume_build(&d2, ocs_tau_group_of(&d2, inside), 15, &vol, &bytes), OC_EIO);
  assert_null(vol);
  tc_free(&c2);
  tc_free(&c);
}

OC_TEST_MAIN(NULL, NULL,
             SLAB_TEST(test_sun_depth__slab_below_three_sun_angles, NULL),
             SLAB_TEST(test_sun_depth__slab_inside, NULL),
             SLAB_TEST(test_sun_depth__zenith_along_an_axis, NULL),
             SLAB_TEST(test_sun_depth__sun_below_horizon, NULL),
             SLAB_TEST(test_sun_depth__root_cube_edge, slab_high_json),
             SLAB_TEST(test_sun_depth__huge_sigma, slab_dense_json),
             cmocka_unit_test(test_sun_depth__above_clouds_is_zero),
             cmocka_unit_test(test_sun_depth__volume_matches_direct_on_the_planet),
             cmocka_unit_test(test_sun_depth__quadrature_is_exact),
             cmocka_unit_test(test_sun_depth__thread_count_independent),
             cmocka_unit_test(test_sun_depth__clear_column_is_the_march),
             cmocka_unit_test(test_sun_depth__ground_columns_match_direct),
             cmocka_unit_test(test_sun_depth__ground_in_group_volume),
             cmocka_unit_test(test_sun_depth__ground_clear_not_covered),
             cmocka_unit_test(test_sun_depth__volume_unchanged_while_answers_are),
             cmocka_unit_test(test_sun_depth__bad_arguments))

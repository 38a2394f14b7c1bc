/* test_voxelize.c — box-filtered brick sampling and the state builder (server/voxelize.c)
 * against the closed-form media of server/analytic.c. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "analytic.h"
#include "oc_brick.h"
#include "oc_err.h"
#include "oc_key.h"
#include "oc_planet.h"
#include "oc_state.h"
#include "voxelize.h"

/* |a − b| ≤ tol, reporting both values (cmocka 1.1 has no floating-point assert). */
#define assert_near(a, b, tol)                                                                  \
  do {                                                                                          \
    double a_ = (a), b_ = (b), t_ = (tol);                                                      \
    if (!(fabs(a_ - b_) <= t_)) fail_msg("%s = %.17g, expected %.17g +- %.3g", #a, a_, b_, t_); \
  } while (0)

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Voxelizes m into a fresh state s with `threads` threads (asserting success); returns the seconds
 * it took, for the printed figures only. */
static double voxelize_timed(oc_state_t *s, const ocs_medium_t *m, int max_level, int sub, oc_dvec3 sun, int threads) {
  oc_state_init(s);
  double t0 = now_s();
  assert_int_equal(ocs_voxelize_medium(s, m, max_level, sub, sun, threads), 0);
  return now_s() - t0;
}

static uint64_t rng_state = 0x2545f4914f6cdd1dull;
static uint64_t rnd_u64(void) {
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return rng_state * 2685821657736338717ull;
}

/* Trapezoid weights of corner samples along one axis: ∫ of the trilinear interpolant over a node
 * of unit edge is Σ w_i w_j w_k v_ijk. */
static const double W[8] = {0.5 / 7, 1.0 / 7, 1.0 / 7, 1.0 / 7, 1.0 / 7, 1.0 / 7, 1.0 / 7, 0.5 / 7};
static double trapezoid_mean(const float v[512]) {
  double s = 0.0;
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) s += W[i] * W[j] * W[k] * (double)v[i + 8 * j + 64 * k];
  return s;
}

/* Decoded values of a leaf's two channels. */
static void node_values(const oc_state_t *s, const oc_node_t *n, float sig[512], float tau[512]) {
  if (n->kind == OC_NODE_BRICK) {
    const oc_brick_t *b = oc_state_find_brick(s, n->brick_id);
    assert_non_null(b);
    oc_brick_decode(&b->codes, n->range, sig, tau);
  } else {
    for (int i = 0; i < 512; i++) {
      sig[i] = n->range[OC_CH_SIGMA].lo;
      tau[i] = n->range[OC_CH_TAU].lo;
    }
  }
}

/* Worst relative error of a decoded channel: the code bound, or the uniform tolerance. */
static double channel_rel_bound(oc_range_t r) {
  if (r.lo == r.hi) return OC_UNIFORM_TOL;
  return oc_code_rel_error_bound(r);
}

/* ---- ocs_brick_sample ------------------------------------------------------------------------- */

typedef struct {
  oc_dvec3 o;
  double a, bx, by, bz;
} lin_t;
static double lin_fn(void *ctx, oc_dvec3 p) {
  const lin_t *l = ctx;
  return l->a + l->bx * (p.x - l->o.x) + l->by * (p.y - l->o.y) + l->bz * (p.z - l->o.z);
}
static double const_fn(void *ctx, oc_dvec3 p) {
  (void)p;
  return *(const double *)ctx;
}
static double step_fn(void *ctx, oc_dvec3 p) { return p.x > *(const double *)ctx ? 1.0 : 0.0; }

static void test_sample__positions_and_filter(void **state) {
  (void)state;
  oc_key_t key = oc_key_from_point(12, oc_geo_to_xyz((oc_geo_t){48, 2, 2000}));
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  /* Sample (i, j, k) sits at origin + (i, j, k)·size/7. */
  for (int k = 0; k < 8; k += 7)
    for (int j = 0; j < 8; j += 3)
      for (int i = 0; i < 8; i++) {
        oc_dvec3 p = ocs_brick_sample_pos(key, i, j, k);
        assert_near(p.x, o.x + i * size / 7, 1e-8);
        assert_near(p.y, o.y + j * size / 7, 1e-8);
        assert_near(p.z, o.z + k * size / 7, 1e-8);
      }
  /* sub = 1: exact point samples of the field at those positions. */
  lin_t l = {o, 0.5, 1e-4, -2e-4, 3e-5};
  float out[512];
  ocs_brick_sample(key, lin_fn, &l, 1, out);
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++)
        assert_true(out[i + 8 * j + 64 * k] == (float)lin_fn(&l, ocs_brick_sample_pos(key, i, j, k)));
  /* A linear field's box average is its value at the centre, for any sub. */
  for (int sub = 2; sub <= 5; sub++) {
    ocs_brick_sample(key, lin_fn, &l, sub, out);
    for (int n = 0; n < 512; n += 37) {
      double v = lin_fn(&l, ocs_brick_sample_pos(key, n % 8, (n / 8) % 8, n / 64));
      assert_near(out[n], v, 1e-6 * fabs(v));
    }
  }
  /* A constant stays exactly constant. */
  double c = 0.0371;
  ocs_brick_sample(key, const_fn, &c, 3, out);
  for (int n = 0; n < 512; n++) assert_true(out[n] == (float)c);
  /* A step through the middle of sample i = 3's footprint: half of the sub-samples (even sub). */
  double xs = ocs_brick_sample_pos(key, 3, 0, 0).x;
  ocs_brick_sample(key, step_fn, &xs, 4, out);
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++) {
      assert_true(out[2 + 8 * j + 64 * k] == 0.0f);
      assert_true(out[3 + 8 * j + 64 * k] == 0.5f);
      assert_true(out[4 + 8 * j + 64 * k] == 1.0f);
    }
  /* The step exactly a quarter of the way, sub = 4: 3/4 of the sub-samples are beyond it. */
  double xq = xs - 0.25 * size / 7 + 1e-6;
  ocs_brick_sample(key, step_fn, &xq, 4, out);
  assert_true(out[3] == 0.75f);
}

/* A field that depends on every bit of the position: any difference in where a sub-sample is
 * evaluated changes the value. */
static double bits_fn(void *ctx, oc_dvec3 p) {
  (void)ctx;
  double c[3] = {p.x, p.y, p.z};
  uint64_t h = 0x84222325cbf29ce4ull;
  for (int a = 0; a < 3; a++) {
    uint64_t u;
    memcpy(&u, &c[a], sizeof u);
    h ^= u;
    h *= 0x9e3779b97f4a7c15ull;
    h ^= h >> 29;
  }
  return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

static int same_bits(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

static void test_sample__neighbour_faces_bit_identical(void **state) {
  (void)state;
  const int levels[] = {1, 4, 9, 14, 18, 21};
  float a[512], b[512];
  int checked = 0;
  for (size_t li = 0; li < sizeof levels / sizeof levels[0]; li++) {
    int L = levels[li];
    for (int rep = 0; rep < 3; rep++) {
      uint32_t n = 1u << L;
      uint32_t ix = (uint32_t)(rnd_u64() % n), iy = (uint32_t)(rnd_u64() % n), iz = (uint32_t)(rnd_u64() % n);
      if (rep == 0) ix = iy = iz = n / 2 - (n > 1); /* around the planet centre: mixed signs */
      oc_key_t key = oc_key_make(L, ix, iy, iz);
      assert_true(oc_key_valid(key));
      for (int sub = 1; sub <= 3; sub++) {
        ocs_brick_sample(key, bits_fn, NULL, sub, a);
        /* Face neighbours along each axis, both directions. */
        for (int axis = 0; axis < 3; axis++)
          for (int dir = -1; dir <= 1; dir += 2) {
            int d[3] = {0, 0, 0};
            d[axis] = dir;
            oc_key_t nb = oc_key_neighbor(key, d[0], d[1], d[2]);
            if (nb == OC_KEY_INVALID) continue;
            ocs_brick_sample(nb, bits_fn, NULL, sub, b);
            for (int u = 0; u < 8; u++)
              for (int v = 0; v < 8; v++) {
                int ia[3], ib[3];
                int fa = dir > 0 ? 7 : 0, fb = 7 - fa;
                int other[2] = {u, v}, oi = 0;
                for (int q = 0; q < 3; q++) {
                  if (q == axis) {
                    ia[q] = fa;
                    ib[q] = fb;
                  } else {
                    ia[q] = ib[q] = other[oi++];
                  }
                }
                float va = a[ia[0] + 8 * ia[1] + 64 * ia[2]], vb = b[ib[0] + 8 * ib[1] + 64 * ib[2]];
                if (!same_bits(va, vb))
                  fail_msg("level %d sub %d axis %d dir %d (%d,%d): %.9g vs %.9g", L, sub, axis, dir, u, v, va, vb);
                checked++;
              }
            /* The field really depends on position: interior samples differ from the neighbour's. */
            assert_false(same_bits(a[3 + 8 * 3 + 64 * 3], b[3 + 8 * 3 + 64 * 3]));
          }
        /* Edge and corner neighbours. */
        oc_key_t e = oc_key_neighbor(key, 1, 1, 0);
        if (e != OC_KEY_INVALID) {
          ocs_brick_sample(e, bits_fn, NULL, sub, b);
          for (int k = 0; k < 8; k++) assert_true(same_bits(a[7 + 8 * 7 + 64 * k], b[0 + 0 + 64 * k]));
        }
        oc_key_t c = oc_key_neighbor(key, -1, 1, -1);
        if (c != OC_KEY_INVALID) {
          ocs_brick_sample(c, bits_fn, NULL, sub, b);
          assert_true(same_bits(a[0 + 8 * 7 + 0], b[7 + 0 + 64 * 7]));
        }
      }
      /* Nested lattices: a parent's point-sample positions are its children's, bit for bit. */
      if (L < 21) {
        for (int ci = 0; ci < 8; ci++) {
          oc_key_t ch = oc_key_child(key, ci);
          int bx = ci & 1, by = (ci >> 1) & 1, bz = (ci >> 2) & 1;
          /* Child sample 2m − 7·b corresponds to parent sample m (when in 0..7). */
          for (int m = 0; m < 8; m++) {
            int cs = 2 * m - 7 * bx;
            if (cs < 0 || cs > 7) continue;
            /* Along y and z take the parent's face sample 7·b, which is the child's sample 7·b. */
            oc_dvec3 pp = ocs_brick_sample_pos(key, m, 7 * by, 7 * bz);
            oc_dvec3 pc = ocs_brick_sample_pos(ch, cs, 7 * by, 7 * bz);
            assert_true(memcmp(&pp, &pc, sizeof pp) == 0);
          }
        }
      }
    }
  }
  assert_true(checked > 1000);
}

/* ---- the state builder: a sphere -------------------------------------------------------------- */

static double dist_box_min(oc_dvec3 c, oc_dvec3 lo, oc_dvec3 hi) {
  double dx = c.x < lo.x ? lo.x - c.x : (c.x > hi.x ? c.x - hi.x : 0);
  double dy = c.y < lo.y ? lo.y - c.y : (c.y > hi.y ? c.y - hi.y : 0);
  double dz = c.z < lo.z ? lo.z - c.z : (c.z > hi.z ? c.z - hi.z : 0);
  return sqrt(dx * dx + dy * dy + dz * dz);
}
static double dist_box_max(oc_dvec3 c, oc_dvec3 lo, oc_dvec3 hi) {
  double dx = fmax(fabs(c.x - lo.x), fabs(c.x - hi.x));
  double dy = fmax(fabs(c.y - lo.y), fabs(c.y - hi.y));
  double dz = fmax(fabs(c.z - lo.z), fabs(c.z - hi.z));
  return sqrt(dx * dx + dy * dy + dz * dz);
}
static void grown_box(oc_key_t key, oc_dvec3 *lo, oc_dvec3 *hi) {
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double g = size / 14 + 1e-6;
  *lo = oc_dv3(o.x - g, o.y - g, o.z - g);
  *hi = oc_dv3(o.x + size + g, o.y + size + g, o.z + size + g);
}

static void test_voxelize__sphere_interior_and_empty(void **state) {
  (void)state;
  const double r = 4000, sig = 0.02;
  ocs_prim_t sp;
  assert_int_equal(ocs_prim_sphere(&sp, (oc_geo_t){45, 10, 5000}, r, sig), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &sp), 0);
  ocs_medium_ctx_t mc = {&m, oc_dv3(0, 0, 1), 0.0};
  ocs_voxelize_stats_t st;
  ocs_voxelize_desc_t d = {0};
  d.sigma = ocs_medium_sigma_cb; /* τ left out: interior nodes are then uniform in both channels */
  d.ctx = &mc;
  d.max_level = 13;
  d.refine = ocs_medium_refine_cb;
  d.sun_dir = oc_dv3(0, 0, 1);
  d.threads = 2;
  d.stats = &st;
  oc_state_t s;
  oc_state_init(&s);
  assert_int_equal(ocs_voxelize(&s, &d), 0);
  char why[200] = "";
  assert_int_equal(oc_state_validate(&s, why, sizeof why), 0);
  assert_int_equal(st.leaves, s.node_count);
  assert_int_equal(st.bricks, s.brick_count);
  assert_int_equal(st.empty + st.uniform + st.bricks, st.leaves);
  assert_true(st.per_level[13] > 0);
  int interior = 0, outside = 0, boundary = 0;
  for (uint32_t i = 0; i < s.node_count; i++) {
    const oc_node_t *n = &s.nodes[i];
    oc_dvec3 lo, hi;
    grown_box(n->key, &lo, &hi);
    if (dist_box_max(sp.sphere.c, lo, hi) < r) {
      interior++;
      assert_int_equal(n->kind, OC_NODE_UNIFORM);
      assert_true(n->range[OC_CH_SIGMA].lo == n->range[OC_CH_SIGMA].hi);
      assert_near(n->range[OC_CH_SIGMA].lo, sig, 1e-7 * sig);
      assert_int_equal(oc_key_level(n->key), 13);
    } else if (dist_box_min(sp.sphere.c, lo, hi) > r) {
      outside++;
      assert_int_equal(n->kind, OC_NODE_EMPTY);
    } else {
      boundary++;
      assert_int_equal(oc_key_level(n->key), 13); /* refined wherever the footprint sees the surface */
    }
  }
  print_message("sphere r=%g m, level 13: %u leaves (%d interior, %d boundary, %d outside), %u bricks, %.3f s\n", r,
                s.node_count, interior, boundary, outside, s.brick_count, st.seconds);
  assert_true(interior > 10 && boundary > 10 && outside > 100);
  oc_state_free(&s);
}

static void test_voxelize__sphere_tau_matches_closed_form(void **state) {
  (void)state;
  const double r = 3000, sig = 0.03;
  ocs_prim_t sp;
  assert_int_equal(ocs_prim_sphere(&sp, (oc_geo_t){-20, 60, 4000}, r, sig), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &sp), 0);
  oc_dvec3 sun = oc_dnorm(oc_dv3(0.2, 0.9, -0.3));
  oc_state_t s;
  oc_state_init(&s);
  assert_int_equal(ocs_voxelize_medium(&s, &m, 12, 2, sun, 2), 0);
  assert_int_equal(oc_state_validate(&s, NULL, 0), 0);
  float sg[512], tu[512];
  long checked = 0, nonzero = 0, empty_far = 0;
  for (uint32_t i = 0; i < s.node_count; i++) {
    const oc_node_t *n = &s.nodes[i];
    node_values(&s, n, sg, tu);
    double rb = channel_rel_bound(n->range[OC_CH_TAU]);
    int all_zero = 1;
    for (int q = 0; q < 512; q++) {
      /* τ is point-sampled: the decoded sample equals the closed form at the sample position. */
      double t = ocs_medium_tau_sun(&m, ocs_brick_sample_pos(n->key, q % 8, (q / 8) % 8, q / 64), sun);
      double tol = (rb + 1.2e-7) * t + n->range[OC_CH_TAU].hi / OC_CODE_MAX_RATIO + 1e-30;
      if (fabs(tu[q] - t) > tol) fail_msg("node %u sample %d: tau %.9g closed form %.9g", i, q, tu[q], t);
      all_zero &= t == 0.0;
      nonzero += t > 0.0;
      checked++;
    }
    /* Far from the sphere and out of its shadow: nothing at all. */
    oc_dvec3 lo, hi;
    grown_box(n->key, &lo, &hi);
    if (all_zero && dist_box_min(sp.sphere.c, lo, hi) > r) {
      assert_int_equal(n->kind, OC_NODE_EMPTY);
      empty_far++;
    }
    /* σt inside: uniform in its channel. */
    if (dist_box_max(sp.sphere.c, lo, hi) < r) {
      assert_true(n->range[OC_CH_SIGMA].lo == n->range[OC_CH_SIGMA].hi);
      assert_near(n->range[OC_CH_SIGMA].lo, sig, 1e-7 * sig);
    }
  }
  print_message("sphere tau: %ld samples checked (%ld in shadow or inside), %ld far leaves empty\n", checked, nonzero,
                empty_far);
  assert_true(nonzero > 1000 && empty_far > 100);
  oc_state_free(&s);
}

/* ---- mean extinction preserved ---------------------------------------------------------------- */

static void test_voxelize__mean_preserved(void **state) {
  (void)state;
  /* A sphere centred in a level-10 node P, radius 0.3·size: P's box filter, its 8 children's and
   * its 64 grandchildren's must all integrate to σt·(4/3)πr³. */
  const int L = 10;
  const double sig = 0.05;
  oc_key_t P = oc_key_from_point(L, oc_geo_to_xyz((oc_geo_t){12, -70, 3000}));
  double size = oc_key_size(L), r = 0.3 * size;
  ocs_prim_t sp;
  assert_int_equal(ocs_prim_sphere(&sp, oc_xyz_to_geo(oc_key_center(P)), r, sig), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &sp), 0);
  ocs_medium_ctx_t mc = {&m, oc_dv3(1, 0, 0), 0.0};
  const double exact = sig * 4.0 / 3.0 * OC_PI * r * r * r;
  float v[512];
  double integ[3] = {0, 0, 0};
  for (int g = 0; g < 3; g++) {
    int nkeys = 1 << (3 * g);
    double cs = size / (double)(1 << g);
    for (int c = 0; c < nkeys; c++) {
      oc_key_t k = g == 0 ? P : g == 1 ? oc_key_child(P, c) : oc_key_child(oc_key_child(P, c >> 3), c & 7);
      ocs_brick_sample(k, ocs_medium_sigma_cb, &mc, 4, v);
      integ[g] += trapezoid_mean(v) * cs * cs * cs;
    }
  }
  print_message("mean preserved (box filter, sub 4): exact %.6e  P %+.3f%%  8 children %+.3f%%  "
                "64 grandchildren %+.3f%%\n",
                exact, 100 * (integ[0] / exact - 1), 100 * (integ[1] / exact - 1), 100 * (integ[2] / exact - 1));
  /* Stratified midpoints on a lattice of spacing size/28 (P), /56, /112: a sphere of radius 8.4,
   * 16.8, 33.6 lattice steps. */
  assert_near(integ[0] / exact, 1.0, 0.03);
  assert_near(integ[1] / exact, 1.0, 0.01);
  assert_near(integ[2] / exact, 1.0, 0.005);
  assert_near(integ[1] / integ[0], 1.0, 0.03);
  assert_near(integ[2] / integ[1], 1.0, 0.01);

  /* The same through the builder: leaves under P down to level 13, decoded. */
  oc_dvec3 blo, bhi;
  ocs_prim_bounds(&sp, &blo, &bhi);
  ocs_aabb_t box = {blo, bhi};
  ocs_voxelize_desc_t d = {0};
  d.sigma = ocs_medium_sigma_cb;
  d.tau = ocs_medium_tau_cb;
  d.ctx = &mc;
  d.max_level = 13;
  d.aabbs = &box;
  d.aabb_count = 1;
  d.sun_dir = mc.sun_dir;
  d.threads = 2;
  oc_state_t s;
  oc_state_init(&s);
  assert_int_equal(ocs_voxelize(&s, &d), 0);
  float sg[512], tu[512];
  double total = 0.0;
  int under = 0;
  for (uint32_t i = 0; i < s.node_count; i++) {
    const oc_node_t *n = &s.nodes[i];
    if (!oc_key_is_ancestor(P, n->key)) continue;
    under++;
    node_values(&s, n, sg, tu);
    double ls = oc_key_size(oc_key_level(n->key));
    total += trapezoid_mean(sg) * ls * ls * ls;
  }
  print_message("mean preserved (state, %d leaves under P to level 13): %+.4f%%\n", under, 100 * (total / exact - 1));
  assert_true(under >= 512);
  assert_near(total / exact, 1.0, 0.003);
  oc_state_free(&s);
}

/* ---- determinism across thread counts --------------------------------------------------------- */

static void test_voxelize__threads_identical(void **state) {
  (void)state;
  ocs_medium_t m;
  ocs_medium_init(&m);
  ocs_prim_t p;
  assert_int_equal(ocs_prim_sphere(&p, (oc_geo_t){5, 5, 3000}, 2500, 0.02), 0);
  assert_int_equal(ocs_medium_add(&m, &p), 0);
  assert_int_equal(ocs_prim_box(&p, (oc_geo_t){5.02, 5.01, 500}, 3000, 1000, 2000, 33, 0.07), 0);
  assert_int_equal(ocs_medium_add(&m, &p), 0);
  oc_dvec3 sun = oc_dnorm(oc_dv3(1, 0.3, 0.2));
  uint64_t sum[3];
  uint32_t nodes = 0, bricks = 0;
  for (int t = 1; t <= 3; t++) {
    oc_state_t s;
    double dt = voxelize_timed(&s, &m, 13, 3, sun, t);
    sum[t - 1] = oc_state_checksum(&s);
    print_message("threads %d: %u leaves, %u bricks, checksum %016llx, %.3f s\n", t, s.node_count, s.brick_count,
                  (unsigned long long)sum[t - 1], dt);
    if (t == 1) {
      nodes = s.node_count;
      bricks = s.brick_count;
    } else {
      assert_int_equal(s.node_count, nodes);
      assert_int_equal(s.brick_count, bricks);
    }
    oc_state_free(&s);
  }
  assert_true(bricks > 50);
  assert_true(sum[0] == sum[1]);
  assert_true(sum[0] == sum[2]);
}

/* ---- a slab: τ below it against the closed form ----------------------------------------------- */

static void test_voxelize__slab_tau_closed_form(void **state) {
  (void)state;
  const double base = 2000, top = 3000, sig = 0.01;
  ocs_prim_t sl;
  assert_int_equal(ocs_prim_slab(&sl, base, top, sig), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &sl), 0);
  oc_dvec3 p0 = oc_geo_to_xyz((oc_geo_t){-5, 100, 500});
  oc_enu_t enu = oc_enu_at(p0);
  const double zenith[3] = {0.0, 60.0, 85.0};
  for (int zi = 0; zi < 3; zi++) {
    double th = zenith[zi] * OC_DEG;
    oc_dvec3 sun = oc_dnorm(oc_dadd(oc_dscale(enu.up, cos(th)), oc_dscale(enu.east, sin(th))));
    ocs_medium_ctx_t mc = {&m, sun, 0.0};
    ocs_aabb_t region = {oc_dsub(p0, oc_dv3(3000, 3000, 3000)), oc_dadd(p0, oc_dv3(3000, 3000, 3000))};
    ocs_voxelize_desc_t d = {0};
    d.sigma = ocs_medium_sigma_cb;
    d.tau = ocs_medium_tau_cb;
    d.ctx = &mc;
    d.min_level = 3;
    d.max_level = 13;
    d.aabbs = &region; /* a slab is planet-wide: refine only here, and only near the slab */
    d.aabb_count = 1;
    d.refine = ocs_medium_refine_cb;
    d.sub_sigma = 2;
    d.sun_dir = sun;
    d.threads = 2;
    d.epoch = 7;
    ocs_voxelize_stats_t st;
    d.stats = &st;
    d.time = 12.5;
    oc_state_t s;
    oc_state_init(&s);
    assert_int_equal(ocs_voxelize(&s, &d), 0);
    assert_true(s.epoch == 7 && s.time == 12.5);
    long checked = 0;
    int in_region = 0;
    double worst = 0.0;
    float sg[512], tu[512];
    long double ro = OC_PLANET_RADIUS + top, ri = OC_PLANET_RADIUS + base;
    for (uint32_t i = 0; i < s.node_count; i++) {
      const oc_node_t *n = &s.nodes[i];
      oc_dvec3 o;
      double size;
      oc_key_bounds(n->key, &o, &size);
      in_region += o.x <= region.hi.x && o.x + size >= region.lo.x && o.y <= region.hi.y && o.y + size >= region.lo.y &&
                   o.z <= region.hi.z && o.z + size >= region.lo.z;
      node_values(&s, n, sg, tu);
      double rb = channel_rel_bound(n->range[OC_CH_TAU]);
      for (int q = 0; q < 512; q++) {
        oc_dvec3 p = ocs_brick_sample_pos(n->key, q % 8, (q / 8) % 8, q / 64);
        long double rp = sqrtl((long double)p.x * p.x + (long double)p.y * p.y + (long double)p.z * p.z);
        if (rp >= ri || rp < 1000.0L) continue; /* below the slab (inside the planet too: no shadow) */
        long double mu = ((long double)p.x * sun.x + (long double)p.y * sun.y + (long double)p.z * sun.z) / rp;
        long double s2 = 1.0L - mu * mu;
        long double to = sqrtl(ro * ro - rp * rp * s2) - rp * mu, ti = sqrtl(ri * ri - rp * rp * s2) - rp * mu;
        double t = (double)(sig * (to - ti));
        double tol = (rb + 1.2e-7) * t + n->range[OC_CH_TAU].hi / OC_CODE_MAX_RATIO;
        double e = fabs((double)tu[q] - t);
        if (e > tol)
          fail_msg("zenith %g node %u sample %d: tau %.9g, closed form %.9g, tol %.3g", zenith[zi], i, q, tu[q], t,
                   tol);
        if (t > 0 && e / t > worst) worst = e / t;
        checked++;
      }
    }
    print_message("slab tau, sun zenith %4.1f: %u leaves (%d meet the region), %ld samples below the slab, worst rel "
                  "err %.2e\n",
                  zenith[zi], s.node_count, in_region, checked, worst);
    assert_true(checked > 10000 && in_region > 8);
    /* Refined to max_level where the region meets the slab, coarse elsewhere. */
    assert_true(st.per_level[13] > 0 && st.per_level[3] > 0);
    assert_true(oc_state_find_leaf(&s, oc_key_from_point(21, p0)) >= 0);
    oc_state_free(&s);
  }
}

/* ---- ids, limits, arguments ------------------------------------------------------------------- */

static double blob_fn(void *ctx, oc_dvec3 p) {
  const oc_dvec3 *c = ctx;
  oc_dvec3 q = oc_dsub(p, *c);
  return oc_ddot(q, q) < 2.5e7 ? 0.01 : 0.0;
}

static void test_voxelize__brick_ids_and_limits(void **state) {
  (void)state;
  oc_dvec3 c = oc_geo_to_xyz((oc_geo_t){0, 0, 0});
  ocs_aabb_t box = {oc_dsub(c, oc_dv3(5000, 5000, 5000)), oc_dadd(c, oc_dv3(5000, 5000, 5000))};
  ocs_voxelize_desc_t d = {0};
  d.sigma = blob_fn;
  d.ctx = &c;
  d.min_level = 2;
  d.max_level = 11;
  d.aabbs = &box;
  d.aabb_count = 1;
  d.sub_sigma = 1;
  d.sun_dir = oc_dv3(0, 0, 2); /* normalised into the state */
  d.first_brick_id = 1000;
  oc_state_t s;
  oc_state_init(&s);
  assert_int_equal(ocs_voxelize(&s, &d), 0);
  assert_true(s.sun_dir.z == 1.0);
  assert_true(s.brick_count > 0);
  uint32_t next = 1000;
  for (uint32_t i = 0; i < s.node_count; i++) {
    if (i > 0) assert_true(s.nodes[i - 1].key < s.nodes[i].key);
    if (s.nodes[i].kind == OC_NODE_BRICK) assert_int_equal(s.nodes[i].brick_id, next++);
  }
  assert_int_equal(next - 1000, s.brick_count);
  /* Ids that would pass UINT32_MAX. */
  d.first_brick_id = UINT32_MAX - 1;
  assert_int_equal(ocs_voxelize(&s, &d), OC_ERANGE);
  assert_int_equal(s.node_count, 0); /* left empty */
  d.first_brick_id = 0;
  /* Too many leaves: refused while refining. */
  d.max_nodes = 100;
  assert_int_equal(ocs_voxelize(&s, &d), OC_ETOOBIG);
  assert_int_equal(s.node_count, 0);
  d.max_nodes = 0;
  ocs_aabb_t all = {oc_dv3(-1e7, -1e7, -1e7), oc_dv3(1e7, 1e7, 1e7)};
  d.aabbs = &all;
  d.min_level = 0;
  d.max_level = 9; /* 8^9 = 134M leaves > OC_STATE_MAX_NODES */
  double t0 = now_s();
  assert_int_equal(ocs_voxelize(&s, &d), OC_ETOOBIG);
  print_message("refusing a 134M-leaf tree took %.3f s\n", now_s() - t0);
  /* The whole cube at level 3 is exactly 512 leaves. */
  d.max_level = 3;
  d.max_nodes = 512;
  assert_int_equal(ocs_voxelize(&s, &d), 0);
  assert_int_equal(s.node_count, 512);
  d.max_nodes = 511;
  assert_int_equal(ocs_voxelize(&s, &d), OC_ETOOBIG);
  d.max_nodes = 0;
  /* Bad descriptions. */
  ocs_voxelize_desc_t b = d;
  b.sigma = NULL;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.min_level = 5;
  b.max_level = 4;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.max_level = 22;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.sun_dir = oc_dv3(0, 0, 0);
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.sub_sigma = OCS_VOXELIZE_MAX_SUB + 1;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.threads = OCS_VOXELIZE_MAX_THREADS + 1;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.aabb_count = 1;
  b.aabbs = NULL;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  b = d;
  b.time = NAN;
  assert_int_equal(ocs_voxelize(&s, &b), OC_EINVAL);
  assert_int_equal(ocs_voxelize(NULL, &d), OC_EINVAL);
  assert_int_equal(ocs_voxelize(&s, NULL), OC_EINVAL);
  /* No refinement at all: the uniform tree at min_level. */
  b = d;
  b.aabb_count = 0;
  b.aabbs = NULL;
  b.min_level = 2;
  b.max_level = 6;
  assert_int_equal(ocs_voxelize(&s, &b), 0);
  assert_int_equal(s.node_count, 64);
  oc_state_free(&s);
}

/* Untrusted field values are sanitised and counted. */
static double nasty_fn(void *ctx, oc_dvec3 p) {
  (void)ctx;
  return p.x > 0 ? NAN : (p.y > 0 ? -1.0 : (p.z > 0 ? INFINITY : 0.5));
}

static void test_voxelize__sanitises(void **state) {
  (void)state;
  ocs_voxelize_stats_t st;
  ocs_voxelize_desc_t d = {0};
  d.sigma = nasty_fn;
  d.tau = nasty_fn;
  d.min_level = 1;
  d.sub_sigma = 1;
  d.sun_dir = oc_dv3(1, 0, 0);
  d.stats = &st;
  oc_state_t s;
  oc_state_init(&s);
  assert_int_equal(ocs_voxelize(&s, &d), 0);
  assert_int_equal(oc_state_validate(&s, NULL, 0), 0);
  assert_true(st.sanitize.nan > 0 && st.sanitize.negative > 0 && st.sanitize.inf > 0);
  assert_int_equal(st.leaves, 8);
  oc_state_free(&s);
}

/* ---- measured figure -------------------------------------------------------------------------- */

static void test_voxelize__timing_level14(void **state) {
  (void)state;
  ocs_prim_t sp;
  assert_int_equal(ocs_prim_sphere(&sp, (oc_geo_t){45, 10, 5000}, 4000, 0.02), 0);
  ocs_medium_t m;
  ocs_medium_init(&m);
  assert_int_equal(ocs_medium_add(&m, &sp), 0);
  oc_dvec3 sun = oc_dnorm(oc_dv3(0.3, 0.4, 0.8));
  for (int t = 1; t <= 2; t++) {
    oc_state_t s;
    double dt = voxelize_timed(&s, &m, 14, 4, sun, t);
    print_message("sphere r=4 km, max_level 14 (790 m), sub 4, %d thread(s): %u leaves, %u bricks, %.3f s "
                  "(%.2f ms/brick)\n",
                  t, s.node_count, s.brick_count, dt, 1e3 * dt / (s.brick_count ? s.brick_count : 1));
    oc_state_free(&s);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_sample__positions_and_filter),
      cmocka_unit_test(test_sample__neighbour_faces_bit_identical),
      cmocka_unit_test(test_voxelize__sphere_interior_and_empty),
      cmocka_unit_test(test_voxelize__sphere_tau_matches_closed_form),
      cmocka_unit_test(test_voxelize__mean_preserved),
      cmocka_unit_test(test_voxelize__threads_identical),
      cmocka_unit_test(test_voxelize__slab_tau_closed_form),
      cmocka_unit_test(test_voxelize__brick_ids_and_limits),
      cmocka_unit_test(test_voxelize__sanitises),
      cmocka_unit_test(test_voxelize__timing_level14),
  };
  return cmocka_run_group_tests_name("voxelize", tests, NULL, NULL);
}

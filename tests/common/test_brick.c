/* test_brick.c — brick classification, 16-bit log codes and the shared decode header
 * (common/oc_brick.c, shaders/brick.h). */
#include <math.h>
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "test_util.h"
#include "report.h"

#include "brick.h"
#include "oc_brick.h"

/* shaders/brick.h and common/oc_brick.h describe one layout. */
_Static_assert(OCG_BRICK_EDGE == OC_BRICK_EDGE, "edge");
_Static_assert(OCG_BRICK_VOXELS == OC_BRICK_VOXELS, "voxels");
_Static_assert(OCG_CODE_MAX == OC_CODE_MAX, "code max");
_Static_assert(OCG_CODE_STEPS == OC_CODE_STEPS, "code steps");
_Static_assert(sizeof(oc_brick_codes_t) == OC_BRICK_CODE_BYTES, "codes");

/* Log-uniform in [a, b]. */
static float rng_log(double a, double b) { return (float)(a * pow(b / a, rng_unit())); }

static float dec(uint16_t c, oc_range_t r) { return ocg_code_decode(c, r.lo, r.hi); }

/* Checks one encoded channel: zeros stay exact, every kept value is within the range's bound and
 * its code is the best any code achieves, flushed values are below hi/OC_CODE_MAX_RATIO.
 * @return the largest relative error seen. */
static double check_channel(const float *v, const uint16_t *code, oc_range_t r, double *bound_out) {
  double bound = oc_code_rel_error_bound(r), worst = 0.0;
  for (int i = 0; i < OC_BRICK_VOXELS; i++) {
    float d = dec(code[i], r);
    if (v[i] == 0.0f) {
      assert_int_equal(code[i], 0);
      assert_true(d == 0.0f);
      continue;
    }
    if (code[i] == 0) {
      assert_true((double)v[i] < (double)r.hi / OC_CODE_MAX_RATIO);
      continue;
    }
    double e = fabs((double)d - (double)v[i]) / (double)v[i];
    if (e > worst) worst = e;
    assert_true(e <= bound);
    /* best achievable: neither neighbour decodes closer */
    double here = fabs((double)d - (double)v[i]);
    if (code[i] > 1) assert_true(fabs((double)dec((uint16_t)(code[i] - 1), r) - (double)v[i]) >= here);
    if (code[i] < OC_CODE_MAX) assert_true(fabs((double)dec((uint16_t)(code[i] + 1), r) - (double)v[i]) >= here);
  }
  if (bound_out) *bound_out = bound;
  return worst;
}

static void test_brick__round_trip_error(void **state) {
  (void)state;
  /* σt ratios inside one brick, up to the whole 1e-6..10 m⁻¹ span; τ up to the 1e9 limit. */
  static const double ratios[] = {1.001, 10.0, 1e3, 1e5, 1e7, 1e9};
  double overall = 0.0, overall_bound = 0.0;
  for (size_t ri = 0; ri < sizeof ratios / sizeof ratios[0]; ri++) {
    double R = ratios[ri], worst = 0.0, worst_bound = 0.0;
    for (int b = 0; b < 12; b++) {
      float sigma[OC_BRICK_VOXELS], tau[OC_BRICK_VOXELS];
      oc_brick_codes_t codes;
      oc_range_t range[OC_CHANNELS];
      /* σt: [a, a·R] inside 1e-6..10 when R allows; the 1e7 bricks hold 1e-6 and 10 together. */
      double smax = R <= 1e7 ? 10.0 / R : 1e-6, a = R >= 1e7 ? 1e-6 : rng_log(1e-6, smax);
      double ta = rng_log(1e-4, 1.0);
      for (int i = 0; i < OC_BRICK_VOXELS; i++) {
        sigma[i] = rng_unit() < 0.05 ? 0.0f : rng_log(a, a * R);
        tau[i] = rng_unit() < 0.05 ? 0.0f : rng_log(ta, ta * R);
      }
      sigma[1] = (float)a, sigma[2] = (float)(a * R);
      tau[1] = (float)ta, tau[2] = (float)(ta * R);
      assert_int_equal(oc_brick_encode(sigma, tau, &codes, range), OC_NODE_BRICK);
      float ds[OC_BRICK_VOXELS], dt[OC_BRICK_VOXELS];
      oc_brick_decode(&codes, range, ds, dt);
      for (int i = 0; i < OC_BRICK_VOXELS; i++) {
        assert_true(ds[i] == dec(codes.code[0][i], range[0]));
        assert_true(dt[i] == dec(codes.code[1][i], range[1]));
      }
      double bs, bt;
      double es = check_channel(sigma, codes.code[OC_CH_SIGMA], range[OC_CH_SIGMA], &bs);
      double et = check_channel(tau, codes.code[OC_CH_TAU], range[OC_CH_TAU], &bt);
      assert_true(bs <= 1.6e-4 && bt <= 1.6e-4);
      if (es > worst) worst = es;
      if (et > worst) worst = et;
      if (bs > worst_bound) worst_bound = bs;
      if (bt > worst_bound) worst_bound = bt;
    }
    printf("  ratio %-8g: max relative error %.4e (bound %.4e, quantisation alone %.4e)\n", R, worst, worst_bound,
           expm1(log(R) / (2.0 * OC_CODE_STEPS)));
    if (worst > overall) overall = worst;
    if (worst_bound > overall_bound) overall_bound = worst_bound;
  }
  printf("  σt/τ round trip over random bricks: max relative error %.4e, largest bound %.4e\n", overall, overall_bound);
}

/* The worst case on purpose: values at the midpoints between neighbouring decoded codes of the
 * largest allowed ratio, where the nearest code is as far as it can be. */
static void test_brick__worst_case_midpoints(void **state) {
  (void)state;
  oc_range_t r = {1e-3f, 1e6f}; /* hi/lo = 1e9 = OC_CODE_MAX_RATIO */
  double bound = oc_code_rel_error_bound(r), worst = 0.0;
  assert_true(bound <= 1.6e-4);
  assert_true(bound >= expm1(log(1e9) / (2.0 * OC_CODE_STEPS)) * 0.999);
  for (int n = 0; n < 20000; n++) {
    uint16_t c = (uint16_t)(1 + rng_u64() % (OC_CODE_MAX - 1));
    float a = dec(c, r), b = dec((uint16_t)(c + 1), r);
    assert_true(a <= b);
    float v = (float)(0.5 * ((double)a + (double)b));
    uint16_t e = oc_code_encode(v, r);
    double err = fabs((double)dec(e, r) - (double)v) / (double)v;
    assert_true(err <= bound);
    if (err > worst) worst = err;
  }
  printf("  ratio 1e9 midpoints: max relative error %.4e, bound %.4e (1.6e-4 allowed)\n", worst, bound);
  oc_report("codes", "σt code round trip, worst case (1e9 range in one brick)", worst, 1.6e-4, "rel");
  assert_true(worst > 1.5e-4); /* the test does reach the worst case */
}

/* The encoder decides most values from their position among the codes alone, where that lies
 * farther than the decoder's rounding from a code and from a midpoint (oc__encode_log); its code
 * must still be the nearest one the decoder gives, ties to the lower, as the decoded search picks.
 * Values at random, at the linear midpoints of two neighbours and a float either side of them, and
 * beside a decoded code, over ratios 2 to 1e9. */
static void check_nearest(float v, oc_range_t r) {
  uint16_t c = oc_code_encode(v, r);
  double here = fabs((double)dec(c, r) - (double)v);
  if (c > 1) assert_true(fabs((double)dec((uint16_t)(c - 1), r) - (double)v) > here);
  if (c < OC_CODE_MAX) assert_true(fabs((double)dec((uint16_t)(c + 1), r) - (double)v) >= here);
}

static void test_brick__nearest_code(void **state) {
  (void)state;
  const float hi[] = {2.0f, 10.0f, 1e3f, 1e6f, 1e9f};
  for (int k = 0; k < 5; k++) {
    oc_range_t r = {1.0f, hi[k]};
    for (int n = 0; n < 40000; n++) {
      uint16_t c = (uint16_t)(1 + rng_u64() % (OC_CODE_MAX - 1));
      float a = dec(c, r), b = dec((uint16_t)(c + 1), r);
      float mid = (float)(0.5 * ((double)a + (double)b)), w = (float)(rng_u64() % 1000000) * 1e-6f;
      check_nearest(a + (b - a) * w, r);
      check_nearest(mid, r);
      check_nearest(nextafterf(mid, 0.0f), r);
      check_nearest(nextafterf(mid, INFINITY), r);
      check_nearest(nextafterf(a, INFINITY), r);
    }
  }
}

/* oc_all_zero: +0 everywhere, and nothing else passes (−0, a denormal, NaN), wherever it sits. */
static void test_brick__all_zero(void **state) {
  (void)state;
  float v[OC_BRICK_VOXELS] = {0};
  assert_true(oc_all_zero(v, OC_BRICK_VOXELS));
  const float bad[] = {-0.0f, 1e-45f, NAN, 1.0f};
  const int at[] = {0, 7, 8, 300, OC_BRICK_VOXELS - 1};
  for (int b = 0; b < 4; b++)
    for (int a = 0; a < 5; a++) {
      v[at[a]] = bad[b];
      assert_false(oc_all_zero(v, OC_BRICK_VOXELS));
      v[at[a]] = 0.0f;
    }
  assert_false(oc_all_zero(NULL, 1));
}

static void test_brick__zero_exact(void **state) {
  (void)state;
  float s[OC_BRICK_VOXELS], t[OC_BRICK_VOXELS], ds[OC_BRICK_VOXELS], dt[OC_BRICK_VOXELS];
  oc_brick_codes_t codes;
  oc_range_t r[OC_CHANNELS];
  for (int i = 0; i < OC_BRICK_VOXELS; i++) {
    s[i] = (i % 3) ? 0.0f : 0.01f * (float)(1 + i % 17);
    t[i] = (i % 5) ? 0.0f : 3.0f * (float)(1 + i % 7);
  }
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  oc_brick_decode(&codes, r, ds, dt);
  for (int i = 0; i < OC_BRICK_VOXELS; i++) {
    assert_true((s[i] == 0.0f) == (ds[i] == 0.0f));
    assert_true((t[i] == 0.0f) == (dt[i] == 0.0f));
    if (s[i] == 0.0f) assert_int_equal(codes.code[0][i], OC_CODE_ZERO);
  }
  /* code 0 is zero whatever the range; a zero range decodes everything to zero without NaN */
  assert_true(ocg_code_decode(0u, 1.0f, 2.0f) == 0.0f);
  assert_true(ocg_code_decode(1234u, 0.0f, 0.0f) == 0.0f);
  assert_true(ocg_code_decode(65535u, 0.0f, 5.0f) == 0.0f);
  assert_true(ocg_code_decode(7u, NAN, 5.0f) == 0.0f);
}

static void test_brick__decode_endpoints(void **state) {
  (void)state;
  /* lo == hi decodes to exactly lo for every code */
  for (uint32_t c = 1; c <= OC_CODE_MAX; c++) assert_true(ocg_code_decode(c, 0.0375f, 0.0375f) == 0.0375f);
  /* code 1 is lo exactly; code 65535 is hi within decoder rounding */
  static const float los[] = {1e-6f, 3.3e-5f, 0.25f, 7.0f};
  static const double rs[] = {1.5, 1e3, 1e7, 1e9};
  for (int a = 0; a < 4; a++)
    for (int b = 0; b < 4; b++) {
      float lo = los[a], hi = (float)(los[a] * rs[b]);
      assert_true(ocg_code_decode(1u, lo, hi) == lo);
      assert_true(fabs((double)ocg_code_decode(65535u, lo, hi) - hi) <= 2e-6 * hi);
    }
  /* corrupt ranges cannot make Inf or NaN */
  float x = ocg_code_decode(65535u, 1e-38f, 3e38f);
  assert_true(isfinite(x) && x > 0.0f);
  x = ocg_code_decode(65535u, 1e-45f, 3.4e38f);
  assert_true(isfinite(x) && x >= 0.0f);
  x = ocg_code_decode(100u, 2.0f, 1.0f); /* hi < lo: treated as uniform */
  assert_true(x == 2.0f);
}

static void test_brick__code_encode_edges(void **state) {
  (void)state;
  oc_range_t r = {0.5f, 8.0f};
  assert_int_equal(oc_code_encode(0.0f, r), 0);
  assert_int_equal(oc_code_encode(-1.0f, r), 0);
  assert_int_equal(oc_code_encode(NAN, r), 0);
  assert_int_equal(oc_code_encode(0.5f, r), 1);
  assert_int_equal(oc_code_encode(8.0f, r), OC_CODE_MAX);
  assert_int_equal(oc_code_encode(100.0f, r), OC_CODE_MAX);       /* above hi: the top code */
  assert_int_equal(oc_code_encode(0.3f, r), 1);                   /* below lo, nearer lo than 0 */
  assert_int_equal(oc_code_encode(0.2f, r), 0);                   /* below lo, nearer 0 */
  assert_int_equal(oc_code_encode(2.0f, (oc_range_t){0, 0}), 0);  /* zero range */
  assert_int_equal(oc_code_encode(2.0f, (oc_range_t){2, 2}), 1);  /* uniform range */
  /* below hi/1e9 flushes to 0 even where lo would be nearer than 0 */
  assert_int_equal(oc_code_encode(9e-8f, (oc_range_t){1.5e-7f, 100.0f}), 0);
  assert_int_equal(oc_code_encode(1.1e-7f, (oc_range_t){1.5e-7f, 100.0f}), 1);
  /* tiny ratios: many codes decode to one float, the bracket search still finds the best */
  oc_range_t t = {1.0f, 1.0001f};
  for (int i = 0; i <= 100; i++) {
    float v = 1.0f + 1e-6f * (float)i;
    uint16_t c = oc_code_encode(v, t);
    double here = fabs((double)dec(c, t) - v);
    for (uint32_t k = 1; k <= OC_CODE_MAX; k += 97) assert_true(fabs((double)dec((uint16_t)k, t) - v) >= here);
    assert_true(here <= 1.2e-7 * v);
  }
}

static void test_brick__flush_below_ratio(void **state) {
  (void)state;
  float s[OC_BRICK_VOXELS], t[OC_BRICK_VOXELS], ds[OC_BRICK_VOXELS], dt[OC_BRICK_VOXELS];
  oc_brick_codes_t codes;
  oc_range_t r[OC_CHANNELS];
  for (int i = 0; i < OC_BRICK_VOXELS; i++) s[i] = t[i] = 1.0f;
  s[0] = 10.0f;   /* hi: flush threshold 1e-8 */
  s[1] = 5e-9f;   /* below: exact zero */
  s[2] = 2e-8f;   /* above: kept, becomes lo */
  s[3] = 9.9e-9f; /* just below */
  t[0] = 2.0f;
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  assert_true(r[0].hi == 10.0f && r[0].lo == 2e-8f);
  assert_true((double)r[0].hi / (double)r[0].lo <= OC_CODE_MAX_RATIO);
  oc_brick_decode(&codes, r, ds, dt);
  assert_int_equal(codes.code[0][1], 0);
  assert_int_equal(codes.code[0][3], 0);
  assert_true(ds[1] == 0.0f && ds[3] == 0.0f);
  assert_true(ds[2] == 2e-8f); /* lo is code 1, exact */
  /* the absolute error of a flushed value is below hi / OC_CODE_MAX_RATIO */
  assert_true(fabs((double)ds[3] - s[3]) < (double)r[0].hi / OC_CODE_MAX_RATIO);
}

static void fill(float *v, float x) {
  for (int i = 0; i < OC_BRICK_VOXELS; i++) v[i] = x;
}

static void test_brick__classify(void **state) {
  (void)state;
  float s[OC_BRICK_VOXELS], t[OC_BRICK_VOXELS], ds[OC_BRICK_VOXELS], dt[OC_BRICK_VOXELS];
  oc_brick_codes_t codes;
  oc_range_t r[OC_CHANNELS];

  fill(s, 0.0f), fill(t, 0.0f);
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_EMPTY);
  assert_true(r[0].lo == 0 && r[0].hi == 0 && r[1].lo == 0 && r[1].hi == 0);
  assert_int_equal(oc_brick_encode(s, t, NULL, r), OC_NODE_EMPTY);

  /* σt zero but τ non-zero (a clear node in a cloud's shadow) is not empty */
  fill(t, 0.5f);
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_UNIFORM);
  assert_true(r[0].lo == 0 && r[0].hi == 0 && r[1].lo == 0.5f && r[1].hi == 0.5f);
  t[100] = 0.7f;
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  for (int i = 0; i < OC_BRICK_VOXELS; i++) assert_int_equal(codes.code[0][i], 0);

  /* uniform σt with varying τ is a brick; σt decodes to its value exactly */
  fill(s, 0.02f);
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  assert_true(r[0].lo == 0.02f && r[0].hi == 0.02f);
  oc_brick_decode(&codes, r, ds, dt);
  for (int i = 0; i < OC_BRICK_VOXELS; i++) assert_true(ds[i] == 0.02f);
  assert_int_equal(oc_brick_encode(s, t, NULL, r), OC_NODE_BRICK);

  /* varying σt with uniform τ likewise */
  fill(t, 3.0f);
  s[7] = 0.03f;
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  assert_true(r[1].lo == 3.0f && r[1].hi == 3.0f);

  /* both uniform within OC_UNIFORM_TOL: one node, the channel means */
  for (int i = 0; i < OC_BRICK_VOXELS; i++) s[i] = (i & 1) ? 1.0f : 1.000005f;
  fill(t, 3.0f);
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_UNIFORM);
  assert_true(r[0].lo == r[0].hi && r[0].lo > 1.0f && r[0].lo < 1.000005f);
  /* just above the tolerance: a brick */
  s[0] = 1.00002f;
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  /* a zero among equal values breaks uniformity */
  fill(s, 1.0f);
  s[5] = 0.0f;
  assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
  assert_true(r[0].lo == 1.0f && r[0].hi == 1.0f);
  assert_int_equal(codes.code[0][5], 0);
  assert_int_equal(codes.code[0][6], 1);

  /* one value anywhere makes a channel non-zero (the all-zero check reads every one); −0 and
   * negatives alone still make it zero */
  const int at[] = {0, 7, 8, 255, OC_BRICK_VOXELS - 1};
  for (int a = 0; a < (int)(sizeof at / sizeof at[0]); a++) {
    fill(s, 0.0f), fill(t, 0.0f);
    s[at[a]] = 0.25f;
    assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
    assert_true(r[0].hi == 0.25f && codes.code[0][at[a]] != 0);
    fill(s, 0.0f);
    t[at[a]] = 4.0f;
    assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_BRICK);
    assert_true(r[1].hi == 4.0f && r[0].hi == 0.0f);
    t[at[a]] = -0.0f, s[at[a]] = -1.0f;
    assert_int_equal(oc_brick_encode(s, t, &codes, r), OC_NODE_EMPTY);
  }
}

static void test_brick__sanitize(void **state) {
  (void)state;
  float v[] = {NAN, INFINITY, -INFINITY, -1.0f, -0.0f, 2e9f, 0.5f, 0.0f, -NAN, -3e-30f};
  oc_sanitize_stats_t st = {0, 0, 0};
  oc_sanitize(v, (int)(sizeof v / sizeof v[0]), &st);
  assert_int_equal(st.nan, 2);
  assert_int_equal(st.inf, 2);
  assert_int_equal(st.negative, 2);
  assert_true(v[0] == 0.0f && v[1] == OC_VALUE_MAX && v[2] == 0.0f && v[3] == 0.0f);
  assert_true(v[4] == 0.0f && !signbit(v[4]));
  assert_true(v[5] == OC_VALUE_MAX && v[6] == 0.5f && v[7] == 0.0f && v[8] == 0.0f && v[9] == 0.0f);
  /* counts accumulate; NULL stats is fine */
  float w[] = {NAN};
  oc_sanitize(w, 1, &st);
  assert_int_equal(st.nan, 3);
  w[0] = NAN;
  oc_sanitize(w, 1, NULL);
  assert_true(w[0] == 0.0f);
  /* a clean brick is left as it is (the whole-brick fast path), and one value that is not, anywhere
   * in it, is still found: −0, a tiny negative, just above OC_VALUE_MAX, ±Inf, NaN */
  const float bad[] = {-0.0f, -1e-30f, nextafterf(OC_VALUE_MAX, INFINITY), INFINITY, -INFINITY, NAN};
  const int at[] = {0, 7, 255, OC_BRICK_VOXELS - 1};
  for (int b = 0; b < (int)(sizeof bad / sizeof bad[0]); b++)
    for (int a = 0; a < (int)(sizeof at / sizeof at[0]); a++) {
      float c[OC_BRICK_VOXELS];
      fill(c, 0.25f);
      c[1] = OC_VALUE_MAX, c[2] = 0.0f, c[3] = 1e-38f;
      c[at[a]] = bad[b];
      oc_sanitize(c, OC_BRICK_VOXELS, NULL);
      float want = bad[b] > 0.0f ? OC_VALUE_MAX : 0.0f;
      assert_true(c[at[a]] == want && !signbit(c[at[a]]));
      for (int i = 0; i < OC_BRICK_VOXELS; i++) {
        if (i == at[a]) continue;
        float keep = i == 1 ? OC_VALUE_MAX : i == 2 ? 0.0f : i == 3 ? 1e-38f : 0.25f;
        assert_true(c[i] == keep && !signbit(c[i]));
      }
    }
  /* an unsanitised brick still encodes without NaN ranges */
  float s[OC_BRICK_VOXELS], t[OC_BRICK_VOXELS];
  oc_range_t r[OC_CHANNELS];
  fill(s, 0.1f), fill(t, 0.0f);
  s[3] = NAN;
  s[4] = INFINITY;
  assert_int_equal(oc_brick_encode(s, t, NULL, r), OC_NODE_BRICK);
  assert_true(isfinite(r[0].lo) && isfinite(r[0].hi) && r[0].hi == OC_VALUE_MAX);
}

static void test_brick__reconstruct(void **state) {
  (void)state;
  assert_int_equal(ocg_brick_voxel(0, 0, 0), 0);
  assert_int_equal(ocg_brick_voxel(7, 0, 0), 7);
  assert_int_equal(ocg_brick_voxel(0, 1, 0), 8);
  assert_int_equal(ocg_brick_voxel(0, 0, 1), 64);
  assert_int_equal(ocg_brick_voxel(7, 7, 7), 511);

  ocg_vec3 u = ocg_v3(0.5f, 1.0f, -0.25f), b = ocg_brick_base(u), f = ocg_brick_frac(u, b);
  assert_true(b.x == 3.0f && f.x == 0.5f);
  assert_true(b.y == 6.0f && f.y == 1.0f); /* u = 1: last cell, fraction 1 */
  assert_true(b.z == 0.0f && f.z == 0.0f); /* clamped */
  assert_int_equal(ocg_brick_base_voxel(b), 3 + 8 * 6);
  u = ocg_v3(1.5f, 0.0f, 1.0f / 7.0f);
  b = ocg_brick_base(u);
  f = ocg_brick_frac(u, b);
  assert_true(b.x == 6.0f && f.x == 1.0f && b.y == 0.0f && f.y == 0.0f);
  assert_true(f.z >= 0.0f && f.z <= 1.0f && b.z <= 1.0f);

  /* corners reproduce exactly; a trilinear function is reproduced everywhere */
  ocg_vec4 z0 = ocg_v4(1, 2, 3, 4), z1 = ocg_v4(5, 6, 7, 8);
  static const float corner[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  for (int q = 0; q < 8; q++)
    assert_true(ocg_trilerp(z0, z1, ocg_v3((float)(q & 1), (float)((q >> 1) & 1), (float)(q >> 2))) == corner[q]);
  /* v = 1 + x + 2y + 4z + xyz */
  z0 = ocg_v4(1, 2, 3, 4);
  z1 = ocg_v4(5, 6, 7, 9);
  for (int n = 0; n < 1000; n++) {
    float x = (float)rng_unit(), y = (float)rng_unit(), z = (float)rng_unit();
    double want = 1.0 + x + 2.0 * y + 4.0 * z + (double)x * y * z;
    assert_true(fabs(ocg_trilerp(z0, z1, ocg_v3(x, y, z)) - want) < 1e-5);
  }
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_brick__round_trip_error),
             cmocka_unit_test(test_brick__worst_case_midpoints),
             cmocka_unit_test(test_brick__nearest_code),
             cmocka_unit_test(test_brick__all_zero),
             cmocka_unit_test(test_brick__zero_exact),
             cmocka_unit_test(test_brick__decode_endpoints),
             cmocka_unit_test(test_brick__code_encode_edges),
             cmocka_unit_test(test_brick__flush_below_ratio),
             cmocka_unit_test(test_brick__classify),
             cmocka_unit_test(test_brick__sanitize),
             cmocka_unit_test(test_brick__reconstruct))

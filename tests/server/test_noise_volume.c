/* test_noise_volume.c — server/noise_volume: texels against the periodic fBm they sample, mips
 * against the means they stand for, fetches against their texels, and bounds against a dense
 * search inside random boxes (with a check that the search would catch a bound 0.8× as wide). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "noise_volume.h"
#include "oc_err.h"
#include "test_main.h"
#include "test_util.h" /* rng_split */

static const ocs_nvol_desc_t DESC = {5, 4, {.octaves = 4, .lacunarity = 2.0, .gain = 0.5, .seed = 11}};

static ocs_nvol_t *make(const ocs_nvol_desc_t *d) {
  ocs_nvol_t *v = NULL;
  char why[128] = "";
  if (ocs_nvol_create(d, &v, why, sizeof why) < 0) fail_msg("%s", why);
  return v;
}

static double rng_range(uint64_t *s, double lo, double hi) { return lo + (hi - lo) * rng_split_unit(s); }

/* Level 0 is the periodic fBm at the texel centres, bit for bit, and a second build is the same
 * bytes at every level. */
static void test_texels_are_the_fbm(void **state) {
  (void)state;
  ocs_nvol_t *v = make(&DESC), *w = make(&DESC);
  int n = 1 << DESC.log2_size;
  double h = ocs_nvol_texel(v, 0);
  assert_true(fabs(h - (double)DESC.period / n) < 1e-15);
  const float *t = ocs_nvol_texels(v, 0);
  for (int i = 0; i < n * n * n; i += 97) {
    int x = i % n, y = i / n % n, z = i / (n * n);
    float want = (float)oc_fbm3_periodic((x + 0.5) * h, (y + 0.5) * h, (z + 0.5) * h, &DESC.fbm, DESC.period);
    assert_true(t[i] == want);
  }
  for (int m = 0; m < ocs_nvol_levels(v); m++) {
    size_t k = (size_t)n >> m;
    assert_memory_equal(ocs_nvol_texels(v, m), ocs_nvol_texels(w, m), k * k * k * sizeof(float));
  }
  ocs_nvol_destroy(v);
  ocs_nvol_destroy(w);
}

/* Each mip texel is the mean of the level-0 texels under it (to float rounding), the last level the
 * mean of the whole tile. */
static void test_mips_are_means(void **state) {
  (void)state;
  ocs_nvol_t *v = make(&DESC);
  int n = 1 << DESC.log2_size;
  const float *t0 = ocs_nvol_texels(v, 0);
  for (int m = 1; m < ocs_nvol_levels(v); m++) {
    int k = n >> m, b = 1 << m;
    const float *t = ocs_nvol_texels(v, m);
    for (int j = 0; j < k * k * k; j += 1 + k * k * k / 50) {
      int x = j % k, y = j / k % k, z = j / (k * k);
      double sum = 0.0;
      for (int c = 0; c < b * b * b; c++)
        sum += t0[((size_t)(z * b + c / (b * b)) * n + (size_t)(y * b + c / b % b)) * n + (size_t)(x * b + c % b)];
      assert_true(fabs(t[j] - sum / (b * b * b)) < 1e-6);
    }
  }
  ocs_nvol_destroy(v);
}

/* A fetch at a texel centre is the texel; a fetch one tile away is the same fetch (to the rounding of
 * the coordinate); level 0 at 4 texels per finest lattice cell stays near the fBm between centres. */
static void test_fetch(void **state) {
  (void)state;
  ocs_nvol_t *v = make(&DESC);
  int n = 1 << DESC.log2_size;
  uint64_t rs = 3;
  double worst_tile = 0.0, worst_fbm = 0.0;
  for (int m = 0; m < ocs_nvol_levels(v); m++) {
    int k = n >> m;
    double h = ocs_nvol_texel(v, m);
    const float *t = ocs_nvol_texels(v, m);
    for (int j = 0; j < 40; j++) {
      int i = (int)(rng_split(&rs) % (uint64_t)(k * k * k));
      double p[3] = {(i % k + 0.5) * h, (i / k % k + 0.5) * h, (i / (k * k) + 0.5) * h};
      assert_true(fabs(ocs_nvol_fetch(v, m, p) - t[i]) < 1e-7);
      double q[3] = {rng_range(&rs, -30, 30), rng_range(&rs, -30, 30), rng_range(&rs, -30, 30)}, r[3];
      for (int a = 0; a < 3; a++) r[a] = q[a] + DESC.period * (double)(1 + (int)(rng_split(&rs) % 3));
      worst_tile = fmax(worst_tile, fabs(ocs_nvol_fetch(v, m, q) - ocs_nvol_fetch(v, m, r)));
      if (m == 0) worst_fbm = fmax(worst_fbm, fabs(ocs_nvol_fetch(v, 0, q) - oc_fbm3_periodic(q[0], q[1], q[2], &DESC.fbm, DESC.period)));
    }
  }
  printf("fetch: largest change over whole tiles %.3g; level 0 against the fBm, largest %.3f\n", worst_tile, worst_fbm);
  assert_true(worst_tile < 1e-5);
  assert_true(worst_fbm < 0.15);
  ocs_nvol_destroy(v);
}

/* Bounds at every level over random boxes from a hundredth of a texel to more than a tile: the
 * fetches at the box's corners and at random points inside stay within them. The search must also
 * find values outside each bound shrunk about its middle to 0.8× its width in a good share of the
 * boxes: a bound loose enough to survive that is not what the pyramid promises. */
static void test_bound_holds(void **state) {
  (void)state;
  ocs_nvol_t *v = make(&DESC);
  uint64_t rs = 5;
  int boxes = SIZE(400, 120), pts = SIZE(400, 120), outside = 0, caught = 0, total = 0;
  double fill = 0.0;
  for (int m = 0; m < ocs_nvol_levels(v); m++)
    for (int b = 0; b < boxes; b++) {
      double a[3], c[3], size = ocs_nvol_texel(v, 0) * exp(rng_range(&rs, log(0.01), log(1.5 * 32.0)));
      for (int k = 0; k < 3; k++) a[k] = rng_range(&rs, -100, 100), c[k] = a[k] + size * rng_range(&rs, 0.3, 1.0);
      float lo, hi;
      ocs_nvol_bound(v, m, a, c, &lo, &hi);
      double mid = 0.5 * (lo + hi), half = 0.4 * (hi - lo), seen_lo = INFINITY, seen_hi = -INFINITY;
      for (int i = 0; i < pts + 8; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = i < 8 ? (i >> k & 1 ? c[k] : a[k]) : rng_range(&rs, a[k], c[k]);
        double f = ocs_nvol_fetch(v, m, p);
        outside += f < lo || f > hi;
        seen_lo = fmin(seen_lo, f), seen_hi = fmax(seen_hi, f);
      }
      caught += seen_lo < mid - half || seen_hi > mid + half;
      fill += hi > lo ? (seen_hi - seen_lo) / (hi - lo) : 1.0;
      total++;
    }
  printf("bounds: %d boxes, %d values outside; a 0.8x bound caught in %d (%.0f %%); the search spans %.0f %% of "
         "the bound on average\n",
         total, outside, caught, 100.0 * caught / total, 100.0 * fill / total);
  assert_int_equal(outside, 0);
  assert_true(caught > total / 4);
  ocs_nvol_destroy(v);
}

static void test_bad_descriptions(void **state) {
  (void)state;
  ocs_nvol_t *v = (ocs_nvol_t *)&v;
  char why[128];
  ocs_nvol_desc_t d = DESC;
  d.log2_size = OCS_NVOL_MAX_LOG2 + 1;
  assert_int_equal(ocs_nvol_create(&d, &v, why, sizeof why), OC_EINVAL);
  assert_null(v);
  assert_non_null(strstr(why, "log2_size"));
  d = DESC, d.period = 0;
  assert_int_equal(ocs_nvol_create(&d, &v, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "period"));
  d = DESC, d.period = 64;
  assert_int_equal(ocs_nvol_create(&d, &v, why, sizeof why), OC_EINVAL);
  d = DESC, d.period = 3;
  assert_int_equal(ocs_nvol_create(&d, &v, why, sizeof why), OC_EINVAL);
  d = DESC, d.fbm.lacunarity = 3.0;
  assert_int_equal(ocs_nvol_create(&d, &v, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "lacunarity"));
  assert_int_equal(ocs_nvol_create(NULL, &v, why, sizeof why), OC_EINVAL);
  ocs_nvol_destroy(NULL);
}

OC_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_texels_are_the_fbm), cmocka_unit_test(test_mips_are_means),
             cmocka_unit_test(test_fetch), cmocka_unit_test(test_bound_holds), cmocka_unit_test(test_bad_descriptions))

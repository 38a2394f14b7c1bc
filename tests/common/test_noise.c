/* test_noise.c — determinism, bound, continuity and statistics of common/oc_noise. */
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "oc_err.h"
#include "oc_noise.h"

/* Test-local deterministic RNG (splitmix64). */
static uint64_t rng_next(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static double rng_unit(uint64_t *s) { return (double)(rng_next(s) >> 11) * (1.0 / 9007199254740992.0); }
static double rng_range(uint64_t *s, double lo, double hi) { return lo + (hi - lo) * rng_unit(s); }

static uint32_t fbits(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u;
}

static const oc_fbm_t FBM6 = {.octaves = 6, .lacunarity = 2.0, .gain = 0.5, .seed = 7};

/* ---- Golden values: an accidental change to the hash, gradients, fade or scale fails here. ----
 * Same bits from gcc 12 and clang 14 at -O0..-O3 (no libm in the kernel). If a change to the
 * noise is intended, it changes every procedural field: update these and say so in the change. */

typedef struct {
  double x, y, z;
  uint64_t seed;
  double want;
} golden_t;

static const golden_t GOLDEN_NOISE[] = {
    {0.5, 0.5, 0.5, 1, -0x1.ee096d1cebc12p-4},
    {1.25, -2.75, 3.125, 1, 0x1.21c4a5a045f4ap-3},
    {-7.3, 0.1, 12.9, 42, -0x1.f121542f8e792p-5},
    {1.0e7 + 0.37, -1.0e7 + 0.61, 0.5e7 + 0.29, 1, -0x1.0df06e5fbfb59p-2},
    {123.456, 789.012, -345.678, 0xFFFFFFFFFFFFFFFFull, 0x1.4097aee9ccfdp-2},
};
static const golden_t GOLDEN_FBM[] = {
    {0.5, 0.5, 0.5, 7, 0x1.160f58627acffp-4},
    {1.25, -2.75, 3.125, 7, -0x1.9cac622b772a3p-6},
    {1.0e7 + 0.37, -1.0e7 + 0.61, 0.5e7 + 0.29, 7, -0x1.7b87f18ff53ebp-3},
};

static void test_golden(void **state) {
  (void)state;
  for (size_t i = 0; i < sizeof GOLDEN_NOISE / sizeof *GOLDEN_NOISE; i++) {
    const golden_t *g = &GOLDEN_NOISE[i];
    double v = oc_noise3(g->x, g->y, g->z, g->seed);
    if (v != g->want) fail_msg("noise golden %zu: got %a (%.17g), want %a", i, v, v, g->want);
  }
  for (size_t i = 0; i < sizeof GOLDEN_FBM / sizeof *GOLDEN_FBM; i++) {
    const golden_t *g = &GOLDEN_FBM[i];
    oc_fbm_t p = FBM6;
    p.seed = g->seed;
    double v = oc_fbm3(g->x, g->y, g->z, &p);
    if (v != g->want) fail_msg("fbm golden %zu: got %a (%.17g), want %a", i, v, v, g->want);
  }
}

/* ---- Batch paths give the scalar bits (whatever clone the CPU picked). ---- */

static void fill_points(double *xyz, int n, uint64_t s) {
  for (int i = 0; i < n; i++) {
    /* Mix of small, negative, near-integer and large coordinates. */
    double scale = (i % 4 == 0) ? 1e7 : (i % 4 == 1) ? 1e3 : (i % 4 == 2) ? 10.0 : 1.0;
    for (int k = 0; k < 3; k++) {
      double v = rng_range(&s, -scale, scale);
      if (i % 16 == 3) v = floor(v); /* exactly on the lattice */
      if (i % 16 == 5) v = floor(v) + 1e-12;
      xyz[3 * i + k] = v;
    }
  }
}

static void test_batch_matches_scalar(void **state) {
  (void)state;
  enum { N = 100003 }; /* not a multiple of any vector width or of the fBm chunk */
  double *xyz = malloc(sizeof(double) * 3 * N);
  float *out = malloc(sizeof(float) * N);
  assert_non_null(xyz);
  assert_non_null(out);
  fill_points(xyz, N, 99);
  assert_int_equal(oc_noise3_batch(xyz, N, 5, out), 0);
  for (int i = 0; i < N; i++) {
    float want = (float)oc_noise3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], 5);
    if (fbits(out[i]) != fbits(want)) fail_msg("noise batch %d: %a vs scalar %a", i, out[i], want);
  }
  enum { M = 2000 + 37 };
  assert_int_equal(oc_fbm3_batch(xyz, M, &FBM6, out), 0);
  for (int i = 0; i < M; i++) {
    float want = (float)oc_fbm3(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], &FBM6);
    if (fbits(out[i]) != fbits(want)) fail_msg("fbm batch %d: %a vs scalar %a", i, out[i], want);
  }
  free(xyz);
  free(out);
}

/* ---- Same bits on 1 and 2 threads. ---- */

enum { GRID = 48, GRID_N = GRID * GRID * GRID };

typedef struct {
  const double *xyz;
  float *out;
  int lo, hi;
  int fbm;
} job_t;

static void *run_job(void *arg) {
  job_t *j = arg;
  if (j->fbm)
    oc_fbm3_batch(j->xyz + 3 * (size_t)j->lo, j->hi - j->lo, &FBM6, j->out + j->lo);
  else
    oc_noise3_batch(j->xyz + 3 * (size_t)j->lo, j->hi - j->lo, 11, j->out + j->lo);
  return NULL;
}

static void test_threads(void **state) {
  (void)state;
  double *xyz = malloc(sizeof(double) * 3 * GRID_N);
  float *one = malloc(sizeof(float) * GRID_N), *two = malloc(sizeof(float) * GRID_N);
  assert_true(xyz && one && two);
  for (int k = 0, i = 0; k < GRID; k++)
    for (int jy = 0; jy < GRID; jy++)
      for (int ix = 0; ix < GRID; ix++, i++) {
        xyz[3 * i] = -3.0 + ix * (6.0 / 7.0) * 0.3;
        xyz[3 * i + 1] = 1e6 + jy * 0.17;
        xyz[3 * i + 2] = -250.5 + k * 0.29;
      }
  for (int fbm = 0; fbm < 2; fbm++) {
    job_t all = {xyz, one, 0, GRID_N, fbm};
    run_job(&all);
    /* Two threads, split at an odd index so the halves' vector alignment differs. */
    job_t a = {xyz, two, 0, GRID_N / 2 + 3, fbm}, b = {xyz, two, GRID_N / 2 + 3, GRID_N, fbm};
    pthread_t ta, tb;
    assert_int_equal(pthread_create(&ta, NULL, run_job, &a), 0);
    assert_int_equal(pthread_create(&tb, NULL, run_job, &b), 0);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    assert_memory_equal(one, two, sizeof(float) * GRID_N);
    /* And a second run gives the same bits again. */
    run_job(&all);
    assert_memory_equal(one, two, sizeof(float) * GRID_N);
  }
  free(xyz);
  free(one);
  free(two);
}

/* ---- Bound, statistics ---- */

typedef struct {
  double min, max, mean, sd;
} stats_t;

static stats_t noise_stats(int n, double cx, double cy, double cz, double half, uint64_t seed, uint64_t rs) {
  stats_t st = {1e9, -1e9, 0, 0};
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; i++) {
    double x = cx + rng_range(&rs, -half, half), y = cy + rng_range(&rs, -half, half),
           z = cz + rng_range(&rs, -half, half);
    double v = oc_noise3(x, y, z, seed);
    if (!(v >= -1.0 && v <= 1.0)) fail_msg("noise(%.17g, %.17g, %.17g) = %.17g outside [-1, 1]", x, y, z, v);
    st.min = v < st.min ? v : st.min;
    st.max = v > st.max ? v : st.max;
    sum += v;
    sum2 += v * v;
  }
  st.mean = sum / n;
  st.sd = sqrt(sum2 / n - st.mean * st.mean);
  return st;
}

static void test_bound(void **state) {
  (void)state;
  stats_t st = noise_stats(1000000, 0, 0, 0, 1000.0, 3, 1234);
  printf("noise over 1e6 points: min %.4f max %.4f mean %.5f sd %.4f\n", st.min, st.max, st.mean, st.sd);
  assert_true(st.max > 0.6 && st.min < -0.6); /* the range is actually used */
  /* Where the unscaled bound is reached: cell point (0.355, 0.481, 0.5) and its mirror images,
   * over many cells (so many gradient combinations). */
  uint64_t rs = 77;
  double worst = 0;
  for (int i = 0; i < 200000; i++) {
    double c[3] = {floor(rng_range(&rs, -1e5, 1e5)), floor(rng_range(&rs, -1e5, 1e5)), floor(rng_range(&rs, -1e5, 1e5))};
    double f[3] = {0.35525671, 0.48149221, 0.5};
    /* a random permutation and mirroring of the cell point */
    int perm = (int)(rng_next(&rs) % 6), flip = (int)(rng_next(&rs) % 8);
    static const int P[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = c[k] + ((flip >> k & 1) ? 1.0 - f[P[perm][k]] : f[P[perm][k]]);
    double v = fabs(oc_noise3(p[0], p[1], p[2], 9));
    assert_true(v <= 1.0);
    worst = v > worst ? v : worst;
  }
  printf("noise at the extremal cell points: max |n| %.4f\n", worst);
  /* fBm stays in the bound too. */
  rs = 5;
  for (int i = 0; i < 100000; i++) {
    double v = oc_fbm3(rng_range(&rs, -1e4, 1e4), rng_range(&rs, -1e4, 1e4), rng_range(&rs, -1e4, 1e4), &FBM6);
    assert_true(v >= -1.0 && v <= 1.0);
  }
}

static void test_lattice_zero(void **state) {
  (void)state;
  uint64_t rs = 8;
  for (int i = 0; i < 10000; i++) {
    double x = floor(rng_range(&rs, -1e7, 1e7)), y = floor(rng_range(&rs, -1e7, 1e7)), z = floor(rng_range(&rs, -1e7, 1e7));
    assert_true(oc_noise3(x, y, z, (uint64_t)i) == 0.0);
  }
  /* -0.0 and +0.0 are the same lattice point: no seam at the origin. */
  assert_true(oc_noise3(-0.0, 0.3, 0.7, 1) == oc_noise3(0.0, 0.3, 0.7, 1));
}

static void check_lipschitz(double cx, double cy, double cz, double half, uint64_t rs) {
  static const double steps[] = {1e-1, 1e-3, 1e-6};
  double worst = 0;
  for (int i = 0; i < 100000; i++) {
    double p[3] = {cx + rng_range(&rs, -half, half), cy + rng_range(&rs, -half, half), cz + rng_range(&rs, -half, half)};
    double d[3] = {rng_range(&rs, -1, 1), rng_range(&rs, -1, 1), rng_range(&rs, -1, 1)};
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (len < 1e-3) continue;
    double h = steps[i % 3];
    double q[3];
    for (int k = 0; k < 3; k++) q[k] = p[k] + d[k] / len * h;
    double dist = sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]));
    double dv = fabs(oc_noise3(q[0], q[1], q[2], 4) - oc_noise3(p[0], p[1], p[2], 4));
    /* allowance for the rounding of a few dozen double operations */
    if (dv > OC_NOISE_LIPSCHITZ * dist + 1e-12)
      fail_msg("|dn| = %.3g over %.3g at (%.17g, %.17g, %.17g)", dv, dist, p[0], p[1], p[2]);
    if (dist > 0 && dv / dist > worst) worst = dv / dist;
  }
  printf("largest |dn|/|dp| near (%g, %g, %g): %.3f (bound %.1f)\n", cx, cy, cz, worst, OC_NOISE_LIPSCHITZ);
}

static void test_continuity(void **state) {
  (void)state;
  check_lipschitz(0, 0, 0, 50.0, 21);
  /* Across cell faces: a tiny step over an integer gives a tiny change. */
  uint64_t rs = 22;
  for (int i = 0; i < 10000; i++) {
    double x = floor(rng_range(&rs, -1e4, 1e4)), y = rng_range(&rs, -1e4, 1e4), z = rng_range(&rs, -1e4, 1e4);
    double a = oc_noise3(x - 1e-9, y, z, 2), b = oc_noise3(x + 1e-9, y, z, 2);
    assert_true(fabs(a - b) <= OC_NOISE_LIPSCHITZ * 2e-9 + 1e-12);
  }
}

static void test_seed_changes_field(void **state) {
  (void)state;
  uint64_t seeds[][2] = {{1, 2}, {0, 1}, {1, 0x8000000000000001ull}, {0xFFFFFFFFFFFFFFFFull, 0}};
  for (size_t s = 0; s < sizeof seeds / sizeof *seeds; s++) {
    uint64_t rs = 31;
    double sab = 0, saa = 0, sbb = 0;
    int same = 0, n = 20000;
    for (int i = 0; i < n; i++) {
      double x = rng_range(&rs, -100, 100), y = rng_range(&rs, -100, 100), z = rng_range(&rs, -100, 100);
      double a = oc_noise3(x, y, z, seeds[s][0]), b = oc_noise3(x, y, z, seeds[s][1]);
      same += a == b;
      sab += a * b;
      saa += a * a;
      sbb += b * b;
    }
    double r = sab / sqrt(saa * sbb);
    printf("seeds %llu/%llu: correlation %.4f, equal %d of %d\n", (unsigned long long)seeds[s][0],
           (unsigned long long)seeds[s][1], r, same, n);
    assert_true(fabs(r) < 0.05);
    assert_true(same < n / 100);
  }
}

static void test_large_coordinates(void **state) {
  (void)state;
  stats_t o = noise_stats(200000, 0, 0, 0, 100.0, 6, 40);
  static const double centres[][3] = {{1e7, 1e7, 1e7}, {-1e7, 1e7, -1e7}, {6.4e6, -3.1e6, 2.2e6}, {-1e9, 3e9, 1e12}};
  for (size_t c = 0; c < sizeof centres / sizeof *centres; c++) {
    stats_t st = noise_stats(200000, centres[c][0], centres[c][1], centres[c][2], 100.0, 6, 41 + c);
    printf("near (%g, %g, %g): min %.3f max %.3f mean %.4f sd %.4f (origin sd %.4f)\n", centres[c][0], centres[c][1],
           centres[c][2], st.min, st.max, st.mean, st.sd, o.sd);
    assert_true(st.sd > 0.8 * o.sd && st.sd < 1.25 * o.sd);
    assert_true(fabs(st.mean) < 0.01);
  }
  check_lipschitz(1e7, -1e7, 1e7, 50.0, 42);
  check_lipschitz(-6.4e9, 1e9, 3e9, 50.0, 43);
}

static void test_fbm_mean(void **state) {
  (void)state;
  uint64_t rs = 50;
  int n = 200000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; i++) {
    double v = oc_fbm3(rng_range(&rs, -1e4, 1e4), rng_range(&rs, -1e4, 1e4), rng_range(&rs, -1e4, 1e4), &FBM6);
    sum += v;
    sum2 += v * v;
  }
  double mean = sum / n, sd = sqrt(sum2 / n - mean * mean);
  printf("fbm (6 octaves, 2.0, 0.5): mean %.5f sd %.4f\n", mean, sd);
  assert_true(fabs(mean) < 0.005);
  assert_true(sd > 0.05);
  /* The octaves do not line up on the integer lattice. */
  assert_true(oc_fbm3(3.0, 4.0, 5.0, &FBM6) != 0.0);
  /* One octave is exactly one offset noise: the weighted mean of a single term is that term. */
  oc_fbm_t one = FBM6;
  one.octaves = 1;
  double v = oc_fbm3(0.3, 0.4, 0.5, &one);
  assert_true(v >= -1 && v <= 1);
}

static void test_args(void **state) {
  (void)state;
  float out[4];
  double xyz[12] = {0};
  assert_int_equal(oc_noise3_batch(xyz, -1, 0, out), OC_EINVAL);
  assert_int_equal(oc_noise3_batch(NULL, 4, 0, out), OC_EINVAL);
  assert_int_equal(oc_noise3_batch(xyz, 4, 0, NULL), OC_EINVAL);
  assert_int_equal(oc_noise3_batch(NULL, 0, 0, NULL), 0);
  oc_fbm_t p = FBM6;
  assert_int_equal(oc_fbm_check(&p), 0);
  assert_int_equal(oc_fbm_check(NULL), OC_EINVAL);
  p.octaves = 0;
  assert_int_equal(oc_fbm_check(&p), OC_EINVAL);
  assert_true(oc_fbm3(1.5, 2.5, 3.5, &p) == 0.0);
  assert_int_equal(oc_fbm3_batch(xyz, 4, &p, out), OC_EINVAL);
  p.octaves = OC_FBM_MAX_OCTAVES + 1;
  assert_int_equal(oc_fbm_check(&p), OC_EINVAL);
  p = FBM6;
  p.gain = NAN;
  assert_int_equal(oc_fbm_check(&p), OC_EINVAL);
  p = FBM6;
  p.lacunarity = 0.0;
  assert_int_equal(oc_fbm_check(&p), OC_EINVAL);
  p = FBM6;
  p.octaves = OC_FBM_MAX_OCTAVES;
  assert_int_equal(oc_fbm3_batch(xyz, 4, &p, out), 0);
  /* Non-finite input: no crash, no UB (the value is unspecified). */
  (void)oc_noise3(NAN, INFINITY, -INFINITY, 1);
  (void)oc_noise3(1e300, -1e300, 0, 1);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_golden),          cmocka_unit_test(test_batch_matches_scalar),
      cmocka_unit_test(test_threads),         cmocka_unit_test(test_bound),
      cmocka_unit_test(test_lattice_zero),    cmocka_unit_test(test_continuity),
      cmocka_unit_test(test_seed_changes_field), cmocka_unit_test(test_large_coordinates),
      cmocka_unit_test(test_fbm_mean),        cmocka_unit_test(test_args),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}

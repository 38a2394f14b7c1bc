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

#include "test_main.h"
#include "test_util.h" /* rng_split */
#include "oc_err.h"
#include "oc_noise.h"

/* Uniform in [lo, hi) from a seeded stream. */
static double rng_range(uint64_t *s, double lo, double hi) { return lo + (hi - lo) * rng_split_unit(s); }

/* FULL (test_util.h): optimised builds prove the Lipschitz bound at full resolution; unoptimised
 * or sanitised ones (the CI's ASan+UBSan stage) run the same code coarsely. */

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

/* The fBm in two passes (oc_fbm3_batch_octaves, oc_fbm3_batch_finish) is oc_fbm3_batch() bit for
 * bit at every split, and oc_fbm3_batch_top() of a partial sum is at least the value (equal when
 * nothing is left), for 3- and 6-octave fBms over 100 003 points. The top is tight enough to fail
 * with the rest's amplitude × 0.8: some point comes within 0.2 × the last octave of it. */
static void test_fbm_two_passes(void **state) {
  (void)state;
  enum { N = 100003 };
  double *xyz = malloc(sizeof(double) * 3 * N), *sum = malloc(sizeof(double) * N);
  float *want = malloc(sizeof(float) * N), *got = malloc(sizeof(float) * N), *top = malloc(sizeof(float) * N);
  assert_true(xyz && sum && want && got && top);
  fill_points(xyz, N, 41);
  const oc_fbm_t three = {.octaves = 3, .lacunarity = 2.0, .gain = 0.5, .seed = 9};
  const oc_fbm_t *fbms[2] = {&three, &FBM6};
  for (int f = 0; f < 2; f++) {
    const oc_fbm_t *p = fbms[f];
    assert_int_equal(oc_fbm3_batch(xyz, N, p, want), 0);
    for (int j = 0; j <= p->octaves; j++) {
      for (int i = 0; i < N; i++) sum[i] = 0.0;
      assert_int_equal(oc_fbm3_batch_octaves(xyz, N, p, 0, j, sum), 0);
      assert_int_equal(oc_fbm3_batch_top(sum, N, p, j, top), 0);
      assert_int_equal(oc_fbm3_batch_octaves(xyz, N, p, j, p->octaves, sum), 0);
      assert_int_equal(oc_fbm3_batch_finish(sum, N, p, got), 0);
      double close = INFINITY, last = ldexp(1.0, -(p->octaves - 1)) / (2.0 - ldexp(1.0, -(p->octaves - 1)));
      for (int i = 0; i < N; i++) {
        if (fbits(got[i]) != fbits(want[i])) fail_msg("fbm split %d at %d: %a vs %a", j, i, got[i], want[i]);
        if (!(top[i] >= want[i])) fail_msg("fbm top after %d octaves at %d: %a below the value %a", j, i, top[i], want[i]);
        if (j == p->octaves && fbits(top[i]) != fbits(want[i])) fail_msg("fbm top of the full sum at %d", i);
        close = fmin(close, (double)top[i] - (double)want[i]);
      }
      /* the last octave alone: some point's value comes within 0.2 of its amplitude of the top */
      if (j == p->octaves - 1 && !(close < 0.2 * last))
        fail_msg("fbm %d octaves: the top is %g above every value (last octave %g)", p->octaves, close, last);
    }
  }
  assert_int_equal(oc_fbm3_batch_octaves(xyz, N, &three, 2, 1, sum), OC_EINVAL);
  assert_int_equal(oc_fbm3_batch_octaves(xyz, N, &three, 0, 4, sum), OC_EINVAL);
  assert_int_equal(oc_fbm3_batch_top(sum, N, &three, 4, top), OC_EINVAL);
  free(xyz), free(sum), free(want), free(got), free(top);
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
    int perm = (int)(rng_split(&rs) % 6), flip = (int)(rng_split(&rs) % 8);
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

/* oc_fbm3_periodic(): repeats with its period on each axis, has oc_fbm3()'s spread, and refuses
 * what cannot wrap (a fractional lacunarity, a period < 1). */
static void test_fbm_periodic(void **state) {
  (void)state;
  uint64_t rs = 51;
  const int period = 4;
  double worst = 0.0, sum = 0.0, sum2 = 0.0, sum2f = 0.0;
  int n = 50000;
  for (int i = 0; i < n; i++) {
    double x = rng_range(&rs, -50, 50), y = rng_range(&rs, -50, 50), z = rng_range(&rs, -50, 50);
    double v = oc_fbm3_periodic(x, y, z, &FBM6, period), f = oc_fbm3(x, y, z, &FBM6);
    int k = (int)(rng_split(&rs) % 3), w = 1 + (int)(rng_split(&rs) % 4);
    double s[3] = {x, y, z};
    s[k] += (double)(w * period) * (rng_split(&rs) & 1 ? 1.0 : -1.0);
    worst = fmax(worst, fabs(oc_fbm3_periodic(s[0], s[1], s[2], &FBM6, period) - v));
    sum += v, sum2 += v * v, sum2f += f * f;
  }
  double sd = sqrt(sum2 / n - (sum / n) * (sum / n)), sdf = sqrt(sum2f / n);
  printf("periodic fBm: largest change over a period %.3g; sd %.4f against oc_fbm3's %.4f\n", worst, sd, sdf);
  assert_true(worst < 1e-9); /* rounding of x·f + offset only */
  assert_true(fabs(sd / sdf - 1.0) < 0.1);
  assert_true(oc_fbm3_periodic(0.3, 0.4, 0.5, &FBM6, period) != oc_fbm3_periodic(1.3, 0.4, 0.5, &FBM6, period));
  oc_fbm_t frac = FBM6;
  frac.lacunarity = 2.5;
  assert_true(oc_fbm3_periodic(0.3, 0.4, 0.5, &frac, period) == 0.0);
  assert_true(oc_fbm3_periodic(0.3, 0.4, 0.5, &FBM6, 0) == 0.0);
  assert_true(oc_fbm3_periodic(0.3, 0.4, 0.5, &FBM6, 3) == 0.0); /* not a power of two */
  /* the batch gives the scalar's bits */
  double xyz[3 * 64];
  float out[64];
  for (int i = 0; i < 3 * 64; i++) xyz[i] = rng_range(&rs, -20, 20);
  assert_int_equal(oc_fbm3_periodic_batch(xyz, 64, &FBM6, period, out), 0);
  for (int i = 0; i < 64; i++) assert_true(out[i] == (float)oc_fbm3_periodic(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2], &FBM6, period));
  assert_int_equal(oc_fbm3_periodic_batch(xyz, 64, &FBM6, 6, out), OC_EINVAL);
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

/* ---- The Lipschitz bound: proven, and tight (oc_noise.h, docs/numerics.md "Noise") ----------
 *
 * Inside a cell, with weights w_c = Π fade(·) of the corners c and b_c = f − c, the noise is
 * S·Σ_c w_c (g_c·b_c) (S = 1/1.03636), so its derivative along a unit d is S·Σ_c g_c·v_c with
 * v_c = (d·∇w_c) b_c + w_c d. Over all gradient configurations the largest derivative along d is
 * Φ(f, d) = S·Σ_c max_g g·v_c (each corner's gradient independent), and the Lipschitz constant is
 * the supremum of Φ over the cell and the unit sphere (the field is C² across cell faces). Φ is
 * convex and positively homogeneous in d (a sum of maxima of linear functions), so over the cone of
 * a spherical triangle p, q, r it is at most max(Φ(p), Φ(q), Φ(r)) / h, h the distance from the
 * origin to the triangle's plane: the supremum over the sphere is bounded by the vertices of a
 * subdivided icosahedron. For each vertex direction, a branch and bound over the cell with interval
 * arithmetic bounds Φ; the cell's symmetries (reflections f → 1 − f, with d) and Φ(f, −d) = Φ(f, d)
 * restrict it to f in [0, ½]³. The supremum is reached at the cell's centre along an axis, where
 * every corner contributes 15/32: Φ = 3.75·S = 3.6184. */

typedef struct {
  double lo, hi;
} iv_t;

static iv_t iv_add(iv_t a, iv_t b) { return (iv_t){a.lo + b.lo, a.hi + b.hi}; }
static iv_t iv_mul(iv_t a, iv_t b) {
  double p[4] = {a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi};
  iv_t r = {p[0], p[0]};
  for (int i = 1; i < 4; i++) r.lo = fmin(r.lo, p[i]), r.hi = fmax(r.hi, p[i]);
  return r;
}
static iv_t iv_scale(iv_t a, double k) { return k >= 0.0 ? (iv_t){a.lo * k, a.hi * k} : (iv_t){a.hi * k, a.lo * k}; }

static double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }
static double dfade(double t) { return 30.0 * t * t * (1.0 - t) * (1.0 - t); }
/* dfade rises on [0, ½] and falls on [½, 1] */
static iv_t dfade_iv(double a, double b) {
  double fa = dfade(a), fb = dfade(b), hi = (a <= 0.5 && b >= 0.5) ? dfade(0.5) : fmax(fa, fb);
  return (iv_t){fmin(fa, fb), hi};
}

/* Perlin's 12 cube-edge gradients (the other 4 of the 16 repeat them). */
static const double GRAD[12][3] = {{1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0}, {1, 0, 1}, {-1, 0, 1},
                                   {1, 0, -1}, {-1, 0, -1}, {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1}};

/* An upper bound of Φ(f, d) / S over the box lo ≤ f ≤ hi (interval arithmetic; exact for a point). */
static double phi_ub(const double lo[3], const double hi[3], const double d[3]) {
  iv_t w[3][2], dw[3][2];
  for (int k = 0; k < 3; k++) {
    iv_t f1 = {fade(lo[k]), fade(hi[k])}, df = dfade_iv(lo[k], hi[k]);
    w[k][1] = f1, w[k][0] = (iv_t){1.0 - f1.hi, 1.0 - f1.lo};
    dw[k][1] = df, dw[k][0] = (iv_t){-df.hi, -df.lo};
  }
  double total = 0.0;
  for (int c = 0; c < 8; c++) {
    int b[3] = {c & 1, c >> 1 & 1, c >> 2 & 1};
    iv_t wc = iv_mul(iv_mul(w[0][b[0]], w[1][b[1]]), w[2][b[2]]);
    iv_t a[3] = {iv_mul(iv_mul(dw[0][b[0]], w[1][b[1]]), w[2][b[2]]), iv_mul(iv_mul(w[0][b[0]], dw[1][b[1]]), w[2][b[2]]),
                 iv_mul(iv_mul(w[0][b[0]], w[1][b[1]]), dw[2][b[2]])};
    iv_t da = iv_add(iv_add(iv_scale(a[0], d[0]), iv_scale(a[1], d[1])), iv_scale(a[2], d[2]));
    iv_t v[3];
    for (int k = 0; k < 3; k++) v[k] = iv_add(iv_mul(da, (iv_t){lo[k] - b[k], hi[k] - b[k]}), iv_scale(wc, d[k]));
    double best = -INFINITY;
    for (int g = 0; g < 12; g++) {
      double sum = 0.0;
      for (int k = 0; k < 3; k++) sum += GRAD[g][k] > 0 ? v[k].hi : GRAD[g][k] < 0 ? -v[k].lo : 0.0;
      best = fmax(best, sum);
    }
    total += best;
  }
  return total;
}

/* The vertices of an icosahedron subdivided `levels` times (unit vectors), and the least distance
 * from the origin to one of its triangles' planes. @return the vertex count. */
static int icosphere(int levels, double (*v)[3], int cap, double *hmin) {
  static const int F0[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  double t = (1.0 + sqrt(5.0)) / 2.0;
  double P[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                     {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  int nv = 12, nf = 20;
  static int F[20 * 4 * 4 * 4 * 4 * 4][3];
  for (int i = 0; i < 12; i++) {
    double n = sqrt(P[i][0] * P[i][0] + P[i][1] * P[i][1] + P[i][2] * P[i][2]);
    for (int k = 0; k < 3; k++) v[i][k] = P[i][k] / n;
  }
  memcpy(F, F0, sizeof F0);
  for (int l = 0; l < levels; l++) {
    int nf2 = 0;
    static int G[20 * 4 * 4 * 4 * 4 * 4][3];
    for (int f = 0; f < nf; f++) {
      int m[3];
      for (int e = 0; e < 3; e++) { /* edge midpoints (duplicated between faces: harmless) */
        int a = F[f][e], b = F[f][(e + 1) % 3];
        assert_true(nv < cap);
        double n = 0.0;
        for (int k = 0; k < 3; k++) v[nv][k] = v[a][k] + v[b][k], n += v[nv][k] * v[nv][k];
        for (int k = 0; k < 3; k++) v[nv][k] /= sqrt(n);
        m[e] = nv++;
      }
      int T[4][3] = {{F[f][0], m[0], m[2]}, {m[0], F[f][1], m[1]}, {m[2], m[1], F[f][2]}, {m[0], m[1], m[2]}};
      memcpy(&G[nf2], T, sizeof T);
      nf2 += 4;
    }
    memcpy(F, G, sizeof(int) * 3 * (size_t)nf2);
    nf = nf2;
  }
  *hmin = 1.0;
  for (int f = 0; f < nf; f++) { /* plane through the three: distance |n·p| / |n| */
    double *a = v[F[f][0]], *b = v[F[f][1]], *c = v[F[f][2]], e1[3], e2[3], n[3];
    for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1], n[1] = e1[2] * e2[0] - e1[0] * e2[2], n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double h = fabs(n[0] * a[0] + n[1] * a[1] + n[2] * a[2]) / sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    *hmin = fmin(*hmin, h);
  }
  return nv;
}

/* Branch and bound of Φ(·, d)/S over [0, ½]³ against a target: boxes whose bound exceeds it are
 * halved along their longest side down to `smallest`; what is left above the target at that
 * size is returned (else the target itself). *boxes counts the bounds evaluated. */
static double bound_direction(const double d[3], double target, double smallest, long *boxes) {
  enum { STACK = 4096 };
  static double st[STACK][6];
  int top = 0;
  double worst = target;
  st[top][0] = st[top][1] = st[top][2] = 0.0;
  st[top][3] = st[top][4] = st[top][5] = 0.5;
  top++;
  while (top > 0) {
    double *b = st[--top], lo[3] = {b[0], b[1], b[2]}, hi[3] = {b[3], b[4], b[5]};
    double ub = phi_ub(lo, hi, d);
    (*boxes)++;
    if (ub <= target) continue;
    int k = 0;
    for (int a = 1; a < 3; a++)
      if (hi[a] - lo[a] > hi[k] - lo[k]) k = a;
    if (hi[k] - lo[k] <= smallest || top + 2 > STACK) {
      worst = fmax(worst, ub);
      continue;
    }
    double mid = 0.5 * (lo[k] + hi[k]);
    for (int h = 0; h < 2; h++) {
      double *n = st[top++];
      for (int a = 0; a < 3; a++) n[a] = lo[a], n[3 + a] = hi[a];
      if (h) n[k] = mid; else n[3 + k] = mid;
    }
  }
  return worst;
}

/* The proof: a certified upper bound of the noise's Lipschitz constant, at most OC_NOISE_LIPSCHITZ,
 * and above the value at the known maximiser (a check of the interval code). */
static void test_lipschitz_proven(void **state) {
  (void)state;
  static double dirs[12 + 20 * 3 * (1 + 4 + 16 + 64 + 256)][3];
  double hmin;
  /* unoptimised and sanitised builds run the same code on a coarse sphere and target (seconds
   * instead of minutes); the constant itself is checked by the optimised build */
  int nd = icosphere(FULL ? 3 : 1, dirs, (int)(sizeof dirs / sizeof *dirs), &hmin);
  const double S = 1.0 / 1.03636, target = FULL ? 4.0 : 5.0;
  double worst = 0.0;
  long boxes = 0;
  for (int i = 0; i < nd; i++) worst = fmax(worst, bound_direction(dirs[i], target, 1.0 / 4096, &boxes));
  double proven = worst / hmin * S * (1.0 + 1e-9); /* 1e-9: the rounding of the interval arithmetic */
  double centre[3] = {0.5, 0.5, 0.5}, ex[3] = {1, 0, 0};
  double at_max = phi_ub(centre, centre, ex) * S;
  printf("Lipschitz: %d directions (triangle planes at ≥ %.6f), %ld boxes: sup |∇n| ≤ %.5f; at the cell's centre "
         "along x %.5f (3.75·S); OC_NOISE_LIPSCHITZ %.4f\n", nd, hmin, boxes, proven, at_max, OC_NOISE_LIPSCHITZ);
  assert_true(fabs(at_max - 3.75 * S) < 1e-12);
  assert_true(proven >= at_max);
  if (FULL) assert_true(proven <= OC_NOISE_LIPSCHITZ);
}

/* The adversarial search, on the kernel itself (oc_noise3_cell): at random points and directions of
 * a cell, each corner's gradient chosen to steepen the field along the direction (the best of the
 * 16 for that corner), then climbed; the difference quotient over a small step must stay within
 * OC_NOISE_LIPSCHITZ, and it reaches more than 0.8 of it: the constant is tight, so a constant
 * lowered to 0.8× its proven value fails here. */
static void test_lipschitz_adversarial(void **state) {
  (void)state;
  uint64_t rs = 77;
  double worst = 0.0;
  const double h = 1e-6;
  for (int start = 0; start < 400; start++) {
    double f[3], d[3];
    for (int k = 0; k < 3; k++) f[k] = rng_split_unit(&rs), d[k] = rng_range(&rs, -1, 1);
    double step = 0.05, best = 0.0;
    for (int it = 0; it < 400; it++) {
      double f2[3], d2[3], n = 0.0;
      for (int k = 0; k < 3; k++) {
        f2[k] = fmin(1.0 - h, fmax(0.0, f[k] + (it ? step * rng_range(&rs, -1, 1) : 0.0)));
        d2[k] = d[k] + (it ? step * rng_range(&rs, -1, 1) : 0.0);
        n += d2[k] * d2[k];
      }
      for (int k = 0; k < 3; k++) d2[k] /= sqrt(n);
      /* each corner's steepest gradient along d2 at f2: the 16 tried one corner at a time */
      unsigned char g[8] = {0};
      double q[3] = {f2[0] + h * d2[0], f2[1] + h * d2[1], f2[2] + h * d2[2]};
      for (int c = 0; c < 8; c++) {
        double top = -INFINITY;
        int arg = 0;
        for (int gi = 0; gi < 16; gi++) {
          g[c] = (unsigned char)gi;
          double dn = oc_noise3_cell(g, q[0], q[1], q[2]) - oc_noise3_cell(g, f2[0], f2[1], f2[2]);
          if (dn > top) top = dn, arg = gi;
        }
        g[c] = (unsigned char)arg;
      }
      double slope = fabs(oc_noise3_cell(g, q[0], q[1], q[2]) - oc_noise3_cell(g, f2[0], f2[1], f2[2])) / h;
      if (slope > best) {
        best = slope;
        memcpy(f, f2, sizeof f);
        memcpy(d, d2, sizeof d);
      } else {
        step *= 0.98;
      }
    }
    worst = fmax(worst, best);
  }
  printf("adversarial search: largest difference quotient %.5f, bound %.4f (%.1f %% of it)\n", worst, OC_NOISE_LIPSCHITZ,
         100.0 * worst / OC_NOISE_LIPSCHITZ);
  assert_true(worst <= OC_NOISE_LIPSCHITZ * (1.0 + 1e-6));
  assert_true(worst > 0.8 * OC_NOISE_LIPSCHITZ);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_golden),
             cmocka_unit_test(test_batch_matches_scalar),
             cmocka_unit_test(test_fbm_two_passes),
             cmocka_unit_test(test_threads),
             cmocka_unit_test(test_bound),
             cmocka_unit_test(test_lattice_zero),
             cmocka_unit_test(test_continuity),
             cmocka_unit_test(test_seed_changes_field),
             cmocka_unit_test(test_large_coordinates),
             cmocka_unit_test(test_fbm_mean),
             cmocka_unit_test(test_fbm_periodic),
             cmocka_unit_test(test_args),
             cmocka_unit_test(test_lipschitz_proven),
             cmocka_unit_test(test_lipschitz_adversarial))

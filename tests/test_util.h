/* test_util.h — helpers shared by the test programs (header-only). */
#ifndef OC_TESTS_UTIL_H
#define OC_TESTS_UTIL_H

#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* Optimised builds run a test's full workload; unoptimised or sanitised ones (the CI's ASan+UBSan
 * stage is a Debug build) the same code paths on a smaller one: SIZE(full, smoke). */
#if defined(__OPTIMIZE__) && !defined(__SANITIZE_ADDRESS__)
#define FULL 1
#else
#define FULL 0
#endif
#define SIZE(full, smoke) (FULL ? (full) : (smoke))

/* xorshift64*: deterministic across platforms, unlike rand(). One stream per test program. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static inline uint64_t rng_u64(void) {
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return rng_state * 2685821657736338717ull;
}
/* Uniform in [0, 1) with 53 random bits. */
static inline double rng_unit(void) { return (double)(rng_u64() >> 11) * (1.0 / 9007199254740992.0); }

/* splitmix64 over the caller's state: seeded streams of their own (one per loop or thread). */
static inline uint64_t rng_split(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
/* Uniform in [0, 1) with 53 bits of rng_split(s). */
static inline double rng_split_unit(uint64_t *s) { return (double)(rng_split(s) >> 11) * (1.0 / 9007199254740992.0); }

/* A new directory /tmp/oc_test_<name>_XXXXXX, its path in dir (cap bytes). @return 0, or -1. */
static inline int oc_test_tmpdir(char *dir, size_t cap, const char *name) {
  snprintf(dir, cap, "/tmp/oc_test_%s_XXXXXX", name);
  return mkdtemp(dir) ? 0 : -1;
}

/* Removes what is in dir (subdirectories too), then dir. */
static inline void oc_test_rmtree(const char *dir) {
  DIR *d = opendir(dir);
  if (d) {
    struct dirent *e;
    char p[4096];
    while ((e = readdir(d)))
      if (e->d_name[0] != '.') {
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (unlink(p) != 0) oc_test_rmtree(p);
      }
    closedir(d);
  }
  rmdir(dir);
}

/* Defines tmpdir_setup and tmpdir_teardown, cmocka setup and teardown functions that make and
 * remove the temporary directory `dir` (a char array) of test `name`. */
#define OC_TEST_TMPDIR_FIXTURE(dir, name)                    \
  static int tmpdir_setup(void **state) {                    \
    (void)state;                                             \
    return oc_test_tmpdir(dir, sizeof dir, name);            \
  }                                                          \
  static int tmpdir_teardown(void **state) {                 \
    (void)state;                                             \
    oc_test_rmtree(dir);                                     \
    return 0;                                                \
  }

/* Mean of σt over a node's own cube from its 8³ corner samples: each sample stands for the box of
 * edge size/7 around it, so samples on faces count half, on edges a quarter, at corners an eighth
 * (trapezoid weights). Used by the filtering tests (a parent's mean against its descendants'). */
static inline double oc_test_node_mean(const float s[512]) {
  double sum = 0.0, wsum = 0.0;
  for (int k = 0; k < 8; k++)
    for (int j = 0; j < 8; j++)
      for (int i = 0; i < 8; i++) {
        double w = (i == 0 || i == 7 ? 0.5 : 1.0) * (j == 0 || j == 7 ? 0.5 : 1.0) * (k == 0 || k == 7 ? 0.5 : 1.0);
        sum += w * s[i + 8 * j + 64 * k];
        wsum += w;
      }
  return sum / wsum;
}

#endif /* OC_TESTS_UTIL_H */

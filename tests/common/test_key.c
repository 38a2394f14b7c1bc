/* test_key.c — octree keys: Morton layout, hierarchy, neighbours, geometry, canonical order
 * (common/oc_key.c). */
#include <math.h>
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h> /* qsort */

#include <cmocka.h>

#include "test_main.h"
#include "test_util.h"

#include "oc_key.h"
#include "oc_planet.h" /* OC_ROOT_HALF */

#define S OC_ROOT_HALF

static uint32_t rng_below(uint64_t n) { return (uint32_t)(rng_u64() % n); }

/* A random cell of `level`: its coordinates, each below 2^level, drawn x first. */
static void rng_cell(int level, uint32_t *ix, uint32_t *iy, uint32_t *iz) {
  uint64_t side = (uint64_t)1 << level;
  *ix = rng_below(side);
  *iy = rng_below(side);
  *iz = rng_below(side);
}

/* The convention written out bit by bit: the reference the magic-number version must match. */
static oc_key_t slow_key(int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  oc_key_t k = 1;
  for (int b = level - 1; b >= 0; b--)
    k = k << 3 | (oc_key_t)((ix >> b & 1) | (iy >> b & 1) << 1 | (iz >> b & 1) << 2);
  return k;
}

static void test_key__root(void **state) {
  (void)state;
  assert_true(oc_key_make(0, 0, 0, 0) == OC_KEY_ROOT);
  assert_int_equal(oc_key_level(OC_KEY_ROOT), 0);
  assert_true(oc_key_parent(OC_KEY_ROOT) == OC_KEY_INVALID);
  assert_true(oc_key_size(0) == 2.0 * S);
  oc_dvec3 o;
  double size;
  oc_key_bounds(OC_KEY_ROOT, &o, &size);
  assert_true(o.x == -S && o.y == -S && o.z == -S && size == 2.0 * S);
  oc_dvec3 c = oc_key_center(OC_KEY_ROOT);
  assert_true(c.x == 0.0 && c.y == 0.0 && c.z == 0.0);
}

static void test_key__layout_matches_convention(void **state) {
  (void)state;
  /* x in the lowest bit of each triple. */
  assert_true(oc_key_make(1, 1, 0, 0) == 011);
  assert_true(oc_key_make(1, 0, 1, 0) == 012);
  assert_true(oc_key_make(1, 0, 0, 1) == 014);
  assert_true(oc_key_make(2, 2, 0, 3) == 0154);
  uint32_t m = (1u << 21) - 1;
  assert_true(oc_key_make(21, m, m, m) == UINT64_MAX);
  assert_true(oc_key_make(21, 0, 0, 0) == (oc_key_t)1 << 63);
  for (int n = 0; n < 20000; n++) {
    int level = (int)rng_below(22);
    uint32_t ix, iy, iz;
    rng_cell(level, &ix, &iy, &iz);
    assert_true(oc_key_make(level, ix, iy, iz) == slow_key(level, ix, iy, iz));
  }
}

/* Runs check(level, a cell's coordinates) on `per_level` random cells (rng_cell()) of every level; with
 * `corners`, the first two are the level's first and last corner cells instead (drawn all the same). */
static void each_cell(int per_level, int corners, void (*check)(int level, uint32_t ix, uint32_t iy, uint32_t iz)) {
  for (int level = 0; level <= OC_KEY_MAX_LEVEL; level++) {
    uint32_t last = (uint32_t)(((uint64_t)1 << level) - 1);
    for (int n = 0; n < per_level; n++) {
      uint32_t ix, iy, iz;
      rng_cell(level, &ix, &iy, &iz);
      if (corners && n == 0) ix = iy = iz = 0;
      if (corners && n == 1) ix = iy = iz = last;
      check(level, ix, iy, iz);
    }
  }
}

static void round_trip_cell(int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  oc_key_t k = oc_key_make(level, ix, iy, iz);
  assert_true(oc_key_valid(k));
  assert_int_equal(oc_key_level(k), level);
  uint32_t x, y, z;
  oc_key_coords(k, &x, &y, &z);
  assert_int_equal(x, ix);
  assert_int_equal(y, iy);
  assert_int_equal(z, iz);
}

static void test_key__make_coords_round_trip(void **state) {
  (void)state;
  each_cell(2000, 1, round_trip_cell);
}

static void test_key__invalid_rejected(void **state) {
  (void)state;
  assert_false(oc_key_valid(0));
  assert_int_equal(oc_key_level(0), -1);
  /* Sentinel not at a multiple of 3. */
  for (int b = 0; b < 64; b++) {
    oc_key_t k = (oc_key_t)1 << b | 1;
    if (b == 0) k = 1;
    assert_true(oc_key_valid(k) == (b % 3 == 0));
    assert_int_equal(oc_key_level(k), b % 3 == 0 ? b / 3 : -1);
  }
  assert_false(oc_key_valid(2));
  assert_false(oc_key_valid(4));
  assert_false(oc_key_valid(0x10));
  /* Level outside 0..21, or a coordinate outside the level. */
  assert_true(oc_key_make(22, 0, 0, 0) == OC_KEY_INVALID);
  assert_true(oc_key_make(-1, 0, 0, 0) == OC_KEY_INVALID);
  assert_true(oc_key_make(3, 8, 0, 0) == OC_KEY_INVALID);
  assert_true(oc_key_make(3, 0, 8, 0) == OC_KEY_INVALID);
  assert_true(oc_key_make(3, 0, 0, 8) == OC_KEY_INVALID);
  assert_true(oc_key_make(21, 1u << 21, 0, 0) == OC_KEY_INVALID);
  assert_true(oc_key_make(0, 1, 0, 0) == OC_KEY_INVALID);
  /* Every operation refuses an invalid key instead of inventing a node. */
  oc_key_t bad = 2;
  assert_true(oc_key_parent(bad) == OC_KEY_INVALID);
  assert_true(oc_key_child(bad, 0) == OC_KEY_INVALID);
  assert_true(oc_key_ancestor(bad, 0) == OC_KEY_INVALID);
  assert_false(oc_key_is_ancestor(bad, 020));
  assert_false(oc_key_is_ancestor(OC_KEY_ROOT, bad));
  assert_true(oc_key_neighbor(bad, 0, 0, 0) == OC_KEY_INVALID);
  assert_true(isnan(oc_key_size(22)) && isnan(oc_key_size(-1)));
  oc_dvec3 o;
  double size;
  oc_key_bounds(bad, &o, &size);
  assert_true(isnan(o.x) && isnan(size));
  assert_true(isnan(oc_key_center(bad).x));
  uint32_t x = 7, y = 7, z = 7;
  oc_key_coords(bad, &x, &y, &z);
  assert_true(x == 0 && y == 0 && z == 0);
  assert_true(oc_key_from_point(22, oc_dv3(0, 0, 0)) == OC_KEY_INVALID);
  assert_true(oc_key_from_point(-1, oc_dv3(0, 0, 0)) == OC_KEY_INVALID);
}

static void test_key__parent_child_ancestor(void **state) {
  (void)state;
  for (int n = 0; n < 5000; n++) {
    int level = (int)rng_below(21); /* 0..20: has children */
    uint32_t ix, iy, iz;
    rng_cell(level, &ix, &iy, &iz);
    oc_key_t k = oc_key_make(level, ix, iy, iz);
    for (int i = 0; i < 8; i++) {
      oc_key_t c = oc_key_child(k, i);
      assert_int_equal(oc_key_level(c), level + 1);
      assert_true(oc_key_parent(c) == k);
      uint32_t x, y, z;
      oc_key_coords(c, &x, &y, &z);
      assert_int_equal(x, 2 * ix + (uint32_t)(i & 1));
      assert_int_equal(y, 2 * iy + (uint32_t)(i >> 1 & 1));
      assert_int_equal(z, 2 * iz + (uint32_t)(i >> 2 & 1));
      assert_true(oc_key_is_ancestor(k, c));
      assert_false(oc_key_is_ancestor(c, k));
      assert_true(oc_key_is_ancestor(OC_KEY_ROOT, c));
    }
    assert_true(oc_key_child(k, -1) == OC_KEY_INVALID);
    assert_true(oc_key_child(k, 8) == OC_KEY_INVALID);
    assert_false(oc_key_is_ancestor(k, k)); /* strict */
    for (int a = 0; a <= level; a++) {
      oc_key_t an = oc_key_ancestor(k, a);
      assert_true(an == oc_key_make(a, ix >> (level - a), iy >> (level - a), iz >> (level - a)));
      assert_true(a == level ? an == k : oc_key_is_ancestor(an, k));
    }
    assert_true(oc_key_ancestor(k, level + 1) == OC_KEY_INVALID);
    assert_true(oc_key_ancestor(k, -1) == OC_KEY_INVALID);
    /* Not an ancestor: a sibling's subtree. */
    if (level > 0) {
      oc_key_t sib = oc_key_parent(k) << 3 | ((k & 7) ^ 1);
      assert_false(oc_key_is_ancestor(sib, oc_key_child(k, 3)));
    }
  }
  uint32_t m = (1u << 21) - 1;
  assert_true(oc_key_child(oc_key_make(21, m, 0, 5), 0) == OC_KEY_INVALID);
}

static void test_key__neighbor_edges(void **state) {
  (void)state;
  assert_true(oc_key_neighbor(OC_KEY_ROOT, 0, 0, 0) == OC_KEY_ROOT);
  assert_true(oc_key_neighbor(OC_KEY_ROOT, 1, 0, 0) == OC_KEY_INVALID);
  assert_true(oc_key_neighbor(OC_KEY_ROOT, 0, -1, 0) == OC_KEY_INVALID);
  for (int level = 1; level <= OC_KEY_MAX_LEVEL; level++) {
    uint32_t last = (uint32_t)((1u << level) - 1);
    oc_key_t lo = oc_key_make(level, 0, 0, 0), hi = oc_key_make(level, last, last, last);
    assert_true(oc_key_neighbor(lo, -1, 0, 0) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(lo, 0, -1, 0) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(lo, 0, 0, -1) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(hi, 1, 0, 0) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(hi, 0, 1, 0) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(hi, 0, 0, 1) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(lo, 1, 1, 1) == oc_key_make(level, 1, 1, 1));
    assert_true(oc_key_neighbor(hi, -1, 0, -1) == oc_key_make(level, last - 1, last, last - 1));
    assert_true(oc_key_neighbor(lo, (int)last, 0, 0) == oc_key_make(level, last, 0, 0));
    assert_true(oc_key_neighbor(lo, (int)last + 1, 0, 0) == OC_KEY_INVALID);
    /* Offsets large enough to wrap a uint32 must not come back into the cube. */
    assert_true(oc_key_neighbor(hi, -2147483647 - 1, 0, 0) == OC_KEY_INVALID);
    assert_true(oc_key_neighbor(lo, 2147483647, 0, 0) == OC_KEY_INVALID);
  }
  /* Interior: neighbours share a face and are their own inverses. */
  for (int n = 0; n < 2000; n++) {
    int level = 2 + (int)rng_below(20);
    uint64_t side = (uint64_t)1 << level;
    uint32_t ix = 1 + rng_below(side - 2), iy = 1 + rng_below(side - 2), iz = 1 + rng_below(side - 2);
    oc_key_t k = oc_key_make(level, ix, iy, iz);
    int d[3] = {(int)rng_below(3) - 1, (int)rng_below(3) - 1, (int)rng_below(3) - 1};
    oc_key_t nb = oc_key_neighbor(k, d[0], d[1], d[2]);
    assert_true(nb == oc_key_make(level, ix + (uint32_t)d[0], iy + (uint32_t)d[1], iz + (uint32_t)d[2]));
    assert_true(oc_key_neighbor(nb, -d[0], -d[1], -d[2]) == k);
  }
}

static void test_key__size_exact(void **state) {
  (void)state;
  for (int level = 0; level <= OC_KEY_MAX_LEVEL; level++) {
    double s = oc_key_size(level);
    assert_true(s == 2.0 * S / (double)(1u << level)); /* no accumulation: exact */
    assert_true(s * (double)(1u << level) == 2.0 * S);
  }
  assert_true(oc_key_size(OC_KEY_MAX_LEVEL) == OC_CELL21_SIZE);
  /* A child's box is exactly an eighth of its parent's: derived, never accumulated. */
  oc_key_t k = oc_key_make(7, 100, 3, 127);
  oc_dvec3 po, co;
  double ps, cs;
  oc_key_bounds(k, &po, &ps);
  oc_key_bounds(oc_key_child(k, 7), &co, &cs);
  assert_true(cs * 2.0 == ps);
  assert_true(co.x == po.x + cs && co.y == po.y + cs && co.z == po.z + cs);
}

static void bounds_cell(int level, uint32_t ix, uint32_t iy, uint32_t iz) {
  uint32_t last = (uint32_t)(((uint64_t)1 << level) - 1);
  oc_key_t k = oc_key_make(level, ix, iy, iz);
  oc_dvec3 o, c = oc_key_center(k);
  double size;
  oc_key_bounds(k, &o, &size);
  assert_true(o.x == -S + (double)ix * size && o.z == -S + (double)iz * size);
  assert_true(c.x == o.x + 0.5 * size && c.y == o.y + 0.5 * size && c.z == o.z + 0.5 * size);
  /* Centre and origin map back; the max corner belongs to the upper neighbour (or, on the
   * root's max face, to this last cell). */
  assert_true(oc_key_from_point(level, c) == k);
  assert_true(oc_key_from_point(level, o) == k);
  oc_dvec3 top = oc_dv3(o.x + size, o.y + size, o.z + size);
  oc_key_t up = oc_key_from_point(level, top);
  uint32_t ux = ix < last ? ix + 1 : ix, uy = iy < last ? iy + 1 : iy, uz = iz < last ? iz + 1 : iz;
  assert_true(up == oc_key_make(level, ux, uy, uz));
  /* A random interior point maps to this key, and its ancestors' keys to the ancestors. */
  oc_dvec3 p = oc_dv3(o.x + size * (0.001 + 0.998 * rng_unit()), o.y + size * (0.001 + 0.998 * rng_unit()),
                      o.z + size * (0.001 + 0.998 * rng_unit()));
  assert_true(oc_key_from_point(level, p) == k);
  for (int a = 0; a < level; a++) assert_true(oc_key_from_point(a, p) == oc_key_ancestor(k, a));
}

static void test_key__bounds_from_point_consistent(void **state) {
  (void)state;
  each_cell(1000, 0, bounds_cell);
}

static void test_key__from_point_outside(void **state) {
  (void)state;
  uint32_t last = (1u << 21) - 1;
  /* The closed cube is covered: +S clamps into the last cell, -S is the first. */
  assert_true(oc_key_from_point(21, oc_dv3(S, S, S)) == oc_key_make(21, last, last, last));
  assert_true(oc_key_from_point(21, oc_dv3(-S, -S, -S)) == oc_key_make(21, 0, 0, 0));
  assert_true(oc_key_from_point(0, oc_dv3(S, -S, 0)) == OC_KEY_ROOT);
  double beyond = nextafter(S, INFINITY), below = nextafter(-S, -INFINITY);
  for (int level = 0; level <= 21; level += 7) {
    assert_true(oc_key_from_point(level, oc_dv3(beyond, 0, 0)) == OC_KEY_INVALID);
    assert_true(oc_key_from_point(level, oc_dv3(0, beyond, 0)) == OC_KEY_INVALID);
    assert_true(oc_key_from_point(level, oc_dv3(0, 0, below)) == OC_KEY_INVALID);
    assert_true(oc_key_from_point(level, oc_dv3(1e7, 0, 0)) == OC_KEY_INVALID);
    assert_true(oc_key_from_point(level, oc_dv3(NAN, 0, 0)) == OC_KEY_INVALID);
    assert_true(oc_key_from_point(level, oc_dv3(0, INFINITY, 0)) == OC_KEY_INVALID);
  }
  /* The planet centre sits on the faces between the halves: upper cells. */
  assert_true(oc_key_from_point(1, oc_dv3(0, 0, 0)) == oc_key_make(1, 1, 1, 1));
  assert_true(oc_key_from_point(1, oc_dv3(-1e-9, 0, -0.0)) == oc_key_make(1, 0, 1, 1));
}

static int cmp_key(const void *a, const void *b) {
  oc_key_t x = *(const oc_key_t *)a, y = *(const oc_key_t *)b;
  return (x > y) - (x < y);
}

static void test_key__canonical_order(void **state) {
  (void)state;
  enum { N = 4096 };
  static oc_key_t keys[N];
  for (int n = 0; n < N; n++) {
    int level = (int)rng_below(22);
    uint64_t side = (uint64_t)1 << level;
    keys[n] = oc_key_make(level, rng_below(side), rng_below(side), rng_below(side));
  }
  qsort(keys, N, sizeof keys[0], cmp_key);
  for (int n = 1; n < N; n++) assert_true(oc_key_level(keys[n - 1]) <= oc_key_level(keys[n]));
  /* Within a level, ascending keys are Morton (z-order) order. */
  assert_true(oc_key_make(1, 1, 0, 0) < oc_key_make(1, 0, 1, 0));
  assert_true(oc_key_make(1, 1, 1, 0) < oc_key_make(1, 0, 0, 1));
  assert_true(oc_key_make(0, 0, 0, 0) < oc_key_make(1, 0, 0, 0));
  assert_true(oc_key_make(20, (1u << 20) - 1, (1u << 20) - 1, (1u << 20) - 1) < oc_key_make(21, 0, 0, 0));
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_key__root),
             cmocka_unit_test(test_key__layout_matches_convention),
             cmocka_unit_test(test_key__make_coords_round_trip),
             cmocka_unit_test(test_key__invalid_rejected),
             cmocka_unit_test(test_key__parent_child_ancestor),
             cmocka_unit_test(test_key__neighbor_edges),
             cmocka_unit_test(test_key__size_exact),
             cmocka_unit_test(test_key__bounds_from_point_consistent),
             cmocka_unit_test(test_key__from_point_outside),
             cmocka_unit_test(test_key__canonical_order))

/* test_interp.c — previous values of the newest state's leaves (client/interp.c): identity, splits
 * (one and several levels, empty/uniform/brick parents), merges (fine previous values: 8 sub-bricks
 * on the children's lattices), refreshes, no previous state, corrupt input, blend weights, and a
 * randomised consistency check against brute-force look-ups and an independent copy of the
 * renderer's reconstruction. */
#include <math.h>
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "brick.h" /* ocg_*: the reference reconstruction */
#include "interp.h"
#include "oc_err.h"
#include "oc_key.h"
#include "oc_render.h"     /* oc_render_sample_state */
#include "oc_state.h"
#include "voxelize.h"   /* ocs_brick_sample_pos */
#include "state_fixture.h" /* child, node, golden_codes, golden_state */
#include "test_util.h"     /* oc_test_node_mean */

/*-*** Helpers ***/

static void expect_valid(const oc_state_t *s) {
  char why[256];
  int e = oc_state_validate(s, why, sizeof why);
  if (e) fail_msg("test state invalid: %s", why);
}

/* s put in canonical order, then checked. */
static void canonical(oc_state_t *s) {
  oc_state_canonicalize(s);
  expect_valid(s);
}

static void add_node(oc_state_t *s, oc_node_t n) { assert_int_equal(oc_state_add_node(s, &n), 0); }

static void add_uniform(oc_state_t *s, oc_key_t key, float sigma, float tau) {
  add_node(s, node(key, OC_NODE_UNIFORM, 0, sigma, sigma, tau, tau));
}

/* Removes the record with this key (and its brick payload); the records need not be sorted. */
static void remove_node(oc_state_t *s, oc_key_t key) {
  int64_t i = -1;
  for (uint32_t k = 0; k < s->node_count; k++)
    if (s->nodes[k].key == key) i = k;
  assert_true(i >= 0);
  if (s->nodes[i].kind == OC_NODE_BRICK) {
    const oc_brick_t *b = oc_state_find_brick(s, s->nodes[i].brick_id);
    assert_non_null(b);
    size_t bi = (size_t)(b - s->bricks);
    memmove(&s->bricks[bi], &s->bricks[bi + 1], (s->brick_count - bi - 1) * sizeof *s->bricks);
    s->brick_count--;
  }
  memmove(&s->nodes[i], &s->nodes[i + 1], (s->node_count - (size_t)i - 1) * sizeof *s->nodes);
  s->node_count--;
}

/* Replaces leaf `key` by its 8 children, uniform (sigma + 0.01·i, tau). */
/* The node at key (a leaf) becomes uniform. */
static void replace_uniform(oc_state_t *s, oc_key_t key, float sigma, float tau) {
  remove_node(s, key);
  add_uniform(s, key, sigma, tau);
}

static void split_uniform(oc_state_t *s, oc_key_t key, float sigma, float tau) {
  remove_node(s, key);
  for (int i = 0; i < 8; i++) add_uniform(s, child(key, i), sigma + 0.01f * (float)i, tau);
}

/* An empty state, lit from +z. */
static void empty_state(oc_state_t *s) {
  oc_state_init(s);
  s->sun_dir = oc_dv3(0, 0, 1);
}

static void copy_state(oc_state_t *dst, const oc_state_t *src) {
  oc_state_init(dst);
  assert_int_equal(oc_state_copy(dst, src), 0);
}

/* Independent copy of the renderer's reconstruction (common/oc_render.c, oc__leaf_channel) of
 * record idx at a planet-frame point, whatever leaf the renderer's locator would pick there. */
static float ref_channel(const oc_state_t *s, int64_t idx, oc_dvec3 p, int ch) {
  const oc_node_t *n = &s->nodes[idx];
  if (n->kind == OC_NODE_EMPTY) return 0.0f;
  const oc_brick_t *b = n->kind == OC_NODE_BRICK ? oc_state_find_brick(s, n->brick_id) : NULL;
  if (!b) return n->range[ch].lo;
  float lo = n->range[ch].lo, hi = n->range[ch].hi;
  if (hi == 0.0f) return 0.0f;
  oc_dvec3 o;
  double size;
  oc_key_bounds(n->key, &o, &size);
  double inv = 1.0 / size;
  ocg_vec3 u = ocg_v3((float)((p.x - o.x) * inv), (float)((p.y - o.y) * inv), (float)((p.z - o.z) * inv));
  ocg_vec3 base = ocg_brick_base(u), f = ocg_brick_frac(u, base);
  ocg_uint b0 = ocg_brick_base_voxel(base);
  float v[8];
  for (ocg_uint q = 0; q < 8u; q++)
    v[q] = ocg_code_decode(b->codes.code[ch][b0 + ocg_brick_voxel(q & 1u, (q >> 1) & 1u, q >> 2)], lo, hi);
  return ocg_trilerp(ocg_v4(v[0], v[1], v[2], v[3]), ocg_v4(v[4], v[5], v[6], v[7]), f);
}

/* a ≈ b: relative 1e-5, plus 1e-6 of the source's largest value (a sample position rounded to the
 * other side of a lattice point weighs the neighbour sample by about one float ulp). */
static void expect_close(float a, float b, float scale, const char *what, uint32_t leaf, int q) {
  double tol = 1e-5 * fmax(fabs(a), fabs(b)) + 1e-6 * scale + 1e-30;
  if (!(fabs((double)a - (double)b) <= tol)) fail_msg("%s: leaf %u sample %d: %.9g vs %.9g", what, leaf, q, (double)a, (double)b);
}

/* The previous value of leaf i at sample q of sub-brick sub (0 unless fine) of channel ch (uniform
 * or pooled). */
static float prev_sub_sample(const ocv_interp_t *ip, uint32_t i, int sub, int ch, int q) {
  const ocv_interp_prev_t *e = &ip->prev[i];
  if (e->uniform) {
    assert_int_equal(e->fine, 0);
    assert_null(ocv_interp_samples(ip, i, ch));
    assert_null(ocv_interp_sub_samples(ip, i, 0, ch));
    return e->value[ch];
  }
  const float *v = ocv_interp_sub_samples(ip, i, sub, ch);
  assert_non_null(v);
  if (!e->fine) assert_ptr_equal(ocv_interp_samples(ip, i, ch), v);
  return v[q];
}

static float prev_sample(const ocv_interp_t *ip, uint32_t i, int ch, int q) {
  assert_int_equal(ip->prev[i].fine, 0);
  return prev_sub_sample(ip, i, 0, ch, q);
}

/* PARENT leaf i of N against the reference reconstruction of P's ancestor. */
static void check_parent(const ocv_interp_t *ip, const oc_state_t *P, const oc_state_t *N, uint32_t i) {
  assert_int_equal(ip->prev[i].source, OCV_INTERP_PARENT);
  oc_key_t key = N->nodes[i].key;
  int64_t a = oc_state_find_leaf(P, key);
  assert_true(a >= 0);
  assert_true(oc_key_is_ancestor(P->nodes[a].key, key));
  for (int q = 0; q < 512; q++) {
    oc_dvec3 p = ocs_brick_sample_pos(key, q & 7, (q >> 3) & 7, q >> 6);
    for (int ch = 0; ch < 2; ch++)
      expect_close(prev_sample(ip, i, ch, q), ref_channel(P, a, p, ch), P->nodes[a].range[ch].hi, "parent", i, q);
  }
}

/* Position of sample q of sub-brick c of a merged leaf: sample q of child c (the lattice of octant
 * c, u = (c_axis + i/7)/2 of the leaf). */
static oc_dvec3 sub_pos(oc_key_t key, int c, int q) { return ocs_brick_sample_pos(child(key, c), q & 7, (q >> 3) & 7, q >> 6); }

/* CHILDREN leaf i of N: a fine value unless uniform (then all 8 sub-bricks the same constant);
 * each sample of each sub-brick against the reference of the one P descendant inside that octant
 * holding it (found by nudging the sample towards the octant's centre, far less than any
 * descendant's face is from a sample: ≥ size/56 for three levels); and where the octant is a P
 * leaf itself (a one-level merge), its decoded samples exactly. */
static void check_children(const ocv_interp_t *ip, const oc_state_t *P, const oc_state_t *N, uint32_t i) {
  const ocv_interp_prev_t *e = &ip->prev[i];
  assert_int_equal(e->source, OCV_INTERP_CHILDREN);
  assert_int_equal(e->fine, !e->uniform);
  oc_key_t key = N->nodes[i].key;
  if (e->fine) {
    assert_null(ocv_interp_samples(ip, i, OC_CH_SIGMA));
    assert_null(ocv_interp_sub_samples(ip, i, 8, OC_CH_SIGMA));
    assert_null(ocv_interp_sub_samples(ip, i, -1, OC_CH_SIGMA));
  }
  for (int c = 0; c < 8; c++) {
    oc_key_t ok = child(key, c);
    oc_dvec3 oc = oc_key_center(ok);
    for (int q = 0; q < 512; q++) {
      oc_dvec3 p = sub_pos(key, c, q);
      oc_dvec3 pin = oc_dv3(p.x + (oc.x - p.x) * 1e-6, p.y + (oc.y - p.y) * 1e-6, p.z + (oc.z - p.z) * 1e-6);
      int64_t d = oc_state_find_leaf(P, oc_key_from_point(OC_KEY_MAX_LEVEL, pin));
      assert_true(d >= 0);
      assert_true(P->nodes[d].key == ok || oc_key_is_ancestor(ok, P->nodes[d].key));
      for (int ch = 0; ch < 2; ch++)
        expect_close(prev_sub_sample(ip, i, c, ch, q), ref_channel(P, d, p, ch), P->nodes[d].range[ch].hi, "children", i, q);
    }
    int64_t own = oc_state_find_node(P, ok); /* one level: child c's own samples, bit for bit */
    if (own < 0) continue;
    const oc_node_t *n = &P->nodes[own];
    const oc_brick_t *b = n->kind == OC_NODE_BRICK ? oc_state_find_brick(P, n->brick_id) : NULL;
    float dec[2][512];
    if (b) {
      oc_brick_decode(&b->codes, n->range, dec[0], dec[1]);
    } else {
      for (int ch = 0; ch < 2; ch++)
        for (int q = 0; q < 512; q++) dec[ch][q] = n->kind == OC_NODE_EMPTY ? 0.0f : n->range[ch].lo;
    }
    for (int ch = 0; ch < 2; ch++)
      for (int q = 0; q < 512; q++)
        if (prev_sub_sample(ip, i, c, ch, q) != dec[ch][q])
          fail_msg("children: leaf %u octant %d ch %d sample %d: %.9g, child's own %.9g", i, c, ch, q,
                   (double)prev_sub_sample(ip, i, c, ch, q), (double)dec[ch][q]);
  }
}

/* A root brick whose σt ramps linearly in x and y and τ in z (sample-index units). */
static float ramp_sigma(double x, double y) { return (float)(0.05 + 0.01 * x + 0.002 * y); }
static float ramp_tau(double z) { return (float)(1.0 + 0.5 * z); }

static void ramp_state(oc_state_t *s, uint32_t id) {
  float sig[512], tau[512];
  for (int q = 0; q < 512; q++) {
    sig[q] = ramp_sigma(q & 7, (q >> 3) & 7);
    tau[q] = ramp_tau(q >> 6);
  }
  oc_brick_codes_t codes;
  oc_range_t r[2];
  assert_int_equal(oc_brick_encode(sig, tau, &codes, r), OC_NODE_BRICK);
  empty_state(s);
  add_node(s, node(OC_KEY_ROOT, OC_NODE_BRICK, id, r[0].lo, r[0].hi, r[1].lo, r[1].hi));
  assert_int_equal(oc_state_add_brick(s, id, &codes), 0);
  expect_valid(s);
}

static void build_ok(ocv_interp_t *ip, const oc_state_t *P, const oc_state_t *N) {
  int e = ocv_interp_build(ip, P, N);
  if (e) fail_msg("ocv_interp_build: %s", oc_strerror(e));
  assert_int_equal(ip->node_count, N->node_count);
}

/* What a test made: the interpolation and its two states. */
static void free_all(ocv_interp_t *ip, oc_state_t *P, oc_state_t *N) {
  ocv_interp_free(ip);
  oc_state_free(P);
  oc_state_free(N);
}

/* P the golden state, N a copy of it to change. */
static void golden_pair(oc_state_t *P, oc_state_t *N) {
  assert_int_equal(golden_state(P), 0);
  copy_state(N, P);
}

/* n nodes take their previous samples from `source`, the other nodes of total are the same. */
static void expect_changed(const ocv_interp_stats_t *st, int source, uint32_t n, uint32_t total) {
  assert_int_equal(st->count[source], n);
  assert_int_equal(st->count[OCV_INTERP_SAME], total - n);
}

/* N made canonical and checked (canonical()), then a new ocv_interp_t built from P to it. @return its
 * stats. */
static ocv_interp_stats_t build_new(ocv_interp_t *ip, const oc_state_t *P, oc_state_t *N) {
  ocv_interp_stats_t st;
  canonical(N);
  ocv_interp_init(ip);
  build_ok(ip, P, N);
  ocv_interp_stats(ip, &st);
  return st;
}

/*-*** Identity, no previous state ***/

static void test_interp__identity_is_same(void **state) {
  (void)state;
  oc_state_t P, N;
  golden_pair(&P, &N);
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, &P, &N);
  assert_int_equal(st.count[OCV_INTERP_SAME], N.node_count);
  assert_int_equal(st.pooled, 0);
  assert_int_equal(st.uniform, 0);
  assert_int_equal(ip.pool_count, 0);
  for (uint32_t i = 0; i < N.node_count; i++) {
    assert_int_equal(ip.prev[i].source, OCV_INTERP_SAME);
    assert_int_equal(ip.prev[i].prev_index, OCV_INTERP_NO_POOL);
    assert_null(ocv_interp_samples(&ip, i, 0));
  }
  build_ok(&ip, &N, &N); /* the same object, and a reused result */
  ocv_interp_stats(&ip, &st);
  assert_int_equal(st.count[OCV_INTERP_SAME], N.node_count);
  free_all(&ip, &P, &N);
}

static void test_interp__null_prev_is_none(void **state) {
  (void)state;
  oc_state_t N;
  assert_int_equal(golden_state(&N), 0);
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, NULL, &N);
  assert_int_equal(st.count[OCV_INTERP_NONE], N.node_count);
  assert_int_equal(ip.pool_count, 0);
  assert_null(ip.pool);
  for (uint32_t i = 0; i < N.node_count; i++) {
    assert_int_equal(ip.prev[i].source, OCV_INTERP_NONE);
    assert_int_equal(ip.prev[i].uniform, 0);
    assert_int_equal(ip.prev[i].prev_index, OCV_INTERP_NO_POOL);
  }
  ocv_interp_free(&ip);
  ocv_interp_free(&ip); /* twice is fine */
  ocv_interp_free(NULL);
  oc_state_free(&N);
}

/*-*** Splits ***/

/* Root brick (a linear ramp) split into 8: each child's previous samples are the ramp at its
 * sample positions, and exactly what the renderer showed there. */
static void test_interp__split_ramp(void **state) {
  (void)state;
  oc_state_t P, N;
  ramp_state(&P, 5);
  empty_state(&N);
  for (int c = 0; c < 8; c++) add_uniform(&N, child(OC_KEY_ROOT, c), 0.3f, 0.3f);
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, &P, &N);
  assert_int_equal(st.count[OCV_INTERP_PARENT], 8);
  assert_int_equal(st.pooled, 8);
  assert_int_equal(ip.pool_count, 8);
  double bound[2] = {oc_code_rel_error_bound(P.nodes[0].range[0]), oc_code_rel_error_bound(P.nodes[0].range[1])};
  for (uint32_t i = 0; i < 8; i++) {
    check_parent(&ip, &P, &N, i);
    uint32_t cx, cy, cz;
    oc_key_coords(N.nodes[i].key, &cx, &cy, &cz);
    for (int q = 0; q < 512; q++) {
      /* Sample positions in the parent's sample-index units: (7c + i)/2. */
      double X = (7.0 * cx + (q & 7)) / 2.0, Y = (7.0 * cy + ((q >> 3) & 7)) / 2.0, Z = (7.0 * cz + (q >> 6)) / 2.0;
      float s = prev_sample(&ip, i, 0, q), t = prev_sample(&ip, i, 1, q);
      float es = ramp_sigma(X, Y), et = ramp_tau(Z);
      assert_true(fabs(s - es) <= (2.0 * bound[0] + 1e-6) * es);
      assert_true(fabs(t - et) <= (2.0 * bound[1] + 1e-6) * et);
      /* Renderer: the root's faces belong to the root here, so its locator agrees everywhere. */
      float rs, rt;
      oc_render_sample_state(&P, ocs_brick_sample_pos(N.nodes[i].key, q & 7, (q >> 3) & 7, q >> 6), &rs, &rt);
      expect_close(s, rs, P.nodes[0].range[0].hi, "renderer sigma", i, q);
      expect_close(t, rt, P.nodes[0].range[1].hi, "renderer tau", i, q);
    }
  }
  free_all(&ip, &P, &N);
}

/* Several levels below the P leaf (children, grandchildren, great-grandchildren of the root). */
static void test_interp__split_multilevel(void **state) {
  (void)state;
  oc_state_t P, N;
  ramp_state(&P, 9);
  empty_state(&N);
  oc_key_t c5 = child(OC_KEY_ROOT, 5), g2 = child(c5, 2);
  for (int c = 0; c < 8; c++)
    if (c != 5) add_uniform(&N, child(OC_KEY_ROOT, c), 0.3f, 0.3f);
  for (int c = 0; c < 8; c++)
    if (c != 2) add_uniform(&N, child(c5, c), 0.3f, 0.3f);
  for (int c = 0; c < 8; c++) add_uniform(&N, child(g2, c), 0.3f, 0.3f);
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, &P, &N);
  assert_int_equal(st.count[OCV_INTERP_PARENT], N.node_count);
  assert_int_equal(ip.pool_count, N.node_count);
  double bound = oc_code_rel_error_bound(P.nodes[0].range[0]);
  for (uint32_t i = 0; i < N.node_count; i++) {
    check_parent(&ip, &P, &N, i);
    int L = oc_key_level(N.nodes[i].key);
    uint32_t cx, cy;
    oc_key_coords(N.nodes[i].key, &cx, &cy, NULL);
    double sc = 1.0 / (double)(1 << L);
    for (int q = 0; q < 512; q++) {
      double X = (7.0 * cx + (q & 7)) * sc, Y = (7.0 * cy + ((q >> 3) & 7)) * sc;
      float s = prev_sample(&ip, i, 0, q), es = ramp_sigma(X, Y);
      assert_true(fabs(s - es) <= (2.0 * bound + 1e-6) * es);
    }
  }
  free_all(&ip, &P, &N);
}

/* Golden state: split its empty, uniform and brick children (and a level-2 brick) one level. */
static void test_interp__split_empty_uniform_brick(void **state) {
  (void)state;
  oc_state_t P, N;
  golden_pair(&P, &N);
  oc_key_t root = OC_KEY_ROOT, c7 = child(root, 7);
  split_uniform(&N, child(root, 0), 0.2f, 0.1f); /* empty parent */
  split_uniform(&N, child(root, 1), 0.2f, 0.1f); /* uniform 0.01, 2 */
  split_uniform(&N, child(root, 3), 0.2f, 0.1f); /* brick 7 */
  split_uniform(&N, child(c7, 7), 0.2f, 0.1f);   /* brick 42, level 2 */
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, &P, &N);
  expect_changed(&st, OCV_INTERP_PARENT, 32, N.node_count);
  assert_int_equal(st.uniform, 16);
  assert_int_equal(st.pooled, 16);
  for (uint32_t i = 0; i < N.node_count; i++) {
    oc_key_t k = N.nodes[i].key;
    const ocv_interp_prev_t *e = &ip.prev[i];
    if (oc_key_is_ancestor(child(root, 0), k)) {
      assert_int_equal(e->source, OCV_INTERP_PARENT);
      assert_int_equal(e->uniform, 1);
      assert_true(e->value[0] == 0.0f && e->value[1] == 0.0f);
      assert_int_equal(e->prev_index, OCV_INTERP_NO_POOL);
    } else if (oc_key_is_ancestor(child(root, 1), k)) {
      assert_int_equal(e->source, OCV_INTERP_PARENT);
      assert_int_equal(e->uniform, 1);
      assert_true(e->value[0] == 0.01f && e->value[1] == 2.0f);
    } else if (oc_key_is_ancestor(child(root, 3), k) || oc_key_is_ancestor(child(c7, 7), k)) {
      assert_int_equal(e->uniform, 0);
      check_parent(&ip, &P, &N, i);
    } else {
      assert_int_equal(e->source, OCV_INTERP_SAME);
    }
  }
  free_all(&ip, &P, &N);
}

/*-*** Merges ***/

/* 8 uniform children with different values merged into the root: a fine value whose sub-brick c
 * is child c's value everywhere (8 pool entries); its mean (each sub-brick's plain and trapezoid
 * mean, oc_test_node_mean: the exact integral of the trilinear reconstruction) is the children's
 * mean. With all 8 children the same constant, the value collapses to uniform (no pool entry). */
static void test_interp__merge_uniform_children(void **state) {
  (void)state;
  for (int same = 0; same < 2; same++) {
    oc_state_t P, N;
    empty_state(&P);
    float cs[8], ct[8];
    double ms = 0, mt = 0;
    for (int c = 0; c < 8; c++) {
      cs[c] = same ? 0.04f : 0.01f * (float)(c + 1) * (float)(c + 1);
      ct[c] = same ? 1.5f : 0.5f * (float)(8 - c);
      ms += cs[c] / 8.0;
      mt += ct[c] / 8.0;
      add_uniform(&P, child(OC_KEY_ROOT, c), cs[c], ct[c]);
    }
    expect_valid(&P);
    empty_state(&N);
    add_uniform(&N, OC_KEY_ROOT, 0.3f, 0.3f);
    ocv_interp_t ip;
    ocv_interp_stats_t st = build_new(&ip, &P, &N);
    assert_int_equal(ip.prev[0].source, OCV_INTERP_CHILDREN);
    assert_int_equal(st.count[OCV_INTERP_CHILDREN], 1);
    if (same) {
      assert_int_equal(ip.prev[0].uniform, 1);
      assert_int_equal(ip.prev[0].fine, 0);
      assert_true(ip.prev[0].value[0] == 0.04f && ip.prev[0].value[1] == 1.5f);
      assert_int_equal(ip.pool_count, 0);
      assert_int_equal(st.pooled, 0);
      assert_int_equal(st.fine, 0);
      assert_null(ocv_interp_sub_samples(&ip, 0, 0, OC_CH_SIGMA));
    } else {
      assert_int_equal(ip.prev[0].uniform, 0);
      assert_int_equal(ip.prev[0].fine, 1);
      assert_int_equal(ip.prev[0].prev_index, 0);
      assert_int_equal(ip.pool_count, OCV_INTERP_FINE_ENTRIES);
      assert_int_equal(st.pooled, OCV_INTERP_FINE_ENTRIES);
      assert_int_equal(st.fine, 1);
      assert_null(ocv_interp_samples(&ip, 0, OC_CH_SIGMA));
      double plain_s = 0, plain_t = 0, trap_s = 0, trap_t = 0;
      for (int c = 0; c < 8; c++) {
        const float *s = ocv_interp_sub_samples(&ip, 0, c, OC_CH_SIGMA), *t = ocv_interp_sub_samples(&ip, 0, c, OC_CH_TAU);
        assert_non_null(s);
        assert_non_null(t);
        assert_ptr_equal(s, ip.pool + (size_t)c * OCV_INTERP_ENTRY_FLOATS);
        for (int q = 0; q < 512; q++) {
          assert_true(s[q] == cs[c]);
          assert_true(t[q] == ct[c]);
          plain_s += s[q] / 4096.0;
          plain_t += t[q] / 4096.0;
        }
        trap_s += oc_test_node_mean(s) / 8.0;
        trap_t += oc_test_node_mean(t) / 8.0;
      }
      assert_true(fabs(plain_s - ms) <= 1e-6 * ms);
      assert_true(fabs(plain_t - mt) <= 1e-6 * mt);
      assert_true(fabs(trap_s - ms) <= 1e-6 * ms);
      assert_true(fabs(trap_t - mt) <= 1e-6 * mt);
    }
    check_children(&ip, &P, &N, 0);
    free_all(&ip, &P, &N);
  }
}

/* Merges over bricks and two levels: the golden state's child 7 merged (level-2 bricks and empties
 * below it: a one-level merge, so each sub-brick is that child's decoded samples bit for bit), then
 * the whole golden state merged into the root (octant 7 two levels deep: its sub-brick is the
 * level-2 descendants sampled on the level-1 lattice). Every sample against the one descendant
 * holding it, and against the renderer itself, except on an octant's upper internal faces (a
 * sub-brick's sample 7 where the octant is the lower one on that axis: the renderer's locator gives
 * face points to the upper cell, the sub-brick to its own octant; there the two octants' values
 * may differ). Lower faces of the merged node go to its own side, and the upper faces here are the
 * root's. */
static void test_interp__merge_bricks(void **state) {
  (void)state;
  oc_state_t P, N;
  assert_int_equal(golden_state(&P), 0);
  for (int pass = 0; pass < 2; pass++) {
    empty_state(&N);
    oc_key_t merged = pass == 0 ? child(OC_KEY_ROOT, 7) : OC_KEY_ROOT;
    if (pass == 0) {
      copy_state(&N, &P);
      for (int c = 0; c < 8; c++) remove_node(&N, child(merged, c));
    }
    add_uniform(&N, merged, 0.3f, 0.3f);
    ocv_interp_t ip;
    ocv_interp_stats_t st = build_new(&ip, &P, &N);
    expect_changed(&st, OCV_INTERP_CHILDREN, 1, N.node_count);
    assert_int_equal(st.fine, 1);
    assert_int_equal(ip.pool_count, OCV_INTERP_FINE_ENTRIES);
    int64_t m = oc_state_find_node(&N, merged);
    assert_true(m >= 0);
    assert_int_equal(ip.prev[m].fine, 1);
    check_children(&ip, &P, &N, (uint32_t)m);
    if (pass == 0) /* octants 0 and 7: the level-2 bricks 3 and 42, decoded; the others empty */
      for (int c = 0; c < 8; c++) {
        const oc_node_t *n = &P.nodes[oc_state_find_node(&P, child(merged, c))];
        float ds[512] = {0}, dt[512] = {0};
        assert_int_equal(n->kind, c == 0 || c == 7 ? OC_NODE_BRICK : OC_NODE_EMPTY);
        if (n->kind == OC_NODE_BRICK) oc_brick_decode(&oc_state_find_brick(&P, n->brick_id)->codes, n->range, ds, dt);
        assert_memory_equal(ocv_interp_sub_samples(&ip, (uint32_t)m, c, OC_CH_SIGMA), ds, sizeof ds);
        assert_memory_equal(ocv_interp_sub_samples(&ip, (uint32_t)m, c, OC_CH_TAU), dt, sizeof dt);
      }
    int checked = 0;
    for (int c = 0; c < 8; c++)
      for (int q = 0; q < 512; q++) {
        int I[3] = {q & 7, (q >> 3) & 7, q >> 6}, internal = 0;
        for (int ax = 0; ax < 3; ax++) internal |= I[ax] == 7 && !((c >> ax) & 1);
        if (internal) continue;
        float rs, rt;
        oc_render_sample_state(&P, sub_pos(merged, c, q), &rs, &rt);
        expect_close(prev_sub_sample(&ip, (uint32_t)m, c, 0, q), rs, 10.0f, "renderer sigma", (uint32_t)m, q);
        expect_close(prev_sub_sample(&ip, (uint32_t)m, c, 1, q), rt, 30.0f, "renderer tau", (uint32_t)m, q);
        checked++;
      }
    assert_int_equal(checked, 15 * 15 * 15); /* Σ_c 7^(lower axes) · 8^(upper axes) = (7 + 8)³ */
    ocv_interp_free(&ip);
    oc_state_free(&N);
  }
  oc_state_free(&P);
}

/*-*** Refreshes ***/

static void test_interp__refresh_is_own(void **state) {
  (void)state;
  oc_state_t P, N;
  golden_pair(&P, &N);
  oc_key_t root = OC_KEY_ROOT, c7 = child(root, 7);
  /* brick 42 → brick 43 (new content, same range) */
  int64_t i42 = oc_state_find_node(&N, child(c7, 7));
  oc_node_t n42 = N.nodes[i42];
  remove_node(&N, n42.key);
  n42.brick_id = 43;
  add_node(&N, n42);
  oc_brick_codes_t codes;
  golden_codes(43, &codes);
  assert_int_equal(oc_state_add_brick(&N, 43, &codes), 0);
  /* brick 3: same id, other range */
  int64_t i3 = oc_state_find_node(&N, child(c7, 0));
  N.nodes[i3].range[0].hi = 0.75f;
  /* uniform 0.01/2 → 0.02/2; empty → uniform; brick 7 → uniform */
  replace_uniform(&N, child(root, 1), 0.02f, 2.0f);
  replace_uniform(&N, child(root, 0), 0.02f, 2.0f);
  replace_uniform(&N, child(root, 3), 0.02f, 2.0f);
  ocv_interp_t ip;
  ocv_interp_stats_t st = build_new(&ip, &P, &N);
  expect_changed(&st, OCV_INTERP_OWN, 5, N.node_count);
  assert_int_equal(st.pooled, 3);
  assert_int_equal(st.uniform, 2);
  float ds[512], dt[512];
  struct {
    oc_key_t key;
    uint32_t old_id;
  } bricks[3] = {{child(c7, 7), 42}, {child(c7, 0), 3}, {child(root, 3), 7}};
  for (int b = 0; b < 3; b++) {
    uint32_t i = (uint32_t)oc_state_find_node(&N, bricks[b].key);
    int64_t pi = oc_state_find_node(&P, bricks[b].key);
    assert_int_equal(ip.prev[i].source, OCV_INTERP_OWN);
    assert_int_equal(ip.prev[i].uniform, 0);
    oc_brick_decode(&oc_state_find_brick(&P, bricks[b].old_id)->codes, P.nodes[pi].range, ds, dt);
    assert_memory_equal(ocv_interp_samples(&ip, i, OC_CH_SIGMA), ds, sizeof ds);
    assert_memory_equal(ocv_interp_samples(&ip, i, OC_CH_TAU), dt, sizeof dt);
  }
  const ocv_interp_prev_t *e1 = &ip.prev[oc_state_find_node(&N, child(root, 1))];
  assert_int_equal(e1->source, OCV_INTERP_OWN);
  assert_int_equal(e1->uniform, 1);
  assert_true(e1->value[0] == 0.01f && e1->value[1] == 2.0f);
  const ocv_interp_prev_t *e0 = &ip.prev[oc_state_find_node(&N, child(root, 0))];
  assert_int_equal(e0->source, OCV_INTERP_OWN);
  assert_int_equal(e0->uniform, 1);
  assert_true(e0->value[0] == 0.0f && e0->value[1] == 0.0f);
  free_all(&ip, &P, &N);
}

/* A constant brick's previous value is stored as uniform, not in the pool. */
static void test_interp__constant_brick_is_uniform(void **state) {
  (void)state;
  oc_state_t P, N;
  empty_state(&P);
  add_node(&P, node(OC_KEY_ROOT, OC_NODE_BRICK, 1, 0.5f, 1.0f, 0.0f, 0.0f));
  oc_brick_codes_t codes;
  memset(&codes, 0, sizeof codes);
  for (int q = 0; q < 512; q++) codes.code[0][q] = OC_CODE_MAX;
  assert_int_equal(oc_state_add_brick(&P, 1, &codes), 0);
  expect_valid(&P);
  empty_state(&N);
  for (int c = 0; c < 8; c++) add_uniform(&N, child(OC_KEY_ROOT, c), 0.3f, 0.3f);
  ocv_interp_t ip;
  ocv_interp_init(&ip);
  build_ok(&ip, &P, &N);
  assert_int_equal(ip.pool_count, 0);
  for (uint32_t i = 0; i < 8; i++) {
    assert_int_equal(ip.prev[i].source, OCV_INTERP_PARENT);
    assert_int_equal(ip.prev[i].uniform, 1);
    assert_true(ip.prev[i].value[0] == 1.0f && ip.prev[i].value[1] == 0.0f);
  }
  free_all(&ip, &P, &N);
}

/*-*** Corrupt input, arguments ***/

static void test_interp__corrupt_input(void **state) {
  (void)state;
  oc_state_t P, N;
  assert_int_equal(golden_state(&P), 0);
  ocv_interp_t ip;
  ocv_interp_init(&ip);
  assert_int_equal(ocv_interp_build(NULL, &P, &P), OC_EINVAL);
  assert_int_equal(ocv_interp_build(&ip, &P, NULL), OC_EINVAL);
  /* a gap in N; then the same gap in P */
  copy_state(&N, &P);
  remove_node(&N, child(OC_KEY_ROOT, 4));
  build_ok(&ip, NULL, &P);
  assert_int_equal(ocv_interp_build(&ip, &P, &N), OC_ECORRUPT);
  assert_int_equal(ip.node_count, 0);
  assert_null(ip.prev);
  assert_int_equal(ocv_interp_build(&ip, &N, &P), OC_ECORRUPT);
  assert_int_equal(ocv_interp_build(&ip, NULL, &N), OC_ECORRUPT);
  /* an overlap: a leaf and its parent */
  oc_state_free(&N);
  copy_state(&N, &P);
  add_uniform(&N, child(OC_KEY_ROOT, 7), 0.1f, 0.1f);
  oc_state_canonicalize(&N);
  assert_int_equal(ocv_interp_build(&ip, &P, &N), OC_ECORRUPT);
  assert_int_equal(ocv_interp_build(&ip, &N, &P), OC_ECORRUPT);
  /* keys out of order */
  oc_state_free(&N);
  copy_state(&N, &P);
  oc_node_t t = N.nodes[0];
  N.nodes[0] = N.nodes[1];
  N.nodes[1] = t;
  assert_int_equal(ocv_interp_build(&ip, &P, &N), OC_ECORRUPT);
  /* empty state */
  oc_state_free(&N);
  oc_state_init(&N);
  assert_int_equal(ocv_interp_build(&ip, &P, &N), OC_ECORRUPT);
  assert_int_equal(ocv_interp_build(&ip, &N, &P), OC_ECORRUPT);
  build_ok(&ip, &P, &P); /* usable again */
  free_all(&ip, &P, &N);
}

/*-*** Blend weights ***/

static void test_interp__weights(void **state) {
  (void)state;
  assert_true(ocv_interp_param(10.0, 10.0, 1.0) == 0.0f);
  assert_true(ocv_interp_param(9.0, 10.0, 1.0) == 0.0f);
  assert_true(ocv_interp_param(10.25, 10.0, 1.0) == 0.25f);
  assert_true(ocv_interp_param(11.5, 10.0, 1.0) == 1.0f);
  assert_true(ocv_interp_param(10.5, 10.0, 2.0) == 0.25f);
  assert_true(ocv_interp_param(10.5, 10.0, 0.0) == 1.0f);
  assert_true(ocv_interp_param(10.5, 10.0, -1.0) == 1.0f);
  assert_true(ocv_interp_param(NAN, 10.0, 1.0) == 1.0f);
  assert_true(ocv_interp_param(10.5, INFINITY, 1.0) == 1.0f);
  assert_true(ocv_interp_param(10.5, 10.0, NAN) == 1.0f);
  /* the blend spans the epochs between the two states (a coalesced tick lengthens it), 1..4 P */
  const uint64_t e = 1764633600ull; /* clocked indices count periods since the Unix epoch */
  assert_true(ocv_interp_blend_seconds(1.0, e, e + 1) == 1.0);
  assert_true(ocv_interp_blend_seconds(1.0, e, e + 2) == 2.0);
  assert_true(ocv_interp_blend_seconds(0.5, e, e + 3) == 1.5);
  assert_true(ocv_interp_blend_seconds(1.0, e, e + 100) == OCV_INTERP_MAX_SPAN);
  assert_true(ocv_interp_blend_seconds(1.0, e, e) == 1.0);
  assert_true(ocv_interp_blend_seconds(1.0, e + 1, e) == 1.0);
  assert_true(ocv_interp_blend_seconds(0.0, e, e + 1) == 0.0);
  assert_true(ocv_interp_blend_seconds(NAN, e, e + 1) == 0.0);
  assert_true(ocv_interp_param(e + 1.0, e, ocv_interp_blend_seconds(1.0, e, e + 2)) == 0.5f);
  for (int animated = 0; animated < 2; animated++) {
    assert_true(ocv_interp_weight(OCV_INTERP_NONE, animated, 10.5, 10.0, 1.0) == 1.0f);
    assert_true(ocv_interp_weight(OCV_INTERP_SAME, animated, 10.5, 10.0, 1.0) == 1.0f);
    assert_true(ocv_interp_weight(OCV_INTERP_PARENT, animated, 10.5, 10.0, 1.0) == 0.5f);
    assert_true(ocv_interp_weight(OCV_INTERP_CHILDREN, animated, 10.5, 10.0, 1.0) == 0.5f);
    assert_true(ocv_interp_weight(OCV_INTERP_CHILDREN, animated, 12.0, 10.0, 1.0) == 1.0f);
    assert_true(ocv_interp_weight(99, animated, 10.5, 10.0, 1.0) == 1.0f);
  }
  assert_true(ocv_interp_weight(OCV_INTERP_OWN, 1, 10.5, 10.0, 1.0) == 0.5f);
  assert_true(ocv_interp_weight(OCV_INTERP_OWN, 0, 10.5, 10.0, 1.0) == 1.0f);
}

/*-*** Randomised consistency ***/

static uint64_t mix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
static uint64_t h3(uint64_t a, uint64_t b, uint64_t c) { return mix64(mix64(mix64(a) ^ b) ^ c); }

#define FUZZ_MAX_LEVEL 3

/* Content of leaf `key` in version v (0..3): a pure function, so the same brick id (key·4 + v + 1)
 * always means the same content, across states. */
static void add_content(oc_state_t *s, oc_key_t key, uint32_t v) {
  uint64_t h = h3(key, v, 0xC0FFEE);
  int kind = (int)(h % 3);
  if (kind == OC_NODE_EMPTY) {
    add_node(s, node(key, OC_NODE_EMPTY, 0, 0, 0, 0, 0));
  } else if (kind == OC_NODE_UNIFORM) {
    add_uniform(s, key, 0.001f * (float)(1 + (h >> 8) % 97), 0.01f * (float)(1 + (h >> 20) % 89));
  } else {
    uint32_t id = (uint32_t)key * 4u + v + 1u;
    float slo = 0.001f * (float)(1 + (h >> 8) % 7), tlo = 0.01f * (float)(1 + (h >> 12) % 5);
    float shi = slo * (float)(1 + (h >> 16) % 500), thi = tlo * (float)(1 + (h >> 28) % 300);
    add_node(s, node(key, OC_NODE_BRICK, id, slo, shi, tlo, thi));
    oc_brick_codes_t c;
    uint64_t r = h;
    for (int ch = 0; ch < 2; ch++)
      for (int q = 0; q < 512; q++) {
        r = mix64(r);
        c.code[ch][q] = (r & 15) == 0 ? 0 : (uint16_t)(1 + (r >> 16) % 65535);
      }
    assert_int_equal(oc_state_add_brick(s, id, &c), 0);
  }
}

/* Random tree: P splits with probability 45 % per level; N flips P's decision with probability
 * 25 % and keeps P's content (version 0) for 60 % of its leaves. */
static void grow(oc_state_t *s, oc_key_t key, int level, uint64_t seed, int is_n) {
  int split_p = level < FUZZ_MAX_LEVEL && (level == 0 ? h3(key, seed, 1) % 100 < 90 : h3(key, seed, 2) % 100 < 45);
  int split = split_p;
  if (is_n && level < FUZZ_MAX_LEVEL && h3(key, seed, 3) % 100 < 25) split = !split_p;
  if (split) {
    for (int c = 0; c < 8; c++) grow(s, child(key, c), level + 1, seed, is_n);
    return;
  }
  uint32_t v = 0;
  if (is_n && h3(key, seed, 4) % 100 >= 60) v = 1 + (uint32_t)(h3(key, seed, 5) % 3);
  add_content(s, key, v);
}

static void random_state(oc_state_t *s, uint64_t seed, int is_n) {
  empty_state(s);
  grow(s, OC_KEY_ROOT, 0, seed, is_n);
  canonical(s);
}

static void test_interp__random_consistency(void **state) {
  (void)state;
  uint64_t total[OCV_INTERP_SOURCES] = {0}, fine_total = 0, one_level_total = 0;
  ocv_interp_t ip;
  ocv_interp_init(&ip); /* reused across rounds */
  for (uint64_t seed = 1; seed <= 60; seed++) {
    oc_state_t P, N;
    random_state(&P, seed, 0);
    random_state(&N, seed, 1);
    build_ok(&ip, &P, &N);
    uint8_t *used = calloc(ip.pool_count + 1, 1);
    assert_non_null(used);
    ocv_interp_stats_t st;
    ocv_interp_stats(&ip, &st);
    uint32_t sum = 0;
    for (int k = 0; k < OCV_INTERP_SOURCES; k++) sum += st.count[k];
    assert_int_equal(sum, N.node_count);
    assert_int_equal(st.pooled, ip.pool_count);
    assert_true(st.fine <= st.count[OCV_INTERP_CHILDREN]);
    assert_int_equal(ip.pool_count, st.pooled);
    assert_true(ip.pool_count <= N.node_count - st.count[OCV_INTERP_SAME] +
                                     (OCV_INTERP_FINE_ENTRIES - 1) * st.count[OCV_INTERP_CHILDREN]);
    for (uint32_t i = 0; i < N.node_count; i++) {
      const ocv_interp_prev_t *e = &ip.prev[i];
      oc_key_t key = N.nodes[i].key;
      /* Brute force: same key, else an ancestor leaf, else descendants. */
      int64_t same = oc_state_find_node(&P, key), anc = oc_state_find_leaf(&P, key);
      int want;
      if (same >= 0) {
        const oc_node_t *a = &P.nodes[same], *b = &N.nodes[i];
        int eq = a->kind == b->kind && a->brick_id == b->brick_id && !memcmp(a->range, b->range, sizeof a->range);
        want = eq ? OCV_INTERP_SAME : OCV_INTERP_OWN;
      } else {
        want = anc >= 0 ? OCV_INTERP_PARENT : OCV_INTERP_CHILDREN;
      }
      assert_int_equal(e->source, want);
      total[want]++;
      if (want == OCV_INTERP_SAME) {
        assert_int_equal(e->uniform, 0);
        assert_int_equal(e->fine, 0);
        assert_int_equal(e->prev_index, OCV_INTERP_NO_POOL);
        continue;
      }
      assert_int_equal(e->fine, want == OCV_INTERP_CHILDREN && !e->uniform);
      if (e->uniform) {
        assert_int_equal(e->prev_index, OCV_INTERP_NO_POOL);
      } else {
        uint32_t entries = e->fine ? OCV_INTERP_FINE_ENTRIES : 1;
        assert_true(e->prev_index + entries <= ip.pool_count);
        for (uint32_t k = 0; k < entries; k++) {
          assert_int_equal(used[e->prev_index + k], 0);
          used[e->prev_index + k] = 1;
        }
      }
      if (want == OCV_INTERP_PARENT) {
        check_parent(&ip, &P, &N, i);
      } else if (want == OCV_INTERP_CHILDREN) {
        check_children(&ip, &P, &N, i);
        fine_total += e->fine;
        for (int c = 0; c < 8; c++) one_level_total += oc_state_find_node(&P, child(key, c)) >= 0;
      } else { /* OWN: P's record, sampled at its own sample positions */
        for (int q = 0; q < 512; q++) {
          oc_dvec3 p = ocs_brick_sample_pos(key, q & 7, (q >> 3) & 7, q >> 6);
          for (int ch = 0; ch < 2; ch++)
            expect_close(prev_sample(&ip, i, ch, q), ref_channel(&P, same, p, ch), P.nodes[same].range[ch].hi, "own", i, q);
        }
      }
    }
    for (uint32_t k = 0; k < ip.pool_count; k++) assert_int_equal(used[k], 1);
    free(used);
    oc_state_free(&P);
    oc_state_free(&N);
  }
  ocv_interp_free(&ip);
  for (int k = OCV_INTERP_SAME; k < OCV_INTERP_SOURCES; k++)
    if (!total[k]) fail_msg("source %d never produced: the generator needs tuning", k);
  if (!fine_total || !one_level_total) fail_msg("no fine or no one-level merge: the generator needs tuning");
  print_message("random: %llu same, %llu own, %llu parent, %llu children (%llu fine, %llu octants one level deep)\n",
                (unsigned long long)total[1], (unsigned long long)total[2], (unsigned long long)total[3],
                (unsigned long long)total[4], (unsigned long long)fine_total, (unsigned long long)one_level_total);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_interp__identity_is_same),
             cmocka_unit_test(test_interp__null_prev_is_none),
             cmocka_unit_test(test_interp__split_ramp),
             cmocka_unit_test(test_interp__split_multilevel),
             cmocka_unit_test(test_interp__split_empty_uniform_brick),
             cmocka_unit_test(test_interp__merge_uniform_children),
             cmocka_unit_test(test_interp__merge_bricks),
             cmocka_unit_test(test_interp__refresh_is_own),
             cmocka_unit_test(test_interp__constant_brick_is_uniform),
             cmocka_unit_test(test_interp__corrupt_input),
             cmocka_unit_test(test_interp__weights),
             cmocka_unit_test(test_interp__random_consistency))

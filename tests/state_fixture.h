/* state_fixture.h — the golden state of docs/protocol.md ("Golden value") and the helpers that
 * build states by hand, shared by the state, wire and epoch tests and the epoch fuzzer
 * (header-only, no test framework). */
#ifndef OC_TESTS_STATE_FIXTURE_H
#define OC_TESTS_STATE_FIXTURE_H

#include <stdint.h>
#include <string.h>

#include "oc_key.h"
#include "oc_state.h"

static inline oc_key_t child(oc_key_t k, int i) { return (k << 3) | (oc_key_t)i; }

static inline oc_node_t node(oc_key_t key, int kind, uint32_t brick, float slo, float shi, float tlo, float thi) {
  oc_node_t n;
  memset(&n, 0, sizeof n);
  n.key = key;
  n.kind = (uint8_t)kind;
  n.brick_id = brick;
  n.range[0].lo = slo, n.range[0].hi = shi, n.range[1].lo = tlo, n.range[1].hi = thi;
  return n;
}

/* Codes from integer arithmetic only, so the golden bytes do not depend on libm. */
static inline void golden_codes(uint32_t id, oc_brick_codes_t *c) {
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    for (uint32_t v = 0; v < OC_BRICK_VOXELS; v++)
      c->code[ch][v] = (uint16_t)((v * 131u + (uint32_t)ch * 7919u + id * 17u) % 65536u);
}

/* An empty state with these header fields: where each fixture state starts. */
static inline void state_begin(oc_state_t *s, uint64_t epoch, double time, oc_dvec3 sun_dir) {
  oc_state_init(s);
  s->epoch = epoch;
  s->time = time;
  s->sun_dir = sun_dir;
}

/* Root split in 8; child 7 split again: 15 leaves, 3 bricks (ids 3, 7, 42), every kind; epoch 42,
 * time 1234.5, sun (0, 0.6, 0.8). @return 0, or OC_ENOMEM. */
static inline int golden_state(oc_state_t *s) {
  oc_brick_codes_t c;
  int r = 0;
  state_begin(s, 42, 1234.5, oc_dv3(0.0, 0.6, 0.8));
  oc_key_t root = OC_KEY_ROOT, c7 = child(root, 7);
  oc_node_t n = node(child(root, 0), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  r |= oc_state_add_node(s, &n);
  n = node(child(root, 1), OC_NODE_UNIFORM, 0, 0.01f, 0.01f, 2.0f, 2.0f);
  r |= oc_state_add_node(s, &n);
  n = node(child(root, 2), OC_NODE_UNIFORM, 0, 0.0f, 0.0f, 0.5f, 0.5f);
  r |= oc_state_add_node(s, &n);
  n = node(child(root, 3), OC_NODE_BRICK, 7, 1e-6f, 10.0f, 0.001f, 30.0f);
  r |= oc_state_add_node(s, &n);
  for (int i = 4; i < 7; i++) {
    n = node(child(root, i), OC_NODE_UNIFORM, 0, 0.001f * (float)i, 0.001f * (float)i, 0.0f, 0.0f);
    r |= oc_state_add_node(s, &n);
  }
  for (int i = 0; i < 8; i++) {
    if (i == 0)
      n = node(child(c7, i), OC_NODE_BRICK, 3, 0.25f, 0.5f, 0.0f, 0.0f);
    else if (i == 7)
      n = node(child(c7, i), OC_NODE_BRICK, 42, 0.125f, 0.125f, 1.0f, 4.0f);
    else
      n = node(child(c7, i), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
    r |= oc_state_add_node(s, &n);
  }
  golden_codes(42, &c);
  r |= oc_state_add_brick(s, 42, &c);
  golden_codes(3, &c);
  memset(c.code[1], 0, sizeof c.code[1]); /* brick 3's τ channel is zero */
  r |= oc_state_add_brick(s, 3, &c);
  golden_codes(7, &c);
  r |= oc_state_add_brick(s, 7, &c);
  oc_state_canonicalize(s);
  return r;
}

#ifdef assert_int_equal /* cmocka tests only (the fuzzers include this file too) */
/* Same header fields and records (a lean state against a full one: bricks are not compared). */
static inline void records_equal(const oc_state_t *a, const oc_state_t *b) {
  assert_int_equal(a->epoch, b->epoch);
  assert_memory_equal(&a->time, &b->time, sizeof a->time);
  assert_memory_equal(&a->sun_dir, &b->sun_dir, sizeof a->sun_dir);
  assert_int_equal(a->node_count, b->node_count);
  for (uint32_t i = 0; i < a->node_count; i++) {
    uint8_t x[OC_STATE_RECORD_BYTES], y[OC_STATE_RECORD_BYTES];
    oc_state_pack_record(&a->nodes[i], x);
    oc_state_pack_record(&b->nodes[i], y);
    assert_memory_equal(x, y, sizeof x);
  }
}

/* A lean decode equals the full state's records and the digests of its bricks. */
static inline void expect_lean_equal(const oc_state_t *full, const oc_state_t *lean, const oc_brick_digests_t *dig) {
  records_equal(lean, full);
  assert_int_equal(lean->brick_count, 0);
  assert_null(lean->bricks);
  oc_brick_digests_t want = {0};
  assert_int_equal(oc_brick_digests_of(&want, full), 0);
  assert_int_equal(dig->count, want.count);
  assert_memory_equal(dig->ids, want.ids, (size_t)want.count * sizeof *want.ids);
  assert_memory_equal(dig->digests, want.digests, (size_t)want.count * sizeof *want.digests);
  oc_brick_digests_free(&want);
  assert_true(oc_state_digest_checksum(lean, dig) == oc_state_digest(full));
}

/* Two states equal in every field, brick code and checksum. */
static inline void states_equal(const oc_state_t *a, const oc_state_t *b) {
  assert_int_equal(a->epoch, b->epoch);
  assert_memory_equal(&a->time, &b->time, sizeof a->time);
  assert_memory_equal(&a->sun_dir, &b->sun_dir, sizeof a->sun_dir);
  assert_int_equal(a->node_count, b->node_count);
  assert_int_equal(a->brick_count, b->brick_count);
  for (uint32_t i = 0; i < a->node_count; i++) {
    const oc_node_t *x = &a->nodes[i], *y = &b->nodes[i];
    assert_int_equal(x->key, y->key);
    assert_int_equal(x->kind, y->kind);
    assert_int_equal(x->brick_id, y->brick_id);
    assert_memory_equal(x->range, y->range, sizeof x->range);
  }
  for (uint32_t i = 0; i < a->brick_count; i++) {
    assert_int_equal(a->bricks[i].id, b->bricks[i].id);
    assert_memory_equal(&a->bricks[i].codes, &b->bricks[i].codes, sizeof a->bricks[i].codes);
  }
  assert_int_equal(oc_state_checksum(a), oc_state_checksum(b));
}
#endif

#endif /* OC_TESTS_STATE_FIXTURE_H */

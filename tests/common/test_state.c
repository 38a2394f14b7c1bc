/* test_state.c — the state: validation, look-ups, byte-exact serialisation, checksum, state files,
 * resident bytes (common/oc_state.c, common/oc_state_io.c).
 *
 * OC_FUZZ_CORPUS_OUT=<dir> regenerates the fuzz seeds (tests/fuzz/corpus/state); without it the
 * committed seeds are checked to still deserialise. */
#include <math.h>
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h> /* rmdir */

#include <cmocka.h>
#include <xxhash.h> /* XXH3_64bits: re-sealing deliberately corrupted bytes */

#include "test_main.h"
#include "test_util.h" /* oc_test_tmpdir, oc_test_rmtree */
#include "oc_err.h"
#include "oc_state.h"
#include "state_fixture.h" /* child, node, golden_codes, golden_state */

/* Golden: the checksum of golden_state() (also in docs/protocol.md, "State"). A change here means
 * the byte format changed: bump OC_STATE_VERSION and document it, never just update the number. */
#define GOLDEN_SIZE 6708u
#define GOLDEN_CHECKSUM 0xc9d949fa8e9ec21bull
/* Its digest checksum (lean viewers; docs/protocol.md, "Digest checksum"): the same stream with each
 * brick as u32 id + u64 XXH3-64 of its 2048 code bytes. */
#define GOLDEN_DIGEST 0x778e2c0f5a869deeull

static void expect_valid(const oc_state_t *s) {
  char why[256];
  int e = oc_state_validate(s, why, sizeof why);
  if (e) fail_msg("unexpectedly invalid: %s", why);
}

/* Invalid with `needle` in the reason. */
static void expect_invalid(const oc_state_t *s, const char *needle) {
  char why[256];
  int e = oc_state_validate(s, why, sizeof why);
  if (e != OC_ECORRUPT) fail_msg("expected ECORRUPT (%s), got %d", needle, e);
  if (!strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);
}

static uint8_t *serialize(const oc_state_t *s, size_t *len) {
  *len = oc_state_serialized_size(s);
  uint8_t *buf = malloc(*len);
  assert_non_null(buf);
  assert_int_equal(oc_state_serialize(s, buf, *len), (int64_t)*len);
  return buf;
}

/* The golden state's serialisation, a state to decode it into and room for the reason. */
typedef struct {
  uint8_t *buf;
  size_t len;
  oc_state_t t;
  char why[256];
} golden_bytes_t;

static void golden_bytes(golden_bytes_t *g) {
  oc_state_t s;
  golden_state(&s);
  g->buf = serialize(&s, &g->len);
  oc_state_free(&s);
  oc_state_init(&g->t);
  g->why[0] = '\0';
}

static void golden_bytes_free(golden_bytes_t *g) {
  free(g->buf);
  oc_state_free(&g->t);
}

static void reseal(uint8_t *buf, size_t len) {
  uint64_t h = XXH3_64bits(buf, len - 8);
  for (int i = 0; i < 8; i++) buf[len - 8 + i] = (uint8_t)(h >> (8 * i));
}

/*-*** Validation ***/

static void test_state__valid_and_canonical(void **state) {
  (void)state;
  oc_state_t s, t;
  golden_state(&s);
  expect_valid(&s);
  /* canonicalize restores any permutation */
  oc_state_init(&t);
  assert_int_equal(oc_state_copy(&t, &s), 0);
  for (uint32_t i = 0; i < t.node_count / 2; i++) {
    oc_node_t x = t.nodes[i];
    t.nodes[i] = t.nodes[t.node_count - 1 - i];
    t.nodes[t.node_count - 1 - i] = x;
  }
  oc_brick_t b = t.bricks[0];
  t.bricks[0] = t.bricks[2];
  t.bricks[2] = b;
  expect_invalid(&t, "ascending");
  oc_state_canonicalize(&t);
  expect_valid(&t);
  states_equal(&s, &t);
  /* a single root leaf is the smallest valid state */
  oc_state_free(&t);
  oc_node_t root = node(OC_KEY_ROOT, OC_NODE_UNIFORM, 0, 1e-4f, 1e-4f, 0.0f, 0.0f);
  oc_state_add_node(&t, &root);
  expect_valid(&t);
  oc_state_free(&t);
  oc_state_free(&s);
}

static void test_state__validate_rejects(void **state) {
  (void)state;
  oc_state_t g, s;
  golden_state(&g);
  oc_state_init(&s);
#define RESET() assert_int_equal(oc_state_copy(&s, &g), 0)
  RESET();
  oc_node_t x = s.nodes[3];
  s.nodes[3] = s.nodes[4], s.nodes[4] = x;
  expect_invalid(&s, "ascending order");
  RESET();
  s.nodes[4].key = s.nodes[3].key;
  expect_invalid(&s, "duplicate key");
  /* overlap: a leaf's ancestor present as well (parent of the level-2 leaves, and the root) */
  RESET();
  oc_node_t p = node(child(OC_KEY_ROOT, 7), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  oc_state_add_node(&s, &p);
  oc_state_canonicalize(&s);
  expect_invalid(&s, "overlaps its ancestor");
  RESET();
  p = node(OC_KEY_ROOT, OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  oc_state_add_node(&s, &p);
  oc_state_canonicalize(&s);
  expect_invalid(&s, "overlaps its ancestor");
  /* overlap with the volume sum still exactly 2^63: leaf 0 is traded for the eight level-2 cells
   * of leaf 1, so only the ancestor check can see it */
  RESET();
  s.nodes[0] = node(child(child(OC_KEY_ROOT, 1), 0), OC_NODE_EMPTY, 0, 0, 0, 0, 0); /* inside leaf 1 */
  for (int i = 1; i < 8; i++) {
    p = node(child(child(OC_KEY_ROOT, 1), i), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
    oc_state_add_node(&s, &p);
  }
  oc_state_canonicalize(&s);
  expect_invalid(&s, "overlaps its ancestor");
  /* gap: a missing leaf */
  RESET();
  memmove(&s.nodes[1], &s.nodes[2], (s.node_count - 2) * sizeof *s.nodes);
  s.node_count--;
  expect_invalid(&s, "gap");
  RESET();
  s.node_count = 0;
  expect_invalid(&s, "no nodes");
  RESET();
  s.nodes[0].key = 0x10; /* sentinel at bit 4: not a multiple of 3 */
  expect_invalid(&s, "invalid key");
  /* kinds and ranges */
  RESET();
  s.nodes[0].kind = 3;
  expect_invalid(&s, "bad kind");
  RESET();
  s.nodes[1].range[0].lo = NAN;
  expect_invalid(&s, "not finite");
  RESET();
  s.nodes[1].range[1].hi = INFINITY;
  expect_invalid(&s, "not finite");
  RESET();
  s.nodes[3].range[0].lo = 20.0f; /* brick, lo > hi */
  expect_invalid(&s, "lo > hi");
  RESET();
  s.nodes[1].range[1].lo = 1.0f; /* uniform lo != hi */
  expect_invalid(&s, "uniform node with tau lo != hi");
  RESET();
  s.nodes[3].range[1].lo = -1.0f;
  expect_invalid(&s, "negative");
  RESET();
  s.nodes[0].range[0].lo = -0.0f; /* −0 is not canonical */
  expect_invalid(&s, "negative");
  RESET();
  s.nodes[3].range[0].lo = 0.0f; /* lo = 0 < hi */
  expect_invalid(&s, "lo = 0 < hi");
  RESET();
  s.nodes[3].range[0].lo = 1e-9f; /* hi/lo = 1e10 */
  expect_invalid(&s, "OC_CODE_MAX_RATIO");
  RESET();
  s.nodes[1].range[0].lo = s.nodes[1].range[0].hi = 2e9f;
  expect_invalid(&s, "OC_VALUE_MAX");
  RESET();
  s.nodes[0].range[1].lo = s.nodes[0].range[1].hi = 1.0f;
  expect_invalid(&s, "empty node with non-zero range");
  RESET();
  s.nodes[2].range[1].lo = s.nodes[2].range[1].hi = 0.0f; /* uniform, both zero */
  expect_invalid(&s, "must be empty");
  RESET();
  s.nodes[1].brick_id = 5;
  expect_invalid(&s, "uniform node with brick id");
  /* brick ids */
  RESET();
  s.nodes[3].brick_id = 99;
  expect_invalid(&s, "missing brick 99");
  RESET();
  oc_brick_codes_t c;
  memset(&c, 0, sizeof c);
  oc_state_add_brick(&s, 100, &c);
  expect_invalid(&s, "brick 100 is not referenced");
  RESET();
  s.bricks[1].id = s.bricks[0].id;
  expect_invalid(&s, "is duplicated");
  RESET();
  s.bricks[0].id = 50;
  expect_invalid(&s, "out of order");
  RESET();
  s.nodes[7].brick_id = s.nodes[3].brick_id; /* two nodes, one brick */
  expect_invalid(&s, "more than one node");
  RESET();
  s.bricks[0].codes.code[1][100] = 5; /* brick 3: τ range is zero */
  expect_invalid(&s, "non-zero tau code in a zero channel");
  /* header fields */
  RESET();
  s.time = NAN;
  expect_invalid(&s, "world time");
  RESET();
  s.sun_dir = oc_dv3(0, 0, 2);
  expect_invalid(&s, "sun direction");
  RESET();
  expect_valid(&s);
  assert_int_equal(oc_state_validate(NULL, NULL, 0), OC_EINVAL);
#undef RESET
  oc_state_free(&s);
  oc_state_free(&g);
}

/*-*** Look-ups ***/

static void test_state__find(void **state) {
  (void)state;
  oc_state_t s;
  golden_state(&s);
  int64_t i = oc_state_find_node(&s, child(child(OC_KEY_ROOT, 7), 3));
  assert_true(i >= 0);
  assert_int_equal(s.nodes[i].key, child(child(OC_KEY_ROOT, 7), 3));
  assert_int_equal(oc_state_find_node(&s, child(OC_KEY_ROOT, 7)), -1);
  assert_int_equal(oc_state_find_node(&s, OC_KEY_ROOT), -1);
  /* level-21 cells: 57 more bits below a level-2 leaf, 60 below a level-1 leaf */
  oc_key_t deep = (child(child(OC_KEY_ROOT, 7), 5) << 57) | 0x0123456789ABCDEull;
  assert_int_equal(oc_state_find_leaf(&s, deep), oc_state_find_node(&s, child(child(OC_KEY_ROOT, 7), 5)));
  deep = (child(OC_KEY_ROOT, 2) << 60) | 0x0FEDCBA987654321ull;
  assert_int_equal(oc_state_find_leaf(&s, deep), oc_state_find_node(&s, child(OC_KEY_ROOT, 2)));
  assert_int_equal(oc_state_find_leaf(&s, child(OC_KEY_ROOT, 4)), oc_state_find_node(&s, child(OC_KEY_ROOT, 4)));
  assert_int_equal(oc_state_find_leaf(&s, child(OC_KEY_ROOT, 7)), -1); /* inside a finer subtree */
  assert_int_equal(oc_state_find_leaf(&s, 0), -1);
  assert_non_null(oc_state_find_brick(&s, 42));
  assert_int_equal(oc_state_find_brick(&s, 42)->id, 42);
  assert_null(oc_state_find_brick(&s, 4));
  assert_null(oc_state_find_brick(&s, 0));
  oc_state_free(&s);
}

static void test_state__copy(void **state) {
  (void)state;
  oc_state_t s, t;
  golden_state(&s);
  golden_state(&t);
  t.nodes[0].kind = OC_NODE_BRICK; /* dst content is replaced */
  assert_int_equal(oc_state_copy(&t, &s), 0);
  states_equal(&s, &t);
  t.bricks[0].codes.code[0][0] ^= 1;
  assert_true(s.bricks[0].codes.code[0][0] != t.bricks[0].codes.code[0][0]);
  assert_int_equal(oc_state_copy(&t, &t), 0);
  oc_state_free(&s);
  oc_state_free(&t);
  oc_state_free(NULL);
}

/*-*** Serialisation ***/

static void test_state__round_trip(void **state) {
  (void)state;
  oc_state_t s, t;
  size_t len;
  char why[256];
  golden_state(&s);
  uint8_t *buf = serialize(&s, &len);
  assert_int_equal(len, 64 + 15 * 32 + 3 * 2052 + 8);
  assert_int_equal(oc_state_serialize(&s, buf, len - 1), OC_ENOBUFS);
  oc_state_init(&t);
  assert_int_equal(oc_state_deserialize(&t, buf, len, why, sizeof why), 0);
  states_equal(&s, &t);
  assert_true(oc_state_checksum(&s) == oc_state_checksum(&t));
  uint64_t trailer = 0;
  for (int i = 7; i >= 0; i--) trailer = (trailer << 8) | buf[len - 8 + i];
  assert_true(trailer == oc_state_checksum(&s));
  assert_true(trailer == XXH3_64bits(buf, len - 8));
  size_t len2;
  uint8_t *buf2 = serialize(&t, &len2);
  assert_int_equal(len, len2);
  assert_memory_equal(buf, buf2, len);
  /* byte layout spot checks */
  assert_memory_equal(buf, "OCST", 4);
  assert_int_equal(buf[4], 1);
  assert_int_equal(buf[8], 42);
  assert_int_equal(buf[48], 15);
  assert_int_equal(buf[52], 3);
  assert_int_equal(buf[64], 8); /* first record: key 8 */
  assert_int_equal(buf[64 + 32 * 3 + 8], OC_NODE_BRICK);
  assert_int_equal(buf[64 + 32 * 3 + 12], 7);
  assert_int_equal(buf[64 + 15 * 32], 3); /* first brick id */
  free(buf);
  free(buf2);
  oc_state_free(&s);
  oc_state_free(&t);
}

static void test_state__checksum_sees_every_code_byte(void **state) {
  (void)state;
  oc_state_t s;
  golden_state(&s);
  uint64_t h0 = oc_state_checksum(&s);
  for (uint32_t b = 0; b < s.brick_count; b++) {
    uint8_t *p = (uint8_t *)s.bricks[b].codes.code;
    for (size_t i = 0; i < sizeof s.bricks[b].codes; i++) {
      p[i] ^= 0x01;
      assert_true(oc_state_checksum(&s) != h0);
      p[i] ^= 0x01;
    }
  }
  assert_true(oc_state_checksum(&s) == h0);
  /* also the header values and a range */
  s.epoch++;
  assert_true(oc_state_checksum(&s) != h0);
  s.epoch--;
  s.nodes[3].range[1].hi = nextafterf(s.nodes[3].range[1].hi, 100.0f);
  assert_true(oc_state_checksum(&s) != h0);
  oc_state_free(&s);
}

static void test_state__truncation(void **state) {
  (void)state;
  golden_bytes_t g;
  golden_bytes(&g);
  for (size_t n = 0; n < g.len; n++) {
    uint8_t *copy = malloc(n ? n : 1); /* exact-size copy so ASan sees any over-read */
    memcpy(copy, g.buf, n);
    int e = oc_state_deserialize(&g.t, copy, n, g.why, sizeof g.why);
    assert_true(e < 0);
    if (n >= 64 + 8) assert_int_equal(e, OC_ETRUNC);
    assert_int_equal(g.t.node_count, 0);
    assert_null(g.t.nodes);
    free(copy);
  }
  /* one byte too many */
  uint8_t *longer = malloc(g.len + 1);
  memcpy(longer, g.buf, g.len);
  longer[g.len] = 0;
  assert_int_equal(oc_state_deserialize(&g.t, longer, g.len + 1, g.why, sizeof g.why), OC_ECORRUPT);
  assert_non_null(strstr(g.why, "trailing"));
  free(longer);
  golden_bytes_free(&g);
}

static void test_state__bit_flips(void **state) {
  (void)state;
  golden_bytes_t g;
  golden_bytes(&g);
  for (size_t i = 0; i < g.len; i++)
    for (int bit = 0; bit < 8; bit++) {
      g.buf[i] ^= (uint8_t)(1u << bit);
      int e = oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why);
      assert_true(e < 0);
      assert_int_equal(g.t.node_count, 0);
      /* Magic, version and counts are checked before the checksum (identity and length first);
       * every other byte is caught by the checksum. */
      bool early = i < 8 || (i >= 48 && i < 56);
      if (!early && e != OC_ECHECKSUM) fail_msg("byte %zu bit %d: %d (%s)", i, bit, e, g.why);
      g.buf[i] ^= (uint8_t)(1u << bit);
    }
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), 0);
  golden_bytes_free(&g);
}

/* Malformed but correctly sealed input reaches the structural checks. */
static void test_state__sealed_corruption(void **state) {
  (void)state;
  golden_bytes_t g;
  golden_bytes(&g);

  g.buf[60] = 1; /* reserved header byte */
  reseal(g.buf, g.len);
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), OC_ECORRUPT);
  assert_non_null(strstr(g.why, "reserved header"));
  g.buf[60] = 0;
  g.buf[64 + 32 + 10] = 1; /* reserved record byte */
  reseal(g.buf, g.len);
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), OC_ECORRUPT);
  assert_non_null(strstr(g.why, "node 1: reserved"));
  g.buf[64 + 32 + 10] = 0;
  g.buf[64 + 32 + 8] = 9; /* kind */
  reseal(g.buf, g.len);
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), OC_ECORRUPT);
  assert_non_null(strstr(g.why, "bad kind"));
  g.buf[64 + 32 + 8] = OC_NODE_UNIFORM;
  g.buf[4] = 2; /* version */
  reseal(g.buf, g.len);
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), OC_EVERSION);
  g.buf[4] = 1;
  reseal(g.buf, g.len);
  assert_int_equal(oc_state_deserialize(&g.t, g.buf, g.len, g.why, sizeof g.why), 0);
  assert_int_equal(g.t.node_count, 15);

  /* Counts at and past the limits against a short buffer: refused before any allocation. */
  uint8_t hdr[72];
  memcpy(hdr, g.buf, 64);
  memset(hdr + 64, 0, 8);
  hdr[48] = 0, hdr[49] = 0, hdr[50] = 0, hdr[51] = 1; /* 2^24 nodes = the limit */
  assert_int_equal(oc_state_deserialize(&g.t, hdr, sizeof hdr, g.why, sizeof g.why), OC_ETRUNC);
  hdr[48] = 1;                                        /* 2^24 + 1 */
  assert_int_equal(oc_state_deserialize(&g.t, hdr, sizeof hdr, g.why, sizeof g.why), OC_ETOOBIG);
  hdr[48] = 0, hdr[51] = 0, hdr[52] = 0xFF, hdr[53] = 0xFF, hdr[54] = 0xFF, hdr[55] = 0xFF;
  assert_int_equal(oc_state_deserialize(&g.t, hdr, sizeof hdr, g.why, sizeof g.why), OC_ETOOBIG);
  assert_int_equal(oc_state_deserialize(&g.t, NULL, 0, g.why, sizeof g.why), OC_ETRUNC);
  assert_int_equal(g.t.node_count, 0);
  golden_bytes_free(&g);
}

static void test_state__golden(void **state) {
  (void)state;
  oc_state_t s;
  golden_state(&s);
  uint64_t h = oc_state_checksum(&s);
  printf("  golden state: %zu bytes, checksum 0x%016llx\n", oc_state_serialized_size(&s), (unsigned long long)h);
  assert_int_equal(oc_state_serialized_size(&s), GOLDEN_SIZE);
  assert_true(h == GOLDEN_CHECKSUM);
  oc_state_free(&s);
}

/*-*** Digest checksum (lean states) ***/

/* The digest stream built by hand from the serialisation: header and records verbatim (brick count
 * included), then per brick its 4 id bytes and the little-endian XXH3-64 of its 2048 code bytes. */
static uint64_t digest_by_hand(const oc_state_t *s) {
  size_t len;
  uint8_t *buf = serialize(s, &len);
  size_t head = OC_STATE_HEADER_BYTES + (size_t)s->node_count * OC_STATE_RECORD_BYTES;
  size_t n = head + (size_t)s->brick_count * 12;
  uint8_t *sub = malloc(n);
  assert_non_null(sub);
  memcpy(sub, buf, head);
  for (uint32_t i = 0; i < s->brick_count; i++) {
    const uint8_t *b = buf + head + (size_t)i * OC_STATE_BRICK_BYTES;
    uint8_t *e = sub + head + (size_t)i * 12;
    memcpy(e, b, 4);
    uint64_t d = XXH3_64bits(b + 4, OC_BRICK_CODE_BYTES);
    for (int k = 0; k < 8; k++) e[4 + k] = (uint8_t)(d >> (8 * k));
  }
  assert_true(len == head + (size_t)s->brick_count * OC_STATE_BRICK_BYTES + 8);
  uint64_t h = XXH3_64bits(sub, n);
  free(sub);
  free(buf);
  return h;
}

static void test_state__digest_golden(void **state) {
  (void)state;
  oc_state_t s, lean;
  golden_state(&s);
  uint64_t h = oc_state_digest(&s);
  printf("  golden state: digest checksum 0x%016llx\n", (unsigned long long)h);
  assert_true(h == digest_by_hand(&s));
  assert_true(h == GOLDEN_DIGEST);
  assert_true(h != oc_state_checksum(&s));
  /* each brick's digest is XXH3-64 of its serialised codes */
  size_t len;
  uint8_t *buf = serialize(&s, &len);
  for (uint32_t i = 0; i < s.brick_count; i++) {
    const uint8_t *b = buf + OC_STATE_HEADER_BYTES + s.node_count * OC_STATE_RECORD_BYTES + i * OC_STATE_BRICK_BYTES;
    assert_true(oc_brick_digest(&s.bricks[i].codes) == XXH3_64bits(b + 4, OC_BRICK_CODE_BYTES));
  }
  free(buf);
  /* what a lean viewer holds: the records without bricks, and the (id, digest) pairs */
  oc_brick_digests_t d = {0};
  assert_int_equal(oc_brick_digests_of(&d, &s), 0);
  assert_int_equal(d.count, 3);
  assert_int_equal(d.ids[0], 3), assert_int_equal(d.ids[1], 7), assert_int_equal(d.ids[2], 42);
  assert_int_equal(oc_brick_digests_find(&d, 7), 1);
  assert_int_equal(oc_brick_digests_find(&d, 8), -1);
  oc_state_init(&lean);
  assert_int_equal(oc_state_copy(&lean, &s), 0);
  free(lean.bricks);
  lean.bricks = NULL, lean.brick_count = lean.brick_cap = 0;
  assert_true(oc_state_digest_checksum(&lean, &d) == h); /* the header's brick count is d's */
  assert_true(oc_state_digest_checksum(&s, &d) == h);    /* s's own bricks are ignored */
  /* every code bit, id and digest is seen */
  s.bricks[1].codes.code[1][300] ^= 0x0100;
  assert_true(oc_state_digest(&s) != h);
  s.bricks[1].codes.code[1][300] ^= 0x0100;
  d.digests[2] ^= 1u << 20;
  assert_true(oc_state_digest_checksum(&lean, &d) != h);
  d.digests[2] ^= 1u << 20;
  lean.nodes[4].range[0].hi = lean.nodes[4].range[0].lo = 0.5f;
  assert_true(oc_state_digest_checksum(&lean, &d) != h);
  oc_state_free(&lean);
  oc_brick_digests_free(&d);
  oc_brick_digests_free(&d); /* idempotent */
  assert_null(d.ids);
  /* a state without bricks, and a larger one, against the hand-built stream */
  oc_state_t r;
  oc_state_init(&r);
  oc_node_t n = node(OC_KEY_ROOT, OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  oc_state_add_node(&r, &n);
  assert_true(oc_state_digest(&r) == digest_by_hand(&r));
  oc_state_free(&r);
  oc_state_free(&s);
}

/* oc_state_validate_lean() applies oc_state_validate()'s brick rules to an id list. */
static void expect_lean_invalid(const oc_state_t *s, const oc_brick_digests_t *d, const char *needle) {
  char why[256];
  int e = oc_state_validate_lean(s, d, why, sizeof why);
  if (e != OC_ECORRUPT) fail_msg("expected ECORRUPT (%s), got %d", needle, e);
  if (!strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);
}

static void test_state__validate_lean(void **state) {
  (void)state;
  oc_state_t s;
  oc_brick_digests_t d = {0};
  char why[256];
  golden_state(&s);
  assert_int_equal(oc_brick_digests_of(&d, &s), 0);
  if (oc_state_validate_lean(&s, &d, why, sizeof why)) fail_msg("%s", why);
  uint32_t id1 = d.ids[1];
  d.ids[1] = 3;
  expect_lean_invalid(&s, &d, "is duplicated");
  d.ids[1] = 50;
  expect_lean_invalid(&s, &d, "is out of order");
  d.ids[1] = 5;
  expect_lean_invalid(&s, &d, "references missing brick 7");
  d.ids[1] = id1;
  d.count = 2;
  expect_lean_invalid(&s, &d, "references missing brick 42");
  d.count = 3;
  s.nodes[14].brick_id = 7; /* brick 42 is then unreferenced, 7 twice */
  expect_lean_invalid(&s, &d, "referenced by more than one node");
  s.nodes[14].brick_id = 42;
  s.nodes[0].key = 0x10;
  expect_lean_invalid(&s, &d, "invalid key"); /* the records' rules are the same code */
  oc_state_free(&s);
  oc_brick_digests_free(&d);
}

/*-*** Files ***/

static char tmpdir[64];

OC_TEST_TMPDIR_FIXTURE(tmpdir, "state")

static void test_state__save_load(void **state) {
  (void)state;
  oc_state_t s, t;
  char path[128], why[512];
  golden_state(&s);
  oc_state_init(&t);
  snprintf(path, sizeof path, "%s/a.ocst", tmpdir);
  assert_int_equal(oc_state_save(&s, path, why, sizeof why), 0);
  assert_int_equal(oc_state_load(&t, path, why, sizeof why), 0);
  states_equal(&s, &t);
  /* the file is exactly the serialisation */
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  size_t len;
  uint8_t *buf = serialize(&s, &len), *got = malloc(len + 1);
  assert_int_equal(fread(got, 1, len + 1, f), len);
  fclose(f);
  assert_memory_equal(buf, got, len);
  char tmp[160];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  assert_null(fopen(tmp, "rb")); /* renamed, nothing left behind */

  /* a corrupt or short file: the error names the file and the cause */
  snprintf(path, sizeof path, "%s/junk.ocst", tmpdir);
  f = fopen(path, "wb");
  got[200] ^= 0x40;
  fwrite(got, 1, len, f);
  fclose(f);
  assert_int_equal(oc_state_load(&t, path, why, sizeof why), OC_ECHECKSUM);
  assert_non_null(strstr(why, path));
  assert_non_null(strstr(why, "checksum"));
  assert_int_equal(t.node_count, 0);
  snprintf(path, sizeof path, "%s/short.ocst", tmpdir);
  f = fopen(path, "wb");
  fwrite(buf, 1, 100, f);
  fclose(f);
  assert_int_equal(oc_state_load(&t, path, why, sizeof why), OC_ETRUNC);
  assert_non_null(strstr(why, path));
  assert_non_null(strstr(why, "truncated"));

  /* a missing file, and an impossible destination */
  assert_int_equal(oc_state_load(&t, "/nonexistent-oc-dir/missing.ocst", why, sizeof why), OC_ENOENT);
  assert_non_null(strstr(why, "/nonexistent-oc-dir/missing.ocst"));
  assert_non_null(strstr(why, "No such file"));
  assert_true(oc_state_save(&s, "/nonexistent-oc-dir/out.ocst", why, sizeof why) < 0);
  assert_non_null(strstr(why, "/nonexistent-oc-dir/out.ocst"));
  free(buf);
  free(got);
  oc_state_free(&s);
  oc_state_free(&t);
}

/*-*** Budget ***/

static void test_state__resident_bytes(void **state) {
  (void)state;
  oc_state_t a, b;
  golden_state(&a);
  golden_state(&b);
  /* b shares bricks 3 and 7 with a and has 43 instead of 42 */
  b.nodes[b.node_count - 1].brick_id = 43;
  b.bricks[2].id = 43;
  expect_valid(&b);
  const oc_state_t *two[] = {&a, &b};
  assert_int_equal(oc_resident_bytes(two, 2, 4096, 64), 4u * 4096u + 30u * 64u);
  const oc_state_t *one[] = {&a};
  assert_int_equal(oc_resident_bytes(one, 1, 4096, 64), 3u * 4096u + 15u * 64u);
  const oc_state_t *same[] = {&a, &a, &a};
  assert_int_equal(oc_resident_bytes(same, 3, 1000, 10), 3u * 1000u + 45u * 10u);
  const oc_state_t *many[10] = {&a, &b, &a, &b, &a, &b, &a, &b, &a, NULL};
  assert_int_equal(oc_resident_bytes(many, 10, 1, 0), 4u);
  assert_int_equal(oc_resident_bytes(NULL, 0, 1, 1), 0u);
  /* lean: the same count from the id lists */
  oc_brick_digests_t da = {0}, db = {0};
  assert_int_equal(oc_brick_digests_of(&da, &a), 0);
  assert_int_equal(oc_brick_digests_of(&db, &b), 0);
  const oc_brick_digests_t *dtwo[] = {&da, &db}, *done[] = {&da}, *dmany[10] = {&da, &db, &da, &db, &da, &db, &da, &db, &da, NULL};
  assert_int_equal(oc_resident_bytes_lean(two, dtwo, 2, 4096, 64), oc_resident_bytes(two, 2, 4096, 64));
  assert_int_equal(oc_resident_bytes_lean(one, done, 1, 4096, 64), 3u * 4096u + 15u * 64u);
  assert_int_equal(oc_resident_bytes_lean(many, dmany, 10, 1, 0), 4u);
  oc_brick_digests_free(&da);
  oc_brick_digests_free(&db);
  oc_state_free(&a);
  oc_state_free(&b);
}

/*-*** Fuzz seeds ***/

/* A root split down one corner to level 21 (7 siblings per level), one brick at the bottom. */
static void deep_state(oc_state_t *s) {
  oc_brick_codes_t c;
  state_begin(s, 7, 0.25, oc_dv3(1.0, 0.0, 0.0));
  oc_key_t k = OC_KEY_ROOT;
  for (int L = 1; L <= OC_KEY_MAX_LEVEL; L++) {
    for (int i = 1; i < 8; i++) {
      oc_node_t n = (i & 1) ? node(child(k, i), OC_NODE_UNIFORM, 0, 0.001f * (float)L, 0.001f * (float)L, 0.1f, 0.1f)
                            : node(child(k, i), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
      oc_state_add_node(s, &n);
    }
    k = child(k, 0);
  }
  oc_node_t n = node(k, OC_NODE_BRICK, 1, 0.5f, 2.0f, 0.0f, 0.0f);
  oc_state_add_node(s, &n);
  golden_codes(1, &c);
  memset(c.code[1], 0, sizeof c.code[1]);
  oc_state_add_brick(s, 1, &c);
  oc_state_canonicalize(s);
}

/* Eight brick leaves from the real encoder. */
static void bricks_state(oc_state_t *s) {
  state_begin(s, 3, 3.0, oc_dv3(0.0, 0.0, -1.0));
  for (int i = 0; i < 8; i++) {
    float sg[OC_BRICK_VOXELS], tu[OC_BRICK_VOXELS];
    oc_brick_codes_t c;
    oc_node_t n = node(child(OC_KEY_ROOT, i), OC_NODE_BRICK, (uint32_t)(100 + i), 0, 0, 0, 0);
    for (int v = 0; v < OC_BRICK_VOXELS; v++) {
      sg[v] = (v % (i + 2)) ? 0.0f : 1e-6f * (float)(1 + v) * (float)(1 << i);
      tu[v] = 0.01f * (float)(v % 13) * (float)(i + 1);
    }
    assert_int_equal(oc_brick_encode(sg, tu, &c, n.range), OC_NODE_BRICK);
    oc_state_add_node(s, &n);
    oc_state_add_brick(s, n.brick_id, &c);
  }
}

static void root_state(oc_state_t *s, int kind) {
  oc_state_init(s);
  oc_node_t n = kind == OC_NODE_EMPTY ? node(OC_KEY_ROOT, OC_NODE_EMPTY, 0, 0, 0, 0, 0)
                                      : node(OC_KEY_ROOT, OC_NODE_UNIFORM, 0, 2e-5f, 2e-5f, 0.3f, 0.3f);
  oc_state_add_node(s, &n);
}

static void test_state__fuzz_seeds(void **state) {
  (void)state;
  static const char *names[] = {"root_empty.ocst", "root_uniform.ocst", "golden.ocst", "deep.ocst", "bricks.ocst"};
  oc_state_t seeds[5], t;
  char path[1024], why[512];
  root_state(&seeds[0], OC_NODE_EMPTY);
  root_state(&seeds[1], OC_NODE_UNIFORM);
  golden_state(&seeds[2]);
  deep_state(&seeds[3]);
  bricks_state(&seeds[4]);
  oc_state_init(&t);
  const char *out = getenv("OC_FUZZ_CORPUS_OUT"), *src = getenv("OC_SOURCE_DIR");
  for (int i = 0; i < 5; i++) {
    expect_valid(&seeds[i]);
    assert_true(oc_state_serialized_size(&seeds[i]) < 20000);
    if (out) {
      snprintf(path, sizeof path, "%s/%s", out, names[i]);
      assert_int_equal(oc_state_save(&seeds[i], path, why, sizeof why), 0);
    }
    if (src) { /* the committed seeds still parse and equal what this test builds */
      snprintf(path, sizeof path, "%s/tests/fuzz/corpus/state/%s", src, names[i]);
      if (oc_state_load(&t, path, why, sizeof why) != 0) fail_msg("%s", why);
      /* bricks.ocst comes from the encoder, whose ties depend on libm's last ulp: only parsed */
      if (i != 4) states_equal(&seeds[i], &t);
    }
    oc_state_free(&seeds[i]);
  }
  oc_state_free(&t);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_state__valid_and_canonical),
             cmocka_unit_test(test_state__validate_rejects),
             cmocka_unit_test(test_state__find),
             cmocka_unit_test(test_state__copy),
             cmocka_unit_test(test_state__round_trip),
             cmocka_unit_test(test_state__checksum_sees_every_code_byte),
             cmocka_unit_test(test_state__truncation),
             cmocka_unit_test(test_state__bit_flips),
             cmocka_unit_test(test_state__sealed_corruption),
             cmocka_unit_test(test_state__golden),
             cmocka_unit_test(test_state__digest_golden),
             cmocka_unit_test(test_state__validate_lean),
             cmocka_unit_test_setup_teardown(test_state__save_load, tmpdir_setup, tmpdir_teardown),
             cmocka_unit_test(test_state__resident_bytes),
             cmocka_unit_test(test_state__fuzz_seeds))

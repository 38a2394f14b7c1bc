/* test_epoch.c — epoch payloads on the wire: record op streams, brick batches with deltas and
 * dictionaries, and the decoder's defences (proto/ocp_epoch.c; docs/protocol.md, "Epoch").
 *
 * States are built by hand: codes come from integer arithmetic, octrees from a seeded xorshift, so
 * every run sends the same bytes. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_state.h"
#include "ocp_epoch.h"
#include "ocp_wire.h"
#include "test_util.h" /* rng_u64 */
#include "state_fixture.h" /* child, node, golden_codes, golden_state */

#define VERSION OCP_VERSION_MAX

/*-*** States ***/

/* Smooth-ish codes with a little hashed noise, like a real field: gradients along x, y and z. */
static void smooth_codes(uint32_t seed, oc_brick_codes_t *c) {
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    for (uint32_t v = 0; v < OC_BRICK_VOXELS; v++) {
      uint32_t x = v & 7, y = (v >> 3) & 7, z = v >> 6;
      uint32_t h = (v + 1) * 2654435761u + seed * 0x9E3779B9u + (uint32_t)ch;
      h ^= h >> 15, h *= 0x85EBCA6Bu, h ^= h >> 13;
      uint32_t noise = h >> 27; /* 0..31, different in every brick */
      c->code[ch][v] = (uint16_t)(20000u + seed * 97u + (uint32_t)ch * 5000u + 311u * x + 1013u * y + 2039u * z + noise);
    }
}

/* A zero-range channel must hold zero codes (oc_state_validate). */
static void zero_channels(const oc_node_t *n, oc_brick_codes_t *c) {
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    if (n->range[ch].hi == 0.0f) memset(c->code[ch], 0, sizeof c->code[ch]);
}

static const float range_set[] = {1e-4f, 0.003f, 0.02f, 0.125f, 0.5f, 1.0f, 3.0f, 12.0f};

/* Content of a fresh leaf: about half bricks (new id), the rest uniform or empty. */
static void fresh_content(oc_state_t *s, oc_key_t key, uint32_t *next_id) {
  uint64_t r = rng_u64();
  oc_node_t n;
  if (r % 4 < 2) {
    float slo = range_set[(r >> 8) % 4], shi = slo * (float)(1 + (r >> 12) % 64);
    float tlo = (r >> 20) % 5 == 0 ? 0.0f : range_set[(r >> 24) % 8], thi = tlo * 4.0f;
    uint32_t id = (*next_id)++;
    n = node(key, OC_NODE_BRICK, id, slo, shi, tlo, thi);
    oc_brick_codes_t c;
    smooth_codes(id, &c);
    zero_channels(&n, &c);
    assert_int_equal(oc_state_add_brick(s, id, &c), 0);
  } else if (r % 4 == 2) {
    float v = range_set[(r >> 8) % 8];
    n = node(key, OC_NODE_UNIFORM, 0, v, v, v * 2.0f, v * 2.0f);
  } else {
    n = node(key, OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  }
  assert_int_equal(oc_state_add_node(s, &n), 0);
}

/* A random complete octree of at least `leaves` leaves (levels ≤ max_level). */
static void random_state(oc_state_t *s, uint64_t epoch, uint32_t leaves, int max_level, uint32_t *next_id) {
  oc_key_t *keys = malloc(sizeof *keys * (leaves + 8));
  assert_non_null(keys);
  uint32_t n = 1;
  keys[0] = OC_KEY_ROOT;
  while (n < leaves) {
    uint32_t i = (uint32_t)(rng_u64() % n);
    if (oc_key_level(keys[i]) >= max_level) continue;
    oc_key_t k = keys[i];
    keys[i] = child(k, 0);
    for (int c = 1; c < 8; c++) keys[n++] = child(k, c);
  }
  state_begin(s, epoch, 10.0 * (double)epoch, oc_dv3(0.0, 0.6, 0.8));
  for (uint32_t i = 0; i < n; i++) fresh_content(s, keys[i], next_id);
  oc_state_canonicalize(s);
  free(keys);
  char why[256];
  if (oc_state_validate(s, why, sizeof why)) fail_msg("random state invalid: %s", why);
}

static int is_parent_run(const oc_state_t *s, uint32_t i) {
  if (i + 8 > s->node_count || oc_key_level(s->nodes[i].key) < 2) return 0;
  oc_key_t p = s->nodes[i].key >> 3;
  for (int c = 0; c < 8; c++)
    if (s->nodes[i + (uint32_t)c].key != child(p, c)) return 0;
  return 1;
}

/* The next epoch of `a`: most records kept; one record in ten refreshed with its ranges (a delta
 * on each non-zero channel), one in ten refreshed with a new σt range (whole), one in twenty split,
 * and up to two groups of eight siblings merged. *deltas: the channels expected as deltas. */
static void next_state(const oc_state_t *a, oc_state_t *b, uint32_t *next_id, uint32_t *deltas) {
  oc_state_init(b);
  b->epoch = a->epoch + 1;
  b->time = a->time + 10.0;
  b->sun_dir = a->sun_dir;
  *deltas = 0;
  int merges = 0;
  for (uint32_t i = 0; i < a->node_count;) {
    const oc_node_t *n = &a->nodes[i];
    if (merges < 2 && i > 20 && is_parent_run(a, i)) {
      oc_node_t p = node(n->key >> 3, OC_NODE_UNIFORM, 0, 0.25f, 0.25f, 1.0f, 1.0f);
      assert_int_equal(oc_state_add_node(b, &p), 0);
      merges++;
      i += 8;
      continue;
    }
    const oc_brick_t *old = n->kind == OC_NODE_BRICK ? oc_state_find_brick(a, n->brick_id) : NULL;
    oc_node_t m = *n;
    oc_brick_codes_t c;
    switch (i % 10) {
      case 0: /* same ranges, slightly changed content: a delta */
        if (!old) break;
        c = old->codes;
        for (int ch = 0; ch < OC_CHANNELS; ch++) {
          if (m.range[ch].hi == 0.0f) continue;
          for (int v = 0; v < OC_BRICK_VOXELS; v += 7) c.code[ch][v] = (uint16_t)(c.code[ch][v] + 3u + (uint32_t)(v % 5));
          (*deltas)++;
        }
        m.brick_id = (*next_id)++;
        assert_int_equal(oc_state_add_brick(b, m.brick_id, &c), 0);
        assert_int_equal(oc_state_add_node(b, &m), 0);
        i++;
        continue;
      case 1: /* σt range changed: whole on σt, τ (unchanged range) still a delta */
        if (!old) break;
        c = old->codes;
        for (int v = 0; v < OC_BRICK_VOXELS; v++) c.code[0][v] = (uint16_t)(c.code[0][v] / 2u + 1u);
        m.range[0].hi *= 2.0f;
        *deltas += m.range[1].hi != 0.0f;
        m.brick_id = (*next_id)++;
        assert_int_equal(oc_state_add_brick(b, m.brick_id, &c), 0);
        assert_int_equal(oc_state_add_node(b, &m), 0);
        i++;
        continue;
      case 2: /* split (one record in twenty) */
        if (i % 20 != 2 || oc_key_level(n->key) >= 12) break;
        for (int k = 0; k < 8; k++) fresh_content(b, child(n->key, k), next_id);
        i++;
        continue;
      default: break;
    }
    assert_int_equal(oc_state_add_node(b, &m), 0); /* kept as is, with its brick */
    if (old) assert_int_equal(oc_state_add_brick(b, old->id, &old->codes), 0);
    i++;
  }
  assert_int_equal(merges, 2);
  oc_state_canonicalize(b);
  char why[256];
  if (oc_state_validate(b, why, sizeof why)) fail_msg("next state invalid: %s", why);
}

/* Ids of `s`'s bricks that `held` lacks (all of them without `held`), ascending. */
static uint32_t *lacking_ids(const oc_state_t *s, const oc_state_t *held, uint32_t *n) {
  uint32_t *ids = malloc(sizeof *ids * (s->brick_count + 1));
  assert_non_null(ids);
  *n = 0;
  for (uint32_t i = 0; i < s->brick_count; i++)
    if (!held || !oc_state_find_brick(held, s->bricks[i].id)) ids[(*n)++] = s->bricks[i].id;
  return ids;
}

/*-*** Frames ***/

typedef struct {
  uint8_t type;
  const uint8_t *p;
  uint32_t n;
} frame_t;

typedef struct {
  frame_t *f;
  int n;
} frames_t;

static void split_frames(const oc_buf_t *b, frames_t *fs) {
  fs->n = 0;
  fs->f = NULL;
  int cap = 0;
  for (size_t at = 0; at < b->len;) {
    ocp_header_t h;
    assert_true(b->len - at >= OCP_HEADER_BYTES);
    assert_int_equal(ocp_header_parse(b->data + at, OCP_MAX_PAYLOAD, &h), 0);
    assert_int_equal(h.version, VERSION);
    assert_true(b->len - at - OCP_HEADER_BYTES >= h.length);
    if (fs->n == cap) {
      cap = cap ? 2 * cap : 16;
      fs->f = realloc(fs->f, sizeof *fs->f * (size_t)cap);
      assert_non_null(fs->f);
    }
    fs->f[fs->n++] = (frame_t){h.type, b->data + at + OCP_HEADER_BYTES, h.length};
    at += OCP_HEADER_BYTES + h.length;
  }
}

static int count_type(const frames_t *fs, uint8_t type) {
  int n = 0;
  for (int i = 0; i < fs->n; i++) n += fs->f[i].type == type;
  return n;
}

static int find_type(const frames_t *fs, uint8_t type, int nth) {
  for (int i = 0; i < fs->n; i++)
    if (fs->f[i].type == type && nth-- == 0) return i;
  fail_msg("no frame of type 0x%02x", type);
  return -1;
}

/* Bricks the viewer holds: those of up to two states, optionally one id answered wrongly. */
typedef struct {
  const oc_state_t *held[2];
  uint32_t bad_id;                /* 0: none */
  const oc_brick_codes_t *bad;    /* what bad_id returns (NULL: not held) */
  uint32_t calls;
} held_t;

static const oc_brick_codes_t *lookup(void *ctx, uint32_t id) {
  held_t *h = ctx;
  h->calls++;
  if (h->bad_id && id == h->bad_id) return h->bad;
  for (int i = 0; i < 2; i++) {
    const oc_brick_t *b = h->held[i] ? oc_state_find_brick(h->held[i], id) : NULL;
    if (b) return &b->codes;
  }
  return NULL;
}

/* Feeds frames to d as a viewer would. @return 0 once an EPOCH_END succeeded (state in *out), or
 * the first error (reason in why). (With decode_lean, below.) */
static int decode_frames(ocp_epoch_dec_t *d, const frames_t *fs, const oc_state_t *base, held_t *h, oc_state_t *out, char *why,
                         size_t why_len);

static void encode(const ocp_enc_desc_t *desc, const oc_state_t *s, const oc_state_t *base, const uint32_t *lacking, uint32_t n,
                   oc_buf_t *out, ocp_enc_stats_t *st) {
  ocp_epoch_enc_t *e = NULL;
  assert_int_equal(ocp_epoch_enc_create(&e, desc), 0);
  assert_int_equal(ocp_epoch_enc_begin(e, s, base, lacking, n), 0);
  size_t start = out->len;
  int r, frames = 0;
  while ((r = ocp_epoch_enc_next(e, VERSION, out)) == 1) frames++;
  assert_int_equal(r, 0);
  assert_int_equal(ocp_epoch_enc_next(e, VERSION, out), 0); /* stays done */
  ocp_enc_stats_t s0;
  ocp_epoch_enc_stats(e, &s0);
  assert_int_equal(s0.frames, (uint64_t)frames);
  assert_int_equal(s0.wire_bytes, out->len - start);
  assert_int_equal(s0.bricks, n);
  assert_int_equal(s0.delta_channels + s0.full_channels, 2 * n);
  if (st) *st = s0;
  ocp_epoch_enc_free(e);
}

/* A new decoder decodes fs on base (NULL: none; the viewer holds base's bricks) into *t; any error
 * fails the test. @return the decoder (the caller frees it and *t). */
static ocp_epoch_dec_t *decode_ok(const frames_t *fs, const oc_state_t *base, oc_state_t *t) {
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  held_t h = {{base, NULL}, 0, NULL, 0};
  oc_state_init(t);
  char why[512];
  int r = decode_frames(d, fs, base, &h, t, why, sizeof why);
  if (r) fail_msg("decode failed (%d): %s", r, why);
  return d;
}

/* Encode (no base), decode, compare. @return the wire bytes. */
static size_t round_trip(const ocp_enc_desc_t *desc, const oc_state_t *s, frames_t *keep_frames, oc_buf_t *keep_buf) {
  uint32_t n;
  uint32_t *ids = lacking_ids(s, NULL, &n);
  oc_buf_t b = {0};
  encode(desc, s, NULL, ids, n, &b, NULL);
  frames_t fs;
  split_frames(&b, &fs);
  assert_int_equal(fs.f[0].type, OCP_MSG_EPOCH_BEGIN);
  assert_int_equal(fs.f[fs.n - 1].type, OCP_MSG_EPOCH_END);
  assert_true(count_type(&fs, OCP_MSG_RECORDS) >= 1);
  oc_state_t t;
  ocp_epoch_dec_t *d = decode_ok(&fs, NULL, &t);
  assert_false(ocp_epoch_dec_active(d));
  states_equal(s, &t);
  size_t len = b.len;
  oc_state_free(&t);
  ocp_epoch_dec_free(d);
  free(ids);
  if (keep_frames) {
    *keep_frames = fs;
    *keep_buf = b;
  } else {
    free(fs.f);
    oc_buf_free(&b);
  }
  return len;
}

/*-*** Round trips ***/

static void test_epoch__full_round_trip(void **state) {
  (void)state;
  oc_state_t s;
  golden_state(&s);
  ocp_enc_desc_t desc = {.deltas = 1};
  round_trip(&desc, &s, NULL, NULL);
  oc_state_free(&s);

  uint32_t next_id = 1;
  random_state(&s, 5, 400, 8, &next_id);
  assert_true(s.brick_count > 100);
  size_t full = round_trip(&desc, &s, NULL, NULL);
  /* smooth codes compress: well under the raw 2060 bytes a brick */
  assert_true(full < (size_t)s.brick_count * 2060u + (size_t)s.node_count * 33u);
  /* a state without bricks: no BRICKS frame at all */
  oc_state_t u;
  oc_state_init(&u);
  oc_node_t root = node(OC_KEY_ROOT, OC_NODE_UNIFORM, 0, 1e-4f, 1e-4f, 0.0f, 0.0f);
  oc_state_add_node(&u, &root);
  frames_t fs;
  oc_buf_t b;
  round_trip(&desc, &u, &fs, &b);
  assert_int_equal(fs.n, 3);
  assert_int_equal(count_type(&fs, OCP_MSG_BRICKS), 0);
  free(fs.f);
  oc_buf_free(&b);
  oc_state_free(&u);
  oc_state_free(&s);
}

typedef struct {
  oc_state_t a, b;
  uint32_t next_id, deltas, nlacking;
  uint32_t *lacking;
} pair_t;

static void make_pair(pair_t *p, uint32_t leaves) {
  p->next_id = 1;
  random_state(&p->a, 7, leaves, 9, &p->next_id);
  next_state(&p->a, &p->b, &p->next_id, &p->deltas);
  p->lacking = lacking_ids(&p->b, &p->a, &p->nlacking);
}

static void free_pair(pair_t *p) {
  oc_state_free(&p->a);
  oc_state_free(&p->b);
  free(p->lacking);
}

static void test_epoch__diff_round_trip(void **state) {
  (void)state;
  pair_t p;
  make_pair(&p, 500);
  assert_true(p.deltas > 10);
  assert_true(p.nlacking > 0 && p.nlacking < p.b.brick_count);
  size_t wire[2];
  for (int deltas = 0; deltas < 2; deltas++) {
    ocp_enc_desc_t desc = {.deltas = deltas};
    oc_buf_t b = {0};
    ocp_enc_stats_t st;
    encode(&desc, &p.b, &p.a, p.lacking, p.nlacking, &b, &st);
    assert_true(st.records_kept > p.b.node_count / 2);
    assert_int_equal(st.records_kept + st.records_added, p.b.node_count);
    assert_int_equal(st.delta_channels, deltas ? p.deltas : 0);
    assert_true(st.raw_bytes > st.wire_bytes);
    frames_t fs;
    split_frames(&b, &fs);
    oc_state_t t;
    ocp_epoch_dec_t *d = decode_ok(&fs, &p.a, &t);
    states_equal(&p.b, &t);
    wire[deltas] = b.len;
    oc_state_free(&t);
    ocp_epoch_dec_free(d);
    free(fs.f);
    oc_buf_free(&b);
  }
  ocp_enc_desc_t desc = {.deltas = 1};
  size_t full = round_trip(&desc, &p.b, NULL, NULL);
  print_message("diff epoch: %zu bytes without deltas, %zu with, full %zu\n", wire[0], wire[1], full);
  assert_true(wire[1] < wire[0]); /* small changes: deltas compress better than x-prediction */
  assert_true(wire[1] < full);
  /* the same state as its own base: one KEEP, nothing sent */
  oc_buf_t b = {0};
  ocp_enc_stats_t st;
  encode(&desc, &p.b, &p.b, NULL, 0, &b, &st);
  assert_int_equal(st.records_kept, p.b.node_count);
  assert_int_equal(st.records_added, 0);
  assert_int_equal(st.frames, 3);
  oc_buf_free(&b);
  free_pair(&p);
}

/* A base brick that differs from the server's gives a different state: the checksum catches it. */
static void test_epoch__wrong_delta_base(void **state) {
  (void)state;
  pair_t p;
  make_pair(&p, 300);
  /* the old brick of record 0 mod 10 that was refreshed with a delta */
  uint32_t base_id = 0;
  for (uint32_t i = 0; i < p.a.node_count && !base_id; i++) {
    const oc_node_t *n = &p.a.nodes[i];
    if (n->kind != OC_NODE_BRICK) continue;
    int64_t j = oc_state_find_node(&p.b, n->key);
    if (j >= 0 && p.b.nodes[j].kind == OC_NODE_BRICK && p.b.nodes[j].brick_id != n->brick_id &&
        !memcmp(p.b.nodes[j].range, n->range, sizeof n->range))
      base_id = n->brick_id;
  }
  assert_true(base_id != 0);
  oc_brick_codes_t bad = oc_state_find_brick(&p.a, base_id)->codes;
  for (int ch = 0; ch < OC_CHANNELS; ch++) bad.code[ch][100] ^= 0x40;

  ocp_enc_desc_t desc = {.deltas = 1};
  oc_buf_t b = {0};
  encode(&desc, &p.b, &p.a, p.lacking, p.nlacking, &b, NULL);
  frames_t fs;
  split_frames(&b, &fs);
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  oc_state_t t;
  oc_state_init(&t);
  char why[512];
  held_t h = {{&p.a, NULL}, base_id, &bad, 0};
  int r = decode_frames(d, &fs, &p.a, &h, &t, why, sizeof why);
  assert_int_equal(r, OC_ECHECKSUM);
  assert_non_null(strstr(why, "checksum mismatch"));
  assert_non_null(strstr(why, "state epoch 8"));
  assert_int_equal(t.node_count, 0); /* out untouched */
  assert_false(ocp_epoch_dec_active(d));

  /* the base not held at all: malformed, named */
  h = (held_t){{&p.a, NULL}, base_id, NULL, 0};
  r = decode_frames(d, &fs, &p.a, &h, &t, why, sizeof why);
  assert_int_equal(r, OC_ECORRUPT);
  char needle[64];
  snprintf(needle, sizeof needle, "delta base %u not held", base_id);
  if (!strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);

  /* a kept brick the viewer lost: neither sent nor held */
  uint32_t kept = 0;
  for (uint32_t i = 0; i < p.b.brick_count && !kept; i++)
    if (oc_state_find_brick(&p.a, p.b.bricks[i].id)) kept = p.b.bricks[i].id;
  assert_true(kept != 0);
  h = (held_t){{&p.a, NULL}, kept, NULL, 0};
  r = decode_frames(d, &fs, &p.a, &h, &t, why, sizeof why);
  assert_int_equal(r, OC_ECORRUPT);
  assert_non_null(strstr(why, "neither sent nor held"));

  /* and the honest decode still works with the same decoder */
  h = (held_t){{&p.a, NULL}, 0, NULL, 0};
  assert_int_equal(decode_frames(d, &fs, &p.a, &h, &t, why, sizeof why), 0);
  states_equal(&p.b, &t);
  oc_state_free(&t);
  ocp_epoch_dec_free(d);
  free(fs.f);
  oc_buf_free(&b);
  free_pair(&p);
}

/*-*** Lean decoding (OCP_CAP_DIGEST) ***/

/* Digests a lean viewer holds: those of up to two states, optionally one id answered wrongly. */
typedef struct {
  const oc_brick_digests_t *held[2];
  uint32_t bad_id;      /* 0: none */
  int bad_missing;      /* bad_id is not held */
  uint64_t bad_digest;  /* else what bad_id returns */
} lean_held_t;

static int lean_lookup(void *ctx, uint32_t id, uint64_t *digest) {
  const lean_held_t *h = ctx;
  if (h->bad_id && id == h->bad_id) {
    *digest = h->bad_digest;
    return !h->bad_missing;
  }
  for (int i = 0; i < 2; i++) {
    int64_t k = oc_brick_digests_find(h->held[i], id);
    if (k >= 0) {
      *digest = h->held[i]->digests[k];
      return 1;
    }
  }
  return 0;
}

/* decode_frames() for a full viewer (h) or a lean one (lh: bricks as digests into *dig). */
static int decode_with(ocp_epoch_dec_t *d, const frames_t *fs, const oc_state_t *base, held_t *h, lean_held_t *lh,
                       oc_state_t *out, oc_brick_digests_t *dig, char *why, size_t why_len) {
  int r = OC_ECORRUPT;
  snprintf(why, why_len, "no epoch end");
  for (int i = 0; i < fs->n; i++) {
    const frame_t *f = &fs->f[i];
    switch (f->type) {
      case OCP_MSG_EPOCH_BEGIN: {
        ocp_epoch_begin_t m;
        if ((r = ocp_get_epoch_begin(f->p, f->n, &m, why, why_len)) < 0) return r;
        const oc_state_t *b = m.base_epoch == OCP_NO_BASE ? NULL : base;
        r = lh ? ocp_epoch_dec_begin_lean(d, &m, b, lean_lookup, lh, why, why_len) : ocp_epoch_dec_begin(d, &m, b, lookup, h, why, why_len);
        break;
      }
      case OCP_MSG_RECORDS: r = ocp_epoch_dec_records(d, f->p, f->n, why, why_len); break;
      case OCP_MSG_BRICKS: r = ocp_epoch_dec_bricks(d, f->p, f->n, why, why_len); break;
      case OCP_MSG_DICT: r = ocp_epoch_dec_dict(d, f->p, f->n, why, why_len); break;
      case OCP_MSG_EPOCH_END: {
        ocp_epoch_end_t m;
        if ((r = ocp_get_epoch_end(f->p, f->n, &m, why, why_len)) < 0) return r;
        r = lh ? ocp_epoch_dec_end_lean(d, &m, out, dig, why, why_len) : ocp_epoch_dec_end(d, &m, out, why, why_len);
        if (r == 0) return 0;
        break;
      }
      default: fail_msg("unexpected frame type 0x%02x", f->type);
    }
    if (r < 0) return r;
  }
  return OC_ECORRUPT;
}

static int decode_frames(ocp_epoch_dec_t *d, const frames_t *fs, const oc_state_t *base, held_t *h, oc_state_t *out, char *why,
                         size_t why_len) {
  return decode_with(d, fs, base, h, NULL, out, NULL, why, why_len);
}

/* decode_frames() for a lean viewer: records into *out, bricks as digests into *dig. */
static int decode_lean(ocp_epoch_dec_t *d, const frames_t *fs, const oc_state_t *base, lean_held_t *h, oc_state_t *out,
                       oc_brick_digests_t *dig, char *why, size_t why_len) {
  return decode_with(d, fs, base, NULL, h, out, dig, why, why_len);
}

/* Decodes fs lean with frame `at` replaced by (p, n) (at < 0: as is); expects `err` with `needle`. */
static void expect_lean_bad(const frames_t *fs, int at, const uint8_t *p, uint32_t n, const oc_state_t *base, lean_held_t *h,
                            int err, const char *needle) {
  frames_t g = {malloc(sizeof *g.f * (size_t)fs->n), fs->n};
  assert_non_null(g.f);
  memcpy(g.f, fs->f, sizeof *g.f * (size_t)fs->n);
  if (at >= 0) g.f[at].p = p, g.f[at].n = n;
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  oc_state_t t;
  oc_brick_digests_t dig = {0};
  oc_state_init(&t);
  char why[512] = "";
  int r = decode_lean(d, &g, base, h, &t, &dig, why, sizeof why);
  if (r != err) fail_msg("expected %s (%s), got %d: %s", oc_err_name(err), needle, r, why);
  if (needle && !strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);
  assert_int_equal(t.node_count, 0);
  assert_int_equal(dig.count, 0);
  assert_false(ocp_epoch_dec_active(d));
  ocp_epoch_dec_free(d);
  free(g.f);
}

static void test_epoch__lean(void **state) {
  (void)state;
  pair_t p;
  make_pair(&p, 300);
  ocp_enc_desc_t lean = {.digest = 1};
  char why[512];
  /* the first state whole, then the second as a difference (kept bricks found as digests) */
  uint32_t na;
  uint32_t *all_a = lacking_ids(&p.a, NULL, &na);
  oc_buf_t ba = {0}, bb = {0};
  encode(&lean, &p.a, NULL, all_a, na, &ba, NULL);
  ocp_enc_stats_t st;
  encode(&lean, &p.b, &p.a, p.lacking, p.nlacking, &bb, &st);
  assert_int_equal(st.delta_channels, 0); /* never a delta to a lean viewer */
  frames_t fa, fb;
  split_frames(&ba, &fa);
  split_frames(&bb, &fb);
  ocp_epoch_end_t end;
  assert_int_equal(ocp_get_epoch_end(fb.f[fb.n - 1].p, fb.f[fb.n - 1].n, &end, why, sizeof why), 0);
  assert_true(end.checksum == oc_state_digest(&p.b));
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  oc_state_t la, lb;
  oc_brick_digests_t da = {0}, db = {0};
  oc_state_init(&la);
  oc_state_init(&lb);
  lean_held_t h = {{NULL, NULL}, 0, 0, 0};
  if (decode_lean(d, &fa, NULL, &h, &la, &da, why, sizeof why)) fail_msg("lean decode a: %s", why);
  expect_lean_equal(&p.a, &la, &da);
  h.held[0] = &da;
  if (decode_lean(d, &fb, &la, &h, &lb, &db, why, sizeof why)) fail_msg("lean decode b: %s", why);
  expect_lean_equal(&p.b, &lb, &db);
  assert_true(p.nlacking < p.b.brick_count); /* some digests did come from what was held */

  /* a held digest that differs from the server's brick: the digest checksum catches it */
  uint32_t kept = 0;
  for (uint32_t i = 0; i < p.b.brick_count && !kept; i++)
    if (oc_state_find_brick(&p.a, p.b.bricks[i].id)) kept = p.b.bricks[i].id;
  assert_true(kept != 0);
  h.bad_id = kept, h.bad_digest = da.digests[oc_brick_digests_find(&da, kept)] ^ 0x80;
  expect_lean_bad(&fb, -1, NULL, 0, &la, &h, OC_ECHECKSUM, "digest checksum mismatch");
  h.bad_missing = 1;
  expect_lean_bad(&fb, -1, NULL, 0, &la, &h, OC_ECORRUPT, "neither sent nor held");
  h.bad_id = 0, h.bad_missing = 0;

  /* one bit of one sent brick flipped (its record unchanged): caught by the digest checksum */
  oc_state_t flipped;
  oc_state_init(&flipped);
  assert_int_equal(oc_state_copy(&flipped, &p.b), 0);
  oc_brick_t *fbk = (oc_brick_t *)oc_state_find_brick(&flipped, p.lacking[0]);
  const oc_node_t *fn = NULL;
  for (uint32_t i = 0; i < flipped.node_count; i++)
    if (flipped.nodes[i].brick_id == fbk->id) fn = &flipped.nodes[i];
  assert_non_null(fn);
  fbk->codes.code[fn->range[0].hi != 0.0f ? 0 : 1][77] ^= 0x0004;
  oc_buf_t bf = {0};
  encode(&lean, &flipped, &p.a, p.lacking, p.nlacking, &bf, NULL);
  frames_t ff;
  split_frames(&bf, &ff);
  assert_int_equal(ff.n, fb.n);
  /* the server's EPOCH_END for the honest state after the flipped bricks */
  expect_lean_bad(&ff, ff.n - 1, fb.f[fb.n - 1].p, fb.f[fb.n - 1].n, &la, &h, OC_ECHECKSUM, "digest checksum mismatch");
  /* a byte of a compressed batch flipped: zstd or the digest checksum refuses it */
  int at = find_type(&fb, OCP_MSG_BRICKS, 0);
  uint8_t *bad = malloc(fb.f[at].n);
  assert_non_null(bad);
  memcpy(bad, fb.f[at].p, fb.f[at].n);
  bad[fb.f[at].n / 2] ^= 0x10;
  {
    frames_t g = {malloc(sizeof *g.f * (size_t)fb.n), fb.n};
    memcpy(g.f, fb.f, sizeof *g.f * (size_t)fb.n);
    g.f[at].p = bad;
    ocp_epoch_dec_t *d2 = NULL;
    assert_int_equal(ocp_epoch_dec_create(&d2), 0);
    oc_state_t t;
    oc_brick_digests_t dt = {0};
    oc_state_init(&t);
    int r = decode_lean(d2, &g, &la, &h, &t, &dt, why, sizeof why);
    assert_true(r == OC_ECORRUPT || r == OC_ECHECKSUM);
    assert_int_equal(dt.count, 0);
    ocp_epoch_dec_free(d2);
    free(g.f);
  }
  free(bad);

  /* a non-zero code in a zero channel: refused as it arrives (the codes are not kept to check later) */
  oc_state_t z;
  oc_state_init(&z);
  assert_int_equal(oc_state_copy(&z, &p.a), 0);
  uint32_t zid = 0;
  for (uint32_t i = 0; i < z.node_count && !zid; i++)
    if (z.nodes[i].kind == OC_NODE_BRICK && z.nodes[i].range[1].hi == 0.0f) zid = z.nodes[i].brick_id;
  assert_true(zid != 0);
  ((oc_brick_t *)oc_state_find_brick(&z, zid))->codes.code[1][5] = 9;
  oc_buf_t bz = {0};
  encode(&lean, &z, NULL, all_a, na, &bz, NULL);
  frames_t fz;
  split_frames(&bz, &fz);
  h = (lean_held_t){{NULL, NULL}, 0, 0, 0};
  char needle[64];
  snprintf(needle, sizeof needle, "brick %u: non-zero tau code in a zero channel", zid);
  expect_lean_bad(&fz, -1, NULL, 0, NULL, &h, OC_ECORRUPT, needle);

  /* a delta is malformed for a lean viewer; and an epoch ends the way it began */
  ocp_enc_desc_t full = {.deltas = 1};
  oc_buf_t bd = {0};
  encode(&full, &p.b, &p.a, p.lacking, p.nlacking, &bd, NULL);
  frames_t fd;
  split_frames(&bd, &fd);
  h.held[0] = &da;
  expect_lean_bad(&fd, -1, NULL, 0, &la, &h, OC_ECORRUPT, "to a lean viewer");
  ocp_epoch_begin_t m;
  assert_int_equal(ocp_get_epoch_begin(fa.f[0].p, fa.f[0].n, &m, why, sizeof why), 0);
  assert_int_equal(ocp_epoch_dec_begin_lean(d, &m, NULL, lean_lookup, &h, why, sizeof why), 0);
  for (int i = 1; i < fa.n - 1; i++)
    assert_int_equal(fa.f[i].type == OCP_MSG_RECORDS ? ocp_epoch_dec_records(d, fa.f[i].p, fa.f[i].n, why, sizeof why)
                                                     : ocp_epoch_dec_bricks(d, fa.f[i].p, fa.f[i].n, why, sizeof why),
                     0);
  assert_int_equal(ocp_get_epoch_end(fa.f[fa.n - 1].p, fa.f[fa.n - 1].n, &end, why, sizeof why), 0);
  oc_state_t t;
  oc_state_init(&t);
  assert_int_equal(ocp_epoch_dec_end(d, &end, &t, why, sizeof why), OC_EINVAL);
  assert_false(ocp_epoch_dec_active(d));
  /* a full viewer refuses the digest form: its checksum is another */
  held_t fh = {{NULL, NULL}, 0, NULL, 0};
  assert_int_equal(decode_frames(d, &fa, NULL, &fh, &t, why, sizeof why), OC_ECHECKSUM);
  /* digest and deltas together: refused by the encoder */
  ocp_epoch_enc_t *e = NULL;
  ocp_enc_desc_t both = {.digest = 1, .deltas = 1};
  assert_int_equal(ocp_epoch_enc_create(&e, &both), OC_EINVAL);
  assert_null(e);
  /* the encoder's checksum is EPOCH_END's, in its form */
  assert_int_equal(ocp_epoch_enc_create(&e, &lean), 0);
  assert_int_equal(ocp_epoch_enc_checksum(e), 0);
  assert_int_equal(ocp_epoch_enc_begin(e, &p.a, NULL, all_a, na), 0);
  assert_true(ocp_epoch_enc_checksum(e) == oc_state_digest(&p.a));
  ocp_epoch_enc_free(e);
  assert_int_equal(ocp_epoch_enc_create(&e, &full), 0);
  assert_int_equal(ocp_epoch_enc_begin(e, &p.a, NULL, all_a, na), 0);
  assert_true(ocp_epoch_enc_checksum(e) == oc_state_checksum(&p.a));
  ocp_epoch_enc_free(e);

  oc_state_free(&t);
  oc_state_free(&z);
  oc_state_free(&flipped);
  oc_state_free(&la);
  oc_state_free(&lb);
  oc_brick_digests_free(&da);
  oc_brick_digests_free(&db);
  ocp_epoch_dec_free(d);
  free(all_a);
  free(fa.f), free(fb.f), free(ff.f), free(fz.f), free(fd.f);
  oc_buf_free(&ba), oc_buf_free(&bb), oc_buf_free(&bf), oc_buf_free(&bz), oc_buf_free(&bd);
  free_pair(&p);
}

/*-*** Hostile input ***/

/* A new decoder's result for fs on base (the reason in why); a failed decode leaves the state empty. */
static int decode_once(const frames_t *fs, const oc_state_t *base, char *why, size_t why_len) {
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  held_t h = {{base, NULL}, 0, NULL, 0};
  oc_state_t t;
  oc_state_init(&t);
  int r = decode_frames(d, fs, base, &h, &t, why, why_len);
  if (r) assert_int_equal(t.node_count, 0);
  oc_state_free(&t);
  ocp_epoch_dec_free(d);
  return r;
}

/* Decodes fs with frame `at` replaced by (p, n); expects `err` with `needle` in the reason. */
static void expect_bad(const frames_t *fs, int at, const uint8_t *p, uint32_t n, const oc_state_t *base, int err, const char *needle) {
  frames_t g = {malloc(sizeof *g.f * (size_t)fs->n), fs->n};
  assert_non_null(g.f);
  memcpy(g.f, fs->f, sizeof *g.f * (size_t)fs->n);
  if (at >= 0) g.f[at].p = p, g.f[at].n = n;
  char why[512] = "";
  int r = decode_once(&g, base, why, sizeof why);
  if (r != err) fail_msg("expected %s (%s), got %d: %s", oc_err_name(err), needle, r, why);
  if (needle && !strstr(why, needle)) fail_msg("reason '%s' lacks '%s'", why, needle);
  free(g.f);
}

static void test_epoch__bad_zstd(void **state) {
  (void)state;
  uint32_t next_id = 1;
  oc_state_t s;
  random_state(&s, 3, 300, 8, &next_id);
  ocp_enc_desc_t desc = {.deltas = 1};
  frames_t fs;
  oc_buf_t b;
  round_trip(&desc, &s, &fs, &b);
  int rec = find_type(&fs, OCP_MSG_RECORDS, 0), bri = find_type(&fs, OCP_MSG_BRICKS, 0);
  uint8_t *copy = malloc((fs.f[rec].n > fs.f[bri].n ? fs.f[rec].n : fs.f[bri].n) + 16);
  assert_non_null(copy);
  const frame_t *R = &fs.f[rec], *B = &fs.f[bri];
  /* truncated */
  for (uint32_t cut = 1; cut < 8; cut++) expect_bad(&fs, rec, R->p, R->n - cut, NULL, OC_ECORRUPT, "records");
  expect_bad(&fs, rec, R->p, 3, NULL, OC_ECORRUPT, "too short");
  expect_bad(&fs, bri, B->p, B->n - 1, NULL, OC_ECORRUPT, "bricks");
  expect_bad(&fs, bri, B->p, 8, NULL, OC_ECORRUPT, "bricks");
  /* garbled zstd magic */
  memcpy(copy, R->p, R->n);
  copy[4] ^= 0xFF;
  expect_bad(&fs, rec, copy, R->n, NULL, OC_ECORRUPT, "not a zstd frame");
  /* raw length disagreeing with the frame's content size, or out of range */
  memcpy(copy, R->p, R->n);
  oc_put_u32(copy, oc_get_u32(R->p) + 1);
  expect_bad(&fs, rec, copy, R->n, NULL, OC_ECORRUPT, "raw length says");
  oc_put_u32(copy, 0);
  expect_bad(&fs, rec, copy, R->n, NULL, OC_ECORRUPT, "raw length 0");
  oc_put_u32(copy, OCP_CHUNK_RAW_MAX + 1);
  expect_bad(&fs, rec, copy, R->n, NULL, OC_ECORRUPT, "raw length");
  /* trailing bytes after the frame */
  memcpy(copy, R->p, R->n);
  memset(copy + R->n, 0, 8);
  expect_bad(&fs, rec, copy, R->n + 8, NULL, OC_ECORRUPT, "exactly one zstd frame");
  memcpy(copy, B->p, B->n);
  memset(copy + B->n, 0, 8);
  expect_bad(&fs, bri, copy, B->n + 8, NULL, OC_ECORRUPT, "exactly one zstd frame");
  /* a byte flipped inside the compressed data: zstd fails, or the bytes change and the state does */
  for (uint32_t at = 12; at < B->n; at += B->n / 7) {
    memcpy(copy, B->p, B->n);
    copy[at] ^= 0x5A;
    frames_t g = {malloc(sizeof *g.f * (size_t)fs.n), fs.n};
    memcpy(g.f, fs.f, sizeof *g.f * (size_t)fs.n);
    g.f[bri].p = copy;
    char why[512];
    int r = decode_once(&g, NULL, why, sizeof why);
    assert_true(r == OC_ECORRUPT || r == OC_ECHECKSUM);
    free(g.f);
  }
  /* an unknown dictionary */
  memcpy(copy, B->p, B->n);
  oc_put_u32(copy, 9);
  expect_bad(&fs, bri, copy, B->n, NULL, OC_ECORRUPT, "unknown dictionary 9");
  free(copy);
  free(fs.f);
  oc_buf_free(&b);
  oc_state_free(&s);
}

static void test_epoch__bad_order(void **state) {
  (void)state;
  pair_t p;
  make_pair(&p, 300);
  ocp_enc_desc_t desc = {.deltas = 1, .batch_max = 1};
  oc_buf_t b = {0};
  encode(&desc, &p.b, &p.a, p.lacking, p.nlacking, &b, NULL);
  frames_t fs;
  split_frames(&b, &fs);
  assert_true(p.nlacking >= 3);
  assert_int_equal(count_type(&fs, OCP_MSG_BRICKS), (int)p.nlacking);
  int rec = find_type(&fs, OCP_MSG_RECORDS, 0), bri = find_type(&fs, OCP_MSG_BRICKS, 0);
  /* BRICKS before the RECORDS */
  frames_t g = {malloc(sizeof *g.f * (size_t)fs.n), fs.n};
  memcpy(g.f, fs.f, sizeof *g.f * (size_t)fs.n);
  frame_t x = g.f[rec];
  g.f[rec] = g.f[bri], g.f[bri] = x;
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "bricks before the records are complete");
  /* RECORDS after BRICKS */
  g.f[rec] = fs.f[rec], g.f[bri] = fs.f[bri];
  g.f[bri + 1] = fs.f[rec];
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "records after the first bricks");
  /* the same brick twice */
  memcpy(g.f, fs.f, sizeof *g.f * (size_t)fs.n);
  g.f[bri + 1] = fs.f[bri];
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "sent twice");
  /* a BRICKS frame lost: EPOCH_END finds one missing */
  memcpy(g.f, fs.f, sizeof *g.f * (size_t)fs.n);
  memmove(&g.f[bri], &g.f[bri + 1], sizeof *g.f * (size_t)(fs.n - bri - 1));
  g.n = fs.n - 1;
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "bricks arrived");
  /* EPOCH_END without anything */
  g.f[1] = fs.f[fs.n - 1];
  g.n = 2;
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "records arrived");
  /* frames outside an epoch */
  g.f[0] = fs.f[rec];
  g.n = 1;
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "records outside an epoch");
  g.f[0] = fs.f[bri];
  expect_bad(&g, -1, NULL, 0, &p.a, OC_ECORRUPT, "bricks outside an epoch");
  free(g.f);

  /* a base shorter than the server's (same epoch): the ops run past it */
  oc_state_t shorter;
  oc_state_init(&shorter);
  assert_int_equal(oc_state_copy(&shorter, &p.a), 0);
  shorter.node_count -= 20;
  expect_bad(&fs, -1, NULL, 0, &shorter, OC_ECORRUPT, "past the base");
  /* a longer one: not consumed exactly */
  oc_state_t longer;
  oc_state_init(&longer);
  assert_int_equal(oc_state_copy(&longer, &p.a), 0);
  oc_node_t extra = node(~(oc_key_t)0 >> 1, OC_NODE_EMPTY, 0, 0, 0, 0, 0);
  assert_int_equal(oc_state_add_node(&longer, &extra), 0);
  expect_bad(&fs, -1, NULL, 0, &longer, OC_ECORRUPT, "consumed");

  /* EPOCH_BEGIN announcing fewer records, or more bricks sent than the state has */
  ocp_epoch_begin_t m;
  char why[256];
  assert_int_equal(ocp_get_epoch_begin(fs.f[0].p, fs.f[0].n, &m, why, sizeof why), 0);
  oc_buf_t nb = {0};
  ocp_epoch_begin_t m2 = m;
  m2.node_count -= 5;
  ocp_put_epoch_begin(&nb, VERSION, &m2);
  expect_bad(&fs, 0, nb.data + OCP_HEADER_BYTES, (uint32_t)(nb.len - OCP_HEADER_BYTES), &p.a, OC_ECORRUPT, "more records than");
  nb.len = 0;
  m2 = m;
  m2.bricks_sent -= 1;
  ocp_put_epoch_begin(&nb, VERSION, &m2);
  expect_bad(&fs, 0, nb.data + OCP_HEADER_BYTES, (uint32_t)(nb.len - OCP_HEADER_BYTES), &p.a, OC_ECORRUPT, "more bricks than");
  nb.len = 0;
  m2 = m;
  m2.brick_count += 1, m2.bricks_sent += 1;
  ocp_put_epoch_begin(&nb, VERSION, &m2);
  expect_bad(&fs, 0, nb.data + OCP_HEADER_BYTES, (uint32_t)(nb.len - OCP_HEADER_BYTES), &p.a, OC_ECORRUPT, "announced");
  oc_buf_free(&nb);

  /* dec_begin: the base must be the announced one */
  ocp_epoch_dec_t *d = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d), 0);
  held_t h = {{&p.a, NULL}, 0, NULL, 0};
  assert_int_equal(ocp_epoch_dec_begin(d, &m, NULL, lookup, &h, why, sizeof why), OC_EINVAL);
  assert_int_equal(ocp_epoch_dec_begin(d, &m, &p.b, lookup, &h, why, sizeof why), OC_EINVAL);
  assert_non_null(strstr(why, "not held"));
  assert_false(ocp_epoch_dec_active(d));
  assert_int_equal(ocp_epoch_dec_begin(d, &m, &p.a, lookup, &h, why, sizeof why), 0);
  assert_true(ocp_epoch_dec_active(d));
  ocp_epoch_end_t em = {m.epoch + 1, 0};
  oc_state_t t;
  oc_state_init(&t);
  assert_int_equal(ocp_epoch_dec_end(d, &em, &t, why, sizeof why), OC_ECORRUPT);
  assert_false(ocp_epoch_dec_active(d));
  ocp_epoch_dec_free(d);

  /* the encoder refuses ids that are not bricks of the state, or not ascending */
  ocp_epoch_enc_t *e = NULL;
  assert_int_equal(ocp_epoch_enc_create(&e, &desc), 0);
  uint32_t bogus[2] = {p.next_id + 5, 0};
  assert_int_equal(ocp_epoch_enc_begin(e, &p.b, &p.a, bogus, 1), OC_EINVAL);
  bogus[0] = p.lacking[1], bogus[1] = p.lacking[0];
  assert_int_equal(ocp_epoch_enc_begin(e, &p.b, &p.a, bogus, 2), OC_EINVAL);
  oc_buf_t o = {0};
  assert_int_equal(ocp_epoch_enc_next(e, VERSION, &o), 0); /* nothing begun */
  assert_int_equal(o.len, 0);
  ocp_epoch_enc_free(e);
  ocp_enc_desc_t bad = {.batch_max = OCP_BATCH_MAX + 1};
  assert_int_equal(ocp_epoch_enc_create(&e, &bad), OC_EINVAL);

  oc_state_free(&shorter);
  oc_state_free(&longer);
  free(fs.f);
  oc_buf_free(&b);
  free_pair(&p);
}

/*-*** Dictionaries, chunks, batches ***/

static void test_epoch__dictionary(void **state) {
  (void)state;
  uint32_t next_id = 1;
  oc_state_t s;
  random_state(&s, 11, 600, 9, &next_id);
  assert_true(s.brick_count >= 64);
  const oc_brick_codes_t **samples = malloc(sizeof *samples * s.brick_count);
  assert_non_null(samples);
  for (uint32_t i = 0; i < s.brick_count; i++) samples[i] = &s.bricks[i].codes;
  oc_buf_t dict = {0};
  assert_int_equal(ocp_dict_train(samples, 10, 16 << 10, &dict), OC_EINVAL); /* too few */
  assert_int_equal(ocp_dict_train(samples, s.brick_count, 16 << 10, &dict), 0);
  assert_true(dict.len > 0 && dict.len <= (16u << 10));

  ocp_enc_desc_t desc = {.deltas = 1, .dict_id = 77, .dict = dict.data, .dict_len = dict.len};
  oc_buf_t b = {0};
  ocp_put_dict(&b, VERSION, 77, dict.data, dict.len);
  uint32_t n;
  uint32_t *ids = lacking_ids(&s, NULL, &n);
  encode(&desc, &s, NULL, ids, n, &b, NULL);
  frames_t fs;
  split_frames(&b, &fs);
  assert_int_equal(fs.f[0].type, OCP_MSG_DICT);
  int bri = find_type(&fs, OCP_MSG_BRICKS, 0);
  assert_int_equal(oc_get_u32(fs.f[bri].p), 77);
  oc_state_t t;
  ocp_epoch_dec_t *d = decode_ok(&fs, NULL, &t);
  states_equal(&s, &t);
  held_t h = {{NULL, NULL}, 0, NULL, 0};
  char why[512];
  /* without the DICT frame the BRICKS cannot be read */
  frames_t g = {fs.f + 1, fs.n - 1};
  ocp_epoch_dec_t *d2 = NULL;
  assert_int_equal(ocp_epoch_dec_create(&d2), 0);
  assert_int_equal(decode_frames(d2, &g, NULL, &h, &t, why, sizeof why), OC_ECORRUPT);
  assert_non_null(strstr(why, "unknown dictionary 77"));
  /* a raw-content dictionary (no zstd magic) under the same id: zstd fails or the state does */
  uint8_t raw[4 + 300];
  oc_put_u32(raw, 77);
  for (int i = 0; i < 300; i++) raw[4 + i] = (uint8_t)(i * 7);
  assert_int_equal(ocp_epoch_dec_dict(d2, raw, sizeof raw, why, sizeof why), 0);
  int r = decode_frames(d2, &g, NULL, &h, &t, why, sizeof why);
  assert_true(r == OC_ECORRUPT || r == OC_ECHECKSUM);
  /* bad DICT payloads */
  assert_int_equal(ocp_epoch_dec_dict(d2, raw, 4, why, sizeof why), OC_ECORRUPT);
  oc_put_u32(raw, 0);
  assert_int_equal(ocp_epoch_dec_dict(d2, raw, sizeof raw, why, sizeof why), OC_ECORRUPT);
  uint8_t *big = calloc(1, 4 + OCP_DICT_MAX + 1);
  assert_non_null(big);
  oc_put_u32(big, 5);
  assert_int_equal(ocp_epoch_dec_dict(d2, big, 4 + OCP_DICT_MAX + 1, why, sizeof why), OC_ECORRUPT);
  /* zstd magic followed by garbage: not a dictionary */
  oc_put_u32(big + 4, 0xEC30A437u);
  memset(big + 8, 0xFF, 200);
  assert_int_equal(ocp_epoch_dec_dict(d2, big, 4 + 204, why, sizeof why), OC_ECORRUPT);
  free(big);
  /* an encoder with a raw-content dictionary round-trips too */
  ocp_enc_desc_t rd = {.deltas = 1, .dict_id = 3, .dict = raw + 4, .dict_len = 300};
  oc_buf_t b2 = {0};
  ocp_put_dict(&b2, VERSION, 3, raw + 4, 300);
  encode(&rd, &s, NULL, ids, n, &b2, NULL);
  frames_t g2;
  split_frames(&b2, &g2);
  oc_state_free(&t);
  assert_int_equal(decode_frames(d2, &g2, NULL, &h, &t, why, sizeof why), 0);
  states_equal(&s, &t);

  free(g2.f);
  oc_buf_free(&b2);
  oc_state_free(&t);
  ocp_epoch_dec_free(d);
  ocp_epoch_dec_free(d2);
  free(fs.f);
  free(ids);
  oc_buf_free(&b);
  oc_buf_free(&dict);
  free(samples);
  oc_state_free(&s);
}

/* More than 40 000 records: 1 MiB of ADD records does not fit one chunk. */
static void test_epoch__chunks(void **state) {
  (void)state;
  oc_state_t s;
  oc_state_init(&s);
  s.epoch = 1;
  s.sun_dir = oc_dv3(1.0, 0.0, 0.0);
  uint32_t id = 1;
  for (uint32_t m = 0; m < 32768; m++) {
    oc_key_t k = ((oc_key_t)1 << 15) | m;
    if (m < 1500) {
      for (int c = 0; c < 8; c++) {
        float v = 0.001f * (float)(1 + (m * 8 + (uint32_t)c) % 97);
        oc_node_t n = node(child(k, c), OC_NODE_UNIFORM, 0, v, v, v, v);
        oc_state_add_node(&s, &n);
      }
    } else if (m % 50 == 0) {
      oc_node_t n = node(k, OC_NODE_BRICK, id, 0.01f, 2.0f, 0.1f, 0.4f);
      oc_brick_codes_t c;
      smooth_codes(id, &c);
      oc_state_add_brick(&s, id++, &c);
      oc_state_add_node(&s, &n);
    } else {
      float v = 0.002f * (float)(1 + m % 31);
      oc_node_t n = m % 3 ? node(k, OC_NODE_UNIFORM, 0, v, v, 0.0f, 0.0f) : node(k, OC_NODE_EMPTY, 0, 0, 0, 0, 0);
      oc_state_add_node(&s, &n);
    }
  }
  oc_state_canonicalize(&s);
  assert_true(s.node_count > 40000);
  assert_int_equal(oc_state_validate(&s, NULL, 0), 0);
  ocp_enc_desc_t desc = {.deltas = 1, .level = 1};
  frames_t fs;
  oc_buf_t b;
  round_trip(&desc, &s, &fs, &b);
  int nrec = count_type(&fs, OCP_MSG_RECORDS);
  assert_true(nrec >= 2);
  uint64_t raw = 0;
  for (int i = 0; i < nrec; i++) {
    const frame_t *f = &fs.f[find_type(&fs, OCP_MSG_RECORDS, i)];
    uint32_t r = oc_get_u32(f->p);
    assert_true(r >= 1 && r <= OCP_CHUNK_RAW_MAX);
    raw += r;
  }
  assert_true(raw >= (uint64_t)s.node_count * 32u);
  assert_true(count_type(&fs, OCP_MSG_BRICKS) == (int)((s.brick_count + OCP_BATCH_MAX - 1) / OCP_BATCH_MAX));
  free(fs.f);
  oc_buf_free(&b);

  /* as a difference from itself with a few records changed: KEEP / SKIP / ADD across chunks */
  oc_state_t t;
  oc_state_init(&t);
  assert_int_equal(oc_state_copy(&t, &s), 0);
  t.epoch = 2;
  for (uint32_t i = 0; i < t.node_count; i += 997)
    if (t.nodes[i].kind == OC_NODE_UNIFORM) t.nodes[i].range[0].lo = t.nodes[i].range[0].hi = 0.5f;
  oc_buf_t b2 = {0};
  ocp_enc_stats_t st;
  encode(&desc, &t, &s, NULL, 0, &b2, &st);
  assert_true(st.records_added > 10 && st.records_added < 100);
  frames_t g;
  split_frames(&b2, &g);
  oc_state_t u;
  ocp_epoch_dec_t *d = decode_ok(&g, &s, &u);
  states_equal(&t, &u);
  ocp_epoch_dec_free(d);
  oc_state_free(&u);
  free(g.f);
  oc_buf_free(&b2);
  oc_state_free(&t);
  oc_state_free(&s);
}

static void test_epoch__batch_one(void **state) {
  (void)state;
  pair_t p;
  make_pair(&p, 300);
  for (uint32_t bm = 1; bm <= 3; bm++) {
    ocp_enc_desc_t desc = {.deltas = 1, .batch_max = bm};
    oc_buf_t b = {0};
    encode(&desc, &p.b, &p.a, p.lacking, p.nlacking, &b, NULL);
    frames_t fs;
    split_frames(&b, &fs);
    assert_int_equal(count_type(&fs, OCP_MSG_BRICKS), (int)((p.nlacking + bm - 1) / bm));
    oc_state_t t;
    ocp_epoch_dec_t *d = decode_ok(&fs, &p.a, &t);
    states_equal(&p.b, &t);
    oc_state_free(&t);
    ocp_epoch_dec_free(d);
    free(fs.f);
    oc_buf_free(&b);
  }
  free_pair(&p);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_epoch__full_round_trip),
             cmocka_unit_test(test_epoch__diff_round_trip),
             cmocka_unit_test(test_epoch__wrong_delta_base),
             cmocka_unit_test(test_epoch__bad_zstd),
             cmocka_unit_test(test_epoch__bad_order),
             cmocka_unit_test(test_epoch__dictionary),
             cmocka_unit_test(test_epoch__chunks),
             cmocka_unit_test(test_epoch__batch_one),
             cmocka_unit_test(test_epoch__lean))

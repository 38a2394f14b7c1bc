/* fuzz_epoch.c — libFuzzer target for the epoch decoder (ocp_epoch_dec_*, proto/ocp_epoch.c).
 *
 * The input is a mode byte, then a byte stream of frames as a server sends them, split by
 * ocp_reader_t. EPOCH_BEGIN, RECORDS, BRICKS, DICT and EPOCH_END go to one decoder the way a viewer
 * routes them; the viewer holds a fixed small base state (epoch 5) and, once an epoch completes,
 * the state it decoded, so difference epochs can chain. Whatever completes must validate and match
 * its checksum.
 *
 * Mode bit 0 clear: payloads go in as they are (zstd frames). Set: RECORDS and BRICKS carry their
 * raw content after the head, and the harness wraps it in a zstd frame of raw blocks (written by
 * hand, RFC 8878) with the raw length patched in, so mutations reach the op-stream and batch parsers
 * instead of dying in zstd. Mode bit 1: the viewer is lean (ocp_epoch_dec_*_lean: digests instead
 * of codes; what completes must validate with its ids and match its digest checksum).
 *
 * Seeds (tests/fuzz/corpus/epoch) come from this file's generator, built by hand once:
 *   cc -std=c17 -DFUZZ_EPOCH_SEEDS -D_POSIX_C_SOURCE=200809L -Icommon -Ishaders -Iproto -Itests \
 *      tests/fuzz/fuzz_epoch.c proto/ocp_epoch.c proto/ocp_wire.c common/oc_*.c \
 *      -lzstd -lxxhash -lcjson -lpng -lm -lpthread -o /tmp/epoch_seeds && /tmp/epoch_seeds tests/fuzz/corpus/epoch */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "oc_err.h"
#include "oc_state.h"
#include "ocp_epoch.h"
#include "ocp_wire.h"
#include "state_fixture.h" /* child, node, golden_codes, golden_state */

static void codes(uint32_t id, int tau_zero, oc_brick_codes_t *c) {
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    for (uint32_t v = 0; v < OC_BRICK_VOXELS; v++)
      c->code[ch][v] = ch && tau_zero ? 0 : (uint16_t)(1000u * id + 40u * (v & 7) + 300u * (v >> 3 & 7) + 9u * (v >> 6) + (uint32_t)ch);
}

/* The base the viewer holds: root split in 8, child 7 split again; bricks 1..4. */
static void base_state(oc_state_t *s) {
  oc_brick_codes_t c;
  state_begin(s, 5, 50.0, oc_dv3(0.0, 0.6, 0.8));
  oc_key_t r = OC_KEY_ROOT, c7 = child(r, 7);
  for (int i = 0; i < 7; i++) {
    oc_node_t n = i == 1 ? node(child(r, i), OC_NODE_BRICK, 1, 0.01f, 0.5f, 0.1f, 2.0f)
                  : i == 3 ? node(child(r, i), OC_NODE_BRICK, 2, 0.02f, 0.2f, 0.0f, 0.0f)
                  : i == 5 ? node(child(r, i), OC_NODE_UNIFORM, 0, 0.03f, 0.03f, 1.0f, 1.0f)
                           : node(child(r, i), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
    oc_state_add_node(s, &n);
  }
  for (int i = 0; i < 8; i++) {
    oc_node_t n = i == 2 ? node(child(c7, i), OC_NODE_BRICK, 3, 0.1f, 4.0f, 0.5f, 8.0f)
                  : i == 6 ? node(child(c7, i), OC_NODE_BRICK, 4, 0.001f, 0.004f, 0.2f, 0.3f)
                           : node(child(c7, i), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
    oc_state_add_node(s, &n);
  }
  for (uint32_t id = 1; id <= 4; id++) {
    codes(id, id == 2, &c);
    oc_state_add_brick(s, id, &c);
  }
  oc_state_canonicalize(s);
}

typedef struct {
  const oc_state_t *held[2]; /* the fixed base and the newest decoded state */
  const oc_brick_digests_t *dig[2]; /* lean: the base's digests and the newest state's */
} held_t;

static int lean_lookup(void *ctx, uint32_t id, uint64_t *digest) {
  const held_t *h = ctx;
  for (int i = 0; i < 2; i++) {
    int64_t k = oc_brick_digests_find(h->dig[i], id);
    if (k >= 0) {
      *digest = h->dig[i]->digests[k];
      return 1;
    }
  }
  return 0;
}

static const oc_brick_codes_t *lookup(void *ctx, uint32_t id) {
  const held_t *h = ctx;
  for (int i = 0; i < 2; i++) {
    const oc_brick_t *b = h->held[i] ? oc_state_find_brick(h->held[i], id) : NULL;
    if (b) return &b->codes;
  }
  return NULL;
}

#define ZSTD_BLOCK_MAX (128u << 10)

/* A zstd frame of raw blocks holding src[0..n): single segment, 4-byte content size, no checksum.
 * Appended to out after `head` (the payload's head, its raw length patched to n). */
static void wrap_raw(oc_buf_t *out, const uint8_t *head, size_t head_len, const uint8_t *src, size_t n) {
  oc_buf_append(out, head, head_len);
  if (head_len >= 4) oc_put_u32(out->data + out->len - 4, (uint32_t)n);
  oc_buf_u32(out, 0xFD2FB528u); /* magic */
  oc_buf_u8(out, 0xA0);         /* 4-byte content size, single segment */
  oc_buf_u32(out, (uint32_t)n);
  size_t at = 0;
  do {
    size_t k = n - at < ZSTD_BLOCK_MAX ? n - at : ZSTD_BLOCK_MAX;
    uint32_t bh = (uint32_t)(k << 3) | (at + k == n); /* raw block; bit 0: last */
    uint8_t *q = oc_buf_grow(out, 3);
    if (q) q[0] = (uint8_t)bh, q[1] = (uint8_t)(bh >> 8), q[2] = (uint8_t)(bh >> 16);
    oc_buf_append(out, src + at, k);
    at += k;
  } while (at < n);
}

/* Routes the frames of data[0..size) to a fresh decoder as a viewer holding `base` would (raw:
 * RECORDS and BRICKS content is wrapped first). @return the epochs completed (each checked: valid,
 * and hashing to its EPOCH_END). */
static int feed(const uint8_t *data, size_t size, const oc_state_t *base, int raw, int lean) {
  ocp_epoch_dec_t *d = NULL;
  if (ocp_epoch_dec_create(&d) < 0) return 0;
  ocp_reader_t r;
  ocp_reader_init(&r, OCP_MAX_PAYLOAD);
  oc_state_t newest, out;
  oc_state_init(&newest);
  oc_state_init(&out);
  oc_brick_digests_t base_dig = {0}, newest_dig = {0}, out_dig = {0};
  if (lean && oc_brick_digests_of(&base_dig, base) < 0) abort();
  held_t h = {{base, NULL}, {&base_dig, NULL}};
  oc_buf_t wrapped = {0};
  char why[512];
  int done = 0;
  if (ocp_reader_feed(&r, data, size) == 0) {
    ocp_header_t hd;
    const uint8_t *p;
    while (ocp_reader_next(&r, &hd, &p) == 1) {
      size_t n = hd.length, head = hd.type == OCP_MSG_RECORDS ? 4 : 8;
      if (raw && (hd.type == OCP_MSG_RECORDS || hd.type == OCP_MSG_BRICKS) && n >= head) {
        wrapped.len = 0;
        wrap_raw(&wrapped, p, head, p + head, n - head);
        if (wrapped.err) break;
        p = wrapped.data, n = wrapped.len;
      }
      switch (hd.type) {
        case OCP_MSG_EPOCH_BEGIN: {
          ocp_epoch_begin_t m;
          if (ocp_get_epoch_begin(p, n, &m, why, sizeof why) < 0) break;
          const oc_state_t *b = m.base_epoch == OCP_NO_BASE                       ? NULL
                                : newest.node_count && m.base_epoch == newest.epoch ? &newest
                                                                                    : base;
          if (lean)
            ocp_epoch_dec_begin_lean(d, &m, b, lean_lookup, &h, why, sizeof why);
          else
            ocp_epoch_dec_begin(d, &m, b, lookup, &h, why, sizeof why);
          break;
        }
        case OCP_MSG_RECORDS: ocp_epoch_dec_records(d, p, n, why, sizeof why); break;
        case OCP_MSG_BRICKS: ocp_epoch_dec_bricks(d, p, n, why, sizeof why); break;
        case OCP_MSG_DICT: ocp_epoch_dec_dict(d, p, n, why, sizeof why); break;
        case OCP_MSG_EPOCH_END: {
          ocp_epoch_end_t m;
          if (ocp_get_epoch_end(p, n, &m, why, sizeof why) < 0) break;
          if (lean) {
            if (ocp_epoch_dec_end_lean(d, &m, &out, &out_dig, why, sizeof why) < 0) break;
            /* accepted: valid records with those ids, hashing to what EPOCH_END said */
            if (out.brick_count || oc_state_validate_lean(&out, &out_dig, NULL, 0) != 0 ||
                oc_state_digest_checksum(&out, &out_dig) != m.checksum || out.epoch != m.epoch)
              abort();
            oc_brick_digests_free(&newest_dig);
            newest_dig = out_dig;
            memset(&out_dig, 0, sizeof out_dig);
            h.dig[1] = &newest_dig;
          } else {
            if (ocp_epoch_dec_end(d, &m, &out, why, sizeof why) < 0) break;
            /* accepted: a valid state that hashes to what EPOCH_END said */
            if (oc_state_validate(&out, NULL, 0) != 0 || oc_state_checksum(&out) != m.checksum || out.epoch != m.epoch) abort();
          }
          oc_state_free(&newest);
          newest = out; /* the decoder is idle: nothing refers to the old newest any more */
          oc_state_init(&out);
          h.held[1] = &newest;
          done++;
          break;
        }
        default: break;
      }
    }
  }
  oc_buf_free(&wrapped);
  ocp_reader_free(&r);
  ocp_epoch_dec_free(d);
  oc_state_free(&newest);
  oc_state_free(&out);
  oc_brick_digests_free(&base_dig);
  oc_brick_digests_free(&newest_dig);
  oc_brick_digests_free(&out_dig);
  return done;
}

#ifndef FUZZ_EPOCH_SEEDS

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static oc_state_t base;
  static int ready;
  if (!ready) {
    base_state(&base);
    ready = 1;
  }
  if (size >= 1) feed(data + 1, size - 1, &base, data[0] & 1, (data[0] >> 1) & 1);
  return 0;
}

#else /* the seed generator */

#include <stdio.h>

static void encode(oc_buf_t *b, const ocp_enc_desc_t *desc, const oc_state_t *s, const oc_state_t *base) {
  uint32_t ids[64], n = 0;
  for (uint32_t i = 0; i < s->brick_count; i++)
    if (!base || !oc_state_find_brick(base, s->bricks[i].id)) ids[n++] = s->bricks[i].id;
  ocp_epoch_enc_t *e = NULL;
  if (ocp_epoch_enc_create(&e, desc) < 0 || ocp_epoch_enc_begin(e, s, base, ids, n) < 0) abort();
  int r;
  while ((r = ocp_epoch_enc_next(e, OCP_VERSION_MAX, b)) == 1) {
  }
  if (r < 0) abort();
  ocp_epoch_enc_free(e);
}

/* Writes one seed (mode byte, then the frames) after checking that it decodes to `epochs`
 * complete states. */
static void save(const char *dir, const char *name, uint8_t mode, const oc_buf_t *b, const oc_state_t *base, int epochs) {
  if (feed(b->data, b->len, base, mode & 1, (mode >> 1) & 1) != epochs) {
    fprintf(stderr, "%s: does not decode\n", name);
    abort();
  }
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", dir, name);
  FILE *f = fopen(path, "wb");
  if (!f || fwrite(&mode, 1, 1, f) != 1 || fwrite(b->data, 1, b->len, f) != b->len || fclose(f) != 0) abort();
  printf("%s: %zu bytes\n", path, b->len + 1);
}

static void pack_record(const oc_node_t *n, uint8_t *r) {
  oc_put_u64(r, n->key);
  r[8] = n->kind;
  r[9] = r[10] = r[11] = 0;
  oc_put_u32(r + 12, n->brick_id);
  for (int c = 0; c < OC_CHANNELS; c++) oc_put_f32(r + 16 + 8 * c, n->range[c].lo), oc_put_f32(r + 20 + 8 * c, n->range[c].hi);
}

static void put_op(oc_buf_t *b, uint8_t op, uint32_t n) {
  oc_buf_u8(b, op);
  oc_buf_u32(b, n);
}

/* An epoch in raw mode, written without the encoder: one op per record (KEEP 1, SKIP 1, ADD 1),
 * one batch with deltas where the node's previous brick has the same non-zero range. */
static void raw_epoch(oc_buf_t *b, const oc_state_t *s, const oc_state_t *base) {
  uint32_t nb = base ? base->node_count : 0, i = 0, j = 0, n = 0;
  for (uint32_t k = 0; k < s->brick_count; k++) n += !base || !oc_state_find_brick(base, s->bricks[k].id);
  ocp_epoch_begin_t m = {s->epoch, s->time, s->sun_dir, base ? base->epoch : OCP_NO_BASE, s->node_count, s->brick_count, n};
  ocp_put_epoch_begin(b, OCP_VERSION_MAX, &m);
  oc_buf_t ops = {0};
  while (i < nb || j < s->node_count) {
    uint8_t x[32], y[32];
    if (i < nb && j < s->node_count && base->nodes[i].key == s->nodes[j].key) {
      pack_record(&base->nodes[i], x);
      pack_record(&s->nodes[j], y);
      if (!memcmp(x, y, 32)) {
        put_op(&ops, OCP_OP_KEEP, 1), i++, j++;
        continue;
      }
    }
    if (i < nb && (j == s->node_count || base->nodes[i].key <= s->nodes[j].key)) {
      put_op(&ops, OCP_OP_SKIP, 1), i++;
    } else {
      put_op(&ops, OCP_OP_ADD, 1);
      pack_record(&s->nodes[j++], oc_buf_grow(&ops, 32));
    }
  }
  size_t h = ocp_frame_begin(b, OCP_VERSION_MAX, OCP_MSG_RECORDS);
  oc_buf_u32(b, (uint32_t)ops.len);
  oc_buf_append(b, ops.data, ops.len);
  ocp_frame_end(b, h);
  if (n) {
    h = ocp_frame_begin(b, OCP_VERSION_MAX, OCP_MSG_BRICKS);
    oc_buf_u32(b, 0);
    oc_buf_u32(b, 4 + 2060 * n);
    oc_buf_u32(b, n);
    const oc_brick_codes_t *bases[64];
    unsigned flags[64];
    uint32_t k = 0;
    for (uint32_t q = 0; q < s->brick_count; q++) {
      const oc_brick_t *br = &s->bricks[q];
      if (base && oc_state_find_brick(base, br->id)) continue;
      uint32_t base_id = 0;
      flags[k] = 0, bases[k] = NULL;
      for (uint32_t t = 0; t < s->node_count; t++) {
        const oc_node_t *nd = &s->nodes[t];
        if (nd->kind != OC_NODE_BRICK || nd->brick_id != br->id || !base) continue;
        int64_t bi = oc_state_find_node(base, nd->key);
        if (bi < 0 || base->nodes[bi].kind != OC_NODE_BRICK) continue;
        for (int c = 0; c < OC_CHANNELS; c++)
          if (nd->range[c].hi != 0.0f && !memcmp(&nd->range[c], &base->nodes[bi].range[c], sizeof nd->range[c])) flags[k] |= 1u << c;
        if (flags[k]) base_id = base->nodes[bi].brick_id, bases[k] = &oc_state_find_brick(base, base_id)->codes;
      }
      oc_buf_u32(b, br->id);
      oc_buf_u32(b, base_id);
      oc_buf_u32(b, flags[k]);
      k++;
    }
    k = 0;
    for (uint32_t q = 0; q < s->brick_count; q++) {
      const oc_brick_t *br = &s->bricks[q];
      if (base && oc_state_find_brick(base, br->id)) continue;
      for (int c = 0; c < OC_CHANNELS; c++) {
        for (int v = 0; v < 512; v++) /* docs/protocol.md, BRICKS: whole codes or deltas, u16 */
          oc_buf_u16(b, (uint16_t)(br->codes.code[c][v] - ((flags[k] >> c) & 1 ? bases[k]->code[c][v] : 0)));
      }
      k++;
    }
    ocp_frame_end(b, h);
  }
  ocp_epoch_end_t e = {s->epoch, oc_state_checksum(s)};
  ocp_put_epoch_end(b, OCP_VERSION_MAX, &e);
  oc_buf_free(&ops);
}

/* The next epoch of a: brick 2 kept, every other brick refreshed (deltas; odd ids also change
 * their σt range: whole σt, delta τ), child 0 split in 8, the children of child 7 merged. */
static void next_state(const oc_state_t *a, oc_state_t *s, uint32_t first_id) {
  state_begin(s, a->epoch + 1, a->time + 10.0, a->sun_dir);
  uint32_t id = first_id;
  oc_key_t c7 = child(OC_KEY_ROOT, 7);
  int merged = 0;
  for (uint32_t i = 0; i < a->node_count; i++) {
    oc_node_t n = a->nodes[i];
    const oc_brick_t *old = n.kind == OC_NODE_BRICK ? oc_state_find_brick(a, n.brick_id) : NULL;
    if (n.key >> 3 == c7) {
      if (!merged++) {
        oc_node_t p = node(c7, OC_NODE_UNIFORM, 0, 0.05f, 0.05f, 0.5f, 0.5f);
        oc_state_add_node(s, &p);
      }
      continue;
    }
    if (n.key == child(OC_KEY_ROOT, 0)) {
      for (int c = 0; c < 8; c++) {
        oc_node_t m = c == 4 ? node(child(n.key, c), OC_NODE_BRICK, id, 0.2f, 0.9f, 0.0f, 0.0f)
                             : node(child(n.key, c), OC_NODE_EMPTY, 0, 0, 0, 0, 0);
        oc_state_add_node(s, &m);
        if (c == 4) {
          oc_brick_codes_t cc;
          codes(id, 1, &cc);
          oc_state_add_brick(s, id++, &cc);
        }
      }
      continue;
    }
    if (old && old->id != 2) { /* refresh */
      oc_brick_codes_t cc = old->codes;
      for (int v = 0; v < OC_BRICK_VOXELS; v += 3) cc.code[0][v] = (uint16_t)(cc.code[0][v] + 5u);
      if (n.range[1].hi != 0.0f)
        for (int v = 0; v < OC_BRICK_VOXELS; v += 5) cc.code[1][v] = (uint16_t)(cc.code[1][v] + 2u);
      if (n.brick_id % 2 == 1) n.range[0].hi *= 1.5f;
      n.brick_id = id++;
      oc_state_add_brick(s, n.brick_id, &cc);
    } else if (old) {
      oc_state_add_brick(s, old->id, &old->codes);
    }
    oc_state_add_node(s, &n);
  }
  oc_state_canonicalize(s);
  char why[256];
  if (oc_state_validate(s, why, sizeof why) != 0) {
    fprintf(stderr, "seed state invalid: %s\n", why);
    abort();
  }
}

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  oc_state_t base, s6, s7;
  base_state(&base);
  next_state(&base, &s6, 10);
  next_state(&s6, &s7, 20);
  ocp_enc_desc_t plain = {.deltas = 1};
  oc_buf_t b = {0};
  /* the base itself, whole (no base) */
  encode(&b, &plain, &base, NULL);
  save(argv[1], "full.bin", 0, &b, &base, 1);
  /* a difference from the base: KEEP, SKIP, ADD, deltas, a held brick */
  b.len = 0;
  encode(&b, &plain, &s6, &base);
  save(argv[1], "diff.bin", 0, &b, &base, 1);
  /* two epochs chained: the second's base is the first's state */
  encode(&b, &plain, &s7, &s6);
  save(argv[1], "chain.bin", 0, &b, &base, 2);
  /* a raw-content dictionary, then batches of one brick compressed with it */
  uint8_t dict[512];
  for (int i = 0; i < (int)sizeof dict; i++) dict[i] = (uint8_t)(i % 8 == 0 ? 3 : i % 8 == 1 ? 0x28 : i);
  ocp_enc_desc_t with_dict = {.deltas = 1, .dict_id = 9, .dict = dict, .dict_len = sizeof dict, .batch_max = 1};
  b.len = 0;
  ocp_put_dict(&b, OCP_VERSION_MAX, 9, dict, sizeof dict);
  encode(&b, &with_dict, &s6, &base);
  save(argv[1], "dict.bin", 0, &b, &base, 1);
  /* raw mode: the content itself, for the op-stream and batch parsers */
  b.len = 0;
  raw_epoch(&b, &base, NULL);
  save(argv[1], "raw_full.bin", 1, &b, &base, 1);
  b.len = 0;
  raw_epoch(&b, &s6, &base);
  raw_epoch(&b, &s7, &s6);
  save(argv[1], "raw_chain.bin", 1, &b, &base, 2);
  /* a lean viewer: digest checksums, no deltas, two epochs chained */
  ocp_enc_desc_t lean = {.digest = 1};
  b.len = 0;
  encode(&b, &lean, &s6, &base);
  encode(&b, &lean, &s7, &s6);
  save(argv[1], "lean_chain.bin", 2, &b, &base, 2);
  oc_buf_free(&b);
  oc_state_free(&base);
  oc_state_free(&s6);
  oc_state_free(&s7);
  return 0;
}

#endif

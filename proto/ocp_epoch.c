/* ocp_epoch.c — one epoch on the wire: record op streams and brick batches, compressed with zstd
 * (ocp_epoch.h; docs/protocol.md, "Epoch"). The only file that includes <zstd.h>.
 *
 * The decoder reads hostile bytes: every zstd frame must declare its content size, equal to the
 * raw length field (≤ OCP_CHUNK_RAW_MAX), and be the whole payload; every count is checked against
 * what is announced and what is left before anything is copied; arrays grow only as records and
 * bricks actually arrive, so a forged EPOCH_BEGIN cannot make it allocate for 2^24 records. */
#include "ocp_epoch.h"

#include <inttypes.h> /* PRIu32, PRIu64, PRIx64 */
#include <stdarg.h>
#include <stdio.h>  /* vsnprintf */
#include <stdlib.h> /* malloc, realloc, free */
#include <string.h> /* memcpy, memcmp, memset */

#include <zdict.h> /* ZDICT_trainFromBuffer */
#include <zstd.h>

#include "oc_err.h" /* OC_E* */

#define OCP__OP_BYTES 5                                      /* u8 op, u32 n */
#define OCP__BRICK_HEAD 12                                   /* u32 id, u32 base id, u8 flags, 3 reserved */
#define OCP__BRICK_PLANES OC_BRICK_CODE_BYTES                /* 2048: both channels' u16 values */
#define OCP__BRICK_WIRE (OCP__BRICK_HEAD + OCP__BRICK_PLANES) /* 2060 */
#define OCP__WINDOW_LOG_MAX 21 /* raw chunks are ≤ 1 MiB: no honest frame needs a larger window */
#define OCP__DICT_MIN_SAMPLES 64
#define OCP__NONE UINT32_MAX

_Static_assert(4 + (size_t)OCP_BATCH_MAX * OCP__BRICK_WIRE <= OCP_CHUNK_RAW_MAX, "a full batch must fit one chunk");


/*-*** Records and bricks in their wire form ***/


/* Equal in all 32 serialised bytes: floats by bit pattern, so a KEEP reproduces the checksum. */
static int ocp__record_same(const oc_node_t *a, const oc_node_t *b) {
  uint8_t x[OC_STATE_RECORD_BYTES], y[OC_STATE_RECORD_BYTES];
  oc_state_pack_record(a, x);
  oc_state_pack_record(b, y);
  return memcmp(x, y, sizeof x) == 0;
}

static int ocp__range_same(oc_range_t a, oc_range_t b) {
  uint8_t x[8], y[8];
  oc_put_f32(x, a.lo), oc_put_f32(x + 4, a.hi);
  oc_put_f32(y, b.lo), oc_put_f32(y + 4, b.hi);
  return memcmp(x, y, sizeof x) == 0;
}

/* Brick codes → 2048 bytes: per channel (σt, τ) 512 little-endian u16 values e[i] = c[i] − b[i]
 * (delta, bit c of flags; mod 2^16) or c[i] (whole). Measured on the planet, whole codes as they
 * are compress better in a batch than x-predicted or split into byte planes: most σt codes are
 * zero, and prediction turns every zero/non-zero edge into two large values (docs/performance.md). */
static void ocp__planes_put(const oc_brick_codes_t *c, const oc_brick_codes_t *base, unsigned flags, uint8_t *dst) {
  for (int ch = 0; ch < OC_CHANNELS; ch++) {
    const uint16_t *v = c->code[ch];
    uint8_t *q = dst + (size_t)ch * 2 * OC_BRICK_VOXELS;
    const uint16_t *b = (flags & (1u << ch)) ? base->code[ch] : NULL;
    for (int i = 0; i < OC_BRICK_VOXELS; i++) oc_put_u16(q + 2 * i, (uint16_t)(b ? v[i] - b[i] : v[i]));
  }
}

/* The inverse of ocp__planes_put. */
static void ocp__planes_get(const uint8_t *src, const oc_brick_codes_t *base, unsigned flags, oc_brick_codes_t *c) {
  for (int ch = 0; ch < OC_CHANNELS; ch++) {
    uint16_t *v = c->code[ch];
    const uint8_t *q = src + (size_t)ch * 2 * OC_BRICK_VOXELS;
    const uint16_t *b = (flags & (1u << ch)) ? base->code[ch] : NULL;
    for (int i = 0; i < OC_BRICK_VOXELS; i++) v[i] = (uint16_t)(oc_get_u16(q + 2 * i) + (b ? b[i] : 0));
  }
}

/*-*** Dictionaries ***/

int ocp_dict_train(const oc_brick_codes_t *const *bricks, size_t n, size_t cap, oc_buf_t *out) {
  if (!out || (n && !bricks) || cap == 0) return OC_EINVAL;
  if (n < OCP__DICT_MIN_SAMPLES) return OC_EINVAL;
  if (cap > OCP_DICT_MAX) cap = OCP_DICT_MAX;
  if (n > UINT32_MAX / OCP__BRICK_PLANES) n = UINT32_MAX / OCP__BRICK_PLANES; /* ZDICT takes unsigned counts */
  uint8_t *samples = malloc(n * OCP__BRICK_PLANES);
  size_t *sizes = malloc(n * sizeof *sizes);
  uint8_t *dict = malloc(cap);
  int r = 0;
  if (!samples || !sizes || !dict) {
    r = OC_ENOMEM;
    goto done;
  }
  for (size_t i = 0; i < n; i++) {
    ocp__planes_put(bricks[i], NULL, 0, samples + i * OCP__BRICK_PLANES);
    sizes[i] = OCP__BRICK_PLANES;
  }
  size_t len = ZDICT_trainFromBuffer(dict, cap, samples, sizes, (unsigned)n);
  if (ZDICT_isError(len) || len == 0) {
    r = OC_EINVAL; /* samples unfit for training (too few, too small or all alike) */
    goto done;
  }
  out->len = 0;
  oc_buf_append(out, dict, len);
  if (out->err) r = OC_ENOMEM;
done:
  free(samples);
  free(sizes);
  free(dict);
  return r;
}

void ocp_put_dict(oc_buf_t *b, uint8_t version, uint32_t id, const void *dict, size_t n) {
  size_t h = ocp_frame_begin(b, version, OCP_MSG_DICT);
  oc_buf_u32(b, id);
  oc_buf_append(b, dict, n);
  ocp_frame_end(b, h);
}

/*-*** Encoder ***/

typedef struct {
  uint8_t op;
  uint32_t n;
  uint32_t first; /* ADD: index of its first record in the state */
} ocp__op_t;

typedef struct {
  const oc_brick_t *brick;
  const oc_brick_codes_t *base; /* the held brick the delta channels are relative to */
  uint32_t base_id;
  uint8_t flags; /* OCP_BRICK_DELTA_* */
} ocp__send_t;

enum { OCP__PH_IDLE, OCP__PH_BEGIN, OCP__PH_RECORDS, OCP__PH_BRICKS, OCP__PH_END };

struct ocp_epoch_enc_s {
  ocp_enc_desc_t desc; /* dict and dict_len cleared: the CDict holds the copy */
  ZSTD_CCtx *cctx;
  ZSTD_CDict *cdict;
  const oc_state_t *state, *base;
  ocp__op_t *ops;
  size_t nops, ops_cap, op_i;
  uint32_t op_done; /* records of ops[op_i] (an ADD) already emitted */
  ocp__send_t *send;
  uint32_t nsend, send_cap, send_i;
  uint8_t *raw; /* one chunk or batch, OCP_CHUNK_RAW_MAX */
  int phase;
  uint64_t checksum; /* of the epoch begun, in the desc's form */
  ocp_enc_stats_t st;
};

int ocp_epoch_enc_create(ocp_epoch_enc_t **out, const ocp_enc_desc_t *desc) {
  if (!out) return OC_EINVAL;
  *out = NULL;
  ocp_enc_desc_t d = desc ? *desc : (ocp_enc_desc_t){0};
  if (d.level == 0) d.level = OCP_LEVEL_DEFAULT;
  if (d.level < ZSTD_minCLevel() || d.level > ZSTD_maxCLevel()) return OC_EINVAL;
  if (d.batch_max == 0) d.batch_max = OCP_BATCH_MAX;
  if (d.batch_max > OCP_BATCH_MAX) return OC_EINVAL;
  if (d.dict_id && (!d.dict || d.dict_len == 0 || d.dict_len > OCP_DICT_MAX)) return OC_EINVAL;
  if (d.digest && d.deltas) return OC_EINVAL; /* a lean viewer holds no base codes */
  ocp_epoch_enc_t *e = calloc(1, sizeof *e);
  if (!e) return OC_ENOMEM;
  e->cctx = ZSTD_createCCtx();
  e->raw = malloc(OCP_CHUNK_RAW_MAX);
  /* A raw-content dictionary (no zstd magic) is accepted as well: zstd then records no id. */
  if (d.dict_id) e->cdict = ZSTD_createCDict(d.dict, d.dict_len, d.level);
  if (!e->cctx || !e->raw || (d.dict_id && !e->cdict)) {
    ocp_epoch_enc_free(e);
    return OC_ENOMEM;
  }
  d.dict = NULL, d.dict_len = 0;
  e->desc = d;
  *out = e;
  return 0;
}

void ocp_epoch_enc_free(ocp_epoch_enc_t *e) {
  if (!e) return;
  ZSTD_freeCCtx(e->cctx);
  ZSTD_freeCDict(e->cdict);
  free(e->ops);
  free(e->send);
  free(e->raw);
  free(e);
}

static int ocp__push_op(ocp_epoch_enc_t *e, uint8_t op, uint32_t n, uint32_t first) {
  if (n == 0) return 0;
  if (e->nops && e->ops[e->nops - 1].op == op && op != OCP_OP_ADD && e->ops[e->nops - 1].n <= UINT32_MAX - n) {
    e->ops[e->nops - 1].n += n;
    return 0;
  }
  if (e->nops == e->ops_cap) {
    size_t nc = e->ops_cap ? 2 * e->ops_cap : 64;
    ocp__op_t *p = realloc(e->ops, nc * sizeof *p);
    if (!p) return OC_ENOMEM;
    e->ops = p, e->ops_cap = nc;
  }
  e->ops[e->nops++] = (ocp__op_t){op, n, first};
  return 0;
}

/* The op stream: a merge-walk of both key-sorted record arrays. Between two KEEPs every base
 * record passed over is one SKIP and every new record one ADD run (contiguous in the state), so
 * replaced records do not alternate SKIP 1 / ADD 1. */
static int ocp__diff(ocp_epoch_enc_t *e) {
  const oc_state_t *s = e->state, *b = e->base;
  uint32_t nb = b ? b->node_count : 0, i = 0, j = 0, skip = 0, add_first = 0, add_n = 0;
  while (i < nb || j < s->node_count) {
    if (i < nb && j < s->node_count && b->nodes[i].key == s->nodes[j].key && ocp__record_same(&b->nodes[i], &s->nodes[j])) {
      OC_TRY(ocp__push_op(e, OCP_OP_SKIP, skip, 0));
      OC_TRY(ocp__push_op(e, OCP_OP_ADD, add_n, add_first));
      OC_TRY(ocp__push_op(e, OCP_OP_KEEP, 1, 0));
      skip = add_n = 0;
      e->st.records_kept++;
      i++, j++;
      continue;
    }
    int take_base = i < nb && (j == s->node_count || b->nodes[i].key <= s->nodes[j].key);
    int take_new = j < s->node_count && (i == nb || s->nodes[j].key <= b->nodes[i].key);
    if (take_base) skip++, i++;
    if (take_new) {
      if (add_n == 0) add_first = j;
      add_n++, j++;
      e->st.records_added++;
    }
  }
  OC_TRY(ocp__push_op(e, OCP_OP_SKIP, skip, 0));
  return ocp__push_op(e, OCP_OP_ADD, add_n, add_first);
}

/* The record index of each brick (by the brick's index in s->bricks), or OCP__NONE. */
static uint32_t *ocp__brick_nodes(const oc_state_t *s) {
  uint32_t *at = malloc(((size_t)s->brick_count + 1) * sizeof *at);
  if (!at) return NULL;
  for (uint32_t k = 0; k < s->brick_count; k++) at[k] = OCP__NONE;
  for (uint32_t i = 0; i < s->node_count; i++) {
    if (s->nodes[i].kind != OC_NODE_BRICK) continue;
    const oc_brick_t *b = oc_state_find_brick(s, s->nodes[i].brick_id);
    if (b) at[b - s->bricks] = i;
  }
  return at;
}

int ocp_epoch_enc_begin(ocp_epoch_enc_t *e, const oc_state_t *state, const oc_state_t *base, const uint32_t *lacking,
                        uint32_t nlacking) {
  if (!e || !state || state->node_count == 0 || (nlacking && !lacking)) return OC_EINVAL;
  if (nlacking > state->brick_count) return OC_EINVAL;
  e->phase = OCP__PH_IDLE;
  e->state = state, e->base = base;
  e->nops = e->op_i = 0, e->op_done = 0;
  e->nsend = e->send_i = 0;
  memset(&e->st, 0, sizeof e->st);
  if (nlacking > e->send_cap) {
    ocp__send_t *p = realloc(e->send, (size_t)nlacking * sizeof *p);
    if (!p) return OC_ENOMEM;
    e->send = p, e->send_cap = nlacking;
  }
  uint32_t *node_of = ocp__brick_nodes(state);
  if (!node_of) return OC_ENOMEM;
  int r = 0;
  for (uint32_t k = 0; k < nlacking && r == 0; k++) {
    const oc_brick_t *b = oc_state_find_brick(state, lacking[k]);
    if (!b || (k && lacking[k] <= lacking[k - 1])) {
      r = OC_EINVAL; /* not a brick of the state, or not ascending (a brick would be sent twice) */
      break;
    }
    uint32_t ni = node_of[b - state->bricks];
    ocp__send_t *s = &e->send[k];
    *s = (ocp__send_t){b, NULL, 0, 0};
    if (!e->desc.deltas || !base || ni == OCP__NONE) continue;
    /* The node's previous brick, held by the viewer since it is in base: a channel is a delta when
     * its range is unchanged (same codes mean the same values) and non-zero (zero is all zeros). */
    const oc_node_t *n = &state->nodes[ni];
    int64_t bi = oc_state_find_node(base, n->key);
    if (bi < 0) continue;
    const oc_node_t *bn = &base->nodes[bi];
    const oc_brick_t *bb = bn->kind == OC_NODE_BRICK && bn->brick_id != 0 ? oc_state_find_brick(base, bn->brick_id) : NULL;
    if (!bb) continue;
    for (int c = 0; c < OC_CHANNELS; c++)
      if (n->range[c].hi != 0.0f && ocp__range_same(n->range[c], bn->range[c])) s->flags |= (uint8_t)(1u << c);
    if (s->flags) s->base = &bb->codes, s->base_id = bb->id;
  }
  free(node_of);
  if (r == 0) r = ocp__diff(e);
  if (r < 0) {
    e->state = e->base = NULL;
    return r;
  }
  /* Hashed once here, for EPOCH_END and for the caller's ACK check (ocp_epoch_enc_checksum). */
  e->checksum = e->desc.digest ? oc_state_digest(state) : oc_state_checksum(state);
  e->nsend = nlacking;
  e->phase = OCP__PH_BEGIN;
  return 0;
}

/* Appends one frame of `type` whose payload is `head` (uncompressed) then `raw` as one zstd frame.
 * Stats count the frame's bytes and what it would be uncompressed. */
static int ocp__put_zframe(ocp_epoch_enc_t *e, uint8_t version, uint8_t type, const uint8_t *head, size_t head_len,
                           size_t raw_len, int with_dict, oc_buf_t *out) {
  size_t h = ocp_frame_begin(out, version, type);
  oc_buf_append(out, head, head_len);
  size_t bound = ZSTD_compressBound(raw_len);
  uint8_t *dst = oc_buf_grow(out, bound);
  if (!dst || out->err) return OC_ENOMEM;
  size_t z = with_dict ? ZSTD_compress_usingCDict(e->cctx, dst, bound, e->raw, raw_len, e->cdict)
                       : ZSTD_compressCCtx(e->cctx, dst, bound, e->raw, raw_len, e->desc.level);
  if (ZSTD_isError(z)) {
    out->len = h; /* drop the partial frame */
    return OC_EIO;
  }
  out->len -= bound - z;
  ocp_frame_end(out, h);
  e->st.frames++;
  e->st.wire_bytes += out->len - h;
  e->st.raw_bytes += OCP_HEADER_BYTES + head_len + raw_len;
  return 0;
}

/* The next RECORDS chunk: whole ops up to OCP_CHUNK_RAW_MAX raw bytes; a long ADD run becomes
 * several ADD ops so chunks fill up. */
static int ocp__next_records(ocp_epoch_enc_t *e, uint8_t version, oc_buf_t *out) {
  size_t len = 0;
  while (e->op_i < e->nops) {
    const ocp__op_t *o = &e->ops[e->op_i];
    size_t room = OCP_CHUNK_RAW_MAX - len;
    if (o->op != OCP_OP_ADD) {
      if (room < OCP__OP_BYTES) break;
      e->raw[len] = o->op;
      oc_put_u32(e->raw + len + 1, o->n);
      len += OCP__OP_BYTES;
      e->op_i++;
      continue;
    }
    if (room < OCP__OP_BYTES + OC_STATE_RECORD_BYTES) break;
    uint32_t k = o->n - e->op_done;
    if (k > (room - OCP__OP_BYTES) / OC_STATE_RECORD_BYTES) k = (uint32_t)((room - OCP__OP_BYTES) / OC_STATE_RECORD_BYTES);
    e->raw[len] = OCP_OP_ADD;
    oc_put_u32(e->raw + len + 1, k);
    len += OCP__OP_BYTES;
    for (uint32_t r = 0; r < k; r++, len += OC_STATE_RECORD_BYTES)
      oc_state_pack_record(&e->state->nodes[o->first + e->op_done + r], e->raw + len);
    e->op_done += k;
    if (e->op_done == o->n) e->op_i++, e->op_done = 0;
  }
  uint8_t head[4];
  oc_put_u32(head, (uint32_t)len);
  return ocp__put_zframe(e, version, OCP_MSG_RECORDS, head, sizeof head, len, 0, out);
}

static int ocp__next_bricks(ocp_epoch_enc_t *e, uint8_t version, oc_buf_t *out) {
  uint32_t n = e->nsend - e->send_i;
  if (n > e->desc.batch_max) n = e->desc.batch_max;
  const ocp__send_t *s = e->send + e->send_i;
  oc_put_u32(e->raw, n);
  uint8_t *planes = e->raw + 4 + (size_t)n * OCP__BRICK_HEAD;
  for (uint32_t k = 0; k < n; k++) {
    uint8_t *p = e->raw + 4 + (size_t)k * OCP__BRICK_HEAD;
    oc_put_u32(p, s[k].brick->id);
    oc_put_u32(p + 4, s[k].base_id);
    p[8] = s[k].flags;
    p[9] = p[10] = p[11] = 0;
    ocp__planes_put(&s[k].brick->codes, s[k].base, s[k].flags, planes + (size_t)k * OCP__BRICK_PLANES);
    int deltas = (s[k].flags & 1u) + ((s[k].flags >> 1) & 1u);
    e->st.delta_channels += (uint32_t)deltas;
    e->st.full_channels += (uint32_t)(OC_CHANNELS - deltas);
  }
  uint8_t head[8];
  oc_put_u32(head, e->cdict ? e->desc.dict_id : 0);
  oc_put_u32(head + 4, (uint32_t)(4 + (size_t)n * OCP__BRICK_WIRE));
  OC_TRY(ocp__put_zframe(e, version, OCP_MSG_BRICKS, head, sizeof head, 4 + (size_t)n * OCP__BRICK_WIRE, e->cdict != NULL, out));
  e->send_i += n;
  e->st.bricks += n;
  return 0;
}

int ocp_epoch_enc_next(ocp_epoch_enc_t *e, uint8_t version, oc_buf_t *out) {
  if (!e || !out) return OC_EINVAL;
  if (out->err) return OC_ENOMEM;
  size_t start = out->len;
  switch (e->phase) {
    case OCP__PH_BEGIN: {
      const oc_state_t *s = e->state;
      ocp_epoch_begin_t m = {.epoch = s->epoch,
                             .time = s->time,
                             .sun_dir = s->sun_dir,
                             .base_epoch = e->base ? e->base->epoch : OCP_NO_BASE,
                             .node_count = s->node_count,
                             .brick_count = s->brick_count,
                             .bricks_sent = e->nsend};
      ocp_put_epoch_begin(out, version, &m);
      if (out->err) return OC_ENOMEM;
      e->phase = OCP__PH_RECORDS;
      break;
    }
    case OCP__PH_RECORDS:
      OC_TRY(ocp__next_records(e, version, out));
      if (e->op_i == e->nops) e->phase = e->nsend ? OCP__PH_BRICKS : OCP__PH_END;
      return 1;
    case OCP__PH_BRICKS:
      OC_TRY(ocp__next_bricks(e, version, out));
      if (e->send_i == e->nsend) e->phase = OCP__PH_END;
      return 1;
    case OCP__PH_END: {
      ocp_epoch_end_t m = {e->state->epoch, e->checksum};
      ocp_put_epoch_end(out, version, &m);
      if (out->err) return OC_ENOMEM;
      e->phase = OCP__PH_IDLE;
      break;
    }
    default: return 0; /* done, or no epoch begun */
  }
  /* EPOCH_BEGIN and EPOCH_END: sent as they are */
  e->st.frames++;
  e->st.wire_bytes += out->len - start;
  e->st.raw_bytes += out->len - start;
  return 1;
}

uint64_t ocp_epoch_enc_checksum(const ocp_epoch_enc_t *e) { return e && e->state ? e->checksum : 0; }

size_t ocp_epoch_enc_memory(const ocp_epoch_enc_t *e) {
  if (!e) return 0;
  return sizeof *e + ZSTD_sizeof_CCtx(e->cctx) + ZSTD_sizeof_CDict(e->cdict) + (e->raw ? OCP_CHUNK_RAW_MAX : 0) +
         e->ops_cap * sizeof *e->ops + e->send_cap * sizeof *e->send;
}

void ocp_epoch_enc_stats(const ocp_epoch_enc_t *e, ocp_enc_stats_t *out) {
  if (!out) return;
  if (!e) {
    memset(out, 0, sizeof *out);
    return;
  }
  *out = e->st;
}

/*-*** Decoder ***/

typedef struct {
  uint32_t id;
  uint32_t slot; /* received: index in st.bricks (full) or 0 (lean: digest in dig); else OCP__NONE */
  uint32_t node; /* index of its record in st.nodes */
} ocp__ref_t;

struct ocp_epoch_dec_s {
  ZSTD_DCtx *dctx;
  ZSTD_DDict *ddict;
  uint32_t dict_id; /* of ddict; 0: none installed */
  int active, bricks_started;
  int lean; /* this epoch keeps digests, not codes (ocp_epoch_dec_begin_lean) */
  ocp_epoch_begin_t m;
  const oc_state_t *base;
  ocp_brick_lookup_fn lookup;
  ocp_digest_lookup_fn dlookup;
  void *ctx;
  uint32_t received; /* bricks received this epoch */
  uint32_t base_pos; /* base records consumed by KEEP and SKIP */
  oc_state_t st;     /* nodes so far; bricks as received (arrival order) */
  ocp__ref_t *refs;  /* ids of the state's brick records, ascending (once records are complete) */
  uint32_t nrefs;
  oc_brick_digests_t dig; /* lean: the state's ids (as refs) and digests, filled as bricks arrive */
  uint8_t *raw; /* one decompressed chunk */
  size_t raw_cap;
};

int ocp_epoch_dec_create(ocp_epoch_dec_t **out) {
  if (!out) return OC_EINVAL;
  *out = NULL;
  ocp_epoch_dec_t *d = calloc(1, sizeof *d);
  if (!d) return OC_ENOMEM;
  d->dctx = ZSTD_createDCtx();
  if (!d->dctx || ZSTD_isError(ZSTD_DCtx_setParameter(d->dctx, ZSTD_d_windowLogMax, OCP__WINDOW_LOG_MAX))) {
    ZSTD_freeDCtx(d->dctx);
    free(d);
    return OC_ENOMEM;
  }
  oc_state_init(&d->st);
  *out = d;
  return 0;
}

/* Drops the epoch in progress; the dictionary and the scratch buffer stay. */
static void ocp__dec_reset(ocp_epoch_dec_t *d) {
  oc_state_free(&d->st);
  free(d->refs);
  d->refs = NULL;
  d->nrefs = 0;
  oc_brick_digests_free(&d->dig);
  d->active = d->bricks_started = d->lean = 0;
  d->base = NULL;
  d->lookup = NULL;
  d->dlookup = NULL;
  d->ctx = NULL;
  d->base_pos = 0;
  d->received = 0;
}

void ocp_epoch_dec_free(ocp_epoch_dec_t *d) {
  if (!d) return;
  ocp__dec_reset(d);
  ZSTD_freeDCtx(d->dctx);
  ZSTD_freeDDict(d->ddict);
  free(d->raw);
  free(d);
}

int ocp_epoch_dec_active(const ocp_epoch_dec_t *d) { return d && d->active; }

int ocp_epoch_dec_dict(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len) {
  if (!d || (!payload && n)) return OC_EINVAL;
  if (n < 4) return oc_errorf(OC_ECORRUPT, why, why_len, "dictionary: %zu-byte payload is too short", n);
  uint32_t id = oc_get_u32(payload);
  size_t len = n - 4;
  if (id == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "dictionary: id 0");
  if (len == 0 || len > OCP_DICT_MAX) return oc_errorf(OC_ECORRUPT, why, why_len, "dictionary %" PRIu32 ": %zu bytes (1..%u)", id, len, OCP_DICT_MAX);
  /* Bytes with the zstd dictionary magic must parse as one; anything else is a raw-content
   * dictionary, which zstd accepts as history. The DDict holds its own copy. */
  ZSTD_DDict *dd = ZSTD_createDDict(payload + 4, len);
  if (!dd) {
    if (len >= 4 && oc_get_u32(payload + 4) == ZSTD_MAGIC_DICTIONARY)
      return oc_errorf(OC_ECORRUPT, why, why_len, "dictionary %" PRIu32 ": not a valid zstd dictionary", id);
    return OC_ENOMEM;
  }
  ZSTD_freeDDict(d->ddict);
  d->ddict = dd;
  d->dict_id = id;
  return 0;
}

/* The start both decoder kinds share: why cleared, arguments checked (has_lookup: the caller's
 * lookup function is set), the counts checked, the base adopted; ctx is the lookup's context. */
static int ocp__dec_begin(ocp_epoch_dec_t *d, const ocp_epoch_begin_t *m, const oc_state_t *base, int has_lookup, void *ctx,
                          char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!d || !m || !has_lookup) return OC_EINVAL;
  ocp__dec_reset(d);
  if (m->node_count == 0 || m->node_count > OC_STATE_MAX_NODES || m->brick_count > OC_STATE_MAX_BRICKS ||
      m->bricks_sent > m->brick_count) {
    oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": bad counts (%" PRIu32 " records, %" PRIu32 " bricks, %" PRIu32 " sent)", m->epoch,
              m->node_count, m->brick_count, m->bricks_sent);
    return OC_EINVAL;
  }
  if ((m->base_epoch == OCP_NO_BASE) != (base == NULL) || (base && base->epoch != m->base_epoch)) {
    if (m->base_epoch == OCP_NO_BASE)
      oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": a base state was given for an epoch without one", m->epoch);
    else
      oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": base state of epoch %" PRIu64 " not held", m->epoch, m->base_epoch);
    return OC_EINVAL;
  }
  d->m = *m;
  d->base = base;
  d->st.epoch = m->epoch;
  d->st.time = m->time;
  d->st.sun_dir = m->sun_dir;
  d->active = 1;
  d->ctx = ctx;
  return 0;
}

int ocp_epoch_dec_begin(ocp_epoch_dec_t *d, const ocp_epoch_begin_t *m, const oc_state_t *base, ocp_brick_lookup_fn lookup,
                        void *ctx, char *why, size_t why_len) {
  OC_TRY(ocp__dec_begin(d, m, base, lookup != NULL, ctx, why, why_len));
  d->lookup = lookup;
  return 0;
}

int ocp_epoch_dec_begin_lean(ocp_epoch_dec_t *d, const ocp_epoch_begin_t *m, const oc_state_t *base, ocp_digest_lookup_fn lookup,
                             void *ctx, char *why, size_t why_len) {
  OC_TRY(ocp__dec_begin(d, m, base, lookup != NULL, ctx, why, why_len));
  d->lean = 1;
  d->dlookup = lookup;
  return 0;
}

/* Decompresses the zstd frame z[0..zn) of exactly `raw_len` bytes into d->raw. The frame must
 * declare that size and be the whole input (no second frame, no skippable frame). */
static int ocp__inflate(ocp_epoch_dec_t *d, const uint8_t *z, size_t zn, uint32_t raw_len, const ZSTD_DDict *dd,
                        const char *what, char *why, size_t why_len) {
  if (raw_len == 0 || raw_len > OCP_CHUNK_RAW_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: raw length %" PRIu32 " (1..%u)", what, raw_len, OCP_CHUNK_RAW_MAX);
  unsigned long long cs = ZSTD_getFrameContentSize(z, zn);
  if (cs == ZSTD_CONTENTSIZE_ERROR || cs == ZSTD_CONTENTSIZE_UNKNOWN)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: not a zstd frame with a content size", what);
  if (cs != raw_len)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%s: zstd frame holds %llu bytes, raw length says %" PRIu32, what, cs, raw_len);
  size_t fz = ZSTD_findFrameCompressedSize(z, zn);
  if (ZSTD_isError(fz) || fz != zn) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: payload is not exactly one zstd frame", what);
  if (d->raw_cap < raw_len) {
    uint8_t *p = realloc(d->raw, raw_len);
    if (!p) return OC_ENOMEM;
    d->raw = p, d->raw_cap = raw_len;
  }
  size_t r = dd ? ZSTD_decompress_usingDDict(d->dctx, d->raw, raw_len, z, zn, dd) : ZSTD_decompressDCtx(d->dctx, d->raw, raw_len, z, zn);
  if (ZSTD_isError(r)) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: zstd: %s", what, ZSTD_getErrorName(r));
  if (r != raw_len) return oc_errorf(OC_ECORRUPT, why, why_len, "%s: zstd frame decompressed to %zu of %" PRIu32 " bytes", what, r, raw_len);
  return 0;
}

/* Room for `need` records; grows by doubling (capped at the announced count), so memory follows
 * what arrived. */
static int ocp__reserve_nodes(ocp_epoch_dec_t *d, uint32_t need) {
  if (need <= d->st.node_cap) return 0;
  uint64_t nc = d->st.node_cap ? 2 * (uint64_t)d->st.node_cap : 64;
  if (nc < need) nc = need;
  if (nc > d->m.node_count) nc = d->m.node_count;
  oc_node_t *p = realloc(d->st.nodes, (size_t)nc * sizeof *p);
  if (!p) return OC_ENOMEM;
  d->st.nodes = p, d->st.node_cap = (uint32_t)nc;
  return 0;
}

static int ocp__dec_ops(ocp_epoch_dec_t *d, const uint8_t *p, size_t n, char *why, size_t why_len) {
  uint32_t nbase = d->base ? d->base->node_count : 0;
  oc_state_t *s = &d->st;
  size_t pos = 0;
  while (pos < n) {
    if (n - pos < OCP__OP_BYTES) return oc_errorf(OC_ECORRUPT, why, why_len, "records: op cut at byte %zu", pos);
    uint8_t op = p[pos];
    uint32_t k = oc_get_u32(p + pos + 1);
    pos += OCP__OP_BYTES;
    if (k == 0) return oc_errorf(OC_ECORRUPT, why, why_len, "records: op %u with count 0", (unsigned)op);
    if (op == OCP_OP_SKIP || op == OCP_OP_KEEP) {
      if (k > nbase - d->base_pos)
        return oc_errorf(OC_ECORRUPT, why, why_len, "records: %s %" PRIu32 " past the base (%" PRIu32 " of %" PRIu32 " records left)",
                         op == OCP_OP_SKIP ? "SKIP" : "KEEP", k, nbase - d->base_pos, nbase);
    }
    if (op == OCP_OP_SKIP) {
      d->base_pos += k;
      continue;
    }
    if (op != OCP_OP_KEEP && op != OCP_OP_ADD) return oc_errorf(OC_ECORRUPT, why, why_len, "records: unknown op %u", (unsigned)op);
    if (k > d->m.node_count - s->node_count)
      return oc_errorf(OC_ECORRUPT, why, why_len, "records: %" PRIu32 " more records than the %" PRIu32 " announced", k,
                       d->m.node_count - s->node_count);
    if (op == OCP_OP_ADD && k > (n - pos) / OC_STATE_RECORD_BYTES)
      return oc_errorf(OC_ECORRUPT, why, why_len, "records: ADD %" PRIu32 " with bytes for %zu", k, (n - pos) / OC_STATE_RECORD_BYTES);
    OC_TRY(ocp__reserve_nodes(d, s->node_count + k));
    oc_node_t *dst = s->nodes + s->node_count;
    if (op == OCP_OP_KEEP) {
      memcpy(dst, d->base->nodes + d->base_pos, (size_t)k * sizeof *dst);
      d->base_pos += k;
    } else {
      for (uint32_t r = 0; r < k; r++, pos += OC_STATE_RECORD_BYTES) {
        if (oc_state_unpack_record(p + pos, &dst[r]) < 0)
          return oc_errorf(OC_ECORRUPT, why, why_len, "records: record %" PRIu32 " has non-zero reserved bytes", s->node_count + r);
      }
    }
    /* Ascending keys (the rest of validity waits for oc_state_validate at the end): a KEEP run is
     * ascending already, so only its first record needs comparing. */
    for (uint32_t r = 0; r < k; r++) {
      uint32_t at = s->node_count + r;
      if (at > 0 && s->nodes[at].key <= s->nodes[at - 1].key)
        return oc_errorf(OC_ECORRUPT, why, why_len, "records: record %" PRIu32 " (key 0x%" PRIx64 ") is not after key 0x%" PRIx64, at,
                         s->nodes[at].key, s->nodes[at - 1].key);
      if (op == OCP_OP_KEEP) break;
    }
    s->node_count += k;
  }
  return 0;
}

int ocp_epoch_dec_records(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!d || (!payload && n)) return OC_EINVAL;
  if (!d->active) return oc_errorf(OC_ECORRUPT, why, why_len, "records outside an epoch");
  int r;
  if (d->bricks_started)
    r = oc_errorf(OC_ECORRUPT, why, why_len, "records after the first bricks of epoch %" PRIu64, d->m.epoch);
  else if (n < 4)
    r = oc_errorf(OC_ECORRUPT, why, why_len, "records: %zu-byte payload is too short", n);
  else if ((r = ocp__inflate(d, payload + 4, n - 4, oc_get_u32(payload), NULL, "records", why, why_len)) == 0)
    r = ocp__dec_ops(d, d->raw, oc_get_u32(payload), why, why_len);
  if (r < 0) ocp__dec_reset(d); /* the stream is broken: the epoch cannot complete */
  return r;
}

static int ocp__cmp_ref(const void *a, const void *b) {
  uint32_t x = ((const ocp__ref_t *)a)->id, y = ((const ocp__ref_t *)b)->id;
  return (x > y) - (x < y);
}

/* The records are complete (every one arrived, the base consumed exactly): the brick ids they
 * name, ascending and distinct, as many as announced. */
static int ocp__records_done(ocp_epoch_dec_t *d, char *why, size_t why_len) {
  const oc_state_t *s = &d->st;
  uint32_t nbase = d->base ? d->base->node_count : 0, nb = 0;
  if (s->node_count != d->m.node_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": %" PRIu32 " of %" PRIu32 " records arrived", d->m.epoch, s->node_count,
                     d->m.node_count);
  if (d->base_pos != nbase)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": ops consumed %" PRIu32 " of the base's %" PRIu32 " records", d->m.epoch,
                     d->base_pos, nbase);
  for (uint32_t i = 0; i < s->node_count; i++) nb += s->nodes[i].kind == OC_NODE_BRICK;
  if (nb != d->m.brick_count)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": the records name %" PRIu32 " bricks, %" PRIu32 " announced", d->m.epoch, nb,
                     d->m.brick_count);
  if (nb) {
    d->refs = malloc((size_t)nb * sizeof *d->refs);
    if (!d->refs) return OC_ENOMEM;
  }
  for (uint32_t i = 0; i < s->node_count; i++)
    if (s->nodes[i].kind == OC_NODE_BRICK) d->refs[d->nrefs++] = (ocp__ref_t){s->nodes[i].brick_id, OCP__NONE, i};
  if (d->nrefs > 1) qsort(d->refs, d->nrefs, sizeof *d->refs, ocp__cmp_ref);
  for (uint32_t k = 1; k < d->nrefs; k++)
    if (d->refs[k].id == d->refs[k - 1].id)
      return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": brick %" PRIu32 " is named by two records", d->m.epoch, d->refs[k].id);
  if (d->lean && nb) { /* the lean state's bricks: exactly the refs, digests filled in as they come */
    d->dig.ids = malloc((size_t)nb * sizeof *d->dig.ids);
    d->dig.digests = malloc((size_t)nb * sizeof *d->dig.digests);
    if (!d->dig.ids || !d->dig.digests) return OC_ENOMEM;
    for (uint32_t k = 0; k < nb; k++) d->dig.ids[k] = d->refs[k].id;
    d->dig.count = nb;
  }
  d->bricks_started = 1;
  return 0;
}

static ocp__ref_t *ocp__find_ref(ocp_epoch_dec_t *d, uint32_t id) {
  if (!d->nrefs) return NULL;
  int64_t k = oc_ids_find(&d->refs[0].id, sizeof *d->refs, d->nrefs, id);
  return k < 0 ? NULL : &d->refs[k];
}

/* A zero channel's codes are all zero (one byte form per content; oc_state_validate's rule, for a
 * lean viewer that cannot check them once the codes are gone). */
static int ocp__zero_channels_ok(const oc_node_t *n, const oc_brick_codes_t *c, uint32_t id, char *why, size_t why_len) {
  static const char *ch_name[OC_CHANNELS] = {"sigma", "tau"};
  for (int ch = 0; ch < OC_CHANNELS; ch++) {
    if (n->range[ch].hi != 0.0f) continue;
    for (int v = 0; v < OC_BRICK_VOXELS; v++)
      if (c->code[ch][v] != OC_CODE_ZERO)
        return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": non-zero %s code in a zero channel", id, ch_name[ch]);
  }
  return 0;
}

static int ocp__dec_batch(ocp_epoch_dec_t *d, const uint8_t *p, size_t n, char *why, size_t why_len) {
  if (n < 4) return oc_errorf(OC_ECORRUPT, why, why_len, "bricks: %zu raw bytes, no brick count", n);
  uint32_t count = oc_get_u32(p);
  if (count == 0 || count > OCP_BATCH_MAX)
    return oc_errorf(OC_ECORRUPT, why, why_len, "bricks: batch of %" PRIu32 " bricks (1..%d)", count, OCP_BATCH_MAX);
  if (n != 4 + (size_t)count * OCP__BRICK_WIRE)
    return oc_errorf(OC_ECORRUPT, why, why_len, "bricks: %zu raw bytes for %" PRIu32 " bricks (%zu expected)", n, count,
                     4 + (size_t)count * OCP__BRICK_WIRE);
  if (count > d->m.bricks_sent - d->received)
    return oc_errorf(OC_ECORRUPT, why, why_len, "bricks: %" PRIu32 " more bricks than the %" PRIu32 " announced", count,
                     d->m.bricks_sent - d->received);
  const uint8_t *planes = p + 4 + (size_t)count * OCP__BRICK_HEAD;
  for (uint32_t k = 0; k < count; k++) {
    const uint8_t *h = p + 4 + (size_t)k * OCP__BRICK_HEAD;
    uint32_t id = oc_get_u32(h), base_id = oc_get_u32(h + 4);
    unsigned flags = h[8];
    ocp__ref_t *ref = ocp__find_ref(d, id);
    if (!ref) return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": no brick record of this state names it", id);
    if (ref->slot != OCP__NONE) return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": sent twice", id);
    if (flags & ~(OCP_BRICK_DELTA_SIGMA | OCP_BRICK_DELTA_TAU) || (h[9] | h[10] | h[11]))
      return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": bad flags 0x%02x or reserved bytes", id, flags);
    if ((base_id != 0) != (flags != 0))
      return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": base id %" PRIu32 " with flags 0x%02x", id, base_id, flags);
    if (flags && d->lean)
      return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": a delta of %" PRIu32 " to a lean viewer, which holds no codes", id,
                       base_id);
    const oc_brick_codes_t *base = NULL;
    if (flags && !(base = d->lookup(d->ctx, base_id)))
      return oc_errorf(OC_ECORRUPT, why, why_len, "brick %" PRIu32 ": delta base %" PRIu32 " not held", id, base_id);
    oc_brick_codes_t c;
    ocp__planes_get(planes + (size_t)k * OCP__BRICK_PLANES, base, flags, &c);
    d->received++;
    if (d->lean) { /* the codes end here: checked and digested now, as oc_state_validate would */
      OC_TRY(ocp__zero_channels_ok(&d->st.nodes[ref->node], &c, id, why, why_len));
      d->dig.digests[ref - d->refs] = oc_brick_digest(&c);
      ref->slot = 0;
      continue;
    }
    ref->slot = d->st.brick_count;
    OC_TRY(oc_state_add_brick(&d->st, id, &c));
  }
  return 0;
}

int ocp_epoch_dec_bricks(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!d || (!payload && n)) return OC_EINVAL;
  if (!d->active) return oc_errorf(OC_ECORRUPT, why, why_len, "bricks outside an epoch");
  int r = 0;
  if (!d->bricks_started && (r = ocp__records_done(d, why, why_len)) < 0) {
    if (r == OC_ECORRUPT) {
      char tmp[256];
      snprintf(tmp, sizeof tmp, "%s", why && why_len ? why : "");
      r = oc_errorf(OC_ECORRUPT, why, why_len, "bricks before the records are complete: %s", tmp);
    }
  } else if (n < 8) {
    r = oc_errorf(OC_ECORRUPT, why, why_len, "bricks: %zu-byte payload is too short", n);
  } else {
    uint32_t dict_id = oc_get_u32(payload), raw_len = oc_get_u32(payload + 4);
    if (dict_id != 0 && (!d->ddict || dict_id != d->dict_id))
      r = oc_errorf(OC_ECORRUPT, why, why_len, "bricks: unknown dictionary %" PRIu32 " (installed: %" PRIu32 ")", dict_id, d->ddict ? d->dict_id : 0);
    else if ((r = ocp__inflate(d, payload + 8, n - 8, raw_len, dict_id ? d->ddict : NULL, "bricks", why, why_len)) == 0)
      r = ocp__dec_batch(d, d->raw, raw_len, why, why_len);
  }
  if (r < 0) ocp__dec_reset(d);
  return r;
}

/* What both ends check first: the epoch, every record, every announced brick. */
static int ocp__end_common(ocp_epoch_dec_t *d, const ocp_epoch_end_t *m, char *why, size_t why_len) {
  if (m->epoch != d->m.epoch)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch end for epoch %" PRIu64 " during epoch %" PRIu64, m->epoch, d->m.epoch);
  if (!d->bricks_started) OC_TRY(ocp__records_done(d, why, why_len));
  if (d->received != d->m.bricks_sent)
    return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": %" PRIu32 " of %" PRIu32 " bricks arrived", d->m.epoch, d->received,
                     d->m.bricks_sent);
  return 0;
}

static int ocp__not_held(const ocp_epoch_dec_t *d, uint32_t id, char *why, size_t why_len) {
  return oc_errorf(OC_ECORRUPT, why, why_len, "epoch %" PRIu64 ": brick %" PRIu32 " was neither sent nor held", d->m.epoch, id);
}

static int ocp__checksum_mismatch(const ocp_epoch_dec_t *d, uint64_t sent, uint64_t rebuilt, const char *what, char *why,
                                  size_t why_len) {
  oc_errorf(OC_ECORRUPT, why, why_len, "state epoch %" PRIu64 ": %s mismatch: sent %016" PRIx64 ", rebuilt %016" PRIx64, d->m.epoch, what,
            sent, rebuilt);
  return OC_ECHECKSUM;
}

int ocp_epoch_dec_end(ocp_epoch_dec_t *d, const ocp_epoch_end_t *m, oc_state_t *out, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!d || !m || !out) return OC_EINVAL;
  if (!d->active) return oc_errorf(OC_ECORRUPT, why, why_len, "epoch end outside an epoch");
  int r = 0;
  oc_brick_t *bricks = NULL;
  if (d->lean) {
    r = OC_EINVAL; /* begun with ocp_epoch_dec_begin_lean: ended by ocp_epoch_dec_end_lean */
    goto done;
  }
  if ((r = ocp__end_common(d, m, why, why_len)) < 0) goto done;
  if (d->nrefs && !(bricks = malloc((size_t)d->nrefs * sizeof *bricks))) {
    r = OC_ENOMEM;
    goto done;
  }
  /* Ascending id, as refs: received bricks, and every other one from what the viewer holds. */
  for (uint32_t k = 0; k < d->nrefs; k++) {
    const ocp__ref_t *ref = &d->refs[k];
    const oc_brick_codes_t *held = NULL;
    if (ref->slot == OCP__NONE && !(held = d->lookup(d->ctx, ref->id))) {
      r = ocp__not_held(d, ref->id, why, why_len);
      goto done;
    }
    bricks[k].id = ref->id;
    bricks[k].codes = held ? *held : d->st.bricks[ref->slot].codes;
  }
  free(d->st.bricks);
  d->st.bricks = bricks;
  d->st.brick_count = d->st.brick_cap = d->nrefs;
  bricks = NULL;
  char tmp[256];
  if ((r = oc_state_validate(&d->st, tmp, sizeof tmp)) < 0) {
    if (r == OC_ECORRUPT) r = oc_errorf(OC_ECORRUPT, why, why_len, "state epoch %" PRIu64 ": %s", d->m.epoch, tmp);
    goto done;
  }
  uint64_t h = oc_state_checksum(&d->st);
  if (h != m->checksum) {
    r = ocp__checksum_mismatch(d, m->checksum, h, "checksum", why, why_len);
    goto done;
  }
  oc_state_free(out);
  *out = d->st;
  oc_state_init(&d->st);
done:
  free(bricks);
  ocp__dec_reset(d);
  return r;
}

int ocp_epoch_dec_end_lean(ocp_epoch_dec_t *d, const ocp_epoch_end_t *m, oc_state_t *out, oc_brick_digests_t *digests, char *why,
                           size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!d || !m || !out || !digests) return OC_EINVAL;
  if (!d->active) return oc_errorf(OC_ECORRUPT, why, why_len, "epoch end outside an epoch");
  int r = 0;
  if (!d->lean) {
    r = OC_EINVAL; /* begun with ocp_epoch_dec_begin */
    goto done;
  }
  if ((r = ocp__end_common(d, m, why, why_len)) < 0) goto done;
  for (uint32_t k = 0; k < d->nrefs; k++) /* held: the digest the viewer kept for that id */
    if (d->refs[k].slot == OCP__NONE && !d->dlookup(d->ctx, d->refs[k].id, &d->dig.digests[k])) {
      r = ocp__not_held(d, d->refs[k].id, why, why_len);
      goto done;
    }
  char tmp[256];
  if ((r = oc_state_validate_lean(&d->st, &d->dig, tmp, sizeof tmp)) < 0) {
    if (r == OC_ECORRUPT) r = oc_errorf(OC_ECORRUPT, why, why_len, "state epoch %" PRIu64 ": %s", d->m.epoch, tmp);
    goto done;
  }
  uint64_t h = oc_state_digest_checksum(&d->st, &d->dig);
  if (h != m->checksum) {
    r = ocp__checksum_mismatch(d, m->checksum, h, "digest checksum", why, why_len);
    goto done;
  }
  oc_state_free(out);
  oc_brick_digests_free(digests);
  *out = d->st; /* records only: brick_count 0, bricks NULL */
  oc_state_init(&d->st);
  *digests = d->dig;
  memset(&d->dig, 0, sizeof d->dig);
done:
  ocp__dec_reset(d);
  return r;
}

/*-*** Plain zstd frames ***/

ocp_zcctx_t *ocp_zcctx_new(void) { return ZSTD_createCCtx(); }
ocp_zdctx_t *ocp_zdctx_new(void) { return ZSTD_createDCtx(); }
void ocp_zcctx_free(ocp_zcctx_t *c) { ZSTD_freeCCtx(c); }
void ocp_zdctx_free(ocp_zdctx_t *d) { ZSTD_freeDCtx(d); }
size_t ocp_zstd_bound(size_t n) { return ZSTD_compressBound(n); }
unsigned ocp_zstd_is_error(size_t code) { return ZSTD_isError(code); }
size_t ocp_zstd_compress(ocp_zcctx_t *c, void *dst, size_t cap, const void *src, size_t n, int level) {
  return ZSTD_compressCCtx(c, dst, cap, src, n, level);
}
size_t ocp_zstd_decompress(ocp_zdctx_t *d, void *dst, size_t cap, const void *src, size_t n) {
  return ZSTD_decompressDCtx(d, dst, cap, src, n);
}
unsigned long long ocp_zstd_content_size(const void *src, size_t n) { return ZSTD_getFrameContentSize(src, n); }

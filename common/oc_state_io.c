/* oc_state_io.c — byte-exact serialisation, checksum and state files (oc_state.h;
 * docs/protocol.md, "State").
 *
 * Layout (little-endian, explicit byte packing, never a struct image):
 *   header   64 bytes   "OCST", u32 version, u64 epoch, f64 time, f64 sun x, y, z,
 *                       u32 node_count, u32 brick_count, 8 reserved zero bytes
 *   records  32 bytes   u64 key, u8 kind, 3 zero bytes, u32 brick_id, f32 σ lo, σ hi, τ lo, τ hi
 *   bricks   2052 bytes u32 id, 512 u16 σ codes, 512 u16 τ codes (x fastest)
 *   trailer  8 bytes    u64 XXH3-64 (seed 0) of every preceding byte
 *
 * One emitter produces the bytes in chunks for three sinks (a buffer, a hash state, a file), so the
 * checksum and the file can never disagree with oc_state_serialize(), and neither needs the whole
 * serialisation in memory. The digest checksum (lean viewers) shares its header and records and
 * replaces each brick by u32 id + u64 XXH3-64 of its 2048 code bytes. */
#include "oc_state.h"

#include <errno.h>
#include <inttypes.h> /* PRIu32 */
#include <stdarg.h>
#include <stdio.h>  /* FILE, snprintf */
#include <stdlib.h> /* malloc */
#include <string.h> /* memcpy, strerror */

/* Header-only xxHash: the XXH3 streaming state lives on the stack, with no allocation and no
 * dependence on the shared library's struct layout; the bytes hashed are identical to
 * libxxhash's XXH3_64bits (the algorithm is frozen since 0.8.0). */
#define XXH_INLINE_ALL
#include <xxhash.h> /* XXH3_state_t, XXH3_64bits_* */

#include "oc_bytes.h" /* oc_put_*, oc_get_* */
#include "oc_err.h"   /* OC_E* */

/*-*** Emitter ***/

typedef int (*oc__sink_fn)(void *ctx, const uint8_t *p, size_t n);

#define OC__REC_CHUNK 128 /* records per sink call: 4 KiB */

/* brick_count: the header's brick count (a lean state's bricks are not in s). */
static void oc__pack_header(const oc_state_t *s, uint32_t brick_count, uint8_t h[OC_STATE_HEADER_BYTES]) {
  memset(h, 0, OC_STATE_HEADER_BYTES);
  memcpy(h, OC_STATE_MAGIC, 4);
  oc_put_u32(h + 4, OC_STATE_VERSION);
  oc_put_u64(h + 8, s->epoch);
  oc_put_f64(h + 16, s->time);
  oc_put_f64(h + 24, s->sun_dir.x);
  oc_put_f64(h + 32, s->sun_dir.y);
  oc_put_f64(h + 40, s->sun_dir.z);
  oc_put_u32(h + 48, s->node_count);
  oc_put_u32(h + 52, brick_count);
  /* 56..63 reserved, zero */
}

void oc_state_pack_record(const oc_node_t *n, uint8_t r[OC_STATE_RECORD_BYTES]) {
  oc_put_u64(r, n->key);
  r[8] = n->kind;
  r[9] = r[10] = r[11] = 0;
  oc_put_u32(r + 12, n->brick_id);
  oc_put_f32(r + 16, n->range[OC_CH_SIGMA].lo);
  oc_put_f32(r + 20, n->range[OC_CH_SIGMA].hi);
  oc_put_f32(r + 24, n->range[OC_CH_TAU].lo);
  oc_put_f32(r + 28, n->range[OC_CH_TAU].hi);
}

int oc_state_unpack_record(const uint8_t r[OC_STATE_RECORD_BYTES], oc_node_t *n) {
  memset(n, 0, sizeof *n);
  n->key = oc_get_u64(r);
  n->kind = r[8];
  n->brick_id = oc_get_u32(r + 12);
  n->range[OC_CH_SIGMA].lo = oc_get_f32(r + 16);
  n->range[OC_CH_SIGMA].hi = oc_get_f32(r + 20);
  n->range[OC_CH_TAU].lo = oc_get_f32(r + 24);
  n->range[OC_CH_TAU].hi = oc_get_f32(r + 28);
  return (r[9] | r[10] | r[11]) ? OC_ECORRUPT : 0;
}

static void oc__pack_brick(const oc_brick_t *b, uint8_t p[OC_STATE_BRICK_BYTES]) {
  oc_put_u32(p, b->id);
  p += 4;
  for (int c = 0; c < OC_CHANNELS; c++)
    for (int v = 0; v < OC_BRICK_VOXELS; v++, p += 2) oc_put_u16(p, b->codes.code[c][v]);
}

/* Header and records, in order, through `sink`, from buf (room for a chunk of records). */
static int oc__emit_head(const oc_state_t *s, uint32_t brick_count, uint8_t *buf, oc__sink_fn sink, void *ctx) {
  oc__pack_header(s, brick_count, buf);
  OC_TRY(sink(ctx, buf, OC_STATE_HEADER_BYTES));
  for (uint32_t i = 0; i < s->node_count;) {
    uint32_t k = 0;
    for (; k < OC__REC_CHUNK && i < s->node_count; k++, i++) oc_state_pack_record(&s->nodes[i], buf + k * OC_STATE_RECORD_BYTES);
    OC_TRY(sink(ctx, buf, (size_t)k * OC_STATE_RECORD_BYTES));
  }
  return 0;
}

/* Everything but the trailing checksum, in order, through `sink`. */
static int oc__emit(const oc_state_t *s, oc__sink_fn sink, void *ctx) {
  uint8_t buf[OC__REC_CHUNK * OC_STATE_RECORD_BYTES];
  _Static_assert(sizeof buf >= OC_STATE_BRICK_BYTES && sizeof buf >= OC_STATE_HEADER_BYTES, "chunk too small");
  OC_TRY(oc__emit_head(s, s->brick_count, buf, sink, ctx));
  for (uint32_t i = 0; i < s->brick_count; i++) {
    oc__pack_brick(&s->bricks[i], buf);
    OC_TRY(sink(ctx, buf, OC_STATE_BRICK_BYTES));
  }
  return 0;
}

#define OC__DIGEST_ENTRY 12 /* u32 id, u64 digest: a brick in the digest form */

/* The digest form of the same stream: header and records as oc__emit, then each brick as its id
 * and digest, from b, or (b NULL) from s's bricks, digested on the fly. */
static int oc__emit_digests(const oc_state_t *s, const oc_brick_digests_t *b, oc__sink_fn sink, void *ctx) {
  uint8_t buf[OC__REC_CHUNK * OC_STATE_RECORD_BYTES];
  enum { per_chunk = sizeof buf / OC__DIGEST_ENTRY };
  uint32_t m = b ? b->count : s->brick_count;
  OC_TRY(oc__emit_head(s, m, buf, sink, ctx));
  for (uint32_t i = 0; i < m;) {
    uint32_t k = 0;
    for (; k < per_chunk && i < m; k++, i++) {
      uint8_t *e = buf + (size_t)k * OC__DIGEST_ENTRY;
      oc_put_u32(e, b ? b->ids[i] : s->bricks[i].id);
      oc_put_u64(e + 4, b ? b->digests[i] : oc_brick_digest(&s->bricks[i].codes));
    }
    OC_TRY(sink(ctx, buf, (size_t)k * OC__DIGEST_ENTRY));
  }
  return 0;
}

static int oc__sink_hash(void *ctx, const uint8_t *p, size_t n) {
  return XXH3_64bits_update((XXH3_state_t *)ctx, p, n) == XXH_OK ? 0 : OC_EINVAL;
}

typedef struct {
  uint8_t *dst;
  size_t pos;
} oc__mem_sink_t;

static int oc__sink_mem(void *ctx, const uint8_t *p, size_t n) {
  oc__mem_sink_t *m = ctx;
  memcpy(m->dst + m->pos, p, n);
  m->pos += n;
  return 0;
}

/*-*** Serialise ***/

static uint64_t oc__size_for(uint64_t nodes, uint64_t bricks) {
  return OC_STATE_HEADER_BYTES + nodes * OC_STATE_RECORD_BYTES + bricks * OC_STATE_BRICK_BYTES + 8;
}

size_t oc_state_serialized_size(const oc_state_t *s) {
  return s ? (size_t)oc__size_for(s->node_count, s->brick_count) : 0;
}

int64_t oc_state_serialize(const oc_state_t *s, uint8_t *dst, size_t cap) {
  if (!s || (!dst && cap)) return OC_EINVAL;
  size_t size = oc_state_serialized_size(s);
  if (!dst || cap < size) return OC_ENOBUFS;
  oc__mem_sink_t m = {dst, 0};
  OC_TRY(oc__emit(s, oc__sink_mem, &m));
  oc_put_u64(dst + m.pos, XXH3_64bits(dst, m.pos));
  return (int64_t)size;
}

uint64_t oc_state_checksum(const oc_state_t *s) {
  XXH3_state_t st;
  if (!s) return 0;
  XXH3_64bits_reset(&st);
  if (oc__emit(s, oc__sink_hash, &st) < 0) return 0; /* cannot happen: the hash sink does not fail */
  return XXH3_64bits_digest(&st);
}

uint64_t oc_brick_digest(const oc_brick_codes_t *c) {
  if (!c) return 0;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  /* The codes in memory are already their serialised bytes: no packing. */
  _Static_assert(sizeof c->code == OC_BRICK_CODE_BYTES, "codes are one packed array");
  return XXH3_64bits(c->code, OC_BRICK_CODE_BYTES);
#else
  uint8_t p[OC_BRICK_CODE_BYTES], *q = p;
  for (int ch = 0; ch < OC_CHANNELS; ch++)
    for (int v = 0; v < OC_BRICK_VOXELS; v++, q += 2) oc_put_u16(q, c->code[ch][v]);
  return XXH3_64bits(p, sizeof p);
#endif
}

/* Here, beside the digest it applies, so that oc_state.c calls nothing of this file. */
int oc_brick_digests_of(oc_brick_digests_t *out, const oc_state_t *s) {
  if (!out || !s) return OC_EINVAL;
  oc_brick_digests_free(out);
  if (!s->brick_count) return 0;
  out->ids = malloc((size_t)s->brick_count * sizeof *out->ids);
  out->digests = malloc((size_t)s->brick_count * sizeof *out->digests);
  if (!out->ids || !out->digests) {
    oc_brick_digests_free(out);
    return OC_ENOMEM;
  }
  for (uint32_t i = 0; i < s->brick_count; i++) {
    out->ids[i] = s->bricks[i].id;
    out->digests[i] = oc_brick_digest(&s->bricks[i].codes);
  }
  out->count = s->brick_count;
  return 0;
}

static uint64_t oc__digest_checksum(const oc_state_t *s, const oc_brick_digests_t *b) {
  XXH3_state_t st;
  XXH3_64bits_reset(&st);
  if (oc__emit_digests(s, b, oc__sink_hash, &st) < 0) return 0; /* cannot happen: the hash sink does not fail */
  return XXH3_64bits_digest(&st);
}

uint64_t oc_state_digest_checksum(const oc_state_t *s, const oc_brick_digests_t *b) {
  if (!s || !b || (b->count && (!b->ids || !b->digests))) return 0;
  return oc__digest_checksum(s, b);
}

uint64_t oc_state_digest(const oc_state_t *s) { return s ? oc__digest_checksum(s, NULL) : 0; }

/*-*** Deserialise ***/


int oc_state_deserialize(oc_state_t *out, const uint8_t *src, size_t len, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!out) return OC_EINVAL;
  oc_state_free(out);
  if (!src && len) return OC_EINVAL;
  /* Order: size of the fixed header, identity, limits, exact length, checksum; only then is
   * anything allocated, and never more than the length already proved present. */
  if (len < OC_STATE_HEADER_BYTES + 8)
    return oc_errorf(OC_ETRUNC, why, why_len, "truncated: %zu bytes, less than the %d-byte header and checksum", len,
                   OC_STATE_HEADER_BYTES + 8);
  if (memcmp(src, OC_STATE_MAGIC, 4) != 0) return oc_errorf(OC_ECORRUPT, why, why_len, "not a state: bad magic");
  uint32_t version = oc_get_u32(src + 4);
  if (version != OC_STATE_VERSION)
    return oc_errorf(OC_EVERSION, why, why_len, "state version %" PRIu32 ", expected %d", version, OC_STATE_VERSION);
  uint32_t n = oc_get_u32(src + 48), m = oc_get_u32(src + 52);
  if (n > OC_STATE_MAX_NODES) return oc_errorf(OC_ETOOBIG, why, why_len, "%" PRIu32 " nodes exceed the limit %u", n, OC_STATE_MAX_NODES);
  if (m > OC_STATE_MAX_BRICKS)
    return oc_errorf(OC_ETOOBIG, why, why_len, "%" PRIu32 " bricks exceed the limit %u", m, OC_STATE_MAX_BRICKS);
  uint64_t need = oc__size_for(n, m); /* ≤ 2^34: no overflow from the limits above */
  if ((uint64_t)len < need)
    return oc_errorf(OC_ETRUNC, why, why_len, "truncated: %zu bytes, %" PRIu64 " needed for %" PRIu32 " nodes and %" PRIu32 " bricks",
                   len, need, n, m);
  if ((uint64_t)len > need)
    return oc_errorf(OC_ECORRUPT, why, why_len, "%" PRIu64 " trailing bytes after %" PRIu32 " nodes and %" PRIu32 " bricks",
                   (uint64_t)len - need, n, m);
  uint64_t stored = oc_get_u64(src + need - 8), actual = XXH3_64bits(src, (size_t)need - 8);
  if (stored != actual)
    return oc_errorf(OC_ECHECKSUM, why, why_len, "checksum mismatch: stored %016" PRIx64 ", computed %016" PRIx64, stored, actual);
  for (int i = 56; i < OC_STATE_HEADER_BYTES; i++)
    if (src[i]) return oc_errorf(OC_ECORRUPT, why, why_len, "reserved header byte %d is not zero", i);

  oc_state_t s;
  oc_state_init(&s);
  s.epoch = oc_get_u64(src + 8);
  s.time = oc_get_f64(src + 16);
  s.sun_dir = oc_dv3(oc_get_f64(src + 24), oc_get_f64(src + 32), oc_get_f64(src + 40));
  if (n) {
    s.nodes = malloc((size_t)n * sizeof *s.nodes);
    if (!s.nodes) return oc_errorf(OC_ENOMEM, why, why_len, "out of memory for %" PRIu32 " nodes", n);
    s.node_cap = n;
  }
  if (m) {
    s.bricks = malloc((size_t)m * sizeof *s.bricks);
    if (!s.bricks) {
      oc_state_free(&s);
      return oc_errorf(OC_ENOMEM, why, why_len, "out of memory for %" PRIu32 " bricks", m);
    }
    s.brick_cap = m;
  }
  const uint8_t *p = src + OC_STATE_HEADER_BYTES;
  for (uint32_t i = 0; i < n; i++, p += OC_STATE_RECORD_BYTES) {
    if (oc_state_unpack_record(p, &s.nodes[i]) < 0) {
      oc_state_free(&s);
      return oc_errorf(OC_ECORRUPT, why, why_len, "node %" PRIu32 ": reserved bytes are not zero", i);
    }
  }
  s.node_count = n;
  for (uint32_t i = 0; i < m; i++) {
    oc_brick_t *b = &s.bricks[i];
    b->id = oc_get_u32(p);
    p += 4;
    for (int c = 0; c < OC_CHANNELS; c++)
      for (int v = 0; v < OC_BRICK_VOXELS; v++, p += 2) b->codes.code[c][v] = oc_get_u16(p);
  }
  s.brick_count = m;
  int err = oc_state_validate(&s, why, why_len);
  if (err < 0) {
    oc_state_free(&s);
    return err;
  }
  *out = s;
  return 0;
}

/*-*** Files ***/

static int oc__errno_code(int e) { return e == ENOENT ? OC_ENOENT : e == ENOMEM ? OC_ENOMEM : OC_EIO; }

typedef struct {
  FILE *f;
  XXH3_state_t *h;
} oc__file_sink_t;

static int oc__sink_file(void *ctx, const uint8_t *p, size_t n) {
  oc__file_sink_t *fs = ctx;
  XXH3_64bits_update(fs->h, p, n);
  return fwrite(p, 1, n, fs->f) == n ? 0 : OC_EIO;
}

/* Written to "<path>.tmp" and renamed, so a reader never sees half a state and a failed save
 * leaves the previous file intact. */
int oc_state_save(const oc_state_t *s, const char *path, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!s || !path) return OC_EINVAL;
  size_t plen = strlen(path);
  char *tmp = malloc(plen + 5);
  if (!tmp) return oc_errorf(OC_ENOMEM, why, why_len, "state file '%s': out of memory", path);
  memcpy(tmp, path, plen);
  memcpy(tmp + plen, ".tmp", 5);
  FILE *f = fopen(tmp, "wb");
  if (!f) {
    int e = errno;
    free(tmp);
    return oc_errorf(oc__errno_code(e), why, why_len, "state file '%s': cannot create: %s", path, strerror(e));
  }
  XXH3_state_t h;
  XXH3_64bits_reset(&h);
  oc__file_sink_t fs = {f, &h};
  int err = oc__emit(s, oc__sink_file, &fs), e = 0;
  if (!err) {
    uint8_t sum[8];
    oc_put_u64(sum, XXH3_64bits_digest(&h));
    if (fwrite(sum, 1, 8, f) != 8) err = OC_EIO;
  }
  if (err) e = errno;
  if (fclose(f) != 0 && !err) {
    e = errno;
    err = OC_EIO;
  }
  if (!err && rename(tmp, path) != 0) {
    e = errno;
    err = oc__errno_code(e);
  }
  if (err) {
    remove(tmp);
    free(tmp);
    return oc_errorf(err, why, why_len, "state file '%s': write failed: %s", path, e ? strerror(e) : oc_strerror(err));
  }
  free(tmp);
  return 0;
}

int oc_state_load(oc_state_t *out, const char *path, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (!out || !path) return OC_EINVAL;
  oc_state_free(out);
  FILE *f = fopen(path, "rb");
  if (!f) {
    int e = errno;
    return oc_errorf(oc__errno_code(e), why, why_len, "state file '%s': cannot open: %s", path, strerror(e));
  }
  /* The file's own size bounds the allocation; anything larger than the biggest legal state is
   * refused before reading. */
  off_t size = -1;
  if (fseeko(f, 0, SEEK_END) == 0) size = ftello(f);
  if (size < 0 || fseeko(f, 0, SEEK_SET) != 0) {
    int e = errno;
    fclose(f);
    return oc_errorf(OC_EIO, why, why_len, "state file '%s': cannot seek: %s", path, strerror(e));
  }
  if ((uint64_t)size > oc__size_for(OC_STATE_MAX_NODES, OC_STATE_MAX_BRICKS) || (uint64_t)size > SIZE_MAX) {
    fclose(f);
    return oc_errorf(OC_ETOOBIG, why, why_len, "state file '%s': %lld bytes exceed the largest legal state", path,
                   (long long)size);
  }
  uint8_t *buf = malloc(size ? (size_t)size : 1);
  if (!buf) {
    fclose(f);
    return oc_errorf(OC_ENOMEM, why, why_len, "state file '%s': out of memory for %lld bytes", path, (long long)size);
  }
  size_t got = fread(buf, 1, (size_t)size, f);
  int rerr = ferror(f);
  fclose(f);
  if (rerr || got != (size_t)size) {
    free(buf);
    return oc_errorf(OC_EIO, why, why_len, "state file '%s': read failed", path);
  }
  char inner[256];
  int err = oc_state_deserialize(out, buf, got, inner, sizeof inner);
  free(buf);
  if (err < 0) return oc_errorf(err, why, why_len, "state file '%s': %s", path, inner);
  return 0;
}

/* ocp_epoch.h — one epoch on the wire: the state's records (whole, or as a difference from a state
 * the viewer holds) and the bricks it lacks, compressed with zstd (docs/protocol.md, "Epoch").
 * The only code that includes <zstd.h>. Pure: no I/O, no clocks.
 *
 * Server side, an encoder turns (state, base, lacking ids) into frames one at a time, so a
 * session can produce them only as fast as its socket drains (bounded send queues):
 *   EPOCH_BEGIN, RECORDS × r, BRICKS × b, EPOCH_END.
 * Viewer side, a decoder rebuilds the complete oc_state_t from those frames, the base state and the
 * bricks the viewer already holds, then checks the state (oc_state_validate) and its XXH3-64
 * checksum against EPOCH_END: a wrong base, a wrong delta base or a lost frame cannot go unnoticed.
 * A lean decoder (OCP_CAP_DIGEST) does the same with a 64-bit digest per brick instead of its
 * codes, and the digest checksum (oc_state_digest_checksum).
 *
 * Records: an op stream (KEEP n / SKIP n base records, ADD n literal 32-byte records), cut into
 * chunks of at most OCP_CHUNK_RAW_MAX bytes that never split an op, each chunk one zstd frame.
 * Bricks: batches of at most OCP_BATCH_MAX bricks, one zstd frame each (optionally with a trained
 * dictionary). Each channel's 512 codes are sent either whole or — when the viewer holds the
 * node's previous brick with the same code range on that channel — as differences from it (a
 * delta), as little-endian u16 values. */
#ifndef OC_PROTO_EPOCH_H
#define OC_PROTO_EPOCH_H

#include <stddef.h>
#include <stdint.h>

#include "oc_bytes.h" /* oc_buf_t */
#include "oc_state.h" /* oc_state_t */
#include "ocp_wire.h" /* ocp_epoch_begin_t, ocp_epoch_end_t */

#define OCP_CHUNK_RAW_MAX (1u << 20) /**< decompressed bytes of one RECORDS chunk or BRICKS batch */
#define OCP_BATCH_MAX 256            /**< bricks per BRICKS batch */
#define OCP_DICT_MAX (256u << 10)    /**< bytes of a dictionary */
#define OCP_LEVEL_DEFAULT 3          /**< zstd level */

#define OCP_OP_KEEP 0
#define OCP_OP_SKIP 1
#define OCP_OP_ADD 2

#define OCP_BRICK_DELTA_SIGMA 0x1u
#define OCP_BRICK_DELTA_TAU 0x2u

/*-*** Dictionaries ***/

/*! ocp_dict_train() : a zstd dictionary of at most `cap` bytes (≤ OCP_DICT_MAX) trained on the
 *  batch form of `n` bricks (as whole bricks), for DICT messages. @return 0,
 *  OC_EINVAL (too few samples: fewer than 64) or OC_ENOMEM; *out owns the bytes. */
int ocp_dict_train(const oc_brick_codes_t *const *bricks, size_t n, size_t cap, oc_buf_t *out);
/*! ocp_put_dict() : a DICT frame (u32 id ≠ 0, then the dictionary bytes). */
void ocp_put_dict(oc_buf_t *b, uint8_t version, uint32_t id, const void *dict, size_t n);

/*-*** Encoder (server) ***/

typedef struct ocp_epoch_enc_s ocp_epoch_enc_t;

typedef struct {
  int level;           /**< zstd level; 0 → OCP_LEVEL_DEFAULT */
  int deltas;          /**< send refreshed bricks as deltas when allowed (viewer has OCP_CAP_DELTA) */
  int digest;          /**< EPOCH_END carries the digest checksum (oc_state_digest; viewer has
                            OCP_CAP_DIGEST); excludes deltas (OC_EINVAL) */
  uint32_t dict_id;    /**< 0: no dictionary */
  const void *dict;    /**< the dictionary bytes sent under dict_id (copied by ocp_epoch_enc_create) */
  size_t dict_len;
  uint32_t batch_max;  /**< bricks per batch, 1..OCP_BATCH_MAX; 0 → OCP_BATCH_MAX */
} ocp_enc_desc_t;

typedef struct {
  uint64_t frames, wire_bytes, raw_bytes; /**< of the current epoch so far */
  uint32_t bricks, delta_channels, full_channels;
  uint32_t records_added, records_kept;
} ocp_enc_stats_t;

int ocp_epoch_enc_create(ocp_epoch_enc_t **out, const ocp_enc_desc_t *desc);
void ocp_epoch_enc_free(ocp_epoch_enc_t *e);
/*! ocp_epoch_enc_begin() : starts an epoch. `state` is the new state, `base` the newest state the
 *  viewer holds (NULL: none, all records are added, no brick is a delta), `lacking` the ascending
 *  ids of the state's bricks the viewer does not hold (all of them are sent). Everything must stay
 *  unchanged until the epoch's last frame. @return 0, OC_EINVAL (an id of `lacking` is not a brick
 *  of `state`) or OC_ENOMEM. */
int ocp_epoch_enc_begin(ocp_epoch_enc_t *e, const oc_state_t *state, const oc_state_t *base, const uint32_t *lacking,
                        uint32_t nlacking);
/*! ocp_epoch_enc_next() : appends the next whole frame to out. @return 1 (a frame appended), 0
 *  (the epoch is done: EPOCH_END was the last frame), or OC_ENOMEM / OC_EIO (zstd failed). */
int ocp_epoch_enc_next(ocp_epoch_enc_t *e, uint8_t version, oc_buf_t *out);
/*! ocp_epoch_enc_checksum() : the checksum EPOCH_END carries for the epoch begun last (the digest
 *  checksum when desc.digest), computed once by ocp_epoch_enc_begin(); what the viewer's ACK must
 *  echo. 0 before any epoch. */
uint64_t ocp_epoch_enc_checksum(const ocp_epoch_enc_t *e);
void ocp_epoch_enc_stats(const ocp_epoch_enc_t *e, ocp_enc_stats_t *out);
/*! ocp_epoch_enc_memory() : bytes the encoder holds (zstd context and dictionary, its buffers), so
 *  a server can account for what each session costs beyond the states it holds. */
size_t ocp_epoch_enc_memory(const ocp_epoch_enc_t *e);

/*-*** Decoder (viewer) ***/

typedef struct ocp_epoch_dec_s ocp_epoch_dec_t;

/*! Where the decoder finds bricks the viewer already holds (the base of a delta, and unchanged
 *  bricks): @return the codes of brick `id`, or NULL when the viewer does not hold it. */
typedef const oc_brick_codes_t *(*ocp_brick_lookup_fn)(void *ctx, uint32_t id);
/*! The same for a lean decoder: @return 1 with the digest (oc_brick_digest) of held brick `id` in
 *  *digest, or 0 when the viewer does not hold it. */
typedef int (*ocp_digest_lookup_fn)(void *ctx, uint32_t id, uint64_t *digest);

int ocp_epoch_dec_create(ocp_epoch_dec_t **out);
void ocp_epoch_dec_free(ocp_epoch_dec_t *d);
/*! ocp_epoch_dec_dict() : installs the dictionary of a DICT frame payload (replaces any previous).
 *  @return 0, OC_ECORRUPT (id 0, empty, too big, not a zstd dictionary) or OC_ENOMEM. */
int ocp_epoch_dec_dict(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len);
/*! ocp_epoch_dec_begin() : starts an epoch from its EPOCH_BEGIN. `base` must be the viewer's state
 *  of epoch m->base_epoch (NULL iff m->base_epoch == OCP_NO_BASE); `lookup` finds held bricks.
 *  base and the held bricks must stay unchanged until ocp_epoch_dec_end(). @return 0 or OC_EINVAL
 *  (base missing or not of that epoch). */
int ocp_epoch_dec_begin(ocp_epoch_dec_t *d, const ocp_epoch_begin_t *m, const oc_state_t *base, ocp_brick_lookup_fn lookup,
                        void *ctx, char *why, size_t why_len);
/*! ocp_epoch_dec_records() / ocp_epoch_dec_bricks() : one RECORDS / BRICKS payload. @return 0 or
 *  OC_ECORRUPT (bad zstd frame, op past the base, more records or bricks than announced, a brick
 *  that no brick record names, unknown dictionary, missing delta base) with a reason. */
int ocp_epoch_dec_records(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len);
int ocp_epoch_dec_bricks(ocp_epoch_dec_t *d, const uint8_t *payload, size_t n, char *why, size_t why_len);
/*! ocp_epoch_dec_end() : completes the epoch: every record and announced brick arrived, the other
 *  bricks are copied from the held ones, the state validates and its checksum equals m's.
 *  @return 0 with the state moved into *out (initialised; previous content freed), or
 *  OC_ECORRUPT / OC_ECHECKSUM with a reason. The decoder is ready for the next epoch either way. */
int ocp_epoch_dec_end(ocp_epoch_dec_t *d, const ocp_epoch_end_t *m, oc_state_t *out, char *why, size_t why_len);
/*! ocp_epoch_dec_begin_lean() / ocp_epoch_dec_end_lean() : the same epoch decoded by a lean
 *  viewer (OCP_CAP_DIGEST), which keeps no codes: each brick is checked (zero channels) and reduced
 *  to its digest as it arrives, the bricks not sent are found as digests by `lookup`, the records
 *  are validated with the ids (oc_state_validate_lean) and the digest checksum compared with m's.
 *  A delta brick is malformed here. `base` needs only its records. End moves the records into *out
 *  (brick_count 0, bricks NULL) and the ascending (id, digest) pairs into *digests (previous
 *  content of both freed). An epoch begun one way must end the same way (else OC_EINVAL). Records
 *  and bricks go through ocp_epoch_dec_records() / ocp_epoch_dec_bricks() as for a full epoch. */
int ocp_epoch_dec_begin_lean(ocp_epoch_dec_t *d, const ocp_epoch_begin_t *m, const oc_state_t *base, ocp_digest_lookup_fn lookup,
                             void *ctx, char *why, size_t why_len);
int ocp_epoch_dec_end_lean(ocp_epoch_dec_t *d, const ocp_epoch_end_t *m, oc_state_t *out, oc_brick_digests_t *digests, char *why,
                           size_t why_len);
/*! ocp_epoch_dec_active() : 1 between begin and end. */
int ocp_epoch_dec_active(const ocp_epoch_dec_t *d);

/*-*** Plain zstd frames: the baseline `overcast-bench wire` measures the epoch coding against ***/
/* zstd's own calls under proto's names, so that no file outside proto/ includes <zstd.h>; results as
 * zstd's (ocp_zstd_is_error() tells an error code from a size). */
typedef struct ZSTD_CCtx_s ocp_zcctx_t;
typedef struct ZSTD_DCtx_s ocp_zdctx_t;
ocp_zcctx_t *ocp_zcctx_new(void);
ocp_zdctx_t *ocp_zdctx_new(void);
void ocp_zcctx_free(ocp_zcctx_t *c);
void ocp_zdctx_free(ocp_zdctx_t *d);
size_t ocp_zstd_bound(size_t n);
unsigned ocp_zstd_is_error(size_t code);
size_t ocp_zstd_compress(ocp_zcctx_t *c, void *dst, size_t cap, const void *src, size_t n, int level);
size_t ocp_zstd_decompress(ocp_zdctx_t *d, void *dst, size_t cap, const void *src, size_t n);
unsigned long long ocp_zstd_content_size(const void *src, size_t n);

#endif /* OC_PROTO_EPOCH_H */

/* oc_state.h — the state: one definition for planner, wire, client, CPU reference, state file and
 * stress checker (design.md, Conventions: state, budget, epochs).
 *
 * A state is the epoch index, world time, sun direction and the node records of a complete linear
 * octree: its leaves, in ascending key order, partition the root cube exactly. Brick payloads are
 * held once per brick id, ascending; a brick id is referenced by exactly one record of a state, and
 * across states the same id always means the same content (ids are assigned by the server). The
 * serialisation is byte-exact and little-endian (docs/protocol.md, "State"); the checksum is
 * XXH3-64 of that serialisation.
 *
 * A lean state (a viewer that verifies but keeps no codes, OCP_CAP_DIGEST) holds the records and,
 * per brick, only its id and a 64-bit digest of its codes (oc_brick_digests_t). Its digest
 * checksum hashes the same byte stream with each 2052-byte brick replaced by 12 bytes (u32 id, u64
 * digest), so it can be computed both from a full state and from records + digests alone. */
#ifndef OC_COMMON_STATE_H
#define OC_COMMON_STATE_H

#include <stddef.h>
#include <stdint.h>

#include "oc_brick.h" /* oc_range_t, oc_brick_codes_t, oc_node_kind_t */
#include "oc_key.h"   /* oc_key_t */
#include "oc_math.h"  /* oc_dvec3 */

#define OC_STATE_MAGIC "OCST"
#define OC_STATE_VERSION 1
#define OC_STATE_HEADER_BYTES 64
#define OC_STATE_RECORD_BYTES 32
#define OC_STATE_BRICK_BYTES (4 + OC_BRICK_CODE_BYTES)
/*! Limits applied to untrusted input (files, wire). */
#define OC_STATE_MAX_NODES (1u << 24)
#define OC_STATE_MAX_BRICKS (1u << 22)

typedef struct {
  oc_key_t key;
  uint8_t kind;                  /**< oc_node_kind_t */
  uint32_t brick_id;             /**< OC_NODE_BRICK only; 0 otherwise */
  oc_range_t range[OC_CHANNELS]; /**< per channel, see oc_brick_encode() */
} oc_node_t;

typedef struct {
  uint32_t id;
  oc_brick_codes_t codes;
} oc_brick_t;

typedef struct {
  uint64_t epoch;      /**< epoch index */
  double time;         /**< world time, s */
  oc_dvec3 sun_dir;    /**< unit vector toward the sun, planet frame */
  uint32_t node_count; /**< leaves, ascending key */
  uint32_t node_cap;
  oc_node_t *nodes;
  uint32_t brick_count; /**< ascending id */
  uint32_t brick_cap;
  oc_brick_t *bricks;
} oc_state_t;

/*! oc_state_init() : an empty state (no nodes). oc_state_free() releases arrays; NULL is fine. */
void oc_state_init(oc_state_t *s);
void oc_state_free(oc_state_t *s);
/*! oc_state_clear() : empty again, keeping its arrays (a state rebuilt every epoch reuses its memory
 *  instead of growing and faulting in a new one). */
void oc_state_clear(oc_state_t *s);
/*! oc_state_add_node() / oc_state_add_brick() : append (any order); @return 0 or OC_ENOMEM. */
int oc_state_add_node(oc_state_t *s, const oc_node_t *n);
int oc_state_add_brick(oc_state_t *s, uint32_t id, const oc_brick_codes_t *codes);
/*! oc_state_canonicalize() : sorts records by key and bricks by id. */
void oc_state_canonicalize(oc_state_t *s);
/*! oc_state_copy() : deep copy into an initialised (possibly non-empty) dst. */
int oc_state_copy(oc_state_t *dst, const oc_state_t *src);
/*! oc_state_validate() : checks everything a decoder must: canonical order, no duplicates, leaves
 *  forming an exact partition of the root cube, kinds and ranges valid (finite, non-negative,
 *  consistent with the kind), every brick id referenced exactly once and present, finite time,
 *  unit sun direction. @return 0 or OC_ECORRUPT with a one-line reason in why (may be NULL). */
int oc_state_validate(const oc_state_t *s, char *why, size_t why_len);

/*! oc_state_find_node() : index of the record with this key, or -1. O(log n). */
int64_t oc_state_find_node(const oc_state_t *s, oc_key_t key);
/*! oc_state_find_leaf() : index of the leaf containing the level-21 cell `key21` (any key works:
 *  the leaf that is it or its ancestor), or -1 when none (the key is inside a finer subtree). */
int64_t oc_state_find_leaf(const oc_state_t *s, oc_key_t key21);
/*! oc_state_find_brick() : the brick with this id, or NULL. O(log n). */
const oc_brick_t *oc_state_find_brick(const oc_state_t *s, uint32_t id);
/*! oc_ids_find() : index of `id` among n ascending u32 ids, the first at `first` and each next one
 *  `stride` bytes on (the id member of an array of structs, or a plain list), or -1. O(log n). */
int64_t oc_ids_find(const void *first, size_t stride, uint32_t n, uint32_t id);
/*! oc_states_find_codes() : the codes of brick `id` in the first of the n states that holds it (a
 *  viewer's held states, newest first), or NULL. */
const oc_brick_codes_t *oc_states_find_codes(const oc_state_t *states, int n, uint32_t id);

/*! oc_state_serialized_size() : exact bytes of the serialisation (header, records, bricks, checksum). */
size_t oc_state_serialized_size(const oc_state_t *s);
/*! oc_state_serialize() : @return bytes written, or OC_ENOBUFS. */
int64_t oc_state_serialize(const oc_state_t *s, uint8_t *dst, size_t cap);
/*! oc_state_deserialize() : parses and validates untrusted bytes into an initialised state.
 *  @return 0, or OC_ETRUNC / OC_ECORRUPT / OC_EVERSION / OC_ECHECKSUM / OC_ETOOBIG / OC_ENOMEM,
 *  with a one-line reason in why (may be NULL). On error, out is left empty. */
int oc_state_deserialize(oc_state_t *out, const uint8_t *src, size_t len, char *why, size_t why_len);
/*! oc_state_pack_record() / oc_state_unpack_record() : one 32-byte node record of the
 *  serialisation (docs/protocol.md), shared by the state file and the wire. Unpacking checks only
 *  the reserved bytes (OC_ECORRUPT when not zero); the rest is oc_state_validate()'s. */
void oc_state_pack_record(const oc_node_t *n, uint8_t r[OC_STATE_RECORD_BYTES]);
int oc_state_unpack_record(const uint8_t r[OC_STATE_RECORD_BYTES], oc_node_t *n);
/*! oc_state_checksum() : XXH3-64 (seed 0) of the serialisation up to, not including, its checksum. */
uint64_t oc_state_checksum(const oc_state_t *s);
/*! oc_state_save() / oc_state_load() : one serialised state per file. Errors name the file. */
int oc_state_save(const oc_state_t *s, const char *path, char *why, size_t why_len);
int oc_state_load(oc_state_t *out, const char *path, char *why, size_t why_len);

/*! oc_resident_bytes() : the budget measure of the Conventions: distinct brick ids referenced by
 *  the n kept states × slot_bytes + their node records × record_bytes. */
uint64_t oc_resident_bytes(const oc_state_t *const *states, int n, uint32_t slot_bytes, uint32_t record_bytes);

/*-*** Lean states: brick digests instead of codes (docs/protocol.md, "Digest checksum") ***/

/*! The bricks of a lean state: `count` ascending ids, digests[k] = oc_brick_digest() of brick ids[k].
 *  12 bytes a brick instead of 2052. */
typedef struct {
  uint32_t count;
  uint32_t *ids;
  uint64_t *digests;
} oc_brick_digests_t;

/*! oc_brick_digests_free() : releases both arrays and zeroes b; NULL is fine. */
void oc_brick_digests_free(oc_brick_digests_t *b);
/*! oc_brick_digests_of() : the digests of s's bricks (s canonical), replacing out's content.
 *  @return 0 or OC_ENOMEM (out left empty). */
int oc_brick_digests_of(oc_brick_digests_t *out, const oc_state_t *s);
/*! oc_brick_digests_find() : index of brick `id` in b, or -1. O(log n). */
int64_t oc_brick_digests_find(const oc_brick_digests_t *b, uint32_t id);
/*! oc_brick_digests_lookup() : the digest of brick `id` from the first of the n lists that holds
 *  it (a lean viewer's held states, newest first). @return 1 with *digest set, or 0. */
int oc_brick_digests_lookup(const oc_brick_digests_t *lists, int n, uint32_t id, uint64_t *digest);
/*! oc_brick_digest() : XXH3-64 (seed 0) of the brick's 2048 code bytes as serialised (σt then τ,
 *  little-endian u16, x fastest). */
uint64_t oc_brick_digest(const oc_brick_codes_t *c);
/*! oc_state_digest_checksum() : the digest checksum from s's header fields and records and the
 *  bricks given as digests in b (s's own bricks and brick_count are ignored; the header's brick
 *  count is b->count). What a lean viewer computes. */
uint64_t oc_state_digest_checksum(const oc_state_t *s, const oc_brick_digests_t *b);
/*! oc_state_digest() : the same value for a full state, hashing each brick's codes on the fly
 *  (no allocation). What the server sends a lean viewer. */
uint64_t oc_state_digest(const oc_state_t *s);
/*! oc_state_validate_lean() : oc_state_validate() for s's records with the bricks given by the
 *  ascending ids of b instead of s's payloads (s->bricks is ignored). Everything but the zero-code
 *  check of zero channels, which needs the codes (the lean decoder does it as each brick arrives). */
int oc_state_validate_lean(const oc_state_t *s, const oc_brick_digests_t *b, char *why, size_t why_len);
/*! oc_resident_bytes_lean() : oc_resident_bytes() for lean states: records from states[i], brick
 *  ids from bricks[i] (states' own bricks are ignored). */
uint64_t oc_resident_bytes_lean(const oc_state_t *const *states, const oc_brick_digests_t *const *bricks, int n,
                                uint32_t slot_bytes, uint32_t record_bytes);

#endif /* OC_COMMON_STATE_H */

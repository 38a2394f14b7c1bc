/* brick_value.h — the identity and the stored form of a brick shared between front-ends.
 *
 * Production is a pure function of its content, so a brick made by one front-end is valid for all
 * of them if, and only if, its key names everything the bytes depend on: the scene's content (its
 * VDB files by their own hashes), the weather history, the sun direction's bits, the level's
 * time-step stamp, the node and the channel. Per-process counters (generations, versions) never
 * enter it: two processes that agree on the content compute the same key.
 *
 * A value is packed explicitly, little-endian, as every Overcast byte format (docs/scale-out.md):
 *
 *   offset  size  field
 *   0       8     magic "OCBRICK1"
 *   8       16    the key (XXH3-128 of the identity, low word first)
 *   24      4     content length n (≤ OCS_BVAL_MAX_CONTENT)
 *   28      n     the content, as the cache holds it
 *   28+n    8     XXH3-64 of bytes 0 … 27+n
 *
 * A value that fails any check (size, magic, key, length, checksum) is discarded: the caller
 * produces the brick again. */
#ifndef OC_SERVER_BRICK_VALUE_H
#define OC_SERVER_BRICK_VALUE_H

#include <stddef.h>
#include <stdint.h>

#define OCS_BVAL_HEAD 28u                 /* magic, key, length */
#define OCS_BVAL_TAIL 8u                  /* the checksum */
#define OCS_BVAL_MAX_CONTENT (1u << 24)   /* 16 MiB: a τ volume is the largest content */
#define OCS_BKEY_TEXT 38u                 /* "oc:b:" + 32 hex digits + NUL */

/*! What a shared brick's bytes depend on; each field is content, never a counter. */
typedef struct {
  uint64_t scene;    /* hash of the scene's content, VDB files by their own hashes */
  uint64_t weather;  /* hash of the weather history */
  uint64_t sun;      /* the sun direction's bits, hashed */
  uint64_t stamp;    /* the level's time-step stamp */
  uint64_t node;     /* oc_key_t, or a τ group's key */
  uint32_t channel;  /* what is stored: brick codes, σt samples, a τ volume */
} ocs_bkey_in_t;

typedef struct {
  uint64_t lo, hi;
} ocs_bkey_t;

/*! ocs_bkey_make() : the key of an identity: XXH3-128 of its fields packed little-endian. */
ocs_bkey_t ocs_bkey_make(const ocs_bkey_in_t *in);
/*! ocs_bkey_text() : the store's name of a key, "oc:b:" and 32 lowercase hex digits (hi then lo).
 *  prefix: "oc:b:" for values, "oc:l:" for leases (any 5 characters). */
void ocs_bkey_text(const ocs_bkey_t *k, const char prefix[6], char out[OCS_BKEY_TEXT]);

/*! ocs_bval_size() : bytes of the packed value of n content bytes. */
static inline size_t ocs_bval_size(size_t n) { return OCS_BVAL_HEAD + n + OCS_BVAL_TAIL; }
/*! ocs_bval_pack() : writes the value of (key, content[0 … n)) into out (ocs_bval_size(n) bytes).
 *  @return the bytes written, or 0 when n is over OCS_BVAL_MAX_CONTENT or cap is short. */
size_t ocs_bval_pack(const ocs_bkey_t *key, const void *content, size_t n, uint8_t *out, size_t cap);
/*! ocs_bval_unpack() : checks a stored value against the key it was fetched for.
 *  @return 0 with *content and *n pointing into v; or OC_ETRUNC (shorter than its header or its
 *  length says), OC_ECORRUPT (magic, or trailing bytes), OC_ETOOBIG (length over the limit),
 *  OC_EINVAL (a different key: a hash collision in the name, or a value stored under the wrong
 *  name), OC_ECHECKSUM. */
int ocs_bval_unpack(const ocs_bkey_t *key, const uint8_t *v, size_t len, const uint8_t **content, size_t *n);

#endif /* OC_SERVER_BRICK_VALUE_H */

/* brick_value.c — keys and packed values of shared bricks (brick_value.h). */
#include "brick_value.h"

#include <string.h>
#include <xxhash.h>

#include "oc_bytes.h"
#include "oc_err.h"

static const uint8_t ocs__bval_magic[8] = {'O', 'C', 'B', 'R', 'I', 'C', 'K', '1'};

ocs_bkey_t ocs_bkey_make(const ocs_bkey_in_t *in) {
  uint8_t b[44];
  oc_put_u64(b, in->scene);
  oc_put_u64(b + 8, in->weather);
  oc_put_u64(b + 16, in->sun);
  oc_put_u64(b + 24, in->stamp);
  oc_put_u64(b + 32, in->node);
  oc_put_u32(b + 40, in->channel);
  XXH128_hash_t h = XXH3_128bits(b, sizeof b);
  return (ocs_bkey_t){h.low64, h.high64};
}

void ocs_bkey_text(const ocs_bkey_t *k, const char prefix[6], char out[OCS_BKEY_TEXT]) {
  static const char hex[] = "0123456789abcdef";
  memcpy(out, prefix, 5);
  for (int i = 0; i < 16; i++) {
    out[5 + i] = hex[(k->hi >> (60 - 4 * i)) & 15];
    out[21 + i] = hex[(k->lo >> (60 - 4 * i)) & 15];
  }
  out[37] = '\0';
}

size_t ocs_bval_pack(const ocs_bkey_t *key, const void *content, size_t n, uint8_t *out, size_t cap) {
  if (n > OCS_BVAL_MAX_CONTENT || cap < ocs_bval_size(n)) return 0;
  memcpy(out, ocs__bval_magic, 8);
  oc_put_u64(out + 8, key->lo);
  oc_put_u64(out + 16, key->hi);
  oc_put_u32(out + 24, (uint32_t)n);
  if (n) memcpy(out + OCS_BVAL_HEAD, content, n);
  oc_put_u64(out + OCS_BVAL_HEAD + n, XXH3_64bits(out, OCS_BVAL_HEAD + n));
  return ocs_bval_size(n);
}

int ocs_bval_unpack(const ocs_bkey_t *key, const uint8_t *v, size_t len, const uint8_t **content, size_t *n) {
  *content = NULL;
  *n = 0;
  if (len < OCS_BVAL_HEAD + OCS_BVAL_TAIL) return OC_ETRUNC;
  if (memcmp(v, ocs__bval_magic, 8) != 0) return OC_ECORRUPT;
  uint32_t m = oc_get_u32(v + 24);
  if (m > OCS_BVAL_MAX_CONTENT) return OC_ETOOBIG;
  if (len < ocs_bval_size(m)) return OC_ETRUNC;
  if (len > ocs_bval_size(m)) return OC_ECORRUPT;
  if (oc_get_u64(v + OCS_BVAL_HEAD + m) != XXH3_64bits(v, OCS_BVAL_HEAD + m)) return OC_ECHECKSUM;
  /* checked after the sum: a damaged key reads as damage, a whole other key as a wrong name */
  if (oc_get_u64(v + 8) != key->lo || oc_get_u64(v + 16) != key->hi) return OC_EINVAL;
  *content = v + OCS_BVAL_HEAD;
  *n = m;
  return 0;
}

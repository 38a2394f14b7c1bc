/* fuzz_state.c — libFuzzer target for oc_state_deserialize() (untrusted state files and wire).
 *
 * Each input is tried twice: as given (identity, limits, length, checksum paths) and re-sealed
 * with a correct XXH3-64 trailer, so mutations reach the record parser and oc_state_validate()
 * instead of dying at the checksum. Whatever is accepted must serialise back to the same bytes
 * (the format has one byte form per state) with the same checksum. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <xxhash.h> /* XXH3_64bits */

#include "oc_state.h"

static void check_accepted(const oc_state_t *s, const uint8_t *data, size_t size) {
  if (oc_state_serialized_size(s) != size) abort();
  uint8_t *buf = malloc(size);
  if (!buf) return;
  if (oc_state_serialize(s, buf, size) != (int64_t)size || memcmp(buf, data, size) != 0) abort();
  uint64_t h = 0;
  for (int i = 7; i >= 0; i--) h = (h << 8) | data[size - 8 + (size_t)i];
  if (oc_state_checksum(s) != h) abort();
  if (oc_state_validate(s, NULL, 0) != 0) abort();
  /* look-ups on whatever passed validation */
  for (uint32_t i = 0; i < s->node_count; i++) {
    if (oc_state_find_node(s, s->nodes[i].key) != (int64_t)i) abort();
    if (oc_state_find_leaf(s, s->nodes[i].key) != (int64_t)i) abort();
  }
  free(buf);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  oc_state_t s;
  char why[256];
  oc_state_init(&s);
  if (oc_state_deserialize(&s, data, size, why, sizeof why) == 0) check_accepted(&s, data, size);
  oc_state_free(&s);
  if (size < 8) return 0;
  uint8_t *copy = malloc(size); /* exact size, so ASan flags any over-read */
  if (!copy) return 0;
  memcpy(copy, data, size);
  uint64_t h = XXH3_64bits(copy, size - 8);
  for (int i = 0; i < 8; i++) copy[size - 8 + (size_t)i] = (uint8_t)(h >> (8 * i));
  if (oc_state_deserialize(&s, copy, size, why, sizeof why) == 0) check_accepted(&s, copy, size);
  oc_state_free(&s);
  free(copy);
  return 0;
}

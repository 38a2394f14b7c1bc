/* oc_backoff.c — reconnect delays (oc_backoff.h). */
#include "oc_backoff.h"

static uint64_t splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

void oc_backoff_init(oc_backoff_t *b, uint32_t server_ms, uint64_t seed) {
  b->base_ms = server_ms > OC_BACKOFF_MIN_MS ? server_ms : OC_BACKOFF_MIN_MS;
  b->cap_ms = OC_BACKOFF_CAP_MS;
  if (b->base_ms > b->cap_ms) b->base_ms = b->cap_ms;
  b->attempt = 0;
  b->rng = seed;
}

uint32_t oc_backoff_next(oc_backoff_t *b) {
  uint32_t n = b->attempt++;
  if (n == 0) return b->base_ms;
  uint64_t ceil = b->base_ms;
  for (uint32_t i = 0; i < n && ceil < b->cap_ms; i++) ceil *= 2; /* no shift past 64 bits */
  if (ceil > b->cap_ms) ceil = b->cap_ms;
  uint64_t span = ceil - b->base_ms + 1;
  return b->base_ms + (uint32_t)(splitmix64(&b->rng) % span);
}

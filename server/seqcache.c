/* seqcache.c — the (key, step) seqlock cache of seqcache.h. */
#include "seqcache.h"

#include <stdatomic.h>
#include <stdlib.h>

/* A slot is 3 + words atomics: seq (odd while a writer fills it), key, step, then the words. */
struct ocs_seqcache_s {
  size_t slots;
  int words;
  _Atomic uint64_t *w;
};

static _Atomic uint64_t *ocs__slot_of(const ocs_seqcache_t *c, uint64_t key, uint64_t step) {
  uint64_t h = key * 0x9e3779b97f4a7c15ull ^ step * 0xc2b2ae3d27d4eb4full;
  h ^= h >> 29;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 32;
  return &c->w[(size_t)(h & (c->slots - 1)) * (size_t)(3 + c->words)];
}

ocs_seqcache_t *ocs_seqcache_new(size_t slots, int words) {
  if (!slots || (slots & (slots - 1)) || words < 1 || words > 64) return NULL;
  ocs_seqcache_t *c = malloc(sizeof *c);
  if (!c) return NULL;
  c->slots = slots, c->words = words;
  c->w = calloc(slots * (size_t)(3 + words), sizeof *c->w); /* zero bits: every atomic 0, no slot valid */
  if (!c->w) {
    free(c);
    return NULL;
  }
  return c;
}

void ocs_seqcache_free(ocs_seqcache_t *c) {
  if (!c) return;
  free(c->w);
  free(c);
}

int ocs_seqcache_get(const ocs_seqcache_t *c, uint64_t key, uint64_t step, uint64_t *out) {
  if (!key) return 0;
  _Atomic uint64_t *e = ocs__slot_of(c, key, step);
  uint64_t s1 = atomic_load_explicit(&e[0], memory_order_acquire);
  if (s1 & 1u) return 0;
  if (atomic_load_explicit(&e[1], memory_order_relaxed) != key || atomic_load_explicit(&e[2], memory_order_relaxed) != step)
    return 0;
  for (int i = 0; i < c->words; i++) out[i] = atomic_load_explicit(&e[3 + i], memory_order_relaxed);
  atomic_thread_fence(memory_order_acquire);
  return atomic_load_explicit(&e[0], memory_order_relaxed) == s1;
}

void ocs_seqcache_put(ocs_seqcache_t *c, uint64_t key, uint64_t step, const uint64_t *words) {
  if (!key) return;
  _Atomic uint64_t *e = ocs__slot_of(c, key, step);
  uint64_t s = atomic_load_explicit(&e[0], memory_order_relaxed);
  if ((s & 1u) || !atomic_compare_exchange_strong_explicit(&e[0], &s, s + 1, memory_order_relaxed, memory_order_relaxed))
    return; /* another writer holds the slot: skip, the next miss inserts */
  atomic_thread_fence(memory_order_release);
  atomic_store_explicit(&e[1], key, memory_order_relaxed);
  atomic_store_explicit(&e[2], step, memory_order_relaxed);
  for (int i = 0; i < c->words; i++) atomic_store_explicit(&e[3 + i], words[i], memory_order_relaxed);
  atomic_store_explicit(&e[0], s + 2, memory_order_release);
}

void ocs_seqcache_clear(ocs_seqcache_t *c) {
  if (!c) return;
  size_t stride = (size_t)(3 + c->words);
  for (size_t j = 0; j < c->slots; j++)
    for (size_t i = 1; i < stride; i++) atomic_store_explicit(&c->w[j * stride + i], 0, memory_order_relaxed);
  atomic_thread_fence(memory_order_seq_cst);
}

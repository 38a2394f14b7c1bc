/* brick_cache.c — the server-wide brick cache (brick_cache.h).
 *
 * One mutex guards everything: the hash table, the LRU list and the counters. Every operation is
 * O(1) expected and holds the lock only for pointer work and the free() of evicted payloads
 * (production happens outside it), so one lock is no bottleneck next to the work it saves.
 *
 * - Table: separate chaining, 2^k buckets indexed by XXH3-64 of the key; doubles when the entries
 *   outnumber the buckets, up to the bucket count that cap_bytes / OCS_CACHE_ENTRY_OVERHEAD can
 *   fill (more entries can only be pinned ones: chains absorb them, the table does not grow).
 * - LRU: an intrusive doubly linked list of the ready entries with zero pins, oldest at the head.
 *   Pinned entries are not in it, so eviction pops the head without skipping anything; a release
 *   to zero pins appends at the tail (most recently used).
 * - Waiting: a waiter pins the entry it waits for (so it cannot be freed under it) and sleeps on one
 *   of OCS__CACHE_CONDS condition variables chosen by the key's hash; publish and abandon
 *   broadcast on that one, so unrelated keys rarely wake each other. */
#include "brick_cache.h"

#include <assert.h>
#include <pthread.h> /* pthread_mutex_t, pthread_cond_t */
#include <stdlib.h>
#include <string.h>

#include <xxhash.h> /* XXH3_64bits */

#include "oc_err.h"

/*! Condition variables a cache stripes its waiters over (a power of two). */
#ifndef OCS__CACHE_CONDS
#define OCS__CACHE_CONDS 64
#endif
/*! First and largest bucket counts: the cap-derived limit is clamped to this. */
#define OCS__CACHE_MIN_BUCKETS 16u
#define OCS__CACHE_MAX_BUCKETS (1u << 28)

enum { OCS__PRODUCING = 0, OCS__READY = 1 };

struct ocs_cache_entry_s {
  ocs_cache_key_t key;
  uint64_t hash;
  ocs_cache_entry_t *chain;            /* next in bucket */
  ocs_cache_entry_t *prev, *next;      /* LRU links, only while ready with zero pins */
  void *data;
  size_t bytes;
  uint32_t pins;                       /* producer or holders, plus waiters */
  uint32_t waiters;                    /* acquires sleeping on this entry */
  uint8_t state;                       /* OCS__PRODUCING / OCS__READY */
  uint8_t handoff;                     /* abandoned with waiters: the first one to wake takes it */
};

/* The record, its bucket slot and a typical allocator header (16 bytes) fit the charged overhead. */
_Static_assert(sizeof(struct ocs_cache_entry_s) + sizeof(void *) + 16 <= OCS_CACHE_ENTRY_OVERHEAD,
               "OCS_CACHE_ENTRY_OVERHEAD too small for the entry record");

struct ocs_cache_s {
  pthread_mutex_t mu;
  pthread_cond_t cv[OCS__CACHE_CONDS];
  ocs_cache_entry_t **buckets;
  size_t nbuckets;                     /* power of two */
  size_t max_buckets;                  /* growth limit from cap_bytes */
  ocs_cache_entry_t *lru_head, *lru_tail;
  ocs_cache_stats_t st;                /* bytes, entries, cap_bytes live here too */
};


static uint64_t ocs__hash(const ocs_cache_key_t *k) { return XXH3_64bits(k, sizeof *k); }


static size_t ocs__max_buckets(uint64_t cap) {
  uint64_t want = cap / OCS_CACHE_ENTRY_OVERHEAD;
  size_t n = OCS__CACHE_MIN_BUCKETS;
  while (n < want && n < OCS__CACHE_MAX_BUCKETS) n <<= 1;
  return n;
}


static ocs_cache_entry_t *ocs__find(const ocs_cache_t *c, uint64_t h, const ocs_cache_key_t *k) {
  for (ocs_cache_entry_t *e = c->buckets[h & (c->nbuckets - 1)]; e; e = e->chain)
    if (e->hash == h && memcmp(&e->key, k, sizeof *k) == 0) return e;
  return NULL;
}


/* Doubles the bucket array if the load exceeds 1 and the cap allows it. A failed allocation is not
 * an error: chains just get longer. */
static void ocs__maybe_grow(ocs_cache_t *c) {
  if (c->st.entries <= c->nbuckets || c->nbuckets >= c->max_buckets) return;
  size_t n = c->nbuckets * 2;
  ocs_cache_entry_t **b = calloc(n, sizeof *b);
  if (!b) return;
  for (size_t i = 0; i < c->nbuckets; i++) {
    ocs_cache_entry_t *e = c->buckets[i];
    while (e) {
      ocs_cache_entry_t *nx = e->chain;
      size_t j = e->hash & (n - 1);
      e->chain = b[j];
      b[j] = e;
      e = nx;
    }
  }
  free(c->buckets);
  c->buckets = b;
  c->nbuckets = n;
}


static void ocs__unchain(ocs_cache_t *c, ocs_cache_entry_t *e) {
  ocs_cache_entry_t **p = &c->buckets[e->hash & (c->nbuckets - 1)];
  while (*p != e) p = &(*p)->chain;
  *p = e->chain;
}


static void ocs__lru_unlink(ocs_cache_t *c, ocs_cache_entry_t *e) {
  if (e->prev) e->prev->next = e->next;
  else c->lru_head = e->next;
  if (e->next) e->next->prev = e->prev;
  else c->lru_tail = e->prev;
  e->prev = e->next = NULL;
}


static void ocs__lru_append(ocs_cache_t *c, ocs_cache_entry_t *e) {
  e->next = NULL;
  e->prev = c->lru_tail;
  if (c->lru_tail) c->lru_tail->next = e;
  else c->lru_head = e;
  c->lru_tail = e;
}


/* Removes an entry from table and accounting and frees it (caller holds the lock; no pins). */
static void ocs__drop(ocs_cache_t *c, ocs_cache_entry_t *e) {
  assert(e->pins == 0);
  ocs__unchain(c, e);
  c->st.bytes -= OCS_CACHE_ENTRY_OVERHEAD + (uint64_t)e->bytes;
  c->st.entries--;
  free(e->data);
  free(e);
}


/* Evicts from the LRU head until `more` bytes fit under the cap, so peak_bytes exceeds the cap only
 * through pins. @return 1 when they fit. */
static int ocs__evict(ocs_cache_t *c, uint64_t more) {
  while (c->st.bytes + more > c->st.cap_bytes && c->lru_head) {
    ocs_cache_entry_t *e = c->lru_head;
    ocs__lru_unlink(c, e);
    ocs__drop(c, e);
    c->st.evictions++;
  }
  return c->st.bytes + more <= c->st.cap_bytes;
}


static void ocs__pin(ocs_cache_t *c, ocs_cache_entry_t *e) {
  if (e->pins++ == 0 && e->state == OCS__READY) ocs__lru_unlink(c, e);
}


static void ocs__add_bytes(ocs_cache_t *c, uint64_t n) {
  c->st.bytes += n;
  if (c->st.bytes > c->st.peak_bytes) c->st.peak_bytes = c->st.bytes;
}


int ocs_cache_create(ocs_cache_t **out, uint64_t cap_bytes) {
  OC_RETURN_IF(!out, OC_EINVAL);
  *out = NULL;
  OC_RETURN_IF(cap_bytes == 0, OC_EINVAL);
  ocs_cache_t *c = calloc(1, sizeof *c);
  OC_RETURN_IF(!c, OC_ENOMEM);
  c->nbuckets = OCS__CACHE_MIN_BUCKETS;
  c->buckets = calloc(c->nbuckets, sizeof *c->buckets);
  if (!c->buckets) {
    free(c);
    return OC_ENOMEM;
  }
  c->max_buckets = ocs__max_buckets(cap_bytes);
  c->st.cap_bytes = cap_bytes;
  pthread_mutex_init(&c->mu, NULL);
  for (int i = 0; i < OCS__CACHE_CONDS; i++) pthread_cond_init(&c->cv[i], NULL);
  *out = c;
  return 0;
}


void ocs_cache_free(ocs_cache_t *c) {
  if (!c) return;
  for (size_t i = 0; i < c->nbuckets; i++) {
    ocs_cache_entry_t *e = c->buckets[i];
    while (e) {
      ocs_cache_entry_t *nx = e->chain;
      free(e->data);
      free(e);
      e = nx;
    }
  }
  free(c->buckets);
  for (int i = 0; i < OCS__CACHE_CONDS; i++) pthread_cond_destroy(&c->cv[i]);
  pthread_mutex_destroy(&c->mu);
  free(c);
}


/* Lookup, then one of: hit; new reservation; busy (!wait); sleep until the producer publishes (hit) or abandons
 * with this waiter first to wake (it inherits the reservation and its own pin becomes the
 * producer's). Waiting pins the entry, so it is neither evicted nor freed while we sleep. */
static int ocs__acquire(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e, int wait) {
  OC_RETURN_IF(!e, OC_EINVAL);
  *e = NULL;
  OC_RETURN_IF(!c || !key, OC_EINVAL);
  uint64_t h = ocs__hash(key);
  int r;
  pthread_mutex_lock(&c->mu);
  ocs_cache_entry_t *x = ocs__find(c, h, key);
  if (!x) {
    x = calloc(1, sizeof *x);
    if (!x) {
      pthread_mutex_unlock(&c->mu);
      return OC_ENOMEM;
    }
    x->key = *key;
    x->hash = h;
    x->pins = 1;
    x->state = OCS__PRODUCING;
    size_t b = h & (c->nbuckets - 1);
    x->chain = c->buckets[b];
    c->buckets[b] = x;
    ocs__evict(c, OCS_CACHE_ENTRY_OVERHEAD); /* the reservation's overhead may push older entries out */
    c->st.entries++;
    ocs__add_bytes(c, OCS_CACHE_ENTRY_OVERHEAD);
    c->st.misses++;
    ocs__maybe_grow(c);
    r = OCS_CACHE_MISS;
  } else if (x->state == OCS__READY) {
    ocs__pin(c, x);
    c->st.hits++;
    r = OCS_CACHE_HIT;
  } else if (!wait) {
    pthread_mutex_unlock(&c->mu);
    return OCS_CACHE_BUSY;
  } else {
    pthread_cond_t *cv = &c->cv[h & (OCS__CACHE_CONDS - 1)];
    x->pins++;
    x->waiters++;
    c->st.waits++;
    while (x->state == OCS__PRODUCING && !x->handoff) pthread_cond_wait(cv, &c->mu);
    x->waiters--;
    if (x->state == OCS__READY) {
      c->st.hits++;
      r = OCS_CACHE_HIT;
    } else {
      x->handoff = 0;
      c->st.misses++;
      r = OCS_CACHE_MISS;
    }
  }
  pthread_mutex_unlock(&c->mu);
  *e = x;
  return r;
}


int ocs_cache_acquire(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e) {
  return ocs__acquire(c, key, e, 1);
}

int ocs_cache_try_acquire(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e) {
  return ocs__acquire(c, key, e, 0);
}


int ocs_cache_peek(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e) {
  if (e) *e = NULL;
  if (!c || !key || !e) return 0;
  uint64_t h = ocs__hash(key);
  pthread_mutex_lock(&c->mu);
  ocs_cache_entry_t *x = ocs__find(c, h, key);
  int r = x && x->state == OCS__READY;
  if (r) {
    ocs__pin(c, x);
    *e = x;
  }
  pthread_mutex_unlock(&c->mu);
  return r;
}


void ocs_cache_publish(ocs_cache_t *c, ocs_cache_entry_t *e, void *data, size_t bytes) {
  if (!c || !e) {
    free(data); /* ownership was given: do not leak it on misuse */
    return;
  }
  pthread_mutex_lock(&c->mu);
  assert(e->state == OCS__PRODUCING && !e->handoff && e->pins >= 1);
  e->data = data;
  e->bytes = bytes;
  e->state = OCS__READY;
  if (!ocs__evict(c, bytes)) c->st.over_cap++;
  ocs__add_bytes(c, bytes);
  if (e->waiters) pthread_cond_broadcast(&c->cv[e->hash & (OCS__CACHE_CONDS - 1)]);
  pthread_mutex_unlock(&c->mu);
}


void ocs_cache_abandon(ocs_cache_t *c, ocs_cache_entry_t *e) {
  if (!c || !e) return;
  pthread_mutex_lock(&c->mu);
  assert(e->state == OCS__PRODUCING && !e->handoff && e->pins == e->waiters + 1);
  c->st.abandoned++;
  e->pins--;
  if (e->waiters) {
    e->handoff = 1;
    pthread_cond_broadcast(&c->cv[e->hash & (OCS__CACHE_CONDS - 1)]);
  } else {
    ocs__drop(c, e);
  }
  pthread_mutex_unlock(&c->mu);
}


void ocs_cache_release(ocs_cache_t *c, ocs_cache_entry_t *e) {
  if (!c || !e) return;
  pthread_mutex_lock(&c->mu);
  assert(e->state == OCS__READY && e->pins >= 1);
  if (--e->pins == 0) {
    ocs__lru_append(c, e);
    ocs__evict(c, 0);
  }
  pthread_mutex_unlock(&c->mu);
}


const void *ocs_cache_data(const ocs_cache_entry_t *e) { return e ? e->data : NULL; }


size_t ocs_cache_bytes(const ocs_cache_entry_t *e) { return e ? e->bytes : 0; }


void ocs_cache_stats(const ocs_cache_t *c, ocs_cache_stats_t *out) {
  if (!out) return;
  memset(out, 0, sizeof *out);
  if (!c) return;
  ocs_cache_t *m = (ocs_cache_t *)c; /* the lock is not part of the observable state */
  pthread_mutex_lock(&m->mu);
  *out = c->st;
  pthread_mutex_unlock(&m->mu);
}


double ocs_cache_hit_rate(const ocs_cache_t *c) {
  ocs_cache_stats_t s;
  ocs_cache_stats(c, &s);
  uint64_t n = s.hits + s.misses;
  return n ? (double)s.hits / (double)n : 0.0;
}


void ocs_cache_set_cap(ocs_cache_t *c, uint64_t cap_bytes) {
  if (!c || cap_bytes == 0) return;
  pthread_mutex_lock(&c->mu);
  c->st.cap_bytes = cap_bytes;
  c->max_buckets = ocs__max_buckets(cap_bytes);
  if (c->max_buckets < c->nbuckets) c->max_buckets = c->nbuckets; /* never shrinks the table */
  ocs__evict(c, 0);
  pthread_mutex_unlock(&c->mu);
}


void ocs_cache_clear(ocs_cache_t *c) {
  if (!c) return;
  pthread_mutex_lock(&c->mu);
  while (c->lru_head) {
    ocs_cache_entry_t *e = c->lru_head;
    ocs__lru_unlink(c, e);
    ocs__drop(c, e);
  }
  pthread_mutex_unlock(&c->mu);
}

/* brick_cache.h — the server-wide brick cache, shared by every viewer and every worker thread.
 *
 * A brick costs a field sample (512 box-filtered points) or a light march to produce, and many
 * viewers look at the same nodes, so produced payloads are kept under one byte budget and evicted
 * least-recently-used. The key is four opaque 64-bit words (e.g. {type | source id, node key, time
 * step, light step}); the cache only hashes and compares them.
 *
 * Single flight: when several threads ask for the same missing key at once, exactly one gets a
 * reservation (a miss) and produces; the others sleep on a condition variable and then get the
 * published entry (a hit), so no brick is ever computed twice concurrently.
 *
 * Pins: every entry handed out is pinned (reference counted) until ocs_cache_release(); a pinned
 * entry is never evicted or freed, so its payload may be read without the lock. Only ready,
 * unpinned entries are evictable.
 *
 * Accounting: `bytes` is, over every entry in the table (reservations included), the payload bytes
 * given to publish() plus OCS_CACHE_ENTRY_OVERHEAD. Charging the overhead bounds the entry count,
 * and so the hash table, by cap_bytes even for empty payloads.
 *
 * Thread safety: every function may be called from any number of threads at once (one mutex per
 * cache; waits are on condition variables, never spinning). A producer must not acquire its own
 * reserved key again before publishing or abandoning it (it would wait for itself). */
#ifndef OC_SERVER_BRICK_CACHE_H
#define OC_SERVER_BRICK_CACHE_H

#include <stddef.h> /* size_t */
#include <stdint.h> /* uint64_t */

/*! Fixed bytes charged per entry on top of its payload: the entry record, the allocator's header
 *  and its hash-bucket slot (the .c checks that the record fits). */
#define OCS_CACHE_ENTRY_OVERHEAD 128u

/*! ocs_cache_acquire() / ocs_cache_peek() results. */
#define OCS_CACHE_MISS 0
#define OCS_CACHE_HIT 1
#define OCS_CACHE_BUSY 2 /**< ocs_cache_try_acquire(): another thread is producing it */

typedef struct {
  uint64_t w[4];
} ocs_cache_key_t; /**< opaque to the cache; hashed with XXH3-64 and compared bytewise */

typedef struct ocs_cache_s ocs_cache_t;
typedef struct ocs_cache_entry_s ocs_cache_entry_t; /**< opaque; valid while pinned */

typedef struct {
  uint64_t hits, misses;  /**< acquire() results; a waiter counts as a hit (published) or a miss (handed a reservation) */
  uint64_t waits;         /**< acquires that waited for another thread's production (counted when the wait starts) */
  uint64_t evictions;     /**< entries dropped for the cap (not by clear()) */
  uint64_t abandoned;     /**< abandon() calls */
  uint64_t bytes;         /**< now: payloads + OCS_CACHE_ENTRY_OVERHEAD per entry */
  uint64_t entries;       /**< now: ready entries and reservations */
  uint64_t peak_bytes;    /**< highest `bytes` seen */
  uint64_t cap_bytes;     /**< current cap */
  uint64_t over_cap;      /**< publishes that left bytes > cap because everything else was pinned */
} ocs_cache_stats_t;

/*! ocs_cache_create() : an empty cache holding at most cap_bytes of unpinned entries.
 *  @return 0, OC_EINVAL (cap_bytes 0 or out NULL) or OC_ENOMEM. */
int ocs_cache_create(ocs_cache_t **out, uint64_t cap_bytes);
/*! ocs_cache_free() : frees every entry and payload (with free()), pinned or not; no thread may
 *  still use the cache. NULL is accepted. */
void ocs_cache_free(ocs_cache_t *c);

/*! ocs_cache_acquire() : looks up `key`, waiting if another thread is producing it.
 *  @return OCS_CACHE_HIT (1): *e is a ready entry, pinned for the caller.
 *          OCS_CACHE_MISS (0): *e is a new pinned reservation ("producing"); the caller must call
 *          ocs_cache_publish() or ocs_cache_abandon() on it, then ocs_cache_release() after publish.
 *          A negative OC_E* (OC_EINVAL, OC_ENOMEM), *e NULL.
 *  note : a waiter gets the hit when the producer publishes, or the reservation when it abandons. */
int ocs_cache_acquire(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e);
/*! ocs_cache_try_acquire() : as ocs_cache_acquire(), but instead of waiting for another thread's
 *  production returns OCS_CACHE_BUSY with *e NULL (nothing pinned, not counted as a wait), so the
 *  caller can do other work first and acquire later. */
int ocs_cache_try_acquire(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e);
/*! ocs_cache_peek() : non-blocking lookup for callers that can do without the brick now.
 *  @return 1 and a pinned ready entry, or 0 with *e NULL (absent or being produced; nothing is
 *  reserved and hits/misses are not counted). */
int ocs_cache_peek(ocs_cache_t *c, const ocs_cache_key_t *key, ocs_cache_entry_t **e);
/*! ocs_cache_publish() : makes a reservation ready with `data` (malloc'd; the cache owns it from now
 *  on and free()s it on eviction; NULL with bytes 0 is allowed) and wakes its waiters. The entry
 *  stays pinned by the caller until ocs_cache_release(). Then evicts least-recently-used unpinned
 *  entries until bytes ≤ cap; when only pinned ones are left, counts over_cap. */
void ocs_cache_publish(ocs_cache_t *c, ocs_cache_entry_t *e, void *data, size_t bytes);
/*! ocs_cache_abandon() : production failed. The reservation is handed to one waiter (whose acquire
 *  returns a miss), or removed when nobody waits; nothing is cached. Releases the caller's pin: do
 *  not release() it afterwards. */
void ocs_cache_abandon(ocs_cache_t *c, ocs_cache_entry_t *e);
/*! ocs_cache_release() : unpins a ready entry; at zero pins it becomes the most recently used
 *  evictable entry (and is evicted at once if the cache is still over its cap). NULL is accepted. */
void ocs_cache_release(ocs_cache_t *c, ocs_cache_entry_t *e);
/*! ocs_cache_data() : payload of a ready entry (valid while pinned). */
const void *ocs_cache_data(const ocs_cache_entry_t *e);
/*! ocs_cache_bytes() : payload size of a ready entry, as given to publish(). */
size_t ocs_cache_bytes(const ocs_cache_entry_t *e);

/*! ocs_cache_stats() : a consistent snapshot of the counters. */
void ocs_cache_stats(const ocs_cache_t *c, ocs_cache_stats_t *out);
/*! ocs_cache_hit_rate() : @return hits / (hits + misses), 0 when there was no acquire. */
double ocs_cache_hit_rate(const ocs_cache_t *c);
/*! ocs_cache_set_cap() : changes the cap (0 is ignored); lowering it evicts at once, unpinned LRU
 *  first. Pinned entries left over the cap go when released. */
void ocs_cache_set_cap(ocs_cache_t *c, uint64_t cap_bytes);
/*! ocs_cache_clear() : drops every ready unpinned entry (e.g. on scene reload: old keys can never
 *  hit again). Pinned entries and reservations stay; not counted as evictions. */
void ocs_cache_clear(ocs_cache_t *c);

#endif /* OC_SERVER_BRICK_CACHE_H */

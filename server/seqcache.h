/* seqcache.h — a lock-free, direct-mapped cache of small values keyed by (node key, time step).
 *
 * The field's bound cache (field.c) and the procedural source's node-bound cache
 * (source_procedural.c) remember results that are pure functions of (key, step), which many
 * threads ask for again and again. Each slot is a seqlock over (key, step, `words` 64-bit words):
 * a reader that meets a write in progress misses, a writer that meets another writer skips its
 * insert (the next miss inserts), so nobody waits. A hit returns exactly the words put.
 *
 * All fields are atomics, read and written relaxed and ordered by fences (the seqlock of Boehm,
 * "Can seqlocks get along with programming language memory models?", 2012). Key 0 is reserved
 * (a zeroed slot holds it; no node key is 0): it is never put and never hits.
 * ocs_seqcache_clear() must not race with the others (callers serialise it, e.g. between epochs). */
#ifndef OC_SERVER_SEQCACHE_H
#define OC_SERVER_SEQCACHE_H

#include <stddef.h>
#include <stdint.h>

typedef struct ocs_seqcache_s ocs_seqcache_t;

/*! ocs_seqcache_new() : `slots` (a power of two) slots of `words` (1 … 64) words each, all empty;
 *  NULL when out of memory or the arguments are invalid. */
ocs_seqcache_t *ocs_seqcache_new(size_t slots, int words);
/*! ocs_seqcache_free() : NULL is accepted. */
void ocs_seqcache_free(ocs_seqcache_t *c);
/*! ocs_seqcache_get() : 1 and the words put for (key, step) into out, or 0 (a miss). */
int ocs_seqcache_get(const ocs_seqcache_t *c, uint64_t key, uint64_t step, uint64_t *out);
/*! ocs_seqcache_put() : remembers the words for (key, step), replacing the slot's entry, unless a
 *  concurrent writer holds the slot. */
void ocs_seqcache_put(ocs_seqcache_t *c, uint64_t key, uint64_t step, const uint64_t *words);
/*! ocs_seqcache_clear() : empties every slot (not concurrently with get or put). */
void ocs_seqcache_clear(ocs_seqcache_t *c);

#endif /* OC_SERVER_SEQCACHE_H */

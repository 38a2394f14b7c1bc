/* test_seqcache.c — the (key, step) seqlock cache (server/seqcache.h): a hit returns exactly the
 * words put, a different key or step misses, clear empties, bad arguments are refused; and under
 * threads that put and get the same few slots at once, no get ever returns a torn entry. */
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "test_main.h"
#include "seqcache.h"

enum { WORDS = 14 };

/* The words every writer puts for (key, step): any mix of two entries is detectable. */
static void words_of(uint64_t key, uint64_t step, uint64_t *w) {
  for (int i = 0; i < WORDS; i++) w[i] = (key * 0x9e3779b97f4a7c15ull) ^ (step << 8) ^ (uint64_t)i;
}

static void test_seqcache__hit_miss_clear(void **st) {
  (void)st;
  assert_null(ocs_seqcache_new(0, 1));
  assert_null(ocs_seqcache_new(1000, 1)); /* not a power of two */
  assert_null(ocs_seqcache_new(64, 0));
  assert_null(ocs_seqcache_new(64, 65));
  ocs_seqcache_free(NULL);
  ocs_seqcache_t *c = ocs_seqcache_new(1024, WORDS);
  assert_non_null(c);
  uint64_t w[WORDS], r[WORDS];
  assert_false(ocs_seqcache_get(c, 0, 0, r)); /* key 0 is reserved: a zeroed slot holds it */
  ocs_seqcache_put(c, 0, 0, r);
  assert_false(ocs_seqcache_get(c, 0, 0, r));
  for (uint64_t k = 1; k <= 300; k++) {
    words_of(k, 7, w);
    ocs_seqcache_put(c, k, 7, w);
  }
  int hits = 0;
  for (uint64_t k = 1; k <= 300; k++) {
    assert_false(ocs_seqcache_get(c, k, 8, r)); /* another step */
    if (!ocs_seqcache_get(c, k, 7, r)) continue; /* evicted by a later key in its slot */
    hits++;
    words_of(k, 7, w);
    assert_memory_equal(r, w, sizeof w);
  }
  assert_true(hits > 200); /* 300 keys over 1024 slots: few collide */
  ocs_seqcache_clear(c);
  for (uint64_t k = 1; k <= 300; k++) assert_false(ocs_seqcache_get(c, k, 7, r));
  ocs_seqcache_free(c);
}

typedef struct {
  ocs_seqcache_t *c;
  int id;
  atomic_long hits, torn;
} race_t;

static void *racer(void *arg) {
  race_t *x = arg;
  uint64_t w[WORDS], r[WORDS], s = 0x1234567u + (uint64_t)x->id;
  long hits = 0, torn = 0;
  for (int it = 0; it < 1000000; it++) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    uint64_t key = 1 + (s >> 59 & 15), step = s >> 40 & 3; /* 16 keys × 4 steps over 8 slots */
    if (s >> 33 & 1) {
      words_of(key, step, w);
      ocs_seqcache_put(x->c, key, step, w);
    } else if (ocs_seqcache_get(x->c, key, step, r)) {
      hits++;
      words_of(key, step, w);
      for (int i = 0; i < WORDS; i++) torn += r[i] != w[i];
    }
  }
  atomic_store(&x->hits, hits);
  atomic_store(&x->torn, torn);
  return NULL;
}

static void test_seqcache__no_torn_reads(void **st) {
  (void)st;
  enum { THREADS = 4 };
  ocs_seqcache_t *c = ocs_seqcache_new(8, WORDS);
  assert_non_null(c);
  pthread_t th[THREADS];
  static race_t x[THREADS];
  for (int i = 0; i < THREADS; i++) {
    x[i].c = c, x[i].id = i;
    atomic_store(&x[i].hits, 0);
    atomic_store(&x[i].torn, 0);
    assert_int_equal(pthread_create(&th[i], NULL, racer, &x[i]), 0);
  }
  long hits = 0;
  for (int i = 0; i < THREADS; i++) {
    pthread_join(th[i], NULL);
    hits += atomic_load(&x[i].hits);
    assert_int_equal(atomic_load(&x[i].torn), 0);
  }
  assert_true(hits > 1000); /* the race was run, not only missed */
  ocs_seqcache_free(c);
}

OC_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_seqcache__hit_miss_clear), cmocka_unit_test(test_seqcache__no_torn_reads))

/* test_brick_cache.c — the server-wide brick cache: hits, misses and exact counters, LRU order,
 * pins against eviction, abandon hand-over, single-flight production under 8 threads, cap changes,
 * clear, and a random multi-thread stress that checks the cap and the byte accounting (the ASan
 * build checks for leaks). Worker threads never call cmocka asserts (they longjmp into the main
 * thread); they count failures, and the main thread asserts on the counts. */
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "test_main.h"
#include "brick_cache.h"
#include "oc_err.h"

#define OVH ((uint64_t)OCS_CACHE_ENTRY_OVERHEAD)
#define PAYLOAD 1000u

static ocs_cache_key_t key_of(uint64_t id) {
  ocs_cache_key_t k = {{1, id * 0x9E3779B97F4A7C15ull, id, 7}};
  return k;
}

static unsigned char pattern(uint64_t id, size_t i) { return (unsigned char)(id * 31u + i * 7u + 1u); }

static void *make_payload(uint64_t id, size_t n) {
  unsigned char *p = malloc(n ? n : 1);
  for (size_t i = 0; i < n; i++) p[i] = pattern(id, i);
  return p;
}

static int payload_ok(const ocs_cache_entry_t *e, uint64_t id, size_t n) {
  const unsigned char *p = ocs_cache_data(e);
  if (ocs_cache_bytes(e) != n || (n && !p)) return 0;
  for (size_t i = 0; i < n; i++)
    if (p[i] != pattern(id, i)) return 0;
  return 1;
}

/* Each test's cache, of the cap given as its initial state (CACHE_TEST), freed after it. */
static int cache_setup(void **state) {
  ocs_cache_t *c = NULL;
  if (ocs_cache_create(&c, (uint64_t)(uintptr_t)*state) != 0) return -1;
  *state = c;
  return 0;
}

static int cache_teardown(void **state) {
  ocs_cache_free(*state);
  return 0;
}

#define CACHE_TEST(f, cap) cmocka_unit_test_prestate_setup_teardown(f, cache_setup, cache_teardown, (void *)(uintptr_t)(cap))

static ocs_cache_stats_t stats_of(const ocs_cache_t *c) {
  ocs_cache_stats_t s;
  ocs_cache_stats(c, &s);
  return s;
}

/* Acquire (must miss), publish PAYLOAD bytes, release. */
static void insert(ocs_cache_t *c, uint64_t id) {
  ocs_cache_key_t k = key_of(id);
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  ocs_cache_publish(c, e, make_payload(id, PAYLOAD), PAYLOAD);
  ocs_cache_release(c, e);
}

/* Acquire (must miss) and publish, keeping the pin. */
static ocs_cache_entry_t *insert_pinned(ocs_cache_t *c, uint64_t id) {
  ocs_cache_key_t k = key_of(id);
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  ocs_cache_publish(c, e, make_payload(id, PAYLOAD), PAYLOAD);
  return e;
}

static int present(ocs_cache_t *c, uint64_t id) {
  ocs_cache_key_t k = key_of(id);
  ocs_cache_entry_t *e = NULL;
  int r = ocs_cache_peek(c, &k, &e);
  ocs_cache_release(c, e);
  return r;
}

static void sleep_us(long us) {
  struct timespec ts = {us / 1000000, (us % 1000000) * 1000};
  nanosleep(&ts, NULL);
}

/* Polls until `n` acquires have started waiting (waits is counted when a wait starts). */
static void wait_for_waits(ocs_cache_t *c, uint64_t n) {
  ocs_cache_stats_t s;
  for (int i = 0; i < 20000; i++) {
    s = stats_of(c);
    if (s.waits >= n) return;
    sleep_us(500);
  }
  fail_msg("waiters never arrived (%llu of %llu)", (unsigned long long)s.waits, (unsigned long long)n);
}

static void test_brick_cache__create_rejects_zero_cap(void **st) {
  (void)st;
  ocs_cache_t *c = (ocs_cache_t *)1;
  assert_int_equal(ocs_cache_create(&c, 0), OC_EINVAL);
  assert_null(c);
  assert_int_equal(ocs_cache_create(NULL, 100), OC_EINVAL);
  ocs_cache_free(NULL);
  ocs_cache_release(NULL, NULL);
  assert_true(ocs_cache_hit_rate(NULL) == 0.0);
}

static void test_brick_cache__miss_publish_then_hit(void **st) {
  ocs_cache_t *c = *st;
  assert_true(ocs_cache_hit_rate(c) == 0.0);
  ocs_cache_key_t k = key_of(42), other = key_of(43);
  ocs_cache_entry_t *e = NULL, *e2 = NULL;

  assert_int_equal(ocs_cache_peek(c, &k, &e), 0); /* absent */
  assert_null(e);
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  assert_non_null(e);
  assert_int_equal(ocs_cache_peek(c, &k, &e2), 0); /* being produced: peek neither waits nor reserves */
  assert_null(e2);
  void *data = make_payload(42, PAYLOAD);
  ocs_cache_publish(c, e, data, PAYLOAD);
  assert_ptr_equal(ocs_cache_data(e), data);
  assert_int_equal(ocs_cache_bytes(e), PAYLOAD);
  ocs_cache_release(c, e);

  assert_int_equal(ocs_cache_acquire(c, &k, &e2), OCS_CACHE_HIT);
  assert_ptr_equal(e2, e);
  assert_true(payload_ok(e2, 42, PAYLOAD));
  ocs_cache_release(c, e2);
  assert_int_equal(ocs_cache_peek(c, &k, &e2), 1);
  assert_ptr_equal(ocs_cache_data(e2), data);
  ocs_cache_release(c, e2);
  assert_int_equal(ocs_cache_peek(c, &other, &e2), 0);

  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.hits, 1); /* peeks are not counted */
  assert_int_equal(s.misses, 1);
  assert_int_equal(s.waits, 0);
  assert_int_equal(s.evictions, 0);
  assert_int_equal(s.abandoned, 0);
  assert_int_equal(s.entries, 1);
  assert_int_equal(s.bytes, PAYLOAD + OVH);
  assert_int_equal(s.peak_bytes, PAYLOAD + OVH);
  assert_int_equal(s.cap_bytes, 1u << 20);
  assert_int_equal(s.over_cap, 0);
  assert_true(ocs_cache_hit_rate(c) == 0.5);

  /* A key differing in any one word is a different entry. */
  for (int w = 0; w < 4; w++) {
    ocs_cache_key_t d = k;
    d.w[w] ^= 1;
    assert_int_equal(ocs_cache_peek(c, &d, &e2), 0);
  }
  /* An empty payload is a valid entry (e.g. an all-zero brick). */
  assert_int_equal(ocs_cache_acquire(c, &other, &e2), OCS_CACHE_MISS);
  ocs_cache_publish(c, e2, NULL, 0);
  ocs_cache_release(c, e2);
  assert_int_equal(present(c, 43), 1);
  s = stats_of(c);
  assert_int_equal(s.bytes, PAYLOAD + 2 * OVH);
}

/* try_acquire: a miss reserves, a reservation in progress is BUSY without a wait or a pin, a ready
 * entry is a pinned hit. */
static void test_brick_cache__try_acquire_never_waits(void **st) {
  ocs_cache_t *c = *st;
  ocs_cache_key_t k = key_of(7);
  ocs_cache_entry_t *e = NULL, *e2 = (ocs_cache_entry_t *)&k;
  assert_int_equal(ocs_cache_try_acquire(c, &k, &e), OCS_CACHE_MISS);
  assert_non_null(e);
  assert_int_equal(ocs_cache_try_acquire(c, &k, &e2), OCS_CACHE_BUSY); /* would wait: returns at once */
  assert_null(e2);
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.waits, 0);
  assert_int_equal(s.misses, 1);
  ocs_cache_publish(c, e, make_payload(7, PAYLOAD), PAYLOAD);
  ocs_cache_release(c, e);
  assert_int_equal(ocs_cache_try_acquire(c, &k, &e2), OCS_CACHE_HIT);
  assert_true(payload_ok(e2, 7, PAYLOAD));
  ocs_cache_release(c, e2);
  ocs_cache_set_cap(c, 1); /* unpinned: evicted, so BUSY left no pin behind */
  s = stats_of(c);
  assert_int_equal(s.entries, 0);
}

/* Cap fits exactly 3 entries: touching A then inserting D evicts B (the least recent), not A. */
static void test_brick_cache__lru_evicts_least_recent(void **st) {
  ocs_cache_t *c = *st;
  insert(c, 'A');
  insert(c, 'B');
  insert(c, 'C');
  ocs_cache_key_t ka = key_of('A');
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &ka, &e), OCS_CACHE_HIT);
  ocs_cache_release(c, e);
  insert(c, 'D'); /* order now C, A, D */
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.evictions, 1);
  assert_int_equal(s.entries, 3);
  assert_int_equal(s.bytes, 3 * (PAYLOAD + OVH));
  assert_int_equal(s.over_cap, 0);
  insert(c, 'E'); /* evicts C; order A, D, E */
  assert_int_equal(present(c, 'B'), 0);
  assert_int_equal(present(c, 'C'), 0);
  assert_int_equal(present(c, 'A'), 1); /* peeks touch too: order D, E, A */
  assert_int_equal(present(c, 'D'), 1); /* E, A, D */
  assert_int_equal(present(c, 'E'), 1); /* A, D, E */
  insert(c, 'F');                       /* evicts A */
  assert_int_equal(present(c, 'A'), 0);
  assert_int_equal(present(c, 'D'), 1);
  s = stats_of(c);
  assert_int_equal(s.evictions, 3);
  assert_int_equal(s.misses, 6);
  assert_int_equal(s.hits, 1);
}

/* Pinned entries survive any pressure (over_cap is counted) and go once released if still over. */
static void test_brick_cache__pinned_never_evicted(void **st) {
  ocs_cache_t *c = *st;
  ocs_cache_entry_t *a = insert_pinned(c, 'A'), *b = insert_pinned(c, 'B'), *cc = insert_pinned(c, 'C');
  ocs_cache_entry_t *d = insert_pinned(c, 'D');
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.evictions, 0);
  assert_int_equal(s.over_cap, 1);
  assert_int_equal(s.entries, 4);
  assert_int_equal(s.bytes, 4 * (PAYLOAD + OVH));
  assert_int_equal(s.peak_bytes, 4 * (PAYLOAD + OVH));
  assert_true(payload_ok(a, 'A', PAYLOAD) && payload_ok(b, 'B', PAYLOAD) && payload_ok(cc, 'C', PAYLOAD));
  assert_true(payload_ok(d, 'D', PAYLOAD));

  ocs_cache_release(c, a); /* the cache is over its cap: A goes at once */
  s = stats_of(c);
  assert_int_equal(s.evictions, 1);
  assert_int_equal(s.bytes, 3 * (PAYLOAD + OVH));
  assert_int_equal(present(c, 'A'), 0);
  ocs_cache_release(c, b);
  ocs_cache_release(c, cc);
  ocs_cache_release(c, d);
  s = stats_of(c);
  assert_int_equal(s.evictions, 1);
  assert_int_equal(s.entries, 3);

  /* A payload larger than the cap: cached while pinned, dropped on release. */
  ocs_cache_key_t kb = key_of('Z');
  ocs_cache_entry_t *z = NULL;
  assert_int_equal(ocs_cache_acquire(c, &kb, &z), OCS_CACHE_MISS);
  ocs_cache_publish(c, z, make_payload('Z', 4 * PAYLOAD), 4 * PAYLOAD);
  s = stats_of(c);
  assert_int_equal(s.over_cap, 2);
  assert_int_equal(s.entries, 1); /* everything else was evicted trying */
  assert_true(payload_ok(z, 'Z', 4 * PAYLOAD));
  ocs_cache_release(c, z);
  s = stats_of(c);
  assert_int_equal(s.entries, 0);
  assert_int_equal(s.bytes, 0);
}

/* Memory bound: even empty payloads are charged the overhead, so the entry count stays bounded. */
static void test_brick_cache__overhead_bounds_entries(void **st) {
  ocs_cache_t *c = *st;
  for (uint64_t i = 0; i < 20000; i++) {
    ocs_cache_key_t k = key_of(i);
    ocs_cache_entry_t *e = NULL;
    assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
    ocs_cache_publish(c, e, NULL, 0);
    ocs_cache_release(c, e);
  }
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.entries, 64);
  assert_int_equal(s.bytes, 64 * OVH);
  assert_int_equal(s.evictions, 20000 - 64);
  assert_int_equal(s.peak_bytes, 64 * OVH); /* room is made before a reservation is charged */
}

static void test_brick_cache__abandon_without_waiters_removes(void **st) {
  ocs_cache_t *c = *st;
  ocs_cache_key_t k = key_of(5);
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  ocs_cache_abandon(c, e);
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.abandoned, 1);
  assert_int_equal(s.entries, 0);
  assert_int_equal(s.bytes, 0);
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS); /* nothing was cached */
  ocs_cache_publish(c, e, make_payload(5, 10), 10);
  ocs_cache_release(c, e);
  s = stats_of(c);
  assert_int_equal(s.misses, 2);
  assert_int_equal(s.entries, 1);
}

typedef struct {
  ocs_cache_t *c;
  uint64_t id;
  int result;
  int data_ok;
  int publish; /* on a miss, produce and publish */
} waiter_t;

static void *waiter_main(void *arg) {
  waiter_t *w = arg;
  ocs_cache_key_t k = key_of(w->id);
  ocs_cache_entry_t *e = NULL;
  w->result = ocs_cache_acquire(w->c, &k, &e);
  if (w->result < 0) return NULL;
  if (w->result == OCS_CACHE_MISS && !w->publish) { /* this production fails too */
    ocs_cache_abandon(w->c, e);
    return NULL;
  }
  if (w->result == OCS_CACHE_MISS) ocs_cache_publish(w->c, e, make_payload(w->id, 64), 64);
  w->data_ok = payload_ok(e, w->id, 64);
  ocs_cache_release(w->c, e);
  return NULL;
}

/* Starts n threads, each acquiring key_of(id) (publish: produces and publishes on a miss, else
 * abandons), then until `n` more acquires wait, so that all of them are waiting for the caller. */
static void start_waiters(ocs_cache_t *c, waiter_t *ws, pthread_t *ts, int n, uint64_t id, int publish) {
  ocs_cache_stats_t s = stats_of(c);
  for (int i = 0; i < n; i++) {
    ws[i] = (waiter_t){c, id, -1, 0, publish};
    assert_int_equal(pthread_create(&ts[i], NULL, waiter_main, &ws[i]), 0);
  }
  wait_for_waits(c, s.waits + (uint64_t)n);
}

/* Production fails while another thread waits: the waiter inherits the reservation (a miss). */
static void test_brick_cache__abandon_hands_reservation_to_waiter(void **st) {
  ocs_cache_t *c = *st;
  ocs_cache_key_t k = key_of(9);
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  waiter_t w;
  pthread_t t;
  start_waiters(c, &w, &t, 1, 9, 1);
  ocs_cache_abandon(c, e);
  pthread_join(t, NULL);
  assert_int_equal(w.result, OCS_CACHE_MISS);
  assert_true(w.data_ok);
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.misses, 2);
  assert_int_equal(s.hits, 0);
  assert_int_equal(s.waits, 1);
  assert_int_equal(s.abandoned, 1);
  assert_int_equal(s.entries, 1);
  assert_int_equal(s.bytes, 64 + OVH);
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_HIT);
  assert_true(payload_ok(e, 9, 64));
  ocs_cache_release(c, e);

  /* Three waiters whose productions all fail: each abandon hands the reservation to exactly one
   * waiter, so every one of them gets a miss, and the last abandon removes the entry. */
  ocs_cache_key_t k2 = key_of(10);
  assert_int_equal(ocs_cache_acquire(c, &k2, &e), OCS_CACHE_MISS);
  waiter_t ws[3];
  pthread_t ts[3];
  start_waiters(c, ws, ts, 3, 10, 0);
  ocs_cache_abandon(c, e);
  for (int i = 0; i < 3; i++) {
    pthread_join(ts[i], NULL);
    assert_int_equal(ws[i].result, OCS_CACHE_MISS);
  }
  s = stats_of(c);
  assert_int_equal(s.misses, 2 + 1 + 3);
  assert_int_equal(s.hits, 1);
  assert_int_equal(s.waits, 4);
  assert_int_equal(s.abandoned, 1 + 1 + 3);
  assert_int_equal(s.entries, 1);
  assert_int_equal(s.bytes, 64 + OVH);
}

static void test_brick_cache__waiters_get_published_entry(void **st) {
  ocs_cache_t *c = *st;
  ocs_cache_key_t k = key_of(11);
  ocs_cache_entry_t *e = NULL;
  assert_int_equal(ocs_cache_acquire(c, &k, &e), OCS_CACHE_MISS);
  waiter_t ws[4];
  pthread_t ts[4];
  start_waiters(c, ws, ts, 4, 11, 1);
  ocs_cache_publish(c, e, make_payload(11, 64), 64);
  ocs_cache_release(c, e);
  for (int i = 0; i < 4; i++) {
    pthread_join(ts[i], NULL);
    assert_int_equal(ws[i].result, OCS_CACHE_HIT);
    assert_true(ws[i].data_ok);
  }
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.hits, 4);
  assert_int_equal(s.misses, 1);
  assert_int_equal(s.waits, 4);
  assert_int_equal(s.entries, 1);
}

/* ---- single flight: 8 threads × the same 200 keys in different orders ---- */

#define SF_THREADS 8
#define SF_KEYS 200

typedef struct {
  ocs_cache_t *c;
  pthread_barrier_t *start;
  atomic_int *produced; /* [SF_KEYS] */
  atomic_int *bad;
  uint64_t seed;
} sf_arg_t;

static uint64_t xs(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return *s * 2685821657736338717ull;
}

static void *sf_main(void *arg) {
  sf_arg_t *a = arg;
  uint64_t order[SF_KEYS], s = a->seed;
  for (int i = 0; i < SF_KEYS; i++) order[i] = (uint64_t)i;
  for (int i = SF_KEYS - 1; i > 0; i--) { /* Fisher–Yates with a per-thread seed */
    int j = (int)(xs(&s) % (uint64_t)(i + 1));
    uint64_t t = order[i];
    order[i] = order[j];
    order[j] = t;
  }
  pthread_barrier_wait(a->start);
  for (int i = 0; i < SF_KEYS; i++) {
    uint64_t id = order[i];
    ocs_cache_key_t k = key_of(id);
    ocs_cache_entry_t *e = NULL;
    int r = ocs_cache_acquire(a->c, &k, &e);
    if (r < 0) {
      atomic_fetch_add(a->bad, 1);
      continue;
    }
    if (r == OCS_CACHE_MISS) {
      atomic_fetch_add(&a->produced[id], 1);
      if (id % 3 == 0) sleep_us(100);
      size_t n = 16 + (size_t)id;
      ocs_cache_publish(a->c, e, make_payload(id, n), n);
    }
    if (!payload_ok(e, id, 16 + (size_t)id)) atomic_fetch_add(a->bad, 1);
    ocs_cache_release(a->c, e);
  }
  return NULL;
}

static void test_brick_cache__single_flight_under_concurrency(void **st) {
  ocs_cache_t *c = *st;
  atomic_int produced[SF_KEYS], bad = 0;
  for (int i = 0; i < SF_KEYS; i++) atomic_init(&produced[i], 0);
  pthread_barrier_t start;
  pthread_barrier_init(&start, NULL, SF_THREADS);
  sf_arg_t args[SF_THREADS];
  pthread_t ts[SF_THREADS];
  for (int t = 0; t < SF_THREADS; t++) {
    args[t] = (sf_arg_t){c, &start, produced, &bad, 0x1234567ull * (uint64_t)(t + 1)};
    assert_int_equal(pthread_create(&ts[t], NULL, sf_main, &args[t]), 0);
  }
  for (int t = 0; t < SF_THREADS; t++) pthread_join(ts[t], NULL);
  pthread_barrier_destroy(&start);
  assert_int_equal(atomic_load(&bad), 0);
  for (int i = 0; i < SF_KEYS; i++) assert_int_equal(atomic_load(&produced[i]), 1);
  ocs_cache_stats_t s = stats_of(c);
  printf("single flight: hits %llu misses %llu waits %llu\n", (unsigned long long)s.hits,
         (unsigned long long)s.misses, (unsigned long long)s.waits);
  assert_int_equal(s.hits + s.misses, SF_THREADS * SF_KEYS);
  assert_int_equal(s.misses, SF_KEYS);
  assert_int_equal(s.entries, SF_KEYS);
  assert_int_equal(s.evictions, 0);
  assert_true(s.waits <= s.hits);
}

static void test_brick_cache__set_cap_lowering_evicts(void **st) {
  ocs_cache_t *c = *st;
  for (uint64_t i = 0; i < 10; i++) insert(c, i);
  ocs_cache_entry_t *p0 = NULL;
  ocs_cache_key_t k0 = key_of(0);
  assert_int_equal(ocs_cache_acquire(c, &k0, &p0), OCS_CACHE_HIT); /* oldest, but pinned */
  ocs_cache_set_cap(c, 4 * (PAYLOAD + OVH));
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.cap_bytes, 4 * (PAYLOAD + OVH));
  assert_int_equal(s.entries, 4); /* the pinned 0 and the 3 newest */
  assert_int_equal(s.evictions, 6);
  assert_int_equal(s.bytes, 4 * (PAYLOAD + OVH));
  for (uint64_t i = 1; i < 7; i++) assert_int_equal(present(c, i), 0);
  for (uint64_t i = 7; i < 10; i++) assert_int_equal(present(c, i), 1);
  assert_true(payload_ok(p0, 0, PAYLOAD));
  ocs_cache_set_cap(c, 2 * (PAYLOAD + OVH)); /* 0 stays while pinned */
  s = stats_of(c);
  assert_int_equal(s.entries, 2);
  assert_int_equal(present(c, 0), 1); /* a peek pins and releases: still within the cap */
  ocs_cache_release(c, p0);
  ocs_cache_set_cap(c, 0); /* ignored */
  s = stats_of(c);
  assert_int_equal(s.cap_bytes, 2 * (PAYLOAD + OVH));
  ocs_cache_set_cap(c, 1); /* smaller than any entry: all unpinned go */
  s = stats_of(c);
  assert_int_equal(s.entries, 0);
  assert_int_equal(s.bytes, 0);
}

static void test_brick_cache__clear_keeps_pinned(void **st) {
  ocs_cache_t *c = *st;
  for (uint64_t i = 0; i < 5; i++) insert(c, i);
  ocs_cache_entry_t *p = insert_pinned(c, 5), *r = NULL;
  ocs_cache_key_t k6 = key_of(6);
  assert_int_equal(ocs_cache_acquire(c, &k6, &r), OCS_CACHE_MISS); /* a reservation survives too */
  ocs_cache_clear(c);
  ocs_cache_stats_t s = stats_of(c);
  assert_int_equal(s.entries, 2);
  assert_int_equal(s.bytes, PAYLOAD + 2 * OVH);
  assert_int_equal(s.evictions, 0);
  for (uint64_t i = 0; i < 5; i++) assert_int_equal(present(c, i), 0);
  assert_true(payload_ok(p, 5, PAYLOAD));
  ocs_cache_publish(c, r, make_payload(6, 64), 64);
  ocs_cache_release(c, r);
  ocs_cache_release(c, p);
  assert_int_equal(present(c, 5), 1);
  ocs_cache_clear(c);
  s = stats_of(c);
  assert_int_equal(s.entries, 0);
  assert_int_equal(s.bytes, 0);
}

/* ---- random stress: many threads, random keys, small cap, abandons, peeks, clears ---- */

#define ST_THREADS 8
#define ST_ROUNDS 40
#define ST_OPS 1000
#define ST_KEYS 96
#define ST_CAP (12 * (1024 + OVH))

typedef struct {
  ocs_cache_t *c;
  pthread_barrier_t *bar;
  atomic_int *bad;
  atomic_int *over; /* bytes > cap seen at a barrier, when nothing was pinned */
  atomic_llong *acquires, *abandons;
  int index;
} st_arg_t;

static size_t st_size(uint64_t id) { return (size_t)((id * 337u) % 2048u); }

static void *st_main(void *arg) {
  st_arg_t *a = arg;
  uint64_t s = 0xABCDEF12345ull * (uint64_t)(a->index + 1);
  for (int round = 0; round < ST_ROUNDS; round++) {
    for (int op = 0; op < ST_OPS; op++) {
      uint64_t r = xs(&s);
      uint64_t id = (r >> 8) % ST_KEYS;
      ocs_cache_key_t k = key_of(id);
      ocs_cache_entry_t *e = NULL;
      unsigned kind = (unsigned)(r & 0xff);
      if (kind < 40) { /* peek */
        if (ocs_cache_peek(a->c, &k, &e)) {
          if (!payload_ok(e, id, st_size(id))) atomic_fetch_add(a->bad, 1);
          ocs_cache_release(a->c, e);
        } else if (e) {
          atomic_fetch_add(a->bad, 1);
        }
        continue;
      }
      if (kind == 40 && a->index == 0) {
        ocs_cache_clear(a->c);
        continue;
      }
      int res = ocs_cache_acquire(a->c, &k, &e);
      atomic_fetch_add(a->acquires, 1);
      if (res < 0) {
        atomic_fetch_add(a->bad, 1);
        continue;
      }
      if (res == OCS_CACHE_MISS) {
        if (kind < 64) { /* production failed */
          atomic_fetch_add(a->abandons, 1);
          ocs_cache_abandon(a->c, e);
          continue;
        }
        if (kind > 250) sleep_us(50);
        ocs_cache_publish(a->c, e, make_payload(id, st_size(id)), st_size(id));
      }
      if (!payload_ok(e, id, st_size(id))) atomic_fetch_add(a->bad, 1);
      ocs_cache_release(a->c, e);
    }
    /* Nothing is pinned between the two barriers: the cache must be within its cap. */
    pthread_barrier_wait(a->bar);
    if (a->index == 0) {
      ocs_cache_stats_t st;
      ocs_cache_stats(a->c, &st);
      if (st.bytes > st.cap_bytes) atomic_fetch_add(a->over, 1);
    }
    pthread_barrier_wait(a->bar);
  }
  return NULL;
}

static void test_brick_cache__random_stress(void **st) {
  ocs_cache_t *c = *st;
  atomic_int bad = 0, over = 0;
  atomic_llong acquires = 0, abandons = 0;
  pthread_barrier_t bar;
  pthread_barrier_init(&bar, NULL, ST_THREADS);
  st_arg_t args[ST_THREADS];
  pthread_t ts[ST_THREADS];
  for (int t = 0; t < ST_THREADS; t++) {
    args[t] = (st_arg_t){c, &bar, &bad, &over, &acquires, &abandons, t};
    assert_int_equal(pthread_create(&ts[t], NULL, st_main, &args[t]), 0);
  }
  for (int t = 0; t < ST_THREADS; t++) pthread_join(ts[t], NULL);
  pthread_barrier_destroy(&bar);
  ocs_cache_stats_t s = stats_of(c);
  printf("stress: hits %llu misses %llu waits %llu evictions %llu abandoned %llu over_cap %llu entries %llu "
         "bytes %llu peak %llu cap %llu\n",
         (unsigned long long)s.hits, (unsigned long long)s.misses, (unsigned long long)s.waits,
         (unsigned long long)s.evictions, (unsigned long long)s.abandoned, (unsigned long long)s.over_cap,
         (unsigned long long)s.entries, (unsigned long long)s.bytes, (unsigned long long)s.peak_bytes,
         (unsigned long long)s.cap_bytes);
  assert_int_equal(atomic_load(&bad), 0);
  assert_int_equal(atomic_load(&over), 0);
  assert_int_equal(s.hits + s.misses, (uint64_t)atomic_load(&acquires));
  assert_int_equal(s.abandoned, (uint64_t)atomic_load(&abandons));
  assert_true(s.hits > 0 && s.evictions > 0 && s.abandoned > 0);
  assert_true(s.bytes <= s.cap_bytes);
  assert_true(s.entries * OVH <= s.bytes);
  /* Accounting is exact: with nothing pinned, clear() leaves nothing. */
  ocs_cache_clear(c);
  s = stats_of(c);
  assert_int_equal(s.entries, 0);
  assert_int_equal(s.bytes, 0);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_brick_cache__create_rejects_zero_cap),
             CACHE_TEST(test_brick_cache__miss_publish_then_hit, 1u << 20),
             CACHE_TEST(test_brick_cache__try_acquire_never_waits, 1u << 20),
             CACHE_TEST(test_brick_cache__lru_evicts_least_recent, 3 * (PAYLOAD + OVH)),
             CACHE_TEST(test_brick_cache__pinned_never_evicted, 3 * (PAYLOAD + OVH)),
             CACHE_TEST(test_brick_cache__overhead_bounds_entries, 64 * OVH),
             CACHE_TEST(test_brick_cache__abandon_without_waiters_removes, 1u << 20),
             CACHE_TEST(test_brick_cache__abandon_hands_reservation_to_waiter, 1u << 20),
             CACHE_TEST(test_brick_cache__waiters_get_published_entry, 1u << 20),
             CACHE_TEST(test_brick_cache__single_flight_under_concurrency, 64u << 20),
             CACHE_TEST(test_brick_cache__set_cap_lowering_evicts, 1u << 20),
             CACHE_TEST(test_brick_cache__clear_keeps_pinned, 1u << 20),
             CACHE_TEST(test_brick_cache__random_stress, ST_CAP))

/* test_pool.c — the producer pool (pool.h): every index once, whatever the thread count, the
 * caller working or not (niced pools spawn every thread and the caller only waits); the first
 * negative result is returned; bad arguments are refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_err.h"
#include "pool.h"

enum { N = 10000 };

typedef struct {
  atomic_int hits[N];
  int threads;
  atomic_int bad_worker;
} run_t;

static int count(void *ctx, size_t i, int worker) {
  run_t *r = ctx;
  atomic_fetch_add(&r->hits[i], 1);
  if (worker < 0 || worker >= r->threads) atomic_store(&r->bad_worker, 1);
  return i == 4321 ? OC_EIO : 0;
}

static void each_once(int threads, int nice) {
  ocs_pool_t *p = NULL;
  assert_int_equal(ocs_pool_create_niced(&p, threads, nice), 0);
  static run_t r;
  for (int i = 0; i < N; i++) atomic_store(&r.hits[i], 0);
  r.threads = ocs_pool_threads(p);
  atomic_store(&r.bad_worker, 0);
  assert_true(r.threads >= 1 && r.threads <= threads);
  assert_int_equal(ocs_pool_run(p, N, count, &r), OC_EIO); /* the one failure, the rest done */
  for (int i = 0; i < N; i++) assert_int_equal(atomic_load(&r.hits[i]), 1);
  assert_int_equal(atomic_load(&r.bad_worker), 0);
  assert_int_equal(ocs_pool_run(p, 0, count, &r), 0);
  ocs_pool_free(p);
}

static void test_pool__every_index_once(void **st) {
  (void)st;
  each_once(1, 0);
  each_once(3, 0);
  each_once(1, 10); /* one spawned worker, the caller waits */
  each_once(3, 10);
}

static void test_pool__bad_arguments(void **st) {
  (void)st;
  ocs_pool_t *p = NULL;
  assert_int_equal(ocs_pool_create_niced(NULL, 2, 0), OC_EINVAL);
  assert_int_equal(ocs_pool_create_niced(&p, -1, 0), OC_EINVAL);
  assert_int_equal(ocs_pool_create_niced(&p, 2, -1), OC_EINVAL);
  assert_int_equal(ocs_pool_create_niced(&p, 2, 20), OC_EINVAL);
  assert_null(p);
  assert_int_equal(ocs_pool_run(NULL, 1, count, NULL), OC_EINVAL);
  assert_int_equal(ocs_pool_create(&p, 2), 0);
  assert_int_equal(ocs_pool_run(p, 1, NULL, NULL), OC_EINVAL);
  ocs_pool_free(p);
  ocs_pool_free(NULL);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_pool__every_index_once),
             cmocka_unit_test(test_pool__bad_arguments))

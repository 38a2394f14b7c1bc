/* test_histogram.c — fixed-bucket histograms (histogram.h): values land in the first bucket whose
 * upper bound holds them (bounds inclusive, as Prometheus' "le"), the read is cumulative with the
 * sum and the count, NaN is ignored, and adds from several threads are all counted. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <pthread.h>

#include "test_main.h"
#include "histogram.h"

static void test_histogram__buckets_and_read(void **st) {
  (void)st;
  ocs_hist_t h;
  ocs_hist_init(&h, ocs_hist_seconds);
  ocs_hist_observe(&h, 0.0);   /* ≤ 1e-4 */
  ocs_hist_observe(&h, 1e-4);  /* on a bound: that bucket */
  ocs_hist_observe(&h, 0.002); /* ≤ 3e-3 */
  ocs_hist_observe(&h, 100.0); /* above every bound: only in the count */
  ocs_hist_observe(&h, NAN);
  ocs_hist_view_t v;
  ocs_hist_read(&h, &v);
  assert_ptr_equal(v.le, ocs_hist_seconds);
  assert_int_equal(v.n, 4);
  assert_int_equal(v.cum[0], 2);
  assert_int_equal(v.cum[1], 2);
  assert_int_equal(v.cum[2], 2);
  assert_int_equal(v.cum[3], 3);
  assert_int_equal(v.cum[OCS_HIST_BUCKETS - 1], 3);
  assert_true(fabs(v.sum - 100.0021) < 1e-9);
  for (int i = 1; i < OCS_HIST_BUCKETS; i++) assert_true(ocs_hist_seconds[i] > ocs_hist_seconds[i - 1]);
}

enum { THREADS = 4, EACH = 20000 };

static void *adder(void *arg) {
  ocs_hist_t *h = arg;
  for (int i = 0; i < EACH; i++) ocs_hist_observe(h, 0.5);
  return NULL;
}

static void test_histogram__threads(void **st) {
  (void)st;
  static ocs_hist_t h;
  ocs_hist_init(&h, ocs_hist_seconds);
  pthread_t t[THREADS];
  for (int i = 0; i < THREADS; i++) assert_int_equal(pthread_create(&t[i], NULL, adder, &h), 0);
  for (int i = 0; i < THREADS; i++) pthread_join(t[i], NULL);
  ocs_hist_view_t v;
  ocs_hist_read(&h, &v);
  assert_int_equal(v.n, THREADS * EACH);
  assert_int_equal(v.cum[8], THREADS * EACH); /* ≤ 1 s */
  assert_int_equal(v.cum[7], 0);              /* ≤ 0.3 s */
  assert_true(fabs(v.sum - 0.5 * THREADS * EACH) < 1e-6);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_histogram__buckets_and_read),
             cmocka_unit_test(test_histogram__threads))

/* test_retry.c — the reconnect policy of overcast-view and overcast-stress (client/net.h,
 * ocv_retry_t): the first wait is the server's delay, waits grow with jitter, a run gives up after
 * its attempts or its time, each attempt and the giving up say so in one line, and a WELCOME
 * starts a new run. Pure: the clock is passed in. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <string.h>

#include "test_main.h"
#include "net.h"

static void test_retry__server_delay_first_then_bounded_attempts(void **state) {
  (void)state;
  ocv_retry_t r;
  ocv_retry_init(&r, 3, 1000, 1);
  char line[256];
  double w = ocv_retry_next(&r, 1500, 100.0, "A:1: draining", line, sizeof line);
  assert_true(w == 1.5); /* the server's wish, exactly */
  assert_string_equal(line, "A:1: draining; reconnect attempt 1 of 3 in 1.50 s");
  for (int i = 2; i <= 3; i++) {
    w = ocv_retry_next(&r, 0, 100.0 + i, "A:1: refused", line, sizeof line);
    assert_true(w >= 1.5 && w <= 10.0); /* never under the server's delay, never over the cap */
    assert_non_null(strstr(line, i == 2 ? "attempt 2 of 3" : "attempt 3 of 3"));
  }
  w = ocv_retry_next(&r, 0, 110.0, "A:1: refused", line, sizeof line);
  assert_true(w < 0);
  assert_string_equal(line, "A:1: refused; gave up after 3 reconnect attempts in 10.0 s");
}

static void test_retry__gives_up_on_time(void **state) {
  (void)state;
  ocv_retry_t r;
  ocv_retry_init(&r, 100, 5.0, 2);
  char line[256];
  assert_true(ocv_retry_next(&r, 2000, 0.0, "x", line, sizeof line) == 2.0);
  /* the next wait would end past 5 s after the first failure */
  assert_true(ocv_retry_next(&r, 0, 4.0, "x", line, sizeof line) < 0);
  assert_non_null(strstr(line, "gave up after 1 reconnect attempt in 4.0 s"));
}

static void test_retry__welcome_starts_a_new_run(void **state) {
  (void)state;
  ocv_retry_t r;
  ocv_retry_init(&r, 2, 100.0, 3);
  char line[256];
  assert_true(ocv_retry_next(&r, 0, 0.0, "x", line, sizeof line) > 0);
  assert_true(ocv_retry_next(&r, 0, 1.0, "x", line, sizeof line) > 0);
  ocv_retry_done(&r);
  double w = ocv_retry_next(&r, 0, 50.0, "x", line, sizeof line);
  assert_true(w == OC_BACKOFF_MIN_MS / 1e3); /* no server delay: the floor */
  assert_non_null(strstr(line, "attempt 1 of 2"));
  /* a drain's delay asked again mid-run is never cut short */
  w = ocv_retry_next(&r, 4000, 51.0, "x", line, sizeof line);
  assert_true(w >= 4.0);
}

static void test_retry__defaults_and_fatal_codes(void **state) {
  (void)state;
  ocv_retry_t r;
  ocv_retry_init(&r, 0, 0, 0);
  assert_int_equal(r.max_attempts, OCV_RETRY_ATTEMPTS);
  assert_true(r.max_s == OCV_RETRY_S);
  assert_true(ocv_retry_fatal(OCP_CODE_TOKEN) && ocv_retry_fatal(OCP_CODE_VERSION) && ocv_retry_fatal(OCP_CODE_KICKED));
  assert_false(ocv_retry_fatal(OCP_CODE_RECONNECT) || ocv_retry_fatal(-1) || ocv_retry_fatal(OCP_CODE_SHUTDOWN));
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_retry__server_delay_first_then_bounded_attempts),
             cmocka_unit_test(test_retry__gives_up_on_time),
             cmocka_unit_test(test_retry__welcome_starts_a_new_run),
             cmocka_unit_test(test_retry__defaults_and_fatal_codes))

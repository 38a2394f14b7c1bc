/* test_world_clock.c — world time from the instant and the control history (world_clock.h):
 * closed forms of W(u) through set, scale, pause and resume; bad input; a full history; and the
 * world's two clocks — the virtual one of stepped mode (T0 + n·P·scale) and epoch n at its due
 * instant n·P, whenever it is stepped. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "test_main.h"
#include "oc_err.h"
#include "oc_scene.h"
#include "world.h"
#include "world_clock.h"

static ocs_clock_t clk; /* 32 KiB: not on the stack */

static void test_clock__closed_forms(void **st) {
  (void)st;
  ocs_clock_init(&clk, 100.0, 5.0);
  assert_true(ocs_clock_world(&clk, 100.0) == 5.0);
  assert_true(ocs_clock_world(&clk, 110.0) == 15.0);
  assert_true(ocs_clock_world(&clk, 50.0) == 5.0); /* before the start: the start */
  assert_int_equal(ocs_clock_set(&clk, 110.0, NAN, 2.0), 0);
  assert_true(ocs_clock_world(&clk, 115.0) == 25.0);
  assert_true(ocs_clock_world(&clk, 105.0) == 10.0); /* the past keeps its history */
  assert_int_equal(ocs_clock_pause(&clk, 120.0), 0);
  assert_true(ocs_clock_world(&clk, 120.0) == 35.0 && ocs_clock_world(&clk, 200.0) == 35.0);
  assert_true(ocs_clock_scale(&clk, 150.0) == 0.0);
  assert_int_equal(ocs_clock_resume(&clk, 200.0), 0);
  assert_true(ocs_clock_world(&clk, 210.0) == 55.0); /* back to 2, the last non-zero scale */
  assert_int_equal(ocs_clock_set(&clk, 210.0, 1000.0, NAN), 0);
  assert_true(ocs_clock_world(&clk, 211.0) == 1002.0);
  assert_int_equal(ocs_clock_set(&clk, 150.0, 0.0, NAN), 0); /* before the newest: taken at 210 */
  assert_true(ocs_clock_world(&clk, 211.0) == 2.0 && ocs_clock_world(&clk, 205.0) == 45.0);
}

static void test_clock__bad_input(void **st) {
  (void)st;
  ocs_clock_init(&clk, 0.0, 0.0);
  assert_int_equal(ocs_clock_set(&clk, 1.0, NAN, -1.0), OC_EINVAL);
  assert_int_equal(ocs_clock_set(&clk, 1.0, NAN, 2e6), OC_EINVAL);
  assert_int_equal(ocs_clock_set(&clk, 1.0, INFINITY, NAN), OC_EINVAL);
  assert_int_equal(ocs_clock_set(&clk, 1.0, 2e12, NAN), OC_EINVAL);
  assert_int_equal(ocs_clock_set(&clk, NAN, 1.0, NAN), OC_EINVAL);
  assert_int_equal(clk.n, 1); /* nothing recorded */
  assert_true(ocs_clock_world(&clk, 3.0) == 3.0);
}

/* Past OCS_CLOCK_MAX entries the oldest go; the clock stays right from the newest on. */
static void test_clock__full_history(void **st) {
  (void)st;
  ocs_clock_init(&clk, 0.0, 0.0);
  for (int i = 1; i <= 3 * OCS_CLOCK_MAX; i++) assert_int_equal(ocs_clock_set(&clk, (double)i, NAN, (i % 2) ? 2.0 : 1.0), 0);
  assert_int_equal(clk.n, OCS_CLOCK_MAX);
  /* scale 1 on [0, 1), then 2 on [i, i+1) for odd i and 1 for even i: W(N) = 1.5·N for even N */
  double n = 3.0 * OCS_CLOCK_MAX;
  assert_true(ocs_clock_world(&clk, n) == 1.5 * n);
  assert_true(ocs_clock_world(&clk, n + 10.0) == 1.5 * n + 10.0); /* the last entry (even i): scale 1 */
  assert_true(ocs_clock_world(&clk, n - 1.0) == 1.5 * n - 2.0);   /* within what is kept */
}

static const char *SPHERE = "{\"version\":1,\"features\":{\"animation\":false},\"epoch_period\":1,"
                            "\"sources\":[{\"type\":\"sphere\",\"lat\":0,\"lon\":0,\"alt\":3000,\"radius\":2000,"
                            "\"sigma_t\":0.05}]}";

static ocs_world_t *world_at(double start_utc, double t0) {
  oc_scene_t sc;
  char why[256];
  assert_int_equal(oc_scene_parse(&sc, SPHERE, strlen(SPHERE), "sphere", why, sizeof why), 0);
  ocs_world_desc_t d = {.threads = 1, .time = t0, .start_utc = start_utc};
  ocs_world_t *w = NULL;
  assert_int_equal(ocs_world_create(&w, &sc, &d, why, sizeof why), 0);
  oc_scene_free(&sc);
  return w;
}

static double world_time(const ocs_world_t *w) {
  ocs_world_stats_t s;
  ocs_world_stats(w, &s);
  return s.time;
}

/* Stepped: T0 + n·P·scale, with control changes taking effect at the last epoch's instant, as
 * the clock of the previous releases did. */
static void test_clock__virtual(void **st) {
  (void)st;
  ocs_world_t *w = world_at(0.0, 100.0);
  for (int i = 0; i < 3; i++) assert_int_equal(ocs_world_step(w), 0);
  assert_true(world_time(w) == 103.0 && ocs_world_utc(w) == 3.0);
  assert_int_equal(ocs_world_set_time_scale(w, ocs_world_utc(w), 2.0), 0);
  assert_int_equal(ocs_world_step(w), 0);
  assert_true(world_time(w) == 105.0);
  assert_int_equal(ocs_world_pause(w, ocs_world_utc(w)), 0);
  assert_int_equal(ocs_world_step(w), 0);
  assert_true(world_time(w) == 105.0);
  assert_int_equal(ocs_world_resume(w, ocs_world_utc(w)), 0);
  assert_int_equal(ocs_world_step(w), 0);
  assert_true(world_time(w) == 107.0);
  assert_int_equal(ocs_world_set_time(w, ocs_world_utc(w), 3600.0), 0);
  assert_true(world_time(w) == 3600.0); /* shows at once */
  assert_int_equal(ocs_world_step(w), 0);
  assert_true(world_time(w) == 3602.0);
  ocs_world_free(w);
}

/* Clocked: epoch n takes W(n·P), the instant it was due, however late it is stepped; a skipped
 * epoch changes nothing of the next one's time. */
static void test_clock__due_instant(void **st) {
  (void)st;
  double start = 1.7e9 + 0.25; /* a server started a quarter second into a period */
  ocs_world_t *w = world_at(start, 10.0);
  uint64_t n = (uint64_t)floor(start) + 1;
  assert_int_equal(ocs_world_step_at(w, n, (double)n), 0);
  assert_true(fabs(world_time(w) - 10.75) < 1e-6);
  assert_int_equal(ocs_world_step_at(w, n + 3, (double)(n + 3)), 0); /* two epochs skipped */
  assert_true(fabs(world_time(w) - 13.75) < 1e-6);
  assert_int_equal(ocs_world_step_at(w, n + 3, (double)(n + 3)), OC_EINVAL); /* not after the last */
  assert_true(fabs(ocs_world_time_at(w, (double)(n + 5)) - 15.75) < 1e-6);
  ocs_world_free(w);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_clock__closed_forms), cmocka_unit_test(test_clock__bad_input),
             cmocka_unit_test(test_clock__full_history), cmocka_unit_test(test_clock__virtual),
             cmocka_unit_test(test_clock__due_instant))

/* test_backoff.c — reconnect delays (common/oc_backoff.c): the server's delay first, the floor, a
 * ceiling that doubles up to the cap, jitter within it and repeatable under a seed. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_backoff.h"

static void test_backoff__first_is_the_servers_delay_floored(void **state) {
  (void)state;
  oc_backoff_t b;
  oc_backoff_init(&b, 1000, 1);
  assert_int_equal(oc_backoff_next(&b), 1000);
  oc_backoff_init(&b, 0, 1); /* a lost connection: no delay asked */
  assert_int_equal(oc_backoff_next(&b), OC_BACKOFF_MIN_MS);
  oc_backoff_init(&b, 60000, 1); /* more than the cap: the cap */
  assert_int_equal(oc_backoff_next(&b), OC_BACKOFF_CAP_MS);
}

static void test_backoff__bounds_growth_and_cap(void **state) {
  (void)state;
  for (uint64_t seed = 1; seed <= 50; seed++) {
    oc_backoff_t b;
    oc_backoff_init(&b, 300, seed);
    uint64_t ceil = 300;
    oc_backoff_next(&b);
    for (int n = 1; n < 40; n++) {
      ceil = ceil * 2 > OC_BACKOFF_CAP_MS ? OC_BACKOFF_CAP_MS : ceil * 2;
      uint32_t d = oc_backoff_next(&b);
      assert_true(d >= 300 && d <= ceil);
    }
  }
  /* the ceiling grows: the largest of many draws at attempt n nears 300·2ⁿ, then the cap */
  uint32_t maxes[8] = {0};
  for (uint64_t seed = 1; seed <= 400; seed++) {
    oc_backoff_t b;
    oc_backoff_init(&b, 300, seed);
    for (int n = 0; n < 8; n++) {
      uint32_t d = oc_backoff_next(&b);
      if (d > maxes[n]) maxes[n] = d;
    }
  }
  for (int n = 1; n < 8; n++) {
    uint32_t c = 300u << n < OC_BACKOFF_CAP_MS ? 300u << n : OC_BACKOFF_CAP_MS;
    assert_true(maxes[n] > c - (c - 300) / 10); /* within the top tenth of the window */
  }
}

static void test_backoff__jitter_seeded(void **state) {
  (void)state;
  oc_backoff_t a, b, c;
  oc_backoff_init(&a, 500, 42);
  oc_backoff_init(&b, 500, 42);
  oc_backoff_init(&c, 500, 43);
  int differ = 0;
  for (int n = 0; n < 20; n++) {
    uint32_t x = oc_backoff_next(&a), y = oc_backoff_next(&b), z = oc_backoff_next(&c);
    assert_int_equal(x, y);
    differ += x != z;
  }
  assert_true(differ > 10); /* another seed, other delays: clients spread out */
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_backoff__first_is_the_servers_delay_floored),
             cmocka_unit_test(test_backoff__bounds_growth_and_cap),
             cmocka_unit_test(test_backoff__jitter_seeded))

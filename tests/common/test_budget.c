/* test_budget.c — the budget contract (common/oc_budget.h): the minimum window and the atlas size
 * follow the granted slot bytes, record bytes and K, with the records taken off. Pure: no GPU. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_budget.h"

static void test_budget__one_definition(void **state) {
  (void)state;
  assert_int_equal(OC_SLOT_BYTES, 2048); /* 8³ voxels × 2 channels × u16 */
  assert_int_equal(OC_RECORD_BYTES, 32);
}

static void test_budget__minimum_is_the_root_in_each_state(void **state) {
  (void)state;
  oc_budget_t b = {.budget = 1, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  assert_int_equal(oc_budget_min(&b), 6240); /* docs/protocol.md, "Grant" */
  b.kept_states = 2;
  assert_int_equal(oc_budget_min(&b), 4160);
}

/* The atlas size: n·(slot + record) ≤ budget, the largest such n. */
static void test_budget__slots_follow_the_grant(void **state) {
  (void)state;
  oc_budget_t b = {.budget = 4u << 20, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  uint32_t n = oc_budget_slots(&b);
  assert_int_equal(n, 2016); /* 4 MiB / 2080, not 4 MiB / 2048 = 2048 */
  assert_true((uint64_t)n * (2048 + 32) <= b.budget && (uint64_t)(n + 1) * (2048 + 32) > b.budget);
  b.slot_bytes = 4096; /* a viewer that spends twice as much per brick gets about half the slots */
  assert_int_equal(oc_budget_slots(&b), (4u << 20) / (4096 + 32));
  b.record_bytes = 1024; /* and fat records take their share off */
  assert_int_equal(oc_budget_slots(&b), (4u << 20) / (4096 + 1024));
}

static void test_budget__edges(void **state) {
  (void)state;
  oc_budget_t b = {.budget = 6240, .slot_bytes = OC_SLOT_BYTES, .record_bytes = OC_RECORD_BYTES, .kept_states = 3};
  assert_int_equal(oc_budget_slots(&b), 3); /* the minimum: the root in each of the 3 states, 3 bricks at most */
  b.kept_states = 2;
  assert_int_equal(oc_budget_slots(&b), 3); /* K does not change the size, only the minimum */
  b.kept_states = 3;
  b.budget = 6239;
  assert_int_equal(oc_budget_slots(&b), 0); /* below the minimum: no window fits */
  b.budget = UINT64_MAX;
  b.slot_bytes = b.record_bytes = 1;
  assert_int_equal(oc_budget_slots(&b), UINT32_MAX); /* clamped, never wrapped */
  oc_budget_t zero = {.budget = 1u << 20, .slot_bytes = 0, .record_bytes = 32, .kept_states = 3};
  assert_int_equal(oc_budget_slots(&zero), 0);
  zero.slot_bytes = 2048;
  zero.kept_states = 0;
  assert_int_equal(oc_budget_slots(&zero), 0);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_budget__one_definition),
             cmocka_unit_test(test_budget__minimum_is_the_root_in_each_state),
             cmocka_unit_test(test_budget__slots_follow_the_grant),
             cmocka_unit_test(test_budget__edges))

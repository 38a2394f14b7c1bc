/* test_main.h — the main() of a cmocka test program (header-only). */
#ifndef OC_TESTS_MAIN_H
#define OC_TESTS_MAIN_H

/* Runs the listed tests as one group, with group setup and teardown (NULL for none):
 *   OC_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_a), cmocka_unit_test(test_b))
 * The file includes <cmocka.h> (and what it needs) itself. */
#define OC_TEST_MAIN(group_setup, group_teardown, ...)            \
  int main(void) {                                                \
    const struct CMUnitTest tests[] = {__VA_ARGS__};              \
    return cmocka_run_group_tests(tests, group_setup, group_teardown); \
  }

#endif /* OC_TESTS_MAIN_H */

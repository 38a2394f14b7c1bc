/* test_prom_text.c — the Prometheus text format writer (server/prom_text.c): numbers that read back
 * exactly, escaping of HELP texts and label values, histograms cumulative with +Inf equal to the
 * count. The end-to-end scrape (promtool) is tests/net/test_metrics.c. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "prom_text.h"

/* The buffer's text (NUL-terminated in place). */
static const char *text(oc_buf_t *b) {
  oc_buf_u8(b, 0);
  b->len--;
  assert_false(b->err);
  return (const char *)b->data;
}

static void test_prom_text__numbers(void **state) {
  (void)state;
  static const struct {
    double v;
    const char *want;
  } cases[] = {{0, "0"},          {12345, "12345"},         {1e-4, "0.0001"},        {3e-4, "0.0003"},
               {0.1, "0.1"},      {-2.5, "-2.5"},           {1e300, "1e+300"},       {9007199254740993.0, "9007199254740992"},
               {INFINITY, "+Inf"}, {-INFINITY, "-Inf"}};
  char out[40];
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    ocs_prom_number(out, sizeof out, cases[i].v);
    assert_string_equal(out, cases[i].want);
  }
  ocs_prom_number(out, sizeof out, NAN);
  assert_string_equal(out, "NaN");
  /* whatever the digits, a number reads back as itself (17 significant digits where 15 do not) */
  static const double hard[] = {0.1 + 0.2, 1.0 / 3.0, 2.2250738585072014e-308, 4.9e-324, 1.7976931348623157e308};
  for (size_t i = 0; i < sizeof hard / sizeof hard[0]; i++) {
    ocs_prom_number(out, sizeof out, hard[i]);
    assert_true(strtod(out, NULL) == hard[i]);
  }
}

static void test_prom_text__family_and_samples(void **state) {
  (void)state;
  oc_buf_t b = {0};
  ocs_prom_family(&b, "overcast_x_total", "counter", "A \\ path\nand a \"quote\".");
  ocs_prom_sample(&b, "overcast_x_total", NULL, NULL, 3);
  ocs_prom_sample(&b, "overcast_x_total", "reason", "a\\b\"c\nd", 0.5);
  assert_string_equal(text(&b), "# HELP overcast_x_total A \\\\ path\\nand a \"quote\".\n"
                                "# TYPE overcast_x_total counter\n"
                                "overcast_x_total 3\n"
                                "overcast_x_total{reason=\"a\\\\b\\\"c\\nd\"} 0.5\n");
  oc_buf_free(&b);
}

static void test_prom_text__histogram(void **state) {
  (void)state;
  ocs_hist_t h;
  ocs_hist_init(&h, ocs_hist_seconds);
  static const double obs[] = {5e-5, 2e-3, 2e-3, 0.5, 100.0}; /* the last above every bound */
  for (size_t i = 0; i < sizeof obs / sizeof obs[0]; i++) ocs_hist_observe(&h, obs[i]);
  ocs_hist_view_t v;
  ocs_hist_read(&h, &v);
  oc_buf_t b = {0};
  ocs_prom_histogram(&b, "overcast_t_seconds", "T.", &v);
  const char *t = text(&b);
  static const char *lines[] = {"# HELP overcast_t_seconds T.\n# TYPE overcast_t_seconds histogram\n",
                                 "overcast_t_seconds_bucket{le=\"0.0001\"} 1\n", "overcast_t_seconds_bucket{le=\"0.001\"} 1\n",
                                 "overcast_t_seconds_bucket{le=\"0.003\"} 3\n", "overcast_t_seconds_bucket{le=\"1\"} 4\n",
                                 "overcast_t_seconds_bucket{le=\"60\"} 4\n", "overcast_t_seconds_bucket{le=\"+Inf\"} 5\n",
                                 "overcast_t_seconds_count 5\n"};
  for (size_t i = 0; i < sizeof lines / sizeof lines[0]; i++)
    if (!strstr(t, lines[i])) fail_msg("no line %s in:\n%s", lines[i], t);
  double sum = strtod(strstr(t, "overcast_t_seconds_sum ") + strlen("overcast_t_seconds_sum "), NULL);
  assert_true(fabs(sum - (5e-5 + 4e-3 + 0.5 + 100.0)) < 1e-12);
  /* every bucket line, in ascending order of le, never decreasing */
  int nbuckets = 0;
  double last = -1;
  for (const char *p = strstr(t, "_bucket{"); p; p = strstr(p + 1, "_bucket{")) {
    double c = strtod(strchr(p, '}') + 2, NULL);
    assert_true(c >= last);
    last = c;
    nbuckets++;
  }
  assert_int_equal(nbuckets, OCS_HIST_BUCKETS + 1);
  oc_buf_free(&b);
  /* a histogram never set up (a world that does not exist): only +Inf, sum and count */
  ocs_hist_view_t none = {0};
  ocs_prom_histogram(&b, "overcast_u_seconds", "U.", &none);
  t = text(&b);
  assert_non_null(strstr(t, "overcast_u_seconds_bucket{le=\"+Inf\"} 0\novercast_u_seconds_sum 0\novercast_u_seconds_count 0\n"));
  oc_buf_free(&b);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_prom_text__numbers),
             cmocka_unit_test(test_prom_text__family_and_samples),
             cmocka_unit_test(test_prom_text__histogram))

/* report.h — stability-suite rows for docs/numerics.md.
 *
 * A test that checks a numerical guard also reports what it measured against its bound. With
 * OC_REPORT_OUT set (scripts/gen-numerics.sh sets it), each call appends one Markdown table row
 * "| suite | case | measured | bound | verdict |" to that file; otherwise it does nothing. The verdict
 * is computed here from the same values the test asserts on. */
#ifndef OC_TESTS_REPORT_H
#define OC_TESTS_REPORT_H

#include <stdio.h>
#include <stdlib.h>

static inline void oc_report_cmp(const char *suite, const char *name, double measured, int above, double bound,
                                 const char *unit) {
  const char *path = getenv("OC_REPORT_OUT");
  if (!path || !*path) return;
  FILE *f = fopen(path, "a");
  if (!f) return;
  int ok = above ? measured > bound : measured < bound;
  fprintf(f, "| %s | %s | %.3g %s | %s %.3g %s | %s |\n", suite, name, measured, unit, above ? ">" : "<", bound, unit,
          ok ? "pass" : "FAIL");
  fclose(f);
}
/* A quantity that must stay below its bound (an error). */
static inline void oc_report(const char *suite, const char *name, double measured, double bound, const char *unit) {
  oc_report_cmp(suite, name, measured, 0, bound, unit);
}
/* A quantity that must exceed its bound (showing that the unguarded form fails). */
static inline void oc_report_above(const char *suite, const char *name, double measured, double bound, const char *unit) {
  oc_report_cmp(suite, name, measured, 1, bound, unit);
}

#endif /* OC_TESTS_REPORT_H */

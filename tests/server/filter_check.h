/* filter_check.h — the Conventions' test of the box filter on one node, for any σt source
 * (header-only, after cmocka.h, test_util.h and report.h). Two measures, both relative to the node's peak σt
 * (what a viewer sees as brightness):
 *  - exactness: the 512 samples' footprints tile the node's extended cube (edge 8/7 of the node),
 *    so their plain mean is the true mean of σt over it (truth by n³ point quadrature);
 *  - the node's mean (trapezoid weights over its own cube, oc_test_node_mean) against its 8 and
 *    64 descendants'. */
#ifndef OC_TESTS_SERVER_FILTER_CHECK_H
#define OC_TESTS_SERVER_FILTER_CHECK_H

#include <math.h>
#include <stdio.h>

#include "oc_key.h"

typedef struct {
  const void *ctx;
  void (*sample)(const void *ctx, oc_key_t key, float out[512]); /* at t = 0; fails the test on error */
  double (*point)(const void *ctx, oc_dvec3 p);                  /* σt at p, t = 0 */
} filter_src_t;

typedef struct {
  double plain, truth, peak; /* the samples' plain mean, the true mean over the extended cube, the peak sample */
  double m0, m1, m2;         /* the node's mean, its 8 children's, its 64 grandchildren's */
  double exact, desc;        /* |plain − truth| and max |m1|2 − m0|, relative to the peak */
} filter_check_t;

/* The mean of the node's descendants `depth` levels down (0: the node's own). */
static inline double filter_descendants_mean(const filter_src_t *src, oc_key_t key, int depth) {
  if (depth == 0) {
    float s[512];
    src->sample(src->ctx, key, s);
    return oc_test_node_mean(s);
  }
  double m = 0.0;
  for (int c = 0; c < 8; c++) m += filter_descendants_mean(src, oc_key_child(key, c), depth - 1) / 8.0;
  return m;
}

static inline filter_check_t filter_check(const filter_src_t *src, oc_key_t key, int n) {
  filter_check_t r = {0};
  float s[512];
  src->sample(src->ctx, key, s);
  for (int i = 0; i < 512; i++) {
    r.plain += s[i] / 512.0;
    r.peak = fmax(r.peak, s[i]);
  }
  oc_dvec3 o;
  double size;
  oc_key_bounds(key, &o, &size);
  double h = size / 7.0, e = 8.0 * h;
  for (int z = 0; z < n; z++)
    for (int y = 0; y < n; y++)
      for (int x = 0; x < n; x++)
        r.truth += src->point(src->ctx, oc_dv3(o.x - h / 2 + (x + 0.5) * e / n, o.y - h / 2 + (y + 0.5) * e / n,
                                               o.z - h / 2 + (z + 0.5) * e / n));
  r.truth /= (double)n * n * n;
  r.m0 = oc_test_node_mean(s);
  r.m1 = filter_descendants_mean(src, key, 1);
  r.m2 = filter_descendants_mean(src, key, 2);
  r.exact = fabs(r.plain - r.truth) / r.peak;
  r.desc = fmax(fabs(r.m1 - r.m0), fabs(r.m2 - r.m0)) / r.peak;
  return r;
}

/* The worst of both measures over a test's nodes. */
typedef struct {
  double exact, desc;
} filter_worst_t;

static inline void filter_worst_add(filter_worst_t *w, const filter_check_t *r) {
  w->exact = fmax(w->exact, r->exact);
  w->desc = fmax(w->desc, r->desc);
}

/* Reports the worst measures of the nodes of `what` at `levels` (suite "filtering") and checks
 * them: exactness within exact_max, descendants within the Conventions' 1e-2. */
static inline void filter_worst_check(const filter_worst_t *w, const char *what, const char *levels, double exact_max) {
  char row[256];
  snprintf(row, sizeof row, "%s: box-filtered samples' mean vs true mean, %s", what, levels);
  oc_report("filtering", row, w->exact, exact_max, "of peak");
  snprintf(row, sizeof row, "%s: parent mean vs 8 and 64 descendants, %s", what, levels);
  oc_report("filtering", row, w->desc, 1e-2, "of peak");
  assert_true(w->exact < exact_max);
  assert_true(w->desc < 1e-2);
}

#endif /* OC_TESTS_SERVER_FILTER_CHECK_H */

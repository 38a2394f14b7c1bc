/* histogram.c — fixed-bucket histograms (histogram.h). */
#include "histogram.h"

#include <math.h>

const double ocs_hist_seconds[OCS_HIST_BUCKETS] = {1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1,
                                                   0.3,  1.0,  3.0,  10.0, 20.0, 40.0, 60.0};

void ocs_hist_init(ocs_hist_t *h, const double *le) {
  h->le = le;
  for (int i = 0; i <= OCS_HIST_BUCKETS; i++) atomic_init(&h->count[i], 0);
  atomic_init(&h->sum, 0.0);
}

void ocs_hist_observe(ocs_hist_t *h, double v) {
  if (isnan(v)) return;
  int i = 0;
  while (i < OCS_HIST_BUCKETS && v > h->le[i]) i++;
  atomic_fetch_add_explicit(&h->count[i], 1, memory_order_relaxed);
  double s = atomic_load_explicit(&h->sum, memory_order_relaxed);
  while (!atomic_compare_exchange_weak_explicit(&h->sum, &s, s + v, memory_order_relaxed, memory_order_relaxed)) {
  }
}

void ocs_hist_read(const ocs_hist_t *h, ocs_hist_view_t *out) {
  uint64_t c = 0;
  out->le = h->le;
  for (int i = 0; i < OCS_HIST_BUCKETS; i++) {
    c += atomic_load_explicit(&h->count[i], memory_order_relaxed);
    out->cum[i] = c;
  }
  out->n = c + atomic_load_explicit(&h->count[OCS_HIST_BUCKETS], memory_order_relaxed);
  out->sum = atomic_load_explicit(&h->sum, memory_order_relaxed);
}

/* histogram.h — a fixed-bucket histogram of seconds, safe to add to from many threads (producer
 * threads time their bricks; the loop thread times its ticks), read as Prometheus reads one:
 * counts per upper bound ("le"), cumulative when written, with the sum and the count. */
#ifndef OC_SERVER_HISTOGRAM_H
#define OC_SERVER_HISTOGRAM_H

#include <stdatomic.h>
#include <stdint.h>

#define OCS_HIST_BUCKETS 14 /* finite upper bounds; +Inf is the count */

typedef struct {
  const double *le;                          /* OCS_HIST_BUCKETS ascending upper bounds */
  _Atomic uint64_t count[OCS_HIST_BUCKETS + 1]; /* per bucket (not cumulative); the last: above every bound */
  _Atomic double sum;
} ocs_hist_t;

/* A copy to read: cum[i] observations ≤ le[i] (cumulative), n in all. */
typedef struct {
  const double *le;
  uint64_t cum[OCS_HIST_BUCKETS], n;
  double sum;
} ocs_hist_view_t;

/* Bounds for seconds from 100 µs to 60 s (bricks, ticks and their lateness). */
extern const double ocs_hist_seconds[OCS_HIST_BUCKETS];

void ocs_hist_init(ocs_hist_t *h, const double *le);
/*! ocs_hist_observe() : counts one value (NaN is ignored). */
void ocs_hist_observe(ocs_hist_t *h, double v);
void ocs_hist_read(const ocs_hist_t *h, ocs_hist_view_t *out);

#endif /* OC_SERVER_HISTOGRAM_H */

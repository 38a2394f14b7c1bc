/* stress_clock.c — overcast-stress's accounting of epochs on the clock, the parts that read no
 * clock and so are tested as they are (tests/stress/test_stress_clock.c):
 *
 *   ticks       lateness (EPOCH_BEGIN readable minus n·P) and coalesced ticks (indices skipped
 *               between a viewer's consecutive states), per viewer;
 *   frame scan  the headers of a viewer's byte stream, to see each EPOCH_BEGIN when it is readable
 *               (the session itself reports a state only when it is complete);
 *   stamp scan  the distinct content stamps of a level at the epochs before a world time: steps s,
 *               s − 1, s − 2, .. of docs/architecture.md's content age;
 *   matching    a reproduced brick against what was received (ranges, and the codes' digest);
 *   ages        the histogram of verified ages per level, its quantiles and mismatches;
 *   samples     growing arrays of doubles and their nearest-rank quantiles. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "oc.h"
#include "stress.h"

/*-*** Samples ***/

int stress_samples_add(stress_samples_t *s, double x) {
  double *nv = oc_grow(s->v, &s->cap, s->n, sizeof *nv, 64);
  if (!nv) return OC_ENOMEM;
  s->v = nv;
  s->v[s->n++] = x;
  return 0;
}

void stress_samples_free(stress_samples_t *s) {
  free(s->v);
  memset(s, 0, sizeof *s);
}

static int sc_cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

double stress_quantile(double *v, size_t n, double q) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, sc_cmp_double);
  size_t k = (size_t)ceil(q * (double)n);
  if (k < 1) k = 1;
  if (k > n) k = n;
  return v[k - 1];
}

/*-*** Ticks ***/

long stress_ticks_add(stress_ticks_t *t, uint64_t epoch, double begin_utc) {
  long skipped = 0;
  if (t->have) {
    if (epoch <= t->last) return -1;
    skipped = (long)(epoch - t->last - 1);
    t->coalesced += (uint64_t)skipped;
  } else {
    t->have = 1;
    t->first = epoch;
  }
  t->last = epoch;
  t->states++;
  if (isfinite(begin_utc) && t->period > 0) stress_samples_add(&t->lateness, begin_utc - (double)epoch * t->period);
  return skipped;
}

uint64_t stress_ticks_due(const stress_ticks_t *t) { return t->have ? t->last - t->first : 0; }

double stress_ticks_coalesced_frac(const stress_ticks_t *t) {
  uint64_t due = stress_ticks_due(t);
  return due ? (double)t->coalesced / (double)due : NAN;
}

void stress_ticks_free(stress_ticks_t *t) { stress_samples_free(&t->lateness); }

/*-*** The frame scan ***/

void stress_scan_feed(stress_scan_t *s, const uint8_t *p, size_t n, double utc, stress_begin_fn begin, void *ctx) {
  while (n && !s->bad) {
    if (s->nhdr < OCP_HEADER_BYTES) { /* a header, possibly split across reads */
      size_t k = (size_t)(OCP_HEADER_BYTES - s->nhdr) < n ? (size_t)(OCP_HEADER_BYTES - s->nhdr) : n;
      memcpy(s->hdr + s->nhdr, p, k);
      s->nhdr += (int)k;
      p += k;
      n -= k;
      if (s->nhdr < OCP_HEADER_BYTES) return;
      ocp_header_t h;
      if (ocp_header_parse(s->hdr, UINT32_MAX, &h) < 0) {
        s->bad = 1;
        return;
      }
      s->type = h.type;
      s->left = h.length;
      s->nhead = 0;
      if (!s->left) s->nhdr = 0;
      continue;
    }
    size_t k = s->left < n ? (size_t)s->left : n;
    if (s->type == OCP_MSG_EPOCH_BEGIN && s->nhead < (int)sizeof s->head) {
      size_t c = sizeof s->head - (size_t)s->nhead < k ? sizeof s->head - (size_t)s->nhead : k;
      memcpy(s->head + s->nhead, p, c);
      s->nhead += (int)c;
      if (s->nhead == (int)sizeof s->head && begin) begin(ctx, oc_get_u64(s->head), oc_get_f64(s->head + 8), utc);
    }
    p += k;
    n -= k;
    s->left -= k;
    if (!s->left) s->nhdr = 0; /* the next header */
  }
}

/*-*** The stamp scan ***/

int stress_stamp_scan(stress_stamp_fn f, void *ctx, int level, double t, double dt, int max_epochs, int want, double *times,
                      uint64_t *stamps) {
  if (want < 1) return 0;
  times[0] = t;
  stamps[0] = f(ctx, level, t);
  int found = 1;
  if (!(dt > 0)) return found;
  for (int j = 1; j <= max_epochs && found < want; j++) {
    double tj = t - (double)j * dt;
    uint64_t st = f(ctx, level, tj);
    if (st != stamps[found - 1]) { /* scanning back, the first time of a new stamp is its latest */
      times[found] = tj;
      stamps[found] = st;
      found++;
    }
  }
  return found;
}

/*-*** Time to full detail ***/

int stress_settle_feed(stress_settle_t *s, uint32_t splits, uint32_t merges, uint32_t waiting, uint32_t leaves, double t,
                       uint64_t epoch) {
  if (s->phase == 1) { /* the plan reacts to the new place: it splits or merges */
    if (splits || merges) s->phase = 2, s->quiet = 0;
    return 0;
  }
  if (s->phase != 2) return 0;
  int slot = s->quiet++ % STRESS_SETTLE_STATES;
  s->changed[slot] = (double)splits + (double)merges + (double)waiting;
  s->leaves[slot] = leaves;
  s->at[slot] = t;
  s->epoch[slot] = epoch;
  if (s->quiet < STRESS_SETTLE_STATES) return 0;
  double changed = 0.0, sum = 0.0;
  for (int i = 0; i < STRESS_SETTLE_STATES; i++) changed += s->changed[i], sum += s->leaves[i];
  if (!(changed <= STRESS_SETTLE_FRACTION * sum)) return 0;
  int first = s->quiet % STRESS_SETTLE_STATES; /* the oldest in the ring */
  s->quiet_at = s->at[first];
  s->quiet_epoch = s->epoch[first];
  s->phase = 0;
  return 1;
}

/*-*** Matching ***/

int stress_brick_matches(const stress_brick_sample_t *got, const ocs_brick_out_t *made) {
  if (made->kind != OC_NODE_BRICK) return 0;
  for (int c = 0; c < OC_CHANNELS; c++)
    if (memcmp(&got->range[c], &made->range[c], sizeof got->range[c]) != 0) return 0;
  return oc_brick_digest(&made->codes) == got->digest;
}

/*-*** Ages ***/

uint64_t stress_age_count(const stress_age_t *a, int level) {
  uint64_t n = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    if (level < 0 || l == level)
      for (int k = 0; k <= STRESS_AGE_MAX + 1; k++) n += a->n[l][k];
  return n;
}

uint64_t stress_age_mismatches(const stress_age_t *a, int level) {
  uint64_t n = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    if (level < 0 || l == level)
      n += a->n[l][STRESS_AGE_MAX + 1];
  return n;
}

int stress_age_quantile(const stress_age_t *a, int level, double q) {
  uint64_t total = stress_age_count(a, level);
  if (!total) return -1;
  uint64_t rank = (uint64_t)ceil(q * (double)total), seen = 0;
  if (rank < 1) rank = 1;
  for (int k = 0; k <= STRESS_AGE_MAX + 1; k++) {
    for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
      if (level < 0 || l == level) seen += a->n[l][k];
    if (seen >= rank) return k;
  }
  return STRESS_AGE_MAX + 1;
}

void stress_age_merge(stress_age_t *dst, const stress_age_t *src) {
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    for (int k = 0; k <= STRESS_AGE_MAX + 1; k++) dst->n[l][k] += src->n[l][k];
  dst->sampled += src->sampled;
  dst->dropped += src->dropped;
  dst->errors += src->errors;
}

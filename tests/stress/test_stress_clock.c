/* test_stress_clock.c — overcast-stress's accounting of epochs on the clock (tools/stress_clock.c),
 * the parts that read no clock: lateness and coalesced ticks from epoch indices and instants given
 * here, the frame scan over a byte stream cut at every offset, the stamp scan back over a stamp
 * function given here, matching a reproduced brick, and the age histogram's quantiles. Nothing
 * here depends on the machine's speed. */
#include <setjmp.h> /* cmocka */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "test_main.h"
#include "oc_bytes.h"
#include "oc_state.h"
#include "stress.h"

static void test_stress_clock__lateness_and_coalesced(void **state) {
  (void)state;
  stress_ticks_t t = {.period = 0.5};
  /* epoch 100 is due at 50 s; its EPOCH_BEGIN was readable at 50.012 s */
  assert_int_equal(stress_ticks_add(&t, 100, 50.012), 0);
  assert_int_equal(stress_ticks_add(&t, 101, 50.5 + 0.030), 0);
  assert_int_equal(stress_ticks_add(&t, 104, 52.0 + 0.001), 2); /* 102 and 103 coalesced */
  assert_int_equal(stress_ticks_add(&t, 105, NAN), 0);           /* EPOCH_BEGIN not seen: no lateness */
  assert_int_equal(stress_ticks_add(&t, 105, 53.0), -1);         /* not increasing: refused, not counted */
  assert_int_equal(t.states, 4);
  assert_int_equal(t.coalesced, 2);
  assert_int_equal(stress_ticks_due(&t), 5); /* 101..105 */
  assert_true(fabs(stress_ticks_coalesced_frac(&t) - 0.4) < 1e-12);
  assert_int_equal(t.lateness.n, 3);
  assert_true(fabs(t.lateness.v[0] - 0.012) < 1e-9 && fabs(t.lateness.v[1] - 0.030) < 1e-9 && fabs(t.lateness.v[2] - 0.001) < 1e-9);
  assert_true(fabs(stress_quantile(t.lateness.v, t.lateness.n, 0.99) - 0.030) < 1e-9);
  stress_ticks_free(&t);
  stress_ticks_t u = {.period = 1};
  assert_true(isnan(stress_ticks_coalesced_frac(&u))); /* nothing due */
  assert_int_equal(stress_ticks_add(&u, 7, 7.0), 0);
  assert_true(isnan(stress_ticks_coalesced_frac(&u)));
  stress_ticks_free(&u);
}

/* A frame: magic, version, type, u32 length, payload. */
static size_t put_frame(uint8_t *p, uint8_t type, const uint8_t *payload, uint32_t n) {
  p[0] = OCP_MAGIC0;
  p[1] = OCP_MAGIC1;
  p[2] = 2;
  p[3] = type;
  oc_put_u32(p + 4, n);
  if (n) memcpy(p + 8, payload, n);
  return 8 + (size_t)n;
}

typedef struct {
  int n;
  uint64_t epoch[4];
  double time[4], utc[4];
} begins_t;

static void on_begin(void *ctx, uint64_t epoch, double world_time, double utc) {
  begins_t *b = ctx;
  if (b->n < 4) {
    b->epoch[b->n] = epoch;
    b->time[b->n] = world_time;
    b->utc[b->n] = utc;
  }
  b->n++;
}

static void test_stress_clock__frame_scan(void **state) {
  (void)state;
  uint8_t stream[1024], pay[64];
  size_t n = 0;
  memset(pay, 0xAB, sizeof pay);
  n += put_frame(stream + n, OCP_MSG_KEEPALIVE, NULL, 0);
  oc_put_u64(pay, 1796000000ull);
  oc_put_f64(pay + 8, 1234.5);
  n += put_frame(stream + n, OCP_MSG_EPOCH_BEGIN, pay, 64);
  uint8_t junk[40];
  memset(junk, OCP_MSG_EPOCH_BEGIN, sizeof junk); /* payload bytes that look like a type: not a header */
  n += put_frame(stream + n, OCP_MSG_BRICKS, junk, sizeof junk);
  oc_put_u64(pay, 1796000003ull);
  oc_put_f64(pay + 8, -2.25);
  size_t second = n;
  n += put_frame(stream + n, OCP_MSG_EPOCH_BEGIN, pay, 64);
  n += put_frame(stream + n, OCP_MSG_STATS, junk, 20);
  /* whole, then cut in two at every offset: the same two EPOCH_BEGINs; the second one is timed by
   * the read that completed its first 16 payload bytes */
  for (size_t cut = 0; cut <= n; cut++) {
    stress_scan_t sc;
    memset(&sc, 0, sizeof sc);
    begins_t b = {0};
    stress_scan_feed(&sc, stream, cut, 10.0, on_begin, &b);
    stress_scan_feed(&sc, stream + cut, n - cut, 20.0, on_begin, &b);
    assert_int_equal(b.n, 2);
    assert_int_equal(b.epoch[0], 1796000000ull);
    assert_true(b.time[0] == 1234.5);
    assert_int_equal(b.epoch[1], 1796000003ull);
    assert_true(b.time[1] == -2.25);
    assert_true(b.utc[1] == (cut >= second + 8 + 16 ? 10.0 : 20.0));
    assert_int_equal(sc.bad, 0);
    assert_int_equal(sc.nhdr, 0); /* ended on a frame boundary */
  }
  /* one byte at a time */
  stress_scan_t sc;
  memset(&sc, 0, sizeof sc);
  begins_t b = {0};
  for (size_t i = 0; i < n; i++) stress_scan_feed(&sc, stream + i, 1, (double)i, on_begin, &b);
  assert_int_equal(b.n, 2);
  assert_true(b.utc[1] == (double)(second + 8 + 15));
  /* a bad magic stops the scan */
  uint8_t bad[16] = {'X', 'Y', 2, OCP_MSG_EPOCH_BEGIN};
  memset(&sc, 0, sizeof sc);
  b.n = 0;
  stress_scan_feed(&sc, bad, sizeof bad, 0, on_begin, &b);
  stress_scan_feed(&sc, stream, n, 0, on_begin, &b);
  assert_int_equal(sc.bad, 1);
  assert_int_equal(b.n, 0);
}

/* A level's stamp changes every `step` world seconds (its time step), offset by the level. */
typedef struct {
  double step;
  int calls;
} stamps_t;

static uint64_t stamp_fn(void *ctx, int level, double t) {
  stamps_t *s = ctx;
  s->calls++;
  return 1000u * (uint64_t)level + (uint64_t)(int64_t)floor(t / s->step);
}

static void test_stress_clock__stamp_scan(void **state) {
  (void)state;
  stamps_t st = {.step = 2.5};
  double times[4];
  uint64_t stamps[4];
  /* t = 10, epochs of 1 world second: stamps change at 10, 7.5 and 5: s at 10 (step 4), s − 1 latest
   * at 9 (step 3), s − 2 latest at 7 (step 2), s − 3 at 4 */
  int n = stress_stamp_scan(stamp_fn, &st, 7, 10.0, 1.0, 64, 4, times, stamps);
  assert_int_equal(n, 4);
  assert_true(times[0] == 10.0 && times[1] == 9.0 && times[2] == 7.0 && times[3] == 4.0);
  assert_int_equal(stamps[0], 7004);
  assert_int_equal(stamps[1], 7003);
  assert_int_equal(stamps[2], 7002);
  assert_int_equal(stamps[3], 7001);
  /* a level whose content never changes within the scan: only s */
  stamps_t still = {.step = 1e9};
  st.calls = 0;
  n = stress_stamp_scan(stamp_fn, &still, 3, 1000.0, 1.0, 64, 3, times, stamps);
  assert_int_equal(n, 1);
  assert_true(times[0] == 1000.0);
  /* the scan stops at max_epochs back, and at once when paused (dt 0) */
  n = stress_stamp_scan(stamp_fn, &st, 7, 10.0, 1.0, 2, 3, times, stamps);
  assert_int_equal(n, 2);
  assert_true(times[1] == 9.0);
  st.calls = 0;
  n = stress_stamp_scan(stamp_fn, &st, 7, 10.0, 0.0, 64, 3, times, stamps);
  assert_int_equal(n, 1);
  assert_int_equal(st.calls, 1);
  /* epochs of more world time than a step: each epoch is a new stamp */
  n = stress_stamp_scan(stamp_fn, &st, 0, 100.0, 3.0, 64, 3, times, stamps);
  assert_int_equal(n, 3);
  assert_true(times[1] == 97.0 && times[2] == 94.0);
}

static void test_stress_clock__match(void **state) {
  (void)state;
  ocs_brick_out_t made;
  memset(&made, 0, sizeof made);
  made.kind = OC_NODE_BRICK;
  made.range[0] = (oc_range_t){0.01f, 2.0f};
  made.range[1] = (oc_range_t){0.5f, 40.0f};
  for (int c = 0; c < OC_CHANNELS; c++)
    for (int i = 0; i < OC_BRICK_VOXELS; i++) made.codes.code[c][i] = (uint16_t)(i * 7 + c);
  stress_brick_sample_t got = {.key = 1, .digest = oc_brick_digest(&made.codes)};
  memcpy(got.range, made.range, sizeof got.range);
  assert_int_equal(stress_brick_matches(&got, &made), 1);
  ocs_brick_out_t other = made;
  other.codes.code[1][300] ^= 1; /* one code */
  assert_int_equal(stress_brick_matches(&got, &other), 0);
  other = made;
  other.range[1].hi = 40.000004f; /* one range, by one ulp or so */
  assert_int_equal(stress_brick_matches(&got, &other), 0);
  other = made;
  other.kind = OC_NODE_UNIFORM;
  assert_int_equal(stress_brick_matches(&got, &other), 0);
}

static void test_stress_clock__ages(void **state) {
  (void)state;
  stress_age_t a;
  memset(&a, 0, sizeof a);
  assert_int_equal(stress_age_quantile(&a, -1, 0.99), -1);
  a.n[5][0] = 98;
  a.n[5][1] = 1;
  a.n[12][2] = 1;
  assert_int_equal(stress_age_count(&a, -1), 100);
  assert_int_equal(stress_age_quantile(&a, -1, 0.99), 1); /* nearest rank 99 of 100 */
  assert_int_equal(stress_age_quantile(&a, -1, 1.0), 2);
  assert_int_equal(stress_age_quantile(&a, 12, 0.5), 2);
  assert_int_equal(stress_age_quantile(&a, 7, 0.5), -1);
  assert_int_equal(stress_age_mismatches(&a, -1), 0);
  a.n[12][3] = 1;                /* older than allowed: stale, not a mismatch */
  assert_int_equal(stress_age_mismatches(&a, -1), 0);
  a.n[12][STRESS_AGE_MAX + 1] = 2; /* matched nothing */
  assert_int_equal(stress_age_mismatches(&a, -1), 2);
  assert_int_equal(stress_age_mismatches(&a, 5), 0);
  assert_int_equal(stress_age_quantile(&a, 12, 0.99), STRESS_AGE_MAX + 1);
  stress_age_t b;
  memset(&b, 0, sizeof b);
  b.sampled = 7;
  stress_age_merge(&b, &a);
  stress_age_merge(&b, &a);
  assert_int_equal(stress_age_count(&b, -1), 2 * stress_age_count(&a, -1));
  assert_int_equal(b.sampled, 7);
}

/* Feeds rows of (splits, merges, waiting, leaves) as the epochs e0, e0 + 1, ... at times t0, t0 + 1,
 * ... until s settles: @return the epoch it settled at, or -1. */
static int settle_rows(stress_settle_t *s, const uint32_t rows[][4], size_t n, double t0, int e0) {
  for (size_t i = 0; i < n; i++)
    if (stress_settle_feed(s, rows[i][0], rows[i][1], rows[i][2], rows[i][3], t0 + (double)i, (uint64_t)e0 + i)) return e0 + (int)i;
  return -1;
}

/* Time to full detail: the stepped reference's own STATS after a jump at 4 MiB (splits, merges,
 * waiting, leaves per epoch). "No split and none waiting" settled at the merge-only epoch 50,
 * while the tree went on changing for 7 more; the rule waits for three quiet states in a row and
 * takes the first's time. */
static void test_stress_clock__settle(void **state) {
  (void)state;
  static const uint32_t trace[][4] = {
      {24, 57, 0, 3417}, {24, 47, 0, 3256}, {24, 48, 0, 3088}, {24, 70, 0, 2766}, {0, 18, 0, 2640}, /* 46..50 */
      {24, 48, 0, 2472}, {24, 75, 0, 2115}, {24, 39, 0, 2010}, {12, 51, 0, 1737},                   /* 51..54 */
      {5, 0, 0, 1772},   {0, 4, 0, 1744},   {10, 0, 0, 1814},  {0, 2, 0, 1800},  {3, 0, 0, 1800}};  /* 55..59 */
  stress_settle_t s = {.phase = 1};
  assert_int_equal(settle_rows(&s, trace, sizeof trace / sizeof trace[0], 100.0, 46), 58); /* known at the fourth state of the quiet window */
  assert_true(s.quiet_epoch == 55 && s.quiet_at == 109.0); /* reached at the first */
  assert_int_equal(s.phase, 0);
  /* splits waiting for content are change too; and no reaction yet is not settling: a clocked
   * tree after a jump, waiting for a few coarse bricks (5 splits waiting, under 1 % of the old
   * tree's 2 700 leaves), has not reacted (it "settled" 1.05 s after a jump: performance.md) */
  stress_settle_t w = {.phase = 1};
  for (int i = 0; i < 5; i++) assert_int_equal(stress_settle_feed(&w, 0, 0, 5, 2700, 1.0 + i, (uint64_t)(1 + i)), 0);
  assert_int_equal(w.phase, 1);
  assert_int_equal(stress_settle_feed(&w, 0, 0, 0, 1000, 1.0, 1), 0);
  assert_int_equal(w.phase, 1);
  assert_int_equal(stress_settle_feed(&w, 24, 0, 0, 1000, 2.0, 2), 0);
  for (int i = 0; i < 5; i++) assert_int_equal(stress_settle_feed(&w, 0, 0, 200, 1000, 3.0 + i, (uint64_t)(3 + i)), 0);
  assert_int_equal(w.phase, 2);
  /* a full clocked 4 MiB tree churning in bursts (ticks 12-21 of one teleporting viewer: deferred
   * refreshes land, 24 splits, 41 merges, none): judged one state at a time, it never settled (a
   * burst above 1 % every second or third tick); over four states together it settles at once */
  static const uint32_t churn[][4] = {{48, 0, 0, 3823}, {1, 24, 0, 3662}, {48, 0, 0, 3998}, {1, 0, 0, 4005},
                                      {22, 0, 0, 4159}, {0, 41, 0, 3872}, {0, 0, 0, 3872}, {24, 29, 0, 3837},
                                      {24, 0, 0, 4005}, {0, 35, 0, 3760}};
  stress_settle_t c = {.phase = 1};
  assert_int_equal(settle_rows(&c, churn, sizeof churn / sizeof churn[0], 12.0, 12), 16);
  assert_true(c.quiet_epoch == 13 && c.quiet_at == 13.0);
  /* a stepped restructuring after a jump (epochs 30-45) stalls for two epochs (34-35: the kept
   * states are full of the old place's bricks); three states with those two in them settled at 33,
   * while the tree went on shrinking from 3 081 to 1 821 leaves until 40 */
  static const uint32_t stall[][4] = {{24, 0, 0, 3473},  {24, 36, 0, 3389}, {24, 45, 0, 3242}, {24, 47, 0, 3081},
                                      {0, 0, 0, 3081},   {0, 0, 0, 3081},   {24, 67, 0, 2780}, {24, 40, 0, 2668},
                                      {23, 77, 0, 2290}, {22, 53, 0, 2073}, {18, 54, 0, 1821}, {4, 0, 0, 1849},
                                      {0, 15, 0, 1744},  {11, 0, 0, 1821},  {0, 6, 0, 1779},   {7, 0, 0, 1828}};
  stress_settle_t d = {.phase = 1};
  assert_int_equal(settle_rows(&d, stall, sizeof stall / sizeof stall[0], 30.0, 30), 44);
  assert_int_equal(d.quiet_epoch, 41);
}

OC_TEST_MAIN(NULL, NULL,
             cmocka_unit_test(test_stress_clock__lateness_and_coalesced),
             cmocka_unit_test(test_stress_clock__frame_scan),
             cmocka_unit_test(test_stress_clock__stamp_scan),
             cmocka_unit_test(test_stress_clock__match),
             cmocka_unit_test(test_stress_clock__ages),
             cmocka_unit_test(test_stress_clock__settle))

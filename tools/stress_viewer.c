/* stress_viewer.c — one overcast-stress viewer: a thread with its own connection (client/net.h,
 * driving the sans-IO session of proto/ocp_viewer.h, which decodes each epoch, verifies its
 * checksum against EPOCH_END's and acknowledges it), flying its camera path, and checking every
 * complete state live:
 *
 *   resident bytes  counted here, independently of the session, from the records of the states the
 *                   viewer keeps (design.md, Conventions: budget): when state N completes, the window
 *                   is N and the K−1 states before it; resident = distinct brick ids referenced by
 *                   their records × the slot bytes we declared + their records × the record bytes
 *                   we declared. It must never exceed the budget granted in WELCOME, and must equal
 *                   the session's own count;
 *   checksums       a mismatch fails the session (OC_ECHECKSUM): counted and reported;
 *   skipped epochs  gaps in the epoch numbers of complete states (each one listed), next to the
 *                   server's own count of coalesced epochs from STATS;
 *   lateness        with a period: the instant each EPOCH_BEGIN was readable (CLOCK_REALTIME, seen
 *                   by the connection's input tap and stress_scan_feed) minus its due instant n·P;
 *   content age     --verify-content F: a fraction F of the bricks each state brings (ids above any
 *                   seen before) is queued, as key, ranges and the digest of its codes, for
 *                   stress_verify.c to re-produce off this thread.
 *
 * Nothing is allocated for a GPU: besides what the session keeps (K−1 states: records and, in a lean
 * session, the default, a 12-byte digest a brick instead of its 2052 bytes), a viewer keeps the
 * sorted brick ids of the K−1 previous states (4 bytes a brick) and its samples. */
#include <inttypes.h>
#include <math.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "oc.h"
#include "stress.h"

#define SV_MIB (1024.0 * 1024.0)

double stress_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

double stress_utc(void) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/*-*** Footprints: the bricks a state's records reference ***/

static int sv_cmp_u32(const void *a, const void *b) {
  uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  return (x > y) - (x < y);
}

static int sv_footprint(stress_footprint_t *f, const oc_state_t *s) {
  f->n = 0;
  f->records = s->node_count;
  for (uint32_t i = 0; i < s->node_count; i++) {
    if (s->nodes[i].kind != OC_NODE_BRICK) continue;
    if (f->n == f->cap) {
      uint32_t cap = f->cap ? 2 * f->cap : 1024;
      uint32_t *ni = realloc(f->ids, (size_t)cap * sizeof *ni);
      if (!ni) return OC_ENOMEM;
      f->ids = ni;
      f->cap = cap;
    }
    f->ids[f->n++] = s->nodes[i].brick_id;
  }
  qsort(f->ids, f->n, sizeof *f->ids, sv_cmp_u32);
  return 0;
}

/* Distinct ids over up to 3 sorted lists (a k-way merge), and the records summed. */
static uint64_t sv_resident(const stress_footprint_t *const *f, int n, uint64_t slot, uint64_t record) {
  uint32_t head[3] = {0, 0, 0};
  uint64_t distinct = 0, records = 0;
  for (int i = 0; i < n; i++) records += f[i]->records;
  for (;;) {
    int any = 0;
    uint32_t min = 0;
    for (int i = 0; i < n; i++)
      if (head[i] < f[i]->n && (!any || f[i]->ids[head[i]] < min)) {
        min = f[i]->ids[head[i]];
        any = 1;
      }
    if (!any) break;
    distinct++;
    for (int i = 0; i < n; i++)
      while (head[i] < f[i]->n && f[i]->ids[head[i]] == min) head[i]++;
  }
  return distinct * slot + records * record;
}

/*-*** Events (called from inside ocv_conn_poll) ***/

static void sv_fail(stress_viewer_t *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sv_fail(stress_viewer_t *v, const char *fmt, ...) {
  if (v->failed) return; /* the first cause is the one worth reading */
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(v->error, sizeof v->error, fmt, ap);
  va_end(ap);
  v->failed = 1;
}

static const char *sv_name(const stress_viewer_t *v) { return stress_path_name(v->path); }

/* When step `step` (1-based) was requested, or NAN. With epoch != 0, the step that made that epoch. */
static double sv_step_time(stress_run_t *run, uint64_t step, uint64_t epoch) {
  double t = NAN;
  pthread_mutex_lock(&run->mu);
  if (epoch) step = epoch > run->epoch0 ? run->step0 + epoch - run->epoch0 : 0;
  if (step >= 1 && step <= run->steps_sent) t = run->step_at[step];
  pthread_mutex_unlock(&run->mu);
  return t;
}

static uint64_t sv_bytes_in(stress_viewer_t *v);

/* --verify-content: the bricks this state brought (ids above every id seen in this session), each
 * with probability F, go to the verifier as key, ranges and the digest of the codes received. */
static void sv_sample_bricks(stress_viewer_t *v, const oc_state_t *s, int measured) {
  stress_run_t *run = v->run;
  double f = run->o->verify_content;
  if (v->have_prev && s->epoch > v->prev_epoch && s->time != v->prev_time) {
    double dt = (s->time - v->prev_time) / (double)(s->epoch - v->prev_epoch);
    pthread_mutex_lock(&run->mu);
    run->world_dt = dt;
    pthread_mutex_unlock(&run->mu);
  }
  v->prev_time = s->time;
  v->prev_epoch = s->epoch;
  v->have_prev = 1;
  uint32_t max_id = v->max_id;
  pthread_mutex_lock(&run->mu);
  int warmup = run->measure_from > 0 && !measured; /* a ramp's warm-up: not reported, not verified */
  pthread_mutex_unlock(&run->mu);
  if (!(f > 0) || !run->verify || warmup) {
    for (uint32_t i = 0; i < s->node_count; i++)
      if (s->nodes[i].kind == OC_NODE_BRICK && s->nodes[i].brick_id > max_id) max_id = s->nodes[i].brick_id;
    v->max_id = max_id;
    return;
  }
  pthread_mutex_lock(&run->mu);
  double dt = run->world_dt;
  pthread_mutex_unlock(&run->mu);
  const oc_brick_digests_t *dig = ocp_viewer_digests(ocv_conn_session(v->conn), 0);
  uint64_t threshold = f >= 1 ? UINT64_MAX : (uint64_t)(f * 18446744073709551616.0);
  for (uint32_t i = 0; i < s->node_count; i++) {
    const oc_node_t *nd = &s->nodes[i];
    if (nd->kind != OC_NODE_BRICK || nd->brick_id <= v->max_id) continue;
    if (nd->brick_id > max_id) max_id = nd->brick_id;
    v->rng ^= v->rng << 13; /* xorshift64 */
    v->rng ^= v->rng >> 7;
    v->rng ^= v->rng << 17;
    if (v->rng > threshold) continue;
    stress_brick_sample_t smp = {.key = nd->key, .t = s->time, .dt = dt, .into = measured ? &v->m_age : &v->age};
    memcpy(smp.range, nd->range, sizeof smp.range);
    if (dig) {
      int64_t k = oc_brick_digests_find(dig, nd->brick_id);
      if (k < 0) continue;
      smp.digest = dig->digests[k];
    } else {
      uint32_t lo = 0, hi = s->brick_count; /* bricks ascend by id */
      while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (s->bricks[mid].id < nd->brick_id) lo = mid + 1;
        else hi = mid;
      }
      if (lo == s->brick_count || s->bricks[lo].id != nd->brick_id) continue;
      smp.digest = oc_brick_digest(&s->bricks[lo].codes);
    }
    stress_verify_push(run->verify, &smp);
  }
  v->max_id = max_id;
}

/* The input tap: frame headers of every byte read; an EPOCH_BEGIN is timed by the read that
 * completed its first bytes (v->poll_utc: when that read's bytes were readable). */
static void sv_on_begin(void *ctx, uint64_t epoch, double world_time, double utc) {
  stress_viewer_t *v = ctx;
  (void)world_time;
  v->begin_epoch = epoch;
  v->begin_utc = utc;
  v->begin_seen = 1;
}

static void sv_tap(void *ctx, const uint8_t *p, size_t n) {
  stress_viewer_t *v = ctx;
  stress_scan_feed(&v->scan, p, n, v->poll_utc, sv_on_begin, v);
}

/* The state's epoch against the last: the first, one after a restart (its resync time), one that
 * does not increase (a protocol error), or skipped epochs (counted and listed). */
static void sv_epoch_sequence(stress_viewer_t *v, const oc_state_t *s, double t) {
  if (v->fresh) { /* the first state from a server that came back: its epochs start anew */
    v->fresh = 0;
    stress_samples_add(&v->resync, t - v->lost_at);
  } else if (v->states == 1) {
    v->first_epoch = s->epoch;
  } else if (s->epoch <= v->last_epoch) {
    v->protocol_errors++;
    sv_fail(v, "viewer %d (%s): epoch %" PRIu64 " after epoch %" PRIu64 ": epochs must increase", v->index, sv_name(v),
            s->epoch, v->last_epoch);
  } else if (s->epoch > v->last_epoch + 1) {
    for (uint64_t e = v->last_epoch + 1; e < s->epoch; e++) {
      v->skipped++;
      if (v->nskipped_list < STRESS_SKIPS_LISTED) v->skipped_list[v->nskipped_list++] = e;
    }
    if (v->run->o->verbose)
      fprintf(stderr, "overcast-stress: viewer %d (%s): skipped epoch%s %" PRIu64 "..%" PRIu64 "\n", v->index, sv_name(v),
              s->epoch - v->last_epoch > 2 ? "s" : "", v->last_epoch + 1, s->epoch - 1);
  }
}

/* The budget measure, counted here from this state and the K−1 before it, against the budget in
 * force; and against the session's own count. @return 0, or -1 (out of memory: the viewer failed). */
static int sv_budget_check(stress_viewer_t *v, const oc_state_t *s, uint64_t *resident_out) {
  int keep = v->welcome.kept_states > 1 ? v->welcome.kept_states - 1 : 1;
  if (keep > 2) keep = 2;
  if (sv_footprint(&v->fp_new, s) < 0) {
    sv_fail(v, "viewer %d: out of memory", v->index);
    return -1;
  }
  v->bricks_last = v->fp_new.n; /* brick records: a lean state carries no brick payloads */
  const stress_footprint_t *win[3] = {&v->fp_new, &v->fp[0], &v->fp[1]};
  uint64_t resident = sv_resident(win, 1 + v->nfp, OC_SLOT_BYTES, OC_RECORD_BYTES);
  stress_footprint_t spare = {0};
  if (v->nfp == keep) spare = v->fp[keep - 1];
  else v->nfp++;
  for (int i = v->nfp - 1; i > 0; i--) v->fp[i] = v->fp[i - 1];
  v->fp[0] = v->fp_new;
  v->fp_new = spare;
  v->resident_last = resident;
  if (resident > v->resident_max) v->resident_max = resident;
  /* The budget in force as the session defines it (ocp_viewer.c): a lowering that settles with
   * this state still had the old budget's last state in this window, so the window counts against
   * the budget in force before it or after it, the larger. */
  uint64_t allowed = v->budget_before > v->welcome.budget ? v->budget_before : v->welcome.budget;
  v->budget_before = v->welcome.budget;
  if (resident > allowed) {
    v->violations++;
    fprintf(stderr,
            "overcast-stress: BUDGET VIOLATION: viewer %d (%s), epoch %" PRIu64 ": resident %" PRIu64
            " bytes (%.3f MiB) > the budget in force %" PRIu64 " bytes (%.3f MiB)\n",
            v->index, sv_name(v), s->epoch, resident, resident / SV_MIB, allowed, allowed / SV_MIB);
  }
  ocp_viewer_stats_t ss;
  ocp_viewer_stats(ocv_conn_session(v->conn), &ss);
  if (ss.resident_bytes != resident) {
    if (!v->resident_mismatch)
      fprintf(stderr,
              "overcast-stress: viewer %d (%s), epoch %" PRIu64 ": resident %" PRIu64 " bytes counted here, %" PRIu64
              " by the session\n",
              v->index, sv_name(v), s->epoch, resident, ss.resident_bytes);
    v->resident_mismatch++;
  }
  *resident_out = resident;
  return 0;
}

static void sv_on_state(void *ctx, const oc_state_t *s, uint32_t bricks) {
  stress_viewer_t *v = ctx;
  stress_run_t *run = v->run;
  double t = stress_now();
  int stepped = v->welcome.epoch_period == 0;
  v->states++;
  v->new_state = 1;
  double prev_at = v->state_at;
  if (v->states > 1) stress_samples_add(&v->interval, t - prev_at);
  v->state_at = t;
  v->bricks_in += bricks;
  v->nodes_last = s->node_count;
  int deepest = -1;
  for (uint32_t i = 0; i < s->node_count; i++) {
    int l = oc_key_level(s->nodes[i].key);
    if (l > deepest) deepest = l;
  }
  v->depth_last = deepest;
  if (deepest > v->depth_max) v->depth_max = deepest;
  pthread_mutex_lock(&run->mu);
  int measured = run->measure_from > 0 && t >= run->measure_from;
  pthread_mutex_unlock(&run->mu);
  if (measured) {
    if (v->m_states) {
      stress_samples_add(&v->m_interval, t - prev_at);
      if (s->epoch > v->last_epoch + 1) v->m_skipped += s->epoch - v->last_epoch - 1;
    } else {
      v->m_t0 = t;
      v->m_bytes0 = sv_bytes_in(v);
    }
    v->m_states++;
  }
  sv_epoch_sequence(v, s, t);
  v->last_epoch = s->epoch;
  if (v->settle.phase && v->teleport_epoch == UINT64_MAX) v->teleport_epoch = s->epoch - 1;
  if (!stepped) { /* lateness and coalesced ticks */
    double begin = v->begin_seen && v->begin_epoch == s->epoch ? v->begin_utc : NAN;
    stress_ticks_add(&v->ticks, s->epoch, begin);
    if (measured) stress_ticks_add(&v->m_ticks, s->epoch, begin);
  }
  sv_sample_bricks(v, s, measured);

  uint64_t resident;
  if (sv_budget_check(v, s, &resident) < 0) return;

  /* Latencies. The first byte of this epoch was seen unless it came in one read with the last one. */
  double transfer = !v->between && v->epoch_first_byte > 0 ? t - v->epoch_first_byte : NAN;
  if (isfinite(transfer)) stress_samples_add(&v->transfer, transfer);
  double latency = transfer;
  if (stepped) latency = t - sv_step_time(run, 0, s->epoch);
  if (isfinite(latency)) stress_samples_add(&v->latency, latency);
  if (run->o->verbose)
    fprintf(stderr,
            "overcast-stress: viewer %d (%s): epoch %" PRIu64 ", %" PRIu32 " nodes, %" PRIu32 " bricks (%" PRIu32
            " sent), resident %.2f of %.2f MiB, latency %.0f ms\n",
            v->index, sv_name(v), s->epoch, s->node_count, s->brick_count, bricks, resident / SV_MIB,
            v->welcome.budget / SV_MIB, 1e3 * latency);
}

static void sv_on_stats(void *ctx, const ocp_stats_t *st) {
  stress_viewer_t *v = ctx;
  v->last_stats = *st;
  v->stats_msgs++;
  v->between = 1; /* STATS ends an epoch: the next byte begins the next one */
  if (st->resident_bytes > v->server_resident_max) v->server_resident_max = st->resident_bytes;
  if (v->run->o->verbose)
    fprintf(stderr,
            "overcast-stress: viewer %d (%s): epoch %" PRIu64 " plan: %" PRIu32 " leaves, %" PRIu32 " splits, %" PRIu32
            " merges, %" PRIu32 " deferred, %" PRIu64 " coalesced, %" PRIu32 " splits waiting, queue %" PRIu32 "\n",
            v->index, sv_name(v), st->epoch, st->leaves, st->splits, st->merges, st->deferred, st->coalesced, st->split_backlog,
            st->queue);
  /* Time to full detail after a teleport: the plan first reacts to the new place (a state planned
   * after the jump with splits or merges; splits that only wait for content are no reaction), then
   * settles (stress.h, STRESS_SETTLE_STATES): the tree stopped growing toward the camera and
   * nothing it wants is still being made, beyond the churn of an animated field. */
  if (!v->settle.phase || st->epoch != v->last_epoch || st->epoch <= v->teleport_epoch) return;
  if (!stress_settle_feed(&v->settle, st->splits, st->merges, st->split_backlog, st->leaves, v->state_at, st->epoch)) return;
  double from = v->welcome.epoch_period == 0 ? sv_step_time(v->run, v->teleport_step, 0) : v->teleport_at;
  if (isfinite(from)) {
    if (!v->detail.n && v->teleports == 1) v->detail_first = 1; /* the first place, from no tree */
    stress_samples_add(&v->detail, v->settle.quiet_at - from);
    if (v->teleport_measured) stress_samples_add(&v->m_detail, v->settle.quiet_at - from);
  }
  stress_samples_add(&v->detail_epochs, (double)(v->settle.quiet_epoch - v->teleport_epoch));
}

static void sv_on_welcome(void *ctx, const ocp_welcome_t *w, int resumed) {
  stress_viewer_t *v = ctx;
  if (v->have_welcome && !resumed) {
    /* a new session (the server restarted): the session dropped its states, so does our count */
    v->fresh = 1;
    for (int i = 0; i < v->nfp; i++) v->fp[i].n = v->fp[i].records = 0; /* emptied, arrays kept */
    v->settle.phase = 0;
    v->max_id = 0; /* ids begin again at 1 */
    v->have_prev = 0;
  }
  v->welcome = *w;
  v->budget_before = w->budget;
  v->have_welcome = 1;
}

/* BUDGET: the budget in force changed as the session defines it (a raise at once, a lowering once
 * no kept state was planned under the old one); every later state is checked against it. */
static void sv_on_budget(void *ctx, const oc_budget_t *grant) {
  stress_viewer_t *v = ctx;
  if (v->run->o->verbose)
    fprintf(stderr, "overcast-stress: viewer %d (%s): budget in force %" PRIu64 " -> %" PRIu64 " bytes\n", v->index,
            sv_name(v), v->welcome.budget, grant->budget);
  v->welcome.budget = grant->budget;
  v->budgets++;
}

/*-*** The thread ***/

static int sv_camera(stress_viewer_t *v, double path_t, double now) {
  const stress_opts_t *o = v->run->o;
  long jump = 0;
  oc_camera_pose_t pose = stress_path_at(&v->p, path_t, &jump);
  if (v->path == STRESS_TELEPORT && jump != v->jump) {
    if (v->settle.phase) { /* the previous place never settled */
      v->detail_unreached++;
      if (v->teleport_measured) v->m_unreached++;
    }
    v->teleports++;
    pthread_mutex_lock(&v->run->mu);
    v->teleport_measured = v->run->measure_from > 0 && now >= v->run->measure_from;
    pthread_mutex_unlock(&v->run->mu);
    if (v->teleport_measured) v->m_teleports++;
    v->settle = (stress_settle_t){.phase = 1};
    v->teleport_at = now;
    v->teleport_epoch = v->states ? v->last_epoch : UINT64_MAX; /* UINT64_MAX: before the first state */
    pthread_mutex_lock(&v->run->mu);
    v->teleport_step = v->run->steps_sent + 1;
    pthread_mutex_unlock(&v->run->mu);
  }
  v->jump = jump;
  oc_camera_t cam = oc_camera_from_pose(pose);
  ocp_camera_t c = {cam.pos, cam.forward, cam.up, pose.fov, (uint32_t)o->width, (uint32_t)o->height};
  int r = ocv_conn_camera(v->conn, &c);
  if (r == OC_EINVAL) sv_fail(v, "viewer %d (%s): the camera at path time %.1f s was refused", v->index, sv_name(v), path_t);
  return r;
}

static uint64_t sv_bytes_in(stress_viewer_t *v) {
  ocp_viewer_stats_t s;
  ocp_viewer_stats(ocv_conn_session(v->conn), &s);
  return s.bytes_in;
}

/* A failed poll or flush: r is 1 (closed by the server) or a negative OC_E*. */
static void sv_poll_failed(stress_viewer_t *v, int r, const char *why) {
  if (r == OC_ECHECKSUM) {
    v->checksum_failures++;
    sv_fail(v, "viewer %d (%s): CHECKSUM MISMATCH: %s", v->index, sv_name(v), why);
  } else if (r == OC_ECORRUPT || r == OC_EVERSION || r == OC_ETOOBIG) {
    v->protocol_errors++;
    sv_fail(v, "viewer %d (%s): protocol error: %s", v->index, sv_name(v), why);
  } else if (r == 1) {
    sv_fail(v, "viewer %d (%s): %s", v->index, sv_name(v), why[0] ? why : "closed by the server");
  } else {
    sv_fail(v, "viewer %d (%s): %s", v->index, sv_name(v), why[0] ? why : oc_strerror(r));
  }
}

static void sv_publish(stress_viewer_t *v, double input_at) {
  stress_run_t *run = v->run;
  pthread_mutex_lock(&run->mu);
  if (input_at > 0) v->last_input = input_at;
  v->busy = 0;
  if (v->new_state) {
    v->have_epoch = v->last_epoch;
    v->have_states = v->states;
  }
  pthread_cond_broadcast(&run->cv);
  pthread_mutex_unlock(&run->mu);
  v->new_state = 0;
}

/* The connection was lost while the server may be restarting (--faults restart), or the server is
 * draining (GOODBYE RECONNECT): reconnects with the viewers' backoff (ocv_retry_t: exponential with
 * jitter, from the server's delay) until a WELCOME (resumed, or a new session after a restart) and
 * sends the camera again. One line per attempt with --verbose.
 * @return 0, or -1 after o->timeout without a server (a failure) or when the run stops. */
static int sv_reconnect(stress_viewer_t *v, const char *cause) {
  stress_run_t *run = v->run;
  const stress_opts_t *o = run->o;
  char why[1024] = "", line[1280];
  const char *text;
  int64_t code = ocv_conn_close_code(v->conn, &text);
  uint32_t server_ms = code == OCP_CODE_RECONNECT ? ocp_reconnect_delay_ms(text) : 0;
  ocv_retry_t rt;
  /* bounded by time (o->timeout) before attempts: a restart under ASan may take long */
  ocv_retry_init(&rt, 64, o->timeout, o->seed * 0x9E3779B97F4A7C15ull + (uint64_t)v->index + 1);
  v->lost_at = stress_now();
  v->reconnects++;
  memset(&v->scan, 0, sizeof v->scan); /* a new byte stream */
  pthread_mutex_lock(&run->mu);
  v->ready = 0;
  pthread_mutex_unlock(&run->mu);
  snprintf(why, sizeof why, "%s", cause);
  while (!atomic_load(&run->stop)) {
    double wait = ocv_retry_next(&rt, server_ms, stress_now(), why, line, sizeof line);
    if (wait < 0) {
      sv_fail(v, "viewer %d (%s): %s (first: %s)", v->index, sv_name(v), line, cause);
      return -1;
    }
    if (o->verbose) fprintf(stderr, "overcast-stress: viewer %d (%s): %s\n", v->index, sv_name(v), line);
    for (double end = stress_now() + wait; stress_now() < end && !atomic_load(&run->stop);) {
      struct timespec ts = {0, 20000000}; /* 20 ms slices: a stopped run does not wait out a backoff */
      nanosleep(&ts, NULL);
    }
    if (atomic_load(&run->stop)) break;
    if (ocv_conn_reconnect(v->conn, 2.0, why, sizeof why) == 0 && ocv_conn_wait_ready(v->conn, 5.0, why, sizeof why) == 0 &&
        ocv_conn_flush(v->conn, o->timeout, why, sizeof why) == 0) {
      pthread_mutex_lock(&run->mu);
      if (v->fresh) v->have_epoch = 0; /* the new server's epochs begin again */
      v->gen = run->restart_gen;
      v->ready = 1;
      pthread_cond_broadcast(&run->cv);
      pthread_mutex_unlock(&run->mu);
      v->between = 1;
      return 0;
    }
    code = ocv_conn_close_code(v->conn, &text); /* a draining server answers HELLO with RECONNECT */
    server_ms = code == OCP_CODE_RECONNECT ? ocp_reconnect_delay_ms(text) : 0;
  }
  return -1;
}

/* Reconnect after this poll result? A lost connection during --faults restart, or a drain. */
static int sv_should_reconnect(stress_viewer_t *v, int r) {
  const stress_opts_t *o = v->run->o;
  int lost = r == 1 || r == OC_EIO; /* closed, reset or refused: not a protocol failure */
  if (!lost || atomic_load(&v->run->stop)) return 0;
  return (o->faults & STRESS_FAULT_RESTART) || ocv_conn_close_code(v->conn, NULL) == OCP_CODE_RECONNECT;
}

/* Connects (--source-address applies to the first connect and every reconnect), waits for the
 * WELCOME and checks it, starts the camera path and sends the first camera, flushed: it must be at
 * the server before the first step. @return 0, or -1 after saying why (sv_fail). */
static int sv_start(stress_viewer_t *v, double *t_start) {
  stress_run_t *run = v->run;
  const stress_opts_t *o = run->o;
  char why[1024] = "";
  /* lean (the default): the session verifies each state by its digest checksum and keeps 12 bytes
   * a brick, not 2052, so N × budget may exceed this machine's memory */
  ocp_viewer_desc_t vd = {.role = OCP_ROLE_VIEWER, .budget = v->budget, .slot_bytes = OC_SLOT_BYTES,
                          .record_bytes = OC_RECORD_BYTES, .max_depth = (uint8_t)v->max_depth,
                          .width = (uint32_t)o->width, .height = (uint32_t)o->height,
                          .caps = o->full_sessions ? OCP_CAP_ALL : OCP_CAP_DICT, .token = o->token,
                          .lean = !o->full_sessions};
  ocp_viewer_events_t ev = {.ctx = v, .welcome = sv_on_welcome, .state = sv_on_state, .stats = sv_on_stats,
                            .budget = sv_on_budget};
  int r = ocv_conn_create(&v->conn, run->host, run->port, &vd, &ev, why, sizeof why);
  if (r == 0) ocv_conn_set_tap(v->conn, sv_tap, v);
  if (r == 0 && o->source && ocv_conn_set_source(v->conn, o->source) < 0) {
    snprintf(why, sizeof why, "--source-address %s: not an IP address", o->source);
    r = OC_EINVAL;
  }
  if (r == 0) r = ocv_conn_reconnect(v->conn, o->timeout, why, sizeof why);
  if (r < 0) {
    sv_fail(v, "viewer %d: %s", v->index, why);
    return -1;
  }
  if ((r = ocv_conn_wait_ready(v->conn, o->timeout, why, sizeof why))) {
    sv_poll_failed(v, r, why);
    return -1;
  }
  v->t_welcome = stress_now();
  if (v->welcome.slot_bytes != OC_SLOT_BYTES || v->welcome.record_bytes != OC_RECORD_BYTES) {
    v->protocol_errors++;
    sv_fail(v, "viewer %d: welcome grants %" PRIu32 "-byte slots and %" PRIu32 "-byte records; we declared %u and %u",
            v->index, v->welcome.slot_bytes, v->welcome.record_bytes, OC_SLOT_BYTES, OC_RECORD_BYTES);
    return -1;
  }
  oc_camera_pose_t home = {{v->welcome.cam_lat, v->welcome.cam_lon, v->welcome.cam_alt}, v->welcome.cam_heading,
                           v->welcome.cam_pitch, v->welcome.cam_fov};
  stress_path_init(&v->p, v->path, home,
                   o->seed * 0x9E3779B97F4A7C15ull + (uint64_t)(o->sweep || o->share_paths ? 0 : v->index) + 1,
                   o->teleport_every, o->dive_seconds);
  v->ticks.period = v->m_ticks.period = v->welcome.epoch_period;
  v->rng = (o->seed + 1) * 0xD1B54A32D192ED03ull + (uint64_t)v->index * 0x9E3779B97F4A7C15ull + 1;
  *t_start = stress_now();
  v->between = 1;
  if (sv_camera(v, 0, *t_start) < 0) return -1;
  if ((r = ocv_conn_flush(v->conn, o->timeout, why, sizeof why))) {
    sv_poll_failed(v, r, why);
    return -1;
  }
  return 0;
}

/* Stepped: the camera for the next step goes out with the ACK, before we say we have this epoch.
 * @return 0, 1 after a reconnect (the loop goes on), -1 when the viewer is done. */
static int sv_answer_step(stress_viewer_t *v, double t_in) {
  stress_run_t *run = v->run;
  char why[1024] = "";
  pthread_mutex_lock(&run->mu);
  uint64_t sent = run->steps_sent;
  pthread_mutex_unlock(&run->mu);
  if (sv_camera(v, (double)sent * run->o->step_seconds, t_in) < 0) return -1;
  int r = ocv_conn_flush(v->conn, run->o->timeout, why, sizeof why);
  if (!r) return 0;
  if (sv_should_reconnect(v, r)) {
    sv_publish(v, t_in);
    return sv_reconnect(v, why[0] ? why : "connection lost") < 0 ? -1 : 1;
  }
  sv_poll_failed(v, r, why);
  return -1;
}

/* Reads, times and answers until the run stops or the connection is lost for good. */
static void sv_loop(stress_viewer_t *v, double t_start) {
  stress_run_t *run = v->run;
  const stress_opts_t *o = run->o;
  char why[1024] = "";
  int stepped = v->welcome.epoch_period == 0;
  double tick = 1.0 / o->tick_hz, next_tick = t_start + tick;
  const char *hook = getenv("OC_STRESS_ACK_DELAY_MS");
  long ack_delay = hook ? strtol(hook, NULL, 10) : 0; /* viewer 0 holds each state's ACK this long */
  if (ack_delay < 0 || ack_delay > 60000) ack_delay = 0;
  while (!atomic_load(&run->stop)) {
    double now = stress_now();
    if (!stepped && now >= next_tick) {
      if (sv_camera(v, now - t_start, now) < 0) break;
      next_tick += tick;
      if (next_tick < now) next_tick = now + tick; /* fell behind: no burst of cameras */
    }
    if (ocv_conn_silence(v->conn) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(v->conn);
    /* Wait for input here rather than inside ocv_conn_poll, so that the first byte of an epoch is
     * timed when it becomes readable, before the read that may complete the whole epoch. */
    double wait = stepped ? 0.1 : fmin(fmax(next_tick - now, 0.0), 0.1);
    struct pollfd pf = {ocv_conn_fd(v->conn), (short)(POLLIN | (ocv_conn_pending(v->conn) ? POLLOUT : 0)), 0};
    int k = poll(&pf, 1, (int)ceil(wait * 1e3));
    double t_in = stress_now();
    v->poll_utc = stress_utc();
    int readable = k > 0 && (pf.revents & (POLLIN | POLLHUP | POLLERR));
    int marked = 0;
    if (readable) { /* seen before it is read: the stepped driver must not take this viewer for idle */
      pthread_mutex_lock(&run->mu);
      v->busy = 1;
      v->last_input = t_in;
      pthread_mutex_unlock(&run->mu);
    }
    if (readable && v->between) {
      v->epoch_first_byte = t_in;
      v->between = 0;
      marked = 1;
    }
    uint64_t before = sv_bytes_in(v);
    int r = ocv_conn_poll(v->conn, 0, why, sizeof why);
    uint64_t got = sv_bytes_in(v) - before;
    if (marked && got == OCP_HEADER_BYTES && !v->new_state) v->between = 1; /* a lone KEEPALIVE */
    if (r) {
      sv_publish(v, got ? t_in : 0); /* what came before the loss counts; not busy while away */
      if (sv_should_reconnect(v, r)) {
        if (sv_reconnect(v, why[0] ? why : "connection lost") < 0) break;
        continue;
      }
      if (!atomic_load(&run->stop) || r < 0) sv_poll_failed(v, r, why);
      break;
    }
    if (v->new_state && v->index == 0 && ack_delay > 0) { /* test hook: a slow viewer (OC_STRESS_ACK_DELAY_MS) */
      struct timespec ts = {(time_t)(ack_delay / 1000), (long)(ack_delay % 1000) * 1000000L};
      nanosleep(&ts, NULL);
    }
    if (v->new_state && stepped) {
      int a = sv_answer_step(v, t_in);
      if (a < 0) break;
      if (a > 0) continue;
    }
    if (got || v->new_state || readable) sv_publish(v, got ? t_in : 0);
  }
  sv_publish(v, 0); /* not busy any more */
}

void *stress_viewer_main(void *arg) {
  stress_viewer_t *v = arg;
  stress_run_t *run = v->run;
  double t_start = 0;
  if (sv_start(v, &t_start) == 0) {
    pthread_mutex_lock(&run->mu);
    v->ready = 1;
    pthread_cond_broadcast(&run->cv);
    pthread_mutex_unlock(&run->mu);
    sv_loop(v, t_start);
  }
  v->t_end = stress_now();
  if (v->settle.phase) { /* cut off by the end: how long it had been waiting */
    v->detail_unreached++;
    if (v->teleport_measured && v->welcome.epoch_period > 0) v->m_open_s = v->t_end - v->teleport_at;
  }
  v->settle.phase = 0;
  if (v->conn) ocp_viewer_stats(ocv_conn_session(v->conn), &v->session);
  pthread_mutex_lock(&run->mu);
  v->done = 1;
  pthread_cond_broadcast(&run->cv);
  pthread_mutex_unlock(&run->mu);
  ocv_conn_close(v->conn);
  v->conn = NULL;
  return NULL;
}

void stress_viewer_free(stress_viewer_t *v) {
  stress_samples_free(&v->latency);
  stress_samples_free(&v->transfer);
  stress_samples_free(&v->interval);
  stress_samples_free(&v->detail);
  stress_samples_free(&v->detail_epochs);
  stress_samples_free(&v->m_interval);
  stress_samples_free(&v->m_detail);
  stress_ticks_free(&v->ticks);
  stress_ticks_free(&v->m_ticks);
  stress_samples_free(&v->resync);
  for (int i = 0; i < 2; i++) free(v->fp[i].ids);
  free(v->fp_new.ids);
  memset(v->fp, 0, sizeof v->fp);
  memset(&v->fp_new, 0, sizeof v->fp_new);
}

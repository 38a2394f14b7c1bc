/* net_epoch.c — epochs (net_internal.h): ticks on the clock, a step of the world on libuv's
 * thread pool, and the new states streamed when it ends. While a step runs the world's viewers
 * are not touched: what viewers say meanwhile is kept in their sessions and applied before the
 * next step.
 *
 * Clocked (period P > 0): epoch n is due at n·P seconds after the Unix epoch and takes the world
 * time of that instant (world_clock.h), whenever it is built. So a tick is built a little ahead
 * (tick_lead: what the last ticks took, with a margin) and its states go out at the due instant
 * itself, not a tick's planning time after it; the world stays busy until then, so input and
 * control changes apply after the send, to the next epoch. The timer is armed for the next build
 * instant; a tick that finds the previous step still running, or that the loop reached late, is
 * skipped and counted (late_ticks), and the step takes the newest due epoch. A tick builds its
 * states from content that exists (world.h, clocked). Between ticks the world's production queue
 * is worked on: no brick is started after shortly before the next build instant, and the bricks
 * still in flight then finish while the tick runs beside them (ocs_world_produce_run()), so
 * production runs behind the clock instead of holding epochs back. Stepped (P = 0): the virtual
 * clock of ocs_world_step(), each step producing all its plans ask. */
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <time.h>

#include "net_internal.h"
#include "net_share.h"
#include "oc_err.h"
#include "oc_log.h"

static void start_step_at(ocs_server_t *srv, uint64_t n);
static void start_production(ocs_server_t *srv);

/* Production starts no brick after this long before the next build instant (or a tenth of the
 * period): the bricks still in flight then finish beside the tick, and the next production (from
 * the tick's wishes) waits for them. */
#define OCS_PRODUCE_MARGIN_S 0.03

/* What a viewer said while a step ran (its acknowledgement, its newest camera) reaches the world. */
static void apply_pending(ocs_session_t *s) {
  if (s->ack_pending) {
    ocs_viewer_ack(s->viewer, s->stream_epoch);
    s->ack_pending = 0;
  }
  if (s->cam_new) {
    ocs_viewer_set_view(s->viewer, &s->cam);
    s->cam_new = 0;
  }
}

double ocs_net_utc(const ocs_server_t *srv) {
  if (!(srv->period > 0)) return ocs_world_utc(srv->world);
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The epoch whose due instant is the newest not after utc. */
static uint64_t due_epoch(const ocs_server_t *srv, double utc) { return (uint64_t)floor(utc / srv->period); }

static double mono_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* A tick is built this much ahead of its due instant at first, and at most half a period. */
#define OCS_TICK_LEAD_S 0.02

static void step_work(uv_work_t *req) {
  ocs_server_t *srv = req->data;
  double t0 = mono_s();
  uint64_t n = srv->step_epoch;
  if (srv->desc.step_gate) { /* the test hook: the producer held until the test releases it */
    struct stat st;
    for (int i = 0; i < 120000 && stat(srv->desc.step_gate, &st) != 0; i++) nanosleep(&(struct timespec){0, 5000000}, NULL);
  }
  srv->step_rc = n ? ocs_world_step_at(srv->world, n, (double)n * srv->period) : ocs_world_step(srv->world);
  srv->step_took = mono_s() - t0;
}

/* Viewers dropped while the world was busy leave it now. */
static void remove_doomed(ocs_server_t *srv) {
  for (int i = 0; i < srv->ndoomed; i++) ocs_world_remove_viewer(srv->world, srv->doomed[i]);
  srv->ndoomed = 0;
}

static void finish_production(ocs_server_t *srv);

static void tick_end(ocs_server_t *srv);

/* The lead: a decaying maximum of what ticks take, 2× with 10 ms more, at most half a period. */
static void learn_lead(ocs_server_t *srv) {
  /* twice: a tree growing by a tenth of its capacity a tick, or a wave of refreshes where several
   * levels' time steps change at once, makes the next tick dearer than the last */
  double lead = 2.0 * srv->step_took + 0.010, old = 0.9 * srv->tick_lead;
  lead = lead > old ? lead : old;
  srv->tick_lead = lead < 0.5 * srv->period ? lead : 0.5 * srv->period;
}

static void on_send_timer(uv_timer_t *t) { tick_end(t->data); }

/* The step's figures for STATS, read once per step, not once per viewer. */
static void take_step_stats(ocs_server_t *srv) {
  ocs_world_stats_t ws;
  ocs_world_stats(srv->world, &ws);
  srv->plan_ms = 1e3 * ws.plan_seconds;
  srv->produce_ms = 1e3 * ws.produce_seconds;
}

/* A session that will stream the step's state: READY, its newest state not sent yet, the one before
 * acknowledged. */
static int will_stream(const ocs_session_t *s) {
  if (s->state != OCS_SS_READY || !s->viewer) return 0;
  const oc_state_t *h0 = ocs_viewer_held(s->viewer, 0);
  return h0 && ocs_viewer_in_flight(s->viewer) && h0->epoch != s->last_out_epoch && !s->streaming && !s->awaiting_ack;
}

/* The streams of a tick built ahead, set up in parallel (each session's encoder is its own; the
 * world is only read), closing those that failed afterwards on this thread. */
typedef struct {
  ocs_session_t **s;
  int *rc;
} prep_job_t;

static int prepare_one(void *ctx, size_t i, int worker) {
  prep_job_t *j = ctx;
  (void)worker;
  j->rc[i] = ocs_session_encode(j->s[i], ocs_viewer_held(j->s[i]->viewer, 1));
  return 0;
}

static void prepare_streams(ocs_server_t *srv) {
  size_t n = 0;
  for (ocs_session_t *s = srv->sessions; s; s = s->next) n += will_stream(s);
  if (!n) return;
  ocs_session_t **ss = malloc(n * sizeof *ss);
  int *rc = malloc(n * sizeof *rc);
  if (!ss || !rc) { /* set up at the due instant instead */
    free(ss), free(rc);
    return;
  }
  size_t k = 0;
  for (ocs_session_t *s = srv->sessions; s && k < n; s = s->next)
    if (will_stream(s)) ss[k++] = s;
  prep_job_t job = {ss, rc};
  ocs_world_parallel(srv->world, k, prepare_one, &job);
  for (size_t i = 0; i < k; i++)
    if (rc[i] < 0 && rc[i] != OC_ENOENT) ocs_session_close(ss[i], OCP_CODE_INTERNAL, oc_strerror(rc[i]));
  free(ss), free(rc);
}

static void step_done(uv_work_t *req, int status) {
  ocs_server_t *srv = req->data;
  (void)status;
  if (srv->tick_hold) {
    /* built ahead: each stream is set up now (the encoder hashes tens of MB for a 64 MiB viewer),
     * so the first frames leave at the due instant; the set-up counts in the lead */
    double t0 = mono_s();
    if (srv->step_rc >= 0) {
      take_step_stats(srv);
      prepare_streams(srv);
    }
    srv->step_took += mono_s() - t0;
    double late = ocs_net_utc(srv) - (double)srv->step_epoch * srv->period;
    if (late > 0) /* built after its due instant: sent late (the lead learns from it) */
      oc_log_info("tick %llu built %.0f ms after its due instant (it took %.0f ms, the lead was %.0f ms)",
                  (unsigned long long)srv->step_epoch, 1e3 * late, 1e3 * srv->step_took, 1e3 * srv->tick_lead);
    learn_lead(srv);
    double wait = (double)srv->step_epoch * srv->period - ocs_net_utc(srv);
    if (wait > 0 && !srv->stopping) { /* built ahead: out at the due instant */
      uv_update_time(&srv->loop); /* the loop's clock was read before the streams' set-up */
      uv_timer_start(&srv->send_timer, on_send_timer, (uint64_t)ceil(wait * 1e3), 0);
      return;
    }
  }
  tick_end(srv);
}

void ocs_epoch_flush(ocs_server_t *srv) {
  if (!uv_is_active((uv_handle_t *)&srv->send_timer)) return;
  uv_timer_stop(&srv->send_timer);
  tick_end(srv);
}

/* The step's states go out, and the world is free again. */
static void tick_end(ocs_server_t *srv) {
  srv->tick_hold = 0;
  srv->ticking = 0;
  srv->stepping = srv->producing; /* production's last bricks may still be in flight */
  srv->steps_done++;
  if (srv->step_rc < 0) oc_log_error("epoch step failed: %s (viewers keep their states)", oc_strerror(srv->step_rc));
  take_step_stats(srv);
  if (!srv->stepping) remove_doomed(srv);
  if (srv->period > 0 && srv->step_rc >= 0) { /* its first frames go out now: how late (0: on time) */
    double late = ocs_net_utc(srv) - (double)srv->step_epoch * srv->period;
    ocs_hist_observe(&srv->tick_lateness, late > 0 ? late : 0.0);
  }
  /* New states go out, then the layers above see the step's end (held input, waiting "step"
   * requests). The list may change under these calls (sessions close), so walk it with care. */
  for (ocs_session_t *s = srv->sessions, *nx; s; s = nx) {
    nx = s->next;
    if (s->state != OCS_SS_READY || !s->viewer) continue;
    apply_pending(s);
    if (s->prepared)
      ocs_session_go(s);
    else if (will_stream(s))
      ocs_session_stream(s, ocs_viewer_held(s->viewer, 1));
  }
  if (srv->producing) return; /* what follows comes when production ends */
  if (srv->end_due) {
    finish_production(srv);
    return;
  }
  if (srv->after_step) srv->after_step(srv);
  if (srv->steps_queued && !srv->stopping) start_step_at(srv, 0);
  else start_production(srv);
}

/*-*** Production between ticks (clocked) ***/

static void produce_work(uv_work_t *req) {
  ocs_server_t *srv = req->data;
  srv->produce_rc = ocs_world_produce_begin(srv->world, srv->produce_s, 0);
  if (srv->produce_rc < 0) return;
  atomic_store(&srv->overlap, 1); /* from here a tick may run beside it */
  uv_async_send(&srv->taken_async);
  ocs_world_produce_run(srv->world);
}

/* Production is over and no tick runs: what was made is counted, then as after a step. */
static void finish_production(ocs_server_t *srv) {
  srv->end_due = 0;
  if (srv->produce_rc < 0) {
    oc_log_warn("production: %s (asked again at the next tick)", oc_strerror(srv->produce_rc));
  } else {
    srv->bricks_made += (uint64_t)ocs_world_produce_end(srv->world);
    ocs_share_store_made(srv); /* for the other front-ends */
  }
  remove_doomed(srv);
  ocs_world_stats_t ws;
  ocs_world_stats(srv->world, &ws);
  if (ws.produce_errors > srv->produce_errors) /* a failed brick: reported, and asked again */
    oc_log_warn("production: %llu brick(s) failed, the last %016llx: %s (asked again at the next tick)",
                (unsigned long long)(ws.produce_errors - srv->produce_errors), (unsigned long long)ws.last_error_key,
                oc_strerror(ws.last_error));
  srv->produce_errors = ws.produce_errors;
  if (srv->after_step) srv->after_step(srv); /* input held while producing: HELLOs, control requests */
  if (srv->stopping) return;
  if (srv->steps_queued) start_step_at(srv, 0);
  else if (srv->tick_epoch > ocs_world_epoch(srv->world) && srv->tick_overrun) start_step_at(srv, srv->tick_epoch);
  else if (ocs_world_epoch(srv->world) != srv->production_epoch) start_production(srv); /* a tick ran beside it */
  srv->tick_overrun = 0;
}

/* A tick that came due while production was taking its bricks starts now, beside the rest. */
static void on_taken(uv_async_t *h) {
  ocs_server_t *srv = h->data;
  if (!srv->tick_overrun || !srv->producing || srv->stopping) return;
  srv->tick_overrun = 0;
  if (srv->tick_epoch > ocs_world_epoch(srv->world)) start_step_at(srv, srv->tick_epoch);
}

static void produce_done(uv_work_t *req, int status) {
  ocs_server_t *srv = req->data;
  (void)status;
  srv->producing = 0;
  atomic_store(&srv->overlap, 0);
  srv->stepping = srv->ticking;
  if (srv->ticking) srv->end_due = 1; /* the tick beside it ends first */
  else finish_production(srv);
}

/* Shared bricks (--redis): production in two parts, with the queue looked up in the shared store
 * on the loop between them (net_share.c); a tick waits meanwhile, at most the lookup's deadline. */
static void produce_run_work(uv_work_t *req) {
  ocs_server_t *srv = req->data;
  if (srv->produce_rc < 0) return;
  atomic_store(&srv->overlap, 1);
  uv_async_send(&srv->taken_async);
  ocs_world_produce_run(srv->world);
}

static void launch_run(ocs_server_t *srv) {
  uv_queue_work(&srv->loop, &srv->produce_work, produce_run_work, produce_done);
}

static void produce_begin_work(uv_work_t *req) {
  ocs_server_t *srv = req->data;
  srv->produce_rc = ocs_world_produce_begin(srv->world, srv->produce_s, 0);
}

static void produce_begin_done(uv_work_t *req, int status) {
  ocs_server_t *srv = req->data;
  (void)status;
  if (srv->produce_rc < 0 || !ocs_share_lookup(srv, launch_run)) launch_run(srv);
}

/* What the last tick's plans wait for is made until shortly before the next build instant, on the
 * producer pool; the world is busy meanwhile (input that needs it waits, as during a step). */
static void start_production(ocs_server_t *srv) {
  if (!(srv->period > 0) || srv->stepping || srv->stopping || !ocs_world_production_due(srv->world)) return;
  double margin = srv->period * 0.1 < OCS_PRODUCE_MARGIN_S ? srv->period * 0.1 : OCS_PRODUCE_MARGIN_S;
  srv->produce_s = (double)srv->armed_epoch * srv->period - srv->tick_lead - ocs_net_utc(srv) - margin;
  if (!(srv->produce_s > 0)) return;
  srv->stepping = srv->producing = 1;
  srv->production_epoch = ocs_world_epoch(srv->world);
  srv->produce_work.data = srv;
  if (srv->share) uv_queue_work(&srv->loop, &srv->produce_work, produce_begin_work, produce_begin_done);
  else uv_queue_work(&srv->loop, &srv->produce_work, produce_work, produce_done);
}

/* A step of epoch n (clocked), or of the next one (a "step" request: on the clock the newest due
 * epoch, or the one after the last if that is not due yet; stepped: the virtual clock's next). */
static int tick_may_start(const ocs_server_t *srv) {
  return !srv->ticking && !srv->stopping && (!srv->producing || atomic_load(&srv->overlap)); /* end_due: ticking */
}

static void start_step_at(ocs_server_t *srv, uint64_t n) {
  if (!tick_may_start(srv)) return;
  if (!n && srv->period > 0) {
    uint64_t due = due_epoch(srv, ocs_net_utc(srv)), last = ocs_world_epoch(srv->world);
    n = due > last ? due : last + 1;
  }
  srv->step_epoch = n;
  if (srv->steps_queued) srv->steps_queued--;
  for (ocs_session_t *s = srv->sessions; s; s = s->next)
    if (s->viewer) apply_pending(s);
  srv->stepping = srv->ticking = 1;
  srv->work.data = srv;
  uv_queue_work(&srv->loop, &srv->work, step_work, step_done);
}

void ocs_server_queue_steps(ocs_server_t *srv, uint64_t n) {
  srv->steps_queued += n;
  start_step_at(srv, 0);
}

static void on_tick_idle(uv_idle_t *h) { (void)h; }

/* After the poll that followed the tick: the acknowledgements that had arrived are applied by
 * now, so a viewer that has its epoch is not skipped for want of reading its ACK. */
static void on_tick_check(uv_check_t *h) {
  ocs_server_t *srv = h->data;
  uv_idle_stop(&srv->tick_idle);
  uv_check_stop(&srv->tick_check);
  if (srv->producing && !atomic_load(&srv->overlap)) { /* it follows production */
    srv->tick_overrun = 1;
    return;
  }
  if (!tick_may_start(srv)) {
    srv->late_ticks++;
    return;
  }
  if (srv->tick_epoch > ocs_world_epoch(srv->world)) {
    int was = srv->ticking;
    start_step_at(srv, srv->tick_epoch);
    srv->tick_hold = !was && srv->ticking;
  } /* else a "step" took it */
}

static void arm_timer(ocs_server_t *srv);

/* libuv runs timers before it polls sockets: a step started here would not yet see ACKs that
 * arrived since the last poll. The step starts right after the next poll instead (which the idle
 * handle keeps from blocking). */
static void on_epoch_timer(uv_timer_t *t) {
  ocs_server_t *srv = t->data;
  uint64_t due = due_epoch(srv, ocs_net_utc(srv) + srv->tick_lead + 1e-3); /* a timer may fire up to 1 ms early */
  if (due < srv->armed_epoch) due = srv->armed_epoch;
  srv->late_ticks += due - srv->armed_epoch; /* due instants the loop reached too late */
  if (srv->producing && srv->tick_overrun) srv->late_ticks++; /* the tick still waiting is replaced: skipped */
  srv->tick_epoch = due;
  arm_timer(srv);
  if (srv->producing && !atomic_load(&srv->overlap)) { /* production has not taken its bricks yet */
    srv->tick_overrun = 1;
    return;
  }
  if (srv->ticking) {
    srv->late_ticks++; /* the previous step is still running: this tick is skipped */
    return;
  }
  uv_idle_start(&srv->tick_idle, on_tick_idle);
  uv_check_start(&srv->tick_check, on_tick_check);
}

/* One shot, for the build instant (tick_lead before the due instant) of the next epoch after
 * tick_epoch. */
static void arm_timer(ocs_server_t *srv) {
  double now = ocs_net_utc(srv);
  uint64_t next = due_epoch(srv, now + srv->tick_lead) + 1;
  if (next <= srv->tick_epoch) next = srv->tick_epoch + 1;
  double wait = (double)next * srv->period - srv->tick_lead - now;
  srv->armed_epoch = next;
  uv_timer_start(&srv->epoch_timer, on_epoch_timer, wait > 0 ? (uint64_t)ceil(wait * 1e3) : 0, 0);
}

void ocs_epoch_init(ocs_server_t *srv) {
  uv_idle_init(&srv->loop, &srv->tick_idle);
  uv_check_init(&srv->loop, &srv->tick_check);
  uv_timer_init(&srv->loop, &srv->epoch_timer);
  uv_timer_init(&srv->loop, &srv->send_timer);
  uv_async_init(&srv->loop, &srv->taken_async, on_taken);
  srv->taken_async.data = srv;
  srv->tick_idle.data = srv->tick_check.data = srv->epoch_timer.data = srv->send_timer.data = srv;
}

void ocs_epoch_close(ocs_server_t *srv) {
  if (!uv_is_closing((uv_handle_t *)&srv->taken_async)) uv_close((uv_handle_t *)&srv->taken_async, NULL);
}

void ocs_epoch_start_timer(ocs_server_t *srv) {
  if (!(srv->period > 0)) return;
  srv->tick_epoch = srv->armed_epoch = 0;
  srv->tick_lead = OCS_TICK_LEAD_S < 0.5 * srv->period ? OCS_TICK_LEAD_S : 0.5 * srv->period;
  arm_timer(srv);
}

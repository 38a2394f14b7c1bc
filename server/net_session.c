/* net_session.c — a session's lifetime and output (net_internal.h): closing with a reason,
 * losing the peer (a welcomed viewer lingers for resume), queued writes with their limits, and
 * an epoch's frames produced only while the socket keeps up. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "net_internal.h"
#include "oc_bytes.h" /* oc_grow */
#include "oc_err.h"
#include "oc_log.h"

/* An epoch's frames are produced only while fewer bytes than this are unsent, in bursts of about
 * OCS_BURST bytes: a session holds at most LOW_WATER + BURST + one frame. */
#define OCS_LOW_WATER (256u << 10)
#define OCS_BURST (256u << 10)

double ocs_net_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

const char *ocs_role_name(int role) { return role == OCP_ROLE_CONTROL ? "control" : "viewer"; }

const char *ocs_session_state_name(int state) {
  static const char *names[OCS_SS_COUNT] = {"handshake", "ready", "lingering", "closing"};
  return state >= 0 && state < OCS_SS_COUNT ? names[state] : "?";
}

/*-*** Sessions: lifetime ***/

void ocs_session_unlink(ocs_server_t *srv, ocs_session_t *s) {
  if (s->prev) s->prev->next = s->next;
  else srv->sessions = s->next;
  if (s->next) s->next->prev = s->prev;
  s->prev = s->next = NULL;
}

void ocs_session_link(ocs_server_t *srv, ocs_session_t *s) {
  s->prev = NULL;
  s->next = srv->sessions;
  if (srv->sessions) srv->sessions->prev = s;
  srv->sessions = s;
}

ocs_session_t *ocs_session_find(ocs_server_t *srv, uint32_t id) {
  for (ocs_session_t *t = srv->sessions; t; t = t->next)
    if (t->id == id) return t;
  return NULL;
}

void ocs_session_free(ocs_session_t *s) {
  ocp_reader_free(&s->rd);
  ocp_epoch_enc_free(s->enc);
  free(s->deferred);
  free(s->proxy_buf);
  free(s);
}

void ocs_session_drop_viewer(ocs_server_t *srv, ocs_session_t *s) {
  if (!s->viewer) return;
  if (srv->stepping) {
    ocs_viewer_t **a = oc_grow(srv->doomed, &srv->doomed_cap, (size_t)srv->ndoomed, sizeof *a, 8);
    if (!a) abort(); /* cannot defer: a stepping world must not be touched */
    srv->doomed = a;
    srv->doomed[srv->ndoomed++] = s->viewer;
  } else {
    ocs_world_remove_viewer(srv->world, s->viewer);
  }
  s->viewer = NULL;
  s->streaming = s->awaiting_ack = s->ack_pending = s->prepared = 0;
}

void ocs_session_on_closed(uv_handle_t *h) {
  ocs_session_t *s = h->data;
  ocs_server_t *srv = s->srv;
  srv->nconnected--;
  s->connected = 0;
  if (s->peer) { /* admitted: it no longer counts against its address or the server */
    ocs_peer_release(s->peer);
    s->peer = NULL;
    srv->nadmitted--;
  }
  if (s->state == OCS_SS_LINGER) return; /* kept for resume; freed by the housekeeper */
  ocs_session_unlink(srv, s);
  ocs_session_free(s);
}

void ocs_session_close_handle(ocs_session_t *s) {
  if (!uv_is_closing((uv_handle_t *)&s->tcp)) uv_close((uv_handle_t *)&s->tcp, ocs_session_on_closed);
}

static void on_shutdown(uv_shutdown_t *req, int status) {
  (void)status;
  ocs_session_close_handle(req->data);
}

void ocs_session_close(ocs_session_t *s, uint32_t code, const char *text) {
  ocs_server_t *srv = s->srv;
  if (s->state == OCS_SS_CLOSING) return;
  int is_error = code != OCP_CODE_OK && code != OCP_CODE_SHUTDOWN && code != OCP_CODE_RELOAD && code != OCP_CODE_KICKED &&
                 code != OCP_CODE_RECONNECT;
  if (is_error) srv->counts.closed_errors++;
  oc_log(is_error ? OC_LOG_WARN : OC_LOG_INFO, "session %" PRIu32 " (%s %s): closing: %s%s%s", s->id, ocs_role_name(s->role),
         s->addr, ocp_code_text(code), text && *text ? ": " : "", text ? text : "");
  ocs_session_drop_viewer(srv, s);
  int was_linger = s->state == OCS_SS_LINGER;
  s->state = OCS_SS_CLOSING;
  s->closing_since = ocs_net_now();
  if (was_linger && !s->connected) { /* nothing open: free now */
    ocs_session_unlink(srv, s);
    ocs_session_free(s);
    return;
  }
  if (!s->drained) uv_read_stop((uv_stream_t *)&s->tcp); /* a drained one's EOF says it has left */
  if (code == OCP_CODE_SLOW || (code == OCP_CODE_TIMEOUT && s->queued)) { /* not draining: queue nothing more */
    ocs_session_close_handle(s);
    return;
  }
  oc_buf_t b = {0};
  ocp_put_text(&b, s->version ? s->version : OCP_VERSION_MAX, is_error ? OCP_MSG_ERROR : OCP_MSG_GOODBYE, code, text);
  ocs_session_send(s, &b);
  if (s->drained) return; /* the peer leaves (EOF: ocs_session_lost()), or the drain's end closes it */
  s->shut.data = s;
  if (uv_shutdown(&s->shut, (uv_stream_t *)&s->tcp, on_shutdown) < 0) ocs_session_close_handle(s);
}

void ocs_session_refuse(ocs_session_t *s, ocs_refusal_t why, const char *text) {
  static const uint32_t codes[] = {OCP_CODE_FULL, OCP_CODE_FULL, OCP_CODE_FULL,  OCP_CODE_FULL,
                                   OCP_CODE_FULL, OCP_CODE_TOKEN, OCP_CODE_VERSION, OCP_CODE_SHUTDOWN,
                                   OCP_CODE_MALFORMED, OCP_CODE_RECONNECT};
  _Static_assert(sizeof codes / sizeof *codes == OCS_REFUSE_COUNT, "a code per refusal");
  s->srv->counts.refused++;
  s->srv->counts.refusals[why]++;
  ocs_session_close(s, codes[why], text);
}

/*-*** Lingering sessions ***/

void ocs_session_let_go(ocs_session_t *t, const char *why) {
  ocs_server_t *srv = t->srv;
  oc_log_info("session %" PRIu32 " (viewer %s): lingering session let go: %s", t->id, t->addr, why);
  ocs_session_drop_viewer(srv, t);
  if (t->connected) { /* its handle is still closing: on_closed frees it */
    t->state = OCS_SS_CLOSING;
    t->closing_since = ocs_net_now();
    return;
  }
  ocs_session_unlink(srv, t);
  ocs_session_free(t);
}

ocs_session_t *ocs_session_oldest_lingering(ocs_server_t *srv, int *count, uint64_t *budget) {
  ocs_session_t *old = NULL;
  int n = 0;
  uint64_t b = 0;
  for (ocs_session_t *t = srv->sessions; t; t = t->next)
    if (t->state == OCS_SS_LINGER && t->viewer) {
      n++;
      b += t->granted.budget;
      if (!old || t->linger_since < old->linger_since) old = t;
    }
  if (count) *count = n;
  if (budget) *budget = b;
  return old;
}

/* Room for s to linger within the caps: the oldest lingering sessions are let go first.
 * @return 1 if s may linger. */
static int linger_room(ocs_session_t *s) {
  const ocs_server_desc_t *d = &s->srv->desc;
  if (s->granted.budget > d->linger_budget) return 0;
  int n;
  uint64_t b;
  ocs_session_t *old;
  while ((old = ocs_session_oldest_lingering(s->srv, &n, &b)) &&
         (n + 1 > d->max_lingering || b + s->granted.budget > d->linger_budget)) {
    char why[160];
    snprintf(why, sizeof why, "the lingering caps (%d sessions, %" PRIu64 " bytes) make room for session %" PRIu32,
             d->max_lingering, d->linger_budget, s->id);
    ocs_session_let_go(old, why);
  }
  return n + 1 <= d->max_lingering;
}

void ocs_session_lost(ocs_session_t *s, const char *cause) {
  ocs_server_t *srv = s->srv;
  if (s->state == OCS_SS_CLOSING) {
    if (s->drained) ocs_session_close_handle(s); /* a drained viewer has left */
    return;
  }
  if (s->role == OCP_ROLE_VIEWER && s->state == OCS_SS_READY && s->viewer && srv->desc.linger_s > 0 && !srv->stopping &&
      linger_room(s)) {
    oc_log_info("session %" PRIu32 " (viewer %s): connection lost (%s); kept %.0f s for resume", s->id, s->addr, cause,
                srv->desc.linger_s);
    s->state = OCS_SS_LINGER;
    s->linger_since = ocs_net_now();
    s->linger_until = s->linger_since + srv->desc.linger_s;
    s->streaming = s->awaiting_ack = s->prepared = 0; /* the epoch in flight is lost with the connection */
    uv_read_stop((uv_stream_t *)&s->tcp);
    ocs_session_close_handle(s);
    return;
  }
  oc_log_info("session %" PRIu32 " (%s %s): connection lost (%s)", s->id, ocs_role_name(s->role), s->addr, cause);
  ocs_session_drop_viewer(srv, s);
  s->state = OCS_SS_CLOSING;
  s->closing_since = ocs_net_now();
  ocs_session_close_handle(s);
}

/*-*** Sessions: output ***/

typedef struct {
  uv_write_t req;
  ocs_session_t *s;
  oc_buf_t buf;
} ocs_send_t;

static void pump(ocs_session_t *s);

static void on_written(uv_write_t *req, int status) {
  ocs_send_t *w = (ocs_send_t *)req;
  ocs_session_t *s = w->s;
  s->queued -= w->buf.len;
  s->bytes_out += status == 0 ? w->buf.len : 0;
  s->last_progress = ocs_net_now();
  oc_buf_free(&w->buf);
  free(w);
  if (status < 0) {
    if (status != UV_ECANCELED) ocs_session_lost(s, uv_strerror(status));
    return;
  }
  if (s->state == OCS_SS_READY) pump(s);
}

void ocs_session_send(ocs_session_t *s, oc_buf_t *b) {
  if (b->err) {
    oc_buf_free(b);
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  if (!s->connected || uv_is_closing((uv_handle_t *)&s->tcp) || !b->len) {
    oc_buf_free(b);
    return;
  }
  ocs_send_t *w = malloc(sizeof *w);
  if (!w) {
    oc_buf_free(b);
    ocs_session_close(s, OCP_CODE_INTERNAL, "out of memory");
    return;
  }
  w->s = s;
  w->buf = *b;
  memset(b, 0, sizeof *b);
  if (!s->queued) s->last_progress = ocs_net_now();
  uv_buf_t ub = uv_buf_init((char *)w->buf.data, (unsigned)w->buf.len);
  int r = uv_write(&w->req, (uv_stream_t *)&s->tcp, &ub, 1, on_written);
  if (r < 0) {
    oc_buf_free(&w->buf);
    free(w);
    ocs_session_lost(s, uv_strerror(r));
    return;
  }
  s->queued += ub.len;
  if (s->queued > s->srv->desc.queue_hard && s->state != OCS_SS_CLOSING) {
    char t[96];
    snprintf(t, sizeof t, "%" PRIu64 " bytes unsent (hard limit %" PRIu64 ")", s->queued, s->srv->desc.queue_hard);
    ocs_session_close(s, OCP_CODE_SLOW, t);
  }
}

/* Produces the current epoch's next frames while the socket keeps up. */
/* Frames while fewer than OCS_LOW_WATER bytes are unsent, in bursts of OCS_BURST; with `first`,
 * only the first frame (EPOCH_BEGIN): every viewer of a tick gets it at the due instant, before
 * any session compresses a burst of bricks (the rest follows from the write's completion). */
static void pump_frames(ocs_session_t *s, int first) {
  while (s->streaming && s->queued < OCS_LOW_WATER && s->state == OCS_SS_READY) {
    oc_buf_t b = {0};
    int r;
    do r = ocp_epoch_enc_next(s->enc, s->version, &b);
    while (r == 1 && !first && b.len < OCS_BURST);
    if (r < 0) {
      oc_buf_free(&b);
      ocs_session_close(s, OCP_CODE_INTERNAL, oc_strerror(r));
      return;
    }
    if (r == 0) {
      s->streaming = 0;
      s->awaiting_ack = 1;
      ocp_enc_stats_t es;
      ocp_epoch_enc_stats(s->enc, &es);
      s->stats_msg.wire_bytes = es.wire_bytes;
      s->stats_msg.raw_bytes = es.raw_bytes;
      ocp_put_stats(&b, s->version, &s->stats_msg);
    }
    ocs_session_send(s, &b);
    if (first) return;
  }
}

static void pump(ocs_session_t *s) { pump_frames(s, 0); }

int ocs_session_prepare(ocs_session_t *s, const oc_state_t *base) {
  int r = ocs_session_encode(s, base);
  if (r == OC_ENOENT) return -1;
  if (r < 0) {
    ocs_session_close(s, OCP_CODE_INTERNAL, oc_strerror(r));
    return -1;
  }
  return 0;
}

int ocs_session_encode(ocs_session_t *s, const oc_state_t *base) {
  ocs_epoch_out_t o;
  if (ocs_viewer_output(s->viewer, &o) < 0) return OC_ENOENT;
  int r = ocp_epoch_enc_begin(s->enc, o.state, base, o.lacking, o.nlacking);
  if (r < 0) return r;
  /* The epoch's STATS are taken now: a step may run while the frames go out, and the world is
   * not read during a step. */
  ocs_viewer_stats_t vs;
  ocs_viewer_stats(s->viewer, &vs);
  s->stats_msg = (ocp_stats_t){.epoch = o.state->epoch, .leaves = o.plan.leaves, .splits = o.plan.splits,
                               .merges = o.plan.merges, .deferred = o.plan.deferred, .coalesced = vs.coalesced,
                               .resident_bytes = vs.resident_bytes, .plan_ms = s->srv->plan_ms,
                               .produce_ms = s->srv->produce_ms,
                               .queue = (uint32_t)ocs_world_queue_length(s->srv->world),
                               .produced = vs.produced, .split_backlog = o.plan.split_backlog};
  memcpy(s->stats_msg.age_p50, vs.age_p50, OCP_STATS_LEVELS);
  memcpy(s->stats_msg.age_p99, vs.age_p99, OCP_STATS_LEVELS);
  s->stream_epoch = o.state->epoch;
  s->stream_checksum = ocp_epoch_enc_checksum(s->enc); /* what EPOCH_END carries, in the session's form */
  s->last_out_epoch = o.state->epoch;
  s->prepared = 1;
  return 0;
}

/* A budget put in force goes out before the first state planned under it (BUDGET, version 3;
 * the world changes budgets only of viewers that speak it). */
static void tell_budget(ocs_session_t *s) {
  ocp_budget_t m;
  if (!ocs_viewer_budget_news(s->viewer, &m.budget, &m.epoch)) return;
  if (s->version < OCP_VERSION_BUDGET) return;
  oc_buf_t b = {0};
  ocp_put_budget(&b, s->version, &m);
  ocs_session_send(s, &b);
  oc_log_info("session %" PRIu32 " (viewer %s): budget %" PRIu64 " bytes from epoch %" PRIu64 " (was %" PRIu64 ")", s->id,
              s->addr, m.budget, m.epoch, s->granted.budget);
  s->granted.budget = m.budget;
  s->budgets_sent++;
}

void ocs_session_go(ocs_session_t *s) {
  if (!s->prepared) return;
  tell_budget(s);
  s->prepared = 0;
  s->streaming = 1;
  s->awaiting_ack = 0;
  s->stream_started = ocs_net_now();
  s->epochs++;
  pump_frames(s, 1);
}

void ocs_session_stream(ocs_session_t *s, const oc_state_t *base) {
  if (ocs_session_prepare(s, base) == 0) ocs_session_go(s);
}


/* ocp_viewer.c — the viewer side of the protocol as a state machine without I/O (ocp_viewer.h).
 *
 * One connection: HELLO out, WELCOME in, then epochs (EPOCH_BEGIN, RECORDS × r, BRICKS × b,
 * EPOCH_END, STATS) with KEEPALIVE and DICT in between, until GOODBYE or ERROR. Every frame is
 * checked against the connection's state before it is decoded, so an out-of-order frame is named
 * as such (ERROR UNEXPECTED) rather than as whatever its payload would break. Any failure appends
 * one ERROR frame and makes the session refuse further input until the next connection: the
 * caller sends what is in `out` and closes. */
#include "ocp_viewer.h"

#include <inttypes.h> /* PRIu64 */
#include <stdarg.h>
#include <stdio.h>  /* vsnprintf */
#include <stdlib.h> /* calloc, malloc, free */
#include <string.h> /* memset, strlen, memcpy */

#include "oc_err.h"
#include "ocp_epoch.h"

#define OCP__HELD_MAX 2                         /* K − 1 for the largest K (3, animated) */
#define OCP__FEED_CHUNK (64u << 10)             /* bytes handed to the reader at once: bounds its buffer */
#define OCP__GPU_BYTES_MAX (1u << 20)
#define OCP__VIEWPORT_MAX 65536u
#define OCP__CONTROL_JSON_MAX (OCP_MAX_CLIENT_PAYLOAD - 8u)

/* Where the current epoch is (docs/protocol.md, "Epoch": BEGIN, RECORDS × r ≥ 1, BRICKS × b). */
enum { OCP__EP_NONE = 0, OCP__EP_BEGUN, OCP__EP_RECORDS, OCP__EP_BRICKS };

struct ocp_viewer_s {
  ocp_viewer_desc_t desc; /* defaults applied; token is ours below */
  uint8_t token[OCP_TOKEN_MAX];
  uint16_t token_len;
  ocp_viewer_events_t ev;
  ocp_reader_t rd;
  ocp_epoch_dec_t *dec; /* viewer role; recreated per connection (drops half epochs, dictionaries) */
  int connections;
  int ready;   /* WELCOME seen on this connection */
  int closed;  /* GOODBYE or ERROR seen on this connection: later input is ignored */
  int failed;  /* OC_E* once we sent ERROR on this connection: later input is refused */
  uint8_t version; /* negotiated */
  int have_welcome;
  ocp_welcome_t welcome;
  uint32_t asked_session; /* resume session named in this connection's HELLO */
  oc_state_t *held[OCP__HELD_MAX]; /* newest first; lean: records only */
  oc_brick_digests_t hdig[OCP__HELD_MAX]; /* lean: held[i]'s bricks as (id, digest) */
  uint64_t hbudget[OCP__HELD_MAX];        /* the budget held[i] was planned under */
  int nheld;
  int have_pend;     /* a lowering (BUDGET) waits for the old budget's states to leave the window */
  ocp_budget_t pend;
  int have_camera;
  ocp_camera_t camera; /* the latest: sent after every WELCOME */
  int phase;           /* OCP__EP_* */
  ocp_epoch_begin_t begin;
  ocp_viewer_stats_t st;
};

/*-*** Helpers ***/

static void ocp__drop_held(ocp_viewer_t *v, int keep) {
  if (keep < 0) keep = 0;
  while (v->nheld > keep) {
    oc_state_t *s = v->held[--v->nheld];
    oc_state_free(s);
    free(s);
    v->held[v->nheld] = NULL;
    oc_brick_digests_free(&v->hdig[v->nheld]);
  }
}

/* The held state's checksum in the session's form (resume). */
static uint64_t ocp__held_checksum(const ocp_viewer_t *v, int i) {
  return v->desc.lean ? oc_state_digest_checksum(v->held[i], &v->hdig[i]) : oc_state_checksum(v->held[i]);
}

static int ocp__keep(const ocp_viewer_t *v) {
  int k = v->welcome.kept_states - 1;
  return k < 0 ? 0 : k > OCP__HELD_MAX ? OCP__HELD_MAX : k;
}

/* The version byte of what we send: the negotiated version after WELCOME; before it (an ERROR
 * about the WELCOME itself, a GOODBYE) the highest one our HELLO offered, which HELLO carried. */
static uint8_t ocp__out_version(const ocp_viewer_t *v) { return v->ready ? v->version : (uint8_t)v->desc.max_version; }

/* Fails the connection: the reason goes to why and, as an ERROR frame with `code`, to out. */
static int ocp__abort(ocp_viewer_t *v, oc_buf_t *out, int err, uint32_t code, char *why, size_t why_len, const char *fmt,
                      ...) __attribute__((format(printf, 7, 8)));
static int ocp__abort(ocp_viewer_t *v, oc_buf_t *out, int err, uint32_t code, char *why, size_t why_len, const char *fmt,
                      ...) {
  char msg[OCP_TEXT_MAX + 1];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  if (why && why_len) snprintf(why, why_len, "%s", msg);
  ocp_put_text(out, ocp__out_version(v), OCP_MSG_ERROR, code, msg);
  v->failed = err;
  return err;
}

/* A decoder or epoch error with its reason: the wire code follows the error. */
static int ocp__abort_err(ocp_viewer_t *v, oc_buf_t *out, int err, const char *reason, char *why, size_t why_len) {
  return ocp__abort(v, out, err, ocp_code_from_err(err), why, why_len, "%s", reason[0] ? reason : oc_strerror(err));
}

static int ocp__unexpected(ocp_viewer_t *v, oc_buf_t *out, const ocp_header_t *h, const char *when, char *why,
                           size_t why_len) {
  const char *name = ocp_msg_name(h->type);
  if (!name)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_UNEXPECTED, why, why_len, "frame: unknown message type 0x%02x",
                      (unsigned)h->type);
  return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_UNEXPECTED, why, why_len, "%s: not valid %s", name, when);
}

/* The frame's message into m (ocp_get_msg); a malformed one fails the connection with the decoder's
 * reason. @return 0 or the negative OC_E*. */
static int ocp__decode(ocp_viewer_t *v, const ocp_header_t *h, const uint8_t *p, ocp_msg_t *m, oc_buf_t *out, char *why,
                       size_t why_len) {
  char reason[OCP_TEXT_MAX + 1];
  reason[0] = '\0';
  int e = ocp_get_msg(h->version, h->type, p, h->length, m, reason, sizeof reason);
  return e ? ocp__abort_err(v, out, e, reason, why, why_len) : 0;
}

static const oc_brick_codes_t *ocp__lookup(void *ctx, uint32_t id) {
  const ocp_viewer_t *v = ctx;
  for (int i = 0; i < v->nheld; i++) {
    const oc_brick_t *b = oc_state_find_brick(v->held[i], id);
    if (b) return &b->codes;
  }
  return NULL;
}

static int ocp__dlookup(void *ctx, uint32_t id, uint64_t *digest) {
  const ocp_viewer_t *v = ctx;
  return oc_brick_digests_lookup(v->hdig, v->nheld, id, digest);
}

/*-*** Life cycle ***/

int ocp_viewer_create(ocp_viewer_t **out, const ocp_viewer_desc_t *desc, const ocp_viewer_events_t *ev) {
  if (!out) return OC_EINVAL;
  *out = NULL;
  if (!desc) return OC_EINVAL;
  if (desc->role != OCP_ROLE_VIEWER && desc->role != OCP_ROLE_CONTROL) return OC_EINVAL;
  if (desc->max_depth > 21) return OC_EINVAL;
  size_t tl = desc->token ? strlen(desc->token) : 0;
  if (tl > OCP_TOKEN_MAX) return OC_EINVAL;
  ocp_viewer_desc_t d = *desc;
  if (!d.max_version) d.max_version = OCP_VERSION_MAX;
  if (d.max_version < OCP_VERSION_MIN || d.max_version > OCP_VERSION_MAX) return OC_EINVAL;
  if (d.role == OCP_ROLE_VIEWER) {
    if (!d.slot_bytes) d.slot_bytes = OC_SLOT_BYTES;
    if (!d.record_bytes) d.record_bytes = OC_RECORD_BYTES;
    if (d.budget == 0 || d.slot_bytes > OCP__GPU_BYTES_MAX || d.record_bytes > OCP__GPU_BYTES_MAX) return OC_EINVAL;
    if (d.width < 1 || d.width > OCP__VIEWPORT_MAX || d.height < 1 || d.height > OCP__VIEWPORT_MAX) return OC_EINVAL;
    if (d.caps & ~OCP_CAP_KNOWN) return OC_EINVAL;
    /* lean and the DIGEST bit say the same; a viewer without codes cannot apply deltas */
    d.lean = d.lean || (d.caps & OCP_CAP_DIGEST);
    if (d.lean) d.caps |= OCP_CAP_DIGEST;
    if (d.lean && (d.caps & OCP_CAP_DELTA)) return OC_EINVAL;
  } else {
    d.lean = 0;
  }
  ocp_viewer_t *v = calloc(1, sizeof *v);
  if (!v) return OC_ENOMEM;
  v->desc = d;
  v->desc.token = NULL;
  if (tl) memcpy(v->token, desc->token, tl);
  v->token_len = (uint16_t)tl;
  if (ev) v->ev = *ev;
  ocp_reader_init(&v->rd, OCP_MAX_PAYLOAD);
  *out = v;
  return 0;
}

void ocp_viewer_free(ocp_viewer_t *v) {
  if (!v) return;
  ocp_reader_free(&v->rd);
  ocp_epoch_dec_free(v->dec);
  ocp__drop_held(v, 0);
  free(v);
}

void ocp_viewer_connected(ocp_viewer_t *v, oc_buf_t *out) {
  if (v->connections++) v->st.reconnects++;
  ocp_reader_free(&v->rd);
  ocp_reader_init(&v->rd, OCP_MAX_PAYLOAD);
  ocp_epoch_dec_free(v->dec);
  v->dec = NULL;
  if (v->desc.role == OCP_ROLE_VIEWER && ocp_epoch_dec_create(&v->dec) < 0) v->dec = NULL; /* retried in feed */
  v->ready = v->closed = v->failed = 0;
  v->phase = OCP__EP_NONE;

  ocp_hello_t h;
  memset(&h, 0, sizeof h);
  h.min_version = OCP_VERSION_MIN;
  h.max_version = v->desc.max_version;
  h.role = v->desc.role;
  h.max_depth = v->desc.max_depth;
  h.token_len = v->token_len;
  memcpy(h.token, v->token, v->token_len);
  if (v->desc.role == OCP_ROLE_VIEWER) { /* control clients send these as zero */
    h.ask = v->desc.ask;
    h.kept_states = 0; /* the server decides K */
    h.width = v->have_camera ? v->camera.width : v->desc.width; /* a resized window's viewport */
    h.height = v->have_camera ? v->camera.height : v->desc.height;
    h.caps = v->desc.caps;
    if (v->have_welcome) {
      h.resume_session = v->welcome.session;
      h.resume_secret = v->welcome.secret;
      if (v->nheld) {
        h.held_epoch = v->held[0]->epoch;
        h.held_checksum = ocp__held_checksum(v, 0);
      }
    }
  }
  v->asked_session = h.resume_session;
  ocp_put_hello(out, &h);
}

/*-*** Frames ***/

/* A pending lowering takes effect once no held state was planned under the old budget: the
 * window (the held states and the one arriving next, which is planned under the new one) then
 * fits the new budget, and the store may shrink. */
static void ocp__budget_settle(ocp_viewer_t *v) {
  if (!v->have_pend) return;
  for (int i = 0; i < v->nheld; i++)
    if (v->held[i]->epoch < v->pend.epoch) return;
  v->have_pend = 0;
  if (v->welcome.budget == v->pend.budget) return; /* a raise, in force already */
  v->welcome.budget = v->pend.budget;
  if (v->ev.budget) v->ev.budget(v->ev.ctx, &v->welcome.grant);
}

static int ocp__on_welcome(ocp_viewer_t *v, const ocp_header_t *h, const ocp_welcome_t *w, oc_buf_t *out, char *why,
                           size_t why_len) {
  if (w->version < OCP_VERSION_MIN || w->version > v->desc.max_version)
    return ocp__abort(v, out, OC_EVERSION, OCP_CODE_VERSION, why, why_len, "welcome: version %u is outside %d..%u",
                      (unsigned)w->version, OCP_VERSION_MIN, (unsigned)v->desc.max_version);
  if (h->version != w->version)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "welcome: frame version %u differs from the chosen version %u", (unsigned)h->version,
                      (unsigned)w->version);
  if ((v->desc.role == OCP_ROLE_VIEWER) != (w->kept_states != 0))
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len, "welcome: kept_states %u for a %s",
                      (unsigned)w->kept_states, v->desc.role == OCP_ROLE_VIEWER ? "viewer" : "control client");
  int resumed = (w->flags & OCP_WELCOME_RESUMED) != 0;
  if (resumed && (v->asked_session == 0 || w->session != v->asked_session))
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "welcome: resumed session %" PRIu32 ", but hello asked to resume %" PRIu32, w->session,
                      v->asked_session);
  v->welcome = *w;
  v->have_welcome = 1;
  v->ready = 1;
  v->version = (uint8_t)w->version;
  /* a new session: nothing held is valid any more (its bricks' ids mean other content) */
  ocp__drop_held(v, resumed ? ocp__keep(v) : 0);
  /* WELCOME names the budget in force; a BUDGET still pending is sent again after it */
  v->have_pend = 0;
  for (int i = 0; i < v->nheld; i++) v->hbudget[i] = w->budget;
  if (resumed) v->st.resumed++;
  if (v->ev.welcome) v->ev.welcome(v->ev.ctx, &v->welcome, resumed);
  if (v->have_camera && v->desc.role == OCP_ROLE_VIEWER) ocp_put_camera(out, v->version, &v->camera);
  return 0;
}

static int ocp__on_epoch_begin(ocp_viewer_t *v, const ocp_epoch_begin_t *m, oc_buf_t *out, char *why, size_t why_len) {
  const oc_state_t *base = NULL;
  if (m->base_epoch != OCP_NO_BASE) {
    for (int i = 0; i < v->nheld && !base; i++)
      if (v->held[i]->epoch == m->base_epoch) base = v->held[i];
    if (!base)
      return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                        "epoch-begin: base_epoch %" PRIu64 " is not a state this viewer holds", m->base_epoch);
  }
  char reason[OCP_TEXT_MAX + 1];
  reason[0] = '\0';
  int e = v->desc.lean ? ocp_epoch_dec_begin_lean(v->dec, m, base, ocp__dlookup, v, reason, sizeof reason)
                       : ocp_epoch_dec_begin(v->dec, m, base, ocp__lookup, v, reason, sizeof reason);
  if (e) return ocp__abort_err(v, out, e, reason, why, why_len);
  v->begin = *m;
  v->phase = OCP__EP_BEGUN;
  return 0;
}

static int ocp__on_epoch_end(ocp_viewer_t *v, const ocp_epoch_end_t *m, oc_buf_t *out, char *why, size_t why_len) {
  v->phase = OCP__EP_NONE;
  if (m->epoch != v->begin.epoch)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "epoch-end: epoch %" PRIu64 " differs from epoch-begin's %" PRIu64, m->epoch, v->begin.epoch);
  oc_state_t *s = malloc(sizeof *s);
  if (!s) return ocp__abort(v, out, OC_ENOMEM, OCP_CODE_INTERNAL, why, why_len, "epoch-end: out of memory");
  oc_state_init(s);
  oc_brick_digests_t dig = {0};
  char reason[OCP_TEXT_MAX + 1];
  reason[0] = '\0';
  int e = v->desc.lean ? ocp_epoch_dec_end_lean(v->dec, m, s, &dig, reason, sizeof reason)
                       : ocp_epoch_dec_end(v->dec, m, s, reason, sizeof reason);
  if (e) {
    oc_state_free(s);
    free(s);
    return ocp__abort_err(v, out, e, reason, why, why_len);
  }
  /* The budget bounds the window of K states: the new one and the K − 1 held (nheld ≤ K − 1).
   * A lean session counts the same ids, from its digests. */
  const oc_state_t *window[OCP__HELD_MAX + 1] = {s};
  const oc_brick_digests_t *dwindow[OCP__HELD_MAX + 1] = {&dig};
  for (int i = 0; i < v->nheld; i++) window[i + 1] = v->held[i], dwindow[i + 1] = &v->hdig[i];
  uint64_t resident = v->desc.lean
                          ? oc_resident_bytes_lean(window, dwindow, v->nheld + 1, v->welcome.slot_bytes, v->welcome.record_bytes)
                          : oc_resident_bytes(window, v->nheld + 1, v->welcome.slot_bytes, v->welcome.record_bytes);
  v->st.resident_bytes = resident;
  if (resident > v->st.resident_peak) v->st.resident_peak = resident;
  /* the window's budget: the largest its states were planned under (an old one stays reserved
   * until its states have left) */
  uint64_t planned = v->have_pend && m->epoch >= v->pend.epoch ? v->pend.budget : v->welcome.budget, allowed = planned;
  for (int i = 0; i < v->nheld && i < ocp__keep(v); i++)
    if (v->hbudget[i] > allowed) allowed = v->hbudget[i];
  if (resident > allowed) v->st.over_budget++;
  /* push as newest; the oldest of the window goes */
  ocp__drop_held(v, ocp__keep(v) - 1);
  memmove(&v->held[1], &v->held[0], (size_t)v->nheld * sizeof v->held[0]);
  memmove(&v->hdig[1], &v->hdig[0], (size_t)v->nheld * sizeof v->hdig[0]);
  memmove(&v->hbudget[1], &v->hbudget[0], (size_t)v->nheld * sizeof v->hbudget[0]);
  v->held[0] = s;
  v->hdig[0] = dig;
  v->hbudget[0] = planned;
  v->nheld++;
  ocp__budget_settle(v);
  v->st.states++;
  v->st.bricks_in += v->begin.bricks_sent;
  ocp_ack_t ack = {m->epoch, m->checksum};
  ocp_put_ack(out, v->version, &ack);
  if (v->ev.state) v->ev.state(v->ev.ctx, s, v->begin.bricks_sent);
  return 0;
}

/* BUDGET (version 3): between epochs, at least the minimum, for an epoch after the newest held. */
static int ocp__on_budget(ocp_viewer_t *v, const ocp_header_t *h, const uint8_t *p, oc_buf_t *out, char *why,
                          size_t why_len) {
  if (v->desc.role != OCP_ROLE_VIEWER) return ocp__unexpected(v, out, h, "for a control client", why, why_len);
  if (v->version < OCP_VERSION_BUDGET)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_UNEXPECTED, why, why_len, "budget: not in protocol version %u",
                      (unsigned)v->version);
  if (v->phase != OCP__EP_NONE) return ocp__unexpected(v, out, h, "inside an epoch", why, why_len);
  ocp_msg_t msg;
  OC_TRY(ocp__decode(v, h, p, &msg, out, why, why_len));
  const ocp_budget_t m = msg.budget;
  uint64_t mn = oc_budget_min(&v->welcome.grant);
  if (m.budget < mn)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "budget: %" PRIu64 " bytes is below the minimum %" PRIu64 " (K = %d)", m.budget, mn,
                      v->welcome.kept_states);
  uint64_t newest = v->nheld ? v->held[0]->epoch : 0;
  if (v->nheld && m.epoch <= newest)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "budget: effective epoch %" PRIu64 " is not after the newest state's %" PRIu64, m.epoch, newest);
  if (v->have_pend && m.epoch < v->pend.epoch)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len,
                      "budget: effective epoch %" PRIu64 " is before the pending one's %" PRIu64, m.epoch, v->pend.epoch);
  v->st.budgets++;
  if (m.budget > v->welcome.budget) { /* a raise holds at once: the store must take states planned under it */
    v->welcome.budget = m.budget;
    if (v->ev.budget) v->ev.budget(v->ev.ctx, &v->welcome.grant);
  }
  if (m.budget == v->welcome.budget && !v->have_pend) return 0;
  /* a lowering, or any change while one is pending: the budget in force stays until the states
   * planned under the larger one have left */
  v->have_pend = 1;
  v->pend = m;
  ocp__budget_settle(v); /* nothing held: at once */
  return 0;
}

/* One whole frame from the server. */
static int ocp__frame(ocp_viewer_t *v, const ocp_header_t *h, const uint8_t *p, oc_buf_t *out, char *why, size_t why_len) {
  char reason[OCP_TEXT_MAX + 1];
  ocp_msg_t m;
  int viewer = v->desc.role == OCP_ROLE_VIEWER, e;
  reason[0] = '\0';
  if (v->ready && h->version != v->version)
    return ocp__abort(v, out, OC_ECORRUPT, OCP_CODE_MALFORMED, why, why_len, "%s: frame version %u, negotiated %u",
                      ocp_msg_name(h->type) ? ocp_msg_name(h->type) : "frame", (unsigned)h->version,
                      (unsigned)v->version);
  switch (h->type) {
    case OCP_MSG_GOODBYE:
    case OCP_MSG_ERROR: {
      OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
      v->closed = 1;
      if (v->ev.closed) v->ev.closed(v->ev.ctx, m.text.code, m.text.text);
      return 0;
    }
    case OCP_MSG_WELCOME:
      if (v->ready) return ocp__unexpected(v, out, h, "twice on one connection", why, why_len);
      OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
      return ocp__on_welcome(v, h, &m.welcome, out, why, why_len);
    default:
      break;
  }
  if (!v->ready) return ocp__unexpected(v, out, h, "before welcome", why, why_len);
  switch (h->type) {
    case OCP_MSG_KEEPALIVE:
      return ocp__decode(v, h, p, &m, out, why, why_len);
    case OCP_MSG_DICT:
      if (!viewer) return ocp__unexpected(v, out, h, "for a control client", why, why_len);
      e = ocp_epoch_dec_dict(v->dec, p, h->length, reason, sizeof reason);
      return e ? ocp__abort_err(v, out, e, reason, why, why_len) : 0;
    case OCP_MSG_EPOCH_BEGIN:
      if (!viewer) return ocp__unexpected(v, out, h, "for a control client", why, why_len);
      if (v->phase != OCP__EP_NONE) return ocp__unexpected(v, out, h, "inside an epoch", why, why_len);
      OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
      return ocp__on_epoch_begin(v, &m.begin, out, why, why_len);
    case OCP_MSG_RECORDS:
    case OCP_MSG_BRICKS:
    case OCP_MSG_EPOCH_END: { /* RECORDS follow the BEGIN or RECORDS; BRICKS and the END, RECORDS or BRICKS */
      int records = h->type == OCP_MSG_RECORDS;
      int after = records ? OCP__EP_BEGUN : OCP__EP_RECORDS, next = records ? OCP__EP_RECORDS : OCP__EP_BRICKS;
      if (v->phase != after && v->phase != next)
        return ocp__unexpected(v, out, h, v->phase == OCP__EP_NONE ? "outside an epoch" : records ? "after bricks" : "before records",
                               why, why_len);
      if (h->type == OCP_MSG_EPOCH_END) {
        OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
        return ocp__on_epoch_end(v, &m.end, out, why, why_len);
      }
      e = records ? ocp_epoch_dec_records(v->dec, p, h->length, reason, sizeof reason)
                  : ocp_epoch_dec_bricks(v->dec, p, h->length, reason, sizeof reason);
      if (e) return ocp__abort_err(v, out, e, reason, why, why_len);
      v->phase = next;
      return 0;
    }
    case OCP_MSG_STATS: {
      if (!viewer) return ocp__unexpected(v, out, h, "for a control client", why, why_len);
      if (v->phase != OCP__EP_NONE) return ocp__unexpected(v, out, h, "inside an epoch", why, why_len);
      OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
      if (v->ev.stats) v->ev.stats(v->ev.ctx, &m.stats);
      return 0;
    }
    case OCP_MSG_BUDGET:
      return ocp__on_budget(v, h, p, out, why, why_len);
    case OCP_MSG_CONTROL_REPLY: {
      if (viewer) return ocp__unexpected(v, out, h, "for a viewer", why, why_len);
      OC_TRY(ocp__decode(v, h, p, &m, out, why, why_len));
      if (v->ev.control_reply) v->ev.control_reply(v->ev.ctx, &m.control);
      return 0;
    }
    default: /* unknown, or a client's message */
      return ocp__unexpected(v, out, h, "from a server", why, why_len);
  }
}

int ocp_viewer_feed(ocp_viewer_t *v, const void *p, size_t n, oc_buf_t *out, char *why, size_t why_len) {
  if (why && why_len) why[0] = '\0';
  if (v->failed) {
    if (why && why_len) snprintf(why, why_len, "the connection already failed: %s", oc_strerror(v->failed));
    return v->failed;
  }
  const uint8_t *q = p;
  while (n && !v->closed) {
    size_t k = n < OCP__FEED_CHUNK ? n : OCP__FEED_CHUNK;
    v->st.bytes_in += k;
    if (ocp_reader_feed(&v->rd, q, k) < 0)
      return ocp__abort(v, out, OC_ENOMEM, OCP_CODE_INTERNAL, why, why_len, "frame: out of memory");
    q += k;
    n -= k;
    while (!v->closed) {
      ocp_header_t h;
      const uint8_t *payload;
      int r = ocp_reader_next(&v->rd, &h, &payload);
      if (r == 0) break;
      if (r == OC_ETOOBIG)
        return ocp__abort(v, out, r, OCP_CODE_TOO_BIG, why, why_len, "frame: payload of %" PRIu32 " bytes is above %u",
                          oc_get_u32(v->rd.buf.data + v->rd.start + 4), (unsigned)OCP_MAX_PAYLOAD);
      if (r == OC_ECORRUPT)
        return ocp__abort(v, out, r, OCP_CODE_MALFORMED, why, why_len, "frame: bad magic 0x%02x 0x%02x",
                          (unsigned)v->rd.buf.data[v->rd.start], (unsigned)v->rd.buf.data[v->rd.start + 1]);
      if (r < 0) return ocp__abort(v, out, r, ocp_code_from_err(r), why, why_len, "frame: %s", oc_strerror(r));
      v->st.frames_in++;
      if (v->desc.role == OCP_ROLE_VIEWER && !v->dec && ocp_epoch_dec_create(&v->dec) < 0) {
        v->dec = NULL;
        return ocp__abort(v, out, OC_ENOMEM, OCP_CODE_INTERNAL, why, why_len, "epoch decoder: out of memory");
      }
      int e = ocp__frame(v, &h, payload, out, why, why_len);
      if (e) return e;
    }
  }
  if (n) v->st.bytes_in += n; /* after GOODBYE or ERROR: counted, not parsed */
  return 0;
}

/*-*** Outgoing ***/

int ocp_viewer_camera(ocp_viewer_t *v, const ocp_camera_t *c, oc_buf_t *out) {
  if (!c || v->desc.role != OCP_ROLE_VIEWER) return OC_EINVAL;
  /* check with the server's own decoder, so a bad camera fails here and not as an ERROR later */
  oc_buf_t tmp = {0};
  ocp_camera_t back;
  ocp_put_camera(&tmp, ocp__out_version(v), c);
  int e = tmp.err ? OC_ENOMEM : ocp_get_camera(tmp.data + OCP_HEADER_BYTES, tmp.len - OCP_HEADER_BYTES, &back, NULL, 0);
  oc_buf_free(&tmp);
  if (e) return e == OC_ENOMEM ? e : OC_EINVAL;
  v->camera = *c;
  v->have_camera = 1;
  if (v->ready && !v->closed && !v->failed) ocp_put_camera(out, v->version, c);
  return 0;
}

int ocp_viewer_control(ocp_viewer_t *v, uint32_t request, const char *json, oc_buf_t *out) {
  if (!json || v->desc.role != OCP_ROLE_CONTROL || !v->ready || v->closed || v->failed) return OC_EINVAL;
  size_t n = strlen(json);
  if (n > OCP__CONTROL_JSON_MAX) return OC_EINVAL;
  ocp_control_t c = {request, 0, json, (uint32_t)n};
  ocp_put_control(out, v->version, OCP_MSG_CONTROL, &c);
  return 0;
}

void ocp_viewer_keepalive(ocp_viewer_t *v, oc_buf_t *out) {
  /* before WELCOME the version is not known yet, and the handshake has its own timeout */
  if (v->ready && !v->closed && !v->failed) ocp_put_empty(out, v->version, OCP_MSG_KEEPALIVE);
}

void ocp_viewer_goodbye(ocp_viewer_t *v, oc_buf_t *out) {
  ocp_put_text(out, ocp__out_version(v), OCP_MSG_GOODBYE, OCP_CODE_OK, "");
}

/*-*** Queries ***/

int ocp_viewer_ready(const ocp_viewer_t *v) { return v->ready; }

const ocp_welcome_t *ocp_viewer_welcome(const ocp_viewer_t *v) { return v->have_welcome ? &v->welcome : NULL; }

const oc_state_t *ocp_viewer_state(const ocp_viewer_t *v, int i) {
  return i >= 0 && i < v->nheld ? v->held[i] : NULL;
}

const oc_brick_digests_t *ocp_viewer_digests(const ocp_viewer_t *v, int i) {
  return v->desc.lean && i >= 0 && i < v->nheld ? &v->hdig[i] : NULL;
}

void ocp_viewer_stats(const ocp_viewer_t *v, ocp_viewer_stats_t *out) {
  *out = v->st;
  /* What the kept states' arrays take in this process (capacities: what is allocated). */
  uint64_t held = 0;
  for (int i = 0; i < v->nheld; i++) {
    held += (uint64_t)v->held[i]->node_cap * sizeof(oc_node_t) + (uint64_t)v->held[i]->brick_cap * sizeof(oc_brick_t);
    held += (uint64_t)v->hdig[i].count * (sizeof *v->hdig[i].ids + sizeof *v->hdig[i].digests);
  }
  out->held_bytes = held;
}

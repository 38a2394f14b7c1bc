/* control_stream.c — the control history in a Redis Stream (control_stream.h; docs/scale-out.md,
 * "Control: the history in a Redis Stream").
 *
 * An entry, field-exact (every value a decimal or "%.17g" string, which reads back to the same
 * double):
 *   v 1  op OP  fe FRONTEND(16 hex)  req N  epoch E  [the op's fields]
 *   origin:  utc U  time T          weather: preset NAME  seconds S
 *   time:    [set T] [scale S]      sun:     x X  y Y  z Z (a unit vector)
 *   step:    epochs N               pause, resume: none
 * ids are Redis's own (`*`: its clock in ms, then a sequence), except the origin's, 0-1. The epoch
 * a change takes effect at is a field, not the id: an append cannot know the stream's top, which
 * the id must exceed, and an id far ahead (a bad entry, another clock) would push every later
 * change after it; an entry's epoch is max(its field, the previous entry's), which every reader
 * computes alike from the same order.
 *
 * Reading: XREAD COUNT 256 from the last id read, without BLOCK until the end of the history, then
 * with BLOCK OCS_CTL_BLOCK_MS; each command has a uv_timer deadline (redis_client.h), and the next
 * read is started from a timer, never from inside a reply. Entries go to a queue, applied in order
 * while the world is idle: a clocked entry when the next tick to be built is its epoch or later
 * (its predecessors first), a stepped change once the steps before it are done. */
#include "control_stream.h"

#include <cjson/cJSON.h>
#include <hiredis/hiredis.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "net_internal.h"
#include "oc_bytes.h" /* oc_grow */
#include "oc_err.h"
#include "oc_log.h"
#include "redis_client.h"

#define OCS_CTL_COUNT 256     /* entries per XREAD */
#define OCS_CTL_WRITE_MS 2000 /* an append's deadline at least (the operator waits for it) */
/* An entry whose epoch is this far after its own id's instant (Redis's clock at the append) is skipped. */
#define OCS_CTL_AHEAD_MAX_S 86400.0

static const char *const chg_names[OCS_CHG_COUNT] = {"origin", "weather", "time", "pause", "resume", "sun", "step"};

const char *ocs_change_name(int op) { return op >= 0 && op < OCS_CHG_COUNT ? chg_names[op] : NULL; }

int ocs_change_apply(ocs_world_t *w, const ocs_change_t *c, double utc) {
  int r;
  switch (c->op) {
  case OCS_CHG_ORIGIN: return ocs_world_set_origin(w, c->utc, c->time);
  case OCS_CHG_WEATHER: return ocs_world_set_weather(w, utc, (oc_preset_t)c->preset, c->seconds);
  case OCS_CHG_TIME:
    r = isnan(c->set) ? 0 : ocs_world_set_time(w, utc, c->set);
    if (r >= 0 && !isnan(c->scale)) r = ocs_world_set_time_scale(w, utc, c->scale);
    return r;
  case OCS_CHG_PAUSE: return ocs_world_pause(w, utc);
  case OCS_CHG_RESUME: return ocs_world_resume(w, utc);
  case OCS_CHG_SUN: return ocs_world_set_sun(w, c->sun);
  default: return OC_EINVAL;
  }
}

uint64_t ocs_ctl_epoch_ahead(double utc, double period) {
  double margin = 0.5 * period + (period > 0.25 ? period : 0.25);
  return (uint64_t)ceil((utc + margin) / period) + 1;
}

/* An entry read, waiting to be applied. */
typedef struct {
  char id[48];
  ocs_change_t chg;
  uint64_t fe, req;
  uint64_t epoch; /* clocked: the epoch it takes effect at (max with the previous) */
} ocs__entry_t;

/* A request of this front-end whose entry has not been applied here yet. */
typedef struct {
  uint64_t req;
  uint32_t session, request;
  int op;
} ocs__mine_t;

struct ocs_ctl_s {
  ocs_server_t *srv;
  ocs_redis_t *rd, *wr;
  uint64_t fe, next_req;
  uint32_t deadline_ms;
  char host[300];
  uv_timer_t kick, catchup;
  int open_handles, closing;
  int reading;            /* an XREAD in flight */
  int at_end;             /* a read found the end of the history */
  int origin_seen;        /* an origin entry was read */
  int origin_sent;        /* our origin's append: 1 in flight, 2 answered */
  int started;            /* the epochs run (ocs_epoch_start_timer() called) */
  int applying_history;   /* before the first epoch: late entries are history, not late */
  int read_error;         /* the last read failed: the next one waits a little */
  char last_id[48];
  uint64_t last_epoch;    /* clocked: the previous entry's epoch */
  uint64_t steps_seen;    /* stepped: epochs the step entries read so far step */
  ocs__entry_t *q;        /* read, not applied: q[qhead .. qlen) */
  size_t qhead, qlen, qcap;
  ocs__mine_t *mine;
  size_t nmine, mine_cap;
  ocs_ctl_stats_t st;
};

static void ocs__kick_soon(ocs_ctl_t *c, uint64_t ms);

static double ocs__period(const ocs_ctl_t *c) { return c->srv->period; }
/* The instant of epoch n: on the clock n·P; stepped, the virtual clock's n·(the scene's period). */
static double ocs__instant(const ocs_ctl_t *c, uint64_t n) {
  double p = c->srv->period > 0 ? c->srv->period : c->srv->scene.epoch_period;
  return (double)n * p;
}

static void ocs__start_epochs(ocs_ctl_t *c, const char *why) {
  if (c->started) return;
  c->started = 1;
  c->st.caught_up = 1;
  uv_timer_stop(&c->catchup);
  if (!c->srv->stopping) ocs_epoch_start_timer(c->srv); /* armed for the first tick: entries up to it apply now */
  ocs_ctl_idle(c); /* the history before the first epoch */
  c->applying_history = 0;
  oc_log_info("control history (redis %s, stream %s): %s; %" PRIu64 " entries read, %" PRIu64 " applied, %" PRIu64
              " skipped", c->host, OCS_CTL_STREAM, why, c->st.read, c->st.applied, c->st.skipped);
}

static void ocs__on_catchup_deadline(uv_timer_t *t) {
  ocs_ctl_t *c = t->data;
  if (c->started || c->closing) return;
  oc_log_warn("control history (redis %s): not read within %.0f s; serving with this front-end's clock until it is "
              "(entries read later for epochs already built are counted late)", c->host, OCS_CTL_CATCHUP_S);
  ocs__start_epochs(c, "given up waiting");
}

/*-*** Entries: parsing ***/

static const char *ocs__field(const redisReply *f, const char *name) {
  for (size_t i = 0; i + 1 < f->elements; i += 2)
    if (f->element[i]->type == REDIS_REPLY_STRING && f->element[i + 1]->type == REDIS_REPLY_STRING &&
        !strcmp(f->element[i]->str, name))
      return f->element[i + 1]->str;
  return NULL;
}

/* A finite double, or NAN (absent, or not a whole number text). */
static double ocs__num(const redisReply *f, const char *name) {
  const char *s = ocs__field(f, name);
  if (!s || !*s) return NAN;
  char *end;
  double v = strtod(s, &end);
  return *end || !isfinite(v) ? NAN : v;
}

static int ocs__u64(const redisReply *f, const char *name, int base, uint64_t *out) {
  const char *s = ocs__field(f, name);
  if (!s || !*s || *s == '-') return -1;
  char *end;
  unsigned long long v = strtoull(s, &end, base);
  if (*end) return -1;
  *out = v;
  return 0;
}

/* Reads entry `id` with fields f into e. @return 0, or -1 after writing why it is skipped. */
static int ocs__parse(const ocs_ctl_t *c, const char *id, const redisReply *f, ocs__entry_t *e, char *why, size_t n) {
  memset(e, 0, sizeof *e);
  snprintf(e->id, sizeof e->id, "%s", id);
  if (!f || f->type != REDIS_REPLY_ARRAY || f->elements % 2) return oc_errorf(-1, why, n, "no field list");
  uint64_t v;
  if (ocs__u64(f, "v", 10, &v) < 0) return oc_errorf(-1, why, n, "no version \"v\"");
  if (v > OCS_CTL_VERSION)
    return oc_errorf(-1, why, n, "from a newer version (v %" PRIu64 "; this front-end reads %d)", v, OCS_CTL_VERSION);
  const char *op = ocs__field(f, "op");
  int k = -1;
  for (int i = 0; op && i < OCS_CHG_COUNT; i++)
    if (!strcmp(op, chg_names[i])) k = i;
  if (k < 0) return oc_errorf(-1, why, n, "unknown op \"%.32s\"", op ? op : "(none)");
  ocs_change_t *g = &e->chg;
  g->op = (ocs_chg_op_t)k;
  g->set = g->scale = NAN;
  if (ocs__u64(f, "fe", 16, &e->fe) < 0 || ocs__u64(f, "req", 10, &e->req) < 0)
    return oc_errorf(-1, why, n, "%s: no \"fe\" or \"req\"", op);
  const char *ps;
  double x, y, z, l;
  switch (g->op) {
  case OCS_CHG_ORIGIN:
    g->utc = ocs__num(f, "utc");
    g->time = ocs__num(f, "time");
    if (!(fabs(g->time) <= 1e12) || isnan(g->utc)) return oc_errorf(-1, why, n, "origin: bad \"utc\" or \"time\"");
    return 0;
  case OCS_CHG_WEATHER:
    ps = ocs__field(f, "preset");
    g->preset = ps ? oc_scene_preset_parse(ps) : OC_EINVAL;
    g->seconds = ocs__num(f, "seconds");
    if (g->preset < 0 || !(g->seconds >= 0 && g->seconds <= 1e7))
      return oc_errorf(-1, why, n, "weather: bad \"preset\" or \"seconds\"");
    break;
  case OCS_CHG_TIME:
    g->set = ocs__num(f, "set");
    g->scale = ocs__num(f, "scale");
    if ((isnan(g->set) && isnan(g->scale)) || (!isnan(g->set) && !(fabs(g->set) <= 1e12)) ||
        (!isnan(g->scale) && !(g->scale >= 0 && g->scale <= 1e6)))
      return oc_errorf(-1, why, n, "time: bad \"set\" or \"scale\"");
    break;
  case OCS_CHG_SUN:
    x = ocs__num(f, "x"), y = ocs__num(f, "y"), z = ocs__num(f, "z");
    l = sqrt(x * x + y * y + z * z);
    if (!(l > 1e-9 && isfinite(l))) return oc_errorf(-1, why, n, "sun: bad \"x\", \"y\" or \"z\"");
    g->sun = oc_dv3(x, y, z);
    break;
  case OCS_CHG_STEP:
    if (ocs__u64(f, "epochs", 10, &v) < 0 || v < 1 || v > 1000) return oc_errorf(-1, why, n, "step: bad \"epochs\"");
    if (ocs__period(c) > 0) return oc_errorf(-1, why, n, "step: epochs tick on the clock here (a stepped front-end's entry)");
    g->epochs = (uint32_t)v;
    break;
  default: break;
  }
  if (ocs__period(c) > 0) { /* clocked: its epoch, not too far after its own append */
    uint64_t ms = strtoull(id, NULL, 10);
    if (ocs__u64(f, "epoch", 10, &e->epoch) < 0) return oc_errorf(-1, why, n, "%s: no \"epoch\"", op);
    if ((double)e->epoch * ocs__period(c) > 1e-3 * (double)ms + OCS_CTL_AHEAD_MAX_S)
      return oc_errorf(-1, why, n, "%s: epoch %" PRIu64 " is more than %.0f s after the entry was appended", op, e->epoch,
                       OCS_CTL_AHEAD_MAX_S);
  }
  return 0;
}

/*-*** Entries: applying ***/

static int ocs__mine_find(const ocs_ctl_t *c, uint64_t req) {
  for (size_t i = 0; i < c->nmine; i++)
    if (c->mine[i].req == req) return (int)i;
  return -1;
}

static void ocs__mine_drop(ocs_ctl_t *c, int i) { c->mine[i] = c->mine[--c->nmine]; }

static void ocs__push(ocs_ctl_t *c, const ocs__entry_t *e) {
  if (c->qhead && c->qhead == c->qlen) c->qhead = c->qlen = 0;
  if (c->qlen == c->qcap) {
    if (c->qhead) { /* room at the front */
      memmove(c->q, c->q + c->qhead, (c->qlen - c->qhead) * sizeof *c->q);
      c->qlen -= c->qhead;
      c->qhead = 0;
    } else {
      size_t nc = c->qcap ? 2 * c->qcap : 64;
      ocs__entry_t *a = realloc(c->q, nc * sizeof *a);
      if (!a) { /* cannot happen in practice: a few entries an hour */
        oc_log_error("control history: no memory for entry %s: skipped (this front-end's world may differ)", e->id);
        return;
      }
      c->q = a;
      c->qcap = nc;
    }
  }
  c->q[c->qlen++] = *e;
}

/* The next tick this front-end builds is `epoch` or later: at an idle point the epoch timer is
 * armed for the next tick (net_epoch.c), before the first one too (ocs__start_epochs()). */
static int ocs__due_now(const ocs_ctl_t *c, uint64_t epoch) {
  const ocs_server_t *srv = c->srv;
  return ocs_world_epoch(srv->world) + 1 >= epoch || (c->started && srv->armed_epoch >= epoch);
}

/* The operator's reply for one of our entries, once applied here. */
static void ocs__answer(ocs_ctl_t *c, const ocs__entry_t *e, uint64_t epoch, double t) {
  if (e->fe != c->fe) return;
  int k = ocs__mine_find(c, e->req);
  if (k < 0) return;
  ocs__mine_t m = c->mine[k];
  ocs__mine_drop(c, k);
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "entry", e->id);
  cJSON_AddNumberToObject(o, "epoch", (double)epoch);
  cJSON_AddNumberToObject(o, "utc", ocs__instant(c, epoch));
  cJSON_AddNumberToObject(o, "time", t);
  cJSON_AddBoolToObject(o, "shared", 1);
  ocs_control_reply_later(c->srv, m.session, m.request, o, NULL);
}

/* Applies the queue's head if it is due. @return 1 applied (or dropped), 0 not yet. */
static int ocs__apply_head(ocs_ctl_t *c) {
  ocs_server_t *srv = c->srv;
  ocs__entry_t *e = &c->q[c->qhead];
  const ocs_change_t *g = &e->chg;
  uint64_t now_epoch = ocs_world_epoch(srv->world);
  if (g->op == OCS_CHG_ORIGIN) {
    if (c->started && !c->applying_history) {
      oc_log_warn("control history: entry %s: an origin after this front-end's first epoch: ignored (it keeps its clock)",
                  e->id);
    } else if (ocs_change_apply(srv->world, g, 0.0) < 0) {
      oc_log_warn("control history: entry %s: origin refused by the world: skipped", e->id);
      c->st.skipped++;
    } else {
      c->st.applied++;
    }
    return 1;
  }
  uint64_t epoch;
  if (srv->period > 0) {
    epoch = e->epoch;
    if (!ocs__due_now(c, epoch)) return 0;
  } else {
    if (g->op == OCS_CHG_STEP) {
      epoch = c->steps_seen + 1;
      c->steps_seen += g->epochs;
      if (e->fe == c->fe) {
        int k = ocs__mine_find(c, e->req);
        ocs_session_t *s = k >= 0 ? ocs_session_find(srv, c->mine[k].session) : NULL;
        if (s && s->step_waiting && s->step_request == c->mine[k].request)
          s->step_target = srv->steps_done + srv->steps_queued + g->epochs;
        if (k >= 0) ocs__mine_drop(c, k);
      }
      c->st.applied++;
      c->st.last_epoch = epoch;
      snprintf(c->st.last_op, sizeof c->st.last_op, "%s", "step");
      ocs_server_queue_steps(srv, g->epochs);
      return 1;
    }
    if (srv->steps_queued || srv->stepping) return 0;
    epoch = c->steps_seen + 1;
  }
  if (epoch <= now_epoch && !c->applying_history) {
    c->st.late++;
    oc_log_warn("control history: entry %s (%s) for epoch %" PRIu64 " read after this front-end built epoch %" PRIu64
                ": applied late", e->id, ocs_change_name(g->op), epoch, now_epoch);
  }
  double utc = ocs__instant(c, epoch);
  int r = ocs_change_apply(srv->world, g, utc);
  if (r < 0) { /* alike on every front-end of one scene (e.g. weather without a procedural source) */
    c->st.skipped++;
    oc_log_warn("control history: entry %s (%s): the world refused it: %s: skipped", e->id, ocs_change_name(g->op),
                oc_strerror(r));
    int k = e->fe == c->fe ? ocs__mine_find(c, e->req) : -1;
    if (k >= 0) {
      char why[160];
      snprintf(why, sizeof why, "%s: the world refused it: %s", ocs_change_name(g->op), oc_strerror(r));
      ocs_control_reply_later(srv, c->mine[k].session, c->mine[k].request, NULL, why);
      ocs__mine_drop(c, k);
    }
    return 1;
  }
  double t = ocs_world_time_at(srv->world, utc);
  c->st.applied++;
  c->st.last_epoch = epoch;
  c->st.last_time = t;
  snprintf(c->st.last_op, sizeof c->st.last_op, "%s", ocs_change_name(g->op));
  oc_log_info("control history: entry %s: %s from epoch %" PRIu64 " (world time %.3f s)", e->id, ocs_change_name(g->op),
              epoch, t);
  ocs__answer(c, e, epoch, t);
  return 1;
}

void ocs_ctl_idle(ocs_ctl_t *c) {
  if (!c || c->closing || c->srv->stopping) return;
  while (c->qhead < c->qlen && !c->srv->stepping && ocs__apply_head(c)) c->qhead++;
}

/* One entry read: checked, given its epoch, queued. */
static void ocs__take(ocs_ctl_t *c, const redisReply *en) {
  if (en->type != REDIS_REPLY_ARRAY || en->elements != 2 || en->element[0]->type != REDIS_REPLY_STRING) return;
  const char *id = en->element[0]->str;
  snprintf(c->last_id, sizeof c->last_id, "%s", id);
  snprintf(c->st.last_id, sizeof c->st.last_id, "%s", id);
  c->st.read++;
  ocs__entry_t e;
  char why[200];
  if (ocs__parse(c, id, en->element[1], &e, why, sizeof why) < 0) {
    c->st.skipped++;
    oc_log_warn("control history: entry %s skipped: %s", id, why);
    return;
  }
  if (e.chg.op == OCS_CHG_ORIGIN) c->origin_seen = 1;
  else if (e.epoch < c->last_epoch) e.epoch = c->last_epoch; /* the stream's order rules */
  if (e.chg.op != OCS_CHG_ORIGIN) c->last_epoch = e.epoch;
  ocs__push(c, &e);
}

/*-*** Reading ***/

static void ocs__on_read(void *ctx, int status, const redisReply *rep) {
  ocs_ctl_t *c = ctx;
  c->reading = 0;
  if (c->closing) return;
  size_t got = 0;
  if (status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_ARRAY) {
    for (size_t i = 0; i < rep->elements; i++) {
      const redisReply *s = rep->element[i];
      if (s->type != REDIS_REPLY_ARRAY || s->elements != 2 || s->element[1]->type != REDIS_REPLY_ARRAY) continue;
      for (size_t j = 0; j < s->element[1]->elements; j++, got++) ocs__take(c, s->element[1]->element[j]);
    }
    c->read_error = 0;
  } else if (status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_NIL) {
    c->read_error = 0;
  } else {
    if (status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_ERROR)
      oc_log_warn("control history: XREAD: %s", rep->str);
    c->read_error = 1;
  }
  if (!c->read_error && got < OCS_CTL_COUNT && !c->at_end) c->at_end = 1; /* the history is read */
  if (c->at_end && c->origin_seen && !c->started) ocs__start_epochs(c, "read");
  else ocs_ctl_idle(c);
  ocs__kick_soon(c, c->read_error ? 250 : 0);
}

static void ocs__read(ocs_ctl_t *c) {
  if (c->reading || !ocs_redis_up(c->rd)) return;
  char count[16], block[16];
  snprintf(count, sizeof count, "%d", OCS_CTL_COUNT);
  snprintf(block, sizeof block, "%u", OCS_CTL_BLOCK_MS);
  const char *argv[8] = {"XREAD", "COUNT", count};
  int n = 3;
  if (c->at_end) {
    argv[n++] = "BLOCK";
    argv[n++] = block;
  }
  argv[n++] = "STREAMS";
  argv[n++] = OCS_CTL_STREAM;
  argv[n++] = c->last_id;
  size_t lens[8];
  for (int i = 0; i < n; i++) lens[i] = strlen(argv[i]);
  uint32_t ms = (c->at_end ? OCS_CTL_BLOCK_MS : 0) + (c->deadline_ms > 1000 ? c->deadline_ms : 1000);
  if (ocs_redis_command(c->rd, ms, ocs__on_read, c, n, argv, lens) == 0) c->reading = 1;
}

/*-*** Appending ***/

typedef struct {
  ocs_ctl_t *c;
  uint64_t req; /* 0: the origin */
} ocs__add_t;

/* The fields of a change as argv strings (in `store`), after "XADD key id". @return how many. */
static int ocs__fields(const ocs_ctl_t *c, const ocs_change_t *g, uint64_t req, uint64_t epoch, const char **argv,
                       char store[][32]) {
  int n = 0, k = 0;
#define F(name, ...)                                  \
  do {                                                \
    argv[n++] = name;                                 \
    snprintf(store[k], sizeof store[k], __VA_ARGS__); \
    argv[n++] = store[k++];                           \
  } while (0)
  F("v", "%d", OCS_CTL_VERSION);
  F("op", "%s", ocs_change_name(g->op));
  F("fe", "%016" PRIx64, c->fe);
  F("req", "%" PRIu64, req);
  F("epoch", "%" PRIu64, epoch);
  switch (g->op) {
  case OCS_CHG_ORIGIN:
    F("utc", "%.17g", g->utc);
    F("time", "%.17g", g->time);
    break;
  case OCS_CHG_WEATHER:
    F("preset", "%s", oc_scene_preset_name(g->preset));
    F("seconds", "%.17g", g->seconds);
    break;
  case OCS_CHG_TIME:
    if (!isnan(g->set)) F("set", "%.17g", g->set);
    if (!isnan(g->scale)) F("scale", "%.17g", g->scale);
    break;
  case OCS_CHG_SUN:
    F("x", "%.17g", g->sun.x);
    F("y", "%.17g", g->sun.y);
    F("z", "%.17g", g->sun.z);
    break;
  case OCS_CHG_STEP: F("epochs", "%" PRIu32, g->epochs); break;
  default: break;
  }
#undef F
  return n;
}

static void ocs__on_added(void *ctx, int status, const redisReply *rep) {
  ocs__add_t *a = ctx;
  ocs_ctl_t *c = a->c;
  uint64_t req = a->req;
  free(a);
  if (c->closing) return;
  int ok = status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_STRING;
  if (!req) { /* our origin: taken, or another front-end's was first */
    c->origin_sent = 2;
    if (!ok && status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_ERROR && !c->origin_seen)
      oc_log_info("control history: the stream has entries but no origin (%s): this front-end keeps its own clock's", rep->str);
    if (!ok && status == OCS_REDIS_OK) c->origin_seen = 1; /* the stream had entries: nothing to wait for */
    if (!ok && status != OCS_REDIS_OK) c->origin_sent = 0; /* tried again */
    ocs__kick_soon(c, 0);
    return;
  }
  int k = ocs__mine_find(c, req);
  if (ok) {
    c->st.published++;
    return;
  }
  c->st.refused++;
  if (k < 0) return; /* already applied (a reply that came after its entry) */
  ocs__mine_t m = c->mine[k];
  ocs__mine_drop(c, k);
  char why[800];
  if (status == OCS_REDIS_TIMEOUT)
    snprintf(why, sizeof why, "the shared control history (Redis %s) did not confirm the change in time: it may still "
             "take effect on every front-end (see stats: share.control.last_id)", c->host);
  else
    snprintf(why, sizeof why, "the shared control history (Redis %s) %s", c->host,
             status == OCS_REDIS_OK && rep && rep->type == REDIS_REPLY_ERROR ? rep->str : "is unreachable");
  ocs_session_t *s = ocs_session_find(c->srv, m.session);
  if (s && m.op == OCS_CHG_STEP && s->step_waiting && s->step_request == m.request) s->step_waiting = 0;
  ocs_control_reply_later(c->srv, m.session, m.request, NULL, why);
}

static int ocs__append(ocs_ctl_t *c, const ocs_change_t *g, uint64_t req, uint64_t epoch) {
  const char *argv[32] = {"XADD", OCS_CTL_STREAM, g->op == OCS_CHG_ORIGIN ? "0-1" : "*"};
  char store[12][32];
  int n = 3 + ocs__fields(c, g, req, epoch, argv + 3, store);
  size_t lens[32];
  for (int i = 0; i < n; i++) lens[i] = strlen(argv[i]);
  ocs__add_t *a = malloc(sizeof *a);
  if (!a) return OC_ENOMEM;
  *a = (ocs__add_t){c, req};
  uint32_t ms = c->deadline_ms > OCS_CTL_WRITE_MS ? c->deadline_ms : OCS_CTL_WRITE_MS;
  int r = ocs_redis_command(c->wr, ms, ocs__on_added, a, n, argv, lens);
  if (r < 0) free(a);
  return r;
}

/* Once the history is read: with no origin in it, ours (the clock this world started with). */
static void ocs__send_origin(ocs_ctl_t *c) {
  if (!c->at_end || c->origin_seen || c->origin_sent || c->started || !ocs_redis_up(c->wr)) return;
  const ocs_world_t *w = c->srv->world;
  double u = ocs_world_utc(w);
  ocs_change_t g = {.op = OCS_CHG_ORIGIN, .utc = u, .time = ocs_world_time_at(w, u)};
  if (ocs__append(c, &g, 0, 0) == 0) c->origin_sent = 1;
}

int ocs_ctl_publish(ocs_ctl_t *c, ocs_session_t *s, uint32_t request, const ocs_change_t *chg, char *why, size_t why_len) {
  if (!ocs_redis_up(c->rd) || !ocs_redis_up(c->wr)) {
    c->st.refused++;
    return oc_errorf(OC_EIO, why, why_len,
                     "the shared control history (Redis %s) is unreachable; a change applied here only would "
                     "split the world", c->host);
  }
  if (!c->started) {
    c->st.refused++;
    return oc_errorf(OC_EIO, why, why_len, "this front-end is still reading the shared control history (Redis %s)",
                     c->host);
  }
  ocs__mine_t *a = oc_grow(c->mine, &c->mine_cap, c->nmine, sizeof *a, 16);
  if (!a) return oc_errorf(OC_ENOMEM, why, why_len, "out of memory");
  c->mine = a;
  ocs_server_t *srv = c->srv;
  uint64_t epoch = srv->period > 0 ? ocs_ctl_epoch_ahead(ocs_net_utc(srv), srv->period)
                                   : ocs_world_epoch(srv->world) + srv->steps_queued + 1; /* stepped: as seen here */
  uint64_t req = ++c->next_req;
  int r = ocs__append(c, chg, req, epoch);
  if (r < 0) {
    c->st.refused++;
    return oc_errorf(r, why, why_len, "the shared control history (Redis %s) is unreachable; a change applied "
                     "here only would split the world", c->host);
  }
  c->mine[c->nmine++] = (ocs__mine_t){req, s->id, request, chg->op};
  return 0;
}

/*-*** Connections, the kick timer ***/

static void ocs__on_kick(uv_timer_t *t) {
  ocs_ctl_t *c = t->data;
  if (c->closing) return;
  ocs__send_origin(c);
  ocs__read(c);
}

static void ocs__kick_soon(ocs_ctl_t *c, uint64_t ms) {
  if (!c->closing) uv_timer_start(&c->kick, ocs__on_kick, ms, 0);
}

static void ocs__on_state(void *ctx, int up) {
  ocs_ctl_t *c = ctx;
  if (up) ocs__kick_soon(c, 0);
}

int ocs_ctl_open(ocs_ctl_t **out, ocs_server_t *srv, uint64_t frontend_id, char *why, size_t why_len) {
  const ocs_server_desc_t *d = &srv->desc;
  ocs_ctl_t *c = calloc(1, sizeof *c);
  if (!c) return OC_ENOMEM;
  c->srv = srv;
  c->fe = frontend_id;
  c->deadline_ms = d->redis_deadline_ms > 0 ? (uint32_t)d->redis_deadline_ms : 200;
  c->applying_history = 1;
  snprintf(c->host, sizeof c->host, "%s:%d", d->redis_host, d->redis_port);
  snprintf(c->last_id, sizeof c->last_id, "0-0");
  ocs_redis_opts_t ro = {.host = d->redis_host, .port = d->redis_port, .seed = frontend_id ^ 0x9e3779b97f4a7c15ull,
                         .on_state = ocs__on_state, .state_ctx = c};
  int r = ocs_redis_open(&c->rd, &srv->loop, &ro);
  if (r >= 0) r = ocs_redis_open(&c->wr, &srv->loop, &ro);
  if (r < 0) { /* the message names c->host: written before c is freed */
    oc_errorf(r, why, why_len, "--redis %s: %s", c->host, oc_strerror(r));
    ocs_redis_close(c->rd);
    free(c);
    return r;
  }
  uv_timer_init(&srv->loop, &c->kick);
  uv_timer_init(&srv->loop, &c->catchup);
  c->kick.data = c->catchup.data = c;
  c->open_handles = 2;
  uv_timer_start(&c->catchup, ocs__on_catchup_deadline, (uint64_t)(OCS_CTL_CATCHUP_S * 1e3), 0);
  *out = c;
  return 0;
}

static void ocs__closed(uv_handle_t *h) {
  ocs_ctl_t *c = h->data;
  if (--c->open_handles) return;
  free(c->q);
  free(c->mine);
  free(c);
}

void ocs_ctl_close(ocs_ctl_t *c) {
  if (!c || c->closing) return;
  c->closing = 1;
  ocs_redis_close(c->rd); /* commands in flight are answered now, and dropped */
  ocs_redis_close(c->wr);
  uv_close((uv_handle_t *)&c->kick, ocs__closed);
  uv_close((uv_handle_t *)&c->catchup, ocs__closed);
}

void ocs_ctl_stats(const ocs_ctl_t *c, ocs_ctl_stats_t *out) {
  *out = c->st;
  out->up = ocs_redis_up(c->rd) && ocs_redis_up(c->wr);
  out->caught_up = c->started;
}

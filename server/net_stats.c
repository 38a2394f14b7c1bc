/* net_stats.c — the server's figures (net_internal.h): gathered once into an ocs_stats_t, then
 * written as the control "stats" and "sessions" replies (cJSON, here) and as Prometheus text
 * (net_metrics.c), so that the two agree by construction. Read on the loop thread while the world
 * is free: a step or production on the pool writes the world's counters. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "net_internal.h"
#include "oc_err.h"

/* Resident memory from /proc/self/statm (its second field, in pages); 0 where it cannot be read. */
static uint64_t resident_bytes(void) {
  unsigned long long size = 0, resident = 0;
  FILE *f = fopen("/proc/self/statm", "r");
  if (!f) return 0;
  int n = fscanf(f, "%llu %llu", &size, &resident);
  fclose(f);
  long page = sysconf(_SC_PAGESIZE);
  return n == 2 && page > 0 ? (uint64_t)resident * (uint64_t)page : 0;
}

static void gather_session(const ocs_session_t *t, ocs_stats_session_t *o) {
  memset(o, 0, sizeof *o);
  o->id = t->id;
  o->role = t->role;
  o->state = t->state;
  snprintf(o->addr, sizeof o->addr, "%s", t->addr);
  o->queued = t->queued;
  /* what the connection itself costs: its frame reader, a held-back frame, its encoder */
  o->memory = sizeof *t + t->rd.buf.cap + (t->deferred ? t->deferred_hdr.length : 0) + ocp_epoch_enc_memory(t->enc);
  o->bytes_out = t->bytes_out;
  o->bytes_in = t->bytes_in;
  if (t->viewer) {
    o->has_viewer = 1;
    ocs_viewer_stats(t->viewer, &o->vs);
    o->ack_latency_ms = t->acks ? 1e3 * t->ack_latency_sum / (double)t->acks : 0.0;
  }
}

int ocs_stats_gather(ocs_server_t *srv, ocs_stats_t *st) {
  memset(st, 0, sizeof *st);
  size_t n = 0;
  for (ocs_session_t *t = srv->sessions; t; t = t->next) n++;
  if (n && !(st->sessions = calloc(n, sizeof *st->sessions))) return OC_ENOMEM;
  for (ocs_session_t *t = srv->sessions; t; t = t->next) {
    gather_session(t, &st->sessions[st->nsessions++]);
    if (t->state >= 0 && t->state < OCS_SS_COUNT) st->by_state[t->state]++;
  }
  ocs_world_stats(srv->world, &st->world);
  st->utc = ocs_net_utc(srv);
  st->time = ocs_world_time_at(srv->world, st->utc); /* now, not the last epoch's */
  st->ticks = srv->steps_done;
  st->late_ticks = srv->late_ticks;
  st->queue = ocs_world_queue_length(srv->world);
  st->bricks_made = srv->bricks_made;
  st->counts = srv->counts;
  st->connections = srv->nconnected;
  st->admitted = srv->nadmitted;
  ocs_session_oldest_lingering(srv, &st->lingering, &st->lingering_budget);
  ocs_plan_desc_t none = {0};
  ocs_admission_t a;
  ocs_world_admission(srv->world, &none, &a);
  st->max_budget = a.max_budget;
  st->total_budget = ocs_world_total_budget(srv->world);
  ocs_hist_read(&srv->tick_lateness, &st->tick_lateness);
  st->rss = resident_bytes();
  ocs_share_stats(srv, &st->share);
  return 0;
}

void ocs_stats_free(ocs_stats_t *st) {
  free(st->sessions);
  st->sessions = NULL;
  st->nsessions = 0;
}

/* Named numbers of a JSON object, added in their order (ADD_NUMBERS takes them as a list). */
typedef struct {
  const char *key;
  double v;
} num_t;

static void add_numbers(cJSON *o, const num_t *f, size_t n) {
  for (size_t i = 0; i < n; i++) cJSON_AddNumberToObject(o, f[i].key, f[i].v);
}
#define ADD_NUMBERS(o, ...)                             \
  do {                                                  \
    const num_t f_[] = {__VA_ARGS__};                   \
    add_numbers((o), f_, sizeof f_ / sizeof f_[0]);     \
  } while (0)

/* {"count": n, "sum": s} of a histogram of seconds. */
static void add_hist(cJSON *o, const char *key, const ocs_hist_view_t *h) {
  ADD_NUMBERS(cJSON_AddObjectToObject(o, key), {"count", (double)h->n}, {"sum", h->sum});
}

/* The connection limits in force, so that a client (overcast-stress) can check it is held to them. */
static void add_limits(cJSON *o, const ocs_server_t *srv, const ocs_stats_t *st) {
  const ocs_server_desc_t *d = &srv->desc;
  ADD_NUMBERS(cJSON_AddObjectToObject(o, "limits"), {"handshake_s", d->handshake_s}, {"idle_s", d->idle_s},
              {"stall_s", d->stall_s}, {"soft_s", d->soft_s}, {"linger_s", d->linger_s},
              {"queue_soft", (double)d->queue_soft}, {"queue_hard", (double)d->queue_hard},
              {"max_connections", d->max_connections}, {"max_per_address", d->max_per_address},
              {"handshake_rate", d->handshake_rate}, {"max_lingering", d->max_lingering},
              {"linger_budget", (double)d->linger_budget}, {"max_budget", (double)st->max_budget},
              {"total_budget", (double)st->total_budget});
}

/* Bricks shared with the other front-ends (net_share.h), when --redis is given. */
static void add_share(cJSON *o, const ocs_share_stats_t *s) {
  if (!s->enabled) return;
  cJSON *j = cJSON_AddObjectToObject(o, "share");
  cJSON_AddBoolToObject(j, "redis_up", s->up);
  ADD_NUMBERS(j, {"lookups", (double)s->lookups}, {"looked_up", (double)s->looked_up}, {"hits", (double)s->hits},
              {"taken", (double)s->taken}, {"leased", (double)s->leased}, {"busy", (double)s->busy},
              {"held", (double)s->held}, {"unavailable", (double)s->unavailable}, {"rejected", (double)s->rejected},
              {"refused", (double)s->refused}, {"skipped", (double)s->skipped}, {"cut_short", (double)s->cut_short},
              {"stored", (double)s->stored}, {"not_stored", (double)s->not_stored},
              {"store_failures", (double)s->store_failures}, {"released", (double)s->released},
              {"answered", (double)s->answered}, {"answer_us", (double)s->answer_us}, {"wait_us", (double)s->wait_us});
  const ocs_ctl_stats_t *c = &s->control; /* the control history (control_stream.h) */
  cJSON *k = cJSON_AddObjectToObject(j, "control");
  cJSON_AddBoolToObject(k, "up", c->up);
  cJSON_AddBoolToObject(k, "caught_up", c->caught_up);
  ADD_NUMBERS(k, {"read", (double)c->read}, {"applied", (double)c->applied}, {"skipped", (double)c->skipped},
              {"late", (double)c->late}, {"published", (double)c->published}, {"refused", (double)c->refused},
              {"last_epoch", (double)c->last_epoch}, {"last_time", c->last_time});
  cJSON_AddStringToObject(k, "last_op", c->last_op);
  cJSON_AddStringToObject(k, "last_id", c->last_id);
}

cJSON *ocs_stats_world_json(const ocs_server_t *srv, const ocs_stats_t *st) {
  const ocs_world_stats_t *ws = &st->world;
  const ocs_net_counts_t *n = &st->counts;
  cJSON *o = cJSON_CreateObject();
  ADD_NUMBERS(o, {"epoch", (double)ws->epoch}, {"time", st->time}, {"utc", st->utc}, {"epoch_period", srv->period},
              {"ticks", (double)st->ticks}, {"viewers", ws->viewers}, {"granted_bytes", (double)ws->granted_bytes},
              {"held_bytes", (double)ws->held_bytes}, {"bricks_produced", (double)ws->bricks_produced},
              {"brick_requests", (double)ws->brick_requests}, {"cache_hits", (double)ws->cache.hits},
              {"cache_misses", (double)ws->cache.misses}, {"cache_evictions", (double)ws->cache.evictions},
              {"cache_hit_rate", ws->cache_hit_rate}, {"cache_bytes", (double)ws->cache.bytes},
              {"plan_ms", 1e3 * ws->plan_seconds}, {"produce_ms", 1e3 * ws->produce_seconds});
  add_hist(o, "brick_seconds", &ws->brick_seconds);
  cJSON_AddNumberToObject(o, "late_ticks", (double)st->late_ticks);
  add_hist(o, "tick_lateness", &st->tick_lateness);
  ADD_NUMBERS(o, {"queue", (double)st->queue}, {"bricks_made_between_ticks", (double)st->bricks_made},
              {"produce_errors", (double)ws->produce_errors}, {"connections", st->connections},
              {"accepted", (double)n->accepted}, {"refused", (double)n->refused},
              {"closed_errors", (double)n->closed_errors}, {"resumes", (double)n->resumes},
              {"budget_lowerings", (double)n->budget_lowerings});
  add_limits(o, srv, st);
  cJSON *rf = cJSON_AddObjectToObject(o, "refusals"); /* by reason: connections and HELLOs refused */
  for (int i = 0; i < OCS_REFUSE_COUNT; i++) cJSON_AddNumberToObject(rf, ocs_refusal_key((ocs_refusal_t)i), (double)n->refusals[i]);
  cJSON *ss = cJSON_AddObjectToObject(o, "sessions_by_state");
  for (int i = 0; i < OCS_SS_COUNT; i++) cJSON_AddNumberToObject(ss, ocs_session_state_name(i), st->by_state[i]);
  ADD_NUMBERS(o, {"lingering", st->lingering}, {"lingering_budget", (double)st->lingering_budget},
              {"admitted", st->admitted}, {"resident_bytes", (double)st->rss});
  add_share(o, &st->share);
  return o;
}

static cJSON *session_json(const ocs_stats_session_t *t) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddNumberToObject(o, "id", t->id);
  cJSON_AddStringToObject(o, "role", t->state == OCS_SS_HANDSHAKE ? "unknown" : ocs_role_name(t->role));
  cJSON_AddStringToObject(o, "state", ocs_session_state_name(t->state));
  cJSON_AddStringToObject(o, "address", t->addr);
  cJSON_AddBoolToObject(o, "lingering", t->state == OCS_SS_LINGER);
  cJSON_AddNumberToObject(o, "queued", (double)t->queued);
  cJSON_AddNumberToObject(o, "memory", (double)t->memory);
  cJSON_AddNumberToObject(o, "bytes_out", (double)t->bytes_out);
  cJSON_AddNumberToObject(o, "bytes_in", (double)t->bytes_in);
  if (t->has_viewer) {
    cJSON_AddNumberToObject(o, "budget", (double)t->vs.budget);
    cJSON_AddNumberToObject(o, "budget_reserved", (double)t->vs.reserved);
    cJSON_AddNumberToObject(o, "epochs", (double)t->vs.epochs_sent);
    cJSON_AddNumberToObject(o, "coalesced", (double)t->vs.coalesced);
    cJSON_AddNumberToObject(o, "resident", (double)t->vs.resident_bytes);
    cJSON_AddNumberToObject(o, "ack_latency_ms", t->ack_latency_ms);
  }
  return o;
}

cJSON *ocs_stats_sessions_json(const ocs_stats_t *st) {
  cJSON *a = cJSON_CreateArray();
  for (size_t i = 0; i < st->nsessions; i++) cJSON_AddItemToArray(a, session_json(&st->sessions[i]));
  return a;
}

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
  st->accepted = srv->accepted;
  st->refused = srv->refused;
  st->closed_errors = srv->closed_errors;
  st->resumes = srv->resumes;
  st->budget_lowerings = srv->budget_lowerings;
  memcpy(st->refusals, srv->refusals, sizeof st->refusals);
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

/* {"count": n, "sum": s} of a histogram of seconds. */
static void add_hist(cJSON *o, const char *key, const ocs_hist_view_t *h) {
  cJSON *j = cJSON_AddObjectToObject(o, key);
  cJSON_AddNumberToObject(j, "count", (double)h->n);
  cJSON_AddNumberToObject(j, "sum", h->sum);
}

/* The connection limits in force, so that a client (overcast-stress) can check it is held to them. */
static void add_limits(cJSON *o, const ocs_server_t *srv, const ocs_stats_t *st) {
  const ocs_server_desc_t *d = &srv->desc;
  cJSON *l = cJSON_AddObjectToObject(o, "limits");
  cJSON_AddNumberToObject(l, "handshake_s", d->handshake_s);
  cJSON_AddNumberToObject(l, "idle_s", d->idle_s);
  cJSON_AddNumberToObject(l, "stall_s", d->stall_s);
  cJSON_AddNumberToObject(l, "soft_s", d->soft_s);
  cJSON_AddNumberToObject(l, "linger_s", d->linger_s);
  cJSON_AddNumberToObject(l, "queue_soft", (double)d->queue_soft);
  cJSON_AddNumberToObject(l, "queue_hard", (double)d->queue_hard);
  cJSON_AddNumberToObject(l, "max_connections", d->max_connections);
  cJSON_AddNumberToObject(l, "max_per_address", d->max_per_address);
  cJSON_AddNumberToObject(l, "handshake_rate", d->handshake_rate);
  cJSON_AddNumberToObject(l, "max_lingering", d->max_lingering);
  cJSON_AddNumberToObject(l, "linger_budget", (double)d->linger_budget);
  cJSON_AddNumberToObject(l, "max_budget", (double)st->max_budget);
  cJSON_AddNumberToObject(l, "total_budget", (double)st->total_budget);
}

/* Bricks shared with the other front-ends (net_share.h), when --redis is given. */
static void add_share(cJSON *o, const ocs_share_stats_t *s) {
  if (!s->enabled) return;
  cJSON *j = cJSON_AddObjectToObject(o, "share");
  cJSON_AddBoolToObject(j, "redis_up", s->up);
  const struct {
    const char *key;
    uint64_t v;
  } f[] = {{"lookups", s->lookups},   {"looked_up", s->looked_up},     {"hits", s->hits},
           {"taken", s->taken},       {"leased", s->leased},           {"busy", s->busy},
           {"held", s->held},         {"unavailable", s->unavailable}, {"rejected", s->rejected},
           {"refused", s->refused},   {"skipped", s->skipped},         {"cut_short", s->cut_short},
           {"stored", s->stored},     {"not_stored", s->not_stored},   {"store_failures", s->store_failures},
           {"released", s->released},   {"answered", s->answered},       {"answer_us", s->answer_us},
           {"wait_us", s->wait_us}};
  for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) cJSON_AddNumberToObject(j, f[i].key, (double)f[i].v);
  const ocs_ctl_stats_t *c = &s->control; /* the control history (control_stream.h) */
  cJSON *k = cJSON_AddObjectToObject(j, "control");
  cJSON_AddBoolToObject(k, "up", c->up);
  cJSON_AddBoolToObject(k, "caught_up", c->caught_up);
  const struct {
    const char *key;
    uint64_t v;
  } g[] = {{"read", c->read},       {"applied", c->applied}, {"skipped", c->skipped},        {"late", c->late},
           {"published", c->published}, {"refused", c->refused}, {"last_epoch", c->last_epoch}};
  for (size_t i = 0; i < sizeof g / sizeof g[0]; i++) cJSON_AddNumberToObject(k, g[i].key, (double)g[i].v);
  cJSON_AddNumberToObject(k, "last_time", c->last_time);
  cJSON_AddStringToObject(k, "last_op", c->last_op);
  cJSON_AddStringToObject(k, "last_id", c->last_id);
}

cJSON *ocs_stats_world_json(const ocs_server_t *srv, const ocs_stats_t *st) {
  const ocs_world_stats_t *ws = &st->world;
  cJSON *o = cJSON_CreateObject();
  cJSON_AddNumberToObject(o, "epoch", (double)ws->epoch);
  cJSON_AddNumberToObject(o, "time", st->time);
  cJSON_AddNumberToObject(o, "utc", st->utc);
  cJSON_AddNumberToObject(o, "epoch_period", srv->period);
  cJSON_AddNumberToObject(o, "ticks", (double)st->ticks);
  cJSON_AddNumberToObject(o, "viewers", ws->viewers);
  cJSON_AddNumberToObject(o, "granted_bytes", (double)ws->granted_bytes);
  cJSON_AddNumberToObject(o, "held_bytes", (double)ws->held_bytes);
  cJSON_AddNumberToObject(o, "bricks_produced", (double)ws->bricks_produced);
  cJSON_AddNumberToObject(o, "brick_requests", (double)ws->brick_requests);
  cJSON_AddNumberToObject(o, "cache_hits", (double)ws->cache_hits);
  cJSON_AddNumberToObject(o, "cache_misses", (double)ws->cache_misses);
  cJSON_AddNumberToObject(o, "cache_evictions", (double)ws->cache_evictions);
  cJSON_AddNumberToObject(o, "cache_hit_rate", ws->cache_hit_rate);
  cJSON_AddNumberToObject(o, "cache_bytes", (double)ws->cache_bytes);
  cJSON_AddNumberToObject(o, "plan_ms", 1e3 * ws->plan_seconds);
  cJSON_AddNumberToObject(o, "produce_ms", 1e3 * ws->produce_seconds);
  add_hist(o, "brick_seconds", &ws->brick_seconds);
  cJSON_AddNumberToObject(o, "late_ticks", (double)st->late_ticks);
  add_hist(o, "tick_lateness", &st->tick_lateness);
  cJSON_AddNumberToObject(o, "queue", (double)st->queue);
  cJSON_AddNumberToObject(o, "bricks_made_between_ticks", (double)st->bricks_made);
  cJSON_AddNumberToObject(o, "produce_errors", (double)ws->produce_errors);
  cJSON_AddNumberToObject(o, "connections", st->connections);
  cJSON_AddNumberToObject(o, "accepted", (double)st->accepted);
  cJSON_AddNumberToObject(o, "refused", (double)st->refused);
  cJSON_AddNumberToObject(o, "closed_errors", (double)st->closed_errors);
  cJSON_AddNumberToObject(o, "resumes", (double)st->resumes);
  cJSON_AddNumberToObject(o, "budget_lowerings", (double)st->budget_lowerings);
  add_limits(o, srv, st);
  cJSON *rf = cJSON_AddObjectToObject(o, "refusals"); /* by reason: connections and HELLOs refused */
  for (int i = 0; i < OCS_REFUSE_COUNT; i++) cJSON_AddNumberToObject(rf, ocs_refusal_key((ocs_refusal_t)i), (double)st->refusals[i]);
  cJSON *ss = cJSON_AddObjectToObject(o, "sessions_by_state");
  for (int i = 0; i < OCS_SS_COUNT; i++) cJSON_AddNumberToObject(ss, ocs_session_state_name(i), st->by_state[i]);
  cJSON_AddNumberToObject(o, "lingering", st->lingering);
  cJSON_AddNumberToObject(o, "lingering_budget", (double)st->lingering_budget);
  cJSON_AddNumberToObject(o, "admitted", st->admitted);
  cJSON_AddNumberToObject(o, "resident_bytes", (double)st->rss);
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

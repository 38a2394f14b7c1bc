/* net_metrics_text.c — what /metrics exports (net_internal.h; the list with meanings is in
 * docs/operations.md, "Metrics"): the figures of net_stats.c, the ones the stats reply shows,
 * as Prometheus families (prom_text.h). Names: the overcast_ prefix, base units (_seconds,
 * _bytes), _total on counters; the process's resident memory under the name client libraries use. */
#include <inttypes.h>
#include <stdio.h>

#include "net_internal.h"
#include "prom_text.h"

static void one(oc_buf_t *b, const char *name, const char *type, const char *help, double v) {
  ocs_prom_family(b, name, type, help);
  ocs_prom_sample(b, name, NULL, NULL, v);
}

static void counter(oc_buf_t *b, const char *name, const char *help, double v) { one(b, name, "counter", help, v); }
static void gauge(oc_buf_t *b, const char *name, const char *help, double v) { one(b, name, "gauge", help, v); }

static void ticks(oc_buf_t *b, const ocs_stats_t *st) {
  counter(b, "overcast_ticks_total", "Epochs stepped: ticks of the clock and epochs of \"step\" requests.", (double)st->ticks);
  counter(b, "overcast_ticks_late_total", "Due ticks skipped: the loop came late, or the previous step still ran.",
          (double)st->late_ticks);
  ocs_prom_histogram(b, "overcast_tick_lateness_seconds",
                     "How long after its due instant a clocked tick's states started out (0: on time).", &st->tick_lateness);
  gauge(b, "overcast_epoch", "Index of the last epoch stepped.", (double)st->world.epoch);
  gauge(b, "overcast_world_time_seconds", "World time now.", st->time);
}

static void production(oc_buf_t *b, const ocs_stats_t *st) {
  const ocs_world_stats_t *w = &st->world;
  gauge(b, "overcast_production_queue_bricks", "Bricks waiting in the production queue.", (double)st->queue);
  counter(b, "overcast_bricks_produced_total", "Bricks made (restarts at a reload).", (double)w->bricks_produced);
  ocs_prom_histogram(b, "overcast_brick_production_seconds", "Wall time each brick made took on its producer thread.",
                     &w->brick_seconds);
  counter(b, "overcast_brick_production_errors_total", "Bricks whose production failed.", (double)w->produce_errors);
  counter(b, "overcast_brick_requests_total", "Bricks the viewers' plans asked for, before sharing.", (double)w->brick_requests);
  counter(b, "overcast_brick_cache_hits_total", "Brick cache lookups that found the brick.", (double)w->cache.hits);
  counter(b, "overcast_brick_cache_misses_total", "Brick cache lookups that did not.", (double)w->cache.misses);
  counter(b, "overcast_brick_cache_evictions_total", "Bricks evicted from the cache.", (double)w->cache.evictions);
  gauge(b, "overcast_brick_cache_bytes", "Bytes held by the brick cache.", (double)w->cache.bytes);
}

static void budgets(oc_buf_t *b, const ocs_stats_t *st) {
  gauge(b, "overcast_viewers", "Viewers in the world.", st->world.viewers);
  gauge(b, "overcast_budget_granted_bytes", "Sum of the budgets granted to viewers.", (double)st->world.granted_bytes);
  gauge(b, "overcast_budget_total_bytes", "Sum of the budgets the server may grant (--total-budget).", (double)st->total_budget);
  gauge(b, "overcast_budget_max_viewer_bytes", "Largest budget one viewer is granted.", (double)st->max_budget);
  gauge(b, "overcast_budget_lingering_bytes", "Of the granted budgets, those of viewers kept for resume.",
        (double)st->lingering_budget);
  gauge(b, "overcast_held_state_bytes", "Server memory of the states kept for viewers.", (double)st->world.held_bytes);
}

static void connections(oc_buf_t *b, const ocs_stats_t *st) {
  gauge(b, "overcast_connections", "Open connections, refused ones still closing included.", st->connections);
  counter(b, "overcast_connections_accepted_total", "Connections accepted by the listener.", (double)st->counts.accepted);
  counter(b, "overcast_connections_closed_errors_total", "Connections closed for an error.", (double)st->counts.closed_errors);
  counter(b, "overcast_resumes_total", "Viewers that resumed a session.", (double)st->counts.resumes);
  counter(b, "overcast_budget_lowerings_total", "Viewers admission lowered to a fair share to make room (BUDGET).",
          (double)st->counts.budget_lowerings);
  ocs_prom_family(b, "overcast_refusals_total", "counter", "Connections and HELLOs refused, by reason.");
  for (int i = 0; i < OCS_REFUSE_COUNT; i++)
    ocs_prom_sample(b, "overcast_refusals_total", "reason", ocs_refusal_key((ocs_refusal_t)i), (double)st->counts.refusals[i]);
  ocs_prom_family(b, "overcast_sessions", "gauge", "Sessions by state.");
  for (int i = 0; i < OCS_SS_COUNT; i++)
    ocs_prom_sample(b, "overcast_sessions", "state", ocs_session_state_name(i), st->by_state[i]);
}

static double sent_bytes(const ocs_stats_session_t *t) { return (double)t->bytes_out; }
static double epochs(const ocs_stats_session_t *t) { return (double)t->vs.epochs_sent; }
static double coalesced(const ocs_stats_session_t *t) { return (double)t->vs.coalesced; }
static double budget(const ocs_stats_session_t *t) { return (double)t->vs.budget; }
static double reserved(const ocs_stats_session_t *t) { return (double)t->vs.reserved; }
static double resident(const ocs_stats_session_t *t) { return (double)t->vs.resident_bytes; }

/* Families with one sample per session that has a viewer, labelled with its id. */
static const struct {
  const char *name, *type, *help;
  double (*get)(const ocs_stats_session_t *t);
} viewer_families[] = {
    {"overcast_viewer_sent_bytes_total", "counter", "Bytes written to each viewer's connection.", sent_bytes},
    {"overcast_viewer_epochs_total", "counter", "States sent to each viewer.", epochs},
    {"overcast_viewer_coalesced_epochs_total", "counter", "Due epochs each viewer got no state of.", coalesced},
    {"overcast_viewer_budget_bytes", "gauge", "Each viewer's budget its plans are made under (BUDGET changes it).", budget},
    {"overcast_viewer_budget_reserved_bytes", "gauge",
     "Each viewer's part of overcast_budget_granted_bytes: its budget, or a lowered one's old budget until its states left.",
     reserved},
    {"overcast_viewer_resident_bytes", "gauge", "Each viewer's resident bytes (the budget measure).", resident},
};

static void viewers(oc_buf_t *b, const ocs_stats_t *st) {
  char id[16];
  for (size_t f = 0; f < sizeof viewer_families / sizeof viewer_families[0]; f++) {
    ocs_prom_family(b, viewer_families[f].name, viewer_families[f].type, viewer_families[f].help);
    for (size_t i = 0; i < st->nsessions; i++) {
      const ocs_stats_session_t *t = &st->sessions[i];
      if (!t->has_viewer) continue;
      snprintf(id, sizeof id, "%" PRIu32, t->id);
      ocs_prom_sample(b, viewer_families[f].name, "session", id, viewer_families[f].get(t));
    }
  }
}

/* Bricks shared through Redis (only with --redis). */
static void sharing(oc_buf_t *b, const ocs_share_stats_t *s) {
  if (!s->enabled) return;
  gauge(b, "overcast_redis_up", "1 while the connection to the shared brick store is up.", s->up);
  ocs_prom_family(b, "overcast_shared_lookups_total", "counter",
                  "Bricks looked up in the shared store before production, by what was found.");
  const struct {
    const char *outcome;
    uint64_t v;
  } f[] = {{"hit", s->hits}, {"leased", s->leased}, {"busy", s->busy}, {"unavailable", s->unavailable}};
  for (size_t i = 0; i < sizeof f / sizeof f[0]; i++)
    ocs_prom_sample(b, "overcast_shared_lookups_total", "outcome", f[i].outcome, (double)f[i].v);
  counter(b, "overcast_shared_bricks_taken_total", "Bricks another front-end made, taken into the cache.", (double)s->taken);
  counter(b, "overcast_shared_bricks_stored_total", "Bricks made here and stored for the others.", (double)s->stored);
  counter(b, "overcast_shared_values_rejected_total", "Stored values that failed their checks (made again).",
          (double)(s->rejected + s->refused));
  counter(b, "overcast_shared_lookups_cut_short_total", "Productions that started before every lookup was answered.",
          (double)s->cut_short);
  counter(b, "overcast_shared_lookups_answered_total", "Bricks looked up whose answer came (in time or late).",
          (double)s->answered);
  counter(b, "overcast_shared_lookup_answer_seconds_total",
          "Summed over answered lookups: from the start of their production's lookup to the answer.", 1e-6 * (double)s->answer_us);
  counter(b, "overcast_shared_lookup_wait_seconds_total", "Time productions waited for their lookups (each at most the deadline).",
          1e-6 * (double)s->wait_us);
  const ocs_ctl_stats_t *c = &s->control; /* the control history (control_stream.h) */
  gauge(b, "overcast_control_up", "1 while the shared control history can take changes (both connections up, read).",
        c->up && c->caught_up);
  ocs_prom_family(b, "overcast_control_entries_total", "counter", "Control history entries read, by what became of them.");
  const struct {
    const char *outcome;
    uint64_t v;
  } g[] = {{"applied", c->applied}, {"skipped", c->skipped}, {"late", c->late}};
  for (size_t i = 0; i < sizeof g / sizeof g[0]; i++)
    ocs_prom_sample(b, "overcast_control_entries_total", "outcome", g[i].outcome, (double)g[i].v);
  counter(b, "overcast_control_refused_total", "Control changes refused: the shared history unreachable, or the append failed.",
          (double)c->refused);
}

void ocs_metrics_text(const ocs_stats_t *st, oc_buf_t *out) {
  ticks(out, st);
  production(out, st);
  budgets(out, st);
  connections(out, st);
  viewers(out, st);
  sharing(out, &st->share);
  gauge(out, "process_resident_memory_bytes", "Resident memory size in bytes.", (double)st->rss);
}

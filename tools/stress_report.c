/* stress_report.c — overcast-stress's results: per-viewer rows and aggregates as a table on stdout
 * (Markdown, to paste into docs/performance.md), everything as JSON with --json, and the verdict.
 *
 * Aggregates: bytes/s is each viewer's bytes received from its WELCOME to the end of the run over
 * that time, median and p99 over the viewers; latency, transfer and time to full detail are pooled
 * over every viewer's samples. Quantiles are nearest-rank. */
#include <cjson/cJSON.h>
#include <inttypes.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plot.h"
#include "stress.h"

#define SR_MIB (1024.0 * 1024.0)

/* Writes j (consumed) to path, pretty-printed. @return 0, or -1 after saying why on stderr. */
static int sr_write_json(cJSON *j, const char *path) {
  char *text = cJSON_Print(j);
  cJSON_Delete(j);
  FILE *f = text ? fopen(path, "w") : NULL;
  int ok = f != NULL;
  if (f) {
    ok = fputs(text, f) >= 0 && fputc('\n', f) != EOF;
    if (fclose(f) != 0) ok = 0;
  }
  cJSON_free(text);
  if (!ok) fprintf(stderr, "overcast-stress: %s: cannot write the JSON\n", path);
  return ok ? 0 : -1;
}

stress_q_t stress_pool(const stress_run_t *run, size_t off, int only) {
  stress_q_t q = {NAN, NAN, NAN, 0};
  size_t n = 0, k = 0;
  for (int i = 0; i < run->nv; i++)
    if (only < 0 || i == only) n += ((const stress_samples_t *)((const char *)&run->v[i] + off))->n;
  double *a = n ? malloc(n * sizeof *a) : NULL;
  if (!a) return q;
  for (int i = 0; i < run->nv; i++) {
    const stress_samples_t *s = (const stress_samples_t *)((const char *)&run->v[i] + off);
    if ((only < 0 || i == only) && s->n) memcpy(a + k, s->v, s->n * sizeof *a);
    if (only < 0 || i == only) k += s->n;
  }
  q.p50 = stress_quantile(a, n, 0.5);
  q.p99 = stress_quantile(a, n, 0.99);
  q.max = a[n - 1];
  q.n = n;
  free(a);
  return q;
}

/* The pooled samples of viewer field f (a stress_samples_t): every viewer's, or viewer `only`'s. */
#define SR_POOL(run, f, only) stress_pool(run, offsetof(stress_viewer_t, f), only)

static const char *sr_age(char *buf, size_t cap, int age);
static cJSON *sr_age_json(const stress_age_t *a);
static void sr_age_levels(const stress_age_t *a);

static double sr_rate(const stress_viewer_t *v) {
  double t = v->t_end - v->t_welcome;
  return v->have_welcome && t > 0 ? (double)v->session.bytes_in / t : NAN;
}

/* "12.3" or "—" */
static const char *sr_num(char *buf, size_t cap, double x, const char *fmt) {
  if (!isfinite(x)) snprintf(buf, cap, "—");
  else snprintf(buf, cap, fmt, x);
  return buf;
}

static void sr_add_num(cJSON *o, const char *k, double x) {
  if (isfinite(x)) cJSON_AddNumberToObject(o, k, x);
  else cJSON_AddNullToObject(o, k);
}

static cJSON *sr_q_json(stress_q_t q) {
  cJSON *o = cJSON_CreateObject();
  sr_add_num(o, "p50", q.p50);
  sr_add_num(o, "p99", q.p99);
  sr_add_num(o, "max", q.max);
  cJSON_AddNumberToObject(o, "count", (double)q.n);
  return o;
}

/* ---- JSON objects from tables: one row per key, its value read at an offset ---- */

typedef enum { SR_INT, SR_LONG, SR_U64, SR_DBL } sr_kind_t;
typedef struct {
  const char *key;
  size_t off;
  sr_kind_t kind;
} sr_field_t;
#define SR_ROW(T, key, field, kind) {key, offsetof(T, field), kind}
#define SR_ADD_FIELDS(o, base, table) sr_add_fields(o, base, table, sizeof table / sizeof table[0])

/* Adds each row's value in `base` to o (a double that is not finite as null). */
static void sr_add_fields(cJSON *o, const void *base, const sr_field_t *f, size_t n) {
  for (size_t i = 0; i < n; i++) {
    const char *p = (const char *)base + f[i].off;
    double x;
    switch (f[i].kind) {
      case SR_INT: x = *(const int *)p; break;
      case SR_LONG: x = (double)*(const long *)p; break;
      case SR_U64: x = (double)*(const uint64_t *)p; break;
      default: x = *(const double *)p; break;
    }
    sr_add_num(o, f[i].key, x);
  }
}

static cJSON *sr_proc_json(const stress_proc_t *p) {
  static const sr_field_t rows[] = {SR_ROW(stress_proc_t, "rss_mib", rss_mib, SR_DBL),
                                    SR_ROW(stress_proc_t, "peak_rss_mib", hwm_mib, SR_DBL),
                                    SR_ROW(stress_proc_t, "cpu_s", cpu_s, SR_DBL)};
  if (!p->ok) return cJSON_CreateNull();
  cJSON *o = cJSON_CreateObject();
  SR_ADD_FIELDS(o, p, rows);
  return o;
}

/* --faults: the table and the checks. @return the number of failed checks; *cause names the first. */
static int sr_faults(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s, char *cause, size_t cap) {
  const stress_fault_conns_t *c = &s->fault_conns;
  const stress_fault_mem_t *m = &s->fault_mem;
  int failed = 0;
  cause[0] = '\0';
#define SR_FAULT(...)                                       \
  do {                                                      \
    if (!failed++) snprintf(cause, cap, __VA_ARGS__);       \
    printf("FAIL: faults: ");                               \
    printf(__VA_ARGS__);                                    \
    printf("\n");                                           \
  } while (0)
  printf("\nfaults (one round every %ld step%s from step 2; the server's handshake timeout %.0f s):\n\n", o->fault_every,
         o->fault_every == 1 ? "" : "s", c->handshake_s);
  printf("| kind | opened | refused at connect | closed by the server | after ERROR/GOODBYE | slowest close s |\n");
  printf("|---|---:|---:|---:|---:|---:|\n");
  for (int k = 0; k < STRESS_FK_COUNT; k++)
    if (o->faults & (1 << k))
      printf("| %s | %" PRIu64 " | %" PRIu64 " | %" PRIu64 " | %" PRIu64 " | %.2f |\n", stress_fault_kind_name(k), c->opened[k],
             c->refused[k], c->closed[k], c->errors[k], c->close_s_max[k]);
  if (o->faults & (1 << STRESS_FK_STALL))
    printf("stalled viewers let go by the server (stall timeout %.0f s): %" PRIu64 "; still held at the end, not yet due: %" PRIu64
           "\n",
           c->stall_s, c->closed[STRESS_FK_STALL], c->open_at_end);
  printf("largest send queue of one connection: %.2f MiB (the server's hard limit %.0f MiB)\n", (double)m->queued_max / SR_MIB,
         (double)m->queue_hard / SR_MIB);
  printf("server RSS: %.1f → %.1f MiB while what it accounts for went %.1f → %.1f MiB: %.1f MiB unaccounted (slack %.0f MiB)\n",
         m->rss_base_mib, m->rss_peak_mib, m->accounted_base / SR_MIB, m->accounted_peak / SR_MIB, m->growth_mib,
         o->fault_rss_slack);
  if (c->failure[0]) SR_FAULT("%s", c->failure);
  if (m->samples < 2) SR_FAULT("fewer than 2 memory samples (the run needs at least 3 steps)");
  if (m->growth_mib > o->fault_rss_slack)
    SR_FAULT("the server's RSS grew %.1f MiB beyond its own accounting (slack %.0f MiB)", m->growth_mib, o->fault_rss_slack);
  if (m->queue_hard && m->queued_max > m->queue_hard + OCP_MAX_PAYLOAD + OCP_HEADER_BYTES)
    SR_FAULT("a connection had %" PRIu64 " bytes unsent, past the hard limit %" PRIu64, m->queued_max, m->queue_hard);
  if (s->steps_incomplete) SR_FAULT("%" PRIu64 " steps left a viewer without its state", s->steps_incomplete);
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    if (v->skipped) SR_FAULT("viewer %d (%s) missed %" PRIu64 " epoch%s", i, stress_path_name(v->path), v->skipped, v->skipped == 1 ? "" : "s");
  }
  if (o->faults & STRESS_FAULT_RESTART) {
    size_t n = 0;
    double worst = 0;
    for (int i = 0; i < run->nv; i++) {
      const stress_viewer_t *v = &run->v[i];
      if (!v->resync.n) SR_FAULT("viewer %d (%s): no state from the restarted server", i, stress_path_name(v->path));
      for (size_t k = 0; k < v->resync.n; k++) worst = fmax(worst, v->resync.v[k]);
      n += v->resync.n;
    }
    printf("restart: %d (kill to every viewer's WELCOME: %.2f s); %zu resynchronisations, the slowest %.2f s from the lost "
           "connection to the first verified state\n",
           m->restarts, m->restart_s, n, worst);
    if (m->restarts < 1) SR_FAULT("the server was not restarted (--restart-at %ld after the last step?)", o->restart_at);
  }
#undef SR_FAULT
  return failed;
}

static cJSON *sr_faults_json(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s) {
#define C(key, field) SR_ROW(stress_fault_conns_t, key, field, SR_U64)
  static const sr_field_t conns[] = {C("late", late), C("garbage_unanswered", unanswered),
                                     C("stalled_open_at_end", open_at_end), C("states_before_drop", states_before_drop)};
#undef C
#define M(key, field, kind) SR_ROW(stress_fault_mem_t, key, field, kind)
  static const sr_field_t mem[] = {M("queued_max", queued_max, SR_U64),       M("queue_hard", queue_hard, SR_U64),
                                   M("rss_base_mib", rss_base_mib, SR_DBL),     M("rss_peak_mib", rss_peak_mib, SR_DBL),
                                   M("accounted_base", accounted_base, SR_DBL), M("accounted_peak", accounted_peak, SR_DBL),
                                   M("unaccounted_growth_mib", growth_mib, SR_DBL)};
  static const sr_field_t restarts[] = {M("restarts", restarts, SR_INT), M("restart_s", restart_s, SR_DBL)};
#undef M
  const stress_fault_conns_t *c = &s->fault_conns;
  cJSON *f = cJSON_CreateObject();
  cJSON_AddNumberToObject(f, "every", (double)o->fault_every);
  cJSON_AddNumberToObject(f, "handshake_s", c->handshake_s);
  cJSON_AddNumberToObject(f, "stall_s", c->stall_s);
  for (int k = 0; k < STRESS_FK_COUNT; k++) {
    if (!(o->faults & (1 << k))) continue;
    cJSON *x = cJSON_AddObjectToObject(f, stress_fault_kind_name(k));
    cJSON_AddNumberToObject(x, "opened", (double)c->opened[k]);
    cJSON_AddNumberToObject(x, "refused", (double)c->refused[k]);
    cJSON_AddNumberToObject(x, "closed_by_server", (double)c->closed[k]);
    cJSON_AddNumberToObject(x, "after_error", (double)c->errors[k]);
    cJSON_AddNumberToObject(x, "slowest_close_s", c->close_s_max[k]);
  }
  SR_ADD_FIELDS(f, c, conns);
  SR_ADD_FIELDS(f, &s->fault_mem, mem);
  cJSON_AddNumberToObject(f, "rss_slack_mib", o->fault_rss_slack);
  SR_ADD_FIELDS(f, &s->fault_mem, restarts);
  cJSON *rs = cJSON_AddArrayToObject(f, "resync_s");
  for (int i = 0; i < run->nv; i++)
    for (size_t k = 0; k < run->v[i].resync.n; k++) cJSON_AddItemToArray(rs, cJSON_CreateNumber(run->v[i].resync.v[k]));
  if (c->failure[0]) cJSON_AddStringToObject(f, "failure", c->failure);
  return f;
}

/* What the report says about the whole run, gathered once for the table, the JSON and the verdict. */
typedef struct {
  uint64_t violations, checksum, protocol, mismatch, failed, empty, skipped, coalesced, teleports, unreached, states;
  uint64_t due, coal_ticks, coarser, fewer, content_mismatch, held, resident;
  double rate_p50, rate_p99;
  stress_q_t lat, tra, det, dep, itv, late;
  stress_age_t ages; /* verified content ages, every viewer's */
  int pass;
} sr_totals_t;

/* --sweep: detail (the deepest level reached) must not drop with a bigger budget or a deeper
 * limit; fewer leaves is only noted (a deeper tree can hold fewer, smaller leaves). */
static void sr_sweep_check(const stress_opts_t *o, const stress_run_t *run, sr_totals_t *t) {
  int nd = o->nsweep_depths;
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    int bi = i / nd, di = i % nd;
    const stress_viewer_t *prev[2] = {bi > 0 ? &run->v[i - nd] : NULL, di > 0 ? &run->v[i - 1] : NULL};
    for (int k = 0; k < 2; k++) {
      const stress_viewer_t *w = prev[k];
      if (!w || !v->states || !w->states) continue;
      int bigger = k == 0 ? v->budget >= w->budget : 1, deeper = k == 1 ? v->max_depth >= w->max_depth : 1;
      if (!bigger || !deeper) continue;
      if (v->depth_max < w->depth_max) {
        t->coarser++;
        printf("NOT GRACEFUL: viewer %d (budget %.3f MiB, depth %d) reached level %d, viewer %d (%.3f MiB, depth %d) "
               "level %d\n",
               v->index, (double)v->budget / SR_MIB, v->max_depth, v->depth_max, w->index, (double)w->budget / SR_MIB,
               w->max_depth, w->depth_max);
      }
      if (v->nodes_last < w->nodes_last) t->fewer++;
    }
  }
}

/* The totals over the viewers (and the sweep's check, which prints what it finds). */
static void sr_totals(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s, sr_totals_t *t) {
  memset(t, 0, sizeof *t);
  double *rates = calloc((size_t)run->nv + 1, sizeof *rates);
  size_t nrates = 0;
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    t->violations += v->violations;
    t->checksum += v->checksum_failures;
    t->protocol += v->protocol_errors;
    t->mismatch += v->resident_mismatch;
    t->failed += v->failed != 0;
    t->empty += v->states == 0;
    t->skipped += v->skipped;
    t->coalesced += v->last_stats.coalesced;
    t->teleports += v->teleports;
    t->unreached += v->detail_unreached;
    t->states += v->states;
    t->held += v->session.held_bytes;
    t->resident += v->resident_last;
    /* epochs on the clock: coalesced ticks summed; verified content ages merged */
    t->due += stress_ticks_due(&v->ticks);
    t->coal_ticks += v->ticks.coalesced;
    stress_age_merge(&t->ages, &v->age);
    stress_age_merge(&t->ages, &v->m_age);
    double r = sr_rate(v);
    if (rates && isfinite(r)) rates[nrates++] = r;
  }
  t->rate_p50 = rates ? stress_quantile(rates, nrates, 0.5) : NAN;
  t->rate_p99 = rates ? stress_quantile(rates, nrates, 0.99) : NAN;
  free(rates);
  t->lat = SR_POOL(run, latency, -1);
  t->tra = SR_POOL(run, transfer, -1);
  t->det = SR_POOL(run, detail, -1);
  t->dep = SR_POOL(run, detail_epochs, -1);
  t->itv = SR_POOL(run, interval, -1);
  if (o->sweep) sr_sweep_check(o, run, t);
  t->late = SR_POOL(run, ticks.lateness, -1);
  t->content_mismatch = stress_age_mismatches(&t->ages, -1);
  t->pass = !t->violations && !t->checksum && !t->protocol && !t->mismatch && !t->failed && !t->empty && !t->coarser &&
            !t->content_mismatch && !s->error[0];
}

/* One row of the viewers' table. */
static void sr_viewer_row(const stress_viewer_t *v, stress_q_t vl, stress_q_t vd) {
  char b1[32], b2[32], b3[32], b4[32], b5[32], b6[32], b7[32], extra[160];
  double granted = v->have_welcome ? (double)v->welcome.budget / SR_MIB : NAN;
  stress_samples_t lt = v->ticks.lateness; /* quantiles sort in place: the viewer's own order does not matter */
  stress_age_t va = v->age;
  stress_age_merge(&va, &v->m_age);
  char c1[32], c2[32], c3[32], c4[32], c5[16];
  double l50 = stress_quantile(lt.v, lt.n, 0.5), l99 = stress_quantile(lt.v, lt.n, 0.99); /* sorted now */
  snprintf(extra, sizeof extra, " %s | %s | %s | %s | %s |", sr_num(c1, sizeof c1, 1e3 * l50, "%.0f"),
           sr_num(c2, sizeof c2, 1e3 * l99, "%.0f"), sr_num(c3, sizeof c3, lt.n ? 1e3 * lt.v[lt.n - 1] : NAN, "%.0f"),
           sr_num(c4, sizeof c4, 100.0 * stress_ticks_coalesced_frac(&v->ticks), "%.1f %%"),
           sr_age(c5, sizeof c5, stress_age_quantile(&va, -1, 0.99)));
  printf("| %d | %s | %s | %d | %" PRIu64 " | %" PRIu64 " | %" PRIu64 " | %s | %s | %s | %s | %s | %s |%s\n", v->index,
         stress_path_name(v->path), sr_num(b1, sizeof b1, granted, "%.1f"), v->max_depth, v->states, v->skipped,
         v->last_stats.coalesced, sr_num(b2, sizeof b2, (double)v->resident_max / SR_MIB, "%.2f"),
         sr_num(b3, sizeof b3, v->have_welcome ? 100.0 * (double)v->resident_max / (double)v->welcome.budget : NAN, "%.1f %%"),
         sr_num(b4, sizeof b4, sr_rate(v) / 1e6, "%.3f"), sr_num(b5, sizeof b5, 1e3 * vl.p50, "%.0f"),
         sr_num(b6, sizeof b6, 1e3 * vl.p99, "%.0f"), v->path == STRESS_TELEPORT ? sr_num(b7, sizeof b7, vd.p50, "%.2f") : "",
         extra);
}

/* The heading and the viewers' table. */
static void sr_print_viewers(const stress_run_t *run, const stress_summary_t *s) {
  printf("overcast-stress: %d viewer%s, scene %s (%s, K = %d), %s, %.1f s\n", run->nv, run->nv == 1 ? "" : "s",
         s->scene[0] ? s->scene : "?", s->kept_states == 3 ? "animated" : "static", s->kept_states,
         s->stepped ? "stepped by this tool" : "epochs by the server's clock", s->wall_s);
  if (s->stepped)
    printf("steps: %" PRIu64 " (%" PRIu64 " with a viewer left without its state)\n", s->steps, s->steps_incomplete);
  else
    printf("epoch period: %g s\n", s->epoch_period);
  printf("\n| viewer | path | budget MiB | depth | states | skipped | coalesced | resident max MiB | of budget | MB/s "
         "| latency p50 ms | p99 ms | full detail s | lateness p50 ms | p99 ms | max ms | ticks coalesced | age p99 |\n");
  printf("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int i = 0; i < run->nv; i++) sr_viewer_row(&run->v[i], SR_POOL(run, latency, i), SR_POOL(run, detail, i));
}

/* --verify-content: what was verified, one line, and any mismatch. */
static void sr_print_verified(const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
  char b1[32];
  printf("content verified here (--verify-content %g): %" PRIu64 " bricks sampled, %" PRIu64 " verified, %" PRIu64
         " dropped (queue full), %" PRIu64 " errors, %zu left unverified; age p99 %s; %.1f s reproducing %" PRIu64
         " bricks; per level p99 (verified):",
         o->verify_content, t->ages.sampled, stress_age_count(&t->ages, -1), t->ages.dropped, t->ages.errors, s->verify_left,
         sr_age(b1, sizeof b1, stress_age_quantile(&t->ages, -1, 0.99)), s->verify_s, s->verify_reproduced);
  sr_age_levels(&t->ages);
  printf("\n");
  if (t->content_mismatch)
    printf("CONTENT MISMATCH: %" PRIu64 " verified bricks matched no stamp s .. s-%d of their state's world time\n",
           t->content_mismatch, STRESS_AGE_MAX);
}

/* The aggregates under the table: rates, latencies, lateness, verified ages, time to detail. */
static void sr_print_aggregates(const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
  char b1[32], b2[32], b3[32], b4[32];
  printf("\nbytes/s per viewer: median %s MB/s, p99 %s MB/s\n", sr_num(b1, sizeof b1, t->rate_p50 / 1e6, "%.3f"),
         sr_num(b2, sizeof b2, t->rate_p99 / 1e6, "%.3f"));
  printf("epoch latency (%s to the complete state): p50 %s ms, p99 %s ms over %zu states\n",
         s->stepped ? "from the step request" : "from the first byte of EPOCH_BEGIN",
         sr_num(b1, sizeof b1, 1e3 * t->lat.p50, "%.0f"), sr_num(b2, sizeof b2, 1e3 * t->lat.p99, "%.0f"), t->lat.n);
  printf("transfer (first byte of EPOCH_BEGIN to the complete state): p50 %s ms, p99 %s ms\n",
         sr_num(b1, sizeof b1, 1e3 * t->tra.p50, "%.0f"), sr_num(b2, sizeof b2, 1e3 * t->tra.p99, "%.0f"));
  printf("interval between a viewer's states: p50 %s ms, p99 %s ms", sr_num(b1, sizeof b1, 1e3 * t->itv.p50, "%.0f"),
         sr_num(b2, sizeof b2, 1e3 * t->itv.p99, "%.0f"));
  if (!s->stepped) printf("; ticks the server skipped (a step still ran): %s", sr_num(b3, sizeof b3, s->late_ticks, "%.0f"));
  printf("\n");
  if (!s->stepped)
    printf("lateness (EPOCH_BEGIN readable minus its due instant n x P, UTC): p50 %s ms, p99 %s ms, max %s ms over %zu "
           "states; ticks coalesced %" PRIu64 " of %" PRIu64 " due (%s)\n",
           sr_num(b1, sizeof b1, 1e3 * t->late.p50, "%.1f"), sr_num(b2, sizeof b2, 1e3 * t->late.p99, "%.1f"),
           sr_num(b3, sizeof b3, 1e3 * t->late.max, "%.1f"), t->late.n, t->coal_ticks, t->due,
           sr_num(b4, sizeof b4, t->due ? 100.0 * (double)t->coal_ticks / (double)t->due : NAN, "%.2f %%"));
  if (o->verify_content > 0) sr_print_verified(o, s, t);
  printf("time to full detail after a teleport: p50 %s s, p99 %s s, p50 %s epochs (%zu of %" PRIu64
         " teleports settled; %" PRIu64 " did not before the next one or the end)\n",
         sr_num(b1, sizeof b1, t->det.p50, "%.2f"), sr_num(b2, sizeof b2, t->det.p99, "%.2f"),
         sr_num(b3, sizeof b3, t->dep.p50, "%.0f"), t->det.n, t->teleports, t->unreached);
}

/* The server, this tool, the brick cache, and the checks. */
static void sr_print_resources(const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
  char b1[32], b2[32], b3[32], b4[32];
  if (s->server_end.ok)
    printf("server: RSS %.1f MiB at the end, peak %.1f MiB; CPU %.2f s (%.0f %% of one core)\n", s->server_end.rss_mib,
           s->server_end.hwm_mib, s->server_cpu_s, s->cpu_span_s > 0 ? 100.0 * s->server_cpu_s / s->cpu_span_s : 0.0);
  else
    printf("server: RSS and CPU unknown (not a local process of ours: --server-pid)\n");
  printf("overcast-stress itself: CPU %.2f s (%.0f %% of one core), peak RSS %s MiB; its %s sessions held %.1f MiB at the "
         "end for %.1f MiB resident\n",
         s->tool_cpu_s, s->cpu_span_s > 0 ? 100.0 * s->tool_cpu_s / s->cpu_span_s : 0.0,
         sr_num(b1, sizeof b1, s->tool.ok ? s->tool.hwm_mib : NAN, "%.1f"), o->full_sessions ? "full" : "lean",
         (double)t->held / SR_MIB, (double)t->resident / SR_MIB);
  printf("brick cache: hit rate %s (%s requests, %s bricks produced), %s MiB held\n",
         sr_num(b1, sizeof b1, 100.0 * s->cache_hit_rate, "%.1f %%"), sr_num(b2, sizeof b2, s->brick_requests, "%.0f"),
         sr_num(b3, sizeof b3, s->bricks_produced, "%.0f"), sr_num(b4, sizeof b4, s->cache_bytes / SR_MIB, "%.1f"));
  printf("checks: %" PRIu64 " states; budget violations %" PRIu64 ", checksum failures %" PRIu64 ", protocol errors %" PRIu64
         ", resident counts differing from the session's %" PRIu64 ", viewers failed %" PRIu64 ", without a state %" PRIu64
         "; skipped epochs %" PRIu64 " (server: %" PRIu64 " coalesced)\n",
         t->states, t->violations, t->checksum, t->protocol, t->mismatch, t->failed, t->empty, t->skipped, t->coalesced);
}

/* Each viewer's skipped epochs and failure. */
static void sr_print_viewer_failures(const stress_run_t *run) {
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    if (v->skipped) {
      printf("skipped: viewer %d:", v->index);
      for (int k = 0; k < v->nskipped_list; k++) printf(" %" PRIu64, v->skipped_list[k]);
      printf("%s\n", v->skipped > (uint64_t)v->nskipped_list ? " ..." : "");
    }
    if (v->failed) printf("FAIL: %s\n", v->error);
    else if (!v->states) printf("FAIL: viewer %d (%s): no state\n", v->index, stress_path_name(v->path));
  }
}

/* --sweep: one row per budget and depth. */
static void sr_print_sweep(const stress_run_t *run, const sr_totals_t *t) {
  char b1[32], b2[32], b3[32], b4[32];
  printf("\nsweep (one viewer per budget and depth, path %s, the same seed):\n\n", stress_path_name(run->v[0].path));
  printf("| budget MiB asked | granted MiB | depth | states | resident max MiB | of granted | leaves | bricks | deepest level |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    double granted = v->have_welcome ? (double)v->welcome.budget : NAN;
    printf("| %s | %s | %d | %" PRIu64 " | %s | %s | %" PRIu64 " | %" PRIu64 " | %d |\n",
           v->budget == 1 ? "1 byte" : sr_num(b1, sizeof b1, (double)v->budget / SR_MIB, "%.0f"),
           sr_num(b2, sizeof b2, granted / SR_MIB, "%.3f"), v->max_depth, v->states,
           sr_num(b3, sizeof b3, (double)v->resident_max / SR_MIB, "%.3f"),
           sr_num(b4, sizeof b4, 100.0 * (double)v->resident_max / granted, "%.1f %%"), v->nodes_last, v->bricks_last,
           v->depth_max);
  }
  printf("\nsweep: %" PRIu64 " combinations coarser than a smaller or shallower one (deepest level), %" PRIu64
         " with fewer leaves than one (noted, not a failure)\n",
         t->coarser, t->fewer);
}

/* The JSON's "config". */
static cJSON *sr_config_json(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s) {
#define O(key, field, kind) SR_ROW(stress_opts_t, key, field, kind)
  static const sr_field_t rows[] = {O("width", width, SR_INT),         O("height", height, SR_INT),
                                    O("seed", seed, SR_U64),           O("epochs", epochs, SR_LONG),
                                    O("duration", duration, SR_DBL),   O("tick_hz", tick_hz, SR_DBL),
                                    O("step_seconds", step_seconds, SR_DBL), O("teleport_every", teleport_every, SR_DBL),
                                    O("dive_seconds", dive_seconds, SR_DBL)};
#undef O
  cJSON *cfg = cJSON_CreateObject();
  cJSON_AddStringToObject(cfg, "server", s->spawned ? "spawned" : "connected");
  cJSON_AddStringToObject(cfg, "address", run->host);
  cJSON_AddNumberToObject(cfg, "port", run->port);
  cJSON_AddStringToObject(cfg, "scene", s->scene);
  cJSON_AddNumberToObject(cfg, "kept_states", s->kept_states);
  cJSON_AddBoolToObject(cfg, "stepped", s->stepped);
  sr_add_num(cfg, "epoch_period", s->epoch_period);
  cJSON_AddNumberToObject(cfg, "viewers", run->nv);
  SR_ADD_FIELDS(cfg, o, rows);
  cJSON_AddNumberToObject(cfg, "slot_bytes", 2048);
  cJSON_AddNumberToObject(cfg, "record_bytes", 32);
  return cfg;
}

/* Lateness quantiles and ticks of one viewer (with a period). */
static void sr_viewer_clock_json(cJSON *x, const stress_viewer_t *v) {
  stress_samples_t lt = v->ticks.lateness;
  stress_q_t q = {NAN, NAN, NAN, lt.n};
  q.p50 = stress_quantile(lt.v, lt.n, 0.5); /* sorts: the max is the last one after it */
  q.p99 = stress_quantile(lt.v, lt.n, 0.99);
  q.max = lt.n ? lt.v[lt.n - 1] : NAN;
  cJSON_AddItemToObject(x, "lateness_s", sr_q_json(q));
  cJSON_AddNumberToObject(x, "ticks_due", (double)stress_ticks_due(&v->ticks));
  cJSON_AddNumberToObject(x, "ticks_coalesced", (double)v->ticks.coalesced);
  sr_add_num(x, "coalesced_fraction", stress_ticks_coalesced_frac(&v->ticks));
}

/* One viewer of the JSON's "viewers". */
static cJSON *sr_viewer_json(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s, int i) {
#define V(key, field) SR_ROW(stress_viewer_t, key, field, SR_U64)
  static const sr_field_t head[] = {V("states", states), V("first_epoch", first_epoch), V("last_epoch", last_epoch),
                                    V("skipped", skipped)};
  static const sr_field_t counts[] = {
      V("coalesced_server", last_stats.coalesced), V("resident_max", resident_max), V("resident_last", resident_last),
      V("server_resident_max", server_resident_max), V("budget_violations", violations),
      V("resident_mismatch", resident_mismatch), V("checksum_failures", checksum_failures),
      V("protocol_errors", protocol_errors), V("bytes_in", session.bytes_in), V("bricks_in", bricks_in),
      V("nodes_last", nodes_last), V("bricks_last", bricks_last), SR_ROW(stress_viewer_t, "depth_last", depth_last, SR_INT),
      SR_ROW(stress_viewer_t, "depth_max", depth_max, SR_INT)};
#undef V
  const stress_viewer_t *v = &run->v[i];
  cJSON *x = cJSON_CreateObject();
  cJSON_AddNumberToObject(x, "index", v->index);
  cJSON_AddStringToObject(x, "path", stress_path_name(v->path));
  cJSON_AddNumberToObject(x, "budget_asked", (double)v->budget);
  if (v->have_welcome) {
    cJSON_AddNumberToObject(x, "budget_granted", (double)v->welcome.budget);
    cJSON_AddNumberToObject(x, "session", v->welcome.session);
  }
  cJSON_AddNumberToObject(x, "max_depth", v->max_depth);
  SR_ADD_FIELDS(x, v, head);
  cJSON *sk = cJSON_AddArrayToObject(x, "skipped_epochs");
  for (int k = 0; k < v->nskipped_list; k++) cJSON_AddItemToArray(sk, cJSON_CreateNumber((double)v->skipped_list[k]));
  SR_ADD_FIELDS(x, v, counts);
  sr_add_num(x, "seconds", v->have_welcome ? v->t_end - v->t_welcome : NAN);
  sr_add_num(x, "bytes_per_s", sr_rate(v));
  cJSON_AddItemToObject(x, "latency_s", sr_q_json(SR_POOL(run, latency, i)));
  cJSON_AddItemToObject(x, "transfer_s", sr_q_json(SR_POOL(run, transfer, i)));
  cJSON_AddItemToObject(x, "interval_s", sr_q_json(SR_POOL(run, interval, i)));
  if (v->path == STRESS_TELEPORT) {
    cJSON_AddItemToObject(x, "full_detail_s", sr_q_json(SR_POOL(run, detail, i)));
    cJSON_AddItemToObject(x, "full_detail_epochs", sr_q_json(SR_POOL(run, detail_epochs, i)));
    cJSON_AddNumberToObject(x, "teleports", (double)v->teleports);
    cJSON_AddNumberToObject(x, "full_detail_unreached", (double)v->detail_unreached);
  }
  if (!s->stepped) sr_viewer_clock_json(x, v);
  if (o->verify_content > 0) {
    stress_age_t va = v->age;
    stress_age_merge(&va, &v->m_age);
    cJSON_AddItemToObject(x, "content_age", sr_age_json(&va));
  }
  if (v->failed) cJSON_AddStringToObject(x, "error", v->error);
  return x;
}

/* The JSON's "aggregate". */
static cJSON *sr_aggregate_json(const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
  cJSON *ag = cJSON_CreateObject();
  sr_add_num(ag, "bytes_per_s_median", t->rate_p50);
  sr_add_num(ag, "bytes_per_s_p99", t->rate_p99);
  cJSON_AddStringToObject(ag, "latency_from", s->stepped ? "step request" : "first byte of EPOCH_BEGIN");
  cJSON_AddItemToObject(ag, "latency_s", sr_q_json(t->lat));
  cJSON_AddItemToObject(ag, "transfer_s", sr_q_json(t->tra));
  cJSON_AddItemToObject(ag, "interval_s", sr_q_json(t->itv));
  cJSON_AddItemToObject(ag, "full_detail_s", sr_q_json(t->det));
  cJSON_AddItemToObject(ag, "full_detail_epochs", sr_q_json(t->dep));
  cJSON_AddNumberToObject(ag, "teleports", (double)t->teleports);
  if (!s->stepped) {
    cJSON_AddItemToObject(ag, "lateness_s", sr_q_json(t->late));
    cJSON_AddNumberToObject(ag, "ticks_due", (double)t->due);
    cJSON_AddNumberToObject(ag, "ticks_coalesced", (double)t->coal_ticks);
    sr_add_num(ag, "coalesced_fraction", t->due ? (double)t->coal_ticks / (double)t->due : NAN);
  }
  if (o->verify_content > 0) {
    cJSON *va = sr_age_json(&t->ages);
    cJSON_AddNumberToObject(va, "fraction", o->verify_content);
    cJSON_AddNumberToObject(va, "left_unverified", (double)s->verify_left);
    cJSON_AddNumberToObject(va, "reproduce_s", s->verify_s);
    cJSON_AddNumberToObject(va, "reproduced", (double)s->verify_reproduced);
    cJSON_AddItemToObject(ag, "content_age", va);
  }
  cJSON_AddNumberToObject(ag, "full_detail_unreached", (double)t->unreached);
  return ag;
}

/* The JSON's "server", "tool" and "run". */
static void sr_resources_json(cJSON *j, const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
#define S(key, field) SR_ROW(stress_summary_t, key, field, SR_DBL)
  static const sr_field_t server[] = {S("cache_hit_rate", cache_hit_rate), S("brick_requests", brick_requests),
                                      S("bricks_produced", bricks_produced), S("late_ticks", late_ticks),
                                      S("cache_bytes", cache_bytes)};
#undef S
  cJSON *sv = cJSON_AddObjectToObject(j, "server");
  cJSON_AddItemToObject(sv, "start", sr_proc_json(&s->server_start));
  cJSON_AddItemToObject(sv, "end", sr_proc_json(&s->server_end));
  sr_add_num(sv, "cpu_s", s->server_cpu_s);
  if (s->spawned) cJSON_AddNumberToObject(sv, "exit_status", s->server_exit);
  SR_ADD_FIELDS(sv, s, server);
  cJSON *tl = cJSON_AddObjectToObject(j, "tool");
  cJSON_AddNumberToObject(tl, "cpu_s", s->tool_cpu_s);
  cJSON_AddStringToObject(tl, "sessions", o->full_sessions ? "full" : "lean");
  cJSON_AddNumberToObject(tl, "sessions_held_bytes", (double)t->held);
  cJSON_AddNumberToObject(tl, "sessions_resident_bytes", (double)t->resident);
  cJSON_AddNumberToObject(tl, "wall_s", s->wall_s);
  cJSON_AddNumberToObject(tl, "cpu_span_s", s->cpu_span_s);
  sr_add_num(tl, "peak_rss_mib", s->tool.ok ? s->tool.hwm_mib : NAN);
  cJSON *run_j = cJSON_AddObjectToObject(j, "run");
  cJSON_AddNumberToObject(run_j, "steps", (double)s->steps);
  cJSON_AddNumberToObject(run_j, "steps_incomplete", (double)s->steps_incomplete);
}

/* The JSON's "checks". */
static cJSON *sr_checks_json(const stress_opts_t *o, const stress_summary_t *s, const sr_totals_t *t) {
#define T(key, field) SR_ROW(sr_totals_t, key, field, SR_U64)
  static const sr_field_t rows[] = {
      T("states", states),         T("budget_violations", violations), T("checksum_failures", checksum),
      T("protocol_errors", protocol), T("resident_mismatch", mismatch), T("viewers_failed", failed),
      T("viewers_without_state", empty), T("skipped_epochs", skipped), T("coalesced_server", coalesced),
      T("content_mismatches", content_mismatch)};
  static const sr_field_t sweep[] = {T("sweep_coarser", coarser), T("sweep_fewer_leaves", fewer)};
#undef T
  cJSON *ck = cJSON_CreateObject();
  SR_ADD_FIELDS(ck, t, rows);
  if (o->sweep) SR_ADD_FIELDS(ck, t, sweep);
  if (s->error[0]) cJSON_AddStringToObject(ck, "error", s->error);
  return ck;
}

/* Everything measured, as JSON (--json). @return 0, or -1 after a message. */
static int sr_json(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s, const sr_totals_t *t,
                   int pass) {
  cJSON *j = cJSON_CreateObject();
  cJSON_AddItemToObject(j, "config", sr_config_json(o, run, s));
  cJSON *vs = cJSON_AddArrayToObject(j, "viewers");
  for (int i = 0; i < run->nv; i++) cJSON_AddItemToArray(vs, sr_viewer_json(o, run, s, i));
  cJSON_AddItemToObject(j, "aggregate", sr_aggregate_json(o, s, t));
  sr_resources_json(j, o, s, t);
  cJSON_AddItemToObject(j, "checks", sr_checks_json(o, s, t));
  if (o->faults) cJSON_AddItemToObject(j, "faults", sr_faults_json(o, run, s));
  cJSON_AddBoolToObject(j, "pass", pass);
  return sr_write_json(j, o->json);
}

/* One line on stderr naming the first cause of a failure (the table has them all). */
static void sr_fail_line(const stress_run_t *run, const stress_summary_t *s, const sr_totals_t *t, const char *fault_cause) {
  const char *cause = s->error[0] ? s->error : fault_cause;
  for (int i = 0; !cause[0] && i < run->nv; i++)
    if (run->v[i].failed) cause = run->v[i].error;
  if (cause[0]) fprintf(stderr, "overcast-stress: FAIL: %s\n", cause);
  else if (t->coarser)
    fprintf(stderr, "overcast-stress: FAIL: %" PRIu64 " sweep combinations coarser than a smaller or shallower one\n", t->coarser);
  else if (t->content_mismatch)
    fprintf(stderr, "overcast-stress: FAIL: CONTENT MISMATCH: %" PRIu64 " verified bricks matched no stamp s .. s-%d\n",
            t->content_mismatch, STRESS_AGE_MAX);
  else if (t->violations || t->mismatch)
    fprintf(stderr, "overcast-stress: FAIL: %" PRIu64 " budget violations, %" PRIu64 " resident counts differing from the session's\n",
            t->violations, t->mismatch);
  else
    fprintf(stderr, "overcast-stress: FAIL: %" PRIu64 " of %d viewers got no state within the run (%.1f s)\n", t->empty,
            run->nv, s->wall_s);
}

int stress_report(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s) {
  static sr_totals_t t; /* its ages are large */
  sr_totals(o, run, s, &t);
  sr_print_viewers(run, s);
  sr_print_aggregates(o, s, &t);
  sr_print_resources(o, s, &t);
  sr_print_viewer_failures(run);
  if (o->sweep) sr_print_sweep(run, &t);
  int pass = t.pass;
  char fault_cause[512] = "";
  if (o->faults && sr_faults(o, run, s, fault_cause, sizeof fault_cause)) pass = 0;
  if (s->error[0]) printf("FAIL: %s\n", s->error);
  printf("%s\n", pass ? "PASS" : "FAIL");
  fflush(stdout);
  int rc = pass;
  if (o->json && sr_json(o, run, s, &t, pass) < 0) rc = -1;
  if (!pass) sr_fail_line(run, s, &t, fault_cause);
  return rc;
}

/* "0".."8", "none" (matched no stamp tried), "—" (nothing verified) */
static const char *sr_age(char *buf, size_t cap, int age) {
  if (age < 0) snprintf(buf, cap, "—");
  else if (age > STRESS_AGE_MAX) snprintf(buf, cap, "none");
  else snprintf(buf, cap, "%d", age);
  return buf;
}

static cJSON *sr_age_json(const stress_age_t *a) {
  cJSON *o = cJSON_CreateObject();
  cJSON_AddNumberToObject(o, "sampled", (double)a->sampled);
  cJSON_AddNumberToObject(o, "dropped", (double)a->dropped);
  cJSON_AddNumberToObject(o, "errors", (double)a->errors);
  cJSON_AddNumberToObject(o, "verified", (double)stress_age_count(a, -1));
  cJSON_AddNumberToObject(o, "mismatches", (double)stress_age_mismatches(a, -1));
  uint64_t none = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) none += a->n[l][STRESS_AGE_MAX + 1];
  cJSON_AddNumberToObject(o, "matched_none", (double)none); /* of the mismatches: no stamp tried matched */
  int p99 = stress_age_quantile(a, -1, 0.99);
  if (p99 >= 0) cJSON_AddNumberToObject(o, "p99", p99);
  else cJSON_AddNullToObject(o, "p99");
  cJSON *lv = cJSON_AddArrayToObject(o, "levels");
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    if (!stress_age_count(a, l)) continue;
    cJSON *x = cJSON_CreateObject();
    cJSON_AddItemToArray(lv, x);
    cJSON_AddNumberToObject(x, "level", l);
    cJSON_AddNumberToObject(x, "verified", (double)stress_age_count(a, l));
    cJSON_AddNumberToObject(x, "p50", stress_age_quantile(a, l, 0.5));
    cJSON_AddNumberToObject(x, "p99", stress_age_quantile(a, l, 0.99));
    cJSON_AddNumberToObject(x, "mismatches", (double)stress_age_mismatches(a, l));
    cJSON *h = cJSON_AddArrayToObject(x, "histogram"); /* ages 0..STRESS_AGE_MAX, then "none" */
    for (int k = 0; k <= STRESS_AGE_MAX + 1; k++) cJSON_AddItemToArray(h, cJSON_CreateNumber((double)a->n[l][k]));
  }
  return o;
}

/* The verified ages per level, one line: "L12 p99 1 (340), L13 ..." */
static void sr_age_levels(const stress_age_t *a) {
  char b[16];
  int any = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    uint64_t n = stress_age_count(a, l);
    if (!n) continue;
    printf("%s L%d %s (%" PRIu64 ")", any ? "," : "", l, sr_age(b, sizeof b, stress_age_quantile(a, l, 0.99)), n);
    any = 1;
  }
  if (!any) printf(" —");
  uint64_t older = 0, none = stress_age_mismatches(a, -1);
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    for (int k = STRESS_AGE_ALLOWED + 1; k <= STRESS_AGE_MAX; k++) older += a->n[l][k];
  if (older) printf("; %" PRIu64 " older than s-2 (stale: matched s-3..s-%d)", older, STRESS_AGE_MAX);
  if (none) printf("; mismatches (matched no stamp): %" PRIu64, none);
}

/* PREFIX-NAME.png from np points (none: no file). @return 0, or -1 after a message. */
static int sr_plot(const char *prefix, const char *name, const octs_plot_point_t *pts, int np, const octs_plot_desc_t *d) {
  char path[4096], why[512];
  if (!np) return 0;
  snprintf(path, sizeof path, "%s-%s.png", prefix, name);
  if (octs_plot_png(path, pts, np, d, why, sizeof why) < 0) {
    fprintf(stderr, "overcast-stress: %s: %s\n", path, why);
    return -1;
  }
  printf("plot: %s\n", path);
  return 0;
}

/* The plot group of a budget: its index among the first nb of o->budgets_mib, or -1. */
static int sr_budget_group(const stress_opts_t *o, int nb, long budget_mib) {
  int g = -1;
  for (int b = 0; b < nb; b++)
    if (o->budgets_mib[b] == budget_mib) g = b;
  return g;
}

/* Plots of a ramp: content age p99 and time to full detail against N, one line per budget. */
static int sr_ramp_plots(const stress_opts_t *o, const char *scene, double period, const stress_ramp_phase_t *ph, int nph) {
  int nb = o->nbudgets < OCTS_PLOT_GROUPS / 3 ? o->nbudgets : OCTS_PLOT_GROUPS / 3;
  octs_plot_point_t *pts = calloc((size_t)(3 * nph + 1), sizeof *pts);
  char names[OCTS_PLOT_GROUPS][48], sub[256];
  if (!pts) return -1;
  int rc = 0;
  snprintf(sub, sizeof sub, "%s, epoch period %g s, %s paths, %.0f s measured per phase", scene, period,
           o->share_paths ? "shared" : "disjoint", o->ramp_seconds);
  /* content age */
  int np = 0;
  for (int i = 0; i < nph; i++) {
    int g = sr_budget_group(o, nb, ph[i].budget_mib);
    if (g < 0 || ph[i].age_p99 < 0) continue;
    pts[np++] = (octs_plot_point_t){.x = ph[i].n, .y = ph[i].age_p99 > STRESS_AGE_MAX ? STRESS_AGE_MAX + 1 : ph[i].age_p99, .group = g};
  }
  octs_plot_desc_t d = {.title = "Verified content age p99 against viewers", .subtitle = sub, .xlabel = "viewers N",
                        .ylabel = "time steps behind", .ngroups = nb, .lines = 1, .ymin_top = 3, .hline = STRESS_AGE_ALLOWED,
                        .hline_label = "sustained limit"};
  for (int b = 0; b < nb; b++) {
    snprintf(names[b], sizeof names[b], "%ld MiB", o->budgets_mib[b]);
    d.group_name[b] = names[b];
  }
  if (sr_plot(o->plot, "age", pts, np, &d) < 0) rc = -1;
  /* time to full detail, the stepped reference drawn as a line across the same N */
  np = 0;
  for (int i = 0; i < nph; i++) {
    int g = sr_budget_group(o, nb, ph[i].budget_mib);
    if (g < 0) continue;
    pts[np++] = (octs_plot_point_t){.x = ph[i].n, .y = ph[i].detail_p50, .group = g};
    if (isfinite(ph[i].detail_lower_s) && !isfinite(ph[i].detail_p50)) /* none settled: a lower bound */
      pts[np++] = (octs_plot_point_t){.x = ph[i].n, .y = ph[i].detail_lower_s, .group = 2 * nb + g};
    if (isfinite(ph[i].detail_ref)) /* what the rule compares with (stress.h: held, seconds or epochs) */
      pts[np++] = (octs_plot_point_t){.x = ph[i].n, .y = ph[i].detail_ref, .group = nb + g};
  }
  octs_plot_desc_t e = {.title = "Time to full detail after a teleport (p50) against viewers", .subtitle = sub,
                        .xlabel = "viewers N", .ylabel = "seconds", .ngroups = 3 * nb, .lines = 1};
  for (int b = 0; b < nb; b++) {
    snprintf(names[nb + b], sizeof names[nb + b], "stepped, %ld MiB", o->budgets_mib[b]);
    snprintf(names[2 * nb + b], sizeof names[2 * nb + b], "not settled: > y");
    e.group_name[2 * nb + b] = names[2 * nb + b];
    e.group_name[b] = names[b];
    e.group_name[nb + b] = names[nb + b];
  }
  if (sr_plot(o->plot, "detail", pts, np, &e) < 0) rc = -1;
  free(pts);
  return rc;
}

/* What the rule compares time to full detail with, in words (o->detail_ref). */
static const char *sr_detail_ref(const stress_opts_t *o, int json) {
  if (o->detail_ref == STRESS_DETAIL_REF_SECONDS) return json ? "stepped seconds" : "seconds";
  if (o->detail_ref == STRESS_DETAIL_REF_EPOCHS) return json ? "stepped epochs x period" : "epochs x P";
  return json ? "stepped seconds or epochs x period, the larger" : "seconds or epochs x P, the larger";
}

/* The ramp's heading, its rule and its stepped references. */
static void sr_ramp_heading(const stress_opts_t *o, const char *scene, double period, const stress_ref_t *refs, int nrefs) {
  char b1[32], b2[32], b3[32], b4[32];
  printf("overcast-stress --ramp: scene %s, epoch period %g s, %.0f s warm-up + %.0f s measured per phase, one server, "
         "%s paths%s\n",
         scene, period, o->ramp_warmup, o->ramp_seconds, o->share_paths ? "shared (one seed)" : "disjoint",
         o->verify_content > 0 ? "" : ", content not verified (--verify-content)");
  printf("sustained: every viewer has lateness p99 <= %.0f ms, <= %.0f %% of ticks coalesced, verified content age p99 <= %d, "
         "time to full detail p50 <= %.2f x stepped, median interval <= %.1f x the period\n",
         1e3 * STRESS_LATE_P99, 100.0 * STRESS_COALESCED_MAX, STRESS_AGE_ALLOWED, STRESS_DETAIL_FACTOR, STRESS_RAMP_INTERVAL);
  for (int r = 0; r < nrefs; r++)
    printf("stepped reference, %ld MiB (viewer %d's teleport path, %.0f s): full detail p50 %s s, p99 %s s, p50 %s epochs "
           "(%s s at the period), %" PRIu64 " of %" PRIu64 " teleports settled; the rule compares with its %s%s%s\n",
           refs[r].budget_mib, refs[r].index, refs[r].seconds, sr_num(b1, sizeof b1, refs[r].detail_p50, "%.2f"),
           sr_num(b2, sizeof b2, refs[r].detail_p99, "%.2f"), sr_num(b3, sizeof b3, refs[r].detail_epochs_p50, "%.0f"),
           sr_num(b4, sizeof b4, refs[r].detail_epochs_p50 * period, "%.0f"), refs[r].settled, refs[r].teleports,
           sr_detail_ref(o, 0), refs[r].error[0] ? "; " : "", refs[r].error);
}

/* One phase's row of the ramp's table. */
static void sr_ramp_row(const stress_ramp_phase_t *p) {
  char b1[32], b2[32], b3[32], b4[32], b5[32], b6[32], b7[32], b8[32], b9[32], b10[32];
  char late[80], coal[80], age[80], det[80];
  snprintf(late, sizeof late, "%s (%s)", sr_num(b1, sizeof b1, 1e3 * p->late_p99, "%.0f"),
           sr_num(b2, sizeof b2, 1e3 * p->late_worst_p99, "%.0f"));
  snprintf(coal, sizeof coal, "%s (%s)", sr_num(b3, sizeof b3, 100.0 * p->coalesced_frac, "%.1f %%"),
           sr_num(b4, sizeof b4, 100.0 * p->coalesced_worst, "%.1f %%"));
  snprintf(age, sizeof age, "%s (%s)", sr_age(b5, sizeof b5, p->age_p99), sr_age(b6, sizeof b6, p->age_worst_p99));
  /* p50, and teleports settled of those made in the window */
  if (p->teleports && !p->detail_n && isfinite(p->detail_lower_s))
    snprintf(det, sizeof det, "> %.0f (0/%" PRIu64 ")", p->detail_lower_s, p->teleports);
  else if (p->teleports)
    snprintf(det, sizeof det, "%s (%" PRIu64 "/%" PRIu64 ")", sr_num(b8, sizeof b8, p->detail_p50, "%.2f"), p->detail_n,
             p->teleports);
  else
    snprintf(det, sizeof det, "—");
  printf("| %ld | %d | %s | %s | %s | %s | %" PRIu64 " | %s | %s | %s | %s | %s | %s%s |\n", p->budget_mib, p->n, late,
         sr_num(b7, sizeof b7, 1e3 * p->late_max, "%.0f"), coal, age, p->age_mismatch, det,
         sr_num(b9, sizeof b9, p->detail_worst_ratio, "%.2f"), sr_num(b10, sizeof b10, p->itv_p50, "%.2f"),
         sr_num(b1, sizeof b1, p->cpu_pct, "%.0f %%"), sr_num(b2, sizeof b2, p->mbps_p50, "%.3f"),
         p->sustained ? "yes" : "no: ", p->sustained ? "" : p->why);
}

/* --verify-content: each phase's verified ages per level. */
static void sr_ramp_ages(const stress_ramp_phase_t *ph, int nph) {
  char b1[32];
  printf("\nverified content age p99 per level (bricks verified):\n");
  for (int i = 0; i < nph; i++) {
    printf("  %ld MiB, N = %d:", ph[i].budget_mib, ph[i].n);
    sr_age_levels(&ph[i].age);
    printf("; sampled %" PRIu64 ", dropped %" PRIu64 ", errors %" PRIu64 "%s; the server's own STATS age p99 (worst level, "
           "last STATS): %s\n", ph[i].age.sampled, ph[i].age.dropped, ph[i].age.errors,
           ph[i].verify_left ? " (some left unverified: the drain timed out)" : "", sr_age(b1, sizeof b1, ph[i].server_age_p99));
    if (ph[i].age_mismatch)
      printf("CONTENT MISMATCH: %ld MiB, N = %d: %" PRIu64 " verified bricks matched no stamp s .. s-%d\n", ph[i].budget_mib,
             ph[i].n, ph[i].age_mismatch, STRESS_AGE_MAX);
  }
}

/* One phase of the ramp's JSON. */
static cJSON *sr_phase_json(const stress_opts_t *o, const stress_ramp_phase_t *p) {
#define P(key, field, kind) SR_ROW(stress_ramp_phase_t, key, field, kind)
  static const sr_field_t rows[] = {
      P("budget_mib", budget_mib, SR_LONG),
      P("viewers", n, SR_INT),
      P("seconds", seconds, SR_DBL),
      P("interval_p50_s", itv_p50, SR_DBL),
      P("interval_p99_s", itv_p99, SR_DBL),
      P("worst_viewer_median_s", worst_median, SR_DBL),
      P("states", states, SR_U64),
      P("skipped", skipped, SR_U64),
      P("skipped_fraction", skipped_frac, SR_DBL),
      P("lateness_p50_s", late_p50, SR_DBL),
      P("lateness_p99_s", late_p99, SR_DBL),
      P("lateness_max_s", late_max, SR_DBL),
      P("lateness_worst_viewer_p99_s", late_worst_p99, SR_DBL),
      P("ticks_due", due, SR_U64),
      P("ticks_coalesced", coalesced, SR_U64),
      P("coalesced_fraction", coalesced_frac, SR_DBL),
      P("coalesced_worst_viewer_fraction", coalesced_worst, SR_DBL),
      P("coalesced_server", coalesced_server, SR_U64),
      P("verify_left", verify_left, SR_U64),
      P("full_detail_p50_s", detail_p50, SR_DBL),
      P("full_detail_p99_s", detail_p99, SR_DBL),
      P("full_detail_stepped_p50_s", detail_ref, SR_DBL),
      P("full_detail_worst_ratio", detail_worst_ratio, SR_DBL),
      P("full_detail_unsettled_at_least_s", detail_lower_s, SR_DBL),
      P("teleports", teleports, SR_U64),
      P("teleports_settled", detail_n, SR_U64),
      P("teleports_unreached", unreached, SR_U64),
      P("server_cpu_percent", cpu_pct, SR_DBL),
      P("server_rss_mib", rss_mib, SR_DBL),
      P("server_peak_rss_mib", hwm_mib, SR_DBL),
      P("mb_per_s_per_viewer_p50", mbps_p50, SR_DBL),
      P("mb_per_s_per_viewer_p99", mbps_p99, SR_DBL),
      P("budget_violations", violations, SR_U64),
      P("checksum_failures", checksum, SR_U64),
      P("protocol_errors", protocol, SR_U64),
      P("resident_mismatch", mismatch, SR_U64),
      P("content_mismatches", age_mismatch, SR_U64),
      P("viewers_failed", failed, SR_U64),
  };
#undef P
  cJSON *x = cJSON_CreateObject();
  SR_ADD_FIELDS(x, p, rows);
  if (o->verify_content > 0) cJSON_AddItemToObject(x, "content_age", sr_age_json(&p->age));
  if (p->age_worst_p99 >= 0) cJSON_AddNumberToObject(x, "content_age_worst_viewer_p99", p->age_worst_p99);
  if (p->server_age_p99 >= 0) cJSON_AddNumberToObject(x, "server_stats_age_p99_worst", p->server_age_p99);
  cJSON_AddBoolToObject(x, "sustained", p->sustained);
  if (p->why[0]) cJSON_AddStringToObject(x, "why", p->why);
  return x;
}

/* One stepped reference of the ramp's JSON. */
static cJSON *sr_ref_json(const stress_ref_t *r) {
#define R(key, field, kind) SR_ROW(stress_ref_t, key, field, kind)
  static const sr_field_t rows[] = {
      R("budget_mib", budget_mib, SR_LONG),          R("viewer_index", index, SR_INT),
      R("full_detail_p50_s", detail_p50, SR_DBL),    R("full_detail_p99_s", detail_p99, SR_DBL),
      R("full_detail_epochs_p50", detail_epochs_p50, SR_DBL), R("teleports", teleports, SR_U64),
      R("settled", settled, SR_U64),                 R("seconds", seconds, SR_DBL)};
#undef R
  cJSON *x = cJSON_CreateObject();
  SR_ADD_FIELDS(x, r, rows);
  if (r->error[0]) cJSON_AddStringToObject(x, "error", r->error);
  return x;
}

/* The ramp's JSON (--json). @return 0, or -1 after a message. */
static int sr_ramp_json(const stress_opts_t *o, const char *scene, double period, const stress_ramp_phase_t *ph, int nph,
                        const int *largest, const stress_ref_t *refs, int nrefs, const stress_summary_t *s, int pass) {
  cJSON *j = cJSON_CreateObject();
  cJSON *r = cJSON_AddObjectToObject(j, "ramp");
  cJSON_AddStringToObject(r, "scene", scene);
  cJSON_AddNumberToObject(r, "epoch_period", period);
  cJSON_AddNumberToObject(r, "warmup_s", o->ramp_warmup);
  cJSON_AddNumberToObject(r, "measured_s", o->ramp_seconds);
  cJSON_AddStringToObject(r, "paths", o->share_paths ? "shared" : "disjoint");
  cJSON_AddNumberToObject(r, "verify_content", o->verify_content);
  cJSON *rule = cJSON_AddObjectToObject(r, "rule");
  cJSON_AddNumberToObject(rule, "lateness_p99_s", STRESS_LATE_P99);
  cJSON_AddNumberToObject(rule, "coalesced_fraction", STRESS_COALESCED_MAX);
  cJSON_AddNumberToObject(rule, "content_age_p99", STRESS_AGE_ALLOWED);
  cJSON_AddNumberToObject(rule, "full_detail_factor", STRESS_DETAIL_FACTOR);
  cJSON_AddStringToObject(rule, "full_detail_reference", sr_detail_ref(o, 1));
  cJSON_AddNumberToObject(rule, "interval_factor", STRESS_RAMP_INTERVAL);
  cJSON *ra = cJSON_AddArrayToObject(r, "stepped_reference");
  for (int k = 0; k < nrefs; k++) cJSON_AddItemToArray(ra, sr_ref_json(&refs[k]));
  cJSON *a = cJSON_AddArrayToObject(r, "phases");
  for (int i = 0; i < nph; i++) cJSON_AddItemToArray(a, sr_phase_json(o, &ph[i]));
  cJSON *lg = cJSON_AddArrayToObject(r, "largest_sustained");
  for (int b = 0; b < o->nbudgets; b++) {
    cJSON *x = cJSON_CreateObject();
    cJSON_AddItemToArray(lg, x);
    cJSON_AddNumberToObject(x, "budget_mib", (double)o->budgets_mib[b]);
    cJSON_AddNumberToObject(x, "viewers", largest[b]);
  }
  sr_add_num(r, "tool_peak_rss_mib", s->tool.ok ? s->tool.hwm_mib : NAN);
  if (s->error[0]) cJSON_AddStringToObject(r, "error", s->error);
  cJSON_AddBoolToObject(j, "pass", pass);
  return sr_write_json(j, o->json);
}

int stress_ramp_report(const stress_opts_t *o, const char *scene, double period, const stress_ramp_phase_t *ph, int nph,
                       const int *largest, const stress_ref_t *refs, int nrefs, const stress_summary_t *s) {
  char b1[32];
  int pass = !s->error[0];
  sr_ramp_heading(o, scene, period, refs, nrefs);
  printf("\n| budget MiB | N | lateness p99 ms (worst viewer) | max ms | coalesced (worst) | age p99 (worst) | mismatches | "
         "full detail p50 s (settled/teleports) | x stepped (worst) | interval p50 s | server CPU | MB/s per viewer p50 | sustained |\n");
  printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  for (int i = 0; i < nph; i++) {
    const stress_ramp_phase_t *p = &ph[i];
    if (p->failed || p->violations || p->checksum || p->protocol || p->mismatch || p->age_mismatch) pass = 0;
    sr_ramp_row(p);
  }
  if (o->verify_content > 0) sr_ramp_ages(ph, nph);
  printf("\n");
  for (int b = 0; b < o->nbudgets; b++) {
    int all = 0; /* the ramp of this budget ended at --ramp-max, not at a failure */
    for (int i = 0; i < nph; i++)
      if (ph[i].budget_mib == o->budgets_mib[b]) all = ph[i].sustained;
    printf("largest N sustained at %ld MiB: %d%s\n", o->budgets_mib[b], largest[b],
           all ? " (every phase was: at least this; raise --ramp-max)" : "");
  }
  if (s->server_end.ok || s->tool.ok)
    printf("overcast-stress itself: peak RSS %s MiB\n", sr_num(b1, sizeof b1, s->tool.ok ? s->tool.hwm_mib : NAN, "%.1f"));
  int rc_plot = o->plot ? sr_ramp_plots(o, scene, period, ph, nph) : 0;
  if (s->error[0]) printf("FAIL: %s\n", s->error);
  printf("%s\n", pass ? "PASS" : "FAIL");
  fflush(stdout);
  int rc = rc_plot < 0 ? -1 : pass;
  if (o->json && sr_ramp_json(o, scene, period, ph, nph, largest, refs, nrefs, s, pass) < 0) rc = -1;
  if (!pass) fprintf(stderr, "overcast-stress: FAIL: %s\n", s->error[0] ? s->error : "a check failed in a ramp phase");
  return rc;
}

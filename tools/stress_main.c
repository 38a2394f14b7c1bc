/* overcast-stress — many headless viewers against one overcast-server, over the real protocol, in
 * one process (docs/performance.md, "Many viewers"). Each viewer is a thread with its own
 * connection, camera path, budget and depth (stress_viewer.c); this file parses the command line,
 * starts the server (a child process, so that its RSS and CPU are its own) or connects to one,
 * steps the epochs when the server is stepped by command, and stops everything and reports
 * (stress_report.c). */
#include <cjson/cJSON.h>
#include <inttypes.h>
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "oc.h"
#include "stress.h"

static const char *prog = "overcast-stress";
static volatile sig_atomic_t g_interrupted = 0;

static void on_signal(int sig) {
  (void)sig;
  g_interrupted = 1;
}

/* One control request; the reply parsed. @return 0 or -1 with a reason in why. */
static int control(ocv_conn_t *ctl, const char *json, double timeout, cJSON **reply, char *why, size_t why_len) {
  char *text = NULL, reason[1024];
  int32_t status = 0;
  *reply = NULL;
  if (ocv_control_request(ctl, json, timeout, &text, &status, reason, sizeof reason) < 0) {
    snprintf(why, why_len, "%s", reason);
    return -1;
  }
  cJSON *r = cJSON_Parse(text);
  if (status != OCP_CODE_OK || !cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(r, "ok"))) {
    const cJSON *e = cJSON_GetObjectItemCaseSensitive(r, "error");
    snprintf(why, why_len, "%s: %s refused: %s", ocv_conn_address(ctl), json,
             cJSON_IsString(e) ? e->valuestring : ocp_code_text((uint32_t)status));
    cJSON_Delete(r);
    free(text);
    return -1;
  }
  free(text);
  if (!r) {
    snprintf(why, why_len, "%s: the reply to %s is not JSON", ocv_conn_address(ctl), json);
    return -1;
  }
  *reply = r;
  return 0;
}

static double world_num(const cJSON *reply, const char *key) {
  const cJSON *w = cJSON_GetObjectItemCaseSensitive(reply, "world");
  const cJSON *x = cJSON_GetObjectItemCaseSensitive(w, key);
  return cJSON_IsNumber(x) ? x->valuedouble : NAN;
}

/* Waits on run->cv (mu held) for at most s seconds. */
static void cv_wait(stress_run_t *run, double s) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  double ns = (double)t.tv_nsec + s * 1e9;
  t.tv_sec += (time_t)(ns / 1e9);
  t.tv_nsec = (long)fmod(ns, 1e9);
  pthread_cond_timedwait(&run->cv, &run->mu, &t);
}

/* Keeps the idle control connection alive (the server closes silent ones) and reads what came. */
static void ctl_tend(ocv_conn_t *ctl) {
  char why[256];
  if (ocv_conn_silence(ctl) >= OCV_KEEPALIVE_S) ocv_conn_keepalive(ctl);
  (void)ocv_conn_poll(ctl, 0, why, sizeof why); /* a lost connection shows at the next request */
}

static int all_done(const stress_run_t *run) {
  for (int i = 0; i < run->nv; i++)
    if (!run->v[i].done) return 0;
  return 1;
}

/*-*** Faults: the coordinator's part (the misbehaving connections are stress_fault.c's) ***/

typedef struct {
  ocv_child_t *child;   /* spawned: the server, restarted in place */
  char **argv;             /* its command line; argv[listen] is rewritten to keep the port */
  int listen;
  char listen_addr[OCV_HOST_MAX + 16];
  int have_base;           /* the current incarnation's baseline was taken */
  double rss_base, acc_base;
} fault_ctx_t;

static double num_at(const cJSON *o, const char *key) {
  const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, key);
  return cJSON_IsNumber(x) ? x->valuedouble : NAN;
}

/* After a step: the server's RSS against what it accounts for (brick cache, held states, and each
 * connection's unsent bytes and own memory). The first sample of an incarnation is its baseline. */
static void fault_sample(stress_run_t *run, ocv_conn_t *ctl, fault_ctx_t *fx, stress_summary_t *sum) {
  const stress_opts_t *o = run->o;
  stress_fault_mem_t *m = &sum->fault_mem;
  char why[1024];
  cJSON *st = NULL, *ss = NULL;
  stress_proc_t p;
  stress_proc_sample(fx->child && fx->child->pid > 0 ? (long)fx->child->pid : o->server_pid, &p);
  if (control(ctl, "{\"op\":\"stats\"}", o->timeout, &st, why, sizeof why) < 0 ||
      control(ctl, "{\"op\":\"sessions\"}", o->timeout, &ss, why, sizeof why) < 0) {
    if (!sum->error[0]) snprintf(sum->error, sizeof sum->error, "faults: %.400s", why);
    cJSON_Delete(st);
    return;
  }
  const cJSON *w = cJSON_GetObjectItemCaseSensitive(st, "world");
  double queued = 0, conn = 0;
  const cJSON *x;
  cJSON_ArrayForEach(x, cJSON_GetObjectItemCaseSensitive(ss, "sessions")) {
    double q = num_at(x, "queued"), mem = num_at(x, "memory");
    if (isfinite(q)) {
      queued += q;
      if ((uint64_t)q > m->queued_max) m->queued_max = (uint64_t)q;
    }
    if (isfinite(mem)) conn += mem;
  }
  double qh = num_at(cJSON_GetObjectItemCaseSensitive(w, "limits"), "queue_hard");
  if (isfinite(qh)) m->queue_hard = (uint64_t)qh;
  double acc = num_at(w, "cache_bytes") + num_at(w, "held_bytes") + queued + conn;
  cJSON_Delete(st);
  cJSON_Delete(ss);
  if (!p.ok || !isfinite(acc)) return;
  m->samples++;
  if (!fx->have_base) {
    fx->have_base = 1;
    fx->rss_base = p.rss_mib;
    fx->acc_base = acc;
    if (m->samples == 1) {
      m->rss_base_mib = m->rss_peak_mib = p.rss_mib;
      m->accounted_base = m->accounted_peak = acc;
    }
    return;
  }
  double growth = (p.rss_mib - fx->rss_base) - fmax(0.0, acc - fx->acc_base) / (1024.0 * 1024.0);
  if (growth > m->growth_mib || m->samples == 2) {
    m->growth_mib = growth;
    m->rss_base_mib = fx->rss_base;
    m->rss_peak_mib = p.rss_mib;
    m->accounted_base = fx->acc_base;
    m->accounted_peak = acc;
  }
}

/* --faults restart, right after step k's reply (its epoch is on the wire): SIGKILL, the same
 * command on the same port, a new control connection, and every viewer back with a WELCOME. */
static int restart_server(stress_run_t *run, ocv_conn_t **ctl, fault_ctx_t *fx, uint64_t k, stress_summary_t *sum) {
  const stress_opts_t *o = run->o;
  char why[1024];
  stress_faults_restarted(run);
  pthread_mutex_lock(&run->mu);
  run->restart_gen++;
  pthread_mutex_unlock(&run->mu);
  stress_proc_t dead;
  stress_proc_sample((long)fx->child->pid, &dead);
  double t_kill = stress_now();
  if (o->restart_drain) {
    /* SIGTERM: every viewer is told GOODBYE RECONNECT and leaves; the server exits 0 */
    int st = ocv_child_stop(fx->child, STRESS_STOP_S);
    fprintf(stderr, "overcast-stress: faults: drained the server after step %llu (exit %d in %.2f s); starting it again on %s\n",
            (unsigned long long)k, st, stress_now() - t_kill, fx->listen_addr);
    if (st != 0) {
      snprintf(sum->error, sizeof sum->error, "faults: the drained server exited with status %d, not 0", st);
      return -1;
    }
  } else {
    ocv_child_kill(fx->child);
    fprintf(stderr, "overcast-stress: faults: killed the server after step %llu; starting it again on %s\n",
            (unsigned long long)k, fx->listen_addr);
  }
  fx->argv[fx->listen] = fx->listen_addr;
  int r = -1;
  for (int attempt = 0; attempt < 50 && r < 0; attempt++) { /* the port may take a moment to be free */
    r = ocv_child_spawn(fx->argv, o->timeout, fx->child, why, sizeof why);
    if (r < 0) {
      struct timespec ts = {0, 100000000};
      nanosleep(&ts, NULL);
    }
  }
  if (r < 0) {
    snprintf(sum->error, sizeof sum->error, "faults: restarting the server: %.400s", why);
    return -1;
  }
  /* the CPU of the killed incarnation is kept: start' = new start − (dead − old start) */
  stress_proc_t born;
  stress_proc_sample((long)fx->child->pid, &born);
  if (dead.ok && born.ok && sum->server_start.ok) sum->server_start.cpu_s = born.cpu_s - (dead.cpu_s - sum->server_start.cpu_s);
  ocv_conn_close(*ctl);
  *ctl = NULL;
  cJSON *reply = NULL;
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = o->token};
  if (ocv_conn_open(ctl, run->host, run->port, &cd, NULL, o->timeout, why, sizeof why) < 0 ||
      control(*ctl, "{\"op\":\"stats\"}", o->timeout, &reply, why, sizeof why) < 0) {
    snprintf(sum->error, sizeof sum->error, "faults: after the restart: %.400s", why);
    return -1;
  }
  double e0 = world_num(reply, "epoch");
  cJSON_Delete(reply);
  pthread_mutex_lock(&run->mu);
  run->epoch0 = isfinite(e0) && e0 >= 0 ? (uint64_t)e0 : 0;
  run->step0 = k;
  for (;;) {
    int waiting = 0;
    for (int i = 0; i < run->nv; i++)
      if (!run->v[i].done && (run->v[i].gen != run->restart_gen || !run->v[i].ready)) waiting++;
    if (!waiting || g_interrupted) break;
    if (stress_now() - t_kill > o->timeout) {
      snprintf(sum->error, sizeof sum->error, "faults: %d viewer%s not back %.0f s after the restart", waiting,
               waiting == 1 ? "" : "s", o->timeout);
      pthread_mutex_unlock(&run->mu);
      return -1;
    }
    cv_wait(run, 0.1);
    pthread_mutex_unlock(&run->mu);
    ctl_tend(*ctl);
    pthread_mutex_lock(&run->mu);
  }
  pthread_mutex_unlock(&run->mu);
  double took = stress_now() - t_kill;
  sum->fault_mem.restarts++;
  if (took > sum->fault_mem.restart_s) sum->fault_mem.restart_s = took;
  fx->have_base = 0;
  return 0;
}

/* --rebalance-at S:MIB: after step S, viewer 0's budget is set by a control "budget" request; the
 * viewers then check every state against the budget in force as their sessions define it. */
static int rebalance(stress_run_t *run, ocv_conn_t *ctl, stress_summary_t *sum) {
  const stress_opts_t *o = run->o;
  char req[160], why[600];
  pthread_mutex_lock(&run->mu);
  uint32_t id = run->v[0].welcome.session;
  pthread_mutex_unlock(&run->mu);
  snprintf(req, sizeof req, "{\"op\":\"budget\",\"session\":%" PRIu32 ",\"bytes\":%ld}", id, o->rebalance_mib << 20);
  cJSON *reply = NULL;
  if (control(ctl, req, o->timeout, &reply, why, sizeof why) < 0) {
    snprintf(sum->error, sizeof sum->error, "--rebalance-at: %.400s", why);
    return -1;
  }
  cJSON_Delete(reply);
  if (o->verbose)
    fprintf(stderr, "overcast-stress: viewer 0 (session %" PRIu32 "): budget set to %ld MiB\n", id, o->rebalance_mib);
  return 0;
}

/* After the viewers stopped: viewer 0's session must have put the new budget in force. */
static void rebalance_verdict(const stress_opts_t *o, const stress_run_t *run, stress_summary_t *sum) {
  if (!o->rebalance_at || !run->nv) return;
  const stress_viewer_t *v = &run->v[0];
  uint64_t want = (uint64_t)o->rebalance_mib << 20;
  printf("rebalance: viewer 0's budget in force %.3f MiB after %" PRIu64 " BUDGET, resident max %.3f MiB, %" PRIu64
         " violations\n", (double)v->welcome.budget / 1048576.0, v->budgets, (double)v->resident_max / 1048576.0, v->violations);
  if (v->welcome.budget != want && !sum->error[0])
    snprintf(sum->error, sizeof sum->error,
             "--rebalance-at: viewer 0's budget in force is %" PRIu64 " bytes at the end, not %" PRIu64, v->welcome.budget, want);
}

/* What the server has done so far: its bricks (stats) and, when it is a local process we know, its
 * CPU in clock ticks; -1 where unknown. Equal readings 0.5 s apart: the server is quiet. CPU counts
 * because not all work makes bricks (σt columns and τ volumes of a cold start). */
typedef struct {
  double bricks, cpu_ticks;
} server_work_t;

static server_work_t server_work(ocv_conn_t *ctl, long pid, double timeout) {
  char why[256];
  cJSON *reply = NULL;
  stress_proc_t p;
  stress_proc_sample(pid, &p);
  server_work_t w = {-1, p.ok ? floor(100.0 * p.cpu_s) : -1};
  if (control(ctl, "{\"op\":\"stats\"}", timeout, &reply, why, sizeof why) == 0) w.bricks = world_num(reply, "bricks_produced");
  cJSON_Delete(reply);
  if (!isfinite(w.bricks)) w.bricks = -1;
  return w;
}

/* Steps the server one epoch at a time: the next once every live viewer has this one's state, or
 * once the server has gone quiet for 2 s after the step's reply (a viewer skipped by this step
 * gets nothing more), or after the timeout. Quiet means nothing reached a viewer, no viewer is
 * reading (decoding and verifying a state may take seconds under ASan on a loaded machine, with
 * the server idle, waiting for its ACK), and the server did no work: a cold server's first epoch (after a restart, under ASan) may work for a minute
 * before it sends a byte, and stepping on then would coalesce a viewer's epoch. */
static void run_stepped(stress_run_t *run, ocv_conn_t **ctlp, fault_ctx_t *fx, stress_summary_t *sum) {
  const stress_opts_t *o = run->o;
  char why[1024];
  int conn_faults = o->faults & ((1 << STRESS_FK_COUNT) - 1);
  for (uint64_t k = 1; k <= STRESS_MAX_STEPS && !g_interrupted; k++) {
    ocv_conn_t *ctl = *ctlp;
    double now = stress_now();
    if (o->epochs && k > (uint64_t)o->epochs) break;
    if (o->duration > 0 && now - run->t0 >= o->duration) break;
    /* misbehaving connections from step 2 on (step 1 gives the baseline), never at the last step */
    if (o->faults && k == 2) fault_sample(run, ctl, fx, sum);
    if (conn_faults && k >= 2 && (!o->epochs || k < (uint64_t)o->epochs) && (k - 2) % (uint64_t)o->fault_every == 0)
      stress_faults_round(run);
    pthread_mutex_lock(&run->mu);
    int done = all_done(run);
    if (!done) {
      run->steps_sent = k;
      run->step_at[k] = now;
    }
    pthread_mutex_unlock(&run->mu);
    if (done) break;
    cJSON *reply = NULL;
    if (control(ctl, "{\"op\":\"step\",\"epochs\":1}", o->timeout, &reply, why, sizeof why) < 0) {
      snprintf(sum->error, sizeof sum->error, "step %llu: %.400s", (unsigned long long)k, why);
      break;
    }
    cJSON_Delete(reply);
    sum->steps = k;
    if (o->rebalance_at && k == (uint64_t)o->rebalance_at && rebalance(run, ctl, sum) < 0) break;
    if ((o->faults & STRESS_FAULT_RESTART) && k == (uint64_t)o->restart_at) {
      if (restart_server(run, ctlp, fx, k, sum) < 0) break;
      continue; /* this step's epoch died with the server */
    }
    double replied = stress_now(), asked_at = 0;
    server_work_t made = {-1, -1};
    int still = 0; /* two readings of the server's work 0.5 s apart were equal */
    long pid = fx->child && fx->child->pid > 0 ? (long)fx->child->pid : o->server_pid;
    uint64_t target = run->epoch0 + (k - run->step0);
    pthread_mutex_lock(&run->mu);
    for (;;) {
      int missing = 0, busy = 0;
      double last_in = 0;
      for (int i = 0; i < run->nv; i++) {
        stress_viewer_t *v = &run->v[i];
        if (!v->done && v->have_epoch < target) missing++;
        if (v->last_input > last_in) last_in = v->last_input;
        busy |= v->busy;
      }
      if (!missing) break;
      now = stress_now();
      int silent = !busy && now - replied >= 2.0 && now - last_in >= 2.0;
      if (!silent) {
        still = 0;
        made = (server_work_t){-1, -1};
      }
      if (silent && !still && now - asked_at >= 0.5) { /* still working? then not quiet */
        pthread_mutex_unlock(&run->mu);
        server_work_t n = server_work(ctl, pid, o->timeout);
        pthread_mutex_lock(&run->mu);
        asked_at = now = stress_now();
        int known = n.bricks >= 0 || n.cpu_ticks >= 0; /* none: judge by the silence alone, as before */
        still = !known || (n.bricks == made.bricks && n.cpu_ticks == made.cpu_ticks);
        made = n;
      }
      if ((silent && still) || now - run->step_at[k] > o->timeout || g_interrupted) {
        sum->steps_incomplete++;
        if (o->verbose)
          fprintf(stderr, "overcast-stress: step %llu: %d viewer%s without its state\n", (unsigned long long)k, missing,
                  missing == 1 ? "" : "s");
        break;
      }
      cv_wait(run, 0.05);
      pthread_mutex_unlock(&run->mu);
      ctl_tend(ctl);
      pthread_mutex_lock(&run->mu);
    }
    pthread_mutex_unlock(&run->mu);
    if (o->faults && k >= 2) fault_sample(run, ctl, fx, sum);
  }
}

/* With a period: until the duration is over, or every live viewer has o->epochs states. */
static void run_period(stress_run_t *run, ocv_conn_t *ctl, double period, stress_summary_t *sum) {
  const stress_opts_t *o = run->o;
  double limit = o->duration > 0 ? o->duration : o->timeout + 3.0 * (double)o->epochs * period;
  if (o->rebalance_at) {
    snprintf(sum->error, sizeof sum->error, "--rebalance-at needs a stepped server (--epoch-period 0)");
    return;
  }
  pthread_mutex_lock(&run->mu);
  while (!g_interrupted && !all_done(run)) {
    pthread_mutex_unlock(&run->mu);
    ctl_tend(ctl);
    pthread_mutex_lock(&run->mu);
    double el = stress_now() - run->t0;
    if (o->epochs) {
      int all = 1;
      for (int i = 0; i < run->nv; i++)
        if (!run->v[i].done && run->v[i].have_states < (uint64_t)o->epochs) all = 0;
      if (all) break;
    }
    if (el >= limit) {
      if (o->duration <= 0)
        snprintf(sum->error, sizeof sum->error, "not every viewer had %ld states within %.0f s", o->epochs, limit);
      break;
    }
    cv_wait(run, 0.2);
  }
  pthread_mutex_unlock(&run->mu);
}

/* Stops and joins every viewer thread (each says GOODBYE); a second call does nothing. */
static void stop_viewers(stress_run_t *run) {
  pthread_mutex_lock(&run->mu);
  atomic_store(&run->stop, 1);
  pthread_cond_broadcast(&run->cv);
  pthread_mutex_unlock(&run->mu);
  for (int i = 0; run->v && i < run->nv; i++)
    if (run->v[i].started) {
      pthread_join(run->v[i].thread, NULL);
      run->v[i].started = 0;
    }
}


static uint64_t viewer_budget(const stress_opts_t *o, int i) {
  if (o->sweep) {
    long mib = o->sweep_budgets_mib[i / o->nsweep_depths];
    return mib ? (uint64_t)mib << 20 : 1; /* 0: one byte, the server grants its smallest */
  }
  return (uint64_t)o->budgets_mib[i % o->nbudgets] << 20;
}

static int viewer_depth(const stress_opts_t *o, int i) {
  return (int)(o->sweep ? o->sweep_depths[i % o->nsweep_depths] : o->depths[i % o->ndepths]);
}

/* The command line of a spawned server (period < 0: the scene's). */
typedef struct {
  char period[32], threads[32], total[32], maxv[32], maxb[32], peraddr[32], drain[32];
  char *argv[32 + 32 + 1]; /* ours, then up to 32 --server-arg, then NULL */
  int listen;              /* argv[listen] is the listen address (a restart rewrites it) */
} server_argv_t;

static void server_argv(const stress_opts_t *o, const char *exe, double period, server_argv_t *sa) {
  long total_mib = 0, max_mib = o->faults ? (long)o->fault_budget_mib : 1;
  for (int i = 0; i < o->viewers; i++) {
    long mib = (long)((viewer_budget(o, i) + (1u << 20) - 1) >> 20);
    total_mib += mib;
    if (mib > max_mib) max_mib = mib;
  }
  if (o->ramp) total_mib = max_mib * (long)o->viewers; /* each budget's ramp has all its viewers at it */
  char **argv = sa->argv;
  int n = 0;
  argv[n++] = (char *)exe;
  argv[n++] = "--listen";
  sa->listen = n;
  argv[n++] = "127.0.0.1:0";
  if (o->scene) {
    argv[n++] = "--scene";
    argv[n++] = (char *)o->scene;
  }
  if (period >= 0) {
    snprintf(sa->period, sizeof sa->period, "%.17g", period);
    argv[n++] = "--epoch-period";
    argv[n++] = sa->period;
  }
  if (o->server_threads) {
    snprintf(sa->threads, sizeof sa->threads, "%ld", o->server_threads);
    argv[n++] = "--threads";
    argv[n++] = sa->threads;
  }
  if (o->token) {
    argv[n++] = "--token";
    argv[n++] = (char *)o->token;
  }
  /* room for every viewer and its whole budget: the server's defaults are 64 viewers, 4 GiB */
  if (total_mib > (1L << 24)) total_mib = 1L << 24; /* the server's largest --total-budget */
  snprintf(sa->total, sizeof sa->total, "%ld", total_mib > 4096 ? total_mib : 4096);
  snprintf(sa->maxv, sizeof sa->maxv, "%d", o->viewers > 64 ? o->viewers : 64);
  argv[n++] = "--total-budget";
  argv[n++] = sa->total;
  argv[n++] = "--max-viewers";
  argv[n++] = sa->maxv;
  /* the server grants one viewer at most a fair share of the total by default: ask for the
   * largest budget we request (the misbehaving viewers' included), so every budget is granted */
  snprintf(sa->maxb, sizeof sa->maxb, "%ld", max_mib);
  argv[n++] = "--max-budget";
  argv[n++] = sa->maxb;
  /* the per-address limits must let all of ours through from one address (two with
   * --source-address): the viewers, the control connection (and a restart's), the fault
   * connections (up to STRESS_FAULT_MAX_CONNS at once), and the connect bursts of the ramp's
   * phases and of a restart, which the handshake rate (a bucket of --max-per-address) allows */
  long per_addr = (long)o->viewers + 64 + (o->faults ? STRESS_FAULT_MAX_CONNS : 0);
  snprintf(sa->peraddr, sizeof sa->peraddr, "%ld", per_addr);
  argv[n++] = "--max-per-address";
  argv[n++] = sa->peraddr;
  argv[n++] = "--handshake-rate";
  argv[n++] = "1000";
  /* a drain (our SIGTERM) ends within STRESS_DRAIN_S, inside ocv_child_stop()'s wait */
  snprintf(sa->drain, sizeof sa->drain, "%g", STRESS_DRAIN_S);
  argv[n++] = "--drain-timeout";
  argv[n++] = sa->drain;
  if (!o->verbose) argv[n++] = "-q";
  for (int i = 0; i < o->nserver_args; i++) argv[n++] = o->server_args[i];
  argv[n] = NULL;
}

/* Starts run->nv viewer threads (run->v zeroed) and waits until each has its WELCOME or gave up. */
static void start_viewers(stress_run_t *run, ocv_conn_t *ctl) {
  const stress_opts_t *o = run->o;
  for (int i = 0; i < run->nv; i++) {
    stress_viewer_t *v = &run->v[i];
    v->index = run->index0 + i;
    v->run = run;
    v->path = (stress_path_kind_t)o->paths[i % o->npaths];
    v->budget = viewer_budget(o, i);
    v->max_depth = viewer_depth(o, i);
    if (pthread_create(&v->thread, NULL, stress_viewer_main, v) != 0) {
      pthread_mutex_lock(&run->mu);
      v->done = 1;
      snprintf(v->error, sizeof v->error, "viewer %d: cannot start a thread", i);
      v->failed = 1;
      pthread_mutex_unlock(&run->mu);
      continue;
    }
    v->started = 1;
  }
  pthread_mutex_lock(&run->mu);
  for (;;) {
    int waiting = 0;
    for (int i = 0; i < run->nv; i++)
      if (!run->v[i].ready && !run->v[i].done) waiting++;
    if (!waiting || g_interrupted) break;
    cv_wait(run, 0.1); /* each viewer's own connect and handshake are bounded by --timeout */
    pthread_mutex_unlock(&run->mu);
    ctl_tend(ctl);
    pthread_mutex_lock(&run->mu);
  }
  pthread_mutex_unlock(&run->mu);
}

/* Tends the control connection until `until` (or every viewer is done, or an interrupt). */
static void idle_until(stress_run_t *run, ocv_conn_t *ctl, double until) {
  pthread_mutex_lock(&run->mu);
  while (!g_interrupted && !all_done(run) && stress_now() < until) {
    cv_wait(run, 0.2);
    pthread_mutex_unlock(&run->mu);
    ctl_tend(ctl);
    pthread_mutex_lock(&run->mu);
  }
  pthread_mutex_unlock(&run->mu);
}

/* The stepped reference for --ramp: time to full detail on the teleport path at one budget, on a
 * server of its own stepped as fast as it makes epochs (period 0), one viewer flying the path of
 * viewer `index` (its seed) with P path seconds per epoch, for o->ref_teleports teleports after the
 * first (the first builds a tree from nothing, which no measured teleport of the ramp does). */
static void stepped_reference(const stress_opts_t *o, const char *exe, long budget_mib, int index, double period, stress_ref_t *out) {
  memset(out, 0, sizeof *out);
  out->budget_mib = budget_mib;
  out->index = index;
  out->detail_p50 = out->detail_p99 = out->detail_epochs_p50 = NAN;
  static stress_opts_t ro;
  ro = *o;
  ro.ramp = 0;
  ro.viewers = 1;
  ro.npaths = 1;
  ro.paths[0] = STRESS_TELEPORT;
  ro.nbudgets = 1;
  ro.budgets_mib[0] = budget_mib;
  ro.epoch_period = 0;
  ro.step_seconds = period;
  ro.verify_content = 0;
  ro.duration = 0;
  /* the first place and K more, each flown for teleport_every path seconds: the camera after step k
   * is at path time k·P, so the last step is the one before the next jump */
  ro.epochs = (long)ceil((double)(o->ref_teleports + 1) * o->teleport_every / period - 1e-9) - 1;
  if (ro.epochs < 2) ro.epochs = 2;
  server_argv_t sa;
  server_argv(&ro, exe, 0, &sa);
  ocv_child_t child = {.pid = -1, .out_fd = -1};
  char why[1024];
  double t0 = stress_now();
  if (ocv_child_spawn(sa.argv, o->timeout, &child, why, sizeof why) < 0) {
    snprintf(out->error, sizeof out->error, "stepped reference: %.150s", why);
    return;
  }
  stress_run_t run;
  memset(&run, 0, sizeof run);
  pthread_mutex_init(&run.mu, NULL);
  pthread_cond_init(&run.cv, NULL);
  run.o = &ro;
  snprintf(run.host, sizeof run.host, "%s", child.host);
  run.port = child.port;
  run.index0 = index;
  ocv_conn_t *ctl = NULL;
  cJSON *reply = NULL;
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = o->token};
  run.step_at = calloc((size_t)ro.epochs + 2, sizeof *run.step_at);
  run.v = calloc(1, sizeof *run.v);
  if (!run.step_at || !run.v) {
    snprintf(out->error, sizeof out->error, "stepped reference: out of memory");
  } else if (ocv_conn_open(&ctl, run.host, run.port, &cd, NULL, o->timeout, why, sizeof why) < 0 ||
             control(ctl, "{\"op\":\"stats\"}", o->timeout, &reply, why, sizeof why) < 0) {
    snprintf(out->error, sizeof out->error, "stepped reference: %.150s", why);
  } else {
    double e0 = world_num(reply, "epoch");
    run.epoch0 = isfinite(e0) && e0 >= 0 ? (uint64_t)e0 : 0;
    run.nv = 1;
    start_viewers(&run, ctl);
    run.t0 = stress_now();
    fault_ctx_t fx = {.child = &child};
    stress_summary_t sum;
    memset(&sum, 0, sizeof sum);
    run_stepped(&run, &ctl, &fx, &sum);
    stop_viewers(&run);
    stress_viewer_t *v = &run.v[0];
    size_t from = v->detail_first ? 1 : 0; /* the first teleport built from nothing */
    if (v->detail.n > from) {
      out->detail_p50 = stress_quantile(v->detail.v + from, v->detail.n - from, 0.5);
      out->detail_p99 = stress_quantile(v->detail.v + from, v->detail.n - from, 0.99);
    }
    if (v->detail_epochs.n > from)
      out->detail_epochs_p50 = stress_quantile(v->detail_epochs.v + from, v->detail_epochs.n - from, 0.5);
    out->teleports = v->teleports > 0 ? v->teleports - 1 : 0;
    out->settled = v->detail.n - from;
    if (v->failed) snprintf(out->error, sizeof out->error, "stepped reference: %.150s", v->error);
    else if (sum.error[0]) snprintf(out->error, sizeof out->error, "stepped reference: %.150s", sum.error);
    stress_viewer_free(v);
  }
  cJSON_Delete(reply);
  ocv_conn_close(ctl);
  ocv_child_stop(&child, STRESS_STOP_S);
  free(run.v);
  free(run.step_at);
  pthread_cond_destroy(&run.cv);
  pthread_mutex_destroy(&run.mu);
  out->seconds = stress_now() - t0;
}

/* *w becomes x when x is finite and larger (NAN: nothing yet). */
static void keep_worst(double *w, double x) {
  if (isfinite(x) && !(x <= *w)) *w = x;
}

/* The stepped figure the ramp's rule compares time to full detail with (stress.h, the rule). */
static double detail_reference(const stress_opts_t *o, const stress_ref_t *ref, double period) {
  if (!ref) return NAN;
  double on_clock = ref->detail_epochs_p50 * period;
  if (o->detail_ref == STRESS_DETAIL_REF_SECONDS) return ref->detail_p50;
  if (o->detail_ref == STRESS_DETAIL_REF_EPOCHS) return on_clock;
  return ref->detail_p50 > on_clock || isnan(on_clock) ? ref->detail_p50 : on_clock;
}

/* A phase before anything is measured: every figure NAN (ages -1). */
static void ramp_phase_init(stress_ramp_phase_t *ph, int n, long budget_mib, double refv) {
  memset(ph, 0, sizeof *ph);
  ph->n = n;
  ph->budget_mib = budget_mib;
  ph->itv_p50 = ph->itv_p99 = ph->worst_median = ph->cpu_pct = ph->rss_mib = ph->hwm_mib = NAN;
  ph->mbps_p50 = ph->mbps_p99 = NAN;
  ph->late_p50 = ph->late_p99 = ph->late_max = ph->late_worst_p99 = ph->coalesced_frac = ph->coalesced_worst = NAN;
  ph->detail_p50 = ph->detail_p99 = ph->detail_worst_ratio = ph->detail_lower_s = NAN;
  ph->detail_ref = refv;
  ph->age_p99 = ph->age_worst_p99 = ph->server_age_p99 = -1;
}

/* The phase's viewers (run->v, run->nv zeroed): started, warmed up, measured, stopped, and the
 * verifier's backlog drained; the server's CPU and RSS over the measured window. */
static void ramp_measure(stress_run_t *run, ocv_conn_t *ctl, long pid, stress_ramp_phase_t *ph) {
  const stress_opts_t *o = run->o;
  atomic_store(&run->stop, 0);
  pthread_mutex_lock(&run->mu);
  run->measure_from = INFINITY; /* a ramp, not measuring yet (the warm-up starts when all are in) */
  pthread_mutex_unlock(&run->mu);
  start_viewers(run, ctl);
  double t = stress_now();
  run->t0 = t;
  pthread_mutex_lock(&run->mu);
  run->measure_from = t + o->ramp_warmup;
  pthread_mutex_unlock(&run->mu);
  idle_until(run, ctl, t + o->ramp_warmup);
  stress_proc_t p0, p1;
  stress_proc_sample(pid, &p0);
  double m0 = stress_now();
  idle_until(run, ctl, m0 + o->ramp_seconds);
  stress_proc_sample(pid, &p1);
  ph->seconds = stress_now() - m0;
  stop_viewers(run);
  /* the verifier's backlog, in slices, keeping the control connection alive */
  for (double until = stress_now() + o->verify_drain_s;;) {
    double left_s = until - stress_now();
    ph->verify_left = stress_verify_drain(run->verify, left_s < 1 ? left_s : 1);
    ctl_tend(ctl);
    if (!ph->verify_left || left_s <= 0 || g_interrupted) break;
  }
  if (p0.ok && p1.ok && ph->seconds > 0) {
    ph->cpu_pct = 100.0 * (p1.cpu_s - p0.cpu_s) / ph->seconds;
    ph->rss_mib = p1.rss_mib;
    ph->hwm_mib = p1.hwm_mib;
  }
}

/* One viewer's figures over the measured window, as the rule judges them. */
typedef struct {
  double late99, coalesced, median, detail50, ratio;
  int age99;
} ramp_viewer_t;

/* Why viewer v breaks the rule (stress.h), in why; "" when it keeps it. */
static void ramp_rule(const stress_viewer_t *v, const ramp_viewer_t *f, double refv, double period, char *why, size_t cap) {
  double limit = refv > 0 ? STRESS_DETAIL_FACTOR * refv : NAN;
  why[0] = 0;
  if (f->late99 > STRESS_LATE_P99)
    snprintf(why, cap, "viewer %d: lateness p99 %.0f ms > %.0f ms", v->index, 1e3 * f->late99, 1e3 * STRESS_LATE_P99);
  else if (f->coalesced > STRESS_COALESCED_MAX)
    snprintf(why, cap, "viewer %d: %.1f %% of ticks coalesced > %.0f %%", v->index, 100.0 * f->coalesced,
             100.0 * STRESS_COALESCED_MAX);
  else if (f->age99 > STRESS_AGE_ALLOWED && f->age99 > STRESS_AGE_MAX)
    snprintf(why, cap, "viewer %d: verified content age p99 beyond every stamp tried (> %d steps)", v->index, STRESS_AGE_MAX);
  else if (f->age99 > STRESS_AGE_ALLOWED)
    snprintf(why, cap, "viewer %d: verified content age p99 %d > %d steps", v->index, f->age99, STRESS_AGE_ALLOWED);
  else if (isfinite(f->ratio) && f->ratio > STRESS_DETAIL_FACTOR)
    snprintf(why, cap, "viewer %d: time to full detail %.2f s > %.2f x stepped %.2f s", v->index, f->detail50,
             STRESS_DETAIL_FACTOR, refv);
  else if (isfinite(limit) && (v->m_unreached || v->m_open_s > limit))
    snprintf(why, cap, "viewer %d: a teleport did not reach full detail within %.2f x stepped %.2f s", v->index,
             STRESS_DETAIL_FACTOR, refv);
  else if (isfinite(f->median) && f->median > STRESS_RAMP_INTERVAL * period)
    snprintf(why, cap, "viewer %d: median interval %.2f s > %.1f x %g s", v->index, f->median, STRESS_RAMP_INTERVAL, period);
}

/* Viewer v's counts summed into the phase; its own figures into *f. */
static void ramp_add_viewer(stress_ramp_phase_t *ph, const stress_viewer_t *v, double teleport_every, ramp_viewer_t *f) {
  ph->states += v->m_states;
  ph->skipped += v->m_skipped;
  ph->violations += v->violations;
  ph->checksum += v->checksum_failures;
  ph->protocol += v->protocol_errors;
  ph->mismatch += v->resident_mismatch;
  ph->failed += v->failed != 0;
  ph->due += stress_ticks_due(&v->m_ticks);
  ph->coalesced += v->m_ticks.coalesced;
  ph->coalesced_server += v->last_stats.coalesced;
  ph->teleports += v->m_teleports;
  ph->unreached += v->m_unreached;
  stress_age_merge(&ph->age, &v->m_age);
  if (v->m_unreached && !(ph->detail_lower_s >= teleport_every)) ph->detail_lower_s = teleport_every;
  if (v->m_open_s > 0 && !(ph->detail_lower_s >= v->m_open_s)) ph->detail_lower_s = v->m_open_s;
  for (int l = 0; l < OCP_STATS_LEVELS; l++)
    if (v->stats_msgs && v->last_stats.age_p99[l] != 255 && v->last_stats.age_p99[l] > ph->server_age_p99)
      ph->server_age_p99 = v->last_stats.age_p99[l];
  if (v->failed && !ph->why[0]) snprintf(ph->why, sizeof ph->why, "%.150s", v->error);
  /* quantiles sort in place: the viewer's own order does not matter */
  f->median = stress_quantile(v->m_interval.v, v->m_interval.n, 0.5);
  keep_worst(&ph->worst_median, f->median);
  f->late99 = stress_quantile(v->m_ticks.lateness.v, v->m_ticks.lateness.n, 0.99);
  f->coalesced = stress_ticks_coalesced_frac(&v->m_ticks);
  f->age99 = stress_age_quantile(&v->m_age, -1, 0.99);
  if (f->age99 > ph->age_worst_p99) ph->age_worst_p99 = f->age99;
  f->detail50 = stress_quantile(v->m_detail.v, v->m_detail.n, 0.5);
  f->ratio = isfinite(f->detail50) && ph->detail_ref > 0 ? f->detail50 / ph->detail_ref : NAN;
  keep_worst(&ph->late_worst_p99, f->late99);
  keep_worst(&ph->coalesced_worst, f->coalesced);
  keep_worst(&ph->detail_worst_ratio, f->ratio);
}

/* The phase's figures from its viewers, and the verdict (stress.h, the rule). */
static void ramp_judge(const stress_run_t *run, double period, stress_ramp_phase_t *ph) {
  const stress_opts_t *o = run->o;
  int short_viewer = -1;
  char vwhy[200] = "";
  double *rates = malloc(((size_t)run->nv + 1) * sizeof *rates);
  size_t nr = 0;
  for (int i = 0; i < run->nv; i++) {
    const stress_viewer_t *v = &run->v[i];
    ramp_viewer_t f;
    ramp_add_viewer(ph, v, o->teleport_every, &f);
    if (!isfinite(f.median) && short_viewer < 0) short_viewer = v->index;
    double span = v->t_end - v->m_t0;
    if (rates && v->m_states && span > 0) rates[nr++] = (double)(v->session.bytes_in - v->m_bytes0) / span / 1e6;
    if (!vwhy[0]) ramp_rule(v, &f, ph->detail_ref, period, vwhy, sizeof vwhy);
  }
  stress_q_t itv = stress_pool(run, offsetof(stress_viewer_t, m_interval), -1);
  stress_q_t late = stress_pool(run, offsetof(stress_viewer_t, m_ticks.lateness), -1);
  stress_q_t det = stress_pool(run, offsetof(stress_viewer_t, m_detail), -1);
  ph->itv_p50 = itv.p50, ph->itv_p99 = itv.p99;
  ph->late_p50 = late.p50, ph->late_p99 = late.p99, ph->late_max = late.max;
  ph->detail_p50 = det.p50, ph->detail_p99 = det.p99, ph->detail_n = det.n;
  if (nr) {
    ph->mbps_p50 = stress_quantile(rates, nr, 0.5);
    ph->mbps_p99 = stress_quantile(rates, nr, 0.99);
  }
  free(rates);
  ph->coalesced_frac = ph->due ? (double)ph->coalesced / (double)ph->due : NAN;
  ph->age_p99 = stress_age_quantile(&ph->age, -1, 0.99);
  ph->age_mismatch = stress_age_mismatches(&ph->age, -1);
  ph->skipped_frac = ph->states + ph->skipped ? (double)ph->skipped / (double)(ph->states + ph->skipped) : NAN;
  if (ph->failed || ph->violations || ph->checksum || ph->protocol || ph->mismatch || ph->age_mismatch) {
    if (!ph->why[0] && ph->age_mismatch)
      snprintf(ph->why, sizeof ph->why, "CONTENT MISMATCH: %" PRIu64 " verified bricks matched no time step s .. s-%d",
               ph->age_mismatch, STRESS_AGE_MAX);
    if (!ph->why[0]) snprintf(ph->why, sizeof ph->why, "a check failed");
  } else if (short_viewer >= 0) {
    snprintf(ph->why, sizeof ph->why, "viewer %d: fewer than 2 states in the measured window", short_viewer);
  } else if (vwhy[0]) {
    snprintf(ph->why, sizeof ph->why, "%s", vwhy);
  } else {
    ph->sustained = 1;
  }
}

/* One ramp phase of n viewers, all at run->o's one budget, on the running server: warm-up,
 * measured window, stop, the verifier drained, figures, and the sustained rule (stress.h). */
static void ramp_phase(stress_run_t *run, ocv_conn_t *ctl, long pid, double period, int n, const stress_ref_t *ref,
                       stress_ramp_phase_t *ph) {
  ramp_phase_init(ph, n, run->o->budgets_mib[0], detail_reference(run->o, ref, period));
  run->v = calloc((size_t)n, sizeof *run->v);
  if (!run->v) {
    snprintf(ph->why, sizeof ph->why, "out of memory");
    ph->failed = 1;
    return;
  }
  run->nv = n;
  ramp_measure(run, ctl, pid, ph);
  ramp_judge(run, period, ph);
  for (int i = 0; i < run->nv; i++) stress_viewer_free(&run->v[i]);
  free(run->v);
  run->v = NULL;
  run->nv = 0;
}

/* The coordinator's state for one invocation: the server, the control connection, the run. */
typedef struct {
  stress_opts_t *o;
  stress_summary_t sum;
  ocv_child_t child;
  char exe[4096];   /* kept: a restart (and the ramp's stepped reference) runs the same server */
  server_argv_t sa; /* kept: a restart runs the same command */
  fault_ctx_t fx;
  stress_run_t run;
  ocv_conn_t *ctl;
  long pid;         /* the server's, for /proc (0: none) */
  double cpu0, wall0, period;
} coord_t;

static void on_signals(void) {
  signal(SIGPIPE, SIG_IGN);
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
}

/* --spawn: the server beside this program (or --server), started on 127.0.0.1:0.
 * @return OC_EXIT_OK, or an exit status after a message. */
static int spawn_server(coord_t *c) {
  stress_opts_t *o = c->o;
  char why[1024], dir[4000];
  if (o->server_path) {
    snprintf(c->exe, sizeof c->exe, "%s", o->server_path);
  } else {
    if (ocv_exe_dir(dir, sizeof dir) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "cannot read /proc/self/exe");
    snprintf(c->exe, sizeof c->exe, "%s/overcast-server", dir);
  }
  if (access(c->exe, X_OK) != 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s: not an executable (give --server PATH, or --connect)", c->exe);
  server_argv(o, c->exe, o->epoch_period, &c->sa);
  c->fx.listen = c->sa.listen;
  if (ocv_child_spawn(c->sa.argv, o->timeout, &c->child, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  snprintf(o->host, sizeof o->host, "%s", c->child.host);
  o->port = c->child.port;
  c->fx.argv = c->sa.argv;
  snprintf(c->fx.listen_addr, sizeof c->fx.listen_addr, "%s:%d", c->child.host, c->child.port);
  return OC_EXIT_OK;
}

/* --verify-content: the verifier's world, the scene the server runs. @return 0 or -1 (why). */
static int start_verifier(coord_t *c, char *why, size_t cap) {
  const stress_opts_t *o = c->o;
  oc_scene_t *sc = calloc(1, sizeof *sc);
  int r = sc ? 0 : OC_ENOMEM;
  if (sc && o->scene) r = oc_scene_load(sc, o->scene, why, cap);
  else if (sc) oc_scene_default(sc);
  if (r == 0) r = stress_verify_start(&c->run.verify, sc, (size_t)o->verify_queue, why, cap);
  else if (r == OC_ENOMEM) snprintf(why, cap, "out of memory");
  if (sc) oc_scene_free(sc);
  free(sc);
  return r < 0 ? -1 : 0;
}

/* The control connection (steps and statistics), the server's period and epoch, --time-scale, the
 * verifier, and the run's arrays. @return OC_EXIT_OK, or an exit status after a message. */
static int open_control(coord_t *c) {
  stress_opts_t *o = c->o;
  stress_run_t *run = &c->run;
  char why[1024];
  cJSON *reply = NULL;
  ocp_viewer_desc_t cd = {.role = OCP_ROLE_CONTROL, .token = o->token};
  if (ocv_conn_open(&c->ctl, o->host, o->port, &cd, NULL, o->timeout, why, sizeof why) < 0 ||
      control(c->ctl, "{\"op\":\"stats\"}", o->timeout, &reply, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  double period = world_num(reply, "epoch_period"), e0 = world_num(reply, "epoch");
  cJSON_Delete(reply);
  c->period = c->sum.epoch_period = period;
  c->sum.stepped = period == 0;
  run->epoch0 = isfinite(e0) && e0 >= 0 ? (uint64_t)e0 : 0;
  run->world_dt = period; /* a world second per second, until two states say otherwise */
  if (o->time_scale >= 0) { /* before any viewer: every state runs at this scale */
    char req[96];
    snprintf(req, sizeof req, "{\"op\":\"time\",\"scale\":%.17g}", o->time_scale);
    if (control(c->ctl, req, o->timeout, &reply, why, sizeof why) < 0)
      return oc_cli_fail(prog, OC_EXIT_RUNTIME, "--time-scale: %s", why);
    cJSON_Delete(reply);
    run->world_dt = period * o->time_scale;
  }
  if (o->verify_content > 0 && start_verifier(c, why, sizeof why) < 0) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  size_t nsteps = (size_t)(o->epochs && !(o->duration > 0) ? o->epochs : STRESS_MAX_STEPS) + 2;
  run->step_at = calloc(nsteps, sizeof *run->step_at);
  run->v = calloc((size_t)o->viewers, sizeof *run->v);
  if (!run->step_at || !run->v) return oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory");
  return OC_EXIT_OK;
}

/* The measured run: the viewers connect, the epochs are stepped or come by the clock, the viewers
 * stop (their bytes/s end then), then the server's CPU and RSS are read, then its statistics (a
 * request waits for a step in progress, which must not count). */
static void run_measured(coord_t *c) {
  const stress_opts_t *o = c->o;
  stress_run_t *run = &c->run;
  stress_summary_t *sum = &c->sum;
  char why[1024];
  cJSON *reply = NULL;
  run->nv = o->viewers;
  start_viewers(run, c->ctl);
  run->t0 = stress_now();
  if (sum->stepped) run_stepped(run, &c->ctl, &c->fx, sum);
  else run_period(run, c->ctl, c->period, sum);
  if (g_interrupted && !sum->error[0]) snprintf(sum->error, sizeof sum->error, "interrupted");
  sum->wall_s = stress_now() - run->t0;
  stop_viewers(run);
  rebalance_verdict(o, run, sum);
  if (o->faults) { /* the last garbage must still be answered; then the memory once more */
    stress_faults_stop(run, &sum->fault_conns);
    if (c->ctl) fault_sample(run, c->ctl, &c->fx, sum);
  }
  if (o->spawn) c->pid = (long)c->child.pid; /* a restart made a new one */
  stress_proc_sample(c->pid, &sum->server_end);
  sum->tool_cpu_s = stress_self_cpu() - c->cpu0;
  sum->cpu_span_s = stress_now() - c->wall0;
  if (c->ctl && control(c->ctl, "{\"op\":\"stats\"}", o->timeout, &reply, why, sizeof why) == 0) {
    sum->cache_hit_rate = world_num(reply, "cache_hit_rate");
    sum->bricks_produced = world_num(reply, "bricks_produced");
    sum->brick_requests = world_num(reply, "brick_requests");
    sum->late_ticks = world_num(reply, "late_ticks");
    sum->cache_bytes = world_num(reply, "cache_bytes");
    cJSON_Delete(reply);
  } else if (!sum->error[0]) {
    snprintf(sum->error, sizeof sum->error, "final stats: %.400s", why);
  }
  /* what the verifier has left is verified now, after the measurements (the control connection
   * is done with) */
  sum->verify_left = stress_verify_drain(run->verify, o->verify_drain_s);
  if (run->verify) stress_verify_work(run->verify, &sum->verify_s, &sum->verify_reproduced);
}

/* The end, however the run went: everything stopped, the last figures, the report (when rc is
 * OC_EXIT_OK), everything freed. @return the exit status. */
static int finish(coord_t *c, int rc) {
  const stress_opts_t *o = c->o;
  stress_run_t *run = &c->run;
  stress_summary_t *sum = &c->sum;
  stop_viewers(run);
  stress_faults_stop(run, &sum->fault_conns);
  if (!sum->server_end.ok) {
    stress_proc_sample(c->pid, &sum->server_end);
    sum->tool_cpu_s = stress_self_cpu() - c->cpu0;
    sum->cpu_span_s = stress_now() - c->wall0;
  }
  if (sum->server_start.ok && sum->server_end.ok) sum->server_cpu_s = sum->server_end.cpu_s - sum->server_start.cpu_s;
  stress_proc_sample((long)getpid(), &sum->tool);
  if (sum->wall_s <= 0) sum->wall_s = stress_now() - c->wall0;
  for (int i = 0; run->v && i < run->nv; i++)
    if (run->v[i].have_welcome) {
      snprintf(sum->scene, sizeof sum->scene, "%s", run->v[i].welcome.name);
      sum->kept_states = run->v[i].welcome.kept_states;
      break;
    }
  ocv_conn_close(c->ctl);
  if (o->spawn && c->child.pid > 0) {
    sum->server_exit = ocv_child_stop(&c->child, STRESS_STOP_S);
    if (sum->server_exit != 0 && rc == OC_EXIT_OK && !sum->error[0])
      snprintf(sum->error, sizeof sum->error, "overcast-server exited with status %d", sum->server_exit);
  }
  if (rc == OC_EXIT_OK) rc = stress_report(o, run, sum) == 1 ? OC_EXIT_OK : OC_EXIT_RUNTIME;
  stress_verify_stop(run->verify); /* after the report: the viewers' ages are counted by it */
  for (int i = 0; run->v && i < run->nv; i++) stress_viewer_free(&run->v[i]);
  free(run->v);
  free(run->step_at);
  pthread_cond_destroy(&run->cv);
  pthread_mutex_destroy(&run->mu);
  return rc;
}

/* One budget's ramp (run->o has that one budget): its stepped reference, then phases of
 * --ramp-from, ×2, .. viewers until one is not sustained (--ramp-all: to --ramp-max). */
static void ramp_budget(coord_t *c, int b, int tele, stress_ramp_phase_t *ph, int maxph, int *nph, stress_ref_t *refs,
                        int *nrefs, int *largest) {
  const stress_opts_t *o = c->o;
  long mib = o->budgets_mib[b];
  const stress_ref_t *ref = NULL;
  if (o->reference && tele >= 0) {
    fprintf(stderr, "overcast-stress: ramp: %ld MiB: time to full detail on a stepped server (reference)\n", mib);
    stepped_reference(c->run.o, c->exe, mib, o->share_paths ? 0 : tele, c->period, &refs[*nrefs]);
    ref = &refs[(*nrefs)++];
    if (ref->error[0])
      fprintf(stderr, "overcast-stress: ramp: %s\n", ref->error);
    else
      fprintf(stderr, "overcast-stress: ramp: %ld MiB: stepped: full detail p50 %.2f s (%" PRIu64 " of %" PRIu64 " teleports)\n",
              mib, ref->detail_p50, ref->settled, ref->teleports);
    if (!(ref->detail_p50 > 0)) ref = NULL;
  }
  int stopped = 0; /* a phase was not sustained: larger N are measured with --ramp-all only */
  for (long n = o->ramp_from; n <= o->ramp_max && *nph < maxph && !g_interrupted; n *= 2) {
    ramp_phase(&c->run, c->ctl, c->pid, c->period, (int)n, ref, &ph[*nph]);
    const stress_ramp_phase_t *p = &ph[(*nph)++];
    fprintf(stderr, "overcast-stress: ramp: %ld MiB, %d viewer%s: %s%s\n", p->budget_mib, p->n, p->n == 1 ? "" : "s",
            p->sustained ? "sustained" : "not sustained: ", p->sustained ? "" : p->why);
    if (!p->sustained) stopped = 1;
    if (!stopped) largest[b] = p->n;
    if (stopped && !o->ramp_all) break;
  }
}

/* --ramp (c->period > 0): every budget's phases on the spawned server, then its report; the run
 * freed. @return the exit status. */
static int run_ramp(coord_t *c) {
  stress_opts_t *o = c->o;
  stress_summary_t *sum = &c->sum;
  free(c->run.v); /* each phase has its own */
  c->run.v = NULL;
  int maxph = 64 * o->nbudgets, nph = 0, nrefs = 0, largest[64] = {0};
  stress_ramp_phase_t *ph = calloc((size_t)maxph, sizeof *ph);
  static stress_ref_t refs[64];
  if (!ph) return finish(c, oc_cli_fail(prog, OC_EXIT_RUNTIME, "out of memory"));
  /* the viewer whose path the stepped reference flies: the first on the teleport path */
  int tele = -1;
  for (int i = 0; i < o->npaths && tele < 0; i++)
    if (o->paths[i] == STRESS_TELEPORT) tele = i;
  static stress_opts_t ob; /* one budget's ramp: every viewer at it */
  for (int b = 0; b < o->nbudgets && !g_interrupted; b++) {
    ob = *o;
    ob.nbudgets = 1;
    ob.budgets_mib[0] = o->budgets_mib[b];
    c->run.o = &ob;
    ramp_budget(c, b, tele, ph, maxph, &nph, refs, &nrefs, largest);
  }
  c->run.o = o;
  if (g_interrupted) snprintf(sum->error, sizeof sum->error, "interrupted");
  sum->wall_s = stress_now() - c->wall0;
  ocv_conn_close(c->ctl);
  c->ctl = NULL;
  sum->server_exit = ocv_child_stop(&c->child, STRESS_STOP_S);
  c->child.pid = -1;
  if (sum->server_exit != 0 && !sum->error[0])
    snprintf(sum->error, sizeof sum->error, "overcast-server exited with status %d", sum->server_exit);
  stress_proc_sample((long)getpid(), &sum->tool);
  int pass = stress_ramp_report(o, o->scene ? o->scene : "planet (built in)", c->period, ph, nph, largest, refs, nrefs, sum);
  stress_verify_stop(c->run.verify);
  free(ph);
  free(c->run.step_at);
  pthread_cond_destroy(&c->run.cv);
  pthread_mutex_destroy(&c->run.mu);
  return pass == 1 ? OC_EXIT_OK : OC_EXIT_RUNTIME;
}

/* --faults: the server's limits, and the thread of misbehaving connections.
 * @return OC_EXIT_OK, or an exit status after a message. */
static int start_faults(coord_t *c) {
  const stress_opts_t *o = c->o;
  char why[1024];
  cJSON *reply = NULL;
  if (!c->sum.stepped)
    return oc_cli_fail(prog, OC_EXIT_USAGE, "--faults needs a stepped server: %s:%d has a period of %g s", o->host, o->port,
                       c->period);
  if (control(c->ctl, "{\"op\":\"stats\"}", o->timeout, &reply, why, sizeof why) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "%s", why);
  const cJSON *lim = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(reply, "world"), "limits");
  double hs = num_at(lim, "handshake_s"), ss = num_at(lim, "stall_s");
  cJSON_Delete(reply);
  if (stress_faults_start(&c->run, isfinite(hs) ? hs : 10.0, isfinite(ss) ? ss : 0.0) < 0)
    return oc_cli_fail(prog, OC_EXIT_RUNTIME, "cannot start the faults thread");
  return OC_EXIT_OK;
}

int main(int argc, char **argv) {
  static stress_opts_t o;
  static coord_t c = {.child = {.pid = -1, .out_fd = -1}};
  int rc = stress_opts_parse(argc, argv, &o);
  if (rc) return rc > 0 ? OC_EXIT_OK : OC_EXIT_USAGE;
  on_signals();
  oc_log_set_level(o.verbose ? OC_LOG_INFO : OC_LOG_WARN);
  c.o = &o;
  c.sum.server_exit = -1;
  c.sum.server_cpu_s = c.sum.cache_hit_rate = NAN;
  c.sum.bricks_produced = c.sum.brick_requests = c.sum.late_ticks = c.sum.cache_bytes = NAN;
  c.sum.spawned = o.spawn;
  if (o.spawn && (rc = spawn_server(&c)) != OC_EXIT_OK) return rc;
  c.fx.child = &c.child;
  c.pid = o.spawn ? (long)c.child.pid : o.server_pid;
  stress_proc_sample(c.pid, &c.sum.server_start);
  c.cpu0 = stress_self_cpu();
  c.wall0 = stress_now();
  stress_run_t *run = &c.run;
  pthread_mutex_init(&run->mu, NULL);
  pthread_cond_init(&run->cv, NULL);
  run->o = &o;
  snprintf(run->host, sizeof run->host, "%s", o.host);
  run->port = o.port;
  if ((rc = open_control(&c)) == OC_EXIT_OK && o.ramp) {
    if (c.period > 0) return run_ramp(&c);
    rc = oc_cli_fail(prog, OC_EXIT_USAGE, "--ramp needs a period: the scene's is %g (give --epoch-period)", c.period);
  }
  if (rc == OC_EXIT_OK && o.faults) rc = start_faults(&c);
  if (rc == OC_EXIT_OK) run_measured(&c);
  return finish(&c, rc);
}

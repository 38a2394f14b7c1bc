/* stress.h — overcast-stress internals shared by its files: options, the run, one viewer, the
 * server process, and the report.
 *
 *   stress_main.c    the coordinator (stepping, stopping, the final stats request)
 *   stress_opts.c    the command line: one table of options, --help generated from it
 *   stress_viewer.c  one viewer: a thread with its own connection (client/net.h), its camera path,
 *                    and the live checks (resident bytes counted here, checksums, skipped epochs)
 *   stress_proc.c    overcast-server as a child process; RSS and CPU from /proc
 *   stress_report.c  aggregates, the table on stdout and the JSON file
 *   stress_path.c    camera paths
 *   stress_clock.c   epochs on the clock, pure parts: lateness and coalesced ticks, the frame scan
 *                    that sees EPOCH_BEGIN arrive, the stamp scan back, matching a reproduced brick
 *   stress_verify.c  --verify-content: a thread re-producing sampled bricks with a world of its own */
#ifndef OC_TOOLS_STRESS_H
#define OC_TOOLS_STRESS_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "ocs.h"
#include "ocv.h"
#include "stress_path.h"

#define STRESS_MAX_VIEWERS 1024
#define STRESS_MAX_STEPS 100000
#define STRESS_SKIPS_LISTED 64 /* skipped epochs listed per viewer (all are counted) */

/*-*** Options ***/

typedef struct {
  int spawn;                /* start overcast-server (else --connect) */
  const char *server_path;  /* NULL: next to this program */
  const char *scene;        /* spawn: NULL → built-in planet */
  double epoch_period;      /* spawn: < 0 → the scene's */
  long server_threads;      /* spawn: 0 → the server's default */
  char host[OCV_HOST_MAX];
  int port;
  long server_pid;          /* connect: a local pid to read /proc of; 0: none */
  const char *token;
  const char *source;       /* --source-address: local IP the viewers and fault connections bind
                               to (port 0) before connecting; NULL: the system's choice */
  int viewers;
  int npaths, paths[STRESS_PATH_COUNT * 4];
  int nbudgets;
  long budgets_mib[64];
  int ndepths;
  long depths[64];
  int width, height;
  uint64_t seed;
  double tick_hz, step_seconds, teleport_every, dive_seconds;
  long epochs;              /* 0: not given */
  double duration;          /* 0: not given */
  double timeout;
  const char *json;
  int verbose;
  /* --ramp: phases of N viewers (ramp_from, ×2, .. ramp_max) on one spawned server */
  int ramp;
  long ramp_from, ramp_max;
  double ramp_seconds, ramp_warmup;
  /* --sweep-budgets × --sweep-depths: one viewer per combination (budget 0: 1 byte) */
  int sweep;
  int nsweep_budgets, nsweep_depths;
  long sweep_budgets_mib[32];
  long sweep_depths[32];
  /* --faults */
  int faults;               /* 1 << STRESS_FK_* | STRESS_FAULT_RESTART */
  long fault_every;         /* steps between rounds */
  uint64_t fault_budget_mib;/* budget of the misbehaving viewers */
  long restart_at;          /* the step after which the server is killed (0: the middle) */
  int restart_drain;        /* --restart-by drain: SIGTERM (a drain), not SIGKILL */
  long rebalance_at;        /* --rebalance-at S MIB: after step S, viewer 0's budget set to MIB (0: none) */
  long rebalance_mib;
  double fault_rss_slack;   /* MiB */
  int full_sessions;        /* keep brick codes (a full session) instead of digests */
  double verify_content;    /* --verify-content F: fraction of received bricks re-produced (0: off) */
  long verify_queue;        /* samples waiting at most (more are dropped, counted) */
  double verify_drain_s;    /* seconds to verify what is left after a run or phase */
  int share_paths;          /* every viewer flies the same path with the same seed (a shared region) */
  double time_scale;        /* --time-scale: set on the server at the start (< 0: not given) */
  const char *plot;         /* --ramp: PNG files PREFIX-age.png, PREFIX-detail.png */
  int reference;            /* --ramp: time to detail of a stepped server side by side (default on) */
  long ref_teleports;       /* teleports the stepped reference measures (after its first) */
  int ramp_all;             /* --ramp-all: every phase, even after one was not sustained */
  int detail_ref;           /* --detail-reference: what time to full detail is compared with
                               (STRESS_DETAIL_REF_*) */
  int nserver_args;
  char *server_args[32];    /* --server-arg: passed on to a spawned server */
} stress_opts_t;

/*! stress_opts_parse() (stress_opts.c) : the command line into *o (zeroed first), defaults
 *  applied and the options checked against each other.
 *  @return 0 to go on; 1 after --help or --version (exit 0); -1 after a one-line usage error on
 *  stderr (exit OC_EXIT_USAGE). */
int stress_opts_parse(int argc, char **argv, stress_opts_t *o);

/* Time to full detail: after a teleport the plan reacts (splits or merges: splits that only wait
 * are not a reaction, else a clocked tree waiting for a few dear coarse bricks "settled" at once,
 * its waiting splits under 1 % of the old tree's leaves), then
 * settles: over STRESS_SETTLE_STATES states in a row the plan changed at most
 * STRESS_SETTLE_FRACTION of their leaves (splits + merges + splits waiting, summed over them); the
 * time is the first of them's. An animated field keeps a settled tree churning (a refreshed node
 * turning empty is merged, one turning cloudy split: 0.2–0.8 % of the leaves a state at 4 MiB, in
 * bursts when deferred refreshes land: 24 splits, then 41 merges, then none), so the states are
 * judged together, not one by one: one by one, a full clocked 4 MiB tree went on "growing" for 20
 * ticks of such bursts, and the stepped one's bursts fell between its states by chance. Four
 * states, not three: a plan held back by the K kept states (they still hold the old place's
 * bricks) changes nothing for K - 1 = 2 states in the middle of a restructuring, and three states
 * with two such in them "settled" a stepped tree 8 epochs early. One state that only merges (a full
 * budget making room) is not settled: with "no split and none waiting", the stepped reference
 * settled 5 epochs after a jump whose tree went on changing for 7 more. */
#define STRESS_SETTLE_FRACTION 0.01
#define STRESS_SETTLE_STATES 4
typedef struct {
  int phase;            /* 0 idle, 1 waiting for the plan to react, 2 waiting for it to settle */
  int quiet;            /* phase 2: states fed since the reaction (the window is full at STATES) */
  double changed[STRESS_SETTLE_STATES], leaves[STRESS_SETTLE_STATES], at[STRESS_SETTLE_STATES];
  uint64_t epoch[STRESS_SETTLE_STATES]; /* the last states, a ring indexed by quiet */
  double quiet_at;      /* when the first of the settled window arrived */
  uint64_t quiet_epoch;
} stress_settle_t;
/*! stress_settle_feed() : one state's plan after a teleport (phase 1 or 2), arrived at t.
 *  @return 1 when it settles (phase back to 0; quiet_at and quiet_epoch say when), else 0. */
int stress_settle_feed(stress_settle_t *s, uint32_t splits, uint32_t merges, uint32_t waiting, uint32_t leaves, double t,
                       uint64_t epoch);

/* The ramp's rule (docs/performance.md, "Epochs on the clock"): a phase is sustained when every
 * viewer, over the measured window, has
 *   - lateness p99 ≤ STRESS_LATE_P99 (EPOCH_BEGIN readable minus n·P),
 *   - at most STRESS_COALESCED_MAX of its due ticks coalesced,
 *   - (--verify-content) verified content age p99 ≤ STRESS_AGE_ALLOWED time steps and no mismatch,
 *   - (teleport path) time to full detail p50 ≤ STRESS_DETAIL_FACTOR × a stepped server's on the
 *     same path and budget, measured side by side (--no-reference: not checked). The stepped
 *     figure is by default the larger of its seconds, stepping as fast as it makes epochs, and its
 *     epochs × P: what the server before the clock took, whose epochs waited for their bricks but
 *     never came faster than the period (with bricks cheaper than an epoch, a stepped server runs
 *     epochs faster than any clock); --detail-reference seconds or epochs takes one of the two,
 *   - and its median interval between states ≤ STRESS_RAMP_INTERVAL × the period (kept from the
 *     first rule: a viewer whose states come rarely is not keeping up, however punctual). */
#define STRESS_LATE_P99 0.050
#define STRESS_COALESCED_MAX 0.01
#define STRESS_DETAIL_FACTOR 1.25
#define STRESS_RAMP_INTERVAL 1.2
/* What the stepped reference's time to full detail is (--detail-reference). */
enum { STRESS_DETAIL_REF_HELD = 0, STRESS_DETAIL_REF_SECONDS = 1, STRESS_DETAIL_REF_EPOCHS = 2 };

/*-*** Fault injection (stress_fault.c) ***/

/* --faults: bits 1 << STRESS_FK_* for the connection kinds, and a restart of the server */
enum { STRESS_FK_STALL, STRESS_FK_DROP, STRESS_FK_GARBAGE, STRESS_FK_COUNT };
#define STRESS_FAULT_RESTART (1 << STRESS_FK_COUNT)
/* seconds past the server's handshake timeout by which garbage must have been closed */
#define STRESS_FAULT_GRACE 10.0
/* seconds a HELLO may wait for its WELCOME: a HELLO that arrives during a step is answered when
 * the step ends (a stepped planet's step under ASan has taken 39 s) */
#define STRESS_FAULT_WELCOME_WAIT 120.0
/* seconds past the server's stall timeout by which a viewer that stopped reading must be let go */
#define STRESS_FAULT_STALL_GRACE 5.0
/* a spawned server's --drain-timeout, s, and how long ocv_child_stop() waits for its exit:
 * the drain's longest, plus room for a step in progress (SIGKILL only after that) */
#define STRESS_DRAIN_S 5.0
#define STRESS_STOP_S (STRESS_DRAIN_S + 25.0)
/* misbehaving connections open at once, at most (stress_fault.c) */
#define STRESS_FAULT_MAX_CONNS 4096
/* RSS growth allowed beyond the server's own accounting (--fault-rss-slack default), MiB */
#define STRESS_FAULT_SLACK_MIB 64

typedef struct {
  double handshake_s, stall_s; /* the server's limits */
  uint64_t opened[STRESS_FK_COUNT], refused[STRESS_FK_COUNT]; /* refused: connect failed (server full, restarting) */
  uint64_t closed[STRESS_FK_COUNT];                           /* closed by the server */
  uint64_t errors[STRESS_FK_COUNT];                           /* of those, after an ERROR or GOODBYE frame */
  double close_s_max[STRESS_FK_COUNT];
  uint64_t late;               /* garbage or a stalled viewer still open past its deadline (a failure) */
  uint64_t unanswered;         /* garbage closed without ERROR, or served (a failure) */
  uint64_t states_before_drop; /* drop 3: complete states before the reset */
  uint64_t open_at_end;        /* stalled viewers the server still held at the end (not yet due) */
  char failure[256];           /* the first failure, "" if none */
} stress_fault_conns_t;

/* The coordinator's side of --faults: the server's memory, sampled after every step. */
typedef struct {
  int samples;
  double rss_base_mib, rss_peak_mib; /* of the incarnation with the largest growth */
  double accounted_base, accounted_peak; /* bytes the server accounts for: its brick cache, the
                                            states it holds for sessions, unsent queues */
  double growth_mib, allow_mib;      /* RSS growth beyond the accounted growth, and the slack */
  uint64_t queued_max, queue_hard;   /* largest unsent bytes of one connection; the server's limit */
  int restarts;
  double restart_s;                  /* the kill to every viewer's WELCOME from the new server (largest) */
} stress_fault_mem_t;

/*-*** Samples ***/

typedef struct {
  double *v;
  size_t n, cap;
} stress_samples_t;

int stress_samples_add(stress_samples_t *s, double x);
void stress_samples_free(stress_samples_t *s);
/*! stress_quantile() : nearest-rank quantile q in [0, 1] of the values (sorted in place); NAN if none. */
double stress_quantile(double *v, size_t n, double q);

/*-*** Epochs on the clock (stress_clock.c: pure, reads no clock) ***/

/* A viewer's ticks: lateness is the instant EPOCH_BEGIN was readable (CLOCK_REALTIME) minus the
 * instant its epoch n was due, n·P after the Unix epoch; coalesced ticks are the indices skipped
 * between consecutive states (each one a due tick this viewer never got). */
typedef struct {
  double period;          /* P, s (> 0) */
  int have;
  uint64_t first, last;   /* epochs of the first and newest state */
  uint64_t states, coalesced;
  stress_samples_t lateness; /* s, one per state whose EPOCH_BEGIN was seen */
} stress_ticks_t;

/*! stress_ticks_add() : a complete state of epoch `epoch` whose EPOCH_BEGIN was readable at
 *  `begin_utc` (NAN: not seen; no lateness sample). @return the ticks skipped since the previous
 *  state (0 for the first), or -1 when the epoch does not increase (not counted). */
long stress_ticks_add(stress_ticks_t *t, uint64_t epoch, double begin_utc);
/*! stress_ticks_due() : ticks due after the first state up to the newest (last − first). */
uint64_t stress_ticks_due(const stress_ticks_t *t);
/*! stress_ticks_coalesced_frac() : coalesced / due, NAN when nothing was due. */
double stress_ticks_coalesced_frac(const stress_ticks_t *t);
void stress_ticks_free(stress_ticks_t *t);

/* Frame headers seen in a viewer's byte stream (client/net.h's input tap), without keeping any
 * payload: for each EPOCH_BEGIN, its epoch index and world time, and the instant of the read that
 * completed those first 16 payload bytes. */
typedef struct {
  uint8_t hdr[OCP_HEADER_BYTES];
  int nhdr;
  uint8_t type;
  uint64_t left;          /* payload bytes of the current frame still to pass */
  uint8_t head[16];       /* EPOCH_BEGIN's first bytes: u64 epoch, f64 world time */
  int nhead;
  int bad;                /* a header without the magic: scanning stops (the session fails too) */
} stress_scan_t;
typedef void (*stress_begin_fn)(void *ctx, uint64_t epoch, double world_time, double utc);
/*! stress_scan_feed() : n bytes read at instant `utc`; calls `begin` for each EPOCH_BEGIN whose
 *  first 16 payload bytes are now complete. */
void stress_scan_feed(stress_scan_t *s, const uint8_t *p, size_t n, double utc, stress_begin_fn begin, void *ctx);

/* Content age: the stamps a level had at the epochs before world time t. */
typedef uint64_t (*stress_stamp_fn)(void *ctx, int level, double t);
/*! stress_stamp_scan() : the latest `want` distinct stamps of `level` at or before world time t,
 *  newest first, scanning t, t − dt, t − 2·dt, .. (dt: world seconds per epoch; up to max_epochs
 *  back). times[k] is the latest scanned time with stamps[k]: stamps[0] is the stamp at t (step s),
 *  stamps[1] the one before (s − 1), and so on. dt ≤ 0 (a paused clock) finds one.
 *  @return how many were found (1..want). */
int stress_stamp_scan(stress_stamp_fn f, void *ctx, int level, double t, double dt, int max_epochs, int want, double *times,
                      uint64_t *stamps);

/* One received brick, sampled for verification. */
typedef struct stress_age_s stress_age_t;
typedef struct {
  oc_key_t key;
  double t, dt;           /* the state's world time, world seconds per epoch */
  oc_range_t range[OC_CHANNELS];
  uint64_t digest;        /* oc_brick_digest() of the codes received (after any delta) */
  stress_age_t *into;     /* where the result is counted (the viewer's) */
} stress_brick_sample_t;
/*! stress_brick_matches() : 1 when `made` (reproduced) is the content received: a brick with the
 *  same ranges, bit for bit, and codes of the same digest. */
int stress_brick_matches(const stress_brick_sample_t *got, const ocs_brick_out_t *made);

/* Verified content age, per level: ages 0..STRESS_AGE_MAX (time steps behind the state's), and
 * those that matched none of them. A mismatch (a failure: content no time step made) is a brick
 * matching none of s .. s − STRESS_AGE_MAX; a brick older than s − 2 is stale, not wrong (the
 * server may show stale content while the newer waits in its queue), and counts in the
 * age quantiles, which the sustained rule bounds. The scan back goes
 * up to STRESS_AGE_SCAN_EPOCHS epochs: a coarse level's time step spans many epochs, and 64 (the
 * first choice) reached only 2–3 of its stamps. */
#define STRESS_AGE_MAX 16
#define STRESS_AGE_ALLOWED 2
#define STRESS_AGE_SCAN_EPOCHS 4096
struct stress_age_s {
  uint64_t n[OC_KEY_MAX_LEVEL + 1][STRESS_AGE_MAX + 2]; /* [level][age]; [STRESS_AGE_MAX + 1]: none */
  uint64_t sampled, dropped, errors; /* queued; not queued (queue full); reproduction failed */
};
/*! stress_age_count() : verified bricks (every level, or one level ≥ 0), and those of them
 *  matching no stamp at all (mismatches). */
uint64_t stress_age_count(const stress_age_t *a, int level);
uint64_t stress_age_mismatches(const stress_age_t *a, int level);
/*! stress_age_quantile() : nearest-rank quantile of the verified ages (a level ≥ 0, or all: -1);
 *  STRESS_AGE_MAX + 1 stands for "none matched"; -1 when nothing was verified. */
int stress_age_quantile(const stress_age_t *a, int level, double q);
/*! stress_age_merge() : dst += src. */
void stress_age_merge(stress_age_t *dst, const stress_age_t *src);

/*-*** --verify-content (stress_verify.c) ***/

typedef struct stress_verify_s stress_verify_t;
/*! stress_verify_start() : the verifier's own world of `scene` (threads 1, stepped clock, no
 *  viewers) and its thread (lowest priority), queue for `cap` samples.
 *  @return 0 or a negative OC_E* with a reason. */
int stress_verify_start(stress_verify_t **out, const oc_scene_t *scene, size_t cap, char *why, size_t why_len);
/*! stress_verify_push() : queues a sample (thread-safe); a full queue drops it (counted in
 *  s->into->dropped). */
void stress_verify_push(stress_verify_t *v, const stress_brick_sample_t *s);
/*! stress_verify_drain() : waits until every queued sample is verified, at most timeout_s.
 *  @return samples still queued (0: all done). Results may be read after it. */
size_t stress_verify_drain(stress_verify_t *v, double timeout_s);
/*! stress_verify_seconds() : seconds the verifier spent reproducing so far, and bricks reproduced. */
void stress_verify_work(stress_verify_t *v, double *seconds, uint64_t *reproduced);
void stress_verify_stop(stress_verify_t *v);

/*-*** One viewer ***/

typedef struct stress_run_s stress_run_t;
typedef struct stress_faults_s stress_faults_t;

/* Brick ids referenced by one state's records (sorted) and its record count. */
typedef struct {
  uint32_t *ids;
  uint32_t n, cap, records;
} stress_footprint_t;

typedef struct {
  /* set before the thread starts */
  int index;
  stress_path_kind_t path;
  uint64_t budget; /* bytes asked for */
  int max_depth;
  stress_run_t *run;
  pthread_t thread;
  int started;

  /* shared with the coordinator, under run->mu */
  int ready;            /* WELCOME arrived and the first camera went out */
  int done;             /* the thread's loop ended (error or stop) */
  uint64_t have_epoch;  /* newest complete state, acknowledged, next camera sent */
  uint64_t have_states; /* complete states so far */
  double last_input;    /* when bytes last arrived */
  int busy;             /* reading input now (a state being decoded and verified may take seconds under ASan) */

  /* the thread's own; read by the coordinator after the join */
  ocv_conn_t *conn;
  stress_path_t p;
  ocp_welcome_t welcome;
  int have_welcome;
  double t_welcome, t_end;
  uint64_t states, first_epoch, last_epoch, skipped;
  uint64_t skipped_list[STRESS_SKIPS_LISTED];
  int nskipped_list;
  ocp_stats_t last_stats;
  uint64_t stats_msgs;
  uint64_t resident_last, resident_max, server_resident_max;
  uint64_t violations;        /* states after which resident > the budget in force (ocp_viewer's:
                                 WELCOME's, changed by BUDGET: a raise at once, a lowering once the
                                 old budget's states have left) */
  uint64_t budgets;           /* budgets put in force by BUDGET */
  uint64_t budget_before;     /* the budget in force when the last state began */
  uint64_t resident_mismatch; /* our count differs from the session's */
  uint64_t checksum_failures, protocol_errors;
  uint64_t nodes_last, bricks_last, bricks_in;
  int depth_last, depth_max; /* deepest octree level among the leaves: the last state's, the most */
  /* --ramp: counted only for states completed at or after run->measure_from */
  uint64_t m_states, m_skipped, m_bytes0;
  double m_t0;
  stress_samples_t m_interval;
  stress_samples_t m_detail; /* time to full detail of teleports made in the measured window */
  uint64_t m_teleports, m_unreached; /* unreached: the next teleport came first */
  double m_open_s;           /* a measured teleport still unsettled at the end: seconds it waited */
  int teleport_measured;     /* the current teleport was made in the measured window */
  /* epochs on the clock (with a period): the whole run's ticks and the measured window's */
  stress_ticks_t ticks, m_ticks;
  stress_scan_t scan;
  double poll_utc;           /* CLOCK_REALTIME when the bytes being read became readable */
  uint64_t begin_epoch;      /* the last EPOCH_BEGIN seen, and when */
  double begin_utc;
  int begin_seen;
  /* --verify-content: bricks with ids above max_id are new (received in this state) */
  stress_age_t age, m_age;
  uint32_t max_id;
  uint64_t rng;
  double prev_time;          /* the previous state's world time and epoch: world seconds per epoch */
  uint64_t prev_epoch;
  int have_prev;
  int failed;
  char error[512];
  stress_samples_t latency;  /* s: stepped from the step request, else from the first byte of EPOCH_BEGIN */
  stress_samples_t transfer; /* s: first byte of EPOCH_BEGIN to the complete state */
  stress_samples_t interval; /* s: between consecutive complete states */
  stress_samples_t detail;   /* s: time to full detail after a teleport */
  stress_samples_t detail_epochs;
  uint64_t teleports, detail_unreached;
  int detail_first;          /* detail.v[0] is the first teleport's (at path time 0, from no tree) */
  ocp_viewer_stats_t session; /* the session's counters at the end */
  /* --faults restart: reconnections after the server went away, and the time from the loss to the
   * first state from the server that came back */
  int gen;             /* the server incarnation of the current WELCOME (under run->mu) */
  int fresh;           /* a new session began: the next state starts a new epoch sequence */
  double lost_at;
  uint64_t reconnects;
  stress_samples_t resync;
  stress_footprint_t fp[2]; /* the K−1 previous states', newest first */
  int nfp;
  stress_footprint_t fp_new; /* the arriving state's (its memory is recycled) */
  /* the thread's bookkeeping */
  int between;         /* no byte of the next epoch seen yet */
  double epoch_first_byte, state_at;
  int new_state;
  long jump;
  stress_settle_t settle; /* time to full detail after the last teleport (.phase 0: idle) */
  double teleport_at;     /* period: when the camera jumped */
  uint64_t teleport_step; /* stepped: the first step planned for the new place */
  uint64_t teleport_epoch;
} stress_viewer_t;

/*-*** The run ***/

struct stress_run_s {
  const stress_opts_t *o;
  char host[OCV_HOST_MAX];
  int port;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  atomic_int stop;    /* set once at the end; the viewer threads poll it */
  /* stepped mode: step k (1-based) was requested at step_at[k] and makes epoch epoch0 + k */
  uint64_t epoch0;
  uint64_t steps_sent;
  double *step_at;
  double t0;
  double measure_from; /* --ramp: the warm-up ends (under mu; 0: no ramp) */
  /* --faults restart: the server's incarnation (under mu); steps before it began */
  int restart_gen;
  uint64_t step0;
  stress_faults_t *faults;
  stress_viewer_t *v;
  int nv;
  int index0;              /* viewer i has index index0 + i (its path's seed) */
  stress_verify_t *verify; /* --verify-content */
  double world_dt;         /* world seconds per epoch (until a viewer has two states: P × 1) */
};

double stress_now(void);
/*! stress_utc() : CLOCK_REALTIME, s since the Unix epoch (lateness: the server ticks on it). */
double stress_utc(void);
/*! stress_viewer_main() : the thread body (arg: stress_viewer_t *). */
void *stress_viewer_main(void *arg);
void stress_viewer_free(stress_viewer_t *v);

/*! stress_faults_start() : the thread of misbehaving connections (o->faults), idle until asked.
 *  handshake_s, stall_s: the server's timeouts (the deadlines of garbage and of stalled viewers).
 *  @return 0 or a negative OC_E*. */
int stress_faults_start(stress_run_t *run, double handshake_s, double stall_s);
/*! stress_faults_round() : one connection of each kind asked for, opened now (before a step). */
void stress_faults_round(stress_run_t *run);
/*! stress_faults_restarted() : the server is about to be killed: the thread forgets the connections
 *  it had (their end is not the server's doing) before this returns. */
void stress_faults_restarted(stress_run_t *run);
/*! stress_faults_stop() : waits until every garbage connection is settled (closed or late), closes
 *  the rest, joins, and copies the counts (out may be NULL). */
void stress_faults_stop(stress_run_t *run, stress_fault_conns_t *out);
const char *stress_fault_kind_name(int kind);

/*-*** The server process (started with client/child.h's ocv_child_spawn) ***/

typedef struct {
  int ok;
  double rss_mib, hwm_mib; /* VmRSS, VmHWM */
  double cpu_s;            /* user + system */
} stress_proc_t;

/*! stress_proc_sample() : VmRSS, VmHWM and CPU seconds of a process (ok = 0 when unreadable). */
void stress_proc_sample(long pid, stress_proc_t *out);
/*! stress_self_cpu() : this process's user + system CPU seconds (getrusage). */
double stress_self_cpu(void);

/*-*** The report ***/

typedef struct {
  int spawned, stepped;
  char scene[OCP_NAME_MAX + 1];
  int kept_states;
  double epoch_period;
  double wall_s;
  uint64_t steps, steps_incomplete;
  stress_proc_t server_start, server_end;
  int server_exit;      /* -1: not ours or unknown */
  double server_cpu_s;  /* during the run; NAN when unknown */
  double tool_cpu_s;
  double cpu_span_s;     /* wall time over which both CPU figures were taken */
  stress_proc_t tool;    /* this process at the end: its RSS and peak RSS */
  double cache_hit_rate; /* NAN when unknown */
  double bricks_produced, brick_requests;
  double cache_bytes;    /* the server's brick cache at the end; NAN unknown */
  double late_ticks;     /* epoch ticks the server skipped because a step still ran; NAN unknown */
  size_t verify_left;    /* --verify-content: samples not verified by the end (drain timed out) */
  double verify_s;       /* seconds the verifier spent reproducing, and bricks it reproduced */
  uint64_t verify_reproduced;
  char error[512];      /* a run-level failure, "" if none */
  stress_fault_conns_t fault_conns; /* --faults */
  stress_fault_mem_t fault_mem;
} stress_summary_t;

/* Quantiles of pooled samples (nearest-rank); NAN when there are none. */
typedef struct {
  double p50, p99, max;
  size_t n;
} stress_q_t;
/*! stress_pool() (stress_report.c) : quantiles of a copy of the samples at byte offset `off` of
 *  stress_viewer_t (a stress_samples_t, e.g. offsetof(stress_viewer_t, m_detail)), pooled over
 *  every viewer of run, or of viewer `only` alone (only >= 0). */
stress_q_t stress_pool(const stress_run_t *run, size_t off, int only);

/*! stress_report() : prints the table on stdout and (o->json) writes the JSON file.
 *  @return 1 when every check passed, 0 otherwise (-1: the JSON file could not be written, with
 *  a message on stderr). */
int stress_report(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s);

/* One --ramp phase: N viewers, all at one budget. */
typedef struct {
  int n;
  long budget_mib;
  double seconds;               /* measured */
  double itv_p50, itv_p99;      /* pooled over the viewers' measured intervals, s */
  double worst_median;          /* the largest of the viewers' median intervals, s */
  uint64_t states, skipped;
  double skipped_frac;
  /* epochs on the clock, over the measured window */
  double late_p50, late_p99, late_max; /* pooled lateness, s */
  double late_worst_p99;        /* the largest of the viewers' lateness p99, s */
  uint64_t due, coalesced;      /* ticks due after each viewer's first measured state; skipped */
  double coalesced_frac, coalesced_worst; /* pooled; the largest of the viewers' fractions */
  uint64_t coalesced_server;    /* STATS coalesced at the end, summed (the server's count, whole phase) */
  stress_age_t age;             /* --verify-content: verified ages in the window, all viewers */
  int age_p99, age_worst_p99;   /* pooled over levels and viewers; the largest viewer's (-1: none) */
  uint64_t age_mismatch, verify_left;
  int server_age_p99;           /* the server's own STATS age_p99, the largest over levels and viewers
                                   (their last STATS; -1: none reported) */
  double detail_p50, detail_p99, detail_ref; /* teleport viewers, s; the stepped server's p50 */
  double detail_worst_ratio;    /* the largest of the viewers' p50 / detail_ref */
  double detail_lower_s;        /* teleports that did not settle waited at least this long (NAN: none) */
  uint64_t teleports, detail_n, unreached;
  double cpu_pct, rss_mib, hwm_mib; /* the server over the measured window; at its end */
  double mbps_p50, mbps_p99;    /* per viewer over the measured window */
  uint64_t violations, checksum, protocol, mismatch, failed;
  int sustained;
  char why[200];                /* why not sustained, or a failure */
} stress_ramp_phase_t;

/* The stepped reference of one budget: time to full detail on the teleport path, one viewer,
 * epochs stepped as fast as the server makes them (period 0), path seconds per epoch = P. */
typedef struct {
  long budget_mib;
  int index;                    /* the viewer index whose path (seed) it flew */
  double detail_p50, detail_p99, detail_epochs_p50;
  uint64_t teleports, settled;
  double seconds;
  char error[200];
} stress_ref_t;

/*! stress_ramp_report() : the ramp's table on stdout and (o->json) its JSON; (o->plot) its PNGs.
 *  largest[b]: the largest N sustained at o->budgets_mib[b]. @return 1 when no check failed in any
 *  phase, 0 otherwise, -1 when the JSON or a plot could not be written. */
int stress_ramp_report(const stress_opts_t *o, const char *scene, double period, const stress_ramp_phase_t *ph, int nph,
                       const int *largest, const stress_ref_t *refs, int nrefs, const stress_summary_t *s);

#endif /* OC_TOOLS_STRESS_H */

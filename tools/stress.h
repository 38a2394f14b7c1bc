/* stress.h — overcast-stress internals shared by its files: options, the run, one viewer, the
 * server process, and the report.
 *
 *   stress_main.c    command line, the coordinator (stepping, stopping, the final stats request)
 *   stress_viewer.c  one viewer: a thread with its own connection (client/net.h), its camera path,
 *                    and the live checks (resident bytes counted here, checksums, skipped epochs)
 *   stress_proc.c    overcast-server as a child process; RSS and CPU from /proc
 *   stress_report.c  aggregates, the table on stdout and the JSON file
 *   stress_path.c    camera paths */
#ifndef OC_TOOLS_STRESS_H
#define OC_TOOLS_STRESS_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "net.h"
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
  double fault_rss_slack;   /* MiB */
  int full_sessions;        /* keep brick codes (a full session) instead of digests */
  int nserver_args;
  char *server_args[32];    /* --server-arg: passed on to a spawned server */
} stress_opts_t;

/* The ramp's rule: a phase is sustained when every viewer's median interval between states is at
 * most STRESS_RAMP_INTERVAL × the period and at most STRESS_RAMP_SKIPPED of the epochs due in the
 * measured window were skipped (skipped / (states + skipped), over all viewers). */
#define STRESS_RAMP_INTERVAL 1.2
#define STRESS_RAMP_SKIPPED 0.05

/*-*** Fault injection (stress_fault.c) ***/

/* --faults: bits 1 << STRESS_FK_* for the connection kinds, and a restart of the server */
enum { STRESS_FK_STALL, STRESS_FK_DROP, STRESS_FK_GARBAGE, STRESS_FK_COUNT };
#define STRESS_FAULT_RESTART (1 << STRESS_FK_COUNT)
/* seconds past the server's handshake timeout by which garbage must have been closed */
#define STRESS_FAULT_GRACE 10.0
/* seconds past the server's stall timeout by which a viewer that stopped reading must be let go */
#define STRESS_FAULT_STALL_GRACE 5.0
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
  uint64_t violations;        /* states after which resident > granted budget */
  uint64_t resident_mismatch; /* our count differs from the session's */
  uint64_t checksum_failures, protocol_errors;
  uint64_t nodes_last, bricks_last, bricks_in;
  int depth_last, depth_max; /* deepest octree level among the leaves: the last state's, the most */
  /* --ramp: counted only for states completed at or after run->measure_from */
  uint64_t m_states, m_skipped, m_bytes0;
  double m_t0;
  stress_samples_t m_interval;
  int failed;
  char error[512];
  stress_samples_t latency;  /* s: stepped from the step request, else from the first byte of EPOCH_BEGIN */
  stress_samples_t transfer; /* s: first byte of EPOCH_BEGIN to the complete state */
  stress_samples_t interval; /* s: between consecutive complete states */
  stress_samples_t detail;   /* s: time to full detail after a teleport */
  stress_samples_t detail_epochs;
  uint64_t teleports, detail_unreached;
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
  int detail_phase;    /* 0 idle, 1 waiting for the plan to react, 2 waiting for it to settle */
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
};

double stress_now(void);
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

/*-*** The server process ***/

typedef struct {
  pid_t pid;
  int out_fd; /* its stdout (kept open, never read after the address) */
  char host[OCV_HOST_MAX];
  int port;
} stress_child_t;

typedef struct {
  int ok;
  double rss_mib, hwm_mib; /* VmRSS, VmHWM */
  double cpu_s;            /* user + system */
} stress_proc_t;

/*! stress_server_spawn() : runs argv[0] with argv (its stdout to a pipe, stderr shared, killed if we
 *  die) and reads its "listening on HOST:PORT" within timeout_s. @return 0 or OC_EIO with a reason. */
int stress_server_spawn(char *const argv[], double timeout_s, stress_child_t *c, char *why, size_t why_len);
/*! stress_server_stop() : SIGTERM, waits up to timeout_s (then SIGKILL). @return its exit status,
 *  128 + signal when killed by one, or -1. */
int stress_server_stop(stress_child_t *c, double timeout_s);
/*! stress_server_kill() : SIGKILL (a crash, as far as its clients can tell) and wait. @return as above. */
int stress_server_kill(stress_child_t *c);
/*! stress_proc_sample() : VmRSS, VmHWM and CPU seconds of a process (ok = 0 when unreadable). */
void stress_proc_sample(long pid, stress_proc_t *out);
/*! stress_self_cpu() : this process's user + system CPU seconds (getrusage). */
double stress_self_cpu(void);
/*! stress_exe_dir() : the folder of this program (/proc/self/exe). @return 0 or -1. */
int stress_exe_dir(char *buf, size_t cap);

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
  char error[512];      /* a run-level failure, "" if none */
  stress_fault_conns_t fault_conns; /* --faults */
  stress_fault_mem_t fault_mem;
} stress_summary_t;

/*! stress_report() : prints the table on stdout and (o->json) writes the JSON file.
 *  @return 1 when every check passed, 0 otherwise (-1: the JSON file could not be written, with
 *  a message on stderr). */
int stress_report(const stress_opts_t *o, const stress_run_t *run, const stress_summary_t *s);

/* One --ramp phase. */
typedef struct {
  int n;
  double seconds;               /* measured */
  double itv_p50, itv_p99;      /* pooled over the viewers' measured intervals, s */
  double worst_median;          /* the largest of the viewers' median intervals, s */
  uint64_t states, skipped;
  double skipped_frac;
  double cpu_pct, rss_mib, hwm_mib; /* the server over the measured window; at its end */
  double mbps_p50, mbps_p99;    /* per viewer over the measured window */
  uint64_t violations, checksum, protocol, mismatch, failed;
  int sustained;
  char why[160];                /* why not sustained, or a failure */
} stress_ramp_phase_t;

/*! stress_ramp_report() : the ramp's table on stdout and (o->json) its JSON. @return 1 when no check
 *  failed in any phase, 0 otherwise, -1 when the JSON could not be written. */
int stress_ramp_report(const stress_opts_t *o, const char *scene, double period, const stress_ramp_phase_t *ph, int nph,
                       int largest, const stress_summary_t *s);

#endif /* OC_TOOLS_STRESS_H */

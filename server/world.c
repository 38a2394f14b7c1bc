/* world.c — epochs: plan every ready viewer, produce what the plans lack once, emit states. */
#include "world.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h> /* readlink: thread_id */

#include "brick_cache.h"
#include "oc_bytes.h"
#include "oc_err.h"
#include "oc_log.h"
#include "oc_planet.h"
#include "ocs_field.h"
#include "pool.h"
#include "sun_depth.h"
#include "world_clock.h"

enum { T_BRICK = 1, T_SIGMA = 2, T_TAUVOL = 3 };

/* Stamps of a level kept after they change (for content age), and the oldest of them whose
 * content a tick may still show (stale but complete) while the newer waits in the queue: 2, the
 * sustained rule's bound (overcast-stress; with 3, 1–5 % of the bricks sent at 2–8 viewers were 3
 * steps old, mostly at levels 9–11, content made minutes before and still cached). */
#define OCS_STAMP_HISTORY 3
#define OCS_READY_AGE 2
/* How much of a level's σt one time step of the procedural field changes (L1 relative to L1, 32
 * brick nodes per level; docs/performance.md, "What skipping costs"; odd levels and levels past 15
 * interpolated or held). Refreshes are worth the node's pixels times this (planner.h). */
static const double STEP_CHANGE[OC_KEY_MAX_LEVEL + 1] = {
    0.52, 0.52, 0.52, 0.44, 0.36, 0.345, 0.33, 0.295, 0.26, 0.11,  0.071,
    0.063, 0.048, 0.034, 0.034, 0.014, 0.014, 0.014, 0.014, 0.014, 0.014, 0.014};

/* Clocked: producer threads run at this nice value, so a tick (which runs beside production's last
 * bricks) and the sockets get the cores first: on 2 cores, a tick shared them with 2 producers at
 * equal priority and went out 40–80 ms late (docs/performance.md). */
#define OCS_PRODUCER_NICE 10

/* A brick's place in the sharing tables: held back (open addressing, OCS_HOLD_SLOTS slots, at most
 * half full) and made since the last take. */
typedef struct {
  oc_key_t key;
  uint64_t stamp;
  int used;
} share_t;
#define OCS_HOLD_SLOTS 8192u
#define OCS_MADE_MAX (1u << 16)

/* The production queue's bound (entries of 24 bytes). */
#define OCS_QUEUE_MAX (1u << 16)

/* A brick some viewer's plan waited for (clocked epochs), with the pixels it buys that viewer. */
typedef struct {
  oc_key_t key;
  uint64_t stamp;
  double prio;
  double turn;              /* its place in production's fair order (wishes_share) */
  uint32_t viewer;          /* index in the world's viewers; OCS_NO_VIEWER: it left */
} wish_t;
#define OCS_NO_VIEWER UINT32_MAX

/* An item of the production queue: a distinct brick, its priority summed over the viewers that
 * want it, and their wishes (wish[first .. first + count)). */
typedef struct {
  oc_key_t key;
  uint64_t stamp;
  double prio;
  double turn; /* the earliest turn of the viewers that want it */
  uint32_t first, count;
} queued_t;

/* A node whose σt of a coming time step is sampled ahead, or (tau) whose group's τ volume of its
 * level's coming light stamp is built ahead (ahead_collect). */
typedef struct {
  oc_key_t key;
  oc_key_t group; /* tau: the volume's group (ocs_tau_group_of) */
  uint64_t ts;    /* σt: the step */
  double time;    /* the world time what it makes comes due (σt: an instant in the step it samples) */
  double cpu;     /* what making it took (0: found made, or not made) */
  int tau;
} ahead_t;

/* What ahead made for a time still to come, and what it took: the stock it keeps (the stats'
 * ahead_cpu_stock). */
typedef struct {
  double due, cpu;
  int tau;
} stock_t;

/* A produced brick as the cache keeps it: codes only when kind is OC_NODE_BRICK. */
typedef struct {
  uint8_t kind;
  oc_range_t range[OC_CHANNELS];
  oc_brick_codes_t codes;
} payload_t;
#define PAYLOAD_HEAD offsetof(payload_t, codes)

/* A payload's bytes: the codes only for a brick. The cache counts an entry by these bytes, and three
 * made bricks in four are empty: a whole payload for each let the process hold about twice the
 * cache's cap (a 1 GiB cache, 1.96 GB resident after 48 epochs of the planet). */
static size_t payload_bytes(uint8_t kind) { return kind == OC_NODE_BRICK ? sizeof(payload_t) : PAYLOAD_HEAD; }

/* A cache entry's copy of a payload made on the stack, of payload_bytes(); NULL: no memory. */
static payload_t *payload_copy(const payload_t *made) {
  payload_t *p = malloc(payload_bytes(made->kind));
  if (p) memcpy(p, made, payload_bytes(made->kind));
  return p;
}

typedef struct {
  oc_key_t key;
  uint64_t stamp;
  ocs_cache_entry_t *entry; /* pinned until the states are built */
  float *sigma;             /* σt kept while the request waits for a τ volume (produce_one) */
  int made;                 /* produced here (not found in the cache) */
  int built_tau;            /* its τ volume was built for it (the expensive kind of brick) */
  uint8_t kind;             /* what it turned out to be (OC_NODE_*), once made */
  double cpu;               /* seconds its producer threads spent on it so far (both passes) */
  double pass0[2];          /* its first pass's interval and thread, for the trace (trace_made) */
  int pass0_tid;
  uint32_t first, count;    /* production: its viewers, who[first .. first + count) */
} req_t;

/* What production reads of the world, fixed when it starts. A tick may run while production's
 * last bricks finish (ocs_world_produce_run()), and the tick moves the world's clock on; so each
 * production, and each step, works from its own copy. */
typedef struct {
  ocs_world_t *w;
  double time;
  uint64_t ts[OC_KEY_MAX_LEVEL + 1], light[OC_KEY_MAX_LEVEL + 1], sun_version;
  uint64_t light_before[OC_KEY_MAX_LEVEL + 1]; /* the light stamp before light (0: none) whose τ
                                                   volumes may be kept (tau_volume_keep) */
  ocs_tau_desc_t tau; /* ctx: this */
  double deadline;    /* no brick is started that is expected to end after it, but for may_start()'s
                         exceptions (monotonic s); 0: none */
  double start;       /* when production began (monotonic s): see may_start() */
  _Atomic double busy_until; /* when the bricks started so far are expected to end */
  req_t *req;
  size_t nreq, req_cap;
  size_t *deferred; /* requests whose τ volume another thread was building */
  size_t ndeferred, deferred_cap;
  struct ocs_viewer_s **who; /* production: the viewers that wanted each request (NULL: it left) */
  size_t nwho, who_cap;
} prod_t;

struct ocs_viewer_s {
  ocs_world_t *w;
  ocs_planner_t *planner;
  ocs_plan_desc_t desc;
  ocs_view_t view;
  int has_view;
  ocs_view_t planned_view;  /* the view of its last plan */
  int has_planned_view;
  uint64_t jumped_at;       /* the tick of its first plan, or its view's last jump (view_jumped) */
  oc_state_t held[OCS_PLAN_MAX_KEPT]; /* held[0]: newest state sent */
  oc_state_t spare;                   /* the last state dropped, its arrays kept for the next one
                                         (tens of MB at 64 MiB: a new one faulted them in every tick) */
  int nheld;
  uint32_t *lacking;
  uint32_t nlacking, lacking_cap;
  ocs_plan_stats_t plan;
  uint64_t in_flight, acked;
  int unacked;
  uint64_t sent, coalesced;
  uint32_t next_id;
  uint32_t last_new;       /* bricks sent in the last state */
  uint32_t ticks;          /* epochs since the last plan */
  uint64_t seen;           /* the last epoch stepped while it was here (0: none yet) */
  int targeted;            /* planned at the last tick: its target is wished for (plan_targets) */
  wish_t *target;          /* its last target plan's wishes, best first (reused: plan_targets) */
  size_t ntarget, target_cap;
  uint64_t target_epoch;   /* the tick it was planned after */
  ocs_view_t target_view;  /* the view it was planned for */
  int has_target;
  double steady;           /* how rarely its view jumps (viewers_steadiness; 1 at first) */
  ocs_view_t steady_view;  /* its view at the last production */
  int has_steady_view;
  uint32_t produced, produced_last; /* bricks made for it since its last state; before that state */
  uint8_t age_p50[OC_KEY_MAX_LEVEL + 1], age_p99[OC_KEY_MAX_LEVEL + 1]; /* of its newest state */
  /* budget changes (docs/architecture.md "Budget changes") */
  int changeable;           /* its protocol has BUDGET: it may be lowered and raised */
  uint64_t ask;             /* its request clamped to the per-viewer maximum: what raises may give */
  uint64_t want;            /* the budget asked for it (set_budget, raises); 0: none */
  uint64_t reserved;        /* its part of w->granted: ocs_plan_reserved(), or `want` when larger */
  int news;                 /* a budget put in force, not yet told (ocs_viewer_budget_news) */
  uint64_t news_budget, news_epoch;
  /* during a step */
  const ocs_plan_leaf_t *leaves;
  uint32_t nleaves;
  uint32_t *req_of;        /* per leaf: request index (produce leaves) */
  uint32_t req_cap;
  int planned;
};

struct ocs_world_s {
  oc_scene_t scene;
  ocs_world_desc_t d;
  ocs_field_t *field;
  ocs_cache_t *cache;
  ocs_pool_t *pool;
  int K, shadows, ground_tau;
  int ground_direct; /* OCS_TAU_GROUND_DIRECT=1: ground τ ray by ray (before/after benches), not by columns */
  /* ahead (ahead_collect): per level, the epochs until its own time step next changes (0: not within
   * OCS_AHEAD_EPOCHS, or it changes every epoch: nothing to spread), that step and an instant in it;
   * the items chosen for this epoch */
  int ahead_off; /* OCS_AHEAD=0 (before/after benches) */
  int keep_tau_off;   /* OCS_TAU_KEEP=0: every τ volume of a new light stamp is built (before/after benches) */
  int keep_sigma_off; /* OCS_SIGMA_KEEP=0: every σt of a new node step is sampled (likewise) */
  uint32_t ahead_in[OC_KEY_MAX_LEVEL + 1];
  uint64_t ahead_ts[OC_KEY_MAX_LEVEL + 1];
  double ahead_t[OC_KEY_MAX_LEVEL + 1];
  uint32_t light_in[OC_KEY_MAX_LEVEL + 1]; /* likewise for each level's light stamp (τ volumes) */
  double light_t[OC_KEY_MAX_LEVEL + 1];
  prod_t ahead_at[OC_KEY_MAX_LEVEL + 1]; /* the world at light_t[l], what its τ volumes read */
  ahead_t *ahead;
  size_t nahead, ahead_cap;
  stock_t *stock; /* made ahead and not yet due (pruned as world time passes their due times) */
  size_t nstock, stock_cap;
  double ahead_now; /* the world time ahead_collect() chose for (ahead_run() may run beside a tick) */
  uint64_t field_gen;
  uint64_t epoch;
  ocs_clock_t clock; /* the control history: world time from the instant */
  double utc, time;  /* the last epoch's instant and world time */
  oc_dvec3 sun;
  uint64_t sun_version; /* the sun direction's bits, hashed (sun_hash): content, not a counter, so
                           that front-ends that agree on the sun agree on every stamp */
  ocs_tau_desc_t tau;
  uint64_t ts[OC_KEY_MAX_LEVEL + 1], stamp[OC_KEY_MAX_LEVEL + 1], light[OC_KEY_MAX_LEVEL + 1];
  uint64_t light_before[OC_KEY_MAX_LEVEL + 1]; /* each level's light stamp before its last change (0: none) */
  double rate[OC_KEY_MAX_LEVEL + 1];
  ocs_viewer_t **viewers;
  int nviewers;
  size_t viewers_cap;
  uint64_t granted;
  prod_t stepping;   /* the step's requests (a clocked tick's: all content that exists) */
  prod_t producing;  /* production's (clocked), between ocs_world_produce_begin() and _end() */
  int in_production; /* begun and not ended */
  int ticked;        /* a tick ran since production began: the queue is the tick's now */
  int produce_rc;    /* ocs_world_produce_run()'s */
  double produce_t0;
  /* clocked epochs */
  uint64_t stamp_hist[OC_KEY_MAX_LEVEL + 1][OCS_STAMP_HISTORY]; /* each level's previous stamps */
  ocs_cache_entry_t **pins; /* content found ready during a tick */
  size_t npins, pins_cap;
  wish_t *wish;             /* what the tick's plans waited for; then, sorted by brick, the queue's */
  size_t nwish, wish_cap;
  queued_t *queue;          /* what production makes between ticks, best first */
  size_t nqueue, queue_cap;
  ocs_pool_t *tick_pool;    /* clocked: the viewers' plans of a tick, in parallel (nice 0: the
                               tick goes before production's threads) */
  pthread_mutex_t tick_mu;  /* guards wish and pins while plans run in parallel */
  int targets_due;          /* the last tick's targets are still to be planned (plan_targets) */
  int target_next;          /* the viewer whose target is planned first (they take turns) */
  double target_cost;       /* s: what one target plan takes, a decaying maximum */
  size_t queue_left;        /* what the last production left queued (reported until the next queue) */
  /* counters (production runs on many threads) */
  _Atomic uint64_t bricks_produced, sigma_produced, tau_volumes, produce_errors;
  /* per level, bricks made and those that ended up empty (σt and τ all zero), and the producer-thread
   * seconds on each (the stats' totals are their sums) */
  _Atomic uint64_t level_made[OC_KEY_MAX_LEVEL + 1], level_empty[OC_KEY_MAX_LEVEL + 1];
  _Atomic double level_cpu[OC_KEY_MAX_LEVEL + 1], level_cpu_empty[OC_KEY_MAX_LEVEL + 1];
  _Atomic uint64_t ahead_sigma, ahead_empty;  /* σt sampled ahead, and those all zero */
  _Atomic uint64_t ahead_tau;                 /* τ volumes built ahead */
  _Atomic uint64_t tau_kept;                  /* τ volumes kept from the light stamp before (tau_volume_keep) */
  _Atomic uint64_t sigma_kept;                /* σt kept from the node's step before (sigma_keep) */
  _Atomic double ahead_cpu, ahead_cpu_empty; /* producer-thread seconds on them */
  _Atomic uint64_t stock_sigma, stock_tau;   /* the stock after the last ahead_run(): items, */
  _Atomic double stock_cpu;                  /* and the seconds they took */
  FILE *trace; /* OCS_BRICK_TRACE (trace_made): the timers' intervals, to check against perf */
  pthread_mutex_t trace_mu;
  _Atomic int last_error;
  _Atomic oc_key_t last_error_key;
  uint64_t brick_requests;
  double produce_seconds, plan_seconds, target_seconds;
  ocs_tau_stats_t tau_stats;
  /* per level, a decaying maximum of the seconds one brick took: [0] with its τ volume at hand,
   * [1] when it had to build the volume; production starts no brick expected to end after the
   * deadline (a brick started is finished, and the tick waits for it) */
  _Atomic double cost[OC_KEY_MAX_LEVEL + 1][2];
  ocs_hist_t brick_seconds; /* what each brick made took on its thread (wall), τ included */
  /* sharing bricks between front-ends (world.h, "Sharing bricks") */
  uint64_t weather_hist;     /* the weather changes so far, hashed */
  pthread_mutex_t share_mu;  /* guards hold[] and made[] */
  share_t hold[OCS_HOLD_SLOTS]; /* made by another front-end now: not here until the next tick */
  _Atomic size_t nhold;
  share_t *made;             /* bricks made since the last ocs_world_made_take() */
  size_t nmade, made_cap;
  uint64_t made_dropped;
};

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

static uint64_t mix(uint64_t h, uint64_t v) {
  h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  h *= 0xBF58476D1CE4E5B9ull;
  return h ^ (h >> 31);
}

static uint64_t sun_hash(oc_dvec3 sun) {
  uint64_t h = 0, b;
  const double c[3] = {sun.x, sun.y, sun.z};
  for (int i = 0; i < 3; i++) {
    memcpy(&b, &c[i], 8);
    h = mix(h, b);
  }
  return h;
}

static ocs_cache_key_t ckey(const ocs_world_t *w, int type, uint64_t a, uint64_t b, uint64_t c) {
  return (ocs_cache_key_t){{(w->field_gen << 8) | (uint64_t)type, a, b, c}};
}

/*-*** Content: σt, τ, codes ***/

/* A sampled σt brick as its cache entry: its 512 floats, or one +0 float when all are +0 (most of
 * the bricks the τ columns read at the level above come out so; a whole brick each was a fifth of
 * the cache's memory). The entry's size says which (sigma_entry). */
static float *sigma_pack(float *s, size_t *bytes) {
  if (!oc_all_zero(s, OC_BRICK_VOXELS)) return *bytes = OC_BRICK_VOXELS * sizeof *s, s;
  float *z = realloc(s, sizeof *s);
  *bytes = sizeof *s;
  return z ? z : s;
}

/* A σt entry's 512 floats into out (sigma_pack's one float: all zero). */
static void sigma_copy(const ocs_cache_entry_t *e, float *out) {
  if (ocs_cache_bytes(e) < OC_BRICK_VOXELS * sizeof *out) memset(out, 0, OC_BRICK_VOXELS * sizeof *out);
  else memcpy(out, ocs_cache_data(e), OC_BRICK_VOXELS * sizeof *out);
}

/* The node's σt of its own step before the one `time` is in, copied into s when it is still cached
 * and the source proves the samples the same (ocs_field_same_samples): the step moved with a layer
 * that meets the node's footprint but, by the node's bound, adds nothing to it. @return 1 (kept)
 * or 0 (sample it). */
static int sigma_keep(ocs_world_t *w, oc_key_t key, double time, float s[OC_BRICK_VOXELS]) {
  double t0;
  if (w->keep_sigma_off || !ocs_field_step_before(w->field, key, time, &t0)) return 0;
  ocs_cache_key_t k = ckey(w, T_SIGMA, key, ocs_field_node_step(w->field, key, t0), 0);
  ocs_cache_entry_t *e;
  if (!ocs_cache_peek(w->cache, &k, &e)) return 0;
  int same = ocs_field_same_samples(w->field, key, t0, time);
  if (same) sigma_copy(e, s);
  ocs_cache_release(w->cache, e);
  return same;
}

/* σt samples of a node at its own time step ts (ocs_field_node_step), sampled at world time `time` (any instant of
 * that step: content is a function of the step), through the cache (sanitised); out: a copy, or
 * NULL. @return 1 when made here (sampled, or kept: sigma_keep), 0 when found, or an OC_E*. */
static int sigma_entry(ocs_world_t *w, oc_key_t key, uint64_t ts, double time, float *out) {
  ocs_cache_key_t k = ckey(w, T_SIGMA, key, ts, 0);
  ocs_cache_entry_t *e;
  int r = ocs_cache_acquire(w->cache, &k, &e);
  if (r < 0) return r;
  int sampled = r == OCS_CACHE_MISS;
  if (sampled) {
    float *s = malloc(OC_BRICK_VOXELS * sizeof *s);
    if (!s) {
      ocs_cache_abandon(w->cache, e);
      return OC_ENOMEM;
    }
    memset(s, 0, OC_BRICK_VOXELS * sizeof *s);
    int kept = sigma_keep(w, key, time, s);
    r = kept ? 0 : ocs_field_sample(w->field, key, time, s);
    if (r < 0) {
      free(s);
      ocs_cache_abandon(w->cache, e);
      return r;
    }
    oc_sanitize(s, OC_BRICK_VOXELS, NULL);
    size_t bytes;
    s = sigma_pack(s, &bytes);
    ocs_cache_publish(w->cache, e, s, bytes);
    w->sigma_produced++;
    if (kept) w->sigma_kept++;
  }
  if (out) sigma_copy(e, out);
  ocs_cache_release(w->cache, e);
  return sampled;
}

/* σt samples of a node at this epoch. */
static int sigma_get(prod_t *p, oc_key_t key, float out[OC_BRICK_VOXELS]) {
  int level = oc_key_level(key);
  if (level < 0) return OC_EINVAL;
  int r = sigma_entry(p->w, key, ocs_field_node_step(p->w->field, key, p->time), p->time, out);
  return r < 0 ? r : 0;
}

static int tau_sigma_cb(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]) { return sigma_get(ctx, key, out); }

/* The ground nodes a group volume covers besides those with σt (ocs_tau_desc_t.ground). */
static int tau_ground_cb(void *ctx, oc_key_t key) {
  const ocs_world_t *w = ((const prod_t *)ctx)->w;
  return w->ground_tau && !w->ground_direct && ocs_plan_ground_tau(key);
}

static void tau_bound_cb(void *ctx, oc_key_t key, float *smin, float *smax) {
  const prod_t *p = ctx;
  ocs_field_bound(p->w->field, key, p->time, smin, smax);
}

/* The cache key of key's group volume at light stamp `light`. */
static ocs_cache_key_t tau_key_at(const prod_t *p, oc_key_t key, uint64_t light) {
  return ckey(p->w, T_TAUVOL, ocs_tau_group_of(&p->tau, key), light, ((uint64_t)oc_key_level(key)) | (p->sun_version << 8));
}

static ocs_cache_key_t tau_key(const prod_t *p, oc_key_t key) { return tau_key_at(p, key, p->light[oc_key_level(key)]); }

/* The volume of key's group and level at the light stamp before p's, when its inputs give the same
 * answers at p's time (ocs_tau_volume_unchanged: a build would make it again, bit for bit), copied
 * into *vol. The light stamp moves on with every level the march reads, and for about a third of
 * the planet's volumes what they read did not change (σt that stepped on but came out the same,
 * most often all zero; docs/performance.md, lever 28). @return 1 (kept), 0 (build it), or a
 * negative OC_E*. */
static int tau_volume_keep(prod_t *p, oc_key_t key, void **vol, size_t *bytes) {
  ocs_world_t *w = p->w;
  uint64_t before = p->light_before[oc_key_level(key)];
  if (w->keep_tau_off || !before || before == p->light[oc_key_level(key)]) return 0;
  ocs_cache_key_t k = tau_key_at(p, key, before);
  ocs_cache_entry_t *e;
  if (!ocs_cache_peek(w->cache, &k, &e)) return 0;
  int r = ocs_tau_volume_unchanged(&p->tau, ocs_cache_data(e));
  if (r == 1) {
    *bytes = ocs_cache_bytes(e);
    *vol = malloc(*bytes);
    if (*vol) memcpy(*vol, ocs_cache_data(e), *bytes);
    else r = OC_ENOMEM;
  }
  ocs_cache_release(w->cache, e);
  return r;
}

/* The volume of key's group and level at p's light stamp, pinned in *e: built into the cache when
 * missing (*built = 1). !wait: OCS_CACHE_BUSY, nothing pinned, when another thread is building it. */
static int tau_volume_acquire(prod_t *p, oc_key_t key, int wait, ocs_cache_entry_t **e, int *built) {
  ocs_world_t *w = p->w;
  ocs_cache_key_t k = tau_key(p, key);
  int r = wait ? ocs_cache_acquire(w->cache, &k, e) : ocs_cache_try_acquire(w->cache, &k, e);
  if (r < 0 || r == OCS_CACHE_BUSY) return r;
  if (r == OCS_CACHE_MISS) {
    void *vol = NULL;
    size_t bytes = 0;
    int kept = r = tau_volume_keep(p, key, &vol, &bytes);
    if (r == 0) r = ocs_tau_volume_build(&p->tau, ocs_tau_group_of(&p->tau, key), oc_key_level(key), &vol, &bytes);
    if (r < 0) {
      ocs_cache_abandon(w->cache, *e);
      return r;
    }
    ocs_cache_publish(w->cache, *e, vol, bytes);
    w->tau_volumes++;
    if (kept == 1) w->tau_kept++;
    *built = 1;
  }
  return 0;
}

/* τ of a node from its group's volume, through the cache. !wait: OCS_CACHE_BUSY, and nothing
 * done, when another thread is building that volume. */
static int tau_get(prod_t *p, oc_key_t key, float out[OC_BRICK_VOXELS], int wait, int *built) {
  ocs_world_t *w = p->w;
  ocs_cache_entry_t *e;
  int r = tau_volume_acquire(p, key, wait, &e, built);
  if (r < 0 || r == OCS_CACHE_BUSY) return r;
  r = ocs_tau_volume_lookup(ocs_cache_data(e), key, out);
  ocs_cache_release(w->cache, e);
  /* the volume covers the nodes its march level says may hold σt and the ground that is not
   * proven clear; ground it leaves out was proven clear there (τ = 0), and a wisp the coarser
   * level missed is marched ray by ray */
  if (r != OC_ENOENT) return r;
  if (tau_ground_cb(p, key)) {
    memset(out, 0, OC_BRICK_VOXELS * sizeof *out);
    return 0;
  }
  return ocs_tau_direct(&p->tau, key, out);
}

/* A request's end: τ where it is needed, the codes, published. !wait: OCS_CACHE_BUSY, with the
 * reservation kept, when another thread is building the τ volume. */
static int produce_finish(prod_t *pr, req_t *q, const float sigma[OC_BRICK_VOXELS], int wait) {
  ocs_world_t *w = pr->w;
  float tau[OC_BRICK_VOXELS];
  memset(tau, 0, sizeof tau);
  int any = 0, r = 0;
  for (int j = 0; j < OC_BRICK_VOXELS; j++) any |= sigma[j] > 0.0f;
  /* nothing scatters where σt is all zero: such a node needs no τ and stays empty, unless it holds
   * the ground, which the renderer lights through τ (cloud shadows on the ground) */
  if (w->shadows && (any || (w->ground_tau && ocs_plan_ground_tau(q->key)))) r = tau_get(pr, q->key, tau, wait, &q->built_tau);
  if (r == OCS_CACHE_BUSY) return r;
  payload_t made, *p = NULL;
  if (r >= 0) {
    oc_sanitize(tau, OC_BRICK_VOXELS, NULL);
    made.kind = (uint8_t)oc_brick_encode(sigma, tau, &made.codes, made.range);
    p = payload_copy(&made);
  }
  if (!p) {
    ocs_cache_abandon(w->cache, q->entry);
    q->entry = NULL;
    return r < 0 ? r : OC_ENOMEM;
  }
  q->kind = p->kind;
  ocs_cache_publish(w->cache, q->entry, p, payload_bytes(p->kind));
  q->made = 1;
  w->bricks_produced++;
  return 0;
}

/* Requests are sorted by key, so neighbours share a τ volume (one per group and level, built by
 * the first thread that needs it, in tens of ms). Waiting for another thread's volume cost about a
 * third of two producer threads' time on the planet; a request that would wait keeps its σt and is
 * finished in a second pass (produce_deferred) while the thread goes on to other requests. */
/* What a brick of `key` is expected to cost: the level's estimate, the dearer kind when its group's
 * τ volume is not in the cache yet (it would be built for it). */
static double expected_cost(const prod_t *p, oc_key_t key) {
  ocs_world_t *w = p->w;
  int level = oc_key_level(key), build = 0;
  if (w->shadows) {
    ocs_cache_key_t k = tau_key(p, key);
    ocs_cache_entry_t *e;
    if (ocs_cache_peek(w->cache, &k, &e)) ocs_cache_release(w->cache, e);
    else build = 1;
  }
  return atomic_load_explicit(&w->cost[level][build], memory_order_relaxed);
}

static void learn_cost(ocs_world_t *w, const req_t *q, double seconds) {
  _Atomic double *c = &w->cost[oc_key_level(q->key)][q->built_tau];
  double old = atomic_load_explicit(c, memory_order_relaxed);
  atomic_store_explicit(c, seconds > 0.9 * old ? seconds : 0.9 * old, memory_order_relaxed); /* races only blur it */
}

static int produce_brick_timed(prod_t *p, req_t *q);

/* A brick is started if it is expected to end before the deadline (the tick is due: it waits),
 * or before the bricks already started are expected to end (production ends with them anyway, so
 * an idle producer beside a dear brick keeps working); and one dearer than the whole window (a
 * coarse brick on the planet takes seconds) while the window is young: else it would wait until
 * its estimate faded, for several productions, and the coarse levels a teleport needs first came
 * one every few ticks. It finishes beside the next tick. */
#define OCS_YOUNG_WINDOW 0.25
static int may_start(prod_t *p, oc_key_t key) {
  if (!(p->deadline > 0)) return 1;
  double now = now_s(), cost = expected_cost(p, key), window = p->deadline - p->start;
  double until = atomic_load(&p->busy_until), end = now + cost;
  if (!(end < (until > p->deadline ? until : p->deadline)) &&
      !(cost >= window && now - p->start < OCS_YOUNG_WINDOW * window))
    return 0;
  while (end > until && !atomic_compare_exchange_weak(&p->busy_until, &until, end)) {
  }
  return 1;
}

static int produce_brick(prod_t *p, req_t *q) {
  if (!may_start(p, q->key)) return 0;
  double t0 = now_s();
  int r = produce_brick_timed(p, q);
  if (r >= 0 && q->made) {
    double took = now_s() - t0;
    learn_cost(p->w, q, took);
    ocs_hist_observe(&p->w->brick_seconds, took);
  }
  return r;
}

static int held_back(ocs_world_t *w, oc_key_t key, uint64_t stamp);

static int produce_brick_timed(prod_t *p, req_t *q) {
  ocs_world_t *w = p->w;
  /* production between ticks skips what another front-end is making (it stays queued); a step
   * never does: its states need every request's entry */
  if (p == &w->producing && atomic_load_explicit(&w->nhold, memory_order_relaxed) && held_back(w, q->key, q->stamp))
    return 0;
  ocs_cache_key_t k = ckey(w, T_BRICK, q->key, q->stamp, 0);
  int r = ocs_cache_acquire(w->cache, &k, &q->entry);
  if (r < 0) {
    q->entry = NULL;
    return r;
  }
  if (r == OCS_CACHE_HIT) return 0;
  if (w->d.fault && (r = w->d.fault(w->d.fault_ctx, q->key)) < 0) { /* the test hook */
    ocs_cache_abandon(w->cache, q->entry);
    q->entry = NULL;
    return r;
  }
  float sigma[OC_BRICK_VOXELS];
  float lo, hi;
  ocs_field_bound(w->field, q->key, p->time, &lo, &hi);
  if (!(hi > 0.0f)) { /* known empty: no sampling */
    memset(sigma, 0, sizeof sigma);
  } else if ((r = sigma_get(p, q->key, sigma)) < 0) {
    ocs_cache_abandon(w->cache, q->entry);
    q->entry = NULL;
    return r;
  }
  r = produce_finish(p, q, sigma, 0);
  if (r != OCS_CACHE_BUSY) return r;
  q->sigma = malloc(sizeof sigma);
  if (!q->sigma) return produce_finish(p, q, sigma, 1); /* no room to set it aside: wait */
  memcpy(q->sigma, sigma, sizeof sigma);
  return 0;
}

static void produce_failed(ocs_world_t *w, oc_key_t key, int r) {
  atomic_fetch_add(&w->produce_errors, 1);
  atomic_store(&w->last_error, r);
  atomic_store(&w->last_error_key, key);
}

static void atomic_add_double(_Atomic double *a, double v) {
  double old = atomic_load_explicit(a, memory_order_relaxed);
  while (!atomic_compare_exchange_weak_explicit(a, &old, old + v, memory_order_relaxed, memory_order_relaxed)) {
  }
}

/* The calling thread's kernel id (what perf reports), read once per thread. */
static int thread_id(void) {
  static _Thread_local int tid;
  char buf[64];
  ssize_t n;
  if (!tid && (n = readlink("/proc/thread-self", buf, sizeof buf - 1)) > 0) {
    buf[n] = 0;
    const char *slash = strrchr(buf, '/');
    tid = slash ? atoi(slash + 1) : -1;
  }
  return tid;
}

/* OCS_BRICK_TRACE=FILE: one line per interval the wasted-work timers count, "<tid> <start> <end>
 * <wasted> <due>" (CLOCK_MONOTONIC seconds, the timers' clock, which `perf record -k
 * CLOCK_MONOTONIC` stamps its samples with), so that scripts/waste_perf.sh can attribute perf's
 * samples to them. due: the world time an ahead item's content comes due, "-" for a brick made
 * for its epoch; the world's last line, "now <world time>", tells which were still stock. */
static void trace_interval(ocs_world_t *w, int tid, double t0, double t1, int wasted, double due) {
  if (!w->trace) return;
  char d[32] = "-";
  if (isfinite(due)) snprintf(d, sizeof d, "%.9f", due);
  pthread_mutex_lock(&w->trace_mu);
  fprintf(w->trace, "%d %.9f %.9f %d %s\n", tid, t0, t1, wasted, d);
  pthread_mutex_unlock(&w->trace_mu);
}

/* A made brick's intervals, once it is known whether it is wasted. */
static void trace_made(ocs_world_t *w, const req_t *q, double since, double now) {
  if (!w->trace) return;
  if (q->pass0[1] > 0.0) trace_interval(w, q->pass0_tid, q->pass0[0], q->pass0[1], q->kind == OC_NODE_EMPTY, NAN);
  trace_interval(w, thread_id(), since, now, q->kind == OC_NODE_EMPTY, NAN);
}

/* What a made brick took on its producer thread (wall time: a thread's CPU clock is a system call,
 * which cost a tenth of production), and whether that was spent on nothing (issue 17's wasted
 * work). */
static void account_cpu(ocs_world_t *w, req_t *q, double since) {
  double now = now_s();
  q->cpu += now - since;
  if (q->sigma && w->trace) { /* set aside: its second pass counts it */
    q->pass0[0] = since, q->pass0[1] = now;
    q->pass0_tid = thread_id();
  }
  if (!q->made || q->sigma) return;
  trace_made(w, q, since, now);
  int l = oc_key_level(q->key);
  atomic_add_double(&w->level_cpu[l], q->cpu);
  atomic_fetch_add_explicit(&w->level_made[l], 1, memory_order_relaxed);
  if (q->kind == OC_NODE_EMPTY) {
    atomic_add_double(&w->level_cpu_empty[l], q->cpu);
    atomic_fetch_add_explicit(&w->level_empty[l], 1, memory_order_relaxed);
  }
}

static int produce_one(void *ctx, size_t i, int worker) {
  prod_t *p = ctx;
  (void)worker;
  double c0 = now_s();
  int r = produce_brick(p, &p->req[i]);
  account_cpu(p->w, &p->req[i], c0);
  if (r < 0) produce_failed(p->w, p->req[i].key, r);
  return r;
}

static int produce_deferred(void *ctx, size_t i, int worker) {
  (void)worker;
  prod_t *p = ctx;
  req_t *q = &p->req[p->deferred[i]];
  double c0 = now_s();
  int r = produce_finish(p, q, q->sigma, 1);
  free(q->sigma);
  q->sigma = NULL;
  account_cpu(p->w, q, c0);
  if (r < 0) produce_failed(p->w, q->key, r);
  return r;
}

/* Production's copy of the world's clock and sun. */
static void prod_snapshot(ocs_world_t *w, prod_t *p) {
  p->w = w;
  p->time = w->time;
  memcpy(p->ts, w->ts, sizeof p->ts);
  memcpy(p->light, w->light, sizeof p->light);
  memcpy(p->light_before, w->light_before, sizeof p->light_before);
  p->sun_version = w->sun_version;
  p->tau = w->tau;
  p->tau.ctx = p;
  p->deadline = p->start = 0;
}

static void prod_free(prod_t *p) {
  free(p->req);
  free(p->deferred);
  free(p->who);
}

/*-*** Clock ***/

/* Every level's time step, stamp and light stamp at world time t. A level's stamp covers the time
 * steps of levels 0 … it; its light stamp those of what its τ reads, levels 0 … its march level
 * (ocs_tau_march_level: the level itself up to level 6, the one above below). Keyed by the levels
 * above only, a τ volume of levels ≤ 6 outlived its own level's step: new σt went out with the old
 * τ, content no time step makes (overcast-stress --verify-content: level-6 mismatches). */
static void stamps_at(const ocs_world_t *w, double t, uint64_t ts[], uint64_t stamp[], uint64_t light[]) {
  uint64_t base = mix((uint64_t)w->shadows, w->shadows ? w->sun_version : 0), h = base;
  uint64_t cum[OC_KEY_MAX_LEVEL + 1];
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    uint64_t s = ocs_field_time_step(w->field, l, t);
    if (ts) ts[l] = s;
    h = mix(h, s);
    cum[l] = h;
    if (stamp) stamp[l] = h;
  }
  for (int l = 0; light && l <= OC_KEY_MAX_LEVEL; l++) {
    int m = ocs_tau_march_level(&w->tau, l);
    light[l] = m < 0 ? base : cum[m]; /* m ≤ l */
  }
}

/* Production's view of the world at a later world time t (the same sun): what τ ahead builds from. */
static void prod_snapshot_at(ocs_world_t *w, prod_t *p, double t) {
  prod_snapshot(w, p);
  p->time = t;
  memcpy(p->light_before, w->light, sizeof p->light_before); /* ahead builds for the first change after now */
  stamps_at(w, t, p->ts, NULL, p->light);
}

#define OCS_RATE_EPOCHS 64

/* The first two epochs (1 … OCS_RATE_EPOCHS) at which a stamp changes. @return 1 when k is the first. */
static int note_change(int k, int *first, int *second) {
  if (!*first) return *first = k, 1;
  if (!*second) *second = k;
  return 0;
}

/* Work for a change `first` epochs away is spread over those epochs when the stamp it brings lasts
 * two epochs or more (one of one epoch has nothing to spread), and it is at most OCS_AHEAD_EPOCHS
 * away (the farther, the likelier the tree has moved on by then): first, or 0. */
#define OCS_AHEAD_EPOCHS 16
static uint32_t epochs_to_spread(int first, int second) {
  int lasts = second ? second - first : OCS_RATE_EPOCHS + 1 - first;
  return first && first <= OCS_AHEAD_EPOCHS && lasts >= 2 ? (uint32_t)first : 0;
}

/* The stamps at the world's time, remembering those they replace. */
static void clock_stamps(ocs_world_t *w) {
  uint64_t stamp[OC_KEY_MAX_LEVEL + 1], light[OC_KEY_MAX_LEVEL + 1];
  stamps_at(w, w->time, w->ts, stamp, light);
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    if (w->light[l] && w->light[l] != light[l]) w->light_before[l] = w->light[l];
    w->light[l] = light[l];
    if (w->stamp[l] && w->stamp[l] != stamp[l]) { /* the level's content moves on: remember the old */
      memmove(&w->stamp_hist[l][1], &w->stamp_hist[l][0], (OCS_STAMP_HISTORY - 1) * sizeof w->stamp_hist[l][0]);
      w->stamp_hist[l][0] = w->stamp[l];
    }
    w->stamp[l] = stamp[l];
  }
}

static void clock_update(ocs_world_t *w) {
  clock_stamps(w);
  /* refresh rate: the share of the next OCS_RATE_EPOCHS epochs that change each level's stamp.
   * Over 8, a level stepping every 16 s read 0 or 1/8 by turns, and the plans' steady cost (each
   * brick weighed by 1 + (K - 1) x rate) moved with it from one tick to the next. */
  double dt = w->scene.epoch_period * ocs_clock_scale(&w->clock, w->utc);
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) w->rate[l] = 0.0;
  memset(w->ahead_in, 0, sizeof w->ahead_in);
  memset(w->light_in, 0, sizeof w->light_in);
  if (!ocs_field_animated(w->field) || !(dt > 0.0)) return;
  uint64_t prev[OC_KEY_MAX_LEVEL + 1], next[OC_KEY_MAX_LEVEL + 1], ts[OC_KEY_MAX_LEVEL + 1], light[OC_KEY_MAX_LEVEL + 1];
  uint64_t ts_prev[OC_KEY_MAX_LEVEL + 1], light_prev[OC_KEY_MAX_LEVEL + 1];
  int first[OC_KEY_MAX_LEVEL + 1] = {0}, second[OC_KEY_MAX_LEVEL + 1] = {0};
  int lfirst[OC_KEY_MAX_LEVEL + 1] = {0}, lsecond[OC_KEY_MAX_LEVEL + 1] = {0};
  memcpy(prev, w->stamp, sizeof prev);
  memcpy(ts_prev, w->ts, sizeof ts_prev);
  memcpy(light_prev, w->light, sizeof light_prev);
  for (int k = 1; k <= OCS_RATE_EPOCHS; k++) {
    double t = w->time + k * dt;
    stamps_at(w, t, ts, next, light);
    for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
      if (next[l] != prev[l]) w->rate[l] += 1.0 / OCS_RATE_EPOCHS;
      prev[l] = next[l];
      if (ts[l] != ts_prev[l] && note_change(k, &first[l], &second[l])) { /* its next step: σt ahead */
        w->ahead_ts[l] = ts[l];
        w->ahead_t[l] = t;
      }
      if (light[l] != light_prev[l] && note_change(k, &lfirst[l], &lsecond[l])) w->light_t[l] = t; /* next light: τ ahead */
      ts_prev[l] = ts[l];
      light_prev[l] = light[l];
    }
  }
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    w->ahead_in[l] = epochs_to_spread(first[l], second[l]);
    w->light_in[l] = epochs_to_spread(lfirst[l], lsecond[l]);
  }
}

static void queue_forget(ocs_world_t *w, uint32_t vi);

/*-*** World ***/

int ocs_world_create(ocs_world_t **out, const oc_scene_t *scene, const ocs_world_desc_t *desc, char *why, size_t why_len) {
  if (!out || !scene) return OC_EINVAL;
  *out = NULL;
  ocs_world_t *w = calloc(1, sizeof *w);
  if (!w) return OC_ENOMEM;
  if (desc) w->d = *desc;
  ocs_hist_init(&w->brick_seconds, ocs_hist_seconds);
  if (!w->d.cache_bytes) w->d.cache_bytes = 256ull << 20;
  if (!w->d.viewer_bytes) w->d.viewer_bytes = 4ull << 30;
  if (!w->d.max_budget) w->d.max_budget = ocs_world_fair_share(w->d.viewer_bytes);
  if (w->d.max_budget > w->d.viewer_bytes) w->d.max_budget = w->d.viewer_bytes;
  if (w->d.max_viewers <= 0) w->d.max_viewers = 64;
  int r = oc_scene_copy(&w->scene, scene);
  if (r < 0) {
    free(w);
    return r;
  }
  if ((r = ocs_field_create(&w->field, &w->scene, why, why_len)) < 0 || (r = ocs_cache_create(&w->cache, w->d.cache_bytes)) < 0 ||
      (r = ocs_pool_create_niced(&w->pool, w->d.threads, w->d.clocked ? OCS_PRODUCER_NICE : 0)) < 0) {
    if (why && r != OC_ESCENE && r != OC_ENOENT && r != OC_EIO && r != OC_ECORRUPT && r != OC_ERANGE)
      snprintf(why, why_len, "creating the world: %s", oc_strerror(r));
    ocs_world_free(w);
    return r;
  }
  if (w->d.exact_filter) ocs_field_set_exact(w->field, 1);
  pthread_mutex_init(&w->tick_mu, NULL);
  pthread_mutex_init(&w->share_mu, NULL);
  if (w->d.clocked && ocs_pool_threads(w->pool) > 1 && ocs_pool_create(&w->tick_pool, 2) < 0) w->tick_pool = NULL; /* serial */
  w->K = ocs_field_animated(w->field) ? 3 : 2;
  w->shadows = oc_scene_has(&w->scene, OC_FEATURE_SHADOWS);
  w->ground_tau = w->shadows && oc_scene_has(&w->scene, OC_FEATURE_PLANET_SURFACE);
  const char *env = getenv("OCS_TAU_GROUND_DIRECT");
  w->ground_direct = env && strcmp(env, "1") == 0;
  env = getenv("OCS_AHEAD");
  w->ahead_off = env && strcmp(env, "0") == 0;
  env = getenv("OCS_TAU_KEEP");
  w->keep_tau_off = env && strcmp(env, "0") == 0;
  env = getenv("OCS_SIGMA_KEEP");
  w->keep_sigma_off = env && strcmp(env, "0") == 0;
  pthread_mutex_init(&w->trace_mu, NULL);
  env = getenv("OCS_BRICK_TRACE");
  if (env && *env && !(w->trace = fopen(env, "w"))) oc_log_warn("OCS_BRICK_TRACE: cannot write %s: %s", env, strerror(errno));
  w->field_gen = 1;
  w->utc = isfinite(w->d.start_utc) ? w->d.start_utc : 0.0;
  w->time = isfinite(w->d.time) ? w->d.time : 0.0;
  ocs_clock_init(&w->clock, w->utc, w->time);
  w->sun = w->scene.sun_dir;
  w->sun_version = sun_hash(w->sun);
  w->tau = (ocs_tau_desc_t){
      .sigma = tau_sigma_cb, .bound = tau_bound_cb, .ground = tau_ground_cb, .sun_dir = w->sun, .stats = &w->tau_stats};
  clock_update(w);
  *out = w;
  return 0;
}

void ocs_world_free(ocs_world_t *w) {
  if (!w) return;
  while (w->nviewers) ocs_world_remove_viewer(w, w->viewers[w->nviewers - 1]);
  if (w->in_production) ocs_world_produce_end(w);
  free(w->viewers);
  prod_free(&w->stepping);
  prod_free(&w->producing);
  free(w->pins);
  free(w->wish);
  free(w->queue);
  free(w->ahead);
  free(w->stock);
  ocs_pool_free(w->pool);
  ocs_pool_free(w->tick_pool);
  pthread_mutex_destroy(&w->tick_mu); /* calloc'd zeros are glibc's static initialiser, also before init */
  pthread_mutex_destroy(&w->share_mu);
  if (w->trace) {
    fprintf(w->trace, "now %.9f\n", w->time); /* ahead's intervals due after it were its stock */
    fclose(w->trace);
  }
  pthread_mutex_destroy(&w->trace_mu);
  free(w->made);
  ocs_cache_free(w->cache);
  ocs_field_free(w->field);
  oc_scene_free(&w->scene);
  free(w);
}

const oc_scene_t *ocs_world_scene(const ocs_world_t *w) { return &w->scene; }
int ocs_world_kept_states(const ocs_world_t *w) { return w->K; }
oc_dvec3 ocs_world_sun(const ocs_world_t *w) { return w->sun; }
const struct ocs_field_s *ocs_world_field(const ocs_world_t *w) { return w->field; }

int ocs_world_set_sun(ocs_world_t *w, oc_dvec3 sun) {
  double l = oc_dlen(sun);
  if (!w || !isfinite(l) || !(l > 0.0)) return OC_EINVAL;
  w->sun = oc_dscale(sun, 1.0 / l);
  w->tau.sun_dir = w->sun;
  w->sun_version = sun_hash(w->sun);
  clock_update(w);
  return 0;
}

/* A control change took effect: the last epoch's world time is W(its instant) again (a change at
 * that very instant, as stepped mode makes them, shows at once). */
static int clock_changed(ocs_world_t *w, int r) {
  if (r < 0) return r;
  w->time = ocs_clock_world(&w->clock, w->utc);
  clock_update(w);
  return 0;
}

int ocs_world_set_time(ocs_world_t *w, double utc, double t) {
  if (!w || !isfinite(t)) return OC_EINVAL;
  return clock_changed(w, ocs_clock_set(&w->clock, utc, t, NAN));
}

int ocs_world_set_time_scale(ocs_world_t *w, double utc, double scale) {
  if (!w || !isfinite(scale)) return OC_EINVAL;
  return clock_changed(w, ocs_clock_set(&w->clock, utc, NAN, scale));
}

int ocs_world_set_origin(ocs_world_t *w, double utc, double t) {
  if (!w || !isfinite(utc) || !(fabs(t) <= 1e12)) return OC_EINVAL;
  ocs_clock_init(&w->clock, utc, t);
  return clock_changed(w, 0);
}

int ocs_world_pause(ocs_world_t *w, double utc) { return w ? clock_changed(w, ocs_clock_pause(&w->clock, utc)) : OC_EINVAL; }
int ocs_world_resume(ocs_world_t *w, double utc) { return w ? clock_changed(w, ocs_clock_resume(&w->clock, utc)) : OC_EINVAL; }

double ocs_world_utc(const ocs_world_t *w) { return w->utc; }
uint64_t ocs_world_epoch(const ocs_world_t *w) { return w->epoch; }
double ocs_world_time_at(const ocs_world_t *w, double utc) { return ocs_clock_world(&w->clock, utc); }
void ocs_world_carry_clock(ocs_world_t *to, const ocs_world_t *from) {
  to->clock = from->clock;
  to->epoch = from->epoch;
  to->utc = from->utc;
  clock_changed(to, 0);
}

int ocs_world_set_weather(ocs_world_t *w, double utc, oc_preset_t preset, double seconds) {
  if (!w) return OC_EINVAL;
  double t0 = ocs_clock_world(&w->clock, utc);
  OC_TRY(ocs_field_set_weather(w->field, preset, t0, seconds));
  uint64_t b[2];
  memcpy(&b[0], &t0, 8);
  memcpy(&b[1], &seconds, 8);
  w->weather_hist = mix(mix(mix(w->weather_hist, (uint64_t)preset), b[0]), b[1]);
  clock_update(w);
  return 0;
}

/*-*** Viewers ***/

uint64_t ocs_world_total_budget(const ocs_world_t *w) { return w->d.viewer_bytes; }

uint64_t ocs_world_fair_share(uint64_t total) {
  uint64_t q = total / 4;
  return q < OCS_FAIR_SHARE_MAX ? q : OCS_FAIR_SHARE_MAX;
}

void ocs_world_admission(const ocs_world_t *w, const ocs_plan_desc_t *req, ocs_admission_t *out) {
  ocs_plan_desc_t d = *req;
  d.kept_states = w->K;
  memset(out, 0, sizeof *out);
  out->max_budget = w->d.max_budget;
  out->left = w->d.viewer_bytes - w->granted;
  out->viewers_left = w->d.max_viewers - w->nviewers;
  if (ocs_plan_clamp(&d, w->d.max_budget) == 0) out->wanted = d.budget;
  out->minimum = ocs_plan_min_budget(&d);
}

int ocs_world_add_viewer(ocs_world_t *w, const ocs_plan_desc_t *req, ocs_viewer_t **out, ocs_plan_desc_t *granted,
                         char *why, size_t why_len) {
  if (!w || !req || !out) return OC_EINVAL;
  *out = NULL;
  if (w->nviewers >= w->d.max_viewers) {
    if (why) snprintf(why, why_len, "server full: %d viewers", w->nviewers);
    return OC_ETOOBIG;
  }
  ocs_plan_desc_t d = *req;
  d.kept_states = w->K;
  ocs_plan_desc_t full = d; /* what it would get with room: a later raise may give it */
  uint64_t ask = ocs_plan_clamp(&full, w->d.max_budget) == 0 ? full.budget : 0;
  uint64_t left = w->d.viewer_bytes - w->granted;
  uint64_t cap = left < w->d.max_budget ? left : w->d.max_budget;
  int r = ocs_plan_clamp(&d, cap);
  if (r < 0) {
    if (why)
      snprintf(why, why_len, "server full: %llu bytes of viewer budget left, the minimum is %llu",
               (unsigned long long)cap, (unsigned long long)ocs_plan_min_budget(&d));
    return OC_ERANGE;
  }
  ocs_viewer_t **a = oc_grow(w->viewers, &w->viewers_cap, (size_t)w->nviewers, sizeof *a, 8);
  if (!a) return OC_ENOMEM;
  w->viewers = a;
  ocs_viewer_t *v = calloc(1, sizeof *v);
  if (!v) return OC_ENOMEM;
  v->steady = 1.0; /* until its view jumps */
  v->w = w;
  v->desc = d;
  v->acked = UINT64_MAX;
  v->next_id = 1;
  for (int i = 0; i < OCS_PLAN_MAX_KEPT; i++) oc_state_init(&v->held[i]);
  oc_state_init(&v->spare);
  if ((r = ocs_planner_create(&v->planner, &d)) < 0) {
    free(v);
    return r;
  }
  w->viewers[w->nviewers++] = v;
  v->ask = ask > d.budget ? ask : d.budget;
  v->reserved = d.budget;
  w->granted += d.budget;
  if (granted) *granted = d;
  *out = v;
  return 0;
}

void ocs_world_remove_viewer(ocs_world_t *w, ocs_viewer_t *v) {
  if (!w || !v) return;
  for (int i = 0; i < w->nviewers; i++)
    if (w->viewers[i] == v) {
      queue_forget(w, (uint32_t)i);
      for (size_t j = 0; j < w->producing.nwho; j++) /* production goes on without it */
        if (w->producing.who[j] == v) w->producing.who[j] = NULL;
      memmove(&w->viewers[i], &w->viewers[i + 1], (size_t)(w->nviewers - i - 1) * sizeof *w->viewers);
      w->nviewers--;
      w->granted -= v->reserved;
      break;
    }
  ocs_planner_free(v->planner);
  for (int i = 0; i < OCS_PLAN_MAX_KEPT; i++) oc_state_free(&v->held[i]);
  oc_state_free(&v->spare);
  free(v->lacking);
  free(v->req_of);
  free(v->target);
  free(v);
}

int ocs_viewer_set_view(ocs_viewer_t *v, const ocs_view_t *view) {
  if (!v || !ocs_view_valid(view)) return OC_EINVAL;
  v->view = *view;
  v->has_view = 1;
  return 0;
}

int ocs_viewer_ack(ocs_viewer_t *v, uint64_t epoch) {
  if (!v || !v->unacked || epoch != v->in_flight) return OC_EINVAL;
  v->unacked = 0;
  v->acked = epoch;
  return 0;
}

int ocs_viewer_output(const ocs_viewer_t *v, ocs_epoch_out_t *out) {
  if (!v || !out) return OC_EINVAL;
  if (!v->nheld) return OC_ENOENT;
  out->state = &v->held[0];
  out->lacking = v->lacking;
  out->nlacking = v->nlacking;
  out->plan = v->plan;
  return 0;
}

void ocs_viewer_stats(const ocs_viewer_t *v, ocs_viewer_stats_t *out) {
  memset(out, 0, sizeof *out);
  if (!v) return;
  out->epochs_sent = v->sent;
  out->coalesced = v->coalesced;
  out->acked = v->acked;
  out->budget = v->desc.budget;
  out->reserved = v->reserved;
  out->produced = v->produced_last;
  memcpy(out->age_p50, v->age_p50, sizeof out->age_p50);
  memcpy(out->age_p99, v->age_p99, sizeof out->age_p99);
  const oc_state_t *s[OCS_PLAN_MAX_KEPT];
  for (int i = 0; i < v->nheld; i++) s[i] = &v->held[i];
  out->resident_bytes = oc_resident_bytes(s, v->nheld, v->desc.slot_bytes, v->desc.record_bytes);
}

const oc_state_t *ocs_viewer_held(const ocs_viewer_t *v, int i) {
  return v && i >= 0 && i < v->nheld ? &v->held[i] : NULL;
}

int ocs_viewer_in_flight(const ocs_viewer_t *v) { return v && v->unacked; }

/*-*** Epochs ***/

/* For OCS_JUMP_TICKS ticks after its view jumped, a clocked viewer's plans split up to this many
 * times the stepped cap: they take a split only when its children exist, so production paces them;
 * with the stepped cap a clocked tree took 12-15 ticks to full detail after a 4 MiB teleport where
 * the stepped server takes 10 epochs (the cap every epoch, and a tick or two waiting for the coarse
 * content). Not always: trees that grow twice as fast make ticks that outgrow their lead (64 MiB,
 * four viewers cruising and orbiting: lateness p99 14 -> 214 ms). */
#define OCS_CLOCKED_SPLIT_SCALE 2.0
#define OCS_JUMP_TICKS 16

static double split_scale(const ocs_world_t *w, const ocs_viewer_t *v) {
  return w->epoch < v->jumped_at + OCS_JUMP_TICKS ? OCS_CLOCKED_SPLIT_SCALE : 1.0;
}

/* What a plan's callbacks are given: the world, and the viewer planned (its wishes are tagged). */
typedef struct {
  ocs_world_t *w;
  uint32_t viewer;
} plan_ctx_t;

static oc_node_kind_t classify_cb(void *ctx, oc_key_t key) {
  const ocs_world_t *w = ((const plan_ctx_t *)ctx)->w;
  float lo, hi;
  ocs_field_bound(w->field, key, w->time, &lo, &hi);
  if (!(hi > 0.0f)) return OC_NODE_EMPTY;
  if (lo == hi) return OC_NODE_UNIFORM;
  return OC_NODE_BRICK;
}

/* Builds viewer v's state from its plan: produced content from the requests, held content copied. */
static int build_state(ocs_world_t *w, ocs_viewer_t *v, oc_state_t *st, uint8_t *kinds, uint32_t *ids) {
  st->epoch = w->epoch;
  st->time = w->time;
  st->sun_dir = w->sun;
  v->nlacking = 0;
  for (uint32_t i = 0; i < v->nleaves; i++) {
    const ocs_plan_leaf_t *L = &v->leaves[i];
    oc_node_t n;
    memset(&n, 0, sizeof n);
    n.key = L->key;
    if (L->produce) {
      const payload_t *p = ocs_cache_data(w->stepping.req[v->req_of[i]].entry);
      n.kind = p->kind;
      n.range[0] = p->range[0];
      n.range[1] = p->range[1];
      if (p->kind == OC_NODE_BRICK) {
        n.brick_id = v->next_id++;
        OC_TRY(oc_state_add_brick(st, n.brick_id, &p->codes));
        if (v->nlacking == v->lacking_cap) {
          uint32_t nc = v->lacking_cap ? 2 * v->lacking_cap : 256;
          uint32_t *a = realloc(v->lacking, nc * sizeof *a);
          if (!a) return OC_ENOMEM;
          v->lacking = a;
          v->lacking_cap = nc;
        }
        v->lacking[v->nlacking++] = n.brick_id;
      }
    } else {
      const oc_state_t *h = &v->held[L->held - 1];
      int64_t j = L->held >= 1 && L->held <= v->nheld ? oc_state_find_node(h, L->key) : -1;
      if (j < 0) return OC_ECORRUPT; /* the planner and the held states disagree: a bug */
      n = h->nodes[j];
      if (n.kind == OC_NODE_BRICK) {
        const oc_brick_t *b = oc_state_find_brick(h, n.brick_id);
        if (!b) return OC_ECORRUPT;
        OC_TRY(oc_state_add_brick(st, n.brick_id, &b->codes));
      }
    }
    OC_TRY(oc_state_add_node(st, &n));
    kinds[i] = n.kind;
    ids[i] = n.brick_id;
  }
  oc_state_canonicalize(st);
  if (w->d.validate) {
    char why[256];
    if (oc_state_validate(st, why, sizeof why) < 0) {
      fprintf(stderr, "world: invalid state for a viewer: %s\n", why);
      return OC_ECORRUPT;
    }
  }
  return 0;
}

static void release_requests(prod_t *p) {
  for (size_t i = 0; i < p->nreq; i++)
    if (p->req[i].entry) ocs_cache_release(p->w->cache, p->req[i].entry);
  p->nreq = 0;
}

static int step(ocs_world_t *w);

int ocs_world_step(ocs_world_t *w) {
  if (!w) return OC_EINVAL;
  return ocs_world_step_at(w, w->epoch + 1, (double)(w->epoch + 1) * w->scene.epoch_period);
}

int ocs_world_step_at(ocs_world_t *w, uint64_t epoch, double utc) {
  if (!w || epoch <= w->epoch || !isfinite(utc)) return OC_EINVAL;
  w->epoch = epoch;
  w->utc = utc;
  w->time = ocs_clock_world(&w->clock, utc);
  clock_update(w);
  return step(w);
}

/*-*** Clocked epochs: content that exists, and what is wanted ***/

/* The planner's ready(): the stamp of existing content of (key), this epoch's or one of the last
 * OCS_READY_AGE of its level, newer than the one it shows (the history is newest first: a
 * refresh stops at `held`, never going back in time, and a waiting refresh costs one look, not
 * three), pinned until the tick's states are built (nothing is produced during a tick, but pins
 * keep that true whatever the cache does). */
static uint64_t ready_cb(void *ctx, oc_key_t key, int level, uint64_t stamp, uint64_t held, uint8_t *kind) {
  ocs_world_t *w = ((plan_ctx_t *)ctx)->w;
  for (int i = -1; i < OCS_READY_AGE; i++) {
    uint64_t st = i < 0 ? stamp : w->stamp_hist[level][i];
    if (held && st == held) return 0;
    if (!st || (i >= 0 && st == stamp)) continue;
    ocs_cache_key_t k = ckey(w, T_BRICK, key, st, 0);
    ocs_cache_entry_t *e;
    if (!ocs_cache_peek(w->cache, &k, &e)) continue;
    pthread_mutex_lock(&w->tick_mu);
    ocs_cache_entry_t **a = oc_grow(w->pins, &w->pins_cap, w->npins, sizeof *a, 1024);
    if (!a) {
      pthread_mutex_unlock(&w->tick_mu);
      ocs_cache_release(w->cache, e);
      return 0; /* treated as not ready */
    }
    w->pins = a;
    w->pins[w->npins++] = e;
    pthread_mutex_unlock(&w->tick_mu);
    *kind = ((const payload_t *)ocs_cache_data(e))->kind;
    return st;
  }
  return 0;
}

/* The planner's want(): kept for the production queue, with the viewer being planned. */
static void want_cb(void *ctx, oc_key_t key, uint64_t stamp, double prio) {
  const plan_ctx_t *c = ctx;
  ocs_world_t *w = c->w;
  pthread_mutex_lock(&w->tick_mu);
  wish_t *a = oc_grow(w->wish, &w->wish_cap, w->nwish, sizeof *a, 1024);
  if (!a) { /* asked again next tick */
    pthread_mutex_unlock(&w->tick_mu);
    return;
  }
  w->wish = a;
  w->wish[w->nwish++] = (wish_t){key, stamp, prio > 0 ? prio : 0.0, 0.0, c->viewer};
  pthread_mutex_unlock(&w->tick_mu);
}

static void release_pins(ocs_world_t *w) {
  for (size_t i = 0; i < w->npins; i++) ocs_cache_release(w->cache, w->pins[i]);
  w->npins = 0;
}

static int cmp_wish_key(const void *a, const void *b) {
  const wish_t *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return x->stamp < y->stamp ? -1 : (x->stamp > y->stamp);
}

static int cmp_wish_prio(const void *a, const void *b) {
  const wish_t *x = a, *y = b;
  if (x->prio != y->prio) return x->prio > y->prio ? -1 : 1;
  return cmp_wish_key(a, b);
}

static int cmp_wish_viewer(const void *a, const void *b) {
  int c = cmp_wish_key(a, b);
  if (c) return c;
  const wish_t *x = a, *y = b;
  return x->viewer < y->viewer ? -1 : (x->viewer > y->viewer);
}

static int cmp_queued_turn(const void *a, const void *b) {
  const queued_t *x = a, *y = b;
  if (x->turn != y->turn) return x->turn < y->turn ? -1 : 1;
  if (x->prio != y->prio) return x->prio > y->prio ? -1 : 1;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return x->stamp < y->stamp ? -1 : (x->stamp > y->stamp);
}

/* Sorts the wishes by (key, stamp, viewer) and keeps one per viewer and brick, the best; the
 * wishes of viewers that left since the tick (queue_forget) go. */
static void wishes_dedup(ocs_world_t *w) {
  size_t kept = 0;
  for (size_t i = 0; i < w->nwish; i++)
    if (w->wish[i].viewer != OCS_NO_VIEWER) w->wish[kept++] = w->wish[i];
  w->nwish = kept;
  if (!w->nwish) return;
  qsort(w->wish, w->nwish, sizeof *w->wish, cmp_wish_viewer);
  size_t m = 0;
  for (size_t i = 0; i < w->nwish; i++) {
    wish_t *last = m ? &w->wish[m - 1] : NULL;
    if (last && !cmp_wish_viewer(last, &w->wish[i])) {
      if (w->wish[i].prio > last->prio) last->prio = w->wish[i].prio;
    } else {
      w->wish[m++] = w->wish[i];
    }
  }
  w->nwish = m;
}

/* The wish of viewer vi for node key (any stamp) in the wishes sorted by brick, or -1. */
static ptrdiff_t wish_find(const ocs_world_t *w, oc_key_t key, uint32_t vi) {
  size_t lo = 0, hi = w->nwish;
  while (lo < hi) { /* the first wish with key >= key */
    size_t mid = lo + (hi - lo) / 2;
    if (w->wish[mid].key < key) lo = mid + 1;
    else hi = mid;
  }
  for (size_t i = lo; i < w->nwish && w->wish[i].key == key; i++)
    if (w->wish[i].viewer == vi) return (ptrdiff_t)i;
  return -1;
}

typedef struct {
  int level;
  size_t i;
} by_level_t;

static int cmp_level_desc(const void *a, const void *b) {
  const by_level_t *x = a, *y = b;
  if (x->level != y->level) return x->level > y->level ? -1 : 1;
  return x->i < y->i ? -1 : (x->i > y->i);
}

/* Coarse before fine: a wished node is worth at least what its wished descendants are (a tick can
 * show them only after it), so each wish passes its priority up to the nearest wished ancestor of
 * the same viewer, deepest first. Ties go to the coarser node (the smaller key). */
static void wishes_inherit(ocs_world_t *w) {
  by_level_t *order = w->nwish ? malloc(w->nwish * sizeof *order) : NULL;
  if (!order) return; /* without it the queue is only less well ordered */
  for (size_t i = 0; i < w->nwish; i++) order[i] = (by_level_t){oc_key_level(w->wish[i].key), i};
  qsort(order, w->nwish, sizeof *order, cmp_level_desc);
  for (size_t j = 0; j < w->nwish; j++) {
    const wish_t *x = &w->wish[order[j].i];
    for (oc_key_t a = oc_key_parent(x->key); a != OC_KEY_INVALID; a = oc_key_parent(a)) {
      ptrdiff_t p = wish_find(w, a, x->viewer);
      if (p < 0) continue;
      if (w->wish[p].prio < x->prio) w->wish[p].prio = x->prio;
      break;
    }
  }
  free(order);
}

/* A jump: the view moved more than a quarter of its altitude (at least OCS_JUMP_MOVE_M) or turned
 * more than 10° since `from`. */
#define OCS_JUMP_MOVE_M 250.0
#define OCS_JUMP_TURN_COS 0.985 /* 10° */
static int view_jumped(const ocs_view_t *from, const ocs_view_t *to) {
  double alt = oc_dlen(to->pos) - OC_PLANET_RADIUS, move = 0.25 * alt;
  if (move < OCS_JUMP_MOVE_M) move = OCS_JUMP_MOVE_M;
  return oc_dlen(oc_dsub(from->pos, to->pos)) > move || oc_ddot(from->forward, to->forward) < OCS_JUMP_TURN_COS;
}

/* How steady each viewer is: a running mean (halved each production) of the productions at which
 * its view had not jumped since the last. One that teleports every tick is served after the
 * steady ones: little of what it wants now is still wanted when it is made. (Measured on the
 * wishes instead, a viewer arriving somewhere new counted as steady: its coarse wishes share
 * parents with those of where it was.) */
static void viewers_steadiness(ocs_world_t *w) {
  for (int vi = 0; vi < w->nviewers; vi++) {
    ocs_viewer_t *v = w->viewers[vi];
    if (!v->has_view) continue;
    int jumped = v->has_steady_view && view_jumped(&v->steady_view, &v->view);
    v->steady = 0.5 * v->steady + 0.5 * (jumped ? 0.0 : 1.0);
    v->steady_view = v->view;
    v->has_steady_view = 1;
  }
}

/* Each viewer's wishes cut to its share of the queue (its best ones) and normalised to sum its
 * steadiness weight: 1/20 for wishes that all change every tick, up to 1. Production takes turns
 * between the viewers in proportion to their weights (weighted fair queueing): a viewer's k-th
 * best wish has turn k / weight. Best-first by priority alone let a viewer with few wishes (one
 * arriving somewhere new: a coarse tree) take a fifth of production from four steady ones whatever
 * its weight, since normalising to a sum makes each of few wishes dear
 * (test_clocked__fair_content_age). */
static void wishes_share(ocs_world_t *w) {
  int nv = w->nviewers > 0 ? w->nviewers : 1;
  size_t share = 2 * OCS_QUEUE_MAX / (size_t)nv, k = 0;
  double *sum = calloc((size_t)nv, sizeof *sum);
  size_t *taken = calloc((size_t)nv, sizeof *taken);
  if (sum && taken && w->nwish) {
    qsort(w->wish, w->nwish, sizeof *w->wish, cmp_wish_prio);
    for (size_t i = 0; i < w->nwish; i++)
      if (taken[w->wish[i].viewer]++ < share) {
        sum[w->wish[i].viewer] += w->wish[i].prio;
        w->wish[k++] = w->wish[i];
      }
    memset(taken, 0, (size_t)nv * sizeof *taken);
    for (size_t i = 0; i < k; i++) { /* best first within each viewer */
      uint32_t vi = w->wish[i].viewer;
      double weight = 0.05 + 0.95 * w->viewers[vi]->steady;
      w->wish[i].prio = sum[vi] > 0 ? weight * w->wish[i].prio / sum[vi] : 0.0;
      w->wish[i].turn = (double)(++taken[vi]) / weight;
    }
  }
  free(sum);
  free(taken);
  w->nwish = k;
}

/* The tick's wishes become the production queue: one item per brick, its priority the sum over
 * the viewers that want it, in turn order (wishes_share), at most OCS_QUEUE_MAX. What no viewer
 * wants any more is gone. The wishes stay, sorted by brick, so that what is made is counted for its viewers. */
static void queue_build(ocs_world_t *w) {
  w->nqueue = 0;
  wishes_dedup(w);
  viewers_steadiness(w);
  wishes_inherit(w);
  wishes_share(w);
  if (w->nwish) qsort(w->wish, w->nwish, sizeof *w->wish, cmp_wish_viewer);
  if (w->queue_cap < w->nwish) {
    queued_t *a = realloc(w->queue, w->nwish * sizeof *a);
    if (!a) return; /* asked again next tick */
    w->queue = a;
    w->queue_cap = w->nwish;
  }
  size_t m = 0;
  for (size_t i = 0; i < w->nwish; i++) {
    const wish_t *x = &w->wish[i];
    queued_t *last = m ? &w->queue[m - 1] : NULL;
    if (last && last->key == x->key && last->stamp == x->stamp) {
      last->prio += x->prio;
      if (x->turn < last->turn) last->turn = x->turn;
      last->count++;
    } else {
      w->queue[m++] = (queued_t){x->key, x->stamp, x->prio, x->turn, (uint32_t)i, 1};
    }
  }
  /* the target plan wishes for content it has not taken yet, which may exist already */
  size_t k = 0;
  for (size_t i = 0; i < m; i++) {
    ocs_cache_key_t ck = ckey(w, T_BRICK, w->queue[i].key, w->queue[i].stamp, 0);
    ocs_cache_entry_t *e;
    if (ocs_cache_peek(w->cache, &ck, &e)) ocs_cache_release(w->cache, e);
    else w->queue[k++] = w->queue[i];
  }
  m = k;
  if (m) qsort(w->queue, m, sizeof *w->queue, cmp_queued_turn);
  w->nqueue = m < OCS_QUEUE_MAX ? m : OCS_QUEUE_MAX;
}

/* A viewer leaves: its wishes are withdrawn, and what only it wanted leaves the queue. Viewers
 * after it in the array move down by one. */
static void queue_forget(ocs_world_t *w, uint32_t vi) {
  for (size_t i = 0; i < w->nwish; i++) {
    if (w->wish[i].viewer == vi) w->wish[i].viewer = OCS_NO_VIEWER;
    else if (w->wish[i].viewer != OCS_NO_VIEWER && w->wish[i].viewer > vi) w->wish[i].viewer--;
  }
  size_t m = 0;
  for (size_t i = 0; i < w->nqueue; i++) {
    queued_t q = w->queue[i];
    q.prio = 0;
    int wanted = 0;
    for (uint32_t j = q.first; j < q.first + q.count; j++)
      if (w->wish[j].viewer != OCS_NO_VIEWER) {
        wanted = 1;
        q.prio += w->wish[j].prio;
      }
    if (wanted) w->queue[m++] = q;
  }
  w->nqueue = m;
}

/*-*** A step ***/

typedef struct {
  oc_key_t key;
  uint64_t stamp;
  uint32_t viewer, leaf;
} want_t;

static int cmp_want(const void *a, const void *b) {
  const want_t *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  if (x->stamp != y->stamp) return x->stamp < y->stamp ? -1 : 1;
  return 0;
}

static int push_want(want_t **want, size_t *n, size_t *cap, want_t x) {
  want_t *a = oc_grow(*want, cap, *n, sizeof *a, 1024);
  if (!a) return OC_ENOMEM;
  *want = a;
  (*want)[(*n)++] = x;
  return 0;
}

/* Clocked: what the viewer's tree is heading for — the plan a stepped epoch would make, all its
 * content assumed ready — is wished for, so that production works toward the whole target tree
 * and not one level per tick; then that plan is dropped. */
static int wish_target(const ocs_world_t *w, ocs_viewer_t *v, const ocs_plan_input_t *in) {
  ocs_plan_input_t target = *in;
  target.ready = NULL; /* want() stays: it hears of everything the target takes */
  /* as far ahead as the viewer's ticks may split: with the stepped cap here, a tick after a jump
   * found only that many splits' children made, whatever its own cap */
  target.split_scale = split_scale(w, v);
  const ocs_plan_leaf_t *leaves;
  uint32_t n;
  int rc = ocs_plan_epoch(v->planner, &v->view, &target, &leaves, &n, NULL);
  if (rc < 0) return rc;
  ocs_plan_abandon(v->planner);
  return 0;
}

/*-*** Budget changes (planner.h; docs/architecture.md "Budget changes") ***/

/* Before a viewer's plan: a budget asked for is put in force when the planner can (a raise at
 * once, a lowering once its newest state fits it); the epoch being planned is the first under it,
 * which the network layer tells the viewer (BUDGET) before that state. Until a lowering can be put
 * in force, the planner's steady target heads for it. Per viewer only: plans run in parallel. */
static void budget_switch(const ocs_world_t *w, ocs_viewer_t *v) {
  if (!v->want || v->want == v->desc.budget) return;
  if (ocs_plan_set_budget(v->planner, v->want) < 0) {
    ocs_plan_aim(v->planner, v->want);
    return;
  }
  v->desc.budget = v->want;
  v->news = 1;
  v->news_budget = v->want;
  v->news_epoch = w->epoch;
}

/* A viewer's reservation follows its window: the old budget of a lowering stays counted until
 * the states planned under it have left the K kept ones. */
static void viewer_reserve(ocs_world_t *w, ocs_viewer_t *v) {
  uint64_t r = ocs_plan_reserved(v->planner);
  if (v->want > r) r = v->want;
  w->granted = w->granted - v->reserved + r;
  v->reserved = r;
}

/* After a step: reservations follow the windows, then room that lowerings freed goes to viewers
 * that were admitted with less than they asked (and may be raised), in admission order. */
static void budgets_settle(ocs_world_t *w) {
  for (int i = 0; i < w->nviewers; i++) viewer_reserve(w, w->viewers[i]);
  for (int i = 0; i < w->nviewers; i++) {
    ocs_viewer_t *v = w->viewers[i];
    uint64_t now = v->want ? v->want : v->desc.budget, left = w->d.viewer_bytes - w->granted;
    if (!v->changeable || v->ask <= now || now < v->desc.budget || !left) continue; /* a lowering is pending */
    uint64_t give = v->reserved + left;
    v->want = give < v->ask ? give : v->ask;
    if (v->want <= now) continue;
    viewer_reserve(w, v);
  }
}

int ocs_world_set_budget(ocs_world_t *w, ocs_viewer_t *v, uint64_t budget, char *why, size_t why_len) {
  if (!w || !v) return OC_EINVAL;
  uint64_t mn = ocs_plan_min_budget(&v->desc), left = w->d.viewer_bytes - w->granted;
  if (budget < mn)
    return oc_errorf(OC_ERANGE, why, why_len, "%" PRIu64 " bytes is below the minimum %" PRIu64
                     " (the root in each of the %d kept states)", budget, mn, w->K);
  if (budget > w->d.max_budget)
    return oc_errorf(OC_ERANGE, why, why_len, "%" PRIu64 " bytes is above the per-viewer maximum %" PRIu64, budget,
                     w->d.max_budget);
  if (budget > v->reserved + left)
    return oc_errorf(OC_ERANGE, why, why_len, "%" PRIu64 " bytes is above what admission can give it: %" PRIu64
                     " (its %" PRIu64 " and the %" PRIu64 " not granted)", budget, v->reserved + left, v->reserved, left);
  v->want = budget;
  v->ask = budget; /* not raised back by budgets_settle() */
  viewer_reserve(w, v);
  return 0;
}

void ocs_viewer_budget_changes(ocs_viewer_t *v, int on) {
  if (v) v->changeable = on;
}

int ocs_viewer_budget_news(ocs_viewer_t *v, uint64_t *budget, uint64_t *epoch) {
  if (!v || !v->news) return 0;
  v->news = 0;
  *budget = v->news_budget;
  *epoch = v->news_epoch;
  return 1;
}

void ocs_viewer_budget_resend(ocs_viewer_t *v) {
  /* not while a raise waits for its plan: that one's news follows (and WELCOME named it) */
  if (!v || v->desc.budget >= v->reserved || v->want > v->desc.budget) return;
  v->news = 1;
  v->news_budget = v->desc.budget;
  v->news_epoch = v->w->epoch + 1;
}

/* One viewer's plan of a tick (the viewers' plans are independent: on the tick pool). */
typedef struct {
  ocs_world_t *w;
  const ocs_plan_input_t *in;
  const int *who;
  plan_ctx_t *ctx;
  int *rc;
} plan_job_t;

static int plan_one(void *arg, size_t i, int worker) {
  const plan_job_t *j = arg;
  (void)worker;
  int vi = j->who[i];
  ocs_viewer_t *v = j->w->viewers[vi];
  ocs_plan_input_t in = *j->in;
  /* a viewer that took k epochs to take the last state gets about 1/k of it per epoch */
  in.max_new_bricks = v->ticks > 1 && v->last_new ? (v->last_new / v->ticks > 8 ? v->last_new / v->ticks : 8) : 0;
  if (in.ready) in.split_scale = split_scale(j->w, v);
  j->ctx[i] = (plan_ctx_t){j->w, (uint32_t)vi};
  in.ctx = &j->ctx[i];
  budget_switch(j->w, v);
  j->rc[i] = ocs_plan_epoch(v->planner, &v->view, &in, &v->leaves, &v->nleaves, &v->plan);
  return 0;
}

/* Plans every viewer that acknowledged its last state; the leaves to produce go to *want.
 * A clocked viewer whose first content is not ready yet gets no plan (OC_EAGAIN). */
static int plan_viewers(ocs_world_t *w, ocs_plan_input_t *in, want_t **want, size_t *nwant) {
  size_t cap = 0;
  int n = 0, *who = malloc(sizeof(int) * (size_t)(w->nviewers ? w->nviewers : 1));
  int *rcs = malloc(sizeof(int) * (size_t)(w->nviewers ? w->nviewers : 1));
  plan_ctx_t *ctx = malloc(sizeof *ctx * (size_t)(w->nviewers ? w->nviewers : 1));
  if (!who || !rcs || !ctx) {
    free(who), free(rcs), free(ctx);
    return OC_ENOMEM;
  }
  for (int vi = 0; vi < w->nviewers; vi++) {
    ocs_viewer_t *v = w->viewers[vi];
    v->planned = 0;
    v->targeted = 0;
    v->ticks++;
    if (v->seen && w->epoch > v->seen + 1) v->coalesced += w->epoch - v->seen - 1; /* ticks the clock skipped */
    v->seen = w->epoch;
    if (!v->has_view) continue;
    if (v->unacked) {
      v->coalesced++;
      continue;
    }
    v->targeted = 1;
    /* a first view is a jump too: the tree starts from the root */
    if (!v->has_planned_view || view_jumped(&v->planned_view, &v->view)) v->jumped_at = w->epoch;
    v->planned_view = v->view;
    v->has_planned_view = 1;
    who[n++] = vi;
  }
  plan_job_t job = {w, in, who, ctx, rcs};
  int rc = 0;
  if (w->tick_pool && n > 1)
    rc = ocs_pool_run(w->tick_pool, (size_t)n, plan_one, &job);
  else
    for (int i = 0; i < n; i++) plan_one(&job, (size_t)i, 0);
  for (int i = 0; i < n && rc >= 0; i++) {
    ocs_viewer_t *v = w->viewers[who[i]];
    if (rcs[i] == OC_EAGAIN) continue;
    if ((rc = rcs[i]) < 0) break;
    v->planned = 1;
    if (v->nleaves > v->req_cap) {
      uint32_t *a = realloc(v->req_of, v->nleaves * sizeof *a);
      if (!a) {
        rc = OC_ENOMEM;
        break;
      }
      v->req_of = a;
      v->req_cap = v->nleaves;
    }
    for (uint32_t k = 0; k < v->nleaves && rc >= 0; k++)
      if (v->leaves[k].produce) rc = push_want(want, nwant, &cap, (want_t){v->leaves[k].key, v->leaves[k].stamp, (uint32_t)who[i], k});
  }
  if (rc < 0) /* the plans not taken up are let go: their planners must not stay pending */
    for (int i = 0; i < n; i++)
      if (rcs[i] >= 0 && !w->viewers[who[i]]->planned) ocs_plan_abandon(w->viewers[who[i]]->planner);
  free(who), free(rcs), free(ctx);
  return rc;
}

static int push_req(prod_t *p, oc_key_t key, uint64_t stamp) {
  req_t *a = oc_grow(p->req, &p->req_cap, p->nreq, sizeof *a, 1024);
  if (!a) return OC_ENOMEM;
  p->req = a;
  p->req[p->nreq++] = (req_t){.key = key, .stamp = stamp};
  return 0;
}

/* One request per distinct (key, stamp) over all viewers. */
static int make_requests(ocs_world_t *w, want_t *want, size_t nwant) {
  prod_t *p = &w->stepping;
  if (nwant) qsort(want, nwant, sizeof *want, cmp_want); /* qsort(NULL, 0) is undefined */
  p->nreq = 0;
  w->brick_requests += nwant;
  for (size_t i = 0; i < nwant; i++) {
    if (!p->nreq || p->req[p->nreq - 1].key != want[i].key || p->req[p->nreq - 1].stamp != want[i].stamp)
      OC_TRY(push_req(p, want[i].key, want[i].stamp));
    w->viewers[want[i].viewer]->req_of[want[i].leaf] = (uint32_t)(p->nreq - 1);
  }
  return 0;
}

/* Produces (or, for content that exists, pins) every request, on the pool or (serial: a clocked
 * tick, whose requests all exist, while production may hold the pool) on this thread; the ones
 * set aside for a τ volume another thread was building are finished in a second pass. */
static int produce_requests(prod_t *p, int serial) {
  ocs_pool_t *pool = p->w->pool;
  int rc = 0;
  if (serial)
    for (size_t i = 0; i < p->nreq; i++) {
      int r = produce_one(p, i, 0);
      if (r < 0 && rc >= 0) rc = r;
    }
  else
    rc = ocs_pool_run(pool, p->nreq, produce_one, p);
  /* the set-aside requests hold reservations: they are finished even after an error */
  p->ndeferred = 0;
  for (size_t i = 0; i < p->nreq; i++) {
    if (!p->req[i].sigma) continue;
    size_t *a = oc_grow(p->deferred, &p->deferred_cap, p->ndeferred, sizeof *a, 256);
    if (!a) { /* finish it here, waiting */
      int r = produce_finish(p, &p->req[i], p->req[i].sigma, 1);
      free(p->req[i].sigma);
      p->req[i].sigma = NULL;
      if (r < 0 && rc >= 0) rc = r;
      continue;
    }
    p->deferred = a;
    p->deferred[p->ndeferred++] = i;
  }
  int r = 0;
  for (size_t i = 0; serial && i < p->ndeferred; i++) {
    int e = produce_deferred(p, i, 0);
    if (e < 0 && r >= 0) r = e;
  }
  if (!serial && p->ndeferred) r = ocs_pool_run(pool, p->ndeferred, produce_deferred, p);
  return r < 0 && rc >= 0 ? r : rc;
}

/*-*** Ahead: a slow level's next σt and τ, spread over the epochs before they are due ***/

/* A level whose own time step lasts n epochs resamples all its leaves' σt in the epoch the step
 * changes, and a level whose light stamp (what its τ volumes read) lasts n epochs rebuilds all its
 * volumes then, while the finest levels change every epoch anyway: on the planet every 4th, 8th and
 * 16th epoch cost 3–5× the median (docs/performance.md, lever 10). Content is a function of the
 * stamps, so both can be made before they are due: each epoch makes its share, what is missing
 * over the epochs left, and the change finds them in the cache. */

/* Items sort by kind, then σt by node, τ by volume (group and level), so duplicates are adjacent. */
static int cmp_ahead(const void *a, const void *b) {
  const ahead_t *x = a, *y = b;
  if (x->tau != y->tau) return x->tau - y->tau;
  if (x->tau && x->group != y->group) return (x->group > y->group) - (x->group < y->group);
  int lx = oc_key_level(x->key), ly = oc_key_level(y->key);
  if (x->tau && lx != ly) return lx - ly;
  return x->tau ? 0 : (x->key > y->key) - (x->key < y->key);
}

static int ahead_same(const ahead_t *x, const ahead_t *y) { return cmp_ahead(x, y) == 0; }

/* 1 when what the item makes is in the cache already. */
static int ahead_cached(ocs_world_t *w, const ahead_t *x) {
  ocs_cache_key_t k = x->tau ? tau_key(&w->ahead_at[oc_key_level(x->key)], x->key) : ckey(w, T_SIGMA, x->key, x->ts, 0);
  ocs_cache_entry_t *e;
  if (!ocs_cache_peek(w->cache, &k, &e)) return 0;
  ocs_cache_release(w->cache, e);
  return 1;
}

static int ahead_push(ocs_world_t *w, ahead_t x) {
  ahead_t *a = oc_grow(w->ahead, &w->ahead_cap, w->nahead, sizeof *a, 1024);
  if (!a) return OC_ENOMEM;
  w->ahead = a;
  w->ahead[w->nahead++] = x;
  return 0;
}

/* The candidates: the leaves of the viewers' newest states that hold σt now (one empty then is
 * proven so cheaply by its bound), at levels whose σt or light stamp ahead_in / light_in name. */
static int ahead_candidates(ocs_world_t *w) {
  int any = 0;
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    if (w->shadows && w->light_in[l]) prod_snapshot_at(w, &w->ahead_at[l], w->light_t[l]);
    any |= w->ahead_in[l] || (w->shadows && w->light_in[l]);
  }
  if (!any) return 0; /* a static field, or no slow level: the held states are not walked */
  for (int vi = 0; vi < w->nviewers; vi++) {
    const ocs_viewer_t *v = w->viewers[vi];
    for (uint32_t i = 0; v->nheld && i < v->held[0].node_count; i++) {
      const oc_node_t *nd = &v->held[0].nodes[i];
      int l = oc_key_level(nd->key);
      if (l < 0 || !(nd->range[0].hi > 0.0f)) continue;
      if (w->ahead_in[l]) /* a node's σt whose own step does not move with the level's is found cached */
        OC_TRY(ahead_push(w, (ahead_t){.key = nd->key, .ts = ocs_field_node_step(w->field, nd->key, w->ahead_t[l]),
                                       .time = w->ahead_t[l]}));
      if (w->shadows && w->light_in[l])
        OC_TRY(ahead_push(w, (ahead_t){.key = nd->key, .group = ocs_tau_group_of(&w->tau, nd->key),
                                       .time = w->light_t[l], .tau = 1}));
    }
  }
  return 0;
}

/* This epoch's share: of the distinct candidates not in the cache, per level and kind, the first
 * ceil(missing / epochs left). Runs while the world is idle (it reads the held states). */
static int ahead_collect(ocs_world_t *w) {
  w->nahead = 0;
  w->ahead_now = w->time;
  if (w->ahead_off) return 0;
  OC_TRY(ahead_candidates(w));
  if (w->nahead) qsort(w->ahead, w->nahead, sizeof *w->ahead, cmp_ahead);
  size_t n = 0, missing[2][OC_KEY_MAX_LEVEL + 1] = {{0}};
  for (size_t i = 0; i < w->nahead; i++)
    if ((!n || !ahead_same(&w->ahead[n - 1], &w->ahead[i])) && !ahead_cached(w, &w->ahead[i])) {
      w->ahead[n++] = w->ahead[i];
      missing[w->ahead[i].tau][oc_key_level(w->ahead[i].key)]++;
    }
  size_t m = 0, taken[2][OC_KEY_MAX_LEVEL + 1] = {{0}};
  for (size_t i = 0; i < n; i++) {
    const ahead_t *x = &w->ahead[i];
    int l = oc_key_level(x->key);
    uint32_t left = x->tau ? w->light_in[l] : w->ahead_in[l];
    if (taken[x->tau][l] < (missing[x->tau][l] + left - 1) / left) {
      taken[x->tau][l]++;
      w->ahead[m++] = *x;
    }
  }
  w->nahead = m;
  return 0;
}

typedef struct {
  ocs_world_t *w;
  double deadline; /* none is started that is expected to end after it (0: none) */
} ahead_run_t;

static void ahead_make_sigma(ocs_world_t *w, ahead_t *x, double c0) {
  float s[OC_BRICK_VOXELS];
  if (sigma_entry(w, x->key, x->ts, x->time, s) <= 0) return; /* found, or failed: made when due */
  double took = now_s() - c0;
  x->cpu = took;
  int any = 0;
  for (int j = 0; j < OC_BRICK_VOXELS; j++) any |= s[j] > 0.0f;
  trace_interval(w, thread_id(), c0, c0 + took, !any, x->time);
  atomic_fetch_add(&w->ahead_sigma, 1);
  atomic_add_double(&w->ahead_cpu, took);
  if (!any) {
    atomic_fetch_add(&w->ahead_empty, 1);
    atomic_add_double(&w->ahead_cpu_empty, took);
  }
}

static void ahead_make_tau(ocs_world_t *w, ahead_t *x, double c0) {
  ocs_cache_entry_t *e;
  int built = 0;
  if (tau_volume_acquire(&w->ahead_at[oc_key_level(x->key)], x->key, 1, &e, &built) < 0) return;
  ocs_cache_release(w->cache, e);
  if (!built) return;
  atomic_fetch_add(&w->ahead_tau, 1);
  double now = now_s();
  x->cpu = now - c0;
  atomic_add_double(&w->ahead_cpu, now - c0);
  trace_interval(w, thread_id(), c0, now, 0, x->time);
}

static int ahead_one(void *ctx, size_t i, int worker) {
  (void)worker;
  const ahead_run_t *a = ctx;
  ocs_world_t *w = a->w;
  ahead_t *x = &w->ahead[i];
  double c0 = now_s();
  if (a->deadline > 0 && c0 + atomic_load(&w->cost[oc_key_level(x->key)][x->tau]) > a->deadline) return 0;
  if (x->tau) ahead_make_tau(w, x, c0);
  else ahead_make_sigma(w, x, c0);
  return 0;
}

/* The stock: what ahead made that is not due yet at world time t (earlier entries are dropped). */
static void stock_prune(ocs_world_t *w, double t) {
  size_t m = 0;
  for (size_t i = 0; i < w->nstock; i++)
    if (w->stock[i].due > t) w->stock[m++] = w->stock[i];
  w->nstock = m;
}

/* The stock's sums for the stats (atomics: a clocked server reads its stats beside production). */
static void stock_sums(ocs_world_t *w) {
  uint64_t n[2] = {0, 0};
  double cpu = 0.0;
  for (size_t i = 0; i < w->nstock; i++) n[w->stock[i].tau != 0]++, cpu += w->stock[i].cpu;
  atomic_store(&w->stock_sigma, n[0]);
  atomic_store(&w->stock_tau, n[1]);
  atomic_store(&w->stock_cpu, cpu);
}

/* Makes ahead_collect()'s share on the producer pool (best effort: what fails is made when due),
 * and adds what it made to the stock. */
static void ahead_run(ocs_world_t *w, double deadline) {
  if (!w->nahead) return;
  ahead_run_t a = {w, deadline};
  for (size_t i = 0; i < w->nahead; i++) w->ahead[i].cpu = 0.0;
  ocs_pool_run(w->pool, w->nahead, ahead_one, &a);
  stock_prune(w, w->ahead_now);
  for (size_t i = 0; i < w->nahead; i++) {
    if (!(w->ahead[i].cpu > 0.0)) continue;
    stock_t *st = oc_grow(w->stock, &w->stock_cap, w->nstock, sizeof *st, 256);
    if (!st) break; /* the stock is a statistic: it just stops growing */
    w->stock = st;
    w->stock[w->nstock++] = (stock_t){w->ahead[i].time, w->ahead[i].cpu, w->ahead[i].tau};
  }
  stock_sums(w);
  w->nahead = 0;
}

/* Content age of the plan's leaves, per level: time steps behind current (0..OCS_STAMP_HISTORY,
 * 255 older), p50 and p99. */
static void content_age(const ocs_world_t *w, ocs_viewer_t *v) {
  uint32_t hist[OC_KEY_MAX_LEVEL + 1][OCS_STAMP_HISTORY + 2];
  memset(hist, 0, sizeof hist);
  for (uint32_t i = 0; i < v->nleaves; i++) {
    int l = oc_key_level(v->leaves[i].key), a = 0;
    uint64_t st = v->leaves[i].stamp;
    if (st != w->stamp[l]) {
      a = OCS_STAMP_HISTORY + 1; /* older than remembered */
      for (int k = 0; k < OCS_STAMP_HISTORY; k++)
        if (w->stamp_hist[l][k] == st) {
          a = k + 1;
          break;
        }
    }
    hist[l][a]++;
  }
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    uint32_t n = 0, c = 0;
    for (int a = 0; a <= OCS_STAMP_HISTORY + 1; a++) n += hist[l][a];
    v->age_p50[l] = v->age_p99[l] = 255;
    for (int a = 0; n && a <= OCS_STAMP_HISTORY; a++) {
      c += hist[l][a];
      if (v->age_p50[l] == 255 && 2 * (uint64_t)c >= n) v->age_p50[l] = (uint8_t)a;
      if (v->age_p99[l] == 255 && 100 * (uint64_t)c >= 99 * (uint64_t)n) v->age_p99[l] = (uint8_t)a;
    }
  }
}

/* One planned viewer's state, built and committed; its previous ones shift down the window.
 * Viewers are independent here (their own planner, states and ids; the requests are read only),
 * so a tick builds them on the tick pool. */
static int emit_one(void *arg, size_t vi, int worker) {
  ocs_world_t *w = arg;
  ocs_viewer_t *v = w->viewers[vi];
  (void)worker;
  if (!v->planned) return 0;
  uint8_t *kinds = malloc(v->nleaves ? v->nleaves : 1);
  uint32_t *ids = malloc((v->nleaves ? v->nleaves : 1) * sizeof *ids);
  oc_state_t st = v->spare; /* its arrays; nothing refers to the state it was */
  oc_state_clear(&st);
  oc_state_init(&v->spare);
  uint32_t first_id = v->next_id;
  int rc = kinds && ids ? build_state(w, v, &st, kinds, ids) : OC_ENOMEM;
  if (rc >= 0) rc = ocs_plan_commit(v->planner, kinds, ids);
  free(kinds);
  free(ids);
  if (rc < 0) {
    v->next_id = first_id;
    oc_state_free(&st);
    return rc;
  }
  content_age(w, v);
  v->planned = 0;
  v->spare = v->held[w->K - 1]; /* dropped: its arrays serve the next state */
  memmove(&v->held[1], &v->held[0], (size_t)(w->K - 1) * sizeof v->held[0]);
  v->held[0] = st;
  if (v->nheld < w->K) v->nheld++;
  v->in_flight = w->epoch;
  v->unacked = 1;
  v->sent++;
  v->last_new = v->nlacking;
  v->ticks = 0;
  v->produced_last = v->produced;
  v->produced = 0;
  return 0;
}

static int emit_states(ocs_world_t *w) {
  if (w->tick_pool && w->nviewers > 1) return ocs_pool_run(w->tick_pool, (size_t)w->nviewers, emit_one, w);
  for (int vi = 0; vi < w->nviewers; vi++) OC_TRY(emit_one(w, (size_t)vi, 0));
  return 0;
}

/* Plans every ready viewer, produces what the plans lack once (clocked: only what exists is
 * planned, and what waits goes to the queue), emits their states. */
/* What a plan of this epoch is given (clocked: ready() and want() too). */
static void plan_input(ocs_world_t *w, ocs_plan_input_t *in) {
  memset(in, 0, sizeof *in);
  in->classify = classify_cb;
  in->ctx = NULL; /* a plan_ctx_t per plan: plan_viewers, plan_targets */
  in->uniform_is_brick = w->shadows;
  in->ground_tau = w->ground_tau;
  memcpy(in->stamp, w->stamp, sizeof in->stamp);
  memcpy(in->refresh_rate, w->rate, sizeof in->refresh_rate);
  if (ocs_field_animated(w->field)) memcpy(in->step_change, STEP_CHANGE, sizeof in->step_change);
  if (w->d.clocked) {
    in->ready = ready_cb;
    in->want = want_cb;
  }
}

static int step(ocs_world_t *w) {
  double t0 = now_s();
  ocs_plan_input_t in;
  plan_input(w, &in);
  prod_snapshot(w, &w->stepping);
  if (w->d.clocked) { /* the queue is made anew from this tick's wishes */
    w->ticked = 1;
    w->queue_left = w->nqueue;
    w->nwish = w->nqueue = 0;
    w->targets_due = 0;
  }
  want_t *want = NULL;
  size_t nwant = 0;
  int rc = plan_viewers(w, &in, &want, &nwant);
  double t1 = now_s();
  w->plan_seconds = t1 - t0;
  if (rc >= 0) rc = make_requests(w, want, nwant);
  free(want);
  if (rc >= 0) rc = produce_requests(&w->stepping, w->d.clocked); /* clocked: every request is a hit */
  for (int vi = 0; vi < w->nviewers && rc >= 0; vi++) { /* stepped: what was made for whom */
    ocs_viewer_t *v = w->viewers[vi];
    for (uint32_t i = 0; v->planned && i < v->nleaves; i++)
      v->produced += v->leaves[i].produce && w->stepping.req[v->req_of[i]].made;
  }
  w->produce_seconds = now_s() - t1;
  if (rc >= 0) rc = emit_states(w);
  if (rc >= 0 && !w->d.clocked) { /* the states are out: the coming changes' σt and τ */
    double t2 = now_s();
    if (ahead_collect(w) >= 0) ahead_run(w, 0.0);
    w->produce_seconds += now_s() - t2;
  }
  budgets_settle(w);
  if (rc < 0)
    for (int vi = 0; vi < w->nviewers; vi++)
      if (w->viewers[vi]->planned) {
        ocs_plan_abandon(w->viewers[vi]->planner);
        w->viewers[vi]->planned = 0;
      }
  release_requests(&w->stepping);
  release_pins(w);
  w->targets_due = w->d.clocked; /* the targets are planned when production starts, off the tick */
  return rc;
}

/* A target plan is a whole plan (tens to hundreds of ms): one is reused, re-stamped to the current
 * time steps, until it is OCS_TARGET_TICKS old, its viewer's view has jumped (view_jumped), or its
 * best wishes are all made. */
#define OCS_TARGET_TICKS 4
#define OCS_TARGET_PROBE 64

static int target_stale(const ocs_world_t *w, const ocs_viewer_t *v) {
  if (!v->has_target || w->epoch >= v->target_epoch + OCS_TARGET_TICKS || view_jumped(&v->target_view, &v->view)) return 1;
  size_t n = v->ntarget < OCS_TARGET_PROBE ? v->ntarget : OCS_TARGET_PROBE;
  for (size_t i = 0; i < n; i++) { /* best first: production makes these first */
    const wish_t *x = &v->target[i];
    ocs_cache_key_t k = ckey(w, T_BRICK, x->key, w->stamp[oc_key_level(x->key)], 0);
    ocs_cache_entry_t *e;
    if (!ocs_cache_peek(w->cache, &k, &e)) return 0;
    ocs_cache_release(w->cache, e);
  }
  return 1;
}

/* The target's wishes (w->wish[from ..]) are kept with the viewer, best first. */
static void target_keep(ocs_world_t *w, ocs_viewer_t *v, size_t from) {
  size_t n = w->nwish - from;
  if (n > v->target_cap) {
    wish_t *a = realloc(v->target, n * sizeof *a);
    if (!a) {
      v->has_target = 0; /* planned again next time */
      return;
    }
    v->target = a;
    v->target_cap = n;
  }
  memcpy(v->target, &w->wish[from], n * sizeof *v->target);
  if (n) qsort(v->target, n, sizeof *v->target, cmp_wish_prio);
  v->ntarget = n;
  v->target_epoch = w->epoch;
  v->target_view = v->view;
  v->has_target = 1;
}

/* The kept target wished for again, at the current time steps. */
static void target_reuse(ocs_world_t *w, const ocs_viewer_t *v, uint32_t vi) {
  plan_ctx_t c = {w, vi};
  for (size_t i = 0; i < v->ntarget; i++) {
    const wish_t *x = &v->target[i];
    want_cb(&c, x->key, w->stamp[oc_key_level(x->key)], x->prio);
  }
}

/* Clocked, at the start of production: each viewer's target (the plan a stepped epoch would make
 * from its tree as the tick left it) is wished for, then the tick's wishes become the queue. Off
 * the tick's path: a target is a whole plan, classifying every new node. */
static int plan_targets(ocs_world_t *w, double deadline) {
  double t0 = now_s();
  ocs_plan_input_t in;
  plan_input(w, &in);
  int rc = 0, n = w->nviewers;
  /* past production's deadline (less what a plan takes) the rest reuse their targets, and plan
   * first at the next production: the tick would wait for them */
  for (int k = 0; k < n && rc >= 0; k++) {
    int vi = (w->target_next + k) % n;
    ocs_viewer_t *v = w->viewers[vi];
    if (!v->has_view || !v->targeted) continue;
    double t = now_s();
    if (!target_stale(w, v) || (deadline > 0 && t + w->target_cost >= deadline)) {
      target_reuse(w, v, (uint32_t)vi);
      continue;
    }
    size_t from = w->nwish;
    plan_ctx_t c = {w, (uint32_t)vi};
    in.ctx = &c;
    rc = wish_target(w, v, &in);
    if (rc >= 0) target_keep(w, v, from);
    double took = now_s() - t;
    w->target_cost = took > 0.9 * w->target_cost ? took : 0.9 * w->target_cost;
    w->target_next = (vi + 1) % n;
  }
  queue_build(w);
  w->targets_due = 0;
  w->target_seconds = now_s() - t0;
  return rc;
}

/* A production's requests: the queue's best `n`, each with the viewers that want it. */
static int round_fill(ocs_world_t *w, prod_t *p, size_t n) {
  p->nreq = p->nwho = 0;
  size_t nwho = 0;
  for (size_t i = 0; i < n; i++) nwho += w->queue[i].count;
  if (nwho > p->who_cap) {
    ocs_viewer_t **a = realloc(p->who, nwho * sizeof *a);
    if (!a) return OC_ENOMEM;
    p->who = a;
    p->who_cap = nwho;
  }
  for (size_t i = 0; i < n; i++) {
    const queued_t *q = &w->queue[i];
    OC_TRY(push_req(p, q->key, q->stamp));
    p->req[i].first = (uint32_t)p->nwho;
    p->req[i].count = q->count;
    for (uint32_t j = q->first; j < q->first + q->count; j++)
      p->who[p->nwho++] = w->wish[j].viewer == OCS_NO_VIEWER ? NULL : w->viewers[w->wish[j].viewer];
  }
  return 0;
}

int ocs_world_produce_begin(ocs_world_t *w, double seconds, size_t limit) {
  if (!w || !w->d.clocked) return 0;
  if (w->in_production) return OC_EAGAIN;
  double t0 = now_s(), deadline = t0 + (seconds > 0 ? seconds : 0.0); /* the targets' time included */
  if (w->targets_due) OC_TRY(plan_targets(w, seconds > 0 ? deadline : 0.0));
  /* estimates fade between productions: a kind of brick too dear for every window would otherwise
   * never be made again (it is made, late, once its estimate fits) */
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++)
    for (int k = 0; k < 2; k++) atomic_store(&w->cost[l][k], 0.7 * atomic_load(&w->cost[l][k]));
  w->target_cost *= 0.7; /* likewise: a target plan too dear for every window is made again */
  prod_t *p = &w->producing;
  prod_snapshot(w, p);
  p->deadline = deadline;
  p->start = now_s(); /* after the targets: the window the bricks have */
  atomic_store(&p->busy_until, 0.0);
  int rc = round_fill(w, p, limit && limit < w->nqueue ? limit : w->nqueue);
  if (rc >= 0 && ahead_collect(w) < 0) w->nahead = 0; /* made in what is left of the window */
  if (rc < 0) {
    p->nreq = 0;
    return rc;
  }
  w->in_production = 1;
  w->ticked = 0;
  w->produce_rc = 0;
  w->produce_t0 = t0;
  return (int)(p->nreq < INT32_MAX ? p->nreq : INT32_MAX);
}

int ocs_world_produce_run(ocs_world_t *w) {
  if (!w || !w->in_production) return 0;
  w->produce_rc = produce_requests(&w->producing, 0);
  if (w->produce_rc >= 0) ahead_run(w, w->producing.deadline);
  return w->produce_rc;
}

static void made_log(ocs_world_t *w, oc_key_t key, uint64_t stamp);

int ocs_world_produce_end(ocs_world_t *w) {
  if (!w || !w->in_production) return 0;
  prod_t *p = &w->producing;
  uint64_t made = 0;
  for (size_t i = 0; i < p->nreq; i++) { /* counted for the viewers that wanted it */
    const req_t *q = &p->req[i];
    made += (uint64_t)q->made;
    if (q->made && w->d.content_id) made_log(w, q->key, q->stamp);
    for (uint32_t j = q->first; q->made && j < q->first + q->count; j++)
      if (p->who[j]) p->who[j]->produced++;
  }
  if (!w->ticked) { /* what was made leaves the queue (req[i] is queue[i]); after a tick, the queue is its */
    size_t m = 0;
    for (size_t i = 0; i < w->nqueue; i++)
      if (!(i < p->nreq && p->req[i].made)) w->queue[m++] = w->queue[i];
    w->nqueue = m;
  }
  release_requests(p);
  p->nwho = 0;
  w->in_production = 0;
  w->produce_seconds = now_s() - w->produce_t0;
  /* a brick that failed (produce_rc) is counted, stays queued and is asked again */
  return (int)(made < INT32_MAX ? made : INT32_MAX);
}

int ocs_world_produce(ocs_world_t *w, double seconds, size_t limit) {
  int rc = ocs_world_produce_begin(w, seconds, limit);
  if (rc < 0) return rc;
  ocs_world_produce_run(w);
  return ocs_world_produce_end(w);
}

int ocs_world_parallel(ocs_world_t *w, size_t n, int (*fn)(void *ctx, size_t index, int worker), void *ctx) {
  if (!w || !fn) return OC_EINVAL;
  if (w->tick_pool && n > 1) return ocs_pool_run(w->tick_pool, n, fn, ctx);
  for (size_t i = 0; i < n; i++) OC_TRY(fn(ctx, i, 0));
  return 0;
}

size_t ocs_world_queue_length(const ocs_world_t *w) { return !w ? 0 : w->targets_due ? w->queue_left : w->nqueue; }

int ocs_world_production_due(const ocs_world_t *w) { return w && w->d.clocked && (w->targets_due || w->nqueue); }

int ocs_world_queue_peek(const ocs_world_t *w, size_t i, oc_key_t *key, double *prio, uint32_t *viewers) {
  if (!w || i >= w->nqueue) return OC_ENOENT;
  const queued_t *q = &w->queue[i];
  if (key) *key = q->key;
  if (prio) *prio = q->prio;
  if (viewers) *viewers = q->count;
  return 0;
}

void ocs_world_stats(const ocs_world_t *w, ocs_world_stats_t *out) {
  memset(out, 0, sizeof *out);
  if (!w) return;
  *out = (ocs_world_stats_t){.epoch = w->epoch,
                             .time = w->time,
                             .bricks_produced = w->bricks_produced,
                             .sigma_produced = w->sigma_produced,
                             .tau_volumes = w->tau_volumes,
                             .brick_requests = w->brick_requests,
                             .cache_hit_rate = ocs_cache_hit_rate(w->cache),
                             .viewers = (uint32_t)w->nviewers,
                             .granted_bytes = w->granted,
                             .produce_seconds = w->produce_seconds,
                             .plan_seconds = w->plan_seconds,
                             .target_seconds = w->target_seconds,
                             .tau_direct = (uint64_t)atomic_load(&w->tau_stats.direct),
                             .tau_clear = (uint64_t)atomic_load(&w->tau_stats.clear_proven),
                             .tau_columns = (uint64_t)atomic_load(&w->tau_stats.columns),
                             .produce_errors = w->produce_errors,
                             .ahead_sigma = w->ahead_sigma,
                             .ahead_empty = w->ahead_empty,
                             .ahead_tau = w->ahead_tau,
                             .tau_kept = w->tau_kept,
                             .sigma_kept = w->sigma_kept,
                             .ahead_cpu = w->ahead_cpu,
                             .ahead_cpu_empty = w->ahead_cpu_empty,
                             .ahead_stock_sigma = w->stock_sigma,
                             .ahead_stock_tau = w->stock_tau,
                             .ahead_cpu_stock = w->stock_cpu,
                             .last_error = w->last_error,
                             .last_error_key = w->last_error_key};
  for (int l = 0; l <= OC_KEY_MAX_LEVEL; l++) {
    out->level[l].made = w->level_made[l], out->level[l].empty = w->level_empty[l];
    out->level[l].cpu = w->level_cpu[l], out->level[l].cpu_empty = w->level_cpu_empty[l];
    out->bricks_empty += out->level[l].empty;
    out->brick_cpu += out->level[l].cpu, out->brick_cpu_empty += out->level[l].cpu_empty;
  }
  ocs_cache_stats(w->cache, &out->cache);
  for (int i = 0; i < w->nviewers; i++)
    for (int j = 0; j < w->viewers[i]->nheld; j++) {
      const oc_state_t *s = &w->viewers[i]->held[j];
      out->held_bytes += (uint64_t)s->node_count * sizeof(oc_node_t) + (uint64_t)s->brick_count * sizeof(oc_brick_t);
    }
  for (int i = 0; i < w->nviewers; i++) { /* the spare's arrays are memory held too */
    const oc_state_t *s = &w->viewers[i]->spare;
    out->held_bytes += (uint64_t)s->node_cap * sizeof(oc_node_t) + (uint64_t)s->brick_cap * sizeof(oc_brick_t);
  }
  ocs_hist_read(&w->brick_seconds, &out->brick_seconds);
}

/*-*** Content at another time (overcast-stress --verify-content) ***/

uint64_t ocs_world_stamp_at(const ocs_world_t *w, int level, double t) {
  if (!w || level < 0 || level > OC_KEY_MAX_LEVEL) return 0;
  uint64_t stamp[OC_KEY_MAX_LEVEL + 1];
  stamps_at(w, t, NULL, stamp, NULL);
  return stamp[level];
}

int ocs_world_reproduce(ocs_world_t *w, oc_key_t key, double t, ocs_brick_out_t *out) {
  int level = oc_key_level(key);
  if (!w || !out || level < 0 || !isfinite(t) || w->nviewers) return OC_EINVAL;
  if (w->time != t) {
    w->time = t;
    clock_update(w);
  }
  prod_t *pr = &w->stepping;
  prod_snapshot(w, pr);
  pr->nreq = 0;
  OC_TRY(push_req(pr, key, w->stamp[level]));
  req_t *q = &pr->req[0];
  int r = produce_brick(pr, q);
  if (r >= 0 && q->sigma) { /* set aside for a τ volume: nobody else builds it here */
    r = produce_finish(pr, q, q->sigma, 1);
    free(q->sigma);
    q->sigma = NULL;
  }
  if (r >= 0) {
    const payload_t *p = ocs_cache_data(q->entry);
    out->kind = p->kind;
    memcpy(out->range, p->range, sizeof out->range);
    if (p->kind == OC_NODE_BRICK) out->codes = p->codes;
    else memset(&out->codes, 0, sizeof out->codes);
  }
  release_requests(&w->stepping);
  return r;
}

int ocs_world_plan_offline(ocs_world_t *w, const ocs_plan_desc_t *req, const ocs_view_t *view, int epochs, oc_state_t *out,
                           char *why, size_t why_len) {
  if (!w || !req || !out || epochs < 1) return OC_EINVAL;
  ocs_viewer_t *v = NULL;
  int r = ocs_world_add_viewer(w, req, &v, NULL, why, why_len);
  if (r < 0) return r;
  if ((r = ocs_viewer_set_view(v, view)) < 0) {
    if (why) snprintf(why, why_len, "invalid camera for the viewer");
    ocs_world_remove_viewer(w, v);
    return r;
  }
  ocs_epoch_out_t o = {0};
  for (int e = 0; e < epochs; e++) {
    if ((r = ocs_world_step(w)) < 0 || (r = ocs_viewer_output(v, &o)) < 0) {
      if (why) snprintf(why, why_len, "epoch %d: %s", e + 1, oc_strerror(r));
      ocs_world_remove_viewer(w, v);
      return r;
    }
    ocs_viewer_ack(v, o.state->epoch);
    oc_log_info("epoch %d/%d: %u leaves, %u new bricks, %u splits, %u merges, plan %.1f ms, produce %.1f ms", e + 1, epochs,
                o.plan.leaves, o.nlacking, o.plan.splits, o.plan.merges, 1e3 * w->plan_seconds, 1e3 * w->produce_seconds);
  }
  r = oc_state_copy(out, o.state);
  ocs_world_remove_viewer(w, v);
  return r;
}

/*-*** Sharing bricks between front-ends ***/

/* A brick as it travels between front-ends: kind, both ranges, and the codes of a brick, packed
 * little-endian (the cache's payload_t is a struct image, never written out). */
#define SHARE_HEAD (1 + 8 * OC_CHANNELS)

ocs_bkey_t ocs_world_brick_id(const ocs_world_t *w, oc_key_t key, uint64_t stamp) {
  ocs_bkey_in_t in = {.scene = w->d.content_id, .weather = w->weather_hist, .sun = w->sun_version, .stamp = stamp, .node = key,
                      .channel = OCS_SHARE_CHANNEL_BRICK};
  return ocs_bkey_make(&in);
}

int ocs_world_queue_item(const ocs_world_t *w, size_t i, oc_key_t *key, uint64_t *stamp) {
  if (!w || i >= w->nqueue) return OC_ENOENT;
  *key = w->queue[i].key;
  *stamp = w->queue[i].stamp;
  return 0;
}

static size_t share_slot(oc_key_t key, uint64_t stamp) { return (size_t)(mix(key, stamp) & (OCS_HOLD_SLOTS - 1)); }

static int held_back(ocs_world_t *w, oc_key_t key, uint64_t stamp) {
  int found = 0;
  pthread_mutex_lock(&w->share_mu);
  for (size_t i = share_slot(key, stamp); w->hold[i].used; i = (i + 1) & (OCS_HOLD_SLOTS - 1))
    if (w->hold[i].key == key && w->hold[i].stamp == stamp) {
      found = 1;
      break;
    }
  pthread_mutex_unlock(&w->share_mu);
  return found;
}

void ocs_world_hold_back(ocs_world_t *w, oc_key_t key, uint64_t stamp) {
  pthread_mutex_lock(&w->share_mu);
  if (atomic_load(&w->nhold) < OCS_HOLD_SLOTS / 2) { /* beyond: made here too, which is only waste */
    size_t i = share_slot(key, stamp);
    while (w->hold[i].used && !(w->hold[i].key == key && w->hold[i].stamp == stamp)) i = (i + 1) & (OCS_HOLD_SLOTS - 1);
    if (!w->hold[i].used) {
      w->hold[i] = (share_t){key, stamp, 1};
      atomic_fetch_add(&w->nhold, 1);
    }
  }
  pthread_mutex_unlock(&w->share_mu);
}

void ocs_world_hold_clear(ocs_world_t *w) {
  pthread_mutex_lock(&w->share_mu);
  if (atomic_load(&w->nhold)) memset(w->hold, 0, sizeof w->hold);
  atomic_store(&w->nhold, 0);
  pthread_mutex_unlock(&w->share_mu);
}

static void made_log(ocs_world_t *w, oc_key_t key, uint64_t stamp) {
  pthread_mutex_lock(&w->share_mu);
  if (w->made_cap < OCS_MADE_MAX) {
    share_t *a = oc_grow(w->made, &w->made_cap, w->nmade, sizeof *a, 1024);
    if (a) w->made = a;
  }
  if (w->nmade < w->made_cap) w->made[w->nmade++] = (share_t){key, stamp, 1};
  else w->made_dropped++; /* not shared: made again elsewhere, which is only waste */
  pthread_mutex_unlock(&w->share_mu);
}

size_t ocs_world_made_take(ocs_world_t *w, oc_key_t *keys, uint64_t *stamps, size_t cap) {
  pthread_mutex_lock(&w->share_mu);
  size_t n = w->nmade < cap ? w->nmade : cap;
  for (size_t i = 0; i < n; i++) {
    keys[i] = w->made[w->nmade - n + i].key;
    stamps[i] = w->made[w->nmade - n + i].stamp;
  }
  w->nmade -= n;
  pthread_mutex_unlock(&w->share_mu);
  return n;
}

size_t ocs_world_export(ocs_world_t *w, oc_key_t key, uint64_t stamp, uint8_t *out, size_t cap) {
  ocs_cache_key_t k = ckey(w, T_BRICK, key, stamp, 0);
  ocs_cache_entry_t *e;
  if (cap < OCS_SHARE_MAX_BYTES || !ocs_cache_peek(w->cache, &k, &e)) return 0;
  const payload_t *p = ocs_cache_data(e);
  out[0] = p->kind;
  for (int c = 0; c < OC_CHANNELS; c++) {
    oc_put_f32(out + 1 + 8 * c, p->range[c].lo);
    oc_put_f32(out + 5 + 8 * c, p->range[c].hi);
  }
  size_t n = SHARE_HEAD;
  if (p->kind == OC_NODE_BRICK)
    for (int c = 0; c < OC_CHANNELS; c++)
      for (int i = 0; i < OC_BRICK_VOXELS; i++, n += 2) oc_put_u16(out + n, p->codes.code[c][i]);
  ocs_cache_release(w->cache, e);
  return n;
}

/* A range as oc_brick_encode() makes them: both 0, or 0 < lo ≤ hi ≤ OC_VALUE_MAX. */
static int range_ok(oc_range_t r) {
  return (r.lo == 0.0f && r.hi == 0.0f) || (r.lo > 0.0f && r.lo <= r.hi && r.hi <= OC_VALUE_MAX);
}

int ocs_world_offer(ocs_world_t *w, oc_key_t key, uint64_t stamp, const uint8_t *content, size_t n) {
  if (n < SHARE_HEAD || content[0] > OC_NODE_BRICK) return OC_ECORRUPT;
  payload_t got;
  got.kind = content[0];
  int ok = n == (got.kind == OC_NODE_BRICK ? (size_t)OCS_SHARE_MAX_BYTES : (size_t)SHARE_HEAD);
  for (int c = 0; c < OC_CHANNELS; c++) {
    got.range[c] = (oc_range_t){oc_get_f32(content + 1 + 8 * c), oc_get_f32(content + 5 + 8 * c)};
    ok &= range_ok(got.range[c]) && (got.kind != OC_NODE_EMPTY || got.range[c].hi == 0.0f);
  }
  if (!ok) return OC_ECORRUPT;
  if (got.kind == OC_NODE_BRICK)
    for (int c = 0, o = SHARE_HEAD; c < OC_CHANNELS; c++)
      for (int i = 0; i < OC_BRICK_VOXELS; i++, o += 2) got.codes.code[c][i] = oc_get_u16(content + o);
  payload_t *p = payload_copy(&got);
  if (!p) return OC_ENOMEM;
  ocs_cache_key_t k = ckey(w, T_BRICK, key, stamp, 0);
  ocs_cache_entry_t *e;
  int r = ocs_cache_try_acquire(w->cache, &k, &e);
  if (r != OCS_CACHE_MISS) { /* here already, or being made here: the local one stands */
    if (r == OCS_CACHE_HIT) ocs_cache_release(w->cache, e);
    free(p);
    return r < 0 ? r : 0;
  }
  ocs_cache_publish(w->cache, e, p, payload_bytes(p->kind));
  ocs_cache_release(w->cache, e);
  return 1;
}

/* world.h — the server core: one world clock, one sun, one field, one brick cache, many viewers.
 *
 * Each epoch (ocs_world_step(): tests step by command, the network server on its timer) every
 * viewer that acknowledged its previous state gets a new plan from its planner (planner.h); the
 * bricks all plans lack are produced once, in parallel, through the shared cache (brick_cache.h),
 * and each viewer's output is a state in the one format of common/ (oc_state.h) plus the ids of the
 * bricks it does not hold yet. A viewer that has not acknowledged is skipped (the epoch is
 * coalesced and counted) and its next plan is sized from the bricks it absorbed per epoch.
 *
 * Content is a pure function of (node key, stamp): the stamp of level L hashes the field's time
 * steps of levels 0..L (τ marches through coarser levels), the sun direction (its bits, hashed) and the shadows flag.
 * Static fields have constant stamps: nothing is ever produced twice for a viewer.
 *
 * Production of a brick: σt from the field (cache entry "sigma", keyed by key and the node's own
 * time step, ocs_field_node_step); τ, when the scene has shadows and the node's σt is not all zero, from the
 * sun-aligned optical-depth volume of the node's group (sun_depth.h; cache entry "tau volume",
 * keyed by group, level, light stamp and sun), marching through "sigma" entries of coarser levels;
 * then the codes (cache entry "brick", keyed by key and stamp).
 *
 * Ahead: a level whose own time step lasts several epochs would resample all its leaves' σt in the
 * epoch its step changes, and one whose light stamp lasts several epochs would rebuild all its τ
 * volumes then. After each step (stepped) or in what is left of production's window (clocked), the
 * leaves holding σt at such levels get their next step's "sigma" entry and their group's next "tau
 * volume", each epoch its share of those still missing, up to 16 epochs before they are due;
 * OCS_AHEAD=0 turns it off for before/after benches. It changes no byte: entries are keyed by the
 * stamps they are made for, and content is a function of them.
 *
 * Keeping: a missing "tau volume" is copied from the one of the light stamp before when every
 * input that one recorded gives the same answer now (ocs_tau_volume_unchanged), and a missing
 * "sigma" entry from the node's step before when the field proves the samples the same
 * (ocs_field_same_samples): the same bytes a build or a sampling would make. OCS_TAU_KEEP=0 and
 * OCS_SIGMA_KEEP=0 turn them off for before/after benches. */
#ifndef OC_SERVER_WORLD_H
#define OC_SERVER_WORLD_H

#include <stddef.h>
#include <stdint.h>

#include "brick_cache.h" /* ocs_cache_stats_t */
#include "brick_value.h"
#include "histogram.h"
#include "oc_scene.h"
#include "oc_state.h"
#include "planner.h"

typedef struct ocs_world_s ocs_world_t;
typedef struct ocs_viewer_s ocs_viewer_t;

typedef struct {
  int threads;               /**< producer threads incl. the caller; 0 → online CPUs (≤ 64) */
  uint64_t cache_bytes;      /**< shared brick cache cap; 0 → 256 MiB */
  uint64_t viewer_bytes;     /**< sum of granted viewer budgets allowed; 0 → 4 GiB */
  uint64_t max_budget;       /**< largest budget one viewer is granted; 0 → a fair share: a quarter
                                  of viewer_bytes, at most 1 GiB (OCS_FAIR_SHARE_MAX) */
  int max_viewers;           /**< 0 → 64 */
  double time;               /**< world time at start_utc, s; default 0 */
  double start_utc;          /**< the instant the clock starts (s since the Unix epoch, clocked
                                  mode); 0: the virtual clock of ocs_world_step() */
  int validate;              /**< check every produced state with oc_state_validate (tests) */
  /** test hook: called before a brick is made; a negative return fails that brick (an error of
   *  the producer), which is counted (ocs_world_stats_t.produce_errors) and asked again */
  int (*fault)(void *ctx, oc_key_t key);
  void *fault_ctx;
  int clocked;               /**< production runs behind the ticks: a step builds states only from
                                  content that exists (ocs_plan_input_t.ready), what the plans wait
                                  for goes to one production queue for all viewers, and
                                  ocs_world_produce() makes it between ticks; 0: a step produces
                                  everything its plans ask before its states go out */
  int exact_filter;          /**< bricks from each source's exact box filter (ocs_field_set_exact):
                                  the oracle of the fast ones, for benches and tests */
  uint64_t content_id;       /**< what the bricks' bytes depend on beyond the world's own state:
                                  the build and the scene's content (ocs_scene_digest()); 0: bricks
                                  are not shared between front-ends ("Sharing bricks" below) */
} ocs_world_desc_t;

typedef struct {
  uint64_t epoch;            /**< epochs stepped */
  double time;               /**< world time of the last epoch, s */
  uint64_t bricks_produced;  /**< final bricks made (cache misses): the generation counter */
  uint64_t sigma_produced;   /**< σt entries made: samplings of the field, or kept (sigma_kept) */
  uint64_t tau_volumes;      /**< τ volumes made (built, or kept: tau_kept) */
  uint64_t brick_requests;   /**< bricks asked for by plans, before sharing */
  ocs_cache_stats_t cache;   /**< the brick cache's counters (brick_cache.h) */
  double cache_hit_rate;
  uint32_t viewers;
  uint64_t granted_bytes;    /**< sum of viewers' budgets */
  uint64_t held_bytes;       /**< server-side memory of the states kept for viewers */
  double produce_seconds, plan_seconds; /**< wall time of the last step's phases (clocked: of the
                                           last production between ticks) */
  double target_seconds;     /**< the clocked target plans' of the last production (not in plan_seconds) */
  uint64_t tau_direct;       /**< clear-sky proofs: ground nodes a group volume considers
                                  (ocs_tau_desc_t.ground), nodes outside their group's volume
                                  (ocs_tau_direct) */
  uint64_t tau_clear;        /**< of those, proven clear toward the sun: τ = 0 without a march */
  uint64_t tau_columns;      /**< of those, ground nodes a group volume covers (its columns) */
  uint64_t produce_errors;   /**< bricks whose production failed (clocked: asked again) */
  double brick_cpu;          /**< seconds producer threads spent making bricks (σt, τ, codes;
                                  per-brick wall timers on threads that run nothing else) */
  double brick_cpu_empty;    /**< of that, on bricks that ended up empty (σt and τ all zero) */
  uint64_t bricks_empty;     /**< bricks made that ended up empty */
  struct {                   /**< the same per level (the three above are their sums): where the
                                  wasted work is */
    uint64_t made, empty;
    double cpu, cpu_empty;
  } level[OC_KEY_MAX_LEVEL + 1];
  uint64_t ahead_sigma;      /**< σt sampled ahead for a slow level's next time step (in sigma_produced) */
  uint64_t ahead_empty;      /**< of those, all zero */
  uint64_t ahead_tau;        /**< τ volumes built ahead for a level's next light stamp (in tau_volumes) */
  uint64_t tau_kept;         /**< τ volumes kept from the light stamp before, their inputs unchanged
                                  (in tau_volumes, which counts those made either way) */
  uint64_t sigma_kept;       /**< σt of a node kept from its step before, proven the same
                                  (ocs_field_same_samples; in sigma_produced) */
  double ahead_cpu;          /**< seconds producer threads spent on both (not in brick_cpu) */
  double ahead_cpu_empty;    /**< of that, on the all-zero ones */
  uint64_t ahead_stock_sigma; /**< of ahead_sigma, those made for a time step not due yet (world time
                                   before it): the stock ahead keeps, not in any brick made so far */
  uint64_t ahead_stock_tau;  /**< likewise of ahead_tau, for a light stamp not due yet */
  double ahead_cpu_stock;    /**< of ahead_cpu, what the stock took: a run that stops now spent it on
                                  no brick it made */
  int last_error;            /**< the last failure's OC_E* and brick */
  oc_key_t last_error_key;
  ocs_hist_view_t brick_seconds; /**< what each brick made took (wall s on its producer thread) */
} ocs_world_stats_t;

typedef struct {
  const oc_state_t *state;   /**< the epoch's state (valid until the viewer's next output) */
  const uint32_t *lacking;   /**< ids of bricks of `state` the viewer does not hold yet, ascending */
  uint32_t nlacking;
  ocs_plan_stats_t plan;
} ocs_epoch_out_t;

typedef struct {
  uint64_t epochs_sent, coalesced; /**< states produced for it; due ticks it got none of (unacknowledged, or skipped by the clock) */
  uint64_t acked;                  /**< newest acknowledged epoch (UINT64_MAX: none) */
  uint64_t resident_bytes;         /**< of the states it keeps (the budget measure) */
  uint64_t budget;                 /**< the budget its plans are made under now */
  uint64_t reserved;               /**< what admission counts for it: `budget`, or a larger one its
                                        kept states were planned under, or a raise asked for */
  uint32_t produced;               /**< bricks made for it (clocked: that it wished for) between its
                                        two newest states */
  uint8_t age_p50[OC_KEY_MAX_LEVEL + 1], age_p99[OC_KEY_MAX_LEVEL + 1]; /**< per level, the content age of
                                      the newest state's leaves in time steps behind current;
                                      255: older than the world remembers, or no leaf there */
} ocs_viewer_stats_t;

/*! ocs_world_create() : builds the field of `scene` (deep-copied), the cache and the pool.
 *  @return 0 or a negative OC_E* with a one-line reason. */
int ocs_world_create(ocs_world_t **out, const oc_scene_t *scene, const ocs_world_desc_t *desc, char *why, size_t why_len);
void ocs_world_free(ocs_world_t *w);

/*! The largest budget one viewer gets by default: a quarter of the total, at most this. */
#define OCS_FAIR_SHARE_MAX (1ull << 30)
uint64_t ocs_world_fair_share(uint64_t total);
/*! ocs_world_total_budget() : the sum of viewer budgets allowed (viewer_bytes with its default). */
uint64_t ocs_world_total_budget(const ocs_world_t *w);

/* What a request would be granted, for admission (net_admit.c). */
typedef struct {
  uint64_t wanted;      /**< the request clamped to [minimum, max_budget] (0: max_budget < minimum) */
  uint64_t minimum;     /**< the root in every kept state (ocs_plan_min_budget) */
  uint64_t max_budget;  /**< the per-viewer maximum */
  uint64_t left;        /**< of the total, not granted to any viewer */
  int viewers_left;     /**< viewers that may still join */
} ocs_admission_t;
void ocs_world_admission(const ocs_world_t *w, const ocs_plan_desc_t *req, ocs_admission_t *out);

/*! ocs_world_add_viewer() : admits a viewer with the request `req` (budget, slot and record bytes,
 *  max depth; optional planner knobs). kept_states is set by the world (3 animated, 2 static).
 *  The granted request (clamped) goes to *granted. @return 0; OC_ERANGE (budget cannot be met:
 *  server full or request below what remains), OC_ETOOBIG (too many viewers), OC_ENOMEM. */
int ocs_world_add_viewer(ocs_world_t *w, const ocs_plan_desc_t *req, ocs_viewer_t **out, ocs_plan_desc_t *granted,
                         char *why, size_t why_len);
/*! ocs_world_remove_viewer() : frees everything of the viewer (NULL ok). */
void ocs_world_remove_viewer(ocs_world_t *w, ocs_viewer_t *v);
/* Budget changes (planner.h, "Budget changes"; docs/architecture.md). */
/*! ocs_world_set_budget() : the viewer's budget from its next possible plan on: a raise at its
 *  next plan, a lowering once its newest state fits it (its steady target heads there meanwhile).
 *  A raise is reserved at once; a lowering's old budget stays reserved until the states planned
 *  under it have left its K kept states. Only for viewers whose protocol has BUDGET.
 *  @return 0, or OC_ERANGE with a reason (below the minimum, above the per-viewer maximum, above
 *  its reservation and what is not granted). */
int ocs_world_set_budget(ocs_world_t *w, ocs_viewer_t *v, uint64_t budget, char *why, size_t why_len);
/*! ocs_viewer_budget_changes() : on: the viewer's protocol has BUDGET; room freed later raises it
 *  toward what it asked when admitted with less. Off (the default): its budget is fixed. */
void ocs_viewer_budget_changes(ocs_viewer_t *v, int on);
/*! ocs_viewer_budget_news() : a budget put in force and not told yet: 1 with it and the first
 *  epoch planned under it (to be sent before that epoch's state), else 0. */
int ocs_viewer_budget_news(ocs_viewer_t *v, uint64_t *budget, uint64_t *epoch);
/*! ocs_viewer_budget_resend() : a resumed viewer was welcomed with its reservation: a lowering in
 *  force that its window still holds older states of is told again, from the next epoch. */
void ocs_viewer_budget_resend(ocs_viewer_t *v);
/*! ocs_viewer_set_view() : the latest camera; the next epoch plans with it. @return 0 / OC_EINVAL. */
int ocs_viewer_set_view(ocs_viewer_t *v, const ocs_view_t *view);
/*! ocs_viewer_ack() : the viewer applied state `epoch`. @return 0, OC_EINVAL (not the epoch in
 *  flight). */
int ocs_viewer_ack(ocs_viewer_t *v, uint64_t epoch);
/*! ocs_viewer_output() : the newest state produced for the viewer. @return 0 or OC_ENOENT. */
int ocs_viewer_output(const ocs_viewer_t *v, ocs_epoch_out_t *out);
void ocs_viewer_stats(const ocs_viewer_t *v, ocs_viewer_stats_t *out);
/*! ocs_viewer_held() : the i-th newest state sent to the viewer (0: the newest, possibly not yet
 *  acknowledged), or NULL. Valid until the viewer's next epoch is produced. */
const oc_state_t *ocs_viewer_held(const ocs_viewer_t *v, int i);
/*! ocs_viewer_in_flight() : 1 while the newest state is unacknowledged. */
int ocs_viewer_in_flight(const ocs_viewer_t *v);

/*! ocs_world_step() : the next epoch on the virtual clock (stepped mode, tests, benches, offline):
 *  epoch e+1 at instant (e+1)·P, P the scene's epoch period, so its world time is
 *  T0 + (e+1)·P·scale without control changes. Plans every ready viewer, produces, emits.
 *  @return 0 or a negative OC_E* (the viewers' previous states are kept). */
int ocs_world_step(ocs_world_t *w);
/*! ocs_world_step_at() : epoch `epoch` (> the last one) at its due instant `utc` (clocked mode:
 *  n·P since the Unix epoch); its world time is the clock's at `utc` (world_clock.h). */
int ocs_world_step_at(ocs_world_t *w, uint64_t epoch, double utc);
/*! ocs_world_produce() : clocked worlds: produces the queue's bricks, best first, for at most
 *  `seconds` (a brick started is finished) and at most `limit` of them (0: no limit); what is left
 *  is asked again at the next tick, if some viewer still wants it. A brick that fails is counted
 *  (ocs_world_stats_t.produce_errors), stays queued and does not stop the others. Nothing else may
 *  touch the world meanwhile. @return bricks made, or a negative OC_E* (no memory to start). */
int ocs_world_produce(ocs_world_t *w, double seconds, size_t limit);
/*! ocs_world_produce() in three parts, so that a tick need not wait for the bricks in flight.
 *  _begin() (nothing else may touch the world): plans the targets, makes the queue and takes its
 *  best `limit` items (0: all) for production, with a copy of the clock; OC_EAGAIN if begun and not
 *  ended. @return the bricks taken, or a negative OC_E*.
 *  _run() (on a thread of its own): produces them on the world's pool; no brick is started that
 *  is expected to end after `seconds` from _begin(), except one expected to take longer than the
 *  whole window, while the window is young (its first quarter), and one expected to end before
 *  the bricks already started: they finish late. While it runs, ocs_world_step_at() (a clocked
 *  tick: it produces nothing and uses no pool) may run on another thread, and nothing else.
 *  _end() (nothing else may touch the world): counts what was made for the viewers that wanted it
 *  (ocs_viewer_stats_t.produced) and, if no tick ran meanwhile, takes it off the queue.
 *  @return bricks made. */
int ocs_world_produce_begin(ocs_world_t *w, double seconds, size_t limit);
int ocs_world_produce_run(ocs_world_t *w);
int ocs_world_produce_end(ocs_world_t *w);
/*! ocs_world_parallel() : fn(ctx, i, worker) for i < n on the threads a clocked tick plans its
 *  viewers with (the caller's thread among them; serially where there are none), for work of the
 *  tick that is independent per viewer (the network layer sets up each viewer's stream with it).
 *  Not while the world steps. @return 0 or fn's first negative result. */
int ocs_world_parallel(ocs_world_t *w, size_t n, int (*fn)(void *ctx, size_t index, int worker), void *ctx);
/*! ocs_world_queue_length() : bricks waiting in the production queue (clocked). The queue of a
 *  tick is made when production starts (ocs_world_produce(), even for 0 seconds), after each
 *  viewer's target plan: those are whole plans, kept off the tick's path. Until then, what the
 *  last production left. */
size_t ocs_world_queue_length(const ocs_world_t *w);
/*! ocs_world_production_due() : clocked, and targets to plan or bricks queued. */
int ocs_world_production_due(const ocs_world_t *w);
/*! ocs_world_queue_peek() : the i-th best item of the queue: its node, priority (the sum over the
 *  viewers that want it of their normalised priorities) and how many viewers want it.
 *  @return 0 or OC_ENOENT (i ≥ the queue's length). */
int ocs_world_queue_peek(const ocs_world_t *w, size_t i, oc_key_t *key, double *prio, uint32_t *viewers);
/*! ocs_world_utc() / ocs_world_epoch() : the instant and index of the last epoch stepped
 *  (start_utc and 0 before the first). */
double ocs_world_utc(const ocs_world_t *w);
uint64_t ocs_world_epoch(const ocs_world_t *w);
/*! ocs_world_time_at() : world time at instant utc (the control history's function). */
double ocs_world_time_at(const ocs_world_t *w, double utc);
/*! ocs_world_carry_clock() : `to` (a reloaded scene's new world) goes on from `from`'s clock: its
 *  control history, last epoch and instant. */
void ocs_world_carry_clock(ocs_world_t *to, const ocs_world_t *from);
/*! ocs_world_set_sun() : the sun moves (unit vector toward it): every τ is recomputed. */
int ocs_world_set_sun(ocs_world_t *w, oc_dvec3 sun_dir);
/*! ocs_world_set_time() / ocs_world_set_time_scale() / ocs_world_pause() / ocs_world_resume() :
 *  entries of the control history at instant utc (≥ the last epoch's): world time t from then on;
 *  world seconds per wall second (0 pauses); scale 0; back to the last non-zero scale.
 *  @return 0 or OC_EINVAL (|t| > 1e12, scale outside [0, 1e6]). */
int ocs_world_set_time(ocs_world_t *w, double utc, double t);
int ocs_world_set_time_scale(ocs_world_t *w, double utc, double scale);
int ocs_world_pause(ocs_world_t *w, double utc);
int ocs_world_resume(ocs_world_t *w, double utc);
/*! ocs_world_set_origin() : the control history starts again from one entry, world time t at
 *  instant utc (a front-end of a shared world takes the cluster's origin before its first epoch:
 *  control_stream.h). @return 0 or OC_EINVAL. */
int ocs_world_set_origin(ocs_world_t *w, double utc, double t);
/*! ocs_world_set_weather() : every procedural source moves to `preset` over `seconds` from the
 *  world time at instant utc. */
int ocs_world_set_weather(ocs_world_t *w, double utc, oc_preset_t preset, double seconds);
void ocs_world_stats(const ocs_world_t *w, ocs_world_stats_t *out);

/*! ocs_world_plan_offline() : adds a viewer with `req` looking through `view`, steps `epochs`
 *  epochs acknowledging each state (progress per epoch through oc_log_info), copies its final
 *  state into `out` (initialised) and removes the viewer: the state a viewer would hold, for
 *  overcast-server --save-state and the benches. @return 0 or a negative OC_E* with a reason. */
int ocs_world_plan_offline(ocs_world_t *w, const ocs_plan_desc_t *req, const ocs_view_t *view, int epochs, oc_state_t *out,
                           char *why, size_t why_len);
/*! ocs_world_stamp_at() : the content stamp of `level` at world time t: content of that level
 *  made at t1 and at t2 is the same iff their stamps are. */
uint64_t ocs_world_stamp_at(const ocs_world_t *w, int level, double t);
typedef struct {
  int kind;                      /**< oc_node_kind_t */
  oc_range_t range[OC_CHANNELS];
  oc_brick_codes_t codes;        /**< when kind is OC_NODE_BRICK, else zero */
} ocs_brick_out_t;
/*! ocs_world_reproduce() : the content of node `key` as it is made at world time t, by a world of
 *  its own without viewers (overcast-stress --verify-content; it moves that world's clock).
 *  @return 0 or a negative OC_E*. */
int ocs_world_reproduce(ocs_world_t *w, oc_key_t key, double t, ocs_brick_out_t *out);
const oc_scene_t *ocs_world_scene(const ocs_world_t *w);
/*! ocs_world_kept_states() : K, the states every viewer keeps: 3 animated, 2 static. */
int ocs_world_kept_states(const ocs_world_t *w);
/*! ocs_world_sun() : the unit vector toward the sun now. */
oc_dvec3 ocs_world_sun(const ocs_world_t *w);
const struct ocs_field_s *ocs_world_field(const ocs_world_t *w);

/*-*** Sharing bricks between front-ends (clocked worlds; brick_remote.h, docs/scale-out.md) ***
 * Between a tick and the production behind it, the network layer looks the queue's bricks up in
 * the shared store: a brick found there is offered to the cache (production then finds it made),
 * one another front-end is making is held back until the next tick, and what production made is
 * taken after it ends, exported and stored for the others. Offers and holds may come while
 * production runs (they only touch the cache and a locked table); the rest runs on the loop's
 * thread while no tick runs. */

#define OCS_SHARE_CHANNEL_BRICK 1u /* the identity's channel of a final brick (codes and ranges) */
/*! Largest exported brick: kind, OC_CHANNELS ranges (two f32 each), the codes. */
#define OCS_SHARE_MAX_BYTES (1 + 8 * OC_CHANNELS + OC_BRICK_CODE_BYTES)

/*! ocs_world_brick_id() : the brick (key, stamp)'s identity across front-ends: desc.content_id,
 *  the weather history, the sun direction's bits, the stamp, the node and the channel. */
ocs_bkey_t ocs_world_brick_id(const ocs_world_t *w, oc_key_t key, uint64_t stamp);
/*! ocs_world_queue_item() : the node and stamp of the queue's i-th best item. @return 0 or OC_ENOENT. */
int ocs_world_queue_item(const ocs_world_t *w, size_t i, oc_key_t *key, uint64_t *stamp);
/*! ocs_world_offer() : a brick made elsewhere (ocs_world_export()'s bytes) into the cache, unless it
 *  is there or being made here already. @return 1 taken, 0 not needed, OC_ECORRUPT (bad kind,
 *  length or range: discarded), OC_ENOMEM. */
int ocs_world_offer(ocs_world_t *w, oc_key_t key, uint64_t stamp, const uint8_t *content, size_t n);
/*! ocs_world_export() : the cached brick (key, stamp) packed into out (≥ OCS_SHARE_MAX_BYTES).
 *  @return its bytes, 0 when it is no longer cached. */
size_t ocs_world_export(ocs_world_t *w, oc_key_t key, uint64_t stamp, uint8_t *out, size_t cap);
/*! ocs_world_hold_back() : another front-end is making (key, stamp): production here skips it
 *  (it stays queued) until ocs_world_hold_clear(), which the network layer calls at every tick. */
void ocs_world_hold_back(ocs_world_t *w, oc_key_t key, uint64_t stamp);
void ocs_world_hold_clear(ocs_world_t *w);
/*! ocs_world_made_take() : up to cap of the bricks made since the last take (only with a
 *  content_id), newest first. @return how many. */
size_t ocs_world_made_take(ocs_world_t *w, oc_key_t *keys, uint64_t *stamps, size_t cap);

#endif /* OC_SERVER_WORLD_H */

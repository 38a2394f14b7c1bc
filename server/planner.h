/* planner.h — the LOD planner: one per viewer, re-plans that viewer's octree once per epoch under
 * its memory budget (design.md, Conventions: state, budget, epochs; Epochs, states, interpolation).
 *
 * The planner holds a complete octree (the leaves of the last state it planned) and, each epoch,
 * moves it toward the viewer's camera with Pettersson's split/merge loop: leaves in descending split
 * priority against mergeable parents (all 8 children leaves) in ascending merge priority; the best
 * split is taken while it fits, else the cheapest merge is taken to make room, and the loop stops
 * when the cheapest merge is worth more than the best split. Priority is a screen-space error: the
 * pixels a voxel (node size / 7) spans at the node's nearest point to the eye, times
 * `outside_weight` outside the view frustum and outside_weight² again when the whole node is hidden
 * behind the planet's horizon (its nearest point is farther than the sum of the eye's and the
 * node's highest point's horizon distances). Nodes known (or bounded) to be empty or uniform in σt,
 * inside the planet or above the atmosphere, or at max_depth, are never split.
 *
 * Budget (the Conventions' measure). The viewer keeps K states (3 animated, 2 static): resident =
 * distinct bricks of those states × slot_bytes + their records × record_bytes ≤ budget. With the
 * K−1 states it still holds (the last ones sent), a new state N must satisfy, for j = 0..K−1,
 *     C_j = (records and distinct bricks of the newest K−1−j held states) + (1+j)·records(N)
 *           + the bricks of N not among them  ≤ budget,
 * i.e. the window stays within budget now (j = 0) and would stay within it if N were repeated j
 * more times. The last condition makes "send N again, reusing its bricks" always admissible next
 * epoch, so a plan always exists and the invariant can never be broken, whatever the camera does.
 * Bricks are predicted conservatively (a node the bound cannot prove empty or uniform counts as a
 * brick); actual content is only ever cheaper.
 *
 * Within those hard limits the tree's steady cost T = K·records·record_bytes + slot_bytes·Σ over
 * leaves of (made·(1 + (K−2)·r) + predicted·r) — r the fraction of epochs in which the leaf's
 * level changes, made 1 when its content came out a brick, predicted 1 when a refresh counts as a
 * brick in the C_j before it is made (stepped: the bound's class; clocked: as made) — is kept
 * under (1 − reserve)·budget, so that every epoch keeps `reserve` of the budget for change (new
 * bricks while the old ones are still held). T is what the leaf adds to the C_j on average, so it
 * does not jump in the epochs that refresh more levels (the tree split and merged by turns when a
 * refresh counted a whole slot only then). A brick costs 1 + (K−1)·r slots; static fields have
 * r = 0: one slot. Stepped, a refreshed leaf keeps the σt class it was made with (an empty one is
 * not split) until its new content is made.
 *
 * Content: every leaf carries a content stamp (the world's per-level stamp: field time step, light
 * step, sun). A leaf whose stamp changed is refreshed (new brick id) when the limits allow, nearest
 * first; otherwise it keeps its old brick for another epoch (counted as deferred). A brick id
 * names one content: it is reused exactly when the same key and stamp are held. */
#ifndef OC_SERVER_PLANNER_H
#define OC_SERVER_PLANNER_H

#include <stddef.h>
#include <stdint.h>

#include "oc_brick.h" /* oc_node_kind_t */
#include "oc_budget.h" /* oc_budget_t */
#include "oc_key.h"   /* oc_key_t */
#include "oc_math.h"  /* oc_dvec3 */

#define OCS_PLAN_MAX_KEPT 3

typedef struct {
  /** the budget contract (oc_budget.h): budget (see ocs_plan_clamp()), GPU bytes per brick slot and
   *  per node record, K kept states (3 animated, 2 static) */
  OC_BUDGET_MEMBER(grant);
  int max_depth;           /**< deepest level, 0..21 */
  double split_fraction;   /**< most new nodes per epoch, as a fraction of capacity; 0 → 0.1 */
  double reserve;          /**< budget fraction kept free for change; 0 → split_fraction */
  double min_pixels;       /**< a leaf is split only while its voxel spans more; 0 → 1 */
  double outside_weight;   /**< priority factor outside the frustum, (0, 1]; 0 → 0.25 */
} ocs_plan_desc_t;

/*! ocs_plan_clamp() : applies the server's limits to a viewer's request, in place: slot and
 *  record bytes to [1, 1 MiB], max_depth to [0, 21], kept_states to 2..3, fractions to sane
 *  ranges, and the budget up to the minimum (the root in every kept state) and down to max_budget.
 *  @return 0, or OC_ERANGE when the request cannot be honoured (budget below the minimum is
 *  raised, not refused; a zero max_budget or one below the minimum is OC_ERANGE). */
int ocs_plan_clamp(ocs_plan_desc_t *d, uint64_t max_budget);
/*! ocs_plan_min_budget() : the root as a brick in each of the K kept states. */
uint64_t ocs_plan_min_budget(const ocs_plan_desc_t *d);

typedef struct {
  oc_dvec3 pos;          /**< eye, planet frame, m */
  oc_dvec3 forward, up;  /**< unit, orthogonal */
  double vfov_deg;       /**< (0, 180) */
  int width, height;     /**< viewport, pixels */
} ocs_view_t;

/* What the world tells the planner about content, per epoch. */
typedef struct {
  /*! The node's σt class from a conservative bound (OC_NODE_BRICK when unsure); only a BRICK
   *  may be split. Called from the planning thread only. */
  oc_node_kind_t (*classify)(void *ctx, oc_key_t key);
  void *ctx;
  int uniform_is_brick;    /**< shadows on: a uniform σt node still carries a τ gradient (a brick) */
  int ground_tau;          /**< shadows on the ground: an empty node of level ≥ OCS_GROUND_TAU_LEVEL
                                touching the planet surface carries τ for the ground (a brick,
                                still never split); see ocs_plan_ground_tau() */
  uint64_t stamp[OC_KEY_MAX_LEVEL + 1];    /**< content stamp per level at this epoch's time */
  double refresh_rate[OC_KEY_MAX_LEVEL + 1]; /**< fraction of epochs a level's content changes, [0,1] */
  uint32_t max_new_bricks; /**< throughput limit for this plan (slow viewer); 0 = none */
  double split_scale;      /**< the split cap (split_fraction of capacity) times this for this plan;
                                ≤ 1: 1. Clocked plans take only splits whose children exist, so
                                production paces them and the cap can be wider */
  double step_change[OC_KEY_MAX_LEVEL + 1]; /**< per level, the share of content one time step
                                changes (docs/performance.md); a refresh wished for (want()) is
                                worth the node's pixels times this, so production goes where change
                                shows; 0: 1 */
  /*! Clocked epochs (production runs behind the ticks): new content is used only when it exists.
   *  ready() returns the stamp of content of (key) that exists, `stamp` itself or an older stamp of
   *  that level (stale but complete) newer than `held` (the stamp the node shows, 0: none: a
   *  refresh never goes back in time), or 0 when none does; NULL: everything is ready (stepped
   *  epochs produce what their plan asks before it goes out). It sets *kind to that content's
   *  oc_node_kind_t as made: the plan counts its cost by it (the field's bound, classify(), says
   *  "brick" of much that comes out empty, and a tick's costs swung by a third with the refreshes
   *  it took), and splits still by the bound's class. want() is told what was not ready,
   *  with the pixels it would buy (the split's or the leaf's priority); NULL: not told. With want()
   *  but no ready(), the plan is a target: want() hears of the new content of its final tree,
   *  inner nodes included (what a split that a later merge undid took is not wished), and the plan
   *  is then abandoned. */
  uint64_t (*ready)(void *ctx, oc_key_t key, int level, uint64_t stamp, uint64_t held, uint8_t *kind);
  void (*want)(void *ctx, oc_key_t key, uint64_t stamp, double prio);
} ocs_plan_input_t;

/* One leaf of a plan, in canonical key order. */
typedef struct {
  oc_key_t key;
  uint64_t stamp;    /**< content stamp the leaf holds */
  uint32_t brick_id; /**< reused brick (content held by the viewer); 0 when `produce` or no brick */
  uint8_t kind;      /**< predicted (or known) oc_node_kind_t */
  uint8_t produce;   /**< 1: content must be produced for (key, stamp) */
  uint8_t held;      /**< produce = 0: the i-th newest held state (1..K-1) has this content */
} ocs_plan_leaf_t;

typedef struct {
  uint32_t splits, merges;       /**< applied this epoch */
  uint32_t refreshed, deferred;  /**< stamp changes served / left for a later epoch */
  uint32_t split_backlog;        /**< splits that waited for their children's content (ready()) */
  uint32_t new_bricks;           /**< predicted new bricks (productions the viewer lacks) */
  uint32_t leaves, max_level;
  uint64_t predicted_bytes;      /**< C_0: the resident bytes once this plan is applied */
  uint64_t steady_bytes;         /**< T, the steady cost */
  const char *stop;              /**< why the split loop stopped */
  double seconds;                /**< wall time of ocs_plan_epoch() */
} ocs_plan_stats_t;

typedef struct ocs_planner_s ocs_planner_t;

/*! ocs_planner_create() : a planner holding the root alone (nothing held by the viewer yet).
 *  The desc must have passed ocs_plan_clamp(). @return 0, OC_EINVAL or OC_ENOMEM. */
int ocs_planner_create(ocs_planner_t **out, const ocs_plan_desc_t *d);
void ocs_planner_free(ocs_planner_t *p);
const ocs_plan_desc_t *ocs_planner_desc(const ocs_planner_t *p);

/*! ocs_plan_epoch() : re-plans for `view`. The result (leaves in key order) stays valid until the
 *  next call; it must be committed (ocs_plan_commit) before planning again. With in->ready, a
 *  split is taken only with all 8 children's content, a merge only with its parent's, a refresh
 *  only with newer content; the rest waits (in->want).
 *  @return 0, OC_EINVAL (bad view), OC_EAGAIN (nothing to show yet: the viewer's first content is
 *  not ready) or OC_ENOMEM (the previous tree is kept). */
int ocs_plan_epoch(ocs_planner_t *p, const ocs_view_t *view, const ocs_plan_input_t *in,
                   const ocs_plan_leaf_t **leaves, uint32_t *count, ocs_plan_stats_t *stats);

/*! ocs_plan_commit() : the plan was turned into a state and sent. For each leaf (same order),
 *  `kind` is the actual kind and `brick_id` its brick (0 unless OC_NODE_BRICK). The state becomes
 *  the newest the viewer holds; the oldest drops out of the window. @return 0 or OC_ENOMEM. */
int ocs_plan_commit(ocs_planner_t *p, const uint8_t *kind, const uint32_t *brick_id);
/*! ocs_plan_abandon() : the plan was not sent (e.g. production failed): the tree returns to the
 *  last committed one. */
void ocs_plan_abandon(ocs_planner_t *p);

/*! ocs_plan_resident() : resident bytes of the held states (the window ending at the newest). */
uint64_t ocs_plan_resident(const ocs_planner_t *p);

/* Budget changes (BUDGET, docs/architecture.md "Budget changes"). Each held state remembers the
 * budget it was planned under, and window j of the limits above counts against the largest budget
 * of the states in it (the new plan's and the held ones'): the viewer's own rule (ocp_viewer.c).
 * A raise may be put in force at once. A lowering to B is put in force only once the newest held
 * state N fits B on its own (K·records(N) + bricks(N) ≤ B, ocs_plan_fits()): then "N repeated"
 * meets every window's limit, the invariant above holds under the new limits, and from the K-th
 * state planned under B on every window fits B. Until then ocs_plan_aim() lowers the steady
 * target, so that merges bring the tree there. */
/*! ocs_plan_fits() : the newest committed state, repeated K times, fits `budget` (1) or not (0). */
int ocs_plan_fits(const ocs_planner_t *p, uint64_t budget);
/*! ocs_plan_set_budget() : plans from the next on are planned under `budget` (a pending plan is
 *  abandoned). @return 0, or OC_EINVAL (below the minimum, or a lowering the newest state does not
 *  fit). */
int ocs_plan_set_budget(ocs_planner_t *p, uint64_t budget);
/*! ocs_plan_aim() : the steady target heads for `budget` (when below the one in force; else none). */
void ocs_plan_aim(ocs_planner_t *p, uint64_t budget);
/*! ocs_plan_reserved() : what any later window may use: the largest of the budget in force and
 *  those the K−1 newest held states were planned under (the oldest leaves as the next comes). */
uint64_t ocs_plan_reserved(const ocs_planner_t *p);

/*! Coarsest level whose empty ground nodes carry τ: a 6 km node, 880 m voxels. Coarser ground
 *  nodes are far from any camera that sees their shadows at that resolution. */
#define OCS_GROUND_TAU_LEVEL 11
/*! ocs_plan_ground_tau() : whether an empty node carries τ for cloud shadows on the ground. */
int ocs_plan_ground_tau(oc_key_t key);

/*! ocs_view_priority() : the split priority of a node: voxel pixels at the nearest point, times
 *  outside_weight when the node's bounding sphere is outside the frustum. */
double ocs_view_priority(const ocs_view_t *v, oc_key_t key, double outside_weight);
/*! ocs_view_valid() : finite position, unit-ish orthogonal axes, fov and viewport in range. */
int ocs_view_valid(const ocs_view_t *v);

#endif /* OC_SERVER_PLANNER_H */

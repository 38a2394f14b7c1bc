/* voxelize.h — box-filtered brick sampling and a state builder for fields given as callbacks.
 *
 * Sampling follows design.md (Conventions: bricks and codes; filtering): sample (i, j, k) of a node
 * sits at origin + (i, j, k)·size/7 and holds the box average of the field over the cube of edge
 * size/7 centred on it. The average is estimated with sub³ stratified midpoint sub-samples
 * (sub = 1: a point sample). Positions are computed from the global integer sample lattice of the
 * node's level, x = −S + (g + f)·u with g = 7·ix + i, u = (2S/7)·2^−level and f the sub-sample
 * offset in (−½, ½), so a face sample evaluates exactly the same points from either of the two
 * nodes that share it, and its value is bit-identical in both bricks.
 *
 * The builder, ocs_voxelize(), refines the root to min_level everywhere and further to max_level
 * where asked (AABB list and/or a callback), samples every leaf — σt box-filtered, τ normally
 * point-sampled — and returns a canonical, validated state. Output bytes do not depend on the
 * thread count. ocs_voxelize_medium() does this for an analytic medium (analytic.h). */
#ifndef OCS_VOXELIZE_H
#define OCS_VOXELIZE_H

#include <stdint.h>

#include "analytic.h" /* ocs_medium_t */
#include "oc_key.h"      /* oc_key_t */
#include "oc_math.h"     /* oc_dvec3 */
#include "oc_state.h"    /* oc_state_t */

/*! Most sub-samples per axis accepted by the builder (sub³ field evaluations per sample). */
#define OCS_VOXELIZE_MAX_SUB 16
/*! Most worker threads used by the builder. */
#define OCS_VOXELIZE_MAX_THREADS 64

/* A scalar field: a value at a planet-frame point (metres). Must be thread-safe (called from
 * several threads at once with the same ctx) and deterministic. */
typedef double (*ocs_field_fn)(void *ctx, oc_dvec3 p);
/* A refinement predicate: nonzero to split `key` (see ocs_voxelize_desc_t for when it is asked). */
typedef int (*ocs_refine_fn)(void *ctx, oc_key_t key);

typedef struct {
  oc_dvec3 lo, hi; /**< planet frame, metres, lo ≤ hi */
} ocs_aabb_t;

/*! ocs_brick_sample_pos() : position of sample (i, j, k) (each 0..7) of a node, planet frame; the
 *  sub = 1 sampling point of ocs_brick_sample(), bit-identical for a face sample from either node. */
oc_dvec3 ocs_brick_sample_pos(oc_key_t key, int i, int j, int k);
/*! ocs_brick_sample() : the 8³ box-filtered samples of fn over a valid node, x fastest
 *  (out[i + 8j + 64k]). Each is the mean of fn at sub³ stratified midpoints of the cube of edge
 *  size/7 centred on the sample (offsets ((m + ½)/sub − ½)·size/7 per axis, m = 0..sub−1), summed
 *  in double in a fixed order; sub < 1 is taken as 1, sub > OCS_VOXELIZE_MAX_SUB as that. Samples
 *  on a face shared with a neighbour of the same level are bit-identical to the neighbour's. */
void ocs_brick_sample(oc_key_t key, double (*fn)(void *ctx, oc_dvec3 p), void *ctx, int sub, float out[512]);

typedef struct {
  uint32_t leaves;             /**< node records */
  uint32_t empty, uniform;     /**< of which empty / uniform */
  uint32_t bricks;             /**< of which bricks (payloads) */
  uint32_t per_level[22];      /**< leaves per level */
  oc_sanitize_stats_t sanitize; /**< values oc_sanitize() replaced, summed over both channels */
  double seconds;              /**< wall time of the whole call */
} ocs_voxelize_stats_t;

/* What ocs_voxelize() builds. Zero-initialise (ocs_voxelize_desc_t d = {0};) and set what you need;
 * every default is the zero value's meaning given per field.
 *
 * Refinement: a node of level L is split when L < min_level, or when min_level ≤ L < max_level
 * and it is wanted: it meets at least one AABB (when aabb_count > 0) AND refine(refine_ctx, key)
 * is nonzero (when refine is set). With neither an AABB list nor a callback nothing is refined
 * beyond min_level. Before the AABB test the node's box is grown by margin plus its own sample
 * footprint half-width size/14 (the box filter reaches that far outside the node), so a coarse
 * leaf's samples never see what lies inside an AABB. Leaves outside every AABB stay at min_level
 * and are sampled like any other (their τ may well be non-zero). */
typedef struct {
  ocs_field_fn sigma;  /**< required: σt, m⁻¹ (negative, NaN, Inf are sanitised and counted) */
  ocs_field_fn tau;    /**< optional: sun optical depth τ; default NULL: τ = 0 everywhere */
  void *ctx;          /**< passed to sigma and tau; default NULL */
  int min_level;      /**< 0..21; default 0 (the root) */
  int max_level;      /**< min_level..21; default 0, which means min_level (no refinement) */
  const ocs_aabb_t *aabbs; /**< optional regions to refine; default none */
  int aabb_count;         /**< entries in aabbs; default 0 */
  double margin;          /**< metres added around every AABB; default 0 */
  ocs_refine_fn refine;    /**< optional refinement criterion; default none. Called from the
                               calling thread only, twice per node (a counting pass, then a
                               placing pass): it must give the same answer both times */
  void *refine_ctx;       /**< passed to refine; default NULL, which means ctx */
  int sub_sigma;      /**< sub-samples per axis for σt (box filter), 1..16; default 0 → 4 */
  int sub_tau;        /**< sub-samples per axis for τ, 1..16; default 0 → 1: τ is a lighting
                           quantity (an optical depth toward the sun, smooth along the sun ray) and
                           the Conventions define the box filter for σt only, so τ is point-sampled
                           at the sample position unless asked otherwise. Above 1, where the
                           mean of a box's 8 corner sub-samples matches its centre within 1e-3,
                           τ is taken as trilinear there and that mean is used (9 evaluations) */
  uint64_t epoch;     /**< copied into the state; default 0 */
  double time;        /**< copied into the state, finite; default 0 */
  oc_dvec3 sun_dir;   /**< toward the sun, copied into the state (normalised unless already unit
                           within 1e-12); required non-zero. It is NOT passed to tau: the tau
                           callback carries its own sun (through ctx) */
  uint32_t first_brick_id; /**< id of the first brick; ids ascend in key order; default 0 → 1 */
  int threads;        /**< worker threads, 1..64; default 0 → 1. Output is identical for any count */
  uint32_t max_nodes; /**< refuse (OC_ETOOBIG) when the tree would have more leaves than this;
                           default 0 → OC_STATE_MAX_NODES, also the ceiling */
  ocs_voxelize_stats_t *stats; /**< optional out: counts and timing; default NULL */
} ocs_voxelize_desc_t;

/*! ocs_voxelize() : builds a complete state from field callbacks. `out` must be initialised
 *  (oc_state_init); on success its previous content is freed and replaced by a canonical state that
 *  passed oc_state_validate(); on error `out` is left empty.
 *  Every leaf: both channels sampled (ocs_brick_sample), oc_sanitize(), oc_brick_encode(); bricks get
 *  ids first_brick_id, first_brick_id + 1, ... in ascending key order.
 *  @return 0; OC_EINVAL for a bad desc (or a refine callback that changed its answers);
 *  OC_ETOOBIG when the tree would exceed max_nodes leaves (found by a counting pass, before
 *  anything is allocated or sampled) or OC_STATE_MAX_BRICKS bricks (found while sampling, which
 *  then stops); OC_ERANGE when the brick ids would pass UINT32_MAX; OC_ENOMEM; OC_ECORRUPT if the
 *  result fails oc_state_validate() (a bug). */
int ocs_voxelize(oc_state_t *out, const ocs_voxelize_desc_t *d);

/* Context of the medium callbacks below. */
typedef struct {
  const ocs_medium_t *medium;
  oc_dvec3 sun_dir; /**< toward the sun, for ocs_medium_tau_cb */
  double margin;    /**< metres, for ocs_medium_refine_cb */
} ocs_medium_ctx_t;

/*! ocs_medium_sigma_cb() / ocs_medium_tau_cb() : ocs_medium_sigma_t() and ocs_medium_tau_sun() as
 *  ocs_field_fn (ctx: const ocs_medium_ctx_t*). */
double ocs_medium_sigma_cb(void *ctx, oc_dvec3 p);
double ocs_medium_tau_cb(void *ctx, oc_dvec3 p);
/*! ocs_medium_refine_cb() : ocs_refine_fn (ctx: const ocs_medium_ctx_t*): nonzero when the node's
 *  box, grown by its footprint half-width size/14 plus ctx->margin, meets any primitive with
 *  σt > 0 (ocs_prim_intersects_box). Tighter than the primitives' AABBs for spheres, rotated boxes
 *  and slabs. */
int ocs_medium_refine_cb(void *ctx, oc_key_t key);

/*! ocs_voxelize_medium() : ocs_voxelize() of an analytic medium: σt = ocs_medium_sigma_t box-filtered
 *  with sub³ sub-samples (0 → 4), τ = ocs_medium_tau_sun toward sun_dir point-sampled, min_level 0,
 *  nodes refined to max_level where ocs_medium_refine_cb says (margin 0), epoch 0, time 0, first
 *  brick id 1, `threads` workers (0 → 1).
 *  A slab covers the whole planet, so refining it to a high level exceeds OC_STATE_MAX_NODES
 *  (OC_ETOOBIG). For a slab, call ocs_voxelize() with an AABB list to limit the region and
 *  refine = ocs_medium_refine_cb (the AABBs and the callback must both agree to split).
 *  @return as ocs_voxelize(). */
int ocs_voxelize_medium(oc_state_t *out, const ocs_medium_t *m, int max_level, int sub, oc_dvec3 sun_dir, int threads);

#endif /* OCS_VOXELIZE_H */

/* interp.h — the "previous value" of every leaf of the newest complete state (design.md,
 * Conventions: "Interpolation").
 *
 * Topology comes from the newest complete state N. For every leaf of N this module finds where its
 * previous value comes from in the previous complete state P, and materialises that value as the
 * renderer would see it, so the GPU can blend previous → current per node without ever looking at
 * P's topology:
 *
 *   NONE      no previous state (P == NULL): nothing to blend.
 *   SAME      P has the same key with identical content (same kind; bricks: same brick id and
 *             bit-identical ranges; uniform: bit-identical values; empty: empty). No blend needed
 *             and nothing stored.
 *   OWN       P has the same key with other content: P's own node, decoded (a brick's 8³ decoded
 *             samples per channel, or a uniform/empty node's value).
 *   PARENT    a new split: the leaf is a strict descendant of a P leaf A (one or several levels up).
 *             Sample (i, j, k) of the leaf is A's reconstruction evaluated at that sample's
 *             position, exactly as the renderer reconstructs (common/oc_render.c, oc__leaf_channel:
 *             ocg_brick_base / ocg_brick_frac / ocg_trilerp of ocg_code_decode'd corners; empty → 0,
 *             uniform → its value). The position is A-local u = (7c + i) / (7·2^D) per axis, with D
 *             the level difference and c the leaf's cell offset inside A, computed in double and
 *             rounded once to float (float(m/7)·7 rounds back to m exactly, so samples that fall on
 *             A's lattice pick exactly A's sample). A uniform or empty A gives a uniform value.
 *   CHILDREN  a merge: the leaf is a strict ancestor of P leaves (its P descendants, of any depth).
 *             Its previous value is kept at the children's resolution ("fine"): 8 sub-bricks, one
 *             per octant c = x | y<<1 | z<<2 (the key's child order), sub-brick c's sample
 *             (i, j, k) lying at leaf-local u = (c_axis + i/7) / 2 per axis, i.e. exactly on the
 *             8³ sample lattice of child c. Definition: that sample is the mean, over the P
 *             descendants inside octant c whose CLOSED box contains it, of each one's renderer
 *             reconstruction there (local u = (i·2^D − 7e) / 7 per axis in the descendant, D ≥ 0
 *             its depth below the octant, e its cell offset inside the octant, computed in double
 *             and rounded once to float). This set has exactly one member: descendant faces lie at
 *             dyadic fractions e/2^D of the octant and samples at i/7, and 7·e = i·2^D has no
 *             solution with 0 < i < 7 (7 is odd), so an interior sample never sits on a face
 *             between descendants, and one on the octant's own boundary (i = 0 or 7) is met by one
 *             descendant per axis (the code still sums and counts, so the definition holds as
 *             written). Consequences: for a one-level merge (the P leaves are the 8 children)
 *             sub-brick c is child c's own decoded samples, exactly (D = 0: u = i/7 picks sample i);
 *             for a deeper merge it is the descendants' field point-sampled one level finer than
 *             the merged leaf. The renderer reconstructs a fine previous value at leaf-local u from
 *             sub-brick c (c_axis = u ≥ ½) at u' = 2u − c_axis, clamped to [0,1], with the same
 *             trilinear code (shaders/raymarch.comp.glsl, ocv_prev_sample). Why not the merged
 *             leaf's own lattice: for a static field the children's field point-sampled there is
 *             almost exactly the server's new coarse content, so the cross-fade would start from
 *             an already-coarse picture and the detail the children resolved between the coarse
 *             samples would vanish in one frame (the merge would pop; tests/gl/test_gl_view.c,
 *             no_popping). At the children's resolution the blend starts from what was on screen
 *             (exactly, for a one-level merge) and the coarse content fades in over the period.
 *
 * Every previous value whose samples are all equal per channel (a uniform or empty source, a brick
 * that happens to be constant, or 8 sub-bricks that are all the same constant) is stored as
 * uniform = 1 with value[], not in the pool. Others take pool entries of 2×512 floats, σt then τ,
 * each x fastest (i + 8j + 64k), as bricks: one entry for OWN and PARENT (fine = 0), eight
 * consecutive ones for CHILDREN (fine = 1: sub-brick c is entry prev_index + c).
 * Memory: the prev array has one 16-byte entry per leaf of N; the pool holds exactly one 4 KiB
 * entry per non-uniform OWN/PARENT leaf and eight (32 KiB) per non-uniform CHILDREN leaf (merges
 * are few per epoch; a first pass classifies and sizes the pool, a second fills it; nothing for
 * SAME, NONE or uniform leaves).
 *
 * Algorithm: one merge pass over both states in spatial (Morton pre-order) order. Ascending key
 * order puts each level in one contiguous, Morton-sorted run (a level-L key lies in
 * [8^L, 2·8^L)); a ≤ 22-way merge of the level runs by first level-21 cell yields the leaves in
 * space-filling order without sorting, and the leaves of two partitions then nest or coincide as
 * two interval lists. Cost O((|P| + |N|)·levels) plus 2×512 trilinear evaluations per non-SAME
 * leaf (8× that per CHILDREN leaf); a P brick is decoded once (1024 decodes) however many new
 * leaves use it.
 *
 * Pure C, no GL, no allocation besides the result's arrays and small scratch buffers; thread-compatible
 * (distinct ocv_interp_t may be built concurrently). Both states must be valid
 * (oc_state_validate); what the merge can see of an invalid one (keys out of order, gaps,
 * overlaps) is reported as OC_ECORRUPT. */
#ifndef OC_CLIENT_INTERP_H
#define OC_CLIENT_INTERP_H

#include <stdint.h>

#include "oc_brick.h" /* OC_BRICK_VOXELS, OC_CHANNELS */
#include "oc_state.h" /* oc_state_t */

typedef enum {
  OCV_INTERP_NONE = 0,     /**< no previous state */
  OCV_INTERP_SAME = 1,     /**< same key, identical content: no blend */
  OCV_INTERP_OWN = 2,      /**< same key, other content: P's node decoded */
  OCV_INTERP_PARENT = 3,   /**< new split: a P ancestor resampled */
  OCV_INTERP_CHILDREN = 4, /**< merge: the P descendants sampled */
  OCV_INTERP_SOURCES = 5
} ocv_interp_source_t;

/*! prev_index of an entry without pool samples (NONE, SAME, or uniform). */
#define OCV_INTERP_NO_POOL UINT32_MAX
/*! Floats per pool entry: σt[512] then τ[512]. */
#define OCV_INTERP_ENTRY_FLOATS (OC_CHANNELS * OC_BRICK_VOXELS)
/*! Pool entries of a fine (CHILDREN) previous value: one sub-brick per octant. */
#define OCV_INTERP_FINE_ENTRIES 8

typedef struct {
  uint8_t source;      /**< ocv_interp_source_t */
  uint8_t uniform;     /**< 1: the previous value is value[] everywhere in the node (OWN, PARENT,
                            CHILDREN only); 0: see prev_index (NONE and SAME are always 0) */
  uint8_t fine;        /**< 1: prev_index is the first of OCV_INTERP_FINE_ENTRIES consecutive
                            entries, sub-brick c (octant c) at prev_index + c (non-uniform
                            CHILDREN only); 0: prev_index is one entry over the whole node */
  float value[OC_CHANNELS]; /**< uniform previous σt, τ; 0 otherwise */
  uint32_t prev_index; /**< pool entry (pool + prev_index·OCV_INTERP_ENTRY_FLOATS), or
                            OCV_INTERP_NO_POOL when uniform or NONE/SAME */
} ocv_interp_prev_t;

typedef struct {
  uint32_t node_count;     /**< entries of prev: the newest state's node_count */
  ocv_interp_prev_t *prev; /**< one per leaf of the newest state, same index */
  uint32_t pool_count;     /**< entries of pool in use */
  uint32_t pool_cap;       /**< entries allocated */
  float *pool;             /**< pool_count × OCV_INTERP_ENTRY_FLOATS */
} ocv_interp_t;

typedef struct {
  uint32_t count[OCV_INTERP_SOURCES]; /**< leaves per source */
  uint32_t uniform;                   /**< of the OWN/PARENT/CHILDREN ones, stored as uniform */
  uint32_t fine;                      /**< leaves with a fine (8-entry) previous value (the
                                           non-uniform CHILDREN) */
  uint32_t pooled;                    /**< pool entries in use: one per non-uniform OWN/PARENT
                                           leaf, OCV_INTERP_FINE_ENTRIES per fine leaf */
} ocv_interp_stats_t;

/*! ocv_interp_init() : an empty result. ocv_interp_free() releases it (NULL is fine) and leaves it
 *  empty, ready for reuse. */
void ocv_interp_init(ocv_interp_t *ip);
void ocv_interp_free(ocv_interp_t *ip);

/*! ocv_interp_build() : the previous value of every leaf of `next` (the newest complete state)
 *  from `prev` (the previous complete state, or NULL for the first state: every leaf NONE).
 *  `ip` must be initialised; its previous content is replaced (its buffers are reused).
 *  `prev` may be the same object as `next` (every leaf SAME).
 *  @return 0; OC_EINVAL (NULL ip or next); OC_ECORRUPT when either state is not a canonical
 *  partition of the root cube; OC_ENOMEM. On error ip is left empty (node_count 0). */
int ocv_interp_build(ocv_interp_t *ip, const oc_state_t *prev, const oc_state_t *next);

/*! ocv_interp_samples() : the 512 previous samples of channel ch (OC_CH_SIGMA, OC_CH_TAU) of leaf
 *  i, x fastest; NULL when leaf i has no single pool entry (uniform, SAME, NONE, or fine: see
 *  ocv_interp_sub_samples) or i/ch is out of range. */
const float *ocv_interp_samples(const ocv_interp_t *ip, uint32_t i, int ch);

/*! ocv_interp_sub_samples() : the 512 samples of channel ch of sub-brick `sub` of leaf i: for a fine
 *  leaf (CHILDREN) octant sub's lattice (0..7, u = (sub_axis + i/7)/2 per axis), else sub 0 is
 *  the one entry over the whole node (as ocv_interp_samples); NULL when leaf i has no pool entry
 *  or sub/i/ch is out of range. */
const float *ocv_interp_sub_samples(const ocv_interp_t *ip, uint32_t i, int sub, int ch);

/*! ocv_interp_stats() : counts per source over ip (zeros for NULL). */
void ocv_interp_stats(const ocv_interp_t *ip, ocv_interp_stats_t *out);

/*! ocv_interp_param() : the blend parameter t = clamp((now − arrival) / period, 0, 1) of the
 *  Conventions (arrival: when the newest state was applied; period: the epoch period P, s);
 *  1 when period ≤ 0 or any input is not finite (never blend on nonsense). */
float ocv_interp_param(double now, double arrival, double period);

/*! The longest blend, in epoch periods: a viewer that fell further behind catches up instead. */
#define OCV_INTERP_MAX_SPAN 4
/*! ocv_interp_blend_seconds() : how long the blend from state `prev` to state `next` lasts: the
 *  wall time the world took to go from one to the other, (next − prev epoch index) × P for clocked
 *  epochs (their indices count periods since the Unix epoch, so a tick coalesced or skipped between
 *  them lengthens it; world time ran at the clock's scale over it), at least P and at most
 *  OCV_INTERP_MAX_SPAN × P; P when the indices do not increase. 0 when period ≤ 0 or not finite. */
double ocv_interp_blend_seconds(double period, uint64_t prev_epoch, uint64_t next_epoch);

/*! ocv_interp_weight() : the weight w of the NEWEST value of a leaf with this source; the shader
 *  shows mix(previous, newest, w) and may skip the previous value wherever w is 1.
 *    animated scenes : t for OWN, PARENT and CHILDREN (time interpolation); 1 for NONE and SAME.
 *    static scenes   : (animated = 0) no time interpolation, so OWN snaps (1); the one-epoch
 *                      cross-fade stays for PARENT and CHILDREN (split, merge), t; 1 for NONE
 *                      and SAME.
 *  t as ocv_interp_param(); an unknown source gives 1. */
float ocv_interp_weight(int source, int animated, double now, double arrival, double period);

#endif /* OC_CLIENT_INTERP_H */

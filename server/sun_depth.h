/* sun_depth.h — the τ channel: optical depth toward the sun at a node's 512 sample positions.
 *
 * τ(p) = ∫₀^∞ σt(p + s·sun) ds (dimensionless; design.md, Conventions: bricks and codes; light,
 * sun, world). It is view-independent: the level of detail follows the node's OWN level, never a
 * viewer's tree, so a node's τ is a function of (node key, σt at the field's time step, sun) and
 * may be shared by every viewer.
 *
 * What is integrated (docs/numerics.md, "Sun optical depth τ", has the derivation and the errors):
 *   - Filtering (Pettersson's shadow filtering): a node of level L is marched through σt
 *     box-filtered at level m = L − filter_levels (never coarser than min_level unless the node
 *     itself is), reconstructed between samples exactly as the renderer does (shaders/brick.h:
 *     trilinear in the node of that level containing the point).
 *   - A cone: the step at distance t from the start is Δ(t) = max(h0, cone·t), h0 = step_factor ×
 *     the voxel (size/7) of level m, and each step samples the level whose voxel is about Δ /
 *     step_factor (m − ⌊log2(Δ/h0)⌋, not coarser than min_level; Δ stops growing there). Far
 *     occluders are therefore sampled coarser, as the cone of directions toward the sun's disc
 *     widens. The ray is cut where the level changes, and each piece is integrated EXACTLY (up to
 *     rounding) through the reconstruction of its level: a 3D DDA walks it cell by cell through
 *     that level's sample lattice (cells of edge size/7, 7³ per node, never straddling nodes); on
 *     a cell segment the trilinear σt is a cubic in the ray parameter, which Simpson's rule (both
 *     ends and the middle) integrates exactly. τ is accumulated in double. step_factor therefore
 *     no longer sets a quadrature step, only (through h0) the distances where the cone changes
 *     level.
 *   - Empty-space skipping: on entering a node the coarsest node (min_level … the level walked)
 *     holding it whose σt bound is [0, 0] is jumped over to where the ray leaves it. The sampled reconstruction is
 *     exactly 0 there (every sample of a node at that level or finer inside it is a box average
 *     over its footprint), so skipping changes nothing but the cost; it is what makes clear sky
 *     cheap. A node whose bound is [v, v] adds v·length without fetching its brick (exact too).
 *   - Where the march stops: the planet's shadow is NOT in τ (the renderer multiplies by clear-sky
 *     transmittance). The ray is cut where it enters the sphere of radius OCS_TAU_PLANET_STOP
 *     (R − 10 km, the lowest altitude a scene may use), where it leaves the atmosphere sphere
 *     (R + 100 km) and where it leaves the root cube; a start point already below R − 10 km has
 *     τ = 0, and σt outside the atmosphere sphere counts as 0.
 *
 * Two methods give the same quantity:
 *   - ocs_tau_direct(): the reference. Each of the 512 samples (ocs_brick_sample_pos) is marched on
 *     its own.
 *   - The group volume: nodes of one level that share the ancestor `group_levels` up (default 2:
 *     4³ = 64 nodes) share one sun-aligned optical-depth grid. Columns run along the sun, one voxel
 *     v_L (size/7 of the nodes' level) apart laterally (OCS_TAU_COLUMN_SPACING), where the group
 *     needs τ: the four columns around the sun ray of every sample of a covered node (note 2 of
 *     ocs_tau_volume_build()), over the slices around those samples. Each column is marched ONCE:
 *     from the top of that run toward the sun by the same cone march (distances counted from the
 *     middle of the run), then along the run, integrated exactly at the march level like the
 *     direct march, recording the running integral at slices 1.5·v_L apart
 *     (OCS_TAU_SLICE_SPACING; a slice inside a cell splits it, each part again exact by Simpson),
 *     so every slice holds the exact τ of its point. A sample's τ is the trilinear
 *     interpolation of the grid (bilinear across the four columns around its sun ray, linear
 *     between slices). Only the slices a column needs are stored.
 *     Resolution and memory for a fully covered group (group_levels 2, any level): 930–1 500
 *     columns marched by sun direction (a 22nd to a 35th of the 32 768 marches of ocs_tau_direct()
 *     for the 64 nodes), 18 500–19 900 stored slices and a 1 050–2 070-entry column table:
 *     83–102 KiB per volume (the 64 nodes' τ floats are 128 KiB); partly covered groups cost
 *     less. Its only error against the direct march is the interpolation between columns and
 *     slices (docs/numerics.md); the speed-up over it is in docs/performance.md.
 *
 * Nodes without σt: a node whose σt is all zero needs no τ (nothing scatters there, and a renderer
 * never reads τ where σt = 0), so callers may skip it and store the node as empty. The functions
 * still compute its τ when asked: ocs_tau_direct() and ocs_tau_node() always, a volume when built
 * with cover_all (by default its lookup answers OC_ENOENT for such nodes).
 *
 * Thread safety and determinism: every function is pure given the callbacks; it keeps its own
 * memo of bricks and bounds for the duration of one call and shares nothing, so calls may run on
 * any number of threads at once, and results are bit-identical whatever the thread count or call
 * order (given deterministic callbacks). No -ffast-math: results are bit-identical across runs. */
#ifndef OC_SERVER_SUN_DEPTH_H
#define OC_SERVER_SUN_DEPTH_H

#include <stdatomic.h> /* atomic_long: ocs_tau_stats_t */
#include <stddef.h>    /* size_t */

#include "oc_brick.h"  /* OC_BRICK_VOXELS */
#include "oc_key.h"    /* oc_key_t */
#include "oc_math.h"   /* oc_dvec3 */
#include "oc_planet.h" /* OC_PLANET_RADIUS */

/*! Defaults of the zero fields of ocs_tau_desc_t. */
#define OCS_TAU_DEFAULT_FILTER_LEVELS 1
#define OCS_TAU_DEFAULT_STEP_FACTOR 1.0
/*! Growth of the step (and of the voxel sampled) with distance: 0.02·t, a cone of full angle 1.15°,
 *  about twice the sun's disc (0.53°). A cloud 10 km away is still seen at 200 m, the clear sky
 *  above the clouds costs a few dozen steps, and the cone's level-of-detail is what the volume's
 *  columns share with the direct march. */
#define OCS_TAU_DEFAULT_CONE 0.02
/*! Coarsest level sampled or asked for a bound by default: level 6 has 202 km nodes and 28.9 km
 *  voxels, about the height of the weather; a coarser voxel would average the clouds with the
 *  empty sky above them, and the cone only reaches it after about 1 450 km (grazing rays). */
#define OCS_TAU_DEFAULT_MIN_LEVEL 6
#define OCS_TAU_DEFAULT_GROUP_LEVELS 2
/*! Most levels between a group and its nodes (ocs_tau_volume_build refuses more: 16³ nodes). */
#define OCS_TAU_MAX_GROUP_LEVELS 4
/*! The march stops where the ray enters this sphere (m from the planet centre). */
#define OCS_TAU_PLANET_STOP (OC_PLANET_RADIUS - 10000.0)

/*! Lateral column spacing of the group volume, in voxels of the nodes' level (half the march
 *  level's voxel at the default filter_levels). τ has sharp lateral edges in the shadows of
 *  optically thick clouds, and interpolating across them is the volume's main error: at 1.0 its
 *  RMS error in e^-τ against the (exact) direct march is 0.005–0.019 on the bench's cumulus; 1.5
 *  costs 0.6× for 1.35–1.4× the error; 0.5 costs 3.3× more for 0.7× (docs/numerics.md). */
#ifndef OCS_TAU_COLUMN_SPACING
#define OCS_TAU_COLUMN_SPACING 1.0
#endif
/*! Spacing of the slices along each column, in voxels of the nodes' level: where the exact
 *  running integral is recorded (τ is linear between slices). It costs memory, hardly time (the
 *  column is walked cell by cell whatever the spacing): 0.75 gives 10–25 % less error for 1.6×
 *  the memory, 2.0 15–35 % more error for 0.85×, 3.0 50–80 % more for 0.7× (docs/numerics.md). */
#ifndef OCS_TAU_SLICE_SPACING
#define OCS_TAU_SLICE_SPACING 1.5
#endif

/*! ocs_tau_stats_t : what the direct march did, counted where a caller asks (ocs_tau_desc_t.stats);
 *  relaxed atomic increments, so one struct may serve every thread. Zero-initialise it. */
typedef struct {
  atomic_long direct;        /**< clear-sky proofs tried: ocs_tau_direct() and ocs_tau_columns()
                                  calls that got as far as marching or proving, and ground nodes a
                                  volume considers (ocs_tau_desc_t.ground) */
  atomic_long clear_proven;  /**< of those, nodes whose sun column was proven clear (bounds, and
                                  samples at the level walked: ocs_tau_direct(), note 1) */
  atomic_long clear_marched; /**< of those, provably clear nodes marched anyway (march_clear set):
                                  wasted work; 0 whenever march_clear is 0 */
  atomic_long columns;       /**< of those, nodes not proven clear whose τ came from their own
                                  columns (ocs_tau_columns()) or whom a group volume covers as
                                  ground (ocs_tau_desc_t.ground) */
} ocs_tau_stats_t;

/* How τ is computed. Zero-initialise (ocs_tau_desc_t d = {0};), set the callbacks and the sun;
 * every other zero field takes the default given here. */
typedef struct {
  /*! sigma() : the node's 512 box-filtered σt samples (m⁻¹, i + 8j + 64k), sanitised (≥ 0, finite;
   *  they are sanitised again here). @return 0 or a negative OC_E*, which aborts the call. */
  int (*sigma)(void *ctx, oc_key_t key, float out[OC_BRICK_VOXELS]);
  /*! bound() : a conservative σt range over the node's sample footprint (the node grown by
   *  size/14), as ocs_field_bound() gives. [0, 0] must mean every sample is 0 (the node is then
   *  skipped), [v, v] that every sample is v (its brick is then never fetched). */
  void (*bound)(void *ctx, oc_key_t key, float *smin, float *smax);
  void *ctx;          /**< passed to both; the callbacks must be thread-safe; they may be slow (a
                           cache lookup): each call here asks for a node at most once */
  oc_dvec3 sun_dir;   /**< toward the sun, planet frame; required, finite and non-zero (normalised
                           here) */
  int filter_levels;  /**< march level = node level − this, 1..21; 0 → 1 (a 2× wider filter) */
  double step_factor; /**< h0 = step_factor × voxel (size/7) of the march level, (0, 16];
                           default 0 → 1. Only sets where the cone changes level (the
                           integration is exact, not stepped) */
  double cone;        /**< Δ(t) = max(h0, cone·t), [0, 1]; default 0 → OCS_TAU_DEFAULT_CONE (0.02).
                           To march without a cone, give a tiny value (1e-12) */
  int min_level;      /**< coarsest level marched or bounded, 1..21; 0 → 6
                           (OCS_TAU_DEFAULT_MIN_LEVEL); a node coarser than it marches at its own
                           level */
  int group_levels;   /**< the volume's group is the ancestor this many levels up, 0..4; default
                           0 → 2 (64 nodes share one volume) */
  int cover_all;      /**< volumes cover every descendant; default 0: only those the march level's
                           σt says may hold σt (ocs_tau_volume_build(), note 2) */
  /*! ground() : whether a node that holds no σt needs τ all the same: the ground, which the
   *  renderer lights through τ (cloud shadows on it and in the air above it). NULL: none does.
   *  Volumes cover these too, unless the clear-sky proof gives their τ as 0 (ocs_tau_direct(),
   *  note 1), so the ground nodes of a group share its columns (ocs_tau_volume_build(), note 2).
   *  Called with ctx; it must be a pure function of the key (a volume's bits depend on it). */
  int (*ground)(void *ctx, oc_key_t key);
  int march_clear;    /**< march even nodes whose sun column is proven clear (ocs_tau_direct(),
                           note 1; the result is the same bits): for tests and before/after
                           figures; default 0 */
  ocs_tau_stats_t *stats; /**< counters to add to (may be NULL: none) */
} ocs_tau_desc_t;

/*! ocs_tau_direct() : τ at the node's 512 sample positions, each marched on its own (the reference).
 *  note 1 : clear sky costs nothing. Before marching, the node's box swept toward the sun (up to a
 *           bound on where any of its rays leaves the atmosphere) is covered by nodes whose bound
 *           is [0, 0], each at a level the march itself would test at that distance (level_lo ..
 *           the cone's level there), or, at that level itself, whose σt samples are all 0 (the
 *           walk fetches such a brick and jumps it); a hierarchical search from the root, on a
 *           budget. When that succeeds every ray only jumps empty nodes, so the march would give
 *           exactly 0 at every sample: τ = 0 is returned without marching, bit for bit what the
 *           march gives (the test compares them with march_clear). When it fails, the march runs
 *           exactly as it would have (bounds and bricks the proof asked for are memoised for it).
 *           Ground nodes under clear air are the common case.
 *  @return 0; OC_EINVAL for a bad desc or key; OC_ENOMEM; or the sigma callback's error. */
int ocs_tau_direct(const ocs_tau_desc_t *d, oc_key_t key, float tau[OC_BRICK_VOXELS]);

/*! ocs_tau_columns() : τ of a node from a volume of its own (ocs_tau_volume_build() with the node
 *  as its group, cover_all), after the clear-sky proof of ocs_tau_direct() (note 1, the same bits
 *  when it holds). For nodes that need τ but hold no σt, when no group volume covers them (the
 *  server's group volumes do, through ocs_tau_desc_t.ground): the ground, which the renderer
 *  lights through τ (cloud shadows on the ground and in the air above it). The
 *  node's own sun columns, one voxel apart over its shadow across the sun (about 80–130), are
 *  marched once each instead of 512 rays, with a group volume's interpolation error
 *  (docs/numerics.md, "The group volume"; larger on the ground, which shadow edges cross).
 *  @return as ocs_tau_direct(). */
int ocs_tau_columns(const ocs_tau_desc_t *d, oc_key_t key, float tau[OC_BRICK_VOXELS]);

/*! ocs_tau_group_of() : the ancestor `group_levels` (default 2) up of key, clamped at the root;
 *  OC_KEY_INVALID for an invalid key or desc. */
oc_key_t ocs_tau_group_of(const ocs_tau_desc_t *d, oc_key_t key);
/*! ocs_tau_march_level() : the finest level whose σt (and bounds) the τ of a node of `node_level`
 *  reads: node_level − filter_levels, never coarser than min_level, nor than the node itself
 *  (at the defaults: the node's own level up to level 6, the one above it below). A cache of τ
 *  must be keyed by the time steps of levels 0 … this one. @return it, or -1 (invalid). */
int ocs_tau_march_level(const ocs_tau_desc_t *d, int node_level);

/*! ocs_tau_volume_build() : the sun-aligned optical-depth grid for the descendants of `group` at
 *  `level` (level(group) ≤ level ≤ level(group) + OCS_TAU_MAX_GROUP_LEVELS, ≤ 21).
 *  On success *vol is ONE malloc'd block (release it with free()) of *bytes bytes; it holds all it
 *  needs (geometry and values, not the callbacks) and may be shared read-only between threads. It
 *  also records its inputs, for ocs_tau_volume_unchanged(): 16 bytes per bound asked, 24 per σt
 *  brick fetched.
 *  note 1 : group need not be ocs_tau_group_of() of anything: any ancestor works (bigger groups
 *           cost more memory per node and less marching).
 *  note 2 : coverage. By default the volume covers the descendants whose footprint meets a
 *           non-zero σt sample of the march level (the bricks its columns march through anyway;
 *           the sample cubes of a level tile space, so a descendant that is not covered has no σt
 *           at its own level either, up to the source's box-filter estimate: a faint wisp that
 *           only the finer level catches). Only covered descendants cost columns, so a group
 *           where few nodes hold σt is cheap. With cover_all every descendant is covered; with a
 *           ground() callback, also the descendants it names whose τ the clear-sky proof does not
 *           give as 0 (one volume's columns for a group's ground, where each node's own volume,
 *           ocs_tau_columns(), marched the columns along their shared faces again).
 *  @return 0; OC_EINVAL (bad desc, key or level); OC_ENOMEM; or the sigma callback's error (then
 *  *vol is NULL and *bytes 0). */
int ocs_tau_volume_build(const ocs_tau_desc_t *d, oc_key_t group, int level, void **vol, size_t *bytes);

/*! ocs_tau_volume_unchanged() : whether building `vol` again with d would make it again, bit for
 *  bit: 1 when it was built with d's parameters and sun and each of its inputs gets the same answer
 *  from d's callbacks now (every bound the build asked, and every σt brick it fetched, which the
 *  volume keeps as an XXH3-128 hash), else 0. The build is a deterministic function of those
 *  answers (each key is asked at most once, and what is asked next depends only on the answers
 *  before). ground() is not asked again: it must be the same pure function of the key. A caller
 *  keeps a volume through a change of time step that did not reach what it read: σt that stepped
 *  on but came out the same (most often all zero), or moved only where the volume never looked.
 *  It costs the callbacks' lookups, a fraction of a build's march.
 *  @return 1, 0, OC_EINVAL (bad desc or not a volume), or the sigma callback's error. */
int ocs_tau_volume_unchanged(const ocs_tau_desc_t *d, const void *vol);

/*! ocs_tau_volume_lookup() : τ at the 512 samples of `key`, a descendant of the volume's group at the
 *  volume's level (the group itself when the two levels are equal).
 *  @return 0; OC_ENOENT when the volume does not cover key (ocs_tau_volume_build(), note 2: its
 *  σt is zero at the march level, so it needs no τ; if its own brick does hold σt after all, use
 *  ocs_tau_direct() for it; a node the desc's ground() names is left out only when the clear-sky
 *  proof gave its τ as 0, the direct march's bits, so it needs no second proof); OC_EINVAL when vol is not a volume or key is not such a
 *  descendant; OC_ECORRUPT if a sample falls outside the grid (a bug). */
int ocs_tau_volume_lookup(const void *vol, oc_key_t key, float tau[OC_BRICK_VOXELS]);

/*! ocs_tau_node() : ocs_tau_volume_build() of ocs_tau_group_of(key) at key's level, then
 *  ocs_tau_volume_lookup() and free(); ocs_tau_direct() for a node the volume does not cover. A
 *  convenience for tests (the server caches volumes). @return as those. */
int ocs_tau_node(const ocs_tau_desc_t *d, oc_key_t key, float tau[OC_BRICK_VOXELS]);

#endif /* OC_SERVER_SUN_DEPTH_H */

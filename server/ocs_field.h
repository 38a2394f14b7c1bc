/* ocs_field.h — the cloud field the server owns: every source of a scene behind one interface.
 *
 * The field answers two questions about a node (design.md, Conventions: filtering):
 *   - the σt samples of its 8³ brick at world time t: sample (i, j, k) at origin + (i, j, k)·size/7,
 *     each the box average over the cube of edge size/7 centred on it of the FINEST σt, after every
 *     nonlinear remap (so a parent's mean equals its descendants' mean: no popping from filtering);
 *   - a cheap conservative bound [min, max] of σt over the node's sample footprint (the node grown
 *     by size/14 on every side), so empty and uniform nodes are known without sampling 512 points.
 * Sources add: the field's σt is the sum of its sources'. The τ (sun optical depth) channel is the
 * server core's job ([3/7]), not the field's.
 *
 * Bound cache: ocs_field_bound() remembers, per source whose vtbl sets bound_by_step, the last
 * bounds it computed in a fixed direct-mapped table of OCS_FIELD_BOUND_CACHE_SLOTS entries per
 * such source (32 bytes each: 2 MiB per procedural source, allocated at create, never grown),
 * keyed by (key, that source's node_step(key, t), or time_step(level of key, t) without one). The planner's classify, production's
 * known-empty check and every τ march ask for the same nodes again and again; a hit returns the
 * bits the source would compute. Entries are per-slot seqlocks (seqcache.h: lock-free, a reader
 * that meets a write in progress misses, a writer that meets another write skips its insert), and
 * ocs_field_set_weather() empties the table, so a generation wrap of the time step can never
 * revive an entry. A source with node_bound() is asked through it (it may remember more than the
 * field does: the procedural source keeps the per-layer ranges its sampler needs). ocs_field_stats() counts hits and misses. The environment variable
 * OCS_FIELD_BOUND_CACHE=0 at ocs_field_create() bypasses the cache (before/after benches).
 *
 * Thread safety: after ocs_field_create(), bound/sample/time_step may be called from any number
 * of threads at once. ocs_field_set_weather() and ocs_field_set_bound_cache() must not race with
 * them (the caller serialises; the server calls set_weather between epochs). */
#ifndef OC_SERVER_FIELD_H
#define OC_SERVER_FIELD_H

#include <stddef.h>
#include <stdint.h>

#include "oc_brick.h" /* OC_BRICK_VOXELS */
#include "oc_key.h"   /* oc_key_t */
#include "oc_math.h"  /* oc_dvec3 */
#include "oc_scene.h" /* oc_scene_t, oc_preset_t */

typedef struct ocs_source_s ocs_source_t;
typedef struct ocs_field_s ocs_field_t;

/* A source implements this table (server/source_*.c). bound, sample, time_step and destroy are
 * required; the others are optional, as each one's comment says (NULL: not offered). */
typedef struct {
  const char *name; /**< "sphere", "procedural", "vdb", ... */
  /*! bound() : conservative σt range over an axis-aligned planet-frame box at time t. */
  void (*bound)(const ocs_source_t *src, oc_dvec3 lo, oc_dvec3 hi, double t, float *smin, float *smax);
  /*! sample() : ADDS this source's box-filtered σt for node `key` at time t into out[512]. */
  int (*sample)(const ocs_source_t *src, oc_key_t key, double t, float out[OC_BRICK_VOXELS]);
  /*! time_step() : an index that changes exactly when the node's content at its resolution may
   *  change (0 forever for static content); part of the brick cache key. */
  uint64_t (*time_step)(const ocs_source_t *src, int level, double t);
  /*! point() : the finest σt at a point (optional; tests compare filtered samples with it). */
  double (*point)(const ocs_source_t *src, oc_dvec3 p, double t);
  /*! set_weather() : procedural only: move to `preset` over [t0, t0 + seconds]. */
  int (*set_weather)(ocs_source_t *src, oc_preset_t preset, double t0, double seconds);
  void (*destroy)(ocs_source_t *src);
  /*! bound_by_step : 1 when bound() over a node's sample footprint is a pure function of (node,
   *  node_step(node, t), or time_step(node's level, t) without one) between set_weather() calls,
   *  so the field may cache it (0: the field calls bound() every time). */
  int bound_by_step;
  /*! sample_exact() : optional; the exact box filter where sample() is a cheaper estimate of it
   *  (NULL: sample() is exact). Tests and benches compare the two (ocs_field_set_exact()). */
  int (*sample_exact)(const ocs_source_t *src, oc_key_t key, double t, float out[OC_BRICK_VOXELS]);
  /*! node_bound() : optional; bound() over node key's sample footprint, the same bits, for a source
   *  that keeps more of that answer for its sampler (the procedural source: its per-layer ranges).
   *  NULL: the field calls bound() with the footprint. */
  void (*node_bound)(const ocs_source_t *src, oc_key_t key, double t, float *smin, float *smax);
  /*! node_step() : optional; an index that changes exactly when node key's own content may change:
   *  equal at two times only where time_step(level of key) is, or where the content is the same
   *  though the level's step moved on (the procedural source: layers that step slower than the
   *  fastest, where only they meet the node). NULL: time_step(level of key, t). */
  uint64_t (*node_step)(const ocs_source_t *src, oc_key_t key, double t);
  /*! step_before() : optional; 1 and an instant *t0 in node key's own step before the one t is in
   *  (where a cache may still hold its samples), or 0 when the source has none to offer. */
  int (*step_before)(const ocs_source_t *src, oc_key_t key, double t, double *t0);
  /*! same_samples() : optional; 1 only when sample() and sample_exact() give node key the same
   *  bits at t0 and t1 though its node_step differs (a proof, not a comparison: the procedural
   *  source's moving layers absent from the node at both instants), else 0. */
  int (*same_samples)(const ocs_source_t *src, oc_key_t key, double t0, double t1);
} ocs_source_vtbl_t;

struct ocs_source_s {
  const ocs_source_vtbl_t *vt;
  int animated; /**< content depends on world time */
};

typedef struct {
  uint64_t sampled_bricks;  /**< sample() calls */
  uint64_t bound_calls;     /**< ocs_field_bound() calls */
  uint64_t bound_hits;      /**< source bounds answered by the bound cache */
  uint64_t bound_misses;    /**< source bounds computed by a cacheable source (then inserted) */
} ocs_field_stats_t;

/*! Entries of the bound cache per cacheable source (a power of two). */
#ifndef OCS_FIELD_BOUND_CACHE_SLOTS
#define OCS_FIELD_BOUND_CACHE_SLOTS 65536
#endif

/*! ocs_field_create() : builds every source of the scene (VDB files are opened here; the OpenVDB
 *  shim is loaded only if the scene has a vdb source). @return 0, or a negative OC_E* with a
 *  one-line reason naming the source and the problem in why. */
int ocs_field_create(ocs_field_t **out, const oc_scene_t *sc, char *why, size_t why_len);
/*! ocs_field_free() : NULL is accepted. */
void ocs_field_free(ocs_field_t *f);
/*! ocs_field_animated() : true when any source changes with world time. */
int ocs_field_animated(const ocs_field_t *f);
/*! ocs_field_bound() : conservative σt range over the node's sample footprint at time t. */
void ocs_field_bound(const ocs_field_t *f, oc_key_t key, double t, float *smin, float *smax);
/*! ocs_field_sample() : the node's 512 box-filtered σt samples at time t (sum of sources), not
 *  yet sanitised or encoded. @return 0 or a negative OC_E*. */
int ocs_field_sample(const ocs_field_t *f, oc_key_t key, double t, float out[OC_BRICK_VOXELS]);
/*! ocs_field_time_step() : combined time step of the sources for a node of this level. */
uint64_t ocs_field_time_step(const ocs_field_t *f, int level, double t);
/*! ocs_field_node_step() : combined node_step() of the sources for node key (the σt cache's key:
 *  the samples are a pure function of it); equals ocs_field_time_step() of the key's level where
 *  no source knows better. */
uint64_t ocs_field_node_step(const ocs_field_t *f, oc_key_t key, double t);
/*! ocs_field_step_before() : 1 and an instant *t0 of node key's previous own step, from the first
 *  source that offers one (the procedural planet), else 0. */
int ocs_field_step_before(const ocs_field_t *f, oc_key_t key, double t, double *t0);
/*! ocs_field_same_samples() : 1 when ocs_field_sample() gives node key the same bits at t0 and t1:
 *  each source's node_step is the same at both, or the source proves its samples the same
 *  (same_samples); else 0. The world keeps σt across a node step with it (lever 29). */
int ocs_field_same_samples(const ocs_field_t *f, oc_key_t key, double t0, double t1);
/*! ocs_field_point() : the finest σt at a point (sum over sources that provide point()). */
double ocs_field_point(const ocs_field_t *f, oc_dvec3 p, double t);
/*! ocs_field_set_weather() : every procedural source moves to `preset` over [t0, t0 + seconds];
 *  @return OC_EINVAL when the scene has no procedural source. */
int ocs_field_set_weather(ocs_field_t *f, oc_preset_t preset, double t0, double seconds);
void ocs_field_stats(const ocs_field_t *f, ocs_field_stats_t *out);
/*! ocs_field_set_bound_cache() : on = 0 bypasses the bound cache (and empties it), on = 1 uses it
 *  again (the default); for tests and before/after benches. Bounds are the same bits either way. */
void ocs_field_set_bound_cache(ocs_field_t *f, int on);

/*! ocs_field_set_exact() : on = 1 makes ocs_field_sample() use each source's exact box filter
 *  (sample_exact) where the source has one, on = 0 its default sample() again. For tests and
 *  benches (the oracle of the fast filters); not to be raced with sampling. The environment
 *  variable OCS_FIELD_EXACT=1 at ocs_field_create() sets it. */
void ocs_field_set_exact(ocs_field_t *f, int on);

/* Constructors of the source kinds (server/source_*.c), used by ocs_field_create(). */
int ocs_source_analytic_create(ocs_source_t **out, const oc_source_t *desc, char *why, size_t why_len);
int ocs_source_procedural_create(ocs_source_t **out, const oc_source_t *desc, uint64_t seed, char *why, size_t why_len);
int ocs_source_vdb_create(ocs_source_t **out, const oc_source_t *desc, char *why, size_t why_len);

#endif /* OC_SERVER_FIELD_H */

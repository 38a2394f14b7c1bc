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
 * Thread safety: after ocs_field_create(), bound/sample/time_step may be called from any number
 * of threads at once. ocs_field_set_weather() must not race with them (the caller serialises;
 * the server calls it between epochs). */
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

/* A source implements this table (server/source_*.c). All functions are required except
 * set_weather (procedural only) and point (tests and export may use it when present). */
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
} ocs_source_vtbl_t;

struct ocs_source_s {
  const ocs_source_vtbl_t *vt;
  int animated; /**< content depends on world time */
};

typedef struct {
  uint64_t sampled_bricks;  /**< sample() calls */
  uint64_t bound_calls;     /**< bound() calls */
} ocs_field_stats_t;

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
/*! ocs_field_point() : the finest σt at a point (sum over sources that provide point()). */
double ocs_field_point(const ocs_field_t *f, oc_dvec3 p, double t);
/*! ocs_field_set_weather() : every procedural source moves to `preset` over [t0, t0 + seconds];
 *  @return OC_EINVAL when the scene has no procedural source. */
int ocs_field_set_weather(ocs_field_t *f, oc_preset_t preset, double t0, double seconds);
void ocs_field_stats(const ocs_field_t *f, ocs_field_stats_t *out);

/* Constructors of the source kinds (server/source_*.c), used by ocs_field_create(). */
int ocs_source_analytic_create(ocs_source_t **out, const oc_source_t *desc, char *why, size_t why_len);
int ocs_source_procedural_create(ocs_source_t **out, const oc_source_t *desc, uint64_t seed, char *why, size_t why_len);
int ocs_source_vdb_create(ocs_source_t **out, const oc_source_t *desc, char *why, size_t why_len);

#endif /* OC_SERVER_FIELD_H */

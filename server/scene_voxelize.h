/* scene_voxelize.h — a whole state built at once from a scene's analytic sources, without a planner.
 *
 * The reference states of the benches (overcast-bench) and of the renderers' tests: the scene's
 * spheres, boxes and slabs become an analytic medium (analytic.h), voxelized with nodes refined
 * where a voxel would look larger than `pixels` pixels from the camera — a projected-size
 * criterion, the measure the planner (planner.h) uses too. The viewer never builds states: its
 * --scene mode starts overcast-server. */
#ifndef OCS_SCENE_VOXELIZE_H
#define OCS_SCENE_VOXELIZE_H

#include <stddef.h>
#include <stdint.h>

#include "analytic.h" /* ocs_medium_t */
#include "oc_camera.h"   /* oc_camera_t */
#include "oc_scene.h"    /* oc_scene_t */
#include "oc_state.h"    /* oc_state_t */

/*! Sub-samples per axis of both channels' box filter: σt's (the Conventions') and τ's, the same
 *  filter so that τ is the optical depth through the σt channel. */
#define OCS_SCENE_VOXELIZE_SUB 4

typedef struct {
  oc_camera_t camera;   /**< refinement follows its position and field of view */
  int viewport_height;  /**< pixels; default 0 → 360 */
  double pixels;        /**< split while a voxel spans more than this many pixels; default 0 → 2 */
  int max_level;        /**< deepest level; default 0 → 16 */
  uint32_t max_nodes;   /**< default 0 → 500 000 leaves */
  int threads;          /**< default 0 → 1 */
} ocs_scene_voxelize_desc_t;

/*! ocs_lod_pixels() : how many pixels a voxel (node size / 7) of `key` spans at its nearest point
 *  to `eye`, for a viewport of `pixels_per_radian` = height / (2·tan(fov/2)): the projected-size
 *  refinement measure. */
double ocs_lod_pixels(oc_key_t key, oc_dvec3 eye, double pixels_per_radian);

/*! ocs_scene_medium() : the scene's analytic sources as a medium. @return 0, or OC_ESCENE when the
 *  scene has a source that is not analytic (procedural, vdb: served by overcast-server), with the
 *  reason in why. */
int ocs_scene_medium(const oc_scene_t *sc, ocs_medium_t *m, char *why, size_t why_len);
/*! ocs_scene_voxelize() : builds the state (epoch 0, time 0, the scene's sun). */
int ocs_scene_voxelize(oc_state_t *out, const oc_scene_t *sc, const ocs_scene_voxelize_desc_t *d, char *why,
                      size_t why_len);

#endif /* OCS_SCENE_VOXELIZE_H */

/* field_state.h — a state built from a server field on the spot, for benches and previews.
 *
 * Until the server core ([3/7]) produces states, tools build one directly: leaves refined by
 * projected voxel size from a camera where the field's bound says there is something, σt as the
 * box average (sub³ points per sample) of the field's finest σt, and τ marched toward the sun
 * through that same field (fixed steps). It is a preview, not the server's producer. */
#ifndef OC_TOOLS_FIELD_STATE_H
#define OC_TOOLS_FIELD_STATE_H

#include <stddef.h>

#include "oc_camera.h"
#include "oc_state.h"
#include "ocs_field.h"

typedef struct {
  const ocs_field_t *field;
  double time;          /**< world time, s */
  oc_dvec3 sun_dir;     /**< unit, toward the sun */
  oc_camera_t camera;   /**< refinement follows it */
  int viewport_height;  /**< pixels (default 360) */
  double pixels;        /**< split while a voxel spans more than this (default 2) */
  int max_level;        /**< default 16 */
  int shadows;          /**< march τ toward the sun (else τ = 0) */
  double tau_step;      /**< m (default 250) */
  double tau_length;    /**< m marched toward the sun (default 20 000) */
  int threads;          /**< default 1 */
} oct_field_state_desc_t;

int oct_field_state(oc_state_t *out, const oct_field_state_desc_t *d, char *why, size_t why_len);

#endif /* OC_TOOLS_FIELD_STATE_H */

/* truth.h — stored Monte Carlo truth images (`overcast-bench truth --save`) read back, the case's
 * state rebuilt, and the real-time model scored against them: one implementation for the bench that
 * fits and reports the model (`overcast-bench model`) and the CI test that holds it to its bounds
 * (tests/tools/test_truth.c, the cases under tests/data/truth). */
#ifndef OCT_TRUTH_H
#define OCT_TRUTH_H

#include <stddef.h>

#include "oc.h"

#define OCT_TRUTH_EXPOSURE 10.0f /**< the exposure every bench tone-maps with before an RMSE 0–255 */

typedef struct {
  char scene[512];   /**< the scene file, as given to the bench (relative to the repository root) */
  char camera[160];  /**< "" for the scene's camera, else LAT,LON,ALT,HEADING,PITCH,FOV */
  double tau;        /**< optical depth of the first source across (sphere diameter, slab thickness) */
  double albedo, background;
  int w, h;
  long paths;
  double mean, mean_se; /**< the truth's image mean and its standard error */
  double env, env_se;   /**< image mean of the radiance per unit uniform-sky radiance (no sun); 0: not stored */
  double air_sigma, air_top; /**< the thin air the truth was traced in (oc_render_desc_t.air_sigma, air_top); 0: none */
  double *L, *se;       /**< per pixel, row-major from the top */
} oct_truth_case_t;

typedef struct {
  double mean;     /**< the model's image mean */
  double rel;      /**< (model − truth)/truth of the image mean */
  double rel_se;   /**< the truth's relative standard error of the mean */
  double rmse8;    /**< RMSE 0–255 after tone mapping (exposure 10) */
  double noise8;   /**< the RMSE 0–255 two truth seeds would show: √2 × each pixel's SE through the tone map */
} oct_truth_score_t;

/*! oct_truth_source_length() : the length across which τ is measured (sphere diameter, box height,
 *  slab thickness); 0 for other sources. oct_truth_source_sigma() : its σt field, or NULL. */
double oct_truth_source_length(const oc_source_t *src);
double *oct_truth_source_sigma(oc_source_t *src);
/*! oct_truth_scale() : every source's σt scaled alike so that the first source with a length has
 *  optical depth tau across it. @return 0, or -1 when it has no extinction to scale. */
int oct_truth_scale(oc_scene_t *sc, double tau);

/*! oct_truth_case_load() : reads a file of `overcast-bench truth --save`. @return 0 or OC_EINVAL (why). */
int oct_truth_case_load(oct_truth_case_t *c, const char *path, char *why, size_t why_len);
void oct_truth_case_free(oct_truth_case_t *c);

/*! oct_truth_case_state() : the case's scene (σt scaled so the first source has optical depth tau;
 *  its albedo), camera and state, voxelized as the truth was (root prefixes the scene path; NULL:
 *  as stored). The caller frees sc and st. @return 0 or a negative OC_E* (why). */
int oct_truth_case_state(const oct_truth_case_t *c, const char *root, oc_scene_t *sc, oc_camera_t *cam, oc_state_t *st,
                        char *why, size_t why_len);

/*! oct_truth_case_desc() : the reference render the truth was made for: OC_BG_CONSTANT, no atmosphere,
 *  the scene's octaves and albedo, step factor 0.25, the case's size, its thin air. */
oc_render_desc_t oct_truth_case_desc(const oct_truth_case_t *c, const oc_scene_t *sc, oc_camera_t cam);

/*! oct_truth_light() : the light the truth is traced in, on a render description: OC_BG_CONSTANT
 *  with radiance `background` (also a uniform sky on the clouds), no atmosphere, no planet, the
 *  delta sun of irradiance 1. */
void oct_truth_light(oc_render_desc_t *d, double background);

/*! oct_truth_ambient() : the model's image mean lit by a uniform sky of radiance 1 alone (no sun):
 *  what the truth's env line measures. @return 0 or a negative OC_E*. */
int oct_truth_ambient(const oct_truth_case_t *c, const oc_state_t *st, oc_render_desc_t d, double *mean);

/*! oct_truth_score() : the model image img against the case's truth. @return 0 or OC_ENOMEM. */
int oct_truth_score(const oct_truth_case_t *c, const oc_image_t *img, oct_truth_score_t *s);

#endif /* OCT_TRUTH_H */

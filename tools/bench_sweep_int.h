/* bench_sweep_int.h — the pieces of `overcast-bench sweep` (bench_sweep.c drives them):
 *   bench_sweep_server.c  the server core stepped for one viewer: its states, CPU time and wire bytes
 *   bench_sweep_render.c  the CPU reference or the GL renderer, timed, with reprojection and
 *                         interpolation frame sequences
 *   plot.c                the error-against-time scatter plot (tools/plot.h, shared with overcast-stress)
 * Not part of the project's API: tools/ only. */
#ifndef OC_TOOLS_BENCH_SWEEP_INT_H
#define OC_TOOLS_BENCH_SWEEP_INT_H

#include <stddef.h>
#include <stdint.h>

#include "oc.h"
#include "plot.h"

/*-*** Server side (bench_sweep_server.c) ***/

typedef struct {
  uint64_t budget;       /**< bytes */
  int max_depth;         /**< 0..21 */
  int epochs;            /**< epochs stepped, ≥ 1 */
  int threads;           /**< producer threads; 0 → all cores */
  double split_fraction; /**< planner split cap per epoch; 0 → the planner's default (0.1) */
  double reserve;        /**< budget fraction kept free for change; 0 → split_fraction */
  double time;           /**< world time at epoch 0 */
  int plan_w, plan_h;    /**< the viewport the planner sizes priorities for */
  int exact_filter;      /**< bricks from the sources' exact box filters (the fast ones' oracle) */
} octs_server_desc_t;

typedef struct {
  oc_state_t newest;     /**< the last epoch's state */
  oc_state_t prev;       /**< the epoch before it (empty when epochs == 1) */
  int animated;          /**< the field is animated (3 kept states) */
  double cpu_ms_mean, cpu_ms_last;   /**< process CPU time of ocs_world_step() per epoch */
  double wall_ms_mean;
  double wire_mean, wire_last;       /**< bytes of the encoded epoch (proto/ocp_epoch.h, deltas on) */
  uint64_t resident;                 /**< the viewer's resident bytes after the last epoch */
  uint32_t bricks_sent;              /**< over all epochs */
} octs_server_out_t;

/*! octs_server_run() : a fresh world of `sc`, one viewer looking through `pose`, `epochs` epochs
 *  stepped and acknowledged, each encoded as the server sends it. `progress` (may be NULL) gets
 *  each finished epoch. out is initialised here; free with octs_server_out_free().
 *  @return 0 or a negative OC_E* with a reason. */
int octs_server_run(const oc_scene_t *sc, const octs_server_desc_t *d, oc_camera_pose_t pose, octs_server_out_t *out,
                    void (*progress)(void *ctx, int epoch, int epochs), void *ctx, char *why, size_t why_len);
void octs_server_out_free(octs_server_out_t *o);

/*-*** Renderers (bench_sweep_render.c) ***/

typedef struct octs_renderer_s octs_renderer_t;

typedef struct {
  double step_factor;
  int ms_octaves;
  int reproject;         /**< GL only: a frame sequence with one pixel in 16 traced per frame */
  int interp;            /**< GL only: blend previous → newest state at interp_t */
  int truth_light;       /**< lit as the Monte Carlo truth is (oct_truth_light: OC_BG_CONSTANT 0, no
                              atmosphere, no planet, sun irradiance 1) instead of the scene's light */
} octs_render_knobs_t;

typedef struct {
  int width, height;
  int threads;           /**< CPU reference threads */
  int repeat;            /**< timed runs (sequences); the fastest counts */
  int frames;            /**< reprojection sequence length (≥ 2) */
  double motion;         /**< heading change per frame of the sequence, degrees */
  float interp_t;        /**< blend parameter with interpolation on */
  const oc_scene_t *scene;
  const oc_atmo_t *atmo;
} octs_render_desc_t;

/*! octs_renderer_open() : gl 0: the CPU reference; 1: the GL compute renderer on a headless EGL
 *  context (OC_HAVE_GL builds only). info receives a description of what renders.
 *  @return NULL with why on failure. */
octs_renderer_t *octs_renderer_open(int gl, const octs_render_desc_t *d, char *info, size_t info_cap, char *why,
                                    size_t why_len);
void octs_renderer_close(octs_renderer_t *r);
/*! octs_renderer_timer() : what octs_times_t.ms is: "cpu-ref" (the CPU reference's process CPU
 *  time, all threads), "llvmpipe-wall" (wall time of dispatch and read-back on Mesa's software
 *  renderer) or "gpu-timer" (GL timer queries of the passes on a GPU). */
const char *octs_renderer_timer(const octs_renderer_t *r);
/*! octs_renderer_set_states() : the states rendered from now on (newest; prev for interpolation,
 *  may be empty). They must outlive their use. @return 0 or OC_E* with why. */
int octs_renderer_set_states(octs_renderer_t *r, const oc_state_t *newest, const oc_state_t *prev, int animated, char *why,
                             size_t why_len);
typedef struct {
  double ms;             /**< the figure the timer names (octs_renderer_timer) */
  double wall, cpu;      /**< wall time, and process CPU time (every thread, llvmpipe's included), ms */
} octs_times_t;

/*! octs_render() : the view `pose` with knobs k into img (allocated, the desc's size); each time
 *  the fastest of `repeat` runs of one frame, or with reprojection of the sequence's mean frame
 *  after the first. @return 0 or OC_E* with why. */
int octs_render(octs_renderer_t *r, oc_camera_pose_t pose, const octs_render_knobs_t *k, oc_image_t *img, octs_times_t *tm,
                char *why, size_t why_len);

/*-*** Error against a Monte Carlo truth (bench_sweep_truth.c) ***/

typedef struct octs_truth_s octs_truth_t;

typedef struct {
  int w, h;              /**< the truth's size; the sweep's size is a multiple of it */
  int full_w, full_h;    /**< the sweep's image size */
  long paths;            /**< per truth pixel, spread evenly over the sweep pixels it covers */
  int threads;
} octs_truth_desc_t;

typedef struct {
  double rel;            /**< (image mean − truth mean) / truth mean */
  double rmse8;          /**< RMSE 0–255 (exposure 10) at the truth's size */
  double noise8;         /**< the RMSE 0–255 two truth seeds would show (oct_truth_score's noise8) */
  double truth_mean;     /**< the truth's image mean (> 0 for a scene with a lit cloud in view) */
} octs_truth_err_t;

/*! octs_truth_make() : the Monte Carlo truth of view `pose` of analytic scene sc (bench_mc.c, every
 *  scattering order, lit by oct_truth_light with background 0) through a state voxelized from the
 *  analytic sources as `overcast-bench truth` voxelizes (independent of the swept knobs). Each
 *  truth pixel averages the rays of the sweep pixels it covers. @return NULL with why. */
octs_truth_t *octs_truth_make(const oc_scene_t *sc, oc_camera_pose_t pose, const octs_truth_desc_t *d, char *why,
                              size_t why_len);
void octs_truth_free(octs_truth_t *t);
/*! octs_truth_score() : img (the sweep's size, rendered with truth_light) box-averaged to the
 *  truth's size and scored against it. @return 0 or OC_ENOMEM. */
int octs_truth_score(const octs_truth_t *t, const oc_image_t *img, octs_truth_err_t *e);

/*-*** Plot: tools/plot.h (octs_plot_png, shared with overcast-stress) ***/

#endif /* OC_TOOLS_BENCH_SWEEP_INT_H */

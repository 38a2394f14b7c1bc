/* test_gl_reproject.c — one pixel in 16 traced per frame (client/gl, shaders/reproject.comp.glsl):
 * with a still camera the 16th frame equals a full render bit for bit; the first frame has no
 * history and fills each 4×4 block from its traced pixel; after a small turn the reprojected frame
 * is much closer to a full render of the new view than the block fill is; switched off, a frame is
 * the full render; with jittered ray starts the frames average the jitter; after a sideways step,
 * history of uncovered background (cloud in the history) is rejected. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "oc_camera.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "scene_voxelize.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 56

/* The analytic sphere seen from the scene's camera: its state, uploaded (after require_gl()). */
typedef struct {
  oc_camera_pose_t pose;
  oc_camera_t cam;
  oc_state_t st;
  ocv_gl_state_t gs;
} sphere_view_t;

static void sphere_view_up(sphere_view_t *sv) {
  require_gl();
  char why[512];
  sv->pose = (oc_camera_pose_t){{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}; /* the scene's camera */
  sv->cam = oc_camera_from_pose(sv->pose);
  sphere_state(&sv->st, sv->cam, H, 0);
  assert_int_equal(ocv_gl_state_upload(&sv->gs, &sv->st, why, sizeof why), 0);
}

static void test_gl_reproject__frames(void **state) {
  (void)state;
  sphere_view_t sv;
  sphere_view_up(&sv);
  oc_render_desc_t d = const_bg_desc(sv.cam, W, H);
  char why[512];
  oc_image_t full = {0}, img = {0};
  assert_int_equal(oc_image_alloc(&full, W, H), 0);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  assert_int_equal(ocv_gl_render_state(ren, &sv.gs, &d, &full, why, sizeof why), 0);
  ocv_gl_history_t *hs = ocv_gl_history_create(W, H, why, sizeof why);
  assert_non_null(hs);
  ocv_gl_frame_stats_t fs;

  /* frame 0: no history */
  assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
  assert_int_equal(fs.traced, W * H / 16);
  assert_int_equal(fs.reprojected, 0);
  double block_fill = rmse(&img, &full);
  /* frames 1..15: still camera, every pixel traced once by the 16th */
  for (int f = 1; f < 16; f++) {
    assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
    assert_int_equal(fs.reprojected + fs.traced, W * H); /* still: nothing rejected */
  }
  assert_memory_equal(img.px, full.px, sizeof(float) * 4 * W * H);

  /* a turn of 0.3°: reprojection keeps most pixels and beats filling the blocks */
  sv.pose.heading += 0.3;
  d.camera = oc_camera_from_pose(sv.pose);
  assert_int_equal(ocv_gl_render_state(ren, &sv.gs, &d, &full, why, sizeof why), 0);
  assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
  double turned = rmse(&img, &full);
  printf("first frame (blocks filled): RMSE %.2f; after a 0.3° turn: RMSE %.2f, %u traced, %u reprojected, %u filled\n",
         block_fill, turned, fs.traced, fs.reprojected, fs.rejected);
  assert_true(fs.reprojected > W * H / 2);
  double tr, rp;
  ocv_gl_renderer_timings(ren, &tr, &rp);
  printf("GPU time (timer queries): trace %.3f ms, reproject %.3f ms\n", tr, rp);
  assert_true(tr >= 0 && rp >= 0); /* measured (llvmpipe reports about 0 for compute) */
  assert_true(turned < block_fill / 2);

  /* off: every pixel traced */
  assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 0, &img, &fs, why, sizeof why), 0);
  assert_int_equal(fs.traced, W * H);
  assert_memory_equal(img.px, full.px, sizeof(float) * 4 * W * H);

  /* jittered ray starts: the traced pixels join their history, so the frames average the jitter —
   * closer to the mean of 16 jittered full renders than any single jittered frame */
  d.camera = sv.cam;
  d.flags = OC_RF_JITTER;
  oc_image_t mean = {0}, one = {0};
  assert_int_equal(oc_image_alloc(&mean, W, H), 0);
  assert_int_equal(oc_image_alloc(&one, W, H), 0);
  memset(mean.px, 0, sizeof(float) * 4 * W * H);
  for (uint32_t f = 0; f < 16; f++) {
    d.frame = 100 + f;
    assert_int_equal(ocv_gl_render_state(ren, &sv.gs, &d, &one, why, sizeof why), 0);
    for (int i = 0; i < 4 * W * H; i++) mean.px[i] += one.px[i] / 16.0f;
  }
  ocv_gl_history_reset(hs);
  for (uint32_t f = 0; f < 96; f++) {
    d.frame = f;
    assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
  }
  double acc = rmse(&img, &mean), single = rmse(&one, &mean);
  printf("jitter: accumulated frames vs the mean of 16 jittered renders RMSE %.3f; one jittered render %.3f\n", acc, single);
  assert_true(acc < single);
  oc_image_free(&mean);
  oc_image_free(&one);

  ocv_gl_history_free(hs);
  oc_image_free(&full);
  oc_image_free(&img);
  ocv_gl_state_free(&sv.gs);
  oc_state_free(&sv.st);
}

/* Disocclusion: the camera steps 1.1 km sideways (lat + 0.01°: the sphere shifts ~11 px) after a
 * full frame, so background is uncovered where the history holds cloud. Uncovered pixels: cloud
 * (transmittance < ½, so they have a cloud depth) in the previous full render and clear sky
 * (transmittance 1) in the new one. Each such pixel's ray, at its old cloud depth, projects into
 * the old view onto background, whose depth disagrees: the history is rejected and the block's
 * traced pixel stands in. The history frame is rendered with a marked background radiance (0.05,
 * the new frames 0.02), so a pixel of the new frame that still shows history background is
 * recognisable. Checks: fs.rejected covers the uncovered pixels; at most a tenth of them show
 * history background or cloud; and there the reprojected frame is close to the new full
 * render: mean absolute error (0–255, tone-mapped) below a fifth of that of the stale history (the
 * previous frame at those pixels) — the negative control, what a reprojection that kept it would
 * score. Tried against broken copies of shaders/reproject.comp.glsl: without the depth test
 * (0 rejected, 233 of 250 show history, error 62.7) and without the reprojection (history taken
 * at the same pixel: 192 rejected, 75 show history, error 11.1) the test fails. Measured on
 * llvmpipe: 250 uncovered, 7 showing cloud (their block's traced pixel is cloud), 716 rejected;
 * error 1.16 vs 26.0 for the stale history. */
static void test_gl_reproject__disocclusion(void **state) {
  (void)state;
  sphere_view_t sv;
  sphere_view_up(&sv);
  oc_render_desc_t d = const_bg_desc(sv.cam, W, H);
  d.background_radiance = 0.05f; /* the mark */
  char why[512];
  oc_image_t before = {0}, after = {0}, img = {0};
  assert_int_equal(oc_image_alloc(&before, W, H), 0);
  assert_int_equal(oc_image_alloc(&after, W, H), 0);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  ocv_gl_history_t *hs = ocv_gl_history_create(W, H, why, sizeof why);
  assert_non_null(hs);
  ocv_gl_frame_stats_t fs;
  assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 0, &before, &fs, why, sizeof why), 0); /* full: the history */
  sv.pose.geo.lat += 0.01;
  d.camera = oc_camera_from_pose(sv.pose);
  d.background_radiance = 0.02f;
  assert_int_equal(ocv_gl_render_state(ren, &sv.gs, &d, &after, why, sizeof why), 0);
  assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
  static uint8_t a[W * H * 3], b[W * H * 3], r[W * H * 3];
  assert_int_equal(oc_image_tonemap(&before, 10.0f, a), 0);
  assert_int_equal(oc_image_tonemap(&after, 10.0f, b), 0);
  assert_int_equal(oc_image_tonemap(&img, 10.0f, r), 0);
  int uncovered = 0, history = 0, covered = 0, covered_history = 0;
  double err_reprojected = 0.0, err_stale = 0.0, err_covered = 0.0, err_covered_stale = 0.0;
  for (int i = 0; i < W * H; i++) {
    const float *p = &img.px[4 * i];
    /* the other side: background before, cloud now (the sphere moved over it). Its history says
     * "far", which reprojects onto far history and passes the depth test; only the fresh traced
     * pixels around it tell that nothing far is seen there any more */
    if (before.px[4 * i + 3] == 1.0f && after.px[4 * i + 3] < 0.5f) {
      covered++;
      covered_history += p[3] == 1.0f && p[0] == 0.05f;
      for (int c = 0; c < 3; c++) {
        err_covered += abs((int)r[3 * i + c] - (int)b[3 * i + c]);
        err_covered_stale += abs((int)a[3 * i + c] - (int)b[3 * i + c]);
      }
    }
    if (!(before.px[4 * i + 3] < 0.5f && after.px[4 * i + 3] == 1.0f)) continue;
    uncovered++;
    history += p[3] < 0.5f || (p[3] == 1.0f && p[0] == 0.05f); /* cloud, or the history's background */
    for (int c = 0; c < 3; c++) {
      err_reprojected += abs((int)r[3 * i + c] - (int)b[3 * i + c]);
      err_stale += abs((int)a[3 * i + c] - (int)b[3 * i + c]);
    }
  }
  assert_true(uncovered >= 100); /* the move does uncover background */
  err_reprojected /= 3.0 * uncovered;
  err_stale /= 3.0 * uncovered;
  printf("disocclusion: %d pixels uncovered, %d of them show history background or cloud; frame: %u traced, "
         "%u reprojected, %u rejected; mean abs error there: reprojected %.2f, stale history %.2f\n",
         uncovered, history, fs.traced, fs.reprojected, fs.rejected, err_reprojected, err_stale);
  assert_true(fs.rejected >= (uint32_t)uncovered);
  assert_true(history * 10 <= uncovered);
  assert_true(err_stale >= 10.0);                  /* the control: stale history is far off */
  assert_true(err_reprojected * 5.0 < err_stale); /* rejected: close to the new full render */
  err_covered /= 3.0 * (covered > 0 ? covered : 1);
  err_covered_stale /= 3.0 * (covered > 0 ? covered : 1);
  printf("covered: %d pixels, %d of them show history background; mean abs error there: reprojected %.2f, stale %.2f\n",
         covered, covered_history, err_covered, err_covered_stale);

  /* a flight of small steps (about a pixel a frame, as at 60 fps): the cloud's leading edge covers
   * background a pixel at a time, which the nearer history beside each pixel reveals. Count the
   * pixels that show background where the full render shows cloud, frame after frame. */
  oc_camera_pose_t fly = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0};
  d.camera = oc_camera_from_pose(fly);
  d.background_radiance = 0.02f;
  ocv_gl_history_reset(hs);
  int ghosts = 0, cloud_px = 0;
  for (int f = 0; f < 24; f++) {
    fly.geo.lat += 0.0012; /* 130 m a frame: about 0.8 pixel at the sphere */
    d.camera = oc_camera_from_pose(fly);
    assert_int_equal(ocv_gl_render_frame(ren, hs, &sv.gs, &d, 1, &img, &fs, why, sizeof why), 0);
    if (f < 16) continue; /* every pixel traced once first */
    assert_int_equal(ocv_gl_render_state(ren, &sv.gs, &d, &after, why, sizeof why), 0);
    for (int i = 0; i < W * H; i++)
      if (after.px[4 * i + 3] < 0.5f) {
        cloud_px++;
        ghosts += img.px[4 * i + 3] == 1.0f;
      }
  }
  printf("small steps: %d pixel-frames show background where the cloud is, of %d cloud pixel-frames\n", ghosts, cloud_px);
  assert_true(covered >= 100);
  /* a jump of 8 pixels in one frame: only the covered pixels with a cloud among their bracketing
   * traced pixels can be told apart; about half */
  assert_true(covered_history * 10 <= covered * 6);
  assert_true(err_covered * 1.3 < err_covered_stale);
  /* 7.2 % measured (the leading edge's pixels whose nearer neighbour's point does not land back on
   * that neighbour); 27 % before the two covering rules (ocv_behind_fresh, ocv_covered) */
  assert_true(ghosts * 100 <= cloud_px * 10);
  ocv_gl_history_free(hs);
  oc_image_free(&before);
  oc_image_free(&after);
  oc_image_free(&img);
  ocv_gl_state_free(&sv.gs);
  oc_state_free(&sv.st);
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_reproject__frames),
             cmocka_unit_test(test_gl_reproject__disocclusion))

/* test_gl_view.c — the viewer's frame loop (client/gl/gl_view.c), headless: a state is shown only
 * once its bricks are uploaded (a bounded number per frame), the next one blends in over one epoch
 * period from the state shown before (t = 0: the previous image, t = 1: the new one exactly), the
 * resident bytes stay within the budget, reprojection runs through the same loop, and a state over
 * the budget is refused while the shown one stays. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "oc_camera.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "oc_scene_voxelize.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54

static void make_state(oc_state_t *st, oc_camera_t cam, uint32_t id_base, uint64_t epoch) {
  sphere_state(st, cam, H, id_base);
  st->epoch = epoch;
}

static void render_direct(const oc_state_t *s, const oc_render_desc_t *d, oc_image_t *img) {
  char why[512];
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, s, why, sizeof why), 0);
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  assert_int_equal(ocv_gl_render_state(ren, &gs, d, img, why, sizeof why), 0);
  ocv_gl_state_free(&gs);
}

static void test_gl_view__epochs(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_camera_pose_t far = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}, near = {{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cf = oc_camera_from_pose(far);
  oc_state_t s1, s2;
  make_state(&s1, cf, 0, 1);
  make_state(&s2, oc_camera_from_pose(near), 1000000, 2);
  oc_render_desc_t d;
  memset(&d, 0, sizeof d);
  d.width = W;
  d.height = H;
  d.camera = cf;
  d.background = OC_BG_CONSTANT;
  d.background_radiance = 0.02f;
  oc_image_t r1, r2, img = {0};
  render_direct(&s1, &d, &r1);
  render_direct(&s2, &d, &r2);
  assert_int_equal(oc_image_alloc(&img, W, H), 0);

  uint64_t budget = (uint64_t)(s1.brick_count + s2.brick_count + 8) * OCV_GL_SLOT_BYTES;
  ocv_gl_view_desc_t vd = {.budget = budget, .kept = 2, .animated = 1, .epoch_period = 1.0,
                           .upload_per_frame = 32 * OCV_GL_SLOT_BYTES};
  ocv_gl_view_t *v = ocv_gl_view_create(ren, &vd, why, sizeof why);
  if (!v) fail_msg("%s", why);
  ocv_gl_view_stats_t st;
  assert_int_equal(ocv_gl_view_frame(v, &d, 0.0, 0, &img, &st, why, sizeof why), 0);
  assert_false(st.shown); /* nothing yet */

  /* epoch 1 arrives: shown after ceil(bricks / 32) frames, then exactly its image */
  assert_int_equal(ocv_gl_view_push(v, &s1, why, sizeof why), 0);
  int frames = 0;
  do {
    assert_int_equal(ocv_gl_view_frame(v, &d, 0.1 * frames, 0, &img, &st, why, sizeof why), 0);
    assert_true(st.uploaded_bytes <= 32 * OCV_GL_SLOT_BYTES);
    frames++;
  } while (!st.shown);
  assert_int_equal(frames, (int)((s1.brick_count + 31) / 32));
  assert_int_equal(st.epoch, 1);
  assert_memory_equal(img.px, r1.px, sizeof(float) * 4 * W * H);

  /* epoch 2 arrives at t = 10 s: it blends in from epoch 1 over one period */
  assert_int_equal(ocv_gl_view_push(v, &s2, why, sizeof why), 0);
  double now = 10.0;
  do {
    assert_int_equal(ocv_gl_view_frame(v, &d, now, 0, &img, &st, why, sizeof why), 0);
    assert_true(st.resident_bytes <= budget + (uint64_t)(s1.node_count + s2.node_count) * OCV_GL_LEAF_BYTES);
  } while (st.epoch != 2);
  assert_true(st.t == 0.0f);
  double at0 = rmse(&img, &r1), p12 = rmse(&r1, &r2);
  assert_int_equal(ocv_gl_view_frame(v, &d, now + 0.5, 0, &img, &st, why, sizeof why), 0);
  double half1 = rmse(&img, &r1), half2 = rmse(&img, &r2);
  assert_int_equal(ocv_gl_view_frame(v, &d, now + 1.0, 0, &img, &st, why, sizeof why), 0);
  assert_true(st.t == 1.0f);
  assert_memory_equal(img.px, r2.px, sizeof(float) * 4 * W * H);
  printf("view: epoch 1 shown after %d frames; epoch 2 at t=0 vs epoch 1 RMSE %.2f (epochs differ by %.2f), "
         "t=½ %.2f / %.2f\n", frames, at0, p12, half1, half2);
  assert_true(at0 < p12 / 3 && half1 < p12 && half2 < p12);

  /* reprojection through the loop: still camera, 16 frames → the full image */
  for (int f = 0; f < 16; f++) assert_int_equal(ocv_gl_view_frame(v, &d, now + 2.0 + f, 1, &img, &st, why, sizeof why), 0);
  assert_true(st.frame.reprojected > 0);
  assert_memory_equal(img.px, r2.px, sizeof(float) * 4 * W * H);

  /* over the budget: refused, the shown state stays */
  oc_state_t big;
  make_state(&big, oc_camera_from_pose((oc_camera_pose_t){{0.0, -0.03, 3000.0}, 90.0, 0.0, 40.0}), 2000000, 3);
  if (big.brick_count > (uint32_t)(budget / OCV_GL_SLOT_BYTES) - s2.brick_count) {
    assert_int_equal(ocv_gl_view_push(v, &big, why, sizeof why), OC_ETOOBIG);
    assert_int_equal(ocv_gl_view_frame(v, &d, now + 30, 0, &img, &st, why, sizeof why), 0);
    assert_int_equal(st.epoch, 2);
  }
  oc_state_free(&big);
  ocv_gl_view_free(v);
  oc_image_free(&r1);
  oc_image_free(&r2);
  oc_image_free(&img);
  oc_state_free(&s1);
  oc_state_free(&s2);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_gl_view__epochs)};
  return cmocka_run_group_tests(tests, setup, teardown);
}

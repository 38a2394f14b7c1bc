/* test_gl_interp.c — interpolation between states on the GPU (client/interp.h → client/gl/gl_interp.c
 * → the kernel's mix(previous, newest, t)): at t = 1 the newest state exactly; at t = 0 the previous
 * state (exactly where bricks were refreshed in place, closely where the tree was re-planned, since
 * a split parent and merged children are resampled); in between, in between; a static scene's
 * refreshed brick snaps (only splits and merges cross-fade). */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "interp.h"
#include "oc_camera.h"
#include "oc_image.h"
#include "oc_render.h"
#include "oc_scene.h"
#include "oc_scene_voxelize.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54

static void make_state(oc_state_t *st, oc_camera_t cam, uint32_t id_base) { sphere_state(st, cam, H, id_base); }

static void render(const oc_state_t *s, oc_camera_t cam, const ocv_gl_prev_t *gp, float t, oc_image_t *img) {
  char why[512];
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, s, why, sizeof why), 0);
  oc_render_desc_t d;
  memset(&d, 0, sizeof d);
  d.width = W;
  d.height = H;
  d.camera = cam;
  d.background = OC_BG_CONSTANT;
  d.background_radiance = 0.02f;
  assert_int_equal(oc_image_alloc(img, W, H), 0);
  ocv_gl_renderer_set_prev(ren, gp, t);
  if (ocv_gl_render_state(ren, &gs, &d, img, why, sizeof why) < 0) fail_msg("render: %s", why);
  ocv_gl_renderer_set_prev(ren, NULL, 1.0f);
  ocv_gl_state_free(&gs);
}

/* P seen from far, N re-planned from nearer (other leaves, other bricks), both from the same view. */
static void blend_case(const char *name, oc_state_t *P, oc_state_t *N, oc_camera_t view, int animated, double max_t0) {
  char why[512];
  ocv_interp_t ip;
  ocv_interp_init(&ip);
  assert_int_equal(ocv_interp_build(&ip, P, N), 0);
  ocv_interp_stats_t is;
  ocv_interp_stats(&ip, &is);
  ocv_gl_prev_t gp;
  if (ocv_gl_prev_upload(&gp, &ip, animated, why, sizeof why) < 0) fail_msg("%s", why);
  oc_image_t ip_, in_, i0, i1, ih;
  render(P, view, NULL, 1.0f, &ip_);
  render(N, view, NULL, 1.0f, &in_);
  render(N, view, &gp, 0.0f, &i0);
  render(N, view, &gp, 1.0f, &i1);
  render(N, view, &gp, 0.5f, &ih);
  double pn = rmse(&ip_, &in_), t0p = rmse(&i0, &ip_), hp = rmse(&ih, &ip_), hn = rmse(&ih, &in_);
  printf("%s: same %u own %u parent %u children %u | RMSE P–N %.2f, t=0 vs P %.2f, t=½ vs P %.2f vs N %.2f\n", name,
         is.count[OCV_INTERP_SAME], is.count[OCV_INTERP_OWN], is.count[OCV_INTERP_PARENT], is.count[OCV_INTERP_CHILDREN],
         pn, t0p, hp, hn);
  assert_memory_equal(i1.px, in_.px, sizeof(float) * 4 * W * H); /* t = 1: the newest state */
  assert_true(pn > 1.0);                                        /* the two states do differ */
  assert_true(t0p <= max_t0);                                   /* t = 0: the previous state */
  assert_true(hp < pn && hn < pn);                              /* t = ½: in between */
  oc_image_free(&ip_);
  oc_image_free(&in_);
  oc_image_free(&i0);
  oc_image_free(&i1);
  oc_image_free(&ih);
  ocv_gl_prev_free(&gp);
  ocv_interp_free(&ip);
}

static void test_gl_interp__refresh_and_replan(void **state) {
  (void)state;
  require_gl();
  oc_camera_pose_t far = {{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0}, near = {{0.0, -0.045, 3000.0}, 90.0, 0.0, 40.0};
  oc_camera_t cf = oc_camera_from_pose(far), cn = oc_camera_from_pose(near);
  oc_state_t P, N, R;
  make_state(&P, cf, 0);
  /* a refresh in place: every brick of P with new content under a new id (OWN) */
  oc_state_init(&R);
  assert_int_equal(oc_state_copy(&R, &P), 0);
  for (uint32_t i = 0; i < R.node_count; i++)
    if (R.nodes[i].kind == OC_NODE_BRICK) R.nodes[i].brick_id += 500000;
  for (uint32_t b = 0; b < R.brick_count; b++) {
    R.bricks[b].id += 500000;
    for (int v = 0; v < 512; v++) R.bricks[b].codes.code[0][v] = (uint16_t)(R.bricks[b].codes.code[0][v] ? 65535 - (v & 255) : 0);
  }
  blend_case("refresh", &P, &R, cf, 1, 0.5);
  { /* a static scene has no time interpolation: a brick refreshed in place snaps to the newest */
    char why[512];
    ocv_interp_t ip;
    ocv_interp_init(&ip);
    assert_int_equal(ocv_interp_build(&ip, &P, &R), 0);
    ocv_gl_prev_t gp;
    assert_int_equal(ocv_gl_prev_upload(&gp, &ip, 0, why, sizeof why), 0);
    oc_image_t a, b;
    render(&R, cf, &gp, 0.0f, &a);
    render(&R, cf, NULL, 1.0f, &b);
    assert_memory_equal(a.px, b.px, sizeof(float) * 4 * W * H);
    oc_image_free(&a);
    oc_image_free(&b);
    ocv_gl_prev_free(&gp);
    ocv_interp_free(&ip);
  }
  /* re-planned for a nearer camera: splits and merges, seen from the far camera */
  make_state(&N, cn, 1000000);
  blend_case("replan", &P, &N, cf, 1, 3.0);
  oc_state_free(&P);
  oc_state_free(&N);
  oc_state_free(&R);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_gl_interp__refresh_and_replan)};
  return cmocka_run_group_tests(tests, setup, teardown);
}

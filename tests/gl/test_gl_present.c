/* test_gl_present.c — the window's picture on the GPU (client/gl/gl_present.c,
 * shaders/present.comp.glsl) against the CPU's: the GL radiance tone-mapped on the GPU equals
 * oc_image_tonemap() of the same radiance read back (to one 8-bit step: both run shaders/optics.h,
 * float on both sides; the GPU's UNORM store rounds like lrintf), the HUD overlay composited on the
 * GPU equals ocv_hud_text() drawn into the frame on the CPU (to two steps: premultiplied "over" in
 * float against the CPU's 8-bit blend), a non-finite pixel shows black as on the CPU, and exposure
 * reaches the picture. */
#include <setjmp.h> /* cmocka needs these three before cmocka.h */
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_main.h"
#include "hud.h"
#include "oc_camera.h"
#include "oc_err.h"
#include "oc_image.h"
#include "oc_render.h"
#include "ocv_gl.h"

#include "gl/gl_fixture.h" /* ctx, ren, setup, teardown, require_gl, sphere_state, rmse */

#define W 96
#define H 54
#define N ((size_t)W * H * 3)

static int max_diff(const uint8_t *a, const uint8_t *b) { return max_step(a, b, N); }

static void test_gl_present__matches_cpu(void **state) {
  (void)state;
  require_gl();
  char why[512];
  oc_camera_t cam = oc_camera_from_pose((oc_camera_pose_t){{0.0, -0.09, 3000.0}, 90.0, 0.0, 40.0});
  oc_state_t st;
  sphere_state(&st, cam, H, 0);
  ocv_gl_state_t gs;
  assert_int_equal(ocv_gl_state_upload(&gs, &st, why, sizeof why), 0);
  oc_render_desc_t d = const_bg_desc(cam, W, H);
  oc_image_t img = {0};
  assert_int_equal(oc_image_alloc(&img, W, H), 0);
  assert_int_equal(ocv_gl_render_state(ren, &gs, &d, &img, why, sizeof why), 0);
  ocv_gl_present_t *p = ocv_gl_present_create(why, sizeof why);
  if (!p) fail_msg("%s", why);
  uint8_t *cpu = malloc(N), *gpu = malloc(N), *overlay = calloc((size_t)W * 32 * 4, 1);
  assert_non_null(cpu);
  assert_non_null(gpu);
  assert_non_null(overlay);
  uint8_t none[3];
  assert_int_equal(ocv_gl_present_read(p, none, why, sizeof why), OC_EINVAL); /* nothing yet */

  /* tone mapping: GPU against CPU, and exposure matters */
  for (int e = 0; e < 2; e++) {
    float exposure = e ? 40.0f : 10.0f;
    assert_int_equal(oc_image_tonemap(&img, exposure, cpu), 0);
    assert_true(ocv_gl_present_tonemap(p, ocv_gl_renderer_output(ren), W, H, exposure, NULL, 0, 0, why, sizeof why) != 0);
    assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
    int md = max_diff(cpu, gpu);
    printf("exposure %g: GPU vs CPU tone mapping, largest difference %d of 255 (RMSE %.3f)\n", (double)exposure, md,
           oc_rgb8_rmse(cpu, gpu, W, H));
    assert_true(md <= 1);
  }
  uint8_t *bright = malloc(N);
  assert_non_null(bright);
  memcpy(bright, gpu, N);
  assert_true(ocv_gl_present_tonemap(p, ocv_gl_renderer_output(ren), W, H, 10.0f, NULL, 0, 0, why, sizeof why) != 0);
  assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
  assert_true(max_diff(bright, gpu) > 20);

  /* the HUD: drawn into the frame on the CPU, or composited as an overlay on the GPU */
  const char *text = "gl  frame 1.0 ms\nepoch 3";
  assert_int_equal(oc_image_tonemap(&img, 10.0f, cpu), 0);
  ocv_hud_text(cpu, W, H, 3, 3, 1, text, (const uint8_t[3]){255, 255, 255});
  ocv_hud_text_rgba(overlay, W, 32, 3, 3, 1, text, (const uint8_t[3]){255, 255, 255});
  assert_true(ocv_gl_present_tonemap(p, ocv_gl_renderer_output(ren), W, H, 10.0f, overlay, W, 32, why, sizeof why) != 0);
  assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
  int md = max_diff(cpu, gpu);
  printf("HUD overlay: largest difference %d of 255\n", md);
  assert_true(md <= 2);
  assert_true(max_diff(bright, gpu) > 100); /* the text is there */

  /* non-finite radiance shows black, as oc_image_tonemap() does (which also counts it) */
  img.px[0] = NAN;
  img.px[4 * (W + 1) + 1] = INFINITY;
  GLuint buf;
  glCreateBuffers(1, &buf);
  glNamedBufferStorage(buf, (GLsizeiptr)(sizeof(float) * 4 * W * H), img.px, 0);
  assert_int_equal(oc_image_tonemap(&img, 10.0f, cpu), 2);
  assert_true(ocv_gl_present_tonemap(p, buf, W, H, 10.0f, NULL, 0, 0, why, sizeof why) != 0);
  assert_int_equal(ocv_gl_present_read(p, gpu, why, sizeof why), 0);
  assert_true(max_diff(cpu, gpu) <= 1);
  assert_int_equal(gpu[0] | gpu[1] | gpu[2], 0);
  glDeleteBuffers(1, &buf);

  /* refusals */
  assert_int_equal(ocv_gl_present_tonemap(p, 0, W, H, 10.0f, NULL, 0, 0, why, sizeof why), 0);
  assert_int_equal(ocv_gl_present_tonemap(p, ocv_gl_renderer_output(ren), W, H, NAN, NULL, 0, 0, why, sizeof why), 0);
  printf("refused: %s\n", why);

  free(bright);
  free(cpu);
  free(gpu);
  free(overlay);
  ocv_gl_present_free(p);
  oc_image_free(&img);
  ocv_gl_state_free(&gs);
  oc_state_free(&st);
}

OC_TEST_MAIN(setup, teardown,
             cmocka_unit_test(test_gl_present__matches_cpu))
